//! Lidar people tracking benchmarks (spec 003 §8), per fused frame of the simulated room:
//!
//! - `lidar_frame/end_to_end_replay/K`: K people walking (band_mid, seed 7, `ideal` network,
//!   `synced` clocks). One iteration = 30 s = 610 fused frames of 50 ms replayed from a fresh
//!   warmed-up state: per frame, the clients' background subtraction of every scan captured in
//!   that period (3 scanners × 2 scans × 1081 beams), the wire encoding and the
//!   `FrameAssembler` fusion, MeanShift, contour ICP and Table 1 (`faithful`). Divide by the
//!   printed frame count for the time per fused frame.
//! - `lidar_frame/server_replay/K`: the same frames, server only (fusion + MeanShift + ICP +
//!   Table 1); the client messages are precomputed.
//! - `lidar_frame/server_replay_jipda/20`: the same 20-person frames with the `jipda` preset
//!   (MeanShift + ICP + CV Kalman/JIPDA; issue 17's budget of 2 ms per frame).
//!
//! - `bg_scan/K`: spec §8's `bg_scan`, the background subtraction of one 1081-beam scan
//!   (`faithful`: m = 40, region constraint, long-term background). One iteration = the 400
//!   scans of scanner A from t = 7 s to 17 s (K people walking) from a fresh warmed-up model;
//!   divide by 400 for the time per scan.
//!
//! - `leg_scan/positive_1`: issue 17's budget, the leg detector + `kf-gnn` tracker
//!   (`detector = legs`) per scan of the real 768-beam leg-height recording
//!   `shared/data/leg-tracker/positive_1` (skipped with a printed reason when absent). One
//!   iteration = the 380 tracked scans from a fresh tracker, on the dynamic points the
//!   background model found (precomputed, untimed); divide by 380 for the time per scan.
//!   `leg_scan/positive_1_jipda`: the same with the `jipda` tracker.
//!
//! The state comes from a 7 s warm-up (untimed setup; the background has learned the room and
//! the tracks exist).
//!
//! `cargo bench --bench lidar -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use quarry::cloud::background::ChiSquareBackground;
use quarry::cloud::scan::BeamTable;
use quarry::core::{
    BeamLabel, FrameIndex, MultiTargetTracker, Pose2, ScanGeometry, SensorId, Stamp, TimeUs,
};
use quarry::data::scans_csv::{ScanCsvOptions, parse_scan_meta, read_scans};
use quarry::net::AssemblerFusion;
use quarry::sim::lidar_room::{ClockProfile, NetworkModel, RoomEvent, Runner, Scenario, SpeedBand};
use quarry::trackers::lidar_people::{
    ClientPipeline, DefaultLidarTracker, Detector, DynamicScan, FusedPoints, LidarPeopleConfig,
    Preset, ServerPipeline, background_of,
};
use quarry::trackers::{PresetName, TrackerConfig};

type Server = ServerPipeline<AssemblerFusion, DefaultLidarTracker>;

struct State {
    clients: Vec<ClientPipeline<ChiSquareBackground>>,
    server: Server,
}

fn scenario(people: u32) -> Scenario {
    Scenario::band(SpeedBand::Mid, people, 7)
        .with_network(NetworkModel::ideal())
        .with_clock(ClockProfile::Synced)
        .with_duration(37.5)
}

