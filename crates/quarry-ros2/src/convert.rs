//! Conversions between quarry's vocabulary (quarry-core) and the ROS 2 messages.

use quarry_core::{PolarScan, Pose2, ScanGeometry, SensorId, TimeUs};

use crate::cdr::CdrError;
use crate::msgs::{
    ColorRGBA, Duration, Header, LaserScan, Marker, MarkerArray, Point, Pose, TFMessage, Time,
    Track, TrackArray, TransformStamped, Vector3,
};

/// The longest range a [`PolarScan`] holds (its ranges are `u16` millimetres).
pub const MAX_RANGE_M: f64 = 65.535;

/// A ROS time from quarry's microsecond stamp.
pub fn time_of(t: TimeUs) -> Time {
    Time::from_micros(t.0)
}

/// quarry's microsecond stamp from a ROS time (rounded down to the microsecond).
pub fn stamp_of(t: &Time) -> TimeUs {
    TimeUs(t.nanos().div_euclid(1000))
}

/// A quarry scan as a `LaserScan` in `frame`: ranges in metres, no return (0 mm) as `+inf`
/// (REP 117), no intensities.
pub fn laser_scan(scan: &PolarScan, frame: &str) -> LaserScan {
    let g = &scan.geometry;
    let n = scan.ranges_mm.len();
    LaserScan {
        header: Header::new(time_of(scan.t), frame),
        angle_min: g.angle_min as f32,
        angle_max: (g.angle_min + g.angle_increment * n.saturating_sub(1) as f64) as f32,
        angle_increment: g.angle_increment as f32,
        time_increment: 0.0,
        scan_time: g.scan_period as f32,
        range_min: g.range_min as f32,
        range_max: g.range_max as f32,
        ranges: scan
            .ranges_mm
            .iter()
            .map(|&mm| {
                if mm == 0 {
                    f32::INFINITY
                } else {
                    f32::from(mm) * 1e-3
                }
            })
            .collect(),
        intensities: Vec::new(),
    }
}

/// The scanner geometry a `LaserScan` declares (its range interval capped at
/// [`MAX_RANGE_M`]; the scan period from `scan_time`, or `default_period_s` where it is 0).
///
/// # Errors
/// [`CdrError::Invalid`]: no beams, non-finite or non-positive angle increment (clockwise
/// scanners, `angle_increment < 0`, are not supported), a bad range interval or period.
pub fn geometry_of(msg: &LaserScan, default_period_s: f64) -> Result<ScanGeometry, CdrError> {
    let bad = |s: String| Err(CdrError::Invalid(s));
    if msg.ranges.is_empty() {
        return bad("LaserScan without ranges".into());
    }
    if !(msg.angle_increment.is_finite() && msg.angle_increment > 0.0) {
        return bad(format!(
            "LaserScan angle_increment {} (must be finite and > 0: counter-clockwise beams)",
            msg.angle_increment
        ));
    }
    if !msg.angle_min.is_finite() {
        return bad(format!("LaserScan angle_min {}", msg.angle_min));
    }
    let (rmin, rmax) = (f64::from(msg.range_min), f64::from(msg.range_max));
    if !(rmin.is_finite() && rmax.is_finite() && rmin >= 0.0 && rmax > rmin) {
        return bad(format!(
            "LaserScan range interval [{rmin}, {rmax}] (need 0 <= range_min < range_max)"
        ));
    }
    let period = if msg.scan_time > 0.0 && msg.scan_time.is_finite() {
        f64::from(msg.scan_time)
    } else {
        default_period_s
    };
    let g = ScanGeometry {
        n_beams: u32::try_from(msg.ranges.len())
            .map_err(|_| CdrError::Invalid("LaserScan with more than 2^32 beams".into()))?,
        angle_min: f64::from(msg.angle_min),
        angle_increment: f64::from(msg.angle_increment),
        range_min: rmin,
        range_max: rmax.min(MAX_RANGE_M),
        scan_period: period,
    };
    g.validate()
        .map_err(|e| CdrError::Invalid(format!("LaserScan geometry: {e}")))?;
    Ok(g)
}

