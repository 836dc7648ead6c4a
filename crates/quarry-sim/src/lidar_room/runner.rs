//! The runner: steps the walkers, captures and stamps the scans of every client, delivers them
//! through the network model, and yields scans and ground-truth frames in true-time order.

use super::clock::ClockModel;
use super::people::{Motion, PersonState};
use super::scenario::Scenario;
use super::walkers::Walker;
use super::{FRAME_US, MOTION_STEP_US, SCAN_US};
use crate::SimError;
use quarry_core::rng::{SeededRng, stream};
use quarry_core::{CoreError, Point2, PolarScan, TimeUs};
use rand::Rng;
use rand_distr::Normal;
#[cfg(feature = "serde")]
use serde::{Deserialize, Serialize};

/// A scan as captured and stamped by a client, with its delivery times at the server.
#[derive(Debug, Clone)]
pub struct CapturedScan {
    /// Index of the scanner in the scenario.
    pub scanner: usize,
    /// True capture time.
    pub t_true: TimeUs,
    /// The scan; `scan.t` is the client's synchronised stamp.
    pub scan: PolarScan,
    /// Whether the client's clock was synchronised at capture.
    pub clock_synced: bool,
    /// True arrival times at the server of each delivered copy (empty = lost).
    pub arrivals: Vec<TimeUs>,
}

/// The ground truth of one person at a frame time.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct GtPerson {
    /// Person id.
    pub id: u32,
    /// Torso centre x, metres.
    pub x: f64,
    /// Torso centre y, metres.
    pub y: f64,
    /// Heading, radians.
    pub heading: f64,
    /// Speed, m/s.
    pub speed: f64,
    /// Semi-axis a.
    pub a: f64,
    /// Semi-axis b.
    pub b: f64,
    /// Beams hitting the person in each scanner's latest scan.
    pub pts: Vec<usize>,
}

/// Ground truth at a frame time `t_f = f·50 ms`.
#[derive(Debug, Clone, PartialEq)]
#[cfg_attr(feature = "serde", derive(Serialize, Deserialize))]
pub struct GtFrame {
    /// Frame index.
    pub frame: u64,
    /// Frame time.
    pub t: TimeUs,
    /// People in the room.
    pub people: Vec<GtPerson>,
}

/// One event of a run, in true-time order.
#[derive(Debug, Clone)]
pub enum RoomEvent {
    /// A scan was captured.
    Scan(CapturedScan),
    /// A frame time passed; ground truth at that time.
    Frame(GtFrame),
}

struct ClientSim {
    clock: ClockModel,
    clock_rng: SeededRng,
    noise_rng: SeededRng,
    net_rng: SeededRng,
    phase_us: i64,
    next_j: i64,
    next_sync_us: i64,
    seq: u32,
    counts: Vec<usize>,
}

/// Runs a scenario, yielding [`RoomEvent`]s in true-time order (an `Iterator`).
pub struct Runner {
    sc: Scenario,
    walkers: Vec<Walker>,
    clients: Vec<ClientSim>,
    t_world_us: i64,
    next_frame: u64,
    end_us: i64,
    noise: Normal<f64>,
}

impl Runner {
    /// A runner for `sc` (validated).
    pub fn new(sc: Scenario) -> Result<Self, SimError> {
        sc.validate()?;
        let seed = sc.seed;
        let walkers = sc
            .people
            .iter()
            .map(|p| Walker::new(p.clone(), seed))
            .collect();
        let clients = (0..sc.scanners.len())
            .map(|i| {
                let i = i as u64;
                let mut clock_rng = stream(seed, &[4, i]);
                let clock = ClockModel::new(sc.clock, &mut clock_rng);
                let phase_us = clock_rng.random_range(0..SCAN_US);
                ClientSim {
                    clock,
                    clock_rng,
                    noise_rng: stream(seed, &[2, i]),
                    net_rng: stream(seed, &[3, i]),
                    phase_us,
                    next_j: 0,
                    next_sync_us: 0,
                    seq: 0,
                    counts: Vec::new(),
                }
            })
            .collect();
        let noise =
            Normal::new(0.0, 1.0).map_err(|e| CoreError::invalid("noise", e.to_string()))?;
        Ok(Self {
            end_us: (sc.duration_s * 1e6).round() as i64,
            sc,
            walkers,
            clients,
            t_world_us: 0,
            next_frame: 0,
            noise,
        })
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.sc
    }

