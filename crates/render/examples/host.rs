//! furbake inside a host renderer (the wgpu middleware pattern), end to end: the host owns the
//! device, an MSAA 4× HDR colour target (`Rgba16Float`) with its own depth buffer, and draws its
//! own world — a ground plane and a box — then, in the same render pass and against the same
//! depth buffer, the Fox's fur and a grass field (the grass patch's shells and blades) through
//! furbake-render's middleware calls (`prepare` into the host's encoder, `render` into the host's
//! pass); it resolves the MSAA target, tonemaps it into an sRGB image and writes a PNG:
//!
//! `cargo run -p furbake-render --example host -- [OUT.png [WIDTH HEIGHT]]` (default `host.png`,
//! 640×480).
//!
//! The packs are baked in-process from the bundled glTF files (`fixtures/real/Fox.glb` with the
//! `fur` preset, `fixtures/generated/grass_patch.gltf` with the `grass` preset and blades), so it
//! runs from a fresh clone. `tests/host.rs` includes this file and runs the same host for the
//! occlusion, format, MSAA and no-submit tests.

#![allow(dead_code)] // `tests/host.rs` includes this file and uses items `main` does not.

use std::error::Error;
use std::path::Path;

use furbake_bake::settings::dotted_override;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::SceneFrame;
use furbake_render::headless::{HeadlessGpu, SceneObject, read_back_texture};
use furbake_render::{
    BladeRenderSettings, BladeRenderer, FurAsset, FurRenderer, PipelineCache, RenderSettings, TargetDesc, View,
};
use furbake_runtime::ShellVertexLayout;
use furbake_runtime::{Camera, Light, LightSource, Pack};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

/// Errors of the example (it is a program, not a library).
pub type AnyError = Box<dyn Error>;

/// The host's own shaders: its geometry and the tonemap pass.
pub const HOST_WGSL: &str = include_str!("host.wgsl");
/// The host's depth buffer format.
pub const HOST_DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The tonemapped output image's format.
pub const OUTPUT_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Linear RGB of the host's box (blue: no fur or grass colour comes close).
pub const BOX_COLOR: [f32; 3] = [0.08, 0.16, 0.85];
/// Linear RGB of the host's ground plane.
pub const GROUND_COLOR: [f32; 3] = [0.30, 0.24, 0.16];

fn main() -> Result<(), AnyError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.first().map_or("host.png", String::as_str);
    let width = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(640);
    let height = args.get(2).map(|s| s.parse()).transpose()?.unwrap_or(480);
    // Any wgpu device works; the headless one stands in for the engine's.
    let gpu = HeadlessGpu::new()?;
    let packs = bake_packs(32, 150.0)?;
    let options = HostOptions { width, height, ..HostOptions::default() };
    let furbake = Furbake::new(gpu.pipelines(), &gpu.queue, &packs, &options.target_desc())?;
    let placement = Placement::new(&furbake);
    let image = render_image(&gpu, Some(&furbake), &placement, &options)?;
    gpu.check()?;
    image.save(out)?;
    println!("{out}: {width}×{height}, {:?} × {} samples, tonemapped to sRGB", options.format, options.samples);
    Ok(())
}

/// The two packs, baked in-process into a temporary folder and opened as a game would.
pub struct Packs {
    _dir: tempfile::TempDir,
    /// The Fox (`fur` preset, skinned: its renderer owns a skinning pass, here in the bind pose).
    pub fox: Pack,
    /// The grass patch (`grass` preset: shells plus a blade field).
    pub grass: Pack,
}

/// Bakes the Fox with `fur_layers` shells and the grass patch with `blades_per_m2` blades.
pub fn bake_packs(fur_layers: u32, blades_per_m2: f32) -> Result<Packs, AnyError> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let dir = tempfile::tempdir()?;
    let bake_one = |gltf: &str, preset: &str, set: String, name: &str| -> Result<Pack, AnyError> {
        let mesh = import_gltf(&root.join(gltf), &ImportSettings::default())?;
        let plan = BakeSettings::preset(preset)?.with_overrides(&dotted_override(&set)?)?.plan()?;
        let baked = bake(&mesh, name, &plan, &mut NoProgress)?;
        let path = dir.path().join(format!("{name}.fbk"));
        baked.to_writer().write_atomic(&path)?;
        Ok(Pack::open(&path)?)
    };
    let fox = bake_one("fixtures/real/Fox.glb", "fur", format!("volume.layers={fur_layers}"), "fox")?;
    let grass = bake_one(
        "fixtures/generated/grass_patch.gltf",
        "grass",
        format!("blades.field.density_per_m2={blades_per_m2}"),
        "grass_patch",
    )?;
    Ok(Packs { _dir: dir, fox, grass })
}

