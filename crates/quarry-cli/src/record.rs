//! `--mcap FILE`: a run recorded as MCAP with ROS 2 messages (CDR, `ros2msg` schemas), for
//! Foxglove, `ros2 bag`, Rerun and the Python `mcap` readers (quarry_ros2::McapRecorder).
//!
//! Every command that records uses the same topic names and frames (docs/ros2.md lists them):
//! inputs on `/scan…`, `/image`, `/odom…`; results on `/tracks` (`quarry_msgs/msg/TrackArray`),
//! `/tracks/markers` (`visualization_msgs/msg/MarkerArray`) or `/detections`
//! (`vision_msgs/msg/Detection2DArray`); ground truth under `/ground_truth/…`; the frames on
//! `/tf_static` and `/tf`.

use std::path::{Path, PathBuf};

use quarry_core::{Pose2, TimeUs};
use quarry_ros2::msgs::{
    ColorRGBA, Duration, Header, Marker, MarkerArray, Pose, TFMessage, Time, Track, TrackArray,
    TransformStamped, Vector3,
};
use quarry_ros2::{McapRecorder, Message};
use serde::Serialize;

use crate::output::CmdError;

/// An open `--mcap` recording.
#[derive(Debug)]
pub struct Mcap {
    rec: McapRecorder,
    path: PathBuf,
}

/// What `--json` reports about a recording.
#[derive(Debug, Clone, Serialize)]
pub struct McapInfo {
    /// The file.
    pub path: String,
    /// Messages written.
    pub messages: u64,
    /// Topics.
    pub topics: usize,
}

impl Mcap {
    /// Creates the file now, so that an unwritable path fails before the run.
    pub fn create(path: &Path) -> Result<Self, CmdError> {
        if path.is_dir() {
            return Err(format!(
                "--mcap {}: is a directory (give a file name, e.g. run.mcap)",
                path.display()
            )
            .into());
        }
        let rec = McapRecorder::create(path).map_err(|e| format!("--mcap {e}"))?;
        Ok(Self {
            rec,
            path: path.to_path_buf(),
        })
    }

    /// Opens `--mcap` if it was given.
    pub fn open(path: Option<&PathBuf>) -> Result<Option<Self>, CmdError> {
        path.map(|p| Self::create(p)).transpose()
    }

    /// Writes `msg` on `topic` at `t`.
    pub fn write<M: Message>(&mut self, topic: &str, t: TimeUs, msg: &M) -> Result<(), CmdError> {
        self.rec
            .write(topic, ns(t), msg)
            .map_err(|e| format!("--mcap {}: {e}", self.path.display()).into())
    }

    /// Writes a metadata record `name` (e.g. `quarry` with the run's seed and time origin).
    pub fn metadata(&mut self, name: &str, entries: &[(&str, String)]) -> Result<(), CmdError> {
        let map = entries
            .iter()
            .map(|(k, v)| ((*k).to_string(), v.clone()))
            .collect();
        self.rec
            .metadata(name, map)
            .map_err(|e| format!("--mcap {}: {e}", self.path.display()).into())
    }

    /// Closes the file (summary, footer).
    pub fn finish(self) -> Result<McapInfo, CmdError> {
        let s = self
            .rec
            .finish()
            .map_err(|e| format!("--mcap {}: {e}", self.path.display()))?;
        Ok(McapInfo {
            path: self.path.display().to_string(),
            messages: s.messages,
            topics: s.channels,
        })
    }
}

/// An MCAP log time (ns) for a quarry stamp; stamps before the epoch are clamped to 0.
pub fn ns(t: TimeUs) -> u64 {
    (t.0.max(0) as u64).saturating_mul(1000)
}

/// A ROS time for a quarry stamp.
pub fn time(t: TimeUs) -> Time {
    quarry_ros2::convert::time_of(t)
}

