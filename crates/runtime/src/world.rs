//! [`World`]: a [`Scene`] made runnable. It opens the scene's packs, plans the stages the declared
//! effects need ([`crate::stages`]), reads only the sections those stages use, and advances one
//! time step per [`World::step`], leaving per pack what the renderer consumes: scale vectors per
//! shell vertex for fur (eq. 3.35, after the wrong-side guard of §3.4.3) and the cluster-corner
//! forces of the grass force field (grass thesis §3.2.2, eq. 3.6–3.8, 4.1, ch. 5), plus the force
//! scene for wind sources with delayed attenuation (§4.2), which are evaluated per blade.
//!
//! This file steps: it applies the scene's timed events (teleports, forces switched off or on),
//! runs the planned stages in order and counts them. Bringing scene quantities into each pack's
//! mesh frame is [`crate::frame`]'s job. [`World::pack_state`] reports a pack's state in world
//! space (skin, masses, velocities, scale vectors) for `furbake simulate --state-out`.

use std::sync::Arc;
use std::time::{Duration, Instant};

use furbake_formats::sections::blade_field::ClusterGrid;
use furbake_formats::sections::spring_topology::NO_MASS;
use furbake_formats::{PackSections, check_consistency};
use furbake_grass::{ForceField, ForceScene};
use furbake_sim::{
    ComputeModel, ForceSet, FrameMotion, GuardSettings, SimError, Simulator, SkinMove, SkinTransform, SolverKind,
    SolverSettings, StepStats, TopologyKind,
};
use glam::{Mat4, Vec3};
use rayon::prelude::*;
use serde::Serialize;

use crate::animation::Animator;
use crate::frame::{self, ForcesOn, MeshFrame};
use crate::scene::{Effect, Effects, Event, PhysicsDevice, Scene, ScenePack};
use crate::stages::{
    AUTO_ANIMATED_XPBD_ITERATIONS, NON_SEPARABLE_PREFERENCE, PackRole, PlannedStage, SEPARABLE_PREFERENCE, StageKind,
    StageStats, choose_solver, choose_topology,
};
use crate::{Pack, RuntimeError, WorldPlan};

/// Most mass updates (masses × substeps) one [`World::step`] may spend on one pack's fur: 2^22,
/// about a fifth of a second of one core for the implicit solver in a release build (measured
/// ~45 ns per mass update on the Fox's separable prisms). The solvers
/// split a step into substeps when forces or stiffness demand it (up to 10,000); on a large
/// topology that alone made one step cost seconds (the Fox's separable prisms under a gravity of
/// 1e9 m/s²), so a pack's substep limit is this budget over its mass count, and a step past it
/// fails with a simulation error instead of running long.
pub const MAX_MASS_UPDATES_PER_STEP: u64 = 1 << 22;

/// How a fur pack's scale vectors are indexed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ShellVertexLayout {
    /// One per skin-mesh vertex (non-separable topologies, and fur at rest).
    PerVertex,
    /// One per triangle corner, `3 × triangle + corner` (separable topologies: fur can part).
    PerCorner,
}

/// Choices a host makes when it builds a [`World`] (the scene says what happens; these say what
/// to measure).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorldOptions {
    /// Compute energy, its budget and the largest displacement every solver step (the statistics
    /// in [`FurFrame::last_step`]; costs a pass over the masses per step). Default false.
    pub step_statistics: bool,
    /// The host places packs frame by frame ([`World::set_model_matrix`]) instead of, or on top
    /// of, the scene's motion paths: with `object_motion` declared, every fur pack gets its
    /// inertial-force stage, whether or not the scene gives it motion keys. Default false.
    pub host_placement: bool,
}

/// The fur state of one pack after the latest step.
#[derive(Clone, Copy, Debug)]
pub struct FurFrame<'a> {
    /// Unit scale vector per shell vertex (eq. 3.35, after the guard); the rest normal `s = n`
    /// where the pack is not simulated or a vertex carries no fur.
    pub scale_vectors: &'a [[f32; 3]],
    /// How `scale_vectors` is indexed.
    pub layout: ShellVertexLayout,
    /// The simulated topology and its solver; `None` when no stage moves this pack's fur.
    pub simulation: Option<(TopologyKind, SolverKind)>,
    /// Statistics of the latest solver step (default before the first step or without one;
    /// energies only with [`WorldOptions::step_statistics`]).
    pub last_step: StepStats,
    /// The latest pose of the animated skin: its fastest anchor and whether that was a cut
    /// (default without an animation).
    pub skin_move: SkinMove,
}

/// The grass state of one pack after the latest step.
#[derive(Clone, Copy, Debug)]
pub struct GrassFrame<'a> {
    /// Force `(x, z)` at every cluster-grid corner, mesh frame (what
    /// `BladeRenderer::set_corner_forces` takes); delayed-attenuation sources are not in it.
    pub corner_forces: &'a [[f32; 2]],
    /// The grid the corners belong to.
    pub grid: ClusterGrid,
    /// The full field (delayed wind sources included, for CPU posing: `ForceField::blade_force`).
    pub field: &'a ForceField,
    /// The force scene the field was updated from, mesh frame (a renderer evaluates its delayed
    /// sources per blade from it).
    pub scene: &'a ForceScene,
}

impl GrassFrame<'_> {
    /// True when a wind source with delayed attenuation acts this step (the corner forces alone
    /// do not describe the blades' forces then).
    pub fn has_delayed_sources(&self) -> bool {
        self.scene.sources.iter().any(|s| s.delayed)
    }
}

/// One pack's state in world space (metres, seconds), as `furbake simulate --state-out` writes it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PackState {
    /// The pack's scene name.
    pub name: String,
    /// Skin-mesh vertex positions (the welded mesh's order), world metres.
    pub skin_positions_m: Vec<[f32; 3]>,
    /// The simulated topology (`None`: the fur is not simulated, the lists below are empty).
    pub topology: Option<String>,
    /// Mass positions in the topology's mass order (anchored masses included), world metres.
    pub mass_positions_m: Vec<[f32; 3]>,
    /// Mass velocities in world space (the frame's own motion included), m/s.
    pub mass_velocities_m_per_s: Vec<[f32; 3]>,
    /// Unit scale vectors per shell vertex in world space, laid out as `scale_layout` says.
    pub scale_vectors: Vec<[f32; 3]>,
    /// How `scale_vectors` is indexed.
    pub scale_layout: ShellVertexLayout,
}

