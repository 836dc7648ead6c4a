//! `quarry video`: the watershed + SIFT pools tracker (paper 004) on an image sequence.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use ab_glyph::{FontRef, PxScale};
use clap::{Args, Subcommand};
use image::RgbImage;
use imageproc::drawing::{draw_hollow_rect_mut, draw_text_mut};
use imageproc::rect::Rect;
use quarry_core::{MultiTargetTracker, Plane, Stamp, TrackStatus};
use quarry_eval::motchallenge::{GtRow, GtStyle, MotRow, read_gt_file, to_frames, write_results};
use quarry_eval::{Iou, MotEvaluation};
use quarry_trackers::watershed_sift::{Profile, WatershedSiftConfig, WatershedSiftTracker};
use quarry_trackers::{PresetName, TrackerConfig};
use quarry_vision::convert::rgb_to_gray_bt601;
use quarry_vision::render::{grey_to_rgb, label_colour};
use serde::Serialize;

use crate::cmd::eval::EvalReport;
use crate::config_args::PresetParser;
use crate::output::{CmdError, CmdResult, Output, Table};
use crate::progress;

/// Arguments of `quarry video`.
#[derive(Debug, Args)]
#[command(
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    about = "Track people in an image sequence with the watershed + SIFT pools tracker (paper 004)",
    long_about = "Fully automatic multi-object tracking of spec 004 (Hu et al. 2012) on an image \
sequence from a static camera: no detector and no initial boxes. Each frame is segmented (ramp, \
f64 Gaussian blur, watershed); regions are mapped onto the previous frame's; regularly moving \
minima start targets; each target keeps a weighted pool of SIFT descriptors that decides splits, \
occlusions and separations. Each target is reported as a fixed box of the typical person size \
(paper), or in the robust profile as the box fitted to its foreground pixels against a running \
median background, which also starts targets on uncovered foreground (docs/video-tracker.md).

