//! Property tests of the segmentation half (spec 004 §7.1 V1, V2, V5, V6, V7).
#![allow(clippy::unwrap_used, clippy::expect_used)]

use proptest::prelude::*;
use quarry_core::{Plane, Segmentation, Segmenter};
use quarry_vision::{
    Connectivity, RampBlurWatershed, RegionAdjacency, RegionMapping, WatershedOptions,
    add_regular_ramp, flood, gaussian_blur_f64, regional_minima, watershed,
};
use std::collections::VecDeque;

/// Grey images with sides in `2..=max_side` and pixel values in `0..levels`.
fn image(max_side: u32, levels: u8) -> impl Strategy<Value = Plane<u8>> {
    quarry_testkit::strategies::plane(2..=max_side, 0..levels)
}

/// Brute-force regional-minimum mask: flood each pixel's plateau and look for a lower neighbour.
fn brute_minima_mask<T: Copy + PartialOrd>(p: &Plane<T>, conn: Connectivity) -> Vec<bool> {
    let (w, h) = (p.width as i64, p.height as i64);
    let mut out = vec![false; p.len()];
    for s in 0..p.len() {
        let v = p.data[s];
        let mut seen = vec![false; p.len()];
        let mut q = VecDeque::from([s]);
        seen[s] = true;
        let mut is_min = true;
        while let Some(c) = q.pop_front() {
            let (cx, cy) = ((c as i64) % w, (c as i64) / w);
            for &(dx, dy) in conn.offsets() {
                let (x, y) = (cx + i64::from(dx), cy + i64::from(dy));
                if x < 0 || y < 0 || x >= w || y >= h {
                    continue;
                }
                let n = (y * w + x) as usize;
                if p.data[n] < v {
                    is_min = false;
                } else if p.data[n] == v && !seen[n] {
                    seen[n] = true;
                    q.push_back(n);
                }
            }
        }
        out[s] = is_min;
    }
    out
}

