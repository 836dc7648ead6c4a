//! Minimum trajectories over N frames and the moving-point test of spec 004 eqs. (3)–(7).
//!
//! Each minimum of the current frame carries the last ≤ N positions of its chain of
//! bidirectional matches; merges, splits and one-way links end a chain. With `(x_k, y_k)`,
//! k = 0 (oldest) … N−1 (newest):
//!
//! * `Mv[k] = |x_{N−1} − x_k| + |y_{N−1} − y_k|` (3)
//! * `NormMv[k] = Mv[k] / max Mv` (all 0 when the max is 0) (4)
//! * `DMv[k] = |NormMv[k] − NormMv[k+1]|`, k = 0..N−2 (5)
//! * moving ⇔ `Mv[0] > M_Thred` (6) and `Var(DMv) < V_Thred` (7), population variance.

use crate::VisionError;
use crate::mapping::RegionMapping;
use quarry_core::{CoreError, Segmentation};
use std::collections::VecDeque;

/// Parameters of the moving-point test (paper: N = 10, M_Thred = 0, V_Thred = 0.01).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MotionTest {
    /// Trajectory length N (≥ 2).
    pub n: usize,
    /// Minimal L1 displacement over the trajectory, eq. (6).
    pub m_thred: f64,
    /// Maximal variance of the normalised displacement steps, eq. (7).
    pub v_thred: f64,
}

impl Default for MotionTest {
    fn default() -> Self {
        Self {
            n: 10,
            m_thred: 0.0,
            v_thred: 0.01,
        }
    }
}

/// The quantities of eqs. (3)–(7) for one trajectory.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MotionStats {
    /// `Mv[0]`, the L1 displacement oldest → newest.
    pub displacement: f64,
    /// `Var(DMv)`.
    pub variance: f64,
    /// Both tests pass.
    pub moving: bool,
}

impl MotionTest {
    /// Validates the parameters.
    pub fn validate(&self) -> Result<(), VisionError> {
        if self.n < 2 {
            return Err(CoreError::invalid("n", format!("must be >= 2, got {}", self.n)).into());
        }
        if !self.m_thred.is_finite() || !self.v_thred.is_finite() {
            return Err(CoreError::invalid("m_thred/v_thred", "must be finite").into());
        }
        Ok(())
    }

    /// Evaluates eqs. (3)–(7) on the last `n` positions (oldest first). `None` when fewer than
    /// `n` positions are given (the paper tests only full trajectories).
    pub fn evaluate(&self, positions: &[(f64, f64)]) -> Result<Option<MotionStats>, VisionError> {
        self.validate()?;
        if positions
            .iter()
            .any(|p| !p.0.is_finite() || !p.1.is_finite())
        {
            return Err(VisionError::NonFinite("trajectory positions"));
        }
        if positions.len() < self.n {
            return Ok(None);
        }
        let t = &positions[positions.len() - self.n..];
        let last = t[self.n - 1];
        let mv: Vec<f64> = t
            .iter()
            .map(|p| (last.0 - p.0).abs() + (last.1 - p.1).abs())
            .collect();
        let max = mv.iter().copied().fold(0.0, f64::max);
        let norm: Vec<f64> = if max > 0.0 {
            mv.iter().map(|m| m / max).collect()
        } else {
            vec![0.0; mv.len()]
        };
        let dmv: Vec<f64> = norm.windows(2).map(|w| (w[0] - w[1]).abs()).collect();
        let n = dmv.len() as f64;
        let mean = dmv.iter().sum::<f64>() / n;
        let variance = dmv.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n;
        Ok(Some(MotionStats {
            displacement: mv[0],
            variance,
            moving: mv[0] > self.m_thred && variance < self.v_thred,
        }))
    }
}

/// Trajectory buffers of the current frame's minima.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MinimumTrajectories {
    /// Maximal length N.
    pub n: usize,
    /// `trajectories[k − 1]`: positions of minimum `k` of the current frame, oldest first.
    pub trajectories: Vec<VecDeque<(u32, u32)>>,
}

impl MinimumTrajectories {
    /// Starts one-point trajectories at the minima of the first frame.
    pub fn new(n: usize, first: &Segmentation) -> Result<Self, VisionError> {
        if n < 1 {
            return Err(CoreError::invalid("n", "must be >= 1").into());
        }
        Ok(Self {
            n,
            trajectories: first
                .minima
                .iter()
                .map(|m| VecDeque::from([m.representative]))
                .collect(),
        })
    }