struct FurSim {
    simulator: Simulator,
    topology: TopologyKind,
    forces: ForceSet,
    last: StepStats,
    last_move: SkinMove,
    /// With `[solver] device = "gpu"`: the steps' forces a renderer records (the simulator stays
    /// at its start state).
    gpu: Option<GpuSteps>,
}

/// How many steps a GPU-physics pack keeps for its renderer: a world may step this many times
/// between two frames.
pub const GPU_PHYSICS_STEPS_KEPT: usize = 16;

/// The forces of a GPU-physics pack's latest steps, a ring of [`GPU_PHYSICS_STEPS_KEPT`].
struct GpuSteps {
    forces: Vec<ForceSet>,
    /// Per kept step: the teleport (mesh frame, metres) that moves the fur at its start.
    teleports: Vec<[f32; 3]>,
    /// Teleports since the last step, applied at the start of the next.
    teleport_m: [f32; 3],
    /// Per kept step of an animated pack: the skin's skinning matrices and morph weights and the
    /// cut speed it was posed with before the step (`Simulator::pose_skin`), or `None`.
    skinning: Vec<Vec<Mat4>>,
    morph_weights: Vec<Vec<f32>>,
    cut_speeds: Vec<Option<f32>>,
    /// The pose of the step being taken (the animation stage runs before the solver stage).
    skinning_pending: Vec<Mat4>,
    morph_weights_pending: Vec<f32>,
    cut_pending: Option<f32>,
    dt_s: f64,
    /// Steps taken since the start (step `n` is slot `n % GPU_PHYSICS_STEPS_KEPT`).
    taken: u64,
    stable_step_s: f64,
    restoring_weight_n: f32,
}

impl GpuSteps {
    fn push(&mut self, forces: &ForceSet) {
        let slot = (self.taken % GPU_PHYSICS_STEPS_KEPT as u64) as usize;
        // clone_from keeps the slot's list of local forces: no allocation once warm.
        self.forces[slot].clone_from(forces);
        self.teleports[slot] = std::mem::take(&mut self.teleport_m);
        // Swaps: the ring's vectors were sized at the first pose, so no allocation once warm.
        std::mem::swap(&mut self.skinning[slot], &mut self.skinning_pending);
        std::mem::swap(&mut self.morph_weights[slot], &mut self.morph_weights_pending);
        self.cut_speeds[slot] = self.cut_pending.take();
        self.taken += 1;
    }

    /// Keeps the pose of the step being taken: `anim`'s skinning matrices and morph weights.
    fn pose(&mut self, anim: &Animator, cut_speed: f32) {
        copy_into(&mut self.skinning_pending, anim.skinning_matrices());
        copy_into(&mut self.morph_weights_pending, anim.morph_weights());
        self.cut_pending = Some(cut_speed);
    }

    /// Sizes the ring for a skin of `binds` skinning matrices and `targets` morph weights.
    fn reserve_poses(&mut self, binds: usize, targets: usize) {
        for v in self.skinning.iter_mut().chain(std::iter::once(&mut self.skinning_pending)) {
            v.resize(binds, Mat4::IDENTITY);
        }
        for v in self.morph_weights.iter_mut().chain(std::iter::once(&mut self.morph_weights_pending)) {
            v.resize(targets, 0.0);
        }
    }
}

/// Copies `from` into `to` (allocating only when the length changes).
fn copy_into<T: Copy>(to: &mut Vec<T>, from: &[T]) {
    if to.len() == from.len() {
        to.copy_from_slice(from);
    } else {
        to.clear();
        to.extend_from_slice(from);
    }
}

/// An animated GPU-physics pack's skin before a step ([`GpuStepInputs::pose`]): what its
/// renderer's skinning pass takes, from which the GPU blends the fur's anchors.
#[derive(Clone, Copy, Debug)]
pub struct GpuSkinPose<'a> {
    /// One per bind, `world(joint) × inverseBind` (`Animator::skinning_matrices`).
    pub skinning_matrices: &'a [Mat4],
    /// One per morph target (`Animator::morph_weights`).
    pub morph_weights: &'a [f32],
    /// The anchor speed above which the fur is carried along, mesh-frame m/s.
    pub cut_speed_m_per_s: f32,
}

/// One step a GPU-physics pack took ([`GpuPhysicsSteps::step`]).
#[derive(Clone, Copy, Debug)]
pub struct GpuStepInputs<'a> {
    /// The step's forces.
    pub forces: &'a ForceSet,
    /// The teleport that moves the fur at its start (mesh frame, metres; `Simulator::teleport`).
    pub teleport_m: [f32; 3],
    /// An animated pack's skin at the step's end, posed before the step (`Simulator::pose_skin`).
    pub pose: Option<GpuSkinPose<'a>>,
}

/// A pack whose fur physics runs on the GPU (`[solver] device = "gpu"`; [`World::gpu_physics`]):
/// what its renderer needs to build the compute solver and record the steps the world took.
#[derive(Clone, Copy)]
pub struct GpuPhysicsSteps<'a> {
    sim: &'a Simulator,
    steps: &'a GpuSteps,
    path: &'a std::path::Path,
}

impl std::fmt::Debug for GpuPhysicsSteps<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuPhysicsSteps").field("taken", &self.steps.taken).finish()
    }
}

impl<'a> GpuPhysicsSteps<'a> {
    /// The solver's model and start state (`Simulator::compute_model`).
    pub fn compute_model(&self) -> Result<ComputeModel, RuntimeError> {
        self.sim.compute_model().map_err(|source| RuntimeError::Simulation { path: self.path.to_path_buf(), source })
    }

    /// The solver's stable step for the pack's restoring weight, seconds (infinite for XPBD).
    pub fn stable_step_s(&self) -> f64 {
        self.steps.stable_step_s
    }

    /// The most substeps a step may take.
    pub fn max_substeps(&self) -> u32 {
        self.sim.settings().max_substeps
    }

    /// The restoring weight every step's forces carry (the pack's scale at time 0), newtons.
    pub fn restoring_weight_n(&self) -> f32 {
        self.steps.restoring_weight_n
    }

    /// The world's time step, seconds.
    pub fn dt_s(&self) -> f64 {
        self.steps.dt_s
    }

    /// Steps the world has taken.
    pub fn taken(&self) -> u64 {
        self.steps.taken
    }

