//! People from a 2-D scanner at leg height: leg clusters, then legs paired into people.
//!
//! At leg height a person is two small arcs 0.1–0.8 m apart, not one torso ellipse. The
//! detector (after the approach of Leigh et al., ICRA 2015, `leg_tracker`, whose published
//! default values it uses where it has one):
//!
//! 1. **Leg clusters**: single-linkage (Euclidean) clustering of the dynamic points with the
//!    linkage distance [`LegDetector::cluster_dist`] (0.13 m, leg_tracker's
//!    `cluster_dist_euclid`); clusters with fewer than [`LegDetector::min_points`] points (3,
//!    leg_tracker's `min_points_per_cluster`) are dropped. Order-independent, so it works on
//!    the points of several fused scanners as well as on one scan.
//! 2. **Leg-sized**: the cluster's extent (the diagonal of its axis-aligned bounding box) must
//!    be at most [`LegDetector::max_width`] (0.45 m: one leg seen from any side is 0.1–0.2 m;
//!    two legs side by side merged into one cluster are up to about 0.4 m; a wall or a table
//!    left by the background model is larger). A cluster's position is its centroid, as the
//!    recordings' own leg labels are.
//! 3. **Pairing**: leg pairs closer than [`LegDetector::max_pair_dist`] (0.8 m, leg_tracker's
//!    `max_leg_pairing_dist`: a long walking stride) are paired greedily, closest pair first;
//!    a pair's person is at the midpoint of its two leg centroids.
//! 4. **Single legs**: with [`LegDetector::single_legs`] (default on) an unpaired leg (the
//!    other occluded, or both legs in one cluster) is a person at its centroid.
//!
//! ```
//! use quarry_cloud::legs::LegDetector;
//! use quarry_core::Point2;
//! // two arcs of 5 points, 0.3 m apart: one person between them
//! let arc = |cx: f64| (0..5).map(move |k| Point2::new(cx + 0.02 * f64::from(k), 2.0));
//! let pts: Vec<Point2> = arc(0.0).chain(arc(0.38)).collect();
//! let people = LegDetector::default().detect(&pts)?;
//! assert_eq!(people.len(), 1);
//! assert_eq!(people[0].legs, 2);
//! assert!((people[0].position.x - 0.23).abs() < 1e-9);
//! # Ok::<(), quarry_cloud::CloudError>(())
//! ```

use crate::CloudError;
use quarry_core::{CoreError, Point2};

/// Largest number of points [`LegDetector::detect`] takes (a scan of 100 000 beams).
pub const MAX_POINTS: usize = 100_000;

/// One leg cluster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Centroid of the cluster's points, metres.
    pub centre: Point2,
    /// Extent: the diagonal of the cluster's bounding box, metres.
    pub width: f64,
    /// Number of points.
    pub points: usize,
}

/// One detected person.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PersonDetection {
    /// The midpoint of the two legs, or the single leg's centroid, metres.
    pub position: Point2,
    /// 2 for a leg pair, 1 for a single leg.
    pub legs: u8,
    /// Points of the person's legs.
    pub support: usize,
}

/// The leg detector's parameters (module docs give each value's source).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LegDetector {
    /// Single-linkage distance, metres [leg_tracker: 0.13].
    pub cluster_dist: f64,
    /// Minimum points of a leg cluster [leg_tracker: 3].
    pub min_points: usize,
    /// Largest extent of a leg cluster, metres [choice: 0.45, two legs side by side].
    pub max_width: f64,
    /// Largest distance between the two legs of a person, metres [leg_tracker: 0.8].
    pub max_pair_dist: f64,
    /// Report an unpaired leg as a person [choice: true].
    pub single_legs: bool,
}

impl Default for LegDetector {
    fn default() -> Self {
        Self {
            cluster_dist: 0.13,
            min_points: 3,
            max_width: 0.45,
            max_pair_dist: 0.8,
            single_legs: true,
        }
    }
}

