//! Batch smoothing of a 2-D landmark-SLAM recording: every pose and landmark at once, by
//! Levenberg–Marquardt over the whole trajectory, with robust (Huber) range-bearing factors and
//! self-calibration of the odometry.
//!
//! A forward filter (the RBPF of [`crate::rbpf`], an EKF) fixes each pose when it is reached and
//! never revisits it: the heading it carried across a stretch without landmarks, or the map frame
//! it set before the first sighting, stays wrong even when later data show it. A smoother uses
//! all the data for every pose. This one estimates, from an odometry record (unicycle or bicycle
//! controls, [`OdometryModel`]) and range-bearing detections of landmarks with **known
//! identity**:
//!
//! - the robot pose at every *node* (the times the caller chooses, typically the detection
//!   epochs), each pair of consecutive nodes tied by the odometry integrated between them, with
//!   the covariance the per-step control noise gives over that interval (the filters'
//!   [`Unicycle`] and [`Bicycle`] models, so the same noise values apply);
//! - every landmark's position;
//! - optionally, the odometry's calibration ([`Calibration`]): a speed scale, a turn-rate scale,
//!   a turn-rate bias and a time offset between the odometry's stamps and the motion (commanded
//!   rather than measured velocities lead the motion), each with a Gaussian prior about "no
//!   error" ([`CalibrationPrior`]). A biased odometry otherwise bends the map the filter builds
//!   before it sees landmarks; calibrated with the whole recording, the early odometry is
//!   corrected too.
//!
//! The first node has a Gaussian prior (the gauge: the map frame is the frame of that prior, as
//! for the filters). Landmark factors use the Huber loss (iteratively reweighted), so a gross
//! outlier (a bearing off by π) pulls with a bounded force.
//!
//! The linear system has an arrow shape: the poses form a block-tridiagonal chain and the
//! landmarks and calibration parameters (`m` of them) are a dense border. It is solved exactly by
//! a block-tridiagonal elimination of the poses and a dense Schur complement of size `m`:
//! `O(n m²)` per iteration for `n` nodes, so a 15-minute recording with a few thousand nodes
//! takes milliseconds per iteration. The dense border limits a problem to
//! [`MAX_LANDMARKS`] landmarks.
//!
//! ```
//! use quarry_core::{LandmarkId, Pose2};
//! use quarry_filter::smoother::{
//!     LandmarkObservation, OdometryStep, SmootherConfig, SmootherProblem, smooth,
//! };
//!
//! // A robot drives 1 m/s along x for 4 s (odometry at 10 Hz) and sees a landmark at (2, 1)
//! // from nodes at t = 0, 1, ..., 4 s.
//! let steps: Vec<OdometryStep> = (1..=40)
//!     .map(|k| OdometryStep { t_end: 0.1 * k as f64, dt: 0.1, control: (1.0, 0.0) })
//!     .collect();
//! let node_times: Vec<f64> = (0..5).map(f64::from).collect();
//! let observations = (0..5)
//!     .map(|i| {
//!         let (dx, dy) = (2.0 - i as f64, 1.0_f64);
//!         LandmarkObservation {
//!             node: i,
//!             landmark: LandmarkId(7),
//!             range: dx.hypot(dy),
//!             bearing: dy.atan2(dx),
//!         }
//!     })
//!     .collect();
//! let problem = SmootherProblem {
//!     prior: Pose2::identity(),
//!     steps,
//!     node_times,
//!     observations,
//!     initial_poses: None,
//!     initial_landmarks: vec![],
//! };
//! let out = smooth(&problem, &SmootherConfig::default())?;
//! assert!((out.poses[4].x - 4.0).abs() < 1e-6);
//! let (id, m) = out.landmarks[0];
//! assert_eq!(id, LandmarkId(7));
//! assert!((m[0] - 2.0).abs() < 1e-6 && (m[1] - 1.0).abs() < 1e-6);
//! # Ok::<(), quarry_filter::FilterError>(())
//! ```

use std::collections::BTreeMap;

use nalgebra::{DMatrix, DVector, Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};
use quarry_core::{CoreError, LandmarkId, MotionModel, Pose2, wrap_angle};

use crate::{Bicycle, FilterError, Unicycle};

/// The most landmarks one problem may hold (the dense border of the linear system is
/// `3 n × 2 L`; beyond this a sparse solver would be needed).
pub const MAX_LANDMARKS: usize = 2_000;

/// The most nodes one problem may hold (100 hours of 10-Hz nodes).
pub const MAX_NODES: usize = 4_000_000;

/// The most entries of the dense border `3 n × (2 L + calibration)` of the linear system
/// (64 Mi doubles = 512 MiB); a larger problem is refused rather than allocated.
pub const MAX_BORDER_ENTRIES: usize = 64 << 20;

/// The most Levenberg–Marquardt iterations a configuration may ask for.
pub const MAX_ITERATIONS: usize = 10_000;

/// One odometry record: the controls held over `[t_end − dt, t_end]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdometryStep {
    /// End of the interval \[s\].
    pub t_end: f64,
    /// Length of the interval \[s\], ≥ 0.
    pub dt: f64,
    /// The controls: `(v [m/s], ω [rad/s])` for [`OdometryModel::Unicycle`], `(V [m/s],
    /// G [rad])` (speed, steering angle) for [`OdometryModel::Bicycle`].
    pub control: (f64, f64),
}

