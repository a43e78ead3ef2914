//! Hand-written glTF documents that must fail with a specific, well-located error — or import
//! with a reported skip — instead of panicking or producing a silently wrong skin.

use crate::common::{document, document_of, import_value, triangle};
use furbake_import::testmesh::{TestPrimitive, data_uri};
use furbake_import::{ImportError, ImportSettings, UriProblem, import_gltf_slice};
use serde_json::json;

fn defaults() -> ImportSettings {
    ImportSettings::default()
}

#[test]
fn missing_position_names_mesh_and_primitive() {
    let (p, i) = triangle();
    let mut doc = document(p, i);
    let attrs = doc["meshes"][0]["primitives"][0]["attributes"].as_object_mut().unwrap();
    let pos = attrs.remove("POSITION").unwrap();
    attrs.insert("NORMAL".into(), pos);
    let err = import_value(&doc, &defaults()).unwrap_err();
    match &err {
        ImportError::MissingPosition { at, file } => {
            assert_eq!((at.mesh, at.primitive, at.mesh_name.as_deref()), (0, 0, Some("testmesh")));
            assert_eq!(file.to_str(), Some("test.gltf"));
        }
        other => panic!("expected MissingPosition, got {other}"),
    }
    assert!(err.to_string().contains("mesh 0 \"testmesh\", primitive 0"), "{err}");
}

#[test]
fn nan_position_names_the_vertex() {
    let (mut p, i) = triangle();
    p[2][1] = f32::NAN;
    let err = import_value(&document(p, i), &defaults()).unwrap_err();
    match &err {
        ImportError::NonFinite { attribute, vertex, .. } => assert_eq!((attribute.as_str(), *vertex), ("POSITION", 2)),
        other => panic!("expected NonFinite, got {other}"),
    }
    assert!(err.to_string().contains("vertex 2"), "{err}");

    let (mut p, i) = triangle();
    p[1][0] = f32::INFINITY;
    assert!(matches!(import_value(&document(p, i), &defaults()), Err(ImportError::NonFinite { vertex: 1, .. })));
}

#[test]
fn huge_finite_texcoords_and_positions_are_errors_not_packs_that_fail_verify() {
    // Cause: the importer checked TEXCOORD_0 and positions only for finiteness, so a glTF with a
    // texture coordinate of 3.4e38 imported, baked and exited 0 — writing a pack whose skin mesh
    // `verify` refuses (coordinates beyond ±1e7; found by furbake-fuzz, glTF seed 2 case 53).
    let (p, i) = triangle();
    let prim = TestPrimitive {
        texcoords: Some(vec![[0.0, 0.0], [3.4e38, 0.0], [0.0, 1.0]]),
        ..TestPrimitive::triangles(p.clone(), i.clone())
    };
    let err = import_value(&document_of(&[prim]), &defaults()).unwrap_err();
    match &err {
        ImportError::OutOfRange { attribute, vertex, .. } => {
            assert_eq!((attribute.as_str(), *vertex), ("TEXCOORD_0", 1))
        }
        other => panic!("expected OutOfRange, got {other}"),
    }
    let (mut p, i) = (p, i);
    p[2][0] = 2e7;
    let err = import_value(&document(p, i), &defaults()).unwrap_err();
    assert!(
        matches!(&err, ImportError::OutOfRange { attribute, vertex: 2, .. } if attribute.starts_with("POSITION")),
        "{err}"
    );
    assert!(err.to_string().contains("beyond the ±1e7 a pack stores"), "{err}");
}

/// The grass patch (13 vertices) under a node DAG of `depth` levels, each node naming the next
/// twice: 2^depth instances of one mesh from about a kilobyte of JSON.
fn node_dag(depth: usize) -> serde_json::Value {
    let mut doc: serde_json::Value = serde_json::from_slice(&furbake_import::testmesh::grass_patch(2.0).gltf).unwrap();
    let mut nodes = vec![json!({ "mesh": 0 })];
    for d in 0..depth {
        let next = if d + 1 == depth { 0 } else { d + 2 };
        nodes.push(json!({ "children": [next, next] }));
    }
    doc["nodes"] = json!(nodes);
    doc["scenes"] = json!([{ "nodes": [1] }]);
    doc
}

#[test]
fn a_node_dag_instancing_one_mesh_millions_of_times_is_refused() {
    // Cause: instancing was bounded only by the raw-vertex limit (8 Mi) and the node-visit limit
    // (2^20), so a 1.7 KB glTF whose nodes branch into 2^19 paths to the grass patch imported
    // 6.8 M vertices: 8 s and 1.2 GB in a release build (found by furbake-fuzz, glTF seed 1 case
    // 995). Repeated instances may now add at most 1 Mi vertices.
    let started = std::time::Instant::now();
    let err = import_value(&node_dag(19), &defaults()).unwrap_err();
    match &err {
        ImportError::TooLarge { what, limit, .. } => {
            assert!(what.contains("repeated mesh instances"), "{err}");
            assert_eq!(*limit, furbake_import::limits::MAX_INSTANCED_VERTICES);
        }
        other => panic!("expected TooLarge, got {other}"),
    }
    assert!(started.elapsed().as_secs() < 30, "refused in {:?}", started.elapsed());
    // Ordinary instancing still imports: 2^10 instances of 13 vertices.
    let mesh = import_value(&node_dag(10), &defaults()).expect("1,024 instances import");
    assert_eq!(mesh.mesh.triangles.len(), 16 << 10);
}

