//! The weighted feature pool of spec 004 §2.11 (Hu et al. 2012, eqs. 9-11).
//!
//! A target's appearance is a set of descriptors, each with a weight. At every frame where the
//! target is visible, the descriptors `P` of its region of interest are classified against the
//! pool and against the previous frame's descriptors `D_prev`:
//!
//! - `P_mp` (eq. 9): `p` whose nearest pool entry is closer than `d_thred`; that entry is `q*(p)`;
//! - `P_mb`: `p` not in `P_mp` that pass Lowe's ratio test against `D_prev` (`d1 < ρ·d2`, at
//!   least two references);
//! - `P_nm`: the rest.
//!
//! Then, in this order (spec A16): every entry gains `inc` (2) if it is some `q*(p)` and loses
//! `dec` (0.5) otherwise (eq. 10; once per frame however many `p` chose it); entries with a weight
//! strictly below `delete_below` (-7) are deleted; `P_mb` is inserted at weight `add_matched` (1)
//! and `P_nm` at `add_unmatched` (0) (eq. 11); `P_mp` is not inserted; when the pool holds more
//! than `cap` entries, the lowest weights (then the oldest) are evicted.
//!
//! The pool is generic over the descriptor ([`PoolDescriptor`]): SIFT's `[u8; 128]` implements
//! it, and any other appearance descriptor with a distance can.
//!
//! ```
//! use quarry_vision::{PoolParams, WeightedPool};
//! let a = [10u8; 128];
//! let mut b = [10u8; 128];
//! b[0] = 250; // far from a (distance 240)
//! let mut pool = WeightedPool::new(PoolParams::default())?;
//! pool.seed(0, &[a], &[])?; // a new target: every descriptor at weight 0
//! let stats = pool.update(1, &[a, b], &[], &[a])?; // a matches its entry, b is new
//! assert_eq!((stats.matched_pool, stats.unmatched), (1, 1));
//! assert_eq!(pool.entries()[0].weight, 2.0);
//! assert_eq!(pool.entries()[1].weight, 0.0);
//! assert_eq!(pool.count_matches(&[a, b]), 2);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use crate::matching::distance_sq;
use crate::sift::SiftDescriptor;
use quarry_core::CoreError;
use serde::{Deserialize, Serialize};

/// A descriptor the pool can hold: it needs a distance.
pub trait PoolDescriptor: Clone {
    /// The distance between two descriptors (for SIFT: Euclidean L2 on the u8 vectors, whose
    /// norm is about 512).
    fn distance(&self, other: &Self) -> f32;
}

impl PoolDescriptor for SiftDescriptor {
    fn distance(&self, other: &Self) -> f32 {
        (distance_sq(self, other) as f32).sqrt()
    }
}

/// The pool's parameters. `Default` is the paper's (spec 004 §3.1) with the spec's resolved cap.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PoolParams {
    /// `D_Thred` of eq. (9): a descriptor matches a pool entry closer than this (strict) [paper:
    /// 150 on the 512-norm u8 scale, spec A5].
    pub d_thred: f32,
    /// `ρ` of the ratio test against the previous frame's descriptors [paper: 0.5].
    pub ratio: f32,
    /// Apply `ρ` to squared distances (Hess's matcher) instead of distances (Lowe) [spec A5:
    /// false].
    pub ratio_on_squared: bool,
    /// Initial weight of a ratio-matched new descriptor (`P_mb`, eq. 11) [paper: 1].
    pub add_matched: f64,
    /// Initial weight of an unmatched new descriptor (`P_nm`, eq. 11) [paper: 0].
    pub add_unmatched: f64,
    /// Weight gained by an entry matched in a frame (eq. 10) [paper: 2].
    pub inc: f64,
    /// Weight lost by an entry not matched in a frame (eq. 10) [paper: 0.5].
    pub dec: f64,
    /// Entries with a weight strictly below this are deleted (`W_del`) [paper: -7].
    pub delete_below: f64,
    /// Most entries kept (lowest weight, then oldest, evicted first) [spec §3.2: 1000, a safety
    /// cap the paper does not have].
    pub cap: usize,
}

