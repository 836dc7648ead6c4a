//! Tracker bindings (quarry-trackers): the video tracker of spec 004 on a frame array and the
//! laser people tracker of spec 003 on recorded scans, each returning its tracks as rows.
//!
//! The configuration is a named preset of the tracker, optionally overlaid with TOML text (the
//! same keys as the CLI's `--config` files).

use crate::args::{self, Values, data, map_err, value_error};
use crate::assoc::rows_to_py;
use numpy::{PyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;
use quarry_core::{MultiTargetTracker, Plane, ScanGeometry, Stamp};
use quarry_trackers::lidar_people::{LidarPeopleConfig, run_recorded};
use quarry_trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use quarry_trackers::{PresetName, TrackerConfig};

/// A tracker configuration from a preset name and optional TOML laid over it.
fn config<C: TrackerConfig>(preset: &str, config_toml: Option<&str>) -> PyResult<C> {
    let p = C::Preset::parse(preset).map_err(|e| value_error("preset", e))?;
    if let Some(text) = config_toml {
        C::from_toml(text, Some(p)).map_err(|e| value_error("config_toml", e))
    } else {
        let c = C::preset(p);
        c.validate().map_err(|e| value_error("preset", e))?;
        Ok(c)
    }
}

/// Runs the video tracker over frames `next(k)` (`None` = end), as MOTChallenge rows.
fn run_video(
    cfg: WatershedSiftConfig,
    mut next: impl FnMut(usize) -> Option<Result<Plane<u8>, String>>,
) -> Result<Vec<f64>, String> {
    let mut tracker = WatershedSiftTracker::new(cfg).map_err(|e| e.to_string())?;
    let mut rows = Vec::new();
    let mut size = None;
    let mut k = 0;
    while let Some(frame) = next(k) {
        let frame = frame?;
        if *size.get_or_insert(frame.dimensions()) != frame.dimensions() {
            return Err(format!(
                "frame {} is {}x{}, the first frame {:?}: every frame must have the same size",
                k + 1,
                frame.width,
                frame.height,
                size
            ));
        }
        let reports = tracker
            .step(Stamp::from_frame(k as u64, 1.0), &frame)
            .map_err(|e| format!("frame {}: {e}", k + 1))?;
        for r in reports {
            let Some(bb) = r.bbox else { continue };
            let [l, tp, bw, bh] = bb.to_ltwh();
            #[allow(clippy::cast_precision_loss)]
            rows.extend_from_slice(&[(k + 1) as f64, f64::from(r.id.0), l + 1.0, tp + 1.0, bw, bh]);
        }
        k += 1;
    }
    Ok(rows)
}

/// Runs the automatic multi-object video tracker (spec 004: watershed segmentation, region
/// mapping, moving points, weighted SIFT pools) on a grey sequence.
///
/// `frames`: a `(T, H, W)` uint8 array, or a directory of PNG / JPEG frames (a MOTChallenge
/// `img1/`: files sorted by name, colour converted to grey with BT.601 as `quarry video` does).
/// `preset` `"paper"` or `"robust"`; `person_size` `(w, h)` pixels of a typical person (sets the
/// box, the blur and the near distance, as the CLI's `--person-size`); `config_toml` TOML
/// overlaid on the preset. Returns the tracks as float64 rows `frame, id, left, top, width,
/// height` in the MOTChallenge convention (frames and pixels 1-based, as `quarry video` writes
/// them), ready for `mot_metrics`.
#[pyfunction]
#[pyo3(signature = (frames, preset = "robust", person_size = None, config_toml = None))]
pub fn track_video<'py>(
    py: Python<'py>,
    frames: &Bound<'py, PyAny>,
    preset: &str,
    person_size: Option<(f64, f64)>,
    config_toml: Option<&str>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let mut cfg: WatershedSiftConfig = config::<WatershedSiftConfig>(preset, config_toml)?;
    if let Some((pw, ph)) = person_size {
        if !(pw.is_finite() && ph.is_finite() && pw > 0.0 && ph > 0.0) {
            return Err(value_error(
                "person_size",
                format!("({pw}, {ph}) must be positive"),
            ));
        }
        cfg = cfg.with_person_size(pw, ph);
        cfg.validate().map_err(|e| value_error("person_size", e))?;
    }
    let is_array = frames.cast::<numpy::PyUntypedArray>().is_ok();
    let rows = match frames.extract::<std::path::PathBuf>() {
        Ok(dir) if !is_array => {
            let files = quarry_data::image_sequence::list_frames(&dir)
                .map_err(|e| value_error("frames", e))?;
            py.detach(|| {
                run_video(cfg, |k| {
                    files.get(k).map(|f| {
                        quarry_vision::io::load_gray(f).map_err(|e| format!("{}: {e}", f.display()))
                    })
                })
            })
        }
        _ => {
            let a = args::array::<u8>(
                frames,
                "frames",
                "(T, H, W)",
                &[None, None, None],
                false,
                Values::Finite,
            )?;
            let (h, w) = (a.shape()[1], a.shape()[2]);
            let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
                return Err(value_error("frames", "frames are too large"));
            };
            let pix = data(&a);
            py.detach(|| {
                run_video(cfg, |k| {
                    pix.chunks_exact(w * h).nth(k).map(|f| {
                        Ok(Plane {
                            width: w32,
                            height: h32,
                            data: f.to_vec(),
                        })
                    })
                })
            })
        }
    }
    .map_err(map_err("track_video"))?;
    let n = rows.len() / 6;
    rows_to_py(py, rows, n, 6)
}

