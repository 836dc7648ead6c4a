//! `quarry video sim`: the synthetic video walkers-v1 of spec 004 §5.2 (frames, ground truth,
//! events), and optionally the tracker scored on it (checks E1-E6, the pool-size plot) and the
//! threshold grid of §5.3.

use std::fmt::Write as _;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use clap::Args;
use plotters::prelude::*;
use quarry_repro::video::{
    EmptyCheck, GridRow, Metrics, VideoRun, WalkersChecks, check_empty, check_walkers, run_walkers,
    score, threshold_grid,
};
use quarry_sim::walkers::{WalkersEvents, WalkersScenario, WalkersVariant};
use quarry_trackers::watershed_sift::{Profile, WatershedSiftConfig};
use quarry_trackers::{PresetName, TrackerConfig};
use serde::Serialize;

use crate::config_args::PresetParser;
use crate::output::{CmdError, CmdResult, Output, Table};
use crate::progress;

/// Arguments of `quarry video sim`.
#[derive(Debug, Args)]
#[command(
    about = "Write the synthetic video walkers-v1 (spec 004 §5.2) and optionally score the tracker on it",
    long_about = "Write the synthetic grey video walkers-v1 of spec 004 §5.2 as a MOTChallenge \
sequence: 800x450 frames of dark textured walkers A-D crossing a static value-noise background \
with a flat wall and a black shadow, N(0, 2^2) pixel noise, everything seeded (bit-identical on \
one platform). Variants: v1 (A-D, 450 frames), ab (A and B only, the paper's two-target case), \
empty (no walker, 200 frames: the control for false tracks).

OUTPUT in --out DIR: img1/000001.png ... (unless --no-images), gt/gt.txt (MOT16/17 ground \
truth: frame,id,left,top,w,h,flag,1,visibility; the full unclipped 26x76 silhouette box; flag \
1 iff at least half the silhouette is in view; occluded walkers keep flag 1), events.json \
(per walker the first visible frame, the frame it is half in view, the frame it starts to \
leave and is gone; box overlaps with the walker in front; near passes; frames 0-based) and \
seqinfo.ini. --frames N keeps the first N frames.

--score runs the tracker (--profile paper by default, or robust; the profiles' 30x80 box \
fits the 26x76 walkers; --config FILE.toml lays the keys of `quarry video --config` over the \
profile, e.g. to switch one extension off) on the generated frames and writes <sequence>-<profile>.txt \
(MOTChallenge results), metrics (IoU 0.5), pools.csv and pools.png (the pool size of every \
target per frame, the paper's Fig. 10(b)); on the full v1 it also evaluates the checks E1-E6 \
of spec §5.2 (checks.json), on empty the false-track check. --grid runs the threshold study of \
§5.3 (tau_split x rho x W_del, 12 runs of the profile) and writes grid.csv: MOTA, IDF1, IDSW, \
centre RMSE, and the largest per-frame centre difference to the profile's own run.

JSON (--json) prints one object: sequence, frames, dir, images, gt_rows, events (as in \
events.json), score (null without --score: profile, results, ms_per_frame, ms_p50, ms_p95 (median and 95th \
percentile of the tracker time per frame), metrics {mota, motp \
(as 1 - IoU, py-motmetrics), idf1, hota, idsw, fp, fn_, gt, centre_rmse}, checks (E1-E6 with \
the numbers behind each, v1 only), empty (empty only), pools_png) and grid (null without \
--grid: one object per configuration).

EXAMPLE:
  quarry video sim --out runs/walkers-v1
  quarry video sim --variant ab --frames 120 --out runs/walkers-ab --no-images --score --json
  quarry video --frames runs/walkers-v1/img1 --gt runs/walkers-v1/gt/gt.txt --out runs/v1-paper"
)]
pub struct SimArgs {
    /// Output directory (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Which video: v1, ab or empty.
    #[arg(long, value_name = "v1|ab|empty", default_value = "v1", value_parser = parse_variant)]
    pub variant: WalkersVariant,
    /// Keep only the first N frames (N >= 1, at most the variant's length).
    #[arg(long, value_name = "N", value_parser = parse_frames)]
    pub frames: Option<u64>,
    /// Do not write the frames (ground truth, events and seqinfo only).
    #[arg(long)]
    pub no_images: bool,
    /// Run the tracker on the video and score it.
    #[arg(long)]
    pub score: bool,
    /// Tracker profile for --score and --grid (`paper` or `robust`; default paper).
    #[arg(long, value_name = "NAME", value_parser = PresetParser::<Profile>::new())]
    pub profile: Option<Profile>,
    /// TOML configuration laid over the profile for --score and --grid (the keys of
    /// `quarry video --config`; unknown keys are refused with the file and line).
    #[arg(long, value_name = "FILE.toml")]
    pub config: Option<PathBuf>,
    /// Run the threshold grid of spec §5.3 (12 tracker runs).
    #[arg(long)]
    pub grid: bool,
}

