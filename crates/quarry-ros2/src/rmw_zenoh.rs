//! How rmw_zenoh (ROS 2's zenoh middleware) names topics and frames samples, so that a quarry
//! process speaks to ROS 2 nodes over zenoh without a bridge. Sans-IO: key expressions and byte
//! layouts only; `quarry-net`'s zenoh transport does the networking.
//!
//! Followed: **rmw_zenoh 0.2 (ROS 2 Jazzy) / 0.6 (Kilted, Rolling)**, zenoh 1.x. There a topic's
//! data travel on the key expression
//! `<domain id>/<topic without leading and trailing '/'>/<DDS type name>/<RIHS01 type hash>`, e.g.
//! `0/scan/sensor_msgs::msg::dds_::LaserScan_/RIHS01_64c1…`, the payload is the CDR message
//! (encapsulation header included), and each sample carries an attachment serialized with
//! zenoh-ext's serializer: the publisher's sequence number (`i64`, little-endian), its source
//! timestamp (`i64` ns since the epoch, little-endian) and its 16-byte GID (a length byte 16 and
//! the bytes). Discovery (`ros2 topic list`) uses liveliness tokens `@ros2_lv/...`
//! ([`publisher_token`]); data flow does not depend on them.

use crate::cdr::CdrError;
use crate::schema::Message;

/// The length of an rmw GID in the attachment.
pub const GID_LEN: usize = 16;

/// The DDS-mangled type name rmw_zenoh uses: `sensor_msgs/msg/LaserScan` →
/// `sensor_msgs::msg::dds_::LaserScan_`.
pub fn dds_type_name(ros_type: &str) -> String {
    match ros_type.rsplit_once('/') {
        Some((pkg, name)) => format!("{}::dds_::{name}_", pkg.replace('/', "::")),
        None => format!("{ros_type}_"),
    }
}

/// Checks a ROS 2 topic name (`/scan`, `robot1/tracks`): non-empty, letters, digits, `_` and
/// `/` only, no empty or digit-leading segment, no `//`.
///
/// # Errors
/// A message saying what is wrong.
pub fn check_topic(topic: &str) -> Result<(), String> {
    let t = topic.trim_matches('/');
    if t.is_empty() {
        return Err(format!("topic `{topic}` is empty"));
    }
    for seg in t.split('/') {
        if seg.is_empty() {
            return Err(format!("topic `{topic}` has an empty segment (`//`)"));
        }
        if seg.starts_with(|c: char| c.is_ascii_digit()) {
            return Err(format!(
                "topic `{topic}`: segment `{seg}` starts with a digit"
            ));
        }
        if let Some(c) = seg
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || *c == '_'))
        {
            return Err(format!(
                "topic `{topic}`: `{c}` is not allowed (letters, digits, `_` and `/`)"
            ));
        }
    }
    Ok(())
}

/// The key expression of `topic` carrying messages of type `M` in ROS domain `domain`.
///
/// # Errors
/// An invalid topic name ([`check_topic`]).
pub fn topic_key<M: Message>(domain: u32, topic: &str) -> Result<String, String> {
    check_topic(topic)?;
    Ok(format!(
        "{domain}/{}/{}/{}",
        topic.trim_matches('/'),
        dds_type_name(M::NAME),
        M::type_hash()
    ))
}

/// The key expression matching `topic` with type `M` under any type hash: a subscriber that
/// wants to see (and count) publishers whose distribution hashes the type differently, which
/// rmw_zenoh itself would never match.
///
/// # Errors
/// An invalid topic name ([`check_topic`]).
pub fn topic_pattern<M: Message>(domain: u32, topic: &str) -> Result<String, String> {
    check_topic(topic)?;
    Ok(format!(
        "{domain}/{}/{}/*",
        topic.trim_matches('/'),
        dds_type_name(M::NAME)
    ))
}

/// The type hash at the end of a topic key (`RIHS01_…`), if the key has one.
pub fn hash_of_key(key: &str) -> Option<&str> {
    key.rsplit('/').next().filter(|h| h.starts_with("RIHS"))
}

/// A publisher GID derived from its liveliness token (the first 16 bytes of its SHA-256): unique
/// per session, node and entity, and the same every time the same entity is declared.
pub fn gid_of(token: &str) -> [u8; GID_LEN] {
    use sha2::Digest;
    let d = sha2::Sha256::digest(token.as_bytes());
    let mut g = [0u8; GID_LEN];
    g.copy_from_slice(&d[..GID_LEN]);
    g
}

