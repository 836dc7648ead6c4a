//! ROS 2 over zenoh, without a bridge (feature `ros2`): the people tracker reads a ROS 2
//! `sensor_msgs/msg/LaserScan` topic and publishes its tracks as ROS 2 messages, both on the key
//! expressions and with the sample attachments of rmw_zenoh (ROS 2's zenoh middleware; the
//! rules followed, and their version, are in [`quarry_ros2::rmw_zenoh`]).
//!
//! - [`Ros2ScanSource`]: a [`ScanSource`] over a LaserScan topic: the first well-formed scan
//!   fixes the scanner's geometry; malformed CDR, scans whose beam count or angles change,
//!   scans of another type hash and stamps that go backwards are skipped and counted
//!   ([`Ros2ScanStats`]), never fatal; the stream ends after `idle` without a scan.
//! - [`Ros2Publisher`]: one ROS 2 publisher (key, liveliness token, GID, sequence numbers).
//! - [`Ros2TrackPublisher`]: a server's tracks per closed frame on `<topic>`
//!   (`quarry_msgs/msg/TrackArray`), `<topic>/poses` (`geometry_msgs/msg/PoseArray`, for tools
//!   without quarry's message) and `<topic>/markers` (`visualization_msgs/msg/MarkerArray`).
//!
//! QoS: rmw_zenoh's default (reliable, keep-last 10, volatile) is what the tokens announce;
//! the samples are put with blocking congestion control, as rmw_zenoh does for reliable
//! publishers.
//!
//! ```
//! use quarry_net::ros2::{Ros2Options, Ros2ScanSource, Ros2Publisher};
//! use quarry_net::LocalBus;
//! use quarry_net::ScanSource;
//! use quarry_ros2::msgs::{Header, LaserScan, Time};
//! use std::time::Duration;
//!
//! let bus = LocalBus::new();
//! let opts = Ros2Options::default();
//! // a ROS 2 node's side: a LaserScan publisher on /scan
//! let mut scan_pub = Ros2Publisher::<LaserScan>::new(&bus, &opts, "/scan", 1)?;
//! // quarry's side: subscribe first, then the scans arrive
//! let sub = Ros2ScanSource::subscribe(&bus, &opts, "/scan", quarry_core::SensorId(1))?;
//! for k in 0..3 {
//!     let msg = LaserScan {
//!         header: Header::new(Time::from_secs_f64(1.0 + 0.1 * f64::from(k)), "laser"),
//!         angle_min: -1.0,
//!         angle_max: 1.0,
//!         angle_increment: 0.5,
//!         range_max: 30.0,
//!         ranges: vec![1.0, 2.0, f32::INFINITY, 2.5, 3.0],
//!         ..LaserScan::default()
//!     };
//!     scan_pub.publish(&bus, &msg, 0)?;
//! }
//! let mut src = sub.first_scan(Duration::from_secs(1), Duration::from_millis(100))?;
//! assert_eq!(src.geometry().n_beams, 5);
//! let mut n = 0;
//! while let Some((_, scan)) = src.next_scan()? {
//!     assert_eq!(scan.ranges_mm[1], 2000);
//!     n += 1;
//! }
//! assert_eq!(n, 3);
//! # Ok::<(), quarry_net::NetError>(())
//! ```

use crate::NetError;
use crate::node::ScanSource;
use crate::server::ClosedFrame;
use crate::transport::{Liveliness, Subscription, Transport};
use quarry_core::{PolarScan, ScanGeometry, SensorId, TimeUs};
use quarry_ros2::Message;
use quarry_ros2::convert::{self, planar_track};
use quarry_ros2::msgs::{Header, LaserScan, MarkerArray, Pose, PoseArray, TrackArray};
use quarry_ros2::rmw_zenoh::{self, Attachment};
use serde::Serialize;
use std::marker::PhantomData;
use std::time::{Duration, Instant};