    /// Moves to the next frame: each bidirectional pair `(i, j)` continues `T(i)` with
    /// `a^{t+1}_j`, every other minimum of `next` starts afresh.
    ///
    /// Errors: a mapping that does not fit the current buffers or `next`.
    pub fn advance(
        &mut self,
        mapping: &RegionMapping,
        next: &Segmentation,
    ) -> Result<(), VisionError> {
        if mapping.forward.len() != self.trajectories.len()
            || mapping.backward.len() != next.n_regions()
        {
            return Err(CoreError::DimensionMismatch {
                what: "trajectory buffers vs region mapping",
                expected: self.trajectories.len(),
                got: mapping.forward.len(),
            }
            .into());
        }
        let mut old = std::mem::take(&mut self.trajectories);
        let mut new: Vec<VecDeque<(u32, u32)>> = next
            .minima
            .iter()
            .map(|m| VecDeque::from([m.representative]))
            .collect();
        for &(i, j) in &mapping.bidirectional {
            let mut t = std::mem::take(&mut old[i as usize - 1]);
            t.push_back(next.minima[j as usize - 1].representative);
            while t.len() > self.n {
                t.pop_front();
            }
            new[j as usize - 1] = t;
        }
        self.trajectories = new;
        Ok(())
    }

    /// The trajectory of minimum `k` of the current frame.
    pub fn get(&self, k: u32) -> Option<&VecDeque<(u32, u32)>> {
        self.trajectories.get(k.checked_sub(1)? as usize)
    }

    /// Runs `test` on every full trajectory; returns `(label, stats)` of the moving ones.
    pub fn moving_points(&self, test: &MotionTest) -> Result<Vec<(u32, MotionStats)>, VisionError> {
        test.validate()?;
        let mut out = Vec::new();
        let mut buf = Vec::with_capacity(test.n);
        for (k, t) in self.trajectories.iter().enumerate() {
            buf.clear();
            buf.extend(t.iter().map(|&(x, y)| (f64::from(x), f64::from(y))));
            if let Some(s) = test.evaluate(&buf)?
                && s.moving
            {
                out.push((k as u32 + 1, s));
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn along_x(xs: &[f64]) -> Vec<(f64, f64)> {
        xs.iter().map(|&x| (x, 3.0)).collect()
    }

    #[test]
    fn spec_reference_values() {
        let t = MotionTest::default();
        // uniform motion
        let s = t
            .evaluate(&along_x(
                &(0..10).map(|k| 2.0 * f64::from(k)).collect::<Vec<_>>(),
            ))
            .unwrap()
            .unwrap();
        assert!(s.variance.abs() < 1e-12 && s.moving);
        assert_eq!(s.displacement, 18.0);
        // single 1-px jump
        let mut xs = vec![0.0; 10];
        xs[5..].fill(1.0);
        let s = t.evaluate(&along_x(&xs)).unwrap().unwrap();
        assert!((s.variance - 8.0 / 81.0).abs() < 1e-9);
        assert!(!s.moving);
        // half speed 0,0,1,1,...,4,4
        let xs: Vec<f64> = (0..10).map(|k| f64::from(k / 2)).collect();
        let s = t.evaluate(&along_x(&xs)).unwrap().unwrap();
        assert!((s.variance - 5.0 / 324.0).abs() < 1e-9, "{}", s.variance);
        assert!(!s.moving);
        // half speed 0,1,1,2,2,...,5
        let xs: Vec<f64> = (0..10).map(|k| f64::from((k + 1) / 2)).collect();
        let s = t.evaluate(&along_x(&xs)).unwrap().unwrap();
        assert!((s.variance - 4.0 / 405.0).abs() < 1e-9, "{}", s.variance);
        assert!(s.moving);
        // static
        let s = t.evaluate(&along_x(&[7.0; 10])).unwrap().unwrap();
        assert_eq!(s.variance, 0.0);
        assert!(!s.moving);
        // too short
        assert!(t.evaluate(&along_x(&[1.0, 2.0])).unwrap().is_none());
        assert!(t.evaluate(&[(f64::NAN, 0.0)]).is_err());
        assert!(MotionTest { n: 1, ..t }.validate().is_err());
    }
}
