//! Region mapping between consecutive frames (spec 004 §2.7, after Kobayashi et al. 2006).
//!
//! The camera is static: minimum `i` of frame t is looked up at the same pixel in frame t+1.
//! forward `f(i) = Λ_{t+1}(a^t_i)`, backward `g(j) = Λ_t(a^{t+1}_j)`; `(i, j)` is a
//! *bidirectional match* when `f(i) = j` and `g(j) = i`; region `j` of t+1 is a *merge* when at
//! least two regions of t map into it; region `i` of t *splits* when at least two regions of t+1
//! map back into it. Each `i` has one primary successor `f(i)` (tagged `Merge` when the link is
//! not bidirectional, spec §2.7) and fragments `g⁻¹(i) \ {f(i)}`.

use crate::VisionError;
use quarry_core::Segmentation;

/// The kind of a primary successor link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum LinkKind {
    /// `g(f(i)) = i`.
    Bidirectional,
    /// A one-way forward link (several regions flowed into one, or the reverse link points
    /// elsewhere).
    Merge,
}

/// The relations between the regions of two consecutive segmentations.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub struct RegionMapping {
    /// `forward[i − 1] = f(i)`, a label of frame t+1, for every region `i` of frame t.
    pub forward: Vec<u32>,
    /// `backward[j − 1] = g(j)`, a label of frame t, for every region `j` of frame t+1.
    pub backward: Vec<u32>,
    /// The bidirectional pairs `(i, j)`, sorted by `i`.
    pub bidirectional: Vec<(u32, u32)>,
    /// Regions `j` of t+1 with `|f⁻¹(j)| ≥ 2`, sorted.
    pub merges: Vec<u32>,
    /// Regions `i` of t with `|g⁻¹(i)| ≥ 2`, sorted.
    pub splits: Vec<u32>,
    /// `fragments[i − 1] = g⁻¹(i) \ {f(i)}`, sorted.
    pub fragments: Vec<Vec<u32>>,
}

impl RegionMapping {
    /// Maps the regions of `prev` (frame t) onto those of `next` (frame t+1).
    ///
    /// Errors: different image sizes, or a representative point outside its image or carrying
    /// a label outside 1..=K of the other frame.
    pub fn new(prev: &Segmentation, next: &Segmentation) -> Result<Self, VisionError> {
        if prev.labels.dimensions() != next.labels.dimensions() {
            return Err(VisionError::SizeMismatch {
                what: "region mapping",
                a: prev.labels.dimensions(),
                b: next.labels.dimensions(),
            });
        }
        let forward = lookup(prev, next)?;
        let backward = lookup(next, prev)?;
        let (kt, kn) = (forward.len(), backward.len());
        let mut preimage_f = vec![0usize; kn];
        for &j in &forward {
            preimage_f[j as usize - 1] += 1;
        }
        let mut preimage_g: Vec<Vec<u32>> = vec![Vec::new(); kt];
        for (j, &i) in backward.iter().enumerate() {
            preimage_g[i as usize - 1].push(j as u32 + 1);
        }
        let bidirectional = forward
            .iter()
            .enumerate()
            .filter(|&(i, &j)| backward[j as usize - 1] == i as u32 + 1)
            .map(|(i, &j)| (i as u32 + 1, j))
            .collect();
        let merges = (0..kn)
            .filter(|&j| preimage_f[j] >= 2)
            .map(|j| j as u32 + 1)
            .collect();
        let splits = (0..kt)
            .filter(|&i| preimage_g[i].len() >= 2)
            .map(|i| i as u32 + 1)
            .collect();
        let fragments = preimage_g
            .into_iter()
            .zip(&forward)
            .map(|(mut g, &f)| {
                g.retain(|&j| j != f);
                g
            })
            .collect();
        Ok(Self {
            forward,
            backward,
            bidirectional,
            merges,
            splits,
            fragments,
        })
    }

