//! The fur part of `docs/accuracy.md` (docs/design.md "Users and their asks"): error against cost,
//! one chart per scene. For every scene × solver × iteration count × step size, in two settings —
//! the *raw scheme* (step limits off: `max_link_rotation_rad = 0`) and the *default settings* a
//! user gets (`SolverSettings::of(kind)`, substeps and limits on) — it records the max and RMS
//! position error of the free masses after the scene's duration against a converged reference, and
//! the wall time per simulated second (best of a few runs). Scenes: the fur thesis's grass patch
//! (prisms and sticks topologies), the stiff net of `furbake_sim::synth`, and the Fox of the glTF
//! samples (prisms and sticks, standing; prisms, walking its `Walk` clip). Plus the time per step
//! at the fur thesis's table 4.5 sizes.
//!
//! The report is generic over [`SolverKind::ALL`]: a new solver kind appears in every table and
//! chart by itself; a new solver with an iteration count appears once per count after one line in
//! [`set_iterations`].
//!
//! Every number comes from running the solvers in this process: errors are deterministic, times
//! depend on the machine and its load (the document describes the machine).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use furbake_sim::synth::{THESIS_TABLE_4_5, stiff_net, stiff_net_forces, synthetic_topology};
use std::sync::Arc;

use furbake_runtime::{AnimatedSkin, AnimationError, Animator};
use furbake_sim::{
    ForceSet, SimError, Simulator, SkinTransform, SolverKind, SolverSettings, SpringTopology, TopologyKind,
    TopologyParams, build_topology, meshes,
};

use crate::ReportError;
use crate::svg::{COLORS, Figure, Marker, Panel, Point, Series, pareto_front, render};

// ------------------------------------------------------------------------------------------------
// THE SOLVER MAPPING — the one place to touch when a solver branch adds a kind with iterations.
// ------------------------------------------------------------------------------------------------

/// Which [`SolverSettings`] field carries the iteration count of `kind`: sets it to `n` and
/// returns `true`, or returns `false` for a kind without an iteration count (run once).
///
/// A new solver kind with an iteration count adds its arm here.
pub fn set_iterations(s: &mut SolverSettings, kind: SolverKind, n: u32) -> bool {
    match kind {
        SolverKind::Implicit => s.implicit_iterations = n,
        SolverKind::Xpbd => s.xpbd_iterations = n,
        SolverKind::LocalGlobal => s.local_global_iterations = n,
        SolverKind::Explicit | SolverKind::Stick | SolverKind::Reference => return false,
    }
    true
}

/// The masses' final positions, in metres, as f64 — the one place the report reads a
/// simulator's state: the reference solver's f64 state (so the reference does not floor the
/// errors at f32 round-off), every other solver's f32 positions widened.
fn final_positions(sim: &Simulator) -> Vec<[f64; 3]> {
    sim.positions_f64().unwrap_or_else(|| sim.positions().iter().map(|p| p.map(f64::from)).collect())
}

/// Whether [`final_positions`] reads the reference's f64 state (shown in the document's
/// reference line).
const POSITIONS_ARE_F64: bool = true;

// ------------------------------------------------------------------------------------------------

/// The fur scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SceneId {
    /// The fur thesis's grass patch (V = 13, F = 16), 2 cm fur, prisms topology.
    GrassPatchPrisms,
    /// The same patch, sticks topology.
    GrassPatchSticks,
    /// `furbake_sim::synth::stiff_net`: 50 masses, 100 stiff springs, gravity and gusty wind.
    StiffNet,
    /// The Fox of the glTF samples (`fixtures/real/Fox.glb`), prisms topology.
    FoxPrisms,
    /// The Fox, sticks topology.
    FoxSticks,
    /// The Fox playing its `Walk` clip (prisms topology): the skin drags the fur's anchors every
    /// step ([`Simulator::pose_skin`]), as a walking character's fur is driven in the runtime.
    FoxWalkPrisms,
}

impl SceneId {
    /// Every scene, in document order.
    pub const ALL: [SceneId; 6] = [
        SceneId::GrassPatchPrisms,
        SceneId::GrassPatchSticks,
        SceneId::StiffNet,
        SceneId::FoxPrisms,
        SceneId::FoxSticks,
        SceneId::FoxWalkPrisms,
    ];

    /// A file-name-safe identifier (`grass-patch-prisms`, …).
    pub fn slug(self) -> &'static str {
        match self {
            SceneId::GrassPatchPrisms => "grass-patch-prisms",
            SceneId::GrassPatchSticks => "grass-patch-sticks",
            SceneId::StiffNet => "stiff-net",
            SceneId::FoxPrisms => "fox-prisms",
            SceneId::FoxSticks => "fox-sticks",
            SceneId::FoxWalkPrisms => "fox-walk-prisms",
        }
    }

    /// A human title.
    pub fn title(self) -> &'static str {
        match self {
            SceneId::GrassPatchPrisms => "Grass patch, prisms",
            SceneId::GrassPatchSticks => "Grass patch, sticks",
            SceneId::StiffNet => "Stiff net",
            SceneId::FoxPrisms => "Fox, prisms",
            SceneId::FoxSticks => "Fox, sticks",
            SceneId::FoxWalkPrisms => "Fox walking, prisms",
        }
    }
}

