//! `furbake view`'s GPU host: a window's surface on an adapter that can present to it (a GPU,
//! or Mesa's lavapipe), the offscreen frame the world is drawn into with the render crate's
//! middleware calls (`SceneRenderer::prepare_world` into this host's encoder,
//! `SceneRenderer::render` into this host's pass), and the present pass that copies that frame
//! onto the surface texture texel for texel — so the screenshot, read back from the same frame,
//! is exactly what the window shows.

use std::path::Path;
use std::sync::{Arc, Mutex};

use anyhow::anyhow;
use furbake_render::headless::{COLOR_FORMAT, DEPTH_FORMAT};
use furbake_render::{PipelineCache, RenderError, SceneRenderer, TargetDesc, View};
use furbake_runtime::{RenderOptions, ShellBlendMode, World};
use winit::window::Window;

use crate::failure::Failure;
use crate::preview_cmd::render_failure;

/// The present pass's shader (beside this file).
pub const PRESENT_WGSL: &str = include_str!("present.wgsl");

/// Bytes per window pixel the host's targets take: the frame's colour and depth (4 + 4) and up to
/// three RGBA8 surface textures (the swapchain), for the `--max-memory` estimate.
pub const TARGET_BYTES_PER_PIXEL: u64 = 20;

/// The surface, its device and everything drawn on it.
pub struct Screen {
    /// The window (the surface keeps its own reference).
    pub window: Arc<Window>,
    instance: wgpu::Instance,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    /// The adapter's name and backend, for messages.
    pub adapter: String,
    device: wgpu::Device,
    queue: wgpu::Queue,
    present: PresentPass,
    frame: FrameTarget,
    renderer: SceneRenderer,
    /// What the renderer was built with, to rebuild it when a key switches a render option.
    pipelines: PipelineCache,
    target: TargetDesc,
    /// The render options over the scene's (the command's flags, then the keys).
    options: RenderOptions,
    /// The surface said it no longer matches the window: reconfigure after presenting.
    reconfigure: bool,
    /// wgpu errors raised outside any error scope, and a lost device, in order.
    failures: Arc<Mutex<Vec<String>>>,
}

