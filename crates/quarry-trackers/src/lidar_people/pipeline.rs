//! The client and server halves of the distributed pipeline (spec 003 §1, §7), and the
//! in-process run over the room simulator.

use super::config::{FusionTime, LidarPeopleConfig};
use super::metrics::EvalFrame;
use super::tracker::{FusedPoints, LidarTrack};
use crate::TrackerConfig as _;
use crate::TrackerError;
use quarry_cloud::net::wire::{FLAG_CLOCK_SYNCED, Header, Kind, encode_scan};
use quarry_cloud::net::{FrameAssembler, FrameConfig, SensorConfig};
use quarry_core::{
    BackgroundModel, BeamLabel, Clusterer, FrameIndex, MultiTargetTracker, Point2, PolarScan,
    Pose2, Registration2, ScanGeometry, SensorId, Stamp, TimeUs,
};
use quarry_sim::lidar_room::{GtFrame, RoomEvent, Runner, Scenario};
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::time::Instant;

/// The dynamic points of one scan, as a client publishes them (the paper's
/// `[timestamp, LaserData]`).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicScan {
    /// Sensor.
    pub sensor: SensorId,
    /// Scan counter.
    pub seq: u32,
    /// Synchronised capture time of the front beam.
    pub t: TimeUs,
    /// Whether the client's clock was synchronised.
    pub synced: bool,
    /// `(beam, range_mm)` of the dynamic beams.
    pub beams: Vec<(u16, u16)>,
}

/// One scanner client: background subtraction, then publication of the dynamic beams.
#[derive(Debug, Clone)]
pub struct ClientPipeline<B> {
    /// Sensor id.
    pub sensor: SensorId,
    /// The background model.
    pub background: B,
    static_points: Vec<(usize, f64)>,
}

impl<B: BackgroundModel> ClientPipeline<B> {
    /// A client for `sensor` with its background model.
    pub fn new(sensor: SensorId, background: B) -> Self {
        Self {
            sensor,
            background,
            static_points: Vec::new(),
        }
    }

    /// Labels a scan and returns its dynamic beams.
    pub fn on_scan(&mut self, scan: &PolarScan, synced: bool) -> Result<DynamicScan, TrackerError> {
        let labels = self.background.classify(scan)?;
        let mut beams = Vec::new();
        self.static_points.clear();
        for (n, l) in labels.iter().enumerate() {
            match l {
                BeamLabel::Dynamic => beams.push((n as u16, scan.ranges_mm[n])),
                BeamLabel::Static => {
                    if let Some(r) = scan.range_m(n) {
                        self.static_points.push((n, r));
                    }
                }
                BeamLabel::Invalid => {}
            }
        }
        Ok(DynamicScan {
            sensor: scan.sensor,
            seq: scan.seq,
            t: scan.t,
            synced,
            beams,
        })
    }

    /// The static returns `(beam, range m)` of the last scan (the background, for plots and
    /// calibration).
    pub fn last_static(&self) -> &[(usize, f64)] {
        &self.static_points
    }
}

/// The server's fusion stage: dynamic scans in (with arrival times), closed frames out.
pub trait Fusion {
    /// Hands over one received message.
    fn push(&mut self, scan: DynamicScan, arrival: TimeUs) -> Result<(), TrackerError>;
    /// Closes every frame whose release condition holds at server time `now`.
    fn poll(&mut self, now: TimeUs) -> Result<Vec<FusedPoints>, TrackerError>;
    /// Replaces the world pose of `sensor` for the frames closed from now on
    /// (`calibration = icp`). The default refuses: a fusion stage that cannot change poses
    /// cannot run with calibrated poses.
    fn set_pose(&mut self, sensor: SensorId, pose: Pose2) -> Result<(), TrackerError> {
        let _ = pose;
        Err(TrackerError::config(
            "lidar_people",
            format!(
                "this fusion stage cannot change the pose of sensor {} (calibration = icp needs Fusion::set_pose)",
                sensor.0
            ),
        ))
    }
}

/// The server: fusion then tracking.
pub struct ServerPipeline<F, T> {
    /// The fusion stage.
    pub fusion: F,
    /// The tracker.
    pub tracker: T,
    frame_us: i64,
    /// Time spent in the tracker, seconds.
    pub tracker_seconds: f64,
}

