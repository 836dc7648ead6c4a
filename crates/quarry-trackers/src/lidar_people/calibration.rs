//! `calibration = icp` (spec 003 §2.3): the server registers the clients' long-term backgrounds
//! `b_n` from rough poses and fuses with the calibrated poses.
//!
//! Step 1 of §2.3: each client's background point set `B_s` is its valid beams with
//! `b_n < 28.5 m`, in the sensor frame ([`quarry_cloud::calib::background_points`]). Steps 2–4
//! are quarry-cloud's [`quarry_cloud::calib::calibrate`]: the reference scanner keeps its
//! configured pose, the others are registered in order of decreasing overlap against the union
//! of the backgrounds calibrated so far (trimmed ICP, distance schedule 1.0 / 0.5 / 0.25 /
//! 0.10 m, point-to-line pairs as §2.3 allows), and each is accepted only with overlap ≥ 0.3
//! and inlier RMS ≤ 0.03 m. Those bounds alone accept some wrong registrations (a scanner slid
//! metres along a wall still overlaps 35–60 % with a low RMS), so the calibrated poses must
//! also be free-space consistent: at most `calib_max_free_space_violation` (2 %) of the other
//! scanners' background points may lie in the space a scanner saw through
//! ([`free_space_violations`]). A scanner that cannot be calibrated is a
//! [`TrackerError::Calibration`] naming it, never a silent fall-back to its rough pose.
//!
//! In the simulator the rough ("hand-measured") poses are the true poses moved by a seeded draw
//! of at most `calib_max_shift_m` and `calib_max_rot_deg`
//! ([`Scenario::hand_measured_poses`]), or the poses of `calib_rough_poses`; the reference
//! scanner's pose is its true (configured) pose unless `calib_rough_poses` says otherwise.

use super::config::{Calibration, LidarPeopleConfig};
use super::{ClientPipeline, background_of};
use crate::TrackerConfig as _;
use crate::TrackerError;
use quarry_cloud::CloudError;
use quarry_cloud::calib::{
    CalibConfig, CalibResult, FreeSpaceCheck, ScannerBackground, background_points, calibrate,
    free_space_violations,
};
use quarry_core::{BackgroundModel, Pose2, SensorId, TimeUs, wrap_angle};
use quarry_sim::lidar_room::{RoomEvent, Runner, ScannerSim, Scenario};
use serde::Serialize;
use std::fmt::Write as _;

/// One scanner's calibration, with its errors against the simulator's true pose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScannerCalibration {
    /// Sensor id.
    pub sensor: u16,
    /// Scanner name (`A`, `B`, `C`).
    pub name: String,
    /// Whether it is the reference scanner s₀ (its pose is taken as exact).
    pub reference: bool,
    /// The rough pose ICP started from.
    pub rough: Pose2,
    /// The calibrated pose.
    pub pose: Pose2,
    /// The true pose (simulator).
    pub truth: Pose2,
    /// Number of background points `|B_s|`.
    pub background_points: usize,
    /// Overlap: fraction of `B_s` within 0.10 m of the union (1 for the reference).
    pub overlap: f64,
    /// Trimmed inlier RMS, metres (0 for the reference).
    pub rms_m: f64,
    /// Free-space violations: the fraction of the other scanners' background points (in view)
    /// that lie in space this scanner saw through, and of its points in the others' free
    /// space, under the calibrated poses ([`free_space_violations`], margin
    /// [`FREE_SPACE_MARGIN_M`]).
    pub free_space_violation: f64,
    /// Extra ICP starts around the rough pose that were needed (0: the rough pose itself
    /// converged and passed the checks).
    pub extra_starts: usize,
    /// Position error of the calibrated pose, metres.
    pub pos_error_m: f64,
    /// Orientation error of the calibrated pose, degrees (absolute, wrapped).
    pub rot_error_deg: f64,
    /// Position error of the rough pose, metres.
    pub rough_pos_error_m: f64,
    /// Orientation error of the rough pose, degrees.
    pub rough_rot_error_deg: f64,
}