fn parse_variant(s: &str) -> Result<WalkersVariant, String> {
    WalkersVariant::parse(s).map_err(|e| e.to_string())
}

fn parse_frames(s: &str) -> Result<u64, String> {
    match s.trim().parse::<u64>() {
        Ok(0) => Err("must be at least 1".into()),
        Ok(n) => Ok(n),
        Err(_) => Err(format!("{s:?} is not a whole number of frames")),
    }
}

#[derive(Debug, Serialize)]
struct ScoreJson {
    profile: &'static str,
    results: String,
    ms_per_frame: f64,
    ms_p50: f64,
    ms_p95: f64,
    metrics: Metrics,
    checks: Option<WalkersChecks>,
    empty: Option<EmptyCheck>,
    pools_png: String,
}

#[derive(Debug, Serialize)]
struct SimJson {
    sequence: String,
    frames: u64,
    dir: String,
    images: bool,
    gt_rows: usize,
    events: WalkersEvents,
    score: Option<ScoreJson>,
    grid: Option<Vec<GridRow>>,
}

fn io_err(p: &Path) -> impl Fn(std::io::Error) -> CmdError + '_ {
    move |e| format!("cannot write {}: {e}", p.display()).into()
}

/// Runs `quarry video sim`.
pub fn run(args: &SimArgs, out: &Output) -> CmdResult {
    // the configuration first, so that a bad file fails before any frame is written
    let cfg = match &args.config {
        Some(p) => WatershedSiftConfig::from_toml_file(p, args.profile)
            .map_err(|e| format!("--config {}: {e}", p.display()))?,
        None => WatershedSiftConfig::preset(args.profile.unwrap_or(Profile::Paper)),
    };
    cfg.validate()
        .map_err(|e| format!("tracker configuration: {e}"))?;
    let mut sc = WalkersScenario::new(args.variant)?;
    if let Some(n) = args.frames {
        if n > sc.len() {
            return Err(format!(
                "--frames {n}: {} has {} frames",
                args.variant.name(),
                sc.len()
            )
            .into());
        }
        sc = sc.truncated(n)?;
    }
    let dir = &args.out;
    let img_dir = dir.join("img1");
    let gt_dir = dir.join("gt");
    std::fs::create_dir_all(&gt_dir).map_err(io_err(&gt_dir))?;
    if !args.no_images {
        std::fs::create_dir_all(&img_dir).map_err(io_err(&img_dir))?;
        let pb = progress::bar(out, sc.len(), "frames");
        for t in 0..sc.len() {
            let f = sc.frame(t)?;
            let p = img_dir.join(format!("{:06}.png", t + 1));
            image::GrayImage::from_raw(f.width, f.height, f.data)
                .ok_or("frame buffer has the wrong size")?
                .save(&p)
                .map_err(|e| format!("cannot write {}: {e}", p.display()))?;
            pb.inc(1);
        }
        pb.finish_and_clear();
    }
    let gt_path = gt_dir.join("gt.txt");
    let f = std::fs::File::create(&gt_path).map_err(io_err(&gt_path))?;
    sc.write_ground_truth(BufWriter::new(f))?;
    let gt_rows = sc.ground_truth_all()?.len();
    let events = sc.events()?;
    let ev_path = dir.join("events.json");
    std::fs::write(&ev_path, serde_json::to_string_pretty(&events)? + "\n")
        .map_err(io_err(&ev_path))?;
    let si_path = dir.join("seqinfo.ini");
    std::fs::write(&si_path, sc.seqinfo()).map_err(io_err(&si_path))?;

    let profile = cfg.preset;
    let score_json = if args.score {
        Some(score_run(&sc, &cfg, profile, args.variant, dir, out)?)
    } else {
        None
    };
    let grid = if args.grid {
        let pb = progress::bar(out, 12, "grid");
        let rows = threshold_grid(&sc, &cfg, None, |k, _| pb.set_position(k as u64))?;
        pb.finish_and_clear();
        write_grid_csv(&dir.join("grid.csv"), &rows)?;
        Some(rows)
    } else {
        None
    };

    let json = SimJson {
        sequence: sc.name().to_owned(),
        frames: sc.len(),
        dir: dir.display().to_string(),
        images: !args.no_images,
        gt_rows,
        events,
        score: score_json,
        grid,
    };
    out.emit(&json, || human(&json))
}

