//! Deterministic MeanShift clustering (Cheng 1995; Comaniciu & Meer 2002), spec 003 §2.5.
//!
//! Non-blurring (the data never move), kd-tree accelerated, and deterministic: seeds come from
//! square cells of side `h/2` sorted by cell index (or every point), modes are merged in order
//! of support, and clusters are numbered by lexicographic mode order, so the per-point labels do
//! not depend on the order of the input points.

use quarry_core::{Clusterer, Clustering, CoreError, Point2};

use crate::error::Result;
use crate::kd::KdIndex;

/// The kernel profile.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Kernel {
    /// `K(r) = 1` for `r ≤ 1`: each step moves to the mean of the points within `h` (default).
    #[default]
    Flat,
    /// `K(r) = exp(−r²/2)` with bandwidth `h/2`, truncated at `3·h/2` (spec 003 §2.5 option).
    Gaussian,
}

/// How seeds are chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Seeding {
    /// One seed per non-empty square cell of side `h/2`, at the cell's centroid (default).
    #[default]
    Bins,
    /// Every point is a seed (exact; slower).
    AllPoints,
}

/// MeanShift parameters (spec 003 §3); `Default` is the paper's flat kernel with `h = 0.30 m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanShift {
    /// Bandwidth `h`, metres.
    pub bandwidth: f64,
    /// Kernel profile.
    pub kernel: Kernel,
    /// Seeding strategy.
    pub seeding: Seeding,
    /// Stop when a seed moves less than this, metres (`ε_ms`).
    pub tolerance: f64,
    /// Maximum iterations per seed.
    pub max_iter: u32,
    /// Modes within this distance of a stronger mode are merged into it (`r_merge`); `None`
    /// means `h/2`.
    pub merge_radius: Option<f64>,
    /// Clusters with fewer points are dropped and their points labelled noise (`n_min`).
    pub min_cluster_size: usize,
    /// Points farther than this multiple of `h` from every mode are noise.
    pub noise_factor: f64,
}

impl Default for MeanShift {
    fn default() -> Self {
        Self {
            bandwidth: 0.30,
            kernel: Kernel::Flat,
            seeding: Seeding::Bins,
            tolerance: 1e-3,
            max_iter: 50,
            merge_radius: None,
            min_cluster_size: 3,
            noise_factor: 2.0,
        }
    }
}

/// A mode found from one seed.
#[derive(Debug, Clone, Copy)]
struct Mode {
    p: Point2,
    support: usize,
}

