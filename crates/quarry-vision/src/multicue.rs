//! The patch-based multi-cue appearance model of spec 001 (eqs. 4-8, 12) and the whole-target
//! colour-texture baseline (the role of the paper's reference \[12\], spec §5.5).
//!
//! * [`RgbdFeatures`]: the per-frame maps (hue bin, LBP class, depth in metres), computed once per
//!   frame over a region of interest (the union of the candidate boxes), not the whole image.
//! * [`PatchMultiCueModel`]: the template (N×N patches, colour + texture histogram each, the
//!   valid set `V`), [`PatchMultiCueModel::describe_box`] (depth histogram → `Z*` → depth band →
//!   patch histograms and occlusion indicators, §§2.2, 2.4, 2.5, 2.7),
//!   [`PatchMultiCueModel::score_descriptor`] (eqs. 6-8 and the pass fractions) and
//!   [`PatchMultiCueModel::learn_counted`] (eq. 12). It implements
//!   [`quarry_core::AppearanceModel`], so a third party can use it without the tracker.
//! * [`PatchModelConfig::whole_target_baseline`]: N = 1, image-plane Epanechnikov kernel over the
//!   whole box, no depth mask: the same histograms, so only the representation differs.
//!
//! ```
//! use quarry_core::{AppearanceModel, BBox, Plane};
//! use quarry_vision::multicue::{PatchModelConfig, PatchMultiCueModel, RgbdFeatures};
//! // A 120×120 frame: a striped "person" 2 m away in front of a grey wall 5 m away.
//! let (w, h) = (120u32, 120u32);
//! let person = |x: u32, y: u32| (40..80).contains(&x) && (10..110).contains(&y);
//! let mut rgb = Vec::new();
//! for y in 0..h {
//!     for x in 0..w {
//!         let c = if person(x, y) { if (y / 6) % 2 == 0 { [40, 90, 200] } else { [220, 180, 60] } } else { [128, 128, 128] };
//!         rgb.extend_from_slice(&c);
//!     }
//! }
//! let depth = Plane::from_fn(w, h, |x, y| if person(x, y) { 2.0f32 } else { 5.0 });
//! let f = RgbdFeatures::new(w, h, &rgb, &depth, None, &PatchModelConfig::default())?;
//! let target = BBox::from_ltwh(40.0, 10.0, 40.0, 100.0);
//! let model = PatchMultiCueModel::new(PatchModelConfig::default(), &f, &target, &target)?;
//! let on = model.score(&model.describe(&f, &target)?);
//! let off = model.score(&model.describe(&f, &BBox { cx: 95.0, ..target })?);
//! assert!(on.m > 0.9 && on.s > off.s);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use crate::colour::{HueBinner, rgb_to_grey, rgb_to_hsv};
use crate::depth_weights::DepthProfile;
use crate::histogram::{DepthHistogram, Histogram, bhattacharyya, cosine};
use crate::lbp::{LBP_NO_CLASS, LbpMapping};
use crate::patches::{PatchCell, PatchGrid, PatchHistograms, min_weight};
use quarry_core::{AppearanceModel, BBox, CoreError, Plane};
use serde::{Deserialize, Serialize};

/// How per-patch similarities are combined into a cue score (spec I1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Aggregate {
    /// Eq. (7) as the spec corrects it: `Σ_{n∈V} ρ̃²/(1 − ρ̃²)` with `ρ̃ = min(ρ, ρ_max)`.
    #[default]
    CotSquared,
    /// `|V|⁻¹ Σ ρ²`, bounded in `[0, 1]`.
    MeanSquare,
}

/// The per-patch histogram similarity (eq. 6 or its Bhattacharyya alternative).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Similarity {
    /// Cosine similarity, eq. (6).
    #[default]
    Cosine,
    /// Bhattacharyya coefficient (Comaniciu, Ramesh & Meer 2003).
    Bhattacharyya,
}

/// Parameters of the appearance model. `Default` = the spec's `paper()` values (§3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PatchModelConfig {
    /// Patches per side N (spec default 4, an unstated paper value).
    pub n: u32,
    /// Depth histogram bin width Δ_d, metres (0.1, spec resolution).
    pub depth_bin_m: f32,
    /// Number of depth bins (80, over [0, 8) m).
    pub depth_bins: usize,
    /// Depth band half-width τ_z, metres (0.3, resolution I10).
    pub tau_z: f32,
    /// Profile `g` inside the band (flat = the paper).
    pub depth_profile: DepthProfile,
    /// Use the depth kernel (eq. 5). `false` = the `no_depth_kernel` ablation / baseline.
    pub depth_kernel: bool,
    /// Multiply in the image-plane Epanechnikov kernel over each patch (baseline only).
    pub spatial_kernel: bool,
    /// Hue bins (16).
    pub hue_bins: u8,
    /// Achromatic value bins (4; 0 = the paper's hue-only histogram).
    pub achromatic_bins: u8,
    /// Saturation / value threshold of a chromatic pixel (0.15).
    pub sv_min: f32,
    /// LBP mapping (riu2, 10 classes).
    pub lbp: LbpMapping,
    /// Patch threshold `th` (0.8).
    pub th: f32,
    /// Cosine clamp ρ_max (0.99, resolution I1).
    pub rho_max: f32,
    /// Cue aggregation (eq. 7).
    pub aggregate: Aggregate,
    /// Patch similarity (eq. 6).
    pub similarity: Similarity,
    /// Template-valid foreground fraction `f_min` (0.2).
    pub f_min: f32,
    /// Occluder flag threshold `o_min` (0.10 of the box pixels with depth).
    pub o_min: f32,
    /// A candidate has no target depth when `h̃(u*) < peak_min · area` (0.05).
    pub peak_min: f32,
    /// Template update rate η ∈ (0, 1] (1 = literal eq. 12).
    pub update_rate: f32,
    /// Pixel stride when sampling patches (1; 2 is the speed option).
    pub stride: u32,
}

impl Default for PatchModelConfig {
    fn default() -> Self {
        Self {
            n: 4,
            depth_bin_m: 0.1,
            depth_bins: 80,
            tau_z: 0.3,
            depth_profile: DepthProfile::Flat,
            depth_kernel: true,
            spatial_kernel: false,
            hue_bins: 16,
            achromatic_bins: 4,
            sv_min: 0.15,
            lbp: LbpMapping::Riu2,
            th: 0.8,
            rho_max: 0.99,
            aggregate: Aggregate::CotSquared,
            similarity: Similarity::Cosine,
            f_min: 0.2,
            o_min: 0.10,
            peak_min: 0.05,
            update_rate: 1.0,
            stride: 1,
        }
    }
}

impl PatchModelConfig {
    /// The whole-target colour-texture baseline (spec §5.5): N = 1, Epanechnikov spatial kernel,
    /// no depth mask, same 20 + 10 bins.
    #[must_use]
    pub fn whole_target_baseline() -> Self {
        Self {
            n: 1,
            depth_kernel: false,
            spatial_kernel: true,
            ..Self::default()
        }
    }