fn score_run(
    sc: &WalkersScenario,
    cfg: &WatershedSiftConfig,
    profile: Profile,
    variant: WalkersVariant,
    dir: &Path,
    out: &Output,
) -> Result<ScoreJson, CmdError> {
    let pb = progress::bar(out, sc.len(), "tracking");
    let run = run_walkers(sc, cfg, None, |k| pb.set_position(k))?;
    pb.finish_and_clear();
    let res_path = dir.join(format!("{}-{}.txt", sc.name(), profile.name()));
    std::fs::write(&res_path, run.results_text()?).map_err(io_err(&res_path))?;
    let metrics = score(sc, &run)?.metrics;
    let full = sc.len() == variant.frames();
    let checks = if variant == WalkersVariant::V1 && full {
        let c = check_walkers(sc, &run)?;
        let p = dir.join("checks.json");
        std::fs::write(&p, serde_json::to_string_pretty(&c)? + "\n").map_err(io_err(&p))?;
        Some(c)
    } else {
        None
    };
    let empty = (variant == WalkersVariant::Empty).then(|| check_empty(&run));
    let csv = dir.join("pools.csv");
    let mut s = String::from("frame,id,pool,occluded\n");
    for &(t, id, n, occ) in &run.pools {
        let _ = writeln!(s, "{t},{id},{n},{}", u8::from(occ));
    }
    std::fs::write(&csv, s).map_err(io_err(&csv))?;
    let png = dir.join("pools.png");
    plot_pools(&png, &run, &format!("{} ({})", sc.name(), profile.name()))?;
    Ok(ScoreJson {
        profile: profile.name(),
        results: res_path.display().to_string(),
        ms_per_frame: run.ms_per_frame,
        ms_p50: run.ms_p50_p95[0],
        ms_p95: run.ms_p50_p95[1],
        metrics,
        checks,
        empty,
        pools_png: png.display().to_string(),
    })
}

fn write_grid_csv(path: &Path, rows: &[GridRow]) -> Result<(), CmdError> {
    let mut s = String::from(
        "tau_split,rho,w_del,default,mota,idf1,hota,idsw,fp,fn,centre_rmse,max_centre_diff,match_differences\n",
    );
    for r in rows {
        let m = &r.metrics;
        let _ = writeln!(
            s,
            "{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{:.3},{:.3},{}",
            r.tau_split,
            r.ratio,
            r.w_del,
            u8::from(r.default),
            m.mota,
            m.idf1,
            m.hota,
            m.idsw,
            m.fp,
            m.fn_,
            m.centre_rmse,
            r.max_centre_diff,
            r.match_differences
        );
    }
    std::fs::write(path, s).map_err(io_err(path))
}

/// Pool size per target and frame (Fig. 10(b)), one line per target, shaded frames where a
/// target is occluded drawn as dots.
fn plot_pools(path: &Path, run: &VideoRun, title: &str) -> Result<(), CmdError> {
    crate::fonts::register()?;
    let series = run.pool_series();
    let occluded: Vec<(f64, f64)> = run
        .pools
        .iter()
        .filter(|p| p.3)
        .map(|p| (p.0 as f64, p.2 as f64))
        .collect();
    let (w, h) = (900u32, 450u32);
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let ymax = run.pools.iter().map(|p| p.2).max().unwrap_or(1).max(1) as f64 * 1.1;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption(title, ("sans-serif", 16))
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0f64..run.frames.max(1) as f64, 0f64..ymax)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .light_line_style(RGBColor(235, 235, 235))
            .x_desc("frame")
            .y_desc("pool size (descriptors)")
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, (id, s)) in series.iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(
                    s.iter().map(|&(t, n)| (t as f64, n as f64)),
                    c.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label(format!("target {id}"))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 15, y)], c));
        }
        chart
            .draw_series(occluded.iter().map(|&p| Circle::new(p, 2, BLACK.filled())))
            .map_err(|e| e.to_string())?
            .label("occluded")
            .legend(|(x, y)| Circle::new((x + 7, y), 2, BLACK.filled()));
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).ok_or("plot buffer has the wrong size")?;
    img.save(path)
        .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    Ok(())
}

