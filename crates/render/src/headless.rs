//! The headless host: what `furbake preview`, the examples and the tests draw with, built on the
//! same middleware calls a game makes ([`FurRenderer::prepare`] / [`FurRenderer::render`] and
//! their blade and scene twins). [`HeadlessGpu`] makes a device without a window (any adapter: a
//! GPU, else a software one such as Mesa's lavapipe) with one [`PipelineCache`];
//! [`RenderTarget`] is an offscreen colour + depth target of fixed formats ([`COLOR_FORMAT`],
//! [`DEPTH_FORMAT`], one sample; [`RenderTarget::desc`]) whose frames this host records, submits
//! and reads back ([`read_back`]). Unlike the middleware path, everything here submits, and
//! readbacks wait (through `crate::blocking`). Several renderers in one headless frame:
//! [`crate::SceneFrame::render`] of [`SceneObject`]s.

use furbake_runtime::Pack;

use crate::{
    BladeRenderSettings, BladeRenderer, FurAsset, FurRenderer, PipelineCache, RenderError, RenderSettings, View,
};

pub use crate::scene::SceneObject;
pub use crate::target::{COLOR_FORMAT, DEPTH_FORMAT, RenderTarget};

/// The command that installs a software Vulkan driver on Debian/Ubuntu machines without a GPU.
pub const LAVAPIPE_HINT: &str =
    "apt-get update && apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1";

/// A device and queue created without a window. wgpu's default reaction to an error outside an
/// error scope is a panic, and a lost device only logs; this host records both instead, and
/// [`HeadlessGpu::check`] turns them into typed errors, so no GPU failure aborts the process.
pub struct HeadlessGpu {
    /// The adapter's name, backend and driver (for logs and reports).
    pub info: wgpu::AdapterInfo,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The pipelines of every renderer drawn on this device.
    pipelines: PipelineCache,
    /// Errors wgpu raised outside any error scope, and a lost device, in order.
    failures: std::sync::Arc<std::sync::Mutex<Vec<RenderError>>>,
}

impl HeadlessGpu {
    /// Requests a hardware adapter, then a fallback (software) one, and a device with no optional
    /// features and the WebGPU default limits (the renderer uses only core features: R8 and
    /// RGBA8 textures, Depth32Float, storage buffers in vertex shaders). Blocks (pollster).
    pub fn new() -> Result<HeadlessGpu, RenderError> {
        Self::build(false, wgpu::Features::empty())
    }

    /// As [`HeadlessGpu::new`], with those of `features` the adapter has (e.g.
    /// `PIPELINE_STATISTICS_QUERY` for a host that counts fragment invocations; check
    /// `device.features()` for what was granted).
    pub fn with_optional_features(features: wgpu::Features) -> Result<HeadlessGpu, RenderError> {
        Self::build(false, features)
    }

    /// As [`HeadlessGpu::new`], with the adapter's largest buffer and storage binding sizes in
    /// place of the default 256 MiB and 128 MiB: for blade fields of more than about 2.8 M blades
    /// (48 bytes per blade instance), as a host with large fields requests them.
    pub fn with_large_buffers() -> Result<HeadlessGpu, RenderError> {
        Self::build(true, wgpu::Features::empty())
    }

    fn build(large_buffers: bool, optional_features: wgpu::Features) -> Result<HeadlessGpu, RenderError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let mut errors = Vec::new();
        let mut adapter = None;
        for force_fallback_adapter in [false, true] {
            let options = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter,
                compatible_surface: None,
                ..Default::default()
            };
            match crate::blocking::block_on(instance.request_adapter(&options)) {
                Ok(a) => {
                    adapter = Some(a);
                    break;
                }
                Err(e) => errors.push(e.to_string()),
            }
        }
        let adapter = adapter.ok_or_else(|| RenderError::NoAdapter { detail: errors.join("; ") })?;
        let mut required_limits = wgpu::Limits::default();
        if large_buffers {
            let available = adapter.limits();
            required_limits.max_buffer_size = available.max_buffer_size;
            required_limits.max_storage_buffer_binding_size = available.max_storage_buffer_binding_size;
        }
        let (device, queue) = crate::blocking::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("furbake headless device"),
            required_features: adapter.features() & optional_features,
            required_limits,
            ..Default::default()
        }))?;
        let failures = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink = std::sync::Arc::clone(&failures);
        device.on_uncaptured_error(std::sync::Arc::new(move |e: wgpu::Error| {
            let mut list = sink.lock().unwrap_or_else(|p| p.into_inner());
            list.push(crate::typed_gpu_error(e, "outside any error scope"));
        }));
        let sink = std::sync::Arc::clone(&failures);
        device.set_device_lost_callback(move |reason, message| {
            // Dropping the device at the end of a run also "loses" it; only other reasons count.
            if reason != wgpu::DeviceLostReason::Destroyed {
                let mut list = sink.lock().unwrap_or_else(|p| p.into_inner());
                list.push(RenderError::DeviceLost { what: format!("{reason:?}: {message}") });
            }
        });
        let pipelines = PipelineCache::with_adapter(&device, &adapter);
        Ok(HeadlessGpu { info: adapter.get_info(), device, queue, pipelines, failures })
    }

    /// The pipeline cache of this device: pass it to every renderer so they share pipelines.
    pub fn pipelines(&self) -> &PipelineCache {
        &self.pipelines
    }

    /// The first GPU failure recorded since the last check (an error outside any error scope,
    /// or a lost device), as a typed error; `Ok` when there was none.
    pub fn check(&self) -> Result<(), RenderError> {
        let mut list = self.failures.lock().unwrap_or_else(|p| p.into_inner());
        if list.is_empty() {
            return Ok(());
        }
        Err(list.remove(0))
    }
}

