//! Scenario tests of the watershed + SIFT tracker (spec 004 §7.1 T2 and a crossing) on small
//! synthetic videos: a value-noise background, dark textured walkers, Gaussian pixel noise,
//! everything seeded.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_core::{MultiTargetTracker, Plane, Stamp, TrackReport, TrackStatus};
use quarry_trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Smooth value noise in [-1, 1] on a lattice of `spacing` px.
struct ValueNoise {
    grid: Vec<f64>,
    gw: usize,
    spacing: f64,
}

impl ValueNoise {
    fn new(w: u32, h: u32, spacing: f64, rng: &mut StdRng) -> Self {
        let gw = (f64::from(w) / spacing) as usize + 3;
        let gh = (f64::from(h) / spacing) as usize + 3;
        let grid = (0..gw * gh).map(|_| rng.random_range(-1.0..1.0)).collect();
        Self { grid, gw, spacing }
    }

    fn at(&self, x: f64, y: f64) -> f64 {
        let (u, v) = (x / self.spacing + 1.0, y / self.spacing + 1.0);
        let (i, j) = (u.floor().max(0.0) as usize, v.floor().max(0.0) as usize);
        let s = |t: f64| t * t * (3.0 - 2.0 * t);
        let (fx, fy) = (s(u - u.floor()), s(v - v.floor()));
        let g = |a: usize, b: usize| self.grid.get(b * self.gw + a).copied().unwrap_or_default();
        let top = g(i, j) * (1.0 - fx) + g(i + 1, j) * fx;
        let bot = g(i, j + 1) * (1.0 - fx) + g(i + 1, j + 1) * fx;
        top * (1.0 - fy) + bot * fy
    }
}

/// A walker: start centre, velocity, first frame, mean grey.
#[derive(Clone, Copy)]
struct Walker {
    start: [f64; 2],
    vel: [f64; 2],
    t0: u64,
    mean: f64,
}

const W: u32 = 240;
const H: u32 = 120;
/// Walker half-width and half-height (an ellipse of 14 x 34 px).
const RX: f64 = 7.0;
const RY: f64 = 17.0;

fn centre(wk: &Walker, t: u64) -> Option<[f64; 2]> {
    (t >= wk.t0).then(|| {
        let d = (t - wk.t0) as f64;
        [wk.start[0] + wk.vel[0] * d, wk.start[1] + wk.vel[1] * d]
    })
}

/// Renders `frames` frames of the walkers (later ones in front).
fn video(walkers: &[Walker], frames: u64, seed: u64) -> Vec<Plane<u8>> {
    video_with(walkers, frames, seed, |i, t| centre(&walkers[i], t))
}

/// Renders `frames` frames of the walkers with walker `i` at `at(i, t)` in frame `t` (hidden
/// where `None`; later ones in front).
fn video_with(
    walkers: &[Walker],
    frames: u64,
    seed: u64,
    at: impl Fn(usize, u64) -> Option<[f64; 2]>,
) -> Vec<Plane<u8>> {
    let mut rng = StdRng::seed_from_u64(seed);
    let bg1 = ValueNoise::new(W, H, 24.0, &mut rng);
    let bg2 = ValueNoise::new(W, H, 12.0, &mut rng);
    let tex: Vec<ValueNoise> = walkers
        .iter()
        .map(|_| ValueNoise::new(40, 60, 3.0, &mut rng))
        .collect();
    let noise = Normal::new(0.0, 2.0).unwrap();
    (0..frames)
        .map(|t| {
            let mut data = Vec::with_capacity((W * H) as usize);
            for y in 0..H {
                for x in 0..W {
                    let (fx, fy) = (f64::from(x), f64::from(y));
                    let mut v = 165.0 + 30.0 * (0.67 * bg1.at(fx, fy) + 0.33 * bg2.at(fx, fy));
                    for (i, (wk, tx)) in walkers.iter().zip(&tex).enumerate() {
                        if let Some(c) = at(i, t) {
                            let (u, w) = (fx - c[0], fy - c[1]);
                            if (u / RX).powi(2) + (w / RY).powi(2) <= 1.0 {
                                v = wk.mean + 30.0 * tx.at(u + 20.0, w + 30.0);
                            }
                        }
                    }
                    v += noise.sample(&mut rng);
                    data.push(v.round().clamp(0.0, 255.0) as u8);
                }
            }
            Plane::from_vec(W, H, data).unwrap()
        })
        .collect()
}