/// Where a quarry process appears in the ROS 2 graph.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Ros2Options {
    /// ROS domain id (`ROS_DOMAIN_ID`; 0 by default, at most 232 as in ROS 2).
    pub domain: u32,
    /// The zenoh session id (hex) the liveliness tokens name (`ZenohTransport::zid`; any
    /// unique string on an in-process bus).
    pub zid: String,
    /// The node name the tokens announce (`ros2 node list` shows `/<node>`).
    pub node: String,
}

impl Default for Ros2Options {
    fn default() -> Self {
        Self {
            domain: 0,
            zid: "0".into(),
            node: "quarry".into(),
        }
    }
}

impl Ros2Options {
    /// Checks the domain id (0-232) and the node name (letters, digits, `_`; not leading with
    /// a digit).
    ///
    /// # Errors
    /// [`NetError::Config`] saying which value is wrong.
    pub fn validate(&self) -> Result<(), NetError> {
        if self.domain > 232 {
            return Err(NetError::Config(format!(
                "ROS domain id {} is out of range (0-232)",
                self.domain
            )));
        }
        let n = &self.node;
        if n.is_empty()
            || n.starts_with(|c: char| c.is_ascii_digit())
            || !n.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            return Err(NetError::Config(format!(
                "ROS node name `{n}`: letters, digits and `_`, not starting with a digit"
            )));
        }
        Ok(())
    }
}

fn topic_err(e: String) -> NetError {
    NetError::Config(e)
}

/// One ROS 2 publisher of messages `M` on a topic, as rmw_zenoh publishes: the CDR message on
/// the topic's key expression, an [`Attachment`] with a sequence number (from 1), the source
/// timestamp and the publisher's GID, and a liveliness token while it exists.
pub struct Ros2Publisher<M: Message> {
    key: String,
    gid: [u8; rmw_zenoh::GID_LEN],
    seq: i64,
    _token: Liveliness,
    _m: PhantomData<fn(&M)>,
}

impl<M: Message> std::fmt::Debug for Ros2Publisher<M> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Publisher")
            .field("key", &self.key)
            .field("seq", &self.seq)
            .finish_non_exhaustive()
    }
}

impl<M: Message> Ros2Publisher<M> {
    /// A publisher on `topic` (entity id `entity`, unique within the process).
    ///
    /// # Errors
    /// [`NetError::Config`]: invalid options or topic name; a transport error declaring the
    /// liveliness token.
    pub fn new(
        transport: &dyn Transport,
        opts: &Ros2Options,
        topic: &str,
        entity: u32,
    ) -> Result<Self, NetError> {
        opts.validate()?;
        let key = rmw_zenoh::topic_key::<M>(opts.domain, topic).map_err(topic_err)?;
        let token =
            rmw_zenoh::publisher_token::<M>(opts.domain, &opts.zid, 0, entity, &opts.node, topic)
                .map_err(topic_err)?;
        let gid = rmw_zenoh::gid_of(&token);
        let token = transport.declare_liveliness(&token)?;
        Ok(Self {
            key,
            gid,
            seq: 0,
            _token: token,
            _m: PhantomData,
        })
    }

    /// The key expression it publishes on.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Messages published so far.
    pub fn published(&self) -> i64 {
        self.seq
    }

    /// Publishes `msg` with source timestamp `source_ns` (ns since the Unix epoch; 0 = now).
    ///
    /// # Errors
    /// The transport's.
    pub fn publish(
        &mut self,
        transport: &dyn Transport,
        msg: &M,
        source_ns: i64,
    ) -> Result<(), NetError> {
        self.seq += 1;
        let ts = if source_ns == 0 { unix_ns() } else { source_ns };
        let att = Attachment {
            sequence_number: self.seq,
            source_timestamp: ts,
            source_gid: self.gid,
        };
        transport.publish_with_attachment(&self.key, &msg.to_cdr(), &att.encode())
    }
}

fn unix_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// The three publishers of a lidar server's tracks.
#[derive(Debug)]
pub struct Ros2TrackPublisher {
    frame_id: String,
    tracks: Ros2Publisher<TrackArray>,
    poses: Ros2Publisher<PoseArray>,
    markers: Ros2Publisher<MarkerArray>,
}

