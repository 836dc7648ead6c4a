//! The detector ([`ContourDetector`]), the two trackers ([`Table1Tracker`], [`KfGnnTracker`])
//! of spec 003 §2.6–§2.9, the tracker of a preset ([`LidarPeopleTracker`]) and the building
//! blocks a configuration makes (gate, MeanShift, ICP, background model).

use super::config::{Detector, LidarPeopleConfig, Preset};
use crate::{TrackerConfig, TrackerError};
use nalgebra::{DMatrix, Matrix4, Vector2, Vector4};
use quarry_assoc::PositionVelocityGate;
use quarry_assoc::PvState;
use quarry_assoc::lifecycle::{MOfN, MOfNRecord, ScanObservation, TrackLifecycle, TrackState};
use quarry_cloud::background::{ChiSquareBackground, ChiSquareConfig, LongTermConfig, SigmaMode};
use quarry_cloud::cluster::MeanShift;
use quarry_cloud::contour::EllipseModel;
use quarry_cloud::icp::{Correspondence, Icp2d, Trim};
use quarry_cloud::legs::LegDetector;
use quarry_core::ScanGeometry;
use quarry_core::{
    Clusterer, Clustering, CoreError, Gate, Gaussian, MultiTargetTracker, Point2, Pose2,
    Registration2, Stamp, StateEstimate, StateLayout, TimeUs, TrackFlags, TrackId, TrackReport,
    TrackStatus,
};
use quarry_filter::{ConstantVelocity2, Ekf, Position2};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::f64::consts::FRAC_PI_2;

/// One fused frame: the world-frame dynamic points of all sensors near `t` (spec §2.4).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FusedPoints {
    /// Frame time t_f.
    pub t: TimeUs,
    /// Dynamic points, world frame, sorted by (sensor, beam).
    pub points: Vec<Point2>,
    /// No sensor contributed: the tracker skips the frame (no deletions, Δt grows).
    pub no_data: bool,
}

/// A fitted contour: the ellipse pose, its ICP residual e* and its support n_rm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourFit {
    /// Model pose in the world (centre = target position; orientation α mod π).
    pub pose: Pose2,
    /// e*: RMS over the kept pairs (+∞ when ICP failed or kept fewer than 3 pairs).
    pub rms: f64,
    /// Points removed by the removal ellipse (n_rm).
    pub support: usize,
}

/// One row of a tracker's output (the columns of `tracks.csv`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LidarTrack {
    /// Track id.
    pub id: u32,
    /// Position x, metres.
    pub x: f64,
    /// Position y, metres.
    pub y: f64,
    /// Ellipse orientation α (mod π).
    pub alpha: f64,
    /// Velocity x (0 when unknown).
    pub vx: f64,
    /// Velocity y (0 when unknown).
    pub vy: f64,
    /// Support n_rm.
    pub support: usize,
    /// ICP RMS e*.
    pub rms: f64,
    /// Born this frame.
    pub born: bool,
    /// Born as the replacement of a track whose gate failed.
    pub gate_replaced: bool,
}

/// The MeanShift + ICP-ellipse detector, generic over the clusterer and the registration.
#[derive(Debug, Clone)]
pub struct ContourDetector<C, R> {
    /// The clusterer (MeanShift, h = 0.30 m).
    pub clusterer: C,
    /// The registration (contour ICP).
    pub registration: R,
    /// The contour model points (model frame, x along the shoulders).
    pub model: Vec<Point2>,
    /// The ellipse (semi-axes a_m, b_m; K_m) whose points are `model`.
    pub ellipse: EllipseModel,
    /// Removal margin r_m.
    pub r_m: f64,
    /// min_num_point.
    pub min_num_point: usize,
    /// d_m_matching.
    pub d_m_matching: f64,
    /// Two orientation starts for new clusters (`faithful`), else one start at α = 0.
    pub two_starts: bool,
    /// The second start runs only when the first fit's e* is at least this (0: always).
    pub second_start_above: f64,
}

impl<C: Clusterer, R: Registration2> ContourDetector<C, R> {
    /// ICP of the model onto `data` from `init`; failure (e.g. `TooFewPoints`) gives e* = ∞.
    pub fn fit(&self, data: &[Point2], init: Pose2) -> (Pose2, f64) {
        match self.registration.register(&self.model, data, init) {
            Ok(r) if r.inliers >= 3 && r.rms.is_finite() && r.pose.is_finite() => (r.pose, r.rms),
            Ok(r) if r.pose.is_finite() => (r.pose, f64::INFINITY),
            _ => (init, f64::INFINITY),
        }
    }

    /// Fit for a new cluster: centre `c`, one start at α = 0 or two starts at φ_pca and
    /// φ_pca + π/2, keeping the lower e* (the second only when the first's e* is at least
    /// `second_start_above`).
    pub fn fit_new(&self, data: &[Point2], c: Point2) -> (Pose2, f64) {
        if !self.two_starts {
            return self.fit(data, Pose2::new(c.x, c.y, 0.0));
        }
        let phi = quarry_cloud::contour::pca_angle(data).unwrap_or(0.0);
        let a = self.fit(data, Pose2::new(c.x, c.y, phi));
        if a.1 < self.second_start_above {
            return a;
        }
        let b = self.fit(data, Pose2::new(c.x, c.y, phi + FRAC_PI_2));
        if b.1 < a.1 { b } else { a }
    }

