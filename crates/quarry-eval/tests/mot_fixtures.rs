//! quarry-eval against py-motmetrics 1.4.0 and TrackEval 1.3.0.
//!
//! The expected numbers in `fixtures/mot_expected.json` were computed by
//! `fixtures/make_mot_fixtures.py` (kept for provenance; these tests never run Python). Every
//! metric must agree to 1e-6. Sequences: designed edge cases (`fixtures/mot_edge_inputs.json`),
//! the bench-data MOT pair, and PETS09-S2L1 ground truth against a deterministic perturbation of
//! itself (the shared-data cases skip, with a message, when `../shared` is absent).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::path::PathBuf;

use quarry_eval::motchallenge::{GtStyle, MotRow, read_gt_file, to_frames};
use quarry_eval::{Euclidean, Frame, Iou, Ltwh, MotEvaluation, Similarity, linear_sum_assignment};
use serde_json::Value;

const TOL: f64 = 1e-6;

fn fixture(name: &str) -> Value {
    let p = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/");
    serde_json::from_str(&std::fs::read_to_string(format!("{p}{name}")).unwrap()).unwrap()
}

fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    if p.join("bench-data").is_dir() {
        Some(p)
    } else {
        eprintln!(
            "skipping: shared data not found at {} (set QUARRY_SHARED)",
            p.display()
        );
        None
    }
}

/// Box-centre distance, as the peer script does (`centres = xy + wh / 2`).
struct CentreDistance(Euclidean);

fn centre(b: &Ltwh) -> [f64; 2] {
    [b[0] + b[2] / 2.0, b[1] + b[3] / 2.0]
}

impl Similarity<Ltwh> for CentreDistance {
    fn distance(&self, gt: &Ltwh, hyp: &Ltwh) -> Option<f64> {
        self.0.distance(&centre(gt), &centre(hyp))
    }
    fn similarity(&self, gt: &Ltwh, hyp: &Ltwh) -> f64 {
        self.0.similarity(&centre(gt), &centre(hyp))
    }
}

fn frames_from_json(v: &Value) -> Vec<Frame<Ltwh>> {
    let side = |a: &Value| -> Vec<(i64, Ltwh)> {
        a.as_array()
            .unwrap()
            .iter()
            .map(|r| {
                let r: Vec<f64> = r
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|x| x.as_f64().unwrap())
                    .collect();
                (r[0] as i64, [r[1], r[2], r[3], r[4]])
            })
            .collect()
    };
    v.as_array()
        .unwrap()
        .iter()
        .map(|f| Frame {
            gt: side(&f["gt"]),
            hyp: side(&f["hyp"]),
        })
        .collect()
}

fn close(name: &str, got: Option<f64>, want: &Value) {
    match (got, want.as_f64()) {
        (None, None) => {}
        (Some(g), Some(w)) => assert!((g - w).abs() <= TOL, "{name}: got {g}, reference {w}"),
        (g, _) => panic!("{name}: got {g:?}, reference {want}"),
    }
}

