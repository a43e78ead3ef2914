//! Imports every real fixture of the real fixture set (`fixtures/real/`, or `FURBAKE_FIXTURES`, see tests/common)
//! and checks topology counts, bounds,
//! transforms, vertex colours and input hashes against values read independently from the files
//! (accessor min/max in their JSON, the SHA-256 column of LICENSES.md).

use crate::common::{edge_count, fixture};
use furbake_import::{ImportError, ImportSettings, SkinMesh, import_gltf};
use sha2::{Digest, Sha256};

fn import(name: &str) -> furbake_import::ImportedMesh {
    import_gltf(&fixture(name), &ImportSettings::default()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Invariants every imported skin must satisfy; returns how many values were checked.
fn check_skin(mesh: &SkinMesh) -> usize {
    let v = mesh.positions.len();
    let f = mesh.triangles.len();
    assert!(v >= 3 && f >= 1);
    assert_eq!(mesh.normals.len(), v);
    assert_eq!(mesh.colors.len(), v);
    assert_eq!(mesh.fur_mask.len(), f);
    assert!(mesh.corner_texcoords.is_empty() || mesh.corner_texcoords.len() == f);
    let mut checked = 0;
    for n in &mesh.normals {
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-4, "normal {n:?} is not unit length");
        checked += 1;
    }
    let mut used = vec![false; v];
    for t in &mesh.triangles {
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2], "degenerate triangle {t:?} kept");
        for &i in t {
            assert!((i as usize) < v);
            used[i as usize] = true;
        }
        checked += 1;
    }
    assert!(used.iter().all(|&u| u), "every vertex is used by a triangle");
    assert!(mesh.positions.iter().flatten().chain(mesh.colors.iter().flatten()).all(|x| x.is_finite()));
    checked
}

#[test]
fn fox_welds_to_the_published_topology() {
    let fox = import("Fox.glb");
    let m = &fox.mesh;
    assert_eq!(m.positions.len(), 290, "V");
    assert_eq!(m.triangles.len(), 576, "F");
    assert_eq!(edge_count(m), 864, "E");
    assert_eq!(m.stats.input_vertices, 1728, "the file's unindexed corners");
    assert_eq!(m.stats.degenerate_triangles_skipped, 0);
    assert!(m.stats.generated_normals, "Fox.glb has no NORMAL attribute");
    assert_eq!(m.corner_texcoords.len(), 576, "Fox.glb has TEXCOORD_0");
    assert!(fox.animation.skeleton.is_some(), "Fox.glb is skinned");
    // Bind pose in the file's units (centimetres-ish): about 25 wide, 79 tall, 155 long.
    let (lo, hi) = m.bounds();
    assert!((hi[0] - lo[0] - 25.19).abs() < 0.1 && (hi[1] - lo[1] - 79.03).abs() < 0.1, "{lo:?} {hi:?}");
    assert!((hi[2] - lo[2] - 154.72).abs() < 0.1, "{lo:?} {hi:?}");
    assert_eq!(fox.input_bytes, 162_852);
    assert!(check_skin(m) > 800);
}

#[test]
fn cesium_milk_truck_gets_its_yup2zup_root_rotation() {
    let truck = import("CesiumMilkTruck.glb");
    let m = &truck.mesh;
    // Raw body accessor bounds (JSON): x ∈ [-2.4309, 2.438], y ∈ [-1.396, 1.396],
    // z ∈ [-2.58437, -0.2668]; wheels are instanced twice under translated nodes. The root node
    // "Yup2Zup" maps raw x → world z, raw y → world x, raw -z → world y.
    let (lo, hi) = m.bounds();
    let expect_lo = [-1.396, 0.0, -2.43091];
    let expect_hi = [1.396, 2.58437, 2.438];
    for k in 0..3 {
        assert!((lo[k] - expect_lo[k]).abs() < 2e-3, "min {lo:?}");
        assert!((hi[k] - expect_hi[k]).abs() < 2e-3, "max {hi:?}");
    }
    assert_eq!(m.stats.primitives, 5, "3 body primitives + 2 wheel instances");
    assert_eq!(m.stats.input_vertices, 2366 + 151 + 650 + 2 * 828);
    assert!(!m.stats.generated_normals);
    assert_eq!(m.corner_texcoords.len(), m.triangles.len());
    // Materials "glass" (0, 0.04, 0.02) and "window_trim" (0.064 grey) are dark; "wheels" and
    // "truck" have no factor (white). Vertices on a material border average their colours.
    assert!(m.colors.iter().any(|c| c[0] < 0.07 && c[1] < 0.07 && c[2] < 0.07));
    assert!(m.colors.contains(&[1.0; 4]));
    assert!(check_skin(m) > 3000);
}

