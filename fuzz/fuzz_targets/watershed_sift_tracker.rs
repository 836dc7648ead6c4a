//! Drives the watershed + SIFT tracker (spec 004) with arbitrary small frame sequences: sizes
//! from 1x1 to 48x48 (changing mid-sequence when the input says so), arbitrary pixels, both
//! profiles and small person sizes. Errors are fine, panics are not; every reported box is
//! finite.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::{MultiTargetTracker, Plane, Stamp};
use quarry_trackers::watershed_sift::{WatershedSiftConfig, WatershedSiftTracker};

fuzz_target!(|data: &[u8]| {
    let Some((&head, rest)) = data.split_first() else {
        return;
    };
    let base = if head & 1 == 0 {
        WatershedSiftConfig::paper()
    } else {
        WatershedSiftConfig::robust()
    };
    let pw = f64::from(4 + (head >> 1) % 16);
    let cfg = base.with_person_size(pw, 2.5 * pw);
    let Ok(mut tr) = WatershedSiftTracker::new(cfg) else {
        return;
    };
    let mut rest = rest;
    let mut k = 0u64;
    while rest.len() >= 2 && k < 24 {
        let (w, h) = (1 + u32::from(rest[0] % 48), 1 + u32::from(rest[1] % 48));
        rest = &rest[2..];
        let n = (w * h) as usize;
        let take = n.min(rest.len());
        let mut px: Vec<u8> = rest[..take].to_vec();
        rest = &rest[take..];
        // repeat the bytes we have so small inputs still give whole frames
        while px.len() < n {
            px.push(px.get(px.len() % take.max(1)).copied().unwrap_or(128));
        }
        let frame = Plane {
            width: w,
            height: h,
            data: px,
        };
        if let Ok(reports) = tr.step(Stamp::from_frame(k, 0.04), &frame) {
            for r in reports {
                if let Some(b) = r.bbox {
                    assert!(b.cx.is_finite() && b.cy.is_finite());
                }
            }
        }
        k += 1;
    }
});
