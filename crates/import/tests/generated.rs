//! Generated meshes (`testmesh`): topology counts, generated normals, fur masks from materials,
//! colours and attributes, node transforms with mirroring, degenerate-triangle skipping, strips,
//! fans and unindexed primitives, and the settings' TOML form.

use crate::common::{document, document_of, edge_count, import_value};
use furbake_import::testmesh::{self, TestPrimitive, gltf_json};
use furbake_import::{ColorChannel, FurMaskSource, ImportError, ImportSettings, WeldTolerance, import_gltf_slice};
use glam::Vec3;

fn import(bytes: &[u8], settings: &ImportSettings) -> furbake_import::ImportedMesh {
    import_gltf_slice(bytes, "generated.gltf", None, settings).unwrap_or_else(|e| panic!("{e}"))
}

fn counts(mesh: &furbake_import::SkinMesh) -> (usize, usize, usize) {
    (mesh.positions.len(), mesh.triangles.len(), edge_count(mesh))
}

#[test]
fn test_meshes_weld_to_their_documented_counts() {
    let mut checked = 0;
    let cases = [
        ("grass patch", testmesh::grass_patch(1.0)),
        ("sphere 8x12", testmesh::uv_sphere(8, 12, 0.5)),
        ("sphere 2x3", testmesh::uv_sphere(2, 3, 1.0)),
        ("cube", testmesh::cube(2.0)),
        ("plane 4", testmesh::plane_with_bare_region(4, 1.0)),
        ("plane 10", testmesh::plane_with_bare_region(10, 3.0)),
    ];
    for (name, t) in &cases {
        let m = import(&t.gltf, &ImportSettings::default());
        assert_eq!(counts(&m.mesh), (t.vertices, t.triangles, t.edges), "{name}");
        assert_eq!(m.mesh.stats.degenerate_triangles_skipped, 0, "{name}");
        assert!(m.mesh.stats.generated_normals, "{name}");
        checked += 1;
    }
    assert_eq!(checked, cases.len());
    // The thesis's grass patch (fur thesis §3.4.1): V = 13, F = 16.
    assert_eq!((cases[0].1.vertices, cases[0].1.triangles), (13, 16));
}

#[test]
fn generated_normals_point_outward_on_closed_meshes() {
    let mut checked = 0;
    for t in [testmesh::cube(1.0), testmesh::uv_sphere(6, 9, 2.0)] {
        let m = import(&t.gltf, &ImportSettings::default()).mesh;
        for (p, n) in m.positions.iter().zip(&m.normals) {
            let (p, n) = (Vec3::from(*p), Vec3::from(*n));
            assert!((n.length() - 1.0).abs() < 1e-5);
            assert!(n.dot(p.normalize()) > 0.5, "normal {n} at {p} points inward");
            checked += 1;
        }
        // Face winding is outward too.
        for tri in &m.triangles {
            let [a, b, c] = tri.map(|i| Vec3::from(m.positions[i as usize]));
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
            checked += 1;
        }
    }
    assert_eq!(checked, 8 + 12 + (2 + 5 * 9) + 2 * 9 * 5);
    // The flat grass patch: every generated normal is +Y.
    let patch = import(&testmesh::grass_patch(1.0).gltf, &ImportSettings::default()).mesh;
    assert!(patch.normals.iter().all(|n| (Vec3::from(*n) - Vec3::Y).length() < 1e-6));
}

#[test]
fn fur_mask_by_material_name() {
    let t = testmesh::plane_with_bare_region(8, 1.0);
    let settings = ImportSettings {
        fur_mask: FurMaskSource::Materials { names: vec!["fur".to_string()] },
        ..ImportSettings::default()
    };
    let m = import(&t.gltf, &settings);
    assert_eq!(m.mesh.furry_triangles(), t.furry_triangles);
    assert_eq!(t.furry_triangles, 2 * (64 - 16), "8x8 cells with a 4x4 bare centre");
    // Bare triangles are exactly those whose centroid lies in the central square.
    let mut checked = 0;
    for (tri, &fur) in m.mesh.triangles.iter().zip(&m.mesh.fur_mask) {
        let c = tri.iter().map(|&i| Vec3::from(m.mesh.positions[i as usize])).sum::<Vec3>() / 3.0;
        let central = c.x.abs() < 0.25 && c.z.abs() < 0.25;
        assert_eq!(fur, u8::from(!central), "triangle at {c}");
        checked += 1;
    }
    assert_eq!(checked, 128);
    // Welding joins the two materials' vertex copies into one surface.
    assert_eq!(m.mesh.positions.len(), 81);
    assert_eq!(m.mesh.stats.input_vertices, 2 * 81);

    // A name no primitive uses is reported; default mask is all furry.
    let typo = ImportSettings {
        fur_mask: FurMaskSource::Materials { names: vec!["Fur".to_string()] },
        ..ImportSettings::default()
    };
    let m = import(&t.gltf, &typo);
    assert_eq!(m.mesh.furry_triangles(), 0);
    assert!(m.warnings.iter().any(|w| w.contains("\"Fur\"") && w.contains("no imported primitive uses")));
    assert!(m.warnings.iter().any(|w| w.contains("no triangle carries fur")));
    assert_eq!(import(&t.gltf, &ImportSettings::default()).mesh.furry_triangles(), 128);
}

