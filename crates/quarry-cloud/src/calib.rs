//! Extrinsic calibration of the scanners (spec 003 §2.3): poses given in the configuration, or
//! trimmed point-to-point ICP between the scanners' static backgrounds from rough initial poses.
//!
//! ICP mode: the reference scanner's background, placed with its configured pose, starts the
//! union `U`. Repeatedly, the remaining scanner whose background (at its rough pose) overlaps `U`
//! most is registered against `U` (kd-tree on `U`; correspondence distance schedule 1.0, 0.5,
//! 0.25, 0.10 m; each stage until ΔRMS < 1e-5 m or 50 iterations; the best 80 % of the pairs
//! kept), accepted if the overlap (pairs within 0.10 m ÷ |B_s|) is at least 0.3 and the inlier
//! RMS at most 0.03 m, and then added to `U`. Correspondences are point-to-line (see
//! [`register_background`]); each step is the closed-form solve of §2.6.

use std::collections::BTreeMap;

use quarry_core::{CoreError, Point2, Pose2, ScanGeometry, SensorId};

use crate::contour::pca_angle;
use crate::error::{CloudError, Result};
use crate::kd::KdIndex;
use crate::scan::BeamTable;

/// Calibration parameters (spec 003 §2.3). `Default` is the spec's values.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibConfig {
    /// Maximum correspondence distance per stage, metres.
    pub stages: Vec<f64>,
    /// Stage stop on RMS improvement, metres.
    pub delta_stop: f64,
    /// Iterations per stage.
    pub max_iter: u32,
    /// Fraction of pairs kept (trimmed ICP).
    pub keep_fraction: f64,
    /// Distance defining overlap and inliers, metres.
    pub inlier_dist: f64,
    /// Minimum overlap to accept.
    pub min_overlap: f64,
    /// Maximum inlier RMS to accept, metres.
    pub max_rms: f64,
    /// Background beams at or beyond this range are not used, metres.
    pub max_background_range: f64,
    /// Point-to-line pairs with Gauss-Newton steps (Censi 2008; default `true`), or the spec's
    /// plain point-to-point pairs with the closed-form solve of §2.6 (`false`, kept to measure
    /// the difference).
    pub point_to_line: bool,
}

impl Default for CalibConfig {
    fn default() -> Self {
        Self {
            stages: vec![1.0, 0.5, 0.25, 0.10],
            delta_stop: 1e-5,
            max_iter: 50,
            keep_fraction: 0.8,
            inlier_dist: 0.10,
            min_overlap: 0.3,
            max_rms: 0.03,
            max_background_range: 28.5,
            point_to_line: true,
        }
    }
}

/// A scanner to calibrate: its background points in its own frame and a rough pose (within
/// about 0.5 m and 15° of the truth).
#[derive(Debug, Clone, PartialEq)]
pub struct ScannerBackground {
    /// Which scanner.
    pub sensor: SensorId,
    /// Background points, sensor frame.
    pub points: Vec<Point2>,
    /// Rough (hand-measured) pose; for the reference scanner, its exact configured pose.
    pub pose: Pose2,
}

/// The calibrated pose of one scanner.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibResult {
    /// Which scanner.
    pub sensor: SensorId,
    /// Its pose in the world frame.
    pub pose: Pose2,
    /// Fraction of its background points within `inlier_dist` of the union.
    pub overlap: f64,
    /// RMS of those inlier distances, metres.
    pub rms: f64,
}

/// Background points of a scanner in its own frame from its long-term background ranges
/// (`None` = unknown), keeping valid ranges below `max_range`.
pub fn background_points(
    background: &[Option<f64>],
    geometry: &ScanGeometry,
    max_range: f64,
) -> Result<Vec<Point2>> {
    let table = BeamTable::new(geometry)?;
    quarry_core::ensure_len(background.len(), table.len(), "background beams")?;
    Ok(background
        .iter()
        .enumerate()
        .filter_map(|(n, b)| {
            let r = (*b)?;
            (r.is_finite() && r >= geometry.range_min && r < max_range && r <= geometry.range_max)
                .then(|| table.point(n, r))
                .flatten()
        })
        .collect())
}

