//! Fur physics on the GPU: the explicit and stick mass–spring solvers (fur thesis §3.3.2,
//! eq. 3.20–3.25; §3.4.1) and XPBD (edge-coloured Gauss–Seidel, a whole step in one workgroup), the
//! wrong-side guard (§3.4.3) and the scale vectors (eq. 3.35) as
//! compute passes (`shaders/fur_physics.wgsl`) over the flat model a CPU
//! [`furbake_sim::Simulator`] hands over ([`furbake_sim::ComputeModel`]), recorded into the host's
//! encoder and writing the scale vectors straight into the buffer its [`FurRenderer`]'s shell
//! shader reads — nothing is read back in a frame. Same forces as the CPU (gravity, wind, the
//! rotating frame's inertial forces, up to [`MAX_LOCAL_FORCES`] local forces, the restoring force
//! of eq. 3.37), same substep count for the same step; the counters (non-finite masses, guard
//! triggers, frozen tips) come back only when asked for, without waiting
//! ([`GpuFurPhysics::request_stats`]). docs/design.md "Fur physics on the GPU" has the design and
//! the measured agreement with the CPU.
//!
//! Packs of one asset step as a herd ([`GpuFurPhysics::herd`]): one set of buffers, one
//! dispatch per pass for up to 64 packs, each pack with its own forces, pose and counters.
//!
//! An animated skin is posed on the GPU before each step as `Simulator::pose_skin` poses it
//! ([`GpuStep::pose`], `physics/pose.rs`); the state's energy comes back on request
//! ([`GpuFurPhysics::request_energy`]). Not yet on the GPU: the implicit, reference and
//! local/global solvers; [`furbake_sim::Simulator::compute_model`] refuses what has no compute
//! form.

use furbake_sim::{ComputeModel, ComputeUpdate, ForceSet, GuardSettings, NO_LINK, SkinTransform};
use wgpu::util::DeviceExt;

use crate::shaders::FUR_PHYSICS_WGSL;
use crate::{FurRenderer, RenderError};

mod pose;

/// Local forces a GPU step applies (more are a [`RenderError::Parameter`]).
pub const MAX_LOCAL_FORCES: usize = 16;
/// Bytes between packs' uniforms, [`PhysicsStep`]'s size (a multiple of every adapter's uniform
/// offset alignment).
const STEP_STRIDE: u64 = 768;
/// The packs one dispatch steps (`HERD_CHUNK` in `fur_physics.wgsl`): the step uniforms are bound
/// as an array of this many, 48 KiB, under WebGPU's smallest uniform binding limit of 64 KiB.
const HERD_CHUNK: u64 = 64;
const WORKGROUP: u32 = 64;

/// One substep's uniforms (`PhysicsStep` in `fur_physics.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsStep {
    accel: [f32; 4],
    omega: [f32; 4],
    alpha: [f32; 4],
    wind_dir: [f32; 4],
    wind: [f32; 4],
    guard: [f32; 4],
    counts: [u32; 4],
    flags: [u32; 4],
    teleport: [f32; 4],
    pose: [f32; 4],
    pose_at: [u32; 4],
    pose_skin: [u32; 4],
    locals: [[f32; 4]; 2 * MAX_LOCAL_FORCES],
    base: [u32; 4],
    base2: [u32; 4],
    pad0: [u32; 4],
    pad1: [u32; 4],
}

/// One free mass (`PhysicsMass`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsMass {
    restoring_n: [f32; 4],
    rest_pos: [f32; 4],
    stick_anchor: [f32; 4],
    mass: f32,
    inv_mass: f32,
    links_start: u32,
    links_end: u32,
    restoring_parent: u32,
    stick_parent: u32,
    stick_len: f32,
    stick_c: f32,
}

/// One link seen from a free mass (`PhysicsLink`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsLink {
    other: u32,
    rest: f32,
    k: f32,
    c: f32,
}

/// One XPBD link (`PhysicsXpbdLink`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsXpbdLink {
    a: u32,
    b: u32,
    rest: f32,
    compliance: f32,
    c: f32,
    wa: f32,
    wb: f32,
    pad0: f32,
}

/// XPBD's colouring (`PhysicsColours`): colours, iterations, links, and where each colour starts.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsColours {
    count: [u32; 4],
    starts: [[u32; 4]; 16],
}

/// The most colours the XPBD kernel's uniform holds (`PhysicsColours::starts` has one more entry).
pub const MAX_XPBD_COLOURS: usize = 63;

/// XPBD's buffers and bind groups.
struct Xpbd {
    /// `bind[i]` steps state `i` into `1 − i`.
    bind: [wgpu::BindGroup; 2],
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
    /// The links (their rest lengths follow a posed skin).
    links: wgpu::Buffer,
    lambda: wgpu::Buffer,
    colours: wgpu::Buffer,
}

/// One tip (`PhysicsTip`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct PhysicsTip {
    n: [f32; 4],
    root_pos: [f32; 4],
    root: u32,
    tip: u32,
    pad0: u32,
    pad1: u32,
}

fn v4(v: [f32; 3], w: f32) -> [f32; 4] {
    [v[0], v[1], v[2], w]
}

/// Fur physics on the GPU for one pack, or for a herd of packs of one asset stepped together,
/// bound to the renderers whose scale vectors it writes ([`FurRenderer::gpu_physics`],
/// [`GpuFurPhysics::herd`]). [`GpuFurPhysics::record`] once per frame, before the frame's draws in
/// the same submission.
///
/// A herd holds its packs' states one after another in the same buffers and steps them with one
/// dispatch per pass (up to 64 packs per dispatch), so the host's cost of a frame barely grows
/// with the number of packs (docs/design.md "Fur physics on the GPU").
pub struct GpuFurPhysics {
    /// Per pack, the forces [`GpuFurPhysics::record`] applies.
    forces: Vec<ForceSet>,
    guard: GuardSettings,
    update: ComputeUpdate,
    project_sticks: bool,
    time_s: f64,
    stable_step_s: f64,
    max_substeps: u32,
    restoring_weight_n: f32,
    /// Per pack: free masses, tips, shell vertices.
    counts: [u32; 3],
    /// Packs in the herd.
    packs: u32,
    /// Per pack: masses, link entries, XPBD links (the strides of its parts).
    strides: [u32; 3],
    #[cfg_attr(not(feature = "testing"), allow(dead_code))]
    order: Vec<u32>,
    x: [wgpu::Buffer; 2],
    v: [wgpu::Buffer; 2],
    #[cfg_attr(not(feature = "testing"), allow(dead_code))]
    guard_state: wgpu::Buffer,
    /// Per pack: non-finite masses, guard triggers, frozen tips, unused.
    stats: wgpu::Buffer,
    steps: wgpu::Buffer,
    /// Uniform entries the step buffer holds (substeps × packs).
    steps_capacity: u32,
    state_layout: wgpu::BindGroupLayout,
    final_layout: wgpu::BindGroupLayout,
    mass_buffer: wgpu::Buffer,
    links: wgpu::Buffer,
    /// `state.step[i]` reads buffers `i` and writes `1 − i`; `state.last[i]` is the final state in
    /// buffers `i` (guard and scale passes).
    state: StateGroups,
    tips: wgpu::BindGroup,
    step_pipeline: wgpu::ComputePipeline,
    guard_pipeline: wgpu::ComputePipeline,
    teleport_pipeline: wgpu::ComputePipeline,
    scale_pipeline: wgpu::ComputePipeline,
    /// A herd's scale vectors, one pack after another, copied into each pack's renderer after the
    /// scale pass (a pack alone writes its renderer's buffer directly).
    herd_scale: Option<(wgpu::Buffer, Vec<wgpu::Buffer>)>,
    /// The buffer pair holding the current state.
    current: usize,
    /// The uniforms of one record, reused (grows only when a step needs more substeps).
    scratch: Vec<PhysicsStep>,
    /// The same as bytes at their stride, reused.
    scratch_bytes: Vec<u8>,
    /// XPBD's part (XPBD models only).
    xpbd: Option<Xpbd>,
    /// The tips (their rest directions and roots follow a posed skin).
    tip_buffer: wgpu::Buffer,
    /// The animated skin's part (models with a bind pose only).
    pose: Option<pose::Pose>,
    /// Steps and substeps of the last record.
    last_record: (u32, u32),
    /// The statistics readback ([`GpuFurPhysics::request_stats`]).
    stats_readback: Readback,
    /// Per pack, the counters last read back ([`GpuFurPhysics::pack_stats`]).
    pack_stats: Vec<GpuPhysicsStats>,
    /// The energy of the state, on request ([`GpuFurPhysics::request_energy`]).
    energy: EnergyPass,
}

