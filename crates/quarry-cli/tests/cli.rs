//! End-to-end tests of the built `quarry` binary.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::process::Command;

use serde_json::Value;

fn quarry(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_quarry"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

fn shared() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    if p.join("bench-data/mot_gt.csv").exists() {
        Some(p)
    } else {
        eprintln!("skipping: no shared data at {}", p.display());
        None
    }
}

/// bench-data's `frame,id,x,y,w,h` CSV (with header) as a MOTChallenge file.
fn to_mot(src: &std::path::Path, dst: &std::path::Path, gt: bool) {
    let text = std::fs::read_to_string(src).unwrap();
    let tail = if gt { "1,-1,-1,-1" } else { "0.9,-1,-1,-1" };
    let mut body = String::new();
    for l in text.lines().skip(1) {
        body.push_str(l);
        body.push(',');
        body.push_str(tail);
        body.push('\n');
    }
    std::fs::write(dst, body).unwrap();
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("quarry-cli-test-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn eval_json_on_bench_pair_matches_motmetrics_and_trackeval() {
    let Some(sh) = shared() else { return };
    let d = tmpdir("eval");
    let (gt, res) = (d.join("gt.txt"), d.join("res.txt"));
    to_mot(&sh.join("bench-data/mot_gt.csv"), &gt, true);
    to_mot(&sh.join("bench-data/mot_hyp.csv"), &res, false);
    let (code, stdout, stderr) = quarry(&[
        "eval",
        "--gt",
        gt.to_str().unwrap(),
        "--res",
        res.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert_eq!(
        stdout.lines().count(),
        1,
        "exactly one JSON object: {stdout}"
    );
    let v: Value = serde_json::from_str(&stdout).unwrap();
    // py-motmetrics 1.4.0 / TrackEval 1.3.0 on the same pair (crates/quarry-eval/tests/fixtures)
    let f = |k: &str| v[k].as_f64().unwrap();
    assert!((f("mota") - 0.911_016_949_152_542_4).abs() < 1e-6);
    assert!((f("idf1") - 0.866_379_310_344_827_6).abs() < 1e-6);
    assert!((f("hota") - 0.747_320_518_874_299_3).abs() < 1e-6);
    assert_eq!(v["idsw"], 1);
    assert_eq!(v["matching"], "iou");
    assert_eq!(v["motp_unit"], "percent_iou");
    assert!((f("motp") - 100.0 * (1.0 - f("motp_distance"))).abs() < 1e-9);
    for k in [
        "deta", "assa", "loca", "fp", "fn", "frag", "mt", "pt", "ml", "gt", "frames",
    ] {
        assert!(v[k].is_number(), "missing {k}");
    }
    // human output names the metrics
    let (code, stdout, _) = quarry(&[
        "eval",
        "--gt",
        gt.to_str().unwrap(),
        "--res",
        res.to_str().unwrap(),
    ]);
    assert_eq!(code, 0);
    assert!(stdout.contains("MOTA (%)") && stdout.contains("91.10"));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn eval_errors_are_clear_and_not_panics() {
    let d = tmpdir("err");
    let gt = d.join("gt.txt");
    std::fs::write(&gt, "1,1,0,0,10,10,1,-1,-1,-1\n2,1,0,0,ten,10,1,-1,-1,-1\n").unwrap();
    let (code, stdout, stderr) = quarry(&[
        "eval",
        "--gt",
        gt.to_str().unwrap(),
        "--res",
        gt.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(stdout.is_empty());
    assert!(
        stderr.contains("line 2") && stderr.contains("\"ten\""),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"));
    let missing = d.join("nope.txt");
    let (code, stdout, stderr) = quarry(&[
        "eval",
        "--gt",
        missing.to_str().unwrap(),
        "--res",
        gt.to_str().unwrap(),
        "--json",
    ]);
    assert_eq!(code, 1);
    assert!(stderr.contains("nope.txt"), "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert!(v["error"].as_str().unwrap().contains("nope.txt"));
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn duration_flags_are_refused_not_panics_or_hangs() {
    // each used to panic in Duration::from_secs_f64 (exit 101) or to run until killed
    for args in [
        &["lidar-node", "--wait-server", "inf"][..],
        &["lidar-node", "--wait-server", "1e20"][..],
        &["lidar-server", "--duration", "1e20"][..],
        &["lidar-server", "--duration=-1"][..],
        &["lidar-server", "--duration", "nan"][..],
        &[
            "lidar-server",
            "--idle-timeout",
            "1e20",
            "--clock",
            "virtual",
        ][..],
    ] {
        let (code, _, stderr) = quarry(args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stderr.contains("30 days"), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

#[test]
fn sift_match_thresholds_are_refused_when_meaningless() {
    // --ratio nan used to switch the ratio test off, --ratio -1 / --max-distance nan gave 0
    // matches; the thresholds are checked before any image is read
    for args in [
        &["sift", "a.png", "b.png", "--ratio", "nan"][..],
        &["sift", "a.png", "b.png", "--ratio=-1"][..],
        &["sift", "a.png", "b.png", "--max-distance", "nan"][..],
    ] {
        let (code, _, stderr) = quarry(args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(
            stderr.contains("ratio") || stderr.contains("max_distance"),
            "{args:?}: {stderr}"
        );
    }
}

#[test]
fn absurd_sizes_are_refused_before_allocating() {
    // each used to allocate gigabytes or abort on a failed allocation (exit 134)
    for (args, needle) in [
        (&["slamot", "--particles", "10000000"][..], "particles"),
        (&["slamot", "--particles", "1000000000"][..], "particles"),
        (&["lidar", "--people", "1000000000"][..], "--people"),
    ] {
        let (code, _, stderr) = quarry(args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
}

#[test]
fn demo_json_reports_kf_rmse() {
    let (code, stdout, stderr) = quarry(&["demo", "--json"]);
    assert_eq!(code, 0, "stderr: {stderr}");
    assert_eq!(stdout.lines().count(), 1);
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let kf = rows
        .iter()
        .find(|r| r["tracker"] == "kf-cv" && r["metric"] == "position RMSE (m)")
        .expect("kf-cv row");
    let rmse = kf["value"].as_f64().unwrap();
    // 0.5 m measurement noise: a working filter is well below the raw 0.71 m error
    assert!(rmse > 0.15 && rmse < 0.45, "rmse {rmse}");
    assert!(kf["ms_per_frame"].as_f64().unwrap() > 0.0);
    assert!(kf["paper"].is_null());
    // same seed, same numbers (only the KF demo, to keep the test fast)
    let (code, again, _) = quarry(&["demo", "--json", "--only", "kf-cv"]);
    assert_eq!(code, 0);
    let w: Value = serde_json::from_str(&again).unwrap();
    assert_eq!(w["rows"][0]["value"], kf["value"]);
    let (code, _, stderr) = quarry(&["demo", "--only", "no-such-demo"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("no demo matches"), "{stderr}");
}

#[test]
fn help_teaches() {
    let (code, stdout, _) = quarry(&["eval", "--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("EXAMPLE") && stdout.contains("frame,id,bb_left"));
    let (_, stdout, _) = quarry(&["demo", "--help"]);
    assert!(stdout.contains("EXAMPLE") && stdout.contains("--json"));
}

#[test]
fn lidar_scenario_runs_a_named_simulator_scenario() {
    // door seed 1, 1640 frames (7-89 s), kf-gnn: measured 1508/1640 successful frames
    // (91.95 %), MOTA 0.961; the crates/quarry-trackers scenario test checks the same run
    let (code, stdout, stderr) = quarry(&[
        "lidar",
        "--scenario",
        "door",
        "--frames",
        "1640",
        "--preset",
        "kf-gnn",
        "--json",
    ]);
    assert_eq!(code, 0, "stderr: {stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["scenario"], "door");
    assert_eq!(v["band"], "mid");
    assert_eq!(v["frames"], 1640);
    assert!(v["success_rate"].as_f64().unwrap() > 0.85, "{v}");
    assert!(v["mota"].as_f64().unwrap() > 0.9, "{v}");
    // more frames than the scenario has: scored to its end (60 s: 1060 frames from 7 s)
    let (code, stdout, _) = quarry(&[
        "lidar",
        "--scenario",
        "side_by_side",
        "--frames",
        "5000",
        "--json",
    ]);
    assert_eq!(code, 0);
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["scenario"], "side_by_side");
    assert_eq!(v["frames"], 1060, "60 s scenario, frames from 7 s");
    let (code, _, stderr) = quarry(&["lidar", "--scenario", "doors"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("unknown scenario name"), "{stderr}");
    let (_, stdout, _) = quarry(&["lidar", "--help"]);
    assert!(stdout.contains("--scenario") && stdout.contains("stop_and_go"));
}
