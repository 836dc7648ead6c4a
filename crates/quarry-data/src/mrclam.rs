//! Reader for the UTIAS MRCLAM datasets (Leung et al., IJRR 2011) as SLAMOT input.
//!
//! One robot K ("ours") drives on its odometry (v, ω) and observes 15 landmarks and the other
//! four robots by barcode. [`load`] turns the files of one dataset into per-control-step
//! [`MrclamFrame`]s for robot K: one frame per odometry interval, **split at every measurement
//! stamp** inside it, so that each measurement closes a frame ending at its own time (the filter
//! propagates the motion model exactly to the measurement, then updates; measurements sharing one
//! stamp share one frame), landmark detections mapped through `Barcodes.dat` to
//! landmark ids (subject 6 → `LandmarkId(0)`, …), detections of other robots **stripped of their
//! barcode** (the tracker must associate them itself) with the true robot kept apart in
//! [`MrclamTruth::target_obs_source`] for scoring, and Vicon ground truth interpolated at the
//! frame times.
//!
//! Column 2 of `RobotN_Measurement.dat` is the barcode, not the subject number (the header says
//! otherwise). Barcodes missing from `Barcodes.dat` are false detections: they are passed on as
//! unlabelled target detections (clutter, source `None`) and counted in [`MrclamSkips`].
//!
//! Bad input: a malformed or truncated line, and a record whose time is earlier than the previous
//! record's, are [`DataError::Parse`] with their file and line number; non-finite odometry,
//! measurement or ground-truth rows, zero-range measurements and the robot's own barcode are
//! counted skips ([`MrclamSkips`], for the caller to print), never a panic and never silent.
//!
//! ```
//! use quarry_data::mrclam::{MrclamTexts, from_texts};
//! let header = "# a\n# b\n# c\n# d\n";
//! let barcodes = format!("{header}1 5\n2 14\n6 63\n");
//! let landmarks = format!("{header}6 1.0 2.0 0.0 0.0\n");
//! let odo = format!("{header}10.00 0.1 0.0\n10.02 0.1 0.0\n10.04 0.1 0.0\n");
//! let meas = format!("{header}10.03 63 1.5 0.1\n10.03 14 2.0 -0.2\n");
//! let gt1 = format!("{header}9.9 0 0 0\n10.1 0.02 0 0\n");
//! let gt2 = format!("{header}9.9 3 3 0\n10.1 3 3 0\n");
//! let texts = MrclamTexts {
//!     barcodes: &barcodes, landmarks: &landmarks, odometry: &odo, measurements: &meas,
//!     groundtruth: vec![(1, gt1.as_str()), (2, gt2.as_str())],
//! };
//! let run = from_texts(&texts, 1)?;
//! // odometry intervals [10.00, 10.02] and [10.02, 10.04], the second split at the 10.03 stamp
//! assert_eq!(run.frames.len(), 3);
//! let f = &run.frames[1];
//! assert!((f.t - 0.03).abs() < 1e-9 && (f.dt - 0.01).abs() < 1e-9);
//! assert_eq!(f.landmark_obs.len(), 1);
//! assert_eq!(f.target_obs, vec![[2.0, -0.2]]);
//! assert_eq!(f.truth.target_obs_source, vec![Some(0)]); // target slot 0 = robot 2
//! # Ok::<(), quarry_data::DataError>(())
//! ```

use std::collections::BTreeMap;
use std::path::Path;

use quarry_core::{LandmarkId, Pose2, wrap_angle};
use serde::{Deserialize, Serialize};

use crate::DataError;

/// Counted skips: records that were dropped (or demoted to clutter) instead of failing the load.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MrclamSkips {
    /// Odometry or measurement records with a non-finite value (dropped).
    pub non_finite: usize,
    /// Ground-truth records (of any robot) with a non-finite value (dropped).
    pub non_finite_groundtruth: usize,
    /// Measurements with range exactly 0 (no detection can be that close; dropped).
    pub zero_range: usize,
    /// Measurements of a barcode missing from `Barcodes.dat` (passed on as clutter).
    pub unknown_barcode: usize,
    /// Measurements of the robot's own barcode (dropped).
    pub own_barcode: usize,
    /// Measurements outside the odometry time span (dropped).
    pub outside_span: usize,
}

