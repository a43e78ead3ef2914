//! The glTF export of real packs, baked here through the bake library from the repository's
//! fixtures (`fixtures/real/Fox.glb`, skinned and animated; `fixtures/generated/sphere.gltf`,
//! static) with small settings: the file re-imports, has one primitive per shell layer at
//! linearly growing offsets, PNG textures with alpha, the rig and clips of an animated pack, the
//! same bytes every time, and passes the Khronos glTF-Validator (tools/validate_gltf.mjs).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use furbake_bake::{BakeSettings, NoProgress};
use furbake_export::{ExportError, ExportOptions, ShellAlpha, export, export_glb};
use furbake_formats::Pack;
use furbake_import::{ImportSettings, import_gltf, import_gltf_slice};
use serde_json::Value;

const LAYERS: u32 = 4;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn bake(fixture: &str) -> Pack {
    let settings = BakeSettings::preset("fur")
        .and_then(|s| s.with_overrides(&serde_json::json!({ "volume": { "resolution": 16, "layers": LAYERS } })))
        .expect("small fur settings");
    let path = repo().join(fixture);
    let imported = import_gltf(&path, &settings.import).expect("fixture imports");
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("input");
    let baked = furbake_bake::bake(&imported, name, &settings.plan().unwrap(), &mut NoProgress).expect("fixture bakes");
    Pack::from_bytes(&baked.to_writer().to_bytes()).expect("baked pack reads back")
}

fn fox() -> &'static Pack {
    static P: OnceLock<Pack> = OnceLock::new();
    P.get_or_init(|| bake("fixtures/real/Fox.glb"))
}

/// A plane: border edges, so fins.
fn plane() -> &'static Pack {
    static P: OnceLock<Pack> = OnceLock::new();
    P.get_or_init(|| bake("fixtures/generated/plane_bare_centre.gltf"))
}

fn sphere() -> &'static Pack {
    static P: OnceLock<Pack> = OnceLock::new();
    P.get_or_init(|| bake("fixtures/generated/sphere.gltf"))
}

/// The JSON and binary chunks of a GLB.
fn chunks(glb: &[u8]) -> (Value, &[u8]) {
    assert_eq!(&glb[0..4], b"glTF");
    assert_eq!(u32::from_le_bytes(glb[4..8].try_into().unwrap()), 2);
    assert_eq!(u32::from_le_bytes(glb[8..12].try_into().unwrap()) as usize, glb.len());
    assert_eq!(glb.len() % 4, 0);
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    assert_eq!(&glb[16..20], b"JSON");
    assert_eq!(json_len % 4, 0);
    let doc: Value = serde_json::from_slice(&glb[20..20 + json_len]).expect("JSON chunk parses");
    let at = 20 + json_len;
    let bin_len = u32::from_le_bytes(glb[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&glb[at + 4..at + 8], b"BIN\0");
    (doc, &glb[at + 8..at + 8 + bin_len])
}

fn view<'a>(doc: &Value, bin: &'a [u8], view: usize) -> &'a [u8] {
    let v = &doc["bufferViews"][view];
    let offset = v["byteOffset"].as_u64().unwrap_or(0) as usize;
    assert_eq!(offset % 4, 0, "buffer view {view} is not 4-byte aligned");
    &bin[offset..offset + v["byteLength"].as_u64().unwrap() as usize]
}

/// A float `VEC3` accessor's elements.
fn vec3s(doc: &Value, bin: &[u8], accessor: usize) -> Vec<[f32; 3]> {
    let a = &doc["accessors"][accessor];
    assert_eq!(a["componentType"], 5126);
    assert_eq!(a["type"], "VEC3");
    let bytes = view(doc, bin, a["bufferView"].as_u64().unwrap() as usize);
    let floats: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
    floats.chunks_exact(3).take(a["count"].as_u64().unwrap() as usize).map(|c| [c[0], c[1], c[2]]).collect()
}

fn meshes_named<'a>(doc: &'a Value, prefix: &str) -> Vec<&'a Value> {
    doc["meshes"].as_array().unwrap().iter().filter(|m| m["name"].as_str().unwrap().starts_with(prefix)).collect()
}

fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[test]
fn skin_alone_reimports_as_the_packs_skin() {
    for pack in [sphere(), fox(), plane()] {
        let options = ExportOptions { layers: Some(0), fins: false, ..ExportOptions::default() };
        let glb = export_glb(pack, &options).expect("exports");
        let back = import_gltf_slice(&glb, "skin.glb", None, &ImportSettings::default()).expect("re-imports");
        let skin = pack.skin_mesh().unwrap();
        assert_eq!(back.mesh.positions.len(), skin.positions.len());
        assert_eq!(back.mesh.triangles.len(), skin.triangles.len());
        let ((lo, hi), (blo, bhi)) = (skin.bounds(), back.mesh.bounds());
        for k in 0..3 {
            assert!(
                (lo[k] - blo[k]).abs() <= 1e-5 && (hi[k] - bhi[k]).abs() <= 1e-5,
                "{lo:?}..{hi:?} vs {blo:?}..{bhi:?}"
            );
        }
    }
}

#[test]
fn a_full_export_reimports_as_its_skin_alone() {
    // furbake's importer skips the nodes the export marks as fur (`extras.furbake`), so baking an
    // exported file again grows fur on the skin, not on the old shells.
    for pack in [sphere(), fox(), plane()] {
        let glb = export_glb(pack, &ExportOptions::default()).expect("exports");
        let back = import_gltf_slice(&glb, "fur.glb", None, &ImportSettings::default()).expect("re-imports");
        let skin = pack.skin_mesh().unwrap();
        assert_eq!(back.mesh.positions.len(), skin.positions.len());
        assert_eq!(back.mesh.triangles.len(), skin.triangles.len());
        assert!(
            back.warnings.iter().any(|w| w.contains("mesh nodes that furbake export wrote")),
            "{:?}",
            back.warnings
        );
        let ((lo, hi), (blo, bhi)) = (skin.bounds(), back.mesh.bounds());
        for k in 0..3 {
            let slack = 1e-4 * (hi[k] - lo[k]).abs().max(1.0);
            assert!(
                (blo[k] - lo[k]).abs() <= slack && (bhi[k] - hi[k]).abs() <= slack,
                "{lo:?}..{hi:?} vs {blo:?}..{bhi:?}"
            );
        }
    }
}

#[test]
fn one_primitive_per_layer_offsets_grow_linearly() {
    for pack in [sphere(), fox(), plane()] {
        let glb = export_glb(pack, &ExportOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        let shells = meshes_named(&doc, "shell ");
        assert_eq!(shells.len(), LAYERS as usize);
        let skin = pack.skin_mesh().unwrap();
        let fur = pack.shell_atlas().unwrap().fur_length_m;
        // Node order: skin, then the shells inner to outer, then the fins.
        let names: Vec<&str> = doc["nodes"].as_array().unwrap().iter().filter_map(|n| n["name"].as_str()).collect();
        assert_eq!(names[0], "skin");
        assert_eq!(names[1..=LAYERS as usize], ["shell 00", "shell 01", "shell 02", "shell 03"]);
        let has_fins = !pack.fin_edges().unwrap().vertices.is_empty();
        assert_eq!(names.get(1 + LAYERS as usize) == Some(&"fins"), has_fins);
        for (i, mesh) in shells.iter().enumerate() {
            let prims = mesh["primitives"].as_array().unwrap();
            assert_eq!(prims.len(), 1);
            let p = &prims[0];
            let material = &doc["materials"][p["material"].as_u64().unwrap() as usize];
            assert_eq!(material["alphaMode"], "BLEND");
            assert_eq!(material["extras"]["layer"], i);
            let positions = vec3s(&doc, bin, p["attributes"]["POSITION"].as_u64().unwrap() as usize);
            let normals = vec3s(&doc, bin, p["attributes"]["NORMAL"].as_u64().unwrap() as usize);
            // Each shell vertex sits on its root's normal at (i + 1)/n of the fur length.
            let t = (i + 1) as f32 / LAYERS as f32;
            let mut mean = 0.0f64;
            for (q, n) in positions.iter().zip(&normals) {
                let root = [0, 1, 2].map(|k| q[k] - n[k] * t * fur);
                let nearest = skin.positions.iter().map(|&s| dist(s, root)).fold(f32::INFINITY, f32::min);
                assert!(nearest < 1e-4 * fur.max(1.0), "shell {i}: a vertex is not on a skin vertex's normal");
                let d = skin.positions.iter().map(|&s| dist(s, *q)).fold(f32::INFINITY, f32::min);
                mean += f64::from(d);
            }
            mean /= positions.len() as f64;
            // The nearest skin vertex of a shell vertex is its root (the fur is short against the
            // skin's edges), so the mean distance is the layer's offset.
            let want = f64::from(t * fur);
            assert!((mean - want).abs() <= 0.02 * want, "shell {i}: mean distance {mean} m, offset {want} m");
        }
    }
}

#[test]
fn textures_are_pngs_with_alpha() {
    for pack in [sphere(), fox(), plane()] {
        let glb = export_glb(pack, &ExportOptions::default()).unwrap();
        let (doc, bin) = chunks(&glb);
        let images = doc["images"].as_array().unwrap();
        let has_fins = !pack.fin_edges().unwrap().vertices.is_empty();
        assert_eq!(
            images.len(),
            LAYERS as usize + usize::from(has_fins),
            "one image per shell slice and the fin atlas"
        );
        for (i, img) in images.iter().enumerate() {
            assert_eq!(img["mimeType"], "image/png");
            let bytes = view(&doc, bin, img["bufferView"].as_u64().unwrap() as usize);
            let decoded = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).expect("PNG decodes");
            assert!(decoded.color().has_alpha(), "image {i} has alpha");
            let la = decoded.to_luma_alpha8();
            let (lo, hi) = la.pixels().fold((255u8, 0u8), |(lo, hi), p| (lo.min(p[1]), hi.max(p[1])));
            assert!(lo < hi, "image {i}: alpha is constant ({lo})");
        }
        if let Some(fins) = doc["materials"].as_array().unwrap().iter().find(|m| m["name"] == "fins") {
            assert!(has_fins);
            assert_eq!(fins["doubleSided"], true);
            assert_eq!(fins["alphaMode"], "BLEND");
        }
        let skin = &doc["materials"][0];
        assert!(skin.get("alphaMode").is_none(), "the skin is opaque");
    }
}