/// The outcome of `calibration = icp` on a simulated room.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    /// Server time at which the poses were calibrated (end of the last client's warm-up), µs.
    pub t_us: i64,
    /// Sensor ids in calibration order (the reference first).
    pub order: Vec<u16>,
    /// Every scanner, in the scenario's order.
    pub scanners: Vec<ScannerCalibration>,
    /// Largest position error over the scanners, metres.
    pub max_pos_error_m: f64,
    /// Largest orientation error over the scanners, degrees.
    pub max_rot_error_deg: f64,
    /// Fused frames the server closed before the calibration and did not track (their poses
    /// were unknown); 0 outside [`super::run_room`].
    pub frames_discarded: usize,
}

impl CalibrationReport {
    /// The calibrated poses `(sensor, pose)`, in the scenario's order.
    pub fn poses(&self) -> Vec<(SensorId, Pose2)> {
        self.scanners
            .iter()
            .map(|s| (SensorId(s.sensor), s.pose))
            .collect()
    }
}

/// Margin of the free-space check, metres: a point counts as seen through only if it is this
/// much closer than the scanner's background range (5× the 3 cm far-range noise).
pub const FREE_SPACE_MARGIN_M: f64 = 0.15;

fn scanner_label(s: &ScannerSim) -> String {
    format!("{} (sensor {})", s.name, s.id.0)
}

/// `(position error m, orientation error degrees)` of `p` against `truth`.
pub fn pose_error(p: &Pose2, truth: &Pose2) -> (f64, f64) {
    (
        (p.x - truth.x).hypot(p.y - truth.y),
        wrap_angle(p.theta - truth.theta).abs().to_degrees(),
    )
}

/// The rough initial poses of `sc`'s scanners under `cfg` (scenario order): the poses of
/// `calib_rough_poses` if given (one per scanner), otherwise the seeded draw of
/// [`Scenario::hand_measured_poses`] with the reference scanner at its true pose.
pub fn rough_poses(sc: &Scenario, cfg: &LidarPeopleConfig) -> Result<Vec<Pose2>, TrackerError> {
    let r = reference_index(&sc.scanners, cfg)?;
    if !cfg.calib_rough_poses.is_empty() {
        if cfg.calib_rough_poses.len() != sc.scanners.len() {
            return Err(TrackerError::config(
                "lidar_people",
                format!(
                    "calib_rough_poses has {} poses, the scenario has {} scanners",
                    cfg.calib_rough_poses.len(),
                    sc.scanners.len()
                ),
            ));
        }
        return Ok(cfg
            .calib_rough_poses
            .iter()
            .map(|p| Pose2::new(p[0], p[1], p[2].to_radians()))
            .collect());
    }
    let mut rough = sc
        .hand_measured_poses(cfg.calib_max_shift_m, cfg.calib_max_rot_deg.to_radians())
        .map_err(|e| TrackerError::config("lidar_people", e.to_string()))?;
    rough[r] = sc.scanners[r].pose;
    Ok(rough)
}

fn reference_index(
    scanners: &[ScannerSim],
    cfg: &LidarPeopleConfig,
) -> Result<usize, TrackerError> {
    scanners
        .iter()
        .position(|s| s.id.0 == cfg.calib_reference)
        .ok_or_else(|| {
            TrackerError::config(
                "lidar_people",
                format!(
                    "calib_reference = {} is not a scanner of the scenario (ids {:?})",
                    cfg.calib_reference,
                    scanners.iter().map(|s| s.id.0).collect::<Vec<_>>()
                ),
            )
        })
}