/// The result of [`free_space_violations`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FreeSpaceCheck {
    /// Points that fall on a beam of the scanner with known background ranges.
    pub in_view: usize,
    /// Of those, points lying in the free space the scanner saw through (closer than its
    /// background range by more than the margin).
    pub violations: usize,
}

impl FreeSpaceCheck {
    /// `violations / in_view` (0 when nothing is in view).
    pub fn fraction(&self) -> f64 {
        if self.in_view == 0 {
            0.0
        } else {
            self.violations as f64 / self.in_view as f64
        }
    }

    /// The sum of two checks.
    pub fn merged(self, other: Self) -> Self {
        Self {
            in_view: self.in_view + other.in_view,
            violations: self.violations + other.violations,
        }
    }
}

/// Free-space consistency of a scanner pose (a check added to spec 003 §2.3 step 4): static
/// points `points` (world frame, e.g. the other scanners' backgrounds under their calibrated
/// poses) must not lie in the space the scanner at `pose` saw through. A point falls on beam `n`
/// of `geometry` when its bearing rounds to it; it is *in view* when the background ranges
/// `b_{n−1}, b_n, b_{n+1}` are all known and its range is at least `range_min`, and a
/// *violation* when it is closer than `min(b_{n−1}, b_n, b_{n+1}) − margin` (the neighbours
/// absorb the bearing quantisation at depth edges). A wrong registration that still overlaps
/// (e.g. a scanner slid along a wall) puts many points into free space; the true pose puts
/// none there.
pub fn free_space_violations(
    points: &[Point2],
    pose: &Pose2,
    background: &[Option<f64>],
    geometry: &ScanGeometry,
    margin: f64,
) -> Result<FreeSpaceCheck> {
    geometry.validate()?;
    quarry_core::ensure_len(
        background.len(),
        geometry.n_beams as usize,
        "background beams",
    )?;
    if !pose.is_finite() {
        return Err(CoreError::NonFinite {
            what: "scanner pose",
        }
        .into());
    }
    if !(margin.is_finite() && margin >= 0.0) {
        return Err(CoreError::invalid("margin", "must be finite and >= 0").into());
    }
    quarry_core::ensure_finite(points.iter().flat_map(|p| [&p.x, &p.y]), "points")?;
    let n_beams = background.len();
    let mut out = FreeSpaceCheck::default();
    for p in points {
        let q = pose.apply_inverse(p);
        let r = q.x.hypot(q.y);
        if r < geometry.range_min {
            continue;
        }
        let k = ((q.y.atan2(q.x) - geometry.angle_min) / geometry.angle_increment).round();
        if !(k >= 1.0 && k < (n_beams - 1) as f64) {
            continue;
        }
        let n = k as usize;
        let (Some(a), Some(b), Some(c)) = (background[n - 1], background[n], background[n + 1])
        else {
            continue;
        };
        out.in_view += 1;
        if r < a.min(b).min(c) - margin {
            out.violations += 1;
        }
    }
    Ok(out)
}

/// Poses straight from the configuration (`calibration = given`).
pub fn given_poses(poses: &[(SensorId, Pose2)]) -> Result<BTreeMap<SensorId, Pose2>> {
    let mut out = BTreeMap::new();
    for (s, p) in poses {
        if !p.is_finite() {
            return Err(CoreError::NonFinite {
                what: "configured sensor pose",
            }
            .into());
        }
        if out.insert(*s, *p).is_some() {
            return Err(CoreError::invalid("poses", format!("sensor {} given twice", s.0)).into());
        }
    }
    Ok(out)
}

/// Local tangent direction of each target point (principal axis of its neighbours within
/// `radius`), `None` where fewer than 3 neighbours.
fn tangents(target: &[Point2], index: &KdIndex, radius: f64) -> Vec<Option<(f64, f64)>> {
    target
        .iter()
        .map(|p| {
            let nb: Vec<Point2> = index
                .within(p, radius)
                .into_iter()
                .map(|i| target[i])
                .collect();
            if nb.len() < 3 {
                return None;
            }
            pca_angle(&nb).ok().map(|a| (a.cos(), a.sin()))
        })
        .collect()
}

