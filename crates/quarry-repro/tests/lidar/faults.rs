//! The networked tracker under faults (issue 18): unknown sensors, the wrong clock mode, two
//! servers on one network, a server that restarts, a node that dies, a server stopped from
//! outside. Every test waits for events (a spy on the bus), not for fixed sleeps, so that a
//! busy machine changes how long they take but not what they see.

use quarry_core::SensorId;
use quarry_net::{
    ClockKind, LocalBus, NetError, Received, SensorSpec, SimSource, Subscription, Transport,
    WallNodeOptions, WallServerOptions, keys, run_sim_node, run_wall_node, run_wall_server_until,
    wait_for_server,
};
use quarry_sim::lidar_room::{NetworkModel, Scenario, SpeedBand};
use quarry_trackers::lidar_people::LidarPeopleConfig;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

fn scenario(seconds: f64) -> Scenario {
    Scenario::band(SpeedBand::Mid, 1, 3)
        .with_network(NetworkModel::ideal())
        .with_duration(seconds)
}

fn sensors(sc: &Scenario) -> Vec<SensorSpec> {
    sc.scanners
        .iter()
        .map(|s| (s.id, s.pose, s.geometry))
        .collect()
}

fn node_opts(max_scans: Option<u64>) -> WallNodeOptions {
    WallNodeOptions {
        max_scans,
        sync_warmup: Duration::from_millis(400),
        wait_server: Duration::from_secs(30),
        ..WallNodeOptions::default()
    }
}

/// A wall-clock server on its own thread, stopped by `stop`.
fn server<T: Transport + Clone + 'static>(
    bus: &T,
    sc: &Scenario,
    stop: &Arc<AtomicBool>,
) -> JoinHandle<Result<quarry_net::ServerRun, NetError>> {
    let (bus, specs, stop) = (bus.clone(), sensors(sc), stop.clone());
    std::thread::spawn(move || {
        run_wall_server_until(
            &bus,
            &specs,
            &LidarPeopleConfig::faithful(),
            &WallServerOptions {
                max_duration: Some(Duration::from_mins(2)),
                idle_timeout: Duration::from_mins(1),
                ..WallServerOptions::default()
            },
            &stop,
        )
    })
}

/// A wall-clock node for scanner `k` of `sc` on its own thread.
fn node<T: Transport + Clone + 'static>(
    bus: &T,
    sc: &Scenario,
    k: usize,
    opts: WallNodeOptions,
) -> JoinHandle<Result<quarry_net::NodeSummary, NetError>> {
    let (bus, sc) = (bus.clone(), sc.clone());
    std::thread::spawn(move || {
        let mut src = SimSource::new(sc, k)?;
        run_wall_node(&bus, &mut src, &LidarPeopleConfig::faithful(), &opts)
    })
}

/// Waits (at most two minutes, so that a broken protocol fails instead of hanging) for `n`
/// samples on `sub`.
fn wait_for(sub: &mut dyn Subscription, n: usize, what: &str) -> Vec<Received> {
    let mut got = Vec::new();
    let t0 = std::time::Instant::now();
    while got.len() < n {
        assert!(
            t0.elapsed() < Duration::from_mins(2),
            "waited two minutes for {what}: saw {} of {n}",
            got.len()
        );
        if let Some(r) = sub.recv_timeout(Duration::from_millis(100)).unwrap() {
            got.push(r);
        }
    }
    got
}

/// A transport that can be cut: once `cut` is set, publications vanish and subscriptions stay
/// silent, as for a process that was killed (it says nothing more, not even goodbye).
/// `cut_after` cuts it by itself after that many publications on scan keys.
#[derive(Clone)]
struct Cuttable {
    bus: LocalBus,
    cut: Arc<AtomicBool>,
    scans: Arc<AtomicU64>,
    cut_after: Option<u64>,
}

