//! Fuzz every tracker's TOML configuration (`TrackerConfig::from_toml`, the `--config FILE`
//! path of the CLI): any text must give a validated configuration or a `TrackerError`, never a
//! panic; an accepted configuration written back as TOML reads back to itself.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_trackers::TrackerConfig;
use quarry_trackers::cv_jpda::JpdaTrackerConfig;
use quarry_trackers::lidar_people::LidarPeopleConfig;
use quarry_trackers::rgbd_person::RgbdPersonConfig;
use quarry_trackers::slamot::SlamotConfig;

fn check<C: TrackerConfig + std::fmt::Debug>(text: &str) {
    if let Ok(c) = C::from_toml(text, None) {
        let again = c.to_toml().expect("an accepted configuration writes");
        assert_eq!(C::from_toml(&again, None).expect("and reads back"), c);
    }
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    check::<SlamotConfig>(text);
    check::<LidarPeopleConfig>(text);
    check::<RgbdPersonConfig>(text);
    check::<JpdaTrackerConfig>(text);
});