/// A distinct, stable colour per track id (golden-angle hue).
pub fn color_of(id: u32) -> ColorRGBA {
    let h = (f64::from(id) * 0.618_033_988_75).fract() * 6.0;
    let x = 1.0 - (h % 2.0 - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    ColorRGBA {
        r: r as f32,
        g: g as f32,
        b: b as f32,
        a: 0.9,
    }
}

/// One planar track for [`tracks_msg`] and [`markers_msg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarTrack {
    /// Id.
    pub id: u32,
    /// `Track::TENTATIVE`, `CONFIRMED` or `COASTING`.
    pub status: u8,
    /// Position (m).
    pub x: f64,
    /// Position (m).
    pub y: f64,
    /// Velocity (m/s; 0 if none).
    pub vx: f64,
    /// Velocity (m/s).
    pub vy: f64,
    /// Row-major position covariance (zeros if none).
    pub cov: [f64; 4],
    /// Existence probability or -1.
    pub existence: f64,
}

impl PlanarTrack {
    /// A confirmed track at (x, y) with velocity (vx, vy) and nothing else known.
    pub fn at(id: u32, x: f64, y: f64, vx: f64, vy: f64) -> Self {
        Self {
            id,
            status: Track::CONFIRMED,
            x,
            y,
            vx,
            vy,
            cov: [0.0; 4],
            existence: -1.0,
        }
    }
}

/// The `quarry_msgs/msg/TrackArray` of `tracks` at `t` in `frame`.
pub fn tracks_msg(t: TimeUs, frame: &str, tracks: &[PlanarTrack]) -> TrackArray {
    TrackArray {
        header: Header::new(time(t), frame),
        tracks: tracks
            .iter()
            .map(|p| Track {
                id: p.id,
                status: p.status,
                x: p.x,
                y: p.y,
                vx: p.vx,
                vy: p.vy,
                position_covariance: p.cov,
                existence: p.existence,
            })
            .collect(),
    }
}

/// Markers for a 3-D panel: a `DELETEALL` (so ended tracks vanish), then per track a cylinder of
/// `height` m and a text label with its id, coloured by id.
pub fn markers_msg(t: TimeUs, frame: &str, tracks: &[PlanarTrack], height: f64) -> MarkerArray {
    let header = Header::new(time(t), frame);
    let mut markers = vec![Marker {
        header: header.clone(),
        action: Marker::DELETEALL,
        ..Marker::default()
    }];
    for p in tracks {
        let base = Marker {
            header: header.clone(),
            id: p.id as i32,
            action: Marker::ADD,
            color: color_of(p.id),
            lifetime: Duration { sec: 1, nanosec: 0 },
            ..Marker::default()
        };
        markers.push(Marker {
            ns: "tracks".into(),
            r#type: Marker::CYLINDER,
            pose: Pose::planar(p.x, p.y, 0.0).with_z(0.5 * height),
            scale: Vector3 {
                x: 0.35,
                y: 0.35,
                z: height,
            },
            ..base.clone()
        });
        markers.push(Marker {
            ns: "track_ids".into(),
            r#type: Marker::TEXT_VIEW_FACING,
            pose: Pose::planar(p.x, p.y, 0.0).with_z(height + 0.2),
            scale: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.3,
            },
            text: p.id.to_string(),
            ..base
        });
    }
    MarkerArray { markers }
}

/// `/tf_static`: each child frame at its planar pose in `parent`.
pub fn static_tf(t: TimeUs, parent: &str, children: &[(String, Pose2)]) -> TFMessage {
    TFMessage {
        transforms: children
            .iter()
            .map(|(name, p)| TransformStamped::planar(time(t), parent, name, p.x, p.y, p.theta))
            .collect(),
    }
}

trait WithZ {
    fn with_z(self, z: f64) -> Self;
}

impl WithZ for Pose {
    fn with_z(mut self, z: f64) -> Self {
        self.position.z = z;
        self
    }
}

