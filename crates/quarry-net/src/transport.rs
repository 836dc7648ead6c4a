//! The publish/subscribe transport: a trait, the key names, and the in-process implementation.
//!
//! Keys are `/`-separated chunks (zenoh key expressions); a subscription pattern may use `*`
//! (exactly one chunk) and `**` (any number of chunks, including none).

use crate::NetError;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The key names used by nodes and the server.
///
/// Everything a node sends lives under [`NODE_ALL`](keys::NODE_ALL) (`quarry/lidar/node/**`),
/// everything the server sends outside it. The server subscribes to `NODE_ALL` only: a
/// subscription that also matched the server's own publications (tracks, acknowledgements,
/// beacon) would be fed by the server's own thread, and with a bounded receive queue (zenoh's
/// FIFO handler holds 256 samples and blocks when full) a queue full of node data then blocks
/// that thread in `publish`, the only thread that empties the queue: a deadlock.
pub mod keys {
    use quarry_core::SensorId;

    /// Every key a node publishes on (the server's one subscription).
    pub const NODE_ALL: &str = "quarry/lidar/node/**";
    /// The prefix of [`scan`] keys.
    pub const SCAN_PREFIX: &str = "quarry/lidar/node/scan/";
    /// The prefix of [`sync_request`] keys.
    pub const SYNC_REQUEST_PREFIX: &str = "quarry/lidar/node/sync/";
    /// The prefix of [`sim`] keys.
    pub const SIM_PREFIX: &str = "quarry/lidar/node/sim/";
    /// The prefix of [`end`] keys.
    pub const END_PREFIX: &str = "quarry/lidar/node/end/";
    /// The prefix of [`join`] keys.
    pub const JOIN_PREFIX: &str = "quarry/lidar/node/join/";
    /// The prefix of [`bye`] keys.
    pub const BYE_PREFIX: &str = "quarry/lidar/node/bye/";

    /// Wall-clock mode: §7.1 wire datagrams (DynamicScan, Hello) of sensor `id`.
    pub fn scan(id: SensorId) -> String {
        format!("{SCAN_PREFIX}{}", id.0)
    }
    /// Everything published on [`scan`] keys.
    pub const SCAN_ALL: &str = "quarry/lidar/node/scan/*";
    /// Wall-clock mode: §7.3 SyncRequest of sensor `id` (node to server).
    pub fn sync_request(id: SensorId) -> String {
        format!("{SYNC_REQUEST_PREFIX}{}", id.0)
    }
    /// Every sync request.
    pub const SYNC_REQUEST_ALL: &str = "quarry/lidar/node/sync/*";
    /// Wall-clock mode: §7.3 SyncReply to sensor `id` (server to node).
    pub fn sync_reply(id: SensorId) -> String {
        format!("quarry/lidar/sync/rep/{}", id.0)
    }
    /// Virtual-time mode: [`crate::SimStep`] envelopes of sensor `id`.
    pub fn sim(id: SensorId) -> String {
        format!("{SIM_PREFIX}{}", id.0)
    }
    /// Every sim envelope.
    pub const SIM_ALL: &str = "quarry/lidar/node/sim/*";
    /// End-of-stream markers ([`crate::EndOfStream`]) of sensor `id` (both modes), repeated
    /// until the server acknowledges them.
    pub fn end(id: SensorId) -> String {
        format!("{END_PREFIX}{}", id.0)
    }
    /// Every end marker.
    pub const END_ALL: &str = "quarry/lidar/node/end/*";
    /// The server's acknowledgement of sensor `id`'s end marker (the node exits only after it,
    /// so nothing it published is lost in its send queue).
    pub fn end_ack(id: SensorId) -> String {
        format!("quarry/lidar/endack/{}", id.0)
    }
    /// The node's confirmation that it received [`end_ack`] (the server stops re-sending the
    /// acknowledgement and may exit once every node has said it).
    pub fn bye(id: SensorId) -> String {
        format!("{BYE_PREFIX}{}", id.0)
    }
    /// The server's track messages ([`crate::TrackMessage`]), one per closed frame.
    pub const TRACKS: &str = "quarry/lidar/tracks";
    /// The server's liveness beacon (10 Hz; `ready <mode> <session> <started_unix_us>`).
    pub const SERVER_READY: &str = "quarry/lidar/server/ready";
    /// A node asking to join (repeated until welcomed): proves the node-to-server route exists
    /// before the node publishes data (a pub/sub engine drops what no subscriber matched yet).
    pub fn join(id: SensorId) -> String {
        format!("{JOIN_PREFIX}{}", id.0)
    }
    /// The server's answer to [`join`] (`welcome <mode> <session>`, see [`crate::session`]).
    pub fn welcome(id: SensorId) -> String {
        format!("quarry/lidar/welcome/{}", id.0)
    }
    /// The server's refusal of a [`join`] (a UTF-8 reason: an id the server does not know, a
    /// node on the other clock mode); the node stops with that reason instead of waiting.
    pub fn refuse(id: SensorId) -> String {
        format!("quarry/lidar/refuse/{}", id.0)
    }
    /// The server's end notice (`end <session>`): it stopped before the nodes were done
    /// (interrupted, or its --duration elapsed); the nodes stop instead of waiting for it.
    pub const SERVER_END: &str = "quarry/lidar/server/end";

