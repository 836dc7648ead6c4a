//! [`LidarPeopleConfig`]: every parameter of spec 003 §3, serde/TOML, `Default` = `faithful`.

use crate::TrackerError;
use serde::{Deserialize, Serialize};

/// The three presets of spec 003: switches over one code path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The paper read word for word (ablation): model→data ICP from the cluster centre, no
    /// trimming, K_m = 16, nearest-mode association, no revealed-background rule.
    Literal,
    /// The reproduction (default): the paper's structure with the smallest documented gap fills.
    #[default]
    Faithful,
    /// The same detector, then a CV Kalman filter, χ² gate, Hungarian GNN and M-of-N.
    KfGnn,
    /// The same detector, then quarry-assoc's JIPDA over CV Kalman tracks (the `cv_jpda`
    /// tracker): soft association, the PDA update, and birth, confirmation and death by the
    /// probability that the track exists, so a track coasts through short occlusions.
    Jipda,
}

impl crate::PresetName for Preset {
    const ALL: &'static [Self] = &[Self::Faithful, Self::Literal, Self::KfGnn, Self::Jipda];
    const TRACKER: &'static str = "lidar_people";

    fn name(self) -> &'static str {
        match self {
            Self::Literal => "literal",
            Self::Faithful => "faithful",
            Self::KfGnn => "kf-gnn",
            Self::Jipda => "jipda",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Literal => "the paper's Table 1 read word for word (ablation)",
            Self::Faithful => "the paper's structure with the spec's gap fills (default)",
            Self::KfGnn => "the same detector, then CV Kalman + chi-square gate + GNN + M-of-N",
            Self::Jipda => {
                "the same detector, then CV Kalman + JIPDA with track existence (coasts through occlusions)"
            }
        }
    }
}

/// Where the `kf-gnn` tracker's detections come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Detector {
    /// MeanShift clusters fitted with the torso ellipse by ICP (spec 003 §2.5–2.6; default).
    #[default]
    Contour,
    /// Leg clusters paired into people (`quarry_cloud::legs`): one scanner at leg height.
    Legs,
}

impl Detector {
    /// Parses `contour` or `legs`.
    pub fn parse(s: &str) -> Result<Self, TrackerError> {
        match s {
            "contour" => Ok(Self::Contour),
            "legs" => Ok(Self::Legs),
            _ => Err(TrackerError::config(
                "lidar_people",
                format!("unknown detector {s:?} (expected contour or legs)"),
            )),
        }
    }

    /// `contour` or `legs`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Contour => "contour",
            Self::Legs => "legs",
        }
    }
}

/// Which time the server fuses scans by (spec 003 §5, option `fusion`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum FusionTime {
    /// The clients' synchronised capture stamps (§2.4; default).
    #[default]
    Capture,
    /// The server's arrival times, ignoring the stamps: a negative control (§8), which puts
    /// scans delayed by the network into later frames.
    Arrival,
}

/// How the server obtains the scanners' world poses (spec 003 §2.3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Calibration {
    /// The poses come from the configuration (in the simulator: the true poses). The spec's
    /// default for the simulator.
    #[default]
    Given,
    /// The server registers the clients' long-term backgrounds `b_n` at the end of the warm-up
    /// (trimmed ICP from rough poses, quarry-cloud's `calib`) and fuses with the calibrated poses.
    Icp,
}

impl Calibration {
    /// Parses `given` or `icp`.
    pub fn parse(s: &str) -> Result<Self, TrackerError> {
        match s {
            "given" => Ok(Self::Given),
            "icp" => Ok(Self::Icp),
            _ => Err(TrackerError::config(
                "lidar_people",
                format!("unknown calibration {s:?} (expected given or icp)"),
            )),
        }
    }

    /// `given` or `icp`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Given => "given",
            Self::Icp => "icp",
        }
    }
}

/// Largest background window `window_m` (scans; 100 s at 40 Hz): each scanner keeps
/// `window_m` ranges per beam.
pub const MAX_WINDOW_M: usize = 4000;
/// Largest number of contour model points `k_m`.
pub const MAX_K_M: usize = 4096;
/// Largest ICP iteration cap `icp_it_max`.
pub const MAX_ICP_IT: u32 = 10_000;
/// Largest minimum support `min_num_point`.
pub const MAX_MIN_NUM_POINT: usize = 100_000;
/// Largest value of a time parameter (`t_warm_s`, `t_relearn_s`, `frame_period_s`,
/// `tau_sync_s`, `l_max_s`), seconds: ten minutes. The warm-up keeps `t_warm_s` worth of scans
/// per scanner (about 100 MB for a 40 Hz, 1081-beam scanner at the limit).
pub const MAX_SECONDS: f64 = 600.0;

