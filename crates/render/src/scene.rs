//! Scene frames: several furry packs and grass blade fields drawn into one render pass per
//! frame, each placed by its own model matrix, seen from the camera and lit by the light of a
//! `furbake_runtime::Scene` (fur thesis §3.2 for the fur passes, grass thesis §4.2 for the blades).
//! Physics is an input: per fur pack the frame's scale vectors (eq. 3.35, in the pack's mesh
//! frame; per welded vertex, or per triangle corner when a separable topology parts the fur,
//! §3.4.1 — `furbake_runtime::ShellVertexLayout`),
//! per grass pack the frame's cluster corner forces (eq. 3.6, `(x, z)` in the pack frame)
//! or a `ForceField`.
//!
//! Two levels:
//! - [`SceneFrame::render`] draws borrowed [`SceneObject`]s (a [`FurRenderer`] or a
//!   [`BladeRenderer`] with a model matrix and optional per-frame physics input) into a headless
//!   [`RenderTarget`] in one pass and one submission, cleared first.
//! - [`SceneRenderer`] owns the renderers of every pack of a running `furbake_runtime::World`,
//!   built from the world's own opened packs (their decoded sections are shared, nothing is read
//!   twice) with the shader features the scene's effects need, all from one [`PipelineCache`]
//!   for one [`TargetDesc`]. As middleware in a host's frame, [`SceneRenderer::prepare_world`]
//!   uploads the world's current state — model matrices, skin poses, fur scale vectors in the
//!   world's layout, grass corner forces plus the per-blade wind of delayed-attenuation sources
//!   (grass thesis §4.2) — in one `queue.write_buffer` for all packs, copied into place by
//!   commands it records into the host's encoder before the frame's compute passes (skinning,
//!   silhouette fin selection, blade culling; docs/design.md "One upload per frame"), and
//!   [`SceneRenderer::render`] draws every pack into the host's pass; neither submits or waits
//!   ([`SceneRenderer::prepare`] takes explicit per-pack [`PackInput`]s instead of a world).
//!   [`SceneRenderer::render_world`] and [`SceneRenderer::render_frame`] are the headless host of
//!   those calls (`furbake preview`): one cleared [`RenderTarget`] pass per frame, submitted.

use std::path::PathBuf;

use furbake_formats::SectionKind;
use furbake_runtime::{Camera, Lighting, RenderOptions, Scene, ShellVertexLayout, World};
use furbake_sim::ForceSet;
use glam::{Mat4, Vec3};

use crate::shaders::FrameUniforms;
use crate::target::RenderTarget;
use crate::upload::{FrameUpload, Upload};
use crate::{
    BladeForces, BladeRenderSettings, BladeRenderer, DepthPyramid, FurAsset, FurGpuAsset, FurRenderer, GpuFurPhysics,
    GpuPhysicsStats, GpuPose, GpuSkin, GpuStep, PipelineCache, RenderError, RenderSettings, TargetDesc, View,
};

/// The fixed GPU (or, on lavapipe, host) memory of one fur or blade renderer beyond its data —
/// uniform buffers, bind groups, its share of the pipeline cache. Measured on lavapipe with
/// renderers sharing their pipelines ([`PipelineCache`]) and each pack's uploaded data
/// ([`FurGpuAsset`], [`BladeRenderer::instance`]): scenes of 1, 50 and 500 entries of the Fox took
/// 101, 209 and 588 MB resident (`/usr/bin/time -v furbake preview SCENE -o x.png --size 64x64`),
/// 0.84 MiB per entry from 50 to 500, all of its data included; 500 Fox plus 500 grass-patch
/// entries (1,500 renderers) took 585 MB. One MiB per renderer bounds that.
pub const RENDERER_OVERHEAD_BYTES: u64 = 1 << 20;

/// One object of a scene frame.
pub enum SceneObject<'a> {
    /// A furry pack.
    Fur {
        /// Its renderer.
        renderer: &'a FurRenderer,
        /// Object (mesh) frame → world: rotation, translation, uniform positive scale.
        model: Mat4,
        /// This frame's scale vectors (mesh frame, indexed as `scale_layout` says), or `None` to
        /// keep the last ones written (initially the rest pose s = n).
        scale_vectors: Option<&'a [[f32; 3]]>,
        /// How `scale_vectors` is indexed: one per welded vertex, or one per triangle corner
        /// (`3 × triangle + corner`, separable topologies). Ignored when `scale_vectors` is `None`.
        scale_layout: ShellVertexLayout,
    },
    /// A grass blade field.
    Blades {
        /// Its renderer.
        renderer: &'a BladeRenderer,
        /// Pack frame → world: rotation, translation, uniform positive scale.
        model: Mat4,
        /// This frame's forces, or `None` to keep the last ones written (initially zero).
        forces: Option<BladeForces<'a>>,
    },
}

impl SceneObject<'_> {
    fn model(&self) -> Mat4 {
        match self {
            SceneObject::Fur { model, .. } | SceneObject::Blades { model, .. } => *model,
        }
    }

    /// The object's bounding sphere in world space.
    fn world_bounds(&self) -> (Vec3, f32) {
        let sphere = match self {
            SceneObject::Fur { renderer, .. } => renderer.bounding_sphere(),
            SceneObject::Blades { renderer, .. } => renderer.bounding_sphere(),
        };
        world_bounds(sphere, self.model())
    }

    fn target(&self) -> &TargetDesc {
        match self {
            SceneObject::Fur { renderer, .. } => renderer.target(),
            SceneObject::Blades { renderer, .. } => renderer.target(),
        }
    }
}

/// A bounding sphere (`center`, `radius`, object frame) in world space: centre moved by the model
/// matrix, radius grown by its largest axis scale.
fn world_bounds((center, radius): ([f32; 3], f32), m: Mat4) -> (Vec3, f32) {
    let scale = m.x_axis.truncate().length().max(m.y_axis.truncate().length()).max(m.z_axis.truncate().length());
    (m.transform_point3(Vec3::from(center)), radius * scale)
}

