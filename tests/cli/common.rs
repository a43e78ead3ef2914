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

/// The shared real fixtures folder (`../shared/fixtures/real` beside the repository).
pub fn shared_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/fixtures/real");
    assert!(dir.is_dir(), "the shared fixtures are missing: expected {}", dir.display());
    dir
}

/// One shared fixture by file name.
pub fn shared_fixture(name: &str) -> PathBuf {
    shared_dir().join(name)
}

/// Every .glb / .gltf under the shared fixtures, sorted.
pub fn real_fixtures() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![shared_dir()];
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