/// Every parameter of spec 003 §3. Tags: **\[P\]** paper, **\[D\]** UTM-30LX datasheet, **\[Q\]**
/// proposed by the spec (with the reason given there).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarPeopleConfig {
    /// Which preset the switches below came from (informational; the switches rule).
    pub preset: Preset,

    // ----- background (§2.2) -----
    /// Background window m, scans [Q: 40 = 1 s; lag 5 cm at 0.10 m/s].
    pub window_m: usize,
    /// Static-probability threshold P_th [P: 0.9].
    pub p_th: f64,
    /// Tolerance factor κ: σ_bg = κ·σ_d(d) [Q: 7, §6 A1].
    pub kappa: f64,
    /// Region-constraint radius δ, metres [Q: 0.30].
    pub delta_region: f64,
    /// Long-term background with the revealed-background override [Q; off in `literal`].
    pub revealed_background: bool,
    /// Background warm-up T_warm, seconds [Q: 5].
    pub t_warm_s: f64,
    /// Background update rate α_b [Q: 0.02].
    pub alpha_b: f64,
    /// Relearn time T_relearn, seconds [Q: 2].
    pub t_relearn_s: f64,
    /// Update b_n only from static readings within τ_g of it [Q: true; the ungated update
    /// drifts toward people and leaves wall ghosts — see docs/lidar-people.md].
    pub bg_gated_update: bool,
    /// Early start of the background, metres (0 = off, the spec's rule (3): every beam is
    /// dynamic until the window holds `window_m / 2` readings, and [`super::run_recorded`]
    /// tracks nothing before that). When > 0, each beam is compared during those first scans
    /// with the farthest range it has returned so far, and a reading at least this far in front
    /// of it is dynamic (quarry-cloud `ChiSquareConfig::early_start`), so tracking starts at the
    /// first scan. [not in the spec; `jipda`: 0.10 m, 0 (off) in the other presets. The value
    /// was set by reasoning before any run: a leg's diameter, since a person is at least that
    /// far in front of the wall behind them, and 10σ of the datasheet range noise, the margin
    /// the farthest of a few noisy readings needs. Measured in docs/lidar-people.md ("Early
    /// start"); the room scenarios spawn people after 5 s of empty room, so it changes none of
    /// their results.]
    pub bg_early_start_m: f64,
    /// Beams that return only now and then get a background (quarry-cloud
    /// `LongTermConfig::sparse_beams`): a beam with under half valid readings during the
    /// warm-up still gets `b_n` when at least half of its valid readings (and two or more) lie
    /// within τ_g of their median. [not in the spec; `jipda`: true, false in the other presets.
    /// Without it such a beam (a dark or shiny surface, a wall at the range limit) is dynamic
    /// by rule (3) each time it returns, and its returns are leg-sized clutter that never
    /// moves: on the leg-height recordings long static tracks behind the scanner and at the
    /// demo's far wall (docs/lidar-people.md, "Beams that return now and then"). No number: the
    /// majority of the returns and the spec's τ_g.]
    pub bg_sparse_beams: bool,

    // ----- fusion (§2.4) -----
    /// Fused-frame interval T_F, seconds [P: 0.05].
    pub frame_period_s: f64,
    /// Fusion time tolerance τ_sync, seconds [Q: 0.0125, half a scan period].
    pub tau_sync_s: f64,
    /// Maximum accepted latency L_max, seconds [Q: 0.1].
    pub l_max_s: f64,
    /// Fuse by capture stamps (default) or by arrival times (`fusion = arrival`, a negative
    /// control of §8).
    pub fusion: FusionTime,

    // ----- MeanShift (§2.5) -----
    /// Flat-kernel bandwidth h, metres [Q: 0.30].
    pub bandwidth: f64,
    /// Minimum cluster size n_min [Q: 3].
    pub n_min_cluster: usize,

    // ----- contour and ICP (§2.6) -----
    /// Ellipse semi-axis a_m (shoulders), metres [Q: 0.22].
    pub a_m: f64,
    /// Ellipse semi-axis b_m (chest depth), metres [Q: 0.13].
    pub b_m: f64,
    /// Model points K_m [Q: 72; `literal` 16].
    pub k_m: usize,
    /// ICP RMS stop e, metres [rule P, value Q: 0.01].
    pub icp_e: f64,
    /// ICP stop on ΔRMS ε_Δ, metres [Q: 1e-4].
    pub icp_eps_delta: f64,
    /// ICP iteration cap it_max [Q: 30].
    pub icp_it_max: u32,
    /// Correspondences data→model (default) or model→data (`literal`, the paper's step ①).
    pub icp_data_to_model: bool,
    /// Trimming τ_out: 0.25 m for the first 3 iterations, then 0.10 m [Q; off in `literal`].
    pub icp_trim: bool,
    /// Removal margin r_m, metres [Q: 0.10].
    pub r_m: f64,
    /// Two orientation starts φ_pca, φ_pca + π/2 for new clusters [Q; `literal`: one start at 0].
    pub two_starts: bool,
    /// With `two_starts`: the second start is skipped when the first already fits with
    /// e* below this, metres [0 = always both starts (`literal`, `faithful`, `kf-gnn`);
    /// `jipda`: 0.037, the median e* of true people on tuning seeds 101–103 (§3's d_m_matching
    /// measurement): a fit that good is not the wrong-orientation minimum the second start is
    /// for].
    pub second_start_above: f64,

    // ----- Table 1 (§2.8) -----
    /// Minimum support min_num_point [Q: 8].
    pub min_num_point: usize,
    /// Maximum match RMS d_m_matching, metres [Q: 0.05; retuned to 0.057 = the 99.5th
    /// percentile of e* for true people on tuning seeds 101–103, as §3 allows (cap 0.06)].
    pub d_m_matching: f64,
    /// ICP data radius for tracks R_icp, metres [Q: a_m + 0.15 = 0.37].
    pub r_icp: f64,
    /// `literal`: a track takes the cluster whose mode is nearest, within R_assoc [Q: 0.5 m].
    pub nearest_mode_assoc: bool,
    /// R_assoc, metres [Q: 0.5].
    pub r_assoc: f64,

    // ----- gate (8) (§2.7) -----
    /// σ_X = σ_Y, metres [Q: 0.06].
    pub sigma_pos: f64,
    /// σ_Ẋ = σ_Ẏ, m/s [Q: 1.5].
    pub sigma_vel: f64,
    /// Gate constant k [Q: √χ²₄(0.99) = 3.644].
    pub gate_k: f64,

    // ----- kf-gnn (§2.9) -----
    /// CWNA intensity q, m²/s³ [Q: 0.5].
    pub kf_q: f64,
    /// Measurement σ_r, metres [Q: 0.03; retuned to 0.045 = the per-axis RMS error of the
    /// contour-fit detections against the true position, 0.043 m pooled over tuning seeds
    /// 101–105 of `band_mid` and 101–103 of `crossing`, rounded up to 5 mm; docs/lidar-people.md].
    pub kf_sigma_r: f64,
    /// χ²₂ gate γ [Q: 9.21 = χ²₂(0.99)].
    pub kf_gamma: f64,
    /// Confirmation M of N [Q: 3 of 4].
    pub kf_m: u32,
    /// Confirmation window N [Q: 4].
    pub kf_n: u32,
    /// Deletion after more than N_del consecutive misses [Q: 5].
    pub kf_n_del: u32,
    /// Report confirmed tracks coasting at most this many frames [Q: 2].
    pub kf_max_coast_report: u32,

    // ----- jipda (issue 17; measured and tuned on tuning seeds 101-105 only,
    //        docs/lidar-people.md "jipda") -----
    /// Detection probability P_D used by JIPDA [tuned: 0.5]. Not the detection rate (0.99
    /// per person-frame for the contour detector on the tuning seeds): misses come in runs
    /// (a person standing half hidden, another person in front), up to 20 frames there, and
    /// JIPDA treats misses as independent. With 0.5 and `jipda_delete` a confirmed track
    /// survives 20 frames (1 s) without a detection; with 0.99 one miss would nearly end it.
    pub jipda_pd: f64,
    /// Gate probability P_G (γ = χ²₂⁻¹(P_G)) [choice: 0.99, as `kf_gamma`].
    pub jipda_prob_gate: f64,
    /// Clutter density κ of false detections, per m² and frame [measured: 0.05]. The contour
    /// detector's false detections on the tuning seeds are second fits of a body that survive
    /// the R_icp suppression: 0.01-0.08 per frame, all 0.2-0.45 m from a person, about
    /// 0.05 m⁻² over the ring around each person.
    pub jipda_clutter: f64,
    /// Probability that a person who exists stays one frame later, p_S [choice: 0.999 per
    /// 50 ms frame: a mean stay of 50 s without evidence].
    pub jipda_survival: f64,
    /// Existence ψ₀ of a track started from an unexplained detection [choice: 0.1].
    pub jipda_birth: f64,
    /// A track is confirmed (reported) once ψ ≥ this [spec 000 A10: 0.9].
    pub jipda_confirm: f64,
    /// A track is deleted once ψ < this [choice: 0.001: with P_D 0.5, 20 frames without a
    /// detection from ψ ≈ 1].
    pub jipda_delete: f64,
    /// Velocity σ of a newborn track, m/s [choice: 1.0, walking speed].
    pub jipda_birth_vel_sigma: f64,
    /// CWNA intensity q of the jipda tracks, m²/s³ [tuned: 4.0, grid 0.5-16]. The walkers'
    /// measured mean intensity is 0.08 (mid band) to 0.38 (fast) m²/s³, but 80-86 % of it
    /// comes as velocity jumps at waypoints; q = 4 with `jipda_sigma_r` keeps the person in
    /// the gate through a jump.
    pub jipda_q: f64,
    /// Measurement σ_r of the contour detections for the jipda tracks, metres [tuned: 0.12,
    /// grid 0.045-0.16]. The detections' noise is 0.045 m per axis (`kf_sigma_r`) with a
    /// heavier tail (radial p99 0.2 m in the fast band, 0.076 m across the walking direction);
    /// the larger value widens the gate to cover the tail and the lag after a turn. With
    /// `detector = legs` the tracker uses `leg_sigma_r`.
    pub jipda_sigma_r: f64,
    /// An unexplained detection within this distance of a track starts no track, metres
    /// [measured: 0.5]. Every second fit left after the suppression lay within 0.45 m of its
    /// person on the tuning seeds; with R_icp = 0.37 such fits started confirmed twins.
    pub jipda_birth_exclusion: f64,
    /// Two jipda tracks closer than this are one person tracked twice: the tentative one, then
    /// the one this frame did not detect, else the younger, is deleted, metres [choice: 0.25 = two torsos' minor semi-axes, the
    /// closest two people's centres can be].
    pub jipda_merge_distance: f64,
    /// A jipda track that has not been detected for more than this many frames is not
    /// reported (it still lives, and is reported again under its id once detected) [choice:
    /// 2, as `kf_max_coast_report`; set after the leg recordings showed coasting ghosts
    /// (docs/lidar-people.md "jipda"); neutral on the tuning seeds].
    pub jipda_max_coast_report: u32,

    // ----- leg detector (one scanner at leg height; quarry_cloud::legs) -----
    /// The detections of the `kf-gnn` and `jipda` trackers: `contour` (default) or `legs`
    /// (the Table 1 trackers need contour fits).
    pub detector: Detector,
    /// Single-linkage distance of leg clusters, metres [leg_tracker `cluster_dist_euclid`: 0.13].
    pub leg_cluster_dist: f64,
    /// Minimum points of a leg cluster [leg_tracker `min_points_per_cluster`: 3].
    pub leg_min_points: usize,
    /// Largest extent of a leg cluster, metres [choice: 0.45, two legs side by side].
    pub leg_max_width: f64,
    /// Largest distance between a person's two legs, metres [leg_tracker
    /// `max_leg_pairing_dist`: 0.8].
    pub leg_pair_dist: f64,
    /// An unpaired leg is a person at its centroid [choice: true].
    pub leg_single: bool,
    /// Measurement σ_r of a leg detection, metres, used instead of `kf_sigma_r` [choice: 0.10:
    /// the midpoint of two legs moves about the hips by a few cm during a stride, and a single
    /// leg is up to 0.3-0.4 m (half a stride) from it, which a 0.10 m σ keeps within the
    /// χ²₂(0.99) gate of a predicted track; not fitted to any recording].
    pub leg_sigma_r: f64,
    /// With `detector = legs`, a track is reported only once it has moved this far from where
    /// it was born, metres [leg_tracker `dist_travelled_together_to_initiate_leg_pair`: 0.5].
    /// Static leg-like clutter the background model lets through (chair and table legs, beams
    /// that flicker between a return and none) then never becomes a track; a person who stands
    /// still from the start is reported once they walk. 0 turns it off.
    pub leg_min_travel_m: f64,
    /// `jipda_merge_distance` for `detector = legs`, metres (0 = no merging) [choice, made on
    /// positive_3 and disclosed as such in docs/lidar-people.md: 0. The merge rule answers the
    /// contour detector's second fits of one body (twins); a leg pair gives one detection per
    /// person and no second fits. On positive_3 the rule deleted a walker's track where two
    /// people passed each other 0.3 m apart (t = 20.5 s): the walker was reported again 1.1 s
    /// later under a new id].
    pub leg_merge_distance: f64,

    // ----- evaluation (§4) -----
    /// Evaluation match threshold d_match, metres [Q: 0.5].
    pub d_match: f64,

    // ----- extrinsic calibration (§2.3) -----
    /// `given` (default in the simulator) or `icp` (from the clients' backgrounds).
    pub calibration: Calibration,
    /// `icp`: sensor id of the reference scanner s₀, whose configured pose is taken as exact
    /// [choice: 0, scanner A].
    pub calib_reference: u16,
    /// `icp` in the simulator without `calib_rough_poses`: the rough poses are the true poses
    /// moved by a seeded draw of at most this many metres [spec §5 `calib`: 0.3].
    pub calib_max_shift_m: f64,
    /// ... and turned by at most this many degrees [spec §5 `calib`: 10].
    pub calib_max_rot_deg: f64,
    /// `icp`: rough ("hand-measured") poses `[x m, y m, θ degrees]`, one per scanner in the
    /// scenario's order, instead of the seeded draw; the reference's entry is its exact pose.
    /// Empty (default): the seeded draw.
    pub calib_rough_poses: Vec<[f64; 3]>,
    /// `icp`: refuse the calibration when, under the calibrated poses, more than this fraction
    /// of the background points of the other scanners lie in the free space a scanner saw
    /// through (or its points in theirs) [choice: 0.02; an addition to §2.3 step 4, whose overlap
    /// and RMS bounds accept scanners slid along a wall; measured 0 at every correct
    /// calibration, ≥ 0.07 at every wrong one, docs/lidar-people.md].
    pub calib_max_free_space_violation: f64,
    /// `icp`: point-to-line registration (Censi 2008, the upgrade §2.3 allows; default `true`)
    /// or the spec's plain point-to-point ICP with the closed-form solve (`false`).
    pub calib_point_to_line: bool,
}