/// furbake's part of the host: three renderers built for the host's pass, sharing one pipeline
/// cache. Drawn grass first (the patch's shells, then its blades), the Fox last, so the Fox's
/// blended shells fall over grass already drawn.
pub struct Furbake {
    /// The Fox's fur.
    pub fox: FurRenderer,
    /// The grass patch's shells.
    pub patch: FurRenderer,
    /// The grass patch's blades.
    pub blades: BladeRenderer,
}

impl Furbake {
    /// Builds the renderers for passes like `target`.
    pub fn new(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        packs: &Packs,
        target: &TargetDesc,
    ) -> Result<Furbake, AnyError> {
        let settings = RenderSettings::default();
        let fox = FurRenderer::new(pipelines, queue, &FurAsset::from_pack(&packs.fox, true)?, &settings, target)?;
        // The patch's vertex colours are white: tinted to a dry-grass green.
        let grass = RenderSettings { tint: [0.45, 0.6, 0.3], ..settings };
        let patch = FurRenderer::new(pipelines, queue, &FurAsset::from_pack(&packs.grass, true)?, &grass, target)?;
        let blades = BladeRenderer::from_pack(pipelines, queue, &packs.grass, &BladeRenderSettings::default(), target)?
            .ok_or("the grass patch has no blade field")?;
        Ok(Furbake { fox, patch, blades })
    }

    /// The three objects at their placements, in drawing order (what the headless host draws
    /// for comparison).
    pub fn objects(&self, placement: &Placement) -> [SceneObject<'_>; 3] {
        let fur = |renderer, model| SceneObject::Fur {
            renderer,
            model,
            scale_vectors: None,
            scale_layout: ShellVertexLayout::PerVertex,
        };
        [
            fur(&self.patch, placement.grass_model),
            SceneObject::Blades { renderer: &self.blades, model: placement.grass_model, forces: None },
            fur(&self.fox, placement.fox_model),
        ]
    }

    /// The middleware's upload: this frame's uniforms per object, and the Fox's skinning
    /// dispatch recorded into the host's `encoder`. Nothing is submitted.
    pub fn prepare(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        placement: &Placement,
        (width, height): (u32, u32),
    ) {
        let frame = placement.view.uniforms(width, height);
        self.patch.prepare(queue, encoder, &frame.with_model(placement.grass_model));
        self.blades.prepare(queue, encoder, &frame.with_model(placement.grass_model));
        self.fox.prepare(queue, encoder, &frame.with_model(placement.fox_model));
    }

    /// The middleware's draw into the host's pass.
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        self.patch.render(pass);
        self.blades.render(pass);
        self.fox.render(pass);
    }
}

/// Where everything is (metres, glTF axes: +Y up): the Fox (centimetres in its file) scaled to
/// metres and turned side-on as in `fixtures/scenes/demo_fox_and_grass.toml`, the 4 m grass patch
/// scaled to 2 m, the camera of that scene, and the host's box between the camera and the Fox.
pub struct Placement {
    /// Camera and light, near and far planes fitted around the Fox and the grass: the host draws
    /// its own geometry with [`View::view_proj`] of it, furbake with [`View::uniforms`].
    pub view: View,
    /// The Fox's model matrix.
    pub fox_model: Mat4,
    /// The grass patch's model matrix.
    pub grass_model: Mat4,
    /// Centre of the host's box.
    pub box_center: Vec3,
    /// Half its edge, metres.
    pub box_half_m: f32,
}

impl Placement {
    /// The placement of `furbake`'s objects (their bounding spheres fit the near and far planes).
    pub fn new(furbake: &Furbake) -> Placement {
        let camera = Camera { eye: [1.6, 1.0, 2.2], target: [0.0, 0.3, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 };
        let mut placement = Placement {
            view: View::framing([0.0; 3], 1.0),
            fox_model: Mat4::from_rotation_y(90f32.to_radians()) * Mat4::from_scale(Vec3::splat(0.01)),
            grass_model: Mat4::from_scale(Vec3::splat(0.5)),
            box_center: Vec3::ZERO,
            box_half_m: 0.0,
        };
        let frame = SceneFrame { camera: Some(camera), lighting: Light::default().into(), background: [0.0; 4] };
        placement.view = frame.view(&furbake.objects(&placement));
        // The box: between the camera and the Fox's centre, a fifth of the Fox's size.
        let (center, radius) = furbake.fox.bounding_sphere();
        let fox_center = placement.fox_model.transform_point3(Vec3::from(center));
        let eye = Vec3::from(camera.eye);
        placement.box_center = fox_center + (eye - fox_center) * 0.4;
        placement.box_half_m = radius * 0.01 * 0.2;
        placement
    }
}

/// What the host draws and into what.
#[derive(Clone, Debug)]
pub struct HostOptions {
    /// Output size in pixels.
    pub width: u32,
    /// Output height in pixels.
    pub height: u32,
    /// The host's colour target format (default `Rgba16Float`, HDR).
    pub format: wgpu::TextureFormat,
    /// Its sample count (default 4).
    pub samples: u32,
    /// Draw the ground plane.
    pub ground: bool,
    /// Draw the box.
    pub r#box: bool,
    /// Linear RGBA the colour target is cleared to (default a sky blue).
    pub clear: [f32; 4],
}

impl Default for HostOptions {
    fn default() -> Self {
        HostOptions {
            width: 640,
            height: 480,
            format: wgpu::TextureFormat::Rgba16Float,
            samples: 4,
            ground: true,
            r#box: true,
            clear: [0.45, 0.62, 0.85, 1.0],
        }
    }
}

impl HostOptions {
    /// The pass furbake draws into: the host's colour format and sample count, its depth buffer
    /// compared `LessEqual`.
    pub fn target_desc(&self) -> TargetDesc {
        TargetDesc::new(self.format)
            .with_depth(HOST_DEPTH_FORMAT, wgpu::CompareFunction::LessEqual)
            .with_samples(self.samples)
    }
}

/// One vertex of the host's geometry (`GeometryIn` in `host.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct HostVertex {
    position: [f32; 3],
    normal: [f32; 3],
    color: [f32; 3],
}

