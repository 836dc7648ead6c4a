//! Per-stage SIFT timing on one rayon thread: scale space, detection, description, as wall time
//! and as the thread's own CPU time (Linux `/proc/thread-self/schedstat`; less sensitive to other
//! load on a shared machine than wall time).
//!
//! `cargo run --release -p quarry-vision --example sift_stage_times [IMAGE] [REPEATS]`
//! (default image: `../shared/bench-data/photo_gray.png`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_vision::sift::Sift;
use std::time::Instant;

/// CPU time of the calling thread in ms (NaN where unavailable).
fn cpu_ms() -> f64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |ns| ns / 1e6)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args.next().unwrap_or_else(|| {
        concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/bench-data/photo_gray.png"
        )
        .into()
    });
    let repeats: usize = args.next().map_or(7, |s| s.parse().unwrap());
    let img = quarry_vision::io::load_gray(&path).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let sift = Sift::default();
    println!("{path}: {}x{}, one thread", img.width, img.height);
    pool.install(|| {
        let mut totals = Vec::new();
        for _ in 0..repeats {
            let f = img.map(|&v| f32::from(v));
            let (c0, t0) = (cpu_ms(), Instant::now());
            let ss = sift.scale_space(&f).unwrap();
            let c1 = cpu_ms();
            let k = sift.detect_in(&ss);
            let c2 = cpu_ms();
            let d = sift.describe_in(&ss, &k).unwrap();
            let (c3, t3) = (cpu_ms(), Instant::now());
            println!(
                "cpu ms: scale space {:6.1} detect {:6.1} describe {:6.1} total {:6.1} | wall ms {:6.1} | {} keypoints",
                c1 - c0,
                c2 - c1,
                c3 - c2,
                c3 - c0,
                (t3 - t0).as_secs_f64() * 1e3,
                d.len()
            );
            totals.push(c3 - c0);
        }
        totals.sort_by(f64::total_cmp);
        println!("min cpu ms {:.1}, median {:.1}", totals[0], totals[totals.len() / 2]);
    });
}
