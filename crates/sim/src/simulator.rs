//! The simulator: a topology's state as struct of arrays (positions, velocities, inverse masses in
//! [`crate::model`]'s internal order), the chosen solver, the force set, the wrong-side guard and
//! the energy bookkeeping the stability tests check. One [`Simulator::step`] advances one frame
//! step: the explicit and stick solvers split it into equal substeps below their stable step
//! (or refuse), every solver checks that the new state is finite before accepting it.

use furbake_formats::sections::spring_topology::SpringTopology;
use glam::Vec3A;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::SimError;
use crate::clusters::Clusters;
use crate::forces::{ForceEval, ForceSet};
use crate::model::SimModel;
use crate::sentinel::NONE;
use crate::shell::{GuardSettings, GuardState};
use crate::skin::{BindPose, SkinMove, SkinTransform};
use crate::solvers::{self, ImplicitScratch, LocalGlobalScratch, ReferenceScratch, Step, XpbdScratch, sum_over};

/// Which solver advances the state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverKind {
    /// Explicit Euler, eq. 3.20–3.25 (substeps below its stable step).
    Explicit,
    /// Implicit Euler, eq. 3.26–3.34 (1 iteration = the thesis's sweep; more: preconditioned CG).
    Implicit,
    /// The stick solver: parent links are rigid sticks, orientation only.
    Stick,
    /// Linearised backward Euler with the exact Jacobian, solved by BiCGSTAB in f64 (Baraff &
    /// Witkin 1998).
    Reference,
    /// Extended position-based dynamics (Macklin, Müller & Chentanez 2016; NVIDIA Warp and
    /// Newton): `xpbd_iterations` Gauss–Seidel passes over compliant link constraints.
    Xpbd,
    /// The fast mass–spring method of Liu, Bargteil, O'Brien & Kavan 2013:
    /// `local_global_iterations` local/global steps with a prefactored constant matrix.
    #[serde(rename = "local_global")]
    LocalGlobal,
}

impl SolverKind {
    /// All solvers, in a fixed order.
    pub const ALL: [SolverKind; 6] = [
        SolverKind::Explicit,
        SolverKind::Implicit,
        SolverKind::Stick,
        SolverKind::Reference,
        SolverKind::Xpbd,
        SolverKind::LocalGlobal,
    ];

    /// The stable name (`explicit`, `implicit`, `stick`, `reference`, `xpbd`, `local_global`).
    pub fn name(self) -> &'static str {
        match self {
            SolverKind::Explicit => "explicit",
            SolverKind::Implicit => "implicit",
            SolverKind::Stick => "stick",
            SolverKind::Reference => "reference",
            SolverKind::Xpbd => "xpbd",
            SolverKind::LocalGlobal => "local_global",
        }
    }

    /// Parses [`SolverKind::name`].
    pub fn from_name(name: &str) -> Option<SolverKind> {
        SolverKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// Solver settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SolverSettings {
    /// The solver. Default implicit.
    pub kind: SolverKind,
    /// Iterations of the implicit solver per step (≥ 1): 1 = the thesis's one sweep; more run
    /// preconditioned conjugate gradient from that sweep. Default 1.
    pub implicit_iterations: u32,
    /// Gauss–Seidel iterations of the XPBD solver per step (≥ 1). Default 8: on the hard cases'
    /// stiff fur (10⁴ N/m) a step then leaves a constraint error near that of one implicit step,
    /// at a cost comparable to the reference solver's; the "small steps" variant is 1 iteration
    /// with the caller stepping `n` times by `dt/n` (XPBD never substeps on its own).
    pub xpbd_iterations: u32,
    /// Local/global iterations of the Liu et al. 2013 solver per step (≥ 1). Default 10, the
    /// paper's choice for real-time use (its fig. 4: most of the gain towards backward Euler
    /// comes within the first ten).
    pub local_global_iterations: u32,
    /// Let the explicit and stick solvers split a step that exceeds their stable step into equal
    /// substeps (default true); off, such a step fails with [`SimError::StepTooLarge`].
    pub allow_substeps: bool,
    /// Most substeps per step before [`SimError::StepTooLarge`]. Default 10,000.
    pub max_substeps: u32,
    /// Fraction of the theoretical stable step the explicit solvers use, (0, 1]. Default 0.25:
    /// `hω ≤ 0.5` for the stiffest mode, which keeps symplectic Euler's energy within
    /// `(1 + hω/2)/(1 − hω/2) ≤ 1.67` of its conserved shadow value.
    pub stability_safety: f32,
    /// Implicit and reference solvers: largest angle (radians) a free mass may turn its shortest
    /// link by in one substep, estimated from its speed and external acceleration; longer steps
    /// are split into substeps. Linearised implicit Euler turns large rotations into stretch and
    /// can add energy, so this keeps it stable by construction. 0 disables it (the raw scheme,
    /// as the accuracy report measures it). Default 0.5.
    pub max_link_rotation_rad: f32,
    /// Relative residual at which the reference solver's BiCGSTAB stops. Default 1e-10.
    pub reference_tolerance: f64,
    /// Most BiCGSTAB iterations per reference step before [`SimError::NotConverged`]. Default
    /// 5,000.
    pub reference_max_iterations: u32,
    /// The wrong-side-scale guard.
    pub guard: GuardSettings,
    /// Compute energy, external work and the largest displacement every step (the statistics of
    /// [`StepStats`]; off in benchmarks). Default true.
    pub track_energy: bool,
}

