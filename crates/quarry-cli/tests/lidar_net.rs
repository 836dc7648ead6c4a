//! Three `quarry lidar-node` processes and a `quarry lidar-server` over zenoh on loopback
//! (explicit TCP endpoint on a port chosen at run time, no multicast) reproduce the tracks of
//! the in-process `quarry lidar` run with the same seed, byte for byte.
#![cfg(feature = "zenoh")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
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

fn spawn(exe: &str, args: &[String]) -> Child {
    Command::new(exe)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits for every process (at most `limit` overall); returns their outputs in order.
fn wait_all(procs: &mut Procs, limit: Duration) -> Vec<Output> {
    let t0 = Instant::now();
    loop {
        let mut done = true;
        for (name, c) in &mut procs.0 {
            match c.try_wait().unwrap() {
                Some(s) if !s.success() => {
                    let name = name.clone();
                    let taken = std::mem::take(&mut procs.0);
                    let outs: Vec<String> = taken
                        .into_iter()
                        .map(|(n, mut c)| {
                            let _ = c.kill();
                            let o = c.wait_with_output().unwrap();
                            format!(
                                "--- {n}: {}\n{}",
                                String::from_utf8_lossy(&o.stdout),
                                String::from_utf8_lossy(&o.stderr)
                            )
                        })
                        .collect();
                    panic!("{name} failed ({s}):\n{}", outs.join("\n"));
                }
                Some(_) => {}
                None => done = false,
            }
        }
        if done {
            break;
        }
        assert!(
            t0.elapsed() < limit,
            "processes still running after {} s",
            limit.as_secs()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    std::mem::take(&mut procs.0)
        .into_iter()
        .map(|(_, c)| c.wait_with_output().unwrap())
        .collect()
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

// Ignored until a known hang is fixed (docs/lidar-people.md, "Networked deployment", known
// issue): on the merged main branch, run from this harness, the nodes finish publishing but never
// receive the server's end acknowledgement, so they time out; the same four processes started by
// hand from a shell (server first, nodes a few seconds later) complete and write the tracks.
// Run it with `cargo test -p quarry-cli --test lidar_net -- --ignored`.
#[test]
#[ignore = "known hang: nodes miss the server's end acknowledgement under this harness"]
fn three_node_processes_and_the_server_reproduce_the_in_process_run() {
    let exe = env!("CARGO_BIN_EXE_quarry");
    let dir = std::env::temp_dir().join(format!("quarry-lidar-net-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
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
        s("60"),
        s("--json"),
    ]);
    procs.0.push((s("server"), spawn(exe, &args)));
    // the server listens once its session is open
    let t0 = Instant::now();
    while TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            t0.elapsed() < Duration::from_mins(1),
            "server never listened"
        );
        if let Some(st) = procs.0[0].1.try_wait().unwrap() {
            panic!("server exited early: {st}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
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
            s("60"),
            s("--json"),
        ]);
        procs.0.push((format!("node {k}"), spawn(exe, &args)));
    }
    let outs = wait_all(&mut procs, Duration::from_mins(5));

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
    let js: serde_json::Value = serde_json::from_slice(&outs[0].stdout).unwrap();
    assert_eq!(js["clock"], "virtual");
    assert!(js["lost"].as_u64().unwrap() > 0, "{js}"); // the wifi model lost some scans
    assert_eq!(js["rejected"], 0, "{js}");
    for o in &outs[1..] {
        let n: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert!(n["scans"].as_u64().unwrap() > 400, "{n}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
