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

use crate::SimError;
use nalgebra::Vector3;
use quarry_core::rng::stream;
use quarry_core::{BBox, CameraMount, CoreError, PinholeIntrinsics, Plane, Pose2};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
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

/// An actor in view: kind, position, normal towards the camera, lateral axis, distance walked.
type ActiveActor = (Kind, [f64; 2], [f64; 2], [f64; 2], f64);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Target,
    Pedestrian,
    Panel,
    Distractor,
}

#[derive(Debug, Clone)]
struct Actor {
    kind: Kind,
    /// World position per frame (`None` = absent).
    pos: Vec<Option<[f64; 2]>>,
    /// Distance walked per frame (leg swing).
    walked: Vec<f64>,
}

#[derive(Debug, Clone, Copy)]
struct Poster {
    wall: u8,
    a0: f64,
    a1: f64,
    z0: f64,
    z1: f64,
    rgb: [f64; 3],
}

/// A scenario instance: trajectories, layout and camera, ready to render any frame.
#[derive(Debug, Clone)]
pub struct RgbdScene {
    id: ScenarioId,
    seed: u64,
    /// Camera intrinsics (525, 525, 319.5, 239.5; 640×480).
    pub intrinsics: PinholeIntrinsics,
    /// Camera mount (0, 0, 1.0) m, no tilt.
    pub mount: CameraMount,
    /// Frame interval, seconds (1/30).
    pub dt: f64,
    robot: Vec<Pose2>,
    delta_noisy: Vec<Pose2>,
    actors: Vec<Actor>,
    posters: Vec<Poster>,
    marks: [[f64; 4]; 3],
    room: (f64, f64),
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

fn hsv(h: f64, s: f64, v: f64) -> [f64; 3] {
    let c = v * s;
    let hp = (h.rem_euclid(360.0)) / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [(r + m) * 255.0, (g + m) * 255.0, (b + m) * 255.0]
}

/// Value noise at 0.05 m cells, ±12 grey levels, bilinear.
fn vnoise(a: f64, b: f64, salt: u64) -> f64 {
    let (fa, fb) = (a / 0.05, b / 0.05);
    let (ia, ib) = (fa.floor(), fb.floor());
    let (ta, tb) = (fa - ia, fb - ib);
    #[allow(clippy::cast_possible_truncation)]
    let lat = |i: f64, j: f64| {
        let mut z = (i as i64 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as i64 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ salt;
        z = (z ^ (z >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^= z >> 29;
        #[allow(clippy::cast_precision_loss)]
        let u = (z >> 11) as f64 / (1u64 << 53) as f64;
        24.0 * u - 12.0
    };
    let v00 = lat(ia, ib);
    let v10 = lat(ia + 1.0, ib);
    let v01 = lat(ia, ib + 1.0);
    let v11 = lat(ia + 1.0, ib + 1.0);
    (v00 * (1.0 - ta) + v10 * ta) * (1.0 - tb) + (v01 * (1.0 - ta) + v11 * ta) * tb
}

fn add(c: [f64; 3], n: f64) -> [f64; 3] {
    [c[0] + n, c[1] + n, c[2] + n]
}

/// Is `(s, h)` on a person silhouette (spec §5.2)? `d` is the distance walked.
fn person_hit(s: f64, h: f64, d: f64) -> bool {
    let head = (s / 0.09).powi(2) + ((h - 1.58) / 0.12).powi(2) <= 1.0;
    let neck = s.abs() <= 0.05 && (1.45..=1.48).contains(&h);
    let torso = s.abs() <= 0.22 && (0.85..=1.45).contains(&h);
    let dl = 0.04 * (std::f64::consts::TAU * d / 1.2).sin();
    let legs = (0.0..0.85).contains(&h)
        && ((0.02..=0.18).contains(&(s - dl).abs()) || (0.02..=0.18).contains(&(s + dl).abs()));
    head || neck || torso || legs
}

fn shirt_target(s: f64, h: f64, alpha: f64) -> [f64; 3] {
    let c1 = hsv(210.0, 0.7, 0.8);
    let c2 = hsv(40.0, 0.6, 0.9);
    let front = if (h / 0.10).floor() as i64 % 2 == 0 {
        c1
    } else {
        c2
    };
    let back = if s.abs() <= 0.05 || (h / 0.20).floor() as i64 % 2 != 0 {
        c2
    } else {
        c1
    };
    [0, 1, 2].map(|i| (1.0 - alpha) * front[i] + alpha * back[i])
}

fn person_colour(kind: Kind, s: f64, h: f64, alpha: f64) -> [f64; 3] {
    if h > 1.62 && (s / 0.09).powi(2) + ((h - 1.58) / 0.12).powi(2) <= 1.0 {
        return hsv(20.0, 0.5, 0.2);
    }
    if h > 1.45 {
        return hsv(25.0, 0.45, 0.85);
    }
    match kind {
        Kind::Pedestrian => {
            if h >= 0.85 {
                let k = (s / 0.08).floor() as i64 + (h / 0.08).floor() as i64;
                if k.rem_euclid(2) == 0 {
                    hsv(0.0, 0.7, 0.8)
                } else {
                    hsv(0.0, 0.0, 0.95)
                }
            } else {
                hsv(220.0, 0.5, 0.5)
            }
        }
        _ => {
            if h >= 0.85 {
                shirt_target(s, h, alpha)
            } else {
                add(hsv(0.0, 0.0, 0.2), vnoise(s, h, 7))
            }
        }
    }
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

    fn gain(&self, t: f64) -> f64 {
        if self.id != ScenarioId::S4Illumination {
            return 1.0;
        }
        if t < 3.0 {
            1.0
        } else if t < 5.0 {
            1.0 - 0.25 * (t - 3.0)
        } else if t < 8.0 {
            0.5
        } else if t < 10.0 {
            0.5 + 0.25 * (t - 8.0)
        } else {
            1.0
        }
    }

    fn alpha(&self, t: f64) -> f64 {
        if self.id == ScenarioId::S1StaticOcclusion || self.id == ScenarioId::S4Illumination {
            ((t - 9.0) / 2.0).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }

    /// Background colour and depth-ray parameter of a world ray.
    fn background(&self, o: [f64; 3], d: [f64; 3]) -> (f64, [f64; 3]) {
        let mut best = f64::INFINITY;
        let mut hit = 0u8;
        let planes = [
            (0usize, self.room.1, 0u8), // back wall x = max
            (0, self.room.0, 1),
            (1, 5.0, 2),
            (1, -5.0, 3),
            (2, 0.0, 4), // floor
            (2, 2.8, 5), // ceiling
        ];
        for (axis, val, id) in planes {
            if d[axis].abs() < 1e-12 {
                continue;
            }
            let t = (val - o[axis]) / d[axis];
            if t > 1e-9 && t < best {
                best = t;
                hit = id;
            }
        }
        let p = [o[0] + best * d[0], o[1] + best * d[1], o[2] + best * d[2]];
        let col = match hit {
            4 => {
                let k = (p[0] / 0.5).floor() as i64 + (p[1] / 0.5).floor() as i64;
                let base = if k.rem_euclid(2) == 0 {
                    [140.0, 140.0, 135.0]
                } else {
                    [100.0, 100.0, 95.0]
                };
                add(base, vnoise(p[0], p[1], 1))
            }
            5 => [200.0, 190.0, 170.0],
            w => {
                // wall index for posters: 0,1 = x walls (coordinate y), 2,3 = y walls (coordinate x)
                let (widx, a) = match w {
                    0 => (0u8, p[1]),
                    1 => (1, p[1]),
                    2 => (2, p[0]),
                    _ => (3, p[0]),
                };
                let mut c = [200.0, 190.0, 170.0];
                for ps in self.posters.iter().filter(|ps| ps.wall == widx) {
                    if a >= ps.a0 && a <= ps.a1 && p[2] >= ps.z0 && p[2] <= ps.z1 {
                        c = ps.rgb;
                    }
                }
                if w == 0
                    && matches!(
                        self.id,
                        ScenarioId::S1StaticOcclusion | ScenarioId::S5Distractor
                    )
                    && (0.25..=0.75).contains(&p[1])
                    && (1.1..=1.7).contains(&p[2])
                {
                    c = shirt_target(p[1] - 0.5, p[2], 0.0);
                }
                add(c, vnoise(a, p[2], 2 + u64::from(widx)))
            }
        };
        (best, col)
    }

    /// Renders frame `k`.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] for `k ≥ len()`.
    #[allow(clippy::too_many_lines, clippy::cast_precision_loss)]
    pub fn render(&self, k: usize) -> Result<RgbdSample, SimError> {
        if k >= self.len() {
            return Err(CoreError::invalid(
                "frame",
                format!("{k} beyond the {} frames of {}", self.len(), self.id.name()),
            )
            .into());
        }
        let t = k as f64 * self.dt;
        let r = self.robot[k];
        let (c, s) = (r.theta.cos(), r.theta.sin());
        let cam = [
            r.x + c * self.mount.t.x - s * self.mount.t.y,
            r.y + s * self.mount.t.x + c * self.mount.t.y,
            self.mount.t.z,
        ];
        let intr = self.intrinsics;
        let (w, h) = (intr.width, intr.height);
        let alpha = self.alpha(t);
        // active actors: (index, kind, position, normal n, lateral l, walked)
        let acts: Vec<ActiveActor> = self
            .actors
            .iter()
            .filter_map(|a| {
                let p = a.pos[k]?;
                let nx = cam[0] - p[0];
                let ny = cam[1] - p[1];
                let l = nx.hypot(ny).max(1e-9);
                let n = [nx / l, ny / l];
                Some((a.kind, p, n, [-n[1], n[0]], a.walked[k]))
            })
            .collect();
        let npx = w as usize * h as usize;
        let mut col = vec![[0.0f64; 3]; npx];
        let mut z_clean = vec![0.0f64; npx];
        let mut id_buf = vec![0u8; npx];
        let (mut amodal, mut visible) = (Bounds::default(), Bounds::default());
        let mut distr = Bounds::default();
        for v in 0..h {
            for u in 0..w {
                let i = v as usize * w as usize + u as usize;
                // camera ray (x right, y down, z forward) -> robot (x fwd, y left, z up) -> world
                let dc = [
                    (f64::from(u) - intr.cx) / intr.fx,
                    (f64::from(v) - intr.cy) / intr.fy,
                ];
                let dr = [1.0, -dc[0], -dc[1]];
                let d = [c * dr[0] - s * dr[1], s * dr[0] + c * dr[1], dr[2]];
                let (mut best, mut colour) = self.background(cam, d);
                let mut id = 0u8;
                for (ai, &(kind, p, n, l, walk)) in acts.iter().enumerate() {
                    let den = d[0] * n[0] + d[1] * n[1];
                    if den >= -1e-12 {
                        continue;
                    }
                    let tt = ((p[0] - cam[0]) * n[0] + (p[1] - cam[1]) * n[1]) / den;
                    if tt <= 0.0 {
                        continue;
                    }
                    let hp = [cam[0] + tt * d[0], cam[1] + tt * d[1], cam[2] + tt * d[2]];
                    let sl = (hp[0] - p[0]) * l[0] + (hp[1] - p[1]) * l[1];
                    let hh = hp[2];
                    let (on, relief) = if kind == Kind::Panel {
                        (sl.abs() <= 0.45 && (0.0..=1.8).contains(&hh), 0.0)
                    } else {
                        let on = person_hit(sl, hh, walk);
                        let q = (sl / 0.25).clamp(-1.0, 1.0);
                        (on, 0.12 * (1.0 - (1.0 - q * q).sqrt()))
                    };
                    if !on {
                        continue;
                    }
                    let z = tt + relief;
                    if kind == Kind::Target {
                        amodal.add(u, v);
                    }
                    if kind == Kind::Distractor {
                        distr.add(u, v);
                    }
                    if z < best {
                        best = z;
                        id = u8::try_from(ai + 1).unwrap_or(u8::MAX);
                        colour = match kind {
                            Kind::Panel => {
                                let dark = self
                                    .marks
                                    .iter()
                                    .any(|m| sl >= m[0] && sl <= m[1] && hh >= m[2] && hh <= m[3]);
                                if dark {
                                    [40.0, 35.0, 30.0]
                                } else {
                                    add(hsv(30.0, 0.5, 0.6), vnoise(sl, hh, 9))
                                }
                            }
                            _ => person_colour(
                                kind,
                                sl,
                                hh,
                                if kind == Kind::Target { alpha } else { 0.0 },
                            ),
                        };
                    }
                }
                if id == 1 {
                    visible.add(u, v);
                }
                col[i] = colour;
                z_clean[i] = best;
                id_buf[i] = id;
            }
        }
        // sensor
        let mut rng = stream(self.seed, &[1, k as u64]);
        let g = self.gain(t);
        let mut rgb = Vec::with_capacity(3 * npx);
        for c in &col {
            for ch in c {
                let n: f64 = StandardNormal.sample(&mut rng);
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                rgb.push((ch * g + 2.0 * n).round().clamp(0.0, 255.0) as u8);
            }
        }
        let mut depth = vec![0.0f32; npx];
        for v in 0..h as usize {
            for u in 0..w as usize {
                let i = v * w as usize + u;
                let z = z_clean[i];
                let n: f64 = StandardNormal.sample(&mut rng);
                let drop: f64 = rng.random();
                let edge_u: f64 = rng.random();
                let mut edge = false;
                for (du, dv) in [(1i64, 0i64), (-1, 0), (0, 1), (0, -1)] {
                    let (uu, vv) = (u as i64 + du, v as i64 + dv);
                    if uu >= 0 && vv >= 0 && uu < i64::from(w) && vv < i64::from(h) {
                        #[allow(clippy::cast_sign_loss, clippy::cast_possible_truncation)]
                        let j = vv as usize * w as usize + uu as usize;
                        if (z_clean[j] - z).abs() > 0.1 {
                            edge = true;
                        }
                    }
                }
                let sz = 0.0012 + 0.0019 * (z - 0.4).powi(2);
                let zn = ((z + sz * n) * 1000.0).round() / 1000.0;
                let invalid = !(0.5..=6.0).contains(&zn) || drop < 0.005 || (edge && edge_u < 0.5);
                #[allow(clippy::cast_possible_truncation)]
                {
                    depth[i] = if invalid { 0.0 } else { zn as f32 };
                }
            }
        }
        let _ = id_buf;
        let amodal_box = amodal.bbox();
        let vis = if amodal.count > 0 {
            visible.count as f64 / amodal.count as f64
        } else {
            0.0
        };
        let tp = self.actors[0].pos[k].unwrap_or([0.0, 0.0]);
        let rel = r.apply_inverse(&nalgebra::Point2::new(tp[0], tp[1]));
        let delta = if k == 0 {
            Pose2::identity()
        } else {
            self.robot[k - 1].inverse().compose(&r)
        };
        Ok(RgbdSample {
            rgb,
            depth_m: Plane::from_vec(w, h, depth)?,
            truth: FrameTruth {
                frame: k,
                t,
                amodal: amodal_box,
                visible: visible.bbox(),
                visibility: vis.clamp(0.0, 1.0),
                target_robot: [rel.x, rel.y, 0.85],
                robot_pose: r,
                delta,
                delta_noisy: self.delta_noisy[k],
                v: if k == 0 {
                    0.0
                } else {
                    delta.x.hypot(delta.y) / self.dt
                },
                omega: if k == 0 { 0.0 } else { delta.theta / self.dt },
                detector_off: self.id == ScenarioId::S6EgoRotation && (100..=130).contains(&k),
                distractor: distr.bbox(),
            },
        })
    }

    /// Ground truth of frame `k` without rendering the image (cheaper bookkeeping is not
    /// available: the boxes come from the ray caster, so this renders).
    ///
    /// # Errors
    /// As [`RgbdScene::render`].
    pub fn truth(&self, k: usize) -> Result<FrameTruth, SimError> {
        Ok(self.render(k)?.truth)
    }
}

#[derive(Debug, Default, Clone, Copy)]
struct Bounds {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
    count: usize,
}

impl Bounds {
    fn add(&mut self, u: u32, v: u32) {
        if self.count == 0 {
            *self = Self {
                x0: u,
                y0: v,
                x1: u,
                y1: v,
                count: 0,
            };
        }
        self.x0 = self.x0.min(u);
        self.y0 = self.y0.min(v);
        self.x1 = self.x1.max(u);
        self.y1 = self.y1.max(v);
        self.count += 1;
    }
    fn bbox(&self) -> Option<BBox> {
        (self.count > 0).then(|| {
            BBox::from_ltwh(
                f64::from(self.x0),
                f64::from(self.y0),
                f64::from(self.x1 - self.x0 + 1),
                f64::from(self.y1 - self.y0 + 1),
            )
        })
    }
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