/// Calibrates `scanners` from their long-term backgrounds `b_n` (`backgrounds[i]` is scanner
/// `i`'s, one entry per beam, metres, `None` = unknown) starting from `rough` (scenario order;
/// the reference's entry is taken as exact), and reports the errors against the scanners' true
/// poses. `t` is stamped on the report.
pub fn calibrate_backgrounds(
    scanners: &[ScannerSim],
    rough: &[Pose2],
    backgrounds: &[&[Option<f64>]],
    cfg: &LidarPeopleConfig,
    t: TimeUs,
) -> Result<CalibrationReport, TrackerError> {
    if scanners.len() != rough.len() || scanners.len() != backgrounds.len() {
        return Err(TrackerError::config(
            "lidar_people",
            format!(
                "calibration needs one rough pose and one background per scanner: {} scanners, {} poses, {} backgrounds",
                scanners.len(),
                rough.len(),
                backgrounds.len()
            ),
        ));
    }
    let r = reference_index(scanners, cfg)?;
    let cc = CalibConfig {
        point_to_line: cfg.calib_point_to_line,
        ..CalibConfig::default()
    };
    let mut sets = Vec::with_capacity(scanners.len());
    for ((s, b), p) in scanners.iter().zip(backgrounds).zip(rough) {
        let fail = |reason: String, cloud: Option<CloudError>| TrackerError::Calibration {
            scanner: scanner_label(s),
            reason,
            cloud,
        };
        if !p.is_finite() {
            return Err(fail("its rough pose is not finite".into(), None));
        }
        let points = background_points(b, &s.geometry, cc.max_background_range)
            .map_err(|e| fail(format!("its background b_n is unusable: {e}"), Some(e)))?;
        if points.len() < 3 {
            return Err(fail(
                format!(
                    "its background has {} valid beams below {} m (need at least 3)",
                    points.len(),
                    cc.max_background_range
                ),
                None,
            ));
        }
        sets.push(ScannerBackground {
            sensor: s.id,
            points,
            pose: *p,
        });
    }
    let mut tried = vec![0usize; scanners.len()];
    let mut first_err: Option<TrackerError> = None;
    let (results, calibrated, free) = loop {
        match attempt(scanners, &sets, backgrounds, r, cfg, &cc) {
            Ok(x) => break x,
            Err((Some(k), e)) if k != r && tried[k] < EXTRA_STARTS.len() => {
                // another start around the rough pose of the scanner that failed
                let (dx, dy, dth) = EXTRA_STARTS[tried[k]];
                tried[k] += 1;
                let p = rough[k];
                sets[k].pose = Pose2::new(p.x + dx, p.y + dy, p.theta + dth.to_radians());
                first_err.get_or_insert(e);
            }
            Err((_, e)) => {
                let n: usize = tried.iter().sum();
                let mut e = first_err.unwrap_or(e);
                if let TrackerError::Calibration { reason, .. } = &mut e
                    && n > 0
                {
                    let _ = write!(
                        reason,
                        " (and {n} further starts around the rough poses failed too)"
                    );
                }
                return Err(e);
            }
        }
    };
    let mut out = Vec::with_capacity(scanners.len());
    for (i, ((s, set), p)) in scanners.iter().zip(&sets).zip(rough).enumerate() {
        let res = &calibrated[i];
        let (pe, re) = pose_error(&res.pose, &s.pose);
        let (rpe, rre) = pose_error(p, &s.pose);
        out.push(ScannerCalibration {
            sensor: s.id.0,
            name: s.name.clone(),
            reference: i == r,
            rough: *p,
            pose: res.pose,
            truth: s.pose,
            background_points: set.points.len(),
            overlap: res.overlap,
            rms_m: res.rms,
            free_space_violation: free[i].fraction(),
            extra_starts: tried[i],
            pos_error_m: pe,
            rot_error_deg: re,
            rough_pos_error_m: rpe,
            rough_rot_error_deg: rre,
        });
    }
    Ok(CalibrationReport {
        t_us: t.0,
        order: results.iter().map(|x| x.sensor.0).collect(),
        max_pos_error_m: out.iter().map(|s| s.pos_error_m).fold(0.0, f64::max),
        max_rot_error_deg: out.iter().map(|s| s.rot_error_deg).fold(0.0, f64::max),
        scanners: out,
        frames_discarded: 0,
    })
}

/// The server side of `calibration = icp` during a run: waits for every client's `b_n`, then
/// calibrates once.
#[derive(Debug, Clone)]
pub(crate) struct PendingCalibration {
    scanners: Vec<ScannerSim>,
    pub(crate) rough: Vec<Pose2>,
    scans: Vec<u64>,
    limit: u64,
}

impl PendingCalibration {
    /// For the scanners of `sc` under `cfg` (which must say `calibration = icp`).
    pub(crate) fn new(sc: &Scenario, cfg: &LidarPeopleConfig) -> Result<Self, TrackerError> {
        if cfg.calibration != Calibration::Icp {
            return Err(TrackerError::config(
                "lidar_people",
                "calibration from the backgrounds needs calibration = icp",
            ));
        }
        let rough = rough_poses(sc, cfg)?;
        let period = sc
            .scanners
            .iter()
            .map(|s| s.geometry.scan_period)
            .fold(f64::INFINITY, f64::min)
            .max(1e-6);
        // a client whose model has not published b_n after twice the warm-up never will
        let limit = (2.0 * cfg.t_warm_s / period).ceil().max(1.0) as u64;
        Ok(Self {
            scanners: sc.scanners.clone(),
            rough,
            scans: vec![0; sc.scanners.len()],
            limit,
        })
    }

