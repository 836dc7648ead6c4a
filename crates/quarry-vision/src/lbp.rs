//! Local binary patterns, P = 8, R = 1 (Ojala, Pietikäinen, Mäenpää, TPAMI 2002), spec 001 §2.5.
//!
//! **Convention (Ojala's).** The 8 neighbours of the 3×3 square are taken in circular order
//! `p = 0..8` = E, NE, N, NW, W, SW, S, SE (image rows run down, so NE is `(x+1, y−1)`), and bit `p`
//! of the code is set when `g_p ≥ g_c` (neighbour at least as bright as the centre). A constant image
//! therefore gives code 255 everywhere, riu2 class 8.
//!
//! This is *not* imageproc's `local_binary_pattern`, which sets a bit when the centre is strictly
//! brighter (the complement) and walks clockwise from N: its riu2 class `k` is our `8 − k` (9 stays 9).
//!
//! **Border.** Pixels in the first/last row and column have no full neighbourhood and no code:
//! [`lbp8_ojala`] writes 0 there (documented filler, not a code), and [`lbp_class_map`] writes
//! [`LBP_NO_CLASS`] so that histogram code skips them.
//!
//! **Mappings** ([`LbpMapping`]): `Riu2` (default, 10 classes: number of 1-bits for uniform codes,
//! 9 for the rest) and `U2` (59 classes: the 58 uniform codes in increasing code order get labels
//! 0..=57, every non-uniform code gets 58). A code is *uniform* when it has at most 2 circular 0↔1
//! transitions.
//!
//! ```
//! use quarry_core::Plane;
//! use quarry_vision::lbp::{LbpMapping, lbp8_ojala, lbp_class_map, LBP_NO_CLASS};
//! let flat = Plane::new(5, 4, 77u8);
//! let codes = lbp8_ojala(&flat)?;
//! assert_eq!(*codes.get(2, 2).unwrap(), 255);
//! let classes = lbp_class_map(&flat, LbpMapping::Riu2)?;
//! assert_eq!(*classes.get(2, 2).unwrap(), 8);
//! assert_eq!(*classes.get(0, 0).unwrap(), LBP_NO_CLASS);
//! # Ok::<(), quarry_vision::VisionError>(())
//! ```

use crate::VisionError;
use quarry_core::Plane;

/// Class written on border pixels by [`lbp_class_map`] (no code there).
pub const LBP_NO_CLASS: u8 = u8::MAX;

