//! The networked tracker (quarry-net): nodes and server as threads over the in-process
//! transport, against the in-process run of the same scenario.

use quarry_core::TimeUs;
use quarry_net::{
    LocalBus, NetError, Received, SensorSpec, SimSource, Subscription, Transport, WallNodeOptions,
    WallServerOptions, keys, run_sim_node, run_sim_server, run_wall_node, run_wall_server,
};
use quarry_repro::lidar::run_room_default;
use quarry_sim::lidar_room::{ClockProfile, NetworkModel, Scenario, SpeedBand};
use quarry_trackers::lidar_people::LidarPeopleConfig;
use std::sync::{Arc, Mutex};
use std::time::Duration;

fn sensors(sc: &Scenario) -> Vec<SensorSpec> {
    sc.scanners
        .iter()
        .map(|s| (s.id, s.pose, s.geometry))
        .collect()
}

fn networked(sc: &Scenario, cfg: &LidarPeopleConfig) -> quarry_net::ServerRun {
    networked_over(&LocalBus::new(), sc, cfg)
}

fn networked_over<T: Transport + Clone + 'static>(
    bus: &T,
    sc: &Scenario,
    cfg: &LidarPeopleConfig,
) -> quarry_net::ServerRun {
    let nodes: Vec<_> = (0..sc.scanners.len())
        .map(|k| {
            let (bus, sc, cfg) = (bus.clone(), sc.clone(), cfg.clone());
            std::thread::spawn(move || run_sim_node(&bus, sc, k, &cfg, Duration::from_secs(30)))
        })
        .collect();
    let t_end = TimeUs((sc.duration_s * 1e6).round() as i64);
    let run = run_sim_server(bus, &sensors(sc), cfg, t_end, Duration::from_secs(30)).unwrap();
    for n in nodes {
        n.join().unwrap().unwrap();
    }
    run
}

#[test]
fn virtual_time_network_run_equals_the_in_process_run() {
    // the default wifi network: loss, duplicates and delay spikes (late scans) are replayed
    let cfg = LidarPeopleConfig::faithful();
    for (sc, name) in [
        (
            Scenario::band(SpeedBand::Mid, 2, 7).with_duration(10.0),
            "wifi",
        ),
        (
            Scenario::band(SpeedBand::Fast, 2, 8)
                .with_duration(9.0)
                .with_network(NetworkModel::bad())
                .with_clock(ClockProfile::Skewed),
            "bad/skewed",
        ),
    ] {
        let local = run_room_default(sc.clone(), &cfg, &mut |_| {}).unwrap();
        let net = networked(&sc, &cfg);
        assert_eq!(net.frames_tracked, local.frames_tracked, "{name}");
        assert!(
            local.tracks.iter().any(|t| !t.2.is_empty()),
            "{name}: the run has no tracks, the comparison would be empty"
        );
        assert_eq!(net.tracks, local.tracks, "{name}");
        assert!(
            net.stats.dup > 0 || name == "wifi",
            "{name}: {:?}",
            net.stats
        );
        assert!(
            net.stats.lost > 0,
            "{name}: the network lost nothing: {:?}",
            net.stats
        );
        assert_eq!(net.rejected, 0);
    }
}

#[test]
fn a_node_running_another_scenario_is_refused() {
    let cfg = LidarPeopleConfig::faithful();
    let sc = Scenario::band(SpeedBand::Mid, 1, 1).with_duration(2.0);
    let bus = LocalBus::new();
    let other = sc.clone().with_duration(3.0);
    let b2 = bus.clone();
    let c2 = cfg.clone();
    let h = std::thread::spawn(move || run_sim_node(&b2, other, 0, &c2, Duration::from_secs(3)));
    let r = run_sim_server(
        &bus,
        &sensors(&sc),
        &cfg,
        TimeUs(2_000_000),
        Duration::from_secs(30),
    );
    assert!(matches!(r, Err(quarry_net::NetError::Config(_))), "{r:?}");
    drop(bus);
    let _ = h.join();
}