    /// Removes (clears in `remaining`) every point inside the removal ellipse of `pose`; returns
    /// how many were removed.
    pub fn remove_inside(&self, pose: &Pose2, pts: &[Point2], remaining: &mut [bool]) -> usize {
        let mut n = 0;
        for (q, r) in pts.iter().zip(remaining.iter_mut()) {
            if !*r {
                continue;
            }
            if self.ellipse.removal_contains(pose, q, self.r_m) {
                *r = false;
                n += 1;
            }
        }
        n
    }

    /// Lines 10–17 of Table 1: fits ellipses to the clusters' remaining points, largest first,
    /// revisiting a cluster up to 3 times (merged people). Returns the fits passing line 16.
    pub fn detect_new(
        &self,
        pts: &[Point2],
        cl: &Clustering,
        remaining: &mut [bool],
    ) -> Vec<ContourFit> {
        let k = cl.modes.len();
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); k];
        for (i, l) in cl.labels.iter().enumerate() {
            if let Some(c) = l
                && let Some(m) = members.get_mut(*c as usize)
            {
                m.push(i);
            }
        }
        let count = |c: usize, rem: &[bool]| members[c].iter().filter(|&&i| rem[i]).count();
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| {
            count(b, remaining).cmp(&count(a, remaining)).then(
                cl.modes[a]
                    .x
                    .total_cmp(&cl.modes[b].x)
                    .then(cl.modes[a].y.total_cmp(&cl.modes[b].y)),
            )
        });
        let mut q: VecDeque<usize> = order.into();
        let mut passes = vec![0u32; k];
        let mut out = Vec::new();
        let mut data = Vec::new();
        while let Some(c) = q.pop_front() {
            data.clear();
            data.extend(
                members[c]
                    .iter()
                    .filter(|&&i| remaining[i])
                    .map(|&i| pts[i]),
            );
            passes[c] += 1;
            if data.len() < self.min_num_point {
                continue;
            }
            let centre = if passes[c] == 1 {
                cl.modes[c]
            } else {
                let n = data.len() as f64;
                Point2::new(
                    data.iter().map(|p| p.x).sum::<f64>() / n,
                    data.iter().map(|p| p.y).sum::<f64>() / n,
                )
            };
            let (pose, rms) = self.fit_new(&data, centre);
            let removed = self.remove_inside(&pose, pts, remaining);
            if removed > self.min_num_point && rms < self.d_m_matching {
                out.push(ContourFit {
                    pose,
                    rms,
                    support: removed,
                });
            }
            if removed > 0 && count(c, remaining) >= self.min_num_point && passes[c] < 3 {
                q.push_back(c);
            }
        }
        out
    }
}

/// Non-maximum suppression of contour fits: keeps the fit with the largest support (then the
/// lowest e*) and drops every fit whose centre lies within `radius` of a kept one. The detector
/// re-queues a cluster whose contour left points outside it (an arm, the far side of a turning
/// body), and such a second fit a few centimetres beside the first is the same body: two torsos
/// cannot be closer than `radius` = R_icp = 0.37 m. Left in, it can win the assignment of the
/// body's track and pull it off the body.
fn suppress_second_fits(mut fits: Vec<ContourFit>, radius: f64) -> Vec<ContourFit> {
    fits.sort_by(|a, b| b.support.cmp(&a.support).then(a.rms.total_cmp(&b.rms)));
    let r2 = radius * radius;
    let mut kept: Vec<ContourFit> = Vec::with_capacity(fits.len());
    for f in fits {
        let c = Point2::new(f.pose.x, f.pose.y);
        if kept
            .iter()
            .all(|k| (Point2::new(k.pose.x, k.pose.y) - c).norm_squared() > r2)
        {
            kept.push(f);
        }
    }
    kept
}

/// Heading from the ellipse orientation, signed by the velocity when known.
fn heading(alpha: f64, v: Option<Vector2<f64>>) -> f64 {
    let h = alpha + FRAC_PI_2;
    match v {
        Some(v) if v.norm() > 1e-6 => {
            let d = Vector2::new(h.cos(), h.sin());
            if d.dot(&v) < 0.0 {
                quarry_core::wrap_angle(h + std::f64::consts::PI)
            } else {
                quarry_core::wrap_angle(h)
            }
        }
        _ => quarry_core::wrap_angle(h),
    }
}

/// The points of a fused frame to track, `None` for a frame without data (the tracker skips
/// it); an error when a point is not finite.
pub(super) fn frame_points(frame: &FusedPoints) -> Result<Option<&[Point2]>, TrackerError> {
    if frame.no_data {
        return Ok(None);
    }
    if frame
        .points
        .iter()
        .any(|p| !(p.x.is_finite() && p.y.is_finite()))
    {
        return Err(CoreError::NonFinite {
            what: "fused frame points",
        }
        .into());
    }
    Ok(Some(&frame.points))
}

