//! Polar scans: beam geometry helpers and polar → Cartesian conversion (spec 003 §2.1).
//!
//! A scan is a [`PolarScan`] (ranges in millimetres, 0 = no return) with its [`ScanGeometry`]
//! (any beam count, field of view and resolution; [`ScanGeometry::utm30lx`] is the paper's
//! Hokuyo UTM-30LX preset with 1081 beams). [`BeamTable`] caches each beam's cosine and sine so
//! that per-scan conversion is a multiply-add per beam.

use quarry_core::{CoreError, Point2, PolarScan, Pose2, ScanGeometry};

use crate::error::Result;

/// Range noise standard deviation of the UTM-30LX (spec 003 §2.1, datasheet repeatability):
/// 0.010 m up to 10 m, 0.030 m beyond.
#[inline]
pub fn sigma_d(d: f64) -> f64 {
    if d <= 10.0 { 0.010 } else { 0.030 }
}

/// A geometry from a field of view centred on the sensor's +x axis: `n_beams` beams spread
/// evenly over `fov` radians (first beam at `-fov/2`, last at `+fov/2`).
///
/// ```
/// use quarry_cloud::scan::geometry_from_fov;
/// let g = geometry_from_fov(1081, 270f64.to_radians(), 0.1, 30.0, 0.025)?;
/// assert!((g.angle_increment - 0.25f64.to_radians()).abs() < 1e-15);
/// assert!((g.angle(540)).abs() < 1e-12);
/// # Ok::<(), quarry_cloud::CloudError>(())
/// ```
pub fn geometry_from_fov(
    n_beams: u32,
    fov: f64,
    range_min: f64,
    range_max: f64,
    scan_period: f64,
) -> Result<ScanGeometry> {
    if n_beams < 2 {
        return Err(
            CoreError::invalid("n_beams", "need at least 2 beams to span a field of view").into(),
        );
    }
    if !(fov.is_finite() && fov > 0.0 && fov <= std::f64::consts::TAU) {
        return Err(CoreError::invalid("fov", "must be in (0, 2pi]").into());
    }
    if !(scan_period.is_finite() && scan_period > 0.0) {
        return Err(CoreError::invalid("scan_period", "must be finite and positive").into());
    }
    let g = ScanGeometry {
        n_beams,
        angle_min: -fov / 2.0,
        angle_increment: fov / f64::from(n_beams - 1),
        range_min,
        range_max,
        scan_period,
    };
    g.validate()?;
    Ok(g)
}

/// The beam whose angle is closest to the sensor's +x axis (540 for the UTM-30LX), or `None`
/// when +x is outside the field of view.
pub fn front_step(g: &ScanGeometry) -> Option<u32> {
    let n = (-g.angle_min / g.angle_increment).round();
    (n >= 0.0 && n < f64::from(g.n_beams)).then_some(n as u32)
}

/// Per-beam cosines and sines of a geometry, for fast polar → Cartesian conversion.
#[derive(Debug, Clone, PartialEq)]
pub struct BeamTable {
    geometry: ScanGeometry,
    cos: Vec<f64>,
    sin: Vec<f64>,
}

impl BeamTable {
    /// Builds the table (validates the geometry).
    pub fn new(geometry: &ScanGeometry) -> Result<Self> {
        geometry.validate()?;
        let (sin, cos) = (0..geometry.n_beams)
            .map(|n| geometry.angle(n).sin_cos())
            .unzip();
        Ok(Self {
            geometry: *geometry,
            cos,
            sin,
        })
    }

    /// The geometry this table was built for.
    pub fn geometry(&self) -> &ScanGeometry {
        &self.geometry
    }

    /// Number of beams.
    pub fn len(&self) -> usize {
        self.cos.len()
    }

    /// True when the table has no beams (never, for a validated geometry).
    pub fn is_empty(&self) -> bool {
        self.cos.is_empty()
    }

    /// The sensor-frame point of beam `n` at range `r` metres (eq. 2), `None` if `n` is out of
    /// range.
    #[inline]
    pub fn point(&self, n: usize, r: f64) -> Option<Point2> {
        Some(Point2::new(r * self.cos.get(n)?, r * self.sin.get(n)?))
    }

    /// Unit direction `(cos φ, sin φ)` of beam `n`.
    #[inline]
    pub fn direction(&self, n: usize) -> Option<(f64, f64)> {
        Some((*self.cos.get(n)?, *self.sin.get(n)?))
    }

    /// Converts a whole scan: one entry per beam, `Some(point)` in the frame of `pose` (the
    /// sensor's pose; [`Pose2::identity`] for the sensor frame) for valid returns, `None` for
    /// invalid ones (outside `[range_min, range_max]`, including 0 = no return).
    pub fn to_points(&self, scan: &PolarScan, pose: &Pose2) -> Result<Vec<Option<Point2>>> {
        check_scan(scan, &self.geometry)?;
        let (s, c) = pose.theta.sin_cos();
        Ok((0..scan.ranges_mm.len())
            .map(|n| {
                let r = scan.range_m(n)?;
                let (x, y) = (r * self.cos[n], r * self.sin[n]);
                Some(Point2::new(pose.x + c * x - s * y, pose.y + s * x + c * y))
            })
            .collect())
    }