    #[cfg(test)]
    mod tests {
        use super::*;
        use crate::transport::key_matches;

        /// The server's subscription matches every node key and none of its own.
        #[test]
        fn the_server_subscription_excludes_the_server_publications() {
            let id = SensorId(7);
            for k in [
                scan(id),
                sync_request(id),
                sim(id),
                end(id),
                join(id),
                bye(id),
            ] {
                assert!(key_matches(NODE_ALL, &k), "{k}");
            }
            for k in [
                sync_reply(id),
                end_ack(id),
                welcome(id),
                refuse(id),
                TRACKS.to_string(),
                SERVER_READY.to_string(),
                SERVER_END.to_string(),
            ] {
                assert!(!key_matches(NODE_ALL, &k), "{k}");
            }
        }
    }
}

/// One received sample.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    /// The key it was published on.
    pub key: String,
    /// The payload bytes.
    pub payload: Vec<u8>,
    /// The sample's attachment, if it had one (rmw_zenoh puts its sequence number, source
    /// timestamp and publisher GID there: `quarry_ros2::rmw_zenoh::Attachment`).
    pub attachment: Option<Vec<u8>>,
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
    /// Publishes `payload` on `key` with an attachment (per-sample metadata beside the payload,
    /// as ROS 2's rmw_zenoh sends). The default refuses: a transport that cannot carry it
    /// must not drop it silently.
    fn publish_with_attachment(
        &self,
        key: &str,
        payload: &[u8],
        attachment: &[u8],
    ) -> Result<(), NetError> {
        let _ = (key, payload, attachment);
        Err(NetError::Transport(
            "this transport does not carry sample attachments".into(),
        ))
    }
    /// Declares a liveliness token on `key` (how ROS 2 tools discover a zenoh publisher); it
    /// lives as long as the returned handle. The default (an in-process transport, which has no
    /// discovery) returns an empty handle.
    fn declare_liveliness(&self, key: &str) -> Result<Liveliness, NetError> {
        let _ = key;
        Ok(Liveliness::none())
    }
}

/// A declared liveliness token ([`Transport::declare_liveliness`]); dropping it undeclares it.
pub struct Liveliness(Option<Box<dyn std::any::Any + Send + Sync>>);

impl Liveliness {
    /// A handle that holds nothing (the transport has no liveliness).
    pub fn none() -> Self {
        Self(None)
    }
    /// A handle holding a transport's token.
    pub fn holding(token: Box<dyn std::any::Any + Send + Sync>) -> Self {
        Self(Some(token))
    }
    /// Whether it holds a token.
    pub fn is_declared(&self) -> bool {
        self.0.is_some()
    }
}

