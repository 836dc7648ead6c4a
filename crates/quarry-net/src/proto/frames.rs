//! Server-side frame assembly (spec 003 §2.4, §7.2), sans-IO.
//!
//! Scans arrive as wire datagrams ([`FrameAssembler::on_datagram`]) in any order, duplicated,
//! late or not at all; [`FrameAssembler::poll`] closes fused frames on the grid
//! `t_f = t₀ + f·T_F` strictly in order. Frame f takes from each sensor the scan whose
//! synchronised capture time τ is closest to `t_f` within `τ_sync` (ties to the earlier scan);
//! its points are transformed to the world frame with the sensor's pose and stored sorted by
//! (sensor, beam), so a frame does not depend on arrival order.
//!
//! Release (watermark) rule: frame f closes at the first `poll(now)` where either (i) every live
//! sensor has delivered a complete scan with `τ ≥ t_f + τ_sync` and every sequence number between
//! its last consumed scan and that one has arrived complete, or (ii) `now ≥ t_f + τ_sync + L_max`.
//! Choices where the spec is silent: rule (i) only counts a sensor once it has been heard for
//! `L_max` (so a scan overtaken by a later one at start-up still makes its frame); a scan still
//! incomplete when its frame closes is used as is with the `partial` bit, but an incomplete scan
//! never allows early release (so partial/complete does not depend on arrival order); counters
//! are kept in [`FusionStats`], outside the frames; `t₀` is the first multiple of `T_F` at or
//! after the start time.

use std::collections::{BTreeMap, BTreeSet};

use quarry_core::{CoreError, Point2, Pose2, ScanGeometry, SensorId, TimeUs};

use super::wire::{FLAG_CLOCK_SYNCED, Kind, Message, Payload};
type Result<T, E = CoreError> = std::result::Result<T, E>;
use quarry_cloud::scan::BeamTable;

/// One scanner known to the server.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorConfig {
    /// Its id (as in the wire header).
    pub id: SensorId,
    /// Its pose in the world frame.
    pub pose: Pose2,
    /// Its beam geometry.
    pub geometry: ScanGeometry,
}

/// Which scans a frame takes from each sensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ScansPerFrame {
    /// The one scan closest to `t_f` within `τ_sync` (default).
    #[default]
    Nearest,
    /// Every scan with τ in `(t_f − T_F/2, t_f + T_F/2]`.
    All,
}

/// Frame assembly parameters (spec 003 §3, §7.2). `Default` is the spec's values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameConfig {
    /// Frame period `T_F`, µs (50 ms).
    pub period_us: i64,
    /// Selection tolerance `τ_sync`, µs (12.5 ms).
    pub tau_sync_us: i64,
    /// Maximum accepted latency `L_max`, µs (100 ms).
    pub max_latency_us: i64,
    /// Messages captured more than this after their arrival are "future", µs (200 ms).
    pub future_tolerance_us: i64,
    /// A sensor silent for this long is offline, µs (1 s).
    pub liveness_us: i64,
    /// Scan selection.
    pub scans_per_frame: ScansPerFrame,
    /// Accept messages without `CLOCK_SYNCED` (only with `sync = none`).
    pub accept_unsynced: bool,
    /// At most this many frames are closed by one `poll` (the rest on the next call), so a
    /// poll far in the future cannot emit an unbounded number of empty frames at once.
    pub max_frames_per_poll: usize,
}

impl Default for FrameConfig {
    fn default() -> Self {
        Self {
            period_us: 50_000,
            tau_sync_us: 12_500,
            max_latency_us: 100_000,
            future_tolerance_us: 200_000,
            liveness_us: 1_000_000,
            scans_per_frame: ScansPerFrame::Nearest,
            accept_unsynced: false,
            max_frames_per_poll: 100_000,
        }
    }
}

/// One point of a fused frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FramePoint {
    /// Source sensor.
    pub sensor: SensorId,
    /// Beam index.
    pub beam: u16,
    /// Capture time of its scan.
    pub t_capture: TimeUs,
    /// World-frame position.
    pub p: Point2,
}

