//! `quarry lidar`: people tracking with distributed 2-D laser scanners (spec 003).
//!
//! Default: the simulated room of spec §5 (three UTM-30LX at 1.2 m, three people in one speed
//! band), tracked by the chosen preset, scored with the paper's success rate and the standard
//! MOT metrics.

use crate::config_args::ConfigArgs;
use crate::output::{CmdError, CmdResult, Output, at};
use crate::progress;
use crate::record::{self, Mcap, McapInfo};
use clap::Args;
use plotters::prelude::*;
use quarry_core::{Point2, Pose2, TimeUs};
use quarry_data::leg_labels::{LabelledScan, parse_leg_scans_csv};
use quarry_data::scans_csv::{RowPolicy, ScanCsvOptions, parse_scan_meta, read_scans};
use quarry_repro::lidar::{
    self as repro, EvalFrame, LabelGroupScore, LabelledError, Paper003Metrics, RoomRun,
    score_label_groups, score_labelled,
};
use quarry_ros2::msgs::Track;
use quarry_sim::lidar_room::{
    ClockProfile, GtWriter, NetworkModel, Obstacle, Room, ScannerSim, Scenario, SpeedBand,
};
use quarry_trackers::PresetName;
use quarry_trackers::lidar_people::{self, LidarPeopleConfig, LidarTrack, Preset};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The most walkers `--people` may put in the 10 x 8 m room (a billion used to abort on a failed
/// allocation; 100 people is already a crowd of 1.25 per square metre).
pub(crate) const MAX_PEOPLE: u32 = 100;

/// The most evaluated frames `--frames` may ask for: 1 000 000 frames of 50 ms, about 14
/// simulated hours (the run keeps every frame's tracks; a billion frames would not fit in memory).
pub(crate) const MAX_FRAMES: usize = 1_000_000;

/// `--frames` in 1..=[`MAX_FRAMES`].
pub(crate) fn check_frames(frames: usize) -> Result<(), CmdError> {
    if frames == 0 || frames > MAX_FRAMES {
        return Err(format!(
            "--frames {frames}: must be in 1..={MAX_FRAMES} (50 ms each; {MAX_FRAMES} frames are about 14 simulated hours)"
        )
        .into());
    }
    Ok(())
}

/// Arguments of `quarry lidar`.
#[derive(Args, Debug)]
#[command(
    about = "People tracking with distributed 2-D laser scanners (paper 003)",
    long_about = "People tracking with three fixed 2-D laser scanners (paper 003): chi-square \
background subtraction per scanner, fusion into 50 ms frames, MeanShift, ICP fit of an elliptical \
torso contour, and the paper's Table 1 tracker (presets literal, faithful), a KF-GNN baseline \
(kf-gnn) or JIPDA with track existence (jipda: soft association, coasting through occlusions).

By default it runs the simulated 10 x 8 m room (three UTM-30LX at 1.2 m, --people walkers in \
one --band) and scores the evaluated frames (from t = 7 s) with the paper's success rate, the \
localisation error and MOTA/MOTP/IDF1/HOTA (0.5 m).

Outputs (--out DIR): tracks.csv (frame,t_us,track_id,x,y,alpha,vx,vy,support,rms,born,\
gate_replaced), tracks_mot.txt (MOTChallenge rows frame,id,-1,-1,-1,-1,1,x,y,0 with world x, y \
in metres), gt_people.csv (simulation), metrics.json and plot.png (room, scanners, background, \
GT in grey, tracks in colour; with --scans: the last scan, the --legs labels in grey and every \
track's trajectory); with --scans also track_counts.png (how many scans after the warm-up had \
0, 1, 2, ... tracks).

Recorded scans of one scanner at leg height: --scans F.csv --detector legs (leg clusters paired \
into people, fed to the kf-gnn or jipda tracker), e.g. \
quarry lidar --scans positive_1_scans.csv --legs positive_1_legs.csv --detector legs --out out/ \
(--legs scores the tracks against labelled legs: per scan, and per person when a scan's labels \
hold two walkers)

JSON (--json): success_rate, success_rate_detectable, loc_error_m, loc_rmse_m, mota, motp, \
idf1, hota, idsw, frames, ms_per_frame, client_ms_per_scan, metrics (every measure), and with \
--calibration icp: calibration (per scanner: rough, calibrated and true pose, errors, overlap, RMS), \
interrupted.

Ctrl-C (or SIGTERM) during a simulated run stops it at the next frame: the outputs and the \
metrics cover the frames tracked so far, the summary says interrupted, the exit status is 130. \
A second Ctrl-C stops at once.

--scenario NAME runs one of the simulator's named scenarios instead (spec §5: empty, \
single_line, crossing, side_by_side, door, stop_and_go, band_*, crowd_<n>) for its own duration, \
scoring up to --frames frames from t = 7 s.

EXAMPLE:
  quarry lidar --band fast --frames 4800 --seed 1 --out run_fast
  quarry lidar --scenario door --frames 1640 --preset kf-gnn
  quarry lidar --preset kf-gnn --json
  quarry lidar --band fast --frames 4800 --preset jipda
  quarry lidar --calibration icp --seed 3"
)]
pub struct LidarArgs {
    /// Walking-speed band: slow (0.10-0.25 m/s), normal (0.75-1.00), fast (1.30-1.50).
    #[arg(long, default_value = "normal")]
    pub band: String,
    /// A named simulator scenario instead of the band protocol: empty, single_line, crossing,
    /// side_by_side, door, stop_and_go, band_slow, band_mid, band_fast or crowd_<n> (spec §5).
    /// It runs for the scenario's own duration (door 90 s, most others 60 s, band_* 250 s) and
    /// scores up to --frames frames from t = 7 s; --band and --people are then ignored.
    #[arg(long, value_name = "NAME")]
    pub scenario: Option<String>,
    /// Evaluated frames (50 ms each) after the 7 s warm-up; the paper's protocol uses 4800
    /// (at most 1 000 000).
    #[arg(long, default_value_t = 1200)]
    pub frames: usize,
    /// People in the room (at most 100).
    #[arg(long, default_value_t = 3)]
    pub people: u32,
    /// Seed (evaluation seeds are 1-5, tuning seeds 101-105).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// --preset (literal, faithful = default, kf-gnn, jipda) and --config FILE.toml over it.
    #[command(flatten)]
    pub cfg: ConfigArgs<Preset>,
    /// Output directory (tracks.csv, tracks_mot.txt, gt_people.csv, plot.png, metrics.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated network: ideal, wifi (default) or bad.
    #[arg(long)]
    pub network: Option<String>,
    /// Simulated clocks: synced (default), skewed, skewed_broadcast or skewed_nosync.
    #[arg(long)]
    pub clock: Option<String>,
    /// Scanner poses: given (the configured/true poses, default) or icp (calibrated from the
    /// clients' backgrounds at the end of the warm-up, from rough poses drawn per seed up to
    /// 0.3 m / 10°; prints the recovered poses and their errors).
    #[arg(long)]
    pub calibration: Option<String>,
    /// Recorded scans of one scanner (CSV `stamp_s,r0..r{N-1}`, metres, inf/nan = no return)
    /// instead of the simulated room.
    #[arg(long)]
    pub scans: Option<PathBuf>,
    /// Scanner geometry for --scans: a scan_meta.json (default: scan_meta.json beside the CSV).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Entry of --meta (default: the CSV's file stem without `_scans`).
    #[arg(long)]
    pub meta_key: Option<String>,
    /// Labelled leg centroids for --scans (`stamp_s,leg_index,x_m,y_m,frame_id`): prints the
    /// person position error (RMSE, nearest track within d_match) twice: with the person at
    /// the mean of every leg labelled in a scan (the recordings' definition), and per person,
    /// the scan's legs split into groups within leg_pair_dist (a second walker in the
    /// labelled wedge is a second person), with the most any tracker of people can match
    /// under the first definition.
    #[arg(long)]
    pub legs: Option<PathBuf>,
    /// With --scans: skip (and count) malformed rows and rows whose stamp goes backwards or
    /// repeats the previous row's (a duplicated row) instead of stopping at the first one.
    #[arg(long)]
    pub skip_bad_rows: bool,
    /// With --scans (offline): once a track is reported, also report it at the earlier scans
    /// where it was detected but held back (tentative, or not yet walked leg_min_travel_m),
    /// so a person who stood still before walking is tracked from their first detection.
    /// A live tracker cannot do this; clutter that never qualifies stays unreported.
    #[arg(long)]
    pub backfill: bool,
    /// Record the run as MCAP (ROS 2 messages, CDR): the scans (`/scan/...`, LaserScan), the
    /// tracks (`/tracks`, quarry_msgs/TrackArray; `/tracks/markers`, MarkerArray), the ground
    /// truth or labels, and the frames (`/tf_static`). Opens in Foxglove; docs/ros2.md.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Detections: contour (MeanShift + torso-ellipse ICP, the paper's; default) or legs (leg
    /// clusters paired into people, for one scanner at leg height; quarry_cloud::legs). legs
    /// runs the kf-gnn or jipda tracker: unless --preset or the --config file chose kf-gnn, it
    /// selects jipda; with --preset literal or faithful it is an error. Also the TOML
    /// key `detector`.
    #[arg(long, value_name = "contour|legs")]
    pub detector: Option<String>,
}

/// The JSON summary of a run.
#[derive(Debug, Clone, Serialize)]
pub struct LidarSummary {
    /// Preset.
    pub preset: String,
    /// Speed band (of the band protocol; the scenario's band for `--scenario`, `-` if none).
    pub band: String,
    /// Simulator scenario (`band_mid` etc. for the band protocol).
    pub scenario: String,
    /// Paper success rate (fraction).
    pub success_rate: f64,
    /// Success rate on detectable frames.
    pub success_rate_detectable: f64,
    /// Mean localisation error, metres.
    pub loc_error_m: f64,
    /// Localisation RMSE, metres.
    pub loc_rmse_m: f64,
    /// MOTA.
    pub mota: f64,
    /// MOTP (metres).
    pub motp: f64,
    /// IDF1.
    pub idf1: f64,
    /// HOTA.
    pub hota: f64,
    /// Identity switches.
    pub idsw: usize,
    /// Evaluated frames.
    pub frames: usize,
    /// Server time (fusion + tracking) per fused frame, ms.
    pub ms_per_frame: f64,
    /// Client background time per scan, ms.
    pub client_ms_per_scan: f64,
    /// Every §4 measure.
    pub metrics: Paper003Metrics,
    /// With `--calibration icp`: the recovered poses and their errors against the truth.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<lidar_people::CalibrationReport>,
    /// Stopped by Ctrl-C / SIGTERM: the metrics cover the frames up to then (`frames`).
    pub interrupted: bool,
    /// With `--mcap`: the recording.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcap: Option<McapInfo>,
}

/// The TF frame of a simulated scanner (`scanner_<name>`, its name's non-identifier characters
/// as `_`).
fn scanner_frame(name: &str) -> String {
    let clean: String = name
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    format!("scanner_{clean}")
}

/// Lidar tracks as planar tracks for the recording.
pub(crate) fn planar(tracks: &[LidarTrack]) -> Vec<Track> {
    tracks
        .iter()
        .map(|r| record::planar_track(r.id, r.x, r.y, r.vx, r.vy))
        .collect()
}

/// Writes a simulated run's results into its recording (the scans are in already):
/// `/tf_static` (map → each scanner), `/tracks` and `/tracks/markers` per tracked frame, and
/// `/ground_truth/people` per ground-truth frame.
fn record_room(mut m: Mcap, sc: &Scenario, run: &RoomRun) -> Result<McapInfo, CmdError> {
    let children: Vec<(String, quarry_core::Pose2)> = sc
        .scanners
        .iter()
        .map(|s| (scanner_frame(&s.name), s.pose))
        .collect();
    m.write(
        "/tf_static",
        TimeUs(0),
        &record::static_tf(TimeUs(0), "map", &children),
    )?;
    for (_, t, rows) in &run.tracks {
        let p = planar(rows);
        m.write("/tracks", *t, &record::tracks_msg(*t, "map", &p))?;
        m.write(
            "/tracks/markers",
            *t,
            &record::markers_msg(*t, "map", &p, 1.2),
        )?;
    }
    for g in &run.gt {
        let p: Vec<Track> = g
            .people
            .iter()
            .map(|q| record::planar_track(q.id, q.x, q.y, 0.0, 0.0))
            .collect();
        m.write(
            "/ground_truth/people",
            g.t,
            &record::tracks_msg(g.t, "map", &p),
        )?;
    }
    m.finish()
}

/// Runs one simulated band and returns the summary (used by `quarry demo` too).
pub fn run_sim_band(
    band: SpeedBand,
    people: u32,
    frames: usize,
    seed: u64,
    cfg: &LidarPeopleConfig,
    out: &Output,
) -> Result<(LidarSummary, RoomRun, Vec<EvalFrame>, Scenario), CmdError> {
    run_sim_variant(band, people, frames, seed, cfg, out, None, None)
}

/// [`run_sim_band`] with an optional network model and clock profile (scenario defaults
/// otherwise: `wifi`, `synced`).
#[allow(clippy::too_many_arguments)]
pub fn run_sim_variant(
    band: SpeedBand,
    people: u32,
    frames: usize,
    seed: u64,
    cfg: &LidarPeopleConfig,
    out: &Output,
    network: Option<NetworkModel>,
    clock: Option<ClockProfile>,
) -> Result<(LidarSummary, RoomRun, Vec<EvalFrame>, Scenario), CmdError> {
    let sc = band_scenario(band, people, frames, seed, cfg);
    run_sim_scenario(sc, band.name(), frames, cfg, out, network, clock, None)
}

/// The band protocol's scenario: `people` walkers of `band`, long enough for the 7 s warm-up
/// and `frames` evaluated frames.
fn band_scenario(
    band: SpeedBand,
    people: u32,
    frames: usize,
    seed: u64,
    cfg: &LidarPeopleConfig,
) -> Scenario {
    let duration = 7.0 + frames as f64 * cfg.frame_period_s + 0.3;
    Scenario::band(band, people, seed).with_duration(duration)
}

/// Runs scenario `sc` (its own duration) and scores up to `frames` frames from t = 7 s;
/// `band` is the name reported in the summary. With `mcap`, every simulated scan is recorded on
/// `/scan/<scanner>` as it is captured.
#[allow(clippy::too_many_arguments)]
fn run_sim_scenario(
    mut sc: Scenario,
    band: &str,
    frames: usize,
    cfg: &LidarPeopleConfig,
    out: &Output,
    network: Option<NetworkModel>,
    clock: Option<ClockProfile>,
    mut mcap: Option<&mut Mcap>,
) -> Result<(LidarSummary, RoomRun, Vec<EvalFrame>, Scenario), CmdError> {
    if let Some(n) = network {
        sc = sc.with_network(n);
    }
    if let Some(c) = clock {
        sc = sc.with_clock(c);
    }
    let pb = if frames >= 400 {
        progress::bar(out, 1000, "lidar sim")
    } else {
        indicatif::ProgressBar::hidden()
    };
    let mut on_progress = |f: f64| pb.set_position((f * 1000.0) as u64);
    // Ctrl-C (with `crate::interrupt::install`, as `quarry lidar` does) ends the run at the
    // next frame; the summary then scores the frames up to it
    let names: Vec<String> = sc.scanners.iter().map(|s| scanner_frame(&s.name)).collect();
    let mut record_err: Option<CmdError> = None;
    let mut on_scan = |i: usize, scan: &quarry_core::PolarScan| {
        if let Some(m) = mcap.as_deref_mut()
            && record_err.is_none()
        {
            let msg = quarry_ros2::convert::laser_scan(scan, &names[i]);
            if let Err(e) = m.write(&format!("/scan/{}", names[i]), scan.t, &msg) {
                record_err = Some(e);
            }
        }
    };
    let run = repro::run_room_default_observed(
        sc.clone(),
        cfg,
        &mut on_progress,
        crate::interrupt::flag(),
        &mut on_scan,
    )?;
    pb.finish_and_clear();
    if let Some(e) = record_err {
        return Err(e);
    }
    let window = run.eval_window(TimeUs(7_000_000), frames);
    let m = repro::evaluate_paper003(
        &window,
        &lidar_people::gate_of(cfg),
        cfg.min_num_point,
        cfg.d_match,
    )?;
    let n_scans = run.gt.len() as f64 * 2.0 * sc.scanners.len() as f64;
    let summary = LidarSummary {
        preset: cfg.preset.name().into(),
        band: band.into(),
        scenario: sc.name.clone(),
        success_rate: m.success_rate(),
        success_rate_detectable: m.success_rate_detectable(),
        loc_error_m: m.loc.mean,
        loc_rmse_m: m.loc.rmse,
        mota: m.mota,
        motp: m.motp,
        idf1: m.idf1,
        hota: m.hota,
        idsw: m.idsw,
        frames: m.frames,
        ms_per_frame: 1e3 * run.server_seconds / run.frames_tracked.max(1) as f64,
        client_ms_per_scan: 1e3 * run.client_seconds / n_scans.max(1.0),
        metrics: m,
        calibration: run.calibration.clone(),
        interrupted: run.interrupted,
        mcap: None,
    };
    Ok((summary, run, window, sc))
}

/// Entry point of `quarry lidar`.
pub fn run(args: &LidarArgs, output: &Output) -> CmdResult {
    let mut cfg: LidarPeopleConfig = args.cfg.load()?;
    if let Some(c) = &args.calibration {
        cfg.calibration = lidar_people::Calibration::parse(c)?;
    }
    if let Some(d) = &args.detector {
        cfg.detector = lidar_people::Detector::parse(d)?;
        if cfg.detector == lidar_people::Detector::Legs
            && args.cfg.preset.is_none()
            && cfg.preset == Preset::Faithful
        {
            // neither the flag nor the config file chose a tracker that takes leg detections
            // (faithful is the default and refuses them): legs run the jipda preset, over the
            // config file if there is one
            let jipda = ConfigArgs {
                preset: Some(Preset::Jipda),
                config: args.cfg.config.clone(),
            };
            cfg = jipda.load()?;
            cfg.detector = lidar_people::Detector::Legs;
            if let Some(c) = &args.calibration {
                cfg.calibration = lidar_people::Calibration::parse(c)?;
            }
        }
    }
    // the flags change a validated configuration: check its cross-field rules again
    quarry_trackers::TrackerConfig::validate(&cfg)?;
    if let Some(scans) = &args.scans {
        if cfg.calibration == lidar_people::Calibration::Icp {
            return Err(
                "--calibration icp needs the simulated room (several scanners); --scans is one recorded scanner"
                    .into(),
            );
        }
        return run_recorded_cmd(args, scans, &cfg, output);
    }
    if args.backfill {
        return Err(
            "--backfill reworks a recorded run offline: it needs --scans (the simulated room reports as a live tracker)"
                .into(),
        );
    }
    check_frames(args.frames)?;
    crate::interrupt::install();
    if args.people > MAX_PEOPLE {
        return Err(format!(
            "--people {}: at most {MAX_PEOPLE} walkers fit the 10 x 8 m room",
            args.people
        )
        .into());
    }
    let network = args
        .network
        .as_deref()
        .map(NetworkModel::parse)
        .transpose()?;
    let clock = args.clock.as_deref().map(ClockProfile::parse).transpose()?;
    let mut mcap = Mcap::open(args.mcap.as_ref())?;
    let (scenario, band) = if let Some(name) = &args.scenario {
        let sc =
            Scenario::by_name(name, args.seed).map_err(|e| format!("--scenario {name}: {e}"))?;
        let band = match sc.people.first().map(|p| p.speed) {
            Some(r) if r == SpeedBand::Slow.range() => "slow",
            Some(r) if r == SpeedBand::Mid.range() => "mid",
            Some(r) if r == SpeedBand::Fast.range() => "fast",
            _ => "-",
        };
        (sc, band)
    } else {
        let band = SpeedBand::parse(&args.band)?;
        let sc = band_scenario(band, args.people, args.frames, args.seed, &cfg);
        (sc, band.name())
    };
    let (summary, run, window, sc) = run_sim_scenario(
        scenario,
        band,
        args.frames,
        &cfg,
        output,
        network,
        clock,
        mcap.as_mut(),
    )?;
    let mcap_info = match mcap {
        Some(m) => Some(record_room(m, &sc, &run)?),
        None => None,
    };
    let summary = LidarSummary {
        mcap: mcap_info,
        ..summary
    };
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).map_err(at(out))?;
        write_tracks(&out.join("tracks.csv"), &run.tracks)?;
        write_mot(&out.join("tracks_mot.txt"), &run.tracks)?;
        let gt_path = out.join("gt_people.csv");
        let f = std::fs::File::create(&gt_path).map_err(at(&gt_path))?;
        let names: Vec<&str> = sc.scanners.iter().map(|s| s.name.as_str()).collect();
        let mut w = GtWriter::new(std::io::BufWriter::new(f), &names)?;
        for g in &run.gt {
            w.write(g)?;
        }
        let js = serde_json::to_string_pretty(&summary)?;
        let mpath = out.join("metrics.json");
        std::fs::write(&mpath, js).map_err(at(&mpath))?;
        let trajs = trajectories(&run.tracks);
        let gt_trajs = gt_trajectories(&window);
        plot_room(
            &out.join("plot.png"),
            &sc.room,
            &sc.scanners,
            &run.background,
            &trajs,
            &gt_trajs,
        )?;
    }
    output.emit(&summary, || {
        let mut t = summary_text(&summary);
        if summary.interrupted {
            let _ = writeln!(
                t,
                "interrupted: the metrics cover the {} frames tracked so far",
                summary.frames
            );
        }
        if let Some(out) = &args.out {
            let _ = writeln!(
                t,
                "wrote tracks.csv, tracks_mot.txt, gt_people.csv, metrics.json, plot.png to {}",
                out.display()
            );
        }
        if let Some(m) = &summary.mcap {
            let _ = writeln!(
                t,
                "recorded {} messages on {} topics to {}",
                m.messages, m.topics, m.path
            );
        }
        t
    })?;
    if summary.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

