//! Client clock synchronisation (spec 003 §7.3), sans-IO.
//!
//! NTP-style four-timestamp exchange (Cristian 1989; Mills 1991): the client sends t1 (local),
//! the server receives at t2 and replies at t3 (server time), the client receives at t4 (local).
//! `θ = ((t2 − t1) + (t3 − t4))/2`, `δ = (t4 − t1) − (t3 − t2)`. The last 8 samples are kept and θ
//! of the sample with the smallest δ is the estimate. The applied offset follows the estimate:
//! changes below 10 ms are slewed at up to 1 ms per second of local time, so stamps stay
//! monotonic; larger changes (and the first estimate) are stepped, and the next stamp is
//! reported unsynchronised (`CLOCK_SYNCED` clear).

use std::collections::VecDeque;

use quarry_core::{CoreError, TimeUs};

type Result<T, E = CoreError> = std::result::Result<T, E>;

/// Which synchronisation the client runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SyncMode {
    /// Four-timestamp exchange, minimum-delay filter (default).
    #[default]
    Ntp,
    /// The paper's one-way broadcast: `θ = t_server − L(arrival)`, biased by the network delay.
    Broadcast,
    /// No synchronisation: raw local time, never flagged synchronised (negative control).
    None,
}

/// One offset measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SyncSample {
    /// Estimated offset server − client, µs.
    pub offset_us: f64,
    /// Round-trip delay, µs.
    pub delay_us: f64,
}

/// The sample of one four-timestamp exchange.
pub fn ntp_sample(t1: TimeUs, t2: TimeUs, t3: TimeUs, t4: TimeUs) -> SyncSample {
    let (t1, t2, t3, t4) = (t1.0 as f64, t2.0 as f64, t3.0 as f64, t4.0 as f64);
    SyncSample {
        offset_us: f64::midpoint(t2 - t1, t3 - t4),
        delay_us: (t4 - t1) - (t3 - t2),
    }
}

/// The client side of clock synchronisation.
#[derive(Debug, Clone)]
pub struct ClockSync {
    mode: SyncMode,
    samples: VecDeque<SyncSample>,
    target: Option<f64>,
    applied: Option<f64>,
    last_local: Option<i64>,
    step_pending: bool,
    last_stamp: Option<i64>,
    /// Samples kept (8).
    pub window: usize,
    /// Changes at or above this are stepped, µs (10 ms).
    pub step_threshold_us: f64,
    /// Maximum slew rate, seconds of correction per second (1 ms/s = 1e-3).
    pub slew_rate: f64,
}

impl ClockSync {
    /// A synchroniser in the given mode, with the spec's constants.
    pub fn new(mode: SyncMode) -> Self {
        Self {
            mode,
            samples: VecDeque::new(),
            target: None,
            applied: None,
            last_local: None,
            step_pending: false,
            last_stamp: None,
            window: 8,
            step_threshold_us: 10_000.0,
            slew_rate: 1e-3,
        }
    }

    /// The mode.
    pub fn mode(&self) -> SyncMode {
        self.mode
    }

    /// Feeds a `SyncReply` (t1 = client send, t2 = server receive, t3 = server send) received at
    /// local time t4. Rejects exchanges where `t4 < t1` or `t3 < t2`, or with a negative delay.
    pub fn on_sync_reply(&mut self, t1: TimeUs, t2: TimeUs, t3: TimeUs, t4: TimeUs) -> Result<()> {
        if self.mode != SyncMode::Ntp {
            return Ok(());
        }
        if t4 < t1 || t3 < t2 {
            return Err(CoreError::invalid(
                "sync reply",
                "timestamps out of order (t4 < t1 or t3 < t2)",
            ));
        }
        let s = ntp_sample(t1, t2, t3, t4);
        if s.delay_us < 0.0 {
            return Err(CoreError::invalid(
                "sync reply",
                "negative round-trip delay",
            ));
        }
        self.samples.push_back(s);
        while self.samples.len() > self.window.max(1) {
            self.samples.pop_front();
        }
        self.target = self.estimate();
        Ok(())
    }

    /// Feeds a server time broadcast received at local time `local_arrival` (mode `Broadcast`).
    pub fn on_broadcast(&mut self, t_server: TimeUs, local_arrival: TimeUs) {
        if self.mode == SyncMode::Broadcast {
            self.target = Some((t_server.0 - local_arrival.0) as f64);
        }
    }

    /// The current estimate: θ of the minimum-delay sample among the last `window` (NTP), or the
    /// last broadcast offset.
    pub fn estimate(&self) -> Option<f64> {
        match self.mode {
            SyncMode::Ntp => self
                .samples
                .iter()
                .min_by(|a, b| a.delay_us.total_cmp(&b.delay_us))
                .map(|s| s.offset_us),
            SyncMode::Broadcast => self.target,
            SyncMode::None => None,
        }
    }