/// Checks that `m` is finite and places an object (non-zero scale).
fn check_model(m: &Mat4) -> Result<(), RenderError> {
    if !m.is_finite() || m.determinant().abs() < 1e-12 {
        return Err(RenderError::Parameter { what: format!("model matrix {m} is not finite and invertible") });
    }
    Ok(())
}

/// The smallest sphere around two spheres.
fn merge(a: (Vec3, f32), b: (Vec3, f32)) -> (Vec3, f32) {
    let d = a.0.distance(b.0);
    if d + b.1 <= a.1 {
        return a;
    }
    if d + a.1 <= b.1 {
        return b;
    }
    let radius = (d + a.1 + b.1) * 0.5;
    let center = if d > 0.0 { a.0 + (b.0 - a.0) * ((radius - a.1) / d) } else { a.0 };
    (center, radius)
}

/// Camera, lights and clear colour of a scene frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneFrame {
    /// The camera; `None` frames every object automatically ([`View::framing`] of their union).
    pub camera: Option<Camera>,
    /// What the frame is lit by.
    pub lighting: Lighting,
    /// Linear RGBA clear colour. Default [`RenderSettings::default`]'s background.
    pub background: [f32; 4],
}

impl SceneFrame {
    /// The scene's camera and lighting ([`Scene::lighting`]), the default background.
    pub fn from_scene(scene: &Scene) -> SceneFrame {
        SceneFrame {
            camera: scene.camera(),
            lighting: scene.lighting(),
            background: RenderSettings::default().background,
        }
    }

    /// The view of this frame for `objects`: the near and far planes fit the union of the
    /// objects' world bounding spheres; without a camera, the three-quarter framing
    /// ([`View::framing`]) of that union.
    pub fn view(&self, objects: &[SceneObject<'_>]) -> View {
        self.view_of(objects.iter().map(SceneObject::world_bounds).reduce(merge))
    }

    /// The view of this frame for everything inside `bounds` (world space; `None`: nothing).
    fn view_of(&self, bounds: Option<(Vec3, f32)>) -> View {
        let bounds = bounds.unwrap_or((Vec3::ZERO, 1.0));
        let mut view = View::framing(bounds.0.to_array(), bounds.1);
        view.lighting = self.lighting;
        if let Some(camera) = self.camera {
            view.camera = camera;
        }
        view
    }

    /// The headless host's frame of borrowed objects: uploads each object's physics input,
    /// prepares every object and draws them in order into `target` in one pass (cleared to
    /// [`SceneFrame::background`]; with no objects the target is just cleared) and one
    /// submission. Every renderer must be built for [`RenderTarget::desc`]. Returns the view
    /// used. Fails before drawing anything on a bad input
    /// (a renderer listed twice, a degenerate model matrix); a wrong scale-vector or corner-force
    /// count or non-finite values fail before anything is drawn, though earlier objects' inputs
    /// may already be uploaded.
    pub fn render(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        objects: &[SceneObject<'_>],
    ) -> Result<View, RenderError> {
        // Each renderer owns one uniform buffer, written once per submission: an object drawn
        // twice in one frame would be drawn twice with the last model matrix.
        let mut seen = std::collections::HashSet::new();
        for object in objects {
            let key = match object {
                SceneObject::Fur { renderer, .. } => *renderer as *const FurRenderer as usize,
                SceneObject::Blades { renderer, .. } => *renderer as *const BladeRenderer as usize,
            };
            if !seen.insert(key) {
                return Err(RenderError::Parameter {
                    what: "a renderer appears twice in one scene frame (one model matrix per renderer per frame)"
                        .into(),
                });
            }
        }
        for object in objects {
            check_model(&object.model())?;
            match object {
                SceneObject::Fur { renderer, scale_vectors: Some(s), scale_layout, .. } => {
                    renderer.set_shell_scale_vectors(queue, s, *scale_layout)?
                }
                SceneObject::Blades { renderer, forces: Some(BladeForces::Corners(f)), .. } => {
                    renderer.set_corner_forces(queue, f)?
                }
                SceneObject::Blades { renderer, forces: Some(BladeForces::Field(f)), .. } => {
                    renderer.set_force_field(queue, f)?
                }
                SceneObject::Blades { renderer, forces: Some(BladeForces::Scene { field, scene }), .. } => {
                    renderer.set_force_scene(queue, field, scene)?
                }
                _ => {}
            }
        }
        for object in objects {
            target.check_renderer(object.target())?;
        }
        let view = self.view(objects);
        let frame = view.uniforms(target.width, target.height);
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake scene frame") });
        for object in objects {
            let uniforms = frame.with_model(object.model());
            match object {
                SceneObject::Fur { renderer, .. } => renderer.prepare(queue, &mut encoder, &uniforms),
                SceneObject::Blades { renderer, .. } => renderer.prepare(queue, &mut encoder, &uniforms),
            }
        }
        {
            let mut pass = target.begin_pass(&mut encoder, "furbake scene frame", Some(self.background));
            for object in objects {
                match object {
                    SceneObject::Fur { renderer, .. } => renderer.render(&mut pass),
                    SceneObject::Blades { renderer, .. } => renderer.render(&mut pass),
                }
            }
        }
        crate::blocking::submit(queue, [encoder.finish()]);
        Ok(view)
    }
}

/// The renderers of one scene pack.
pub struct PackRenderers {
    /// The pack's name in the scene.
    pub name: String,
    /// The pack file.
    pub path: PathBuf,
    /// Its fur (when the pack has a skin mesh and a shell atlas).
    pub fur: Option<FurRenderer>,
    /// Its grass blades (when the pack has a blade field).
    pub blades: Option<BladeRenderer>,
    /// Its placement at time 0 (`ScenePack::transform`), used when a [`PackInput`] gives none.
    pub model: Mat4,
    /// An animated pack's bounding sphere (pack frame, metres, fur included) over the whole clip
    /// the world plays, which the automatic framing covers instead of the bind pose; `None` for
    /// a static pack.
    pub clip_bounds: Option<([f32; 3], f32)>,
}

/// One pack's inputs for a frame (all optional: `PackInput::default()` redraws the last state).
#[derive(Clone, Copy, Debug)]
pub struct PackInput<'a> {
    /// Placement this frame (e.g. along the pack's motion path); `None`: the time-0 placement.
    pub model: Option<Mat4>,
    /// Fur scale vectors, mesh frame (`furbake_runtime::FurFrame::scale_vectors`), indexed as
    /// `scale_layout` says.
    pub scale_vectors: Option<&'a [[f32; 3]]>,
    /// How `scale_vectors` is indexed (`furbake_runtime::FurFrame::layout`): one per welded
    /// skin vertex, or one per triangle corner for a separable topology (parted fur). Default
    /// per vertex.
    pub scale_layout: ShellVertexLayout,
    /// Grass forces.
    pub blade_forces: Option<BladeForces<'a>>,
    /// The skin's pose this frame: skinning matrices (one per bind, `world(joint) ×
    /// inverseBind`) and morph weights (`furbake_runtime::Animator::skinning_matrices` and
    /// `morph_weights`), for a pack whose renderer has a skinning pass. `None`: the last pose.
    pub pose: Option<(&'a [Mat4], &'a [f32])>,
}

impl Default for PackInput<'_> {
    fn default() -> Self {
        PackInput {
            model: None,
            scale_vectors: None,
            scale_layout: ShellVertexLayout::PerVertex,
            blade_forces: None,
            pose: None,
        }
    }
}