    /// The colour binner these parameters describe.
    #[must_use]
    pub fn hue_binner(&self) -> HueBinner {
        HueBinner {
            hue_bins: self.hue_bins,
            achromatic_bins: self.achromatic_bins,
            s_min: self.sv_min,
            v_min: self.sv_min,
        }
    }

    /// Checks every parameter.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] naming the first parameter out of range.
    pub fn validate(&self) -> Result<(), VisionError> {
        self.hue_binner().validate()?;
        let bad = |name: &'static str, why: String| Err(CoreError::invalid(name, why).into());
        if !(1..=16).contains(&self.n) {
            return bad(
                "n",
                format!("patches per side must be in 1..=16, got {}", self.n),
            );
        }
        if !(self.depth_bin_m.is_finite() && self.depth_bin_m > 0.0) {
            return bad(
                "depth_bin_m",
                format!("must be > 0, got {}", self.depth_bin_m),
            );
        }
        if self.depth_bins == 0 || self.depth_bins > 10_000 {
            return bad(
                "depth_bins",
                format!("must be in 1..=10000, got {}", self.depth_bins),
            );
        }
        if !(self.tau_z.is_finite() && self.tau_z > 0.0) {
            return bad("tau_z", format!("must be > 0, got {}", self.tau_z));
        }
        for (name, x) in [
            ("th", self.th),
            ("f_min", self.f_min),
            ("o_min", self.o_min),
            ("peak_min", self.peak_min),
        ] {
            if !(0.0..=1.0).contains(&x) {
                return bad(name, format!("must lie in [0, 1], got {x}"));
            }
        }
        if !(self.rho_max > 0.0 && self.rho_max < 1.0) {
            return bad(
                "rho_max",
                format!("must lie in (0, 1), got {}", self.rho_max),
            );
        }
        if !(self.update_rate > 0.0 && self.update_rate <= 1.0) {
            return bad(
                "update_rate",
                format!("must lie in (0, 1], got {}", self.update_rate),
            );
        }
        if !(1..=8).contains(&self.stride) {
            return bad("stride", format!("must be in 1..=8, got {}", self.stride));
        }
        Ok(())
    }

    fn n_colour(&self) -> usize {
        self.hue_binner().n_bins()
    }
}

/// One registered RGB-D frame with the robot's motion since the previous frame (the RGB-D
/// person tracker's input; its time and index come in the `Stamp` passed to `step`).
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFrame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Interleaved RGB8, `width · height · 3` bytes.
    pub rgb: Vec<u8>,
    /// Depth in metres (0 or NaN = no depth), registered to the RGB image.
    pub depth_m: Plane<f32>,
    /// Robot motion over the interval ending at this frame.
    pub ego: quarry_core::EgoMotion,
}

impl RgbdFrame {
    /// A validated frame.
    ///
    /// # Errors
    /// [`VisionError::SizeMismatch`] when depth and RGB sizes differ, a dimension mismatch for an
    /// RGB buffer of the wrong length, [`VisionError::EmptyImage`] below 3×3, and
    /// [`CoreError::NonFinite`] for a non-finite ego-motion.
    pub fn new(
        width: u32,
        height: u32,
        rgb: Vec<u8>,
        depth_m: Plane<f32>,
        ego: quarry_core::EgoMotion,
    ) -> Result<Self, VisionError> {
        if width < 3 || height < 3 {
            return Err(VisionError::EmptyImage {
                what: "RgbdFrame",
                width,
                height,
                min: 3,
            });
        }
        quarry_core::ensure_len(
            rgb.len(),
            3 * width as usize * height as usize,
            "RGB buffer (width · height · 3)",
        )?;
        if depth_m.dimensions() != (width, height) {
            return Err(VisionError::SizeMismatch {
                what: "depth vs RGB",
                a: depth_m.dimensions(),
                b: (width, height),
            });
        }
        quarry_core::ensure_len(
            depth_m.data.len(),
            width as usize * height as usize,
            "depth plane data",
        )?;
        let ok = match ego {
            quarry_core::EgoMotion::None => true,
            quarry_core::EgoMotion::Velocity { v, omega } => v.is_finite() && omega.is_finite(),
            quarry_core::EgoMotion::Delta(p) => p.is_finite(),
        };
        if !ok {
            return Err(CoreError::NonFinite { what: "ego-motion" }.into());
        }
        Ok(Self {
            width,
            height,
            rgb,
            depth_m,
            ego,
        })
    }
}

/// Pixel-rectangle `(x0, y0, x1, y1)`, exclusive ends, inside the image.
pub type Rect = (u32, u32, u32, u32);

/// The per-frame maps of one RGB-D frame over a region of interest.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdFeatures {
    /// Full image width.
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// The region the maps cover, in image pixels.
    pub roi: Rect,
    /// Colour bin per ROI pixel ([`HueBinner::NO_BIN`] = none).
    pub hue_bin: Plane<u8>,
    /// LBP class per ROI pixel ([`LBP_NO_CLASS`] on the image border).
    pub lbp_class: Plane<u8>,
    /// Depth per ROI pixel, metres; 0 = no depth.
    pub depth_m: Plane<f32>,
    /// Depth-histogram bin per ROI pixel (eq. 1) for `depth_bins = (Δ_d, B_d)`;
    /// [`RgbdFeatures::NO_DEPTH_BIN`] = not counted (no depth, or beyond the last bin).
    pub depth_bin: Plane<u16>,
    /// The `(bin width, bin count)` of `depth_bin` (the configuration's).
    pub depth_bins: (f32, usize),
}

impl RgbdFeatures {
    /// `depth_bin` value of a pixel the depth histogram does not count.
    pub const NO_DEPTH_BIN: u16 = u16::MAX;

