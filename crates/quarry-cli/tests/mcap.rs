//! `--mcap` recordings read back by tools nobody here wrote: the Python `mcap` reader with
//! `mcap-ros2-support` decodes every message, and the decoded tracks equal the run's CSV /
//! MOTChallenge output. The venv is quarry_testkit::python's (`ros2`, pinned in
//! crates/quarry-ros2/tests/python/requirements.txt).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use quarry_testkit::python::{PythonEnv, venv_or_skip};
use serde_json::Value;

fn python() -> Option<PythonEnv> {
    let reqs =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../quarry-ros2/tests/python/requirements.txt");
    venv_or_skip(Path::new(env!("CARGO_TARGET_TMPDIR")), "ros2", &reqs)
}

fn tmpdir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("mcap-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

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

fn read_back(py: &PythonEnv, mcap: &Path) -> Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/read_mcap.py");
    let out = py.command().arg(script).arg(mcap).output().unwrap();
    assert!(
        out.status.success(),
        "read_mcap.py {}: {}",
        mcap.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn shared_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    let d = p.join("data");
    if d.exists() {
        Some(d)
    } else {
        eprintln!("skipping the recorded-data part: no {}", d.display());
        None
    }
}

/// `tracks.csv` rows as (t_ns, id) → (x, y).
fn csv_tracks(path: &Path) -> BTreeMap<(u64, u64), (f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut m = BTreeMap::new();
    for l in text.lines().skip(1) {
        let c: Vec<&str> = l.split(',').collect();
        let t_ns = c[1].parse::<u64>().unwrap() * 1000;
        m.insert(
            (t_ns, c[2].parse().unwrap()),
            (c[3].parse().unwrap(), c[4].parse().unwrap()),
        );
    }
    m
}

/// Every decoded `/tracks` row equals a CSV row (positions to the CSV's 4 decimals) and the
/// counts agree.
fn assert_tracks_equal(decoded: &Value, csv: &BTreeMap<(u64, u64), (f64, f64)>) {
    let rows = decoded["tracks"]["/tracks"].as_array().unwrap();
    assert_eq!(
        rows.len(),
        csv.len(),
        "decoded track rows vs tracks.csv rows"
    );
    assert!(!rows.is_empty(), "the run produced no tracks to compare");
    for r in rows {
        let key = (r[0].as_u64().unwrap(), r[1].as_u64().unwrap());
        let (x, y) = csv
            .get(&key)
            .unwrap_or_else(|| panic!("track {key:?} of the MCAP is not in tracks.csv"));
        assert!((r[2].as_f64().unwrap() - x).abs() <= 5.1e-5, "{key:?} x");
        assert!((r[3].as_f64().unwrap() - y).abs() <= 5.1e-5, "{key:?} y");
    }
}

fn assert_every_message_decoded(v: &Value) {
    assert_eq!(v["profile"], "ros2");
    let total: u64 = v["topics"]
        .as_object()
        .unwrap()
        .values()
        .map(|t| {
            assert_eq!(t["schema_encoding"], "ros2msg");
            assert_eq!(t["message_encoding"], "cdr");
            t["count"].as_u64().unwrap()
        })
        .sum();
    assert_eq!(v["decoded"].as_u64().unwrap(), total);
}

#[test]
fn lidar_sim_recording_decodes_in_python_and_equals_the_csv() {
    let Some(py) = python() else { return };
    let d = tmpdir("lidar-sim");
    let (file, out) = (d.join("run.mcap"), d.join("out"));
    let (code, stdout, err) = quarry(&[
        "lidar",
        "--frames",
        "200",
        "--json",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(&stdout).unwrap();
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    assert_eq!(summary["mcap"]["messages"], v["decoded"]);
    for topic in [
        "/tf_static",
        "/tracks",
        "/tracks/markers",
        "/ground_truth/people",
    ] {
        assert!(
            v["topics"][topic]["count"].as_u64().unwrap() >= 1,
            "{topic}"
        );
    }
    assert_eq!(
        v["topics"]["/tracks"]["schema"],
        "quarry_msgs/msg/TrackArray"
    );
    assert_eq!(
        v["topics"]["/tracks/markers"]["schema"],
        "visualization_msgs/msg/MarkerArray"
    );
    // three scanners, 1081 beams each, about 40 scans per simulated second
    let scans = v["scans"].as_object().unwrap();
    assert_eq!(scans.len(), 3);
    for s in scans.values() {
        assert_eq!(s["beams"], 1081);
        assert!(s["count"].as_u64().unwrap() > 400);
    }
    assert_tracks_equal(&v, &csv_tracks(&out.join("tracks.csv")));
    // the MOTChallenge rows are the same tracks: one line per decoded track row
    let mot = std::fs::read_to_string(out.join("tracks_mot.txt")).unwrap();
    assert_eq!(
        mot.lines().count(),
        v["tracks"]["/tracks"].as_array().unwrap().len()
    );
}

#[test]
fn lidar_recorded_scans_recording_holds_every_scan_and_the_tracks() {
    let Some(py) = python() else { return };
    let Some(data) = shared_data() else { return };
    let lt = data.join("leg-tracker");
    let d = tmpdir("lidar-scans");
    let (file, out) = (d.join("p1.mcap"), d.join("out"));
    let (code, stdout, err) = quarry(&[
        "lidar",
        "--scans",
        lt.join("positive_1_scans.csv").to_str().unwrap(),
        "--legs",
        lt.join("positive_1_legs.csv").to_str().unwrap(),
        "--detector",
        "legs",
        "--preset",
        "jipda",
        "--json",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(&stdout).unwrap();
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    // every scan read is recorded, with the recording's own beam count
    assert_eq!(v["scans"]["/scan"]["beams"], summary["n_beams"]);
    assert_eq!(
        v["scans"]["/scan"]["count"].as_u64().unwrap(),
        summary["frames"].as_u64().unwrap()
    );
    assert_eq!(
        v["topics"]["/ground_truth/person"]["count"]
            .as_u64()
            .unwrap(),
        summary["labelled"]["labelled"].as_u64().unwrap()
    );
    assert_tracks_equal(&v, &csv_tracks(&out.join("tracks.csv")));
}

#[test]
fn mcap_flag_errors_name_the_path() {
    let d = tmpdir("errors");
    // an unwritable place: a file below a regular file
    let blocker = d.join("file");
    std::fs::write(&blocker, "x").unwrap();
    let bad = blocker.join("run.mcap");
    let (code, _, err) = quarry(&["lidar", "--frames", "20", "--mcap", bad.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("--mcap") && err.contains("run.mcap"), "{err}");
    // a directory
    let (code, _, err) = quarry(&["lidar", "--frames", "20", "--mcap", d.to_str().unwrap()]);
    assert_ne!(code, 0);
    assert!(err.contains("is a directory"), "{err}");
    // the other recorders refuse the same path at once (the server before it opens a network
    // session)
    for cmd in [
        vec!["rgbd", "--scenario", "s1"],
        vec!["lidar-server", "--listen", "tcp/127.0.0.1:1"],
    ] {
        let mut a = cmd.clone();
        a.extend(["--mcap", bad.to_str().unwrap()]);
        let (code, _, err) = quarry(&a);
        assert_ne!(code, 0, "{cmd:?}");
        assert!(
            err.contains("--mcap") && err.contains("run.mcap"),
            "{cmd:?}: {err}"
        );
    }
}

/// Rows of a CSV with a header, as column name → values.
fn csv_columns(path: &Path) -> BTreeMap<String, Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let names: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut cols: BTreeMap<String, Vec<f64>> = names.iter().map(|n| (n.clone(), vec![])).collect();
    for l in lines {
        for (n, v) in names.iter().zip(l.split(',')) {
            cols.get_mut(n).unwrap().push(v.parse().unwrap_or(f64::NAN));
        }
    }
    cols
}

#[test]
fn slamot_sim_recording_decodes_and_equals_the_trajectory_and_map_csvs() {
    let Some(py) = python() else { return };
    let d = tmpdir("slamot-sim");
    let (file, out) = (d.join("run.mcap"), d.join("out"));
    let (code, _, err) = quarry(&[
        "slamot",
        "--particles",
        "20",
        "--runs",
        "1",
        "--seed",
        "4",
        "--json",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    let cols = csv_columns(&out.join("trajectories_run4.csv"));
    let t = &cols["t"];
    // the estimated pose per epoch
    let est = v["poses"]["/pose/estimate"].as_array().unwrap();
    assert_eq!(est.len(), t.len());
    for (k, p) in est.iter().enumerate() {
        assert!(
            (p[0].as_f64().unwrap() * 1e-9 - t[k]).abs() < 1.1e-3,
            "epoch {k} time"
        );
        assert!((p[1].as_f64().unwrap() - cols["est_x"][k]).abs() < 1e-4);
        assert!((p[2].as_f64().unwrap() - cols["est_y"][k]).abs() < 1e-4);
        assert!((p[3].as_f64().unwrap() - cols["est_theta"][k]).abs() < 1e-4);
    }
    // the targets: one row per epoch per target slot, equal to the CSV's estimate columns
    let rows = v["tracks"]["/targets"].as_array().unwrap();
    let n_targets = cols.keys().filter(|k| k.ends_with("_est_x")).count();
    assert!(n_targets >= 1);
    assert_eq!(rows.len(), t.len() * n_targets);
    for (i, r) in rows.iter().enumerate() {
        let (k, l) = (i / n_targets, r[1].as_u64().unwrap() as usize);
        let x = cols[&format!("t{l}_est_x")][k];
        let y = cols[&format!("t{l}_est_y")][k];
        assert!(
            (r[2].as_f64().unwrap() - x).abs() < 1e-4 && (r[3].as_f64().unwrap() - y).abs() < 1e-4
        );
    }
    // the map: the CSV's landmarks, by id
    let map = csv_columns(&out.join("map_run4.csv"));
    let lm = v["markers"]["/map/landmarks"].as_array().unwrap();
    assert_eq!(lm.len(), map["landmark"].len());
    for m in lm {
        let i = map["landmark"]
            .iter()
            .position(|&id| id == m[0].as_f64().unwrap())
            .unwrap();
        assert!((m[1].as_f64().unwrap() - map["x"][i]).abs() < 1e-4);
        assert!((m[2].as_f64().unwrap() - map["y"][i]).abs() < 1e-4);
    }
    assert!(v["topics"]["/odom"]["count"].as_u64().unwrap() >= t.len() as u64);
    assert!(
        v["topics"]["/ground_truth/targets"]["count"]
            .as_u64()
            .unwrap()
            >= 1
    );
}

#[test]
fn slamot_mrclam_recording_holds_the_tracks_of_the_csv() {
    let Some(py) = python() else { return };
    let Some(data) = shared_data() else { return };
    let d = tmpdir("slamot-mrclam");
    let (file, out) = (d.join("r3.mcap"), d.join("out"));
    let (code, _, err) = quarry(&[
        "slamot",
        "--mrclam",
        data.join("mrclam-6").to_str().unwrap(),
        "--robot",
        "3",
        "--particles",
        "20",
        "--json",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    let tracks = csv_columns(&out.join("mrclam_robot3_tracks.csv"));
    let rows = v["tracks"]["/targets"].as_array().unwrap();
    assert_eq!(rows.len(), tracks["t"].len());
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r[1].as_f64().unwrap(), tracks["track"][i]);
        assert!((r[2].as_f64().unwrap() - tracks["x"][i]).abs() < 1e-4);
        assert!((r[3].as_f64().unwrap() - tracks["y"][i]).abs() < 1e-4);
    }
    let traj = csv_columns(&out.join("mrclam_robot3_trajectory.csv"));
    assert_eq!(
        v["poses"]["/ground_truth/pose"].as_array().unwrap().len(),
        traj["t"].len()
    );
    assert!(
        v["markers"]["/ground_truth/landmarks"]
            .as_array()
            .unwrap()
            .len()
            >= 10
    );
}

/// MOTChallenge rows `frame,id,l,t,w,h,...` as (frame, id) → box.
fn mot_rows(path: &Path) -> BTreeMap<(u64, String), [f64; 4]> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            let f = |i: usize| c[i].trim().parse::<f64>().unwrap();
            (
                (c[0].trim().parse().unwrap(), c[1].trim().to_string()),
                [f(2), f(3), f(4), f(5)],
            )
        })
        .collect()
}

#[test]
fn video_recording_on_pets_decodes_and_equals_the_motchallenge_output() {
    let Some(py) = python() else { return };
    let Some(data) = shared_data() else { return };
    let pets = data.join("pets09-s2l1");
    let d = tmpdir("video");
    let (file, out) = (d.join("pets.mcap"), d.join("out"));
    let (code, stdout, err) = quarry(&[
        "--json",
        "video",
        "--frames",
        pets.join("img1").to_str().unwrap(),
        "--gt",
        pets.join("gt.txt").to_str().unwrap(),
        "--range",
        "1..12",
        "--person-size",
        "32x84",
        "--profile",
        "robust",
        "--no-images",
        "--fps",
        "7",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(stdout.trim()).unwrap();
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    assert_eq!(v["topics"]["/image"]["count"], 12);
    assert_eq!(
        v["topics"]["/image"]["schema"],
        "sensor_msgs/msg/CompressedImage"
    );
    assert_eq!(v["topics"]["/ground_truth/detections"]["count"], 12);
    let mot = mot_rows(Path::new(summary["results"].as_str().unwrap()));
    let det = v["detections"].as_array().unwrap();
    assert!(!det.is_empty(), "no tracks in 12 PETS frames");
    assert_eq!(det.len(), mot.len(), "one decoded box per MOT row");
    let ours: Vec<&Value> = det
        .iter()
        .filter(|r| {
            let frame = (r[0].as_f64().unwrap() * 1e-9 * 7.0).round() as u64 + 1;
            mot.contains_key(&(frame, r[1].as_str().unwrap().to_string()))
        })
        .collect();
    assert_eq!(ours.len(), mot.len(), "every MOT row is in the MCAP");
    for r in ours {
        let frame = (r[0].as_f64().unwrap() * 1e-9 * 7.0).round() as u64 + 1;
        let b = mot[&(frame, r[1].as_str().unwrap().to_string())];
        for (i, want) in b.iter().enumerate() {
            // the MCAP box is 0-based, the MOT file 1-based
            let got = r[2 + i].as_f64().unwrap() + if i < 2 { 1.0 } else { 0.0 };
            assert!(
                (got - want).abs() < 1e-2,
                "frame {frame} box {i}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn rgbd_recording_decodes_and_equals_the_boxes_file() {
    let Some(py) = python() else { return };
    let d = tmpdir("rgbd");
    let (file, out) = (d.join("s1.mcap"), d.join("out"));
    let (code, stdout, err) = quarry(&[
        "--json",
        "rgbd",
        "--scenario",
        "s1",
        "--seed",
        "0",
        "--frames",
        "40",
        "--out",
        out.to_str().unwrap(),
        "--mcap",
        file.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: Value = serde_json::from_str(stdout.trim()).unwrap();
    let frames = summary["frames"].as_u64().unwrap();
    // --frames 40: frame 0 (the initialisation) and 39 tracked frames, not the scenario's 360
    assert_eq!(frames, 40);
    assert_eq!(summary["mcap"]["topics"], 6);
    let v = read_back(&py, &file);
    assert_every_message_decoded(&v);
    for topic in [
        "/camera/color",
        "/camera/depth",
        "/detections",
        "/ground_truth/detections",
        "/odom",
        "/ground_truth/pose",
    ] {
        assert_eq!(v["topics"][topic]["count"], frames, "{topic}");
    }
    assert_eq!(
        v["topics"]["/camera/depth"]["schema"],
        "sensor_msgs/msg/CompressedImage"
    );
    // one decoded box per boxes.txt row, in order, equal to its 2 decimals
    let boxes = std::fs::read_to_string(out.join("boxes.txt")).unwrap();
    let rows: Vec<Vec<f64>> = boxes
        .lines()
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    let det = v["detections"].as_array().unwrap();
    assert_eq!(det.len(), rows.len());
    for (r, b) in det.iter().zip(&rows) {
        assert_eq!(r[1], "1");
        for i in 0..4 {
            let got = r[2 + i].as_f64().unwrap();
            assert!((got - b[2 + i]).abs() < 6e-3, "{r} vs {b:?}");
        }
    }
}
