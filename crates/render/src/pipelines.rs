//! [`PipelineCache`]: the render pipelines of every renderer on one device, created once per
//! (target description, program, override constants) and shared: a second pack drawn with the
//! same settings into the same kind of pass reuses the first one's pipelines, and resizing the
//! host's textures rebuilds nothing. The cache also owns what pipelines and bind groups must agree
//! on — the bind group layouts and pipeline layouts of the fur and blade programs, and each
//! shader module, compiled on first use.
//!
//! Effects are WGSL `override` constants fixed at pipeline creation (WGSL specification,
//! "Override Declarations"; `shaders/fur_common.wgsl`), so they are part of the key
//! ([`FurSwitches`]); the target's formats, blend, depth comparison and sample count are the
//! rest ([`TargetDesc`]). Each pipeline is created inside its own error scope, so a failed one is
//! reported ([`RenderError`]) and never cached.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use crate::shaders::{
    BLADES_WGSL, FIN_ATTRIBUTES, FIN_WGSL, FinVertex, SHELL_WGSL, SILHOUETTE_WGSL, SKIN_WGSL, SURFACE_ATTRIBUTES,
    SurfaceVertex,
};
use crate::{RenderError, TargetDesc};

/// The shader switches (WGSL `override` constants) of a fur pipeline, decided by the
/// [`crate::RenderSettings`] and whether the asset is animated (`fur_switches` in `renderer.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct FurSwitches {
    pub lambert: bool,
    pub shadow: bool,
    pub skinned: bool,
    /// The strand shading (`FurShading::enabled`; docs/design.md "Fur shading").
    pub strand: bool,
    pub shear: bool,
    pub alpha_blend: bool,
    /// Alpha to coverage for the alpha-tested shells and fins
    /// ([`crate::RenderSettings::alpha_to_coverage`]; only on multisampled targets).
    pub alpha_to_coverage: bool,
    /// Lights the shading evaluates ([`crate::RenderSettings::light_slots`]).
    pub light_slots: u32,
}

/// The three fur stages (fur thesis §3.2: skin, shells, fins), the back faces of blended shells
/// (the shell program with front faces culled, drawn before the front faces; docs/design.md
/// "Shell order") and the silhouette fins (`crate::silhouette`): the fin program drawn indirectly
/// from the selected edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum FurStage {
    Skin,
    Shell,
    ShellBack,
    Fin,
    SilhouetteFin,
}

/// What a render pipeline runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Program {
    Fur(FurStage, FurSwitches),
    Blades,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
struct PipelineKey {
    target: TargetDesc,
    program: Program,
}

/// The skin, shell and fin pipelines of one fur renderer.
#[derive(Clone, Debug)]
pub(crate) struct FurPipelines {
    pub skin: wgpu::RenderPipeline,
    /// The shells; blended, their front faces only.
    pub shell: wgpu::RenderPipeline,
    /// The back faces of blended shells, drawn first (none for alpha-tested shells, which write
    /// depth and draw every face in one pass).
    pub shell_back: Option<wgpu::RenderPipeline>,
    pub fin: wgpu::RenderPipeline,
    /// The silhouette fins, when the renderer draws them.
    pub silhouette_fin: Option<wgpu::RenderPipeline>,
}

/// The layouts of the silhouette fins: the selection's compute group, and group 1 of the
/// silhouette fin draw (group 0 is the fur group).
pub(crate) struct SilhouetteLayouts {
    compute: wgpu::BindGroupLayout,
    compute_pipeline: wgpu::PipelineLayout,
    draw: wgpu::BindGroupLayout,
    draw_pipeline: wgpu::PipelineLayout,
}

/// The layouts of the blade program: group 0 shared by the compute pass and the draw, group 1 the
/// compute pass's output.
pub(crate) struct BladeLayouts {
    pub shared: wgpu::BindGroupLayout,
    pub out: wgpu::BindGroupLayout,
    /// The culling passes' group (`blade_cull.wgsl`).
    pub cull: wgpu::BindGroupLayout,
    draw: wgpu::PipelineLayout,
    compute: wgpu::PipelineLayout,
    cull_pipeline: wgpu::PipelineLayout,
}