/// The 5 × 5 covariance of `[x, y, vx, vy, heading]` from a CV track's 4 × 4 one (heading
/// variance 1: the heading comes from the contour orientation, not the filter).
pub(super) fn with_heading_cov(report: &mut TrackReport, cov4: &Matrix4<f64>) {
    if let Some(st) = report.state.as_mut() {
        let mut cov = DMatrix::zeros(5, 5);
        cov.view_mut((0, 0), (4, 4)).copy_from(cov4);
        cov[(4, 4)] = 1.0;
        st.cov = Some(cov);
    }
}

pub(super) fn report(stamp: Stamp, row: &LidarTrack, vel_known: bool) -> TrackReport {
    let mut r = TrackReport::new(stamp, TrackId(row.id), TrackStatus::Confirmed);
    let v = vel_known.then(|| Vector2::new(row.vx, row.vy));
    let h = heading(row.alpha, v);
    r.state = Some(if vel_known {
        StateEstimate {
            layout: StateLayout::XyVxVyHeading,
            mean: nalgebra::DVector::from_vec(vec![row.x, row.y, row.vx, row.vy, h]),
            cov: None,
        }
    } else {
        StateEstimate {
            layout: StateLayout::XyHeading,
            mean: nalgebra::DVector::from_vec(vec![row.x, row.y, h]),
            cov: None,
        }
    });
    r.score = Some(row.rms);
    if row.born {
        r.flags.insert(TrackFlags::BORN);
    }
    if row.gate_replaced {
        r.flags.insert(TrackFlags::GATE_REPLACED);
    }
    r
}

#[derive(Debug, Clone)]
struct T1Track {
    id: u32,
    p: Vector2<f64>,
    v: Option<Vector2<f64>>,
    alpha: f64,
    t_last: TimeUs,
    age: u32,
    rms: f64,
    support: usize,
}

/// The paper's tracker (Table 1): per-track ICP from the prediction, removal of explained points,
/// gate (8), create/update/delete. Generic over the gate.
#[derive(Debug, Clone)]
pub struct Table1Tracker<C, R, G> {
    /// The detector.
    pub detector: ContourDetector<C, R>,
    /// The association gate (eq. 8 by default).
    pub gate: G,
    /// ICP data radius R_icp around the prediction.
    pub r_icp: f64,
    /// `literal`: take the cluster whose mode is nearest the track, within `r_assoc`.
    pub nearest_mode_assoc: bool,
    /// R_assoc.
    pub r_assoc: f64,
    tracks: Vec<T1Track>,
    next_id: u32,
    last: Vec<LidarTrack>,
}

impl<C: Clusterer, R: Registration2, G: Gate<PvState, Vector2<f64>>> Table1Tracker<C, R, G> {
    /// A tracker from its parts and the Table 1 parameters of `cfg`.
    pub fn new(detector: ContourDetector<C, R>, gate: G, cfg: &LidarPeopleConfig) -> Self {
        Self {
            detector,
            gate,
            r_icp: cfg.r_icp,
            nearest_mode_assoc: cfg.nearest_mode_assoc,
            r_assoc: cfg.r_assoc,
            tracks: Vec::new(),
            next_id: 0,
            last: Vec::new(),
        }
    }

    /// The rows of the last processed frame.
    pub fn last_rows(&self) -> &[LidarTrack] {
        &self.last
    }

    fn new_id(&mut self) -> u32 {
        let id = self.next_id;
        self.next_id += 1;
        id
    }