impl Default for SolverSettings {
    fn default() -> Self {
        SolverSettings {
            kind: SolverKind::Implicit,
            implicit_iterations: 1,
            xpbd_iterations: 8,
            local_global_iterations: 10,
            allow_substeps: true,
            max_substeps: 10_000,
            stability_safety: 0.25,
            max_link_rotation_rad: 0.5,
            reference_tolerance: 1e-10,
            reference_max_iterations: 5_000,
            guard: GuardSettings::default(),
            track_energy: true,
        }
    }
}

impl SolverSettings {
    /// Settings for `kind` with every other field at its default.
    pub fn of(kind: SolverKind) -> Self {
        SolverSettings { kind, ..Default::default() }
    }

    fn validate(&self) -> Result<(), SimError> {
        let bad = |name, what: &str| Err(SimError::Parameter { name, what: what.into() });
        if self.implicit_iterations == 0 {
            return bad("implicit_iterations", "must be at least 1");
        }
        if self.xpbd_iterations == 0 {
            return bad("xpbd_iterations", "must be at least 1");
        }
        if self.local_global_iterations == 0 {
            return bad("local_global_iterations", "must be at least 1");
        }
        if self.max_substeps == 0 {
            return bad("max_substeps", "must be at least 1");
        }
        if !(self.stability_safety > 0.0 && self.stability_safety <= 1.0) {
            return bad("stability_safety", "must lie in (0, 1]");
        }
        if !(self.max_link_rotation_rad.is_finite() && self.max_link_rotation_rad >= 0.0) {
            return bad("max_link_rotation_rad", "must be finite and ≥ 0");
        }
        if !(self.reference_tolerance > 0.0 && self.reference_tolerance < 1.0) {
            return bad("reference_tolerance", "must lie in (0, 1)");
        }
        let a = self.guard.max_angle_deg;
        let impulse = self.guard.impulse_m_per_s;
        if !(a > 0.0 && a < 90.0 && impulse.is_finite() && impulse >= 0.0) {
            return bad("guard", "max_angle_deg must lie in (0, 90), impulse_m_per_s finite and ≥ 0");
        }
        Ok(())
    }
}

/// Energy of the fur, joules. The stability bound applies to [`Energy::total_j`] = kinetic +
/// spring energy; the restoring force of eq. 3.37 is not conservative (its pull does not depend
/// on distance), so its work is booked with the external forces' and `restoring_j` is only
/// informative.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Energy {
    /// `Σ ½ m v²` over free masses.
    pub kinetic_j: f64,
    /// `Σ ½ k (l − l₀)²` over springs.
    pub spring_j: f64,
    /// `Σ ½ w L (1 − n·s)²` over restoring links (an approximate potential of eq. 3.37; not in
    /// the total).
    pub restoring_j: f64,
}