/// The robot's motion model (the filters' models of the same names).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum OdometryModel {
    /// [`Unicycle`]: speed and turn rate, integrated exactly along the arc.
    #[default]
    Unicycle,
    /// [`Bicycle`]: speed and steering angle with this wheelbase \[m\].
    Bicycle {
        /// Wheelbase \[m\], > 0.
        wheelbase: f64,
    },
}

/// The motion model with its control noise.
enum Motion {
    Unicycle(Unicycle),
    Bicycle(Bicycle),
}

impl Motion {
    fn new(m: OdometryModel, sigma: [f64; 2]) -> Result<Self, FilterError> {
        Ok(match m {
            OdometryModel::Unicycle => Self::Unicycle(Unicycle::new(sigma[0], sigma[1])?),
            OdometryModel::Bicycle { wheelbase } => Self::Bicycle(Bicycle::new(
                wheelbase,
                Matrix2::new(sigma[0] * sigma[0], 0.0, 0.0, sigma[1] * sigma[1]),
            )?),
        })
    }

    fn transition(&self, x: &Vector3<f64>, u: &(f64, f64), dt: f64) -> Vector3<f64> {
        match self {
            Self::Unicycle(m) => m.transition(x, u, dt),
            Self::Bicycle(m) => m.transition(x, u, dt),
        }
    }

    fn jacobian(&self, x: &Vector3<f64>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        match self {
            Self::Unicycle(m) => m.jacobian(x, u, dt),
            Self::Bicycle(m) => m.jacobian(x, u, dt),
        }
    }

    fn process_noise(&self, x: &Vector3<f64>, u: &(f64, f64), dt: f64) -> Matrix3<f64> {
        match self {
            Self::Unicycle(m) => m.process_noise(x, u, dt),
            Self::Bicycle(m) => m.process_noise(x, u, dt),
        }
    }
}

/// A range-bearing detection of a landmark of known identity, made at a node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LandmarkObservation {
    /// Index of the node (into [`SmootherProblem::node_times`]).
    pub node: usize,
    /// The landmark's identity.
    pub landmark: LandmarkId,
    /// Range \[m\], > 0.
    pub range: f64,
    /// Bearing in the robot frame \[rad\].
    pub bearing: f64,
}

/// A recording to smooth.
#[derive(Debug, Clone, PartialEq)]
pub struct SmootherProblem {
    /// Prior mean of the first node's pose (the gauge; its spread is
    /// [`SmootherConfig::prior_sigma`]).
    pub prior: Pose2,
    /// The odometry, in time order (intervals must not overlap; gaps between records mean "no
    /// motion"; before the first record its controls hold, after the last the last's).
    pub steps: Vec<OdometryStep>,
    /// The node times \[s\], strictly increasing; node 0 carries the prior.
    pub node_times: Vec<f64>,
    /// The landmark detections.
    pub observations: Vec<LandmarkObservation>,
    /// A starting guess per node (e.g. a forward filter's estimates); `None` = dead reckoning
    /// from the prior.
    pub initial_poses: Option<Vec<Pose2>>,
    /// Starting guesses for landmarks; a landmark without one starts at its first detection.
    pub initial_landmarks: Vec<(LandmarkId, [f64; 2])>,
}

/// The odometry calibration: the motion at time `t` is the model driven by
/// `(speed_scale · v(t − time_offset), turn_scale · ω(t − time_offset) + turn_bias)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// Multiplies the recorded speed.
    pub speed_scale: f64,
    /// Multiplies the recorded turn rate.
    pub turn_scale: f64,
    /// Added to the turn rate \[rad/s\].
    pub turn_bias: f64,
    /// How far the odometry stamps lead the motion \[s\] (positive: the record changes before
    /// the robot moves).
    pub time_offset: f64,
}

impl Calibration {
    /// No error: scales 1, bias 0, offset 0.
    pub const IDENTITY: Calibration = Calibration {
        speed_scale: 1.0,
        turn_scale: 1.0,
        turn_bias: 0.0,
        time_offset: 0.0,
    };

    fn get(&self, k: usize) -> f64 {
        match k {
            0 => self.speed_scale,
            1 => self.turn_scale,
            2 => self.turn_bias,
            _ => self.time_offset,
        }
    }

    fn set(&mut self, k: usize, v: f64) {
        match k {
            0 => self.speed_scale = v,
            1 => self.turn_scale = v,
            2 => self.turn_bias = v,
            _ => self.time_offset = v,
        }
    }
}

impl Default for Calibration {
    fn default() -> Self {
        Self::IDENTITY
    }
}

/// Which calibration parameters are estimated, each with the standard deviation of its Gaussian
/// prior about [`Calibration::IDENTITY`]; `None` holds the parameter at its identity value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationPrior {
    /// σ of the speed scale (dimensionless).
    pub speed_scale: Option<f64>,
    /// σ of the turn-rate scale (dimensionless).
    pub turn_scale: Option<f64>,
    /// σ of the turn-rate bias \[rad/s\].
    pub turn_bias: Option<f64>,
    /// σ of the time offset \[s\].
    pub time_offset: Option<f64>,
}

