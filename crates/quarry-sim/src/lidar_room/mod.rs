//! The room simulator of spec 003 §5: fixed 2-D laser scanners (Hokuyo UTM-30LX beam model) in a
//! furnished room, people walking as ellipses with swinging arms, client clocks with offset, drift
//! and stamping jitter, and a lossy network with variable delay and duplicates.
//!
//! Everything is seeded. Each component draws from its own stream
//! (`quarry_core::rng::stream(seed, [kind, id])`), so adding a person does not change the scanner
//! noise.
//!
//! ```
//! use quarry_sim::lidar_room::{Runner, RoomEvent, Scenario, SpeedBand};
//! let sc = Scenario::band(SpeedBand::Mid, 3, 7).with_duration(5.5);
//! let mut scans = 0;
//! let mut frames = 0;
//! for ev in Runner::new(sc)? {
//!     match ev {
//!         RoomEvent::Scan(s) => { scans += 1; assert_eq!(s.scan.ranges_mm.len(), 1081); }
//!         RoomEvent::Frame(f) => { frames += 1; if f.t.0 > 5_000_000 { assert_eq!(f.people.len(), 3); } }
//!     }
//! }
//! assert_eq!(frames, 110); // 5.5 s at 20 Hz
//! assert!(scans >= 3 * 219);
//! # Ok::<(), quarry_sim::SimError>(())
//! ```
//!
//! Choices where the spec leaves one (documented here and in docs/lidar-people.md):
//! - The network model is applied per scan (one message per scan); the dynamic points of a scan
//!   rarely exceed the 350-point part size.
//! - Clock corrections are applied as steps (no slewing); the offset estimate is refreshed once per
//!   second from the NTP-style exchange, keeping the sample with the smallest round trip of the
//!   last 8.
//! - `per_beam_timing` is not modelled: all beams of a scan see the world at its capture time.
//! - A walker whose next step would bring its centre within 0.3 m of an obstacle (or 0.6 m of
//!   another person) does not take it, and picks a new waypoint after 0.5 s blocked.
//! - `side_by_side` walks its two people 0.65 m apart centre to centre (the avoidance distance
//!   is 0.6 m); `door` scripts visitors in from the corridor and out again ([`Visit`]), letting
//!   nobody in while someone is on the way out; `stop_and_go` pauses U(0, 3) s at every
//!   waypoint ([`Motion::StopAndGo`]).

mod clock;
mod csv;
mod network;
mod people;
mod raycast;
mod room;
mod runner;
mod scanner;
mod scenario;
#[cfg(test)]
mod tests;
mod walkers;

pub use clock::{ClockModel, ClockProfile};
pub use csv::GtWriter;
pub use network::NetworkModel;
pub use people::{Motion, PersonSpec, PersonState, SpeedBand, Visit};
pub use raycast::{ray_circle, ray_ellipse, ray_segment};
pub use room::{Obstacle, Room, Wall};
pub use runner::{CapturedScan, GtFrame, GtPerson, RoomEvent, Runner};
pub use scanner::{Hit, ScannerSim, sigma_d};
pub use scenario::Scenario;

/// Largest shift of the rough initial scanner poses of the `calib` scenario, metres (spec §5).
pub const CALIB_MAX_SHIFT_M: f64 = 0.3;
/// Largest rotation of the rough initial scanner poses of the `calib` scenario, degrees (spec §5).
pub const CALIB_MAX_ROT_DEG: f64 = 10.0;

/// Integration step of the people's motion, microseconds (5 ms, spec §5).
pub const MOTION_STEP_US: i64 = 5_000;
/// Fused-frame interval, microseconds (50 ms).
pub const FRAME_US: i64 = 50_000;
/// Scan period of the UTM-30LX, microseconds (25 ms).
pub const SCAN_US: i64 = 25_000;
/// Braking and starting acceleration of a [`Motion::Route`] walker at its turning points, m/s²
/// (a comfortable pedestrian deceleration: from 1.0 m/s to a stop in 1 s over 0.5 m).
pub const ROUTE_ACCEL: f64 = 1.0;