    /// Step `n` (0-based): its forces, the teleport at its start and an animated skin's pose,
    /// while the world keeps them (its last [`GPU_PHYSICS_STEPS_KEPT`]); `None` before or after
    /// that.
    pub fn step(&self, n: u64) -> Option<GpuStepInputs<'a>> {
        let kept = self.steps.taken.saturating_sub(GPU_PHYSICS_STEPS_KEPT as u64);
        let slot = (n % GPU_PHYSICS_STEPS_KEPT as u64) as usize;
        let s = self.steps;
        (n >= kept && n < s.taken).then(|| GpuStepInputs {
            forces: &s.forces[slot],
            teleport_m: s.teleports[slot],
            pose: s.cut_speeds[slot].map(|cut| GpuSkinPose {
                skinning_matrices: &s.skinning[slot],
                morph_weights: &s.morph_weights[slot],
                cut_speed_m_per_s: cut,
            }),
        })
    }
}

struct FurState {
    sim: Option<FurSim>,
    /// Rest direction per shell vertex (the posed normals when animated): the scale vector where
    /// the simulation gives none.
    rest: Vec<[f32; 3]>,
    scale_vectors: Vec<[f32; 3]>,
    layout: ShellVertexLayout,
    /// Skin vertex of every shell vertex (per-corner layouts; empty per vertex).
    corner_vertices: Vec<u32>,
    /// Per shell vertex, the skin's transform (per-corner layouts; reused every step).
    shell_transforms: Vec<SkinTransform>,
}

impl FurState {
    /// Poses the fur on `anim`'s skin for the step of `dt_s` that follows (anchors, rest
    /// directions, and the rest scale vectors of fur that is not simulated). Fur whose physics
    /// runs on the GPU keeps the pose for its renderer, unless `on_cpu` (the world's first pose,
    /// which the GPU solver starts from).
    fn follow(
        &mut self,
        anim: &Animator,
        dt_s: f64,
        cut_speed: f32,
        path: &std::path::Path,
        on_cpu: bool,
    ) -> Result<(), RuntimeError> {
        if let Some(gpu) = self.sim.as_mut().and_then(|s| s.gpu.as_mut()).filter(|_| !on_cpu) {
            // The GPU blends the anchors from the skinning matrices itself (and draws from its
            // own scale vectors): nothing per vertex here.
            gpu.pose(anim, cut_speed);
            return Ok(());
        }
        let normals = anim.normals();
        if self.corner_vertices.is_empty() {
            self.rest.copy_from_slice(normals);
        } else {
            for ((r, t), &v) in self.rest.iter_mut().zip(&mut self.shell_transforms).zip(&self.corner_vertices) {
                *r = normals[v as usize];
                *t = anim.transforms()[v as usize];
            }
        }
        match &mut self.sim {
            Some(sim) => {
                let transforms =
                    if self.corner_vertices.is_empty() { anim.transforms() } else { &self.shell_transforms[..] };
                if let Some(gpu) = sim.gpu.as_mut() {
                    // The world's first pose: the simulator the GPU starts from is posed, and
                    // the ring is sized for the skin.
                    gpu.reserve_poses(anim.skinning_matrices().len(), anim.morph_weights().len());
                }
                sim.last_move = sim
                    .simulator
                    .pose_skin(transforms, dt_s, cut_speed)
                    .map_err(|source| RuntimeError::Simulation { path: path.to_path_buf(), source })?;
            }
            None => self.scale_vectors.copy_from_slice(&self.rest),
        }
        Ok(())
    }
}

struct GrassState {
    field: ForceField,
    scene: ForceScene,
    corner_forces: Vec<[f32; 2]>,
}

/// The placements a host gave one pack ([`World::set_model_matrix`]), newest last: scene time
/// and model matrix. Three keys are what the central differences of [`frame::path_motion`] read.
#[derive(Clone, Copy, Debug)]
struct HostTrack {
    keys: [(f64, Mat4); 3],
}

impl HostTrack {
    /// The key nearest to `t` (a later one on a tie).
    fn at(&self, t: f64) -> Mat4 {
        let mut best = self.keys[2];
        for k in self.keys.iter().rev() {
            if (k.0 - t).abs() < (best.0 - t).abs() {
                best = *k;
            }
        }
        best.1
    }

    /// Adds the placement at `t`: replaces the newest key when it has the same time.
    fn push(&mut self, t: f64, m: Mat4) {
        if self.keys[2].0 != t {
            self.keys.rotate_left(1);
        }
        self.keys[2] = (t, m);
    }
}

struct WorldPack {
    scene: ScenePack,
    /// Placements from the host, once it gave one (the scene's motion path before that).
    host: Option<HostTrack>,
    pack: Arc<Pack>,
    /// Sum of the teleports applied so far, world metres (on top of the motion path).
    teleported_m: Vec3,
    fur: Option<FurState>,
    grass: Option<GrassState>,
    /// The pack's animation, when the scene gives it one.
    anim: Option<Animator>,
    /// Model matrix and mesh frame at the start of the current step (computed once per step,
    /// read by every fur stage).
    step_frame: (Mat4, MeshFrame),
    /// This pack's planned stages in run order: the index in [`World::stages`], the kind, runs
    /// and total wall time.
    stage_runs: Vec<(usize, StageKind, u64, Duration)>,
    /// The error this pack's stages ended the current step with (reported by [`World::step`] in
    /// pack order, so the same error whichever worker ran first).
    failed: Option<RuntimeError>,
}

/// What a pack's stages read besides their own pack: the same for every pack in a step.
struct StepInputs<'a> {
    effects: &'a Effects,
    on: ForcesOn,
    interaction_point_m: Option<Vec3>,
}

impl WorldPack {
    /// Model matrix at `t`: teleports on top of the motion (the host's placements, else the
    /// scene's motion path on top of its placement).
    fn model_at(&self, t: f64) -> Mat4 {
        Mat4::from_translation(self.teleported_m) * self.motion_at(t)
    }

    /// The pack's motion at `t` without teleports (what inertial forces differentiate).
    fn motion_at(&self, t: f64) -> Mat4 {
        match &self.host {
            Some(track) => track.at(t),
            None => self.scene.model_at(t),
        }
    }
}

/// A running scene: its packs, its planned stages and their counters.
pub struct World {
    scene: Scene,
    packs: Vec<WorldPack>,
    stages: Vec<PlannedStage>,
    /// The scene's events in time order (stable among equal times); `next_event` is the first
    /// not yet applied.
    events: Vec<Event>,
    next_event: usize,
    forces_on: ForcesOn,
    /// The effects before the host's last edit (restored when it is refused; its lists keep their
    /// capacity, so edits do not allocate).
    effects_backup: Effects,
    interaction_point_m: Option<Vec3>,
    time_s: f64,
    steps: u64,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("packs", &self.packs.iter().map(|p| &p.scene.name).collect::<Vec<_>>())
            .field("stages", &self.stages)
            .field("time_s", &self.time_s)
            .finish()
    }
}

