//! [`WorldPlan`]: what running a scene takes, decided once before a [`World`] is built — each
//! pack file opened once, the stages the scene's effects call for (docs/design.md "Runtime:
//! scenes and stages"), and the memory the run will hold (docs/design.md "Memory budget"). Every
//! host that runs a scene (`furbake simulate`, `preview` and `view`, a game) builds its world
//! from a plan, so the stages it checks and the memory it budgets are the ones the world runs.
//!
//! The plan reads only what the world it builds will read: the skin mesh of a fur or animated
//! pack, the one spring topology a solver stage simulates, the blade field of a grass pack with
//! a force stage (shared with the world through the pack's decoded sections, never read twice).

use std::sync::Arc;

use furbake_formats::SectionKind;
use furbake_sim::TopologyKind;

use crate::stages::{PackRole, PlannedStage, StageKind, choose_topology, plan_stages};
use crate::{Pack, RuntimeError, Scene, World, WorldOptions};

/// Solver bytes per mass of the simulated topology: position, velocity and their next values,
/// rest state and the model's per-mass arrays (`Vec3A`s and indices), fitted to measurements
/// (docs/design.md "Memory budget").
const SOLVER_BYTES_PER_MASS: u64 = 160;
/// Solver bytes per spring or stick (both ends' adjacency entries, weights, the energy list and
/// the implicit solver's scratch), fitted with [`SOLVER_BYTES_PER_MASS`].
const SOLVER_BYTES_PER_LINK: u64 = 136;
/// Per shell vertex of a fur pack: its rest direction and scale vector (`[f32; 3]` each).
const BYTES_PER_SHELL_VERTEX: u64 = 24;
/// Per triangle corner of a separable topology: the skin transform it follows (`Mat4`, `Mat3`,
/// `Vec3`: 112 bytes) and its skin vertex.
const BYTES_PER_PARTING_CORNER: u64 = 112 + 4;
/// Per skin vertex of an animated pack: its skin transform and posed position and normal.
const BYTES_PER_ANIMATED_VERTEX: u64 = 112 + 2 * 12;
/// Per cluster corner of a grass pack with a force stage: the field's and the frame's `(x, z)`.
const BYTES_PER_GRASS_CORNER: u64 = 16;

/// What one scene entry will hold while the world runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EntryMemory {
    /// The entry's name in the scene.
    pub name: String,
    /// Bytes: the decoded sections of its pack file (counted for the first entry that names the
    /// file, as the entries share them), plus its own solver state, shell vertices, animation
    /// and grass corners.
    pub bytes: u64,
    /// Welded skin vertices (0 when the world reads no skin mesh for it).
    pub vertices: u64,
    /// Skin triangles (0 when the world reads no skin mesh for it).
    pub triangles: u64,
    /// Simulated masses (0 when no solver stage moves its fur).
    pub masses: u64,
    /// Vectors of its state in a [`World::pack_state`] report besides the skin: the simulated
    /// masses' positions and velocities and the scale vectors.
    pub state_vectors: u64,
}

/// A scene's packs opened, its stages planned and its memory estimated, before its [`World`] is
/// built ([`WorldPlan::build`]).
#[derive(Debug)]
pub struct WorldPlan {
    scene: Scene,
    packs: Vec<Arc<Pack>>,
    options: WorldOptions,
    roles: Vec<PackRole>,
    stages: Vec<PlannedStage>,
    memory: Vec<EntryMemory>,
    /// The largest payload among the sections the packs hold decoded once planned.
    largest_payload: u64,
}

impl WorldPlan {
    /// Opens every pack file of `scene` once ([`World::open_packs`]), plans its stages and
    /// estimates its memory.
    pub fn new(scene: Scene, options: WorldOptions) -> Result<WorldPlan, RuntimeError> {
        let packs = World::open_packs(&scene)?;
        WorldPlan::with_packs(scene, packs, options)
    }