impl Screen {
    /// Creates a surface on `window`, picks an adapter that can present to it (a hardware one
    /// first, then a fallback one such as lavapipe), a device with the WebGPU default limits
    /// (textures up to the adapter's size), an sRGB surface format where the surface offers one,
    /// the frame targets at the window's size and `world`'s renderers (sharing the world's packs).
    /// `vsync` paces presentation to the display (interactive); without it frames are presented
    /// as soon as they are drawn where the surface allows.
    pub fn new(
        window: Arc<Window>,
        world: &World,
        path: &Path,
        vsync: bool,
        options: RenderOptions,
    ) -> Result<Screen, Failure> {
        let gpu_failure = |what: String| Failure::Input(anyhow!("{}: {what}", path.display()));
        // The display handle is only used by the GLES backend, which this build leaves out.
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle());
        let surface = instance
            .create_surface(Arc::clone(&window))
            .map_err(|e| gpu_failure(format!("cannot create a GPU surface on the window: {e}")))?;
        let mut tried = Vec::new();
        let mut adapter = None;
        for force_fallback_adapter in [false, true] {
            let options = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter,
                compatible_surface: Some(&surface),
                ..Default::default()
            };
            match pollster::block_on(instance.request_adapter(&options)) {
                Ok(a) => {
                    adapter = Some(a);
                    break;
                }
                Err(e) => tried.push(e.to_string()),
            }
        }
        let adapter = adapter.ok_or_else(|| {
            render_failure(
                RenderError::NoAdapter { detail: format!("none can present to this window: {}", tried.join("; ")) },
                path,
            )
        })?;
        let info = adapter.get_info();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("furbake view"),
            required_features: wgpu::Features::empty(),
            required_limits: wgpu::Limits::default().using_resolution(adapter.limits()),
            ..Default::default()
        }))
        .map_err(|e| render_failure(e.into(), path))?;
        let failures = Arc::new(Mutex::new(Vec::new()));
        let sink = Arc::clone(&failures);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            sink.lock().unwrap_or_else(|p| p.into_inner()).push(e.to_string());
        }));
        let sink = Arc::clone(&failures);
        device.set_device_lost_callback(move |reason, message| {
            // Dropping the device when the viewer closes also "loses" it; only other reasons count.
            if reason != wgpu::DeviceLostReason::Destroyed {
                sink.lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .push(format!("the device was lost: {reason:?}: {message}"));
            }
        });

        let size = window.inner_size();
        let (width, height) = (size.width.max(1), size.height.max(1));
        let max = device.limits().max_texture_dimension_2d;
        if width > max || height > max {
            return Err(Failure::Usage(anyhow!(
                "--size {width}x{height}: this adapter ({}) draws at most {max} pixels a side",
                info.name
            )));
        }
        let caps = surface.get_capabilities(&adapter);
        let format = surface_format(&caps.formats).ok_or_else(|| {
            gpu_failure(format!("the window's surface offers no 8-bit colour format: {:?}", caps.formats))
        })?;
        let mut config = surface
            .get_default_config(&adapter, width, height)
            .ok_or_else(|| gpu_failure(format!("the adapter {} cannot present to this window", info.name)))?;
        config.format = format;
        config.present_mode = if vsync { wgpu::PresentMode::AutoVsync } else { wgpu::PresentMode::AutoNoVsync };
        surface.configure(&device, &config);

        // The pass the world is drawn into: the frame's sRGB colour and its depth buffer.
        let target = TargetDesc::new(COLOR_FORMAT).with_depth(DEPTH_FORMAT, wgpu::CompareFunction::LessEqual);
        target.validate(&device, Some(&adapter), true).map_err(|e| render_failure(e, path))?;
        let pipelines = PipelineCache::with_adapter(&device, &adapter);
        // As `furbake preview` draws on this adapter (isotropic atlases on a software one).
        let options = furbake_render::headless::options_for_adapter(&options, &info, Some(world.scene()));
        let renderer = SceneRenderer::for_target_with(&pipelines, &queue, world, &target, &options)
            .map_err(|e| render_failure(e, path))?;
        let present = PresentPass::new(&device, format);
        let frame = FrameTarget::new(&device, &present, width, height);
        let adapter = format!("{} ({:?})", info.name, info.backend);
        let mut screen = Screen {
            window,
            instance,
            surface,
            config,
            adapter,
            device,
            queue,
            present,
            frame,
            renderer,
            pipelines,
            target,
            options,
            reconfigure: false,
            failures,
        };
        screen.occlude_grass().map_err(|e| render_failure(e, path))?;
        screen.check(path)?;
        Ok(screen)
    }

    /// Culls the scene's grass against the depth of what is drawn before it (the fur, and the
    /// grass pack's own ground), at the frame's size: the same picture with fewer blades
    /// (docs/design.md "Depth pyramid and occlusion culling"). For scenes with grass blades.
    fn occlude_grass(&mut self) -> Result<(), RenderError> {
        if self.renderer.packs().iter().any(|p| p.blades.is_some()) {
            let size = self.size();
            self.renderer.set_grass_occlusion(&self.pipelines, Some(size))?;
        }
        Ok(())
    }

    /// The frame's size in pixels (the surface's).
    pub fn size(&self) -> (u32, u32) {
        (self.config.width, self.config.height)
    }

    /// Follows the window to a new size (ignored while it is 0 × 0, e.g. minimised).
    pub fn resize(&mut self, width: u32, height: u32) {
        let max = self.device.limits().max_texture_dimension_2d;
        let (width, height) = (width.min(max), height.min(max));
        if width == 0 || height == 0 || (width, height) == self.size() {
            return;
        }
        (self.config.width, self.config.height) = (width, height);
        self.surface.configure(&self.device, &self.config);
        self.frame = FrameTarget::new(&self.device, &self.present, width, height);
    }

    /// What the first fur pack is drawn with, for the title: its shell count (and the level of
    /// detail's count in the last frame where that is fewer), and the switches
    /// the keys turned from their defaults (`None` without fur).
    pub fn drawn(&self) -> Option<String> {
        let fur = self.renderer.packs().iter().find_map(|p| p.fur.as_ref())?;
        let settings = fur.settings();
        // The level of detail's count in the last frame, of the most it draws.
        let (most, layers) = (fur.drawn_layers(), fur.layers_in_view(0).unwrap_or(fur.drawn_layers()));
        let mut text = if layers < most { format!("{layers} of {most} shells") } else { format!("{most} shells") };
        if !settings.shading.enabled {
            text.push_str(", flat");
        }
        if settings.lod.is_none() {
            text.push_str(", no level of detail");
        }
        if !settings.fins {
            text.push_str(", no fins");
        }
        if settings.blend == furbake_render::ShellBlend::AlphaTest {
            text.push_str(", alpha test");
        }
        Some(text)
    }

    /// Switches a render option from the keyboard and rebuilds the renderers with it (the packs
    /// stay opened; their GPU data is uploaded again): `s` shading (strand and blade shading) off
    /// or on, `f` every fin off or on, `t` alpha blending or the alpha test, `[` and `]` half or
    /// twice the shells drawn, `l` the shells' level of detail off or on. Returns what is drawn now, for the viewer's message.
    pub fn toggle_render(&mut self, key: &str, world: &World) -> Result<String, RenderError> {
        let drawn = self.renderer.packs().iter().find_map(|p| p.fur.as_ref()).map(|f| (f.settings(), f.drawn_layers()));
        let Some((settings, layers)) = drawn else { return Ok("render: this scene has no fur".into()) };
        let mut o = self.options;
        let message = match key {
            "s" => {
                let on = !settings.shading.enabled;
                (o.strand_shading, o.blade_shading) = (Some(on), Some(on));
                if on {
                    "shading: strand and blade shading"
                } else {
                    "shading: flat (Lambert × self-shadow, flat grass)"
                }
                .to_owned()
            }
            "f" => {
                let on = !settings.fins;
                (o.fins, o.silhouette_fins) = (Some(on), Some(on));
                format!("fins: {}", if on { "on (fin edges and silhouette)" } else { "off" })
            }
            "t" => {
                let test = settings.blend == furbake_render::ShellBlend::AlphaBlend;
                o.blend = Some(if test { ShellBlendMode::AlphaTest } else { ShellBlendMode::AlphaBlend });
                // Each mode's own default threshold.
                o.alpha_threshold = None;
                format!("blend: {}", if test { "alpha test" } else { "alpha blending" })
            }
            "[" | "]" => {
                let n = if key == "[" { layers / 2 } else { (layers.max(1) * 2).min(1024) };
                o.shell_layers = Some(n);
                format!("shells: at most {n} drawn")
            }
            "l" => {
                let on = settings.lod.is_none();
                o.lod = Some(on);
                format!("shell level of detail: {}", if on { "on" } else { "off (every layer at any distance)" })
            }
            _ => return Ok(String::new()),
        };
        // The new renderers keep each blade field's culling as the G key left it.
        let culling: Vec<_> = self.renderer.packs().iter().map(|p| p.blades.as_ref().map(|b| *b.culling())).collect();
        self.renderer = SceneRenderer::for_target_with(&self.pipelines, &self.queue, world, &self.target, &o)?;
        self.occlude_grass()?;
        for (pack, culling) in self.renderer.packs_mut().iter_mut().zip(culling) {
            if let (Some(blades), Some(culling)) = (pack.blades.as_mut(), culling) {
                blades.set_culling(&self.queue, culling)?;
            }
        }
        self.options = o;
        Ok(message)
    }

    /// Switches grass culling and distance LOD off, or back to the scene's `[grass_culling]`,
    /// on every grass renderer; returns whether culling is now on, or `None` when the scene has
    /// no grass.
    pub fn toggle_grass_culling(&mut self, world: &furbake_runtime::World) -> Result<Option<bool>, RenderError> {
        let scene = world.scene().grass_culling();
        let mut now = None;
        for pack in self.renderer.packs_mut() {
            if let Some(blades) = pack.blades.as_mut() {
                let on = !blades.culling().enabled;
                let culling = if on { scene } else { furbake_render::GrassCulling::off() };
                blades.set_culling(&self.queue, culling)?;
                now = Some(culling.enabled);
            }
        }
        Ok(now)
    }

    /// The view the renderer frames `world` with: the scene's camera (or the automatic framing
    /// of every pack where the scene has none), near and far planes fitted to the packs.
    pub fn world_view(&self, world: &World) -> View {
        self.renderer.world_view(world)
    }

    /// The next surface texture, or `None` when the surface has none to give this time (timed
    /// out, occluded, or reconfigured because it no longer matched the window): skip the frame.
    pub fn acquire(&mut self, path: &Path) -> Result<Option<wgpu::SurfaceTexture>, Failure> {
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(texture) => Ok(Some(texture)),
            wgpu::CurrentSurfaceTexture::Suboptimal(texture) => {
                self.reconfigure = true;
                Ok(Some(texture))
            }
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => Ok(None),
            wgpu::CurrentSurfaceTexture::Outdated => {
                self.surface.configure(&self.device, &self.config);
                Ok(None)
            }
            wgpu::CurrentSurfaceTexture::Lost => {
                self.surface = self.instance.create_surface(Arc::clone(&self.window)).map_err(|e| {
                    Failure::Input(anyhow!(
                        "{}: the window's surface was lost and cannot be recreated: {e}",
                        path.display()
                    ))
                })?;
                self.surface.configure(&self.device, &self.config);
                Ok(None)
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                self.check(path)?;
                Err(Failure::Input(anyhow!("{}: the surface refused to give a texture", path.display())))
            }
        }
    }

    /// One frame: the world's state uploaded (`prepare_world`) and drawn (`render`) into the
    /// frame from `view`, cleared to the scene's background; the frame copied onto `texture`;
    /// one submission; presented.
    pub fn draw(
        &mut self,
        texture: wgpu::SurfaceTexture,
        world: &World,
        view: &View,
        path: &Path,
    ) -> Result<(), Failure> {
        let (width, height) = self.size();
        if self.renderer.grass_occlusion().is_some_and(|size| size != (width, height)) {
            // The window was resized: the pyramid follows the frame.
            self.occlude_grass().map_err(|e| render_failure(e, path))?;
        }
        let uniforms = view.uniforms(width, height);
        let mut encoder =
            self.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake view") });
        // On an error the encoder is dropped unsubmitted and the texture unpresented.
        self.renderer
            .prepare_world(&self.queue, &mut encoder, world, &uniforms)
            .map_err(|e| render_failure(e, path))?;
        let background = self.renderer.frame().background.map(f64::from);
        if self.renderer.grass_occlusion().is_some() {
            // The fur (and the ground) first, the grass culled against their depth, then drawn.
            self.renderer.render_fur(&mut self.frame.world_pass(&mut encoder, Some(background), true));
            self.renderer
                .prepare_grass(&self.device, &mut encoder, &self.frame.depth)
                .map_err(|e| render_failure(e, path))?;
            self.renderer.render_grass(&mut self.frame.world_pass(&mut encoder, None, false));
        } else {
            self.renderer.render(&mut self.frame.world_pass(&mut encoder, Some(background), false));
        }
        let surface_view = texture.texture.create_view(&Default::default());
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("furbake view present"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &surface_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.present.pipeline);
            pass.set_bind_group(0, &self.frame.present_group, &[]);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.window.pre_present_notify();
        self.queue.present(texture);
        if std::mem::take(&mut self.reconfigure) {
            self.surface.configure(&self.device, &self.config);
        }
        self.check(path)
    }

    /// The last frame drawn, as an opaque image (what the window shows): read back from the
    /// frame's colour texture (waits for the GPU).
    pub fn screenshot(&self, path: &Path) -> Result<image::RgbaImage, Failure> {
        let mut image = furbake_render::headless::read_back_texture(&self.device, &self.queue, &self.frame.color)
            .map_err(|e| render_failure(e, path))?;
        // The present pass writes alpha 1: so does the screenshot.
        image.pixels_mut().for_each(|p| p.0[3] = 255);
        self.check(path)?;
        Ok(image)
    }

    /// The first GPU failure recorded outside an error scope, as bad input naming `path`.
    fn check(&self, path: &Path) -> Result<(), Failure> {
        let list = self.failures.lock().unwrap_or_else(|p| p.into_inner());
        match list.first() {
            None => Ok(()),
            Some(e) => Err(Failure::Input(anyhow!("{}: GPU error: {e}", path.display()))),
        }
    }
}