/// Writes a recorded run into its recording: `/tf_static` (map → laser, identity), `/scan`
/// (every scan read, LaserScan in `laser`), `/tracks` and `/tracks/markers` per processed scan,
/// and with `--legs` `/ground_truth/person` (PoseStamped, the labelled person).
fn record_recorded(
    mut m: Mcap,
    polar: &[quarry_core::PolarScan],
    run: &lidar_people::RecordedRun,
    labels: &[quarry_data::leg_labels::LabelledPerson],
) -> Result<McapInfo, CmdError> {
    let t0 = polar.first().map_or(TimeUs(0), |s| s.t);
    let laser = [("laser".to_string(), Pose2::default())];
    m.write("/tf_static", t0, &record::static_tf(t0, "map", &laser))?;
    for s in polar {
        m.write("/scan", s.t, &quarry_ros2::convert::laser_scan(s, "laser"))?;
    }
    for f in &run.frames {
        let p = planar(&f.tracks);
        m.write("/tracks", f.t, &record::tracks_msg(f.t, "laser", &p))?;
        m.write(
            "/tracks/markers",
            f.t,
            &record::markers_msg(f.t, "laser", &p, 0.8),
        )?;
    }
    for l in labels {
        let msg = quarry_ros2::msgs::PoseStamped {
            header: quarry_ros2::msgs::Header::new(record::time(l.t), "laser"),
            pose: quarry_ros2::msgs::Pose::planar(l.pos.x, l.pos.y, 0.0),
        };
        m.write("/ground_truth/person", l.t, &msg)?;
    }
    m.finish()
}

