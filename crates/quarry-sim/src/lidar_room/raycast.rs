//! Ray intersections of the simulator: the distance along a beam `o + t·d` to a segment (walls,
//! box obstacles), a circle (round obstacles, arms) and an ellipse (torsos).

use quarry_core::Point2;

/// Distance along the ray `o + t·d` (`d` a unit vector) to segment `ab`, if it hits (`t > 0`).
pub fn ray_segment(o: Point2, d: [f64; 2], a: Point2, b: Point2) -> Option<f64> {
    let e = [b.x - a.x, b.y - a.y];
    let denom = d[0] * e[1] - d[1] * e[0];
    if denom.abs() < 1e-15 {
        return None;
    }
    let w = [a.x - o.x, a.y - o.y];
    let t = (w[0] * e[1] - w[1] * e[0]) / denom;
    let u = (w[0] * d[1] - w[1] * d[0]) / denom;
    (t > 1e-9 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// Distance along the ray `o + t·d` (`d` a unit vector) to the circle `(c, r)`, if it hits from
/// outside (the nearest positive root).
pub fn ray_circle(o: Point2, d: [f64; 2], c: Point2, r: f64) -> Option<f64> {
    let w = [o.x - c.x, o.y - c.y];
    let b = w[0] * d[0] + w[1] * d[1];
    let cc = w[0] * w[0] + w[1] * w[1] - r * r;
    let disc = b * b - cc;
    if disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    let t0 = -b - s;
    let t1 = -b + s;
    if t0 > 1e-9 {
        Some(t0)
    } else if t1 > 1e-9 {
        Some(t1)
    } else {
        None
    }
}

/// Distance along the ray `o + t·d` (`d` a unit vector) to the ellipse with centre `c`, semi-axes
/// `a` (along the ellipse's x axis, at angle `rot`) and `b`. Solved in the ellipse frame scaled by
/// `(1/a, 1/b)`, where it is a unit-circle quadratic (spec §5).
pub fn ray_ellipse(o: Point2, d: [f64; 2], c: Point2, a: f64, b: f64, rot: f64) -> Option<f64> {
    let (s, co) = rot.sin_cos();
    let wx = o.x - c.x;
    let wy = o.y - c.y;
    // into the ellipse frame, then scale
    let ox = (co * wx + s * wy) / a;
    let oy = (-s * wx + co * wy) / b;
    let dx = (co * d[0] + s * d[1]) / a;
    let dy = (-s * d[0] + co * d[1]) / b;
    let qa = dx * dx + dy * dy;
    let qb = ox * dx + oy * dy;
    let qc = ox * ox + oy * oy - 1.0;
    let disc = qb * qb - qa * qc;
    if disc < 0.0 {
        return None;
    }
    let sq = disc.sqrt();
    let t0 = (-qb - sq) / qa;
    let t1 = (-qb + sq) / qa;
    if t0 > 1e-9 {
        Some(t0)
    } else if t1 > 1e-9 {
        Some(t1)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn ray_segment_hits_wall_analytically() {
        let o = Point2::new(1.0, 1.0);
        let ang = 30f64.to_radians();
        let d = [ang.cos(), ang.sin()];
        // wall x = 5 from y = -10 to 10: t = 4 / cos 30
        let t = ray_segment(o, d, Point2::new(5.0, -10.0), Point2::new(5.0, 10.0)).unwrap();
        assert!((t - 4.0 / ang.cos()).abs() < 1e-12);
        // behind the origin: no hit
        assert!(
            ray_segment(
                o,
                [-1.0, 0.0],
                Point2::new(5.0, -10.0),
                Point2::new(5.0, 10.0)
            )
            .is_none()
        );
    }

    #[test]
    fn ray_circle_and_ellipse_analytic() {
        let o = Point2::new(0.0, 0.0);
        let t = ray_circle(o, [1.0, 0.0], Point2::new(5.0, 0.0), 0.5).unwrap();
        assert!((t - 4.5).abs() < 1e-12);
        // offset ray: y = 0.3 tangent distance: hit at x = 5 - sqrt(0.25 - 0.09) = 4.6
        let t = ray_circle(
            Point2::new(0.0, 0.3),
            [1.0, 0.0],
            Point2::new(5.0, 0.0),
            0.5,
        )
        .unwrap();
        assert!((t - 4.6).abs() < 1e-12);
        // ellipse a = 0.4 along x: hit at 5 - 0.4
        let t = ray_ellipse(o, [1.0, 0.0], Point2::new(5.0, 0.0), 0.4, 0.1, 0.0).unwrap();
        assert!((t - 4.6).abs() < 1e-12);
        // rotated by 90 deg: the 0.1 axis faces the ray
        let t = ray_ellipse(o, [1.0, 0.0], Point2::new(5.0, 0.0), 0.4, 0.1, PI / 2.0).unwrap();
        assert!((t - 4.9).abs() < 1e-12);
        // equals the circle when a = b
        let t1 = ray_ellipse(o, [0.6, 0.8], Point2::new(3.0, 4.2), 0.3, 0.3, 0.7);
        let t2 = ray_circle(o, [0.6, 0.8], Point2::new(3.0, 4.2), 0.3);
        assert!((t1.unwrap() - t2.unwrap()).abs() < 1e-12);
    }
}