/// Runs the laser people tracker of spec 003 (chi-square background, MeanShift, ICP ellipse
/// contours, Table 1 tracking) on the recorded scans of one scanner placed at `pose` in the
/// world.
///
/// `scans` `(T, n_beams)` float64 ranges in metres (0 or out of range = no return), `stamps`
/// `(T,)` seconds; the beam geometry (`angle_min`, `angle_increment` in radians, ranges in
/// metres, `scan_period` seconds). `preset` `"faithful"`, `"literal"`, `"kf-gnn"` or `"jipda"`;
/// `config_toml` TOML overlaid on it. The first `window_m / 2` scans fill the background window
/// and carry no tracks. `backfill` (offline; `kf-gnn` and `jipda`): a track is also reported at
/// the earlier scans where it was detected but held back (tentative, or not yet walked
/// `leg_min_travel_m`), once it is reported. Returns float64 rows `scan, t, id, x, y, vx, vy,
/// alpha, rms` (scan = 0-based index, world metres).
#[pyfunction]
#[pyo3(signature = (scans, stamps, angle_min, angle_increment, range_min = 0.1, range_max = 30.0, scan_period = 0.025, pose = (0.0, 0.0, 0.0), preset = "faithful", config_toml = None, gap_factor = 3.0, backfill = false))]
#[allow(clippy::too_many_arguments)]
pub fn track_lidar<'py>(
    py: Python<'py>,
    scans: &Bound<'py, PyAny>,
    stamps: &Bound<'py, PyAny>,
    angle_min: f64,
    angle_increment: f64,
    range_min: f64,
    range_max: f64,
    scan_period: f64,
    pose: (f64, f64, f64),
    preset: &str,
    config_toml: Option<&str>,
    gap_factor: f64,
    backfill: bool,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let s = args::array::<f64>(
        scans,
        "scans",
        "(T, n_beams)",
        &[None, None],
        false,
        Values::Finite,
    )?;
    let (t, nb) = (s.shape()[0], s.shape()[1]);
    let st = args::array::<f64>(
        stamps,
        "stamps",
        &format!("({t},)"),
        &[Some(t)],
        false,
        Values::Finite,
    )?;
    let n_beams = u32::try_from(nb).map_err(|_| value_error("scans", "too many beams"))?;
    let geometry = ScanGeometry {
        n_beams,
        angle_min,
        angle_increment,
        range_min,
        range_max,
        scan_period,
    };
    let cfg: LidarPeopleConfig = config::<LidarPeopleConfig>(preset, config_toml)?;
    let pose = args::pose("pose", pose)?;
    let mut polar = Vec::with_capacity(t);
    for (k, (ranges, &ts)) in data(&s).chunks_exact(nb).zip(data(&st)).enumerate() {
        let seq = u32::try_from(k).unwrap_or(u32::MAX);
        if ts.abs() > crate::cloud::MAX_STAMP_S {
            return Err(value_error(
                "stamps",
                format!("scan {k}: {ts} s is beyond ±1e12 s"),
            ));
        }
        polar.push(crate::cloud::polar_scan(ranges, ts, seq, geometry)?);
    }
    let mut run = py
        .detach(|| run_recorded(&cfg, &geometry, pose, &polar, gap_factor))
        .map_err(map_err("track_lidar"))?;
    if backfill {
        run.backfill();
    }
    // processed scans map back to their input index through their (strictly increasing) stamps
    let mut index = std::collections::HashMap::new();
    for (k, sc) in polar.iter().enumerate() {
        index.entry(sc.t.0).or_insert(k);
    }
    let mut rows = Vec::new();
    for f in &run.frames {
        let k = index.get(&f.t.0).copied().unwrap_or(usize::MAX);
        for tr in &f.tracks {
            #[allow(clippy::cast_precision_loss)]
            rows.extend_from_slice(&[
                k as f64,
                f.t.0 as f64 * 1e-6,
                f64::from(tr.id),
                tr.x,
                tr.y,
                tr.vx,
                tr.vy,
                tr.alpha,
                tr.rms,
            ]);
        }
    }
    let n = rows.len() / 9;
    rows_to_py(py, rows, n, 9)
}