/// The JSON summary of a `--scans` run.
#[derive(Debug, Clone, Serialize)]
pub struct RecordedSummary {
    /// Preset.
    pub preset: String,
    /// Detector: contour or legs.
    pub detector: String,
    /// Input file.
    pub scans_file: String,
    /// Beams per scan.
    pub n_beams: u32,
    /// Scans processed.
    pub frames: usize,
    /// CSV rows skipped as malformed (with --skip-bad-rows).
    pub skipped_bad_rows: u64,
    /// CSV rows or scans skipped because their stamp went backwards.
    pub skipped_backwards: u64,
    /// CSV rows or scans skipped because their stamp repeated the previous one (duplicates).
    pub skipped_repeated: u64,
    /// Beams marked invalid (NaN, inf, out of range).
    pub invalid_beams: u64,
    /// Scans used only to fill the background window (not tracked).
    pub warm_up_scans: usize,
    /// Gaps longer than 3 scan periods (the scanner stopped sending).
    pub gaps: usize,
    /// Longest interval between scans, seconds.
    pub longest_gap_s: f64,
    /// Distinct track ids.
    pub distinct_tracks: usize,
    /// Scans with 0, 1, 2, ... tracks.
    pub track_count_histogram: Vec<usize>,
    /// Tracks living at least 1 s.
    pub tracks_over_1s: usize,
    /// With --backfill: rows added at scans where a track was held back before its first
    /// report.
    pub backfilled_rows: usize,
    /// Position error against --legs, if given (the recordings' definition: one person per
    /// scan at the mean of every label).
    pub labelled: Option<LabelledError>,
    /// With --legs: each scan's labels split into people (legs linked within `leg_pair_dist`),
    /// each scored on its own, and the most any tracker of people can match under the
    /// recordings' definition.
    pub label_groups: Option<LabelGroupScore>,
    /// Tracker time per scan, ms.
    pub ms_per_frame: f64,
    /// Background time per scan, ms.
    pub client_ms_per_scan: f64,
    /// With `--mcap`: the recording.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcap: Option<McapInfo>,
}

