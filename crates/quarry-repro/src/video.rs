//! Paper 004: the watershed + SIFT pools tracker ([`quarry_trackers::watershed_sift`]) on the
//! synthetic video `walkers-v1` of [`quarry_sim::walkers`] (spec 004 §5.2-5.3).
//!
//! - [`run_walkers`] runs a configuration on a scenario (frames generated one at a time) and
//!   keeps every reported box with its occlusion flag and pool size ([`VideoRun`]).
//! - [`check_walkers`] scores a run against the scenario's ground truth and events: the gating
//!   checks E1-E6 of §5.2, each with the numbers behind it ([`WalkersChecks`]); [`check_empty`]
//!   is E2's second half (no track on `walkers-v1-empty`), [`check_determinism`] is E7.
//! - [`threshold_grid`] is the §5.3 study: τ_split × ρ × W_del, each run scored (MOTA, IDF1,
//!   IDSW, centre RMSE) and compared with the default run ([`GridRow`]).
//! - [`VideoRun::pool_series`] is Fig. 10(b): the pool size per target and frame.
//!
//! The tracker is configured from the walkers' geometry alone: the `paper` profile's 30 × 80
//! box (σ = 8, the paper's values) fits the 26 × 76 silhouette; nothing is set from a run.
//!
//! ```
//! use quarry_repro::video::{check_determinism, run_walkers};
//! use quarry_sim::walkers::{WalkersScenario, WalkersVariant};
//! use quarry_trackers::watershed_sift::WatershedSiftConfig;
//! let sc = WalkersScenario::new(WalkersVariant::Empty)?;
//! let cfg = WatershedSiftConfig::paper();
//! let a = run_walkers(&sc, &cfg, Some(3), |_| {})?;
//! let b = run_walkers(&sc, &cfg, Some(3), |_| {})?;
//! assert_eq!(a.frames, 3);
//! assert!(check_determinism(&a, &b)?.identical);
//! # Ok::<(), quarry_repro::ReproError>(())
//! ```

use std::collections::{BTreeMap, BTreeSet};

use quarry_core::{BBox, MultiTargetTracker, Stamp, TrackStatus};
use quarry_eval::motchallenge::{GtRow, MotRow, to_frames, write_results};
use quarry_eval::{Iou, MotEvaluation};
use quarry_sim::walkers::{GroundTruthObject, WalkersEvents, WalkersScenario};
use quarry_trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use serde::{Deserialize, Serialize};

use crate::ReproError;

/// Seconds per frame of the walkers videos' stamps (25 fps, nominal).
pub const FRAME_DT: f64 = 0.04;

/// One reported box.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReportedBox {
    /// Frame, 0-based.
    pub t: u64,
    /// Track id.
    pub id: u32,
    /// The box (0-based pixel coordinates, centre form).
    pub bbox: BBox,
    /// Reported as occluded.
    pub occluded: bool,
    /// The target's pool size after the frame (0 when the target was not found).
    pub pool: usize,
}

/// One run of the tracker on a walkers video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VideoRun {
    /// Sequence name.
    pub sequence: String,
    /// Frames processed (0..frames).
    pub frames: u64,
    /// Every reported box, in frame order.
    pub boxes: Vec<ReportedBox>,
    /// Pool size of every live target (reported or not) per frame: `(t, id, size, occluded)`.
    pub pools: Vec<(u64, u32, usize, bool)>,
    /// Mean tracker time per frame, milliseconds (informational; never compared).
    pub ms_per_frame: f64,
    /// Median and 95th percentile (nearest rank) of the tracker time per frame, milliseconds
    /// (informational; never compared; spec §7.2 states its goal on these).
    pub ms_p50_p95: [f64; 2],
}

/// The `q`-quantile (0..=1) of `values` by the nearest-rank rule (the smallest value with at
/// least `q`·n values at or below it); NaN for an empty slice.
#[must_use]
pub fn nearest_rank(values: &[f64], q: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let rank = (q.clamp(0.0, 1.0) * v.len() as f64).ceil() as usize;
    v[rank.clamp(1, v.len()) - 1]
}