#[test]
fn out_of_range_index_is_reported_with_its_position() {
    let (p, _) = triangle();
    let err = import_value(&document(p, vec![0, 1, 2, 2, 1, 7]), &defaults()).unwrap_err();
    match err {
        ImportError::IndexOutOfRange { position, index, vertex_count, .. } => {
            assert_eq!((position, index, vertex_count), (5, 7, 3));
        }
        other => panic!("expected IndexOutOfRange, got {other}"),
    }
}

#[test]
fn primitives_and_scenes_without_triangles_are_errors() {
    let (p, _) = triangle();
    let err = import_value(&document(p.clone(), vec![0, 1]), &defaults()).unwrap_err();
    assert!(matches!(err, ImportError::PrimitiveWithoutTriangles { elements: 2, .. }), "{err}");

    // Only a POINTS primitive: skipped with a warning, so the scene has no triangles.
    let points = TestPrimitive { mode: 0, ..TestPrimitive::triangles(p.clone(), vec![0, 1, 2]) };
    let err = import_value(&document_of(std::slice::from_ref(&points)), &defaults()).unwrap_err();
    assert!(matches!(&err, ImportError::NoTriangles { details, .. } if details.contains("1 point/line")), "{err}");

    // Points next to a triangle: imported, with a warning about the skipped primitive.
    let tri = TestPrimitive::triangles(p.clone(), vec![0, 1, 2]);
    let ok = import_value(&document_of(&[points, tri]), &defaults()).unwrap();
    assert_eq!(ok.mesh.triangles.len(), 1);
    assert_eq!(ok.mesh.stats.primitives, 1);
    assert!(ok.warnings.iter().any(|w| w.contains("mesh 0 \"testmesh\", primitive 0: skipped, mode POINTS")));

    // A scene whose only triangle is degenerate.
    let flat = vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    let err = import_value(&document(flat, vec![0, 1, 2]), &defaults()).unwrap_err();
    assert!(matches!(&err, ImportError::NoTriangles { details, .. } if details.contains("degenerate")), "{err}");

    // A document with no meshes at all.
    let empty = json!({ "asset": { "version": "2.0" }, "scenes": [{ "nodes": [] }], "scene": 0 });
    assert!(matches!(import_value(&empty, &defaults()), Err(ImportError::NoTriangles { .. })));
}

#[test]
fn required_draco_is_refused_by_name_before_the_gltf_crate_sees_it() {
    // A Draco-compressed primitive as exporters write it: extension data, no plain accessors.
    let doc = json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_draco_mesh_compression"],
        "extensionsRequired": ["KHR_draco_mesh_compression"],
        "scene": 0,
        "scenes": [{ "nodes": [0] }],
        "nodes": [{ "mesh": 0 }],
        "meshes": [{ "primitives": [{
            "attributes": { "POSITION": 0 },
            "extensions": { "KHR_draco_mesh_compression": { "bufferView": 0, "attributes": { "POSITION": 0 } } }
        }]}],
        "accessors": [{ "componentType": 5126, "count": 3, "type": "VEC3" }],
        "bufferViews": [{ "buffer": 0, "byteLength": 4 }],
        "buffers": [{ "byteLength": 4, "uri": data_uri(&[0, 0, 0, 0]) }],
    });
    let err = import_value(&doc, &defaults()).unwrap_err();
    match &err {
        ImportError::UnsupportedExtension { extension, .. } => assert_eq!(extension, "KHR_draco_mesh_compression"),
        other => panic!("expected UnsupportedExtension, got {other}"),
    }
    assert!(err.to_string().contains("gltfpack"), "the message suggests a way out: {err}");

    let mut checked = 0;
    for ext in ["EXT_meshopt_compression", "KHR_mesh_quantization", "EXT_some_future_thing"] {
        let (p, i) = triangle();
        let mut doc = document(p, i);
        doc["extensionsRequired"] = json!([ext]);
        doc["extensionsUsed"] = json!([ext]);
        let err = import_value(&doc, &defaults()).unwrap_err();
        assert!(matches!(&err, ImportError::UnsupportedExtension { extension, .. } if extension == ext), "{err}");
        checked += 1;
    }
    assert_eq!(checked, 3);

    // A required extension that does not touch geometry is accepted.
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["extensionsRequired"] = json!(["KHR_materials_unlit"]);
    doc["extensionsUsed"] = json!(["KHR_materials_unlit"]);
    assert_eq!(import_value(&doc, &defaults()).unwrap().mesh.triangles.len(), 1);
}