fn run_recorded_cmd(
    args: &LidarArgs,
    scans: &Path,
    cfg: &LidarPeopleConfig,
    output: &Output,
) -> CmdResult {
    let stem = scans
        .file_stem()
        .and_then(|s| s.to_str())
        .ok_or_else(|| format!("{}: no file name", scans.display()))?;
    let key = args
        .meta_key
        .clone()
        .unwrap_or_else(|| stem.trim_end_matches("_scans").to_string());
    let meta = args.meta.clone().unwrap_or_else(|| {
        scans
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join("scan_meta.json")
    });
    // the scans first: a missing CSV is reported as such, not as a missing scan_meta.json
    // beside it
    std::fs::File::open(scans)
        .map_err(|e| format!("{}: cannot read the scans CSV: {e}", scans.display()))?;
    let meta_text = std::fs::read_to_string(&meta).map_err(|e| {
        format!(
            "{}: cannot read the scanner geometry (a scan_meta.json; give another with --meta): {e}",
            meta.display()
        )
    })?;
    let geometry =
        parse_scan_meta(&meta_text, &key).map_err(|e| format!("{}: {e}", meta.display()))?;
    let policy = if args.skip_bad_rows {
        RowPolicy::Skip
    } else {
        RowPolicy::Error
    };
    let opts = ScanCsvOptions {
        bad_rows: policy,
        backwards: policy,
        ..ScanCsvOptions::default()
    };
    let (polar, stats) =
        read_scans(scans, geometry, opts).map_err(|e| format!("{}: {e}", scans.display()))?;
    if polar.is_empty() {
        return Err(format!("{}: no scans", scans.display()).into());
    }
    let mut mcap = Mcap::open(args.mcap.as_ref())?;
    let mut run = lidar_people::run_recorded(cfg, &geometry, Pose2::default(), &polar, 3.0)?;
    let backfilled_rows = if args.backfill { run.backfill() } else { 0 };
    let mut label_positions: Vec<Point2> = Vec::new();
    let mut labels = Vec::new();
    let (labelled, label_groups) = match &args.legs {
        Some(p) => {
            let text = std::fs::read_to_string(p).map_err(at(p))?;
            let scans = parse_leg_scans_csv(&text).map_err(|e| format!("{}: {e}", p.display()))?;
            labels = scans.iter().map(LabelledScan::person).collect();
            label_positions = labels.iter().map(|l| l.pos).collect();
            (
                Some(score_labelled(&run, &labels, cfg.d_match)?),
                Some(score_label_groups(
                    &run,
                    &scans,
                    cfg.d_match,
                    cfg.leg_pair_dist,
                )?),
            )
        }
        None => (None, None),
    };
    let mcap_info = match mcap.take() {
        Some(m) => Some(record_recorded(m, &polar, &run, &labels)?),
        None => None,
    };
    let min_scans = (1.0 / geometry.scan_period).ceil() as usize;
    let n = run.frames.len().max(1) as f64;
    let summary = RecordedSummary {
        preset: cfg.preset.name().into(),
        detector: cfg.detector.name().into(),
        scans_file: scans.display().to_string(),
        n_beams: geometry.n_beams,
        frames: run.frames.len(),
        skipped_bad_rows: stats.skipped_bad_rows,
        skipped_backwards: stats.skipped_backwards + run.skipped_backwards as u64,
        skipped_repeated: stats.skipped_repeated + run.skipped_repeated as u64,
        invalid_beams: stats.invalid_beams,
        warm_up_scans: run.warm_up_scans,
        gaps: run.gaps,
        longest_gap_s: run.longest_gap_s,
        distinct_tracks: run.distinct_tracks(),
        track_count_histogram: run.track_count_histogram(),
        tracks_over_1s: run
            .track_lifetimes()
            .iter()
            .filter(|(_, l)| *l >= min_scans)
            .count(),
        labelled,
        label_groups,
        backfilled_rows,
        ms_per_frame: 1e3 * run.tracker_seconds / n,
        client_ms_per_scan: 1e3 * run.client_seconds / n,
        mcap: mcap_info,
    };
    if let Some(out) = &args.out {
        std::fs::create_dir_all(out).map_err(at(out))?;
        let rows: Vec<(u64, TimeUs, Vec<LidarTrack>)> = run
            .frames
            .iter()
            .enumerate()
            .map(|(k, f)| (k as u64, f.t, f.tracks.clone()))
            .collect();
        write_tracks(&out.join("tracks.csv"), &rows)?;
        write_mot(&out.join("tracks_mot.txt"), &rows)?;
        // the last scan's returns (background and people) as the backdrop of the trajectories
        let table = quarry_cloud::scan::BeamTable::new(&geometry).map_err(|e| e.to_string())?;
        let last = &polar[polar.len() - 1];
        let backdrop: Vec<Point2> = (0..geometry.n_beams as usize)
            .filter_map(|n| last.range_m(n).and_then(|r| table.point(n, r)))
            .collect();
        let label_pts: Vec<(f64, f64)> = label_positions.iter().map(|p| (p.x, p.y)).collect();
        plot_recorded(
            &out.join("plot.png"),
            &backdrop,
            &trajectories(&rows),
            &label_pts,
        )?;
        // tracks per scan after the warm-up (the warm-up scans carry no tracks by rule)
        let mut counts = vec![0usize; 1];
        for f in run.frames.iter().skip(run.warm_up_scans) {
            let k = f.tracks.len();
            if counts.len() <= k {
                counts.resize(k + 1, 0);
            }
            counts[k] += 1;
        }
        plot_track_counts(&out.join("track_counts.png"), &counts)?;
        let js = serde_json::to_string_pretty(&summary)?;
        let mpath = out.join("metrics.json");
        std::fs::write(&mpath, js).map_err(at(&mpath))?;
    }
    output.emit(&summary, || {
        let mut t = String::new();
        let _ = writeln!(t,
            "quarry lidar --scans {}: preset {}, detector {}, {} beams, {} scans ({} warm-up scans not tracked)",
            summary.scans_file,
            summary.preset,
            summary.detector,
            summary.n_beams,
            summary.frames,
            summary.warm_up_scans
        );
        let _ = writeln!(t,
            "  skipped: {} malformed rows, {} backwards stamps, {} repeated stamps; {} invalid beams; {} gaps (longest {:.3} s)",
            summary.skipped_bad_rows,
            summary.skipped_backwards,
            summary.skipped_repeated,
            summary.invalid_beams,
            summary.gaps,
            summary.longest_gap_s
        );
        let _ = writeln!(t,
            "  tracks: {} distinct ids, {} living >= 1 s; scans with 0,1,2,.. tracks: {:?}",
            summary.distinct_tracks, summary.tracks_over_1s, summary.track_count_histogram
        );
        if args.backfill {
            let _ = writeln!(t,
                "  backfill: {} rows added where a track was held back before its first report",
                summary.backfilled_rows
            );
        }
        if let Some(l) = &summary.labelled {
            let _ = writeln!(t,
                "  vs labelled legs: {}/{} scans matched within {} m, RMSE {:.3} m, mean {:.3} m, median {:.3} m; two-leg labels: {} matched, RMSE {:.3} m",
                l.matched,
                l.labelled,
                cfg.d_match,
                l.rmse_m,
                l.mean_m,
                l.median_m,
                l.matched_two_legs,
                l.rmse_two_legs_m
            );
        }
        if let Some(g) = &summary.label_groups {
            let _ = writeln!(t,
                "  per person (each scan's legs linked within {} m): {}/{} matched within {} m, RMSE {:.3} m; {} scans label more than one person; a tracker exactly on every person would match {}/{} scans of the line above (RMSE {:.3} m)",
                cfg.leg_pair_dist,
                g.matched,
                g.groups,
                cfg.d_match,
                g.rmse_m,
                g.multi_group_scans,
                g.ceiling_matched,
                g.labelled,
                g.ceiling_rmse_m
            );
        }
        let _ = writeln!(t,
            "  tracker {:.3} ms per scan, background {:.3} ms per scan",
            summary.ms_per_frame, summary.client_ms_per_scan
        );
        if let Some(m) = &summary.mcap {
            let _ = writeln!(t, "  recorded {} messages on {} topics to {}", m.messages, m.topics, m.path);
        }
        t
    })
}