impl Energy {
    /// Kinetic + spring energy (the quantity the energy budget bounds).
    pub fn total_j(&self) -> f64 {
        self.kinetic_j + self.spring_j
    }
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StepStats {
    /// Substeps taken (1 for the implicit and reference solvers).
    pub substeps: u32,
    /// BiCGSTAB iterations (reference solver; summed over substeps).
    pub cg_iterations: u32,
    /// Energy after the step (zero when energy tracking is off).
    pub energy: Energy,
    /// Upper bound the energy must respect: initial energy plus the work of the external and
    /// restoring forces, guard impulses and teleports so far (zero when tracking is off).
    pub energy_budget_j: f64,
    /// Largest distance of a free mass from its rest position, metres (zero when tracking is off).
    pub max_displacement_m: f32,
    /// Tips whose wrong-side test fired in this step.
    pub guard_triggers: u32,
    /// Tips whose scale vector is frozen after this step.
    pub frozen_scale_vectors: u32,
}

/// A topology being simulated.
pub struct Simulator {
    pub(crate) model: SimModel,
    pub(crate) settings: SolverSettings,
    forces: ForceSet,
    pub(crate) x: Vec<Vec3A>,
    pub(crate) v: Vec<Vec3A>,
    x_next: Vec<Vec3A>,
    v_next: Vec<Vec3A>,
    pub(crate) guard: GuardState,
    implicit: ImplicitScratch,
    /// Small independent clusters of free masses the implicit solver solves exactly.
    clusters: Option<Clusters>,
    reference: ReferenceScratch,
    /// The XPBD solver's links, colouring and buffers (XPBD only).
    pub(crate) xpbd: Option<XpbdScratch>,
    /// The local/global solver's matrix, factor and buffers (local/global only).
    local_global: Option<LocalGlobalScratch>,
    stable_dt: Option<(f32, f64)>,
    /// The rotation-limited step of the current state, when the last step's kernel computed it
    /// (cleared by anything that changes the state or the forces).
    rotation_next: Option<f64>,
    /// Per free mass `2 L sqrt(ε m / k)` (see [`Simulator::stretch_limited_step_s`]).
    stretch_reach: Vec<f32>,
    /// The bind pose, once the skin has been posed ([`Simulator::pose_skin`]).
    pub(crate) bind: Option<BindPose>,
    /// Some anchored mass has a velocity (the skin moves): its links' damping does work.
    anchors_moving: bool,
    /// Largest stiffest-link `k / m` over the free masses, 1/s².
    stiff_k_over_m: f64,
    /// The state was just set (start, teleport, `set_state`): no velocity history to estimate
    /// accelerations from.
    fresh: bool,
    /// The last substep's length, seconds.
    last_h: f64,
    pub(crate) time_s: f64,
    steps: u64,
    budget_j: f64,
}

impl Simulator {
    /// Starts at rest (every mass at its rest position, zero velocity) under `ForceSet::default()`.
    pub fn new(topology: &SpringTopology, settings: SolverSettings) -> Result<Simulator, SimError> {
        settings.validate()?;
        let model = SimModel::new(topology, settings.kind == SolverKind::Stick)?;
        let x = model.rest.clone();
        let n = model.n;
        let guard = GuardState::new(&model);
        let (stretch_reach, stiff_k_over_m) = stretch_reach(&model);
        let clusters = if settings.kind == SolverKind::Implicit { Clusters::find(&model) } else { None };
        let xpbd = (settings.kind == SolverKind::Xpbd).then(|| XpbdScratch::new(&model));
        let local_global = (settings.kind == SolverKind::LocalGlobal).then(|| LocalGlobalScratch::new(&model));
        let mut sim = Simulator {
            x_next: x.clone(),
            x,
            v: vec![Vec3A::ZERO; n],
            v_next: vec![Vec3A::ZERO; n],
            model,
            settings,
            forces: ForceSet::default(),
            guard,
            implicit: ImplicitScratch::default(),
            clusters,
            reference: ReferenceScratch::default(),
            xpbd,
            local_global,
            stable_dt: None,
            rotation_next: None,
            stretch_reach,
            bind: None,
            anchors_moving: false,
            stiff_k_over_m,
            fresh: true,
            last_h: 0.0,
            time_s: 0.0,
            steps: 0,
            budget_j: 0.0,
        };
        sim.budget_j = sim.energy().total_j();
        Ok(sim)
    }

    /// Replaces the force set.
    pub fn set_forces(&mut self, forces: ForceSet) -> Result<(), SimError> {
        forces.validate()?;
        self.forces = forces;
        self.rotation_next = None;
        self.fresh = true;
        Ok(())
    }

    /// [`Simulator::set_forces`] from a borrowed set, copied into this simulator's own without
    /// allocating once its list of local forces is long enough (a host's per-step update).
    pub fn set_forces_from(&mut self, forces: &ForceSet) -> Result<(), SimError> {
        forces.validate()?;
        self.forces.clone_from(forces);
        self.rotation_next = None;
        self.fresh = true;
        Ok(())
    }

    /// The current force set.
    pub fn forces(&self) -> &ForceSet {
        &self.forces
    }

