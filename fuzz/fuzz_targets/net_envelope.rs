//! Fuzz quarry-net's envelope decoders (virtual-time steps, end markers, track messages): any
//! bytes must decode or give an `EnvelopeError`, never panic; a decoded message re-encodes to
//! the same bytes, and the datagrams a step carries go through the §7.1 decoder safely.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_net::proto::wire::Message;
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
});
