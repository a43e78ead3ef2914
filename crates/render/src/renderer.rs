//! [`FurRenderer`]: the GPU side of one furry asset (fur thesis §3.2): uploads the skin corners,
//! the shell atlas (R8 texture array with a box-filtered mip chain, repeat sampler), the
//! per-layer shadow table, the fin atlas and fin quads, and a scale-vector buffer (eq. 3.35; the
//! physics rewrites it through [`FurRenderer::set_scale_vectors`], one vector per welded vertex,
//! or through [`FurRenderer::set_shell_scale_vectors`] one per triangle corner when a separable
//! topology lets the fur part, §3.4.1 — the shaders pick the index by a uniform).
//!
//! A renderer is middleware in the host's frame: built for the host's pass ([`TargetDesc`], its
//! pipelines from a shared [`PipelineCache`]), [`FurRenderer::prepare`] writes this frame's
//! uniforms and records the skinning dispatch of an animated asset into the host's encoder, and
//! [`FurRenderer::render`] draws skin, shells (instanced; blended ones back faces first,
//! outermost to innermost, then front faces innermost to outermost) and fins into the host's
//! render pass, depth-tested against whatever the host drew, then the silhouette fins
//! ([`crate::silhouette`]: `prepare` also records their selection dispatch, `render` their
//! indirect draw). Neither submits nor waits (`crate::blocking`). Effects are switched with WGSL
//! `override` constants at pipeline creation. An animated asset (skin weights or morph targets)
//! owns a [`SkinningPass`]; the skin, shell and fin shaders (compiled with `SKINNED`) read their
//! roots from its output instead of the vertex attributes; a static asset's shaders are compiled
//! without it and draw exactly as before.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use furbake_runtime::ShellVertexLayout;
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::asset::FurAsset;
use crate::pipelines::{FurPipelines, FurSwitches};
use crate::shaders::{FrameUniforms, FurUniforms, SkinnedVertex, SurfaceVertex};
#[cfg(feature = "testing")]
use crate::shaders::{ProbeVertex, SHELL_WGSL};
use crate::skinning::SkinningPass;
use crate::upload::Upload;
use crate::{FurShading, PipelineCache, RenderError, TargetDesc};
use furbake_draw::mips::mip_chain;

/// How shell and fin fragments combine with what is behind them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShellBlend {
    /// Alpha blending, no depth writes (soft, order from innermost to outermost). Default.
    AlphaBlend,
    /// Alpha test: fragments above the threshold are opaque and write depth (hard, order-free).
    AlphaTest,
}

const MAX_VIEWS: u32 = RenderSettings::MAX_VIEWS;

/// Checks a renderer's view slot count (`setting` names it) against 1..=`MAX_VIEWS`.
pub(crate) fn check_view_count(views: u32, setting: &str) -> Result<(), RenderError> {
    if (1..=MAX_VIEWS).contains(&views) {
        return Ok(());
    }
    Err(RenderError::Parameter { what: format!("{setting} = {views} is not in 1..={MAX_VIEWS}") })
}

/// The error of a view index at or past a renderer's `count` slots (`setting` says where the
/// count was chosen).
pub(crate) fn view_out_of_range(view: usize, count: usize, setting: &str) -> RenderError {
    RenderError::Parameter { what: format!("view {view} of a renderer built for {count} ({setting})") }
}

/// The shader switches of a fur pipeline drawn with `settings`, for an animated (`skinned`) asset
/// or not.
fn fur_switches(settings: &RenderSettings, skinned: bool) -> FurSwitches {
    FurSwitches {
        lambert: settings.lambert,
        shadow: settings.self_shadow,
        skinned,
        strand: settings.shading.enabled,
        shear: settings.shearing,
        alpha_blend: settings.blend == ShellBlend::AlphaBlend,
        alpha_to_coverage: settings.blend == ShellBlend::AlphaTest && settings.alpha_to_coverage,
        light_slots: settings.light_slots,
    }
}

/// Rendering parameters of one asset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    /// Shell layers drawn; `None` = one per atlas slice. `Some(0)` draws the bare skin (and no
    /// fins). When different from the atlas, layer i samples the slab holding its height
    /// (`ShellAtlas::slice_for`).
    pub shell_layers: Option<u32>,
    /// Exponent k of the shell shearing, eq. 3.36. Default 2.
    pub shear_exponent: f32,
    /// Compile the eq. 3.36 shearing into the shaders (off for static fur: s = n). Default true.
    pub shearing: bool,
    /// Per-layer self-shadow factor from the atlas table. Default true.
    pub self_shadow: bool,
    /// Lambert diffuse (off: unlit colour). Default true.
    pub lambert: bool,
    /// Draw fins on the fin edges (when the asset has them). Default true.
    pub fins: bool,
    /// With `fins`, also draw fins on the interior edges on or near this frame's silhouette,
    /// selected on the GPU each frame (`silhouette.rs`; fur thesis §4.1).
    /// Default true.
    pub silhouette_fins: bool,
    /// Half-width of the band around the silhouette whose edges get a (faded) fin, in units of
    /// n·v (the cosine between a face normal and the view vector), in [0, 1]: an edge is drawn
    /// when its two faces' n·v differ in sign, or when the smaller |n·v| is below this, with alpha
    /// × (1 − |n·v|/band). 0 keeps only the sign change (fins pop in and out). Default 0.05: wider bands also fin the ridges of low-poly meshes seen at grazing angles (on the Fox, 0.2 drew fin lines along its back and face).
    pub silhouette_band: f32,
    /// Blending of shells and fins. Default [`ShellBlend::AlphaBlend`].
    pub blend: ShellBlend,
    /// Fragments with alpha at or below this are discarded, in [0, 1). Default 0
    /// (`FurLook::BLEND_ALPHA_THRESHOLD`): with blending only empty texels are skipped, so the
    /// faint mip-averaged coverage of sparse hair tips still counts at a distance. Use about 0.4
    /// with [`ShellBlend::AlphaTest`].
    pub alpha_threshold: f32,
    /// With [`ShellBlend::AlphaTest`] on a multisampled target, turn the shells' and fins' alpha
    /// into sample coverage (alpha to coverage, its step widened to one pixel), so each hair's
    /// edge is antialiased by the multisampling instead of cut per pixel. No effect on a
    /// single-sampled target or with blending. Default true.
    pub alpha_to_coverage: bool,
    /// Linear RGB multiplier of the vertex colours. Default `[1, 1, 1]`.
    pub tint: [f32; 3],
    /// Linear RGBA clear colour. Default opaque dark grey.
    pub background: [f32; 4],
    /// How many of a frame's lights the fur's shading evaluates, in 1..=`MAX_LIGHTS` (4); the
    /// frame's lights beyond it are not drawn. A pipeline constant, so the loop over the lights
    /// is unrolled: on lavapipe each slot costs fragment time even when the frame has fewer
    /// lights (docs/performance.md "Lights"). Default 4 (every frame drawn right);
    /// [`RenderSettings::for_scene`] and the headless previews take their lighting's count.
    pub light_slots: u32,
    /// Views one renderer draws in one frame (split screen, reflections, shadow views), each with
    /// its own uniforms and silhouette selection ([`FurRenderer::prepare_view`],
    /// [`FurRenderer::render_view`]), in 1..=[`RenderSettings::MAX_VIEWS`]. Default 1.
    pub views: u32,
    /// The fur's strand shading (docs/design.md "Fur shading"): its parameters, and with
    /// [`FurShading::enabled`] off the earlier Lambert × self-shadow look (a pipeline switch, the
    /// `STRAND` override). Default [`FurShading::default`]; a scene pack's `[packs.shading]`
    /// overrides it ([`crate::SceneRenderer::for_target`]).
    pub shading: FurShading,
    /// With blending, blend each layer's alpha with the asset's stacking exponent for this view
    /// angle, layer count and mip level (`shell.wgsl` `stacked_alpha`, docs/design.md "Shell
    /// opacity"), so that the stack lets through as much light as the hair volume it slices
    /// and the coat's tone does not change with the shell count. Default true.
    pub stacking_correction: bool,
    /// The shells' level of detail: each view draws fewer layers where the fur projects short
    /// ([`crate::ShellLod`], docs/design.md "Shell level of detail"), never more than
    /// `shell_layers` (or the atlas's count). `None`: every view draws them all. Needs the
    /// frame's viewport ([`FrameUniforms::with_viewport`]; [`crate::View::uniforms`] sets it).
    /// Default `Some(ShellLod::default())`.
    pub lod: Option<crate::ShellLod>,
    /// With blending, the shell and fin atlases are filtered anisotropically, averaging up to this
    /// many texels along the pixel footprint's long axis and taking the mip level from its short
    /// axis (docs/design.md "Rendering accuracy": the isotropic mip blurred the strands at oblique
    /// views into a haze): 1 (off), 2, 4, 8 or 16. The alpha test always reads level 0
    /// isotropically. Default 16.
    pub anisotropy: u16,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            shell_layers: None,
            shear_exponent: 2.0,
            shearing: true,
            self_shadow: true,
            lambert: true,
            fins: true,
            silhouette_fins: true,
            silhouette_band: 0.05,
            blend: ShellBlend::AlphaBlend,
            alpha_threshold: furbake_draw::FurLook::BLEND_ALPHA_THRESHOLD,
            alpha_to_coverage: true,
            tint: [1.0, 1.0, 1.0],
            background: [0.06, 0.06, 0.07, 1.0],
            views: 1,
            light_slots: furbake_runtime::MAX_LIGHTS as u32,
            shading: FurShading::default(),
            stacking_correction: true,
            lod: Some(crate::ShellLod::default()),
            anisotropy: 16,
        }
    }
}

