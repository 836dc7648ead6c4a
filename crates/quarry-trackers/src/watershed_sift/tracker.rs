//! [`WatershedSiftTracker`]: the per-frame procedure of spec 004 §2.17.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::time::Instant;

use quarry_core::{
    BBox, Keypoint, MultiTargetTracker, Plane, Segmentation, Stamp, TrackFlags, TrackId,
    TrackReport, TrackStatus,
};
use quarry_vision::{
    LinkKind, MedianBackground, RegionAdjacency, RegionMapping, Sift, SiftDescriptor, SiftParams,
    WeightedPool,
};
use serde::Serialize;

use super::config::WatershedSiftConfig;
use super::frontend::MotionFrontEnd;
use crate::{TrackerConfig, TrackerError};

/// How a region entered a target's list (spec §2.9); the order is the priority of step 7.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum Provenance {
    /// The bidirectional successor of one of the target's regions (step 1).
    Bidirectional,
    /// A one-way successor (step 3).
    Merge,
    /// A fragment accepted by the SIFT ownership test (step 4).
    SplitSift,
    /// Close to one of the target's old minima (step 5).
    Distance,
    /// A moving point absorbed or starting the target (step 6).
    MovingPoint,
    /// The occlusion region of an occluded target (§2.14).
    Occlusion,
    /// A region assigned at separation (§2.15).
    Separation,
    /// The region under the centre of a target that had lost its regions (`reacquire`, an
    /// extension); the last in step 7's priority.
    Reacquired,
}

impl Provenance {
    /// Rank of step 7's priority (lower wins).
    fn rank(self) -> u8 {
        match self {
            Self::Separation | Self::Occlusion => 0,
            Self::Bidirectional => 1,
            Self::Merge => 2,
            Self::SplitSift => 3,
            Self::Distance => 4,
            Self::MovingPoint => 5,
            Self::Reacquired => 6,
        }
    }
}

/// One region of a target's list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct RegionRef {
    /// Label in the current frame's label image.
    pub label: u32,
    /// Its representative minimum `(x, y)`.
    pub minimum: (u32, u32),
    /// How it was added.
    pub provenance: Provenance,
}

/// A tracked person (spec §2.9).
#[derive(Debug, Clone)]
pub struct Target {
    /// Identity (never reused).
    pub id: TrackId,
    /// Tracked through an occlusion (§2.14) in the last frame.
    pub occluded: bool,
    /// The region list S_k.
    pub regions: Vec<RegionRef>,
    /// Centre O_c, eq. (8).
    pub centre: [f64; 2],
    /// The weighted SIFT pool.
    pub pool: WeightedPool<SiftDescriptor>,
    /// The previous frame's ROI descriptors D_prev.
    pub prev_desc: Vec<SiftDescriptor>,
    /// Frame index of creation.
    pub born: u64,
    history: VecDeque<[f64; 2]>,
    lost: usize,
    fresh: bool,
    placed: bool,
    /// Consecutive frames of box overlap with younger targets (fusion, an extension).
    fuse_streak: BTreeMap<TrackId, usize>,
    /// The last foreground fit (`fg_box`): box centre minus O_c, and size.
    fit: Option<[f64; 4]>,
    /// Consecutive visible frames without foreground support (`fg_gate`).
    no_fg: usize,
    /// The box reported this frame (None: not reported).
    report: Option<BBox>,
    /// The centre at the first frame that ended (for `moved`).
    origin: Option<[f64; 2]>,
    /// The centre has been half a box width away from `origin` at some frame.
    moved: bool,
    /// A companion (`fg_pairs`): the target whose foreground this one's person shares.
    host: Option<TrackId>,
    /// Consecutive frames this target's foreground was a pair (`fg_pairs`).
    pair_streak: usize,
    /// The centres of the target's part and of the other part when the streak began.
    pair_first: [[f64; 2]; 2],
    /// The id this target is reported under: its own [`id`](Self::id), or with `recall_ids`
    /// the id of a lost target whose person it was found on (docs of `recall_ids`).
    pub report_id: TrackId,
    /// The last frames this target was reported in with a box that observed it: (frame, box
    /// centre), at most [`RECALL_VELOCITY_FRAMES`] + 1 of them (`recall_ids`). A box that only
    /// repeats the last one is not among them (see `held`).
    reported: VecDeque<(u64, [f64; 2])>,
    /// The last frame this target was reported in, fitted or held (`recall_ids`).
    last_shown: Option<u64>,
    /// This frame's centre is the last frame's: the target is occluded, holds only regions
    /// of the occlusion, and its pool located it nowhere (§2.14), so nothing placed it.
    frozen: bool,
    /// This frame's box repeats the last one: the centre is `frozen` and no box was fitted to
    /// this frame's foreground. It is no observation of the person, so `recall_ids` does not
    /// measure motion from it.
    held: bool,
}

/// Frames over which a lost target's velocity is measured for `recall_ids`: its last five
/// reported boxes (under a second at PETS09's 7 fps; long enough to average the fitted
/// boxes' jitter of a few pixels, short enough to follow a turn).
const RECALL_VELOCITY_FRAMES: usize = 5;

/// A target that ended while `recall_ids` may still hand its id to a newborn.
#[derive(Debug, Clone)]
struct Ended {
    id: TrackId,
    /// The last frame it was reported in (fitted or held): the recall window counts from it.
    last: u64,
    /// The last frame its box was fitted, and that box's centre: the prediction starts there.
    at: u64,
    centre: [f64; 2],
    velocity: [f64; 2],
}

/// What `recall_ids` keeps of a target: its last reported frame (fitted or held), and its
/// last fitted frame, box centre and velocity (px per frame) over the fitted boxes of
/// `reported`.
fn last_motion(tg: &Target) -> Option<Ended> {
    let last = tg.last_shown?;
    let &(f1, c1) = tg.reported.back()?;
    let &(f0, c0) = tg.reported.front()?;
    let v = if f1 > f0 {
        let dt = (f1 - f0) as f64;
        [(c1[0] - c0[0]) / dt, (c1[1] - c0[1]) / dt]
    } else {
        [0.0; 2]
    };
    Some(Ended {
        id: tg.report_id,
        last,
        at: f1,
        centre: c1,
        velocity: v,
    })
}

impl Target {
    /// A target created at frame `born` (its pool is seeded at its first step 8).
    fn start(
        id: TrackId,
        centre: [f64; 2],
        regions: Vec<RegionRef>,
        pool: WeightedPool<SiftDescriptor>,
        born: u64,
    ) -> Self {
        Self {
            id,
            occluded: false,
            regions,
            centre,
            pool,
            prev_desc: Vec::new(),
            born,
            history: VecDeque::new(),
            lost: 0,
            fresh: true,
            placed: false,
            fuse_streak: BTreeMap::new(),
            fit: None,
            no_fg: 0,
            report: None,
            origin: None,
            moved: false,
            host: None,
            pair_streak: 0,
            pair_first: [[0.0; 2]; 2],
            report_id: id,
            reported: VecDeque::new(),
            last_shown: None,
            frozen: false,
            held: false,
        }
    }
}

/// Per-target diagnostics of one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TargetDiagnostics {
    /// The target's own id ([`Target::id`]; the occlusion groups of [`FrameDiagnostics`] use
    /// it too). Its boxes are reported under [`Target::report_id`], which differs after
    /// `recall_ids` handed it a lost target's id.
    pub id: u32,
    /// Centre O_c.
    pub centre: [f64; 2],
    /// Pool size.
    pub pool: usize,
    /// Occluded in this frame.
    pub occluded: bool,
    /// Number of regions.
    pub regions: usize,
}

/// Wall-clock time per stage of one frame, microseconds (diagnostics only).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct StageTimes {
    /// Ramp, blur, minima, watershed (the front end's segmentation).
    pub segment_us: f64,
    /// Region mapping, adjacency, trajectories and the moving-point test.
    pub map_us: f64,
    /// SIFT on target areas.
    pub sift_us: f64,
    /// Everything else: ownership tests, pools, resolution.
    pub track_us: f64,
    /// Background model update and the foreground box fits (`fg_box`, `fg_gate`).
    pub foreground_us: f64,
}

/// What happened in one frame (spec §8 `FrameDiagnostics`, for the figures of §5.3).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct FrameDiagnostics {
    /// 0-based frame index.
    pub frame: u64,
    /// Number of watershed regions.
    pub regions: usize,
    /// Bidirectional links from the previous frame.
    pub bidirectional: usize,
    /// Merges.
    pub merges: usize,
    /// Splits.
    pub splits: usize,
    /// Moving points `(x, y)` of this frame.
    pub moving: Vec<(u32, u32)>,
    /// Targets alive after this frame.
    pub targets: Vec<TargetDiagnostics>,
    /// Occlusion groups of this frame (target ids).
    pub occlusion_groups: Vec<Vec<u32>>,
    /// Targets created.
    pub created: usize,
    /// Targets terminated.
    pub terminated: usize,
    /// Stage times.
    pub times: StageTimes,
}

/// The described SIFT keypoints of one padded crop (those some area asked for).
struct CropFeatures {
    /// Keypoints in crop coordinates with their descriptors, in the order first asked for.
    described: Vec<(Keypoint, SiftDescriptor)>,
    /// The crop's top-left corner in the frame.
    origin: (u32, u32),
    /// The crop's scale space, kept for the frame (a crop is asked for again in about 2 % of
    /// the calls on PETS09, with another area).
    ss: quarry_vision::sift::ScaleSpace,
}

/// Whether two keypoints are the same detection (every field the detector sets).
fn same_keypoint(a: &Keypoint, b: &Keypoint) -> bool {
    a.x.to_bits() == b.x.to_bits()
        && a.y.to_bits() == b.y.to_bits()
        && a.sigma.to_bits() == b.sigma.to_bits()
        && a.angle_deg.to_bits() == b.angle_deg.to_bits()
        && a.response.to_bits() == b.response.to_bits()
        && a.octave == b.octave
        && a.layer == b.layer
        && a.layer_offset.to_bits() == b.layer_offset.to_bits()
}

/// SIFT results per crop rectangle of the current frame (spec §2.10: memoised per frame).
/// Keypoints are those detected on the whole padded crop, but only the extrema that lie in
/// the area asked for are given orientations and descriptors ([`Sift::detect_in_where`]): a
/// keypoint depends only on the crop's scale space and its own extremum, so K(A) is exactly
/// what detecting and describing every keypoint of the crop and then filtering would give (the
/// padding's keypoints, most of a crop's, are never oriented or described). A crop asked for
/// again with another area reuses the descriptors it already has.
struct FeatureCache<'a> {
    frame: &'a Plane<u8>,
    sift: &'a Sift,
    pad: u32,
    crops: BTreeMap<[u32; 4], CropFeatures>,
    us: f64,
}

impl<'a> FeatureCache<'a> {
    /// An empty cache over `frame`.
    fn new(frame: &'a Plane<u8>, sift: &'a Sift, pad: u32) -> Self {
        Self {
            frame,
            sift,
            pad,
            crops: BTreeMap::new(),
            us: 0.0,
        }
    }

    /// The scale space of the crop `[x0, y0, x1, y1]` (inclusive).
    fn scale_space(&self, key: [u32; 4]) -> Result<quarry_vision::sift::ScaleSpace, TrackerError> {
        let w = self.frame.width as usize;
        let (x0, y0) = (key[0], key[1]);
        let sub = Plane::from_fn(key[2] - x0 + 1, key[3] - y0 + 1, |x, y| {
            f32::from(self.frame.data[(y0 + y) as usize * w + (x0 + x) as usize])
        });
        Ok(self.sift.scale_space(&sub)?)
    }

