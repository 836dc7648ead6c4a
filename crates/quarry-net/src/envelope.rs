//! The messages that travel beside the §7.1 wire datagrams (little-endian, CRC-32 trailer).
//!
//! ```text
//! SimStep (virtual-time mode, node -> server), magic "QSIM", kind 1
//!   0  4  magic            4  1  version = 1     5  1  kind = 1
//!   6  2  sensor u16       8  4  step u32 (per-node counter, 0, 1, 2, ...)
//!  12  8  t_true_us i64 (simulated capture time)   20  8  t_end_us i64 (scenario end)
//!  28  2  n_arrivals u16  30  2  n_datagrams u16
//!  32  8*n_arrivals       simulated arrival times (i64) of each delivered copy
//!      n_datagrams x { len u16, len bytes }   the scan's §7.1 datagrams
//! end  4  CRC-32/ISO-HDLC over all preceding bytes
//!
//! EndOfStream (node -> server), magic "QSIM", kind 2
//!   0  4  magic  4 1 version  5 1 kind = 2  6 2 sensor  8 4 steps sent u32  12 8 t_end_us i64
//!  20  4  CRC
//!
//! TrackMessage (server -> anyone), magic "QTRK"
//!   0  4  magic  4 1 version = 1  5 1 flags (bit0 no_data)  6 2 n u16
//!   8  8  frame u64  16 8 t_us i64
//!  24  n x 57 bytes { id u32, support u32, flags u8 (bit0 born, bit1 gate_replaced),
//!                     x, y, alpha, vx, vy, rms: f64 }
//! end  4  CRC
//! ```
//! Decoding checks every length against the buffer before reading and never panics.

use crate::error::EnvelopeError;
use crate::proto::wire::crc32;
use quarry_core::{SensorId, TimeUs};
use quarry_trackers::lidar_people::LidarTrack;

const SIM_MAGIC: [u8; 4] = *b"QSIM";
const TRK_MAGIC: [u8; 4] = *b"QTRK";
const VERSION: u8 = 1;
const TRACK_LEN: usize = 57;
/// At most this many tracks in one message.
pub const MAX_TRACKS: usize = 4096;

/// One captured scan of a node in virtual-time mode: the scan's datagrams and the simulated
/// arrival times of each delivered copy (none = lost, two = duplicated).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SimStep {
    /// Sending sensor.
    pub sensor: SensorId,
    /// Per-node step counter (0, 1, 2, ...): the server orders and de-duplicates by it.
    pub step: u32,
    /// Simulated (true) capture time.
    pub t_true: TimeUs,
    /// End of the simulated scenario (the server checks that all nodes agree).
    pub t_end: TimeUs,
    /// Simulated arrival times at the server of each delivered copy.
    pub arrivals: Vec<TimeUs>,
    /// The scan's §7.1 datagrams (several parts when it has more than 350 points).
    pub datagrams: Vec<Vec<u8>>,
}

/// A node's last message: it sent `steps` steps (virtual-time mode) or stopped (wall mode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EndOfStream {
    /// Sending sensor.
    pub sensor: SensorId,
    /// Steps sent (virtual-time mode; the server waits for all of them), scans in wall mode.
    pub steps: u32,
    /// End of the scenario (virtual-time mode) or the node's last stamp (wall mode).
    pub t_end: TimeUs,
}

/// A decoded node message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SimMessage {
    /// A step.
    Step(SimStep),
    /// An end marker.
    End(EndOfStream),
}

/// The tracks of one closed frame, as the server publishes them.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackMessage {
    /// Frame index.
    pub frame: u64,
    /// Frame time.
    pub t: TimeUs,
    /// The frame had no data (the tracker skipped it).
    pub no_data: bool,
    /// The track rows.
    pub tracks: Vec<LidarTrack>,
}

