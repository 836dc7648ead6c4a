//! The in-process run of the room simulator (spec 003 §1, §7): simulated clients (the same
//! client code as the networked nodes), the simulated network, and the server, over one event
//! queue in simulated time.

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use quarry_core::{
    BackgroundModel, MultiTargetTracker, Point2, PolarScan, Pose2, ScanGeometry, SensorId, TimeUs,
};
use quarry_net::AssemblerFusion;
use quarry_sim::lidar_room::{GtFrame, RoomEvent, Runner, Scenario};
use quarry_trackers::lidar_people::{
    Calibration, CalibrationReport, ClientPipeline, DefaultLidarTracker, DynamicScan, FusedPoints,
    Fusion, LidarPeopleConfig, LidarTrack, PendingCalibration, RowSource, ServerPipeline,
    background_of,
};
use quarry_trackers::{TrackerConfig, TrackerError};

use super::calibration::{rough_poses, scanner_infos};
use super::metrics::EvalFrame;
use crate::{ReproError, Result};

/// The result of an in-process run over the room simulator.
#[derive(Debug, Clone, Default)]
pub struct RoomRun {
    /// Ground truth of every frame.
    pub gt: Vec<GtFrame>,
    /// Track rows of every tracked frame, by frame index.
    pub tracks: Vec<(u64, TimeUs, Vec<LidarTrack>)>,
    /// Background (static) points in the world frame, from the last scans.
    pub background: Vec<Point2>,
    /// Number of tracked frames.
    pub frames_tracked: usize,
    /// Time spent in fusion + tracking, seconds.
    pub server_seconds: f64,
    /// Time spent in the clients' background subtraction, seconds.
    pub client_seconds: f64,
    /// `calibration = icp`: the calibrated poses and their errors against the truth.
    pub calibration: Option<CalibrationReport>,
    /// The run was stopped early by its stop flag ([`run_room_default_until`]): `gt` and
    /// `tracks` end at the frame it stopped at.
    pub interrupted: bool,
}

impl RoomRun {
    /// The evaluation frames of the §4 window: `n` consecutive frames from the first with
    /// `t ≥ t_start`. Frames the server never closed count as "no tracks".
    pub fn eval_window(&self, t_start: TimeUs, n: usize) -> Vec<EvalFrame> {
        let by_frame: std::collections::HashMap<u64, &Vec<LidarTrack>> =
            self.tracks.iter().map(|(k, _, r)| (*k, r)).collect();
        self.gt
            .iter()
            .filter(|g| g.t >= t_start)
            .take(n)
            .map(|g| EvalFrame {
                t: g.t,
                gt: g
                    .people
                    .iter()
                    .map(|p| (p.id, [p.x, p.y], p.pts.iter().sum()))
                    .collect(),
                tracks: by_frame
                    .get(&g.frame)
                    .map(|rows| rows.iter().map(|r| (r.id, [r.x, r.y])).collect())
                    .unwrap_or_default(),
            })
            .collect()
    }
}

