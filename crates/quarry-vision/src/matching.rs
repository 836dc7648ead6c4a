//! Matching SIFT descriptors: exact brute force, a k-d tree with best-bin-first search for large
//! sets, Lowe's ratio test, a distance threshold (spec 004 eq. 9), and the mutual check.
//!
//! Distances are Euclidean between the u8 vectors (L2 norm ≈ 512, OpenCV's scale), computed
//! exactly in integers (sum of squared differences as u32, then sqrt), so a threshold such as
//! spec 004's `DThred = 150` means what it means with OpenCV's `BFMatcher(NORM_L2)`.
//!
//! ```
//! use quarry_vision::matching::{BruteForceL2, DescriptorMatcher, MatchOptions, match_descriptors};
//! let mut a = [[0u8; 128]; 3];
//! a[0][0] = 200;
//! a[1][1] = 200;
//! a[2][2] = 200;
//! let mut b = a;
//! b[0][0] = 190; // a slightly different copy of a[0]
//! let nn = BruteForceL2.nearest2(&a, &b);
//! assert_eq!(nn[0].map(|(i, d1, _)| (i, d1)), Some((0, 10.0)));
//! let m = match_descriptors(&BruteForceL2, &a, &b, &MatchOptions::default());
//! assert_eq!(m.len(), 3);
//! ```

use crate::VisionError;
use crate::sift::SiftDescriptor;
use serde::{Deserialize, Serialize};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// A match of query descriptor `query` to train descriptor `train` at L2 `distance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DMatch {
    /// Index into the query set.
    pub query: usize,
    /// Index into the train set.
    pub train: usize,
    /// Euclidean distance.
    pub distance: f32,
}

/// Nearest and second-nearest neighbour of every query: `(train index of the nearest, d1, d2)`,
/// `d2 = ∞` when the train set has one descriptor, `None` when it is empty. Ties go to the lowest
/// train index.
pub trait DescriptorMatcher {
    /// Two nearest neighbours of every query descriptor among `train`.
    fn nearest2(
        &self,
        query: &[SiftDescriptor],
        train: &[SiftDescriptor],
    ) -> Vec<Option<(usize, f32, f32)>>;
}

/// Squared Euclidean distance between two descriptors, exact.
#[inline]
pub fn distance_sq(a: &SiftDescriptor, b: &SiftDescriptor) -> u32 {
    // Eight independent lanes of 16 elements: the loop vectorises (psubw/pmaddwd on x86-64).
    let mut acc = [0u32; 8];
    for (ca, cb) in a.chunks_exact(16).zip(b.chunks_exact(16)) {
        for (k, (&x, &y)) in ca.iter().zip(cb).enumerate() {
            let d = i32::from(x) - i32::from(y);
            acc[k % 8] += (d * d) as u32;
        }
    }
    acc.iter().sum()
}

/// Euclidean distance between two descriptors.
#[inline]
pub fn distance(a: &SiftDescriptor, b: &SiftDescriptor) -> f32 {
    (distance_sq(a, b) as f32).sqrt()
}

/// The two best (squared distance, index) pairs, ordered by (distance, index).
#[derive(Debug, Clone, Copy)]
struct Best2 {
    d1: u32,
    i1: usize,
    d2: u32,
    i2: usize,
}

impl Best2 {
    const EMPTY: Self = Self {
        d1: u32::MAX,
        i1: usize::MAX,
        d2: u32::MAX,
        i2: usize::MAX,
    };

    #[inline]
    fn push(&mut self, d: u32, i: usize) {
        if (d, i) < (self.d1, self.i1) {
            self.d2 = self.d1;
            self.i2 = self.i1;
            self.d1 = d;
            self.i1 = i;
        } else if (d, i) < (self.d2, self.i2) {
            self.d2 = d;
            self.i2 = i;
        }
    }

    fn result(&self) -> Option<(usize, f32, f32)> {
        if self.i1 == usize::MAX {
            return None;
        }
        let d2 = if self.i2 == usize::MAX {
            f32::INFINITY
        } else {
            (self.d2 as f32).sqrt()
        };
        Some((self.i1, (self.d1 as f32).sqrt(), d2))
    }
}

/// Exact brute-force L2 matcher (queries in parallel with the `parallel` feature; the result does
/// not depend on the thread count).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BruteForceL2;

impl DescriptorMatcher for BruteForceL2 {
    fn nearest2(
        &self,
        query: &[SiftDescriptor],
        train: &[SiftDescriptor],
    ) -> Vec<Option<(usize, f32, f32)>> {
        let one = |q: &SiftDescriptor| {
            let mut b = Best2::EMPTY;
            for (i, t) in train.iter().enumerate() {
                let d = distance_sq(q, t);
                if d <= b.d2 {
                    b.push(d, i);
                }
            }
            b.result()
        };
        #[cfg(feature = "parallel")]
        {
            query.par_iter().with_min_len(8).map(one).collect()
        }
        #[cfg(not(feature = "parallel"))]
        {
            query.iter().map(one).collect()
        }
    }
}

