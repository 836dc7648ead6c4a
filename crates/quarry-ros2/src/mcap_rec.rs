//! Recording ROS 2 messages into an MCAP file (feature `mcap`), with the `ros2` profile, CDR
//! message encoding and each type's `ros2msg` definition in its schema record: what `ros2 bag
//! record -s mcap` writes, so Foxglove, `ros2 bag`, Rerun and the Python `mcap` readers open it.
//!
//! The container is the `mcap` crate (Foxglove's own Rust implementation of the format), without
//! its default `zstd`/`lz4` features: chunks are uncompressed, which keeps a C build of zstd out
//! of quarry and costs nothing in the common case (scans and tracks are small; the video tracker
//! stores its frames as PNG `CompressedImage`s).

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::rmw_zenoh::check_topic;
use crate::schema::Message;

/// What went wrong while recording.
#[derive(Debug, Error)]
pub enum RecordError {
    /// The file could not be created or written.
    #[error("{path}: {source}")]
    Io {
        /// The MCAP path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The MCAP writer failed.
    #[error("{path}: MCAP: {msg}")]
    Mcap {
        /// The MCAP path.
        path: PathBuf,
        /// The writer's message.
        msg: String,
    },
    /// An invalid topic name.
    #[error("MCAP topic: {0}")]
    Topic(String),
    /// One topic used with two message types.
    #[error("MCAP topic `{topic}` already carries {existing}, not {new}")]
    TypeClash {
        /// The topic.
        topic: String,
        /// Its type.
        existing: &'static str,
        /// The type written now.
        new: &'static str,
    },
}

/// What a finished recording holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordSummary {
    /// Messages written.
    pub messages: u64,
    /// Topics (channels).
    pub channels: usize,
    /// Message types (schemas).
    pub schemas: usize,
}

/// An MCAP file being written.
pub struct McapRecorder {
    writer: mcap::Writer<BufWriter<File>>,
    path: PathBuf,
    schemas: HashMap<&'static str, u16>,
    channels: HashMap<String, (u16, &'static str, u32)>,
    messages: u64,
}

impl std::fmt::Debug for McapRecorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapRecorder")
            .field("path", &self.path)
            .field("messages", &self.messages)
            .finish_non_exhaustive()
    }
}

impl McapRecorder {
    /// Creates (or truncates) `path`.
    ///
    /// # Errors
    /// [`RecordError::Io`] naming the path (a missing or unwritable directory, ...).
    pub fn create(path: &Path) -> Result<Self, RecordError> {
        let file = File::create(path).map_err(|source| RecordError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let opts = mcap::WriteOptions::new()
            .compression(None)
            .profile("ros2")
            .library(concat!("quarry-ros2 ", env!("CARGO_PKG_VERSION")));
        let writer = opts
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| RecordError::Mcap {
                path: path.to_path_buf(),
                msg: e.to_string(),
            })?;
        Ok(Self {
            writer,
            path: path.to_path_buf(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            messages: 0,
        })
    }

    fn mcap_err(&self, e: &mcap::McapError) -> RecordError {
        RecordError::Mcap {
            path: self.path.clone(),
            msg: e.to_string(),
        }
    }

    /// Writes `msg` on `topic` at `stamp_ns` (log and publish time, ns; a run's own clock or the
    /// Unix epoch). The first message on a topic creates its channel (and its type's schema).
    ///
    /// # Errors
    /// An invalid topic, a topic already used with another type, or a write failure.
    pub fn write<M: Message>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), RecordError> {
        let data = msg.to_cdr();
        self.write_cdr::<M>(topic, stamp_ns, &data)
    }

    /// As [`McapRecorder::write`], with the message already serialized (e.g. a CDR payload
    /// received from ROS 2).
    ///
    /// # Errors
    /// As [`McapRecorder::write`].
    pub fn write_cdr<M: Message>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        data: &[u8],
    ) -> Result<(), RecordError> {
        let (id, seq) = self.channel::<M>(topic)?;
        let header = mcap::records::MessageHeader {
            channel_id: id,
            sequence: seq,
            log_time: stamp_ns,
            publish_time: stamp_ns,
        };
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| self.mcap_err(&e))?;
        self.messages += 1;
        Ok(())
    }

    fn channel<M: Message>(&mut self, topic: &str) -> Result<(u16, u32), RecordError> {
        if let Some((id, ty, seq)) = self.channels.get_mut(topic) {
            if *ty != M::NAME {
                return Err(RecordError::TypeClash {
                    topic: topic.into(),
                    existing: ty,
                    new: M::NAME,
                });
            }
            *seq += 1;
            return Ok((*id, *seq));
        }
        check_topic(topic).map_err(RecordError::Topic)?;
        let schema = if let Some(s) = self.schemas.get(M::NAME) {
            *s
        } else {
            let s = self
                .writer
                .add_schema(M::NAME, "ros2msg", M::definition().as_bytes())
                .map_err(|e| self.mcap_err(&e))?;
            self.schemas.insert(M::NAME, s);
            s
        };
        let id = self
            .writer
            .add_channel(schema, topic, "cdr", &BTreeMap::new())
            .map_err(|e| self.mcap_err(&e))?;
        self.channels.insert(topic.to_string(), (id, M::NAME, 1));
        Ok((id, 1))
    }

    /// Writes a metadata record (`name` and string pairs), e.g. the command line of a run.
    ///
    /// # Errors
    /// A write failure.
    pub fn metadata(
        &mut self,
        name: &str,
        entries: BTreeMap<String, String>,
    ) -> Result<(), RecordError> {
        let m = mcap::records::Metadata {
            name: name.to_string(),
            metadata: entries,
        };
        self.writer
            .write_metadata(&m)
            .map_err(|e| self.mcap_err(&e))
    }

    /// Messages written so far.
    pub fn messages(&self) -> u64 {
        self.messages
    }

    /// Writes the summary and footer and closes the file.
    ///
    /// # Errors
    /// A write failure (e.g. the disk filled up).
    pub fn finish(mut self) -> Result<RecordSummary, RecordError> {
        self.writer.finish().map_err(|e| self.mcap_err(&e))?;
        let summary = RecordSummary {
            messages: self.messages,
            channels: self.channels.len(),
            schemas: self.schemas.len(),
        };
        let path = self.path.clone();
        // flush the buffer here, where its error can be reported (not in a drop)
        let mut file = self.writer.into_inner();
        std::io::Write::flush(&mut file).map_err(|source| RecordError::Io { path, source })?;
        Ok(summary)
    }
}