    /// The primary successor of region `i` of frame t and the kind of link (`None` for an
    /// unknown label).
    pub fn successor(&self, i: u32) -> Option<(u32, LinkKind)> {
        let j = *self.forward.get(i.checked_sub(1)? as usize)?;
        let kind = if self.backward[j as usize - 1] == i {
            LinkKind::Bidirectional
        } else {
            LinkKind::Merge
        };
        Some((j, kind))
    }

    /// The fragments of region `i` of frame t (regions of t+1 whose minimum lies in `i` but
    /// which are not its successor); empty for an unknown label.
    pub fn fragments(&self, i: u32) -> &[u32] {
        i.checked_sub(1)
            .and_then(|k| self.fragments.get(k as usize))
            .map_or(&[], Vec::as_slice)
    }

    /// The bidirectional partner in frame t of region `j` of frame t+1, if any.
    pub fn predecessor(&self, j: u32) -> Option<u32> {
        let i = *self.backward.get(j.checked_sub(1)? as usize)?;
        (self.forward[i as usize - 1] == j).then_some(i)
    }
}

/// For each minimum of `from`, the label of `to` at its representative point.
fn lookup(from: &Segmentation, to: &Segmentation) -> Result<Vec<u32>, VisionError> {
    let k_to = to.n_regions() as u32;
    from.minima
        .iter()
        .map(|m| {
            let (x, y) = m.representative;
            match to.labels.get(x, y) {
                Some(&l) if (1..=k_to).contains(&l) => Ok(l),
                Some(&l) => Err(quarry_core::CoreError::invalid(
                    "label",
                    format!("{l} at ({x}, {y}) is not in 1..={k_to}"),
                )
                .into()),
                None => Err(quarry_core::CoreError::invalid(
                    "representative point",
                    format!("({x}, {y}) outside the image"),
                )
                .into()),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::{MinimumInfo, Plane};

    fn seg(w: u32, labels: Vec<u32>, reps: &[(u32, u32)]) -> Segmentation {
        let h = labels.len() as u32 / w;
        Segmentation {
            labels: Plane::from_vec(w, h, labels).unwrap(),
            minima: reps
                .iter()
                .enumerate()
                .map(|(i, &r)| MinimumInfo {
                    id: i as u32 + 1,
                    representative: r,
                    size: 1,
                    value: 0.0,
                })
                .collect(),
        }
    }

    #[test]
    fn merge_and_split() {
        // t: regions 1 (x<3) and 2 (x>=3) on a 6x1 strip; t+1: one region
        let a = seg(6, vec![1, 1, 1, 2, 2, 2], &[(1, 0), (4, 0)]);
        let b = seg(6, vec![1; 6], &[(2, 0)]);
        let m = RegionMapping::new(&a, &b).unwrap();
        assert_eq!(m.forward, vec![1, 1]);
        assert_eq!(m.backward, vec![1]);
        assert_eq!(m.bidirectional, vec![(1, 1)]);
        assert_eq!(m.merges, vec![1]);
        assert!(m.splits.is_empty());
        assert_eq!(m.successor(2), Some((1, LinkKind::Merge)));
        assert_eq!(m.successor(1), Some((1, LinkKind::Bidirectional)));
        // and the reverse direction is a split
        let r = RegionMapping::new(&b, &a).unwrap();
        assert_eq!(r.splits, vec![1]);
        assert!(r.merges.is_empty());
        assert_eq!(r.bidirectional, vec![(1, 1)]);
        assert_eq!(r.fragments(1), &[2]);
        assert_eq!(r.predecessor(2), None);
        assert_eq!(r.predecessor(1), Some(1));
    }

    #[test]
    fn errors() {
        let a = seg(2, vec![1, 1], &[(0, 0)]);
        let b = seg(1, vec![1, 1], &[(0, 0)]);
        assert!(RegionMapping::new(&a, &b).is_err());
        let c = seg(2, vec![1, 1], &[(5, 0)]);
        assert!(RegionMapping::new(&c, &a).is_err());
    }
}