impl MeanShift {
    /// A flat-kernel MeanShift with bandwidth `h` and the other parameters at their defaults.
    pub fn with_bandwidth(h: f64) -> Self {
        Self {
            bandwidth: h,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        if !(self.bandwidth.is_finite() && self.bandwidth > 0.0) {
            return Err(CoreError::invalid("bandwidth", "must be finite and positive").into());
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(CoreError::invalid("tolerance", "must be finite and positive").into());
        }
        if let Some(r) = self.merge_radius
            && !(r.is_finite() && r >= 0.0)
        {
            return Err(CoreError::invalid("merge_radius", "must be finite and >= 0").into());
        }
        if !(self.noise_factor > 0.0) {
            return Err(CoreError::invalid("noise_factor", "must be positive").into());
        }
        Ok(())
    }

    /// Clusters `pts` and returns the crate error type (see [`Clusterer::cluster`]).
    pub fn run(&self, pts: &[Point2]) -> Result<Clustering> {
        self.validate()?;
        quarry_core::ensure_finite(pts.iter().flat_map(|p| [&p.x, &p.y]), "MeanShift points")?;
        if pts.is_empty() {
            return Ok(Clustering::default());
        }
        let h = self.bandwidth;
        let index = KdIndex::new(pts)?;
        let seeds = self.seeds(&index);
        let modes: Vec<Mode> = seeds.iter().map(|s| self.climb(&index, *s)).collect();
        // merge: support descending, then lexicographic (x, y)
        let mut order: Vec<usize> = (0..modes.len()).collect();
        order.sort_by(|&a, &b| {
            modes[b]
                .support
                .cmp(&modes[a].support)
                .then(modes[a].p.x.total_cmp(&modes[b].p.x))
                .then(modes[a].p.y.total_cmp(&modes[b].p.y))
        });
        let r_merge = self.merge_radius.unwrap_or(h / 2.0);
        let mut kept: Vec<Point2> = Vec::new();
        for &i in &order {
            let p = modes[i].p;
            if modes[i].support == 0 {
                continue;
            }
            if kept.iter().all(|k| (k - p).norm() > r_merge) {
                kept.push(p);
            }
        }
        // number by lexicographic mode order
        kept.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
        // assign each point to its nearest kept mode (ties: lower mode index)
        let noise2 = (self.noise_factor * h).powi(2);
        let mut labels: Vec<Option<u32>> = pts
            .iter()
            .map(|p| {
                let mut best = (usize::MAX, f64::INFINITY);
                for (k, m) in kept.iter().enumerate() {
                    let d2 = (m - p).norm_squared();
                    if d2 < best.1 {
                        best = (k, d2);
                    }
                }
                (best.0 != usize::MAX && best.1 <= noise2).then_some(best.0 as u32)
            })
            .collect();
        let mut sizes = vec![0usize; kept.len()];
        for l in labels.iter().flatten() {
            sizes[*l as usize] += 1;
        }
        // prune small clusters, renumber the rest (order preserved, so still lexicographic)
        let mut remap = vec![None; kept.len()];
        let mut out_modes = Vec::new();
        let mut out_sizes = Vec::new();
        for (k, &s) in sizes.iter().enumerate() {
            if s >= self.min_cluster_size && s > 0 {
                remap[k] = Some(out_modes.len() as u32);
                out_modes.push(kept[k]);
                out_sizes.push(s);
            }
        }
        for l in &mut labels {
            *l = l.and_then(|k| remap[k as usize]);
        }
        Ok(Clustering {
            labels,
            modes: out_modes,
            sizes: out_sizes,
        })
    }

    fn seeds(&self, index: &KdIndex) -> Vec<Point2> {
        match self.seeding {
            Seeding::AllPoints => index.unique_points().map(|(p, _)| p).collect(),
            Seeding::Bins => {
                let cell = self.bandwidth / 2.0;
                // (ix, iy, sum x, sum y, count): unique points are already sorted, so sums are
                // taken in an order independent of the input order
                let mut cells: Vec<((i64, i64), f64, f64, usize)> = index
                    .unique_points()
                    .map(|(p, m)| {
                        let c = ((p.x / cell).floor() as i64, (p.y / cell).floor() as i64);
                        (c, p.x * m as f64, p.y * m as f64, m)
                    })
                    .collect();
                cells.sort_by_key(|c| c.0);
                let mut seeds = Vec::new();
                let mut i = 0;
                while i < cells.len() {
                    let (c, mut sx, mut sy, mut n) = cells[i];
                    let mut j = i + 1;
                    while j < cells.len() && cells[j].0 == c {
                        sx += cells[j].1;
                        sy += cells[j].2;
                        n += cells[j].3;
                        j += 1;
                    }
                    seeds.push(Point2::new(sx / n as f64, sy / n as f64));
                    i = j;
                }
                seeds
            }
        }
    }

    fn climb(&self, index: &KdIndex, seed: Point2) -> Mode {
        let h = self.bandwidth;
        let mut y = seed;
        for _ in 0..self.max_iter {
            let (mut sx, mut sy, mut sw) = (0.0, 0.0, 0.0);
            match self.kernel {
                Kernel::Flat => index.for_each_unique_within(&y, h, |p, m, _| {
                    let w = m as f64;
                    sx += w * p.x;
                    sy += w * p.y;
                    sw += w;
                }),
                Kernel::Gaussian => {
                    let hg = h / 2.0;
                    let inv = 1.0 / (2.0 * hg * hg);
                    index.for_each_unique_within(&y, 3.0 * hg, |p, m, d2| {
                        let w = m as f64 * (-d2 * inv).exp();
                        sx += w * p.x;
                        sy += w * p.y;
                        sw += w;
                    });
                }
            }
            if !(sw > 0.0) {
                break;
            }
            let next = Point2::new(sx / sw, sy / sw);
            let shift = (next - y).norm();
            y = next;
            if shift < self.tolerance {
                break;
            }
        }
        let mut support = 0;
        index.for_each_unique_within(&y, h, |_, m, _| support += m);
        Mode { p: y, support }
    }
}

impl Clusterer for MeanShift {
    fn cluster(&self, pts: &[Point2]) -> Result<Clustering, CoreError> {
        self.run(pts).map_err(CoreError::from)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{SeedableRng, seq::SliceRandom};
    use rand_distr::{Distribution, Normal};

    /// Blobs with centres at least 1 m apart; returns points and their blob index.
    fn blobs(seed: u64, k: usize, n: &[usize]) -> (Vec<Point2>, Vec<usize>, Vec<Point2>) {
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
        let u = rand_distr::Uniform::new(0.0, 8.0).unwrap();
        let mut centres: Vec<Point2> = Vec::new();
        while centres.len() < k {
            let c = Point2::new(u.sample(&mut rng), u.sample(&mut rng));
            if centres.iter().all(|d| (d - c).norm() >= 1.0) {
                centres.push(c);
            }
        }
        let g = Normal::new(0.0, 0.05).unwrap();
        let mut pts = Vec::new();
        let mut lab = Vec::new();
        for (i, c) in centres.iter().enumerate() {
            for _ in 0..n[i] {
                pts.push(Point2::new(
                    c.x + g.sample(&mut rng),
                    c.y + g.sample(&mut rng),
                ));
                lab.push(i);
            }
        }
        (pts, lab, centres)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        #[test]
        fn blobs_are_found(seed in 0u64..10_000, k in 2usize..=6, n in prop::collection::vec(30usize..=80, 6)) {
            let (pts, lab, _) = blobs(seed, k, &n);
            for ms in [MeanShift::default(), MeanShift { seeding: Seeding::AllPoints, ..MeanShift::default() }] {
                let c = ms.run(&pts).unwrap();
                prop_assert_eq!(c.modes.len(), k);
                // purity: each cluster holds one blob, and each blob one cluster
                let mut map = vec![None; k];
                for (l, b) in c.labels.iter().zip(&lab) {
                    let l = l.expect("no noise in well-separated blobs") as usize;
                    match map[l] { None => map[l] = Some(*b), Some(x) => prop_assert_eq!(x, *b) }
                }
                // each mode within 1 cm of its blob's sample mean
                for (l, m) in c.modes.iter().enumerate() {
                    let b = map[l].unwrap();
                    let (s, cnt) = pts.iter().zip(&lab).filter(|(_, x)| **x == b)
                        .fold((nalgebra::Vector2::zeros(), 0.0), |(s, c), (p, _)| (s + p.coords, c + 1.0));
                    prop_assert!((m.coords - s / cnt).norm() < 0.01);
                }
            }
        }

        #[test]
        fn shuffle_invariant(seed in 0u64..10_000, k in 2usize..=5, gauss in any::<bool>(), all in any::<bool>()) {
            let (pts, _, _) = blobs(seed, k, &[40, 50, 60, 70, 80, 30]);
            let ms = MeanShift {
                kernel: if gauss { Kernel::Gaussian } else { Kernel::Flat },
                seeding: if all { Seeding::AllPoints } else { Seeding::Bins },
                ..MeanShift::default()
            };
            let a = ms.run(&pts).unwrap();
            let mut perm: Vec<usize> = (0..pts.len()).collect();
            perm.shuffle(&mut rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed + 1));
            let shuffled: Vec<Point2> = perm.iter().map(|&i| pts[i]).collect();
            let b = ms.run(&shuffled).unwrap();
            prop_assert_eq!(a.modes.len(), b.modes.len());
            for (x, y) in a.modes.iter().zip(&b.modes) { prop_assert!((x - y).norm() < 1e-12); }
            for (j, &i) in perm.iter().enumerate() { prop_assert_eq!(a.labels[i], b.labels[j]); }
            prop_assert_eq!(a.sizes, b.sizes);
        }

        #[test]
        fn translation_equivariant(seed in 0u64..10_000, tx in -100.0f64..100.0, ty in -100.0f64..100.0) {
            let (pts, _, _) = blobs(seed, 3, &[40, 50, 60]);
            let moved: Vec<Point2> = pts.iter().map(|p| Point2::new(p.x + tx, p.y + ty)).collect();
            for (ms, tol) in [(MeanShift::default(), 5e-3), (MeanShift { seeding: Seeding::AllPoints, ..MeanShift::default() }, 1e-9)] {
                let a = ms.run(&pts).unwrap();
                let b = ms.run(&moved).unwrap();
                prop_assert_eq!(a.modes.len(), b.modes.len());
                for (x, y) in a.modes.iter().zip(&b.modes) {
                    prop_assert!(((y.x - x.x - tx).powi(2) + (y.y - x.y - ty).powi(2)).sqrt() < tol);
                }
            }
        }
    }

    #[test]
    fn edge_cases() {
        assert!(MeanShift::default().run(&[]).unwrap().modes.is_empty());
        assert!(
            MeanShift::default()
                .run(&[Point2::new(f64::NAN, 0.0)])
                .is_err()
        );
        assert!(
            MeanShift::with_bandwidth(0.0)
                .run(&[Point2::origin()])
                .is_err()
        );
        // two points: below n_min -> noise
        let c = MeanShift::default()
            .run(&[Point2::origin(), Point2::new(0.01, 0.0)])
            .unwrap();
        assert!(c.modes.is_empty() && c.labels.iter().all(Option::is_none));
        // many identical points
        let c = MeanShift::default()
            .run(&vec![Point2::new(1.0, 1.0); 1000])
            .unwrap();
        assert_eq!(c.modes, vec![Point2::new(1.0, 1.0)]);
        assert_eq!(c.sizes, vec![1000]);
    }
}