#[test]
fn fur_mask_by_vertex_colour_and_by_attribute() {
    // Two triangles sharing an edge: vertex 3's value decides the second triangle.
    let positions = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    let indices = vec![0, 1, 2, 2, 1, 3];
    let colors = vec![[1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]];
    let fur = vec![1.0, 1.0, 1.0, 0.0];
    let prim = TestPrimitive {
        colors: Some(colors),
        scalars: vec![("_FUR".to_string(), fur)],
        ..TestPrimitive::triangles(positions, indices)
    };
    let bytes = gltf_json(&[prim], None);
    let by_colour = |threshold| ImportSettings {
        fur_mask: FurMaskSource::VertexColor { channel: ColorChannel::R, threshold },
        ..ImportSettings::default()
    };
    // Triangle 1's mean red is 2/3.
    assert_eq!(import(&bytes, &by_colour(0.5)).mesh.fur_mask, vec![1, 1]);
    assert_eq!(import(&bytes, &by_colour(0.7)).mesh.fur_mask, vec![1, 0]);
    let green = ImportSettings {
        fur_mask: FurMaskSource::VertexColor { channel: ColorChannel::G, threshold: 0.5 },
        ..ImportSettings::default()
    };
    assert_eq!(import(&bytes, &green).mesh.fur_mask, vec![0, 0]);
    let mut checked = 0;
    for name in ["_FUR", "FUR"] {
        let s = ImportSettings {
            fur_mask: FurMaskSource::Attribute { name: name.to_string(), threshold: 0.9 },
            ..ImportSettings::default()
        };
        assert_eq!(import(&bytes, &s).mesh.fur_mask, vec![1, 0], "{name}");
        checked += 1;
    }
    assert_eq!(checked, 2);
    // Vertex colours reach the skin.
    let m = import(&bytes, &ImportSettings::default()).mesh;
    assert!(m.stats.had_vertex_colors);
    assert_eq!(m.colors[3], [0.0, 0.0, 0.0, 1.0]);

    // No primitive has the attribute / colour: an error, not a silently bare mesh.
    let plain = testmesh::grass_patch(1.0).gltf;
    let s = ImportSettings {
        fur_mask: FurMaskSource::Attribute { name: "_FUR".to_string(), threshold: 0.5 },
        ..ImportSettings::default()
    };
    assert!(matches!(import_gltf_slice(&plain, "p.gltf", None, &s), Err(ImportError::FurMask { .. })));
    assert!(matches!(import_gltf_slice(&plain, "p.gltf", None, &by_colour(0.5)), Err(ImportError::FurMask { .. })));
}

#[test]
fn degenerate_triangles_are_skipped_and_counted() {
    let positions = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [2.0, 0.0, 0.0], // collinear with 0 and 1
        [1.0, 0.0, 0.0], // a duplicate of vertex 1 (welds to it)
        [0.0, 0.0, 5.0], // only used by a degenerate triangle
    ];
    let indices = vec![
        0, 1, 2, // good
        0, 1, 3, // zero area (collinear)
        2, 2, 1, // repeated index
        1, 4, 2, // repeated after welding
        5, 5, 5, // point-like
    ];
    let m = import_value(&document(positions, indices), &ImportSettings::default()).unwrap();
    assert_eq!(m.mesh.triangles, vec![[0, 1, 2]]);
    assert_eq!(m.mesh.stats.degenerate_triangles_skipped, 4);
    assert_eq!(m.mesh.positions.len(), 3, "vertices used only by skipped triangles are dropped");
    assert!(m.warnings.iter().any(|w| w.contains("dropped")));
}

