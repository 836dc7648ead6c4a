//! `quarry demo`: run every tracker that exists on its built-in scenario and print one summary
//! table.
//!
//! To add a row: write `fn my_tracker(args: &DemoArgs) -> Result<Vec<Row>, CmdError>` that runs
//! the scenario (seeded from `args.seed`) and returns one [`Row`] per metric, then add
//! `("name", my_tracker)` to [`DEMOS`].

use std::time::Instant;

use clap::Args;
use nalgebra::{Matrix4, Vector2, Vector4};
use quarry_core::{Gaussian, MotionModel, rng};
use quarry_eval::position::{nees, nees_consistency, position_rmse};
use quarry_filter::{ConstantVelocity2, Ekf, Position2};
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use crate::output::{CmdError, CmdResult, Output, Table, fmt_opt};
use crate::progress;

/// Arguments of `quarry demo`.
#[derive(Debug, Args)]
#[command(
    about = "Run every tracker on its built-in scenario and print one summary table",
    long_about = "Run every tracker that exists on its built-in, simulated scenario and print \
one summary table: tracker, scenario, metric, value, the paper's value where the paper reports \
one, and the time per frame. No input files are needed; every scenario is seeded (--seed), so \
a run is reproducible.

Current rows:
  kf-cv   a Kalman filter (quarry-filter's Ekf on linear models) tracking a simulated \
constant-velocity target (1000 steps, dt 0.1 s, q 0.5 m^2/s^3, position noise 0.5 m); \
reports the position RMSE and the mean NEES with its 95 % chi-square interval (quarry-eval).
  rgbd-person / rgbd-baseline   the RGB-D person tracker (paper 001) and the whole-target \
baseline on the first 210 frames of synthetic S1 (static robot, crossing occluder): success \
at IoU 0.5 and centre error.
  slamot   PFJPDA_SLAMOT (paper 000) on S0, one run with 50 particles: robot and target \
mean errors beside the paper's.
  lidar-people   the lidar people tracker (paper 003), faithful and jipda presets on the simulated room.
  watershed-sift   the watershed + SIFT pools tracker (paper 004, paper profile) on the first 120 \
frames of the synthetic walkers-v1-ab layout (two walkers, drawn with --seed): MOTA, IDF1 and \
the matched centre RMSE.

With --data DIR, two rows on recordings nobody here made (skipped, with a note, where DIR does \
not hold them):
  lidar-legs (real)   the jipda preset with the leg detector on DIR/leg-tracker/positive_1 (one \
leg-height scanner; Leigh et al. 2015): labelled scans matched within 0.5 m, RMSE, labelled \
people matched (a scan's legs split into people), long tracks.
  watershed-sift (real)   the robust profile on DIR/pets09-s2l1 frames 1-200 (PETS 2009 S2L1, \
MOTChallenge layout): MOTA, IDF1, HOTA, beside the best peer's.

Ctrl-C (or SIGTERM) ends the demo after the tracker in progress: the rows so far are printed \
with \"interrupted\": true and the exit status is 130; a second Ctrl-C stops at once.

JSON (--json) prints {\"seed\": N, \"rows\": [{\"tracker\", \"scenario\", \"metric\", \
\"value\", \"paper\" (null when the paper has no such number), \"ms_per_frame\"}, ...]}.

EXAMPLE:
  quarry demo
  quarry demo --json --seed 7 | jq '.rows[] | select(.tracker == \"kf-cv\")'
  quarry demo --data ../shared/data"
)]
pub struct DemoArgs {
    /// Seed of every scenario's random generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Run only the demos whose name contains this text.
    #[arg(long, value_name = "NAME")]
    pub only: Option<String>,
    /// A directory with real recordings (leg-tracker/, pets09-s2l1/): adds their rows.
    #[arg(long, value_name = "DIR")]
    pub data: Option<std::path::PathBuf>,
}

/// One line of the summary table (JSON field names are stable).
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Tracker name.
    pub tracker: String,
    /// Scenario description.
    pub scenario: String,
    /// What is measured, with its unit.
    pub metric: String,
    /// The measured value.
    pub value: f64,
    /// The paper's value for the same metric, when it reports one.
    pub paper: Option<f64>,
    /// Wall-clock milliseconds per frame (per filter step) of the tracker alone.
    pub ms_per_frame: Option<f64>,
}

