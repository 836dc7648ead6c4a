//! Track management: tentative → confirmed → deleted.
//!
//! A [`TrackLifecycle`] is a policy; each track carries the policy's [`TrackLifecycle::Record`]
//! and feeds it one [`ScanObservation`] per scan.
//!
//! - [`MOfN`]: confirm after `m` hits within the first `n` scans (birth counts as a hit); delete a
//!   tentative track as soon as that has become unreachable, a confirmed one after more than
//!   `max_misses` consecutive misses (spec 003 `kf-gnn`: 3 of 4, 5 misses).
//! - [`ExistenceThresholds`]: JIPDA existence — confirm when ψ ≥ `confirm`, delete when
//!   ψ < `delete` (spec 000 A10: 0.9 / 0.05, birth ψ₀ = 0.2).
//! - [`ReplaceOnGateFailure`]: spec 003 Table 1 — a track is reported from birth, deleted the first
//!   scan it has no valid detection, and replaced by a new track (new id, flagged
//!   `GATE_REPLACED`) when its detection fails the position–velocity gate.
//!
//! ```
//! use quarry_assoc::lifecycle::{MOfN, ScanObservation, TrackLifecycle, TrackState};
//! let p = MOfN::new(3, 4, 5)?;
//! let mut r = p.birth();
//! assert_eq!(p.observe(&mut r, &ScanObservation::hit()), TrackState::Tentative);
//! assert_eq!(p.observe(&mut r, &ScanObservation::hit()), TrackState::Confirmed);
//! # Ok::<(), quarry_core::CoreError>(())
//! ```

use quarry_core::CoreError;

/// The state of a managed track.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TrackState {
    /// Not yet confirmed (not reported by default).
    Tentative,
    /// Confirmed (reported).
    Confirmed,
    /// Deleted; the record should be dropped (a deleted track never comes back).
    Deleted,
}

/// What happened to a track in one scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanObservation {
    /// The track was updated with a detection (GNN assignment, or β_0 < 0.5 for soft updates).
    pub detected: bool,
    /// Posterior existence ψ⁺ (JIPDA), if the tracker has one.
    pub existence: Option<f64>,
    /// The detection passed the track's gate (only [`ReplaceOnGateFailure`] looks at it).
    pub gate_passed: bool,
}

impl ScanObservation {
    /// A detected scan that passed its gate.
    pub fn hit() -> Self {
        Self {
            detected: true,
            existence: None,
            gate_passed: true,
        }
    }
    /// A missed scan.
    pub fn miss() -> Self {
        Self {
            detected: false,
            existence: None,
            gate_passed: true,
        }
    }
    /// A scan carrying only an existence probability.
    pub fn with_existence(psi: f64) -> Self {
        Self {
            detected: false,
            existence: Some(psi),
            gate_passed: true,
        }
    }
}

/// A track-management policy.
pub trait TrackLifecycle {
    /// Per-track bookkeeping.
    type Record: Clone + std::fmt::Debug;
    /// The record of a track born this scan (from a detection).
    fn birth(&self) -> Self::Record;
    /// Feeds one scan; returns the new state. Once `Deleted`, always `Deleted`.
    fn observe(&self, rec: &mut Self::Record, obs: &ScanObservation) -> TrackState;
    /// The current state.
    fn state(&self, rec: &Self::Record) -> TrackState;
}

/// M-of-N confirmation with a consecutive-miss deletion rule for confirmed tracks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MOfN {
    m: u32,
    n: u32,
    max_misses: u32,
}

impl MOfN {
    /// `m` hits within the first `n` scans confirm (1 ≤ m ≤ n ≤ 64); a confirmed track is
    /// deleted after more than `max_misses` consecutive misses.
    pub fn new(m: u32, n: u32, max_misses: u32) -> Result<Self, CoreError> {
        if m == 0 || m > n || n > 64 {
            return Err(CoreError::invalid(
                "M-of-N",
                format!("need 1 <= m <= n <= 64, got {m} of {n}"),
            ));
        }
        Ok(Self { m, n, max_misses })
    }
}

