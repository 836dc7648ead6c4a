//! The scanner model: a fixed 2-D laser scanner (Hokuyo UTM-30LX beam model) casting its beams
//! into the room and the people, with range noise, dropouts and optional mixed pixels.

use super::people::PersonState;
use super::room::Room;
use quarry_core::rng::SeededRng;
use quarry_core::{Point2, Pose2, ScanGeometry, SensorId};
use rand::Rng;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// A simulated scanner: pose and beam model.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct ScannerSim {
    /// Sensor id.
    pub id: SensorId,
    /// Name (`A`, `B`, `C`).
    pub name: String,
    /// True world pose.
    pub pose: Pose2,
    /// Beam geometry (UTM-30LX by default).
    pub geometry: ScanGeometry,
    /// Per-beam dropout probability (0.002).
    pub p_drop: f64,
    /// Mixed pixels at depth edges (off by default).
    pub mixed_pixels: bool,
}

/// Range noise standard deviation of the UTM-30LX: 1 cm up to 10 m, 3 cm beyond (spec §2.1).
pub fn sigma_d(range_m: f64) -> f64 {
    if range_m <= 10.0 { 0.010 } else { 0.030 }
}

/// What a beam hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hit {
    /// Nothing within range.
    None,
    /// A wall or an obstacle.
    Static,
    /// Person `i` (index into the people slice).
    Person(usize),
}

impl ScannerSim {
    /// The three scanners of spec §5: A (0.25, 0.25, 45°), B (9.75, 0.25, 135°),
    /// C (5.00, 7.75, −90°).
    pub fn default_three() -> Vec<ScannerSim> {
        let mk = |i: u16, n: &str, x: f64, y: f64, deg: f64| ScannerSim {
            id: SensorId(i),
            name: n.into(),
            pose: Pose2::new(x, y, f64::to_radians(deg)),
            geometry: ScanGeometry::utm30lx(),
            p_drop: 0.002,
            mixed_pixels: false,
        };
        vec![
            mk(0, "A", 0.25, 0.25, 45.0),
            mk(1, "B", 9.75, 0.25, 135.0),
            mk(2, "C", 5.00, 7.75, -90.0),
        ]
    }

    /// Noise-free ranges (metres, `None` = no hit within `range_max`) and what each beam hit.
    pub fn true_ranges(
        &self,
        room: &Room,
        people: &[PersonState],
        arms: bool,
    ) -> Vec<(Option<f64>, Hit)> {
        let g = &self.geometry;
        let o = Point2::new(self.pose.x, self.pose.y);
        (0..g.n_beams)
            .map(|n| {
                let ang = self.pose.theta + g.angle(n);
                let d = [ang.cos(), ang.sin()];
                let mut best = room.ray_cast(o, d).map(|t| (t, Hit::Static));
                for (i, p) in people.iter().enumerate() {
                    // cheap reject: person farther than the current best
                    let dist = (p.pos - o).norm();
                    if best.is_some_and(|(t, _)| dist - 0.4 > t) {
                        continue;
                    }
                    if let Some(t) = p.ray(o, d, arms)
                        && best.is_none_or(|(b, _)| t < b)
                    {
                        best = Some((t, Hit::Person(i)));
                    }
                }
                match best {
                    Some((t, h)) if t <= g.range_max => (Some(t), h),
                    _ => (None, Hit::None),
                }
            })
            .collect()
    }

    /// Renders one scan: noisy ranges in mm (1 = no return / out of range, 4 = too close, 0 =
    /// dropout), and the number of beams hitting each person.
    pub fn render(
        &self,
        room: &Room,
        people: &[PersonState],
        arms: bool,
        rng: &mut SeededRng,
    ) -> (Vec<u16>, Vec<usize>) {
        let tr = self.true_ranges(room, people, arms);
        let mut counts = vec![0usize; people.len()];
        let mut out = Vec::with_capacity(tr.len());
        for (n, &(r, hit)) in tr.iter().enumerate() {
            if let Hit::Person(i) = hit {
                counts[i] += 1;
            }
            let Some(mut t) = r else {
                out.push(1);
                continue;
            };
            if t < self.geometry.range_min {
                out.push(4);
                continue;
            }
            if self.mixed_pixels
                && let Some((Some(t2), _)) = tr.get(n + 1)
                && (t2 - t).abs() > 0.3
                && rng.random_bool(0.2)
            {
                t = rng.random_range(t.min(*t2)..t.max(*t2));
            }
            let noisy = t + sigma_d(t) * rng.sample::<f64, _>(rand_distr::StandardNormal);
            if rng.random_bool(self.p_drop) {
                out.push(0);
                continue;
            }
            out.push((noisy * 1000.0).round().clamp(0.0, f64::from(u16::MAX)) as u16);
        }
        (out, counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scanner_sees_room_walls() {
        let room = Room::room10x8();
        let sc = &ScannerSim::default_three()[0];
        let tr = sc.true_ranges(&room, &[], false);
        // beam 540 looks along 45 deg from (0.25, 0.25): hits the pillar? line y = x passes
        // (4.8..5.2, 3.8..4.2)? y=x at x=4.8 -> y=4.8 > 4.2: no; it meets the cabinet edge x = 7.5
        let t = tr[540].0.unwrap();
        assert!((t - 7.25 * 2f64.sqrt()).abs() < 1e-9, "{t}");
        assert!(
            tr.iter().all(|(r, _)| r.is_some()),
            "a closed room returns every beam"
        );
    }
}
