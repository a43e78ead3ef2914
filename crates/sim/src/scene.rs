//! The headless scene runner behind `furbake simulate`: a small TOML scene (forces, solver, step,
//! duration, motion windows, teleports) runs one topology and returns per-step statistics and the
//! final mass positions and velocities, serialisable to JSON so the results can be checked by an
//! independent integrator.
//!
//! ```toml
//! topology = "prisms"          # optional: the kind the scene expects
//! dt_s = 0.016666
//! duration_s = 2.0
//! forces_stop_s = 1.0          # optional: external forces off after this time
//! [solver]
//! kind = "implicit"            # explicit | implicit | stick | reference
//! implicit_iterations = 1
//! [forces]
//! gravity_m_per_s2 = [0.0, -9.81, 0.0]
//! restoring_weight_n = 0.01
//! [forces.wind]
//! direction = [1.0, 0.0, 0.0]
//! force_n = 1e-4
//! [[motion]]                   # the mesh frame accelerates between from_s and to_s
//! from_s = 0.2
//! to_s = 0.3
//! linear_accel_m_per_s2 = [490.5, 0.0, 0.0]
//! [[teleports]]
//! at_s = 0.5
//! offset_m = [0.1, 0.0, 0.0]
//! ```

use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::SpringTopology;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::forces::{ForceSet, FrameMotion};
use crate::simulator::{Energy, Simulator, SolverSettings};

/// A window of object motion: between `from_s` and `to_s` the mesh frame moves as given
/// (replacing `forces.motion`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionWindow {
    /// Start, seconds.
    pub from_s: f64,
    /// End, seconds.
    pub to_s: f64,
    /// Linear acceleration of the frame, m/s².
    #[serde(default)]
    pub linear_accel_m_per_s2: [f32; 3],
    /// Angular velocity of the frame, rad/s.
    #[serde(default)]
    pub angular_velocity_rad_per_s: [f32; 3],
    /// Angular acceleration of the frame, rad/s².
    #[serde(default)]
    pub angular_accel_rad_per_s2: [f32; 3],
}

/// An instantaneous jump of the mesh frame (see [`Simulator::teleport`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Teleport {
    /// When, seconds (applied before the first step starting at or after it).
    pub at_s: f64,
    /// Offset of the frame, metres.
    pub offset_m: [f32; 3],
}

/// A headless simulation scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimScene {
    /// The topology kind name the scene is meant for (checked when given).
    #[serde(default)]
    pub topology: Option<String>,
    /// Solver settings.
    #[serde(default)]
    pub solver: SolverSettings,
    /// Frame step, seconds (> 0).
    pub dt_s: f64,
    /// Simulated duration, seconds (≥ 0); `ceil(duration / dt)` steps run.
    pub duration_s: f64,
    /// Forces.
    #[serde(default)]
    pub forces: ForceSet,
    /// After this time every external force (gravity, wind, motion, local) is off; the restoring
    /// force stays. `None`: forces stay on.
    #[serde(default)]
    pub forces_stop_s: Option<f64>,
    /// Object-motion windows.
    #[serde(default)]
    pub motion: Vec<MotionWindow>,
    /// Teleports.
    #[serde(default)]
    pub teleports: Vec<Teleport>,
    /// Record statistics every this many steps (≥ 1; the last step is always recorded). Default 1.
    #[serde(default = "one")]
    pub record_every: u32,
}

fn one() -> u32 {
    1
}

/// Statistics of one recorded step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// Step index (0-based).
    pub step: u64,
    /// Time at the end of the step, seconds.
    pub time_s: f64,
    /// Energy after the step.
    pub energy: Energy,
    /// Total energy, joules.
    pub energy_j: f64,
    /// The energy budget (initial energy + external work + guard impulses + teleports), joules.
    pub energy_budget_j: f64,
    /// Largest displacement of a free mass from rest, metres.
    pub max_displacement_m: f32,
    /// Substeps taken.
    pub substeps: u32,
    /// CG iterations (reference solver).
    pub cg_iterations: u32,
    /// Wrong-side tests that fired.
    pub guard_triggers: u32,
    /// Frozen scale vectors after the step.
    pub frozen_scale_vectors: u32,
}

/// The result of [`run_scene`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimReport {
    /// Topology kind name.
    pub topology: String,
    /// Solver name.
    pub solver: String,
    /// Masses, springs, sticks.
    pub masses: usize,
    /// Springs.
    pub springs: usize,
    /// Sticks.
    pub sticks: usize,
    /// Frame step, seconds.
    pub dt_s: f64,
    /// Steps run.
    pub steps: u64,
    /// Substeps run in total.
    pub total_substeps: u64,
    /// Largest total energy seen, joules.
    pub max_energy_j: f64,
    /// Per recorded step.
    pub step_stats: Vec<StepRecord>,
    /// Final mass positions (topology order, mesh frame), metres.
    pub final_positions_m: Vec<[f32; 3]>,
    /// Final mass velocities (topology order, mesh frame), m/s.
    pub final_velocities_m_per_s: Vec<[f32; 3]>,
    /// Final scale vectors per shell vertex (eq. 3.35, after the guard).
    pub final_scale_vectors: Vec<[f32; 3]>,
}