impl World {
    /// Opens every pack of `scene`, plans the stages its effects need and reads the sections
    /// those stages use (skin mesh and one spring topology per simulated fur pack, the blade
    /// field per grass pack with a force stage; the skin mesh of a fur pack at rest for its
    /// normals). Nothing else is read.
    pub fn new(scene: Scene) -> Result<World, RuntimeError> {
        World::with_options(scene, WorldOptions::default())
    }

    /// As [`World::new`], with `options`. Scene entries that name the same file share one opened
    /// pack, so its sections are read and decoded once however often the scene places it.
    pub fn with_options(scene: Scene, options: WorldOptions) -> Result<World, RuntimeError> {
        let opened = World::open_packs(&scene)?;
        World::with_packs(scene, opened, options)
    }

    /// Opens the packs of `scene` as [`World::with_options`] does — one [`Pack`] per file, shared
    /// by every entry that names it (`Arc::ptr_eq`), header and table validated, no section read —
    /// for a host that checks them (e.g. `Pack::verify`) before [`World::with_packs`].
    pub fn open_packs(scene: &Scene) -> Result<Vec<Arc<Pack>>, RuntimeError> {
        let mut opened: Vec<Arc<Pack>> = Vec::with_capacity(scene.packs.len());
        let mut by_file: Vec<(std::path::PathBuf, Arc<Pack>)> = Vec::new();
        for sp in &scene.packs {
            // The canonical path identifies the file (a missing file fails in `Pack::open`).
            let key = std::fs::canonicalize(&sp.path).unwrap_or_else(|_| sp.path.clone());
            let pack = match by_file.iter().find(|(k, _)| *k == key) {
                Some((_, p)) => Arc::clone(p),
                None => {
                    let p = Arc::new(Pack::open(&sp.path)?);
                    by_file.push((key, Arc::clone(&p)));
                    p
                }
            };
            opened.push(pack);
        }
        Ok(opened)
    }

    /// As [`World::with_options`] with the scene's packs opened by the caller (one per
    /// `scene.packs` entry, same order), e.g. to inspect their read counters. The grass force
    /// field at time 0 is computed here, outside the stage counters, so a renderer has forces
    /// before the first step.
    pub fn with_packs(scene: Scene, opened: Vec<Arc<Pack>>, options: WorldOptions) -> Result<World, RuntimeError> {
        WorldPlan::with_packs(scene, opened, options)?.build()
    }

