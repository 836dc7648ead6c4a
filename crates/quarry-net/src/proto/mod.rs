//! The sans-IO protocol of the networked tracker (spec 003 §7): the wire format, clock
//! synchronisation and the server's frame assembly. No sockets here: the caller feeds bytes and
//! times in and takes frames out, so the same code runs in the simulator, over [`crate::LocalBus`],
//! over zenoh, or behind a user's own UDP sockets, and needs no zenoh.

mod clock;
mod frames;
pub mod wire;

pub use clock::{ClockSync, SyncMode, SyncSample, ntp_sample};
pub use frames::{
    Disposition, Frame, FrameAssembler, FrameConfig, FramePoint, FusionStats, ScansPerFrame,
    SensorConfig,
};
