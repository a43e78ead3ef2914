//! furbake-bake: the bake pipeline — from an imported skin mesh and a validated [`BakeSettings`]
//! plan to the typed sections of one pack. No file formats of its own (those are in
//! `furbake-formats`), no glTF parsing (in `furbake-import`), no CLI.
//!
//! [`bake`] reads as the pipeline's table of contents: derive the fur length and texel density,
//! grow the hair volume and slice it into shell and fin atlases (fur thesis §3.1), map every
//! triangle on its own (§3.2), find the fin edges (§3.2), carry the imported skeleton, skin
//! weights, morph targets and clips through (glTF 2.0 "Skins", "Morph Targets", "Animations"),
//! and record the manifest. [`estimate_bake_memory`] tells a caller, before any stage runs, about
//! how much memory a plan will take on a mesh ([`budget`]), so it can refuse a plan over budget.
//!
//! ```
//! use furbake_bake::{BakeSettings, bake, NoProgress};
//! use furbake_import::{import_gltf_slice, testmesh};
//!
//! let gltf = testmesh::uv_sphere(8, 12, 1.0).gltf;
//! let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &Default::default())?;
//! let mut settings = BakeSettings::preset("fur")?;
//! settings.volume.resolution = 32; // keep the doctest quick
//! let baked = bake(&imported, "sphere.gltf", &settings.plan()?, &mut NoProgress)?;
//! assert_eq!(baked.uv_map.corners.len(), baked.mesh.triangles.len());
//! let bytes = baked.to_writer().to_bytes();
//! assert!(furbake_formats::Pack::from_bytes(&bytes).is_ok());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]
pub mod budget;
pub mod fin_edges;
pub mod rng;
pub mod settings;
pub mod uv_map;
pub mod validate;
pub mod volume;

use furbake_formats::PackWriter;
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::keyframe_table::KeyframeTable;
use furbake_formats::sections::manifest::{BakeManifest, ManifestInput};
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind};
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_import::{ImportedAnimation, ImportedMesh};

pub use budget::{MemoryEstimate, MemoryPart, estimate_bake_memory};
pub use settings::{BakeSettings, BladeSettings, SettingsError, ShellSettings};
pub use validate::BakePlan;

/// Why a bake failed.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// A setting is out of range, unknown, or too large for the mesh. Blame: the caller's
    /// settings. The message starts with the setting's key.
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// The hair volume parameters are invalid.
    #[error(transparent)]
    Volume(#[from] volume::VolumeError),
    /// The grass-blade stages failed (bad blade settings, or a mesh blades cannot grow on).
    #[error(transparent)]
    Grass(#[from] furbake_grass::GrassError),
    /// A mass–spring topology cannot be built on the mesh.
    #[error(transparent)]
    Topology(#[from] furbake_sim::SimError),
    /// The mesh cannot carry fur (e.g. the fur mask selects no triangle).
    #[error("{input}: {what}")]
    Mesh {
        /// Input name.
        input: String,
        /// What is wrong.
        what: String,
    },
}

impl BakeError {
    /// True when the caller's settings are to blame (a usage error: the CLI exits 2), false when
    /// the input mesh is (exit 1). Settings errors keep this blame through every layer: a
    /// parameter or limit refused by the volume, grass or topology stage is the settings' fault.
    pub fn is_settings_error(&self) -> bool {
        match self {
            BakeError::Settings(_) | BakeError::Volume(_) => true,
            BakeError::Grass(e) => matches!(
                e,
                furbake_grass::GrassError::Parameter { .. }
                    | furbake_grass::GrassError::Limit { .. }
                    | furbake_grass::GrassError::NotConverged { .. }
            ),
            BakeError::Topology(e) => matches!(e, furbake_sim::SimError::Parameter { .. }),
            BakeError::Mesh { .. } => false,
        }
    }
}

/// The stages of [`bake`], reported to a [`Progress`] as they start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Growing hairs and slicing the shell and fin atlases.
    Volume,
    /// Mapping every triangle into the texture.
    UvMap,
    /// Finding fin edges.
    FinEdges,
    /// Scattering grass blades and simulating their keyframe table (only with blades).
    Blades,
    /// Building the mass–spring topologies (only when some are asked for).
    Topologies,
}

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 5] = [Stage::Volume, Stage::UvMap, Stage::FinEdges, Stage::Blades, Stage::Topologies];

    /// Stable identifier (`volume`, `uv_map`, `fin_edges`, `blades`, `topologies`), as machine
    /// reports name the stage.
    pub fn id(self) -> &'static str {
        match self {
            Stage::Volume => "volume",
            Stage::UvMap => "uv_map",
            Stage::FinEdges => "fin_edges",
            Stage::Blades => "blades",
            Stage::Topologies => "topologies",
        }
    }

    /// Short human name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Volume => "hair volume, shell and fin atlases",
            Stage::UvMap => "per-triangle UV map",
            Stage::FinEdges => "fin edges",
            Stage::Blades => "grass blades and keyframes",
            Stage::Topologies => "mass-spring topologies",
        }
    }
}

/// Receives stage notifications (the CLI drives a progress bar with them).
pub trait Progress {
    /// Stage `stage` starts.
    fn stage(&mut self, stage: Stage);
}

/// A [`Progress`] that ignores everything.
pub struct NoProgress;

impl Progress for NoProgress {
    fn stage(&mut self, _: Stage) {}
}

