//! [`SlamotConfig`]: every parameter of spec 000 §3, its enums, and the named presets
//! ([`Preset`]: `paper` = `Default`, `s1`, `mrclam`), following the crate's
//! [configuration convention](crate::TrackerConfig).
//!
//! In TOML the enums are lower case (`association = "jipda"`, `readout = "best-particle"`), the
//! two enums with data are tables with a `kind` key (`motion = { kind = "unicycle" }`,
//! `target_init = { kind = "two-point", max_speed = 3.0 }`), and the optional numbers take a
//! number or `"none"` (`sensor_range = 6.0`, `landmark_gate = "none"`).

use serde::{Deserialize, Serialize};

use crate::TrackerError;

/// How target detections are associated inside each particle (spec §2.8, A1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AssociationMode {
    /// Exact parametric JPDA (Bar-Shalom & Fortmann) — the spec's default.
    #[default]
    Jpda,
    /// The paper's eqs. (5), (11), (12) as printed (plus the spec's gate guard) — ablation.
    Paper,
    /// Musicki-Evans JIPDA with track existence; with `track_management` also births/deaths.
    Jipda,
}

/// The target factor of the particle weight (spec §2.10, A5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TargetWeight {
    /// The mode's own: JPDA/JIPDA normaliser c for `Jpda`/`Jipda`, eq. (11) for `Paper`.
    #[default]
    ModeDefault,
    /// The JPDA marginal likelihood c (the proper Rao-Blackwellized weight) in every mode.
    MarginalLikelihood,
    /// The paper's eq. (11) in every mode.
    PaperEq11,
    /// No target factor: the particles are weighted by the landmark detections alone, so that
    /// target detections (and clutter among them) cannot move the pose estimate. Targets are
    /// still associated and updated inside every particle. For recordings whose "targets" are
    /// poorly modelled movers (MRCLAM's other robots).
    None,
}

/// Robot motion model of the particles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum RobotMotion {
    /// Bicycle with wheelbase B \[m\], control (V, G) (spec §2.3; the simulator's).
    Bicycle {
        /// Wheelbase \[m\].
        wheelbase: f64,
    },
    /// Unicycle, control (v, ω) (MRCLAM odometry).
    Unicycle,
}

/// Motion model of the targets (each a planar state `[x, y, vx, vy]`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TargetMotion {
    /// Constant velocity with discrete white-noise acceleration σ_a = `target_sigma_a`
    /// (spec §2.6; the paper's).
    #[default]
    Dwna,
    /// Velocity reverting to zero (`quarry_filter::MeanRevertingVelocity2`): each velocity
    /// component has the stationary standard deviation `sigma_v` and forgets itself over `tau`.
    /// A target unseen for Δ ≫ τ spreads as a random walk (position variance 2 σ_v² τ Δ) instead
    /// of a constant-velocity model's Δ³, which suits slow movers seen in short glimpses
    /// (MRCLAM's robots through a 72° camera). `target_sigma_a` is not used.
    MeanReverting {
        /// Stationary standard deviation of each velocity component \[m/s\].
        sigma_v: f64,
        /// Velocity correlation time \[s\].
        tau: f64,
    },
}

/// The target motion model a configuration builds (`TargetMotion`, validated).
#[derive(Debug, Clone, Copy)]
pub(crate) enum TargetModel {
    Cv(quarry_filter::ConstantVelocity2),
    MeanReverting(quarry_filter::MeanRevertingVelocity2),
}

impl quarry_core::MotionModel<4> for TargetModel {
    type Control = ();
    fn transition(&self, x: &nalgebra::Vector4<f64>, u: &(), dt: f64) -> nalgebra::Vector4<f64> {
        match self {
            Self::Cv(m) => m.transition(x, u, dt),
            Self::MeanReverting(m) => m.transition(x, u, dt),
        }
    }
    fn jacobian(&self, x: &nalgebra::Vector4<f64>, u: &(), dt: f64) -> nalgebra::Matrix4<f64> {
        match self {
            Self::Cv(m) => m.jacobian(x, u, dt),
            Self::MeanReverting(m) => m.jacobian(x, u, dt),
        }
    }
    fn process_noise(&self, x: &nalgebra::Vector4<f64>, u: &(), dt: f64) -> nalgebra::Matrix4<f64> {
        match self {
            Self::Cv(m) => m.process_noise(x, u, dt),
            Self::MeanReverting(m) => m.process_noise(x, u, dt),
        }
    }
}

