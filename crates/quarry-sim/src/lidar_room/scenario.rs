//! Scenarios: a complete simulation set-up (room, scanners, people, network and clock profiles)
//! and the named scenarios of spec §5 (`empty`, `single_line`, `crossing`, `side_by_side`, `door`,
//! `stop_and_go`, `calib`, `band_*`, `crowd_<n>`).

use super::clock::ClockProfile;
use super::network::NetworkModel;
use super::people::{Motion, PersonSpec, SpeedBand, Visit};
use super::room::Room;
use super::scanner::ScannerSim;
use crate::SimError;
use quarry_core::rng::stream;
use quarry_core::{CoreError, Pose2};
use rand::Rng;
use std::f64::consts::PI;

/// A complete simulation set-up.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Scenario name.
    pub name: String,
    /// Master seed.
    pub seed: u64,
    /// Duration, seconds.
    pub duration_s: f64,
    /// The room.
    pub room: Room,
    /// The scanners.
    pub scanners: Vec<ScannerSim>,
    /// The people.
    pub people: Vec<PersonSpec>,
    /// Arms on the torso ellipses.
    pub arms: bool,
    /// Network profile.
    pub network: NetworkModel,
    /// Clock profile.
    pub clock: ClockProfile,
    /// Client processing delay, seconds (1 ms).
    pub processing_s: f64,
}

impl Scenario {
    fn base(name: &str, seed: u64, duration_s: f64) -> Self {
        Self {
            name: name.into(),
            seed,
            duration_s,
            room: Room::room10x8(),
            scanners: ScannerSim::default_three(),
            people: Vec::new(),
            arms: true,
            network: NetworkModel::wifi(),
            clock: ClockProfile::Synced,
            processing_s: 0.001,
        }
    }

    /// `band_<b>`: `n` people (3 in the protocol), waypoint motion, spawning at t = 5 s, 250 s.
    pub fn band(band: SpeedBand, n: u32, seed: u64) -> Self {
        let mut s = Self::base(&format!("band_{}", band.name()), seed, 250.0);
        s.people = (0..n)
            .map(|id| PersonSpec {
                id,
                speed: band.range(),
                motion: Motion::Waypoint,
                spawn: None,
                t_spawn: 5.0,
            })
            .collect();
        s
    }

    /// `empty`: 60 s, no people.
    pub fn empty(seed: u64) -> Self {
        Self::base("empty", seed, 60.0)
    }

    /// `single_line`: one person back and forth between x = 2 and 8 at 1.0 m/s, 60 s. The spec's
    /// line y = 4 runs through the pillar, so the walker uses y = 3.
    pub fn single_line(seed: u64) -> Self {
        let mut s = Self::base("single_line", seed, 60.0);
        s.people = vec![PersonSpec {
            id: 0,
            speed: (1.0, 1.0),
            motion: Motion::Route(vec![[8.0, 3.0], [2.0, 3.0]]),
            spawn: Some([2.0, 3.0]),
            t_spawn: 5.0,
        }];
        s
    }

    /// `crossing`: two people walking back and forth at 1.0 m/s on perpendicular routes that
    /// cross at (6.2, 4.8), 30 s. Both routes are centred on the crossing point and equally long
    /// (4.6 m between the turning points), and the second walker starts 0.86 s after the first,
    /// so *every* meeting, not only the first, passes at the spec's closest approach (0.61 m:
    /// two perpendicular walkers at speed v offset by Δt pass at v·Δt/√2; 1 cm above the 0.6 m
    /// avoidance distance, so neither has to yield). They brake into and out of each turn
    /// ([`Motion::Route`]), so the meetings come every 5.6 s: t ≈ 7.8, 13.3, 18.9 and 24.5 s.
    pub fn crossing(seed: u64) -> Self {
        // a route walker turns when within 0.3 m of its turning target
        const HALF: f64 = 2.3 + 0.3;
        const C: [f64; 2] = [6.2, 4.8];
        let lag = 0.61 * std::f64::consts::SQRT_2;
        let mut s = Self::base("crossing", seed, 30.0);
        s.people = vec![
            PersonSpec {
                id: 0,
                speed: (1.0, 1.0),
                motion: Motion::Route(vec![[C[0] + HALF, C[1]], [C[0] - HALF, C[1]]]),
                spawn: Some([C[0] - HALF + 0.3, C[1]]),
                t_spawn: 5.0,
            },
            PersonSpec {
                id: 1,
                speed: (1.0, 1.0),
                motion: Motion::Route(vec![[C[0], C[1] + HALF], [C[0], C[1] - HALF]]),
                spawn: Some([C[0], C[1] - HALF + 0.3]),
                t_spawn: 5.0 + lag,
            },
        ];
        s
    }