impl Cuttable {
    fn new(bus: &LocalBus, cut_after: Option<u64>) -> Self {
        Self {
            bus: bus.clone(),
            cut: Arc::default(),
            scans: Arc::default(),
            cut_after,
        }
    }
}

struct CutSub {
    inner: Box<dyn Subscription>,
    cut: Arc<AtomicBool>,
}

impl Subscription for CutSub {
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, NetError> {
        if self.cut.load(Ordering::SeqCst) {
            std::thread::sleep(timeout.min(Duration::from_millis(50)));
            return Ok(None);
        }
        self.inner.recv_timeout(timeout)
    }
}

impl Transport for Cuttable {
    fn publish(&self, key: &str, payload: &[u8]) -> Result<(), NetError> {
        if key.starts_with(keys::SCAN_PREFIX) {
            let n = self.scans.fetch_add(1, Ordering::SeqCst) + 1;
            if self.cut_after.is_some_and(|m| n > m) {
                self.cut.store(true, Ordering::SeqCst);
            }
        }
        if self.cut.load(Ordering::SeqCst) {
            return Ok(());
        }
        self.bus.publish(key, payload)
    }
    fn subscribe(&self, pattern: &str) -> Result<Box<dyn Subscription>, NetError> {
        Ok(Box::new(CutSub {
            inner: self.bus.subscribe(pattern)?,
            cut: self.cut.clone(),
        }))
    }
}

#[test]
fn a_node_with_an_unknown_sensor_id_is_refused_with_the_reason() {
    let sc = scenario(5.0);
    let bus = LocalBus::new();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    // the timeout is long: a refusal must come back at once, not as this timeout
    let r = wait_for_server(&bus, SensorId(99), ClockKind::Wall, Duration::from_mins(1));
    match r {
        Err(NetError::Refused(m)) => {
            assert!(m.contains("99") && m.contains("--sensor-id"), "{m}");
        }
        other => panic!("{other:?}"),
    }
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert!(run.interrupted);
    assert_eq!(run.refused.len(), 1, "{:?}", run.refused);
    assert_eq!(run.refused[0].0, 99);
    assert!(run.sensors.iter().all(|s| s.state() == "never joined"));
}

#[test]
fn a_virtual_time_node_sent_to_a_wall_clock_server_is_refused() {
    let sc = scenario(5.0);
    let bus = LocalBus::new();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    let r = run_sim_node(
        &bus,
        sc.clone(),
        0,
        &LidarPeopleConfig::faithful(),
        Duration::from_mins(1),
    );
    match r {
        Err(NetError::Refused(m)) => assert!(m.contains("--clock"), "{m}"),
        other => panic!("{other:?}"),
    }
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert_eq!(run.refused.len(), 1, "{:?}", run.refused);
    assert!(run.refused[0].1.contains("clock"), "{:?}", run.refused);
    assert_eq!(run.sensors[0].accepted, 0);
}

#[test]
fn a_second_server_gives_way_and_the_nodes_keep_the_first() {
    let sc = scenario(3.0);
    let bus = LocalBus::new();
    let mut ready = bus.subscribe(keys::SERVER_READY).unwrap();
    let stop_a = Arc::new(AtomicBool::new(false));
    let a = server(&bus, &sc, &stop_a);
    wait_for(ready.as_mut(), 1, "the first server's beacon");
    // the second server sees the older one's beacon within its first 100 ms and stops
    let stop_b = Arc::new(AtomicBool::new(false));
    let b = server(&bus, &sc, &stop_b).join().unwrap();
    match b {
        Err(NetError::Conflict(m)) => assert!(m.contains("another lidar-server"), "{m}"),
        other => panic!("the second server should give way: {other:?}"),
    }
    let nodes: Vec<_> = (0..sc.scanners.len())
        .map(|k| node(&bus, &sc, k, node_opts(Some(15))))
        .collect();
    for n in nodes {
        let s = n.join().unwrap().unwrap();
        assert_eq!(s.scans, 15);
        assert_eq!(s.rejoins, 0, "{s:?}");
        assert_eq!(s.foreign_sync_replies, 0, "{s:?}");
    }
    let run = a.join().unwrap().unwrap();
    assert!(!run.interrupted);
    assert!(run.other_servers >= 1, "{run:?}");
    for s in &run.sensors {
        assert_eq!(s.state(), "ended", "{s:?}");
        assert!(s.accepted > 0, "{s:?}");
    }
}

