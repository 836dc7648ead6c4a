//! `quarry slamot`: the RBPF SLAM + multi-target tracker of paper 000 on its simulated scenario
//! (S0 / S1) or on a UTIAS MRCLAM recording, and `quarry slamot sweep` (error vs particles,
//! the paper's Figs. 3 and 4).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use clap::{Args, Subcommand, ValueEnum};
use plotters::prelude::*;
use quarry_repro::slamot::{
    SimRunResult, filter_seed, mean_var, run_mrclam, run_simulated, run_simulated_ekf,
    smooth_mrclam,
};
use quarry_sim::slamot::SlamotScenarioConfig;
use quarry_trackers::slamot::{AssociationMode, Preset, SlamotConfig, TargetWeight};
use quarry_trackers::{TrackerConfig, TrackerError};
use serde::Serialize;

use crate::config_args::ConfigArgs;
use crate::output::{CmdError, CmdResult, Output, Table};
use crate::progress;
use crate::record::{self, Mcap, SlamotRecording};
use quarry_core::Pose2;
use quarry_ros2::msgs::Track;

/// What `quarry slamot` refuses before running anything.
#[derive(Debug)]
pub enum SlamotCmdError {
    /// Flags that do not go together, or a count that must be positive.
    Usage(&'static str),
    /// A file or directory could not be written.
    Io {
        /// The path.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
}

impl std::fmt::Display for SlamotCmdError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Usage(m) => f.write_str(m),
            Self::Io { path, .. } => write!(f, "cannot write {}", path.display()),
        }
    }
}

impl std::error::Error for SlamotCmdError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Usage(_) => None,
            Self::Io { source, .. } => Some(source),
        }
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> SlamotCmdError + '_ {
    move |source| SlamotCmdError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// The paper's one-run numbers (N = 50): robot, targets 1..3, (mean, variance).
pub const PAPER_ROBOT: (f64, f64) = (0.452, 0.117);
/// The paper's target numbers (mean, variance) for targets 1, 2, 3.
pub const PAPER_TARGETS: [(f64, f64); 3] = [(0.923, 0.353), (1.544, 1.235), (1.952, 0.5543)];

/// Association mode on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModeArg {
    /// Exact JPDA (default).
    Jpda,
    /// The paper's eqs. (5), (11), (12) literally.
    Paper,
    /// JIPDA with existence.
    Jipda,
}

/// Which filter runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum FilterArg {
    /// The Rao-Blackwellized particle filter of the paper (PFJPDA_SLAMOT).
    #[default]
    Rbpf,
    /// The joint-EKF baseline (the paper's reference [8]); deterministic, --particles ignored.
    Ekf,
}

/// Built-in scenario.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ScenarioArg {
    /// The paper's scenario (spec §3.2): clean detections.
    S0,
    /// Stress: P_D 0.9 and Poisson(2) clutter per scan.
    S1,
}

/// Arguments of `quarry slamot`.
#[derive(Debug, Args)]
#[command(
    about = "RBPF SLAM + multi-target tracking (paper 000) on its scenario or on MRCLAM data",
    long_about = "Run PFJPDA_SLAMOT (spec 000): a Rao-Blackwellized particle filter that localises \
the robot, maps the landmarks and tracks the moving targets in one filter.

Without --mrclam it runs the simulated scenario (--scenario s0: the paper's 100 m x 100 m world, \
three constant-velocity targets, 80 s; s1: with missed detections and clutter) --runs times \
(truth seeds --seed, --seed+1, ...) and reports the robot and per-target position errors \
(mean over epochs, population variance over epochs, then averaged over runs) beside the paper's \
numbers, and the number of runs with a swap or loss after the crossing (target error > 3 m \
after t = 40 s).

With --mrclam DIR --robot K it reads a UTIAS MRCLAM dataset: robot K does SLAM on the 15 \
landmarks (known barcodes) and tracks the other four robots WITHOUT their barcodes (JIPDA with \
births and deaths); scored against Vicon. --smooth plain|calibrated then refines each run with a \
batch smoother over the whole recording (every pose and landmark at once, Huber detections, \
started from the filter's estimate; calibrated also estimates the odometry's scales, turn-rate \
bias and time offset) and scores it beside the filter: the filter is what a robot has online, \
the smoother what it has after the run (docs/slamot.md).

Configuration: the filter's configuration is a preset (--preset paper|s1|mrclam; `quarry \
slamot --help` lists them) with an optional TOML file laid over it (--config FILE.toml: keys \
missing from the file keep the preset's values, unknown keys are errors; see \
quarry_trackers::slamot::SlamotConfig for the keys). Without --preset the preset is the \
--config file's `preset` key if it has one, else the one the run implies: --scenario s0 -> \
paper, --scenario s1 -> s1, --mrclam -> mrclam (so `--scenario s1` alone keeps meaning the S1 \
configuration). --preset chooses only the filter's configuration, --scenario only the \
simulated world. --particles, --mode and --eq11 are applied on top of that configuration when \
given (without them the configuration's values rule; every preset has N = 50 and mode jpda, \
mrclam jipda); --mrclam always uses JIPDA with births and deaths.

JSON (--json): {\"robot_err_mean\", \"robot_err_var\", \"target_err_mean\": [..], \
\"target_err_var\": [..], \"losses\", \"ms_per_step\", \"runs\", \"particles\", \"mode\", \
\"scenario\", \"filter\", \"paper\", \"interrupted\"}; with --mrclam also \"map_err\", \"ospa\", \
\"assoc_accuracy\" and \"mrclam\" (every score per seed and its spread; with --smooth a \
\"smoothed\" entry per seed and \"mrclam.smoothed\": the smoothed spreads).

Ctrl-C (or SIGTERM) ends the runs after the one in progress: the report and the outputs cover \
the runs completed (\"runs\" says how many), \"interrupted\" is true and the exit status is 130. \
A second Ctrl-C stops at once.

--out DIR writes trajectories_run<r>.csv, map_run<r>.csv and fig1.png (the median run like the \
paper's Fig. 1: truth dashed, estimates solid, true landmarks as crosses, estimated landmarks as \
dots; robot black, targets red/green/blue; no text). With --mrclam it writes, for the median \
run, mrclam_robotK_trajectory.csv, _map.csv, _tracks.csv and mrclam_robotK.png (the estimate \
over the Vicon truth), and with --smooth also mrclam_robotK_smoothed_trajectory.csv and \
_smoothed_map.csv (the smoothed run, drawn in blue on the plot).

EXAMPLES:
  quarry slamot --runs 20 --particles 50 --json
  quarry slamot --mode paper --scenario s1 --runs 20
  quarry slamot --scenario s1 --preset paper --runs 20   (S1 world, S0 filter)
  quarry slamot --preset s1 --config my.toml --json
  quarry slamot --filter ekf --runs 20 --json
  quarry slamot --mrclam ../shared/data/mrclam-6 --robot 1 --out out/
  quarry slamot --mrclam ../shared/data/mrclam-6 --robot 1 --particles 100 --runs 5 --smooth plain
  quarry slamot sweep --particles 20,50,100,200 --runs 20 --out out/"
)]
pub struct SlamotArgs {
    /// Error-vs-particles sweep (Figs. 3 and 4).
    #[command(subcommand)]
    pub sub: Option<SlamotSub>,
    /// The filter's configuration: --preset and --config (see above).
    #[command(flatten)]
    pub cfg: ConfigArgs<Preset>,
    /// Number of particles N, over the configuration's (every preset: 50).
    #[arg(long)]
    pub particles: Option<usize>,
    /// Monte-Carlo runs (truth seeds seed, seed+1, ...).
    #[arg(long, default_value_t = 1)]
    pub runs: u64,
    /// First truth seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Association mode, over the configuration's (paper, s1: jpda).
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Use the paper's eq. (11) target weight (ablation; default: the configuration's, the
    /// mode's own in every preset).
    #[arg(long)]
    pub eq11: bool,
    /// Filter: the RBPF (default) or the joint-EKF baseline.
    #[arg(long, value_enum, default_value_t = FilterArg::Rbpf)]
    pub filter: FilterArg,
    /// Built-in scenario (s1 also implies the s1 preset when neither --preset nor a `preset`
    /// key in --config says otherwise).
    #[arg(long, value_enum, default_value_t = ScenarioArg::S0)]
    pub scenario: ScenarioArg,
    /// MRCLAM dataset directory (instead of the simulation).
    #[arg(long, value_name = "DIR")]
    pub mrclam: Option<PathBuf>,
    /// MRCLAM robot that drives (1..=5).
    #[arg(long, default_value_t = 1)]
    pub robot: u32,
    /// Output directory for CSV trajectories and the plot.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// MRCLAM: when a measurement is applied (own = at its own stamp, the odometry interval is
    /// cut there; next-odometry = at the end of its odometry interval, the old behaviour, kept
    /// to measure the difference).
    #[arg(long, value_enum, default_value_t = TimingArg::Own)]
    pub timing: TimingArg,
    /// Record the run as MCAP (ROS 2 messages, CDR; docs/ros2.md): odometry (`/odom`), the
    /// estimated and true poses, `/tf`, the target tracks (`/targets`), the map and the ground
    /// truth. With several --runs, the median run by robot error (the one --out plots). Stamps
    /// count from the run's start; the metadata record `quarry` holds the seed (and, for MRCLAM,
    /// the recording's start time).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// MRCLAM: also refine every run with the batch smoother (all poses and landmarks at once,
    /// started from the filter's estimate; quarry_filter::smoother) and score it beside the
    /// filter. `plain` takes the odometry as recorded; `calibrated` also estimates its speed
    /// and turn-rate scales, a turn-rate bias and a time offset.
    #[arg(long, value_enum, value_name = "MODE")]
    pub smooth: Option<SmoothArg>,
}

/// `--smooth` on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum SmoothArg {
    /// The odometry as recorded.
    Plain,
    /// The odometry's scales, turn-rate bias and time offset estimated too.
    Calibrated,
}

/// MRCLAM measurement timing on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ValueEnum)]
pub enum TimingArg {
    /// At the measurement's own stamp (default).
    #[default]
    Own,
    /// At the end of the odometry interval it falls in (up to ~15 ms late).
    NextOdometry,
}

/// Subcommands of `quarry slamot`.
#[derive(Debug, Subcommand)]
pub enum SlamotSub {
    /// Mean errors vs number of particles (the paper's Figs. 3 and 4).
    Sweep(SweepArgs),
}

/// Arguments of `quarry slamot sweep`.
#[derive(Debug, Args)]
#[command(
    long_about = "Mean robot and target errors against the number of particles (the paper's \
Figs. 3 and 4): --runs seeded runs per count, the same truth seeds for every count. Writes \
sweep.csv, fig3.png and fig4.png into --out.

Ctrl-C (or SIGTERM) ends the sweep after the run in progress: the counts whose runs all \
completed are written and printed with \"interrupted\": true (a count cut short is left out, \
not averaged over fewer runs) and the exit status is 130; a second Ctrl-C stops at once.

EXAMPLE:
  quarry slamot sweep --particles 20,50,100,200 --runs 20 --out out/"
)]
pub struct SweepArgs {
    /// The filter's configuration (as for `quarry slamot`; the particle counts are the
    /// sweep's).
    #[command(flatten)]
    pub cfg: ConfigArgs<Preset>,
    /// Particle counts, comma separated.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "20,50,100,150,200,250,300,350,400,450,500,550,600"
    )]
    pub particles: Vec<usize>,
    /// Runs per particle count (the same truth seeds for every N).
    #[arg(long, default_value_t = 20)]
    pub runs: u64,
    /// First truth seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Association mode, over the configuration's (paper, s1: jpda).
    #[arg(long, value_enum)]
    pub mode: Option<ModeArg>,
    /// Built-in scenario (s1 also implies the s1 preset, as for `quarry slamot`).
    #[arg(long, value_enum, default_value_t = ScenarioArg::S0)]
    pub scenario: ScenarioArg,
    /// Output directory for sweep.csv, fig3.png and fig4.png.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// The paper's numbers, echoed in the JSON.
