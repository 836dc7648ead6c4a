//! `calibration = icp` in the simulated room: the seeded "hand-measured" rough poses around the
//! true ones, and the spec's `calib` scenario run on its own.

use quarry_core::Pose2;
use quarry_sim::lidar_room::{RoomEvent, Runner, Scenario};
use quarry_trackers::lidar_people::{
    Calibration, CalibrationReport, ClientPipeline, LidarPeopleConfig, PendingCalibration,
    ScannerInfo, background_of, reference_index,
};
use quarry_trackers::{TrackerConfig, TrackerError};

use crate::{ReproError, Result};

/// The scanners of `sc` as the calibration sees them (with their true poses, against which
/// the report measures the errors).
pub fn scanner_infos(sc: &Scenario) -> Vec<ScannerInfo> {
    sc.scanners
        .iter()
        .map(|s| ScannerInfo {
            id: s.id,
            name: s.name.clone(),
            geometry: s.geometry,
            pose: s.pose,
        })
        .collect()
}

/// The rough initial poses of `sc`'s scanners under `cfg` (scenario order): the poses of
/// `calib_rough_poses` if given (one per scanner), otherwise the seeded draw of
/// [`Scenario::hand_measured_poses`] with the reference scanner at its true pose.
pub fn rough_poses(sc: &Scenario, cfg: &LidarPeopleConfig) -> Result<Vec<Pose2>> {
    let r = reference_index(&scanner_infos(sc), cfg)?;
    if !cfg.calib_rough_poses.is_empty() {
        if cfg.calib_rough_poses.len() != sc.scanners.len() {
            return Err(TrackerError::config(
                "lidar_people",
                format!(
                    "calib_rough_poses has {} poses, the scenario has {} scanners",
                    cfg.calib_rough_poses.len(),
                    sc.scanners.len()
                ),
            )
            .into());
        }
        return Ok(cfg
            .calib_rough_poses
            .iter()
            .map(|p| Pose2::new(p[0], p[1], p[2].to_radians()))
            .collect());
    }
    let mut rough =
        sc.hand_measured_poses(cfg.calib_max_shift_m, cfg.calib_max_rot_deg.to_radians())?;
    rough[r] = sc.scanners[r].pose;
    Ok(rough)
}

/// Runs the clients of `sc` (quarry-cloud's chi-square background of `cfg`) until every one has
/// learned its background, then calibrates as `calibration = icp` does in [`super::run_room`]
/// (`cfg.calibration` is taken as `icp`). This is the spec's `calib` scenario run on its own:
/// `calibrate_scenario(Scenario::calib(seed), &cfg)` returns the recovered poses and their
/// errors against the truth.
pub fn calibrate_scenario(sc: Scenario, cfg: &LidarPeopleConfig) -> Result<CalibrationReport> {
    let cfg = LidarPeopleConfig {
        calibration: Calibration::Icp,
        ..cfg.clone()
    };
    cfg.validate()?;
    let mut pending = PendingCalibration::new(scanner_infos(&sc), rough_poses(&sc, &cfg)?, &cfg)?;
    let mut clients = sc
        .scanners
        .iter()
        .map(|s| Ok(ClientPipeline::new(s.id, background_of(&cfg, &s.geometry)?)))
        .collect::<Result<Vec<_>, TrackerError>>()?;
    let mut runner = Runner::new(sc)?;
    while let Some(ev) = runner.next_event()? {
        if let RoomEvent::Scan(cs) = ev {
            clients[cs.scanner].on_scan(&cs.scan, cs.clock_synced)?;
            if let Some(rep) = pending.on_scan(&clients, cs.scanner, cs.t_true, &cfg)? {
                return Ok(rep);
            }
        }
    }
    Err(ReproError::Invalid(
        "the scenario ended before every scanner had learned its background (it must last longer than t_warm_s)"
            .into(),
    ))
}