/// The host's camera uniform (`Camera` in `host.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct HostCamera {
    view_proj: [[f32; 4]; 4],
    light_dir: [f32; 4],
}

/// The host renderer: its targets, its geometry pipeline and buffers, its tonemap pass.
pub struct Host {
    options: HostOptions,
    /// The colour attachment (multisampled when `samples > 1`).
    color: wgpu::Texture,
    /// The single-sampled resolve of `color` (when multisampled).
    resolve: Option<wgpu::Texture>,
    depth: wgpu::Texture,
    output: wgpu::Texture,
    camera: wgpu::Buffer,
    camera_group: wgpu::BindGroup,
    geometry: wgpu::RenderPipeline,
    vertices: wgpu::Buffer,
    ground_vertices: u32,
    box_vertices: u32,
    tonemap: wgpu::RenderPipeline,
    tonemap_group: wgpu::BindGroup,
}

impl Host {
    /// Creates the host's targets at the options' size and its pipelines.
    pub fn new(device: &wgpu::Device, options: &HostOptions, placement: &Placement) -> Host {
        let texture = |label, format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: options.width, height: options.height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let sampled = attach | wgpu::TextureUsages::TEXTURE_BINDING;
        let multisampled = options.samples > 1;
        let color_usage = if multisampled { attach } else { sampled };
        let color = texture("host colour", options.format, options.samples, color_usage);
        let resolve = multisampled.then(|| texture("host resolve", options.format, 1, sampled));
        let depth = texture("host depth", HOST_DEPTH_FORMAT, options.samples, attach);
        let output = texture("host output", OUTPUT_FORMAT, 1, attach | wgpu::TextureUsages::COPY_SRC);

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("host"),
            source: wgpu::ShaderSource::Wgsl(HOST_WGSL.into()),
        });
        let camera = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("host camera"),
            size: std::mem::size_of::<HostCamera>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let camera_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("host camera"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let camera_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("host camera"),
            layout: &camera_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: camera.as_entire_binding() }],
        });
        let layout = |label, group: &wgpu::BindGroupLayout| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(group)],
                immediate_size: 0,
            })
        };
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x3];
        let geometry = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("host geometry"),
            layout: Some(&layout("host geometry", &camera_layout)),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_geometry"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<HostVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            primitive: Default::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: HOST_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: wgpu::MultisampleState { count: options.samples, ..Default::default() },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_geometry"),
                compilation_options: Default::default(),
                targets: &[Some(options.format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let (mut mesh, ground_vertices) = (ground(), 6);
        mesh.extend(cube(placement.box_center, placement.box_half_m));
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("host geometry"),
            contents: bytemuck::cast_slice(&mesh),
            usage: wgpu::BufferUsages::VERTEX,
        });

        let hdr_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("host tonemap"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let resolved = resolve.as_ref().unwrap_or(&color).create_view(&Default::default());
        let tonemap_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("host tonemap"),
            layout: &hdr_layout,
            entries: &[wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::TextureView(&resolved) }],
        });
        let tonemap = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("host tonemap"),
            layout: Some(&layout("host tonemap", &hdr_layout)),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_fullscreen"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_tonemap"),
                compilation_options: Default::default(),
                targets: &[Some(OUTPUT_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        Host {
            options: options.clone(),
            color,
            resolve,
            depth,
            output,
            camera,
            camera_group,
            geometry,
            vertices,
            ground_vertices,
            box_vertices: (mesh.len() - ground_vertices as usize) as u32,
            tonemap,
            tonemap_group,
        }
    }

    /// Width / height of the host's targets.
    pub fn aspect(&self) -> f32 {
        self.options.width as f32 / self.options.height as f32
    }

    /// The tonemapped sRGB output (`COPY_SRC`).
    pub fn output(&self) -> &wgpu::Texture {
        &self.output
    }

    /// Records the host's whole frame into `encoder`: its camera uniform, furbake's `prepare`,
    /// one render pass (clear; the host's ground and box; furbake's `render` against the same
    /// depth buffer; the MSAA resolve at its end), and the tonemap pass. Submits nothing.
    pub fn encode_frame(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        placement: &Placement,
        furbake: Option<&Furbake>,
    ) {
        // The host lights its own geometry with furbake's first light (a directional one here)
        // and the ambient from above.
        let lighting = &placement.view.lighting;
        let to_light = match lighting.sources().first() {
            Some(LightSource::Directional { direction, .. }) => -Vec3::from(*direction).normalize_or(Vec3::NEG_Y),
            _ => Vec3::Y,
        };
        let camera = HostCamera {
            view_proj: placement.view.view_proj(self.aspect()).to_cols_array_2d(),
            light_dir: [to_light.x, to_light.y, to_light.z, lighting.ambient.sky[0]],
        };
        queue.write_buffer(&self.camera, 0, bytemuck::bytes_of(&camera));
        if let Some(furbake) = furbake {
            furbake.prepare(queue, encoder, placement, (self.options.width, self.options.height));
        }
        let color = self.color.create_view(&Default::default());
        let resolve = self.resolve.as_ref().map(|t| t.create_view(&Default::default()));
        let depth = self.depth.create_view(&Default::default());
        {
            let [r, g, b, a] = self.options.clear.map(f64::from);
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("host world"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &color,
                    depth_slice: None,
                    resolve_target: resolve.as_ref(),
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                        // The multisampled samples are not needed once resolved.
                        store: if resolve.is_some() { wgpu::StoreOp::Discard } else { wgpu::StoreOp::Store },
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &depth,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.geometry);
            pass.set_bind_group(0, &self.camera_group, &[]);
            pass.set_vertex_buffer(0, self.vertices.slice(..));
            if self.options.ground {
                pass.draw(0..self.ground_vertices, 0..1);
            }
            if self.options.r#box {
                pass.draw(self.ground_vertices..self.ground_vertices + self.box_vertices, 0..1);
            }
            if let Some(furbake) = furbake {
                furbake.render(&mut pass);
            }
        }
        let output = self.output.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("host tonemap"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &output,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: wgpu::LoadOp::Clear(wgpu::Color::BLACK), store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.tonemap);
        pass.set_bind_group(0, &self.tonemap_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

/// One whole host frame: a new [`Host`] for `options`, its frame recorded, submitted by the host
/// (the only submission), and the tonemapped image read back.
pub fn render_image(
    gpu: &HeadlessGpu,
    furbake: Option<&Furbake>,
    placement: &Placement,
    options: &HostOptions,
) -> Result<image::RgbaImage, AnyError> {
    let host = Host::new(&gpu.device, options, placement);
    let mut encoder = gpu.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("host frame") });
    host.encode_frame(&gpu.queue, &mut encoder, placement, furbake);
    gpu.queue.submit([encoder.finish()]);
    Ok(read_back_texture(&gpu.device, &gpu.queue, host.output())?)
}

