//! A closed stdout ends a command quietly: `furbake inspect PACK | head -1` and friends exit 0
//! with nothing on stderr.
//!
//! Regression: output went through `println!`, which panics when the write fails, so a reader that
//! had exited (`head`) made furbake print "failed printing to stdout: Broken pipe" with a panic
//! message and exit 101.

use std::path::Path;
use std::process::{Command, Output, Stdio};

use crate::common::*;

/// Runs `furbake` with stdout a pipe whose read end is already closed, so the first write fails
/// with `EPIPE` (deterministically: no reader ever existed to drain the pipe).
fn furbake_into_closed_pipe(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(args)
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .expect("the furbake binary runs")
}

#[test]
fn inspect_verify_extract_and_simulate_exit_quietly_on_a_closed_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let pack = dir.path().join("patch.fbk");
    let bake = ["bake", s(&patch), "-o", s(&pack), "--resolution", "16", "--topology", "prisms", "-q"];
    assert_ok(&furbake(&bake), "bake");
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/fur_wind_gust.toml");
    let scene = dir.path().join("fur_wind_gust.toml");
    std::fs::copy(example, &scene).unwrap();
    let ex = dir.path().join("ex");
    let cases: [&[&str]; 6] = [
        &["inspect", s(&pack)],
        &["inspect", "--json", s(&pack)],
        &["verify", s(&pack)],
        &["extract", s(&pack), "-o", s(&ex)],
        &["simulate", s(&scene), "--frames", "2", "--json"],
        &["simulate", s(&scene), "--frames", "2"],
    ];
    let mut checked = 0;
    for args in cases {
        // The command works when someone reads its output …
        let out = furbake(args);
        assert_ok(&out, &format!("{args:?}"));
        assert!(!out.stdout.is_empty(), "{args:?} prints something to stdout");
        // … and stops quietly when nobody does.
        let out = furbake_into_closed_pipe(args);
        assert_eq!(out.status.code(), Some(0), "{args:?}: {}", stderr(&out));
        assert_eq!(stderr(&out), "", "{args:?} wrote to stderr");
        checked += 1;
    }
    assert_eq!(checked, 6);
}