/// Runs the RGB-D person tracker of spec 001 (patch multi-cue appearance model, ego-motion
/// EKF, occlusion handling) on a sequence from an initial box, for a static camera.
///
/// `rgb` `(T, H, W, 3)` uint8, `depth` `(T, H, W)` float32 metres registered to the colour image
/// (0 or NaN = no depth), `init_box` `(left, top, width, height)` of the person in frame 0
/// (pixels, 0-based). `preset` `"paper"`, `"strict"`, `"baseline"`, `"no-depth-kernel"`,
/// `"single-patch"` ...; `config_toml` TOML overlaid on it (the camera is its `[intrinsics]`
/// table, Kinect v1 640×480 by default); `fps` the frame rate. Returns one float64 row per
/// frame: `frame (1-based), left, top, width, height, state` where the box is NaN when the
/// target is lost and `state` is 0 normal, 1 appearance change, 2 partial, 3 severe, 4 full
/// occlusion, 5 lost.
#[pyfunction]
#[pyo3(signature = (rgb, depth, init_box, preset = "paper", config_toml = None, fps = 30.0))]
pub fn track_rgbd<'py>(
    py: Python<'py>,
    rgb: &Bound<'py, PyAny>,
    depth: &Bound<'py, PyAny>,
    init_box: (f64, f64, f64, f64),
    preset: &str,
    config_toml: Option<&str>,
    fps: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    use quarry_core::{BBox, EgoMotion, SingleTargetTracker};
    use quarry_trackers::rgbd_person::{OcclusionState, RgbdPersonConfig, RgbdPersonTracker};
    use quarry_vision::RgbdFrame;
    let c = args::array::<u8>(
        rgb,
        "rgb",
        "(T, H, W, 3)",
        &[None, None, None, Some(3)],
        false,
        Values::Finite,
    )?;
    let (t, h, w) = (c.shape()[0], c.shape()[1], c.shape()[2]);
    let shape = format!("({t}, {h}, {w})");
    let d = args::array::<f32>(
        depth,
        "depth",
        &shape,
        &[Some(t), Some(h), Some(w)],
        false,
        Values::FiniteOrNan,
    )?;
    let (l, tp, bw, bh) = init_box;
    for v in [l, tp, bw, bh] {
        args::finite("init_box", v)?;
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(value_error("fps", format!("{fps} must be positive")));
    }
    let (Ok(w32), Ok(h32)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(value_error("rgb", "frames are too large"));
    };
    let cfg: RgbdPersonConfig = config::<RgbdPersonConfig>(preset, config_toml)?;
    let (cs, ds) = (data(&c), data(&d));
    let rows = py
        .detach(|| -> Result<Vec<f64>, String> {
            let mut tracker = RgbdPersonTracker::new(cfg).map_err(|e| e.to_string())?;
            let mut rows = Vec::with_capacity(t * 6);
            for k in 0..t {
                let depth_m = Plane {
                    width: w32,
                    height: h32,
                    data: ds[k * w * h..(k + 1) * w * h].to_vec(),
                };
                let rgb = cs[k * w * h * 3..(k + 1) * w * h * 3].to_vec();
                let frame = RgbdFrame::new(w32, h32, rgb, depth_m, EgoMotion::None)
                    .map_err(|e| format!("frame {}: {e}", k + 1))?;
                let stamp = Stamp::from_frame(k as u64, 1.0 / fps);
                #[allow(clippy::cast_precision_loss)]
                let n = (k + 1) as f64;
                if k == 0 {
                    let b = BBox::from_ltwh(l, tp, bw, bh);
                    tracker
                        .init(stamp, &frame, b)
                        .map_err(|e| format!("init_box: {e}"))?;
                    rows.extend_from_slice(&[n, l, tp, bw, bh, 0.0]);
                    continue;
                }
                let out = tracker
                    .step(stamp, &frame)
                    .map_err(|e| format!("frame {}: {e}", k + 1))?;
                let state = match out.state {
                    OcclusionState::Normal => 0.0,
                    OcclusionState::AppearanceChange => 1.0,
                    OcclusionState::PartialOcclusion => 2.0,
                    OcclusionState::SevereOcclusion => 3.0,
                    OcclusionState::FullOcclusion => 4.0,
                    OcclusionState::Lost => 5.0,
                };
                let [bl, bt, bw2, bh2] = out.bbox.map_or([f64::NAN; 4], |b| b.to_ltwh());
                rows.extend_from_slice(&[n, bl, bt, bw2, bh2, state]);
            }
            Ok(rows)
        })
        .map_err(map_err("track_rgbd"))?;
    rows_to_py(py, rows, t, 6)
}