/// What the fur part measures.
#[derive(Clone, Debug)]
pub struct AccuracySettings {
    /// The scenes. Default: all of [`SceneId::ALL`].
    pub scenes: Vec<SceneId>,
    /// Step sizes, seconds. Default 1/30, 1/60, 1/100, 1/300, 1/1000, 1/3000.
    pub step_sizes_s: Vec<f64>,
    /// Iteration counts run for every solver kind that has one (see [`set_iterations`]).
    /// Default 1, 2, 4, 8.
    pub iterations: Vec<u32>,
    /// Step of the reference run, seconds. Default 1/30,000.
    pub reference_dt_s: f64,
    /// Relative residual at which the reference's linear solves (BiCGSTAB) stop. Default 1e-12.
    pub reference_tolerance: f64,
    /// Simulated time before the error is taken, seconds (every scene but the Fox). Default 1.
    pub duration_s: f64,
    /// Simulated time of the Fox scenes, seconds. Default 1.
    pub fox_duration_s: f64,
    /// Timed runs per configuration (the fastest counts); runs after the first stop once one
    /// configuration has taken `repeat_budget_s`. Default 3.
    pub repeats: usize,
    /// See `repeats`. Default 0.5 s.
    pub repeat_budget_s: f64,
    /// The glTF of the Fox scenes. Default: the repository's `fixtures/real/Fox.glb`.
    pub fox_path: PathBuf,
    /// (masses, springs) sizes for the time-per-step table. Default: table 4.5, then 10× and 100×
    /// its largest.
    pub timing_sizes: Vec<(usize, usize)>,
    /// Minimum wall time spent timing one solver at one size, seconds. Default 0.3.
    pub timing_budget_s: f64,
}

impl Default for AccuracySettings {
    fn default() -> Self {
        let (m, s) = THESIS_TABLE_4_5[4];
        let mut timing_sizes = THESIS_TABLE_4_5.to_vec();
        timing_sizes.extend([(m * 10, s * 10), (m * 100, s * 100)]);
        AccuracySettings {
            scenes: SceneId::ALL.to_vec(),
            step_sizes_s: vec![1.0 / 30.0, 1.0 / 60.0, 1.0 / 100.0, 1.0 / 300.0, 1.0 / 1000.0, 1.0 / 3000.0],
            iterations: vec![1, 2, 4, 8],
            reference_dt_s: 1.0 / 30000.0,
            reference_tolerance: 1e-12,
            duration_s: 1.0,
            fox_duration_s: 1.0,
            repeats: 3,
            repeat_budget_s: 0.5,
            fox_path: default_fox_path(),
            timing_sizes,
            timing_budget_s: 0.3,
        }
    }
}

/// Scale of the Fox scenes' mesh (its units are centimetres in effect).
pub const FOX_SCALE: f32 = 0.01;

/// The repository's `fixtures/real/Fox.glb`.
pub fn default_fox_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb")
}

/// Raw scheme or default settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Mode {
    /// `max_link_rotation_rad = 0` (step limits off); the explicit and stick solvers still substep
    /// below their stable step (up to 100,000 substeps).
    Raw,
    /// `SolverSettings::of(kind)`: substeps and step limits on.
    Default,
}

impl Mode {
    /// `raw` or `default`.
    pub fn name(self) -> &'static str {
        match self {
            Mode::Raw => "raw",
            Mode::Default => "default",
        }
    }
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub enum Outcome {
    /// It ran to the end.
    Ran,
    /// A state went non-finite.
    Diverged,
    /// The solver refused or failed (the message).
    Failed(String),
}

/// One measurement: a configuration run on a scene.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ErrorRow {
    /// Scene slug.
    pub scene: String,
    /// Solver kind name.
    pub solver: String,
    /// Iteration count, for kinds that have one.
    pub iterations: Option<u32>,
    /// Raw scheme or default settings.
    pub mode: Mode,
    /// Step size, seconds.
    pub dt_s: f64,
    /// Substeps of the last step.
    pub substeps: u32,
    /// How the run ended.
    pub outcome: Outcome,
    /// Largest position error of a free mass, metres (∞ unless it ran).
    pub max_error_m: f64,
    /// RMS over free masses of the position error, metres (∞ unless it ran).
    pub rms_error_m: f64,
    /// Wall time per simulated second, seconds (fastest run).
    pub wall_s_per_sim_s: f64,
}

impl ErrorRow {
    /// `implicit ×4` or `explicit`.
    pub fn config(&self) -> String {
        match self.iterations {
            Some(n) => format!("{} ×{n}", self.solver),
            None => self.solver.clone(),
        }
    }

    /// `1/300 ×4` or `1/300`: the point label of the charts.
    pub fn point_label(&self) -> String {
        let step = format!("1/{:.0}", 1.0 / self.dt_s);
        match self.iterations {
            Some(n) => format!("{step} ×{n}"),
            None => step,
        }
    }
}

/// One scene's results.
#[derive(Clone, Debug)]
pub struct SceneReport {
    /// Which scene.
    pub id: SceneId,
    /// What the scene is (mesh, topology, counts, forces), for the document.
    pub description: String,
    /// Simulated time, seconds.
    pub duration_s: f64,
    /// Free masses.
    pub free_masses: usize,
    /// The floor: (max, RMS) difference between the extrapolated reference from (dt, 2·dt) and
    /// from (2·dt, 4·dt).
    pub floor_m: (f64, f64),
    /// The plain backward-Euler self-check: (max, RMS) difference between the runs at dt and 2·dt.
    pub plain_floor_m: (f64, f64),
    /// Wall time of the reference run, seconds.
    pub reference_wall_s: f64,
    /// Every configuration.
    pub rows: Vec<ErrorRow>,
    /// Point labels left out of the chart for lack of room.
    pub labels_omitted: usize,
}

/// One timing measurement.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TimingRow {
    /// Solver name.
    pub solver: String,
    /// Masses.
    pub masses: usize,
    /// Springs + sticks.
    pub links: usize,
    /// Mean wall time per step, seconds.
    pub time_per_step_s: f64,
    /// Links updated per second.
    pub links_per_s: f64,
}