    /// Called after client `i` has processed a scan at server time `t`: the report once every
    /// client has published its background, `None` before; an error if client `i` has not
    /// published one after twice the warm-up, or if the calibration fails.
    pub(crate) fn on_scan<B: BackgroundModel>(
        &mut self,
        clients: &[ClientPipeline<B>],
        i: usize,
        t: TimeUs,
        cfg: &LidarPeopleConfig,
    ) -> Result<Option<CalibrationReport>, TrackerError> {
        if let Some(n) = self.scans.get_mut(i) {
            *n += 1;
            if *n > self.limit && clients[i].background.published_background().is_none() {
                return Err(TrackerError::Calibration {
                    scanner: scanner_label(&self.scanners[i]),
                    reason: format!(
                        "its background model published no long-term background b_n after {n} scans \
                         (calibration = icp needs it: revealed_background = true; the literal preset keeps none)"
                    ),
                    cloud: None,
                });
            }
        }
        let Some(bgs) = clients
            .iter()
            .map(|c| c.background.published_background())
            .collect::<Option<Vec<_>>>()
        else {
            return Ok(None);
        };
        calibrate_backgrounds(&self.scanners, &self.rough, &bgs, cfg, t).map(Some)
    }
}

/// Runs the clients of `sc` (quarry-cloud's chi-square background of `cfg`) until every one has
/// learned its background, then calibrates as `calibration = icp` does in [`super::run_room`]
/// (`cfg.calibration` is taken as `icp`). This is the spec's `calib` scenario run on its own:
/// `calibrate_scenario(Scenario::calib(seed), &cfg)` returns the recovered poses and their
/// errors against the truth.
pub fn calibrate_scenario(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
) -> Result<CalibrationReport, TrackerError> {
    let cfg = LidarPeopleConfig {
        calibration: Calibration::Icp,
        ..cfg.clone()
    };
    cfg.validate()?;
    if !cfg.revealed_background {
        return Err(TrackerError::config(
            "lidar_people",
            "calibration = icp needs the long-term background b_n (revealed_background = true)",
        ));
    }
    let mut pending = PendingCalibration::new(&sc, &cfg)?;
    let mut clients = sc
        .scanners
        .iter()
        .map(|s| Ok(ClientPipeline::new(s.id, background_of(&cfg, &s.geometry)?)))
        .collect::<Result<Vec<_>, TrackerError>>()?;
    let mut runner =
        Runner::new(sc).map_err(|e| TrackerError::config("lidar_people", e.to_string()))?;
    while let Some(ev) = runner
        .next_event()
        .map_err(|e| TrackerError::config("lidar_people", e.to_string()))?
    {
        if let RoomEvent::Scan(cs) = ev {
            clients[cs.scanner].on_scan(&cs.scan, cs.clock_synced)?;
            if let Some(rep) = pending.on_scan(&clients, cs.scanner, cs.t_true, &cfg)? {
                return Ok(rep);
            }
        }
    }
    Err(TrackerError::config(
        "lidar_people",
        "the scenario ended before every scanner had learned its background (it must last longer than t_warm_s)",
    ))
}

/// Extra ICP starts `(dx m, dy m, dθ degrees)` around a scanner's rough pose, tried in this
/// order when its registration is refused (a choice beyond §2.3; every result still passes the
/// same acceptance and free-space checks).
const EXTRA_STARTS: [(f64, f64, f64); 10] = [
    (0.0, 0.0, 5.0),
    (0.0, 0.0, -5.0),
    (0.0, 0.0, 10.0),
    (0.0, 0.0, -10.0),
    (0.0, 0.0, 15.0),
    (0.0, 0.0, -15.0),
    (0.25, 0.0, 0.0),
    (-0.25, 0.0, 0.0),
    (0.0, 0.25, 0.0),
    (0.0, -0.25, 0.0),
];