impl Default for LidarPeopleConfig {
    fn default() -> Self {
        Self::faithful()
    }
}

impl LidarPeopleConfig {
    /// The `faithful` preset (the default).
    pub fn faithful() -> Self {
        Self {
            preset: Preset::Faithful,
            window_m: 40,
            p_th: 0.9,
            kappa: 7.0,
            delta_region: 0.30,
            revealed_background: true,
            t_warm_s: 5.0,
            alpha_b: 0.02,
            t_relearn_s: 2.0,
            bg_gated_update: true,
            bg_early_start_m: 0.0,
            bg_sparse_beams: false,
            frame_period_s: 0.05,
            tau_sync_s: 0.0125,
            l_max_s: 0.1,
            fusion: FusionTime::Capture,
            bandwidth: 0.30,
            n_min_cluster: 3,
            a_m: 0.22,
            b_m: 0.13,
            k_m: 72,
            icp_e: 0.01,
            icp_eps_delta: 1e-4,
            icp_it_max: 30,
            icp_data_to_model: true,
            icp_trim: true,
            r_m: 0.10,
            two_starts: true,
            second_start_above: 0.0,
            min_num_point: 8,
            d_m_matching: 0.057,
            r_icp: 0.37,
            nearest_mode_assoc: false,
            r_assoc: 0.5,
            sigma_pos: 0.06,
            sigma_vel: 1.5,
            gate_k: 3.643_721,
            kf_q: 0.5,
            kf_sigma_r: 0.045,
            kf_gamma: 9.21,
            kf_m: 3,
            kf_n: 4,
            kf_n_del: 5,
            kf_max_coast_report: 2,
            jipda_pd: 0.5,
            jipda_prob_gate: 0.99,
            jipda_clutter: 0.05,
            jipda_survival: 0.999,
            jipda_birth: 0.1,
            jipda_confirm: 0.9,
            jipda_delete: 0.001,
            jipda_birth_vel_sigma: 1.0,
            jipda_q: 4.0,
            jipda_sigma_r: 0.12,
            jipda_birth_exclusion: 0.5,
            jipda_merge_distance: 0.25,
            jipda_max_coast_report: 2,
            detector: Detector::Contour,
            leg_cluster_dist: 0.13,
            leg_min_points: 3,
            leg_max_width: 0.45,
            leg_pair_dist: 0.8,
            leg_single: true,
            leg_sigma_r: 0.10,
            leg_min_travel_m: 0.5,
            leg_merge_distance: 0.0,
            d_match: 0.5,
            calibration: Calibration::Given,
            calib_reference: 0,
            calib_max_shift_m: 0.3,
            calib_max_rot_deg: 10.0,
            calib_rough_poses: Vec::new(),
            calib_max_free_space_violation: 0.02,
            calib_point_to_line: true,
        }
    }

