//! SIFT on random small images: never panics; keypoints are finite, inside the image, and have
//! one descriptor each; matching an image's descriptors against themselves finds each one.
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
    let Ok((kps, desc)) = Sift::default().extract(&img) else {
        return;
    };
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