/// Results in calibration order, the same in scenario order, free-space checks per scanner.
type Attempt = (Vec<CalibResult>, Vec<CalibResult>, Vec<FreeSpaceCheck>);

/// One calibration of every scanner from the poses in `sets`, with the acceptance and
/// free-space checks; on failure, the index of the scanner to blame (if known) and the error.
fn attempt(
    scanners: &[ScannerSim],
    sets: &[ScannerBackground],
    backgrounds: &[&[Option<f64>]],
    r: usize,
    cfg: &LidarPeopleConfig,
    cc: &CalibConfig,
) -> Result<Attempt, (Option<usize>, TrackerError)> {
    let index_of = |id: SensorId| scanners.iter().position(|s| s.id == id);
    let reference = sets[r].clone();
    let others: Vec<ScannerBackground> = sets
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != r)
        .map(|(_, s)| s.clone())
        .collect();
    let results = calibrate(cc, &reference, &others).map_err(|e| {
        let blamed = match &e {
            CloudError::CalibrationInsufficient { sensor, .. } => index_of(*sensor),
            _ => None,
        };
        let scanner = match &e {
            CloudError::CalibrationInsufficient { sensor, .. } => scanners
                .iter()
                .find(|s| s.id == *sensor)
                .map_or_else(|| format!("sensor {}", sensor.0), scanner_label),
            _ => "(registration of the background set)".to_string(),
        };
        let reason = match &e {
            CloudError::CalibrationInsufficient {
                overlap,
                min_overlap,
                rms,
                max_rms,
                ..
            } => format!(
                "ICP of its background from the rough pose ends with overlap {overlap:.3} \
                 (need >= {min_overlap}) and inlier RMS {rms:.4} m (need <= {max_rms}); \
                 the rough pose must be within about 0.5 m and 15° of the truth"
            ),
            other => other.to_string(),
        };
        (
            blamed,
            TrackerError::Calibration {
                scanner,
                reason,
                cloud: Some(e),
            },
        )
    })?;
    let mut calibrated = Vec::with_capacity(scanners.len());
    for s in scanners {
        let res = results.iter().find(|x| x.sensor == s.id).ok_or_else(|| {
            (
                None,
                TrackerError::Calibration {
                    scanner: scanner_label(s),
                    reason: "no result from the registration".into(),
                    cloud: None,
                },
            )
        })?;
        calibrated.push(*res);
    }
    // free-space consistency of every scanner with every other one, under the calibrated poses
    let world: Vec<Vec<quarry_core::Point2>> = sets
        .iter()
        .zip(&calibrated)
        .map(|(set, res)| set.points.iter().map(|q| res.pose.apply(q)).collect())
        .collect();
    let mut free = vec![FreeSpaceCheck::default(); scanners.len()];
    for (i, s) in scanners.iter().enumerate() {
        for (j, o) in scanners.iter().enumerate() {
            if i == j {
                continue;
            }
            let c = free_space_violations(
                &world[j],
                &calibrated[i].pose,
                backgrounds[i],
                &s.geometry,
                FREE_SPACE_MARGIN_M,
            )
            .map_err(|e| {
                (
                    None,
                    TrackerError::Calibration {
                        scanner: scanner_label(s),
                        reason: format!("free-space check against {}: {e}", scanner_label(o)),
                        cloud: Some(e),
                    },
                )
            })?;
            free[i] = free[i].merged(c);
            free[j] = free[j].merged(c);
        }
    }
    // blame the non-reference scanner with the most violations
    if let Some((i, f)) = free
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != r)
        .map(|(i, f)| (i, f.fraction()))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        && f > cfg.calib_max_free_space_violation
    {
        return Err((
            Some(i),
            TrackerError::Calibration {
                scanner: scanner_label(&scanners[i]),
                reason: format!(
                    "ICP converged to a pose inconsistent with the other scanners: {:.1} % of the \
                 background points in view lie in space one of them saw through (allowed {:.1} %, \
                 calib_max_free_space_violation); the rough pose must be within about 0.5 m and \
                 15° of the truth",
                    100.0 * f,
                    100.0 * cfg.calib_max_free_space_violation
                ),
                cloud: None,
            },
        ));
    }
    Ok((results, calibrated, free))
}
