//! Planar and spatial rigid poses, angle wrapping, and image boxes.

use nalgebra::{Isometry2, Isometry3, Translation3, UnitQuaternion, Vector2, Vector3};

/// A 2-D point in metres (world, sensor or robot frame as the context says).
pub type Point2 = nalgebra::Point2<f64>;
/// A 3-D point in metres.
pub type Point3 = nalgebra::Point3<f64>;

/// Wraps an angle to (-pi, pi]. A non-finite input gives NaN.
///
/// ```
/// use quarry_core::wrap_angle;
/// use std::f64::consts::PI;
/// assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
/// assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
/// assert!((wrap_angle(0.5) - 0.5).abs() < 1e-15);
/// ```
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if !a.is_finite() {
        return f64::NAN;
    }
    if a > -PI && a <= PI {
        return a;
    }
    let w = (a + PI).rem_euclid(TAU) - PI; // in [-pi, pi)
    if w <= -PI { PI } else { w }
}

/// A rigid pose in the plane, SE(2): position `(x, y)` and heading `theta` (radians, wrapped).
///
/// `apply` maps points from the pose's own frame into the parent frame; `compose` chains poses
/// (`a.compose(&b)` is "b expressed in a's frame, then a").
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pose2 {
    /// x in metres.
    pub x: f64,
    /// y in metres.
    pub y: f64,
    /// Heading in radians, counter-clockwise from +x.
    pub theta: f64,
}

impl Pose2 {
    /// A pose from its parts (theta is wrapped to (-pi, pi]).
    pub fn new(x: f64, y: f64, theta: f64) -> Self {
        Self {
            x,
            y,
            theta: wrap_angle(theta),
        }
    }

    /// The identity pose.
    pub fn identity() -> Self {
        Self::default()
    }

    /// `self ⊕ other`: the pose `other`, given in this pose's frame, expressed in the parent frame.
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            self.theta + other.theta,
        )
    }

    /// The inverse pose: `p.compose(&p.inverse())` is the identity.
    pub fn inverse(&self) -> Pose2 {
        let (s, c) = self.theta.sin_cos();
        Pose2::new(
            -c * self.x - s * self.y,
            s * self.x - c * self.y,
            -self.theta,
        )
    }

    /// Maps a point from this pose's frame into the parent frame.
    pub fn apply(&self, p: &Point2) -> Point2 {
        let (s, c) = self.theta.sin_cos();
        Point2::new(self.x + c * p.x - s * p.y, self.y + s * p.x + c * p.y)
    }

    /// Maps a point from the parent frame into this pose's frame.
    pub fn apply_inverse(&self, p: &Point2) -> Point2 {
        let (s, c) = self.theta.sin_cos();
        let dx = p.x - self.x;
        let dy = p.y - self.y;
        Point2::new(c * dx + s * dy, -s * dx + c * dy)
    }

    /// The pose increment of a unicycle driving at speed `v` (m/s) and turn rate `omega` (rad/s)
    /// for `dt` seconds, integrated exactly (spec 001, eq. A3), in the start pose's frame.
    ///
    /// ```
    /// use quarry_core::Pose2;
    /// let d = Pose2::from_unicycle(1.0, 0.0, 2.0);
    /// assert!((d.x - 2.0).abs() < 1e-12 && d.y.abs() < 1e-12);
    /// ```
    pub fn from_unicycle(v: f64, omega: f64, dt: f64) -> Pose2 {
        let dtheta = omega * dt;
        let (dx, dy) = if dtheta.abs() < 1e-9 {
            (
                v * dt * (1.0 - dtheta * dtheta / 6.0),
                v * dt * dtheta / 2.0,
            )
        } else {
            let half = (dtheta / 2.0).sin();
            ((v / omega) * dtheta.sin(), (v / omega) * 2.0 * half * half)
        };
        Pose2::new(dx, dy, dtheta)
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.theta.is_finite()
    }

    /// The translation as a vector.
    pub fn translation(&self) -> Vector2<f64> {
        Vector2::new(self.x, self.y)
    }
}

impl From<Isometry2<f64>> for Pose2 {
    fn from(iso: Isometry2<f64>) -> Self {
        Pose2::new(
            iso.translation.vector.x,
            iso.translation.vector.y,
            iso.rotation.angle(),
        )
    }
}

impl From<Pose2> for Isometry2<f64> {
    fn from(p: Pose2) -> Self {
        Isometry2::new(Vector2::new(p.x, p.y), p.theta)
    }
}

/// A rigid pose in space, SE(3): a translation and a unit-quaternion rotation.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Pose3 {
    /// Translation in metres.
    pub translation: Vector3<f64>,
    /// Rotation.
    pub rotation: UnitQuaternion<f64>,
}

