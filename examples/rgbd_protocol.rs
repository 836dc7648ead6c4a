//! The spec 001 §6.2 protocol on the synthetic RGB-D scenarios: every scenario × seeds ×
//! {patch tracker, whole-target baseline} (S6 also with noisy odometry and `no_ego`), each frame
//! rendered once and fed to every tracker. Prints one line per run, then a Markdown table of
//! mean ± sample standard deviation over the seeds.
//!
//! `cargo run --release --example rgbd_protocol -- [s1,s2,..|all] [n_seeds]`

use quarry::repro::rgbd::{OdometryFeed, ScenarioSummary, run_scenario_multi};
use quarry::sim::rgbd::{RgbdScene, ScenarioId};
use quarry::trackers::rgbd_person::RgbdPersonConfig;

fn mean_sd(v: &[f64]) -> (f64, f64) {
    #[allow(clippy::cast_precision_loss)]
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = if v.len() > 1 {
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    (m, var.sqrt())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let which = args.next().unwrap_or_else(|| "all".into());
    let n_seeds: u64 = args.next().map_or(Ok(5), |s| s.parse())?;
    let ids: Vec<ScenarioId> = if which == "all" {
        ScenarioId::ALL.to_vec()
    } else {
        which
            .split(',')
            .map(ScenarioId::from_name)
            .collect::<Result<_, _>>()?
    };
    let mut table: Vec<(String, String, Vec<ScenarioSummary>)> = Vec::new();
    for id in ids {
        let mut runs = vec![
            ("patch", RgbdPersonConfig::paper(), OdometryFeed::Exact),
            (
                "baseline",
                RgbdPersonConfig::whole_target_baseline(),
                OdometryFeed::Exact,
            ),
        ];
        if id == ScenarioId::S6EgoRotation {
            runs.push((
                "patch, 5 % odometry noise",
                RgbdPersonConfig::paper(),
                OdometryFeed::Noisy,
            ));
            runs.push((
                "patch, no_ego",
                RgbdPersonConfig {
                    ego: false,
                    ..RgbdPersonConfig::paper()
                },
                OdometryFeed::Exact,
            ));
        }
        let cfgs: Vec<_> = runs.iter().map(|(_, c, o)| (c.clone(), *o)).collect();
        let mut per: Vec<Vec<ScenarioSummary>> = vec![Vec::new(); runs.len()];
        for seed in 0..n_seeds {
            let scene = RgbdScene::new(id, seed)?;
            let out = run_scenario_multi(&scene, seed, &cfgs, scene.len(), |_, _, _| {})?;
            for (r, (s, _)) in out.into_iter().enumerate() {
                println!(
                    "{} seed {seed} {:26} success {:.3} CLE {:.1} recovery {:?} upd<0.6 {} \
                     occ_recall {:?} rmse3d {:.3} distractor {} lost {} s6_err {:?}",
                    id.name(),
                    runs[r].0,
                    s.success_rate_iou50,
                    s.center_err_px,
                    s.recovery_frames,
                    s.updates_low_visibility,
                    s.occlusion_recall,
                    s.rmse_3d_m,
                    s.distractor_frames,
                    s.lost_frames,
                    s.blackout_end_err_px,
                );
                per[r].push(s);
            }
        }
        for (r, v) in per.into_iter().enumerate() {
            table.push((id.name().to_string(), runs[r].0.to_string(), v));
        }
    }
    println!(
        "\n| scenario | tracker | success@0.5 | CLE (px) | recovery (frames) | updates at vis < 0.6 | other |"
    );
    println!("|---|---|---|---|---|---|---|");
    for (sc, tr, v) in &table {
        let (sm, ss) = mean_sd(&v.iter().map(|s| s.success_rate_iou50).collect::<Vec<_>>());
        let (cm, cs) = mean_sd(&v.iter().map(|s| s.center_err_px).collect::<Vec<_>>());
        let rec: Vec<String> = v
            .iter()
            .map(|s| s.recovery_frames.map_or("never".into(), |r| r.to_string()))
            .collect();
        let upd: Vec<String> = v
            .iter()
            .map(|s| s.updates_low_visibility.to_string())
            .collect();
        let mut other = Vec::new();
        if let Some(o) = v
            .iter()
            .map(|s| s.occlusion_recall)
            .collect::<Option<Vec<_>>>()
        {
            let (m, _) = mean_sd(&o);
            let lo = o.iter().copied().fold(f64::INFINITY, f64::min);
            other.push(format!("occlusion recall {m:.3} (min {lo:.3})"));
        }
        let (rm, _) = mean_sd(&v.iter().map(|s| s.rmse_3d_m).collect::<Vec<_>>());
        other.push(format!("3-D RMSE {rm:.3} m"));
        if sc.starts_with("s5") {
            let d: Vec<String> = v.iter().map(|s| s.distractor_frames.to_string()).collect();
            other.push(format!("distractor frames {}", d.join("/")));
        }
        let lost: usize = v.iter().map(|s| s.lost_frames).sum();
        if lost > 0 {
            other.push(format!("{lost} `Lost` frames in all"));
        }
        if let Some(e) = v
            .iter()
            .map(|s| s.blackout_end_err_px)
            .collect::<Option<Vec<_>>>()
        {
            let (m, sd) = mean_sd(&e);
            other.push(format!("error at frame 130: {m:.1} ± {sd:.1} px"));
        }
        let smin = v
            .iter()
            .map(|s| s.success_rate_iou50)
            .fold(f64::INFINITY, f64::min);
        println!(
            "| {sc} | {tr} | {sm:.3} ± {ss:.3} (min {smin:.3}) | {cm:.1} ± {cs:.1} | {} | {} | {} |",
            rec.join("/"),
            upd.join("/"),
            other.join(", ")
        );
    }
    Ok(())
}
