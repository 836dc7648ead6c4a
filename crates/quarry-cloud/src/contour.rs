//! The human contour model of spec 003 §2.6: an ellipse (torso and arms cut at 1.2 m) sampled at
//! `K_m` points equally spaced along its perimeter, plus the helpers the tracker needs around an
//! ICP fit (removal ellipse, PCA start angle).

use quarry_core::{CoreError, Point2, Pose2};

use crate::error::Result;

/// An elliptical contour model. Model frame: x along the shoulder line (semi-axis `a`), y facing
/// forward (semi-axis `b`). `Default` is the `faithful` model: 0.22 × 0.13 m, 72 points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EllipseModel {
    /// Semi-axis along x (half the shoulder width), metres.
    pub a: f64,
    /// Semi-axis along y (half the chest depth), metres.
    pub b: f64,
    /// Number of model points `K_m`.
    pub k: usize,
}

impl Default for EllipseModel {
    fn default() -> Self {
        Self {
            a: 0.22,
            b: 0.13,
            k: 72,
        }
    }
}

impl EllipseModel {
    /// The `literal` model (16 points).
    pub fn literal() -> Self {
        Self {
            k: 16,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        if !(self.a.is_finite() && self.b.is_finite() && self.a > 0.0 && self.b > 0.0) {
            return Err(
                CoreError::invalid("ellipse semi-axes", "must be finite and positive").into(),
            );
        }
        if self.k < 3 {
            return Err(CoreError::invalid("k", "need at least 3 model points").into());
        }
        Ok(())
    }

    /// The `K_m` model points, equally spaced in arc length (numerical integration over 256
    /// sub-steps per point), starting at `(a, 0)` and running counter-clockwise. Use them with
    /// [`crate::icp::Icp2d::contour`], which reads them as a closed contour.
    ///
    /// ```
    /// use quarry_cloud::contour::EllipseModel;
    /// let m = EllipseModel::default().points()?;
    /// assert_eq!(m.len(), 72);
    /// assert!((m[0].x - 0.22).abs() < 1e-12 && m[0].y.abs() < 1e-12);
    /// # Ok::<(), quarry_cloud::CloudError>(())
    /// ```
    pub fn points(&self) -> Result<Vec<Point2>> {
        self.validate()?;
        let steps = 256 * self.k;
        let at = |t: f64| Point2::new(self.a * t.cos(), self.b * t.sin());
        // cumulative arc length on a fine polyline
        let mut cum = Vec::with_capacity(steps + 1);
        cum.push(0.0);
        let mut prev = at(0.0);
        for i in 1..=steps {
            let p = at(std::f64::consts::TAU * i as f64 / steps as f64);
            let last = cum[i - 1];
            cum.push(last + (p - prev).norm());
            prev = p;
        }
        let total = cum[steps];
        let mut out = Vec::with_capacity(self.k);
        let mut i = 0;
        for j in 0..self.k {
            let s = total * j as f64 / self.k as f64;
            while i + 1 < steps && cum[i + 1] < s {
                i += 1;
            }
            let seg = cum[i + 1] - cum[i];
            let f = if seg > 0.0 { (s - cum[i]) / seg } else { 0.0 };
            let t = std::f64::consts::TAU * (i as f64 + f) / steps as f64;
            out.push(at(t));
        }
        Ok(out)
    }

    /// The perimeter (Ramanujan's second approximation; relative error below 1e-9 for these
    /// aspect ratios).
    pub fn perimeter(&self) -> f64 {
        let (a, b) = (self.a, self.b);
        let h = ((a - b) / (a + b)).powi(2);
        std::f64::consts::PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()))
    }

    /// True when world point `q` lies inside the removal ellipse of a fit at `pose`: semi-axes
    /// inflated by `margin` (`r_m` = 0.10 m), i.e. `(u/(a + r_m))² + (v/(b + r_m))² ≤ 1` with
    /// `(u, v) = pose⁻¹ q`.
    pub fn removal_contains(&self, pose: &Pose2, q: &Point2, margin: f64) -> bool {
        let l = pose.apply_inverse(q);
        (l.x / (self.a + margin)).powi(2) + (l.y / (self.b + margin)).powi(2) <= 1.0
    }
}

/// The principal-axis angle `φ = ½·atan2(2C_xy, C_xx − C_yy)` of a point set (the ICP start
/// orientation for a new cluster; spec §2.6). Errors on fewer than 2 points or non-finite input.
pub fn pca_angle(points: &[Point2]) -> Result<f64> {
    if points.len() < 2 {
        return Err(CoreError::Empty {
            what: "PCA needs at least 2 points",
        }
        .into());
    }
    quarry_core::ensure_finite(points.iter().flat_map(|p| [&p.x, &p.y]), "PCA points")?;
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(x, y), p| (x + p.x, y + p.y));
    let (mx, my) = (mx / n, my / n);
    let (mut cxx, mut cyy, mut cxy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p.x - mx, p.y - my);
        cxx += dx * dx;
        cyy += dy * dy;
        cxy += dx * dy;
    }
    Ok(0.5 * (2.0 * cxy).atan2(cxx - cyy))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_arc_spacing() {
        let m = EllipseModel::default();
        let p = m.points().unwrap();
        let d: Vec<f64> = (0..p.len())
            .map(|i| (p[(i + 1) % p.len()] - p[i]).norm())
            .collect();
        let (lo, hi) = d
            .iter()
            .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
        // chords of equal arcs differ only by curvature: within 1 %
        assert!(hi / lo < 1.01, "{lo} {hi}");
        let poly: f64 = d.iter().sum();
        assert!((poly - m.perimeter()).abs() / m.perimeter() < 1e-3);
        // counter-clockwise: the second point has y > 0
        assert!(p[1].y > 0.0);
        assert!(EllipseModel { k: 2, ..m }.points().is_err());
        assert!(EllipseModel { a: f64::NAN, ..m }.points().is_err());
    }

    #[test]
    fn removal_and_pca() {
        let m = EllipseModel::default();
        let pose = Pose2::new(1.0, 1.0, std::f64::consts::FRAC_PI_2);
        assert!(m.removal_contains(&pose, &Point2::new(1.0, 1.31), 0.10));
        assert!(!m.removal_contains(&pose, &Point2::new(1.0, 1.33), 0.10));
        assert!(m.removal_contains(&pose, &Point2::new(1.22, 1.0), 0.10));
        assert!(!m.removal_contains(&pose, &Point2::new(1.24, 1.0), 0.10));
        let line: Vec<Point2> = (0..10)
            .map(|i| Point2::new(f64::from(i), f64::from(i)))
            .collect();
        assert!((pca_angle(&line).unwrap() - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!(pca_angle(&line[..1]).is_err());
    }
}
