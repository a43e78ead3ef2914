//! [`SkinningPass`]: the GPU skinning of one animated pack (glTF 2.0 specification, "Morph
//! Targets", then "Skins" → "Skinned Mesh Attributes"), one compute dispatch per frame that morphs
//! and skins every welded skin vertex into one storage buffer of posed positions and normals
//! (`shaders/skinning.wgsl`, the rules of `furbake_runtime::animation::morph_and_skin`):
//!
//! `p' = (Σ wᵢ·Mᵢ)(p + Σ wₜ·Δpₜ)`, `n' = normalize(cof(Σ wᵢ·Mᵢ)·(n + Σ wₜ·Δnₜ)·sign det)`, the bind
//! normal where `n'` collapses.
//!
//! The skin, every shell layer and the fins read that buffer by welded vertex index
//! ([`crate::FurRenderer`] binds it), so nothing is skinned twice. What is uploaded once per asset:
//! the bind pose, the influences as the pack stores them (docs/format.md "11 `skin_weights`") and
//! the morph deltas ("12 `morph_targets`"); per frame only the skinning matrices (one per bind,
//! `world(joint) × inverseBind`, docs/format.md "10 `skeleton`") and the morph weights are
//! written ([`SkinningPass::set_pose`]), and [`SkinningPass::encode`] records the dispatch into the
//! host's encoder. Nothing here submits or waits, except the test readback
//! [`SkinningPass::read_back`].

use furbake_formats::sections::morph_targets::MorphTargets;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use glam::Mat4;
use wgpu::util::DeviceExt;

use crate::RenderError;
use crate::shaders::{SKINNING_WGSL, SkinnedVertex, SkinningUniforms};
use crate::upload::Upload;

/// Vertices per workgroup of `cs_skin` (its `@workgroup_size`).
const WORKGROUP_SIZE: u32 = 64;
/// Storage buffers `cs_skin` binds (bindings 1–7).
const STORAGE_BINDINGS: u32 = 7;

/// The bytes of each GPU buffer of a skinning pass, computed from the sections' sizes alone (in
/// `u64`, so no size overflows before it is compared with a limit).
#[derive(Clone, Copy, Debug)]
struct BufferSizes {
    /// Bind pose, and equally the posed output: one [`SkinnedVertex`] per welded vertex.
    vertices: u64,
    /// Bind indices, `u16` per slot.
    binds: u64,
    /// Weights, `f32` per slot.
    weights: u64,
    /// Morph deltas, `3 × f32` per (target, vertex), twice with normal deltas.
    deltas: u64,
    /// Skinning matrices, 64 bytes per bind.
    matrices: u64,
    /// Morph weights, `f32` per target.
    morph_weights: u64,
}

impl BufferSizes {
    fn of(mesh: &SkinMesh, weights: Option<&SkinWeights>, morphs: Option<&MorphTargets>) -> BufferSizes {
        let v = mesh.positions.len() as u64;
        let slots = weights.map_or(0, |w| w.binds.len() as u64);
        let targets = morphs.map_or(0, |m| m.target_count() as u64);
        let delta_sets = morphs.map_or(0, |m| if m.normal_deltas.is_empty() { 1 } else { 2 });
        BufferSizes {
            vertices: v.saturating_mul(std::mem::size_of::<SkinnedVertex>() as u64),
            binds: slots.saturating_mul(2),
            weights: slots.saturating_mul(4),
            deltas: targets.saturating_mul(v).saturating_mul(12).saturating_mul(delta_sets),
            matrices: weights.map_or(0, |w| u64::from(w.bind_count)).saturating_mul(64),
            morph_weights: targets.saturating_mul(4),
        }
    }

    /// Every buffer with its name, for the limit checks.
    fn named(&self) -> [(&'static str, u64); 6] {
        [
            ("skinned vertex bytes", self.vertices),
            ("skin influence bind bytes", self.binds),
            ("skin influence weight bytes", self.weights),
            ("morph delta bytes", self.deltas),
            ("skinning matrix bytes", self.matrices),
            ("morph weight bytes", self.morph_weights),
        ]
    }

    fn total(&self) -> u64 {
        // The vertices twice: the bind pose in, the posed vertices out; plus the params uniform.
        let n = self.named();
        n.iter().fold(self.vertices, |sum, (_, b)| sum.saturating_add(*b)).saturating_add(16)
    }
}

#[cfg(feature = "testing")]
/// Posed welded vertices read back from the GPU, struct of arrays (the output buffers of
/// `furbake_runtime::animation::morph_and_skin`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PosedVertices {
    /// Position per welded vertex, metres (the pack's mesh frame).
    pub positions: Vec<[f32; 3]>,
    /// Unit normal per welded vertex.
    pub normals: Vec<[f32; 3]>,
}