/// Correspondences under `pose`: each source point with the closest point on the local tangent
/// line of its nearest target point (point-to-line), kept if within `dmax`.
fn correspond(
    points: &[Point2],
    pose: &Pose2,
    target: &[Point2],
    tang: &[Option<(f64, f64)>],
    index: &KdIndex,
    dmax: f64,
) -> Vec<(Point2, Point2, f64)> {
    let mut out = Vec::with_capacity(points.len());
    for p in points {
        let q = pose.apply(p);
        let Some((j, d)) = index.nearest(&q) else {
            continue;
        };
        if d > dmax {
            continue;
        }
        let n = target[j];
        let c = match tang[j] {
            Some((tx, ty)) => {
                let s = ((q.x - n.x) * tx + (q.y - n.y) * ty)
                    .clamp(-PROJECTION_LIMIT, PROJECTION_LIMIT);
                Point2::new(n.x + s * tx, n.y + s * ty)
            }
            None => n,
        };
        out.push((*p, c, (q - c).norm()));
    }
    out
}

/// One linearised residual row: `e + J·δ`, with `δ = (dx, dy, dθ)` about `centre`.
#[derive(Debug, Clone, Copy)]
struct Row {
    /// World point under the current pose.
    q: Point2,
    /// Unit direction of the residual (the target line's normal, or a coordinate axis).
    n: (f64, f64),
    /// Residual along `n`.
    e: f64,
}

/// Point-to-line rows (one per pair; target points without a tangent give the two
/// point-to-point rows).
fn correspond_gn(
    points: &[Point2],
    pose: &Pose2,
    target: &[Point2],
    tang: &[Option<(f64, f64)>],
    index: &KdIndex,
    dmax: f64,
) -> Vec<Row> {
    let mut out = Vec::with_capacity(points.len());
    for p in points {
        let q = pose.apply(p);
        let Some((j, d)) = index.nearest(&q) else {
            continue;
        };
        if d > dmax {
            continue;
        }
        let c = target[j];
        if let Some((tx, ty)) = tang[j] {
            let n = (-ty, tx);
            out.push(Row {
                q,
                n,
                e: n.0 * (q.x - c.x) + n.1 * (q.y - c.y),
            });
        } else {
            out.push(Row {
                q,
                n: (1.0, 0.0),
                e: q.x - c.x,
            });
            out.push(Row {
                q,
                n: (0.0, 1.0),
                e: q.y - c.y,
            });
        }
    }
    out
}

/// One Gauss-Newton step of point-to-line ICP (Censi 2008) on the rows; the increment rotates
/// about the rows' centroid for conditioning. Falls back to keeping the pose when the normal
/// equations are singular (e.g. only parallel walls).
fn gauss_newton_step(rows: &[Row], pose: &Pose2) -> Result<Pose2> {
    let n = rows.len() as f64;
    let (cx, cy) = rows
        .iter()
        .fold((0.0, 0.0), |(x, y), r| (x + r.q.x, y + r.q.y));
    let (cx, cy) = (cx / n, cy / n);
    let mut h = nalgebra::Matrix3::<f64>::zeros();
    let mut g = nalgebra::Vector3::<f64>::zeros();
    for r in rows {
        let j = nalgebra::Vector3::new(r.n.0, r.n.1, r.n.0 * -(r.q.y - cy) + r.n.1 * (r.q.x - cx));
        h += j * j.transpose();
        g += j * r.e;
    }
    let Some(chol) = h.cholesky() else {
        return Ok(*pose);
    };
    let delta = -chol.solve(&g);
    if !delta.iter().all(|v| v.is_finite()) {
        return Err(CoreError::numerical("calibration ICP", "non-finite step").into());
    }
    // x ↦ R(dθ)(x − c) + c + d, applied after `pose`
    let step = Pose2::new(cx + delta.x, cy + delta.y, delta.z).compose(&Pose2::new(-cx, -cy, 0.0));
    Ok(step.compose(pose))
}

/// Largest slide along a tangent line from the nearest target point, metres.
const PROJECTION_LIMIT: f64 = 0.10;
/// Neighbourhood radius for the tangents, metres.
const TANGENT_RADIUS: f64 = 0.15;

