//! The `quarry` command-line tool.

use clap::{Parser, Subcommand};

/// quarry: multi-target tracking for robotics and vision.
#[derive(Parser)]
#[command(name = "quarry", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run every tracker on its built-in scenario and print one summary table.
    Demo,
}

fn main() {
    let cli = Cli::parse();
    match cli.command {
        Command::Demo => println!("quarry demo: no tracker has landed yet"),
    }
}