struct Reader<'a> {
    b: &'a [u8],
    o: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], EnvelopeError> {
        let end = self.o.checked_add(n).ok_or(EnvelopeError::Truncated {
            need: usize::MAX,
            have: self.b.len(),
        })?;
        let s = self.b.get(self.o..end).ok_or(EnvelopeError::Truncated {
            need: end,
            have: self.b.len(),
        })?;
        self.o = end;
        Ok(s)
    }
    fn arr<const N: usize>(&mut self) -> Result<[u8; N], EnvelopeError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn u8(&mut self) -> Result<u8, EnvelopeError> {
        Ok(self.arr::<1>()?[0])
    }
    fn u16(&mut self) -> Result<u16, EnvelopeError> {
        Ok(u16::from_le_bytes(self.arr()?))
    }
    fn u32(&mut self) -> Result<u32, EnvelopeError> {
        Ok(u32::from_le_bytes(self.arr()?))
    }
    fn u64(&mut self) -> Result<u64, EnvelopeError> {
        Ok(u64::from_le_bytes(self.arr()?))
    }
    fn i64(&mut self) -> Result<i64, EnvelopeError> {
        Ok(i64::from_le_bytes(self.arr()?))
    }
    fn f64(&mut self) -> Result<f64, EnvelopeError> {
        Ok(f64::from_le_bytes(self.arr()?))
    }
}