    /// True clock offset of client `i` at true time `t` (seconds; `L(t) − t`).
    pub fn clock_offset(&self, i: usize, t: f64) -> Option<f64> {
        self.clients.get(i).map(|c| c.clock.local(t) - t)
    }

    fn advance_to(&mut self, t_us: i64) {
        while self.t_world_us < t_us {
            let t_next = self.t_world_us + MOTION_STEP_US;
            // spawns
            for i in 0..self.walkers.len() {
                if !self.walkers[i].alive
                    && !self.walkers[i].done
                    && (self.walkers[i].spec.t_spawn * 1e6).round() as i64 <= t_next
                {
                    let others: Vec<Point2> = self
                        .walkers
                        .iter()
                        .filter(|w| w.alive)
                        .map(|w| w.state.pos)
                        .collect();
                    // a visitor waits (unborn) while someone is in the doorway
                    if let Motion::Visit(v) = &self.walkers[i].spec.motion
                        && !v.spawn_free(&others)
                    {
                        continue;
                    }
                    let room = self.sc.room.clone();
                    self.walkers[i].spawn(&room, &others);
                }
            }
            let dt = MOTION_STEP_US as f64 * 1e-6;
            for i in 0..self.walkers.len() {
                if !self.walkers[i].alive {
                    continue;
                }
                let others: Vec<Point2> = self
                    .walkers
                    .iter()
                    .enumerate()
                    .filter(|(j, w)| *j != i && w.alive)
                    .map(|(_, w)| w.state.pos)
                    .collect();
                let noise = self.noise;
                let room = &self.sc.room;
                self.walkers[i].step(room, &others, dt, &noise);
            }
            self.t_world_us = t_next;
        }
    }

    /// People alive at time `t_us` (≤ the world time), interpolated.
    fn people_at(&self, t_us: i64) -> Vec<PersonState> {
        let s = 1.0 - (self.t_world_us - t_us) as f64 / MOTION_STEP_US as f64;
        self.walkers
            .iter()
            .filter(|w| w.alive)
            .map(|w| w.at(s.clamp(0.0, 1.0)))
            .collect()
    }

    fn capture(&mut self, i: usize, t_us: i64) -> Result<CapturedScan, SimError> {
        // sync exchanges due before this capture
        while self.clients[i].next_sync_us <= t_us {
            let ts = self.clients[i].next_sync_us;
            let net = self.sc.network;
            let c = &mut self.clients[i];
            let up = net.deliveries(&mut c.net_rng).first().copied();
            let down = net.deliveries(&mut c.net_rng).first().copied();
            c.clock.sync_exchange(ts as f64 * 1e-6, up, down);
            c.next_sync_us += 1_000_000;
        }
        self.advance_to(t_us);
        let people = self.people_at(t_us);
        let arms = self.sc.arms;
        let scanner = &self.sc.scanners[i];
        let c = &mut self.clients[i];
        let (ranges, counts) = scanner.render(&self.sc.room, &people, arms, &mut c.noise_rng);
        c.counts = people
            .iter()
            .zip(&counts)
            .map(|(p, &n)| (p.id as usize, n))
            .fold(vec![0; self.sc.people.len()], |mut v, (id, n)| {
                if let Some(x) = v.get_mut(id) {
                    *x = n;
                }
                v
            });
        let t_true = t_us as f64 * 1e-6;
        let stamp = TimeUs::from_secs_f64(c.clock.stamp(t_true, &mut c.clock_rng));
        let seq = c.seq;
        c.seq = c.seq.wrapping_add(1);
        let scan = PolarScan::try_new(scanner.id, seq, stamp, ranges, scanner.geometry)?;
        let arrivals = self
            .sc
            .network
            .deliveries(&mut c.net_rng)
            .into_iter()
            .map(|d| TimeUs(t_us + ((self.sc.processing_s + d) * 1e6).round() as i64))
            .collect();
        Ok(CapturedScan {
            scanner: i,
            t_true: TimeUs(t_us),
            scan,
            clock_synced: c.clock.is_synced(),
            arrivals,
        })
    }