/// The generated fur part.
#[derive(Clone, Debug)]
pub struct AccuracyReport {
    /// Its markdown (starts with `# Accuracy vs time of the fur solvers`).
    pub markdown: String,
    /// (file name, SVG text) of the plots the markdown links to.
    pub plots: Vec<(String, String)>,
    /// Per scene.
    pub scenes: Vec<SceneReport>,
    /// Time per step.
    pub timings: Vec<TimingRow>,
}

/// The fur scenes' forces: [`synth::fur_wind_forces`] (wind and the restoring force, no
/// gravity; its doc says why).
fn fur_forces() -> ForceSet {
    furbake_sim::synth::fur_wind_forces()
}

fn describe_forces(f: &ForceSet) -> String {
    let mut parts = Vec::new();
    let g = f.gravity_m_per_s2;
    if g != [0.0; 3] {
        parts.push(format!("gravity ({}, {}, {}) m/s²", g[0], g[1], g[2]));
    } else {
        parts.push("no gravity".into());
    }
    if let Some(w) = &f.wind {
        parts.push(format!(
            "gusty wind {} N per tip along ({}, {}, {}), {:.0} % gusts at {} Hz, wavelength {} m",
            w.force_n,
            w.direction[0],
            w.direction[1],
            w.direction[2],
            100.0 * w.gust_amplitude,
            w.gust_frequency_hz,
            w.gust_wavelength_m
        ));
    }
    if f.restoring_weight_n > 0.0 {
        parts.push(format!("restoring weight {} N (eq. 3.37)", f.restoring_weight_n));
    } else {
        parts.push("no restoring force".into());
    }
    parts.join(", ")
}

struct Scene {
    id: SceneId,
    topology: SpringTopology,
    forces: ForceSet,
    duration_s: f64,
    description: String,
    /// The skin's animation, for a walking scene: played from its start in every run.
    motion: Option<Motion>,
}

/// A clip that moves the skin under the fur, in the simulation's units.
struct Motion {
    /// The clip's player, at the clip's start (each run plays a clone).
    animator: Animator,
    /// Mesh units → metres (the Fox's [`FOX_SCALE`]): a skin transform `M` acts as
    /// `S·M·S⁻¹`, its translation scaled.
    scale: f32,
}

impl Motion {
    /// Poses `animator` at clip time `t_s` and writes the posed skin's transforms, in the
    /// simulation's units, into `out` (one per skin vertex). The time is computed in f64 by the
    /// caller, not accumulated step by step in the player's f32 clock, whose drift over 30,000
    /// reference steps would differ from that over 50 game steps.
    fn pose_at(&self, animator: &mut Animator, t_s: f64, out: &mut [SkinTransform]) -> Result<(), ReportError> {
        animator.seek(t_s as f32).map_err(ReportError::Animation)?;
        animator.update().map_err(ReportError::Animation)?;
        for (o, t) in out.iter_mut().zip(animator.transforms()) {
            let mut m = t.matrix;
            m.w_axis = (m.w_axis.truncate() * self.scale).extend(1.0);
            *o = SkinTransform::new(m, t.morph_offset_m * self.scale);
        }
        Ok(())
    }
}

fn build_scene(id: SceneId, s: &AccuracySettings) -> Result<Scene, ReportError> {
    let params = TopologyParams::default();
    let fur_params = format!(
        "{} cm fur, default topology parameters (tip mass {} kg, {} N/m, {} N·s/m)",
        params.fur_length_m * 100.0,
        params.hair_mass_kg,
        params.stiffness_n_per_m,
        params.damping_n_s_per_m
    );
    let (mut motion, mut notes) = (None, String::new());
    let (topology, forces, duration_s, what) = match id {
        SceneId::GrassPatchPrisms | SceneId::GrassPatchSticks => {
            let kind = if id == SceneId::GrassPatchPrisms { TopologyKind::PRISMS } else { TopologyKind::STICKS };
            let mesh = meshes::grass_patch(0.02);
            let t = build_topology(&mesh, kind, &params)?;
            (t, fur_forces(), s.duration_s, format!("the fur thesis's grass patch (V = 13, F = 16), {kind} topology, {fur_params}"))
        }
        SceneId::StiffNet => (
            stiff_net(),
            stiff_net_forces(),
            s.duration_s,
            "`furbake_sim::synth::stiff_net`: a 10 × 5 net of 1 g masses with 1 cm spacing hanging from its anchored top row, 100 springs of 100 N/m and 0.01 N·s/m (h·ω ≈ 25 at 1/30 s)".to_owned(),
        ),
        SceneId::FoxPrisms | SceneId::FoxSticks | SceneId::FoxWalkPrisms => {
            let kind = if id == SceneId::FoxSticks { TopologyKind::STICKS } else { TopologyKind::PRISMS };
            let imported = furbake_import::import_gltf(&s.fox_path, &Default::default())
                .map_err(|source| ReportError::Import { path: s.fox_path.clone(), source: Box::new(source) })?;
            if id == SceneId::FoxWalkPrisms {
                motion = Some(walk_motion(&imported, &s.fox_path)?);
            }
            let mut m = imported.mesh;
            // Authored in centimetres-as-units, the Fox is 155 units long; simulated as metres
            // its coordinates reach ~90, where f32's spacing (7.6e-6) makes every run's round-off
            // ~2e-4 m after a second and no step size converges. Scaled to a 1.55 m fox.
            for p in &mut m.positions {
                *p = p.map(|c| c * FOX_SCALE);
            }
            let m = &m;
            let t = build_topology(m, kind, &params)?;
            let what = if id == SceneId::FoxWalkPrisms {
                format!(
                    "the Fox of the glTF samples (`fixtures/real/Fox.glb`) playing its `{WALK_CLIP}` clip from its start (linear blend skinning of the runtime's `Animator` at clip time k·dt computed in f64, each step's skin transforms posing the fur's anchors with `Simulator::pose_skin` before the step, as the runtime does; the cost includes the skinning), welded to {} vertices and {} triangles, all furry, scaled by {FOX_SCALE} to a 1.55 m fox.",
                    m.positions.len(),
                    m.triangles.len()
                )
            } else {
                format!(
                    "the Fox of the glTF samples (`fixtures/real/Fox.glb`, bind pose, welded to {} vertices and {} triangles, all furry) scaled by {FOX_SCALE} to a 1.55 m fox (in its authored units it is 155 m long, and f32 round-off at coordinates ~90 — spacing 7.6e-6 — floors every error at ~2e-4 m after 1 s)",
                    m.positions.len(),
                    m.triangles.len()
                )
            };
            if id == SceneId::FoxWalkPrisms {
                notes = WALK_NOTES.to_owned();
            }
            (t, fur_forces(), s.fox_duration_s, format!("{what}, {kind} topology, {fur_params}"))
        }
    };
    let free = topology.mass_anchored.iter().filter(|&&a| a == 0).count();
    let description = format!(
        "{what}; {} masses ({free} free), {} springs, {} sticks. Forces: {}. Duration {} s.{notes}",
        topology.mass_kg.len(),
        topology.spring_ends.len(),
        topology.stick_ends.len(),
        describe_forces(&forces),
        duration_s
    );
    Ok(Scene { id, topology, forces, duration_s, description, motion })
}