    /// Processes one fused frame (TRACK_FRAME of spec §2.8).
    pub fn process(
        &mut self,
        stamp: Stamp,
        frame: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        let Some(pts) = frame_points(frame)? else {
            self.last.clear();
            return Ok(Vec::new());
        };
        let t = frame.t;
        let cl = if pts.is_empty() {
            Clustering::default()
        } else {
            self.detector.clusterer.cluster(pts)?
        };
        let mut remaining = vec![true; pts.len()];
        let mut rows: Vec<LidarTrack> = Vec::new();
        let mut keep: Vec<T1Track> = Vec::new();
        let mut replacements: Vec<(Pose2, f64, usize)> = Vec::new();
        let tracks = std::mem::take(&mut self.tracks);
        let mut data = Vec::new();
        for mut tr in tracks {
            let dt = t.secs_since(tr.t_last);
            let p_hat = tr.p + tr.v.unwrap_or_else(Vector2::zeros) * dt;
            data.clear();
            let init;
            if self.nearest_mode_assoc {
                let best = cl
                    .modes
                    .iter()
                    .enumerate()
                    .map(|(c, m)| (c, (m.coords - tr.p).norm()))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                match best {
                    Some((c, d)) if d <= self.r_assoc => {
                        data.extend(
                            cl.labels
                                .iter()
                                .enumerate()
                                .filter(|(i, l)| remaining[*i] && **l == Some(c as u32))
                                .map(|(i, _)| pts[i]),
                        );
                        init = Pose2::new(cl.modes[c].x, cl.modes[c].y, tr.alpha);
                    }
                    _ => init = Pose2::new(p_hat.x, p_hat.y, tr.alpha),
                }
            } else {
                let r2 = self.r_icp * self.r_icp;
                data.extend(
                    pts.iter()
                        .zip(&remaining)
                        .filter(|(q, r)| **r && (q.coords - p_hat).norm_squared() <= r2)
                        .map(|(q, _)| *q),
                );
                init = Pose2::new(p_hat.x, p_hat.y, tr.alpha);
            }
            if data.len() < 3 {
                continue; // delete: nothing to match
            }
            let (pose, rms) = self.detector.fit(&data, init);
            let removed = self.detector.remove_inside(&pose, pts, &mut remaining);
            if removed < self.detector.min_num_point || rms > self.detector.d_m_matching {
                continue; // delete
            }
            let p_new = Vector2::new(pose.x, pose.y);
            let g = self.gate.distance2(
                &PvState {
                    pos: tr.p,
                    vel: tr.v,
                },
                &p_new,
                dt,
            );
            if g <= 1.0 && dt > 0.0 {
                tr.v = Some((p_new - tr.p) / dt);
                tr.p = p_new;
                tr.alpha = pose.theta;
                tr.t_last = t;
                tr.age += 1;
                tr.rms = rms;
                tr.support = removed;
                keep.push(tr);
            } else {
                replacements.push((pose, rms, removed));
            }
        }
        for (pose, rms, support) in replacements {
            let id = self.new_id();
            keep.push(T1Track {
                id,
                p: Vector2::new(pose.x, pose.y),
                v: None,
                alpha: pose.theta,
                t_last: t,
                age: 0,
                rms,
                support,
            });
            rows.push(row_of(keep.last(), true, true));
        }
        for fit in self.detector.detect_new(pts, &cl, &mut remaining) {
            let id = self.new_id();
            keep.push(T1Track {
                id,
                p: Vector2::new(fit.pose.x, fit.pose.y),
                v: None,
                alpha: fit.pose.theta,
                t_last: t,
                age: 0,
                rms: fit.rms,
                support: fit.support,
            });
            rows.push(row_of(keep.last(), true, false));
        }
        keep.sort_by_key(|k| k.id);
        // rows for the updated tracks (born ones already have theirs)
        for tr in &keep {
            if tr.age > 0 {
                rows.push(row_of(Some(tr), false, false));
            }
        }
        rows.sort_by_key(|r| r.id);
        self.tracks = keep;
        let reports = rows
            .iter()
            .map(|r| {
                let vk = self.tracks.iter().any(|k| k.id == r.id && k.v.is_some());
                report(stamp, r, vk)
            })
            .collect();
        self.last = rows;
        Ok(reports)
    }
}

fn row_of(tr: Option<&T1Track>, born: bool, gate_replaced: bool) -> LidarTrack {
    let Some(tr) = tr else {
        return LidarTrack {
            id: u32::MAX,
            x: f64::NAN,
            y: f64::NAN,
            alpha: 0.0,
            vx: 0.0,
            vy: 0.0,
            support: 0,
            rms: f64::INFINITY,
            born,
            gate_replaced,
        };
    };
    let v = tr.v.unwrap_or_else(Vector2::zeros);
    LidarTrack {
        id: tr.id,
        x: tr.p.x,
        y: tr.p.y,
        alpha: tr.alpha,
        vx: v.x,
        vy: v.y,
        support: tr.support,
        rms: tr.rms,
        born,
        gate_replaced,
    }
}

impl<C: Clusterer, R: Registration2, G: Gate<PvState, Vector2<f64>>> MultiTargetTracker
    for Table1Tracker<C, R, G>
{
    type Input = FusedPoints;
    type Error = TrackerError;
    fn step(
        &mut self,
        stamp: Stamp,
        input: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.process(stamp, input)
    }
}

#[derive(Debug, Clone)]
struct KfTrack {
    id: u32,
    kf: Ekf<4, 2, ConstantVelocity2, Position2>,
    rec: MOfNRecord,
    misses: u32,
    alpha: f64,
    rms: f64,
    support: usize,
    reported: bool,
    /// Where the track was born (for `leg_min_travel_m`).
    origin: Point2,
    /// It has been at least `min_travel` from `origin` (always true when that is 0).
    moved: bool,
}

/// The leg detector of `cfg` when `detector = legs` (validated), else `None`.
pub(super) fn leg_detector_of(
    cfg: &LidarPeopleConfig,
) -> Result<Option<LegDetector>, TrackerError> {
    if cfg.detector != Detector::Legs {
        return Ok(None);
    }
    let l = LegDetector {
        cluster_dist: cfg.leg_cluster_dist,
        min_points: cfg.leg_min_points,
        max_width: cfg.leg_max_width,
        max_pair_dist: cfg.leg_pair_dist,
        single_legs: cfg.leg_single,
    };
    l.validate()?;
    Ok(Some(l))
}