impl CalibrationPrior {
    /// Nothing estimated: the odometry is taken as recorded.
    pub const NONE: CalibrationPrior = CalibrationPrior {
        speed_scale: None,
        turn_scale: None,
        turn_bias: None,
        time_offset: None,
    };

    /// Everything estimated with weak priors: scales σ 0.1 (a wheel radius or gyro scale off by
    /// up to ~20 %), bias σ 0.05 rad/s (≈ 3 °/s, a poor gyro), offset σ 0.5 s (a command
    /// pipeline's delay). Weak enough for the data to decide on a recording of minutes.
    pub const WEAK: CalibrationPrior = CalibrationPrior {
        speed_scale: Some(0.1),
        turn_scale: Some(0.1),
        turn_bias: Some(0.05),
        time_offset: Some(0.5),
    };

    fn sigmas(&self) -> [Option<f64>; 4] {
        [
            self.speed_scale,
            self.turn_scale,
            self.turn_bias,
            self.time_offset,
        ]
    }
}

/// The smoother's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmootherConfig {
    /// The robot's motion model.
    pub motion: OdometryModel,
    /// Control noise per odometry step: standard deviations of the two controls (as
    /// [`Unicycle::sigma_v`] / [`Unicycle::sigma_omega`], or the square roots of the diagonal of
    /// [`Bicycle::control_noise`]).
    pub control_sigma: [f64; 2],
    /// Range noise \[m\].
    pub sigma_range: f64,
    /// Bearing noise \[rad\].
    pub sigma_bearing: f64,
    /// Huber threshold on a detection's whitened residual norm; `None` = plain least squares.
    /// Default 1.345 (95 % efficiency at Gaussian data: the textbook value).
    pub huber_k: Option<f64>,
    /// Standard deviations of the first node's prior (x, y \[m\], θ \[rad\]).
    pub prior_sigma: [f64; 3],
    /// The calibration parameters to estimate.
    pub calibration: CalibrationPrior,
    /// Iteration limit (≤ [`MAX_ITERATIONS`]).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub tolerance: f64,
    /// A floor on each odometry factor's standard deviations (position \[m\], heading \[rad\]),
    /// so that two nodes a few microseconds apart do not make the system ill-conditioned.
    pub min_segment_sigma: [f64; 2],
}

impl Default for SmootherConfig {
    /// Noise of a small indoor robot (σ_v 0.05 m/s and σ_ω 0.1 rad/s per step, 0.05 m and
    /// 0.01 rad detections), a tight prior (1 mm, 1 mrad), Huber 1.345, no calibration, up to
    /// 100 iterations to a relative cost change of 1e-9.
    fn default() -> Self {
        Self {
            motion: OdometryModel::Unicycle,
            control_sigma: [0.05, 0.1],
            sigma_range: 0.05,
            sigma_bearing: 0.01,
            huber_k: Some(1.345),
            prior_sigma: [1e-3, 1e-3, 1e-3],
            calibration: CalibrationPrior::NONE,
            max_iterations: 100,
            tolerance: 1e-9,
            min_segment_sigma: [1e-4, 1e-5],
        }
    }
}

impl SmootherConfig {
    /// Checks every value: noises finite and > 0, the Huber threshold > 0, the priors finite and
    /// > 0, the iteration limit at most [`MAX_ITERATIONS`], the tolerance finite and ≥ 0.
    pub fn validate(&self) -> Result<(), FilterError> {
        let pos = |name: &'static str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(FilterError::Core(CoreError::invalid(
                    name,
                    format!("{v} (must be finite and > 0)"),
                )))
            }
        };
        pos("control_sigma", self.control_sigma[0])?;
        pos("control_sigma", self.control_sigma[1])?;
        if let OdometryModel::Bicycle { wheelbase } = self.motion {
            pos("wheelbase", wheelbase)?;
        }
        pos("sigma_range", self.sigma_range)?;
        pos("sigma_bearing", self.sigma_bearing)?;
        if let Some(k) = self.huber_k {
            pos("huber_k", k)?;
        }
        for &s in &self.prior_sigma {
            pos("prior_sigma", s)?;
        }
        for s in self.calibration.sigmas().into_iter().flatten() {
            pos("calibration prior sigma", s)?;
        }
        for &s in &self.min_segment_sigma {
            pos("min_segment_sigma", s)?;
        }
        if self.max_iterations > MAX_ITERATIONS {
            return Err(FilterError::Core(CoreError::invalid(
                "max_iterations",
                format!("{} (at most {MAX_ITERATIONS})", self.max_iterations),
            )));
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(FilterError::Core(CoreError::invalid(
                "tolerance",
                format!("{} (must be finite and >= 0)", self.tolerance),
            )));
        }
        Ok(())
    }
}