    /// The settings.
    pub fn settings(&self) -> &SolverSettings {
        &self.settings
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Steps taken.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Number of masses, springs and sticks.
    pub fn counts(&self) -> (usize, usize, usize) {
        (self.model.n, self.model.spring_count, self.model.stick_count)
    }

    /// The stable step of the explicit and stick solvers for the current forces, seconds
    /// (infinite for the implicit, reference, XPBD and local/global solvers and when nothing
    /// limits the step).
    pub fn stable_step_s(&mut self) -> f64 {
        let w = self.forces.restoring_weight_n;
        match self.stable_dt {
            Some((cw, dt)) if cw == w => dt,
            _ => {
                let dt = match self.settings.kind {
                    SolverKind::Explicit => solvers::stable_step(&self.model, w, false, self.settings.stability_safety),
                    SolverKind::Stick => solvers::stable_step(&self.model, w, false, self.settings.stability_safety),
                    SolverKind::Implicit | SolverKind::Reference | SolverKind::Xpbd | SolverKind::LocalGlobal => {
                        f64::INFINITY
                    }
                };
                self.stable_dt = Some((w, dt));
                dt
            }
        }
    }

    /// The implicit solvers' step limit from `max_link_rotation_rad`: per free mass the `h` with
    /// `|v| h + |a| h² = θ · shortest link`, `a` the external and restoring acceleration at the
    /// current state; infinite when disabled.
    fn rotation_limited_step_s(&self) -> f64 {
        let theta = self.settings.max_link_rotation_rad as f64;
        if theta == 0.0 {
            return f64::INFINITY;
        }
        let fe = ForceEval::new(&self.forces, self.time_s);
        solvers::rotation_limit(&self.model, &fe, theta, &self.x, &self.v)
    }

    /// The implicit solvers' second step limit (on top of `max_link_rotation_rad`, off with it):
    /// turning a link of length `L` and stiffness `k` by `θ = d/L` (`d = |v| h + |a| h²`, the
    /// step's displacement) makes linearised backward Euler stretch it by `L θ²/2`, a spurious
    /// energy `k L² θ⁴/8`, while the motion carries `½ m (d/h)²`. Their ratio
    /// `k h² d²/(4 m L²)` stays below [`STRETCH_ENERGY_RATIO`] when `h d ≤ 2 L sqrt(ε m/k)`
    /// (stiffest link, shortest length, per mass; each of the two terms within half). `a` is the
    /// net acceleration: from the last substep's velocity change, or — right after the state was
    /// set (start, teleport, `set_state`) — from one evaluation of every force on the mass.
    /// Skipped (infinite) when the rotation limit alone already keeps the ratio below `ε`, i.e.
    /// `dt² k/m ≤ 16 ε/θ²` for every mass: soft fur never pays for this scan.
    fn stretch_limited_step_s(&self, dt_s: f64) -> f64 {
        let theta = self.settings.max_link_rotation_rad as f64;
        if theta == 0.0 || dt_s * dt_s * self.stiff_k_over_m <= 16.0 * STRETCH_ENERGY_RATIO / (theta * theta) {
            return f64::INFINITY;
        }
        let m = &self.model;
        let fe = ForceEval::new(&self.forces, self.time_s);
        let (x, v, v_prev) = (&self.x, &self.v, &self.v_next);
        (0..m.n_free)
            .into_par_iter()
            .with_min_len(solvers::CHUNK)
            .map(|k| {
                let c = self.stretch_reach[k] as f64;
                if !c.is_finite() {
                    return f64::INFINITY;
                }
                let a = if self.fresh || self.last_h <= 0.0 {
                    let mut f = fe.external(m.mass[k], x[k], v[k], m.rest[k]);
                    for l in m.adj_of(k) {
                        let j = l.other as usize;
                        let d = x[j] - x[k];
                        let len = d.length();
                        if len > 0.0 {
                            f += d * (l.k * (1.0 - l.rest / len));
                        }
                        f += (v[j] - v[k]) * l.c;
                    }
                    (f.length() / m.mass[k]) as f64
                } else {
                    ((v[k] - v_prev[k]).length() as f64) / self.last_h
                };
                let speed = v[k].length() as f64;
                let by_v = if speed > 0.0 { (0.5 * c / speed).sqrt() } else { f64::INFINITY };
                let by_a = if a > 0.0 { (0.5 * c / a).cbrt() } else { f64::INFINITY };
                by_v.min(by_a)
            })
            .reduce(|| f64::INFINITY, f64::min)
    }

    /// Moves the mesh frame by `offset_m` in one instant: free masses stay where they were in the
    /// world, so in the mesh frame they jump by `−offset_m`; rigid links are re-projected at once
    /// (removing velocity along them); otherwise velocities are unchanged. The change in energy is
    /// added to the energy budget.
    pub fn teleport(&mut self, offset_m: [f32; 3]) {
        let before = if self.settings.track_energy { self.energy().total_j() } else { 0.0 };
        self.rotation_next = None;
        self.fresh = true;
        let o = Vec3A::from(offset_m);
        for x in &mut self.x[..self.model.n_free] {
            *x -= o;
        }
        // Rigid links snap back at once, as part of the jump (their energy change is booked
        // with the teleport, not with the next step).
        solvers::project_sticks(&self.model, &mut self.x, &mut self.v);
        if self.settings.track_energy {
            self.budget_j += self.energy().total_j() - before;
        }
    }

    /// Shell vertices (scale vectors; [`Simulator::pose_skin`] takes one transform per shell
    /// vertex): welded skin vertices, or triangle corners for a separable topology.
    pub fn shell_vertex_count(&self) -> usize {
        self.model.shell_tip.len()
    }

    /// Poses the topology on the animated skin for the step of `dt_s` seconds that follows:
    /// `transforms` has one [`SkinTransform`] per shell vertex (bind pose → now). Anchored masses
    /// take their posed positions, with the velocity of that motion over `dt_s`; free masses'
    /// rest positions and rest directions follow (see [`crate::skin`]). When an anchor would move
    /// faster than `cut_speed_m_per_s` the fur is carried along instead (a cut). Work done on the
    /// fur by the move is added to the energy budget. Fails, changing nothing, on a wrong count,
    /// a non-finite transform or a bad `dt_s`.
    pub fn pose_skin(
        &mut self,
        transforms: &[SkinTransform],
        dt_s: f64,
        cut_speed_m_per_s: f32,
    ) -> Result<SkinMove, SimError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(SimError::Parameter { name: "dt_s", what: format!("{dt_s} (must be finite and positive)") });
        }
        if cut_speed_m_per_s.is_nan() || cut_speed_m_per_s < 0.0 {
            return Err(SimError::Parameter { name: "cut_speed_m_per_s", what: format!("{cut_speed_m_per_s}") });
        }
        BindPose::check(&self.model, transforms).map_err(|what| SimError::Parameter { name: "transforms", what })?;
        let before = if self.settings.track_energy { self.energy().total_j() } else { 0.0 };
        let bind = self.bind.get_or_insert_with(|| BindPose::new(&self.model));
        let moved = bind.pose(
            &mut self.model,
            transforms,
            dt_s,
            cut_speed_m_per_s,
            &mut self.x,
            &mut self.x_next,
            &mut self.v,
            &mut self.v_next,
        );
        // Rigid links snap onto their moved anchors at once, as a teleport's do, so the work of
        // dragging them is measured with the move (the solver's projections then see static
        // anchors).
        solvers::project_sticks(&self.model, &mut self.x, &mut self.v);
        self.guard.follow_rest_directions(&self.model, &self.settings.guard);
        self.rotation_next = None;
        self.fresh = true;
        self.anchors_moving = !moved.cut && moved.max_anchor_speed_m_per_s > 0.0;
        if self.settings.track_energy {
            self.budget_j += self.energy().total_j() - before;
        }
        Ok(moved)
    }