impl FurRenderer {
    /// The headless host's frame: prepares this renderer with `view` (identity model), clears
    /// `target` to [`RenderSettings::background`], renders, and submits. Returns once the work is
    /// submitted (see [`read_back`]). The renderer must be built for [`RenderTarget::desc`].
    pub fn render_to(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        view: &View,
    ) -> Result<(), RenderError> {
        target.check_renderer(self.target())?;
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake frame") });
        self.prepare(queue, &mut encoder, &view.uniforms(target.width, target.height));
        self.render(&mut target.begin_pass(&mut encoder, "furbake fur pass", Some(self.settings().background)));
        crate::blocking::submit(queue, [encoder.finish()]);
        Ok(())
    }
}

impl BladeRenderer {
    /// The headless host's frame: prepares this renderer with `view` (identity model), draws every
    /// blade into `target` after clearing it to the linear RGBA `clear` (colour and depth), or over
    /// what it holds with `None` (e.g. after [`FurRenderer::render_to`], depth-tested against
    /// it), and submits. The renderer must be built for [`RenderTarget::desc`].
    pub fn render_to(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        view: &View,
        clear: Option<[f32; 4]>,
    ) -> Result<(), RenderError> {
        target.check_renderer(self.target())?;
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake blade frame") });
        self.prepare(queue, &mut encoder, &view.uniforms(target.width, target.height));
        self.render(&mut target.begin_pass(&mut encoder, "furbake blade pass", clear));
        crate::blocking::submit(queue, [encoder.finish()]);
        Ok(())
    }
}

/// Copies `target`'s colour texture into an image (waits for the GPU).
pub fn read_back(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    target: &RenderTarget,
) -> Result<image::RgbaImage, RenderError> {
    read_back_texture(device, queue, &target.color)
}

/// Copies mip level 0 of a single-sampled 2D `texture` of an RGBA8 format (`Rgba8Unorm` or
/// `Rgba8UnormSrgb`, stored bytes as they are) created with `COPY_SRC` into an image: submits a
/// copy and waits for the GPU. For hosts and tests that read their own output back.
pub fn read_back_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &wgpu::Texture,
) -> Result<image::RgbaImage, RenderError> {
    use wgpu::TextureFormat::{Rgba8Unorm, Rgba8UnormSrgb};
    if !matches!(texture.format(), Rgba8Unorm | Rgba8UnormSrgb)
        || texture.sample_count() != 1
        || !texture.usage().contains(wgpu::TextureUsages::COPY_SRC)
    {
        return Err(RenderError::Parameter {
            what: format!(
                "read_back_texture of a {:?} texture with {} samples and usage {:?} (RGBA8, 1 sample, COPY_SRC)",
                texture.format(),
                texture.sample_count(),
                texture.usage()
            ),
        });
    }
    let (w, h) = (texture.width(), texture.height());
    let row = w * 4;
    let padded_row = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("furbake readback"),
        size: padded_row as u64 * h as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder =
        device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake readback") });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded_row), rows_per_image: Some(h) },
        },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    crate::blocking::submit(queue, [encoder.finish()]);
    crate::blocking::map_for_reading(device, &buffer, "image readback")?;
    let mut pixels = Vec::with_capacity(row as usize * h as usize);
    {
        let view = buffer.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
        for y in 0..h as usize {
            let start = y * padded_row as usize;
            pixels.extend_from_slice(&view[start..start + row as usize]);
        }
    }
    buffer.unmap();
    Ok(image::RgbaImage::from_raw(w, h, pixels).expect("w·h·4 bytes were copied"))
}