/// Bookkeeping of [`MOfN`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MOfNRecord {
    /// Scans since birth, birth included.
    pub scans: u32,
    /// Hits since birth, birth included.
    pub hits: u32,
    /// Consecutive misses.
    pub misses: u32,
    /// Current state.
    pub state: TrackState,
}

impl TrackLifecycle for MOfN {
    type Record = MOfNRecord;
    fn birth(&self) -> MOfNRecord {
        MOfNRecord {
            scans: 1,
            hits: 1,
            misses: 0,
            state: if self.m <= 1 {
                TrackState::Confirmed
            } else {
                TrackState::Tentative
            },
        }
    }
    fn observe(&self, r: &mut MOfNRecord, obs: &ScanObservation) -> TrackState {
        if r.state == TrackState::Deleted {
            return r.state;
        }
        r.scans = r.scans.saturating_add(1);
        if obs.detected {
            r.hits = r.hits.saturating_add(1);
            r.misses = 0;
        } else {
            r.misses = r.misses.saturating_add(1);
        }
        r.state = match r.state {
            TrackState::Tentative => {
                if obs.detected && r.hits >= self.m && r.scans <= self.n {
                    TrackState::Confirmed
                } else if r.hits + self.n.saturating_sub(r.scans) < self.m {
                    TrackState::Deleted
                } else {
                    TrackState::Tentative
                }
            }
            TrackState::Confirmed => {
                if r.misses > self.max_misses {
                    TrackState::Deleted
                } else {
                    TrackState::Confirmed
                }
            }
            TrackState::Deleted => TrackState::Deleted,
        };
        r.state
    }
    fn state(&self, r: &MOfNRecord) -> TrackState {
        r.state
    }
}

/// Existence-based confirmation and deletion for JIPDA.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExistenceThresholds {
    /// Initial existence ψ₀ of a new track.
    pub birth: f64,
    /// Confirm when ψ ≥ this.
    pub confirm: f64,
    /// Delete when ψ < this.
    pub delete: f64,
}

impl Default for ExistenceThresholds {
    /// Spec 000 A10: ψ₀ = 0.2, confirm at 0.9, delete below 0.05.
    fn default() -> Self {
        Self {
            birth: 0.2,
            confirm: 0.9,
            delete: 0.05,
        }
    }
}

impl ExistenceThresholds {
    /// Validated constructor: `0 ≤ delete < confirm ≤ 1`, `birth ∈ [0, 1]`.
    pub fn new(birth: f64, confirm: f64, delete: f64) -> Result<Self, CoreError> {
        let ok = [birth, confirm, delete]
            .iter()
            .all(|v| (0.0..=1.0).contains(v))
            && delete < confirm;
        if !ok {
            return Err(CoreError::invalid(
                "ExistenceThresholds",
                format!(
                    "need 0 <= delete < confirm <= 1 and birth in [0, 1]; got birth {birth}, confirm {confirm}, delete {delete}"
                ),
            ));
        }
        Ok(Self {
            birth,
            confirm,
            delete,
        })
    }
}

/// Bookkeeping of [`ExistenceThresholds`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExistenceRecord {
    /// Latest existence probability.
    pub existence: f64,
    /// Current state.
    pub state: TrackState,
}

impl TrackLifecycle for ExistenceThresholds {
    type Record = ExistenceRecord;
    fn birth(&self) -> ExistenceRecord {
        ExistenceRecord {
            existence: self.birth,
            state: if self.birth >= self.confirm {
                TrackState::Confirmed
            } else {
                TrackState::Tentative
            },
        }
    }
    /// Uses `obs.existence` (a scan without one, or with NaN, keeps the previous ψ).
    fn observe(&self, r: &mut ExistenceRecord, obs: &ScanObservation) -> TrackState {
        if r.state == TrackState::Deleted {
            return r.state;
        }
        if let Some(psi) = obs.existence.filter(|p| p.is_finite()) {
            r.existence = psi.clamp(0.0, 1.0);
        }
        if r.existence < self.delete {
            r.state = TrackState::Deleted;
        } else if r.existence >= self.confirm {
            r.state = TrackState::Confirmed;
        }
        r.state
    }
    fn state(&self, r: &ExistenceRecord) -> TrackState {
        r.state
    }
}