impl Ros2TrackPublisher {
    /// Publishers on `topic`, `topic/poses` and `topic/markers` (entity ids 10-12), with the
    /// positions in `frame_id`; the stamps are the frames' Unix times
    /// ([`ClosedFrame::unix_us`]).
    ///
    /// # Errors
    /// As [`Ros2Publisher::new`]; an empty frame id.
    pub fn new(
        transport: &dyn Transport,
        opts: &Ros2Options,
        topic: &str,
        frame_id: &str,
    ) -> Result<Self, NetError> {
        if frame_id.is_empty() {
            return Err(NetError::Config("the ROS frame id is empty".into()));
        }
        let base = topic.trim_end_matches('/');
        Ok(Self {
            frame_id: frame_id.to_string(),
            tracks: Ros2Publisher::new(transport, opts, base, 10)?,
            poses: Ros2Publisher::new(transport, opts, &format!("{base}/poses"), 11)?,
            markers: Ros2Publisher::new(transport, opts, &format!("{base}/markers"), 12)?,
        })
    }

    /// Frames published.
    pub fn published(&self) -> i64 {
        self.tracks.published()
    }

    /// Publishes one closed frame's tracks on the three topics.
    ///
    /// # Errors
    /// The transport's.
    pub fn publish(
        &mut self,
        transport: &dyn Transport,
        f: &ClosedFrame<'_>,
    ) -> Result<(), NetError> {
        let t = f.unix_us();
        let tracks: Vec<_> = f
            .tracks
            .iter()
            .map(|r| planar_track(r.id, r.x, r.y, r.vx, r.vy))
            .collect();
        let ns = t.0.saturating_mul(1000);
        let poses = PoseArray {
            header: Header::new(convert::time_of(t), &self.frame_id),
            poses: f
                .tracks
                .iter()
                .map(|r| Pose::planar(r.x, r.y, r.vy.atan2(r.vx)))
                .collect(),
        };
        let markers = convert::track_markers(t, &self.frame_id, &tracks, 1.2);
        self.poses.publish(transport, &poses, ns)?;
        self.markers.publish(transport, &markers, ns)?;
        self.tracks.publish(
            transport,
            &convert::track_array(t, &self.frame_id, tracks),
            ns,
        )
    }
}

/// What a [`Ros2ScanSource`] received and skipped.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct Ros2ScanStats {
    /// Samples received on the topic.
    pub received: u64,
    /// Scans passed on.
    pub scans: u64,
    /// Samples that did not decode as a LaserScan (truncated, malformed CDR).
    pub malformed: u64,
    /// Scans whose beam count or angles differ from the first scan's.
    pub wrong_geometry: u64,
    /// Samples of the topic with another type hash (another ROS distribution's LaserScan).
    pub foreign_hash: u64,
    /// Scans whose stamp is not after the previous scan's.
    pub stamps_backwards: u64,
    /// Scans dropped because newer ones were queued behind them ([`MAX_LAG_S`]).
    pub stale: u64,
    /// The first skip's reason, for the report.
    pub first_skip: Option<String>,
}

impl Ros2ScanStats {
    fn skip(&mut self, why: String) {
        if self.first_skip.is_none() {
            self.first_skip = Some(why);
        }
    }
}

/// A subscription to a LaserScan topic, before its first scan ([`Ros2ScanSource::subscribe`]):
/// subscribe before the publisher starts, then wait for the first scan.
pub struct Ros2ScanSubscription {
    sub: Box<dyn Subscription>,
    sensor: SensorId,
    hash: String,
    topic: String,
    stats: Ros2ScanStats,
}

impl std::fmt::Debug for Ros2ScanSubscription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2ScanSubscription")
            .field("topic", &self.topic)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// A [`ScanSource`] over a ROS 2 `sensor_msgs/msg/LaserScan` topic published by rmw_zenoh.
pub struct Ros2ScanSource {
    inner: Ros2ScanSubscription,
    geometry: ScanGeometry,
    pending: std::collections::VecDeque<PolarScan>,
    max_lag: TimeUs,
    last: TimeUs,
    idle: Duration,
    seq: u32,
}

