//! The wire format of spec 003 §7.1 (little-endian, version 1), sans-IO.
//!
//! ```text
//! offset size field
//!  0     4    magic "QRY1"
//!  4     1    version = 1
//!  5     1    kind (1 DynamicScan, 2 BackgroundScan, 3 Hello, 4 SyncRequest, 5 SyncReply,
//!             6 Heartbeat, 7 BackgroundRequest)
//!  6     2    sensor_id u16
//!  8     4    seq u32
//! 12     1    part (0-based)
//! 13     1    parts (>= 1)
//! 14     2    n (entries in this part)
//! 16     2    flags (bit0 CLOCK_SYNCED, bit1 BG_WARMING, bit2 SENSOR_ERROR)
//! 18     2    reserved = 0
//! 20     8    t_capture_us i64
//! 28     8    t_send_us i64
//! 36     ...  payload
//! end    4    CRC-32/ISO-HDLC over all preceding bytes
//! ```
//!
//! Payloads: scans carry `n` × {`beam: u16`, `range_mm: u16`} (at most 350 per part); `Hello`,
//! `SyncReply` and `Heartbeat` carry one fixed-size record and have `n = 1`; `SyncRequest` and
//! `BackgroundRequest` carry nothing and have `n = 0` (this use of `n` for the non-scan kinds
//! is our choice; the spec leaves it open). [`Message::decode`] validates everything and never
//! panics; any single-bit flip is rejected (CRC-32 detects every single-bit error).

use quarry_core::{SensorId, TimeUs};
use thiserror::Error;

/// The four magic bytes.
pub const MAGIC: [u8; 4] = *b"QRY1";
/// The protocol version.
pub const VERSION: u8 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 36;
/// CRC trailer length in bytes.
pub const CRC_LEN: usize = 4;
/// Maximum `(beam, range)` pairs in one part.
pub const MAX_POINTS_PER_PART: usize = 350;

/// Flag bit: the sender's clock is synchronised.
pub const FLAG_CLOCK_SYNCED: u16 = 1;
/// Flag bit: the sender's background model is still warming up.
pub const FLAG_BG_WARMING: u16 = 2;
/// Flag bit: the sensor reported an error.
pub const FLAG_SENSOR_ERROR: u16 = 4;

/// Why a datagram was rejected.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum WireError {
    /// Shorter than a header plus CRC.
    #[error("message too short: {0} bytes")]
    TooShort(usize),
    /// The magic bytes are not `QRY1`.
    #[error("bad magic")]
    BadMagic,
    /// Unsupported version.
    #[error("unsupported version {0}")]
    BadVersion(u8),
    /// Unknown message kind.
    #[error("unknown message kind {0}")]
    UnknownKind(u8),
    /// The byte length does not match the header's `n` and kind.
    #[error("length mismatch: header implies {expected} bytes, got {got}")]
    BadLength {
        /// Length implied by the header.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// The CRC does not match.
    #[error("CRC mismatch: stored {stored:#010x}, computed {computed:#010x}")]
    BadCrc {
        /// CRC in the message.
        stored: u32,
        /// CRC of the bytes.
        computed: u32,
    },
    /// More than 350 points in a part.
    #[error("{0} points in one part (max 350)")]
    TooManyPoints(usize),
    /// `part >= parts` or `parts == 0`.
    #[error("bad part numbering: part {part} of {parts}")]
    BadPart {
        /// 0-based part index.
        part: u8,
        /// Number of parts.
        parts: u8,
    },
    /// The reserved field is not zero.
    #[error("reserved field is not zero")]
    Reserved,
    /// The payload does not fit the kind (e.g. `n != 1` for a Hello).
    #[error("entry count {n} invalid for message kind {kind:?}")]
    BadCount {
        /// The kind.
        kind: Kind,
        /// The entry count.
        n: u16,
    },
    /// A scan that needs more than 255 parts.
    #[error("scan of {0} points needs more than 255 parts")]
    TooManyParts(usize),
}

