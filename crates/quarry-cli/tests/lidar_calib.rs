//! `quarry lidar --calibration given|icp`: the recovered poses in the JSON, and clear errors.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use serde_json::Value;
use std::process::Command;

fn quarry(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_quarry"))
        .args(args)
        .output()
        .expect("run quarry");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn lidar_icp_calibration_reports_the_recovered_poses() {
    let (code, stdout, stderr) = quarry(&[
        "--json",
        "lidar",
        "--calibration",
        "icp",
        "--frames",
        "40",
        "--seed",
        "4",
    ]);
    assert_eq!(code, 0, "{stderr}");
    let v: Value = serde_json::from_str(&stdout).unwrap();
    let c = &v["calibration"];
    let scanners = c["scanners"].as_array().unwrap();
    assert_eq!(scanners.len(), 3);
    assert!(c["max_pos_error_m"].as_f64().unwrap() <= 0.02, "{c}");
    assert!(c["max_rot_error_deg"].as_f64().unwrap() <= 0.3, "{c}");
    // the rough poses were really off: the calibration did something
    assert!(
        scanners
            .iter()
            .any(|s| s["rough_pos_error_m"].as_f64().unwrap() > 0.02)
    );
    // given: no calibration field
    let (code, stdout, _) = quarry(&["--json", "lidar", "--frames", "40", "--seed", "4"]);
    assert_eq!(code, 0);
    let v: Value = serde_json::from_str(&stdout).unwrap();
    assert!(v.get("calibration").is_none());
    // bad values are clear errors
    let (code, _, stderr) = quarry(&["lidar", "--calibration", "sideways", "--frames", "40"]);
    assert_eq!(code, 1);
    assert!(stderr.contains("expected given or icp"), "{stderr}");
    let (code, _, stderr) = quarry(&[
        "lidar",
        "--calibration",
        "icp",
        "--preset",
        "literal",
        "--frames",
        "40",
    ]);
    assert_eq!(code, 1);
    assert!(stderr.contains("revealed_background"), "{stderr}");
}
