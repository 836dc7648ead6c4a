//! Scene set-up: the scenario's trajectories (target, panel, pedestrian, distractor, robot),
//! the seeded wall posters and panel marks, the camera, and the noisy odometry.

use super::ScenarioId;
use super::texture::hsv;
use crate::SimError;
use nalgebra::Vector3;
use quarry_core::rng::stream;
use quarry_core::{CameraMount, PinholeIntrinsics, Pose2};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// What an actor is: the tracked target, a passing pedestrian, the occluding panel, or the
/// same-clothing distractor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Target,
    Pedestrian,
    Panel,
    Distractor,
}

/// A billboard in the scene and its trajectory.
#[derive(Debug, Clone)]
pub(super) struct Actor {
    pub(super) kind: Kind,
    /// World position per frame (`None` = absent).
    pub(super) pos: Vec<Option<[f64; 2]>>,
    /// Distance walked per frame (leg swing).
    pub(super) walked: Vec<f64>,
}

/// A coloured rectangle on a wall (`a` along the wall, `z` up).
#[derive(Debug, Clone, Copy)]
pub(super) struct Poster {
    pub(super) wall: u8,
    pub(super) a0: f64,
    pub(super) a1: f64,
    pub(super) z0: f64,
    pub(super) z1: f64,
    pub(super) rgb: [f64; 3],
}

/// A scenario instance: trajectories, layout and camera, ready to render any frame.
#[derive(Debug, Clone)]
pub struct RgbdScene {
    pub(super) id: ScenarioId,
    pub(super) seed: u64,
    /// Camera intrinsics (525, 525, 319.5, 239.5; 640×480).
    pub intrinsics: PinholeIntrinsics,
    /// Camera mount (0, 0, 1.0) m, no tilt.
    pub mount: CameraMount,
    /// Frame interval, seconds (1/30).
    pub dt: f64,
    pub(super) robot: Vec<Pose2>,
    pub(super) delta_noisy: Vec<Pose2>,
    pub(super) actors: Vec<Actor>,
    pub(super) posters: Vec<Poster>,
    pub(super) marks: [[f64; 4]; 3],
    pub(super) room: (f64, f64),
}

fn lerp_waypoints(w: &[(f64, f64, f64)], t: f64) -> [f64; 2] {
    if t <= w[0].0 {
        return [w[0].1, w[0].2];
    }
    for p in w.windows(2) {
        let (a, b) = (p[0], p[1]);
        if t <= b.0 {
            let s = (t - a.0) / (b.0 - a.0);
            return [a.1 + s * (b.1 - a.1), a.2 + s * (b.2 - a.2)];
        }
    }
    let l = w[w.len() - 1];
    [l.1, l.2]
}

