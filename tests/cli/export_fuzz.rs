//! Fuzzed exports: every pack `verify` accepts exports to a .glb the Khronos glTF-Validator
//! accepts. Two small rigged packs — the skinned strip of the animation tests and the Fox — are
//! mutated with the pack fuzzer's structure-aware mutator (`furbake_fuzz::packs::mutate_pack`,
//! checksums recomputed so the mutants reach the decoders); the mutants that `Pack::verify`
//! accepts are exported by `furbake export` (which verifies them again and must exit 0), and the
//! distinct files are validated in one batch (`tools/validate_gltf.mjs FILE…`). The figures are
//! printed (`--nocapture`). Before the skeleton decoder and the exporter were fixed, 5 of the 326
//! distinct exports of this campaign had 1,772 validator errors between them: an inverse bind
//! whose bottom row was not `0, 0, 0, 1` (`ACCESSOR_INVALID_IBM`: now refused by the decoder), a
//! vertex naming one bind twice (`ACCESSOR_JOINTS_INDEX_DUPLICATE`: now merged by the exporter)
//! and weights summing to 1 within the pack's 1e-3 but not within the validator's rounding
//! allowance (`ACCESSOR_WEIGHTS_NON_NORMALIZED`: now renormalised by the exporter). The importer
//! refuses a projective inverse bind and stores rounding in its bottom row as the exact row.

use std::collections::{BTreeMap, HashSet};
use std::path::Path;
use std::process::Command;

use furbake_formats::{Pack, SectionKind};
use furbake_fuzz::packs::{PackModel, mutate_pack};
use furbake_fuzz::rng::Rng;
use furbake_import::testmesh::SkinnedStrip;

use super::common::*;

/// Campaign seed.
const SEED: u64 = 0x6c7f;
/// Mutants tried; `FURBAKE_EXPORT_FUZZ_CASES` sets another count (a longer local campaign).
const CASES: u64 = 8000;

/// Bakes `mesh` into `out` with a small volume (16² × 4 shells).
fn bake(mesh: &Path, out: &Path) -> PackModel {
    let args = ["bake", s(mesh), "-o", s(out), "--resolution", "16", "--layers", "4", "-q"];
    assert_ok(&furbake(&args), &format!("bake {}", mesh.display()));
    PackModel::parse(&std::fs::read(out).unwrap()).expect("a valid pack")
}

