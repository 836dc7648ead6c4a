//! [`RgbdPersonConfig`]: every parameter of spec 001 §3, its presets ([`Preset`]: the paper,
//! the `strict` variant, the whole-target baseline and the one-switch ablations of §5.5), serde /
//! TOML over a preset, and the one [`validate`](crate::TrackerConfig::validate).

use nalgebra::Vector3;
use quarry_core::{CameraMount, PinholeIntrinsics};
use quarry_vision::lbp::LbpMapping;
use quarry_vision::multicue::{Aggregate, PatchModelConfig};
use serde::{Deserialize, Serialize};

use crate::{TrackerConfig, TrackerError};

/// The tracker's name in messages and errors.
const NAME: &str = "rgbd_person";

/// The named configurations of the RGB-D person tracker: the paper (default), its `strict`
/// variant, the whole-target baseline (spec §5.5) and the one-switch ablations of §5.5. Each is
/// [`RgbdPersonConfig::paper`] with the switches its line names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The spec's defaults (§3), with the two guards found on S1 seed 2 (default).
    #[default]
    Paper,
    /// `a = 0.9` and the learning gate `m(c*) ≥ 0.9` (spec §4 I2 option).
    Strict,
    /// The whole-target colour-texture baseline (spec §5.5).
    Baseline,
    /// Ablation: no depth kernel (`K ≡ 1` inside the box).
    NoDepthKernel,
    /// Ablation: N = 1 patch, with the depth kernel.
    N1,
    /// Ablation: learn whatever the occlusion state (`occlusion_gate = false`).
    NoOcclusionGate,
    /// Ablation: the MEKF ignores the odometry (Δ ≡ 0).
    NoEgo,
    /// Ablation: the MEKF transition as eq. (11) is printed (`EgoModel::PaperLiteral`).
    #[serde(rename = "paper-literal-11")]
    PaperLiteral11,
    /// Ablation: the box size never changes (`ScaleRule::Frozen`).
    ScaleFrozen,
    /// Ablation: the paper's hue-only colour histogram (16 bins, no achromatic bins).
    HueOnly,
    /// Ablation: uniform LBP with 59 classes instead of riu2.
    LbpU2,
    /// Ablation: eq. (7) aggregated by the mean square instead of cot².
    AggregateMeanSquare,
    /// The spec's literal selection and learning rules: no T2b self-score guard, learning gated
    /// on the occlusion state only (`t2b_self_score_fraction = None`,
    /// `learn_unoccluded_only = false`).
    SpecLiteral,
}

impl crate::PresetName for Preset {
    const ALL: &'static [Self] = &[
        Self::Paper,
        Self::Strict,
        Self::Baseline,
        Self::NoDepthKernel,
        Self::N1,
        Self::NoOcclusionGate,
        Self::NoEgo,
        Self::PaperLiteral11,
        Self::ScaleFrozen,
        Self::HueOnly,
        Self::LbpU2,
        Self::AggregateMeanSquare,
        Self::SpecLiteral,
    ];
    const TRACKER: &'static str = NAME;

    fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::Strict => "strict",
            Self::Baseline => "baseline",
            Self::NoDepthKernel => "no-depth-kernel",
            Self::N1 => "n1",
            Self::NoOcclusionGate => "no-occlusion-gate",
            Self::NoEgo => "no-ego",
            Self::PaperLiteral11 => "paper-literal-11",
            Self::ScaleFrozen => "scale-frozen",
            Self::HueOnly => "hue-only",
            Self::LbpU2 => "lbp-u2",
            Self::AggregateMeanSquare => "aggregate-mean-square",
            Self::SpecLiteral => "spec-literal",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Paper => "the spec's defaults with the T2b and learning guards (default)",
            Self::Strict => "a = 0.9 and learning only when m(c*) >= 0.9",
            Self::Baseline => "the whole-target colour-texture baseline (spec 5.5)",
            Self::NoDepthKernel => "ablation: no depth kernel (K = 1 inside the box)",
            Self::N1 => "ablation: one patch (N = 1) with the depth kernel",
            Self::NoOcclusionGate => "ablation: learn in every occlusion state",
            Self::NoEgo => "ablation: the MEKF ignores the odometry",
            Self::PaperLiteral11 => "ablation: the MEKF transition of eq. (11) as printed",
            Self::ScaleFrozen => "ablation: the box size never changes",
            Self::HueOnly => "ablation: hue-only colour histogram (16 bins)",
            Self::LbpU2 => "ablation: uniform LBP, 59 classes",
            Self::AggregateMeanSquare => "ablation: eq. (7) by the mean square",
            Self::SpecLiteral => "the spec's literal rules: no T2b guard, state-only learning gate",
        }
    }
}