/// What to know when reading the walking Fox's table (measured when the scene was added).
const WALK_NOTES: &str = " The skin is posed once per step and its anchors move along the chord between two poses, so a long step misses the curve of a swinging leg: that is part of every solver's error here, and the explicit solver, which substeps within a step on the same chords, shows it alone (its error falls at first order with dt). Read the small steps with one hair in mind: when this scene was added (2026-12-03) free mass 257 ended 3.4 cm (1.7 fur lengths) from the reference in every implicit-class solver (implicit, reference, XPBD, local/global) at steps of 1/3000 s and longer, while all of them agreed with the reference at 1/6000 s and finer and the explicit solver (substeps of 1/6000 s) followed it; a max error of ~3.4e-2 m at small steps is that hair, and it alone puts ~2.0e-3 m (3.4e-2/√290) into the RMS.";

/// The clip the walking Fox plays.
pub const WALK_CLIP: &str = "Walk";

/// The Fox's `Walk` clip at its start, from the imported glTF's own sections.
fn walk_motion(imported: &furbake_import::ImportedMesh, path: &std::path::Path) -> Result<Motion, ReportError> {
    let a = &imported.animation;
    let missing = || {
        ReportError::Animation(AnimationError::UnknownClip {
            name: WALK_CLIP.into(),
            known: format!("no clips in {}", path.display()),
        })
    };
    let sections = AnimatedSkin {
        mesh: Arc::new(imported.mesh.clone()),
        clips: Arc::new(a.clips.clone().ok_or_else(missing)?),
        skeleton: a.skeleton.clone().map(Arc::new),
        weights: a.skin_weights.clone().map(Arc::new),
        morphs: a.morph_targets.clone().map(Arc::new),
    };
    let animator =
        Animator::from_sections(sections, Some(WALK_CLIP), 1.0, true, 0.0).map_err(ReportError::Animation)?;
    Ok(Motion { animator, scale: FOX_SCALE })
}

/// The settings of one configuration.
fn settings(kind: SolverKind, iterations: Option<u32>, mode: Mode) -> SolverSettings {
    let mut s = SolverSettings { track_energy: false, ..SolverSettings::of(kind) };
    if mode == Mode::Raw {
        s.max_link_rotation_rad = 0.0;
        s.max_substeps = 100_000;
    }
    if let Some(n) = iterations {
        set_iterations(&mut s, kind, n);
    }
    s
}

/// Runs `scene` with `s` at step `dt`: final positions, substeps of the last step, wall seconds
/// (the skin's animation, for a walking scene, included: it is part of what a step costs).
fn simulate(scene: &Scene, s: SolverSettings, dt: f64) -> Result<(Vec<[f64; 3]>, u32, f64), ReportError> {
    let start = Instant::now();
    let mut sim = Simulator::new(&scene.topology, s)?;
    sim.set_forces(scene.forces.clone())?;
    let steps = (scene.duration_s / dt).round().max(1.0) as u64;
    let mut substeps = 1;
    let mut walk =
        scene.motion.as_ref().map(|m| (m, m.animator.clone(), vec![SkinTransform::IDENTITY; sim.shell_vertex_count()]));
    for k in 0..steps {
        if let Some((motion, animator, transforms)) = &mut walk {
            motion.pose_at(animator, (k + 1) as f64 * dt, transforms)?;
            sim.pose_skin(transforms, dt, f32::INFINITY)?;
        }
        substeps = sim.step(dt)?.substeps;
    }
    let wall = start.elapsed().as_secs_f64();
    Ok((final_positions(&sim), substeps, wall))
}

/// (max, RMS) over free masses of the distance between `a` and `b`, metres.
fn errors(t: &SpringTopology, a: &[[f64; 3]], b: &[[f64; 3]]) -> (f64, f64) {
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0usize);
    for (i, (p, q)) in a.iter().zip(b).enumerate() {
        if t.mass_anchored[i] != 0 {
            continue;
        }
        let d2: f64 = (0..3).map(|k| (p[k] - q[k]).powi(2)).sum();
        sum += d2;
        max = max.max(d2.sqrt());
        n += 1;
    }
    (max, (sum / n.max(1) as f64).sqrt())
}

