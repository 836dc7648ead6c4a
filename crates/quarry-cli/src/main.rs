//! The `quarry` command-line tool.
//!
//! Layout: `main.rs` holds the [`Cli`], the [`Command`] enum and the dispatch; each subcommand
//! lives in `cmd/<name>.rs` (see `cmd/mod.rs` for how to add one); `output.rs` prints JSON
//! (`--json`: exactly one object on stdout) or tables; `progress.rs` gives progress bars that
//! hide themselves when stdout is not a terminal or with `--json`.

use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};

mod cmd;
mod config_args;
mod fonts;
mod interrupt;
mod output;
mod progress;
mod record;

use output::Output;

/// quarry: multi-target tracking for robotics and vision.
#[derive(Debug, Parser)]
#[command(
    name = "quarry",
    version,
    about = "quarry: multi-target tracking for robotics and vision",
    long_about = "quarry: multi-target tracking for robotics and vision.

Run the trackers of four published papers on built-in simulated scenarios or on your data, \
and score tracking results with the standard metrics (CLEAR MOT, IDF1, HOTA).

Every subcommand accepts --json: it then prints exactly one JSON object on stdout (field names \
documented in the subcommand's --help) and nothing else; errors go to stderr (and, with --json, \
as {\"error\": \"...\"} on stdout) with a non-zero exit status.

Run `quarry <command> --help` for each command's input formats and an example.",
    after_help = "EXAMPLES:\n  quarry demo\n  quarry eval --gt gt.txt --res results.txt --json"
)]
struct Cli {
    #[command(flatten)]
    global: GlobalArgs,
    #[command(subcommand)]
    command: Command,
}

/// Options every subcommand accepts.
#[derive(Debug, Args)]
struct GlobalArgs {
    /// Print exactly one JSON object on stdout instead of human-readable text.
    #[arg(long, global = true)]
    json: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    // No doc comments on the variants: clap would take them as the subcommand's help and hide
    // the `about` / `long_about` written on each Args struct in cmd/<name>.rs.
    Demo(cmd::demo::DemoArgs),
    Eval(cmd::eval::EvalArgs),
    /// RBPF SLAM + multi-target tracking (paper 000) on its scenario or on MRCLAM data.
    Slamot(cmd::slamot::SlamotArgs),
    /// People tracking with distributed 2-D laser scanners (paper 003) in the simulated room.
    Lidar(cmd::lidar::LidarArgs),
    LidarNode(cmd::lidar_net::LidarNodeArgs),
    LidarServer(cmd::lidar_net::LidarServerArgs),
    /// SIFT keypoints of an image, or keypoints and matches of two images.
    Sift(cmd::sift::SiftArgs),
    Segment(cmd::segment::SegmentArgs),
    Motion(cmd::motion::MotionArgs),
    Rgbd(cmd::rgbd::RgbdArgs),
    Video(cmd::video::VideoArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => return usage_error(&e),
    };
    let out = Output {
        json: cli.global.json,
    };
    let result = match &cli.command {
        Command::Demo(a) => cmd::demo::run(a, &out),
        Command::Eval(a) => cmd::eval::run(a, &out),
        Command::Slamot(a) => cmd::slamot::run(a, &out),
        Command::Lidar(a) => cmd::lidar::run(a, &out),
        Command::LidarNode(a) => cmd::lidar_net::run_node(a, &out),
        Command::LidarServer(a) => cmd::lidar_net::run_server(a, &out),
        Command::Sift(a) => cmd::sift::run(a, &out),
        Command::Segment(a) => cmd::segment::run(a, &out),
        Command::Motion(a) => cmd::motion::run(a, &out),
        Command::Rgbd(a) => cmd::rgbd::run(a, &out),
        Command::Video(a) => cmd::video::run(a, &out),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<interrupt::Interrupted>() => {
            // the summary (and, with --json, its one object) is out already
            eprintln!("{e}");
            ExitCode::from(interrupt::EXIT)
        }
        Err(e) => {
            out.error(e.as_ref());
            ExitCode::FAILURE
        }
    }
}

/// A command line clap could not parse: `--help` and `--version` print as usual (exit 0); any
/// other error prints clap's message on stderr and, when `--json` is among the arguments, also
/// `{"error": "..."}` on stdout, so that a script asking for JSON always gets one object. Exit
/// status 2, as clap's own usage errors.
fn usage_error(e: &clap::Error) -> ExitCode {
    use clap::error::ErrorKind;
    if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        e.exit();
    }
    let _ = e.print();
    if std::env::args_os().skip(1).any(|a| a == "--json") {
        let msg = if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
            "no command given: run `quarry --help` for the list".to_string()
        } else {
            usage_text(e)
        };
        println!("{}", serde_json::json!({ "error": msg }));
    }
    ExitCode::from(2)
}

/// clap's error message without the `error: ` prefix, the usage block and the `--help` hint:
/// the first paragraph, on one line.
fn usage_text(e: &clap::Error) -> String {
    let rendered = e.render().to_string();
    let first = rendered.split("\n\n").next().unwrap_or_default();
    let first = first.trim().strip_prefix("error: ").unwrap_or(first.trim());
    first.split_whitespace().collect::<Vec<_>>().join(" ")
}