/// How the box size follows the target depth (A2, I6).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ScaleRule {
    /// `γ = c_base·Z_0/Z_ref` on the base size, clamped to ±`scale_clamp` per frame (default).
    #[default]
    Disparity,
    /// Size never changes (`scale_frozen` ablation).
    Frozen,
}

/// Configuration (spec §3). `Default` = [`RgbdPersonConfig::paper`]; the named configurations
/// are [`Preset`]s, and TOML is read over one of them
/// ([`TrackerConfig::from_toml`](crate::TrackerConfig::from_toml)). Unknown keys and tables,
/// also inside `[model]`, `[intrinsics]` and `[mount]`, are errors.
///
/// The three options (`update_fraction`, `t2b_self_score_fraction`, `gate_chi2`) are off when
/// their key is absent: TOML has no null, so a preset whose option is off has no key for it,
/// and a file read over that preset keeps it off unless the file sets it. A file cannot turn
/// off an option its preset has on; the presets that do (`spec-literal`) are the way.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RgbdPersonConfig {
    /// Which preset the values below came from (informational; the values rule).
    pub preset: Preset,
    /// The appearance model (N, bins, band, th, ...).
    pub model: PatchModelConfig,
    /// `c_base` (paper: 0.9), a one-time shrink of the initial box.
    pub c_base: f64,
    /// Acceptance fraction `a` (0.8, step 6; I2).
    pub accept_fraction: f32,
    /// Severe-occlusion fraction (0.5, I3).
    pub severe_fraction: f32,
    /// Depth gate floor (0.5 m) and multiple of the predicted std (3).
    pub gate_floor_m: f64,
    /// Depth gate: multiple of `sqrt(P⁻[0,0])`.
    pub gate_sigmas: f64,
    /// White acceleration σ_w, m/s² (1.0).
    pub sigma_w: f64,
    /// Height random walk σ_h, m/√s (0.05).
    pub sigma_h: f64,
    /// Measurement noise σ_p, m (0.10).
    pub sigma_p: f64,
    /// Initial velocity std σ_v0, m/s (1.0).
    pub sigma_v0: f64,
    /// Camera intrinsics (Kinect v1 default 525, 525, 319.5, 239.5).
    #[serde(with = "IntrinsicsDef")]
    pub intrinsics: PinholeIntrinsics,
    /// Camera mount (0, 0, 1.0) m, no tilt (tilt ≠ 0 is rejected).
    #[serde(with = "MountDef")]
    pub mount: CameraMount,
    /// G1 half-width in strides along u (4 → 9 columns).
    pub grid_i: i32,
    /// G1 half-height in strides along v (2 → 5 rows).
    pub grid_j: i32,
    /// Add the projected MEKF prediction as a candidate.
    pub mekf_candidate: bool,
    /// Add the 3×3 grid G2 around the MEKF candidate (I11; needs `mekf_candidate`).
    pub mekf_local_grid: bool,
    /// Per-frame relative change limit of the size (0.05).
    pub scale_clamp: f64,
    /// Scale rule.
    pub scale_rule: ScaleRule,
    /// Frames of full occlusion before `Lost` (90).
    pub lost_after: u32,
    /// `strict` preset: learn only when `m(c*) ≥` this.
    #[serde(default)]
    pub update_fraction: Option<f32>,
    /// Gate learning on the occlusion state (false = `no_occlusion_gate` ablation).
    pub occlusion_gate: bool,
    /// Learn only when every valid patch of `c*` is unoccluded (`U(c*) = V`: no valid patch
    /// depth-occluded, out of view or empty), on top of the state gate. A box that slid beside a
    /// partly covered target has empty patches but no occluder pixels, so `D(c*)` alone lets it
    /// learn (S1 seeds 1-2). `false` = the spec's literal state-only gate.
    pub learn_unoccluded_only: bool,
    /// Tier T2b (texture only, also inside T3) also needs `S_Ld ≥` this fraction of the
    /// template's texture self-score over the scored patches (spec §8; `None` = off). Flat,
    /// noisy surfaces (floor, panel) have riu2 histograms close to a plain shirt's, so without
    /// it T2b accepts the floor during a full occlusion and drags the MEKF off (S1 seed 2).
    #[serde(default)]
    pub t2b_self_score_fraction: Option<f32>,
    /// Use odometry in the MEKF (false = `no_ego` ablation).
    pub ego: bool,
    /// Use the paper's literal eq. (11) (ablation).
    pub paper_literal_11: bool,
    /// Whole-target baseline behaviour: argmax S always accepted, no occlusion reasoning,
    /// update every frame (per-cue λ > th), no MEKF candidate.
    pub baseline: bool,
    /// Optional NIS gate on the MEKF update (χ²₃ 0.999 = 16.27).
    #[serde(default)]
    pub gate_chi2: Option<f64>,
}