/// The configurations of the sweep: (kind, iterations) for every kind of [`SolverKind::ALL`].
pub fn configurations(iterations: &[u32]) -> Vec<(SolverKind, Option<u32>)> {
    let mut out = Vec::new();
    for kind in SolverKind::ALL {
        let mut probe = SolverSettings::of(kind);
        if set_iterations(&mut probe, kind, 1) && !iterations.is_empty() {
            out.extend(iterations.iter().map(|&n| (kind, Some(n))));
        } else {
            out.push((kind, None));
        }
    }
    out
}

fn measure_scene(scene: &Scene, s: &AccuracySettings) -> Result<SceneReport, ReportError> {
    let t = &scene.topology;
    let reference = SolverSettings {
        reference_tolerance: s.reference_tolerance,
        ..settings(SolverKind::Reference, None, Mode::Raw)
    };
    // Backward Euler is first order, x(h) = x* + C·h + O(h²): at the reference step its own error
    // is still ~1e-5 m on the stiff net. Richardson extrapolation R(h) = 2·x(h) − x(2h) cancels
    // the first-order term; the floor compares R(h) with R(2h) (whose error is ~4× R(h)'s).
    let (fine, _, reference_wall_s) = simulate(scene, reference.clone(), s.reference_dt_s)?;
    let (coarse, _, _) = simulate(scene, reference.clone(), 2.0 * s.reference_dt_s)?;
    let (coarser, _, _) = simulate(scene, reference, 4.0 * s.reference_dt_s)?;
    let extrapolate = |a: &[[f64; 3]], b: &[[f64; 3]]| -> Vec<[f64; 3]> {
        a.iter().zip(b).map(|(p, q)| [2.0 * p[0] - q[0], 2.0 * p[1] - q[1], 2.0 * p[2] - q[2]]).collect()
    };
    let truth = extrapolate(&fine, &coarse);
    let floor_m = errors(t, &truth, &extrapolate(&coarse, &coarser));
    let plain_floor_m = errors(t, &fine, &coarse);
    let mut rows = Vec::new();
    for (kind, iterations) in configurations(&s.iterations) {
        for mode in [Mode::Raw, Mode::Default] {
            for &dt in &s.step_sizes_s {
                let mut best = f64::INFINITY;
                let mut spent = 0.0;
                let mut result = None;
                for run in 0..s.repeats.max(1) {
                    if run > 0 && spent > s.repeat_budget_s {
                        break;
                    }
                    match simulate(scene, settings(kind, iterations, mode), dt) {
                        Ok((pos, sub, wall)) => {
                            best = best.min(wall);
                            spent += wall;
                            result = Some(Ok((pos, sub)));
                        }
                        Err(e) => {
                            result = Some(Err(e));
                            break;
                        }
                    }
                }
                let (outcome, substeps, (max, rms)) = match result {
                    Some(Ok((pos, sub))) => (Outcome::Ran, sub, errors(t, &pos, &truth)),
                    Some(Err(ReportError::Fur(SimError::NonFinite { .. }))) => {
                        (Outcome::Diverged, 0, (f64::INFINITY, f64::INFINITY))
                    }
                    Some(Err(e)) => (Outcome::Failed(e.to_string()), 0, (f64::INFINITY, f64::INFINITY)),
                    None => (Outcome::Failed("not run".into()), 0, (f64::INFINITY, f64::INFINITY)),
                };
                rows.push(ErrorRow {
                    scene: scene.id.slug().to_owned(),
                    solver: kind.name().to_owned(),
                    iterations,
                    mode,
                    dt_s: dt,
                    substeps,
                    outcome,
                    max_error_m: max,
                    rms_error_m: rms,
                    wall_s_per_sim_s: best / scene.duration_s,
                });
            }
        }
    }
    Ok(SceneReport {
        id: scene.id,
        description: scene.description.clone(),
        duration_s: scene.duration_s,
        free_masses: t.mass_anchored.iter().filter(|&&a| a == 0).count(),
        floor_m,
        plain_floor_m,
        reference_wall_s,
        rows,
        labels_omitted: 0,
    })
}

/// Runs every measurement and renders the fur part. `progress` is told each scene's title as it
/// starts.
pub fn accuracy_report(s: &AccuracySettings, mut progress: impl FnMut(&str)) -> Result<AccuracyReport, ReportError> {
    let mut scenes = Vec::new();
    let mut plots = Vec::new();
    for &id in &s.scenes {
        progress(id.title());
        let scene = build_scene(id, s)?;
        let mut report = measure_scene(&scene, s)?;
        let (svg, omitted) = scene_chart(&report);
        report.labels_omitted = omitted;
        plots.push((chart_name(id), svg));
        scenes.push(report);
    }
    progress("time per step");
    let timings = measure_timings(s)?;
    plots.push(("accuracy_time.svg".to_owned(), timing_chart(&timings).0));
    let markdown = render_markdown(s, &scenes, &timings);
    Ok(AccuracyReport { markdown, plots, scenes, timings })
}

/// The chart file of a scene.
pub fn chart_name(id: SceneId) -> String {
    format!("accuracy_{}.svg", id.slug())
}