impl MrclamSkips {
    /// Total records skipped or demoted to clutter.
    pub fn total(&self) -> usize {
        self.non_finite
            + self.non_finite_groundtruth
            + self.zero_range
            + self.unknown_barcode
            + self.own_barcode
            + self.outside_span
    }
}

impl std::fmt::Display for MrclamSkips {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} non-finite odometry/measurement rows, {} non-finite ground-truth rows, {} zero-range \
             measurements, {} unknown barcodes (clutter), {} own-barcode measurements, {} \
             measurements outside the odometry span",
            self.non_finite,
            self.non_finite_groundtruth,
            self.zero_range,
            self.unknown_barcode,
            self.own_barcode,
            self.outside_span
        )
    }
}

/// Ground truth at one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MrclamTruth {
    /// Robot K's Vicon pose, interpolated at the frame time (`None` outside its record).
    pub robot: Option<Pose2>,
    /// The other robots' Vicon positions, one slot per entry of [`MrclamRun::target_robots`].
    pub targets: Vec<Option<[f64; 2]>>,
    /// For each target detection: the slot of the robot it came from, `None` = unknown barcode.
    pub target_obs_source: Vec<Option<usize>>,
}

/// One control step of robot K.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MrclamFrame {
    /// Frame index (0-based).
    pub k: u64,
    /// Time at the end of the step, seconds since the first frame (for an observing frame: the
    /// measurements' own stamp).
    pub t: f64,
    /// Step length, seconds.
    pub dt: f64,
    /// Odometry (v [m/s], ω [rad/s]) applied over the step.
    pub odometry: (f64, f64),
    /// True when the step ends at a measurement stamp (its detections are attached).
    pub observe: bool,
    /// Landmark detections (landmark id, [range, bearing]).
    pub landmark_obs: Vec<(LandmarkId, [f64; 2])>,
    /// Detections of other robots (and unknown barcodes), barcode removed.
    pub target_obs: Vec<[f64; 2]>,
    /// Ground truth.
    pub truth: MrclamTruth,
}

/// One robot's run prepared for SLAMOT.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MrclamRun {
    /// The robot that drives (1..=5).
    pub robot: u32,
    /// Subject numbers of the target robots, in slot order.
    pub target_robots: Vec<u32>,
    /// Absolute time of frame time 0, seconds.
    pub t0: f64,
    /// Robot K's true pose at the start (the filter's map frame is anchored to it).
    pub initial_pose: Pose2,
    /// The frames.
    pub frames: Vec<MrclamFrame>,
    /// True landmark positions (landmark id, [x, y]); ids are subject − 6.
    pub landmarks: Vec<(LandmarkId, [f64; 2])>,
    /// What was skipped.
    pub skips: MrclamSkips,
}

/// The file contents of one dataset (for [`from_texts`]; [`load`] reads them from disk).
#[derive(Debug, Clone)]
pub struct MrclamTexts<'a> {
    /// `Barcodes.dat`.
    pub barcodes: &'a str,
    /// `Landmark_Groundtruth.dat`.
    pub landmarks: &'a str,
    /// `RobotK_Odometry.dat` of the driving robot.
    pub odometry: &'a str,
    /// `RobotK_Measurement.dat` of the driving robot.
    pub measurements: &'a str,
    /// `RobotN_Groundtruth.dat` of every robot N (K included), with N.
    pub groundtruth: Vec<(u32, &'a str)>,
}

/// Parses a whitespace-separated numeric table with `#` comment lines. Every data line must
/// have exactly `cols` fields; blank lines are ignored.
pub fn parse_table(
    text: &str,
    path: &str,
    cols: usize,
) -> Result<Vec<(usize, Vec<f64>)>, DataError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != cols {
            return Err(DataError::Parse {
                path: path.to_string(),
                line: i + 1,
                reason: format!(
                    "expected {cols} columns, found {} (truncated?)",
                    fields.len()
                ),
            });
        }
        let mut row = Vec::with_capacity(cols);
        for f in fields {
            let v: f64 = f.parse().map_err(|_| DataError::Parse {
                path: path.to_string(),
                line: i + 1,
                reason: format!("not a number: {f:?}"),
            })?;
            row.push(v);
        }
        out.push((i + 1, row));
    }
    Ok(out)
}

