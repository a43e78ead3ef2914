//! Packs the tests share, baked once per test binary.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use furbake_bake::{BakeSettings, NoProgress, bake, settings::dotted_override};
use furbake_import::{ImportSettings, import_gltf};

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A directory holding `fox.fbk` (the bundled Fox, CC-BY 4.0, fur with a prisms topology, small
/// atlas), `grass.fbk` (the grass patch with 400 blades/m²), `strip.fbk` (a skinned strip
/// with a morph target) and `plane.fbk` (a plane with a bare centre: fin edges along the fur's
/// border), baked once.
pub fn packs() -> &'static Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let small = ["volume.resolution=16", "volume.layers=4", "topologies=[\"prisms\"]"];
        bake_into(dir.path(), "fixtures/real/Fox.glb", "fur", &small, "fox.fbk");
        let grass = [&small[..], &["blades.field.density_per_m2=400"]].concat();
        bake_into(dir.path(), "fixtures/generated/grass_patch.gltf", "grass", &grass, "grass.fbk");
        // A skinned strip with a morph target (furbake_import::testmesh::SkinnedStrip).
        let strip = dir.path().join("strip.gltf");
        std::fs::write(&strip, furbake_import::testmesh::SkinnedStrip::default().to_gltf()).unwrap();
        bake_into(dir.path(), strip.to_str().unwrap(), "fur", &small, "strip.fbk");
        bake_into(dir.path(), "fixtures/generated/plane_bare_centre.gltf", "fur", &small, "plane.fbk");
        dir
    })
    .path()
}

fn bake_into(dir: &Path, gltf: &str, preset: &str, sets: &[&str], name: &str) {
    let mesh = import_gltf(&root().join(gltf), &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset(preset).unwrap();
    for set in sets {
        settings = settings.with_overrides(&dotted_override(set).unwrap()).unwrap();
    }
    let baked = bake(&mesh, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    baked.to_writer().write_atomic(&dir.join(name)).unwrap();
}
