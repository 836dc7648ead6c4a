//! `lidar-server`: subscribes to the nodes, fuses their scans into frames with the
//! [`FrameAssembler`](crate::proto::FrameAssembler) (spec §7.2: late, duplicated,
//! out-of-order, multi-part and missing scans, unsynchronised and future stamps, restarts,
//! liveness), tracks every closed frame and publishes its tracks.
//!
//! In virtual time ([`run_sim_server`]) the server replays the nodes' simulated deliveries in
//! virtual-time order with a conservative merge: an event at virtual time `t` is processed only
//! once every node has reported progress up to `t` (or ended), so the order of events is that of
//! the in-process run, whatever the real transport does to the interleaving of nodes, and the
//! frames and tracks are bit-identical. In wall-clock mode ([`run_wall_server`]) the server
//! stamps arrivals with its own monotonic clock, answers the nodes' sync requests, and polls
//! the assembler every few milliseconds.

use crate::NetError;
#[cfg(feature = "sim")]
use crate::envelope::SimStep;
use crate::envelope::{SimMessage, TrackMessage};
use crate::fusion::AssemblerFusion;
use crate::proto::FusionStats;
use crate::proto::wire::{Header, Kind, Message, Payload};
use crate::transport::{Transport, keys, sensor_of_key};
use quarry_core::{Point2, Pose2, ScanGeometry, SensorId, TimeUs};
#[cfg(feature = "sim")]
use quarry_sim::lidar_room::FRAME_US;
use quarry_trackers::lidar_people::{
    DefaultLidarTracker, LidarPeopleConfig, LidarTrack, ServerPipeline,
};
#[cfg(feature = "sim")]
use std::cmp::Reverse;
#[cfg(feature = "sim")]
use std::collections::{BTreeMap, BinaryHeap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// One scanner known to the server: id, world pose, beam geometry.
pub type SensorSpec = (SensorId, Pose2, ScanGeometry);

/// What a server run produced.
#[derive(Debug, Clone, Default)]
pub struct ServerRun {
    /// Track rows of every closed frame: (frame index, frame time, rows).
    pub tracks: Vec<(u64, TimeUs, Vec<LidarTrack>)>,
    /// The frame assembler's counters (accepted, dup, late, future, unsynced, lost, ...).
    pub stats: FusionStats,
    /// Frames closed and tracked.
    pub frames_tracked: usize,
    /// Frames closed with no data (skipped by the tracker).
    pub frames_no_data: usize,
    /// Fusion + tracking time, seconds.
    pub server_seconds: f64,
    /// Virtual time: node steps processed.
    pub steps: u64,
    /// Node messages dropped: undecodable, unknown sensor, or a repeated step.
    pub rejected: u64,
    /// Wall clock: sync requests answered.
    pub sync_replies: u64,
    /// Per sensor: the skew monitor's ε_s = min(arrival − t_capture), µs (negative: the sensor's
    /// clock is ahead; above 100 ms: behind, or a slow link).
    pub min_latency_us: Vec<(u16, Option<i64>)>,
    /// This run's session id ([`crate::session`]).
    pub session: u64,
    /// Per sensor (in the server's order): joined, ended, scans accepted, last heard.
    pub sensors: Vec<SensorStatus>,
    /// Join requests refused: (sensor id, reason), once per sensor and reason.
    pub refused: Vec<(u16, String)>,
    /// Beacons of other (older) servers seen on the network.
    pub other_servers: u64,
    /// The run was stopped from outside (Ctrl-C, SIGTERM) before it was complete.
    pub interrupted: bool,
}

/// A frame the server has just closed and tracked, as a frame observer sees it
/// ([`run_wall_server_observed`]): what a recorder (MCAP) or a republisher (ROS 2) needs.
#[derive(Debug, Clone, Copy)]
pub struct ClosedFrame<'a> {
    /// Frame index k (t_f = k · frame period).
    pub frame: u64,
    /// Frame time t_f (server clock).
    pub t: TimeUs,
    /// No sensor contributed (the tracker skipped the frame).
    pub no_data: bool,
    /// Wall clock: the Unix time (µs) of server time 0; `None` in virtual time.
    pub epoch_unix_us: Option<i64>,
    /// The fused dynamic points, world frame.
    pub points: &'a [Point2],
    /// The tracker's rows after this frame.
    pub tracks: &'a [LidarTrack],
}