fn check(seq: &str, frames: &[Frame<Ltwh>]) {
    let expected = fixture("mot_expected.json");
    for kind in ["iou", "dist"] {
        let ev = if kind == "iou" {
            MotEvaluation::new(frames, &Iou::default()).unwrap()
        } else {
            MotEvaluation::new(frames, &CentreDistance(Euclidean::new(20.0).unwrap())).unwrap()
        };
        let s = ev.summary().unwrap();
        let mm = &expected[seq][kind]["motmetrics"];
        let te = &expected[seq][kind]["trackeval"];
        let n = |x: usize| Some(x as f64);
        let c = &s.clear;
        let i = &s.identity;
        let tag = |f: &str| format!("{seq}/{kind}/{f}");
        close(&tag("mota"), c.mota(), &mm["mota"]);
        close(&tag("motp"), c.motp(), &mm["motp"]);
        close(&tag("num_frames"), n(c.num_frames), &mm["num_frames"]);
        close(&tag("num_objects"), n(c.num_objects), &mm["num_objects"]);
        close(
            &tag("num_predictions"),
            n(c.num_predictions),
            &mm["num_predictions"],
        );
        close(
            &tag("num_unique_objects"),
            n(c.num_unique_objects),
            &mm["num_unique_objects"],
        );
        close(&tag("num_matches"), n(c.num_matches), &mm["num_matches"]);
        close(&tag("num_switches"), n(c.num_switches), &mm["num_switches"]);
        close(
            &tag("num_detections"),
            n(c.num_detections),
            &mm["num_detections"],
        );
        close(
            &tag("num_false_positives"),
            n(c.num_false_positives),
            &mm["num_false_positives"],
        );
        close(&tag("num_misses"), n(c.num_misses), &mm["num_misses"]);
        close(
            &tag("num_fragmentations"),
            n(c.num_fragmentations),
            &mm["num_fragmentations"],
        );
        close(&tag("num_transfer"), n(c.num_transfer), &mm["num_transfer"]);
        close(&tag("num_ascend"), n(c.num_ascend), &mm["num_ascend"]);
        close(&tag("num_migrate"), n(c.num_migrate), &mm["num_migrate"]);
        close(
            &tag("mostly_tracked"),
            n(c.mostly_tracked),
            &mm["mostly_tracked"],
        );
        close(
            &tag("partially_tracked"),
            n(c.partially_tracked),
            &mm["partially_tracked"],
        );
        close(&tag("mostly_lost"), n(c.mostly_lost), &mm["mostly_lost"]);
        close(&tag("recall"), c.recall(), &mm["recall"]);
        close(&tag("precision"), c.precision(), &mm["precision"]);
        close(&tag("idtp"), n(i.idtp), &mm["idtp"]);
        close(&tag("idfp"), n(i.idfp), &mm["idfp"]);
        close(&tag("idfn"), n(i.idfn), &mm["idfn"]);
        close(&tag("idf1"), i.idf1(), &mm["idf1"]);
        close(&tag("idp"), i.idp(), &mm["idp"]);
        close(&tag("idr"), i.idr(), &mm["idr"]);
        // TrackEval reports IDF1 = 0 where motmetrics has 0/0
        close(
            &tag("IDF1 (TrackEval)"),
            Some(i.idf1().unwrap_or(0.0)),
            &te["IDF1"],
        );
        let h = &s.hota;
        close(&tag("HOTA"), Some(h.hota_mean()), &te["HOTA"]);
        close(&tag("DetA"), Some(h.deta_mean()), &te["DetA"]);
        close(&tag("AssA"), Some(h.assa_mean()), &te["AssA"]);
        close(&tag("LocA"), Some(h.loca_mean()), &te["LocA"]);
        close(&tag("DetRe"), Some(h.detre_mean()), &te["DetRe"]);
        close(&tag("DetPr"), Some(h.detpr_mean()), &te["DetPr"]);
        close(&tag("AssRe"), Some(h.assre_mean()), &te["AssRe"]);
        close(&tag("AssPr"), Some(h.asspr_mean()), &te["AssPr"]);
        for (a, w) in te["HOTA_per_alpha"].as_array().unwrap().iter().enumerate() {
            close(&tag(&format!("HOTA[{a}]")), Some(h.hota[a]), w);
        }
    }
}

#[test]
fn edge_cases_match_references() {
    let inputs = fixture("mot_edge_inputs.json");
    let names: Vec<&String> = inputs.as_object().unwrap().keys().collect();
    assert_eq!(names.len(), 5);
    for name in names {
        check(name, &frames_from_json(&inputs[name]));
    }
}