/// A fused frame. Bit k of the masks is the k-th sensor of the configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Frame index f.
    pub index: u64,
    /// Frame time `t_f`.
    pub t: TimeUs,
    /// Points sorted by (sensor order, beam, capture time).
    pub points: Vec<FramePoint>,
    /// Sensors that contributed.
    pub present: u64,
    /// Live sensors with no scan within tolerance.
    pub missing: u64,
    /// Sensors whose selected scan was incomplete.
    pub partial: u64,
    /// No sensor contributed (the tracker skips such frames).
    pub no_data: bool,
}

/// What happened to one datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Disposition {
    /// Stored for fusion.
    Accepted,
    /// Already seen `(sensor, kind, seq, part)`.
    Duplicate,
    /// Captured at or before the watermark.
    Late,
    /// Captured more than the future tolerance after its arrival.
    Future,
    /// `CLOCK_SYNCED` clear.
    Unsynced,
    /// Sensor not in the configuration.
    UnknownSensor,
    /// Did not decode, or contradicts earlier parts of the same scan.
    Malformed,
    /// A valid message of another kind (Hello resets the sensor's sequence state).
    Other,
}

/// Counters (spec §7.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FusionStats {
    /// Scan parts accepted.
    pub accepted: u64,
    /// Duplicates dropped.
    pub dup: u64,
    /// Late messages dropped.
    pub late: u64,
    /// Future messages dropped.
    pub future: u64,
    /// Unsynchronised messages dropped.
    pub unsynced: u64,
    /// Messages from unknown sensors.
    pub unknown: u64,
    /// Undecodable or inconsistent messages.
    pub malformed: u64,
    /// Sequence numbers skipped (gaps).
    pub lost: u64,
    /// Sensor restarts (Hello, or a sequence drop of more than 1000).
    pub restarts: u64,
    /// Points with an unknown beam or invalid range (skipped).
    pub bad_points: u64,
    /// Frames closed.
    pub frames: u64,
}

#[derive(Debug, Clone)]
struct ScanEntry {
    t: TimeUs,
    parts: u8,
    got: BTreeMap<u8, Vec<(u16, u16)>>,
}

impl ScanEntry {
    fn complete(&self) -> bool {
        self.got.len() == usize::from(self.parts)
    }
}

#[derive(Debug)]
struct SensorState {
    cfg: SensorConfig,
    table: BeamTable,
    scans: BTreeMap<u32, ScanEntry>,
    seen: BTreeSet<(u32, u8)>,
    max_seq: Option<u32>,
    /// Every seq at or below `base` is consumed or given up.
    base: Option<u32>,
    complete: BTreeSet<u32>,
    first_arrival: Option<TimeUs>,
    last_heard: TimeUs,
    min_latency_us: Option<i64>,
}

impl SensorState {
    fn reset_seq(&mut self) {
        self.seen.clear();
        self.max_seq = None;
        self.base = None;
        self.complete.clear();
        self.scans.clear();
        self.first_arrival = None;
    }
}

/// The server's sans-IO frame assembler.
#[derive(Debug)]
pub struct FrameAssembler {
    cfg: FrameConfig,
    sensors: Vec<SensorState>,
    t0: i64,
    next_frame: u64,
    watermark: Option<TimeUs>,
    stats: FusionStats,
}

impl FrameAssembler {
    /// An assembler for `sensors` (at most 64; bit k of the frame masks is `sensors[k]`), whose
    /// server started at `start`.
    pub fn new(cfg: FrameConfig, sensors: &[SensorConfig], start: TimeUs) -> Result<Self> {
        if !(cfg.period_us > 0
            && cfg.tau_sync_us >= 0
            && cfg.max_latency_us >= 0
            && cfg.liveness_us > 0
            && cfg.max_frames_per_poll > 0)
        {
            return Err(CoreError::invalid(
                "frame config",
                "periods must be positive, tolerances >= 0",
            ));
        }
        if sensors.is_empty() || sensors.len() > 64 {
            return Err(CoreError::invalid("sensors", "need 1 to 64 sensors"));
        }
        let mut ids = BTreeSet::new();
        let mut states = Vec::new();
        for s in sensors {
            if !ids.insert(s.id) {
                return Err(CoreError::invalid(
                    "sensors",
                    format!("duplicate sensor id {}", s.id.0),
                ));
            }
            if !s.pose.is_finite() {
                return Err(CoreError::NonFinite {
                    what: "sensor pose",
                });
            }
            states.push(SensorState {
                cfg: *s,
                table: BeamTable::new(&s.geometry)?,
                scans: BTreeMap::new(),
                seen: BTreeSet::new(),
                max_seq: None,
                base: None,
                complete: BTreeSet::new(),
                first_arrival: None,
                last_heard: start,
                min_latency_us: None,
            });
        }
        let t0 = start.0.div_euclid(cfg.period_us) * cfg.period_us;
        let t0 = if t0 < start.0 {
            t0.saturating_add(cfg.period_us)
        } else {
            t0
        };
        Ok(Self {
            cfg,
            sensors: states,
            t0,
            next_frame: 0,
            watermark: None,
            stats: FusionStats::default(),
        })
    }

