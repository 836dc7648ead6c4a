//! Per-pixel weights for kernel-weighted histograms (spec 001 eqs. 4, 5 and §2.7).
//!
//! * [`PixelWeight`]: `weight(u, v) ≥ 0` for the pixel at column `u`, row `v`.
//! * [`DepthBand`] (eq. 5, widened to a band, spec resolution I10): weight `g` when
//!   `|Z(u, v) − Z*| ≤ τ`, 0 otherwise and for pixels without depth (0 / NaN), negative or infinite
//!   depth, or outside the image. `g ≡ 1` for [`DepthProfile::Flat`] (the paper), and
//!   `g = 1 − ((Z − Z*)/τ)²` for [`DepthProfile::Epanechnikov`]. It also classifies pixels into
//!   foreground / occluder / behind / no depth ([`DepthBand::class`]).
//! * [`Epanechnikov`]: the image-plane kernel `max(0, 1 − ‖(x − y₀)/h‖²)` of Comaniciu et al.,
//!   with per-axis bandwidths.
//! * [`Product`]: the product of two weights (e.g. depth band × spatial kernel).
//!
//! ```
//! use quarry_core::Plane;
//! use quarry_vision::depth_weights::{DepthBand, DepthClass, DepthProfile, PixelWeight};
//! let depth = Plane::from_fn(4, 1, |x, _| [1.0f32, 3.0, 3.2, 6.0][x as usize]);
//! let band = DepthBand::new(&depth, 3.0, 0.3, DepthProfile::Flat)?;
//! assert_eq!((0..4).map(|u| band.weight(u, 0)).collect::<Vec<_>>(), vec![0.0, 1.0, 1.0, 0.0]);
//! assert_eq!(band.class(0, 0), DepthClass::Occluder);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use quarry_core::{CoreError, Plane};

/// A non-negative weight per pixel (column `u`, row `v`).
pub trait PixelWeight {
    /// The weight of pixel `(u, v)`; finite and `≥ 0`.
    fn weight(&self, u: u32, v: u32) -> f32;
}

/// Profile `g` of the depth band.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum DepthProfile {
    /// `g ≡ 1` inside the band (the paper; all target pixels weigh the same).
    #[default]
    Flat,
    /// `g = 1 − ((Z − Z*)/τ)²` (Comaniciu's profile applied along depth).
    Epanechnikov,
}

/// Depth class of a pixel relative to a target depth `Z*` and band half-width `τ` (spec §2.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthClass {
    /// `|Z − Z*| ≤ τ`.
    Foreground,
    /// `Z < Z* − τ` (in front of the target).
    Occluder,
    /// `Z > Z* + τ`.
    Behind,
    /// No (valid) depth, or outside the image.
    NoDepth,
}

/// The depth kernel (eq. 5): weight by closeness of the pixel's depth to the target depth.
#[derive(Debug, Clone, Copy)]
pub struct DepthBand<'a> {
    depth: &'a Plane<f32>,
    /// Target depth `Z*`, metres.
    pub z_star: f32,
    /// Band half-width `τ`, metres.
    pub tau: f32,
    /// The profile `g`.
    pub profile: DepthProfile,
}

