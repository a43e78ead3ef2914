//! The seed inputs every campaign mutates, made in-process and deterministically (so case `i` of
//! a campaign is the same mutant on every machine): packs baked by `furbake-bake` from the
//! generated test meshes and the bundled Fox with every topology kind between them, a small blade
//! field on the grass patch and on the Fox; the generated meshes as glTF JSON; the bundled `.glb`
//! files; and the fixture scenes.

use std::path::{Path, PathBuf};

use furbake_bake::{BakeSettings, BladeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};

/// The repository root (this crate lives in `crates/fuzz`).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A named seed input.
#[derive(Clone, Debug)]
pub struct Seed {
    /// Name for messages and reproducer files.
    pub name: String,
    /// The bytes.
    pub bytes: Vec<u8>,
}

/// The glTF JSON seeds: the generated test meshes (buffers embedded as `data:` URIs).
pub fn gltf_json_seeds() -> Vec<Seed> {
    let mut seeds: Vec<Seed> = testmesh::committed_meshes()
        .into_iter()
        .map(|(name, mesh)| Seed { name: name.to_owned(), bytes: mesh.gltf })
        .collect();
    seeds.push(Seed { name: "cube.gltf".into(), bytes: testmesh::cube(1.0).gltf });
    seeds
}

/// The binary glTF seeds bundled in `fixtures/real/`.
pub fn glb_seeds() -> std::io::Result<Vec<Seed>> {
    ["Fox.glb", "BoxVertexColors.glb"]
        .into_iter()
        .map(|name| Ok(Seed { name: name.into(), bytes: std::fs::read(repo_root().join("fixtures/real").join(name))? }))
        .collect()
}

/// The fixture scenes (`fixtures/scenes/*.toml`), sorted by name.
pub fn scene_seeds() -> std::io::Result<Vec<Seed>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(repo_root().join("fixtures/scenes"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    paths
        .into_iter()
        .map(|p| {
            let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            Ok(Seed { name, bytes: std::fs::read(&p)? })
        })
        .collect()
}

fn small_blades(density_per_m2: f32, cluster_size_m: f32) -> BladeSettings {
    let mut b = BladeSettings::default();
    b.field.density_per_m2 = density_per_m2;
    b.field.cluster_size_m = cluster_size_m;
    b.keyframes.grid.poses = 40;
    b
}

/// Bakes `gltf` with a small volume (16² × 4 layers), `topologies` and optionally blades.
fn bake_seed(name: &str, gltf: &[u8], topologies: &[&str], blades: Option<BladeSettings>) -> Result<Seed, String> {
    let mesh = import_gltf_slice(gltf, name, None, &ImportSettings::default()).map_err(|e| e.to_string())?;
    let mut settings = BakeSettings::preset("fur").map_err(|e| e.to_string())?;
    settings.volume.resolution = 16;
    settings.volume.layers = 4;
    settings.topologies = topologies.iter().map(|t| t.to_string()).collect();
    settings.blades = blades;
    let baked = bake(&mesh, name, &settings.plan().map_err(|e| format!("{name}: {e}"))?, &mut NoProgress)
        .map_err(|e| format!("{name}: {e}"))?;
    Ok(Seed { name: name.replace(".gltf", ".fbk").replace(".glb", ".fbk"), bytes: baked.to_writer().to_bytes() })
}

/// The base packs: a sphere with the chain topologies, the grass patch with blades and sticks,
/// a plane with a bare centre (fin edges on the fur boundary) and the Fox with prisms,
/// separable prisms and a small blade field. Every topology kind appears in one of them.
pub fn base_packs() -> Result<Vec<Seed>, String> {
    let fox = std::fs::read(repo_root().join("fixtures/real/Fox.glb")).map_err(|e| format!("Fox.glb: {e}"))?;
    Ok(vec![
        bake_seed(
            "sphere.gltf",
            &testmesh::uv_sphere(6, 8, 0.5).gltf,
            &["chain", "reduced-chain", "spring-sticks"],
            None,
        )?,
        bake_seed(
            "grass_patch.gltf",
            &testmesh::grass_patch(2.0).gltf,
            &["sticks", "separable-sticks", "prisms"],
            Some(small_blades(20.0, 0.5)),
        )?,
        bake_seed(
            "plane.gltf",
            &testmesh::plane_with_bare_region(4, 2.0).gltf,
            &["separable-spring-sticks", "prisms"],
            None,
        )?,
        // The Fox is ~100 units long (centimetres as metres): a sparse field of large clusters.
        bake_seed("Fox.glb", &fox, &["prisms", "separable-prisms"], Some(small_blades(0.02, 20.0)))?,
    ])
}
