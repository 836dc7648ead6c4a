//! Regional minima (watershed seeds), spec 004 §2.4.
//!
//! A regional minimum is a maximal connected plateau (exact equality of values) with no
//! strictly lower neighbour. Plateaus of any size and shape are handled. Minima are numbered
//! 1..K in raster order of their first pixel; the representative point of a minimum is its pixel
//! closest (Euclidean) to the plateau's centroid, ties to the first in raster order, so it always
//! lies inside the minimum.

use crate::VisionError;
use quarry_core::{MinimumInfo, Plane};

/// Pixel neighbourhood.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum Connectivity {
    /// N, W, E, S.
    Four,
    /// The 8 neighbours, in spec 004's fixed order (−1,−1), (0,−1), (1,−1), (−1,0), (1,0),
    /// (−1,1), (0,1), (1,1).
    #[default]
    Eight,
}

const N8: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];
const N4: [(i32, i32); 4] = [(0, -1), (-1, 0), (1, 0), (0, 1)];

impl Connectivity {
    /// The neighbour offsets `(dx, dy)` in the fixed visiting order.
    pub fn offsets(self) -> &'static [(i32, i32)] {
        match self {
            Connectivity::Four => &N4,
            Connectivity::Eight => &N8,
        }
    }
}

/// Values a relief may hold: compared with `<`/`==`, converted to f64 for reports.
pub trait Relief: Copy + PartialOrd + Send + Sync + 'static {
    /// The value as f64.
    fn to_f64(self) -> f64;
}
impl Relief for f64 {
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}
impl Relief for f32 {
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}
impl Relief for u8 {
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}
impl Relief for u16 {
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}

/// The regional minima of a relief.
#[derive(Debug, Clone, PartialEq)]
pub struct Minima {
    /// `k` on the pixels of minimum `k`, 0 elsewhere.
    pub labels: Plane<u32>,
    /// The minima, `minima[k − 1]` has id `k`.
    pub minima: Vec<MinimumInfo>,
}

impl Minima {
    /// Number of minima.
    pub fn len(&self) -> usize {
        self.minima.len()
    }
    /// True when there is no minimum (only for an empty relief, which is rejected).
    pub fn is_empty(&self) -> bool {
        self.minima.is_empty()
    }
}

/// Validates a relief: non-empty, consistent length, finite values.
pub(crate) fn check_relief<T: Relief>(
    relief: &Plane<T>,
    what: &'static str,
) -> Result<(), VisionError> {
    if relief.width == 0 || relief.height == 0 {
        return Err(VisionError::EmptyImage {
            what,
            width: relief.width,
            height: relief.height,
            min: 1,
        });
    }
    quarry_core::ensure_len(
        relief.data.len(),
        relief.width as usize * relief.height as usize,
        "plane data length (width * height)",
    )?;
    if relief.width as u64 * relief.height as u64 >= u64::from(u32::MAX) {
        return Err(VisionError::TooLarge {
            what,
            width: relief.width,
            height: relief.height,
            limit: u64::from(u32::MAX) - 1,
        });
    }
    if !relief.data.iter().all(|v| v.to_f64().is_finite()) {
        return Err(VisionError::NonFinite(what));
    }
    Ok(())
}

/// Finds the regional minima of `relief` (Algorithm RM of spec 004 §2.4), O(n).
///
/// Errors: empty plane, NaN/infinite values, more than 2³² − 2 pixels.
pub fn regional_minima<T: Relief>(
    relief: &Plane<T>,
    connectivity: Connectivity,
) -> Result<Minima, VisionError> {
    check_relief(relief, "regional minima")?;
    let (w, h) = (relief.width as usize, relief.height as usize);
    let d = &relief.data;
    let offs = connectivity.offsets();
    // `done`: pixel already classified as part of a flooded plateau (or a single-pixel minimum)
    let mut labels = vec![0u32; w * h];
    let mut done = vec![false; w * h];
    let mut minima = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let mut plateau: Vec<usize> = Vec::new();
    let mut in_plateau = vec![false; 0];
    let lin: Vec<isize> = offs
        .iter()
        .map(|&(dx, dy)| dy as isize * w as isize + dx as isize)
        .collect();
    for y in 0..h {
        let row_inside = y > 0 && y + 1 < h;
        for x in 0..w {
            let p = y * w + x;
            if done[p] {
                continue;
            }
            let v = d[p];
            // fast path: classify with the neighbours. A pixel with a lower neighbour is not a
            // minimum, nor is any plateau containing it (a plateau member reached later floods
            // the plateau and finds that neighbour), so it needs no bookkeeping.
            let mut lower = false;
            let mut equal = false;
            if row_inside && x > 0 && x + 1 < w {
                for &o in &lin {
                    let u = d[p.wrapping_add_signed(o)];
                    if u < v {
                        lower = true;
                        break;
                    }
                    equal |= u == v;
                }
            } else {
                for &(dx, dy) in offs {
                    let (qx, qy) = (x as isize + dx as isize, y as isize + dy as isize);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        continue;
                    }
                    let u = d[qy as usize * w + qx as usize];
                    if u < v {
                        lower = true;
                        break;
                    }
                    equal |= u == v;
                }
            }
            if lower {
                continue;
            }
            if !equal {
                done[p] = true;
                let id = minima.len() as u32 + 1;
                labels[p] = id;
                minima.push(MinimumInfo {
                    id,
                    representative: (x as u32, y as u32),
                    size: 1,
                    value: v.to_f64(),
                });
                continue;
            }
            // plateau: flood the equal-valued component (BFS/DFS order does not matter for the
            // set), checking for lower outer neighbours
            if in_plateau.is_empty() {
                in_plateau = vec![false; w * h];
            }
            plateau.clear();
            stack.clear();
            stack.push(p);
            in_plateau[p] = true;
            let mut is_min = true;
            while let Some(c) = stack.pop() {
                plateau.push(c);
                let (cx, cy) = ((c % w) as isize, (c / w) as isize);
                for &(dx, dy) in offs {
                    let (qx, qy) = (cx + dx as isize, cy + dy as isize);
                    if qx < 0 || qy < 0 || qx >= w as isize || qy >= h as isize {
                        continue;
                    }
                    let q = qy as usize * w + qx as usize;
                    let u = d[q];
                    if u == v {
                        if !in_plateau[q] {
                            in_plateau[q] = true;
                            stack.push(q);
                        }
                    } else if u < v {
                        is_min = false;
                    }
                }
            }
            for &c in &plateau {
                done[c] = true;
                in_plateau[c] = false;
            }
            if is_min {
                plateau.sort_unstable();
                let id = minima.len() as u32 + 1;
                for &c in &plateau {
                    labels[c] = id;
                }
                minima.push(MinimumInfo {
                    id,
                    representative: representative(&plateau, w),
                    size: plateau.len(),
                    value: v.to_f64(),
                });
            }
        }
    }
    Ok(Minima {
        labels: Plane {
            width: relief.width,
            height: relief.height,
            data: labels,
        },
        minima,
    })
}