    /// The world of a [`WorldPlan`] ([`WorldPlan::build`]): its packs, pack roles and stages as
    /// planned.
    pub(crate) fn from_plan(
        scene: Scene,
        opened: Vec<Arc<Pack>>,
        options: WorldOptions,
        roles: Vec<PackRole>,
        stages: Vec<PlannedStage>,
    ) -> Result<World, RuntimeError> {
        let packs: Vec<(ScenePack, Arc<Pack>)> = scene.packs.iter().cloned().zip(opened).collect();
        let mut world_packs = Vec::with_capacity(packs.len());
        for (i, (sp, pack)) in packs.into_iter().enumerate() {
            let planned = |k: StageKind| stages.iter().any(|s| s.pack == i && s.kind == k);
            let mut anim = match &sp.animation {
                Some(a) => {
                    let animator = Animator::new(&pack, a.clip.as_deref(), a.speed, a.looping, a.start_s)?;
                    // Every clip an event switches to must exist now, not mid-run.
                    for e in &scene.events {
                        if let Event::PlayClip { pack: name, clip, .. } = e {
                            if *name == sp.name {
                                animator
                                    .check_clip(clip)
                                    .map_err(|source| RuntimeError::Animation { path: pack.display_path(), source })?;
                            }
                        }
                    }
                    Some(animator)
                }
                None => None,
            };
            let fur = if roles[i].fur {
                let frame0 = MeshFrame::of(sp.model_at(0.0));
                let animated = sp.animation.is_some();
                let device = sp.physics_device.unwrap_or(scene.solver.device);
                let fur = FurInputs { simulate: planned(StageKind::FurSolver), animated, device, frame0: &frame0 };
                let mut fur = build_fur(&scene, &pack, fur, options)?;
                if let Some(a) = &anim {
                    // The fur starts in the bind pose: the first pose is a cut (speed 0).
                    fur.follow(a, scene.time_step_s as f64, 0.0, &sp.path, true)?;
                    if let Some(sim) = &fur.sim {
                        sim.simulator
                            .write_scale_vectors(&mut fur.scale_vectors)
                            .map_err(|source| RuntimeError::Simulation { path: sp.path.clone(), source })?;
                        fill_rest(&mut fur.scale_vectors, &fur.rest);
                    }
                }
                if let (Some(a), Some(true)) = (anim.as_mut(), fur.sim.as_ref().map(|s| s.gpu.is_some())) {
                    // From here on the GPU blends the skin (the renderer's skinning pass) and the
                    // fur's anchors (GPU physics) from the matrices: the step poses no vertex.
                    a.set_vertex_posing(false);
                }
                Some(fur)
            } else {
                None
            };
            let grass = if planned(StageKind::GrassForces) {
                let field = pack.blade_field()?;
                let corners = field.grid.corners();
                Some(GrassState {
                    field: ForceField::new(field.grid),
                    scene: ForceScene::default(),
                    corner_forces: vec![[0.0; 2]; corners],
                })
            } else {
                None
            };
            let model = sp.model_at(0.0);
            let step_frame = (model, MeshFrame::of(model));
            let stage_runs = stages
                .iter()
                .enumerate()
                .filter(|(_, s)| s.pack == i)
                .map(|(k, s)| (k, s.kind, 0, Duration::ZERO))
                .collect();
            world_packs.push(WorldPack {
                scene: sp,
                host: None,
                pack,
                teleported_m: Vec3::ZERO,
                fur,
                grass,
                anim,
                step_frame,
                stage_runs,
                failed: None,
            });
        }
        let interaction_point_m = scene.effects.interaction.and_then(|i| i.position).map(Vec3::from);
        let mut events = scene.events.clone();
        events.sort_by(|a, b| a.at_s().total_cmp(&b.at_s()));
        let effects_backup = scene.effects.clone();
        let mut world = World {
            scene,
            packs: world_packs,
            stages,
            events,
            next_event: 0,
            forces_on: ForcesOn::ALL,
            effects_backup,
            interaction_point_m,
            time_s: 0.0,
            steps: 0,
        };
        world.apply_events(0.0)?;
        let inputs = StepInputs {
            effects: &world.scene.effects,
            on: world.forces_on,
            interaction_point_m: world.interaction_point_m,
        };
        for p in &mut world.packs {
            update_grass(p, &inputs, 0.0);
        }
        Ok(world)
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The planned stages, in run order.
    pub fn stages(&self) -> &[PlannedStage] {
        &self.stages
    }

    /// True when a stage of `kind` was planned for any pack.
    pub fn has_stage(&self, kind: StageKind) -> bool {
        self.stages.iter().any(|s| s.kind == kind)
    }

    /// Runs and wall time of every planned stage, in run order.
    pub fn stage_stats(&self) -> Vec<StageStats> {
        self.stages
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let p = &self.packs[s.pack];
                let (runs, total) = p.stage_runs.iter().find(|r| r.0 == k).map_or((0, Duration::ZERO), |r| (r.2, r.3));
                StageStats { name: s.kind.name(), pack: p.scene.name.clone(), runs, total }
            })
            .collect()
    }

    /// Scene time, seconds (steps × `time_step_s`).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Number of packs (scene order).
    pub fn pack_count(&self) -> usize {
        self.packs.len()
    }

    /// Index of the pack named `name` in the scene.
    pub fn pack_index(&self, name: &str) -> Option<usize> {
        self.packs.iter().position(|p| p.scene.name == name)
    }

    /// The opened pack `index` (its read counters show what the world touched; a renderer
    /// shares its decoded sections instead of opening the file again).
    pub fn pack(&self, index: usize) -> &Arc<Pack> {
        &self.packs[index].pack
    }

    /// Model matrix of pack `index` at the current time (teleports, then the motion path, on top
    /// of the placement).
    pub fn model_matrix(&self, index: usize) -> Mat4 {
        self.packs[index].model_at(self.time_s)
    }

    /// True when force `effect` is declared and not switched off by an event.
    pub fn force_is_on(&self, effect: Effect) -> bool {
        self.scene.effects.has(effect) && self.forces_on.has(effect)
    }

    /// The fur state of pack `index`; `None` when the pack has no fur.
    pub fn fur(&self, index: usize) -> Option<FurFrame<'_>> {
        let f = self.packs[index].fur.as_ref()?;
        Some(FurFrame {
            scale_vectors: &f.scale_vectors,
            layout: f.layout,
            simulation: f.sim.as_ref().map(|s| (s.topology, s.simulator.settings().kind)),
            last_step: f.sim.as_ref().map(|s| s.last).unwrap_or_default(),
            skin_move: f.sim.as_ref().map(|s| s.last_move).unwrap_or_default(),
        })
    }

    /// The GPU side of pack `index` when its fur physics runs on the GPU (`[solver] device =
    /// "gpu"`): the solver's model and the forces of the steps taken, for a renderer to record;
    /// `None` for CPU physics or a pack without a simulation.
    pub fn gpu_physics(&self, index: usize) -> Option<GpuPhysicsSteps<'_>> {
        let p = self.packs.get(index)?;
        let sim = p.fur.as_ref()?.sim.as_ref()?;
        Some(GpuPhysicsSteps { sim: &sim.simulator, steps: sim.gpu.as_ref()?, path: &p.scene.path })
    }

    /// The animation of pack `index` — clip, skinning matrices, morph weights, skinned positions
    /// and normals of the latest step; `None` when the scene gives the pack none. A pack whose fur
    /// physics runs on the GPU has its vertex posing off after the world's first pose
    /// ([`Animator::set_vertex_posing`]: the GPU blends its skin and anchors from the matrices);
    /// [`World::animation_mut`] turns it back on for a host that reads its vertices.
    pub fn animation(&self, index: usize) -> Option<&Animator> {
        self.packs[index].anim.as_ref()
    }

    /// The grass state of pack `index`; `None` when the pack has no blades or no stage pushes
    /// them (they stay in their rest pose: zero corner forces).
    pub fn grass(&self, index: usize) -> Option<GrassFrame<'_>> {
        let g = self.packs[index].grass.as_ref()?;
        Some(GrassFrame { corner_forces: &g.corner_forces, grid: *g.field.grid(), field: &g.field, scene: &g.scene })
    }

    /// Pack `index`'s state in world space (see [`PackState`]); reads the skin mesh if no stage
    /// has. Allocates: meant for reports, not for every frame. A pack whose fur physics runs on
    /// the GPU has its state there: a [`RuntimeError::Parameter`].
    pub fn pack_state(&self, index: usize) -> Result<PackState, RuntimeError> {
        let p = &self.packs[index];
        if p.fur.as_ref().and_then(|f| f.sim.as_ref()).is_some_and(|s| s.gpu.is_some()) {
            return Err(RuntimeError::Parameter {
                what: format!(
                    "pack {:?}: its fur physics runs on the GPU ([solver] device = \"gpu\"), so the world holds no mass state",
                    p.scene.name
                ),
            });
        }
        let model = p.model_at(self.time_s);
        let (scale, rotation, origin) = model.to_scale_rotation_translation();
        let mesh = p.pack.skin_mesh()?;
        let skin = p.anim.as_ref().map_or(&mesh.positions[..], |a| a.positions());
        let skin_positions_m = skin.iter().map(|&x| model.transform_point3(Vec3::from(x)).to_array()).collect();
        let mut state = PackState {
            name: p.scene.name.clone(),
            skin_positions_m,
            topology: None,
            mass_positions_m: Vec::new(),
            mass_velocities_m_per_s: Vec::new(),
            scale_vectors: Vec::new(),
            scale_layout: ShellVertexLayout::PerVertex,
        };
        let Some(fur) = &p.fur else { return Ok(state) };
        state.scale_layout = fur.layout;
        state.scale_vectors =
            fur.scale_vectors.iter().map(|&s| (rotation * Vec3::from(s)).normalize_or_zero().to_array()).collect();
        let Some(sim) = &fur.sim else { return Ok(state) };
        state.topology = Some(sim.topology.to_string());
        // World velocity of a mass: the frame's own velocity at that point plus the mass's
        // velocity relative to the frame, rotated and scaled into world units.
        let motion = frame::path_motion(|t| p.motion_at(t), self.time_s, self.scene.time_step_s as f64);
        let positions = sim.simulator.positions();
        let velocities = sim.simulator.velocities();
        for (x, v) in positions.iter().zip(&velocities) {
            let xw = model.transform_point3(Vec3::from(*x));
            let vw = motion.velocity + motion.angular_velocity.cross(xw - origin) + rotation * Vec3::from(*v) * scale.x;
            state.mass_positions_m.push(xw.to_array());
            state.mass_velocities_m_per_s.push(vw.to_array());
        }
        Ok(state)
    }

    /// Places pack `index` at `model` (rotation, translation, positive uniform scale; world
    /// metres) for the end of the next step, replacing the scene's motion path from now on — a
    /// game's transform update. The inertial forces of `object_motion` come from the change
    /// between the placements the host gives, step after step (build the world with
    /// [`WorldOptions::host_placement`] so a pack without motion keys has that stage); the first
    /// placement continues from where the scene had the pack. Teleports still add on top.
    pub fn set_model_matrix(&mut self, index: usize, model: Mat4) -> Result<(), RuntimeError> {
        let p = self.packs.get_mut(index).ok_or_else(|| RuntimeError::Parameter {
            what: format!("pack {index} of a scene of {}", self.scene.packs.len()),
        })?;
        let (scale, _, _) = model.to_scale_rotation_translation();
        let uniform = (scale.x - scale.y).abs() <= 1e-4 * scale.x && (scale.x - scale.z).abs() <= 1e-4 * scale.x;
        if !(model.is_finite() && scale.x > 0.0 && uniform && model.determinant() > 0.0) {
            return Err(RuntimeError::Parameter {
                what: format!(
                    "pack {:?}: the model matrix must be finite: rotation, translation and a positive uniform scale",
                    p.scene.name
                ),
            });
        }
        let (t, dt) = (self.time_s, self.scene.time_step_s as f64);
        let track = p.host.get_or_insert_with(|| {
            let (before, now) = (p.scene.model_at(t - dt), p.scene.model_at(t));
            HostTrack { keys: [(t - dt, before), (t, now), (t, now)] }
        });
        track.push(t + dt, model);
        Ok(())
    }

    /// The effects the world runs with (the scene's, as the host last changed them).
    pub fn effects(&self) -> &Effects {
        &self.scene.effects
    }

    /// Lets the host change the declared effects' values for the next steps — wind, wind
    /// sources, gravity, colliders moving with the game's objects, the interaction brush: `edit`
    /// changes them in place, then they are validated as a scene's are. The stage plan was built
    /// from what the scene declared, so an edit may change values but not which effects are
    /// declared (declare it in the scene, even at zero strength, to drive it from the host). A
    /// refused edit leaves the previous effects in place. Allocates nothing once the lists have
    /// reached their size.
    pub fn update_effects(&mut self, edit: impl FnOnce(&mut Effects)) -> Result<(), RuntimeError> {
        self.effects_backup.clone_from(&self.scene.effects);
        edit(&mut self.scene.effects);
        let declared = |e: &Effects| e.declared().map(|(on, _)| on);
        let problem = if declared(&self.scene.effects) != declared(&self.effects_backup) {
            Some("an edit may change effects' values, not which effects are declared".to_string())
        } else {
            self.scene.check_effects().err().map(|(field, what)| format!("{field}: {what}"))
        };
        match problem {
            None => {
                self.interaction_point_m = self
                    .scene
                    .effects
                    .interaction
                    .and_then(|i| i.position)
                    .map(Vec3::from)
                    .or(self.interaction_point_m);
                Ok(())
            }
            Some(what) => {
                std::mem::swap(&mut self.scene.effects, &mut self.effects_backup);
                Err(RuntimeError::Parameter { what })
            }
        }
    }

    /// The animation of pack `index`, for the host to drive (switch clips, seek, change speed).
    pub fn animation_mut(&mut self, index: usize) -> Option<&mut Animator> {
        self.packs.get_mut(index)?.anim.as_mut()
    }

    /// Moves the interaction brush to `point_m` (world metres), or lifts it (`None`). Has an
    /// effect only when the scene declares `interaction`.
    pub fn set_interaction_point(&mut self, point_m: Option<[f32; 3]>) {
        self.interaction_point_m = point_m.map(Vec3::from);
    }

    /// Advances the scene by one `time_step_s`: applies the events due at the step's start,
    /// then runs every planned stage once. A scene of several packs steps them side by side on
    /// the current rayon thread pool (call it inside a host's own pool with `pool.install`); the
    /// results are the same for any number of threads, and nothing is allocated per step. After
    /// an error (a simulation that refuses its step or turns non-finite) the world is left
    /// mid-step and should be dropped; the error is the first pack's, in scene order.
    pub fn step(&mut self) -> Result<(), RuntimeError> {
        let dt = self.scene.time_step_s as f64;
        let t = self.time_s;
        self.apply_events(t)?;
        let inputs = StepInputs {
            effects: &self.scene.effects,
            on: self.forces_on,
            interaction_point_m: self.interaction_point_m,
        };
        let run = |p: &mut WorldPack| {
            let model = p.model_at(t);
            p.step_frame = (model, MeshFrame::of(model));
            for i in 0..p.stage_runs.len() {
                let started = Instant::now();
                if let Err(e) = run_stage(p, &inputs, p.stage_runs[i].1, t, dt) {
                    p.failed = Some(e);
                    return;
                }
                let r = &mut p.stage_runs[i];
                r.2 += 1;
                r.3 += started.elapsed();
            }
        };
        // A step's stages read nothing of another pack, so the packs step side by side, one per
        // worker (the characters of a crowd scale with the cores); each pack's arithmetic is the
        // same on any worker, so the results are identical for any thread count.
        if self.packs.len() > 1 {
            self.packs.par_iter_mut().for_each(run);
        } else {
            self.packs.iter_mut().for_each(run);
        }
        if let Some(e) = self.packs.iter_mut().find_map(|p| p.failed.take()) {
            return Err(e);
        }
        self.time_s = (self.steps + 1) as f64 * dt;
        self.steps += 1;
        Ok(())
    }

    /// Applies every event due at `t`: at or before it, within a thousandth of a step (scene
    /// times are multiples of an `f32` step, so an event at 0.05 s is due at the step that starts
    /// at 5 × 0.01f32 = 0.0499999989 s).
    fn apply_events(&mut self, t: f64) -> Result<(), RuntimeError> {
        let due = t + 1e-3 * self.scene.time_step_s as f64;
        while let Some(event) = self.events.get(self.next_event).filter(|e| e.at_s() <= due) {
            match event {
                Event::Teleport { pack, offset_m, .. } => {
                    let i = self.pack_index(pack).ok_or_else(|| RuntimeError::Parameter {
                        what: format!("a teleport names pack {pack:?}, which the scene does not have"),
                    })?;
                    let p = &mut self.packs[i];
                    let offset = Vec3::from(*offset_m);
                    let frame = MeshFrame::of(p.model_at(t));
                    p.teleported_m += offset;
                    if let Some(sim) = p.fur.as_mut().and_then(|f| f.sim.as_mut()) {
                        let o = frame.vector(offset).to_array();
                        match sim.gpu.as_mut() {
                            // The GPU moves the fur at the start of the next step it records.
                            Some(gpu) => gpu.teleport_m = (Vec3::from(gpu.teleport_m) + Vec3::from(o)).to_array(),
                            None => sim.simulator.teleport(o),
                        }
                    }
                }
                Event::PlayClip { pack, clip, fade_s, .. } => {
                    let i = self.pack_index(pack).ok_or_else(|| RuntimeError::Parameter {
                        what: format!("play_clip names pack {pack:?}, which the scene does not have"),
                    })?;
                    let p = &mut self.packs[i];
                    let path = p.pack.display_path();
                    let anim = p.anim.as_mut().ok_or_else(|| RuntimeError::Parameter {
                        what: format!("play_clip: pack {pack:?} has no animation in the scene"),
                    })?;
                    anim.play(clip, *fade_s).map_err(|source| RuntimeError::Animation { path, source })?;
                }
                Event::ForcesOff { effects, .. } => self.forces_on.set(effects, false),
                Event::ForcesOn { effects, .. } => self.forces_on.set(effects, true),
            }
            self.next_event += 1;
        }
        Ok(())
    }
}