#[derive(Debug, Serialize)]
struct Paper {
    robot_err_mean: f64,
    robot_err_var: f64,
    target_err_mean: [f64; 3],
    target_err_var: [f64; 3],
}

fn paper() -> Paper {
    Paper {
        robot_err_mean: PAPER_ROBOT.0,
        robot_err_var: PAPER_ROBOT.1,
        target_err_mean: PAPER_TARGETS.map(|t| t.0),
        target_err_var: PAPER_TARGETS.map(|t| t.1),
    }
}

/// One run's summary.
#[derive(Debug, Serialize)]
struct RunSummary {
    seed: u64,
    robot_err_mean: f64,
    robot_err_var: f64,
    target_err_mean: Vec<f64>,
    target_err_var: Vec<f64>,
    swap_or_loss: bool,
    resample_rate: f64,
    ms_per_step: f64,
}

#[derive(Debug, Serialize)]
struct Report {
    scenario: String,
    filter: String,
    mode: String,
    particles: usize,
    runs: u64,
    robot_err_mean: f64,
    robot_err_var: f64,
    target_err_mean: Vec<f64>,
    target_err_var: Vec<f64>,
    losses: usize,
    ms_per_step: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    map_err: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    ospa: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    assoc_accuracy: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mrclam: Option<MrclamReport>,
    paper: Paper,
    per_run: Vec<RunSummary>,
    /// Stopped by Ctrl-C / SIGTERM after `runs` runs (fewer than asked for).
    interrupted: bool,
}

/// The robot and map errors of one run, the filter's or the smoother's (flattened into the
/// JSON of both).
#[derive(Debug, Clone, Serialize)]
struct PoseMapScores {
    robot_err: f64,
    robot_err_max: f64,
    ate_rmse: f64,
    ate_rmse_aligned: f64,
    map_err: f64,
    map_err_aligned: f64,
}

impl PoseMapScores {
    fn new(t: &quarry_repro::slamot::TrajectoryScore, m: &quarry_repro::slamot::MapScore) -> Self {
        Self {
            robot_err: t.mean,
            robot_err_max: t.max,
            ate_rmse: t.ate_rmse,
            ate_rmse_aligned: t.ate_rmse_aligned,
            map_err: m.mean,
            map_err_aligned: m.mean_aligned,
        }
    }
}

/// The MRCLAM scores of one run (definitions: `quarry_repro::slamot::score`, docs/slamot.md).
#[derive(Debug, Clone, Serialize)]
struct MrclamRunScores {
    seed: u64,
    #[serde(flatten)]
    pose: PoseMapScores,
    landmarks_mapped: usize,
    ospa: f64,
    gospa: f64,
    assoc_accuracy: f64,
    /// Detections of other robots that no track explained (births, misses).
    assoc_unassigned: usize,
    /// Detections of other robots.
    assoc_detections: usize,
    /// Target slots created over the run.
    slots_created: u32,
    epochs: usize,
    resamples: usize,
    neff_mean: f64,
    landmark_nis_mean: f64,
    seconds: f64,
    /// The same run refined by the batch smoother (`--smooth`).
    #[serde(skip_serializing_if = "Option::is_none")]
    smoothed: Option<SmoothedScores>,
}

/// The scores of one smoothed run.
#[derive(Debug, Clone, Serialize)]
struct SmoothedScores {
    #[serde(flatten)]
    pose: PoseMapScores,
    /// speed scale, turn-rate scale, turn-rate bias (rad/s), time offset (s)
    calibration: [f64; 4],
    iterations: usize,
    converged: bool,
    downweighted: usize,
    seconds: f64,
}

/// Every MRCLAM score: per run, and (mean, standard deviation, min, max) over runs.
#[derive(Debug, Serialize)]
struct MrclamReport {
    robot: u32,
    target_robots: Vec<u32>,
    timing: String,
    skipped: quarry_data::mrclam::MrclamSkips,
    runs: Vec<MrclamRunScores>,
    robot_err: [f64; 4],
    ate_rmse: [f64; 4],
    ate_rmse_aligned: [f64; 4],
    map_err: [f64; 4],
    gospa: [f64; 4],
    assoc_accuracy: [f64; 4],
    /// With --smooth: the smoothed runs' robot error, aligned ATE and map error spreads.
    #[serde(skip_serializing_if = "Option::is_none")]
    smoothed: Option<SmoothedSpread>,
}