/// Events after the warm-up, and a function making the warmed-up state.
fn prepare(people: u32, cfg: LidarPeopleConfig) -> (Vec<RoomEvent>, impl Fn() -> State) {
    let sc = scenario(people);
    let sensors: Vec<(SensorId, Pose2, ScanGeometry)> = sc
        .scanners
        .iter()
        .map(|s| (s.id, s.pose, s.geometry))
        .collect();
    let fresh = move || {
        let sc = scenario(people);
        let clients = sc
            .scanners
            .iter()
            .map(|s| ClientPipeline::new(s.id, background_of(&cfg, &s.geometry).unwrap()))
            .collect();
        let server = ServerPipeline::new(
            AssemblerFusion::new(&sensors, &cfg).unwrap(),
            DefaultLidarTracker::from_config(&cfg).unwrap(),
            cfg.frame_period_s,
        );
        let mut st = State { clients, server };
        let mut runner = Runner::new(sc).unwrap();
        while let Some(ev) = runner.next_event().unwrap() {
            let warm = match &ev {
                RoomEvent::Scan(cs) => cs.t_true.0 < 7_000_000,
                RoomEvent::Frame(g) => g.t.0 < 7_000_000,
            };
            if !warm {
                break;
            }
            step(&mut st, &ev);
        }
        st
    };
    let mut runner = Runner::new(scenario(people)).unwrap();
    let mut events = Vec::new();
    while let Some(ev) = runner.next_event().unwrap() {
        let t = match &ev {
            RoomEvent::Scan(cs) => cs.t_true.0,
            RoomEvent::Frame(g) => g.t.0,
        };
        if t >= 7_000_000 {
            events.push(ev);
        }
    }
    (events, fresh)
}

/// One event; returns whether it was a frame (the server polled and tracked).
fn step(st: &mut State, ev: &RoomEvent) -> bool {
    match ev {
        RoomEvent::Scan(cs) => {
            let msg = st.clients[cs.scanner]
                .on_scan(&cs.scan, cs.clock_synced)
                .unwrap();
            for a in &cs.arrivals {
                st.server.on_message(msg.clone(), *a).unwrap();
            }
            false
        }
        RoomEvent::Frame(g) => {
            black_box(st.server.poll(g.t).unwrap());
            true
        }
    }
}

fn frames(c: &mut Criterion) {
    let mut g = c.benchmark_group("lidar_frame");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    // `faithful` at 5 and 20 people; the `jipda` preset's server at 20 (issue 17)
    for (people, preset) in [
        (5u32, Preset::Faithful),
        (20, Preset::Faithful),
        (20, Preset::Jipda),
    ] {
        let jipda = preset == Preset::Jipda;
        let (events, fresh) = prepare(people, LidarPeopleConfig::preset(preset));
        let n_frames = events
            .iter()
            .filter(|e| matches!(e, RoomEvent::Frame(_)))
            .count();
        // how many tracks the replay carries (printed once, for the record)
        let mut st = fresh();
        let mut n_tracks = 0usize;
        for ev in &events {
            if let RoomEvent::Frame(gt) = ev {
                for (_, _, reps) in st.server.poll(gt.t).unwrap() {
                    n_tracks += reps.len();
                }
            } else {
                step(&mut st, ev);
            }
        }
        eprintln!(
            "lidar_frame/{people} people ({}): one iteration = {n_frames} fused frames, {:.2} tracks per frame",
            preset.name(),
            n_tracks as f64 / n_frames.max(1) as f64
        );
        // end to end: one iteration replays every frame from a fresh warmed-up state
        if !jipda {
            g.bench_function(BenchmarkId::new("end_to_end_replay", people), |b| {
                b.iter_batched(
                    &fresh,
                    |mut st| {
                        for ev in &events {
                            step(&mut st, ev);
                        }
                        st
                    },
                    BatchSize::PerIteration,
                );
            });
        }
        // server only: precompute the client messages of the replay
        let mut st = fresh();
        let msgs: Vec<Result<Vec<(DynamicScan, TimeUs)>, TimeUs>> = events
            .iter()
            .map(|ev| match ev {
                RoomEvent::Scan(cs) => {
                    let m = st.clients[cs.scanner]
                        .on_scan(&cs.scan, cs.clock_synced)
                        .unwrap();
                    Ok(cs.arrivals.iter().map(|a| (m.clone(), *a)).collect())
                }
                RoomEvent::Frame(g) => Err(g.t),
            })
            .collect();
        let name = if jipda {
            "server_replay_jipda"
        } else {
            "server_replay"
        };
        g.bench_function(BenchmarkId::new(name, people), |b| {
            b.iter_batched(
                &fresh,
                |mut st| {
                    for m in &msgs {
                        match m {
                            Ok(list) => {
                                for (d, a) in list {
                                    st.server.on_message(d.clone(), *a).unwrap();
                                }
                            }
                            Err(t) => {
                                black_box(st.server.poll(*t).unwrap());
                            }
                        }
                    }
                    st
                },
                BatchSize::PerIteration,
            );
        });
    }
    g.finish();
}

