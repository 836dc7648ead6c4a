//! SIFT on a real image (`bench-data/photo_gray.png`, 800×450, large enough that every parallel
//! path runs: row-parallel blurs, extremum rows, candidates, descriptors) gives the same
//! keypoints and descriptors, bit for bit, with 1, 2 and 3 rayon threads; and (on x86-64 Linux,
//! where the reference digest was recorded) the same output as before the speed work of
//! issue 6, through a digest of every keypoint field and descriptor byte.
//!
//! The image comes from `$QUARRY_SHARED` or `<repo>/../shared`; without it the tests skip.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use quarry_core::Keypoint;
use quarry_vision::sift::{Sift, SiftDescriptor};
use std::path::PathBuf;

fn photo() -> Option<quarry_core::Plane<u8>> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared")),
        PathBuf::from,
    );
    let f = p.join("bench-data/photo_gray.png");
    if !f.exists() {
        eprintln!("skipping: {} not found", f.display());
        return None;
    }
    Some(quarry_vision::io::load_gray(f).unwrap())
}

/// FNV-1a over the bits of every keypoint field and every descriptor byte, in output order.
fn digest(kps: &[Keypoint], desc: &[SiftDescriptor]) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    };
    for (k, d) in kps.iter().zip(desc) {
        for v in [k.x, k.y, k.sigma, k.angle_deg, k.response, k.layer_offset] {
            eat(&v.to_bits().to_le_bytes());
        }
        eat(&k.octave.to_le_bytes());
        eat(&k.layer.to_le_bytes());
        eat(d);
    }
    h
}

#[test]
fn thread_count_does_not_change_the_result() {
    let Some(img) = photo() else { return };
    let sift = Sift::default();
    let run = |t: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap();
        pool.install(|| sift.extract(&img).unwrap())
    };
    let one = run(1);
    assert_eq!(one.0.len(), one.1.len());
    assert!(one.0.len() > 1000, "{} keypoints", one.0.len());
    for t in [2, 3] {
        let other = run(t);
        assert_eq!(one.0.len(), other.0.len(), "{t} threads");
        // Keypoint equality is float equality: compare the bits too.
        assert_eq!(
            digest(&one.0, &one.1),
            digest(&other.0, &other.1),
            "{t} threads"
        );
        assert_eq!(one, other, "{t} threads");
    }
}

/// Digest of the output before the speed work (1463 keypoints), recorded on x86-64 Linux.
/// Other targets may round `sin`, `cos`, `exp` or `powf` of their libm differently, so the
/// check is limited to where it was recorded.
#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
#[test]
fn output_unchanged_by_speed_work() {
    let Some(img) = photo() else { return };
    let (kps, desc) = Sift::default().extract(&img).unwrap();
    assert_eq!(kps.len(), 1463);
    assert_eq!(
        digest(&kps, &desc),
        EXPECTED_DIGEST,
        "{:#018x}",
        digest(&kps, &desc)
    );
}

#[cfg(all(target_arch = "x86_64", target_os = "linux"))]
const EXPECTED_DIGEST: u64 = 0xa1c5_b62f_285d_9cbc;