    /// `side_by_side`: two people walking abreast, back and forth along x between the turning
    /// points 2.3 and 7.7 m (route ends 2 and 8) at 1.0 m/s on parallel lines y = 2.4 and
    /// y = 3.05, 60 s. The spec's "0.6 m apart" is taken as 0.65 m centre to centre: the
    /// person–person avoidance stops any step to within 0.6 m, and at exactly 0.6 m rounding
    /// would make one of them side-step. Both start together at t = 5 s and brake into and out
    /// of the turns alike ([`Motion::Route`]), so they stay abreast all the time.
    pub fn side_by_side(seed: u64) -> Self {
        let mut s = Self::base("side_by_side", seed, 60.0);
        s.people = [2.4, 3.05]
            .into_iter()
            .zip(0..)
            .map(|(y, id)| PersonSpec {
                id,
                speed: (1.0, 1.0),
                motion: Motion::Route(vec![[8.0, y], [2.0, y]]),
                spawn: Some([2.3, y]),
                t_spawn: 5.0,
            })
            .collect();
        s
    }

    /// `door`: five visitors enter through the door in the east wall (gap y ∈ [3.5, 4.5]) and
    /// leave through it again, 90 s. Each appears in the corridor at (11.5, 4.0), walks
    /// straight in to (9.0, 4.0), walks random waypoints (band_mid speeds, U(0.75, 1.00) m/s per
    /// leg) for its stay, then heads for the waiting point (8.8, 5.0) in front of the door,
    /// walks out along (9.6, 4.0) → (11.5, 4.0) and vanishes there ([`Visit`]). Spawn times 5,
    /// 13, 21, 29 and 37 s, stays 12, 14, 10, 12 and 10 s. A visitor is born only while nobody
    /// is in x ∈ [8.3, 13], y ∈ [3, 5.4] (doorway, waiting point, way out), and starts its way
    /// out only while nobody is in x ∈ [8.5, 13], y ∈ [3, 4.6], so nobody meets head-on in the
    /// door and births can slip by a few seconds. Everyone has left well before the end
    /// (seeds 1-3: by 56-74 s).
    pub fn door(seed: u64) -> Self {
        const SPAWN: [f64; 5] = [5.0, 13.0, 21.0, 29.0, 37.0];
        const STAY: [f64; 5] = [12.0, 14.0, 10.0, 12.0, 10.0];
        let mut s = Self::base("door", seed, 90.0);
        s.people = SPAWN
            .into_iter()
            .zip(STAY)
            .zip(0..)
            .map(|((t_spawn, stay_s), id)| PersonSpec {
                id,
                speed: SpeedBand::Mid.range(),
                motion: Motion::Visit(Visit {
                    enter: vec![[9.0, 4.0]],
                    stay_s,
                    door_front: [8.8, 5.0],
                    exit: vec![[9.6, 4.0], [11.5, 4.0]],
                    lane: [8.5, 13.0, 3.0, 4.6],
                    spawn_box: [8.3, 13.0, 3.0, 5.4],
                }),
                spawn: Some([11.5, 4.0]),
                t_spawn,
            })
            .collect();
        s
    }

