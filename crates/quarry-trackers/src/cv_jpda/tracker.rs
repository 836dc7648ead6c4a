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

#[derive(Debug, Clone)]
enum Life {
    Existence(quarry_assoc::lifecycle::ExistenceRecord),
    MOfN(quarry_assoc::lifecycle::MOfNRecord),
    Fixed,
}

/// One track of the tracker.
#[derive(Debug, Clone)]
pub struct Track {
    /// Identity (never reused).
    pub id: TrackId,
    /// State estimate `[x, y, vx, vy]`.
    pub est: Gaussian<4>,
    /// Existence probability (JIPDA; 1 otherwise).
    pub existence: f64,
    /// The last scan detected it (`β_i0 < 0.5`); false for a track born in that scan.
    pub detected: bool,
    /// The detection (index into the scan's input) with the largest `β_ij` in the last scan,
    /// when that `β_ij` is larger than `β_i0`; for a newborn track, the detection it started
    /// from.
    pub best_detection: Option<usize>,
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
#[derive(Debug, Clone)]
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
                detected: false,
                best_detection: None,
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

    /// Deletes the weaker of every pair of tracks closer than `d`: a confirmed track beats a
    /// tentative one, then a track this scan detected beats one that coasted (a coasting
    /// track that drifts onto another target must not take over its identity), then the
    /// older (smaller id) wins. Strongest first, so a kept track is never deleted later.
    fn merge_twins(&mut self, d: f64) {
        let n = self.tracks.len();
        let cfg = self.cfg;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&i| {
            let t = &self.tracks[i];
            (t.state(&cfg) != TrackState::Confirmed, !t.detected, t.id.0)
        });
        let d2 = d * d;
        let pos = |t: &Track| Vector2::new(t.est.mean[0], t.est.mean[1]);
        let mut keep = vec![false; n];
        let mut kept: Vec<Vector2<f64>> = Vec::with_capacity(n);
        for i in order {
            let p = pos(&self.tracks[i]);
            if kept.iter().all(|k| (k - p).norm_squared() > d2) {
                keep[i] = true;
                kept.push(p);
            }
        }
        let mut k = keep.into_iter();
        self.tracks.retain(|_| k.next().unwrap_or(true));
    }

    fn birth(&mut self, z: &[f64; 2], j: usize) {
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
            detected: false,
            best_detection: Some(j),
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
        self.advance(stamp, input)?;
        Ok(self.report(stamp))
    }
}

impl JpdaTracker {
    /// [`MultiTargetTracker::step`] without building the reports: predicts, associates,
    /// updates and manages the tracks for one scan of position detections. For a caller that
    /// reads [`tracks`](Self::tracks) and reports in its own form.
    pub fn advance(&mut self, stamp: Stamp, input: &[[f64; 2]]) -> Result<(), TrackerError> {
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
            t.detected = b0 < 0.5;
            t.best_detection = (0..m)
                .filter(|&j| assoc.beta[(i, j + 1)] > b0)
                .max_by(|&a, &b| assoc.beta[(i, a + 1)].total_cmp(&assoc.beta[(i, b + 1)]));
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
            if cfg.merge_distance > 0.0 {
                self.merge_twins(cfg.merge_distance);
            }
            let r2 = cfg.birth_exclusion * cfg.birth_exclusion;
            // Updated positions of the surviving tracks, then of this scan's newborns.
            let mut near: Vec<Vector2<f64>> = if r2 > 0.0 {
                self.tracks
                    .iter()
                    .map(|t| Vector2::new(t.est.mean[0], t.est.mean[1]))
                    .collect()
            } else {
                Vec::new()
            };
            for (j, z) in input.iter().enumerate() {
                let explained: f64 = (0..n).map(|i| assoc.beta[(i, j + 1)]).sum();
                if explained >= 0.5 {
                    continue;
                }
                let zj = Vector2::new(z[0], z[1]);
                if r2 > 0.0 {
                    if near.iter().any(|p| (p - zj).norm_squared() <= r2) {
                        continue;
                    }
                    near.push(zj);
                }
                self.birth(z, j);
            }
        }
        Ok(())
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

