//! `quarry rgbd`: RGB-D person tracking (paper 001) on a synthetic scenario or a Princeton
//! Tracking Benchmark sequence.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;
use image::{Rgb, RgbImage};
use quarry_core::{BBox, EgoMotion, PinholeIntrinsics, Plane, SingleTargetTracker, Stamp};
use quarry_data::ptb::{DepthFormat, PtbSequence, depth_metres};
use quarry_repro::rgbd::{OdometryFeed, ScenarioSummary, run_scenario_frames};
use quarry_sim::rgbd::{RgbdScene, ScenarioId};
use quarry_trackers::rgbd_person::{
    OcclusionState, Preset, RgbdPersonConfig, RgbdPersonTracker, TrackOutput,
};
use quarry_trackers::{PresetName, TrackerError};
use quarry_vision::RgbdFrame;
use serde::Serialize;

use crate::config_args::ConfigArgs;
use crate::output::{CmdError, CmdResult, Output, fmt_opt};

/// Arguments of `quarry rgbd`.
#[derive(Debug, Args)]
#[command(
    about = "RGB-D person tracking with patch multi-cue descriptors and the MEKF (paper 001)",
    long_about = "RGB-D person tracking of spec 001 (Wang et al. 2016): N x N patch hue + LBP \
histograms masked by a depth band, tiered selection with occlusion states, online template \
update, and an ego-motion compensated EKF (MEKF) whose prediction is a candidate and the \
output during full occlusion.