    /// Keypoints (frame coordinates) and descriptors of the crop `[x0, y0, x1, y1]`
    /// (inclusive) padded by `pad`, restricted to the keypoints for which `keep(x, y)` holds
    /// (frame coordinates), in the detector's order.
    fn crop(
        &mut self,
        rect: [u32; 4],
        keep: impl Fn(f32, f32) -> bool + Sync,
    ) -> Result<(Vec<[f64; 2]>, Vec<SiftDescriptor>), TrackerError> {
        let t = Instant::now();
        let (w, h) = self.frame.dimensions();
        let x0 = rect[0].saturating_sub(self.pad);
        let y0 = rect[1].saturating_sub(self.pad);
        let x1 = (rect[2] + self.pad).min(w - 1);
        let y1 = (rect[3] + self.pad).min(h - 1);
        let key = [x0, y0, x1, y1];
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let (mut pos, mut out) = (Vec::new(), Vec::new());
        if cw >= quarry_vision::sift::MIN_SIDE && ch >= quarry_vision::sift::MIN_SIDE {
            let (ox, oy) = (x0 as f32, y0 as f32);
            if !self.crops.contains_key(&key) {
                let ss = self.scale_space(key)?;
                self.crops.insert(
                    key,
                    CropFeatures {
                        described: Vec::new(),
                        origin: (x0, y0),
                        ss,
                    },
                );
            }
            let entry = self
                .crops
                .get_mut(&key)
                .ok_or_else(|| TrackerError::State("internal: crop cache entry".into()))?;
            let ss = &entry.ss;
            let kps = self.sift.detect_in_where(ss, |x, y| keep(x + ox, y + oy));
            // each keypoint's descriptor: one already described, or the next fresh one
            let known: Vec<Option<usize>> = kps
                .iter()
                .map(|k| {
                    entry
                        .described
                        .iter()
                        .position(|(d, _)| same_keypoint(d, k))
                })
                .collect();
            let fresh: Vec<Keypoint> = kps
                .iter()
                .zip(&known)
                .filter(|(_, i)| i.is_none())
                .map(|(k, _)| *k)
                .collect();
            let mut next = entry.described.len();
            if !fresh.is_empty() {
                let d = self.sift.describe_in(ss, &fresh)?;
                entry.described.extend(
                    fresh
                        .into_iter()
                        .zip(d.iter().map(quarry_vision::sift::quantize)),
                );
            }
            for (k, i) in kps.iter().zip(known) {
                let i = i.unwrap_or_else(|| {
                    next += 1;
                    next - 1
                });
                let (x, y) = (k.x + entry.origin.0 as f32, k.y + entry.origin.1 as f32);
                pos.push([f64::from(x), f64::from(y)]);
                out.push(entry.described[i].1);
            }
        }
        self.us += t.elapsed().as_secs_f64() * 1e6;
        Ok((pos, out))
    }
}

/// The SIFT features of one target's ROI: keypoint positions (frame coordinates) and their
/// quantised descriptors.
pub type RoiFeatures = (Vec<[f64; 2]>, Vec<SiftDescriptor>);

/// Per-frame region geometry.
struct RegionGeometry {
    /// Inclusive bounding boxes `[x0, y0, x1, y1]`, by label − 1.
    bbox: Vec<[u32; 4]>,
}

impl RegionGeometry {
    /// One pass over the label image by runs of equal labels along each row (a region's
    /// pixels come in long runs, so this touches each region's box a few times per row
    /// instead of once per pixel, with no division per pixel).
    fn new(seg: &Segmentation) -> Self {
        let mut bbox = vec![[u32::MAX, u32::MAX, 0, 0]; seg.n_regions()];
        let w = seg.labels.width as usize;
        if w == 0 {
            return Self { bbox };
        }
        for (y, row) in seg.labels.data.chunks_exact(w).enumerate() {
            let y = y as u32;
            let mut x = 0;
            while x < row.len() {
                let (l, start) = (row[x], x);
                while x < row.len() && row[x] == l {
                    x += 1;
                }
                if l == 0 {
                    continue;
                }
                if let Some(b) = bbox.get_mut(l as usize - 1) {
                    b[0] = b[0].min(start as u32);
                    b[1] = b[1].min(y);
                    b[2] = b[2].max((x - 1) as u32);
                    b[3] = b[3].max(y);
                }
            }
        }
        Self { bbox }
    }
}

/// The watershed + SIFT pools tracker of spec 004 (Hu et al. 2012): input the grey frame,
/// output one fixed-size box per target (see the module docs).
#[derive(Debug, Clone)]
pub struct WatershedSiftTracker {
    cfg: WatershedSiftConfig,
    front: MotionFrontEnd,
    sift: Sift,
    targets: Vec<Target>,
    /// Occlusion groups of the previous frame: (label of that frame, member ids).
    groups_prev: Vec<(u32, Vec<TrackId>)>,
    next_id: u32,
    frames: u64,
    diagnostics: FrameDiagnostics,
    /// The running background (`fg_box`, `fg_gate` or `fg_births`).
    background: Option<MedianBackground>,
    /// Foreground birth candidates of the last frame: blob box `[x0, y0, x1, y1)` and the
    /// number of consecutive frames it was seen.
    birth_candidates: Vec<([f64; 4], usize)>,
    /// Targets ended within the last `lost_frames` frames (`recall_ids`).
    ended: Vec<Ended>,
}

/// `p` rounded half away from zero and clamped into a `w × h` image.
fn pixel(p: [f64; 2], w: u32, h: u32) -> (u32, u32) {
    let c = |v: f64, n: u32| v.round().clamp(0.0, f64::from(n - 1)) as u32;
    (c(p[0], w), c(p[1], h))
}

fn dist(a: (u32, u32), b: [f64; 2]) -> f64 {
    (f64::from(a.0) - b[0]).hypot(f64::from(a.1) - b[1])
}