/// The GPU skinning of one animated pack: its bind pose, influences and morph deltas on the GPU,
/// the per-frame skinning matrices and morph weights, the `cs_skin` pipeline, and the output
/// buffer of posed vertices ([`SkinningPass::skinned_buffer`]). Created only for a pack with skin
/// weights or morph targets: a static pack has no pass and pays nothing.
pub struct SkinningPass {
    vertex_count: u32,
    bind_count: u32,
    target_count: u32,
    /// What GPU fur physics blends an animated skin's transforms from ([`SkinInputs`]).
    inputs: SkinBuffers,
    /// What every pass of the asset shares ([`SkinningPass::instance`]).
    shared: std::sync::Arc<SkinShared>,
    matrices: wgpu::Buffer,
    morph_weights: wgpu::Buffer,
    skinned: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Workgroups dispatched in x and y (2D once one dimension's limit is exceeded).
    workgroups: (u32, u32),
}

/// The part of a skinning pass every pass of one asset shares: the params, the bind pose (on the
/// GPU, and on the CPU to start each pass's output from), the morph targets' default weights, the
/// bind group layout and the pipeline.
struct SkinShared {
    params: wgpu::Buffer,
    bind_pose: wgpu::Buffer,
    bind_pose_data: Vec<SkinnedVertex>,
    default_weights: Vec<f32>,
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

/// The static skin data a GPU blend reads, shared with the skinning pass.
#[derive(Clone)]
struct SkinBuffers {
    binds: wgpu::Buffer,
    weights: wgpu::Buffer,
    deltas: wgpu::Buffer,
    corners: wgpu::Buffer,
    vertices: wgpu::Buffer,
    influences_per_vertex: u32,
}

/// What GPU fur physics needs to blend an animated skin's per-shell-vertex transforms from a
/// step's skinning matrices and morph weights, as `furbake_runtime::animation` blends them on the
/// CPU: the pack's influences and morph deltas as the skinning pass holds them, and the welded
/// vertex of each shell vertex.
#[derive(Clone)]
pub(crate) struct SkinInputs {
    /// Bind index per influence slot, two `u16` per word.
    pub binds: wgpu::Buffer,
    /// Weight per influence slot.
    pub weights: wgpu::Buffer,
    /// Morph deltas, xyz triples, position deltas target-major first.
    pub deltas: wgpu::Buffer,
    /// Per shell vertex, its welded skin vertex.
    pub shell_vertices: wgpu::Buffer,
    /// Influence slots per vertex (0 without skin weights).
    pub influences_per_vertex: u32,
    /// Skinning matrices (binds) and morph targets a pose has.
    pub bind_count: u32,
    pub target_count: u32,
    /// Welded skin vertices.
    pub vertex_count: u32,
}

impl SkinningPass {
    /// The skin data for GPU fur physics whose shell vertices are this skin's welded vertices,
    /// or (`per_corner`) its triangles' corners.
    pub(crate) fn physics_inputs(&self, per_corner: bool) -> SkinInputs {
        let b = &self.inputs;
        SkinInputs {
            binds: b.binds.clone(),
            weights: b.weights.clone(),
            deltas: b.deltas.clone(),
            shell_vertices: if per_corner { b.corners.clone() } else { b.vertices.clone() },
            influences_per_vertex: b.influences_per_vertex,
            bind_count: self.bind_count,
            target_count: self.target_count,
            vertex_count: self.vertex_count,
        }
    }

