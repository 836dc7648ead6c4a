//! Networked deployment of the lidar people tracker (spec 003 §7): scanner nodes publish the
//! dynamic points of their scans, a server fuses them by timestamp, tracks, and publishes the
//! tracks.
//!
//! - [`Transport`]: publish/subscribe of byte messages on `/`-separated keys. [`LocalBus`] is
//!   the in-process implementation (channels, for the simulator and tests); `ZenohTransport`
//!   (feature `zenoh`) runs over zenoh 1.x sessions in peer mode with explicit TCP endpoints.
//! - [`node`]: [`run_sim_node`] (virtual time: simulated scanner K with the room's network
//!   model, reproducible) and [`run_wall_node`] (real time, §7.3 clock sync, over a
//!   [`ScanSource`]: the simulated room or a recorded CSV).
//! - [`server`]: [`run_sim_server`] and [`run_wall_server`], both over quarry-cloud's
//!   `FrameAssembler` and the tracker of `quarry_trackers::lidar_people`.
//! - [`envelope`]: the virtual-time step and end markers and the track message (decoders
//!   fuzzed in `fuzz/`).
//!
//! ```
//! use quarry_net::{LocalBus, run_sim_node, run_sim_server};
//! use quarry_sim::lidar_room::{Scenario, SpeedBand};
//! use quarry_trackers::lidar_people::LidarPeopleConfig;
//! use std::time::Duration;
//!
//! let sc = Scenario::band(SpeedBand::Mid, 1, 3).with_duration(1.0);
//! let cfg = LidarPeopleConfig::faithful();
//! let sensors: Vec<_> = sc.scanners.iter().map(|s| (s.id, s.pose, s.geometry)).collect();
//! let bus = LocalBus::new();
//! let nodes: Vec<_> = (0..3)
//!     .map(|k| {
//!         let (bus, sc, cfg) = (bus.clone(), sc.clone(), cfg.clone());
//!         std::thread::spawn(move || run_sim_node(&bus, sc, k, &cfg, Duration::from_secs(10)))
//!     })
//!     .collect();
//! let t_end = quarry_core::TimeUs(1_000_000);
//! let run = run_sim_server(&bus, &sensors, &cfg, t_end, Duration::from_secs(10))?;
//! for n in nodes {
//!     n.join().expect("node thread")?;
//! }
//! // the same frames and tracks as the in-process run of the scenario
//! let local = quarry_trackers::lidar_people::run_room_default(sc, &cfg, &mut |_| {})?;
//! assert_eq!(run.frames_tracked, local.frames_tracked);
//! assert_eq!(run.tracks, local.tracks);
//! # Ok::<(), quarry_net::NetError>(())
//! ```

pub mod envelope;
mod error;
pub mod node;
pub mod server;
pub mod transport;
#[cfg(feature = "zenoh")]
mod zenoh_transport;

pub use envelope::{EndOfStream, SimMessage, SimStep, TrackMessage};
pub use error::{EnvelopeError, NetError};
pub use node::{
    CsvSource, NodeSummary, ScanSource, SimSource, WallNodeOptions, run_sim_node, run_wall_node,
};
pub use server::{SensorSpec, ServerRun, WallServerOptions, run_sim_server, run_wall_server};
pub use transport::{LocalBus, Received, Subscription, Transport, key_matches, keys};
#[cfg(feature = "zenoh")]
pub use zenoh_transport::{ZenohOptions, ZenohTransport};
