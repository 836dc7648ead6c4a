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
//! The queue is a radix heap on the order-preserving bits of the level with a FIFO for the
//! current level: the same pop order as a binary heap on `(level.total_cmp, seq)` (tested), in
//! amortised O(1) per pixel for the monotone keys of a flood.

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

/// A monotone radix heap over `(level: u64, seq)` with FIFO order among equal levels.
///
/// Buckets are indexed by the highest bit in which a level differs from the last popped level;
/// bucket 0 holds the items at exactly the current level, in arrival (sequence) order. When it
/// runs dry the lowest non-empty bucket is redistributed; the items that land in bucket 0 are
/// sorted by sequence number, so the pop order equals that of a binary heap on `(level, seq)`.
struct RadixHeap {
    last: u64,
    current: std::collections::VecDeque<(u64, u32)>,
    buckets: Vec<Vec<(u64, u64, u32)>>,
    nonempty: u128,
    seq: u64,
}

impl RadixHeap {
    fn new() -> Self {
        Self {
            last: 0,
            current: std::collections::VecDeque::new(),
            buckets: (0..65).map(|_| Vec::new()).collect(),
            nonempty: 0,
            seq: 0,
        }
    }

    #[inline]
    fn push(&mut self, level: u64, v: u32) {
        debug_assert!(level >= self.last);
        let seq = self.seq;
        self.seq += 1;
        if level == self.last {
            self.current.push_back((seq, v));
        } else {
            let b = 64 - (level ^ self.last).leading_zeros() as usize;
            self.buckets[b].push((level, seq, v));
            self.nonempty |= 1 << b;
        }
    }

    /// Pops the item with the least `(level, seq)`: returns `(level, value)`.
    #[inline]
    fn pop(&mut self) -> Option<(u64, u32)> {
        if self.current.is_empty() {
            if self.nonempty == 0 {
                return None;
            }
            let b = self.nonempty.trailing_zeros() as usize;
            let mut items = std::mem::take(&mut self.buckets[b]);
            self.nonempty &= !(1 << b);
            self.last = items.iter().map(|e| e.0).min().unwrap_or(self.last);
            let mut at_level: Vec<(u64, u32)> = Vec::new();
            for &(level, seq, v) in &items {
                if level == self.last {
                    at_level.push((seq, v));
                } else {
                    let nb = 64 - (level ^ self.last).leading_zeros() as usize;
                    self.buckets[nb].push((level, seq, v));
                    self.nonempty |= 1 << nb;
                }
            }
            at_level.sort_unstable_by_key(|e| e.0);
            self.current.extend(at_level);
            items.clear();
            if self.buckets[b].is_empty() {
                self.buckets[b] = items;
            }
        }
        let (_, v) = self.current.pop_front()?;
        Some((self.last, v))
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
    // Seeds are pushed in raster order; the minimum seed level goes first so that pushes are
    // monotone from the start.
    let mut heap = RadixHeap::new();
    heap.last = labels
        .iter()
        .zip(d)
        .filter(|(l, _)| **l != 0)
        .map(|(_, v)| level_key(v.to_f64()))
        .min()
        .unwrap_or(0);
    for (p, &l) in labels.iter().enumerate() {
        if l != 0 {
            heap.push(level_key(d[p].to_f64()), p as u32);
        }
    }
    let offs = options.connectivity.offsets();
    while let Some((level, p)) = heap.pop() {
        let p = p as usize;
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
                heap.push(lq, q as u32);
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
        use quarry_core::rng::RngCore;
        let mut rng = quarry_core::rng::seeded(7);
        let mut rh = RadixHeap::new();
        let mut bh = BinaryHeap::new();
        let mut last = 0u64;
        let mut popped = 0;
        for i in 0..20000u32 {
            // many equal levels (FIFO must hold) and jumps of all sizes
            let level = match rng.next_u32() % 4 {
                0 => last,
                1 => last + rng.next_u64() % 4,
                2 => last + (rng.next_u64() % 1000) * (1 << (rng.next_u32() % 40)),
                _ => last + rng.next_u64() % (1 << 50),
            };
            rh.push(level, i);
            bh.push(Reverse((level, u64::from(i), i)));
            if rng.next_u32().is_multiple_of(2) {
                let a = rh.pop().unwrap();
                let Reverse(b) = bh.pop().unwrap();
                assert_eq!(a, (b.0, b.2));
                last = a.0;
                popped += 1;
            }
        }
        while let Some(a) = rh.pop() {
            let Reverse(b) = bh.pop().unwrap();
            assert_eq!(a, (b.0, b.2));
        }
        assert!(bh.is_empty());
        assert!(popped > 5000);
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
