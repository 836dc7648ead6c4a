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
    ColorRGBA, Header, Marker, MarkerArray, Pose, Time, Track, TrackArray, Vector3,
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

pub use quarry_ros2::convert::{planar_track, static_tf, track_markers};

/// The `quarry_msgs/msg/TrackArray` of `tracks` at `t` in `frame`.
pub fn tracks_msg(t: TimeUs, frame: &str, tracks: &[Track]) -> TrackArray {
    quarry_ros2::convert::track_array(t, frame, tracks.to_vec())
}

/// [`track_markers`] (cylinders and id labels of `height` m).
pub fn markers_msg(t: TimeUs, frame: &str, tracks: &[Track], height: f64) -> MarkerArray {
    track_markers(t, frame, tracks, height)
}

/// Boxes (id, `[left, top, width, height]` in 0-based pixels, score) as a
/// `vision_msgs/msg/Detection2DArray` in `frame`: the box centre and size, class `person`, the
/// id in `id` (a track id for the trackers, which is how Foxglove labels them).
pub fn detections(
    t: TimeUs,
    frame: &str,
    boxes: impl Iterator<Item = (String, [f64; 4], f64)>,
) -> quarry_ros2::msgs::Detection2DArray {
    use quarry_ros2::msgs::{
        BoundingBox2D, Detection2D, Detection2DArray, ObjectHypothesis, ObjectHypothesisWithPose,
        Point2D, Pose2D,
    };
    let header = Header::new(time(t), frame);
    Detection2DArray {
        header: header.clone(),
        detections: boxes
            .map(|(id, b, score)| Detection2D {
                header: header.clone(),
                results: vec![ObjectHypothesisWithPose {
                    hypothesis: ObjectHypothesis {
                        class_id: "person".into(),
                        score,
                    },
                    ..ObjectHypothesisWithPose::default()
                }],
                bbox: BoundingBox2D {
                    center: Pose2D {
                        position: Point2D {
                            x: b[0] + 0.5 * b[2],
                            y: b[1] + 0.5 * b[3],
                        },
                        theta: 0.0,
                    },
                    size_x: b[2],
                    size_y: b[3],
                },
                id,
            })
            .collect(),
    }
}

/// Pixels (`color`: `L8`, `L16` (native-endian `u16` as bytes: depth in mm) or `Rgb8`) as a PNG
/// `sensor_msgs/msg/CompressedImage` in `frame` (fast compression).
///
/// # Errors
/// The encoder's (a buffer that does not hold `width` x `height` pixels).
pub fn png_image(
    t: TimeUs,
    frame: &str,
    pixels: &[u8],
    width: u32,
    height: u32,
    color: image::ExtendedColorType,
) -> Result<quarry_ros2::msgs::CompressedImage, CmdError> {
    use image::ImageEncoder;
    let mut data = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut data,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Sub,
    )
    .write_image(pixels, width, height, color)
    .map_err(|e| format!("PNG encoding for --mcap: {e}"))?;
    Ok(quarry_ros2::msgs::CompressedImage {
        header: Header::new(time(t), frame),
        format: "png".into(),
        data,
    })
}

/// One SLAM + tracking run as the recording sees it (times in seconds from the run's start).
#[derive(Debug, Default)]
pub struct SlamotRecording {
    /// Odometry per control step: (t, v, ω).
    pub odometry: Vec<(f64, f64, f64)>,
    /// Per epoch: (t, estimated pose, true pose if known).
    pub poses: Vec<(f64, Pose2, Option<Pose2>)>,
    /// Per epoch: (t, tracks).
    pub targets: Vec<(f64, Vec<Track>)>,
    /// Per epoch: (t, true target positions with their ids).
    pub targets_truth: Vec<(f64, Vec<Track>)>,
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
