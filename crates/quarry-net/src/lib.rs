//! Networked deployment of the lidar people tracker (spec 003 §7): scanner nodes publish the
//! dynamic points of their scans, a server fuses them by timestamp, tracks, and publishes the
//! tracks.
//!
//! - [`proto`]: the sans-IO protocol: the §7.1 wire format, clock synchronisation and the
//!   server's frame assembly ([`proto::FrameAssembler`]); no sockets, no zenoh;
//! - [`AssemblerFusion`]: quarry-trackers' fusion stage over the frame assembler and the wire
//!   codec;
//! - [`Transport`]: publish/subscribe of byte messages on `/`-separated keys. [`LocalBus`] is
//!   the in-process implementation (channels, for the simulator and tests); `ZenohTransport`
//!   (feature `zenoh`) runs over zenoh 1.x sessions in peer mode with explicit TCP endpoints.
//! - [`node`]: `run_sim_node` (feature `sim`; virtual time: simulated scanner K with the room's
//!   network model, reproducible) and [`run_wall_node`] (real time, §7.3 clock sync, over a
//!   [`ScanSource`]: the simulated room or a recorded CSV).
//! - [`server`]: `run_sim_server` (feature `sim`) and [`run_wall_server`], both over the
//!   frame assembler and the tracker of `quarry_trackers::lidar_people`.
//! - [`session`]: the join / welcome / refuse handshake, the server's beacon and end notice,
//!   each carrying the server's session id (two servers, a restarted server);
//! - [`envelope`]: the virtual-time step and end markers and the track message (decoders
//!   fuzzed in `fuzz/`).
//!
//! - [`ros2`] (feature `ros2`): ROS 2 over zenoh without a bridge: `Ros2ScanSource` reads a
//!   `sensor_msgs/msg/LaserScan` topic published by rmw_zenoh, `Ros2TrackPublisher` publishes a
//!   server's tracks as ROS 2 messages on rmw_zenoh's key expressions.
//!
//! Features: `zenoh` (the zenoh transport), `sim` (simulated nodes and the virtual-time server
//! over quarry-sim's room; the example below needs it), `ros2` (the [`ros2`] module).
//!
//! ```
//! # #[cfg(feature = "sim")] {
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
//! // about 20 frames of 50 ms, each fused from the three nodes' scans (the same frames and tracks
//! // as quarry-repro's in-process run of the scenario: tested there)
//! assert!(run.frames_tracked >= 15, "{}", run.frames_tracked);
//! # }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod envelope;
mod error;
mod fusion;
pub mod node;
pub mod proto;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod server;
pub mod session;
pub mod transport;
#[cfg(feature = "zenoh")]
mod zenoh_transport;

pub use envelope::{EndOfStream, SimMessage, SimStep, TrackMessage};
pub use error::{EnvelopeError, NetError};
pub use fusion::{AssemblerFusion, encode_dynamic};
pub use node::{
    CsvSource, MAX_SOURCE_GAP, NodeSummary, ScanSource, WallNodeOptions, run_wall_node,
    wait_for_server,
};
#[cfg(feature = "sim")]
pub use node::{SimSource, run_sim_node};
pub use server::{
    ClosedFrame, FrameObserver, SensorSpec, SensorStatus, ServerRun, WallServerOptions,
    run_wall_server, run_wall_server_observed, run_wall_server_until,
};
#[cfg(feature = "sim")]
pub use server::{run_sim_server, run_sim_server_observed, run_sim_server_until};
pub use session::{ClockKind, Welcome};
pub use transport::{Liveliness, LocalBus, Received, Subscription, Transport, key_matches, keys};
#[cfg(feature = "zenoh")]
pub use zenoh_transport::{ZenohOptions, ZenohTransport};
