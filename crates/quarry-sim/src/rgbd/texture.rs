//! Procedural colours and textures: HSV, value noise, the person silhouette, and the clothing
//! of the target, the pedestrian and the distractor.

use super::scene::Kind;

/// HSV (hue in degrees, saturation and value in `[0, 1]`) to RGB in `[0, 255]`.
pub(super) fn hsv(h: f64, s: f64, v: f64) -> [f64; 3] {
    let c = v * s;
    let hp = (h.rem_euclid(360.0)) / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [(r + m) * 255.0, (g + m) * 255.0, (b + m) * 255.0]
}

/// Value noise at 0.05 m cells, ±12 grey levels, bilinear.
pub(super) fn vnoise(a: f64, b: f64, salt: u64) -> f64 {
    let (fa, fb) = (a / 0.05, b / 0.05);
    let (ia, ib) = (fa.floor(), fb.floor());
    let (ta, tb) = (fa - ia, fb - ib);
    #[allow(clippy::cast_possible_truncation)]
    let lat = |i: f64, j: f64| {
        let mut z = (i as i64 as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ (j as i64 as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
            ^ salt;
        z = (z ^ (z >> 31)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^= z >> 29;
        #[allow(clippy::cast_precision_loss)]
        let u = (z >> 11) as f64 / (1u64 << 53) as f64;
        24.0 * u - 12.0
    };
    let v00 = lat(ia, ib);
    let v10 = lat(ia + 1.0, ib);
    let v01 = lat(ia, ib + 1.0);
    let v11 = lat(ia + 1.0, ib + 1.0);
    (v00 * (1.0 - ta) + v10 * ta) * (1.0 - tb) + (v01 * (1.0 - ta) + v11 * ta) * tb
}

/// `c` with `n` grey levels added to every channel.
pub(super) fn add(c: [f64; 3], n: f64) -> [f64; 3] {
    [c[0] + n, c[1] + n, c[2] + n]
}

/// Is `(s, h)` on a person silhouette (spec §5.2)? `d` is the distance walked.
pub(super) fn person_hit(s: f64, h: f64, d: f64) -> bool {
    let head = (s / 0.09).powi(2) + ((h - 1.58) / 0.12).powi(2) <= 1.0;
    let neck = s.abs() <= 0.05 && (1.45..=1.48).contains(&h);
    let torso = s.abs() <= 0.22 && (0.85..=1.45).contains(&h);
    let dl = 0.04 * (std::f64::consts::TAU * d / 1.2).sin();
    let legs = (0.0..0.85).contains(&h)
        && ((0.02..=0.18).contains(&(s - dl).abs()) || (0.02..=0.18).contains(&(s + dl).abs()));
    head || neck || torso || legs
}

/// The target's shirt: horizontal stripes in front, a different pattern on the back, blended
/// by `alpha` (0 = front, 1 = back).
pub(super) fn shirt_target(s: f64, h: f64, alpha: f64) -> [f64; 3] {
    let c1 = hsv(210.0, 0.7, 0.8);
    let c2 = hsv(40.0, 0.6, 0.9);
    let front = if (h / 0.10).floor() as i64 % 2 == 0 {
        c1
    } else {
        c2
    };
    let back = if s.abs() <= 0.05 || (h / 0.20).floor() as i64 % 2 != 0 {
        c2
    } else {
        c1
    };
    [0, 1, 2].map(|i| (1.0 - alpha) * front[i] + alpha * back[i])
}

/// Colour of a person billboard at `(s, h)`: hair, skin, then clothing by [`Kind`].
pub(super) fn person_colour(kind: Kind, s: f64, h: f64, alpha: f64) -> [f64; 3] {
    if h > 1.62 && (s / 0.09).powi(2) + ((h - 1.58) / 0.12).powi(2) <= 1.0 {
        return hsv(20.0, 0.5, 0.2);
    }
    if h > 1.45 {
        return hsv(25.0, 0.45, 0.85);
    }
    match kind {
        Kind::Pedestrian => {
            if h >= 0.85 {
                let k = (s / 0.08).floor() as i64 + (h / 0.08).floor() as i64;
                if k.rem_euclid(2) == 0 {
                    hsv(0.0, 0.7, 0.8)
                } else {
                    hsv(0.0, 0.0, 0.95)
                }
            } else {
                hsv(220.0, 0.5, 0.5)
            }
        }
        _ => {
            if h >= 0.85 {
                shirt_target(s, h, alpha)
            } else {
                add(hsv(0.0, 0.0, 0.2), vnoise(s, h, 7))
            }
        }
    }
}