impl RgbdScene {
    /// Builds scenario `id` with `seed`.
    ///
    /// # Errors
    /// None in practice for the built-in scenarios; kept fallible for configured scenes.
    #[allow(clippy::too_many_lines)]
    pub fn new(id: ScenarioId, seed: u64) -> Result<Self, SimError> {
        let n = id.n_frames();
        let dt = 1.0 / 30.0;
        #[allow(clippy::cast_precision_loss)]
        let time = |k: usize| k as f64 * dt;
        let target_w: Vec<(f64, f64, f64)> = match id {
            ScenarioId::S1StaticOcclusion | ScenarioId::S4Illumination => vec![
                (0.0, 3.0, -1.0),
                (2.0, 3.0, -1.0),
                (4.0, 3.0, 0.0),
                (8.0, 3.0, 0.0),
                (10.0, 3.0, 1.0),
                (12.0, 3.0, 1.0),
            ],
            ScenarioId::S2Scale => vec![(0.0, 2.5, 0.3), (4.0, 5.0, 0.3), (8.0, 2.5, -0.3)],
            ScenarioId::S3Follow => vec![
                (0.0, 2.5, 0.0),
                (4.0, 5.5, 0.0),
                (8.0, 7.5, 2.0),
                (12.0, 10.5, 2.0),
            ],
            ScenarioId::S5Distractor => vec![(0.0, 3.0, -1.2), (6.0, 3.0, 1.2)],
            ScenarioId::S6EgoRotation => vec![(0.0, 3.0, 0.0)],
        };
        let tpos: Vec<[f64; 2]> = (0..n).map(|k| lerp_waypoints(&target_w, time(k))).collect();
        let walked = |p: &[Option<[f64; 2]>]| {
            let mut d = 0.0;
            let mut out = Vec::with_capacity(p.len());
            for k in 0..p.len() {
                if k > 0
                    && let (Some(a), Some(b)) = (p[k - 1], p[k])
                {
                    d += (b[0] - a[0]).hypot(b[1] - a[1]);
                }
                out.push(d);
            }
            out
        };
        // robot
        let mut robot = vec![Pose2::identity(); n];
        match id {
            ScenarioId::S6EgoRotation => {
                for (k, r) in robot.iter_mut().enumerate() {
                    let t = time(k);
                    *r = Pose2::new(
                        0.0,
                        0.0,
                        (std::f64::consts::PI * t / 2.0).sin() / std::f64::consts::PI,
                    );
                }
            }
            ScenarioId::S3Follow => {
                for k in 1..n {
                    let p = robot[k - 1];
                    let rel =
                        p.apply_inverse(&nalgebra::Point2::new(tpos[k - 1][0], tpos[k - 1][1]));
                    let d = rel.x.hypot(rel.y);
                    let v = (0.8 * (d - 2.5)).clamp(0.0, 1.0);
                    let w = (1.5 * rel.y.atan2(rel.x)).clamp(-0.6, 0.6);
                    robot[k] = p.compose(&Pose2::from_unicycle(v, w, dt));
                }
            }
            _ => {}
        }
        let mut actors = vec![Actor {
            kind: Kind::Target,
            pos: tpos.iter().copied().map(Some).collect(),
            walked: Vec::new(),
        }];
        match id {
            ScenarioId::S1StaticOcclusion => {
                let w = [(2.0, 2.0, 2.4), (8.0, 2.0, -2.4)];
                actors.push(Actor {
                    kind: Kind::Panel,
                    pos: (0..n).map(|k| Some(lerp_waypoints(&w, time(k)))).collect(),
                    walked: Vec::new(),
                });
            }
            ScenarioId::S5Distractor => actors.push(Actor {
                kind: Kind::Distractor,
                pos: vec![Some([4.5, 0.4]); n],
                walked: Vec::new(),
            }),
            ScenarioId::S3Follow => {
                let kc = 180usize.min(n - 1);
                let r = robot[kc];
                let mid = [
                    f64::midpoint(r.x, tpos[kc][0]),
                    f64::midpoint(r.y, tpos[kc][1]),
                ];
                let los = [tpos[kc][0] - r.x, tpos[kc][1] - r.y];
                let l = los[0].hypot(los[1]).max(1e-9);
                let perp = [-los[1] / l, los[0] / l];
                actors.push(Actor {
                    kind: Kind::Pedestrian,
                    pos: (0..n)
                        .map(|k| {
                            let dtc = time(k) - 6.0;
                            (dtc.abs() <= 2.0)
                                .then(|| [mid[0] + perp[0] * dtc, mid[1] + perp[1] * dtc])
                        })
                        .collect(),
                    walked: Vec::new(),
                });
            }
            _ => {}
        }
        for a in &mut actors {
            a.walked = walked(&a.pos);
        }
        // layout
        let mut rng = stream(seed, &[0]);
        let room = (
            -2.0,
            if id == ScenarioId::S3Follow {
                14.0
            } else {
                10.0
            },
        );
        let mut posters = Vec::new();
        for wall in 0..4u8 {
            let (lo, hi) = if wall < 2 {
                (-5.0, 5.0)
            } else {
                (room.0, room.1)
            };
            for _ in 0..30 {
                let c: f64 = rng.random_range(lo..hi);
                let zc: f64 = rng.random_range(0.0..2.8);
                let w: f64 = rng.random_range(0.3..1.2);
                let h: f64 = rng.random_range(0.3..1.2);
                let col = hsv(
                    rng.random_range(0.0..360.0),
                    rng.random_range(0.4..0.9),
                    rng.random_range(0.4..0.9),
                );
                posters.push(Poster {
                    wall,
                    a0: c - w / 2.0,
                    a1: c + w / 2.0,
                    z0: zc - h / 2.0,
                    z1: zc + h / 2.0,
                    rgb: col,
                });
            }
        }
        let marks = [(); 3].map(|()| {
            let s0: f64 = rng.random_range(-0.4..0.3);
            let h0: f64 = rng.random_range(0.1..1.5);
            [
                s0,
                s0 + rng.random_range(0.05..0.15),
                h0,
                h0 + rng.random_range(0.05..0.25),
            ]
        });
        // odometry noise
        let mut orng = stream(seed, &[2]);
        let mut delta_noisy = vec![Pose2::identity(); n];
        for k in 1..n {
            let d = robot[k - 1].inverse().compose(&robot[k]);
            let ss = 0.05 * d.x.hypot(d.y) + 0.002;
            let st = 0.05 * d.theta.abs() + 0.002;
            let g = |r: &mut quarry_core::rng::SeededRng| -> f64 { StandardNormal.sample(r) };
            delta_noisy[k] = Pose2::new(
                d.x + ss * g(&mut orng),
                d.y + ss * g(&mut orng),
                d.theta + st * g(&mut orng),
            );
        }
        Ok(Self {
            id,
            seed,
            intrinsics: PinholeIntrinsics {
                fx: 525.0,
                fy: 525.0,
                cx: 319.5,
                cy: 239.5,
                width: 640,
                height: 480,
            },
            mount: CameraMount {
                t: Vector3::new(0.0, 0.0, 1.0),
                tilt: 0.0,
            },
            dt,
            robot,
            delta_noisy,
            actors,
            posters,
            marks,
            room,
        })
    }

    /// The scenario.
    #[must_use]
    pub fn id(&self) -> ScenarioId {
        self.id
    }

    /// Number of frames.
    #[must_use]
    pub fn len(&self) -> usize {
        self.robot.len()
    }

    /// Always false (every scenario has frames).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.robot.is_empty()
    }
}