/// (mean, standard deviation, min, max) over the smoothed runs.
#[derive(Debug, Serialize)]
struct SmoothedSpread {
    mode: String,
    robot_err: [f64; 4],
    robot_err_max: [f64; 4],
    ate_rmse_aligned: [f64; 4],
    map_err: [f64; 4],
}

fn spread(v: impl Iterator<Item = f64>) -> [f64; 4] {
    let v: Vec<f64> = v.collect();
    let (m, var) = mean_var(&v);
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    [m, var.sqrt(), lo, hi]
}

fn finite_mean(v: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = v.filter(|x| x.is_finite()).collect();
    mean_var(&v).0
}

fn mode_of(m: ModeArg) -> AssociationMode {
    match m {
        ModeArg::Jpda => AssociationMode::Jpda,
        ModeArg::Paper => AssociationMode::Paper,
        ModeArg::Jipda => AssociationMode::Jipda,
    }
}

/// The preset a run implies when neither --preset nor the --config file names one: the
/// scenario's (S1: [`SlamotConfig::s1`], the filter knows P_D 0.9 and the clutter rate, spec
/// §4.3 E6, and initiates targets from two points), or `mrclam` for MRCLAM runs.
fn implied_preset(scenario: ScenarioArg, mrclam: bool) -> Preset {
    match (mrclam, scenario) {
        (true, _) => Preset::Mrclam,
        (false, ScenarioArg::S0) => Preset::Paper,
        (false, ScenarioArg::S1) => Preset::S1,
    }
}

/// Whether the TOML file at `path` has a top-level `preset` key (a file that cannot be read or
/// parsed has none here: loading it reports the error).
fn file_names_preset(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.len() <= 1 << 20)
        && std::fs::read_to_string(path)
            .ok()
            .and_then(|t| t.parse::<toml::Table>().ok())
            .is_some_and(|t| t.contains_key("preset"))
}

/// The configuration of --preset / --config, validated once; the base preset is --preset, else
/// the file's `preset` key, else `implied`.
pub fn load_config(
    args: &ConfigArgs<Preset>,
    implied: Preset,
) -> Result<SlamotConfig, TrackerError> {
    let file_preset = args.config.as_deref().is_some_and(file_names_preset);
    if args.preset.is_some() || file_preset {
        return args.load();
    }
    ConfigArgs {
        preset: Some(implied),
        config: args.config.clone(),
    }
    .load()
}

/// The filter configuration for a built-in scenario: `base` with the command-line overrides
/// (validated again when overrides were given), and the scenario.
pub fn sim_config(
    base: SlamotConfig,
    particles: Option<usize>,
    mode: Option<ModeArg>,
    scenario: ScenarioArg,
    eq11: bool,
) -> Result<(SlamotConfig, SlamotScenarioConfig), TrackerError> {
    let scen = match scenario {
        ScenarioArg::S0 => SlamotScenarioConfig::s0(),
        ScenarioArg::S1 => SlamotScenarioConfig::s1(),
    };
    let cfg = overrides(base, particles, mode, eq11)?;
    Ok((cfg, scen))
}

/// `--particles`, `--mode` and `--eq11` over a configuration.
fn overrides(
    mut cfg: SlamotConfig,
    particles: Option<usize>,
    mode: Option<ModeArg>,
    eq11: bool,
) -> Result<SlamotConfig, TrackerError> {
    let any = particles.is_some() || mode.is_some() || eq11;
    if let Some(n) = particles {
        cfg.particles = n;
    }
    if let Some(m) = mode {
        cfg.association = mode_of(m);
    }
    if eq11 {
        cfg.target_weight = TargetWeight::PaperEq11;
    }
    if any {
        cfg.validate()?;
    }
    Ok(cfg)
}

fn mode_name(m: AssociationMode) -> String {
    format!("{m:?}").to_lowercase()
}

fn summarise(seed: u64, r: &SimRunResult) -> RunSummary {
    let (rm, rv) = mean_var(&r.robot_err);
    let (tm, tv): (Vec<f64>, Vec<f64>) = r.target_err.iter().map(|e| mean_var(e)).unzip();
    RunSummary {
        seed,
        robot_err_mean: rm,
        robot_err_var: rv,
        target_err_mean: tm,
        target_err_var: tv,
        swap_or_loss: r.swap_or_loss,
        resample_rate: r.resample_rate,
        ms_per_step: r.ms_per_step,
    }
}

fn avg(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { f64::NAN } else { s / n as f64 }
}

