//! `quarry lidar-node` and `quarry lidar-server`: the networked deployment of the lidar people
//! tracker (spec 003 §7) over zenoh (feature `zenoh`, on by default).

use crate::config_args::ConfigArgs;
use crate::output::{CmdError, CmdResult, Output, at};
use clap::Args;
use quarry_core::{Pose2, ScanGeometry, SensorId, TimeUs};
use quarry_data::scans_csv::{ScanCsvOptions, ScanCsvReader, parse_scan_meta};
use quarry_net::proto::SyncMode;
use quarry_net::ros2::{Ros2Options, Ros2ScanSource, Ros2ScanStats, Ros2TrackPublisher};
use quarry_net::{
    ClosedFrame, CsvSource, NodeSummary, SensorSpec, SensorStatus, ServerRun, SimSource, Transport,
    WallNodeOptions, WallServerOptions,
};
use quarry_sim::lidar_room::{ClockProfile, NetworkModel, Scenario, SpeedBand};
use quarry_trackers::lidar_people::{LidarPeopleConfig, Preset};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::time::Duration;

/// The simulated room both node and server must agree on (virtual time), and the tracker
/// configuration.
#[derive(Args, Debug, Clone)]
pub struct RoomArgs {
    /// Walking-speed band of the simulated room: slow, normal, fast.
    #[arg(long, default_value = "normal")]
    pub band: String,
    /// Evaluated frames as in `quarry lidar` (the run lasts 7 s + frames x 50 ms + 0.3 s).
    #[arg(long, default_value_t = 1200)]
    pub frames: usize,
    /// People in the room.
    #[arg(long, default_value_t = 3)]
    pub people: u32,
    /// Seed of the simulated room.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated network (virtual time only): ideal, wifi (default, as `quarry lidar`), bad.
    #[arg(long, default_value = "wifi")]
    pub network: String,
    /// Simulated client clocks (virtual time only): synced (default), skewed,
    /// skewed_broadcast, skewed_nosync.
    #[arg(long, default_value = "synced")]
    pub clock_profile: String,
    /// --preset and --config, as `quarry lidar`.
    #[command(flatten)]
    pub cfg: ConfigArgs<Preset>,
}

/// How to reach the other processes.
#[derive(Args, Debug, Clone)]
pub struct ZenohArgs {
    /// zenoh endpoint to listen on (repeatable), e.g. tcp/0.0.0.0:7447.
    #[arg(long)]
    pub listen: Vec<String>,
    /// zenoh endpoint to connect to (repeatable), e.g. tcp/192.168.1.10:7447.
    #[arg(long)]
    pub connect: Vec<String>,
    /// Also find peers by zenoh multicast scouting (off: only the explicit endpoints).
    #[arg(long)]
    pub multicast: bool,
    /// ROS 2 domain id for --ros2 / --ros2-scan (0-232; default: $ROS_DOMAIN_ID, else 0).
    #[arg(long)]
    pub ros2_domain: Option<u32>,
}

impl ZenohArgs {
    /// The ROS 2 options of this process: domain (flag, else `ROS_DOMAIN_ID`, else 0), the
    /// session's zenoh id and the node name.
    fn ros2(&self, zid: &str, node: &str) -> Result<Ros2Options, CmdError> {
        let domain = match self.ros2_domain {
            Some(d) => d,
            None => match std::env::var("ROS_DOMAIN_ID") {
                Ok(v) if !v.trim().is_empty() => v
                    .trim()
                    .parse()
                    .map_err(|_| format!("ROS_DOMAIN_ID={v:?} is not a domain id (0-232)"))?,
                _ => 0,
            },
        };
        let o = Ros2Options {
            domain,
            zid: zid.into(),
            node: node.into(),
        };
        o.validate().map_err(|e| format!("--ros2-domain: {e}"))?;
        Ok(o)
    }
}

/// The longest wait or run a duration flag accepts: 30 days (anything longer is a typo, and
/// `inf` or `1e20` would not fit a `Duration` or the deadline arithmetic on an `Instant`).
const MAX_FLAG_SECONDS: f64 = 30.0 * 86_400.0;

/// A duration flag in seconds: finite, `>= 0` (or `> 0` when `positive`), at most
/// [`MAX_FLAG_SECONDS`].
fn seconds_flag(flag: &str, v: f64, positive: bool) -> Result<Duration, CmdError> {
    let ok_low = if positive { v > 0.0 } else { v >= 0.0 };
    if !(v.is_finite() && ok_low && v <= MAX_FLAG_SECONDS) {
        let low = if positive { "> 0" } else { ">= 0" };
        return Err(format!(
            "{flag} {v}: expected a number of seconds {low} and at most {MAX_FLAG_SECONDS} (30 days)"
        )
        .into());
    }
    Ok(Duration::try_from_secs_f64(v).map_err(|e| format!("{flag} {v}: {e}"))?)
}

