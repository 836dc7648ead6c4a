//! Conversions between quarry's vocabulary (quarry-core) and the ROS 2 messages.

use quarry_core::{PolarScan, ScanGeometry, SensorId, TimeUs};

use crate::cdr::CdrError;
use crate::msgs::{Header, LaserScan, Time};

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
}
