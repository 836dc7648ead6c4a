//! # quarry-assoc
//!
//! Placeholder crate: its contents land with their issue.
//!
//! ```
//! assert_eq!(1 + 1, 2);
//! ```