impl WatershedSiftTracker {
    /// A tracker from a configuration (validated here).
    pub fn new(cfg: WatershedSiftConfig) -> Result<Self, TrackerError> {
        cfg.validate()?;
        let front = MotionFrontEnd::new(cfg.sigma, cfg.levels, cfg.polarity, cfg.motion_test())?;
        let sift = Sift::new(SiftParams {
            upsample: cfg.sift_upsample,
            ..SiftParams::default()
        })?;
        Ok(Self {
            front,
            sift,
            targets: Vec::new(),
            groups_prev: Vec::new(),
            next_id: 1,
            frames: 0,
            diagnostics: FrameDiagnostics::default(),
            birth_candidates: Vec::new(),
            ended: Vec::new(),
            background: if cfg.fg_box || cfg.fg_gate || cfg.fg_births {
                Some(MedianBackground::new(cfg.background_params())?)
            } else {
                None
            },
            cfg,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &WatershedSiftConfig {
        &self.cfg
    }

    /// The live targets.
    pub fn targets(&self) -> &[Target] {
        &self.targets
    }

    /// What happened in the last frame.
    pub fn diagnostics(&self) -> &FrameDiagnostics {
        &self.diagnostics
    }

    /// The motion front end (segmentation, mapping, trajectories of the last frame).
    pub fn front_end(&self) -> &MotionFrontEnd {
        &self.front
    }

    /// The box of a target centred at `c`.
    fn bbox(&self, c: [f64; 2]) -> BBox {
        BBox {
            cx: c[0],
            cy: c[1],
            w: self.cfg.box_w,
            h: self.cfg.box_h,
        }
    }

    /// SIFT of the pixels of `labels` (∩ `clip` when given, a box `[x0, y0, x1, y1]` with
    /// real bounds `x0 <= x < x1`): (positions, descriptors).
    fn features(
        cache: &mut FeatureCache<'_>,
        seg: &Segmentation,
        geo: &RegionGeometry,
        labels: &[u32],
        clip: Option<[f64; 4]>,
    ) -> Result<(Vec<[f64; 2]>, Vec<SiftDescriptor>), TrackerError> {
        let (w, h) = seg.labels.dimensions();
        let mut r = [u32::MAX, u32::MAX, 0u32, 0u32];
        for &l in labels {
            let Some(b) = geo.bbox.get(l as usize - 1) else {
                continue;
            };
            if b[0] > b[2] {
                continue;
            }
            r = [
                r[0].min(b[0]),
                r[1].min(b[1]),
                r[2].max(b[2]),
                r[3].max(b[3]),
            ];
        }
        if let Some(c) = clip {
            let lo = |v: f64, n: u32| v.ceil().clamp(0.0, f64::from(n - 1)) as u32;
            let hi = |v: f64, n: u32| (v.ceil() - 1.0).clamp(0.0, f64::from(n - 1)) as u32;
            r = [
                r[0].max(lo(c[0], w)),
                r[1].max(lo(c[1], h)),
                r[2].min(hi(c[2], w)),
                r[3].min(hi(c[3], h)),
            ];
        }
        if r[0] > r[2] || r[1] > r[3] {
            return Ok((Vec::new(), Vec::new()));
        }
        let keep = |kx: f32, ky: f32| {
            let (x, y) = pixel([f64::from(kx), f64::from(ky)], w, h);
            if let Some(c) = clip {
                let (fx, fy) = (f64::from(x), f64::from(y));
                if !(fx >= c[0] && fx < c[2] && fy >= c[1] && fy < c[3]) {
                    return false;
                }
            }
            labels.contains(&seg.labels.data[y as usize * w as usize + x as usize])
        };
        cache.crop(r, keep)
    }

    /// Step 8's SIFT: the keypoints and descriptors of target `k`'s ROI (its regions ∩ the
    /// box around its centre); `None` for a target that step 8 skips (occluded, just
    /// separated, or without regions).
    fn roi_features(
        &self,
        cache: &mut FeatureCache<'_>,
        seg: &Segmentation,
        geo: &RegionGeometry,
        k: usize,
    ) -> Result<Option<RoiFeatures>, TrackerError> {
        let tg = &self.targets[k];
        if tg.occluded || tg.placed || tg.regions.is_empty() {
            return Ok(None);
        }
        let labels: Vec<u32> = tg.regions.iter().map(|r| r.label).collect();
        let clip = self.roi_clip(tg.centre);
        Self::features(cache, seg, geo, &labels, Some(clip)).map(Some)
    }

    /// Step 8's pool update of target `tg` at frame `t` with its ROI's keypoints `pos` and
    /// descriptors `d` (eqs. 9-11; the first one seeds the pool).
    fn update_pool(
        tg: &mut Target,
        t: u64,
        pos: &[[f64; 2]],
        d: Vec<SiftDescriptor>,
    ) -> Result<(), TrackerError> {
        let c = tg.centre;
        let offs: Vec<[f64; 2]> = pos.iter().map(|p| [p[0] - c[0], p[1] - c[1]]).collect();
        if tg.fresh {
            tg.pool.seed(t, &d, &offs)?;
            tg.fresh = false;
        } else {
            let prevd = std::mem::take(&mut tg.prev_desc);
            tg.pool.update(t, &d, &offs, &prevd)?;
        }
        tg.prev_desc = d;
        Ok(())
    }

    /// Bench support (`benches/video_tracker.rs`, not a stable API): step 8's SIFT for the
    /// last frame's targets, recomputed on `frame` — which must be the last frame given to
    /// [`step`](MultiTargetTracker::step) — with an empty per-frame crop cache. One entry per
    /// live target, `None` where step 8 skips it. The crops that steps 4 and 6 described
    /// earlier in the frame are not included.
    ///
    /// Errors: no frame processed yet, or `frame` of another size than the last one.
    #[doc(hidden)]
    pub fn stage_roi_features(
        &self,
        frame: &Plane<u8>,
    ) -> Result<Vec<Option<RoiFeatures>>, TrackerError> {
        let seg = self
            .front
            .current()
            .ok_or_else(|| TrackerError::State("no frame processed yet".into()))?;
        if seg.labels.dimensions() != frame.dimensions()
            || frame.data.len() != frame.width as usize * frame.height as usize
        {
            return Err(TrackerError::State(format!(
                "frame of {}x{} for a segmentation of {}x{}",
                frame.width, frame.height, seg.labels.width, seg.labels.height
            )));
        }
        let geo = RegionGeometry::new(seg);
        let mut cache = FeatureCache::new(frame, &self.sift, self.cfg.sift_pad);
        (0..self.targets.len())
            .map(|k| self.roi_features(&mut cache, seg, &geo, k))
            .collect()
    }

    /// Bench support (not a stable API): step 8's pool updates at frame `t` with the features
    /// of [`stage_roi_features`](Self::stage_roi_features) (one entry per live target).
    /// Returns the number of pools updated.
    ///
    /// Errors: `features` not one entry per live target, or a pool error.
    #[doc(hidden)]
    pub fn stage_pool_updates(
        &mut self,
        t: u64,
        features: Vec<Option<RoiFeatures>>,
    ) -> Result<usize, TrackerError> {
        if features.len() != self.targets.len() {
            return Err(TrackerError::State(format!(
                "{} feature sets for {} targets",
                features.len(),
                self.targets.len()
            )));
        }
        let mut n = 0;
        for (k, f) in features.into_iter().enumerate() {
            if let Some((pos, d)) = f {
                Self::update_pool(&mut self.targets[k], t, &pos, d)?;
                n += 1;
            }
        }
        Ok(n)
    }

    fn roi_clip(&self, c: [f64; 2]) -> [f64; 4] {
        let (hw, hh) = (self.cfg.box_w / 2.0, self.cfg.box_h / 2.0);
        [c[0] - hw, c[1] - hh, c[0] + hw, c[1] + hh]
    }

    /// One frame (spec §2.17). Returns the reports of the live targets with at least one
    /// region.
    fn process(
        &mut self,
        stamp: Stamp,
        frame: &Plane<u8>,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        let t0 = Instant::now();
        self.front.step(frame)?;
        let t_seg = t0.elapsed().as_secs_f64() * 1e6;
        let tb = Instant::now();
        if let Some(bg) = &mut self.background {
            // only targets seen moving: a target born on a ghost (foreground left where a
            // person stood while the background warmed up) must not keep its ghost
            let boxes: Vec<BBox> = self
                .targets
                .iter()
                .filter(|t| t.moved)
                .filter_map(|t| t.report)
                .collect();
            if self.cfg.bg_selective && bg.sample_due() && !boxes.is_empty() {
                let mut hold = Plane::new(frame.width, frame.height, false);
                let (w, h) = (frame.width as usize, frame.height as usize);
                for b in boxes {
                    let lo = |c: f64| c.ceil().max(0.0) as usize;
                    let (x0, y0) = (lo(b.cx - b.w / 2.0), lo(b.cy - b.h / 2.0));
                    let (x1, y1) = (
                        ((b.cx + b.w / 2.0).ceil().max(0.0) as usize).min(w),
                        ((b.cy + b.h / 2.0).ceil().max(0.0) as usize).min(h),
                    );
                    for y in y0.min(h)..y1 {
                        hold.data[y * w + x0.min(x1)..y * w + x1].fill(true);
                    }
                }
                bg.update_selective(frame, &hold)?;
            } else {
                bg.update(frame)?;
            }
        }
        let t_bg = tb.elapsed().as_secs_f64() * 1e6;
        let t = stamp.frame.0;
        self.frames += 1;
        // the previous segmentation exists exactly when the mapping does (not the first frame)
        let (Some(seg), Some(_), Some(map)) = (
            self.front.current(),
            self.front.previous(),
            self.front.mapping(),
        ) else {
            // the first frame: nothing to track yet
            let seg = self.front.current().ok_or_else(|| {
                TrackerError::State("internal: no segmentation after a step".into())
            })?;
            self.diagnostics = FrameDiagnostics {
                frame: t,
                regions: seg.n_regions(),
                times: StageTimes {
                    segment_us: t_seg,
                    foreground_us: t_bg,
                    ..StageTimes::default()
                },
                ..FrameDiagnostics::default()
            };
            return Ok(Vec::new());
        };
        // clones keep the borrow checker simple; the segmentations are a few MB
        let seg = seg.clone();
        let map = map.clone();
        let t1 = Instant::now();
        let adj = RegionAdjacency::from_segmentation(&seg)?;
        let geo = RegionGeometry::new(&seg);
        let traj = self
            .front
            .trajectories()
            .ok_or_else(|| TrackerError::State("internal: no trajectories".into()))?;
        let mut moving: Vec<(u32, f64, [f64; 2])> = self
            .front
            .moving()
            .iter()
            .map(|(l, s)| {
                let d = traj.get(*l).map_or([0.0; 2], |tr| {
                    let (a, b) = (tr[0], tr[tr.len() - 1]);
                    [
                        f64::from(b.0) - f64::from(a.0),
                        f64::from(b.1) - f64::from(a.1),
                    ]
                });
                (*l, s.displacement, d)
            })
            .collect();
        moving.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let t_map = t1.elapsed().as_secs_f64() * 1e6;
        let t2 = Instant::now();
        let mut cache = FeatureCache::new(frame, &self.sift, self.cfg.sift_pad);
        let (w, h) = seg.labels.dimensions();
        let lab = |p: (u32, u32)| seg.labels.data[p.1 as usize * w as usize + p.0 as usize];
        let minimum = |l: u32| seg.minima[l as usize - 1].representative;
        let n_t = self.targets.len();

        // ----- [ext] regions with foreground (fg_skip_background) -----
        let tfg = Instant::now();
        let fg_regions = self.foreground_regions(&seg, frame);
        let t_fgr = tfg.elapsed().as_secs_f64() * 1e6;
        let background_region = |j: u32| {
            fg_regions
                .as_ref()
                .is_some_and(|f| !f.get(j as usize).copied().unwrap_or(false))
        };

        // ----- occlusion detection (§2.14) -----
        let mut groups: BTreeMap<u32, Vec<usize>> = BTreeMap::new();
        for (k, tg) in self.targets.iter().enumerate() {
            if !tg.regions.is_empty() {
                groups
                    .entry(lab(pixel(tg.centre, w, h)))
                    .or_default()
                    .push(k);
            }
        }
        // ----- separation (§2.15) -----
        let bidir_of = |tg: &Target| -> Vec<u32> {
            tg.regions
                .iter()
                .filter_map(|r| match map.successor(r.label) {
                    Some((j, LinkKind::Bidirectional)) => Some(j),
                    _ => None,
                })
                .collect()
        };
        for tg in &mut self.targets {
            tg.placed = false;
        }
        let groups_prev = std::mem::take(&mut self.groups_prev);
        for (lp, members) in &groups_prev {
            let jset: Vec<u32> = map
                .backward
                .iter()
                .enumerate()
                .filter(|&(_, &i)| i == *lp)
                .map(|(j, _)| j as u32 + 1)
                .collect();
            if jset.len() < 2 {
                continue;
            }
            let idx: Vec<usize> = members
                .iter()
                .filter_map(|id| self.targets.iter().position(|t| t.id == *id))
                .collect();
            let bidir_taken: BTreeSet<u32> = idx
                .iter()
                .flat_map(|&k| bidir_of(&self.targets[k]))
                .collect();
            let tf: Vec<usize> = idx
                .iter()
                .copied()
                .filter(|&k| bidir_of(&self.targets[k]).is_empty())
                .collect();
            let mut counts: Vec<(usize, usize, u32)> = Vec::new();
            for &j in &jset {
                if bidir_taken.contains(&j) {
                    continue;
                }
                let (_, d) = Self::features(&mut cache, &seg, &geo, &[j], None)?;
                for &k in &tf {
                    let c = self.targets[k].pool.count_matches(&d);
                    if c >= self.cfg.separation_min_matches.max(1) {
                        counts.push((c, k, j));
                    }
                }
            }
            counts.sort_by(|a, b| {
                b.0.cmp(&a.0)
                    .then(self.targets[a.1].id.cmp(&self.targets[b.1].id))
                    .then(a.2.cmp(&b.2))
            });
            let (mut used_k, mut used_j) = (BTreeSet::new(), BTreeSet::new());
            for (_, k, j) in counts {
                if used_k.contains(&k) || used_j.contains(&j) {
                    continue;
                }
                used_k.insert(k);
                used_j.insert(j);
                let tg = &mut self.targets[k];
                tg.regions = vec![RegionRef {
                    label: j,
                    minimum: minimum(j),
                    provenance: Provenance::Separation,
                }];
                let m = minimum(j);
                tg.centre = [f64::from(m.0), f64::from(m.1)];
                tg.placed = true;
                tg.occluded = false;
            }
        }
        // placed targets leave this frame's groups; a group with < 2 members dissolves
        let mut occluded = vec![false; n_t];
        let mut groups_now: Vec<(u32, Vec<TrackId>)> = Vec::new();
        for (l, ks) in &groups {
            let ks: Vec<usize> = ks
                .iter()
                .copied()
                .filter(|&k| !self.targets[k].placed)
                .collect();
            if ks.len() >= 2 {
                for &k in &ks {
                    occluded[k] = true;
                }
                groups_now.push((*l, ks.iter().map(|&k| self.targets[k].id).collect()));
            }
        }

        // ----- steps 1-5 and occluded tracking -----
        // provisional regions (primary successors) for the ownership candidates
        let provisional: Vec<Vec<u32>> = self
            .targets
            .iter()
            .map(|tg| {
                tg.regions
                    .iter()
                    .filter_map(|r| map.successor(r.label).map(|s| s.0))
                    .collect()
            })
            .collect();
        let mut claims: Vec<Vec<RegionRef>> = vec![Vec::new(); n_t];
        let mut located: Vec<Option<[f64; 2]>> = vec![None; n_t];
        let push = |list: &mut Vec<RegionRef>, label: u32, p: Provenance| {
            if !list.iter().any(|r| r.label == label) {
                list.push(RegionRef {
                    label,
                    minimum: minimum(label),
                    provenance: p,
                });
            }
        };
        let old_regions: Vec<Vec<RegionRef>> =
            self.targets.iter().map(|t| t.regions.clone()).collect();
        for k in 0..n_t {
            if self.targets[k].placed {
                claims[k].clone_from(&self.targets[k].regions);
                continue;
            }
            let s = &old_regions[k];
            if occluded[k] {
                // Bi_k: the bidirectional successors of the target's *own* regions; the shared
                // occlusion region of the previous frame is not one of them (read literally,
                // §2.14 would hand its successor to every member, and the members would share
                // one centre for as long as the group lasts)
                let own = Target {
                    regions: s
                        .iter()
                        .filter(|r| r.provenance != Provenance::Occlusion)
                        .copied()
                        .collect(),
                    ..self.targets[k].clone()
                };
                let bi = bidir_of(&own);
                if bi.is_empty() {
                    let l = lab(pixel(self.targets[k].centre, w, h));
                    let (pos, d) = Self::features(&mut cache, &seg, &geo, &[l], None)?;
                    let tg = &self.targets[k];
                    let mut pts = Vec::new();
                    for (p, dd) in pos.iter().zip(&d) {
                        if let Some(q) = tg.pool.matched_entry(dd) {
                            if self.cfg.offset_voting {
                                let off = tg.pool.entries()[q].offset;
                                pts.push([p[0] - off[0], p[1] - off[1]]);
                            } else {
                                pts.push(*p);
                            }
                        }
                    }
                    if !pts.is_empty() {
                        located[k] = Some(if self.cfg.offset_voting {
                            let med = |mut v: Vec<f64>| {
                                v.sort_by(f64::total_cmp);
                                let n = v.len();
                                if n % 2 == 1 {
                                    v[n / 2]
                                } else {
                                    0.5 * (v[n / 2 - 1] + v[n / 2])
                                }
                            };
                            [
                                med(pts.iter().map(|p| p[0]).collect()),
                                med(pts.iter().map(|p| p[1]).collect()),
                            ]
                        } else {
                            let n = pts.len() as f64;
                            [
                                pts.iter().map(|p| p[0]).sum::<f64>() / n,
                                pts.iter().map(|p| p[1]).sum::<f64>() / n,
                            ]
                        });
                    }
                    push(&mut claims[k], l, Provenance::Occlusion);
                    // [ext] occluded_hold_located: the region the target is located in
                    if self.cfg.occluded_hold_located
                        && let Some(c) = located[k]
                    {
                        let l2 = lab(pixel(c, w, h));
                        let taken = provisional
                            .iter()
                            .enumerate()
                            .any(|(o, pr)| o != k && !occluded[o] && pr.contains(&l2));
                        if l2 != l && adj.are_adjacent(l, l2) && !background_region(l2) && !taken {
                            push(&mut claims[k], l2, Provenance::Occlusion);
                        }
                    }
                } else {
                    for j in bi {
                        push(&mut claims[k], j, Provenance::Bidirectional);
                    }
                }
                continue;
            }
            // [ext] reacquire: a target without regions (not a companion) claims the region
            // under its centre if it holds foreground, has no moving point and passes step
            // 4's ownership test against the target's pool
            if self.cfg.reacquire
                && s.is_empty()
                && self.targets[k].host.is_none()
                && fg_regions.is_some()
            {
                let l = lab(pixel(self.targets[k].centre, w, h));
                // a region another target continues into is that target's (the claim would
                // come last in step 7); its SIFT is not asked for
                let continued = provisional
                    .iter()
                    .enumerate()
                    .any(|(o, pr)| o != k && pr.contains(&l));
                if !continued && !background_region(l) && !moving.iter().any(|m| m.0 == l) {
                    // the region must be the target's person: step 4's ownership test
                    let (_, d) = Self::features(&mut cache, &seg, &geo, &[l], None)?;
                    let tg = &self.targets[k];
                    if d.len() >= self.cfg.n_min
                        && tg
                            .pool
                            .ownership_ratio(&d, &tg.prev_desc)
                            .is_some_and(|r| r > self.cfg.tau_split)
                    {
                        push(&mut claims[k], l, Provenance::Reacquired);
                    }
                }
            }
            // steps 1 and 3: primary successors
            for r in s {
                if let Some((j, kind)) = map.successor(r.label) {
                    let p = if kind == LinkKind::Bidirectional {
                        Provenance::Bidirectional
                    } else {
                        Provenance::Merge
                    };
                    push(&mut claims[k], j, p);
                }
            }
            // step 4: fragments, by the ownership test
            for r in s {
                for &j in map.fragments(r.label) {
                    if claims[k].iter().any(|c| c.label == j) || background_region(j) {
                        continue;
                    }
                    let (_, d) = Self::features(&mut cache, &seg, &geo, &[j], None)?;
                    if d.len() < self.cfg.n_min {
                        continue;
                    }
                    let mut cands: Vec<usize> = vec![k];
                    for (o, pr) in provisional.iter().enumerate() {
                        if o != k && pr.iter().any(|&l| adj.are_adjacent(l, j)) {
                            cands.push(o);
                        }
                    }
                    let mut best: Option<(f64, usize)> = None;
                    for &o in &cands {
                        let tg = &self.targets[o];
                        if let Some(r) = tg.pool.ownership_ratio(&d, &tg.prev_desc)
                            && r > self.cfg.tau_split
                            && best.is_none_or(|(b, bo)| {
                                r > b || (r == b && self.targets[o].id < self.targets[bo].id)
                            })
                        {
                            best = Some((r, o));
                        }
                    }
                    if let Some((_, o)) = best {
                        push(&mut claims[o], j, Provenance::SplitSift);
                    }
                }
            }
            // step 5: the distance rule
            let olds: Vec<(u32, u32)> = s.iter().map(|r| r.minimum).collect();
            if !olds.is_empty() {
                for (jj, m) in seg.minima.iter().enumerate() {
                    let j = jj as u32 + 1;
                    let near = olds.iter().any(|o| {
                        (f64::from(m.representative.0) - f64::from(o.0))
                            .hypot(f64::from(m.representative.1) - f64::from(o.1))
                            < self.cfg.d_near
                    });
                    if near {
                        push(&mut claims[k], j, Provenance::Distance);
                    }
                }
            }
            // [ext] region gate around the previous centre
            if self.cfg.region_gate {
                let c = self.targets[k].centre;
                let (gw, gh) = (
                    self.cfg.gate_w * self.cfg.box_w / 2.0,
                    self.cfg.gate_h * self.cfg.box_h / 2.0,
                );
                claims[k].retain(|r| {
                    (f64::from(r.minimum.0) - c[0]).abs() <= gw
                        && (f64::from(r.minimum.1) - c[1]).abs() <= gh
                });
            }
        }

        // ----- step 6: moving points -----
        let mut created = 0;
        let owned_by = |claims: &Vec<Vec<RegionRef>>, j: u32| -> bool {
            claims.iter().any(|c| c.iter().any(|r| r.label == j))
        };
        let mut consumed: BTreeSet<u32> = BTreeSet::new();
        for mi in 0..moving.len() {
            let (j, _, disp) = moving[mi];
            if consumed.contains(&j) || owned_by(&claims, j) || background_region(j) {
                continue;
            }
            let neigh: Vec<usize> = (0..claims.len())
                .filter(|&o| claims[o].iter().any(|r| adj.are_adjacent(r.label, j)))
                .collect();
            if !neigh.is_empty() {
                let (_, d) = Self::features(&mut cache, &seg, &geo, &[j], None)?;
                if d.len() >= self.cfg.n_min {
                    let mut best: Option<(f64, usize)> = None;
                    for &o in &neigh {
                        let (pool, prevd) = if o < n_t {
                            (&self.targets[o].pool, &self.targets[o].prev_desc)
                        } else {
                            // a target created earlier in this frame has no pool yet: its
                            // first ROI is its only appearance; it cannot own by SIFT
                            continue;
                        };
                        if let Some(r) = pool.ownership_ratio(&d, prevd)
                            && r > self.cfg.tau_split
                            && best.is_none_or(|(b, _)| r > b)
                        {
                            best = Some((r, o));
                        }
                    }
                    if let Some((_, o)) = best {
                        push(&mut claims[o], j, Provenance::MovingPoint);
                        continue;
                    }
                }
            }
            // create a target
            let mut regions = vec![j];
            if self.cfg.coherent_grouping {
                let a = minimum(j);
                for &(j2, _, d2) in &moving[mi + 1..] {
                    if consumed.contains(&j2) || owned_by(&claims, j2) {
                        continue;
                    }
                    let b = minimum(j2);
                    let near = adj.are_adjacent(j, j2)
                        || (self.cfg.group_box_frac > 0.0
                            && (f64::from(a.0) - f64::from(b.0)).abs()
                                <= self.cfg.group_box_frac * self.cfg.box_w
                            && (f64::from(a.1) - f64::from(b.1)).abs()
                                <= self.cfg.group_box_frac * self.cfg.box_h);
                    if !near {
                        continue;
                    }
                    let (l1, l2) = (disp[0].hypot(disp[1]), d2[0].hypot(d2[1]));
                    if l1 <= 0.0 || l2 <= 0.0 {
                        continue;
                    }
                    let rel = (l1 - l2).abs() / l1.max(l2);
                    let cosang = (disp[0] * d2[0] + disp[1] * d2[1]) / (l1 * l2);
                    let ang = cosang.clamp(-1.0, 1.0).acos().to_degrees();
                    if rel < self.cfg.group_len_tol && ang < self.cfg.group_angle_deg {
                        regions.push(j2);
                    }
                }
            }
            let ms: Vec<(u32, u32)> = regions.iter().map(|&l| minimum(l)).collect();
            let n = ms.len() as f64;
            let centre = [
                ms.iter().map(|m| f64::from(m.0)).sum::<f64>() / n,
                ms.iter().map(|m| f64::from(m.1)).sum::<f64>() / n,
            ];
            if self.cfg.min_new_separation > 0.0 {
                let too_close = self.targets.iter().any(|tg| {
                    (tg.centre[0] - centre[0]).abs() < self.cfg.min_new_separation * self.cfg.box_w
                        && (tg.centre[1] - centre[1]).abs()
                            < self.cfg.min_new_separation * self.cfg.box_h
                });
                if too_close {
                    continue;
                }
            }
            for &l in &regions {
                consumed.insert(l);
            }
            let id = TrackId(self.next_id);
            self.next_id += 1;
            created += 1;
            self.targets.push(Target::start(
                id,
                centre,
                Vec::new(),
                WeightedPool::new(self.cfg.pool_params())?,
                t,
            ));
            occluded.push(false);
            located.push(None);
            claims.push(
                regions
                    .iter()
                    .map(|&l| RegionRef {
                        label: l,
                        minimum: minimum(l),
                        provenance: Provenance::MovingPoint,
                    })
                    .collect(),
            );
        }

        // ----- step 7: resolve and centre -----
        let n_all = self.targets.len();
        // regions held by occluded or just-separated targets are theirs alone
        let reserved: BTreeSet<u32> = (0..n_all)
            .filter(|&k| occluded[k] || self.targets[k].placed)
            .flat_map(|k| claims[k].iter().map(|r| r.label).collect::<Vec<_>>())
            .collect();
        let mut winner: BTreeMap<u32, usize> = BTreeMap::new();
        for k in 0..n_all {
            if occluded[k] || self.targets[k].placed {
                continue;
            }
            for r in &claims[k] {
                if reserved.contains(&r.label) {
                    continue;
                }
                let better = match winner.get(&r.label) {
                    None => true,
                    Some(&o) => {
                        let ro = claims[o]
                            .iter()
                            .find(|x| x.label == r.label)
                            .map_or(u8::MAX, |x| x.provenance.rank());
                        let (dk, dn) = (
                            dist(r.minimum, self.targets[k].centre),
                            dist(r.minimum, self.targets[o].centre),
                        );
                        (r.provenance.rank(), dk, self.targets[k].id) < (ro, dn, self.targets[o].id)
                    }
                };
                if better {
                    winner.insert(r.label, k);
                }
            }
        }
        for k in 0..n_all {
            let keep: Vec<RegionRef> = if occluded[k] || self.targets[k].placed {
                claims[k].clone()
            } else {
                claims[k]
                    .iter()
                    .filter(|r| winner.get(&r.label) == Some(&k))
                    .copied()
                    .collect()
            };
            let tg = &mut self.targets[k];
            tg.occluded = occluded[k];
            tg.regions = keep;
            tg.frozen = true;
            if tg.regions.is_empty() {
                tg.lost += 1;
            } else {
                tg.lost = 0;
                if let Some(c) = located[k] {
                    tg.centre = c;
                    tg.frozen = false;
                } else if !(tg.occluded
                    && tg
                        .regions
                        .iter()
                        .all(|r| r.provenance == Provenance::Occlusion))
                {
                    tg.frozen = false;
                    let n = tg.regions.len() as f64;
                    tg.centre = [
                        tg.regions
                            .iter()
                            .map(|r| f64::from(r.minimum.0))
                            .sum::<f64>()
                            / n,
                        tg.regions
                            .iter()
                            .map(|r| f64::from(r.minimum.1))
                            .sum::<f64>()
                            / n,
                    ];
                }
            }
        }

        // ----- step 8: pools -----
        for k in 0..n_all {
            if let Some((pos, d)) = self.roi_features(&mut cache, &seg, &geo, k)? {
                Self::update_pool(&mut self.targets[k], t, &pos, d)?;
            }
        }
        let sift_us = cache.us;

        // ----- [ours] fusion of targets that follow one person -----
        if self.cfg.fuse_iou > 0.0 {
            self.fuse();
        }

        // ----- reported boxes: fixed (paper) or fitted to the foreground \[ext\] -----
        let tf = Instant::now();
        created += self.report_boxes(&seg, frame, t)?;
        if self.cfg.fg_births {
            created += self.foreground_births(&seg, frame, t)?;
        }
        let t_fit = tf.elapsed().as_secs_f64() * 1e6;

        // ----- termination (§2.16) -----
        let (bw, bh) = (self.cfg.box_w / 2.0, self.cfg.box_h / 2.0);
        let (fw, fh) = (f64::from(w) - 1.0, f64::from(h) - 1.0);
        let before = self.targets.len();
        let cfg = &self.cfg;
        let ended = &mut self.ended;
        self.targets.retain_mut(|tg| {
            tg.history.push_back(tg.centre);
            let origin = tg.origin.get_or_insert(tg.centre);
            if (tg.centre[0] - origin[0]).hypot(tg.centre[1] - origin[1]) >= cfg.box_w / 2.0 {
                tg.moved = true;
            }
            let keep = cfg.exit_frames.max(cfg.stuck_frames) + 1;
            while tg.history.len() > keep {
                tg.history.pop_front();
            }
            let d_k = |k: usize| -> Option<f64> {
                let n = tg.history.len();
                (n > k).then(|| {
                    let (a, b) = (tg.history[n - 1], tg.history[n - 1 - k]);
                    (a[0] - b[0]).hypot(a[1] - b[1])
                })
            };
            let c = tg.centre;
            let in_band = c[0] < bw || c[0] > fw - bw || c[1] < bh || c[1] > fh - bh;
            let exit = in_band && d_k(cfg.exit_frames).is_some_and(|d| d < cfg.still_px);
            // with the foreground gate, a target on foreground is a person standing, not
            // regions frozen on background: the gate ends the latter (`stuck_needs_no_fg`)
            // with `reacquire`, a target without regions is lost, not stuck on background: the
            // lost rule ends it
            let stuck = d_k(cfg.stuck_frames).is_some_and(|d| d < cfg.still_px)
                && !(cfg.stuck_needs_no_fg && tg.moved && tg.no_fg == 0 && tg.report.is_some())
                && !(cfg.reacquire && tg.regions.is_empty() && tg.host.is_none());
            let lost = tg.lost > cfg.lost_frames || tg.no_fg > cfg.lost_frames;
            let end = exit || stuck || lost;
            if end
                && cfg.recall_ids
                && let Some(e) = last_motion(tg)
            {
                ended.push(e);
            }
            !end
        });
        let terminated = before - self.targets.len();
        let ids: BTreeSet<TrackId> = self.targets.iter().map(|t| t.id).collect();
        self.groups_prev = groups_now
            .into_iter()
            .filter_map(|(l, m)| {
                let m: Vec<TrackId> = m.into_iter().filter(|i| ids.contains(i)).collect();
                (m.len() >= 2).then_some((l, m))
            })
            .collect();
        let t_track = t2.elapsed().as_secs_f64() * 1e6 - sift_us - t_fit - t_fgr;

        // ----- reports -----
        let report_after = self.cfg.report_after as u64;
        let shown = |tg: &Target| {
            tg.report.is_some()
                && !(tg.regions.is_empty() && tg.host.is_none())
                && t >= tg.born + report_after
        };
        let show: Vec<bool> = self.targets.iter().map(shown).collect();
        if self.cfg.recall_ids {
            self.recall(&show, t);
        }
        let mut reports = Vec::new();
        for tg in &mut self.targets {
            let Some(bbox) = tg.report.filter(|_| shown(tg)) else {
                continue;
            };
            tg.last_shown = Some(t);
            if !tg.held {
                tg.reported.push_back((t, [bbox.cx, bbox.cy]));
                while tg.reported.len() > RECALL_VELOCITY_FRAMES + 1 {
                    tg.reported.pop_front();
                }
            }
            let mut r = TrackReport::new(
                stamp,
                tg.report_id,
                if tg.occluded {
                    TrackStatus::Occluded
                } else {
                    TrackStatus::Confirmed
                },
            );
            r.bbox = Some(bbox);
            r.score = Some(1.0);
            if tg.born == t {
                r.flags = TrackFlags::BORN;
            }
            reports.push(r);
        }
        self.diagnostics = FrameDiagnostics {
            frame: t,
            regions: seg.n_regions(),
            bidirectional: map.bidirectional.len(),
            merges: map.merges.len(),
            splits: map.splits.len(),
            moving: moving.iter().map(|m| minimum(m.0)).collect(),
            targets: self
                .targets
                .iter()
                .map(|tg| TargetDiagnostics {
                    id: tg.id.0,
                    centre: tg.centre,
                    pool: tg.pool.len(),
                    occluded: tg.occluded,
                    regions: tg.regions.len(),
                })
                .collect(),
            occlusion_groups: self
                .groups_prev
                .iter()
                .map(|(_, m)| m.iter().map(|i| i.0).collect())
                .collect(),
            created,
            terminated,
            times: StageTimes {
                segment_us: t_seg,
                map_us: t_map,
                sift_us,
                track_us: t_track.max(0.0),
                foreground_us: t_bg + t_fgr + t_fit,
            },
        };
        Ok(reports)
    }
}

impl WatershedSiftTracker {
    /// Sets every target's reported box for this frame: the fixed box around O_c (paper), or
    /// with `fg_box` the box fitted to its foreground pixels (see the config docs); a target
    /// without a fit this frame keeps its last fit's offset and size. With `fg_gate` a visible
    /// target without foreground support is not reported and counts towards termination.
    /// With `fg_pairs` a target whose foreground is a pair side by side is fitted to its own
    /// part and a companion is reported on the other (see the config docs). Returns the
    /// number of companions created.
    fn report_boxes(
        &mut self,
        seg: &Segmentation,
        frame: &Plane<u8>,
        t: u64,
    ) -> Result<usize, TrackerError> {
        let mature = self
            .background
            .as_ref()
            .filter(|b| b.samples_held() >= 3.min(b.params().samples));
        let fixed = |c: [f64; 2]| BBox {
            cx: c[0],
            cy: c[1],
            w: self.cfg.box_w,
            h: self.cfg.box_h,
        };
        let Some(bg) = mature else {
            for tg in &mut self.targets {
                tg.report = (!tg.regions.is_empty()).then(|| fixed(tg.centre));
            }
            return Ok(0);
        };
        // owners of each label: visible targets, and the members of an occlusion group
        let mut owners: Vec<Vec<usize>> = vec![Vec::new(); seg.n_regions() + 1];
        for (k, tg) in self.targets.iter().enumerate() {
            for r in &tg.regions {
                if let Some(o) = owners.get_mut(r.label as usize) {
                    o.push(k);
                }
            }
        }
        let cfg = &self.cfg;
        let (w, h) = (seg.labels.width as usize, seg.labels.height as usize);
        let back = &bg.background().data;
        let thr = cfg.fg_threshold;
        let mut fits: Vec<Option<[f64; 4]>> = vec![None; self.targets.len()];
        // [ext] fg_pairs: the other person's box, for targets whose foreground is a pair
        let mut pairs: Vec<Option<[BBox; 2]>> = vec![None; self.targets.len()];
        // [ext] fg_pairs_hold: the column between a target's and its companion's boxes of the
        // previous frame, moved with the target's centre since then
        let held_cut = |tg: &Target, cp: Option<&Target>| -> Option<f64> {
            if !cfg.fg_pairs_hold {
                return None;
            }
            let (hb, cb, prev) = (tg.report?, cp?.report?, tg.history.back()?);
            Some(f64::midpoint(hb.cx, cb.cx) + tg.centre[0] - prev[0])
        };
        for (k, tg) in self.targets.iter().enumerate() {
            if tg.regions.is_empty() || tg.occluded {
                continue;
            }
            let (hw, hh) = (cfg.fg_window * cfg.box_w, cfg.fg_window * cfg.box_h);
            let clampi = |v: f64, n: usize| v.clamp(0.0, n as f64 - 1.0) as usize;
            let (x0, x1) = (
                clampi((tg.centre[0] - hw).ceil(), w),
                clampi((tg.centre[0] + hw).floor(), w),
            );
            let (y0, y1) = (
                clampi((tg.centre[1] - hh).ceil(), h),
                clampi((tg.centre[1] + hh).floor(), h),
            );
            let mut cols = vec![0usize; x1 - x0 + 1];
            let mut rows = vec![0usize; y1 - y0 + 1];
            let (mut n, mut n_own) = (0usize, 0usize);
            for y in y0..=y1 {
                let row = y * w;
                for x in x0..=x1 {
                    let i = row + x;
                    if frame.data[i].abs_diff(back[i]) <= thr {
                        continue;
                    }
                    let o = &owners[seg.labels.data[i] as usize];
                    let own = o.contains(&k);
                    if o.is_empty() || own {
                        cols[x - x0] += 1;
                        rows[y - y0] += 1;
                        n += 1;
                        n_own += usize::from(own);
                    }
                }
            }
            // support: the foreground must lie in the target's own regions (a target frozen
            // on a lamp post gets the foreground of people passing it only from other regions)
            if (n_own as f64) < cfg.fg_min_frac * cfg.box_w * cfg.box_h || n_own == 0 {
                continue;
            }
            let span = |hist: &[usize], lo0: usize| -> (f64, f64) {
                let (lo_n, hi_n) = (cfg.fg_trim * n as f64, (1.0 - cfg.fg_trim) * n as f64);
                let (mut acc, mut lo, mut hi) = (0usize, 0usize, hist.len() - 1);
                let mut lo_set = false;
                for (i, &c) in hist.iter().enumerate() {
                    acc += c;
                    if !lo_set && acc as f64 > lo_n {
                        lo = i;
                        lo_set = true;
                    }
                    if acc as f64 >= hi_n {
                        hi = i;
                        break;
                    }
                }
                ((lo0 + lo) as f64, (lo0 + hi) as f64 + 1.0)
            };
            let fit_axis = |(a, b): (f64, f64), size: f64, c: f64, cap: f64| -> (f64, f64) {
                let s = cfg.fg_max_scale;
                let len = (b - a).clamp(size / s, size * s).min(cap.max(size / s));
                // centre as close to O_c as the blob allows
                let lo = a + len / 2.0;
                let hi = b - len / 2.0;
                let cc = if lo <= hi {
                    c.clamp(lo, hi)
                } else {
                    f64::midpoint(a, b)
                };
                (cc, len)
            };
            let (cy, fh) = fit_axis(span(&rows, y0), cfg.box_h, tg.centre[1], f64::INFINITY);
            let wcap = cfg.fg_max_aspect * cfg.box_w / cfg.box_h * fh;
            let (cx, fw) = fit_axis(span(&cols, x0), cfg.box_w, tg.centre[0], wcap);
            fits[k] = Some([cx - tg.centre[0], cy - tg.centre[1], fw, fh]);
            let companion = cfg
                .fg_pairs
                .then(|| self.targets.iter().find(|o| o.host == Some(tg.id)))
                .flatten();
            if cfg.fg_pairs
                && let Some((host, other)) = Self::pair_split(
                    cfg,
                    tg.centre,
                    fh,
                    (y0, y1),
                    |x, y| {
                        let i = y * w + x;
                        if frame.data[i].abs_diff(back[i]) <= thr {
                            return None;
                        }
                        // only pixels darker than the background count: every target here
                        // is a dark minimum, and the ghost a moving person leaves in a
                        // background model that has not caught up (it trails the person like
                        // a second one, inside or outside the target's regions) is brighter
                        if frame.data[i] > back[i] {
                            return None;
                        }
                        let o = &owners[seg.labels.data[i] as usize];
                        let own = o.contains(&k);
                        (o.is_empty() || own).then_some(own)
                    },
                    w,
                    held_cut(tg, companion),
                )
            {
                // a companion stays on the part nearer its last place
                let (host, other) = match companion {
                    Some(cp)
                        if (host.cx - cp.centre[0]).hypot(host.cy - cp.centre[1])
                            < (other.cx - cp.centre[0]).hypot(other.cy - cp.centre[1]) =>
                    {
                        (other, host)
                    }
                    _ => (host, other),
                };
                fits[k] = Some([
                    host.cx - tg.centre[0],
                    host.cy - tg.centre[1],
                    host.w,
                    host.h,
                ]);
                pairs[k] = Some([host, other]);
            }
        }
        // members of an occlusion group hidden behind two other people (see below)
        let mut hidden = vec![false; self.targets.len()];
        // [ext] fg_pairs, occlusion groups: two targets tracked through an occlusion on the
        // same regions whose foreground is a pair side by side are each fitted to one part
        // (the assignment nearer their last reported boxes); other groups keep their last fits
        if cfg.fg_pairs {
            let mut groups: BTreeMap<Vec<u32>, Vec<usize>> = BTreeMap::new();
            for (k, tg) in self.targets.iter().enumerate() {
                if tg.occluded && !tg.regions.is_empty() {
                    let mut key: Vec<u32> = tg.regions.iter().map(|r| r.label).collect();
                    key.sort_unstable();
                    key.dedup();
                    groups.entry(key).or_default().push(k);
                }
            }
            for members in groups.values().filter(|m| m.len() == 2) {
                let (m0, m1) = (&self.targets[members[0]], &self.targets[members[1]]);
                let c = [
                    f64::midpoint(m0.centre[0], m1.centre[0]),
                    f64::midpoint(m0.centre[1], m1.centre[1]),
                ];
                // the height of the members' last fits (the pair's people are seen at one
                // distance), else the configured box
                let heights: Vec<f64> = [m0, m1]
                    .iter()
                    .filter_map(|m| m.fit.map(|f| f[3]))
                    .collect();
                let fh = if heights.is_empty() {
                    cfg.box_h
                } else {
                    heights.iter().sum::<f64>() / heights.len() as f64
                };
                let hh = cfg.fg_window * cfg.box_h;
                let clampi = |v: f64, n: usize| v.clamp(0.0, n as f64 - 1.0) as usize;
                let rows = (
                    clampi((c[1] - hh).ceil(), h),
                    clampi((c[1] + hh).floor(), h),
                );
                let (k0, k1) = (members[0], members[1]);
                let split = Self::pair_split(
                    cfg,
                    c,
                    fh,
                    rows,
                    |x, y| {
                        let i = y * w + x;
                        // darker than the background only, as for a single target's pair
                        if frame.data[i].abs_diff(back[i]) <= thr || frame.data[i] > back[i] {
                            return None;
                        }
                        let o = &owners[seg.labels.data[i] as usize];
                        let own = o.contains(&k0) || o.contains(&k1);
                        (o.is_empty() || own).then_some(own)
                    },
                    w,
                    None,
                );
                if let Some((p, q)) = split {
                    // each member keeps to the part nearer its last reported box (continuity:
                    // the centres located through the occlusion are the less certain)
                    let at = |m: &Target| m.report.map_or(m.centre, |b| [b.cx, b.cy]);
                    let d = |b: &BBox, a: [f64; 2]| (b.cx - a[0]).hypot(b.cy - a[1]);
                    // [ext] fg_pairs_group_companion: a member's companion is a third person,
                    // at its last place; the two parts go to the two candidates nearest them
                    let hosted = cfg
                        .fg_pairs_group_companion
                        .then(|| {
                            [k0, k1].into_iter().find_map(|mk| {
                                let id = self.targets[mk].id;
                                let c = self.targets.iter().position(|o| o.host == Some(id))?;
                                Some((mk, c))
                            })
                        })
                        .flatten();
                    let mut cands = vec![(k0, at(m0)), (k1, at(m1))];
                    if let Some((_, c)) = hosted {
                        cands.push((c, self.targets[c].centre));
                    }
                    // ordered pairs (gets p, gets q), least total distance; ties keep the
                    // first found (the members, in order)
                    let mut best: Option<(f64, usize, usize)> = None;
                    for (i, &(_, ai)) in cands.iter().enumerate() {
                        for (j, &(_, aj)) in cands.iter().enumerate() {
                            let cost = d(&p, ai) + d(&q, aj);
                            if i != j && best.is_none_or(|(c, _, _)| cost < c) {
                                best = Some((cost, i, j));
                            }
                        }
                    }
                    if let Some((_, i, j)) = best {
                        for (ci, b) in [(i, p), (j, q)] {
                            if let Some((host, _)) = hosted.filter(|_| ci == 2) {
                                // the companion, reported on its part as on its host's pair
                                pairs[host] = Some([b, b]);
                            } else {
                                let k = cands[ci].0;
                                let ctr = self.targets[k].centre;
                                fits[k] = Some([b.cx - ctr[0], b.cy - ctr[1], b.w, b.h]);
                            }
                        }
                        // a member without a part is hidden behind the other two
                        if let Some(left) = (0..2).find(|&m| m != i && m != j) {
                            hidden[cands[left].0] = true;
                        }
                    }
                }
            }
        }
        let (fg_box, fg_gate) = (cfg.fg_box, cfg.fg_gate);
        for ((tg, fit), hide) in self.targets.iter_mut().zip(fits).zip(hidden) {
            if tg.regions.is_empty() || hide {
                tg.report = None;
                tg.held = false;
                continue;
            }
            let visible = !tg.occluded;
            if visible && fit.is_none() {
                tg.no_fg += 1;
            } else {
                tg.no_fg = 0;
            }
            if fit.is_some() {
                tg.fit = fit;
            }
            // nothing placed the target this frame: its box is the last one again
            tg.held = tg.frozen && !(fg_box && fit.is_some());
            tg.report = if fg_gate && visible && fit.is_none() {
                None
            } else if let (true, Some(f)) = (fg_box, tg.fit) {
                Some(BBox {
                    cx: tg.centre[0] + f[0],
                    cy: tg.centre[1] + f[1],
                    w: f[2],
                    h: f[3],
                })
            } else {
                Some(fixed(tg.centre))
            };
        }
        if self.cfg.fg_pairs {
            return self.update_companions(&pairs, t);
        }
        Ok(0)
    }

    /// `fg_pairs`: whether the foreground around a target centred at `c` with fitted height
    /// `fh` is two people side by side, and if so the boxes of its own part and of the other
    /// part. `pixel(x, y)` is `None` for a pixel not counted (background, or another target's
    /// region) and `Some(own)` otherwise; `rows` is the fit window's row range (inclusive) and
    /// `w` the image width. The window spans a pair's width, `fg_max_aspect` + 1/`fg_max_scale`
    /// typical widths at `fh`, on each side of `c`, so the pair is inside whether `c` lies on
    /// one person or between the two.
    fn pair_split(
        cfg: &WatershedSiftConfig,
        c: [f64; 2],
        fh: f64,
        rows: (usize, usize),
        pixel: impl Fn(usize, usize) -> Option<bool>,
        w: usize,
        hold: Option<f64>,
    ) -> Option<(BBox, BBox)> {
        let s = cfg.fg_max_scale;
        let pw = cfg.box_w / cfg.box_h * fh;
        let pair_w = (cfg.fg_max_aspect + 1.0 / s) * pw;
        let clampi = |v: f64| v.clamp(0.0, w as f64 - 1.0) as usize;
        let (x0, x1) = (
            clampi((c[0] - pair_w).ceil()),
            clampi((c[0] + pair_w).floor()),
        );
        let (y0, y1) = rows;
        let (ww, wh) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut mask = vec![false; ww * wh];
        let (mut cols, mut cols_own) = (vec![0usize; ww], vec![0usize; ww]);
        for y in y0..=y1 {
            for x in x0..=x1 {
                if let Some(own) = pixel(x, y) {
                    mask[(y - y0) * ww + x - x0] = true;
                    cols[x - x0] += 1;
                    cols_own[x - x0] += usize::from(own);
                }
            }
        }
        // trimmed span [a, b) of a histogram, as indices
        let span = |hist: &[usize]| -> Option<(usize, usize)> {
            let n: usize = hist.iter().sum();
            if n == 0 {
                return None;
            }
            let (lo_n, hi_n) = (cfg.fg_trim * n as f64, (1.0 - cfg.fg_trim) * n as f64);
            let (mut acc, mut lo, mut hi) = (0usize, None, hist.len() - 1);
            for (i, &v) in hist.iter().enumerate() {
                acc += v;
                if lo.is_none() && acc as f64 > lo_n {
                    lo = Some(i);
                }
                if acc as f64 >= hi_n {
                    hi = i;
                    break;
                }
            }
            lo.map(|lo| (lo, hi + 1))
        };
        let (a, b) = span(&cols)?;
        // at least two narrow people wide; the gap test below tells a pair from one person
        if ((b - a) as f64) < 2.0 * pw / s {
            return None;
        }
        // the emptiest column with a part of at least a narrow person on each side
        let part = (pw / s).ceil() as usize;
        let mut cut: Option<usize> = None;
        for k in a + part..b.saturating_sub(part) {
            if cut.is_none_or(|q| cols[k] < cols[q]) {
                cut = Some(k);
            }
        }
        let mut cut = cut?;
        let peak = |r: std::ops::Range<usize>| cols[r].iter().copied().max().unwrap_or(0);
        let low = |cut: usize| peak(a..cut).min(peak(cut + 1..b)) as f64;
        let low_at_gap = low(cut);
        if low_at_gap < 0.5 * fh || cols[cut] as f64 > 0.5 * low_at_gap {
            // no gap: a pair held from the previous frame is cut where it was (`fg_pairs_hold`)
            let held = hold
                .map(|x| x.round() - x0 as f64)
                .filter(|&k| k >= (a + part) as f64 && k < b.saturating_sub(part) as f64)?;
            cut = held as usize;
            if low(cut) < 0.5 * fh {
                return None;
            }
        }
        // each part at most one person wide (a part wider than that is a person and
        // something else: a third person, or a ghost left in the background)
        for r in [a..cut, cut + 1..b] {
            let (ca, cb) = span(&cols[r])?;
            if (cb - ca) as f64 > cfg.fg_max_aspect * pw {
                return None;
            }
        }
        // each part's box from its own pixels (sizes bounded as the fit's)
        let fit_part = |r: std::ops::Range<usize>, near: Option<[f64; 2]>| -> Option<BBox> {
            let prow: Vec<usize> = (0..wh)
                .map(|yy| {
                    mask[yy * ww + r.start..yy * ww + r.end]
                        .iter()
                        .filter(|&&m| m)
                        .count()
                })
                .collect();
            let (ra, rb) = span(&prow)?;
            let (ca, cb) = span(&cols[r.clone()])?;
            let (ya, yb) = ((y0 + ra) as f64, (y0 + rb) as f64);
            let (xa, xb) = ((x0 + r.start + ca) as f64, (x0 + r.start + cb) as f64);
            let want = near.unwrap_or([f64::midpoint(xa, xb), f64::midpoint(ya, yb)]);
            let axis = |lo: f64, hi: f64, size: f64, c: f64, cap: f64| -> (f64, f64) {
                let len = (hi - lo).clamp(size / s, size * s).min(cap.max(size / s));
                let (l, h) = (lo + len / 2.0, hi - len / 2.0);
                (
                    if l <= h {
                        c.clamp(l, h)
                    } else {
                        f64::midpoint(lo, hi)
                    },
                    len,
                )
            };
            let (cy, ph) = axis(ya, yb, cfg.box_h, want[1], f64::INFINITY);
            let cap = cfg.fg_max_aspect * cfg.box_w / cfg.box_h * ph;
            let (cx, pwid) = axis(xa, xb, cfg.box_w, want[0], cap);
            Some(BBox {
                cx,
                cy,
                w: pwid,
                h: ph,
            })
        };
        // the target keeps the part holding more of its own regions' foreground
        let own_left: usize = cols_own[a..cut].iter().sum();
        let own_right: usize = cols_own[cut + 1..b].iter().sum();
        let (mine, other) = if own_left >= own_right {
            (a..cut, cut + 1..b)
        } else {
            (cut + 1..b, a..cut)
        };
        Some((fit_part(mine, Some(c))?, fit_part(other, None)?))
    }

    /// `fg_pairs`: refreshes, creates or hides the companions after this frame's fits;
    /// `pairs[k]` holds the boxes of target `k`'s part and of the other person (the targets
    /// before any creation). A companion is created when the pair has lasted `birth_frames`
    /// frames and the other part moved with the target's part meanwhile (their displacements
    /// differ by at most half the target's or `still_px`): foreground left behind where a
    /// person stood while the background warms up (a ghost) stays put.
    fn update_companions(
        &mut self,
        pairs: &[Option<[BBox; 2]>],
        t: u64,
    ) -> Result<usize, TrackerError> {
        let inside = |b: &BBox, p: [f64; 2]| {
            (p[0] - b.cx).abs() < b.w / 2.0 && (p[1] - b.cy).abs() < b.h / 2.0
        };
        let mut created = 0;
        for (k, pair) in pairs.iter().enumerate() {
            let id = self.targets[k].id;
            let companion = self.targets.iter().position(|o| o.host == Some(id));
            // not where another target (but the host and its companion) is reported
            let pair = pair.filter(|[_, b]| {
                !self.targets.iter().any(|o| {
                    o.id != id
                        && o.host != Some(id)
                        && o.report.is_some_and(|r| inside(&r, [b.cx, b.cy]))
                })
            });
            let Some([hb, b]) = pair else {
                self.targets[k].pair_streak = 0;
                continue;
            };
            let tg = &mut self.targets[k];
            tg.pair_streak += 1;
            if tg.pair_streak == 1 {
                tg.pair_first = [[hb.cx, hb.cy], [b.cx, b.cy]];
            }
            if let Some(c) = companion {
                let cp = &mut self.targets[c];
                cp.report = Some(b);
                cp.centre = [b.cx, b.cy];
                cp.lost = 0;
                cp.no_fg = 0;
            } else if tg.pair_streak >= self.cfg.birth_frames {
                let [h0, o0] = tg.pair_first;
                let dh = [hb.cx - h0[0], hb.cy - h0[1]];
                let d_o = [b.cx - o0[0], b.cy - o0[1]];
                let apart = (d_o[0] - dh[0]).hypot(d_o[1] - dh[1]);
                if apart > (0.5 * dh[0].hypot(dh[1])).max(self.cfg.still_px) {
                    tg.pair_streak = 0;
                    continue;
                }
                let cid = TrackId(self.next_id);
                self.next_id += 1;
                created += 1;
                let mut cp = Target::start(
                    cid,
                    [b.cx, b.cy],
                    Vec::new(),
                    WeightedPool::new(self.cfg.pool_params())?,
                    t,
                );
                cp.host = Some(id);
                cp.report = Some(b);
                self.targets.push(cp);
            }
        }
        Ok(created)
    }

    /// With `fg_skip_background` and a background of at least 3 samples: per label (index =
    /// label), whether the region holds at least `fg_min_frac`/4 · w·h foreground pixels.
    fn foreground_regions(&self, seg: &Segmentation, frame: &Plane<u8>) -> Option<Vec<bool>> {
        let bg = self.background.as_ref().filter(|b| {
            self.cfg.fg_skip_background && b.samples_held() >= 3.min(b.params().samples)
        })?;
        let mut count = vec![0u32; seg.n_regions() + 1];
        let thr = self.cfg.fg_threshold;
        for ((&v, &b), &l) in frame
            .data
            .iter()
            .zip(&bg.background().data)
            .zip(&seg.labels.data)
        {
            if v.abs_diff(b) > thr
                && let Some(c) = count.get_mut(l as usize)
            {
                *c += 1;
            }
        }
        let min = self.cfg.fg_min_frac / 4.0 * self.cfg.box_w * self.cfg.box_h;
        Some(count.iter().map(|&c| f64::from(c) >= min).collect())
    }

    /// Foreground births (`fg_births`, see the config docs): blobs of foreground that no live
    /// target's box covers, confirmed over `birth_frames` frames, start targets on the unowned
    /// regions whose minima lie in the blob. Returns the number of targets created.
    fn foreground_births(
        &mut self,
        seg: &Segmentation,
        frame: &Plane<u8>,
        t: u64,
    ) -> Result<usize, TrackerError> {
        const CELL: usize = 4;
        let Some(bg) = self
            .background
            .as_ref()
            .filter(|b| b.samples_held() >= 3.min(b.params().samples))
        else {
            self.birth_candidates.clear();
            return Ok(0);
        };
        let cfg = &self.cfg;
        let (w, h) = (seg.labels.width as usize, seg.labels.height as usize);
        let (gw, gh) = (w.div_ceil(CELL), h.div_ceil(CELL));
        let back = &bg.background().data;
        // cells with at least a quarter of their pixels in the foreground
        let mut count = vec![0u16; gw * gh];
        for y in 0..h {
            let crow = (y / CELL) * gw;
            for x in 0..w {
                let i = y * w + x;
                if frame.data[i].abs_diff(back[i]) > cfg.fg_threshold {
                    count[crow + x / CELL] += 1;
                }
            }
        }
        let mut cell: Vec<bool> = (0..gw * gh)
            .map(|c| {
                let (cx, cy) = (c % gw, c / gw);
                let cw = CELL.min(w - cx * CELL);
                let ch = CELL.min(h - cy * CELL);
                usize::from(count[c]) * 4 >= cw * ch
            })
            .collect();
        // cells whose centre lies in a live target's box are covered
        for tg in &self.targets {
            if tg.host.is_some() && tg.report.is_none() {
                continue;
            }
            let b = tg.report.unwrap_or(BBox {
                cx: tg.centre[0],
                cy: tg.centre[1],
                w: cfg.box_w,
                h: cfg.box_h,
            });
            let (l, tp) = (b.cx - b.w / 2.0, b.cy - b.h / 2.0);
            let c0 = ((l / CELL as f64 - 0.5).ceil().max(0.0)) as usize;
            let r0 = ((tp / CELL as f64 - 0.5).ceil().max(0.0)) as usize;
            let c1 = ((l + b.w) / CELL as f64 - 0.5).floor();
            let r1 = ((tp + b.h) / CELL as f64 - 0.5).floor();
            if c1 < 0.0 || r1 < 0.0 {
                continue;
            }
            let (c1, r1) = ((c1 as usize).min(gw - 1), (r1 as usize).min(gh - 1));
            for r in r0..=r1 {
                for c in c0..=c1 {
                    cell[r * gw + c] = false;
                }
            }
        }
        // 8-connected blobs of the remaining cells
        let mut seen = vec![false; gw * gh];
        let mut blobs: Vec<[f64; 4]> = Vec::new();
        let mut stack = Vec::new();
        let min_area = cfg.birth_min_frac * cfg.box_w * cfg.box_h;
        for start in 0..gw * gh {
            if !cell[start] || seen[start] {
                continue;
            }
            seen[start] = true;
            stack.push(start);
            let (mut n, mut bb) = (0usize, [usize::MAX, usize::MAX, 0, 0]);
            while let Some(c) = stack.pop() {
                let (cx, cy) = (c % gw, c / gw);
                n += 1;
                bb = [bb[0].min(cx), bb[1].min(cy), bb[2].max(cx), bb[3].max(cy)];
                for &(dx, dy) in quarry_vision::Connectivity::Eight.offsets() {
                    let (nx, ny) = (cx as i64 + i64::from(dx), cy as i64 + i64::from(dy));
                    if nx < 0 || ny < 0 || nx >= gw as i64 || ny >= gh as i64 {
                        continue;
                    }
                    let q = ny as usize * gw + nx as usize;
                    if cell[q] && !seen[q] {
                        seen[q] = true;
                        stack.push(q);
                    }
                }
            }
            let area = (n * CELL * CELL) as f64;
            let px = [
                (bb[0] * CELL) as f64,
                (bb[1] * CELL) as f64,
                ((bb[2] + 1) * CELL).min(w) as f64,
                ((bb[3] + 1) * CELL).min(h) as f64,
            ];
            if area >= min_area && px[3] - px[1] >= 0.5 * cfg.box_h {
                blobs.push(px);
            }
        }
        let iou = |a: &[f64; 4], b: &[f64; 4]| {
            let ix = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
            let iy = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
            let i = ix * iy;
            let u = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - i;
            if u > 0.0 { i / u } else { 0.0 }
        };
        let prev = std::mem::take(&mut self.birth_candidates);
        let mut next = Vec::new();
        let mut created = 0;
        let mut owned = vec![false; seg.n_regions() + 1];
        for tg in &self.targets {
            for r in &tg.regions {
                if let Some(o) = owned.get_mut(r.label as usize) {
                    *o = true;
                }
            }
        }
        for b in blobs {
            let streak = prev
                .iter()
                .filter(|(p, _)| iou(p, &b) >= 0.3)
                .map(|(_, s)| *s)
                .max()
                .unwrap_or(0)
                + 1;
            if streak < self.cfg.birth_frames {
                next.push((b, streak));
                continue;
            }
            // [ext] births_wait_for_occluded: a blob within one box of an occluded target's box
            if self.cfg.births_wait_for_occluded
                && self.targets.iter().any(|tg| {
                    tg.occluded && {
                        let c = tg.centre;
                        let (hw, hh) = (1.5 * cfg.box_w, 1.5 * cfg.box_h);
                        c[0] > b[0] - hw && c[0] < b[2] + hw && c[1] > b[1] - hh && c[1] < b[3] + hh
                    }
                })
            {
                next.push((b, streak));
                continue;
            }
            let mut labels: Vec<u32> = seg
                .minima
                .iter()
                .enumerate()
                .filter(|(l, m)| {
                    let (x, y) = (f64::from(m.representative.0), f64::from(m.representative.1));
                    !owned[l + 1] && x >= b[0] && x < b[2] && y >= b[1] && y < b[3]
                })
                .map(|(l, _)| l as u32 + 1)
                .collect();
            if labels.is_empty() {
                let (x, y) = (
                    f64::midpoint(b[0], b[2]) as usize,
                    f64::midpoint(b[1], b[3]) as usize,
                );
                let l = seg.labels.data[y.min(h - 1) * w + x.min(w - 1)];
                if !owned[l as usize] {
                    labels.push(l);
                }
            }
            if labels.is_empty() {
                next.push((b, streak));
                continue;
            }
            let regions: Vec<RegionRef> = labels
                .iter()
                .map(|&l| RegionRef {
                    label: l,
                    minimum: seg.minima[l as usize - 1].representative,
                    provenance: Provenance::MovingPoint,
                })
                .collect();
            let n = regions.len() as f64;
            let centre = [
                regions.iter().map(|r| f64::from(r.minimum.0)).sum::<f64>() / n,
                regions.iter().map(|r| f64::from(r.minimum.1)).sum::<f64>() / n,
            ];
            let cfg = &self.cfg;
            let s = cfg.fg_max_scale;
            let fh = (b[3] - b[1]).clamp(cfg.box_h / s, cfg.box_h * s);
            let wcap = (cfg.fg_max_aspect * cfg.box_w / cfg.box_h * fh).max(cfg.box_w / s);
            let fw = (b[2] - b[0]).clamp(cfg.box_w / s, cfg.box_w * s).min(wcap);
            let bc = [f64::midpoint(b[0], b[2]), f64::midpoint(b[1], b[3])];
            let fit = [bc[0] - centre[0], bc[1] - centre[1], fw, fh];
            for &l in &labels {
                owned[l as usize] = true;
            }
            let id = TrackId(self.next_id);
            self.next_id += 1;
            created += 1;
            let mut target = Target::start(
                id,
                centre,
                regions,
                WeightedPool::new(self.cfg.pool_params())?,
                t,
            );
            target.fit = Some(fit);
            target.report = Some(BBox {
                cx: bc[0],
                cy: bc[1],
                w: fw,
                h: fh,
            });
            self.targets.push(target);
        }
        self.birth_candidates = next;
        Ok(created)
    }

    /// `recall_ids`: each target reported for the first time this frame (`show`) takes the id
    /// of a lost target — one that ended, or is alive but not reported this frame, and was
    /// last reported at most `lost_frames` frames ago — when its box centre lies within
    /// `box_w` of where the lost target's last box would be by now at the velocity of its
    /// last reported frames; nearest pairs first. A live lost target whose id is taken ends.
    fn recall(&mut self, show: &[bool], t: u64) {
        /// Where a lost target is kept: `ended[i]`, or `targets[k]` (alive, unreported).
        #[derive(Clone, Copy)]
        enum Source {
            Ended(usize),
            Live(usize),
        }
        let window = self.cfg.lost_frames as u64;
        self.ended.retain(|e| t.saturating_sub(e.last) <= window);
        let mut lost: Vec<(Source, Ended)> = self
            .ended
            .iter()
            .enumerate()
            .map(|(i, e)| (Source::Ended(i), e.clone()))
            .collect();
        for (k, tg) in self.targets.iter().enumerate() {
            // a target hosting a companion stays (the companion lives on its host's pair)
            if show[k] || self.targets.iter().any(|o| o.host == Some(tg.id)) {
                continue;
            }
            if let Some(e) = last_motion(tg)
                && t.saturating_sub(e.last) <= window
            {
                lost.push((Source::Live(k), e));
            }
        }
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (k, tg) in self.targets.iter().enumerate() {
            let Some(b) = tg.report.filter(|_| show[k] && tg.last_shown.is_none()) else {
                continue;
            };
            for (i, (_, e)) in lost.iter().enumerate() {
                if e.last >= t {
                    continue;
                }
                let dt = (t - e.at) as f64;
                let (c, v) = (e.centre, e.velocity);
                let d = (b.cx - (c[0] + v[0] * dt)).hypot(b.cy - (c[1] + v[1] * dt));
                if d <= self.cfg.box_w {
                    pairs.push((d, k, i));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let (mut used_k, mut used_i) = (BTreeSet::new(), BTreeSet::new());
        let mut gone_targets = BTreeSet::new();
        let mut gone_ended = BTreeSet::new();
        for (_, k, i) in pairs {
            if used_k.contains(&k) || used_i.contains(&i) {
                continue;
            }
            used_k.insert(k);
            used_i.insert(i);
            self.targets[k].report_id = lost[i].1.id;
            match lost[i].0 {
                Source::Ended(e) => gone_ended.insert(e),
                Source::Live(o) => gone_targets.insert(o),
            };
        }
        let mut e = 0;
        self.ended.retain(|_| {
            e += 1;
            !gone_ended.contains(&(e - 1))
        });
        if !gone_targets.is_empty() {
            let mut k = 0;
            self.targets.retain(|_| {
                k += 1;
                !gone_targets.contains(&(k - 1))
            });
        }
    }

    /// Fuses visible targets whose boxes overlapped (IoU >= `fuse_iou`) for `fuse_frames`
    /// consecutive frames: the younger (larger id) joins the older.
    fn fuse(&mut self) {
        let n = self.targets.len();
        let visible = |t: &Target| !t.occluded && !t.regions.is_empty();
        let mut absorbed = vec![false; n];
        for i in 0..n {
            let mut streak = std::mem::take(&mut self.targets[i].fuse_streak);
            let mut next = BTreeMap::new();
            for j in 0..n {
                if i == j || absorbed[i] || absorbed[j] || self.targets[j].id <= self.targets[i].id
                {
                    continue;
                }
                let (a, b) = (&self.targets[i], &self.targets[j]);
                if !(visible(a) && visible(b)) {
                    continue;
                }
                if self.bbox(a.centre).iou(&self.bbox(b.centre)) >= self.cfg.fuse_iou {
                    let s = streak.get(&b.id).copied().unwrap_or(0) + 1;
                    if s >= self.cfg.fuse_frames.max(1) {
                        absorbed[j] = true;
                        let regs = std::mem::take(&mut self.targets[j].regions);
                        let a = &mut self.targets[i];
                        for r in regs {
                            if !a.regions.iter().any(|x| x.label == r.label) {
                                a.regions.push(r);
                            }
                        }
                        let m = a.regions.len() as f64;
                        a.centre = [
                            a.regions
                                .iter()
                                .map(|r| f64::from(r.minimum.0))
                                .sum::<f64>()
                                / m,
                            a.regions
                                .iter()
                                .map(|r| f64::from(r.minimum.1))
                                .sum::<f64>()
                                / m,
                        ];
                    } else {
                        next.insert(b.id, s);
                    }
                }
            }
            streak.clear();
            self.targets[i].fuse_streak = next;
        }
        let mut k = 0;
        self.targets.retain(|_| {
            let keep = !absorbed[k];
            k += 1;
            keep
        });
    }
}

impl MultiTargetTracker for WatershedSiftTracker {
    type Input = Plane<u8>;
    type Error = TrackerError;

    /// Tracks one grey frame. Errors: a frame smaller than 2×2, a frame of another size than
    /// the first, a frame whose pixel count does not match its size.
    ///
    /// With the `rayon` feature, a call from outside a rayon pool runs the frame on a worker of
    /// the global pool: one hand-off per frame instead of one per parallel blur pass of every
    /// SIFT crop (a few hundred per frame, which cost 5-10 % of the frame in scheduler wake-ups
    /// with `RAYON_NUM_THREADS=1`). The result does not depend on the thread.
    fn step(&mut self, stamp: Stamp, input: &Plane<u8>) -> Result<Vec<TrackReport>, TrackerError> {
        if input.data.len() != input.width as usize * input.height as usize {
            return Err(TrackerError::State(format!(
                "frame data has {} pixels for a {}x{} frame",
                input.data.len(),
                input.width,
                input.height
            )));
        }
        #[cfg(feature = "rayon")]
        if rayon::current_thread_index().is_none() {
            return rayon::scope(|_| self.process(stamp, input));
        }
        self.process(stamp, input)
    }
}

/// Reads a mapping's relation counts (used by the diagnostics of callers).
pub fn mapping_counts(map: &RegionMapping) -> (usize, usize, usize) {
    (map.bidirectional.len(), map.merges.len(), map.splits.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A robust tracker for a 32×84 person (box_w = 32, lost_frames = 10).
    fn tracker() -> WatershedSiftTracker {
        WatershedSiftTracker::new(WatershedSiftConfig::robust().with_person_size(32.0, 84.0))
            .unwrap()
    }

    /// A target `id` reported in frames `from..=to` moving from `c0` at `v` px per frame; not
    /// reported now.
    fn lost_target(
        tr: &WatershedSiftTracker,
        id: u32,
        from: u64,
        to: u64,
        c0: [f64; 2],
        v: [f64; 2],
    ) -> Target {
        let mut tg = Target::start(
            TrackId(id),
            c0,
            Vec::new(),
            WeightedPool::new(tr.cfg.pool_params()).unwrap(),
            from,
        );
        for f in from..=to {
            let d = (f - from) as f64;
            tg.reported
                .push_back((f, [c0[0] + v[0] * d, c0[1] + v[1] * d]));
            while tg.reported.len() > RECALL_VELOCITY_FRAMES + 1 {
                tg.reported.pop_front();
            }
        }
        tg.last_shown = Some(to);
        tg
    }

    /// A target `id` born now and reported for the first time at `c`.
    fn newborn(tr: &WatershedSiftTracker, id: u32, t: u64, c: [f64; 2]) -> Target {
        let mut tg = Target::start(
            TrackId(id),
            c,
            Vec::new(),
            WeightedPool::new(tr.cfg.pool_params()).unwrap(),
            t,
        );
        tg.report = Some(BBox {
            cx: c[0],
            cy: c[1],
            w: 30.0,
            h: 80.0,
        });
        tg
    }

    /// Runs the recall on `targets` (`show`: reported this frame) at frame `t`; (own id,
    /// reported id) of the targets left.
    fn recall_on(
        tr: &mut WatershedSiftTracker,
        targets: Vec<Target>,
        show: &[bool],
        t: u64,
    ) -> Vec<(u32, u32)> {
        tr.targets = targets;
        tr.recall(show, t);
        tr.targets.iter().map(|t| (t.id.0, t.report_id.0)).collect()
    }

    /// A lost live target's id goes to the newborn where it was going (its last box moved at
    /// its velocity), and the lost target ends; a newborn elsewhere keeps its own id.
    #[test]
    fn a_newborn_where_a_lost_target_was_going_takes_its_id() {
        let mut tr = tracker();
        // reported in frames 10-14 at 4 px/frame: at frame 17 it would be at x = 116 + 12
        let a = lost_target(&tr, 1, 10, 14, [100.0, 200.0], [4.0, 0.0]);
        let b = newborn(&tr, 2, 17, [131.0, 202.0]);
        let c = newborn(&tr, 3, 17, [300.0, 200.0]);
        let ids = recall_on(&mut tr, vec![a, b, c], &[false, true, true], 17);
        assert_eq!(ids, vec![(2, 1), (3, 3)]);
    }

    /// A target whose box was held (occluded, located nowhere, no fit: the same box again)
    /// keeps walking in the recall: its motion is measured on its observed boxes and predicted
    /// from the last of them, and the window counts from its last held report.
    #[test]
    fn a_held_box_is_not_motion() {
        let mut tr = tracker();
        // fitted in frames 10-14 walking left at 3 px/frame (x 130 -> 118), then held at
        // x = 118 in frames 15-20 (occluded); a newborn at frame 26, 10 frames later still
        let mut a = lost_target(&tr, 1, 10, 14, [130.0, 200.0], [-3.0, 0.0]);
        a.last_shown = Some(20);
        // where it was going: 118 - 3 * 12 = 82
        let b = newborn(&tr, 2, 26, [84.0, 200.0]);
        let ids = recall_on(&mut tr, vec![a.clone(), b.clone()], &[false, true], 26);
        assert_eq!(ids, vec![(2, 1)]);
        // the same target with its held boxes taken as motion (reported in 10-20, standing
        // from 15) would be predicted at rest near x = 118, 34 px from the newborn
        let mut still = a;
        for f in 15..=20 {
            still.reported.push_back((f, [118.0, 200.0]));
            while still.reported.len() > RECALL_VELOCITY_FRAMES + 1 {
                still.reported.pop_front();
            }
        }
        let ids = recall_on(&mut tr, vec![still, b], &[false, true], 26);
        assert_eq!(ids, vec![(1, 1), (2, 2)]);
        // 11 frames after the last held report: outside the window
        let mut tr = tracker();
        let mut a = lost_target(&tr, 1, 10, 14, [130.0, 200.0], [-3.0, 0.0]);
        a.last_shown = Some(20);
        let b = newborn(&tr, 2, 31, [118.0 - 3.0 * 17.0, 200.0]);
        let ids = recall_on(&mut tr, vec![a, b], &[false, true], 31);
        assert_eq!(ids, vec![(1, 1), (2, 2)]);
    }

    /// The gate is one box width around the predicted place (at rest: the last place), the
    /// window `lost_frames` frames after the last report.
    #[test]
    fn recall_is_gated_in_space_and_time() {
        for (t, x, recalled) in [
            (24, 110.0 + 31.0, true),  // 10 frames after the last report, 31 px away
            (24, 110.0 + 33.0, false), // 33 px: outside one box width
            (25, 110.0, false),        // 11 frames after the last report
        ] {
            let mut tr = tracker();
            let a = lost_target(&tr, 1, 10, 14, [110.0, 200.0], [0.0, 0.0]);
            let b = newborn(&tr, 2, t, [x, 200.0]);
            let ids = recall_on(&mut tr, vec![a, b], &[false, true], t);
            if recalled {
                assert_eq!(ids, vec![(2, 1)], "t {t} x {x}");
            } else {
                assert_eq!(ids, vec![(1, 1), (2, 2)], "t {t} x {x}");
            }
        }
    }

    /// Nearest pairs first and each lost id once: of two newborns near one lost target the
    /// nearer takes its id; an ended target's id is recalled once and then forgotten; a
    /// target hosting a companion is not taken.
    #[test]
    fn recall_takes_nearest_pairs_first_and_each_id_once() {
        let mut tr = tracker();
        let a = lost_target(&tr, 1, 10, 14, [100.0, 200.0], [0.0, 0.0]);
        let far = newborn(&tr, 2, 16, [120.0, 200.0]);
        let near = newborn(&tr, 3, 16, [105.0, 200.0]);
        let ids = recall_on(&mut tr, vec![a, far, near], &[false, true, true], 16);
        assert_eq!(ids, vec![(2, 2), (3, 1)]);

        let mut tr = tracker();
        tr.ended.push(Ended {
            id: TrackId(7),
            last: 14,
            at: 14,
            centre: [100.0, 200.0],
            velocity: [2.0, 0.0],
        });
        let b = newborn(&tr, 8, 16, [104.0, 200.0]);
        let ids = recall_on(&mut tr, vec![b], &[true], 16);
        assert_eq!(ids, vec![(8, 7)]);
        assert!(tr.ended.is_empty());

        let mut tr = tracker();
        let host = lost_target(&tr, 1, 10, 14, [100.0, 200.0], [0.0, 0.0]);
        let mut companion = newborn(&tr, 2, 12, [140.0, 200.0]);
        companion.host = Some(TrackId(1));
        companion.reported.push_back((14, [140.0, 200.0]));
        companion.last_shown = Some(14);
        let b = newborn(&tr, 3, 16, [101.0, 200.0]);
        let ids = recall_on(&mut tr, vec![host, companion, b], &[false, true, true], 16);
        assert_eq!(ids, vec![(1, 1), (2, 2), (3, 3)]);
    }
}