struct Inner {
    device: wgpu::Device,
    adapter: Option<wgpu::Adapter>,
    fur_layout: wgpu::BindGroupLayout,
    fur_pipeline_layout: wgpu::PipelineLayout,
    blade_layouts: BladeLayouts,
    silhouette_layouts: SilhouetteLayouts,
    silhouette_module: OnceLock<wgpu::ShaderModule>,
    silhouette_compute: Mutex<Option<wgpu::ComputePipeline>>,
    skin_module: OnceLock<wgpu::ShaderModule>,
    shell_module: OnceLock<wgpu::ShaderModule>,
    fin_module: OnceLock<wgpu::ShaderModule>,
    blade_module: OnceLock<wgpu::ShaderModule>,
    blade_compute: Mutex<Option<wgpu::ComputePipeline>>,
    blade_cull_module: OnceLock<wgpu::ShaderModule>,
    blade_cull: Mutex<Option<[wgpu::ComputePipeline; 5]>>,
    render: Mutex<HashMap<PipelineKey, wgpu::RenderPipeline>>,
    /// Target descriptions already validated (with and without blending).
    validated: Mutex<Vec<(TargetDesc, bool)>>,
    /// The shell and fin atlas samplers, `[shells, fins]`, by anisotropy clamp
    /// ([`PipelineCache::atlas_samplers`]).
    atlas_samplers: Mutex<HashMap<u16, [wgpu::Sampler; 2]>>,
}

/// Every pipeline of the fur and blade renderers on one device (see the module documentation).
/// Cheap to clone (a shared handle); give the same cache to every renderer of a host so they
/// share pipelines. Holds the device it was created for.
#[derive(Clone)]
pub struct PipelineCache {
    inner: Arc<Inner>,
}

impl std::fmt::Debug for PipelineCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PipelineCache").field("render_pipelines", &self.render_pipeline_count()).finish()
    }
}

impl PipelineCache {
    /// An empty cache for `device`. Target descriptions are checked against the formats' features
    /// the device guarantees (`TextureFormat::guaranteed_format_features`); a device created with
    /// `Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES` wants [`PipelineCache::with_adapter`].
    pub fn new(device: &wgpu::Device) -> PipelineCache {
        Self::build(device, None)
    }

    /// An empty cache for `device`, checking target descriptions against `adapter`'s format
    /// features when the device enabled `Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES`
    /// (e.g. 8× MSAA, or MSAA of a format that does not guarantee it).
    pub fn with_adapter(device: &wgpu::Device, adapter: &wgpu::Adapter) -> PipelineCache {
        Self::build(device, Some(adapter.clone()))
    }