fn config(robust: bool) -> WatershedSiftConfig {
    let c = if robust {
        WatershedSiftConfig::robust()
    } else {
        WatershedSiftConfig::paper()
    };
    c.with_person_size(2.0 * RX + 2.0, 2.0 * RY + 2.0)
}

fn run(cfg: WatershedSiftConfig, frames: &[Plane<u8>]) -> Vec<Vec<TrackReport>> {
    let mut tr = WatershedSiftTracker::new(cfg).unwrap();
    frames
        .iter()
        .enumerate()
        .map(|(k, f)| tr.step(Stamp::from_frame(k as u64, 0.04), f).unwrap())
        .collect()
}

/// The report whose centre is nearest `c`, within `r` px.
fn near(reports: &[TrackReport], c: [f64; 2], r: f64) -> Option<&TrackReport> {
    reports
        .iter()
        .filter_map(|rp| {
            let b = rp.bbox?;
            let d = (b.cx - c[0]).hypot(b.cy - c[1]);
            (d <= r).then_some((d, rp))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|x| x.1)
}

/// T2: one walker at 2 px/frame is detected within N + 5 frames of being fully visible, its
/// centre stays within 6 px of the silhouette centre, and it keeps one identity; no other track.
#[test]
fn single_walker_is_found_and_followed() {
    let wk = Walker {
        start: [10.0, 60.0],
        vel: [2.0, 0.0],
        t0: 0,
        mean: 80.0,
    };
    let frames = video(&[wk], 90, 7);
    for robust in [false, true] {
        let out = run(config(robust), &frames);
        // fully visible from t = 0 (x = 10 > RX): detected by N + 5 = 15
        let first = out
            .iter()
            .position(|r| centre(&wk, 0).is_some() && !r.is_empty())
            .expect("never detected");
        assert!(first <= 15, "robust={robust}: first track at frame {first}");
        let mut ids = std::collections::BTreeSet::new();
        let mut errs = Vec::new();
        let mut extra = 0;
        for (t, reps) in out.iter().enumerate().skip(first) {
            let c = centre(&wk, t as u64).unwrap();
            if c[0] > f64::from(W) - RX - 2.0 {
                break;
            }
            match near(reps, c, 12.0) {
                Some(r) => {
                    ids.insert(r.id);
                    let b = r.bbox.unwrap();
                    errs.push((b.cx - c[0]).hypot(b.cy - c[1]));
                }
                None => errs.push(f64::INFINITY),
            }
            extra += reps.len().saturating_sub(1);
        }
        errs.sort_by(f64::total_cmp);
        let median = errs[errs.len() / 2];
        let covered = errs.iter().filter(|e| e.is_finite()).count() as f64 / errs.len() as f64;
        assert!(
            median <= 6.0,
            "robust={robust}: median centre error {median}"
        );
        assert!(covered >= 0.9, "robust={robust}: covered {covered}");
        assert_eq!(ids.len(), 1, "robust={robust}: ids {ids:?}");
        assert!(
            extra as f64 <= 0.1 * errs.len() as f64,
            "robust={robust}: {extra} extra boxes"
        );
    }
}

/// Two walkers in opposite directions cross; both are tracked before and after the crossing,
/// and the robust profile keeps their identities (the paper profile is reported, not gated, on
/// identity: its occlusion handling is the paper's).
#[test]
fn two_walkers_cross() {
    let a = Walker {
        start: [12.0, 58.0],
        vel: [1.5, 0.0],
        t0: 0,
        mean: 70.0,
    };
    let b = Walker {
        start: [228.0, 62.0],
        vel: [-1.5, 0.0],
        t0: 0,
        mean: 100.0,
    };
    let frames = video(&[a, b], 140, 11);
    for robust in [false, true] {
        let out = run(config(robust), &frames);
        let ids_at = |t: usize| {
            (
                near(&out[t], centre(&a, t as u64).unwrap(), 12.0).map(|r| r.id),
                near(&out[t], centre(&b, t as u64).unwrap(), 12.0).map(|r| r.id),
            )
        };
        // before the crossing (x meet at t = 72): both tracked at t = 40..55
        let mut before = 0;
        for t in 40..55 {
            if let (Some(_), Some(_)) = ids_at(t) {
                before += 1;
            }
        }
        assert!(
            before >= 12,
            "robust={robust}: both tracked in {before}/15 frames before"
        );
        let mut after = 0;
        for t in 100..130 {
            if let (Some(x), Some(y)) = ids_at(t)
                && x != y
            {
                after += 1;
            }
        }
        assert!(
            after >= 20,
            "robust={robust}: both tracked in {after}/30 frames after"
        );
    }
}

/// Bad input: frames of different sizes and 1x1 frames are errors, not panics.
#[test]
fn bad_frames_are_errors() {
    let mut tr = WatershedSiftTracker::new(WatershedSiftConfig::paper()).unwrap();
    assert!(
        tr.step(Stamp::from_frame(0, 0.04), &Plane::new(1, 1, 0u8))
            .is_err()
    );
    tr.step(Stamp::from_frame(0, 0.04), &Plane::new(40, 30, 100u8))
        .unwrap();
    let e = tr
        .step(Stamp::from_frame(1, 0.04), &Plane::new(41, 30, 100u8))
        .unwrap_err();
    assert!(e.to_string().contains("same size"), "{e}");
    let bad = Plane {
        width: 10,
        height: 10,
        data: vec![0u8; 7],
    };
    assert!(tr.step(Stamp::from_frame(2, 0.04), &bad).is_err());
}

/// Two runs are identical (spec E7).
#[test]
fn deterministic() {
    let wk = Walker {
        start: [20.0, 60.0],
        vel: [2.0, 0.5],
        t0: 0,
        mean: 80.0,
    };
    let frames = video(&[wk], 40, 3);
    let a = run(config(true), &frames);
    let b = run(config(true), &frames);
    assert_eq!(a, b);
}

/// IoU of a report's box with the silhouette's bounding box at centre `c`.
fn silhouette_iou(r: &TrackReport, c: [f64; 2]) -> f64 {
    let b = r.bbox.unwrap();
    let s = quarry_core::BBox {
        cx: c[0],
        cy: c[1],
        w: 2.0 * RX + 1.0,
        h: 2.0 * RY + 1.0,
    };
    b.iou(&s)
}

/// `robust` (`fg_box`): with a configured person size 1.4 times the walker's, the paper's fixed
/// box cannot reach IoU 0.5 with the walker, while the box fitted to the foreground follows the
/// walker's own extent.
#[test]
fn robust_box_fits_the_walker_not_the_configured_size() {
    let wk = Walker {
        start: [20.0, 60.0],
        vel: [2.0, 0.0],
        t0: 0,
        mean: 80.0,
    };
    let frames = video(&[wk], 90, 5);
    let size = (1.4 * (2.0 * RX + 2.0), 1.4 * (2.0 * RY + 2.0));
    let median_iou = |robust: bool| {
        let cfg = if robust {
            WatershedSiftConfig::robust()
        } else {
            WatershedSiftConfig::paper()
        }
        .with_person_size(size.0, size.1);
        let out = run(cfg, &frames);
        let mut ious: Vec<f64> = (30..80)
            .map(|t| {
                let c = centre(&wk, t as u64).unwrap();
                near(&out[t], c, 12.0).map_or(0.0, |r| silhouette_iou(r, c))
            })
            .collect();
        ious.sort_by(f64::total_cmp);
        ious[ious.len() / 2]
    };
    let (paper, robust) = (median_iou(false), median_iou(true));
    assert!(paper < 0.55, "paper median IoU {paper}");
    assert!(robust >= 0.7, "robust median IoU {robust} (paper {paper})");
}

/// Two walkers side by side, 4 px apart (centres 18 px apart, silhouettes 14 px wide), walking
/// along x at 2 px per frame.
fn side_by_side() -> [Walker; 2] {
    let wk = |x: f64, mean: f64| Walker {
        start: [x, 60.0],
        vel: [2.0, 0.0],
        t0: 0,
        mean,
    };
    [wk(20.0, 70.0), wk(38.0, 80.0)]
}

/// Per walker (`at(i, t)` its centre in frame `t`): the frames of `frames` in which a box
/// covers it at IoU ≥ 0.5, and the ids of those boxes.
fn pair_coverage(
    out: &[Vec<TrackReport>],
    at: impl Fn(usize, u64) -> [f64; 2],
    frames: std::ops::Range<usize>,
) -> [(usize, std::collections::BTreeSet<quarry_core::TrackId>); 2] {
    [0, 1].map(|i| {
        let mut ids = std::collections::BTreeSet::new();
        let mut n = 0;
        for t in frames.clone() {
            let c = at(i, t as u64);
            if let Some(r) = out[t]
                .iter()
                .filter(|r| silhouette_iou(r, c) >= 0.5)
                .max_by(|x, y| silhouette_iou(x, c).total_cmp(&silhouette_iou(y, c)))
            {
                n += 1;
                ids.insert(r.id);
            }
        }
        (n, ids)
    })
}

/// Each walker of a [`pair_coverage`] boxed in at least `min` frames under one id, and the
/// two ids different.
fn assert_each_walker_boxed_under_its_own_id(
    coverage: &[(usize, std::collections::BTreeSet<quarry_core::TrackId>); 2],
    min: usize,
) {
    assert!(
        coverage.iter().all(|(n, ids)| *n >= min && ids.len() == 1),
        "{coverage:?}"
    );
    assert_ne!(coverage[0].1, coverage[1].1, "one identity per walker");
}

/// `robust` (`fg_pairs`): two walkers side by side, 4 px apart, with a blur wide enough that
/// they share one minimum and one basin (σ = 10 against silhouettes 14 px wide; on PETS09 a
/// pair at σ = 8.5 does the same). Without `fg_pairs` one target covers the pair and one walker
/// has no box at IoU ≥ 0.5 in most frames; with it each walker has its own box and identity.
#[test]
fn robust_pair_side_by_side_gets_two_boxes() {
    let walkers = side_by_side();
    let frames = video(&walkers, 90, 21);
    // per walker: frames of 40..85 with a box at IoU >= 0.5, and the ids of those boxes
    let coverage = |pairs: bool| {
        let mut cfg = config(true);
        cfg.sigma = 10.0;
        cfg.fg_pairs = pairs;
        let out = run(cfg, &frames);
        pair_coverage(&out, |i, t| centre(&walkers[i], t).unwrap(), 40..85)
    };
    let without = coverage(false);
    let with = coverage(true);
    eprintln!("frames at IoU >= 0.5 of 45, per walker: without {without:?}, with {with:?}");
    let (w0, w1) = (without[0].0.min(without[1].0), with[0].0.min(with[1].0));
    assert!(
        w0 < 20,
        "without fg_pairs the pair is one target: coverage {without:?}"
    );
    assert!(
        w1 >= 40,
        "with fg_pairs: coverage {with:?} (without {without:?})"
    );
    assert!(
        with.iter().all(|(_, ids)| ids.len() == 1) && with[0].1 != with[1].1,
        "one identity per walker: {with:?}"
    );
}

/// `robust` (`fg_pairs`): the same pair as above, but with a typical person size 20 % wider
/// than these walkers (people farther from the camera than the typical person are slimmer at
/// their height, as the pair at the top right of PETS09-S2L1 frames 136-178). The pair's
/// foreground is then 1.7 typical widths wide with a clear gap: a pair for the test of stop 33
/// (at least two narrowest people, 2/`fg_max_scale` = 1.25 widths), not for the earlier one
/// (the widest single person plus the narrowest, 1.93 widths), which left one walker unboxed.
#[test]
fn robust_slim_pair_gets_two_boxes() {
    let walkers = side_by_side();
    let frames = video(&walkers, 90, 21);
    let mut cfg = config(true).with_person_size(1.2 * (2.0 * RX + 2.0), 2.0 * RY + 2.0);
    cfg.sigma = 10.0;
    let out = run(cfg, &frames);
    let coverage = pair_coverage(&out, |i, t| centre(&walkers[i], t).unwrap(), 40..85);
    eprintln!("frames at IoU >= 0.5 of 45, per walker: {coverage:?}");
    assert_each_walker_boxed_under_its_own_id(&coverage, 40);
}

/// `robust` (`fg_pairs`, occlusion groups): two walkers start apart (two targets), converge
/// and walk on side by side 4 px apart, where they share one minimum and one basin and the two
/// targets are tracked through an occlusion on the same regions. Each target is then fitted
/// to one person of the pair and keeps its identity.
#[test]
fn robust_occluded_pair_keeps_two_boxes() {
    let [a, b] = side_by_side();
    // from 24 px above and below the pair's line, converging over 40 frames, then in parallel
    let at = |i: usize, t: u64| {
        let (wk, dy) = if i == 0 { (a, -24.0) } else { (b, 24.0) };
        let k = t.min(40) as f64;
        [
            wk.start[0] + 2.0 * t as f64,
            wk.start[1] + dy * (1.0 - k / 40.0),
        ]
    };
    let frames = video_with(&[a, b], 100, 21, |i, t| Some(at(i, t)));
    let mut cfg = config(true);
    cfg.sigma = 10.0;
    let out = run(cfg, &frames);
    let coverage = pair_coverage(&out, at, 50..95);
    let occluded: usize = out[50..95]
        .iter()
        .map(|r| {
            r.iter()
                .filter(|r| r.status == TrackStatus::Occluded)
                .count()
        })
        .sum();
    eprintln!("frames at IoU >= 0.5 of 45, per walker: {coverage:?}; occluded reports {occluded}");
    assert!(
        occluded >= 60,
        "the test needs an occlusion group ({occluded} reports)"
    );
    assert_each_walker_boxed_under_its_own_id(&coverage, 38);
}

/// `robust` (`fg_pairs_hold`): the side-by-side pair closes up for 26 frames — centres 10 px
/// apart, the 14-px silhouettes overlapping by 4 px, so no column between them is emptier than
/// half a person — and opens again. Without the hold the companion is hidden from the first
/// frame without a gap (and ends `lost_frames` later); with it the pair is cut where it was,
/// and both walkers keep their boxes and identities.
#[test]
fn robust_pair_that_touches_keeps_two_boxes() {
    let [a, b] = side_by_side();
    // b's offset from a: 18 px, closing to 10 px over frames 40-44, opening over 70-74
    let offset = |t: u64| {
        let t = t as f64;
        18.0 - 2.0 * (t - 40.0).clamp(0.0, 4.0) + 2.0 * (t - 70.0).clamp(0.0, 4.0)
    };
    let at = |i: usize, t: u64| {
        let x = a.start[0] + 2.0 * t as f64;
        if i == 0 {
            [x, a.start[1]]
        } else {
            [x + offset(t), b.start[1]]
        }
    };
    let frames = video_with(&[a, b], 100, 21, |i, t| Some(at(i, t)));
    let coverage = |hold: bool| {
        let mut cfg = config(true);
        cfg.sigma = 10.0;
        cfg.fg_pairs_hold = hold;
        pair_coverage(&run(cfg, &frames), at, 44..70)
    };
    let (without, with) = (coverage(false), coverage(true));
    eprintln!("frames at IoU >= 0.5 of 26, per walker: without {without:?}, with {with:?}");
    assert!(
        without[0].0.min(without[1].0) < 13,
        "without the hold one walker of the touching pair is unboxed: {without:?}"
    );
    assert_each_walker_boxed_under_its_own_id(&with, 24);
}

/// Seeded random small frame sequences through both profiles (the fuzz target's input space on
/// stable Rust, so the foreground extensions' box and blob arithmetic is exercised at image
/// borders and on 1-px frames): errors are allowed, panics and non-finite boxes are not.
#[test]
fn random_small_sequences_never_panic() {
    let mut rng = StdRng::seed_from_u64(2024);
    let mut steps = 0usize;
    for case in 0..160u32 {
        let base = if case % 2 == 0 {
            WatershedSiftConfig::paper()
        } else {
            WatershedSiftConfig::robust()
        };
        let pw = f64::from(rng.random_range(4u32..20));
        let mut tr = WatershedSiftTracker::new(base.with_person_size(pw, 2.5 * pw)).unwrap();
        let (mut w, mut h) = (rng.random_range(1u32..49), rng.random_range(1u32..49));
        let blob = rng.random_range(0u32..2) == 1;
        for k in 0..rng.random_range(1u64..25) {
            if rng.random_range(0u32..12) == 0 {
                (w, h) = (rng.random_range(1u32..49), rng.random_range(1u32..49));
            }
            let frame = Plane::from_fn(w, h, |x, y| {
                // half the cases: a dark square walking on noise, the others pure noise
                let inside = blob
                    && (i64::from(x) - 2 * k as i64).abs() < 4
                    && (i64::from(y) - i64::from(h / 2)).abs() < 8;
                if inside {
                    30
                } else {
                    ((x * 31 + y * 17 + k as u32 * 7 + case) % 97 + 120) as u8
                }
            });
            if let Ok(reports) = tr.step(Stamp::from_frame(k, 0.04), &frame) {
                steps += 1;
                for r in reports {
                    let b = r.bbox.unwrap();
                    assert!(
                        [b.cx, b.cy, b.w, b.h].iter().all(|v| v.is_finite()),
                        "case {case} frame {k}: {b:?}"
                    );
                }
            }
        }
    }
    assert!(steps > 500, "only {steps} frames were accepted");
}

/// A single dark walker on a textured ground while the background model is still warming up
/// (the Python guide's example): the ghost the walker leaves in the model trails it like a
/// second person side by side, but it is brighter than the model, so `fg_pairs` reports no
/// companion. Before that rule it reported one behind the walker in frames 12-21 (with the rule
/// applied only outside the target's own regions, still in frame 15).
#[test]
fn robust_pairs_ignore_the_walkers_own_ghost() {
    let (w, h) = (192usize, 96usize);
    let frames: Vec<Plane<u8>> = (0..30)
        .map(|k| {
            let cx = 30.0 + 2.0 * f64::from(k);
            let mut d = vec![0u8; w * h];
            for y in 0..h {
                for x in 0..w {
                    let (xf, yf) = (x as f64, y as f64);
                    let v = if ((xf - cx) / 6.0).powi(2) + ((yf - 40.0) / 14.0).powi(2) <= 1.0 {
                        60.0 + 15.0 * ((xf + yf) * 0.9).sin()
                    } else {
                        170.0 + 20.0 * (xf * 0.3).sin() * (yf * 0.23).cos()
                    };
                    d[y * w + x] = v as u8;
                }
            }
            Plane::from_vec(w as u32, h as u32, d).unwrap()
        })
        .collect();
    let cfg = WatershedSiftConfig::robust().with_person_size(12.0, 30.0);
    assert!(cfg.fg_pairs);
    let out = run(cfg, &frames);
    let ids: std::collections::BTreeSet<_> = out.iter().flatten().map(|r| r.id).collect();
    let boxes: usize = out.iter().map(Vec::len).sum();
    assert_eq!(ids.len(), 1, "one walker, one id: {ids:?}");
    assert!(boxes >= 18, "the walker is followed: {boxes} boxes");
}

/// `robust` (`fg_pairs_group_companion`): the side-by-side pair of the tests above (a target
/// and its companion) walks right while a third walker walks left at the same height and
/// passes behind it. The host and the third walker's target form a two-member occlusion
/// group; the group's pair test sees the pair's two people. Without the rule the two members
/// take those two parts and the companion ends, so the pair's walkers change identities; with
/// it the host and its companion take the parts, the third is hidden, and each walker of the
/// pair keeps the id it had before the crossing.
#[test]
fn robust_pair_passed_behind_keeps_its_ids() {
    let [a, b] = side_by_side();
    // the third walker first in the list: drawn first, so behind the pair
    let c = Walker {
        start: [236.0, 60.0],
        vel: [-2.0, 0.0],
        t0: 0,
        mean: 75.0,
    };
    let walkers = [c, a, b];
    let frames = video(&walkers, 110, 21);
    let at = |i: usize, t: u64| centre(&walkers[i + 1], t).unwrap();
    let ids = |group: bool, range: std::ops::Range<usize>| {
        let mut cfg = config(true);
        cfg.sigma = 10.0;
        cfg.fg_pairs_group_companion = group;
        let out = run(cfg, &frames);
        pair_coverage(&out, at, range)
    };
    let (before, after) = (ids(false, 30..44), ids(false, 62..100));
    eprintln!("without: before {before:?}, after {after:?}");
    assert_each_walker_boxed_under_its_own_id(&before, 12);
    assert!(
        before[0].1 != after[0].1 || before[1].1 != after[1].1,
        "the test needs the failure: without the rule an identity changes ({before:?}, {after:?})"
    );
    let (before, after) = (ids(true, 30..44), ids(true, 62..100));
    eprintln!("with: before {before:?}, after {after:?}");
    assert_each_walker_boxed_under_its_own_id(&before, 12);
    assert_each_walker_boxed_under_its_own_id(&after, 34);
    assert_eq!(
        (&before[0].1, &before[1].1),
        (&after[0].1, &after[1].1),
        "each walker of the pair keeps its id"
    );
    // the third walker is boxed again once it has come out on the other side
    let mut cfg = config(true);
    cfg.sigma = 10.0;
    let out = run(cfg, &frames);
    let third = |range| {
        pair_coverage(
            &out,
            |i, t| centre(&walkers[usize::from(i != 0)], t).unwrap(),
            range,
        )[0]
        .clone()
    };
    let (seen, again) = (third(20..40), third(80..100));
    eprintln!("third walker: frames 20-39 {seen:?}, 80-99 {again:?}");
    assert!(again.0 >= 16 && again.1 == seen.1, "{seen:?} {again:?}");
}

/// A walker passing in front of a person who stands, at the same height: the structure of
/// PETS09-S2L1's sign at frames 104-113 (docs/video-tracker.md, "Missing"). Person A walks in
/// and stands from frame 35; walker B enters at frame 40 and passes in front of A around frame
/// 95. σ = 8 blurs the two into one basin during the pass, as σ = 8.53 does for PETS's people.
/// Wanted: A is boxed under the id it had before the pass once B has passed, and B keeps its id.
/// B's target takes A's region at frame 98; with `reacquire` A's target, now without regions, waits
/// and takes the region back once B has moved off it (A is boxed under its id again in every frame
/// from 106; B keeps its id throughout). Without it (stop 38) A's target ends at 98, A is boxed
/// again under a new id for some frames and then not at all (a person standing without a target
/// that moved is absorbed into the median background): 0 of 54. Still wrong with it: in frames
/// 96-97 the two ids swap (the occlusion group's pair split compares the parts with last boxes that
/// both lie at A, docs/video-tracker.md).
#[test]
fn robust_walker_passing_a_standing_person_keeps_both_ids() {
    let a = Walker {
        start: [40.0, 60.0],
        vel: [2.0, 0.0],
        t0: 0,
        mean: 70.0,
    };
    let b = Walker {
        start: [236.0, 60.0],
        vel: [-2.5, 0.0],
        t0: 40,
        mean: 60.0,
    };
    let walkers = [a, b];
    let pos = |i: usize, t: u64| -> Option<[f64; 2]> {
        if i == 0 {
            Some([(40.0 + 2.0 * t as f64).min(110.0), 60.0])
        } else {
            centre(&walkers[1], t).filter(|c| c[0] > -20.0)
        }
    };
    let frames = video_with(&walkers, 170, 5, pos);
    let kept = |reacquire: bool| {
        let mut cfg = config(true);
        cfg.sigma = 8.0;
        cfg.reacquire = reacquire;
        let out = run(cfg, &frames);
        let id_of = |i: usize, t: u64| {
            pos(i, t)
                .and_then(|c| near(&out[t as usize], c, 8.0))
                .map(|r| r.id)
        };
        let (a_id, b_id) = (id_of(0, 70), id_of(1, 70));
        assert!(
            a_id.is_some() && b_id.is_some() && a_id != b_id,
            "before the pass"
        );
        let a_after = (106..160).filter(|&t| id_of(0, t) == a_id).count();
        let b_kept = (100..130).filter(|&t| id_of(1, t) == b_id).count();
        (a_after, b_kept)
    };
    let (on, off) = (kept(true), kept(false));
    eprintln!(
        "A under its id in frames 106-159 / B in 100-129: {on:?} of (54, 30) with \
         `reacquire`, {off:?} without"
    );
    assert!(on.0 >= 52 && on.1 >= 27, "{on:?} of (54, 30)");
    assert!(off.0 < on.0, "without `reacquire`: {off:?}");
}