fn clock_mode(s: &str) -> Result<bool, CmdError> {
    match s {
        "virtual" => Ok(true),
        "wall" => Ok(false),
        _ => Err(format!("--clock: expected virtual or wall, got {s:?}").into()),
    }
}

fn load_config(a: &RoomArgs) -> Result<LidarPeopleConfig, CmdError> {
    Ok(a.cfg.load()?)
}

/// The scenario of `quarry lidar --band --people --frames --seed` (same duration formula), with
/// the network and clock profiles.
fn scenario(a: &RoomArgs, cfg: &LidarPeopleConfig) -> Result<Scenario, CmdError> {
    super::lidar::check_frames(a.frames)?;
    let band = SpeedBand::parse(&a.band)?;
    let duration = 7.0 + a.frames as f64 * cfg.frame_period_s + 0.3;
    if a.people > super::lidar::MAX_PEOPLE {
        return Err(format!(
            "--people {}: at most {} walkers fit the 10 x 8 m room",
            a.people,
            super::lidar::MAX_PEOPLE
        )
        .into());
    }
    Ok(Scenario::band(band, a.people, a.seed)
        .with_duration(duration)
        .with_network(NetworkModel::parse(&a.network)?)
        .with_clock(ClockProfile::parse(&a.clock_profile)?))
}

/// The zenoh session and its id (the id names the ROS 2 liveliness tokens).
#[cfg(feature = "zenoh")]
fn open_transport(z: &ZenohArgs) -> Result<(Box<dyn Transport>, String), CmdError> {
    let t = quarry_net::ZenohTransport::open(&quarry_net::ZenohOptions {
        listen: z.listen.clone(),
        connect: z.connect.clone(),
        multicast_scouting: z.multicast,
    })?;
    let zid = t.zid();
    Ok((Box::new(t), zid))
}

#[cfg(not(feature = "zenoh"))]
fn open_transport(_: &ZenohArgs) -> Result<(Box<dyn Transport>, String), CmdError> {
    Err("this quarry was built without the `zenoh` feature (cargo build -p quarry-cli --features zenoh)".into())
}

/// Arguments of `quarry lidar-node`.
#[derive(Args, Debug)]
#[command(
    about = "One laser-scanner client of the networked lidar tracker: background model, publish dynamic points",
    long_about = "One scanner client of the networked people tracker (paper 003, spec §7). It reads a \
scanner source (scanner --scanner K of the simulated room, or a recorded scan CSV with --scans), runs \
the scanner's chi-square background model and publishes the dynamic points of every scan over zenoh \
(keys quarry/lidar/*, see docs/lidar-people.md \"Networked deployment\"). Start the server first; \
the node retries its join request for --wait-server seconds.

Clock modes (--clock):
  wall     (default) scans are paced in real time (--speed), stamped with the node clock \
synchronised to the server's (spec §7.3 NTP-style exchange at 1 Hz) and published as §7.1 wire \
datagrams; the real network's delay, loss and duplicates are handled by the server.
  virtual  simulated room only: the node publishes each scan with its simulated capture time and \
the simulated arrival times of its copies (--network), as fast as the transport takes them; a \
server in virtual mode replays them and reproduces `quarry lidar` with the same --band/--people/\
--frames/--seed exactly.

CSV sources (--scans): one row per scan, stamp_s,r0..r{N-1} (ranges in metres, NaN/inf/empty = \
no return); the geometry comes from --meta (scan_meta.json) and --meta-key. Malformed rows and \
stamps going backwards are skipped and counted.

ROS 2 source (--ros2-scan TOPIC): subscribes to a sensor_msgs/msg/LaserScan topic published by a \
ROS 2 node with rmw_zenoh (connect to its zenoh router, e.g. --connect tcp/127.0.0.1:7447, and to the \
server). The first scan fixes the geometry; scans are sent on as they arrive (a backlog older than \
0.25 s is dropped), and the node stops after --ros2-idle seconds without a scan. Malformed messages, \
a changed beam count, other type hashes and stamps going backwards are skipped and counted (JSON \
field ros2). See docs/ros2.md.