#[test]
fn a_restarted_server_is_joined_again_and_receives_scans() {
    let sc = scenario(60.0);
    let bus = LocalBus::new();
    let mut spy = bus.subscribe(&keys::scan(SensorId(0))).unwrap();
    // the first server dies without a word once it has seen a few scans
    let first = Cuttable::new(&bus, None);
    let stop_a = Arc::new(AtomicBool::new(false));
    let a = server(&first, &sc, &stop_a);
    let n = node(&bus, &sc, 0, node_opts(Some(200)));
    wait_for(spy.as_mut(), 6, "the node's first scans");
    first.cut.store(true, Ordering::SeqCst);
    stop_a.store(true, Ordering::SeqCst);
    let run_a = a.join().unwrap().unwrap();
    assert!(run_a.sensors[0].accepted > 0, "{:?}", run_a.sensors);
    // a new server on the same network: the node notices the old one is gone, joins the new
    // one (new session, new clock), and its remaining scans are accepted there
    let stop_b = Arc::new(AtomicBool::new(false));
    let b = server(&bus, &sc, &stop_b);
    let s = n.join().unwrap().unwrap();
    assert_eq!(s.scans, 200);
    assert_eq!(s.rejoins, 1, "{s:?}");
    stop_b.store(true, Ordering::SeqCst); // its other two sensors never come
    let run_b = b.join().unwrap().unwrap();
    assert_ne!(run_b.session, run_a.session);
    let st = run_b.sensors[0];
    assert_eq!(st.joins, 1, "{st:?}");
    assert_eq!(st.state(), "ended", "{st:?}");
    assert!(st.accepted > 0, "{st:?}");
    assert!(run_b.frames_tracked > 0, "{run_b:?}");
}

#[test]
fn a_node_that_dies_is_named_silent_in_the_report() {
    let sc = scenario(60.0);
    let bus = LocalBus::new();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    // sensor 0 "dies" after its Hello and 5 scans; sensor 1 works and finishes
    let dying = Cuttable::new(&bus, Some(6));
    let d = node(
        &dying,
        &sc,
        0,
        WallNodeOptions {
            wait_server: Duration::from_secs(3),
            ..node_opts(Some(30))
        },
    );
    let ok = node(&bus, &sc, 1, node_opts(Some(10)));
    ok.join().unwrap().unwrap();
    // the dead node's own thread ends with a timeout (its end marker never arrives), at least
    // 3 s after its last datagram
    assert!(matches!(d.join().unwrap(), Err(NetError::Timeout(_))));
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert!(run.interrupted);
    let dead = run.sensors[0];
    assert_eq!(dead.state(), "silent", "{dead:?}");
    assert!(dead.joined && !dead.ended, "{dead:?}");
    // it was heard, and at most its five scans were fused (on a busy machine some may count
    // as late instead of accepted: the other tests of this file assert only the accounting)
    assert!(dead.last_heard_s.is_some(), "{dead:?}");
    assert!(dead.accepted <= 5, "{dead:?}");
    assert_eq!(run.sensors[1].state(), "ended", "{:?}", run.sensors[1]);
    assert_eq!(
        run.sensors[2].state(),
        "never joined",
        "{:?}",
        run.sensors[2]
    );
}