impl RenderSettings {
    /// The alpha threshold [`RenderSettings::with_options`] gives the alpha test when the options
    /// choose it without a threshold of their own (the blending default, 0, would keep every
    /// covered texel of the mip-averaged atlas).
    pub const ALPHA_TEST_THRESHOLD: f32 = 0.4;

    /// The most views one renderer draws in a frame ([`RenderSettings::views`]).
    pub const MAX_VIEWS: u32 = 8;

    /// The light slots a renderer needs for `lighting` ([`RenderSettings::light_slots`]).
    pub fn light_slots_for(lighting: &furbake_runtime::Lighting) -> u32 {
        lighting.sources().len().clamp(1, furbake_runtime::MAX_LIGHTS) as u32
    }

    /// The default settings with the shader features a scene needs: the eq. 3.36 shearing is
    /// compiled in only when the scene declares an effect that moves the fur (any physics effect);
    /// a static scene keeps s = n and skips the scale-vector math; the light slots are the
    /// scene's lights.
    pub fn for_scene(scene: &furbake_runtime::Scene) -> RenderSettings {
        RenderSettings {
            shearing: !scene.effects().enabled().is_empty(),
            light_slots: Self::light_slots_for(&scene.lighting()),
            ..Default::default()
        }
    }

    /// These settings with every key `options` gives applied (a scene's `[render]` and
    /// `[packs.render]`, a command's flags; [`furbake_runtime::RenderOptions`]).
    pub fn with_options(mut self, options: &furbake_runtime::RenderOptions) -> RenderSettings {
        let o = options;
        if let Some(n) = o.shell_layers {
            self.shell_layers = Some(n);
        }
        self.fins = o.fins.unwrap_or(self.fins);
        match o.lod {
            Some(false) => self.lod = None,
            Some(true) => self.lod = Some(self.lod.unwrap_or_default()),
            None => {}
        }
        self.silhouette_fins = o.silhouette_fins.unwrap_or(self.silhouette_fins);
        self.silhouette_band = o.silhouette_band.unwrap_or(self.silhouette_band);
        self.alpha_threshold = o.alpha_threshold.unwrap_or(self.alpha_threshold);
        if let Some(blend) = o.blend {
            self.blend = match blend {
                furbake_runtime::ShellBlendMode::AlphaBlend => ShellBlend::AlphaBlend,
                furbake_runtime::ShellBlendMode::AlphaTest => ShellBlend::AlphaTest,
            };
            // The blending default threshold only skips empty texels; a test needs a real cut.
            if blend == furbake_runtime::ShellBlendMode::AlphaTest && o.alpha_threshold.is_none() {
                self.alpha_threshold = self.alpha_threshold.max(Self::ALPHA_TEST_THRESHOLD);
            }
        }
        self.shading.enabled = o.strand_shading.unwrap_or(self.shading.enabled);
        self.anisotropy = o.anisotropy.unwrap_or(self.anisotropy);
        self
    }

    /// The parameters of these settings that the `Fur` uniform block carries.
    pub fn fur_look(&self) -> furbake_draw::FurLook {
        furbake_draw::FurLook {
            tint: self.tint,
            shear_exponent: self.shear_exponent,
            alpha_threshold: self.alpha_threshold,
            shading: self.shading,
            stacking_correction: self.stacking_correction,
            anisotropy: f32::from(self.atlas_anisotropy()),
        }
    }

    /// The anisotropy clamp the atlases are sampled with: [`RenderSettings::anisotropy`] when
    /// blending, 1 for the alpha test (it reads level 0, and an anisotropic sampler still averages
    /// along the pixel's long axis there on lavapipe, which thinned the tested tips).
    fn atlas_anisotropy(&self) -> u16 {
        match self.blend {
            ShellBlend::AlphaBlend => self.anisotropy,
            ShellBlend::AlphaTest => 1,
        }
    }

    fn validate(&self) -> Result<(), RenderError> {
        let bad = |what: &str| Err(RenderError::Parameter { what: what.into() });
        if !(self.shear_exponent.is_finite() && self.shear_exponent > 0.0) {
            return bad("shear_exponent must be positive");
        }
        if !(0.0..=1.0).contains(&self.silhouette_band) {
            return bad("silhouette_band must be in [0, 1]");
        }
        if !(1..=furbake_runtime::MAX_LIGHTS as u32).contains(&self.light_slots) {
            return bad("light_slots must be in 1..=4");
        }
        check_view_count(self.views, "views")?;
        if !(0.0..1.0).contains(&self.alpha_threshold) {
            return bad("alpha_threshold must be in [0, 1)");
        }
        if self.tint.iter().chain(&self.background).any(|c| !c.is_finite() || *c < 0.0) {
            return bad("tint and background must be finite and non-negative");
        }
        if self.shell_layers.is_some_and(|n| n > furbake_formats::sections::shell_atlas::MAX_LAYERS) {
            return bad("shell_layers is above the atlas layer limit");
        }
        if let Some(lod) = &self.lod {
            lod.validate().map_err(|what| RenderError::Parameter { what })?;
        }
        if !furbake_runtime::scene::ANISOTROPY_RATIOS.contains(&self.anisotropy) {
            return bad("anisotropy must be 1, 2, 4, 8 or 16");
        }
        crate::shading::check(&self.shading)
    }
}