impl VideoRun {
    /// The results as MOTChallenge rows (1-based frame and box, conf 1).
    #[must_use]
    pub fn mot_rows(&self) -> Vec<MotRow> {
        self.boxes
            .iter()
            .map(|b| {
                let [l, t, w, h] = b.bbox.to_ltwh();
                MotRow {
                    frame: b.t + 1,
                    id: i64::from(b.id),
                    bbox: [l + 1.0, t + 1.0, w, h],
                    conf: 1.0,
                    extra: [None; 3],
                }
            })
            .collect()
    }

    /// This run cut to its first `frames` frames (the tracker is causal, so a run of only
    /// those frames must equal this prefix: E7 on a shorter second run).
    #[must_use]
    pub fn prefix(&self, frames: u64) -> VideoRun {
        let frames = frames.min(self.frames);
        VideoRun {
            sequence: self.sequence.clone(),
            frames,
            boxes: self
                .boxes
                .iter()
                .filter(|b| b.t < frames)
                .copied()
                .collect(),
            pools: self
                .pools
                .iter()
                .filter(|p| p.0 < frames)
                .copied()
                .collect(),
            ms_per_frame: self.ms_per_frame,
            ms_p50_p95: self.ms_p50_p95,
        }
    }

    /// The results file's bytes (MOTChallenge, as `quarry video` writes it).
    ///
    /// # Errors
    /// Formatting fails (not expected: the writer is a `Vec`).
    pub fn results_text(&self) -> Result<Vec<u8>, ReproError> {
        let mut buf = Vec::new();
        write_results(&mut buf, &self.mot_rows())?;
        Ok(buf)
    }

    /// Fig. 10(b): per target id, its pool size per frame `(t, size)` while it lives.
    #[must_use]
    pub fn pool_series(&self) -> BTreeMap<u32, Vec<(u64, usize)>> {
        let mut m: BTreeMap<u32, Vec<(u64, usize)>> = BTreeMap::new();
        for &(t, id, n, _) in &self.pools {
            m.entry(id).or_default().push((t, n));
        }
        m
    }
}

/// Runs `cfg` on the first `frames` frames of `scenario` (all when `None`), generating each
/// frame in turn; `progress` is called with the number of frames done.
///
/// # Errors
/// An invalid configuration, `frames` = 0 or beyond the video, a tracker failure.
pub fn run_walkers(
    scenario: &WalkersScenario,
    cfg: &WatershedSiftConfig,
    frames: Option<u64>,
    mut progress: impl FnMut(u64),
) -> Result<VideoRun, ReproError> {
    let n = frames.unwrap_or(scenario.len());
    if n == 0 || n > scenario.len() {
        return Err(ReproError::Invalid(format!(
            "frames {n}: {} has 1..={} frames",
            scenario.name(),
            scenario.len()
        )));
    }
    let mut tr = WatershedSiftTracker::new(cfg.clone())?;
    let mut boxes = Vec::new();
    let mut pools = Vec::new();
    let mut ms = Vec::with_capacity(n as usize);
    for t in 0..n {
        let f = scenario.frame(t)?;
        let start = std::time::Instant::now();
        let reports = tr.step(Stamp::from_frame(t, FRAME_DT), &f)?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
        let targets = tr.targets();
        for r in &reports {
            let Some(bbox) = r.bbox else { continue };
            let pool = targets
                .iter()
                .find(|x| x.report_id == r.id)
                .map_or(0, |x| x.pool.len());
            boxes.push(ReportedBox {
                t,
                id: r.id.0,
                bbox,
                occluded: r.status == TrackStatus::Occluded,
                pool,
            });
        }
        pools.extend(
            targets
                .iter()
                .map(|x| (t, x.report_id.0, x.pool.len(), x.occluded)),
        );
        progress(t + 1);
    }
    Ok(VideoRun {
        sequence: scenario.name().to_owned(),
        frames: n,
        boxes,
        pools,
        ms_per_frame: ms.iter().sum::<f64>() / n as f64,
        ms_p50_p95: [nearest_rank(&ms, 0.5), nearest_rank(&ms, 0.95)],
    })
}

