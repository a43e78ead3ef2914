//! furbake-render: draws baked fur and grass with wgpu — skin, shells innermost to outermost with
//! the eq. 3.36 shearing in the vertex shader, and fins (fur thesis §3.2, §3.4.2), and instanced
//! grass blades that select and decode their keyframe on the GPU (grass thesis §4.2–4.4,
//! [`BladeRenderer`]) — as middleware inside a host's renderer, or headless into an image; and
//! the same shaders for engines that draw with their own graphics API ([`export_shaders`]:
//! SPIR-V, GLSL, HLSL, MSL, with a manifest of their bindings). Nothing else:
//! packs are opened by `furbake-runtime`, physics lives in `furbake-sim`, the grass CPU reference
//! in `furbake-grass`.
//!
//! # Embedding in a wgpu renderer
//!
//! The host owns the device, its colour and depth attachments, MSAA and the frame; furbake draws
//! in the host's render pass, depth-tested against the host's world (the pattern of wgpu's
//! middleware guide and of egui-wgpu and glyphon). A renderer is built once for a [`TargetDesc`]
//! — the pass's colour format and blend, depth format and comparison, sample count — with
//! pipelines from a [`PipelineCache`] shared by every renderer of the host; each frame,
//! `prepare` writes uniforms with `queue.write_buffer` and records compute work (the skinning of
//! an animated pack) into the host's encoder, and `render(&self, &mut RenderPass)` draws. No
//! library call submits or waits in a frame; the host submits. Resizing the host's attachments
//! rebuilds nothing.
//!
//! ```
//! # use std::sync::Arc;
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! use furbake_render::{FurAsset, FurRenderer, PipelineCache, RenderSettings, TargetDesc, View};
//! use furbake_runtime::Pack;
//! # let gpu = furbake_render::headless::HeadlessGpu::new()?; // stands in for the engine's device
//! # let (device, queue) = (&gpu.device, &gpu.queue);
//! # let dir = tempfile::tempdir()?;
//! # let fox_path = dir.path().join("fox.fbk");
//! # {
//! #     use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
//! #     let gltf = testmesh::uv_sphere(12, 16, 1.0).gltf;
//! #     let mesh = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default())?;
//! #     let mut settings = furbake_bake::BakeSettings::preset("fur")?;
//! #     (settings.volume.layers, settings.volume.resolution) = (8, 32);
//! #     let baked = furbake_bake::bake(&mesh, "sphere", &settings.plan()?, &mut furbake_bake::NoProgress)?;
//! #     baked.to_writer().write_atomic(&fox_path)?;
//! # }
//! // Once: the pass furbake draws into (the engine's HDR target, 4× MSAA, its depth buffer),
//! // and the renderer of a pack.
//! let target = TargetDesc::new(wgpu::TextureFormat::Rgba16Float)
//!     .with_depth(wgpu::TextureFormat::Depth32Float, wgpu::CompareFunction::LessEqual)
//!     .with_samples(4);
//! let pipelines = PipelineCache::new(device); // one per device, shared by every renderer
//! let asset = FurAsset::from_pack(&Pack::open(&fox_path)?, true)?;
//! let fur = FurRenderer::new(&pipelines, queue, &asset, &RenderSettings::default(), &target)?;
//!
//! // The engine's attachments, any size.
//! let attachment = |format| {
//!     let size = wgpu::Extent3d { width: 96, height: 64, depth_or_array_layers: 1 };
//!     let usage = wgpu::TextureUsages::RENDER_ATTACHMENT;
//!     let desc = wgpu::TextureDescriptor { label: None, size, mip_level_count: 1, sample_count: 4,
//!         dimension: wgpu::TextureDimension::D2, format, usage, view_formats: &[] };
//!     device.create_texture(&desc).create_view(&Default::default())
//! };
//! let color = attachment(wgpu::TextureFormat::Rgba16Float);
//! let depth = attachment(wgpu::TextureFormat::Depth32Float);
//!
//! // Every frame: the engine's camera and light (`FrameUniforms::new` takes its own matrix),
//! // furbake's upload, the engine's pass with its own draws and then furbake's, one submit.
//! let (center, radius) = asset.bounding_sphere();
//! let frame = View::framing(center, radius).uniforms(96, 64);
//! let mut encoder = device.create_command_encoder(&Default::default());
//! fur.prepare(queue, &mut encoder, &frame);
//! {
//!     let clear = wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store };
//!     let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
//!         color_attachments: &[Some(wgpu::RenderPassColorAttachment {
//!             view: &color, depth_slice: None, resolve_target: None, ops: clear })],
//!         depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
//!             view: &depth, depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0),
//!             store: wgpu::StoreOp::Store }), stencil_ops: None }),
//!         ..Default::default()
//!     });
//!     // ... the engine's own draws here ...
//!     fur.render(&mut pass);
//! }
//! queue.submit([encoder.finish()]);
//! # gpu.check()?;
//! # Ok(()) }
//! ```
//!
//! Grass blades work the same way ([`BladeRenderer::prepare`], [`BladeRenderer::render`]), and a
//! whole `furbake_runtime::World` — every pack placed, posed and simulated — through
//! [`SceneRenderer::for_target`], [`SceneRenderer::prepare_world`] and [`SceneRenderer::render`].
//! `examples/host.rs` is a complete host: MSAA 4× HDR target, its own ground and box, the Fox and
//! a grass field in the same pass, resolve and tonemap (`cargo run -p furbake-render --example
//! host`).
//!
//! # Headless
//!
//! [`headless`] is a small host of the same calls, which `furbake preview` and the tests use:
//! [`headless::HeadlessGpu`] makes a device without a window (any adapter: a GPU, else a
//! software one such as Mesa's lavapipe), [`headless::RenderTarget`] is its offscreen colour +
//! depth target, [`headless::read_back`] copies it into an [`image::RgbaImage`], and
//! [`headless::render_preview`] is the one-call path:
//!
//! ```no_run
//! let pack = furbake_runtime::Pack::open("fox.fbk")?;
//! let image = furbake_render::headless::render_preview(&pack, 512, 512, &Default::default())?;
//! image.save("fox.png").expect("writable");
//! # Ok::<(), furbake_render::RenderError>(())
//! ```
//!
//! # What is drawn
//!
//! The frame of a fur pack: the skin (Lambert × vertex colour), the shells as instanced draws
//! (blended: their back faces outermost first, then their front faces innermost first, so a ray
//! grazing a silhouette blends the far side of the coat before the near side, docs/design.md
//! "Shell order"; each hair lit along its sheared direction by the strand shading,
//! [`FurShading`], docs/design.md "Fur shading"), then the fins
//! on the pack's fin edges (borders, fur/bare edges: always on), then the silhouette fins: the
//! interior edges on or near this frame's silhouette, selected by a compute pass that `prepare`
//! records and drawn indirectly, faded by their faces' n·v
//! ([`RenderSettings::silhouette_fins`]). Several packs in one frame, each with its model matrix
//! and this frame's physics (scale vectors, blade corner forces), from a runtime scene's camera
//! and lights: [`SceneRenderer`]. An animated pack (skin weights or morph targets, glTF 2.0
//! "Skins", "Morph Targets") is morphed and skinned on the GPU once per frame by a compute pass
//! that its renderer owns ([`FurRenderer::set_pose`]); skin, shells and fins read the posed
//! vertices it writes.
//!
//! # The `testing` feature
//!
//! Off by default. It adds the `testing` module and the renderers' readbacks: the CPU references
//! the GPU passes are checked against, and readbacks that submit and wait — what this crate's
//! tests inspect, never what a frame calls.