impl std::fmt::Debug for Liveliness {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Liveliness")
            .field("declared", &self.is_declared())
            .finish()
    }
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

#[derive(Debug, Clone)]
enum Tx {
    Unbounded(mpsc::Sender<Received>),
    Bounded(mpsc::SyncSender<Received>),
}

impl Tx {
    fn send(&self, r: Received) -> bool {
        match self {
            Tx::Unbounded(tx) => tx.send(r).is_ok(),
            Tx::Bounded(tx) => tx.send(r).is_ok(),
        }
    }
}

#[derive(Debug, Default)]
struct Subscribers {
    next_id: u64,
    list: Vec<(u64, String, Tx)>,
}

/// The in-process transport: every clone of a `LocalBus` shares the same subscribers, so
/// threads of one process (the simulator, tests) talk through it. [`LocalBus::new`] never
/// blocks (unbounded queues); [`LocalBus::bounded`] gives every subscription a queue of fixed
/// capacity and blocks the publisher while a matching queue is full, as zenoh's FIFO handler
/// does (256 samples), so tests see the same back-pressure as a zenoh deployment.
#[derive(Debug, Clone, Default)]
pub struct LocalBus {
    subs: Arc<Mutex<Subscribers>>,
    capacity: Option<usize>,
}

impl LocalBus {
    /// An empty bus with unbounded queues.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty bus whose subscriptions hold at most `capacity` samples (at least 1); a
    /// publisher waits while a matching subscription's queue is full.
    pub fn bounded(capacity: usize) -> Self {
        Self {
            subs: Arc::default(),
            capacity: Some(capacity.max(1)),
        }
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

fn poisoned<T>(_: T) -> NetError {
    NetError::Transport("local bus lock poisoned".into())
}

impl LocalBus {
    fn deliver(
        &self,
        key: &str,
        payload: &[u8],
        attachment: Option<&[u8]>,
    ) -> Result<(), NetError> {
        // send outside the lock: a bounded send may wait for its subscriber
        let targets: Vec<(u64, Tx)> = self
            .subs
            .lock()
            .map_err(poisoned)?
            .list
            .iter()
            .filter(|(_, pattern, _)| key_matches(pattern, key))
            .map(|(id, _, tx)| (*id, tx.clone()))
            .collect();
        let mut gone = Vec::new();
        for (id, tx) in targets {
            let r = Received {
                key: key.to_string(),
                payload: payload.to_vec(),
                attachment: attachment.map(<[u8]>::to_vec),
            };
            if !tx.send(r) {
                gone.push(id);
            }
        }
        if !gone.is_empty() {
            self.subs
                .lock()
                .map_err(poisoned)?
                .list
                .retain(|(id, _, _)| !gone.contains(id));
        }
        Ok(())
    }
}

impl Transport for LocalBus {
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError> {
        self.deliver(key, payload, None)
    }

    fn publish_with_attachment(
        &self,
        key: &str,
        payload: &[u8],
        attachment: &[u8],
    ) -> Result<(), NetError> {
        self.deliver(key, payload, Some(attachment))
    }

    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError> {
        let (tx, rx) = match self.capacity {
            None => {
                let (tx, rx) = mpsc::channel();
                (Tx::Unbounded(tx), rx)
            }
            Some(c) => {
                let (tx, rx) = mpsc::sync_channel(c);
                (Tx::Bounded(tx), rx)
            }
        };
        let mut subs = self.subs.lock().map_err(poisoned)?;
        let id = subs.next_id;
        subs.next_id += 1;
        subs.list.push((id, pattern.to_string(), tx));
        Ok(Box::new(LocalSub { rx }))
    }
}

/// The sensor id at the end of a key such as `quarry/lidar/node/scan/2`.
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
            sensor_of_key("quarry/lidar/node/scan/3"),
            Some(quarry_core::SensorId(3))
        );
        assert_eq!(sensor_of_key("quarry/lidar/node/scan/x"), None);
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
        assert_eq!(bus.subs.lock().unwrap().list.len(), 1);
    }
}