    /// `stop_and_go`: three people, waypoint motion at band_mid speeds (U(0.75, 1.00) m/s per
    /// leg), standing still for U(0, 3) s at every waypoint reached ([`Motion::StopAndGo`],
    /// spec §5), spawning at t = 5 s, 60 s. Pauses longer than the background's
    /// `T_relearn = 2 s` can make a standing person part of the background (spec A4).
    pub fn stop_and_go(seed: u64) -> Self {
        let mut s = Self::base("stop_and_go", seed, 60.0);
        s.people = (0..3)
            .map(|id| PersonSpec {
                id,
                speed: SpeedBand::Mid.range(),
                motion: Motion::StopAndGo {
                    pause_s: (0.0, 3.0),
                },
                spawn: None,
                t_spawn: 5.0,
            })
            .collect();
        s
    }

    /// `calib`: the empty room for 10 s, for calibrating the scanners from their backgrounds
    /// (spec §5, §2.3). The rough ("hand-measured") initial poses, the true poses perturbed by up
    /// to [`CALIB_MAX_SHIFT_M`](super::CALIB_MAX_SHIFT_M) and [`CALIB_MAX_ROT_DEG`](super::CALIB_MAX_ROT_DEG), are drawn by
    /// [`Scenario::hand_measured_poses`] from the scenario's seed.
    pub fn calib(seed: u64) -> Self {
        Self::base("calib", seed, 10.0)
    }

