//! Writes the generated test meshes as `.gltf` files into `fixtures/generated/` (the files the
//! demo and users can bake directly). `tests/generated_files.rs` checks the committed files still
//! equal what the generators produce. Run: `cargo run -p furbake-import --example write_test_meshes`.

use std::path::Path;

use furbake_import::testmesh;

fn main() -> std::io::Result<()> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/generated");
    std::fs::create_dir_all(&dir)?;
    for (name, mesh) in testmesh::committed_meshes() {
        std::fs::write(dir.join(name), &mesh.gltf)?;
        println!("wrote fixtures/generated/{name}: {} vertices, {} triangles", mesh.vertices, mesh.triangles);
    }
    Ok(())
}