    /// Computes the maps of an interleaved RGB8 image (`width · height · 3` bytes) and a depth
    /// plane in metres (0 or NaN = no depth) over `roi` (the whole image for `None`; clipped to
    /// the image).
    ///
    /// # Errors
    /// [`VisionError::SizeMismatch`] when depth and RGB differ in size, a dimension mismatch for a
    /// short RGB buffer, [`VisionError::EmptyImage`] for an image below 3×3 or an ROI that misses
    /// the image, [`CoreError::InvalidParameter`] for negative or infinite depth, or an invalid
    /// configuration.
    pub fn new(
        width: u32,
        height: u32,
        rgb: &[u8],
        depth: &Plane<f32>,
        roi: Option<Rect>,
        cfg: &PatchModelConfig,
    ) -> Result<Self, VisionError> {
        cfg.validate()?;
        if width < 3 || height < 3 {
            return Err(VisionError::EmptyImage {
                what: "RgbdFeatures",
                width,
                height,
                min: 3,
            });
        }
        let npx = width as usize * height as usize;
        quarry_core::ensure_len(rgb.len(), 3 * npx, "RGB buffer (width · height · 3)")?;
        if depth.dimensions() != (width, height) {
            return Err(VisionError::SizeMismatch {
                what: "depth vs RGB",
                a: depth.dimensions(),
                b: (width, height),
            });
        }
        quarry_core::ensure_len(depth.data.len(), npx, "depth plane data")?;
        let (x0, y0, x1, y1) = roi.unwrap_or((0, 0, width, height));
        let (x0, y0, x1, y1) = (x0.min(width), y0.min(height), x1.min(width), y1.min(height));
        if x0 >= x1 || y0 >= y1 {
            return Err(VisionError::EmptyImage {
                what: "RgbdFeatures region of interest",
                width: x1.saturating_sub(x0),
                height: y1.saturating_sub(y0),
                min: 1,
            });
        }
        let binner = cfg.hue_binner();
        let table = cfg.lbp.table();
        let (rw, rh) = (x1 - x0, y1 - y0);
        let mut hue = Vec::with_capacity(rw as usize * rh as usize);
        let mut dep = Vec::with_capacity(rw as usize * rh as usize);
        let mut dbin = Vec::with_capacity(rw as usize * rh as usize);
        #[allow(clippy::cast_precision_loss)]
        let n_bins_f = cfg.depth_bins as f32;
        for y in y0..y1 {
            let row = y as usize * width as usize;
            for x in x0..x1 {
                let i = row + x as usize;
                let p = &rgb[3 * i..3 * i + 3];
                hue.push(bin_unchecked(&binner, p));
                let z = depth.data[i];
                if z.is_nan() || z == 0.0 {
                    dep.push(0.0);
                    dbin.push(Self::NO_DEPTH_BIN);
                } else if !z.is_finite() || z < 0.0 {
                    return Err(CoreError::invalid(
                        "depth",
                        format!(
                            "pixel ({x}, {y}) is {z}: depth must be ≥ 0 and finite (0/NaN = none)"
                        ),
                    )
                    .into());
                } else {
                    dep.push(z);
                    // as `DepthHistogram::bin_of`: floor(z / Δ_d), counted below B_d
                    // (z / Δ_d > 0, so truncation is the floor)
                    let b = z / cfg.depth_bin_m;
                    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                    dbin.push(if b < n_bins_f {
                        b as u16
                    } else {
                        Self::NO_DEPTH_BIN
                    });
                }
            }
        }
        // Grey over the ROI grown by one pixel (clipped), then Ojala codes.
        let (gx0, gy0) = (x0.saturating_sub(1), y0.saturating_sub(1));
        let (gx1, gy1) = ((x1 + 1).min(width), (y1 + 1).min(height));
        let gw = (gx1 - gx0) as usize;
        let mut grey = Vec::with_capacity(gw * (gy1 - gy0) as usize);
        for y in gy0..gy1 {
            let row = y as usize * width as usize;
            for x in gx0..gx1 {
                let i = 3 * (row + x as usize);
                grey.push(rgb_to_grey([rgb[i], rgb[i + 1], rgb[i + 2]]));
            }
        }
        let mut lbp = Vec::with_capacity(rw as usize * rh as usize);
        for y in y0..y1 {
            for x in x0..x1 {
                if x == 0 || y == 0 || x + 1 == width || y + 1 == height {
                    lbp.push(LBP_NO_CLASS);
                    continue;
                }
                let gx = (x - gx0) as usize;
                let gy = (y - gy0) as usize;
                let at = |dx: isize, dy: isize| {
                    grey[(gy.wrapping_add_signed(dy)) * gw + gx.wrapping_add_signed(dx)]
                };
                let c = at(0, 0);
                let code = u8::from(at(1, 0) >= c)
                    | u8::from(at(1, -1) >= c) << 1
                    | u8::from(at(0, -1) >= c) << 2
                    | u8::from(at(-1, -1) >= c) << 3
                    | u8::from(at(-1, 0) >= c) << 4
                    | u8::from(at(-1, 1) >= c) << 5
                    | u8::from(at(0, 1) >= c) << 6
                    | u8::from(at(1, 1) >= c) << 7;
                lbp.push(table[usize::from(code)]);
            }
        }
        Ok(Self {
            width,
            height,
            roi: (x0, y0, x1, y1),
            hue_bin: Plane::from_vec(rw, rh, hue)?,
            lbp_class: Plane::from_vec(rw, rh, lbp)?,
            depth_m: Plane::from_vec(rw, rh, dep)?,
            depth_bin: Plane::from_vec(rw, rh, dbin)?,
            depth_bins: (cfg.depth_bin_m, cfg.depth_bins),
        })
    }
}

fn bin_unchecked(b: &HueBinner, p: &[u8]) -> u8 {
    let c = rgb_to_hsv(p[0], p[1], p[2]);
    if c.s >= b.s_min && c.v >= b.v_min {
        // non-negative, so truncation is the floor (and avoids a libm call per pixel)
        let k = (c.h * f32::from(b.hue_bins) / 360.0).max(0.0);
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let k = (k as u32).min(u32::from(b.hue_bins) - 1);
        u8::try_from(k).unwrap_or(0)
    } else if b.achromatic_bins == 0 {
        HueBinner::NO_BIN
    } else {
        let a = (c.v * f32::from(b.achromatic_bins)).max(0.0);
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let a = (a as u32).min(u32::from(b.achromatic_bins) - 1);
        u8::try_from(u32::from(b.hue_bins) + a).unwrap_or(HueBinner::NO_BIN)
    }
}

/// Description of one candidate box: its patch histograms, target depth and occlusion
/// indicators (spec §2.7).
#[derive(Debug, Clone, PartialEq)]
pub struct PatchDescriptor {
    /// The described box.
    pub bbox: BBox,
    /// Patch histograms in grid order (`None` = empty patch).
    pub hist: PatchHistograms,
    /// Target depth `Z*`, metres; `None` = no target depth (every similarity is then 0 when the
    /// depth kernel is on).
    pub z_star: Option<f32>,
    /// Occluder fraction `o(c)`: occluder pixels / pixels with depth over the box.
    pub occluder_fraction: f32,
    /// Per patch: depth-occluded (≥ half of its depth pixels are occluders), out of view (less
    /// than half its area in the image) or empty.
    pub patch_blocked: Vec<bool>,
    /// Per patch: the fraction of its pixels that are foreground (`|Z − Z*| ≤ τ`).
    pub foreground_fraction: Vec<f32>,
    /// Some patch is out of view (counts as `D(c)` for T3 only).
    pub out_of_view: bool,
}

