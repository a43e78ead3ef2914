//! `furbake export`: a baked pack becomes a .glb that the Khronos glTF-Validator accepts with no
//! errors and that `furbake bake` takes again; bad flags exit 2 and write nothing.

use std::path::Path;
use std::process::Command;

use super::common::*;

/// Runs the Khronos glTF-Validator (`tools/validate_gltf.mjs`) on `glb`: its error count.
fn validator_errors(glb: &Path) -> u64 {
    let tools = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools");
    assert!(
        tools.join("node_modules/gltf-validator").is_dir(),
        "the glTF-Validator is not installed: run `npm ci --prefix tools` (make deps does)"
    );
    let out = Command::new("node").arg(tools.join("validate_gltf.mjs")).arg(glb).output().expect("node runs");
    assert!(matches!(out.status.code(), Some(0 | 1)), "validator failed: {}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("the validator prints JSON");
    report["issues"]["numErrors"].as_u64().expect("numErrors")
}

#[test]
fn an_exported_fox_validates_and_bakes_again() {
    let dir = tempfile::tempdir().unwrap();
    let (pack, glb) = (dir.path().join("fox.fbk"), dir.path().join("fox.glb"));
    let fox = real_fixture("Fox.glb");
    assert_ok(&furbake(&["bake", s(&fox), "-o", s(&pack), "--resolution", "16", "--layers", "4", "-q"]), "bake");
    let out = furbake(&["export", s(&pack), "-o", s(&glb)]);
    assert_ok(&out, "export");
    assert!(stdout(&out).contains("fox.glb"), "{}", stdout(&out));
    assert_eq!(validator_errors(&glb), 0, "the exported Fox has validator errors");
    // The glTF carries the skin, four shell layers and the Fox's three clips.
    let bytes = std::fs::read(&glb).unwrap();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    assert_eq!(doc["animations"].as_array().unwrap().len(), 3);
    let primitives: usize =
        doc["meshes"].as_array().unwrap().iter().map(|m| m["primitives"].as_array().unwrap().len()).sum();
    assert!(primitives >= 5, "skin + 4 shell layers, got {primitives} primitives");
    // It bakes again: the importer skips the exported shells and fins, so the new pack's skin is
    // the Fox's skin (290 welded vertices, 576 triangles) with the Fox's three clips.
    let again = dir.path().join("again.fbk");
    let out = furbake(&["bake", s(&glb), "-o", s(&again), "--resolution", "16"]);
    assert_ok(&out, "bake the export");
    assert!(stderr(&out).contains("mesh nodes that furbake export wrote"), "{}", stderr(&out));
    assert_ok(&furbake(&["verify", s(&again)]), "verify");
    let json: serde_json::Value = serde_json::from_slice(&furbake(&["inspect", "--json", s(&again)]).stdout).unwrap();
    assert_eq!(json["statistics"]["vertices"], 290, "{}", json["statistics"]);
    assert_eq!(json["statistics"]["triangles"], 576);
    assert_eq!(json["clips"].as_array().unwrap().len(), 3);
    // The same pack exports to the same bytes.
    let twice = dir.path().join("twice.glb");
    assert_ok(&furbake(&["export", s(&pack), "-o", s(&twice), "-q"]), "export again");
    assert_eq!(std::fs::read(&twice).unwrap(), bytes);
    // Bad flags exit 2 and write nothing; a broken pack exits 1.
    let bad = dir.path().join("bad.glb");
    for args in [vec!["--layers", "99"], vec!["--alpha-mask", "2"]] {
        let out = furbake(&[&["export", s(&pack), "-o", s(&bad)][..], &args[..]].concat());
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(!bad.exists());
    }
    std::fs::write(dir.path().join("broken.fbk"), b"not a pack").unwrap();
    let out = furbake(&["export", s(&dir.path().join("broken.fbk")), "-o", s(&bad)]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("broken.fbk") && !bad.exists());
}