impl std::fmt::Debug for Ros2ScanSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2ScanSource")
            .field("topic", &self.inner.topic)
            .field("geometry", &self.geometry)
            .field("stats", &self.inner.stats)
            .finish_non_exhaustive()
    }
}

/// A live consumer must not fall behind its sensor: of the scans queued when the node asks for
/// the next, those more than this many seconds older than the newest are dropped (counted in
/// [`Ros2ScanStats::stale`]), e.g. the scans that arrived while the node synchronised its
/// clock.
pub const MAX_LAG_S: f64 = 0.25;

/// The largest difference between a LaserScan's stamp and this machine's wall clock at which
/// the stamp is taken as the scan's capture time on this clock ([`ScanSource::capture_age`]):
/// one second, four times [`MAX_LAG_S`] (older scans are dropped as stale anyway).
pub const MAX_CAPTURE_AGE_S: f64 = 1.0;

/// The scan period assumed when a LaserScan's `scan_time` is 0 (many drivers leave it unset).
pub const DEFAULT_SCAN_PERIOD_S: f64 = 0.025;

impl Ros2ScanSource {
    /// Subscribes to LaserScans on `topic` (any type hash; those other than this build's are
    /// counted and skipped), as sensor `sensor`.
    ///
    /// # Errors
    /// [`NetError::Config`]: invalid options or topic; the transport's.
    pub fn subscribe(
        transport: &dyn Transport,
        opts: &Ros2Options,
        topic: &str,
        sensor: SensorId,
    ) -> Result<Ros2ScanSubscription, NetError> {
        opts.validate()?;
        let pattern =
            rmw_zenoh::topic_pattern::<LaserScan>(opts.domain, topic).map_err(topic_err)?;
        Ok(Ros2ScanSubscription {
            sub: transport.subscribe(&pattern)?,
            sensor,
            hash: LaserScan::type_hash(),
            topic: topic.to_string(),
            stats: Ros2ScanStats::default(),
        })
    }

    /// The counters so far.
    pub fn stats(&self) -> &Ros2ScanStats {
        &self.inner.stats
    }
}

impl Ros2ScanSubscription {
    /// The next sample that decodes as a LaserScan of this build's type, waiting at most
    /// `timeout` in all; skips are counted.
    fn next_msg(&mut self, timeout: Duration) -> Result<Option<LaserScan>, NetError> {
        let until = Instant::now() + timeout;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            let Some(r) = self.sub.recv_timeout(left)? else {
                return Ok(None);
            };
            self.stats.received += 1;
            match rmw_zenoh::hash_of_key(&r.key) {
                Some(h) if h == self.hash => {}
                other => {
                    self.stats.foreign_hash += 1;
                    self.stats.skip(format!(
                        "a LaserScan with type hash {} (this build's is {})",
                        other.unwrap_or("(none)"),
                        self.hash
                    ));
                    continue;
                }
            }
            match LaserScan::from_cdr(&r.payload) {
                Ok(m) => return Ok(Some(m)),
                Err(e) => {
                    self.stats.malformed += 1;
                    self.stats.skip(format!("a malformed LaserScan: {e}"));
                }
            }
        }
    }

    /// Waits up to `wait` for the first well-formed scan, whose geometry becomes the run's
    /// (the scan period from `scan_time`, else [`DEFAULT_SCAN_PERIOD_S`]), and returns the
    /// source, which ends once `idle` passes without a scan.
    ///
    /// # Errors
    /// [`NetError::Timeout`] if no usable scan arrives within `wait` (naming the topic and
    /// what was skipped).
    pub fn first_scan(
        mut self,
        wait: Duration,
        idle: Duration,
    ) -> Result<Ros2ScanSource, NetError> {
        let until = Instant::now() + wait;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            let Some(m) = self.next_msg(left)? else {
                return Err(NetError::Timeout(format!(
                    "no usable LaserScan on {} within {:.1} s ({} samples received{})",
                    self.topic,
                    wait.as_secs_f64(),
                    self.stats.received,
                    self.stats
                        .first_skip
                        .as_ref()
                        .map(|s| format!("; first skipped: {s}"))
                        .unwrap_or_default()
                )));
            };
            let g = match convert::geometry_of(&m, DEFAULT_SCAN_PERIOD_S) {
                Ok(g) => g,
                Err(e) => {
                    self.stats.wrong_geometry += 1;
                    self.stats
                        .skip(format!("a LaserScan with an unusable geometry: {e}"));
                    continue;
                }
            };
            let scan = match convert::polar_scan(&m, self.sensor, 0, &g) {
                Ok(s) => s,
                Err(e) => {
                    self.stats.malformed += 1;
                    self.stats.skip(format!("{e}"));
                    continue;
                }
            };
            return Ok(Ros2ScanSource {
                last: scan.t,
                inner: self,
                geometry: g,
                pending: std::collections::VecDeque::from([scan]),
                max_lag: TimeUs::from_secs_f64(MAX_LAG_S),
                idle,
                seq: 1,
            });
        }
    }
}

