//! # quarry-ros2
//!
//! ROS 2 messages for quarry's inputs and outputs, their CDR wire encoding, MCAP recording, and
//! the naming rules of rmw_zenoh, so that quarry's trackers feed Foxglove, `ros2 bag` and ROS 2
//! robots directly.
//!
//! - [`cdr`]: the CDR encoder and a bounds-checked decoder (malformed bytes are an error, never
//!   a panic or an oversized allocation).
//! - [`schema`]: message definitions as data, from which the `.msg` text ([`Message::definition`])
//!   and the RIHS01 type hash ([`Message::type_hash`]) follow; the [`ros_msg!`] macro defines a
//!   type, its encoder and its definition from one field list.
//! - [`msgs`]: `sensor_msgs` (LaserScan, Image, CompressedImage), `geometry_msgs`, `tf2_msgs`,
//!   `visualization_msgs` (Marker, MarkerArray), `vision_msgs` (Detection2DArray) as in ROS 2
//!   Jazzy, and `quarry_msgs` (Track, TrackArray; the `.msg` files are in `msg/`).
//! - [`McapRecorder`] (feature `mcap`, on by default): writes an MCAP file with the `ros2` profile.
//! - [`convert`]: quarry-core's `PolarScan` to and from `LaserScan` (with the checks a
//!   subscriber needs: beam count, angles, ranges), stamps to and from ROS time.
//! - [`rmw_zenoh`]: key expressions, sample attachments and liveliness tokens of rmw_zenoh.
//!
//! ```
//! use quarry_ros2::msgs::{Header, LaserScan, Time};
//! use quarry_ros2::Message;
//!
//! let scan = LaserScan {
//!     header: Header::new(Time::from_secs_f64(1.5), "laser"),
//!     angle_min: -1.0,
//!     angle_max: 1.0,
//!     angle_increment: 0.5,
//!     range_max: 30.0,
//!     ranges: vec![1.0, 2.0, f32::INFINITY, 2.5, 3.0],
//!     ..LaserScan::default()
//! };
//! let bytes = scan.to_cdr();
//! assert_eq!(&bytes[..4], &[0, 1, 0, 0]); // little-endian plain CDR
//! let back = LaserScan::from_cdr(&bytes)?;
//! assert_eq!(back.header.frame_id, "laser");
//! assert_eq!(back.ranges.len(), 5);
//! // the type's identity on the wire (ROS 2 Jazzy's hash) and in an MCAP schema record
//! assert!(LaserScan::type_hash().starts_with("RIHS01_64c19139"));
//! assert!(LaserScan::definition().starts_with("std_msgs/Header header\n"));
//! // a truncated message is an error, not a panic
//! assert!(LaserScan::from_cdr(&bytes[..bytes.len() - 3]).is_err());
//! # Ok::<(), quarry_ros2::CdrError>(())
//! ```
//!
//! ## Features
//!
//! - `mcap` (default): [`McapRecorder`], on the `mcap` crate without compression.

pub mod cdr;
pub mod convert;
#[cfg(feature = "mcap")]
mod mcap_rec;
pub mod msgs;
pub mod rmw_zenoh;
pub mod schema;

pub use cdr::{CdrError, CdrReader, CdrWriter};
#[cfg(feature = "mcap")]
pub use mcap_rec::{McapRecorder, RecordError, RecordSummary};
pub use schema::Message;
