//! [`World`]: a [`Scene`] made runnable. It opens the scene's packs, plans the stages the declared
//! effects need ([`crate::stages`]), reads only the sections those stages use, and advances one
//! time step per [`World::step`], leaving per pack what the renderer consumes: scale vectors per
//! shell vertex for fur (eq. 3.35, after the wrong-side guard of §3.4.3) and the cluster-corner
//! forces of the grass force field (grass thesis §3.2.2, eq. 3.6–3.8, 4.1, ch. 5).
//!
//! Frames and units. The fur simulation runs in each pack's mesh frame, in the mesh's own units
//! (the topology was baked in them). Scene quantities are in world metres and are brought into
//! that frame with the pack's model matrix at the current time (`world = motion(t) · placement`,
//! rotation `R`, uniform scale `s`): directions are rotated by `R⁻¹`, lengths and accelerations
//! divided by `s`, forces divided by `s` (`F = m·a` with lengths in mesh units). Object motion is
//! the motion path differentiated over one time step `h`: linear acceleration
//! `(p(t+h) − 2p(t) + p(t−h))/h²`, angular velocity from `q(t+h)·q(t−h)⁻¹` over `2h` and angular
//! acceleration from the angular velocities at `t ± h` — a key's velocity change arrives as one
//! step of acceleration, as it would from a game's transform updates. Wind on fur is furbake-sim's
//! single travelling-gust wind: the scene's global wind plus every point wind source evaluated at
//! the pack's origin (eq. 4.1; the simulator has no per-mass source term).
//!
//! The grass force field is computed over the blade field's grid in the mesh frame: wind sources,
//! colliders and windless areas are moved into that frame (positions by the inverse model matrix,
//! radii by `1/s`, a source's power by `s^−σ` so eq. 4.1 gives the same force at the same world
//! distance), the global wind is rotated. Forces stay horizontal `(x, z)`; rotations about axes
//! other than +y are not meaningful for grass and windless boxes are bounded conservatively.

use std::sync::Arc;
use std::time::{Duration, Instant};

use furbake_formats::SectionKind;
use furbake_formats::sections::blade_field::ClusterGrid;
use furbake_formats::sections::spring_topology::NO_MASS;
use furbake_grass::{ForceField, ForceScene};
use furbake_sim::{
    ForceSet, FrameMotion, GuardParams, LocalForce, SimError, Simulator, SolverKind, SolverSettings, StepStats,
    TopologyKind, Wind,
};
use glam::{Mat4, Quat, Vec2, Vec3};

use crate::scene::{Collider, Scene, ScenePack};
use crate::stages::{
    NON_SEPARABLE_PREFERENCE, PackRole, PlannedStage, SEPARABLE_PREFERENCE, StageKind, StageStats, choose_solver,
    choose_topology, plan_stages,
};
use crate::{Pack, RuntimeError};

/// Mean wind force on one free fur mass per m/s of wind speed, newtons (world units). With the
/// default hair (1e-4 kg per hair) a 2 m/s breeze pushes a tip with 1e-4 N, furbake-sim's default
/// wind. Point wind sources count their eq. 4.1 strength as m/s of wind speed.
pub const FUR_WIND_N_PER_M_S: f32 = 5e-5;
/// Wavelength of the fur wind's travelling gust along the wind, world metres.
pub const FUR_GUST_WAVELENGTH_M: f32 = 4.0;
/// Grass force units per m/s of global wind (the keyframe tables are indexed by force magnitude).
pub const GRASS_FORCE_PER_M_S: f32 = 1.0;
/// Push of a collider on grass at and inside its surface, force units.
pub const GRASS_COLLIDER_STRENGTH: f32 = 2.0;
/// Distance beyond a collider's surface over which its push fades out, as a fraction of its
/// (smallest) radius.
pub const GRASS_COLLIDER_FALLOFF: f32 = 0.5;

