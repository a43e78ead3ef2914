//! [`BladeRenderer`]: instanced grass blades on the GPU (grass thesis §3.2.5–3.2.6, §4.2), the
//! twin of furbake-grass's CPU reference `KeyframeDecoder::world_positions`. Uploads a blade
//! field (roots, yaw, height scale, cluster corner indices and bilinear weights, eq. 3.6–3.8) and
//! a keyframe table (reference blade, vertex→stored-vector map, the displacement payload packed
//! into u32 words in its own encoding: f32, snorm16, f16, unorm8 or snorm8); each frame the
//! caller writes the cluster corner forces (from a `ForceField`), a compute pass (`cs_blades` in
//! `shaders/blades.wgsl`) selects every blade's pose (eq. 3.10–3.12, nearest or linear eq. 3.13)
//! and writes pack-frame vertex positions, which [`BladeRenderer::read_positions`] reads back
//! (tests compare them with the CPU reference). The instanced draw (instance = blade) poses each
//! vertex in the vertex shader with the same WGSL functions and shades it two-sided with Lambert
//! diffuse into the host's render pass ([`BladeRenderer::prepare`], [`BladeRenderer::render`]:
//! middleware that never submits or waits, pipelines from a shared [`PipelineCache`] for the
//! host's [`TargetDesc`]), depth-tested against what the host drew.
//!
//! Wind sources with delayed attenuation (§4.5, fig. 4.8) are evaluated per blade on the GPU when
//! the forces come from [`BladeRenderer::set_force_scene`]. Not on the GPU: spherical
//! in-betweening (eq. 3.14).

use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::{Displacements, KeyframeTable, STATIC_VERTEX};
use furbake_grass::{ForceField, PoseInterpolation};
use wgpu::util::DeviceExt;

use crate::culling::{BLOCK, BLOCKS_AT, BladeLods, CullUniforms, GrassCulling, LISTS_AT};
#[cfg(feature = "testing")]
use crate::culling::{CullLists, MAX_LODS};
use crate::shaders::FrameUniforms;
use crate::upload::{ExactLen, Upload};
use crate::{DepthPyramid, PipelineCache, RenderError, TargetDesc};

/// The `BladeUniforms` uniform of `blades.wgsl` (binding 1).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BladeUniforms {
    /// Linear RGB blade colour (a unused).
    pub color: [f32; 4],
    /// Number of blades.
    pub blade_count: u32,
    /// Vertices per blade.
    pub vertex_count: u32,
    /// Stored vectors per stored pose.
    pub stored_vectors: u32,
    /// Stored angles per magnitude (angles / symmetry factor).
    pub stored_angles: u32,
    /// Magnitude samples (zero force excluded).
    pub magnitudes: u32,
    /// Angle samples over the full circle.
    pub angles: u32,
    /// 1 when the x mirror is exploited.
    pub mirror_x: u32,
    /// 1 when the z mirror is exploited.
    pub mirror_z: u32,
    /// `magnitudes / max_force`.
    pub magnitude_per_force: f32,
    /// `angles / 2π`.
    pub angle_per_radian: f32,
    /// Dequantisation scale (1 for the float encodings).
    pub scale: f32,
    /// 0 f32, 1 snorm16, 2 f16, 3 unorm8, 4 snorm8.
    pub encoding: u32,
    /// 0 nearest, 1 linear.
    pub interpolation: u32,
    /// 1: Lambert diffuse.
    pub lambert: u32,
    /// Wind sources with delayed attenuation in this frame (rewritten by
    /// [`BladeRenderer::set_force_scene`]; 0 after [`BladeRenderer::set_corner_forces`]).
    pub delayed_sources: u32,
    /// Cluster grid corners (stride of the delayed-direction buffer).
    pub corner_count: u32,
    /// Cells along x of the cluster grid (a blade's corners follow from its cluster).
    pub cells_x: u32,
    /// Seed of the per-blade and per-clump colour variation (the blade field's bake seed).
    pub seed: u32,
    /// 1: the blade shading of [`BladeShading`]; 0: flat colour × two-sided Lambert.
    pub shading: u32,
    /// Unused (uniform alignment).
    pub pad: u32,
    /// Linear RGB colour at the tip (the root takes `color`); a unused.
    pub tip_color: [f32; 4],
    /// x root occlusion, y blade variation, z clump variation, w translucency.
    pub shade: [f32; 4],
    /// x gloss, y gloss exponent, z normal rounding, w edge darkening.
    pub gloss: [f32; 4],
}

/// One grass field's forces for this frame.
#[derive(Clone, Copy, Debug)]
pub enum BladeForces<'a> {
    /// Cluster corner forces `(x, z)`, one per grid corner ([`BladeRenderer::set_corner_forces`]).
    Corners(&'a [[f32; 2]]),
    /// A CPU force field over the blade field's grid ([`BladeRenderer::set_force_field`]; its
    /// delayed-attenuation sources are dropped: use [`BladeForces::Scene`] for those).
    Field(&'a ForceField),
    /// A force field updated from `scene` plus the scene's delayed-attenuation sources, evaluated
    /// per blade on the GPU ([`BladeRenderer::set_force_scene`]).
    Scene {
        /// The field (`ForceField::update(scene)` already called).
        field: &'a ForceField,
        /// The scene it was updated from.
        scene: &'a furbake_grass::ForceScene,
    },
}

/// Bytes of one [`DelayedSourceGpu`].
const DELAYED_SOURCE_BYTES: usize = std::mem::size_of::<DelayedSourceGpu>();

/// One wind source with delayed attenuation as `blades.wgsl` reads it (`DelayedSource`,
/// binding 7).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DelayedSourceGpu {
    /// Position `W` in metres (xyz) and emissive power `ω` (w).
    pub position_power: [f32; 4],
    /// Concentration `σ`, lower distance clamp in metres, unused, unused.
    pub params: [f32; 4],
}

/// Most wind sources with delayed attenuation one frame can carry on the GPU (fewer when
/// `corners × sources × 8` bytes would pass the device's storage binding limit).
pub const MAX_DELAYED_SOURCES: u32 = 8;

/// One blade instance as `blades.wgsl` reads it (`Blade`, binding 2).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BladeGpu {
    /// Root position in metres (xyz) and height scale in metres per blade length (w).
    pub root: [f32; 4],
    /// `cos yaw`, `sin yaw`.
    pub yaw: [f32; 2],
    /// The blade's cluster (grid cell).
    pub cluster: u32,
    /// Unused (alignment).
    pub pad: u32,
    /// The bilinear weights of the cluster's corners `[P1, P2, P3, P4]` (their indices follow
    /// from the cluster and the grid, as `ClusterGrid::corner_indices`).
    pub weights: [f32; 4],
}

/// Compute workgroup size of `cs_blades` (one thread per blade).
const WORKGROUP: u32 = 64;
/// A blade's culling decision when it is hidden behind the depth pyramid (`OCCLUDED` in
/// grass_common.wgsl).
#[cfg(feature = "testing")]
const OCCLUDED: u32 = 0xffff_fffe;

/// How blades are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BladeRenderSettings {
    /// Pose selection: [`PoseInterpolation::Nearest`] (default) or [`PoseInterpolation::Linear`];
    /// spherical is CPU-only and refused.
    pub interpolation: PoseInterpolation,
    /// Linear RGB blade colour. Default a grass green `[0.18, 0.45, 0.08]`.
    pub color: [f32; 3],
    /// Lambert diffuse (off: unlit colour). Default true.
    pub lambert: bool,
    /// Culling and level of detail (docs/design.md, grass culling). Default [`GrassCulling::default`]; a
    /// runtime scene's `[grass_culling]`.
    pub culling: GrassCulling,
    /// How a blade is shaded (docs/design.md "Grass blade shading"). Default
    /// [`BladeShading::default`]; [`BladeShading::FLAT`] is the flat colour × Lambert of before.
    pub shading: BladeShading,
    /// Views one renderer draws in one frame, each with its own uniforms and culling
    /// ([`BladeRenderer::prepare_view`], [`BladeRenderer::render_view`]), in
    /// 1..=[`crate::RenderSettings::MAX_VIEWS`]. Default 1.
    pub views: u32,
}