/// The human-readable summary of a simulated run.
fn summary_text(s: &LidarSummary) -> String {
    let m = &s.metrics;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "quarry lidar: preset {}, scenario {}, band {}, {} frames",
        s.preset, s.scenario, s.band, s.frames
    );
    let _ = writeln!(
        t,
        "  paper success  {}/{} = {:.2} %   (detectable frames: {:.2} %)",
        m.success,
        m.frames,
        100.0 * s.success_rate,
        100.0 * s.success_rate_detectable
    );
    let _ = writeln!(
        t,
        "  localisation   mean {:.3} m, RMSE {:.3} m, median {:.3} m, p95 {:.3} m ({} pairs)",
        m.loc.mean, m.loc.rmse, m.loc.median, m.loc.p95, m.loc.n
    );
    let _ = writeln!(
        t,
        "  MOTA {:.3}  MOTP {:.3} m  IDF1 {:.3}  HOTA {:.3}  IDSW {}  FP {}  FN {}",
        s.mota, s.motp, s.idf1, s.hota, m.idsw, m.fp, m.fn_
    );
    let _ = writeln!(
        t,
        "  server {:.3} ms per fused frame, client {:.3} ms per scan",
        s.ms_per_frame, s.client_ms_per_scan
    );
    if let Some(c) = &s.calibration {
        let _ = writeln!(
            t,
            "  calibration icp at {:.3} s ({} frames before it not tracked): max error {:.4} m, {:.4} deg",
            c.t_us as f64 * 1e-6,
            c.frames_discarded,
            c.max_pos_error_m,
            c.max_rot_error_deg
        );
        for k in &c.scanners {
            let _ = writeln!(
                t,
                "    {}{}: rough ({:.3}, {:.3}, {:.2}°) -> ({:.4}, {:.4}, {:.3}°), error {:.4} m {:.4}° (rough {:.3} m {:.2}°), overlap {:.3}, RMS {:.4} m",
                k.name,
                if k.reference { " (reference)" } else { "" },
                k.rough.x,
                k.rough.y,
                k.rough.theta.to_degrees(),
                k.pose.x,
                k.pose.y,
                k.pose.theta.to_degrees(),
                k.pos_error_m,
                k.rot_error_deg,
                k.rough_pos_error_m,
                k.rough_rot_error_deg,
                k.overlap,
                k.rms_m
            );
        }
    }
    t
}