/// One SLAM + tracking run as the recording sees it (times in seconds from the run's start).
#[derive(Debug, Default)]
pub struct SlamotRecording {
    /// Odometry per control step: (t, v, ω).
    pub odometry: Vec<(f64, f64, f64)>,
    /// Per epoch: (t, estimated pose, true pose if known).
    pub poses: Vec<(f64, Pose2, Option<Pose2>)>,
    /// Per epoch: (t, tracks).
    pub targets: Vec<(f64, Vec<PlanarTrack>)>,
    /// Per epoch: (t, true target positions with their ids).
    pub targets_truth: Vec<(f64, Vec<PlanarTrack>)>,
    /// The final map: (landmark id, position).
    pub map: Vec<(u32, [f64; 2])>,
    /// The true landmarks, if known.
    pub landmarks_truth: Vec<(u32, [f64; 2])>,
}

fn secs(t: f64) -> TimeUs {
    TimeUs::from_secs_f64(t)
}

fn landmark_markers(t: TimeUs, ns: &str, lm: &[(u32, [f64; 2])], c: &ColorRGBA) -> MarkerArray {
    let header = Header::new(time(t), "map");
    MarkerArray {
        markers: lm
            .iter()
            .map(|(id, p)| Marker {
                header: header.clone(),
                ns: ns.into(),
                id: *id as i32,
                r#type: Marker::CYLINDER,
                action: Marker::ADD,
                pose: Pose::planar(p[0], p[1], 0.0),
                scale: Vector3 {
                    x: 0.15,
                    y: 0.15,
                    z: 0.3,
                },
                color: c.clone(),
                ..Marker::default()
            })
            .collect(),
    }
}

/// Writes a SLAM + tracking run: `/odom` (TwistStamped per control step, the input),
/// `/pose/estimate` and `/ground_truth/pose` (PoseStamped per epoch), `/tf` (map → base_link,
/// the estimate), `/targets` and `/ground_truth/targets` (TrackArray per epoch), and at the last
/// epoch `/map/landmarks` and `/ground_truth/landmarks` (MarkerArray, id = landmark id).
pub fn record_slamot(mut m: Mcap, r: &SlamotRecording) -> Result<McapInfo, CmdError> {
    use quarry_ros2::msgs::{PoseStamped, TwistStamped};
    for &(t, v, w) in &r.odometry {
        m.write(
            "/odom",
            secs(t),
            &TwistStamped::planar(time(secs(t)), "base_link", v, w),
        )?;
    }
    for (t, est, truth) in &r.poses {
        let ts = secs(*t);
        let pose = |p: &Pose2| PoseStamped {
            header: Header::new(time(ts), "map"),
            pose: Pose::planar(p.x, p.y, p.theta),
        };
        m.write("/pose/estimate", ts, &pose(est))?;
        if let Some(g) = truth {
            m.write("/ground_truth/pose", ts, &pose(g))?;
        }
        let tf = static_tf(ts, "map", &[("base_link".to_string(), *est)]);
        m.write("/tf", ts, &tf)?;
    }
    for (t, tr) in &r.targets {
        m.write("/targets", secs(*t), &tracks_msg(secs(*t), "map", tr))?;
    }
    for (t, tr) in &r.targets_truth {
        m.write(
            "/ground_truth/targets",
            secs(*t),
            &tracks_msg(secs(*t), "map", tr),
        )?;
    }
    let end = secs(r.poses.last().map_or(0.0, |p| p.0));
    let est = ColorRGBA {
        r: 0.9,
        g: 0.1,
        b: 0.1,
        a: 1.0,
    };
    let truth = ColorRGBA {
        r: 0.2,
        g: 0.2,
        b: 0.2,
        a: 0.6,
    };
    m.write(
        "/map/landmarks",
        end,
        &landmark_markers(end, "landmarks", &r.map, &est),
    )?;
    if !r.landmarks_truth.is_empty() {
        m.write(
            "/ground_truth/landmarks",
            end,
            &landmark_markers(end, "landmarks_truth", &r.landmarks_truth, &truth),
        )?;
    }
    m.finish()
}
