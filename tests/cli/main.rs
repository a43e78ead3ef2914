//! End-to-end tests of the `furbake` binary: bake every real fixture, verify, inspect, extract;
//! bad inputs give exit 1 and a one-line message and leave no file behind; usage errors exit 2;
//! output is byte-identical for any thread count.

use std::path::Path;

mod animation;
mod batch;
mod bazel;
mod closed_stdout;
mod common;
mod confinement;
mod depfile;
mod export;
mod export_fuzz;
mod file_modes;
mod fuzz_gltf;
mod fuzz_pipelines;
mod golden;
mod hermetic;
mod hostile;
mod memory_budget;
mod pipeline;
mod plan_first;
mod preview_scene;
mod schemas;
mod shaders;
mod simulate_scene;
mod verify_first;
mod view;
use common::*;

#[test]
fn every_real_fixture_bakes_verifies_inspects_and_extracts() {
    let dir = tempfile::tempdir().unwrap();
    let fixtures = real_fixtures();
    assert!(fixtures.len() >= 6, "expected the six shared real fixtures, found {fixtures:?}");
    let mut checked = 0;
    for mesh in &fixtures {
        let stem = mesh.file_stem().unwrap().to_string_lossy().into_owned();
        let pack = dir.path().join(format!("{stem}.fbk"));
        let out = furbake(&["bake", s(mesh), "-o", s(&pack), "--resolution", "64", "-q"]);
        assert_ok(&out, &format!("bake {stem}"));
        assert_ok(&furbake(&["verify", s(&pack)]), &format!("verify {stem}"));
        let json = inspect_json(&pack);
        let sections = json["sections"].as_array().unwrap();
        let kinds: Vec<&str> = sections.iter().map(|s| s["kind"].as_str().unwrap()).collect();
        for k in ["bake_manifest", "skin_mesh", "shell_atlas", "fin_atlas", "triangle_uv_map", "fin_edges"] {
            assert!(kinds.contains(&k), "{stem}: no {k} in {kinds:?}");
        }
        for s in sections {
            assert!(s["size"].as_u64().unwrap() > 0, "{stem}: empty section {s}");
        }
        let stats = &json["statistics"];
        assert!(stats["triangles"].as_u64().unwrap() > 0);
        assert!(stats["texels_per_m"].as_f64().unwrap() > 0.0);
        assert_eq!(stats["hair_coverage_per_layer"].as_array().unwrap().len(), 16);
        let ex = dir.path().join(format!("{stem}-png"));
        assert_ok(&furbake(&["extract", s(&pack), "-o", s(&ex)]), &format!("extract {stem}"));
        let grid = image::open(ex.join("shells_grid.png")).unwrap().to_luma8();
        let lit = grid.pixels().filter(|p| p.0[0] > 128).count();
        assert!(lit > 100, "{stem}: the shell grid shows no hair ({lit} bright pixels)");
        let fins = image::open(ex.join("fins.png")).unwrap().to_luma8();
        assert!(fins.pixels().any(|p| p.0[0] > 128), "{stem}: the fin texture is empty");
        assert!(ex.join("metadata.json").exists());
        checked += 1;
    }
    assert_eq!(checked, fixtures.len());
}

#[test]
fn bake_is_byte_identical_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = real_fixture("Fox.glb");
    let mut packs = Vec::new();
    for threads in ["1", "2", "4"] {
        let pack = dir.path().join(format!("fox-{threads}.fbk"));
        assert_ok(&furbake(&["--threads", threads, "bake", s(&mesh), "-o", s(&pack), "-q"]), "bake");
        packs.push(std::fs::read(&pack).unwrap());
    }
    assert!(packs.windows(2).all(|w| w[0] == w[1]), "packs differ between thread counts");
    // A different seed gives different bytes (the seed is really used).
    let other = dir.path().join("fox-seed2.fbk");
    assert_ok(&furbake(&["bake", s(&mesh), "-o", s(&other), "--seed", "2", "-q"]), "bake seed 2");
    assert_ne!(std::fs::read(&other).unwrap(), packs[0]);
}