/// The largest image side the intrinsics may declare (pixels): well above any RGB-D camera
/// (Kinect 640 x 480, Azure Kinect 3840 x 2160).
pub const MAX_IMAGE_SIDE: u32 = 16_384;

/// [`PinholeIntrinsics`] in the configuration, with unknown keys refused.
#[derive(Serialize, Deserialize)]
#[serde(remote = "PinholeIntrinsics", deny_unknown_fields)]
#[allow(dead_code)]
struct IntrinsicsDef {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    width: u32,
    height: u32,
}

/// [`CameraMount`] in the configuration, with unknown keys refused.
#[derive(Serialize, Deserialize)]
#[serde(remote = "CameraMount", deny_unknown_fields)]
#[allow(dead_code)]
struct MountDef {
    t: Vector3<f64>,
    tilt: f64,
}

impl Default for RgbdPersonConfig {
    fn default() -> Self {
        Self::paper()
    }
}

impl RgbdPersonConfig {
    /// The spec's defaults (§3): the `paper` preset.
    #[must_use]
    pub fn paper() -> Self {
        Self {
            preset: Preset::Paper,
            model: PatchModelConfig::default(),
            c_base: 0.9,
            accept_fraction: 0.8,
            severe_fraction: 0.5,
            gate_floor_m: 0.5,
            gate_sigmas: 3.0,
            sigma_w: 1.0,
            sigma_h: 0.05,
            sigma_p: 0.10,
            sigma_v0: 1.0,
            intrinsics: PinholeIntrinsics {
                fx: 525.0,
                fy: 525.0,
                cx: 319.5,
                cy: 239.5,
                width: 640,
                height: 480,
            },
            mount: CameraMount {
                t: Vector3::new(0.0, 0.0, 1.0),
                tilt: 0.0,
            },
            grid_i: 4,
            grid_j: 2,
            mekf_candidate: true,
            mekf_local_grid: true,
            scale_clamp: 0.05,
            scale_rule: ScaleRule::Disparity,
            lost_after: 90,
            update_fraction: None,
            occlusion_gate: true,
            learn_unoccluded_only: true,
            t2b_self_score_fraction: Some(0.5),
            ego: true,
            paper_literal_11: false,
            baseline: false,
            gate_chi2: None,
        }
    }

    /// The `strict` preset: `a = 0.9` and the learning gate `m(c*) ≥ 0.9`.
    #[must_use]
    pub fn strict() -> Self {
        Self {
            preset: Preset::Strict,
            accept_fraction: 0.9,
            update_fraction: Some(0.9),
            ..Self::paper()
        }
    }

    /// The whole-target colour-texture baseline (§5.5): the `baseline` preset.
    #[must_use]
    pub fn whole_target_baseline() -> Self {
        Self {
            preset: Preset::Baseline,
            model: PatchModelConfig::whole_target_baseline(),
            mekf_candidate: false,
            mekf_local_grid: false,
            occlusion_gate: false,
            baseline: true,
            ..Self::paper()
        }
    }
}