/// The smoothed recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed {
    /// The pose at every node.
    pub poses: Vec<Pose2>,
    /// Every detected landmark, sorted by id.
    pub landmarks: Vec<(LandmarkId, [f64; 2])>,
    /// The estimated odometry calibration (identity values where not estimated).
    pub calibration: Calibration,
    /// Accepted Levenberg–Marquardt steps.
    pub iterations: usize,
    /// Cost (sum of squared whitened residuals, Huber beyond the threshold) at the start.
    pub initial_cost: f64,
    /// Cost at the end.
    pub final_cost: f64,
    /// True when the relative cost change fell below the tolerance (or no step could lower the
    /// cost) before the iteration limit.
    pub converged: bool,
    /// Detections beyond the Huber threshold at the end (down-weighted as outliers).
    pub downweighted: usize,
}

/// Calls `f(controls, length)` for every piece of constant calibrated controls that drives the
/// motion over `[a, b]` (motion time), in order. Before the first record its controls hold,
/// after the last record the last's (a time offset moves the interval past the record's ends; a
/// robot already moving keeps moving); gaps between records are no motion.
fn for_each_piece(
    steps: &[OdometryStep],
    a: f64,
    b: f64,
    c: &Calibration,
    mut f: impl FnMut((f64, f64), f64),
) {
    let (lo, hi) = (a - c.time_offset, b - c.time_offset);
    let (Some(first), Some(last)) = (steps.first(), steps.last()) else {
        return;
    };
    let u = |s: &OdometryStep| {
        (
            c.speed_scale * s.control.0,
            c.turn_scale * s.control.1 + c.turn_bias,
        )
    };
    let start = first.t_end - first.dt;
    if lo < start && hi > lo {
        f(u(first), hi.min(start) - lo);
    }
    let mut i = steps.partition_point(|s| s.t_end <= lo);
    while i < steps.len() {
        let s = &steps[i];
        let s0 = s.t_end - s.dt;
        if s0 >= hi {
            break;
        }
        let (t0, t1) = (s0.max(lo), s.t_end.min(hi));
        if t1 > t0 {
            f(u(s), t1 - t0);
        }
        i += 1;
    }
    if hi > last.t_end && hi > lo {
        f(u(last), hi - lo.max(last.t_end));
    }
}

/// Integrates the odometry over `[a, b]` (motion time) with calibration `c`, from the identity.
fn integrate(steps: &[OdometryStep], a: f64, b: f64, c: &Calibration, model: &Motion) -> Pose2 {
    let mut x = Vector3::zeros();
    for_each_piece(steps, a, b, c, |u, len| {
        x = model.transition(&x, &u, len);
    });
    Pose2::new(x[0], x[1], x[2])
}

/// The covariance of the relative pose over `[a, b]` under the per-step control noise.
fn segment_covariance(
    steps: &[OdometryStep],
    a: f64,
    b: f64,
    c: &Calibration,
    model: &Motion,
    floor: [f64; 2],
) -> Matrix3<f64> {
    let mut x = Vector3::zeros();
    let mut cov = Matrix3::zeros();
    for_each_piece(steps, a, b, c, |u, len| {
        let f = model.jacobian(&x, &u, len);
        cov = f * cov * f.transpose() + model.process_noise(&x, &u, len);
        x = model.transition(&x, &u, len);
    });
    cov + Matrix3::from_diagonal(&Vector3::new(
        floor[0] * floor[0],
        floor[0] * floor[0],
        floor[1] * floor[1],
    ))
}

/// The current estimate.
#[derive(Clone)]
struct State {
    poses: Vec<Pose2>,
    landmarks: Vec<[f64; 2]>,
    calib: Calibration,
}

/// The arrow-shaped normal equations: pose blocks `d` (diagonal) and `e` (i, i+1), the border
/// `b` (3n × m), its square `c` (m × m), and the gradient.
struct System {
    d: Vec<Matrix3<f64>>,
    e: Vec<Matrix3<f64>>,
    gp: Vec<Vector3<f64>>,
    b: DMatrix<f64>,
    c: DMatrix<f64>,
    gd: DVector<f64>,
}

/// The problem after validation, with the per-segment information matrices.
struct Prepared<'a> {
    p: &'a SmootherProblem,
    cfg: &'a SmootherConfig,
    /// Landmark id of each landmark column.
    ids: Vec<LandmarkId>,
    /// Landmark column of each observation.
    obs_lm: Vec<usize>,
    /// Estimated calibration parameters (indices 0..4 of [`Calibration`]) and their prior σ.
    cal: Vec<(usize, f64)>,
    /// Information of each odometry factor (node i → i+1).
    omega: Vec<Matrix3<f64>>,
    /// The motion model with its control noise.
    model: Motion,
    /// The odometry integrated between consecutive nodes at the identity calibration (used
    /// when no calibration parameter is estimated: the odometry factors are then fixed).
    nominal: Vec<Pose2>,
    prior_info: Matrix3<f64>,
    meas_w: Matrix2<f64>,
}