/// Runs a scenario in process: simulated clients (the same client code as the networked
/// clients), the simulated network, and the server.
///
/// `make_background` builds each scanner's background model from its geometry;
/// `progress` receives the simulated time fraction in [0, 1].
///
/// With `calibration = icp` the fusion starts from the rough poses of
/// [`rough_poses`] (the true poses are never handed to it), the server calibrates once
/// every client has published its long-term background `b_n`
/// ([`BackgroundModel::published_background`], i.e. at the end of the warm-up), sets the
/// calibrated poses ([`Fusion::set_pose`]) and only then tracks: frames that close before the
/// calibration are not tracked (counted in [`CalibrationReport::frames_discarded`]). A
/// failed calibration ends the run with `TrackerError::Calibration` naming the scanner.
///
/// `stop` is read at every ground-truth frame: once it is set, the run delivers what is in
/// flight, closes the due frames and returns with [`RoomRun::interrupted`] set (for Ctrl-C
/// in a command line; pass a flag that stays `false` to run to the end). `on_scan` sees every
/// simulated scan (scanner index, scan) before its client pipeline does.
pub fn run_room<B, F, T>(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    mut make_background: impl FnMut(&ScanGeometry) -> Result<B, TrackerError>,
    fusion: F,
    tracker: T,
    progress: &mut dyn FnMut(f64),
    stop: &AtomicBool,
    on_scan: &mut dyn FnMut(usize, &PolarScan),
) -> Result<RoomRun>
where
    B: BackgroundModel,
    F: Fusion,
    T: MultiTargetTracker<Input = FusedPoints, Error = TrackerError> + RowSource,
{
    cfg.validate()?;
    let mut fusion = fusion;
    let mut discarded = 0usize;
    let mut calib = match cfg.calibration {
        Calibration::Given => None,
        Calibration::Icp => {
            let p = PendingCalibration::new(scanner_infos(&sc), rough_poses(&sc, cfg)?, cfg)?;
            for (s, r) in sc.scanners.iter().zip(p.rough()) {
                fusion.set_pose(s.id, *r)?;
            }
            Some(p)
        }
    };
    let mut poses: Vec<Pose2> = sc.scanners.iter().map(|s| s.pose).collect();
    let mut clients = sc
        .scanners
        .iter()
        .map(|s| Ok(ClientPipeline::new(s.id, make_background(&s.geometry)?)))
        .collect::<Result<Vec<_>, TrackerError>>()?;
    let geoms: Vec<ScanGeometry> = sc.scanners.iter().map(|s| s.geometry).collect();
    let duration = sc.duration_s;
    let mut runner = Runner::new(sc)?;
    let mut server = ServerPipeline::new(fusion, tracker, cfg.frame_period_s);
    let mut queue: BinaryHeap<Reverse<(i64, u64, usize)>> = BinaryHeap::new();
    let mut pending: Vec<Option<DynamicScan>> = Vec::new();
    let mut counter = 0u64;
    let mut run = RoomRun::default();
    let mut last_report = 0.0;
    let deliver = |server: &mut ServerPipeline<F, T>,
                   queue: &mut BinaryHeap<Reverse<(i64, u64, usize)>>,
                   pending: &mut Vec<Option<DynamicScan>>,
                   now: i64,
                   run: &mut RoomRun,
                   discarded: Option<&mut usize>|
     -> Result<(), TrackerError> {
        while let Some(Reverse((ta, _, idx))) = queue.peek().copied() {
            if ta > now {
                break;
            }
            queue.pop();
            if let Some(m) = pending.get_mut(idx).and_then(Option::take) {
                server.on_message(m, TimeUs(ta))?;
            }
        }
        let t0 = Instant::now();
        if let Some(d) = discarded {
            // poses not calibrated yet: close the due frames without tracking them
            *d += server.fusion.poll(TimeUs(now))?.len();
            run.server_seconds += t0.elapsed().as_secs_f64();
            return Ok(());
        }
        for (k, f, _) in server.poll(TimeUs(now))? {
            run.frames_tracked += 1;
            run.tracks.push((k, f.t, server.tracker.rows().to_vec()));
        }
        run.server_seconds += t0.elapsed().as_secs_f64();
        Ok(())
    };
    while let Some(ev) = runner.next_event()? {
        match ev {
            RoomEvent::Scan(cs) => {
                let now = cs.t_true.0;
                let t0 = Instant::now();
                let i = cs.scanner;
                on_scan(i, &cs.scan);
                let msg = clients[i].on_scan(&cs.scan, cs.clock_synced)?;
                run.client_seconds += t0.elapsed().as_secs_f64();
                if let Some(p) = calib.as_mut()
                    && let Some(rep) = p.on_scan(&clients, i, TimeUs(now), cfg)?
                {
                    for s in &rep.scanners {
                        server.fusion.set_pose(SensorId(s.sensor), s.pose)?;
                    }
                    poses = rep.scanners.iter().map(|s| s.pose).collect();
                    run.calibration = Some(rep);
                    calib = None;
                }
                for a in &cs.arrivals {
                    pending.push(Some(msg.clone()));
                    queue.push(Reverse((a.0, counter, pending.len() - 1)));
                    counter += 1;
                }
                let d = calib.is_some().then_some(&mut discarded);
                deliver(&mut server, &mut queue, &mut pending, now, &mut run, d)?;
            }
            RoomEvent::Frame(g) => {
                if stop.load(Ordering::Relaxed) {
                    run.interrupted = true;
                    break;
                }
                let now = g.t.0;
                let frac = g.t.as_secs_f64() / duration;
                if frac - last_report >= 0.01 {
                    progress(frac.min(1.0));
                    last_report = frac;
                }
                run.gt.push(g);
                let d = calib.is_some().then_some(&mut discarded);
                deliver(&mut server, &mut queue, &mut pending, now, &mut run, d)?;
                if pending.len() > 4096 && queue.is_empty() {
                    pending.clear();
                }
            }
        }
    }
    // flush: everything arrives, then the last frames close at their deadline
    let end = run.gt.last().map_or(0, |g| g.t.0) + 1_000_000;
    if calib.is_some() && !run.interrupted {
        return Err(ReproError::Invalid(
            "calibration = icp: the scenario ended before every scanner had learned its background (it must last longer than t_warm_s)".into(),
        ));
    }
    deliver(&mut server, &mut queue, &mut pending, end, &mut run, None)?;
    if let Some(c) = run.calibration.as_mut() {
        c.frames_discarded = discarded;
    }
    if !run.interrupted {
        progress(1.0);
    }
    // background points for plots
    for (c, (pose, g)) in clients.iter().zip(poses.iter().zip(&geoms)) {
        for &(n, r) in c.last_static() {
            let a = g.angle(n as u32);
            run.background
                .push(pose.apply(&Point2::new(r * a.cos(), r * a.sin())));
        }
    }
    Ok(run)
}

