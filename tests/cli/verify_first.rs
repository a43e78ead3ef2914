//! Every command validates a pack as `verify` does before it uses it (docs/design.md "Runtime:
//! packs"): a pack with a corrupt section that the command would not otherwise read, and a pack
//! whose sections decode alone but disagree with one another, are refused by `export`,
//! `simulate`, `preview` and `view` exactly as by `verify` — exit 1, one line naming the file,
//! nothing written — and `simulate` says so (exit 1) even with a `--max-memory` its estimate
//! would also refuse (exit 2).

use std::path::{Path, PathBuf};

use furbake_formats::SectionKind;
use furbake_fuzz::packs::PackModel;

use super::common::*;

/// Bakes `mesh` with a prisms topology into `out` (16² × 4 shells).
fn bake(mesh: &Path, out: &Path) {
    let args = ["bake", s(mesh), "-o", s(out), "--resolution", "16", "--layers", "4", "--topology", "prisms", "-q"];
    assert_ok(&furbake(&args), &format!("bake {}", mesh.display()));
}

/// The two bad packs, beside a good `box.fbk`: `crc.fbk`, one byte of its spring topology flipped
/// (the checksum no longer matches), and `spliced.fbk`, whose topology comes from a bake of
/// another mesh (every section decodes; the topology disagrees with the skin mesh). Neither the
/// export, nor a pack preview, nor a scene without effects reads the topology.
fn bad_packs(dir: &Path) -> Vec<PathBuf> {
    let good = dir.join("box.fbk");
    bake(&real_fixture("Box.glb"), &good);
    let sphere = dir.join("sphere.fbk");
    bake(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/sphere.gltf"), &sphere);
    let bytes = std::fs::read(&good).unwrap();
    let model = PackModel::parse(&bytes).expect("a valid pack");
    let topology = SectionKind::SPRING_TOPOLOGY.0;
    let at = model.sections.iter().position(|s| s.kind == topology).expect("the bake has a topology");

    let crc = dir.join("crc.fbk");
    let entry = furbake_formats::Pack::from_bytes(&bytes).unwrap().sections()[at];
    let mut corrupt = bytes.clone();
    corrupt[(entry.offset + entry.length / 2) as usize] ^= 0x10;
    std::fs::write(&crc, &corrupt).unwrap();

    let spliced = dir.join("spliced.fbk");
    let other = PackModel::parse(&std::fs::read(&sphere).unwrap()).unwrap();
    let mut model = model;
    model.sections[at] = other.sections.into_iter().find(|s| s.kind == topology).unwrap();
    std::fs::write(&spliced, model.assemble()).unwrap();

    for bad in [&crc, &spliced] {
        let out = furbake(&["verify", s(bad)]);
        assert_eq!(out.status.code(), Some(1), "verify {}: {}", bad.display(), stderr(&out));
    }
    assert_ok(&furbake(&["verify", s(&good)]), "verify the good pack");
    vec![crc, spliced]
}

/// Exit 1 with one line naming `pack`, and `written` absent.
fn assert_refused(args: &[&str], pack: &Path, written: &Path) {
    let out = furbake(args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.starts_with("furbake: error: "), "{args:?}: {err}");
    assert!(err.contains(s(pack)) && err.contains("invalid container"), "{args:?}: the message names no pack: {err}");
    assert!(!written.exists(), "{args:?}: {} was written", written.display());
    assert!(out.stdout.is_empty(), "{args:?}: {}", stdout(&out));
}

/// A scene beside `pack` of `pack` alone and no effect: the world reads the skin mesh only.
fn scene_of(dir: &Path, pack: &Path) -> PathBuf {
    let scene = dir.join(format!("{}.toml", pack.file_stem().unwrap().to_string_lossy()));
    let name = pack.file_name().unwrap().to_string_lossy();
    std::fs::write(&scene, format!("time_step_s = 0.02\n[[packs]]\nname = \"p\"\npath = \"{name}\"\n")).unwrap();
    scene
}

#[test]
fn a_pack_verify_rejects_is_refused_by_every_command() {
    let dir = tempfile::tempdir().unwrap();
    let mut refused = 0;
    for pack in bad_packs(dir.path()) {
        let glb = dir.path().join("out.glb");
        assert_refused(&["export", s(&pack), "-o", s(&glb)], &pack, &glb);
        let png = dir.path().join("out.png");
        assert_refused(&["preview", s(&pack), "-o", s(&png)], &pack, &png);
        let scene = scene_of(dir.path(), &pack);
        let report = dir.path().join("report.json");
        let state = dir.path().join("state.json");
        let args = ["simulate", s(&scene), "--frames", "2", "-o", s(&report), "--state-out", s(&state)];
        assert_refused(&args, &pack, &report);
        assert!(!state.exists());
        assert_refused(&["preview", s(&scene), "-o", s(&png)], &pack, &png);
        // The viewer validates before it looks for a display (the message would name DISPLAY).
        let shot = dir.path().join("shot.png");
        assert_refused(&["view", s(&pack), "--frames", "1", "--screenshot", s(&shot)], &pack, &shot);
        refused += 5;
    }
    assert_eq!(refused, 10);
    // The good pack exports and simulates (the control).
    let good = dir.path().join("box.fbk");
    let glb = dir.path().join("box.glb");
    assert_ok(&furbake(&["export", s(&good), "-o", s(&glb), "-q"]), "export the good pack");
    assert_ok(&furbake(&["simulate", s(&scene_of(dir.path(), &good)), "--frames", "2", "-q"]), "simulate it");
}

#[test]
fn simulate_blames_a_corrupt_pack_before_the_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let packs = bad_packs(dir.path());
    // The good pack over a tiny budget: the estimate refuses it (exit 2).
    let good = scene_of(dir.path(), &dir.path().join("box.fbk"));
    let out = furbake(&["simulate", s(&good), "--frames", "2", "--max-memory", "1K"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("above --max-memory"), "{}", stderr(&out));
    // A bad pack over the same budget is bad input first (exit 1).
    for pack in packs {
        let scene = scene_of(dir.path(), &pack);
        let report = dir.path().join("report.json");
        let args = ["simulate", s(&scene), "--frames", "2", "--max-memory", "1K", "-o", s(&report)];
        assert_refused(&args, &pack, &report);
    }
}