    /// Counters so far.
    pub fn stats(&self) -> FusionStats {
        self.stats
    }

    /// The time of the next frame to close.
    pub fn next_frame_time(&self) -> TimeUs {
        TimeUs(
            self.t0
                .saturating_add((self.next_frame as i64).saturating_mul(self.cfg.period_us)),
        )
    }

    /// Per-sensor minimum of `arrival − t_capture` seen so far, µs (the skew monitor's ε_s: a
    /// negative value means the sensor's clock is ahead).
    pub fn min_latency_us(&self, sensor: SensorId) -> Option<i64> {
        self.sensors
            .iter()
            .find(|s| s.cfg.id == sensor)?
            .min_latency_us
    }

    fn half_window(&self) -> i64 {
        match self.cfg.scans_per_frame {
            ScansPerFrame::Nearest => self.cfg.tau_sync_us,
            ScansPerFrame::All => self.cfg.period_us / 2,
        }
    }

    /// Replaces the world pose of `sensor` (e.g. after calibration, spec 003 §2.3). Scans are
    /// transformed when their frame closes, so every frame closed afterwards uses the new pose,
    /// including frames of scans already received. Errors: unknown sensor, non-finite pose.
    pub fn set_pose(&mut self, sensor: SensorId, pose: Pose2) -> Result<()> {
        if !pose.is_finite() {
            return Err(CoreError::NonFinite {
                what: "sensor pose",
            });
        }
        let s = self
            .sensors
            .iter_mut()
            .find(|s| s.cfg.id == sensor)
            .ok_or_else(|| {
                CoreError::invalid("sensor", format!("unknown sensor id {}", sensor.0))
            })?;
        s.cfg.pose = pose;
        Ok(())
    }

    /// The world pose of `sensor` in use, if known.
    pub fn pose(&self, sensor: SensorId) -> Option<Pose2> {
        self.sensors
            .iter()
            .find(|s| s.cfg.id == sensor)
            .map(|s| s.cfg.pose)
    }

    /// Decodes and files one datagram received at server time `arrival`.
    pub fn on_datagram(&mut self, bytes: &[u8], arrival: TimeUs) -> Disposition {
        if let Ok(m) = Message::decode(bytes) {
            self.on_message(&m, arrival)
        } else {
            self.stats.malformed += 1;
            Disposition::Malformed
        }
    }

