//! Point-cloud benchmarks on `../shared/bench-data`, mirroring `../shared/peers/bench_meanshift.py`,
//! `bench_icp.py` and `bench_chi2.py` (same inputs, same success criterion):
//!
//! - `meanshift/bins` and `meanshift/all_points`: flat-kernel MeanShift, h = 0.3 m, on the 338
//!   dynamic points of meanshift_points.csv (sklearn: `MeanShift(bandwidth=0.3)` seeds with every
//!   point; `bin_seeding=True` with grid cells).
//! - `icp/<variant>/<init>`: the 20 trials of icp_observed.csv against icp_model.csv (observed arc
//!   = data, model = model, i.e. the peers' "arc->model" direction), initial pose = the predicted
//!   pose of icp_transforms.csv or the identity; time per registration = time of all 20 / 20.
//!   Success as in the peer: rotation error < 2 deg and translation error < 2 cm (printed once).
//! - `chi2/variance_running`: the peer's per-beam variance test (m = 20, χ²₁(0.999), s ≥ 5 mm,
//!   one-sided) over its 200-scan stream, 3 × 1081 beams per scan; `chi2/paper_model`: the
//!   paper's ChiSquareBackground (m = 20, region constraint) on the same stream, per scan of
//!   3 × 1081 beams.
//! - `wire/encode_decode_350`: encode + decode one 350-point part.
//!
//! `cargo bench --bench cloud -- --noplot`
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::hint::black_box;
use std::path::{Path, PathBuf};

use criterion::{Criterion, criterion_group, criterion_main};
use quarry::cloud::background::{ChiSquareBackground, ChiSquareConfig, VarianceChi2Test};
use quarry::cloud::cluster::{MeanShift, Seeding};
use quarry::cloud::icp::{Correspondence, Icp2d, ModelShape};
use quarry::core::{Point2, PolarScan, Pose2, Registration2, ScanGeometry, SensorId, TimeUs};
use quarry::net::proto::wire::{Header, Kind, Message, Payload};

fn bench_data() -> Option<PathBuf> {
    let p = std::env::var_os("QUARRY_SHARED").map_or_else(
        || PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared")),
        PathBuf::from,
    );
    let d = p.join("bench-data");
    if d.join("meanshift_points.csv").exists() {
        Some(d)
    } else {
        eprintln!("skipping cloud benches: no bench-data at {}", d.display());
        None
    }
}

/// Columns by name, as f64.
fn read_cols(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').map(|f| f.parse().unwrap()).collect())
        .collect();
    (header, rows)
}

fn col(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).unwrap()
}

fn meanshift(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let (h, rows) = read_cols(&dir.join("meanshift_points.csv"));
    let (ix, iy, ip) = (col(&h, "x"), col(&h, "y"), col(&h, "person"));
    let pts: Vec<Point2> = rows.iter().map(|r| Point2::new(r[ix], r[iy])).collect();
    let person: Vec<usize> = rows.iter().map(|r| r[ip] as usize).collect();
    for (name, ms) in [
        ("bins", MeanShift::default()),
        (
            "all_points",
            MeanShift {
                seeding: Seeding::AllPoints,
                ..MeanShift::default()
            },
        ),
    ] {
        let cl = ms.run(&pts).unwrap();
        let mut pure = 0;
        for k in 0..cl.modes.len() {
            let mut counts = [0usize; 16];
            for (l, p) in cl.labels.iter().zip(&person) {
                if *l == Some(k as u32) {
                    counts[*p] += 1;
                }
            }
            pure += counts.iter().max().unwrap();
        }
        eprintln!(
            "meanshift/{name}: {} points, {} clusters, purity {:.4}, noise {}",
            pts.len(),
            cl.modes.len(),
            pure as f64 / pts.len() as f64,
            cl.labels.iter().filter(|l| l.is_none()).count()
        );
        c.bench_function(&format!("meanshift/{name}"), |b| {
            b.iter(|| black_box(ms.run(black_box(&pts)).unwrap()));
        });
    }
}

struct Trial {
    obs: Vec<Point2>,
    truth: Pose2,
    init: Pose2,
}