#[test]
fn mutants_that_verify_export_to_files_the_validator_accepts() {
    let tools = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools");
    assert!(
        tools.join("node_modules/gltf-validator").is_dir(),
        "the glTF-Validator is not installed: run `npm ci --prefix tools` (make deps does)"
    );
    let dir = tempfile::tempdir().unwrap();
    let strip = dir.path().join("strip.gltf");
    std::fs::write(&strip, SkinnedStrip::default().to_gltf()).unwrap();
    let bases =
        [bake(&strip, &dir.path().join("strip.fbk")), bake(&real_fixture("Fox.glb"), &dir.path().join("fox.fbk"))];

    let (mut accepted, mut unexportable, mut exported) = (0u64, 0u64, Vec::new());
    let (mut seen_packs, mut seen_glbs) = (HashSet::new(), HashSet::new());
    let cases = std::env::var("FURBAKE_EXPORT_FUZZ_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(CASES);
    for case in 0..cases {
        let bytes = mutate_pack(&mut Rng::for_case(SEED, case), &bases);
        let Some(pack) = Pack::from_bytes(&bytes).ok().filter(|p| p.verify().is_ok()) else { continue };
        accepted += 1;
        if !seen_packs.insert(bytes.clone()) {
            continue;
        }
        let (path, glb) = (dir.path().join(format!("m{case}.fbk")), dir.path().join(format!("m{case}.glb")));
        std::fs::write(&path, &bytes).unwrap();
        let out = furbake(&["export", s(&path), "-o", s(&glb), "-q"]);
        // A pack without a skin, shells or UV map is valid but has nothing to export.
        let needed = [SectionKind::SKIN_MESH, SectionKind::SHELL_ATLAS, SectionKind::TRIANGLE_UV_MAP];
        if let Some(kind) = needed.into_iter().find(|&k| !pack.has(k)) {
            assert_eq!(out.status.code(), Some(1), "mutant {case}: {}", stderr(&out));
            assert!(stderr(&out).contains(&format!("has no {kind} section")), "mutant {case}: {}", stderr(&out));
            unexportable += 1;
            continue;
        }
        assert_ok(&out, &format!("export mutant {case}"));
        if seen_glbs.insert(std::fs::read(&glb).unwrap()) {
            exported.push((case, glb));
        } else {
            std::fs::remove_file(&glb).unwrap();
        }
    }
    let distinct = seen_packs.len();

    let out = Command::new("node")
        .arg(tools.join("validate_gltf.mjs"))
        .args(exported.iter().map(|(_, glb)| glb))
        .output()
        .expect("node runs");
    assert!(matches!(out.status.code(), Some(0 | 1)), "validator failed: {}", stderr(&out));
    let reports: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).expect("the validator prints JSON");
    assert_eq!(reports.len(), exported.len());
    let mut errors = 0;
    // Error code → mutant → how many.
    let mut codes: BTreeMap<String, BTreeMap<u64, u64>> = BTreeMap::new();
    for ((case, _), report) in exported.iter().zip(&reports) {
        errors += report["issues"]["numErrors"].as_u64().expect("numErrors");
        for m in report["issues"]["messages"].as_array().into_iter().flatten().filter(|m| m["severity"] == 0) {
            *codes.entry(m["code"].as_str().unwrap_or("?").to_owned()).or_default().entry(*case).or_default() += 1;
        }
    }
    eprintln!(
        "export fuzz: {cases} mutants tried, {accepted} verified ({distinct} distinct, {unexportable} without a \
         skin, shells or UV map), {} distinct .glb files exported and validated, {errors} validator errors",
        exported.len()
    );
    for (code, cases) in &codes {
        eprintln!("  {code}: {} errors; mutant: count {cases:?}", cases.values().sum::<u64>());
    }
    assert!(exported.len() >= 100, "only {} distinct exports: the campaign tests too little", exported.len());
    assert_eq!(errors, 0, "exports of packs that verify have validator errors: {codes:?}");
}

#[test]
fn the_importer_stores_inverse_binds_exactly_affine() {
    let dir = tempfile::tempdir().unwrap();
    let (gltf, pack) = (dir.path().join("strip.gltf"), dir.path().join("strip.fbk"));
    let bake = || furbake(&["bake", s(&gltf), "-o", s(&pack), "--resolution", "16", "--layers", "4", "-q"]);
    // A projective bottom row is no inverse bind: refused, naming the joint.
    let mut strip = SkinnedStrip::default();
    strip.inverse_binds[1][3] = 0.5;
    std::fs::write(&gltf, strip.to_gltf()).unwrap();
    let out = bake();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("inverse bind matrix of joint 1 is not affine"), "{}", stderr(&out));
    assert!(!pack.exists());
    // Rounding in the bottom row is stored as the exact row.
    let mut strip = SkinnedStrip::default();
    strip.inverse_binds[1][7] = -2e-7;
    strip.inverse_binds[1][15] = 1.0 + f32::EPSILON;
    std::fs::write(&gltf, strip.to_gltf()).unwrap();
    assert_ok(&bake(), "bake with a rounded inverse bind");
    let skeleton = Pack::read(&pack).unwrap().skeleton().unwrap().expect("the strip is rigged");
    for m in &skeleton.inverse_binds {
        assert_eq!([m[3], m[7], m[11], m[15]], [0.0, 0.0, 0.0, 1.0], "{m:?}");
    }
    assert_ok(&furbake(&["verify", s(&pack)]), "verify");
}
