//! The zenoh transport (feature `zenoh`): a zenoh 1.x session in peer mode with explicit TCP
//! endpoints (no multicast scouting by default), puts with blocking congestion control so a
//! fast publisher is slowed down rather than dropped.

use crate::NetError;
use crate::transport::{Liveliness, Received, Subscription, Transport};
use std::time::Duration;
use zenoh::Wait;
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;

/// How a zenoh session is opened.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct ZenohOptions {
    /// Endpoints to listen on, e.g. `tcp/0.0.0.0:7447` (the server).
    pub listen: Vec<String>,
    /// Endpoints to connect to, e.g. `tcp/192.168.1.10:7447` (the nodes).
    pub connect: Vec<String>,
    /// Enable multicast scouting (finds peers on the LAN without endpoints).
    pub multicast_scouting: bool,
}

/// A zenoh session as a [`Transport`].
pub struct ZenohTransport {
    session: zenoh::Session,
}

impl std::fmt::Debug for ZenohTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZenohTransport").finish_non_exhaustive()
    }
}

fn zerr(what: &str, e: impl std::fmt::Display) -> NetError {
    NetError::Transport(format!("zenoh {what}: {e}"))
}

fn json_list(v: &[String]) -> Result<String, NetError> {
    serde_json::to_string(v).map_err(|e| NetError::Config(e.to_string()))
}

impl ZenohTransport {
    /// Opens a peer-mode session.
    pub fn open(opts: &ZenohOptions) -> Result<Self, NetError> {
        let mut c = zenoh::Config::default();
        let set = |c: &mut zenoh::Config, k: &str, v: &str| {
            c.insert_json5(k, v)
                .map_err(|e| zerr(&format!("config {k}"), e))
        };
        set(&mut c, "mode", "\"peer\"")?;
        set(&mut c, "listen/endpoints", &json_list(&opts.listen)?)?;
        set(&mut c, "connect/endpoints", &json_list(&opts.connect)?)?;
        set(
            &mut c,
            "scouting/multicast/enabled",
            if opts.multicast_scouting {
                "true"
            } else {
                "false"
            },
        )?;
        let session = zenoh::open(c).wait().map_err(|e| zerr("open", e))?;
        Ok(Self { session })
    }

    /// This session's zenoh id (hex), as rmw_zenoh's liveliness tokens name it.
    pub fn zid(&self) -> String {
        self.session.zid().to_string()
    }
}

impl Drop for ZenohTransport {
    /// Closes the session (flushing what is queued) instead of dropping it at process exit.
    fn drop(&mut self) {
        let _ = self.session.close().wait();
    }
}

struct ZenohSub {
    sub: Subscriber<FifoChannelHandler<Sample>>,
}

impl Subscription for ZenohSub {
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, NetError> {
        let s = if timeout.is_zero() {
            self.sub.try_recv()
        } else {
            self.sub.recv_timeout(timeout)
        }
        .map_err(|e| zerr("receive", e))?;
        Ok(s.map(|s| Received {
            key: s.key_expr().as_str().to_string(),
            payload: s.payload().to_bytes().into_owned(),
            attachment: s.attachment().map(|a| a.to_bytes().into_owned()),
        }))
    }
}

impl Transport for ZenohTransport {
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError> {
        self.session
            .put(key, payload.to_vec())
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(|e| zerr("put", e))
    }

    fn publish_with_attachment(
        &self,
        key: &str,
        payload: &[u8],
        attachment: &[u8],
    ) -> Result<(), NetError> {
        self.session
            .put(key, payload.to_vec())
            .attachment(attachment.to_vec())
            .congestion_control(CongestionControl::Block)
            .wait()
            .map_err(|e| zerr("put", e))
    }

    fn declare_liveliness(&self, key: &str) -> Result<Liveliness, NetError> {
        let token = self
            .session
            .liveliness()
            .declare_token(key.to_string())
            .wait()
            .map_err(|e| zerr(&format!("liveliness token {key}"), e))?;
        Ok(Liveliness::holding(Box::new(token)))
    }

    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError> {
        let sub = self
            .session
            .declare_subscriber(pattern.to_string())
            .wait()
            .map_err(|e| zerr("subscribe", e))?;
        Ok(Box::new(ZenohSub { sub }))
    }
}
