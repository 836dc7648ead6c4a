//! The ordered N×N patch grid of a box and its kernel-weighted patch histograms (spec 001 §2.4,
//! eq. 4).
//!
//! * [`PatchGrid`]: patch `n = r·N + q` (row `r`, column `q`) of box `B` covers columns
//!   `[left + round(q·W/N), left + round((q+1)·W/N))` with `left = round(c_u − W/2)`, and rows
//!   likewise (`f64::round`, halves away from zero). Cells are in image coordinates and may extend
//!   past the image; pixels outside are skipped when sampling.
//! * [`patch_histograms`]: for each cell, a colour and a texture histogram weighted by a
//!   [`PixelWeight`] (eq. 4). Map values at or above the bin count (e.g. `HueBinner::NO_BIN`,
//!   `LBP_NO_CLASS`) are skipped. A histogram is `None` (empty) when the summed weight of its
//!   counted pixels is below `m_min = max(10, 0.05 · nominal cell area)`.
//!
//! ```
//! use quarry_core::{BBox, Plane};
//! use quarry_vision::depth_weights::{DepthBand, DepthProfile};
//! use quarry_vision::patches::{FeatureMaps, PatchGrid, patch_histograms};
//! let colour = Plane::new(40, 40, 3u8);
//! let texture = Plane::new(40, 40, 8u8);
//! let depth = Plane::new(40, 40, 2.0f32);
//! let band = DepthBand::new(&depth, 2.0, 0.3, DepthProfile::Flat)?;
//! let maps = FeatureMaps { colour_bin: &colour, texture_class: &texture };
//! let h = patch_histograms(&maps, &BBox { cx: 20.0, cy: 20.0, w: 32.0, h: 32.0 }, PatchGrid::new(4)?, &band, 20, 10)?;
//! assert_eq!(h.colour.len(), 16);
//! assert_eq!(h.colour[5].as_ref().unwrap().bins()[3], 1.0);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use crate::depth_weights::PixelWeight;
use crate::histogram::Histogram;
use quarry_core::{BBox, CoreError, Plane};

/// An N×N patch grid (spec default N = 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatchGrid {
    /// Cells per side; at least 1.
    pub n: u32,
}

/// One cell of a [`PatchGrid`] in image coordinates: columns `x0..x1`, rows `y0..y1` (exclusive
/// ends, possibly outside the image).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PatchCell {
    /// First column.
    pub x0: i64,
    /// First row.
    pub y0: i64,
    /// One past the last column.
    pub x1: i64,
    /// One past the last row.
    pub y1: i64,
}

impl PatchCell {
    /// Nominal area `(x1 − x0)(y1 − y0)` in pixels, including any part outside the image.
    #[must_use]
    pub fn area(&self) -> i64 {
        (self.x1 - self.x0).max(0) * (self.y1 - self.y0).max(0)
    }
}

impl PatchGrid {
    /// A grid with `n` cells per side.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] for `n = 0`.
    pub fn new(n: u32) -> Result<Self, VisionError> {
        if n == 0 {
            return Err(
                CoreError::invalid("n", "patch grid needs at least 1 cell per side").into(),
            );
        }
        Ok(Self { n })
    }

    /// The `n²` cells of `bbox`, in order `r·N + q`.
    ///
    /// # Errors
    /// [`CoreError::InvalidParameter`] for `n = 0`, [`CoreError::NonFinite`] for a non-finite box,
    /// [`CoreError::InvalidParameter`] for a box whose rounded size is below `n` pixels on a side or
    /// larger than 2²⁴ pixels.
    #[allow(clippy::cast_possible_truncation)]
    pub fn cells(&self, bbox: &BBox) -> Result<Vec<PatchCell>, VisionError> {
        if self.n == 0 {
            return Err(
                CoreError::invalid("n", "patch grid needs at least 1 cell per side").into(),
            );
        }
        if ![bbox.cx, bbox.cy, bbox.w, bbox.h]
            .iter()
            .all(|v| v.is_finite())
        {
            return Err(CoreError::NonFinite {
                what: "patch grid box",
            }
            .into());
        }
        let lim = f64::from(1u32 << 24);
        let n = f64::from(self.n);
        if bbox.w.round() < n
            || bbox.h.round() < n
            || bbox.w > lim
            || bbox.h > lim
            || bbox.cx.abs() > lim
            || bbox.cy.abs() > lim
        {
            return Err(CoreError::invalid(
                "bbox",
                format!(
                    "size {}x{} must be ≥ {} px per side and ≤ 2^24",
                    bbox.w, bbox.h, self.n
                ),
            )
            .into());
        }
        let left = (bbox.cx - bbox.w / 2.0).round() as i64;
        let top = (bbox.cy - bbox.h / 2.0).round() as i64;
        let edge = |start: i64, size: f64, k: u32| start + (f64::from(k) * size / n).round() as i64;
        let mut out = Vec::with_capacity((self.n * self.n) as usize);
        for r in 0..self.n {
            for q in 0..self.n {
                out.push(PatchCell {
                    x0: edge(left, bbox.w, q),
                    x1: edge(left, bbox.w, q + 1),
                    y0: edge(top, bbox.h, r),
                    y1: edge(top, bbox.h, r + 1),
                });
            }
        }
        Ok(out)
    }
}