#![deny(missing_docs)]
mod asset;
mod blades;
mod blocking;
mod culling;
mod depth_pyramid;
mod export;
pub mod headless;
mod lod;
mod physics;
mod pipelines;
mod renderer;
mod scene;
mod shaders;
mod shading;
mod silhouette;
mod skinning;
mod target;
#[cfg(feature = "testing")]
pub mod testing;
mod upload;

use furbake_runtime::{Camera, Lighting, RuntimeError};
use glam::Vec3;
use headless::LAVAPIPE_HINT;
use scene::RENDERER_OVERHEAD_BYTES;

pub use asset::FurAsset;
pub use blades::{BladeForces, BladeRenderSettings, BladeRenderer, BladeShading};
pub use culling::GrassCulling;
pub use depth_pyramid::DepthPyramid;
pub use export::{ExportedShader, ShaderExport, ShaderTarget, export_shaders};
pub use lod::ShellLod;
#[cfg(feature = "testing")]
pub use physics::PhysicsReadback;
pub use physics::{
    GpuFurPhysics, GpuPhysicsStats, GpuPose, GpuSkin, GpuStep, MAX_LOCAL_FORCES, MAX_XPBD_COLOURS, same_herd,
};
pub use pipelines::PipelineCache;
pub use renderer::{FurGpuAsset, FurRenderer, RenderSettings, ShellBlend};
pub use scene::{PackInput, PackRenderers, SceneFrame, SceneRenderer};
pub use shaders::FrameUniforms;
pub use shading::FurShading;
pub use target::{ColorTarget, DepthTarget, TargetDesc};