    fn build(device: &wgpu::Device, adapter: Option<wgpu::Adapter>) -> PipelineCache {
        let fur_layout = fur_bind_group_layout(device);
        let silhouette_layouts = silhouette_layouts(device, &fur_layout);
        let fur_pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("furbake fur pipeline layout"),
            bind_group_layouts: &[Some(&fur_layout)],
            immediate_size: 0,
        });
        PipelineCache {
            inner: Arc::new(Inner {
                device: device.clone(),
                adapter,
                fur_layout,
                fur_pipeline_layout,
                blade_layouts: blade_layouts(device),
                silhouette_layouts,
                silhouette_module: OnceLock::new(),
                silhouette_compute: Mutex::new(None),
                skin_module: OnceLock::new(),
                shell_module: OnceLock::new(),
                fin_module: OnceLock::new(),
                blade_module: OnceLock::new(),
                blade_compute: Mutex::new(None),
                blade_cull_module: OnceLock::new(),
                blade_cull: Mutex::new(None),
                render: Mutex::new(HashMap::new()),
                validated: Mutex::new(Vec::new()),
                atlas_samplers: Mutex::new(HashMap::new()),
            }),
        }
    }

    /// The device the cache creates pipelines on.
    pub fn device(&self) -> &wgpu::Device {
        &self.inner.device
    }

    /// Render pipelines created so far (each distinct target description × program × override
    /// constants once).
    pub fn render_pipeline_count(&self) -> usize {
        lock(&self.inner.render).len()
    }

    /// Validates `target` for this device ([`TargetDesc::validate`]; `blended`: some stage
    /// alpha-blends into colour attachment 0), once per description.
    pub(crate) fn check_target(&self, target: &TargetDesc, blended: bool) -> Result<(), RenderError> {
        let mut validated = lock(&self.inner.validated);
        if validated.iter().any(|(t, b)| t == target && (*b || !blended)) {
            return Ok(());
        }
        target.validate(&self.inner.device, self.inner.adapter.as_ref(), blended)?;
        validated.push((target.clone(), blended));
        Ok(())
    }

    /// The trilinear samplers of the shell atlas (repeating) and the fin atlas (repeating along
    /// the edge, clamped root to tip), filtering anisotropically up to `anisotropy` (1: off); one
    /// pair per clamp for every renderer of the device.
    pub(crate) fn atlas_samplers(&self, anisotropy: u16) -> [wgpu::Sampler; 2] {
        let mut samplers = lock(&self.inner.atlas_samplers);
        let device = &self.inner.device;
        let pair = samplers.entry(anisotropy.max(1)).or_insert_with(|| {
            [
                ("furbake shell sampler", wgpu::AddressMode::Repeat),
                ("furbake fin sampler", wgpu::AddressMode::ClampToEdge),
            ]
            .map(|(label, address_mode_v)| {
                device.create_sampler(&wgpu::SamplerDescriptor {
                    label: Some(label),
                    address_mode_u: wgpu::AddressMode::Repeat,
                    address_mode_v,
                    address_mode_w: wgpu::AddressMode::ClampToEdge,
                    mag_filter: wgpu::FilterMode::Linear,
                    min_filter: wgpu::FilterMode::Linear,
                    mipmap_filter: wgpu::MipmapFilterMode::Linear,
                    anisotropy_clamp: anisotropy.max(1),
                    ..Default::default()
                })
            })
        });
        pair.clone()
    }

    /// The fur bind group layout (group 0 of `skin.wgsl`, `shell.wgsl`, `fin.wgsl`).
    pub(crate) fn fur_layout(&self) -> &wgpu::BindGroupLayout {
        &self.inner.fur_layout
    }

    /// The blade program's bind group layouts.
    pub(crate) fn blade_layouts(&self) -> &BladeLayouts {
        &self.inner.blade_layouts
    }

    /// The selection's compute group layout.
    pub(crate) fn silhouette_compute_layout(&self) -> &wgpu::BindGroupLayout {
        &self.inner.silhouette_layouts.compute
    }

    /// Group 1 of the silhouette fin draw.
    pub(crate) fn silhouette_draw_layout(&self) -> &wgpu::BindGroupLayout {
        &self.inner.silhouette_layouts.draw
    }

    /// The silhouette selection compute pipeline (`cs_silhouette`), independent of any target.
    pub(crate) fn silhouette_compute(&self) -> Result<wgpu::ComputePipeline, RenderError> {
        let mut slot = lock(&self.inner.silhouette_compute);
        if let Some(p) = slot.as_ref() {
            return Ok(p.clone());
        }
        let device = &self.inner.device;
        let module = self.inner.silhouette_module.get_or_init(|| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("furbake silhouette"),
                source: wgpu::ShaderSource::Wgsl(SILHOUETTE_WGSL.into()),
            })
        });
        let pipeline = crate::gpu_scope(device, "creating the silhouette compute pipeline", || {
            Ok(device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("furbake silhouette selection"),
                layout: Some(&self.inner.silhouette_layouts.compute_pipeline),
                module,
                entry_point: Some("cs_silhouette"),
                compilation_options: Default::default(),
                cache: None,
            }))
        })?;
        *slot = Some(pipeline.clone());
        Ok(pipeline)
    }

    /// The skin, shell and fin pipelines for `switches` drawn into `target`, and the silhouette
    /// fin pipeline when `silhouette`.
    pub(crate) fn fur(
        &self,
        target: &TargetDesc,
        switches: FurSwitches,
        silhouette: bool,
    ) -> Result<FurPipelines, RenderError> {
        self.check_target(target, switches.alpha_blend)?;
        // The skin has neither a shearing nor a blending switch: one pipeline serves both.
        let skin_switches = FurSwitches { shear: false, alpha_blend: false, ..switches };
        Ok(FurPipelines {
            skin: self.render_pipeline(target, Program::Fur(FurStage::Skin, skin_switches))?,
            shell: self.render_pipeline(target, Program::Fur(FurStage::Shell, switches))?,
            shell_back: if switches.alpha_blend {
                Some(self.render_pipeline(target, Program::Fur(FurStage::ShellBack, switches))?)
            } else {
                None
            },
            fin: self.render_pipeline(target, Program::Fur(FurStage::Fin, switches))?,
            silhouette_fin: if silhouette {
                Some(self.render_pipeline(target, Program::Fur(FurStage::SilhouetteFin, switches))?)
            } else {
                None
            },
        })
    }

    /// The instanced blade draw into `target`.
    pub(crate) fn blades(&self, target: &TargetDesc) -> Result<wgpu::RenderPipeline, RenderError> {
        self.check_target(target, false)?;
        self.render_pipeline(target, Program::Blades)
    }

    /// The blade posing compute pipeline (`cs_blades`), independent of any target.
    pub(crate) fn blade_compute(&self) -> Result<wgpu::ComputePipeline, RenderError> {
        let mut slot = lock(&self.inner.blade_compute);
        if let Some(p) = slot.as_ref() {
            return Ok(p.clone());
        }
        let device = &self.inner.device;
        let pipeline = crate::gpu_scope(device, "creating the blade compute pipeline", || {
            Ok(device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("furbake blade poses"),
                layout: Some(&self.inner.blade_layouts.compute),
                module: self.module(Module::Blades),
                entry_point: Some("cs_blades"),
                compilation_options: Default::default(),
                cache: None,
            }))
        })?;
        *slot = Some(pipeline.clone());
        Ok(pipeline)
    }

    /// The blade culling passes (`cs_cull_clusters`, `cs_cull_blades`, `cs_scan_blocks`,
    /// `cs_compact`) and the unculled frame's `cs_pose_all`, independent of any target.
    pub(crate) fn blade_cull(&self) -> Result<[wgpu::ComputePipeline; 5], RenderError> {
        let mut slot = lock(&self.inner.blade_cull);
        if let Some(p) = slot.as_ref() {
            return Ok(p.clone());
        }
        let device = &self.inner.device;
        let pipelines = crate::gpu_scope(device, "creating the blade culling pipelines", || {
            let module = self.inner.blade_cull_module.get_or_init(|| {
                device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some("furbake blade culling"),
                    source: wgpu::ShaderSource::Wgsl(crate::shaders::BLADE_CULL_WGSL.into()),
                })
            });
            Ok(["cs_cull_clusters", "cs_cull_blades", "cs_scan_blocks", "cs_compact", "cs_pose_all"].map(|entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&self.inner.blade_layouts.cull_pipeline),
                    module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            }))
        })?;
        *slot = Some(pipelines.clone());
        Ok(pipelines)
    }

    fn module(&self, which: Module) -> &wgpu::ShaderModule {
        let (cell, label, source) = match which {
            Module::Skin => (&self.inner.skin_module, "furbake skin", SKIN_WGSL),
            Module::Shell => (&self.inner.shell_module, "furbake shells", SHELL_WGSL),
            Module::Fin => (&self.inner.fin_module, "furbake fins", FIN_WGSL),
            Module::Blades => (&self.inner.blade_module, "furbake blades", BLADES_WGSL),
        };
        cell.get_or_init(|| {
            self.inner.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
        })
    }

    fn render_pipeline(&self, target: &TargetDesc, program: Program) -> Result<wgpu::RenderPipeline, RenderError> {
        let key = PipelineKey { target: target.clone(), program };
        // Held while creating, so two renderers asking at once create one pipeline.
        let mut map = lock(&self.inner.render);
        if let Some(p) = map.get(&key) {
            return Ok(p.clone());
        }
        let device = &self.inner.device;
        let pipeline = crate::gpu_scope(device, &format!("creating the {program:?} pipeline"), || {
            Ok(match program {
                Program::Fur(stage, switches) => self.create_fur(target, stage, switches),
                Program::Blades => self.create_blades(target),
            })
        })?;
        map.insert(key, pipeline.clone());
        Ok(pipeline)
    }

    fn create_fur(&self, target: &TargetDesc, stage: FurStage, s: FurSwitches) -> wgpu::RenderPipeline {
        let (label, module, vs, fs) = match stage {
            FurStage::Skin => ("furbake skin", self.module(Module::Skin), "vs_skin", "fs_skin"),
            FurStage::Shell => ("furbake shells", self.module(Module::Shell), "vs_shell", "fs_shell"),
            FurStage::ShellBack => ("furbake shell back faces", self.module(Module::Shell), "vs_shell", "fs_shell"),
            FurStage::Fin => ("furbake fins", self.module(Module::Fin), "vs_fin", "fs_fin"),
            FurStage::SilhouetteFin => {
                ("furbake silhouette fins", self.module(Module::Fin), "vs_silhouette_fin", "fs_fin")
            }
        };
        let flag = |on: bool| if on { 1.0 } else { 0.0 };
        // Alpha-tested shells and fins on a multisampled target turn their alpha into coverage.
        let coverage = s.alpha_to_coverage && !s.alpha_blend && target.sample_count > 1 && stage != FurStage::Skin;
        // Overrides each shader declares (the skin has no shearing or blending switch).
        let all = [
            ("LAMBERT", flag(s.lambert)),
            ("SHADOW", flag(s.shadow)),
            ("SKINNED", flag(s.skinned)),
            ("STRAND", flag(s.strand)),
            ("LIGHT_SLOTS", s.light_slots as f64),
            ("SHEAR", flag(s.shear)),
            ("ALPHA_BLEND", flag(s.alpha_blend)),
            ("ALPHA_TO_COVERAGE", flag(coverage)),
        ];
        let constants: &[(&str, f64)] = if stage == FurStage::Skin { &all[..5] } else { &all };
        let options = wgpu::PipelineCompilationOptions { constants, zero_initialize_workgroup_memory: false };
        let surface_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<SurfaceVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &SURFACE_ATTRIBUTES,
        };
        let fin_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<FinVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &FIN_ATTRIBUTES,
        };
        let buffers = [Some(if stage == FurStage::Fin { fin_layout } else { surface_layout })];
        // The silhouette fins read everything from storage buffers (groups 0 and 1).
        let buffers: &[Option<wgpu::VertexBufferLayout>] =
            if stage == FurStage::SilhouetteFin { &[] } else { &buffers };
        let layout = if stage == FurStage::SilhouetteFin {
            &self.inner.silhouette_layouts.draw_pipeline
        } else {
            &self.inner.fur_pipeline_layout
        };
        let (blend, depth_write, cull) = match stage {
            FurStage::Skin => (None, true, Some(wgpu::Face::Back)),
            // Blended shells draw their back faces first, then their front faces, so that a ray
            // grazing a silhouette blends the far side of the coat before the near side
            // (docs/design.md "Shell order"). Both are drawn: back-facing shells near the
            // silhouette are what makes it furry.
            FurStage::ShellBack => (Some(target.color.blend), false, Some(wgpu::Face::Front)),
            FurStage::Shell if s.alpha_blend => (Some(target.color.blend), false, Some(wgpu::Face::Back)),
            _ if s.alpha_blend => (Some(target.color.blend), false, None),
            // Alpha-tested shells and fins write depth: every face in one pass.
            _ => (None, true, None),
        };
        let targets = target.color_states(blend);
        self.inner.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            vertex: wgpu::VertexState { module, entry_point: Some(vs), compilation_options: options.clone(), buffers },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                cull_mode: cull,
                ..Default::default()
            },
            depth_stencil: target.depth_stencil(depth_write),
            multisample: wgpu::MultisampleState { alpha_to_coverage_enabled: coverage, ..target.multisample() },
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some(fs),
                compilation_options: options,
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    }

    fn create_blades(&self, target: &TargetDesc) -> wgpu::RenderPipeline {
        let module = self.module(Module::Blades);
        let targets = target.color_states(None);
        self.inner.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("furbake blade draw"),
            layout: Some(&self.inner.blade_layouts.draw),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some("vs_blade"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Two-sided blades.
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: target.depth_stencil(true),
            multisample: target.multisample(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fs_blade"),
                compilation_options: Default::default(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    }
}

#[derive(Clone, Copy)]
enum Module {
    Skin,
    Shell,
    Fin,
    Blades,
}

/// A poisoned lock still guards consistent data here (every critical section only reads or
/// inserts whole entries), so it is used as is.
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|p| p.into_inner())
}