/// The scenario's ground truth as MOTChallenge rows (1-based), frames `0..frames`.
///
/// # Errors
/// `frames` beyond the video.
pub fn gt_rows(scenario: &WalkersScenario, frames: u64) -> Result<Vec<GtRow>, ReproError> {
    let mut out = Vec::new();
    for t in 0..frames {
        out.extend(scenario.ground_truth(t)?.iter().map(gt_row));
    }
    Ok(out)
}

fn gt_row(g: &GroundTruthObject) -> GtRow {
    let [l, t, w, h] = g.full_box.to_ltwh();
    GtRow {
        frame: g.frame + 1,
        id: i64::from(g.id),
        bbox: [l + 1.0, t + 1.0, w, h],
        consider: g.flag,
        class: Some(1),
        visibility: Some(g.visibility),
        world_xy: None,
    }
}

/// The MOT metrics of a run (IoU ≥ 0.5 for CLEAR and IDF1, HOTA averaged over α).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// MOTA.
    pub mota: f64,
    /// MOTP (mean IoU of matches).
    pub motp: f64,
    /// IDF1.
    pub idf1: f64,
    /// HOTA.
    pub hota: f64,
    /// ID switches.
    pub idsw: usize,
    /// False positives.
    pub fp: usize,
    /// Misses.
    pub fn_: usize,
    /// Scored ground-truth boxes.
    pub gt: usize,
    /// RMSE of the matched track centres to their ground-truth box centres, pixels.
    pub centre_rmse: f64,
}

/// A run scored against the scenario: metrics, and the CLEAR matches per frame (index = t).
#[derive(Debug, Clone)]
pub struct Scored {
    /// The metrics.
    pub metrics: Metrics,
    /// `matches[t]` = the (walker id, track id) pairs CLEAR MOT settles on in frame t.
    pub matches: Vec<Vec<(u32, u32)>>,
    /// Matched track centre per frame and walker: `centres[t][walker id]`.
    pub centres: Vec<BTreeMap<u32, [f64; 2]>>,
}

/// Scores `run` against `scenario`'s ground truth on the run's frames.
///
/// # Errors
/// Scoring fails (a duplicate id in a frame, non-finite boxes).
pub fn score(scenario: &WalkersScenario, run: &VideoRun) -> Result<Scored, ReproError> {
    let gt = gt_rows(scenario, run.frames)?;
    let rows = run.mot_rows();
    // one Frame per frame 0..frames, even when neither file has a row there
    let mut frames = to_frames(&gt, &rows, 0.5)?;
    let present: Vec<u64> = {
        let s: BTreeSet<u64> = gt
            .iter()
            .map(|g| g.frame)
            .chain(rows.iter().map(|r| r.frame))
            .collect();
        s.into_iter().collect()
    };
    let mut full = vec![
        quarry_eval::Frame {
            gt: vec![],
            hyp: vec![]
        };
        run.frames as usize
    ];
    for (f, k) in frames.drain(..).zip(&present) {
        if let Some(slot) = full.get_mut((*k - 1) as usize) {
            *slot = f;
        }
    }
    let sim = Iou::new(0.5)?;
    let ev = MotEvaluation::new(&full, &sim)?;
    let s = ev.summary()?;
    let m = ev.clear_matches()?;
    let mut matches = Vec::with_capacity(m.len());
    let mut centres = Vec::with_capacity(m.len());
    let (mut se, mut n) = (0.0, 0usize);
    for (k, pairs) in m.iter().enumerate() {
        let f = &full[k];
        let centre = |b: &[f64; 4]| [b[0] + b[2] / 2.0, b[1] + b[3] / 2.0];
        let mut cm = BTreeMap::new();
        let mut pm = Vec::new();
        for &(g, h) in pairs {
            let (Some(gb), Some(hb)) = (
                f.gt.iter().find(|x| x.0 == g).map(|x| x.1),
                f.hyp.iter().find(|x| x.0 == h).map(|x| x.1),
            ) else {
                continue;
            };
            let (gc, hc) = (centre(&gb), centre(&hb));
            se += (gc[0] - hc[0]).powi(2) + (gc[1] - hc[1]).powi(2);
            n += 1;
            cm.insert(g as u32, hc);
            pm.push((g as u32, h as u32));
        }
        matches.push(pm);
        centres.push(cm);
    }
    let c = &s.clear;
    Ok(Scored {
        metrics: Metrics {
            mota: c.mota().unwrap_or(f64::NAN),
            motp: c.motp().unwrap_or(f64::NAN),
            idf1: s.identity.idf1().unwrap_or(f64::NAN),
            hota: s.hota.hota_mean(),
            idsw: c.num_switches,
            fp: c.num_false_positives,
            fn_: c.num_misses,
            gt: c.num_objects,
            centre_rmse: if n == 0 {
                f64::NAN
            } else {
                (se / n as f64).sqrt()
            },
        },
        matches,
        centres,
    })
}

