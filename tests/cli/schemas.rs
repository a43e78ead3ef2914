//! The JSON Schemas in `docs/schemas/` describe what the commands really write: `inspect
//! --json` of fur, grass and animated packs, `bake --report` and `simulate --state-out` are
//! validated against them by an independent validator (Python's `jsonschema`, through
//! `tools/check_schema.py`), and documents that break a rule are refused (so the schemas are not
//! vacuous).

use std::path::{Path, PathBuf};
use std::process::Command;

use super::common::*;

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

/// Runs the validator on `docs` against `docs/schemas/<schema>.schema.json`: its violations.
fn violations(schema: &str, docs: &[&Path]) -> Vec<String> {
    let out = Command::new("python3")
        .arg(repo("tools/check_schema.py"))
        .arg(repo(&format!("docs/schemas/{schema}.schema.json")))
        .args(docs)
        .output()
        .expect("python3 runs (make deps installs it with python3-jsonschema)");
    match out.status.code() {
        Some(0) => Vec::new(),
        Some(1) => stdout(&out).lines().map(str::to_owned).collect(),
        _ => panic!("tools/check_schema.py failed: {}{}", stdout(&out), stderr(&out)),
    }
}

fn write_json(p: &Path, v: &serde_json::Value) -> PathBuf {
    std::fs::write(p, serde_json::to_vec(v).unwrap()).unwrap();
    p.to_path_buf()
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

#[test]
fn real_outputs_validate_against_the_documented_schemas() {
    let dir = tempfile::tempdir().unwrap();
    let (mut inspects, mut reports) = (Vec::new(), Vec::new());
    // Fur (animated Fox, with a topology), grass (blades, keyframes) and a static textured glTF.
    let patch = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/generated/grass_patch.gltf");
    let plane = real_fixture("TwoSidedPlane/TwoSidedPlane.gltf");
    let fox = real_fixture("Fox.glb");
    let bakes: [(&str, &Path, &[&str]); 3] = [
        ("fox", &fox, &["--topology", "prisms"]),
        ("grass-patch", &patch, &["--preset", "grass", "--blades", "50", "--topology", "prisms"]),
        ("plane", &plane, &[]),
    ];
    let mut validated = 0;
    for (name, mesh, extra) in bakes {
        let (pack, json) = (dir.path().join(format!("{name}.fbk")), dir.path().join(format!("{name}.json")));
        let args = ["bake", s(mesh), "-o", s(&pack), "--resolution", "16", "-q", "--report", s(&json)];
        assert_ok(&furbake(&[&args[..], extra].concat()), &format!("bake {name}"));
        reports.push(json);
        let out = furbake(&["inspect", "--json", s(&pack)]);
        assert_ok(&out, "inspect --json");
        let inspected = dir.path().join(format!("{name}-inspect.json"));
        std::fs::write(&inspected, &out.stdout).unwrap();
        inspects.push(inspected);
        validated += 2;
    }
    // The demo scene's final state (the Fox walking on the grass).
    let scene = dir.path().join("scene.toml");
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/scenes/demo_fox_and_grass.toml"), &scene)
        .unwrap();
    let st = dir.path().join("state.json");
    assert_ok(&furbake(&["simulate", s(&scene), "--frames", "3", "--state-out", s(&st), "-q"]), "simulate");
    validated += 1;
    assert_eq!(validated, 7);
    let as_paths = |v: &[PathBuf]| v.iter().map(|p| p.to_path_buf()).collect::<Vec<_>>();
    for (schema, docs) in
        [("bake-report", as_paths(&reports)), ("inspect", as_paths(&inspects)), ("state", vec![st.clone()])]
    {
        let docs: Vec<&Path> = docs.iter().map(PathBuf::as_path).collect();
        let v = violations(schema, &docs);
        assert!(v.is_empty(), "{schema}: {v:#?}");
    }
    let doc = read_json(&st);

    // Broken documents are refused: a missing field, a wrong type, an unknown stage.
    let mut broken = doc.clone();
    broken["packs"][0].as_object_mut().unwrap().remove("name");
    let v = violations("state", &[&write_json(&dir.path().join("b1.json"), &broken)]);
    assert!(v.len() == 1 && v[0].contains("name"), "a pack without a name: {v:?}");
    let mut broken = read_json(&dir.path().join("fox.json"));
    broken["stages"][0]["stage"] = "teleport".into();
    broken["pack_sha256"] = "not a hash".into();
    let v = violations("bake-report", &[&write_json(&dir.path().join("b2.json"), &broken)]);
    assert_eq!(v.len(), 2, "an unknown stage and a malformed hash: {v:?}");
    let mut broken = read_json(&dir.path().join("fox-inspect.json"));
    broken["sections"][0]["crc32"] = 5.into();
    let v = violations("inspect", &[&write_json(&dir.path().join("b3.json"), &broken)]);
    assert!(v.len() == 1 && v[0].contains("crc32"), "a numeric crc32: {v:?}");
}

#[test]
fn scene_files_have_a_schema_that_says_what_furbake_reads() {
    // The committed schemas are what `furbake schema KIND` derives from the types that read the
    // files.
    for kind in ["scene", "config", "batch"] {
        let out = furbake(&["schema", kind]);
        assert_ok(&out, "furbake schema");
        let committed = std::fs::read_to_string(repo(&format!("docs/schemas/{kind}.schema.json"))).unwrap();
        assert!(
            stdout(&out) == committed,
            "docs/schemas/{kind}.schema.json is stale: furbake schema {kind} > docs/schemas/{kind}.schema.json"
        );
    }

    // Every scene the repository ships validates.
    let scenes: Vec<PathBuf> = std::fs::read_dir(repo("fixtures/scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    assert!(scenes.len() >= 4);
    let v = violations("scene", &scenes.iter().map(PathBuf::as_path).collect::<Vec<_>>());
    assert!(v.is_empty(), "{v:#?}");

    // Broken scenes: the schema refuses each, and furbake (exit 1) names the key, what it
    // expects, and where.
    let dir = tempfile::tempdir().unwrap();
    let base = "time_step_s = 0.02\n[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\n[effects.gravity]\n";
    let cases: [(&str, &str, &[&str]); 11] = [
        ("time_step_s = 0.02", "time_step_s = \"0.02\"", &["time_step_s:", "expected a number", "line 1"]),
        ("time_step_s = 0.02", "time_step_s = 0.02\nframe_rate = 60", &["frame_rate", "unknown field", "time_step_s"]),
        (
            "[effects.gravity]",
            "[effects]\ngravity = [0.0, -9.81, 0.0]",
            &["effects.gravity:", "expected a table, e.g. `gravity = { acceleration_m_per_s2"],
        ),
        ("path = \"fox.fbk\"", "", &["packs[0]:", "missing field `path`"]),
        ("time_step_s = 0.02", "time_step_s = 0.02\nsolver = \"verlet\"", &["solver:", "`implicit`", "`xpbd`"]),
        (
            "time_step_s = 0.02",
            "time_step_s = 0.02\n[[lights]]\ntype = \"spot\"",
            &["lights[0].type:", "`directional` or `point`"],
        ),
        (
            "time_step_s = 0.02",
            "time_step_s = 0.02\n[camera]\neye = [1.0, 2.0]\ntarget = [0.0, 0.0, 0.0]",
            &["camera.eye:", "invalid length 2", "array of 3 numbers, e.g. `[0.0, 1.0, 0.0]`"],
        ),
        (
            "[effects.gravity]",
            "[effects.wind]\nvelocity_m_per_s = \"fast\"",
            &["effects.wind.velocity_m_per_s:", "array of 3 numbers"],
        ),
        (
            "[effects.gravity]",
            "[effects.gravity]\n[[events]]\nat_s = 1.0\nkind = \"explode\"",
            &["events[0].kind:", "`teleport`", "`forces_off`"],
        ),
        ("[effects.gravity]", "[effects.gravity]\n[render]\nblend = \"additive\"", &["render.blend:", "`alpha_blend`"]),
        (
            "path = \"fox.fbk\"",
            "path = \"fox.fbk\"\nscale = \"big\"",
            &["packs[0].scale:", "expected a number", "line 5"],
        ),
    ];
    for (i, (from, to, needles)) in cases.iter().enumerate() {
        let scene = dir.path().join(format!("broken{i}.toml"));
        std::fs::write(&scene, base.replacen(from, to, 1)).unwrap();
        let v = violations("scene", &[&scene]);
        assert!(!v.is_empty(), "the schema accepts broken scene {i}: {to}");
        let out = furbake(&["simulate", s(&scene), "--frames", "1"]);
        assert_eq!(out.status.code(), Some(1), "broken scene {i}: {}", stderr(&out));
        let err = stderr(&out);
        assert_eq!(err.lines().count(), 1, "one line: {err}");
        for needle in *needles {
            assert!(err.contains(needle), "broken scene {i} ({to}): {needle:?} not in {err}");
        }
    }
}

/// The `.toml` files of `fixtures/DIR`.
fn toml_fixtures(dir: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(repo(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    files
}

#[test]
fn bake_configs_and_batch_files_have_schemas_that_say_what_furbake_reads() {
    // The bundled configs and batch file validate, and furbake reads them: each config bakes.
    let configs = toml_fixtures("fixtures/configs");
    let batches = toml_fixtures("fixtures/batch");
    assert!(configs.len() >= 2 && !batches.is_empty());
    let v = violations("config", &configs.iter().map(PathBuf::as_path).collect::<Vec<_>>());
    assert!(v.is_empty(), "{v:#?}");
    let v = violations("batch", &batches.iter().map(PathBuf::as_path).collect::<Vec<_>>());
    assert!(v.is_empty(), "{v:#?}");
    let dir = tempfile::tempdir().unwrap();
    let sphere = repo("fixtures/generated/sphere.gltf");
    for config in &configs {
        let pack = dir.path().join("out.fbk");
        let out = furbake(&["bake", s(&sphere), "-o", s(&pack), "--resolution", "16", "--config", s(config), "-q"]);
        assert_ok(&out, &format!("bake --config {}", config.display()));
    }

    // Broken configs: refused by the schema, and by furbake (exit 2, a setting) naming the
    // dotted key and what it expects in words.
    let configs: [(&str, &[&str]); 5] = [
        ("seed = \"seven\"\n", &["seed:", "expected a whole number"]),
        ("[volume]\nlayerz = 4\n", &["volume.layerz:", "unknown field", "`layers`"]),
        ("[volume]\nresolution = 2.5\n", &["volume.resolution:", "expected a whole number"]),
        ("topologies = \"prisms\"\n[uv]\nrepeat_m = 0.1\n", &["topologies:", "expected an array"]),
        (
            "[import]\nfur_mask = { source = \"texture\" }\n[uv]\nrepeat_m = 0.1\n",
            &["import.fur_mask.source:", "`vertex_color`"],
        ),
    ];
    for (i, (text, needles)) in configs.iter().enumerate() {
        let config = dir.path().join(format!("broken{i}.toml"));
        std::fs::write(&config, text).unwrap();
        assert!(!violations("config", &[&config]).is_empty(), "the schema accepts broken config {i}: {text}");
        let out = furbake(&["bake", s(&sphere), "-o", s(&dir.path().join("x.fbk")), "--config", s(&config), "-q"]);
        assert_eq!(out.status.code(), Some(2), "broken config {i}: {}", stderr(&out));
        let err = stderr(&out);
        for needle in *needles {
            assert!(err.contains(needle), "broken config {i} ({text}): {needle:?} not in {err}");
        }
    }

    // Broken batch files: refused by the schema, and by furbake naming the asset and the key.
    std::fs::copy(&sphere, dir.path().join("sphere.gltf")).unwrap();
    let batches: [(&str, i32, &[&str]); 6] = [
        (
            "[[asset]]\nouput = \"x.fbk\"\ninput = \"sphere.gltf\"\n",
            1,
            &["asset[0].ouput:", "unknown field `ouput`", "line 2, column 1"],
        ),
        // Keys shared by [defaults] and [[asset]] keep their name and place.
        (
            "[defaults]\ndepfile = \"yes\"\n[[asset]]\ninput = \"sphere.gltf\"\n",
            1,
            &["defaults.depfile:", "expected a boolean", "line 2, column 11"],
        ),
        (
            "[[asset]]\ninput = \"sphere.gltf\"\nmax_memory = 3\n",
            1,
            &["asset[0].max_memory:", "expected a string", "line 3, column 14"],
        ),
        (
            "[defaults]\npreset = \"fur\"\n[[asset]]\noutput = \"x.fbk\"\n",
            1,
            &["asset[0]:", "missing field `input`", "line 3"],
        ),
        (
            "[[asset]]\ninput = \"sphere.gltf\"\n[asset.settings]\nvolume.layers = \"many\"\n",
            2,
            &["asset 1 (sphere.gltf)", "volume.layers:", "expected a whole number"],
        ),
        ("[defaults.settings]\nvolume = 3\n[[asset]]\ninput = \"sphere.gltf\"\n", 2, &["volume:", "expected a table"]),
    ];
    for (i, (text, code, needles)) in batches.iter().enumerate() {
        let batch = dir.path().join(format!("batch{i}.toml"));
        std::fs::write(&batch, text).unwrap();
        assert!(!violations("batch", &[&batch]).is_empty(), "the schema accepts broken batch file {i}: {text}");
        let out = furbake(&["batch", s(&batch), "-q"]);
        assert_eq!(out.status.code(), Some(*code), "broken batch file {i}: {}", stderr(&out));
        let err = stderr(&out);
        for needle in *needles {
            assert!(err.contains(needle), "broken batch file {i} ({text}): {needle:?} not in {err}");
        }
    }
}

/// `furbake shaders`' manifest.json of every target validates against
/// `docs/schemas/shaders-manifest.schema.json` (hand-written: what a host's build script may rely
/// on), and manifests that break it are refused: a GLSL binding without its OpenGL number, an
/// unknown switch, a vertex stage with a workgroup size, a SPIR-V manifest naming a GLSL file.
#[test]
fn shader_manifests_validate_against_their_schema() {
    let dir = tempfile::tempdir().unwrap();
    let mut manifests = Vec::new();
    for target in ["spirv", "glsl", "hlsl", "msl"] {
        let out_dir = dir.path().join(target);
        assert_ok(&furbake(&["shaders", "--target", target, "-o", s(&out_dir)]), "furbake shaders");
        manifests.push(out_dir.join("manifest.json"));
    }
    let v = violations("shaders-manifest", &manifests.iter().map(PathBuf::as_path).collect::<Vec<_>>());
    assert!(v.is_empty(), "{v:#?}");

    let glsl = read_json(&manifests[1]);
    let vertex = glsl["files"].as_array().unwrap().iter().position(|f| f["stage"] == "vertex").unwrap();
    let mut broken = glsl.clone();
    broken["files"][0]["bindings"][0].as_object_mut().unwrap().remove("glsl_binding");
    broken["files"][1]["constants"]["FAST_MATH"] = 1.0.into();
    broken["files"][vertex]["workgroup_size"] = serde_json::json!([64, 1, 1]);
    let v = violations("shaders-manifest", &[&write_json(&dir.path().join("b1.json"), &broken)]);
    for needle in ["files/0/bindings/0: 'glsl_binding' is a required property", "FAST_MATH", "workgroup_size"] {
        assert!(v.iter().any(|line| line.contains(needle)), "{needle:?} not refused: {v:#?}");
    }
    let mut broken = read_json(&manifests[0]);
    broken["files"][0]["file"] = "skin.vs_skin.none.vert".into();
    let v = violations("shaders-manifest", &[&write_json(&dir.path().join("b2.json"), &broken)]);
    assert!(v.len() == 1 && v[0].contains("file"), "a SPIR-V manifest naming a GLSL file: {v:#?}");
}