    /// Converts the listed `(beam, range_mm)` pairs (a wire payload) to points in the frame of
    /// `pose`; pairs with an unknown beam or an invalid range are skipped and counted in the
    /// second return value.
    pub fn pairs_to_points(
        &self,
        pairs: &[(u16, u16)],
        pose: &Pose2,
    ) -> (Vec<(u16, Point2)>, usize) {
        let (s, c) = pose.theta.sin_cos();
        let mut skipped = 0;
        let mut out = Vec::with_capacity(pairs.len());
        for &(beam, mm) in pairs {
            let r = f64::from(mm) * 1e-3;
            let n = usize::from(beam);
            if n >= self.len() || r < self.geometry.range_min || r > self.geometry.range_max {
                skipped += 1;
                continue;
            }
            let (x, y) = (r * self.cos[n], r * self.sin[n]);
            out.push((
                beam,
                Point2::new(pose.x + c * x - s * y, pose.y + s * x + c * y),
            ));
        }
        (out, skipped)
    }
}

/// Checks that a scan matches a geometry (same beam count) and that the geometry is usable.
pub fn check_scan(scan: &PolarScan, geometry: &ScanGeometry) -> Result<()> {
    geometry.validate()?;
    quarry_core::ensure_len(
        scan.ranges_mm.len(),
        geometry.n_beams as usize,
        "scan beams",
    )?;
    Ok(())
}

/// Converts a range in metres to the millimetre code of [`PolarScan`]: `None` (no return) for
/// NaN, infinities, negatives, values outside `[range_min, range_max]` or above 65.534 m.
#[inline]
pub fn metres_to_mm(r: f64, geometry: &ScanGeometry) -> Option<u16> {
    if !r.is_finite() || r < geometry.range_min || r > geometry.range_max {
        return None;
    }
    let mm = (r * 1000.0).round();
    (mm >= 1.0 && mm <= f64::from(u16::MAX - 1)).then_some(mm as u16)
}

/// The valid returns of a scan as sensor-frame points with their beam index (a convenience over
/// [`BeamTable::to_points`] that drops invalid beams).
pub fn valid_points(scan: &PolarScan) -> Result<Vec<(usize, Point2)>> {
    let table = BeamTable::new(&scan.geometry)?;
    Ok(table
        .to_points(scan, &Pose2::identity())?
        .into_iter()
        .enumerate()
        .filter_map(|(n, p)| p.map(|p| (n, p)))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use quarry_core::{SensorId, TimeUs};

    #[test]
    fn utm_front_beam_is_plus_x() {
        let g = ScanGeometry::utm30lx();
        assert_eq!(front_step(&g), Some(540));
        let t = BeamTable::new(&g).unwrap();
        let p = t.point(540, 2.0).unwrap();
        assert!((p.x - 2.0).abs() < 1e-12 && p.y.abs() < 1e-12);
        let p0 = t.point(0, 1.0).unwrap();
        let a = -135f64.to_radians();
        assert!((p0.x - a.cos()).abs() < 1e-12 && (p0.y - a.sin()).abs() < 1e-12);
    }

    #[test]
    fn to_points_marks_invalid_and_applies_pose() {
        let g = ScanGeometry::utm30lx();
        let mut r = vec![0u16; 1081];
        r[540] = 1000;
        r[541] = 50; // below 0.1 m
        let scan = PolarScan::try_new(SensorId(0), 0, TimeUs(0), r, g).unwrap();
        let t = BeamTable::new(&g).unwrap();
        let pose = Pose2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2);
        let pts = t.to_points(&scan, &pose).unwrap();
        assert_eq!(pts.iter().filter(|p| p.is_some()).count(), 1);
        let p = pts[540].unwrap();
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 3.0).abs() < 1e-12);
    }

    #[test]
    fn wrong_beam_count_is_an_error() {
        let g = ScanGeometry::utm30lx();
        let scan = PolarScan {
            sensor: SensorId(0),
            seq: 0,
            t: TimeUs(0),
            ranges_mm: vec![0; 10],
            geometry: g,
        };
        assert!(
            BeamTable::new(&g)
                .unwrap()
                .to_points(&scan, &Pose2::identity())
                .is_err()
        );
    }

    #[test]
    fn metres_to_mm_rejects_bad_values() {
        let g = ScanGeometry::utm30lx();
        assert_eq!(metres_to_mm(f64::NAN, &g), None);
        assert_eq!(metres_to_mm(f64::INFINITY, &g), None);
        assert_eq!(metres_to_mm(0.05, &g), None);
        assert_eq!(metres_to_mm(31.0, &g), None);
        assert_eq!(metres_to_mm(1.2344, &g), Some(1234));
    }
}