/// E1: per walker, the first frame with a track centre inside its full box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Walker id.
    pub id: u32,
    /// Walker name.
    pub name: char,
    /// Frame at which it is ≥ 50 % in view.
    pub enters: u64,
    /// Latest frame allowed (enters + 30).
    pub deadline: u64,
    /// First frame (from its first visible frame on) with a track centre in its box.
    pub detected: Option<u64>,
    /// `detected <= deadline`.
    pub pass: bool,
}

/// E2: one track's share of frames with its centre inside some walker's full box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackPurity {
    /// Track id.
    pub id: u32,
    /// Frames in which it was reported.
    pub frames: usize,
    /// Frames with its centre inside a walker's full box.
    pub on_walker: usize,
    /// `on_walker / frames`.
    pub fraction: f64,
}

/// E3 and E4 for one walker of the crossing.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Crossing {
    /// Walker id.
    pub id: u32,
    /// Walker name.
    pub name: char,
    /// The track that carried it most often in frames 290-299 (CLEAR matches).
    pub carrier_before: Option<u32>,
    /// Frames of 300-330 in which that track was reported as occluded.
    pub occluded_frames: Vec<u64>,
    /// Scored frames of 340-449 in which the walker has ground truth.
    pub frames_after: usize,
    /// Of those, frames in which `carrier_before` carries it again.
    pub carried_after: usize,
    /// `carried_after / frames_after`.
    pub fraction_after: f64,
}

/// E5: the exit of walker C.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Exit {
    /// The track that carried C most often over the run.
    pub carrier: Option<u32>,
    /// The carrier's last reported frame.
    pub carrier_last: Option<u64>,
    /// Reported boxes (any track) with a centre within 60 px of (799, 110) in frames 421-449.
    pub boxes_near_exit: usize,
    /// `carrier_last <= 420` and no box near the exit.
    pub pass: bool,
}

/// E6: the metrics against their starting targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsCheck {
    /// The run's metrics.
    pub metrics: Metrics,
    /// MOTA ≥ 0.75, IDF1 ≥ 0.75, HOTA ≥ 0.55.
    pub pass: bool,
}

/// E1-E6 of spec §5.2 on one run of `walkers-v1` (or a prefix of it: a check whose frames
/// were not run is reported as failed with its numbers empty).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WalkersChecks {
    /// E1 per walker.
    pub e1_detection: Vec<Detection>,
    /// E1 verdict.
    pub e1: bool,
    /// E2 per track.
    pub e2_tracks: Vec<TrackPurity>,
    /// E2 verdict (every track ≥ 80 %).
    pub e2: bool,
    /// E3/E4 per walker of the crossing (A, B).
    pub crossing: Vec<Crossing>,
    /// E3 verdict: A's and B's carriers flagged occluded in some frame of 300-330.
    pub e3: bool,
    /// ID switches over the run (E4).
    pub idsw: usize,
    /// E4 verdict: both carried again in ≥ 90 % of frames 340-449, IDSW ≤ 1.
    pub e4: bool,
    /// E5 details.
    pub e5_exit: Exit,
    /// E5 verdict.
    pub e5: bool,
    /// E6 details.
    pub e6_metrics: MetricsCheck,
    /// E6 verdict.
    pub e6: bool,
    /// Informational (spec: reported, not failed): frames in which a track carrying C or D
    /// was flagged occluded during their near pass (t 330-357).
    pub cd_occlusion_frames: Vec<u64>,
}