/// How a fur pack's scale vectors are indexed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ShellVertexLayout {
    /// One per skin-mesh vertex (non-separable topologies, and fur at rest).
    PerVertex,
    /// One per triangle corner, `3 × triangle + corner` (separable topologies: fur can part).
    PerCorner,
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
    /// Statistics of the latest solver step (default before the first step or without one).
    pub last_step: StepStats,
}

/// The grass state of one pack after the latest step.
#[derive(Clone, Copy, Debug)]
pub struct GrassFrame<'a> {
    /// Force `(x, z)` at every cluster-grid corner, mesh frame (what
    /// `BladeRenderer::set_corner_forces` takes).
    pub corner_forces: &'a [[f32; 2]],
    /// The grid the corners belong to.
    pub grid: ClusterGrid,
    /// The full field (delayed wind sources included, for CPU posing).
    pub field: &'a ForceField,
}

struct FurSim {
    simulator: Simulator,
    topology: TopologyKind,
    forces: ForceSet,
    last: StepStats,
}

struct FurState {
    sim: Option<FurSim>,
    rest: Vec<[f32; 3]>,
    scale_vectors: Vec<[f32; 3]>,
    layout: ShellVertexLayout,
}

struct GrassState {
    field: ForceField,
    corner_forces: Vec<[f32; 2]>,
}

struct WorldPack {
    scene: ScenePack,
    pack: Arc<Pack>,
    fur: Option<FurState>,
    grass: Option<GrassState>,
}

