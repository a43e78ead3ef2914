//! Fixtures the render tests share: the headless device (one for the whole test binary), a furry
//! UV sphere baked in-process, the keyframe table of the default blade and a patch of blades.

use std::sync::{Arc, OnceLock};

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, KeyframeTable, Symmetry};
use furbake_grass::keyframes::PoseGridSettings;
use furbake_grass::{
    BladeFieldSettings, BladeMaterial, BladeShape, build_reference_blade, compress_poses, ground_grid_mesh,
    scatter_blades, simulate_poses,
};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::FurAsset;
use furbake_render::headless::HeadlessGpu;

/// The machine's adapter (lavapipe without a GPU); the tests never skip without one.
pub fn gpu() -> &'static HeadlessGpu {
    static GPU: OnceLock<HeadlessGpu> = OnceLock::new();
    GPU.get_or_init(|| HeadlessGpu::new().unwrap_or_else(|e| panic!("render tests need a wgpu adapter: {e}")))
}

/// A unit UV sphere (`rings` × `segments`) baked with the `fur` preset at `layers` shells of
/// `resolution`², fur `fur_m` long.
pub fn furry_sphere(rings: u32, segments: u32, layers: u32, resolution: u32, fur_m: f32) -> FurAsset {
    let gltf = testmesh::uv_sphere(rings, segments, 1.0).gltf;
    let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.layers, settings.volume.resolution) = (layers, resolution);
    settings.shells.fur_length_m = Some(fur_m);
    let baked = bake(&imported, "sphere", &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
    FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins).unwrap()
}

/// The default blade's keyframe table with `poses` poses (a multiple of 4 angles).
pub fn blade_table(poses: u32) -> KeyframeTable {
    let grid = PoseGridSettings { poses, ..Default::default() }.resolve(Symmetry::XZ).unwrap();
    let blade = build_reference_blade(&BladeShape::default()).unwrap();
    let poses = simulate_poses(&blade, &BladeMaterial::default(), grid).unwrap();
    let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
    compress_poses(&poses, Symmetry::XZ, stages, DisplacementEncoding::Snorm16).unwrap()
}

/// A 1.5 m square patch of `density` blades/m² in clumps of 0.25 m.
pub fn blade_patch(density: f32) -> BladeField {
    let settings = BladeFieldSettings { density_per_m2: density, cluster_size_m: 0.25, ..Default::default() };
    scatter_blades(&ground_grid_mesh([1.5, 1.5], [3, 3]), &settings).unwrap()
}

/// [`blade_table`] with 100 poses, made once.
pub fn default_blade_table() -> &'static KeyframeTable {
    static TABLE: OnceLock<KeyframeTable> = OnceLock::new();
    TABLE.get_or_init(|| blade_table(100))
}

/// [`blade_patch`] at 200 blades/m², made once.
pub fn default_blade_patch() -> &'static BladeField {
    static FIELD: OnceLock<BladeField> = OnceLock::new();
    FIELD.get_or_init(|| blade_patch(200.0))
}