/// Every region is 8-connected, contains exactly its own seed, and labels are in 1..=K.
fn check_partition(seg: &Segmentation, seed_labels: &Plane<u32>) {
    let k = seg.n_regions() as u32;
    assert!(k >= 1);
    assert!(seg.labels.data.iter().all(|&l| (1..=k).contains(&l)));
    // seeds: each seed pixel carries its own label; each minimum's representative too
    for (i, &s) in seed_labels.data.iter().enumerate() {
        if s != 0 {
            assert_eq!(seg.labels.data[i], s);
        }
    }
    let mut seeds_per_region = vec![0usize; k as usize];
    for m in &seg.minima {
        let (x, y) = m.representative;
        assert_eq!(*seg.labels.get(x, y).unwrap(), m.id);
        assert_eq!(*seed_labels.get(x, y).unwrap(), m.id);
        seeds_per_region[m.id as usize - 1] += 1;
    }
    assert!(seeds_per_region.iter().all(|&c| c == 1));
    // connectivity: BFS from the representative covers the whole region
    let (w, h) = (seg.labels.width as i64, seg.labels.height as i64);
    let mut area = vec![0usize; k as usize];
    for &l in &seg.labels.data {
        area[l as usize - 1] += 1;
    }
    for m in &seg.minima {
        let start = (i64::from(m.representative.1) * w + i64::from(m.representative.0)) as usize;
        let mut seen = vec![false; seg.labels.len()];
        seen[start] = true;
        let mut q = VecDeque::from([start]);
        let mut n = 0;
        while let Some(c) = q.pop_front() {
            n += 1;
            let (cx, cy) = ((c as i64) % w, (c as i64) / w);
            for &(dx, dy) in Connectivity::Eight.offsets() {
                let (x, y) = (cx + i64::from(dx), cy + i64::from(dy));
                if x < 0 || y < 0 || x >= w || y >= h {
                    continue;
                }
                let j = (y * w + x) as usize;
                if !seen[j] && seg.labels.data[j] == m.id {
                    seen[j] = true;
                    q.push_back(j);
                }
            }
        }
        assert_eq!(n, area[m.id as usize - 1], "region {} not connected", m.id);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// V5: minima agree with brute force on small images with many plateaus.
    #[test]
    fn minima_match_brute_force(img in image(12, 4), eight in any::<bool>()) {
        let conn = if eight { Connectivity::Eight } else { Connectivity::Four };
        let m = regional_minima(&img, conn).unwrap();
        let mask = brute_minima_mask(&img, conn);
        for (i, &b) in mask.iter().enumerate() {
            prop_assert_eq!(m.labels.data[i] != 0, b, "pixel {}", i);
        }
        // numbering in raster order of first pixel, flat, sizes consistent
        let mut first = vec![usize::MAX; m.len()];
        let mut size = vec![0usize; m.len()];
        for (i, &l) in m.labels.data.iter().enumerate() {
            if l != 0 {
                let k = l as usize - 1;
                first[k] = first[k].min(i);
                size[k] += 1;
                prop_assert_eq!(f64::from(img.data[i]), m.minima[k].value);
            }
        }
        prop_assert!(first.windows(2).all(|w| w[0] < w[1]));
        for (k, mi) in m.minima.iter().enumerate() {
            prop_assert_eq!(mi.size, size[k]);
            prop_assert_eq!(mi.id as usize, k + 1);
        }
    }

    /// V6: watershed of a raw image with plateaus: complete partition, one seed per region,
    /// connected regions, deterministic.
    #[test]
    fn watershed_partition(img in image(20, 6)) {
        let seeds = regional_minima(&img, Connectivity::Eight).unwrap();
        let seg = flood(&img, &seeds, WatershedOptions::default()).unwrap();
        check_partition(&seg, &seeds.labels);
        let again = flood(&img, &seeds, WatershedOptions::default()).unwrap();
        prop_assert_eq!(&seg, &again);
        // adjacency is symmetric and irreflexive
        let adj = RegionAdjacency::from_segmentation(&seg).unwrap();
        for k in 1..=seg.n_regions() as u32 {
            for &n in adj.of(k) {
                prop_assert!(n != k);
                prop_assert!(adj.are_adjacent(n, k));
            }
        }
    }

    /// The whole spec-004 step: every pixel labelled, one seed per region, connected regions.
    #[test]
    fn segmenter_partition(img in image(24, 255), sigma in 0.3f64..4.0) {
        let seg = RampBlurWatershed::new(sigma).segment(&img).unwrap();
        let relief = add_regular_ramp(&img, 256).unwrap();
        let relief = gaussian_blur_f64(&relief, sigma).unwrap();
        let seeds = regional_minima(&relief, Connectivity::Eight).unwrap();
        check_partition(&seg, &seeds.labels);
    }

    /// V1: the ramp preserves grey order and stays in range.
    #[test]
    fn ramp_preserves_order(img in image(24, 255)) {
        let r = add_regular_ramp(&img, 256).unwrap();
        prop_assert!(r.data.iter().all(|&v| (0.0..253.0157).contains(&v)));
        for i in 0..img.len() {
            for j in 0..img.len() {
                if img.data[i] < img.data[j] {
                    prop_assert!(r.data[i] < r.data[j]);
                }
            }
        }
    }

    /// V2a: on images with no two equal pixels the ramp does not move any minimum.
    #[test]
    fn ramp_keeps_minima_of_non_flat_images(perm in Just((0u8..=255).collect::<Vec<u8>>()).prop_shuffle()) {
        let img = Plane::from_vec(16, 16, perm).unwrap();
        let before = regional_minima(&img, Connectivity::Eight).unwrap();
        let after = regional_minima(&add_regular_ramp(&img, 256).unwrap(), Connectivity::Eight).unwrap();
        prop_assert_eq!(before.labels, after.labels);
    }

    /// V2b: with W ≠ H the ramp removes every plateau (all minima are single pixels), and each
    /// minimal plateau of the input keeps a minimum at its pixel of least x/W + y/H.
    #[test]
    fn ramp_removes_plateaus(img in image(16, 3)) {
        prop_assume!(img.width != img.height);
        let ramped = add_regular_ramp(&img, 256).unwrap();
        let after = regional_minima(&ramped, Connectivity::Eight).unwrap();
        prop_assert!(after.minima.iter().all(|m| m.size == 1));
        let before = regional_minima(&img, Connectivity::Eight).unwrap();
        let (w, h) = (f64::from(img.width), f64::from(img.height));
        for m in &before.minima {
            let pix: Vec<usize> = (0..img.len()).filter(|&i| before.labels.data[i] == m.id).collect();
            let inside: Vec<usize> = pix.iter().copied().filter(|&i| after.labels.data[i] != 0).collect();
            // a non-convex plateau may keep several local minima of the tilted plane; the
            // global one (least x/W + y/H) is always among them
            let g = |i: usize| (i % img.width as usize) as f64 / w + (i / img.width as usize) as f64 / h;
            let best = pix.iter().copied().min_by(|&a, &b| g(a).total_cmp(&g(b))).unwrap();
            prop_assert!(inside.contains(&best));
        }
    }

    /// V2c: a constant rectangle that is a minimum of I yields exactly one minimum of I', at
    /// the rectangle's top-left pixel.
    #[test]
    fn rectangle_plateau_keeps_one_minimum_top_left(
        bg in image(20, 200), x0 in 0u32..20, y0 in 0u32..20, rw in 1u32..8, rh in 1u32..8,
    ) {
        let (w, h) = bg.dimensions();
        let (x0, y0) = (x0 % w, y0 % h);
        let (x1, y1) = ((x0 + rw).min(w), (y0 + rh).min(h));
        let img = Plane::from_fn(w, h, |x, y| {
            if (x0..x1).contains(&x) && (y0..y1).contains(&y) { 3 } else { 10 + bg.get(x, y).unwrap() }
        });
        let after = regional_minima(&add_regular_ramp(&img, 256).unwrap(), Connectivity::Eight).unwrap();
        let inside: Vec<_> = after.minima.iter().filter(|m| {
            let (x, y) = m.representative;
            (x0..x1).contains(&x) && (y0..y1).contains(&y)
        }).collect();
        prop_assert_eq!(inside.len(), 1);
        prop_assert_eq!(inside[0].representative, (x0, y0));
    }

    /// Region mapping is consistent in both directions.
    #[test]
    fn mapping_is_consistent(a in image(16, 255), seed in any::<u64>(), sigma in 0.5f64..2.0) {
        // second frame: same size, perturbed
        let mut s = seed | 1;
        let b = a.map(|&v| {
            s ^= s << 13; s ^= s >> 7; s ^= s << 17;
            v.saturating_add((s % 40) as u8)
        });
        let seg = RampBlurWatershed::new(sigma);
        let (sa, sb) = (seg.segment(&a).unwrap(), seg.segment(&b).unwrap());
        let ab = RegionMapping::new(&sa, &sb).unwrap();
        let ba = RegionMapping::new(&sb, &sa).unwrap();
        prop_assert_eq!(&ab.forward, &ba.backward);
        prop_assert_eq!(&ab.backward, &ba.forward);
        let mut swapped: Vec<(u32, u32)> = ba.bidirectional.iter().map(|&(i, j)| (j, i)).collect();
        swapped.sort_unstable();
        prop_assert_eq!(&ab.bidirectional, &swapped);
        prop_assert_eq!(&ab.merges, &ba.splits);
        prop_assert_eq!(&ab.splits, &ba.merges);
        for (i, &j) in ab.forward.iter().enumerate() {
            prop_assert_eq!(*sb.labels.get(sa.minima[i].representative.0, sa.minima[i].representative.1).unwrap(), j);
            prop_assert!(!ab.fragments(i as u32 + 1).contains(&j));
        }
        // a frame against itself: all bidirectional, no merge, no split
        let aa = RegionMapping::new(&sa, &sa).unwrap();
        prop_assert_eq!(aa.bidirectional.len(), sa.n_regions());
        prop_assert!(aa.merges.is_empty() && aa.splits.is_empty());
    }
}

/// Labels do not depend on the number of threads (the blur is split over rows with rayon).
#[test]
fn labels_independent_of_thread_count() {
    let img = Plane::from_fn(160, 97, |x, y| {
        ((f64::from(x) * 0.21).sin() * 60.0 + (f64::from(y) * 0.13).cos() * 50.0 + 128.0) as u8
    });
    let seg = RampBlurWatershed::new(3.0);
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let three = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let a = one.install(|| seg.run(&img).unwrap());
    let b = three.install(|| seg.run(&img).unwrap());
    assert_eq!(a.relief.data, b.relief.data);
    assert_eq!(a.segmentation, b.segmentation);
    assert!(a.segmentation.n_regions() > 5);
}

/// V7: a 2-px shift of a textured image keeps at least 90 % of the minima bidirectional.
#[test]
fn shifted_texture_maps_bidirectionally() {
    let mut s = 0x9e37_79b9_7f4a_7c15_u64;
    let noise = Plane::from_fn(140, 100, |_, _| {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s % 256) as f64
    });
    let tex = gaussian_blur_f64(&noise, 3.0).unwrap();
    let lo = tex.data.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = tex.data.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let frame = |dx: u32| {
        Plane::from_fn(120, 90, |x, y| {
            ((tex.get(x + 10 - dx, y + 5).unwrap() - lo) / (hi - lo) * 255.0).round() as u8
        })
    };
    let seg = RampBlurWatershed::new(2.0);
    let (a, b) = (
        seg.segment(&frame(0)).unwrap(),
        seg.segment(&frame(2)).unwrap(),
    );
    let m = RegionMapping::new(&a, &b).unwrap();
    let frac = m.bidirectional.len() as f64 / a.n_regions() as f64;
    assert!(a.n_regions() > 20, "{}", a.n_regions());
    assert!(frac >= 0.9, "bidirectional fraction {frac}");
}

/// V6: two Gaussian dips give a boundary within 1 px of the ridge, through the whole pipeline
/// (watershed on an f64 relief).
#[test]
fn two_dips_boundary_at_ridge() {
    let p = Plane::from_fn(61, 31, |x, y| {
        let (xf, yf) = (f64::from(x), f64::from(y));
        let g = |cx: f64| (-((xf - cx).powi(2) + (yf - 15.0).powi(2)) / 60.0).exp();
        100.0 - 50.0 * (g(20.0) + g(41.0))
    });
    let s = watershed(&p, WatershedOptions::default()).unwrap();
    assert_eq!(s.n_regions(), 2, "{:?}", s.minima);
    for y in 0..31 {
        for x in 0..61u32 {
            let l = *s.labels.get(x, y).unwrap();
            if x + 1 < 30 {
                assert_eq!(l, 1, "({x},{y})");
            } else if x > 31 {
                assert_eq!(l, 2, "({x},{y})");
            }
        }
    }
}