/// Score of one candidate against the template (eqs. 6-8, pass fractions, indicators).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CandidateScore {
    /// Colour score `S_Cd` (7).
    pub s_cd: f32,
    /// Texture score `S_Ld` (7).
    pub s_ld: f32,
    /// Overall score `S = S_Cd · S_Ld` (8).
    pub s: f32,
    /// Fraction of the scored patches with `ρ_n = ρ_Cd·ρ_Ld > th`.
    pub m: f32,
    /// Fraction with `ρ_Cd > th`.
    pub m_cd: f32,
    /// Fraction with `ρ_Ld > th`.
    pub m_ld: f32,
    /// Number of scored patches passing `ρ_n > th`.
    pub n_pass: usize,
    /// Number passing `ρ_Cd > th`.
    pub n_pass_cd: usize,
    /// Number passing `ρ_Ld > th`.
    pub n_pass_ld: usize,
    /// `[ρ_Cd, ρ_Ld]` per patch, grid order (0 for patches outside `V`).
    pub rho: Vec<[f32; 2]>,
    /// Depth occlusion flag `D(c) = o(c) ≥ o_min`.
    pub d_flag: bool,
    /// Unoccluded valid patches `U(c) = V \ O(c)`, per patch in grid order.
    pub unoccluded: Vec<bool>,
}

/// The patch multi-cue template and scorer (spec 001 §§2.2-2.7, 2.10).
#[derive(Debug, Clone, PartialEq)]
pub struct PatchMultiCueModel {
    cfg: PatchModelConfig,
    colour: Vec<Option<Histogram>>,
    texture: Vec<Option<Histogram>>,
    valid: Vec<bool>,
    z0: f32,
    gate: Option<(f32, f32)>,
}

impl PatchMultiCueModel {
    /// Builds the template (steps 1-2): `Z_0` from the depth peak over `depth_box` (ungated),
    /// then the patch histograms of `template_box` with the band at `Z_0`, and the valid set `V`
    /// (patches with at least `f_min` foreground pixels; every non-empty patch without the depth
    /// kernel).
    ///
    /// # Errors
    /// An invalid configuration, a box that is non-finite, smaller than `N` px a side or entirely
    /// outside the image or ROI, no depth peak in `depth_box` (e.g. all-zero depth) while the depth
    /// kernel is on, or fewer than `max(2, ⌈|V|/4⌉)`-worthy valid patches (`|V| = 0`, or `|V| < 2`
    /// for `N > 1`).
    pub fn new(
        cfg: PatchModelConfig,
        f: &RgbdFeatures,
        depth_box: &BBox,
        template_box: &BBox,
    ) -> Result<Self, VisionError> {
        cfg.validate()?;
        let mut m = Self {
            cfg,
            colour: Vec::new(),
            texture: Vec::new(),
            valid: Vec::new(),
            z0: 1.0,
            gate: None,
        };
        let z0 = m.target_depth(f, depth_box)?;
        let z0 = match (z0, cfg.depth_kernel) {
            (Some(z), _) => z,
            (None, false) => 1.0,
            (None, true) => {
                return Err(CoreError::invalid(
                    "init box",
                    "no target depth in the initial box (all-zero or out-of-range depth?)",
                )
                .into());
            }
        };
        m.z0 = z0;
        let d = m.describe_at(f, template_box, Some(z0))?;
        m.valid = if cfg.depth_kernel {
            d.foreground_fraction
                .iter()
                .zip(&d.hist.colour)
                .map(|(&fg, c)| fg >= cfg.f_min && c.is_some())
                .collect()
        } else {
            d.hist.colour.iter().map(Option::is_some).collect()
        };
        let nv = m.valid.iter().filter(|&&v| v).count();
        let need = if cfg.n > 1 { 2 } else { 1 };
        if nv < need {
            return Err(CoreError::invalid(
                "init box",
                format!(
                    "only {nv} valid template patches (need {need}): is the target in the box?"
                ),
            )
            .into());
        }
        m.colour = d.hist.colour;
        m.texture = d.hist.texture;
        Ok(m)
    }

    /// The configuration.
    #[must_use]
    pub fn config(&self) -> &PatchModelConfig {
        &self.cfg
    }

    /// Target depth of the template box, `Z_0`, metres.
    #[must_use]
    pub fn z0(&self) -> f32 {
        self.z0
    }

    /// The valid template patches `V`, grid order.
    #[must_use]
    pub fn valid(&self) -> &[bool] {
        &self.valid
    }

    /// `k_min = max(2, ⌈|V|/4⌉)` (1 for a single-patch model).
    #[must_use]
    pub fn k_min(&self) -> usize {
        let nv = self.valid.iter().filter(|&&v| v).count();
        if self.cfg.n == 1 {
            1
        } else {
            nv.div_ceil(4).max(2)
        }
    }

    /// The template histograms `(colour, texture)`, grid order.
    #[must_use]
    pub fn template(&self) -> (&[Option<Histogram>], &[Option<Histogram>]) {
        (&self.colour, &self.texture)
    }

    /// Sets the depth gate `(Ẑ⁻, G_z)` used by later descriptions (`None` = ungated).
    ///
    /// # Errors
    /// [`CoreError::NonFinite`] / [`CoreError::InvalidParameter`] for a non-finite gate or `G_z < 0`.
    pub fn set_depth_gate(&mut self, gate: Option<(f32, f32)>) -> Result<(), VisionError> {
        if let Some((z, g)) = gate {
            if !(z.is_finite() && g.is_finite()) {
                return Err(CoreError::NonFinite { what: "depth gate" }.into());
            }
            if g < 0.0 {
                return Err(CoreError::invalid("depth gate", format!("G_z = {g} < 0")).into());
            }
        }
        self.gate = gate;
        Ok(())
    }

    /// Target depth `Z*` of a box (§2.2): the smoothed depth peak, gated by the current depth gate,
    /// refined to the mean depth of bins `u*−1…u*+1`; `None` when the peak holds fewer than
    /// `peak_min · area` pixels.
    ///
    /// # Errors
    /// A non-finite or too small box.
    pub fn target_depth(&self, f: &RgbdFeatures, b: &BBox) -> Result<Option<f32>, VisionError> {
        let cells = PatchGrid::new(1)?.cells(b)?;
        let c = cells[0];
        let mut h = DepthHistogram::new(self.cfg.depth_bin_m, self.cfg.depth_bins)?;
        let (x0, y0, x1, y1) = clip(&c, f);
        let s = self.cfg.stride as usize;
        let (lo, hi) = ((x0 - f.roi.0) as usize, (x1 - f.roi.0) as usize);
        if f.depth_bins == (self.cfg.depth_bin_m, self.cfg.depth_bins) {
            // the per-frame bin map: no per-pixel division, floor or validation
            for y in (y0..y1).step_by(s) {
                let zr = &f.depth_m.row(y - f.roi.1)[lo..hi];
                let br = &f.depth_bin.row(y - f.roi.1)[lo..hi];
                let br = &br[..zr.len()];
                let mut x = 0;
                while x < zr.len() {
                    let b = br[x];
                    if b != RgbdFeatures::NO_DEPTH_BIN {
                        h.add_to_bin(usize::from(b), zr[x]);
                    }
                    x += s;
                }
            }
        } else {
            for y in (y0..y1).step_by(s) {
                let row = f.depth_m.row(y - f.roi.1);
                for &z in row[lo..hi].iter().step_by(s) {
                    h.add(z)?;
                }
            }
        }
        let Some(peak) = h.peak_smoothed(self.gate)? else {
            return Ok(None);
        };
        #[allow(clippy::cast_precision_loss)]
        let area = c.area() as f32 / (s * s) as f32;
        #[allow(clippy::cast_precision_loss)]
        if (peak.smoothed as f32) < self.cfg.peak_min * area {
            return Ok(None);
        }
        Ok(Some(peak.z_star))
    }