    /// The `literal` preset.
    pub fn literal() -> Self {
        Self {
            preset: Preset::Literal,
            revealed_background: false,
            k_m: 16,
            icp_data_to_model: false,
            icp_trim: false,
            two_starts: false,
            nearest_mode_assoc: true,
            ..Self::faithful()
        }
    }

    /// The `kf-gnn` preset.
    pub fn kf_gnn() -> Self {
        Self {
            preset: Preset::KfGnn,
            ..Self::faithful()
        }
    }

    /// The `jipda` preset.
    pub fn jipda() -> Self {
        Self {
            preset: Preset::Jipda,
            second_start_above: 0.037,
            bg_early_start_m: 0.10,
            bg_sparse_beams: true,
            ..Self::faithful()
        }
    }

    /// The `cv_jpda` tracker configuration of the `jipda` preset: JIPDA with the `jipda_*`
    /// values (σ_r is `leg_sigma_r` with `detector = legs`, else `jipda_sigma_r`).
    pub fn jipda_tracker(&self) -> crate::cv_jpda::JpdaTrackerConfig {
        use crate::cv_jpda::{AssocMode, JpdaTrackerConfig};
        JpdaTrackerConfig {
            pd: self.jipda_pd,
            prob_gate: self.jipda_prob_gate,
            clutter_density: self.jipda_clutter,
            q: self.jipda_q,
            sigma_meas: if self.detector == Detector::Legs {
                self.leg_sigma_r
            } else {
                self.jipda_sigma_r
            },
            mode: AssocMode::Jipda,
            birth_vel_sigma: self.jipda_birth_vel_sigma,
            existence: quarry_assoc::lifecycle::ExistenceThresholds {
                birth: self.jipda_birth,
                confirm: self.jipda_confirm,
                delete: self.jipda_delete,
            },
            survival: self.jipda_survival,
            report_tentative: false,
            birth_exclusion: self.jipda_birth_exclusion,
            merge_distance: if self.detector == Detector::Legs {
                self.leg_merge_distance
            } else {
                self.jipda_merge_distance
            },
            ..JpdaTrackerConfig::default()
        }
    }
}