/// Why rendering failed.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter at all (not even a software one). Blame: the machine.
    #[error(
        "no GPU adapter found (tried a hardware adapter, then a fallback one): {detail}. On a machine without a GPU install Mesa's software Vulkan driver (lavapipe): {LAVAPIPE_HINT}"
    )]
    NoAdapter {
        /// What wgpu reported.
        detail: String,
    },
    /// The adapter refused to create a device.
    #[error("the GPU adapter refused to create a device: {0}")]
    RequestDevice(#[from] wgpu::RequestDeviceError),
    /// The pack could not be read.
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    /// A pack is unreadable, lacks a section, or its sections disagree.
    #[error(transparent)]
    Format(#[from] furbake_formats::FormatError),
    /// The pack's sections do not belong together. Blame: the file.
    #[error("invalid fur asset: {what}")]
    InvalidAsset {
        /// What is inconsistent.
        what: String,
    },
    /// The host's render target cannot be drawn into on this device: a format that is not
    /// renderable (or not blendable where shells blend), a sample count the format does not
    /// support, a depth format without a depth aspect. Blame: the host's target description.
    #[error("unsupported render target: {what}")]
    UnsupportedTarget {
        /// Which attachment, and what it lacks.
        what: String,
    },
    /// A caller-supplied value is out of range. Blame: the caller.
    #[error("invalid render parameter: {what}")]
    Parameter {
        /// What is wrong.
        what: String,
    },
    /// A fur shading parameter ([`FurShading`]) is out of range. Blame: the caller (a scene's
    /// `[packs.shading]` is refused when the scene is read, naming `packs[i].shading.FIELD`).
    #[error("invalid fur shading: {field}: {what}")]
    Shading {
        /// The [`FurShading`] field (`primary_exponent`).
        field: String,
        /// What is wrong with its value.
        what: String,
    },
    /// The asset exceeds a device limit.
    #[error("{what} is {value}, above this device's limit of {limit}")]
    Limit {
        /// What was measured.
        what: &'static str,
        /// The value needed.
        value: u64,
        /// The device's limit.
        limit: u64,
    },
    /// The device ran out of memory creating a resource (blame: the scene's size for this
    /// machine; smaller targets, fewer packs or fewer layers fit).
    #[error("the GPU ran out of memory: {what}")]
    OutOfMemory {
        /// wgpu's message, with what was being created.
        what: String,
    },
    /// The device was lost (driver reset, GPU removed); nothing more can be drawn with it.
    #[error("the GPU device was lost: {what}")]
    DeviceLost {
        /// The reason the driver gave.
        what: String,
    },
    /// wgpu reported a validation error or a failed readback (a bug in this crate or the driver).
    #[error("GPU error: {what}")]
    Gpu {
        /// wgpu's message.
        what: String,
    },
}

/// A compute-stage buffer binding of a bind group layout (the skinning pass's and the shell
/// probe's layouts are lists of these).
pub(crate) fn compute_buffer_entry(binding: u32, ty: wgpu::BufferBindingType) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    }
}

/// Runs `f` inside error scopes for validation, out-of-memory and internal errors and returns
/// the first error wgpu reported as a typed [`RenderError`] naming `what` was being done.
/// (Popping a scope is bookkeeping on the device timeline, not a wait for the GPU.)
pub(crate) fn gpu_scope<T>(
    device: &wgpu::Device,
    what: &str,
    f: impl FnOnce() -> Result<T, RenderError>,
) -> Result<T, RenderError> {
    let oom = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let internal = device.push_error_scope(wgpu::ErrorFilter::Internal);
    let result = f();
    // Scopes pop in reverse order of pushing.
    let errors = [
        crate::blocking::block_on(internal.pop()),
        crate::blocking::block_on(validation.pop()),
        crate::blocking::block_on(oom.pop()),
    ];
    let value = result?;
    match errors.into_iter().flatten().next() {
        None => Ok(value),
        Some(e) => Err(typed_gpu_error(e, what)),
    }
}

pub(crate) fn typed_gpu_error(e: wgpu::Error, what: &str) -> RenderError {
    match e {
        wgpu::Error::OutOfMemory { .. } => RenderError::OutOfMemory { what: format!("{what}: {e}") },
        e => RenderError::Gpu { what: format!("{what}: {e}") },
    }
}

/// Where the camera and light are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// The camera (`furbake-runtime`'s scene camera).
    pub camera: Camera,
    /// What the frame is lit by (`furbake-runtime`'s lights and ambient).
    pub lighting: Lighting,
    /// Centre and radius of a sphere holding everything drawn, in metres (fits near/far planes).
    pub bounds_center: [f32; 3],
    /// Radius of that sphere in metres.
    pub bounds_radius: f32,
}