impl TrackerConfig for RgbdPersonConfig {
    type Preset = Preset;
    const NAME: &'static str = NAME;

    fn preset(p: Preset) -> Self {
        let paper = Self::paper();
        let model = paper.model;
        let c = match p {
            Preset::Paper => return paper,
            Preset::Strict => return Self::strict(),
            Preset::Baseline => return Self::whole_target_baseline(),
            Preset::NoDepthKernel => Self {
                model: PatchModelConfig {
                    depth_kernel: false,
                    ..model
                },
                ..paper
            },
            Preset::N1 => Self {
                model: PatchModelConfig { n: 1, ..model },
                ..paper
            },
            Preset::NoOcclusionGate => Self {
                occlusion_gate: false,
                ..paper
            },
            Preset::NoEgo => Self {
                ego: false,
                ..paper
            },
            Preset::PaperLiteral11 => Self {
                paper_literal_11: true,
                ..paper
            },
            Preset::ScaleFrozen => Self {
                scale_rule: ScaleRule::Frozen,
                ..paper
            },
            Preset::HueOnly => Self {
                model: PatchModelConfig {
                    achromatic_bins: 0,
                    ..model
                },
                ..paper
            },
            Preset::LbpU2 => Self {
                model: PatchModelConfig {
                    lbp: LbpMapping::U2,
                    ..model
                },
                ..paper
            },
            Preset::AggregateMeanSquare => Self {
                model: PatchModelConfig {
                    aggregate: Aggregate::MeanSquare,
                    ..model
                },
                ..paper
            },
            Preset::SpecLiteral => Self {
                t2b_self_score_fraction: None,
                learn_unoccluded_only: false,
                ..paper
            },
        };
        Self { preset: p, ..c }
    }