impl ScanSource for Ros2ScanSource {
    fn sensor(&self) -> SensorId {
        self.inner.sensor
    }

    fn geometry(&self) -> ScanGeometry {
        self.geometry
    }

    fn next_scan(&mut self) -> Result<Option<(TimeUs, PolarScan)>, NetError> {
        // what is queued now, then (if nothing) wait up to `idle` for one
        while let Some(s) = self.accept(Duration::ZERO)? {
            self.pending.push_back(s);
        }
        if self.pending.is_empty() {
            match self.accept(self.idle)? {
                Some(s) => self.pending.push_back(s),
                None => return Ok(None),
            }
        }
        let newest = self.pending.back().map_or(TimeUs(0), |s| s.t);
        while self
            .pending
            .front()
            .is_some_and(|s| s.t.0 < newest.0 - self.max_lag.0)
        {
            self.pending.pop_front();
            self.inner.stats.stale += 1;
        }
        let s = self.pending.pop_front().ok_or_else(|| {
            NetError::Config("internal: an empty scan queue after a scan arrived".into())
        })?;
        self.inner.stats.scans += 1;
        Ok(Some((s.t, s)))
    }

    fn live(&self) -> bool {
        true
    }

    /// The age of a scan whose stamp is this machine's wall clock (a driver on this machine
    /// or on a synchronised one): now − stamp, at least 0 (a clock a little ahead), when it
    /// lies within ±[`MAX_CAPTURE_AGE_S`]; otherwise the stamps are on another clock (ROS sim
    /// time, an unsynchronised machine) and the scan is stamped when the node handles it.
    fn capture_age(&self, t_src: TimeUs) -> Option<Duration> {
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .ok()?;
        let age = now.as_secs_f64() - t_src.as_secs_f64();
        (age.abs() <= MAX_CAPTURE_AGE_S).then(|| Duration::from_secs_f64(age.max(0.0)))
    }
}