fn measure_timings(s: &AccuracySettings) -> Result<Vec<TimingRow>, ReportError> {
    let params = TopologyParams::default();
    let mut timing_rows = Vec::new();
    for &(masses, links) in &s.timing_sizes {
        for solver in SolverKind::ALL {
            let Some(t) = synthetic_topology(masses, links, solver == SolverKind::Stick, &params) else {
                return Err(SimError::Parameter {
                    name: "timing_sizes",
                    what: format!("{masses} masses / {links} links"),
                }
                .into());
            };
            let mut probe = Simulator::new(&t, SolverSettings::of(SolverKind::Explicit))?;
            let dt = probe.stable_step_s().min(1.0 / 60.0);
            let mut sim = Simulator::new(&t, SolverSettings { track_energy: false, ..SolverSettings::of(solver) })?;
            sim.set_forces(ForceSet::default())?;
            sim.step(dt)?; // warm-up
            let start = Instant::now();
            let mut steps = 0u32;
            while steps < 3 || start.elapsed().as_secs_f64() < s.timing_budget_s {
                sim.step(dt)?;
                steps += 1;
            }
            let per = start.elapsed().as_secs_f64() / steps as f64;
            timing_rows.push(TimingRow {
                solver: solver.name().into(),
                masses,
                links,
                time_per_step_s: per,
                links_per_s: links as f64 / per,
            });
        }
    }
    Ok(timing_rows)
}

/// Colour and marker of a configuration: the marker by solver kind, the colour by configuration.
fn style(index: usize, kind_index: usize) -> (String, Marker) {
    (COLORS[index % COLORS.len()].to_owned(), Marker::ALL[kind_index % Marker::ALL.len()])
}

/// The error-vs-cost chart of one scene: 2 × 2 panels (raw scheme / default settings × max / RMS
/// error), a series per configuration, every point labelled with its step (and iterations), the
/// Pareto front of each panel drawn.
pub fn scene_chart(r: &SceneReport) -> (String, usize) {
    let mut configs: Vec<(String, String)> = Vec::new(); // (config, solver)
    for row in &r.rows {
        if !configs.iter().any(|c| c.0 == row.config()) {
            configs.push((row.config(), row.solver.clone()));
        }
    }
    let mut kinds: Vec<&str> = Vec::new();
    for c in &configs {
        if !kinds.contains(&c.1.as_str()) {
            kinds.push(&c.1);
        }
    }
    let mut panels = Vec::new();
    for mode in [Mode::Raw, Mode::Default] {
        for (metric, get) in
            [("max", (|r: &ErrorRow| r.max_error_m) as fn(&ErrorRow) -> f64), ("RMS", |r| r.rms_error_m)]
        {
            let series = configs
                .iter()
                .enumerate()
                .map(|(i, (config, solver))| {
                    let (color, marker) = style(i, kinds.iter().position(|k| k == solver).unwrap_or(0));
                    Series {
                        name: config.clone(),
                        color,
                        marker,
                        filled: true,
                        line: false,
                        points: r
                            .rows
                            .iter()
                            .filter(|row| row.mode == mode && &row.config() == config && row.outcome == Outcome::Ran)
                            .map(|row| Point { x: row.wall_s_per_sim_s, y: get(row), label: row.point_label() })
                            .collect(),
                    }
                })
                .collect();
            let mode_title = match mode {
                Mode::Raw => "raw scheme (limits off)",
                Mode::Default => "default settings (substeps + limits)",
            };
            panels.push(Panel {
                title: format!("{metric} error — {mode_title}"),
                x_title: "wall time per simulated second (s/s)".into(),
                y_title: format!("{metric} position error after {} s (m)", r.duration_s),
                series,
                pareto: true,
            });
        }
    }
    let fig = Figure {
        title: format!("{}: position error against cost ({} free masses)", r.id.title(), r.free_masses),
        columns: 2,
        panels,
        legend_notes: vec![
            "labels: step (s) ×iterations".into(),
            format!("reference floor: RMS {:.1e} m", r.floor_m.1),
        ],
    };
    render(&fig)
}

fn timing_chart(rows: &[TimingRow]) -> (String, usize) {
    let mut series: Vec<Series> = Vec::new();
    for r in rows {
        let p = Point { x: r.links as f64, y: r.time_per_step_s, label: String::new() };
        match series.iter_mut().find(|s| s.name == r.solver) {
            Some(s) => s.points.push(p),
            None => {
                let i = series.len();
                let (color, marker) = style(i, i);
                series.push(Series {
                    name: r.solver.clone(),
                    color,
                    marker,
                    filled: true,
                    line: true,
                    points: vec![p],
                });
            }
        }
    }
    render(&Figure {
        title: "Time per step against size".into(),
        columns: 1,
        panels: vec![Panel {
            title: "one step at the explicit solver's stable step".into(),
            x_title: "springs + sticks".into(),
            y_title: "wall time per step (s)".into(),
            series,
            pareto: false,
        }],
        legend_notes: vec![],
    })
}

fn fmt_err(e: f64) -> String {
    if e.is_finite() { format!("{e:.2e}") } else { "—".into() }
}

/// The cells every error table row starts with (solver, settings, dt, substeps, max and RMS
/// error, cost), `mark` after the RMS error; the caller appends the last cell.
fn row_cells(x: &ErrorRow, mark: &str) -> String {
    format!(
        "| {} | {} | 1/{:.0} s | {} | {} m | {} m{mark} | {:.2e} |",
        x.config(),
        x.mode.name(),
        1.0 / x.dt_s,
        x.substeps,
        fmt_err(x.max_error_m),
        fmt_err(x.rms_error_m),
        x.wall_s_per_sim_s
    )
}

fn outcome_note(r: &ErrorRow) -> String {
    match &r.outcome {
        Outcome::Ran => String::new(),
        Outcome::Diverged => "diverged".into(),
        Outcome::Failed(m) => format!("failed: {}", m.replace('|', "/")),
    }
}