/// A running scene: its packs, its planned stages and their counters.
pub struct World {
    scene: Scene,
    packs: Vec<WorldPack>,
    stages: Vec<PlannedStage>,
    stats: Vec<(u64, Duration)>,
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
        let mut opened = Vec::with_capacity(scene.packs.len());
        for sp in &scene.packs {
            opened.push(Arc::new(Pack::open(&sp.path)?));
        }
        World::with_packs(scene, opened)
    }

    /// As [`World::new`] with the scene's packs opened by the caller (one per `scene.packs`
    /// entry, same order), e.g. to share them with a renderer or to inspect their read counters.
    /// The grass force field at time 0 is computed here, outside the stage counters, so a
    /// renderer has forces before the first step.
    pub fn with_packs(scene: Scene, opened: Vec<Arc<Pack>>) -> Result<World, RuntimeError> {
        if opened.len() != scene.packs.len() {
            return Err(RuntimeError::Parameter {
                what: format!("{} packs opened for a scene of {}", opened.len(), scene.packs.len()),
            });
        }
        let packs: Vec<(ScenePack, Arc<Pack>)> = scene.packs.iter().cloned().zip(opened).collect();
        let roles: Vec<PackRole> = packs
            .iter()
            .map(|(sp, p)| PackRole {
                fur: p.has(SectionKind::SHELL_ATLAS) || p.has(SectionKind::SPRING_TOPOLOGY),
                grass: p.has(SectionKind::BLADE_FIELD),
                moving: sp.motion.len() > 1,
                topology: p.has(SectionKind::SPRING_TOPOLOGY),
            })
            .collect();
        let stages = plan_stages(&scene.effects, &roles);
        let mut world_packs = Vec::with_capacity(packs.len());
        for (i, (sp, pack)) in packs.into_iter().enumerate() {
            let planned = |k: StageKind| stages.iter().any(|s| s.pack == i && s.kind == k);
            let fur = if roles[i].fur { Some(build_fur(&scene, &pack, planned(StageKind::FurSolver))?) } else { None };
            let grass = if planned(StageKind::GrassForces) {
                let field = pack.blade_field()?;
                let corners = field.grid.corners();
                Some(GrassState { field: ForceField::new(field.grid), corner_forces: vec![[0.0; 2]; corners] })
            } else {
                None
            };
            world_packs.push(WorldPack { scene: sp, pack, fur, grass });
        }
        let interaction_point_m = scene.effects.interaction.and_then(|i| i.position).map(Vec3::from);
        let stats = vec![(0, Duration::ZERO); stages.len()];
        let mut world = World { scene, packs: world_packs, stages, stats, interaction_point_m, time_s: 0.0, steps: 0 };
        for i in 0..world.packs.len() {
            world.update_grass(i, 0.0);
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
            .zip(&self.stats)
            .map(|(s, &(runs, total))| StageStats {
                name: s.kind.name(),
                pack: self.packs[s.pack].scene.name.clone(),
                runs,
                total,
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

    /// The opened pack `index` (its read counters show what the world touched).
    pub fn pack(&self, index: usize) -> &Arc<Pack> {
        &self.packs[index].pack
    }

    /// Model matrix of pack `index` at the current time (motion path on top of the placement).
    pub fn model_matrix(&self, index: usize) -> Mat4 {
        self.packs[index].scene.model_at(self.time_s)
    }

    /// The fur state of pack `index`; `None` when the pack has no fur.
    pub fn fur(&self, index: usize) -> Option<FurFrame<'_>> {
        let f = self.packs[index].fur.as_ref()?;
        Some(FurFrame {
            scale_vectors: &f.scale_vectors,
            layout: f.layout,
            simulation: f.sim.as_ref().map(|s| (s.topology, s.simulator.settings().kind)),
            last_step: f.sim.as_ref().map(|s| s.last).unwrap_or_default(),
        })
    }

    /// The grass state of pack `index`; `None` when the pack has no blades or no stage pushes
    /// them (they stay in their rest pose: zero corner forces).
    pub fn grass(&self, index: usize) -> Option<GrassFrame<'_>> {
        let g = self.packs[index].grass.as_ref()?;
        Some(GrassFrame { corner_forces: &g.corner_forces, grid: *g.field.grid(), field: &g.field })
    }

    /// Moves the interaction brush to `point_m` (world metres), or lifts it (`None`). Has an
    /// effect only when the scene declares `interaction`.
    pub fn set_interaction_point(&mut self, point_m: Option<[f32; 3]>) {
        self.interaction_point_m = point_m.map(Vec3::from);
    }

    /// Advances the scene by one `time_step_s`, running every planned stage once. After an
    /// error (a simulation that refuses its step or turns non-finite) the world is left
    /// mid-step and should be dropped.
    pub fn step(&mut self) -> Result<(), RuntimeError> {
        let dt = self.scene.time_step_s as f64;
        let t = self.time_s;
        for k in 0..self.stages.len() {
            let (kind, pack) = (self.stages[k].kind, self.stages[k].pack);
            let started = Instant::now();
            self.run_stage(kind, pack, t, dt)?;
            let s = &mut self.stats[k];
            s.0 += 1;
            s.1 += started.elapsed();
        }
        self.time_s = (self.steps + 1) as f64 * dt;
        self.steps += 1;
        Ok(())
    }

    fn run_stage(&mut self, kind: StageKind, index: usize, t: f64, dt: f64) -> Result<(), RuntimeError> {
        if kind == StageKind::GrassForces {
            self.update_grass(index, t + dt);
            return Ok(());
        }
        let effects = &self.scene.effects;
        let p = &mut self.packs[index];
        let frame = || MeshFrame::at(&p.scene, t);
        // Only fur stages remain; the planner builds them only for packs with a simulation.
        let Some(sim) = p.fur.as_mut().and_then(|f| f.sim.as_mut()) else { return Ok(()) };
        match kind {
            StageKind::FurObjectMotion => {
                let scale = effects.object_motion.map_or(1.0, |m| m.inertia_scale);
                sim.forces.motion = frame_motion(&p.scene, t, dt, scale);
            }
            StageKind::FurGravity => {
                let g = effects.gravity.map_or([0.0; 3], |g| g.acceleration_m_s2);
                sim.forces.gravity_m_per_s2 = frame().vector(Vec3::from(g)).to_array();
            }
            StageKind::FurWind => {
                let frame = frame();
                // Global wind plus every point source evaluated at the pack's origin (eq. 4.1 in
                // 3D): furbake-sim has one wind per simulation, so sources act on fur uniformly.
                let origin = p.scene.model_at(t).transform_point3(Vec3::ZERO);
                let mut v = effects.wind.map_or(Vec3::ZERO, |w| Vec3::from(w.velocity_m_s));
                for s in &effects.wind_sources {
                    v += point_source_wind(s, origin);
                }
                let (amp, hz) = effects.wind.map_or((0.0, 0.0), |w| (w.gust_amplitude, w.gust_frequency_hz));
                sim.forces.wind = Some(Wind {
                    direction: (frame.rotation.inverse() * v).normalize_or_zero().to_array(),
                    force_n: FUR_WIND_N_PER_M_S * v.length() / frame.scale,
                    gust_amplitude: amp,
                    gust_frequency_hz: hz,
                    gust_wavelength_m: FUR_GUST_WAVELENGTH_M / frame.scale,
                });
            }
            StageKind::FurInteraction => {
                sim.forces.local.clear();
                if let (Some(it), Some(point)) = (effects.interaction, self.interaction_point_m) {
                    let frame = frame();
                    sim.forces.local.push(LocalForce {
                        point_m: frame.point(point).to_array(),
                        radius_m: it.radius_m / frame.scale,
                        strength_n: it.strength_n / frame.scale,
                    });
                }
            }
            StageKind::FurSolver => {
                let path = &p.scene.path;
                let err = |source: SimError| RuntimeError::Simulation { path: path.clone(), source };
                sim.simulator.set_forces(sim.forces.clone()).map_err(err)?;
                sim.last = sim.simulator.step(dt).map_err(err)?;
            }
            StageKind::FurScaleVectors => {
                let fur = p.fur.as_mut().expect("a simulation lives in a fur state");
                let sim = fur.sim.as_ref().expect("checked above");
                fur.scale_vectors = sim.simulator.scale_vectors();
                for (s, n) in fur.scale_vectors.iter_mut().zip(&fur.rest) {
                    if *s == [0.0; 3] {
                        *s = *n;
                    }
                }
            }
            StageKind::GrassForces => unreachable!("handled above"),
        }
        Ok(())
    }

    /// Recomputes the grass field of pack `index` for time `t` (no-op without a grass stage).
    fn update_grass(&mut self, index: usize, t: f64) {
        let effects = &self.scene.effects;
        let p = &mut self.packs[index];
        let Some(g) = p.grass.as_mut() else { return };
        let frame = MeshFrame::at(&p.scene, t);
        let mut scene = ForceScene::default();
        if let Some(w) = effects.wind {
            let gust = 1.0 + w.gust_amplitude * (std::f64::consts::TAU * w.gust_frequency_hz as f64 * t).sin() as f32;
            let v = frame.rotation.inverse() * Vec3::from(w.velocity_m_s);
            scene.global_wind = Vec2::new(v.x, v.z) * (GRASS_FORCE_PER_M_S * gust);
        }
        for s in &effects.wind_sources {
            scene.sources.push(furbake_grass::WindSource {
                position_m: frame.point(Vec3::from(s.position)),
                power: s.power * frame.scale.powf(-s.falloff_exponent),
                concentration: s.falloff_exponent,
                delayed: s.propagation_m_s.is_some(),
            });
        }
        for c in &effects.collisions {
            scene.colliders.push(match *c {
                Collider::Sphere { center, radius_m } => furbake_grass::Collider::Sphere {
                    center_m: frame.point(Vec3::from(center)),
                    radius_m: radius_m / frame.scale,
                    strength: GRASS_COLLIDER_STRENGTH,
                    falloff_m: GRASS_COLLIDER_FALLOFF * radius_m / frame.scale,
                },
                Collider::Ellipsoid { center, radii_m } => {
                    let r = Vec3::from(radii_m) / frame.scale;
                    furbake_grass::Collider::Ellipsoid {
                        center_m: frame.point(Vec3::from(center)),
                        radii_m: r,
                        strength: GRASS_COLLIDER_STRENGTH,
                        falloff_m: GRASS_COLLIDER_FALLOFF * r.min_element(),
                    }
                }
            });
        }
        for a in &effects.windless_areas {
            // The box's eight corners in the mesh frame, bounded in xz.
            let (lo, hi) = (Vec3::from(a.min), Vec3::from(a.max));
            let (mut min, mut max) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
            for k in 0..8 {
                let c = Vec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                );
                let m = frame.point(c);
                min = min.min(Vec2::new(m.x, m.z));
                max = max.max(Vec2::new(m.x, m.z));
            }
            scene.blockers.push(furbake_grass::WindBlocker { min_m: min, max_m: max });
        }
        g.field.update(&scene);
        for (out, f) in g.corner_forces.iter_mut().zip(&g.field.corner_forces) {
            *out = f.to_array();
        }
    }
}

