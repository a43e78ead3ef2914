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
    pipeline: wgpu::ComputePipeline,
    /// The links (their rest lengths follow a posed skin).
    links: wgpu::Buffer,
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

/// A pack's fur physics on the GPU, bound to the renderer whose scale vectors it writes
/// ([`FurRenderer::gpu_physics`]). [`GpuFurPhysics::record`] once per frame, before the frame's
/// draws in the same submission.
pub struct GpuFurPhysics {
    forces: ForceSet,
    guard: GuardSettings,
    update: ComputeUpdate,
    project_sticks: bool,
    time_s: f64,
    stable_step_s: f64,
    max_substeps: u32,
    restoring_weight_n: f32,
    counts: [u32; 3],
    #[cfg_attr(not(feature = "testing"), allow(dead_code))]
    masses: u32,
    #[cfg_attr(not(feature = "testing"), allow(dead_code))]
    order: Vec<u32>,
    x: [wgpu::Buffer; 2],
    v: [wgpu::Buffer; 2],
    #[cfg_attr(not(feature = "testing"), allow(dead_code))]
    guard_state: wgpu::Buffer,
    stats: wgpu::Buffer,
    steps: wgpu::Buffer,
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
        model.validate().map_err(|e| RenderError::Parameter { what: e.to_string() })?;
        let shell = model.shell_tip.len() as u32;
        let layout = if shell == self.vertex_count() {
            furbake_runtime::ShellVertexLayout::PerVertex
        } else if shell == 3 * self.triangle_count() {
            furbake_runtime::ShellVertexLayout::PerCorner
        } else {
            return Err(RenderError::Parameter {
                what: format!(
                    "the physics model has {shell} shell vertices; this pack has {} welded vertices and {} corners",
                    self.vertex_count(),
                    3 * self.triangle_count()
                ),
            });
        };
        if stable_step_s.is_nan() || stable_step_s <= 0.0 || max_substeps == 0 {
            return Err(RenderError::Parameter {
                what: format!("stable step {stable_step_s} s and {max_substeps} substeps (must be positive)"),
            });
        }
        self.set_scale_layout(queue, layout);
        let skin =
            self.skinning_pass().map(|s| s.physics_inputs(layout == furbake_runtime::ShellVertexLayout::PerCorner));
        GpuFurPhysics::new(device, model, forces, stable_step_s, max_substeps, self.scale_buffer(), skin)
    }
}