/// Renders one frame of `asset` at `width × height` from `view` and reads it back.
pub fn render_image(
    gpu: &HeadlessGpu,
    asset: &FurAsset,
    settings: &RenderSettings,
    view: &View,
    width: u32,
    height: u32,
) -> Result<image::RgbaImage, RenderError> {
    let renderer = FurRenderer::new(gpu.pipelines(), &gpu.queue, asset, settings, &RenderTarget::desc())?;
    let target = RenderTarget::new(&gpu.device, width, height)?;
    renderer.render_to(&gpu.device, &gpu.queue, &target, view)?;
    read_back(&gpu.device, &gpu.queue, &target)
}

/// What `furbake preview PACK` draws: a pack the caller opened (and, as `furbake preview` does,
/// validated with `Pack::verify`: the sections it decoded are drawn, none is decoded again),
/// framed automatically (three-quarter view; an animated pack in its rest pose) and rendered on a
/// new headless device with `options` over the default fur and blade settings (shell count,
/// fins, blending, shading switches), plus its grass blades when it has a blade field (every
/// blade in view at full detail: `GrassCulling::frustum_only`), the options taken as
/// [`options_for_adapter`] says. Reads only the skin mesh, shell
/// atlas, UV map, fin atlas and fin edges (and the blade field and keyframe table, skin weights
/// and morph targets when present).
pub fn render_preview(
    pack: &Pack,
    width: u32,
    height: u32,
    options: &furbake_runtime::RenderOptions,
) -> Result<image::RgbaImage, RenderError> {
    options.validate().map_err(|(field, what)| RenderError::Parameter { what: format!("{field}: {what}") })?;
    let gpu = HeadlessGpu::new()?;
    let options = &options_for_adapter(options, &gpu.info, None);
    let blades = preview_blade_settings().with_options(options);
    render_pack_on(&gpu, pack, width, height, None, &RenderSettings::default().with_options(options), &blades)
}

/// `options` (a command's flags, over `scene`'s keys when it draws a scene) as `furbake preview`
/// and `furbake view` draw with them on the adapter `info` describes: on a software adapter
/// (`DeviceType::Cpu`, such as lavapipe) the atlases are filtered isotropically unless the flags
/// or the scene choose an anisotropy, because there anisotropic filtering cost 1.2–5× a fur
/// frame (docs/performance.md "Anisotropic filtering"), while a GPU filters anisotropically in
/// its texture units.
pub fn options_for_adapter(
    options: &furbake_runtime::RenderOptions,
    info: &wgpu::AdapterInfo,
    scene: Option<&furbake_runtime::Scene>,
) -> furbake_runtime::RenderOptions {
    let chosen = options.anisotropy.is_some()
        || scene.is_some_and(|s| {
            s.render().anisotropy.is_some() || s.packs().iter().any(|p| p.render.anisotropy.is_some())
        });
    let software = info.device_type == wgpu::DeviceType::Cpu;
    match software && !chosen {
        true => furbake_runtime::RenderOptions { anisotropy: Some(1), ..*options },
        false => *options,
    }
}

/// The blade settings of a pack previewed alone: every blade in view at full detail (a pack has
/// no scene to say what its units are — the Fox glTF is in centimetres — so only the frustum
/// culls).
fn preview_blade_settings() -> BladeRenderSettings {
    BladeRenderSettings { culling: crate::GrassCulling::frustum_only(), ..BladeRenderSettings::default() }
}

/// [`render_preview`] with a chosen view (`None`: framed automatically) and fur settings.
pub fn render_pack(
    pack: &Pack,
    width: u32,
    height: u32,
    view: Option<View>,
    settings: &RenderSettings,
) -> Result<image::RgbaImage, RenderError> {
    render_pack_on(&HeadlessGpu::new()?, pack, width, height, view, settings, &preview_blade_settings())
}

