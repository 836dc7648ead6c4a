//! One module per subcommand. To add one: write `src/cmd/<name>.rs` with an `Args` struct
//! (clap `Args` derive, long help with an example) and `pub fn run(args: &Args, out: &Output)
//! -> CmdResult`, add `pub mod <name>;` here, and one variant plus one dispatch line in
//! `src/main.rs`.

pub mod demo;
pub mod eval;
pub mod lidar;
pub mod lidar_net;
pub mod motion;
pub mod rgbd;
pub mod segment;
pub mod sift;
pub mod slamot;
pub mod video;
pub mod video_sim;