/// Reads what one fur pack needs: its skin mesh (rest normals), and when a solver stage is
/// planned, the one topology the scene calls for and a simulator over it.
fn build_fur(scene: &Scene, pack: &Pack, simulate: bool) -> Result<FurState, RuntimeError> {
    let mesh = pack.skin_mesh()?;
    let per_vertex: Vec<[f32; 3]> = mesh.normals.clone();
    if !simulate {
        return Ok(FurState {
            sim: None,
            scale_vectors: per_vertex.clone(),
            rest: per_vertex,
            layout: ShellVertexLayout::PerVertex,
        });
    }
    let parting = scene.effects.parting.is_some();
    let available: Vec<TopologyKind> = pack.topology_kinds()?.into_iter().map(|(_, k)| k).collect();
    let Some(kind) = choose_topology(&available, parting) else {
        let wanted: &[TopologyKind] = if parting { &SEPARABLE_PREFERENCE } else { &NON_SEPARABLE_PREFERENCE };
        return Err(RuntimeError::MissingTopology {
            path: pack.path().to_path_buf(),
            separable: parting,
            wanted: wanted.to_vec(),
            found: available,
        });
    };
    let topology = pack.spring_topology(kind)?;
    let (v, f) = (mesh.positions.len(), mesh.triangles.len());
    let (layout, rest) = if kind.is_separable() {
        let rest = mesh.triangles.iter().flat_map(|t| t.map(|i| mesh.normals[i as usize])).collect::<Vec<_>>();
        (ShellVertexLayout::PerCorner, rest)
    } else {
        (ShellVertexLayout::PerVertex, per_vertex)
    };
    let s = &topology.stats;
    if s.source_vertices as usize != v
        || s.source_triangles as usize != f
        || topology.shell_vertex_masses.len() != rest.len()
    {
        return Err(RuntimeError::InvalidPack {
            path: pack.path().to_path_buf(),
            what: format!(
                "the {kind} topology was built on {} vertices / {} triangles with {} shell vertices; the skin mesh has {v} / {f}",
                s.source_vertices,
                s.source_triangles,
                topology.shell_vertex_masses.len()
            ),
        });
    }
    debug_assert!(topology.shell_vertex_masses.iter().all(|m| (m[0] == NO_MASS) == (m[1] == NO_MASS)));
    let guard = match scene.effects.wrong_side_guard {
        Some(g) => GuardParams { enabled: true, threshold_angle_deg: g.max_angle_deg, impulse_m_per_s: g.impulse_m_s },
        None => GuardParams { enabled: false, ..GuardParams::default() },
    };
    let settings =
        SolverSettings { guard, track_energy: false, ..SolverSettings::of(choose_solver(kind, scene.solver)) };
    let sim_err = |source| RuntimeError::Simulation { path: pack.path().to_path_buf(), source };
    let simulator = Simulator::new(&topology, settings).map_err(sim_err)?;
    // Every force stage overwrites its own term each step; a term without a stage stays off.
    let forces = ForceSet {
        restoring_weight_n: scene
            .effects
            .wrong_side_guard
            .map_or(ForceSet::default().restoring_weight_n, |g| g.restoring_weight_n),
        ..ForceSet::none()
    };
    let mut scale_vectors = simulator.scale_vectors();
    for (s, n) in scale_vectors.iter_mut().zip(&rest) {
        if *s == [0.0; 3] {
            *s = *n;
        }
    }
    Ok(FurState {
        sim: Some(FurSim { simulator, topology: kind, forces, last: StepStats::default() }),
        scale_vectors,
        rest,
        layout,
    })
}