/// Message kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Kind {
    /// The dynamic points of one scan.
    DynamicScan = 1,
    /// A scanner's long-term background (for calibration).
    BackgroundScan = 2,
    /// A client announcing itself (and its geometry).
    Hello = 3,
    /// Clock-sync request (t1 in `t_send`).
    SyncRequest = 4,
    /// Clock-sync reply.
    SyncReply = 5,
    /// Client statistics.
    Heartbeat = 6,
    /// Server asking a client for its background.
    BackgroundRequest = 7,
}

impl Kind {
    /// Parses the kind byte.
    pub fn from_u8(b: u8) -> Result<Self, WireError> {
        Ok(match b {
            1 => Self::DynamicScan,
            2 => Self::BackgroundScan,
            3 => Self::Hello,
            4 => Self::SyncRequest,
            5 => Self::SyncReply,
            6 => Self::Heartbeat,
            7 => Self::BackgroundRequest,
            other => return Err(WireError::UnknownKind(other)),
        })
    }
}

/// The message header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Message kind (must match the payload).
    pub kind: Kind,
    /// Sending scanner.
    pub sensor: SensorId,
    /// Per-sensor scan counter (per kind); request id for sync.
    pub seq: u32,
    /// 0-based part index.
    pub part: u8,
    /// Number of parts (≥ 1).
    pub parts: u8,
    /// Flag bits (`FLAG_*`).
    pub flags: u16,
    /// Synchronised capture time of the front beam.
    pub t_capture: TimeUs,
    /// Synchronised send time.
    pub t_send: TimeUs,
}

/// `Hello` payload: the client's scanner geometry and window.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Hello {
    /// Beams per scan.
    pub n_beams: u16,
    /// Beam index of the front (+x) direction.
    pub front_step: u16,
    /// Beams per full turn (1440 for the UTM-30LX).
    pub slit_division: u16,
    /// Minimum valid range, mm.
    pub range_min_mm: u16,
    /// Maximum valid range, mm.
    pub range_max_mm: u16,
    /// Scan period, µs.
    pub scan_period_us: u32,
    /// Background window length `m`.
    pub window_m: u16,
}

/// `Heartbeat` payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Heartbeat {
    /// Scans captured.
    pub captured: u32,
    /// Messages sent.
    pub sent: u32,
    /// Current clock offset estimate, µs.
    pub offset_us: i64,
    /// Last round-trip time, µs.
    pub rtt_us: i32,
}

/// A message payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Payload {
    /// `(beam, range_mm)` pairs (DynamicScan, BackgroundScan).
    Points(Vec<(u16, u16)>),
    /// Hello record.
    Hello(Hello),
    /// Sync reply: client send time t1, server receive t2, server send t3 (µs).
    SyncReply {
        /// Client send time.
        t1: i64,
        /// Server receive time.
        t2: i64,
        /// Server send time.
        t3: i64,
    },
    /// Heartbeat record.
    Heartbeat(Heartbeat),
    /// No payload (SyncRequest, BackgroundRequest).
    Empty,
}

/// One wire message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Message {
    /// Header.
    pub header: Header,
    /// Payload (must match `header.kind`).
    pub payload: Payload,
}

const HELLO_LEN: usize = 16;
const SYNC_REPLY_LEN: usize = 24;
const HEARTBEAT_LEN: usize = 20;

fn payload_len(kind: Kind, n: u16) -> Result<usize, WireError> {
    let bad = || WireError::BadCount { kind, n };
    Ok(match kind {
        Kind::DynamicScan | Kind::BackgroundScan => {
            if usize::from(n) > MAX_POINTS_PER_PART {
                return Err(WireError::TooManyPoints(usize::from(n)));
            }
            4 * usize::from(n)
        }
        Kind::Hello if n == 1 => HELLO_LEN,
        Kind::SyncReply if n == 1 => SYNC_REPLY_LEN,
        Kind::Heartbeat if n == 1 => HEARTBEAT_LEN,
        Kind::SyncRequest | Kind::BackgroundRequest if n == 0 => 0,
        _ => return Err(bad()),
    })
}

