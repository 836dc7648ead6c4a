//! Normalised histograms with cosine / Bhattacharyya similarity, and the depth count histogram
//! with its smoothed, gated peak (spec 001 eqs. 1, 6 and §2.2).
//!
//! * [`Histogram`]: non-negative `f32` bins summing to 1, built by [`Histogram::from_weights`].
//! * [`cosine`] (eq. 6) on raw non-negative vectors: in `[0, 1]`, 0 when either input is empty or
//!   all-zero. Accumulated in `f64` and clamped to `[0, 1]`.
//! * [`bhattacharyya`]: the coefficient `Σ √(p_u q_u)` of two normalised histograms, in `[0, 1]`.
//! * [`DepthHistogram`]: the count histogram (1) with bin width `bin_m` (default 0.1 m, 80 bins over
//!   `[0, 8)` m). Depth 0 or NaN means "no depth" (spec §1) and is not counted, nor is depth at or
//!   beyond the last bin; negative or infinite depth is an error. It also keeps the per-bin depth
//!   sums, so [`DepthHistogram::peak_smoothed`] returns the refined `Z*` (mean depth of the pixels in
//!   bins `u*−1 … u*+1`) with the peak.
//!
//! ```
//! use quarry_core::Plane;
//! use quarry_vision::histogram::{DepthHistogram, Histogram};
//! let h = Histogram::from_weights(&[1.0, 3.0])?;
//! assert_eq!(h.bins(), &[0.25, 0.75]);
//! assert!((h.cosine(&h)? - 1.0).abs() < 1e-6);
//! let depth = Plane::from_fn(10, 10, |x, _| if x < 7 { 2.04 } else { 5.0 });
//! let dh = DepthHistogram::from_plane(&depth, (0, 0, 10, 10), 0.1, 80)?;
//! let peak = dh.peak_smoothed(None)?.unwrap();
//! assert_eq!(peak.bin, 20);
//! assert!((peak.z_star - 2.04).abs() < 1e-5);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use quarry_core::{CoreError, Plane};

/// A normalised histogram: entries `≥ 0`, summing to 1 (up to `f32` rounding).
#[derive(Debug, Clone, PartialEq)]
pub struct Histogram {
    bins: Vec<f32>,
}

fn check_weights(w: &[f32], what: &'static str) -> Result<(), VisionError> {
    if w.iter().any(|x| !x.is_finite()) {
        return Err(CoreError::NonFinite { what }.into());
    }
    if w.iter().any(|&x| x < 0.0) {
        return Err(CoreError::invalid(what, "entries must be non-negative").into());
    }
    Ok(())
}

impl Histogram {
    /// Normalises non-negative weights to sum 1 (the sum is taken in `f64`).
    ///
    /// # Errors
    /// [`CoreError::Empty`] for no bins, [`CoreError::NonFinite`] / [`CoreError::InvalidParameter`]
    /// for non-finite or negative weights, [`CoreError::Numerical`] when all weights are 0.
    pub fn from_weights(weights: &[f32]) -> Result<Self, VisionError> {
        if weights.is_empty() {
            return Err(CoreError::Empty {
                what: "histogram weights",
            }
            .into());
        }
        check_weights(weights, "histogram weights")?;
        let sum: f64 = weights.iter().map(|&x| f64::from(x)).sum();
        if sum <= 0.0 {
            return Err(
                CoreError::numerical("Histogram::from_weights", "all weights are zero").into(),
            );
        }
        #[allow(clippy::cast_possible_truncation)]
        let bins = weights
            .iter()
            .map(|&x| (f64::from(x) / sum) as f32)
            .collect();
        Ok(Self { bins })
    }

    /// The normalised bins.
    #[must_use]
    pub fn bins(&self) -> &[f32] {
        &self.bins
    }

    /// Number of bins.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bins.len()
    }

    /// Always false (a histogram has at least one bin); provided for API symmetry with `len`.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bins.is_empty()
    }

    /// Cosine similarity (eq. 6) with another histogram, in `[0, 1]`.
    ///
    /// # Errors
    /// [`CoreError::DimensionMismatch`] when the bin counts differ.
    pub fn cosine(&self, other: &Self) -> Result<f32, VisionError> {
        cosine(&self.bins, &other.bins)
    }

    /// Bhattacharyya coefficient `Σ √(p q)` with another histogram, in `[0, 1]`.
    ///
    /// # Errors
    /// [`CoreError::DimensionMismatch`] when the bin counts differ.
    pub fn bhattacharyya(&self, other: &Self) -> Result<f32, VisionError> {
        bhattacharyya(&self.bins, &other.bins)
    }
}