/// Wind of a point source at `p` (grass thesis eq. 4.1 with the full 3D direction):
/// `normalize(p − W) · ω / max(|p − W|, 5 cm)^σ`, in m/s of wind speed.
fn point_source_wind(s: &crate::scene::WindSource, p: Vec3) -> Vec3 {
    let wp = p - Vec3::from(s.position);
    let d = wp.length();
    if d == 0.0 {
        return Vec3::ZERO;
    }
    wp / d * (s.power / d.max(POINT_SOURCE_MIN_DISTANCE_M).powf(s.falloff_exponent))
}

/// Lower clamp of a point source's distance, metres (as furbake-grass's default).
const POINT_SOURCE_MIN_DISTANCE_M: f32 = 0.05;

/// A pack's mesh frame at one time: rotation, uniform scale and the inverse model matrix.
struct MeshFrame {
    rotation: Quat,
    scale: f32,
    inverse: Mat4,
}

impl MeshFrame {
    fn at(pack: &ScenePack, t: f64) -> MeshFrame {
        let model = pack.model_at(t);
        let (scale, rotation, _) = model.to_scale_rotation_translation();
        // Scales are validated positive and uniform, so the model matrix is invertible.
        MeshFrame { rotation, scale: scale.x, inverse: model.inverse() }
    }

