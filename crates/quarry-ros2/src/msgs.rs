//! The ROS 2 message types quarry reads and writes, field for field as in ROS 2 Jazzy (their
//! RIHS01 hashes equal Jazzy's; the tests check them against `rosbags`' Jazzy type store), plus
//! quarry's own track messages (`quarry_msgs`).

use crate::ros_msg;

/// Nanoseconds per second.
const NS: i64 = 1_000_000_000;

ros_msg! {
    /// `builtin_interfaces/msg/Time`: seconds and nanoseconds since the epoch (or a run's start).
    #[derive(Default)]
    pub struct Time = "builtin_interfaces/msg/Time" {
        /// Whole seconds.
        pub sec: i32,
        /// Nanoseconds, 0..1e9.
        pub nanosec: u32,
    }
}

impl Time {
    /// From nanoseconds (negative values count back from 0; seconds saturate at `i32`).
    pub fn from_nanos(ns: i64) -> Self {
        let sec = ns
            .div_euclid(NS)
            .clamp(i64::from(i32::MIN), i64::from(i32::MAX));
        Self {
            sec: sec as i32,
            nanosec: ns.rem_euclid(NS) as u32,
        }
    }
    /// From microseconds.
    pub fn from_micros(us: i64) -> Self {
        Self::from_nanos(us.saturating_mul(1000))
    }
    /// From seconds (non-finite values give 0).
    pub fn from_secs_f64(s: f64) -> Self {
        if s.is_finite() {
            Self::from_nanos((s * 1e9).round() as i64)
        } else {
            Self::default()
        }
    }
    /// As nanoseconds.
    pub fn nanos(&self) -> i64 {
        i64::from(self.sec) * NS + i64::from(self.nanosec)
    }
}

ros_msg! {
    /// `builtin_interfaces/msg/Duration`.
    #[derive(Default)]
    pub struct Duration = "builtin_interfaces/msg/Duration" {
        /// Whole seconds.
        pub sec: i32,
        /// Nanoseconds, 0..1e9.
        pub nanosec: u32,
    }
}

ros_msg! {
    /// `std_msgs/msg/Header`: a stamp and the coordinate frame of the data.
    #[derive(Default)]
    pub struct Header = "std_msgs/msg/Header" {
        /// Acquisition time.
        pub stamp: Time,
        /// Coordinate frame (`map`, `laser`, `camera`, ...).
        pub frame_id: String,
    }
}

impl Header {
    /// A header at `stamp` in `frame`.
    pub fn new(stamp: Time, frame: &str) -> Self {
        Self {
            stamp,
            frame_id: frame.to_string(),
        }
    }
}

ros_msg! {
    /// `std_msgs/msg/ColorRGBA` (components 0..1).
    #[derive(Default)]
    pub struct ColorRGBA = "std_msgs/msg/ColorRGBA" {
        /// Red.
        pub r: f32,
        /// Green.
        pub g: f32,
        /// Blue.
        pub b: f32,
        /// Opacity.
        pub a: f32,
    }
}

ros_msg! {
    /// `sensor_msgs/msg/LaserScan`: one planar scan, beams counter-clockwise from `angle_min`.
    #[derive(Default)]
    pub struct LaserScan = "sensor_msgs/msg/LaserScan" {
        /// Stamp of the first beam and the scanner's frame.
        pub header: Header,
        /// Angle of the first beam (rad).
        pub angle_min: f32,
        /// Angle of the last beam (rad).
        pub angle_max: f32,
        /// Angle between beams (rad).
        pub angle_increment: f32,
        /// Time between beams (s).
        pub time_increment: f32,
        /// Time between scans (s).
        pub scan_time: f32,
        /// Shortest valid range (m).
        pub range_min: f32,
        /// Longest valid range (m).
        pub range_max: f32,
        /// Ranges (m); values outside [range_min, range_max], NaN or inf are no return.
        pub ranges: Vec<f32>,
        /// Intensities (device units), empty or one per range.
        pub intensities: Vec<f32>,
    }
}

ros_msg! {
    /// `sensor_msgs/msg/CompressedImage`: an encoded image (`format` = `png`, `jpeg`).
    #[derive(Default)]
    pub struct CompressedImage = "sensor_msgs/msg/CompressedImage" {
        /// Stamp and camera frame.
        pub header: Header,
        /// `png` or `jpeg`.
        pub format: String,
        /// The encoded file.
        pub data: Vec<u8>,
    }
}

