//! The server's fusion stage over the sans-IO [`FrameAssembler`](crate::proto::FrameAssembler):
//! [`AssemblerFusion`] implements quarry-trackers' [`Fusion`] trait, and every message goes
//! through the wire codec ([`encode_dynamic`]), so the in-process run of the room simulator
//! exercises the same bytes as the networked nodes and server.

use crate::proto::wire::{FLAG_CLOCK_SYNCED, Header, Kind, WireError, encode_scan};
use crate::proto::{FrameAssembler, FrameConfig, SensorConfig};
use quarry_core::{Pose2, ScanGeometry, SensorId, TimeUs};
use quarry_trackers::TrackerError;
use quarry_trackers::lidar_people::{
    DynamicScan, FusedPoints, Fusion, FusionTime, LidarPeopleConfig,
};

/// Encodes a client's dynamic scan as wire datagrams (spec §7.1; several parts when it has more
/// than 350 points).
pub fn encode_dynamic(scan: &DynamicScan, t_send: TimeUs) -> Result<Vec<Vec<u8>>, WireError> {
    let header = Header {
        kind: Kind::DynamicScan,
        sensor: scan.sensor,
        seq: scan.seq,
        part: 0,
        parts: 1,
        flags: if scan.synced { FLAG_CLOCK_SYNCED } else { 0 },
        t_capture: scan.t,
        t_send,
    };
    encode_scan(header, &scan.beams)
}

/// The fusion stage over the sans-IO [`FrameAssembler`]: every message goes through
/// the wire codec, so the in-process run exercises the same bytes as the networked one.
#[derive(Debug)]
pub struct AssemblerFusion {
    /// The assembler.
    pub assembler: FrameAssembler,
    /// Which time a scan is fused by (`cfg.fusion`).
    pub fusion: FusionTime,
}

impl AssemblerFusion {
    /// An assembler for sensors `(id, world pose, geometry)` with the §2.4 times of `cfg`, the
    /// server starting at time 0.
    pub fn new(
        sensors: &[(SensorId, Pose2, ScanGeometry)],
        cfg: &LidarPeopleConfig,
    ) -> Result<Self, TrackerError> {
        let sc: Vec<SensorConfig> = sensors
            .iter()
            .map(|(id, pose, g)| SensorConfig {
                id: *id,
                pose: *pose,
                geometry: *g,
            })
            .collect();
        let fc = FrameConfig {
            period_us: (cfg.frame_period_s * 1e6).round() as i64,
            tau_sync_us: (cfg.tau_sync_s * 1e6).round() as i64,
            max_latency_us: (cfg.l_max_s * 1e6).round() as i64,
            ..FrameConfig::default()
        };
        let assembler = FrameAssembler::new(fc, &sc, TimeUs(0))?;
        Ok(Self {
            assembler,
            fusion: cfg.fusion,
        })
    }
}

impl Fusion for AssemblerFusion {
    fn push(&mut self, mut scan: DynamicScan, arrival: TimeUs) -> Result<(), TrackerError> {
        if self.fusion == FusionTime::Arrival {
            // the negative control: the server's own clock stands in for the capture stamp
            scan.t = arrival;
            scan.synced = true;
        }
        // a dynamic scan always fits the wire format (at most 65535 beams, split in parts), so
        // an encoding error is a bug upstream: report it as a numerical failure of the stage
        let datagrams = encode_dynamic(&scan, scan.t)
            .map_err(|e| quarry_core::CoreError::numerical("wire encode", e.to_string()))?;
        for d in datagrams {
            self.assembler.on_datagram(&d, arrival);
        }
        Ok(())
    }

    fn set_pose(&mut self, sensor: SensorId, pose: Pose2) -> Result<(), TrackerError> {
        Ok(self.assembler.set_pose(sensor, pose)?)
    }

    fn poll(&mut self, now: TimeUs) -> Result<Vec<FusedPoints>, TrackerError> {
        Ok(self
            .assembler
            .poll(now)
            .into_iter()
            .map(|f| FusedPoints {
                t: f.t,
                points: f.points.iter().map(|p| p.p).collect(),
                no_data: f.no_data,
            })
            .collect())
    }
}