    /// Describes a box (§§2.2, 2.4, 2.5, 2.7): its target depth under the current gate, then the
    /// depth-masked patch histograms and the occlusion indicators.
    ///
    /// # Errors
    /// A non-finite box or one smaller than `N` px a side.
    pub fn describe_box(&self, f: &RgbdFeatures, b: &BBox) -> Result<PatchDescriptor, VisionError> {
        let z = self.target_depth(f, b)?;
        self.describe_at(f, b, z)
    }

    /// Describes a box with a given target depth (`None` = no target depth).
    ///
    /// # Errors
    /// As [`PatchMultiCueModel::describe_box`].
    #[allow(clippy::too_many_lines, clippy::cast_precision_loss)]
    pub fn describe_at(
        &self,
        f: &RgbdFeatures,
        b: &BBox,
        z_star: Option<f32>,
    ) -> Result<PatchDescriptor, VisionError> {
        let cfg = &self.cfg;
        let cells = PatchGrid::new(cfg.n)?.cells(b)?;
        let nc = cfg.n_colour();
        let nt = cfg.lbp.n_classes();
        let np = cells.len();
        let mut out = PatchDescriptor {
            bbox: *b,
            hist: PatchHistograms {
                colour: Vec::with_capacity(np),
                texture: Vec::with_capacity(np),
            },
            z_star,
            occluder_fraction: 0.0,
            patch_blocked: Vec::with_capacity(np),
            foreground_fraction: Vec::with_capacity(np),
            out_of_view: false,
        };
        let mut ca = vec![0.0f32; nc];
        let mut ta = vec![0.0f32; nt];
        // The paper's kernel (flat depth band, no image-plane kernel): every weight is 1, so the
        // histograms are integer counts (exact in f32 below 2^24, hence identical to the
        // general path) and a pixel needs one band test.
        let flat =
            cfg.depth_kernel && !cfg.spatial_kernel && cfg.depth_profile == DepthProfile::Flat;
        // indexed by the u8 codes directly (no bounds test); codes ≥ nc / nt are dropped below
        let mut cnt_c = [0u32; 256];
        let mut cnt_t = [0u32; 256];
        let edges = z_star.map(|zs| band_edges(zs, cfg.tau_z));
        let (mut box_occ, mut box_depth) = (0usize, 0usize);
        let tau = cfg.tau_z;
        let s = cfg.stride as usize;
        let sf = (s * s) as f32;
        for cell in &cells {
            ca.fill(0.0);
            ta.fill(0.0);
            let (x0, y0, x1, y1) = clip(cell, f);
            let inside = (x1.saturating_sub(x0) as usize) * (y1.saturating_sub(y0) as usize);
            let (mut occ, mut with_depth, mut fg) = (0usize, 0usize, 0usize);
            let (hu, hv) = (
                (cell.x1 - cell.x0) as f32 / 2.0,
                (cell.y1 - cell.y0) as f32 / 2.0,
            );
            let (cu, cv) = (
                (cell.x0 + cell.x1 - 1) as f32 / 2.0,
                (cell.y0 + cell.y1 - 1) as f32 / 2.0,
            );
            if flat {
                cnt_c.fill(0);
                cnt_t.fill(0);
                let (lo, hi) = ((x0 - f.roi.0) as usize, (x1 - f.roi.0) as usize);
                for y in (y0..y1).step_by(s) {
                    let ry = y - f.roi.1;
                    let zr = &f.depth_m.row(ry)[lo..hi];
                    let Some((z_lo, z_hi)) = edges else {
                        with_depth += zr.iter().step_by(s).filter(|&&z| z > 0.0).count();
                        continue;
                    };
                    let n = zr.len();
                    let hr = &f.hue_bin.row(ry)[lo..hi][..n];
                    let lr = &f.lbp_class.row(ry)[lo..hi][..n];
                    let mut x = 0;
                    while x < n {
                        let (z, c, t) = (zr[x], hr[x], lr[x]);
                        x += s;
                        if z > 0.0 {
                            with_depth += 1;
                            if z < z_lo {
                                occ += 1;
                            } else if z <= z_hi {
                                fg += 1;
                                cnt_c[usize::from(c)] += 1;
                                cnt_t[usize::from(t)] += 1;
                            }
                        }
                    }
                }
                for (a, &n) in ca.iter_mut().zip(&cnt_c) {
                    *a = n as f32;
                }
                for (a, &n) in ta.iter_mut().zip(&cnt_t) {
                    *a = n as f32;
                }
            }
            // the general path (Epanechnikov profiles, no depth kernel): per-pixel weights
            let general_rows = if flat { y1..y1 } else { y0..y1 };
            for y in general_rows.step_by(s) {
                let ry = (y - f.roi.1) as usize;
                let rw = f.depth_m.width as usize;
                let base = ry * rw;
                let dv = (y as f32 - cv) / hv;
                for x in (x0..x1).step_by(s) {
                    let i = base + (x - f.roi.0) as usize;
                    let z = f.depth_m.data[i];
                    let mut k = 1.0f32;
                    if z > 0.0 {
                        with_depth += 1;
                        if let Some(zs) = z_star {
                            let d = (z - zs) / tau;
                            if d < -1.0 {
                                occ += 1;
                                if cfg.depth_kernel {
                                    continue;
                                }
                            } else if d > 1.0 {
                                if cfg.depth_kernel {
                                    continue;
                                }
                            } else {
                                fg += 1;
                                if cfg.depth_profile == DepthProfile::Epanechnikov {
                                    k = 1.0 - d * d;
                                }
                            }
                        } else if cfg.depth_kernel {
                            continue;
                        }
                    } else if cfg.depth_kernel {
                        continue;
                    }
                    if cfg.spatial_kernel {
                        let du = (x as f32 - cu) / hu;
                        k *= (1.0 - du * du - dv * dv).max(0.0);
                    }
                    if k <= 0.0 {
                        continue;
                    }
                    let c = usize::from(f.hue_bin.data[i]);
                    if c < nc {
                        ca[c] += k;
                    }
                    let t = usize::from(f.lbp_class.data[i]);
                    if t < nt {
                        ta[t] += k;
                    }
                }
            }
            let m_min = min_weight(cell) / f64::from(sf);
            out.hist.colour.push(finish(&ca, m_min)?);
            out.hist.texture.push(finish(&ta, m_min)?);
            let area = cell.area().max(1) as f32;
            let out_of_view = (inside as f32) < 0.5 * area;
            out.out_of_view |= out_of_view;
            let blocked = out_of_view
                || (with_depth > 0 && 2 * occ >= with_depth)
                || out.hist.colour.last().is_some_and(Option::is_none);
            out.patch_blocked.push(blocked);
            out.foreground_fraction.push(fg as f32 * sf / area);
            box_occ += occ;
            box_depth += with_depth;
        }
        out.occluder_fraction = if box_depth > 0 {
            box_occ as f32 / box_depth as f32
        } else {
            0.0
        };
        if cfg.depth_kernel && z_star.is_none() {
            for h in out
                .hist
                .colour
                .iter_mut()
                .chain(out.hist.texture.iter_mut())
            {
                *h = None;
            }
        }
        Ok(out)
    }

