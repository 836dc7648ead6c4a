//! Fuzz the wire decoder and the server's frame assembler: any bytes must decode to a message or
//! a `WireError`, never panic; a decoded message re-encodes to the same bytes; feeding the bytes
//! to a `FrameAssembler` and polling never panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{Pose2, ScanGeometry, SensorId, TimeUs};
use quarry_net::proto::wire::Message;
use quarry_net::proto::{FrameAssembler, FrameConfig, SensorConfig};

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = Message::decode(data) {
        let again = m.encode().expect("a decoded message encodes");
        assert_eq!(again, data);
    }
    let sensors = [SensorConfig {
        id: SensorId(1),
        pose: Pose2::new(1.0, 2.0, 0.5),
        geometry: ScanGeometry::utm30lx(),
    }];
    if let Ok(mut fa) = FrameAssembler::new(FrameConfig::default(), &sensors, TimeUs(0)) {
        let arrival = data.get(..8).map_or(0, |b| {
            i64::from_le_bytes(b.try_into().unwrap_or([0; 8])) % 10_000_000
        });
        fa.on_datagram(data, TimeUs(arrival));
        let _ = fa.poll(TimeUs(arrival.saturating_add(1_000_000)));
    }
});
