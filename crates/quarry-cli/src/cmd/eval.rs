//! `quarry eval`: score a MOTChallenge result file against ground truth.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use quarry_eval::motchallenge::{
    GtStyle, read_gt_file, read_results_file, to_frames, to_point_frames,
};
use quarry_eval::{Euclidean, Iou, MotEvaluation, MotSummary};
use serde::Serialize;

use crate::output::{CmdResult, Output, Table, fmt_opt};

/// Ground-truth layout (`--gt-style`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StyleArg {
    /// 9 columns = MOT16/17/20 (flag, class, visibility), otherwise MOT15 (flag, x, y, z).
    Auto,
    /// 2D MOT 2015: `frame,id,l,t,w,h,flag,x,y,z`.
    Mot15,
    /// MOT16/17/20: `frame,id,l,t,w,h,flag,class,visibility`.
    Mot16,
}

/// The largest `--dist`: far beyond any scene, and small enough that HOTA's similarity scale
/// (twice the threshold) stays finite.
const MAX_DIST: f64 = 1e12;

/// Arguments of `quarry eval`.
#[derive(Debug, Args)]
#[command(
    about = "Score a MOTChallenge tracking result against ground truth (MOTA, MOTP, IDF1, HOTA)",
    long_about = "Score a MOTChallenge tracking result against ground truth.

Computes CLEAR MOT (MOTA, MOTP, ID switches, false positives, misses, fragmentations, \
mostly tracked / lost), the identity measures (IDF1, IDP, IDR) and HOTA (HOTA, DetA, AssA, \
LocA, averaged over alpha = 0.05..0.95). The numbers agree with py-motmetrics (CLEAR MOT, \
IDF1) and TrackEval (HOTA) to 1e-6.

INPUT FORMATS (comma-separated text, one object per line, 1-based frames, pixel boxes):
  results:               frame,id,bb_left,bb_top,bb_width,bb_height,conf[,x,y,z]
  ground truth, MOT15:   frame,id,bb_left,bb_top,bb_width,bb_height,flag,x,y,z
  ground truth, MOT16+:  frame,id,bb_left,bb_top,bb_width,bb_height,flag,class,visibility
Lines with 6 to 10 columns are accepted. Ground-truth rows with flag 0 (and MOT16+ distractor \
classes 2, 6, 7, 8, 12) are ignored: results matching them are dropped, not counted as false \
positives; other non-pedestrian classes are removed from the ground truth.

MATCHING: by default a result matches an object when their box IoU >= 0.5 (--iou to change); \
MOTP is then the MOTChallenge percentage (mean IoU of matches x 100). With --dist METRES the \
world coordinates x, y (columns 8-9) are compared instead, a match needs a distance <= METRES, \
HOTA's similarity is max(0, 1 - d / (2 METRES)), and MOTP is the mean distance in metres.

JSON (--json) prints one object with: mota, motp, motp_unit (\"percent_iou\" or \"metres\"), \
motp_distance (py-motmetrics' MOTP: mean 1 - IoU, or metres), idf1, idp, idr, hota, deta, \
assa, loca, idsw, fp, fn, frag, mt, pt, ml, gt (ground-truth boxes), predictions, frames, \
matching (\"iou\" or \"dist\"), threshold. Undefined ratios (e.g. MOTA without ground truth) \
are null.

EXAMPLE:
  quarry eval --gt MOT17-04/gt/gt.txt --res results/MOT17-04.txt
  quarry eval --gt gt.txt --res res.txt --json | jq .hota"
)]
pub struct EvalArgs {
    /// Ground-truth file (MOTChallenge gt.txt).
    #[arg(long, value_name = "GT.txt")]
    pub gt: PathBuf,
    /// Tracker result file (MOTChallenge results).
    #[arg(long, value_name = "RES.txt")]
    pub res: PathBuf,
    /// Minimum box IoU of a match.
    #[arg(
        long,
        value_name = "IOU",
        default_value_t = 0.5,
        conflicts_with = "dist"
    )]
    pub iou: f64,
    /// Match world positions (columns 8-9) within this distance instead of boxes.
    #[arg(long, value_name = "METRES")]
    pub dist: Option<f64>,
    /// Ground-truth column layout.
    #[arg(long, value_enum, default_value_t = StyleArg::Auto)]
    pub gt_style: StyleArg,
}

/// The JSON object `quarry eval --json` prints (field names are stable).
#[derive(Debug, Serialize)]
pub struct EvalReport {
    /// Multiple object tracking accuracy `1 - (FN + FP + IDSW) / GT`.
    pub mota: Option<f64>,
    /// MOTChallenge MOTP: mean IoU x 100 (`--iou`) or mean distance in metres (`--dist`).
    pub motp: Option<f64>,
    /// `"percent_iou"` or `"metres"`.
    pub motp_unit: &'static str,
    /// py-motmetrics' MOTP: mean distance of matches (`1 - IoU`, or metres).
    pub motp_distance: Option<f64>,
    /// IDF1.
    pub idf1: Option<f64>,
    /// ID precision.
    pub idp: Option<f64>,
    /// ID recall.
    pub idr: Option<f64>,
    /// HOTA (mean over alpha).
    pub hota: f64,
    /// Detection accuracy (mean over alpha).
    pub deta: f64,
    /// Association accuracy (mean over alpha).
    pub assa: f64,
    /// Localisation accuracy (mean over alpha).
    pub loca: f64,
    /// Identity switches.
    pub idsw: usize,
    /// False positives.
    pub fp: usize,
    /// False negatives (misses).
    #[serde(rename = "fn")]
    pub fn_: usize,
    /// Fragmentations.
    pub frag: usize,
    /// Mostly tracked objects.
    pub mt: usize,
    /// Partially tracked objects.
    pub pt: usize,
    /// Mostly lost objects.
    pub ml: usize,
    /// Ground-truth boxes scored.
    pub gt: usize,
    /// Result boxes scored.
    pub predictions: usize,
    /// Frames (union of the frames in either file).
    pub frames: usize,
    /// `"iou"` or `"dist"`.
    pub matching: &'static str,
    /// The IoU or distance threshold.
    pub threshold: f64,
}

