//! Point-cloud vocabulary: polar scans, detections, clustering, registration, background models.

use crate::{CoreError, Point2, Pose2, SensorId, TimeUs};
use nalgebra::Matrix2;

/// The beam geometry of a 2-D scanner (the fields of a ROS `LaserScan` header).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct ScanGeometry {
    /// Number of beams per scan.
    pub n_beams: u32,
    /// Angle of beam 0 in the sensor frame, radians (counter-clockwise from the sensor's +x).
    pub angle_min: f64,
    /// Angle between consecutive beams, radians.
    pub angle_increment: f64,
    /// Shortest valid range, metres.
    pub range_min: f64,
    /// Longest valid range, metres.
    pub range_max: f64,
    /// Time between scans, seconds.
    pub scan_period: f64,
}

impl ScanGeometry {
    /// The Hokuyo UTM-30LX of paper 003: 1081 beams over 270 degrees (0.25 degree steps, beam 540
    /// straight ahead), 0.1-30 m, 40 Hz.
    pub fn utm30lx() -> Self {
        Self {
            n_beams: 1081,
            angle_min: -135f64.to_radians(),
            angle_increment: 0.25f64.to_radians(),
            range_min: 0.1,
            range_max: 30.0,
            scan_period: 0.025,
        }
    }

    /// Checks that the geometry is usable (at least one beam, finite positive increment, valid
    /// range interval).
    pub fn validate(&self) -> Result<(), CoreError> {
        if self.n_beams == 0 {
            return Err(CoreError::Empty {
                what: "scan geometry (n_beams = 0)",
            });
        }
        if !(self.angle_min.is_finite()
            && self.angle_increment.is_finite()
            && self.angle_increment > 0.0)
        {
            return Err(CoreError::invalid(
                "angle_increment",
                "must be finite and positive",
            ));
        }
        if !(self.range_min.is_finite()
            && self.range_max.is_finite()
            && self.range_min >= 0.0
            && self.range_max > self.range_min)
        {
            return Err(CoreError::invalid(
                "range_min/range_max",
                "need 0 <= range_min < range_max, both finite",
            ));
        }
        Ok(())
    }

    /// The angle of beam `n` in the sensor frame.
    #[inline]
    pub fn angle(&self, n: u32) -> f64 {
        self.angle_min + f64::from(n) * self.angle_increment
    }
}

/// One scan of a 2-D scanner, ranges in millimetres (0 = no return).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct PolarScan {
    /// Which scanner.
    pub sensor: SensorId,
    /// The scanner's scan counter.
    pub seq: u32,
    /// Capture time (front beam).
    pub t: TimeUs,
    /// One range per beam, millimetres; 0 means "no return".
    pub ranges_mm: Vec<u16>,
    /// The beam geometry.
    pub geometry: ScanGeometry,
}

impl PolarScan {
    /// A validated scan: the geometry is usable and there is one range per beam.
    pub fn try_new(
        sensor: SensorId,
        seq: u32,
        t: TimeUs,
        ranges_mm: Vec<u16>,
        geometry: ScanGeometry,
    ) -> Result<Self, CoreError> {
        geometry.validate()?;
        crate::ensure_len(ranges_mm.len(), geometry.n_beams as usize, "scan ranges")?;
        Ok(Self {
            sensor,
            seq,
            t,
            ranges_mm,
            geometry,
        })
    }

    /// Range of beam `n` in metres, or `None` if it is outside the valid range interval.
    pub fn range_m(&self, n: usize) -> Option<f64> {
        let r = f64::from(*self.ranges_mm.get(n)?) * 1e-3;
        (r >= self.geometry.range_min && r <= self.geometry.range_max).then_some(r)
    }

    /// The valid returns as points in the frame given by `pose` (the sensor's pose; identity for
    /// the sensor frame), each with its beam index.
    pub fn to_points(&self, pose: &Pose2) -> Vec<(usize, Point2)> {
        (0..self.ranges_mm.len())
            .filter_map(|n| {
                let r = self.range_m(n)?;
                let a = self.geometry.angle(n as u32);
                Some((n, pose.apply(&Point2::new(r * a.cos(), r * a.sin()))))
            })
            .collect()
    }
}

/// The class of one beam after background subtraction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum BeamLabel {
    /// Consistent with the static background.
    Static,
    /// A moving (foreground) return.
    Dynamic,
    /// No valid return, or still learning.
    Invalid,
}

/// A background model that labels each beam of a scan.
pub trait BackgroundModel {
    /// Labels every beam (one label per beam) and updates the model.
    fn classify(&mut self, scan: &PolarScan) -> Result<Vec<BeamLabel>, CoreError>;

    /// The long-term per-beam background range `b_n` (metres, `None` where unknown) that a
    /// client publishes for calibration (spec 003 §2.2, §2.3), once it has been learned. `None`
    /// while it is still being learned or when the model keeps no long-term background (the
    /// default).
    fn published_background(&self) -> Option<&[Option<f64>]> {
        None
    }
}

/// A 2-D detection (a person, a cluster centre, ...).
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Detection2 {
    /// Position, metres.
    pub pos: Point2,
    /// Heading, when the detector estimates one.
    pub heading: Option<f64>,
    /// Position covariance, when known.
    pub cov: Option<Matrix2<f64>>,
    /// Number of points that support it.
    pub support: usize,
    /// Detector-specific quality (ICP RMS for paper 003: lower is better).
    pub score: f64,
}

/// The result of clustering a point set.
#[derive(Debug, Clone, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Clustering {
    /// Cluster of each input point (`None` = noise / unassigned).
    pub labels: Vec<Option<u32>>,
    /// The mode (centre) of each cluster.
    pub modes: Vec<Point2>,
    /// Number of points of each cluster.
    pub sizes: Vec<usize>,
}

/// Groups 2-D points into clusters.
pub trait Clusterer {
    /// Clusters `pts`; deterministic for the same input.
    fn cluster(&self, pts: &[Point2]) -> Result<Clustering, CoreError>;
}

/// The result of a 2-D rigid registration.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RegResult {
    /// The pose mapping the model frame onto the data frame.
    pub pose: Pose2,
    /// Root-mean-square residual of the inlier pairs, metres.
    pub rms: f64,
    /// Number of inlier pairs.
    pub inliers: usize,
    /// Iterations run.
    pub iters: u32,
    /// True when the convergence criterion was met (not the iteration cap).
    pub converged: bool,
}

/// Rigid 2-D registration (ICP and friends).
pub trait Registration2 {
    /// Estimates the pose mapping `model` (its own frame) onto `data` (world frame), starting
    /// from `init`.
    fn register(
        &self,
        model: &[Point2],
        data: &[Point2],
        init: Pose2,
    ) -> Result<RegResult, CoreError>;
}
