//! Builds nothing itself: finds the cdylib cargo built for this test profile, installs it as the
//! `quarry` extension module in a temp package dir and runs the pytest suite in
//! `tests/python` inside a pinned venv (`requirements.txt`, then `requirements-nodeps.txt`
//! without dependencies; skipped with a printed reason when the venv cannot be made, unless
//! `QUARRY_REQUIRE_PYTHON=1`).

use std::path::{Path, PathBuf};

fn cdylib() -> Option<PathBuf> {
    // CARGO_TARGET_TMPDIR is <target>/tmp; the test binary lives in <target>/<profile>/deps.
    let exe = std::env::current_exe().ok()?;
    let deps = exe.parent()?;
    let profile = deps.parent()?;
    [
        profile.join("libquarry_py.so"),
        deps.join("libquarry_py.so"),
    ]
    .into_iter()
    .find(|p| p.exists())
}

#[test]
fn pytest_suite() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let reqs = here.join("tests/python/requirements.txt");
    let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let Some(py) = quarry_testkit::python::venv_or_skip(tmp, "py", &reqs) else {
        return;
    };
    if let Err(e) = py.install_no_deps(&here.join("tests/python/requirements-nodeps.txt")) {
        assert!(
            std::env::var_os("QUARRY_REQUIRE_PYTHON").is_none(),
            "pip install --no-deps -r requirements-nodeps.txt failed: {e}"
        );
        eprintln!("skipped: pip install --no-deps -r requirements-nodeps.txt failed ({e})");
        return;
    }
    let Some(so) = cdylib() else {
        panic!(
            "libquarry_py.so not found next to the test binary; build with cargo test -p quarry-py"
        );
    };
    let pkg = tmp.join("quarry-py-pkg");
    let _ = std::fs::remove_dir_all(&pkg);
    std::fs::create_dir_all(&pkg).expect("create temp package dir");
    std::fs::copy(&so, pkg.join("quarry.so")).expect("copy the extension module");
    let status = py
        .command()
        .args(["-m", "pytest", "-q", "-p", "no:cacheprovider"])
        .arg(here.join("tests/python"))
        .env("PYTHONPATH", &pkg)
        .status()
        .expect("run pytest");
    assert!(status.success(), "pytest failed: {status}");
}