    fn similarity(&self, p: Option<&Histogram>, q: Option<&Histogram>) -> f32 {
        match (p, q) {
            (Some(p), Some(q)) => match self.cfg.similarity {
                Similarity::Cosine => cosine(p.bins(), q.bins()),
                Similarity::Bhattacharyya => bhattacharyya(p.bins(), q.bins()),
            }
            .unwrap_or(0.0),
            _ => 0.0,
        }
    }

    /// φ of eq. (7) for one similarity (the clamped `ρ̃²/(1 − ρ̃²)`, or `ρ²` for mean-square).
    #[must_use]
    pub fn phi(&self, rho: f32) -> f32 {
        match self.cfg.aggregate {
            Aggregate::CotSquared => {
                let r = rho.clamp(0.0, self.cfg.rho_max);
                r * r / (1.0 - r * r)
            }
            Aggregate::MeanSquare => rho * rho,
        }
    }

    /// The cue score (eq. 7) of a candidate identical to the template over `n_scored` patches:
    /// `n_scored · φ(1)` (`φ(1)` for the mean-square aggregate, which is normalised). Used for
    /// the spec §8 guard on the texture-only tier.
    #[must_use]
    #[allow(clippy::cast_precision_loss)]
    pub fn cue_self_score(&self, n_scored: usize) -> f32 {
        match self.cfg.aggregate {
            Aggregate::CotSquared => self.phi(1.0) * n_scored as f32,
            Aggregate::MeanSquare => self.phi(1.0),
        }
    }

    /// Scores a descriptor over the valid patches `V` (eqs. 6-8, pass fractions).
    #[must_use]
    pub fn score_descriptor(&self, d: &PatchDescriptor) -> CandidateScore {
        self.score_over(d, &self.valid)
    }

    /// Scores a descriptor over a subset of the patches (e.g. `U(c)` for tier T3); patches outside
    /// `V` are never scored. Fractions are over the subset's size.
    #[must_use]
    #[allow(clippy::cast_precision_loss)]
    pub fn score_over(&self, d: &PatchDescriptor, subset: &[bool]) -> CandidateScore {
        let th = self.cfg.th;
        let np = self.valid.len();
        let mut s = CandidateScore {
            rho: vec![[0.0, 0.0]; np],
            d_flag: d.occluder_fraction >= self.cfg.o_min,
            unoccluded: self
                .valid
                .iter()
                .zip(&d.patch_blocked)
                .map(|(&v, &b)| v && !b)
                .collect(),
            ..CandidateScore::default()
        };
        if d.hist.colour.len() != np {
            return s;
        }
        let mut count = 0usize;
        for n in 0..np {
            if !(self.valid[n] && subset.get(n).copied().unwrap_or(false)) {
                continue;
            }
            count += 1;
            let rc = self.similarity(d.hist.colour[n].as_ref(), self.colour[n].as_ref());
            let rl = self.similarity(d.hist.texture[n].as_ref(), self.texture[n].as_ref());
            s.rho[n] = [rc, rl];
            s.s_cd += self.phi(rc);
            s.s_ld += self.phi(rl);
            s.n_pass_cd += usize::from(rc > th);
            s.n_pass_ld += usize::from(rl > th);
            s.n_pass += usize::from(rc * rl > th);
        }
        if count > 0 {
            if self.cfg.aggregate == Aggregate::MeanSquare {
                s.s_cd /= count as f32;
                s.s_ld /= count as f32;
            }
            s.m = s.n_pass as f32 / count as f32;
            s.m_cd = s.n_pass_cd as f32 / count as f32;
            s.m_ld = s.n_pass_ld as f32 / count as f32;
        }
        s.s = s.s_cd * s.s_ld;
        s
    }

    /// Template update (eq. 12) for every valid patch and cue independently: when the cue's
    /// similarity λ = ρ_{f,n} exceeds `th`, `q ← ηλ·p + (1 − ηλ)·q`. Returns how many (patch, cue)
    /// histograms changed. The caller decides whether to learn at all (occlusion gating).
    pub fn learn_counted(&mut self, d: &PatchDescriptor, s: &CandidateScore) -> usize {
        let th = self.cfg.th;
        let eta = self.cfg.update_rate;
        let mut changed = 0;
        for n in 0..self.valid.len() {
            if !self.valid[n] {
                continue;
            }
            let Some(r) = s.rho.get(n) else { continue };
            for (cue, lam) in [(0usize, r[0]), (1, r[1])] {
                if lam <= th {
                    continue;
                }
                let (tmpl, obs) = if cue == 0 {
                    (&mut self.colour[n], d.hist.colour.get(n))
                } else {
                    (&mut self.texture[n], d.hist.texture.get(n))
                };
                let (Some(q), Some(Some(p))) = (tmpl.as_mut(), obs) else {
                    continue;
                };
                let a = eta * lam;
                let w: Vec<f32> = p
                    .bins()
                    .iter()
                    .zip(q.bins())
                    .map(|(&pu, &qu)| a * pu + (1.0 - a) * qu)
                    .collect();
                if let Ok(h) = Histogram::from_weights(&w) {
                    *q = h;
                    changed += 1;
                }
            }
        }
        changed
    }
}

/// The exact f32 edges of the depth band: for every f32 `z`, `(z − zs)/τ < −1` ⟺ `z < lo` and
/// `(z − zs)/τ ≤ 1` ⟺ `z ≤ hi`. Both sides are monotone in `z` under rounding, so each edge is
/// found by bisection over the ordered f32 values between `zs ∓ 2τ` and `zs` (exact whatever
/// the ulp scale: near 0 one rounding step of `z − zs` spans hundreds of ulps of `z`, which an
/// ulp-by-ulp walk from `zs ∓ τ` did not always cover). The band test then needs no
/// subtraction or division per pixel and classifies every pixel exactly as the formula does.
fn band_edges(zs: f32, tau: f32) -> (f32, f32) {
    let d = |z: f32| (z - zs) / tau;
    // f32 -> u32 preserving the order of finite values, and back
    let key = |x: f32| {
        let b = x.to_bits();
        if b & 0x8000_0000 != 0 {
            !b
        } else {
            b | 0x8000_0000
        }
    };
    let val = |k: u32| {
        f32::from_bits(if k & 0x8000_0000 != 0 {
            k & 0x7fff_ffff
        } else {
            !k
        })
    };
    // smallest z in (a, b] with pred(z), given !pred(a) and pred(b), pred monotone
    let first_true = |a: f32, b: f32, pred: &dyn Fn(f32) -> bool| {
        let (mut lo, mut hi) = (key(a), key(b));
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if pred(val(mid)) { hi = mid } else { lo = mid }
        }
        val(hi)
    };
    let lo = first_true(zs - 2.0 * tau, zs, &|z| d(z) >= -1.0);
    // the largest z with d(z) <= 1 is the one below the smallest with d(z) > 1
    let above = first_true(zs, zs + 2.0 * tau, &|z| d(z) > 1.0);
    (lo, val(key(above) - 1))
}

