//! Hermetic output: a bake is a pure function of its inputs and settings. The same glTF (with an
//! external buffer and texture) baked from two different directories — different absolute input
//! paths, working directories, relative or absolute arguments, user, time zone and thread count —
//! gives byte-identical packs, and no path of the machine appears inside a pack.

use std::path::Path;
use std::process::Command;

use super::common::*;

/// Copies the shared real fixture `TwoSidedPlane` (a .gltf with an external buffer and textures)
/// into `dir`; returns the number of files copied.
fn copy_plane(dir: &Path) -> usize {
    let src = real_fixture("TwoSidedPlane");
    std::fs::create_dir_all(dir).unwrap();
    let mut copied = 0;
    for entry in std::fs::read_dir(&src).unwrap() {
        let path = entry.unwrap().path();
        if path.file_name().unwrap().to_string_lossy().starts_with("TwoSidedPlane") {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
            copied += 1;
        }
    }
    copied
}

#[test]
fn the_same_input_baked_from_two_directories_gives_the_same_bytes() {
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let name = "TwoSidedPlane.gltf";
    let dir_a = a.path().join("assets");
    let dir_b = b.path().join("some/deeper/place");
    assert_eq!(copy_plane(&dir_a), 5, "the .gltf, its buffer and three textures");
    copy_plane(&dir_b);
    let common = ["--resolution", "16", "--topology", "prisms", "-q"];
    // A: relative paths from the asset folder, one thread, one user and time zone.
    let out = Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(["bake", name, "-o", "out.fbk", "--threads", "1"])
        .args(common)
        .current_dir(&dir_a)
        .env("TZ", "UTC")
        .env("USER", "alice")
        .output()
        .unwrap();
    assert_ok(&out, "bake A");
    // B: absolute paths from elsewhere, two threads, another user and time zone.
    let out_b = b.path().join("elsewhere.fbk");
    let out = Command::new(env!("CARGO_BIN_EXE_furbake"))
        .args(["bake", dir_b.join(name).to_str().unwrap(), "-o", out_b.to_str().unwrap(), "--threads", "2"])
        .args(common)
        .current_dir(b.path())
        .env("TZ", "Pacific/Auckland")
        .env("USER", "bob")
        .output()
        .unwrap();
    assert_ok(&out, "bake B");
    let (bytes_a, bytes_b) = (std::fs::read(dir_a.join("out.fbk")).unwrap(), std::fs::read(&out_b).unwrap());
    assert_eq!(bytes_a.len(), bytes_b.len());
    assert!(bytes_a == bytes_b, "the two bakes differ");
    // Nothing of either machine path is inside the pack.
    let text = String::from_utf8_lossy(&bytes_a);
    for needle in [a.path().to_str().unwrap(), b.path().to_str().unwrap(), "/tmp", "alice", "bob"] {
        assert!(!text.contains(needle), "the pack contains {needle:?}");
    }
}