#[test]
fn bench_pair_matches_references() {
    let Some(sh) = shared() else { return };
    let read = |name: &str| -> Vec<(u64, i64, Ltwh)> {
        let text = std::fs::read_to_string(sh.join("bench-data").join(name)).unwrap();
        text.lines()
            .skip(1)
            .map(|l| {
                let c: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                (c[0] as u64, c[1] as i64, [c[2], c[3], c[4], c[5]])
            })
            .collect()
    };
    let mut by_frame: BTreeMap<u64, Frame<Ltwh>> = BTreeMap::new();
    for (f, id, b) in read("mot_gt.csv") {
        by_frame.entry(f).or_default().gt.push((id, b));
    }
    for (f, id, b) in read("mot_hyp.csv") {
        by_frame.entry(f).or_default().hyp.push((id, b));
    }
    let frames: Vec<Frame<Ltwh>> = by_frame.into_values().collect();
    assert_eq!(frames.len(), 60);
    check("bench_pair", &frames);
    // the scripted errors of bench-data/README.md
    let s = MotEvaluation::new(&frames, &Iou::default())
        .unwrap()
        .clear_mot()
        .unwrap();
    assert_eq!(s.num_switches, 1);
}

/// The deterministic hypothesis of `make_mot_fixtures.py::perturb_pets`, operation for operation.
fn perturb_pets(gt: &[(u64, i64, Ltwh)]) -> Vec<MotRow> {
    let mut out = Vec::new();
    for &(f, i, b) in gt {
        let (fi, ii) = (f as i64, i);
        if (fi + 3 * ii) % 17 == 0 {
            continue;
        }
        let mut dx = ((fi * 7 + ii * 13) % 11 - 5) as f64 * 0.9;
        let dy = ((fi * 5 + ii * 3) % 9 - 4) as f64 * 0.8;
        let s = 1.0 + ((fi + ii) % 5 - 2) as f64 * 0.03;
        let mut hid = ii;
        if fi > 120 && ii % 4 == 1 {
            hid = ii + 1000;
        }
        if (60..80).contains(&fi) && (ii == 15 || ii == 19) {
            hid = 34 - ii;
        }
        if fi % 23 == 0 && ii % 2 == 0 {
            dx += 25.0;
        }
        out.push(MotRow {
            frame: f,
            id: hid,
            bbox: [b[0] + dx, b[1] + dy, b[2] * s, b[3] * s],
            conf: 1.0,
            extra: [None; 3],
        });
    }
    for f in 1..=200u64 {
        if f % 10 == 0 {
            out.push(MotRow {
                frame: f,
                id: 9999,
                bbox: [((f * 3) % 700) as f64, 400.0, 40.0, 90.0],
                conf: 1.0,
                extra: [None; 3],
            });
        }
    }
    out
}

#[test]
fn pets09_against_perturbed_copy_matches_references() {
    let Some(sh) = shared() else { return };
    let gt = read_gt_file(sh.join("data/pets09-s2l1/gt.txt"), GtStyle::Auto).unwrap();
    assert!(gt.len() > 1000 && gt.iter().all(|g| g.consider));
    let triples: Vec<(u64, i64, Ltwh)> = gt.iter().map(|g| (g.frame, g.id, g.bbox)).collect();
    let res = perturb_pets(&triples);
    let frames = to_frames(&gt, &res, 0.5).unwrap();
    check("pets09_perturbed", &frames);
}

#[test]
fn lsap_breaks_ties_like_scipy() {
    let cases = fixture("lsap_ties.json");
    let cases = cases.as_array().unwrap();
    assert_eq!(cases.len(), 300);
    for (k, c) in cases.iter().enumerate() {
        let nr = c["rows"].as_u64().unwrap() as usize;
        let nc = c["cols"].as_u64().unwrap() as usize;
        let cost: Vec<f64> = c["cost"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        let want: Vec<(usize, usize)> = c["pairs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| {
                (
                    p[0].as_u64().unwrap() as usize,
                    p[1].as_u64().unwrap() as usize,
                )
            })
            .collect();
        assert_eq!(
            linear_sum_assignment(&cost, nr, nc).unwrap(),
            want,
            "case {k}: {cost:?} {nr}x{nc}"
        );
    }
}
