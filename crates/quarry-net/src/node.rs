//! `lidar-node`: one scanner client. It reads a [`ScanSource`], runs the scanner's chi-square
//! background model and publishes the dynamic points of every scan.
//!
//! Two clock modes:
//! - **virtual time** ([`run_sim_node`]): the source is scanner K of the simulated room; the
//!   node publishes, per scan, a [`SimStep`] with the §7.1 datagrams and the *simulated* arrival
//!   times of each delivered copy (the room's network model: delay, loss, duplicates) as fast as
//!   the transport takes them. The server replays the arrivals in virtual time, so a networked
//!   run is bit-identical to the in-process one of the same seed.
//! - **wall clock** ([`run_wall_node`]): scans are paced in real time, stamped with the node's
//!   clock synchronised to the server's by the §7.3 exchange (SyncRequest/SyncReply over the
//!   transport), and published as plain §7.1 datagrams; the real network's delays, losses and
//!   duplicates are what the server's frame assembler handles.

use crate::NetError;
#[cfg(feature = "sim")]
use crate::envelope::SimStep;
use crate::envelope::{EndOfStream, SimMessage};
use crate::fusion::encode_dynamic;
use crate::proto::wire::{Header, Hello, Kind, Message, Payload};
use crate::proto::{ClockSync, SyncMode};
use crate::session::{ClockKind, Welcome};
use crate::transport::{Subscription, Transport, keys};
use quarry_core::{PolarScan, ScanGeometry, SensorId, TimeUs};
use quarry_data::scans_csv::ScanCsvReader;
#[cfg(feature = "sim")]
use quarry_sim::lidar_room::{RoomEvent, Runner, Scenario};
use quarry_trackers::TrackerConfig;
use quarry_trackers::lidar_people::{ClientPipeline, LidarPeopleConfig, background_of};
use serde::Serialize;
use std::io::Read;
use std::time::{Duration, Instant};

/// A source of scans for a node (spec §7.3: `sim` or `replay`).
pub trait ScanSource {
    /// The scanner's id.
    fn sensor(&self) -> SensorId;
    /// Its beam geometry.
    fn geometry(&self) -> ScanGeometry;
    /// The next scan with its source time (the pacing clock), or `None` at the end.
    fn next_scan(&mut self) -> Result<Option<(TimeUs, PolarScan)>, NetError>;
    /// A live source (a sensor topic) delivers scans as they happen: the node publishes each
    /// as soon as it has it instead of pacing by the source clock. Recordings are not live.
    fn live(&self) -> bool {
        false
    }
    /// How long before now the scan with source time `t_src` (just returned by
    /// [`next_scan`](Self::next_scan)) was captured, when the source can tell: a sensor topic
    /// stamped with this machine's wall clock. The node then stamps the scan at its capture
    /// instead of at the moment it handles it, so a node that falls behind (a busy machine)
    /// delays its scans instead of shifting them out of the server's ±τ_sync frame windows.
    /// `None` (the default): stamped when handled.
    fn capture_age(&self, t_src: TimeUs) -> Option<Duration> {
        let _ = t_src;
        None
    }
}

/// Scanner `k` of a simulated room: its scans with their simulated capture times (feature
/// `sim`).
#[cfg(feature = "sim")]
pub struct SimSource {
    runner: Runner,
    k: usize,
    id: SensorId,
    geometry: ScanGeometry,
}

#[cfg(feature = "sim")]
impl SimSource {
    /// Scanner `k` (0-based) of `scenario`.
    pub fn new(scenario: Scenario, k: usize) -> Result<Self, NetError> {
        let s = scenario.scanners.get(k).ok_or_else(|| {
            NetError::Config(format!(
                "scanner {k} does not exist (the scenario has {})",
                scenario.scanners.len()
            ))
        })?;
        let (id, geometry) = (s.id, s.geometry);
        let runner = Runner::new(scenario).map_err(|e| NetError::Config(e.to_string()))?;
        Ok(Self {
            runner,
            k,
            id,
            geometry,
        })
    }