/// The people of one fused frame, at least `r_icp` apart: leg pairs when `legs` is given
/// (orientation 0, ICP RMS 0), else the contour fits of `detector`'s clusters.
pub(super) fn detect_people<C: Clusterer, R: Registration2>(
    detector: &ContourDetector<C, R>,
    legs: Option<&LegDetector>,
    pts: &[Point2],
    r_icp: f64,
) -> Result<Vec<ContourFit>, TrackerError> {
    let fits = if let Some(legs) = legs {
        legs.detect(pts)?
            .into_iter()
            .map(|p| ContourFit {
                pose: Pose2::new(p.position.x, p.position.y, 0.0),
                rms: 0.0,
                support: p.support,
            })
            .collect()
    } else {
        let cl = if pts.is_empty() {
            Clustering::default()
        } else {
            detector.clusterer.cluster(pts)?
        };
        let mut remaining = vec![true; pts.len()];
        detector.detect_new(pts, &cl, &mut remaining)
    };
    Ok(suppress_second_fits(fits, r_icp))
}

/// The `kf-gnn` baseline (spec §2.9): the same detector, a CV Kalman filter per track, a χ²
/// innovation gate, Hungarian GNN and M-of-N confirmation. An unassigned detection within
/// `r_icp` of a track (or of a detection that started a track in the same frame) is a second
/// contour fit of the same body and starts no track.
#[derive(Debug, Clone)]
pub struct KfGnnTracker<C, R> {
    /// The detector.
    pub detector: ContourDetector<C, R>,
    /// With `detector = legs`: the leg detector, used instead of `detector` (its detections
    /// have orientation 0 and ICP RMS 0).
    pub legs: Option<LegDetector>,
    /// A track is reported only once it has been this far from where it was born, metres
    /// (`leg_min_travel_m` with `detector = legs`, else 0).
    min_travel: f64,
    motion: ConstantVelocity2,
    meas: Position2,
    gamma: f64,
    sigma_r: f64,
    r_icp: f64,
    life: MOfN,
    max_coast_report: u32,
    tracks: Vec<KfTrack>,
    next_id: u32,
    t_last: Option<TimeUs>,
    last: Vec<LidarTrack>,
    withheld: Vec<LidarTrack>,
}

impl<C: Clusterer, R: Registration2> KfGnnTracker<C, R> {
    /// A tracker with the `kf-gnn` parameters of `cfg`.
    pub fn new(
        detector: ContourDetector<C, R>,
        cfg: &LidarPeopleConfig,
    ) -> Result<Self, TrackerError> {
        let motion = ConstantVelocity2::cwna(cfg.kf_q).map_err(CoreError::from)?;
        let legs = leg_detector_of(cfg)?;
        let sigma_r = if legs.is_some() {
            cfg.leg_sigma_r
        } else {
            cfg.kf_sigma_r
        };
        let meas = Position2::isotropic(sigma_r).map_err(CoreError::from)?;
        let life = MOfN::new(cfg.kf_m, cfg.kf_n, cfg.kf_n_del)?;
        let min_travel = if legs.is_some() {
            cfg.leg_min_travel_m
        } else {
            0.0
        };
        Ok(Self {
            detector,
            legs,
            min_travel,
            motion,
            meas,
            gamma: cfg.kf_gamma,
            sigma_r,
            r_icp: cfg.r_icp,
            life,
            max_coast_report: cfg.kf_max_coast_report,
            tracks: Vec::new(),
            next_id: 0,
            t_last: None,
            last: Vec::new(),
            withheld: Vec::new(),
        })
    }

    /// The rows of the last processed frame.
    pub fn last_rows(&self) -> &[LidarTrack] {
        &self.last
    }

    /// The rows the last frame held back: tracks detected in it but not reported, because
    /// they are not confirmed yet or have not walked `leg_min_travel_m` (`born` is false).
    /// An offline run can report them once their id is reported
    /// ([`RecordedRun::backfill`](super::RecordedRun::backfill)).
    pub fn last_withheld(&self) -> &[LidarTrack] {
        &self.withheld
    }