/// Scanner A's scans after the 7 s warm-up (400 of them) and its warmed-up background model.
fn prepare_bg(people: u32) -> (Vec<quarry::core::PolarScan>, ChiSquareBackground) {
    let cfg = LidarPeopleConfig::faithful();
    let sc = scenario(people);
    let mut bg = background_of(&cfg, &sc.scanners[0].geometry).unwrap();
    let mut runner = Runner::new(sc).unwrap();
    let mut scans = Vec::new();
    while let Some(ev) = runner.next_event().unwrap() {
        if let RoomEvent::Scan(cs) = ev
            && cs.scanner == 0
        {
            if cs.t_true.0 < 7_000_000 {
                bg.classify_scan(&cs.scan).unwrap();
            } else if scans.len() < 400 {
                scans.push(cs.scan);
            } else {
                break;
            }
        }
    }
    (scans, bg)
}

fn bg_scan(c: &mut Criterion) {
    let mut g = c.benchmark_group("bg_scan");
    g.sample_size(20).measurement_time(Duration::from_secs(10));
    for people in [5u32, 20] {
        let (scans, bg) = prepare_bg(people);
        assert_eq!(scans.len(), 400);
        g.bench_function(BenchmarkId::from_parameter(people), |b| {
            b.iter_batched(
                || bg.clone(),
                |mut bg| {
                    for s in &scans {
                        black_box(bg.classify_scan(s).unwrap());
                    }
                    bg
                },
                BatchSize::PerIteration,
            );
        });
    }
    g.finish();
}

/// The dynamic points of every tracked scan of positive_1 (as `run_recorded` computes them).
fn prepare_legs() -> Option<Vec<FusedPoints>> {
    let d = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/leg-tracker");
    let Ok(meta) = std::fs::read_to_string(d.join("scan_meta.json")) else {
        eprintln!("leg_scan skipped: no {}", d.display());
        return None;
    };
    let g = parse_scan_meta(&meta, "positive_1").unwrap();
    let (scans, _) =
        read_scans(d.join("positive_1_scans.csv"), g, ScanCsvOptions::default()).unwrap();
    let cfg = LidarPeopleConfig::kf_gnn();
    let mut bg = background_of(&cfg, &g).unwrap();
    let table = BeamTable::new(&g).unwrap();
    let mut frames = Vec::new();
    for (k, scan) in scans.iter().enumerate() {
        let labels = bg.classify_scan(scan).unwrap();
        if k < cfg.window_m / 2 {
            continue;
        }
        let points = labels
            .iter()
            .enumerate()
            .filter(|(_, l)| **l == BeamLabel::Dynamic)
            .filter_map(|(n, _)| scan.range_m(n).and_then(|r| table.point(n, r)))
            .collect();
        frames.push(FusedPoints {
            t: scan.t,
            points,
            no_data: false,
        });
    }
    Some(frames)
}

fn leg_scan(c: &mut Criterion) {
    let Some(frames) = prepare_legs() else { return };
    assert_eq!(frames.len(), 380);
    let mut g = c.benchmark_group("leg_scan");
    g.sample_size(30).measurement_time(Duration::from_secs(5));
    for (name, preset) in [
        ("positive_1", Preset::KfGnn),
        ("positive_1_jipda", Preset::Jipda),
    ] {
        let cfg = LidarPeopleConfig {
            detector: Detector::Legs,
            ..LidarPeopleConfig::preset(preset)
        };
        g.bench_function(name, |b| {
            b.iter_batched(
                || DefaultLidarTracker::from_config(&cfg).unwrap(),
                |mut tr| {
                    for (k, f) in frames.iter().enumerate() {
                        let stamp = Stamp {
                            frame: FrameIndex(k as u64),
                            t: f.t,
                        };
                        black_box(tr.step(stamp, f).unwrap());
                    }
                    tr
                },
                BatchSize::PerIteration,
            );
        });
    }
    g.finish();
}

criterion_group!(benches, frames, bg_scan, leg_scan);
criterion_main!(benches);