/// Where a particle's pose at an observation epoch is drawn from (spec A20).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Proposal {
    /// FastSLAM 1.0: the motion model is sampled at every control step; the weight is the
    /// measurement likelihood at the sampled pose (the paper's, default).
    #[default]
    Motion,
    /// FastSLAM 2.0: between epochs each particle carries its motion Gaussian (mean and
    /// linearised covariance); at an epoch that Gaussian is conditioned on the known-landmark
    /// measurements (`quarry_filter::rbpf::fastslam2`), the pose is drawn from it, and the
    /// weight is the measurements' predictive likelihood.
    Measurement,
}

/// How estimates are read out of the particle set (spec §2.11, A8).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Readout {
    /// Weighted mean over particles, before resampling (default).
    #[default]
    WeightedMean,
    /// The highest-weight particle (Bailey's plots).
    BestParticle,
}

/// How the target slots are created when the target count n is known (spec §2.12, A19).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum TargetInit {
    /// Spec §2.12 default: at the first epoch with exactly n detections, slot l from detection l
    /// (velocity 0, σ_v0). With clutter and missed detections the n detections can include a
    /// clutter point (S1: ≈ 43 % of 3-detection scans), and that slot is lost from the start.
    #[default]
    FirstN,
    /// Spec A19 option, two-point initiation: a detection is a candidate when its nearest
    /// detection of the previous epoch (both placed in the map frame from the weighted-mean pose)
    /// lies within `max_speed · Δt + 3 √(tr Σ_k + tr Σ_{k−1})` (pairing is exclusive, nearest
    /// first); slots are created at the first epoch with exactly n candidates. The velocity is the
    /// two-point difference, fused with the N(0, σ_v0² I) prior of §2.12.
    TwoPoint {
        /// Largest plausible target speed [m/s] (gate of the pairing).
        max_speed: f64,
    },
}

/// Which landmark store the particles use (spec A9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MapStoreKind {
    /// Persistent, structure-shared tree: O(1) particle copy, O(log M) landmark update.
    #[default]
    Persistent,
    /// Flat vector per particle: O(M) copy.
    Vec,
}

/// The named configurations of [`SlamotConfig`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// Spec §3, the paper's scenario S0 (= `SlamotConfig::default()`).
    #[default]
    Paper,
    /// The S1 stress configuration (spec §4.3 E6, [`SlamotConfig::s1`]).
    S1,
    /// The UTIAS MRCLAM configuration ([`SlamotConfig::mrclam`]; N = 50, the CLI's default).
    Mrclam,
}

impl crate::PresetName for Preset {
    const ALL: &'static [Self] = &[Self::Paper, Self::S1, Self::Mrclam];
    const TRACKER: &'static str = "slamot";

    fn name(self) -> &'static str {
        match self {
            Self::Paper => "paper",
            Self::S1 => "s1",
            Self::Mrclam => "mrclam",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Paper => "spec 000 section 3, the paper's S0 (default)",
            Self::S1 => "S1 stress: filter P_D 0.9, clutter 2 per scan, two-point initiation",
            Self::Mrclam => {
                "UTIAS MRCLAM: unicycle odometry, 60 degree camera, JIPDA births/deaths"
            }
        }
    }
}

/// `Option<f64>` in TOML, which has no null: a number, or the string `"none"`.
mod opt_f64 {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    #[derive(Serialize, Deserialize)]
    #[serde(untagged)]
    enum Repr {
        Num(f64),
        Word(String),
    }

    #[allow(clippy::ref_option)] // serde's `with` passes `&Option<T>`
    pub fn serialize<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        match v {
            Some(x) => Repr::Num(*x),
            None => Repr::Word("none".to_owned()),
        }
        .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        match Repr::deserialize(d)? {
            Repr::Num(x) => Ok(Some(x)),
            Repr::Word(w) if w == "none" => Ok(None),
            Repr::Word(w) => Err(serde::de::Error::custom(format!(
                "expected a number or \"none\", got {w:?}"
            ))),
        }
    }
}