/// Runs `quarry slamot`.
pub fn run(args: &SlamotArgs, out: &Output) -> CmdResult {
    if let Some(SlamotSub::Sweep(s)) = &args.sub {
        return sweep(s, out);
    }
    if args.particles == Some(0) || args.runs == 0 {
        return Err(SlamotCmdError::Usage("--particles and --runs must be > 0").into());
    }
    if args.smooth.is_some() && args.mrclam.is_none() {
        return Err(SlamotCmdError::Usage(
            "--smooth refines a recorded MRCLAM run: give --mrclam DIR (the simulated scenarios \
             are scored on the filter alone)",
        )
        .into());
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    }
    let base = load_config(
        &args.cfg,
        implied_preset(args.scenario, args.mrclam.is_some()),
    )?;
    if let Some(dir) = &args.mrclam {
        return run_mrclam_cmd(args, base, dir, out);
    }
    let (cfg, scen) = sim_config(base, args.particles, args.mode, args.scenario, args.eq11)?;
    let mut mcap = Mcap::open(args.mcap.as_ref())?;
    crate::interrupt::install();
    let pb = progress::bar(out, args.runs, "slamot");
    let mut results = Vec::new();
    for i in 0..args.runs {
        // Ctrl-C ends the loop after the run in progress (at least one run is reported)
        if crate::interrupt::requested() {
            break;
        }
        let r = args.seed + i;
        let res = match args.filter {
            FilterArg::Rbpf => run_simulated(&cfg, &scen, r, filter_seed(r, cfg.particles))?,
            FilterArg::Ekf => run_simulated_ekf(&cfg, &scen, r)?,
        };
        if let Some(dir) = &args.out {
            write_sim_csv(dir, r, &res)?;
        }
        results.push((r, res));
        pb.inc(1);
    }
    pb.finish_and_clear();
    let per_run: Vec<RunSummary> = results.iter().map(|(r, x)| summarise(*r, x)).collect();
    if (args.out.is_some() || mcap.is_some()) && !results.is_empty() {
        // the median run by robot error is the figure run (spec §4.3 E1)
        let mut idx: Vec<usize> = (0..per_run.len()).collect();
        idx.sort_by(|a, b| {
            per_run[*a]
                .robot_err_mean
                .total_cmp(&per_run[*b].robot_err_mean)
        });
        let med = idx[idx.len() / 2];
        let frames = quarry_sim::slamot::simulate(&scen, results[med].0)?;
        if let Some(dir) = &args.out {
            plot_fig1(&dir.join("fig1.png"), &scen, &results[med].1, &frames)?;
        }
        if let Some(mut m) = mcap.take() {
            m.metadata(
                "quarry",
                &[
                    ("command", "slamot".into()),
                    ("seed", results[med].0.to_string()),
                ],
            )?;
            record::record_slamot(m, &sim_recording(&scen, &results[med].1, &frames))?;
        }
    }
    let nt = per_run.first().map_or(0, |r| r.target_err_mean.len());
    let report = Report {
        scenario: format!("{:?}", args.scenario).to_lowercase(),
        filter: format!("{:?}", args.filter).to_lowercase(),
        mode: mode_name(cfg.association),
        particles: cfg.particles,
        runs: per_run.len() as u64,
        robot_err_mean: avg(per_run.iter().map(|r| r.robot_err_mean)),
        robot_err_var: avg(per_run.iter().map(|r| r.robot_err_var)),
        target_err_mean: (0..nt)
            .map(|l| avg(per_run.iter().map(|r| r.target_err_mean[l])))
            .collect(),
        target_err_var: (0..nt)
            .map(|l| avg(per_run.iter().map(|r| r.target_err_var[l])))
            .collect(),
        losses: per_run.iter().filter(|r| r.swap_or_loss).count(),
        ms_per_step: avg(per_run.iter().map(|r| r.ms_per_step)),
        map_err: None,
        ospa: None,
        assoc_accuracy: None,
        mrclam: None,
        paper: paper(),
        per_run,
        interrupted: crate::interrupt::requested(),
    };
    out.emit(&report, || human(&report))?;
    if report.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

fn human(r: &Report) -> String {
    let mut t = Table::new([
        "object",
        "mean err (m)",
        "variance",
        "paper mean",
        "paper var",
    ]);
    t.row([
        "robot".to_string(),
        format!("{:.4}", r.robot_err_mean),
        format!("{:.4}", r.robot_err_var),
        format!("{}", PAPER_ROBOT.0),
        format!("{}", PAPER_ROBOT.1),
    ]);
    for (l, (m, v)) in r.target_err_mean.iter().zip(&r.target_err_var).enumerate() {
        let p = PAPER_TARGETS.get(l);
        t.row([
            format!("target {}", l + 1),
            format!("{m:.4}"),
            format!("{v:.4}"),
            p.map_or("-".into(), |p| format!("{}", p.0)),
            p.map_or("-".into(), |p| format!("{}", p.1)),
        ]);
    }
    let mut s = format!(
        "slamot: scenario {}, mode {}, N = {}, {} run(s){}\n",
        r.scenario,
        r.mode,
        r.particles,
        r.runs,
        if r.interrupted {
            " (interrupted: the runs completed before Ctrl-C)"
        } else {
            ""
        }
    );
    s.push_str(&t.render());
    let _ = writeln!(
        s,
        "swaps/losses after the crossing: {} of {}; {:.4} ms per control step",
        r.losses, r.runs, r.ms_per_step
    );
    if let (Some(m), Some(o), Some(a)) = (r.map_err, r.ospa, r.assoc_accuracy) {
        let _ = writeln!(
            s,
            "map error {m:.3} m, OSPA (p 2, c 1 m) {o:.3} m, association accuracy {a:.3}"
        );
    }
    s
}

fn write_sim_csv(dir: &Path, r: u64, res: &SimRunResult) -> Result<(), CmdError> {
    let mut s = String::from("t,robot_x,robot_y,robot_theta,est_x,est_y,est_theta");
    for l in 0..res.target_true.len() {
        let _ = write!(s, ",t{l}_x,t{l}_y,t{l}_est_x,t{l}_est_y");
    }
    s.push('\n');
    for k in 0..res.epoch_t.len() {
        let (a, b) = (res.robot_true[k], res.robot_est[k]);
        let _ = write!(
            s,
            "{:.3},{:.4},{:.4},{:.5},{:.4},{:.4},{:.5}",
            res.epoch_t[k], a[0], a[1], a[2], b[0], b[1], b[2]
        );
        for l in 0..res.target_true.len() {
            let (t, e) = (res.target_true[l][k], res.target_est[l][k]);
            let _ = write!(s, ",{:.4},{:.4},{:.4},{:.4}", t[0], t[1], e[0], e[1]);
        }
        s.push('\n');
    }
    let p = dir.join(format!("trajectories_run{r}.csv"));
    std::fs::write(&p, s).map_err(io_err(&p))?;
    let mut m = String::from("landmark,x,y\n");
    for (id, xy) in &res.map {
        let _ = writeln!(m, "{},{:.4},{:.4}", id.0, xy[0], xy[1]);
    }
    let p = dir.join(format!("map_run{r}.csv"));
    std::fs::write(&p, m).map_err(io_err(&p))?;
    Ok(())
}

const COLOURS: [RGBColor; 4] = [BLACK, RED, RGBColor(0, 150, 0), BLUE];

fn save_png(path: &Path, buf: Vec<u8>, w: u32, h: u32) -> Result<(), CmdError> {
    let img = image::RgbImage::from_raw(w, h, buf).ok_or("plot buffer has the wrong size")?;
    img.save(path)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

/// Fig. 1 analogue: truth dashed, estimates solid, true landmarks as crosses, estimated
/// landmarks as dots, the last epoch's landmark detections as grey segments; a caption and
/// axes in metres.
fn plot_fig1(
    path: &Path,
    scen: &SlamotScenarioConfig,
    res: &SimRunResult,
    frames: &[quarry_sim::slamot::SlamotFrame],
) -> Result<(), CmdError> {
    crate::fonts::register()?;
    let (w, h) = (900u32, 940u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption(
                "robot (black), targets (colours): truth dashed, estimate solid; landmarks: x true, dot estimated",
                ("sans-serif", 15),
            )
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..100f64, 0f64..100f64)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x (m)")
            .y_desc("y (m)")
            .draw()
            .map_err(|e| e.to_string())?;
        // last epoch's detections
        if let Some(f) = frames.iter().rev().find(|f| f.observe) {
            let p = f.truth.robot;
            for (_, z) in &f.landmark_obs {
                let q = (
                    p.x + z[0] * (p.theta + z[1]).cos(),
                    p.y + z[0] * (p.theta + z[1]).sin(),
                );
                drawn(chart.draw_series(std::iter::once(PathElement::new(
                    vec![(p.x, p.y), q],
                    RGBColor(190, 190, 190).stroke_width(1),
                ))))?;
            }
        }
        drawn(
            chart.draw_series(
                scen.landmarks
                    .iter()
                    .map(|l| Cross::new((l[0], l[1]), 6, BLACK.stroke_width(2))),
            ),
        )?;
        drawn(
            chart.draw_series(
                res.map
                    .iter()
                    .map(|(_, l)| Circle::new((l[0], l[1]), 3, MAGENTA.filled())),
            ),
        )?;
        type Xy = Vec<(f64, f64)>;
        let mut series: Vec<(Xy, Xy)> = vec![(
            res.robot_true.iter().map(|p| (p[0], p[1])).collect(),
            res.robot_est.iter().map(|p| (p[0], p[1])).collect(),
        )];
        for l in 0..res.target_true.len() {
            series.push((
                res.target_true[l].iter().map(|p| (p[0], p[1])).collect(),
                res.target_est[l]
                    .iter()
                    .filter(|p| p[0].is_finite())
                    .map(|p| (p[0], p[1]))
                    .collect(),
            ));
        }
        for (i, (t, est)) in series.into_iter().enumerate() {
            let c = COLOURS[i % COLOURS.len()];
            drawn(chart.draw_series(DashedLineSeries::new(t, 6, 5, c.stroke_width(1))))?;
            drawn(chart.draw_series(LineSeries::new(est, c.stroke_width(2))))?;
        }
        root.present().map_err(|x| x.to_string())?;
    }
    save_png(path, buf, w, h)
}

/// One point of the sweep.
#[derive(Debug, Serialize)]
struct SweepPoint {
    particles: usize,
    robot_err_mean: f64,
    robot_err_se: f64,
    target_err_mean: Vec<f64>,
    target_err_avg: f64,
    losses: usize,
    ms_per_step: f64,
}

#[derive(Debug, Serialize)]
struct SweepReport {
    scenario: String,
    mode: String,
    runs: u64,
    points: Vec<SweepPoint>,
    /// Ctrl-C / SIGTERM stopped the sweep: `points` holds the particle counts whose runs all
    /// completed (a count cut short is left out rather than averaged over fewer runs).
    interrupted: bool,
}

fn sweep(args: &SweepArgs, out: &Output) -> CmdResult {
    if args.particles.is_empty() || args.particles.contains(&0) || args.runs == 0 {
        return Err(SlamotCmdError::Usage(
            "--particles must be a list of counts > 0 and --runs > 0",
        )
        .into());
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).map_err(io_err(dir))?;
    }
    let base = load_config(&args.cfg, implied_preset(args.scenario, false))?;
    let mode = mode_name(overrides(base.clone(), None, args.mode, false)?.association);
    crate::interrupt::install();
    let pb = progress::bar(out, args.particles.len() as u64 * args.runs, "sweep");
    let mut points = Vec::new();
    'counts: for &n in &args.particles {
        let (cfg, scen) = sim_config(base.clone(), Some(n), args.mode, args.scenario, false)?;
        let mut runs = Vec::new();
        for i in 0..args.runs {
            // Ctrl-C ends the sweep after the run in progress; this count is then incomplete
            if crate::interrupt::requested() {
                break 'counts;
            }
            let r = args.seed + i;
            runs.push(summarise(
                r,
                &run_simulated(&cfg, &scen, r, filter_seed(r, n))?,
            ));
            pb.inc(1);
        }
        let rm: Vec<f64> = runs.iter().map(|r| r.robot_err_mean).collect();
        let (m, v) = mean_var(&rm);
        let nt = runs[0].target_err_mean.len();
        let tm: Vec<f64> = (0..nt)
            .map(|l| avg(runs.iter().map(|r| r.target_err_mean[l])))
            .collect();
        points.push(SweepPoint {
            particles: n,
            robot_err_mean: m,
            robot_err_se: (v * rm.len() as f64 / (rm.len().max(2) - 1) as f64 / rm.len() as f64)
                .sqrt(),
            target_err_avg: avg(tm.iter().copied()),
            target_err_mean: tm,
            losses: runs.iter().filter(|r| r.swap_or_loss).count(),
            ms_per_step: avg(runs.iter().map(|r| r.ms_per_step)),
        });
    }
    pb.finish_and_clear();
    if let Some(dir) = &args.out {
        let mut s = String::from(
            "particles,robot_err_mean,robot_err_se,t1,t2,t3,t_avg,losses,ms_per_step\n",
        );
        for p in &points {
            let t = |l: usize| p.target_err_mean.get(l).copied().unwrap_or(f64::NAN);
            let _ = writeln!(
                s,
                "{},{:.5},{:.5},{:.5},{:.5},{:.5},{:.5},{},{:.5}",
                p.particles,
                p.robot_err_mean,
                p.robot_err_se,
                t(0),
                t(1),
                t(2),
                p.target_err_avg,
                p.losses,
                p.ms_per_step
            );
        }
        let p = dir.join("sweep.csv");
        std::fs::write(&p, s).map_err(io_err(&p))?;
        plot_sweep(
            &dir.join("fig3.png"),
            &[points
                .iter()
                .map(|p| (p.particles as f64, p.robot_err_mean))
                .collect()],
            &["Fig. 3: robot position error vs particles"],
        )?;
        let mut fig4: Vec<Vec<(f64, f64)>> = (0..3)
            .map(|l| {
                points
                    .iter()
                    .map(|p| {
                        (
                            p.particles as f64,
                            p.target_err_mean.get(l).copied().unwrap_or(f64::NAN),
                        )
                    })
                    .collect()
            })
            .collect();
        fig4.push(
            points
                .iter()
                .map(|p| (p.particles as f64, p.target_err_avg))
                .collect(),
        );
        plot_sweep(
            &dir.join("fig4.png"),
            &fig4,
            &["target 1", "target 2", "target 3", "mean over targets"],
        )?;
    }
    let report = SweepReport {
        scenario: format!("{:?}", args.scenario).to_lowercase(),
        mode,
        runs: args.runs,
        points,
        interrupted: crate::interrupt::requested(),
    };
    let shown = out.emit(&report, || {
        let mut t = Table::new([
            "N",
            "robot err",
            "s.e.",
            "target 1",
            "target 2",
            "target 3",
            "avg",
            "losses",
            "ms/step",
        ]);
        for p in &report.points {
            let tt = |l: usize| {
                format!(
                    "{:.4}",
                    p.target_err_mean.get(l).copied().unwrap_or(f64::NAN)
                )
            };
            t.row([
                p.particles.to_string(),
                format!("{:.4}", p.robot_err_mean),
                format!("{:.4}", p.robot_err_se),
                tt(0),
                tt(1),
                tt(2),
                format!("{:.4}", p.target_err_avg),
                p.losses.to_string(),
                format!("{:.3}", p.ms_per_step),
            ]);
        }
        format!(
            "slamot sweep: scenario {}, mode {}, {} runs per N{}\n{}",
            report.scenario,
            report.mode,
            report.runs,
            if report.interrupted {
                " (interrupted: only the counts whose runs all completed)"
            } else {
                ""
            },
            t.render()
        )
    });
    shown?;
    if report.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