Input: either a built-in synthetic scenario (--scenario s1..s6, --seed; ground truth known) or \
a sequence in the Princeton Tracking Benchmark layout (--sequence DIR): DIR/rgb/*.png and \
DIR/depth/*.png paired by the last integer in the file name, depth 16-bit with PTB's 3-bit \
circular shift (--depth-format ptb, the default) or plain millimetres (--depth-format mm); the \
first box from --init x,y,w,h (top-left, pixels) or DIR/init.txt. Without odometry the MEKF \
runs with no ego-motion. Real sequences use the default Kinect intrinsics (f = 525 px, the \
principal point moved to the frame's centre) unless --config sets them in an [intrinsics] table; \
intrinsics that --config sets must have the frames' width and height, or the run stops with an \
error.

Configuration: --preset NAME picks a named configuration (default paper; the list is under \
--preset: the paper, strict, the whole-target baseline and the one-switch ablations of spec \
5.5). --config FILE.toml reads a TOML RgbdPersonConfig laid over the preset: keys missing from \
the file keep the preset's values, a `preset = \"name\"` key in the file picks the preset, and \
unknown keys or tables are errors. --baseline is the older spelling of --preset baseline (with \
--config, the file is laid over the baseline preset).

Recording (--mcap FILE): /camera/color and /camera/depth (PNG CompressedImage; depth in 16-bit \
mm), /detections (the tracked box, Detection2DArray, id 1, score 1 = detection, 0 = prediction) \
and, in the synthetic scenarios, /ground_truth/detections, /odom (TwistStamped v, omega) and \
/ground_truth/pose: ROS 2 CDR with the schemas embedded, for Foxglove, ros2 bag and Rerun.

Output: with --out DIR, boxes.txt in MOTChallenge form (frame,id,x,y,w,h,conf,-1,-1,-1; \
1-based frames; conf 1 for a detection, 0 for a prediction) and frames/NNNNNN.png annotated \
(green = accepted detection, yellow = partial / severe occlusion, red = MEKF prediction).

With --sequence, Ctrl-C (or SIGTERM) stops after the current frame: boxes.txt and the frames so \
far are written, the report says \"interrupted\": true and the exit status is 130.

JSON (--json): {scenario|sequence, preset, frames, center_err_px, success_rate_iou50, \
recovery_frames, ms_per_frame, summary, interrupted}; the accuracy fields are null without ground \
truth (recovery_frames is null when never recovered).

EXAMPLE:
  quarry rgbd --scenario s1 --seed 0
  quarry rgbd --scenario s1 --baseline --json
  quarry rgbd --scenario s6 --preset no-ego
  quarry rgbd --sequence ptb/child_no1 --init 232,145,80,200 --out res/
  quarry rgbd --scenario s3 --frames 60 --mcap s3.mcap"
)]
pub struct RgbdArgs {
    /// Synthetic scenario: s1..s6 or its full name.
    #[arg(long, default_value = "s1", conflicts_with = "sequence")]
    pub scenario: String,
    /// Seed of the synthetic scenario.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// A sequence directory in the Princeton Tracking Benchmark layout.
    #[arg(long, value_name = "DIR")]
    pub sequence: Option<PathBuf>,
    /// Initial box x,y,w,h (top-left corner, pixels) for --sequence.
    #[arg(long, value_name = "x,y,w,h")]
    pub init: Option<String>,
    /// Depth PNG encoding of --sequence: ptb (3-bit circular shift) or mm.
    #[arg(long, default_value = "ptb")]
    pub depth_format: String,
    /// Run the whole-target baseline: the same as --preset baseline.
    #[arg(long, conflicts_with = "preset")]
    pub baseline: bool,
    // --preset NAME and --config FILE.toml (laid over the preset)
    #[command(flatten)]
    pub cfg: ConfigArgs<Preset>,
    /// Feed the synthetic run the noisy odometry (5 % proportional).
    #[arg(long)]
    pub noisy_odometry: bool,
    /// Synthetic scenarios: process only the first N frames (frame 0, the initialisation,
    /// included; a quick look, or a short recording with --mcap); the scores cover those frames.
    /// Default: the whole scenario.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..), conflicts_with = "sequence")]
    pub frames: Option<u32>,
    /// Output directory for boxes.txt and annotated frames.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Record the run as MCAP (ROS 2 CDR): colour and depth frames, the tracked box, ground
    /// truth and odometry where known.
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
}

/// `--mcap`: what one frame of the run records. Colour on `/camera/color` and depth (16-bit
/// millimetres, 0 = no reading) on `/camera/depth`, both PNG `CompressedImage`s in frame
/// `camera`; the tracked box on `/detections` (`Detection2DArray`, id `1`, score 1 for an
/// accepted detection and 0 for a prediction, none while lost); and in the synthetic scenarios
/// `/ground_truth/detections` (the amodal box), `/odom` (the robot's v, ω: the tracker's
/// ego-motion input) and `/ground_truth/pose` (the robot's pose in `map`).
struct RgbdRecorder {
    m: crate::record::Mcap,
}

/// Per frame: the stamp, the colour pixels (RGB8) and the depth (m).
struct RecFrame<'a> {
    t: quarry_core::TimeUs,
    w: u32,
    h: u32,
    rgb: &'a [u8],
    depth: &'a Plane<f32>,
}

impl RgbdRecorder {
    fn frame(
        &mut self,
        f: &RecFrame<'_>,
        tracked: Option<(BBox, bool)>,
        truth: Option<&quarry_sim::rgbd::FrameTruth>,
    ) -> Result<(), CmdError> {
        use crate::record::{detections, png_image};
        let t = f.t;
        let colour = png_image(t, "camera", f.rgb, f.w, f.h, image::ExtendedColorType::Rgb8)?;
        self.m.write("/camera/color", t, &colour)?;
        let mm: Vec<u8> = f
            .depth
            .data
            .iter()
            .flat_map(|&d| {
                let v = if d.is_finite() && d > 0.0 {
                    (d * 1000.0).round().min(65_535.0) as u16
                } else {
                    0
                };
                v.to_ne_bytes()
            })
            .collect();
        let depth = png_image(t, "camera", &mm, f.w, f.h, image::ExtendedColorType::L16)?;
        self.m.write("/camera/depth", t, &depth)?;
        let det =
            tracked.map(|(b, conf)| ("1".to_string(), b.to_ltwh(), f64::from(u8::from(conf))));
        self.m
            .write("/detections", t, &detections(t, "camera", det.into_iter()))?;
        if let Some(g) = truth {
            let gt = g.amodal.map(|b| ("1".to_string(), b.to_ltwh(), 1.0));
            self.m.write(
                "/ground_truth/detections",
                t,
                &detections(t, "camera", gt.into_iter()),
            )?;
            let odom = quarry_ros2::msgs::TwistStamped::planar(
                crate::record::time(t),
                "base_link",
                g.v,
                g.omega,
            );
            self.m.write("/odom", t, &odom)?;
            let p = g.robot_pose;
            let pose = quarry_ros2::msgs::PoseStamped {
                header: quarry_ros2::msgs::Header::new(crate::record::time(t), "map"),
                pose: quarry_ros2::msgs::Pose::planar(p.x, p.y, p.theta),
            };
            self.m.write("/ground_truth/pose", t, &pose)?;
        }
        Ok(())
    }
}

#[derive(Debug, Serialize)]
struct Report {
    scenario: Option<String>,
    sequence: Option<String>,
    preset: &'static str,
    frames: usize,
    center_err_px: Option<f64>,
    success_rate_iou50: Option<f64>,
    recovery_frames: Option<usize>,
    ms_per_frame: f64,
    summary: Option<ScenarioSummary>,
    /// With --mcap: the recording.
    #[serde(skip_serializing_if = "Option::is_none")]
    mcap: Option<crate::record::McapInfo>,
    /// Stopped by Ctrl-C / SIGTERM (`frames` is then the number processed).
    interrupted: bool,
}

fn parse_box(s: &str) -> Result<BBox, CmdError> {
    Ok(quarry_data::ptb::parse_box(s)?)
}

/// Reads one depth PNG (u16) into metres.
fn load_depth(p: &Path, format: DepthFormat) -> Result<Plane<f32>, CmdError> {
    let img = quarry_vision::io::open_image(p)?.to_luma16();
    let (w, h) = img.dimensions();
    Ok(depth_metres(&img.into_raw(), w, h, format)?)
}

fn colour(o: &TrackOutput) -> Rgb<u8> {
    match o.state {
        OcclusionState::Normal | OcclusionState::AppearanceChange => Rgb([0, 230, 0]),
        OcclusionState::PartialOcclusion | OcclusionState::SevereOcclusion => Rgb([240, 220, 0]),
        _ => Rgb([230, 0, 0]),
    }
}

#[allow(clippy::cast_possible_truncation)]
fn draw(img: &mut RgbImage, b: &BBox, c: Rgb<u8>, gt: Option<&BBox>) {
    let rect = |img: &mut RgbImage, b: &BBox, c: Rgb<u8>| {
        let (l, t, r, bo) = (
            b.left() as i64,
            b.top() as i64,
            b.right() as i64,
            b.bottom() as i64,
        );
        for (a, z) in [
            ((l, t), (r, t)),
            ((r, t), (r, bo)),
            ((r, bo), (l, bo)),
            ((l, bo), (l, t)),
        ] {
            quarry_vision::render::draw_line(img, a, z, c);
        }
    };
    if let Some(g) = gt {
        rect(img, g, Rgb([255, 255, 255]));
    }
    rect(img, b, c);
}

struct Writer {
    dir: PathBuf,
    mot: String,
}

impl Writer {
    fn new(dir: &Path) -> Result<Self, CmdError> {
        std::fs::create_dir_all(dir.join("frames"))
            .map_err(|e| format!("{}: {e}", dir.display()))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            mot: String::new(),
        })
    }
    fn line(&mut self, k: usize, b: &BBox, conf: bool) {
        let [x, y, bw, bh] = b.to_ltwh();
        let _ = writeln!(
            self.mot,
            "{},1,{x:.2},{y:.2},{bw:.2},{bh:.2},{},-1,-1,-1",
            k + 1,
            u8::from(conf)
        );
    }
    /// The initialisation frame: the given box, conf 1 (the first line of `boxes.txt`).
    fn init_frame(
        &mut self,
        k: usize,
        w: u32,
        h: u32,
        rgb: &[u8],
        init: &BBox,
    ) -> Result<(), CmdError> {
        self.line(k, init, true);
        let mut img = RgbImage::from_raw(w, h, rgb.to_vec()).ok_or("RGB buffer size")?;
        draw(&mut img, init, Rgb([0, 230, 0]), None);
        img.save(self.dir.join(format!("frames/{:06}.png", k + 1)))?;
        Ok(())
    }
    fn frame(
        &mut self,
        k: usize,
        w: u32,
        h: u32,
        rgb: &[u8],
        o: &TrackOutput,
        gt: Option<&BBox>,
    ) -> Result<(), CmdError> {
        if let Some(b) = o.bbox {
            self.line(k, &b, o.confirmed);
        }
        let mut img = RgbImage::from_raw(w, h, rgb.to_vec()).ok_or("RGB buffer size")?;
        if let Some(b) = o.bbox {
            draw(&mut img, &b, colour(o), gt);
        }
        img.save(self.dir.join(format!("frames/{:06}.png", k + 1)))?;
        Ok(())
    }
    fn finish(&self) -> Result<(), CmdError> {
        std::fs::write(self.dir.join("boxes.txt"), &self.mot)?;
        Ok(())
    }
}

/// Whether the `--config` file sets the camera intrinsics itself (an `[intrinsics]` table):
/// then they must match the frames; otherwise the default intrinsics are fitted to them.
fn intrinsics_given(args: &RgbdArgs) -> Result<bool, CmdError> {
    let Some(path) = &args.cfg.config else {
        return Ok(false);
    };
    // the file was read and validated by `config` already (1 MiB cap), so this cannot grow
    let text = std::fs::read_to_string(path).map_err(crate::output::at(path))?;
    let table: toml::Table = text
        .parse()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(table.contains_key("intrinsics"))
}

/// The intrinsics of a real sequence of `w` x `h` frames: the configured ones, which must be
/// for that size when the config file set them, or the default focal length with the
/// principal point at the frame's centre.
fn sequence_intrinsics(
    cfg: &RgbdPersonConfig,
    given: bool,
    w: u32,
    h: u32,
) -> Result<PinholeIntrinsics, CmdError> {
    let mut k = cfg.intrinsics;
    if (k.width, k.height) == (w, h) {
        return Ok(k);
    }
    if given {
        return Err(format!(
            "the [intrinsics] of --config are for {}x{} frames but the sequence's frames are \
             {w}x{h}: set width = {w} and height = {h} (and the focal length and principal \
             point of the camera that recorded them)",
            k.width, k.height
        )
        .into());
    }
    k.width = w;
    k.height = h;
    k.cx = (f64::from(w) - 1.0) / 2.0;
    k.cy = (f64::from(h) - 1.0) / 2.0;
    Ok(k)
}

/// The configuration of `--preset` / `--baseline` and `--config`, validated.
fn config(args: &RgbdArgs) -> Result<RgbdPersonConfig, TrackerError> {
    let mut flags = args.cfg.clone();
    if args.baseline {
        flags.preset = Some(Preset::Baseline);
    }
    flags.load()
}

/// What the human-readable line calls the tracker.
fn tracker_name(cfg: &RgbdPersonConfig) -> String {
    let kind = if cfg.baseline {
        "whole-target baseline"
    } else {
        "patch multi-cue"
    };
    match cfg.preset {
        Preset::Paper | Preset::Baseline => kind.to_owned(),
        p => format!("{kind}, preset {}", p.name()),
    }
}

/// Runs `quarry rgbd`.
pub fn run(args: &RgbdArgs, out: &Output) -> CmdResult {
    let cfg = config(args)?;
    if let Some(dir) = &args.sequence {
        return run_sequence(args, dir, &cfg, out);
    }
    let id = ScenarioId::from_name(&args.scenario)?;
    let scene = RgbdScene::new(id, args.seed)?;
    let mut writer = args.out.as_deref().map(Writer::new).transpose()?;
    let mut rec = crate::record::Mcap::open(args.mcap.as_ref())?.map(|m| RgbdRecorder { m });
    if writer.is_some() || rec.is_some() {
        // frame 0 is the initialisation frame (the tracker starts on frame 0's amodal box)
        let f0 = scene.render(0)?;
        if let (Some(w), Some(b)) = (writer.as_mut(), f0.truth.amodal) {
            w.init_frame(0, 640, 480, &f0.rgb, &b)?;
        }
        if let Some(r) = rec.as_mut() {
            let f = RecFrame {
                t: quarry_core::TimeUs::from_secs_f64(f0.truth.t),
                w: 640,
                h: 480,
                rgb: &f0.rgb,
                depth: &f0.depth_m,
            };
            r.frame(&f, f0.truth.amodal.map(|b| (b, true)), Some(&f0.truth))?;
        }
    }
    let mut werr: Option<CmdError> = None;
    let odo = if args.noisy_odometry {
        OdometryFeed::Noisy
    } else {
        OdometryFeed::Exact
    };
    let n_frames = args.frames.map_or(scene.len(), |n| n as usize);
    let (s, recs) = run_scenario_frames(&scene, args.seed, &cfg, odo, n_frames, |smp, o| {
        if let Some(w) = writer.as_mut()
            && werr.is_none()
            && let Err(e) = w.frame(
                smp.truth.frame,
                640,
                480,
                &smp.rgb,
                o,
                smp.truth.amodal.as_ref(),
            )
        {
            werr = Some(e);
        }
        if let Some(r) = rec.as_mut()
            && werr.is_none()
        {
            let f = RecFrame {
                t: quarry_core::TimeUs::from_secs_f64(smp.truth.t),
                w: 640,
                h: 480,
                rgb: &smp.rgb,
                depth: &smp.depth_m,
            };
            if let Err(e) = r.frame(&f, o.bbox.map(|b| (b, o.confirmed)), Some(&smp.truth)) {
                werr = Some(e);
            }
        }
    })?;
    if let Some(e) = werr {
        return Err(e);
    }
    if let Some(w) = &writer {
        w.finish()?;
    }
    let rep = Report {
        scenario: Some(id.name().into()),
        sequence: None,
        preset: cfg.preset.name(),
        frames: recs.len() + 1,
        center_err_px: Some(s.center_err_px),
        success_rate_iou50: Some(s.success_rate_iou50),
        recovery_frames: s.recovery_frames,
        ms_per_frame: s.ms_per_frame,
        summary: Some(s.clone()),
        mcap: rec.map(|r| r.m.finish()).transpose()?,
        interrupted: false,
    };
    out.emit(&rep, || {
        format!(
            "{} seed {} ({}): success@0.5 {:.3}, centre error {:.1} px, recovery {}, \
             updates at visibility < 0.6: {}, occlusion recall {}, 3-D RMSE {:.3} m, lost frames {}, \
             distractor frames {}, S6 blackout-end error {}, template drift score {}, \
             height within 10 % {}, {:.1} ms/frame\n",
            id.name(),
            args.seed,
            tracker_name(&cfg),
            s.success_rate_iou50,
            s.center_err_px,
            s.recovery_frames.map_or("never".into(), |r| format!("{r} frames")),
            s.updates_low_visibility,
            fmt_opt(s.occlusion_recall, 3),
            s.rmse_3d_m,
            s.lost_frames,
            s.distractor_frames,
            fmt_opt(s.blackout_end_err_px, 1),
            fmt_opt(s.drift_score, 3),
            fmt_opt(s.height_within_10pct, 3),
            s.ms_per_frame
        )
    })
}

#[allow(clippy::cast_precision_loss)]
fn run_sequence(args: &RgbdArgs, dir: &Path, cfg: &RgbdPersonConfig, out: &Output) -> CmdResult {
    let format = DepthFormat::parse(&args.depth_format)
        .map_err(|_| format!("--depth-format {:?}: expected ptb or mm", args.depth_format))?;
    let seq = PtbSequence::open(dir)?;
    let init = if let Some(s) = &args.init {
        parse_box(s)?
    } else {
        seq.init_box().map_err(|e| format!("no --init and {e}"))?
    };
    let given = intrinsics_given(args)?;
    let mut tr: Option<RgbdPersonTracker> = None;
    let mut writer = args.out.as_deref().map(Writer::new).transpose()?;
    let mut rec = crate::record::Mcap::open(args.mcap.as_ref())?.map(|m| RgbdRecorder { m });
    let (mut total_ms, mut n) = (0.0, 0usize);
    crate::interrupt::install();
    let mut processed = 0usize;
    for (k, f) in seq.frames.iter().enumerate() {
        if crate::interrupt::requested() {
            break;
        }
        processed = k + 1;
        let (num, rp, dp) = (f.number, &f.rgb, &f.depth);
        let rgb = quarry_vision::io::open_image(rp)?.to_rgb8();
        let depth = load_depth(dp, format)?;
        let (w, h) = rgb.dimensions();
        if depth.dimensions() != (w, h) {
            return Err(format!(
                "frame {num}: RGB is {w}x{h} but depth is {}x{}",
                depth.width, depth.height
            )
            .into());
        }
        let frame = RgbdFrame::new(w, h, rgb.into_raw(), depth, EgoMotion::None)?;
        let stamp = Stamp::from_frame(k as u64, 1.0 / 30.0);
        if let Some(t) = tr.as_mut() {
            let t0 = Instant::now();
            let o = t.step(stamp, &frame)?;
            total_ms += t0.elapsed().as_secs_f64() * 1e3;
            n += 1;
            if let Some(wr) = writer.as_mut() {
                wr.frame(k, w, h, &frame.rgb, &o, None)?;
            }
            if let Some(r) = rec.as_mut() {
                let f = RecFrame {
                    t: stamp.t,
                    w,
                    h,
                    rgb: &frame.rgb,
                    depth: &frame.depth_m,
                };
                r.frame(&f, o.bbox.map(|b| (b, o.confirmed)), None)?;
            }
        } else {
            let mut c = cfg.clone();
            c.intrinsics = sequence_intrinsics(cfg, given, w, h)?;
            let mut t = RgbdPersonTracker::new(c)?;
            t.init(stamp, &frame, init)?;
            if let Some(wr) = writer.as_mut() {
                wr.init_frame(k, w, h, &frame.rgb, &init)?;
            }
            if let Some(r) = rec.as_mut() {
                let f = RecFrame {
                    t: stamp.t,
                    w,
                    h,
                    rgb: &frame.rgb,
                    depth: &frame.depth_m,
                };
                r.frame(&f, Some((init, true)), None)?;
            }
            tr = Some(t);
        }
    }
    if let Some(w) = &writer {
        w.finish()?;
    }
    let rep = Report {
        scenario: None,
        sequence: Some(dir.display().to_string()),
        preset: cfg.preset.name(),
        frames: processed,
        center_err_px: None,
        success_rate_iou50: None,
        recovery_frames: None,
        ms_per_frame: if n > 0 { total_ms / n as f64 } else { 0.0 },
        summary: None,
        mcap: rec.map(|r| r.m.finish()).transpose()?,
        interrupted: crate::interrupt::requested(),
    };
    out.emit(&rep, || {
        format!(
            "{}: {} frames tracked, {:.1} ms/frame (no ground truth read){}\n",
            dir.display(),
            processed,
            rep.ms_per_frame,
            if rep.interrupted {
                " (interrupted)"
            } else {
                ""
            }
        )
    })?;
    if rep.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

/// Rows of `quarry demo`: the first 210 frames of S1 (static robot, the panel crosses in front
/// of the target around frame 150), patch tracker and baseline.
///
/// # Errors
/// A simulator or tracker error.
pub fn demo_rows(seed: u64) -> Result<Vec<super::demo::Row>, CmdError> {
    let scene = RgbdScene::new(ScenarioId::S1StaticOcclusion, seed)?;
    let mut rows = Vec::new();
    for (name, cfg) in [
        ("rgbd-person", RgbdPersonConfig::paper()),
        ("rgbd-baseline", RgbdPersonConfig::whole_target_baseline()),
    ] {
        let (s, _) = run_scenario_frames(&scene, seed, &cfg, OdometryFeed::Exact, 210, |_, _| {})?;
        for (metric, value) in [
            ("success@IoU0.5", s.success_rate_iou50),
            ("centre error (px)", s.center_err_px),
        ] {
            rows.push(super::demo::Row {
                tracker: name.into(),
                scenario: "S1 frames 0-209, static robot, crossing occluder".into(),
                metric: metric.into(),
                value,
                paper: None,
                ms_per_frame: Some(s.ms_per_frame),
            });
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parsing() {
        use quarry_data::ptb::frame_number;
        assert_eq!(frame_number(Path::new("r-123_45.png")), Some(45));
        assert_eq!(frame_number(Path::new("abc.png")), None);
        assert!(parse_box("1,2,3,4").is_ok());
        assert!(parse_box("1,2,0,4").is_err());
        assert!(parse_box("1,2,nan,4").is_err());
        assert!(parse_box("1,2").is_err());
        assert_eq!(0x1234u16.rotate_right(3), 0x8246); // (v >> 3) | (v << 13)
    }

    /// A tiny PTB-layout sequence (`rgb/r-<ts>-<n>.png`, `depth/d-<ts>-<n>.png` with the 3-bit
    /// circular shift, `init.txt`): a striped person 2 m away stepping right over a wall 4 m away.
    fn write_ptb(dir: &Path, n: u32, with_init: bool) {
        let (w, h) = (96u32, 72u32);
        std::fs::create_dir_all(dir.join("rgb")).unwrap();
        std::fs::create_dir_all(dir.join("depth")).unwrap();
        for k in 0..n {
            let x0 = 36 + 2 * k;
            let person = |x: u32, y: u32| (x0..x0 + 24).contains(&x) && (12..60).contains(&y);
            let rgb = RgbImage::from_fn(w, h, |x, y| {
                if person(x, y) {
                    // three vertical colour bands, darker every other 6 rows
                    let c =
                        [[40u8, 90, 200], [220, 180, 60], [200, 40, 60]][((x - x0) / 8) as usize];
                    let d = if (y / 6) % 2 == 0 { 1 } else { 2 };
                    Rgb(c.map(|v| v / d))
                } else {
                    let g = u8::try_from(100 + (x * 7 + y * 13) % 50).unwrap();
                    Rgb([g, g, g])
                }
            });
            rgb.save(dir.join(format!("rgb/r-{}-{}.png", 1000 + 33 * k, k + 1)))
                .unwrap();
            let depth = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
                let mm: u16 = if person(x, y) { 2000 } else { 4000 };
                image::Luma([mm.rotate_left(3)])
            });
            depth
                .save(dir.join(format!("depth/d-{}-{}.png", 1010 + 33 * k, k + 1)))
                .unwrap();
        }
        if with_init {
            std::fs::write(dir.join("init.txt"), "36,12,24,48\n").unwrap();
        }
    }

    fn args(dir: &Path, out: Option<PathBuf>) -> RgbdArgs {
        RgbdArgs {
            scenario: "s1".into(),
            seed: 0,
            sequence: Some(dir.to_path_buf()),
            init: None,
            depth_format: "ptb".into(),
            baseline: false,
            cfg: ConfigArgs::default(),
            noisy_odometry: false,
            frames: None,
            out,
            mcap: None,
        }
    }

    fn parse(flags: &[&str]) -> Result<RgbdArgs, clap::Error> {
        use clap::Parser as _;
        let cli = crate::Cli::try_parse_from(["quarry", "rgbd"].iter().chain(flags))?;
        match cli.command {
            crate::Command::Rgbd(a) => Ok(a),
            other => panic!("parsed as {other:?}"),
        }
    }

    #[test]
    fn preset_baseline_and_config_flags() {
        use quarry_trackers::TrackerConfig as _;
        let cfg = |flags: &[&str]| config(&parse(flags).unwrap());
        assert_eq!(cfg(&[]).unwrap(), RgbdPersonConfig::paper());
        // --baseline is --preset baseline
        let baseline = RgbdPersonConfig::whole_target_baseline();
        assert_eq!(cfg(&["--baseline"]).unwrap(), baseline);
        assert_eq!(cfg(&["--preset", "baseline"]).unwrap(), baseline);
        assert!(parse(&["--baseline", "--preset", "strict"]).is_err());
        // every preset by name, `_` for `-` too
        for &p in Preset::ALL {
            assert_eq!(
                cfg(&["--preset", p.name()]).unwrap(),
                RgbdPersonConfig::preset(p)
            );
        }
        assert!(!cfg(&["--preset", "no_ego"]).unwrap().ego);
        assert!(parse(&["--preset", "sideways"]).is_err());
        // --config over the preset; unknown keys and tables are errors naming them
        let dir = std::env::temp_dir().join(format!("quarry-rgbd-cfg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = |name: &str, text: &str| {
            let p = dir.join(name);
            std::fs::write(&p, text).unwrap();
            p.display().to_string()
        };
        let ok = file("ok.toml", "c_base = 0.8\n[intrinsics]\nfx = 500.0\n");
        let c = cfg(&["--baseline", "--config", &ok]).unwrap();
        assert!(c.baseline && (c.c_base - 0.8).abs() < 1e-12 && c.intrinsics.fx == 500.0);
        assert_eq!(c.model, baseline.model);
        let c = cfg(&["--config", &ok]).unwrap();
        assert!(!c.baseline && (c.c_base - 0.8).abs() < 1e-12);
        let named = file("named.toml", "preset = \"no-ego\"\n");
        assert!(!cfg(&["--config", &named]).unwrap().ego);
        assert!(cfg(&["--baseline", "--config", &named]).is_err());
        let typo = file("typo.toml", "[modle]\nn = 3\n");
        let e = cfg(&["--config", &typo]).unwrap_err();
        assert!(e.to_string().contains("modle"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn intrinsics_set_by_the_config_must_match_the_frames() {
        let root = std::env::temp_dir().join(format!("quarry-rgbd-k-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let seq = root.join("seq");
        write_ptb(&seq, 2, true);
        let (w, h) = image::image_dimensions(seq.join("rgb/r-1000-1.png")).unwrap();
        let toml = |name: &str, text: String| {
            let p = root.join(name);
            std::fs::write(&p, text).unwrap();
            p
        };
        let mut a = args(&seq, None);
        // a config that sets intrinsics for another camera: an error naming both sizes
        a.cfg.config = Some(toml("vga.toml", "[intrinsics]\nfx = 500.0\n".into()));
        let e = run_sequence(&a, &seq, &config(&a).unwrap(), &Output { json: true }).unwrap_err();
        assert!(
            e.to_string().contains(&format!("{w}x{h}")) && e.to_string().contains("640x480"),
            "{e}"
        );
        // the same camera at the frames' size runs
        let text =
            format!("[intrinsics]\nfx = 500.0\nwidth = {w}\nheight = {h}\ncx = 40.0\ncy = 30.0\n");
        a.cfg.config = Some(toml("fit.toml", text));
        run_sequence(&a, &seq, &config(&a).unwrap(), &Output { json: true }).unwrap();
        // no [intrinsics]: the defaults are fitted to the frames
        let k = sequence_intrinsics(&RgbdPersonConfig::paper(), false, w, h).unwrap();
        assert_eq!((k.width, k.height, k.fx), (w, h, 525.0));
        assert!((k.cx - (f64::from(w) - 1.0) / 2.0).abs() < 1e-12);
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn ptb_sequence_writes_every_frame_including_the_first() {
        let root = std::env::temp_dir().join(format!("quarry-rgbd-ptb-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        let seq = root.join("seq");
        write_ptb(&seq, 4, true);
        let res = root.join("res");
        let a = args(&seq, Some(res.clone()));
        run_sequence(&a, &seq, &config(&a).unwrap(), &Output { json: true }).unwrap();
        let boxes = std::fs::read_to_string(res.join("boxes.txt")).unwrap();
        let lines: Vec<Vec<f64>> = boxes
            .lines()
            .map(|l| l.split(',').map(|t| t.parse().unwrap()).collect())
            .collect();
        assert_eq!(lines.len(), 4, "{boxes}");
        // line 1 = frame 1 = the init box, conf 1
        assert_eq!(&lines[0][..7], &[1.0, 1.0, 36.0, 12.0, 24.0, 48.0, 1.0]);
        for (k, l) in lines.iter().enumerate() {
            assert!((l[0] - (k as f64 + 1.0)).abs() < 1e-12, "{boxes}");
            assert!(res.join(format!("frames/{:06}.png", k + 1)).exists());
        }
        // the tracker follows the person 2 px/frame to the right (box centre x = 48 + 2k; the
        // candidate grid stride is 3 px)
        for (k, l) in lines.iter().enumerate().skip(1) {
            let cx = l[2] + l[4] / 2.0;
            assert!(
                (cx - (48.0 + 2.0 * k as f64)).abs() <= 3.0,
                "frame {}: {boxes}",
                k + 1
            );
            assert!((l[6] - 1.0).abs() < 1e-12, "{boxes}");
        }
        // errors, never panics: no init, a missing depth frame
        let bad = root.join("noinit");
        write_ptb(&bad, 2, false);
        let e = run_sequence(
            &args(&bad, None),
            &bad,
            &config(&a).unwrap(),
            &Output { json: true },
        )
        .unwrap_err();
        assert!(e.to_string().contains("init.txt"), "{e}");
        std::fs::remove_file(seq.join("depth/d-1043-2.png")).unwrap();
        let e = run_sequence(
            &args(&seq, None),
            &seq,
            &config(&a).unwrap(),
            &Output { json: true },
        )
        .unwrap_err();
        assert!(e.to_string().contains("frame 2"), "{e}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