/// One step for [`GpuFurPhysics::record_steps`]: its forces and the teleport that moves the fur
/// at its start (mesh frame, metres, as `Simulator::teleport`; zero for none).
#[derive(Clone, Copy, Debug)]
pub struct GpuStep<'a> {
    /// The step's forces.
    pub forces: &'a ForceSet,
    /// The teleport before it.
    pub teleport_m: [f32; 3],
    /// The animated skin's pose at the step's end, applied before it (as
    /// `Simulator::pose_skin`); `None` where the skin did not move.
    pub pose: Option<GpuPose<'a>>,
}

/// An animated skin's pose for one GPU step ([`GpuStep::pose`]): how the skin moved (bind pose
/// → the step's end) and the cut speed above which the fur is carried along (mesh-frame metres
/// per second), as `Simulator::pose_skin` takes them.
#[derive(Clone, Copy, Debug)]
pub struct GpuPose<'a> {
    /// The skin's motion.
    pub skin: GpuSkin<'a>,
    /// The fastest anchor speed that still drags the fur through its springs, m/s.
    pub cut_speed_m_per_s: f32,
}

/// How an animated skin moved, for [`GpuPose`].
#[derive(Clone, Copy, Debug)]
pub enum GpuSkin<'a> {
    /// One [`SkinTransform`] per shell vertex, blended by the host.
    Transforms(&'a [SkinTransform]),
    /// The pack's skinning matrices (one per bind, `world(joint) × inverseBind`) and morph
    /// weights (one per target), as its renderer's skinning pass takes them
    /// ([`FurRenderer::set_pose`]): the transforms are blended on the GPU from the pack's
    /// influences and morph deltas (`cs_pose_blend`), so a step uploads a few matrices instead
    /// of a transform per shell vertex. Needs the physics of an animated asset's renderer.
    Skinning {
        /// One per bind.
        matrices: &'a [glam::Mat4],
        /// One per morph target.
        morph_weights: &'a [f32],
    },
}

/// What one record of the GPU physics counted ([`GpuFurPhysics::poll_stats`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuPhysicsStats {
    /// Steps recorded.
    pub steps: u32,
    /// Substeps over those steps.
    pub substeps: u32,
    /// Free masses whose new position or velocity was not finite, summed over the substeps (the
    /// CPU simulator refuses such a step; on the GPU the host decides: rebuild from a simulator).
    pub non_finite: u32,
    /// Tips the wrong-side guard froze afresh (and kicked), summed over the steps.
    pub guard_triggers: u32,
    /// Tips frozen after each step, summed over the steps (the CPU's `frozen_scale_vectors` of a
    /// one-step record).
    pub frozen: u32,
}

/// A small buffer's way back to the host, without waiting: copied into `buffer` by a request,
/// mapped at the first poll after the host's submission, read at a later poll.
struct Readback {
    buffer: wgpu::Buffer,
    state: ReadbackState,
    /// Set by the mapping's callback (1 mapped, 2 failed).
    mapped: std::sync::Arc<std::sync::atomic::AtomicU8>,
    /// The record the copy belongs to.
    record: (u32, u32),
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum ReadbackState {
    Idle,
    Copied,
    Mapping,
}

impl Readback {
    fn new(device: &wgpu::Device, label: &str, size: u64) -> Readback {
        Readback {
            buffer: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            state: ReadbackState::Idle,
            mapped: Default::default(),
            record: (0, 0),
        }
    }

    /// Records the copy of `source` into `encoder`; false while an earlier request is on its way.
    fn request(&mut self, encoder: &mut wgpu::CommandEncoder, source: &wgpu::Buffer, record: (u32, u32)) -> bool {
        if self.state != ReadbackState::Idle {
            return false;
        }
        encoder.copy_buffer_to_buffer(source, 0, &self.buffer, 0, self.buffer.size());
        self.state = ReadbackState::Copied;
        self.record = record;
        true
    }

    /// `read` of the copied bytes and the record they belong to, once mapped; `None` until then.
    fn try_read<T>(&mut self, what: &str, read: impl FnOnce(&[u8]) -> T) -> Result<Read<T>, RenderError> {
        use std::sync::atomic::Ordering;
        match self.state {
            ReadbackState::Idle => Ok(None),
            ReadbackState::Copied => {
                self.mapped.store(0, Ordering::Release);
                let flag = self.mapped.clone();
                self.buffer.slice(..).map_async(wgpu::MapMode::Read, move |res| {
                    flag.store(if res.is_ok() { 1 } else { 2 }, Ordering::Release);
                });
                self.state = ReadbackState::Mapping;
                Ok(None)
            }
            ReadbackState::Mapping => match self.mapped.load(Ordering::Acquire) {
                0 => Ok(None),
                1 => {
                    let out = self.buffer.slice(..).get_mapped_range().map(|view| read(&view));
                    self.buffer.unmap();
                    self.state = ReadbackState::Idle;
                    let out = out.map_err(|e| RenderError::Gpu { what: format!("{what}: {e}") })?;
                    Ok(Some((out, self.record)))
                }
                _ => {
                    self.state = ReadbackState::Idle;
                    Err(RenderError::Gpu { what: format!("mapping the {what} failed") })
                }
            },
        }
    }
}

/// What a [`Readback`] read, with the record it belongs to; `None` until it is mapped.
type Read<T> = Option<(T, (u32, u32))>;

/// The energy pass (`cs_energy`) and its partial sums' way back.
struct EnergyPass {
    pipeline: wgpu::ComputePipeline,
    /// Over state buffers 0 and 1.
    groups: [wgpu::BindGroup; 2],
    partials: wgpu::Buffer,
    workgroups: u32,
    readback: Readback,
}

impl FurRenderer {
    /// Fur physics on the GPU for this renderer's pack, starting from `model` (a
    /// [`furbake_sim::Simulator::compute_model`] of the pack's topology, with its forces and
    /// settings) and writing this renderer's scale vectors from now on. `stable_step_s` and
    /// `max_substeps` are the CPU simulator's ([`furbake_sim::Simulator::stable_step_s`],
    /// `SolverSettings::max_substeps`), so that a step takes as many substeps on both. The model's
    /// shell vertices must be this renderer's welded vertices or triangle corners.
    pub fn gpu_physics(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        model: &ComputeModel,
        forces: &ForceSet,
        stable_step_s: f64,
        max_substeps: u32,
    ) -> Result<GpuFurPhysics, RenderError> {
        GpuFurPhysics::herd(device, queue, &[(self, model)], forces, stable_step_s, max_substeps)
    }

    /// The scale-vector layout of `model`'s shell vertices on this renderer.
    fn physics_layout(&self, model: &ComputeModel) -> Result<furbake_runtime::ShellVertexLayout, RenderError> {
        let shell = model.shell_tip.len() as u32;
        if shell == self.vertex_count() {
            Ok(furbake_runtime::ShellVertexLayout::PerVertex)
        } else if shell == 3 * self.triangle_count() {
            Ok(furbake_runtime::ShellVertexLayout::PerCorner)
        } else {
            Err(RenderError::Parameter {
                what: format!(
                    "the physics model has {shell} shell vertices; this pack has {} welded vertices and {} corners",
                    self.vertex_count(),
                    3 * self.triangle_count()
                ),
            })
        }
    }
}

/// Whether two packs' models can step in one herd ([`GpuFurPhysics::herd`]): the same topology,
/// solver, guard, bind pose and XPBD colouring (what the herd holds once), at the same time.
/// Their states, forces, rest shapes and link parameters may differ.
pub fn same_herd(a: &ComputeModel, b: &ComputeModel) -> bool {
    let ends = |m: &ComputeModel| m.xpbd.links.iter().map(|l| (l.ends, l.entry)).collect::<Vec<_>>();
    let tips = |m: &ComputeModel| m.tips.iter().map(|t| (t.root, t.tip)).collect::<Vec<_>>();
    a.update == b.update
        && a.masses == b.masses
        && a.free == b.free
        && a.project_sticks == b.project_sticks
        && a.guard == b.guard
        && a.time_s == b.time_s
        && a.links_start == b.links_start
        && a.link_other == b.link_other
        && a.restoring_parent == b.restoring_parent
        && a.stick_parent == b.stick_parent
        && a.shell_tip == b.shell_tip
        && a.pose == b.pose
        && a.xpbd.colour_start == b.xpbd.colour_start
        && tips(a) == tips(b)
        && ends(a) == ends(b)
}

impl GpuFurPhysics {
    /// The most packs of `model` one herd holds on a device with `limits`: each of the herd's
    /// arrays (per pack: the masses' data, link entries, tips, XPBD links, scale vectors and an
    /// animated skin's transforms) must fit one storage binding and one buffer. At least 1.
    pub fn herd_capacity(limits: &wgpu::Limits, model: &ComputeModel) -> usize {
        let limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        let bytes = |n: usize, size: usize| (n * size) as u64;
        let shell = model.shell_tip.len();
        let per_pack = [
            bytes(model.masses as usize, size_of::<PhysicsMass>()),
            bytes(model.link_other.len(), size_of::<PhysicsLink>()),
            bytes(model.tips.len(), size_of::<PhysicsTip>()),
            bytes(model.xpbd.links.len(), size_of::<PhysicsXpbdLink>()),
            bytes(shell, 16),
            if model.pose.is_some() { bytes(shell, size_of::<pose::PoseTransform>()) } else { 0 },
        ]
        .into_iter()
        .max()
        .unwrap_or(0)
        .max(1);
        (limit / per_pack).clamp(1, usize::MAX as u64) as usize
    }