/// Per-pixel bin maps of one frame (same size).
#[derive(Debug, Clone, Copy)]
pub struct FeatureMaps<'a> {
    /// Colour-bin map (e.g. [`crate::colour::HueBinner::bin_map`]).
    pub colour_bin: &'a Plane<u8>,
    /// Texture-class map (e.g. [`crate::lbp::lbp_class_map`]).
    pub texture_class: &'a Plane<u8>,
}

/// The colour and texture histograms of each patch, in grid order; `None` = empty patch.
#[derive(Debug, Clone, PartialEq)]
pub struct PatchHistograms {
    /// Colour histogram per patch.
    pub colour: Vec<Option<Histogram>>,
    /// Texture histogram per patch.
    pub texture: Vec<Option<Histogram>>,
}

/// `m_min = max(10, 0.05 · area)` of a cell.
#[must_use]
#[allow(clippy::cast_precision_loss)]
pub fn min_weight(cell: &PatchCell) -> f64 {
    (0.05 * cell.area() as f64).max(10.0)
}

fn finish(acc: &[f64], m_min: f64) -> Result<Option<Histogram>, VisionError> {
    let sum: f64 = acc.iter().sum();
    if sum < m_min || sum <= 0.0 {
        return Ok(None);
    }
    #[allow(clippy::cast_possible_truncation)]
    let w: Vec<f32> = acc.iter().map(|&x| (x / sum) as f32).collect();
    Histogram::from_weights(&w).map(Some)
}