#[test]
fn a_stopped_server_tells_its_nodes_and_reports_what_it_has() {
    let sc = scenario(60.0);
    let bus = LocalBus::new();
    let mut spy = bus.subscribe(&keys::scan(SensorId(1))).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    let nodes: Vec<_> = (0..2)
        .map(|k| node(&bus, &sc, k, node_opts(None)))
        .collect();
    wait_for(spy.as_mut(), 4, "the node's first scans");
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert!(run.interrupted);
    for n in nodes {
        match n.join().unwrap() {
            Err(NetError::ServerEnded(m)) => assert!(m.contains("stopped"), "{m}"),
            other => panic!("the node should stop with the server: {other:?}"),
        }
    }
    // the spy saw node 1's Hello and at least three scan datagrams before the stop: the server
    // fuses what had arrived before it closes (`STOP_DRAIN`), so each is accounted for. Whether
    // a scan counts as accepted or late depends on the machine's load (CI saw 0 accepted once,
    // before the drain existed): the test asserts only the accounting.
    assert!(run.sensors[1].last_heard_s.is_some(), "{:?}", run.sensors);
    let st = &run.stats;
    let classified = st.accepted + st.dup + st.late + st.future + st.unsynced;
    assert!(classified >= 3, "{st:?}");
}

#[test]
fn a_server_started_after_its_nodes_is_joined_when_it_comes() {
    let sc = scenario(30.0);
    let bus = LocalBus::new();
    let mut joins = bus.subscribe(&keys::join(SensorId(0))).unwrap();
    let n = node(&bus, &sc, 0, node_opts(Some(10)));
    // the node asks for a server every 100 ms; start one once it has asked three times
    wait_for(joins.as_mut(), 3, "the node's join requests");
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    let s = n.join().unwrap().unwrap();
    assert_eq!(s.scans, 10);
    assert_eq!(s.rejoins, 0);
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert_eq!(run.sensors[0].state(), "ended", "{:?}", run.sensors[0]);
    assert!(run.sensors[0].accepted > 0, "{:?}", run.sensors[0]);
}

#[test]
fn garbage_on_every_node_key_is_counted_and_the_run_goes_on() {
    let sc = scenario(30.0);
    let bus = LocalBus::new();
    let mut ready = bus.subscribe(keys::SERVER_READY).unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    wait_for(ready.as_mut(), 1, "the server's beacon");
    let id = SensorId(0);
    let mut rng = 0x9e37_79b9_7f4a_7c15u64;
    for round in 0..200 {
        let len = round % 97;
        let bytes: Vec<u8> = (0..len)
            .map(|_| {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng as u8
            })
            .collect();
        for key in [
            keys::scan(id),
            keys::sync_request(id),
            keys::sim(id),
            keys::end(id),
            keys::join(id),
            keys::bye(id),
            keys::SERVER_READY.to_string(),
            keys::SERVER_END.to_string(),
            format!("{}not-a-number", keys::SCAN_PREFIX),
        ] {
            bus.publish(&key, &bytes).unwrap();
        }
    }
    // the nodes still join, sync and are tracked
    let nodes: Vec<_> = (0..2)
        .map(|k| node(&bus, &sc, k, node_opts(Some(10))))
        .collect();
    for n in nodes {
        assert_eq!(n.join().unwrap().unwrap().scans, 10);
    }
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert!(run.stats.malformed > 0, "{:?}", run.stats);
    for k in 0..2 {
        assert_eq!(run.sensors[k].state(), "ended", "{:?}", run.sensors[k]);
        assert!(run.sensors[k].accepted > 0, "{:?}", run.sensors[k]);
    }
}

/// A source whose stamps jump an hour ahead after `at` scans (a recording with a gap, or a
/// sensor clock that was set).
struct Jumps {
    inner: SimSource,
    at: u64,
    n: u64,
}