impl Default for Pose3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Pose3 {
    /// The identity pose.
    pub fn identity() -> Self {
        Self {
            translation: Vector3::zeros(),
            rotation: UnitQuaternion::identity(),
        }
    }
    /// From a translation and roll, pitch, yaw (radians, applied in the order yaw-pitch-roll).
    pub fn from_parts(translation: Vector3<f64>, roll: f64, pitch: f64, yaw: f64) -> Self {
        Self {
            translation,
            rotation: UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        }
    }
    /// `self ⊕ other`.
    pub fn compose(&self, other: &Pose3) -> Pose3 {
        Pose3 {
            translation: self.translation + self.rotation * other.translation,
            rotation: self.rotation * other.rotation,
        }
    }
    /// The inverse pose.
    pub fn inverse(&self) -> Pose3 {
        let r = self.rotation.inverse();
        Pose3 {
            translation: -(r * self.translation),
            rotation: r,
        }
    }
    /// Maps a point from this pose's frame into the parent frame.
    pub fn apply(&self, p: &Point3) -> Point3 {
        Point3::from(self.rotation * p.coords + self.translation)
    }
    /// The planar part (x, y, yaw), for a pose that moves in the ground plane.
    pub fn to_pose2(&self) -> Pose2 {
        let (_, _, yaw) = self.rotation.euler_angles();
        Pose2::new(self.translation.x, self.translation.y, yaw)
    }
}

impl From<Pose3> for Isometry3<f64> {
    fn from(p: Pose3) -> Self {
        Isometry3::from_parts(Translation3::from(p.translation), p.rotation)
    }
}

impl From<Isometry3<f64>> for Pose3 {
    fn from(iso: Isometry3<f64>) -> Self {
        Pose3 {
            translation: iso.translation.vector,
            rotation: iso.rotation,
        }
    }
}

impl From<Pose2> for Pose3 {
    fn from(p: Pose2) -> Self {
        Pose3::from_parts(Vector3::new(p.x, p.y, 0.0), 0.0, 0.0, p.theta)
    }
}

/// An axis-aligned image box in pixels, centre form.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BBox {
    /// Centre x (column), pixels.
    pub cx: f64,
    /// Centre y (row), pixels.
    pub cy: f64,
    /// Width, pixels.
    pub w: f64,
    /// Height, pixels.
    pub h: f64,
}