/// The most particles a configuration may ask for (memory grows with N; one million particles
/// of the S0 scenario need about 0.9 GB).
pub const MAX_PARTICLES: usize = 1_000_000;

/// Configuration of [`SlamotTracker`](super::SlamotTracker). `Default` = spec §3 values (the
/// `paper` preset); each field says its source.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlamotConfig {
    /// Number of particles N (paper: 50).
    pub particles: usize,
    /// Robot motion model (spec §2.3: bicycle, wheelbase 4 m — Bailey's simulator).
    pub motion: RobotMotion,
    /// Control noise standard deviations of (V, G) or (v, ω) (paper: 0.3 m/s, 0.0872 rad; A13).
    pub control_noise: [f64; 2],
    /// Measurement noise standard deviations (σ_r \[m\], σ_b \[rad\]) (spec §3.2: 0.1 m, 1°).
    pub meas_noise: [f64; 2],
    /// Target DWNA acceleration std σ_a [m/s²] (paper's "0.4", A14), used by
    /// `target_motion = dwna`.
    pub target_sigma_a: f64,
    /// Target motion model (spec §2.6: constant velocity, `dwna`).
    pub target_motion: TargetMotion,
    /// Association mode (spec A1: `Jpda`).
    pub association: AssociationMode,
    /// Target weight factor (spec A5).
    pub target_weight: TargetWeight,
    /// Detection probability P_D in the filter (spec §3.2: 0.99).
    pub p_detect: f64,
    /// Gate probability P_G (0.99 → γ = 9.2103).
    pub p_gate: f64,
    /// Clutter density κ [(m·rad)⁻¹] (spec §3.2: 0.1 / (30 · 2π)).
    pub clutter_density: f64,
    /// Initial velocity std σ_v0 of a new target [m/s] (spec §2.12: 1.5).
    pub sigma_v0: f64,
    /// How target slots are created with a known target count (spec §2.12 / A19).
    pub target_init: TargetInit,
    /// Known target count n: targets are created at the first epoch with exactly n detections
    /// (spec §2.12, A10; paper: 3). Ignored when `track_management` is on.
    pub n_targets: usize,
    /// JIPDA births/deaths with global slots (spec A10). Requires `association = Jipda`.
    pub track_management: bool,
    /// JIPDA survival probability per epoch p_S (spec §3.2: 0.999).
    pub survival: f64,
    /// Existence of a new slot ψ₀ (0.2).
    pub birth_existence: f64,
    /// Existence at which a slot is confirmed (0.9).
    pub confirm_existence: f64,
    /// Existence below which a slot is deleted (0.05).
    pub delete_existence: f64,
    /// With track management, a slot whose position standard deviation (the square root of
    /// the largest eigenvalue of its read-out position covariance) exceeds this \[m\] is deleted:
    /// it no longer says where its target is, and kept it would hold a slot and be reported.
    /// Stone Soup's `CovarianceBasedDeleter` rule. `None`: existence alone decides (spec).
    #[serde(with = "opt_f64")]
    pub delete_sigma: Option<f64>,
    /// Upper bound on simultaneous slots with track management (guards clutter storms).
    pub max_slots: usize,
    /// Resample when N_eff < `neff_threshold` · N (Bailey: 0.75; A21).
    pub neff_threshold: f64,
    /// Estimate read-out.
    pub readout: Readout,
    /// Landmark store kind (used by the experiment drivers of quarry-repro and the CLI; the
    /// tracker's store is its type parameter).
    pub map_store: MapStoreKind,
    /// Sensor range for targets \[m\]; a target predicted beyond it gets detection probability
    /// `p_detect_outside` (`None`: unlimited, the simulator's 360° sensor covers all targets).
    #[serde(with = "opt_f64")]
    pub sensor_range: Option<f64>,
    /// Sensor field of view \[rad\] centred on the heading (2π: all around).
    pub sensor_fov: f64,
    /// Detection probability of a target predicted outside range/field of view (MRCLAM's
    /// camera sees ~60°).
    pub p_detect_outside: f64,
    /// Robust landmark update: a known-landmark detection with d² = νᵀS⁻¹ν above this is not
    /// applied to the landmark and contributes the likelihood at d² = gate to the weight
    /// (real data has range outliers; `None` in the simulation, which has none).
    #[serde(with = "opt_f64")]
    pub landmark_gate: Option<f64>,
    /// Pose proposal (`motion` = FastSLAM 1.0, default; `measurement` = FastSLAM 2.0).
    pub proposal: Proposal,
}

