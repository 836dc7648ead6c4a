//! SIFT invariants (spec 004 §7.1 S1–S3) and bad input, on small procedural images.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use quarry_core::rng::{RngCore, seeded};
use quarry_core::{FeatureDetector, FeatureExtractor, Keypoint, Plane};
use quarry_vision::VisionError;
use quarry_vision::matching::distance;
use quarry_vision::sift::{MAX_PIXELS, MIN_SIDE, Sift, SiftParams};

/// Dead-leaves image: `n` random discs of uniform grey (radii 2..`rmax`), then a light blur
/// by averaging each pixel with its 4 neighbours.
fn dead_leaves(w: u32, h: u32, n: usize, rmax: u32, seed: u64) -> Plane<u8> {
    let mut rng = seeded(seed);
    let mut img = Plane::new(w, h, 128u8);
    for _ in 0..n {
        let cx = (rng.next_u32() % w) as i64;
        let cy = (rng.next_u32() % h) as i64;
        let r = 2 + (rng.next_u32() % (rmax - 1)) as i64;
        let v = (rng.next_u32() % 256) as u8;
        for y in (cy - r).max(0)..(cy + r + 1).min(h as i64) {
            for x in (cx - r).max(0)..(cx + r + 1).min(w as i64) {
                if (x - cx).pow(2) + (y - cy).pow(2) <= r * r {
                    img.set(x as u32, y as u32, v);
                }
            }
        }
    }
    let src = img.clone();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let s: u32 = [(0, 0), (1, 0), (0, 1), (2, 1), (1, 2)]
                .iter()
                .map(|&(dx, dy)| u32::from(*src.get(x + dx - 1, y + dy - 1).unwrap()))
                .sum::<u32>()
                + 3 * u32::from(*src.get(x, y).unwrap());
            img.set(x, y, (s / 8) as u8);
        }
    }
    img
}

/// Rotates 90° clockwise as displayed: new (x', y') = old (x, y) with x' = H − 1 − y, y' = x.
fn rot90(img: &Plane<u8>) -> Plane<u8> {
    let (w, h) = img.dimensions();
    Plane::from_fn(h, w, |xn, yn| *img.get(yn, h - 1 - xn).unwrap())
}

fn angle_diff(a: f32, b: f32) -> f32 {
    ((a - b + 540.0).rem_euclid(360.0) - 180.0).abs()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(6))]

    /// S1: unit norm before quantisation; |‖q‖ − 512| ≤ 6 when no byte saturates.
    #[test]
    fn descriptors_have_unit_norm(seed in 0u64..1000, n in 20usize..120) {
        let img = dead_leaves(72, 64, n, 12, seed);
        let sift = Sift::default();
        let ss = sift.scale_space(&img.map(|&v| f32::from(v))).unwrap();
        let kps = sift.detect_in(&ss);
        let fd = sift.describe_in(&ss, &kps).unwrap();
        prop_assert!(!kps.is_empty());
        for v in &fd {
            let n2: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            prop_assert!((n2 - 1.0).abs() < 1e-5, "norm {}", n2);
            prop_assert!(v.iter().all(|&x| (0.0..=1.0).contains(&x)));
            let q = quarry_vision::sift::quantize(v);
            if q.iter().all(|&b| b < 255) {
                let qn = q.iter().map(|&b| f64::from(b).powi(2)).sum::<f64>().sqrt();
                prop_assert!((qn - 512.0).abs() <= 6.0, "quantised norm {}", qn);
            }
        }
    }

    /// Keypoints and descriptors are deterministic and identical with 1 and 2 threads.
    #[test]
    fn deterministic_and_thread_independent(seed in 0u64..1000) {
        let img = dead_leaves(96, 80, 80, 14, seed);
        let sift = Sift::default();
        let run = |t: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
            pool.install(|| sift.extract(&img).unwrap())
        };
        let a = run(1);
        let b = run(2);
        let c = run(2);
        prop_assert!(!a.0.is_empty());
        prop_assert_eq!(&a, &b);
        prop_assert_eq!(&b, &c);
    }
}