JSON (--json): sensor, scans, datagrams, dynamic_points, lost, duplicated, unsynced, sync_replies, \
offset_us, client_ms_per_scan; with --ros2-scan also ros2 (received, scans, malformed, \
wrong_geometry, foreign_hash, stamps_backwards, stale, first_skip).

EXAMPLES:
  quarry lidar-node --scanner 0 --connect tcp/192.168.1.10:7447
  quarry lidar-node --clock virtual --scanner 2 --frames 200 --seed 4 --connect tcp/127.0.0.1:7447
  quarry lidar-node --scans right.csv --meta scan_meta.json --meta-key positive_1 --sensor-id 0 \\
      --connect tcp/127.0.0.1:7447
  quarry lidar-node --ros2-scan /scan --sensor-id 0 --connect tcp/127.0.0.1:7447"
)]
pub struct LidarNodeArgs {
    /// Clock mode: wall (real time, synchronised clocks) or virtual (simulated time).
    #[arg(long, default_value = "wall")]
    pub clock: String,
    /// Scanner of the simulated room (0 = A, 1 = B, 2 = C); ignored with --scans.
    #[arg(long, default_value_t = 0)]
    pub scanner: usize,
    /// Recorded scans (CSV) instead of the simulated room (wall clock only).
    #[arg(long)]
    pub scans: Option<PathBuf>,
    /// scan_meta.json with the CSV's geometry (default: UTM-30LX, 1081 beams).
    #[arg(long)]
    pub meta: Option<PathBuf>,
    /// Key of the recording in --meta.
    #[arg(long)]
    pub meta_key: Option<String>,
    /// Sensor id of a CSV source (must be in the server's --sensors).
    #[arg(long, default_value_t = 0)]
    pub sensor_id: u16,
    /// Wall clock: replay speed (1 = real time).
    #[arg(long, default_value_t = 1.0)]
    pub speed: f64,
    /// Wall clock: stop after this many scans.
    #[arg(long)]
    pub max_scans: Option<u64>,
    /// Wall clock: no clock synchronisation. Stamps go out without the CLOCK_SYNCED flag and
    /// the server counts and drops every one of them (spec §7.3): a test of that path, not a
    /// way to run.
    #[arg(long)]
    pub no_sync: bool,
    /// Seconds to wait for the server's beacon and, with --ros2-scan, for the first scan (>= 0,
    /// at most 30 days).
    #[arg(long, default_value_t = 30.0)]
    pub wait_server: f64,
    /// Read scans from this ROS 2 LaserScan topic (rmw_zenoh) instead of the simulated room or
    /// a CSV (wall clock only; --sensor-id names the scanner).
    #[arg(long, value_name = "TOPIC")]
    pub ros2_scan: Option<String>,
    /// With --ros2-scan: stop after this many seconds without a scan (> 0, at most 30 days).
    #[arg(long, default_value_t = 5.0)]
    pub ros2_idle: f64,
    #[command(flatten)]
    pub room: RoomArgs,
    #[command(flatten)]
    pub net: ZenohArgs,
}

/// What `quarry lidar-node --json` prints.
#[derive(Debug, Serialize)]
pub struct NodeReport {
    #[serde(flatten)]
    node: NodeSummary,
    /// With --ros2-scan: what the ROS 2 source received and skipped.
    #[serde(skip_serializing_if = "Option::is_none")]
    ros2: Option<Ros2ScanStats>,
}

/// Entry point of `quarry lidar-node`.
pub fn run_node(a: &LidarNodeArgs, out: &Output) -> CmdResult {
    let r = node_inner(a)?;
    let s = r.node;
    out.emit(&r, || {
        let ros2 = r.ros2.as_ref().map_or(String::new(), |st| {
            format!(
                "  ROS 2 source: {} received, {} scans; skipped {} malformed, {} wrong geometry, \
                 {} other type hash, {} stamps backwards, {} stale{}\n",
                st.received,
                st.scans,
                st.malformed,
                st.wrong_geometry,
                st.foreign_hash,
                st.stamps_backwards,
                st.stale,
                st.first_skip
                    .as_ref()
                    .map_or(String::new(), |w| format!(" (first: {w})"))
            )
        });
        format!(
            "lidar-node sensor {}: {} scans, {} datagrams, {} dynamic points; lost {}, duplicated {}, \
             unsynced {}; {} sync replies, offset {}; {:.3} ms per scan\n",
            s.sensor,
            s.scans,
            s.datagrams,
            s.dynamic_points,
            s.lost,
            s.duplicated,
            s.unsynced,
            s.sync_replies,
            s.offset_us.map_or("-".into(), |o| format!("{o:.0} µs")),
            s.client_ms_per_scan
        ) + &ros2
    })
}