/// One fur asset's static data on the GPU — skin corners, fin quads, shadow table, shell and fin
/// atlases with their samplers — uploaded once and shared (`Arc`) by every [`FurRenderer`] of
/// that asset ([`FurRenderer::with_gpu_asset`]): a scene that places one pack many times holds
/// these once (docs/design.md "Memory budget").
pub struct FurGpuAsset {
    bounds: ([f32; 3], f32),
    vertex_count: u32,
    triangle_count: u32,
    /// Whether the fin quads were uploaded (the renderers' `RenderSettings::fins`).
    with_fins: bool,
    shadow: wgpu::Buffer,
    /// The stacking exponents (`crate::stacking`, binding 9).
    stacking: wgpu::Buffer,
    surface: wgpu::Buffer,
    surface_corners: u32,
    furry_corners: u32,
    fins: Option<(wgpu::Buffer, u32)>,
    shell_view: wgpu::TextureView,
    fin_view: wgpu::TextureView,
    /// The interior edges that may carry a silhouette fin, with what their draw reads.
    silhouette: Option<SilhouetteData>,
    /// An animated asset's skinning: its bind pose, influences, morph deltas and pipeline, which
    /// each renderer's own pass shares (`SkinningPass::instance`).
    skin: Option<SkinningPass>,
}

/// The shared data of the silhouette fins: the interior edges (`crate::silhouette`), one colour
/// per welded vertex, and the bind pose as `SkinnedVertex`es (what a static asset's selection and
/// draw read where an animated one reads its skinning pass's output).
struct SilhouetteData {
    edges: wgpu::Buffer,
    edge_count: u32,
    colors: wgpu::Buffer,
    rest: wgpu::Buffer,
}

impl FurGpuAsset {
    /// Uploads `asset`'s static data (its fin quads when `with_fins`) through `queue.write_*` (no
    /// submission), after checking every size against the device's limits.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &FurAsset,
        with_fins: bool,
    ) -> Result<Arc<FurGpuAsset>, RenderError> {
        let skin = if asset.is_animated() {
            Some(SkinningPass::new(device, asset.mesh(), asset.skin_weights(), asset.morph_targets())?)
        } else {
            None
        };
        crate::gpu_scope(device, "uploading a fur asset", || Self::upload(device, queue, asset, with_fins, skin))
    }

    fn upload(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &FurAsset,
        with_fins: bool,
        skin: Option<SkinningPass>,
    ) -> Result<Arc<FurGpuAsset>, RenderError> {
        let shells = asset.shells();
        let (corners, furry_triangles) = asset.surface_vertices();
        let fin_vertices = if with_fins { asset.fin_vertices() } else { Vec::new() };
        let limits = device.limits();
        let check = |what: &'static str, bytes: usize, limit: u64| {
            if bytes as u64 > limit { Err(RenderError::Limit { what, value: bytes as u64, limit }) } else { Ok(()) }
        };
        check("skin vertex buffer bytes", std::mem::size_of_val(corners.as_slice()), limits.max_buffer_size)?;
        check("fin vertex buffer bytes", std::mem::size_of_val(fin_vertices.as_slice()), limits.max_buffer_size)?;
        let res = shells.params.resolution;
        check("shell resolution", res as usize, limits.max_texture_dimension_2d as u64)?;
        check("shell layers", shells.layers(), limits.max_texture_array_layers as u64)?;
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let shadow = init("furbake shadow table", bytemuck::cast_slice(&shells.shadow), wgpu::BufferUsages::STORAGE);
        let stacking =
            init("furbake stacking table", bytemuck::cast_slice(asset.stacking_table()), wgpu::BufferUsages::STORAGE);
        let placeholder = [SurfaceVertex::default()]; // vertex buffers cannot be empty
        let surface = init(
            "furbake skin corners",
            bytemuck::cast_slice(if corners.is_empty() { &placeholder[..] } else { &corners }),
            wgpu::BufferUsages::VERTEX,
        );
        let shell_view =
            upload_r8_array(device, queue, "furbake shell atlas", res, res, shells.layers() as u32, &shells.alpha);
        let fin_view = match asset.fins() {
            Some((atlas, _)) => {
                upload_r8_array(device, queue, "furbake fin atlas", atlas.width, atlas.height, 1, &atlas.alpha)
            }
            None => upload_r8_array(device, queue, "furbake empty fin atlas", 1, 1, 1, &[0]),
        };
        let fin_view = fin_view.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2),
            ..Default::default()
        });
        let shell_view = shell_view.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        });

        // Silhouette fins need the fin atlas; derived from the skin's triangles at load time.
        let edges = match (with_fins, asset.fins()) {
            (true, Some((_, fin_edges))) => crate::silhouette::interior_edges(asset.mesh(), Some(fin_edges)),
            _ => Vec::new(),
        };
        check(
            "silhouette edge bytes",
            std::mem::size_of_val(edges.as_slice()),
            limits.max_storage_buffer_binding_size,
        )?;
        let silhouette = (!edges.is_empty()).then(|| {
            let m = asset.mesh();
            let rest: Vec<SkinnedVertex> = m
                .positions
                .iter()
                .zip(&m.normals)
                .map(|(p, n)| SkinnedVertex { position: [p[0], p[1], p[2], 1.0], normal: [n[0], n[1], n[2], 0.0] })
                .collect();
            let storage = wgpu::BufferUsages::STORAGE;
            SilhouetteData {
                edges: init("furbake silhouette edges", bytemuck::cast_slice(&edges), storage),
                edge_count: edges.len() as u32,
                colors: init("furbake vertex colours", bytemuck::cast_slice(&m.colors), storage),
                rest: init("furbake bind pose", bytemuck::cast_slice(&rest), storage),
            }
        });
        let fins = (!fin_vertices.is_empty()).then(|| {
            let buffer = init("furbake fin quads", bytemuck::cast_slice(&fin_vertices), wgpu::BufferUsages::VERTEX);
            (buffer, fin_vertices.len() as u32)
        });
        Ok(Arc::new(FurGpuAsset {
            bounds: asset.bounding_sphere(),
            vertex_count: asset.mesh().positions.len() as u32,
            triangle_count: asset.mesh().triangles.len() as u32,
            with_fins,
            shadow,
            stacking,
            surface,
            surface_corners: corners.len() as u32,
            furry_corners: furry_triangles * 3,
            fins,
            shell_view,
            fin_view,
            silhouette,
            skin,
        }))
    }
}