/// The surface format: the first sRGB 8-bit format offered, else the first 8-bit unorm one
/// (the present pass then copies the frame's encoded bytes as they are). `None` when neither is
/// offered (e.g. only float or 10-bit formats).
pub fn surface_format(offered: &[wgpu::TextureFormat]) -> Option<wgpu::TextureFormat> {
    use wgpu::TextureFormat::{Bgra8Unorm, Bgra8UnormSrgb, Rgba8Unorm, Rgba8UnormSrgb};
    let srgb = offered.iter().find(|f| matches!(f, Bgra8UnormSrgb | Rgba8UnormSrgb));
    srgb.or_else(|| offered.iter().find(|f| matches!(f, Bgra8Unorm | Rgba8Unorm))).copied()
}

/// The present pass: one triangle over the surface loading the frame's texel under each pixel.
struct PresentPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::RenderPipeline,
    /// Whether the surface format is sRGB: the frame is then bound through its sRGB view (decoded
    /// here, encoded again on store), else through its plain view (bytes copied as stored).
    srgb: bool,
}

impl PresentPass {
    fn new(device: &wgpu::Device, surface_format: wgpu::TextureFormat) -> PresentPass {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("furbake view present"),
            source: wgpu::ShaderSource::Wgsl(PRESENT_WGSL.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("furbake view present"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake view present"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("furbake view present"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_cover"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_copy"),
                compilation_options: Default::default(),
                targets: &[Some(surface_format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        PresentPass { layout, pipeline, srgb: surface_format.is_srgb() }
    }
}

/// The frame the world is drawn into, the window's size: colour ([`COLOR_FORMAT`], read by the
/// present pass and copied for the screenshot) and depth ([`DEPTH_FORMAT`]).
struct FrameTarget {
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    /// Also read by the grass occlusion's depth pyramid (`SceneRenderer::prepare_grass`).
    depth: wgpu::Texture,
    depth_view: wgpu::TextureView,
    /// The present pass's binding of `color`.
    present_group: wgpu::BindGroup,
}

impl FrameTarget {
    /// A pass into the frame's colour and depth: cleared to `clear` (and depth 1), or loading
    /// what an earlier pass of the frame drew; its depth kept for a later pass when `keep_depth`.
    fn world_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        clear: Option<[f64; 4]>,
        keep_depth: bool,
    ) -> wgpu::RenderPass<'e> {
        let store = if keep_depth { wgpu::StoreOp::Store } else { wgpu::StoreOp::Discard };
        let (color, depth) = match clear {
            Some([r, g, b, a]) => (wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }), wgpu::LoadOp::Clear(1.0)),
            None => (wgpu::LoadOp::Load, wgpu::LoadOp::Load),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("furbake view world"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: color, store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth_view,
                depth_ops: Some(wgpu::Operations { load: depth, store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    fn new(device: &wgpu::Device, present: &PresentPass, width: u32, height: u32) -> FrameTarget {
        let raw = COLOR_FORMAT.remove_srgb_suffix();
        let texture = |label, format, usage, view_formats| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats,
            })
        };
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::TEXTURE_BINDING
            | wgpu::TextureUsages::COPY_SRC;
        let raw_formats = [raw];
        let color = texture("furbake view colour", COLOR_FORMAT, usage, &raw_formats[..]);
        let depth_usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING;
        let depth = texture("furbake view depth", DEPTH_FORMAT, depth_usage, &[][..]);
        let color_view = color.create_view(&Default::default());
        let present_view = match present.srgb {
            true => color.create_view(&Default::default()),
            false => color.create_view(&wgpu::TextureViewDescriptor { format: Some(raw), ..Default::default() }),
        };
        let present_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("furbake view present"),
            layout: &present.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&present_view),
            }],
        });
        let depth_view = depth.create_view(&Default::default());
        FrameTarget { color, color_view, depth, depth_view, present_group }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_present_shader_validates() {
        let module =
            naga::front::wgsl::parse_str(PRESENT_WGSL).unwrap_or_else(|e| panic!("{}", e.emit_to_string(PRESENT_WGSL)));
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::empty())
            .validate(&module)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(PRESENT_WGSL)));
        let entry_points: Vec<&str> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(entry_points, ["vs_cover", "fs_copy"]);
    }

    #[test]
    fn surface_format_prefers_srgb_then_8_bit_unorm() {
        use wgpu::TextureFormat::*;
        let cases = [
            (vec![Bgra8Unorm, Bgra8UnormSrgb], Some(Bgra8UnormSrgb)),
            (vec![Rgb10a2Unorm, Rgba8UnormSrgb, Bgra8UnormSrgb], Some(Rgba8UnormSrgb)),
            (vec![Rgba16Float, Bgra8Unorm], Some(Bgra8Unorm)),
            (vec![Rgba16Float, Rgb10a2Unorm], None),
            (vec![], None),
        ];
        for (offered, expected) in &cases {
            assert_eq!(surface_format(offered), *expected, "{offered:?}");
        }
        assert_eq!(cases.len(), 5);
    }
}