    /// The next captured scan of this scanner, with its simulated arrivals.
    pub fn next_captured(
        &mut self,
    ) -> Result<Option<quarry_sim::lidar_room::CapturedScan>, NetError> {
        loop {
            match self
                .runner
                .next_event()
                .map_err(|e| NetError::Config(e.to_string()))?
            {
                None => return Ok(None),
                Some(RoomEvent::Scan(cs)) if cs.scanner == self.k => return Ok(Some(cs)),
                Some(_) => {}
            }
        }
    }
}

#[cfg(feature = "sim")]
impl ScanSource for SimSource {
    fn sensor(&self) -> SensorId {
        self.id
    }
    fn geometry(&self) -> ScanGeometry {
        self.geometry
    }
    fn next_scan(&mut self) -> Result<Option<(TimeUs, PolarScan)>, NetError> {
        Ok(self.next_captured()?.map(|cs| (cs.t_true, cs.scan)))
    }
}

/// A recorded scan CSV (`stamp_s,r0..r{N-1}`, see quarry-data's `scans_csv`), replayed at the
/// pace of its stamps. Malformed rows are skipped and counted as the reader's options say.
pub struct CsvSource<R: Read> {
    reader: ScanCsvReader<R>,
    id: SensorId,
    geometry: ScanGeometry,
}

impl<R: Read> CsvSource<R> {
    /// A source over `reader` (whose options carry the sensor id).
    pub fn new(reader: ScanCsvReader<R>, id: SensorId, geometry: ScanGeometry) -> Self {
        Self {
            reader,
            id,
            geometry,
        }
    }
    /// The reader's counters (rows, skipped rows, invalid beams).
    pub fn stats(&self) -> quarry_data::scans_csv::ScanCsvStats {
        self.reader.stats()
    }
}

impl<R: Read> ScanSource for CsvSource<R> {
    fn sensor(&self) -> SensorId {
        self.id
    }
    fn geometry(&self) -> ScanGeometry {
        self.geometry
    }
    fn next_scan(&mut self) -> Result<Option<(TimeUs, PolarScan)>, NetError> {
        match self.reader.next() {
            None => Ok(None),
            Some(Err(e)) => Err(NetError::Io(e.to_string())),
            Some(Ok(s)) => Ok(Some((s.t, s))),
        }
    }
}

/// What a node did.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct NodeSummary {
    /// Sensor id.
    pub sensor: u16,
    /// Scans read from the source.
    pub scans: u64,
    /// §7.1 datagrams published (wall mode), or carried in steps (virtual time).
    pub datagrams: u64,
    /// Dynamic points published.
    pub dynamic_points: u64,
    /// Virtual time: scans the simulated network lost (no arrival).
    pub lost: u64,
    /// Virtual time: scans the simulated network duplicated.
    pub duplicated: u64,
    /// Wall clock: scans stamped without `CLOCK_SYNCED` (the server drops them).
    pub unsynced: u64,
    /// Wall clock: sync replies received.
    pub sync_replies: u64,
    /// Wall clock: the last clock offset estimate, µs (server − node).
    pub offset_us: Option<f64>,
    /// Background subtraction time per scan, ms.
    pub client_ms_per_scan: f64,
    /// Wall clock: times the node re-joined a restarted server.
    pub rejoins: u64,
    /// Wall clock: sync replies of another server (another session) ignored.
    pub foreign_sync_replies: u64,
    /// Wall clock: jumps of the source's stamps that re-anchored the pacing.
    pub source_jumps: u64,
}

/// The reason of the first queued refusal addressed to a node on the clock `mode`, if any
/// (refusals of another mode's request for the same sensor id are dropped).
fn refusal(refused: &mut dyn Subscription, mode: ClockKind) -> Result<Option<String>, NetError> {
    while let Some(r) = refused.recv_timeout(Duration::ZERO)? {
        let r = crate::session::Refusal::decode(&r.payload);
        if r.applies_to(mode) {
            return Ok(Some(r.reason));
        }
        if let Some(other) = r.to {
            trace(&format!(
                "node: ignored a refusal of a {other}-clock request for this sensor id"
            ));
        }
    }
    Ok(None)
}