impl Default for SlamotConfig {
    fn default() -> Self {
        Self {
            particles: 50,
            motion: RobotMotion::Bicycle { wheelbase: 4.0 },
            control_noise: [0.3, 0.0872],
            meas_noise: [0.1, 1f64.to_radians()],
            target_sigma_a: 0.4,
            target_motion: TargetMotion::Dwna,
            association: AssociationMode::Jpda,
            target_weight: TargetWeight::ModeDefault,
            p_detect: 0.99,
            p_gate: 0.99,
            clutter_density: 0.1 / (30.0 * 2.0 * std::f64::consts::PI),
            sigma_v0: 1.5,
            target_init: TargetInit::FirstN,
            n_targets: 3,
            track_management: false,
            survival: 0.999,
            birth_existence: 0.2,
            confirm_existence: 0.9,
            delete_existence: 0.05,
            delete_sigma: None,
            max_slots: 32,
            neff_threshold: 0.75,
            readout: Readout::WeightedMean,
            map_store: MapStoreKind::Persistent,
            sensor_range: None,
            sensor_fov: 2.0 * std::f64::consts::PI,
            p_detect_outside: 1e-3,
            landmark_gate: None,
            proposal: Proposal::Motion,
        }
    }
}

impl SlamotConfig {
    /// The S1 stress configuration (spec §4.3 E6): filter P_D = 0.9, κ = 2 / (30 m · 2π) and
    /// two-point target initiation (A19, max speed 3 m/s), which keeps clutter from creating a
    /// slot at the first epoch. Everything else as `Default`. The `s1` preset.
    pub fn s1() -> Self {
        Self {
            p_detect: 0.9,
            clutter_density: 2.0 / (30.0 * 2.0 * std::f64::consts::PI),
            target_init: TargetInit::TwoPoint { max_speed: 3.0 },
            ..Self::default()
        }
    }

    /// A configuration for MRCLAM: unicycle odometry, camera noise, JIPDA with births and deaths
    /// (the number of robots in view varies), a 6 m / 72° camera, N = 50 particles. The values
    /// are this crate's choices for the dataset (documented in docs/slamot.md), not the paper's.
    /// The `mrclam` preset.
    ///
    /// The noise is robot 1's of dataset 6, estimated against its Vicon truth
    /// (`benches/peers/mrclam_peers.py --estimate-noise --robot 1`: robust std of the landmark
    /// range and bearing residuals, and the 1-s odometry errors as per-step control noise), so
    /// results on robot 1 of dataset 6 are in-sample and those on robots 2-5 are not. No
    /// landmark gate: on this data a gate turned a heading error into permanent divergence
    /// (docs/slamot.md, "Diagnosis").
    ///
    /// The targets (the other robots) are measured too, by `docs/analysis/mrclam_target_stats.py`
    /// on dataset 6 (docs/slamot.md, "Associating the other robots"):
    /// - `p_detect` = 0.36: the camera reports a robot that is inside its 6 m / 72° view at 36 %
    ///   of the observation epochs (3945 of 10 866, pooled over the five observers, 0.27-0.42
    ///   each; against Vicon). It was 0.8, which deleted a track after 2-4 s in view without a
    ///   detection and a new one within a second.
    /// - `target_motion` = mean-reverting, σ_v = 0.043 m/s per axis, τ = 24 s: the robots' own
    ///   odometry (no Vicon; Vicon agrees within 10 % on σ_v and 15 % on τ). A constant-velocity
    ///   model let an unseen robot's position σ grow to kilometres and such tracks filled the
    ///   slots. `sigma_v0` = σ_v: a new track's velocity is drawn from the stationary spread.
    /// - `delete_sigma` = 1 m (a choice): a track whose position σ passes 1 m, half the ~2 m
    ///   between robots that meet, is deleted rather than kept as a slot that explains nothing.
    pub fn mrclam() -> Self {
        Self {
            particles: 50,
            motion: RobotMotion::Unicycle,
            control_noise: [0.046, 0.139],
            meas_noise: [0.079, 0.0109],
            target_sigma_a: 0.3,
            target_motion: TargetMotion::MeanReverting {
                sigma_v: 0.043,
                tau: 24.0,
            },
            association: AssociationMode::Jipda,
            track_management: true,
            p_detect: 0.36,
            clutter_density: 0.05 / (5.0 * std::f64::consts::FRAC_PI_3),
            sigma_v0: 0.043,
            delete_sigma: Some(1.0),
            max_slots: 12,
            sensor_range: Some(6.0),
            sensor_fov: std::f64::consts::FRAC_PI_3 * 1.2,
            survival: 0.9995,
            landmark_gate: None,
            delete_existence: 0.02,
            ..Self::default()
        }
    }