/// Every pack of a scene on the GPU, drawn together frame by frame.
pub struct SceneRenderer {
    /// Camera, light and background.
    frame: SceneFrame,
    /// One entry per `scene.packs()`, in order.
    packs: Vec<PackRenderers>,
    /// The pass every pack's renderers draw into.
    target: TargetDesc,
    /// The device the renderers live on (the frame upload's buffer is made and grown on it).
    device: wgpu::Device,
    /// The frame's writes for all packs, uploaded at once (docs/design.md "One upload per
    /// frame"); behind a lock because `prepare_world` takes `&self`, never contended in a frame.
    upload: std::sync::Mutex<FrameUpload>,
    /// The fur physics of the packs the world runs on the GPU (`[solver] device = "gpu"`), in
    /// herds of one asset's packs: built at the first `prepare_world`, then stepped by the world's
    /// steps.
    physics: std::sync::Mutex<GpuHerds>,
    /// Per pack, whether its fur physics runs on the GPU.
    on_gpu: Vec<bool>,
    /// Grass occlusion ([`SceneRenderer::set_grass_occlusion`]): the depth pyramid every blade
    /// renderer tests against; blade culling is then recorded by
    /// [`SceneRenderer::prepare_grass`] after the fur is drawn instead of by the prepare.
    occlusion: Option<DepthPyramid>,
}

/// A scene's GPU physics: packs of one opened asset whose models can step together share one
/// [`GpuFurPhysics`] herd (one dispatch per pass for up to 64 of them).
#[derive(Default)]
struct GpuHerds {
    herds: Vec<GpuHerd>,
    /// Per pack: its herd and its place in it (packs on the CPU: none).
    member: Vec<Option<(usize, usize)>>,
}

/// One herd: its physics, its packs (scene indices) and how many of the world's steps it has
/// recorded.
struct GpuHerd {
    physics: GpuFurPhysics,
    packs: Vec<usize>,
    recorded: u64,
    /// Per member: counters read back and not yet handed over.
    fresh: Vec<bool>,
}

impl SceneRenderer {
    /// The scene's camera, lights and background.
    pub fn frame(&self) -> &SceneFrame {
        &self.frame
    }

    /// The camera, lights and background, to move the camera or change the lights between
    /// frames.
    pub fn frame_mut(&mut self) -> &mut SceneFrame {
        &mut self.frame
    }

    /// The renderers of each scene pack, in the scene's order.
    pub fn packs(&self) -> &[PackRenderers] {
        &self.packs
    }

    /// The renderers of each scene pack, to change their settings (e.g.
    /// [`BladeRenderer::set_culling`]) between frames.
    pub fn packs_mut(&mut self) -> &mut [PackRenderers] {
        &mut self.packs
    }

