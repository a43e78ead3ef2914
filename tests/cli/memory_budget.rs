//! A memory budget decided before work (docs/design.md "Memory budget"): `bake` estimates the peak
//! memory of its plan on the imported mesh, and `simulate` that of its run from the scene and the
//! packs' section tables, before anything large is allocated. A plan over `--max-memory` (default
//! 2G) exits 2 with one line naming the file, the estimate, the budget and what drives the largest
//! part, and writes nothing. The refused plans here would take gigabytes (or run for minutes): a
//! budget check that came after the work would not finish quickly.

use std::path::{Path, PathBuf};

use super::common::*;

/// Runs a bake that must be refused by the budget: exit 2, one line naming `mesh`, `--max-memory`
/// and `key`, no pack written. Returns the message.
fn assert_bake_refused(mesh: &Path, extra: &[&str], key: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("out.fbk");
    let mut args = vec!["bake", s(mesh), "-o", s(&pack)];
    args.extend_from_slice(extra);
    let out = furbake(&args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    assert!(err.starts_with(&format!("furbake: error: {}: the bake needs about ", mesh.display())), "{err}");
    for needle in ["MiB", "above --max-memory", key, "raise --max-memory"] {
        assert!(err.contains(needle), "{args:?}: no {needle:?} in {err}");
    }
    assert!(!pack.exists(), "{args:?}: the pack was written");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{args:?}: files left behind");
    err
}

#[test]
fn a_bake_over_the_budget_exits_2_naming_the_setting_that_drives_it() {
    let fox = real_fixture("Fox.glb");
    // The fur preset's shells are the Fox bake's largest part: 16 layers of 128² at the write.
    let err = assert_bake_refused(&fox, &["--max-memory", "1M"], "volume.resolution = 128");
    assert!(err.contains("lower volume.resolution (--resolution)"), "{err}");
    // 16 layers of 4096² texels: ~800 MiB of shells, within the format's voxel limit.
    assert_bake_refused(&fox, &["--resolution", "4096", "--max-memory", "256M"], "volume.resolution = 4096");
    // 1024 layers of 512²: the same volume, blamed on the layers.
    assert_bake_refused(
        &fox,
        &["--layers", "1024", "--resolution", "512", "--max-memory", "256M"],
        "volume.layers = 1024",
    );
}

#[test]
fn a_huge_blade_density_is_refused_before_any_blade_is_scattered() {
    // The thesis's 4 m × 4 m patch at 900,000 blades per m²: 14.4 million blades, under the
    // format's count limit but about 1.7 GiB at the write — gigabytes and minutes of work if the
    // budget were checked after it.
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let err = assert_bake_refused(
        &patch,
        &["--preset", "grass", "--blades", "900000", "--max-memory", "1G"],
        "blades.field.density_per_m2 = 900000",
    );
    assert!(err.contains("grass blade field"), "{err}");
    assert!(err.contains("(--blades)"), "{err}");
}

#[test]
fn the_default_budget_accepts_the_usual_bakes() {
    let dir = tempfile::tempdir().unwrap();
    let fox = real_fixture("Fox.glb");
    let pack = dir.path().join("fox.fbk");
    let out = furbake(&["bake", s(&fox), "-o", s(&pack), "--topology", "prisms", "-q"]);
    assert_ok(&out, "bake Fox with the default budget");
    assert!(pack.exists());
    // An explicit budget just above the estimate is enough, too.
    let out = furbake(&["bake", s(&fox), "-o", s(&pack), "--max-memory", "64M", "-q"]);
    assert_ok(&out, "bake Fox within 64M");
    assert!(
        furbake(&["bake", s(&fox), "-o", s(&pack), "--max-memory", "lots"]).status.code() == Some(2),
        "a size that is not one is a usage error"
    );
}

/// Bakes the Fox with prisms into `dir/fox.fbk` and writes a windy scene for it.
fn fox_scene(dir: &Path) -> PathBuf {
    let pack = dir.join("fox.fbk");
    let out = furbake(&["bake", s(&real_fixture("Fox.glb")), "-o", s(&pack), "--topology", "prisms", "-q"]);
    assert_ok(&out, "bake Fox");
    let scene = dir.join("fox.toml");
    std::fs::write(
        &scene,
        "time_step_s = 0.02\n[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\nscale = 0.01\n[effects.gravity]\n",
    )
    .unwrap();
    scene
}

#[test]
fn a_run_over_the_budget_exits_2_before_the_world_is_built() {
    let dir = tempfile::tempdir().unwrap();
    let scene = fox_scene(dir.path());
    let state = dir.path().join("state.json");
    let out = furbake(&["simulate", s(&scene), "--frames", "3", "--max-memory", "1K", "--state-out", s(&state)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.starts_with(&format!("furbake: error: {}: the run needs about ", scene.display())), "{err}");
    for needle in ["above --max-memory 1 KiB", "pack entry `fox`", "simulated masses"] {
        assert!(err.contains(needle), "no {needle:?} in {err}");
    }
    assert!(!state.exists(), "--state-out was written");
    assert!(out.stdout.is_empty(), "{}", stdout(&out));

    // The default budget runs it.
    let out = furbake(&["simulate", s(&scene), "--frames", "3", "--json", "--state-out", s(&state), "-q"]);
    assert_ok(&out, "simulate with the default budget");
    assert!(state.exists());
}
