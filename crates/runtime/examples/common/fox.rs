//! The bundled Fox baked as `make demo` bakes it, for the examples that run it.

use std::path::{Path, PathBuf};

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_import::{ImportSettings, import_gltf};

/// Bakes `fixtures/real/Fox.glb` (`--preset fur --topology prisms`) into `dir/fox.fbk` and returns
/// its welded skin (the scale vectors' order).
pub fn bake_fox(dir: &Path) -> SkinMesh {
    let fox = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let imported = import_gltf(&fox, &ImportSettings::default()).expect("the bundled Fox imports");
    let mut settings = BakeSettings::preset("fur").expect("the fur preset");
    settings.topologies = vec!["prisms".into()];
    let baked = bake(&imported, "Fox.glb", &settings.plan().expect("valid settings"), &mut NoProgress).expect("bakes");
    baked.to_writer().write_atomic(&dir.join("fox.fbk")).expect("writes the pack");
    imported.mesh
}