/// Joins the server: publishes a join request (with this node's clock `mode`) every 100 ms
/// until the server's welcome arrives (so the route from this node to the server's
/// subscriptions exists before any data is sent). Returns the welcome (the server's session).
/// A refusal (an id the server does not know, the other clock mode) is
/// [`NetError::Refused`] with the server's reason, at once.
pub fn wait_for_server(
    transport: &dyn Transport,
    id: SensorId,
    mode: ClockKind,
    timeout: Duration,
) -> Result<Welcome, NetError> {
    let mut sub = transport.subscribe(&keys::welcome(id))?;
    let mut refused = transport.subscribe(&keys::refuse(id))?;
    let t0 = Instant::now();
    let join = crate::session::encode_join(mode);
    while t0.elapsed() < timeout {
        transport.publish(&keys::join(id), &join)?;
        if let Some(r) = refusal(refused.as_mut(), mode)? {
            return Err(NetError::Refused(r));
        }
        if let Some(r) = sub.recv_timeout(Duration::from_millis(100))? {
            // a server of an older version answers a bare "welcome": its own mode, session 0
            let w = Welcome::decode(&r.payload).unwrap_or(Welcome { mode, session: 0 });
            if w.mode != mode {
                return Err(NetError::Refused(format!(
                    "the server runs on the {} clock, this node on the {} clock: start both with the same --clock",
                    w.mode, mode
                )));
            }
            return Ok(w);
        }
    }
    if let Some(r) = refusal(refused.as_mut(), mode)? {
        return Err(NetError::Refused(r));
    }
    Err(NetError::Timeout(format!(
        "the server did not answer the join of sensor {} within {:.1} s",
        id.0,
        timeout.as_secs_f64()
    )))
}

/// A node's watch on its server: the beacons (is it alive; has another server taken its
/// place?) and the end notice.
struct ServerWatch {
    ready: Box<dyn Subscription>,
    end: Box<dyn Subscription>,
    session: u64,
    last_mine: Instant,
    /// The newest beacon of another server of this node's mode.
    other: Option<(u64, Instant)>,
    mode: ClockKind,
}

/// What the watch saw.
enum Watch {
    /// Nothing new.
    Fine,
    /// The server stopped early (its end notice).
    Ended,
    /// The joined server has been silent for over a second while another one of this mode
    /// beacons: it was restarted (or replaced); re-join it.
    Replaced,
}

impl ServerWatch {
    fn new(transport: &dyn Transport, mode: ClockKind) -> Result<Self, NetError> {
        Ok(Self {
            ready: transport.subscribe(keys::SERVER_READY)?,
            end: transport.subscribe(keys::SERVER_END)?,
            session: 0,
            last_mine: Instant::now(),
            other: None,
            mode,
        })
    }

    fn joined(&mut self, w: Welcome) {
        self.session = w.session;
        self.last_mine = Instant::now();
        self.other = None;
    }

    fn poll(&mut self) -> Result<Watch, NetError> {
        while let Some(r) = self.end.recv_timeout(Duration::ZERO)? {
            if crate::session::decode_end(&r.payload) == Some(self.session) {
                return Ok(Watch::Ended);
            }
        }
        while let Some(r) = self.ready.recv_timeout(Duration::ZERO)? {
            let Some(b) = crate::session::Beacon::decode(&r.payload) else {
                continue;
            };
            if b.session == self.session {
                self.last_mine = Instant::now();
            } else if b.mode == self.mode {
                self.other = Some((b.session, Instant::now()));
            }
        }
        let other_alive = self
            .other
            .is_some_and(|(_, t)| t.elapsed() < Duration::from_millis(500));
        if self.session != 0 && other_alive && self.last_mine.elapsed() > Duration::from_secs(1) {
            return Ok(Watch::Replaced);
        }
        Ok(Watch::Fine)
    }

    fn silent_for(&self) -> Duration {
        self.last_mine.elapsed()
    }
}