#[test]
fn not_gltf_at_all_is_invalid_gltf() {
    let mut checked = 0;
    for bytes in
        [&b"hello"[..], b"{}", b"glTF\x02\0\0\0", b"{\"asset\":{\"version\":\"2.0\"},\"nodes\":[{\"mesh\":5}]}"]
    {
        let err = import_gltf_slice(bytes, "junk.gltf", None, &defaults()).unwrap_err();
        assert!(matches!(err, ImportError::InvalidGltf { .. }), "{err}");
        assert!(err.to_string().starts_with("junk.gltf: "), "{err}");
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn a_value_that_does_not_fit_the_schema_is_named_by_its_json_path() {
    // An early glTF 2.0 sample's camera without its required `type`: the message names the
    // object, not only a line and column.
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["cameras"] = json!([{ "perspective": { "yfov": 0.66, "znear": 1.0 } }]);
    let err = import_value(&doc, &defaults()).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, ImportError::InvalidGltf { .. }), "{text}");
    assert!(text.contains("JSON at cameras[0]: missing field `type`"), "{text}");
    // Trailing bytes after the document are still refused.
    let (p, i) = triangle();
    let mut bytes = serde_json::to_vec(&document(p, i)).unwrap();
    bytes.extend_from_slice(b" x");
    let err = import_gltf_slice(&bytes, "trailing.gltf", None, &defaults()).unwrap_err();
    assert!(matches!(err, ImportError::InvalidGltf { .. }), "{err}");
}

#[test]
fn accessors_that_lie_about_their_size_are_errors_not_panics() {
    let (p, i) = triangle();
    let mut doc = document(p.clone(), i.clone());
    doc["accessors"][0]["count"] = json!(1000);
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(matches!(&err, ImportError::Accessor { attribute, .. } if attribute == "POSITION"), "{err}");

    let mut doc = document(p.clone(), i.clone());
    doc["accessors"][0]["count"] = json!(1u64 << 40);
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(matches!(err, ImportError::TooLarge { .. }), "{err}");

    let mut doc = document(p.clone(), i.clone());
    doc["bufferViews"][0]["byteOffset"] = json!(1u64 << 62);
    assert!(import_value(&doc, &defaults()).is_err());

    // A buffer shorter than its byteLength.
    let mut doc = document(p, i);
    doc["buffers"][0]["byteLength"] = json!(10_000);
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(matches!(err, ImportError::Buffer { buffer: 0, .. }), "{err}");
}

#[test]
fn node_cycles_are_reported() {
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["nodes"] = json!([{ "mesh": 0, "children": [1] }, { "children": [0] }]);
    let err = import_value(&doc, &defaults()).unwrap_err();
    // Either the gltf crate's validation or our walk catches it; both name the file.
    assert!(matches!(err, ImportError::Scene { .. } | ImportError::InvalidGltf { .. }), "{err}");
}

#[test]
fn external_buffers_need_a_base_directory() {
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["buffers"][0]["uri"] = json!("mesh.bin");
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(
        matches!(&err, ImportError::ExternalFile { problem, .. } if matches!(**problem, UriProblem::NoBaseDirectory)),
        "{err}"
    );
    assert!(err.to_string().contains("no base directory"), "{err}");
    doc["buffers"][0]["uri"] = json!("https://example.invalid/mesh.bin");
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(
        matches!(&err, ImportError::ExternalFile { problem, .. } if matches!(**problem, UriProblem::Scheme { .. })),
        "{err}"
    );
}

#[test]
fn invalid_settings_are_rejected() {
    let (p, i) = triangle();
    let doc = document(p, i);
    let mut checked = 0;
    for s in [
        ImportSettings { weld_tolerance: furbake_import::WeldTolerance::AbsoluteM(-1.0), ..defaults() },
        ImportSettings { weld_tolerance: furbake_import::WeldTolerance::Relative(f32::NAN), ..defaults() },
        ImportSettings { fur_mask: furbake_import::FurMaskSource::Materials { names: vec![] }, ..defaults() },
        ImportSettings {
            fur_mask: furbake_import::FurMaskSource::VertexColor {
                channel: furbake_import::ColorChannel::R,
                threshold: 2.0,
            },
            ..defaults()
        },
    ] {
        assert!(matches!(import_value(&doc, &s), Err(ImportError::Settings { .. })));
        checked += 1;
    }
    assert_eq!(checked, 4);
}

#[test]
fn out_of_range_position_accessor_index_is_an_error_not_a_gltf_json_panic() {
    // Cause: gltf-json 1.4.1's primitive validation hook indexes `accessors[POSITION]` without a
    // bounds check (mesh.rs:151) and panicked on this input before the importer checked it.
    let (p, i) = triangle();
    let mut doc = document(p, i);
    doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(9);
    let err = import_value(&doc, &defaults()).unwrap_err();
    assert!(matches!(&err, ImportError::InvalidGltf { message, .. } if message.contains("accessor 9")), "{err}");
}