/// Registers one scanner's background (`points`, sensor frame) against `target` (world frame,
/// indexed by `index`) from `rough`, through the stage schedule. Returns the pose, the overlap
/// and the inlier RMS (not checked against the acceptance bounds).
///
/// Point-to-line ICP (Censi 2008, the upgrade the spec allows): each source point's residual is
/// its distance to the local tangent line (principal axis of the neighbours within 0.15 m) of
/// its nearest target point, the best `keep_fraction` of the pairs within the stage distance are
/// kept, and a Gauss-Newton step solves the linearised problem. Plain point-to-point pairing
/// stalls here: with two scans of the same room the sampled walls create fixed points several
/// centimetres off (found by this module's tests), and its linear convergence along walls stops
/// the ΔRMS < 1e-5 m rule short of the 1 mm / 0.01° target.
pub fn register_background(
    cfg: &CalibConfig,
    points: &[Point2],
    target: &[Point2],
    index: &KdIndex,
    rough: Pose2,
) -> Result<(Pose2, f64, f64)> {
    if points.is_empty() {
        return Err(CoreError::Empty {
            what: "scanner background",
        }
        .into());
    }
    if cfg.stages.is_empty() || cfg.stages.iter().any(|d| !(d.is_finite() && *d > 0.0)) {
        return Err(CoreError::invalid("stages", "need at least one positive distance").into());
    }
    if !(cfg.keep_fraction > 0.0 && cfg.keep_fraction <= 1.0) {
        return Err(CoreError::invalid("keep_fraction", "must be in (0, 1]").into());
    }
    if !rough.is_finite() {
        return Err(CoreError::NonFinite { what: "rough pose" }.into());
    }
    quarry_core::ensure_len(index.len(), target.len(), "kd index of the target")?;
    quarry_core::ensure_finite(
        points.iter().flat_map(|p| [&p.x, &p.y]),
        "background points",
    )?;
    let tang = if cfg.point_to_line {
        tangents(target, index, TANGENT_RADIUS)
    } else {
        vec![None; target.len()]
    };
    let mut pose = rough;
    if !cfg.point_to_line {
        pose = point_to_point_stages(cfg, points, target, index, rough)?;
    }
    for &d in cfg.stages.iter().filter(|_| cfg.point_to_line) {
        let mut prev = f64::INFINITY;
        for _ in 0..cfg.max_iter {
            let mut pairs = correspond_gn(points, &pose, target, &tang, index, d);
            if pairs.len() < 3 {
                break;
            }
            let keep =
                ((pairs.len() as f64 * cfg.keep_fraction).ceil() as usize).clamp(3, pairs.len());
            pairs.sort_by(|a, b| a.e.abs().total_cmp(&b.e.abs()));
            pairs.truncate(keep);
            pose = gauss_newton_step(&pairs, &pose)?;
            let rms = (pairs.iter().map(|p| p.e * p.e).sum::<f64>() / pairs.len() as f64).sqrt();
            if (prev - rms).abs() < cfg.delta_stop {
                break;
            }
            prev = rms;
        }
    }
    // overlap: pairs within inlier_dist / |B_s|; inlier RMS: trimmed (best keep_fraction of
    // those pairs), the trimmed-ICP error of Chetverikov et al. 2002 — points on surfaces the
    // union never saw can still fall within 0.10 m of something and would inflate a plain RMS
    let mut fin: Vec<f64> = correspond(points, &pose, target, &tang, index, cfg.inlier_dist)
        .into_iter()
        .map(|x| x.2)
        .collect();
    let overlap = fin.len() as f64 / points.len() as f64;
    fin.sort_by(f64::total_cmp);
    let keep = (fin.len() as f64 * cfg.keep_fraction).ceil() as usize;
    fin.truncate(keep.max(1).min(fin.len()));
    let rms = if fin.is_empty() {
        f64::INFINITY
    } else {
        (fin.iter().map(|r| r * r).sum::<f64>() / fin.len() as f64).sqrt()
    };
    Ok((pose, overlap, rms))
}