/// A demo: produces the rows of one tracker.
pub type RowFn = fn(&DemoArgs) -> Result<Vec<Row>, CmdError>;

/// Every demo, in table order: `(name, function)`.
pub const DEMOS: &[(&str, RowFn)] = &[
    ("kf-cv", kf_cv),
    ("slamot", slamot),
    ("lidar-people", lidar_people),
    ("rgbd-person", rgbd_person),
    ("watershed-sift", watershed_sift),
    ("lidar-legs-real", lidar_legs_real),
    ("watershed-sift-real", watershed_sift_real),
];

/// A real-data demo: its rows with `--data DIR` when DIR holds the recording, else none (and
/// a note on stderr saying why).
fn real(
    args: &DemoArgs,
    what: &str,
    rows: fn(&std::path::Path) -> Result<Option<Vec<Row>>, CmdError>,
) -> Result<Vec<Row>, CmdError> {
    let Some(dir) = &args.data else {
        return Ok(Vec::new());
    };
    if let Some(r) = rows(dir)? {
        return Ok(r);
    }
    eprintln!(
        "quarry demo: skipping the {what} row: not found under {}",
        dir.display()
    );
    Ok(Vec::new())
}

/// The lidar people tracker on the real leg-height recording (with `--data`).
fn lidar_legs_real(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    real(args, "leg-tracker/positive_1", super::lidar::demo_real_rows)
}

/// The watershed + SIFT tracker on PETS09-S2L1 (with `--data`).
fn watershed_sift_real(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    real(args, "pets09-s2l1", super::video::demo_real_rows)
}

/// The watershed + SIFT pools tracker (paper 004) on a short synthetic walkers clip.
fn watershed_sift(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    super::video_sim::demo_rows(args.seed)
}

/// The RGB-D person tracker (paper 001) on S1, patch tracker and whole-target baseline.
fn rgbd_person(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    super::rgbd::demo_rows(args.seed)
}

/// The lidar people tracker (paper 003), `faithful` and `jipda` presets on band_mid.
fn lidar_people(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    super::lidar::demo_rows(args.seed)
}

/// PFJPDA_SLAMOT (paper 000) on S0: one run, N = 50, robot and target errors beside the paper's.
fn slamot(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    super::slamot::demo_rows(args.seed)
}

#[derive(Serialize)]
struct DemoReport<'a> {
    seed: u64,
    rows: &'a [Row],
    /// Ctrl-C / SIGTERM stopped the demo: `rows` are those of the trackers that completed.
    interrupted: bool,
}