#[test]
fn an_animated_pack_exports_its_rig_and_clips() {
    let pack = fox();
    let exported = export(pack, &ExportOptions::default()).unwrap();
    let (doc, _) = chunks(&exported.glb);
    let sk = pack.skeleton().unwrap().expect("the fox is rigged");
    let clips = pack.animation_clips().unwrap().expect("the fox has clips");
    assert_eq!(doc["skins"].as_array().unwrap().len(), 1);
    assert_eq!(doc["skins"][0]["joints"].as_array().unwrap().len(), sk.bind_count());
    assert_eq!(doc["animations"].as_array().unwrap().len(), clips.clips.len());
    for mesh in doc["meshes"].as_array().unwrap() {
        let a = &mesh["primitives"][0]["attributes"];
        assert!(a.get("JOINTS_0").is_some() && a.get("WEIGHTS_0").is_some(), "{} is skinned", mesh["name"]);
    }
    for node in doc["nodes"].as_array().unwrap().iter().filter(|n| n.get("mesh").is_some()) {
        assert_eq!(node["skin"], 0);
    }
    let back = import_gltf_slice(&exported.glb, "fox_fur.glb", None, &ImportSettings::default()).unwrap();
    let back_clips = back.animation.clips.expect("clips re-import");
    assert_eq!(back_clips.clips.len(), clips.clips.len());
    for (a, b) in back_clips.clips.iter().zip(&clips.clips) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.channels.len(), b.channels.len());
    }
    assert!(back.animation.skeleton.is_some() && back.animation.skin_weights.is_some());
}

#[test]
fn fins_stand_on_the_fin_edges() {
    let pack = plane();
    let edges = pack.fin_edges().unwrap();
    assert!(!edges.vertices.is_empty(), "the plane has border edges");
    let glb = export_glb(pack, &ExportOptions::default()).unwrap();
    let (doc, bin) = chunks(&glb);
    let fins = meshes_named(&doc, "fins");
    assert_eq!(fins.len(), 1);
    let p = &fins[0]["primitives"][0];
    let positions = vec3s(&doc, bin, p["attributes"]["POSITION"].as_u64().unwrap() as usize);
    assert_eq!(positions.len(), 4 * edges.vertices.len(), "one quad per fin edge");
    assert_eq!(doc["accessors"][p["indices"].as_u64().unwrap() as usize]["count"], 6 * edges.vertices.len());
    let skin = pack.skin_mesh().unwrap();
    let fur = pack.shell_atlas().unwrap().fur_length_m;
    for (quad, &[a, b]) in positions.chunks_exact(4).zip(&edges.vertices) {
        let (pa, pb) = (skin.positions[a as usize], skin.positions[b as usize]);
        assert_eq!([quad[0], quad[1]], [pa, pb], "roots on the edge");
        assert!((dist(quad[2], pa) - fur).abs() < 1e-5 && (dist(quad[3], pb) - fur).abs() < 1e-5, "fur-length tall");
    }
}