impl SimScene {
    /// Fails unless the scene's numbers are in range.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |name, what: &str| Err(SimError::Parameter { name, what: what.into() });
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return bad("dt_s", "must be finite and positive");
        }
        if !(self.duration_s.is_finite() && self.duration_s >= 0.0) || self.duration_s / self.dt_s > 1e8 {
            return bad("duration_s", "must be finite, ≥ 0 and at most 1e8 steps");
        }
        if self.record_every == 0 {
            return bad("record_every", "must be at least 1");
        }
        if self.motion.iter().any(|m| !(m.from_s.is_finite() && m.to_s.is_finite() && m.from_s <= m.to_s)) {
            return bad("motion", "windows need finite from_s ≤ to_s");
        }
        if self.teleports.iter().any(|t| !t.at_s.is_finite() || t.offset_m.iter().any(|c| !c.is_finite())) {
            return bad("teleports", "not finite");
        }
        self.forces.validate()
    }

    fn forces_at(&self, t: f64) -> ForceSet {
        if self.forces_stop_s.is_some_and(|s| t >= s) {
            return ForceSet { restoring_weight_n: self.forces.restoring_weight_n, ..ForceSet::none() };
        }
        let mut f = self.forces.clone();
        if let Some(m) = self.motion.iter().find(|m| t >= m.from_s && t < m.to_s) {
            f.motion = FrameMotion {
                linear_accel_m_per_s2: m.linear_accel_m_per_s2,
                angular_velocity_rad_per_s: m.angular_velocity_rad_per_s,
                angular_accel_rad_per_s2: m.angular_accel_rad_per_s2,
            };
        }
        f
    }
}

/// Runs `scene` on `topology` (built on `mesh`) from rest and reports.
pub fn run_scene(topology: &SpringTopology, mesh: &SkinMesh, scene: &SimScene) -> Result<SimReport, SimError> {
    scene.validate()?;
    if let Some(name) = &scene.topology {
        if topology.kind.name() != Some(name.as_str()) {
            return Err(SimError::Parameter {
                name: "topology",
                what: format!("the scene asks for {name}, the topology is {}", topology.kind),
            });
        }
    }
    let s = &topology.stats;
    if s.source_vertices as usize != mesh.positions.len() || s.source_triangles as usize != mesh.triangles.len() {
        return Err(SimError::InvalidInput(format!(
            "the topology was built on a mesh of {} vertices / {} triangles, this one has {} / {}",
            s.source_vertices,
            s.source_triangles,
            mesh.positions.len(),
            mesh.triangles.len()
        )));
    }
    let mut sim = Simulator::new(topology, scene.solver.clone())?;
    let steps = (scene.duration_s / scene.dt_s - 1e-9).ceil().max(0.0) as u64;
    let mut teleports: Vec<&Teleport> = scene.teleports.iter().collect();
    teleports.sort_by(|a, b| a.at_s.total_cmp(&b.at_s));
    let mut next_teleport = 0;
    let mut records = Vec::new();
    let (mut total_substeps, mut max_energy) = (0u64, sim.energy().total_j());
    for step in 0..steps {
        let t = step as f64 * scene.dt_s;
        while next_teleport < teleports.len() && teleports[next_teleport].at_s <= t + 1e-12 {
            sim.teleport(teleports[next_teleport].offset_m);
            next_teleport += 1;
        }
        sim.set_forces(scene.forces_at(t))?;
        let st = sim.step(scene.dt_s)?;
        total_substeps += st.substeps as u64;
        max_energy = max_energy.max(st.energy.total_j());
        if step % scene.record_every as u64 == 0 || step + 1 == steps {
            records.push(StepRecord {
                step,
                time_s: sim.time_s(),
                energy: st.energy,
                energy_j: st.energy.total_j(),
                energy_budget_j: st.energy_budget_j,
                max_displacement_m: st.max_displacement_m,
                substeps: st.substeps,
                cg_iterations: st.cg_iterations,
                guard_triggers: st.guard_triggers,
                frozen_scale_vectors: st.frozen_scale_vectors,
            });
        }
    }
    let (masses, springs, sticks) = sim.counts();
    Ok(SimReport {
        topology: topology.kind.to_string(),
        solver: scene.solver.kind.name().to_owned(),
        masses,
        springs,
        sticks,
        dt_s: scene.dt_s,
        steps,
        total_substeps,
        max_energy_j: max_energy,
        step_stats: records,
        final_positions_m: sim.positions(),
        final_velocities_m_per_s: sim.velocities(),
        final_scale_vectors: sim.scale_vectors(),
    })
}