fn finish(acc: &[f32], m_min: f64) -> Result<Option<Histogram>, VisionError> {
    let sum: f64 = acc.iter().map(|&x| f64::from(x)).sum();
    if sum < m_min || sum <= 0.0 {
        return Ok(None);
    }
    #[allow(clippy::cast_possible_truncation)]
    let w: Vec<f32> = acc.iter().map(|&x| (f64::from(x) / sum) as f32).collect();
    Histogram::from_weights(&w).map(Some)
}

/// A cell clipped to the image and the features' ROI.
#[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
fn clip(c: &PatchCell, f: &RgbdFeatures) -> Rect {
    let (rx0, ry0, rx1, ry1) = f.roi;
    let cx = |v: i64| v.clamp(i64::from(rx0), i64::from(rx1)) as u32;
    let cy = |v: i64| v.clamp(i64::from(ry0), i64::from(ry1)) as u32;
    (cx(c.x0), cy(c.y0), cx(c.x1), cy(c.y1))
}

fn into_core(e: VisionError) -> CoreError {
    match e {
        VisionError::Core(c) => c,
        other => CoreError::invalid("frame", other.to_string()),
    }
}

impl AppearanceModel for PatchMultiCueModel {
    type FrameFeatures = RgbdFeatures;
    type Descriptor = PatchDescriptor;
    type Score = CandidateScore;

    fn describe(&self, f: &RgbdFeatures, region: &BBox) -> Result<PatchDescriptor, CoreError> {
        self.describe_box(f, region).map_err(into_core)
    }

    fn score(&self, d: &PatchDescriptor) -> CandidateScore {
        self.score_descriptor(d)
    }

    fn learn(&mut self, d: &PatchDescriptor, s: &CandidateScore) {
        self.learn_counted(d, s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A frame with a two-colour striped target at `z_t` over columns `tx..tx+tw`, an optional
    /// occluder at `z_o` over `ox..ox+ow`, a grey background at 5 m.
    fn frame(tx: u32, ox: Option<u32>) -> (u32, u32, Vec<u8>, Plane<f32>) {
        let (w, h) = (160u32, 140u32);
        let mut rgb = Vec::new();
        let mut dep = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let occ = ox.is_some_and(|o| (o..o + 30).contains(&x));
                let tgt = (tx..tx + 40).contains(&x) && (10..130).contains(&y);
                let (c, z) = if occ {
                    ([200u8, 30, 30], 1.5f32)
                } else if tgt {
                    let c = if (y / 6) % 2 == 0 {
                        [40, 90, 200]
                    } else {
                        [220, 180, 60]
                    };
                    (c, 2.5)
                } else {
                    let g = u8::try_from(100 + (x * 7 + y * 13) % 50).unwrap();
                    ([g, g, g], 5.0)
                };
                rgb.extend_from_slice(&c);
                dep.push(z);
            }
        }
        (w, h, rgb, Plane::from_vec(w, h, dep).unwrap())
    }

    fn feats(tx: u32, ox: Option<u32>, cfg: &PatchModelConfig) -> RgbdFeatures {
        let (w, h, rgb, d) = frame(tx, ox);
        RgbdFeatures::new(w, h, &rgb, &d, None, cfg).unwrap()
    }

    #[test]
    fn detects_target_and_occlusion() {
        let cfg = PatchModelConfig::default();
        let f = feats(50, None, &cfg);
        let b = BBox::from_ltwh(50.0, 10.0, 40.0, 120.0);
        let m = PatchMultiCueModel::new(cfg, &f, &b, &b).unwrap();
        assert!((m.z0() - 2.5).abs() < 0.01);
        assert_eq!(m.valid().iter().filter(|&&v| v).count(), 16);
        let s = m.score_descriptor(&m.describe_box(&f, &b).unwrap());
        assert_eq!(s.m, 1.0);
        assert!(!s.d_flag);
        // moved target: the box at the new place scores, the old place does not
        let f2 = feats(80, None, &cfg);
        let here = m.score_descriptor(&m.describe_box(&f2, &BBox { cx: 100.0, ..b }).unwrap());
        let there = m.score_descriptor(&m.describe_box(&f2, &b).unwrap());
        assert!(here.s > there.s);
        assert!(here.m >= 0.8);
        // half occluded: D flag, unoccluded patches are the uncovered columns, still matching
        let f3 = feats(50, Some(50), &cfg);
        // ungated, the occluder (3/4 of the box) would own the depth peak (I7)
        assert!(m.target_depth(&f3, &b).unwrap().unwrap() < 2.0);
        let mut m = m;
        m.set_depth_gate(Some((2.5, 0.5))).unwrap();
        let d = m.describe_box(&f3, &b).unwrap();
        let s = m.score_descriptor(&d);
        assert!(s.d_flag);
        assert!(s.m < 0.8);
        let u = s.unoccluded.iter().filter(|&&x| x).count();
        assert!((4..=12).contains(&u), "{u}");
        let su = m.score_over(&d, &s.unoccluded);
        assert!(su.m >= 0.8, "{su:?}");
    }