#[test]
fn grass_preset_and_config_overrides_reach_the_pack() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("bake.toml");
    std::fs::write(
        &cfg,
        "seed = 9\n[volume]\nlayers = 24\n[volume.coat]\ndensity = 0.2\n[shells]\nfur_length_m = 0.05\n",
    )
    .unwrap();
    let pack = dir.path().join("box.fbk");
    let mesh = real_fixture("BoxVertexColors.glb");
    let out = furbake(&[
        "bake",
        s(&mesh),
        "-o",
        s(&pack),
        "--preset",
        "grass",
        "--config",
        s(&cfg),
        "--fin-slices",
        "7",
        "-q",
    ]);
    assert_ok(&out, "bake with config");
    let json = inspect_json(&pack);
    let shells = section(&json, "shell_atlas");
    assert_eq!(shells["layers"], 24);
    assert_eq!(shells["resolution"], 64, "grass preset resolution kept");
    assert_eq!(shells["params"]["coat"]["density"], 0.2);
    assert!((shells["fur_length_m"].as_f64().unwrap() - 0.05).abs() < 1e-6);
    assert_eq!(section(&json, "fin_atlas")["slices"], 7);
    let manifest = section(&json, "bake_manifest");
    assert_eq!(manifest["seed"], 9);
    assert_eq!(manifest["preset"], "grass");
    assert_eq!(manifest["input_sha256"].as_str().unwrap().len(), 64);
}

#[test]
fn corrupted_and_truncated_packs_exit_1_with_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("box.fbk");
    assert_ok(&furbake(&["bake", s(&real_fixture("Box.glb")), "-o", s(&pack), "--resolution", "16", "-q"]), "bake");
    let bytes = std::fs::read(&pack).unwrap();
    let mut cases = 0;
    for (name, damaged) in [
        ("truncated", bytes[..bytes.len() / 2].to_vec()),
        ("empty", Vec::new()),
        ("flipped", {
            let mut b = bytes.clone();
            let at = b.len() - 40;
            b[at] ^= 0x20;
            b
        }),
        ("not-a-pack", b"hello world, this is not a furbake container at all....................".to_vec()),
    ] {
        let bad = dir.path().join(format!("{name}.fbk"));
        std::fs::write(&bad, &damaged).unwrap();
        for cmd in ["verify", "inspect", "extract"] {
            let mut args = vec![cmd, s(&bad)];
            let ex = dir.path().join("ex");
            if cmd == "extract" {
                args.extend(["-o", s(&ex)]);
            }
            let out = furbake(&args);
            assert_eq!(out.status.code(), Some(1), "{cmd} {name}: {}", stderr(&out));
            let err = stderr(&out);
            assert_eq!(err.trim_end().lines().count(), 1, "{cmd} {name}: not one line: {err}");
            assert!(err.contains(&format!("{name}.fbk")), "{cmd} {name}: message does not name the file: {err}");
            cases += 1;
        }
    }
    assert_eq!(cases, 12);
}

#[test]
fn broken_gltf_exits_1_and_leaves_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("garbage.glb", b"glTF\x02\x00\x00\x00garbage".to_vec()),
        ("truncated.glb", std::fs::read(real_fixture("Fox.glb")).unwrap()[..5000].to_vec()),
        ("empty.gltf", b"{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"nodes\":[]}],\"scene\":0}".to_vec()),
        (
            "draco.gltf",
            b"{\"asset\":{\"version\":\"2.0\"},\"extensionsUsed\":[\"KHR_draco_mesh_compression\"],\"extensionsRequired\":[\"KHR_draco_mesh_compression\"]}".to_vec(),
        ),
    ];
    for (name, bytes) in &cases {
        let input = dir.path().join(name);
        std::fs::write(&input, bytes).unwrap();
        let pack = dir.path().join(format!("{name}.fbk"));
        let out = furbake(&["bake", s(&input), "-o", s(&pack)]);
        assert_eq!(out.status.code(), Some(1), "{name}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.trim_end().lines().count(), 1, "{name}: {err}");
        assert!(err.contains(name), "{name}: message does not name the file: {err}");
        assert!(!pack.exists(), "{name}: a failed bake left {pack:?} behind");
    }
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
    let err = stderr(&furbake(&["bake", s(&dir.path().join("draco.gltf")), "-o", s(&dir.path().join("x.fbk"))]));
    assert!(err.contains("KHR_draco_mesh_compression"), "{err}");
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = real_fixture("Box.glb");
    let out_path = dir.path().join("x.fbk");
    for args in [
        vec!["bake"],
        vec!["frobnicate"],
        vec!["bake", s(&mesh), "-o", s(&out_path), "--preset", "fluffy"],
        vec!["bake", s(&mesh), "-o", s(&out_path), "--set", "volume.nonsense=1"],
        vec!["bake", s(&mesh), "-o", s(&out_path), "--layers", "0"],
        vec!["bake", s(&mesh), "-o", s(&out_path), "--fur-length", "-1"],
    ] {
        let out = furbake(&args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!out_path.exists());
    }
    let help = furbake(&["--help"]);
    assert_eq!(help.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&help.stdout).contains("Exit codes"));
}