    /// Fur physics on the GPU for a herd: `members` are packs of one asset, each with its
    /// renderer and its model (as [`FurRenderer::gpu_physics`] takes them; every model
    /// [`same_herd`] as the first; an animated asset's renderers made from one uploaded asset,
    /// [`FurRenderer::with_gpu_asset`]), stepped together under one `stable_step_s` and
    /// `max_substeps`, each starting under `forces` ([`GpuFurPhysics::set_pack_forces`] to give
    /// each its own). Each renderer's scale vectors are written from now on. One dispatch per
    /// pass steps up to 64 packs.
    pub fn herd(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        members: &[(&FurRenderer, &ComputeModel)],
        forces: &ForceSet,
        stable_step_s: f64,
        max_substeps: u32,
    ) -> Result<GpuFurPhysics, RenderError> {
        let Some(&(first, model)) = members.first() else {
            return Err(RenderError::Parameter { what: "a GPU physics herd of no packs".into() });
        };
        let mut layouts = Vec::with_capacity(members.len());
        for (k, &(renderer, m)) in members.iter().enumerate() {
            m.validate().map_err(|e| RenderError::Parameter { what: e.to_string() })?;
            if !same_herd(model, m) {
                return Err(RenderError::Parameter {
                    what: format!("pack {k} of the herd has another topology, solver, bind pose or time than pack 0"),
                });
            }
            layouts.push(renderer.physics_layout(m)?);
        }
        if stable_step_s.is_nan() || stable_step_s <= 0.0 || max_substeps == 0 {
            return Err(RenderError::Parameter {
                what: format!("stable step {stable_step_s} s and {max_substeps} substeps (must be positive)"),
            });
        }
        let capacity = Self::herd_capacity(&device.limits(), model);
        if members.len() > capacity {
            return Err(RenderError::Parameter {
                what: format!(
                    "a herd of {} packs: this device's storage bindings hold {capacity} packs of this model in one \
                     herd (GpuFurPhysics::herd_capacity)",
                    members.len()
                ),
            });
        }
        check_forces(forces)?;
        for (&(renderer, _), &layout) in members.iter().zip(&layouts) {
            renderer.set_scale_layout(queue, layout);
        }
        let per_corner = layouts[0] == furbake_runtime::ShellVertexLayout::PerCorner;
        let skin = first.skinning_pass().map(|s| s.physics_inputs(per_corner));
        // Skin transforms are blended from the first pack's influences and morph deltas: an
        // animated herd's renderers draw one uploaded asset (`FurRenderer::with_gpu_asset`).
        for (k, &(renderer, _)) in members.iter().enumerate().skip(1) {
            let same = match (first.is_animated(), renderer.is_animated()) {
                (false, false) => true,
                (true, true) => first.shares_gpu_asset(renderer),
                _ => false,
            };
            if !same {
                return Err(RenderError::Parameter {
                    what: format!(
                        "pack {k} of the herd has another skin than pack 0 (an animated herd's renderers share one \
                         uploaded asset, FurRenderer::with_gpu_asset)"
                    ),
                });
            }
        }
        let models: Vec<&ComputeModel> = members.iter().map(|&(_, m)| m).collect();
        let targets: Vec<wgpu::Buffer> = members.iter().map(|&(r, _)| r.scale_buffer().clone()).collect();
        GpuFurPhysics::new(device, &models, forces, stable_step_s, max_substeps, targets, skin)
    }