/// S3: exact 90° rotations of dead-leaves images.
#[test]
fn rotation_by_90_degrees() {
    let sift = Sift::default();
    let mut matched_total = 0usize;
    let mut total = 0usize;
    let mut dists = Vec::new();
    for seed in [1u64, 2] {
        let img = dead_leaves(160, 128, 300, 30, seed);
        let rot = rot90(&img);
        let (k1, d1) = sift.extract(&img).unwrap();
        let (k2, d2) = sift.extract(&rot).unwrap();
        let h = img.height as f32;
        for (a, da) in k1.iter().zip(&d1) {
            // OpenCV keypoint coordinates sit 0.25 px off pixel centres (up-sampled octave):
            // true = kp − 0.25, so x' = H − 1 − (y − 0.25) + 0.25, y' = x.
            let (xe, ye) = (h - 0.5 - a.y, a.x);
            let ae = (a.angle_deg + 90.0).rem_euclid(360.0);
            let tol = (0.5 * a.sigma).max(1.0);
            total += 1;
            let best = k2
                .iter()
                .enumerate()
                .filter(|(_, b)| {
                    (b.x - xe).hypot(b.y - ye) <= tol
                        && (b.sigma / a.sigma).log2().abs() <= 0.1
                        && angle_diff(b.angle_deg, ae) <= 5.0
                })
                .min_by(|x, y| {
                    let dx = (x.1.x - xe).hypot(x.1.y - ye);
                    let dy = (y.1.x - xe).hypot(y.1.y - ye);
                    dx.total_cmp(&dy)
                });
            if let Some((j, _)) = best {
                matched_total += 1;
                dists.push(distance(da, &d2[j]));
            }
        }
    }
    let frac = matched_total as f64 / total as f64;
    dists.sort_by(f32::total_cmp);
    let med = dists[dists.len() / 2];
    eprintln!("rot90: {matched_total}/{total} = {frac:.3} matched, median descriptor L2 {med:.1}");
    assert!(total > 100, "too few keypoints: {total}");
    assert!(
        frac >= 0.85,
        "only {frac} of keypoints have a rotated counterpart"
    );
    assert!(med <= 40.0, "median descriptor distance {med}");
}