#[test]
fn a_mirroring_node_matrix_flips_the_winding_and_transforms_bounds() {
    let cube = testmesh::cube(1.0);
    let doc: serde_json::Value = serde_json::from_slice(&cube.gltf).unwrap();
    let mut checked = 0;
    // Scale x by -2, y by 3, translate by (10, 0, -1): det < 0.
    let matrix = [-2.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 10.0, 0.0, -1.0, 1.0];
    for (name, node) in [
        ("matrix", serde_json::json!({ "mesh": 0, "matrix": matrix })),
        ("trs", serde_json::json!({ "mesh": 0, "scale": [-2.0, 3.0, 1.0], "translation": [10.0, 0.0, -1.0] })),
    ] {
        let mut d = doc.clone();
        d["nodes"][0] = node;
        let m = import_value(&d, &ImportSettings::default()).unwrap().mesh;
        assert_eq!(m.bounds(), ([9.0, -1.5, -1.5], [11.0, 1.5, -0.5]), "{name}");
        let centre = Vec3::new(10.0, 0.0, -1.0);
        for tri in &m.triangles {
            let [a, b, c] = tri.map(|i| Vec3::from(m.positions[i as usize]));
            assert!((b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) > 0.0, "{name}: inward face");
            checked += 1;
        }
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!(Vec3::from(*n).dot(Vec3::from(*p) - centre) > 0.0, "{name}: inward normal");
            checked += 1;
        }
    }
    assert_eq!(checked, 2 * (12 + 8));

    // File normals go through the inverse transpose: a +Y normal under a shear stays
    // perpendicular to the transformed surface.
    let grid = TestPrimitive {
        normals: Some(vec![[0.0, 1.0, 0.0]; 3]),
        ..TestPrimitive::triangles(vec![[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], vec![0, 1, 2])
    };
    let shear = [1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    // Mirroring y: the inverse transpose turns +Y into -Y and the flipped winding agrees.
    let mirror_y = [1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let mut checked = 0;
    for (name, matrix, expected) in [("shear", shear, None), ("mirror y", mirror_y, Some(Vec3::NEG_Y))] {
        let m = import(&gltf_json(std::slice::from_ref(&grid), Some(matrix)), &ImportSettings::default()).mesh;
        let [a, b, c] = m.triangles[0].map(|i| Vec3::from(m.positions[i as usize]));
        let face = (b - a).cross(c - a).normalize();
        if let Some(e) = expected {
            assert!((face - e).length() < 1e-6, "{name}: face {face}");
        }
        for n in &m.normals {
            assert!((Vec3::from(*n) - face).length() < 1e-6, "{name}: {n:?} vs {face}");
            checked += 1;
        }
        assert!(!m.stats.generated_normals);
    }
    assert_eq!(checked, 6);
}

#[test]
fn strips_fans_and_unindexed_primitives_are_triangulated() {
    let quad = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
    let strip = TestPrimitive { mode: 5, indices: None, ..TestPrimitive::triangles(quad.clone(), vec![]) };
    let fan_pts = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let fan = TestPrimitive { mode: 6, ..TestPrimitive::triangles(fan_pts, vec![0, 1, 2, 3]) };
    let mut checked = 0;
    for (name, p) in [("strip", strip), ("fan", fan)] {
        let m = import(&gltf_json(&[p], None), &ImportSettings::default()).mesh;
        assert_eq!(counts(&m), (4, 2, 5), "{name}");
        for n in &m.normals {
            assert_eq!(*n, [0.0, 0.0, 1.0], "{name}: consistent CCW winding");
            checked += 1;
        }
    }
    assert_eq!(checked, 8);
    // Unindexed TRIANGLES: 6 corners, welded to 4 vertices.
    let soup =
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
    let unindexed = TestPrimitive { indices: None, ..TestPrimitive::triangles(soup, vec![]) };
    let m = import(&gltf_json(&[unindexed], None), &ImportSettings::default()).mesh;
    assert_eq!(counts(&m), (4, 2, 5));
}

#[test]
fn weld_tolerance_decides_what_becomes_one_vertex() {
    // Two triangles whose shared edge is offset by 1 mm in the second copy.
    let d = 1e-3;
    let p = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 1.0 + d, 0.0],
        [1.0 + d, 0.0, 0.0],
        [1.0, 1.0, 0.0],
    ];
    let doc = document(p, vec![0, 1, 2, 3, 4, 5]);
    let with = |t| ImportSettings { weld_tolerance: t, ..ImportSettings::default() };
    let tight = import_value(&doc, &with(WeldTolerance::default())).unwrap();
    assert_eq!(tight.mesh.positions.len(), 6);
    let loose = import_value(&doc, &with(WeldTolerance::AbsoluteM(2e-3))).unwrap();
    assert_eq!(loose.mesh.positions.len(), 4);
    assert_eq!(loose.mesh.stats.weld_tolerance_m, 2e-3);
    let relative = import_value(&doc, &with(WeldTolerance::Relative(1e-2))).unwrap();
    assert_eq!(relative.mesh.positions.len(), 4);
    assert!((relative.mesh.stats.weld_tolerance_m - 1e-2 * (2.0f32 * 1.001 * 1.001).sqrt()).abs() < 1e-6);
    let exact = import_value(&doc, &with(WeldTolerance::AbsoluteM(0.0))).unwrap();
    assert_eq!(exact.mesh.positions.len(), 6);
}