fn as_id(v: f64, path: &str, line: usize, what: &str) -> Result<u32, DataError> {
    if v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v < 1e6 {
        Ok(v as u32)
    } else {
        Err(DataError::Parse {
            path: path.to_string(),
            line,
            reason: format!("{what} must be a non-negative integer, found {v}"),
        })
    }
}

/// Checks that a time series (column 0) never goes backwards: a record earlier than the one
/// before it is an error naming the file and line (the recordings are time ordered; a shuffled
/// file would otherwise feed the filter a wrong history).
fn monotone(rows: Vec<(usize, Vec<f64>)>, path: &str) -> Result<Vec<Vec<f64>>, DataError> {
    let mut out: Vec<Vec<f64>> = Vec::with_capacity(rows.len());
    for (line, r) in rows {
        if let Some(prev) = out.last()
            && r[0] < prev[0]
        {
            return Err(DataError::Parse {
                path: path.to_string(),
                line,
                reason: format!(
                    "time {} is earlier than the previous record's {} (records out of time order)",
                    r[0], prev[0]
                ),
            });
        }
        out.push(r);
    }
    Ok(out)
}

/// Linear interpolation of a ground-truth series [t, x, y, θ] at time t (`None` outside).
fn interpolate(gt: &[Vec<f64>], t: f64) -> Option<Pose2> {
    let first = gt.first()?;
    let last = gt.last()?;
    if !(t >= first[0] && t <= last[0]) {
        return None;
    }
    let i = gt.partition_point(|r| r[0] <= t);
    if i == 0 {
        return Some(Pose2::new(first[1], first[2], wrap_angle(first[3])));
    }
    let a = &gt[i - 1];
    let Some(b) = gt.get(i) else {
        return Some(Pose2::new(a[1], a[2], wrap_angle(a[3])));
    };
    let span = b[0] - a[0];
    let s = if span > 0.0 { (t - a[0]) / span } else { 0.0 };
    Some(Pose2::new(
        a[1] + s * (b[1] - a[1]),
        a[2] + s * (b[2] - a[2]),
        wrap_angle(a[3] + s * wrap_angle(b[3] - a[3])),
    ))
}

/// When a measurement is handed to the filter.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum MeasurementTiming {
    /// At its own stamp: the odometry interval is cut there (default).
    #[default]
    OwnStamp,
    /// At the end of the odometry interval it falls in (up to one odometry period, ~15 ms,
    /// late: the behaviour before per-measurement timing, kept to measure its effect).
    NextOdometry,
}

/// Builds the run of robot `robot` from file contents (measurements at their own stamps).
pub fn from_texts(texts: &MrclamTexts<'_>, robot: u32) -> Result<MrclamRun, DataError> {
    from_texts_with(texts, robot, MeasurementTiming::OwnStamp)
}