/// Publishes the end marker until the server acknowledges it on `ack` (every 200 ms, at most
/// `timeout`), then confirms with a bye. `ack` is declared before the node joins, so it exists
/// at the server well before the first acknowledgement; the exchange is idempotent on both
/// sides (the server re-acknowledges every end marker it receives and lingers until it has the
/// bye or its linger time is over).
fn finish(
    transport: &dyn Transport,
    ack: &mut dyn Subscription,
    id: SensorId,
    end: &SimMessage,
    timeout: Duration,
) -> Result<(), NetError> {
    let bytes = end.encode()?;
    let t0 = Instant::now();
    let mut sent = 0u32;
    while t0.elapsed() < timeout {
        transport.publish(&keys::end(id), &bytes)?;
        sent += 1;
        if ack.recv_timeout(Duration::from_millis(200))?.is_some() {
            trace(&format!(
                "node {}: end acknowledged after {sent} end marker(s)",
                id.0
            ));
            transport.publish(&keys::bye(id), b"bye")?;
            return Ok(());
        }
    }
    Err(NetError::Timeout(format!(
        "the server did not acknowledge the end of sensor {} within {:.1} s ({sent} end markers sent)",
        id.0,
        timeout.as_secs_f64()
    )))
}

/// Writes `msg` to stderr when `QUARRY_NET_TRACE` is set (protocol tracing for debugging a
/// deployment; off by default).
pub(crate) fn trace(msg: &str) {
    if std::env::var_os("QUARRY_NET_TRACE").is_some() {
        eprintln!("[quarry-net {:.3}] {msg}", trace_clock());
    }
}

fn trace_clock() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64() % 1000.0)
}

/// Virtual-time node: scanner `k` of `scenario`, background model of `cfg`. Publishes one
/// [`SimStep`] per captured scan and an [`EndOfStream`]; waits up to `wait_server` for the
/// server's beacon first (feature `sim`).
#[cfg(feature = "sim")]
pub fn run_sim_node(
    transport: &dyn Transport,
    scenario: Scenario,
    k: usize,
    cfg: &LidarPeopleConfig,
    wait_server: Duration,
) -> Result<NodeSummary, NetError> {
    cfg.validate()?; // the node's entry point: no tracker is built here to validate it
    let t_end = TimeUs((scenario.duration_s * 1e6).round() as i64);
    let mut src = SimSource::new(scenario, k)?;
    let id = src.sensor();
    let mut client = ClientPipeline::new(id, background_of(cfg, &src.geometry())?);
    let mut ack = transport.subscribe(&keys::end_ack(id))?;
    let mut watch = ServerWatch::new(transport, ClockKind::Virtual)?;
    watch.joined(wait_for_server(
        transport,
        id,
        ClockKind::Virtual,
        wait_server,
    )?);
    trace(&format!("node {}: joined", id.0));
    let key = keys::sim(id);
    let mut sum = NodeSummary {
        sensor: id.0,
        ..NodeSummary::default()
    };
    let mut client_s = 0.0;
    let mut step = 0u32;
    while let Some(cs) = src.next_captured()? {
        let t0 = Instant::now();
        let msg = client.on_scan(&cs.scan, cs.clock_synced)?;
        client_s += t0.elapsed().as_secs_f64();
        // the same bytes the in-process fusion builds (t_send = the capture stamp)
        let datagrams = encode_dynamic(&msg, msg.t)?;
        sum.scans += 1;
        sum.datagrams += datagrams.len() as u64;
        sum.dynamic_points += msg.beams.len() as u64;
        sum.lost += u64::from(cs.arrivals.is_empty());
        sum.duplicated += u64::from(cs.arrivals.len() > 1);
        let m = SimMessage::Step(SimStep {
            sensor: id,
            step,
            t_true: cs.t_true,
            t_end,
            arrivals: cs.arrivals,
            datagrams,
        });
        transport.publish(&key, &m.encode()?)?;
        step += 1;
        if matches!(watch.poll()?, Watch::Ended) {
            return Err(server_ended(id, sum.scans));
        }
    }
    let end = SimMessage::End(EndOfStream {
        sensor: id,
        steps: step,
        t_end,
    });
    trace(&format!("node {}: {step} steps published", id.0));
    finish(transport, ack.as_mut(), id, &end, wait_server)?;
    sum.client_ms_per_scan = 1e3 * client_s / (sum.scans.max(1) as f64);
    Ok(sum)
}