impl LegDetector {
    /// Checks the parameters: distances finite and > 0, `min_points >= 1`.
    pub fn validate(&self) -> Result<(), CloudError> {
        for (name, v) in [
            ("cluster_dist", self.cluster_dist),
            ("max_width", self.max_width),
            ("max_pair_dist", self.max_pair_dist),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(
                    CoreError::invalid(name, format!("must be finite and > 0, got {v}")).into(),
                );
            }
        }
        if self.min_points == 0 {
            return Err(CoreError::invalid("min_points", "must be >= 1").into());
        }
        Ok(())
    }

    /// The leg clusters of `points` (any order), sorted by their smallest point index.
    ///
    /// Errors: invalid parameters, a non-finite point, more than [`MAX_POINTS`] points.
    pub fn legs(&self, points: &[Point2]) -> Result<Vec<Leg>, CloudError> {
        self.validate()?;
        if points.len() > MAX_POINTS {
            return Err(CoreError::invalid(
                "points",
                format!("at most {MAX_POINTS} points, got {}", points.len()),
            )
            .into());
        }
        if points.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
            return Err(CoreError::NonFinite {
                what: "leg detector points",
            }
            .into());
        }
        let n = points.len();
        // single linkage by a sweep over x: only pairs within cluster_dist in x are compared
        let mut by_x: Vec<usize> = (0..n).collect();
        by_x.sort_by(|&a, &b| points[a].x.total_cmp(&points[b].x).then(a.cmp(&b)));
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(p: &mut [usize], mut i: usize) -> usize {
            while p[i] != i {
                p[i] = p[p[i]];
                i = p[i];
            }
            i
        }
        let d2 = self.cluster_dist * self.cluster_dist;
        for (k, &i) in by_x.iter().enumerate() {
            for &j in &by_x[k + 1..] {
                if points[j].x - points[i].x > self.cluster_dist {
                    break;
                }
                if (points[j] - points[i]).norm_squared() <= d2 {
                    let (a, b) = (find(&mut parent, i), find(&mut parent, j));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                }
            }
        }
        // accumulate per root (roots are the smallest index of their cluster)
        let mut acc: Vec<(usize, f64, f64, f64, f64, f64, f64)> = Vec::new(); // n, mean, bbox
        let mut slot = vec![usize::MAX; n];
        for i in 0..n {
            let r = find(&mut parent, i);
            if slot[r] == usize::MAX {
                slot[r] = acc.len();
                acc.push((
                    0,
                    0.0,
                    0.0,
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ));
            }
            let a = &mut acc[slot[r]];
            let p = points[i];
            // running mean: no overflow of a sum for coordinates near f64::MAX
            a.0 += 1;
            a.1 += (p.x - a.1) / a.0 as f64;
            a.2 += (p.y - a.2) / a.0 as f64;
            a.3 = a.3.min(p.x);
            a.4 = a.4.min(p.y);
            a.5 = a.5.max(p.x);
            a.6 = a.6.max(p.y);
        }
        Ok(acc
            .into_iter()
            .filter_map(|(k, mx, my, x0, y0, x1, y1)| {
                let width = (x1 - x0).hypot(y1 - y0);
                (k >= self.min_points && width <= self.max_width).then(|| Leg {
                    centre: Point2::new(mx, my),
                    width,
                    points: k,
                })
            })
            .collect())
    }

    /// Pairs legs into people: closest pairs within [`LegDetector::max_pair_dist`] first, then
    /// (with [`LegDetector::single_legs`]) each unpaired leg alone. Order: pairs by distance,
    /// then single legs in input order.
    pub fn pair(&self, legs: &[Leg]) -> Vec<PersonDetection> {
        let mut cand: Vec<(f64, usize, usize)> = Vec::new();
        for i in 0..legs.len() {
            for j in i + 1..legs.len() {
                let d = (legs[i].centre - legs[j].centre).norm();
                if d <= self.max_pair_dist {
                    cand.push((d, i, j));
                }
            }
        }
        cand.sort_by(|a, b| a.0.total_cmp(&b.0).then((a.1, a.2).cmp(&(b.1, b.2))));
        let mut used = vec![false; legs.len()];
        let mut out = Vec::new();
        for (_, i, j) in cand {
            if used[i] || used[j] {
                continue;
            }
            used[i] = true;
            used[j] = true;
            let (a, b) = (legs[i].centre, legs[j].centre);
            out.push(PersonDetection {
                position: Point2::new(a.x + 0.5 * (b.x - a.x), a.y + 0.5 * (b.y - a.y)),
                legs: 2,
                support: legs[i].points + legs[j].points,
            });
        }
        if self.single_legs {
            for (i, l) in legs.iter().enumerate() {
                if !used[i] {
                    out.push(PersonDetection {
                        position: l.centre,
                        legs: 1,
                        support: l.points,
                    });
                }
            }
        }
        out
    }

    /// [`LegDetector::legs`] then [`LegDetector::pair`].
    pub fn detect(&self, points: &[Point2]) -> Result<Vec<PersonDetection>, CloudError> {
        Ok(self.pair(&self.legs(points)?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arc(cx: f64, cy: f64, n: u32) -> Vec<Point2> {
        (0..n)
            .map(|k| {
                let a =
                    std::f64::consts::PI * (0.25 + 0.5 * f64::from(k) / f64::from(n.max(2) - 1));
                Point2::new(cx + 0.06 * a.cos(), cy - 0.06 * a.sin())
            })
            .collect()
    }

    #[test]
    fn two_people_with_two_legs_each_and_a_wall_remnant() {
        let mut pts = arc(0.0, 2.0, 6);
        pts.extend(arc(0.35, 2.0, 6));
        pts.extend(arc(2.0, 3.0, 5));
        pts.extend(arc(2.1, 3.5, 5)); // second person, legs 0.51 m apart (mid-stride)
        // a 1 m wall segment the background missed: too wide for a leg
        pts.extend((0..40).map(|k| Point2::new(-2.0 + 0.025 * f64::from(k), -1.0)));
        // two stray points: too few for a leg
        pts.push(Point2::new(5.0, 5.0));
        pts.push(Point2::new(5.05, 5.0));
        let d = LegDetector::default();
        let legs = d.legs(&pts).unwrap();
        assert_eq!(legs.len(), 4, "{legs:?}");
        let people = d.pair(&legs);
        assert_eq!(people.len(), 2, "{people:?}");
        assert!(people.iter().all(|p| p.legs == 2));
        let mut xs: Vec<f64> = people.iter().map(|p| p.position.x).collect();
        xs.sort_by(f64::total_cmp);
        assert!(
            (xs[0] - 0.175).abs() < 1e-9 && (xs[1] - 2.05).abs() < 1e-9,
            "{xs:?}"
        );
    }

    #[test]
    fn an_unpaired_leg_is_a_person_only_with_single_legs() {
        let pts = arc(1.0, 1.0, 5);
        let on = LegDetector::default().detect(&pts).unwrap();
        assert_eq!(on.len(), 1);
        assert_eq!(on[0].legs, 1);
        let off = LegDetector {
            single_legs: false,
            ..LegDetector::default()
        }
        .detect(&pts)
        .unwrap();
        assert!(off.is_empty());
    }

    #[test]
    fn legs_too_far_apart_are_two_single_legs() {
        let mut pts = arc(0.0, 0.0, 5);
        pts.extend(arc(1.0, 0.0, 5));
        let p = LegDetector::default().detect(&pts).unwrap();
        assert_eq!(p.len(), 2);
        assert!(p.iter().all(|p| p.legs == 1));
    }

    #[test]
    fn bad_input_and_parameters_are_errors() {
        let d = LegDetector::default();
        assert!(d.detect(&[Point2::new(f64::NAN, 0.0)]).is_err());
        assert!(d.detect(&[]).unwrap().is_empty());
        for bad in [
            LegDetector {
                cluster_dist: 0.0,
                ..d
            },
            LegDetector {
                max_width: f64::NAN,
                ..d
            },
            LegDetector {
                max_pair_dist: f64::INFINITY,
                ..d
            },
            LegDetector { min_points: 0, ..d },
        ] {
            assert!(bad.detect(&arc(0.0, 0.0, 5)).is_err(), "{bad:?}");
        }
        let many = vec![Point2::new(0.0, 0.0); MAX_POINTS + 1];
        assert!(d.legs(&many).is_err());
    }

    proptest! {
        /// Never panics; every detection is finite, lies within the points' bounding box, and
        /// uses each point at most once (support sums to at most the number of points).
        #[test]
        fn never_panics_and_detections_are_well_formed(
            raw in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0), 0..200),
            dist in 0.01f64..1.0,
            min_points in 1usize..6,
            single in any::<bool>(),
        ) {
            let pts: Vec<Point2> = raw.iter().map(|&(x, y)| Point2::new(x, y)).collect();
            let d = LegDetector { cluster_dist: dist, min_points, single_legs: single, ..LegDetector::default() };
            let people = d.detect(&pts).unwrap();
            let support: usize = people.iter().map(|p| p.support).sum();
            prop_assert!(support <= pts.len());
            for p in &people {
                prop_assert!(p.position.x.is_finite() && p.position.y.is_finite());
                prop_assert!(p.position.x.abs() <= 5.0 && p.position.y.abs() <= 5.0);
                prop_assert!(p.legs == 1 || p.legs == 2);
            }
        }
    }
}