    /// The target motion model of `target_motion` (and `target_sigma_a`).
    pub(crate) fn target_model(&self) -> Result<TargetModel, TrackerError> {
        Ok(match self.target_motion {
            TargetMotion::Dwna => TargetModel::Cv(quarry_filter::ConstantVelocity2::dwna(
                self.target_sigma_a.max(1e-12),
            )?),
            TargetMotion::MeanReverting { sigma_v, tau } => TargetModel::MeanReverting(
                quarry_filter::MeanRevertingVelocity2::new(sigma_v, tau)?,
            ),
        })
    }

    /// Gate threshold γ = χ²₂⁻¹(P_G) = −2 ln(1 − P_G).
    pub fn gate_threshold(&self) -> f64 {
        -2.0 * (1.0 - self.p_gate).ln()
    }
}

impl crate::TrackerConfig for SlamotConfig {
    type Preset = Preset;
    const NAME: &'static str = "slamot";

    fn preset(p: Preset) -> Self {
        match p {
            Preset::Paper => Self::default(),
            Preset::S1 => Self::s1(),
            Preset::Mrclam => Self::mrclam(),
        }
    }

    /// Checks every field and the rules between fields.
    fn validate(&self) -> Result<(), TrackerError> {
        let fail = |m: String| Err(TrackerError::config(Self::NAME, m));
        if self.particles == 0 || self.particles > MAX_PARTICLES {
            return fail(format!(
                "particles = {} must be in 1..={MAX_PARTICLES} (each particle holds a map and \
                 its targets: 10 million took 8.4 GB)",
                self.particles
            ));
        }
        if let RobotMotion::Bicycle { wheelbase } = self.motion
            && !(wheelbase.is_finite() && wheelbase > 0.0)
        {
            return fail(format!("wheelbase {wheelbase} must be finite and > 0"));
        }
        if self
            .control_noise
            .iter()
            .any(|v| !(v.is_finite() && *v >= 0.0))
        {
            return fail(format!(
                "control_noise {:?} must be finite and >= 0",
                self.control_noise
            ));
        }
        if self.meas_noise.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return fail(format!(
                "meas_noise {:?} must be finite and > 0",
                self.meas_noise
            ));
        }
        if !(self.target_sigma_a.is_finite() && self.target_sigma_a >= 0.0) {
            return fail("target_sigma_a must be finite and >= 0".into());
        }
        if let TargetMotion::MeanReverting { sigma_v, tau } = self.target_motion
            && !(sigma_v.is_finite() && sigma_v > 0.0 && tau.is_finite() && tau > 0.0)
        {
            return fail(format!(
                "target_motion mean-reverting: sigma_v {sigma_v} and tau {tau} must be finite \
                 and > 0"
            ));
        }
        if let Some(s) = self.delete_sigma
            && !(s.is_finite() && s > 0.0)
        {
            return fail(format!(
                "delete_sigma {s} must be finite and > 0 (or \"none\")"
            ));
        }
        for (n, v) in [
            ("p_detect", self.p_detect),
            ("p_gate", self.p_gate),
            ("survival", self.survival),
            ("birth_existence", self.birth_existence),
            ("confirm_existence", self.confirm_existence),
            ("delete_existence", self.delete_existence),
            ("p_detect_outside", self.p_detect_outside),
        ] {
            if !(v > 0.0 && v <= 1.0) {
                return fail(format!("{n} = {v} must be in (0, 1]"));
            }
        }
        if self.p_gate >= 1.0 {
            return fail("p_gate must be < 1 (the gate threshold would be infinite)".into());
        }
        if self.delete_existence >= self.confirm_existence {
            return fail(format!(
                "delete_existence {} must be below confirm_existence {}",
                self.delete_existence, self.confirm_existence
            ));
        }
        if !(self.clutter_density.is_finite() && self.clutter_density > 0.0) {
            return fail("clutter_density must be finite and > 0".into());
        }
        if !(self.sigma_v0.is_finite() && self.sigma_v0 > 0.0) {
            return fail("sigma_v0 must be finite and > 0".into());
        }
        if let TargetInit::TwoPoint { max_speed } = self.target_init
            && !(max_speed.is_finite() && max_speed > 0.0)
        {
            return fail(format!(
                "two-point max_speed {max_speed} must be finite and > 0"
            ));
        }
        if !(self.neff_threshold > 0.0 && self.neff_threshold <= 1.0) {
            return fail("neff_threshold must be in (0, 1]".into());
        }
        if let Some(r) = self.sensor_range
            && !(r.is_finite() && r > 0.0)
        {
            return fail(format!(
                "sensor_range {r} must be finite and > 0 (or \"none\")"
            ));
        }
        if !(self.sensor_fov > 0.0 && self.sensor_fov <= 2.0 * std::f64::consts::PI) {
            return fail(format!(
                "sensor_fov {} must be in (0, 2 pi]",
                self.sensor_fov
            ));
        }
        if let Some(g) = self.landmark_gate
            && !(g.is_finite() && g > 0.0)
        {
            return fail(format!(
                "landmark_gate {g} must be finite and > 0 (or \"none\")"
            ));
        }
        if self.track_management && self.association != AssociationMode::Jipda {
            return fail("track_management needs association = Jipda".into());
        }
        if self.track_management && self.max_slots == 0 {
            return fail("max_slots must be > 0 with track management".into());
        }
        if !self.track_management && self.n_targets == 0 {
            return fail("n_targets must be > 0 without track management".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PresetName, TrackerConfig};

    #[test]
    fn target_motion_and_delete_sigma_parse_and_validate() {
        let c: SlamotConfig = toml::from_str(
            "target_motion = { kind = \"mean-reverting\", sigma_v = 0.05, tau = 10.0 }\n\
             delete_sigma = 2.0",
        )
        .unwrap();
        assert_eq!(
            c.target_motion,
            TargetMotion::MeanReverting {
                sigma_v: 0.05,
                tau: 10.0
            }
        );
        assert_eq!(c.delete_sigma, Some(2.0));
        c.validate().unwrap();
        let none: SlamotConfig = toml::from_str("delete_sigma = \"none\"").unwrap();
        assert_eq!(none.delete_sigma, None);
        for bad in [
            SlamotConfig {
                target_motion: TargetMotion::MeanReverting {
                    sigma_v: 0.05,
                    tau: 0.0,
                },
                ..SlamotConfig::default()
            },
            SlamotConfig {
                target_motion: TargetMotion::MeanReverting {
                    sigma_v: f64::NAN,
                    tau: 1.0,
                },
                ..SlamotConfig::default()
            },
            SlamotConfig {
                delete_sigma: Some(-1.0),
                ..SlamotConfig::default()
            },
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains("tau") || e.contains("delete_sigma"), "{e}");
        }
        assert!(
            toml::from_str::<SlamotConfig>(
                "target_motion = { kind = \"mean-reverting\", tau = 1.0 }"
            )
            .is_err(),
            "sigma_v is required"
        );
    }

