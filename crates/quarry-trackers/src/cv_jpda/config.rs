//! [`JpdaTrackerConfig`], [`AssocMode`] and the presets ([`Preset`]: `jipda` = `Default`,
//! `jpda`), following the crate's [configuration convention](crate::TrackerConfig).
//!
//! In TOML: `mode = "jpda"`, `m_of_n = [3, 4, 5]`, `[existence] birth = 0.2 ...`, `[solver]
//! max_states = 262144 ...` with `method = { kind = "k-best", k = 100 }` (or `"auto"`,
//! `"exact"`, `"lbp"` as `{ kind = "..." }`).

use quarry_assoc::lifecycle::{ExistenceThresholds, MOfN};
use quarry_assoc::{Jpda, Method, Solver};
use serde::{Deserialize, Serialize};

use crate::TrackerError;

/// Which associator the tracker uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AssocMode {
    /// JPDA; M-of-N track management.
    Jpda,
    /// JIPDA with existence; existence-threshold track management.
    Jipda,
}

/// The named configurations of [`JpdaTrackerConfig`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Preset {
    /// The shared `jpda_n*` bench scenarios with JIPDA and existence-based track management
    /// (= `JpdaTrackerConfig::default()`).
    #[default]
    Jipda,
    /// The same parameters with JPDA and M-of-N track management (the known-targets workload of
    /// the Stone Soup peer benchmark uses this mode).
    Jpda,
}

impl crate::PresetName for Preset {
    const ALL: &'static [Self] = &[Self::Jipda, Self::Jpda];
    const TRACKER: &'static str = "cv_jpda";

    fn name(self) -> &'static str {
        match self {
            Self::Jipda => "jipda",
            Self::Jpda => "jpda",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Self::Jipda => "bench scenarios, JIPDA with existence-based track management (default)",
            Self::Jpda => "bench scenarios, JPDA with M-of-N track management",
        }
    }
}

/// quarry-assoc's [`ExistenceThresholds`] in serde form.
#[derive(Serialize, Deserialize)]
#[serde(remote = "ExistenceThresholds", deny_unknown_fields)]
struct ExistenceThresholdsDef {
    birth: f64,
    confirm: f64,
    delete: f64,
}

/// quarry-assoc's [`Method`] in serde form.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Method", tag = "kind", rename_all = "kebab-case")]
enum MethodDef {
    Auto,
    Exact,
    KBest { k: usize },
    Lbp,
}

/// quarry-assoc's [`Solver`] in serde form.
#[derive(Serialize, Deserialize)]
#[serde(remote = "Solver", deny_unknown_fields)]
struct SolverDef {
    #[serde(with = "MethodDef")]
    method: Method,
    max_states: usize,
    lbp_max_iter: usize,
    lbp_tol: f64,
}

/// Tracker parameters. `Default` (the `jipda` preset) matches the shared `jpda_n*` bench
/// scenarios (`bench-data/params.json`): P_D 0.9, P_G 0.99, κ = 10/3600 m⁻², q = 0.001, σ = 0.5 m.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct JpdaTrackerConfig {
    /// Detection probability P_D.
    pub pd: f64,
    /// Gate probability P_G (γ = χ²₂⁻¹(P_G)).
    pub prob_gate: f64,
    /// Clutter density κ (m⁻²).
    pub clutter_density: f64,
    /// CWNA process-noise spectral density q (m²/s³).
    pub q: f64,
    /// Position measurement standard deviation (m).
    pub sigma_meas: f64,
    /// JPDA or JIPDA.
    pub mode: AssocMode,
    /// Velocity standard deviation of a newborn track (m/s).
    pub birth_vel_sigma: f64,
    /// JIPDA: existence of a newborn track and confirm / delete thresholds.
    #[serde(with = "ExistenceThresholdsDef")]
    pub existence: ExistenceThresholds,
    /// JIPDA: survival probability per scan.
    pub survival: f64,
    /// JPDA: M-of-N confirmation `(m, n, max consecutive misses)`.
    pub m_of_n: (u32, u32, u32),
    /// Report tentative tracks too.
    pub report_tentative: bool,
    /// A detection left unexplained starts no track when it lies within this distance (m) of
    /// a track's updated position: it is taken as a second view of that target (a split
    /// detection) rather than a new one. 0 (the default) switches the rule off.
    pub birth_exclusion: f64,
    /// Two tracks whose updated positions lie within this distance (m) are taken as one
    /// target tracked twice: a tentative one goes before a confirmed one, then one that this
    /// scan did not detect (a coasting track drifting onto another target) before a detected
    /// one, else the younger (its identity is the newer) is deleted. 0 (the default) switches the rule off. Only for trackers that manage their
    /// tracks ([`JpdaTracker::new`](super::JpdaTracker::new)).
    pub merge_distance: f64,
    /// Association solver (exact / k-best / LBP choice).
    #[serde(with = "SolverDef")]
    pub solver: Solver,
}