/// One asset's GPU resources and pipelines.
pub struct FurRenderer {
    settings: RenderSettings,
    /// The asset's static data on the GPU, shared with every other renderer of the same asset.
    gpu: Arc<FurGpuAsset>,
    /// One per view ([`RenderSettings::views`]): its frame uniforms, the bind group that reads
    /// them, and its silhouette fin selection.
    views: Vec<ViewSlot>,
    fur_buffer: wgpu::Buffer,
    scale_buffer: wgpu::Buffer,
    /// The fur uniforms as uploaded (rewritten when the scale layout changes).
    fur_uniforms: FurUniforms,
    /// `FurUniforms::scale_layout` of the buffer's current contents (0 per vertex, 1 per corner).
    scale_layout: AtomicU32,
    /// The most shell layers a view draws (`RenderSettings::shell_layers` or the atlas's).
    drawn_layers: u32,
    lod: Option<crate::ShellLod>,
    /// The asset's bounding sphere (pack frame) and fur length, which the level of detail
    /// projects.
    bounds: (Vec3, f32),
    fur_length_m: f32,
    /// The pass this renderer draws into.
    target: TargetDesc,
    pipelines: FurPipelines,
    /// The GPU skinning of an animated asset; `None` for a static one.
    skinning: Option<SkinningPass>,
    #[cfg(feature = "testing")]
    /// What binding 8 (`skinned`) holds: the skinning pass's output, or a placeholder.
    posed_vertices: wgpu::Buffer,
}

/// What a renderer holds per view: the frame uniforms, the bind group that reads them, and the
/// silhouette fin selection (`RenderSettings::silhouette_fins` on an asset with interior furry
/// edges and a fin atlas), which depends on the camera.
struct ViewSlot {
    frame: wgpu::Buffer,
    /// Shell layers this view draws (the level of detail its last `prepare` chose).
    layers: AtomicU32,
    bind_group: wgpu::BindGroup,
    silhouette: Option<crate::silhouette::SilhouettePass>,
}

impl FurRenderer {
    /// Uploads `asset` and takes the pipelines for `settings` drawn into passes like `target` from
    /// `pipelines` (created there on first use, shared with every other renderer of that cache).
    /// Fails on bad settings ([`RenderError::Parameter`]), a target this device cannot draw into
    /// ([`RenderError::UnsupportedTarget`]; alpha-blended shells need a blendable colour format),
    /// an asset above the device's limits, or a GPU error while creating resources. Uploads go
    /// through `queue.write_texture` (no submission).
    pub fn new(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        asset: &FurAsset,
        settings: &RenderSettings,
        target: &TargetDesc,
    ) -> Result<FurRenderer, RenderError> {
        settings.validate()?;
        let gpu = FurGpuAsset::new(pipelines.device(), queue, asset, settings.fins)?;
        FurRenderer::with_gpu_asset(pipelines, asset, gpu, settings, target)
    }

    /// As [`FurRenderer::new`] on an asset already uploaded: `gpu` (from [`FurGpuAsset::new`] with
    /// `settings.fins`) is shared, so a scene that places one pack many times holds its atlases
    /// and vertex buffers once. This renderer owns only what differs per placement: its
    /// uniforms, scale vectors and (for an animated asset) its skinning pass.
    pub fn with_gpu_asset(
        pipelines: &PipelineCache,
        asset: &FurAsset,
        gpu: Arc<FurGpuAsset>,
        settings: &RenderSettings,
        target: &TargetDesc,
    ) -> Result<FurRenderer, RenderError> {
        settings.validate()?;
        if gpu.vertex_count as usize != asset.mesh().positions.len()
            || gpu.triangle_count as usize != asset.mesh().triangles.len()
            || gpu.with_fins != settings.fins
        {
            return Err(RenderError::Parameter {
                what: "the shared GPU asset was uploaded from another asset or with other fin settings".into(),
            });
        }
        let switches = fur_switches(settings, asset.is_animated());
        let silhouette = settings.silhouette_fins && gpu.silhouette.is_some();
        let stage_pipelines = pipelines.fur(target, switches, silhouette)?;
        let device = pipelines.device();
        crate::gpu_scope(device, "creating the fur renderer", || {
            Self::build(pipelines, asset, gpu, settings, target, stage_pipelines)
        })
    }

