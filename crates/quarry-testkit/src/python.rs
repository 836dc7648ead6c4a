//! A Python virtual environment for the tests that check quarry against Python tools nobody here
//! wrote (the `mcap` reader, `rosbags`, `eclipse-zenoh`, filterpy, ...).
//!
//! [`venv`] creates (once) a venv under the caller's target directory and installs a pinned
//! requirements file into it; later calls reuse it as long as the requirements file is unchanged.
//! Test processes that race for the same venv wait for each other (a lock directory), so
//! `cargo test` and `cargo nextest` both work.
//!
//! Whether a missing Python is an error is the caller's environment's choice: with
//! `QUARRY_REQUIRE_PYTHON=1` (set by `.ci/run`) [`venv_or_skip`] panics with the reason, so CI
//! cannot pass by skipping; without it the test prints the reason and skips. The interpreter is
//! `$QUARRY_PYTHON`, else `python3`.
//!
//! ```no_run
//! use std::path::Path;
//! // In an integration test: `env!("CARGO_TARGET_TMPDIR")` is the crate's scratch directory.
//! let reqs = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/requirements.txt");
//! if let Some(py) = quarry_testkit::python::venv_or_skip(Path::new("/tmp"), "example", &reqs) {
//!     let out = py.command().arg("-c").arg("print(1 + 1)").output().unwrap();
//!     assert_eq!(String::from_utf8_lossy(&out.stdout).trim(), "2");
//! }
//! ```

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// A ready virtual environment.
#[derive(Debug, Clone)]
pub struct PythonEnv {
    root: PathBuf,
    python: PathBuf,
}

impl PythonEnv {
    /// The venv's directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The venv's interpreter.
    pub fn python(&self) -> &Path {
        &self.python
    }

    /// Installs a second requirements file with `pip install --no-deps` (for packages whose
    /// declared dependencies would pull in what the caller does not need), once per content of
    /// the file: a stamp in the venv remembers it, and a new venv (changed main requirements)
    /// starts without the stamp.
    ///
    /// # Errors
    /// An unreadable file, or pip failing (message included).
    pub fn install_no_deps(&self, requirements: &Path) -> Result<(), String> {
        let wanted = fs::read_to_string(requirements)
            .map_err(|e| format!("cannot read {}: {e}", requirements.display()))?;
        let stamp = self.root.join("quarry-requirements-nodeps.txt");
        if fs::read_to_string(&stamp).ok().as_deref() == Some(&wanted) {
            return Ok(());
        }
        pip_install(&self.python, &["--no-deps"], requirements)?;
        fs::write(&stamp, &wanted).map_err(|e| format!("cannot write {}: {e}", stamp.display()))
    }

    /// A `Command` running the venv's interpreter (add the script and its arguments).
    pub fn command(&self) -> Command {
        let mut c = Command::new(&self.python);
        c.env("PYTHONDONTWRITEBYTECODE", "1");
        c
    }
}

/// Serialises venv creation between the threads of one test binary (the lock directory does it
/// between processes).
static IN_PROCESS: Mutex<()> = Mutex::new(());

/// How long a test waits for another process that is installing the same venv.
const LOCK_WAIT: Duration = Duration::from_mins(30);

/// Creates or reuses the venv `<dir>/pyenv-<name>` with `requirements` installed.
///
/// # Errors
/// A message saying what failed: no interpreter, `venv` or `pip` failing (no registry access),
/// an unreadable requirements file, or waiting on another installer for more than 30 minutes.
pub fn venv(dir: &Path, name: &str, requirements: &Path) -> Result<PythonEnv, String> {
    let _guard = IN_PROCESS
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let wanted = fs::read_to_string(requirements)
        .map_err(|e| format!("cannot read {}: {e}", requirements.display()))?;
    fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let root = dir.join(format!("pyenv-{name}"));
    let python = root.join("bin").join("python");
    let stamp = root.join("quarry-requirements.txt");
    let env = PythonEnv {
        root: root.clone(),
        python: python.clone(),
    };
    let ready = || python.exists() && fs::read_to_string(&stamp).ok().as_deref() == Some(&wanted);
    if ready() {
        return Ok(env);
    }
    let lock = dir.join(format!("pyenv-{name}.lock"));
    let _lock = DirLock::acquire(&lock)?;
    if ready() {
        return Ok(env);
    }
    let interpreter = std::env::var("QUARRY_PYTHON").unwrap_or_else(|_| "python3".into());
    let _ = fs::remove_dir_all(&root);
    run(Command::new(&interpreter).arg("-m").arg("venv").arg(&root))
        .map_err(|e| format!("`{interpreter} -m venv` failed: {e}"))?;
    pip_install(&python, &[], requirements)?;
    fs::write(&stamp, &wanted).map_err(|e| format!("cannot write {}: {e}", stamp.display()))?;
    Ok(env)
}

/// [`venv`], or `None` after printing why it is skipped; panics instead when
/// `QUARRY_REQUIRE_PYTHON` is set (CI), so that a broken install fails the run.
pub fn venv_or_skip(dir: &Path, name: &str, requirements: &Path) -> Option<PythonEnv> {
    match venv(dir, name, requirements) {
        Ok(env) => Some(env),
        Err(e) if std::env::var_os("QUARRY_REQUIRE_PYTHON").is_some() => {
            panic!("QUARRY_REQUIRE_PYTHON is set and the Python venv `{name}` is not ready: {e}")
        }
        Err(e) => {
            eprintln!("skipped: Python venv `{name}` not available ({e})");
            None
        }
    }
}

/// `python -m pip install -q [extra] -r requirements`.
fn pip_install(python: &Path, extra: &[&str], requirements: &Path) -> Result<(), String> {
    run(Command::new(python)
        .args(["-m", "pip", "install", "-q", "--disable-pip-version-check"])
        .args(extra)
        .arg("-r")
        .arg(requirements))
    .map_err(|e| {
        format!(
            "pip install {extra:?} -r {} failed: {e}",
            requirements.display()
        )
    })
}

fn run(cmd: &mut Command) -> Result<(), String> {
    let out = cmd.output().map_err(|e| e.to_string())?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "{}: {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// A lock held as a directory (created atomically); holds the owner's pid so a lock left by a
/// killed process is taken over.
struct DirLock(PathBuf);

impl DirLock {
    fn acquire(path: &Path) -> Result<Self, String> {
        let start = Instant::now();
        loop {
            match fs::create_dir(path) {
                Ok(()) => {
                    let _ = fs::write(path.join("pid"), std::process::id().to_string());
                    return Ok(Self(path.to_path_buf()));
                }
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let owner = fs::read_to_string(path.join("pid")).ok();
                    let dead = owner
                        .as_deref()
                        .and_then(|p| p.trim().parse::<u32>().ok())
                        .is_some_and(|pid| !Path::new(&format!("/proc/{pid}")).exists());
                    if dead {
                        let _ = fs::remove_dir_all(path);
                        continue;
                    }
                    if start.elapsed() > LOCK_WAIT {
                        return Err(format!("waited {LOCK_WAIT:?} for {}", path.display()));
                    }
                    std::thread::sleep(Duration::from_millis(500));
                }
                Err(e) => return Err(format!("cannot create {}: {e}", path.display())),
            }
        }
    }
}

impl Drop for DirLock {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.0);
    }
}