    /// The headless host's scene renderer ([`SceneRenderer::for_target`] with a new
    /// [`PipelineCache`] on `device` and [`RenderTarget::desc`]), what
    /// [`SceneRenderer::render_world`] draws with.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue, world: &World) -> Result<SceneRenderer, RenderError> {
        Self::for_target(&PipelineCache::new(device), queue, world, &RenderTarget::desc())
    }

    /// Uploads every pack of `world`'s scene from the packs the world opened (decoded sections are
    /// shared through the packs' caches, so nothing the world read is read again): its fur (skin
    /// mesh + shell atlas + UV map, fins, skin weights and morph targets when present; an animated
    /// pack's renderer owns a skinning pass, posed from the world's animation by
    /// [`SceneRenderer::prepare_world`] and in its bind pose until then) and its blade field, with
    /// the shader features the scene's effects need ([`RenderSettings::for_scene`]), each fur
    /// pack's `[packs.shading]` ([`crate::FurShading`]) and the scene's `[grass_culling]` for the
    /// blades, every
    /// renderer drawing into passes like `target` with pipelines from `pipelines` (packs with the
    /// same settings share them). A pack with neither fur nor blades is an
    /// [`RenderError::InvalidAsset`].
    pub fn for_target(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        world: &World,
        target: &TargetDesc,
    ) -> Result<SceneRenderer, RenderError> {
        Self::for_target_with(pipelines, queue, world, target, &RenderOptions::default())
    }

    /// [`SceneRenderer::for_target`] with `overrides` over every pack's render options (what
    /// `furbake preview` and `furbake view` flags and keys set): for each pack, `overrides` over
    /// its `[packs.render]` over the scene's `[render]` over the defaults.
    pub fn for_target_with(
        pipelines: &PipelineCache,
        queue: &wgpu::Queue,
        world: &World,
        target: &TargetDesc,
        overrides: &RenderOptions,
    ) -> Result<SceneRenderer, RenderError> {
        overrides.validate().map_err(|(field, what)| RenderError::Parameter { what: format!("{field}: {what}") })?;
        let scene = world.scene();
        let base = RenderSettings::for_scene(scene);
        let mut packs = Vec::with_capacity(scene.packs().len());
        // Entries naming the same file share the world's one opened pack, and here its one
        // uploaded asset (per fin setting): atlases and vertex buffers are held once however often
        // it is placed.
        type Uploaded<'w> = (&'w std::sync::Arc<furbake_runtime::Pack>, bool, FurAsset, std::sync::Arc<FurGpuAsset>);
        let mut uploaded: Vec<Uploaded<'_>> = Vec::new();
        for (i, p) in scene.packs().iter().enumerate() {
            let pack = world.pack(i);
            let options = pack_options(scene, i, overrides);
            let settings = RenderSettings { shading: p.shading, ..base }.with_options(&options);
            let fur = if pack.has(SectionKind::SKIN_MESH) && pack.has(SectionKind::SHELL_ATLAS) {
                let fins = settings.fins;
                let k = match uploaded.iter().position(|(q, f, _, _)| std::sync::Arc::ptr_eq(q, pack) && *f == fins) {
                    Some(k) => k,
                    None => {
                        let asset = FurAsset::from_pack(pack, fins)?;
                        let gpu = FurGpuAsset::new(pipelines.device(), queue, &asset, fins)?;
                        uploaded.push((pack, fins, asset, gpu));
                        uploaded.len() - 1
                    }
                };
                let (_, _, asset, gpu) = &uploaded[k];
                // The entry's own `[packs.shading]` and `[packs.render]`; entries that only differ
                // in shading parameters share pipelines unless one switches a shader path.
                let mut settings = settings;
                if pack.has(SectionKind::BLADE_FIELD) && settings.tint == RenderSettings::default().tint {
                    // The ground under the blades takes the grass colour.
                    settings.tint = BladeRenderSettings::default().ground_tint();
                }
                Some(FurRenderer::with_gpu_asset(pipelines, asset, gpu.clone(), &settings, target)?)
            } else {
                None
            };
            // A grass pack placed again draws from the first placement's uploaded field.
            let first = (0..i).find(|&j| std::sync::Arc::ptr_eq(world.pack(j), pack));
            let blade_settings =
                BladeRenderSettings { culling: scene.grass_culling(), ..BladeRenderSettings::default() }
                    .with_options(&options);
            let earlier = first.and_then(|j| packs.get(j)).and_then(|p: &PackRenderers| p.blades.as_ref());
            let blades = match earlier.filter(|b| b.shading_enabled() == blade_settings.shading.enabled) {
                Some(earlier) => Some(earlier.instance(pipelines)?),
                None => BladeRenderer::from_pack(pipelines, queue, pack, &blade_settings, target)?,
            };
            if fur.is_none() && blades.is_none() {
                return Err(RenderError::InvalidAsset {
                    what: format!("scene pack {:?} ({}) has neither fur nor grass blades", p.name, p.path.display()),
                });
            }
            let clip_bounds = match (world.animation(i), &fur) {
                (Some(animator), Some(fur)) => {
                    let (lo, hi) = animator.clip_bounds(CLIP_BOUND_POSES).map_err(|source| {
                        RenderError::Runtime(furbake_runtime::RuntimeError::Animation {
                            path: pack.display_path(),
                            source,
                        })
                    })?;
                    let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
                    let fur_m = fur.fur_length_m();
                    Some((((lo + hi) * 0.5).to_array(), (hi - lo).length() * 0.5 + fur_m))
                }
                _ => None,
            };
            packs.push(PackRenderers {
                name: p.name.clone(),
                path: p.path.clone(),
                fur,
                blades,
                model: p.transform().to_mat4(),
                clip_bounds,
            });
        }
        let on_gpu =
            (0..world.pack_count()).map(|i| world.gpu_physics(i).is_some() && packs[i].fur.is_some()).collect();
        Ok(SceneRenderer {
            physics: Default::default(),
            on_gpu,
            frame: SceneFrame::from_scene(scene),
            packs,
            target: target.clone(),
            device: pipelines.device().clone(),
            upload: Default::default(),
            occlusion: None,
        })
    }

    /// Culls the scene's grass against the depth its fur (and whatever the host draws first)
    /// leaves in passes of `size` (`None`: no occlusion test, the default): builds the depth
    /// pyramid and binds it to every blade renderer ([`BladeRenderer::set_occlusion`]). From then
    /// on a frame is: the prepare (which no longer records blade culling), a pass with
    /// [`SceneRenderer::render_fur`] and the host's own occluders, [`SceneRenderer::prepare_grass`]
    /// with that pass's depth texture, and a pass (loading colour and depth) with
    /// [`SceneRenderer::render_grass`]; the image is the same, with fewer blades drawn
    /// (docs/design.md "Depth pyramid and occlusion culling"). Call again after a resize.
    pub fn set_grass_occlusion(
        &mut self,
        pipelines: &PipelineCache,
        size: Option<(u32, u32)>,
    ) -> Result<(), RenderError> {
        let reversed =
            self.target.depth.as_ref().is_some_and(|d| {
                matches!(d.compare, wgpu::CompareFunction::Greater | wgpu::CompareFunction::GreaterEqual)
            });
        let pyramid = match size {
            Some((w, h)) if self.target.depth.is_some() => Some(DepthPyramid::new(pipelines.device(), w, h, reversed)?),
            Some(_) => {
                return Err(RenderError::Parameter { what: "grass occlusion needs a target with depth".into() });
            }
            None => None,
        };
        for blades in self.packs.iter_mut().filter_map(|p| p.blades.as_mut()) {
            blades.set_occlusion(pipelines, 0, pyramid.as_ref())?;
        }
        self.occlusion = pyramid;
        Ok(())
    }

    /// The grass occlusion pyramid's size, when [`SceneRenderer::set_grass_occlusion`] set one.
    pub fn grass_occlusion(&self) -> Option<(u32, u32)> {
        self.occlusion.as_ref().map(DepthPyramid::size)
    }

    /// The GPU memory [`SceneRenderer::new`] would allocate for `world` — each distinct fur
    /// asset's shared data once ([`FurGpuAsset`]), each entry's own fur data and blade data, plus
    /// `RENDERER_OVERHEAD_BYTES` (1 MiB) per renderer — computed from the sections' sizes before
    /// anything is created, so a host can refuse a scene that would not fit instead of failing
    /// inside the driver. Reads (and shares) the sections the renderer would read.
    pub fn estimate_gpu_bytes(world: &World) -> Result<u64, RenderError> {
        let base = RenderSettings::for_scene(world.scene());
        let mut total = 0u64;
        for i in 0..world.pack_count() {
            let pack = world.pack(i);
            let settings = base.with_options(&pack_options(world.scene(), i, &RenderOptions::default()));
            // The first entry naming a file uploads what its entries share.
            let first = (0..i).find(|&j| std::sync::Arc::ptr_eq(world.pack(j), pack));
            if pack.has(SectionKind::SKIN_MESH) && pack.has(SectionKind::SHELL_ATLAS) {
                let asset = FurAsset::from_pack(pack, settings.fins)?;
                if first.is_none() {
                    total = total.saturating_add(asset.shared_gpu_bytes(settings.fins));
                }
                total = total.saturating_add(asset.instance_gpu_bytes() + crate::RENDERER_OVERHEAD_BYTES);
            }
            if let Some(field) = pack.optional_section::<furbake_formats::sections::blade_field::BladeField>()? {
                if first.is_none() {
                    let table = pack.keyframe_table()?;
                    total = total.saturating_add(BladeRenderer::shared_gpu_bytes(&field, &table));
                }
                total =
                    total.saturating_add(BladeRenderer::instance_gpu_bytes(&field) + crate::RENDERER_OVERHEAD_BYTES);
            }
        }
        Ok(total)
    }

    /// The pass description every pack's renderers were built for.
    pub fn target(&self) -> &TargetDesc {
        &self.target
    }

    /// The view of [`SceneRenderer::frame`] (the scene's camera, or the three-quarter framing of
    /// everything when it has none, and its light) with near and far planes fitted around every
    /// pack placed by `world`'s model matrices. Allocates nothing.
    pub fn world_view(&self, world: &World) -> View {
        self.fitted_view(|i| if i < world.pack_count() { world.model_matrix(i) } else { self.packs[i].model })
    }

    /// [`SceneRenderer::world_view`] for packs placed by `inputs` (the time-0 placement where an
    /// input gives none or is missing).
    pub fn view(&self, inputs: &[PackInput<'_>]) -> View {
        self.fitted_view(|i| inputs.get(i).and_then(|input| input.model).unwrap_or(self.packs[i].model))
    }

    fn fitted_view(&self, model: impl Fn(usize) -> Mat4) -> View {
        let mut bounds = None;
        for (i, pack) in self.packs.iter().enumerate() {
            let m = model(i);
            let spheres = [
                pack.clip_bounds.or_else(|| pack.fur.as_ref().map(FurRenderer::bounding_sphere)),
                pack.blades.as_ref().map(BladeRenderer::bounding_sphere),
            ];
            for sphere in spheres.into_iter().flatten() {
                let b = world_bounds(sphere, m);
                bounds = Some(bounds.map_or(b, |a| merge(a, b)));
            }
        }
        self.frame.view_of(bounds)
    }

    fn check_world(&self, world: &World) -> Result<(), RenderError> {
        if world.pack_count() != self.packs.len() {
            return Err(RenderError::Parameter {
                what: format!("a world of {} packs for a renderer of {}", world.pack_count(), self.packs.len()),
            });
        }
        Ok(())
    }

    /// The middleware's per-frame upload for `world`'s current state (see the module doc): for
    /// every pack, its model matrix, its skin in the world's pose (an animated pack's skinning
    /// matrices and morph weights, dispatched into `encoder`), its fur with the world's scale
    /// vectors, its blades with the world's corner forces — and, when a wind source with delayed
    /// attenuation acts, that source evaluated per blade on the GPU. `frame` carries the host's
    /// view-projection, eye and light (e.g. [`SceneRenderer::world_view`]'s
    /// [`View::uniforms`]); its model matrix places the whole scene in the host's world
    /// (identity: scene frame = world frame), each pack drawn at `frame.model × pack model`.
    /// `world` must be the one this renderer was built from (same packs, same order). Call once
    /// per frame before the host's render pass; then [`SceneRenderer::render`]. Every pack's data
    /// of the frame goes up in one `queue.write_buffer`, copied into place by commands recorded
    /// into `encoder` ahead of the frame's compute passes (docs/design.md "One upload per
    /// frame"), so the host must submit `encoder` for the frame to reach the GPU. Does not submit
    /// or wait, and allocates nothing of its own once the first frames have sized its staging
    /// memory (except to build the message of an error). Every input is checked before anything
    /// is written: a bad one (a degenerate model matrix, wrong counts, non-finite values) fails
    /// with nothing uploaded or recorded.
    pub fn prepare_world(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        world: &World,
        frame: &FrameUniforms,
    ) -> Result<(), RenderError> {
        self.check_world(world)?;
        let input = |i: usize| {
            let drawn = &self.packs[i];
            let fur = world.fur(i).filter(|_| drawn.fur.is_some());
            let grass = world.grass(i).filter(|_| drawn.blades.is_some());
            let skinned = drawn.fur.as_ref().is_some_and(|f| f.is_animated());
            let pose = world.animation(i).filter(|_| skinned).map(|a| (a.skinning_matrices(), a.morph_weights()));
            // GPU physics writes its scale vectors in place (recorded below).
            let gpu = self.on_gpu[i];
            PackInput {
                pose,
                model: Some(world.model_matrix(i)),
                scale_vectors: fur.filter(|_| !gpu).map(|f| f.scale_vectors),
                scale_layout: fur.map_or(ShellVertexLayout::PerVertex, |f| f.layout),
                blade_forces: grass.map(|g| {
                    if g.has_delayed_sources() {
                        BladeForces::Scene { field: g.field, scene: g.scene }
                    } else {
                        BladeForces::Corners(g.corner_forces)
                    }
                }),
            }
        };
        self.prepare_all(queue, encoder, input, frame)?;
        self.record_gpu_physics(queue, encoder, world)
    }

    /// Records, for every pack whose fur physics runs on the GPU, the world's steps since the
    /// last record (building the herds from the world's models at the first), into `encoder`
    /// after the frame's upload, before the frame's draws read the scale vectors.
    fn record_gpu_physics(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        world: &World,
    ) -> Result<(), RenderError> {
        if !self.on_gpu.contains(&true) {
            return Ok(());
        }
        let mut herds = self.physics.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let restarted = herds
            .herds
            .iter()
            .any(|h| h.packs.iter().any(|&i| world.gpu_physics(i).is_none_or(|steps| steps.taken() < h.recorded)));
        if herds.herds.is_empty() || restarted {
            // First frame, or a world that started over: the solvers from the world's start.
            *herds = self.build_herds(queue, world)?;
        }
        for herd in &mut herds.herds {
            let GpuHerd { physics, packs, recorded, .. } = herd;
            let steps_of = |i: usize| world.gpu_physics(i).expect("the world runs the pack on the GPU");
            let taken = steps_of(packs[0]).taken();
            if taken == *recorded {
                continue;
            }
            for &i in packs.iter() {
                let steps = steps_of(i);
                if steps.taken() != taken || steps.step(*recorded).is_none() {
                    return Err(RenderError::Parameter {
                        what: format!(
                            "pack {:?}: the world took {} steps since the last frame; GPU physics records at most {} per frame",
                            self.packs[i].name,
                            steps.taken() - *recorded,
                            furbake_runtime::GPU_PHYSICS_STEPS_KEPT
                        ),
                    });
                }
            }
            let first = *recorded;
            let step = |m: usize, n: u32| {
                let s = steps_of(packs[m])
                    .step(first + n as u64)
                    .expect("the world keeps every step from the first unrecorded one");
                GpuStep {
                    forces: s.forces,
                    teleport_m: s.teleport_m,
                    pose: s.pose.map(|p| GpuPose {
                        skin: GpuSkin::Skinning { matrices: p.skinning_matrices, morph_weights: p.morph_weights },
                        cut_speed_m_per_s: p.cut_speed_m_per_s,
                    }),
                }
            };
            let dt_s = steps_of(packs[0]).dt_s();
            physics.record_herd(&self.device, queue, encoder, dt_s, (taken - first) as u32, step)?;
            *recorded = taken;
        }
        Ok(())
    }

    /// The herds of the world's GPU packs at its start: packs placing the same opened asset whose
    /// models [`crate::same_herd`] and whose solvers take the same stable step, substep limit and
    /// restoring weight step together, as many per herd as the device's storage bindings hold
    /// ([`GpuFurPhysics::herd_capacity`]); each other pack is a herd of its own.
    fn build_herds(&self, queue: &wgpu::Queue, world: &World) -> Result<GpuHerds, RenderError> {
        struct Candidate<'w> {
            pack: usize,
            model: furbake_sim::ComputeModel,
            steps: furbake_runtime::GpuPhysicsSteps<'w>,
            renderer: &'w FurRenderer,
        }
        let mut groups: Vec<Vec<Candidate<'_>>> = Vec::new();
        for (i, drawn) in self.packs.iter().enumerate() {
            let (true, Some(steps), Some(renderer)) = (self.on_gpu[i], world.gpu_physics(i), drawn.fur.as_ref()) else {
                continue;
            };
            let model = steps.compute_model()?;
            let joins = |g: &Vec<Candidate<'_>>| {
                let c = &g[0];
                std::sync::Arc::ptr_eq(world.pack(c.pack), world.pack(i))
                    && c.steps.stable_step_s() == steps.stable_step_s()
                    && c.steps.max_substeps() == steps.max_substeps()
                    && c.steps.restoring_weight_n() == steps.restoring_weight_n()
                    && c.renderer.is_animated() == renderer.is_animated()
                    && crate::same_herd(&c.model, &model)
            };
            let at = groups.iter().position(joins);
            let candidate = Candidate { pack: i, model, steps, renderer };
            match at {
                Some(k) => groups[k].push(candidate),
                None => groups.push(vec![candidate]),
            }
        }
        // A herd holds as many packs as the device's storage bindings take.
        let limits = self.device.limits();
        let groups: Vec<Vec<Candidate<'_>>> = groups
            .into_iter()
            .flat_map(|mut g| {
                let capacity = GpuFurPhysics::herd_capacity(&limits, &g[0].model);
                let mut parts = Vec::new();
                while g.len() > capacity {
                    let rest = g.split_off(capacity);
                    parts.push(std::mem::replace(&mut g, rest));
                }
                parts.push(g);
                parts
            })
            .collect();
        let mut out = GpuHerds { herds: Vec::with_capacity(groups.len()), member: vec![None; self.packs.len()] };
        for group in groups {
            let c = &group[0];
            let forces = ForceSet { restoring_weight_n: c.steps.restoring_weight_n(), ..ForceSet::none() };
            let members: Vec<(&FurRenderer, &furbake_sim::ComputeModel)> =
                group.iter().map(|c| (c.renderer, &c.model)).collect();
            let physics = GpuFurPhysics::herd(
                &self.device,
                queue,
                &members,
                &forces,
                c.steps.stable_step_s(),
                c.steps.max_substeps(),
            )?;
            for (m, c) in group.iter().enumerate() {
                out.member[c.pack] = Some((out.herds.len(), m));
            }
            out.herds.push(GpuHerd {
                physics,
                packs: group.iter().map(|c| c.pack).collect(),
                recorded: 0,
                fresh: vec![false; group.len()],
            });
        }
        Ok(out)
    }

    /// How many herds step the packs whose fur physics runs on the GPU (0 before the first
    /// `prepare_world`): each herd is one set of dispatches per frame, however many packs it
    /// holds.
    pub fn gpu_physics_herds(&self) -> usize {
        self.physics.lock().unwrap_or_else(std::sync::PoisonError::into_inner).herds.len()
    }

    /// Asks every pack whose fur physics runs on the GPU for the counters of its last record
    /// ([`GpuFurPhysics::request_stats`]), recording their copies into `encoder` (after this
    /// frame's `prepare_world`); [`SceneRenderer::poll_gpu_physics_stats`] hands them over once
    /// the host's submission is done. Returns how many packs were asked (a pack whose earlier
    /// request is still on its way is not).
    pub fn request_gpu_physics_stats(&self, encoder: &mut wgpu::CommandEncoder) -> usize {
        let mut herds = self.physics.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        herds.herds.iter_mut().map(|h| if h.physics.request_stats(encoder) { h.packs.len() } else { 0 }).sum()
    }

    /// Pack `index`'s GPU physics counters asked for by
    /// [`SceneRenderer::request_gpu_physics_stats`], once the GPU has written them; `None` until
    /// then, without a request, or for a pack whose physics is not on the GPU. Never waits
    /// ([`GpuFurPhysics::poll_stats`]).
    pub fn poll_gpu_physics_stats(&self, index: usize) -> Result<Option<GpuPhysicsStats>, RenderError> {
        let mut herds = self.physics.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let Some(&Some((h, m))) = herds.member.get(index) else { return Ok(None) };
        let herd = &mut herds.herds[h];
        if herd.physics.poll_stats()?.is_some() {
            herd.fresh.fill(true);
        }
        if !std::mem::replace(&mut herd.fresh[m], false) {
            return Ok(None);
        }
        Ok(herd.physics.pack_stats(m))
    }

    /// [`SceneRenderer::prepare_world`] with explicit inputs: `inputs[i]` belongs to `packs[i]`
    /// (fewer inputs than packs: the rest keep their last physics and pose, at their time-0
    /// placement).
    pub fn prepare(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &[PackInput<'_>],
        frame: &FrameUniforms,
    ) -> Result<(), RenderError> {
        if inputs.len() > self.packs.len() {
            return Err(RenderError::Parameter {
                what: format!("{} pack inputs for {} scene packs", inputs.len(), self.packs.len()),
            });
        }
        self.prepare_all(queue, encoder, |i| inputs.get(i).copied().unwrap_or_default(), frame)
    }

    /// Checks every pack's input, writes them all into the frame's one upload, flushes it into
    /// `encoder`, then records every pack's compute passes (which read what was uploaded).
    fn prepare_all<'a>(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        input: impl Fn(usize) -> PackInput<'a>,
        frame: &FrameUniforms,
    ) -> Result<(), RenderError> {
        for (i, pack) in self.packs.iter().enumerate() {
            check_pack(pack, &input(i), frame)?;
        }
        let mut upload = self.upload.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let staged = (0..self.packs.len())
            .try_for_each(|i| write_pack(&mut Upload::Frame(&mut upload), &self.packs[i], &input(i), frame));
        if let Err(e) = staged {
            upload.discard();
            return Err(e);
        }
        upload.flush(&self.device, queue, encoder);
        drop(upload);
        for pack in &self.packs {
            record_pack(encoder, pack, self.occlusion.is_none());
        }
        Ok(())
    }

    /// With grass occlusion on ([`SceneRenderer::set_grass_occlusion`]): records the depth
    /// pyramid of `depth` (the pass [`SceneRenderer::render_fur`] drew into, ended) and every blade
    /// renderer's culling against it into `encoder`; without, records nothing (the prepare
    /// recorded the culling). Does not submit or wait.
    pub fn prepare_grass(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        depth: &wgpu::Texture,
    ) -> Result<(), RenderError> {
        let Some(pyramid) = &self.occlusion else { return Ok(()) };
        pyramid.record(device, encoder, depth)?;
        for blades in self.packs.iter().filter_map(|p| p.blades.as_ref()) {
            blades.record(encoder, 0);
        }
        Ok(())
    }

    /// Draws every pack's fur (skin, shells, fins) into `pass`, in scene order.
    pub fn render_fur(&self, pass: &mut wgpu::RenderPass<'_>) {
        for fur in self.packs.iter().filter_map(|p| p.fur.as_ref()) {
            fur.render(pass);
        }
    }

    /// Draws every pack's grass blades into `pass`, in scene order.
    pub fn render_grass(&self, pass: &mut wgpu::RenderPass<'_>) {
        for blades in self.packs.iter().filter_map(|p| p.blades.as_ref()) {
            blades.render(pass);
        }
    }

    /// Draws every pack into the host's `pass` (attachments matching
    /// [`SceneRenderer::target`]) as the last prepare left it: fur before blades within a pack,
    /// packs in scene order. With grass occlusion on, draw with [`SceneRenderer::render_fur`] and
    /// [`SceneRenderer::render_grass`] around [`SceneRenderer::prepare_grass`] instead. Does not submit or wait, and allocates nothing of its own (wgpu
    /// allocates inside its calls; docs/performance.md).
    pub fn render(&self, pass: &mut wgpu::RenderPass<'_>) {
        for pack in &self.packs {
            if let Some(fur) = &pack.fur {
                fur.render(pass);
            }
            if let Some(blades) = &pack.blades {
                blades.render(pass);
            }
        }
    }

    /// The headless host's frame of `world`'s current state: [`SceneRenderer::world_view`],
    /// [`SceneRenderer::prepare_world`], one pass into `target` cleared to the frame's background,
    /// [`SceneRenderer::render`], submitted. Returns the view used. The renderer must be built for
    /// [`RenderTarget::desc`] ([`SceneRenderer::new`]).
    pub fn render_world(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        world: &World,
    ) -> Result<View, RenderError> {
        self.check_world(world)?;
        let view = self.world_view(world);
        self.render_headless(device, queue, target, &view, |encoder, frame| {
            self.prepare_world(queue, encoder, world, frame)
        })?;
        Ok(view)
    }

    /// [`SceneRenderer::render_world`] with explicit per-pack inputs ([`SceneRenderer::prepare`]).
    pub fn render_frame(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        inputs: &[PackInput<'_>],
    ) -> Result<View, RenderError> {
        let view = self.view(inputs);
        self.render_headless(device, queue, target, &view, |encoder, frame| {
            self.prepare(queue, encoder, inputs, frame)
        })?;
        Ok(view)
    }

    fn render_headless(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        target: &RenderTarget,
        view: &View,
        prepare: impl FnOnce(&mut wgpu::CommandEncoder, &FrameUniforms) -> Result<(), RenderError>,
    ) -> Result<(), RenderError> {
        target.check_renderer(&self.target)?;
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("furbake scene frame") });
        // On an error the encoder is dropped unsubmitted: nothing of this frame is drawn.
        if let Some((w, h)) = self.grass_occlusion().filter(|&s| s != (target.width, target.height)) {
            return Err(RenderError::Parameter {
                what: format!(
                    "grass occlusion is set for {w}×{h} passes and the target is {}×{}",
                    target.width, target.height
                ),
            });
        }
        prepare(&mut encoder, &view.uniforms(target.width, target.height))?;
        if self.occlusion.is_some() {
            // The fur first, its depth's pyramid, the grass culled against it, then the grass.
            self.render_fur(&mut target.begin_pass(&mut encoder, "furbake scene fur", Some(self.frame.background)));
            self.prepare_grass(device, &mut encoder, &target.depth)?;
            self.render_grass(&mut target.begin_pass(&mut encoder, "furbake scene grass", None));
        } else {
            self.render(&mut target.begin_pass(&mut encoder, "furbake scene frame", Some(self.frame.background)));
        }
        crate::blocking::submit(queue, [encoder.finish()]);
        Ok(())
    }
}