#[derive(Debug, Clone)]
enum Node {
    Leaf {
        start: usize,
        end: usize,
    },
    Split {
        dim: usize,
        value: u8,
        left: usize,
        right: usize,
    },
}

/// A k-d tree over a set of descriptors, searched best-bin-first (Beis & Lowe 1997): branches are
/// visited in order of a lower bound on their distance, and the search stops after `max_checks`
/// descriptors have been compared (approximate) or when no branch can hold a closer one (exact).
///
/// Splits are on the dimension of largest variance at the median. The lower bound of a branch is
/// the largest single-axis gap met on the way to it, so with `max_checks = 0` (unlimited) the
/// result equals [`BruteForceL2`]'s, ties included.
#[derive(Debug, Clone)]
pub struct KdTreeIndex<'a> {
    train: &'a [SiftDescriptor],
    perm: Vec<usize>,
    nodes: Vec<Node>,
}

impl<'a> KdTreeIndex<'a> {
    /// Builds the tree with leaves of at most `leaf_size` descriptors (at least 1).
    pub fn build(train: &'a [SiftDescriptor], leaf_size: usize) -> Self {
        let mut idx = Self {
            train,
            perm: (0..train.len()).collect(),
            nodes: Vec::new(),
        };
        if !train.is_empty() {
            let n = train.len();
            idx.build_node(0, n, leaf_size.max(1));
        }
        idx
    }

    fn build_node(&mut self, start: usize, end: usize, leaf: usize) -> usize {
        let id = self.nodes.len();
        self.nodes.push(Node::Leaf { start, end });
        if end - start <= leaf {
            return id;
        }
        // Dimension of largest variance (over at most 256 evenly spaced samples).
        let items = &self.perm[start..end];
        let step = (items.len() / 256).max(1);
        let mut sum = [0f64; 128];
        let mut sum2 = [0f64; 128];
        let mut cnt = 0f64;
        for &i in items.iter().step_by(step) {
            for (k, &v) in self.train[i].iter().enumerate() {
                let v = f64::from(v);
                sum[k] += v;
                sum2[k] += v * v;
            }
            cnt += 1.0;
        }
        let mut dim = 0;
        let mut best = -1.0;
        for k in 0..128 {
            let var = sum2[k] / cnt - (sum[k] / cnt).powi(2);
            if var > best {
                best = var;
                dim = k;
            }
        }
        if best <= 0.0 {
            // Sampled points identical on every axis: keep a (large) leaf.
            return id;
        }
        let mid = (end - start) / 2;
        let train = self.train;
        self.perm[start..end].select_nth_unstable_by_key(mid, |&i| (train[i][dim], i));
        let value = train[self.perm[start + mid]][dim];
        let left = self.build_node(start, start + mid, leaf);
        let right = self.build_node(start + mid, end, leaf);
        self.nodes[id] = Node::Split {
            dim,
            value,
            left,
            right,
        };
        id
    }

    /// Number of indexed descriptors.
    pub fn len(&self) -> usize {
        self.train.len()
    }

    /// True when nothing is indexed.
    pub fn is_empty(&self) -> bool {
        self.train.is_empty()
    }

    /// Two nearest neighbours of `q` (see [`DescriptorMatcher`]); `max_checks = 0` is exact.
    pub fn nearest2(&self, q: &SiftDescriptor, max_checks: usize) -> Option<(usize, f32, f32)> {
        if self.nodes.is_empty() {
            return None;
        }
        let limit = if max_checks == 0 {
            usize::MAX
        } else {
            max_checks
        };
        let mut best = Best2::EMPTY;
        let mut heap: BinaryHeap<Reverse<(u32, usize)>> = BinaryHeap::new();
        heap.push(Reverse((0, 0)));
        let mut checks = 0usize;
        while let Some(Reverse((bound, mut node))) = heap.pop() {
            if bound > best.d2 || checks >= limit {
                break;
            }
            loop {
                match self.nodes[node] {
                    Node::Split {
                        dim,
                        value,
                        left,
                        right,
                    } => {
                        let diff = i32::from(q[dim]) - i32::from(value);
                        let (near, far) = if diff < 0 {
                            (left, right)
                        } else {
                            (right, left)
                        };
                        let b = bound.max((diff * diff) as u32);
                        if b <= best.d2 {
                            heap.push(Reverse((b, far)));
                        }
                        node = near;
                    }
                    Node::Leaf { start, end } => {
                        for &i in &self.perm[start..end] {
                            let d = distance_sq(q, &self.train[i]);
                            if d <= best.d2 {
                                best.push(d, i);
                            }
                        }
                        checks += end - start;
                        break;
                    }
                }
            }
        }
        best.result()
    }
}