impl Default for JpdaTrackerConfig {
    fn default() -> Self {
        Self {
            pd: 0.9,
            prob_gate: 0.99,
            clutter_density: 10.0 / 3600.0,
            q: 0.001,
            sigma_meas: 0.5,
            mode: AssocMode::Jipda,
            birth_vel_sigma: 1.0,
            existence: ExistenceThresholds {
                birth: 0.2,
                confirm: 0.9,
                delete: 0.05,
            },
            survival: 0.99,
            m_of_n: (3, 4, 5),
            report_tentative: false,
            birth_exclusion: 0.0,
            merge_distance: 0.0,
            solver: Solver::default(),
        }
    }
}

impl crate::TrackerConfig for JpdaTrackerConfig {
    type Preset = Preset;
    const NAME: &'static str = "cv_jpda";

    fn preset(p: Preset) -> Self {
        match p {
            Preset::Jipda => Self::default(),
            Preset::Jpda => Self {
                mode: AssocMode::Jpda,
                ..Self::default()
            },
        }
    }

    /// Checks every field (the associator's, the filter's and the life cycle's rules).
    fn validate(&self) -> Result<(), TrackerError> {
        let fail = |m: String| Err(TrackerError::config(Self::NAME, m));
        // pd in (0, 1], prob_gate in (0, 1), clutter_density > 0: quarry-assoc's rules
        if let Err(e) = Jpda::new(self.pd, self.prob_gate, self.clutter_density) {
            return fail(e.to_string());
        }
        if !(self.q.is_finite() && self.q >= 0.0) {
            return fail(format!("q = {} must be finite and >= 0", self.q));
        }
        if !(self.sigma_meas.is_finite() && self.sigma_meas > 0.0) {
            return fail(format!(
                "sigma_meas = {} must be finite and > 0",
                self.sigma_meas
            ));
        }
        if !(self.birth_vel_sigma.is_finite() && self.birth_vel_sigma > 0.0) {
            return fail("birth_vel_sigma must be positive".into());
        }
        if !(self.birth_exclusion.is_finite() && self.birth_exclusion >= 0.0) {
            return fail(format!(
                "birth_exclusion = {} must be finite and >= 0 (metres; 0 = off)",
                self.birth_exclusion
            ));
        }
        if !(self.merge_distance.is_finite() && self.merge_distance >= 0.0) {
            return fail(format!(
                "merge_distance = {} must be finite and >= 0 (metres; 0 = off)",
                self.merge_distance
            ));
        }
        if !(0.0..=1.0).contains(&self.survival) {
            return fail("survival must be in [0, 1]".into());
        }
        let (m, n, k) = self.m_of_n;
        if let Err(e) = MOfN::new(m, n, k) {
            return fail(format!("m_of_n: {e}"));
        }
        let ex = self.existence;
        if let Err(e) = ExistenceThresholds::new(ex.birth, ex.confirm, ex.delete) {
            return fail(format!("existence: {e}"));
        }
        let s = self.solver;
        if s.max_states == 0 || s.lbp_max_iter == 0 || !(s.lbp_tol.is_finite() && s.lbp_tol >= 0.0)
        {
            return fail(format!(
                "solver needs max_states >= 1, lbp_max_iter >= 1 and a finite lbp_tol >= 0, got {s:?}"
            ));
        }
        if let Method::KBest { k: 0 } = s.method {
            return fail("solver method k-best needs k >= 1".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TrackerConfig;

    #[test]
    fn every_preset_validates_and_round_trips() {
        crate::config::check_convention::<JpdaTrackerConfig>();
        let c = JpdaTrackerConfig::from_toml(
            "preset = \"jpda\"\nm_of_n = [2, 3, 4]\n[solver]\nmethod = { kind = \"k-best\", k = 50 }",
            None,
        )
        .unwrap();
        assert_eq!(c.mode, AssocMode::Jpda);
        assert_eq!(c.m_of_n, (2, 3, 4));
        assert_eq!(c.solver.method, Method::KBest { k: 50 });
        assert_eq!(c.solver.max_states, Solver::default().max_states);
        assert_eq!(
            JpdaTrackerConfig::from_toml(&c.to_toml().unwrap(), None).unwrap(),
            c
        );
    }

    #[test]
    fn unknown_keys_and_bad_values_are_errors() {
        for bad in ["pdd = 0.9", "[existence]\nbirht = 0.1", "mode = \"gnn\""] {
            assert!(matches!(
                JpdaTrackerConfig::from_toml(bad, None),
                Err(TrackerError::Toml { .. })
            ));
        }
        for bad in [
            "pd = 1.5",
            "m_of_n = [5, 4, 1]",
            "[existence]\ndelete = 0.95",
            "survival = 2.0",
            "sigma_meas = 0.0",
            "birth_exclusion = -1.0",
            "merge_distance = nan",
        ] {
            assert!(matches!(
                JpdaTrackerConfig::from_toml(bad, None),
                Err(TrackerError::Config {
                    tracker: "cv_jpda",
                    ..
                })
            ));
        }
    }
}
