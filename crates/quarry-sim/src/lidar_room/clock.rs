//! Client clocks: offset, drift and stamping jitter, and the NTP-style (or one-way broadcast)
//! offset estimate of spec §5 and §7.3.

use crate::SimError;
use quarry_core::CoreError;
use quarry_core::rng::SeededRng;
use rand::Rng;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// Clock profile of the clients (spec §5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub enum ClockProfile {
    /// Perfect clocks (o = ρ = 0), still with stamping jitter.
    Synced,
    /// Offsets U(−0.5, 0.5) s and drifts U(−50, 50) ppm, NTP-style sync on.
    Skewed,
    /// As `Skewed` with the paper's one-way broadcast sync (biased by the delay).
    SkewedBroadcast,
    /// As `Skewed` without sync (negative control).
    SkewedNoSync,
}

impl ClockProfile {
    /// Parses `synced`, `skewed`, `skewed_broadcast`, `skewed_nosync`.
    pub fn parse(s: &str) -> Result<Self, SimError> {
        match s {
            "synced" => Ok(Self::Synced),
            "skewed" => Ok(Self::Skewed),
            "skewed_broadcast" => Ok(Self::SkewedBroadcast),
            "skewed_nosync" => Ok(Self::SkewedNoSync),
            _ => Err(CoreError::invalid(
                "clock",
                "expected synced, skewed, skewed_broadcast or skewed_nosync",
            )
            .into()),
        }
    }
}

/// One client's clock: `L(t) = t + o + ρ·t`, stamping jitter, and the offset estimate.
#[derive(Debug, Clone)]
pub struct ClockModel {
    /// Offset o, seconds.
    pub offset_s: f64,
    /// Drift ρ (dimensionless; 50 ppm = 5e-5).
    pub drift: f64,
    /// Stamping jitter standard deviation, seconds (0.5 ms).
    pub jitter_s: f64,
    profile: ClockProfile,
    samples: Vec<(f64, f64)>,
    theta: f64,
    synced: bool,
}

impl ClockModel {
    /// A clock of the given profile, drawn from `rng`.
    pub fn new(profile: ClockProfile, rng: &mut SeededRng) -> Self {
        let (o, r) = match profile {
            ClockProfile::Synced => (0.0, 0.0),
            _ => (rng.random_range(-0.5..0.5), rng.random_range(-50e-6..50e-6)),
        };
        Self {
            offset_s: o,
            drift: r,
            jitter_s: 0.0005,
            profile,
            samples: Vec::new(),
            theta: 0.0,
            synced: matches!(profile, ClockProfile::Synced | ClockProfile::SkewedNoSync),
        }
    }

    /// Local time at true time `t` (seconds).
    pub fn local(&self, t: f64) -> f64 {
        t + self.offset_s + self.drift * t
    }

    /// Runs one sync exchange at true time `t` with uplink / downlink delays (seconds; `None` when
    /// a message is lost). NTP-style: θ = ((t2 − t1) + (t3 − t4))/2, keep the sample of smallest
    /// round trip among the last 8 (spec §7.3).
    pub fn sync_exchange(&mut self, t: f64, up: Option<f64>, down: Option<f64>) {
        match self.profile {
            ClockProfile::Synced | ClockProfile::SkewedNoSync => {}
            ClockProfile::SkewedBroadcast => {
                if let Some(d) = down {
                    // server broadcasts its time t; the client sets theta = t - L(arrival)
                    self.theta = t - self.local(t + d);
                    self.synced = true;
                }
            }
            ClockProfile::Skewed => {
                let (Some(d1), Some(d2)) = (up, down) else {
                    return;
                };
                let t1 = self.local(t);
                let t2 = t + d1;
                let t3 = t2;
                let t4 = self.local(t + d1 + d2);
                let theta = f64::midpoint(t2 - t1, t3 - t4);
                let delta = (t4 - t1) - (t3 - t2);
                self.samples.push((delta, theta));
                if self.samples.len() > 8 {
                    self.samples.remove(0);
                }
                if let Some(&(_, th)) = self.samples.iter().min_by(|a, b| a.0.total_cmp(&b.0)) {
                    self.theta = th;
                }
                self.synced = true;
            }
        }
    }

    /// The synchronised stamp of a capture at true time `t` (seconds): `L(t) + jitter + θ̂`.
    pub fn stamp(&self, t: f64, rng: &mut SeededRng) -> f64 {
        let j = self.jitter_s * rng.sample::<f64, _>(rand_distr::StandardNormal);
        self.local(t) + j + self.theta
    }

    /// True once an offset estimate exists (always true for `synced` and `skewed_nosync`).
    pub fn is_synced(&self) -> bool {
        self.synced
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar_room::NetworkModel;
    use quarry_core::rng::stream;

    #[test]
    fn ntp_sync_residual_small() {
        let mut rng = stream(3, &[9]);
        let mut clk = ClockModel::new(ClockProfile::Skewed, &mut rng);
        let net = NetworkModel::wifi();
        let mut nrng = stream(3, &[10]);
        for k in 0..10 {
            let up = net.deliveries(&mut nrng).first().copied();
            let down = net.deliveries(&mut nrng).first().copied();
            clk.sync_exchange(f64::from(k), up, down);
        }
        let mut errs: Vec<f64> = (0..1000)
            .map(|i| {
                let t = 10.0 + f64::from(i) * 0.001;
                (clk.stamp(t, &mut rng) - t).abs()
            })
            .collect();
        errs.sort_by(f64::total_cmp);
        assert!(errs[950] < 0.003, "p95 residual {}", errs[950]);
        assert!(clk.offset_s.abs() > 0.0);
    }
}