/// CRC-32/ISO-HDLC (the zlib/Ethernet CRC).
pub fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

fn rd_u16(b: &[u8], o: usize) -> u16 {
    u16::from_le_bytes([b[o], b[o + 1]])
}
fn rd_u32(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]])
}
fn rd_i64(b: &[u8], o: usize) -> i64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[o..o + 8]);
    i64::from_le_bytes(a)
}

impl Message {
    /// Number of entries (`n`) this message's payload encodes to.
    fn count(&self) -> Result<u16, WireError> {
        let ok = matches!(
            (&self.payload, self.header.kind),
            (Payload::Points(_), Kind::DynamicScan | Kind::BackgroundScan)
                | (Payload::Hello(_), Kind::Hello)
                | (Payload::SyncReply { .. }, Kind::SyncReply)
                | (Payload::Heartbeat(_), Kind::Heartbeat)
                | (Payload::Empty, Kind::SyncRequest | Kind::BackgroundRequest)
        );
        let n = match &self.payload {
            Payload::Points(p) => {
                if p.len() > MAX_POINTS_PER_PART {
                    return Err(WireError::TooManyPoints(p.len()));
                }
                p.len() as u16
            }
            Payload::Empty => 0,
            _ => 1,
        };
        if ok {
            Ok(n)
        } else {
            Err(WireError::BadCount {
                kind: self.header.kind,
                n,
            })
        }
    }

