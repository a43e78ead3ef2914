//! Plan first, then work: every bake setting — import, volume, shells, fins, UV, topology
//! parameters, blades and keyframes, and CLI flags — is validated before the input is read. A bad
//! value exits 2 with one line that starts with the key (as `inspect` shows it under the manifest's
//! `settings`), the value and the allowed range, and no output file appears. "Before the input is
//! read" is observable: the input here does not exist, or is garbage, and the setting's message
//! still wins.

use std::path::Path;

use super::common::*;

/// Runs `furbake bake MISSING -o OUT <extra>` and checks it is refused as a bad `key`.
fn assert_refused_before_reading(extra: &[&str], key: &str) {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("does-not-exist.glb");
    let out_path = dir.path().join("x.fbk");
    let mut args = vec!["bake", s(&missing), "-o", s(&out_path)];
    args.extend_from_slice(extra);
    assert_refused(&args, key, dir.path(), &out_path);
}

/// Exit 2, one line starting with `furbake: error: KEY`, nothing written into `dir`.
fn assert_refused(args: &[&str], key: &str, dir: &Path, out_path: &Path) {
    let out = furbake(args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
    let prefix = format!("furbake: error: {key}");
    assert!(err.starts_with(&prefix), "{args:?}: the message does not start with {key:?}: {err}");
    assert!(!out_path.exists(), "{args:?}: {out_path:?} was written");
    let written: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .filter(|n| n.to_string_lossy().ends_with(".tmp") || n.to_string_lossy().ends_with(".fbk"))
        .collect();
    assert!(written.is_empty(), "{args:?}: files left: {written:?}");
}

#[test]
fn a_bad_import_setting_exits_2_before_the_input_is_read() {
    assert_refused_before_reading(
        &["--set", r#"import.fur_mask={"source":"vertex_color","channel":"r","threshold":1.5}"#],
        "import.fur_mask.threshold = 1.5",
    );
    assert_refused_before_reading(
        &["--set", r#"import.weld_tolerance={"relative":-1}"#],
        "import.weld_tolerance.relative",
    );
}

#[test]
fn a_bad_volume_setting_exits_2_before_the_input_is_read() {
    let mut checked = 0;
    for (set, key) in [
        ("volume.coat.density=0", "volume.coat.density = 0"),
        ("volume.coat.density=NaN", "volume.coat.density"),
        ("volume.shadow_min=3e38", "volume.shadow_min"),
        // Alone in range, together 1024 × 8192² voxels: gigabytes.
        ("volume.resolution=8192", "volume.layers"),
    ] {
        let layers = if key == "volume.layers" { "1024" } else { "16" };
        assert_refused_before_reading(&["--set", set, "--layers", layers], key);
        checked += 1;
    }
    assert_refused_before_reading(&["--layers", "0"], "volume.layers = 0 is out of range (allowed: 1..=1024)");
    assert_eq!(checked, 4);
}

#[test]
fn a_bad_shell_setting_exits_2_before_the_input_is_read() {
    for length in ["3e38", "1e-45", "0"] {
        assert_refused_before_reading(&["--fur-length", length], &format!("shells.fur_length_m = {length}"));
    }
    assert_refused_before_reading(&["--set", "shells.fur_length_m=-1"], "shells.fur_length_m = -1");
    assert_refused_before_reading(&["--set", "shells.auto_fur_length_fraction=0"], "shells.auto_fur_length_fraction");
}

#[test]
fn a_bad_fin_setting_exits_2_before_the_input_is_read() {
    assert_refused_before_reading(&["--fin-slices", "0"], "volume.fin_slices = 0");
    assert_refused_before_reading(&["--set", "volume.fin_height=100000"], "volume.fin_height = 100000");
}

#[test]
fn a_bad_uv_setting_exits_2_before_the_input_is_read() {
    assert_refused_before_reading(&["--repeat", "1e-45"], "uv.repeat_m = 1e-45");
    assert_refused_before_reading(&["--set", "uv.repeat_m=3e38"], "uv.repeat_m");
    assert_refused_before_reading(&["--set", "uv.random_offset=7"], "uv.random_offset");
}

#[test]
fn a_bad_topology_parameter_exits_2_before_the_input_is_read() {
    // Cause: topology parameters were checked only when the topology was built, after the volume
    // was baked, and the check's container error ("<memory>: invalid container") exited 1.
    assert_refused_before_reading(
        &["--topology", "chain", "--set", "topology.stiffness_n_per_m=-1"],
        "topology.stiffness_n_per_m = -1 is out of range (allowed: [0, 1e9])",
    );
    assert_refused_before_reading(&["--set", "topology.hair_mass_kg=1e-45"], "topology.hair_mass_kg");
    assert_refused_before_reading(&["--set", "topology.stifness_n_per_m=5"], "topology.stifness_n_per_m: unknown key");
    // Every topology hangs one chain mass on each shell layer: one layer is too few.
    assert_refused_before_reading(&["--topology", "sticks", "--layers", "1"], "volume.layers = 1");
    assert_refused_before_reading(&["--set", "topologies=[\"braid\"]"], "topologies[0]");
    // Cause: `topology.chain_layers=1000000` was recorded in the manifest but ignored (the chain
    // follows the shell layers); a setting the bake overrides is refused, naming what decides.
    assert_refused_before_reading(
        &["--set", "topology.chain_layers=1000000"],
        "topology.chain_layers: is taken from volume.layers",
    );
    assert_refused_before_reading(
        &["--set", "topology.fur_length_m=0.5"],
        "topology.fur_length_m: is taken from shells.fur_length_m",
    );
    // A pack holds one topology of each kind (what `verify` checks), so a repeat is refused.
    assert_refused_before_reading(&["--topology", "prisms", "--topology", "prisms"], "topologies[1]");
}

#[test]
fn the_topology_symptom_of_the_issue_exits_2_with_a_real_input_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.fbk");
    let mesh = real_fixture("Box.glb");
    let args = [
        "bake",
        s(&mesh),
        "-o",
        s(&out_path),
        "--resolution",
        "16",
        "--topology",
        "chain",
        "--set",
        "topology.stiffness_n_per_m=-1",
    ];
    assert_refused(&args, "topology.stiffness_n_per_m", dir.path(), &out_path);
    let err = stderr(&furbake(&args));
    assert!(!err.contains("invalid container"), "{err}");
}

#[test]
fn a_bad_blade_or_keyframe_setting_exits_2_before_the_input_is_read() {
    let mut checked = 0;
    for (extra, key) in [
        (vec!["--blades", "0"], "blades.field.density_per_m2 = 0"),
        (vec!["--set", "blades.field.density_per_m2=-5"], "blades.field.density_per_m2 = -5"),
        (vec!["--blades", "1e30"], "blades.field.density_per_m2"),
        (vec!["--set", "blades.field.height_min_m=0"], "blades.field.height_min_m"),
        (vec!["--blades", "100", "--set", "blades.field.height_max_m=0.01"], "blades.field.height_max_m"),
        (vec!["--set", "blades.keyframes.grid.poses=0"], "blades.keyframes.grid.poses = 0"),
        (vec!["--set", "blades.keyframes.grid.max_force=1e30"], "blades.keyframes.grid.max_force"),
        (vec!["--set", "blades.keyframes.grid.magnitudes=7"], "blades.keyframes.grid.magnitudes"),
        (vec!["--set", "blades.keyframes.shape.segments=100000"], "blades.keyframes.shape.segments"),
        (vec!["--set", "blades.keyframes.shape.curl=0.2"], "blades.keyframes.shape.curl"),
        (vec!["--set", "blades.keyframes.material.weight=-1"], "blades.keyframes.material.weight"),
        (vec!["--set", "blades.keyframes.encoding=\"snorm12\""], "blades.keyframes.encoding"),
    ] {
        assert_refused_before_reading(&extra, key);
        checked += 1;
    }
    assert_eq!(checked, 12);
}

#[test]
fn a_setting_too_large_for_the_mesh_exits_2_before_any_stage() {
    // In range alone, but 1 µm clusters over the box's metre-wide furry surface are ~10^12 cells:
    // refused after the import (it needs the mesh's size), before the volume is grown.
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.fbk");
    let mesh = real_fixture("Box.glb");
    let args =
        ["bake", s(&mesh), "-o", s(&out_path), "--blades", "10", "--set", "blades.field.cluster_size_m=0.000001"];
    assert_refused(&args, "blades.field.cluster_size_m", dir.path(), &out_path);
}

#[test]
fn a_bad_flag_exits_2_before_the_input_is_read() {
    assert_refused_before_reading(&["--threads", "0"], "--threads = 0 is out of range (allowed: 1..=1024)");
    assert_refused_before_reading(&["--threads", "100000"], "--threads");
    assert_refused_before_reading(&["--set", "seed=-3"], "seed");
    // An output directory that does not exist is a bad flag, found before the bake.
    let dir = tempfile::tempdir().unwrap();
    let mesh = real_fixture("Box.glb");
    let out_path = dir.path().join("no-such-dir").join("x.fbk");
    assert_refused(&["bake", s(&mesh), "-o", s(&out_path)], "--output", dir.path(), &out_path);
}

#[test]
fn a_bad_setting_wins_over_a_broken_input() {
    // The garbage file would exit 1 if it were read: the setting is refused first.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("garbage.glb");
    std::fs::write(&input, b"glTF\x02\x00\x00\x00garbage").unwrap();
    let out_path = dir.path().join("x.fbk");
    let args = ["bake", s(&input), "-o", s(&out_path), "--set", "volume.coat.taper=2"];
    assert_refused(&args, "volume.coat.taper = 2 is out of range (allowed: [0, 1])", dir.path(), &out_path);
    // With good settings the same file is bad input (exit 1).
    let out = furbake(&["bake", s(&input), "-o", s(&out_path)]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
}

#[test]
fn a_bad_config_file_value_exits_2_naming_the_key_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("bake.toml");
    std::fs::write(&cfg, "[topology]\ndamping_n_s_per_m = -0.5\n").unwrap();
    let out_path = dir.path().join("x.fbk");
    let missing = dir.path().join("does-not-exist.glb");
    let args = ["bake", s(&missing), "-o", s(&out_path), "--config", s(&cfg)];
    assert_refused(&args, "topology.damping_n_s_per_m = -0.5", dir.path(), &out_path);
    std::fs::write(&cfg, "[volume]\nlayerz = 3\n").unwrap();
    let out = furbake(&args);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("layerz") && stderr(&out).contains("bake.toml"), "{}", stderr(&out));
    // A config that is not TOML is a bad input file (exit 1).
    std::fs::write(&cfg, "[volume\n").unwrap();
    assert_eq!(furbake(&args).status.code(), Some(1));
}
