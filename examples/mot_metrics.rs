//! Score a tracker with the standard MOT metrics (CLEAR MOT, IDF1, HOTA).
//!
//! With arguments, scores MOTChallenge files:
//!     cargo run --example mot_metrics -- path/to/gt.txt path/to/results.txt
//! Without, scores a small built-in sequence (two people, one identity switch), both with box
//! IoU (image trackers) and with world distances (laser trackers).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry::eval::motchallenge::{GtStyle, read_gt_file, read_results_file, to_frames};
use quarry::eval::{Euclidean, Frame, Iou, MotEvaluation, MotSummary};

fn print(label: &str, s: &MotSummary) {
    let c = &s.clear;
    println!("{label}");
    println!(
        "  MOTA {:.4}  MOTP (py-motmetrics distance) {:.4}",
        c.mota().unwrap_or(f64::NAN),
        c.motp().unwrap_or(f64::NAN)
    );
    println!(
        "  IDF1 {:.4}  HOTA {:.4}  DetA {:.4}  AssA {:.4}",
        s.identity.idf1().unwrap_or(f64::NAN),
        s.hota.hota_mean(),
        s.hota.deta_mean(),
        s.hota.assa_mean()
    );
    println!(
        "  ID switches {}  FP {}  FN {}  fragmentations {}",
        c.num_switches, c.num_false_positives, c.num_misses, c.num_fragmentations
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [gt, res] = args.as_slice() {
        let gt = read_gt_file(gt, GtStyle::Auto)?;
        let res = read_results_file(res)?;
        let frames = to_frames(&gt, &res, 0.5)?;
        let s = MotEvaluation::new(&frames, &Iou::default())?.summary()?;
        print("MOTChallenge files, IoU >= 0.5", &s);
        if let Some(p) = s.clear.motchallenge_motp() {
            println!("  MOTP (MOTChallenge, mean IoU %) {p:.2}");
        }
        return Ok(());
    }

    // Boxes: [left, top, width, height]. Track 11 follows person 1, then jumps to person 2.
    let boxes: Vec<Frame<[f64; 4]>> = (0..20)
        .map(|k| {
            let x = f64::from(k) * 5.0;
            let p1 = [x, 100.0, 40.0, 90.0];
            let p2 = [300.0 - x, 100.0, 40.0, 90.0];
            let hyp = if k < 10 {
                vec![
                    (11, [x + 2.0, 101.0, 40.0, 90.0]),
                    (12, [302.0 - x, 99.0, 40.0, 88.0]),
                ]
            } else {
                vec![
                    (12, [x + 1.0, 100.0, 40.0, 90.0]),
                    (11, [299.0 - x, 100.0, 42.0, 90.0]),
                ]
            };
            Frame {
                gt: vec![(1, p1), (2, p2)],
                hyp,
            }
        })
        .collect();
    print(
        "boxes, IoU >= 0.5",
        &MotEvaluation::new(&boxes, &Iou::default())?.summary()?,
    );

    // World points in metres, matched within 0.5 m (spec 003's protocol).
    let points: Vec<Frame<[f64; 2]>> = boxes
        .iter()
        .map(|f| Frame {
            gt: f
                .gt
                .iter()
                .map(|(id, b)| (*id, [b[0] / 100.0, 0.0]))
                .collect(),
            hyp: f
                .hyp
                .iter()
                .map(|(id, b)| (*id, [b[0] / 100.0, 0.1]))
                .collect(),
        })
        .collect();
    print(
        "points, distance <= 0.5 m",
        &MotEvaluation::new(&points, &Euclidean::new(0.5)?)?.summary()?,
    );
    Ok(())
}