fn node_inner(a: &LidarNodeArgs) -> Result<NodeReport, CmdError> {
    let virtual_time = clock_mode(&a.clock)?;
    let cfg = load_config(&a.room)?;
    let wait = seconds_flag("--wait-server", a.wait_server, false)?;
    let report = |node| NodeReport { node, ros2: None };
    if a.scans.is_some() && a.ros2_scan.is_some() {
        return Err("--scans and --ros2-scan are two sources: give one".into());
    }
    if virtual_time {
        if a.scans.is_some() || a.ros2_scan.is_some() {
            return Err(
                "--scans and --ros2-scan need --clock wall (real scans come in real time)".into(),
            );
        }
        let sc = scenario(&a.room, &cfg)?;
        let (t, _) = open_transport(&a.net)?;
        return Ok(report(quarry_net::run_sim_node(
            t.as_ref(),
            sc,
            a.scanner,
            &cfg,
            wait,
        )?));
    }
    let opts = WallNodeOptions {
        speed: a.speed,
        max_scans: a.max_scans,
        wait_server: wait,
        sync: if a.no_sync {
            SyncMode::None
        } else {
            SyncMode::Ntp
        },
        window_m: cfg.window_m as u16,
        ..WallNodeOptions::default()
    };
    if let Some(path) = &a.scans {
        let geometry = match &a.meta {
            Some(m) => {
                let key = a
                    .meta_key
                    .as_deref()
                    .ok_or("--meta needs --meta-key (the recording's key in the file)")?;
                let text = std::fs::read_to_string(m).map_err(at(m))?;
                parse_scan_meta(&text, key)?
            }
            None => ScanGeometry::utm30lx(),
        };
        let f = std::fs::File::open(path).map_err(at(path))?;
        let id = SensorId(a.sensor_id);
        let reader = ScanCsvReader::new(
            std::io::BufReader::new(f),
            geometry,
            ScanCsvOptions {
                sensor: id,
                ..ScanCsvOptions::default()
            },
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        let mut src = CsvSource::new(reader, id, geometry);
        let (t, _) = open_transport(&a.net)?;
        return Ok(report(quarry_net::run_wall_node(
            t.as_ref(),
            &mut src,
            &cfg,
            &opts,
        )?));
    }
    if let Some(topic) = &a.ros2_scan {
        let idle = seconds_flag("--ros2-idle", a.ros2_idle, true)?;
        let (t, zid) = open_transport(&a.net)?;
        let ros = a
            .net
            .ros2(&zid, &format!("quarry_lidar_node_{}", a.sensor_id))?;
        let id = SensorId(a.sensor_id);
        let sub = Ros2ScanSource::subscribe(t.as_ref(), &ros, topic, id)
            .map_err(|e| format!("--ros2-scan {topic}: {e}"))?;
        let mut src = sub.first_scan(wait, idle)?;
        let node = quarry_net::run_wall_node(t.as_ref(), &mut src, &cfg, &opts)?;
        return Ok(NodeReport {
            node,
            ros2: Some(src.stats().clone()),
        });
    }
    let sc = scenario(&a.room, &cfg)?;
    let mut src = SimSource::new(sc, a.scanner)?;
    let (t, _) = open_transport(&a.net)?;
    Ok(report(quarry_net::run_wall_node(
        t.as_ref(),
        &mut src,
        &cfg,
        &opts,
    )?))
}

/// Arguments of `quarry lidar-server`.
#[derive(Args, Debug)]
#[command(
    about = "Fusion server of the networked lidar tracker: fuse by timestamp, track, publish tracks",
    long_about = "The fusion server of the networked people tracker (paper 003, spec §7). It subscribes \
to the nodes' dynamic points, fuses them into 50 ms frames by synchronised timestamp with quarry-cloud's \
FrameAssembler (late, duplicated, out-of-order, multi-part and missing scans, unsynchronised and future \
stamps, restarts and silent sensors handled as spec §7.2 says, and counted), tracks every frame, \
publishes its tracks on quarry/lidar/tracks and writes them to --out. It answers the nodes' clock-sync \
requests (wall clock) and publishes a beacon on quarry/lidar/server/ready at 10 Hz.

Faults: a node with an unknown --sensor-id, or on the other --clock, is refused at once with the \
reason (the node stops with it). Of two servers on one network the younger stops with an error and \
the nodes keep to the older one (each run has its own session id, in its beacon and sync replies). \
A node whose server is restarted re-joins the new one and synchronises again. A node that stops or \
dies is reported in server.json (sensors: state \"silent\", last heard), and the server tracks on \
with the others. Ctrl-C or SIGTERM stops the server cleanly: it closes its frames, tells the nodes \
(they stop at once), writes --out and its summary with \"interrupted\": true, and exits with status \
130. A run that accepted no scan at all exits with an error saying what was dropped and why.

Sensors: the simulated room's three scanners (default), or --sensors FILE.json, a list of \
{\"id\": 0, \"x\": 0.25, \"y\": 0.25, \"theta_deg\": 45, \"geometry\": {...}} (geometry as in \
quarry-core's ScanGeometry; omitted = UTM-30LX).

--clock virtual: replays the virtual-time nodes' simulated deliveries in simulated time; needs the \
same --band/--people/--frames/--seed as the nodes and then writes exactly the tracks of `quarry lidar` \
with those options. --clock wall (default): real time; stops when every sensor has sent its end \
marker, after --duration seconds, or --idle-timeout seconds without data.

ROS 2 (--ros2): the tracks of every frame also go out as ROS 2 messages over rmw_zenoh's keys \
(domain --ros2-domain or $ROS_DOMAIN_ID): --ros2-topic (default /quarry/tracks, \
quarry_msgs/msg/TrackArray), its /poses (geometry_msgs/msg/PoseArray) and /markers \
(visualization_msgs/msg/MarkerArray), positions in --frame-id (default map), stamped with Unix time. \
See docs/ros2.md.

Recording (--mcap FILE): /tracks, /tracks/markers, /fused/points (the fused foreground points the \
nodes sent, a visualization_msgs/msg/Marker of POINTS: the server never sees the full scans), \
/tf_static (each sensor's pose as laser_<id> in map), ROS 2 CDR with the schemas embedded, for \
Foxglove, ros2 bag and Rerun.

Outputs (--out DIR): tracks.csv (frame,t_us,track_id,x,y,alpha,vx,vy,support,rms,born,gate_replaced, \
as `quarry lidar`), tracks_mot.txt (MOTChallenge rows with world x, y) and server.json (the summary).

JSON (--json): clock, frames, frames_no_data, track_rows, ms_per_frame, steps, rejected, \
sync_replies, accepted, dup, late, future, unsynced, unknown, malformed, lost, restarts, bad_points, \
min_latency_us (per sensor: the skew monitor's min(arrival - t_capture)), session, interrupted, \
other_servers, refused (sensor, reason), sensors (per sensor: sensor, state = ended / running / \
silent / never joined, joined, joins, ended, accepted, last_heard_s, silent_for_s).

EXAMPLES:
  quarry lidar-server --listen tcp/0.0.0.0:7447 --out run1
  quarry lidar-server --clock virtual --frames 200 --seed 4 --listen tcp/127.0.0.1:7447 --out net
  quarry lidar-server --sensors robot.json --ros2 --listen tcp/127.0.0.1:7448 --mcap run.mcap"
)]
pub struct LidarServerArgs {
    /// Clock mode: wall (real time) or virtual (replay of virtual-time nodes).
    #[arg(long, default_value = "wall")]
    pub clock: String,
    /// Sensors file (JSON list of id, x, y, theta_deg, geometry); default: the simulated room.
    #[arg(long)]
    pub sensors: Option<PathBuf>,
    /// Output directory (tracks.csv, tracks_mot.txt, server.json).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Wall clock: stop after this many seconds (> 0, at most 30 days).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Stop (wall clock) or fail (virtual time) after this many seconds without data (> 0, at
    /// most 30 days).
    #[arg(long, default_value_t = 20.0)]
    pub idle_timeout: f64,
    /// Also publish the tracks as ROS 2 messages over rmw_zenoh (see --ros2-topic).
    #[arg(long)]
    pub ros2: bool,
    /// With --ros2: the tracks' topic (its /poses and /markers are published too).
    #[arg(long, default_value = "/quarry/tracks")]
    pub ros2_topic: String,
    /// With --ros2: the frame id of the track positions (the sensors' world frame).
    #[arg(long, default_value = "map")]
    pub frame_id: String,
    /// Record the run as MCAP (ROS 2 CDR messages: tracks, markers, fused points, sensor frames).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
    #[command(flatten)]
    pub room: RoomArgs,
    #[command(flatten)]
    pub net: ZenohArgs,
}

#[derive(Debug, Deserialize)]
struct SensorFileEntry {
    id: u16,
    x: f64,
    y: f64,
    theta_deg: f64,
    geometry: Option<ScanGeometry>,
}

/// The JSON summary of `quarry lidar-server`.
#[derive(Debug, Serialize)]
pub struct ServerSummary {
    /// `virtual` or `wall`.
    pub clock: String,
    /// Frames closed and tracked.
    pub frames: usize,
    /// Frames with no data.
    pub frames_no_data: usize,
    /// Track rows written.
    pub track_rows: usize,
    /// Fusion + tracking per frame, ms.
    pub ms_per_frame: f64,
    /// Virtual-time steps processed.
    pub steps: u64,
    /// Node messages rejected.
    pub rejected: u64,
    /// Sync requests answered.
    pub sync_replies: u64,
    /// Scan parts accepted.
    pub accepted: u64,
    /// Duplicates dropped.
    pub dup: u64,
    /// Late parts dropped.
    pub late: u64,
    /// Future-stamped parts dropped.
    pub future: u64,
    /// Unsynchronised parts dropped.
    pub unsynced: u64,
    /// Parts from unknown sensors.
    pub unknown: u64,
    /// Undecodable datagrams.
    pub malformed: u64,
    /// Sequence numbers never seen.
    pub lost: u64,
    /// Sensor restarts.
    pub restarts: u64,
    /// Invalid points skipped.
    pub bad_points: u64,
    /// Per sensor id: min(arrival − t_capture), µs.
    pub min_latency_us: Vec<(u16, Option<i64>)>,
    /// The run's session id (hex).
    pub session: String,
    /// Stopped by Ctrl-C / SIGTERM before the run was complete.
    pub interrupted: bool,
    /// Beacons of other servers seen.
    pub other_servers: u64,
    /// Joins refused: (sensor id, reason).
    pub refused: Vec<(u16, String)>,
    /// Per sensor: what the server knows of it at the end.
    pub sensors: Vec<SensorReport>,
    /// With --ros2: frames published as ROS 2 messages.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ros2_frames: Option<i64>,
    /// With --mcap: the recording.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mcap: Option<crate::record::McapInfo>,
}

/// One sensor in the server's summary.
#[derive(Debug, Serialize)]
pub struct SensorReport {
    /// `ended`, `running`, `silent` (no end marker and nothing for over 2 s: stopped, crashed or
    /// cut off) or `never joined`.
    pub state: &'static str,
    #[serde(flatten)]
    status: SensorStatus,
}

fn summary(clock: &str, r: &ServerRun) -> ServerSummary {
    let s = r.stats;
    ServerSummary {
        clock: clock.into(),
        frames: r.frames_tracked,
        frames_no_data: r.frames_no_data,
        track_rows: r.tracks.iter().map(|t| t.2.len()).sum(),
        ms_per_frame: 1e3 * r.server_seconds / r.frames_tracked.max(1) as f64,
        steps: r.steps,
        rejected: r.rejected,
        sync_replies: r.sync_replies,
        accepted: s.accepted,
        dup: s.dup,
        late: s.late,
        future: s.future,
        unsynced: s.unsynced,
        unknown: s.unknown,
        malformed: s.malformed,
        lost: s.lost,
        restarts: s.restarts,
        bad_points: s.bad_points,
        min_latency_us: r.min_latency_us.clone(),
        session: format!("{:016x}", r.session),
        interrupted: r.interrupted,
        other_servers: r.other_servers,
        refused: r.refused.clone(),
        sensors: r
            .sensors
            .iter()
            .map(|st| SensorReport {
                state: st.state(),
                status: *st,
            })
            .collect(),
        ros2_frames: None,
        mcap: None,
    }
}

/// Why a run that accepted nothing did (an error, not a success with zero scans).
fn nothing_accepted(s: &ServerSummary) -> Option<String> {
    let got = if s.clock == "virtual" {
        s.steps
    } else {
        s.accepted
    };
    if got > 0 || s.interrupted {
        return None;
    }
    let mut why = vec![];
    for (id, r) in &s.refused {
        why.push(format!("sensor {id} refused: {r}"));
    }
    for (n, c) in [
        ("unsynchronised (no CLOCK_SYNCED flag)", s.unsynced),
        ("stamped in the future (another server's clock?)", s.future),
        ("late", s.late),
        ("from unknown sensors", s.unknown),
        ("malformed", s.malformed),
    ] {
        if c > 0 {
            why.push(format!("{c} parts {n}"));
        }
    }
    if why.is_empty() {
        why.push("no node sent anything".into());
    }
    Some(format!("the server accepted no scan: {}", why.join("; ")))
}

/// Entry point of `quarry lidar-server`.
pub fn run_server(a: &LidarServerArgs, out: &Output) -> CmdResult {
    let s = server_inner(a)?;
    if let Some(why) = nothing_accepted(&s) {
        return Err(why.into());
    }
    out.emit(&s, || {
        let lat: Vec<String> = s
            .min_latency_us
            .iter()
            .map(|(id, l)| format!("{id}: {}", l.map_or("-".into(), |v| format!("{v} µs"))))
            .collect();
        format!(
            "lidar-server ({} clock): {} frames ({} without data), {} track rows, {:.3} ms per frame\n  \
             accepted {}, dup {}, late {}, future {}, unsynced {}, unknown {}, malformed {}, lost {}, \
             restarts {}, bad points {}; rejected node messages {}; sync replies {}\n  \
             min(arrival - capture) per sensor: {}\n  \
             sensors: {}{}{}\n",
            s.clock,
            s.frames,
            s.frames_no_data,
            s.track_rows,
            s.ms_per_frame,
            s.accepted,
            s.dup,
            s.late,
            s.future,
            s.unsynced,
            s.unknown,
            s.malformed,
            s.lost,
            s.restarts,
            s.bad_points,
            s.rejected,
            s.sync_replies,
            lat.join(", "),
            s.sensors
                .iter()
                .map(|r| format!("{} {} ({} accepted)", r.status.sensor, r.state, r.status.accepted))
                .collect::<Vec<_>>()
                .join(", "),
            if s.refused.is_empty() {
                String::new()
            } else {
                format!(
                    "; refused: {}",
                    s.refused
                        .iter()
                        .map(|(id, r)| format!("{id}: {r}"))
                        .collect::<Vec<_>>()
                        .join("; ")
                )
            },
            if s.interrupted {
                " (interrupted)"
            } else {
                ""
            }
        )
    })?;
    if s.interrupted {
        return Err(Box::new(crate::interrupt::Interrupted));
    }
    Ok(())
}

fn server_inner(a: &LidarServerArgs) -> Result<ServerSummary, CmdError> {
    let virtual_time = clock_mode(&a.clock)?;
    let cfg = load_config(&a.room)?;
    let sc = scenario(&a.room, &cfg)?;
    let sensors: Vec<SensorSpec> = match &a.sensors {
        None => sc
            .scanners
            .iter()
            .map(|s| (s.id, s.pose, s.geometry))
            .collect(),
        Some(p) => {
            if virtual_time {
                return Err(
                    "--sensors needs --clock wall (virtual time simulates the room's scanners)"
                        .into(),
                );
            }
            let text = std::fs::read_to_string(p).map_err(at(p))?;
            let list: Vec<SensorFileEntry> =
                serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))?;
            list.into_iter()
                .map(|s| {
                    (
                        SensorId(s.id),
                        Pose2::new(s.x, s.y, s.theta_deg.to_radians()),
                        s.geometry.unwrap_or_else(ScanGeometry::utm30lx),
                    )
                })
                .collect()
        }
    };
    let idle = seconds_flag("--idle-timeout", a.idle_timeout, true)?;
    let max_duration = a
        .duration
        .map(|d| seconds_flag("--duration", d, true))
        .transpose()?;
    // the recording first: an unwritable --mcap path fails before any network is opened
    let mut mcap = crate::record::Mcap::open(a.mcap.as_ref())?;
    let (t, zid) = open_transport(&a.net)?;
    let mut ros2 = if a.ros2 {
        let o = a.net.ros2(&zid, "quarry_lidar_server")?;
        Some(
            Ros2TrackPublisher::new(t.as_ref(), &o, &a.ros2_topic, &a.frame_id)
                .map_err(|e| format!("--ros2-topic {}: {e}", a.ros2_topic))?,
        )
    } else {
        None
    };
    let mut tf_written = false;
    let mut observe = |f: &ClosedFrame<'_>| -> Result<(), quarry_net::NetError> {
        if let Some(p) = ros2.as_mut() {
            p.publish(t.as_ref(), f)?;
        }
        if let Some(m) = mcap.as_mut() {
            let stamp = f.unix_us();
            if !tf_written {
                tf_written = true;
                let lasers: Vec<(String, Pose2)> = sensors
                    .iter()
                    .map(|s| (format!("laser_{}", s.0.0), s.1))
                    .collect();
                m.write(
                    "/tf_static",
                    stamp,
                    &crate::record::static_tf(stamp, "map", &lasers),
                )
                .map_err(rec_err)?;
            }
            let tracks = super::lidar::planar(f.tracks);
            m.write(
                "/tracks",
                stamp,
                &crate::record::tracks_msg(stamp, "map", &tracks),
            )
            .map_err(rec_err)?;
            m.write(
                "/tracks/markers",
                stamp,
                &crate::record::markers_msg(stamp, "map", &tracks, 1.2),
            )
            .map_err(rec_err)?;
            let pts: Vec<(f64, f64)> = f.points.iter().map(|p| (p.x, p.y)).collect();
            m.write(
                "/fused/points",
                stamp,
                &quarry_ros2::convert::points_marker(stamp, "map", &pts, 0.04),
            )
            .map_err(rec_err)?;
        }
        Ok(())
    };
    // Ctrl-C / SIGTERM: stop cleanly with what we have
    crate::interrupt::install();
    let run = if virtual_time {
        let t_end = TimeUs((sc.duration_s * 1e6).round() as i64);
        quarry_net::run_sim_server_observed(
            t.as_ref(),
            &sensors,
            &cfg,
            t_end,
            idle,
            crate::interrupt::flag(),
            &mut observe,
        )?
    } else {
        let opts = WallServerOptions {
            max_duration,
            idle_timeout: idle,
            ..WallServerOptions::default()
        };
        quarry_net::run_wall_server_observed(
            t.as_ref(),
            &sensors,
            &cfg,
            &opts,
            crate::interrupt::flag(),
            &mut observe,
        )?
    };
    let mut s = summary(&a.clock, &run);
    s.ros2_frames = ros2.as_ref().map(Ros2TrackPublisher::published);
    if let Some(m) = mcap {
        s.mcap = Some(m.finish()?);
    }
    if let Some(dir) = &a.out {
        std::fs::create_dir_all(dir).map_err(at(dir))?;
        super::lidar::write_tracks(&dir.join("tracks.csv"), &run.tracks)?;
        super::lidar::write_mot(&dir.join("tracks_mot.txt"), &run.tracks)?;
        let js = serde_json::to_string_pretty(&s)?;
        let path = dir.join("server.json");
        std::fs::write(&path, js).map_err(at(&path))?;
    }
    Ok(s)
}

