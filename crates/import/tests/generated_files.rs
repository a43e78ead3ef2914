//! The committed generated fixtures (`fixtures/generated/*.gltf`) equal what the generators in
//! `testmesh` produce today, and import with the counts the generators promise. Regenerate with
//! `cargo run -p furbake-import --example write_test_meshes`.

use std::path::Path;

use furbake_import::{ImportSettings, import_gltf, testmesh};

#[test]
fn committed_generated_fixtures_are_current_and_import() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/generated");
    let mut checked = 0;
    for (name, mesh) in testmesh::committed_meshes() {
        let path = dir.join(name);
        let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(bytes == mesh.gltf, "{name} is stale: run the write_test_meshes example");
        let imported = import_gltf(&path, &ImportSettings::default()).unwrap();
        assert_eq!(imported.mesh.positions.len(), mesh.vertices, "{name}");
        assert_eq!(imported.mesh.triangles.len(), mesh.triangles, "{name}");
        checked += 1;
    }
    assert_eq!(checked, 3);
}