    /// Checks every parameter and the rules between them: the appearance model's own rules
    /// (a [`TrackerError::Vision`] naming the parameter), then ranges, the camera, the grids,
    /// and that the image can hold the smallest box the patch grid allows.
    fn validate(&self) -> Result<(), TrackerError> {
        let bad = |reason: String| Err(TrackerError::config(NAME, reason));
        self.model.validate()?;
        for (name, x) in [
            ("c_base", self.c_base),
            ("sigma_p", self.sigma_p),
            ("sigma_v0", self.sigma_v0),
            ("gate_floor_m", self.gate_floor_m),
            ("gate_sigmas", self.gate_sigmas),
            ("scale_clamp", self.scale_clamp),
        ] {
            if !(x.is_finite() && x > 0.0) {
                return bad(format!("{name} must be finite and > 0, got {x}"));
            }
        }
        for (n, x) in [("sigma_w", self.sigma_w), ("sigma_h", self.sigma_h)] {
            if !(x.is_finite() && x >= 0.0) {
                return bad(format!("{n} must be ≥ 0, got {x}"));
            }
        }
        if self.c_base > 1.0 {
            return bad(format!("c_base must be ≤ 1, got {}", self.c_base));
        }
        for (n, x) in [
            ("accept_fraction", self.accept_fraction),
            ("severe_fraction", self.severe_fraction),
            ("update_fraction", self.update_fraction.unwrap_or(0.0)),
            (
                "t2b_self_score_fraction",
                self.t2b_self_score_fraction.unwrap_or(0.0),
            ),
        ] {
            if !(0.0..=1.0).contains(&x) {
                return bad(format!("{n} must lie in [0, 1], got {x}"));
            }
        }
        let k = self.intrinsics;
        if ![k.fx, k.fy, k.cx, k.cy].iter().all(|v| v.is_finite()) || k.fx <= 0.0 || k.fy <= 0.0 {
            return bad("intrinsics must be finite, f > 0".into());
        }
        if !(1..=MAX_IMAGE_SIDE).contains(&k.width) || !(1..=MAX_IMAGE_SIDE).contains(&k.height) {
            return bad(format!(
                "intrinsics width and height must be in 1..={MAX_IMAGE_SIDE} pixels, got {}x{}",
                k.width, k.height
            ));
        }
        if self.mount.tilt != 0.0 || !self.mount.t.iter().all(|v| v.is_finite()) {
            return bad(
                "camera mount: finite translation and tilt = 0 (tilt is not implemented)".into(),
            );
        }
        if !(0..=20).contains(&self.grid_i) || !(0..=20).contains(&self.grid_j) {
            return bad("grid_i / grid_j must be in 0..=20".into());
        }
        if let Some(g) = self.gate_chi2
            && !(g.is_finite() && g > 0.0)
        {
            return bad(format!("gate_chi2 must be > 0, got {g}"));
        }
        // rules between fields
        if self.mekf_local_grid && !self.mekf_candidate {
            return bad(
                "mekf_local_grid = true needs mekf_candidate = true (G2 is the grid around the \
                 MEKF candidate); set both to false to drop the MEKF candidates"
                    .into(),
            );
        }
        // the initial box, shrunk by c_base, needs 4 px per patch a side (checked at init):
        // an image smaller than that can hold no initial box
        let side = 4.0 * f64::from(self.model.n) / self.c_base;
        if f64::from(k.width.min(k.height)) < side {
            return bad(format!(
                "intrinsics {}x{} cannot hold an initial box of {side:.1} px a side (4 px per \
                 patch for n = {} after c_base = {})",
                k.width, k.height, self.model.n, self.c_base
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PresetName;

    #[test]
    fn config_presets_and_toml() {
        assert!(RgbdPersonConfig::paper().validate().is_ok());
        assert!(RgbdPersonConfig::strict().validate().is_ok());
        assert!(RgbdPersonConfig::whole_target_baseline().validate().is_ok());
        let c = RgbdPersonConfig::from_toml("c_base = 0.8\n[model]\nn = 3\n", None).unwrap();
        assert_eq!(c.model.n, 3);
        assert!((c.c_base - 0.8).abs() < 1e-12);
        assert!(RgbdPersonConfig::from_toml("c_base = -1", None).is_err());
        assert!(RgbdPersonConfig::from_toml("c_base = [", None).is_err());
        let back = toml::to_string(&RgbdPersonConfig::paper()).unwrap();
        assert_eq!(
            RgbdPersonConfig::from_toml(&back, None).unwrap(),
            RgbdPersonConfig::paper()
        );
    }

    #[test]
    fn every_preset_validates_and_round_trips() {
        assert_eq!(Preset::ALL[0], Preset::default());
        assert_eq!(
            RgbdPersonConfig::default(),
            RgbdPersonConfig::preset(Preset::Paper)
        );
        for &p in Preset::ALL {
            let c = RgbdPersonConfig::preset(p);
            c.validate()
                .unwrap_or_else(|e| panic!("preset {}: {e}", p.name()));
            assert_eq!(c.preset, p);
            assert!(!p.about().is_empty());
            // the name a user types, the serde name and the parser agree
            assert_eq!(Preset::parse(p.name()).unwrap(), p);
            assert_eq!(Preset::parse(&p.name().replace('-', "_")).unwrap(), p);
            let text = c.to_toml().unwrap();
            assert!(
                text.contains(&format!("preset = \"{}\"", p.name())),
                "{text}"
            );
            // over the file's own preset key, over the same preset, and over the default
            assert_eq!(
                RgbdPersonConfig::from_toml(&text, None).unwrap(),
                c,
                "{text}"
            );
            assert_eq!(RgbdPersonConfig::from_toml(&text, Some(p)).unwrap(), c);
            // the preset alone, as a file
            let short = format!("preset = \"{}\"", p.name());
            assert_eq!(RgbdPersonConfig::from_toml(&short, None).unwrap(), c);
        }
        // each ablation is one switch off the paper
        let paper = RgbdPersonConfig::paper();
        assert!(!RgbdPersonConfig::preset(Preset::NoEgo).ego);
        assert!(!RgbdPersonConfig::preset(Preset::NoOcclusionGate).occlusion_gate);
        assert_eq!(
            RgbdPersonConfig::preset(Preset::ScaleFrozen).scale_rule,
            ScaleRule::Frozen
        );
        assert!(RgbdPersonConfig::preset(Preset::PaperLiteral11).paper_literal_11);
        assert!(
            !RgbdPersonConfig::preset(Preset::NoDepthKernel)
                .model
                .depth_kernel
        );
        assert_eq!(RgbdPersonConfig::preset(Preset::N1).model.n, 1);
        let lit = RgbdPersonConfig::preset(Preset::SpecLiteral);
        assert_eq!(lit.t2b_self_score_fraction, None);
        assert!(!lit.learn_unoccluded_only);
        assert_eq!(
            RgbdPersonConfig {
                preset: Preset::Paper,
                ego: true,
                ..RgbdPersonConfig::preset(Preset::NoEgo)
            },
            paper
        );
        // a key over a preset keeps the preset's other values
        let s = RgbdPersonConfig::from_toml("c_base = 0.8", Some(Preset::SpecLiteral)).unwrap();
        assert_eq!(s.t2b_self_score_fraction, None);
        assert!((s.c_base - 0.8).abs() < 1e-12);
        // the file's preset and the caller's must agree
        assert!(
            RgbdPersonConfig::from_toml("preset = \"strict\"", Some(Preset::Baseline)).is_err()
        );
        assert!(RgbdPersonConfig::from_toml("preset = \"sideways\"", None).is_err());
    }

    #[test]
    fn intrinsics_of_size_zero_or_absurd_size_are_errors() {
        for (w, h) in [(0, 480), (640, 0), (0, 0), (MAX_IMAGE_SIDE + 1, 480)] {
            let toml = format!("[intrinsics]\nwidth = {w}\nheight = {h}");
            let e = RgbdPersonConfig::from_toml(&toml, None).unwrap_err();
            assert!(e.to_string().contains("width and height"), "{w}x{h}: {e}");
        }
        assert!(
            RgbdPersonConfig::from_toml("[intrinsics]\nwidth = 320\nheight = 240", None).is_ok()
        );
    }

    #[test]
    fn unknown_keys_and_tables_are_errors() {
        // a misspelt key, at the top and inside each table
        assert!(RgbdPersonConfig::from_toml("c_bsae = 0.8", None).is_err());
        assert!(RgbdPersonConfig::from_toml("[model]\nnn = 3", None).is_err());
        assert!(RgbdPersonConfig::from_toml("[intrinsics]\nfxx = 500.0", None).is_err());
        assert!(RgbdPersonConfig::from_toml("[mount]\ntlit = 0.0", None).is_err());
        // a misspelt table
        let e = RgbdPersonConfig::from_toml("[modle]\nn = 3", None).unwrap_err();
        assert!(e.to_string().contains("modle"), "{e}");
        // the right spellings are fine and merge key by key
        let c = RgbdPersonConfig::from_toml("[intrinsics]\nfx = 500.0", None).unwrap();
        assert_eq!(c.intrinsics.fx, 500.0);
        assert_eq!(c.intrinsics.width, 640);
        let c = RgbdPersonConfig::from_toml("[mount]\nt = [0.1, 0.0, 1.2]", None).unwrap();
        assert_eq!(c.mount.t, Vector3::new(0.1, 0.0, 1.2));
    }

    #[test]
    fn rules_between_fields() {
        let base = RgbdPersonConfig::paper();
        let g2 = RgbdPersonConfig {
            mekf_candidate: false,
            ..base.clone()
        };
        assert!(
            g2.validate()
                .unwrap_err()
                .to_string()
                .contains("mekf_local_grid")
        );
        assert!(
            RgbdPersonConfig {
                mekf_local_grid: false,
                ..g2
            }
            .validate()
            .is_ok()
        );
        let mut tiny = base.clone();
        tiny.intrinsics.width = 16;
        tiny.intrinsics.height = 16;
        assert!(tiny.validate().unwrap_err().to_string().contains("16x16"));
        tiny.model.n = 3; // 4·3/0.9 = 13.3 px fits
        assert!(tiny.validate().is_ok());
        // the appearance model's own rules keep their type
        let mut m = base;
        m.model.n = 0;
        assert!(matches!(m.validate(), Err(TrackerError::Vision(_))));
    }
}
