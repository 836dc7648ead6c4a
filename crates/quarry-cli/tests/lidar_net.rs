//! Three `quarry lidar-node` processes and a `quarry lidar-server` over zenoh on loopback
//! (explicit TCP endpoint on a port chosen at run time, no multicast) reproduce the tracks of
//! the in-process `quarry lidar` run with the same seed, byte for byte.
#![cfg(feature = "zenoh")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Kills and reaps every child still running when dropped (test failure, timeout).
struct Procs(Vec<(String, Child)>);

impl Drop for Procs {
    fn drop(&mut self) {
        for (_, c) in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Starts `exe args` with stdout and stderr going to `<dir>/<name>.out` and `.err` (files, not
/// pipes: a child blocked writing into a full pipe nobody reads would hang the test).
fn spawn(exe: &str, args: &[String], dir: &Path, name: &str) -> Child {
    let file = |ext: &str| std::fs::File::create(dir.join(format!("{name}.{ext}"))).unwrap();
    Command::new(exe)
        .args(args)
        .env("QUARRY_NET_TRACE", "1")
        .stdout(Stdio::from(file("out")))
        .stderr(Stdio::from(file("err")))
        .spawn()
        .unwrap()
}

/// Everything a child wrote (stdout, then stderr).
fn logs(dir: &Path, name: &str) -> String {
    let r =
        |ext: &str| std::fs::read_to_string(dir.join(format!("{name}.{ext}"))).unwrap_or_default();
    format!(
        "--- {name} stdout:\n{}--- {name} stderr:\n{}",
        r("out"),
        r("err")
    )
}

/// Waits for every process (at most `limit` overall); on a failure or the time limit, kills
/// them all and panics with every process's output. Returns the stdout of each, in order.
fn wait_all(procs: &mut Procs, dir: &Path, limit: Duration) -> Vec<String> {
    let t0 = Instant::now();
    loop {
        let mut done = true;
        let mut failed = None;
        for (name, c) in &mut procs.0 {
            match c.try_wait().unwrap() {
                Some(s) if !s.success() => failed = Some(format!("{name} failed ({s})")),
                Some(_) => {}
                None => done = false,
            }
        }
        if failed.is_none() && !done && t0.elapsed() > limit {
            failed = Some(format!(
                "processes still running after {} s",
                limit.as_secs()
            ));
        }
        if let Some(why) = failed {
            let names: Vec<String> = procs.0.iter().map(|(n, _)| n.clone()).collect();
            for (_, c) in &mut procs.0 {
                let _ = c.kill();
                let _ = c.wait();
            }
            procs.0.clear();
            let all: Vec<String> = names.iter().map(|n| logs(dir, n)).collect();
            panic!("{why}:\n{}", all.join("\n"));
        }
        if done {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let names: Vec<String> = std::mem::take(&mut procs.0)
        .into_iter()
        .map(|(n, _)| n)
        .collect();
    names
        .iter()
        .map(|n| std::fs::read_to_string(dir.join(format!("{n}.out"))).unwrap())
        .collect()
}

/// Waits (at most a minute) until the server, the first process, listens on `port` (once its
/// session is open); panics with its output if it exits first.
fn wait_listening(procs: &mut Procs, port: u16, dir: &Path) {
    let t0 = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t0.elapsed() < Duration::from_mins(1),
            "server never listened"
        );
        if let Some(st) = procs.0[0].1.try_wait().unwrap() {
            panic!("server exited early: {st}\n{}", logs(dir, "server"));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

// This test once hung on merged main (docs/lidar-people.md, "Networked deployment", "The end
// handshake"): the server subscribed to `quarry/lidar/**`, which matched its own track messages,
// and its thread blocked publishing into its own full zenoh receive queue. Fixed by the
// server's node-only subscription; the end handshake is also acknowledged until confirmed.
// stderr of every process carries the QUARRY_NET_TRACE protocol trace, printed on failure.
#[test]
fn three_node_processes_and_the_server_reproduce_the_in_process_run() {
    let exe = env!("CARGO_BIN_EXE_quarry");
    let dir = std::env::temp_dir().join(format!("quarry-lidar-net-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let room: Vec<String> = ["--frames", "60", "--seed", "4", "--band", "normal"]
        .iter()
        .map(ToString::to_string)
        .collect();
    let s = |x: &str| x.to_string();

    // the in-process run (default wifi network: loss, duplicates, delay spikes)
    let mut args = vec![s("lidar")];
    args.extend(room.clone());
    args.extend([
        s("--out"),
        dir.join("local").display().to_string(),
        s("--json"),
    ]);
    let o = Command::new(exe).args(&args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    let port = free_port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let mut procs = Procs(Vec::new());
    let mut args = vec![s("lidar-server"), s("--clock"), s("virtual")];
    args.extend(room.clone());
    args.extend([
        s("--listen"),
        endpoint.clone(),
        s("--out"),
        dir.join("net").display().to_string(),
        s("--idle-timeout"),
        s("30"),
        s("--json"),
    ]);
    procs
        .0
        .push((s("server"), spawn(exe, &args, &dir, "server")));
    // the server listens once its session is open
    wait_listening(&mut procs, port, &dir);
    for k in 0..3 {
        let mut args = vec![
            s("lidar-node"),
            s("--clock"),
            s("virtual"),
            s("--scanner"),
            k.to_string(),
        ];
        args.extend(room.clone());
        args.extend([
            s("--connect"),
            endpoint.clone(),
            s("--wait-server"),
            s("30"),
            s("--json"),
        ]);
        let name = format!("node{k}");
        procs.0.push((name.clone(), spawn(exe, &args, &dir, &name)));
    }
    let outs = wait_all(&mut procs, &dir, Duration::from_mins(2));

    let local = read(&dir.join("local/tracks.csv"));
    let net = read(&dir.join("net/tracks.csv"));
    assert!(
        local.lines().count() > 50,
        "too few track rows to compare:\n{local}"
    );
    assert_eq!(
        net, local,
        "networked tracks differ from the in-process run"
    );
    assert_eq!(
        read(&dir.join("net/tracks_mot.txt")),
        read(&dir.join("local/tracks_mot.txt"))
    );
    let js: serde_json::Value = serde_json::from_str(&outs[0]).unwrap();
    assert_eq!(js["clock"], "virtual");
    assert!(js["lost"].as_u64().unwrap() > 0, "{js}"); // the wifi model lost some scans
    assert_eq!(js["rejected"], 0, "{js}");
    for o in &outs[1..] {
        let n: serde_json::Value = serde_json::from_str(o).unwrap();
        assert!(n["scans"].as_u64().unwrap() > 400, "{n}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The ROS 2 side of the loopback test: a Python process with `eclipse-zenoh` and `rosbags`
/// (tests/python/ros2_peer.py) plays a robot running rmw_zenoh. It publishes LaserScans of one
/// person walking (with a truncated message and a wrong beam count mixed in) on `/scan`;
/// `quarry lidar-node --ros2-scan /scan` tracks them through `quarry lidar-server --ros2`, and
/// the Python side decodes every published track message. Only 127.0.0.1.
#[test]
fn a_ros2_peer_feeds_the_node_and_decodes_the_servers_tracks() {
    let reqs =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../quarry-ros2/tests/python/requirements.txt");
    let Some(py) =
        quarry_testkit::python::venv_or_skip(Path::new(env!("CARGO_TARGET_TMPDIR")), "ros2", &reqs)
    else {
        return;
    };
    let exe = env!("CARGO_BIN_EXE_quarry");
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ros2-loopback");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let s = |x: &str| x.to_string();
    let p = |x: &Path| x.display().to_string();
    // the peer's scanner: 541 beams over 270°, 40 Hz
    let sensors = r#"[{"id": 0, "x": 0.0, "y": 0.0, "theta_deg": 0.0, "geometry":
        {"n_beams": 541, "angle_min": -2.356194490192345, "angle_increment": 0.008726646259971648,
         "range_min": 0.05, "range_max": 30.0, "scan_period": 0.025}}]"#;
    std::fs::write(dir.join("sensors.json"), sensors).unwrap();
    let (port, py_port) = (free_port(), free_port());
    let server_ep = format!("tcp/127.0.0.1:{port}");
    let py_ep = format!("tcp/127.0.0.1:{py_port}");
    let mut procs = Procs(Vec::new());
    let args = vec![
        s("lidar-server"),
        s("--sensors"),
        p(&dir.join("sensors.json")),
        s("--ros2"),
        s("--listen"),
        server_ep.clone(),
        s("--out"),
        p(&dir.join("out")),
        s("--mcap"),
        p(&dir.join("server.mcap")),
        s("--idle-timeout"),
        s("20"),
        s("--json"),
    ];
    procs
        .0
        .push((s("server"), spawn(exe, &args, &dir, "server")));
    wait_listening(&mut procs, port, &dir);
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/ros2_peer.py");
    let msg_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../quarry-ros2/msg");
    let ready = dir.join("peer.ready");
    let args = vec![
        p(&script),
        s("--listen"),
        py_ep.clone(),
        s("--connect"),
        server_ep.clone(),
        s("--msg-dir"),
        p(&msg_dir),
        s("--ready"),
        p(&ready),
    ];
    procs
        .0
        .push((s("peer"), spawn(&p(py.python()), &args, &dir, "peer")));
    let t0 = Instant::now();
    while !ready.exists() {
        assert!(
            t0.elapsed() < Duration::from_mins(2),
            "the Python peer never got ready"
        );
        if let Some(st) = procs.0[1].1.try_wait().unwrap() {
            panic!("the Python peer exited early: {st}\n{}", logs(&dir, "peer"));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let args = vec![
        s("lidar-node"),
        s("--ros2-scan"),
        s("/scan"),
        s("--sensor-id"),
        s("0"),
        s("--connect"),
        server_ep,
        s("--connect"),
        py_ep,
        s("--ros2-idle"),
        s("2"),
        s("--json"),
    ];
    procs.0.push((s("node"), spawn(exe, &args, &dir, "node")));
    let outs = wait_all(&mut procs, &dir, Duration::from_mins(3));
    let server: serde_json::Value = serde_json::from_str(&outs[0]).unwrap();
    let peer: serde_json::Value = serde_json::from_str(&outs[1]).unwrap();
    let node: serde_json::Value = serde_json::from_str(&outs[2]).unwrap();

    // the node skipped exactly the faulty messages, and counted them
    let r = &node["ros2"];
    assert_eq!(r["malformed"], 1, "{node}");
    assert_eq!(r["wrong_geometry"], 1, "{node}");
    assert_eq!(r["foreign_hash"], 0, "{node}");
    assert!(r["scans"].as_u64().unwrap() > 300, "{node}");
    // every frame the server tracked reached the peer on the three topics, in order, decoded
    assert_eq!(peer["errors"], serde_json::json!([]), "{peer}");
    assert_eq!(peer["other"], serde_json::json!([]));
    assert_eq!(peer["attachment_len"], 33);
    let frames = server["frames"].as_u64().unwrap() as usize;
    assert_eq!(server["ros2_frames"].as_u64().unwrap() as usize, frames);
    // the server closes (empty) frames from its start, so the peer misses those published
    // before it subscribed, and no other
    let tracks = peer["tracks"].as_array().unwrap();
    let seq0 = tracks[0]["seq"].as_u64().unwrap() as usize;
    assert!(
        tracks[0]["stamp"].as_f64().unwrap() < peer["ready_at"].as_f64().unwrap() + 0.5,
        "the peer missed frames after it subscribed: {}",
        tracks[0]
    );
    assert_eq!(
        tracks.len() + seq0 - 1,
        frames,
        "the peer missed track messages"
    );
    assert_eq!(peer["poses"].as_u64().unwrap() as usize, tracks.len());
    assert_eq!(peer["markers"].as_u64().unwrap() as usize, tracks.len());
    for (k, f) in tracks.iter().enumerate() {
        assert_eq!(f["seq"].as_u64().unwrap() as usize, seq0 + k);
        assert_eq!(f["gid_len"], 16);
        assert_eq!(f["frame_id"], "map");
    }
    // the decoded rows are the server's tracks.csv (4 decimals there)
    let csv = read(&dir.join("out/tracks.csv"));
    let mut by_frame: Vec<Vec<(u64, f64, f64)>> = Vec::new();
    let mut last_frame = None;
    for line in csv.lines().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        if last_frame != Some(c[0]) {
            by_frame.push(Vec::new());
            last_frame = Some(c[0]);
        }
        let v = |i: usize| c[i].parse::<f64>().unwrap();
        by_frame
            .last_mut()
            .unwrap()
            .push((c[2].parse().unwrap(), v(3), v(4)));
    }
    let decoded: Vec<Vec<(u64, f64, f64)>> = tracks
        .iter()
        .map(|f| {
            f["rows"]
                .as_array()
                .unwrap()
                .iter()
                .map(|r| {
                    (
                        r[0].as_u64().unwrap(),
                        r[1].as_f64().unwrap(),
                        r[2].as_f64().unwrap(),
                    )
                })
                .collect()
        })
        .filter(|v: &Vec<_>| !v.is_empty())
        .collect();
    assert_eq!(decoded.len(), by_frame.len());
    for (a, b) in decoded.iter().zip(&by_frame) {
        assert_eq!(a.len(), b.len());
        for (x, y) in a.iter().zip(b) {
            assert_eq!(x.0, y.0);
            assert!(
                (x.1 - y.1).abs() < 6e-5 && (x.2 - y.2).abs() < 6e-5,
                "{x:?} {y:?}"
            );
        }
    }
    // and the person is tracked: from 1 s after they enter, a track within 0.3 m of them in at
    // least 90 % of the frames
    let truth: Vec<(f64, f64, f64)> = peer["truth"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            (
                r[0].as_f64().unwrap(),
                r[1].as_f64().unwrap(),
                r[2].as_f64().unwrap(),
            )
        })
        .collect();
    assert!(truth.len() > 150, "{}", truth.len());
    let (t_in, t_out) = (truth[0].0 + 1.0, truth[truth.len() - 1].0);
    let (mut n, mut hit) = (0, 0);
    for f in tracks {
        let t = f["stamp"].as_f64().unwrap();
        if t < t_in || t > t_out {
            continue;
        }
        let k = truth.partition_point(|r| r.0 < t).min(truth.len() - 1);
        let (_, x, y) = truth[k];
        n += 1;
        hit += usize::from(
            f["rows"]
                .as_array()
                .unwrap()
                .iter()
                .any(|r| (r[1].as_f64().unwrap() - x).hypot(r[2].as_f64().unwrap() - y) < 0.3),
        );
    }
    assert!(n > 80, "{n} frames while the person walked");
    assert!(
        hit * 10 >= n * 9,
        "the person was tracked in {hit} of {n} frames"
    );
    // the server's recording holds the same frames
    assert_eq!(
        server["mcap"]["messages"].as_u64().unwrap() as usize,
        1 + 3 * frames
    );
}