/// A `LaserScan` as a quarry scan with the geometry `expected` (the run's, fixed by its first
/// scan): a beam count or angle that differs is an error the caller counts and skips. Ranges
/// that are NaN, infinite, outside [range_min, range_max] or beyond [`MAX_RANGE_M`] become "no
/// return" (0).
///
/// # Errors
/// [`CdrError::Invalid`] naming what differs from `expected`.
pub fn polar_scan(
    msg: &LaserScan,
    sensor: SensorId,
    seq: u32,
    expected: &ScanGeometry,
) -> Result<PolarScan, CdrError> {
    if msg.ranges.len() != expected.n_beams as usize {
        return Err(CdrError::Invalid(format!(
            "LaserScan with {} beams, the run's scans have {}",
            msg.ranges.len(),
            expected.n_beams
        )));
    }
    let tol = 1e-6_f64.max(1e-4 * expected.angle_increment.abs());
    if (f64::from(msg.angle_min) - expected.angle_min).abs() > tol
        || (f64::from(msg.angle_increment) - expected.angle_increment).abs() > tol
    {
        return Err(CdrError::Invalid(format!(
            "LaserScan angles ({}, step {}) differ from the run's ({}, step {})",
            msg.angle_min, msg.angle_increment, expected.angle_min, expected.angle_increment
        )));
    }
    let (lo, hi) = (f64::from(msg.range_min), f64::from(msg.range_max));
    let ranges_mm = msg
        .ranges
        .iter()
        .map(|&r| {
            let r = f64::from(r);
            if r.is_finite() && r >= lo && r <= hi && r <= MAX_RANGE_M && r > 0.0 {
                ((r * 1e3).round() as u16).max(1)
            } else {
                0
            }
        })
        .collect();
    PolarScan::try_new(
        sensor,
        seq,
        stamp_of(&msg.header.stamp),
        ranges_mm,
        *expected,
    )
    .map_err(|e| CdrError::Invalid(format!("LaserScan: {e}")))
}

/// A confirmed planar track at (x, y) with velocity (vx, vy) and nothing else known (no
/// covariance, no existence probability).
pub fn planar_track(id: u32, x: f64, y: f64, vx: f64, vy: f64) -> Track {
    Track {
        id,
        status: Track::CONFIRMED,
        x,
        y,
        vx,
        vy,
        position_covariance: [0.0; 4],
        existence: -1.0,
    }
}

/// The `quarry_msgs/msg/TrackArray` of `tracks` at `t` in `frame`.
pub fn track_array(t: TimeUs, frame: &str, tracks: Vec<Track>) -> TrackArray {
    TrackArray {
        header: Header::new(time_of(t), frame),
        tracks,
    }
}

/// A distinct, stable colour per track id (golden-angle hue), so that a track keeps its colour
/// in every panel and every recording.
pub fn color_of(id: u32) -> ColorRGBA {
    let h = (f64::from(id) * 0.618_033_988_75).fract() * 6.0;
    let x = 1.0 - (h % 2.0 - 1.0).abs();
    let (r, g, b) = match h as u32 {
        0 => (1.0, x, 0.0),
        1 => (x, 1.0, 0.0),
        2 => (0.0, 1.0, x),
        3 => (0.0, x, 1.0),
        4 => (x, 0.0, 1.0),
        _ => (1.0, 0.0, x),
    };
    ColorRGBA {
        r: r as f32,
        g: g as f32,
        b: b as f32,
        a: 0.9,
    }
}

fn lifted(x: f64, y: f64, z: f64) -> Pose {
    let mut p = Pose::planar(x, y, 0.0);
    p.position.z = z;
    p
}