fn human(j: &SimJson) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: {} frames, {} ground-truth rows in {}{}",
        j.sequence,
        j.frames,
        j.gt_rows,
        j.dir,
        if j.images { "" } else { " (no images)" }
    );
    for w in &j.events.walkers {
        let f = |v: Option<u64>| v.map_or("-".into(), |v| v.to_string());
        let _ = writeln!(
            s,
            "  walker {} (id {}): visible from {}, half in view from {}, leaving from {}, gone from {}",
            w.name,
            w.id,
            f(w.first_visible),
            f(w.half_in_view),
            f(w.below_half_from),
            f(w.gone_from)
        );
    }
    for o in &j.events.overlaps {
        let _ = writeln!(
            s,
            "  boxes of {} and {} overlap in frames {}-{} ({} in front)",
            o.ids[0], o.ids[1], o.first, o.last, o.front
        );
    }
    if let Some(sc) = &j.score {
        let m = &sc.metrics;
        let _ = writeln!(
            s,
            "tracker ({}, {:.1} ms per frame, median {:.1}, p95 {:.1}): results in {}, pool plot {}",
            sc.profile, sc.ms_per_frame, sc.ms_p50, sc.ms_p95, sc.results, sc.pools_png
        );
        let mut t = Table::new(["MOTA", "IDF1", "HOTA", "IDSW", "FP", "FN", "centre RMSE"]);
        t.row([
            format!("{:.3}", m.mota),
            format!("{:.3}", m.idf1),
            format!("{:.3}", m.hota),
            m.idsw.to_string(),
            m.fp.to_string(),
            m.fn_.to_string(),
            format!("{:.2}", m.centre_rmse),
        ]);
        s.push_str(&t.render());
        if let Some(c) = &sc.checks {
            let v = |b: bool| if b { "pass" } else { "FAIL" };
            let det: Vec<String> = c
                .e1_detection
                .iter()
                .map(|d| {
                    format!(
                        "{} {}/{}",
                        d.name,
                        d.detected.map_or("-".into(), |t| t.to_string()),
                        d.deadline
                    )
                })
                .collect();
            let _ = writeln!(s, "E1 detection  {}  ({})", v(c.e1), det.join(", "));
            let bad: Vec<String> = c
                .e2_tracks
                .iter()
                .filter(|p| p.fraction < 0.8)
                .map(|p| format!("{} {:.0}% of {}", p.id, 100.0 * p.fraction, p.frames))
                .collect();
            let _ = writeln!(
                s,
                "E2 no false   {}  ({} tracks; below 80%: {})",
                v(c.e2),
                c.e2_tracks.len(),
                if bad.is_empty() {
                    "none".into()
                } else {
                    bad.join(", ")
                }
            );
            for x in &c.crossing {
                let _ = writeln!(
                    s,
                    "E3/E4 {}      carrier {:?}, occluded in {} frames of 300-330, carried again {}/{}",
                    x.name,
                    x.carrier_before,
                    x.occluded_frames.len(),
                    x.carried_after,
                    x.frames_after
                );
            }
            let _ = writeln!(s, "E3 occlusion  {}", v(c.e3));
            let _ = writeln!(s, "E4 identity   {}  (IDSW {})", v(c.e4), c.idsw);
            let _ = writeln!(
                s,
                "E5 exit       {}  (C's track {:?} last at {:?}, {} boxes near the exit in 421-449)",
                v(c.e5),
                c.e5_exit.carrier,
                c.e5_exit.carrier_last,
                c.e5_exit.boxes_near_exit
            );
            let _ = writeln!(s, "E6 metrics    {}", v(c.e6));
        }
        if let Some(e) = &sc.empty {
            let _ = writeln!(
                s,
                "false tracks on the empty video: {} tracks, {} boxes ({})",
                e.tracks,
                e.boxes,
                if e.pass { "pass" } else { "FAIL" }
            );
        }
    }
    if let Some(g) = &j.grid {
        let mut t = Table::new([
            "tau_split",
            "rho",
            "W_del",
            "MOTA",
            "IDF1",
            "IDSW",
            "RMSE px",
            "max diff px",
        ]);
        for r in g {
            t.row([
                format!("{}{}", r.tau_split, if r.default { "*" } else { "" }),
                r.ratio.to_string(),
                r.w_del.to_string(),
                format!("{:.3}", r.metrics.mota),
                format!("{:.3}", r.metrics.idf1),
                r.metrics.idsw.to_string(),
                format!("{:.2}", r.metrics.centre_rmse),
                format!("{:.1}", r.max_centre_diff),
            ]);
        }
        s.push_str(&t.render());
    }
    s
}

/// The `quarry demo` row: the `paper` tracker on the first 120 frames of the walkers-v1-ab
/// layout drawn with the demo's seed (A and B walking towards each other, before they cross).
pub fn demo_rows(seed: u64) -> Result<Vec<super::demo::Row>, CmdError> {
    let sc = WalkersScenario::with_size(
        quarry_sim::walkers::WIDTH,
        quarry_sim::walkers::HEIGHT,
        120,
        WalkersVariant::Ab.walkers(),
        seed,
    )?
    .named("walkers-ab");
    let run = run_walkers(&sc, &WatershedSiftConfig::paper(), None, |_| {})?;
    let m = score(&sc, &run)?.metrics;
    let scenario = format!("walkers-v1-ab layout, seed {seed}, frames 0-119");
    Ok([
        ("MOTA", m.mota),
        ("IDF1", m.idf1),
        ("centre RMSE (px)", m.centre_rmse),
    ]
    .into_iter()
    .map(|(metric, value)| super::demo::Row {
        tracker: "watershed-sift".into(),
        scenario: scenario.clone(),
        metric: metric.into(),
        value,
        paper: None,
        ms_per_frame: Some(run.ms_per_frame),
    })
    .collect())
}
