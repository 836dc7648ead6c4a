//! `quarry motion`: moving-point detection over an image sequence (spec 004 §2.7–2.8).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use image::Rgb;
use quarry_trackers::watershed_sift::{MotionFrontEnd, Polarity, mapping_counts};
use quarry_vision::MotionTest;
use quarry_vision::convert::rgb_to_gray_bt601;
use quarry_vision::io::load_rgb;
use quarry_vision::render::{draw_cross, draw_polyline, grey_to_rgb};
use serde::Serialize;

use crate::output::{CmdResult, Output, Table};
use crate::progress;

/// Arguments of `quarry motion`.
#[derive(Debug, Args)]
#[command(
    about = "Moving points (watershed minima with a regular trajectory) over an image sequence",
    long_about = "Moving-point detection of spec 004 (Hu et al. 2012) over an image sequence from a \
static camera: each frame is segmented (ramp, f64 Gaussian blur, regional minima, watershed); \
the regions of consecutive frames are mapped through their minima (bidirectional match, merge, \
split); chains of bidirectional matches give trajectories of the last N minima positions; a \
trajectory is a moving point when its L1 displacement exceeds --m-thred (eq. 6) and the \
variance of its normalised displacement steps is below --v-thred (eqs. 3-5, 7).

DIR holds the frames as image files (PNG or JPEG, e.g. MOTChallenge's img1/000001.jpg), taken \
in file-name order; colour is converted to grey with Y = round(0.299 R + 0.587 G + 0.114 B). \
--frames A..B selects frames A to B inclusive, 1-based in that order (MOTChallenge frame \
numbers).

OUTPUT: one line per frame (regions, bidirectional links, merges, splits, moving points) and \
annotated frames written to --out DIR as <frame>.png: the grey frame, every full-length \
trajectory in yellow, moving points in red with a cross at their current position.

Ctrl-C (or SIGTERM) stops after the current frame: the frames so far are written and reported \
(\"interrupted\": true) and the exit status is 130.

JSON (--json) prints one object with: frames (number processed), interrupted, ms (mean segmentation + \
mapping time per frame in milliseconds, excluding image I/O and drawing), per_frame (list of \
{frame, regions, bidirectional, merges, splits, moving: [{x, y, displacement, variance}]}).

EXAMPLE:
  quarry motion ../shared/data/pets09-s2l1/img1 --frames 1..40 --sigma 8 --out motion/"
)]
pub struct MotionArgs {
    /// Directory of frames.
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,
    /// Frames A..B (1-based, inclusive) in file-name order; default all.
    #[arg(long, value_name = "A..B")]
    pub frames: Option<String>,
    /// Gaussian blur sigma in pixels (> 0).
    #[arg(long, default_value_t = 8.0)]
    pub sigma: f64,
    /// Trajectory length N.
    #[arg(long, default_value_t = 10)]
    pub n: usize,
    /// Minimal L1 displacement over the trajectory (eq. 6), pixels.
    #[arg(long, default_value_t = 0.0)]
    pub m_thred: f64,
    /// Maximal variance of the normalised displacement steps (eq. 7).
    #[arg(long, default_value_t = 0.01)]
    pub v_thred: f64,
    /// Directory for the annotated frames (created if needed).
    #[arg(long, value_name = "DIR", default_value = "quarry-motion")]
    pub out: PathBuf,
    /// Do not write annotated frames.
    #[arg(long)]
    pub no_images: bool,
}

#[derive(Debug, Serialize)]
struct MovingJson {
    x: u32,
    y: u32,
    displacement: f64,
    variance: f64,
}

#[derive(Debug, Serialize)]
struct FrameJson {
    frame: usize,
    regions: usize,
    bidirectional: usize,
    merges: usize,
    splits: usize,
    moving: Vec<MovingJson>,
}

#[derive(Debug, Serialize)]
struct MotionJson {
    frames: usize,
    interrupted: bool,
    ms: f64,
    per_frame: Vec<FrameJson>,
}

pub(crate) fn parse_range(flag: &str, s: &str, n: usize) -> Result<(usize, usize), String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("{flag} {s}: expected A..B"))?;
    let a: usize = a
        .trim()
        .parse()
        .map_err(|_| format!("{flag} {s}: bad start"))?;
    let b: usize = if b.trim().is_empty() {
        n
    } else {
        b.trim()
            .parse()
            .map_err(|_| format!("{flag} {s}: bad end"))?
    };
    if a == 0 || b < a {
        return Err(format!("{flag} {s}: need 1 <= A <= B"));
    }
    if b > n {
        return Err(format!("{flag} {s}: the directory has only {n} frames"));
    }
    Ok((a, b))
}