fn fur_bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
    let buffer = |binding, ty, visibility| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    };
    let uniform = |binding| buffer(binding, wgpu::BufferBindingType::Uniform, vf);
    let storage =
        |binding, visibility| buffer(binding, wgpu::BufferBindingType::Storage { read_only: true }, visibility);
    let texture = |binding, view_dimension| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension,
            multisampled: false,
        },
        count: None,
    };
    let sampler = |binding| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake fur bind group layout"),
        entries: &[
            uniform(0),
            uniform(1),
            storage(2, vf),
            storage(3, vf),
            texture(4, wgpu::TextureViewDimension::D2Array),
            sampler(5),
            texture(6, wgpu::TextureViewDimension::D2),
            sampler(7),
            // The posed vertices of an animated asset, read by the vertex shaders.
            storage(8, wgpu::ShaderStages::VERTEX),
            // The shells' stacking exponents (crate::stacking), read by the shell fragments.
            storage(9, wgpu::ShaderStages::FRAGMENT),
        ],
    })
}

fn silhouette_layouts(device: &wgpu::Device, fur_layout: &wgpu::BindGroupLayout) -> SilhouetteLayouts {
    let entry = crate::compute_buffer_entry;
    let ro = wgpu::BufferBindingType::Storage { read_only: true };
    let rw = wgpu::BufferBindingType::Storage { read_only: false };
    let compute = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake silhouette selection layout"),
        entries: &[entry(0, wgpu::BufferBindingType::Uniform), entry(1, ro), entry(2, ro), entry(3, rw), entry(4, rw)],
    });
    let compute_pipeline = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("furbake silhouette selection layout"),
        bind_group_layouts: &[Some(&compute)],
        immediate_size: 0,
    });
    let vertex = |binding| wgpu::BindGroupLayoutEntry { visibility: wgpu::ShaderStages::VERTEX, ..entry(binding, ro) };
    let draw = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake silhouette fin layout"),
        entries: &[vertex(0), vertex(1), vertex(2), vertex(3)],
    });
    let draw_pipeline = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("furbake silhouette fin pipeline layout"),
        bind_group_layouts: &[Some(fur_layout), Some(&draw)],
        immediate_size: 0,
    });
    SilhouetteLayouts { compute, compute_pipeline, draw, draw_pipeline }
}

