//! Rendering: the per-pixel ray caster (room, posters, billboards), the illumination and
//! clothing changes over time, the RGB and depth sensor noise, and the ground-truth boxes.

use super::scene::{Kind, RgbdScene};
use super::texture::{add, hsv, person_colour, person_hit, shirt_target, vnoise};
use super::{FrameTruth, RgbdSample, ScenarioId};
use crate::SimError;
use quarry_core::rng::stream;
use quarry_core::{BBox, CoreError, Plane, Pose2};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// An actor in view: kind, position, normal towards the camera, lateral axis, distance walked.
type ActiveActor = (Kind, [f64; 2], [f64; 2], [f64; 2], f64);

impl RgbdScene {
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

/// Pixel bounds and count of a region, grown one pixel at a time.
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