/// [`run_room`] with the default parts: quarry-cloud's chi-square background per scanner, the
/// fusion over quarry-net's `FrameAssembler` (`AssemblerFusion`), and the tracker of `cfg.preset`.
pub fn run_room_default(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<RoomRun> {
    run_room_default_until(sc, cfg, progress, &AtomicBool::new(false))
}

/// [`run_room_default`] that stops early once `stop` is set (see [`run_room`]): the frames
/// up to then are in the returned run, [`RoomRun::interrupted`] says it stopped.
pub fn run_room_default_until(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    progress: &mut dyn FnMut(f64),
    stop: &AtomicBool,
) -> Result<RoomRun> {
    run_room_default_observed(sc, cfg, progress, stop, &mut |_, _| {})
}

/// [`run_room_default_until`] that also hands every simulated scan to `on_scan` (scanner index
/// in `sc.scanners`, the scan as captured) before the client pipeline sees it: what
/// `quarry lidar --mcap` records as the run's input.
pub fn run_room_default_observed(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    progress: &mut dyn FnMut(f64),
    stop: &AtomicBool,
    on_scan: &mut dyn FnMut(usize, &PolarScan),
) -> Result<RoomRun> {
    // with `icp` the fusion only ever sees the rough poses, then the calibrated ones
    let start_poses: Vec<Pose2> = match cfg.calibration {
        Calibration::Given => sc.scanners.iter().map(|s| s.pose).collect(),
        Calibration::Icp => rough_poses(&sc, cfg)?,
    };
    let sensors: Vec<(SensorId, Pose2, ScanGeometry)> = sc
        .scanners
        .iter()
        .zip(start_poses)
        .map(|(s, p)| (s.id, p, s.geometry))
        .collect();
    let fusion = AssemblerFusion::new(&sensors, cfg)?;
    let tracker = DefaultLidarTracker::from_config(cfg)?;
    run_room(
        sc,
        cfg,
        |g| background_of(cfg, g),
        fusion,
        tracker,
        progress,
        stop,
        on_scan,
    )
}
