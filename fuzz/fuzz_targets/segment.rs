//! Segmentation on random small images and sigmas: valid input (≥ 2×2, σ > 0) always succeeds,
//! invalid input is an error (never a panic); every pixel is labelled, each minimum's
//! representative carries its own label, and mapping a segmentation onto itself is all
//! bidirectional; the single-threaded blur gives the multi-threaded one's bits.
#![no_main]

use libfuzzer_sys::fuzz_target;
use quarry_core::Plane;
use quarry_vision::{
    Connectivity, RampBlurWatershed, RegionAdjacency, RegionMapping, WatershedOptions, flood,
    regional_minima,
};

/// A pool of one thread, where the blur takes its streaming path.
fn one_thread() -> &'static rayon::ThreadPool {
    static POOL: std::sync::OnceLock<rayon::ThreadPool> = std::sync::OnceLock::new();
    POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("a one-thread pool")
    })
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 4 {
        return;
    }
    let w = u32::from(data[0] % 40);
    let h = u32::from(data[1] % 40);
    let sigma = match data[2] {
        0 => f64::NAN,
        1 => f64::INFINITY,
        s => f64::from(s) / 32.0 - 0.5,
    };
    let eight = data[3] & 1 == 1;
    let px = &data[4..];
    let img = Plane::from_fn(w, h, |x, y| {
        let i = (y * w + x) as usize;
        if px.is_empty() { 0 } else { px[i % px.len()] }
    });
    let seg = RampBlurWatershed {
        sigma,
        levels: 256,
        connectivity: if eight {
            Connectivity::Eight
        } else {
            Connectivity::Four
        },
    };
    let valid = w >= 2 && h >= 2 && sigma.is_finite() && sigma > 0.0 && sigma < 4000.0;
    let result = seg.run(&img);
    // the single-threaded blur (a ring of rows) must give the multi-threaded one's bits
    let single = one_thread().install(|| seg.run(&img));
    match (&result, &single) {
        (Ok(a), Ok(b)) => {
            assert!(a.relief.data.iter().zip(&b.relief.data).all(|(x, y)| x.to_bits() == y.to_bits()));
            assert_eq!(a.segmentation.labels, b.segmentation.labels);
        }
        (Err(_), Err(_)) => {}
        _ => panic!("one thread and several disagree on whether the input is valid"),
    }
    match result {
        Ok(out) => {
            assert!(valid);
            let s = &out.segmentation;
            let k = s.n_regions() as u32;
            assert!(k >= 1);
            assert!(s.labels.data.iter().all(|&l| (1..=k).contains(&l)));
            for m in &s.minima {
                assert_eq!(
                    s.labels.get(m.representative.0, m.representative.1),
                    Some(&m.id)
                );
            }
            let adj = RegionAdjacency::from_segmentation(s).unwrap();
            assert_eq!(adj.neighbours.len(), k as usize);
            let map = RegionMapping::new(s, s).unwrap();
            assert_eq!(map.bidirectional.len(), k as usize);
        }
        Err(_) => assert!(!valid),
    }
    // raw f64 reliefs with arbitrary bit patterns (NaN, inf): error or a complete partition
    let vals: Vec<f64> = px
        .chunks_exact(2)
        .map(|c| f64::from_bits(u64::from(c[0]) << 56 | u64::from(c[1])))
        .collect();
    let n = (w * h) as usize;
    if n > 0 && vals.len() >= n {
        let relief = Plane::from_vec(w, h, vals[..n].to_vec()).unwrap();
        let finite = relief.data.iter().all(|v| v.is_finite());
        match regional_minima(&relief, Connectivity::Eight) {
            Ok(m) => {
                assert!(finite);
                let s = flood(&relief, &m, WatershedOptions::default()).unwrap();
                assert!(
                    s.labels
                        .data
                        .iter()
                        .all(|&l| l >= 1 && l as usize <= m.len())
                );
            }
            Err(_) => assert!(!finite),
        }
    }
});