fn render_pack_on(
    gpu: &HeadlessGpu,
    pack: &Pack,
    width: u32,
    height: u32,
    view: Option<View>,
    settings: &RenderSettings,
    blade_settings: &BladeRenderSettings,
) -> Result<image::RgbaImage, RenderError> {
    let asset = FurAsset::from_pack(pack, settings.fins)?;
    let rest = rest_pose(pack)?;
    let aspect = width as f32 / height.max(1) as f32;
    let view = view.unwrap_or_else(|| match &rest {
        // An animated pack is framed as it stands in its rest pose, not in raw bind space.
        Some(rest) => {
            View::fit_points(&rest.positions, asset.shells().fur_length_m, aspect, rest.bounding_sphere(&asset))
        }
        None => asset.auto_view(aspect),
    });
    let desc = RenderTarget::desc();
    // The blades of a grass pack, and the ground under them in their colour (as scenes draw it).
    let mut settings = *settings;
    // As many light slots as the view has lights (the shading's cost on lavapipe grows with them).
    settings.light_slots = RenderSettings::light_slots_for(&view.lighting);
    if pack.has(furbake_formats::SectionKind::BLADE_FIELD) && settings.tint == RenderSettings::default().tint {
        settings.tint = blade_settings.ground_tint();
    }
    let settings = &settings;
    let fur = FurRenderer::new(gpu.pipelines(), &gpu.queue, &asset, settings, &desc)?;
    if let (Some(rest), true) = (&rest, fur.is_animated()) {
        fur.set_pose(&gpu.queue, &rest.skinning, &rest.morph_weights)?;
        // Unsheared fur in the posed frame: s = n of the posed skin (eq. 3.35 at rest).
        fur.set_scale_vectors(&gpu.queue, &rest.normals)?;
    }
    // Grass blades, when the pack has a blade field: drawn after the fur, depth-tested against
    // it, in their rest pose (a still preview has no wind).
    let blades = BladeRenderer::from_pack(gpu.pipelines(), &gpu.queue, pack, blade_settings, &desc)?;
    let target = RenderTarget::new(&gpu.device, width, height)?;
    let frame = view.uniforms(target.width, target.height);
    let mut encoder =
        gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake preview") });
    fur.prepare(&gpu.queue, &mut encoder, &frame);
    if let Some(blades) = &blades {
        blades.prepare(&gpu.queue, &mut encoder, &frame);
    }
    {
        let mut pass = target.begin_pass(&mut encoder, "furbake preview", Some(settings.background));
        fur.render(&mut pass);
        if let Some(blades) = &blades {
            blades.render(&mut pass);
        }
    }
    crate::blocking::submit(&gpu.queue, [encoder.finish()]);
    let image = read_back(&gpu.device, &gpu.queue, &target)?;
    gpu.check()?;
    Ok(image)
}

/// An animated pack in its rest pose: the skeleton's node transforms (glTF's rest TRS of every
/// joint, which often carries an export's up-axis rotation) and the default morph weights, as
/// skinning matrices for [`FurRenderer::set_pose`] and as the posed skin positions for framing.
struct RestPose {
    skinning: Vec<glam::Mat4>,
    morph_weights: Vec<f32>,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
}

impl RestPose {
    /// The sphere around the posed skin and its fur (as [`FurAsset::bounding_sphere`] in bind
    /// space).
    fn bounding_sphere(&self, asset: &FurAsset) -> ([f32; 3], f32) {
        use glam::Vec3;
        let (lo, hi) = self
            .positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(Vec3::from(p)), hi.max(Vec3::from(p))));
        let center = (lo + hi) * 0.5;
        let far = self.positions.iter().map(|&p| Vec3::from(p).distance(center)).fold(0.0f32, f32::max);
        (center.to_array(), far + asset.shells().fur_length_m)
    }
}

/// The rest pose of `pack` when it is animated (skin weights or morph targets), `None` for a
/// static pack (docs/design.md "Rendering": a pack alone is drawn as it stands).
fn rest_pose(pack: &Pack) -> Result<Option<RestPose>, RenderError> {
    use furbake_runtime::animation::{Pose, joint_world_matrices, morph_and_skin, skinning_matrices};
    let (weights, morphs) = (pack.skin_weights()?, pack.morph_targets()?);
    if weights.is_none() && morphs.is_none() {
        return Ok(None);
    }
    let skeleton = pack.skeleton()?;
    let mesh = pack.skin_mesh()?;
    let pose = Pose::rest(skeleton.as_deref(), morphs.as_deref());
    let invalid = |e: furbake_runtime::AnimationError| RenderError::InvalidAsset { what: format!("rest pose: {e}") };
    let mut skinning = Vec::new();
    if let (Some(skeleton), Some(_)) = (&skeleton, &weights) {
        let mut world = vec![glam::Mat4::IDENTITY; skeleton.joint_count()];
        joint_world_matrices(skeleton, &pose, &mut world).map_err(invalid)?;
        skinning = vec![glam::Mat4::IDENTITY; skeleton.bind_count()];
        skinning_matrices(skeleton, &world, &mut skinning).map_err(invalid)?;
    }
    let v = mesh.positions.len();
    let (mut positions, mut normals) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
    let morph_input = morphs.as_deref().map(|m| (m, pose.morph_weights.as_slice()));
    morph_and_skin(&mesh, weights.as_deref(), morph_input, &skinning, &mut positions, &mut normals).map_err(invalid)?;
    Ok(Some(RestPose { skinning, morph_weights: pose.morph_weights, positions, normals }))
}