/// Poses sampled over an animated pack's clip for its framing bounds
/// ([`PackRenderers::clip_bounds`]).
const CLIP_BOUND_POSES: u32 = 32;

/// The render options of scene pack `i`: `overrides` over its `[packs.render]` over the
/// scene's `[render]`.
fn pack_options(scene: &Scene, i: usize, overrides: &RenderOptions) -> RenderOptions {
    overrides.over(&scene.packs()[i].render.over(scene.render()))
}

/// The checks of one pack's inputs (see [`SceneRenderer::prepare_world`]): its model matrix, and
/// its pose, scale vectors and blade forces against its renderers.
fn check_pack(pack: &PackRenderers, input: &PackInput<'_>, frame: &FrameUniforms) -> Result<(), RenderError> {
    check_model(&(frame.model() * input.model.unwrap_or(pack.model)))?;
    match &pack.fur {
        Some(renderer) => {
            if let Some((matrices, weights)) = input.pose {
                renderer.check_pose(matrices, weights)?;
            }
            if let Some(s) = input.scale_vectors {
                renderer.check_shell_scale_vectors(s, input.scale_layout)?;
            }
        }
        None if input.scale_vectors.is_some() => {
            return Err(RenderError::Parameter { what: format!("scale vectors for pack {:?} without fur", pack.name) });
        }
        None => {}
    }
    match (&pack.blades, input.blade_forces) {
        (Some(renderer), Some(forces)) => renderer.check_forces(forces)?,
        (None, Some(_)) => {
            return Err(RenderError::Parameter {
                what: format!("blade forces for pack {:?} without blades", pack.name),
            });
        }
        _ => {}
    }
    Ok(())
}

