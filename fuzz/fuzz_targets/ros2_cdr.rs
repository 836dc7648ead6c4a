//! Fuzz quarry-ros2's CDR decoder, the path a ROS 2 subscriber (`lidar-node --ros2-scan`) feeds
//! with whatever arrives on the wire: any bytes decode as each message type or give a
//! `CdrError`, never a panic or an oversized allocation; a decoded message re-encodes to bytes
//! that decode and re-encode to themselves; a decoded LaserScan goes through the subscriber's
//! geometry and scan conversion (an error or a valid scan); an rmw_zenoh attachment decodes or
//! errs and round-trips.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::SensorId;
use quarry_ros2::Message;
use quarry_ros2::convert::{geometry_of, polar_scan};
use quarry_ros2::msgs::{
    CompressedImage, Detection2DArray, Image, LaserScan, MarkerArray, PoseArray, TFMessage,
    TrackArray, TwistStamped,
};
use quarry_ros2::rmw_zenoh::Attachment;

fn stable<M: Message>(data: &[u8]) -> Option<M> {
    let m = M::from_cdr(data).ok()?;
    let once = m.to_cdr();
    let again = M::from_cdr(&once).expect("re-encoded bytes decode");
    assert_eq!(again.to_cdr(), once, "{}: encoding is not stable", M::NAME);
    Some(m)
}

fuzz_target!(|data: &[u8]| {
    if let Some(scan) = stable::<LaserScan>(data)
        && let Ok(g) = geometry_of(&scan, 0.025)
    {
        if let Ok(s) = polar_scan(&scan, SensorId(0), 0, &g) {
            assert_eq!(s.ranges_mm.len(), g.n_beams as usize);
        }
    }
    let _ = stable::<TrackArray>(data);
    let _ = stable::<MarkerArray>(data);
    let _ = stable::<Detection2DArray>(data);
    let _ = stable::<TFMessage>(data);
    let _ = stable::<PoseArray>(data);
    let _ = stable::<TwistStamped>(data);
    let _ = stable::<Image>(data);
    let _ = stable::<CompressedImage>(data);
    if let Ok(a) = Attachment::decode(data) {
        assert_eq!(a.encode(), data);
    }
});