    fn build(
        cache: &PipelineCache,
        asset: &FurAsset,
        gpu: Arc<FurGpuAsset>,
        settings: &RenderSettings,
        target: &TargetDesc,
        pipelines: FurPipelines,
    ) -> Result<FurRenderer, RenderError> {
        let device = cache.device();
        let shells = asset.shells();
        let limits = device.limits();
        let (vertex_count, triangle_count) = (gpu.vertex_count as usize, gpu.triangle_count as usize);
        // Room for either layout: one vector per welded vertex or per triangle corner.
        let scale_capacity = vertex_count.max(3 * triangle_count).max(1);
        if scale_capacity as u64 * 16 > limits.max_storage_buffer_binding_size {
            return Err(RenderError::Limit {
                what: "scale vector bytes",
                value: scale_capacity as u64 * 16,
                limit: limits.max_storage_buffer_binding_size,
            });
        }
        // An animated asset: one skinning pass writes the posed vertices every stage reads (its
        // static part shared with the asset's other renderers).
        let skinning = match &gpu.skin {
            Some(shared) => Some(shared.instance(device)?),
            None if asset.is_animated() => {
                Some(SkinningPass::new(device, asset.mesh(), asset.skin_weights(), asset.morph_targets())?)
            }
            None => None,
        };

        let drawn_layers = settings.shell_layers.unwrap_or(shells.params.layers);
        let fur = settings.fur_look().fur_uniforms(shells, asset.uv_map().repeat_m, drawn_layers);
        let init = |label, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let fur_buffer = init(
            "furbake fur uniforms",
            bytemuck::bytes_of(&fur),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        // Rest pose s = n per welded vertex; the tail (room for per-corner vectors) is unused
        // until a per-corner upload overwrites the whole prefix it reads.
        let mut rest = asset.rest_scale_vectors();
        rest.resize(scale_capacity, [0.0; 4]); // also: storage bindings cannot be empty
        let scale_buffer = init(
            "furbake scale vectors",
            bytemuck::cast_slice(&rest),
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
        );
        // A static asset's shaders never read binding 8; it still needs a (one-entry) buffer.
        let posed_vertices = match &skinning {
            Some(pass) => pass.skinned_buffer().clone(),
            None => init(
                "furbake no skinned vertices",
                bytemuck::bytes_of(&SkinnedVertex::default()),
                wgpu::BufferUsages::STORAGE,
            ),
        };

        let samplers = cache.atlas_samplers(settings.atlas_anisotropy());
        let view_slot = || -> Result<ViewSlot, RenderError> {
            let frame = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("furbake frame uniforms"),
                size: std::mem::size_of::<FrameUniforms>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("furbake fur bind group"),
                layout: cache.fur_layout(),
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: frame.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: fur_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: scale_buffer.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: gpu.shadow.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 4, resource: wgpu::BindingResource::TextureView(&gpu.shell_view) },
                    wgpu::BindGroupEntry { binding: 5, resource: wgpu::BindingResource::Sampler(&samplers[0]) },
                    wgpu::BindGroupEntry { binding: 6, resource: wgpu::BindingResource::TextureView(&gpu.fin_view) },
                    wgpu::BindGroupEntry { binding: 7, resource: wgpu::BindingResource::Sampler(&samplers[1]) },
                    wgpu::BindGroupEntry { binding: 8, resource: posed_vertices.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 9, resource: gpu.stacking.as_entire_binding() },
                ],
            });
            let silhouette = match (&gpu.silhouette, settings.silhouette_fins) {
                (Some(data), true) => {
                    let vertices = skinning.as_ref().map_or(&data.rest, |pass| pass.skinned_buffer());
                    Some(crate::silhouette::SilhouettePass::new(
                        cache,
                        &data.edges,
                        &data.colors,
                        vertices,
                        data.edge_count,
                        settings.silhouette_band,
                    )?)
                }
                _ => None,
            };
            Ok(ViewSlot { frame, layers: AtomicU32::new(drawn_layers), bind_group, silhouette })
        };
        let views = (0..settings.views).map(|_| view_slot()).collect::<Result<Vec<_>, _>>()?;
        Ok(FurRenderer {
            settings: *settings,
            gpu,
            views,
            fur_buffer,
            scale_buffer,
            fur_uniforms: fur,
            scale_layout: AtomicU32::new(0),
            drawn_layers,
            lod: settings.lod,
            bounds: (Vec3::from(asset.bounding_sphere().0), asset.bounding_sphere().1),
            fur_length_m: shells.fur_length_m,
            target: target.clone(),
            pipelines,
            skinning,
            #[cfg(feature = "testing")]
            posed_vertices,
        })
    }

    /// Writes this frame's pose of an animated asset: one skinning matrix per bind
    /// (`world(joint) × inverseBind`, `furbake_runtime::animation::skinning_matrices`; empty
    /// without skin weights) and one weight per morph target (empty without morph targets). The
    /// skinning dispatch the next [`FurRenderer::prepare`] records skins the asset with it before
    /// [`FurRenderer::render`] draws. Scale vectors are given in the posed mesh frame (the runtime
    /// poses the physics on the skinned surface) and used as given. A static asset, a wrong count or a non-finite
    /// value is a [`RenderError::Parameter`] and changes nothing. No allocation (see
    /// `SkinningPass::set_pose`).
    pub fn set_pose(
        &self,
        queue: &wgpu::Queue,
        skinning_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<(), RenderError> {
        self.check_pose(skinning_matrices, morph_weights)?;
        self.write_pose(&mut Upload::Queue(queue), skinning_matrices, morph_weights)
    }

    /// The checks of [`FurRenderer::set_pose`].
    pub(crate) fn check_pose(&self, skinning_matrices: &[Mat4], morph_weights: &[f32]) -> Result<(), RenderError> {
        match &self.skinning {
            Some(pass) => pass.check_pose(skinning_matrices, morph_weights),
            None => Err(RenderError::Parameter {
                what: "set_pose on a static asset (the pack has no skin weights or morph targets)".into(),
            }),
        }
    }

    /// Writes a checked pose through `upload`.
    pub(crate) fn write_pose(
        &self,
        upload: &mut Upload<'_>,
        skinning_matrices: &[Mat4],
        morph_weights: &[f32],
    ) -> Result<(), RenderError> {
        match &self.skinning {
            Some(pass) => pass.write_pose(upload, skinning_matrices, morph_weights),
            None => Ok(()),
        }
    }

    /// Whether the asset is animated (skin weights or morph targets): its renderer skins it on
    /// the GPU with the pose [`FurRenderer::set_pose`] writes.
    pub fn is_animated(&self) -> bool {
        self.skinning.is_some()
    }

    /// The skinning pass of an animated asset, for the crate's own passes.
    pub(crate) fn skinning_pass(&self) -> Option<&SkinningPass> {
        self.skinning.as_ref()
    }

    #[cfg(feature = "testing")]
    /// The skinning pass of an animated asset (`None` for a static one): its counts, its output
    /// buffer, and its readback for tests.
    pub fn skinning(&self) -> Option<&SkinningPass> {
        self.skinning.as_ref()
    }

    /// Replaces the per-vertex scale vectors (eq. 3.35, one unit vector per skin vertex), e.g.
    /// with the physics solver's result for this frame. Vectors are used as given.
    pub fn set_scale_vectors(&self, queue: &wgpu::Queue, scale_vectors: &[[f32; 3]]) -> Result<(), RenderError> {
        self.set_shell_scale_vectors(queue, scale_vectors, ShellVertexLayout::PerVertex)
    }

    /// Replaces the scale vectors (eq. 3.35) in either layout: one per welded skin vertex, or —
    /// [`ShellVertexLayout::PerCorner`], what `furbake_runtime::World` gives for a separable
    /// topology (§3.4.1) — one per triangle corner, `3 × triangle + corner` in the skin mesh's
    /// triangle order, so that triangles sharing a vertex can shear apart and the fur parts.
    /// Shells and fins read the layout last written. Vectors are used as given; a wrong count or
    /// a non-finite value is an error and changes nothing.
    pub fn set_shell_scale_vectors(
        &self,
        queue: &wgpu::Queue,
        scale_vectors: &[[f32; 3]],
        layout: ShellVertexLayout,
    ) -> Result<(), RenderError> {
        self.check_shell_scale_vectors(scale_vectors, layout)?;
        self.write_shell_scale_vectors(&mut Upload::Queue(queue), scale_vectors, layout)
    }

    /// The checks of [`FurRenderer::set_shell_scale_vectors`]: the count and finite values.
    pub(crate) fn check_shell_scale_vectors(
        &self,
        scale_vectors: &[[f32; 3]],
        layout: ShellVertexLayout,
    ) -> Result<(), RenderError> {
        let (expected, what) = match layout {
            ShellVertexLayout::PerVertex => (self.gpu.vertex_count as usize, "vertices"),
            ShellVertexLayout::PerCorner => (3 * self.gpu.triangle_count as usize, "triangle corners"),
        };
        if scale_vectors.len() != expected {
            return Err(RenderError::Parameter {
                what: format!("{} scale vectors for {expected} {what}", scale_vectors.len()),
            });
        }
        if scale_vectors.iter().flatten().any(|c| !c.is_finite()) {
            return Err(RenderError::Parameter { what: "scale vectors must be finite".into() });
        }
        Ok(())
    }

    /// Writes checked scale vectors through `upload`, padded to vec4, and the layout into the fur
    /// uniforms (when it changed, or on every collected frame).
    pub(crate) fn write_shell_scale_vectors(
        &self,
        upload: &mut Upload<'_>,
        scale_vectors: &[[f32; 3]],
        layout: ShellVertexLayout,
    ) -> Result<(), RenderError> {
        let code = layout_code(layout);
        if self.scale_layout.swap(code, Ordering::Relaxed) != code || upload.collected() {
            let fur = FurUniforms { scale_layout: code, ..self.fur_uniforms };
            upload.write(&self.fur_buffer, 0, bytemuck::bytes_of(&fur));
        }
        let vectors = scale_vectors.iter().map(|s| bytemuck::cast::<[f32; 4], [u8; 16]>([s[0], s[1], s[2], 0.0]));
        upload.write_chunks(&self.scale_buffer, 0, vectors, "scale vector")
    }

    /// The scale-vector buffer the shell and fin shaders read (written by the GPU physics).
    pub(crate) fn scale_buffer(&self) -> &wgpu::Buffer {
        &self.scale_buffer
    }

    /// Tells the shaders how the scale-vector buffer is laid out (the GPU physics writes it).
    pub(crate) fn set_scale_layout(&self, queue: &wgpu::Queue, layout: ShellVertexLayout) {
        let code = layout_code(layout);
        if self.scale_layout.swap(code, Ordering::Relaxed) != code {
            let fur = FurUniforms { scale_layout: code, ..self.fur_uniforms };
            queue.write_buffer(&self.fur_buffer, 0, bytemuck::bytes_of(&fur));
        }
    }

    /// The layout of the scale vectors last written (initially [`ShellVertexLayout::PerVertex`],
    /// the rest pose).
    pub fn scale_layout(&self) -> ShellVertexLayout {
        if self.scale_layout.load(Ordering::Relaxed) == 1 {
            ShellVertexLayout::PerCorner
        } else {
            ShellVertexLayout::PerVertex
        }
    }

    #[cfg(feature = "testing")]
    /// The scale vectors the shell and fin shaders read now, one per welded vertex or triangle
    /// corner ([`FurRenderer::scale_layout`]); submits and waits.
    pub fn shell_scale_vectors(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        let count = match self.scale_layout() {
            ShellVertexLayout::PerVertex => self.gpu.vertex_count,
            ShellVertexLayout::PerCorner => 3 * self.gpu.triangle_count,
        };
        let v: Vec<[f32; 4]> =
            crate::blocking::read_buffer(device, queue, &self.scale_buffer, count as u64, "scale vectors")?;
        Ok(v.iter().map(|s| [s[0], s[1], s[2]]).collect())
    }

    /// Whether this renderer and `other` draw from one uploaded asset.
    pub(crate) fn shares_gpu_asset(&self, other: &FurRenderer) -> bool {
        Arc::ptr_eq(&self.gpu, &other.gpu)
    }

    #[cfg(feature = "testing")]
    /// The asset's static GPU data this renderer draws from (shared by every renderer built on
    /// the same [`FurGpuAsset`]).
    pub fn gpu_asset(&self) -> &Arc<FurGpuAsset> {
        &self.gpu
    }

    /// The most shell layers a view draws (`RenderSettings::shell_layers`, or one per atlas
    /// slice); with a level of detail, a view may draw fewer ([`FurRenderer::layers_in_view`]).
    pub fn drawn_layers(&self) -> u32 {
        self.drawn_layers
    }

    /// The shell layers view `view` draws with what its last prepare wrote (the level of detail's
    /// choice; [`FurRenderer::drawn_layers`] without one). A view out of range is a
    /// [`RenderError::Parameter`].
    pub fn layers_in_view(&self, view: usize) -> Result<u32, RenderError> {
        Ok(self.view_slot(view)?.layers.load(Ordering::Relaxed))
    }

    /// Welded skin vertices (= scale vectors expected by [`FurRenderer::set_scale_vectors`]).
    pub fn vertex_count(&self) -> u32 {
        self.gpu.vertex_count
    }

    /// Skin triangles (3 × this = per-corner scale vectors expected by
    /// [`FurRenderer::set_shell_scale_vectors`] with [`ShellVertexLayout::PerCorner`]).
    pub fn triangle_count(&self) -> u32 {
        self.gpu.triangle_count
    }

    /// The settings the pipelines were built with.
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Centre and radius (metres, object frame) of a sphere holding the skin and its fur
    /// ([`FurAsset::bounding_sphere`]).
    pub fn bounding_sphere(&self) -> ([f32; 3], f32) {
        self.gpu.bounds
    }

    /// Distance from the skin to the outermost shell, metres.
    pub(crate) fn fur_length_m(&self) -> f32 {
        self.fur_uniforms.fur_length_m
    }

    /// The pass description this renderer's pipelines were built for.
    pub fn target(&self) -> &TargetDesc {
        &self.target
    }

    /// Writes `frame` (the host's view-projection, eye and light, and this object's model matrix,
    /// e.g. from [`crate::View::uniforms_with_model`] or [`FrameUniforms::new`]) into this
    /// renderer's uniform buffer with `queue.write_buffer`, and records an animated asset's
    /// skinning dispatch (the pose last written by [`FurRenderer::set_pose`]) into `encoder`, in
    /// its own compute pass. Call once per frame before the host begins the render pass that
    /// [`FurRenderer::render`] draws into, on an encoder submitted on `queue`: the uniform write
    /// lands before that submission's commands run. One model matrix per renderer per
    /// submission. Does not submit or wait, and allocates nothing of its own (wgpu
    /// allocates inside its calls; docs/performance.md).
    pub fn prepare(&self, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder, frame: &FrameUniforms) {
        self.write_frame(&mut Upload::Queue(queue), frame);
        self.record(encoder);
    }

    /// The writes of [`FurRenderer::prepare`]: view 0's uniforms and silhouette camera.
    pub(crate) fn write_frame(&self, upload: &mut Upload<'_>, frame: &FrameUniforms) {
        self.views[0].write(upload, frame, self.shell_level(frame));
    }

    /// The commands of [`FurRenderer::prepare`], after its writes: the skinning dispatch and
    /// view 0's silhouette selection.
    pub(crate) fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(skinning) = &self.skinning {
            skinning.encode(encoder);
        }
        self.views[0].record(encoder);
    }

    /// The shells a view of `frame` draws: its level of detail ([`RenderSettings::lod`]) from the
    /// fur's projected length, or every layer.
    pub(crate) fn shell_level(&self, frame: &FrameUniforms) -> crate::lod::ShellLevel {
        let px =
            self.lod.and_then(|_| crate::lod::projected_fur_px(frame, self.bounds.0, self.bounds.1, self.fur_length_m));
        match (self.lod, px) {
            (Some(lod), Some(px)) => crate::lod::ShellLevel::of(self.drawn_layers, &lod, px),
            _ => crate::lod::ShellLevel::full(self.drawn_layers),
        }
    }

    /// Writes the uniforms of view `view` (1 ≤ `view` < [`RenderSettings::views`]; view 0 is
    /// [`FurRenderer::prepare`]'s) and records its silhouette fin selection into `encoder`, so that
    /// [`FurRenderer::render_view`] draws this frame from another camera (split screen, a
    /// reflection, a shadow view) before the host submits: each view keeps its own uniforms, so
    /// a later view no longer overwrites an earlier one. Call after [`FurRenderer::prepare`] (the
    /// frame's skinning, recorded once, comes first in the encoder). A view out of range is a
    /// [`RenderError::Parameter`]. Does not submit, wait or allocate.
    pub fn prepare_view(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        view: usize,
        frame: &FrameUniforms,
    ) -> Result<(), RenderError> {
        let slot = self.view_slot(view)?;
        slot.write(&mut Upload::Queue(queue), frame, self.shell_level(frame));
        slot.record(encoder);
        Ok(())
    }

    fn view_slot(&self, view: usize) -> Result<&ViewSlot, RenderError> {
        self.views.get(view).ok_or_else(|| view_out_of_range(view, self.views.len(), "RenderSettings::views"))
    }

    #[cfg(feature = "testing")]
    /// Whether this renderer selects and draws silhouette fins
    /// ([`RenderSettings::silhouette_fins`] on an asset with interior furry edges and fins).
    pub fn has_silhouette_fins(&self) -> bool {
        self.views[0].silhouette.is_some()
    }

    #[cfg(feature = "testing")]
    /// Reads back the silhouette fin selection the GPU makes for `frame` (the same dispatch
    /// [`FurRenderer::prepare`] records, after an animated asset's skinning with the pose last
    /// written): `(edge, fade)` per selected edge, edges indexing
    /// [`crate::silhouette::interior_edges`] of the asset's skin and fin edges, sorted by edge.
    /// Empty without silhouette fins. For tests against [`crate::silhouette::silhouette_edges`];
    /// submits and waits for the GPU.
    pub fn silhouette_selection(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        frame: &FrameUniforms,
    ) -> Result<Vec<(u32, f32)>, RenderError> {
        let Some(silhouette) = &self.views[0].silhouette else { return Ok(Vec::new()) };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let readback = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            })
        };
        let args = readback("furbake silhouette args readback", 16);
        let instances = readback("furbake silhouette instances readback", silhouette.instance_bytes());
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake silhouette readback") });
        if let Some(skinning) = &self.skinning {
            skinning.encode(&mut encoder);
        }
        silhouette.write_camera(&mut Upload::Queue(queue), object_eye(frame));
        silhouette.record(&mut encoder);
        silhouette.copy_out(&mut encoder, &args, &instances);
        crate::blocking::submit(queue, [encoder.finish()]);
        if let Some(e) = crate::blocking::block_on(scope.pop()) {
            return Err(RenderError::Gpu { what: e.to_string() });
        }
        crate::blocking::map_for_reading(device, &args, "silhouette args readback")?;
        crate::blocking::map_for_reading(device, &instances, "silhouette instances readback")?;
        let count = {
            let view = args.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
            bytemuck::cast_slice::<u8, u32>(&view)[1] as usize
        };
        let mut out: Vec<(u32, f32)> = {
            let view = instances.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
            let words: &[[u32; 2]] = bytemuck::cast_slice(&view);
            // The drawn prefix holds every edge in order; unselected ones have fade 0.
            words.iter().take(count).map(|w| (w[0], f32::from_bits(w[1]))).filter(|&(_, fade)| fade > 0.0).collect()
        };
        args.unmap();
        instances.unmap();
        out.sort_by_key(|e| e.0);
        Ok(out)
    }

    /// Draws skin, shells and fins into the host's `pass`, whose attachments must match
    /// [`FurRenderer::target`], with what the last [`FurRenderer::prepare`] wrote. Sets its own
    /// pipelines, bind group 0 and vertex buffer 0 (the host re-sets its own afterwards); draws
    /// nothing else. Does not submit or wait, and allocates nothing of its own (wgpu
    /// allocates inside its calls; docs/performance.md).
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.draw(pass, &self.views[0]);
    }

    /// [`FurRenderer::render`] with what [`FurRenderer::prepare_view`] wrote for view `view`. A
    /// view out of range is a [`RenderError::Parameter`] and draws nothing.
    pub fn render_view(&self, pass: &mut wgpu::RenderPass<'_>, view: usize) -> Result<(), RenderError> {
        self.draw(pass, self.view_slot(view)?);
        Ok(())
    }

    fn draw(&self, pass: &mut wgpu::RenderPass<'_>, view: &ViewSlot) {
        pass.set_bind_group(0, &view.bind_group, &[]);
        let gpu = &*self.gpu;
        if gpu.surface_corners > 0 {
            pass.set_pipeline(&self.pipelines.skin);
            pass.set_vertex_buffer(0, gpu.surface.slice(..));
            pass.draw(0..gpu.surface_corners, 0..1);
        }
        let layers = view.layers.load(Ordering::Relaxed);
        if gpu.furry_corners > 0 && layers > 0 {
            pass.set_vertex_buffer(0, gpu.surface.slice(..));
            // Blended: the back faces first, as instances layers..2·layers (shell.wgsl).
            if let Some(back) = &self.pipelines.shell_back {
                pass.set_pipeline(back);
                pass.draw(0..gpu.furry_corners, layers..2 * layers);
            }
            pass.set_pipeline(&self.pipelines.shell);
            pass.draw(0..gpu.furry_corners, 0..layers);
        }
        if let Some((buffer, count)) = gpu.fins.as_ref().filter(|_| self.drawn_layers > 0) {
            pass.set_pipeline(&self.pipelines.fin);
            pass.set_vertex_buffer(0, buffer.slice(..));
            pass.draw(0..*count, 0..1);
        }
        if let (Some(pipeline), Some(silhouette)) = (&self.pipelines.silhouette_fin, &view.silhouette)
            && self.drawn_layers > 0
        {
            pass.set_pipeline(pipeline);
            silhouette.draw(pass);
        }
    }

    #[cfg(feature = "testing")]
    /// Reads back the sheared shell positions the shell vertex shader draws, computed on the GPU
    /// by the same WGSL function (`shell_vertex` in `shell.wgsl`, via its compute entry point
    /// `cs_shell_positions`) with this renderer's uniforms, override constants and current scale
    /// vectors: `drawn_layers × vertices` object-frame positions in metres, layer-major
    /// (`[layer · vertices + vertex]`, layer 0 = innermost shell at t = 1/drawn_layers), where
    /// the vertices are those of the current [`FurRenderer::scale_layout`]
    /// ([`FurAsset::shell_vertices`]: welded vertices, or `3 × triangle + corner`). `asset`
    /// must be the one this renderer was built from (its skin positions and normals are the
    /// input). An animated asset's shells grow from its posed vertices: the skinning dispatch
    /// with the pose last written runs first, so this is the GPU truth of the drawn shells. For
    /// tests against `furbake_sim::shell_vertex_position`; waits for the GPU.
    pub fn shell_positions(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &FurAsset,
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        Ok(self.shell_probe(device, queue, asset)?.0)
    }

    #[cfg(feature = "testing")]
    /// Reads back the hair directions the shell shader shades along (docs/design.md "Fur
    /// shading"), computed on the GPU by the same WGSL function the draw uses (`shell_tangent` in
    /// `shell.wgsl`, the eq. 3.36 derivative `strand_tangent`), in the order and object frame of
    /// [`FurRenderer::shell_positions`]: unit vectors, the normal at rest. For tests against
    /// [`crate::shading::strand_tangent`]; waits for the GPU.
    pub fn shell_tangents(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &FurAsset,
    ) -> Result<Vec<[f32; 3]>, RenderError> {
        Ok(self.shell_probe(device, queue, asset)?.1)
    }

    #[cfg(feature = "testing")]
    /// The shell probe (`cs_shell_positions`): positions and hair directions of every shell
    /// vertex, layer-major.
    fn shell_probe(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        asset: &FurAsset,
    ) -> Result<ShellProbe, RenderError> {
        let mesh = asset.mesh();
        if mesh.positions.len() != self.gpu.vertex_count as usize
            || mesh.triangles.len() != self.gpu.triangle_count as usize
        {
            return Err(RenderError::Parameter {
                what: format!(
                    "asset has {} vertices / {} triangles, the renderer {} / {}",
                    mesh.positions.len(),
                    mesh.triangles.len(),
                    self.gpu.vertex_count,
                    self.gpu.triangle_count
                ),
            });
        }
        let vertices = asset.shell_vertices(self.scale_layout());
        let count = vertices.len() as u64 * self.drawn_layers as u64;
        if count == 0 {
            return Ok((Vec::new(), Vec::new()));
        }
        let limit = device.limits().max_storage_buffer_binding_size;
        if count * 16 > limit {
            return Err(RenderError::Limit { what: "shell probe bytes", value: count * 16, limit });
        }
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        // The welded vertex of each shell vertex (where its posed root is read).
        let welded: Vec<u32> = match self.scale_layout() {
            ShellVertexLayout::PerVertex => (0..mesh.positions.len() as u32).collect(),
            ShellVertexLayout::PerCorner => mesh.triangles.iter().flatten().copied().collect(),
        };
        let probe: Vec<ProbeVertex> = vertices
            .iter()
            .zip(welded)
            .map(|((p, n), vertex_index)| ProbeVertex {
                position: [p[0], p[1], p[2], 1.0],
                normal: [n[0], n[1], n[2], 0.0],
                vertex_index,
                pad: [0; 3],
            })
            .collect();
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("furbake shell probe vertices"),
            contents: bytemuck::cast_slice(&probe),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: count * 16,
                usage,
                mapped_at_creation: false,
            })
        };
        let out_usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        let read_usage = wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ;
        let output = buffer("furbake shell probe output", out_usage);
        let tangents = buffer("furbake shell probe tangents", out_usage);
        let readback = buffer("furbake shell probe readback", read_usage);
        let tangent_readback = buffer("furbake shell probe tangent readback", read_usage);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("furbake shell probe"),
            source: wgpu::ShaderSource::Wgsl(SHELL_WGSL.into()),
        });
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        let constants: &[(&str, f64)] =
            &[("SHEAR", flag(self.settings.shearing)), ("SKINNED", flag(self.skinning.is_some()))];
        // An explicit layout: `skinned` (binding 8) is bound whether or not SKINNED reads it.
        let probe_layouts = probe_bind_group_layouts(device);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake shell probe"),
            bind_group_layouts: &[Some(&probe_layouts[0]), Some(&probe_layouts[1])],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("furbake shell probe"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("cs_shell_positions"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        });
        let shared = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake shell probe uniforms"),
            layout: &probe_layouts[0],
            entries: &[
                wgpu::BindGroupEntry { binding: 1, resource: self.fur_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.scale_buffer.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: self.posed_vertices.as_entire_binding() },
            ],
        });
        let io = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake shell probe io"),
            layout: &probe_layouts[1],
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: input.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: output.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: tangents.as_entire_binding() },
            ],
        });
        let groups = (count as u32).div_ceil(64);
        let max = device.limits().max_compute_workgroups_per_dimension;
        let (x, y) = if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) };
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake shell probe") });
        if let Some(skinning) = &self.skinning {
            skinning.encode(&mut encoder);
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("furbake shell probe"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &shared, &[]);
            pass.set_bind_group(1, &io, &[]);
            pass.dispatch_workgroups(x, y, 1);
        }
        encoder.copy_buffer_to_buffer(&output, 0, &readback, 0, count * 16);
        encoder.copy_buffer_to_buffer(&tangents, 0, &tangent_readback, 0, count * 16);
        crate::blocking::submit(queue, [encoder.finish()]);
        if let Some(e) = crate::blocking::block_on(scope.pop()) {
            return Err(RenderError::Gpu { what: e.to_string() });
        }
        let read = |buffer: &wgpu::Buffer, what| -> Result<Vec<[f32; 3]>, RenderError> {
            crate::blocking::map_for_reading(device, buffer, what)?;
            let out = {
                let view = buffer.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
                let words: &[[f32; 4]] = bytemuck::cast_slice(&view);
                words.iter().map(|p| [p[0], p[1], p[2]]).collect()
            };
            buffer.unmap();
            Ok(out)
        };
        Ok((read(&readback, "shell probe readback")?, read(&tangent_readback, "shell probe tangent readback")?))
    }
}

