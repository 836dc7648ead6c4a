//! Fuzz quarry-net's envelope decoders (virtual-time steps, end markers, track messages): any
//! bytes must decode or give an `EnvelopeError`, never panic; a decoded message re-encodes to
//! the same bytes, and the datagrams a step carries go through the §7.1 decoder safely. The
//! session messages (join, welcome, beacon, end notice, refusal) decode or give `None`, and a
//! decoded one re-encodes to what it decoded from.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_net::proto::wire::Message;
use quarry_net::session::{self, Beacon, Welcome};
use quarry_net::{SimMessage, TrackMessage};

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = SimMessage::decode(data) {
        assert_eq!(m.encode().expect("a decoded step encodes"), data);
        if let SimMessage::Step(s) = m {
            for d in &s.datagrams {
                let _ = Message::decode(d);
            }
        }
    }
    if let Ok(t) = TrackMessage::decode(data) {
        assert_eq!(t.encode().expect("a decoded track message encodes"), data);
        assert!(t.tracks.iter().all(|r| r.x.is_finite() && r.y.is_finite()));
    }
    if let Some(w) = Welcome::decode(data) {
        assert_eq!(Welcome::decode(&w.encode()), Some(w));
    }
    if let Some(b) = Beacon::decode(data) {
        assert_eq!(Beacon::decode(&b.encode()), Some(b));
    }
    if let Some(m) = session::decode_join(data) {
        assert_eq!(session::decode_join(&session::encode_join(m)), Some(m));
    }
    if let Some(id) = session::decode_end(data) {
        assert_eq!(session::decode_end(&session::encode_end(id)), Some(id));
    }
    let r = session::Refusal::decode(data);
    assert!(r.reason.len() <= 4 * session::MAX_PAYLOAD + 64);
    if r.to.is_some() {
        assert_eq!(session::Refusal::decode(&r.encode()), r);
    }
});