/// A recorder error inside the server's frame observer (which speaks `NetError`).
#[allow(clippy::needless_pass_by_value)] // used as `map_err(rec_err)`
fn rec_err(e: CmdError) -> quarry_net::NetError {
    quarry_net::NetError::Io(format!("--mcap: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn duration_flags_refuse_what_a_duration_cannot_hold() {
        // quarry lidar-node --wait-server inf / 1e20 and lidar-server --duration 1e20 used to
        // panic in Duration::from_secs_f64; --duration -1 / nan / inf ran until killed
        for v in [f64::INFINITY, 1e20, -1.0, f64::NAN, f64::NEG_INFINITY] {
            assert!(seconds_flag("--wait-server", v, false).is_err(), "{v}");
            assert!(seconds_flag("--duration", v, true).is_err(), "{v}");
        }
        assert!(seconds_flag("--duration", 0.0, true).is_err());
        assert_eq!(
            seconds_flag("--wait-server", 0.0, false).unwrap(),
            Duration::ZERO
        );
        assert_eq!(
            seconds_flag("--idle-timeout", 20.0, true).unwrap(),
            Duration::from_secs(20)
        );
        assert!(seconds_flag("--duration", MAX_FLAG_SECONDS, true).is_ok());
        let e = seconds_flag("--duration", 1e20, true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--duration") && e.contains("30 days"), "{e}");
    }

    #[test]
    fn a_run_that_accepted_nothing_is_an_error_saying_why() {
        let mut run = ServerRun::default();
        run.stats.unsynced = 12;
        run.refused
            .push((4, "sensor id 4 is not one of this server's sensors".into()));
        let why = nothing_accepted(&summary("wall", &run)).expect("an error");
        assert!(
            why.contains("12 parts unsynchronised") && why.contains("sensor 4"),
            "{why}"
        );
        let why = nothing_accepted(&summary("wall", &ServerRun::default())).expect("an error");
        assert!(why.contains("no node sent anything"), "{why}");
        // an interrupted run reports what it has instead
        run.interrupted = true;
        assert!(nothing_accepted(&summary("wall", &run)).is_none());
        run.interrupted = false;
        run.stats.accepted = 1;
        assert!(nothing_accepted(&summary("wall", &run)).is_none());
    }
}