/// Runs one stage of pack `p` for the step from `t` to `t + dt`.
fn run_stage(p: &mut WorldPack, inputs: &StepInputs, kind: StageKind, t: f64, dt: f64) -> Result<(), RuntimeError> {
    if kind == StageKind::GrassForces {
        update_grass(p, inputs, t + dt);
        return Ok(());
    }
    if kind == StageKind::Animation {
        let Some(anim) = p.anim.as_mut() else { return Ok(()) };
        anim.advance(dt as f32);
        // The path is built only for an error: a step allocates nothing.
        anim.update().map_err(|source| RuntimeError::Animation { path: p.pack.display_path(), source })?;
        // The cut speed is in world metres per second; the skin moves in the mesh frame,
        // which the pack's uniform scale maps to the world.
        let cut = p.scene.animation.as_ref().map_or(f32::INFINITY, |a| a.cut_speed_m_per_s) / p.step_frame.1.scale;
        if let Some(fur) = p.fur.as_mut() {
            fur.follow(anim, dt, cut, &p.scene.path, false)?;
        }
        return Ok(());
    }
    let (effects, on) = (inputs.effects, inputs.on);
    let (model, mesh_frame) = p.step_frame;
    let path = (kind == StageKind::FurObjectMotion).then(|| frame::path_motion(|t| p.motion_at(t), t, dt));
    // Only fur stages remain; the planner builds them only for packs with a simulation.
    let Some(fur) = p.fur.as_mut() else { return Ok(()) };
    let Some(sim) = fur.sim.as_mut() else { return Ok(()) };
    match kind {
        StageKind::FurObjectMotion => {
            sim.forces.motion = match (effects.object_motion, on.has(Effect::ObjectMotion), path) {
                (Some(m), true, Some(motion)) => frame::frame_motion(&motion, &mesh_frame, m.inertia_scale),
                _ => FrameMotion::default(),
            };
        }
        StageKind::FurGravity => {
            let g = effects.gravity.filter(|_| on.has(Effect::Gravity)).map_or([0.0; 3], |g| g.acceleration_m_per_s2);
            sim.forces.gravity_m_per_s2 = mesh_frame.vector(Vec3::from(g)).to_array();
        }
        StageKind::FurWind => {
            let origin = model.transform_point3(Vec3::ZERO);
            sim.forces.wind = Some(frame::fur_wind(effects, on, origin, &mesh_frame));
        }
        StageKind::FurInteraction => {
            sim.forces.local.clear();
            if let (Some(it), Some(point), true) =
                (effects.interaction, inputs.interaction_point_m, on.has(Effect::Interaction))
            {
                sim.forces.local.push(frame::interaction_force(&it, point, &mesh_frame));
            }
        }
        StageKind::FurSolver => {
            let path = &p.scene.path;
            let err = |source: SimError| RuntimeError::Simulation { path: path.clone(), source };
            sim.forces.restoring_weight_n = frame::restoring_weight(effects, &mesh_frame);
            if let Some(gpu) = sim.gpu.as_mut() {
                // The renderer steps the fur on the GPU with these forces.
                sim.forces.validate().map_err(err)?;
                gpu.push(&sim.forces);
                return Ok(());
            }
            sim.simulator.set_forces_from(&sim.forces).map_err(err)?;
            sim.last = sim.simulator.step(dt).map_err(err)?;
        }
        StageKind::FurScaleVectors if sim.gpu.is_some() => {}
        StageKind::FurScaleVectors => {
            let path = &p.scene.path;
            let err = |source: SimError| RuntimeError::Simulation { path: path.clone(), source };
            sim.simulator.write_scale_vectors(&mut fur.scale_vectors).map_err(err)?;
            fill_rest(&mut fur.scale_vectors, &fur.rest);
        }
        StageKind::GrassForces | StageKind::Animation => unreachable!("handled above"),
    }
    Ok(())
}