/// Spec 003 Table 1: every track is reported from birth; a scan without a valid detection
/// deletes it; a detection that fails the gate deletes it *and* asks for a replacement track at
/// the detection ([`ReplaceRecord::replace`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ReplaceOnGateFailure;

/// Bookkeeping of [`ReplaceOnGateFailure`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReplaceRecord {
    /// Current state.
    pub state: TrackState,
    /// Set when the track was deleted because its detection failed the gate: the caller creates
    /// a new track there (flags `BORN | GATE_REPLACED`).
    pub replace: bool,
}

impl TrackLifecycle for ReplaceOnGateFailure {
    type Record = ReplaceRecord;
    fn birth(&self) -> ReplaceRecord {
        ReplaceRecord {
            state: TrackState::Confirmed,
            replace: false,
        }
    }
    fn observe(&self, r: &mut ReplaceRecord, obs: &ScanObservation) -> TrackState {
        if r.state == TrackState::Deleted {
            return r.state;
        }
        if !obs.detected {
            r.state = TrackState::Deleted;
        } else if !obs.gate_passed {
            r.state = TrackState::Deleted;
            r.replace = true;
        }
        r.state
    }
    fn state(&self, r: &ReplaceRecord) -> TrackState {
        r.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run<L: TrackLifecycle>(l: &L, seq: &[ScanObservation]) -> Vec<TrackState> {
        let mut r = l.birth();
        seq.iter().map(|o| l.observe(&mut r, o)).collect()
    }

    #[test]
    fn m_of_n() {
        use TrackState::*;
        let p = MOfN::new(3, 4, 2).unwrap();
        let (h, m) = (ScanObservation::hit(), ScanObservation::miss());
        assert_eq!(run(&p, &[h, m, h]), vec![Tentative, Tentative, Confirmed]);
        // Two misses after birth: 1 + (4 − 3) < 3 → unreachable.
        assert_eq!(run(&p, &[m, m]), vec![Tentative, Deleted]);
        // Confirmed then 3 misses > 2 → deleted, and stays deleted.
        assert_eq!(
            run(&p, &[h, h, m, m, m, h]),
            vec![Tentative, Confirmed, Confirmed, Confirmed, Deleted, Deleted]
        );
        assert!(MOfN::new(0, 3, 1).is_err());
        assert!(MOfN::new(4, 3, 1).is_err());
    }

    #[test]
    fn existence() {
        use TrackState::*;
        let p = ExistenceThresholds::default();
        let o = ScanObservation::with_existence;
        assert_eq!(
            run(&p, &[o(0.5), o(0.95), o(0.3), o(0.01)]),
            vec![Tentative, Confirmed, Confirmed, Deleted]
        );
        assert_eq!(run(&p, &[o(f64::NAN)]), vec![Tentative]);
        assert!(ExistenceThresholds::new(0.2, 0.05, 0.9).is_err());
    }

    #[test]
    fn replace_on_gate_failure() {
        let p = ReplaceOnGateFailure;
        let mut r = p.birth();
        assert_eq!(
            p.observe(&mut r, &ScanObservation::hit()),
            TrackState::Confirmed
        );
        let fail = ScanObservation {
            detected: true,
            existence: None,
            gate_passed: false,
        };
        assert_eq!(p.observe(&mut r, &fail), TrackState::Deleted);
        assert!(r.replace);
        let mut r = p.birth();
        assert_eq!(
            p.observe(&mut r, &ScanObservation::miss()),
            TrackState::Deleted
        );
        assert!(!r.replace);
    }
}