    /// Files one decoded message received at server time `arrival`.
    pub fn on_message(&mut self, m: &Message, arrival: TimeUs) -> Disposition {
        let h = &m.header;
        let Some(k) = self.sensors.iter().position(|s| s.cfg.id == h.sensor) else {
            self.stats.unknown += 1;
            return Disposition::UnknownSensor;
        };
        let s = &mut self.sensors[k];
        s.last_heard = s.last_heard.max(arrival);
        match h.kind {
            Kind::Hello => {
                s.reset_seq();
                self.stats.restarts += 1;
                return Disposition::Other;
            }
            Kind::DynamicScan => {}
            _ => return Disposition::Other,
        }
        let Payload::Points(pts) = &m.payload else {
            self.stats.malformed += 1;
            return Disposition::Malformed;
        };
        if h.flags & FLAG_CLOCK_SYNCED == 0 && !self.cfg.accept_unsynced {
            self.stats.unsynced += 1;
            return Disposition::Unsynced;
        }
        if h.t_capture.0 > arrival.0.saturating_add(self.cfg.future_tolerance_us) {
            self.stats.future += 1;
            return Disposition::Future;
        }
        let lat = arrival.0.saturating_sub(h.t_capture.0);
        s.min_latency_us = Some(s.min_latency_us.map_or(lat, |m| m.min(lat)));
        // restart: the sequence dropped by more than 1000
        if let Some(mx) = s.max_seq
            && h.seq.saturating_add(1000) < mx
        {
            s.reset_seq();
            self.stats.restarts += 1;
        }
        if s.seen.contains(&(h.seq, h.part)) {
            self.stats.dup += 1;
            return Disposition::Duplicate;
        }
        if self.watermark.is_some_and(|w| h.t_capture <= w) || s.base.is_some_and(|b| h.seq <= b) {
            s.seen.insert((h.seq, h.part));
            self.stats.late += 1;
            return Disposition::Late;
        }
        if let Some(e) = s.scans.get(&h.seq)
            && (e.t != h.t_capture || e.parts != h.parts)
        {
            self.stats.malformed += 1;
            return Disposition::Malformed;
        }
        s.seen.insert((h.seq, h.part));
        match s.max_seq {
            Some(mx) if h.seq > mx => {
                self.stats.lost += u64::from(h.seq - mx - 1);
                s.max_seq = Some(h.seq);
            }
            None => s.max_seq = Some(h.seq),
            _ => {}
        }
        if let Some(mx) = s.max_seq {
            let floor = mx.saturating_sub(4096);
            while s.seen.first().is_some_and(|&(q, _)| q < floor) {
                s.seen.pop_first();
            }
        }
        if s.first_arrival.is_none() {
            s.first_arrival = Some(arrival);
        }
        let e = s.scans.entry(h.seq).or_insert_with(|| ScanEntry {
            t: h.t_capture,
            parts: h.parts,
            got: BTreeMap::new(),
        });
        e.got.insert(h.part, pts.clone());
        if e.complete() {
            s.complete.insert(h.seq);
        }
        self.stats.accepted += 1;
        Disposition::Accepted
    }

    fn live(&self, s: &SensorState, now: TimeUs) -> bool {
        now.0.saturating_sub(s.last_heard.0) < self.cfg.liveness_us
    }

    /// Rule (i) for one sensor and frame time.
    fn sensor_ready(&self, s: &SensorState, t_f: i64, now: TimeUs) -> bool {
        let Some(first) = s.first_arrival else {
            return false;
        };
        if now.0 < first.0.saturating_add(self.cfg.max_latency_us) {
            return false;
        }
        let edge = t_f.saturating_add(self.half_window());
        // lowest expected seq: above base, or the lowest seen
        let mut expect = match s.base {
            Some(b) => b.wrapping_add(1),
            None => match s.scans.keys().next() {
                Some(&k) => k,
                None => return false,
            },
        };
        for (&seq, e) in &s.scans {
            if seq != expect || !e.complete() {
                return false;
            }
            if e.t.0 >= edge {
                return true;
            }
            expect = seq.wrapping_add(1);
        }
        false
    }

    /// Closes every frame that is due at server time `now` and returns them in order.
    pub fn poll(&mut self, now: TimeUs) -> Vec<Frame> {
        let mut out = Vec::new();
        let w = self.half_window();
        while out.len() < self.cfg.max_frames_per_poll {
            let t_f = self
                .t0
                .saturating_add((self.next_frame as i64).saturating_mul(self.cfg.period_us));
            let deadline = now.0
                >= t_f
                    .saturating_add(w)
                    .saturating_add(self.cfg.max_latency_us);
            let live: Vec<usize> = (0..self.sensors.len())
                .filter(|&k| self.live(&self.sensors[k], now))
                .collect();
            let early = !live.is_empty()
                && live
                    .iter()
                    .all(|&k| self.sensor_ready(&self.sensors[k], t_f, now));
            if !(deadline || early) {
                break;
            }
            out.push(self.close(t_f, now));
        }
        out
    }

