//! The network between the scanner clients and the server: base delay, exponential extra delay,
//! delay spikes, loss and duplicates (profiles `ideal`, `wifi`, `bad` of spec §5).

use crate::SimError;
use quarry_core::CoreError;
use quarry_core::rng::SeededRng;
use rand::Rng;
use rand_distr::{Distribution, Exp};
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// Network profile (spec §5).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct NetworkModel {
    /// Base delay, seconds.
    pub base_s: f64,
    /// Mean of the exponential extra delay, seconds.
    pub exp_mean_s: f64,
    /// Probability of a delay spike of U(50, 300) ms.
    pub p_spike: f64,
    /// Loss probability.
    pub p_loss: f64,
    /// Duplicate probability.
    pub p_dup: f64,
}

impl NetworkModel {
    /// No delay, no loss.
    pub fn ideal() -> Self {
        Self {
            base_s: 0.0,
            exp_mean_s: 0.0,
            p_spike: 0.0,
            p_loss: 0.0,
            p_dup: 0.0,
        }
    }

    /// 2 ms + Exp(3 ms), 1 % spikes, 1 % loss, 0.5 % duplicates.
    pub fn wifi() -> Self {
        Self {
            base_s: 0.002,
            exp_mean_s: 0.003,
            p_spike: 0.01,
            p_loss: 0.01,
            p_dup: 0.005,
        }
    }

    /// 2 ms + Exp(3 ms), 5 % spikes, 5 % loss, 2 % duplicates.
    pub fn bad() -> Self {
        Self {
            p_spike: 0.05,
            p_loss: 0.05,
            p_dup: 0.02,
            ..Self::wifi()
        }
    }

    /// Parses `ideal`, `wifi`, `bad`.
    pub fn parse(s: &str) -> Result<Self, SimError> {
        match s {
            "ideal" => Ok(Self::ideal()),
            "wifi" => Ok(Self::wifi()),
            "bad" => Ok(Self::bad()),
            _ => Err(CoreError::invalid("network", "expected ideal, wifi or bad").into()),
        }
    }

    /// One delay draw, seconds.
    pub fn delay(&self, rng: &mut SeededRng) -> f64 {
        let mut d = self.base_s;
        if self.exp_mean_s > 0.0
            && let Ok(e) = Exp::new(1.0 / self.exp_mean_s)
        {
            d += e.sample(rng);
        }
        if self.p_spike > 0.0 && rng.random_bool(self.p_spike) {
            d += rng.random_range(0.050..0.300);
        }
        d
    }

    /// The delays of the copies of one message that arrive (empty = lost, two = duplicated).
    pub fn deliveries(&self, rng: &mut SeededRng) -> Vec<f64> {
        if self.p_loss > 0.0 && rng.random_bool(self.p_loss) {
            return Vec::new();
        }
        let mut v = vec![self.delay(rng)];
        if self.p_dup > 0.0 && rng.random_bool(self.p_dup) {
            v.push(self.delay(rng));
        }
        v
    }
}
