//! [`JpdaTracker`]: prediction, gating, JPDA / JIPDA association, the PDA update and the track
//! life cycle (see the [module docs](super)).

use nalgebra::{DMatrix, DVector, Matrix2, Matrix4, Vector2, Vector4};
use quarry_assoc::lifecycle::{MOfN, ScanObservation, TrackLifecycle, TrackState};
use quarry_assoc::{ChiSquareGate, Jipda, Jpda};
use quarry_core::{
    Associator, CoreError, Gaussian, LikelihoodMatrix, MultiTargetTracker, Stamp, StateEstimate,
    StateLayout, TimeUs, TrackFlags, TrackId, TrackPrior, TrackReport, TrackStatus,
};
use quarry_filter::ekf::{self, MeasurementPrediction};
use quarry_filter::{ConstantVelocity2, Position2, UpdateForm};

use super::config::{AssocMode, JpdaTrackerConfig};
use crate::{TrackerConfig, TrackerError};

enum Life {
    Existence(quarry_assoc::lifecycle::ExistenceRecord),
    MOfN(quarry_assoc::lifecycle::MOfNRecord),
    Fixed,
}

/// One track of the tracker.
pub struct Track {
    /// Identity (never reused).
    pub id: TrackId,
    /// State estimate `[x, y, vx, vy]`.
    pub est: Gaussian<4>,
    /// Existence probability (JIPDA; 1 otherwise).
    pub existence: f64,
    life: Life,
    born_now: bool,
}

impl Track {
    /// Life-cycle state.
    pub fn state(&self, cfg: &JpdaTrackerConfig) -> TrackState {
        match &self.life {
            Life::Existence(r) => cfg.existence.state(r),
            Life::MOfN(r) => r.state,
            Life::Fixed => TrackState::Confirmed,
        }
    }
}

/// The stand-alone JPDA / JIPDA tracker (see the module docs).
pub struct JpdaTracker {
    cfg: JpdaTrackerConfig,
    motion: ConstantVelocity2,
    meas: Position2,
    gamma: f64,
    m_of_n: MOfN,
    tracks: Vec<Track>,
    next_id: u32,
    last_t: Option<TimeUs>,
    manage: bool,
}

impl JpdaTracker {
    /// A tracker that starts with no tracks and creates them from detections; `cfg` is
    /// validated ([`TrackerConfig::validate`]).
    pub fn new(cfg: JpdaTrackerConfig) -> Result<Self, TrackerError> {
        cfg.validate()?;
        let motion = ConstantVelocity2::cwna(cfg.q)?;
        let meas = Position2::isotropic(cfg.sigma_meas)?;
        let gamma = ChiSquareGate::new(cfg.prob_gate)?.threshold(2)?;
        let (m, n, k) = cfg.m_of_n;
        let m_of_n = MOfN::new(m, n, k)?;
        Ok(Self {
            cfg,
            motion,
            meas,
            gamma,
            m_of_n,
            tracks: Vec::new(),
            next_id: 0,
            last_t: None,
            manage: true,
        })
    }

    /// A tracker with a fixed, known set of tracks (no birth or deletion), starting at time `t0`.
    pub fn with_tracks(
        cfg: JpdaTrackerConfig,
        initial: &[Gaussian<4>],
        t0: TimeUs,
    ) -> Result<Self, TrackerError> {
        let mut s = Self::new(cfg)?;
        for g in initial {
            g.validate()?;
            s.tracks.push(Track {
                id: TrackId(s.next_id),
                est: *g,
                existence: 1.0,
                life: Life::Fixed,
                born_now: false,
            });
            s.next_id += 1;
        }
        s.last_t = Some(t0);
        s.manage = false;
        Ok(s)
    }

    /// The current tracks (all states, including tentative).
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    fn birth(&mut self, z: &[f64; 2]) {
        let sv = self.cfg.birth_vel_sigma * self.cfg.birth_vel_sigma;
        let r = self.cfg.sigma_meas * self.cfg.sigma_meas;
        let est = Gaussian::new_unchecked(
            Vector4::new(z[0], z[1], 0.0, 0.0),
            Matrix4::from_diagonal(&Vector4::new(r, r, sv, sv)),
        );
        let life = match self.cfg.mode {
            AssocMode::Jipda => Life::Existence(self.cfg.existence.birth()),
            AssocMode::Jpda => Life::MOfN(self.m_of_n.birth()),
        };
        self.tracks.push(Track {
            id: TrackId(self.next_id),
            est,
            existence: if self.cfg.mode == AssocMode::Jipda {
                self.cfg.existence.birth
            } else {
                1.0
            },
            life,
            born_now: true,
        });
        self.next_id = self.next_id.saturating_add(1);
    }