    /// Processes one fused frame.
    pub fn process(
        &mut self,
        stamp: Stamp,
        frame: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.withheld.clear();
        let Some(pts) = frame_points(frame)? else {
            self.last.clear();
            return Ok(Vec::new());
        };
        let t = frame.t;
        let dt = self.t_last.map_or(0.0, |t0| t.secs_since(t0)).max(0.0);
        self.t_last = Some(t);
        let dets = detect_people(&self.detector, self.legs.as_ref(), pts, self.r_icp)?;
        for tr in &mut self.tracks {
            if dt > 0.0 {
                tr.kf.predict(&(), dt).map_err(CoreError::from)?;
            }
        }
        let n = self.tracks.len();
        let m = dets.len();
        let mut cost = DMatrix::from_element(n, m, f64::INFINITY);
        for (i, tr) in self.tracks.iter().enumerate() {
            for (j, d) in dets.iter().enumerate() {
                if let Ok(inn) = tr.kf.innovation(&Vector2::new(d.pose.x, d.pose.y)) {
                    let c = inn.nis;
                    if c.is_finite() && c <= self.gamma {
                        cost[(i, j)] = c;
                    }
                }
            }
        }
        let assignment = if n > 0 && m > 0 {
            quarry_assoc::assign::hungarian_with_miss(&cost, &vec![self.gamma; n])
                .map_err(CoreError::from)?
                .row_to_col
        } else {
            vec![None; n]
        };
        let mut used = vec![false; m];
        for (i, tr) in self.tracks.iter_mut().enumerate() {
            match assignment.get(i).copied().flatten() {
                Some(j) if cost[(i, j)].is_finite() => {
                    used[j] = true;
                    let d = &dets[j];
                    tr.kf
                        .update(&Vector2::new(d.pose.x, d.pose.y))
                        .map_err(CoreError::from)?;
                    tr.misses = 0;
                    tr.alpha = d.pose.theta;
                    tr.rms = d.rms;
                    tr.support = d.support;
                    // travel is measured on the detections, not on a coasting estimate
                    if !tr.moved {
                        tr.moved =
                            (Point2::new(d.pose.x, d.pose.y) - tr.origin).norm() >= self.min_travel;
                    }
                    self.life.observe(&mut tr.rec, &ScanObservation::hit());
                }
                _ => {
                    tr.misses += 1;
                    self.life.observe(&mut tr.rec, &ScanObservation::miss());
                }
            }
        }
        self.tracks
            .retain(|tr| self.life.state(&tr.rec) != TrackState::Deleted);
        let s2 = self.sigma_r * self.sigma_r;
        // An unassigned detection within R_icp of a track is that track's body seen outside its
        // gate (a turn, a partial view), not a new person: it starts no track, so the track
        // coasts instead of getting a twin (spec 003 §2.9 line 7 leaves the rule open; common
        // GNN practice). Detections are already at least R_icp apart.
        let r2 = self.r_icp * self.r_icp;
        let occupied: Vec<Point2> = self
            .tracks
            .iter()
            .map(|tr| Point2::new(tr.kf.mean()[0], tr.kf.mean()[1]))
            .collect();
        for (j, d) in dets.iter().enumerate() {
            if used[j] {
                continue;
            }
            let c = Point2::new(d.pose.x, d.pose.y);
            if occupied.iter().any(|o| (o - c).norm_squared() <= r2) {
                continue;
            }
            let x0 = Vector4::new(d.pose.x, d.pose.y, 0.0, 0.0);
            let p0 = Matrix4::from_diagonal(&Vector4::new(s2, s2, 1.0, 1.0));
            let g = Gaussian::try_new(x0, p0)?;
            let kf = Ekf::new(g, self.motion, self.meas).map_err(CoreError::from)?;
            let id = self.next_id;
            self.next_id += 1;
            self.tracks.push(KfTrack {
                id,
                kf,
                rec: self.life.birth(),
                misses: 0,
                alpha: d.pose.theta,
                rms: d.rms,
                support: d.support,
                reported: false,
                origin: c,
                moved: self.min_travel <= 0.0,
            });
        }
        let mut rows = Vec::new();
        let mut reports = Vec::new();
        for tr in &mut self.tracks {
            let x = tr.kf.mean();
            let row = LidarTrack {
                id: tr.id,
                x: x[0],
                y: x[1],
                alpha: tr.alpha,
                vx: x[2],
                vy: x[3],
                support: if tr.misses == 0 { tr.support } else { 0 },
                rms: tr.rms,
                born: !tr.reported,
                gate_replaced: false,
            };
            if self.life.state(&tr.rec) != TrackState::Confirmed || !tr.moved {
                if tr.misses == 0 {
                    self.withheld.push(LidarTrack { born: false, ..row });
                }
                continue;
            }
            if tr.misses > self.max_coast_report {
                continue;
            }
            tr.reported = true;
            let mut r = report(stamp, &row, true);
            if tr.misses > 0 {
                r.status = TrackStatus::Coasting;
            }
            with_heading_cov(&mut r, tr.kf.cov());
            reports.push(r);
            rows.push(row);
        }
        self.last = rows;
        Ok(reports)
    }
}

impl<C: Clusterer, R: Registration2> MultiTargetTracker for KfGnnTracker<C, R> {
    type Input = FusedPoints;
    type Error = TrackerError;
    fn step(
        &mut self,
        stamp: Stamp,
        input: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        self.process(stamp, input)
    }
}

// ---------------------------------------------------------------------------------------------
// The tracker of a preset, and the building blocks of a configuration.
// ---------------------------------------------------------------------------------------------

/// The gate (8) with the σ and k of a configuration.
pub fn gate_of(cfg: &LidarPeopleConfig) -> PositionVelocityGate {
    PositionVelocityGate {
        sigma_pos: [cfg.sigma_pos; 2],
        sigma_vel: [cfg.sigma_vel; 2],
        k: cfg.gate_k,
        frame_period: cfg.frame_period_s,
    }
}