    /// A world point in mesh coordinates.
    fn point(&self, p: Vec3) -> Vec3 {
        self.inverse.transform_point3(p)
    }

    /// A world acceleration (or force per unit mass) in mesh units.
    fn vector(&self, v: Vec3) -> Vec3 {
        self.rotation.inverse() * v / self.scale
    }
}

/// Frame motion at `t` from the pack's motion path (see the module doc), in the mesh frame at
/// `t`, multiplied by `inertia_scale`.
fn frame_motion(pack: &ScenePack, t: f64, h: f64, inertia_scale: f32) -> FrameMotion {
    let place = |t: f64| {
        let (_, r, p) = pack.model_at(t.max(0.0)).to_scale_rotation_translation();
        (p, r)
    };
    let (p0, q0) = place(t - h);
    let (p1, q1) = place(t);
    let (p2, q2) = place(t + h);
    let (hf, frame) = (h as f32, MeshFrame::at(pack, t));
    let accel = (p2 - 2.0 * p1 + p0) / (hf * hf);
    let omega = |a: Quat, b: Quat, span: f32| {
        let d = (b * a.inverse()).normalize();
        // The shortest rotation (q and −q are the same rotation).
        let d = if d.w < 0.0 { -d } else { d };
        let (axis, angle) = d.to_axis_angle();
        if angle.is_finite() { axis * (angle / span) } else { Vec3::ZERO }
    };
    let w_back = omega(q0, q1, hf);
    let w_fwd = omega(q1, q2, hf);
    let w = omega(q0, q2, 2.0 * hf);
    let alpha = (w_fwd - w_back) / hf;
    let to_mesh = frame.rotation.inverse();
    FrameMotion {
        linear_accel_m_per_s2: (frame.vector(accel) * inertia_scale).to_array(),
        angular_velocity_rad_per_s: (to_mesh * w * inertia_scale).to_array(),
        angular_accel_rad_per_s2: (to_mesh * alpha * inertia_scale).to_array(),
    }
}