#[test]
fn same_pack_same_bytes() {
    for pack in [sphere(), fox(), plane()] {
        let a = export_glb(pack, &ExportOptions::default()).unwrap();
        let b = export_glb(pack, &ExportOptions::default()).unwrap();
        assert!(a == b, "the export is deterministic");
    }
}

#[test]
fn options_are_checked_and_fewer_layers_sample_the_atlas() {
    let err = export_glb(sphere(), &ExportOptions { layers: Some(LAYERS + 1), ..ExportOptions::default() });
    assert!(matches!(err, Err(ExportError::Option { option: "layers", .. })), "{err:?}");
    let err = export_glb(sphere(), &ExportOptions { alpha: ShellAlpha::Mask { cutoff: 2.0 }, ..Default::default() });
    assert!(matches!(err, Err(ExportError::Option { option: "alpha", .. })), "{err:?}");
    let glb = export_glb(
        sphere(),
        &ExportOptions { layers: Some(2), alpha: ShellAlpha::Mask { cutoff: 0.5 }, ..Default::default() },
    )
    .unwrap();
    let (doc, _) = chunks(&glb);
    assert_eq!(meshes_named(&doc, "shell ").len(), 2);
    let slices: Vec<u64> =
        doc["materials"].as_array().unwrap().iter().filter_map(|m| m["extras"]["atlas_slice"].as_u64()).collect();
    // The slab holding each layer's height (ShellAtlas::slice_for, as the renderer picks slices).
    assert_eq!(slices, [(LAYERS / 2 - 1) as u64, (LAYERS - 1) as u64], "atlas of {LAYERS} layers");
    assert!(doc["materials"].as_array().unwrap().iter().skip(1).all(|m| m["alphaMode"] == "MASK"));
}

/// Runs the Khronos glTF-Validator on `glb`; returns its report.
fn validate(name: &str, glb: &[u8]) -> Value {
    let tools = repo().join("tools");
    assert!(
        tools.join("node_modules/gltf-validator").is_dir(),
        "tools/node_modules/gltf-validator is missing: run `npm ci --prefix tools` (needs node and npm)"
    );
    let file = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&file, glb).unwrap();
    let out = std::process::Command::new("node")
        .arg(tools.join("validate_gltf.mjs"))
        .arg(&file)
        .output()
        .expect("node runs (install Node.js, then `npm ci --prefix tools`)");
    let report: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("validator output is not JSON ({e}): {}", String::from_utf8_lossy(&out.stderr)));
    let issues = &report["issues"];
    eprintln!(
        "{name}: {} errors, {} warnings, {} infos, {} hints; {} bytes",
        issues["numErrors"],
        issues["numWarnings"],
        issues["numInfos"],
        issues["numHints"],
        glb.len()
    );
    for m in issues["messages"].as_array().into_iter().flatten() {
        eprintln!("  {} {} {} {}", m["severity"], m["code"], m["pointer"], m["message"]);
    }
    assert_eq!(issues["numErrors"], 0, "{name}: the glTF-Validator reports errors (see above)");
    assert!(out.status.success(), "{name}: validate_gltf.mjs failed: {}", String::from_utf8_lossy(&out.stderr));
    report
}

#[test]
fn the_khronos_validator_finds_no_errors() {
    validate("sphere_fur.glb", &export_glb(sphere(), &ExportOptions::default()).unwrap());
    validate("fox_fur.glb", &export_glb(fox(), &ExportOptions::default()).unwrap());
    validate("plane_fur.glb", &export_glb(plane(), &ExportOptions::default()).unwrap());
    let masked =
        ExportOptions { layers: Some(2), fins: false, alpha: ShellAlpha::Mask { cutoff: 0.3 }, ..Default::default() };
    validate("fox_fur_mask.glb", &export_glb(fox(), &masked).unwrap());
    let report = validate(
        "sphere_skin.glb",
        &export_glb(sphere(), &ExportOptions { layers: Some(0), ..Default::default() }).unwrap(),
    );
    assert_eq!(report["issues"]["numErrors"], 0);
}