    /// Uploads the bind pose of `mesh`, the influences of `weights` and the deltas of `morphs`
    /// (at least one of the two must be given) and builds the pipeline. The pose starts as
    /// identity skinning matrices and the targets' default weights, so before the first
    /// [`SkinningPass::set_pose`] a dispatch yields the bind pose with the default morph. Checks
    /// the sections against the mesh (counts, bind indices below `bind_count`; a pack's sections
    /// were already checked by `furbake_formats::check_consistency`) and every buffer against the
    /// device's limits ([`RenderError::Limit`]) before creating anything.
    pub fn new(
        device: &wgpu::Device,
        mesh: &SkinMesh,
        weights: Option<&SkinWeights>,
        morphs: Option<&MorphTargets>,
    ) -> Result<SkinningPass, RenderError> {
        check_sections(mesh, weights, morphs)?;
        let sizes = BufferSizes::of(mesh, weights, morphs);
        let limits = device.limits();
        for (what, bytes) in sizes.named() {
            for limit in [limits.max_storage_buffer_binding_size, limits.max_buffer_size] {
                if bytes > limit {
                    return Err(RenderError::Limit { what, value: bytes, limit });
                }
            }
        }
        if limits.max_storage_buffers_per_shader_stage < STORAGE_BINDINGS {
            return Err(RenderError::Limit {
                what: "storage buffers of the skinning pass",
                value: STORAGE_BINDINGS.into(),
                limit: limits.max_storage_buffers_per_shader_stage.into(),
            });
        }
        let workgroups = workgroups(mesh.positions.len() as u64, limits.max_compute_workgroups_per_dimension)?;
        crate::gpu_scope(device, "creating the skinning pass", || {
            Ok(Self::build(device, mesh, weights, morphs, workgroups))
        })
    }

    /// Bytes of GPU memory [`SkinningPass::new`] allocates for these sections (0 when neither
    /// `weights` nor `morphs` is given: no pass is made). From the sections' sizes alone.
    pub fn gpu_bytes(mesh: &SkinMesh, weights: Option<&SkinWeights>, morphs: Option<&MorphTargets>) -> u64 {
        if weights.is_none() && morphs.is_none() {
            return 0;
        }
        BufferSizes::of(mesh, weights, morphs).total()
    }

    /// The part of [`SkinningPass::gpu_bytes`] each further pass of the asset
    /// ([`SkinningPass::instance`]) allocates again: its posed vertices, skinning matrices and
    /// morph weights.
    pub fn instance_gpu_bytes(mesh: &SkinMesh, weights: Option<&SkinWeights>, morphs: Option<&MorphTargets>) -> u64 {
        if weights.is_none() && morphs.is_none() {
            return 0;
        }
        let b = BufferSizes::of(mesh, weights, morphs);
        b.vertices.saturating_add(b.matrices).saturating_add(b.morph_weights)
    }

    /// Another pass of the same asset: the bind pose, influences, morph deltas and pipeline
    /// shared with this one, its own pose and posed vertices (from the bind pose and the default
    /// morph, as a new pass starts). What a scene that places one animated pack many times makes
    /// for each placement.
    pub(crate) fn instance(&self, device: &wgpu::Device) -> Result<SkinningPass, RenderError> {
        crate::gpu_scope(device, "creating a skinning pass", || {
            Ok(Self::with_shared(
                device,
                std::sync::Arc::clone(&self.shared),
                self.inputs.clone(),
                (self.vertex_count, self.bind_count, self.target_count),
                self.workgroups,
            ))
        })
    }

    /// A pass over `shared` with its own pose buffers and output.
    fn with_shared(
        device: &wgpu::Device,
        shared: std::sync::Arc<SkinShared>,
        inputs: SkinBuffers,
        (vertex_count, bind_count, target_count): (u32, u32, u32),
        workgroups: (u32, u32),
    ) -> SkinningPass {
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label, contents: &[u8], usage| init_buffer(device, label, contents, usage);
        let skinned = init(
            "furbake skinned vertices",
            bytemuck::cast_slice(&shared.bind_pose_data),
            storage | wgpu::BufferUsages::COPY_SRC,
        );
        let identity = vec![Mat4::IDENTITY.to_cols_array(); bind_count as usize];
        let matrices =
            init("furbake skinning matrices", bytemuck::cast_slice(&identity), storage | wgpu::BufferUsages::COPY_DST);
        let morph_weights = init(
            "furbake morph weights",
            bytemuck::cast_slice(&shared.default_weights),
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let entries = [
            &shared.params,
            &shared.bind_pose,
            &inputs.binds,
            &inputs.weights,
            &inputs.deltas,
            &matrices,
            &morph_weights,
            &skinned,
        ];
        let entries: Vec<wgpu::BindGroupEntry<'_>> = entries
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake skinning bind group"),
            layout: &shared.layout,
            entries: &entries,
        });
        SkinningPass {
            vertex_count,
            bind_count,
            target_count,
            inputs,
            shared,
            matrices,
            morph_weights,
            skinned,
            bind_group,
            workgroups,
        }
    }