    #[test]
    fn baseline_and_bad_input() {
        let cfg = PatchModelConfig::whole_target_baseline();
        let f = feats(50, None, &cfg);
        let b = BBox::from_ltwh(50.0, 10.0, 40.0, 120.0);
        let m = PatchMultiCueModel::new(cfg, &f, &b, &b).unwrap();
        assert_eq!(m.valid().len(), 1);
        let s = m.score_descriptor(&m.describe_box(&f, &b).unwrap());
        assert!(s.m == 1.0 && s.s > 0.0);
        // errors, never panics
        let (w, h, rgb, d) = frame(50, None);
        let c = PatchModelConfig::default();
        assert!(RgbdFeatures::new(w, h - 1, &rgb, &d, None, &c).is_err());
        assert!(RgbdFeatures::new(w, h, &rgb[1..], &d, None, &c).is_err());
        assert!(RgbdFeatures::new(w, h, &rgb, &d, Some((500, 500, 600, 600)), &c).is_err());
        let neg = Plane::new(w, h, -1.0f32);
        assert!(RgbdFeatures::new(w, h, &rgb, &neg, None, &c).is_err());
        let zero = Plane::new(w, h, 0.0f32);
        let fz = RgbdFeatures::new(w, h, &rgb, &zero, None, &c).unwrap();
        assert!(PatchMultiCueModel::new(c, &fz, &b, &b).is_err());
        let f = feats(50, None, &c);
        let m = PatchMultiCueModel::new(c, &f, &b, &b).unwrap();
        assert!(m.describe_box(&f, &BBox { w: 0.0, ..b }).is_err());
        assert!(m.describe_box(&f, &BBox { cx: f64::NAN, ..b }).is_err());
        // far outside: every patch blocked, zero score
        let d = m.describe_box(&f, &BBox { cx: -500.0, ..b }).unwrap();
        let s = m.score_descriptor(&d);
        assert!(d.out_of_view && s.s == 0.0 && s.m == 0.0);
        assert!(PatchMultiCueModel::new(PatchModelConfig { n: 0, ..c }, &f, &b, &b).is_err());
        assert!(PatchMultiCueModel::new(PatchModelConfig { th: 2.0, ..c }, &f, &b, &b).is_err());
    }

    #[test]
    fn band_edges_hold_where_the_lower_edge_is_just_below_zero() {
        let (zs, tau) = (0.640_141_96_f32, 0.643_665_97_f32);
        let (lo, hi) = band_edges(zs, tau);
        let d = |z: f32| (z - zs) / tau;
        assert!(d(lo) >= -1.0 && d(lo.next_down()) < -1.0, "lo {lo}");
        assert!(d(hi) <= 1.0 && d(hi.next_up()) > 1.0, "hi {hi}");
        let mut z = lo;
        for _ in 0..600 {
            z = z.next_down();
            assert!(z < lo && d(z) < -1.0 || d(z) >= -1.0 && z >= lo, "z {z}");
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// §6.1.3: φ finite, non-negative, non-decreasing, equals ρ²/(1−ρ²) below ρ_max.
        #[test]
        fn phi_props(a in 0.0f32..1.0, b in 0.0f32..1.0) {
            let f = feats(50, None, &PatchModelConfig::default());
            let bx = BBox::from_ltwh(50.0, 10.0, 40.0, 120.0);
            let m = PatchMultiCueModel::new(PatchModelConfig::default(), &f, &bx, &bx).unwrap();
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(m.phi(lo).is_finite() && m.phi(lo) >= 0.0);
            prop_assert!(m.phi(lo) <= m.phi(hi));
            if hi <= 0.99 {
                prop_assert!((m.phi(hi) - hi * hi / (1.0 - hi * hi)).abs() <= 1e-4 * (1.0 + m.phi(hi)));
            }
            prop_assert!(m.phi(1.0) <= 49.26);
        }

        /// §6.1.10: λ ≤ th leaves the template bit-identical; otherwise each entry is between the
        /// old template's and the observation's, and the histogram stays normalised.
        #[test]
        fn update_is_convex(shift in 0u32..30, occl in proptest::option::of(40u32..100)) {
            let cfg = PatchModelConfig::default();
            let f = feats(50, None, &cfg);
            let bx = BBox::from_ltwh(50.0, 10.0, 40.0, 120.0);
            let mut m = PatchMultiCueModel::new(cfg, &f, &bx, &bx).unwrap();
            let g = feats(50 + shift, occl, &cfg);
            let d = m.describe_box(&g, &bx).unwrap();
            let s = m.score_descriptor(&d);
            let before = m.clone();
            let changed = m.learn_counted(&d, &s);
            let mut seen = 0;
            for n in 0..16 {
                for cue in 0..2 {
                    let (old, new, obs) = if cue == 0 {
                        (&before.colour[n], &m.colour[n], &d.hist.colour[n])
                    } else {
                        (&before.texture[n], &m.texture[n], &d.hist.texture[n])
                    };
                    if s.rho[n][cue] <= cfg.th || obs.is_none() {
                        prop_assert_eq!(old, new);
                        continue;
                    }
                    seen += 1;
                    let (old, new, obs) = (old.as_ref().unwrap(), new.as_ref().unwrap(), obs.as_ref().unwrap());
                    let sum: f32 = new.bins().iter().sum();
                    prop_assert!((sum - 1.0).abs() < 1e-5);
                    for ((&o, &nw), &p) in old.bins().iter().zip(new.bins()).zip(obs.bins()) {
                        prop_assert!(nw >= o.min(p) - 1e-6 && nw <= o.max(p) + 1e-6);
                    }
                }
            }
            prop_assert_eq!(seen, changed);
        }

        /// The precomputed band edges classify every depth exactly as `(z − Z*)/τ` does.
        /// (Z* < τ puts the lower edge just below 0, where one rounding step of `z − Z*` spans
        /// hundreds of ulps of `z`: a case the first, ulp-walking version got wrong; CI seed
        /// zs = 0.64014196, τ = 0.64366597.)
        #[test]
        fn band_edges_are_exact(zs in 0.05f32..8.0, tau in 0.01f32..1.0, t in -2.0f32..2.0, k in -3i32..=3) {
            let (lo, hi) = band_edges(zs, tau);
            // around both edges, a few ulps either side, and a random depth
            let mut zs_to_test = vec![zs + t * tau];
            for e in [lo, hi] {
                let mut z = e;
                for _ in 0..k.unsigned_abs() {
                    z = if k < 0 { z.next_down() } else { z.next_up() };
                }
                zs_to_test.extend([z, z.next_up(), z.next_down()]);
            }
            for z in zs_to_test {
                let d = (z - zs) / tau;
                prop_assert_eq!(z < lo, d < -1.0, "z {} lo {}", z, lo);
                prop_assert_eq!(z <= hi, d <= 1.0, "z {} hi {}", z, hi);
            }
        }

        /// Scores are non-negative, fractions in [0, 1], deterministic.
        #[test]
        fn scores_well_formed(cx in -40.0f64..200.0, cy in -40.0f64..180.0, w in 4.0f64..120.0, h in 4.0f64..160.0) {
            let cfg = PatchModelConfig::default();
            let f = feats(50, Some(70), &cfg);
            let bx = BBox::from_ltwh(50.0, 10.0, 40.0, 120.0);
            let m = PatchMultiCueModel::new(cfg, &f, &bx, &bx).unwrap();
            let c = BBox { cx, cy, w, h };
            let d = m.describe_box(&f, &c).unwrap();
            let s = m.score_descriptor(&d);
            prop_assert!(s.s >= 0.0 && s.s_cd >= 0.0 && s.s_ld >= 0.0);
            for x in [s.m, s.m_cd, s.m_ld] { prop_assert!((0.0..=1.0).contains(&x)); }
            prop_assert_eq!(s, m.score_descriptor(&m.describe_box(&f, &c).unwrap()));
        }
    }
}