/// The pixel of a (raster-sorted) plateau closest to its centroid, ties to the first.
fn representative(sorted: &[usize], w: usize) -> (u32, u32) {
    let n = sorted.len() as f64;
    let (sx, sy) = sorted.iter().fold((0.0, 0.0), |(sx, sy), &c| {
        (sx + (c % w) as f64, sy + (c / w) as f64)
    });
    let (mx, my) = (sx / n, sy / n);
    let mut best = (f64::INFINITY, 0usize);
    for &c in sorted {
        let (dx, dy) = ((c % w) as f64 - mx, (c / w) as f64 - my);
        let d2 = dx * dx + dy * dy;
        if d2 < best.0 {
            best = (d2, c);
        }
    }
    ((best.1 % w) as u32, (best.1 / w) as u32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_pixel_minima() {
        let p = Plane::from_vec(
            4,
            3,
            vec![5.0, 4.0, 5.0, 6.0, 5.0, 5.0, 6.0, 1.0, 9.0, 9.0, 9.0, 2.0],
        )
        .unwrap();
        let m = regional_minima(&p, Connectivity::Eight).unwrap();
        // (1,0) = 4 has neighbour 5s only -> minimum; (3,1)=1 -> minimum; (3,2)=2 touches 1 -> no
        assert_eq!(m.len(), 2);
        assert_eq!(m.minima[0].representative, (1, 0));
        assert_eq!(m.minima[1].representative, (3, 1));
        assert_eq!(m.minima[1].value, 1.0);
        assert_eq!(*m.labels.get(3, 1).unwrap(), 2);
        assert_eq!(m.labels.data.iter().filter(|&&l| l > 0).count(), 2);
    }

    #[test]
    fn flat_image_is_one_minimum() {
        let p = Plane::new(5, 4, 3u8);
        let m = regional_minima(&p, Connectivity::Eight).unwrap();
        assert_eq!(m.len(), 1);
        assert_eq!(m.minima[0].size, 20);
        // centroid (2, 1.5): (2,1) and (2,2) tie, first in raster order wins
        assert_eq!(m.minima[0].representative, (2, 1));
    }

    #[test]
    fn plateau_with_lower_neighbour_is_not_minimum() {
        // a plateau of 2s touching a 1 diagonally: not a minimum under 8-, a minimum under 4-conn.
        #[rustfmt::skip]
        let p = Plane::from_vec(4, 4, vec![
            9u8, 9, 9, 9,
            9, 2, 2, 9,
            9, 2, 2, 9,
            9, 9, 9, 1,
        ]).unwrap();
        let m8 = regional_minima(&p, Connectivity::Eight).unwrap();
        assert_eq!(m8.len(), 1);
        assert_eq!(m8.minima[0].representative, (3, 3));
        let m4 = regional_minima(&p, Connectivity::Four).unwrap();
        assert_eq!(m4.len(), 2);
        assert_eq!(m4.minima[0].size, 4);
        assert_eq!(m4.minima[0].representative, (1, 1));
    }

    #[test]
    fn errors() {
        assert!(matches!(
            regional_minima(&Plane::<f64>::new(0, 3, 0.0), Connectivity::Eight),
            Err(VisionError::EmptyImage { .. })
        ));
        let mut p = Plane::new(3, 3, 0.0f64);
        p.set(1, 1, f64::NAN);
        assert!(matches!(
            regional_minima(&p, Connectivity::Eight),
            Err(VisionError::NonFinite(_))
        ));
    }
}
