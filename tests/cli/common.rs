//! Helpers shared by the CLI tests: running the binary and finding fixtures.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs the `furbake` binary built for this test.
pub fn furbake(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_furbake")).args(args).output().expect("the furbake binary runs")
}

/// Fails with the command's stderr unless it exited 0.
pub fn assert_ok(out: &Output, what: &str) {
    assert!(out.status.success(), "{what} failed ({:?}): {}", out.status.code(), stderr(out));
}

/// The command's stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The command's stdout as text.
pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// A path as `&str` (test paths are UTF-8).
pub fn s(p: &Path) -> &str {
    p.to_str().expect("test paths are UTF-8")
}

/// The real fixtures folder: the repository's `fixtures/real/` (licences beside them), or the
/// folder `FURBAKE_FIXTURES` names (to run the tests on another set of models).
pub fn real_dir() -> PathBuf {
    let dir = std::env::var_os("FURBAKE_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/real"));
    assert!(dir.is_dir(), "the real fixtures are missing: expected {}", dir.display());
    dir
}

/// One real fixture by file name.
pub fn real_fixture(name: &str) -> PathBuf {
    real_dir().join(name)
}

/// Every .glb / .gltf under the real fixtures, sorted.
pub fn real_fixtures() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![real_dir()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if matches!(p.extension().and_then(|x| x.to_str()), Some("glb" | "gltf")) {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}
