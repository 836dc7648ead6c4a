//! The session handshake between nodes and a server: which server a node joined, in which clock
//! mode, and the server's liveness beacon and end notice.
//!
//! Every server run has a **session id** (a `u64` chosen when it starts, [`new_session_id`]).
//! It appears in the server's beacon, its welcome, its clock-sync replies and its end notice,
//! so that a node can tell its server from another one on the same network (two servers, or a
//! server restarted on the same port) and ignore or follow it:
//!
//! | key | payload | from |
//! |---|---|---|
//! | [`keys::join`](crate::keys::join) | `join <mode>` | node, every 100 ms until answered |
//! | [`keys::welcome`](crate::keys::welcome) | `welcome <mode> <session>` | server |
//! | [`keys::refuse`](crate::keys::refuse) | `refuse <mode\|any> <reason>` ([`Refusal`]) | server (unknown sensor: `any`; other clock mode: the request's mode) |
//! | [`keys::SERVER_READY`](crate::keys::SERVER_READY) | `ready <mode> <session> <started_unix_us>` | server, 10 Hz |
//! | [`keys::SERVER_END`](crate::keys::SERVER_END) | `end <session>` | server, when it stops early (Ctrl-C, SIGTERM) |
//!
//! `<mode>` is `wall` or `virtual` ([`ClockKind`]). A clock-sync reply carries the session in
//! its header's `t_capture` field, unused otherwise (spec §7.1 leaves it zero for replies).
//! Every payload is short ASCII; the decoders accept at most [`MAX_PAYLOAD`] bytes and never
//! panic (fuzzed with the envelopes in `fuzz/fuzz_targets/net_envelope.rs`).

use std::fmt;

/// The longest handshake payload a decoder looks at (a beacon is about 50 bytes).
pub const MAX_PAYLOAD: usize = 256;

/// Which clock a node or server runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClockKind {
    /// Real time, with the §7.3 clock synchronisation.
    Wall,
    /// Virtual time: simulated nodes replayed by the server in capture order.
    Virtual,
}

impl ClockKind {
    /// `wall` or `virtual`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Wall => "wall",
            Self::Virtual => "virtual",
        }
    }

    fn parse(s: &str) -> Option<Self> {
        match s {
            "wall" => Some(Self::Wall),
            "virtual" => Some(Self::Virtual),
            _ => None,
        }
    }
}

impl fmt::Display for ClockKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A fresh session id: the wall clock's nanoseconds mixed with the process id (distinct for
/// two servers started on one machine in the same nanosecond only by the pid). Not a random
/// number in the statistical sense and not used as one: it only has to differ between runs.
pub fn new_session_id() -> u64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    // splitmix64 finaliser, so that nearby start times give unrelated ids
    let mut z = nanos ^ (u64::from(std::process::id()) << 32);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (z ^ (z >> 31)).max(1)
}

/// Microseconds since the UNIX epoch now (0 if the system clock is before 1970).
pub fn unix_us() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX))
}

fn words(payload: &[u8]) -> Option<Vec<&str>> {
    if payload.len() > MAX_PAYLOAD {
        return None;
    }
    let s = std::str::from_utf8(payload).ok()?;
    Some(s.split_ascii_whitespace().collect())
}

/// A node's join request.
pub fn encode_join(mode: ClockKind) -> Vec<u8> {
    format!("join {mode}").into_bytes()
}

/// The clock mode of a join request; `None` for a request without one (a node of an older
/// version, accepted as the server's own mode) or an undecodable one.
pub fn decode_join(payload: &[u8]) -> Option<ClockKind> {
    match words(payload)?.as_slice() {
        ["join", m] => ClockKind::parse(m),
        _ => None,
    }
}

/// The server's welcome: its clock mode and session.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Welcome {
    /// The server's clock mode.
    pub mode: ClockKind,
    /// The server's session id.
    pub session: u64,
}

impl Welcome {
    /// `welcome <mode> <session>`.
    pub fn encode(&self) -> Vec<u8> {
        format!("welcome {} {}", self.mode, self.session).into_bytes()
    }

    /// The welcome, or `None` when the bytes are not one.
    pub fn decode(payload: &[u8]) -> Option<Self> {
        match words(payload)?.as_slice() {
            ["welcome", m, s] => Some(Self {
                mode: ClockKind::parse(m)?,
                session: s.parse().ok()?,
            }),
            _ => None,
        }
    }
}

/// The server's 10 Hz liveness beacon.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Beacon {
    /// The server's clock mode.
    pub mode: ClockKind,
    /// The server's session id.
    pub session: u64,
    /// When the server started, µs since the UNIX epoch (of the server's system clock): of two
    /// servers on one network the younger one gives way.
    pub started_unix_us: i64,
}

impl Beacon {
    /// `ready <mode> <session> <started_unix_us>`.
    pub fn encode(&self) -> Vec<u8> {
        format!(
            "ready {} {} {}",
            self.mode, self.session, self.started_unix_us
        )
        .into_bytes()
    }

    /// The beacon, or `None` when the bytes are not one.
    pub fn decode(payload: &[u8]) -> Option<Self> {
        match words(payload)?.as_slice() {
            ["ready", m, s, t] => Some(Self {
                mode: ClockKind::parse(m)?,
                session: s.parse().ok()?,
                started_unix_us: t.parse().ok()?,
            }),
            _ => None,
        }
    }