fn blade_layouts(device: &wgpu::Device) -> BladeLayouts {
    let all = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::VERTEX_FRAGMENT;
    let entry = |binding, ty, visibility| wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    };
    let ro = wgpu::BufferBindingType::Storage { read_only: true };
    let uniform = wgpu::BufferBindingType::Uniform;
    let shared = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake blade shared layout"),
        entries: &[
            entry(0, uniform, all),
            entry(1, uniform, all),
            entry(2, ro, all),
            entry(3, ro, all),
            entry(4, ro, all),
            entry(5, ro, all),
            entry(6, ro, all),
            entry(7, ro, all),
            entry(8, ro, all),
            // The culling parameters and the instance lists (the draw's only; the posing compute
            // pass stays within eight storage buffers per stage with its output).
            entry(9, uniform, wgpu::ShaderStages::VERTEX),
            entry(10, ro, wgpu::ShaderStages::VERTEX),
        ],
    });
    let rw = wgpu::BufferBindingType::Storage { read_only: false };
    let c = wgpu::ShaderStages::COMPUTE;
    let cull = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake blade culling layout"),
        entries: &[
            entry(0, uniform, c),
            entry(1, ro, c),
            entry(2, ro, c),
            entry(3, rw, c),
            entry(4, rw, c),
            entry(5, rw, c),
            entry(6, uniform, c),
            entry(7, ro, c),
            entry(8, ro, c),
            entry(9, ro, c),
            // The view's depth pyramid (`R32Float`, read with textureLoad).
            wgpu::BindGroupLayoutEntry {
                binding: 10,
                visibility: c,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
        ],
    });
    let cull_pipeline = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("furbake blade culling layout"),
        bind_group_layouts: &[Some(&cull)],
        immediate_size: 0,
    });
    let out = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("furbake blade positions out layout"),
        entries: &[entry(0, wgpu::BufferBindingType::Storage { read_only: false }, wgpu::ShaderStages::COMPUTE)],
    });
    let compute = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("furbake blade compute layout"),
        bind_group_layouts: &[Some(&shared), Some(&out)],
        immediate_size: 0,
    });
    let draw = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("furbake blade draw layout"),
        bind_group_layouts: &[Some(&shared)],
        immediate_size: 0,
    });
    BladeLayouts { shared, out, cull, draw, compute, cull_pipeline }
}