    fn new(
        device: &wgpu::Device,
        models: &[&ComputeModel],
        forces: &ForceSet,
        stable_step_s: f64,
        max_substeps: u32,
        scale_targets: Vec<wgpu::Buffer>,
        skin: Option<crate::skinning::SkinInputs>,
    ) -> Result<GpuFurPhysics, RenderError> {
        let model = models[0];
        let packs = models.len() as u32;
        if packs as u64 * model.masses as u64 >= NO_LINK as u64 {
            return Err(RenderError::Parameter {
                what: format!("a herd of {packs} packs of {} masses is too large for 32-bit indices", model.masses),
            });
        }
        let nf = model.free as usize;
        let (nm, nl, nx) = (model.masses, model.link_other.len() as u32, model.xpbd.links.len() as u32);
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        // Pack p's masses start at p·masses; its free masses' data is laid out the same way (the
        // anchored masses' slots unused), its links at p·links, its tips and shell vertices at
        // p·tips and p·shell vertices. Indices into the state are made global here.
        let global = |i: u32, p: u32| if i == NO_LINK { NO_LINK } else { i + p * nm };
        let mut positions = Vec::with_capacity(models.len() * nm as usize);
        let mut velocities = Vec::with_capacity(models.len() * nm as usize);
        let mut masses: Vec<PhysicsMass> = Vec::with_capacity(models.len() * nm as usize);
        let mut links: Vec<PhysicsLink> = Vec::with_capacity(models.len() * nl as usize);
        let mut tips: Vec<PhysicsTip> = Vec::with_capacity(models.len() * model.tips.len());
        let mut guard_state: Vec<[f32; 4]> = Vec::with_capacity(models.len() * model.tips.len());
        for (p, m) in (0..packs).zip(models) {
            positions.extend(m.positions.iter().map(|&x| v4(x, 0.0)));
            velocities.extend(m.velocities.iter().map(|&x| v4(x, 0.0)));
            masses.extend((0..nf).map(|k| PhysicsMass {
                restoring_n: v4(m.restoring_n[k], m.restoring_len[k]),
                rest_pos: v4(m.rest[k], 0.0),
                stick_anchor: match m.stick_parent[k] {
                    NO_LINK => [0.0; 4],
                    q => v4(m.rest[q as usize], 0.0),
                },
                mass: m.mass[k],
                inv_mass: 1.0 / m.mass[k],
                links_start: m.links_start[k] + p * nl,
                links_end: m.links_start[k + 1] + p * nl,
                restoring_parent: global(m.restoring_parent[k], p),
                stick_parent: global(m.stick_parent[k], p),
                stick_len: m.stick[k][0],
                stick_c: m.stick[k][1],
            }));
            if p + 1 < packs {
                masses.resize(((p + 1) * nm) as usize, bytemuck::Zeroable::zeroed());
            }
            links.extend(m.link_other.iter().zip(&m.link_params).map(|(&other, q)| PhysicsLink {
                other: global(other, p),
                rest: q[0],
                k: q[1],
                c: q[2],
            }));
            tips.extend(m.tips.iter().map(|t| PhysicsTip {
                n: v4(t.n, 0.0),
                root_pos: v4(m.rest[t.root as usize], 0.0),
                root: global(t.root, p),
                tip: global(t.tip, p),
                pad0: 0,
                pad1: 0,
            }));
            guard_state.extend(m.scale.iter().zip(&m.frozen).map(|(&s, &f)| v4(s, if f { 1.0 } else { 0.0 })));
        }
        let mut shell_tip = model.shell_tip.clone();
        pad(&mut positions);
        pad(&mut velocities);
        pad(&mut masses);
        pad(&mut links);
        pad(&mut tips);
        pad(&mut guard_state);
        pad(&mut shell_tip);
        let shell = model.shell_tip.len() as u64;
        crate::gpu_scope(device, "creating the fur physics", || {
            let init = |label: &str, contents: &[u8], usage| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
            };
            let x = [
                init("furbake physics positions 0", bytemuck::cast_slice(&positions), storage),
                init("furbake physics positions 1", bytemuck::cast_slice(&positions), storage),
            ];
            let v = [
                init("furbake physics velocities 0", bytemuck::cast_slice(&velocities), storage),
                init("furbake physics velocities 1", bytemuck::cast_slice(&velocities), storage),
            ];
            let read = wgpu::BufferUsages::STORAGE;
            let mass_buffer = init("furbake physics masses", bytemuck::cast_slice(&masses), read);
            let links = init("furbake physics links", bytemuck::cast_slice(&links), read);
            let tip_buffer = init("furbake physics tips", bytemuck::cast_slice(&tips), read);
            let guard_state = init("furbake physics guard", bytemuck::cast_slice(&guard_state), storage);
            let shell_tip = init("furbake physics shell tips", bytemuck::cast_slice(&shell_tip), read);
            let stats = init("furbake physics counters", &vec![0u8; 16 * packs as usize], storage);
            // A pack alone writes its renderer's buffer; a herd its own, copied out per pack.
            let (scale_out, herd_scale) = if packs > 1 {
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("furbake physics herd scale vectors"),
                    size: (packs as u64 * shell).max(1) * 16,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                (buffer.clone(), Some((buffer, scale_targets)))
            } else {
                (scale_targets[0].clone(), None)
            };
            let steps_capacity = 4 * packs;
            let steps = step_buffer(device, steps_capacity);
            let (entry, buffer) = (layout_entry, storage_binding);
            let state_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("furbake physics state"),
                entries: &[
                    entry(0, dynamic_steps()),
                    entry(1, buffer(true)),
                    entry(2, buffer(true)),
                    entry(3, buffer(false)),
                    entry(4, buffer(false)),
                    entry(6, buffer(true)),
                    entry(7, buffer(true)),
                    entry(8, buffer(false)),
                ],
            });
            // The guard and scale passes see only the final state (at most eight storage buffers
            // per stage, WebGPU's default limit).
            let final_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("furbake physics final state"),
                entries: &[
                    entry(0, dynamic_steps()),
                    entry(3, buffer(false)),
                    entry(4, buffer(false)),
                    entry(6, buffer(true)),
                    entry(8, buffer(false)),
                ],
            });
            let tip_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("furbake physics tips"),
                entries: &[
                    entry(0, buffer(true)),
                    entry(1, buffer(false)),
                    entry(2, buffer(true)),
                    entry(3, buffer(false)),
                ],
            });
            let tips = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("furbake physics tips"),
                layout: &tip_layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: tip_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: guard_state.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: shell_tip.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: scale_out.as_entire_binding() },
                ],
            });
            let parts = StateParts {
                layout: &state_layout,
                final_layout: &final_layout,
                steps: &steps,
                masses: &mass_buffer,
                links: &links,
                stats: &stats,
            };
            let state = parts.bind_all(device, &x, &v);
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("furbake fur_physics.wgsl"),
                source: wgpu::ShaderSource::Wgsl(FUR_PHYSICS_WGSL.into()),
            });
            let step_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("furbake physics step"),
                bind_group_layouts: &[Some(&state_layout)],
                immediate_size: 0,
            });
            let tips_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("furbake physics tips"),
                bind_group_layouts: &[Some(&final_layout), Some(&tip_layout)],
                immediate_size: 0,
            });
            let pipeline = |entry: &str, layout: &wgpu::PipelineLayout| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            };
            let xpbd = match model.update {
                ComputeUpdate::Xpbd { iterations } => Some(Xpbd::new(
                    device,
                    models,
                    iterations,
                    XpbdParts { x: &x, v: &v, module: &module, state: &parts },
                )?),
                _ => None,
            };
            let targets = pose::PoseTargets {
                steps: &steps,
                x: &x,
                v: &v,
                masses: &mass_buffer,
                links: &links,
                tips: &tip_buffer,
                guard: &guard_state,
            };
            let pose = pose::Pose::new(device, model, packs, &module, &targets, xpbd.as_ref().map(|x| &x.links), skin)?;
            let strides = [nm, nl, nx];
            let energy = EnergyPass::new(device, &module, model, packs, strides, forces, &x, &v, &mass_buffer, &links);
            Ok(GpuFurPhysics {
                xpbd,
                tip_buffer,
                pose,
                forces: vec![forces.clone(); packs as usize],
                guard: model.guard.clone(),
                update: model.update,
                project_sticks: model.project_sticks,
                time_s: model.time_s,
                stable_step_s,
                max_substeps,
                restoring_weight_n: forces.restoring_weight_n,
                counts: [model.free, model.tips.len() as u32, model.shell_tip.len() as u32],
                packs,
                strides,
                order: model.order.clone(),
                x,
                v,
                guard_state,
                stats,
                steps,
                steps_capacity,
                state_layout,
                final_layout,
                mass_buffer,
                links,
                state,
                tips,
                step_pipeline: pipeline("cs_step", &step_layout),
                guard_pipeline: pipeline("cs_guard", &tips_layout),
                teleport_pipeline: pipeline("cs_teleport", &tips_layout),
                scale_pipeline: pipeline("cs_scale", &tips_layout),
                herd_scale,
                current: 0,
                scratch: Vec::with_capacity(steps_capacity as usize),
                scratch_bytes: Vec::with_capacity(steps_capacity as usize * STEP_STRIDE as usize),
                last_record: (0, 0),
                stats_readback: Readback::new(device, "furbake physics counters readback", 16 * packs as u64),
                pack_stats: vec![GpuPhysicsStats::default(); packs as usize],
                energy,
            })
        })
    }

    /// Packs in this physics (1 unless built as a herd).
    pub fn pack_count(&self) -> usize {
        self.packs as usize
    }

    /// Replaces the forces of every pack. The restoring weight stays the one the stable step was
    /// computed for (a different one is a [`RenderError::Parameter`]: build again from a
    /// simulator with it).
    pub fn set_forces(&mut self, forces: &ForceSet) -> Result<(), RenderError> {
        check_forces(forces)?;
        self.check_restoring(forces)?;
        for f in &mut self.forces {
            f.clone_from(forces);
        }
        Ok(())
    }

    /// Replaces the forces of pack `pack` of a herd, as [`GpuFurPhysics::set_forces`].
    pub fn set_pack_forces(&mut self, pack: usize, forces: &ForceSet) -> Result<(), RenderError> {
        check_forces(forces)?;
        self.check_restoring(forces)?;
        let packs = self.packs;
        let f = self
            .forces
            .get_mut(pack)
            .ok_or_else(|| RenderError::Parameter { what: format!("pack {pack} of a GPU physics herd of {packs}") })?;
        f.clone_from(forces);
        Ok(())
    }

    /// Simulated time, seconds.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Records one step of `dt_s` seconds under the forces last set into `encoder` — as many
    /// substeps as the CPU simulator takes, the guard and the scale vectors — and returns the
    /// substep count. Writes the step's uniforms with `queue.write_buffer` (staged until the
    /// host's next submission), so one record per submission; never submits or waits. A step
    /// needing more than the allowed substeps is a [`RenderError::Parameter`] and records nothing.
    /// A herd steps every pack under its own forces.
    pub fn record(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        dt_s: f64,
    ) -> Result<u32, RenderError> {
        let forces = std::mem::take(&mut self.forces);
        let out = self.record_herd(device, queue, encoder, dt_s, 1, |p, _| GpuStep {
            forces: &forces[p],
            teleport_m: [0.0; 3],
            pose: None,
        });
        self.forces = forces;
        out
    }

    /// Records `steps.len()` steps of `dt_s` seconds (what a world that stepped several times
    /// since the last frame hands over), each with its teleport, substeps and guard, then the
    /// scale vectors; returns the substeps recorded. One record per submission, as
    /// [`GpuFurPhysics::record`]. The forces must keep the restoring weight the physics was built
    /// for; a step with too many substeps, bad forces or a non-finite teleport records nothing.
    /// A herd records with [`GpuFurPhysics::record_herd`].
    pub fn record_steps(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        dt_s: f64,
        steps: &[GpuStep<'_>],
    ) -> Result<u32, RenderError> {
        if self.packs != 1 {
            return Err(RenderError::Parameter {
                what: format!("record_steps of a herd of {} packs (record_herd gives each its steps)", self.packs),
            });
        }
        self.record_herd(device, queue, encoder, dt_s, steps.len() as u32, |_, n| steps[n as usize])
    }

    /// Records `count` steps of `dt_s` seconds for every pack of the herd, `step(pack, n)` being
    /// pack `pack`'s step `n` (its forces, teleport and pose), as [`GpuFurPhysics::record_steps`]
    /// records one pack's: every pack takes the same substeps, and each pass is one dispatch per
    /// 64 packs. `step` is called several times per step (to check, then to write); a bad step of
    /// any pack records nothing.
    pub fn record_herd<'s>(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        dt_s: f64,
        count: u32,
        step: impl Fn(usize, u32) -> GpuStep<'s>,
    ) -> Result<u32, RenderError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(RenderError::Parameter {
                what: format!("physics step {dt_s} s (must be finite and positive)"),
            });
        }
        let packs = self.packs as usize;
        // Poses, those given as transforms, and whether any is blended from skinning matrices.
        let (mut posed, mut given, mut blended) = (0u32, 0u32, false);
        for n in 0..count {
            for p in 0..packs {
                let step = step(p, n);
                self.check_restoring(step.forces)?;
                check_forces(step.forces)?;
                if !step.teleport_m.iter().all(|c| c.is_finite()) {
                    return Err(RenderError::Parameter {
                        what: format!("teleport {:?} is not finite", step.teleport_m),
                    });
                }
                if let Some(q) = &step.pose {
                    match &self.pose {
                        Some(pose) => pose.check(q)?,
                        None => {
                            return Err(RenderError::Parameter {
                                what: "a skin pose for GPU physics built from a static skin (pose the simulator \
                                       once, Simulator::pose_skin, before its compute_model)"
                                    .into(),
                            });
                        }
                    }
                    posed += 1;
                    match q.skin {
                        GpuSkin::Transforms(_) => given += 1,
                        GpuSkin::Skinning { .. } => blended = true,
                    }
                }
            }
        }
        // XPBD never substeps (crates/sim/src/solvers/xpbd.rs).
        let substeps = if dt_s <= self.stable_step_s || self.xpbd.is_some() {
            1
        } else {
            (dt_s / self.stable_step_s).ceil() as u64
        };
        if substeps > self.max_substeps as u64 {
            return Err(RenderError::Parameter {
                what: format!(
                    "a step of {dt_s} s needs {substeps} substeps of the stable {} s; {} allowed",
                    self.stable_step_s, self.max_substeps
                ),
            });
        }
        let substeps = substeps as u32;
        if count == 0 {
            return Ok(0);
        }
        let total = substeps * count;
        let entries = total * self.packs;
        // The pose's buffers first: a record too large for them fails before anything changes.
        let mut rebind_pose = match self.pose.as_mut() {
            // Transforms given by the host each take a slot; a blended pose's are written by the
            // GPU before its step reads them, so each pack reuses one slot after those.
            Some(pose) => {
                pose.reserve(device, given + if blended { self.packs } else { 0 }, posed, count * self.packs)?
            }
            None => false,
        };
        if entries > self.steps_capacity {
            // Grows, never shrinks: a steady frame rate allocates nothing here.
            self.steps_capacity = entries.next_power_of_two();
            self.steps = step_buffer(device, self.steps_capacity);
            self.state = self.parts().bind_all(device, &self.x, &self.v);
            if let Some(mut xpbd) = self.xpbd.take() {
                xpbd.rebind(device, &self.parts(), &self.x, &self.v);
                self.xpbd = Some(xpbd);
            }
            rebind_pose = true;
        }
        if let (Some(pose), true) = (self.pose.as_mut(), rebind_pose) {
            let targets = pose::PoseTargets {
                steps: &self.steps,
                x: &self.x,
                v: &self.v,
                masses: &self.mass_buffer,
                links: &self.links,
                tips: &self.tip_buffer,
                guard: &self.guard_state,
            };
            pose.rebind(device, &targets);
        }
        let h = dt_s / substeps as f64;
        self.scratch.clear();
        // Time advances step by step, as the CPU simulator's does (so one record of n steps and n
        // records of one agree to the bit). Uniforms lie step by step, substep by substep, pack
        // by pack; the poses take slots in the same order.
        let mut t = self.time_s;
        let (mut slot, mut given_slot) = (0, 0);
        for n in 0..count {
            for sub in 0..substeps {
                for p in 0..packs {
                    let step = step(p, n);
                    // The teleport and the pose belong to the step's first substep (cs_teleport
                    // and the pose passes read them there).
                    let teleport = if sub == 0 { step.teleport_m } else { [0.0; 3] };
                    let mut u = self.uniforms(step.forces, teleport, t + sub as f64 * h, h as f32, p as u32);
                    if let (0, Some(q), Some(pose)) = (sub, &step.pose, &self.pose) {
                        let blend = matches!(q.skin, GpuSkin::Skinning { .. });
                        let speed = n * self.packs + p as u32;
                        let transforms = if blend {
                            given + p as u32
                        } else {
                            given_slot += 1;
                            given_slot - 1
                        };
                        (u.pose, u.pose_at, u.pose_skin) =
                            pose.uniforms(slot, transforms, speed, dt_s, q.cut_speed_m_per_s, blend);
                        slot += 1;
                    }
                    self.scratch.push(u);
                }
            }
            t += dt_s;
        }
        let bytes = self.scratch_bytes();
        queue.write_buffer(&self.steps, 0, &bytes);
        self.scratch_bytes = bytes;
        encoder.clear_buffer(&self.stats, 0, None);
        if let (Some(pose), true) = (self.pose.as_mut(), posed > 0) {
            let steps = (0..count).flat_map(|n| (0..packs).map(move |p| (p, n)));
            pose.write(queue, steps.filter_map(|(p, n)| step(p, n).pose));
            pose.clear(encoder);
        }
        let groups = |n: u32| n.div_ceil(WORKGROUP).max(1);
        let (free_groups, tip_groups, shell_groups) =
            (groups(self.counts[0]), groups(self.counts[1]), groups(self.counts[2]));
        let chunks = self.packs.div_ceil(HERD_CHUNK as u32);
        // The dynamic offset of substep `sub`'s (counted over the record) chunk `c`, and the packs
        // in that chunk.
        let packs_u = self.packs;
        let chunk = move |sub: u32, c: u32| {
            let first = c * HERD_CHUNK as u32;
            ((((sub * packs_u + first) as u64) * STEP_STRIDE) as u32, (packs_u - first).min(HERD_CHUNK as u32))
        };
        for n in 0..count {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("furbake fur physics"),
                timestamp_writes: None,
            });
            let first = n * substeps;
            if (0..packs).any(|p| step(p, n).teleport_m != [0.0; 3]) {
                pass.set_pipeline(&self.teleport_pipeline);
                pass.set_bind_group(1, &self.tips, &[]);
                for c in 0..chunks {
                    let (offset, y) = chunk(first, c);
                    pass.set_bind_group(0, &self.state.last[self.current], &[offset]);
                    pass.dispatch_workgroups(free_groups, y, 1);
                }
            }
            if let Some(pose) = &self.pose {
                // The skin moves to its pose at the step's end before the step (as the CPU
                // world poses the simulator before stepping it).
                let mut any = false;
                let mut blend = false;
                for p in 0..packs {
                    if let Some(q) = step(p, n).pose {
                        any = true;
                        blend |= matches!(q.skin, GpuSkin::Skinning { .. });
                    }
                }
                if any {
                    for c in 0..chunks {
                        let (offset, y) = chunk(first, c);
                        pose.record(&mut pass, offset, self.current, blend, y);
                    }
                }
            }
            if let Some(x) = &self.xpbd {
                for c in 0..chunks {
                    let (offset, y) = chunk(first, c);
                    x.record(&mut pass, offset, self.current, y);
                }
                self.current = 1 - self.current;
            } else {
                pass.set_pipeline(&self.step_pipeline);
                for sub in first..first + substeps {
                    for c in 0..chunks {
                        let (offset, y) = chunk(sub, c);
                        pass.set_bind_group(0, &self.state.step[self.current], &[offset]);
                        pass.dispatch_workgroups(free_groups, y, 1);
                    }
                    self.current = 1 - self.current;
                }
            }
            // The guard reads and kicks the step's final state, with its last substep's uniforms.
            pass.set_pipeline(&self.guard_pipeline);
            pass.set_bind_group(1, &self.tips, &[]);
            for c in 0..chunks {
                let (offset, y) = chunk(first + substeps - 1, c);
                pass.set_bind_group(0, &self.state.last[self.current], &[offset]);
                pass.dispatch_workgroups(tip_groups, y, 1);
            }
            if n + 1 == count {
                pass.set_pipeline(&self.scale_pipeline);
                for c in 0..chunks {
                    let (offset, y) = chunk(first + substeps - 1, c);
                    pass.set_bind_group(0, &self.state.last[self.current], &[offset]);
                    pass.dispatch_workgroups(shell_groups, y, 1);
                }
            }
        }
        if let Some((herd, targets)) = &self.herd_scale {
            // Each pack's part into its renderer's scale vectors.
            let bytes = self.counts[2] as u64 * 16;
            for (p, target) in targets.iter().enumerate() {
                encoder.copy_buffer_to_buffer(herd, p as u64 * bytes, target, 0, bytes);
            }
        }
        self.time_s = t;
        self.last_record = (count, total);
        Ok(total)
    }

    /// Asks for the counters of the last record ([`GpuPhysicsStats`]): records their copy into
    /// `encoder` (after the record, in the same or a later encoder). Then, after the host has
    /// submitted it, [`GpuFurPhysics::poll_stats`] hands them over once the GPU is done. False
    /// (nothing recorded) while an earlier request is still on its way.
    pub fn request_stats(&mut self, encoder: &mut wgpu::CommandEncoder) -> bool {
        self.stats_readback.request(encoder, &self.stats, self.last_record)
    }

    /// The counters [`GpuFurPhysics::request_stats`] asked for, once the GPU has written them,
    /// summed over a herd's packs ([`GpuFurPhysics::pack_stats`] has each pack's); `None` until
    /// then (and without a request). Never waits: the first call after the host's submission
    /// starts the mapping, and the host's own device polling (its next frame's submit or
    /// `Device::poll`) completes it. A failed mapping is a [`RenderError::Gpu`].
    pub fn poll_stats(&mut self) -> Result<Option<GpuPhysicsStats>, RenderError> {
        let stats = &mut self.pack_stats;
        let read = |view: &[u8]| {
            for (s, c) in stats.iter_mut().zip(view.chunks_exact(16)) {
                let c: [u32; 4] = bytemuck::pod_read_unaligned(c);
                (s.non_finite, s.guard_triggers, s.frozen) = (c[0], c[1], c[2]);
            }
        };
        let Some(((), record)) = self.stats_readback.try_read("GPU physics counters", read)? else {
            return Ok(None);
        };
        let mut total = GpuPhysicsStats { steps: record.0, substeps: record.1, ..Default::default() };
        for s in &mut self.pack_stats {
            (s.steps, s.substeps) = record;
            total.non_finite += s.non_finite;
            total.guard_triggers += s.guard_triggers;
            total.frozen += s.frozen;
        }
        Ok(Some(total))
    }

    /// Pack `pack`'s counters as the last [`GpuFurPhysics::poll_stats`] that returned some read
    /// them (zero before any).
    pub fn pack_stats(&self, pack: usize) -> Option<GpuPhysicsStats> {
        self.pack_stats.get(pack).copied()
    }

    /// Asks for the energy of the current state (after the records so far), as
    /// `Simulator::energy` measures it, summed over a herd's packs: records one compute pass of
    /// per-workgroup partial sums and their copy into `encoder`. Then, after the host's
    /// submission, [`GpuFurPhysics::poll_energy`] hands it over without waiting. False (nothing
    /// recorded) while an earlier request is still on its way.
    pub fn request_energy(&mut self, encoder: &mut wgpu::CommandEncoder) -> bool {
        let e = &mut self.energy;
        if e.readback.state != ReadbackState::Idle {
            return false;
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("furbake fur physics energy"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&e.pipeline);
            for c in 0..self.packs.div_ceil(HERD_CHUNK as u32) {
                let first = c * HERD_CHUNK as u32;
                pass.set_bind_group(0, &e.groups[self.current], &[(first as u64 * STEP_STRIDE) as u32]);
                pass.dispatch_workgroups(e.workgroups, (self.packs - first).min(HERD_CHUNK as u32), 1);
            }
        }
        e.readback.request(encoder, &e.partials, self.last_record)
    }

    /// The energy [`GpuFurPhysics::request_energy`] asked for (kinetic, spring and restoring
    /// energy, joules; the partial sums added in f64), once the GPU has written it; `None` until
    /// then. Never waits, as [`GpuFurPhysics::poll_stats`].
    pub fn poll_energy(&mut self) -> Result<Option<furbake_sim::Energy>, RenderError> {
        let read = |view: &[u8]| {
            let mut sum = [0.0f64; 3];
            for p in view.chunks_exact(16) {
                let p: [f32; 4] = bytemuck::pod_read_unaligned(p);
                for (s, v) in sum.iter_mut().zip(p) {
                    *s += v as f64;
                }
            }
            furbake_sim::Energy { kinetic_j: sum[0], spring_j: sum[1], restoring_j: sum[2] }
        };
        Ok(self.energy.readback.try_read("GPU physics energy", read)?.map(|(e, _)| e))
    }

    /// The uniforms of one record as bytes, each substep at its stride (reusing the scratch's
    /// allocation once it has grown).
    fn scratch_bytes(&mut self) -> Vec<u8> {
        let mut bytes = std::mem::take(&mut self.scratch_bytes);
        bytes.clear();
        for s in &self.scratch {
            bytes.extend_from_slice(bytemuck::bytes_of(s));
            bytes.resize(bytes.len().next_multiple_of(STEP_STRIDE as usize), 0);
        }
        bytes
    }

    fn check_restoring(&self, forces: &ForceSet) -> Result<(), RenderError> {
        if forces.restoring_weight_n != self.restoring_weight_n {
            return Err(RenderError::Parameter {
                what: format!(
                    "restoring weight {} N: the GPU physics was built for {} N",
                    forces.restoring_weight_n, self.restoring_weight_n
                ),
            });
        }
        Ok(())
    }

    fn parts(&self) -> StateParts<'_> {
        StateParts {
            layout: &self.state_layout,
            final_layout: &self.final_layout,
            steps: &self.steps,
            masses: &self.mass_buffer,
            links: &self.links,
            stats: &self.stats,
        }
    }

    /// Pack `pack`'s uniforms of the substep starting at `t` (as `furbake_sim`'s
    /// `ForceEval::new`), with where its parts start.
    fn uniforms(&self, f: &ForceSet, teleport_m: [f32; 3], t: f64, h: f32, pack: u32) -> PhysicsStep {
        let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
        let m = &f.motion;
        let rotating = m.angular_velocity_rad_per_s != [0.0; 3] || m.angular_accel_rad_per_s2 != [0.0; 3];
        let wind = f.wind.as_ref().and_then(|w| {
            let d = glam::Vec3::from(w.direction).try_normalize()?;
            Some((d, w))
        });
        let mut locals = [[0.0f32; 4]; 2 * MAX_LOCAL_FORCES];
        for (i, l) in f.local.iter().enumerate().take(MAX_LOCAL_FORCES) {
            locals[2 * i] = v4(l.point_m, l.radius_m);
            locals[2 * i + 1] = [l.strength_n, 0.0, 0.0, 0.0];
        }
        let g = &self.guard;
        PhysicsStep {
            accel: v4(sub(f.gravity_m_per_s2, m.linear_accel_m_per_s2), h),
            omega: v4(m.angular_velocity_rad_per_s, t as f32),
            alpha: v4(m.angular_accel_rad_per_s2, f.restoring_weight_n),
            wind_dir: wind.map_or([0.0; 4], |(d, w)| v4(d.to_array(), w.force_n)),
            wind: wind
                .map_or([0.0; 4], |(_, w)| [w.gust_amplitude, w.gust_frequency_hz, 1.0 / w.gust_wavelength_m, 1.0]),
            guard: [g.max_angle_deg.to_radians().cos(), g.impulse_m_per_s, if g.enabled { 1.0 } else { 0.0 }, 0.0],
            counts: [self.counts[0], self.counts[1], self.counts[2], f.local.len().min(MAX_LOCAL_FORCES) as u32],
            flags: [
                match self.update {
                    ComputeUpdate::Explicit => 0,
                    ComputeUpdate::Stick => 1,
                    ComputeUpdate::Xpbd { .. } => 2,
                },
                self.project_sticks as u32,
                rotating as u32,
                0,
            ],
            teleport: v4(teleport_m, if teleport_m == [0.0; 3] { 0.0 } else { 1.0 }),
            pose: [0.0; 4],
            pose_at: [0; 4],
            pose_skin: [0; 4],
            locals,
            base: [
                pack * self.strides[0],
                pack * self.strides[1],
                pack * self.counts[1],
                if self.herd_scale.is_some() { pack * self.counts[2] } else { 0 },
            ],
            base2: [pack * self.strides[2], pack, 0, 0],
            pad0: [0; 4],
            pad1: [0; 4],
        }
    }
}