/// Checks the CRC trailer and returns the body.
fn body(b: &[u8]) -> Result<&[u8], EnvelopeError> {
    if b.len() < 8 {
        return Err(EnvelopeError::Truncated {
            need: 8,
            have: b.len(),
        });
    }
    let (body, tail) = b.split_at(b.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    if crc32(body) != stored {
        return Err(EnvelopeError::BadCrc);
    }
    Ok(body)
}

fn finish(mut out: Vec<u8>) -> Vec<u8> {
    let c = crc32(&out);
    out.extend_from_slice(&c.to_le_bytes());
    out
}

impl SimMessage {
    /// Encodes the message. Fails when a count does not fit its u16 field or a datagram is
    /// longer than 65535 bytes.
    pub fn encode(&self) -> Result<Vec<u8>, EnvelopeError> {
        let mut o = Vec::new();
        o.extend_from_slice(&SIM_MAGIC);
        o.push(VERSION);
        match self {
            Self::Step(s) => {
                o.push(1);
                o.extend_from_slice(&s.sensor.0.to_le_bytes());
                o.extend_from_slice(&s.step.to_le_bytes());
                o.extend_from_slice(&s.t_true.0.to_le_bytes());
                o.extend_from_slice(&s.t_end.0.to_le_bytes());
                let na = u16::try_from(s.arrivals.len())
                    .map_err(|_| EnvelopeError::Invalid("n_arrivals"))?;
                let nd = u16::try_from(s.datagrams.len())
                    .map_err(|_| EnvelopeError::Invalid("n_datagrams"))?;
                o.extend_from_slice(&na.to_le_bytes());
                o.extend_from_slice(&nd.to_le_bytes());
                for a in &s.arrivals {
                    o.extend_from_slice(&a.0.to_le_bytes());
                }
                for d in &s.datagrams {
                    let l = u16::try_from(d.len())
                        .map_err(|_| EnvelopeError::Invalid("datagram length"))?;
                    o.extend_from_slice(&l.to_le_bytes());
                    o.extend_from_slice(d);
                }
            }
            Self::End(e) => {
                o.push(2);
                o.extend_from_slice(&e.sensor.0.to_le_bytes());
                o.extend_from_slice(&e.steps.to_le_bytes());
                o.extend_from_slice(&e.t_end.0.to_le_bytes());
            }
        }
        Ok(finish(o))
    }

    /// Decodes a message; validates magic, version, kind, every length and the CRC.
    pub fn decode(b: &[u8]) -> Result<Self, EnvelopeError> {
        let body = body(b)?;
        let mut r = Reader { b: body, o: 0 };
        if r.arr::<4>()? != SIM_MAGIC {
            return Err(EnvelopeError::BadMagic);
        }
        let v = r.u8()?;
        if v != VERSION {
            return Err(EnvelopeError::BadVersion(v));
        }
        let kind = r.u8()?;
        let sensor = SensorId(r.u16()?);
        let m = match kind {
            1 => {
                let step = r.u32()?;
                let t_true = TimeUs(r.i64()?);
                let t_end = TimeUs(r.i64()?);
                let na = usize::from(r.u16()?);
                let nd = usize::from(r.u16()?);
                let mut arrivals = Vec::with_capacity(na.min(body.len() / 8));
                for _ in 0..na {
                    arrivals.push(TimeUs(r.i64()?));
                }
                let mut datagrams = Vec::with_capacity(nd.min(body.len() / 2));
                for _ in 0..nd {
                    let l = usize::from(r.u16()?);
                    datagrams.push(r.take(l)?.to_vec());
                }
                Self::Step(SimStep {
                    sensor,
                    step,
                    t_true,
                    t_end,
                    arrivals,
                    datagrams,
                })
            }
            2 => Self::End(EndOfStream {
                sensor,
                steps: r.u32()?,
                t_end: TimeUs(r.i64()?),
            }),
            k => return Err(EnvelopeError::BadKind(k)),
        };
        if r.o != body.len() {
            return Err(EnvelopeError::Trailing(body.len() - r.o));
        }
        Ok(m)
    }
}

impl TrackMessage {
    /// Encodes the message (at most [`MAX_TRACKS`] tracks).
    pub fn encode(&self) -> Result<Vec<u8>, EnvelopeError> {
        if self.tracks.len() > MAX_TRACKS {
            return Err(EnvelopeError::Invalid("track count"));
        }
        let mut o = Vec::with_capacity(28 + TRACK_LEN * self.tracks.len());
        o.extend_from_slice(&TRK_MAGIC);
        o.push(VERSION);
        o.push(u8::from(self.no_data));
        o.extend_from_slice(&(self.tracks.len() as u16).to_le_bytes());
        o.extend_from_slice(&self.frame.to_le_bytes());
        o.extend_from_slice(&self.t.0.to_le_bytes());
        for t in &self.tracks {
            o.extend_from_slice(&t.id.to_le_bytes());
            let support =
                u32::try_from(t.support).map_err(|_| EnvelopeError::Invalid("support"))?;
            o.extend_from_slice(&support.to_le_bytes());
            o.push(u8::from(t.born) | (u8::from(t.gate_replaced) << 1));
            for v in [t.x, t.y, t.alpha, t.vx, t.vy, t.rms] {
                o.extend_from_slice(&v.to_le_bytes());
            }
        }
        Ok(finish(o))
    }

    /// Decodes a message; validates magic, version, count, length, CRC, and that every
    /// coordinate is finite.
    pub fn decode(b: &[u8]) -> Result<Self, EnvelopeError> {
        let body = body(b)?;
        let mut r = Reader { b: body, o: 0 };
        if r.arr::<4>()? != TRK_MAGIC {
            return Err(EnvelopeError::BadMagic);
        }
        let v = r.u8()?;
        if v != VERSION {
            return Err(EnvelopeError::BadVersion(v));
        }
        let flags = r.u8()?;
        if flags > 1 {
            return Err(EnvelopeError::Invalid("frame flags"));
        }
        let n = usize::from(r.u16()?);
        if n > MAX_TRACKS {
            return Err(EnvelopeError::Invalid("track count"));
        }
        let frame = r.u64()?;
        let t = TimeUs(r.i64()?);
        let need = r.o + n * TRACK_LEN;
        if body.len() != need {
            return Err(if body.len() < need {
                EnvelopeError::Truncated {
                    need,
                    have: body.len(),
                }
            } else {
                EnvelopeError::Trailing(body.len() - need)
            });
        }
        let mut tracks = Vec::with_capacity(n);
        for _ in 0..n {
            let id = r.u32()?;
            let support = r.u32()? as usize;
            let f = r.u8()?;
            if f > 3 {
                return Err(EnvelopeError::Invalid("track flags"));
            }
            let mut v = [0.0; 6];
            for x in &mut v {
                *x = r.f64()?;
                if !x.is_finite() {
                    return Err(EnvelopeError::Invalid("non-finite track value"));
                }
            }
            tracks.push(LidarTrack {
                id,
                x: v[0],
                y: v[1],
                alpha: v[2],
                vx: v[3],
                vy: v[4],
                support,
                rms: v[5],
                born: f & 1 != 0,
                gate_replaced: f & 2 != 0,
            });
        }
        Ok(Self {
            frame,
            t,
            no_data: flags == 1,
            tracks,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_step() -> impl Strategy<Value = SimMessage> {
        (
            any::<u16>(),
            any::<u32>(),
            any::<i64>(),
            any::<i64>(),
            prop::collection::vec(any::<i64>(), 0..4),
            prop::collection::vec(prop::collection::vec(any::<u8>(), 0..64), 0..4),
            any::<bool>(),
        )
            .prop_map(|(s, step, t, e, a, d, end)| {
                if end {
                    SimMessage::End(EndOfStream {
                        sensor: SensorId(s),
                        steps: step,
                        t_end: TimeUs(e),
                    })
                } else {
                    SimMessage::Step(SimStep {
                        sensor: SensorId(s),
                        step,
                        t_true: TimeUs(t),
                        t_end: TimeUs(e),
                        arrivals: a.into_iter().map(TimeUs).collect(),
                        datagrams: d,
                    })
                }
            })
    }

    fn arb_tracks() -> impl Strategy<Value = TrackMessage> {
        let tr = (
            any::<u32>(),
            0usize..10_000,
            prop::array::uniform6(-1e6f64..1e6),
            any::<(bool, bool)>(),
        )
            .prop_map(|(id, support, v, (born, gr))| LidarTrack {
                id,
                x: v[0],
                y: v[1],
                alpha: v[2],
                vx: v[3],
                vy: v[4],
                support,
                rms: v[5],
                born,
                gate_replaced: gr,
            });
        (
            any::<u64>(),
            any::<i64>(),
            any::<bool>(),
            prop::collection::vec(tr, 0..6),
        )
            .prop_map(|(frame, t, no_data, tracks)| TrackMessage {
                frame,
                t: TimeUs(t),
                no_data,
                tracks,
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        #[test]
        fn sim_round_trip_and_bit_flips(m in arb_step(), bit in any::<prop::sample::Index>()) {
            let b = m.encode().unwrap();
            prop_assert_eq!(SimMessage::decode(&b).unwrap(), m);
            let mut c = b.clone();
            let i = bit.index(c.len() * 8);
            c[i / 8] ^= 1 << (i % 8);
            prop_assert!(SimMessage::decode(&c).is_err());
            prop_assert!(SimMessage::decode(&b[..b.len() - 1]).is_err());
        }

        #[test]
        fn track_round_trip_and_bit_flips(m in arb_tracks(), bit in any::<prop::sample::Index>()) {
            let b = m.encode().unwrap();
            prop_assert_eq!(TrackMessage::decode(&b).unwrap(), m);
            let mut c = b.clone();
            let i = bit.index(c.len() * 8);
            c[i / 8] ^= 1 << (i % 8);
            prop_assert!(TrackMessage::decode(&c).is_err());
        }

        #[test]
        fn garbage_never_panics(b in prop::collection::vec(any::<u8>(), 0..300)) {
            let _ = SimMessage::decode(&b);
            let _ = TrackMessage::decode(&b);
        }
    }

    #[test]
    fn forged_lengths_are_rejected_not_trusted() {
        // a step claiming 65535 arrivals with a valid CRC
        let mut o = Vec::new();
        o.extend_from_slice(b"QSIM");
        o.extend_from_slice(&[1, 1, 0, 0]);
        o.extend_from_slice(&[0; 20]);
        o.extend_from_slice(&u16::MAX.to_le_bytes());
        o.extend_from_slice(&0u16.to_le_bytes());
        let b = finish(o);
        assert!(matches!(
            SimMessage::decode(&b),
            Err(EnvelopeError::Truncated { .. })
        ));
        let nan = TrackMessage {
            frame: 1,
            t: TimeUs(0),
            no_data: false,
            tracks: vec![LidarTrack {
                id: 0,
                x: f64::NAN,
                y: 0.0,
                alpha: 0.0,
                vx: 0.0,
                vy: 0.0,
                support: 1,
                rms: 0.0,
                born: false,
                gate_replaced: false,
            }],
        };
        let b = nan.encode().unwrap();
        assert_eq!(
            TrackMessage::decode(&b),
            Err(EnvelopeError::Invalid("non-finite track value"))
        );
    }
}