/// Options of a wall-clock node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WallNodeOptions {
    /// Replay speed (1 = real time): source time is divided by it when pacing.
    pub speed: f64,
    /// Stop after this many scans (`None` = the whole source).
    pub max_scans: Option<u64>,
    /// How long to wait for the server's beacon.
    pub wait_server: Duration,
    /// How long to run sync exchanges before the first scan (scans before the first estimate
    /// go out without `CLOCK_SYNCED` and the server drops them).
    pub sync_warmup: Duration,
    /// Synchronisation mode (`Ntp` by default; `None` = send raw local time unflagged).
    pub sync: SyncMode,
    /// Background window length `m` reported in the Hello.
    pub window_m: u16,
}

impl Default for WallNodeOptions {
    fn default() -> Self {
        Self {
            speed: 1.0,
            max_scans: None,
            wait_server: Duration::from_secs(30),
            sync_warmup: Duration::from_millis(1500),
            sync: SyncMode::Ntp,
            window_m: 40,
        }
    }
}

/// The node's local clock: µs since the UNIX epoch at start plus monotonic time since.
struct LocalClock {
    t0: Instant,
    base_us: i64,
}

impl LocalClock {
    fn new() -> Self {
        let base_us = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_micros() as i64);
        Self {
            t0: Instant::now(),
            base_us,
        }
    }
    fn now(&self) -> TimeUs {
        TimeUs(self.base_us + self.t0.elapsed().as_micros() as i64)
    }
}

struct Syncer {
    sync: ClockSync,
    /// The joined server's session: replies of any other server are ignored.
    session: u64,
    /// Replies of other servers ignored.
    foreign: u64,
    sub: Box<dyn Subscription>,
    req_key: String,
    id: SensorId,
    next_req: Instant,
    seq: u32,
    replies: u64,
}

impl Syncer {
    /// Sends a request when due and files every reply waiting (at most `wait`).
    fn service(
        &mut self,
        transport: &dyn Transport,
        clock: &LocalClock,
        wait: Duration,
    ) -> Result<(), NetError> {
        if self.sync.mode() == SyncMode::None {
            return Ok(());
        }
        if Instant::now() >= self.next_req {
            let m = Message {
                header: Header {
                    kind: Kind::SyncRequest,
                    sensor: self.id,
                    seq: self.seq,
                    part: 0,
                    parts: 1,
                    flags: 0,
                    t_capture: TimeUs(0),
                    t_send: clock.now(),
                },
                payload: Payload::Empty,
            };
            transport.publish(&self.req_key, &m.encode()?)?;
            self.seq = self.seq.wrapping_add(1);
            // 1 Hz as the spec says; faster (5 Hz) until the first estimate exists
            let period = if self.sync.estimate().is_some() {
                1000
            } else {
                200
            };
            self.next_req = Instant::now() + Duration::from_millis(period);
        }
        let mut w = wait;
        while let Some(r) = self.sub.recv_timeout(w)? {
            w = Duration::ZERO;
            let t4 = clock.now();
            let Ok(m) = Message::decode(&r.payload) else {
                continue;
            };
            // session 0: a server of an older version, which leaves t_capture zero
            if self.session != 0 && m.header.t_capture.0 as u64 != self.session {
                self.foreign += 1;
                continue;
            }
            if let Payload::SyncReply { t1, t2, t3 } = m.payload
                && m.header.sensor == self.id
                && self
                    .sync
                    .on_sync_reply(TimeUs(t1), TimeUs(t2), TimeUs(t3), t4)
                    .is_ok()
            {
                self.replies += 1;
            }
        }
        Ok(())
    }
}

/// The longest gap between two scans' source stamps that a wall-clock node waits for (a
/// larger jump, or a stamp going backwards, re-anchors the pacing: counted in
/// [`NodeSummary::source_jumps`]).
pub const MAX_SOURCE_GAP: Duration = Duration::from_secs(10);