/// The spec's plain trimmed point-to-point ICP (§2.3 step 3): nearest target point within the
/// stage distance, the best `keep_fraction` of the pairs, the closed-form solve of §2.6.
fn point_to_point_stages(
    cfg: &CalibConfig,
    points: &[Point2],
    target: &[Point2],
    index: &KdIndex,
    rough: Pose2,
) -> Result<Pose2> {
    let mut pose = rough;
    for &d in &cfg.stages {
        let mut prev = f64::INFINITY;
        for _ in 0..cfg.max_iter {
            let mut pairs: Vec<(Point2, Point2, f64)> = points
                .iter()
                .filter_map(|p| {
                    let (j, dist) = index.nearest(&pose.apply(p))?;
                    (dist <= d).then_some((*p, target[j], dist))
                })
                .collect();
            if pairs.len() < 3 {
                break;
            }
            let keep =
                ((pairs.len() as f64 * cfg.keep_fraction).ceil() as usize).clamp(3, pairs.len());
            pairs.sort_by(|a, b| a.2.total_cmp(&b.2));
            pairs.truncate(keep);
            let (p, q): (Vec<Point2>, Vec<Point2>) = pairs.iter().map(|x| (x.0, x.1)).unzip();
            pose = crate::icp::rigid_2d(&p, &q, None, pose.theta)?;
            let rms = (pairs.iter().map(|x| x.2 * x.2).sum::<f64>() / pairs.len() as f64).sqrt();
            if (prev - rms).abs() < cfg.delta_stop {
                break;
            }
            prev = rms;
        }
    }
    Ok(pose)
}

