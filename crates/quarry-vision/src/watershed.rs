//! Priority-flood (Meyer) watershed, spec 004 §2.5.
//!
//! Every regional minimum seeds one region; pixels are flooded in order of the key
//! `(max(level of the flooding pixel, own value), arrival sequence)`: a pixel lower than the
//! current flood level is flooded *at* that level, and equal levels are served first-in
//! first-out. Labels are assigned when a pixel is pushed, each pixel is pushed once, seeds are
//! pushed in raster order and neighbours visited in the fixed N8 (or N4) order, so the result is
//! fully deterministic. There are no watershed lines: every pixel gets a label in 1..K
//! ([`boundary_mask`] gives a display-only boundary).
//!
//! The queue is a radix heap on the 128-bit key (order-preserving bits of the level, sequence
//! number): the same pop order as a binary heap on `(level.total_cmp, seq)`, in amortised
//! O(1) per pixel for the monotone keys of a flood.

use crate::VisionError;
use crate::minima::{Connectivity, Minima, Relief, check_relief, regional_minima};
use quarry_core::{Plane, Segmentation};

/// Options of [`flood`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct WatershedOptions {
    /// Neighbourhood used to grow regions (8 by default, as in spec 004).
    pub connectivity: Connectivity,
}

/// An order-preserving u64 image of a finite f64 (`total_cmp` order).
#[inline]
fn level_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}

/// A monotone radix heap over u128 keys (keys pushed are never below the last popped one).
struct RadixHeap {
    last: u128,
    buckets: Vec<Vec<(u128, u32)>>,
    nonempty: [u64; 3],
    len: usize,
}

impl RadixHeap {
    fn new() -> Self {
        Self {
            last: 0,
            buckets: (0..129).map(|_| Vec::new()).collect(),
            nonempty: [0; 3],
            len: 0,
        }
    }

    #[inline]
    fn bucket(&self, key: u128) -> usize {
        128 - (key ^ self.last).leading_zeros() as usize
    }

    #[inline]
    fn push(&mut self, key: u128, v: u32) {
        debug_assert!(key >= self.last);
        let b = self.bucket(key);
        self.buckets[b].push((key, v));
        self.nonempty[b >> 6] |= 1 << (b & 63);
        self.len += 1;
    }

    fn first_nonempty(&self) -> Option<usize> {
        self.nonempty
            .iter()
            .enumerate()
            .find(|(_, m)| **m != 0)
            .map(|(i, m)| i * 64 + m.trailing_zeros() as usize)
    }

    fn pop(&mut self) -> Option<(u128, u32)> {
        if self.len == 0 {
            return None;
        }
        if self.buckets[0].is_empty() {
            let b = self.first_nonempty()?;
            let items = std::mem::take(&mut self.buckets[b]);
            self.nonempty[b >> 6] &= !(1 << (b & 63));
            self.last = items.iter().map(|e| e.0).min().unwrap_or(self.last);
            for (k, v) in &items {
                let nb = self.bucket(*k);
                self.buckets[nb].push((*k, *v));
                self.nonempty[nb >> 6] |= 1 << (nb & 63);
            }
            // give the allocation back to its bucket
            let mut items = items;
            items.clear();
            if self.buckets[b].is_empty() {
                self.buckets[b] = items;
            }
        }
        let e = self.buckets[0].pop();
        if self.buckets[0].is_empty() {
            self.nonempty[0] &= !1;
        }
        if e.is_some() {
            self.len -= 1;
        }
        e
    }
}

/// Floods `relief` from `seeds` (Algorithm WS of spec 004 §2.5). `seeds.labels` gives the seed
/// label of each seed pixel (0 elsewhere) and `seeds.minima` the seed records, copied into the
/// result.
///
/// Errors: empty relief, NaN/infinite values, size mismatch between relief and seeds, seed
/// labels outside 1..=K, no seed at all.
pub fn flood<T: Relief>(
    relief: &Plane<T>,
    seeds: &Minima,
    options: WatershedOptions,
) -> Result<Segmentation, VisionError> {
    check_relief(relief, "watershed")?;
    if relief.dimensions() != seeds.labels.dimensions() {
        return Err(VisionError::SizeMismatch {
            what: "watershed relief vs seeds",
            a: relief.dimensions(),
            b: seeds.labels.dimensions(),
        });
    }
    let k = seeds.minima.len() as u32;
    if k == 0 {
        return Err(quarry_core::CoreError::Empty {
            what: "watershed seeds",
        }
        .into());
    }
    if let Some(&bad) = seeds.labels.data.iter().find(|&&l| l > k) {
        return Err(quarry_core::CoreError::invalid(
            "seed label",
            format!("{bad} is not in 0..={k}"),
        )
        .into());
    }
    let (w, h) = (relief.width as usize, relief.height as usize);
    let d = &relief.data;
    let mut labels = seeds.labels.data.clone();
    let mut heap = RadixHeap::new();
    let mut seq: u128 = 0;
    for (p, &l) in labels.iter().enumerate() {
        if l != 0 {
            heap.push(u128::from(level_key(d[p].to_f64())) << 64 | seq, p as u32);
            seq += 1;
        }
    }
    let offs = options.connectivity.offsets();
    while let Some((key, p)) = heap.pop() {
        let p = p as usize;
        let level = (key >> 64) as u64;
        let lab = labels[p];
        let (x, y) = (p % w, p / w);
        let interior = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
        for &(dx, dy) in offs {
            let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
            if !interior && (qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize) {
                continue;
            }
            let q = qy as usize * w + qx as usize;
            if labels[q] == 0 {
                labels[q] = lab;
                let lq = level_key(d[q].to_f64()).max(level);
                heap.push(u128::from(lq) << 64 | seq, q as u32);
                seq += 1;
            }
        }
    }
    Ok(Segmentation {
        labels: Plane {
            width: relief.width,
            height: relief.height,
            data: labels,
        },
        minima: seeds.minima.clone(),
    })
}