impl Default for PoolParams {
    fn default() -> Self {
        Self {
            d_thred: 150.0,
            ratio: 0.5,
            ratio_on_squared: false,
            add_matched: 1.0,
            add_unmatched: 0.0,
            inc: 2.0,
            dec: 0.5,
            delete_below: -7.0,
            cap: 1000,
        }
    }
}

impl PoolParams {
    /// Checks every parameter: finite values, `d_thred > 0`, `0 < ratio <= 1`, `inc >= 0`,
    /// `dec >= 0`, `cap >= 1`.
    pub fn validate(&self) -> Result<(), VisionError> {
        let bad = |name: &'static str, why: &str| Err(CoreError::invalid(name, why).into());
        if !(self.d_thred.is_finite() && self.d_thred > 0.0) {
            return bad("d_thred", "must be finite and > 0");
        }
        if !(self.ratio.is_finite() && self.ratio > 0.0 && self.ratio <= 1.0) {
            return bad("ratio", "must be in (0, 1]");
        }
        for (name, v) in [
            ("add_matched", self.add_matched),
            ("add_unmatched", self.add_unmatched),
            ("delete_below", self.delete_below),
        ] {
            if !v.is_finite() {
                return bad(name, "must be finite");
            }
        }
        if !(self.inc.is_finite() && self.inc >= 0.0) {
            return bad("inc", "must be finite and >= 0");
        }
        if !(self.dec.is_finite() && self.dec >= 0.0) {
            return bad("dec", "must be finite and >= 0");
        }
        if self.cap == 0 {
            return bad("cap", "must be >= 1");
        }
        Ok(())
    }
}

/// One pool entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoolEntry<D> {
    /// The descriptor.
    pub descriptor: D,
    /// Its weight `W` (eq. 10).
    pub weight: f64,
    /// The frame it was inserted at.
    pub birth: u64,
    /// Keypoint position minus the target centre at insertion, `δ` (used by offset voting, an
    /// extension of spec §2.14); `[0, 0]` when the caller gave none.
    pub offset: [f64; 2],
}

/// What one [`WeightedPool::update`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PoolUpdateStats {
    /// `|P_mp|`: current descriptors matched to the pool (eq. 9).
    pub matched_pool: usize,
    /// `|P_mb \ P_mp|`: ratio-matched to the previous frame only (inserted at `add_matched`).
    pub matched_previous: usize,
    /// `|P_nm|`: matched to neither (inserted at `add_unmatched`).
    pub unmatched: usize,
    /// Entries that gained `inc` (`|DesPO_mp|`).
    pub reinforced: usize,
    /// Entries deleted below `delete_below`.
    pub deleted: usize,
    /// Entries evicted by the cap.
    pub evicted: usize,
    /// Pool size after the update.
    pub size: usize,
}

/// The weighted descriptor pool of spec 004 §2.11 (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightedPool<D> {
    entries: Vec<PoolEntry<D>>,
    params: PoolParams,
}

/// Checks that `offsets` is empty or as long as the descriptors.
fn check_offsets(n: usize, offsets: &[[f64; 2]]) -> Result<(), VisionError> {
    if !offsets.is_empty() && offsets.len() != n {
        return Err(CoreError::DimensionMismatch {
            what: "pool offsets (one per descriptor, or none)",
            expected: n,
            got: offsets.len(),
        }
        .into());
    }
    if offsets.iter().flatten().any(|v| !v.is_finite()) {
        return Err(VisionError::NonFinite("pool offsets"));
    }
    Ok(())
}

impl<D: PoolDescriptor> WeightedPool<D> {
    /// An empty pool with checked parameters.
    pub fn new(params: PoolParams) -> Result<Self, VisionError> {
        params.validate()?;
        Ok(Self {
            entries: Vec::new(),
            params,
        })
    }

    /// The parameters.
    pub fn params(&self) -> &PoolParams {
        &self.params
    }

