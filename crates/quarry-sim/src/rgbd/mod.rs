//! Synthetic RGB-D sequences for spec 001 (§5.2-5.3): a room, billboard people, an occluding
//! panel, a robot-mounted Kinect-like camera, and the six scenarios S1-S6 with ground truth.
//!
//! Everything is ray cast per pixel (the ray through the pixel centre, nearest hit wins). The
//! generator is deterministic in `(scenario, seed)`: scene layout (posters, panel marks) comes from
//! `stream(seed, [0])`, per-frame sensor noise from `stream(seed, [1, frame])`, odometry noise from
//! `stream(seed, [2])`. Frames are rendered on demand by [`RgbdScene::render`], so a sequence
//! never has to be held in memory.
//!
//! Simplifications against the spec, on purpose: the ceiling is plain wall colour; arms are part
//! of the torso rectangle; a pedestrian crossing in S3 exists only during its 4 s walk.
//!
//! ```
//! use quarry_sim::rgbd::{RgbdScene, ScenarioId};
//! let scene = RgbdScene::new(ScenarioId::S2Scale, 0)?;
//! assert_eq!(scene.len(), 240);
//! let f = scene.render(0)?;
//! let b = f.truth.amodal.unwrap();
//! // a 1.70 m person 2.5 m away: about 1.70 · 525 / 2.5 = 357 px tall
//! assert!((b.h - 357.0).abs() < 4.0, "{}", b.h);
//! assert_eq!(f.rgb.len(), 640 * 480 * 3);
//! # Ok::<(), quarry_sim::SimError>(())
//! ```

mod render;
mod scene;
mod texture;

pub use scene::RgbdScene;

use crate::SimError;
use quarry_core::{BBox, CoreError, Plane, Pose2};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// The six scenarios of spec §5.3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum ScenarioId {
    /// S1: static robot, a panel crosses in front of the target, the target turns.
    S1StaticOcclusion,
    /// S2: static robot, the target walks away to 5 m and back (2× scale change).
    S2Scale,
    /// S3: the robot follows the target (oracle follower); a pedestrian crosses between them.
    S3Follow,
    /// S4: S1 without the panel, illumination gain down to 0.5 and back.
    S4Illumination,
    /// S5: a distractor in identical clothing stands 1.5 m behind the target's path.
    S5Distractor,
    /// S6: target static, the robot turns in place; the detector is blacked out for frames
    /// 100-130.
    S6EgoRotation,
}

impl ScenarioId {
    /// All six, in order.
    pub const ALL: [ScenarioId; 6] = [
        ScenarioId::S1StaticOcclusion,
        ScenarioId::S2Scale,
        ScenarioId::S3Follow,
        ScenarioId::S4Illumination,
        ScenarioId::S5Distractor,
        ScenarioId::S6EgoRotation,
    ];

    /// The spec's name, e.g. `s1_static_occlusion`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ScenarioId::S1StaticOcclusion => "s1_static_occlusion",
            ScenarioId::S2Scale => "s2_scale",
            ScenarioId::S3Follow => "s3_follow",
            ScenarioId::S4Illumination => "s4_illumination",
            ScenarioId::S5Distractor => "s5_distractor",
            ScenarioId::S6EgoRotation => "s6_ego_rotation",
        }
    }

    /// Parses `s1` … `s6` or the full names.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] for an unknown name.
    pub fn from_name(s: &str) -> Result<Self, SimError> {
        let l = s.to_ascii_lowercase();
        Self::ALL
            .into_iter()
            .find(|id| id.name() == l || id.name()[..2] == l)
            .ok_or_else(|| {
                CoreError::invalid(
                    "scenario",
                    format!("unknown scenario {s:?}; expected s1..s6 or e.g. s1_static_occlusion"),
                )
                .into()
            })
    }

    /// Number of frames (30 Hz).
    #[must_use]
    pub fn n_frames(self) -> usize {
        match self {
            ScenarioId::S2Scale | ScenarioId::S6EgoRotation => 240,
            ScenarioId::S5Distractor => 180,
            _ => 360,
        }
    }
}

