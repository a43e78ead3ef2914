//! `furbake simulate SCENE.toml`: a runtime scene runs headless and prints its per-stage timings;
//! only the stages its effects call for appear; `--json` / `-o` give the same as JSON; the
//! example fox scene runs on a real bake; a pack, the retired `--scene` form and a furbake-sim
//! scene file are usage errors that say how to write a runtime scene.

use std::path::{Path, PathBuf};

use super::common::*;

/// Bakes the thesis's grass patch with a prisms topology and 200 blades into `dir/patch.fbk`.
fn bake_patch(dir: &Path) -> PathBuf {
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let pack = dir.join("patch.fbk");
    let args = [
        "bake",
        s(&patch),
        "-o",
        s(&pack),
        "--preset",
        "grass",
        "--resolution",
        "16",
        "--blades",
        "50",
        "--set",
        "blades.keyframes.grid.poses=40",
        "--topology",
        "prisms",
        "-q",
    ];
    assert_ok(&furbake(&args), "bake patch");
    pack
}

fn write_scene(dir: &Path, name: &str, effects: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, format!("time_step_s = 0.05\n[[packs]]\nname = \"patch\"\npath = \"patch.fbk\"\n{effects}"))
        .unwrap();
    path
}

fn json_of(out: &std::process::Output) -> serde_json::Value {
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

fn stage_names(report: &serde_json::Value) -> Vec<String> {
    report["stages"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap().to_owned()).collect()
}

#[test]
fn simulate_scene_prints_only_the_stages_its_effects_need() {
    let dir = tempfile::tempdir().unwrap();
    bake_patch(dir.path());
    let windy = write_scene(
        dir.path(),
        "windy.toml",
        "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.0]\ngust_amplitude = 0.3\n",
    );
    let out = furbake(&["simulate", s(&windy), "--frames", "12"]);
    assert_ok(&out, "simulate windy");
    let table = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut rows = 0;
    for name in ["fur_gravity", "fur_wind", "fur_solver", "fur_scale_vectors", "grass_forces"] {
        let line = table.lines().find(|l| l.starts_with(name)).unwrap_or_else(|| panic!("no {name} row in\n{table}"));
        let cols: Vec<&str> = line.split_whitespace().collect();
        assert_eq!(cols.len(), 5, "{line}");
        assert_eq!((cols[1], cols[2]), ("patch", "12"), "{line}");
        assert!(cols[3].parse::<f64>().unwrap() >= 0.0 && cols[4].parse::<f64>().unwrap() >= 0.0, "{line}");
        rows += 1;
    }
    assert_eq!(rows, 5);
    assert!(table.lines().next().unwrap().contains("mean µs"), "{table}");
    assert!(stderr(&out).contains("12 steps"), "{}", stderr(&out));

    // Gravity alone: no wind and no grass stage.
    let still = write_scene(dir.path(), "still.toml", "[effects.gravity]\n");
    let json_path = dir.path().join("still.json");
    let out = furbake(&["simulate", s(&still), "--frames", "7", "--json", "-o", s(&json_path), "-q"]);
    assert_ok(&out, "simulate still");
    let report = json_of(&out);
    let from_file: serde_json::Value = serde_json::from_slice(&std::fs::read(&json_path).unwrap()).unwrap();
    assert_eq!(stage_names(&from_file), stage_names(&report), "-o writes the same report");
    assert_eq!(stage_names(&report), ["fur_gravity", "fur_solver", "fur_scale_vectors"]);
    assert_eq!(report["frames"], 7);
    for stage in report["stages"].as_array().unwrap() {
        assert_eq!(stage["runs"], 7, "{stage}");
        assert!(stage["total_ms"].as_f64().unwrap() > 0.0 && stage["mean_us"].as_f64().unwrap() > 0.0, "{stage}");
    }
    let pack = &report["packs"][0];
    assert_eq!((pack["topology"].as_str(), pack["solver"].as_str()), (Some("prisms"), Some("implicit")));
    assert!(pack["grass_corners"].is_null());
    // `simulate` validates the pack as `verify` does before the world is built (docs/design.md
    // "Runtime: packs"), so it reads every section, once; the world shares what that decoded and
    // reads nothing more. (A `World` on its own reads only what its stages need:
    // crates/runtime/tests/world.rs.)
    let read: Vec<&str> = pack["sections_read"].as_array().unwrap().iter().map(|k| k.as_str().unwrap()).collect();
    let inspect: serde_json::Value =
        serde_json::from_slice(&furbake(&["inspect", "--json", s(&dir.path().join("patch.fbk"))]).stdout).unwrap();
    let mut kinds: Vec<&str> = Vec::new();
    for section in inspect["sections"].as_array().unwrap() {
        let kind = section["kind"].as_str().unwrap();
        if !kinds.contains(&kind) {
            kinds.push(kind);
        }
    }
    assert_eq!(read, kinds, "every section is read by the validation");
    assert!(stderr(&out).is_empty(), "-q prints nothing: {}", stderr(&out));

    // Without --frames: 2 s of scene time at 0.05 s per step.
    let out = furbake(&["simulate", s(&still), "--json", "-q"]);
    assert_ok(&out, "simulate default frames");
    assert_eq!(json_of(&out)["frames"], 40);
}

#[test]
fn simulate_runs_the_example_fox_scene() {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("fox.fbk");
    let fox = real_fixture("Fox.glb");
    let bake = ["bake", s(&fox), "-o", s(&pack), "--resolution", "16", "--topology", "prisms", "-q"];
    assert_ok(&furbake(&bake), "bake fox");
    let scene = dir.path().join("runtime_fox_in_wind.toml");
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/runtime_fox_in_wind.toml");
    std::fs::copy(example, &scene).unwrap();
    let out = furbake(&["simulate", s(&scene), "--frames", "30", "--json", "-q"]);
    assert_ok(&out, "simulate fox");
    let report = json_of(&out);
    assert_eq!(
        stage_names(&report),
        ["fur_object_motion", "fur_gravity", "fur_wind", "fur_solver", "fur_scale_vectors"],
        "the fox walks, falls and feels the wind; it has no blades, so no grass stage"
    );
    assert_eq!(report["packs"][0]["shell_vertices"], 290, "Fox.glb welds to 290 vertices");
}

#[test]
fn simulate_scene_errors_name_their_cause() {
    let dir = tempfile::tempdir().unwrap();
    let pack = bake_patch(dir.path());
    let mut checked = 0;
    // A pack given as the scene is a usage error that says what to do.
    let out = furbake(&["simulate", s(&pack)]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("runtime scene"), "{}", stderr(&out));
    checked += 1;
    // A scene whose pack is missing, or whose effects need a topology the pack lacks: bad input.
    let missing = dir.path().join("missing.toml");
    std::fs::write(&missing, "[[packs]]\nname = \"x\"\npath = \"nope.fbk\"\n").unwrap();
    let sep = write_scene(dir.path(), "parting.toml", "[effects.gravity]\n[effects.parting]\n");
    for (scene, needle) in [(&missing, "nope.fbk"), (&sep, "--topology separable-prisms")] {
        let out = furbake(&["simulate", s(scene), "--frames", "2"]);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        assert!(err.contains(needle), "{err}");
        checked += 1;
    }
    // The retired `simulate PACK --scene SIM.toml` form, and a furbake-sim scene file or a retired
    // key given as the scene: exit 2 with one line that says how to write it now.
    let old_scene = dir.path().join("old_sim.toml");
    std::fs::write(
        &old_scene,
        "topology = \"prisms\"\ndt_s = 0.016666\nduration_s = 1.0\n[forces]\nrestoring_weight_n = 0.01\n",
    )
    .unwrap();
    let renamed = write_scene(dir.path(), "renamed.toml", "[effects.wind]\nvelocity_m_s = [1.0, 0.0, 0.0]\n");
    // A day of scene time at a microsecond step: 8.6e10 steps would run for days.
    let endless = dir.path().join("endless.toml");
    std::fs::write(&endless, "time_step_s = 1e-6\nduration_s = 86400.0\n[[packs]]\nname = \"patch\"\npath = \"patch.fbk\"\n[effects.gravity]\n").unwrap();
    let still = write_scene(dir.path(), "still.toml", "[effects.gravity]\n");
    for (args, needle) in [
        (vec!["simulate", s(&pack), "--scene", s(&old_scene)], "runtime scene"),
        (vec!["simulate", s(&still), "--topology", "prisms"], "retired"),
        (vec!["simulate", s(&old_scene)], "runtime scene"),
        (vec!["preview", s(&old_scene), "-o", "never.png"], "runtime scene"),
        (vec!["simulate", s(&renamed)], "velocity_m_per_s"),
        (vec!["simulate", s(&endless)], "duration_s / time_step_s"),
    ] {
        let out = furbake(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        checked += 1;
    }
    assert_eq!(checked, 9);
}

#[test]
fn every_fixture_scene_runs_in_the_one_runtime() {
    // Every scene in fixtures/scenes/ is a runtime scene: with its packs baked beside it, it
    // simulates.
    let dir = tempfile::tempdir().unwrap();
    let generated = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let fox = real_fixture("Fox.glb");
    let grass = [
        "--preset",
        "grass",
        "--blades",
        "50",
        "--set",
        "blades.keyframes.grid.poses=40",
        "--topology",
        "prisms",
        "--topology",
        "separable-prisms",
    ];
    for (input, output, extra) in [
        (&fox, "fox.fbk", &["--topology", "prisms"][..]),
        (&generated, "patch.fbk", &["--topology", "prisms"][..]),
        (&generated, "grass-patch.fbk", &grass[..]),
    ] {
        let out_path = dir.path().join(output);
        let mut args = vec!["bake", s(input), "-o", s(&out_path), "--resolution", "16", "-q"];
        args.extend_from_slice(extra);
        assert_ok(&furbake(&args), &format!("{args:?}"));
    }
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes");
    let mut ran = Vec::new();
    for entry in std::fs::read_dir(&scenes).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let copy = dir.path().join(path.file_name().unwrap());
        std::fs::copy(&path, &copy).unwrap();
        let out = furbake(&["simulate", s(&copy), "--frames", "5", "--json", "-q"]);
        assert_ok(&out, &format!("simulate {}", path.display()));
        let report = json_of(&out);
        assert_eq!(report["frames"], 5);
        assert!(!stage_names(&report).is_empty(), "{} declares effects, so stages run", path.display());
        ran.push(path.file_name().unwrap().to_string_lossy().into_owned());
    }
    ran.sort();
    assert_eq!(
        ran,
        [
            "demo_fox_and_grass.toml",
            "fox_walk_stop.toml",
            "fur_wind_gust.toml",
            "runtime_everything.toml",
            "runtime_fox_in_wind.toml"
        ]
    );
}

/// The report streams: every recorded step is written as it is taken (nothing is kept, so a long
/// run's memory does not grow with it), `-o` and `--json` get the same bytes, and a run that fails
/// mid-way leaves no `-o` file.
#[test]
fn simulate_streams_its_report() {
    let dir = tempfile::tempdir().unwrap();
    bake_patch(dir.path());
    let scene = write_scene(dir.path(), "gravity.toml", "[effects.gravity]\n");
    let file = dir.path().join("report.json");
    let out = furbake(&["simulate", s(&scene), "--frames", "3000", "--record-every", "1", "--json", "-o", s(&file)]);
    assert_ok(&out, "a streamed report");
    assert_eq!(std::fs::read(&file).unwrap(), out.stdout, "-o and --json get the same document");
    let report = json_of(&out);
    for key in ["scene", "frames", "time_step_s", "record_every", "steps", "scene_time_s", "wall_s", "packs", "stages"]
    {
        assert!(report.get(key).is_some(), "no {key:?} in the report");
    }
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3000);
    assert_eq!((steps[0]["step"].as_u64(), steps[2999]["step"].as_u64()), (Some(0), Some(2999)));
    assert!(steps.iter().all(|r| r["energy_j"].as_f64().unwrap() <= r["energy_budget_j"].as_f64().unwrap() * 1.7));
    // A run that fails (a gravity no step can take) writes no report file.
    let failing =
        write_scene(dir.path(), "crushing.toml", "[effects.gravity]\nacceleration_m_per_s2 = [0.0, -1e30, 0.0]\n");
    let lost = dir.path().join("lost.json");
    let out = furbake(&["simulate", s(&failing), "--frames", "50", "-o", s(&lost)]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(!lost.exists(), "a failed run left its report");
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(!names.iter().any(|n| n.to_string_lossy().ends_with(".tmp")), "{names:?}");
}

#[test]
fn simulate_refuses_a_scene_whose_physics_runs_on_the_gpu() {
    // `simulate` has no GPU: a scene with `[solver] device = "gpu"` is a usage error (exit 2)
    // that says how to run it, and writes nothing.
    let dir = tempfile::tempdir().unwrap();
    bake_patch(dir.path());
    let scene = write_scene(dir.path(), "gpu.toml", "[solver]\nkind = \"xpbd\"\ndevice = \"gpu\"\n[effects.gravity]\n");
    let report = dir.path().join("report.json");
    let out = furbake(&["simulate", s(&scene), "--frames", "3", "-o", s(&report)]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    let e = stderr(&out);
    assert!(e.contains("\"patch\"") && e.contains("device = \"cpu\"") && e.contains("furbake preview"), "{e}");
    assert!(!report.exists());
}