pub(crate) fn write_tracks(
    path: &Path,
    tracks: &[(u64, TimeUs, Vec<LidarTrack>)],
) -> Result<(), CmdError> {
    let mut s =
        String::from("frame,t_us,track_id,x,y,alpha,vx,vy,support,rms,born,gate_replaced\n");
    for (k, t, rows) in tracks {
        for r in rows {
            let _ = writeln!(
                s,
                "{k},{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{},{:.5},{},{}",
                t.0,
                r.id,
                r.x,
                r.y,
                r.alpha,
                r.vx,
                r.vy,
                r.support,
                r.rms,
                u8::from(r.born),
                u8::from(r.gate_replaced)
            );
        }
    }
    Ok(std::fs::write(path, s).map_err(at(path))?)
}

/// MOTChallenge-style rows with world coordinates: `frame,id,-1,-1,-1,-1,conf,x,y,z`
/// (1-based frame; the 3-D world columns carry x, y in metres, z = 0).
pub(crate) fn write_mot(
    path: &Path,
    tracks: &[(u64, TimeUs, Vec<LidarTrack>)],
) -> Result<(), CmdError> {
    let mut s = String::new();
    for (k, _, rows) in tracks {
        for r in rows {
            let _ = writeln!(
                s,
                "{},{},-1,-1,-1,-1,1,{:.4},{:.4},0",
                k + 1,
                r.id + 1,
                r.x,
                r.y
            );
        }
    }
    Ok(std::fs::write(path, s).map_err(at(path))?)
}

fn trajectories(tracks: &[(u64, TimeUs, Vec<LidarTrack>)]) -> Vec<Vec<(f64, f64)>> {
    let mut by: std::collections::BTreeMap<u32, Vec<(f64, f64)>> = Default::default();
    for (_, _, rows) in tracks {
        for r in rows {
            by.entry(r.id).or_default().push((r.x, r.y));
        }
    }
    by.into_values().collect()
}

