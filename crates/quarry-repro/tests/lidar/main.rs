//! Paper 003 (people tracking with distributed 2-D laser scanners): the scenario tests on the
//! room simulator, `calibration = icp`, and the runs on the real leg-tracker recordings. One
//! test binary for the paper (each `tests/*.rs` file links a binary of its own).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod calib;
mod faults;
mod net;
mod people;
mod recorded;