ros_msg! {
    /// `sensor_msgs/msg/Image`: a raw image.
    #[derive(Default)]
    pub struct Image = "sensor_msgs/msg/Image" {
        /// Stamp and camera frame.
        pub header: Header,
        /// Rows.
        pub height: u32,
        /// Columns.
        pub width: u32,
        /// Pixel encoding (`mono8`, `rgb8`, `16UC1`, ...).
        pub encoding: String,
        /// 1 if multi-byte pixels are big-endian.
        pub is_bigendian: u8,
        /// Bytes per row.
        pub step: u32,
        /// `height * step` bytes.
        pub data: Vec<u8>,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Point`.
    #[derive(Default)]
    pub struct Point = "geometry_msgs/msg/Point" {
        /// x (m).
        pub x: f64,
        /// y (m).
        pub y: f64,
        /// z (m).
        pub z: f64,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Vector3`.
    #[derive(Default)]
    pub struct Vector3 = "geometry_msgs/msg/Vector3" {
        /// x.
        pub x: f64,
        /// y.
        pub y: f64,
        /// z.
        pub z: f64,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Quaternion` (x, y, z, w; the identity is w = 1).
    pub struct Quaternion = "geometry_msgs/msg/Quaternion" {
        /// x.
        pub x: f64,
        /// y.
        pub y: f64,
        /// z.
        pub z: f64,
        /// w.
        pub w: f64,
    }
}

impl Default for Quaternion {
    /// The identity rotation.
    fn default() -> Self {
        Self {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl Default for PoseWithCovariance {
    /// The identity pose with a zero covariance.
    fn default() -> Self {
        Self {
            pose: Pose::default(),
            covariance: [0.0; 36],
        }
    }
}

impl Quaternion {
    /// A rotation by `yaw` (rad) about z.
    pub fn from_yaw(yaw: f64) -> Self {
        let (s, c) = (0.5 * yaw).sin_cos();
        Self {
            x: 0.0,
            y: 0.0,
            z: s,
            w: c,
        }
    }
    /// The rotation about z (for a quaternion that is one).
    pub fn yaw(&self) -> f64 {
        2.0 * self.z.atan2(self.w)
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Pose`.
    #[derive(Default)]
    pub struct Pose = "geometry_msgs/msg/Pose" {
        /// Position.
        pub position: Point,
        /// Orientation.
        pub orientation: Quaternion,
    }
}

impl Pose {
    /// A planar pose (x, y, heading) at z = 0.
    pub fn planar(x: f64, y: f64, yaw: f64) -> Self {
        Self {
            position: Point { x, y, z: 0.0 },
            orientation: Quaternion::from_yaw(yaw),
        }
    }
}

ros_msg! {
    /// `geometry_msgs/msg/PoseStamped`.
    #[derive(Default)]
    pub struct PoseStamped = "geometry_msgs/msg/PoseStamped" {
        /// Stamp and frame.
        pub header: Header,
        /// The pose.
        pub pose: Pose,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/PoseArray`.
    #[derive(Default)]
    pub struct PoseArray = "geometry_msgs/msg/PoseArray" {
        /// Stamp and frame.
        pub header: Header,
        /// The poses.
        pub poses: Vec<Pose>,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/PoseWithCovariance` (row-major 6 x 6 over x, y, z, roll, pitch, yaw).
    pub struct PoseWithCovariance = "geometry_msgs/msg/PoseWithCovariance" {
        /// The pose.
        pub pose: Pose,
        /// Its covariance.
        pub covariance: [f64; 36],
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Twist`: linear and angular velocity.
    #[derive(Default)]
    pub struct Twist = "geometry_msgs/msg/Twist" {
        /// Linear velocity (m/s).
        pub linear: Vector3,
        /// Angular velocity (rad/s).
        pub angular: Vector3,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/TwistStamped`: e.g. a robot's odometry command (v along x, ω about z).
    #[derive(Default)]
    pub struct TwistStamped = "geometry_msgs/msg/TwistStamped" {
        /// Stamp and frame (quarry: `base_link`).
        pub header: Header,
        /// The velocity.
        pub twist: Twist,
    }
}

impl TwistStamped {
    /// A planar velocity command: `v` forward, `omega` about z.
    pub fn planar(stamp: Time, frame: &str, v: f64, omega: f64) -> Self {
        Self {
            header: Header::new(stamp, frame),
            twist: Twist {
                linear: Vector3 {
                    x: v,
                    y: 0.0,
                    z: 0.0,
                },
                angular: Vector3 {
                    x: 0.0,
                    y: 0.0,
                    z: omega,
                },
            },
        }
    }
}

ros_msg! {
    /// `geometry_msgs/msg/Transform`.
    #[derive(Default)]
    pub struct Transform = "geometry_msgs/msg/Transform" {
        /// Translation.
        pub translation: Vector3,
        /// Rotation.
        pub rotation: Quaternion,
    }
}

ros_msg! {
    /// `geometry_msgs/msg/TransformStamped`: the pose of `child_frame_id` in `header.frame_id`.
    #[derive(Default)]
    pub struct TransformStamped = "geometry_msgs/msg/TransformStamped" {
        /// Stamp and parent frame.
        pub header: Header,
        /// The child frame.
        pub child_frame_id: String,
        /// The transform.
        pub transform: Transform,
    }
}

impl TransformStamped {
    /// A planar transform: `child` at (x, y, yaw) in `parent`.
    pub fn planar(stamp: Time, parent: &str, child: &str, x: f64, y: f64, yaw: f64) -> Self {
        Self {
            header: Header::new(stamp, parent),
            child_frame_id: child.to_string(),
            transform: Transform {
                translation: Vector3 { x, y, z: 0.0 },
                rotation: Quaternion::from_yaw(yaw),
            },
        }
    }
}

ros_msg! {
    /// `tf2_msgs/msg/TFMessage`: what `/tf` and `/tf_static` carry.
    #[derive(Default)]
    pub struct TFMessage = "tf2_msgs/msg/TFMessage" {
        /// The transforms.
        pub transforms: Vec<TransformStamped>,
    }
}

ros_msg! {
    /// `visualization_msgs/msg/UVCoordinate`.
    #[derive(Default)]
    pub struct UVCoordinate = "visualization_msgs/msg/UVCoordinate" {
        /// u.
        pub u: f32,
        /// v.
        pub v: f32,
    }
}

ros_msg! {
    /// `visualization_msgs/msg/MeshFile`.
    #[derive(Default)]
    pub struct MeshFile = "visualization_msgs/msg/MeshFile" {
        /// File name.
        pub filename: String,
        /// File contents.
        pub data: Vec<u8>,
    }
}

ros_msg! {
    /// `visualization_msgs/msg/Marker` (Jazzy's fields). quarry fills header, ns, id, type,
    /// action, pose, scale, color, lifetime and text; the mesh and texture fields stay empty.
    #[derive(Default)]
    pub struct Marker = "visualization_msgs/msg/Marker" {
        /// Stamp and frame.
        pub header: Header,
        /// Namespace (with `id`, identifies the marker).
        pub ns: String,
        /// Id within the namespace (quarry: the track id).
        pub id: i32,
        /// Shape: [`Marker::CYLINDER`], [`Marker::TEXT_VIEW_FACING`], [`Marker::LINE_STRIP`], ...
        pub r#type: i32,
        /// [`Marker::ADD`] or [`Marker::DELETEALL`], ...
        pub action: i32,
        /// Pose.
        pub pose: Pose,
        /// Size (m).
        pub scale: Vector3,
        /// Colour.
        pub color: ColorRGBA,
        /// How long it stays (0 = until replaced).
        pub lifetime: Duration,
        /// Re-transform with the frame over time.
        pub frame_locked: bool,
        /// Points of line and list types.
        pub points: Vec<Point>,
        /// Per-point colours.
        pub colors: Vec<ColorRGBA>,
        /// Texture resource URI.
        pub texture_resource: String,
        /// Embedded texture.
        pub texture: CompressedImage,
        /// Texture coordinates.
        pub uv_coordinates: Vec<UVCoordinate>,
        /// Text of `TEXT_VIEW_FACING`.
        pub text: String,
        /// Mesh resource URI.
        pub mesh_resource: String,
        /// Embedded mesh.
        pub mesh_file: MeshFile,
        /// Use the mesh's own materials.
        pub mesh_use_embedded_materials: bool,
    }
}

impl Marker {
    /// Marker type `CYLINDER`.
    pub const CYLINDER: i32 = 3;
    /// Marker type `LINE_STRIP`.
    pub const LINE_STRIP: i32 = 4;
    /// Marker type `POINTS` (squares of `scale.x` by `scale.y`).
    pub const POINTS: i32 = 8;
    /// Marker type `SPHERE_LIST`.
    pub const SPHERE_LIST: i32 = 7;
    /// Marker type `TEXT_VIEW_FACING`.
    pub const TEXT_VIEW_FACING: i32 = 9;
    /// Action `ADD` (also `MODIFY`).
    pub const ADD: i32 = 0;
    /// Action `DELETEALL`: clears the namespace's markers.
    pub const DELETEALL: i32 = 3;
}

ros_msg! {
    /// `visualization_msgs/msg/MarkerArray`.
    #[derive(Default)]
    pub struct MarkerArray = "visualization_msgs/msg/MarkerArray" {
        /// The markers.
        pub markers: Vec<Marker>,
    }
}

ros_msg! {
    /// `vision_msgs/msg/Point2D` (vision_msgs 4, Jazzy).
    #[derive(Default)]
    pub struct Point2D = "vision_msgs/msg/Point2D" {
        /// x (px).
        pub x: f64,
        /// y (px).
        pub y: f64,
    }
}

ros_msg! {
    /// `vision_msgs/msg/Pose2D`.
    #[derive(Default)]
    pub struct Pose2D = "vision_msgs/msg/Pose2D" {
        /// Position.
        pub position: Point2D,
        /// Rotation (rad).
        pub theta: f64,
    }
}

ros_msg! {
    /// `vision_msgs/msg/BoundingBox2D`: centre and size in pixels.
    #[derive(Default)]
    pub struct BoundingBox2D = "vision_msgs/msg/BoundingBox2D" {
        /// Centre.
        pub center: Pose2D,
        /// Width (px).
        pub size_x: f64,
        /// Height (px).
        pub size_y: f64,
    }
}

ros_msg! {
    /// `vision_msgs/msg/ObjectHypothesis`.
    #[derive(Default)]
    pub struct ObjectHypothesis = "vision_msgs/msg/ObjectHypothesis" {
        /// Class (quarry: `person`).
        pub class_id: String,
        /// Score.
        pub score: f64,
    }
}

ros_msg! {
    /// `vision_msgs/msg/ObjectHypothesisWithPose`.
    #[derive(Default)]
    pub struct ObjectHypothesisWithPose = "vision_msgs/msg/ObjectHypothesisWithPose" {
        /// Class and score.
        pub hypothesis: ObjectHypothesis,
        /// Pose (unused by image trackers).
        pub pose: PoseWithCovariance,
    }
}

ros_msg! {
    /// `vision_msgs/msg/Detection2D`: one box; quarry's image trackers put the track id in `id`.
    #[derive(Default)]
    pub struct Detection2D = "vision_msgs/msg/Detection2D" {
        /// Stamp and camera frame.
        pub header: Header,
        /// Class hypotheses.
        pub results: Vec<ObjectHypothesisWithPose>,
        /// The box.
        pub bbox: BoundingBox2D,
        /// The track id (decimal).
        pub id: String,
    }
}

ros_msg! {
    /// `vision_msgs/msg/Detection2DArray`.
    #[derive(Default)]
    pub struct Detection2DArray = "vision_msgs/msg/Detection2DArray" {
        /// Stamp and camera frame.
        pub header: Header,
        /// The boxes.
        pub detections: Vec<Detection2D>,
    }
}

ros_msg! {
    /// `quarry_msgs/msg/Track`: one track of a quarry tracker, in the array's frame (m, m/s).
    /// The `.msg` file is `crates/quarry-ros2/msg/Track.msg`.
    #[derive(Default)]
    pub struct Track = "quarry_msgs/msg/Track" {
        /// Track id (unique within a run).
        pub id: u32,
        /// [`Track::TENTATIVE`], [`Track::CONFIRMED`] or [`Track::COASTING`].
        pub status: u8,
        /// Position x (m).
        pub x: f64,
        /// Position y (m).
        pub y: f64,
        /// Velocity x (m/s; 0 where the tracker has none).
        pub vx: f64,
        /// Velocity y (m/s).
        pub vy: f64,
        /// Row-major 2 x 2 covariance of (x, y) (m²; zeros where the tracker has none).
        pub position_covariance: [f64; 4],
        /// Existence probability, or -1 where the tracker keeps none.
        pub existence: f64,
    }
}

impl Track {
    /// Status: not confirmed yet.
    pub const TENTATIVE: u8 = 0;
    /// Status: confirmed and updated this step.
    pub const CONFIRMED: u8 = 1;
    /// Status: confirmed, not updated this step (predicted).
    pub const COASTING: u8 = 2;
}

ros_msg! {
    /// `quarry_msgs/msg/TrackArray`: a tracker's tracks at one time.
    #[derive(Default)]
    pub struct TrackArray = "quarry_msgs/msg/TrackArray" {
        /// Stamp and frame of the positions.
        pub header: Header,
        /// The tracks.
        pub tracks: Vec<Track>,
    }
}
