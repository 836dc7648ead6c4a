//! Fuzz quarry-data's PTB helpers: the init-box parser on any text, and the depth conversion on
//! any 16-bit values and any declared size. A box is finite with positive size, a depth plane
//! has one value per pixel; anything else is a clear error, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_data::ptb::{DepthFormat, depth_metres, parse_box};

fuzz_target!(|data: &[u8]| {
    if let Ok(b) = parse_box(&String::from_utf8_lossy(data)) {
        assert!(b.w > 0.0 && b.h > 0.0 && b.cx.is_finite() && b.cy.is_finite());
    }
    if data.len() >= 2 {
        let (w, h) = (u32::from(data[0]), u32::from(data[1]));
        let raw: Vec<u16> = data[2..]
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        for f in [DepthFormat::Ptb, DepthFormat::Millimetres] {
            if let Ok(p) = depth_metres(&raw, w, h, f) {
                assert_eq!(p.data.len(), (w * h) as usize);
            }
        }
    }
});
