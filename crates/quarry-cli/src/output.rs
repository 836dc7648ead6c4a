//! Shared output helpers: one JSON object on stdout with `--json`, aligned tables otherwise, and
//! error reporting.

use std::fmt::Write as _;

use serde::Serialize;

/// The boxed error every subcommand returns; `main` prints it and exits non-zero.
pub type CmdError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What a subcommand returns.
pub type CmdResult = Result<(), CmdError>;

/// A file that could not be read or written, with the path (the I/O error stays the source).
#[derive(Debug, thiserror::Error)]
#[error("{path}: {source}")]
pub struct PathError {
    /// The file.
    pub path: String,
    /// What the OS said.
    #[source]
    pub source: std::io::Error,
}

/// `map_err(at(path))`: an I/O error on `path` as a [`PathError`].
pub fn at(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> PathError + '_ {
    move |source| PathError {
        path: path.display().to_string(),
        source,
    }
}

/// Where and how a subcommand prints its result (passed to every subcommand as `&Output`;
/// deliberately not `Copy` so that it can grow, e.g. a verbosity level or an output directory).
#[derive(Debug, Clone)]
pub struct Output {
    /// `--json`: print exactly one JSON object on stdout, nothing else.
    pub json: bool,
}

impl Output {
    /// Prints the result: `value` as one JSON object with `--json`, else the `human` text.
    pub fn emit<T: Serialize>(&self, value: &T, human: impl FnOnce() -> String) -> CmdResult {
        let text = if self.json {
            format!("{}\n", serde_json::to_string(value)?)
        } else {
            human()
        };
        write_stdout(&text)
    }

    /// Reports an error: `error: ...` (with its causes) on stderr; with `--json` also
    /// `{"error": "..."}` on stdout so scripts always get one object.
    pub fn error(&self, e: &(dyn std::error::Error + 'static)) {
        let mut msg = e.to_string();
        let mut src = e.source();
        while let Some(s) = src {
            // a message that already says its source (`{path}: {source}`) is not repeated
            let text = s.to_string();
            if !msg.contains(&text) {
                let _ = write!(msg, ": {text}");
            }
            src = s.source();
        }
        eprintln!("error: {msg}");
        if self.json {
            let _ = write_stdout(&format!("{}\n", serde_json::json!({ "error": msg })));
        }
    }
}

/// A plain-text table with left-aligned text and right-aligned numbers.
#[derive(Debug, Clone, Default)]
pub struct Table {
    headers: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with these column headers.
    pub fn new<S: Into<String>>(headers: impl IntoIterator<Item = S>) -> Self {
        Self {
            headers: headers.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row (missing cells print empty, extra cells are kept).
    pub fn row<S: Into<String>>(&mut self, cells: impl IntoIterator<Item = S>) {
        self.rows.push(cells.into_iter().map(Into::into).collect());
    }

    /// The table as text, one line per row, columns separated by two spaces.
    pub fn render(&self) -> String {
        let ncol = self
            .rows
            .iter()
            .map(Vec::len)
            .chain([self.headers.len()])
            .max()
            .unwrap_or(0);
        let cell = |r: &Vec<String>, c: usize| r.get(c).cloned().unwrap_or_default();
        let width: Vec<usize> = (0..ncol)
            .map(|c| {
                self.rows
                    .iter()
                    .chain([&self.headers])
                    .map(|r| cell(r, c).chars().count())
                    .max()
                    .unwrap_or(0)
            })
            .collect();
        let numeric = |s: &str| s.parse::<f64>().is_ok();
        let line = |r: &Vec<String>| -> String {
            let parts: Vec<String> = (0..ncol)
                .map(|c| {
                    let s = cell(r, c);
                    if numeric(&s) {
                        format!("{s:>w$}", w = width[c])
                    } else {
                        format!("{s:<w$}", w = width[c])
                    }
                })
                .collect();
            parts.join("  ").trim_end().to_string()
        };
        let mut out = String::new();
        let _ = writeln!(out, "{}", line(&self.headers));
        let rule: Vec<String> = width.iter().map(|&w| "-".repeat(w)).collect();
        let _ = writeln!(out, "{}", rule.join("  "));
        for r in &self.rows {
            let _ = writeln!(out, "{}", line(r));
        }
        out
    }
}

/// Formats an optional ratio with `digits` decimals, `n/a` when undefined.
pub fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "n/a".to_string(), |x| format!("{x:.digits$}"))
}

/// Writes `text` to stdout. A closed pipe (`quarry ... --json | head -c 100`) ends the output
/// quietly instead of panicking as `println!` does; other write errors are reported.
fn write_stdout(text: &str) -> CmdResult {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(format!("cannot write to stdout: {e}").into()),
        Ok(()) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_aligns_columns() {
        let mut t = Table::new(["name", "value"]);
        t.row(["MOTA", "0.9110"]);
        t.row(["ID switches", "1"]);
        let s = t.render();
        let lines: Vec<&str> = s.lines().collect();
        assert_eq!(lines[0], "name         value");
        assert_eq!(lines[2], "MOTA         0.9110");
        assert_eq!(lines[3], "ID switches       1");
        assert_eq!(fmt_opt(None, 3), "n/a");
        assert_eq!(fmt_opt(Some(0.5), 2), "0.50");
    }
}