    fn close(&mut self, t_f: i64, now: TimeUs) -> Frame {
        let w = self.half_window();
        let edge = t_f.saturating_add(w);
        let mut frame = Frame {
            index: self.next_frame,
            t: TimeUs(t_f),
            points: Vec::new(),
            present: 0,
            missing: 0,
            partial: 0,
            no_data: false,
        };
        let mut bad_points = 0;
        for k in 0..self.sensors.len() {
            let live = self.live(&self.sensors[k], now);
            let s = &mut self.sensors[k];
            let in_window = |e: &ScanEntry| match self.cfg.scans_per_frame {
                ScansPerFrame::Nearest => e.t.0.abs_diff(t_f) <= w.unsigned_abs(),
                ScansPerFrame::All => e.t.0 > t_f.saturating_sub(w) && e.t.0 <= edge,
            };
            let mut chosen: Vec<u32> = s
                .scans
                .iter()
                .filter(|(_, e)| in_window(e))
                .map(|(&q, _)| q)
                .collect();
            if self.cfg.scans_per_frame == ScansPerFrame::Nearest && chosen.len() > 1 {
                let best = chosen
                    .iter()
                    .copied()
                    .min_by_key(|q| {
                        let t = s.scans[q].t.0;
                        (t.abs_diff(t_f), t, *q)
                    })
                    .into_iter()
                    .collect();
                chosen = best;
            }
            if chosen.is_empty() {
                if live {
                    frame.missing |= 1 << k;
                }
            } else {
                frame.present |= 1 << k;
            }
            for q in &chosen {
                let e = &s.scans[q];
                if !e.complete() {
                    frame.partial |= 1 << k;
                }
                for part in e.got.values() {
                    let (pts, skipped) = s.table.pairs_to_points(part, &s.cfg.pose);
                    bad_points += skipped as u64;
                    frame
                        .points
                        .extend(pts.into_iter().map(|(beam, p)| FramePoint {
                            sensor: s.cfg.id,
                            beam,
                            t_capture: e.t,
                            p,
                        }));
                }
            }
            // drop everything at or before the watermark; advance the sequence base
            let old: Vec<u32> = s
                .scans
                .iter()
                .filter(|(_, e)| e.t.0 <= edge)
                .map(|(&q, _)| q)
                .collect();
            for q in old {
                s.scans.remove(&q);
                s.base = Some(s.base.map_or(q, |b| b.max(q)));
            }
            if let Some(b) = s.base {
                while s.complete.first().is_some_and(|&q| q <= b) {
                    s.complete.pop_first();
                }
            }
        }
        let order: BTreeMap<SensorId, usize> = self
            .sensors
            .iter()
            .enumerate()
            .map(|(k, s)| (s.cfg.id, k))
            .collect();
        frame.points.sort_by(|a, b| {
            order[&a.sensor]
                .cmp(&order[&b.sensor])
                .then(a.beam.cmp(&b.beam))
                .then(a.t_capture.cmp(&b.t_capture))
        });
        frame.no_data = frame.present == 0;
        self.stats.bad_points += bad_points;
        self.stats.frames += 1;
        self.watermark = Some(TimeUs(edge));
        self.next_frame += 1;
        frame
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::wire::{Header, encode_scan};
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng, seq::SliceRandom};

    fn sensors() -> Vec<SensorConfig> {
        let g = ScanGeometry::utm30lx();
        vec![
            SensorConfig {
                id: SensorId(10),
                pose: Pose2::new(0.25, 0.25, 0.785),
                geometry: g,
            },
            SensorConfig {
                id: SensorId(11),
                pose: Pose2::new(9.75, 0.25, 2.356),
                geometry: g,
            },
            SensorConfig {
                id: SensorId(12),
                pose: Pose2::new(5.0, 7.75, -1.571),
                geometry: g,
            },
        ]
    }

    /// (capture time, datagrams) of `n` scans per sensor at 40 Hz with phases.
    fn messages(seed: u64, n: u32) -> Vec<(i64, Vec<u8>)> {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut out = Vec::new();
        for (k, s) in sensors().iter().enumerate() {
            let phase: i64 = rng.random_range(0..25_000);
            for j in 0..n {
                let t = 1_000_000 + phase + i64::from(j) * 25_000 + k as i64;
                let npts: usize = rng.random_range(0..500);
                let pts: Vec<(u16, u16)> = (0..npts)
                    .map(|_| (rng.random_range(0..1081), rng.random_range(100..9000)))
                    .collect();
                let h = Header {
                    kind: Kind::DynamicScan,
                    sensor: s.id,
                    seq: j,
                    part: 0,
                    parts: 1,
                    flags: FLAG_CLOCK_SYNCED,
                    t_capture: TimeUs(t),
                    t_send: TimeUs(t + 1000),
                };
                for b in encode_scan(h, &pts).unwrap() {
                    out.push((t, b));
                }
            }
        }
        out
    }