impl Prepared<'_> {
    fn m(&self) -> usize {
        2 * self.ids.len() + self.cal.len()
    }

    /// Odometry residual between nodes i and i+1.
    fn odo_residual(&self, s: &State, i: usize, calib: &Calibration) -> Vector3<f64> {
        let t = &self.p.node_times;
        let d = if self.cal.is_empty() {
            self.nominal[i]
        } else {
            integrate(&self.p.steps, t[i], t[i + 1], calib, &self.model)
        };
        let (a, b) = (&s.poses[i], &s.poses[i + 1]);
        let (sn, cs) = a.theta.sin_cos();
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        Vector3::new(
            cs * dx + sn * dy - d.x,
            -sn * dx + cs * dy - d.y,
            wrap_angle(b.theta - a.theta - d.theta),
        )
    }

    /// Landmark residual of observation k, with its Jacobians (pose, landmark), or `None` when the
    /// landmark sits on the pose.
    fn lm_residual(
        &self,
        s: &State,
        k: usize,
    ) -> Option<(Vector2<f64>, Matrix2x3<f64>, Matrix2<f64>)> {
        let o = &self.p.observations[k];
        let x = &s.poses[o.node];
        let m = s.landmarks[self.obs_lm[k]];
        let (dx, dy) = (m[0] - x.x, m[1] - x.y);
        let q = dx * dx + dy * dy;
        if q < 1e-18 {
            return None;
        }
        let r = q.sqrt();
        let e = Vector2::new(r - o.range, wrap_angle(dy.atan2(dx) - x.theta - o.bearing));
        let jp = Matrix2x3::new(-dx / r, -dy / r, 0.0, dy / q, -dx / q, -1.0);
        let jm = Matrix2::new(dx / r, dy / r, -dy / q, dx / q);
        Some((e, jp, jm))
    }

    /// Huber weight and cost of a whitened squared norm.
    fn huber(&self, s2: f64) -> (f64, f64) {
        match self.cfg.huber_k {
            Some(k) if s2 > k * k => {
                let n = s2.sqrt();
                (k / n, 2.0 * k * n - k * k)
            }
            _ => (1.0, s2),
        }
    }

    fn prior_residual(&self, s: &State) -> Vector3<f64> {
        let (a, p) = (&s.poses[0], &self.p.prior);
        Vector3::new(a.x - p.x, a.y - p.y, wrap_angle(a.theta - p.theta))
    }

    fn cost(&self, s: &State) -> f64 {
        let n = s.poses.len();
        let pr = self.prior_residual(s);
        let mut c = pr.dot(&(self.prior_info * pr));
        for i in 0..n.saturating_sub(1) {
            let e = self.odo_residual(s, i, &s.calib);
            c += e.dot(&(self.omega[i] * e));
        }
        for k in 0..self.p.observations.len() {
            if let Some((e, _, _)) = self.lm_residual(s, k) {
                c += self.huber(e.dot(&(self.meas_w * e))).1;
            }
        }
        for &(j, sig) in &self.cal {
            let d = (s.calib.get(j) - Calibration::IDENTITY.get(j)) / sig;
            c += d * d;
        }
        c
    }

    fn build(&self, s: &State) -> System {
        let n = s.poses.len();
        let m = self.m();
        let nl2 = 2 * self.ids.len();
        let mut sys = System {
            d: vec![Matrix3::zeros(); n],
            e: vec![Matrix3::zeros(); n.saturating_sub(1)],
            gp: vec![Vector3::zeros(); n],
            b: DMatrix::zeros(3 * n, m),
            c: DMatrix::zeros(m, m),
            gd: DVector::zeros(m),
        };
        // prior on node 0
        let pr = self.prior_residual(s);
        sys.d[0] += self.prior_info;
        sys.gp[0] += self.prior_info * pr;
        // odometry factors
        for i in 0..n.saturating_sub(1) {
            let e = self.odo_residual(s, i, &s.calib);
            let (a, b) = (&s.poses[i], &s.poses[i + 1]);
            let (sn, cs) = a.theta.sin_cos();
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            let ja = Matrix3::new(
                -cs,
                -sn,
                -sn * dx + cs * dy,
                sn,
                -cs,
                -cs * dx - sn * dy,
                0.0,
                0.0,
                -1.0,
            );
            let jb = Matrix3::new(cs, sn, 0.0, -sn, cs, 0.0, 0.0, 0.0, 1.0);
            let w = &self.omega[i];
            let wa = ja.transpose() * w;
            let wb = jb.transpose() * w;
            sys.d[i] += wa * ja;
            sys.d[i + 1] += wb * jb;
            sys.e[i] += wa * jb;
            sys.gp[i] += wa * e;
            sys.gp[i + 1] += wb * e;
            // calibration columns: forward differences of the integrated odometry, one
            // re-integration per estimated parameter
            let jcs: Vec<Vector3<f64>> = self
                .cal
                .iter()
                .map(|&(j, _)| {
                    let h = if j == 3 { 1e-4 } else { 1e-6 };
                    let mut cp = s.calib;
                    cp.set(j, s.calib.get(j) + h);
                    let ep = self.odo_residual(s, i, &cp);
                    let mut jc = (ep - e) / h;
                    jc[2] = wrap_angle(ep[2] - e[2]) / h;
                    jc
                })
                .collect();
            for (col, jc) in jcs.iter().enumerate() {
                let wjc = w * jc;
                let gcol = nl2 + col;
                let ra = ja.transpose() * wjc;
                let rb = jb.transpose() * wjc;
                for r in 0..3 {
                    sys.b[(3 * i + r, gcol)] += ra[r];
                    sys.b[(3 * i + 3 + r, gcol)] += rb[r];
                }
                sys.gd[gcol] += wjc.dot(&e);
                for (col2, jc2) in jcs.iter().enumerate().skip(col) {
                    let val = wjc.dot(jc2);
                    sys.c[(gcol, nl2 + col2)] += val;
                    if col2 != col {
                        sys.c[(nl2 + col2, gcol)] += val;
                    }
                }
            }
        }
        // landmark factors
        for k in 0..self.p.observations.len() {
            let Some((e, jp, jm)) = self.lm_residual(s, k) else {
                continue;
            };
            let (wt, _) = self.huber(e.dot(&(self.meas_w * e)));
            let w = self.meas_w * wt;
            let i = self.p.observations[k].node;
            let l = 2 * self.obs_lm[k];
            let wp = jp.transpose() * w;
            sys.d[i] += wp * jp;
            sys.gp[i] += wp * e;
            let bpl = wp * jm;
            for r in 0..3 {
                for q in 0..2 {
                    sys.b[(3 * i + r, l + q)] += bpl[(r, q)];
                }
            }
            let wm = jm.transpose() * w;
            let cll = wm * jm;
            let gl = wm * e;
            for r in 0..2 {
                sys.gd[l + r] += gl[r];
                for q in 0..2 {
                    sys.c[(l + r, l + q)] += cll[(r, q)];
                }
            }
        }
        // calibration priors
        for (col, &(j, sig)) in self.cal.iter().enumerate() {
            let g = nl2 + col;
            sys.c[(g, g)] += 1.0 / (sig * sig);
            sys.gd[g] += (s.calib.get(j) - Calibration::IDENTITY.get(j)) / (sig * sig);
        }
        sys
    }

    /// Solves `(H + λ diag H) δ = −g` for the pose steps and the border step.
    fn solve(sys: &System, lambda: f64) -> Result<(Vec<Vector3<f64>>, DVector<f64>), FilterError> {
        let n = sys.d.len();
        let m = sys.c.ncols();
        let damp3 = |a: &Matrix3<f64>| {
            let mut a = *a;
            for r in 0..3 {
                a[(r, r)] *= 1.0 + lambda;
                a[(r, r)] += 1e-12;
            }
            a
        };
        let not_pd = || {
            FilterError::Core(CoreError::NotPositiveDefinite {
                what: "smoother normal equations",
            })
        };
        // block-tridiagonal forward elimination with right-hand sides [B | g_p]
        let cols = m + 1;
        let mut sinv: Vec<Matrix3<f64>> = Vec::with_capacity(n);
        let mut y = DMatrix::<f64>::zeros(3 * n, cols);
        for i in 0..n {
            let mut si = damp3(&sys.d[i]);
            let mut yi = DMatrix::<f64>::zeros(3, cols);
            yi.columns_mut(0, m).copy_from(&sys.b.rows(3 * i, 3));
            yi.set_column(m, &DVector::from_column_slice(sys.gp[i].as_slice()));
            if i > 0 {
                let mt = sys.e[i - 1].transpose() * sinv[i - 1];
                si -= mt * sys.e[i - 1];
                let prev = y.rows(3 * (i - 1), 3).into_owned();
                yi -= nalgebra::DMatrix::from_column_slice(3, 3, mt.as_slice()) * prev;
            }
            let si = nalgebra::Cholesky::new((si + si.transpose()) * 0.5)
                .ok_or_else(not_pd)?
                .inverse();
            sinv.push(si);
            y.rows_mut(3 * i, 3).copy_from(&yi);
        }
        // back substitution: x = A⁻¹ [B | g_p]
        let mut x = DMatrix::<f64>::zeros(3 * n, cols);
        for i in (0..n).rev() {
            let mut r = y.rows(3 * i, 3).into_owned();
            if i + 1 < n {
                let e = DMatrix::from_column_slice(3, 3, sys.e[i].as_slice());
                r -= e * x.rows(3 * (i + 1), 3);
            }
            let si = DMatrix::from_column_slice(3, 3, sinv[i].as_slice());
            x.rows_mut(3 * i, 3).copy_from(&(si * r));
        }
        let z = x.column(m).into_owned();
        let dd = if m > 0 {
            let zb = x.columns(0, m);
            let mut cd = sys.c.clone();
            for r in 0..m {
                cd[(r, r)] = cd[(r, r)] * (1.0 + lambda) + 1e-12;
            }
            let s = cd - sys.b.transpose() * zb;
            let rhs = -&sys.gd + sys.b.transpose() * &z;
            let sym = (&s + s.transpose()) * 0.5;
            let ch = nalgebra::Cholesky::new(sym).ok_or_else(not_pd)?;
            ch.solve(&rhs)
        } else {
            DVector::zeros(0)
        };
        let dp_all = if m > 0 {
            -&z - x.columns(0, m) * &dd
        } else {
            -z
        };
        let dp = (0..n)
            .map(|i| Vector3::new(dp_all[3 * i], dp_all[3 * i + 1], dp_all[3 * i + 2]))
            .collect();
        Ok((dp, dd))
    }

    fn apply(&self, s: &State, dp: &[Vector3<f64>], dd: &DVector<f64>) -> State {
        let mut t = s.clone();
        for (p, d) in t.poses.iter_mut().zip(dp) {
            *p = Pose2::new(p.x + d[0], p.y + d[1], p.theta + d[2]);
        }
        for (l, m) in t.landmarks.iter_mut().enumerate() {
            m[0] += dd[2 * l];
            m[1] += dd[2 * l + 1];
        }
        let nl2 = 2 * self.ids.len();
        for (col, &(j, _)) in self.cal.iter().enumerate() {
            t.calib.set(j, s.calib.get(j) + dd[nl2 + col]);
        }
        t
    }
}

