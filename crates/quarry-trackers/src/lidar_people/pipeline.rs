//! The client and server halves of the distributed pipeline (spec 003 §1, §7): the client's
//! background subtraction ([`ClientPipeline`]), the server's fusion stage ([`Fusion`]; the
//! implementation over the wire format is quarry-net's `AssemblerFusion`) and tracking
//! ([`ServerPipeline`]). The in-process run over the room simulator is quarry-repro's.

use super::tracker::{FusedPoints, LidarTrack};
use crate::TrackerError;
use quarry_core::{
    BackgroundModel, BeamLabel, Clusterer, FrameIndex, MultiTargetTracker, PolarScan, Pose2,
    Registration2, SensorId, Stamp, TimeUs,
};
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
