//! furbake-runtime: what a game or tool links to use baked furbake packs — describe a scene
//! ([`Scene`]: packs, camera, light, solver, the effects it wants and timed events) and run it
//! ([`World`]): only the stages the scene's effects call for are built, and only the sections
//! those stages use are read (docs/design.md "Runtime: scenes and stages", the user's ask 3). No
//! CLI, no GPU code (rendering is `furbake-render`, which draws a world's state), no baking.
//!
//! Packs are opened with the one reader, [`Pack`] (re-exported from `furbake-formats`): its
//! header and section table are validated at open; each section is read, checksummed and decoded
//! the first time it is asked for and shared afterwards ([`Pack::read_counts`] shows which ones
//! were touched). A scene is parsed from TOML and validated once; a [`World`] plans its stages from
//! the scene's [`Effects`] ([`stages`]: no effect, no stage; without parting a non-separable
//! topology, with parting a separable one), then each [`World::step`] applies the events due and
//! advances one `time_step_s`, leaving per pack the fur scale vectors (eq. 3.35, after the
//! wrong-side guard of §3.4.3) and the grass forces. [`World::stage_stats`] counts each stage's
//! runs and wall time; [`World::pack_state`] reports a pack's state in world space. A host that
//! budgets memory or checks the stages before building the world plans it first
//! ([`WorldPlan`]: each pack file opened once, the stages, the memory each entry will hold) and
//! builds the world from that plan.
//! [`animation`] is the CPU reference of character animation — clip sampling, a clip player
//! with cross-fades, joint and skinning matrices, morph-then-skin of positions and normals — on
//! a pack's skeleton, skin weights, morph targets and clips; the [`World`] drives it for packs
//! whose scene entry names a clip (`animation = { clip = "Walk" }`) and drags the fur with the
//! posed skin.
//!
//! ```
//! use furbake_bake::{BakeSettings, NoProgress, bake};
//! use furbake_formats::SectionKind;
//! use furbake_import::{import_gltf_slice, testmesh};
//! use furbake_runtime::{Scene, StageKind, World};
//!
//! // Bake a small furry sphere with a prisms topology into a pack on disk.
//! let dir = tempfile::tempdir()?;
//! let gltf = testmesh::uv_sphere(6, 8, 0.5).gltf;
//! let mesh = import_gltf_slice(&gltf, "sphere.gltf", None, &Default::default())?;
//! let mut settings = BakeSettings::preset("fur")?;
//! (settings.volume.resolution, settings.volume.layers) = (16, 4);
//! settings.topologies = vec!["prisms".into()];
//! bake(&mesh, "sphere.gltf", &settings.plan()?, &mut NoProgress)?.to_writer().write_atomic(&dir.path().join("ball.fbk"))?;
//!
//! // A scene with gravity and nothing else: no wind stage, no grass stage.
//! let scene = Scene::from_toml_str(
//!     r#"
//!     time_step_s = 0.02
//!     [[packs]]
//!     name = "ball"
//!     path = "ball.fbk"
//!     [effects.gravity]
//!     "#,
//!     "scene.toml".as_ref(),
//!     dir.path(),
//! )?;
//! let mut world = World::new(scene)?;
//! assert!(world.has_stage(StageKind::FurSolver) && !world.has_stage(StageKind::FurWind));
//! for _ in 0..10 {
//!     world.step()?;
//! }
//! let fur = world.fur(0).expect("the pack has fur");
//! assert!(fur.scale_vectors.iter().flatten().all(|c| c.is_finite()));
//! let solver = world.stage_stats().into_iter().find(|s| s.name == "fur_solver").unwrap();
//! assert_eq!(solver.runs, 10);
//! assert!(!world.pack(0).kinds_read().contains(&SectionKind::SHELL_ATLAS), "physics reads no atlas");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Opening a pack reads nothing until asked:
//!
//! ```
//! use furbake_formats::{PackWriter, SectionKind, sections::fin_atlas::FinAtlas};
//! use furbake_runtime::Pack;
//!
//! let dir = tempfile::tempdir()?;
//! let path = dir.path().join("fins.fbk");
//! let fins = FinAtlas { width: 2, height: 2, slices: 20, alpha: vec![0, 255, 128, 9] };
//! PackWriter::new().push_section(&fins).write_atomic(&path)?;
//! let pack = Pack::open(&path)?;
//! assert!(pack.kinds_read().is_empty()); // opening reads no section
//! assert_eq!(pack.fin_atlas()?.alpha, fins.alpha);
//! assert_eq!(pack.kinds_read(), vec![SectionKind::FIN_ATLAS]);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![deny(missing_docs)]
pub mod animation;
mod frame;
mod plan;
pub mod scene;
pub mod stages;
mod world;