#[cfg(feature = "testing")]
/// What a test reads back from the GPU physics (submits and waits).
#[derive(Clone, Debug)]
pub struct PhysicsReadback {
    /// Positions in the topology's mass order.
    pub positions: Vec<[f32; 3]>,
    /// Velocities in the topology's mass order.
    pub velocities: Vec<[f32; 3]>,
    /// Per tip: the guarded scale vector and whether it is frozen.
    pub scale: Vec<([f32; 3], bool)>,
    /// Masses that became non-finite, guard triggers and frozen tips in the last record.
    pub counters: [u32; 3],
}

#[cfg(feature = "testing")]
impl GpuFurPhysics {
    /// Reads the current state back (submits and waits: tests and tools only); a herd's first
    /// pack.
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<PhysicsReadback, RenderError> {
        self.read_back_pack(device, queue, 0)
    }

    /// Reads pack `pack`'s current state back (submits and waits: tests and tools only).
    pub fn read_back_pack(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pack: usize,
    ) -> Result<PhysicsReadback, RenderError> {
        use crate::blocking::read_buffer;
        let (n, tips, packs) = (self.strides[0] as usize, self.counts[1] as usize, self.packs as usize);
        if pack >= packs {
            return Err(RenderError::Parameter { what: format!("pack {pack} of a GPU physics herd of {packs}") });
        }
        let order = |v: Vec<[f32; 4]>| {
            let mut out = vec![[0.0f32; 3]; n];
            for (k, &i) in self.order.iter().enumerate() {
                let s = v[pack * n + k];
                out[i as usize] = [s[0], s[1], s[2]];
            }
            out
        };
        let all = (n * packs) as u64;
        let x: Vec<[f32; 4]> = read_buffer(device, queue, &self.x[self.current], all, "physics positions")?;
        let v: Vec<[f32; 4]> = read_buffer(device, queue, &self.v[self.current], all, "physics velocities")?;
        let g: Vec<[f32; 4]> = read_buffer(device, queue, &self.guard_state, (tips * packs) as u64, "physics guard")?;
        let c: Vec<u32> = read_buffer(device, queue, &self.stats, 4 * packs as u64, "physics counters")?;
        Ok(PhysicsReadback {
            positions: order(x),
            velocities: order(v),
            scale: g[pack * tips..(pack + 1) * tips].iter().map(|s| ([s[0], s[1], s[2]], s[3] != 0.0)).collect(),
            counters: [c[4 * pack], c[4 * pack + 1], c[4 * pack + 2]],
        })
    }
}