/// Writes one pack's checked inputs and frame uniforms through `upload`.
fn write_pack(
    upload: &mut Upload<'_>,
    pack: &PackRenderers,
    input: &PackInput<'_>,
    frame: &FrameUniforms,
) -> Result<(), RenderError> {
    let uniforms = frame.with_model(frame.model() * input.model.unwrap_or(pack.model));
    if let Some(renderer) = &pack.fur {
        if let Some((matrices, weights)) = input.pose {
            renderer.write_pose(upload, matrices, weights)?;
        }
        if let Some(s) = input.scale_vectors {
            renderer.write_shell_scale_vectors(upload, s, input.scale_layout)?;
        }
        renderer.write_frame(upload, &uniforms);
    }
    if let Some(renderer) = &pack.blades {
        if let Some(forces) = input.blade_forces {
            renderer.write_forces(upload, forces)?;
        }
        renderer.write_frame(upload, 0, &uniforms);
    }
    Ok(())
}

/// Records one pack's compute passes (skinning, silhouette fin selection, and blade culling
/// unless it waits for the occluders' depth).
fn record_pack(encoder: &mut wgpu::CommandEncoder, pack: &PackRenderers, cull_blades: bool) {
    if let Some(renderer) = &pack.fur {
        renderer.record(encoder);
    }
    if let (Some(renderer), true) = (&pack.blades, cull_blades) {
        renderer.record(encoder, 0);
    }
}