impl WalkersChecks {
    /// All of E1-E6 passed.
    #[must_use]
    pub fn all(&self) -> bool {
        self.e1 && self.e2 && self.e3 && self.e4 && self.e5 && self.e6
    }
}

/// The walker id of a name in the scenario.
fn id_of(ev: &WalkersEvents, name: char) -> Option<u32> {
    ev.walkers.iter().find(|w| w.name == name).map(|w| w.id)
}

/// The track most often matched to `walker` in frames `range`.
fn carrier(s: &Scored, walker: u32, range: std::ops::RangeInclusive<u64>) -> Option<u32> {
    let mut count: BTreeMap<u32, usize> = BTreeMap::new();
    for t in range {
        let Some(m) = s.matches.get(t as usize) else {
            break;
        };
        for &(g, h) in m {
            if g == walker {
                *count.entry(h).or_default() += 1;
            }
        }
    }
    count
        .into_iter()
        .max_by_key(|&(h, n)| (n, std::cmp::Reverse(h)))
        .map(|x| x.0)
}

fn inside(b: &BBox, c: [f64; 2]) -> bool {
    (c[0] - b.cx).abs() <= b.w / 2.0 && (c[1] - b.cy).abs() <= b.h / 2.0
}

/// Scores E1-E6 of spec §5.2 for a run of `walkers-v1` (the frame numbers of the checks are
/// the spec's, 0-based).
///
/// # Errors
/// Scoring fails, or the scenario lacks a walker A-D.
pub fn check_walkers(
    scenario: &WalkersScenario,
    run: &VideoRun,
) -> Result<WalkersChecks, ReproError> {
    let ev = scenario.events()?;
    let s = score(scenario, run)?;
    let last = run.frames.saturating_sub(1);
    let gt: Vec<Vec<GroundTruthObject>> = (0..run.frames)
        .map(|t| scenario.ground_truth(t))
        .collect::<Result<_, _>>()?;
    let mut by_frame: Vec<Vec<&ReportedBox>> = vec![Vec::new(); run.frames as usize];
    for b in &run.boxes {
        by_frame[b.t as usize].push(b);
    }
    let need = |n: char| {
        id_of(&ev, n)
            .ok_or_else(|| ReproError::Invalid(format!("{} has no walker {n}", scenario.name())))
    };
    let (a, b, c, d) = (need('A')?, need('B')?, need('C')?, need('D')?);

    // E1
    let mut e1_detection = Vec::new();
    for w in &ev.walkers {
        let Some(enters) = w.half_in_view else {
            continue;
        };
        let deadline = enters + 30;
        let from = w.first_visible.unwrap_or(enters);
        let detected = (from..=deadline.min(last)).find(|&t| {
            gt[t as usize]
                .iter()
                .find(|g| g.id == w.id)
                .is_some_and(|g| {
                    by_frame[t as usize]
                        .iter()
                        .any(|r| inside(&g.full_box, [r.bbox.cx, r.bbox.cy]))
                })
        });
        e1_detection.push(Detection {
            id: w.id,
            name: w.name,
            enters,
            deadline,
            detected,
            pass: detected.is_some_and(|t| t <= deadline),
        });
    }
    let e1 = !e1_detection.is_empty() && e1_detection.iter().all(|d| d.pass);

    // E2
    let mut per: BTreeMap<u32, (usize, usize)> = BTreeMap::new();
    for r in &run.boxes {
        let e = per.entry(r.id).or_default();
        e.0 += 1;
        if gt[r.t as usize]
            .iter()
            .any(|g| inside(&g.full_box, [r.bbox.cx, r.bbox.cy]))
        {
            e.1 += 1;
        }
    }
    let e2_tracks: Vec<TrackPurity> = per
        .into_iter()
        .map(|(id, (n, k))| TrackPurity {
            id,
            frames: n,
            on_walker: k,
            fraction: k as f64 / n as f64,
        })
        .collect();
    let e2 = e2_tracks.iter().all(|p| p.fraction >= 0.8);

    // E3, E4
    let mut crossing = Vec::new();
    for (w, name) in [(a, 'A'), (b, 'B')] {
        let cb = carrier(&s, w, 290..=299);
        let occluded_frames = match cb {
            Some(h) => (300..=330u64.min(last))
                .filter(|&t| by_frame[t as usize].iter().any(|r| r.id == h && r.occluded))
                .collect(),
            None => Vec::new(),
        };
        let (mut n, mut k) = (0usize, 0usize);
        for t in 340..=449u64.min(last) {
            if gt[t as usize].iter().any(|g| g.id == w && g.flag) {
                n += 1;
                if cb.is_some_and(|h| s.matches[t as usize].contains(&(w, h))) {
                    k += 1;
                }
            }
        }
        crossing.push(Crossing {
            id: w,
            name,
            carrier_before: cb,
            occluded_frames,
            frames_after: n,
            carried_after: k,
            fraction_after: if n == 0 { 0.0 } else { k as f64 / n as f64 },
        });
    }
    let e3 = crossing.iter().all(|x| !x.occluded_frames.is_empty());
    let idsw = s.metrics.idsw;
    let e4 = crossing
        .iter()
        .all(|x| x.frames_after > 0 && x.fraction_after >= 0.9)
        && idsw <= 1;

    // E5
    let cc = carrier(&s, c, 0..=last);
    let carrier_last = cc.and_then(|h| run.boxes.iter().filter(|r| r.id == h).map(|r| r.t).max());
    let boxes_near_exit = run
        .boxes
        .iter()
        .filter(|r| (421..=449).contains(&r.t))
        .filter(|r| (r.bbox.cx - 799.0).hypot(r.bbox.cy - 110.0) <= 60.0)
        .count();
    let e5 = last >= 449
        && cc.is_some()
        && carrier_last.is_some_and(|t| t <= 420)
        && boxes_near_exit == 0;
    let e5_exit = Exit {
        carrier: cc,
        carrier_last,
        boxes_near_exit,
        pass: e5,
    };

    // E6
    let m = s.metrics;
    let e6 = m.mota >= 0.75 && m.idf1 >= 0.75 && m.hota >= 0.55;

    // C/D near pass (informational)
    let cd: BTreeSet<u32> = [c, d]
        .iter()
        .filter_map(|&w| carrier(&s, w, 320..=367))
        .collect();
    let cd_occlusion_frames = (330..=357u64.min(last))
        .filter(|&t| {
            by_frame[t as usize]
                .iter()
                .any(|r| r.occluded && cd.contains(&r.id))
        })
        .collect();

    Ok(WalkersChecks {
        e1_detection,
        e1,
        e2_tracks,
        e2,
        crossing,
        e3,
        idsw,
        e4,
        e5_exit,
        e5,
        e6_metrics: MetricsCheck {
            metrics: m,
            pass: e6,
        },
        e6,
        cd_occlusion_frames,
    })
}

