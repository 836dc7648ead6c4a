//! Arbitrary bytes through the MOTChallenge reader and, when they parse, through the metrics:
//! nothing may panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_eval::motchallenge::{GtStyle, parse_bytes, read_gt, to_frames};
use quarry_eval::{Iou, MotEvaluation};

fuzz_target!(|data: &[u8]| {
    let Ok(rows) = parse_bytes(data) else { return };
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    for style in [GtStyle::Auto, GtStyle::Mot15, GtStyle::Mot16] {
        let Ok(gt) = read_gt(text, style) else {
            continue;
        };
        if let Ok(frames) = to_frames(&gt, &rows, 0.5) {
            if let Ok(ev) = MotEvaluation::new(&frames, &Iou::default()) {
                let _ = ev.summary();
            }
        }
    }
});
