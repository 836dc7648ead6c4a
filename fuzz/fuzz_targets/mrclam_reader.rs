//! Fuzz the MRCLAM reader: arbitrary bytes split into the five file contents must give a run or
//! an error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_data::mrclam::{MrclamTexts, from_texts, parse_table};

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
    if let Ok(run) = from_texts(&texts, 1) {
        for f in &run.frames {
            assert!(f.dt >= 0.0);
            assert_eq!(f.target_obs.len(), f.truth.target_obs_source.len());
        }
    }
});
