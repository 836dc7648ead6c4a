//! SIFT on random small images: never panics; keypoints are finite, inside the image, and have
//! one descriptor each; matching an image's descriptors against themselves finds each one;
//! `detect_in_where` with a box gives exactly the keypoints of `detect_in` inside it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::Plane;
use quarry_vision::matching::{BruteForceL2, DescriptorMatcher};
use quarry_vision::sift::Sift;

fuzz_target!(|data: &[u8]| {
    if data.len() < 2 {
        return;
    }
    let w = u32::from(data[0] % 64) + 1;
    let h = u32::from(data[1] % 64) + 1;
    let px = &data[2..];
    let img = Plane::from_fn(w, h, |x, y| {
        let i = (y * w + x) as usize;
        if px.is_empty() { 0 } else { px[i % px.len()] }
    });
    let sift = Sift::default();
    let Ok((kps, desc)) = sift.extract(&img) else {
        return;
    };
    // a box from the first two bytes (quarters of the image, possibly empty)
    let (bx, by) = (f32::from(data[0] & 3) * w as f32 / 4.0, f32::from(data[1] & 3) * h as f32 / 4.0);
    let (bw, bh) = (f32::from(data[0] >> 6) * w as f32 / 3.0, f32::from(data[1] >> 6) * h as f32 / 3.0);
    let keep = |x: f32, y: f32| x >= bx && x < bx + bw && y >= by && y < by + bh;
    let f = Plane::from_fn(w, h, |x, y| f32::from(*img.get(x, y).unwrap_or(&0)));
    let ss = sift.scale_space(&f).expect("the image extract accepted");
    let got = sift.detect_in_where(&ss, keep);
    let want: Vec<_> = kps.iter().filter(|k| keep(k.x, k.y)).collect();
    assert_eq!(got.len(), want.len());
    for (a, b) in got.iter().zip(want) {
        assert!(a.x.to_bits() == b.x.to_bits() && a.y.to_bits() == b.y.to_bits());
        assert!(a.sigma.to_bits() == b.sigma.to_bits() && a.angle_deg.to_bits() == b.angle_deg.to_bits());
        assert!(a.octave == b.octave && a.layer == b.layer);
    }
    assert_eq!(kps.len(), desc.len());
    for k in &kps {
        assert!(k.x.is_finite() && k.y.is_finite() && k.sigma > 0.0);
        assert!(k.x >= -1.0 && k.y >= -1.0 && k.x <= w as f32 && k.y <= h as f32);
        assert!((0.0..360.0).contains(&k.angle_deg));
    }
    let nn = BruteForceL2.nearest2(&desc, &desc);
    for m in &nn {
        assert_eq!(m.map(|(_, d1, _)| d1), Some(0.0));
    }
});