impl Ros2ScanSource {
    /// The next usable scan within `timeout` (skips counted), or `None`.
    fn accept(&mut self, timeout: Duration) -> Result<Option<PolarScan>, NetError> {
        let until = Instant::now() + timeout;
        loop {
            let left = until.saturating_duration_since(Instant::now());
            let Some(m) = self.inner.next_msg(left)? else {
                return Ok(None);
            };
            let s = match convert::polar_scan(&m, self.inner.sensor, self.seq, &self.geometry) {
                Ok(s) => s,
                Err(e) => {
                    self.inner.stats.wrong_geometry += 1;
                    self.inner.stats.skip(format!("{e}"));
                    continue;
                }
            };
            if s.t <= self.last {
                self.inner.stats.stamps_backwards += 1;
                self.inner.stats.skip(format!(
                    "a LaserScan stamped {} s, not after the previous {} s",
                    s.t.as_secs_f64(),
                    self.last.as_secs_f64()
                ));
                continue;
            }
            self.last = s.t;
            self.seq = self.seq.wrapping_add(1);
            return Ok(Some(s));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LocalBus;
    use quarry_ros2::msgs::Time;

    fn scan(t: f64, n: usize) -> LaserScan {
        LaserScan {
            header: Header::new(Time::from_secs_f64(t), "laser"),
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.01,
            range_max: 20.0,
            ranges: vec![3.0; n],
            ..LaserScan::default()
        }
    }

    #[test]
    fn bad_samples_are_counted_and_skipped() {
        let bus = LocalBus::new();
        let opts = Ros2Options::default();
        let sub = Ros2ScanSource::subscribe(&bus, &opts, "/scan", SensorId(2)).unwrap();
        let mut p = Ros2Publisher::<LaserScan>::new(&bus, &opts, "/scan", 1).unwrap();
        let key = p.key().to_string();
        // garbage before the first scan, then a good scan
        bus.publish_with_attachment(&key, &[0, 1, 0, 0, 9], &[])
            .unwrap();
        p.publish(&bus, &scan(1.0, 201), 0).unwrap();
        // a truncated one, a changed beam count, one from the past, another distribution's
        // hash, then a good one
        let good = scan(1.02, 201).to_cdr();
        bus.publish(&key, &good[..good.len() - 7]).unwrap();
        p.publish(&bus, &scan(1.04, 150), 0).unwrap();
        p.publish(&bus, &scan(0.5, 201), 0).unwrap();
        let other = key.replace("RIHS01_", "RIHS01_00");
        bus.publish(&other, &good).unwrap();
        p.publish(&bus, &scan(1.1, 201), 0).unwrap();
        let mut src = sub
            .first_scan(Duration::from_secs(1), Duration::from_millis(50))
            .unwrap();
        assert_eq!(src.geometry().n_beams, 201);
        let mut stamps = Vec::new();
        while let Some((t, s)) = src.next_scan().unwrap() {
            assert_eq!(s.sensor, SensorId(2));
            stamps.push(t.as_secs_f64());
        }
        assert_eq!(stamps.len(), 2, "{stamps:?}");
        assert!((stamps[1] - 1.1).abs() < 1e-6);
        let st = src.stats();
        assert_eq!(st.received, 7);
        assert_eq!(st.malformed, 2);
        assert_eq!(st.wrong_geometry, 1);
        assert_eq!(st.stamps_backwards, 1);
        assert_eq!(st.foreign_hash, 1);
        assert_eq!(st.scans, 2);
        assert_eq!(st.stale, 0);
    }

    #[test]
    fn a_wall_clock_stamp_gives_the_capture_age_and_another_clock_none() {
        let bus = LocalBus::new();
        let opts = Ros2Options::default();
        let sub = Ros2ScanSource::subscribe(&bus, &opts, "/scan", SensorId(0)).unwrap();
        let mut p = Ros2Publisher::<LaserScan>::new(&bus, &opts, "/scan", 1).unwrap();
        p.publish(&bus, &scan(1.0, 11), 0).unwrap();
        let src = sub
            .first_scan(Duration::from_secs(1), Duration::from_millis(50))
            .unwrap();
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_secs_f64();
        // captured 0.3 s ago on this clock: an age of 0.3 s (a little more by now, a µs less
        // through the stamp's rounding to whole µs)
        let age = src.capture_age(TimeUs::from_secs_f64(now - 0.3)).unwrap();
        assert!(age.as_secs_f64() >= 0.3 - 2e-6, "{age:?}");
        // a clock a little ahead counts as now
        let ahead = src.capture_age(TimeUs::from_secs_f64(now + 0.5)).unwrap();
        assert!(ahead.as_secs_f64() < 0.5, "{ahead:?}");
        // ROS sim time, or a stamp far from this clock: not a capture time here
        assert_eq!(src.capture_age(TimeUs::from_secs_f64(1.0)), None);
        assert_eq!(src.capture_age(TimeUs::from_secs_f64(now + 5.0)), None);
    }

    #[test]
    fn a_live_source_drops_the_backlog_it_cannot_catch_up_with() {
        let bus = LocalBus::new();
        let opts = Ros2Options::default();
        let sub = Ros2ScanSource::subscribe(&bus, &opts, "/scan", SensorId(0)).unwrap();
        let mut p = Ros2Publisher::<LaserScan>::new(&bus, &opts, "/scan", 1).unwrap();
        // 2 s of scans at 40 Hz queued while the node was busy
        for k in 0..80 {
            p.publish(&bus, &scan(10.0 + 0.025 * f64::from(k), 201), 0)
                .unwrap();
        }
        let mut src = sub
            .first_scan(Duration::from_secs(1), Duration::from_millis(30))
            .unwrap();
        assert!(src.live());
        let mut n = 0;
        while src.next_scan().unwrap().is_some() {
            n += 1;
        }
        // the first (already taken as the geometry's) goes out, then only the last 0.25 s
        let st = src.stats();
        assert_eq!(u64::from(n as u32), st.scans);
        assert_eq!(st.scans + st.stale, 80);
        assert!((10..=12).contains(&st.scans), "{st:?}");
    }

    #[test]
    fn no_scan_is_a_timeout_naming_the_topic() {
        let bus = LocalBus::new();
        let opts = Ros2Options::default();
        let sub = Ros2ScanSource::subscribe(&bus, &opts, "/front/scan", SensorId(0)).unwrap();
        let e = sub
            .first_scan(Duration::from_millis(20), Duration::from_millis(20))
            .unwrap_err();
        assert!(e.to_string().contains("/front/scan"), "{e}");
    }

    #[test]
    fn options_and_topics_are_checked() {
        let bus = LocalBus::new();
        let bad = Ros2Options {
            domain: 300,
            ..Ros2Options::default()
        };
        assert!(Ros2ScanSource::subscribe(&bus, &bad, "/scan", SensorId(0)).is_err());
        let bad = Ros2Options {
            node: "9x".into(),
            ..Ros2Options::default()
        };
        assert!(Ros2Publisher::<LaserScan>::new(&bus, &bad, "/scan", 0).is_err());
        let opts = Ros2Options::default();
        assert!(Ros2Publisher::<LaserScan>::new(&bus, &opts, "/a b", 0).is_err());
        assert!(Ros2TrackPublisher::new(&bus, &opts, "/tracks", "").is_err());
    }

    #[test]
    fn tracks_go_out_on_three_topics_with_attachments() {
        use quarry_trackers::lidar_people::LidarTrack;
        let bus = LocalBus::new();
        let opts = Ros2Options::default();
        let mut sub = bus.subscribe("0/quarry/tracks/**").unwrap();
        let mut p = Ros2TrackPublisher::new(&bus, &opts, "/quarry/tracks", "map").unwrap();
        let rows = [LidarTrack {
            id: 4,
            x: 1.0,
            y: 2.0,
            alpha: 0.0,
            vx: 0.5,
            vy: 0.0,
            support: 12,
            rms: 0.01,
            born: false,
            gate_replaced: false,
        }];
        for k in 0..2 {
            p.publish(
                &bus,
                &ClosedFrame {
                    frame: k,
                    t: TimeUs(50_000 * k as i64),
                    no_data: false,
                    epoch_unix_us: None,
                    points: &[],
                    tracks: &rows,
                },
            )
            .unwrap();
        }
        let mut got = Vec::new();
        while let Some(r) = sub.recv_timeout(Duration::ZERO).unwrap() {
            got.push(r);
        }
        assert_eq!(got.len(), 6);
        let arrays: Vec<_> = got
            .iter()
            .filter(|r| r.key.contains("TrackArray_"))
            .collect();
        assert_eq!(arrays.len(), 2);
        let a = TrackArray::from_cdr(&arrays[1].payload).unwrap();
        assert_eq!(a.tracks[0].id, 4);
        assert_eq!(a.header.frame_id, "map");
        let att = Attachment::decode(arrays[1].attachment.as_deref().unwrap()).unwrap();
        assert_eq!(att.sequence_number, 2);
        assert_eq!(att.source_timestamp, 50_000_000);
        assert_eq!(p.published(), 2);
    }
}