fn section<'a>(json: &'a serde_json::Value, kind: &str) -> &'a serde_json::Value {
    json["sections"].as_array().unwrap().iter().find(|s| s["kind"] == kind).unwrap_or_else(|| panic!("no {kind}"))
}

fn inspect_json(pack: &Path) -> serde_json::Value {
    let out = furbake(&["inspect", "--json", s(pack)]);
    assert_ok(&out, "inspect --json");
    serde_json::from_slice(&out.stdout).expect("inspect --json prints JSON")
}

#[test]
fn bare_region_gets_fur_boundary_fins_and_the_table_inspects() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = furbake_import::testmesh::plane_with_bare_region(8, 2.0);
    let input = dir.path().join("plane.gltf");
    std::fs::write(&input, &mesh.gltf).unwrap();
    let pack = dir.path().join("plane.fbk");
    let out = furbake(&[
        "bake",
        s(&input),
        "-o",
        s(&pack),
        "--resolution",
        "16",
        "-q",
        "--set",
        r#"import.fur_mask={"source":"materials","names":["fur"]}"#,
    ]);
    assert_ok(&out, "bake plane");
    let json = inspect_json(&pack);
    let mesh_json = section(&json, "skin_mesh");
    assert_eq!(mesh_json["furry_triangles"].as_u64().unwrap() as usize, mesh.furry_triangles);
    assert!(mesh.furry_triangles < mesh.triangles, "the fixture has a bare region");
    let fins = section(&json, "fin_edges");
    assert!(fins["fur_boundary_edges"].as_u64().unwrap() > 0, "{fins}");
    assert!(fins["border_edges"].as_u64().unwrap() > 0, "{fins}");
    let table = furbake(&["inspect", s(&pack)]);
    assert_ok(&table, "inspect");
    let text = String::from_utf8_lossy(&table.stdout);
    for kind in ["skin_mesh", "shell_atlas", "fin_atlas", "triangle_uv_map", "fin_edges", "hair_coverage_per_layer"] {
        assert!(text.contains(kind), "the table lacks {kind}");
    }
}