/// E2's second half: the tracks reported on `walkers-v1-empty` (none expected).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EmptyCheck {
    /// Frames run.
    pub frames: u64,
    /// Distinct track ids reported.
    pub tracks: usize,
    /// Boxes reported.
    pub boxes: usize,
    /// No box at all.
    pub pass: bool,
}

/// Scores a run on a video without walkers: any reported box fails.
#[must_use]
pub fn check_empty(run: &VideoRun) -> EmptyCheck {
    let ids: BTreeSet<u32> = run.boxes.iter().map(|b| b.id).collect();
    EmptyCheck {
        frames: run.frames,
        tracks: ids.len(),
        boxes: run.boxes.len(),
        pass: run.boxes.is_empty(),
    }
}

/// E7: two runs' result files compared byte for byte.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct DeterminismCheck {
    /// Result lines of the first run.
    pub lines: usize,
    /// The files are byte-identical.
    pub identical: bool,
    /// The first differing line (1-based), if any.
    pub first_difference: Option<usize>,
}

/// E7: compares the MOTChallenge result files of two runs byte for byte.
///
/// # Errors
/// Formatting a result file fails.
pub fn check_determinism(a: &VideoRun, b: &VideoRun) -> Result<DeterminismCheck, ReproError> {
    let (ta, tb) = (a.results_text()?, b.results_text()?);
    let first_difference = if ta == tb {
        None
    } else {
        let la: Vec<&[u8]> = ta.split(|&c| c == b'\n').collect();
        let lb: Vec<&[u8]> = tb.split(|&c| c == b'\n').collect();
        Some(
            la.iter()
                .zip(&lb)
                .position(|(x, y)| x != y)
                .unwrap_or(la.len().min(lb.len()))
                + 1,
        )
    };
    Ok(DeterminismCheck {
        lines: ta.split(|&c| c == b'\n').count() - 1,
        identical: ta == tb,
        first_difference,
    })
}

