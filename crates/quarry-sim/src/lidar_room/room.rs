//! The static world: wall segments, obstacles reaching the scan plane, the walkable region, and
//! the default 10 × 8 m room of spec §5.

use super::raycast::{ray_circle, ray_segment};
use quarry_core::Point2;
use quarry_core::rng::SeededRng;
use rand::Rng;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// A static obstacle reaching the scan plane.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum Obstacle {
    /// An axis-aligned rectangle `[x0, x1] × [y0, y1]`.
    Rect {
        /// Lower-left corner.
        min: [f64; 2],
        /// Upper-right corner.
        max: [f64; 2],
    },
    /// A circle.
    Circle {
        /// Centre.
        c: [f64; 2],
        /// Radius, metres.
        r: f64,
    },
}

impl Obstacle {
    /// Distance from `p` to the obstacle (0 inside).
    pub fn distance(&self, p: Point2) -> f64 {
        match *self {
            Obstacle::Rect { min, max } => {
                let dx = (min[0] - p.x).max(0.0).max(p.x - max[0]);
                let dy = (min[1] - p.y).max(0.0).max(p.y - max[1]);
                dx.hypot(dy)
            }
            Obstacle::Circle { c, r } => ((p.x - c[0]).hypot(p.y - c[1]) - r).max(0.0),
        }
    }

    /// Ray intersection distance.
    pub fn ray(&self, o: Point2, d: [f64; 2]) -> Option<f64> {
        match *self {
            Obstacle::Rect { min, max } => {
                let c = [
                    Point2::new(min[0], min[1]),
                    Point2::new(max[0], min[1]),
                    Point2::new(max[0], max[1]),
                    Point2::new(min[0], max[1]),
                ];
                (0..4)
                    .filter_map(|i| ray_segment(o, d, c[i], c[(i + 1) % 4]))
                    .min_by(f64::total_cmp)
            }
            Obstacle::Circle { c, r } => ray_circle(o, d, Point2::new(c[0], c[1]), r),
        }
    }
}

/// A wall segment.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Wall {
    /// One end.
    pub a: [f64; 2],
    /// The other end.
    pub b: [f64; 2],
}

/// The room: walls, obstacles and the walkable region.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct Room {
    /// Name (`room10x8`).
    pub name: String,
    /// Wall segments.
    pub walls: Vec<Wall>,
    /// Named obstacles.
    pub obstacles: Vec<(String, Obstacle)>,
    /// Walkable box `[x0, x1, y0, y1]` before removing the inflated obstacles.
    pub walkable: [f64; 4],
    /// Obstacle inflation of the walkable region, metres (0.5).
    pub inflate: f64,
}

impl Room {
    /// The default room of spec §5: 10 × 8 m, a door gap in the east wall at y ∈ [3.5, 4.5], a
    /// corridor wall at x = 13, a pillar, a shelf, a cabinet, a fridge and a coat stand.
    pub fn room10x8() -> Self {
        let w = |a: [f64; 2], b: [f64; 2]| Wall { a, b };
        Self {
            name: "room10x8".into(),
            walls: vec![
                w([0.0, 0.0], [10.0, 0.0]),
                w([10.0, 0.0], [10.0, 3.5]),
                w([10.0, 4.5], [10.0, 8.0]),
                w([10.0, 8.0], [0.0, 8.0]),
                w([0.0, 8.0], [0.0, 0.0]),
                // the corridor behind the door
                w([13.0, -2.0], [13.0, 10.0]),
                w([10.0, 3.5], [10.2, 3.5]),
                w([10.0, 4.5], [10.2, 4.5]),
            ],
            obstacles: vec![
                (
                    "pillar".into(),
                    Obstacle::Rect {
                        min: [4.8, 3.8],
                        max: [5.2, 4.2],
                    },
                ),
                (
                    "shelf".into(),
                    Obstacle::Rect {
                        min: [0.0, 4.5],
                        max: [0.4, 6.5],
                    },
                ),
                (
                    "cabinet".into(),
                    Obstacle::Rect {
                        min: [7.5, 7.4],
                        max: [9.0, 8.0],
                    },
                ),
                (
                    "fridge".into(),
                    Obstacle::Rect {
                        min: [9.3, 1.8],
                        max: [10.0, 2.5],
                    },
                ),
                (
                    "coat stand".into(),
                    Obstacle::Circle {
                        c: [2.0, 6.0],
                        r: 0.20,
                    },
                ),
            ],
            walkable: [0.6, 9.4, 0.6, 7.4],
            inflate: 0.5,
        }
    }

    /// Distance from `p` to the nearest obstacle (walls excluded).
    pub fn obstacle_distance(&self, p: Point2) -> f64 {
        self.obstacles
            .iter()
            .map(|(_, o)| o.distance(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// True when `p` is in the walkable box and at least `clearance` from every obstacle.
    pub fn is_free(&self, p: Point2, clearance: f64) -> bool {
        let [x0, x1, y0, y1] = self.walkable;
        p.x >= x0 && p.x <= x1 && p.y >= y0 && p.y <= y1 && self.obstacle_distance(p) >= clearance
    }

    /// True when the straight segment `a → b` keeps `clearance` from every obstacle (sampled
    /// every 5 cm).
    pub fn segment_clear(&self, a: Point2, b: Point2, clearance: f64) -> bool {
        let n = ((b - a).norm() / 0.05).ceil().max(1.0) as usize;
        (0..=n).all(|i| {
            let s = i as f64 / n as f64;
            self.obstacle_distance(a + (b - a) * s) >= clearance
        })
    }

    /// The nearest static hit along a ray (walls and obstacles).
    pub fn ray_cast(&self, o: Point2, d: [f64; 2]) -> Option<f64> {
        let walls = self.walls.iter().filter_map(|w| {
            ray_segment(
                o,
                d,
                Point2::new(w.a[0], w.a[1]),
                Point2::new(w.b[0], w.b[1]),
            )
        });
        let obs = self.obstacles.iter().filter_map(|(_, ob)| ob.ray(o, d));
        walls.chain(obs).min_by(f64::total_cmp)
    }

    /// A uniformly drawn point of the walkable region (rejection sampling, up to 1000 tries).
    pub(super) fn sample_free(&self, rng: &mut SeededRng) -> Point2 {
        let [x0, x1, y0, y1] = self.walkable;
        let mut p = Point2::new(0.5 * (x0 + x1), 0.5 * (y0 + y1));
        for _ in 0..1000 {
            p = Point2::new(rng.random_range(x0..x1), rng.random_range(y0..y1));
            if self.is_free(p, self.inflate) {
                break;
            }
        }
        p
    }
}