impl quarry_net::ScanSource for Jumps {
    fn sensor(&self) -> SensorId {
        self.inner.sensor()
    }
    fn geometry(&self) -> quarry_core::ScanGeometry {
        self.inner.geometry()
    }
    fn next_scan(
        &mut self,
    ) -> Result<Option<(quarry_core::TimeUs, quarry_core::PolarScan)>, NetError> {
        self.n += 1;
        Ok(self.inner.next_scan()?.map(|(t, s)| {
            let jump = if self.n > self.at { 3_600_000_000 } else { 0 };
            (quarry_core::TimeUs(t.0 + jump), s)
        }))
    }
}

#[test]
fn a_jump_of_the_source_clock_re_anchors_the_pacing_instead_of_sleeping() {
    let sc = scenario(30.0);
    let bus = LocalBus::new();
    let stop = Arc::new(AtomicBool::new(false));
    let srv = server(&bus, &sc, &stop);
    let (b2, sc2) = (bus.clone(), sc.clone());
    let n = std::thread::spawn(move || {
        let mut src = Jumps {
            inner: SimSource::new(sc2, 0)?,
            at: 5,
            n: 0,
        };
        run_wall_node(
            &b2,
            &mut src,
            &LidarPeopleConfig::faithful(),
            &node_opts(Some(12)),
        )
    });
    // an hour of sleep would hang this test: the two-minute guard of `wait_for` is not needed
    // here because the node returns on its own once it re-anchors
    let s = n.join().unwrap().unwrap();
    assert_eq!(s.scans, 12);
    assert_eq!(s.source_jumps, 1, "{s:?}");
    stop.store(true, Ordering::SeqCst);
    let run = srv.join().unwrap().unwrap();
    assert_eq!(run.sensors[0].state(), "ended", "{:?}", run.sensors[0]);
    assert!(run.sensors[0].accepted > 5, "{:?}", run.sensors[0]);
}

#[test]
fn a_refusal_of_the_other_clock_for_the_same_id_does_not_stop_a_node() {
    // A stray virtual-time message for sensor 0 reaches a wall-clock server, which refuses it
    // on sensor 0's refuse key, where a wall-clock node 0 is waiting to join. The node must
    // ignore it: it was addressed to a virtual-time request. (Before, the node stopped with
    // the other node's reason: CI saw it once in the garbage test above.)
    let bus = LocalBus::new();
    let id = SensorId(0);
    let mut joins = bus.subscribe(&keys::join(id)).unwrap();
    let b = bus.clone();
    let n = std::thread::spawn(move || {
        wait_for_server(&b, id, ClockKind::Wall, Duration::from_mins(1))
    });
    // the node has subscribed to its welcome and refuse keys before its first join request
    wait_for(joins.as_mut(), 1, "the node's join request");
    let refusal = |to| quarry_net::session::Refusal {
        to,
        reason: "this server runs on the wall clock but sensor 0 runs on the virtual clock".into(),
    };
    bus.publish(
        &keys::refuse(id),
        &refusal(Some(ClockKind::Virtual)).encode(),
    )
    .unwrap();
    let w = quarry_net::Welcome {
        mode: ClockKind::Wall,
        session: 7,
    };
    bus.publish(&keys::welcome(id), &w.encode()).unwrap();
    assert_eq!(n.join().unwrap().unwrap(), w);

    // a refusal addressed to this node's clock, or to every node of the id, stops it at once
    for to in [Some(ClockKind::Wall), None] {
        // a fresh spy: the first node's requests are still queued on the old one
        let mut joins = bus.subscribe(&keys::join(id)).unwrap();
        let b = bus.clone();
        let n = std::thread::spawn(move || {
            wait_for_server(&b, id, ClockKind::Wall, Duration::from_mins(1))
        });
        wait_for(joins.as_mut(), 1, "the node's join request");
        bus.publish(&keys::refuse(id), &refusal(to).encode())
            .unwrap();
        match n.join().unwrap() {
            Err(NetError::Refused(m)) => assert!(m.starts_with("this server runs"), "{m}"),
            other => panic!("{to:?}: {other:?}"),
        }
    }
}