/// Recomputes the grass field of pack `p` for time `t` (no-op without a grass stage).
fn update_grass(p: &mut WorldPack, inputs: &StepInputs, t: f64) {
    let model = p.model_at(t);
    let Some(g) = p.grass.as_mut() else { return };
    frame::grass_force_scene(inputs.effects, inputs.on, t, &MeshFrame::of(model), &mut g.scene);
    g.field.update(&g.scene);
    for (out, f) in g.corner_forces.iter_mut().zip(&g.field.corner_forces) {
        *out = f.to_array();
    }
}

/// Reads what one fur pack needs: its skin mesh (rest normals), and when a solver stage is
/// planned, the one topology the scene calls for and a simulator over it.
/// The fur of `pack`, simulated when `inputs.simulate`, on `inputs.device`; the pack's uniform
/// scale at time 0 (`inputs.frame0`) brings the guard's impulse, a speed in world metres per
/// second, into the mesh's units, as the per-step forces are with the scale of their step
/// (`crate::frame`).
fn build_fur(
    scene: &Scene,
    pack: &Pack,
    inputs: FurInputs<'_>,
    options: WorldOptions,
) -> Result<FurState, RuntimeError> {
    let FurInputs { simulate, animated, device, frame0 } = inputs;
    let scale = frame0.scale;
    let mesh = pack.skin_mesh()?;
    let per_vertex: Vec<[f32; 3]> = mesh.normals.clone();
    if !simulate {
        return Ok(FurState {
            sim: None,
            scale_vectors: per_vertex.clone(),
            rest: per_vertex,
            layout: ShellVertexLayout::PerVertex,
            corner_vertices: Vec::new(),
            shell_transforms: Vec::new(),
        });
    }
    let parting = scene.effects.parting.is_some();
    let available: Vec<TopologyKind> = pack.topology_kinds()?.into_iter().map(|(_, k)| k).collect();
    let Some(kind) = choose_topology(&available, parting) else {
        let wanted: &[TopologyKind] = if parting { &SEPARABLE_PREFERENCE } else { &NON_SEPARABLE_PREFERENCE };
        return Err(RuntimeError::MissingTopology {
            path: pack.display_path(),
            separable: parting,
            wanted: wanted.to_vec(),
            found: available,
        });
    };
    let topology = pack.spring_topology(kind)?;
    let (layout, rest) = if kind.is_separable() {
        let rest = mesh.triangles.iter().flat_map(|t| t.map(|i| mesh.normals[i as usize])).collect::<Vec<_>>();
        (ShellVertexLayout::PerCorner, rest)
    } else {
        (ShellVertexLayout::PerVertex, per_vertex)
    };
    // The one cross-section check (formats): the topology was built on this skin mesh. After it,
    // the shell-vertex mapping below indexes `rest` in range.
    let sections = PackSections { mesh: Some(&mesh), topologies: &[&topology], ..PackSections::default() };
    check_consistency(pack.sections(), &sections).map_err(|e| e.with_path(&pack.display_path()))?;
    debug_assert!(topology.shell_vertex_masses.iter().all(|m| (m[0] == NO_MASS) == (m[1] == NO_MASS)));
    let guard = match scene.effects.wrong_side_guard {
        Some(g) => {
            GuardSettings { enabled: true, max_angle_deg: g.max_angle_deg, impulse_m_per_s: g.impulse_m_per_s / scale }
        }
        None => GuardSettings { enabled: false, ..GuardSettings::default() },
    };
    let solver = choose_solver(kind, scene.solver.kind, animated, device);
    let auto_xpbd = scene.solver.kind == crate::SolverChoice::Auto && solver == SolverKind::Xpbd && animated;
    let defaults = SolverSettings::of(solver);
    let masses = topology.mass_kg.len().max(1) as u64;
    let settings = SolverSettings {
        guard,
        track_energy: options.step_statistics,
        implicit_iterations: scene.solver.implicit_iterations,
        xpbd_iterations: if auto_xpbd { AUTO_ANIMATED_XPBD_ITERATIONS } else { scene.solver.xpbd_iterations },
        local_global_iterations: scene.solver.local_global_iterations,
        max_substeps: (MAX_MASS_UPDATES_PER_STEP / masses).clamp(1, defaults.max_substeps as u64) as u32,
        ..defaults
    };
    let sim_err = |source| RuntimeError::Simulation { path: pack.display_path(), source };
    let mut simulator = Simulator::new(&topology, settings).map_err(sim_err)?;
    let gpu = match device {
        PhysicsDevice::Cpu => None,
        PhysicsDevice::Gpu => Some(gpu_steps(scene, pack, &mut simulator, frame0)?),
    };
    // Every force stage overwrites its own term each step; a term without a stage stays off. The
    // restoring weight is set by the solver stage, in the mesh's units of its step.
    let forces = ForceSet::none();
    let mut scale_vectors = simulator.scale_vectors();
    fill_rest(&mut scale_vectors, &rest);
    let corner_vertices: Vec<u32> =
        if kind.is_separable() { mesh.triangles.iter().flatten().copied().collect() } else { Vec::new() };
    Ok(FurState {
        sim: Some(FurSim {
            simulator,
            topology: kind,
            forces,
            last: StepStats::default(),
            last_move: SkinMove::default(),
            gpu,
        }),
        scale_vectors,
        rest,
        layout,
        shell_transforms: vec![SkinTransform::IDENTITY; corner_vertices.len()],
        corner_vertices,
    })
}