impl<'a> DepthBand<'a> {
    /// A depth band over `depth` (metres; 0 / NaN = no depth).
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] unless `z_star` and `tau` are finite and `> 0`;
    /// [`VisionError::EmptyImage`] for an empty plane; a dimension mismatch for a malformed plane.
    pub fn new(
        depth: &'a Plane<f32>,
        z_star: f32,
        tau: f32,
        profile: DepthProfile,
    ) -> Result<Self, VisionError> {
        if !(z_star.is_finite() && z_star > 0.0) {
            return Err(CoreError::invalid(
                "z_star",
                format!("must be finite and > 0, got {z_star}"),
            )
            .into());
        }
        if !(tau.is_finite() && tau > 0.0) {
            return Err(
                CoreError::invalid("tau", format!("must be finite and > 0, got {tau}")).into(),
            );
        }
        if depth.width == 0 || depth.height == 0 {
            return Err(VisionError::EmptyImage {
                what: "DepthBand",
                width: depth.width,
                height: depth.height,
                min: 1,
            });
        }
        quarry_core::ensure_len(
            depth.data.len(),
            depth.width as usize * depth.height as usize,
            "depth plane data",
        )?;
        Ok(Self {
            depth,
            z_star,
            tau,
            profile,
        })
    }

    /// Valid depth at a pixel (finite and `> 0`), else `None`.
    fn z(&self, u: u32, v: u32) -> Option<f32> {
        self.depth
            .get(u, v)
            .copied()
            .filter(|z| z.is_finite() && *z > 0.0)
    }

    /// The pixel's [`DepthClass`].
    #[must_use]
    pub fn class(&self, u: u32, v: u32) -> DepthClass {
        match self.z(u, v) {
            None => DepthClass::NoDepth,
            Some(z) if z < self.z_star - self.tau => DepthClass::Occluder,
            Some(z) if z > self.z_star + self.tau => DepthClass::Behind,
            Some(_) => DepthClass::Foreground,
        }
    }
}

impl PixelWeight for DepthBand<'_> {
    fn weight(&self, u: u32, v: u32) -> f32 {
        let Some(z) = self.z(u, v) else { return 0.0 };
        let d = (z - self.z_star) / self.tau;
        if d.abs() > 1.0 {
            return 0.0;
        }
        match self.profile {
            DepthProfile::Flat => 1.0,
            DepthProfile::Epanechnikov => (1.0 - d * d).max(0.0),
        }
    }
}

/// The image-plane Epanechnikov kernel `max(0, 1 − ((u − c_u)/h_u)² − ((v − c_v)/h_v)²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Epanechnikov {
    /// Kernel centre `(c_u, c_v)`, pixels.
    pub centre: (f64, f64),
    /// Bandwidths `(h_u, h_v)`, pixels (e.g. half the box width and height).
    pub h: (f64, f64),
}

impl Epanechnikov {
    /// A kernel centred at `centre` with bandwidths `h`.
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] for a non-finite centre, [`CoreError::InvalidParameter`] unless both
    /// bandwidths are finite and `> 0`.
    pub fn new(centre: (f64, f64), h: (f64, f64)) -> Result<Self, VisionError> {
        if !(centre.0.is_finite() && centre.1.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "Epanechnikov centre",
            }
            .into());
        }
        if !(h.0.is_finite() && h.1.is_finite() && h.0 > 0.0 && h.1 > 0.0) {
            return Err(CoreError::invalid(
                "h",
                format!("bandwidths must be finite and > 0, got {h:?}"),
            )
            .into());
        }
        Ok(Self { centre, h })
    }
}

impl PixelWeight for Epanechnikov {
    fn weight(&self, u: u32, v: u32) -> f32 {
        let a = (f64::from(u) - self.centre.0) / self.h.0;
        let b = (f64::from(v) - self.centre.1) / self.h.1;
        #[allow(clippy::cast_possible_truncation)]
        let w = (1.0 - a * a - b * b).max(0.0) as f32;
        if w.is_finite() { w } else { 0.0 }
    }
}

/// The product of two weights.
#[derive(Debug, Clone, Copy)]
pub struct Product<A, B>(pub A, pub B);