/// The tracker of a preset: Table 1 (`literal`, `faithful`), KF-GNN (`kf-gnn`) or JIPDA
/// (`jipda`), over the same detector.
#[derive(Debug, Clone)]
pub enum LidarPeopleTracker<C, R> {
    /// `literal` / `faithful`.
    Table1(Table1Tracker<C, R, PositionVelocityGate>),
    /// `kf-gnn`.
    KfGnn(KfGnnTracker<C, R>),
    /// `jipda` (boxed: its JIPDA state is several times the size of the other variants).
    Jipda(Box<super::jipda::JipdaPeopleTracker<C, R>>),
}

impl<C: Clusterer, R: Registration2> LidarPeopleTracker<C, R> {
    /// Assembles the tracker of `cfg.preset` from a clusterer and a registration; the contour
    /// model is the ellipse of `cfg` (a_m, b_m, K_m).
    pub fn from_parts(
        cfg: &LidarPeopleConfig,
        clusterer: C,
        registration: R,
    ) -> Result<Self, TrackerError> {
        cfg.validate()?;
        let ellipse = EllipseModel {
            a: cfg.a_m,
            b: cfg.b_m,
            k: cfg.k_m,
        };
        let model = ellipse.points().map_err(CoreError::from)?;
        let det = ContourDetector {
            clusterer,
            registration,
            model,
            ellipse,
            r_m: cfg.r_m,
            min_num_point: cfg.min_num_point,
            d_m_matching: cfg.d_m_matching,
            two_starts: cfg.two_starts,
            second_start_above: cfg.second_start_above,
        };
        Ok(match cfg.preset {
            Preset::KfGnn => Self::KfGnn(KfGnnTracker::new(det, cfg)?),
            Preset::Jipda => {
                Self::Jipda(Box::new(super::jipda::JipdaPeopleTracker::new(det, cfg)?))
            }
            Preset::Literal | Preset::Faithful => {
                Self::Table1(Table1Tracker::new(det, gate_of(cfg), cfg))
            }
        })
    }

    /// The rows (`tracks.csv` columns) of the last processed frame.
    pub fn last_rows(&self) -> &[LidarTrack] {
        match self {
            Self::Table1(t) => t.last_rows(),
            Self::KfGnn(t) => t.last_rows(),
            Self::Jipda(t) => t.last_rows(),
        }
    }

    /// The rows the last frame held back (detected, not yet confirmed or not yet walked
    /// `leg_min_travel_m`); always empty for Table 1, which reports every track it keeps.
    pub fn last_withheld(&self) -> &[LidarTrack] {
        match self {
            Self::Table1(_) => &[],
            Self::KfGnn(t) => t.last_withheld(),
            Self::Jipda(t) => t.last_withheld(),
        }
    }
}

impl<C: Clusterer, R: Registration2> MultiTargetTracker for LidarPeopleTracker<C, R> {
    type Input = FusedPoints;
    type Error = TrackerError;
    fn step(
        &mut self,
        stamp: Stamp,
        input: &FusedPoints,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        match self {
            Self::Table1(t) => t.process(stamp, input),
            Self::KfGnn(t) => t.process(stamp, input),
            Self::Jipda(t) => t.process(stamp, input),
        }
    }
}

/// The tracker with quarry-cloud's MeanShift and contour ICP.
pub type DefaultLidarTracker = LidarPeopleTracker<MeanShift, Icp2d>;

/// MeanShift with the §2.5 parameters of `cfg`.
pub fn meanshift_of(cfg: &LidarPeopleConfig) -> MeanShift {
    MeanShift {
        min_cluster_size: cfg.n_min_cluster,
        ..MeanShift::with_bandwidth(cfg.bandwidth)
    }
}

/// The contour ICP with the §2.6 switches of `cfg`.
pub fn icp_of(cfg: &LidarPeopleConfig) -> Icp2d {
    Icp2d {
        direction: if cfg.icp_data_to_model {
            Correspondence::DataToModel
        } else {
            Correspondence::ModelToData
        },
        trim: cfg.icp_trim.then(Trim::default),
        rms_stop: cfg.icp_e,
        delta_stop: cfg.icp_eps_delta,
        max_iter: cfg.icp_it_max,
        require_full_model: !cfg.icp_data_to_model,
        ..Icp2d::default()
    }
}

/// The chi-square background of §2.2 for a scanner of `geometry`, with the switches of `cfg`.
pub fn background_of(
    cfg: &LidarPeopleConfig,
    geometry: &ScanGeometry,
) -> Result<ChiSquareBackground, TrackerError> {
    let per_scan = |s: f64| (s / geometry.scan_period.max(1e-6)).round().max(1.0);
    let bc = ChiSquareConfig {
        window: cfg.window_m,
        p_threshold: cfg.p_th,
        kappa: cfg.kappa,
        sigma: SigmaMode::Datasheet,
        region_constraint: true,
        region_radius: cfg.delta_region,
        long_term: cfg.revealed_background.then(|| LongTermConfig {
            warm_scans: per_scan(cfg.t_warm_s) as usize,
            min_valid_fraction: 0.5,
            alpha: cfg.alpha_b,
            relearn_scans: per_scan(cfg.t_relearn_s) as u32,
            gated_update: cfg.bg_gated_update,
            sparse_beams: cfg.bg_sparse_beams,
        }),
        early_start: (cfg.bg_early_start_m > 0.0).then_some(cfg.bg_early_start_m),
    };
    Ok(ChiSquareBackground::new(geometry, bc)?)
}