/// Markers of planar tracks for a 3-D panel (Foxglove, RViz): a `DELETEALL` first (so that
/// ended tracks vanish), then per track a cylinder of `height` m and a text label with its id,
/// coloured by [`color_of`], living 1 s.
pub fn track_markers(t: TimeUs, frame: &str, tracks: &[Track], height: f64) -> MarkerArray {
    let header = Header::new(time_of(t), frame);
    let mut markers = Vec::with_capacity(1 + 2 * tracks.len());
    markers.push(Marker {
        header: header.clone(),
        action: Marker::DELETEALL,
        ..Marker::default()
    });
    for p in tracks {
        let base = Marker {
            header: header.clone(),
            id: p.id as i32,
            action: Marker::ADD,
            color: color_of(p.id),
            lifetime: Duration { sec: 1, nanosec: 0 },
            ..Marker::default()
        };
        markers.push(Marker {
            ns: "tracks".into(),
            r#type: Marker::CYLINDER,
            pose: lifted(p.x, p.y, 0.5 * height),
            scale: Vector3 {
                x: 0.35,
                y: 0.35,
                z: height,
            },
            ..base.clone()
        });
        markers.push(Marker {
            ns: "track_ids".into(),
            r#type: Marker::TEXT_VIEW_FACING,
            pose: lifted(p.x, p.y, height + 0.2),
            scale: Vector3 {
                x: 0.0,
                y: 0.0,
                z: 0.3,
            },
            text: p.id.to_string(),
            ..base
        });
    }
    MarkerArray { markers }
}

/// A `POINTS` marker (`ns` = `points`) of planar points at height 0 in `frame`: the fused
/// foreground points of a lidar frame, say. One colour, `size` m squares.
pub fn points_marker(t: TimeUs, frame: &str, points: &[(f64, f64)], size: f64) -> Marker {
    Marker {
        header: Header::new(time_of(t), frame),
        ns: "points".into(),
        r#type: Marker::POINTS,
        action: Marker::ADD,
        pose: Pose::planar(0.0, 0.0, 0.0),
        scale: Vector3 {
            x: size,
            y: size,
            z: 0.0,
        },
        color: ColorRGBA {
            r: 0.9,
            g: 0.9,
            b: 0.9,
            a: 1.0,
        },
        points: points
            .iter()
            .map(|&(x, y)| Point { x, y, z: 0.0 })
            .collect(),
        ..Marker::default()
    }
}

/// `/tf_static`: each child frame at its planar pose in `parent`.
pub fn static_tf(t: TimeUs, parent: &str, children: &[(String, Pose2)]) -> TFMessage {
    TFMessage {
        transforms: children
            .iter()
            .map(|(name, p)| TransformStamped::planar(time_of(t), parent, name, p.x, p.y, p.theta))
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scans_survive_the_round_trip() {
        let g = ScanGeometry::utm30lx();
        let mut r = vec![0u16; g.n_beams as usize];
        r[10] = 1234;
        r[500] = 29_000;
        let s = PolarScan::try_new(SensorId(1), 7, TimeUs(1_500_000), r, g).unwrap();
        let m = laser_scan(&s, "laser");
        assert!(m.ranges[0].is_infinite());
        let g2 = geometry_of(&m, 0.025).unwrap();
        let back = polar_scan(&m, SensorId(1), 7, &g2).unwrap();
        assert_eq!(back.ranges_mm, s.ranges_mm);
        assert_eq!(back.t, s.t);
        let mut short = m.clone();
        short.ranges.pop();
        assert!(polar_scan(&short, SensorId(1), 8, &g2).is_err());
        let mut cw = m;
        cw.angle_increment = -cw.angle_increment;
        assert!(geometry_of(&cw, 0.025).is_err());
    }

    #[test]
    fn markers_clear_then_draw_each_track_twice_in_its_colour() {
        let tracks = [
            planar_track(3, 1.0, 2.0, 0.0, 0.0),
            planar_track(9, -1.0, 0.5, 0.1, 0.0),
        ];
        let m = track_markers(TimeUs(2_000_000), "map", &tracks, 1.2);
        assert_eq!(m.markers.len(), 5);
        assert_eq!(m.markers[0].action, Marker::DELETEALL);
        assert_eq!(m.markers[1].r#type, Marker::CYLINDER);
        assert_eq!(m.markers[2].text, "3");
        assert!((m.markers[1].pose.position.z - 0.6).abs() < 1e-12);
        assert_eq!(m.markers[3].color, color_of(9));
        assert_ne!(color_of(3), color_of(9));
        let a = track_array(TimeUs(2_000_000), "map", tracks.to_vec());
        assert_eq!(a.header.stamp.sec, 2);
        assert_eq!(a.tracks[1].id, 9);
    }
}