/// Runs `quarry motion`.
pub fn run(args: &MotionArgs, out: &Output) -> CmdResult {
    let files = quarry_data::image_sequence::list_frames(&args.dir)?;
    let (a, b) = match &args.frames {
        Some(s) => parse_range("--frames", s, files.len())?,
        None => (1, files.len()),
    };
    let test = MotionTest {
        n: args.n,
        m_thred: args.m_thred,
        v_thred: args.v_thred,
    };
    test.validate()?;
    if !args.no_images {
        std::fs::create_dir_all(&args.out)
            .map_err(|e| format!("cannot create {}: {e}", args.out.display()))?;
    }
    let mut front = MotionFrontEnd::new(args.sigma, 256, Polarity::Dark, test)?;
    let pb = progress::bar(out, (b - a + 1) as u64, "motion");
    let mut per_frame = Vec::new();
    let mut total_ms = 0.0;
    crate::interrupt::install();
    for (k, path) in files[a - 1..b].iter().enumerate() {
        if crate::interrupt::requested() {
            break;
        }
        let frame_no = a + k;
        let grey = rgb_to_gray_bt601(&load_rgb(path)?);
        let t = Instant::now();
        // the per-frame loop lives in the library: segment, map, trajectories, moving points
        front
            .step(&grey)
            .map_err(|e| format!("frame {}: {e}", path.display()))?;
        let (bidir, merges, splits) = front.mapping().map_or((0, 0, 0), mapping_counts);
        let seg = front.current().ok_or("internal: no segmentation")?;
        let tr = front.trajectories().ok_or("internal: no trajectories")?;
        let moving = front.moving();
        total_ms += t.elapsed().as_secs_f64() * 1e3;

        if !args.no_images {
            let mut img = grey_to_rgb(&grey);
            for t in &tr.trajectories {
                if t.len() == args.n {
                    let pts: Vec<(u32, u32)> = t.iter().copied().collect();
                    draw_polyline(&mut img, &pts, Rgb([255, 220, 0]));
                }
            }
            for (label, _) in moving {
                if let Some(t) = tr.get(*label) {
                    let pts: Vec<(u32, u32)> = t.iter().copied().collect();
                    draw_polyline(&mut img, &pts, Rgb([255, 0, 0]));
                    if let Some(&last) = t.back() {
                        draw_cross(&mut img, last, 5, Rgb([255, 0, 0]));
                    }
                }
            }
            let p = args.out.join(format!("{frame_no:06}.png"));
            img.save(&p)
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
        }
        per_frame.push(FrameJson {
            frame: frame_no,
            regions: seg.n_regions(),
            bidirectional: bidir,
            merges,
            splits,
            moving: moving
                .iter()
                .map(|(label, s)| {
                    let (x, y) = seg.minima[*label as usize - 1].representative;
                    MovingJson {
                        x,
                        y,
                        displacement: s.displacement,
                        variance: s.variance,
                    }
                })
                .collect(),
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    let n = per_frame.len();
    let json = MotionJson {
        frames: n,
        interrupted: crate::interrupt::requested(),
        ms: total_ms / n.max(1) as f64,
        per_frame,
    };
    out.emit(&json, || {
        let mut t = Table::new(["frame", "regions", "bidir", "merges", "splits", "moving"]);
        for f in &json.per_frame {
            t.row([
                f.frame.to_string(),
                f.regions.to_string(),
                f.bidirectional.to_string(),
                f.merges.to_string(),
                f.splits.to_string(),
                f.moving.len().to_string(),
            ]);
        }
        let mut s = t.render();
        let _ = writeln!(
            s,
            "{n} frames, {:.1} ms per frame (segmentation + mapping)",
            json.ms
        );
        if !args.no_images {
            let _ = writeln!(s, "annotated frames in {}", args.out.display());
        }
        s
    })?;
    if json.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_range;

    #[test]
    fn ranges() {
        assert_eq!(parse_range("--frames", "1..5", 10), Ok((1, 5)));
        assert_eq!(parse_range("--frames", "3..", 10), Ok((3, 10)));
        assert!(parse_range("--frames", "0..5", 10).is_err());
        assert!(parse_range("--frames", "5..3", 10).is_err());
        assert!(parse_range("--frames", "1..11", 10).is_err());
        assert!(parse_range("--frames", "x", 10).is_err());
    }
}