    fn report(&self, stamp: Stamp) -> Vec<TrackReport> {
        self.tracks
            .iter()
            .filter_map(|t| {
                let st = t.state(&self.cfg);
                let status = match st {
                    TrackState::Confirmed => TrackStatus::Confirmed,
                    TrackState::Tentative if self.cfg.report_tentative => TrackStatus::Tentative,
                    _ => return None,
                };
                let mut r = TrackReport::new(stamp, t.id, status);
                r.state = Some(StateEstimate {
                    layout: StateLayout::XyVxVy,
                    mean: DVector::from_column_slice(t.est.mean.as_slice()),
                    cov: Some(DMatrix::from_column_slice(4, 4, t.est.cov.as_slice())),
                });
                if self.cfg.mode == AssocMode::Jipda && self.manage {
                    r.existence = Some(t.existence);
                }
                if t.born_now {
                    r.flags.insert(TrackFlags::BORN);
                }
                Some(r)
            })
            .collect()
    }
}

impl MultiTargetTracker for JpdaTracker {
    /// Position detections `[x, y]` of one scan.
    type Input = Vec<[f64; 2]>;
    type Error = TrackerError;

    fn step(
        &mut self,
        stamp: Stamp,
        input: &Vec<[f64; 2]>,
    ) -> Result<Vec<TrackReport>, TrackerError> {
        if input.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CoreError::NonFinite {
                what: "detection position",
            }
            .into());
        }
        let dt = match self.last_t {
            Some(t0) => stamp.t.secs_since(t0),
            None => 0.0,
        };
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(
                CoreError::invalid("stamp", format!("time went backwards by {} s", -dt)).into(),
            );
        }
        self.last_t = Some(stamp.t);
        for t in &mut self.tracks {
            t.born_now = false;
            t.est = ekf::predict(&t.est, &self.motion, &(), dt)?;
        }
        let n = self.tracks.len();
        let m = input.len();
        // Predicted measurements, innovations and gated log-likelihoods.
        let mut preds = Vec::with_capacity(n);
        for t in &self.tracks {
            preds.push(MeasurementPrediction::<4, 2>::new(&t.est, &self.meas)?);
        }
        let mut nus = vec![Vector2::zeros(); n * m];
        let lik = LikelihoodMatrix::from_fn(n, m, |i, j| {
            let p = &preds[i];
            let nu = Vector2::new(input[j][0], input[j][1]) - p.zhat;
            // Cheap rectangular pre-gate, then the ellipse.
            if nu[0] * nu[0] > self.gamma * p.s[(0, 0)] || nu[1] * nu[1] > self.gamma * p.s[(1, 1)]
            {
                return None;
            }
            let d2 = p.nis(&nu);
            if d2 > self.gamma {
                return None;
            }
            nus[i * m + j] = nu;
            Some(p.log_normaliser() - 0.5 * d2)
        })?;
        let jipda = self.cfg.mode == AssocMode::Jipda && self.manage;
        let priors: Vec<TrackPrior> = self
            .tracks
            .iter()
            .map(|t| TrackPrior {
                existence: jipda.then_some(t.existence),
                detection: None,
            })
            .collect();
        let assoc = if jipda {
            Jipda::new(self.cfg.pd, self.cfg.prob_gate, self.cfg.clutter_density)?
                .with_survival(self.cfg.survival)
                .with_solver(self.cfg.solver)
                .associate(&lik, &priors)?
        } else {
            Jpda::new(self.cfg.pd, self.cfg.prob_gate, self.cfg.clutter_density)?
                .with_solver(self.cfg.solver)
                .associate(&lik, &priors)?
        };
        // PDA combined-innovation update (spec 000 §2.9).
        for (i, t) in self.tracks.iter_mut().enumerate() {
            let b0 = assoc.beta[(i, 0)];
            if b0 < 1.0 {
                let p = &preds[i];
                let mut nubar = Vector2::zeros();
                let mut spread = Matrix2::zeros();
                for j in 0..m {
                    let b = assoc.beta[(i, j + 1)];
                    if b > 0.0 {
                        let nu = nus[i * m + j];
                        nubar += b * nu;
                        spread += b * nu * nu.transpose();
                    }
                }
                let pc = p.posterior_cov(&t.est.cov, UpdateForm::Joseph);
                let k = p.gain;
                let mean = t.est.mean + k * nubar;
                let cov = t.est.cov * b0
                    + pc * (1.0 - b0)
                    + k * (spread - nubar * nubar.transpose()) * k.transpose();
                let mut g = Gaussian::new_unchecked(mean, cov);
                g.symmetrize();
                g.validate()?;
                t.est = g;
            }
            if let Some(e) = &assoc.existence {
                t.existence = e[i];
            }
            let obs = ScanObservation {
                detected: b0 < 0.5,
                existence: Some(t.existence),
                gate_passed: true,
            };
            match &mut t.life {
                Life::Existence(r) => {
                    self.cfg.existence.observe(r, &obs);
                }
                Life::MOfN(r) => {
                    self.m_of_n.observe(r, &obs);
                }
                Life::Fixed => {}
            }
        }
        if self.manage {
            let cfg = self.cfg;
            self.tracks.retain(|t| t.state(&cfg) != TrackState::Deleted);
            for (j, z) in input.iter().enumerate() {
                let explained: f64 = (0..n).map(|i| assoc.beta[(i, j + 1)]).sum();
                if explained < 0.5 {
                    self.birth(z);
                }
            }
        }
        Ok(self.report(stamp))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_tracks_follow_targets() {
        let cfg = JpdaTrackerConfig {
            mode: AssocMode::Jpda,
            ..Default::default()
        };
        let p0 = Matrix4::from_diagonal(&Vector4::new(0.25, 0.25, 0.05, 0.05));
        let init = [
            Gaussian::try_new(Vector4::new(0.0, 0.0, 1.0, 0.0), p0).unwrap(),
            Gaussian::try_new(Vector4::new(0.0, 3.0, 1.0, 0.0), p0).unwrap(),
        ];
        let mut t = JpdaTracker::with_tracks(cfg, &init, TimeUs(0)).unwrap();
        let mut out = Vec::new();
        for k in 0..20u64 {
            let x = k as f64;
            out = t
                .step(
                    Stamp::from_frame(k, 1.0),
                    &vec![[x, 3.0], [x, 0.0], [x + 7.0, 30.0]],
                )
                .unwrap();
        }
        assert_eq!(out.len(), 2);
        assert!((out[0].xy().unwrap()[1]).abs() < 0.1);
        assert!((out[1].xy().unwrap()[1] - 3.0).abs() < 0.1);
        assert!((out[0].xy().unwrap()[0] - 19.0).abs() < 0.1);
    }

    #[test]
    fn bad_input_is_an_error() {
        let mut t = JpdaTracker::new(JpdaTrackerConfig::default()).unwrap();
        assert!(
            t.step(Stamp::from_frame(0, 1.0), &vec![[f64::NAN, 0.0]])
                .is_err()
        );
        t.step(Stamp::from_frame(3, 1.0), &vec![]).unwrap();
        assert!(t.step(Stamp::from_frame(1, 1.0), &vec![]).is_err());
        let bad = JpdaTrackerConfig {
            pd: 1.5,
            ..Default::default()
        };
        assert!(JpdaTracker::new(bad).is_err());
    }

    #[test]
    fn jipda_deletes_vanished_targets() {
        let mut t = JpdaTracker::new(JpdaTrackerConfig::default()).unwrap();
        for k in 0..10u64 {
            t.step(Stamp::from_frame(k, 1.0), &vec![[k as f64, 0.0]])
                .unwrap();
        }
        assert_eq!(t.tracks().len(), 1);
        assert!(t.tracks()[0].existence > 0.9);
        for k in 10..30u64 {
            t.step(Stamp::from_frame(k, 1.0), &vec![]).unwrap();
        }
        assert!(t.tracks().is_empty());
    }
}