    fn run(events: &[(i64, Vec<u8>)], end: i64) -> (Vec<Frame>, FusionStats) {
        let mut fa =
            FrameAssembler::new(FrameConfig::default(), &sensors(), TimeUs(1_000_000)).unwrap();
        let mut frames = Vec::new();
        for (arr, b) in events {
            fa.on_datagram(b, TimeUs(*arr));
            frames.extend(fa.poll(TimeUs(*arr)));
        }
        frames.extend(fa.poll(TimeUs(end)));
        (frames, fa.stats())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn frames_do_not_depend_on_arrival_order(seed in 0u64..1000, dup_p in 0.0f64..0.3) {
            let msgs = messages(seed, 16);
            let end = 1_000_000 + 16 * 25_000 + 400_000;
            let in_order: Vec<(i64, Vec<u8>)> = msgs.iter().map(|(t, b)| (t + 1_000, b.clone())).collect();
            let mut sorted = in_order.clone();
            sorted.sort_by_key(|e| e.0);
            let (base, st0) = run(&sorted, end);
            prop_assert!(base.len() >= 8);
            prop_assert_eq!(st0.late, 0);
            // random delays up to 60 ms (all before their deadlines), duplicates, shuffled ties
            let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed + 77);
            let mut ev: Vec<(i64, Vec<u8>)> = Vec::new();
            for (t, b) in &msgs {
                ev.push((t + rng.random_range(0..60_000), b.clone()));
                if rng.random_bool(dup_p) {
                    ev.push((t + rng.random_range(0..60_000), b.clone()));
                }
            }
            ev.shuffle(&mut rng);
            ev.sort_by_key(|e| e.0); // stable: equal arrival times stay shuffled
            let (frames, st) = run(&ev, end);
            prop_assert_eq!(st.late, 0);
            prop_assert_eq!(frames.len(), base.len());
            for (a, b) in frames.iter().zip(&base) {
                prop_assert_eq!(a, b);
            }
        }
    }

    #[test]
    fn late_missing_and_stopped_sensor() {
        let msgs = messages(5, 40);
        let stop = 1_000_000 + 20 * 25_000;
        // sensor 12 stops half-way
        let mut ev: Vec<(i64, Vec<u8>)> = msgs
            .iter()
            .filter(|(t, b)| {
                !(Message::decode(b).unwrap().header.sensor == SensorId(12) && *t > stop)
            })
            .map(|(t, b)| (t + 2_000, b.clone()))
            .collect();
        ev.sort_by_key(|e| e.0);
        let mut fa =
            FrameAssembler::new(FrameConfig::default(), &sensors(), TimeUs(1_000_000)).unwrap();
        let mut frames = Vec::new();
        for (arr, b) in &ev {
            fa.on_datagram(b, TimeUs(*arr));
            frames.extend(fa.poll(TimeUs(*arr)));
        }
        frames.extend(fa.poll(TimeUs(stop + 400_000)));
        // before the stop sensor 12 is present; after it, frames close (at their deadline) with
        // its missing bit while the others still deliver
        let last_other = 1_000_000 + 39 * 25_000;
        let before: Vec<&Frame> = frames
            .iter()
            .filter(|f| f.t.0 > 1_100_000 && f.t.0 < stop - 50_000)
            .collect();
        let after: Vec<&Frame> = frames
            .iter()
            .filter(|f| f.t.0 > stop + 40_000 && f.t.0 < last_other - 50_000)
            .collect();
        assert!(
            before.len() >= 5 && after.len() >= 5,
            "{} {}",
            before.len(),
            after.len()
        );
        assert!(before.iter().all(|f| f.present == 0b111 && f.missing == 0));
        assert!(
            after
                .iter()
                .all(|f| f.missing == 1 << 2 && f.present == 0b011 && !f.no_data)
        );
        // a message for a closed frame is late and changes nothing
        let closed = frames.clone();
        let (t, b) = &msgs[0];
        let mut h = Message::decode(b).unwrap();
        h.header.seq = 1000;
        let d = fa.on_message(&h, TimeUs(*t + 500_000));
        assert_eq!(d, Disposition::Late);
        assert_eq!(fa.stats().late, 1);
        assert_eq!(closed, frames);
        // after 1 s of silence sensor 12 is offline: no longer missing
        let later = fa.poll(TimeUs(stop + 2_000_000));
        assert_eq!(later.last().unwrap().missing, 0);
        assert!(later.last().unwrap().no_data);
        // garbage, unknown sensors and unsynced messages are counted
        assert_eq!(
            fa.on_datagram(&[1, 2, 3], TimeUs(0)),
            Disposition::Malformed
        );
        let mut u = Message::decode(b).unwrap();
        u.header.sensor = SensorId(99);
        assert_eq!(fa.on_message(&u, TimeUs(*t)), Disposition::UnknownSensor);
        let mut u = Message::decode(b).unwrap();
        u.header.flags = 0;
        assert_eq!(fa.on_message(&u, TimeUs(*t)), Disposition::Unsynced);
        u.header.flags = FLAG_CLOCK_SYNCED;
        u.header.t_capture = TimeUs(t + 10_000_000);
        assert_eq!(fa.on_message(&u, TimeUs(*t)), Disposition::Future);
    }

    /// The header of a synchronised one-part dynamic scan captured at `t_us`, sent 1 ms later.
    fn synced_header(sensor: SensorId, t_us: i64) -> Header {
        Header {
            kind: Kind::DynamicScan,
            sensor,
            seq: 0,
            part: 0,
            parts: 1,
            flags: FLAG_CLOCK_SYNCED,
            t_capture: TimeUs(t_us),
            t_send: TimeUs(t_us + 1000),
        }
    }

    #[test]
    fn set_pose_applies_to_frames_closed_afterwards() {
        let s = sensors();
        let mut fa = FrameAssembler::new(FrameConfig::default(), &s, TimeUs(0)).unwrap();
        let h = synced_header(SensorId(10), 51_000);
        let b = &encode_scan(h, &[(540, 2000)]).unwrap()[0];
        fa.on_datagram(b, TimeUs(53_000));
        let moved = Pose2::new(1.0, 2.0, 0.5);
        assert!(fa.set_pose(SensorId(99), moved).is_err());
        assert!(
            fa.set_pose(SensorId(10), Pose2::new(f64::NAN, 0.0, 0.0))
                .is_err()
        );
        assert_eq!(fa.pose(SensorId(10)), Some(s[0].pose));
        fa.set_pose(SensorId(10), moved).unwrap();
        assert_eq!(fa.pose(SensorId(10)), Some(moved));
        let frames = fa.poll(TimeUs(1_000_000));
        let f = frames.iter().find(|f| f.t == TimeUs(50_000)).unwrap();
        let want = moved.apply(&Point2::new(2.0, 0.0));
        assert!((f.points[0].p - want).norm() < 1e-9);
    }

    #[test]
    fn frame_points_are_in_world_frame() {
        let s = sensors();
        let mut fa = FrameAssembler::new(FrameConfig::default(), &s, TimeUs(0)).unwrap();
        let h = synced_header(SensorId(11), 51_000);
        let b = &encode_scan(h, &[(540, 2000), (100, 50)]).unwrap()[0];
        assert_eq!(fa.on_datagram(b, TimeUs(53_000)), Disposition::Accepted);
        assert_eq!(fa.on_datagram(b, TimeUs(53_500)), Disposition::Duplicate);
        let frames = fa.poll(TimeUs(1_000_000));
        let f = frames.iter().find(|f| f.t == TimeUs(50_000)).unwrap();
        assert_eq!(f.present, 1 << 1);
        assert_eq!(f.points.len(), 1); // the 50 mm return is invalid
        let want = s[1].pose.apply(&Point2::new(2.0, 0.0));
        assert!((f.points[0].p - want).norm() < 1e-9);
        assert_eq!(fa.stats().dup, 1);
        assert_eq!(fa.stats().bad_points, 1);
        assert!(frames[0].no_data);
    }
}