    fn build(
        device: &wgpu::Device,
        mesh: &SkinMesh,
        weights: Option<&SkinWeights>,
        morphs: Option<&MorphTargets>,
        workgroups: (u32, u32),
    ) -> SkinningPass {
        let v = mesh.positions.len();
        let bind_pose: Vec<SkinnedVertex> = mesh
            .positions
            .iter()
            .zip(&mesh.normals)
            .map(|(p, n)| SkinnedVertex { position: [p[0], p[1], p[2], 1.0], normal: [n[0], n[1], n[2], 0.0] })
            .collect();
        let params = SkinningUniforms {
            vertex_count: v as u32,
            influences_per_vertex: weights.map_or(0, |w| w.influences_per_vertex),
            target_count: morphs.map_or(0, |m| m.target_count() as u32),
            pad0: 0,
        };
        let bind_count = weights.map_or(0, |w| w.bind_count);
        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label, contents: &[u8], usage| init_buffer(device, label, contents, usage);
        let params_buffer = init("furbake skinning params", bytemuck::bytes_of(&params), wgpu::BufferUsages::UNIFORM);
        let bind_buffer = init("furbake skinning bind pose", bytemuck::cast_slice(&bind_pose), storage);
        let (binds, slot_weights): (&[u16], &[f32]) = weights.map_or((&[], &[]), |w| (&w.binds, &w.weights));
        let binds_buffer = init("furbake skin influence binds", bytemuck::cast_slice(binds), storage);
        let weights_buffer = init("furbake skin influence weights", bytemuck::cast_slice(slot_weights), storage);
        // Position deltas, then normal deltas (when any), one upload: docs/format.md
        // "12 `morph_targets`" arrays 0 and 1 back to back.
        let deltas: Vec<[f32; 3]> =
            morphs.map(|m| m.position_deltas.iter().chain(&m.normal_deltas).copied().collect()).unwrap_or_default();
        let deltas_buffer = init("furbake morph deltas", bytemuck::cast_slice(&deltas), storage);
        let layout = bind_group_layout(device);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("furbake skinning"),
            source: wgpu::ShaderSource::Wgsl(SKINNING_WGSL.into()),
        });
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let constants: &[(&str, f64)] = &[
            ("SKIN", flag(weights.is_some())),
            ("MORPH", flag(morphs.is_some_and(|m| m.target_count() > 0))),
            ("MORPH_NORMALS", flag(morphs.is_some_and(|m| !m.normal_deltas.is_empty()))),
        ];
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake skinning pipeline layout"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("furbake skinning"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("cs_skin"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        // Per triangle corner, its welded vertex (the shell vertices of a per-corner layout).
        let corners: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
        let inputs = SkinBuffers {
            binds: binds_buffer,
            weights: weights_buffer,
            deltas: deltas_buffer,
            corners: init("furbake skin corner vertices", bytemuck::cast_slice(&corners), storage),
            vertices: init(
                "furbake skin vertex indices",
                bytemuck::cast_slice(&(0..v as u32).collect::<Vec<u32>>()),
                storage,
            ),
            influences_per_vertex: params.influences_per_vertex,
        };
        let shared = std::sync::Arc::new(SkinShared {
            params: params_buffer,
            bind_pose: bind_buffer,
            bind_pose_data: bind_pose,
            default_weights: morphs.map_or_else(Vec::new, |m| m.default_weights.clone()),
            layout,
            pipeline,
        });
        Self::with_shared(device, shared, inputs, (v as u32, bind_count, params.target_count), workgroups)
    }

    #[cfg(feature = "testing")]
    /// Writes this frame's pose: `skinning_matrices`, one per bind (`world(joint) ×
    /// inverseBind`, e.g. from `furbake_runtime::animation::skinning_matrices`; empty for a pack
    /// without skin weights), and `morph_weights`, one per morph target (empty for a pack without
    /// them). A wrong count or a non-finite value is a [`RenderError::Parameter`] and changes
    /// nothing. Only `queue.write_buffer`s, straight from the caller's slices (no allocation):
    /// the pose lands before the next submission's dispatch.
    pub fn set_pose(
        &self,
        queue: &wgpu::Queue,
        skinning_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<(), RenderError> {
        self.check_pose(skinning_matrices, morph_weights)?;
        self.write_pose(&mut Upload::Queue(queue), skinning_matrices, morph_weights)
    }

    /// The checks of [`SkinningPass::set_pose`]: counts and finite values.
    pub(crate) fn check_pose(&self, skinning_matrices: &[Mat4], morph_weights: &[f32]) -> Result<(), RenderError> {
        let bad = |what: String| Err(RenderError::Parameter { what });
        if skinning_matrices.len() != self.bind_count as usize {
            return bad(format!("{} skinning matrices for {} binds", skinning_matrices.len(), self.bind_count));
        }
        if morph_weights.len() != self.target_count as usize {
            return bad(format!("{} morph weights for {} morph targets", morph_weights.len(), self.target_count));
        }
        if let Some(i) = skinning_matrices.iter().position(|m| !m.is_finite()) {
            return bad(format!("skinning matrix {i} is not finite"));
        }
        if let Some(i) = morph_weights.iter().position(|w| !w.is_finite()) {
            return bad(format!("morph weight {i} is not finite"));
        }
        Ok(())
    }

    /// Writes a checked pose ([`SkinningPass::check_pose`]) through `upload`.
    pub(crate) fn write_pose(
        &self,
        upload: &mut Upload<'_>,
        skinning_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<(), RenderError> {
        // Column-major, as WGSL's mat4x4<f32> and glam's to_cols_array.
        let matrices = skinning_matrices.iter().map(|m| bytemuck::cast::<[f32; 16], [u8; 64]>(m.to_cols_array()));
        upload.write_chunks(&self.matrices, 0, matrices, "skinning matrix")?;
        if !morph_weights.is_empty() {
            upload.write(&self.morph_weights, 0, bytemuck::cast_slice(morph_weights));
        }
        Ok(())
    }

    /// Records the skinning dispatch into `encoder` (its own compute pass): every welded vertex
    /// morphed and skinned with the pose last written, into [`SkinningPass::skinned_buffer`].
    /// Record it before the render passes that read the buffer; wgpu orders the two.
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        if self.vertex_count == 0 {
            return;
        }
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("furbake skinning"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.shared.pipeline);
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.dispatch_workgroups(self.workgroups.0, self.workgroups.1, 1);
    }

    /// The posed vertices: one [`SkinnedVertex`] per welded skin vertex, as the last submitted
    /// dispatch wrote them (the bind pose before the first). A read-only storage binding for
    /// shaders that draw the posed skin.
    pub fn skinned_buffer(&self) -> &wgpu::Buffer {
        &self.skinned
    }

    #[cfg(feature = "testing")]
    /// Welded skin vertices skinned per dispatch.
    pub fn vertex_count(&self) -> u32 {
        self.vertex_count
    }

    #[cfg(feature = "testing")]
    /// Skinning matrices [`SkinningPass::set_pose`] expects (the skeleton's binds; 0 without
    /// skin weights).
    pub fn bind_count(&self) -> u32 {
        self.bind_count
    }

    #[cfg(feature = "testing")]
    /// Morph weights [`SkinningPass::set_pose`] expects (0 without morph targets).
    pub fn target_count(&self) -> u32 {
        self.target_count
    }

    #[cfg(feature = "testing")]
    /// Copies [`SkinningPass::skinned_buffer`] back: the posed position and normal of every
    /// welded vertex, as the last submitted dispatch wrote them. Submits a copy and waits for the
    /// GPU: for tests against `furbake_runtime::animation::morph_and_skin` (whose output buffers
    /// [`PosedVertices`] mirrors), not for frames.
    pub fn read_back(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<PosedVertices, RenderError> {
        let size = self.skinned.size();
        let readback = crate::gpu_scope(device, "reading back the skinned vertices", || {
            let readback = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("furbake skinned readback"),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let mut encoder = device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake skinned readback") });
            encoder.copy_buffer_to_buffer(&self.skinned, 0, &readback, 0, size);
            crate::blocking::submit(queue, [encoder.finish()]);
            Ok(readback)
        })?;
        crate::blocking::map_for_reading(device, &readback, "skinned vertex readback")?;
        let out = {
            let view = readback.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
            let vertices: &[SkinnedVertex] = bytemuck::cast_slice(&view);
            let vertices = &vertices[..self.vertex_count as usize];
            PosedVertices {
                positions: vertices.iter().map(|s| [s.position[0], s.position[1], s.position[2]]).collect(),
                normals: vertices.iter().map(|s| [s.normal[0], s.normal[1], s.normal[2]]).collect(),
            }
        };
        readback.unmap();
        Ok(out)
    }
}

/// A buffer holding `contents`. Storage bindings cannot be empty: an absent input (or an empty
/// mesh) is a zeroed placeholder the shader never reads (its SKIN or MORPH switch is off).
fn init_buffer(device: &wgpu::Device, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    const PLACEHOLDER: [u8; 64] = [0; 64];
    let contents = if contents.is_empty() { &PLACEHOLDER[..] } else { contents };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
}

/// Checks the animation sections against the mesh and one another, so the shader indexes in
/// range: at least one of them, one influence set per vertex with 4 or 8 slots and bind indices
/// below `bind_count`, one delta per (target, vertex), normal deltas none or as many.
fn check_sections(
    mesh: &SkinMesh,
    weights: Option<&SkinWeights>,
    morphs: Option<&MorphTargets>,
) -> Result<(), RenderError> {
    let bad = |what: String| Err(RenderError::InvalidAsset { what });
    let v = mesh.positions.len();
    if weights.is_none() && morphs.is_none() {
        return Err(RenderError::Parameter {
            what: "a skinning pass needs skin weights or morph targets (a static pack has no pass)".into(),
        });
    }
    if mesh.normals.len() != v {
        return bad(format!("{v} positions but {} normals", mesh.normals.len()));
    }
    if v > u32::MAX as usize / 2 {
        return bad(format!("{v} vertices exceed the skinning pass's index range"));
    }
    if let Some(w) = weights {
        let k = w.influences_per_vertex as usize;
        if k != 4 && k != 8 {
            return bad(format!("skin weights with {k} influences per vertex (4 or 8)"));
        }
        if w.binds.len() != k * v || w.weights.len() != k * v {
            return bad(format!(
                "skin weights for {} / {} slots, the mesh needs {k} × {v}",
                w.binds.len(),
                w.weights.len()
            ));
        }
        if let Some(b) = w.binds.iter().find(|&&b| u32::from(b) >= w.bind_count) {
            return bad(format!("skin weight bind {b} is outside the {} binds", w.bind_count));
        }
    }
    if let Some(m) = morphs {
        let deltas = m.target_count().checked_mul(v);
        if m.vertex_count as usize != v || deltas != Some(m.position_deltas.len()) {
            return bad(format!(
                "morph targets for {} vertices with {} position deltas, the mesh has {v} vertices and {} targets",
                m.vertex_count,
                m.position_deltas.len(),
                m.target_count()
            ));
        }
        if !m.normal_deltas.is_empty() && m.normal_deltas.len() != m.position_deltas.len() {
            return bad(format!(
                "{} normal deltas for {} position deltas",
                m.normal_deltas.len(),
                m.position_deltas.len()
            ));
        }
    }
    Ok(())
}

/// Workgroups `(x, y)` covering `vertices` at [`WORKGROUP_SIZE`] each: one row while it fits the
/// per-dimension limit, else rows of `max` (the shader flattens `x + y·groups_x`).
fn workgroups(vertices: u64, max: u32) -> Result<(u32, u32), RenderError> {
    let groups = vertices.div_ceil(u64::from(WORKGROUP_SIZE));
    let max64 = u64::from(max.max(1));
    if groups <= max64 {
        return Ok((groups as u32, 1));
    }
    let rows = groups.div_ceil(max64);
    if rows > max64 {
        return Err(RenderError::Limit { what: "skinning workgroups", value: groups, limit: max64 * max64 });
    }
    Ok((max, rows as u32))
}

fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let entry = crate::compute_buffer_entry;
    let read = wgpu::BufferBindingType::Storage { read_only: true };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake skinning bind group layout"),
        entries: &[
            entry(0, wgpu::BufferBindingType::Uniform),
            entry(1, read),
            entry(2, read),
            entry(3, read),
            entry(4, read),
            entry(5, read),
            entry(6, read),
            entry(7, wgpu::BufferBindingType::Storage { read_only: false }),
        ],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workgroups_fold_into_rows_past_the_dimension_limit() {
        assert_eq!(workgroups(0, 65_535).unwrap(), (0, 1));
        assert_eq!(workgroups(64, 65_535).unwrap(), (1, 1));
        assert_eq!(workgroups(65, 65_535).unwrap(), (2, 1));
        // 10 groups with a limit of 4: rows of 4, three rows (the shader skips the overhang).
        assert_eq!(workgroups(640, 4).unwrap(), (4, 3));
        assert!(matches!(workgroups(64 * 17, 4), Err(RenderError::Limit { .. })));
    }
}
