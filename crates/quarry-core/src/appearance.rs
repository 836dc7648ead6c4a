//! Appearance models and camera geometry (spec 001).

use crate::{BBox, CoreError, Pose2};
use nalgebra::Vector3;

/// A region appearance model: describe a region, score it against the template, learn.
pub trait AppearanceModel {
    /// Per-frame precomputed maps (bin indices, texture classes, depth).
    type FrameFeatures;
    /// The description of one region.
    type Descriptor;
    /// The similarity of a descriptor to the template.
    type Score;
    /// Describes `region` of a frame.
    fn describe(
        &self,
        f: &Self::FrameFeatures,
        region: &BBox,
    ) -> Result<Self::Descriptor, CoreError>;
    /// Scores a descriptor against the template.
    fn score(&self, d: &Self::Descriptor) -> Self::Score;
    /// Updates the template with `d` (the caller decides *whether*, e.g. occlusion gating).
    fn learn(&mut self, d: &Self::Descriptor, s: &Self::Score);
}

/// Pinhole camera intrinsics.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PinholeIntrinsics {
    /// Focal length in pixels, x.
    pub fx: f64,
    /// Focal length in pixels, y.
    pub fy: f64,
    /// Principal point x.
    pub cx: f64,
    /// Principal point y.
    pub cy: f64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
}

impl PinholeIntrinsics {
    /// The back-projection of pixel `(u, v)` at depth `z` (camera frame, z forward, x right, y
    /// down).
    pub fn back_project(&self, u: f64, v: f64, z: f64) -> Vector3<f64> {
        Vector3::new((u - self.cx) * z / self.fx, (v - self.cy) * z / self.fy, z)
    }
    /// The projection of a camera-frame point, or `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }
}

/// The camera's mount on the robot (robot <- camera): translation and downward tilt (radians).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CameraMount {
    /// Camera centre in the robot frame (x forward, y left, z up), metres.
    pub t: Vector3<f64>,
    /// Downward tilt of the optical axis, radians.
    pub tilt: f64,
}

/// The robot's own motion over one frame interval.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum EgoMotion {
    /// The robot did not move (or no odometry is available).
    #[default]
    None,
    /// Speed `v` (m/s) and turn rate `omega` (rad/s), integrated by [`Pose2::from_unicycle`].
    Velocity {
        /// Forward speed, m/s.
        v: f64,
        /// Turn rate, rad/s.
        omega: f64,
    },
    /// A pose increment from odometry, in the previous robot frame.
    Delta(Pose2),
}

impl EgoMotion {
    /// The pose increment over `dt` seconds.
    pub fn delta(&self, dt: f64) -> Pose2 {
        match *self {
            EgoMotion::None => Pose2::identity(),
            EgoMotion::Velocity { v, omega } => Pose2::from_unicycle(v, omega, dt),
            EgoMotion::Delta(p) => p,
        }
    }
}