/// The node's Hello (its geometry, spec §7.1).
fn hello(id: SensorId, g: &ScanGeometry, t_send: TimeUs, window_m: u16) -> Message {
    Message {
        header: Header {
            kind: Kind::Hello,
            sensor: id,
            seq: 0,
            part: 0,
            parts: 1,
            flags: 0,
            t_capture: TimeUs(0),
            t_send,
        },
        payload: Payload::Hello(Hello {
            n_beams: g.n_beams as u16,
            front_step: (-g.angle_min / g.angle_increment)
                .round()
                .clamp(0.0, 65535.0) as u16,
            slit_division: (std::f64::consts::TAU / g.angle_increment)
                .round()
                .clamp(0.0, 65535.0) as u16,
            range_min_mm: (g.range_min * 1e3).round().clamp(0.0, 65535.0) as u16,
            range_max_mm: (g.range_max * 1e3).round().clamp(0.0, 65535.0) as u16,
            scan_period_us: (g.scan_period * 1e6).round().clamp(0.0, 4e9) as u32,
            window_m,
        }),
    }
}

/// Runs sync exchanges for `warmup` before scans go out.
fn warm_up(
    syncer: &mut Syncer,
    transport: &dyn Transport,
    clock: &LocalClock,
    warmup: Duration,
) -> Result<(), NetError> {
    let warm = Instant::now();
    while warm.elapsed() < warmup {
        syncer.service(transport, clock, Duration::from_millis(20))?;
        // apply the estimate now, so that its first step (which clears CLOCK_SYNCED for one
        // stamp) does not fall on a scan
        let _ = syncer.sync.stamp(clock.now());
    }
    Ok(())
}

/// The error of a node whose server stopped first.
fn server_ended(id: SensorId, scans: u64) -> NetError {
    NetError::ServerEnded(format!(
        "the server stopped its run (interrupted, or its --duration elapsed) while sensor {} was still sending, after {scans} scans",
        id.0
    ))
}