impl BladeRenderSettings {
    /// These settings with `options`' blade key (`blade_shading`) applied where it is given.
    pub fn with_options(mut self, options: &furbake_runtime::RenderOptions) -> BladeRenderSettings {
        if let Some(on) = options.blade_shading {
            self.shading.enabled = on;
        }
        self
    }

    /// The colour the ground under these blades is drawn in — the fur renderer's tint for a pack
    /// with a blade field whose host set none (docs/design.md "Grass blade shading"): the root
    /// colour, half as dark as the root occlusion makes the blades' bases, so gaps between
    /// blades show grass-coloured ground rather than the mesh's own (often white or grey)
    /// vertex colours.
    pub fn ground_tint(&self) -> [f32; 3] {
        let dim = if self.shading.enabled { 1.0 - 0.5 * self.shading.root_occlusion } else { 1.0 };
        self.color.map(|c| c * dim)
    }
}

impl Default for BladeRenderSettings {
    fn default() -> Self {
        BladeRenderSettings {
            interpolation: PoseInterpolation::Nearest,
            color: [0.18, 0.45, 0.08],
            lambert: true,
            culling: GrassCulling::default(),
            shading: BladeShading::default(),
            views: 1,
        }
    }
}

/// The blade shading of the grass thesis's fig. 4.1 pipeline and of shipped grass
/// (docs/design.md "Grass blade shading"): a root-to-tip colour, v-coordinate shadowing towards
/// the root, edge darkening across the width, normals rounded across the width, per-blade and
/// per-clump colour variation from the bake's seed, two-sided translucency and a gloss that rises
/// towards the tip. Every amount is in `0..=1` except `gloss_exponent` (`1..=512`); the colour is
/// linear RGB, finite and non-negative.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BladeShading {
    /// Off: the flat colour × two-sided Lambert (every other field ignored). Default true.
    pub enabled: bool,
    /// Linear RGB colour at the tip; the root takes [`BladeRenderSettings::color`]. Default a lighter,
    /// yellower green `[0.36, 0.58, 0.12]`.
    pub tip_color: [f32; 3],
    /// How much darker the root is than the tip (grass thesis fig. 4.1's v-shadowing: the
    /// blades around shade it): brightness `1 − root_occlusion` at the root rising to 1 at the
    /// tip. Default 0.65.
    pub root_occlusion: f32,
    /// Brightness spread between blades (± half of it). Default 0.3.
    pub blade_variation: f32,
    /// How far a clump (a cluster of the blade field) may turn towards a dry, yellower green.
    /// Default 0.5.
    pub clump_variation: f32,
    /// Light through a blade lit from behind (two-sided translucency), relative to the direct
    /// diffuse term. Default 0.8.
    pub translucency: f32,
    /// Strength of the normalised Blinn–Phong gloss, reached at the tip (none at the root).
    /// Default 0.2.
    pub gloss: f32,
    /// Exponent of the gloss lobe. Default 32.
    pub gloss_exponent: f32,
    /// How far normals turn outwards towards the blade's edges (a blade is rounded across its
    /// width, not flat). Default 0.6.
    pub rounding: f32,
    /// Darkening at the blade's edges (fig. 4.1's alpha × diffuse). Default 0.35.
    pub edge_darkening: f32,
}

impl Default for BladeShading {
    fn default() -> Self {
        BladeShading {
            enabled: true,
            tip_color: [0.36, 0.58, 0.12],
            root_occlusion: 0.65,
            blade_variation: 0.3,
            clump_variation: 0.5,
            translucency: 0.8,
            gloss: 0.2,
            gloss_exponent: 32.0,
            rounding: 0.6,
            edge_darkening: 0.35,
        }
    }
}

impl BladeShading {
    /// The flat colour × two-sided Lambert shading of before (every term off).
    pub const FLAT: BladeShading = BladeShading {
        enabled: false,
        tip_color: [0.0; 3],
        root_occlusion: 0.0,
        blade_variation: 0.0,
        clump_variation: 0.0,
        translucency: 0.0,
        gloss: 0.0,
        gloss_exponent: 1.0,
        rounding: 0.0,
        edge_darkening: 0.0,
    };

    /// Checks every range; the error names the field.
    pub fn validate(&self) -> Result<(), RenderError> {
        let bad = |what: String| Err(RenderError::Parameter { what });
        if self.tip_color.iter().any(|c| !c.is_finite() || *c < 0.0) {
            return bad(format!("blade shading tip_color {:?} must be finite and non-negative", self.tip_color));
        }
        for (name, v) in [
            ("root_occlusion", self.root_occlusion),
            ("blade_variation", self.blade_variation),
            ("clump_variation", self.clump_variation),
            ("translucency", self.translucency),
            ("gloss", self.gloss),
            ("rounding", self.rounding),
            ("edge_darkening", self.edge_darkening),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(format!("blade shading {name} = {v} is outside 0..=1"));
            }
        }
        if !(1.0..=512.0).contains(&self.gloss_exponent) {
            return bad(format!("blade shading gloss_exponent = {} is outside 1..=512", self.gloss_exponent));
        }
        Ok(())
    }
}

/// One blade field with its keyframe table on the GPU.
pub struct BladeRenderer {
    params: BladeUniforms,
    /// The roots' bounding sphere and the largest height scale ([`root_bounds`]).
    bounds: ([f32; 3], f32, f32),
    blade_count: u32,
    vertex_count: u32,
    corner_count: u32,
    /// The levels of detail (index lists, reach of any pose).
    lods: std::sync::Arc<BladeLods>,
    /// Culling and level of detail; off: one instanced draw of every blade at full detail.
    culling: GrassCulling,
    /// This renderer's own buffers (uniforms, forces, delayed sources, culling state).
    own: InstanceBuffers,
    /// `BladeUniforms::delayed_sources` as last uploaded.
    delayed_count: std::sync::atomic::AtomicU32,
    grid: furbake_formats::sections::blade_field::ClusterGrid,
    #[cfg(feature = "testing")]
    /// Positions buffer and its compute bind group, created by the first compute pass.
    positions: std::sync::OnceLock<(wgpu::Buffer, wgpu::BindGroup)>,
    out_layout: wgpu::BindGroupLayout,
    indices: wgpu::Buffer,
    /// The field's and table's static buffers (blades, keyframe payload, vertex map, reference
    /// blade, cluster bounds), shared with every other instance of the same field
    /// ([`BladeRenderer::instance`]).
    data: BladeData,
    /// Per view: the draw's bind group and the culling passes' bind group.
    groups: Vec<(wgpu::BindGroup, wgpu::BindGroup)>,
    /// Per view: the occlusion test's parameters (`CullUniforms::occlusion`) while a depth
    /// pyramid is bound ([`BladeRenderer::set_occlusion`]).
    occlusion: Vec<Option<[u32; 4]>>,
    compute_pipeline: wgpu::ComputePipeline,
    /// `cs_cull_clusters`, `cs_cull_blades`, `cs_scan_blocks`, `cs_compact`, `cs_pose_all`.
    cull_pipelines: [wgpu::ComputePipeline; 5],
    /// The pass this renderer draws into.
    target: TargetDesc,
    draw_pipeline: wgpu::RenderPipeline,
}

/// The frame uniforms and the culling parameters in one uniform buffer, so a frame uploads both
/// with one `queue.write_buffer`: the culling parameters at byte 512, a multiple of 256 (the
/// largest uniform binding offset alignment a device may require) past the frame uniforms.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameAndCull {
    frame: FrameUniforms,
    pad: [f32; CULL_PAD],
    cull: CullUniforms,
}

/// Byte offset of [`FrameAndCull::cull`].
const CULL_OFFSET: u64 = 512;
const CULL_PAD: usize = (CULL_OFFSET as usize - std::mem::size_of::<FrameUniforms>()) / 4;
const _: () = assert!(std::mem::offset_of!(FrameAndCull, cull) == CULL_OFFSET as usize);