INPUT: --frames DIR holds the frames as PNG or JPEG files taken in file-name order (MOTChallenge's \
img1/000001.jpg); the k-th file is MOTChallenge frame k. Colour is converted to grey with \
Y = round(0.299 R + 0.587 G + 0.114 B). Every frame must have the same size.

CONFIGURATION: --profile paper (default; the paper with the spec's gap fills) or robust (the \
documented extensions); --config FILE.toml is laid over the profile (unknown keys are refused with \
the file and line). The box size and the blur sigma come from the sequence's typical person size: \
--person-size WxH sets box_w = W, box_h = H, sigma = 8 W / 30 and d_near = W / 2 after the config \
file. They are never taken from the ground truth. The configuration used is written to \
OUT/config.toml.

OUTPUT in --out DIR: <name>.txt (MOTChallenge results: frame,id,left,top,w,h,1,-1,-1,-1), \
config.toml, and unless --no-images, frames/<frame>.png: the grey frame with each target's box \
and 'id pool-size' (an occluded target's box is drawn double and labelled 'occ').

With --gt GT.txt (MOTChallenge ground truth) the results are scored exactly as `quarry eval --gt \
GT.txt --res OUT/<name>.txt` does (box IoU >= 0.5), on the frames processed.

Ctrl-C (or SIGTERM) stops after the current frame: the results so far are written and scored \
(\"interrupted\": true) and the exit status is 130.

SYNTHETIC DATA: `quarry video sim --out DIR` writes the synthetic video walkers-v1 of spec 004 \
§5.2 (frames, ground truth, events) and can score the tracker on it (`quarry video sim --help`).

JSON (--json) prints one object with: name, frames, interrupted, profile, results (path), \
tracks (distinct ids), boxes, ms_per_frame (mean tracker time per frame, excluding image I/O and \
drawing), ms_p50 and ms_p95 (its median and 95th percentile), stages_ms {segment, map, sift, track, foreground} (means per frame; foreground = the \
background model and the robust profile's foreground boxes and births), config (the configuration \
used), and with --gt: metrics (the object of `quarry eval --json`).

EXAMPLE:
  quarry video --frames ../shared/data/pets09-s2l1/img1 --gt ../shared/data/pets09-s2l1/gt.txt \\
      --profile robust --person-size 36x90 --out runs/pets-robust
  quarry video sim --variant ab --frames 120 --out runs/walkers-ab
  quarry video --frames runs/walkers-ab/img1 --gt runs/walkers-ab/gt/gt.txt --out runs/ab-paper"
)]
pub struct VideoArgs {
    /// `sim`: write (and optionally score) the synthetic walkers video.
    #[command(subcommand)]
    pub sub: Option<VideoSub>,
    /// Directory of frames.
    #[arg(long, value_name = "DIR", required = true)]
    pub frames: Option<PathBuf>,
    /// MOTChallenge ground truth to score against.
    #[arg(long, value_name = "GT.txt")]
    pub gt: Option<PathBuf>,
    /// Profile (`paper` or `robust`).
    #[arg(long, value_name = "NAME", value_parser = PresetParser::<Profile>::new())]
    pub profile: Option<Profile>,
    /// TOML configuration laid over the profile.
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// Typical person size WxH in pixels (sets the box, sigma and d_near).
    #[arg(long, value_name = "WxH")]
    pub person_size: Option<String>,
    /// Frames A..B (1-based, inclusive) in file-name order; default all.
    #[arg(long, value_name = "A..B")]
    pub range: Option<String>,
    /// Sequence name for `<name>.txt` (default: the directory's name, or its parent's when it
    /// is called img1).
    #[arg(long)]
    pub name: Option<String>,
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR", required = true)]
    pub out: Option<PathBuf>,
    /// Do not write annotated frames.
    #[arg(long)]
    pub no_images: bool,
    /// Record the run as MCAP (ROS 2 messages, CDR; docs/ros2.md): the frames (`/image`,
    /// sensor_msgs/CompressedImage, PNG), the tracks (`/detections`, vision_msgs/Detection2DArray,
    /// track id in `id`) and with --gt the ground truth (`/ground_truth/detections`).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    /// Frame rate for the recording's stamps (frame k at (k - 1) / fps seconds; PETS09 is 7).
    #[arg(long, default_value_t = 25.0)]
    pub fps: f64,
}

/// Subcommands of `quarry video`.
#[derive(Debug, Subcommand)]
pub enum VideoSub {
    // no doc comment: clap would take it as the subcommand's help and hide the long help
    // written on `SimArgs` (see main.rs)
    Sim(super::video_sim::SimArgs),
}

/// The stamp of 1-based frame `k` at `fps`.
fn frame_time(k: u64, fps: f64) -> quarry_core::TimeUs {
    quarry_core::TimeUs::from_secs_f64((k.saturating_sub(1)) as f64 / fps)
}

/// MOT boxes (1-based left/top) as a Detection2DArray in pixel coordinates (0-based centre).
fn detections_msg(
    t: quarry_core::TimeUs,
    boxes: impl Iterator<Item = (i64, [f64; 4])>,
) -> quarry_ros2::msgs::Detection2DArray {
    crate::record::detections(
        t,
        "camera",
        boxes.map(|(id, b)| (id.to_string(), [b[0] - 1.0, b[1] - 1.0, b[2], b[3]], 1.0)),
    )
}

/// A grey frame as a PNG CompressedImage (fast compression).
fn png_msg(
    t: quarry_core::TimeUs,
    grey: &Plane<u8>,
) -> Result<quarry_ros2::msgs::CompressedImage, crate::output::CmdError> {
    crate::record::png_image(
        t,
        "camera",
        &grey.data,
        grey.width,
        grey.height,
        image::ExtendedColorType::L8,
    )
}

/// Mean stage times per frame, milliseconds.
#[derive(Debug, Serialize, Default)]
struct StagesMs {
    segment: f64,
    map: f64,
    sift: f64,
    track: f64,
    foreground: f64,
}

#[derive(Debug, Serialize)]
struct VideoJson {
    name: String,
    frames: usize,
    interrupted: bool,
    profile: &'static str,
    results: String,
    tracks: usize,
    boxes: usize,
    ms_per_frame: f64,
    ms_p50: f64,
    ms_p95: f64,
    stages_ms: StagesMs,
    config: WatershedSiftConfig,
    metrics: Option<EvalReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    mcap: Option<crate::record::McapInfo>,
}

/// Parses `WxH`.
fn parse_size(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("--person-size {s}: expected WxH, e.g. 36x90"))?;
    let p = |v: &str| {
        v.trim()
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v >= 2.0)
            .ok_or_else(|| format!("--person-size {s}: sides must be numbers >= 2"))
    };
    Ok((p(a)?, p(b)?))
}