fn icp(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let (h, rows) = read_cols(&dir.join("icp_model.csv"));
    let model: Vec<Point2> = rows
        .iter()
        .map(|r| Point2::new(r[col(&h, "x")], r[col(&h, "y")]))
        .collect();
    let (ho, obs) = read_cols(&dir.join("icp_observed.csv"));
    let (ht, tf) = read_cols(&dir.join("icp_transforms.csv"));
    let trials: Vec<Trial> = tf
        .iter()
        .map(|r| {
            let t = r[col(&ht, "trial")];
            Trial {
                obs: obs
                    .iter()
                    .filter(|o| o[col(&ho, "trial")] == t)
                    .map(|o| Point2::new(o[col(&ho, "x")], o[col(&ho, "y")]))
                    .collect(),
                truth: Pose2::new(
                    r[col(&ht, "tx")],
                    r[col(&ht, "ty")],
                    r[col(&ht, "theta_deg")].to_radians(),
                ),
                init: Pose2::new(
                    r[col(&ht, "init_tx")],
                    r[col(&ht, "init_ty")],
                    r[col(&ht, "init_theta_deg")].to_radians(),
                ),
            }
        })
        .collect();
    let variants = [
        ("contour_faithful", Icp2d::contour()),
        (
            "contour_converged",
            Icp2d {
                rms_stop: 0.0,
                delta_stop: 1e-9,
                max_iter: 100,
                ..Icp2d::contour()
            },
        ),
        ("contour_point_to_line", Icp2d::contour_point_to_line()),
        ("points_faithful", Icp2d::default()),
        (
            "points_peer_settings",
            Icp2d {
                direction: Correspondence::DataToModel,
                model_shape: ModelShape::Points,
                trim: None,
                max_corr_dist: 0.5,
                rms_stop: 0.0,
                delta_stop: 1e-9,
                max_iter: 100,
                ..Icp2d::default()
            },
        ),
    ];
    for (name, icp) in variants {
        for init_name in ["predicted", "identity"] {
            let init_of = |t: &Trial| {
                if init_name == "predicted" {
                    t.init
                } else {
                    Pose2::identity()
                }
            };
            let mut ok = 0;
            let (mut rot, mut tr) = (Vec::new(), Vec::new());
            for t in &trials {
                let r = icp.register(&model, &t.obs, init_of(t)).unwrap();
                let dth = quarry::core::wrap_angle(r.pose.theta - t.truth.theta)
                    .abs()
                    .to_degrees();
                let dt = (r.pose.x - t.truth.x).hypot(r.pose.y - t.truth.y);
                rot.push(dth);
                tr.push(dt);
                ok += usize::from(dth < 2.0 && dt < 0.02);
            }
            rot.sort_by(f64::total_cmp);
            tr.sort_by(f64::total_cmp);
            eprintln!(
                "icp/{name}/{init_name}: success {ok}/{} ({:.2}), median rot {:.3} deg, median trans {:.4} m",
                trials.len(),
                ok as f64 / trials.len() as f64,
                0.5 * (rot[9] + rot[10]),
                0.5 * (tr[9] + tr[10])
            );
            c.bench_function(&format!("icp/{name}/{init_name}/20_trials"), |b| {
                b.iter(|| {
                    for t in &trials {
                        black_box(
                            icp.register(black_box(&model), black_box(&t.obs), init_of(t))
                                .unwrap(),
                        );
                    }
                });
            });
        }
    }
}