/// Neighbour offsets `(dx, dy)` in Ojala order: E, NE, N, NW, W, SW, S, SE.
pub const OJALA_OFFSETS: [(i32, i32); 8] = [
    (1, 0),
    (1, -1),
    (0, -1),
    (-1, -1),
    (-1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Number of circular 0↔1 transitions of an 8-bit code.
#[must_use]
pub const fn transitions(code: u8) -> u32 {
    (code ^ code.rotate_right(1)).count_ones()
}

const fn build_riu2() -> [u8; 256] {
    let mut t = [0u8; 256];
    let mut c = 0usize;
    while c < 256 {
        #[allow(clippy::cast_possible_truncation)]
        let code = c as u8;
        #[allow(clippy::cast_possible_truncation)]
        let ones = code.count_ones() as u8;
        t[c] = if transitions(code) <= 2 { ones } else { 9 };
        c += 1;
    }
    t
}

const fn build_u2() -> [u8; 256] {
    let mut t = [0u8; 256];
    let mut next = 0u8;
    let mut c = 0usize;
    while c < 256 {
        #[allow(clippy::cast_possible_truncation)]
        let code = c as u8;
        if transitions(code) <= 2 {
            t[c] = next;
            next += 1;
        } else {
            t[c] = 58;
        }
        c += 1;
    }
    t
}

/// Rotation-invariant uniform mapping: code → class in `0..10`.
pub const RIU2_TABLE: [u8; 256] = build_riu2();
/// Uniform mapping: code → class in `0..59`.
pub const U2_TABLE: [u8; 256] = build_u2();

/// Which LBP code → class mapping to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
pub enum LbpMapping {
    /// Rotation-invariant uniform, 10 classes (spec 001 default).
    #[default]
    Riu2,
    /// Uniform, 59 classes.
    U2,
}

impl LbpMapping {
    /// The const lookup table of this mapping.
    #[must_use]
    pub const fn table(self) -> &'static [u8; 256] {
        match self {
            Self::Riu2 => &RIU2_TABLE,
            Self::U2 => &U2_TABLE,
        }
    }

    /// Number of classes (histogram bins): 10 or 59.
    #[must_use]
    pub const fn n_classes(self) -> usize {
        match self {
            Self::Riu2 => 10,
            Self::U2 => 59,
        }
    }

    /// Class of one code.
    #[must_use]
    pub const fn class(self, code: u8) -> u8 {
        self.table()[code as usize]
    }
}

fn check_size(grey: &Plane<u8>, what: &'static str) -> Result<(), VisionError> {
    if grey.width < 3 || grey.height < 3 {
        return Err(VisionError::EmptyImage {
            what,
            width: grey.width,
            height: grey.height,
            min: 3,
        });
    }
    if grey.data.len() != grey.width as usize * grey.height as usize {
        return Err(quarry_core::CoreError::DimensionMismatch {
            what,
            expected: grey.width as usize * grey.height as usize,
            got: grey.data.len(),
        }
        .into());
    }
    Ok(())
}

/// Calls `f(index, code)` for every interior pixel.
fn for_each_code(grey: &Plane<u8>, mut f: impl FnMut(usize, u8)) {
    let w = grey.width as usize;
    let h = grey.height as usize;
    let d = &grey.data;
    for y in 1..h - 1 {
        let up = &d[(y - 1) * w..y * w];
        let mid = &d[y * w..(y + 1) * w];
        let down = &d[(y + 1) * w..(y + 2) * w];
        for x in 1..w - 1 {
            let c = mid[x];
            let code = u8::from(mid[x + 1] >= c)
                | u8::from(up[x + 1] >= c) << 1
                | u8::from(up[x] >= c) << 2
                | u8::from(up[x - 1] >= c) << 3
                | u8::from(mid[x - 1] >= c) << 4
                | u8::from(down[x - 1] >= c) << 5
                | u8::from(down[x] >= c) << 6
                | u8::from(down[x + 1] >= c) << 7;
            f(y * w + x, code);
        }
    }
}

/// LBP codes (P = 8, R = 1, Ojala bit order and `≥` test, see the module docs), same size as the
/// input; border pixels hold 0 (no code).
///
/// # Errors
/// [`VisionError::EmptyImage`] for an image smaller than 3×3, a dimension mismatch for a
/// malformed plane.
pub fn lbp8_ojala(grey: &Plane<u8>) -> Result<Plane<u8>, VisionError> {
    check_size(grey, "lbp8_ojala")?;
    let mut out = vec![0u8; grey.data.len()];
    for_each_code(grey, |i, code| out[i] = code);
    Ok(Plane::from_vec(grey.width, grey.height, out)?)
}

/// LBP class map of a grey image under `mapping`; border pixels hold [`LBP_NO_CLASS`].
///
/// # Errors
/// As [`lbp8_ojala`].
pub fn lbp_class_map(grey: &Plane<u8>, mapping: LbpMapping) -> Result<Plane<u8>, VisionError> {
    check_size(grey, "lbp_class_map")?;
    let table = mapping.table();
    let mut out = vec![LBP_NO_CLASS; grey.data.len()];
    for_each_code(grey, |i, code| out[i] = table[usize::from(code)]);
    Ok(Plane::from_vec(grey.width, grey.height, out)?)
}

/// Maps an existing code plane (from [`lbp8_ojala`]) to classes; border pixels get [`LBP_NO_CLASS`].
///
/// # Errors
/// As [`lbp8_ojala`].
pub fn codes_to_classes(codes: &Plane<u8>, mapping: LbpMapping) -> Result<Plane<u8>, VisionError> {
    check_size(codes, "codes_to_classes")?;
    let (w, h) = (codes.width, codes.height);
    let table = mapping.table();
    Ok(Plane::from_fn(w, h, |x, y| {
        if x == 0 || y == 0 || x == w - 1 || y == h - 1 {
            LBP_NO_CLASS
        } else {
            codes
                .get(x, y)
                .map_or(LBP_NO_CLASS, |&c| table[usize::from(c)])
        }
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Straightforward reference: neighbours through OJALA_OFFSETS.
    fn code_ref(g: &Plane<u8>, x: u32, y: u32) -> u8 {
        let c = *g.get(x, y).unwrap();
        let mut code = 0u8;
        for (p, (dx, dy)) in OJALA_OFFSETS.iter().enumerate() {
            let n = *g
                .get(x.wrapping_add_signed(*dx), y.wrapping_add_signed(*dy))
                .unwrap();
            if n >= c {
                code |= 1 << p;
            }
        }
        code
    }

    #[test]
    fn tables() {
        let uniform: Vec<u8> = (0..=255u8).filter(|&c| transitions(c) <= 2).collect();
        assert_eq!(uniform.len(), 58);
        // transitions are always even, so "U ≤ 2" is "U ∈ {0, 2}"
        assert!((0..=255u8).all(|c| transitions(c).is_multiple_of(2)));
        for c in 0..=255u8 {
            let riu2 = RIU2_TABLE[usize::from(c)];
            if transitions(c) <= 2 {
                assert_eq!(u32::from(riu2), c.count_ones());
            } else {
                assert_eq!(riu2, 9);
            }
        }
        let mut riu2_labels: Vec<u8> = RIU2_TABLE.to_vec();
        riu2_labels.sort_unstable();
        riu2_labels.dedup();
        assert_eq!(riu2_labels, (0..10).collect::<Vec<u8>>());
        let mut u2_uniform: Vec<u8> = uniform.iter().map(|&c| U2_TABLE[usize::from(c)]).collect();
        u2_uniform.sort_unstable();
        u2_uniform.dedup();
        assert_eq!(u2_uniform, (0..58).collect::<Vec<u8>>());
        assert!(
            (0..=255u8)
                .filter(|&c| transitions(c) > 2)
                .all(|c| U2_TABLE[usize::from(c)] == 58)
        );
        assert_eq!(LbpMapping::U2.n_classes(), 59);
        assert_eq!(LbpMapping::Riu2.n_classes(), 10);
        assert_eq!(LbpMapping::default(), LbpMapping::Riu2);
        // spot values
        assert_eq!(RIU2_TABLE[0b0000_1111], 4);
        assert_eq!(RIU2_TABLE[0b0101_0101], 9);
        assert_eq!(U2_TABLE[0], 0);
        assert_eq!(U2_TABLE[255], 57);
    }

    #[test]
    fn known_codes() {
        let flat = Plane::new(3, 3, 9u8);
        assert_eq!(*lbp8_ojala(&flat).unwrap().get(1, 1).unwrap(), 255);
        // only the east neighbour brighter, all others darker
        let mut g = Plane::new(3, 3, 0u8);
        g.set(1, 1, 100);
        g.set(2, 1, 200);
        assert_eq!(*lbp8_ojala(&g).unwrap().get(1, 1).unwrap(), 0b0000_0001);
        // north-east brighter -> bit 1
        let mut g = Plane::new(3, 3, 0u8);
        g.set(1, 1, 100);
        g.set(2, 0, 200);
        assert_eq!(*lbp8_ojala(&g).unwrap().get(1, 1).unwrap(), 0b0000_0010);
        // south-east -> bit 7
        let mut g = Plane::new(3, 3, 0u8);
        g.set(1, 1, 100);
        g.set(2, 2, 100);
        assert_eq!(*lbp8_ojala(&g).unwrap().get(1, 1).unwrap(), 0b1000_0000);
        let codes = lbp8_ojala(&flat).unwrap();
        assert_eq!(*codes.get(0, 0).unwrap(), 0);
    }

    #[test]
    fn errors() {
        assert!(lbp8_ojala(&Plane::new(2, 5, 0u8)).is_err());
        assert!(lbp_class_map(&Plane::new(5, 0, 0u8), LbpMapping::U2).is_err());
        let bad = Plane {
            width: 4,
            height: 4,
            data: vec![0u8; 3],
        };
        assert!(lbp8_ojala(&bad).is_err());
        assert!(codes_to_classes(&Plane::new(1, 1, 0u8), LbpMapping::Riu2).is_err());
    }

    fn image() -> impl Strategy<Value = Plane<u8>> {
        (3u32..12, 3u32..12).prop_flat_map(|(w, h)| {
            proptest::collection::vec(0u8..8, (w * h) as usize)
                .prop_map(move |d| Plane::from_vec(w, h, d).unwrap())
        })
    }

    fn rot90(g: &Plane<u8>) -> Plane<u8> {
        // counter-clockwise: new(x, y) = old(w - 1 - y, x), new size h×w
        let (w, h) = (g.width, g.height);
        Plane::from_fn(h, w, |x, y| *g.get(w - 1 - y, x).unwrap())
    }

    fn interior_hist(classes: &Plane<u8>, n: usize) -> Vec<u32> {
        let mut h = vec![0u32; n];
        for &c in &classes.data {
            if c != LBP_NO_CLASS {
                h[usize::from(c)] += 1;
            }
        }
        h
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        #[test]
        fn matches_reference_and_border(g in image()) {
            let codes = lbp8_ojala(&g).unwrap();
            let classes = lbp_class_map(&g, LbpMapping::U2).unwrap();
            prop_assert_eq!(&classes, &codes_to_classes(&codes, LbpMapping::U2).unwrap());
            for y in 0..g.height {
                for x in 0..g.width {
                    let border = x == 0 || y == 0 || x == g.width - 1 || y == g.height - 1;
                    if border {
                        prop_assert_eq!(*classes.get(x, y).unwrap(), LBP_NO_CLASS);
                    } else {
                        let c = code_ref(&g, x, y);
                        prop_assert_eq!(*codes.get(x, y).unwrap(), c);
                        prop_assert_eq!(*classes.get(x, y).unwrap(), U2_TABLE[usize::from(c)]);
                    }
                }
            }
        }

        /// Any strictly increasing grey lookup table leaves every code unchanged.
        #[test]
        fn monotone_lut_invariance(g in image(), steps in proptest::collection::vec(1u8..30, 8)) {
            let mut lut = [0u8; 8];
            let mut acc = 0u8;
            for (i, s) in steps.iter().enumerate() {
                acc = acc.saturating_add(*s);
                lut[i] = acc;
            }
            prop_assume!(lut.windows(2).all(|w| w[0] < w[1]));
            let mapped = g.map(|&v| lut[usize::from(v)]);
            prop_assert_eq!(lbp8_ojala(&g).unwrap(), lbp8_ojala(&mapped).unwrap());
        }

        /// A 90° rotation leaves the interior riu2 histogram unchanged.
        #[test]
        fn rotation_invariant_histogram(g in image()) {
            let a = interior_hist(&lbp_class_map(&g, LbpMapping::Riu2).unwrap(), 10);
            let b = interior_hist(&lbp_class_map(&rot90(&g), LbpMapping::Riu2).unwrap(), 10);
            prop_assert_eq!(a, b);
        }

        /// Spec 001 §6.1.4: our riu2 class is `8 − k` of imageproc's class `k` for uniform codes,
        /// and 9 maps to 9.
        #[test]
        fn imageproc_cross_check(g in image()) {
            let img = image::GrayImage::from_raw(g.width, g.height, g.data.clone()).unwrap();
            let ours = lbp_class_map(&g, LbpMapping::Riu2).unwrap();
            for y in 1..g.height - 1 {
                for x in 1..g.width - 1 {
                    let theirs = imageproc::local_binary_patterns::local_binary_pattern(&img, x, y).unwrap();
                    let k = RIU2_TABLE[usize::from(theirs)];
                    let expected = if k == 9 { 9 } else { 8 - k };
                    prop_assert_eq!(*ours.get(x, y).unwrap(), expected);
                }
            }
        }

        /// The complement convention (centre strictly brighter, as imageproc) gives riu2 class 8 − k
        /// for uniform codes and 9 for the rest.
        #[test]
        fn complement_convention(code in any::<u8>()) {
            let ours = RIU2_TABLE[usize::from(code)];
            let theirs = RIU2_TABLE[usize::from(!code)];
            if ours == 9 { prop_assert_eq!(theirs, 9); } else { prop_assert_eq!(theirs, 8 - ours); }
            // the order of the bits (clockwise vs counter-clockwise) does not change riu2
            prop_assert_eq!(RIU2_TABLE[usize::from(code.reverse_bits())], ours);
        }
    }
}
