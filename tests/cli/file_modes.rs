//! Files as users expect them: packs, PNGs and JSON that furbake writes get the permissions of an
//! ordinary file write (`0o666` minus the umask), still written atomically.
//!
//! Regression: every output went through a temporary file created `0o600` and renamed into place,
//! so a pipeline handing baked assets to another user or a web server could not read them.

#![cfg(unix)]

use std::os::unix::fs::PermissionsExt;
use std::path::Path;
use std::process::{Command, Output};

use super::common::*;

/// Runs `furbake ARGS` from a shell that set `umask 022` first.
fn furbake_under_umask_022(args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg("umask 022 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_furbake"))
        .args(args)
        .output()
        .expect("sh runs")
}

fn mode(p: &Path) -> u32 {
    std::fs::metadata(p).unwrap_or_else(|e| panic!("{}: {e}", p.display())).permissions().mode() & 0o777
}

#[test]
fn packs_pngs_and_json_are_0644_under_umask_022() {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("box.fbk");
    let png_dir = dir.path().join("bake-png");
    let mesh = real_fixture("Box.glb");
    let out = furbake_under_umask_022(&[
        "bake",
        s(&mesh),
        "-o",
        s(&pack),
        "--resolution",
        "16",
        "--layers",
        "4",
        "--png-dir",
        s(&png_dir),
        "-q",
    ]);
    assert_ok(&out, "bake");
    let extracted = dir.path().join("extracted");
    assert_ok(&furbake_under_umask_022(&["extract", s(&pack), "-o", s(&extracted), "-q"]), "extract");
    let table = dir.path().join("table.fbk");
    assert_ok(
        &furbake_under_umask_022(&["keyframes", "-o", s(&table), "--poses", "40", "--segments", "2", "-q"]),
        "keyframes",
    );
    let mut checked = Vec::new();
    for path in [
        pack.clone(),
        table.clone(),
        png_dir.join("fins.png"),
        png_dir.join("shells_grid.png"),
        extracted.join("shell_layer_000.png"),
        extracted.join("fins.png"),
        extracted.join("metadata.json"),
    ] {
        assert_eq!(mode(&path), 0o644, "{}: mode {:o}", path.display(), mode(&path));
        checked.push(path);
    }
    assert_eq!(checked.len(), 7);
    // Every PNG of both directories, not only the named ones.
    let pngs: Vec<_> = [&png_dir, &extracted]
        .iter()
        .flat_map(|d| std::fs::read_dir(d).unwrap().map(|e| e.unwrap().path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    assert_eq!(pngs.len(), 2 * (4 + 2), "{pngs:?}");
    for p in &pngs {
        assert_eq!(mode(p), 0o644, "{}", p.display());
    }
}