/// What [`build_fur`] needs of a pack entry besides the scene and the pack.
struct FurInputs<'a> {
    /// A solver stage is planned.
    simulate: bool,
    /// The pack plays an animation.
    animated: bool,
    /// Where its physics runs (the entry's `physics_device`, else the scene's `[solver] device`).
    device: PhysicsDevice,
    /// Its mesh frame at time 0.
    frame0: &'a MeshFrame,
}

/// The GPU side of a simulated pack (`[solver] device = "gpu"`): refused for solvers without a
/// compute form; the stable step at the restoring weight of time 0 (an animated pack's ring of
/// skin poses is sized at its first pose).
fn gpu_steps(
    scene: &Scene,
    pack: &Pack,
    simulator: &mut Simulator,
    frame0: &MeshFrame,
) -> Result<GpuSteps, RuntimeError> {
    let path = pack.display_path();
    let err = |source| RuntimeError::Simulation { path: path.clone(), source };
    simulator.compute_model().map_err(err)?;
    let restoring_weight_n = frame::restoring_weight(&scene.effects, frame0);
    simulator.set_forces(ForceSet { restoring_weight_n, ..ForceSet::none() }).map_err(err)?;
    Ok(GpuSteps {
        forces: vec![ForceSet::none(); GPU_PHYSICS_STEPS_KEPT],
        teleports: vec![[0.0; 3]; GPU_PHYSICS_STEPS_KEPT],
        teleport_m: [0.0; 3],
        skinning: vec![Vec::new(); GPU_PHYSICS_STEPS_KEPT],
        morph_weights: vec![Vec::new(); GPU_PHYSICS_STEPS_KEPT],
        cut_speeds: vec![None; GPU_PHYSICS_STEPS_KEPT],
        skinning_pending: Vec::new(),
        morph_weights_pending: Vec::new(),
        cut_pending: None,
        dt_s: scene.time_step_s as f64,
        taken: 0,
        stable_step_s: simulator.stable_step_s(),
        restoring_weight_n,
    })
}

/// Where a shell vertex has no scale vector (no fur: `[0, 0, 0]`), its rest direction.
fn fill_rest(scale_vectors: &mut [[f32; 3]], rest: &[[f32; 3]]) {
    for (s, n) in scale_vectors.iter_mut().zip(rest) {
        if *s == [0.0; 3] {
            *s = *n;
        }
    }
}