/// One blade renderer's own buffers: frame uniforms, parameters, corner forces, the delayed
/// wind sources with their per-corner directions, and the culling passes' parameters, decisions,
/// work (indirect draw arguments and block counts) and instance lists.
struct InstanceBuffers {
    /// One per view ([`BladeRenderSettings::views`]): what the camera decides.
    views: Vec<ViewBuffers>,
    params: wgpu::Buffer,
    forces: wgpu::Buffer,
    delayed: wgpu::Buffer,
    directions: wgpu::Buffer,
    delayed_capacity: u32,
    /// The device's `max_compute_workgroups_per_dimension`.
    max_groups: u32,
}

/// A blade renderer's buffers for one view: the frame uniforms with the culling parameters
/// ([`FrameAndCull`]: bound as the frame uniforms, binding 0, and the culling parameters), and
/// the culling passes' decisions, work (indirect draw arguments and block counts) and instance
/// lists.
struct ViewBuffers {
    frame: wgpu::Buffer,
    decisions: wgpu::Buffer,
    work: wgpu::Buffer,
    instances: wgpu::Buffer,
}

/// Sizes of the culling buffers, bytes: decisions, work, instances.
fn cull_buffer_bytes(blades: u64, clusters: u64) -> [u64; 3] {
    let blocks = blades.div_ceil(BLOCK as u64);
    [(clusters + blades).max(1) * 4, (BLOCKS_AT + 4 * blocks) * 4, (LISTS_AT + 3 * blades) * 4]
}

impl InstanceBuffers {
    fn new(
        device: &wgpu::Device,
        params: &BladeUniforms,
        corners: usize,
        cull: &CullUniforms,
        views: u32,
    ) -> InstanceBuffers {
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let limits = device.limits();
        let params = init(
            "furbake blade params",
            bytemuck::bytes_of(params),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        // Room for the delayed sources' per-corner directions (at least one source's worth).
        let per_source = corners.max(1) as u64 * 8;
        let delayed_capacity =
            (limits.max_storage_buffer_binding_size / per_source).clamp(1, MAX_DELAYED_SOURCES as u64) as u32;
        let delayed = init(
            "furbake delayed wind sources",
            bytemuck::cast_slice(&vec![DelayedSourceGpu::default(); delayed_capacity as usize]),
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let directions = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake delayed wind directions"),
            size: per_source * delayed_capacity as u64,
            usage: storage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Storage bindings cannot be empty: one zero force stands in for a grid without corners.
        let forces = init(
            "furbake corner forces",
            bytemuck::cast_slice(&vec![[0.0f32; 2]; corners.max(1)]),
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let [decisions, work, instances] = cull_buffer_bytes(cull.counts[0] as u64, cull.counts[1] as u64);
        let buffer = |label, size, usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
        };
        let copy = wgpu::BufferUsages::COPY_SRC;
        let view = || ViewBuffers {
            frame: init(
                "furbake blade frame uniforms",
                bytemuck::bytes_of(&FrameAndCull {
                    frame: FrameUniforms::default(),
                    pad: [0.0; CULL_PAD],
                    cull: *cull,
                }),
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            decisions: buffer("furbake blade culling decisions", decisions, storage | copy),
            work: buffer("furbake blade culling work", work, storage | wgpu::BufferUsages::INDIRECT | copy),
            instances: buffer("furbake blade instance lists", instances, storage | copy),
        };
        InstanceBuffers {
            views: (0..views.max(1)).map(|_| view()).collect(),
            params,
            forces,
            delayed,
            directions,
            delayed_capacity,
            max_groups: limits.max_compute_workgroups_per_dimension,
        }
    }

    /// The frame uniforms' part of [`ViewBuffers::frame`].
    fn frame_binding(view: &ViewBuffers) -> wgpu::BindingResource<'_> {
        let size = wgpu::BufferSize::new(std::mem::size_of::<FrameUniforms>() as u64);
        wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: &view.frame, offset: 0, size })
    }

    /// The culling parameters' part of [`InstanceBuffers::frame`].
    fn cull_binding(view: &ViewBuffers) -> wgpu::BindingResource<'_> {
        let size = wgpu::BufferSize::new(std::mem::size_of::<CullUniforms>() as u64);
        wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: &view.frame, offset: CULL_OFFSET, size })
    }

    /// Each view's draw and culling bind groups.
    fn view_groups(&self, pipelines: &PipelineCache, data: &BladeData) -> Vec<(wgpu::BindGroup, wgpu::BindGroup)> {
        self.views
            .iter()
            .map(|v| (self.bind_group(pipelines, data, v), self.cull_group(pipelines, data, v, &data.no_pyramid)))
            .collect()
    }

    /// The draw's bind group: these buffers and the field's shared ones.
    fn bind_group(&self, pipelines: &PipelineCache, data: &BladeData, view: &ViewBuffers) -> wgpu::BindGroup {
        pipelines.device().create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake blade shared"),
            layout: &pipelines.blade_layouts().shared,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: Self::frame_binding(view) },
                wgpu::BindGroupEntry { binding: 1, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: data.blades.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: self.forces.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: data.payload.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: data.map.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: data.reference.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: self.delayed.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: self.directions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: Self::cull_binding(view) },
                wgpu::BindGroupEntry { binding: 10, resource: view.instances.as_entire_binding() },
            ],
        })
    }

    /// The culling passes' bind group, testing against `pyramid` (`BladeData::no_pyramid`: none).
    fn cull_group(
        &self,
        pipelines: &PipelineCache,
        data: &BladeData,
        view: &ViewBuffers,
        pyramid: &wgpu::TextureView,
    ) -> wgpu::BindGroup {
        pipelines.device().create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake blade culling"),
            layout: &pipelines.blade_layouts().cull,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: Self::cull_binding(view) },
                wgpu::BindGroupEntry { binding: 1, resource: data.blades.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: data.cluster_bounds.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: view.decisions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: view.work.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: view.instances.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: self.forces.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: self.delayed.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: self.directions.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 10, resource: wgpu::BindingResource::TextureView(pyramid) },
            ],
        })
    }
}

/// A blade field's static GPU buffers (cheap to clone: wgpu buffers are reference-counted).
#[derive(Clone)]
struct BladeData {
    blades: wgpu::Buffer,
    payload: wgpu::Buffer,
    map: wgpu::Buffer,
    reference: wgpu::Buffer,
    /// Per cluster: root bounds and tallest height scale (`culling::cluster_bounds`).
    cluster_bounds: wgpu::Buffer,
    /// A 1 × 1 `R32Float` texture bound where a view has no depth pyramid (never read: the
    /// occlusion test is off).
    no_pyramid: wgpu::TextureView,
}

/// The payload packed into u32 words (little-endian lanes) and its shader encoding code.
fn pack_payload(d: &Displacements) -> (Vec<u32>, u32) {
    fn words<T: Copy, const N: usize>(values: &[T], bits: impl Fn(T) -> u32) -> Vec<u32> {
        let lane = 32 / N as u32;
        values
            .chunks(N)
            .map(|c| c.iter().enumerate().fold(0u32, |w, (k, &v)| w | bits(v) << (lane * k as u32)))
            .collect()
    }
    match d {
        Displacements::F32(v) => (v.iter().map(|x| x.to_bits()).collect(), 0),
        Displacements::Snorm16 { values, .. } => (words::<i16, 2>(values, |q| q as u16 as u32), 1),
        Displacements::F16(v) => (words::<u16, 2>(v, |b| b as u32), 2),
        Displacements::Unorm8 { values, .. } => (words::<u8, 4>(values, |q| q as u32), 3),
        Displacements::Snorm8 { values, .. } => (words::<i8, 4>(values, |q| q as u8 as u32), 4),
    }
}