impl EvalReport {
    /// The report of a summary (`dist`: world matching, else IoU).
    pub fn new(s: &MotSummary, dist: Option<f64>, threshold: f64) -> Self {
        let c = &s.clear;
        Self {
            mota: c.mota(),
            motp: if dist.is_some() {
                c.motp()
            } else {
                c.motchallenge_motp()
            },
            motp_unit: if dist.is_some() {
                "metres"
            } else {
                "percent_iou"
            },
            motp_distance: c.motp(),
            idf1: s.identity.idf1(),
            idp: s.identity.idp(),
            idr: s.identity.idr(),
            hota: s.hota.hota_mean(),
            deta: s.hota.deta_mean(),
            assa: s.hota.assa_mean(),
            loca: s.hota.loca_mean(),
            idsw: c.num_switches,
            fp: c.num_false_positives,
            fn_: c.num_misses,
            frag: c.num_fragmentations,
            mt: c.mostly_tracked,
            pt: c.partially_tracked,
            ml: c.mostly_lost,
            gt: c.num_objects,
            predictions: c.num_predictions,
            frames: c.num_frames,
            matching: if dist.is_some() { "dist" } else { "iou" },
            threshold,
        }
    }

    fn human(&self) -> String {
        let pct = |v: Option<f64>| fmt_opt(v.map(|x| 100.0 * x), 2);
        let mut t = Table::new(["metric", "value"]);
        t.row(["MOTA (%)".to_string(), pct(self.mota)]);
        let motp_label = if self.matching == "dist" {
            "MOTP (m, mean distance)"
        } else {
            "MOTP (%, mean IoU)"
        };
        t.row([motp_label.to_string(), fmt_opt(self.motp, 3)]);
        t.row(["IDF1 (%)".to_string(), pct(self.idf1)]);
        t.row(["HOTA (%)".to_string(), pct(Some(self.hota))]);
        t.row(["DetA (%)".to_string(), pct(Some(self.deta))]);
        t.row(["AssA (%)".to_string(), pct(Some(self.assa))]);
        t.row(["LocA (%)".to_string(), pct(Some(self.loca))]);
        for (k, v) in [
            ("ID switches", self.idsw),
            ("false positives", self.fp),
            ("false negatives", self.fn_),
            ("fragmentations", self.frag),
            ("mostly tracked", self.mt),
            ("partially tracked", self.pt),
            ("mostly lost", self.ml),
            ("GT boxes", self.gt),
            ("result boxes", self.predictions),
            ("frames", self.frames),
        ] {
            t.row([k.to_string(), v.to_string()]);
        }
        let crit = if self.matching == "dist" {
            format!("world distance <= {} m", self.threshold)
        } else {
            format!("box IoU >= {}", self.threshold)
        };
        format!("matching: {crit}\n{}", t.render())
    }
}

/// Runs `quarry eval`.
pub fn run(args: &EvalArgs, out: &Output) -> CmdResult {
    let style = match args.gt_style {
        StyleArg::Auto => GtStyle::Auto,
        StyleArg::Mot15 => GtStyle::Mot15,
        StyleArg::Mot16 => GtStyle::Mot16,
    };
    if let Some(d) = args.dist
        && !(d.is_finite() && d > 0.0 && d <= MAX_DIST)
    {
        return Err(format!(
            "--dist {d}: expected a distance in world units (metres in MOTChallenge) > 0 and at most {MAX_DIST:e}"
        )
        .into());
    }
    if !(args.iou > 0.0 && args.iou <= 1.0) {
        return Err(format!("--iou {}: expected an IoU in (0, 1]", args.iou).into());
    }
    let gt = read_gt_file(&args.gt, style)
        .map_err(|e| format!("ground truth {}: {e}", args.gt.display()))?;
    let res =
        read_results_file(&args.res).map_err(|e| format!("results {}: {e}", args.res.display()))?;
    let (summary, threshold) = if let Some(d) = args.dist {
        let sim = Euclidean::new(d)?;
        let frames = to_point_frames(&gt, &res, 0.5)?;
        (MotEvaluation::new(&frames, &sim)?.summary()?, d)
    } else {
        let sim = Iou::new(args.iou)?;
        let frames = to_frames(&gt, &res, 0.5)?;
        (MotEvaluation::new(&frames, &sim)?.summary()?, args.iou)
    };
    let report = EvalReport::new(&summary, args.dist, threshold);
    out.emit(&report, || report.human())
}
