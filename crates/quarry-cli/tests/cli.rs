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
        (&["lidar", "--frames", "1000000000"][..], "--frames"),
        (&["lidar-server", "--frames", "1000000000"][..], "--frames"),
    ] {
        let (code, _, stderr) = quarry(args);
        assert_eq!(code, 1, "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
}

/// `quarry demo --data DIR`: the real-data rows where DIR holds the recordings, a note and no
/// rows where it does not.
#[test]
fn demo_real_rows_with_data_and_a_note_without() {
    // `quarry --json demo --only ONLY --data DIR`: its JSON and its stderr
    let demo = |only: &str, dir: &std::path::Path| {
        let (code, stdout, stderr) = quarry(&[
            "--json",
            "demo",
            "--only",
            only,
            "--data",
            dir.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{stderr}");
        let v: Value = serde_json::from_str(stdout.trim()).unwrap();
        (v, stderr)
    };
    let (v, stderr) = demo("real", &tmpdir("demo-no-data"));
    assert_eq!(v["rows"].as_array().unwrap().len(), 0, "{v}");
    assert!(
        stderr.contains("skipping the leg-tracker/positive_1 row"),
        "{stderr}"
    );
    assert!(stderr.contains("skipping the pets09-s2l1 row"), "{stderr}");
    let Some(sh) = shared() else { return };
    let data = sh.join("data");
    if !data.join("leg-tracker/positive_1_scans.csv").exists() {
        eprintln!("skipping the real rows: no {}", data.display());
        return;
    }
    // the leg row only: the PETS row runs the same 200 frames as `video_on_pets_if_present`
    // (13 s in the dev profile), through the same scoring
    let (v, _) = demo("lidar-legs-real", &data);
    let value = |tracker: &str, metric: &str| {
        v["rows"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r["tracker"] == tracker && r["metric"].as_str().unwrap().starts_with(metric))
            .and_then(|r| r["value"].as_f64())
            .unwrap_or_else(|| panic!("no {tracker} {metric} row: {v}"))
    };
    // the figures of docs/lidar-people.md (stop 33), with a margin
    assert!(value("lidar-legs (real)", "labelled scans") >= 80.0, "{v}");
    assert!(
        value("lidar-legs (real)", "person position RMSE") <= 0.075,
        "{v}"
    );
    // per person (stop 37): 184/207 = 88.9 %
    assert!(value("lidar-legs (real)", "labelled people") >= 85.0, "{v}");
    assert_eq!(v["rows"].as_array().unwrap().len(), 4, "{v}");
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
    // the lidar rows: faithful and jipda on the same run, jipda keeping identities
    let idf1 = |preset: &str| {
        rows.iter()
            .find(|r| {
                r["tracker"] == "lidar-people"
                    && r["metric"] == "IDF1"
                    && r["scenario"].as_str().unwrap().contains(preset)
            })
            .unwrap_or_else(|| panic!("lidar-people IDF1 row of {preset}"))["value"]
            .as_f64()
            .unwrap()
    };
    assert!(idf1("jipda") >= 0.9, "jipda IDF1 {}", idf1("jipda"));
    assert!(idf1("jipda") >= idf1("faithful"));
    // the video tracker's row: both walkers found in the short clip
    let ws = rows
        .iter()
        .find(|r| r["tracker"] == "watershed-sift" && r["metric"] == "IDF1")
        .expect("watershed-sift IDF1 row");
    assert!(ws["value"].as_f64().unwrap() > 0.3, "{ws}");
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
    let (code, stdout, _) = quarry(&["video", "sim", "--help"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("EXAMPLE") && stdout.contains("events.json"));
    let (_, stdout, _) = quarry(&["video", "--help"]);
    assert!(stdout.contains("quarry video sim") && stdout.contains("--frames"));
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

/// With `--json`, a command line that does not parse still prints exactly one JSON object on
/// stdout (`{"error": ...}` naming the problem), exit status 2; without `--json`, stdout stays
/// empty; `--help` still prints help and exits 0.
#[test]
fn json_usage_errors_print_one_error_object() {
    for args in [
        &["eval", "--json", "--frobnicate"][..],
        &["slamot", "--particles", "many", "--json"][..],
        &["no-such-command", "--json"][..],
        &["--json"][..],
    ] {
        let (code, stdout, stderr) = quarry(args);
        assert_eq!(code, 2, "{args:?}: {stderr}");
        let v: Value = serde_json::from_str(stdout.trim()).unwrap_or_else(|e| {
            panic!("{args:?}: stdout is not one JSON object ({e}): {stdout:?}")
        });
        let msg = v["error"].as_str().unwrap();
        assert!(!msg.is_empty() && !msg.starts_with("error:"), "{msg}");
        assert!(!stderr.is_empty());
    }
    let (_, stdout, _) = quarry(&["slamot", "--particles", "many", "--json"]);
    assert!(stdout.contains("many"), "{stdout}");
    let (code, stdout, _) = quarry(&["eval", "--frobnicate"]);
    assert_eq!((code, stdout.as_str()), (2, ""));
    let (code, stdout, _) = quarry(&["eval", "--help", "--json"]);
    assert_eq!(code, 0);
    assert!(stdout.contains("--gt"));
}

/// `quarry slamot --smooth` refines a recorded MRCLAM run: without `--mrclam`, or with a mode it
/// does not know, it is refused before anything runs.
#[test]
fn slamot_smooth_needs_a_recording_and_a_known_mode() {
    let (code, _, stderr) = quarry(&["slamot", "--smooth", "plain"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--smooth") && stderr.contains("--mrclam"),
        "{stderr}"
    );
    let (code, _, stderr) = quarry(&["slamot", "--smooth", "best"]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("plain") && stderr.contains("calibrated"),
        "{stderr}"
    );
}

/// `quarry eval`'s thresholds are checked before any file is read, with errors that name the
/// flag (not an internal parameter such as HOTA's similarity scale).
#[test]
fn eval_thresholds_are_refused_naming_the_flag() {
    for (flag, v) in [
        ("--dist", "1e308"),
        ("--dist", "0"),
        ("--dist", "nan"),
        ("--iou", "1.5"),
        ("--iou", "nan"),
    ] {
        let (code, _, stderr) = quarry(&["eval", "--gt", "nope.txt", "--res", "nope.txt", flag, v]);
        assert_eq!(code, 1, "{flag} {v}");
        assert!(
            stderr.contains(flag) && !stderr.contains("zero_at"),
            "{flag} {v}: {stderr}"
        );
    }
}

#[test]
fn a_missing_scans_csv_is_named_as_such() {
    let d = tmpdir("missing-scans");
    let p = d.join("nowhere_scans.csv");
    let (code, _, stderr) = quarry(&["lidar", "--scans", p.to_str().unwrap()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("cannot read the scans CSV") && !stderr.contains("scan_meta"),
        "{stderr}"
    );
}

#[test]
fn lidar_detector_legs_runs_jipda_and_refuses_the_table1_presets() {
    let d = tmpdir("legs-flags");
    let p = d.join("nowhere_scans.csv");
    let scans = p.to_str().unwrap();
    let (code, _, stderr) = quarry(&["lidar", "--scans", scans, "--detector", "feet"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("unknown detector \"feet\""), "{stderr}");
    let (code, _, stderr) = quarry(&[
        "lidar",
        "--scans",
        scans,
        "--detector",
        "legs",
        "--preset",
        "faithful",
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("detector = legs needs preset = kf-gnn"),
        "{stderr}"
    );
    // the backfill reworks a recording: the simulated room refuses it
    let (code, _, stderr) = quarry(&["lidar", "--backfill", "--frames", "10"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("--backfill") && stderr.contains("--scans"),
        "{stderr}"
    );
    let Some(sh) = shared() else { return };
    let data = sh.join("data/leg-tracker");
    if !data.join("scan_meta.json").exists() {
        eprintln!("skipping the recorded run: no {}", data.display());
        return;
    }
    let out = d.join("out");
    let (scans, legs) = (
        data.join("positive_2_scans.csv"),
        data.join("positive_2_legs.csv"),
    );
    let positive_2 = |more: &[&str]| {
        let mut a = vec![
            "--json",
            "lidar",
            "--scans",
            scans.to_str().unwrap(),
            "--legs",
            legs.to_str().unwrap(),
            "--detector",
            "legs",
        ];
        a.extend_from_slice(more);
        let (code, stdout, stderr) = quarry(&a);
        assert_eq!(code, 0, "{stderr}");
        serde_json::from_str::<Value>(stdout.trim()).unwrap()
    };
    let v = positive_2(&["--out", out.to_str().unwrap()]);
    assert_eq!(v["preset"], "jipda", "{v}");
    assert_eq!(v["detector"], "legs", "{v}");
    // the jipda preset's background starts early: no warm-up scans
    assert_eq!(v["warm_up_scans"], 0, "{v}");
    assert!(v["labelled"]["rmse_m"].as_f64().unwrap() < 0.1, "{v}");
    for f in [
        "tracks.csv",
        "tracks_mot.txt",
        "metrics.json",
        "plot.png",
        "track_counts.png",
    ] {
        assert!(out.join(f).exists(), "{f} not written");
    }
    // the bar chart is a real image of the chart's size
    let img = image::open(out.join("track_counts.png")).unwrap();
    assert_eq!((img.width(), img.height()), (800, 500));
    // per person: one walker in every labelled scan, so 83 people, all reachable
    let groups = &v["label_groups"];
    assert_eq!(groups["groups"], 83, "{v}");
    assert_eq!(groups["ceiling_matched"], 83, "{v}");
    assert_eq!(v["backfilled_rows"], 0, "{v}");
    // offline, the held-back scans of the walker's track are reported too
    let b = positive_2(&["--backfill"]);
    assert!(b["backfilled_rows"].as_u64().unwrap() > 0, "{b}");
    assert!(
        b["label_groups"]["matched"].as_u64() > groups["matched"].as_u64(),
        "{b}"
    );
}

#[test]
fn broken_and_oversized_images_are_refused() {
    let d = tmpdir("bad-images");
    let img =
        image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([(x * 3) as u8, (y * 5) as u8, 7]));
    let jpg = d.join("frame.jpg");
    img.save(&jpg).unwrap();
    let bytes = std::fs::read(&jpg).unwrap();
    let cut = d.join("cut.jpg");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let (code, _, stderr) = quarry(&["segment", jpg.to_str().unwrap(), "--sigma", "2"]);
    assert_eq!(code, 0, "{stderr}");
    for cmd in ["segment", "sift"] {
        let (code, _, stderr) = quarry(&[cmd, cut.to_str().unwrap()]);
        assert_eq!(code, 1, "{cmd}: {stderr}");
        assert!(stderr.contains("truncated"), "{cmd}: {stderr}");
    }
    // a PNG declaring 100 000 x 100 000 RGB with almost no pixel data
    let crc32 = |data: &[u8]| {
        let mut crc = 0xFFFF_FFFFu32;
        for &b in data {
            crc ^= u32::from(b);
            for _ in 0..8 {
                crc = if crc & 1 == 1 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    };
    let mut png = vec![0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];
    let mut ihdr = 100_000u32.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&100_000u32.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    for (kind, data) in [
        (*b"IHDR", ihdr),
        (
            *b"IDAT",
            vec![0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01],
        ),
        (*b"IEND", vec![]),
    ] {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(&data);
        png.extend_from_slice(&body);
        png.extend_from_slice(&crc32(&body).to_be_bytes());
    }
    let huge = d.join("huge.png");
    std::fs::write(&huge, &png).unwrap();
    let (code, _, stderr) = quarry(&["segment", huge.to_str().unwrap()]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("at most 16384"), "{stderr}");
    let (code, _, stderr) = quarry(&["segment", jpg.to_str().unwrap(), "--sigma", "1e6"]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("too large"), "{stderr}");
}

#[cfg(all(unix, feature = "zenoh"))]
/// A free TCP port on 127.0.0.1 (bound and released; the test binds it again at once).
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Waits for `child` at most `limit`, killing it (and failing) if it is still running.
fn wait_child(child: &mut std::process::Child, limit: std::time::Duration) -> i32 {
    let t0 = std::time::Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st.code().unwrap_or(-1);
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("still running after {} s", limit.as_secs());
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

#[cfg(all(unix, feature = "zenoh"))]
#[test]
fn lidar_server_refuses_an_unknown_sensor_and_stops_cleanly_on_sigterm() {
    use std::process::Stdio;
    let d = tmpdir("sigterm");
    let port = free_port();
    let ep = format!("tcp/127.0.0.1:{port}");
    // a server of one scanner, id 5
    let sensors = d.join("sensors.json");
    std::fs::write(
        &sensors,
        r#"[{"id": 5, "x": 0.0, "y": 0.0, "theta_deg": 0.0}]"#,
    )
    .unwrap();
    let mut server = Command::new(env!("CARGO_BIN_EXE_quarry"))
        .args(["lidar-server", "--listen", &ep, "--json", "--sensors"])
        .arg(&sensors)
        .arg("--out")
        .arg(&d)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // the server is up once its zenoh listener accepts connections
    let t0 = std::time::Instant::now();
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t0.elapsed() < std::time::Duration::from_mins(2),
            "the server never listened"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    // a node (the simulated room's scanner 0) the server does not have is told why at once,
    // not after its 120 s wait
    let (code, _, stderr) = quarry(&[
        "lidar-node",
        "--connect",
        &ep,
        "--max-scans",
        "5",
        "--wait-server",
        "120",
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("not one of this server's sensors"),
        "{stderr}"
    );
    let st = Command::new("kill")
        .args(["-TERM", &server.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let code = wait_child(&mut server, std::time::Duration::from_mins(2));
    let mut out = String::new();
    std::io::Read::read_to_string(server.stdout.as_mut().unwrap(), &mut out).unwrap();
    assert_eq!(code, 130, "stdout: {out}");
    let v: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(v["interrupted"], true, "{v}");
    assert_eq!(v["refused"][0][0], 0, "{v}");
    assert!(d.join("server.json").exists());
}

#[cfg(unix)]
#[test]
fn motion_stops_cleanly_on_sigint_and_reports_the_frames_done() {
    use std::process::Stdio;
    let Some(sh) = shared() else { return };
    let frames = sh.join("data/pets09-s2l1/img1");
    if !frames.exists() {
        eprintln!("skipping: no {}", frames.display());
        return;
    }
    let d = tmpdir("motion-sigint");
    let mut child = Command::new(env!("CARGO_BIN_EXE_quarry"))
        .args(["--json", "motion"])
        .arg(&frames)
        .arg("--out")
        .arg(&d)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // interrupt once the second annotated frame is written
    let t0 = std::time::Instant::now();
    while !d.join("000002.png").exists() {
        assert!(
            t0.elapsed() < std::time::Duration::from_mins(2),
            "no frame written"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let code = wait_child(&mut child, std::time::Duration::from_mins(2));
    let mut out = String::new();
    std::io::Read::read_to_string(child.stdout.as_mut().unwrap(), &mut out).unwrap();
    assert_eq!(code, 130, "stdout: {out}");
    let v: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(v["interrupted"], true, "{v}");
    let n = v["frames"].as_u64().unwrap();
    assert!((2..200).contains(&n), "{n} frames");
    assert_eq!(v["per_frame"].as_array().unwrap().len() as u64, n);
}

/// Whether process `pid` has a handler installed for SIGINT (Linux: bit 1 of `SigCgt` in
/// /proc/PID/status), so that a test signals it only once the signal is caught.
#[cfg(target_os = "linux")]
fn catches_sigint(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("SigCgt:"))
                .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
        })
        .is_some_and(|mask| mask & (1 << 1) != 0)
}

/// Runs `quarry ARGS`, sends it SIGINT once it catches the signal (after `settle` more), and
/// returns its exit status and JSON summary (stdout).
#[cfg(target_os = "linux")]
fn interrupted_run(args: &[&str], settle: std::time::Duration) -> (i32, Value) {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_quarry"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !catches_sigint(child.id()) {
        assert!(
            t0.elapsed() < std::time::Duration::from_mins(2),
            "the handler was never installed"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    std::thread::sleep(settle);
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let code = wait_child(&mut child, std::time::Duration::from_mins(2));
    let mut out = String::new();
    std::io::Read::read_to_string(child.stdout.as_mut().unwrap(), &mut out).unwrap();
    let v: Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    (code, v)
}

#[cfg(target_os = "linux")]
#[test]
fn lidar_sim_stops_cleanly_on_sigint_and_writes_the_frames_done() {
    let d = tmpdir("lidar-sigint");
    let out = d.to_str().unwrap();
    // a million frames: about 14 simulated hours, stopped long before; it tracks a little
    // before the signal (not needed for the test to hold: 0 frames is a valid answer)
    let (code, v) = interrupted_run(
        &["--json", "lidar", "--frames", "1000000", "--out", out],
        std::time::Duration::from_millis(1500),
    );
    assert_eq!(code, 130, "{v}");
    assert_eq!(v["interrupted"], true, "{v}");
    let n = v["frames"].as_u64().unwrap();
    assert!(n < 1_000_000, "{n} frames");
    for f in ["tracks.csv", "tracks_mot.txt", "metrics.json", "plot.png"] {
        assert!(d.join(f).exists(), "{f} not written");
    }
    let m: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(m["interrupted"], true);
}

#[cfg(target_os = "linux")]
#[test]
fn slamot_runs_stop_cleanly_on_sigint_and_report_the_runs_done() {
    // A signal before the first run ends is a valid answer too (no run done, none reported);
    // on a busy machine that happens, so the signal then waits twice as long, until a run is
    // done before it and the summary of the runs done can be checked.
    let mut settle = std::time::Duration::from_millis(250);
    loop {
        let (code, v) = interrupted_run(
            &["--json", "slamot", "--runs", "100000", "--particles", "5"],
            settle,
        );
        assert_eq!(code, 130, "{v}");
        assert_eq!(v["interrupted"], true, "{v}");
        let n = v["runs"].as_u64().unwrap();
        assert!(n < 100_000, "{n} runs");
        assert_eq!(v["per_run"].as_array().unwrap().len() as u64, n);
        if n == 0 {
            settle *= 2;
            assert!(
                settle < std::time::Duration::from_mins(1),
                "no run done in 30 s"
            );
            continue;
        }
        assert!(v["robot_err_mean"].as_f64().unwrap().is_finite(), "{v}");
        break;
    }
}

#[cfg(target_os = "linux")]
#[test]
fn slamot_sweep_stops_cleanly_on_sigint_and_keeps_only_complete_counts() {
    let d = tmpdir("sweep-sigint");
    let out = d.to_str().unwrap();
    // 100 000 runs per count: the first count never completes before the signal
    let (code, v) = interrupted_run(
        &[
            "--json",
            "slamot",
            "sweep",
            "--particles",
            "5,10",
            "--runs",
            "100000",
            "--out",
            out,
        ],
        std::time::Duration::ZERO,
    );
    assert_eq!(code, 130, "{v}");
    assert_eq!(v["interrupted"], true, "{v}");
    assert_eq!(v["points"].as_array().unwrap().len(), 0, "{v}");
    let csv = std::fs::read_to_string(d.join("sweep.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1, "only the header: {csv}");
    assert!(d.join("fig3.png").exists() && d.join("fig4.png").exists());
}

#[cfg(target_os = "linux")]
#[test]
fn demo_stops_cleanly_on_sigint_after_the_tracker_in_progress() {
    // the signal comes while the first rows run; the last tracker (rgbd) is never started
    let (code, v) = interrupted_run(&["--json", "demo"], std::time::Duration::ZERO);
    assert_eq!(code, 130, "{v}");
    assert_eq!(v["interrupted"], true, "{v}");
    let rows = v["rows"].as_array().unwrap();
    assert!(
        rows.iter()
            .all(|r| !r["tracker"].as_str().unwrap().contains("rgbd")),
        "{v}"
    );
}

/// Writes `n` grey PNG frames of `w x h` (a dark disc moving right on a gradient) into `dir`.
fn write_frames(dir: &std::path::Path, n: u32, w: u32, h: u32) {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..n {
        let img = image::GrayImage::from_fn(w, h, |x, y| {
            let cx = 10.0 + 2.0 * f64::from(k);
            let d = (f64::from(x) - cx).hypot(f64::from(y) - f64::from(h) / 2.0);
            image::Luma([if d < 5.0 {
                40
            } else {
                (150 + (x + y) % 50) as u8
            }])
        });
        img.save(dir.join(format!("{:06}.png", k + 1))).unwrap();
    }
}

#[test]
fn video_runs_writes_results_and_scores_like_eval() {
    let d = tmpdir("video-ok");
    let frames = d.join("img1");
    write_frames(&frames, 12, 64, 48);
    let gt = d.join("gt.txt");
    let mut body = String::new();
    for k in 0..12u32 {
        let cx = 10.0 + 2.0 * f64::from(k);
        use std::fmt::Write as _;
        writeln!(body, "{},1,{},{},12,30,1,-1,-1,-1", k + 1, cx - 5.0, 10.0).unwrap();
    }
    std::fs::write(&gt, body).unwrap();
    let out = d.join("out");
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "video",
        "--frames",
        frames.to_str().unwrap(),
        "--gt",
        gt.to_str().unwrap(),
        "--profile",
        "robust",
        "--person-size",
        "12x30",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["frames"], 12);
    assert_eq!(v["profile"], "robust");
    assert_eq!(v["config"]["box_w"], 12.0);
    let res = out.join(format!("{}.txt", v["name"].as_str().unwrap()));
    assert!(res.exists(), "{v}");
    assert!(out.join("config.toml").exists());
    assert!(out.join("frames/000001.png").exists());
    // the metrics are those of `quarry eval` on the written files
    let (c2, s2, e2) = quarry(&[
        "--json",
        "eval",
        "--gt",
        gt.to_str().unwrap(),
        "--res",
        res.to_str().unwrap(),
    ]);
    assert_eq!(c2, 0, "{e2}");
    let e: Value = serde_json::from_str(s2.trim()).unwrap();
    for k in ["mota", "idf1", "hota", "fp", "fn", "idsw"] {
        assert_eq!(v["metrics"][k], e[k], "{k}");
    }
}

/// `quarry video sim` writes a MOTChallenge sequence that `quarry video` reads back: the
/// tracker's result file is byte-identical to the one `--score` wrote from the in-memory
/// frames, and so are the metrics.
/// `video sim --config` lays a TOML file over the profile: a 44-px box shows in the results.
#[test]
fn video_sim_score_takes_a_config_overlay() {
    let d = tmpdir("video-sim-config");
    let cfg = d.join("box.toml");
    std::fs::write(&cfg, "box_w = 44.0\n").unwrap();
    let seq = d.join("ab");
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "video",
        "sim",
        "--variant",
        "ab",
        "--frames",
        "70",
        "--no-images",
        "--score",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        seq.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["score"]["profile"], "paper");
    let res = std::fs::read_to_string(seq.join("walkers-v1-ab-paper.txt")).unwrap();
    let widths: Vec<f64> = res
        .lines()
        .map(|l| l.split(',').nth(4).unwrap().parse().unwrap())
        .collect();
    assert!(!widths.is_empty(), "no box in 70 frames");
    assert!(widths.iter().all(|&w| w == 44.0), "{widths:?}");
}

#[test]
fn video_sim_writes_a_sequence_that_video_reads_back() {
    let d = tmpdir("video-sim");
    let seq = d.join("ab");
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "video",
        "sim",
        "--variant",
        "ab",
        "--frames",
        "90",
        "--score",
        "--out",
        seq.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["sequence"], "walkers-v1-ab");
    assert_eq!(v["frames"], 90);
    assert_eq!(v["events"]["walkers"][0]["half_in_view"], 34);
    for f in [
        "img1/000001.png",
        "img1/000090.png",
        "gt/gt.txt",
        "events.json",
        "seqinfo.ini",
        "pools.png",
    ] {
        assert!(seq.join(f).exists(), "{f}");
    }
    assert!(!seq.join("img1/000091.png").exists());
    let gt_text = std::fs::read_to_string(seq.join("gt/gt.txt")).unwrap();
    assert_eq!(
        gt_text.lines().count(),
        v["gt_rows"].as_u64().unwrap() as usize
    );
    assert!(
        std::fs::read_to_string(seq.join("seqinfo.ini"))
            .unwrap()
            .contains("seqLength=90")
    );
    let sim_res = std::fs::read(v["score"]["results"].as_str().unwrap()).unwrap();
    assert!(!sim_res.is_empty());

    let out = d.join("run");
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "video",
        "--frames",
        seq.join("img1").to_str().unwrap(),
        "--gt",
        seq.join("gt/gt.txt").to_str().unwrap(),
        "--name",
        "ab",
        "--no-images",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let w: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(w["frames"], 90);
    assert_eq!(std::fs::read(out.join("ab.txt")).unwrap(), sim_res);
    for k in ["mota", "idf1"] {
        let (a, b) = (
            w["metrics"][k].as_f64().unwrap(),
            v["score"]["metrics"][k].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-12, "{k}: {a} vs {b}");
    }
    assert_eq!(w["metrics"]["idsw"], v["score"]["metrics"]["idsw"]);
}

/// Absurd `quarry video sim` flags are clear errors, and `quarry video` still needs --frames.
#[test]
fn video_sim_rejects_bad_flags() {
    let d = tmpdir("video-sim-bad");
    let o = d.to_str().unwrap();
    let bad = d.join("bad.toml");
    std::fs::write(&bad, "not_a_key = 1\n").unwrap();
    let bad_cfg = bad.to_str().unwrap().to_owned();
    for (args, needle) in [
        (
            vec!["video", "sim", "--frames", "0", "--out", o],
            "at least 1",
        ),
        (
            vec!["video", "sim", "--frames", "ten", "--out", o],
            "whole number",
        ),
        (
            vec!["video", "sim", "--variant", "v9", "--out", o],
            "expected v1, ab or empty",
        ),
        (
            vec![
                "video",
                "sim",
                "--variant",
                "empty",
                "--frames",
                "201",
                "--out",
                o,
            ],
            "has 200 frames",
        ),
        (vec!["video", "--out", o], "--frames"),
        (
            vec![
                "video", "sim", "--frames", "2", "--out", o, "--config", &bad_cfg,
            ],
            "not_a_key",
        ),
        (
            vec![
                "video", "sim", "--frames", "2", "--out", o, "--range", "1..2",
            ],
            "--range",
        ),
    ] {
        let (code, _o, e) = quarry(&args);
        assert_ne!(code, 0, "{args:?}");
        assert!(e.contains(needle), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
}

#[test]
fn video_bad_input_is_a_clear_error_naming_the_file() {
    let d = tmpdir("video-bad");
    let run = |frames: &std::path::Path, extra: &[&str]| {
        let mut a = vec!["video", "--frames", frames.to_str().unwrap()];
        a.extend_from_slice(extra);
        let out = d.join("out");
        a.extend_from_slice(&["--out", out.to_str().unwrap(), "--no-images"]);
        let (code, _o, e) = quarry(&a);
        assert_ne!(code, 0);
        assert!(!e.contains("panicked"), "{e}");
        e
    };
    // empty directory
    let empty = d.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let e = run(&empty, &[]);
    assert!(
        e.contains("empty") && e.contains("no PNG or JPEG frames"),
        "{e}"
    );
    // truncated image
    let trunc = d.join("trunc");
    write_frames(&trunc, 3, 40, 30);
    let p = trunc.join("000002.png");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() / 2]).unwrap();
    let e = run(&trunc, &[]);
    assert!(e.contains("000002.png"), "{e}");
    // unreadable (not an image at all)
    let junk = d.join("junk");
    write_frames(&junk, 2, 40, 30);
    std::fs::write(junk.join("000003.png"), b"not a png").unwrap();
    let e = run(&junk, &[]);
    assert!(e.contains("000003.png"), "{e}");
    // frames of different sizes
    let mixed = d.join("mixed");
    write_frames(&mixed, 2, 40, 30);
    image::GrayImage::new(41, 30)
        .save(mixed.join("000003.png"))
        .unwrap();
    let e = run(&mixed, &[]);
    assert!(e.contains("000003.png") && e.contains("same size"), "{e}");
    // a 1x1 frame
    let tiny = d.join("tiny");
    std::fs::create_dir_all(&tiny).unwrap();
    image::GrayImage::new(1, 1)
        .save(tiny.join("000001.png"))
        .unwrap();
    let e = run(&tiny, &[]);
    assert!(e.contains("000001.png") && e.contains("1x1"), "{e}");
    // ground truth that does not parse
    let ok = d.join("ok");
    write_frames(&ok, 2, 40, 30);
    let gt = d.join("bad_gt.txt");
    std::fs::write(&gt, "1,2,three\n").unwrap();
    let e = run(&ok, &["--gt", gt.to_str().unwrap()]);
    assert!(e.contains("bad_gt.txt"), "{e}");
    // a config with an unknown key: file and line
    let cfg = d.join("bad.toml");
    std::fs::write(&cfg, "sigma = 4.0\nsigmaa = 2.0\n").unwrap();
    let e = run(&ok, &["--config", cfg.to_str().unwrap()]);
    assert!(e.contains("bad.toml") && e.contains("line 2"), "{e}");
}

/// `robust` on PETS09-S2L1 frames 1-200 (read in place), scored against its ground truth.
#[test]
fn video_on_pets_if_present() {
    let Some(sh) = shared() else { return };
    let frames = sh.join("data/pets09-s2l1/img1");
    if !frames.exists() {
        eprintln!("skipping: no {}", frames.display());
        return;
    }
    let d = tmpdir("video-pets");
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "video",
        "--frames",
        frames.to_str().unwrap(),
        "--gt",
        sh.join("data/pets09-s2l1/gt.txt").to_str().unwrap(),
        "--person-size",
        "32x84",
        "--profile",
        "robust",
        "--no-images",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{stderr}");
    let v: Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["frames"], 200);
    assert_eq!(v["metrics"]["gt"], 1223);
    // the accuracy on real video (docs/video-tracker.md, stop 39: MOTA 0.541, IDF1 0.584,
    // HOTA 0.450; the best peer, KNN + ByteTrack: 0.419, 0.447, 0.362), with a margin; MOTA
    // fails without `fg_pairs_hold` (stop 34: 0.504), IDF1 and HOTA without `reacquire`
    // (stop 38: 0.564, 0.440), the recall's held-box rule (stop 37: 0.534, 0.423) and
    // `fg_pairs_group_companion` (stop 35: 0.482, 0.367); IDF1 >= 0.55 is the issue's goal
    let m = &v["metrics"];
    let get = |k: &str| m[k].as_f64().unwrap();
    assert!(get("mota") >= 0.53, "{m}");
    assert!(get("idf1") >= 0.57, "{m}");
    assert!(get("hota") >= 0.445, "{m}");
}

#[test]
fn rgbd_frames_limits_a_scenario_run_and_refuses_absurd_values() {
    let (code, stdout, err) = quarry(&["--json", "rgbd", "--scenario", "s1", "--frames", "6"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["frames"], 6);
    assert!(v["center_err_px"].as_f64().unwrap().is_finite());
    for bad in ["0", "1", "many"] {
        let (code, _, err) = quarry(&["rgbd", "--scenario", "s1", "--frames", bad]);
        assert_eq!(code, 2, "--frames {bad}: {err}");
        assert!(err.contains("--frames"), "--frames {bad}: {err}");
    }
    let (code, _, err) = quarry(&[
        "rgbd",
        "--sequence",
        "x",
        "--init",
        "1,1,2,2",
        "--frames",
        "5",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--frames") && err.contains("--sequence"),
        "{err}"
    );
}
