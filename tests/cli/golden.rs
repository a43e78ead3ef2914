//! Golden packs: small bakes of generated meshes whose SHA-256 is committed in
//! `fixtures/golden/checksums.txt`, and one committed pack (`fixtures/golden/grass_patch_v1.fbk`,
//! written by the first build and never regenerated) that must stay readable as the format evolves. A change to any algorithm or to the format
//! shows up here; after checking the change is intended, regenerate with `make golden`
//! (`FURBAKE_BLESS=1 cargo test -p furbake-cli --test cli golden`).

use std::path::Path;

use furbake_import::testmesh;
use sha2::{Digest, Sha256};

use crate::common::*;

const GOLDEN_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/golden");

/// (name, glTF bytes, extra bake flags)
fn cases() -> Vec<(&'static str, Vec<u8>, Vec<&'static str>)> {
    vec![
        (
            "grass_patch",
            testmesh::grass_patch(1.0).gltf,
            vec!["--preset", "grass", "--resolution", "16", "--layers", "8"],
        ),
        ("sphere", testmesh::uv_sphere(6, 8, 0.5).gltf, vec!["--resolution", "32", "--seed", "5"]),
        ("bare_region", testmesh::plane_with_bare_region(4, 1.0).gltf, vec!["--resolution", "16"]),
    ]
}

#[test]
fn golden_pack_checksums_match() {
    let bless = std::env::var_os("FURBAKE_BLESS").is_some();
    let dir = tempfile::tempdir().unwrap();
    let mut lines = Vec::new();
    for (name, gltf, flags) in cases() {
        let input = dir.path().join(format!("{name}.gltf"));
        std::fs::write(&input, &gltf).unwrap();
        let pack = dir.path().join(format!("{name}.fbk"));
        let mut args = vec!["bake", s(&input), "-o", s(&pack), "-q"];
        args.extend(flags);
        if name == "bare_region" {
            args.extend(["--set", "import.fur_mask={\"source\":\"materials\",\"names\":[\"fur\"]}"]);
        }
        assert_ok(&furbake(&args), name);
        let bytes = std::fs::read(&pack).unwrap();
        lines.push(format!("{name} {:x}", Sha256::digest(&bytes)));
        // The committed v1 pack is written once and then kept as it is: it pins that files
        // written by older builds stay readable.
        let v1 = Path::new(GOLDEN_DIR).join("grass_patch_v1.fbk");
        if bless && name == "grass_patch" && !v1.exists() {
            std::fs::write(&v1, &bytes).unwrap();
        }
    }
    let path = Path::new(GOLDEN_DIR).join("checksums.txt");
    let text = lines.join("\n") + "\n";
    if bless {
        std::fs::write(&path, &text).unwrap();
    }
    let want = std::fs::read_to_string(&path).expect("fixtures/golden/checksums.txt exists (make golden)");
    assert_eq!(lines.len(), 3);
    assert_eq!(text, want, "golden checksums changed; if intended, run `make golden`");
}

#[test]
fn committed_version_1_pack_stays_readable() {
    let pack = Path::new(GOLDEN_DIR).join("grass_patch_v1.fbk");
    assert_ok(&furbake(&["verify", s(&pack)]), "verify the committed v1 pack");
    let out = furbake(&["inspect", "--json", s(&pack)]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["statistics"]["vertices"], 13, "the thesis's grass patch has 13 vertices");
    assert_eq!(json["statistics"]["triangles"], 16);
}