/// The metadata rmw_zenoh attaches to each sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's sequence number (from 1).
    pub sequence_number: i64,
    /// Source timestamp (ns since the Unix epoch).
    pub source_timestamp: i64,
    /// The publisher's GID.
    pub source_gid: [u8; GID_LEN],
}

impl Attachment {
    /// The attachment's bytes (33).
    pub fn encode(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(8 + 8 + 1 + GID_LEN);
        b.extend_from_slice(&self.sequence_number.to_le_bytes());
        b.extend_from_slice(&self.source_timestamp.to_le_bytes());
        b.push(GID_LEN as u8);
        b.extend_from_slice(&self.source_gid);
        b
    }

    /// Parses an attachment.
    ///
    /// # Errors
    /// [`CdrError::Invalid`] if the bytes are not 33 long or the GID's length byte is not 16.
    pub fn decode(b: &[u8]) -> Result<Self, CdrError> {
        if b.len() != 8 + 8 + 1 + GID_LEN || usize::from(b[16]) != GID_LEN {
            return Err(CdrError::Invalid(format!(
                "rmw_zenoh attachment of {} bytes (expected 33: i64, i64, 16, 16-byte GID)",
                b.len()
            )));
        }
        let i64_at = |k: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[k..k + 8]);
            i64::from_le_bytes(a)
        };
        let mut gid = [0u8; GID_LEN];
        gid.copy_from_slice(&b[17..]);
        Ok(Self {
            sequence_number: i64_at(0),
            source_timestamp: i64_at(8),
            source_gid: gid,
        })
    }
}

/// Mangles a name for a liveliness token (`/` → `%`; empty → `%`).
pub fn mangle(name: &str) -> String {
    if name.is_empty() {
        "%".into()
    } else {
        name.replace('/', "%")
    }
}

/// The liveliness token rmw_zenoh declares for a publisher, by which `ros2 topic list` and
/// `ros2 node list` see it: `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/MP/%/<namespace>/
/// <node>/<topic>/<type>/<hash>/<qos>` with the QoS `reliable, keep-last 10, volatile`
/// (`::,10:,:,:,,`).
///
/// # Errors
/// An invalid topic name.
pub fn publisher_token<M: Message>(
    domain: u32,
    zid: &str,
    node_id: u32,
    entity_id: u32,
    node: &str,
    topic: &str,
) -> Result<String, String> {
    check_topic(topic)?;
    Ok(format!(
        "@ros2_lv/{domain}/{zid}/{node_id}/{entity_id}/MP/%/%/{node}/{}/{}/{}/::,10:,:,:,,",
        mangle(&format!("/{}", topic.trim_matches('/'))),
        dds_type_name(M::NAME),
        M::type_hash()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msgs::LaserScan;

    #[test]
    fn keys_follow_rmw_zenoh() {
        assert_eq!(
            dds_type_name("sensor_msgs/msg/LaserScan"),
            "sensor_msgs::msg::dds_::LaserScan_"
        );
        let k = topic_key::<LaserScan>(0, "/scan").unwrap();
        assert!(k.starts_with("0/scan/sensor_msgs::msg::dds_::LaserScan_/RIHS01_"));
        assert!(topic_key::<LaserScan>(0, "/a//b").is_err());
        assert!(topic_key::<LaserScan>(0, "/a b").is_err());
        assert!(topic_key::<LaserScan>(0, "/").is_err());
        let p = topic_pattern::<LaserScan>(3, "robot/scan").unwrap();
        assert_eq!(p, "3/robot/scan/sensor_msgs::msg::dds_::LaserScan_/*");
        assert_eq!(hash_of_key(&k), Some(LaserScan::type_hash().as_str()));
        assert_eq!(hash_of_key("0/scan"), None);
        assert_ne!(gid_of("a"), gid_of("b"));
    }

    #[test]
    fn attachments_round_trip_and_reject_wrong_lengths() {
        let a = Attachment {
            sequence_number: 3,
            source_timestamp: -5,
            source_gid: [7; 16],
        };
        assert_eq!(Attachment::decode(&a.encode()).unwrap(), a);
        assert!(Attachment::decode(&[0; 10]).is_err());
        let mut b = a.encode();
        b[16] = 15;
        assert!(Attachment::decode(&b).is_err());
    }
}