impl EnergyPass {
    #[allow(clippy::too_many_arguments)]
    fn new(
        device: &wgpu::Device,
        module: &wgpu::ShaderModule,
        model: &ComputeModel,
        packs: u32,
        strides: [u32; 3],
        forces: &ForceSet,
        x: &[wgpu::Buffer; 2],
        v: &[wgpu::Buffer; 2],
        masses: &wgpu::Buffer,
        links: &wgpu::Buffer,
    ) -> EnergyPass {
        const THREADS: u32 = 256;
        let workgroups = model.free.div_ceil(THREADS).max(1);
        // Its own uniforms per pack: the free masses, the restoring weight and where the pack
        // starts, fixed for the physics; a whole window past the last chunk's first pack.
        let mut contents = vec![0u8; (packs as u64).next_multiple_of(HERD_CHUNK) as usize * STEP_STRIDE as usize];
        for p in 0..packs {
            let mut uniforms: PhysicsStep = bytemuck::Zeroable::zeroed();
            uniforms.counts = [model.free, model.tips.len() as u32, model.shell_tip.len() as u32, 0];
            uniforms.alpha[3] = forces.restoring_weight_n;
            uniforms.base = [p * strides[0], p * strides[1], 0, 0];
            uniforms.base2 = [0, p, 0, 0];
            let at = p as usize * STEP_STRIDE as usize;
            contents[at..at + size_of::<PhysicsStep>()].copy_from_slice(bytemuck::bytes_of(&uniforms));
        }
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("furbake physics energy uniforms"),
            contents: &contents,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let partials = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake physics energy partial sums"),
            size: workgroups as u64 * packs as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("furbake physics energy"),
            entries: &[
                layout_entry(0, dynamic_steps()),
                layout_entry(40, storage_binding(true)),
                layout_entry(41, storage_binding(true)),
                layout_entry(42, storage_binding(true)),
                layout_entry(43, storage_binding(true)),
                layout_entry(44, storage_binding(false)),
            ],
        });
        let groups = [0, 1].map(|at| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("furbake physics energy"),
                layout: &layout,
                entries: &[
                    steps_entry(&uniform),
                    entry(40, &x[at]),
                    entry(41, &v[at]),
                    entry(42, masses),
                    entry(43, links),
                    entry(44, &partials),
                ],
            })
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake physics energy"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("cs_energy"),
            layout: Some(&pipeline_layout),
            module,
            entry_point: Some("cs_energy"),
            compilation_options: Default::default(),
            cache: None,
        });
        EnergyPass {
            pipeline,
            groups,
            readback: Readback::new(device, "furbake physics energy readback", partials.size()),
            partials,
            workgroups,
        }
    }
}