    fn gt_frame(&mut self, f: u64) -> GtFrame {
        let t_us = f as i64 * FRAME_US;
        self.advance_to(t_us);
        let people = self
            .people_at(t_us)
            .into_iter()
            .map(|p| GtPerson {
                id: p.id,
                x: p.pos.x,
                y: p.pos.y,
                heading: p.heading,
                speed: p.speed,
                a: p.a,
                b: p.b,
                pts: self
                    .clients
                    .iter()
                    .map(|c| c.counts.get(p.id as usize).copied().unwrap_or(0))
                    .collect(),
            })
            .collect();
        GtFrame {
            frame: f,
            t: TimeUs(t_us),
            people,
        }
    }

    /// The next event, or `Ok(None)` at the end of the run.
    pub fn next_event(&mut self) -> Result<Option<RoomEvent>, SimError> {
        let t_frame = self.next_frame as i64 * FRAME_US;
        let next_scan = self
            .clients
            .iter()
            .enumerate()
            .map(|(i, c)| (c.phase_us + c.next_j * SCAN_US, i))
            .min();
        match next_scan {
            Some((ts, i)) if ts < t_frame && ts < self.end_us => {
                self.clients[i].next_j += 1;
                Ok(Some(RoomEvent::Scan(self.capture(i, ts)?)))
            }
            _ if t_frame < self.end_us => {
                self.next_frame += 1;
                Ok(Some(RoomEvent::Frame(self.gt_frame(self.next_frame - 1))))
            }
            _ => Ok(None),
        }
    }
}

impl Iterator for Runner {
    type Item = RoomEvent;
    /// Iterates the events; a failure (which a validated scenario cannot produce) ends the run.
    fn next(&mut self) -> Option<RoomEvent> {
        self.next_event().ok().flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lidar_room::{NetworkModel, SpeedBand};

    fn run_events(sc: Scenario) -> Vec<RoomEvent> {
        Runner::new(sc).unwrap().collect()
    }

    #[test]
    fn deterministic_by_seed() {
        let a = run_events(Scenario::band(SpeedBand::Mid, 3, 4).with_duration(6.0));
        let b = run_events(Scenario::band(SpeedBand::Mid, 3, 4).with_duration(6.0));
        let c = run_events(Scenario::band(SpeedBand::Mid, 3, 5).with_duration(6.0));
        let sig = |ev: &[RoomEvent]| -> Vec<u64> {
            ev.iter()
                .map(|e| match e {
                    RoomEvent::Scan(s) => {
                        s.scan.ranges_mm.iter().map(|&r| u64::from(r)).sum::<u64>()
                            + s.arrivals.iter().map(|t| t.0 as u64).sum::<u64>()
                    }
                    RoomEvent::Frame(f) => f.people.iter().map(|p| (p.x * 1e6) as u64).sum(),
                })
                .collect()
        };
        assert_eq!(sig(&a), sig(&b));
        assert_ne!(sig(&a), sig(&c));
    }

    #[test]
    fn scans_count_person_beams_and_network_loses_some() {
        let sc = Scenario::single_line(2)
            .with_duration(10.0)
            .with_network(NetworkModel::bad());
        let mut lost = 0;
        let mut dup = 0;
        let mut n = 0;
        let mut seen = 0;
        for ev in Runner::new(sc).unwrap() {
            match ev {
                RoomEvent::Scan(s) => {
                    n += 1;
                    lost += usize::from(s.arrivals.is_empty());
                    dup += usize::from(s.arrivals.len() == 2);
                    for a in &s.arrivals {
                        assert!(a.0 >= s.t_true.0 + 3000, "base + processing delay");
                    }
                }
                RoomEvent::Frame(f) => {
                    if let Some(p) = f.people.first() {
                        seen += usize::from(p.pts.iter().sum::<usize>() >= 8);
                    }
                }
            }
        }
        assert_eq!(n, 3 * 400);
        assert!((20..=110).contains(&lost), "5% loss of 1200: {lost}");
        assert!((5..=60).contains(&dup), "2% duplicates: {dup}");
        assert!(
            seen > 90,
            "the walker is seen in most frames after spawn: {seen}"
        );
    }
}