#[test]
fn a_silent_node_times_out_with_a_clear_error() {
    let cfg = LidarPeopleConfig::faithful();
    let sc = Scenario::band(SpeedBand::Mid, 1, 1).with_duration(2.0);
    let bus = LocalBus::new();
    let r = run_sim_server(
        &bus,
        &sensors(&sc),
        &cfg,
        TimeUs(2_000_000),
        Duration::from_millis(300),
    );
    match r {
        Err(quarry_net::NetError::Timeout(m)) => assert!(m.contains("sensor 0"), "{m}"),
        other => panic!("{other:?}"),
    }
}

/// Three wall-clock nodes of 60 scans each and a wall-clock server over the in-process bus.
fn wall_clock_run(
    cfg: &LidarPeopleConfig,
    warmup: Duration,
) -> (Vec<quarry_net::NodeSummary>, quarry_net::ServerRun) {
    let sc = Scenario::band(SpeedBand::Mid, 2, 3).with_network(NetworkModel::ideal());
    let bus = LocalBus::new();
    let opts = WallNodeOptions {
        max_scans: Some(60),
        sync_warmup: warmup,
        ..WallNodeOptions::default()
    };
    let nodes: Vec<_> = (0..3)
        .map(|k| {
            let (bus, sc, cfg) = (bus.clone(), sc.clone(), cfg.clone());
            std::thread::spawn(move || {
                let mut src = SimSource::new(sc, k)?;
                run_wall_node(&bus, &mut src, &cfg, &opts)
            })
        })
        .collect();
    let run = run_wall_server(
        &bus,
        &sensors(&sc),
        cfg,
        &WallServerOptions {
            max_duration: Some(Duration::from_mins(2)),
            idle_timeout: Duration::from_mins(1),
            ..WallServerOptions::default()
        },
    )
    .unwrap();
    let sums = nodes
        .into_iter()
        .map(|n| n.join().unwrap().unwrap())
        .collect();
    (sums, run)
}

#[test]
fn wall_clock_nodes_sync_and_the_server_fuses_every_scan() {
    // What must hold on any machine, however busy: every scan is published, every part is
    // accounted for exactly (accepted, late, unsynchronised or ahead of the server's clock),
    // the server's count of unsynchronised parts is the nodes' own, nothing is malformed or
    // unknown, every node says Hello once and ends. The frame deadline L_max is 5 s here, not
    // 100 ms, so that a starved thread makes scans arrive late without making them "late":
    // how the default deadline holds up under real timing is the soak test below.
    let cfg = LidarPeopleConfig {
        l_max_s: 5.0,
        ..LidarPeopleConfig::faithful()
    };
    let (sums, run) = wall_clock_run(&cfg, Duration::from_secs(2));
    for s in &sums {
        assert_eq!(s.scans, 60);
        assert!(s.sync_replies >= 1, "{s:?}");
    }
    let unsynced: u64 = sums.iter().map(|s| s.unsynced).sum();
    let st = run.stats;
    let datagrams: u64 = sums.iter().map(|s| s.datagrams).sum();
    assert_eq!(
        st.accepted + st.late + st.unsynced + st.future,
        datagrams,
        "{st:?} {sums:?}"
    );
    assert_eq!(st.unsynced, unsynced, "{st:?}");
    assert_eq!(st.malformed + st.unknown + st.dup, 0, "{st:?}");
    assert_eq!(st.restarts, 3); // one Hello per node
    assert!(st.accepted > 0 && run.frames_tracked > 0, "{st:?}");
    for s in &run.sensors {
        assert_eq!(s.state(), "ended", "{s:?}");
    }
}

/// The same run with the default deadlines, asserting timing: on an idle machine at most a
/// few late scans, at most two unsynchronised stamps per node, no negative delay beyond
/// jitter. Timing depends on the machine's load, so this is a soak test, not in the default
/// suite: `cargo test -p quarry-repro --test lidar -- --ignored wall_clock_timing`.
#[test]
#[ignore = "timing soak test: depends on the machine's load"]
fn wall_clock_timing_soak() {
    let (sums, run) = wall_clock_run(&LidarPeopleConfig::faithful(), Duration::from_millis(600));
    for s in &sums {
        assert!(s.sync_replies >= 2, "{s:?}");
        // a clock step of 10 ms or more clears CLOCK_SYNCED for one scan
        assert!(s.unsynced <= 2, "{s:?}");
    }
    let st = run.stats;
    assert!(st.late <= 9, "{st:?}");
    assert_eq!(st.future, 0, "{st:?}");
    assert!(run.frames_tracked >= 25, "{}", run.frames_tracked);
    // the bus is in-process: the skew monitor sees no negative delay beyond jitter
    for (id, l) in &run.min_latency_us {
        let l = l.unwrap_or_else(|| panic!("sensor {id} never heard"));
        assert!(l > -5_000, "sensor {id}: {l} µs");
    }
}