/// The sequence name of a frame directory.
fn sequence_name(dir: &Path) -> String {
    let base = |p: &Path| p.file_name().map(|s| s.to_string_lossy().into_owned());
    let dir = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    match base(&dir) {
        Some(n) if n == "img1" => dir
            .parent()
            .and_then(base)
            .unwrap_or_else(|| "sequence".into()),
        Some(n) => n,
        None => "sequence".into(),
    }
}

/// The configuration the flags ask for.
fn load_config(
    args: &VideoArgs,
) -> Result<WatershedSiftConfig, Box<dyn std::error::Error + Send + Sync>> {
    let mut cfg = match &args.config {
        Some(p) => WatershedSiftConfig::from_toml_file(p, args.profile)?,
        None => args
            .profile
            .map_or_else(WatershedSiftConfig::default, WatershedSiftConfig::preset),
    };
    if let Some(s) = &args.person_size {
        let (w, h) = parse_size(s)?;
        cfg = cfg.with_person_size(w, h);
    }
    cfg.validate()?;
    Ok(cfg)
}

/// Reads one frame as grey, naming the file in every error.
fn read_frame(path: &Path) -> Result<Plane<u8>, String> {
    let img = quarry_vision::io::open_image(path).map_err(|e| e.to_string())?;
    let grey = rgb_to_gray_bt601(&img.to_rgb8());
    if grey.width < 2 || grey.height < 2 {
        return Err(format!(
            "frame {}: {}x{} is too small (the tracker needs at least 2x2 pixels)",
            path.display(),
            grey.width,
            grey.height
        ));
    }
    Ok(grey)
}

/// Draws the boxes and labels of one frame.
fn annotate(grey: &Plane<u8>, rows: &[(MotRow, bool, usize)], font: &FontRef<'_>) -> RgbImage {
    let mut img = grey_to_rgb(grey);
    let (w, h) = (i64::from(grey.width), i64::from(grey.height));
    for (r, occluded, pool) in rows {
        let c = label_colour(r.id as u32);
        let [l, t, bw, bh] = r.bbox;
        let (x0, y0) = ((l - 1.0).round() as i64, (t - 1.0).round() as i64);
        let (rw, rh) = (bw.round().max(1.0) as u32, bh.round().max(1.0) as u32);
        if x0 >= w || y0 >= h || x0 + i64::from(rw) < 0 || y0 + i64::from(rh) < 0 {
            continue;
        }
        let x0c = x0.clamp(-10_000, w) as i32;
        let y0c = y0.clamp(-10_000, h) as i32;
        draw_hollow_rect_mut(&mut img, Rect::at(x0c, y0c).of_size(rw, rh), c);
        if *occluded && rw > 4 && rh > 4 {
            draw_hollow_rect_mut(
                &mut img,
                Rect::at(x0c + 2, y0c + 2).of_size(rw - 4, rh - 4),
                c,
            );
        }
        let label = if *occluded {
            format!("{} occ", r.id)
        } else {
            format!("{} p{}", r.id, pool)
        };
        let ty = (y0c - 13).max(0);
        draw_text_mut(
            &mut img,
            c,
            x0c.max(0),
            ty,
            PxScale::from(12.0),
            font,
            &label,
        );
    }
    img
}