#[test]
fn box_root_matrix_is_a_quarter_turn_about_x() {
    // Box.glb's root node matrix is column-major [1,0,0,0, 0,0,-1,0, 0,1,0,0, 0,0,0,1]:
    // (x, y, z) -> (x, z, -y), a -90° turn about X. The mesh is the unit cube centred at the
    // origin, so the bounds stay [-0.5, 0.5]³ and the hard-edged cube welds to 8 vertices whose
    // averaged normals point along the diagonals, outward.
    let b = import("Box.glb");
    let m = &b.mesh;
    assert_eq!((m.positions.len(), m.triangles.len(), edge_count(m)), (8, 12, 18));
    assert_eq!(m.bounds(), ([-0.5; 3], [0.5; 3]));
    for (p, n) in m.positions.iter().zip(&m.normals) {
        for k in 0..3 {
            assert!((n[k] - p[k].signum() / 3f32.sqrt()).abs() < 1e-5, "normal {n:?} at {p:?}");
        }
    }
    assert_eq!(m.colors[0], [0.8, 0.0, 0.0, 1.0], "material Red's base colour factor");
    // LICENSES.md lists this SHA-256 for Box.glb.
    assert_eq!(b.input_sha256, "ed52f7192b8311d700ac0ce80644e3852cd01537e4d62241b9acba023da3d54e");
    assert_eq!(b.input_bytes, 1664);
    check_skin(m);
}

#[test]
fn box_vertex_colors_come_through() {
    let b = import("BoxVertexColors.glb");
    let m = &b.mesh;
    assert!(m.stats.had_vertex_colors);
    assert_eq!(m.positions.len(), 8);
    // The file colours each corner of the unit cube [0,1]³ with its own position (an RGB cube).
    let mut checked = 0;
    for (p, c) in m.positions.iter().zip(&m.colors) {
        assert_eq!([c[0], c[1], c[2], c[3]], [p[0], p[1], p[2], 1.0]);
        checked += 1;
    }
    assert_eq!(checked, 8);
}

#[test]
fn quaternius_wolf_imports_as_a_closed_skinned_mesh() {
    let w = import("Quaternius_Wolf.glb");
    let m = &w.mesh;
    let (v, f, e) = (m.positions.len(), m.triangles.len(), edge_count(m));
    assert_eq!(m.stats.primitives, 4);
    assert!(v > 900 && f > 1900, "V={v} F={f}");
    assert_eq!(v as i64 - e as i64 + f as i64, 2, "Euler characteristic of a closed genus-0 skin");
    assert!(w.animation.skeleton.is_some() && w.animation.skin_weights.is_some(), "the wolf is skinned");
    // Four materials' base colours (no COLOR_0).
    assert!(!m.stats.had_vertex_colors);
    assert!(m.colors.iter().any(|c| (c[0] - 0.18424858).abs() < 1e-6));
    assert!(m.corner_texcoords.is_empty(), "the wolf has no TEXCOORD_0");
    check_skin(m);
}

#[test]
fn two_sided_plane_reads_its_external_buffer_and_hashes_it() {
    let path = fixture("TwoSidedPlane/TwoSidedPlane.gltf");
    // Without texture sampling only the .gltf and its .bin are read.
    let settings = ImportSettings { base_color_texture: false, ..ImportSettings::default() };
    let p = import_gltf(&path, &settings).unwrap();
    assert_eq!((p.mesh.positions.len(), p.mesh.triangles.len()), (4, 2));
    assert_eq!(p.mesh.bounds(), ([-1.0, 0.0, -1.0], [1.0, 0.0, 1.0]));
    assert!(p.mesh.normals.iter().all(|n| *n == [0.0, 1.0, 0.0]));
    let gltf = std::fs::read(&path).unwrap();
    let bin = std::fs::read(path.with_file_name("TwoSidedPlane.bin")).unwrap();
    let mut h = Sha256::new();
    h.update(&gltf);
    h.update(&bin);
    let expected: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(p.input_sha256, expected);
    assert_eq!(p.input_bytes, (gltf.len() + bin.len()) as u64);
    // With it (the default), the external base colour PNG shapes the colours, so it joins the hash.
    let textured = import_gltf(&path, &ImportSettings::default()).unwrap();
    let png = std::fs::read(path.with_file_name("TwoSidedPlane_BaseColor.png")).unwrap();
    let mut h = Sha256::new();
    h.update(&gltf);
    h.update(&bin);
    h.update(&png);
    let expected: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(textured.input_sha256, expected);
    assert_eq!(textured.input_bytes, (gltf.len() + bin.len() + png.len()) as u64);
    assert!(textured.mesh.colors.iter().any(|c| *c != [1.0; 4]), "the texture colours the vertices");
}