    /// As [`WorldPlan::new`] with the packs the caller opened (one per `scene.packs` entry, in
    /// order; entries naming one file share one `Arc`), e.g. after validating each with
    /// `Pack::verify` as `furbake simulate`, `preview` and `view` do.
    pub fn with_packs(scene: Scene, packs: Vec<Arc<Pack>>, options: WorldOptions) -> Result<WorldPlan, RuntimeError> {
        if packs.len() != scene.packs.len() {
            return Err(RuntimeError::Parameter {
                what: format!("{} packs opened for a scene of {}", packs.len(), scene.packs.len()),
            });
        }
        let roles: Vec<PackRole> = scene
            .packs
            .iter()
            .zip(&packs)
            .map(|(sp, p)| PackRole {
                fur: p.has(SectionKind::SHELL_ATLAS) || p.has(SectionKind::SPRING_TOPOLOGY),
                grass: p.has(SectionKind::BLADE_FIELD),
                moving: sp.motion.len() > 1 || options.host_placement,
                topology: p.has(SectionKind::SPRING_TOPOLOGY),
                animated: sp.animation.is_some(),
            })
            .collect();
        let stages = plan_stages(&scene.effects, &roles);
        let mut plan = WorldPlan { scene, packs, options, roles, stages, memory: Vec::new(), largest_payload: 0 };
        plan.memory = plan.estimate_memory()?;
        plan.largest_payload = plan.held_sections().map(|(_, length)| length).max().unwrap_or(0);
        Ok(plan)
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The opened packs, one per scene entry (entries naming one file share it).
    pub fn packs(&self) -> &[Arc<Pack>] {
        &self.packs
    }

    /// The options the world will be built with.
    pub fn options(&self) -> WorldOptions {
        self.options
    }

    /// The stages the world will run, in order.
    pub fn stages(&self) -> &[PlannedStage] {
        &self.stages
    }

    /// What each scene entry will hold, in the scene's order.
    pub fn memory(&self) -> &[EntryMemory] {
        &self.memory
    }

    /// The estimated bytes the world holds while it runs: every entry's, plus the largest
    /// section payload once more (held while it is decoded).
    pub fn estimated_bytes(&self) -> u64 {
        self.memory.iter().map(|m| m.bytes).sum::<u64>().saturating_add(self.largest_payload)
    }

    /// The largest payload among the sections the packs hold decoded once planned (held once
    /// more while it is decoded).
    pub fn largest_payload(&self) -> u64 {
        self.largest_payload
    }

    /// Builds the world this plan describes.
    pub fn build(self) -> Result<World, RuntimeError> {
        World::from_plan(self.scene, self.packs, self.options, self.roles, self.stages)
    }

    /// `(file index, payload length)` of every section the packs hold decoded, each file once
    /// (the first entry naming it).
    fn held_sections(&self) -> impl Iterator<Item = (usize, u64)> + '_ {
        self.packs.iter().enumerate().filter(|(i, p)| self.first_entry_of(p) == *i).flat_map(|(i, p)| {
            p.sections()
                .iter()
                .zip(p.read_counts())
                .filter(|(e, (_, reads))| *reads > 0 && SectionKind::KNOWN.contains(&e.kind))
                .map(move |(e, _)| (i, e.length))
                .collect::<Vec<_>>()
        })
    }

    fn first_entry_of(&self, pack: &Arc<Pack>) -> usize {
        self.packs.iter().position(|q| Arc::ptr_eq(pack, q)).unwrap_or(0)
    }

    /// Each entry's memory, reading what the world will read (see the module doc).
    fn estimate_memory(&self) -> Result<Vec<EntryMemory>, RuntimeError> {
        let parting = self.scene.effects.parting.is_some();
        let mut entries = Vec::with_capacity(self.packs.len());
        for (i, (sp, pack)) in self.scene.packs.iter().zip(&self.packs).enumerate() {
            let role = self.roles[i];
            let planned = |k: StageKind| self.stages.iter().any(|s| s.pack == i && s.kind == k);
            let (vertices, triangles) = if (role.fur || role.animated) && pack.has(SectionKind::SKIN_MESH) {
                let mesh = pack.skin_mesh()?;
                (mesh.positions.len() as u64, mesh.triangles.len() as u64)
            } else {
                (0, 0)
            };
            let mut own = 0u64;
            let (mut masses, mut state_vectors) = (0u64, 0u64);
            if role.fur {
                let simulated = if planned(StageKind::FurSolver) {
                    let available: Vec<TopologyKind> = pack.topology_kinds()?.into_iter().map(|(_, k)| k).collect();
                    // No usable topology: the world refuses the scene when it is built.
                    match choose_topology(&available, parting) {
                        Some(kind) => Some((kind, pack.spring_topology(kind)?)),
                        None => None,
                    }
                } else {
                    None
                };
                match simulated {
                    Some((kind, topology)) => {
                        masses = topology.mass_kg.len() as u64;
                        let links = (topology.spring_ends.len() + topology.stick_ends.len()) as u64;
                        let shell = topology.shell_vertex_masses.len() as u64;
                        own += masses * SOLVER_BYTES_PER_MASS
                            + links * SOLVER_BYTES_PER_LINK
                            + shell * BYTES_PER_SHELL_VERTEX;
                        if kind.is_separable() {
                            own += shell * BYTES_PER_PARTING_CORNER;
                        }
                        state_vectors += 2 * masses + shell;
                    }
                    None => {
                        own += vertices * BYTES_PER_SHELL_VERTEX;
                        state_vectors += vertices;
                    }
                }
            }
            if role.animated {
                own += vertices * BYTES_PER_ANIMATED_VERTEX;
            }
            if planned(StageKind::GrassForces) {
                let corners = pack.blade_field()?.grid.corners() as u64;
                own = own.saturating_add(corners.saturating_mul(BYTES_PER_GRASS_CORNER));
            }
            entries.push(EntryMemory { name: sp.name.clone(), bytes: own, vertices, triangles, masses, state_vectors });
        }
        // The decoded sections of each file, counted for its first entry (read after the loop,
        // which decoded what the world will read).
        for (file, length) in self.held_sections().collect::<Vec<_>>() {
            entries[file].bytes = entries[file].bytes.saturating_add(length);
        }
        Ok(entries)
    }
}