    /// Whether `self` started after `other` (ties broken by the session id), i.e. should give
    /// way to it.
    pub fn younger_than(&self, other: &Self) -> bool {
        (self.started_unix_us, self.session) > (other.started_unix_us, other.session)
    }
}

/// The server's end notice (it stops before the nodes are done).
pub fn encode_end(session: u64) -> Vec<u8> {
    format!("end {session}").into_bytes()
}

/// The session of an end notice.
pub fn decode_end(payload: &[u8]) -> Option<u64> {
    match words(payload)?.as_slice() {
        ["end", s] => s.parse().ok(),
        _ => None,
    }
}

/// The server's refusal of a join: to whom it is addressed and why.
///
/// A refusal goes out on the sensor's [`keys::refuse`](crate::keys::refuse) key, which every
/// node started with that `--sensor-id` hears. It names the clock mode of the request it
/// answers, so that a wall-clock node is not stopped by the refusal of a stray virtual-time
/// message for its id (another program, an old recording replayed) and the other way round.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Refusal {
    /// The clock mode of the refused request; `None` for every node of the sensor (an id the
    /// server does not know).
    pub to: Option<ClockKind>,
    /// The reason, for a person.
    pub reason: String,
}

impl Refusal {
    /// `refuse <wall|virtual|any> <reason>`.
    pub fn encode(&self) -> Vec<u8> {
        let to = self.to.map_or("any", ClockKind::name);
        format!("refuse {to} {}", self.reason).into_bytes()
    }

    /// The refusal in `payload` (lossy UTF-8, at most [`MAX_PAYLOAD`] bytes looked at). A
    /// payload without the `refuse <to>` prefix (a server of an older version sent the bare
    /// reason) is a refusal to every node.
    pub fn decode(payload: &[u8]) -> Self {
        let n = payload.len().min(MAX_PAYLOAD);
        let text = String::from_utf8_lossy(&payload[..n]);
        let mut parts = text.splitn(3, ' ');
        if let (Some("refuse"), Some(to), rest) = (parts.next(), parts.next(), parts.next()) {
            let to = match to {
                "any" => Some(None),
                m => ClockKind::parse(m).map(Some),
            };
            if let Some(to) = to {
                return Self {
                    to,
                    reason: rest.unwrap_or("").to_string(),
                };
            }
        }
        Self {
            to: None,
            reason: text.into_owned(),
        }
    }

    /// Whether a node on the clock `mode` must stop on this refusal.
    pub fn applies_to(&self, mode: ClockKind) -> bool {
        self.to.is_none_or(|m| m == mode)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn handshake_messages_round_trip() {
        for mode in [ClockKind::Wall, ClockKind::Virtual] {
            assert_eq!(decode_join(&encode_join(mode)), Some(mode));
            let w = Welcome { mode, session: 42 };
            assert_eq!(Welcome::decode(&w.encode()), Some(w));
            let b = Beacon {
                mode,
                session: u64::MAX,
                started_unix_us: 1_700_000_000_000_000,
            };
            assert_eq!(Beacon::decode(&b.encode()), Some(b));
        }
        assert_eq!(decode_end(&encode_end(7)), Some(7));
        for to in [None, Some(ClockKind::Wall), Some(ClockKind::Virtual)] {
            let r = Refusal {
                to,
                reason: "sensor 9 is not one of this server's sensors".into(),
            };
            assert_eq!(Refusal::decode(&r.encode()), r);
        }
        // an older server's bare reason is a refusal to every node
        let old = Refusal::decode(b"no such sensor");
        assert_eq!(old.to, None);
        assert_eq!(old.reason, "no such sensor");
        assert!(old.applies_to(ClockKind::Wall) && old.applies_to(ClockKind::Virtual));
        let virt = Refusal {
            to: Some(ClockKind::Virtual),
            reason: String::new(),
        };
        assert!(virt.applies_to(ClockKind::Virtual) && !virt.applies_to(ClockKind::Wall));
        // an older node's bare join has no mode
        assert_eq!(decode_join(b"join"), None);
        assert_eq!(Welcome::decode(b"welcome"), None);
        assert_eq!(Beacon::decode(b"ready"), None);
    }

    #[test]
    fn the_younger_server_gives_way() {
        let a = Beacon {
            mode: ClockKind::Wall,
            session: 5,
            started_unix_us: 100,
        };
        let b = Beacon {
            started_unix_us: 200,
            session: 1,
            ..a
        };
        assert!(b.younger_than(&a) && !a.younger_than(&b));
        let c = Beacon { session: 6, ..a };
        assert!(c.younger_than(&a) && !a.younger_than(&c));
        assert_ne!(new_session_id(), 0);
    }

    proptest! {
        /// The decoders never panic and refuse oversized input.
        #[test]
        fn decoders_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode_join(&bytes);
            let _ = Welcome::decode(&bytes);
            let _ = Beacon::decode(&bytes);
            let _ = decode_end(&bytes);
            prop_assert!(Refusal::decode(&bytes).reason.len() <= 3 * MAX_PAYLOAD);
        }
    }
}