impl<F: Fusion, T> ServerPipeline<F, T>
where
    T: MultiTargetTracker<Input = FusedPoints, Error = TrackerError>,
{
    /// A server over a fusion stage and a tracker, with frame period `frame_period_s`.
    pub fn new(fusion: F, tracker: T, frame_period_s: f64) -> Self {
        Self {
            fusion,
            tracker,
            frame_us: (frame_period_s * 1e6).round() as i64,
            tracker_seconds: 0.0,
        }
    }

    /// Receives one message.
    pub fn on_message(&mut self, scan: DynamicScan, arrival: TimeUs) -> Result<(), TrackerError> {
        self.fusion.push(scan, arrival)
    }

    /// Closes the due frames and tracks them; returns `(frame index, frame)` of each.
    pub fn poll(
        &mut self,
        now: TimeUs,
    ) -> Result<Vec<(u64, FusedPoints, Vec<quarry_core::TrackReport>)>, TrackerError> {
        let mut out = Vec::new();
        for f in self.fusion.poll(now)? {
            let k = (f.t.0 / self.frame_us.max(1)) as u64;
            let stamp = Stamp {
                frame: FrameIndex(k),
                t: f.t,
            };
            let t0 = Instant::now();
            let reps = self.tracker.step(stamp, &f)?;
            self.tracker_seconds += t0.elapsed().as_secs_f64();
            out.push((k, f, reps));
        }
        Ok(out)
    }
}

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
    pub calibration: Option<super::CalibrationReport>,
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
/// [`super::rough_poses`] (the true poses are never handed to it), the server calibrates once
/// every client has published its long-term background `b_n`
/// ([`BackgroundModel::published_background`], i.e. at the end of the warm-up), sets the
/// calibrated poses ([`Fusion::set_pose`]) and only then tracks: frames that close before the
/// calibration are not tracked (counted in [`super::CalibrationReport::frames_discarded`]). A
/// failed calibration ends the run with [`TrackerError::Calibration`] naming the scanner.
pub fn run_room<B, F, T>(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    mut make_background: impl FnMut(&ScanGeometry) -> Result<B, TrackerError>,
    fusion: F,
    tracker: T,
    progress: &mut dyn FnMut(f64),
) -> Result<RoomRun, TrackerError>
where
    B: BackgroundModel,
    F: Fusion,
    T: MultiTargetTracker<Input = FusedPoints, Error = TrackerError> + RowSource,
{
    cfg.validate()?;
    let mut fusion = fusion;
    let mut discarded = 0usize;
    let mut calib = match cfg.calibration {
        super::Calibration::Given => None,
        super::Calibration::Icp => {
            let p = super::calibration::PendingCalibration::new(&sc, cfg)?;
            for (s, r) in sc.scanners.iter().zip(&p.rough) {
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
    let mut runner =
        Runner::new(sc).map_err(|e| TrackerError::config("lidar_people", e.to_string()))?;
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
    while let Some(ev) = runner
        .next_event()
        .map_err(|e| TrackerError::config("lidar_people", e.to_string()))?
    {
        match ev {
            RoomEvent::Scan(cs) => {
                let now = cs.t_true.0;
                let t0 = Instant::now();
                let i = cs.scanner;
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
    if calib.is_some() {
        return Err(TrackerError::config(
            "lidar_people",
            "calibration = icp: the scenario ended before every scanner had learned its background (it must last longer than t_warm_s)",
        ));
    }
    deliver(&mut server, &mut queue, &mut pending, end, &mut run, None)?;
    if let Some(c) = run.calibration.as_mut() {
        c.frames_discarded = discarded;
    }
    progress(1.0);
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

/// Trackers that expose the `tracks.csv` rows of their last frame.
pub trait RowSource {
    /// The rows of the last processed frame.
    fn rows(&self) -> &[LidarTrack];
}

impl<C: Clusterer, R: Registration2> RowSource for super::LidarPeopleTracker<C, R> {
    fn rows(&self) -> &[LidarTrack] {
        self.last_rows()
    }
}

/// Encodes a client's dynamic scan as wire datagrams (spec §7.1; several parts when it has more
/// than 350 points).
pub fn encode_dynamic(scan: &DynamicScan, t_send: TimeUs) -> Result<Vec<Vec<u8>>, TrackerError> {
    let header = Header {
        kind: Kind::DynamicScan,
        sensor: scan.sensor,
        seq: scan.seq,
        part: 0,
        parts: 1,
        flags: if scan.synced { FLAG_CLOCK_SYNCED } else { 0 },
        t_capture: scan.t,
        t_send,
    };
    encode_scan(header, &scan.beams)
        .map_err(|e| quarry_core::CoreError::numerical("wire encode", e.to_string()).into())
}

/// The fusion stage over quarry-cloud's sans-IO [`FrameAssembler`]: every message goes through
/// the wire codec, so the in-process run exercises the same bytes as the networked one.
#[derive(Debug)]
pub struct AssemblerFusion {
    /// The assembler.
    pub assembler: FrameAssembler,
    /// Which time a scan is fused by (`cfg.fusion`).
    pub fusion: FusionTime,
}

impl AssemblerFusion {
    /// An assembler for sensors `(id, world pose, geometry)` with the §2.4 times of `cfg`, the
    /// server starting at time 0.
    pub fn new(
        sensors: &[(SensorId, Pose2, ScanGeometry)],
        cfg: &LidarPeopleConfig,
    ) -> Result<Self, TrackerError> {
        let sc: Vec<SensorConfig> = sensors
            .iter()
            .map(|(id, pose, g)| SensorConfig {
                id: *id,
                pose: *pose,
                geometry: *g,
            })
            .collect();
        let fc = FrameConfig {
            period_us: (cfg.frame_period_s * 1e6).round() as i64,
            tau_sync_us: (cfg.tau_sync_s * 1e6).round() as i64,
            max_latency_us: (cfg.l_max_s * 1e6).round() as i64,
            ..FrameConfig::default()
        };
        let assembler =
            FrameAssembler::new(fc, &sc, TimeUs(0)).map_err(quarry_core::CoreError::from)?;
        Ok(Self {
            assembler,
            fusion: cfg.fusion,
        })
    }
}

impl Fusion for AssemblerFusion {
    fn push(&mut self, mut scan: DynamicScan, arrival: TimeUs) -> Result<(), TrackerError> {
        if self.fusion == FusionTime::Arrival {
            // the negative control: the server's own clock stands in for the capture stamp
            scan.t = arrival;
            scan.synced = true;
        }
        for d in encode_dynamic(&scan, scan.t)? {
            self.assembler.on_datagram(&d, arrival);
        }
        Ok(())
    }

    fn set_pose(&mut self, sensor: SensorId, pose: Pose2) -> Result<(), TrackerError> {
        self.assembler
            .set_pose(sensor, pose)
            .map_err(|e| quarry_core::CoreError::from(e).into())
    }

    fn poll(&mut self, now: TimeUs) -> Result<Vec<FusedPoints>, TrackerError> {
        Ok(self
            .assembler
            .poll(now)
            .into_iter()
            .map(|f| FusedPoints {
                t: f.t,
                points: f.points.iter().map(|p| p.p).collect(),
                no_data: f.no_data,
            })
            .collect())
    }
}

/// [`run_room`] with the default parts: quarry-cloud's chi-square background per scanner, the
/// fusion over quarry-cloud's `FrameAssembler`, and the tracker of `cfg.preset`.
pub fn run_room_default(
    sc: Scenario,
    cfg: &LidarPeopleConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<RoomRun, TrackerError> {
    if cfg.calibration == super::Calibration::Icp && !cfg.revealed_background {
        return Err(TrackerError::config(
            "lidar_people",
            "calibration = icp needs the long-term background b_n (revealed_background = true; the literal preset keeps none)",
        ));
    }
    // with `icp` the fusion only ever sees the rough poses, then the calibrated ones
    let start_poses: Vec<Pose2> = match cfg.calibration {
        super::Calibration::Given => sc.scanners.iter().map(|s| s.pose).collect(),
        super::Calibration::Icp => super::rough_poses(&sc, cfg)?,
    };
    let sensors: Vec<(SensorId, Pose2, ScanGeometry)> = sc
        .scanners
        .iter()
        .zip(start_poses)
        .map(|(s, p)| (s.id, p, s.geometry))
        .collect();
    let fusion = AssemblerFusion::new(&sensors, cfg)?;
    let tracker = super::DefaultLidarTracker::from_config(cfg)?;
    run_room(
        sc,
        cfg,
        |g| super::background_of(cfg, g),
        fusion,
        tracker,
        progress,
    )
}