/// The blade roots' bounding sphere (the root box's centre and half-diagonal) and the largest
/// height scale; [`BladeRenderer::bounding_sphere`] grows it by the reach of any pose.
fn root_bounds(field: &BladeField) -> ([f32; 3], f32, f32) {
    let (mut lo, mut hi) = (glam::Vec3::splat(f32::INFINITY), glam::Vec3::splat(f32::NEG_INFINITY));
    for p in &field.positions {
        lo = lo.min(glam::Vec3::from(*p));
        hi = hi.max(glam::Vec3::from(*p));
    }
    if field.positions.is_empty() || !(lo.is_finite() && hi.is_finite()) {
        return ([0.0; 3], 1.0, 0.0);
    }
    let h = field.height_scale.iter().copied().filter(|h| h.is_finite()).fold(0.0f32, f32::max);
    (((lo + hi) * 0.5).to_array(), (hi - lo).length() * 0.5, h)
}

fn check_culling(culling: &GrassCulling) -> Result<(), RenderError> {
    culling.validate().map_err(|(field, what)| RenderError::Parameter { what: format!("{field}: {what}") })
}

fn invalid(what: String) -> RenderError {
    RenderError::InvalidAsset { what }
}

impl BladeRenderer {
    /// Uploads `field` and `table` and takes the compute pipeline and the draw pipeline for passes
    /// like `target` from `pipelines` (created there on first use, shared). Fails on an
    /// inconsistent table or field (counts, symmetry, out-of-range indices), on spherical
    /// interpolation, on a target this device cannot draw into
    /// ([`RenderError::UnsupportedTarget`]), and when the blade instances, payload or corner
    /// forces are above the device's storage binding limit.
    pub fn new(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        field: &BladeField,
        table: &KeyframeTable,
        settings: &BladeRenderSettings,
        target: &TargetDesc,
    ) -> Result<BladeRenderer, RenderError> {
        let draw_pipeline = pipelines.blades(target)?;
        crate::gpu_scope(pipelines.device(), "creating the blade renderer", || {
            Self::build(pipelines, queue, field, table, settings, target, draw_pipeline)
        })
    }

    fn build(
        pipelines: &PipelineCache,
        _queue: &wgpu::Queue,
        field: &BladeField,
        table: &KeyframeTable,
        settings: &BladeRenderSettings,
        target: &TargetDesc,
        draw_pipeline: wgpu::RenderPipeline,
    ) -> Result<BladeRenderer, RenderError> {
        let device = pipelines.device();
        let interpolation = match settings.interpolation {
            PoseInterpolation::Nearest => 0,
            PoseInterpolation::Linear => 1,
            PoseInterpolation::Spherical => {
                return Err(RenderError::Parameter {
                    what: "spherical blade interpolation is CPU-only; use nearest or linear".into(),
                });
            }
        };
        if settings.color.iter().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(RenderError::Parameter { what: "blade colour must be finite and non-negative".into() });
        }
        check_culling(&settings.culling)?;
        settings.shading.validate()?;
        crate::renderer::check_view_count(settings.views, "BladeRenderSettings::views")?;
        // The checks of `KeyframeDecoder::new`, so a hand-built table cannot index out of range.
        let g = table.grid;
        let factor = table.symmetry.factor();
        if g.magnitudes == 0
            || g.angles == 0
            || !g.angles.is_multiple_of(factor)
            || g.max_force.is_nan()
            || g.max_force <= 0.0
        {
            return Err(invalid(format!("pose grid {g:?} does not fit symmetry {}", table.symmetry.name())));
        }
        let sv = table.stored_vectors as u64;
        let expected = table.stored_poses() * sv * 3;
        if table.displacements.len() as u64 != expected {
            return Err(invalid(format!("{} displacement components, expected {expected}", table.displacements.len())));
        }
        let vertex_count = table.vertex_count();
        if table.vertex_map.len() != vertex_count
            || table.vertex_map.iter().any(|&m| m != STATIC_VERTEX && m as u64 >= sv)
        {
            return Err(invalid("vertex_map does not fit the reference blade and stored vectors".into()));
        }
        if table.triangles.iter().flatten().any(|&i| i as usize >= vertex_count) {
            return Err(invalid("a blade triangle indexes past the reference vertices".into()));
        }
        let n = field.blade_count();
        let lens = [field.positions.len(), field.yaw_rad.len(), field.height_scale.len(), field.cluster.len()];
        if lens.iter().chain([&field.weights.len()]).any(|&l| l != n) {
            return Err(invalid(format!(
                "blade field arrays have different lengths ({lens:?}, {} weights)",
                field.weights.len()
            )));
        }
        let corners = field.grid.corners();
        let blades: Vec<BladeGpu> = (0..field.blade_count())
            .map(|b| {
                let [x, y, z] = field.positions[b];
                let (s, c) = field.yaw_rad[b].sin_cos();
                let cluster = field.cluster[b];
                if cluster as usize >= field.grid.clusters() {
                    return Err(invalid(format!("blade {b} is in cluster {cluster}, past the grid")));
                }
                Ok(BladeGpu {
                    root: [x, y, z, field.height_scale[b]],
                    yaw: [c, s],
                    cluster,
                    pad: 0,
                    weights: field.weights[b],
                })
            })
            .collect::<Result<_, _>>()?;

        let limits = device.limits();
        for (what, value) in [
            ("blade instance bytes", blades.len() as u64 * std::mem::size_of::<BladeGpu>() as u64),
            ("displacement payload bytes", expected * 4),
            ("corner force bytes", corners as u64 * 8),
            ("blade instance list bytes", cull_buffer_bytes(blades.len() as u64, field.grid.clusters() as u64)[2]),
        ] {
            let limit = limits.max_storage_buffer_binding_size;
            if value > limit {
                return Err(RenderError::Limit { what, value, limit });
            }
        }
        let groups = (blades.len() as u32).div_ceil(WORKGROUP);
        if groups.div_ceil(limits.max_compute_workgroups_per_dimension) > limits.max_compute_workgroups_per_dimension {
            return Err(RenderError::Limit {
                what: "blade workgroups",
                value: groups as u64,
                limit: limits.max_compute_workgroups_per_dimension as u64
                    * limits.max_compute_workgroups_per_dimension as u64,
            });
        }

