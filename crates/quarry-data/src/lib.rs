//! # quarry-data
//!
//! Readers of real recordings, for running the quarry trackers on data nobody here made:
//!
//! | module | reads | feeds |
//! |---|---|---|
//! | [`mrclam`] | the UTIAS MRCLAM datasets (odometry, barcoded measurements, Vicon truth) | `quarry_trackers::slamot` |
//! | [`ptb`] | Princeton Tracking Benchmark RGB-D sequences (paired rgb/depth PNGs, PTB depth encoding, init box) | `quarry_trackers::rgbd_person` |
//! | [`image_sequence`] | MOTChallenge-style image directories (`img1/000001.jpg`, ...) | the video trackers, `quarry motion` |
//! | [`leg_labels`] | the leg-tracker recordings' labels (leg centroids per scan) | scoring the lidar tracker |
//! | [`scans_csv`] | recorded 2-D laser scans, `stamp_s,r0..r{N-1}` CSV with a `scan_meta.json` geometry | `quarry_trackers::lidar_people` |
//!
//! Every reader returns [`DataError`] naming the file and the line on malformed or truncated
//! input; none panics (each is a fuzz target).
//!
//! ```
//! use quarry_core::ScanGeometry;
//! use quarry_data::scans_csv::{ScanCsvOptions, ScanCsvReader};
//! let g = ScanGeometry {
//!     n_beams: 3, angle_min: -0.1, angle_increment: 0.1,
//!     range_min: 0.05, range_max: 10.0, scan_period: 0.025,
//! };
//! let csv = "stamp_s,r0,r1,r2\n0.000,1.0,nan,2.5\n0.025,1.1,1.2,2.4\n";
//! let mut reader = ScanCsvReader::new(csv.as_bytes(), g, ScanCsvOptions::default())?;
//! let scans = reader.by_ref().collect::<Result<Vec<_>, _>>()?;
//! assert_eq!(scans.len(), 2);
//! assert_eq!(reader.stats().invalid_beams, 1);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod error;
pub mod image_sequence;
pub mod leg_labels;
pub mod mrclam;
pub mod ptb;
pub mod scans_csv;

pub use error::{DataError, Result};