/// Cosine similarity of two non-negative vectors (eq. 6), in `[0, 1]`; 0 when either is empty or
/// all-zero. Scale-invariant in each argument.
///
/// # Errors
/// [`CoreError::DimensionMismatch`] for different lengths, [`CoreError::NonFinite`] /
/// [`CoreError::InvalidParameter`] for non-finite or negative entries.
pub fn cosine(a: &[f32], b: &[f32]) -> Result<f32, VisionError> {
    quarry_core::ensure_len(b.len(), a.len(), "cosine: second vector")?;
    check_weights(a, "cosine input")?;
    check_weights(b, "cosine input")?;
    let (mut ab, mut aa, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    for (&x, &y) in a.iter().zip(b) {
        let (x, y) = (f64::from(x), f64::from(y));
        ab += x * y;
        aa += x * x;
        bb += y * y;
    }
    if aa <= 0.0 || bb <= 0.0 {
        return Ok(0.0);
    }
    #[allow(clippy::cast_possible_truncation)]
    let rho = (ab / (aa.sqrt() * bb.sqrt())).clamp(0.0, 1.0) as f32;
    Ok(rho)
}

/// Bhattacharyya coefficient `Σ √(p_u q_u)` of two vectors, each normalised to sum 1 first, in
/// `[0, 1]`; 0 when either is empty or all-zero.
///
/// # Errors
/// As [`cosine`].
pub fn bhattacharyya(p: &[f32], q: &[f32]) -> Result<f32, VisionError> {
    quarry_core::ensure_len(q.len(), p.len(), "bhattacharyya: second vector")?;
    check_weights(p, "bhattacharyya input")?;
    check_weights(q, "bhattacharyya input")?;
    let sp: f64 = p.iter().map(|&x| f64::from(x)).sum();
    let sq: f64 = q.iter().map(|&x| f64::from(x)).sum();
    if sp <= 0.0 || sq <= 0.0 {
        return Ok(0.0);
    }
    let s: f64 = p
        .iter()
        .zip(q)
        .map(|(&x, &y)| (f64::from(x) * f64::from(y)).sqrt())
        .sum();
    #[allow(clippy::cast_possible_truncation)]
    let bc = (s / (sp * sq).sqrt()).clamp(0.0, 1.0) as f32;
    Ok(bc)
}

/// The depth count histogram (1): `counts[u]` = number of pixels with `⌊Z / bin_m⌋ = u`.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthHistogram {
    bin_m: f32,
    counts: Vec<u32>,
    sums: Vec<f64>,
}

/// The smoothed peak of a [`DepthHistogram`] (spec 001 §2.2).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthPeak {
    /// The peak bin `u*`.
    pub bin: usize,
    /// Its smoothed count `h̃(u*) = q(u*−1) + q(u*) + q(u*+1)`.
    pub smoothed: u32,
    /// Refined target depth `Z*`: the mean depth of the pixels in bins `u*−1 … u*+1`, metres.
    pub z_star: f32,
}

impl DepthHistogram {
    /// An empty histogram with `n_bins` bins of width `bin_m` metres.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] unless `bin_m` is finite and `> 0` and `n_bins ≥ 1`.
    pub fn new(bin_m: f32, n_bins: usize) -> Result<Self, VisionError> {
        if !(bin_m.is_finite() && bin_m > 0.0) {
            return Err(CoreError::invalid(
                "bin_m",
                format!("must be finite and > 0, got {bin_m}"),
            )
            .into());
        }
        if n_bins == 0 {
            return Err(CoreError::invalid("n_bins", "must be at least 1").into());
        }
        Ok(Self {
            bin_m,
            counts: vec![0; n_bins],
            sums: vec![0.0; n_bins],
        })
    }

    /// The spec's default: 80 bins of 0.1 m over `[0, 8)` m.
    #[must_use]
    pub fn paper() -> Self {
        Self {
            bin_m: 0.1,
            counts: vec![0; 80],
            sums: vec![0.0; 80],
        }
    }

    /// Bin width, metres.
    #[must_use]
    pub fn bin_m(&self) -> f32 {
        self.bin_m
    }

    /// The counts per bin.
    #[must_use]
    pub fn counts(&self) -> &[u32] {
        &self.counts
    }