impl DefaultLidarTracker {
    /// The tracker of `cfg` with quarry-cloud's MeanShift and ICP.
    pub fn from_config(cfg: &LidarPeopleConfig) -> Result<Self, TrackerError> {
        Self::from_parts(cfg, meanshift_of(cfg), icp_of(cfg))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn fit(x: f64, y: f64, support: usize, rms: f64) -> ContourFit {
        ContourFit {
            pose: Pose2::new(x, y, 0.0),
            rms,
            support,
        }
    }

    #[test]
    fn a_second_fit_beside_a_body_is_dropped_and_a_neighbour_kept() {
        // an 11-point arm fit 0.12 m beside a 59-point body fit, and another person 0.6 m away
        let out = suppress_second_fits(
            vec![
                fit(6.08, 5.75, 11, 0.008),
                fit(6.18, 5.73, 59, 0.022),
                fit(6.78, 5.73, 40, 0.030),
            ],
            0.37,
        );
        assert_eq!(
            out,
            vec![fit(6.18, 5.73, 59, 0.022), fit(6.78, 5.73, 40, 0.030)]
        );
        // equal support: the lower residual wins
        let out =
            suppress_second_fits(vec![fit(0.0, 0.0, 20, 0.03), fit(0.1, 0.0, 20, 0.01)], 0.37);
        assert_eq!(out, vec![fit(0.1, 0.0, 20, 0.01)]);
    }

    #[test]
    fn second_start_above_skips_the_second_start_only_after_a_good_first_fit() {
        use crate::TrackerConfig;
        let cfg = LidarPeopleConfig::preset(Preset::KfGnn);
        let LidarPeopleTracker::KfGnn(t) = DefaultLidarTracker::from_config(&cfg).unwrap() else {
            panic!("kf-gnn builds the kf-gnn tracker");
        };
        let mut det = t.detector;
        // the near half of a torso ellipse rotated by 0.4 rad
        let (c, s) = (0.4f64.cos(), 0.4f64.sin());
        let data: Vec<Point2> = (0..40)
            .map(|i| {
                let a = std::f64::consts::PI * (1.0 + f64::from(i) / 40.0);
                let (x, y) = (0.22 * a.cos(), 0.13 * a.sin());
                Point2::new(3.0 + c * x - s * y, 2.0 + s * x + c * y)
            })
            .collect();
        let centre = Point2::new(3.0, 1.95);
        let phi = quarry_cloud::contour::pca_angle(&data).unwrap();
        let first = det.fit(&data, Pose2::new(centre.x, centre.y, phi));
        let second = det.fit(&data, Pose2::new(centre.x, centre.y, phi + FRAC_PI_2));
        let best = if second.1 < first.1 { second } else { first };
        assert_eq!(
            det.second_start_above, 0.0,
            "the other presets always run both"
        );
        assert_eq!(det.fit_new(&data, centre), best);
        det.second_start_above = first.1 * 2.0 + 1e-9;
        assert_eq!(
            det.fit_new(&data, centre),
            first,
            "a good first fit is kept"
        );
        det.second_start_above = first.1 * 0.5;
        assert_eq!(
            det.fit_new(&data, centre),
            best,
            "a poor first fit tries the second"
        );
    }

    proptest! {
        #[test]
        fn suppression_keeps_separated_maxima_and_covers_every_fit(
            raw in prop::collection::vec((0.0..3.0f64, 0.0..3.0f64, 8usize..80, 0.0..0.05f64), 0..30),
            radius in 0.05..1.0f64,
        ) {
            let fits: Vec<ContourFit> = raw.iter().map(|&(x, y, n, e)| fit(x, y, n, e)).collect();
            let kept = suppress_second_fits(fits.clone(), radius);
            let d = |a: &ContourFit, b: &ContourFit| (a.pose.x - b.pose.x).hypot(a.pose.y - b.pose.y);
            for (i, a) in kept.iter().enumerate() {
                prop_assert!(fits.contains(a));
                for b in &kept[i + 1..] {
                    prop_assert!(d(a, b) > radius);
                }
            }
            // every dropped fit lies within the radius of a kept fit at least as well supported
            for f in &fits {
                prop_assert!(kept.iter().any(|k| k == f || (d(k, f) <= radius && k.support >= f.support)));
            }
            // the best-supported fit always survives, and suppressing again changes nothing
            if let Some(best) = fits.iter().map(|f| f.support).max() {
                prop_assert!(kept.iter().any(|k| k.support == best));
            }
            prop_assert_eq!(suppress_second_fits(kept.clone(), radius), kept);
        }
    }
}
