//! The watershed + SIFT pools tracker (spec 004) on an image sequence, frame by frame, through
//! the library (what `quarry video` does without the drawing and the scoring).
//!
//! `cargo run --release --example video_tracker [DIR [WxH]]` (default: PETS09-S2L1's `img1` in
//! `../shared/data`, person size 32x84). Prints one MOTChallenge row per box on stdout.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use quarry::core::{MultiTargetTracker, Stamp};
use quarry::trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use quarry::vision::convert::rgb_to_gray_bt601;
use quarry::vision::io::open_image;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args.first().map_or_else(
        || {
            PathBuf::from(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../shared/data/pets09-s2l1/img1"
            ))
        },
        PathBuf::from,
    );
    let (w, h) = args
        .get(1)
        .and_then(|s| s.split_once('x'))
        .map_or((32.0, 84.0), |(a, b)| {
            (a.parse().unwrap(), b.parse().unwrap())
        });
    let Ok(files) = quarry::data::image_sequence::list_frames(&dir) else {
        eprintln!("skipping: no frames in {}", dir.display());
        return;
    };
    // the robust profile, box and blur set from the sequence's typical person size
    let cfg = WatershedSiftConfig::robust().with_person_size(w, h);
    let mut tracker = WatershedSiftTracker::new(cfg).unwrap();
    for (k, path) in files.iter().enumerate() {
        let grey = rgb_to_gray_bt601(&open_image(path).unwrap().to_rgb8());
        let reports = tracker
            .step(Stamp::from_frame(k as u64, 1.0 / 7.0), &grey)
            .unwrap();
        for r in reports {
            let [l, t, bw, bh] = r.bbox.unwrap().to_ltwh();
            println!(
                "{},{},{:.1},{:.1},{bw},{bh},1,-1,-1,-1",
                k + 1,
                r.id.0,
                l + 1.0,
                t + 1.0
            );
        }
        let d = tracker.diagnostics();
        eprintln!(
            "frame {}: {} regions, {} moving points, {} targets",
            k + 1,
            d.regions,
            d.moving.len(),
            d.targets.len()
        );
    }
}
