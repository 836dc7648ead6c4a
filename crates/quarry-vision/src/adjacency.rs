//! Region adjacency and per-region statistics of a label image (spec 004 §2.6).

use crate::VisionError;
use quarry_core::{Plane, Segmentation};

/// Which regions touch which: regions `i ≠ j` are adjacent iff a pixel of `i` and a pixel of `j`
/// are 8-neighbours.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct RegionAdjacency {
    /// `neighbours[k − 1]`: the labels adjacent to region `k`, sorted and deduplicated.
    pub neighbours: Vec<Vec<u32>>,
}

impl RegionAdjacency {
    /// Builds the adjacency of a label image with labels in `1..=n_regions` (one raster pass over
    /// the E, SE, S and SW neighbours of every pixel).
    ///
    /// Errors: a label of 0 or above `n_regions`, or an inconsistent plane.
    pub fn new(labels: &Plane<u32>, n_regions: usize) -> Result<Self, VisionError> {
        check_labels(labels, n_regions)?;
        let (w, h) = (labels.width as usize, labels.height as usize);
        let d = &labels.data;
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        // A pair found along a boundary is usually the pair found at the previous boundary
        // pixel: skipping such repeats keeps the list (and its sort) short.
        let mut last = (0u32, 0u32);
        let mut add = |a: u32, b: u32| {
            let p = (a.min(b), a.max(b));
            if p != last {
                pairs.push(p);
                last = p;
            }
        };
        // (an empty plane has no pairs; w = 0 would underflow the slices below)
        for y in (0..h).filter(|_| w > 0) {
            let row = &d[y * w..(y + 1) * w];
            for_each_difference(&row[..w - 1], &row[1..], &mut add);
            if y + 1 < h {
                let below = &d[(y + 1) * w..(y + 2) * w];
                for_each_difference(row, below, &mut add);
                // SE: (x, y) with (x + 1, y + 1); SW: (x + 1, y) with (x, y + 1)
                for_each_difference(&row[..w - 1], &below[1..], &mut add);
                for_each_difference(&row[1..], &below[..w - 1], &mut add);
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut neighbours = vec![Vec::new(); n_regions];
        for (a, b) in pairs {
            neighbours[a as usize - 1].push(b);
            neighbours[b as usize - 1].push(a);
        }
        for n in &mut neighbours {
            n.sort_unstable();
        }
        Ok(Self { neighbours })
    }

    /// The adjacency of a segmentation.
    pub fn from_segmentation(seg: &Segmentation) -> Result<Self, VisionError> {
        Self::new(&seg.labels, seg.n_regions())
    }

    /// The regions adjacent to region `label` (empty for an unknown label).
    pub fn of(&self, label: u32) -> &[u32] {
        label
            .checked_sub(1)
            .and_then(|i| self.neighbours.get(i as usize))
            .map_or(&[], Vec::as_slice)
    }

    /// True when regions `a` and `b` are adjacent.
    pub fn are_adjacent(&self, a: u32, b: u32) -> bool {
        self.of(a).binary_search(&b).is_ok()
    }
}

/// Calls `f(a[i], b[i])` for every `i` where the two differ, in order. Blocks of 16 equal
/// labels (most of a label image) cost one vectorised comparison.
// Non-lazy `|` keeps the block test branch-free (it vectorises).
#[allow(clippy::needless_bitwise_bool)]
fn for_each_difference(a: &[u32], b: &[u32], mut f: impl FnMut(u32, u32)) {
    const B: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (mut ca, mut cb) = (a.chunks_exact(B), b.chunks_exact(B));
    for (x, y) in (&mut ca).zip(&mut cb) {
        let differ = x.iter().zip(y).fold(false, |acc, (p, q)| acc | (p != q));
        if differ {
            for (&p, &q) in x.iter().zip(y) {
                if p != q {
                    f(p, q);
                }
            }
        }
    }
    for (&p, &q) in ca.remainder().iter().zip(cb.remainder()) {
        if p != q {
            f(p, q);
        }
    }
}

fn check_labels(labels: &Plane<u32>, n_regions: usize) -> Result<(), VisionError> {
    quarry_core::ensure_len(
        labels.data.len(),
        labels.width as usize * labels.height as usize,
        "plane data length (width * height)",
    )?;
    // l in 1..=n  <=>  l - 1 (wrapping) < n; a branch-free fold over the whole plane
    // vectorises, the search for the culprit runs only when there is one
    let n = u32::try_from(n_regions).unwrap_or(u32::MAX);
    let valid = labels
        .data
        .iter()
        .fold(true, |acc, &l| acc & (l.wrapping_sub(1) < n));
    if valid {
        return Ok(());
    }
    if let Some(&bad) = labels
        .data
        .iter()
        .find(|&&l| l == 0 || l as usize > n_regions)
    {
        return Err(quarry_core::CoreError::invalid(
            "label",
            format!("{bad} is not in 1..={n_regions}"),
        )
        .into());
    }
    Ok(())
}

/// Statistics of one region.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegionStats {
    /// The region's label.
    pub label: u32,
    /// Number of pixels.
    pub area: usize,
    /// Mean pixel position `(x, y)`.
    pub centroid: (f64, f64),
    /// Bounding box `(min_x, min_y, max_x, max_y)`, inclusive.
    pub bbox: (u32, u32, u32, u32),
    /// Mean of the given values over the region.
    pub mean: f64,
    /// Minimum of the given values over the region.
    pub min: f64,
    /// Maximum of the given values over the region.
    pub max: f64,
}

/// Area, centroid, bounding box and value statistics of every region (`values` is any image of
/// the same size, e.g. the grey frame or the relief).
pub fn region_stats<T: Copy + Into<f64>>(
    seg: &Segmentation,
    values: &Plane<T>,
) -> Result<Vec<RegionStats>, VisionError> {
    let n = seg.n_regions();
    check_labels(&seg.labels, n)?;
    if seg.labels.dimensions() != values.dimensions() || values.data.len() != seg.labels.len() {
        return Err(VisionError::SizeMismatch {
            what: "region statistics labels vs values",
            a: seg.labels.dimensions(),
            b: values.dimensions(),
        });
    }
    let mut acc: Vec<RegionStats> = (1..=n as u32)
        .map(|label| RegionStats {
            label,
            area: 0,
            centroid: (0.0, 0.0),
            bbox: (u32::MAX, u32::MAX, 0, 0),
            mean: 0.0,
            min: f64::INFINITY,
            max: f64::NEG_INFINITY,
        })
        .collect();
    let w = seg.labels.width as usize;
    for (i, (&l, &v)) in seg.labels.data.iter().zip(&values.data).enumerate() {
        let (x, y) = ((i % w) as u32, (i / w) as u32);
        let v: f64 = v.into();
        if !v.is_finite() {
            return Err(VisionError::NonFinite("region statistics values"));
        }
        let s = &mut acc[l as usize - 1];
        s.area += 1;
        s.centroid.0 += f64::from(x);
        s.centroid.1 += f64::from(y);
        s.bbox = (
            s.bbox.0.min(x),
            s.bbox.1.min(y),
            s.bbox.2.max(x),
            s.bbox.3.max(y),
        );
        s.mean += v;
        s.min = s.min.min(v);
        s.max = s.max.max(v);
    }
    for s in &mut acc {
        if s.area > 0 {
            let a = s.area as f64;
            s.centroid = (s.centroid.0 / a, s.centroid.1 / a);
            s.mean /= a;
        }
    }
    Ok(acc)
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::MinimumInfo;

    fn seg(w: u32, h: u32, labels: Vec<u32>, n: u32) -> Segmentation {
        Segmentation {
            labels: Plane::from_vec(w, h, labels).unwrap(),
            minima: (1..=n)
                .map(|id| MinimumInfo {
                    id,
                    representative: (0, 0),
                    size: 1,
                    value: 0.0,
                })
                .collect(),
        }
    }

    proptest::proptest! {
        /// The blocked raster pass gives exactly the 8-neighbour pairs of a brute-force scan,
        /// on images from 1 pixel to wider than two comparison blocks, with few labels (long
        /// equal runs) or many.
        #[test]
        fn matches_brute_force(
            w in 1u32..40,
            h in 1u32..12,
            n in 1u32..6,
            seed in proptest::prelude::any::<u64>(),
        ) {
            let mut state = seed | 1;
            let labels: Vec<u32> = (0..w * h)
                .map(|i| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    // runs of equal labels, as in a segmentation
                    if i % 7 < 5 && i > 0 { 0 } else { 1 + (state % u64::from(n)) as u32 }
                })
                .collect();
            let mut filled = labels.clone();
            for i in 1..filled.len() {
                if filled[i] == 0 {
                    filled[i] = filled[i - 1];
                }
            }
            let plane = Plane::from_vec(w, h, filled.clone()).unwrap();
            let adj = RegionAdjacency::new(&plane, n as usize).unwrap();
            let mut want = vec![std::collections::BTreeSet::new(); n as usize];
            let (wi, hi) = (w as i64, h as i64);
            for y in 0..hi {
                for x in 0..wi {
                    let l = filled[(y * wi + x) as usize];
                    for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                        let (u, v) = (x + dx, y + dy);
                        if (0..wi).contains(&u) && (0..hi).contains(&v) {
                            let m = filled[(v * wi + u) as usize];
                            if m != l {
                                want[l as usize - 1].insert(m);
                            }
                        }
                    }
                }
            }
            for l in 1..=n {
                let got: Vec<u32> = adj.of(l).to_vec();
                let exp: Vec<u32> = want[l as usize - 1].iter().copied().collect();
                proptest::prop_assert_eq!(got, exp, "label {}", l);
            }
        }
    }

    #[test]
    fn bad_labels_and_empty_planes() {
        let p = Plane::from_vec(3, 1, vec![1, 0, 1]).unwrap();
        assert!(RegionAdjacency::new(&p, 1).is_err());
        let p = Plane::from_vec(3, 1, vec![1, 3, 1]).unwrap();
        assert!(RegionAdjacency::new(&p, 2).is_err());
        let p = Plane::from_vec(0, 5, Vec::new()).unwrap();
        assert!(RegionAdjacency::new(&p, 0).unwrap().of(1).is_empty());
    }

    #[test]
    fn diagonal_counts_as_adjacent() {
        #[rustfmt::skip]
        let s = seg(3, 3, vec![
            1, 1, 2,
            1, 3, 2,
            4, 2, 2,
        ], 4);
        let a = RegionAdjacency::from_segmentation(&s).unwrap();
        assert_eq!(a.of(1), &[2, 3, 4]);
        assert_eq!(a.of(2), &[1, 3, 4]);
        assert_eq!(a.of(3), &[1, 2, 4]);
        assert_eq!(a.of(4), &[1, 2, 3]);
        assert!(a.are_adjacent(4, 3));
        assert!(a.of(9).is_empty());
        let s = seg(3, 1, vec![1, 2, 3], 3);
        let a = RegionAdjacency::from_segmentation(&s).unwrap();
        assert!(!a.are_adjacent(1, 3));
    }

    #[test]
    fn stats() {
        let s = seg(3, 2, vec![1, 1, 2, 1, 2, 2], 2);
        let v = Plane::from_vec(3, 2, vec![1u8, 2, 3, 4, 5, 6]).unwrap();
        let st = region_stats(&s, &v).unwrap();
        assert_eq!(st[0].area, 3);
        assert!((st[0].mean - 7.0 / 3.0).abs() < 1e-12);
        assert_eq!(st[0].bbox, (0, 0, 1, 1));
        assert!((st[1].centroid.0 - 5.0 / 3.0).abs() < 1e-12);
        assert_eq!((st[1].min, st[1].max), (3.0, 6.0));
        let bad = seg(2, 1, vec![0, 1], 1);
        assert!(RegionAdjacency::from_segmentation(&bad).is_err());
    }
}