#[cfg(feature = "testing")]
/// What the shell probe reads back: shell positions and hair directions, layer-major.
type ShellProbe = (Vec<[f32; 3]>, Vec<[f32; 3]>);

impl ViewSlot {
    /// Writes this view's uniforms (with its level of detail) and silhouette camera.
    fn write(&self, upload: &mut Upload<'_>, frame: &FrameUniforms, level: crate::lod::ShellLevel) {
        self.layers.store(level.layers, Ordering::Relaxed);
        let frame = FrameUniforms { shells: level.uniform(), ..*frame };
        upload.write(&self.frame, 0, bytemuck::bytes_of(&frame));
        if let Some(silhouette) = &self.silhouette {
            silhouette.write_camera(upload, object_eye(&frame));
        }
    }

    /// Records this view's silhouette fin selection.
    fn record(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(silhouette) = &self.silhouette {
            silhouette.record(encoder);
        }
    }
}

/// The eye of `frame` in the object frame (the inverse model matrix applied to it), where the
/// silhouette selection compares it with the posed vertices.
fn object_eye(frame: &FrameUniforms) -> Vec3 {
    let eye = Vec3::new(frame.camera_pos[0], frame.camera_pos[1], frame.camera_pos[2]);
    frame.model().inverse().transform_point3(eye)
}