#[test]
fn invalid_import_settings_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.fbk");
    let mesh = real_fixture("Box.glb");
    let out = furbake(&["bake", s(&mesh), "-o", s(&out_path), "--set", r#"import.weld_tolerance={"relative":-1}"#]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!out_path.exists());
}

#[test]
fn keyframes_reproduce_the_thesis_bit_counts() {
    // Grass thesis §3.3: 8 segments, 32 vertices, 1000 poses ⇒ 3,072,000 bits raw,
    // 720,000 bits compressed without symmetry, 180,000 with (xz).
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for (symmetry, payload) in [("none", 720_000u64), ("x", 360_000), ("xz", 180_000)] {
        let file = dir.path().join(format!("kf-{symmetry}.fbk"));
        assert_ok(&furbake(&["keyframes", "-o", s(&file), "--symmetry", symmetry, "-q"]), "keyframes");
        assert_ok(&furbake(&["verify", s(&file)]), "verify keyframes");
        let json = inspect_json(&file);
        let table = &json["keyframe_tables"][0];
        assert_eq!(table["raw_bits"], 3_072_000u64, "{symmetry}");
        assert_eq!(table["payload_bits"], payload, "{symmetry}");
        assert_eq!(table["vertices"], 32);
        assert!(table["error_max_blade_lengths"].as_f64().unwrap() < 1e-4, "snorm16 within 1e-4 blade lengths");
        checked += 1;
    }
    assert_eq!(checked, 3);
    let out = furbake(&["keyframes", "-o", s(&dir.path().join("bad.fbk")), "--segments", "0"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

#[test]
fn bake_with_blades_adds_a_blade_field_and_its_keyframes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = furbake_import::testmesh::grass_patch(4.0);
    let input = dir.path().join("patch.gltf");
    std::fs::write(&input, &mesh.gltf).unwrap();
    let pack = dir.path().join("patch.fbk");
    let out = furbake(&[
        "bake",
        s(&input),
        "-o",
        s(&pack),
        "--preset",
        "grass",
        "--blades",
        "50",
        "--resolution",
        "16",
        "-q",
    ]);
    assert_ok(&out, "bake with blades");
    assert_ok(&furbake(&["verify", s(&pack)]), "verify");
    let json = inspect_json(&pack);
    let field = &json["blade_fields"][0];
    let blades = field["blades"].as_u64().unwrap();
    // 16 m² at 50 per m²: a Poisson-like count near 800.
    assert!((600..=1000).contains(&blades), "{blades} blades");
    assert!(field["clusters"].as_u64().unwrap() >= 1);
    assert_eq!(json["keyframe_tables"].as_array().unwrap().len(), 1);
}

#[test]
fn preview_renders_a_recognisable_fur_image() {
    // Runs on lavapipe (software Vulkan) where there is no GPU; `.ci/run` installs it.
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("fox.fbk");
    assert_ok(&furbake(&["bake", s(&real_fixture("Fox.glb")), "-o", s(&pack), "--resolution", "64", "-q"]), "bake");
    let png = dir.path().join("fox.png");
    let out = furbake(&["preview", s(&pack), "-o", s(&png), "--size", "160x120"]);
    assert_ok(&out, "preview");
    assert!(!stderr(&out).contains("XDG_RUNTIME_DIR"), "driver noise leaked: {}", stderr(&out));
    let img = image::open(&png).unwrap().to_rgba8();
    assert_eq!(img.dimensions(), (160, 120));
    // The background is a flat colour; the fox covers a good part of the frame.
    let bg = *img.get_pixel(0, 0);
    let covered = img.pixels().filter(|p| p.0.iter().zip(bg.0).any(|(a, b)| a.abs_diff(b) > 24)).count();
    assert!(covered > 160 * 120 / 10, "only {covered} pixels differ from the background");
    let bad = furbake(&["preview", s(&pack), "-o", s(&png), "--size", "0x10"]);
    assert_eq!(bad.status.code(), Some(2));
    let missing = furbake(&["preview", s(&dir.path().join("nope.fbk")), "-o", s(&png)]);
    assert_eq!(missing.status.code(), Some(1));
    assert!(stderr(&missing).contains("nope.fbk"));
}

const ALL_TOPOLOGIES: [&str; 8] = [
    "chain",
    "reduced-chain",
    "sticks",
    "spring-sticks",
    "prisms",
    "separable-sticks",
    "separable-spring-sticks",
    "separable-prisms",
];

/// Bakes `mesh` with every topology and returns `kind → (masses, springs, sticks)`.
fn topology_counts(mesh: &Path, dir: &Path) -> std::collections::BTreeMap<String, (u64, u64, u64)> {
    let pack = dir.join("topo.fbk");
    let mut args = vec!["bake", s(mesh), "-o", s(&pack), "--resolution", "16", "-q"];
    for k in ALL_TOPOLOGIES {
        args.extend(["--topology", k]);
    }
    assert_ok(&furbake(&args), "bake with every topology");
    assert_ok(&furbake(&["verify", s(&pack)]), "verify");
    let json = inspect_json(&pack);
    json["topologies"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| {
            let n = |k: &str| t[k].as_u64().unwrap_or_else(|| panic!("{k} missing in {t}"));
            (t["kind"].as_str().unwrap().to_owned(), (n("masses"), n("springs"), n("sticks")))
        })
        .collect()
}

#[test]
fn topology_counts_follow_the_spec_on_the_grass_patch_and_the_fox() {
    let dir = tempfile::tempdir().unwrap();
    // docs/design.md "Topology counts": the thesis's grass patch V=13, F=16 (E=28) ⇒ spring–sticks 26/13, prisms 26/V+E,
    // separable spring–sticks 6F/3F = 96/48, separable prisms 96/96.
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let c = topology_counts(&patch, dir.path());
    assert_eq!(c.len(), 8);
    assert_eq!(c["spring-sticks"], (26, 13, 0));
    assert_eq!(c["sticks"], (26, 0, 13));
    assert_eq!(c["prisms"], (26, 13 + 28, 0));
    assert_eq!(c["separable-spring-sticks"], (96, 48, 0));
    assert_eq!(c["separable-sticks"], (96, 0, 48));
    assert_eq!(c["separable-prisms"], (96, 96, 0));
    assert_eq!(c["chain"].0, 13 * 16, "a mass on every one of the 16 layers");
    // Fox.glb welds to V=290, E=864, F=576.
    let c = topology_counts(&real_fixture("Fox.glb"), dir.path());
    assert_eq!(c["spring-sticks"], (580, 290, 0));
    assert_eq!(c["prisms"], (580, 290 + 864, 0));
    assert_eq!(c["separable-spring-sticks"], (3456, 1728, 0));
    assert_eq!(c["separable-prisms"], (3456, 3456, 0));
}

#[test]
fn simulate_runs_the_wind_gust_scene_with_its_events_statistics_and_state() {
    // The former furbake-sim scenario (jolt, teleport, forces off), now a runtime scene.
    let dir = tempfile::tempdir().unwrap();
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/fur_wind_gust.toml");
    let scene = dir.path().join("fur_wind_gust.toml");
    std::fs::copy(example, &scene).unwrap();
    let pack = dir.path().join("patch.fbk");
    assert_ok(
        &furbake(&["bake", s(&patch), "-o", s(&pack), "--resolution", "16", "--topology", "prisms", "-q"]),
        "bake",
    );
    let (json_path, state_path) = (dir.path().join("sim.json"), dir.path().join("state.json"));
    let out = furbake(&["simulate", s(&scene), "-o", s(&json_path), "--state-out", s(&state_path)]);
    assert_ok(&out, "simulate");
    assert!(stdout(&out).contains("fur_solver"), "the stage table: {}", stdout(&out));
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(&json_path).unwrap()).unwrap();
    let frames = report["frames"].as_u64().unwrap();
    assert_eq!(frames, (3.0f64 / 0.016666 - 1e-9).ceil() as u64, "the scene's duration_s");
    assert_eq!(report["packs"][0]["topology"], "prisms");
    assert_eq!(report["packs"][0]["solver"], "implicit");
    let steps = report["steps"].as_array().unwrap();
    assert_eq!(steps.len() as u64, frames, "one record per step of the one simulated pack");
    let at = |t: f64| steps.iter().find(|r| r["time_s"].as_f64().unwrap() >= t).unwrap();
    let field = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    // The teleport at 0.5 s reaches the simulator (its energy is booked in the budget); after the
    // forces stop at 1 s the fur comes back to rest.
    // Times are step ends: the event is applied before the first step starting at or after 0.5 s.
    let (before, after) = (field(at(0.48), "energy_budget_j"), field(at(0.52), "energy_budget_j"));
    assert!(field(at(0.52), "max_displacement_m") > 0.05, "the fur was left behind: {}", at(0.52));
    assert!(after > before * 1.5, "teleport energy booked: budget {before} → {after}");
    let (loaded, last) = (at(0.98), steps.last().unwrap());
    assert!(field(loaded, "max_displacement_m") > 1e-4, "gravity and wind bend the fur: {loaded}");
    // Without forces the fur calms down: its motion dies out, and only the weak restoring force
    // of eq. 3.37 turns it back, so it does not stray further.
    assert!(field(last, "kinetic_j") < field(loaded, "kinetic_j") * 0.1, "{loaded} → {last}");
    assert!(field(last, "max_displacement_m") <= field(loaded, "max_displacement_m"), "{loaded} → {last}");
    for r in steps {
        assert!(
            field(r, "energy_j").is_finite() && field(r, "energy_j") <= field(r, "energy_budget_j") * 1.001 + 1e-9,
            "{r}"
        );
    }
    let state: serde_json::Value = serde_json::from_slice(&std::fs::read(&state_path).unwrap()).unwrap();
    let p = &state["packs"][0];
    assert_eq!(p["name"], "patch");
    assert_eq!(p["skin_positions_m"].as_array().unwrap().len(), 13, "the patch welds to 13 vertices");
    assert_eq!(p["mass_positions_m"].as_array().unwrap().len(), 26);
    assert_eq!(p["mass_velocities_m_per_s"].as_array().unwrap().len(), 26);
    assert_eq!(p["scale_vectors"].as_array().unwrap().len(), 13);
    // The pack was jolted 8 cm and teleported 10 cm along +x: its skin is there now.
    let xs: Vec<f64> = p["skin_positions_m"].as_array().unwrap().iter().map(|v| v[0].as_f64().unwrap()).collect();
    let mean_x = xs.iter().sum::<f64>() / xs.len() as f64;
    assert!((mean_x - 0.18).abs() < 1e-3, "mean skin x {mean_x}");
    // Same inputs, same bytes.
    let again = dir.path().join("state2.json");
    assert_ok(&furbake(&["simulate", s(&scene), "--state-out", s(&again), "-q"]), "simulate again");
    assert_eq!(std::fs::read(&state_path).unwrap(), std::fs::read(&again).unwrap());
}

/// Decodes every section of `bytes` with its typed decoder (what `verify` does).
fn decode_every_section(bytes: &[u8]) -> Result<usize, furbake_formats::FormatError> {
    use furbake_formats::SectionKind as K;
    use furbake_formats::sections::*;
    let pack = furbake_formats::Pack::from_bytes(bytes)?;
    for (i, e) in pack.sections().iter().enumerate() {
        match e.kind {
            K::BAKE_MANIFEST => drop(pack.decode::<manifest::BakeManifest>(i)?),
            K::SKIN_MESH => drop(pack.decode::<skin_mesh::SkinMesh>(i)?),
            K::SHELL_ATLAS => drop(pack.decode::<shell_atlas::ShellAtlas>(i)?),
            K::FIN_ATLAS => drop(pack.decode::<fin_atlas::FinAtlas>(i)?),
            K::TRIANGLE_UV_MAP => drop(pack.decode::<triangle_uv_map::TriangleUvMap>(i)?),
            K::FIN_EDGES => drop(pack.decode::<fin_edges::FinEdges>(i)?),
            K::SPRING_TOPOLOGY => drop(pack.decode::<spring_topology::SpringTopology>(i)?),
            K::KEYFRAME_TABLE => drop(pack.decode::<keyframe_table::KeyframeTable>(i)?),
            K::BLADE_FIELD => drop(pack.decode::<blade_field::BladeField>(i)?),
            _ => {}
        }
    }
    Ok(pack.sections().len())
}

#[test]
fn every_truncation_and_byte_corruption_of_a_real_pack_is_rejected() {
    // A real bake of the BoxVertexColors fixture with every section kind in it (blades,
    // keyframes, a topology), kept small so the sweep is quick.
    let dir = tempfile::tempdir().unwrap();
    let pack = dir.path().join("box.fbk");
    let mesh = real_fixture("BoxVertexColors.glb");
    let args = [
        "bake",
        s(&mesh),
        "-o",
        s(&pack),
        "--resolution",
        "8",
        "--layers",
        "4",
        "--blades",
        "20",
        "--set",
        "blades.keyframes.grid.poses=40",
        "--topology",
        "prisms",
        "-q",
    ];
    assert_ok(&furbake(&args), "bake");
    let bytes = std::fs::read(&pack).unwrap();
    assert_eq!(decode_every_section(&bytes).unwrap(), 9, "the clean pack holds all nine section kinds");
    let mut truncations = 0;
    for len in 0..bytes.len() {
        let r = std::panic::catch_unwind(|| decode_every_section(&bytes[..len]));
        assert!(r.expect("no panic on truncation").is_err(), "truncation to {len} accepted");
        truncations += 1;
    }
    let mut rejected = 0;
    let mut tried = 0;
    for at in (0..bytes.len()).step_by(3) {
        let mut b = bytes.clone();
        b[at] ^= 0x5a;
        let r = std::panic::catch_unwind(|| decode_every_section(&b)).expect("no panic on corruption");
        tried += 1;
        rejected += r.is_err() as usize;
    }
    assert_eq!(truncations, bytes.len());
    // Only the zero padding between sections and the reserved header bytes are outside every
    // checksum; everything else must be caught.
    assert!(rejected * 100 >= tried * 97, "{rejected} of {tried} corruptions rejected");
}

#[test]
fn preview_draws_the_grass_blades_of_a_pack() {
    let dir = tempfile::tempdir().unwrap();
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let green = |pack: &Path| {
        let png = dir.path().join("p.png");
        assert_ok(&furbake(&["preview", s(pack), "-o", s(&png), "--size", "160x120", "-q"]), "preview");
        let img = image::open(&png).unwrap().to_rgba8();
        img.pixels().filter(|p| p.0[1] as u32 > p.0[0] as u32 + 30 && p.0[1] as u32 > p.0[2] as u32 + 30).count()
    };
    let with = dir.path().join("with.fbk");
    let args = ["bake", s(&patch), "-o", s(&with), "--preset", "grass", "--resolution", "16", "--blades", "200", "-q"];
    assert_ok(&furbake(&args), "bake with blades");
    let without = dir.path().join("without.fbk");
    assert_ok(
        &furbake(&["bake", s(&patch), "-o", s(&without), "--preset", "grass", "--resolution", "16", "-q"]),
        "bake",
    );
    let (g_with, g_without) = (green(&with), green(&without));
    assert!(g_with > 200, "only {g_with} green pixels with 3,200 blades");
    assert_eq!(g_without, 0, "no blades, no green");
}