use std::path::PathBuf;

use furbake_formats::FormatError;
use furbake_sim::{SimError, TopologyKind};

pub use animation::{AnimatedSkin, AnimationError, AnimationPlayer, Animator, ClipPlayback, Pose};
pub use frame::{
    FUR_GUST_WAVELENGTH_M, FUR_WIND_N_PER_M_PER_S, GRASS_COLLIDER_FALLOFF, GRASS_COLLIDER_STRENGTH,
    GRASS_FORCE_PER_M_PER_S,
};
pub use furbake_formats::Pack;
pub use plan::{EntryMemory, WorldPlan};
pub use scene::{
    Ambient, Camera, Effect, Effects, Event, GrassCulling, Light, LightSource, Lighting, MAX_LIGHTS, PhysicsDevice,
    RenderOptions, Scene, SceneBuilder, SceneError, ScenePack, ShellBlendMode, Solver, SolverChoice,
};
pub use stages::{PlannedStage, StageKind, StageStats};
pub use world::{
    FurFrame, GPU_PHYSICS_STEPS_KEPT, GpuPhysicsSteps, GpuSkinPose, GpuStepInputs, GrassFrame,
    MAX_MASS_UPDATES_PER_STEP, PackState, ShellVertexLayout, World, WorldOptions,
};

/// Why a runtime operation failed.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// The pack file is unreadable or invalid, lacks a section the caller needs, or its sections
    /// disagree with one another (blame: the file or the OS; see [`FormatError`]).
    #[error(transparent)]
    Format(#[from] FormatError),
    /// The scene file is unreadable or invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The scene moves a pack's fur but the pack holds no topology the scene can use (blame: the
    /// bake settings, or the scene's `parting`).
    #[error(
        "{path}: the scene's effects need a {what} spring topology ({wanted}); the pack has {found} — bake it with `--topology {first}`",
        path = path.display(),
        what = if *separable { "separable" } else { "non-separable" },
        wanted = kind_list(wanted),
        found = if found.is_empty() { "none".to_string() } else { kind_list(found) },
        first = wanted.first().copied().unwrap_or(TopologyKind::PRISMS),
    )]
    MissingTopology {
        /// The pack file.
        path: PathBuf,
        /// True when the scene parts fur (`effects.parting`).
        separable: bool,
        /// The kinds that would do, most preferred first.
        wanted: Vec<TopologyKind>,
        /// The kinds the pack holds.
        found: Vec<TopologyKind>,
    },
    /// A pack cannot play what the scene asks (no clips, or no clip of that name). Blame: the
    /// scene.
    #[error("{path}: animation: {source}", path = path.display())]
    Animation {
        /// The pack file.
        path: PathBuf,
        /// What the player reported.
        #[source]
        source: AnimationError,
    },
    /// The caller passed something inconsistent (e.g. a pack list that does not match the scene).
    #[error("{what}")]
    Parameter {
        /// What is wrong.
        what: String,
    },
    /// The fur simulation of a pack failed (non-finite state, a step its solver refuses).
    #[error("{path}: fur simulation: {source}", path = path.display())]
    Simulation {
        /// The pack file.
        path: PathBuf,
        /// The simulator's error.
        #[source]
        source: SimError,
    },
}

fn kind_list(kinds: &[TopologyKind]) -> String {
    kinds.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", ")
}
