//! # quarry-eval
//!
//! Metrics for trackers, agreeing with the reference tools to 1e-6:
//! - [`mot`]: CLEAR MOT (MOTA, MOTP, ID switches, fragmentations, MT/PT/ML) with
//!   py-motmetrics' conventions, IDF1 / IDP / IDR, and HOTA / DetA / AssA / LocA with TrackEval's,
//!   generic over a [`Similarity`] ([`Iou`] for image boxes, [`Euclidean`] for world points).
//! - [`lsap`]: optimal assignment (an exact port of SciPy's solver) and [`hungarian_match`].
//! - [`motchallenge`]: the MOTChallenge text format (ground truth and results), read and write.
//! - [`position`]: position-error series — RMSE, NEES with its chi-square consistency test.
//! - [`ospa`]: the set distances OSPA and GOSPA (with GOSPA's decomposition).
//! - [`single_target`]: centre error, IoU success curve and AUC, precision at a threshold.
//!
//! ```
//! use quarry_eval::mot::{evaluate, Frame};
//! use quarry_eval::Euclidean;
//!
//! // Two people, tracked in world coordinates (metres), scored with a 0.5 m threshold.
//! let frames: Vec<Frame<[f64; 2]>> = (0..10)
//!     .map(|k| {
//!         let t = k as f64 * 0.1;
//!         Frame {
//!             gt: vec![(1, [t, 0.0]), (2, [t, 3.0])],
//!             hyp: vec![(10, [t + 0.1, 0.0]), (11, [t, 3.2])],
//!         }
//!     })
//!     .collect();
//! let s = evaluate(&frames, &Euclidean::new(0.5)?)?;
//! assert_eq!(s.clear.mota(), Some(1.0));
//! assert!((s.clear.motp().unwrap() - 0.15).abs() < 1e-12); // mean distance, metres
//! assert_eq!(s.identity.idf1(), Some(1.0));
//! assert!(s.hota.hota_mean() > 0.8);
//! # Ok::<(), quarry_eval::EvalError>(())
//! ```
//!
//! ## Features
//!
//! - `serde` (default): `serde::Serialize` on the MOT summaries ([`ClearMot`], [`Identity`],
//!   [`Hota`], [`MotSummary`]), for writing scores as JSON or CSV.
//!
//! quarry-core is used without its default features; enable `quarry-core/serde` if you also
//! serialise core types.

mod error;
pub mod lsap;
pub mod mot;
pub mod motchallenge;
pub mod ospa;
pub mod position;
pub mod similarity;
pub mod single_target;

pub use error::EvalError;
pub use lsap::{hungarian_match, linear_sum_assignment};
pub use mot::{
    ClearMot, Frame, Hota, Identity, MotEvaluation, MotSummary, clear_mot, evaluate, hota, idf1,
};
pub use similarity::{Euclidean, Iou, Ltwh, Similarity};