/// Kernel-weighted patch histograms (eq. 4) of `bbox` on `maps`.
///
/// # Errors
/// Maps of different sizes or empty, zero bin counts (or above 255), a bad grid or box
/// ([`PatchGrid::cells`]), or a non-finite / negative weight.
pub fn patch_histograms(
    maps: &FeatureMaps<'_>,
    bbox: &BBox,
    grid: PatchGrid,
    weight: &impl PixelWeight,
    n_colour: usize,
    n_texture: usize,
) -> Result<PatchHistograms, VisionError> {
    let (cm, tm) = (maps.colour_bin, maps.texture_class);
    if cm.dimensions() != tm.dimensions() {
        return Err(VisionError::SizeMismatch {
            what: "patch_histograms maps",
            a: cm.dimensions(),
            b: tm.dimensions(),
        });
    }
    if cm.width == 0 || cm.height == 0 {
        return Err(VisionError::EmptyImage {
            what: "patch_histograms",
            width: cm.width,
            height: cm.height,
            min: 1,
        });
    }
    let npx = cm.width as usize * cm.height as usize;
    quarry_core::ensure_len(cm.data.len(), npx, "colour map data")?;
    quarry_core::ensure_len(tm.data.len(), npx, "texture map data")?;
    for (name, n) in [("n_colour", n_colour), ("n_texture", n_texture)] {
        if n == 0 || n > 255 {
            return Err(CoreError::invalid(name, format!("must be in 1..=255, got {n}")).into());
        }
    }
    let cells = grid.cells(bbox)?;
    let mut out = PatchHistograms {
        colour: Vec::with_capacity(cells.len()),
        texture: Vec::with_capacity(cells.len()),
    };
    let mut ca = vec![0.0f64; n_colour];
    let mut ta = vec![0.0f64; n_texture];
    let (w, h) = (i64::from(cm.width), i64::from(cm.height));
    for cell in &cells {
        ca.fill(0.0);
        ta.fill(0.0);
        for y in cell.y0.clamp(0, h)..cell.y1.clamp(0, h) {
            for x in cell.x0.clamp(0, w)..cell.x1.clamp(0, w) {
                #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
                let (xu, yu) = (x as u32, y as u32);
                let k = weight.weight(xu, yu);
                if !k.is_finite() || k < 0.0 {
                    return Err(
                        CoreError::invalid("pixel weight", format!("{k} at ({x}, {y})")).into(),
                    );
                }
                if k == 0.0 {
                    continue;
                }
                #[allow(clippy::cast_sign_loss, clippy::cast_possible_truncation)]
                let i = (y * w + x) as usize;
                let c = usize::from(cm.data[i]);
                if c < n_colour {
                    ca[c] += f64::from(k);
                }
                let t = usize::from(tm.data[i]);
                if t < n_texture {
                    ta[t] += f64::from(k);
                }
            }
        }
        let m_min = min_weight(cell);
        out.colour.push(finish(&ca, m_min)?);
        out.texture.push(finish(&ta, m_min)?);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    struct Ones;
    impl PixelWeight for Ones {
        fn weight(&self, _: u32, _: u32) -> f32 {
            1.0
        }
    }
    struct Table(Plane<f32>, f32);
    impl PixelWeight for Table {
        fn weight(&self, u: u32, v: u32) -> f32 {
            self.0.get(u, v).map_or(0.0, |w| w * self.1)
        }
    }

    #[test]
    fn cells_follow_spec() {
        let g = PatchGrid::new(4).unwrap();
        let c = g
            .cells(&BBox {
                cx: 50.0,
                cy: 40.0,
                w: 70.0,
                h: 30.0,
            })
            .unwrap();
        assert_eq!(c.len(), 16);
        // left = 15, edges 15 + round(k·17.5) = 15, 33 (17.5 → 18), 50, 68 (52.5 → 53), 85
        assert_eq!(
            [c[0].x0, c[0].x1, c[1].x1, c[2].x1, c[3].x1],
            [15, 33, 50, 68, 85]
        );
        assert_eq!(
            [c[0].y0, c[4].y0, c[8].y0, c[12].y0, c[12].y1],
            [25, 33, 40, 48, 55]
        );
        assert!(PatchGrid::new(0).is_err());
        assert!(
            g.cells(&BBox {
                cx: f64::NAN,
                cy: 0.0,
                w: 10.0,
                h: 10.0
            })
            .is_err()
        );
        assert!(
            g.cells(&BBox {
                cx: 0.0,
                cy: 0.0,
                w: 3.0,
                h: 10.0
            })
            .is_err()
        );
    }

    #[test]
    fn errors_and_empty() {
        let a = Plane::new(10, 10, 0u8);
        let b = Plane::new(10, 9, 0u8);
        let bx = BBox {
            cx: 5.0,
            cy: 5.0,
            w: 8.0,
            h: 8.0,
        };
        let g = PatchGrid::new(2).unwrap();
        assert!(
            patch_histograms(
                &FeatureMaps {
                    colour_bin: &a,
                    texture_class: &b
                },
                &bx,
                g,
                &Ones,
                20,
                10
            )
            .is_err()
        );
        let m = FeatureMaps {
            colour_bin: &a,
            texture_class: &a,
        };
        assert!(patch_histograms(&m, &bx, g, &Ones, 0, 10).is_err());
        assert!(
            patch_histograms(
                &m,
                &bx,
                g,
                &Table(Plane::new(10, 10, f32::NAN), 1.0),
                20,
                10
            )
            .is_err()
        );
        // 4×4 cells = 16 px < m_min = 10? no: 16 ≥ 10 → present; box far outside → all empty
        let h = patch_histograms(&m, &bx, g, &Ones, 20, 10).unwrap();
        assert!(h.colour.iter().all(Option::is_some));
        let far = BBox {
            cx: 500.0,
            cy: 5.0,
            w: 8.0,
            h: 8.0,
        };
        let h = patch_histograms(&m, &far, g, &Ones, 20, 10).unwrap();
        assert!(h.colour.iter().chain(&h.texture).all(Option::is_none));
        // NO_BIN values skipped: texture all 255 → empty
        let t = Plane::new(10, 10, 255u8);
        let h = patch_histograms(
            &FeatureMaps {
                colour_bin: &a,
                texture_class: &t,
            },
            &bx,
            g,
            &Ones,
            20,
            10,
        )
        .unwrap();
        assert!(h.texture.iter().all(Option::is_none) && h.colour.iter().all(Option::is_some));
    }

    fn scene() -> impl Strategy<Value = (Plane<u8>, Plane<u8>, Plane<f32>, BBox)> {
        (8u32..30, 8u32..30).prop_flat_map(|(w, h)| {
            let n = (w * h) as usize;
            (
                proptest::collection::vec(0u8..22, n),
                proptest::collection::vec(0u8..11, n),
                proptest::collection::vec(prop_oneof![Just(0.0f32), 0.0f32..3.0], n),
                -5.0f64..35.0,
                -5.0f64..35.0,
                4.0f64..30.0,
                4.0f64..30.0,
            )
                .prop_map(move |(c, t, k, cx, cy, bw, bh)| {
                    (
                        Plane::from_vec(w, h, c).unwrap(),
                        Plane::from_vec(w, h, t).unwrap(),
                        Plane::from_vec(w, h, k).unwrap(),
                        BBox {
                            cx,
                            cy,
                            w: bw,
                            h: bh,
                        },
                    )
                })
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(96))]

        /// Spec 001 §6.1.1: normalised, None exactly when the weight sum is below m_min, and
        /// invariant to scaling the weight (bit-identical for powers of two).
        #[test]
        fn histogram_invariants((c, t, k, bx) in scene(), scale in 0.1f32..10.0) {
            let grid = PatchGrid::new(2).unwrap();
            let maps = FeatureMaps { colour_bin: &c, texture_class: &t };
            let base = patch_histograms(&maps, &bx, grid, &Table(k.clone(), 1.0), 20, 10).unwrap();
            let cells = grid.cells(&bx).unwrap();
            for (i, cell) in cells.iter().enumerate() {
                // brute-force weight sums of counted pixels
                let (mut sc, mut st) = (0.0f64, 0.0f64);
                for y in 0..c.height {
                    for x in 0..c.width {
                        let (xi, yi) = (i64::from(x), i64::from(y));
                        if xi >= cell.x0 && xi < cell.x1 && yi >= cell.y0 && yi < cell.y1 {
                            let kw = f64::from(*k.get(x, y).unwrap());
                            if *c.get(x, y).unwrap() < 20 { sc += kw; }
                            if *t.get(x, y).unwrap() < 10 { st += kw; }
                        }
                    }
                }
                let m_min = min_weight(cell);
                prop_assert_eq!(base.colour[i].is_none(), sc < m_min);
                prop_assert_eq!(base.texture[i].is_none(), st < m_min);
                for h in base.colour[i].iter().chain(&base.texture[i]) {
                    prop_assert!(h.bins().iter().all(|&x| x >= 0.0));
                    let s: f32 = h.bins().iter().sum();
                    prop_assert!((s - 1.0).abs() < 1e-5);
                }
            }
            let pow2 = patch_histograms(&maps, &bx, grid, &Table(k.clone(), 4.0), 20, 10).unwrap();
            for (a, b) in base.colour.iter().zip(&pow2.colour).chain(base.texture.iter().zip(&pow2.texture)) {
                if let (Some(a), Some(b)) = (a, b) { prop_assert_eq!(a, b); }
            }
            let scaled = patch_histograms(&maps, &bx, grid, &Table(k, scale), 20, 10).unwrap();
            for (a, b) in base.colour.iter().zip(&scaled.colour).chain(base.texture.iter().zip(&scaled.texture)) {
                if let (Some(a), Some(b)) = (a, b) {
                    for (x, y) in a.bins().iter().zip(b.bins()) { prop_assert!((x - y).abs() <= 1e-6); }
                }
            }
        }

        /// The cells tile [left, left + round(W)) × [top, top + round(H)) without gaps or overlap.
        #[test]
        fn cells_tile_box(cx in -50.0f64..50.0, cy in -50.0f64..50.0, w in 4.0f64..300.0, h in 4.0f64..300.0, n in 1u32..6) {
            prop_assume!(w.round() >= f64::from(n) && h.round() >= f64::from(n));
            let cells = PatchGrid::new(n).unwrap().cells(&BBox { cx, cy, w, h }).unwrap();
            let total: i64 = cells.iter().map(PatchCell::area).sum();
            let bw = cells[n as usize - 1].x1 - cells[0].x0;
            let bh = cells[cells.len() - 1].y1 - cells[0].y0;
            prop_assert_eq!(total, bw * bh);
            prop_assert!((bw as f64 - w).abs() <= 1.0 && (bh as f64 - h).abs() <= 1.0);
            for r in 0..n as usize {
                for q in 1..n as usize {
                    let i = r * n as usize + q;
                    prop_assert_eq!(cells[i].x0, cells[i - 1].x1);
                    prop_assert!(cells[i].x1 > cells[i].x0);
                }
            }
        }
    }
}