impl BBox {
    /// From left, top, width, height (the MOTChallenge form).
    pub fn from_ltwh(l: f64, t: f64, w: f64, h: f64) -> Self {
        Self {
            cx: l + w / 2.0,
            cy: t + h / 2.0,
            w,
            h,
        }
    }
    /// To left, top, width, height.
    pub fn to_ltwh(&self) -> [f64; 4] {
        [
            self.cx - self.w / 2.0,
            self.cy - self.h / 2.0,
            self.w,
            self.h,
        ]
    }
    /// Left edge.
    pub fn left(&self) -> f64 {
        self.cx - self.w / 2.0
    }
    /// Top edge.
    pub fn top(&self) -> f64 {
        self.cy - self.h / 2.0
    }
    /// Right edge (`left + w`).
    pub fn right(&self) -> f64 {
        self.cx + self.w / 2.0
    }
    /// Bottom edge (`top + h`).
    pub fn bottom(&self) -> f64 {
        self.cy + self.h / 2.0
    }
    /// Area (zero for a degenerate or negative-size box).
    pub fn area(&self) -> f64 {
        self.w.max(0.0) * self.h.max(0.0)
    }
    /// True when all four numbers are finite and the size is positive.
    pub fn is_valid(&self) -> bool {
        self.cx.is_finite()
            && self.cy.is_finite()
            && self.w.is_finite()
            && self.h.is_finite()
            && self.w > 0.0
            && self.h > 0.0
    }
    /// Area of the intersection with `other`.
    pub fn intersection_area(&self, other: &BBox) -> f64 {
        let w = (self.right().min(other.right()) - self.left().max(other.left())).max(0.0);
        let h = (self.bottom().min(other.bottom()) - self.top().max(other.top())).max(0.0);
        w * h
    }
    /// Intersection over union, in [0, 1] (0 when both boxes are empty).
    ///
    /// ```
    /// use quarry_core::BBox;
    /// let a = BBox::from_ltwh(0.0, 0.0, 10.0, 10.0);
    /// let b = BBox::from_ltwh(5.0, 0.0, 10.0, 10.0);
    /// assert!((a.iou(&b) - 1.0 / 3.0).abs() < 1e-12);
    /// ```
    pub fn iou(&self, other: &BBox) -> f64 {
        let inter = self.intersection_area(other);
        let union = self.area() + other.area() - inter;
        if union > 0.0 { inter / union } else { 0.0 }
    }
    /// The box scaled by `s` about its centre.
    pub fn scale_about_centre(&self, s: f64) -> BBox {
        BBox {
            cx: self.cx,
            cy: self.cy,
            w: self.w * s,
            h: self.h * s,
        }
    }
    /// The integer pixel rectangle `(x0, y0, x1, y1)` (exclusive end) covered by the box, clipped to
    /// an image of `width` x `height`; `None` when the clipped box is empty or not finite.
    pub fn to_pixel_rect(&self, width: u32, height: u32) -> Option<(u32, u32, u32, u32)> {
        if !(self.cx.is_finite() && self.cy.is_finite() && self.w.is_finite() && self.h.is_finite())
        {
            return None;
        }
        let x0 = self.left().round().clamp(0.0, f64::from(width));
        let y0 = self.top().round().clamp(0.0, f64::from(height));
        let x1 = self.right().round().clamp(0.0, f64::from(width));
        let y1 = self.bottom().round().clamp(0.0, f64::from(height));
        if x1 > x0 && y1 > y0 {
            Some((x0 as u32, y0 as u32, x1 as u32, y1 as u32))
        } else {
            None
        }
    }
    /// True when the point lies inside (edges inclusive on the left/top).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.left() && x < self.right() && y >= self.top() && y < self.bottom()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn wrap_is_in_range(a in -1e6f64..1e6) {
            let w = wrap_angle(a);
            prop_assert!(w > -std::f64::consts::PI && w <= std::f64::consts::PI);
            prop_assert!(((a - w) / std::f64::consts::TAU - ((a - w) / std::f64::consts::TAU).round()).abs() < 1e-6);
        }

        #[test]
        fn pose_inverse_composes_to_identity(x in -100.0f64..100.0, y in -100.0f64..100.0, t in -4.0f64..4.0) {
            let p = Pose2::new(x, y, t);
            let i = p.compose(&p.inverse());
            prop_assert!(i.x.abs() < 1e-9 && i.y.abs() < 1e-9 && i.theta.abs() < 1e-12);
        }

        #[test]
        fn pose_apply_matches_isometry(x in -10.0f64..10.0, y in -10.0f64..10.0, t in -4.0f64..4.0,
                                      px in -10.0f64..10.0, py in -10.0f64..10.0) {
            let p = Pose2::new(x, y, t);
            let iso: Isometry2<f64> = p.into();
            let q = Point2::new(px, py);
            let a = p.apply(&q);
            let b = iso * q;
            prop_assert!((a - b).norm() < 1e-9);
            prop_assert!((p.apply_inverse(&a) - q).norm() < 1e-9);
        }

        #[test]
        fn unicycle_matches_fine_integration(v in -2.0f64..2.0, w in -2.0f64..2.0, dt in 0.001f64..0.1) {
            let d = Pose2::from_unicycle(v, w, dt);
            let n = 2000;
            let h = dt / f64::from(n);
            let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
            for _ in 0..n {
                let mid = th + w * h / 2.0;
                x += v * h * mid.cos();
                y += v * h * mid.sin();
                th += w * h;
            }
            prop_assert!((d.x - x).abs() < 1e-8 && (d.y - y).abs() < 1e-8);
        }

        #[test]
        fn iou_symmetric_and_bounded(a in 0.0f64..50.0, b in 0.0f64..50.0, w in 1.0f64..30.0, h in 1.0f64..30.0,
                                     c in 0.0f64..50.0, d in 0.0f64..50.0) {
            let p = BBox::from_ltwh(a, b, w, h);
            let q = BBox::from_ltwh(c, d, h, w);
            let i = p.iou(&q);
            prop_assert!((0.0..=1.0).contains(&i));
            prop_assert!((i - q.iou(&p)).abs() < 1e-12);
            prop_assert!((p.iou(&p) - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn ltwh_roundtrip() {
        let b = BBox::from_ltwh(3.0, 4.0, 10.0, 20.0);
        assert_eq!(b.to_ltwh(), [3.0, 4.0, 10.0, 20.0]);
        assert_eq!(b.to_pixel_rect(100, 100), Some((3, 4, 13, 24)));
        assert_eq!(b.to_pixel_rect(5, 5), Some((3, 4, 5, 5)));
        assert_eq!(
            BBox::from_ltwh(200.0, 0.0, 5.0, 5.0).to_pixel_rect(100, 100),
            None
        );
    }

    #[test]
    fn pose3_roundtrip() {
        let p = Pose3::from_parts(Vector3::new(1.0, 2.0, 3.0), 0.1, -0.2, 0.3);
        let q = p.compose(&p.inverse());
        assert!(q.translation.norm() < 1e-12);
        assert!(q.rotation.angle() < 1e-12);
        let p2 = Pose3::from(Pose2::new(1.0, 2.0, 0.5)).to_pose2();
        assert!((p2.theta - 0.5).abs() < 1e-12 && (p2.x - 1.0).abs() < 1e-12);
    }
}
