//! A 2-D kd-tree index: a thin wrapper over [`kiddo::ImmutableKdTree<f64, 2>`] that
//! de-duplicates identical points first and keeps a removal mask.
//!
//! kiddo's trees misbehave on many identical points (see TOOLCHAIN.md), and laser data has them
//! (a sensor that sees the same wall point twice, merged scans). [`KdIndex`] therefore stores each
//! distinct point once with its multiplicity and maps results back to the caller's indices.
//! Unique points are sorted lexicographically before the tree is built, so the tree, and every
//! query result, is independent of the input order.

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use quarry_core::{CoreError, Point2};

use crate::error::Result;

/// A kd-tree over a point set with de-duplication and a removal mask.
#[derive(Debug)]
pub struct KdIndex {
    tree: Option<ImmutableKdTree<f64, 2>>,
    /// Distinct points, lexicographically sorted.
    unique: Vec<[f64; 2]>,
    /// CSR: original indices of unique point u are `members[offsets[u]..offsets[u + 1]]`.
    offsets: Vec<u32>,
    members: Vec<u32>,
    /// Unique point of each original index.
    unique_of: Vec<u32>,
    removed: Vec<bool>,
    /// Remaining (not removed) originals per unique point.
    remaining: Vec<u32>,
    n_removed: usize,
}

fn key(p: &Point2) -> [f64; 2] {
    // normalise -0.0 so that equal values compare equal bitwise
    [p.x + 0.0, p.y + 0.0]
}