    /// The substeps a step of `dt_s` takes: one when `dt_s` is within the solver's stable step,
    /// else as many as make it so; a [`SimError::StepTooLarge`] when that is more than the settings
    /// allow. What [`Simulator::step`] does, for solvers that step elsewhere (compute shaders).
    pub fn substeps_for(&mut self, dt_s: f64) -> Result<u32, SimError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(SimError::Parameter { name: "dt_s", what: format!("{dt_s} (must be finite and positive)") });
        }
        let stable = match self.settings.kind {
            SolverKind::Explicit | SolverKind::Stick => self.stable_step_s(),
            SolverKind::Implicit | SolverKind::Reference => match self.rotation_next {
                Some(h) => h,
                None => self.rotation_limited_step_s(),
            }
            .min(self.stretch_limited_step_s(dt_s)),
            // Both solve the nonlinear springs (no linearisation to protect): never substepped.
            SolverKind::Xpbd | SolverKind::LocalGlobal => f64::INFINITY,
        };
        let substeps = if dt_s <= stable {
            1u64
        } else {
            let needed = (dt_s / stable).ceil() as u64;
            let allowed = if self.settings.allow_substeps { self.settings.max_substeps } else { 1 };
            if needed > allowed as u64 {
                return Err(SimError::StepTooLarge { dt_s, stable_dt_s: stable, needed, allowed });
            }
            needed
        };
        Ok(substeps as u32)
    }

    /// Advances by `dt_s` seconds.
    pub fn step(&mut self, dt_s: f64) -> Result<StepStats, SimError> {
        if self.model.n_free >= solvers::PARALLEL_MIN && rayon::current_thread_index().is_none() {
            // Called from outside the thread pool: hand the whole step to the pool once, so its
            // parallel passes start from a worker instead of each waking the pool and putting
            // the caller to sleep (measured: up to 30 % of an 18,152-mass explicit step).
            rayon::scope(|_| self.step_in_pool(dt_s))
        } else {
            self.step_in_pool(dt_s)
        }
    }

    fn step_in_pool(&mut self, dt_s: f64) -> Result<StepStats, SimError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(SimError::Parameter { name: "dt_s", what: format!("{dt_s} (must be finite and positive)") });
        }
        let substeps = self.substeps_for(dt_s)? as u64;
        // The rotation limit it used belongs to the state before this step.
        self.rotation_next = None;
        let h = dt_s / substeps as f64;
        let mut stats = StepStats { substeps: substeps as u32, ..Default::default() };
        let mut work_j = 0.0;
        let mut fused_guard = None;
        let mut rotation_next = None;
        for sub in 0..substeps {
            let t = self.time_s + sub as f64 * h;
            let fe = ForceEval::new(&self.forces, t);
            let hf = h as f32;
            let (x, v) = (&self.x, &self.v);
            let (xo, vo) = (&mut self.x_next, &mut self.v_next);
            // The mass–spring kernels run the guard in their pass on the last substep, if they can.
            let guard = (sub + 1 == substeps).then_some((&self.settings.guard, &mut self.guard));
            let step = Step {
                model: &self.model,
                fe: &fe,
                h: hf,
                x,
                v,
                x_out: xo,
                v_out: vo,
                guard,
                rotation: Some(self.settings.max_link_rotation_rad as f64),
            };
            let out = match self.settings.kind {
                SolverKind::Explicit => solvers::explicit_step(Step { rotation: None, ..step }),
                SolverKind::Stick => solvers::stick_step(Step { rotation: None, ..step }),
                SolverKind::Implicit => solvers::implicit_step(
                    step,
                    self.settings.implicit_iterations,
                    self.clusters.as_ref(),
                    &mut self.implicit,
                ),
                SolverKind::Reference => {
                    let r = solvers::reference_step(
                        step,
                        self.settings.reference_tolerance,
                        self.settings.reference_max_iterations,
                        &mut self.reference,
                    );
                    stats.cg_iterations += r.iterations;
                    if r.residual > self.settings.reference_tolerance && r.residual.is_finite() {
                        return Err(SimError::NotConverged { iterations: r.iterations, residual: r.residual });
                    }
                    r.step
                }
                SolverKind::Xpbd => solvers::xpbd_step(
                    step,
                    self.settings.xpbd_iterations,
                    self.xpbd.as_mut().expect("built in Simulator::new for the XPBD solver"),
                ),
                SolverKind::LocalGlobal => solvers::local_global_step(
                    step,
                    self.settings.local_global_iterations,
                    self.local_global.as_mut().expect("built in Simulator::new for the local/global solver"),
                )?,
            };
            // The lane-group kernels check their output as they write it; the rest is checked here.
            if !out.finite {
                self.check_finite(t)?;
            }
            fused_guard = out.guard;
            rotation_next = out.rotation;
            if self.settings.track_energy {
                work_j += self.external_work(&fe);
            }
            std::mem::swap(&mut self.x, &mut self.x_next);
            std::mem::swap(&mut self.v, &mut self.v_next);
        }
        let g = match fused_guard {
            Some(g) => g,
            None => self.guard.apply(&self.model, &self.settings.guard, &self.x, &mut self.v),
        };
        self.time_s += dt_s;
        self.steps += 1;
        self.rotation_next = rotation_next;
        self.fresh = false;
        self.last_h = h;
        stats.guard_triggers = g.triggers;
        stats.frozen_scale_vectors = g.frozen;
        if self.settings.track_energy {
            stats.max_displacement_m = self.max_displacement_m();
            self.budget_j += work_j + g.kinetic_added_j;
            stats.energy = self.energy();
            stats.energy_budget_j = self.budget_j;
        }
        Ok(stats)
    }

    fn check_finite(&self, t: f64) -> Result<(), SimError> {
        let nf = self.model.n_free;
        let (xs, vs) = (&self.x_next[..nf], &self.v_next[..nf]);
        // One pass over both arrays; the slow search below only runs on failure.
        let ok = if nf < 4 * solvers::CHUNK {
            xs.iter().zip(vs).all(|(p, q)| (*p + *q).is_finite() || (p.is_finite() && q.is_finite()))
        } else {
            xs.par_chunks(solvers::CHUNK)
                .zip(vs.par_chunks(solvers::CHUNK))
                .all(|(a, b)| a.iter().zip(b).all(|(p, q)| (*p + *q).is_finite() || (p.is_finite() && q.is_finite())))
        };
        if ok {
            return Ok(());
        }
        for (what, s) in [("position", xs), ("velocity", vs)] {
            if let Some(k) = s.iter().position(|p| !p.is_finite()) {
                return Err(SimError::NonFinite {
                    step: self.steps,
                    time_s: t,
                    what: format!("{what} of mass {} is {:?}", self.model.order[k], s[k]),
                });
            }
        }
        Ok(())
    }

    /// Work of the external and restoring forces (evaluated at the start of the substep) over
    /// the substep.
    fn external_work(&self, fe: &ForceEval) -> f64 {
        let m = &self.model;
        sum_over(m.n_free, |k| {
            let mut f = if fe.uniform_only() {
                fe.accel * m.mass[k]
            } else {
                fe.external(m.mass[k], self.x[k], self.v[k], m.rest[k])
            };
            let p = m.rest_parent[k];
            if p != NONE && fe.restoring_w != 0.0 {
                f += crate::forces::restoring_force(self.x[p as usize], self.x[k], m.rest_n[k], fe.restoring_w);
            }
            if self.anchors_moving {
                // A moving skin drags through the damping of its links (`c · v_anchor`; the
                // `−c · v_k` part only dissipates).
                for l in m.adj_of(k).iter().filter(|l| l.other as usize >= m.n_free) {
                    f += self.v[l.other as usize] * l.c;
                }
                // The stick solver damps a rigid link towards its parent's velocity.
                let p = m.parent[k];
                if p != NONE && p as usize >= m.n_free {
                    f += self.v[p as usize] * m.parent_c[k];
                }
            }
            // Over the whole displacement, projections included (a teleport's projection is
            // booked with the teleport itself).
            f.dot(self.x_next[k] - self.x[k]) as f64
        })
    }

    /// Energy of the current state.
    pub fn energy(&self) -> Energy {
        let m = &self.model;
        let x = &self.x;
        let kinetic_j = sum_over(m.n_free, |k| 0.5 * m.mass[k] as f64 * self.v[k].length_squared() as f64);
        let spring_j = sum_over(m.springs.len(), |s| {
            let ([a, b], rest, k) = m.springs[s];
            let l = x[a as usize].as_dvec3().distance(x[b as usize].as_dvec3());
            0.5 * k as f64 * (l - rest as f64).powi(2)
        });
        let w = self.forces.restoring_weight_n as f64;
        let restoring_j = sum_over(m.n_free, |k| {
            let p = m.rest_parent[k];
            if p == NONE {
                return 0.0;
            }
            let len = m.rest_len[k] as f64;
            match (x[k] - x[p as usize]).try_normalize() {
                Some(s) => 0.5 * w * len * (1.0 - m.rest_n[k].dot(s) as f64).powi(2),
                None => 0.5 * w * len,
            }
        });
        Energy { kinetic_j, spring_j, restoring_j }
    }

    /// Largest distance of a free mass from its rest position, metres.
    pub fn max_displacement_m(&self) -> f32 {
        let m = &self.model;
        self.x[..m.n_free]
            .par_iter()
            .with_min_len(solvers::CHUNK)
            .zip(&m.rest[..m.n_free])
            .map(|(x, r)| x.distance(*r))
            .reduce(|| 0.0, f32::max)
    }

    fn to_topology_order(&self, internal: &[Vec3A]) -> Vec<[f32; 3]> {
        let mut out = vec![[0.0; 3]; self.model.n];
        for (k, &i) in self.model.order.iter().enumerate() {
            out[i as usize] = internal[k].to_array();
        }
        out
    }

    /// Mass positions in the mesh frame, in the topology's mass order, metres.
    pub fn positions(&self) -> Vec<[f32; 3]> {
        self.to_topology_order(&self.x)
    }

    /// Mass positions in f64 (topology order), metres, when the solver carries an f64 state (the
    /// reference solver, while the simulator's f32 state is its rounding); `None` otherwise.
    pub fn positions_f64(&self) -> Option<Vec<[f64; 3]>> {
        if self.settings.kind != SolverKind::Reference {
            return None;
        }
        let m = &self.model;
        let mut out = vec![[0.0; 3]; m.n];
        for (k, &i) in m.order.iter().enumerate() {
            let p = if k < m.n_free { self.reference.position_f64(k, self.x[k]) } else { self.x[k].as_dvec3() };
            out[i as usize] = p.to_array();
        }
        Some(out)
    }

    /// Mass velocities in the mesh frame, in the topology's mass order, m/s.
    pub fn velocities(&self) -> Vec<[f32; 3]> {
        self.to_topology_order(&self.v)
    }

    /// Overwrites positions and velocities (topology order). Anchored masses keep their rest
    /// positions and zero velocity whatever is passed for them.
    pub fn set_state(&mut self, positions: &[[f32; 3]], velocities: &[[f32; 3]]) -> Result<(), SimError> {
        let n = self.model.n;
        if positions.len() != n || velocities.len() != n {
            return Err(SimError::Parameter { name: "state", what: format!("expected {n} positions and velocities") });
        }
        if positions.iter().chain(velocities).flatten().any(|c| !c.is_finite()) {
            return Err(SimError::Parameter { name: "state", what: "not finite".into() });
        }
        self.rotation_next = None;
        self.fresh = true;
        for k in 0..self.model.n_free {
            let i = self.model.order[k] as usize;
            self.x[k] = Vec3A::from(positions[i]);
            self.v[k] = Vec3A::from(velocities[i]);
        }
        if self.settings.track_energy {
            self.budget_j = self.energy().total_j();
        }
        Ok(())
    }

    /// Scale vectors (eq. 3.35) per shell vertex after the guard, as rendering uses them;
    /// `[0, 0, 0]` for shell vertices without fur.
    pub fn scale_vectors(&self) -> Vec<[f32; 3]> {
        self.model
            .shell_tip
            .iter()
            .map(|&s| if s == NONE { [0.0; 3] } else { self.guard.scale[s as usize].to_array() })
            .collect()
    }

    /// As [`Simulator::scale_vectors`], written into `out` (one per shell vertex) without
    /// allocating, for per-frame use. Fails when `out` has the wrong length.
    pub fn write_scale_vectors(&self, out: &mut [[f32; 3]]) -> Result<(), SimError> {
        if out.len() != self.model.shell_tip.len() {
            return Err(SimError::Parameter {
                name: "scale_vectors",
                what: format!("{} slots for {} shell vertices", out.len(), self.model.shell_tip.len()),
            });
        }
        for (o, &s) in out.iter_mut().zip(&self.model.shell_tip) {
            *o = if s == NONE { [0.0; 3] } else { self.guard.scale[s as usize].to_array() };
        }
        Ok(())
    }

    /// Rest directions (vertex normals) per shell vertex; `[0, 0, 0]` without fur.
    pub fn shell_normals(&self) -> Vec<[f32; 3]> {
        self.model
            .shell_tip
            .iter()
            .map(|&s| if s == NONE { [0.0; 3] } else { self.model.tips[s as usize].n.to_array() })
            .collect()
    }

    /// Raw scale vectors straight from the masses (before the guard); `None` where a tip sits on
    /// its root or the vertex has no fur.
    pub fn raw_scale_vectors(&self) -> Vec<Option<[f32; 3]>> {
        self.model
            .shell_tip
            .iter()
            .map(|&s| {
                if s == NONE {
                    return None;
                }
                let t = self.model.tips[s as usize];
                (self.x[t.tip as usize] - self.x[t.root as usize]).try_normalize().map(|v| v.to_array())
            })
            .collect()
    }
}

/// Largest ratio of the linearisation's spurious stretch energy to the kinetic energy of a step's
/// motion that the implicit and reference solvers accept before substepping (see
/// `Simulator::stretch_limited_step_s`).
pub(crate) const STRETCH_ENERGY_RATIO: f64 = 0.05;

/// Per free mass `2 L sqrt(ε m / k)` (`L` its shortest link, `k` its stiffest, `ε` =
/// [`STRETCH_ENERGY_RATIO`]; infinite without links), and the largest `k / m`.
fn stretch_reach(model: &SimModel) -> (Vec<f32>, f64) {
    let mut stiff = 0.0f64;
    let reach = (0..model.n_free)
        .map(|k| {
            let stiffest = model.adj_of(k).iter().map(|a| a.k).fold(0.0f32, f32::max) as f64;
            let l = model.shortest_link[k] as f64;
            stiff = stiff.max(stiffest / model.mass[k] as f64);
            if stiffest > 0.0 && l.is_finite() {
                (2.0 * l * (STRETCH_ENERGY_RATIO * model.mass[k] as f64 / stiffest).sqrt()) as f32
            } else {
                f32::INFINITY
            }
        })
        .collect();
    (reach, stiff)
}
