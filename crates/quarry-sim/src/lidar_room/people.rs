//! Who walks the room: speed bands, motion kinds (waypoints, random walk, scripted routes,
//! stop-and-go, door visits), a person's specification, and the ground-truth body state (torso
//! ellipse and swinging arms) that the scanners see.

use super::raycast::{ray_circle, ray_ellipse};
use crate::SimError;
use quarry_core::{CoreError, Point2};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The three walking-speed bands of the paper's Table 2.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum SpeedBand {
    /// 0.10–0.25 m/s.
    Slow,
    /// 0.75–1.00 m/s.
    Mid,
    /// 1.30–1.50 m/s.
    Fast,
}

impl SpeedBand {
    /// The band's speed interval, m/s.
    pub fn range(self) -> (f64, f64) {
        match self {
            SpeedBand::Slow => (0.10, 0.25),
            SpeedBand::Mid => (0.75, 1.00),
            SpeedBand::Fast => (1.30, 1.50),
        }
    }

    /// `slow`, `mid` (or `normal`), `fast`.
    pub fn parse(s: &str) -> Result<Self, SimError> {
        match s {
            "slow" => Ok(SpeedBand::Slow),
            "mid" | "normal" => Ok(SpeedBand::Mid),
            "fast" => Ok(SpeedBand::Fast),
            _ => Err(CoreError::invalid("band", "expected slow, mid (normal) or fast").into()),
        }
    }

    /// Lower-case name (`slow`, `mid`, `fast`).
    pub fn name(self) -> &'static str {
        match self {
            SpeedBand::Slow => "slow",
            SpeedBand::Mid => "mid",
            SpeedBand::Fast => "fast",
        }
    }
}

/// How a person moves.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum Motion {
    /// Random waypoints in the walkable region, speed per leg from the band (default).
    Waypoint,
    /// Heading random walk (0.8 rad/√s), speed redrawn every 5 s.
    RandomWalk,
    /// A fixed closed route of waypoints at a fixed cruising speed (scripted scenarios). The
    /// walker brakes at [`ROUTE_ACCEL`](super::ROUTE_ACCEL) to a stop at each waypoint (0.3 m before it, as a
    /// waypoint walker switches targets), turns on the spot and accelerates back at the same
    /// rate: a person cannot reverse at walking speed within one step.
    Route(Vec<[f64; 2]>),
    /// [`Motion::Waypoint`] with a pause at every waypoint reached: the walker stands still
    /// (speed 0, no arm swing) for a duration drawn from `U(pause_s)` seconds, then picks the
    /// next waypoint (scenario `stop_and_go`, spec §5).
    StopAndGo {
        /// Pause interval `(lo, hi)`, seconds.
        pause_s: (f64, f64),
    },
    /// A visit through a door (scenario `door`): scripted legs in, random waypoints inside for
    /// a while, scripted legs out, then the person leaves the simulation for good.
    Visit(Visit),
}

/// The script of a [`Motion::Visit`]: in from the spawn point, waypoints inside, out again.
///
/// The scripted legs (`enter`, `exit`) are straight lines followed exactly (the walker turns on
/// the spot at each point); they skip the walkable-region check, so they may cross a door gap
/// and a corridor, but keep the 0.6 m person–person distance (the walker waits while blocked).
/// A visitor spawns, and starts its way out, only while no other person's centre is in `lane`,
/// so two people never meet head-on in the doorway.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Visit {
    /// The way in from the spawn point; the last point is in the walkable region, where the
    /// random waypoints start.
    pub enter: Vec<[f64; 2]>,
    /// Time spent inside, seconds, from the end of `enter` to the first waypoint switch after
    /// which the walker heads for `door_front`.
    pub stay_s: f64,
    /// The point in front of the door. When the stay is over, the walker makes it its next
    /// waypoint as soon as the straight way there is clear of obstacles (0.5 m).
    pub door_front: [f64; 2],
    /// The way out from `door_front`; at the last point the person vanishes (no longer in the
    /// ground truth, never respawned).
    pub exit: Vec<[f64; 2]>,
    /// The doorway box `[x0, x1, y0, y1]` that must be free of other people for the visitor to
    /// start its way out (it waits at `door_front`, which should lie outside this box, so
    /// that two waiting visitors do not wait for each other).
    pub lane: [f64; 4],
    /// The box that must be free of other people for the visitor to spawn: the doorway, the
    /// door front and the whole way out, so nobody walks in while someone walks out.
    pub spawn_box: [f64; 4],
}

