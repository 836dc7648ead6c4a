//! Drives the patch multi-cue descriptor entry points (RgbdFeatures::new, PatchMultiCueModel::new,
//! describe_box, score, learn) with arbitrary small frames, depths (NaN, inf, negative, zero),
//! boxes and parameters: errors are fine, panics are not; scores must be well-formed.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{BBox, Plane};
use quarry_vision::multicue::{PatchModelConfig, PatchMultiCueModel, RgbdFeatures};

struct Bytes<'a>(&'a [u8]);
impl Bytes<'_> {
    fn u8(&mut self) -> u8 {
        match self.0.split_first() {
            Some((b, rest)) => {
                self.0 = rest;
                *b
            }
            None => 0,
        }
    }
    fn depth(&mut self) -> f32 {
        match self.u8() % 16 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => -1.0,
            3 => 0.0,
            k => f32::from(k) * 0.5,
        }
    }
    fn coord(&mut self) -> f64 {
        match self.u8() % 32 {
            0 => f64::NAN,
            1 => 1e30,
            k => f64::from(k) * 3.0 - 20.0,
        }
    }
}

fuzz_target!(|data: &[u8]| {
    let mut b = Bytes(data);
    let w = u32::from(b.u8() % 48);
    let h = u32::from(b.u8() % 48);
    let short = b.u8() % 16 == 0;
    let n = (w * h) as usize;
    let rgb: Vec<u8> = (0..3 * n - usize::from(short && n > 0))
        .map(|_| b.u8())
        .collect();
    let Ok(depth) = Plane::from_vec(w, h, (0..n).map(|_| b.depth()).collect()) else {
        return;
    };
    let cfg = PatchModelConfig {
        n: u32::from(b.u8() % 6),
        depth_kernel: b.u8() % 4 != 0,
        spatial_kernel: b.u8() % 4 == 0,
        stride: u32::from(b.u8() % 3),
        ..PatchModelConfig::default()
    };
    let roi = (b.u8() % 4 == 0).then(|| {
        (
            u32::from(b.u8()),
            u32::from(b.u8()),
            u32::from(b.u8()),
            u32::from(b.u8()),
        )
    });
    let Ok(f) = RgbdFeatures::new(w, h, &rgb, &depth, roi, &cfg) else {
        return;
    };
    let mut bx = || BBox {
        cx: b.coord(),
        cy: b.coord(),
        w: b.coord(),
        h: b.coord(),
    };
    let (init, tmpl, cand) = (bx(), bx(), bx());
    let Ok(mut m) = PatchMultiCueModel::new(cfg, &f, &init, &tmpl) else {
        return;
    };
    let _ = m.set_depth_gate(Some((f32::from(b.u8()) / 10.0, f32::from(b.u8()) / 50.0)));
    if let Ok(d) = m.describe_box(&f, &cand) {
        let s = m.score_descriptor(&d);
        assert!(s.s >= 0.0 && s.s.is_finite());
        assert!((0.0..=1.0).contains(&s.m));
        m.learn_counted(&d, &s);
    }
});