/// A 8 m ground square at y = −3 mm (just under the grass patch's skin, so the two do not fight
/// for depth), two triangles.
fn ground() -> Vec<HostVertex> {
    let (y, s) = (-0.003, 4.0);
    let v = |x: f32, z: f32| HostVertex { position: [x, y, z], normal: [0.0, 1.0, 0.0], color: GROUND_COLOR };
    vec![v(-s, -s), v(-s, s), v(s, s), v(-s, -s), v(s, s), v(s, -s)]
}

/// An axis-aligned cube, 36 vertices with face normals.
fn cube(center: Vec3, half: f32) -> Vec<HostVertex> {
    let mut out = Vec::with_capacity(36);
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3::ZERO;
            n[axis] = sign;
            // Two unit vectors spanning the face.
            let a = if axis == 0 { Vec3::Y } else { Vec3::X };
            let b = n.cross(a);
            let corner = |s: f32, t: f32| HostVertex {
                position: (center + (n + a * s + b * t) * half).to_array(),
                normal: n.to_array(),
                color: BOX_COLOR,
            };
            out.extend([corner(-1.0, -1.0), corner(1.0, -1.0), corner(1.0, 1.0)]);
            out.extend([corner(-1.0, -1.0), corner(1.0, 1.0), corner(-1.0, 1.0)]);
        }
    }
    out
}
