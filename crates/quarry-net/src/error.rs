//! The crate's error type.

use crate::proto::wire::WireError;
use quarry_trackers::TrackerError;
use thiserror::Error;

/// Everything that can go wrong in a node, the server or a transport.
#[derive(Debug, Error)]
pub enum NetError {
    /// The transport failed (could not open, publish or receive).
    #[error("transport: {0}")]
    Transport(String),
    /// A §7.1 wire message did not encode or decode.
    #[error("wire: {0}")]
    Wire(#[from] WireError),
    /// A node-to-server or track message did not decode.
    #[error("envelope: {0}")]
    Envelope(#[from] EnvelopeError),
    /// The tracker, the background model or the fusion failed.
    #[error(transparent)]
    Tracker(#[from] TrackerError),
    /// A shared error kind (bad parameter, non-finite value, ...), e.g. from the frame
    /// assembler.
    #[error(transparent)]
    Core(#[from] quarry_core::CoreError),
    /// A recorded scan source could not be read.
    #[error(transparent)]
    Data(#[from] quarry_data::DataError),
    /// A bad option or configuration.
    #[error("config: {0}")]
    Config(String),
    /// Nothing arrived in time.
    #[error("timeout: {0}")]
    Timeout(String),
    /// The server refused this node (an unknown sensor id, the other clock mode), with its
    /// reason.
    #[error("refused by the server: {0}")]
    Refused(String),
    /// The server stopped before this node was done (interrupted, or its duration elapsed).
    #[error("{0}")]
    ServerEnded(String),
    /// Another server of the same kind already runs on this network: this one gives way.
    #[error("{0}")]
    Conflict(String),
    /// Reading a scan source or writing an output failed.
    #[error("i/o: {0}")]
    Io(String),
}

/// Why an envelope (sim step, end marker or track message) was rejected.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum EnvelopeError {
    /// Shorter than its fixed part, or a length field points past the end.
    #[error("truncated: need {need} bytes, have {have}")]
    Truncated {
        /// Bytes needed.
        need: usize,
        /// Bytes present.
        have: usize,
    },
    /// Wrong magic bytes.
    #[error("bad magic")]
    BadMagic,
    /// Unsupported version.
    #[error("unsupported version {0}")]
    BadVersion(u8),
    /// Unknown message kind.
    #[error("unknown kind {0}")]
    BadKind(u8),
    /// Bytes left over after the declared content.
    #[error("{0} trailing bytes")]
    Trailing(usize),
    /// The CRC-32 trailer does not match.
    #[error("CRC mismatch")]
    BadCrc,
    /// A field holds an impossible value (non-finite coordinate, too many entries).
    #[error("invalid field {0}")]
    Invalid(&'static str),
}