    /// The offset currently applied, µs.
    pub fn applied_offset(&self) -> Option<f64> {
        self.applied
    }

    /// Stamps a capture at local time `local`: returns the synchronised time and whether it may
    /// be flagged `CLOCK_SYNCED`. Call with non-decreasing local times.
    pub fn stamp(&mut self, local: TimeUs) -> (TimeUs, bool) {
        if self.mode == SyncMode::None {
            return (local, false);
        }
        let dt_s = self
            .last_local
            .map_or(0.0, |l| ((local.0 - l).max(0)) as f64 * 1e-6);
        self.last_local = Some(local.0);
        if let Some(target) = self.target {
            match self.applied {
                None => {
                    self.applied = Some(target);
                    self.step_pending = true;
                }
                Some(a) => {
                    let diff = target - a;
                    if diff.abs() >= self.step_threshold_us {
                        self.applied = Some(target);
                        self.step_pending = true;
                    } else {
                        let max = self.slew_rate * dt_s * 1e6;
                        self.applied = Some(a + diff.clamp(-max, max));
                    }
                }
            }
        }
        let Some(a) = self.applied else {
            return (local, false);
        };
        let mut t = local.0.saturating_add(a.round() as i64);
        // slewing never goes backwards; after a step the flag tells the server
        let synced = !std::mem::take(&mut self.step_pending);
        if synced && let Some(last) = self.last_stamp {
            t = t.max(last);
        }
        self.last_stamp = Some(t);
        (TimeUs(t), synced)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_exchange_is_exact() {
        // client is 300 ms behind the server, 4 ms each way
        let s = ntp_sample(
            TimeUs(1_000_000),
            TimeUs(1_304_000),
            TimeUs(1_305_000),
            TimeUs(1_009_000),
        );
        assert_eq!(s.offset_us, 300_000.0);
        assert_eq!(s.delay_us, 8_000.0);
    }

    #[test]
    fn min_delay_sample_wins_and_stamps_are_monotonic() {
        let mut c = ClockSync::new(SyncMode::Ntp);
        assert_eq!(c.stamp(TimeUs(0)), (TimeUs(0), false));
        let theta = 250_000i64;
        // asymmetric delays bias the estimate; the 1 ms round trip is the best
        for (k, (up, down)) in [(30_000i64, 2_000i64), (500, 500), (10_000, 40_000)]
            .iter()
            .enumerate()
        {
            let t1 = 1_000_000 * (k as i64 + 1);
            let t2 = t1 + theta + up;
            let t3 = t2 + 100;
            let t4 = t3 - theta + down;
            c.on_sync_reply(TimeUs(t1), TimeUs(t2), TimeUs(t3), TimeUs(t4))
                .unwrap();
        }
        assert_eq!(c.estimate(), Some(theta as f64));
        let (t, synced) = c.stamp(TimeUs(5_000_000));
        assert_eq!(t, TimeUs(5_000_000 + theta));
        assert!(!synced); // the first estimate is a step
        assert!(c.stamp(TimeUs(5_025_000)).1);
        // a 5 ms change (symmetric 300 us each way: the new best sample) is slewed at 1 ms/s
        c.on_sync_reply(
            TimeUs(6_000_000),
            TimeUs(6_000_000 + theta + 5_300),
            TimeUs(6_000_000 + theta + 5_400),
            TimeUs(6_000_700),
        )
        .unwrap();
        assert_eq!(c.estimate(), Some((theta + 5_000) as f64));
        let mut last = 0;
        for k in 0..400 {
            let local = 6_100_000 + k * 25_000;
            let (t, synced) = c.stamp(TimeUs(local));
            assert!(synced && t.0 >= last);
            last = t.0;
        }
        // after 10 s of slewing the 5 ms are absorbed
        assert!((c.applied_offset().unwrap() - (theta + 5_000) as f64).abs() < 1.0);
        assert!(
            c.on_sync_reply(TimeUs(10), TimeUs(0), TimeUs(0), TimeUs(5))
                .is_err()
        );
    }

    #[test]
    fn none_and_broadcast() {
        let mut n = ClockSync::new(SyncMode::None);
        n.on_sync_reply(TimeUs(0), TimeUs(10), TimeUs(11), TimeUs(2))
            .unwrap();
        assert_eq!(n.stamp(TimeUs(7)), (TimeUs(7), false));
        let mut b = ClockSync::new(SyncMode::Broadcast);
        b.on_broadcast(TimeUs(1_000_000), TimeUs(400_000));
        assert_eq!(b.stamp(TimeUs(500_000)).0, TimeUs(1_100_000));
    }
}