impl<A: PixelWeight, B: PixelWeight> PixelWeight for Product<A, B> {
    fn weight(&self, u: u32, v: u32) -> f32 {
        self.0.weight(u, v) * self.1.weight(u, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn errors() {
        let d = Plane::new(3, 3, 1.0f32);
        assert!(DepthBand::new(&d, f32::NAN, 0.3, DepthProfile::Flat).is_err());
        assert!(DepthBand::new(&d, 2.0, 0.0, DepthProfile::Flat).is_err());
        assert!(DepthBand::new(&Plane::new(0, 0, 1.0f32), 2.0, 0.3, DepthProfile::Flat).is_err());
        assert!(Epanechnikov::new((f64::NAN, 0.0), (1.0, 1.0)).is_err());
        assert!(Epanechnikov::new((0.0, 0.0), (0.0, 1.0)).is_err());
    }

    #[test]
    fn known_weights() {
        let d = Plane::from_fn(5, 1, |x, _| [2.0f32, 2.15, 0.0, f32::NAN, -1.0][x as usize]);
        let b = DepthBand::new(&d, 2.0, 0.3, DepthProfile::Epanechnikov).unwrap();
        assert_eq!(b.weight(0, 0), 1.0);
        assert!((b.weight(1, 0) - 0.75).abs() < 1e-5);
        assert_eq!(b.weight(2, 0), 0.0);
        assert_eq!(b.weight(3, 0), 0.0);
        assert_eq!(b.weight(4, 0), 0.0);
        assert_eq!(b.weight(9, 9), 0.0);
        assert_eq!(b.class(4, 0), DepthClass::NoDepth);
        assert_eq!(b.class(9, 0), DepthClass::NoDepth);
        let k = Epanechnikov::new((2.0, 2.0), (2.0, 4.0)).unwrap();
        assert_eq!(k.weight(2, 2), 1.0);
        assert!((k.weight(3, 2) - 0.75).abs() < 1e-6);
        assert!((k.weight(2, 4) - 0.75).abs() < 1e-6);
        assert_eq!(k.weight(4, 2), 0.0);
        assert!((Product(k, b).weight(0, 0) - 0.0).abs() < 1e-9); // k(0,0) = 1 − 1 − 0.25 < 0 → 0
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        /// Flat-band weight is 1 exactly on foreground pixels; Epanechnikov band weight lies in
        /// [0, 1], is positive only on foreground, and decreases with |Z − Z*|.
        #[test]
        fn band_consistent_with_classes(zs in proptest::collection::vec(prop_oneof![Just(0.0f32), 0.1f32..8.0], 1..40),
                                         z_star in 0.5f32..7.0, tau in 0.05f32..1.0) {
            let n = zs.len() as u32;
            let d = Plane::from_vec(n, 1, zs.clone()).unwrap();
            let flat = DepthBand::new(&d, z_star, tau, DepthProfile::Flat).unwrap();
            let epa = DepthBand::new(&d, z_star, tau, DepthProfile::Epanechnikov).unwrap();
            for u in 0..n {
                let z = zs[u as usize];
                let c = flat.class(u, 0);
                prop_assert_eq!(flat.weight(u, 0) == 1.0, c == DepthClass::Foreground);
                prop_assert!(flat.weight(u, 0) == 0.0 || flat.weight(u, 0) == 1.0);
                let w = epa.weight(u, 0);
                prop_assert!((0.0..=1.0).contains(&w));
                if w > 0.0 { prop_assert_eq!(c, DepthClass::Foreground); }
                match c {
                    DepthClass::NoDepth => prop_assert_eq!(z, 0.0),
                    DepthClass::Occluder => prop_assert!(z < z_star - tau),
                    DepthClass::Behind => prop_assert!(z > z_star + tau),
                    DepthClass::Foreground => prop_assert!((z - z_star).abs() <= tau + 1e-6),
                }
                for v in 0..n {
                    let z2 = zs[v as usize];
                    if z > 0.0 && z2 > 0.0 && (z - z_star).abs() < (z2 - z_star).abs() {
                        prop_assert!(epa.weight(u, 0) >= epa.weight(v, 0));
                    }
                }
            }
        }

        #[test]
        fn epanechnikov_bounds(cu in -10.0f64..50.0, cv in -10.0f64..50.0, hu in 0.5f64..30.0, hv in 0.5f64..30.0,
                               u in 0u32..60, v in 0u32..60) {
            let k = Epanechnikov::new((cu, cv), (hu, hv)).unwrap();
            let w = k.weight(u, v);
            prop_assert!((0.0..=1.0).contains(&w));
            let r2 = ((f64::from(u) - cu) / hu).powi(2) + ((f64::from(v) - cv) / hv).powi(2);
            prop_assert_eq!(w > 0.0, r2 < 1.0);
        }
    }
}