/// The bind groups over the two state buffers.
struct StateGroups {
    step: [wgpu::BindGroup; 2],
    last: [wgpu::BindGroup; 2],
}

/// What XPBD's part shares with the rest of the physics.
struct XpbdParts<'a> {
    x: &'a [wgpu::Buffer; 2],
    v: &'a [wgpu::Buffer; 2],
    module: &'a wgpu::ShaderModule,
    /// The step uniforms, masses and counters.
    state: &'a StateParts<'a>,
}

impl Xpbd {
    fn new(
        device: &wgpu::Device,
        models: &[&ComputeModel],
        iterations: u32,
        parts: XpbdParts<'_>,
    ) -> Result<Xpbd, RenderError> {
        let XpbdParts { x, v, module, state } = parts;
        let model = models[0];
        let colours = model.xpbd.colour_start.len().saturating_sub(1);
        if colours > MAX_XPBD_COLOURS {
            return Err(RenderError::Parameter {
                what: format!("XPBD's links take {colours} colours; the GPU physics takes at most {MAX_XPBD_COLOURS}"),
            });
        }
        // Each pack's links after the last's, their ends global (colour starts stay per pack).
        let masses = model.masses;
        let mut links: Vec<PhysicsXpbdLink> = (0u32..)
            .zip(models)
            .flat_map(|(p, m)| {
                m.xpbd.links.iter().map(move |l| PhysicsXpbdLink {
                    a: l.ends[0] + p * masses,
                    b: l.ends[1] + p * masses,
                    rest: l.rest,
                    compliance: l.compliance,
                    c: l.c,
                    wa: l.inv_mass[0],
                    wb: l.inv_mass[1],
                    pad0: 0.0,
                })
            })
            .collect();
        let count = model.xpbd.links.len();
        pad(&mut links);
        let mut uniforms =
            PhysicsColours { count: [colours as u32, iterations, count as u32, 0], starts: [[0; 4]; 16] };
        for (c, &start) in model.xpbd.colour_start.iter().enumerate() {
            uniforms.starts[c / 4][c % 4] = start;
        }
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let links_buffer =
            init("furbake physics xpbd links", bytemuck::cast_slice(&links), wgpu::BufferUsages::STORAGE);
        let lambda = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake physics xpbd multipliers"),
            size: links.len() as u64 * 16,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        });
        let colours_buffer =
            init("furbake physics xpbd colours", bytemuck::bytes_of(&uniforms), wgpu::BufferUsages::UNIFORM);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("furbake physics xpbd"),
            entries: &[
                layout_entry(0, dynamic_steps()),
                layout_entry(1, storage_binding(true)),
                layout_entry(2, storage_binding(true)),
                layout_entry(3, storage_binding(false)),
                layout_entry(4, storage_binding(false)),
                layout_entry(6, storage_binding(true)),
                layout_entry(8, storage_binding(false)),
                layout_entry(10, storage_binding(true)),
                layout_entry(11, storage_binding(false)),
                layout_entry(
                    12,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake physics xpbd"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("cs_xpbd_step"),
            layout: Some(&pipeline_layout),
            module,
            entry_point: Some("cs_xpbd_step"),
            compilation_options: Default::default(),
            cache: None,
        });
        let bind = [0, 1]
            .map(|from| xpbd_group(device, &layout, state, x, v, [&links_buffer, &lambda, &colours_buffer], from));
        Ok(Xpbd { bind, layout, pipeline, links: links_buffer, lambda, colours: colours_buffer })
    }

    /// Binds the groups again (after the step uniforms' buffer was replaced).
    fn rebind(&mut self, device: &wgpu::Device, state: &StateParts<'_>, x: &[wgpu::Buffer; 2], v: &[wgpu::Buffer; 2]) {
        let own = [&self.links, &self.lambda, &self.colours];
        self.bind = [0, 1].map(|from| xpbd_group(device, &self.layout, state, x, v, own, from));
    }

    /// Records one XPBD step of `packs` packs from state `from` into `1 − from` with the step
    /// uniforms at `step_offset`: one workgroup does a pack's whole step (`cs_xpbd_step`).
    fn record(&self, pass: &mut wgpu::ComputePass<'_>, step_offset: u32, from: usize, packs: u32) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind[from], &[step_offset]);
        pass.dispatch_workgroups(1, packs, 1);
    }
}

/// XPBD's group stepping state `from` into `1 − from`; `own` are its links, multipliers and
/// colours.
fn xpbd_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    state: &StateParts<'_>,
    x: &[wgpu::Buffer; 2],
    v: &[wgpu::Buffer; 2],
    own: [&wgpu::Buffer; 3],
    from: usize,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("furbake physics xpbd"),
        layout,
        entries: &[
            state.steps_entry(),
            entry(1, &x[from]),
            entry(2, &v[from]),
            entry(3, &x[1 - from]),
            entry(4, &v[1 - from]),
            entry(6, state.masses),
            entry(8, state.stats),
            entry(10, own[0]),
            entry(11, own[1]),
            entry(12, own[2]),
        ],
    })
}