    /// The entries, in insertion order.
    pub fn entries(&self) -> &[PoolEntry<D>] {
        &self.entries
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the pool has no entry.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// A new target's first pool: every descriptor inserted at weight `add_unmatched` (0), the
    /// spec's reading of "the first pool" (A16). Replaces any entries. `offsets` is empty or one
    /// per descriptor.
    pub fn seed(
        &mut self,
        frame: u64,
        descriptors: &[D],
        offsets: &[[f64; 2]],
    ) -> Result<(), VisionError> {
        check_offsets(descriptors.len(), offsets)?;
        self.entries.clear();
        for (k, d) in descriptors.iter().enumerate() {
            self.entries.push(PoolEntry {
                descriptor: d.clone(),
                weight: self.params.add_unmatched,
                birth: frame,
                offset: offsets.get(k).copied().unwrap_or([0.0; 2]),
            });
        }
        self.enforce_cap();
        Ok(())
    }

    /// The nearest entry to `d` and its distance (ties → lowest index); `None` for an empty pool.
    pub fn nearest(&self, d: &D) -> Option<(usize, f32)> {
        let mut best: Option<(usize, f32)> = None;
        for (i, e) in self.entries.iter().enumerate() {
            let dist = d.distance(&e.descriptor);
            if best.is_none_or(|(_, b)| dist < b) {
                best = Some((i, dist));
            }
        }
        best
    }

    /// Eq. (9) for one descriptor: the nearest entry when it is closer than `d_thred`.
    pub fn matched_entry(&self, d: &D) -> Option<usize> {
        self.nearest(d)
            .and_then(|(i, dist)| (dist < self.params.d_thred).then_some(i))
    }

    /// How many of `query` match some entry (eq. 9): the separation count `c_jk` of spec §2.15.
    pub fn count_matches(&self, query: &[D]) -> usize {
        query
            .iter()
            .filter(|d| self.matched_entry(d).is_some())
            .count()
    }

    /// Lowe's ratio test of `d` against `previous`: the nearest distance below `ratio` times the
    /// second nearest (on squared distances with `ratio_on_squared`); needs two references.
    pub fn ratio_matches(&self, d: &D, previous: &[D]) -> bool {
        if previous.len() < 2 {
            return false;
        }
        let (mut d1, mut d2) = (f32::INFINITY, f32::INFINITY);
        for p in previous {
            let x = d.distance(p);
            if x < d1 {
                d2 = d1;
                d1 = x;
            } else if x < d2 {
                d2 = x;
            }
        }
        if self.params.ratio_on_squared {
            d1 * d1 < self.params.ratio * d2 * d2
        } else {
            d1 < self.params.ratio * d2
        }
    }

    /// Whether `d` is "matched to" this pool's target in the sense of the ownership test (spec
    /// §2.12): eq. (9) against the pool, or the ratio test against `previous`.
    pub fn owns(&self, d: &D, previous: &[D]) -> bool {
        self.matched_entry(d).is_some() || self.ratio_matches(d, previous)
    }

    /// The ownership ratio `r` of spec §2.12: the fraction of `query` that [`owns`](Self::owns)
    /// accepts (each descriptor counted once); `None` for an empty query.
    pub fn ownership_ratio(&self, query: &[D], previous: &[D]) -> Option<f64> {
        if query.is_empty() {
            return None;
        }
        let n = query.iter().filter(|d| self.owns(d, previous)).count();
        Some(n as f64 / query.len() as f64)
    }

    /// One frame's update (`POOL_UPDATE` of spec §2.11, see the module docs): `current` are the
    /// descriptors of the target's region of interest at `frame`, `previous` those of the frame
    /// before (`D_prev`; the caller keeps it, and afterwards sets it to `current`). `offsets` is
    /// empty or one per current descriptor (stored with the inserted entries).
    pub fn update(
        &mut self,
        frame: u64,
        current: &[D],
        offsets: &[[f64; 2]],
        previous: &[D],
    ) -> Result<PoolUpdateStats, VisionError> {
        check_offsets(current.len(), offsets)?;
        let p = self.params;
        let mut hit = vec![false; self.entries.len()];
        let mut insert: Vec<(usize, f64)> = Vec::new();
        let mut stats = PoolUpdateStats::default();
        for (k, d) in current.iter().enumerate() {
            if let Some(q) = self.matched_entry(d) {
                hit[q] = true;
                stats.matched_pool += 1;
            } else if self.ratio_matches(d, previous) {
                stats.matched_previous += 1;
                insert.push((k, p.add_matched));
            } else {
                stats.unmatched += 1;
                insert.push((k, p.add_unmatched));
            }
        }
        for (e, &h) in self.entries.iter_mut().zip(&hit) {
            if h {
                e.weight += p.inc;
                stats.reinforced += 1;
            } else {
                e.weight -= p.dec;
            }
        }
        let before = self.entries.len();
        // weights are finite (finite parameters), so `>=` is the negation of the strict `<`
        self.entries.retain(|e| e.weight >= p.delete_below);
        stats.deleted = before - self.entries.len();
        for (k, w) in insert {
            self.entries.push(PoolEntry {
                descriptor: current[k].clone(),
                weight: w,
                birth: frame,
                offset: offsets.get(k).copied().unwrap_or([0.0; 2]),
            });
        }
        stats.evicted = self.enforce_cap();
        stats.size = self.entries.len();
        Ok(stats)
    }

    /// Evicts the lowest weights, then the oldest, down to `cap`; returns how many.
    fn enforce_cap(&mut self) -> usize {
        let cap = self.params.cap;
        if self.entries.len() <= cap {
            return 0;
        }
        let n = self.entries.len() - cap;
        // rank by (weight, birth, index): the first n go
        let mut order: Vec<usize> = (0..self.entries.len()).collect();
        order.sort_by(|&a, &b| {
            let (ea, eb) = (&self.entries[a], &self.entries[b]);
            ea.weight
                .total_cmp(&eb.weight)
                .then(ea.birth.cmp(&eb.birth))
                .then(a.cmp(&b))
        });
        let mut drop = vec![false; self.entries.len()];
        for &i in &order[..n] {
            drop[i] = true;
        }
        let mut k = 0;
        self.entries.retain(|_| {
            let keep = !drop[k];
            k += 1;
            keep
        });
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A descriptor far (L2 = 200·√2) from every other of this family.
    fn desc(k: usize) -> SiftDescriptor {
        let mut d = [0u8; 128];
        d[k % 64] = 200;
        d[64 + k / 64 % 64] = 200;
        d
    }

    #[test]
    fn matched_every_frame_gains_two_per_frame() {
        let mut pool = WeightedPool::new(PoolParams::default()).unwrap();
        pool.seed(0, &[desc(1)], &[]).unwrap();
        for t in 1..=20u64 {
            let s = pool.update(t, &[desc(1)], &[], &[desc(1)]).unwrap();
            assert_eq!(s.reinforced, 1);
            assert_eq!(pool.entries()[0].weight, 2.0 * t as f64);
            assert_eq!(pool.len(), 1);
        }
    }

    #[test]
    fn unmatched_lifetimes_are_15_and_17_updates() {
        for (start_matched, life) in [(false, 15u64), (true, 17)] {
            let mut pool = WeightedPool::new(PoolParams::default()).unwrap();
            // previous frame: two references, one identical to the new descriptor -> ratio match
            let prev = if start_matched {
                vec![desc(7), desc(300)]
            } else {
                vec![]
            };
            pool.update(0, &[desc(7)], &[], &prev).unwrap();
            assert_eq!(
                pool.entries()[0].weight,
                if start_matched { 1.0 } else { 0.0 }
            );
            for k in 1..=life {
                pool.update(k, &[], &[], &[]).unwrap();
                assert_eq!(pool.is_empty(), k == life, "update {k}");
            }
        }
        // W_del = -9: the 19th and 21st updates
        let p = PoolParams {
            delete_below: -9.0,
            ..PoolParams::default()
        };
        let mut pool = WeightedPool::new(p).unwrap();
        pool.seed(0, &[desc(3)], &[]).unwrap();
        for k in 1..=19u64 {
            pool.update(k, &[], &[], &[]).unwrap();
            assert_eq!(pool.is_empty(), k == 19);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(
            WeightedPool::<SiftDescriptor>::new(PoolParams {
                d_thred: f32::NAN,
                ..PoolParams::default()
            })
            .is_err()
        );
        assert!(
            WeightedPool::<SiftDescriptor>::new(PoolParams {
                cap: 0,
                ..PoolParams::default()
            })
            .is_err()
        );
        let mut pool = WeightedPool::new(PoolParams::default()).unwrap();
        assert!(pool.seed(0, &[desc(1)], &[[0.0; 2], [1.0; 2]]).is_err());
        assert!(pool.update(0, &[desc(1)], &[[f64::NAN, 0.0]], &[]).is_err());
        assert_eq!(pool.ownership_ratio(&[], &[]), None);
    }

    #[test]
    fn cap_evicts_lowest_then_oldest() {
        let p = PoolParams {
            cap: 3,
            ..PoolParams::default()
        };
        let mut pool = WeightedPool::new(p).unwrap();
        pool.seed(0, &[desc(1), desc(2)], &[]).unwrap();
        pool.update(1, &[desc(1), desc(3), desc(4)], &[], &[])
            .unwrap();
        // desc(1) at 2, desc(2) at -0.5, desc(3) and desc(4) at 0 (born 1): desc(2) evicted
        let ws: Vec<f64> = pool.entries().iter().map(|e| e.weight).collect();
        assert_eq!(ws, vec![2.0, 0.0, 0.0]);
        assert_eq!(pool.entries()[1].descriptor, desc(3));
    }

    proptest! {
        /// Eq. (10)-(11) arithmetic: after any sequence of updates each surviving entry's weight
        /// is its initial weight + 2·(frames matched) - 0.5·(frames not matched), no weight is
        /// below W_del, the pool never exceeds its cap, and the classification counts add up.
        #[test]
        fn weights_follow_eq_10(
            frames in proptest::collection::vec(proptest::collection::vec(0usize..12, 0..6), 1..30)
        ) {
            let mut pool = WeightedPool::new(PoolParams { cap: 50, ..PoolParams::default() }).unwrap();
            // reference model: per descriptor key -> (weight), entries unique per key
            let mut model: Vec<(usize, f64)> = Vec::new();
            let mut prev: Vec<SiftDescriptor> = Vec::new();
            for (t, keys) in frames.iter().enumerate() {
                let mut keys = keys.clone();
                keys.sort_unstable();
                keys.dedup();
                let cur: Vec<SiftDescriptor> = keys.iter().map(|&k| desc(k)).collect();
                let s = pool.update(t as u64, &cur, &[], &prev).unwrap();
                prop_assert_eq!(s.matched_pool + s.matched_previous + s.unmatched, cur.len());
                // model
                let present: Vec<usize> = model.iter().map(|m| m.0).collect();
                for m in &mut model {
                    m.1 += if keys.contains(&m.0) { 2.0 } else { -0.5 };
                }
                model.retain(|m| m.1 >= -7.0);
                for &k in &keys {
                    if !present.contains(&k) {
                        // ratio test against prev: identical descriptor present and >= 2 refs
                        let w = if prev.len() >= 2 && prev.contains(&desc(k)) { 1.0 } else { 0.0 };
                        model.push((k, w));
                    }
                }
                prop_assert!(pool.len() <= 50);
                let got: Vec<(SiftDescriptor, f64)> =
                    pool.entries().iter().map(|e| (e.descriptor, e.weight)).collect();
                let want: Vec<(SiftDescriptor, f64)> =
                    model.iter().map(|&(k, w)| (desc(k), w)).collect();
                prop_assert_eq!(got, want);
                prop_assert!(pool.entries().iter().all(|e| e.weight >= -7.0));
                prev = cur;
            }
        }

        /// Matching never changes the pool (an occluded target's pool stays bit-identical).
        #[test]
        fn queries_do_not_mutate(keys in proptest::collection::vec(0usize..20, 0..10)) {
            let mut pool = WeightedPool::new(PoolParams::default()).unwrap();
            let d: Vec<SiftDescriptor> = keys.iter().map(|&k| desc(k)).collect();
            pool.seed(3, &d, &[]).unwrap();
            let before = pool.clone();
            let _ = pool.count_matches(&d);
            let _ = pool.ownership_ratio(&d, &d);
            let _ = d.first().map(|x| pool.nearest(x));
            prop_assert_eq!(pool, before);
        }
    }
}