impl KdIndex {
    /// Builds the index; every coordinate must be finite. An empty set gives an empty index.
    pub fn new(points: &[Point2]) -> Result<Self> {
        if points.len() >= u32::MAX as usize {
            return Err(CoreError::invalid("points", "more than 2^32 - 1 points").into());
        }
        if points.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(CoreError::NonFinite {
                what: "kd-tree points",
            }
            .into());
        }
        let mut order: Vec<u32> = (0..points.len() as u32).collect();
        order.sort_by(|&a, &b| {
            let (pa, pb) = (key(&points[a as usize]), key(&points[b as usize]));
            pa[0]
                .total_cmp(&pb[0])
                .then(pa[1].total_cmp(&pb[1]))
                .then(a.cmp(&b))
        });
        let mut unique: Vec<[f64; 2]> = Vec::new();
        let mut offsets = Vec::new();
        let mut unique_of = vec![0u32; points.len()];
        for (k, &i) in order.iter().enumerate() {
            let p = key(&points[i as usize]);
            if unique.last() != Some(&p) {
                unique.push(p);
                offsets.push(k as u32);
            }
            unique_of[i as usize] = (unique.len() - 1) as u32;
        }
        offsets.push(points.len() as u32);
        let remaining = offsets.windows(2).map(|w| w[1] - w[0]).collect();
        let tree = if unique.is_empty() {
            None
        } else {
            Some(
                ImmutableKdTree::new_from_slice(&unique)
                    .map_err(|e| CoreError::numerical("kd-tree construction", format!("{e:?}")))?,
            )
        };
        Ok(Self {
            tree,
            unique,
            offsets,
            members: order,
            unique_of,
            removed: vec![false; points.len()],
            remaining,
            n_removed: 0,
        })
    }

    /// Number of indexed points (including removed ones).
    pub fn len(&self) -> usize {
        self.removed.len()
    }

    /// True when no point was indexed.
    pub fn is_empty(&self) -> bool {
        self.removed.is_empty()
    }

    /// Number of distinct points.
    pub fn n_unique(&self) -> usize {
        self.unique.len()
    }

    /// Number of points not yet removed.
    pub fn n_remaining(&self) -> usize {
        self.len() - self.n_removed
    }

    /// The distinct points (sorted) and how many original points each stands for (counting
    /// removed ones).
    pub fn unique_points(&self) -> impl Iterator<Item = (Point2, usize)> + '_ {
        self.unique
            .iter()
            .zip(self.offsets.windows(2))
            .map(|(p, w)| (Point2::new(p[0], p[1]), (w[1] - w[0]) as usize))
    }

    /// Marks original point `i` removed; later queries skip it. Returns false if it was already
    /// removed or out of range.
    pub fn remove(&mut self, i: usize) -> bool {
        match self.removed.get_mut(i) {
            Some(r) if !*r => {
                *r = true;
                self.remaining[self.unique_of[i] as usize] -= 1;
                self.n_removed += 1;
                true
            }
            _ => false,
        }
    }

    /// True when point `i` was removed (or is out of range).
    pub fn is_removed(&self, i: usize) -> bool {
        self.removed.get(i).copied().unwrap_or(true)
    }

    fn members_of(&self, u: usize) -> &[u32] {
        &self.members[self.offsets[u] as usize..self.offsets[u + 1] as usize]
    }

    /// Calls `f(unique_point, remaining_multiplicity, squared_distance)` for every distinct point
    /// within `radius` (inclusive) of `q` that still has unremoved members. The fast path for
    /// kernel sums (MeanShift).
    pub fn for_each_unique_within(
        &self,
        q: &Point2,
        radius: f64,
        mut f: impl FnMut(Point2, usize, f64),
    ) {
        let Some(tree) = &self.tree else { return };
        if !(radius >= 0.0 && q.x.is_finite() && q.y.is_finite()) {
            return;
        }
        let hits = tree
            .query(&[q.x, q.y])
            .within::<SquaredEuclidean<f64>>(radius * radius)
            .unsorted()
            .execute();
        for h in hits {
            let u = h.item as usize;
            let m = self.remaining[u];
            if m > 0 {
                let p = self.unique[u];
                f(Point2::new(p[0], p[1]), m as usize, h.distance);
            }
        }
    }

    /// The distinct-point id of original point `i` (ids index [`Self::unique_points`]).
    pub fn unique_index(&self, i: usize) -> Option<usize> {
        self.unique_of.get(i).map(|&u| u as usize)
    }

    /// Calls `f(unique_id, remaining_multiplicity, squared_distance)` for every distinct point
    /// within `radius` (inclusive) of `q` that still has unremoved members (allocation-free).
    pub fn for_each_unique_id_within(
        &self,
        q: &Point2,
        radius: f64,
        mut f: impl FnMut(usize, usize, f64),
    ) {
        let Some(tree) = &self.tree else { return };
        if !(radius >= 0.0 && q.x.is_finite() && q.y.is_finite()) {
            return;
        }
        let hits = tree
            .query(&[q.x, q.y])
            .within::<SquaredEuclidean<f64>>(radius * radius)
            .unsorted()
            .execute();
        for h in hits {
            let u = h.item as usize;
            let m = self.remaining[u];
            if m > 0 {
                f(u, m as usize, h.distance);
            }
        }
    }

    /// Original indices of the unremoved points within `radius` (inclusive) of `q`, ascending.
    pub fn within(&self, q: &Point2, radius: f64) -> Vec<usize> {
        let mut out = Vec::new();
        let Some(tree) = &self.tree else { return out };
        if !(radius >= 0.0 && q.x.is_finite() && q.y.is_finite()) {
            return out;
        }
        let hits = tree
            .query(&[q.x, q.y])
            .within::<SquaredEuclidean<f64>>(radius * radius)
            .unsorted()
            .execute();
        for h in hits {
            let u = h.item as usize;
            if self.remaining[u] > 0 {
                out.extend(
                    self.members_of(u)
                        .iter()
                        .map(|&i| i as usize)
                        .filter(|&i| !self.removed[i]),
                );
            }
        }
        out.sort_unstable();
        out
    }

    /// The nearest unremoved point to `q`: `(original index, distance)`. Among identical points
    /// the lowest index is returned. `None` when every point is removed or `q` is not finite.
    pub fn nearest(&self, q: &Point2) -> Option<(usize, f64)> {
        let tree = self.tree.as_ref()?;
        if !(q.x.is_finite() && q.y.is_finite()) || self.n_remaining() == 0 {
            return None;
        }
        let nn = tree
            .query(&[q.x, q.y])
            .nearest_one::<SquaredEuclidean<f64>>()
            .execute();
        let u = nn.item as usize;
        if self.remaining[u] > 0 {
            let i = self
                .members_of(u)
                .iter()
                .map(|&i| i as usize)
                .find(|&i| !self.removed[i])?;
            return Some((i, nn.distance.sqrt()));
        }
        // the nearest distinct point is fully removed: fall back to a linear scan (rare: only
        // after removals, on the small clouds this is used with)
        let mut best: Option<(usize, f64)> = None;
        for (u, p) in self.unique.iter().enumerate() {
            if self.remaining[u] == 0 {
                continue;
            }
            let d2 = (p[0] - q.x).powi(2) + (p[1] - q.y).powi(2);
            if best.is_none_or(|(_, b)| d2 < b) {
                best = Some((u, d2));
            }
        }
        let (u, d2) = best?;
        let i = self
            .members_of(u)
            .iter()
            .map(|&i| i as usize)
            .find(|&i| !self.removed[i])?;
        Some((i, d2.sqrt()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use quarry_testkit::brute;

    #[test]
    fn many_identical_points_do_not_panic() {
        let mut pts = vec![Point2::new(1.0, 1.0); 5000];
        pts.extend((0..200).map(|i| Point2::new(f64::from(i) * 0.01, 0.0)));
        let idx = KdIndex::new(&pts).unwrap();
        assert_eq!(idx.n_unique(), 201);
        assert_eq!(idx.within(&Point2::new(1.0, 1.0), 0.001).len(), 5000);
        let (i, d) = idx.nearest(&Point2::new(1.0, 1.1)).unwrap();
        assert_eq!(i, 0);
        assert!((d - 0.1).abs() < 1e-12);
    }

    #[test]
    fn removal_and_empty() {
        let e = KdIndex::new(&[]).unwrap();
        assert!(e.nearest(&Point2::origin()).is_none());
        assert!(e.within(&Point2::origin(), 1.0).is_empty());
        let pts = [
            Point2::new(0.0, 0.0),
            Point2::new(1.0, 0.0),
            Point2::new(0.0, 0.0),
        ];
        let mut idx = KdIndex::new(&pts).unwrap();
        assert!(idx.remove(0));
        assert!(!idx.remove(0));
        assert_eq!(idx.nearest(&Point2::new(0.1, 0.0)).unwrap().0, 2);
        idx.remove(2);
        assert_eq!(idx.nearest(&Point2::new(0.1, 0.0)).unwrap().0, 1);
        assert_eq!(idx.within(&Point2::new(0.0, 0.0), 2.0), vec![1]);
        assert!(KdIndex::new(&[Point2::new(f64::NAN, 0.0)]).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn radius_query_equals_brute_force(
            raw in prop::collection::vec((-20i32..20, -20i32..20), 1..300),
            q in (-25i32..25, -25i32..25),
            r in 0.0f64..10.0,
            remove in prop::collection::vec(0usize..300, 0..30),
        ) {
            // a coarse grid makes duplicates and ties on the radius common
            let pts: Vec<Point2> = raw.iter().map(|&(x, y)| Point2::new(f64::from(x) * 0.5, f64::from(y) * 0.5)).collect();
            let q = Point2::new(f64::from(q.0) * 0.5, f64::from(q.1) * 0.5);
            let mut idx = KdIndex::new(&pts).unwrap();
            for &i in &remove { idx.remove(i % pts.len()); }
            let got = idx.within(&q, r);
            let want = brute::within(&pts, &q, r, |i| !idx.is_removed(i));
            prop_assert_eq!(got, want);
            let bf = brute::nearest_distance(&pts, &q, |i| !idx.is_removed(i));
            match idx.nearest(&q) {
                Some((i, d)) => { prop_assert!((d - bf).abs() < 1e-12); prop_assert!(((pts[i] - q).norm() - bf).abs() < 1e-12); }
                None => prop_assert!(bf.is_infinite()),
            }
        }
    }
}