/// A short description of the machine: threads, rayon pool, CPU model, build profile.
pub fn machine() -> String {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let profile = if cfg!(debug_assertions) { "debug" } else { "release" };
    format!(
        "{cpu}, {threads} hardware threads available, rayon pool of {} threads, {profile} build, {} {}",
        rayon::current_num_threads(),
        std::env::consts::OS,
        std::env::consts::ARCH
    )
}

fn render_markdown(s: &AccuracySettings, scenes: &[SceneReport], timings: &[TimingRow]) -> String {
    let mut md = String::new();
    let machine = machine();
    let positions = if POSITIONS_ARE_F64 { "f64" } else { "f32" };
    let _ = writeln!(md, "# Accuracy vs time of the fur solvers\n");
    let _ = writeln!(
        md,
        "For every scene below, every solver of `SolverKind::ALL` ({}) runs at every step size ({}) — solvers \
         with an iteration count once per count ({}) — in two settings:\n\n\
         - **raw scheme**: `max_link_rotation_rad = 0`, the implicit solvers' step limits off; the explicit and \
         stick solvers still split a step longer than their stable step into substeps (up to 100,000);\n\
         - **default settings**: `SolverSettings::of(kind)` as a user gets it — substeps and step limits on \
         (for the explicit and stick solvers this is the same scheme as raw).\n\n\
         Energy statistics are off in both (`track_energy = false`).\n",
        SolverKind::ALL.map(|k| format!("`{}`", k.name())).join(", "),
        s.step_sizes_s.iter().map(|dt| format!("1/{:.0} s", 1.0 / dt)).collect::<Vec<_>>().join(", "),
        s.iterations.iter().map(|n| format!("×{n}")).collect::<Vec<_>>().join(", ")
    );
    let _ = writeln!(
        md,
        "- **Metric**: position error of the free masses at the end of the run against the reference, in metres: \
         **max** = the largest over free masses, **RMS** = root mean square over free masses. Cost = wall time per \
         simulated second, the fastest of up to {} runs (runs after the first stop once a configuration has spent \
         {} s).\n\
         - **Reference**: `SolverKind::Reference` — backward Euler linearised per step with the exact Jacobian of every force, solved by BiCGSTAB \
         to a relative residual of {:.0e}, step limits off — run at dt = 1/{:.0} s and 2·dt, and Richardson-extrapolated: \
         backward Euler is first order, x(h) = x* + C·h + O(h²), so R = 2·x(dt) − x(2·dt) cancels its own step error \
         (at dt alone it would still be ~1e-5 m on the stiff net, above the explicit solver's error). Positions read \
         as {positions}. The reference itself is checked by `crates/sim/tests/reference_check.rs` against two \
         independent integrators written in the test: classic RK4 in f64 at 1e-6 s (the reference converges at first \
         order: its error falls 1.75–1.98× per halving of dt) and backward Euler by dense elimination (over 1 s, RMS: \
         5e-10–1e-9 m at 1/30 s and 1/300 s, except the stiff net at 1/30 s, 1.5e-5 m, where the reference's \
         compression floor acts).\n\
         - **XPBD's energy**: at low iteration counts XPBD leaves part of each step's stretch unresolved, so its stored \
         spring energy can exceed the work done on the fur (the hard-case tests measure up to 0.99 of the peak energy \
         on stiff chains at 8 iterations, none at 32): its errors here are what a user gets, its stability is not \
         the implicit solvers'.\n\
         - **Floor**: the reference's self-check, per scene: the difference between R from (dt, 2·dt) and R from \
         (2·dt, 4·dt) — an upper bound of R's own error, by a factor not measured here (an independent check found \
         1.6–2.5×) — and, for comparison, the plain backward-Euler \
         difference between dt and 2·dt. A cell marked ‡ is within 2× the RMS floor: its error is the reference's \
         as much as the solver's, and the true error may be smaller.\n\
         - **Machine**: {machine}. Times move with machine load.\n",
        s.repeats,
        s.repeat_budget_s,
        s.reference_tolerance,
        1.0 / s.reference_dt_s
    );
    for r in scenes {
        let _ = writeln!(md, "## {} — error against cost\n", r.id.title());
        let _ = writeln!(md, "Scene: {}\n", r.description);
        let _ = writeln!(
            md,
            "Metric: max and RMS position error over the {} free masses after {} s, metres. Reference: \
             `reference` at dt = 1/{:.0} s and 2·dt, BiCGSTAB to {:.0e}, f64 state, Richardson-extrapolated ({:.1} s of wall time at dt). \
             Floor (extrapolations from dt and 2·dt): max {:.2e} m, RMS {:.2e} m (plain backward Euler, dt vs 2·dt: \
             max {:.2e} m, RMS {:.2e} m). Machine: as above.\n",
            r.free_masses,
            r.duration_s,
            1.0 / s.reference_dt_s,
            s.reference_tolerance,
            r.reference_wall_s,
            r.floor_m.0,
            r.floor_m.1,
            r.plain_floor_m.0,
            r.plain_floor_m.1
        );
        let name = chart_name(r.id);
        let _ = writeln!(md, "![{}: error against wall time per simulated second]({name})\n", r.id.title());
        let floor_mark = |e: f64| if e.is_finite() && e < 2.0 * r.floor_m.1 { " ‡" } else { "" };
        let ran: Vec<&ErrorRow> = r.rows.iter().filter(|x| x.outcome == Outcome::Ran).collect();
        let by_max = pareto_front(&ran.iter().map(|x| (x.wall_s_per_sim_s, x.max_error_m)).collect::<Vec<_>>());
        let by_rms = pareto_front(&ran.iter().map(|x| (x.wall_s_per_sim_s, x.rms_error_m)).collect::<Vec<_>>());
        let mut front: Vec<usize> = by_max.iter().chain(&by_rms).copied().collect();
        front.sort_by(|&a, &b| ran[a].wall_s_per_sim_s.total_cmp(&ran[b].wall_s_per_sim_s));
        front.dedup();
        let _ = writeln!(md, "### {} — Pareto front\n", r.id.title());
        let _ = writeln!(
            md,
            "The configurations no other beats in both cost and error (raw and default settings together), by cost; \
             *front* says for which metric.\n"
        );
        let _ = writeln!(
            md,
            "| solver | settings | dt | substeps | max error | RMS error | wall s per simulated s | front |"
        );
        let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---|");
        for &i in &front {
            let x = ran[i];
            let which = match (by_max.contains(&i), by_rms.contains(&i)) {
                (true, true) => "max, RMS",
                (true, false) => "max",
                _ => "RMS",
            };
            let _ = writeln!(md, "{} {which} |", row_cells(x, floor_mark(x.rms_error_m)));
        }
        let _ = writeln!(md, "\n### {} — every configuration\n", r.id.title());
        let _ = writeln!(md, "<details><summary>{} rows</summary>\n", r.rows.len());
        let _ = writeln!(
            md,
            "| solver | settings | dt | substeps | max error | RMS error | wall s per simulated s | note |"
        );
        let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---|");
        for x in &r.rows {
            let note = outcome_note(x);
            let note = if note.is_empty() { "·".to_owned() } else { note };
            let _ = writeln!(md, "{} {note} |", row_cells(x, floor_mark(x.rms_error_m)));
        }
        let _ = writeln!(md, "\n</details>\n");
    }
    let _ = writeln!(
        md,
        "## Time per step\n\nScene: synthetic topologies of exactly the thesis's table 4.5 sizes and 10× / 100× its \
         largest (half the masses anchored roots, one root–tip link each, the rest tip–tip springs; sticks for the \
         stick solver), default forces. Metric: mean wall time of one step at the explicit solver's stable step \
         (capped at 1/60 s), default settings, statistics off; throughput = links (springs + sticks) updated per \
         second. Reference and floor: none (a cost, not an error). Machine: {machine}.\n"
    );
    let _ = writeln!(md, "![time per step against size](accuracy_time.svg)\n");
    let mut header = "| masses | links |".to_owned();
    let mut rule = "|---:|---:|".to_owned();
    for k in SolverKind::ALL {
        let _ = write!(header, " {} |", k.name());
        rule.push_str("---:|");
    }
    let _ = writeln!(md, "{header}\n{rule}");
    let mut sizes: Vec<(usize, usize)> = timings.iter().map(|t| (t.masses, t.links)).collect();
    sizes.dedup();
    for (m, l) in sizes {
        let mut line = format!("| {m} | {l} |");
        for k in SolverKind::ALL {
            match timings.iter().find(|t| t.masses == m && t.links == l && t.solver == k.name()) {
                Some(t) => {
                    let _ = write!(line, " {:.3} ms ({:.1} M/s) |", t.time_per_step_s * 1e3, t.links_per_s / 1e6);
                }
                None => line.push_str(" — |"),
            }
        }
        let _ = writeln!(md, "{line}");
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quick() -> AccuracySettings {
        AccuracySettings {
            scenes: vec![SceneId::GrassPatchPrisms, SceneId::StiffNet],
            step_sizes_s: vec![1.0 / 30.0, 1.0 / 300.0],
            iterations: vec![1, 4],
            reference_dt_s: 1.0 / 3000.0,
            duration_s: 0.2,
            repeats: 1,
            timing_sizes: vec![(200, 300)],
            timing_budget_s: 0.0,
            ..AccuracySettings::default()
        }
    }

    /// The sweep covers every kind of `SolverKind::ALL`, iterative ones once per count, and the
    /// mapping sets the implicit solver's field.
    #[test]
    fn configurations_cover_every_kind_and_iteration_count() {
        let c = configurations(&[1, 4]);
        for k in SolverKind::ALL {
            assert!(c.iter().any(|(kind, _)| *kind == k), "{k:?}");
        }
        assert!(c.contains(&(SolverKind::Implicit, Some(4))));
        assert!(c.contains(&(SolverKind::Explicit, None)));
        let s = settings(SolverKind::Implicit, Some(4), Mode::Raw);
        assert_eq!((s.implicit_iterations, s.max_link_rotation_rad), (4, 0.0));
        let d = settings(SolverKind::Implicit, Some(4), Mode::Default);
        assert_eq!(d.max_link_rotation_rad, SolverSettings::default().max_link_rotation_rad);
    }

    /// A quick report: every row is measured, errors shrink with the step for the converged
    /// implicit solver, and the chart has a point per run.
    #[test]
    fn quick_report_is_complete() {
        let s = quick();
        let r = accuracy_report(&s, |_| {}).expect("runs");
        let configs = configurations(&s.iterations).len();
        assert_eq!(r.scenes.len(), 2);
        for scene in &r.scenes {
            assert_eq!(scene.rows.len(), configs * 2 * s.step_sizes_s.len());
            assert!(scene.floor_m.1 > 0.0 && scene.floor_m.1 < 1e-3, "{:?}", scene.floor_m);
            let conv: Vec<&ErrorRow> =
                scene.rows.iter().filter(|e| e.solver == "reference" && e.mode == Mode::Raw).collect();
            assert!(conv[1].rms_error_m < conv[0].rms_error_m, "{conv:?}");
            assert!(scene.rows.iter().all(|x| x.wall_s_per_sim_s > 0.0));
        }
        assert_eq!(r.plots.len(), 3);
        assert!(r.markdown.contains("| implicit ×4 | raw | 1/300 s |"));
    }
}
