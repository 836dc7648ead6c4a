//! Progress bars that stay out of the way: hidden when stdout is not a terminal or with
//! `--json`, so piped and machine-read output stays clean.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

use crate::output::Output;

/// A progress bar over `len` steps labelled `what`; hidden unless stdout is a terminal and
/// `--json` is off. Draws on stderr.
pub fn bar(out: &Output, len: u64, what: &str) -> ProgressBar {
    if out.json || !std::io::stdout().is_terminal() {
        return ProgressBar::hidden();
    }
    let pb = ProgressBar::new(len);
    if let Ok(style) = ProgressStyle::with_template("{msg:>12} [{bar:30}] {pos}/{len} ({eta})") {
        pb.set_style(style.progress_chars("=> "));
    }
    pb.set_message(what.to_string());
    pb
}