impl crate::TrackerConfig for LidarPeopleConfig {
    type Preset = Preset;
    const NAME: &'static str = "lidar_people";

    fn preset(p: Preset) -> Self {
        match p {
            Preset::Literal => Self::literal(),
            Preset::Faithful => Self::faithful(),
            Preset::KfGnn => Self::kf_gnn(),
            Preset::Jipda => Self::jipda(),
        }
    }

    /// Checks every value is usable.
    fn validate(&self) -> Result<(), TrackerError> {
        let pos = [
            ("p_th", self.p_th),
            ("kappa", self.kappa),
            ("delta_region", self.delta_region),
            ("t_warm_s", self.t_warm_s),
            ("alpha_b", self.alpha_b),
            ("t_relearn_s", self.t_relearn_s),
            ("frame_period_s", self.frame_period_s),
            ("tau_sync_s", self.tau_sync_s),
            ("l_max_s", self.l_max_s),
            ("bandwidth", self.bandwidth),
            ("a_m", self.a_m),
            ("b_m", self.b_m),
            ("d_m_matching", self.d_m_matching),
            ("r_icp", self.r_icp),
            ("r_assoc", self.r_assoc),
            ("sigma_pos", self.sigma_pos),
            ("sigma_vel", self.sigma_vel),
            ("gate_k", self.gate_k),
            ("kf_q", self.kf_q),
            ("kf_sigma_r", self.kf_sigma_r),
            ("kf_gamma", self.kf_gamma),
            ("d_match", self.d_match),
            ("leg_cluster_dist", self.leg_cluster_dist),
            ("leg_max_width", self.leg_max_width),
            ("leg_pair_dist", self.leg_pair_dist),
            ("leg_sigma_r", self.leg_sigma_r),
        ];
        for (name, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(TrackerError::config(
                    "lidar_people",
                    format!("{name} must be finite and > 0, got {v}"),
                ));
            }
        }
        let nonneg = [
            ("icp_e", self.icp_e),
            ("icp_eps_delta", self.icp_eps_delta),
            ("r_m", self.r_m),
            ("second_start_above", self.second_start_above),
            ("bg_early_start_m", self.bg_early_start_m),
            ("leg_merge_distance", self.leg_merge_distance),
        ];
        for (name, v) in nonneg {
            if !(v.is_finite() && v >= 0.0) {
                return Err(TrackerError::config(
                    "lidar_people",
                    format!("{name} must be finite and >= 0, got {v}"),
                ));
            }
        }
        if !(self.p_th < 1.0 && self.alpha_b <= 1.0) {
            return Err(TrackerError::config(
                "lidar_people",
                "p_th must be < 1 and alpha_b <= 1",
            ));
        }
        if self.window_m < 2 || self.k_m < 3 || self.icp_it_max == 0 || self.min_num_point == 0 {
            return Err(TrackerError::config(
                "lidar_people",
                "window_m >= 2, k_m >= 3, icp_it_max >= 1 and min_num_point >= 1 are required",
            ));
        }
        for (name, v) in [
            ("calib_max_shift_m", self.calib_max_shift_m),
            ("calib_max_rot_deg", self.calib_max_rot_deg),
            (
                "calib_max_free_space_violation",
                self.calib_max_free_space_violation,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(TrackerError::config(
                    "lidar_people",
                    format!("{name} must be finite and >= 0, got {v}"),
                ));
            }
        }
        // upper bounds where memory or work grows with the value (per scanner: the warm-up
        // buffer holds t_warm_s worth of scans, the window window_m scans, the model k_m points)
        for (name, v, max) in [
            ("window_m", self.window_m as f64, MAX_WINDOW_M as f64),
            ("k_m", self.k_m as f64, MAX_K_M as f64),
            ("icp_it_max", f64::from(self.icp_it_max), MAX_ICP_IT as f64),
            (
                "min_num_point",
                self.min_num_point as f64,
                MAX_MIN_NUM_POINT as f64,
            ),
            ("t_warm_s", self.t_warm_s, MAX_SECONDS),
            ("t_relearn_s", self.t_relearn_s, MAX_SECONDS),
            ("frame_period_s", self.frame_period_s, MAX_SECONDS),
            ("tau_sync_s", self.tau_sync_s, MAX_SECONDS),
            ("l_max_s", self.l_max_s, MAX_SECONDS),
        ] {
            if v > max {
                return Err(TrackerError::config(
                    "lidar_people",
                    format!("{name} must be at most {max}, got {v}"),
                ));
            }
        }
        if let Some((i, p)) = self
            .calib_rough_poses
            .iter()
            .enumerate()
            .find(|(_, p)| !p.iter().all(|v| v.is_finite()))
        {
            return Err(TrackerError::config(
                "lidar_people",
                format!("calib_rough_poses[{i}] must be finite, got {p:?}"),
            ));
        }
        if self.calibration == Calibration::Icp && !self.revealed_background {
            return Err(TrackerError::config(
                "lidar_people",
                "calibration = icp needs the long-term background b_n (revealed_background = true; the literal preset keeps none)",
            ));
        }
        if !(self.leg_min_travel_m.is_finite() && self.leg_min_travel_m >= 0.0) {
            return Err(TrackerError::config(
                "lidar_people",
                format!(
                    "leg_min_travel_m must be finite and >= 0, got {}",
                    self.leg_min_travel_m
                ),
            ));
        }
        if self.leg_min_points == 0 || self.leg_min_points > MAX_MIN_NUM_POINT {
            return Err(TrackerError::config(
                "lidar_people",
                format!(
                    "leg_min_points must be in 1..={MAX_MIN_NUM_POINT}, got {}",
                    self.leg_min_points
                ),
            ));
        }
        if self.detector == Detector::Legs && !matches!(self.preset, Preset::KfGnn | Preset::Jipda)
        {
            return Err(TrackerError::config(
                "lidar_people",
                format!(
                    "detector = legs needs preset = kf-gnn or jipda (the {} tracker needs contour fits)",
                    crate::PresetName::name(self.preset)
                ),
            ));
        }
        if self.kf_m == 0 || self.kf_m > self.kf_n || self.kf_n > 64 {
            return Err(TrackerError::config(
                "lidar_people",
                "kf-gnn needs 1 <= kf_m <= kf_n <= 64",
            ));
        }
        // the jipda_* values: cv_jpda's own rules, with the keys named as in this file
        if let Err(e) = crate::TrackerConfig::validate(&self.jipda_tracker()) {
            return Err(TrackerError::config(
                "lidar_people",
                format!("jipda_* keys: {e}"),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackerConfig;

    #[test]
    fn values_that_would_allocate_without_bound_are_refused_by_name() {
        for (toml, name) in [
            ("k_m = 1000000000", "k_m"),
            ("window_m = 1000000000", "window_m"),
            ("t_warm_s = 1e12", "t_warm_s"),
            ("t_relearn_s = 1e9", "t_relearn_s"),
            ("icp_it_max = 4000000000", "icp_it_max"),
        ] {
            let e = LidarPeopleConfig::from_toml(toml, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains(name) && e.contains("at most"), "{toml}: {e}");
        }
        for p in [
            Preset::Faithful,
            Preset::Literal,
            Preset::KfGnn,
            Preset::Jipda,
        ] {
            LidarPeopleConfig::preset(p).validate().unwrap();
        }
    }

    #[test]
    fn toml_round_trip_and_defaults() {
        let c = LidarPeopleConfig::default();
        assert_eq!(c.preset, Preset::Faithful);
        let t = c.to_toml().unwrap();
        assert_eq!(LidarPeopleConfig::from_toml(&t, None).unwrap(), c);
        let l = LidarPeopleConfig::from_toml("preset = \"literal\"\nk_m = 16\n", None).unwrap();
        assert_eq!(l.k_m, 16);
        assert_eq!(l.window_m, 40);
        assert!(LidarPeopleConfig::from_toml("bandwidth = -1.0", None).is_err());
        // the jipda keys: each bad value is refused, naming its key
        for (bad, key) in [
            ("second_start_above = -0.1", "second_start_above"),
            ("jipda_pd = 1.5", "jipda_*"),
            ("jipda_sigma_r = 0.0", "jipda_*"),
            ("jipda_birth_exclusion = nan", "jipda_*"),
            ("jipda_merge_distance = -1.0", "jipda_*"),
            ("leg_merge_distance = -1.0", "leg_merge_distance"),
            ("bg_early_start_m = -0.1", "bg_early_start_m"),
            ("jipda_delete = 0.95", "jipda_*"),
        ] {
            let e = LidarPeopleConfig::from_toml(bad, Some(Preset::Jipda)).unwrap_err();
            assert!(e.to_string().contains(key), "{bad}: {e}");
        }
        let j = LidarPeopleConfig::preset(Preset::Jipda);
        assert_eq!(
            LidarPeopleConfig::from_toml(&j.to_toml().unwrap(), None).unwrap(),
            j
        );
        assert!(LidarPeopleConfig::from_toml("nonsense = 1", None).is_err());
        assert_eq!(LidarPeopleConfig::literal().k_m, 16);
        assert!(!LidarPeopleConfig::literal().icp_trim);
        assert!((c.gate_k * c.gate_k - 13.2767).abs() < 1e-3);
        assert_eq!(c.fusion, FusionTime::Capture);
        let a = LidarPeopleConfig::from_toml("fusion = \"arrival\"", None).unwrap();
        assert_eq!(a.fusion, FusionTime::Arrival);
        assert_eq!(
            LidarPeopleConfig::from_toml(&a.to_toml().unwrap(), None).unwrap(),
            a
        );
        assert!(LidarPeopleConfig::from_toml("fusion = \"guess\"", None).is_err());
    }

    #[test]
    fn calibration_switch_parses_and_validates() {
        assert_eq!(LidarPeopleConfig::default().calibration, Calibration::Given);
        let c = LidarPeopleConfig::from_toml(
            "calibration = \"icp\"\ncalib_reference = 1\ncalib_rough_poses = [[0.3, 0.2, 44.0], [9.7, 0.3, 136.0], [5.0, 7.7, -91.0]]\n", None)
        .unwrap();
        assert_eq!(c.calibration, Calibration::Icp);
        assert_eq!(c.calib_reference, 1);
        assert_eq!(c.calib_rough_poses[2], [5.0, 7.7, -91.0]);
        assert_eq!(
            LidarPeopleConfig::from_toml(&c.to_toml().unwrap(), None).unwrap(),
            c
        );
        assert!(LidarPeopleConfig::from_toml("calibration = \"sideways\"", None).is_err());
        assert!(LidarPeopleConfig::from_toml("calib_max_shift_m = -0.1", None).is_err());
        assert!(LidarPeopleConfig::from_toml("calib_max_rot_deg = nan", None).is_err());
        let bad = LidarPeopleConfig {
            calib_rough_poses: vec![[0.0, f64::INFINITY, 0.0]],
            ..LidarPeopleConfig::default()
        };
        assert!(bad.validate().is_err());
        assert_eq!(Calibration::parse("icp").unwrap(), Calibration::Icp);
        assert!(Calibration::parse("ICP!").is_err());
        assert_eq!(Calibration::Given.name(), "given");
    }
}