/// Runs `f` on a thread and fails (instead of hanging the test run) when it takes longer than
/// `limit`.
fn within<R: Send + 'static>(limit: Duration, f: impl FnOnce() -> R + Send + 'static) -> R {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(limit) {
        Ok(r) => r,
        Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
            panic!("still running after {} s: deadlock?", limit.as_secs())
        }
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => panic!("the run panicked"),
    }
}

#[test]
fn a_bounded_transport_like_zenoh_does_not_deadlock_the_server() {
    // zenoh's subscriber queue holds 256 samples and blocks the publisher when full; with 8 the
    // nodes fill the server's queue at once. A server subscription that also matched the
    // server's own track messages (the old `quarry/lidar/**`) deadlocked here: the server's
    // thread blocked publishing into its own full queue.
    let cfg = LidarPeopleConfig::faithful();
    let sc = Scenario::band(SpeedBand::Mid, 2, 5).with_duration(4.0);
    let local = run_room_default(sc.clone(), &cfg, &mut |_| {}).unwrap();
    let (sc2, cfg2) = (sc.clone(), cfg.clone());
    let net = within(Duration::from_mins(2), move || {
        networked_over(&LocalBus::bounded(8), &sc2, &cfg2)
    });
    assert_eq!(net.frames_tracked, local.frames_tracked);
    assert_eq!(net.tracks, local.tracks);
}

/// A transport that loses the first `drop_acks` end acknowledgements to every node (as a
/// pub/sub engine does while the node's subscription has not reached the server yet).
#[derive(Clone)]
struct LosesAcks {
    bus: LocalBus,
    drop_acks: usize,
    dropped: Arc<Mutex<Vec<String>>>,
}

impl Transport for LosesAcks {
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError> {
        if key.starts_with("quarry/lidar/endack/") {
            let mut d = self.dropped.lock().unwrap();
            if d.iter().filter(|k| *k == key).count() < self.drop_acks {
                d.push(key.to_string());
                return Ok(());
            }
        }
        self.bus.publish(key, payload)
    }
    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError> {
        self.bus.subscribe(pattern)
    }
}

#[test]
fn lost_end_acknowledgements_are_resent_until_every_node_confirms() {
    let cfg = LidarPeopleConfig::faithful();
    let sc = Scenario::band(SpeedBand::Mid, 1, 6).with_duration(2.0);
    let local = run_room_default(sc.clone(), &cfg, &mut |_| {}).unwrap();
    let t = LosesAcks {
        bus: LocalBus::new(),
        drop_acks: 2,
        dropped: Arc::default(),
    };
    // a spy on the nodes' confirmations
    let mut byes = t.subscribe("quarry/lidar/node/bye/*").unwrap();
    let (t2, sc2, cfg2) = (t.clone(), sc.clone(), cfg.clone());
    let net = within(Duration::from_mins(1), move || {
        networked_over(&t2, &sc2, &cfg2)
    });
    assert_eq!(net.tracks, local.tracks);
    // every node lost two acknowledgements, re-sent its end marker and got the third
    assert_eq!(t.dropped.lock().unwrap().len(), 2 * sc.scanners.len());
    let mut seen: Vec<Received> = Vec::new();
    while let Some(r) = byes.recv_timeout(Duration::from_millis(10)).unwrap() {
        seen.push(r);
    }
    let mut ids: Vec<&str> = seen.iter().map(|r| r.key.as_str()).collect();
    ids.sort_unstable();
    let want: Vec<String> = sc.scanners.iter().map(|s| keys::bye(s.id)).collect();
    assert_eq!(ids, want);
}