    #[test]
    fn every_preset_validates_and_round_trips() {
        assert_eq!(Preset::ALL[0], Preset::default());
        crate::config::check_convention::<SlamotConfig>();
        assert_eq!(SlamotConfig::preset(Preset::S1), SlamotConfig::s1());
        assert_eq!(Preset::parse("S1").ok(), None);
        assert!(Preset::parse("s2").is_err());
    }

    #[test]
    fn toml_overlays_a_preset_and_refuses_typos() {
        let c = SlamotConfig::from_toml("particles = 20", Some(Preset::Mrclam)).unwrap();
        assert_eq!(
            c,
            SlamotConfig {
                particles: 20,
                ..SlamotConfig::mrclam()
            }
        );
        let c = SlamotConfig::from_toml(
            "association = \"jipda\"\ntarget_init = { kind = \"two-point\", max_speed = 2.5 }\n\
             sensor_range = 10.0\nreadout = \"best-particle\"",
            None,
        )
        .unwrap();
        assert_eq!(c.association, AssociationMode::Jipda);
        assert_eq!(c.target_init, TargetInit::TwoPoint { max_speed: 2.5 });
        assert_eq!(c.sensor_range, Some(10.0));
        assert_eq!(c.readout, Readout::BestParticle);
        // back to first-n over s1, to the bicycle over mrclam, no gate over mrclam
        let c = SlamotConfig::from_toml("target_init = { kind = \"first-n\" }", Some(Preset::S1))
            .unwrap();
        assert_eq!(c.target_init, TargetInit::FirstN);
        let c = SlamotConfig::from_toml(
            "motion = { kind = \"bicycle\", wheelbase = 2.0 }\nlandmark_gate = \"none\"",
            Some(Preset::Mrclam),
        )
        .unwrap();
        assert_eq!(c.motion, RobotMotion::Bicycle { wheelbase: 2.0 });
        assert_eq!(c.landmark_gate, None);
        let c = SlamotConfig::from_toml("motion = { kind = \"unicycle\" }", None).unwrap();
        assert_eq!(c.motion, RobotMotion::Unicycle);
        // unknown keys, wrong types and bad values are errors naming them
        for bad in [
            "particels = 20",
            "[motion]\nkind = \"bicycle\"\nwheelbas = 4.0",
            "particles = \"many\"",
            "association = \"gnn\"",
            "sensor_range = \"far\"",
        ] {
            let e = SlamotConfig::from_toml(bad, None).unwrap_err();
            assert!(matches!(e, TrackerError::Toml { .. }), "{bad}: {e}");
        }
        let e = SlamotConfig::from_toml("particles = 0", None).unwrap_err();
        assert!(e.to_string().contains("particles"), "{e}");
        let e = SlamotConfig::from_toml("track_management = true", None).unwrap_err();
        assert!(e.to_string().contains("track_management"), "{e}");
        let e = SlamotConfig::from_toml("preset = \"mrclam\"", Some(Preset::S1)).unwrap_err();
        assert!(matches!(e, TrackerError::Config { .. }), "{e}");
    }