/// One configuration of the §5.3 threshold study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridRow {
    /// τ_split.
    pub tau_split: f64,
    /// ρ.
    pub ratio: f32,
    /// W_del.
    pub w_del: f64,
    /// This is the base configuration's own values.
    pub default: bool,
    /// The metrics (MOTA, IDF1, IDSW, centre RMSE, ...).
    pub metrics: Metrics,
    /// Largest per-frame difference, pixels, between this run's and the default run's track
    /// centres matched to the same walker (frames where both match it).
    pub max_centre_diff: f64,
    /// Frames × walkers matched in exactly one of the two runs.
    pub match_differences: usize,
}

/// The grid of spec §5.3.
pub const GRID_TAU_SPLIT: [f64; 3] = [0.4, 0.48, 0.6];
/// The grid of spec §5.3.
pub const GRID_RATIO: [f32; 2] = [0.5, 0.7];
/// The grid of spec §5.3.
pub const GRID_W_DEL: [f64; 2] = [-7.0, -9.0];

/// Runs the §5.3 grid τ_split × ρ × W_del over `base` on `frames` frames of `scenario` (all
/// when `None`) and compares each run with `base` itself. `progress(done, total)` is called
/// after each run.
///
/// # Errors
/// A run or its scoring fails.
pub fn threshold_grid(
    scenario: &WalkersScenario,
    base: &WatershedSiftConfig,
    frames: Option<u64>,
    mut progress: impl FnMut(usize, usize),
) -> Result<Vec<GridRow>, ReproError> {
    let def_run = run_walkers(scenario, base, frames, |_| {})?;
    let def = score(scenario, &def_run)?;
    let total = GRID_TAU_SPLIT.len() * GRID_RATIO.len() * GRID_W_DEL.len();
    let mut out = Vec::with_capacity(total);
    for &tau in &GRID_TAU_SPLIT {
        for &rho in &GRID_RATIO {
            for &wd in &GRID_W_DEL {
                let cfg = WatershedSiftConfig {
                    tau_split: tau,
                    ratio: rho,
                    w_del: wd,
                    ..base.clone()
                };
                let is_default = tau == base.tau_split && rho == base.ratio && wd == base.w_del;
                let s = if is_default {
                    def.clone()
                } else {
                    score(scenario, &run_walkers(scenario, &cfg, frames, |_| {})?)?
                };
                let (mut max_d, mut diffs) = (0.0f64, 0usize);
                for (x, y) in s.centres.iter().zip(&def.centres) {
                    let keys: BTreeSet<&u32> = x.keys().chain(y.keys()).collect();
                    for k in keys {
                        match (x.get(k), y.get(k)) {
                            (Some(p), Some(q)) => {
                                max_d = max_d.max((p[0] - q[0]).hypot(p[1] - q[1]));
                            }
                            _ => diffs += 1,
                        }
                    }
                }
                out.push(GridRow {
                    tau_split: tau,
                    ratio: rho,
                    w_del: wd,
                    default: is_default,
                    metrics: s.metrics,
                    max_centre_diff: max_d,
                    match_differences: diffs,
                });
                progress(out.len(), total);
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::nearest_rank;

    #[test]
    fn nearest_rank_quantiles() {
        let v: Vec<f64> = (1..=20).rev().map(f64::from).collect();
        assert_eq!(nearest_rank(&v, 0.5), 10.0);
        assert_eq!(nearest_rank(&v, 0.95), 19.0);
        assert_eq!(nearest_rank(&v, 0.0), 1.0);
        assert_eq!(nearest_rank(&v, 1.0), 20.0);
        assert_eq!(nearest_rank(&[7.0], 0.95), 7.0);
        assert!(nearest_rank(&[], 0.5).is_nan());
    }
}