#[test]
fn a_missing_external_buffer_names_the_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let copy = dir.path().join("plane.gltf");
    std::fs::copy(fixture("TwoSidedPlane/TwoSidedPlane.gltf"), &copy).unwrap();
    let err = import_gltf(&copy, &ImportSettings::default()).unwrap_err();
    match &err {
        ImportError::ExternalFile { file, referrer, uri, problem } => {
            assert_eq!(file, &copy);
            assert_eq!(*referrer, furbake_import::ExternalRef::Buffer(0));
            assert_eq!(&**uri, "TwoSidedPlane.bin");
            assert!(
                matches!(&**problem, furbake_import::UriProblem::Io { path, .. } if path.ends_with("TwoSidedPlane.bin"))
            );
            assert!(err.to_string().contains("TwoSidedPlane.bin"), "{err}");
        }
        other => panic!("expected ExternalFile, got {other}"),
    }
    let missing = dir.path().join("nope.glb");
    let err = import_gltf(&missing, &ImportSettings::default()).unwrap_err();
    assert!(matches!(err, ImportError::Io { .. }) && err.to_string().contains("nope.glb"), "{err}");
}

#[test]
fn import_is_deterministic() {
    let a = import("Quaternius_Wolf.glb");
    let b = import("Quaternius_Wolf.glb");
    assert_eq!(a, b);
}

#[test]
fn fox_takes_its_colour_from_the_base_colour_texture() {
    // Fox.glb has no COLOR_0, only a base colour texture: its fur must come out fox-coloured
    // (orange: red well above blue), and white when texture sampling is switched off.
    let textured = import("Fox.glb").mesh;
    let orange = textured.colors.iter().filter(|c| c[0] > 0.3 && c[0] > 2.0 * c[2]).count();
    assert!(orange > textured.colors.len() / 3, "{orange} of {} vertices are orange", textured.colors.len());
    let settings = ImportSettings { base_color_texture: false, ..ImportSettings::default() };
    let plain = import_gltf(&fixture("Fox.glb"), &settings).unwrap().mesh;
    assert!(plain.colors.iter().all(|c| *c == [1.0; 4]), "without the texture every vertex is the white factor");
    assert_eq!(plain.positions, textured.positions, "colour sampling leaves the geometry alone");
}

/// Each joint records its glTF node: the node of that index in the file's own JSON (read here
/// from the GLB's JSON chunk, not through the importer) carries the joint's name, and every node
/// a skin lists as a joint is one of them.
#[test]
fn skeleton_joints_record_their_gltf_nodes() {
    for name in ["Fox.glb", "Quaternius_Wolf.glb"] {
        let imported = import(name);
        let sk = imported.animation.skeleton.as_ref().unwrap_or_else(|| panic!("{name} is skinned"));
        assert_eq!(sk.nodes.len(), sk.joint_count(), "{name}");
        let bytes = std::fs::read(fixture(name)).unwrap();
        let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
        assert_eq!(&bytes[16..20], b"JSON", "{name}: the GLB's first chunk is its JSON");
        let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
        let nodes = json["nodes"].as_array().unwrap();
        for (j, &n) in sk.nodes.iter().enumerate() {
            let node_name = nodes[n as usize]["name"].as_str().unwrap_or("");
            assert_eq!(
                node_name.get(..128.min(node_name.len())).unwrap_or(node_name),
                sk.names[j],
                "{name}: joint {j}"
            );
        }
        for skin in json["skins"].as_array().unwrap() {
            for joint in skin["joints"].as_array().unwrap() {
                let n = joint.as_u64().unwrap() as u32;
                assert!(sk.nodes.contains(&n), "{name}: skin joint node {n} is not a skeleton joint");
            }
        }
    }
}