    /// Rough ("hand-measured") poses of the scanners: each true pose moved by a seeded draw of
    /// at most `max_shift_m` metres (direction uniform, distance uniform in `[0, max_shift_m]`)
    /// and turned by at most `max_rot_rad` (uniform in `[−max_rot_rad, max_rot_rad]`). Scanner
    /// `i` draws from its own stream `(seed, [6, i])`, so the draw does not depend on the number
    /// of scanners or on anything else in the run. In scenario order.
    pub fn hand_measured_poses(
        &self,
        max_shift_m: f64,
        max_rot_rad: f64,
    ) -> Result<Vec<Pose2>, SimError> {
        if !(max_shift_m.is_finite() && max_shift_m >= 0.0) {
            return Err(CoreError::invalid("max_shift_m", "must be finite and >= 0").into());
        }
        if !(max_rot_rad.is_finite() && max_rot_rad >= 0.0) {
            return Err(CoreError::invalid("max_rot_rad", "must be finite and >= 0").into());
        }
        Ok(self
            .scanners
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let mut rng = stream(self.seed, &[6, i as u64]);
                let dir = rng.random_range(-PI..PI);
                let dist = max_shift_m * rng.random::<f64>();
                let rot = max_rot_rad * (2.0 * rng.random::<f64>() - 1.0);
                Pose2::new(
                    s.pose.x + dist * dir.cos(),
                    s.pose.y + dist * dir.sin(),
                    s.pose.theta + rot,
                )
            })
            .collect())
    }

    /// A scenario by name: `empty`, `single_line`, `crossing`, `side_by_side`, `door`,
    /// `stop_and_go`, `calib`, `band_slow`, `band_mid`, `band_fast`, `crowd_<n>`.
    pub fn by_name(name: &str, seed: u64) -> Result<Self, SimError> {
        match name {
            "empty" => Ok(Self::empty(seed)),
            "single_line" => Ok(Self::single_line(seed)),
            "crossing" => Ok(Self::crossing(seed)),
            "side_by_side" => Ok(Self::side_by_side(seed)),
            "door" => Ok(Self::door(seed)),
            "stop_and_go" => Ok(Self::stop_and_go(seed)),
            "calib" => Ok(Self::calib(seed)),
            _ => {
                if let Some(b) = name.strip_prefix("band_") {
                    return Ok(Self::band(SpeedBand::parse(b)?, 3, seed));
                }
                if let Some(n) = name.strip_prefix("crowd_")
                    && let Ok(n) = n.parse::<u32>()
                {
                    let mut s = Self::band(SpeedBand::Mid, n, seed);
                    s.name = name.into();
                    return Ok(s);
                }
                Err(CoreError::invalid("scenario", "unknown scenario name (expected empty, single_line, crossing, side_by_side, door, stop_and_go, band_slow, band_mid, band_fast or crowd_<n>)").into())
            }
        }
    }

    /// Sets the duration (seconds).
    pub fn with_duration(mut self, s: f64) -> Self {
        self.duration_s = s;
        self
    }

    /// Sets the network profile.
    pub fn with_network(mut self, n: NetworkModel) -> Self {
        self.network = n;
        self
    }

    /// Sets the clock profile.
    pub fn with_clock(mut self, c: ClockProfile) -> Self {
        self.clock = c;
        self
    }

    /// Checks the scenario.
    pub fn validate(&self) -> Result<(), SimError> {
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return Err(CoreError::invalid("duration_s", "must be finite and positive").into());
        }
        if self.scanners.is_empty() {
            return Err(CoreError::Empty { what: "scanners" }.into());
        }
        for s in &self.scanners {
            s.geometry.validate()?;
            if !s.pose.is_finite() {
                return Err(CoreError::invalid("scanner pose", "must be finite").into());
            }
        }
        for p in &self.people {
            if !(p.speed.0.is_finite() && p.speed.1 >= p.speed.0 && p.speed.0 >= 0.0) {
                return Err(CoreError::invalid("person speed", "need 0 <= lo <= hi").into());
            }
            match &p.motion {
                Motion::StopAndGo { pause_s: (lo, hi) } => {
                    if !(lo.is_finite() && hi.is_finite() && *lo >= 0.0 && hi >= lo) {
                        return Err(CoreError::invalid(
                            "stop_and_go pause",
                            "need finite 0 <= lo <= hi seconds",
                        )
                        .into());
                    }
                }
                Motion::Visit(v) => {
                    if v.enter.is_empty() || v.exit.is_empty() || p.spawn.is_none() {
                        return Err(CoreError::invalid(
                            "visit",
                            "needs a spawn point and non-empty enter and exit legs",
                        )
                        .into());
                    }
                    if !v.is_finite() || p.speed.0 <= 0.0 {
                        return Err(CoreError::invalid(
                            "visit",
                            "points, lane and stay must be finite (stay >= 0) and the speed > 0",
                        )
                        .into());
                    }
                }
                Motion::Waypoint | Motion::RandomWalk | Motion::Route(_) => {}
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar_room::{CALIB_MAX_ROT_DEG, CALIB_MAX_SHIFT_M};

    proptest::proptest! {
        /// The rough poses of `calib` stay within the bounds, are reproducible from the seed and
        /// differ between seeds.
        #[test]
        fn hand_measured_poses_stay_within_bounds(seed in 0u64..1_000_000, shift in 0.0f64..2.0, rot in 0.0f64..1.5) {
            let sc = Scenario::calib(seed);
            let a = sc.hand_measured_poses(shift, rot).unwrap();
            proptest::prop_assert_eq!(&a, &sc.hand_measured_poses(shift, rot).unwrap());
            proptest::prop_assert_eq!(a.len(), sc.scanners.len());
            for (p, s) in a.iter().zip(&sc.scanners) {
                proptest::prop_assert!((p.x - s.pose.x).hypot(p.y - s.pose.y) <= shift + 1e-12);
                proptest::prop_assert!(quarry_core::wrap_angle(p.theta - s.pose.theta).abs() <= rot + 1e-12);
            }
            if shift > 0.01 {
                proptest::prop_assert_ne!(a, Scenario::calib(seed + 1).hand_measured_poses(shift, rot).unwrap());
            }
        }
    }

    #[test]
    fn calib_scenario_is_the_empty_room_for_ten_seconds() {
        let sc = Scenario::by_name("calib", 4).unwrap();
        assert_eq!(sc.name, "calib");
        assert!(sc.people.is_empty());
        assert_eq!(sc.duration_s, 10.0);
        assert!(sc.hand_measured_poses(f64::NAN, 0.1).is_err());
        assert!(sc.hand_measured_poses(0.3, -0.1).is_err());
        let p = sc
            .hand_measured_poses(CALIB_MAX_SHIFT_M, CALIB_MAX_ROT_DEG.to_radians())
            .unwrap();
        assert!(p.iter().zip(&sc.scanners).all(|(p, s)| *p != s.pose));
    }
}