impl ClosedFrame<'_> {
    /// The frame's time as a Unix time (µs) in wall-clock mode, the simulated time otherwise.
    pub fn unix_us(&self) -> TimeUs {
        TimeUs(self.t.0.saturating_add(self.epoch_unix_us.unwrap_or(0)))
    }
}

/// A frame observer: called once per closed frame, in frame order; an error stops the run.
pub type FrameObserver<'o> = dyn FnMut(&ClosedFrame<'_>) -> Result<(), NetError> + 'o;

/// What the server knows of one of its sensors at the end of a run.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct SensorStatus {
    /// Sensor id.
    pub sensor: u16,
    /// Its node joined (welcomed at least once).
    pub joined: bool,
    /// Joins welcomed (more than one: the node restarted or re-joined).
    pub joins: u64,
    /// Its node sent its end marker.
    pub ended: bool,
    /// Scan datagrams (wall clock) or steps (virtual time) of this sensor accepted.
    pub accepted: u64,
    /// Server seconds since start when anything of this sensor last arrived.
    pub last_heard_s: Option<f64>,
    /// Seconds between that and the end of the run.
    pub silent_for_s: Option<f64>,
}

impl SensorStatus {
    /// `ended`, `never joined`, `silent` (no end marker and nothing for more than 2 s at the
    /// end: the node stopped, crashed or lost its link) or `running`.
    pub fn state(&self) -> &'static str {
        if self.ended {
            "ended"
        } else if !self.joined && self.last_heard_s.is_none() {
            "never joined"
        } else if self.silent_for_s.is_none_or(|s| s > 2.0) {
            "silent"
        } else {
            "running"
        }
    }
}

struct Core {
    server: ServerPipeline<AssemblerFusion, DefaultLidarTracker>,
    run: ServerRun,
    ids: Vec<SensorId>,
    start: Instant,
    last_heard: Vec<Option<Instant>>,
    epoch_unix_us: Option<i64>,
}

impl Core {
    fn new(sensors: &[SensorSpec], cfg: &LidarPeopleConfig) -> Result<Self, NetError> {
        // validates the configuration (once, where the server's tracker is built from it)
        let tracker = DefaultLidarTracker::from_config(cfg)?;
        if cfg.calibration == quarry_trackers::lidar_people::Calibration::Icp {
            // the nodes do not publish BackgroundScan messages yet: refuse rather than fuse
            // with uncalibrated poses
            return Err(NetError::Config(
                "calibration = icp is not supported by the networked server yet (its nodes do not publish their backgrounds); use calibration = given with calibrated poses".into(),
            ));
        }
        let fusion = AssemblerFusion::new(sensors, cfg)?;
        Ok(Self {
            server: ServerPipeline::new(fusion, tracker, cfg.frame_period_s),
            run: ServerRun {
                sensors: sensors
                    .iter()
                    .map(|s| SensorStatus {
                        sensor: s.0.0,
                        ..SensorStatus::default()
                    })
                    .collect(),
                ..ServerRun::default()
            },
            ids: sensors.iter().map(|s| s.0).collect(),
            start: Instant::now(),
            last_heard: vec![None; sensors.len()],
            epoch_unix_us: None,
        })
    }

    /// Notes that something of sensor `k` arrived now.
    fn heard(&mut self, k: usize) {
        let now = Instant::now();
        self.last_heard[k] = Some(now);
        self.run.sensors[k].last_heard_s = Some(now.duration_since(self.start).as_secs_f64());
    }