/// Every artifact of one bake, typed.
#[derive(Clone, Debug)]
pub struct BakedPack {
    /// Provenance and parameters.
    pub manifest: BakeManifest,
    /// The welded skin.
    pub mesh: SkinMesh,
    /// Shell slices and shadow table.
    pub shells: ShellAtlas,
    /// Fin texture.
    pub fins: FinAtlas,
    /// Per-triangle UVs.
    pub uv_map: TriangleUvMap,
    /// Fin-carrying edges.
    pub fin_edges: FinEdges,
    /// Grass blades and their keyframe table, when the settings ask for blades.
    pub blades: Option<(BladeField, KeyframeTable)>,
    /// The mass–spring topologies asked for, in settings order.
    pub topologies: Vec<SpringTopology>,
    /// The skeleton, skin weights, morph targets and clips of an animated input (all `None`
    /// for a static one, whose pack is then byte-identical to before they existed).
    pub animation: ImportedAnimation,
}

impl BakedPack {
    /// The container holding every section, manifest first.
    pub fn to_writer(&self) -> PackWriter {
        let mut w = PackWriter::new();
        w.push_section(&self.manifest)
            .push_section(&self.mesh)
            .push_section(&self.shells)
            .push_section(&self.fins)
            .push_section(&self.uv_map);
        w.push(
            <FinEdges as furbake_formats::Section>::KIND,
            <FinEdges as furbake_formats::Section>::VERSION,
            self.fin_edges.encode_with_bounds(self.mesh.positions.len(), self.mesh.triangles.len()),
        );
        if let Some((field, keyframes)) = &self.blades {
            w.push_section(field).push_section(keyframes);
        }
        for t in &self.topologies {
            w.push_section(t);
        }
        let a = &self.animation;
        if let Some(s) = &a.skeleton {
            w.push_section(s);
        }
        if let Some(s) = &a.skin_weights {
            w.push_section(s);
        }
        if let Some(m) = &a.morph_targets {
            w.push_section(m);
        }
        if let Some(c) = &a.clips {
            w.push_section(c);
        }
        w
    }
}

/// Runs the whole pipeline on an imported mesh with settings validated when they were planned
/// ([`BakeSettings::plan`]); what depends on the mesh's size is checked first
/// ([`validate::check_against_mesh`]), and no stage starts before it passes.
pub fn bake(
    input: &ImportedMesh,
    input_name: &str,
    plan: &BakePlan,
    progress: &mut dyn Progress,
) -> Result<BakedPack, BakeError> {
    let settings = plan.settings();
    validate::check_against_mesh(settings, &input.mesh)?;
    let mesh = &input.mesh;
    if mesh.furry_triangles() == 0 {
        return Err(BakeError::Mesh { input: input_name.into(), what: "the fur mask selects no triangle".into() });
    }
    let fur_length_m = fur_length(mesh, &settings.shells);
    let repeat_m = settings.uv.repeat_m.unwrap_or(4.0 * fur_length_m);

    progress.stage(Stage::Volume);
    let (shells, fins) =
        volume::bake_volume(&settings.volume, rng::derive_seed(settings.seed, rng::stage::VOLUME, 0), fur_length_m)?;

    progress.stage(Stage::UvMap);
    let uv_map = uv_map::map_triangles(mesh, repeat_m, settings.uv.random_offset, settings.seed);

    progress.stage(Stage::FinEdges);
    let fin_edges = fin_edges::find_fin_edges(mesh);

    let blades = match &settings.blades {
        Some(b) => {
            progress.stage(Stage::Blades);
            let mut field_settings = b.field;
            field_settings.seed = rng::derive_seed(settings.seed, rng::stage::BLADES, b.field.seed);
            Some((
                furbake_grass::scatter_blades(mesh, &field_settings)?,
                furbake_grass::bake_keyframe_table(&b.keyframes)?,
            ))
        }
        None => None,
    };

    let mut topologies = Vec::with_capacity(settings.topologies.len());
    if !settings.topologies.is_empty() {
        progress.stage(Stage::Topologies);
        // The physics drives the shells: same fur length, one chain mass per shell layer.
        let params = furbake_formats::sections::spring_topology::TopologyParams {
            fur_length_m,
            chain_layers: settings.volume.layers,
            ..settings.topology.clone()
        };
        for name in &settings.topologies {
            let kind = TopologyKind::from_name(name).expect("validate() checked every topology name");
            topologies.push(furbake_sim::build_topology(mesh, kind, &params)?);
        }
    }

    let animation = input.animation.clone();

    let manifest = record_manifest(input, input_name, settings);
    Ok(BakedPack { manifest, mesh: mesh.clone(), shells, fins, uv_map, fin_edges, blades, topologies, animation })
}

/// The fur length in metres: the explicit setting, or a fraction of the bounding-box diagonal.
pub fn fur_length(mesh: &SkinMesh, shells: &ShellSettings) -> f32 {
    if let Some(l) = shells.fur_length_m {
        return l;
    }
    let (lo, hi) = mesh.bounds();
    let diag = glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let l = diag * shells.auto_fur_length_fraction;
    if l.is_finite() && l > 0.0 { l } else { 1e-3 }
}

fn record_manifest(input: &ImportedMesh, input_name: &str, settings: &BakeSettings) -> BakeManifest {
    BakeManifest {
        tool: "furbake".into(),
        tool_version: env!("CARGO_PKG_VERSION").into(),
        input_name: input_name.into(),
        input_bytes: input.input_bytes,
        input_sha256: input.input_sha256.clone(),
        preset: settings.preset.clone(),
        seed: settings.seed,
        settings_json: serde_json::to_string(settings).expect("settings are plain serde structs"),
        inputs: input
            .inputs
            .iter()
            .map(|f| ManifestInput { name: f.name.clone(), bytes: f.bytes, sha256: f.sha256.clone() })
            .collect(),
    }
}