fn invalid(name: &'static str, reason: impl Into<String>) -> FilterError {
    FilterError::Core(CoreError::invalid(name, reason))
}

fn check_problem(p: &SmootherProblem) -> Result<(), FilterError> {
    let n = p.node_times.len();
    if n == 0 {
        return Err(FilterError::Core(CoreError::Empty {
            what: "smoother node times",
        }));
    }
    if n > MAX_NODES {
        return Err(invalid(
            "node_times",
            format!("{n} nodes (at most {MAX_NODES})"),
        ));
    }
    if !p.prior.is_finite() {
        return Err(FilterError::Core(CoreError::NonFinite {
            what: "smoother prior pose",
        }));
    }
    if p.node_times.iter().any(|t| !t.is_finite()) {
        return Err(FilterError::Core(CoreError::NonFinite {
            what: "smoother node time",
        }));
    }
    for (i, w) in p.node_times.windows(2).enumerate() {
        if w[1] <= w[0] {
            return Err(invalid(
                "node_times",
                format!(
                    "node {} at {} s is not after node {i} at {} s",
                    i + 1,
                    w[1],
                    w[0]
                ),
            ));
        }
    }
    let mut prev_end = f64::NEG_INFINITY;
    for (k, s) in p.steps.iter().enumerate() {
        if !(s.t_end.is_finite()
            && s.dt.is_finite()
            && s.control.0.is_finite()
            && s.control.1.is_finite())
        {
            return Err(FilterError::Core(CoreError::NonFinite {
                what: "odometry step",
            }));
        }
        if s.dt < 0.0 {
            return Err(invalid(
                "odometry dt",
                format!("step {k}: dt = {} < 0", s.dt),
            ));
        }
        if s.t_end - s.dt < prev_end - 1e-9 {
            return Err(invalid(
                "odometry steps",
                format!(
                    "step {k} starts at {} s, before the previous step ends",
                    s.t_end - s.dt
                ),
            ));
        }
        prev_end = s.t_end;
    }
    for (k, o) in p.observations.iter().enumerate() {
        if o.node >= n {
            return Err(invalid(
                "observation node",
                format!("observation {k} refers to node {} of {n}", o.node),
            ));
        }
        if !(o.range.is_finite() && o.bearing.is_finite()) {
            return Err(FilterError::NonFiniteMeasurement);
        }
        if o.range <= 0.0 {
            return Err(invalid(
                "observation range",
                format!("observation {k}: {} <= 0", o.range),
            ));
        }
    }
    if let Some(g) = &p.initial_poses {
        quarry_core::ensure_len(g.len(), n, "initial poses (one per node)")?;
        if g.iter().any(|q| !q.is_finite()) {
            return Err(FilterError::Core(CoreError::NonFinite {
                what: "initial pose",
            }));
        }
    }
    if p.initial_landmarks
        .iter()
        .any(|(_, m)| !(m[0].is_finite() && m[1].is_finite()))
    {
        return Err(FilterError::Core(CoreError::NonFinite {
            what: "initial landmark",
        }));
    }
    Ok(())
}