    /// Answers a join request on `key`: a welcome for a sensor of this server in the same clock
    /// mode, else a refusal naming the reason (recorded once per sensor and reason).
    fn on_join(
        &mut self,
        transport: &dyn Transport,
        session: &Session,
        key: &str,
        payload: &[u8],
    ) -> Result<(), NetError> {
        let Some(id) = sensor_of_key(key) else {
            self.run.rejected += 1;
            return Ok(());
        };
        let requested = crate::session::decode_join(payload);
        let reason = match (self.index(id), requested) {
            (None, _) => Some(format!(
                "sensor id {} is not one of this server's sensors ({}): check the node's --sensor-id and the server's --sensors",
                id.0,
                self.ids
                    .iter()
                    .map(|s| s.0.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
            (Some(_), Some(m)) if m != session.mode => Some(format!(
                "this server runs on the {} clock but sensor {} runs on the {} clock: start node and server with the same --clock",
                session.mode, id.0, m
            )),
            (Some(k), _) => {
                self.heard(k);
                let st = &mut self.run.sensors[k];
                st.joined = true;
                st.joins += 1;
                let w = crate::session::Welcome {
                    mode: session.mode,
                    session: session.id,
                };
                transport.publish(&keys::welcome(id), &w.encode())?;
                None
            }
        };
        if let Some(r) = reason {
            let refusal = crate::session::Refusal {
                // an unknown id concerns every node of that id; a clock mismatch only the
                // nodes on the requested clock
                to: requested.filter(|_| self.index(id).is_some()),
                reason: r.clone(),
            };
            transport.publish(&keys::refuse(id), &refusal.encode())?;
            if !self.run.refused.iter().any(|(s, x)| *s == id.0 && *x == r) {
                crate::node::trace(&format!("server: refused sensor {}: {r}", id.0));
                self.run.refused.push((id.0, r));
            }
        }
        Ok(())
    }

    fn index(&self, id: SensorId) -> Option<usize> {
        self.ids.iter().position(|&s| s == id)
    }

    /// Polls at `now`, tracks the closed frames, publishes their tracks and shows each to
    /// `observer`.
    fn poll(
        &mut self,
        transport: &dyn Transport,
        now: TimeUs,
        observer: &mut FrameObserver<'_>,
    ) -> Result<(), NetError> {
        let t0 = Instant::now();
        let frames = self.server.poll(now)?;
        self.run.server_seconds += t0.elapsed().as_secs_f64();
        for (k, f, _) in frames {
            let rows = self.server.tracker.last_rows().to_vec();
            let m = TrackMessage {
                frame: k,
                t: f.t,
                no_data: f.no_data,
                tracks: rows.clone(),
            };
            transport.publish(keys::TRACKS, &m.encode()?)?;
            observer(&ClosedFrame {
                frame: k,
                t: f.t,
                no_data: f.no_data,
                epoch_unix_us: self.epoch_unix_us,
                points: &f.points,
                tracks: &rows,
            })?;
            self.run.frames_tracked += 1;
            self.run.frames_no_data += usize::from(f.no_data);
            self.run.tracks.push((k, f.t, rows));
        }
        Ok(())
    }

    fn finish(mut self) -> ServerRun {
        let end = Instant::now();
        for (st, h) in self.run.sensors.iter_mut().zip(&self.last_heard) {
            st.silent_for_s = h.map(|h| end.duration_since(h).as_secs_f64());
        }
        let a = &self.server.fusion.assembler;
        self.run.stats = a.stats();
        self.run.min_latency_us = self
            .ids
            .iter()
            .map(|&s| (s.0, a.min_latency_us(s)))
            .collect();
        self.run
    }
}

/// The server's side of [`crate::session`]: its id, the 10 Hz beacon, and the watch for
/// other servers on the same network.
struct Session {
    id: u64,
    mode: crate::session::ClockKind,
    started_unix_us: i64,
    next: Instant,
    others: Box<dyn crate::transport::Subscription>,
}

impl Session {
    fn new(
        transport: &dyn Transport,
        id: u64,
        mode: crate::session::ClockKind,
    ) -> Result<Self, NetError> {
        Ok(Self {
            id,
            mode,
            started_unix_us: crate::session::unix_us(),
            next: Instant::now(),
            others: transport.subscribe(keys::SERVER_READY)?,
        })
    }

    fn beacon(&self) -> crate::session::Beacon {
        crate::session::Beacon {
            mode: self.mode,
            session: self.id,
            started_unix_us: self.started_unix_us,
        }
    }

    /// Publishes the beacon when due and reads the other servers' beacons: this server gives
    /// way ([`NetError::Conflict`]) to an older one; a younger one is counted (it gives way).
    fn tick(&mut self, transport: &dyn Transport, run: &mut ServerRun) -> Result<(), NetError> {
        if Instant::now() >= self.next {
            transport.publish(keys::SERVER_READY, &self.beacon().encode())?;
            self.next = Instant::now() + Duration::from_millis(100);
        }
        let me = self.beacon();
        while let Some(r) = self.others.recv_timeout(Duration::ZERO)? {
            let Some(b) = crate::session::Beacon::decode(&r.payload) else {
                continue;
            };
            if b.session == self.id {
                continue;
            }
            if me.younger_than(&b) {
                return Err(NetError::Conflict(format!(
                    "another lidar-server ({} clock, session {:016x}, started {:.1} s before this one) \
                     already runs on this network: stop it first, or give this one other endpoints",
                    b.mode,
                    b.session,
                    (me.started_unix_us - b.started_unix_us) as f64 / 1e6
                )));
            }
            run.other_servers += 1;
        }
        Ok(())
    }

    /// Tells the nodes that this server stops before they are done (a few copies: the notice
    /// is a datagram like any other).
    fn end_notice(&self, transport: &dyn Transport) -> Result<(), NetError> {
        let m = crate::session::encode_end(self.id);
        for _ in 0..3 {
            transport.publish(keys::SERVER_END, &m)?;
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }
}

/// How long a server waits, once its run is complete, for every node's bye (re-acknowledging
/// the end markers of nodes that missed their acknowledgement) before it returns anyway.
pub const END_LINGER: Duration = Duration::from_secs(3);

/// The end of a run: every node has sent its end marker. Re-acknowledges every end marker that
/// still arrives (a node whose acknowledgement was lost re-sends its marker every 200 ms) until
/// every node has confirmed with a bye, at most [`END_LINGER`].
fn linger(
    transport: &dyn Transport,
    sub: &mut dyn crate::transport::Subscription,
    ids: &[SensorId],
    byes: &mut [bool],
) -> Result<(), NetError> {
    let t0 = Instant::now();
    while !byes.iter().all(|&b| b) && t0.elapsed() < END_LINGER {
        let Some(r) = sub.recv_timeout(Duration::from_millis(50))? else {
            continue;
        };
        let Some(k) = sensor_of_key(&r.key).and_then(|id| ids.iter().position(|&s| s == id)) else {
            continue;
        };
        if r.key.starts_with(keys::END_PREFIX) {
            transport.publish(&keys::end_ack(ids[k]), b"ok")?;
        } else if r.key.starts_with(keys::BYE_PREFIX) {
            byes[k] = true;
        }
    }
    let missing: Vec<String> = ids
        .iter()
        .zip(byes.iter())
        .filter(|(_, b)| !**b)
        .map(|(s, _)| s.0.to_string())
        .collect();
    if missing.is_empty() {
        crate::node::trace(&format!(
            "server: every node confirmed its end after {:.3} s",
            t0.elapsed().as_secs_f64()
        ));
    } else {
        crate::node::trace(&format!(
            "server: no bye from sensor(s) {} within {:.1} s",
            missing.join(", "),
            END_LINGER.as_secs_f64()
        ));
    }
    Ok(())
}

/// Records a node's bye (it received its end acknowledgement).
fn note_bye(key: &str, ids: &[SensorId], byes: &mut [bool]) {
    if let Some(k) = sensor_of_key(key).and_then(|id| ids.iter().position(|&s| s == id)) {
        byes[k] = true;
    }
}

#[cfg(feature = "sim")]
#[derive(Default)]
struct NodeIn {
    next: u32,
    buf: BTreeMap<u32, SimStep>,
    progress: Option<i64>,
    end_steps: Option<u32>,
}

#[cfg(feature = "sim")]
impl NodeIn {
    fn done(&self) -> bool {
        self.end_steps.is_some_and(|n| self.next >= n)
    }
    fn horizon(&self) -> i64 {
        if self.done() {
            i64::MAX
        } else {
            self.progress.unwrap_or(i64::MIN)
        }
    }
}

/// Virtual-time server for `sensors` (in the scenario's scanner order) and a scenario ending
/// at `t_end`. Returns once every node has sent its end marker and every event is processed;
/// fails with [`NetError::Timeout`] when nothing arrives for `idle_timeout`. (Feature `sim`.)
#[cfg(feature = "sim")]
pub fn run_sim_server(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    t_end: TimeUs,
    idle_timeout: Duration,
) -> Result<ServerRun, NetError> {
    let never = AtomicBool::new(false);
    run_sim_server_until(transport, sensors, cfg, t_end, idle_timeout, &never)
}

/// [`run_sim_server`] that also stops, with what it has (`interrupted` set, the nodes told by
/// the end notice), once `stop` is set (a Ctrl-C / SIGTERM handler's flag). (Feature `sim`.)
#[cfg(feature = "sim")]
pub fn run_sim_server_until(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    t_end: TimeUs,
    idle_timeout: Duration,
    stop: &AtomicBool,
) -> Result<ServerRun, NetError> {
    run_sim_server_observed(
        transport,
        sensors,
        cfg,
        t_end,
        idle_timeout,
        stop,
        &mut |_| Ok(()),
    )
}

/// [`run_sim_server_until`] that shows every closed frame to `observer` (a recorder, a
/// republisher). (Feature `sim`.)
#[cfg(feature = "sim")]
pub fn run_sim_server_observed(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    t_end: TimeUs,
    idle_timeout: Duration,
    stop: &AtomicBool,
    observer: &mut FrameObserver<'_>,
) -> Result<ServerRun, NetError> {
    let mut core = Core::new(sensors, cfg)?;
    let mut sub = transport.subscribe(keys::NODE_ALL)?;
    let mut session = Session::new(
        transport,
        crate::session::new_session_id(),
        crate::session::ClockKind::Virtual,
    )?;
    core.run.session = session.id;
    let mut nodes: Vec<NodeIn> = sensors.iter().map(|_| NodeIn::default()).collect();
    let mut ready: BTreeMap<(i64, usize), SimStep> = BTreeMap::new();
    let mut queue: BinaryHeap<Reverse<(i64, u64, usize)>> = BinaryHeap::new();
    let mut pending: Vec<Option<Vec<Vec<u8>>>> = Vec::new();
    let mut counter = 0u64;
    let mut next_frame = 0i64;
    let mut last_gt: Option<i64> = None;
    let mut last_rx = Instant::now();
    let mut byes = vec![false; sensors.len()];

    // the in-process run's `deliver`: every copy that has arrived by `now`, then a poll
    let mut deliver = |core: &mut Core,
                       queue: &mut BinaryHeap<Reverse<(i64, u64, usize)>>,
                       pending: &mut Vec<Option<Vec<Vec<u8>>>>,
                       now: i64|
     -> Result<(), NetError> {
        while let Some(Reverse((ta, _, idx))) = queue.peek().copied() {
            if ta > now {
                break;
            }
            queue.pop();
            if let Some(ds) = pending.get_mut(idx).and_then(Option::take) {
                for d in &ds {
                    core.server.fusion.assembler.on_datagram(d, TimeUs(ta));
                }
            }
        }
        core.poll(transport, TimeUs(now), observer)
    };

    loop {
        // process every event that no node can precede any more
        loop {
            let h = nodes.iter().map(NodeIn::horizon).min().unwrap_or(i64::MAX);
            let tf = next_frame.saturating_mul(FRAME_US);
            let next_scan = ready.keys().next().copied();
            let frame_due = tf < t_end.0;
            if frame_due && h >= tf - 1 && next_scan.is_none_or(|(t, _)| tf <= t) {
                deliver(&mut core, &mut queue, &mut pending, tf)?;
                last_gt = Some(tf);
                next_frame += 1;
                continue;
            }
            if let Some((t, k)) = next_scan
                && h >= t
                && (!frame_due || t < tf)
                && let Some(step) = ready.remove(&(t, k))
            {
                for a in &step.arrivals {
                    pending.push(Some(step.datagrams.clone()));
                    queue.push(Reverse((a.0, counter, pending.len() - 1)));
                    counter += 1;
                }
                core.run.steps += 1;
                deliver(&mut core, &mut queue, &mut pending, t)?;
                if pending.len() > 4096 && queue.is_empty() {
                    pending.clear();
                }
                continue;
            }
            break;
        }
        if nodes.iter().all(NodeIn::done) && ready.is_empty() {
            // everything arrives, then the last frames close at their deadline
            let end = last_gt.unwrap_or(0) + 1_000_000;
            deliver(&mut core, &mut queue, &mut pending, end)?;
            crate::node::trace(&format!(
                "server: run complete, {} steps, {} frames",
                core.run.steps, core.run.frames_tracked
            ));
            let ids = core.ids.clone();
            linger(transport, sub.as_mut(), &ids, &mut byes)?;
            return Ok(core.finish());
        }
        if stop.load(Ordering::Relaxed) {
            crate::node::trace("server: interrupted");
            core.run.interrupted = true;
            session.end_notice(transport)?;
            return Ok(core.finish());
        }
        session.tick(transport, &mut core.run)?;
        let Some(r) = sub.recv_timeout(Duration::from_millis(50))? else {
            if last_rx.elapsed() > idle_timeout {
                let waiting: Vec<String> = sensors
                    .iter()
                    .zip(&nodes)
                    .filter(|(_, n)| !n.done())
                    .map(|(s, n)| format!("sensor {} (at step {})", s.0.0, n.next))
                    .collect();
                return Err(NetError::Timeout(format!(
                    "nothing received for {:.1} s; still waiting for {}",
                    idle_timeout.as_secs_f64(),
                    waiting.join(", ")
                )));
            }
            continue;
        };
        if r.key.starts_with(keys::JOIN_PREFIX) {
            core.on_join(transport, &session, &r.key, &r.payload)?;
            continue;
        }
        if r.key.starts_with(keys::SCAN_PREFIX) {
            // a wall-clock node that did not say its mode when it joined
            if let Some(id) = sensor_of_key(&r.key) {
                core.on_join(transport, &session, &keys::join(id), b"join wall")?;
            }
            continue;
        }
        if r.key.starts_with(keys::BYE_PREFIX) {
            note_bye(&r.key, &core.ids, &mut byes);
            continue;
        }
        if !(r.key.starts_with(keys::SIM_PREFIX) || r.key.starts_with(keys::END_PREFIX)) {
            continue;
        }
        last_rx = Instant::now();
        let Ok(m) = SimMessage::decode(&r.payload) else {
            core.run.rejected += 1;
            continue;
        };
        let sensor = match &m {
            SimMessage::Step(s) => s.sensor,
            SimMessage::End(e) => e.sensor,
        };
        let Some(k) = core
            .index(sensor)
            .filter(|_| sensor_of_key(&r.key) == Some(sensor))
        else {
            core.run.rejected += 1;
            continue;
        };
        core.heard(k);
        let n = &mut nodes[k];
        match m {
            SimMessage::End(e) => {
                core.run.sensors[k].ended = true;
                if e.t_end != t_end {
                    return Err(NetError::Config(format!(
                        "node {} simulates a scenario ending at {} µs, the server one ending at {} µs: \
                         run node and server with the same --band/--people/--frames/--seed",
                        sensor.0, e.t_end.0, t_end.0
                    )));
                }
                n.end_steps = Some(e.steps);
                crate::node::trace(&format!(
                    "server: end of sensor {} ({} steps, {} received)",
                    sensor.0, e.steps, n.next
                ));
                transport.publish(&keys::end_ack(sensor), b"ok")?;
            }
            SimMessage::Step(s) => {
                if s.t_end != t_end {
                    return Err(NetError::Config(format!(
                        "node {} simulates a scenario ending at {} µs, the server one ending at {} µs",
                        sensor.0, s.t_end.0, t_end.0
                    )));
                }
                if s.step < n.next || n.buf.contains_key(&s.step) {
                    core.run.rejected += 1;
                    continue;
                }
                n.buf.insert(s.step, s);
                core.run.sensors[k].accepted += 1;
                while let Some(s) = n.buf.remove(&n.next) {
                    if n.progress.is_some_and(|p| s.t_true.0 <= p) {
                        return Err(NetError::Config(format!(
                            "node {}: capture times go backwards at step {}",
                            sensor.0, s.step
                        )));
                    }
                    n.progress = Some(s.t_true.0);
                    n.next += 1;
                    ready.insert((s.t_true.0, k), s);
                }
            }
        }
    }
}

/// Options of the wall-clock server.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallServerOptions {
    /// Stop after this long (`None`: until every sensor has sent its end marker).
    pub max_duration: Option<Duration>,
    /// Stop when nothing has arrived for this long after the first scan.
    pub idle_timeout: Duration,
    /// How often the assembler is polled.
    pub poll_interval: Duration,
}

impl Default for WallServerOptions {
    fn default() -> Self {
        Self {
            max_duration: None,
            idle_timeout: Duration::from_secs(10),
            poll_interval: Duration::from_millis(5),
        }
    }
}

/// Wall-clock server: server time is µs since it started (the nodes synchronise to it).
pub fn run_wall_server(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    opts: &WallServerOptions,
) -> Result<ServerRun, NetError> {
    run_wall_server_until(transport, sensors, cfg, opts, &AtomicBool::new(false))
}

/// How long a wall-clock server told to stop (or past `max_duration`) keeps reading the
/// messages already queued before it closes its frames: scans that arrived before the stop are
/// fused, and nodes that keep sending cannot hold it longer than this.
pub const STOP_DRAIN: Duration = Duration::from_secs(2);

/// [`run_wall_server`] that also stops once `stop` is set (a Ctrl-C / SIGTERM handler's flag):
/// it then fuses the messages already queued (for at most [`STOP_DRAIN`]), closes the frames it
/// can, tells the nodes with the end notice, and returns what it has with `interrupted` set.
pub fn run_wall_server_until(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    opts: &WallServerOptions,
    stop: &AtomicBool,
) -> Result<ServerRun, NetError> {
    run_wall_server_observed(transport, sensors, cfg, opts, stop, &mut |_| Ok(()))
}

/// [`run_wall_server_until`] that shows every closed frame to `observer`: `lidar-server
/// --mcap` records through it, `--ros2` republishes the tracks as ROS 2 messages.
pub fn run_wall_server_observed(
    transport: &dyn Transport,
    sensors: &[SensorSpec],
    cfg: &LidarPeopleConfig,
    opts: &WallServerOptions,
    stop: &AtomicBool,
    observer: &mut FrameObserver<'_>,
) -> Result<ServerRun, NetError> {
    let mut core = Core::new(sensors, cfg)?;
    let mut sub = transport.subscribe(keys::NODE_ALL)?;
    let mut session = Session::new(
        transport,
        crate::session::new_session_id(),
        crate::session::ClockKind::Wall,
    )?;
    core.run.session = session.id;
    let start = Instant::now();
    core.epoch_unix_us = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .ok()
        .and_then(|d| i64::try_from(d.as_micros()).ok());
    let now = || TimeUs(start.elapsed().as_micros() as i64);
    let mut ended = vec![false; sensors.len()];
    let mut byes = vec![false; sensors.len()];
    let mut last_rx: Option<Instant> = None;
    let mut next_poll = Instant::now();
    // set once the run is told to stop: what had arrived by then is still fused
    let mut drain_until: Option<Instant> = None;
    loop {
        session.tick(transport, &mut core.run)?;
        let wait = if drain_until.is_some() {
            Duration::ZERO
        } else {
            next_poll.saturating_duration_since(Instant::now())
        };
        let received = sub.recv_timeout(wait)?;
        let queue_empty = received.is_none();
        if let Some(r) = received {
            let arrival = now();
            let sensor = sensor_of_key(&r.key);
            let k = sensor.and_then(|id| core.index(id));
            if r.key.starts_with(keys::JOIN_PREFIX) {
                core.on_join(transport, &session, &r.key, &r.payload)?;
            } else if r.key.starts_with(keys::BYE_PREFIX) {
                note_bye(&r.key, &core.ids, &mut byes);
            } else if r.key.starts_with(keys::SCAN_PREFIX) {
                last_rx = Some(Instant::now());
                let d = core
                    .server
                    .fusion
                    .assembler
                    .on_datagram(&r.payload, arrival);
                if let Some(k) = k {
                    core.heard(k);
                    if d == crate::proto::Disposition::Accepted {
                        core.run.sensors[k].accepted += 1;
                    }
                }
            } else if r.key.starts_with(keys::SIM_PREFIX) {
                // a virtual-time node that did not say its mode when it joined
                core.run.rejected += 1;
                if let Some(id) = sensor {
                    core.on_join(transport, &session, &keys::join(id), b"join virtual")?;
                }
            } else if r.key.starts_with(keys::SYNC_REQUEST_PREFIX) {
                if let Ok(m) = Message::decode(&r.payload)
                    && m.header.kind == Kind::SyncRequest
                    && Some(m.header.sensor) == sensor
                {
                    if let Some(k) = k {
                        core.heard(k);
                    }
                    let t3 = now();
                    let reply = Message {
                        header: Header {
                            kind: Kind::SyncReply,
                            // the session, so that a node tells its server's replies from
                            // another's (crate::session)
                            t_capture: TimeUs(session.id as i64),
                            t_send: t3,
                            flags: 0,
                            ..m.header
                        },
                        payload: Payload::SyncReply {
                            t1: m.header.t_send.0,
                            t2: arrival.0,
                            t3: t3.0,
                        },
                    };
                    transport.publish(&keys::sync_reply(m.header.sensor), &reply.encode()?)?;
                    core.run.sync_replies += 1;
                } else {
                    core.run.rejected += 1;
                }
            } else if r.key.starts_with(keys::END_PREFIX) {
                match SimMessage::decode(&r.payload) {
                    Ok(SimMessage::End(e)) if Some(e.sensor) == sensor => {
                        if let Some(k) = core.index(e.sensor) {
                            ended[k] = true;
                            core.run.sensors[k].ended = true;
                            core.heard(k);
                        }
                        transport.publish(&keys::end_ack(e.sensor), b"ok")?;
                    }
                    _ => core.run.rejected += 1,
                }
            }
        }
        if Instant::now() >= next_poll {
            core.poll(transport, now(), observer)?;
            next_poll = Instant::now() + opts.poll_interval;
        }
        let all_ended = ended.iter().all(|&e| e);
        let idle = last_rx.is_some_and(|t| t.elapsed() > opts.idle_timeout);
        let over = opts.max_duration.is_some_and(|d| start.elapsed() > d);
        let interrupted = stop.load(Ordering::Relaxed);
        if (over || interrupted) && !all_ended && !idle {
            // drain the messages already queued (scans sent before the stop), for at most
            // STOP_DRAIN while the nodes keep sending
            let until = *drain_until.get_or_insert_with(|| Instant::now() + STOP_DRAIN);
            if !queue_empty && Instant::now() < until {
                continue;
            }
        }
        if all_ended || idle || over || interrupted {
            // every frame whose deadline has passed by then, plus the last window
            let fc = cfg.tau_sync_s + cfg.l_max_s + cfg.frame_period_s;
            let flush = TimeUs(now().0 + (fc * 1e6).round() as i64);
            core.poll(transport, flush, observer)?;
            if all_ended {
                let ids = core.ids.clone();
                linger(transport, sub.as_mut(), &ids, &mut byes)?;
            } else {
                // the nodes still running stop now instead of waiting for acknowledgements
                core.run.interrupted = interrupted;
                session.end_notice(transport)?;
            }
            return Ok(core.finish());
        }
    }
}
