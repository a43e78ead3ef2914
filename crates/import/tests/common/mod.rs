//! Shared helpers for the import integration tests: fixture paths, edge counting and small
//! hand-editable glTF documents built on `testmesh`.

use std::collections::HashSet;
use std::path::PathBuf;

use furbake_import::testmesh::{TestPrimitive, gltf_json};
use furbake_import::{ImportError, ImportSettings, ImportedMesh, SkinMesh, import_gltf_slice};
use serde_json::Value;

/// Path of a real fixture in the repository's `fixtures/real/` (licences beside them), or under
/// the folder `FURBAKE_FIXTURES` names (to run the tests on another set of models).
pub fn fixture(name: &str) -> PathBuf {
    let root = std::env::var_os("FURBAKE_FIXTURES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real"));
    let path = root.join(name);
    assert!(path.exists(), "fixture {} is missing", path.display());
    path
}

/// Number of unique undirected edges.
pub fn edge_count(mesh: &SkinMesh) -> usize {
    let mut edges = HashSet::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            edges.insert((a.min(b), a.max(b)));
        }
    }
    edges.len()
}

/// A one-primitive glTF document as a JSON value, ready to be edited.
pub fn document(positions: Vec<[f32; 3]>, indices: Vec<u32>) -> Value {
    document_of(&[TestPrimitive::triangles(positions, indices)])
}

/// A glTF document holding `primitives`, as a JSON value.
pub fn document_of(primitives: &[TestPrimitive]) -> Value {
    serde_json::from_slice(&gltf_json(primitives, None)).expect("testmesh writes valid JSON")
}

/// Imports a JSON document with `settings`.
pub fn import_value(doc: &Value, settings: &ImportSettings) -> Result<ImportedMesh, ImportError> {
    import_gltf_slice(&serde_json::to_vec(doc).unwrap(), "test.gltf", None, settings)
}

/// One triangle in the XY plane.
pub fn triangle() -> (Vec<[f32; 3]>, Vec<u32>) {
    (vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], vec![0, 1, 2])
}