/// Approximate matcher: builds a [`KdTreeIndex`] over the train set and searches it best-bin-first
/// with at most `max_checks` distance computations per query (0 = exact). Worth it over brute
/// force from a few thousand train descriptors on; in 128-D the tree prunes little, so accuracy
/// is traded for speed through `max_checks` (Lowe 2004 used 200).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct KdTreeMatcher {
    /// Distance computations per query; 0 searches exhaustively (exact).
    pub max_checks: usize,
    /// Descriptors per leaf.
    pub leaf_size: usize,
}

impl Default for KdTreeMatcher {
    fn default() -> Self {
        Self {
            max_checks: 256,
            leaf_size: 16,
        }
    }
}

impl DescriptorMatcher for KdTreeMatcher {
    fn nearest2(
        &self,
        query: &[SiftDescriptor],
        train: &[SiftDescriptor],
    ) -> Vec<Option<(usize, f32, f32)>> {
        let index = KdTreeIndex::build(train, self.leaf_size);
        let one = |q: &SiftDescriptor| index.nearest2(q, self.max_checks);
        #[cfg(feature = "parallel")]
        {
            query.par_iter().with_min_len(8).map(one).collect()
        }
        #[cfg(not(feature = "parallel"))]
        {
            query.iter().map(one).collect()
        }
    }
}

/// Lowe's ratio test on [`DescriptorMatcher::nearest2`] output: keeps query `k` iff the train set
/// had at least two descriptors and `d1 < ratio·d2` (distances, not squared distances).
pub fn ratio_match(nn: &[Option<(usize, f32, f32)>], ratio: f32) -> Vec<DMatch> {
    nn.iter()
        .enumerate()
        .filter_map(|(q, m)| {
            let (t, d1, d2) = (*m)?;
            (d2.is_finite() && d1 < ratio * d2).then_some(DMatch {
                query: q,
                train: t,
                distance: d1,
            })
        })
        .collect()
}

/// Spec 004 eq. (9): for every query, its nearest train descriptor (ties → lowest index) if the
/// distance is below `d_thred` (strict), else `None`.
pub fn threshold_match(
    query: &[SiftDescriptor],
    train: &[SiftDescriptor],
    d_thred: f32,
) -> Vec<Option<DMatch>> {
    BruteForceL2
        .nearest2(query, train)
        .iter()
        .enumerate()
        .map(|(q, m)| {
            let (t, d1, _) = (*m)?;
            (d1 < d_thred).then_some(DMatch {
                query: q,
                train: t,
                distance: d1,
            })
        })
        .collect()
}

/// Keeps the matches whose train descriptor's own nearest query is the match's query
/// (`backward` = nearest2(train, query)).
pub fn mutual_filter(matches: &[DMatch], backward: &[Option<(usize, f32, f32)>]) -> Vec<DMatch> {
    matches
        .iter()
        .filter(|m| matches!(backward.get(m.train), Some(Some((q, _, _))) if *q == m.query))
        .copied()
        .collect()
}

/// Options of [`match_descriptors`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchOptions {
    /// Lowe's ratio (keep if d1 < ratio·d2); `None` disables the test. Default 0.8.
    pub ratio: Option<f32>,
    /// Keep only matches with distance below this; `None` disables. Default none.
    pub max_distance: Option<f32>,
    /// Keep only mutual nearest neighbours. Default false.
    pub mutual: bool,
}

impl Default for MatchOptions {
    fn default() -> Self {
        Self {
            ratio: Some(0.8),
            max_distance: None,
            mutual: false,
        }
    }
}

impl MatchOptions {
    /// Checks the thresholds: a ratio must be finite and in (0, 1], a distance threshold finite
    /// and > 0. (A NaN ratio would switch the test off silently, a negative one or a NaN
    /// distance would reject every match.)
    pub fn validate(&self) -> Result<(), VisionError> {
        if let Some(r) = self.ratio
            && !(r.is_finite() && r > 0.0 && r <= 1.0)
        {
            return Err(quarry_core::CoreError::invalid(
                "ratio",
                format!("{r}: must be finite and in (0, 1]"),
            )
            .into());
        }
        if let Some(t) = self.max_distance
            && !(t.is_finite() && t > 0.0)
        {
            return Err(quarry_core::CoreError::invalid(
                "max_distance",
                format!("{t}: must be finite and > 0"),
            )
            .into());
        }
        Ok(())
    }
}