#[test]
fn settings_read_from_toml_and_reject_unknown_fields() {
    let s: ImportSettings = toml::from_str(
        r#"
        weld_tolerance = { absolute_m = 0.0001 }
        [fur_mask]
        source = "materials"
        names = ["Fur", "Mane"]
        "#,
    )
    .unwrap();
    assert_eq!(s.weld_tolerance, WeldTolerance::AbsoluteM(1e-4));
    assert_eq!(s.fur_mask, FurMaskSource::Materials { names: vec!["Fur".into(), "Mane".into()] });
    let back: ImportSettings = toml::from_str(&toml::to_string(&s).unwrap()).unwrap();
    assert_eq!(back, s);

    let empty: ImportSettings = toml::from_str("").unwrap();
    assert_eq!(empty, ImportSettings::default());
    assert_eq!(empty.weld_tolerance, WeldTolerance::Relative(1e-6));
    assert_eq!(empty.fur_mask, FurMaskSource::All);

    let colour: ImportSettings =
        toml::from_str("fur_mask = { source = \"vertex_color\", channel = \"a\", threshold = 0.25 }").unwrap();
    assert_eq!(colour.fur_mask, FurMaskSource::VertexColor { channel: ColorChannel::A, threshold: 0.25 });
    let attr: ImportSettings =
        toml::from_str("fur_mask = { source = \"attribute\", name = \"_FUR\", threshold = 0.5 }").unwrap();
    assert!(matches!(attr.fur_mask, FurMaskSource::Attribute { .. }));

    let mut rejected = 0;
    for bad in [
        "weld_tolerence = { relative = 1e-6 }",
        "fur_mask = { source = \"materials\", names = [], extra = 1 }",
        "fur_mask = { source = \"vertex_color\", channel = \"x\", threshold = 0.5 }",
        "fur_mask = { source = \"everything\" }",
        "weld_tolerance = { relative = 1e-6, absolute_m = 1.0 }",
    ] {
        assert!(toml::from_str::<ImportSettings>(bad).is_err(), "accepted: {bad}");
        rejected += 1;
    }
    assert_eq!(rejected, 5);
}

#[test]
fn multiple_primitives_without_texcoords_leave_corner_texcoords_empty() {
    let patch = testmesh::grass_patch(1.0);
    let m = import(&patch.gltf, &ImportSettings::default()).mesh;
    assert_eq!(m.corner_texcoords.len(), 16, "the patch has TEXCOORD_0");
    // Corner UVs follow the corners: uv = xz / size + 0.5.
    for (tri, uvs) in m.triangles.iter().zip(&m.corner_texcoords) {
        for (i, uv) in tri.iter().zip(uvs) {
            let p = m.positions[*i as usize];
            assert_eq!(*uv, [p[0] + 0.5, p[2] + 0.5]);
        }
    }
    let with_uv = TestPrimitive {
        texcoords: Some(vec![[0.0, 0.0]; 3]),
        ..TestPrimitive::triangles(vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![0, 1, 2])
    };
    let without = TestPrimitive::triangles(vec![[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]], vec![0, 1, 2]);
    let m = import_value(&document_of(&[with_uv, without]), &ImportSettings::default()).unwrap().mesh;
    assert_eq!(m.triangles.len(), 2);
    assert!(m.corner_texcoords.is_empty());
}