/// S2: a constant image has no keypoints; adding a constant barely changes anything.
#[test]
fn constant_and_offset() {
    let sift = Sift::default();
    assert!(sift.detect(&Plane::new(64, 48, 77u8)).unwrap().is_empty());
    let img = dead_leaves(120, 100, 200, 20, 7).map(|&v| v / 2 + 20); // 20..147
    let brighter = img.map(|&v| v + 40);
    let (k1, d1) = sift.detect_and_compute(&img).unwrap();
    let (k2, d2) = sift.detect_and_compute(&brighter).unwrap();
    let dn = (k1.len() as f64 - k2.len() as f64).abs() / k1.len() as f64;
    assert!(dn <= 0.01, "{} vs {} keypoints", k1.len(), k2.len());
    let (mut pos, mut same) = (0, 0);
    for (a, da) in k1.iter().zip(&d1) {
        if let Some(j) = k2.iter().position(|b: &Keypoint| {
            (b.x - a.x).abs() < 1e-3
                && (b.y - a.y).abs() < 1e-3
                && angle_diff(b.angle_deg, a.angle_deg) < 0.1
        }) {
            pos += 1;
            if distance(da, &d2[j]) <= 4.0 {
                same += 1;
            }
        }
    }
    let n = k1.len() as f64;
    eprintln!(
        "offset: {} keypoints, {pos} at the same place, {same} with descriptor L2 <= 4",
        k1.len()
    );
    assert!(f64::from(pos) / n >= 0.99, "{pos} of {n} at the same place");
    assert!(
        f64::from(same) / n >= 0.99,
        "{same} of {n} with close descriptors"
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let sift = Sift::default();
    assert!(matches!(
        sift.extract(&Plane::new(0, 0, 0u8)),
        Err(VisionError::EmptyImage { .. })
    ));
    assert!(matches!(
        sift.extract(&Plane::new(MIN_SIDE - 1, 100, 0u8)),
        Err(VisionError::EmptyImage { .. })
    ));
    // The core trait reports it too.
    assert!(sift.detect(&Plane::new(3, 3, 0u8)).is_err());
    // Smallest accepted size works.
    assert!(sift.extract(&Plane::new(MIN_SIDE, MIN_SIDE, 9u8)).is_ok());
    let side = (MAX_PIXELS as f64).sqrt() as u32 + 1;
    assert!(matches!(
        sift.extract(&Plane::new(side, side, 0u8)),
        Err(VisionError::TooLarge { .. })
    ));
    let mut f = Plane::new(40, 40, 10.0f32);
    f.set(3, 4, f32::NAN);
    assert!(matches!(
        sift.extract_f32(&f),
        Err(VisionError::NonFinite(_))
    ));
    let bad = Plane {
        width: 40,
        height: 40,
        data: vec![0u8; 10],
    };
    assert!(sift.extract(&bad).is_err());
    // Keypoints that do not belong to the scale space.
    let img = dead_leaves(64, 64, 40, 10, 3);
    let kp = Keypoint {
        x: 10.0,
        y: 10.0,
        sigma: 2.0,
        angle_deg: 0.0,
        response: 0.1,
        octave: 12,
        layer: 1,
        layer_offset: 0.0,
    };
    assert!(sift.describe(&img, &[kp]).is_err());
    assert!(
        sift.describe(
            &img,
            &[Keypoint {
                x: f32::NAN,
                octave: 0,
                ..kp
            }]
        )
        .is_err()
    );
    // Parameters.
    assert!(
        Sift::new(SiftParams {
            contrast_threshold: -1.0,
            ..SiftParams::default()
        })
        .is_err()
    );
}

/// Recomputing descriptors for detected keypoints gives the detect-and-compute result, and
/// `max_features` keeps the strongest.
#[test]
fn compute_matches_detect_and_compute() {
    use quarry_core::DescriptorExtractor;
    let img = dead_leaves(96, 96, 120, 16, 11);
    let sift = Sift::default();
    let (k, d) = sift.detect_and_compute(&img).unwrap();
    assert_eq!(sift.compute(&img, &k).unwrap(), d);
    let best = Sift::new(SiftParams {
        max_features: 10,
        ..SiftParams::default()
    })
    .unwrap();
    let kb = best.detect(&img).unwrap();
    assert!(kb.len() >= 10 && kb.len() < k.len());
    let mut r: Vec<f32> = k.iter().map(|k| k.response).collect();
    r.sort_by(|a, b| b.total_cmp(a));
    assert!(kb.iter().all(|x| x.response >= r[9]));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// `detect_in_where` is `detect_in` filtered by the predicate, in the same order, for a
    /// random box (a padded crop's area), with and without up-sampling, and with a feature cap.
    #[test]
    fn detect_in_where_is_detect_in_filtered(
        seed in 0u64..1000,
        n in 20usize..150,
        bx in 0.0f32..60.0,
        by in 0.0f32..60.0,
        bw in 0.0f32..70.0,
        bh in 0.0f32..70.0,
        upsample in proptest::bool::ANY,
        cap in 0usize..3,
    ) {
        let img = dead_leaves(80, 72, n, 12, seed);
        let sift = Sift::new(SiftParams {
            upsample,
            max_features: [0, 5, 40][cap],
            ..SiftParams::default()
        })
        .unwrap();
        let f = Plane::from_fn(80, 72, |x, y| f32::from(*img.get(x, y).unwrap()));
        let ss = sift.scale_space(&f).unwrap();
        let keep = |x: f32, y: f32| x >= bx && x < bx + bw && y >= by && y < by + bh;
        let mut want = sift.detect_in(&ss);
        want.retain(|k| keep(k.x, k.y));
        let got = sift.detect_in_where(&ss, keep);
        let bits = |k: &Keypoint| {
            (k.x.to_bits(), k.y.to_bits(), k.sigma.to_bits(), k.angle_deg.to_bits(),
             k.response.to_bits(), k.octave, k.layer, k.layer_offset.to_bits())
        };
        prop_assert_eq!(
            got.iter().map(bits).collect::<Vec<_>>(),
            want.iter().map(bits).collect::<Vec<_>>()
        );
    }
}