fn gt_trajectories(window: &[EvalFrame]) -> Vec<Vec<(f64, f64)>> {
    let mut by: std::collections::BTreeMap<u32, Vec<(f64, f64)>> = Default::default();
    for f in window {
        for (id, p, _) in &f.gt {
            by.entry(*id).or_default().push((p[0], p[1]));
        }
    }
    by.into_values().collect()
}

/// Draws a `w` × `h` chart on a white bitmap with `draw` and saves it as a PNG at `path`.
fn render_png(
    path: &Path,
    (w, h): (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), CmdError>,
) -> Result<(), CmdError> {
    crate::fonts::register()?;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        draw(&root)?;
        root.present().map_err(|e| e.to_string())?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or("plot buffer size mismatch")?;
    img.save(path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

/// Draws the room (walls, obstacles), the scanners, the background points, GT (grey) and the
/// tracks (one colour per id), with a caption and axes in metres (the bundled font).
pub fn plot_room(
    path: &Path,
    room: &Room,
    scanners: &[ScannerSim],
    background: &[Point2],
    tracks: &[Vec<(f64, f64)>],
    gt: &[Vec<(f64, f64)>],
) -> Result<(), CmdError> {
    let (w, h) = (1100u32, 900u32);
    render_png(path, (w, h), |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(20)
            .caption(
                "scanners (red), background (blue dots), truth (grey), tracks (colours)",
                ("sans-serif", 16),
            )
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(-0.5f64..13.5f64, -0.5f64..8.5f64)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()
            .map_err(|e| e.to_string())?;
        let e = |x: Result<(), DrawingAreaErrorKind<_>>| x.map_err(|e| e.to_string());
        for wall in &room.walls {
            e(chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(wall.a[0], wall.a[1]), (wall.b[0], wall.b[1])],
                    BLACK.stroke_width(3),
                )))
                .map(|_| ()))?;
        }
        for (_, o) in &room.obstacles {
            match *o {
                Obstacle::Rect { min, max } => {
                    e(chart
                        .draw_series(std::iter::once(Rectangle::new(
                            [(min[0], min[1]), (max[0], max[1])],
                            RGBColor(160, 160, 160).filled(),
                        )))
                        .map(|_| ()))?;
                }
                Obstacle::Circle { c, r } => {
                    let pts: Vec<(f64, f64)> = (0..=36)
                        .map(|k| {
                            let a = f64::from(k) * std::f64::consts::TAU / 36.0;
                            (c[0] + r * a.cos(), c[1] + r * a.sin())
                        })
                        .collect();
                    e(chart
                        .draw_series(std::iter::once(Polygon::new(
                            pts,
                            RGBColor(160, 160, 160).filled(),
                        )))
                        .map(|_| ()))?;
                }
            }
        }
        e(chart
            .draw_series(
                background
                    .iter()
                    .map(|p| Circle::new((p.x, p.y), 1, RGBColor(120, 120, 200).filled())),
            )
            .map(|_| ()))?;
        for g in gt {
            e(chart
                .draw_series(std::iter::once(PathElement::new(
                    g.clone(),
                    RGBColor(200, 200, 200).stroke_width(4),
                )))
                .map(|_| ()))?;
        }
        for (i, t) in tracks.iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            if t.len() == 1 {
                e(chart
                    .draw_series(std::iter::once(Circle::new(t[0], 2, c.filled())))
                    .map(|_| ()))?;
            } else {
                e(chart
                    .draw_series(std::iter::once(PathElement::new(
                        t.clone(),
                        c.stroke_width(2),
                    )))
                    .map(|_| ()))?;
            }
        }
        for s in scanners {
            let p: Pose2 = s.pose;
            let tip = (p.x + 0.4 * p.theta.cos(), p.y + 0.4 * p.theta.sin());
            e(chart
                .draw_series(std::iter::once(Circle::new((p.x, p.y), 7, RED.filled())))
                .map(|_| ()))?;
            e(chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(p.x, p.y), tip],
                    RED.stroke_width(3),
                )))
                .map(|_| ()))?;
        }
        Ok(())
    })
}

/// A bar chart of `counts[k]` = scans with `k` tracks (after the warm-up), each bar labelled
/// with its share of the scans.
fn plot_track_counts(path: &Path, counts: &[usize]) -> Result<(), CmdError> {
    let total = counts.iter().sum::<usize>().max(1);
    let top = counts.iter().copied().max().unwrap_or(0).max(1) as f64 * 1.15;
    let n = counts.len().max(1);
    let (w, h) = (800u32, 500u32);
    render_png(path, (w, h), |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(20)
            .caption(
                format!("tracks per scan ({total} scans after the warm-up)"),
                ("sans-serif", 16),
            )
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(-0.5f64..n as f64 - 0.5, 0.0f64..top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(n.min(30))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .x_desc("tracks reported in the scan")
            .y_desc("scans")
            .draw()
            .map_err(|e| e.to_string())?;
        let e = |x: Result<(), DrawingAreaErrorKind<_>>| x.map_err(|e| e.to_string());
        for (k, &c) in counts.iter().enumerate() {
            let x = k as f64;
            e(chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x - 0.35, 0.0), (x + 0.35, c as f64)],
                    RGBColor(70, 110, 180).filled(),
                )))
                .map(|_| ()))?;
            e(chart
                .draw_series(std::iter::once(Text::new(
                    format!("{:.1}%", 100.0 * c as f64 / total as f64),
                    (x - 0.3, c as f64 + 0.02 * top),
                    ("sans-serif", 13),
                )))
                .map(|_| ()))?;
        }
        Ok(())
    })
}