/// Runs `quarry demo`.
pub fn run(args: &DemoArgs, out: &Output) -> CmdResult {
    let selected: Vec<&(&str, RowFn)> = DEMOS
        .iter()
        .filter(|(name, _)| args.only.as_deref().is_none_or(|o| name.contains(o)))
        .collect();
    if selected.is_empty() {
        let names: Vec<&str> = DEMOS.iter().map(|d| d.0).collect();
        return Err(format!(
            "no demo matches --only {:?} (demos: {})",
            args.only.as_deref().unwrap_or(""),
            names.join(", ")
        )
        .into());
    }
    crate::interrupt::install();
    let pb = progress::bar(out, selected.len() as u64, "demo");
    let mut rows = Vec::new();
    for (name, f) in selected {
        // Ctrl-C ends the demo after the tracker in progress; the rows so far are shown
        if crate::interrupt::requested() {
            break;
        }
        pb.set_message((*name).to_string());
        rows.extend(f(args).map_err(|e| format!("demo {name}: {e}"))?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let report = DemoReport {
        seed: args.seed,
        rows: &rows,
        interrupted: crate::interrupt::requested(),
    };
    out.emit(&report, || {
        let mut t = Table::new([
            "tracker", "scenario", "metric", "value", "paper", "ms/frame",
        ]);
        for r in &rows {
            t.row([
                r.tracker.clone(),
                r.scenario.clone(),
                r.metric.clone(),
                format!("{:.4}", r.value),
                r.paper.map_or_else(|| "-".to_string(), |p| format!("{p}")),
                fmt_opt(r.ms_per_frame, 4),
            ]);
        }
        if report.interrupted {
            format!(
                "interrupted: the rows of the trackers that completed\n{}",
                t.render()
            )
        } else {
            t.render()
        }
    })?;
    if report.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

/// Kalman filter on a simulated constant-velocity target: position RMSE and NEES consistency.
fn kf_cv(args: &DemoArgs) -> Result<Vec<Row>, CmdError> {
    const STEPS: usize = 1000;
    const DT: f64 = 0.1;
    const Q: f64 = 0.5;
    const SIGMA: f64 = 0.5;
    let model = ConstantVelocity2::cwna(Q)?;
    let sensor = Position2::isotropic(SIGMA)?;
    let mut g = rng::stream(args.seed, &[0x6b66]); // "kf"
    let mut normal = || -> f64 { StandardNormal.sample(&mut g) };

    // truth: x_{k+1} = F x_k + w, w ~ N(0, Q(dt)) drawn through the Cholesky factor of Q
    let q_chol = model
        .process_noise(&Vector4::zeros(), &(), DT)
        .cholesky()
        .ok_or("process noise is not positive definite")?
        .l();
    let mut x = Vector4::new(0.0, 0.0, 1.0, 0.5); // [x, y, vx, vy]
    let mut truth = Vec::with_capacity(STEPS);
    let mut meas = Vec::with_capacity(STEPS);
    for _ in 0..STEPS {
        let w = Vector4::new(normal(), normal(), normal(), normal());
        x = model.transition(&x, &(), DT) + q_chol * w;
        truth.push(x);
        meas.push(Vector2::new(
            x[0] + SIGMA * normal(),
            x[1] + SIGMA * normal(),
        ));
    }

    let x0 = Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 0.5), Matrix4::identity())?;
    let mut kf = Ekf::new(x0, model, sensor)?;
    let mut est = Vec::with_capacity(STEPS);
    let mut covs = Vec::with_capacity(STEPS);
    let start = Instant::now();
    for z in &meas {
        kf.predict(&(), DT)?;
        kf.update(z)?;
        est.push(*kf.mean());
        covs.push(*kf.cov());
    }
    let ms = start.elapsed().as_secs_f64() * 1e3 / STEPS as f64;

    let pos_est: Vec<[f64; 2]> = est.iter().map(|m| [m[0], m[1]]).collect();
    let pos_true: Vec<[f64; 2]> = truth.iter().map(|t| [t[0], t[1]]).collect();
    let rmse = position_rmse(&pos_est, &pos_true)?;
    let errors: Vec<Vector4<f64>> = est.iter().zip(&truth).map(|(e, t)| e - t).collect();
    let check = nees_consistency(&nees(&errors, &covs)?, 4, 0.95)?;
    let scenario = format!("CV target, {STEPS} steps, dt {DT} s, q {Q}, sigma {SIGMA} m");
    Ok(vec![
        Row {
            tracker: "kf-cv".into(),
            scenario: scenario.clone(),
            metric: "position RMSE (m)".into(),
            value: rmse,
            paper: None,
            ms_per_frame: Some(ms),
        },
        Row {
            tracker: "kf-cv".into(),
            scenario,
            metric: format!(
                "mean NEES (95% interval {:.2}-{:.2})",
                check.lower, check.upper
            ),
            value: check.mean,
            paper: None,
            ms_per_frame: Some(ms),
        },
    ])
}