/// The buffers every state bind group shares.
struct StateParts<'a> {
    layout: &'a wgpu::BindGroupLayout,
    final_layout: &'a wgpu::BindGroupLayout,
    steps: &'a wgpu::Buffer,
    masses: &'a wgpu::Buffer,
    links: &'a wgpu::Buffer,
    stats: &'a wgpu::Buffer,
}

impl StateParts<'_> {
    fn bind_all(&self, device: &wgpu::Device, x: &[wgpu::Buffer; 2], v: &[wgpu::Buffer; 2]) -> StateGroups {
        StateGroups {
            step: [self.bind(device, x, v, 0), self.bind(device, x, v, 1)],
            last: [self.bind_last(device, x, v, 0), self.bind_last(device, x, v, 1)],
        }
    }

    fn steps_entry(&self) -> wgpu::BindGroupEntry<'_> {
        steps_entry(self.steps)
    }

    /// The guard's and scale pass's bind group over the final state in buffers `at`.
    fn bind_last(
        &self,
        device: &wgpu::Device,
        x: &[wgpu::Buffer; 2],
        v: &[wgpu::Buffer; 2],
        at: usize,
    ) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake physics final state"),
            layout: self.final_layout,
            entries: &[
                self.steps_entry(),
                entry(3, &x[at]),
                entry(4, &v[at]),
                entry(6, self.masses),
                entry(8, self.stats),
            ],
        })
    }

    /// The bind group reading state buffers `from` and writing `1 − from`.
    fn bind(
        &self,
        device: &wgpu::Device,
        x: &[wgpu::Buffer; 2],
        v: &[wgpu::Buffer; 2],
        from: usize,
    ) -> wgpu::BindGroup {
        let to = 1 - from;
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake physics state"),
            layout: self.layout,
            entries: &[
                self.steps_entry(),
                entry(1, &x[from]),
                entry(2, &v[from]),
                entry(3, &x[to]),
                entry(4, &v[to]),
                entry(6, self.masses),
                entry(7, self.links),
                entry(8, self.stats),
            ],
        })
    }
}

/// The step uniforms' binding (0): a chunk of packs' uniforms of one substep at a dynamic offset.
fn steps_entry(steps: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding: 0,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: steps,
            offset: 0,
            size: wgpu::BufferSize::new(STEPS_WINDOW),
        }),
    }
}

/// Bytes of the step uniforms' binding.
const STEPS_WINDOW: u64 = HERD_CHUNK * STEP_STRIDE;

// A step is one uniform array element of the shader's layout, its offsets fit the 256-byte
// dynamic-offset alignment, and a chunk's window fits the 64 KiB uniform binding every adapter has.
const _: () =
    assert!(size_of::<PhysicsStep>() as u64 == STEP_STRIDE && STEP_STRIDE.is_multiple_of(256) && STEPS_WINDOW <= 65536);

/// Storage bindings cannot be empty: every array gets at least one (zeroed) element.
fn pad<T: bytemuck::Zeroable>(v: &mut Vec<T>) {
    if v.is_empty() {
        v.push(T::zeroed());
    }
}

fn layout_entry(binding: u32, ty: wgpu::BindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry { binding, visibility: wgpu::ShaderStages::COMPUTE, ty, count: None }
}

fn storage_binding(read_only: bool) -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Storage { read_only },
        has_dynamic_offset: false,
        min_binding_size: None,
    }
}

/// The step uniforms at a dynamic offset (a chunk of packs of one substep).
fn dynamic_steps() -> wgpu::BindingType {
    wgpu::BindingType::Buffer {
        ty: wgpu::BufferBindingType::Uniform,
        has_dynamic_offset: true,
        min_binding_size: wgpu::BufferSize::new(STEPS_WINDOW),
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}

/// Room for `capacity` packs' substep uniforms, and the binding window past the last one.
fn step_buffer(device: &wgpu::Device, capacity: u32) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("furbake physics steps"),
        size: (capacity as u64 - 1) * STEP_STRIDE + STEPS_WINDOW,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn check_forces(forces: &ForceSet) -> Result<(), RenderError> {
    forces.validate().map_err(|e| RenderError::Parameter { what: e.to_string() })?;
    if forces.local.len() > MAX_LOCAL_FORCES {
        return Err(RenderError::Parameter {
            what: format!("{} local forces; the GPU physics applies at most {MAX_LOCAL_FORCES}", forces.local.len()),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn physics_structs_match_the_shader() {
        use crate::shaders::tests::check_layout;
        use std::mem::offset_of;
        let step = [
            ("accel", offset_of!(PhysicsStep, accel)),
            ("omega", offset_of!(PhysicsStep, omega)),
            ("alpha", offset_of!(PhysicsStep, alpha)),
            ("wind_dir", offset_of!(PhysicsStep, wind_dir)),
            ("wind", offset_of!(PhysicsStep, wind)),
            ("guard", offset_of!(PhysicsStep, guard)),
            ("counts", offset_of!(PhysicsStep, counts)),
            ("flags", offset_of!(PhysicsStep, flags)),
            ("teleport", offset_of!(PhysicsStep, teleport)),
            ("pose", offset_of!(PhysicsStep, pose)),
            ("pose_at", offset_of!(PhysicsStep, pose_at)),
            ("pose_skin", offset_of!(PhysicsStep, pose_skin)),
            ("locals", offset_of!(PhysicsStep, locals)),
            ("base", offset_of!(PhysicsStep, base)),
            ("base2", offset_of!(PhysicsStep, base2)),
            ("pad0", offset_of!(PhysicsStep, pad0)),
            ("pad1", offset_of!(PhysicsStep, pad1)),
        ];
        assert_eq!(check_layout("PhysicsStep", size_of::<PhysicsStep>(), &step), 1);
        let mass = [
            ("restoring_n", offset_of!(PhysicsMass, restoring_n)),
            ("rest_pos", offset_of!(PhysicsMass, rest_pos)),
            ("stick_anchor", offset_of!(PhysicsMass, stick_anchor)),
            ("mass", offset_of!(PhysicsMass, mass)),
            ("inv_mass", offset_of!(PhysicsMass, inv_mass)),
            ("links_start", offset_of!(PhysicsMass, links_start)),
            ("links_end", offset_of!(PhysicsMass, links_end)),
            ("restoring_parent", offset_of!(PhysicsMass, restoring_parent)),
            ("stick_parent", offset_of!(PhysicsMass, stick_parent)),
            ("stick_len", offset_of!(PhysicsMass, stick_len)),
            ("stick_c", offset_of!(PhysicsMass, stick_c)),
        ];
        assert_eq!(check_layout("PhysicsMass", size_of::<PhysicsMass>(), &mass), 1);
        let link = [
            ("other", offset_of!(PhysicsLink, other)),
            ("rest", offset_of!(PhysicsLink, rest)),
            ("k", offset_of!(PhysicsLink, k)),
            ("c", offset_of!(PhysicsLink, c)),
        ];
        assert_eq!(check_layout("PhysicsLink", size_of::<PhysicsLink>(), &link), 1);
        let tip = [
            ("n", offset_of!(PhysicsTip, n)),
            ("root_pos", offset_of!(PhysicsTip, root_pos)),
            ("root", offset_of!(PhysicsTip, root)),
            ("tip", offset_of!(PhysicsTip, tip)),
            ("pad0", offset_of!(PhysicsTip, pad0)),
            ("pad1", offset_of!(PhysicsTip, pad1)),
        ];
        assert_eq!(check_layout("PhysicsTip", size_of::<PhysicsTip>(), &tip), 1);
        let link = [
            ("a", offset_of!(PhysicsXpbdLink, a)),
            ("b", offset_of!(PhysicsXpbdLink, b)),
            ("rest", offset_of!(PhysicsXpbdLink, rest)),
            ("compliance", offset_of!(PhysicsXpbdLink, compliance)),
            ("c", offset_of!(PhysicsXpbdLink, c)),
            ("wa", offset_of!(PhysicsXpbdLink, wa)),
            ("wb", offset_of!(PhysicsXpbdLink, wb)),
            ("pad0", offset_of!(PhysicsXpbdLink, pad0)),
        ];
        assert_eq!(check_layout("PhysicsXpbdLink", size_of::<PhysicsXpbdLink>(), &link), 1);
        let colours = [("count", offset_of!(PhysicsColours, count)), ("starts", offset_of!(PhysicsColours, starts))];
        assert_eq!(check_layout("PhysicsColours", size_of::<PhysicsColours>(), &colours), 1);
    }
}