impl Visit {
    pub(super) fn lane_free(&self, others: &[Point2]) -> bool {
        box_free(self.lane, others)
    }

    pub(super) fn spawn_free(&self, others: &[Point2]) -> bool {
        box_free(self.spawn_box, others)
    }

    pub(super) fn is_finite(&self) -> bool {
        let pts = |v: &[[f64; 2]]| v.iter().flatten().all(|x| x.is_finite());
        pts(&self.enter)
            && pts(&self.exit)
            && self.door_front.iter().all(|x| x.is_finite())
            && self.lane.iter().all(|x| x.is_finite())
            && self.spawn_box.iter().all(|x| x.is_finite())
            && self.stay_s.is_finite()
            && self.stay_s >= 0.0
    }
}

/// True when no point of `others` lies in the box `[x0, x1, y0, y1]`.
fn box_free(b: [f64; 4], others: &[Point2]) -> bool {
    let [x0, x1, y0, y1] = b;
    !others
        .iter()
        .any(|o| o.x >= x0 && o.x <= x1 && o.y >= y0 && o.y <= y1)
}

/// One simulated person.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct PersonSpec {
    /// Ground-truth id.
    pub id: u32,
    /// Speed interval (m/s).
    pub speed: (f64, f64),
    /// Motion kind.
    pub motion: Motion,
    /// Spawn position (`None` = drawn uniformly in free space, ≥ 1 m from the others).
    pub spawn: Option<[f64; 2]>,
    /// Spawn time, seconds.
    pub t_spawn: f64,
}

/// The state of one person at one instant (ground truth).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct PersonState {
    /// Ground-truth id.
    pub id: u32,
    /// Torso-ellipse centre.
    pub pos: Point2,
    /// Walking direction, radians.
    pub heading: f64,
    /// Current speed, m/s.
    pub speed: f64,
    /// Semi-axis across the shoulders, metres.
    pub a: f64,
    /// Semi-axis along the heading (chest depth), metres.
    pub b: f64,
    /// Arm-swing phase time, seconds.
    pub t: f64,
}

impl PersonState {
    /// The arm circles (centre), radius 0.045 m.
    pub fn arms(&self) -> [Point2; 2] {
        let v = self.speed;
        let amp = 0.15 * v.min(1.0);
        let fg = 0.5 + 0.5 * v;
        let swing = amp * (2.0 * PI * fg * self.t).sin();
        let (s, c) = self.heading.sin_cos();
        let fwd = [c, s];
        let lat = [-s, c];
        let off = self.a + 0.03;
        [
            Point2::new(
                self.pos.x + off * lat[0] + swing * fwd[0],
                self.pos.y + off * lat[1] + swing * fwd[1],
            ),
            Point2::new(
                self.pos.x - off * lat[0] - swing * fwd[0],
                self.pos.y - off * lat[1] - swing * fwd[1],
            ),
        ]
    }

    /// Nearest hit of a ray on the torso ellipse or the arms.
    pub fn ray(&self, o: Point2, d: [f64; 2], arms: bool) -> Option<f64> {
        // major axis (a) perpendicular to the heading
        let torso = ray_ellipse(o, d, self.pos, self.a, self.b, self.heading + PI / 2.0);
        if !arms {
            return torso;
        }
        let [l, r] = self.arms();
        [
            torso,
            ray_circle(o, d, l, 0.045),
            ray_circle(o, d, r, 0.045),
        ]
        .into_iter()
        .flatten()
        .min_by(f64::total_cmp)
    }
}