/// The MOTChallenge row of report `r` in 1-based frame `frame_no` (1-based left/top, as the
/// ground truth); `None` for a report without a box.
fn mot_row(frame_no: u64, r: &quarry_core::TrackReport) -> Option<MotRow> {
    let [l, tp, bw, bh] = r.bbox?.to_ltwh();
    Some(MotRow {
        frame: frame_no,
        id: i64::from(r.id.0),
        bbox: [l + 1.0, tp + 1.0, bw, bh],
        conf: 1.0,
        extra: [None; 3],
    })
}

/// The scores of `rows` against `gt` at IoU 0.5, as `quarry eval` computes them.
fn score(gt: &[GtRow], rows: &[MotRow]) -> Result<EvalReport, CmdError> {
    let frames = to_frames(gt, rows, 0.5)?;
    let summary = MotEvaluation::new(&frames, &Iou::new(0.5)?)?.summary()?;
    Ok(EvalReport::new(&summary, None, 0.5))
}

/// Runs `quarry video` (or `quarry video sim`).
pub fn run(args: &VideoArgs, out: &Output) -> CmdResult {
    if let Some(VideoSub::Sim(a)) = &args.sub {
        return super::video_sim::run(a, out);
    }
    let (Some(frames_arg), Some(out_dir)) = (&args.frames, &args.out) else {
        return Err("quarry video needs --frames DIR and --out DIR (or the subcommand sim)".into());
    };
    let cfg = load_config(args)?;
    let files = quarry_data::image_sequence::list_frames(frames_arg)
        .map_err(|e| format!("--frames {}: {e}", frames_arg.display()))?;
    let (a, b) = match &args.range {
        Some(s) => super::motion::parse_range("--range", s, files.len())?,
        None => (1, files.len()),
    };
    // parse the ground truth before the long run, so that a bad file fails at once
    let gt: Option<Vec<GtRow>> = match &args.gt {
        Some(p) => Some(
            read_gt_file(p, GtStyle::Auto)
                .map_err(|e| format!("ground truth {}: {e}", p.display()))?,
        ),
        None => None,
    };
    std::fs::create_dir_all(out_dir)
        .map_err(|e| format!("cannot create {}: {e}", out_dir.display()))?;
    let frames_dir = out_dir.join("frames");
    if !args.no_images {
        std::fs::create_dir_all(&frames_dir)
            .map_err(|e| format!("cannot create {}: {e}", frames_dir.display()))?;
    }
    let cfg_path = out_dir.join("config.toml");
    std::fs::write(&cfg_path, cfg.to_toml()?)
        .map_err(|e| format!("cannot write {}: {e}", cfg_path.display()))?;
    let name = args
        .name
        .clone()
        .unwrap_or_else(|| sequence_name(frames_arg));
    let font = FontRef::try_from_slice(crate::fonts::DEJAVU_SANS_MONO)
        .map_err(|e| format!("bundled font: {e}"))?;

    if !(args.fps.is_finite() && args.fps > 0.0 && args.fps <= 1000.0) {
        return Err(format!("--fps {}: must be in (0, 1000]", args.fps).into());
    }
    let mut mcap = crate::record::Mcap::open(args.mcap.as_ref())?;
    let mut tracker = WatershedSiftTracker::new(cfg.clone())?;
    let pb = progress::bar(out, (b - a + 1) as u64, "video");
    crate::interrupt::install();
    let mut rows: Vec<MotRow> = Vec::new();
    let mut size: Option<(u32, u32, PathBuf)> = None;
    let (mut frame_ms, mut stages) = (Vec::new(), StagesMs::default());
    let mut processed = 0usize;
    for (k, path) in files[a - 1..b].iter().enumerate() {
        if crate::interrupt::requested() {
            break;
        }
        let frame_no = (a + k) as u64; // 1-based MOT frame
        let grey = read_frame(path)?;
        match &size {
            None => size = Some((grey.width, grey.height, path.clone())),
            Some((w, h, first)) if (*w, *h) != grey.dimensions() => {
                return Err(format!(
                    "frame {} is {}x{}, but {} is {w}x{h}: every frame of a sequence must have the same size",
                    path.display(),
                    grey.width,
                    grey.height,
                    first.display()
                )
                .into());
            }
            Some(_) => {}
        }
        let t = Instant::now();
        let reports = tracker
            .step(Stamp::from_frame(frame_no - 1, 1.0), &grey)
            .map_err(|e| format!("frame {}: {e}", path.display()))?;
        frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let st = tracker.diagnostics().times;
        stages.segment += st.segment_us / 1e3;
        stages.map += st.map_us / 1e3;
        stages.sift += st.sift_us / 1e3;
        stages.track += st.track_us / 1e3;
        stages.foreground += st.foreground_us / 1e3;
        processed += 1;
        let mut drawn = Vec::new();
        for r in &reports {
            let Some(row) = mot_row(frame_no, r) else {
                continue;
            };
            let pool = tracker
                .targets()
                .iter()
                .find(|t| t.report_id == r.id)
                .map_or(0, |t| t.pool.len());
            drawn.push((row, r.status == TrackStatus::Occluded, pool));
            rows.push(row);
        }
        if let Some(m) = mcap.as_mut() {
            let t = frame_time(frame_no, args.fps);
            m.write("/image", t, &png_msg(t, &grey)?)?;
            let boxes = drawn.iter().map(|(r, _, _)| (r.id, r.bbox));
            m.write("/detections", t, &detections_msg(t, boxes))?;
            if let Some(gt) = &gt {
                let g = gt
                    .iter()
                    .filter(|g| g.frame == frame_no)
                    .map(|g| (g.id, g.bbox));
                m.write("/ground_truth/detections", t, &detections_msg(t, g))?;
            }
        }
        if !args.no_images {
            let img = annotate(&grey, &drawn, &font);
            let p = frames_dir.join(format!("{frame_no:06}.png"));
            img.save(&p)
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let mcap_info = mcap.map(crate::record::Mcap::finish).transpose()?;
    let res_path = out_dir.join(format!("{name}.txt"));
    let f = std::fs::File::create(&res_path)
        .map_err(|e| format!("cannot write {}: {e}", res_path.display()))?;
    write_results(std::io::BufWriter::new(f), &rows)
        .map_err(|e| format!("cannot write {}: {e}", res_path.display()))?;
    let metrics = match &gt {
        Some(gt) => {
            // score the processed frames only (all of them unless --range or an interrupt)
            let last = (a + processed).saturating_sub(1) as u64;
            let gt: Vec<GtRow> = gt
                .iter()
                .filter(|g| g.frame >= a as u64 && g.frame <= last)
                .copied()
                .collect();
            Some(score(&gt, &rows)?)
        }
        None => None,
    };
    let n = processed.max(1) as f64;
    let ids: std::collections::BTreeSet<i64> = rows.iter().map(|r| r.id).collect();
    let json = VideoJson {
        name,
        frames: processed,
        interrupted: crate::interrupt::requested(),
        profile: cfg.preset.name(),
        results: res_path.display().to_string(),
        tracks: ids.len(),
        boxes: rows.len(),
        ms_per_frame: frame_ms.iter().sum::<f64>() / n,
        ms_p50: quarry_repro::video::nearest_rank(&frame_ms, 0.5),
        ms_p95: quarry_repro::video::nearest_rank(&frame_ms, 0.95),
        stages_ms: StagesMs {
            segment: stages.segment / n,
            map: stages.map / n,
            sift: stages.sift / n,
            track: stages.track / n,
            foreground: stages.foreground / n,
        },
        config: cfg,
        metrics,
        mcap: mcap_info,
    };
    out.emit(&json, || {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "{} frames of {}, profile {}: {} tracks, {} boxes, {:.1} ms per frame \
             (segment {:.1}, map {:.1}, SIFT {:.1}, track {:.1})",
            json.frames,
            json.name,
            json.profile,
            json.tracks,
            json.boxes,
            json.ms_per_frame,
            json.stages_ms.segment,
            json.stages_ms.map,
            json.stages_ms.sift,
            json.stages_ms.track
        );
        let _ = writeln!(s, "results in {}", json.results);
        if let Some(m) = &json.mcap {
            let _ = writeln!(
                s,
                "recorded {} messages on {} topics to {}",
                m.messages, m.topics, m.path
            );
        }
        if let Some(m) = &json.metrics {
            let mut t = Table::new(["MOTA", "MOTP", "IDF1", "HOTA", "IDSW", "FP", "FN"]);
            let f = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.3}"));
            t.row([
                f(m.mota),
                f(m.motp),
                f(m.idf1),
                format!("{:.3}", m.hota),
                m.idsw.to_string(),
                m.fp.to_string(),
                m.fn_.to_string(),
            ]);
            s.push_str(&t.render());
        }
        s
    })?;
    if json.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

/// `quarry demo --data DIR`: the `robust` profile on PETS09-S2L1 frames 1-200
/// (`DIR/pets09-s2l1`, person size 32x84 as in docs/video-tracker.md), scored against its ground
/// truth like `quarry eval`. `Ok(None)` when the sequence is not there.
pub fn demo_real_rows(data: &Path) -> Result<Option<Vec<super::demo::Row>>, CmdError> {
    let dir = data.join("pets09-s2l1");
    let (img, gt_path) = (dir.join("img1"), dir.join("gt.txt"));
    if !img.is_dir() || !gt_path.exists() {
        return Ok(None);
    }
    let files = quarry_data::image_sequence::list_frames(&img)
        .map_err(|e| format!("{}: {e}", img.display()))?;
    let gt = read_gt_file(&gt_path, GtStyle::Auto)
        .map_err(|e| format!("ground truth {}: {e}", gt_path.display()))?;
    let n = files.len().min(200);
    let cfg = WatershedSiftConfig::robust().with_person_size(32.0, 84.0);
    let mut tracker = WatershedSiftTracker::new(cfg)?;
    let (mut rows, mut ms) = (Vec::new(), 0.0);
    for (k, path) in files[..n].iter().enumerate() {
        let grey = read_frame(path)?;
        let t = Instant::now();
        let reports = tracker
            .step(Stamp::from_frame(k as u64, 1.0), &grey)
            .map_err(|e| format!("frame {}: {e}", path.display()))?;
        ms += t.elapsed().as_secs_f64() * 1e3;
        rows.extend(reports.iter().filter_map(|r| mot_row(k as u64 + 1, r)));
    }
    let gt: Vec<GtRow> = gt.into_iter().filter(|g| g.frame <= n as u64).collect();
    let r = score(&gt, &rows)?;
    let row = |metric: &str, value: f64| super::demo::Row {
        tracker: "watershed-sift (real)".into(),
        scenario: format!(
            "PETS09-S2L1 frames 1-{n}, robust profile (best peer, KNN + ByteTrack: MOTA 0.419, IDF1 0.447, HOTA 0.362)"
        ),
        metric: metric.into(),
        value,
        paper: None,
        ms_per_frame: Some(ms / n.max(1) as f64),
    };
    Ok(Some(vec![
        row("MOTA", r.mota.unwrap_or(f64::NAN)),
        row("IDF1", r.idf1.unwrap_or(f64::NAN)),
        row("HOTA", r.hota),
    ]))
}

#[cfg(test)]
mod tests {
    use super::parse_size;
    use crate::cmd::motion::parse_range;

    #[test]
    fn sizes_and_ranges() {
        assert_eq!(parse_size("36x90"), Ok((36.0, 90.0)));
        assert!(parse_size("36").is_err());
        assert!(parse_size("0x5").is_err());
        assert_eq!(parse_range("--range", "2..4", 9), Ok((2, 4)));
        assert!(parse_range("--range", "4..2", 9).is_err());
    }
}
