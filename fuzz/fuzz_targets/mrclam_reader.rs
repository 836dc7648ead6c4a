//! Fuzz the MRCLAM reader: arbitrary bytes split into the file contents must give a run or an
//! error, never a panic; a run's frames are in time order, cover the odometry span in pieces of
//! non-negative length, and observing frames (own-stamp timing) end at a measurement stamp.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_data::mrclam::{MeasurementTiming, MrclamTexts, from_texts_with, parse_table};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = parse_table(&text, "fuzz", 4);
    // Files separated by '|': barcodes | landmarks | odometry | measurements | gt1 | gt2
    let parts: Vec<&str> = text.split('|').collect();
    let get = |i: usize| parts.get(i).copied().unwrap_or("");
    let texts = MrclamTexts {
        barcodes: get(0),
        landmarks: get(1),
        odometry: get(2),
        measurements: get(3),
        groundtruth: vec![(1, get(4)), (2, get(5))],
    };
    for timing in [MeasurementTiming::OwnStamp, MeasurementTiming::NextOdometry] {
        let Ok(run) = from_texts_with(&texts, 1, timing) else {
            continue;
        };
        let mut t_prev = 0.0;
        for (i, f) in run.frames.iter().enumerate() {
            assert!(f.dt >= 0.0 && f.dt.is_finite());
            assert_eq!(f.k, i as u64);
            assert!(f.t >= t_prev);
            t_prev = f.t;
            assert_eq!(f.target_obs.len(), f.truth.target_obs_source.len());
            assert!(
                f.landmark_obs
                    .iter()
                    .all(|(_, z)| z[0] > 0.0 && z[1].is_finite())
            );
            assert!(f.target_obs.iter().all(|z| z[0] > 0.0 && z[1].is_finite()));
        }
        let _ = run.skips.to_string();
    }
});