    /// Number of counted pixels.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.counts.iter().map(|&c| u64::from(c)).sum()
    }

    /// Bin of a depth, or `None` for no depth (0 / NaN) or depth beyond the last bin.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] for negative or infinite depth.
    pub fn bin_of(&self, z: f32) -> Result<Option<usize>, VisionError> {
        if z.is_nan() || z == 0.0 {
            return Ok(None);
        }
        if z.is_infinite() || z < 0.0 {
            return Err(CoreError::invalid(
                "depth",
                format!("must be ≥ 0, finite, 0 or NaN for none; got {z}"),
            )
            .into());
        }
        let b = (z / self.bin_m).floor();
        #[allow(clippy::cast_precision_loss)]
        if b >= self.counts.len() as f32 {
            return Ok(None);
        }
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        Ok(Some(b as usize))
    }

    /// Counts one depth sample; returns whether it was counted.
    ///
    /// # Errors
    /// As [`DepthHistogram::bin_of`].
    pub fn add(&mut self, z: f32) -> Result<bool, VisionError> {
        match self.bin_of(z)? {
            Some(b) => {
                self.counts[b] += 1;
                self.sums[b] += f64::from(z);
                Ok(true)
            }
            None => Ok(false),
        }
    }

    /// Counts a depth sample into a bin the caller already computed (`bin = bin_of(z)`, e.g.
    /// from a per-frame bin map), without re-validating it; a bin out of range is ignored.
    pub fn add_to_bin(&mut self, bin: usize, z: f32) {
        if let (Some(c), Some(s)) = (self.counts.get_mut(bin), self.sums.get_mut(bin)) {
            *c += 1;
            *s += f64::from(z);
        }
    }

    /// Histogram of the depth pixels in the rectangle `(x0, y0, x1, y1)` (exclusive ends, as
    /// `BBox::to_pixel_rect` returns).
    ///
    /// # Errors
    /// Invalid bins ([`DepthHistogram::new`]), a rectangle that is empty or exceeds the plane,
    /// a malformed plane, or a negative / infinite depth pixel.
    pub fn from_plane(
        depth: &Plane<f32>,
        rect: (u32, u32, u32, u32),
        bin_m: f32,
        n_bins: usize,
    ) -> Result<Self, VisionError> {
        let mut h = Self::new(bin_m, n_bins)?;
        let (x0, y0, x1, y1) = rect;
        if x0 >= x1 || y0 >= y1 || x1 > depth.width || y1 > depth.height {
            return Err(CoreError::invalid(
                "rect",
                format!(
                    "({x0}, {y0}, {x1}, {y1}) is empty or exceeds the {}x{} plane",
                    depth.width, depth.height
                ),
            )
            .into());
        }
        quarry_core::ensure_len(
            depth.data.len(),
            depth.width as usize * depth.height as usize,
            "depth plane data",
        )?;
        for y in y0..y1 {
            let row = depth.row(y);
            for &z in &row[x0 as usize..x1 as usize] {
                h.add(z)?;
            }
        }
        Ok(h)
    }

    /// Smoothed count `h̃(u) = q(u−1) + q(u) + q(u+1)` (missing neighbours count 0).
    #[must_use]
    pub fn smoothed(&self, u: usize) -> u32 {
        let n = self.counts.len();
        if u >= n {
            return 0;
        }
        let lo = u.saturating_sub(1);
        let hi = (u + 1).min(n - 1);
        self.counts[lo..=hi].iter().sum()
    }

    /// The argmax of the smoothed histogram (spec 001 §2.2), optionally restricted to bins whose
    /// centre lies in the gate `|(u + ½)·bin_m − z_pred| ≤ g` with `gate = Some((z_pred, g))`.
    /// Ties go to the bin with the larger raw count `q(u)` (so a single-bin spike peaks at its own
    /// bin, not its neighbour), then to the lowest (nearest) bin. `None` when no eligible bin has a
    /// non-zero smoothed
    /// count. The `0.05 · area` acceptance test is left to the caller (it knows the box area).
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] / [`CoreError::InvalidParameter`] for a non-finite gate or `g < 0`.
    pub fn peak_smoothed(
        &self,
        gate: Option<(f32, f32)>,
    ) -> Result<Option<DepthPeak>, VisionError> {
        if let Some((z, g)) = gate {
            if !(z.is_finite() && g.is_finite()) {
                return Err(CoreError::NonFinite { what: "depth gate" }.into());
            }
            if g < 0.0 {
                return Err(
                    CoreError::invalid("gate width", format!("must be ≥ 0, got {g}")).into(),
                );
            }
        }
        let mut best: Option<(usize, u32, u32)> = None;
        for u in 0..self.counts.len() {
            if let Some((z, g)) = gate {
                #[allow(clippy::cast_precision_loss)]
                let centre = (u as f32 + 0.5) * self.bin_m;
                if (centre - z).abs() > g {
                    continue;
                }
            }
            let s = self.smoothed(u);
            let q = self.counts[u];
            if s > 0 && best.is_none_or(|(_, bs, bq)| (s, q) > (bs, bq)) {
                best = Some((u, s, q));
            }
        }
        Ok(best.map(|(bin, smoothed, _)| {
            let lo = bin.saturating_sub(1);
            let hi = (bin + 1).min(self.counts.len() - 1);
            let sum: f64 = self.sums[lo..=hi].iter().sum();
            #[allow(clippy::cast_possible_truncation)]
            let z_star = (sum / f64::from(smoothed)) as f32;
            DepthPeak {
                bin,
                smoothed,
                z_star,
            }
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn normalise_and_errors() {
        let h = Histogram::from_weights(&[2.0, 0.0, 6.0]).unwrap();
        assert_eq!(h.bins(), &[0.25, 0.0, 0.75]);
        assert_eq!(h.len(), 3);
        assert!(Histogram::from_weights(&[]).is_err());
        assert!(Histogram::from_weights(&[0.0, 0.0]).is_err());
        assert!(Histogram::from_weights(&[1.0, -0.1]).is_err());
        assert!(Histogram::from_weights(&[1.0, f32::NAN]).is_err());
        let g = Histogram::from_weights(&[1.0, 1.0]).unwrap();
        assert!(h.cosine(&g).is_err());
        assert!(h.bhattacharyya(&g).is_err());
    }

    #[test]
    fn known_similarities() {
        assert_eq!(cosine(&[1.0, 0.0], &[0.0, 1.0]).unwrap(), 0.0);
        let c = cosine(&[1.0, 1.0], &[1.0, 0.0]).unwrap();
        assert!((c - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6);
        assert_eq!(cosine(&[], &[]).unwrap(), 0.0);
        assert_eq!(cosine(&[0.0, 0.0], &[1.0, 2.0]).unwrap(), 0.0);
        let b = bhattacharyya(&[0.5, 0.5], &[1.0, 0.0]).unwrap();
        assert!((b - 0.5f32.sqrt()).abs() < 1e-6);
        assert!(cosine(&[1.0], &[1.0, 2.0]).is_err());
        assert!(cosine(&[-1.0], &[1.0]).is_err());
    }

    #[test]
    fn depth_histogram_basics() {
        let mut h = DepthHistogram::paper();
        assert!(!h.add(0.0).unwrap());
        assert!(!h.add(f32::NAN).unwrap());
        assert!(!h.add(8.0).unwrap());
        assert!(h.add(-1.0).is_err());
        assert!(h.add(f32::INFINITY).is_err());
        assert!(h.add(0.05).unwrap());
        assert!(h.add(7.99).unwrap());
        assert_eq!(h.counts()[0], 1);
        assert_eq!(h.counts()[79], 1);
        assert_eq!(h.total(), 2);
        assert_eq!(h.smoothed(0), 1);
        assert_eq!(h.smoothed(78), 1);
        assert_eq!(h.smoothed(80), 0);
        assert!(DepthHistogram::new(0.0, 80).is_err());
        assert!(DepthHistogram::new(f32::NAN, 80).is_err());
        assert!(DepthHistogram::new(0.1, 0).is_err());
        assert_eq!(DepthHistogram::paper().peak_smoothed(None).unwrap(), None);
        assert!(h.peak_smoothed(Some((f32::NAN, 1.0))).is_err());
        assert!(h.peak_smoothed(Some((1.0, -1.0))).is_err());
        let d = Plane::new(4, 4, 1.0f32);
        assert!(DepthHistogram::from_plane(&d, (0, 0, 5, 4), 0.1, 80).is_err());
        assert!(DepthHistogram::from_plane(&d, (2, 0, 2, 4), 0.1, 80).is_err());
    }

    #[test]
    fn gated_peak_picks_target_not_occluder() {
        // occluder at 1.2 m (60 px), target at 3.0 m (40 px), background 6 m (100 px)
        let mut h = DepthHistogram::paper();
        for _ in 0..60 {
            h.add(1.25).unwrap();
        }
        for _ in 0..40 {
            h.add(3.05).unwrap();
        }
        for _ in 0..100 {
            h.add(6.05).unwrap();
        }
        assert_eq!(h.peak_smoothed(None).unwrap().unwrap().bin, 60);
        let p = h.peak_smoothed(Some((3.0, 0.5))).unwrap().unwrap();
        assert_eq!(p.bin, 30); // bins 29..31 all see the 40 px; the raw count breaks the tie
        assert_eq!(p.smoothed, 40);
        assert!((p.z_star - 3.05).abs() < 1e-5);
        assert_eq!(h.peak_smoothed(Some((4.5, 0.3))).unwrap(), None);
    }

    fn vecs() -> impl Strategy<Value = (Vec<f32>, Vec<f32>)> {
        (1usize..24).prop_flat_map(|n| {
            (
                proptest::collection::vec(0.0f32..10.0, n),
                proptest::collection::vec(0.0f32..10.0, n),
            )
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        /// Spec 001 §6.1.2.
        #[test]
        fn cosine_properties((a, b) in vecs(), alpha in 0.01f32..100.0, beta in 0.01f32..100.0) {
            let r = cosine(&a, &b).unwrap();
            prop_assert!((0.0..=1.0).contains(&r));
            prop_assert_eq!(r, cosine(&b, &a).unwrap());
            let a2: Vec<f32> = a.iter().map(|x| x * alpha).collect();
            let b2: Vec<f32> = b.iter().map(|x| x * beta).collect();
            prop_assert!((cosine(&a2, &b2).unwrap() - r).abs() < 1e-5);
            if a.iter().any(|&x| x > 0.0) {
                prop_assert!((cosine(&a, &a).unwrap() - 1.0).abs() < 1e-6);
                let h = Histogram::from_weights(&a).unwrap();
                let s: f32 = h.bins().iter().sum();
                prop_assert!((s - 1.0).abs() < 1e-5);
                prop_assert!(h.bins().iter().all(|&x| x >= 0.0));
                prop_assert!((h.bhattacharyya(&h).unwrap() - 1.0).abs() < 1e-5);
            } else {
                prop_assert_eq!(r, 0.0);
            }
            let bc = bhattacharyya(&a, &b).unwrap();
            prop_assert!((0.0..=1.0).contains(&bc));
            prop_assert!((bc - bhattacharyya(&b, &a).unwrap()).abs() < 1e-6);
        }

        /// The peak is the brute-force argmax of the smoothed counts among gated bins, and Z* lies
        /// in its three bins.
        #[test]
        fn peak_is_gated_argmax(zs in proptest::collection::vec(0.0f32..9.0, 0..200),
                                gz in 0.0f32..8.0, g in 0.0f32..2.0, use_gate in any::<bool>()) {
            let mut h = DepthHistogram::paper();
            let mut counted = 0u64;
            for &z in &zs {
                if h.add(z).unwrap() { counted += 1; }
            }
            prop_assert_eq!(h.total(), counted);
            prop_assert_eq!(counted, zs.iter().filter(|&&z| z > 0.0 && z < 8.0 - 1e-4).count() as u64
                + zs.iter().filter(|&&z| (8.0 - 1e-4..8.0).contains(&z)).filter(|&&z| h.bin_of(z).unwrap().is_some()).count() as u64);
            let gate = use_gate.then_some((gz, g));
            let eligible = |u: usize| gate.is_none_or(|(z, g)| ((u as f32 + 0.5) * 0.1 - z).abs() <= g);
            let best = (0..80).filter(|&u| eligible(u)).map(|u| h.smoothed(u)).max().unwrap_or(0);
            match h.peak_smoothed(gate).unwrap() {
                None => prop_assert_eq!(best, 0),
                Some(p) => {
                    prop_assert!(eligible(p.bin));
                    prop_assert_eq!(p.smoothed, best);
                    let q = h.counts()[p.bin];
                    prop_assert!((0..80).filter(|&u| eligible(u) && h.smoothed(u) == best).all(|u| h.counts()[u] <= q));
                    prop_assert!((0..p.bin).filter(|&u| eligible(u) && h.smoothed(u) == best).all(|u| h.counts()[u] < q));
                    let lo = p.bin.saturating_sub(1) as f32 * 0.1;
                    let hi = (p.bin + 2) as f32 * 0.1;
                    prop_assert!(p.z_star >= lo - 1e-5 && p.z_star < hi + 1e-5, "{:?}", p);
                }
            }
        }
    }
}