impl View {
    /// A three-quarter view from the front-right and slightly above (glTF: +Y up, +Z front) that
    /// frames the sphere (`center`, `radius` in metres) whole at any aspect ≥ 1, with the default
    /// light.
    pub fn framing(center: [f32; 3], radius: f32) -> View {
        let center = Vec3::from(center);
        let radius = if radius.is_finite() && radius > 0.0 { radius } else { 1.0 };
        let fov_y_deg = 35.0f32;
        let distance = radius / (fov_y_deg.to_radians() * 0.5).sin() * 1.02;
        let dir = Vec3::new(0.75, 0.35, 1.0).normalize();
        let camera = Camera {
            eye: (center + dir * distance).to_array(),
            target: center.to_array(),
            up: [0.0, 1.0, 0.0],
            fov_y_deg,
        };
        View { camera, lighting: Lighting::default(), bounds_center: center.to_array(), bounds_radius: radius }
    }

    /// The same three-quarter direction as [`View::framing`], aimed at the centre of the points'
    /// projection and at the distance where every point (grown by `pad_m` metres) fits an
    /// `aspect`-wide target with a 4 % margin — a tight frame for elongated meshes. `bounds`
    /// (centre, radius) fits the near and far planes.
    pub fn fit_points(points: &[[f32; 3]], pad_m: f32, aspect: f32, bounds: ([f32; 3], f32)) -> View {
        let mut view = View::framing(bounds.0, bounds.1);
        let mut center = Vec3::from(bounds.0);
        let back = (Vec3::from(view.camera.eye) - center).normalize();
        let right = Vec3::Y.cross(back).normalize();
        let up = back.cross(right);
        let tan_y = (view.camera.fov_y_deg.to_radians() * 0.5).tan() * 0.96;
        let tan_x = tan_y * if aspect.is_finite() && aspect > 0.0 { aspect } else { 1.0 };
        // Distance at which every point fits around `center`: x/(d − z) ≤ tan for each point.
        let fit = |center: Vec3| {
            let mut distance = 0.0f32;
            for p in points {
                let d = Vec3::from(*p) - center;
                let (x, y, z) = (d.dot(right).abs() + pad_m, d.dot(up).abs() + pad_m, d.dot(back) + pad_m);
                distance = distance.max(z + x / tan_x).max(z + y / tan_y);
            }
            distance
        };
        // Twice: fit, then move the aim to the middle of the projected extent (perspective makes
        // the near side of the mesh project larger) and fit again.
        for _ in 0..2 {
            let distance = fit(center);
            if !(distance.is_finite() && distance > 0.0) {
                return view;
            }
            let eye = center + back * distance;
            let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
            for p in points {
                let d = Vec3::from(*p) - eye;
                let depth = (-d.dot(back)).max(1e-6);
                let q = glam::Vec2::new(d.dot(right), d.dot(up)) / depth;
                (lo, hi) = (lo.min(q), hi.max(q));
            }
            let mid = (lo + hi) * 0.5 * distance;
            view.camera.eye = eye.to_array();
            view.camera.target = center.to_array();
            if mid.is_finite() {
                center += right * mid.x + up * mid.y;
            }
        }
        view
    }

    /// The view-projection matrix (wgpu clip space, depth in [0, 1] growing away from the eye,
    /// near and far planes fitted around the bounding sphere) for a target of the given aspect
    /// ratio — what a host draws its own geometry with so that it and the fur share one depth.
    pub fn view_proj(&self, aspect: f32) -> glam::Mat4 {
        let c = &self.camera;
        let (eye, target, up) = (Vec3::from(c.eye), Vec3::from(c.target), Vec3::from(c.up));
        renderer::view_proj(eye, target, up, c.fov_y_deg, aspect, self.bounds_center.into(), self.bounds_radius)
    }

    /// The `Frame` uniforms for a target of `width` × `height` pixels (identity model matrix).
    pub fn uniforms(&self, width: u32, height: u32) -> shaders::FrameUniforms {
        self.uniforms_with_model(width, height, glam::Mat4::IDENTITY)
    }

    /// The `Frame` uniforms for a target of `width` × `height` pixels and an object placed by
    /// `model` (object/pack frame → world; rotation, translation, uniform positive scale).
    pub fn uniforms_with_model(&self, width: u32, height: u32, model: glam::Mat4) -> shaders::FrameUniforms {
        let aspect = width.max(1) as f32 / height.max(1) as f32;
        shaders::FrameUniforms::new(self.view_proj(aspect), Vec3::from(self.camera.eye), self.lighting, model)
            .with_viewport(width, height)
    }
}