    #[test]
    fn merge_distance_deletes_the_younger_twin_of_a_target() {
        // Frames 0-9: two targets 1 m apart. From frame 10 a second view of target 0 appears
        // 0.6 m from it (a twin is born and confirmed); from frame 20 it moves onto target 0
        // and stays 0.05 m beside it.
        let run = |merge_distance: f64| {
            let cfg = JpdaTrackerConfig {
                sigma_meas: 0.05,
                merge_distance,
                ..Default::default()
            };
            let mut t = JpdaTracker::new(cfg).unwrap();
            let mut out = Vec::new();
            for k in 0..40u64 {
                let mut z = vec![[0.0, 0.0], [0.0, 1.0]];
                if k >= 10 {
                    let off = if k < 20 {
                        0.6
                    } else {
                        0.6 - 0.06 * (k - 19) as f64
                    };
                    z.push([off.max(0.05), 0.0]);
                }
                out = t.step(Stamp::from_frame(k, 0.1), &z).unwrap();
            }
            let mut ids: Vec<u32> = out.iter().map(|r| r.id.0).collect();
            ids.sort_unstable();
            ids
        };
        assert_eq!(run(0.0).len(), 3, "without the rule the twin survives");
        assert_eq!(run(0.25), vec![0, 1], "the first two tracks keep their ids");
    }

    #[test]
    fn a_coasting_track_drifting_onto_a_detected_one_is_the_one_merged_away() {
        // Target A walks along x at 1 m/s and is last seen at x = 0 (frame 10); its track
        // coasts on towards target B, which stands at x = 1 and is seen every frame.
        let cfg = JpdaTrackerConfig {
            sigma_meas: 0.05,
            pd: 0.5,
            existence: quarry_assoc::lifecycle::ExistenceThresholds {
                birth: 0.1,
                confirm: 0.9,
                delete: 0.001,
            },
            merge_distance: 0.25,
            ..Default::default()
        };
        let mut t = JpdaTracker::new(cfg).unwrap();
        let mut out = Vec::new();
        for k in 0..25u64 {
            let mut z = vec![[1.0, 0.0]];
            if k <= 10 {
                z.insert(0, [-1.0 + 0.1 * k as f64, 0.0]);
            }
            out = t.step(Stamp::from_frame(k, 0.1), &z).unwrap();
        }
        let ids: Vec<u32> = t.tracks().iter().map(|tr| tr.id.0).collect();
        assert_eq!(
            ids,
            vec![1],
            "B keeps its id; A's coasting track is deleted"
        );
        assert_eq!(out.len(), 1);
    }

    #[test]
    fn birth_exclusion_keeps_a_split_detection_from_starting_a_twin() {
        // Each scan sees one target twice, 0.3 m apart (a split detection).
        let run = |birth_exclusion: f64| {
            let cfg = JpdaTrackerConfig {
                sigma_meas: 0.05,
                birth_exclusion,
                ..Default::default()
            };
            let mut t = JpdaTracker::new(cfg).unwrap();
            let mut out = Vec::new();
            for k in 0..15u64 {
                let x = 0.1 * k as f64;
                out = t
                    .step(Stamp::from_frame(k, 0.1), &vec![[x, 0.0], [x, 0.3]])
                    .unwrap();
            }
            (out.len(), t.tracks().to_vec())
        };
        let (without, _) = run(0.0);
        assert_eq!(without, 2, "without the rule each view gets a track");
        let (with, tracks) = run(0.5);
        assert_eq!(with, 1, "the second view starts no track");
        assert!(tracks[0].detected);
        assert!(tracks[0].best_detection.is_some());
    }
}