/// [`from_texts`] with a choice of [`MeasurementTiming`].
pub fn from_texts_with(
    texts: &MrclamTexts<'_>,
    robot: u32,
    timing: MeasurementTiming,
) -> Result<MrclamRun, DataError> {
    let mut skips = MrclamSkips::default();
    // barcode -> subject
    let mut by_barcode: BTreeMap<u32, u32> = BTreeMap::new();
    for (line, r) in parse_table(texts.barcodes, "Barcodes.dat", 2)? {
        let subject = as_id(r[0], "Barcodes.dat", line, "subject")?;
        let code = as_id(r[1], "Barcodes.dat", line, "barcode")?;
        by_barcode.insert(code, subject);
    }
    let mut landmarks = Vec::new();
    for (line, r) in parse_table(texts.landmarks, "Landmark_Groundtruth.dat", 5)? {
        let subject = as_id(r[0], "Landmark_Groundtruth.dat", line, "subject")?;
        if subject < 6 || !r[1].is_finite() || !r[2].is_finite() {
            return Err(DataError::Parse {
                path: "Landmark_Groundtruth.dat".into(),
                line,
                reason: format!(
                    "landmark subject must be >= 6 with a finite position, got {subject}"
                ),
            });
        }
        landmarks.push((LandmarkId(subject - 6), [r[1], r[2]]));
    }
    let mut gts: BTreeMap<u32, Vec<Vec<f64>>> = BTreeMap::new();
    for (n, text) in &texts.groundtruth {
        let path = format!("Robot{n}_Groundtruth.dat");
        let rows = parse_table(text, &path, 4)?;
        let before = rows.len();
        let rows: Vec<_> = rows
            .into_iter()
            .filter(|(_, r)| r.iter().all(|v| v.is_finite()))
            .collect();
        skips.non_finite_groundtruth += before - rows.len();
        gts.insert(*n, monotone(rows, &path)?);
    }
    let own_gt = gts.get(&robot).ok_or_else(|| DataError::Io {
        path: format!("Robot{robot}_Groundtruth.dat"),
        reason: "ground truth of the driving robot is missing".into(),
    })?;
    let (gt_start, gt_end) = match (own_gt.first(), own_gt.last()) {
        (Some(a), Some(b)) => (a[0], b[0]),
        _ => {
            return Err(DataError::Io {
                path: format!("Robot{robot}_Groundtruth.dat"),
                reason: "no ground-truth records".into(),
            });
        }
    };
    let odo_path = format!("Robot{robot}_Odometry.dat");
    let odo_rows = parse_table(texts.odometry, &odo_path, 3)?;
    let mut odo_ok = Vec::with_capacity(odo_rows.len());
    for (l, r) in odo_rows {
        if r.iter().all(|v| v.is_finite()) {
            odo_ok.push((l, r));
        } else {
            skips.non_finite += 1;
        }
    }
    let odo: Vec<Vec<f64>> = monotone(odo_ok, &odo_path)?
        .into_iter()
        .filter(|r| r[0] >= gt_start && r[0] <= gt_end)
        .collect();
    if odo.len() < 2 {
        return Err(DataError::Io {
            path: odo_path,
            reason: "fewer than two odometry records inside the ground-truth span".into(),
        });
    }
    let meas_path = format!("Robot{robot}_Measurement.dat");
    let meas_rows = parse_table(texts.measurements, &meas_path, 4)?;
    let mut meas_ok = Vec::with_capacity(meas_rows.len());
    for (l, r) in meas_rows {
        as_id(r[1], &meas_path, l, "barcode")?;
        if !r.iter().all(|v| v.is_finite()) {
            skips.non_finite += 1;
        } else if r[2] < 0.0 {
            return Err(DataError::Parse {
                path: meas_path,
                line: l,
                reason: format!("negative range {}", r[2]),
            });
        } else if r[2] == 0.0 {
            skips.zero_range += 1;
        } else {
            meas_ok.push((l, r));
        }
    }
    let meas = monotone(meas_ok, &meas_path)?;

    let target_robots: Vec<u32> = gts.keys().copied().filter(|&n| n != robot).collect();
    let slot_of = |subject: u32| target_robots.iter().position(|&n| n == subject);
    let t0 = odo[0][0];
    let initial_pose = interpolate(own_gt, t0).ok_or_else(|| DataError::Io {
        path: format!("Robot{robot}_Groundtruth.dat"),
        reason: "no ground truth at the first odometry time".into(),
    })?;
    let mut frames: Vec<MrclamFrame> = Vec::with_capacity(odo.len() + meas.len());
    let mut mi = meas.partition_point(|m| m[0] <= t0);
    skips.outside_span += mi;
    let truth_at = |t: f64, source: Vec<Option<usize>>| MrclamTruth {
        robot: interpolate(own_gt, t),
        targets: target_robots
            .iter()
            .map(|n| {
                gts.get(n)
                    .and_then(|g| interpolate(g, t))
                    .map(|p| [p.x, p.y])
            })
            .collect(),
        target_obs_source: source,
    };
    for w in odo.windows(2) {
        let (ta, tb) = (w[0][0], w[1][0]);
        let odometry = (w[0][1], w[0][2]);
        // the interval [ta, tb] is cut at each distinct measurement stamp in (ta, tb]
        let mut t_prev = ta;
        while let Some(&[t_first, ..]) = meas.get(mi).map(Vec::as_slice) {
            if t_first > tb {
                break;
            }
            // the frame ends at the measurements' stamp, or (legacy) at the interval's end
            let tm = match timing {
                MeasurementTiming::OwnStamp => t_first,
                MeasurementTiming::NextOdometry => tb,
            };
            let mut landmark_obs = Vec::new();
            let mut target_obs = Vec::new();
            let mut source = Vec::new();
            while let Some(m) = meas.get(mi) {
                let same = match timing {
                    MeasurementTiming::OwnStamp => m[0] == tm,
                    MeasurementTiming::NextOdometry => m[0] <= tb,
                };
                if !same {
                    break;
                }
                mi += 1;
                let code = m[1] as u32;
                let z = [m[2], wrap_angle(m[3])];
                match by_barcode.get(&code) {
                    Some(&s) if s == robot => skips.own_barcode += 1,
                    Some(&s) if s >= 6 => landmark_obs.push((LandmarkId(s - 6), z)),
                    Some(&s) => {
                        target_obs.push(z);
                        source.push(slot_of(s));
                    }
                    None => {
                        skips.unknown_barcode += 1;
                        target_obs.push(z);
                        source.push(None);
                    }
                }
            }
            frames.push(MrclamFrame {
                k: frames.len() as u64,
                t: tm - t0,
                dt: tm - t_prev,
                odometry,
                observe: true,
                landmark_obs,
                target_obs,
                truth: truth_at(tm, source),
            });
            t_prev = tm;
        }
        if tb > t_prev {
            frames.push(MrclamFrame {
                k: frames.len() as u64,
                t: tb - t0,
                dt: tb - t_prev,
                odometry,
                observe: false,
                landmark_obs: Vec::new(),
                target_obs: Vec::new(),
                truth: truth_at(tb, Vec::new()),
            });
        }
    }
    skips.outside_span += meas.len() - mi;
    Ok(MrclamRun {
        robot,
        target_robots,
        t0,
        initial_pose,
        frames,
        landmarks,
        skips,
    })
}