/// `FurUniforms::scale_layout` of a layout.
fn layout_code(layout: ShellVertexLayout) -> u32 {
    match layout {
        ShellVertexLayout::PerVertex => 0,
        ShellVertexLayout::PerCorner => 1,
    }
}

#[cfg(feature = "testing")]
/// Group 0 (the fur uniforms, scale vectors and posed vertices `cs_shell_positions` reads) and
/// group 1 (probe input, positions and hair directions out) of the shell readback probe.
fn probe_bind_group_layouts(device: &wgpu::Device) -> [wgpu::BindGroupLayout; 2] {
    let entry = crate::compute_buffer_entry;
    let read = wgpu::BufferBindingType::Storage { read_only: true };
    let layout = |label, entries: &[wgpu::BindGroupLayoutEntry]| {
        device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
    };
    [
        layout(
            "furbake shell probe uniforms",
            &[entry(1, wgpu::BufferBindingType::Uniform), entry(2, read), entry(8, read)],
        ),
        layout(
            "furbake shell probe io",
            &[
                entry(0, read),
                entry(1, wgpu::BufferBindingType::Storage { read_only: false }),
                entry(2, wgpu::BufferBindingType::Storage { read_only: false }),
            ],
        ),
    ]
}

/// Uploads `layers` slices of `width × height` R8 texels with a full box-filtered mip chain.
fn upload_r8_array(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    label: &str,
    width: u32,
    height: u32,
    layers: u32,
    texels: &[u8],
) -> wgpu::Texture {
    let slice_len = width as usize * height as usize;
    let chains: Vec<_> = texels.chunks_exact(slice_len).map(|s| mip_chain(width, height, s)).collect();
    let mip_level_count = chains.first().map_or(1, |c| c.len() as u32);
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
        mip_level_count,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (layer, chain) in chains.iter().enumerate() {
        for (level, (w, h, data)) in chain.iter().enumerate() {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: level as u32,
                    origin: wgpu::Origin3d { x: 0, y: 0, z: layer as u32 },
                    aspect: wgpu::TextureAspect::All,
                },
                data,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(*w), rows_per_image: Some(*h) },
                wgpu::Extent3d { width: *w, height: *h, depth_or_array_layers: 1 },
            );
        }
    }
    texture
}

/// View-projection matrix (wgpu clip space, depth in [0, 1]) of a camera, with near and far
/// planes fitted around a bounding sphere.
pub(crate) fn view_proj(
    eye: Vec3,
    target: Vec3,
    up: Vec3,
    fov_y_deg: f32,
    aspect: f32,
    center: Vec3,
    radius: f32,
) -> Mat4 {
    let view = Mat4::look_at_rh(eye, target, up);
    let dist = eye.distance(center);
    let far = (dist + radius * 1.5).max(1e-3);
    let near = (dist - radius * 1.5).max(far * 1e-4);
    Mat4::perspective_rh(fov_y_deg.to_radians(), aspect, near, far) * view
}