fn chi2(c: &mut Criterion) {
    let Some(dir) = bench_data() else { return };
    let (_, bg) = read_cols(&dir.join("laser_background.csv"));
    let m = 20;
    // window rows: scan k = concatenation of the three sensors' scan k (sensor-major)
    let w0: Vec<Vec<f64>> = (0..m)
        .map(|k| {
            let mut row = Vec::new();
            for s in 0..3 {
                let r = bg
                    .iter()
                    .find(|r| r[0] as usize == k && r[1] as usize == s)
                    .unwrap();
                row.extend_from_slice(&r[2..]);
            }
            row
        })
        .collect();
    let (hs, scan) = read_cols(&dir.join("laser_scan.csv"));
    let r_now: Vec<f64> = scan.iter().map(|r| r[col(&hs, "range")]).collect();
    let label: Vec<i64> = scan.iter().map(|r| r[col(&hs, "label")] as i64).collect();
    let stream: Vec<&Vec<f64>> = (0..200)
        .map(|k| if k % 2 == 0 { &r_now } else { &w0[k % m] })
        .collect();
    let thr = 10.827_566_170_662_733; // chi2.ppf(0.999, 1)
    {
        let t = VarianceChi2Test::new(&w0, 0.005, thr).unwrap();
        let mut mask = Vec::new();
        t.test(&r_now, &mut mask).unwrap();
        let tp = mask
            .iter()
            .zip(&label)
            .filter(|(m, l)| **m && **l >= 0)
            .count();
        let flagged = mask.iter().filter(|m| **m).count();
        let fg = label.iter().filter(|l| **l >= 0).count();
        eprintln!(
            "chi2/variance_running: precision {:.5} recall {:.5} (flagged {flagged}, person beams {fg})",
            tp as f64 / flagged as f64,
            tp as f64 / fg as f64
        );
    }
    c.bench_function("chi2/variance_running/200_scans", |b| {
        b.iter(|| {
            let mut t = VarianceChi2Test::new(&w0, 0.005, thr).unwrap();
            let mut mask = Vec::new();
            for r in &stream {
                t.test(r, &mut mask).unwrap();
                t.push(r).unwrap();
                black_box(&mask);
            }
        });
    });
    // the paper's model: one ChiSquareBackground per sensor, window m = 20, region constraint
    let g = ScanGeometry::utm30lx();
    let to_mm = |r: &[f64]| -> Vec<u16> {
        r.iter()
            .map(|x| (x * 1000.0).round().clamp(0.0, 65_534.0) as u16)
            .collect()
    };
    let mk = || {
        let cfg = ChiSquareConfig {
            window: m,
            ..ChiSquareConfig::literal()
        };
        let mut models: Vec<ChiSquareBackground> = (0..3)
            .map(|_| ChiSquareBackground::new(&g, cfg).unwrap())
            .collect();
        for (k, row) in w0.iter().enumerate() {
            for (s, model) in models.iter_mut().enumerate() {
                let scan = PolarScan::try_new(
                    SensorId(s as u16),
                    k as u32,
                    TimeUs(k as i64 * 25_000),
                    to_mm(&row[s * 1081..(s + 1) * 1081]),
                    g,
                )
                .unwrap();
                model.classify_scan(&scan).unwrap();
            }
        }
        models
    };
    let scans: Vec<Vec<PolarScan>> = stream
        .iter()
        .enumerate()
        .map(|(k, row)| {
            (0..3)
                .map(|s| {
                    PolarScan::try_new(
                        SensorId(s as u16),
                        (k + m) as u32,
                        TimeUs((k + m) as i64 * 25_000),
                        to_mm(&row[s * 1081..(s + 1) * 1081]),
                        g,
                    )
                    .unwrap()
                })
                .collect()
        })
        .collect();
    {
        let mut models = mk();
        let mut tp = 0;
        let mut flagged = 0;
        for (s, model) in models.iter_mut().enumerate() {
            let lab = model.classify_scan(&scans[0][s]).unwrap();
            for (n, l) in lab.iter().enumerate() {
                if *l == quarry::core::BeamLabel::Dynamic {
                    flagged += 1;
                    tp += usize::from(label[s * 1081 + n] >= 0);
                }
            }
        }
        let fg = label.iter().filter(|l| **l >= 0).count();
        eprintln!(
            "chi2/paper_model: precision {:.5} recall {:.5} (flagged {flagged})",
            tp as f64 / flagged as f64,
            tp as f64 / fg as f64
        );
    }
    c.bench_function("chi2/paper_model/200_scans", |b| {
        b.iter_batched(
            mk,
            |mut models| {
                for frame in &scans {
                    for (model, scan) in models.iter_mut().zip(frame) {
                        black_box(model.classify_scan(scan).unwrap());
                    }
                }
            },
            criterion::BatchSize::LargeInput,
        );
    });
}

fn wire(c: &mut Criterion) {
    let msg = Message {
        header: Header {
            kind: Kind::DynamicScan,
            sensor: SensorId(1),
            seq: 42,
            part: 0,
            parts: 1,
            flags: 1,
            t_capture: TimeUs(1_000_000),
            t_send: TimeUs(1_001_000),
        },
        payload: Payload::Points((0..350).map(|i| (i, 2000 + i)).collect()),
    };
    let mut buf = Vec::new();
    c.bench_function("wire/encode_decode_350", |b| {
        b.iter(|| {
            msg.encode_into(&mut buf).unwrap();
            black_box(Message::decode(black_box(&buf)).unwrap())
        });
    });
}

criterion_group!(benches, meanshift, icp, chi2, wire);
criterion_main!(benches);