/// Wall-clock node over any [`ScanSource`]: Hello, clock sync warm-up, then every scan paced
/// by its source time, stamped with the synchronised clock (at its capture when the source
/// knows it, [`ScanSource::capture_age`]; else when the node handles it) and published as §7.1
/// datagrams.
pub fn run_wall_node(
    transport: &dyn Transport,
    source: &mut dyn ScanSource,
    cfg: &LidarPeopleConfig,
    opts: &WallNodeOptions,
) -> Result<NodeSummary, NetError> {
    cfg.validate()?; // the node's entry point: no tracker is built here to validate it
    if !(opts.speed.is_finite() && opts.speed > 0.0) {
        return Err(NetError::Config("speed must be finite and positive".into()));
    }
    let id = source.sensor();
    let g = source.geometry();
    let mut client = ClientPipeline::new(id, background_of(cfg, &g)?);
    let clock = LocalClock::new();
    let mut syncer = Syncer {
        sync: ClockSync::new(opts.sync),
        session: 0,
        foreign: 0,
        sub: transport.subscribe(&keys::sync_reply(id))?,
        req_key: keys::sync_request(id),
        id,
        next_req: Instant::now(),
        seq: 0,
        replies: 0,
    };
    let mut ack = transport.subscribe(&keys::end_ack(id))?;
    let mut watch = ServerWatch::new(transport, ClockKind::Wall)?;
    let w = wait_for_server(transport, id, ClockKind::Wall, opts.wait_server)?;
    watch.joined(w);
    syncer.session = w.session;
    trace(&format!("node {}: joined session {:016x}", id.0, w.session));
    let key = keys::scan(id);
    transport.publish(&key, &hello(id, &g, clock.now(), opts.window_m).encode()?)?;
    warm_up(&mut syncer, transport, &clock, opts.sync_warmup)?;
    let mut sum = NodeSummary {
        sensor: id.0,
        ..NodeSummary::default()
    };
    let mut client_s = 0.0;
    let mut first: Option<(TimeUs, Instant)> = None;
    let mut seq = 0u32;
    let mut last_stamp = TimeUs(0);
    let mut last_capture = TimeUs(i64::MIN);
    while opts.max_scans.is_none_or(|m| sum.scans < m) {
        match watch.poll()? {
            Watch::Fine => {}
            Watch::Ended => return Err(server_ended(id, sum.scans)),
            Watch::Replaced => {
                // the server restarted: its clock and session are new. Join it, start the
                // clock synchronisation afresh, say Hello (its assembler starts this sensor's
                // sequence state anew) and pace from the next scan on.
                trace(&format!(
                    "node {}: the server was replaced; re-joining",
                    id.0
                ));
                let w = wait_for_server(transport, id, ClockKind::Wall, opts.wait_server)?;
                watch.joined(w);
                syncer.session = w.session;
                syncer.sync = ClockSync::new(opts.sync);
                syncer.next_req = Instant::now();
                transport.publish(&key, &hello(id, &g, clock.now(), opts.window_m).encode()?)?;
                warm_up(&mut syncer, transport, &clock, opts.sync_warmup)?;
                first = None;
                sum.rejoins += 1;
            }
        }
        let Some((t_src, mut scan)) = source.next_scan()? else {
            break;
        };
        // pace by the source clock (a live source is paced by its sensor already); a jump of
        // the source's stamps (forwards by more than MAX_SOURCE_GAP, or backwards) re-anchors
        // the pacing instead of sleeping for it
        if source.live() {
            first = Some((t_src, Instant::now()));
        }
        let (s0, w0) = *first.get_or_insert((t_src, Instant::now()));
        let ahead = t_src.secs_since(s0) / opts.speed;
        let since = w0.elapsed().as_secs_f64();
        if !(ahead >= 0.0 && ahead - since <= MAX_SOURCE_GAP.as_secs_f64()) {
            sum.source_jumps += 1;
            first = Some((t_src, Instant::now()));
        }
        let (s0, w0) = first.unwrap_or((t_src, Instant::now()));
        let due = w0 + Duration::from_secs_f64((t_src.secs_since(s0) / opts.speed).max(0.0));
        loop {
            let left = due.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            syncer.service(transport, &clock, left.min(Duration::from_millis(20)))?;
        }
        // the background model runs on the node's own monotonic clock, which never jumps
        // (the synchronised clock can: a new server, a sync step); the message carries the
        // synchronised stamp
        // (a source that knows when the scan was captured moves the stamp back to it; capture
        // times are increasing, the max guards a clock that stepped)
        let now = clock.now();
        let capture = match source.capture_age(t_src) {
            Some(age) => TimeUs(now.0.saturating_sub(age.as_micros() as i64)).max(last_capture),
            None => now,
        };
        last_capture = capture;
        scan.t = capture;
        scan.seq = seq;
        scan.sensor = id;
        seq = seq.wrapping_add(1);
        let t0 = Instant::now();
        let (stamp, synced) = syncer.sync.stamp(capture);
        let mut msg = client.on_scan(&scan, synced)?;
        msg.t = stamp;
        client_s += t0.elapsed().as_secs_f64();
        // the send time on the same synchronised clock, without stamping a later local time
        // (the synchronised stamps never go backwards, and the next capture may be earlier)
        let t_send = TimeUs(stamp.0.saturating_add(clock.now().0 - capture.0));
        for d in encode_dynamic(&msg, t_send)? {
            transport.publish(&key, &d)?;
            sum.datagrams += 1;
        }
        sum.scans += 1;
        sum.unsynced += u64::from(!synced);
        sum.dynamic_points += msg.beams.len() as u64;
        last_stamp = stamp;
        syncer.service(transport, &clock, Duration::ZERO)?;
    }
    let end = SimMessage::End(EndOfStream {
        sensor: id,
        steps: u32::try_from(sum.scans).unwrap_or(u32::MAX),
        t_end: last_stamp,
    });
    trace(&format!("node {}: {} scans published", id.0, sum.scans));
    finish(transport, ack.as_mut(), id, &end, opts.wait_server).map_err(|e| match e {
        NetError::Timeout(m) => NetError::Timeout(format!(
            "{m} (the server's last beacon was {:.1} s ago)",
            watch.silent_for().as_secs_f64()
        )),
        e => e,
    })?;
    sum.foreign_sync_replies = syncer.foreign;
    sum.sync_replies = syncer.replies;
    sum.offset_us = syncer.sync.applied_offset();
    sum.client_ms_per_scan = 1e3 * client_s / (sum.scans.max(1) as f64);
    Ok(sum)
}