impl GpuFurPhysics {
    fn new(
        device: &wgpu::Device,
        model: &ComputeModel,
        forces: &ForceSet,
        stable_step_s: f64,
        max_substeps: u32,
        scale_out: &wgpu::Buffer,
        skin: Option<crate::skinning::SkinInputs>,
    ) -> Result<GpuFurPhysics, RenderError> {
        check_forces(forces)?;
        let nf = model.free as usize;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        // Storage bindings cannot be empty: every array has at least one element.
        let padded = |mut v: Vec<[f32; 4]>| {
            if v.is_empty() {
                v.push([0.0; 4]);
            }
            v
        };
        let positions = padded(model.positions.iter().map(|&p| v4(p, 0.0)).collect());
        let velocities = padded(model.velocities.iter().map(|&p| v4(p, 0.0)).collect());
        let mut masses: Vec<PhysicsMass> = (0..nf)
            .map(|k| PhysicsMass {
                restoring_n: v4(model.restoring_n[k], model.restoring_len[k]),
                rest_pos: v4(model.rest[k], 0.0),
                stick_anchor: match model.stick_parent[k] {
                    NO_LINK => [0.0; 4],
                    p => v4(model.rest[p as usize], 0.0),
                },
                mass: model.mass[k],
                inv_mass: 1.0 / model.mass[k],
                links_start: model.links_start[k],
                links_end: model.links_start[k + 1],
                restoring_parent: model.restoring_parent[k],
                stick_parent: model.stick_parent[k],
                stick_len: model.stick[k][0],
                stick_c: model.stick[k][1],
            })
            .collect();
        if masses.is_empty() {
            masses.push(bytemuck::Zeroable::zeroed());
        }
        let mut links: Vec<PhysicsLink> = model
            .link_other
            .iter()
            .zip(&model.link_params)
            .map(|(&other, p)| PhysicsLink { other, rest: p[0], k: p[1], c: p[2] })
            .collect();
        if links.is_empty() {
            links.push(bytemuck::Zeroable::zeroed());
        }
        let mut tips: Vec<PhysicsTip> = model
            .tips
            .iter()
            .map(|t| PhysicsTip {
                n: v4(t.n, 0.0),
                root_pos: v4(model.rest[t.root as usize], 0.0),
                root: t.root,
                tip: t.tip,
                pad0: 0,
                pad1: 0,
            })
            .collect();
        if tips.is_empty() {
            tips.push(bytemuck::Zeroable::zeroed());
        }
        let mut guard_state: Vec<[f32; 4]> =
            model.scale.iter().zip(&model.frozen).map(|(&s, &f)| v4(s, if f { 1.0 } else { 0.0 })).collect();
        if guard_state.is_empty() {
            guard_state.push([0.0; 4]);
        }
        let mut shell_tip = model.shell_tip.clone();
        if shell_tip.is_empty() {
            shell_tip.push(NO_LINK);
        }
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
            let stats = init("furbake physics counters", &[0u8; 16], storage);
            let steps_capacity = 4;
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
                    model,
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
            let pose = pose::Pose::new(device, model, &module, &targets, xpbd.as_ref().map(|x| &x.links), skin)?;
            let energy = EnergyPass::new(device, &module, model, forces, &x, &v, &mass_buffer, &links);
            Ok(GpuFurPhysics {
                xpbd,
                tip_buffer,
                pose,
                forces: forces.clone(),
                guard: model.guard.clone(),
                update: model.update,
                project_sticks: model.project_sticks,
                time_s: model.time_s,
                stable_step_s,
                max_substeps,
                restoring_weight_n: forces.restoring_weight_n,
                counts: [model.free, model.tips.len() as u32, model.shell_tip.len() as u32],
                masses: model.masses,
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
                current: 0,
                scratch: Vec::with_capacity(steps_capacity as usize),
                scratch_bytes: Vec::with_capacity(steps_capacity as usize * STEP_STRIDE as usize),
                last_record: (0, 0),
                stats_readback: Readback::new(device, "furbake physics counters readback", 16),
                energy,
            })
        })
    }

    /// Replaces the forces. The restoring weight stays the one the stable step was computed for
    /// (a different one is a [`RenderError::Parameter`]: build again from a simulator with it).
    pub fn set_forces(&mut self, forces: &ForceSet) -> Result<(), RenderError> {
        check_forces(forces)?;
        self.check_restoring(forces)?;
        self.forces.clone_from(forces);
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
    pub fn record(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        dt_s: f64,
    ) -> Result<u32, RenderError> {
        let forces = std::mem::take(&mut self.forces);
        let out = self.record_steps(
            device,
            queue,
            encoder,
            dt_s,
            &[GpuStep { forces: &forces, teleport_m: [0.0; 3], pose: None }],
        );
        self.forces = forces;
        out
    }

    /// Records `steps.len()` steps of `dt_s` seconds (what a world that stepped several times
    /// since the last frame hands over), each with its teleport, substeps and guard, then the
    /// scale vectors; returns the substeps recorded. One record per submission, as
    /// [`GpuFurPhysics::record`]. The forces must keep the restoring weight the physics was built
    /// for; a step with too many substeps, bad forces or a non-finite teleport records nothing.
    pub fn record_steps(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        dt_s: f64,
        steps: &[GpuStep<'_>],
    ) -> Result<u32, RenderError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(RenderError::Parameter {
                what: format!("physics step {dt_s} s (must be finite and positive)"),
            });
        }
        for step in steps {
            self.check_restoring(step.forces)?;
            check_forces(step.forces)?;
            if !step.teleport_m.iter().all(|c| c.is_finite()) {
                return Err(RenderError::Parameter { what: format!("teleport {:?} is not finite", step.teleport_m) });
            }
            if let Some(p) = &step.pose {
                match &self.pose {
                    Some(pose) => pose.check(p)?,
                    None => {
                        return Err(RenderError::Parameter {
                            what: "a skin pose for GPU physics built from a static skin (pose the simulator once, \
                                   Simulator::pose_skin, before its compute_model)"
                                .into(),
                        });
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
        let (substeps, count) = (substeps as u32, steps.len() as u32);
        if count == 0 {
            return Ok(0);
        }
        let total = substeps * count;
        let posed = steps.iter().filter(|s| s.pose.is_some()).count() as u32;
        let mut rebind_pose = false;
        if total > self.steps_capacity {
            // Grows, never shrinks: a steady frame rate allocates nothing here.
            self.steps_capacity = total.next_power_of_two();
            self.steps = step_buffer(device, self.steps_capacity);
            self.state = self.parts().bind_all(device, &self.x, &self.v);
            rebind_pose = true;
        }
        if let Some(pose) = self.pose.as_mut() {
            rebind_pose |= pose.reserve(device, posed, count);
            if rebind_pose {
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
        }
        let h = dt_s / substeps as f64;
        self.scratch.clear();
        // Time advances step by step, as the CPU simulator's does (so one record of n steps and n
        // records of one agree to the bit).
        let mut t = self.time_s;
        let mut poses = 0;
        for (n, step) in (0..count).zip(steps) {
            for sub in 0..substeps {
                // The teleport and the pose belong to the step's first substep (cs_teleport and
                // the pose passes read them there).
                let teleport = if sub == 0 { step.teleport_m } else { [0.0; 3] };
                let mut u = self.uniforms(step.forces, teleport, t + sub as f64 * h, h as f32);
                if let (0, Some(p), Some(pose)) = (sub, &step.pose, &self.pose) {
                    (u.pose, u.pose_at, u.pose_skin) = pose.uniforms(poses, n, dt_s, p.cut_speed_m_per_s);
                    poses += 1;
                }
                self.scratch.push(u);
            }
            t += dt_s;
        }
        let bytes = self.scratch_bytes();
        queue.write_buffer(&self.steps, 0, &bytes);
        self.scratch_bytes = bytes;
        encoder.clear_buffer(&self.stats, 0, None);
        if let (Some(pose), true) = (self.pose.as_mut(), posed > 0) {
            pose.write(queue, steps.iter().filter_map(|s| s.pose.as_ref()));
            pose.clear(encoder);
        }
        let free_groups = self.counts[0].div_ceil(WORKGROUP).max(1);
        for (n, step) in (0..count).zip(steps) {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("furbake fur physics"),
                timestamp_writes: None,
            });
            let first = n * substeps;
            if step.teleport_m != [0.0; 3] {
                pass.set_pipeline(&self.teleport_pipeline);
                pass.set_bind_group(0, &self.state.last[self.current], &[(first as u64 * STEP_STRIDE) as u32]);
                pass.set_bind_group(1, &self.tips, &[]);
                pass.dispatch_workgroups(free_groups, 1, 1);
            }
            if let (Some(p), Some(pose)) = (&step.pose, &self.pose) {
                // The skin moves to its pose at the step's end before the step (as the CPU
                // world poses the simulator before stepping it).
                let blend = matches!(p.skin, GpuSkin::Skinning { .. });
                pose.record(&mut pass, (first as u64 * STEP_STRIDE) as u32, self.current, blend);
            }
            if let Some(x) = &self.xpbd {
                x.record(&mut pass, (first as u64 * STEP_STRIDE) as u32, self.current);
                self.current = 1 - self.current;
            } else {
                pass.set_pipeline(&self.step_pipeline);
                for sub in first..first + substeps {
                    pass.set_bind_group(0, &self.state.step[self.current], &[(sub as u64 * STEP_STRIDE) as u32]);
                    pass.dispatch_workgroups(free_groups, 1, 1);
                    self.current = 1 - self.current;
                }
            }
            // The guard reads and kicks the step's final state, with its last substep's uniforms.
            let last = ((first + substeps - 1) as u64 * STEP_STRIDE) as u32;
            pass.set_pipeline(&self.guard_pipeline);
            pass.set_bind_group(0, &self.state.last[self.current], &[last]);
            pass.set_bind_group(1, &self.tips, &[]);
            pass.dispatch_workgroups(self.counts[1].div_ceil(WORKGROUP).max(1), 1, 1);
            if n + 1 == count {
                pass.set_pipeline(&self.scale_pipeline);
                pass.dispatch_workgroups(self.counts[2].div_ceil(WORKGROUP).max(1), 1, 1);
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

    /// The counters [`GpuFurPhysics::request_stats`] asked for, once the GPU has written them;
    /// `None` until then (and without a request). Never waits: the first call after the host's
    /// submission starts the mapping, and the host's own device polling (its next frame's submit
    /// or `Device::poll`) completes it. A failed mapping is a [`RenderError::Gpu`].
    pub fn poll_stats(&mut self) -> Result<Option<GpuPhysicsStats>, RenderError> {
        let read = |view: &[u8]| -> [u32; 4] { bytemuck::pod_read_unaligned(&view[..16]) };
        Ok(self.stats_readback.try_read("GPU physics counters", read)?.map(|(c, record)| GpuPhysicsStats {
            steps: record.0,
            substeps: record.1,
            non_finite: c[0],
            guard_triggers: c[1],
            frozen: c[2],
        }))
    }

    /// Asks for the energy of the current state (after the records so far), as
    /// `Simulator::energy` measures it: records one compute pass of per-workgroup partial sums and
    /// their copy into `encoder`. Then, after the host's submission,
    /// [`GpuFurPhysics::poll_energy`] hands it over without waiting. False (nothing recorded)
    /// while an earlier request is still on its way.
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
            pass.set_bind_group(0, &e.groups[self.current], &[0]);
            pass.dispatch_workgroups(e.workgroups, 1, 1);
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

    /// The uniforms of the substep starting at `t` (as `furbake_sim`'s `ForceEval::new`).
    fn uniforms(&self, f: &ForceSet, teleport_m: [f32; 3], t: f64, h: f32) -> PhysicsStep {
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
            teleport: v4(teleport_m, 0.0),
            pose: [0.0; 4],
            pose_at: [0; 4],
            pose_skin: [0; 4],
            locals,
            base: [0; 4],
            base2: [0; 4],
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
    /// Reads the current state back (submits and waits: tests and tools only).
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<PhysicsReadback, RenderError> {
        use crate::blocking::read_buffer;
        let n = self.masses as u64;
        let order = |v: Vec<[f32; 4]>| {
            let mut out = vec![[0.0f32; 3]; n as usize];
            for (k, &i) in self.order.iter().enumerate() {
                out[i as usize] = [v[k][0], v[k][1], v[k][2]];
            }
            out
        };
        let x: Vec<[f32; 4]> = read_buffer(device, queue, &self.x[self.current], n, "physics positions")?;
        let v: Vec<[f32; 4]> = read_buffer(device, queue, &self.v[self.current], n, "physics velocities")?;
        let g: Vec<[f32; 4]> = read_buffer(device, queue, &self.guard_state, self.counts[1] as u64, "physics guard")?;
        let c: Vec<u32> = read_buffer(device, queue, &self.stats, 3, "physics counters")?;
        Ok(PhysicsReadback {
            positions: order(x),
            velocities: order(v),
            scale: g.iter().map(|s| ([s[0], s[1], s[2]], s[3] != 0.0)).collect(),
            counters: [c[0], c[1], c[2]],
        })
    }
}

impl EnergyPass {
    #[allow(clippy::too_many_arguments)]
    fn new(
        device: &wgpu::Device,
        module: &wgpu::ShaderModule,
        model: &ComputeModel,
        forces: &ForceSet,
        x: &[wgpu::Buffer; 2],
        v: &[wgpu::Buffer; 2],
        masses: &wgpu::Buffer,
        links: &wgpu::Buffer,
    ) -> EnergyPass {
        const THREADS: u32 = 256;
        let workgroups = model.free.div_ceil(THREADS).max(1);
        // Its own uniforms: the free masses and the restoring weight, fixed for the physics.
        let mut uniforms: PhysicsStep = bytemuck::Zeroable::zeroed();
        uniforms.counts = [model.free, model.tips.len() as u32, model.shell_tip.len() as u32, 0];
        uniforms.alpha[3] = forces.restoring_weight_n;
        let mut contents = vec![0u8; STEPS_WINDOW as usize];
        contents[..size_of::<PhysicsStep>()].copy_from_slice(bytemuck::bytes_of(&uniforms));
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("furbake physics energy uniforms"),
            contents: &contents,
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let partials = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake physics energy partial sums"),
            size: workgroups as u64 * 16,
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
        model: &ComputeModel,
        iterations: u32,
        parts: XpbdParts<'_>,
    ) -> Result<Xpbd, RenderError> {
        let XpbdParts { x, v, module, state } = parts;
        let colours = model.xpbd.colour_start.len().saturating_sub(1);
        if colours > MAX_XPBD_COLOURS {
            return Err(RenderError::Parameter {
                what: format!("XPBD's links take {colours} colours; the GPU physics takes at most {MAX_XPBD_COLOURS}"),
            });
        }
        let mut links: Vec<PhysicsXpbdLink> = model
            .xpbd
            .links
            .iter()
            .map(|l| PhysicsXpbdLink {
                a: l.ends[0],
                b: l.ends[1],
                rest: l.rest,
                compliance: l.compliance,
                c: l.c,
                wa: l.inv_mass[0],
                wb: l.inv_mass[1],
                pad0: 0.0,
            })
            .collect();
        let count = links.len();
        if links.is_empty() {
            links.push(bytemuck::Zeroable::zeroed());
        }
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
        let bind = |from: usize| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("furbake physics xpbd"),
                layout: &layout,
                entries: &[
                    state.steps_entry(),
                    entry(1, &x[from]),
                    entry(2, &v[from]),
                    entry(3, &x[1 - from]),
                    entry(4, &v[1 - from]),
                    entry(6, state.masses),
                    entry(8, state.stats),
                    entry(10, &links_buffer),
                    entry(11, &lambda),
                    entry(12, &colours_buffer),
                ],
            })
        };
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
        let bind = [bind(0), bind(1)];
        Ok(Xpbd { bind, pipeline, links: links_buffer })
    }

    /// Records one XPBD step from state `from` into `1 − from` with the step uniforms at
    /// `step_offset`: one workgroup does the whole step (`cs_xpbd_step`).
    fn record(&self, pass: &mut wgpu::ComputePass<'_>, step_offset: u32, from: usize) {
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.bind[from], &[step_offset]);
        pass.dispatch_workgroups(1, 1, 1);
    }
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