    /// Encodes the message (appends to `out`, which is cleared first).
    pub fn encode_into(&self, out: &mut Vec<u8>) -> Result<(), WireError> {
        let h = &self.header;
        if h.parts == 0 || h.part >= h.parts {
            return Err(WireError::BadPart {
                part: h.part,
                parts: h.parts,
            });
        }
        let n = self.count()?;
        out.clear();
        out.reserve(HEADER_LEN + payload_len(h.kind, n)? + CRC_LEN);
        out.extend_from_slice(&MAGIC);
        out.push(VERSION);
        out.push(h.kind as u8);
        out.extend_from_slice(&h.sensor.0.to_le_bytes());
        out.extend_from_slice(&h.seq.to_le_bytes());
        out.push(h.part);
        out.push(h.parts);
        out.extend_from_slice(&n.to_le_bytes());
        out.extend_from_slice(&h.flags.to_le_bytes());
        out.extend_from_slice(&0u16.to_le_bytes());
        out.extend_from_slice(&h.t_capture.0.to_le_bytes());
        out.extend_from_slice(&h.t_send.0.to_le_bytes());
        match &self.payload {
            Payload::Points(p) => {
                for &(b, r) in p {
                    out.extend_from_slice(&b.to_le_bytes());
                    out.extend_from_slice(&r.to_le_bytes());
                }
            }
            Payload::Hello(x) => {
                for v in [
                    x.n_beams,
                    x.front_step,
                    x.slit_division,
                    x.range_min_mm,
                    x.range_max_mm,
                ] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                out.extend_from_slice(&x.scan_period_us.to_le_bytes());
                out.extend_from_slice(&x.window_m.to_le_bytes());
            }
            Payload::SyncReply { t1, t2, t3 } => {
                for v in [t1, t2, t3] {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
            Payload::Heartbeat(x) => {
                out.extend_from_slice(&x.captured.to_le_bytes());
                out.extend_from_slice(&x.sent.to_le_bytes());
                out.extend_from_slice(&x.offset_us.to_le_bytes());
                out.extend_from_slice(&x.rtt_us.to_le_bytes());
            }
            Payload::Empty => {}
        }
        let crc = crc32(out);
        out.extend_from_slice(&crc.to_le_bytes());
        Ok(())
    }

    /// Encodes the message into a new buffer.
    pub fn encode(&self) -> Result<Vec<u8>, WireError> {
        let mut v = Vec::new();
        self.encode_into(&mut v)?;
        Ok(v)
    }

    /// Decodes one message; validates magic, version, kind, part numbering, length, reserved
    /// field and CRC. Never panics.
    pub fn decode(b: &[u8]) -> Result<Message, WireError> {
        if b.len() < HEADER_LEN + CRC_LEN {
            return Err(WireError::TooShort(b.len()));
        }
        if b[0..4] != MAGIC {
            return Err(WireError::BadMagic);
        }
        if b[4] != VERSION {
            return Err(WireError::BadVersion(b[4]));
        }
        let kind = Kind::from_u8(b[5])?;
        let n = rd_u16(b, 14);
        let expected = HEADER_LEN + payload_len(kind, n)? + CRC_LEN;
        if b.len() != expected {
            return Err(WireError::BadLength {
                expected,
                got: b.len(),
            });
        }
        let body = &b[..expected - CRC_LEN];
        let stored = rd_u32(b, expected - CRC_LEN);
        let computed = crc32(body);
        if stored != computed {
            return Err(WireError::BadCrc { stored, computed });
        }
        let (part, parts) = (b[12], b[13]);
        if parts == 0 || part >= parts {
            return Err(WireError::BadPart { part, parts });
        }
        if rd_u16(b, 18) != 0 {
            return Err(WireError::Reserved);
        }
        let header = Header {
            kind,
            sensor: SensorId(rd_u16(b, 6)),
            seq: rd_u32(b, 8),
            part,
            parts,
            flags: rd_u16(b, 16),
            t_capture: TimeUs(rd_i64(b, 20)),
            t_send: TimeUs(rd_i64(b, 28)),
        };
        let p = HEADER_LEN;
        let payload = match kind {
            Kind::DynamicScan | Kind::BackgroundScan => Payload::Points(
                (0..usize::from(n))
                    .map(|i| (rd_u16(b, p + 4 * i), rd_u16(b, p + 4 * i + 2)))
                    .collect(),
            ),
            Kind::Hello => Payload::Hello(Hello {
                n_beams: rd_u16(b, p),
                front_step: rd_u16(b, p + 2),
                slit_division: rd_u16(b, p + 4),
                range_min_mm: rd_u16(b, p + 6),
                range_max_mm: rd_u16(b, p + 8),
                scan_period_us: rd_u32(b, p + 10),
                window_m: rd_u16(b, p + 14),
            }),
            Kind::SyncReply => Payload::SyncReply {
                t1: rd_i64(b, p),
                t2: rd_i64(b, p + 8),
                t3: rd_i64(b, p + 16),
            },
            Kind::Heartbeat => Payload::Heartbeat(Heartbeat {
                captured: rd_u32(b, p),
                sent: rd_u32(b, p + 4),
                offset_us: rd_i64(b, p + 8),
                rtt_us: rd_u32(b, p + 16) as i32,
            }),
            Kind::SyncRequest | Kind::BackgroundRequest => Payload::Empty,
        };
        Ok(Message { header, payload })
    }
}

/// Splits a scan's `(beam, range_mm)` pairs into parts of at most 350 and encodes each.
/// `header.part`/`header.parts` are overwritten; a scan with no points still gives one message
/// (`n = 0`, `parts = 1`), so "nothing moving" can be told from "packet missing".
pub fn encode_scan(header: Header, points: &[(u16, u16)]) -> Result<Vec<Vec<u8>>, WireError> {
    let chunks: Vec<&[(u16, u16)]> = if points.is_empty() {
        vec![&[]]
    } else {
        points.chunks(MAX_POINTS_PER_PART).collect()
    };
    let parts = u8::try_from(chunks.len()).map_err(|_| WireError::TooManyParts(points.len()))?;
    chunks
        .iter()
        .enumerate()
        .map(|(i, c)| {
            Message {
                header: Header {
                    part: i as u8,
                    parts,
                    ..header
                },
                payload: Payload::Points(c.to_vec()),
            }
            .encode()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_message() -> impl Strategy<Value = Message> {
        let kind = prop_oneof![
            Just(Kind::DynamicScan),
            Just(Kind::BackgroundScan),
            Just(Kind::Hello),
            Just(Kind::SyncRequest),
            Just(Kind::SyncReply),
            Just(Kind::Heartbeat),
            Just(Kind::BackgroundRequest)
        ];
        (
            kind,
            any::<u16>(),
            any::<u32>(),
            (1u8..=255).prop_flat_map(|parts| (0..parts, Just(parts))),
            any::<u16>(),
            any::<i64>(),
            any::<i64>(),
            prop::collection::vec(any::<(u16, u16)>(), 0..=MAX_POINTS_PER_PART),
            any::<[u16; 6]>(),
            any::<(i64, i64, i64)>(),
        )
            .prop_map(
                |(kind, sensor, seq, (part, parts), flags, tc, ts, pts, h, t)| {
                    let payload = match kind {
                        Kind::DynamicScan | Kind::BackgroundScan => Payload::Points(pts),
                        Kind::Hello => Payload::Hello(Hello {
                            n_beams: h[0],
                            front_step: h[1],
                            slit_division: h[2],
                            range_min_mm: h[3],
                            range_max_mm: h[4],
                            scan_period_us: u32::from(h[5]) * 7,
                            window_m: h[5],
                        }),
                        Kind::SyncReply => Payload::SyncReply {
                            t1: t.0,
                            t2: t.1,
                            t3: t.2,
                        },
                        Kind::Heartbeat => Payload::Heartbeat(Heartbeat {
                            captured: u32::from(h[0]),
                            sent: u32::from(h[1]),
                            offset_us: t.0,
                            rtt_us: t.1 as i32,
                        }),
                        _ => Payload::Empty,
                    };
                    Message {
                        header: Header {
                            kind,
                            sensor: SensorId(sensor),
                            seq,
                            part,
                            parts,
                            flags,
                            t_capture: TimeUs(tc),
                            t_send: TimeUs(ts),
                        },
                        payload,
                    }
                },
            )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn round_trip(m in arb_message()) {
            let b = m.encode().unwrap();
            prop_assert!(b.len() <= 1472);
            prop_assert_eq!(Message::decode(&b).unwrap(), m);
        }

        #[test]
        fn any_single_bit_flip_is_rejected(m in arb_message(), bit in any::<prop::sample::Index>()) {
            let mut b = m.encode().unwrap();
            let i = bit.index(b.len() * 8);
            b[i / 8] ^= 1 << (i % 8);
            prop_assert!(Message::decode(&b).is_err());
        }

        #[test]
        fn truncation_is_rejected(m in arb_message(), cut in any::<prop::sample::Index>()) {
            let b = m.encode().unwrap();
            let k = cut.index(b.len());
            prop_assert!(Message::decode(&b[..k]).is_err());
        }

        #[test]
        fn garbage_never_panics(b in prop::collection::vec(any::<u8>(), 0..200)) {
            let _ = Message::decode(&b);
        }
    }

    #[test]
    fn every_bit_of_a_scan_message() {
        let h = Header {
            kind: Kind::DynamicScan,
            sensor: SensorId(2),
            seq: 77,
            part: 0,
            parts: 1,
            flags: FLAG_CLOCK_SYNCED,
            t_capture: TimeUs(123_456),
            t_send: TimeUs(124_000),
        };
        let parts = encode_scan(h, &(0..800).map(|i| (i, 1000 + i)).collect::<Vec<_>>()).unwrap();
        assert_eq!(parts.len(), 3);
        let b = &parts[2];
        assert_eq!(b.len(), 36 + 4 * 100 + 4);
        let m = Message::decode(b).unwrap();
        assert_eq!((m.header.part, m.header.parts), (2, 3));
        for i in 0..b.len() * 8 {
            let mut c = b.clone();
            c[i / 8] ^= 1 << (i % 8);
            assert!(Message::decode(&c).is_err(), "bit {i}");
        }
        let empty = encode_scan(h, &[]).unwrap();
        assert_eq!(empty.len(), 1);
        assert_eq!(
            Message::decode(&empty[0]).unwrap().payload,
            Payload::Points(vec![])
        );
        // the CRC is the standard one
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }
}