/// Runs the RBPF SLAM + JIPDA multi-target tracker of spec 000 on one robot of a UTIAS MRCLAM
/// dataset directory (the robot maps the barcoded landmarks and tracks the other robots) and
/// scores it against the Vicon ground truth — the narrow entry point of `quarry slamot --mrclam`
/// (`quarry_repro::slamot::run_mrclam` with the `mrclam` preset).
///
/// `directory` holds `Barcodes.dat`, `Landmark_Groundtruth.dat` and `Robot{k}_*.dat`; `robot`
/// 1..=5; `particles` and `seed` as the CLI's; `max_frames` keeps only the first frames (None =
/// the whole run). Returns a dict: `tracks` rows `t, id, x, y, vx, vy, existence` (confirmed
/// targets at each scored epoch), `robot_est` / `robot_true` `(E, 3)` poses, `epoch_t`, `map`
/// rows `landmark id, x, y`, and the scores `ospa`, `gospa` (p = 2, c = 1 m), `map_err`,
/// `assoc_accuracy`, `ate` (aligned trajectory RMSE), `ms_per_step`. With `smooth = "plain"`
/// or `"calibrated"` the run is also refined by the batch smoother
/// (`quarry_repro::slamot::smooth_mrclam`, as `quarry slamot --smooth`) and the dict gains
/// `smoothed_est` `(E, 3)`, `smoothed_map` rows, `smoothed_robot_err`, `smoothed_map_err`,
/// `smoothed_ate` and `calibration` (speed scale, turn-rate scale, turn-rate bias, time offset).
#[pyfunction]
#[pyo3(signature = (directory, robot = 1, particles = 50, seed = 0, max_frames = None, smooth = None))]
#[allow(clippy::needless_pass_by_value)] // pyo3 extracts an owned path and string
pub fn track_mrclam(
    py: Python<'_>,
    directory: std::path::PathBuf,
    robot: u32,
    particles: usize,
    seed: u64,
    max_frames: Option<usize>,
    smooth: Option<String>,
) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    use pyo3::types::PyDict;
    if particles == 0 {
        return Err(value_error("particles", "must be at least 1"));
    }
    let calibrate = match smooth.as_deref() {
        None => None,
        Some("plain") => Some(false),
        Some("calibrated") => Some(true),
        Some(other) => {
            return Err(value_error(
                "smooth",
                format!("{other:?} (expected None, \"plain\" or \"calibrated\")"),
            ));
        }
    };
    type Out = (
        quarry_repro::slamot::MrclamResult,
        Option<quarry_repro::slamot::MrclamSmoothed>,
    );
    let (res, sm) = py
        .detach(|| -> Result<Out, String> {
            let mut run =
                quarry_data::mrclam::load(&directory, robot).map_err(|e| e.to_string())?;
            if let Some(n) = max_frames {
                run.frames.truncate(n);
            }
            let cfg = quarry_repro::slamot::mrclam_config(particles);
            let res =
                quarry_repro::slamot::run_mrclam(&cfg, &run, seed).map_err(|e| e.to_string())?;
            let sm = calibrate
                .map(|c| quarry_repro::slamot::smooth_mrclam(&cfg, &run, &res, c))
                .transpose()
                .map_err(|e| e.to_string())?;
            Ok((res, sm))
        })
        .map_err(map_err("track_mrclam"))?;
    let out = PyDict::new(py);
    let tracks: Vec<f64> = res
        .tracks
        .iter()
        .flat_map(|r| {
            [
                r.t,
                f64::from(r.id.0),
                r.state[0],
                r.state[1],
                r.state[2],
                r.state[3],
                r.existence,
            ]
        })
        .collect();
    out.set_item("tracks", rows_to_py(py, tracks, res.tracks.len(), 7)?)?;
    let poses = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    out.set_item(
        "robot_est",
        rows_to_py(py, poses(&res.robot_est), res.robot_est.len(), 3)?,
    )?;
    out.set_item(
        "robot_true",
        rows_to_py(py, poses(&res.robot_true), res.robot_true.len(), 3)?,
    )?;
    out.set_item("epoch_t", numpy::PyArray1::from_slice(py, &res.epoch_t))?;
    let map: Vec<f64> = res
        .map
        .iter()
        .flat_map(|(id, p)| [f64::from(id.0), p[0], p[1]])
        .collect();
    out.set_item("map", rows_to_py(py, map, res.map.len(), 3)?)?;
    out.set_item("ospa", res.ospa)?;
    out.set_item("gospa", res.gospa)?;
    out.set_item("map_err", res.map_err)?;
    out.set_item("assoc_accuracy", res.assoc_accuracy)?;
    out.set_item("ate", res.trajectory.ate_rmse_aligned)?;
    out.set_item("ms_per_step", res.ms_per_step)?;
    if let Some(sm) = sm {
        out.set_item(
            "smoothed_est",
            rows_to_py(py, poses(&sm.robot_est), sm.robot_est.len(), 3)?,
        )?;
        let map: Vec<f64> = sm
            .map
            .iter()
            .flat_map(|(id, p)| [f64::from(id.0), p[0], p[1]])
            .collect();
        out.set_item("smoothed_map", rows_to_py(py, map, sm.map.len(), 3)?)?;
        out.set_item("smoothed_robot_err", sm.trajectory.mean)?;
        out.set_item("smoothed_map_err", sm.map_err)?;
        out.set_item("smoothed_ate", sm.trajectory.ate_rmse_aligned)?;
        out.set_item("calibration", sm.calibration.to_vec())?;
    }
    Ok(out)
}

/// Registers the tracker functions.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(track_video, m)?)?;
    m.add_function(wrap_pyfunction!(track_lidar, m)?)?;
    m.add_function(wrap_pyfunction!(track_rgbd, m)?)?;
    m.add_function(wrap_pyfunction!(track_mrclam, m)?)?;
    Ok(())
}
