//! Networked operation, sans-IO (spec 003 §7): the wire format, clock synchronisation and the
//! server's frame assembly. No sockets here: the caller feeds bytes and times in and takes
//! frames out, so the same code runs in the simulator and behind real UDP sockets.

mod clock;
mod frames;
pub mod wire;

pub use clock::{ClockSync, SyncMode, SyncSample, ntp_sample};
pub use frames::{
    Disposition, Frame, FrameAssembler, FrameConfig, FramePoint, FusionStats, ScansPerFrame,
    SensorConfig,
};