/// Matches `query` against `train`: nearest neighbour, then the ratio test, the distance
/// threshold and the mutual check as selected in `opts` (check them first with
/// [`MatchOptions::validate`]: NaN or negative thresholds are not meaningful). Sorted by query
/// index.
pub fn match_descriptors<M: DescriptorMatcher + ?Sized>(
    matcher: &M,
    query: &[SiftDescriptor],
    train: &[SiftDescriptor],
    opts: &MatchOptions,
) -> Vec<DMatch> {
    let nn = matcher.nearest2(query, train);
    let mut m: Vec<DMatch> = match opts.ratio {
        Some(r) => ratio_match(&nn, r),
        None => nn
            .iter()
            .enumerate()
            .filter_map(|(q, m)| {
                m.map(|(t, d, _)| DMatch {
                    query: q,
                    train: t,
                    distance: d,
                })
            })
            .collect(),
    };
    if let Some(t) = opts.max_distance {
        m.retain(|x| x.distance < t);
    }
    if opts.mutual {
        let back = matcher.nearest2(train, query);
        m = mutual_filter(&m, &back);
    }
    m
}

#[cfg(test)]
mod tests {
    #[test]
    fn match_options_refuse_meaningless_thresholds() {
        assert!(MatchOptions::default().validate().is_ok());
        for r in [f32::NAN, -1.0, 0.0, 1.5, f32::INFINITY] {
            let o = MatchOptions {
                ratio: Some(r),
                ..MatchOptions::default()
            };
            assert!(o.validate().is_err(), "{r}");
        }
        for t in [f32::NAN, -1.0, 0.0] {
            let o = MatchOptions {
                max_distance: Some(t),
                ..MatchOptions::default()
            };
            assert!(o.validate().is_err(), "{t}");
        }
    }

    use super::*;
    use proptest::prelude::*;

    fn desc_from(seed: &[u8]) -> SiftDescriptor {
        let mut d = [0u8; 128];
        for (k, v) in d.iter_mut().enumerate() {
            *v = seed[k % seed.len()].wrapping_mul((k as u8).wrapping_add(1));
        }
        d
    }

    #[test]
    fn distance_is_exact() {
        let a = [255u8; 128];
        let b = [0u8; 128];
        assert_eq!(distance_sq(&a, &b), 128 * 255 * 255);
        let mut c = a;
        c[5] = 252;
        assert_eq!(distance_sq(&a, &c), 9);
        assert_eq!(distance(&a, &c), 3.0);
    }

    #[test]
    fn empty_and_single_train() {
        let q = [desc_from(&[1, 2, 3])];
        assert_eq!(BruteForceL2.nearest2(&q, &[]), vec![None]);
        let r = BruteForceL2.nearest2(&q, &q);
        assert_eq!(r, vec![Some((0, 0.0, f32::INFINITY))]);
        assert!(ratio_match(&r, 0.8).is_empty());
        let kd = KdTreeMatcher::default();
        assert_eq!(kd.nearest2(&q, &[]), vec![None]);
        assert_eq!(kd.nearest2(&q, &q), r);
    }

    #[test]
    fn threshold_and_ties() {
        let a = desc_from(&[10, 20]);
        let mut b = a;
        b[0] = b[0].wrapping_add(100);
        let train = [b, a, a];
        let m = threshold_match(&[a], &train, 150.0);
        assert_eq!(m[0].map(|m| m.train), Some(1)); // tie between 1 and 2 → lowest index
        let m = threshold_match(&[b], &[a], 100.0);
        assert!(m[0].is_none()); // distance exactly 100 is not < 100
    }

    #[test]
    fn mutual_check() {
        let x = desc_from(&[1]);
        let mut y = x;
        y[0] = 90;
        let mut z = x;
        z[0] = 100;
        // Both queries (y, z) prefer x, x prefers y.
        let opts = MatchOptions {
            ratio: None,
            max_distance: None,
            mutual: true,
        };
        let m = match_descriptors(&BruteForceL2, &[y, z], &[x], &opts);
        assert_eq!(m.len(), 1);
        assert_eq!(m[0].query, 0);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn kdtree_exact_equals_brute_force(
            seeds in proptest::collection::vec(proptest::collection::vec(0u8..8, 3), 1..120),
            qs in proptest::collection::vec(proptest::collection::vec(0u8..8, 3), 1..12),
            leaf in 1usize..20,
        ) {
            // Few distinct values per axis: many ties, the hard case.
            let train: Vec<SiftDescriptor> = seeds.iter().map(|s| desc_from(s)).collect();
            let query: Vec<SiftDescriptor> = qs.iter().map(|s| desc_from(s)).collect();
            let bf = BruteForceL2.nearest2(&query, &train);
            let kd = KdTreeMatcher { max_checks: 0, leaf_size: leaf }.nearest2(&query, &train);
            prop_assert_eq!(bf, kd);
        }
    }
}