/// Regional minima of `relief` followed by [`flood`] from them.
pub fn watershed<T: Relief>(
    relief: &Plane<T>,
    options: WatershedOptions,
) -> Result<Segmentation, VisionError> {
    let seeds = regional_minima(relief, options.connectivity)?;
    flood(relief, &seeds, options)
}

/// Display-only boundary: pixels with a 4-neighbour of another label.
pub fn boundary_mask(labels: &Plane<u32>) -> Plane<bool> {
    let (w, h) = (labels.width as usize, labels.height as usize);
    let d = &labels.data;
    Plane::from_fn(labels.width, labels.height, |x, y| {
        let (x, y) = (x as usize, y as usize);
        let l = d[y * w + x];
        (x + 1 < w && d[y * w + x + 1] != l)
            || (y + 1 < h && d[(y + 1) * w + x] != l)
            || (x > 0 && d[y * w + x - 1] != l)
            || (y > 0 && d[(y - 1) * w + x] != l)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;

    #[test]
    fn level_key_is_monotone() {
        let vals = [-1e300, -2.5, -0.0, 0.0, 1e-300, 0.5, 1.0, 253.0, 1e300];
        for w in vals.windows(2) {
            assert!(level_key(w[0]) <= level_key(w[1]), "{w:?}");
        }
        assert!(level_key(-1.0) < level_key(1.0));
    }

    #[test]
    fn radix_heap_matches_binary_heap() {
        let mut rng = quarry_core::rng::seeded(7);
        use quarry_core::rng::RngCore;
        let mut rh = RadixHeap::new();
        let mut bh = BinaryHeap::new();
        let mut last = 0u128;
        let mut out_r = Vec::new();
        let mut out_b = Vec::new();
        for i in 0..5000u32 {
            let k = last + u128::from(rng.next_u64() % 1000) * (1 << 70) + u128::from(i);
            rh.push(k, i);
            bh.push(Reverse((k, i)));
            if rng.next_u32().is_multiple_of(3) {
                let a = rh.pop().unwrap();
                let Reverse(b) = bh.pop().unwrap();
                assert_eq!(a, b);
                last = a.0;
                out_r.push(a);
                out_b.push(b);
            }
        }
        while let Some(a) = rh.pop() {
            let Reverse(b) = bh.pop().unwrap();
            assert_eq!(a, b);
        }
        assert!(bh.is_empty());
        assert!(out_r.len() > 1000);
    }

    #[test]
    fn two_dips_split_at_ridge() {
        // two Gaussian dips at x = 10 and x = 30 of a 41x15 image: ridge at x = 20
        let p = Plane::from_fn(41, 15, |x, y| {
            let (xf, yf) = (f64::from(x), f64::from(y));
            let g = |cx: f64| (-((xf - cx).powi(2) + (yf - 7.0).powi(2)) / 50.0).exp();
            -(g(10.0) + g(30.0)) + 1e-3 * yf
        });
        let s = watershed(&p, WatershedOptions::default()).unwrap();
        assert_eq!(s.n_regions(), 2);
        for y in 0..15 {
            for x in 0..41 {
                let l = *s.labels.get(x, y).unwrap();
                if x < 20 {
                    assert_eq!(l, 1, "({x},{y})");
                } else if x > 20 {
                    assert_eq!(l, 2, "({x},{y})");
                }
            }
        }
    }

    #[test]
    fn errors() {
        let p = Plane::new(4, 4, 1.0f64);
        let seeds = Minima {
            labels: Plane::new(3, 4, 0),
            minima: vec![],
        };
        assert!(matches!(
            flood(&p, &seeds, WatershedOptions::default()),
            Err(VisionError::SizeMismatch { .. })
        ));
        let seeds = Minima {
            labels: Plane::new(4, 4, 0),
            minima: vec![],
        };
        assert!(flood(&p, &seeds, WatershedOptions::default()).is_err());
    }

    #[test]
    fn boundary() {
        let l = Plane::from_vec(3, 1, vec![1u32, 1, 2]).unwrap();
        assert_eq!(boundary_mask(&l).data, vec![false, true, true]);
    }
}