/// The plot of a `--scans` run: the last scan's returns (blue dots), the labelled person
/// positions when `--legs` is given (grey), every track's trajectory (one colour per id) and
/// the scanner (red, at the origin, looking along +x); axes in metres, the extent that of the
/// tracks and labels plus 1 m (at least 4 m × 4 m).
fn plot_recorded(
    path: &Path,
    backdrop: &[Point2],
    tracks: &[Vec<(f64, f64)>],
    labels: &[(f64, f64)],
) -> Result<(), CmdError> {
    let (mut x0, mut x1, mut y0, mut y1) = (-2.0f64, 2.0f64, -2.0f64, 2.0f64);
    for &(x, y) in tracks.iter().flatten().chain(labels) {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x - 1.0);
            x1 = x1.max(x + 1.0);
            y0 = y0.min(y - 1.0);
            y1 = y1.max(y + 1.0);
        }
    }
    // equal scale on both axes
    let (w, h) = (1000u32, 900u32);
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let half = 0.5 * (x1 - x0).max((y1 - y0) * f64::from(w) / f64::from(h));
    let half_y = half * f64::from(h) / f64::from(w);
    let (x0, x1, y0, y1) = (cx - half, cx + half, cy - half_y, cy + half_y);
    render_png(path, (w, h), |root| {
        let mut chart = ChartBuilder::on(root)
            .margin(20)
            .caption(
                "scanner (red), last scan (blue dots), labels (grey), tracks (colours)",
                ("sans-serif", 16),
            )
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()
            .map_err(|e| e.to_string())?;
        let e = |x: Result<(), DrawingAreaErrorKind<_>>| x.map_err(|e| e.to_string());
        let inside = |x: f64, y: f64| x >= x0 && x <= x1 && y >= y0 && y <= y1;
        e(chart
            .draw_series(
                backdrop
                    .iter()
                    .filter(|p| inside(p.x, p.y))
                    .map(|p| Circle::new((p.x, p.y), 2, RGBColor(120, 120, 200).filled())),
            )
            .map(|_| ()))?;
        e(chart
            .draw_series(
                labels
                    .iter()
                    .filter(|p| inside(p.0, p.1))
                    .map(|p| Circle::new(*p, 3, RGBColor(190, 190, 190).filled())),
            )
            .map(|_| ()))?;
        for (i, t) in tracks.iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            e(chart
                .draw_series(std::iter::once(PathElement::new(
                    t.clone(),
                    c.stroke_width(2),
                )))
                .map(|_| ()))?;
            if let Some(&end) = t.last() {
                e(chart
                    .draw_series(std::iter::once(Circle::new(end, 3, c.filled())))
                    .map(|_| ()))?;
            }
        }
        e(chart
            .draw_series(std::iter::once(Circle::new((0.0, 0.0), 7, RED.filled())))
            .map(|_| ()))?;
        e(chart
            .draw_series(std::iter::once(PathElement::new(
                vec![(0.0, 0.0), (0.4, 0.0)],
                RED.stroke_width(3),
            )))
            .map(|_| ()))?;
        Ok(())
    })
}

/// `quarry demo --data DIR`: the `jipda` preset with the leg detector on the real leg-height
/// recording `DIR/leg-tracker/positive_1` (docs/lidar-people.md), scored against its labels.
/// `Ok(None)` when the recording is not there.
pub fn demo_real_rows(data: &Path) -> Result<Option<Vec<super::demo::Row>>, CmdError> {
    let dir = data.join("leg-tracker");
    let scans = dir.join("positive_1_scans.csv");
    if !scans.exists() {
        return Ok(None);
    }
    let meta = dir.join("scan_meta.json");
    let meta_text = std::fs::read_to_string(&meta).map_err(at(&meta))?;
    let geometry = parse_scan_meta(&meta_text, "positive_1")
        .map_err(|e| format!("{}: {e}", meta.display()))?;
    let (polar, _) = read_scans(&scans, geometry, ScanCsvOptions::default())
        .map_err(|e| format!("{}: {e}", scans.display()))?;
    let cfg = LidarPeopleConfig {
        detector: lidar_people::Detector::Legs,
        ..LidarPeopleConfig::jipda()
    };
    let t = std::time::Instant::now();
    let run = lidar_people::run_recorded(&cfg, &geometry, Pose2::default(), &polar, 3.0)?;
    let ms = t.elapsed().as_secs_f64() * 1e3 / polar.len().max(1) as f64;
    let legs = dir.join("positive_1_legs.csv");
    let text = std::fs::read_to_string(&legs).map_err(at(&legs))?;
    let label_scans = parse_leg_scans_csv(&text).map_err(|e| format!("{}: {e}", legs.display()))?;
    let labels: Vec<_> = label_scans.iter().map(LabelledScan::person).collect();
    let e = score_labelled(&run, &labels, cfg.d_match)?;
    let g = score_label_groups(&run, &label_scans, cfg.d_match, cfg.leg_pair_dist)?;
    let min_scans = (1.0 / geometry.scan_period).ceil() as usize;
    let long = run
        .track_lifetimes()
        .iter()
        .filter(|(_, l)| *l >= min_scans)
        .count();
    let row = |metric: &str, value: f64| super::demo::Row {
        tracker: "lidar-legs (real)".into(),
        scenario:
            "leg-tracker positive_1 (one leg-height scanner, 400 scans), jipda preset, leg detector"
                .into(),
        metric: metric.into(),
        value,
        paper: None,
        ms_per_frame: Some(ms),
    };
    Ok(Some(vec![
        row(
            "labelled scans with a track within 0.5 m (%)",
            100.0 * e.matched as f64 / e.labelled.max(1) as f64,
        ),
        row("person position RMSE (m)", e.rmse_m),
        row(
            &format!(
                "labelled people (legs within {} m of each other) with a track within {} m (%)",
                cfg.leg_pair_dist, cfg.d_match
            ),
            100.0 * g.matched as f64 / g.groups.max(1) as f64,
        ),
        row("tracks living >= 1 s", long as f64),
    ]))
}

/// The `quarry demo` rows: `faithful`, then `jipda`, on `band_mid` (seed `seed`, 600 evaluated
/// frames = 30 s): success rate and mean localisation error beside the paper's 90.88 % and
/// 0.18 m, MOTA and IDF1.
pub fn demo_rows(seed: u64) -> Result<Vec<super::demo::Row>, crate::output::CmdError> {
    let quiet = Output { json: true };
    let mut rows = Vec::new();
    // the paper's tracker, then the jipda preset on the same run (identities: IDF1)
    for (cfg, name) in [
        (LidarPeopleConfig::faithful(), "faithful"),
        (LidarPeopleConfig::jipda(), "jipda"),
    ] {
        let (s, ..) = run_sim_band(SpeedBand::Mid, 3, 600, seed, &cfg, &quiet)?;
        let scenario = format!("band_mid (spec 003), 3 people, 600 frames, {name} preset");
        let row = |metric: &str, value: f64, paper: Option<f64>| super::demo::Row {
            tracker: "lidar-people".into(),
            scenario: scenario.clone(),
            metric: metric.into(),
            value,
            paper,
            ms_per_frame: Some(s.ms_per_frame),
        };
        rows.extend([
            row(
                "paper success rate (%)",
                100.0 * s.success_rate,
                Some(90.88),
            ),
            row("mean localisation error (m)", s.loc_error_m, Some(0.18)),
            row("MOTA", s.mota, None),
            row("IDF1", s.idf1, None),
        ]);
    }
    Ok(rows)
}