/// Calibrates `others` against `reference` (whose pose is taken as exact). Returns one result per
/// scanner, the reference first, in calibration order; fails with
/// [`CloudError::CalibrationInsufficient`] naming the first scanner that cannot be registered.
pub fn calibrate(
    cfg: &CalibConfig,
    reference: &ScannerBackground,
    others: &[ScannerBackground],
) -> Result<Vec<CalibResult>> {
    if reference.points.is_empty() {
        return Err(CoreError::Empty {
            what: "reference background",
        }
        .into());
    }
    let mut union: Vec<Point2> = reference
        .points
        .iter()
        .map(|p| reference.pose.apply(p))
        .collect();
    let mut out = vec![CalibResult {
        sensor: reference.sensor,
        pose: reference.pose,
        overlap: 1.0,
        rms: 0.0,
    }];
    let mut left: Vec<&ScannerBackground> = others.iter().collect();
    while !left.is_empty() {
        let index = KdIndex::new(&union)?;
        // most overlapping first (at the rough pose, within the second stage's distance)
        let probe = cfg
            .stages
            .get(1)
            .or(cfg.stages.first())
            .copied()
            .unwrap_or(0.5);
        let (best, _) = left
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let near = s
                    .points
                    .iter()
                    .filter(|p| {
                        index
                            .nearest(&s.pose.apply(p))
                            .is_some_and(|(_, d)| d <= probe)
                    })
                    .count();
                (i, near as f64 / s.points.len().max(1) as f64)
            })
            .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
        let s = left.remove(best);
        let (pose, overlap, rms) = register_background(cfg, &s.points, &union, &index, s.pose)?;
        if !(overlap >= cfg.min_overlap && rms <= cfg.max_rms) {
            return Err(CloudError::CalibrationInsufficient {
                sensor: s.sensor,
                overlap,
                min_overlap: cfg.min_overlap,
                rms,
                max_rms: cfg.max_rms,
            });
        }
        union.extend(s.points.iter().map(|p| pose.apply(p)));
        out.push(CalibResult {
            sensor: s.sensor,
            pose,
            overlap,
            rms,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Room 10 x 8 m with a pillar and a cabinet (segments).
    fn room() -> Vec<(Point2, Point2)> {
        let rect = |x0: f64, y0: f64, x1: f64, y1: f64| {
            let c = [
                Point2::new(x0, y0),
                Point2::new(x1, y0),
                Point2::new(x1, y1),
                Point2::new(x0, y1),
            ];
            (0..4)
                .map(move |i| (c[i], c[(i + 1) % 4]))
                .collect::<Vec<_>>()
        };
        let mut s = rect(0.0, 0.0, 10.0, 8.0);
        s.extend(rect(4.8, 3.8, 5.2, 4.2));
        s.extend(rect(7.5, 7.4, 9.0, 8.0));
        s.extend(rect(9.3, 1.8, 10.0, 2.5));
        s
    }

    fn cast(pose: &Pose2, g: &ScanGeometry) -> Vec<Option<f64>> {
        let segs = room();
        (0..g.n_beams)
            .map(|n| {
                let a = pose.theta + g.angle(n);
                let (dx, dy) = (a.cos(), a.sin());
                let mut best = f64::INFINITY;
                for (p, q) in &segs {
                    let (ex, ey) = (q.x - p.x, q.y - p.y);
                    let den = dx * ey - dy * ex;
                    if den.abs() < 1e-12 {
                        continue;
                    }
                    let (wx, wy) = (p.x - pose.x, p.y - pose.y);
                    let t = (wx * ey - wy * ex) / den;
                    let u = (wx * dy - wy * dx) / den;
                    if t > 1e-9 && (0.0..=1.0).contains(&u) {
                        best = best.min(t);
                    }
                }
                (best < 30.0).then_some(best)
            })
            .collect()
    }

    #[test]
    fn own_background_moved_is_recovered() {
        let g = ScanGeometry::utm30lx();
        let truth = Pose2::new(0.25, 0.25, 45f64.to_radians());
        let bg = background_points(&cast(&truth, &g), &g, 28.5).unwrap();
        let target: Vec<Point2> = bg.iter().map(|p| truth.apply(p)).collect();
        let index = KdIndex::new(&target).unwrap();
        for (dx, dy, dth) in [(0.3, 0.0, 10.0f64), (-0.2, 0.2, -8.0), (0.1, -0.25, 5.0)] {
            let rough = Pose2::new(truth.x + dx, truth.y + dy, truth.theta + dth.to_radians());
            let cfg = CalibConfig::default();
            let (pose, overlap, rms) =
                register_background(&cfg, &bg, &target, &index, rough).unwrap();
            assert!(
                (pose.x - truth.x).hypot(pose.y - truth.y) < 1e-3,
                "{pose:?}"
            );
            assert!(
                quarry_core::wrap_angle(pose.theta - truth.theta)
                    .abs()
                    .to_degrees()
                    < 0.01,
                "{pose:?} {overlap} {rms}"
            );
            assert!(overlap > 0.99 && rms < 1e-3);
        }
    }

    fn any_f64() -> impl proptest::strategy::Strategy<Value = f64> {
        use proptest::prelude::*;
        prop_oneof![
            4 => -40.0f64..40.0,
            1 => Just(f64::NAN),
            1 => Just(f64::INFINITY),
            1 => Just(f64::NEG_INFINITY),
            1 => Just(0.0),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Arbitrary backgrounds, poses, points and margins (NaN, inf, wrong sizes): a result
        /// or an error, never a panic; counts are consistent.
        #[test]
        fn free_space_and_calibration_never_panic(
            bg in proptest::collection::vec(proptest::option::of(any_f64()), 0..40),
            pts in proptest::collection::vec((any_f64(), any_f64()), 0..30),
            pose in (any_f64(), any_f64(), any_f64()),
            margin in any_f64(),
        ) {
            let g = ScanGeometry {
                n_beams: 32,
                angle_min: -1.5,
                angle_increment: 0.1,
                ..ScanGeometry::utm30lx()
            };
            let pose = Pose2 { x: pose.0, y: pose.1, theta: pose.2 };
            let points: Vec<Point2> = pts.iter().map(|(x, y)| Point2::new(*x, *y)).collect();
            if let Ok(c) = free_space_violations(&points, &pose, &bg, &g, margin) {
                proptest::prop_assert!(c.violations <= c.in_view && c.in_view <= points.len());
                proptest::prop_assert!((0.0..=1.0).contains(&c.fraction()));
            }
            let own = background_points(&bg, &g, 28.5);
            if let Ok(own) = &own {
                proptest::prop_assert!(own.iter().all(|p| p.x.is_finite() && p.y.is_finite()));
            }
            let reference = ScannerBackground { sensor: SensorId(0), points: points.clone(), pose };
            let other = ScannerBackground {
                sensor: SensorId(1),
                points: own.unwrap_or_default(),
                pose: Pose2::new(0.5, 0.5, 0.3),
            };
            if let Ok(res) = calibrate(&CalibConfig::default(), &reference, &[other]) {
                proptest::prop_assert_eq!(res.len(), 2);
            }
        }
    }

    #[test]
    fn free_space_check_flags_a_slid_scanner() {
        let g = ScanGeometry::utm30lx();
        let a = Pose2::new(0.25, 0.25, 45f64.to_radians());
        let c = Pose2::new(5.0, 7.75, -90f64.to_radians());
        let bg_a = cast(&a, &g);
        let bg_c = cast(&c, &g);
        let pts_c: Vec<Point2> = background_points(&bg_c, &g, 28.5)
            .unwrap()
            .iter()
            .map(|p| c.apply(p))
            .collect();
        // the true poses: C's background is consistent with what A saw through
        let ok = free_space_violations(&pts_c, &a, &bg_a, &g, 0.15).unwrap();
        assert!(ok.in_view > 100 && ok.fraction() < 0.01, "{ok:?}");
        // C slid 2 m along the north wall: its points enter A's free space
        let slid = Pose2::new(3.0, 7.75, c.theta);
        let pts_slid: Vec<Point2> = background_points(&bg_c, &g, 28.5)
            .unwrap()
            .iter()
            .map(|p| slid.apply(p))
            .collect();
        let bad = free_space_violations(&pts_slid, &a, &bg_a, &g, 0.15).unwrap();
        assert!(bad.fraction() > 0.1, "{bad:?}");
        assert_eq!(ok.merged(bad).in_view, ok.in_view + bad.in_view);
        assert_eq!(FreeSpaceCheck::default().fraction(), 0.0);
        assert!(free_space_violations(&pts_c, &a, &bg_a[1..], &g, 0.15).is_err());
        assert!(free_space_violations(&pts_c, &a, &bg_a, &g, f64::NAN).is_err());
        let nan = [Point2::new(f64::NAN, 0.0)];
        assert!(free_space_violations(&nan, &a, &bg_a, &g, 0.1).is_err());
    }

    #[test]
    fn three_scanners_calibrate() {
        let g = ScanGeometry::utm30lx();
        let truths = [
            Pose2::new(0.25, 0.25, 45f64.to_radians()),
            Pose2::new(9.75, 0.25, 135f64.to_radians()),
            Pose2::new(5.0, 7.75, -90f64.to_radians()),
        ];
        let scanners: Vec<ScannerBackground> = truths
            .iter()
            .enumerate()
            .map(|(k, t)| ScannerBackground {
                sensor: SensorId(k as u16),
                points: background_points(&cast(t, &g), &g, 28.5).unwrap(),
                pose: if k == 0 {
                    *t
                } else {
                    Pose2::new(t.x + 0.2, t.y - 0.15, t.theta + 0.1)
                },
            })
            .collect();
        let res = calibrate(&CalibConfig::default(), &scanners[0], &scanners[1..]).unwrap();
        assert_eq!(res.len(), 3);
        for r in &res {
            let t = truths[r.sensor.0 as usize];
            assert!((r.pose.x - t.x).hypot(r.pose.y - t.y) < 0.02, "{r:?}");
            assert!(
                quarry_core::wrap_angle(r.pose.theta - t.theta)
                    .abs()
                    .to_degrees()
                    < 0.3
            );
        }
        // a scanner far off its rough pose is refused
        let mut bad = scanners[1].clone();
        bad.pose = Pose2::new(3.0, 5.0, 2.0);
        let e = calibrate(&CalibConfig::default(), &scanners[0], &[bad]);
        assert!(
            matches!(e, Err(CloudError::CalibrationInsufficient { .. })),
            "{e:?}"
        );
        assert!(given_poses(&[(SensorId(0), truths[0]), (SensorId(0), truths[1])]).is_err());
    }
}
