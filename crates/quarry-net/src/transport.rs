//! The publish/subscribe transport: a trait, the key names, and the in-process implementation.
//!
//! Keys are `/`-separated chunks (zenoh key expressions); a subscription pattern may use `*`
//! (exactly one chunk) and `**` (any number of chunks, including none).

use crate::NetError;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The key names used by nodes and the server.
pub mod keys {
    use quarry_core::SensorId;

    /// Wall-clock mode: §7.1 wire datagrams (DynamicScan, Hello) of sensor `id`.
    pub fn scan(id: SensorId) -> String {
        format!("quarry/lidar/scan/{}", id.0)
    }
    /// Everything published on [`scan`] keys.
    pub const SCAN_ALL: &str = "quarry/lidar/scan/*";
    /// Wall-clock mode: §7.3 SyncRequest of sensor `id` (node to server).
    pub fn sync_request(id: SensorId) -> String {
        format!("quarry/lidar/sync/req/{}", id.0)
    }
    /// Every sync request.
    pub const SYNC_REQUEST_ALL: &str = "quarry/lidar/sync/req/*";
    /// Wall-clock mode: §7.3 SyncReply to sensor `id` (server to node).
    pub fn sync_reply(id: SensorId) -> String {
        format!("quarry/lidar/sync/rep/{}", id.0)
    }
    /// Virtual-time mode: [`crate::SimStep`] envelopes of sensor `id`.
    pub fn sim(id: SensorId) -> String {
        format!("quarry/lidar/sim/{}", id.0)
    }
    /// Every sim envelope.
    pub const SIM_ALL: &str = "quarry/lidar/sim/*";
    /// End-of-stream markers ([`crate::EndOfStream`]) of sensor `id` (both modes).
    pub fn end(id: SensorId) -> String {
        format!("quarry/lidar/end/{}", id.0)
    }
    /// Every end marker.
    pub const END_ALL: &str = "quarry/lidar/end/*";
    /// The server's acknowledgement of sensor `id`'s end marker (the node exits only after it,
    /// so nothing it published is lost in its send queue).
    pub fn end_ack(id: SensorId) -> String {
        format!("quarry/lidar/endack/{}", id.0)
    }
    /// The server's track messages ([`crate::TrackMessage`]), one per closed frame.
    pub const TRACKS: &str = "quarry/lidar/tracks";
    /// The server's liveness beacon (10 Hz).
    pub const SERVER_READY: &str = "quarry/lidar/server/ready";
    /// A node asking to join (repeated until welcomed): proves the node-to-server route exists
    /// before the node publishes data (a pub/sub engine drops what no subscriber matched yet).
    pub fn join(id: SensorId) -> String {
        format!("quarry/lidar/join/{}", id.0)
    }
    /// The server's answer to [`join`].
    pub fn welcome(id: SensorId) -> String {
        format!("quarry/lidar/welcome/{}", id.0)
    }
}

/// One received sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    /// The key it was published on.
    pub key: String,
    /// The payload bytes.
    pub payload: Vec<u8>,
}

/// A subscription's receiving end.
pub trait Subscription: Send {
    /// The next sample, waiting at most `timeout`; `Ok(None)` on timeout.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, NetError>;
}

/// A publish/subscribe transport.
pub trait Transport: Send + Sync {
    /// Publishes `payload` on `key`. Blocks rather than drops when the transport is congested.
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError>;
    /// Subscribes to the keys matching `pattern`.
    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError>;
}

/// Whether `key` matches `pattern` (`*` = one chunk, `**` = any number of chunks).
pub fn key_matches(pattern: &str, key: &str) -> bool {
    fn go(p: &[&str], k: &[&str]) -> bool {
        match p.split_first() {
            None => k.is_empty(),
            Some((&"**", rest)) => (0..=k.len()).any(|i| go(rest, &k[i..])),
            Some((&c, rest)) => match k.split_first() {
                Some((&kc, krest)) => (c == "*" || c == kc) && go(rest, krest),
                None => false,
            },
        }
    }
    let p: Vec<&str> = pattern.split('/').collect();
    let k: Vec<&str> = key.split('/').collect();
    go(&p, &k)
}

type Subscribers = Vec<(String, mpsc::Sender<Received>)>;

/// The in-process transport: every clone of a `LocalBus` shares the same subscribers, so
/// threads of one process (the simulator, tests) talk through it. Publishing never blocks:
/// the channels are unbounded.
#[derive(Debug, Clone, Default)]
pub struct LocalBus {
    subs: Arc<Mutex<Subscribers>>,
}

impl LocalBus {
    /// An empty bus.
    pub fn new() -> Self {
        Self::default()
    }
}

struct LocalSub {
    rx: mpsc::Receiver<Received>,
}

impl Subscription for LocalSub {
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, NetError> {
        match self.rx.recv_timeout(timeout) {
            Ok(r) => Ok(Some(r)),
            Err(mpsc::RecvTimeoutError::Timeout) => Ok(None),
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                Err(NetError::Transport("local bus closed".into()))
            }
        }
    }
}

impl Transport for LocalBus {
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError> {
        let mut subs = self
            .subs
            .lock()
            .map_err(|_| NetError::Transport("local bus lock poisoned".into()))?;
        subs.retain(|(pattern, tx)| {
            !key_matches(pattern, key)
                || tx
                    .send(Received {
                        key: key.to_string(),
                        payload: payload.to_vec(),
                    })
                    .is_ok()
        });
        Ok(())
    }

    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError> {
        let (tx, rx) = mpsc::channel();
        self.subs
            .lock()
            .map_err(|_| NetError::Transport("local bus lock poisoned".into()))?
            .push((pattern.to_string(), tx));
        Ok(Box::new(LocalSub { rx }))
    }
}

/// The sensor id at the end of a key such as `quarry/lidar/scan/2`.
pub fn sensor_of_key(key: &str) -> Option<quarry_core::SensorId> {
    key.rsplit('/')
        .next()?
        .parse()
        .ok()
        .map(quarry_core::SensorId)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns() {
        assert!(key_matches("a/*/c", "a/b/c"));
        assert!(!key_matches("a/*/c", "a/b/b/c"));
        assert!(key_matches("a/**", "a"));
        assert!(key_matches("a/**", "a/b/c"));
        assert!(key_matches("**/c", "a/b/c"));
        assert!(!key_matches("a/b", "a/b/c"));
        assert!(key_matches(
            keys::SCAN_ALL,
            &keys::scan(quarry_core::SensorId(3))
        ));
        assert_eq!(
            sensor_of_key("quarry/lidar/scan/3"),
            Some(quarry_core::SensorId(3))
        );
        assert_eq!(sensor_of_key("quarry/lidar/scan/x"), None);
    }

    #[test]
    fn local_bus_delivers_to_matching_subscribers_only() {
        let bus = LocalBus::new();
        let mut a = bus.subscribe("t/*").unwrap();
        let mut b = bus.subscribe("u").unwrap();
        bus.publish("t/1", b"x").unwrap();
        let r = a.recv_timeout(Duration::from_millis(10)).unwrap().unwrap();
        assert_eq!((r.key.as_str(), r.payload.as_slice()), ("t/1", &b"x"[..]));
        assert!(b.recv_timeout(Duration::from_millis(10)).unwrap().is_none());
        drop(a);
        bus.publish("t/2", b"y").unwrap(); // the dropped subscriber is removed, no error
        assert_eq!(bus.subs.lock().unwrap().len(), 1);
    }
}