/// Error-vs-particles curves (one panel per series, 1 or 2x2, titled by `titles`), y from 0,
/// axes labelled (the numbers are also in sweep.csv).
fn plot_sweep(path: &Path, series: &[Vec<(f64, f64)>], titles: &[&str]) -> Result<(), CmdError> {
    crate::fonts::register()?;
    let (w, h) = (900u32, 700u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let panels = if series.len() == 1 {
            vec![root.clone()]
        } else {
            root.split_evenly((2, 2))
        };
        for (i, (s, area)) in series.iter().zip(panels.iter()).enumerate() {
            let xmax = s.iter().map(|p| p.0).fold(1.0, f64::max) * 1.05;
            let ymax = s
                .iter()
                .map(|p| p.1)
                .filter(|v| v.is_finite())
                .fold(0.01, f64::max)
                * 1.3;
            let mut chart = ChartBuilder::on(area)
                .margin(15)
                .caption(titles.get(i).copied().unwrap_or(""), ("sans-serif", 16))
                .x_label_area_size(35)
                .y_label_area_size(50)
                .build_cartesian_2d(0f64..xmax, 0f64..ymax)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .light_line_style(RGBColor(235, 235, 235))
                .x_desc("particles")
                .y_desc("mean position error (m)")
                .draw()
                .map_err(|e| e.to_string())?;
            let c = COLOURS[(i + usize::from(series.len() > 1)) % COLOURS.len()];
            chart
                .draw_series(LineSeries::new(s.iter().copied(), c.stroke_width(2)))
                .map_err(|e| e.to_string())?;
            chart
                .draw_series(s.iter().map(|p| Circle::new(*p, 4, c.filled())))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    save_png(path, buf, w, h)
}

fn run_mrclam_cmd(args: &SlamotArgs, base: SlamotConfig, dir: &Path, out: &Output) -> CmdResult {
    if args.filter == FilterArg::Ekf {
        return Err(SlamotCmdError::Usage(
            "--filter ekf needs a known target count; MRCLAM runs use JIPDA births and \
             deaths (the number of robots in view varies): use the RBPF",
        )
        .into());
    }
    let timing = match args.timing {
        TimingArg::Own => quarry_data::mrclam::MeasurementTiming::OwnStamp,
        TimingArg::NextOdometry => quarry_data::mrclam::MeasurementTiming::NextOdometry,
    };
    let run = quarry_data::mrclam::load_with(dir, args.robot, timing)?;
    if args.mode.is_some_and(|m| m != ModeArg::Jipda) {
        eprintln!(
            "note: MRCLAM uses JIPDA with births and deaths (the number of robots in view varies)"
        );
    }
    let mut cfg = overrides(base, args.particles, None, args.eq11)?;
    cfg.association = AssociationMode::Jipda;
    cfg.validate()?;
    let mcap = Mcap::open(args.mcap.as_ref())?;
    if let Some(d) = &args.out {
        std::fs::create_dir_all(d).map_err(io_err(d))?;
    }
    crate::interrupt::install();
    let pb = progress::bar(out, args.runs, "mrclam");
    let mut per_run = Vec::new();
    let mut extras = Vec::new();
    let mut scores = Vec::new();
    let mut results = Vec::new();
    let mut smooth_results = Vec::new();
    for i in 0..args.runs {
        // Ctrl-C ends the loop after the run in progress (at least one run is reported)
        if crate::interrupt::requested() {
            break;
        }
        let r = args.seed + i;
        let t_run = std::time::Instant::now();
        let res = run_mrclam(&cfg, &run, filter_seed(r, cfg.particles))?;
        let seconds = t_run.elapsed().as_secs_f64();
        let sm_run = match args.smooth {
            None => None,
            Some(mode) => Some(smooth_mrclam(
                &cfg,
                &run,
                &res,
                mode == SmoothArg::Calibrated,
            )?),
        };
        let smoothed = sm_run.as_ref().map(|sm| SmoothedScores {
            pose: PoseMapScores::new(&sm.trajectory, &sm.map_score),
            calibration: sm.calibration,
            iterations: sm.iterations,
            converged: sm.converged,
            downweighted: sm.downweighted,
            seconds: sm.ms / 1e3,
        });
        let (rm, rv) = mean_var(&res.robot_err);
        let (tm, tv): (Vec<f64>, Vec<f64>) = res.target_err.iter().map(|e| mean_var(e)).unzip();
        let resamples = res.resampled.iter().filter(|b| **b).count();
        per_run.push(RunSummary {
            seed: r,
            robot_err_mean: rm,
            robot_err_var: rv,
            target_err_mean: tm,
            target_err_var: tv,
            swap_or_loss: res.target_slot.iter().any(Option::is_none),
            resample_rate: resamples as f64 / res.resampled.len().max(1) as f64,
            ms_per_step: res.ms_per_step,
        });
        scores.push(MrclamRunScores {
            seed: r,
            pose: PoseMapScores::new(&res.trajectory, &res.map_score),
            landmarks_mapped: res.map_score.landmarks,
            ospa: res.ospa,
            gospa: res.gospa,
            assoc_accuracy: res.assoc_accuracy,
            assoc_unassigned: res.assoc_unassigned,
            assoc_detections: res.assoc_per_target.iter().map(|p| p.0).sum(),
            slots_created: res.slots_created,
            epochs: res.trajectory.epochs,
            resamples,
            neff_mean: finite_mean(res.neff.iter().copied()),
            landmark_nis_mean: finite_mean(res.landmark_nis.iter().map(|x| x.0)),
            seconds,
            smoothed,
        });
        extras.push((res.map_err, res.ospa, res.assoc_accuracy));
        results.push(res);
        smooth_results.push(sm_run);
        pb.inc(1);
    }
    pb.finish_and_clear();
    // the run written out and plotted: the median robot error
    let mut order: Vec<usize> = (0..results.len()).collect();
    order.sort_by(|a, b| {
        scores[*a]
            .pose
            .robot_err
            .total_cmp(&scores[*b].pose.robot_err)
    });
    if let (Some(d), Some(&med)) = (&args.out, order.get(order.len() / 2)) {
        write_mrclam_outputs(
            d,
            args.robot,
            &run,
            &results[med],
            smooth_results[med].as_ref(),
            scores[med].seed,
        )?;
    }
    if let (Some(mut m), Some(&med)) = (mcap, order.get(order.len() / 2)) {
        m.metadata(
            "quarry",
            &[
                ("command", "slamot --mrclam".into()),
                ("robot", args.robot.to_string()),
                ("seed", scores[med].seed.to_string()),
                ("t0_unix_s", format!("{:.3}", run.t0)),
            ],
        )?;
        record::record_slamot(m, &mrclam_recording(&run, &results[med]))?;
    }
    let nt = per_run.first().map_or(0, |r| r.target_err_mean.len());
    let mrclam = MrclamReport {
        robot: args.robot,
        target_robots: run.target_robots.clone(),
        timing: format!("{:?}", args.timing),
        skipped: run.skips,
        robot_err: spread(scores.iter().map(|s| s.pose.robot_err)),
        ate_rmse: spread(scores.iter().map(|s| s.pose.ate_rmse)),
        ate_rmse_aligned: spread(scores.iter().map(|s| s.pose.ate_rmse_aligned)),
        map_err: spread(scores.iter().map(|s| s.pose.map_err)),
        gospa: spread(scores.iter().map(|s| s.gospa)),
        assoc_accuracy: spread(scores.iter().map(|s| s.assoc_accuracy)),
        smoothed: args.smooth.map(|mode| {
            let sm = || scores.iter().filter_map(|s| s.smoothed.as_ref());
            SmoothedSpread {
                mode: format!("{mode:?}").to_lowercase(),
                robot_err: spread(sm().map(|s| s.pose.robot_err)),
                robot_err_max: spread(sm().map(|s| s.pose.robot_err_max)),
                ate_rmse_aligned: spread(sm().map(|s| s.pose.ate_rmse_aligned)),
                map_err: spread(sm().map(|s| s.pose.map_err)),
            }
        }),
        runs: scores,
    };
    let report = Report {
        scenario: format!(
            "mrclam robot {} (targets: robots {:?})",
            args.robot, run.target_robots
        ),
        filter: "rbpf".into(),
        mode: "jipda".into(),
        particles: cfg.particles,
        runs: per_run.len() as u64,
        robot_err_mean: avg(per_run.iter().map(|r| r.robot_err_mean)),
        robot_err_var: avg(per_run.iter().map(|r| r.robot_err_var)),
        target_err_mean: (0..nt)
            .map(|l| avg(per_run.iter().map(|r| r.target_err_mean[l])))
            .collect(),
        target_err_var: (0..nt)
            .map(|l| avg(per_run.iter().map(|r| r.target_err_var[l])))
            .collect(),
        losses: per_run.iter().filter(|r| r.swap_or_loss).count(),
        ms_per_step: avg(per_run.iter().map(|r| r.ms_per_step)),
        map_err: Some(avg(extras.iter().map(|e| e.0))),
        ospa: Some(avg(extras.iter().map(|e| e.1))),
        assoc_accuracy: Some(avg(extras.iter().map(|e| e.2))),
        mrclam: Some(mrclam),
        paper: paper(),
        per_run,
        interrupted: crate::interrupt::requested(),
    };
    out.emit(&report, || {
        let mut s = human(&report);
        if let Some(m) = &report.mrclam {
            let mut t = Table::new([
                "seed",
                "robot err (m)",
                "max",
                "ATE rmse",
                "ATE aligned",
                "map err",
                "GOSPA",
                "assoc acc",
                "resamples",
                "mean NIS (lm)",
                "s",
            ]);
            for r in &m.runs {
                t.row([
                    r.seed.to_string(),
                    format!("{:.3}", r.pose.robot_err),
                    format!("{:.3}", r.pose.robot_err_max),
                    format!("{:.3}", r.pose.ate_rmse),
                    format!("{:.3}", r.pose.ate_rmse_aligned),
                    format!("{:.3}", r.pose.map_err),
                    format!("{:.3}", r.gospa),
                    format!("{:.3}", r.assoc_accuracy),
                    format!("{}/{}", r.resamples, r.epochs),
                    format!("{:.2}", r.landmark_nis_mean),
                    format!("{:.1}", r.seconds),
                ]);
            }
            s.push_str(&t.render());
            let f = |v: [f64; 4]| format!("{:.3} ± {:.3} ({:.3}-{:.3})", v[0], v[1], v[2], v[3]);
            let _ = writeln!(
                s,
                "robot error {}\nATE rmse {} (aligned {})\nmap error {}\nGOSPA {}, association accuracy {}",
                f(m.robot_err),
                f(m.ate_rmse),
                f(m.ate_rmse_aligned),
                f(m.map_err),
                f(m.gospa),
                f(m.assoc_accuracy)
            );
            if let Some(sm) = &m.smoothed {
                let mut t = Table::new([
                    "seed",
                    "smoothed robot err (m)",
                    "max",
                    "ATE aligned",
                    "map err",
                    "v scale",
                    "ω scale",
                    "ω bias (rad/s)",
                    "offset (s)",
                    "iterations",
                    "s",
                ]);
                for r in &m.runs {
                    if let Some(x) = &r.smoothed {
                        t.row([
                            r.seed.to_string(),
                            format!("{:.3}", x.pose.robot_err),
                            format!("{:.3}", x.pose.robot_err_max),
                            format!("{:.3}", x.pose.ate_rmse_aligned),
                            format!("{:.3}", x.pose.map_err),
                            format!("{:.4}", x.calibration[0]),
                            format!("{:.4}", x.calibration[1]),
                            format!("{:.4}", x.calibration[2]),
                            format!("{:.3}", x.calibration[3]),
                            format!("{}{}", x.iterations, if x.converged { "" } else { " (limit)" }),
                            format!("{:.2}", x.seconds),
                        ]);
                    }
                }
                s.push_str(&t.render());
                let _ = writeln!(
                    s,
                    "smoothed ({}): robot error {}, max {}\nATE aligned {}, map error {}",
                    sm.mode,
                    f(sm.robot_err),
                    f(sm.robot_err_max),
                    f(sm.ate_rmse_aligned),
                    f(sm.map_err)
                );
            }
            let _ = writeln!(
                s,
                "(target k = robot {:?}[k]; measurement timing {}; paper columns are the paper's \
                 simulation, for reference)\nskipped records: {}",
                m.target_robots, m.timing, m.skipped
            );
        }
        s
    })?;
    if report.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

fn pose_of(p: [f64; 3]) -> Pose2 {
    Pose2 {
        x: p[0],
        y: p[1],
        theta: p[2],
    }
}

/// A simulated run as a recording (target ids = slots; landmark ids as in the map).
fn sim_recording(
    scen: &quarry_sim::slamot::SlamotScenarioConfig,
    res: &SimRunResult,
    frames: &[quarry_sim::slamot::SlamotFrame],
) -> SlamotRecording {
    let epochs = 0..res.epoch_t.len();
    let slot = |v: &Vec<Vec<[f64; 2]>>, k: usize| -> Vec<Track> {
        v.iter()
            .enumerate()
            .map(|(l, s)| record::planar_track(l as u32, s[k][0], s[k][1], 0.0, 0.0))
            .collect()
    };
    SlamotRecording {
        odometry: frames
            .iter()
            .map(|f| (f.t, f.odometry.0, f.odometry.1))
            .collect(),
        poses: epochs
            .clone()
            .map(|k| {
                (
                    res.epoch_t[k],
                    pose_of(res.robot_est[k]),
                    Some(pose_of(res.robot_true[k])),
                )
            })
            .collect(),
        targets: epochs
            .clone()
            .map(|k| (res.epoch_t[k], slot(&res.target_est, k)))
            .collect(),
        targets_truth: epochs
            .map(|k| (res.epoch_t[k], slot(&res.target_true, k)))
            .collect(),
        map: res.map.iter().map(|(id, p)| (id.0, *p)).collect(),
        landmarks_truth: scen
            .landmarks
            .iter()
            .enumerate()
            .map(|(i, p)| (i as u32, *p))
            .collect(),
    }
}

/// An MRCLAM run as a recording (target ids = track slots, truth ids = subject numbers of the
/// robots; landmark ids = subject numbers, as in the CSVs).
fn mrclam_recording(
    run: &quarry_data::mrclam::MrclamRun,
    res: &quarry_repro::slamot::MrclamResult,
) -> SlamotRecording {
    let mut targets: Vec<(f64, Vec<Track>)> = Vec::new();
    for r in &res.tracks {
        let p = Track {
            existence: r.existence,
            ..record::planar_track(r.id.0, r.state[0], r.state[1], r.state[2], r.state[3])
        };
        match targets.last_mut() {
            Some((t, v)) if *t == r.t => v.push(p),
            _ => targets.push((r.t, vec![p])),
        }
    }
    SlamotRecording {
        odometry: run
            .frames
            .iter()
            .map(|f| (f.t, f.odometry.0, f.odometry.1))
            .collect(),
        poses: (0..res.epoch_t.len())
            .map(|k| {
                (
                    res.epoch_t[k],
                    pose_of(res.robot_est[k]),
                    Some(pose_of(res.robot_true[k])),
                )
            })
            .collect(),
        targets,
        targets_truth: run
            .frames
            .iter()
            .filter(|f| f.observe)
            .map(|f| {
                let v = f
                    .truth
                    .targets
                    .iter()
                    .zip(&run.target_robots)
                    .filter_map(|(p, id)| {
                        p.map(|p| record::planar_track(*id, p[0], p[1], 0.0, 0.0))
                    })
                    .collect();
                (f.t, v)
            })
            .collect(),
        map: res.map.iter().map(|(id, p)| (id.0 + 6, *p)).collect(),
        landmarks_truth: run.landmarks.iter().map(|(id, p)| (id.0 + 6, *p)).collect(),
    }
}

/// Writes the trajectory, map, tracks and per-epoch diagnostics as CSV, and the plot.
fn write_mrclam_outputs(
    d: &Path,
    robot: u32,
    run: &quarry_data::mrclam::MrclamRun,
    res: &quarry_repro::slamot::MrclamResult,
    smoothed: Option<&quarry_repro::slamot::MrclamSmoothed>,
    seed: u64,
) -> Result<(), CmdError> {
    let mut s = String::from(
        "t,robot_x,robot_y,robot_theta,est_x,est_y,est_theta,err,neff,resampled,landmark_nis,landmark_updates\n",
    );
    for k in 0..res.epoch_t.len() {
        let (a, b) = (res.robot_true[k], res.robot_est[k]);
        let _ = writeln!(
            s,
            "{:.3},{:.4},{:.4},{:.5},{:.4},{:.4},{:.5},{:.4},{:.2},{},{:.3},{}",
            res.epoch_t[k],
            a[0],
            a[1],
            a[2],
            b[0],
            b[1],
            b[2],
            res.robot_err[k],
            res.neff[k],
            u8::from(res.resampled[k]),
            res.landmark_nis[k].0,
            res.landmark_nis[k].1
        );
    }
    let p = d.join(format!("mrclam_robot{robot}_trajectory.csv"));
    std::fs::write(&p, s).map_err(io_err(&p))?;
    let p = d.join(format!("mrclam_robot{robot}_map.csv"));
    std::fs::write(&p, map_csv(run, &res.map)).map_err(io_err(&p))?;
    if let Some(sm) = smoothed {
        let mut s = String::from("t,robot_x,robot_y,robot_theta,est_x,est_y,est_theta,err\n");
        for k in 0..sm.robot_est.len().min(res.epoch_t.len()) {
            let (a, b) = (res.robot_true[k], sm.robot_est[k]);
            let _ = writeln!(
                s,
                "{:.3},{:.4},{:.4},{:.5},{:.4},{:.4},{:.5},{:.4}",
                res.epoch_t[k], a[0], a[1], a[2], b[0], b[1], b[2], sm.robot_err[k]
            );
        }
        let p = d.join(format!("mrclam_robot{robot}_smoothed_trajectory.csv"));
        std::fs::write(&p, s).map_err(io_err(&p))?;
        let p = d.join(format!("mrclam_robot{robot}_smoothed_map.csv"));
        std::fs::write(&p, map_csv(run, &sm.map)).map_err(io_err(&p))?;
    }
    let mut tr = String::from("t,track,x,y,vx,vy,existence\n");
    for r in &res.tracks {
        let _ = writeln!(
            tr,
            "{:.3},{},{:.4},{:.4},{:.4},{:.4},{:.3}",
            r.t, r.id.0, r.state[0], r.state[1], r.state[2], r.state[3], r.existence
        );
    }
    let p = d.join(format!("mrclam_robot{robot}_tracks.csv"));
    std::fs::write(&p, tr).map_err(io_err(&p))?;
    plot_mrclam(
        &d.join(format!("mrclam_robot{robot}.png")),
        run,
        res,
        smoothed,
        &format!(
            "MRCLAM robot {robot}, seed {seed}: Vicon dashed black, filter red{}, tracks dots; landmarks x true, dot estimated",
            if smoothed.is_some() {
                ", smoothed blue"
            } else {
                ""
            }
        ),
    )
}

/// A landmark map as CSV: subject number, estimate, truth (NaN where the recording has none).
fn map_csv(
    run: &quarry_data::mrclam::MrclamRun,
    map: &[(quarry_core::LandmarkId, [f64; 2])],
) -> String {
    let mut m = String::from("landmark_subject,x,y,true_x,true_y\n");
    for (id, xy) in map {
        let t = run
            .landmarks
            .iter()
            .find(|(i, _)| i == id)
            .map_or([f64::NAN; 2], |l| l.1);
        let _ = writeln!(
            m,
            "{},{:.4},{:.4},{:.4},{:.4}",
            id.0 + 6,
            xy[0],
            xy[1],
            t[0],
            t[1]
        );
    }
    m
}

/// The estimate over the Vicon truth: robot truth dashed, estimate solid (the smoothed one in
/// blue when there is one), target tracks as dots, true landmarks as crosses, estimated
/// landmarks as filled dots.
fn plot_mrclam(
    path: &Path,
    run: &quarry_data::mrclam::MrclamRun,
    res: &quarry_repro::slamot::MrclamResult,
    smoothed: Option<&quarry_repro::slamot::MrclamSmoothed>,
    caption: &str,
) -> Result<(), CmdError> {
    crate::fonts::register()?;
    let pts = res
        .robot_true
        .iter()
        .chain(&res.robot_est)
        .map(|p| [p[0], p[1]])
        .chain(run.landmarks.iter().map(|l| l.1))
        .chain(res.map.iter().map(|l| l.1));
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in pts.filter(|p| p[0].is_finite() && p[1].is_finite()) {
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    let pad = 0.5;
    let (x0, x1, y0, y1) = (x0 - pad, x1 + pad, y0 - pad, y1 + pad);
    let w = 1100u32;
    let h = ((f64::from(w - 60) * (y1 - y0) / (x1 - x0)) as u32 + 100).clamp(300, 1400);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption(caption, ("sans-serif", 14))
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
        let palette = [
            RGBColor(0, 150, 0),
            BLUE,
            RGBColor(200, 120, 0),
            RGBColor(140, 0, 160),
            RGBColor(0, 150, 150),
        ];
        drawn(
            chart.draw_series(
                res.tracks
                    .iter()
                    .filter(|r| (x0..=x1).contains(&r.state[0]) && (y0..=y1).contains(&r.state[1]))
                    .map(|r| {
                        let c = palette[r.id.0 as usize % palette.len()];
                        Circle::new((r.state[0], r.state[1]), 1, c.mix(0.35).filled())
                    }),
            ),
        )?;
        drawn(
            chart.draw_series(
                run.landmarks
                    .iter()
                    .map(|l| Cross::new((l.1[0], l.1[1]), 6, BLACK.stroke_width(2))),
            ),
        )?;
        drawn(
            chart.draw_series(
                res.map
                    .iter()
                    .map(|(_, l)| Circle::new((l[0], l[1]), 4, MAGENTA.filled())),
            ),
        )?;
        let truth: Vec<(f64, f64)> = res.robot_true.iter().map(|p| (p[0], p[1])).collect();
        let est: Vec<(f64, f64)> = res.robot_est.iter().map(|p| (p[0], p[1])).collect();
        drawn(chart.draw_series(DashedLineSeries::new(truth, 6, 5, BLACK.stroke_width(1))))?;
        drawn(chart.draw_series(LineSeries::new(est, RED.stroke_width(2))))?;
        if let Some(sm) = smoothed {
            let est: Vec<(f64, f64)> = sm.robot_est.iter().map(|p| (p[0], p[1])).collect();
            drawn(chart.draw_series(LineSeries::new(est, BLUE.stroke_width(2))))?;
            drawn(
                chart.draw_series(
                    sm.map
                        .iter()
                        .map(|(_, l)| Circle::new((l[0], l[1]), 4, BLUE.filled())),
                ),
            )?;
        }
        root.present().map_err(|x| x.to_string())?;
    }
    save_png(path, buf, w, h)
}

/// A plotters drawing result as the CLI's error (the drawn element is not needed).
fn drawn<T, E: std::fmt::Display>(r: Result<T, E>) -> Result<(), String> {
    r.map(|_| ()).map_err(|x| x.to_string())
}

/// The `quarry demo` row: S0, one run, N = 50, robot and target errors next to the paper's.
pub fn demo_rows(seed: u64) -> Result<Vec<super::demo::Row>, CmdError> {
    let (cfg, scen) = sim_config(
        SlamotConfig::preset(Preset::Paper),
        Some(50),
        Some(ModeArg::Jpda),
        ScenarioArg::S0,
        false,
    )?;
    let res = run_simulated(&cfg, &scen, seed, filter_seed(seed, 50))?;
    let s = summarise(seed, &res);
    let scenario = "S0 (spec 000), N 50, 1 run".to_string();
    let mut rows = vec![super::demo::Row {
        tracker: "slamot".into(),
        scenario: scenario.clone(),
        metric: "robot mean error (m)".into(),
        value: s.robot_err_mean,
        paper: Some(PAPER_ROBOT.0),
        ms_per_frame: Some(s.ms_per_step),
    }];
    for (l, m) in s.target_err_mean.iter().enumerate() {
        rows.push(super::demo::Row {
            tracker: "slamot".into(),
            scenario: scenario.clone(),
            metric: format!("target {} mean error (m)", l + 1),
            value: *m,
            paper: PAPER_TARGETS.get(l).map(|p| p.0),
            ms_per_frame: Some(s.ms_per_step),
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(preset: Option<Preset>, config: Option<PathBuf>) -> ConfigArgs<Preset> {
        ConfigArgs { preset, config }
    }

    #[test]
    fn the_run_implies_the_preset_unless_told_otherwise() {
        assert_eq!(implied_preset(ScenarioArg::S0, false), Preset::Paper);
        assert_eq!(implied_preset(ScenarioArg::S1, false), Preset::S1);
        assert_eq!(implied_preset(ScenarioArg::S1, true), Preset::Mrclam);
        // --scenario s1 alone: the S1 configuration, as before --preset existed
        let c = load_config(&args(None, None), Preset::S1).unwrap();
        assert_eq!(c, SlamotConfig::s1());
        // --preset wins over the scenario
        let c = load_config(&args(Some(Preset::Paper), None), Preset::S1).unwrap();
        assert_eq!(c, SlamotConfig::default());
        let dir = std::env::temp_dir().join(format!("quarry-slamot-cli-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // a file without a preset key lies over the implied preset
        let f = dir.join("n.toml");
        std::fs::write(&f, "particles = 20\n").unwrap();
        let c = load_config(&args(None, Some(f.clone())), Preset::S1).unwrap();
        assert_eq!(
            c,
            SlamotConfig {
                particles: 20,
                ..SlamotConfig::s1()
            }
        );
        // the file's preset key wins over the implied one
        let g = dir.join("p.toml");
        std::fs::write(&g, "preset = \"paper\"\nparticles = 30\n").unwrap();
        let c = load_config(&args(None, Some(g)), Preset::S1).unwrap();
        assert_eq!(c.particles, 30);
        assert_eq!(c.p_detect, SlamotConfig::default().p_detect);
        // a typo is an error naming the key
        let t = dir.join("t.toml");
        std::fs::write(&t, "particels = 20\n").unwrap();
        let e = load_config(&args(None, Some(t)), Preset::Paper).unwrap_err();
        assert!(e.to_string().contains("particels"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn flags_apply_over_the_configuration() {
        let (c, _) = sim_config(SlamotConfig::s1(), None, None, ScenarioArg::S1, false).unwrap();
        assert_eq!(c, SlamotConfig::s1());
        let (c, _) = sim_config(
            SlamotConfig::s1(),
            Some(20),
            Some(ModeArg::Paper),
            ScenarioArg::S1,
            true,
        )
        .unwrap();
        assert_eq!(
            c,
            SlamotConfig {
                particles: 20,
                association: AssociationMode::Paper,
                target_weight: TargetWeight::PaperEq11,
                ..SlamotConfig::s1()
            }
        );
        // an override that breaks a rule of validate() is an error
        assert!(overrides(SlamotConfig::mrclam(), None, Some(ModeArg::Jpda), false).is_err());
    }
}