fn read(dir: &Path, name: &str) -> Result<String, DataError> {
    let p = dir.join(name);
    let bytes = std::fs::read(&p).map_err(|e| DataError::Io {
        path: p.display().to_string(),
        reason: e.to_string(),
    })?;
    String::from_utf8(bytes).map_err(|e| DataError::Io {
        path: p.display().to_string(),
        reason: format!("not UTF-8 text: {e}"),
    })
}

/// Reads dataset directory `dir` (the 17 files of one MRCLAM dataset) for robot `robot` (1..=5),
/// measurements at their own stamps.
pub fn load(dir: &Path, robot: u32) -> Result<MrclamRun, DataError> {
    load_with(dir, robot, MeasurementTiming::OwnStamp)
}

/// [`load`] with a choice of [`MeasurementTiming`].
pub fn load_with(
    dir: &Path,
    robot: u32,
    timing: MeasurementTiming,
) -> Result<MrclamRun, DataError> {
    if !(1..=5).contains(&robot) {
        return Err(DataError::Core(quarry_core::CoreError::invalid(
            "robot",
            format!("MRCLAM robots are 1..=5, got {robot}"),
        )));
    }
    let barcodes = read(dir, "Barcodes.dat")?;
    let landmarks = read(dir, "Landmark_Groundtruth.dat")?;
    let odometry = read(dir, &format!("Robot{robot}_Odometry.dat"))?;
    let measurements = read(dir, &format!("Robot{robot}_Measurement.dat"))?;
    let mut gt_texts = Vec::new();
    for n in 1..=5_u32 {
        gt_texts.push((n, read(dir, &format!("Robot{n}_Groundtruth.dat"))?));
    }
    let texts = MrclamTexts {
        barcodes: &barcodes,
        landmarks: &landmarks,
        odometry: &odometry,
        measurements: &measurements,
        groundtruth: gt_texts.iter().map(|(n, s)| (*n, s.as_str())).collect(),
    };
    from_texts_with(&texts, robot, timing)
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: &str = "# a\r\n# b\r\n# c\r\n# d\r\n";

    fn texts_owned() -> Vec<String> {
        vec![
            format!("{H}1 5\r\n2 14\r\n3 41\r\n6 63\r\n7 81\r\n"),
            format!("{H}6 1.0 2.0 0 0\r\n7 3.0 4.0 0 0\r\n"),
            format!("{H}100.0 0.5 0.1\r\n100.1 0.5 0.1\r\n100.2 0.5 0.1\r\n100.3 0.5 0.1\r\n"),
            format!(
                "{H}99.0 63 1.0 0.0\r\n100.05 63 1.5 0.2\r\n100.05 14 2.0 -0.1\r\n100.15 41 3.0 4.0\r\n100.15 99 1.0 0.0\r\n100.25 5 1.0 0.0\r\n"
            ),
            format!("{H}99.9 0 0 3.1\r\n100.4 1 0 -3.1\r\n"),
            format!("{H}99.0 5 5 0\r\n101 6 5 0\r\n"),
            format!("{H}100.2 7 7 0\r\n101 8 7 0\r\n"),
        ]
    }

    fn run_of(t: &[String]) -> Result<MrclamRun, DataError> {
        from_texts(
            &MrclamTexts {
                barcodes: &t[0],
                landmarks: &t[1],
                odometry: &t[2],
                measurements: &t[3],
                groundtruth: vec![(1, &t[4]), (2, &t[5]), (3, &t[6])],
            },
            1,
        )
    }

    #[test]
    fn frames_barcodes_truth() {
        let run = run_of(&texts_owned()).unwrap();
        assert_eq!(run.target_robots, vec![2, 3]);
        // 3 odometry intervals, each cut at its measurement stamp (100.05, 100.15, 100.25)
        assert_eq!(run.frames.len(), 6);
        let ends: Vec<f64> = run.frames.iter().map(|f| f.t).collect();
        for (e, x) in ends.iter().zip([0.05, 0.1, 0.15, 0.2, 0.25, 0.3]) {
            assert!((e - x).abs() < 1e-9, "{ends:?}");
        }
        assert!(
            run.frames
                .iter()
                .all(|f| f.dt > 0.0 && (f.dt - 0.05).abs() < 1e-9)
        );
        assert!(
            run.frames
                .iter()
                .all(|f| (f.odometry.0 - 0.5).abs() < 1e-12)
        );
        let observing: Vec<bool> = run.frames.iter().map(|f| f.observe).collect();
        assert_eq!(observing, [true, false, true, false, true, false]);
        assert_eq!(
            run.frames.iter().map(|f| f.k).collect::<Vec<_>>(),
            (0..6).collect::<Vec<_>>()
        );
        let f0 = &run.frames[0];
        assert_eq!(f0.landmark_obs, vec![(LandmarkId(0), [1.5, 0.2])]);
        assert_eq!(f0.target_obs, vec![[2.0, -0.1]]);
        assert_eq!(f0.truth.target_obs_source, vec![Some(0)]);
        // robot 3's truth starts at 100.2: unknown at 100.15, known at 100.2
        assert_eq!(run.frames[2].truth.targets[1], None);
        assert_eq!(run.frames[3].truth.targets[1], Some([7.0, 7.0]));
        // bearing 4.0 wrapped; unknown barcode 99 is clutter
        let f2 = &run.frames[2];
        assert!((f2.target_obs[0][1] - (4.0 - 2.0 * std::f64::consts::PI)).abs() < 1e-12);
        assert_eq!(f2.truth.target_obs_source, vec![Some(1), None]);
        assert_eq!(run.skips.unknown_barcode, 1);
        assert_eq!(run.skips.own_barcode, 1);
        assert_eq!(run.skips.outside_span, 1);
        assert_eq!(run.skips.total(), 3);
        // heading interpolation across the ±π cut: 3.1 → −3.1 passes through π, not 0
        let p = run.frames[0].truth.robot.unwrap();
        assert!(p.theta.abs() > 3.0, "{p:?}");
        assert!((run.initial_pose.x - 0.2).abs() < 1e-9);
        // truth is taken at the measurement's own stamp (x = 0.2 + 2 * 0.05 at 100.05)
        assert!((p.x - 0.3).abs() < 1e-9, "{p:?}");
    }

    #[test]
    fn measurements_sharing_a_stamp_share_a_frame_and_end_it_at_their_time() {
        let mut t = texts_owned();
        t[3] = format!("{H}100.03 63 1.0 0.0\r\n100.03 81 2.0 0.0\r\n100.1 63 1.1 0.0\r\n");
        let run = run_of(&t).unwrap();
        let obs: Vec<&MrclamFrame> = run.frames.iter().filter(|f| f.observe).collect();
        assert_eq!(obs.len(), 2);
        assert_eq!(obs[0].landmark_obs.len(), 2);
        assert!((obs[0].t - 0.03).abs() < 1e-9 && (obs[0].dt - 0.03).abs() < 1e-9);
        // a measurement exactly at an odometry stamp closes that interval, no empty remainder
        assert!((obs[1].t - 0.1).abs() < 1e-9 && (obs[1].dt - 0.07).abs() < 1e-9);
        // the pieces of every interval add up to the odometry span
        let total: f64 = run.frames.iter().map(|f| f.dt).sum();
        assert!((total - 0.3).abs() < 1e-9, "{total}");
    }

    #[test]
    fn malformed_and_truncated_lines_are_parse_errors() {
        let mut t = texts_owned();
        t[2] = format!("{H}100.0 0.5 0.1\r\n100.1 0.5\r\n");
        match run_of(&t) {
            Err(DataError::Parse { line, path, .. }) => {
                assert_eq!(line, 6);
                assert!(path.contains("Odometry"));
            }
            other => panic!("{other:?}"),
        }
        let mut t = texts_owned();
        t[3] = format!("{H}100.05 6x3 1.5 0.2\r\n");
        assert!(matches!(run_of(&t), Err(DataError::Parse { line: 5, .. })));
        let mut t = texts_owned();
        t[3] = format!("{H}100.05 -3 1.5 0.2\r\n");
        assert!(matches!(run_of(&t), Err(DataError::Parse { line: 5, .. })));
    }

    #[test]
    fn legacy_timing_attaches_measurements_to_the_interval_end() {
        let t = texts_owned();
        let texts = MrclamTexts {
            barcodes: &t[0],
            landmarks: &t[1],
            odometry: &t[2],
            measurements: &t[3],
            groundtruth: vec![(1, &t[4]), (2, &t[5]), (3, &t[6])],
        };
        let run = from_texts_with(&texts, 1, MeasurementTiming::NextOdometry).unwrap();
        assert_eq!(run.frames.len(), 3);
        assert!(run.frames.iter().all(|f| f.observe));
        assert!((run.frames[0].t - 0.1).abs() < 1e-9);
        assert_eq!(run.frames[0].landmark_obs.len(), 1);
    }

    #[test]
    fn nan_and_zero_range_are_counted_skips() {
        let mut t = texts_owned();
        t[2] = format!("{H}100.0 0.5 0.1\r\n100.1 NaN 0.1\r\n100.2 0.5 0.1\r\n100.3 0.5 0.1\r\n");
        t[3] = format!(
            "{H}100.05 63 0.0 0.2\r\n100.06 63 nan 0.2\r\n100.07 63 1.0 inf\r\n100.08 63 1.0 0.1\r\n"
        );
        t[4] = format!("{H}99.9 0 0 3.1\r\n100.0 NaN 0 3.1\r\n100.4 1 0 -3.1\r\n");
        let run = run_of(&t).unwrap();
        assert_eq!(run.skips.non_finite, 3);
        assert_eq!(run.skips.zero_range, 1);
        assert_eq!(run.skips.non_finite_groundtruth, 1);
        assert!(run.skips.to_string().contains("1 zero-range"));
        assert_eq!(run.frames.iter().filter(|f| f.observe).count(), 1);
        assert!(
            run.frames
                .iter()
                .all(|f| f.odometry.0.is_finite() && f.dt > 0.0)
        );
    }

    #[test]
    fn records_out_of_time_order_are_errors_naming_file_and_line() {
        let mut t = texts_owned();
        t[2] = format!("{H}100.0 0.5 0.1\r\n100.1 0.5 0.1\r\n99.95 0.5 0.1\r\n100.2 0.5 0.1\r\n");
        let e = run_of(&t).unwrap_err();
        assert!(
            matches!(&e, DataError::Parse { path, line: 7, .. } if path == "Robot1_Odometry.dat"),
            "{e}"
        );
        assert!(e.to_string().contains("out of time order"), "{e}");
        let mut t = texts_owned();
        t[3] = format!("{H}100.15 63 1.0 0.0\r\n100.05 63 1.0 0.0\r\n");
        assert!(matches!(
            run_of(&t),
            Err(DataError::Parse { line: 6, ref path, .. }) if path == "Robot1_Measurement.dat"
        ));
        let mut t = texts_owned();
        t[5] = format!("{H}99.0 5 5 0\r\n98.0 6 5 0\r\n");
        assert!(matches!(
            run_of(&t),
            Err(DataError::Parse { line: 6, ref path, .. }) if path == "Robot2_Groundtruth.dat"
        ));
        // equal stamps are in order
        let mut t = texts_owned();
        t[3] = format!("{H}100.05 63 1.0 0.0\r\n100.05 63 1.0 0.0\r\n");
        assert!(run_of(&t).is_ok());
        // a negative range is malformed
        let mut t = texts_owned();
        t[3] = format!("{H}100.05 63 -1.0 0.0\r\n");
        assert!(matches!(run_of(&t), Err(DataError::Parse { line: 5, .. })));
    }

    #[test]
    fn empty_inputs_are_errors() {
        let mut t = texts_owned();
        t[2] = H.to_string();
        assert!(matches!(run_of(&t), Err(DataError::Io { .. })));
        let mut t = texts_owned();
        t[4] = H.to_string();
        assert!(matches!(run_of(&t), Err(DataError::Io { .. })));
    }

    #[test]
    fn real_dataset_if_present() {
        let dir = std::env::var("QUARRY_SHARED").map_or_else(
            |_| std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
            std::path::PathBuf::from,
        );
        let dir = dir.join("data/mrclam-6");
        if !dir.join("Barcodes.dat").exists() {
            eprintln!("skipping: {} not found", dir.display());
            return;
        }
        let run = load(&dir, 1).unwrap();
        assert_eq!(run.landmarks.len(), 15);
        assert_eq!(run.target_robots, vec![2, 3, 4, 5]);
        let n_lm: usize = run.frames.iter().map(|f| f.landmark_obs.len()).sum();
        let n_tg: usize = run.frames.iter().map(|f| f.target_obs.len()).sum();
        // PROVENANCE: robot 1 has 1942 measurements, 407 of other robots (some outside the span)
        assert!(n_lm + n_tg > 1700 && n_lm + n_tg <= 1942, "{n_lm} {n_tg}");
        // measurements agree with ground truth to a few cm (landmarks)
        let mut errs = Vec::new();
        for f in &run.frames {
            let Some(p) = f.truth.robot else { continue };
            for (id, z) in &f.landmark_obs {
                let lm = run.landmarks.iter().find(|(i, _)| i == id).unwrap().1;
                let r = (lm[0] - p.x).hypot(lm[1] - p.y);
                errs.push((z[0] - r).abs());
            }
        }
        errs.sort_by(f64::total_cmp);
        let med = errs[errs.len() / 2];
        assert!(med < 0.15, "median landmark range error {med}");
        assert!(load(&dir, 9).is_err());
    }
}
