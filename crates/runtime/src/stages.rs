//! The stage plan (docs/design.md "Runtime: scenes and stages", the user's ask 3): which per-step stages a scene
//! needs, decided from its declared [`Effects`] and from each pack's section table alone — no
//! effect, no stage — plus the rules that pick a pack's spring topology (separable only when the
//! scene parts fur, fur thesis §3.4.1) and its solver (§3.3), and the per-stage counters.
//!
//! Stages, in the order one [`crate::World::step`] runs them, each with a stable name:
//!
//! | name                | per   | built when the scene declares                     | does |
//! |---------------------|-------|---------------------------------------------------|------|
//! | `animation`         | pack  | an `animation` for the pack                       | advances its clip player, skins the mesh (morph, then linear blend skinning) and poses the fur's anchored masses on it |
//! | `fur_object_motion` | fur   | object motion and the pack has motion keys        | differentiates the motion path into frame accelerations (inertial forces) |
//! | `fur_gravity`       | fur   | gravity                                           | gravity in the mesh frame |
//! | `fur_wind`          | fur   | wind or wind sources                              | the travelling-gust wind force in the mesh frame |
//! | `fur_interaction`   | fur   | interaction                                       | the brush as a local force |
//! | `fur_solver`        | fur   | any of the five above, the wrong-side guard, or an animation | one solver step, the guard (§3.4.3) at its end |
//! | `fur_scale_vectors` | fur   | same as `fur_solver`                              | scale vectors per shell vertex (eq. 3.35) for the renderer |
//! | `grass_forces`      | grass | wind, wind sources, collisions or windless areas  | the cluster-corner force field (grass thesis §3.2.2, eq. 4.1, ch. 5) |
//!
//! A pack is a fur pack when its table lists a shell atlas or a spring topology, a grass pack when
//! it lists a blade field (a pack can be both). Fur stages are planned for fur packs, except for a
//! grass pack baked without any spring topology: its effects reach it through `grass_forces` and
//! its shells stay at rest (a fur-only pack without a usable topology is an error instead, see
//! [`crate::RuntimeError::MissingTopology`]). The wrong-side guard has no stage of its own:
//! furbake-sim applies it inside each solver step, so its time is part of `fur_solver`.

use std::time::Duration;

use furbake_sim::{SolverKind, TopologyKind};
use serde::Serialize;

use crate::scene::{Effect, Effects, SolverChoice};

/// One kind of stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StageKind {
    /// The pack's clip player, skinning and the fur's posed anchors.
    Animation,
    /// Frame accelerations from the motion path.
    FurObjectMotion,
    /// Gravity in the mesh frame.
    FurGravity,
    /// Global wind on the fur.
    FurWind,
    /// The interaction brush.
    FurInteraction,
    /// One solver step (with the wrong-side guard when declared).
    FurSolver,
    /// Scale vectors for the renderer.
    FurScaleVectors,
    /// The grass cluster force field.
    GrassForces,
}

impl StageKind {
    /// Every stage kind, in run order.
    pub const ALL: [StageKind; 8] = [
        StageKind::Animation,
        StageKind::FurObjectMotion,
        StageKind::FurGravity,
        StageKind::FurWind,
        StageKind::FurInteraction,
        StageKind::FurSolver,
        StageKind::FurScaleVectors,
        StageKind::GrassForces,
    ];

    /// The stable name (see the module table).
    pub fn name(self) -> &'static str {
        match self {
            StageKind::Animation => "animation",
            StageKind::FurObjectMotion => "fur_object_motion",
            StageKind::FurGravity => "fur_gravity",
            StageKind::FurWind => "fur_wind",
            StageKind::FurInteraction => "fur_interaction",
            StageKind::FurSolver => "fur_solver",
            StageKind::FurScaleVectors => "fur_scale_vectors",
            StageKind::GrassForces => "grass_forces",
        }
    }
}

impl std::fmt::Display for StageKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the planner knows about a pack before reading any section: its roles, from the section
/// table, and whether the scene moves it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PackRole {
    /// The pack has shells or a spring topology.
    pub fur: bool,
    /// The pack has a blade field.
    pub grass: bool,
    /// The scene gives the pack motion keys.
    pub moving: bool,
    /// The pack holds at least one spring topology.
    pub topology: bool,
    /// The scene gives the pack an animation.
    pub animated: bool,
}

/// One planned stage.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct PlannedStage {
    /// What it does.
    pub kind: StageKind,
    /// Index of the pack it works on, in scene order.
    pub pack: usize,
    /// The effects it serves.
    pub effects: Vec<Effect>,
}