/// Smooths a recording: Levenberg–Marquardt on the poses at every node, every detected landmark
/// and the enabled calibration parameters (see the [module docs](self)).
///
/// Errors: an empty or non-increasing node list, non-finite or overlapping odometry, a detection
/// with a non-finite value, a non-positive range or a node index out of range, a starting guess
/// of the wrong length, more than [`MAX_LANDMARKS`] landmarks or [`MAX_BORDER_ENTRIES`] border
/// entries, an invalid configuration, or a
/// linear system that is not positive definite.
pub fn smooth(problem: &SmootherProblem, cfg: &SmootherConfig) -> Result<Smoothed, FilterError> {
    cfg.validate()?;
    check_problem(problem)?;
    let n = problem.node_times.len();
    // landmark columns
    let mut col_of: BTreeMap<LandmarkId, usize> = BTreeMap::new();
    for o in &problem.observations {
        let next = col_of.len();
        col_of.entry(o.landmark).or_insert(next);
        if col_of.len() > MAX_LANDMARKS {
            return Err(invalid(
                "observations",
                format!("more than {MAX_LANDMARKS} distinct landmarks"),
            ));
        }
    }
    // columns in id order
    let ids: Vec<LandmarkId> = col_of.keys().copied().collect();
    let idx: BTreeMap<LandmarkId, usize> = ids.iter().enumerate().map(|(i, id)| (*id, i)).collect();
    let obs_lm: Vec<usize> = problem
        .observations
        .iter()
        .map(|o| idx[&o.landmark])
        .collect();
    let border = 3 * n * (2 * col_of.len() + 4);
    if border > MAX_BORDER_ENTRIES {
        return Err(invalid(
            "problem size",
            format!(
                "{n} nodes x {} landmarks need a {border}-entry dense border (at most \
                 {MAX_BORDER_ENTRIES}); split the recording",
                col_of.len()
            ),
        ));
    }
    let cal: Vec<(usize, f64)> = cfg
        .calibration
        .sigmas()
        .iter()
        .enumerate()
        .filter_map(|(j, s)| s.map(|s| (j, s)))
        .collect();
    let model = Motion::new(cfg.motion, cfg.control_sigma)?;
    let t = &problem.node_times;
    let mut omega = Vec::with_capacity(n.saturating_sub(1));
    for i in 0..n.saturating_sub(1) {
        let cov = segment_covariance(
            &problem.steps,
            t[i],
            t[i + 1],
            &Calibration::IDENTITY,
            &model,
            cfg.min_segment_sigma,
        );
        let inv = cov
            .try_inverse()
            .ok_or(FilterError::Core(CoreError::NotPositiveDefinite {
                what: "odometry segment covariance",
            }))?;
        omega.push((inv + inv.transpose()) * 0.5);
    }
    let nominal = (0..n.saturating_sub(1))
        .map(|i| {
            integrate(
                &problem.steps,
                t[i],
                t[i + 1],
                &Calibration::IDENTITY,
                &model,
            )
        })
        .collect();
    let ps = cfg.prior_sigma;
    let prep = Prepared {
        p: problem,
        cfg,
        ids,
        obs_lm,
        cal,
        omega,
        nominal,
        model,
        prior_info: Matrix3::from_diagonal(&Vector3::new(
            1.0 / (ps[0] * ps[0]),
            1.0 / (ps[1] * ps[1]),
            1.0 / (ps[2] * ps[2]),
        )),
        meas_w: Matrix2::new(
            1.0 / (cfg.sigma_range * cfg.sigma_range),
            0.0,
            0.0,
            1.0 / (cfg.sigma_bearing * cfg.sigma_bearing),
        ),
    };
    // starting point
    let poses = if let Some(g) = &problem.initial_poses {
        g.clone()
    } else {
        let mut v = Vec::with_capacity(n);
        let mut cur = problem.prior;
        v.push(cur);
        for i in 0..n - 1 {
            cur = cur.compose(&integrate(
                &problem.steps,
                t[i],
                t[i + 1],
                &Calibration::IDENTITY,
                &prep.model,
            ));
            v.push(cur);
        }
        v
    };
    let guess: BTreeMap<LandmarkId, [f64; 2]> = problem.initial_landmarks.iter().copied().collect();
    let mut landmarks = vec![[f64::NAN; 2]; prep.ids.len()];
    for (l, id) in prep.ids.iter().enumerate() {
        if let Some(m) = guess.get(id) {
            landmarks[l] = *m;
        }
    }
    for (k, o) in problem.observations.iter().enumerate() {
        let l = prep.obs_lm[k];
        if landmarks[l][0].is_nan() {
            let x = &poses[o.node];
            let a = x.theta + o.bearing;
            landmarks[l] = [x.x + o.range * a.cos(), x.y + o.range * a.sin()];
        }
    }
    let mut state = State {
        poses,
        landmarks,
        calib: Calibration::IDENTITY,
    };
    let initial_cost = prep.cost(&state);
    if !initial_cost.is_finite() {
        return Err(FilterError::NonFiniteResult {
            what: "smoother initial cost",
        });
    }
    let mut cost = initial_cost;
    let mut lambda = 1e-6;
    let mut iterations = 0;
    let mut converged = false;
    for _ in 0..cfg.max_iterations {
        let sys = prep.build(&state);
        let mut accepted = false;
        while lambda < 1e12 {
            let (dp, dd) = Prepared::solve(&sys, lambda)?;
            let cand = prep.apply(&state, &dp, &dd);
            let c = prep.cost(&cand);
            if c.is_finite() && c < cost {
                let rel = (cost - c) / cost.max(f64::MIN_POSITIVE);
                state = cand;
                cost = c;
                lambda = (lambda / 10.0).max(1e-12);
                accepted = true;
                iterations += 1;
                if rel < cfg.tolerance {
                    converged = true;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted {
            // no step lowers the cost: a minimum to working precision
            converged = true;
        }
        if converged {
            break;
        }
    }
    let mut downweighted = 0;
    for k in 0..problem.observations.len() {
        if let Some((e, _, _)) = prep.lm_residual(&state, k)
            && prep.huber(e.dot(&(prep.meas_w * e))).0 < 1.0
        {
            downweighted += 1;
        }
    }
    Ok(Smoothed {
        poses: state.poses,
        landmarks: prep.ids.iter().copied().zip(state.landmarks).collect(),
        calibration: state.calib,
        iterations,
        initial_cost,
        final_cost: cost,
        converged,
        downweighted,
    })
}