    #[test]
    fn validate_checks_every_field() {
        let ok = SlamotConfig::default();
        let bad = [
            SlamotConfig {
                sensor_range: Some(-1.0),
                ..ok.clone()
            },
            SlamotConfig {
                landmark_gate: Some(f64::NAN),
                ..ok.clone()
            },
            SlamotConfig {
                sensor_fov: 0.0,
                ..ok.clone()
            },
            SlamotConfig {
                p_detect_outside: 0.0,
                ..ok.clone()
            },
            SlamotConfig {
                delete_existence: 0.95,
                ..ok.clone()
            },
            SlamotConfig {
                max_slots: 0,
                ..SlamotConfig::mrclam()
            },
            SlamotConfig {
                n_targets: 0,
                ..ok.clone()
            },
            SlamotConfig {
                motion: RobotMotion::Bicycle { wheelbase: 0.0 },
                ..ok.clone()
            },
        ];
        for c in bad {
            assert!(
                matches!(
                    c.validate(),
                    Err(TrackerError::Config {
                        tracker: "slamot",
                        ..
                    })
                ),
                "{c:?}"
            );
        }
        // n_targets is ignored with track management
        SlamotConfig {
            n_targets: 0,
            ..SlamotConfig::mrclam()
        }
        .validate()
        .unwrap();
    }
}