/// Plans the stages of one step for `effects` over packs with `roles` (scene order): pack by
/// pack, stages in [`StageKind::ALL`] order. An effect the scene does not declare yields no stage;
/// a pack no declared effect touches yields none either.
pub fn plan_stages(effects: &Effects, roles: &[PackRole]) -> Vec<PlannedStage> {
    let mut plan = Vec::new();
    for (pack, role) in roles.iter().enumerate() {
        let mut push = |kind, effects: Vec<Effect>| plan.push(PlannedStage { kind, pack, effects });
        if role.animated {
            push(StageKind::Animation, Vec::new());
        }
        if role.fur && (role.topology || !role.grass) {
            let moving = effects.object_motion.is_some() && role.moving;
            let on = |pairs: &[(bool, Effect)]| pairs.iter().filter(|(on, _)| *on).map(|&(_, e)| e).collect::<Vec<_>>();
            let wind =
                on(&[(effects.wind.is_some(), Effect::Wind), (!effects.wind_sources.is_empty(), Effect::WindSources)]);
            let mut physics = Vec::new();
            for (kind, served) in [
                (StageKind::FurObjectMotion, on(&[(moving, Effect::ObjectMotion)])),
                (StageKind::FurGravity, on(&[(effects.gravity.is_some(), Effect::Gravity)])),
                (StageKind::FurWind, wind),
                (StageKind::FurInteraction, on(&[(effects.interaction.is_some(), Effect::Interaction)])),
            ] {
                if !served.is_empty() {
                    physics.extend_from_slice(&served);
                    push(kind, served);
                }
            }
            if effects.wrong_side_guard.is_some() {
                physics.push(Effect::WrongSideGuard);
            }
            // An animated skin moves its fur by itself: the solver runs even with no force.
            if !physics.is_empty() || (role.animated && role.topology) {
                if effects.parting.is_some() {
                    physics.push(Effect::Parting);
                }
                push(StageKind::FurSolver, physics.clone());
                push(StageKind::FurScaleVectors, physics);
            }
        }
        if role.grass {
            let grass: Vec<Effect> = [
                (effects.wind.is_some(), Effect::Wind),
                (!effects.wind_sources.is_empty(), Effect::WindSources),
                (!effects.collisions.is_empty(), Effect::Collisions),
                (!effects.windless_areas.is_empty(), Effect::WindlessAreas),
            ]
            .into_iter()
            .filter(|(on, _)| *on)
            .map(|(_, e)| e)
            .collect();
            if !grass.is_empty() {
                push(StageKind::GrassForces, grass);
            }
        }
    }
    plan
}

/// Topologies a scene without parting uses, most preferred first (prisms keep neighbouring tips
/// together; chains cost the most masses).
pub const NON_SEPARABLE_PREFERENCE: [TopologyKind; 5] = [
    TopologyKind::PRISMS,
    TopologyKind::SPRING_STICKS,
    TopologyKind::STICKS,
    TopologyKind::CHAIN,
    TopologyKind::REDUCED_CHAIN,
];

/// Topologies a scene with parting uses, most preferred first.
pub const SEPARABLE_PREFERENCE: [TopologyKind; 3] =
    [TopologyKind::SEPARABLE_PRISMS, TopologyKind::SEPARABLE_SPRING_STICKS, TopologyKind::SEPARABLE_STICKS];

/// The topology to simulate among `available`: the first of [`SEPARABLE_PREFERENCE`] when
/// `parting`, else of [`NON_SEPARABLE_PREFERENCE`]; `None` when none is available.
pub fn choose_topology(available: &[TopologyKind], parting: bool) -> Option<TopologyKind> {
    let order: &[TopologyKind] = if parting { &SEPARABLE_PREFERENCE } else { &NON_SEPARABLE_PREFERENCE };
    order.iter().copied().find(|k| available.contains(k))
}

/// XPBD iterations per step of the solver [`SolverChoice::Auto`] picks for an animated pack.
pub const AUTO_ANIMATED_XPBD_ITERATIONS: u32 = 1;

/// The solver for `kind` on a pack whose skin is `animated` or not, its physics on `device`: the
/// scene's choice, or with [`SolverChoice::Auto`] the stick solver for the stick kinds (their
/// links are rigid), XPBD with [`AUTO_ANIMATED_XPBD_ITERATIONS`] iteration for the other kinds
/// on an animated skin, and for the rest implicit Euler on the CPU (springs stiff enough to need
/// it, eq. 3.26–3.34) and XPBD on the GPU (the implicit-class solver with a compute form). Why XPBD on an
/// animated skin (docs/accuracy.md "Fox walking, prisms"): at game steps every solver's error
/// there is dominated by posing the skin once per step, which XPBD with one iteration reaches at
/// 1/4–1/8 of implicit Euler's cost, in one substep, where implicit Euler's rotation limit splits
/// a walking Fox's step of 1/30 s into 39.
pub fn choose_solver(
    kind: TopologyKind,
    choice: SolverChoice,
    animated: bool,
    device: crate::PhysicsDevice,
) -> SolverKind {
    match choice {
        SolverChoice::Auto if kind.uses_sticks() => SolverKind::Stick,
        SolverChoice::Auto if animated || device == crate::PhysicsDevice::Gpu => SolverKind::Xpbd,
        SolverChoice::Auto => SolverKind::Implicit,
        SolverChoice::Explicit => SolverKind::Explicit,
        SolverChoice::Implicit => SolverKind::Implicit,
        SolverChoice::Stick => SolverKind::Stick,
        SolverChoice::Reference => SolverKind::Reference,
        SolverChoice::Xpbd => SolverKind::Xpbd,
        SolverChoice::LocalGlobal => SolverKind::LocalGlobal,
    }
}

/// How often one planned stage ran and for how long.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct StageStats {
    /// The stage's stable name ([`StageKind::name`]).
    pub name: &'static str,
    /// The scene name of the pack it works on.
    pub pack: String,
    /// Times it ran.
    pub runs: u64,
    /// Wall time of all its runs together.
    pub total: Duration,
}

impl StageStats {
    /// Mean wall time per run (zero before the first run).
    pub fn mean(&self) -> Duration {
        if self.runs == 0 { Duration::ZERO } else { self.total / self.runs.min(u32::MAX as u64) as u32 }
    }
}