        let (payload, encoding) = pack_payload(&table.displacements);
        let [r, gr, b] = settings.color;
        let sh = &settings.shading;
        let params = BladeUniforms {
            color: [r, gr, b, 1.0],
            blade_count: blades.len() as u32,
            vertex_count: vertex_count as u32,
            stored_vectors: table.stored_vectors,
            stored_angles: g.stored_angles(table.symmetry),
            magnitudes: g.magnitudes,
            angles: g.angles,
            mirror_x: table.symmetry.mirrors_x() as u32,
            mirror_z: table.symmetry.mirrors_z() as u32,
            // The same f32 expressions as `KeyframeDecoder::new`.
            magnitude_per_force: g.magnitudes as f32 / g.max_force,
            angle_per_radian: g.angles as f32 / std::f32::consts::TAU,
            scale: table.displacements.scale(),
            encoding,
            interpolation,
            lambert: settings.lambert as u32,
            delayed_sources: 0,
            corner_count: corners as u32,
            cells_x: field.grid.cells_x,
            seed: (field.params.seed ^ (field.params.seed >> 32)) as u32,
            shading: settings.shading.enabled as u32,
            pad: 0,
            tip_color: [sh.tip_color[0], sh.tip_color[1], sh.tip_color[2], 1.0],
            shade: [sh.root_occlusion, sh.blade_variation, sh.clump_variation, sh.translucency],
            gloss: [sh.gloss, sh.gloss_exponent, sh.rounding, sh.edge_darkening],
        };
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        // Storage bindings cannot be empty: a zero-filled placeholder stands in (never read).
        fn nonempty<T: bytemuck::Pod + Default>(v: Vec<T>) -> Vec<T> {
            if v.is_empty() { vec![T::default()] } else { v }
        }
        let storage = wgpu::BufferUsages::STORAGE;
        let data = BladeData {
            blades: init("furbake blades", bytemuck::cast_slice(&nonempty(blades)), storage),
            payload: init("furbake keyframe payload", bytemuck::cast_slice(&nonempty(payload)), storage),
            map: init(
                "furbake keyframe vertex map",
                bytemuck::cast_slice(&nonempty(table.vertex_map.clone())),
                storage,
            ),
            reference: {
                let reference: Vec<[f32; 4]> =
                    table.reference_positions.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
                init("furbake reference blade", bytemuck::cast_slice(&nonempty(reference)), storage)
            },
            cluster_bounds: init(
                "furbake blade cluster bounds",
                bytemuck::cast_slice(&crate::culling::cluster_bounds(field)),
                storage,
            ),
            no_pyramid: device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some("furbake no depth pyramid"),
                    size: wgpu::Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: wgpu::TextureDimension::D2,
                    format: wgpu::TextureFormat::R32Float,
                    usage: wgpu::TextureUsages::TEXTURE_BINDING,
                    view_formats: &[],
                })
                .create_view(&Default::default()),
        };
        let lods = std::sync::Arc::new(BladeLods::new(table));
        let indices = init(
            "furbake blade triangles",
            bytemuck::cast_slice(&nonempty(lods.indices.clone())),
            wgpu::BufferUsages::INDEX,
        );
        let clusters = field.grid.clusters() as u32;
        let cull = CullUniforms::new(&FrameUniforms::default(), &settings.culling, &lods, params.blade_count, clusters);
        let own = InstanceBuffers::new(device, &params, corners, &cull, settings.views);
        let groups = own.view_groups(pipelines, &data);
        Ok(BladeRenderer {
            params,
            bounds: root_bounds(field),
            blade_count: params.blade_count,
            vertex_count: vertex_count as u32,
            corner_count: corners as u32,
            lods,
            culling: settings.culling,
            own,
            delayed_count: std::sync::atomic::AtomicU32::new(0),
            grid: field.grid,
            #[cfg(feature = "testing")]
            positions: std::sync::OnceLock::new(),
            out_layout: pipelines.blade_layouts().out.clone(),
            indices,
            data,
            occlusion: vec![None; groups.len()],
            groups,
            // One per cache, independent of the target.
            compute_pipeline: pipelines.blade_compute()?,
            cull_pipelines: pipelines.blade_cull()?,
            target: target.clone(),
            draw_pipeline,
        })
    }

    /// Another renderer of the same blade field, settings and target that shares this one's
    /// static buffers (blades, keyframe payload, vertex map, reference blade, triangles) and owns
    /// only what differs per placement — uniforms, corner forces, wind-source directions: a scene
    /// that places one grass pack many times uploads its field once.
    pub fn instance(&self, pipelines: &PipelineCache) -> Result<BladeRenderer, RenderError> {
        let device = pipelines.device();
        crate::gpu_scope(device, "creating a blade renderer instance", || {
            let cull = self.cull_params(&FrameUniforms::default());
            let own = InstanceBuffers::new(
                device,
                &self.params,
                self.corner_count as usize,
                &cull,
                self.own.views.len() as u32,
            );
            let groups = own.view_groups(pipelines, &self.data);
            Ok(BladeRenderer {
                params: self.params,
                bounds: self.bounds,
                blade_count: self.blade_count,
                vertex_count: self.vertex_count,
                corner_count: self.corner_count,
                lods: self.lods.clone(),
                culling: self.culling,
                own,
                delayed_count: std::sync::atomic::AtomicU32::new(0),
                grid: self.grid,
                #[cfg(feature = "testing")]
                positions: std::sync::OnceLock::new(),
                out_layout: self.out_layout.clone(),
                indices: self.indices.clone(),
                data: self.data.clone(),
                occlusion: vec![None; groups.len()],
                groups,
                compute_pipeline: self.compute_pipeline.clone(),
                cull_pipelines: self.cull_pipelines.clone(),
                target: self.target.clone(),
                draw_pipeline: self.draw_pipeline.clone(),
            })
        })
    }

    #[cfg(feature = "testing")]
    /// True when `other` draws from the same uploaded blade field as this renderer.
    pub fn shares_data_with(&self, other: &BladeRenderer) -> bool {
        self.data.blades == other.data.blades
    }

    /// Reads the pack's first blade field and keyframe table and uploads them ([`BladeRenderer::new`]);
    /// `Ok(None)` when the pack has no blade field. A blade field without a keyframe table is an
    /// [`RenderError::Runtime`] (missing section).
    pub fn from_pack(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        pack: &furbake_formats::Pack,
        settings: &BladeRenderSettings,
        target: &TargetDesc,
    ) -> Result<Option<BladeRenderer>, RenderError> {
        let Some(field) = pack.optional_section::<BladeField>()? else { return Ok(None) };
        let table = pack.section::<KeyframeTable>()?;
        let sections =
            furbake_formats::PackSections { blade_fields: &[&field], keyframe_tables: &[&table], ..Default::default() };
        furbake_formats::check_consistency(pack.sections(), &sections)
            .map_err(|e| e.with_path(&pack.display_path()))?;
        BladeRenderer::new(pipelines, queue, &field, &table, settings, target).map(Some)
    }

    /// Bytes of GPU memory a renderer of `field` and `table` allocates for its data (blade
    /// instances, the displacement payload, corner forces and delayed-source directions), not
    /// counting its fixed cost (1 MiB, `RENDERER_OVERHEAD_BYTES`) nor the positions buffer a
    /// compute readback adds.
    pub fn gpu_bytes(field: &BladeField, table: &KeyframeTable) -> u64 {
        Self::shared_gpu_bytes(field, table) + Self::instance_gpu_bytes(field)
    }

    /// The part of [`BladeRenderer::gpu_bytes`] every [`BladeRenderer::instance`] of one field
    /// shares: the blades, the keyframe payload and the cluster bounds.
    pub fn shared_gpu_bytes(field: &BladeField, table: &KeyframeTable) -> u64 {
        field.blade_count() as u64 * std::mem::size_of::<BladeGpu>() as u64
            + table.stored_poses() * table.stored_vectors as u64 * 3 * 4
            + field.grid.clusters() as u64 * 32
    }

    /// The part of [`BladeRenderer::gpu_bytes`] each instance holds of its own: corner forces,
    /// the delayed wind sources' per-corner directions and the culling passes' decisions, block
    /// counts and instance lists (8 bytes per blade).
    pub fn instance_gpu_bytes(field: &BladeField) -> u64 {
        let corners = field.grid.corners() as u64;
        let culling: u64 = cull_buffer_bytes(field.blade_count() as u64, field.grid.clusters() as u64).iter().sum();
        corners * 8 + corners * 8 * MAX_DELAYED_SOURCES as u64 + culling
    }

    /// Centre and radius (metres) of a sphere holding every blade in any pose (roots grown by the
    /// tallest blade's reference extent), for [`crate::View::framing`] and the near/far planes.
    pub fn bounding_sphere(&self) -> ([f32; 3], f32) {
        let (center, radius, h) = self.bounds;
        let widening = if self.culling.enabled { 1.0 / self.culling.min_density - 1.0 } else { 0.0 };
        (center, (radius + (self.lods.reach + widening * self.lods.half_width) * h).max(1e-3))
    }

    /// Number of blades.
    pub fn blade_count(&self) -> u32 {
        self.blade_count
    }

    /// Cluster grid corners (the length [`BladeRenderer::set_corner_forces`] expects).
    pub fn corner_count(&self) -> u32 {
        self.corner_count
    }

    /// Vertices per blade.
    pub fn vertex_count(&self) -> u32 {
        self.vertex_count
    }

    #[cfg(feature = "testing")]
    /// The uniforms the shaders receive.
    pub fn params(&self) -> &BladeUniforms {
        &self.params
    }

    /// Writes this frame's cluster corner forces `(x, z)` (one per grid corner, force units, in
    /// the pack frame) and turns delayed-attenuation sources off for the frame.
    pub fn set_corner_forces(&self, queue: &wgpu::Queue, forces: &[[f32; 2]]) -> Result<(), RenderError> {
        self.check_corner_forces(forces.iter().copied())?;
        self.write_forces(&mut Upload::Queue(queue), BladeForces::Corners(forces))
    }

    /// Writes `BladeUniforms::delayed_sources` when it changes (most frames it stays 0: one upload
    /// fewer per frame).
    /// (Every frame when the frame's writes are collected: see [`Upload::collected`].)
    fn write_delayed_count(&self, upload: &mut Upload<'_>, count: u32) {
        if self.delayed_count.swap(count, std::sync::atomic::Ordering::Relaxed) == count && !upload.collected() {
            return;
        }
        let offset = std::mem::offset_of!(BladeUniforms, delayed_sources) as u64;
        upload.write(&self.own.params, offset, bytemuck::bytes_of(&count));
    }

    /// Most delayed-attenuation sources [`BladeRenderer::set_force_scene`] accepts on this device.
    pub fn delayed_capacity(&self) -> u32 {
        self.own.delayed_capacity
    }

    /// Writes the forces of `scene` on this blade field: `field`'s corner forces (it must have
    /// been updated from `scene` with `ForceField::update` over this renderer's grid) plus the
    /// scene's wind sources with delayed attenuation (grass thesis §4.5, fig. 4.8), whose per-corner
    /// directions are computed here as `ForceField::update` does (unit horizontal direction from
    /// the source to the corner at `scene.sample_height_m`, zero inside a windless area) and whose
    /// attenuation the shaders evaluate per blade: the GPU then matches `ForceField::blade_force`.
    /// Fails on a grid mismatch or more delayed sources than [`BladeRenderer::delayed_capacity`].
    pub fn set_force_scene(
        &self,
        queue: &wgpu::Queue,
        field: &ForceField,
        scene: &furbake_grass::ForceScene,
    ) -> Result<(), RenderError> {
        self.check_forces(BladeForces::Scene { field, scene })?;
        self.write_forces(&mut Upload::Queue(queue), BladeForces::Scene { field, scene })
    }

    /// Writes the corner forces of `field` (its `corner_forces`) with no delayed-attenuation
    /// sources; a field with delayed sources needs [`BladeRenderer::set_force_scene`].
    pub fn set_force_field(&self, queue: &wgpu::Queue, field: &ForceField) -> Result<(), RenderError> {
        self.check_forces(BladeForces::Field(field))?;
        self.write_forces(&mut Upload::Queue(queue), BladeForces::Field(field))
    }

    /// The checks of [`BladeRenderer::set_corner_forces`], [`BladeRenderer::set_force_field`] and
    /// [`BladeRenderer::set_force_scene`].
    pub(crate) fn check_forces(&self, forces: BladeForces<'_>) -> Result<(), RenderError> {
        match forces {
            BladeForces::Corners(f) => self.check_corner_forces(f.iter().copied()),
            BladeForces::Field(field) => self.check_corner_forces(field.corner_forces.iter().map(|f| f.to_array())),
            BladeForces::Scene { field, scene } => {
                if *field.grid() != self.grid {
                    return Err(RenderError::Parameter {
                        what: "the force field's grid is not the blade field's".into(),
                    });
                }
                let delayed = scene.sources.iter().filter(|s| s.delayed);
                if delayed.clone().count() > self.own.delayed_capacity as usize {
                    return Err(RenderError::Parameter {
                        what: format!(
                            "{} delayed wind sources, at most {} on this device",
                            delayed.count(),
                            self.own.delayed_capacity
                        ),
                    });
                }
                let bad = |v: &[f32]| v.iter().any(|c| !c.is_finite());
                if delayed.clone().any(|s| bad(&s.position_m.to_array()) || bad(&[s.power, s.falloff_exponent]))
                    || bad(&[scene.sample_height_m, scene.min_distance_m])
                {
                    return Err(RenderError::Parameter { what: "delayed wind sources must be finite".into() });
                }
                self.check_corner_forces(field.corner_forces.iter().map(|f| f.to_array()))
            }
        }
    }

    /// Writes checked forces ([`BladeRenderer::check_forces`]) through `upload`: the corner
    /// forces, and for a scene its delayed-attenuation sources with their per-corner directions
    /// (computed as `ForceField::update` does: unit horizontal direction from the source to the
    /// corner at `scene.sample_height_m`, zero inside a windless area), straight into the staging
    /// memory.
    pub(crate) fn write_forces(&self, upload: &mut Upload<'_>, forces: BladeForces<'_>) -> Result<(), RenderError> {
        let to_bytes = |f: [f32; 2]| bytemuck::cast::<[f32; 2], [u8; 8]>(f);
        match forces {
            BladeForces::Corners(f) => {
                upload.write_chunks(&self.own.forces, 0, f.iter().map(|&f| to_bytes(f)), "corner force")?;
                self.write_delayed_count(upload, 0);
            }
            BladeForces::Field(field) => {
                let f = field.corner_forces.iter().map(|f| to_bytes(f.to_array()));
                upload.write_chunks(&self.own.forces, 0, f, "corner force")?;
                self.write_delayed_count(upload, 0);
            }
            BladeForces::Scene { field, scene } => {
                let f = field.corner_forces.iter().map(|f| to_bytes(f.to_array()));
                upload.write_chunks(&self.own.forces, 0, f, "corner force")?;
                let delayed = scene.sources.iter().filter(|s| s.delayed);
                let count = delayed.clone().count();
                if count > 0 {
                    let sources = delayed.clone().map(|s| {
                        let w = s.position_m;
                        bytemuck::cast::<DelayedSourceGpu, [u8; DELAYED_SOURCE_BYTES]>(DelayedSourceGpu {
                            position_power: [w.x, w.y, w.z, s.power],
                            params: [s.falloff_exponent, scene.min_distance_m, 0.0, 0.0],
                        })
                    });
                    upload.write_chunks(&self.own.delayed, 0, ExactLen(sources, count), "delayed wind source")?;
                    let corners = self.corner_count as usize;
                    let directions = delayed.flat_map(|s| {
                        (0..corners).map(move |i| {
                            let [x, z] = self.grid.corner_position(i as u32);
                            let p = glam::Vec3::new(x, scene.sample_height_m, z);
                            let xz = glam::Vec2::new(p.x, p.z);
                            let d = if scene.blockers.iter().any(|b| b.contains(xz)) {
                                glam::Vec2::ZERO
                            } else {
                                let wp = p - s.position_m;
                                glam::Vec2::new(wp.x, wp.z).normalize_or_zero()
                            };
                            to_bytes(d.to_array())
                        })
                    });
                    upload.write_chunks(
                        &self.own.directions,
                        0,
                        ExactLen(directions, count * corners),
                        "wind direction",
                    )?;
                }
                self.write_delayed_count(upload, count as u32);
            }
        }
        Ok(())
    }

    /// Checks one `(x, z)` force per grid corner, all finite.
    fn check_corner_forces<I>(&self, forces: I) -> Result<(), RenderError>
    where
        I: ExactSizeIterator<Item = [f32; 2]> + Clone,
    {
        if forces.len() != self.corner_count as usize {
            return Err(RenderError::Parameter {
                what: format!("{} corner forces for {} grid corners", forces.len(), self.corner_count),
            });
        }
        if forces.flatten().any(|c| !c.is_finite()) {
            return Err(RenderError::Parameter { what: "corner forces must be finite".into() });
        }
        Ok(())
    }

    #[cfg(feature = "testing")]
    /// The positions buffer (`blades × vertices` `vec4<f32>`) and its bind group, created on first
    /// use; fails when it is above the device's storage binding limit.
    fn positions(&self, device: &wgpu::Device) -> Result<&(wgpu::Buffer, wgpu::BindGroup), RenderError> {
        if let Some(p) = self.positions.get() {
            return Ok(p);
        }
        let bytes = self.blade_count as u64 * self.vertex_count as u64 * 16;
        let limit = device.limits().max_storage_buffer_binding_size;
        if bytes > limit {
            return Err(RenderError::Limit { what: "blade positions bytes", value: bytes, limit });
        }
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("furbake blade positions"),
            size: bytes.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake blade positions out"),
            layout: &self.out_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: buffer.as_entire_binding() }],
        });
        Ok(self.positions.get_or_init(|| (buffer, group)))
    }

    #[cfg(feature = "testing")]
    /// Records the compute pass that poses every blade and writes its world-space vertices into
    /// the positions buffer (created on first use; `blades × vertices × 16` bytes, which must fit
    /// the device's storage binding limit — the draw does not need it).
    pub fn encode_compute(&self, encoder: &mut wgpu::CommandEncoder, device: &wgpu::Device) -> Result<(), RenderError> {
        let (_, out) = self.positions(device)?;
        if self.blade_count == 0 {
            return Ok(());
        }
        let groups = self.blade_count.div_ceil(WORKGROUP);
        let max = device.limits().max_compute_workgroups_per_dimension;
        // `new` checked that groups fit max × max.
        let (x, y) = if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("furbake blade poses"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.compute_pipeline);
        pass.set_bind_group(0, &self.groups[0].0, &[]);
        pass.set_bind_group(1, out, &[]);
        pass.dispatch_workgroups(x, y, 1);
        Ok(())
    }

    #[cfg(feature = "testing")]
    /// Poses every blade under the current corner forces and submits (see
    /// [`BladeRenderer::read_positions`]). For tests and tools; a host records
    /// [`BladeRenderer::encode_compute`] into its own encoder instead.
    pub fn compute(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<(), RenderError> {
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake blade poses") });
        self.encode_compute(&mut encoder, device)?;
        crate::blocking::submit(queue, [encoder.finish()]);
        Ok(())
    }

    /// The pass description this renderer's draw pipeline was built for.
    pub fn target(&self) -> &TargetDesc {
        &self.target
    }

    /// Whether the blades are shaded ([`BladeShading::enabled`]) or drawn flat.
    pub(crate) fn shading_enabled(&self) -> bool {
        self.params.shading != 0
    }

    /// This renderer's culling and level-of-detail settings.
    pub fn culling(&self) -> &GrassCulling {
        &self.culling
    }

    /// Changes the culling and level-of-detail settings from the next frame on (fails on a value
    /// out of range, see [`GrassCulling::validate`]). With culling switched off, writes the
    /// parameters the draw reads once here (`queue.write_buffer`), so frames upload nothing for it.
    pub fn set_culling(&mut self, queue: &wgpu::Queue, culling: GrassCulling) -> Result<(), RenderError> {
        check_culling(&culling)?;
        self.culling = culling;
        if !culling.enabled {
            let params = self.cull_params(&FrameUniforms::default());
            for view in &self.own.views {
                queue.write_buffer(&view.frame, CULL_OFFSET, bytemuck::bytes_of(&params));
            }
        }
        Ok(())
    }

    #[cfg(feature = "testing")]
    /// Levels of detail of this field's blade (index lists, segments per level, reach of any pose).
    pub fn lods(&self) -> &BladeLods {
        &self.lods
    }

    /// The culling parameters of `frame` (what [`BladeRenderer::prepare`] uploads).
    pub(crate) fn cull_params(&self, frame: &FrameUniforms) -> CullUniforms {
        CullUniforms::new(frame, &self.culling, &self.lods, self.blade_count, self.grid.clusters() as u32)
    }

    /// Writes `frame` (the host's view-projection, eye and light, and the field's model matrix,
    /// e.g. from [`crate::View::uniforms_with_model`] or [`FrameUniforms::new`]) into this
    /// renderer's uniform buffer with one `queue.write_buffer` (with culling on, together with the
    /// frame's culling parameters), and records one compute pass into `encoder`: with culling on,
    /// four dispatches (clusters, blades, block offsets, compaction into one instance list per
    /// level of detail with each drawn blade's pose-grid coordinates; `culling.rs`);
    /// off, one dispatch writing every blade's entry. Call once per frame before the host's render pass; one
    /// model matrix per renderer per submission. The model matrix moves the drawn blades only;
    /// `BladeRenderer::read_positions` (feature `testing`) stays in the pack frame. Does not submit, wait or
    /// allocate.
    pub fn prepare(&self, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder, frame: &FrameUniforms) {
        self.write_frame(&mut Upload::Queue(queue), 0, frame);
        self.record(encoder, 0);
    }

    /// Writes the uniforms of view `view` (1 ≤ `view` < [`BladeRenderSettings::views`]; view 0 is
    /// [`BladeRenderer::prepare`]'s) and records its culling passes into `encoder`, so that
    /// [`BladeRenderer::render_view`] draws this frame's blades from another camera before the
    /// host submits (each view keeps its own uniforms and instance lists). A view out of range is
    /// a [`RenderError::Parameter`]. Does not submit, wait or allocate.
    pub fn prepare_view(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        view: usize,
        frame: &FrameUniforms,
    ) -> Result<(), RenderError> {
        self.check_view(view)?;
        self.write_frame(&mut Upload::Queue(queue), view, frame);
        self.record(encoder, view);
        Ok(())
    }

    /// Tests view `view`'s blades against `pyramid` from now on (`None`: no occlusion test):
    /// blades whose bounds lie wholly behind its depth are not drawn. The pyramid must be built
    /// ([`DepthPyramid::record`]) from the depth of this view's camera, of the size of the pass
    /// the blades are drawn into, each frame after the host drew its occluders and before this
    /// view's [`BladeRenderer::prepare_view`] — so nothing visible this frame is culled, whatever
    /// moved since the last (docs/design.md "Occlusion culling"). Only with culling on; binds
    /// once (call again with a new pyramid after a resize), records nothing.
    pub fn set_occlusion(
        &mut self,
        pipelines: &PipelineCache,
        view: usize,
        pyramid: Option<&DepthPyramid>,
    ) -> Result<(), RenderError> {
        self.check_view(view)?;
        let texture_view;
        let (bound, params) = match pyramid {
            Some(p) => {
                let (w, h) = p.size();
                texture_view = p.texture().create_view(&Default::default());
                (&texture_view, Some([w, h, p.levels(), 1 | (p.reversed_depth() as u32) << 1]))
            }
            None => (&self.data.no_pyramid, None),
        };
        self.groups[view].1 = self.own.cull_group(pipelines, &self.data, &self.own.views[view], bound);
        self.occlusion[view] = params;
        Ok(())
    }

    fn check_view(&self, view: usize) -> Result<(), RenderError> {
        if view < self.groups.len() {
            return Ok(());
        }
        Err(crate::renderer::view_out_of_range(view, self.groups.len(), "BladeRenderSettings::views"))
    }

    /// The writes of [`BladeRenderer::prepare_view`]: view `view`'s uniforms (with culling on,
    /// together with the frame's culling parameters).
    pub(crate) fn write_frame(&self, upload: &mut Upload<'_>, view: usize, frame: &FrameUniforms) {
        let buffers = &self.own.views[view];
        if self.culling.enabled && !self.draws_nothing() {
            let mut cull = self.cull_params(frame);
            cull.occlusion = self.occlusion[view].unwrap_or_default();
            let both = FrameAndCull { frame: *frame, pad: [0.0; CULL_PAD], cull };
            upload.write(&buffers.frame, 0, bytemuck::bytes_of(&both));
        } else {
            // The culling parameters (culling off) were written by `new` or `set_culling`.
            upload.write(&buffers.frame, 0, bytemuck::bytes_of(frame));
        }
    }

    /// Whether there is nothing to pose or draw (no blades, or a blade without triangles).
    fn draws_nothing(&self) -> bool {
        self.blade_count == 0 || self.lods.index_count[0] == 0
    }

    /// The commands of [`BladeRenderer::prepare_view`], after its writes: view `view`'s culling
    /// (or posing) pass.
    pub(crate) fn record(&self, encoder: &mut wgpu::CommandEncoder, view: usize) {
        if self.draws_nothing() {
            return;
        }
        let max = self.own.max_groups;
        let grid = |groups: u32| if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) };
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("furbake blade culling"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.groups[view].1, &[]);
        let blocks = grid(self.blade_count.div_ceil(BLOCK));
        let [clusters, blades, scan, compact, pose_all] = &self.cull_pipelines;
        if self.culling.enabled {
            let dispatches = [
                (clusters, grid((self.grid.clusters() as u32).div_ceil(64))),
                (blades, blocks),
                (scan, (1, 1)),
                (compact, blocks),
            ];
            for (pipeline, (x, y)) in dispatches {
                pass.set_pipeline(pipeline);
                pass.dispatch_workgroups(x, y, 1);
            }
        } else {
            pass.set_pipeline(pose_all);
            pass.dispatch_workgroups(blocks.0, blocks.1, 1);
        }
    }

    /// Draws the blades into the host's `pass`, whose attachments must match
    /// [`BladeRenderer::target`]: with culling on, one `draw_indexed_indirect` per level of detail
    /// from the instance lists [`BladeRenderer::prepare`] recorded; off, every blade instanced at
    /// full detail. Sets its own pipeline, bind group 0 and index buffer. Does not submit, wait or
    /// allocate.
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.draw(pass, 0);
    }

    /// [`BladeRenderer::render`] from the instance lists [`BladeRenderer::prepare_view`] recorded
    /// for view `view`. A view out of range is a [`RenderError::Parameter`] and draws nothing.
    pub fn render_view(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) -> Result<(), RenderError> {
        self.check_view(view)?;
        self.draw(pass, view);
        Ok(())
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) {
        if self.draws_nothing() {
            return;
        }
        pass.set_pipeline(&self.draw_pipeline);
        pass.set_bind_group(0, &self.groups[view].0, &[]);
        pass.set_index_buffer(self.indices.slice(..), wgpu::IndexFormat::Uint32);
        if self.culling.enabled {
            for l in 0..self.lods.count as u64 {
                pass.draw_indexed_indirect(&self.own.views[view].work, l * 20);
            }
        } else {
            pass.draw_indexed(0..self.lods.index_count[0], 0, 0..self.blade_count);
        }
    }

    #[cfg(feature = "testing")]
    /// Reads back the instance lists of the last frame's culling passes and checks them against
    /// the indirect draw arguments (with culling off: LOD 0's list, every blade); waits for the
    /// GPU. For tests and tools.
    pub fn read_culling(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<CullLists, RenderError> {
        let read = |buffer, count, what| crate::blocking::read_buffer::<u32>(device, queue, buffer, count, what);
        let lists =
            read(&self.own.views[0].instances, LISTS_AT + 3 * self.blade_count as u64, "culling instance lists")?;
        let mut out = CullLists::default();
        if !self.culling.enabled {
            // Every blade, in LOD 0's list (`cs_pose_all`; the draw is not indirect).
            out.lods[0] = lists[LISTS_AT as usize..].chunks_exact(3).map(|e| e[0]).collect();
            return Ok(out);
        }
        let args = read(&self.own.views[0].work, 20, "culling draw arguments")?;
        for l in 0..MAX_LODS.min(self.lods.count as usize) {
            let start = lists[l] as usize;
            let count = args[5 * l + 1] as usize;
            let from = LISTS_AT as usize + 3 * start;
            let Some(list) = lists.get(from..from + 3 * count) else {
                return Err(RenderError::Gpu { what: format!("LOD {l}: {count} blades from {start} pass the list") });
            };
            if args[5 * l] != self.lods.index_count[l] || args[5 * l + 2] != self.lods.first_index[l] {
                return Err(RenderError::Gpu {
                    what: format!("LOD {l}: draw arguments {:?}", &args[5 * l..5 * l + 5]),
                });
            }
            out.lods[l] = list.chunks_exact(3).map(|e| e[0]).collect();
        }
        Ok(out)
    }

    #[cfg(feature = "testing")]
    /// Reads back how many blades the last frame's culling passes of view 0 found hidden behind
    /// the depth pyramid (their own bounds or their cluster's); waits for the GPU.
    pub fn read_occluded(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<u32, RenderError> {
        let clusters = self.grid.clusters() as u64;
        let decisions = crate::blocking::read_buffer::<u32>(
            device,
            queue,
            &self.own.views[0].decisions,
            clusters + self.blade_count as u64,
            "culling decisions",
        )?;
        Ok(decisions[clusters as usize..].iter().filter(|&&d| d == OCCLUDED).count() as u32)
    }

    #[cfg(feature = "testing")]
    /// Reads back the positions of the last compute pass: `blades × vertices` world positions in
    /// metres, blade-major (waits for the GPU).
    pub fn read_positions(&self, device: &wgpu::Device, queue: &wgpu::Queue) -> Result<Vec<[f32; 3]>, RenderError> {
        let n = self.blade_count as u64 * self.vertex_count as u64;
        let Some((positions, _)) = self.positions.get() else {
            return Err(RenderError::Parameter { what: "read_positions before any compute pass".into() });
        };
        if n == 0 {
            return Ok(Vec::new());
        }
        let words: Vec<[f32; 4]> =
            crate::blocking::read_buffer(device, queue, positions, n, "blade positions readback")?;
        let out = words.iter().map(|p| [p[0], p[1], p[2]]).collect();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn payload_packing_puts_the_first_value_in_the_low_lane() {
        let (w, e) = pack_payload(&Displacements::Snorm16 { scale: 1.0, values: vec![-1, 2, 3] });
        assert_eq!((w, e), (vec![0x0002_ffff, 0x0000_0003], 1));
        let (w, e) = pack_payload(&Displacements::Snorm8 { scale: 1.0, values: vec![-2, 1, 0, 127, 5] });
        assert_eq!((w, e), (vec![0x7f00_01fe, 0x0000_0005], 4));
        let (w, e) = pack_payload(&Displacements::F32(vec![1.5]));
        assert_eq!((w, e), (vec![1.5f32.to_bits()], 0));
    }

    /// The grass structs mirror their WGSL declarations (see `crate::shaders`'s layout tests).
    #[test]
    fn blade_structs_match_the_shaders() {
        use std::mem::{offset_of, size_of};

        use crate::shaders::tests::check_layout;
        type B = BladeUniforms;
        let pad = offset_of!(B, pad);
        let params = [
            ("color", offset_of!(B, color)),
            ("blade_count", offset_of!(B, blade_count)),
            ("vertex_count", offset_of!(B, vertex_count)),
            ("stored_vectors", offset_of!(B, stored_vectors)),
            ("stored_angles", offset_of!(B, stored_angles)),
            ("magnitudes", offset_of!(B, magnitudes)),
            ("angles", offset_of!(B, angles)),
            ("mirror_x", offset_of!(B, mirror_x)),
            ("mirror_z", offset_of!(B, mirror_z)),
            ("magnitude_per_force", offset_of!(B, magnitude_per_force)),
            ("angle_per_radian", offset_of!(B, angle_per_radian)),
            ("scale", offset_of!(B, scale)),
            ("encoding", offset_of!(B, encoding)),
            ("interpolation", offset_of!(B, interpolation)),
            ("lambert", offset_of!(B, lambert)),
            ("delayed_sources", offset_of!(B, delayed_sources)),
            ("corner_count", offset_of!(B, corner_count)),
            ("cells_x", offset_of!(B, cells_x)),
            ("seed", offset_of!(B, seed)),
            ("shading", offset_of!(B, shading)),
            ("pad0", pad),
            ("tip_color", offset_of!(B, tip_color)),
            ("shade", offset_of!(B, shade)),
            ("gloss", offset_of!(B, gloss)),
        ];
        // grass_pose.wgsl, prepended to the draw and to the culling passes.
        assert_eq!(check_layout("BladeUniforms", size_of::<B>(), &params), 2);
        let blade = [
            ("root", offset_of!(BladeGpu, root)),
            ("yaw", offset_of!(BladeGpu, yaw)),
            ("cluster", offset_of!(BladeGpu, cluster)),
            ("pad", offset_of!(BladeGpu, pad)),
            ("weights", offset_of!(BladeGpu, weights)),
        ];
        assert_eq!(check_layout("Blade", size_of::<BladeGpu>(), &blade), 2, "grass_common.wgsl, in both");
        let delayed = [
            ("position_power", offset_of!(DelayedSourceGpu, position_power)),
            ("params", offset_of!(DelayedSourceGpu, params)),
        ];
        assert_eq!(check_layout("DelayedSource", size_of::<DelayedSourceGpu>(), &delayed), 2);
    }
}