/// Ground truth of one frame.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct FrameTruth {
    /// Frame index (0-based).
    pub frame: usize,
    /// Time, seconds.
    pub t: f64,
    /// Amodal box of the target (other actors removed); `None` when out of view.
    pub amodal: Option<BBox>,
    /// Bounds of the visible part of the target; `None` when fully hidden.
    pub visible: Option<BBox>,
    /// `|visible| / |amodal|` in pixels, in `[0, 1]`.
    pub visibility: f64,
    /// The target's axis at h = 0.85 m in the robot frame (x forward, y left, z up).
    pub target_robot: [f64; 3],
    /// Robot pose in the world.
    pub robot_pose: Pose2,
    /// Exact odometry increment from the previous frame (identity at frame 0).
    pub delta: Pose2,
    /// The increment with proportional noise (σ = 0.05·|Δs| + 0.002 m, 0.05·|Δθ| + 0.002 rad).
    pub delta_noisy: Pose2,
    /// Mean speed over the increment, m/s.
    pub v: f64,
    /// Mean turn rate over the increment, rad/s.
    pub omega: f64,
    /// Test hook: the detector must report "no detection" on this frame (S6 blackout).
    pub detector_off: bool,
    /// Amodal box of the same-clothing distractor (S5), when in view.
    pub distractor: Option<BBox>,
}

/// One rendered frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbdSample {
    /// Interleaved RGB8, `640 · 480 · 3` bytes.
    pub rgb: Vec<u8>,
    /// Depth in metres, 1 mm quantised, 0 = none.
    pub depth_m: Plane<f32>,
    /// Ground truth.
    pub truth: FrameTruth,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_and_consistent() {
        let a = RgbdScene::new(ScenarioId::S1StaticOcclusion, 3).unwrap();
        let b = RgbdScene::new(ScenarioId::S1StaticOcclusion, 3).unwrap();
        let fa = a.render(150).unwrap();
        assert_eq!(fa, b.render(150).unwrap());
        let c = RgbdScene::new(ScenarioId::S1StaticOcclusion, 4).unwrap();
        assert_ne!(fa.rgb, c.render(150).unwrap().rgb);
        assert!(a.render(360).is_err());
        // the panel covers the target around t = 5 s (frame 150)
        assert!(fa.truth.visibility < 0.1, "{}", fa.truth.visibility);
        let f0 = a.render(0).unwrap();
        assert!(f0.truth.visibility > 0.99);
        let (am, vi) = (f0.truth.amodal.unwrap(), f0.truth.visible.unwrap());
        assert!(vi.left() >= am.left() && vi.right() <= am.right());
        // target 3 m ahead, 1 m left... no: y = -1 → right of centre
        assert!(am.cx > 319.5);
        assert!((am.h - 1.70 * 525.0 / 3.0).abs() < 4.0, "{}", am.h);
        // depth at the target centre ≈ 3.16 m (distance to the billboard), in range
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let z = *f0.depth_m.get(am.cx as u32, am.cy as u32).unwrap();
        assert!(z == 0.0 || (z - 3.16).abs() < 0.1, "{z}");
    }

    #[test]
    fn names_and_robot_motion() {
        assert_eq!(ScenarioId::from_name("s3").unwrap(), ScenarioId::S3Follow);
        assert_eq!(
            ScenarioId::from_name("s6_ego_rotation").unwrap(),
            ScenarioId::S6EgoRotation
        );
        assert!(ScenarioId::from_name("s9").is_err());
        let s6 = RgbdScene::new(ScenarioId::S6EgoRotation, 0).unwrap();
        let f = s6.render(120).unwrap().truth;
        assert!(f.detector_off);
        let yaw = (std::f64::consts::PI * 4.0 / 2.0).sin() / std::f64::consts::PI;
        assert!((f.robot_pose.theta - yaw).abs() < 1e-12);
        let s3 = RgbdScene::new(ScenarioId::S3Follow, 0).unwrap();
        let last = s3.render(359).unwrap().truth;
        assert!(last.robot_pose.x > 3.0, "{:?}", last.robot_pose);
        let d = last.target_robot[0].hypot(last.target_robot[1]);
        assert!(d < 5.0, "follower lost the target: {d}");
    }
}
