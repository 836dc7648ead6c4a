//! Ctrl-C / SIGTERM for the long-running commands: the first signal asks the run to stop at the
//! next frame (it then writes what it has and exits with [`EXIT`]); a second one ends the
//! process at once, for a run that does not get to its next frame.

use std::sync::atomic::{AtomicBool, Ordering};

/// Set by the signal handler.
static STOP: AtomicBool = AtomicBool::new(false);

/// The exit status of a run stopped by a signal (128 + SIGINT, as shells report it).
pub const EXIT: u8 = 130;

/// Installs the handler (once per process; later calls do nothing).
pub fn install() {
    let _ = ctrlc::set_handler(|| {
        if STOP.swap(true, Ordering::SeqCst) {
            eprintln!("interrupted twice: stopping now, without writing the outputs");
            std::process::exit(i32::from(EXIT));
        }
        eprintln!("interrupted: finishing the current frame and writing what there is");
    });
}

/// Whether a stop was asked for.
pub fn requested() -> bool {
    STOP.load(Ordering::SeqCst)
}

/// The flag itself, for library loops that take one (e.g. `quarry_net::run_wall_server_until`).
pub fn flag() -> &'static AtomicBool {
    &STOP
}

/// A run stopped by a signal: its outputs so far are written; the exit status is [`EXIT`].
#[derive(Debug, thiserror::Error)]
#[error("interrupted: the outputs so far are written")]
pub struct Interrupted;
