//! [`TargetDesc`]: what a host's render pass looks like to the renderers that draw into it — the
//! colour attachment's format, how translucent fur blends into it and which channels it may
//! write, the formats of further colour attachments fur leaves alone, the depth attachment's
//! format and comparison, and the sample count. Every pipeline is built for one description
//! ([`crate::PipelineCache`] keys them by it), so a renderer draws into any pass whose attachments
//! match it, at any size: resizing the host's textures rebuilds nothing.
//!
//! Validated once against the device before any pipeline is built ([`TargetDesc::validate`]):
//! each format must be renderable, blendable where fur blends, and support the sample count
//! (WebGPU specification, "Texture Format Capabilities"; wgpu's
//! `TextureFormat::guaranteed_format_features`, or the adapter's own table when the device was
//! created with `Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES`).
//!
//! [`RenderTarget`] is the headless host's own pass (`crate::headless`): textures of fixed formats
//! matching [`RenderTarget::desc`], here below the host and the scene frames that draw into it.

use crate::RenderError;

/// The colour attachment fur and grass write (fragment output `@location(0)`). Shaders write
/// linear RGB and straight (not premultiplied) alpha; an sRGB format encodes on store, a float
/// format (HDR) keeps the linear values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ColorTarget {
    /// The attachment's format (e.g. the swapchain's `Bgra8UnormSrgb`, or an HDR `Rgba16Float`).
    pub format: wgpu::TextureFormat,
    /// How the translucent stages (shells and fins with [`crate::ShellBlend::AlphaBlend`]) combine
    /// with what the host drew before them. Opaque stages (skin, alpha-tested shells, grass
    /// blades) replace. Default [`wgpu::BlendState::ALPHA_BLENDING`] (straight alpha "over").
    pub blend: wgpu::BlendState,
    /// Channels written. Default all.
    pub write_mask: wgpu::ColorWrites,
}

impl ColorTarget {
    /// `format` with straight alpha blending and every channel written.
    pub fn new(format: wgpu::TextureFormat) -> ColorTarget {
        ColorTarget { format, blend: wgpu::BlendState::ALPHA_BLENDING, write_mask: wgpu::ColorWrites::ALL }
    }
}

/// The host's depth (or depth-stencil) attachment. Fur and grass test against it and write the
/// depth of their opaque stages (skin, alpha-tested shells, blades); blended shells and fins only
/// test. The stencil aspect, if any, is neither tested nor written.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct DepthTarget {
    /// A format with a depth aspect (`Depth32Float`, `Depth24Plus`, `Depth24PlusStencil8`, ...).
    pub format: wgpu::TextureFormat,
    /// How a fragment's depth compares with the stored one to pass: `LessEqual` for the usual
    /// depth in [0, 1] growing away from the eye (what [`crate::View`] produces), `GreaterEqual`
    /// for a reversed-Z host that passes its own projection in
    /// [`crate::shaders::FrameUniforms::view_proj`].
    pub compare: wgpu::CompareFunction,
}

/// A host's render pass as the pipelines see it (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct TargetDesc {
    /// Colour attachment 0, the one drawn.
    pub color: ColorTarget,
    /// Formats of colour attachments 1, 2, ... of the host's pass (a G-buffer, a velocity
    /// target): fur writes none of them (write mask empty), but a pipeline must list every
    /// attachment of the pass it is used in. Usually empty.
    pub extra_color_formats: Vec<wgpu::TextureFormat>,
    /// The depth attachment, or `None` for a pass without one (fur is then drawn in submission
    /// order without occlusion, which only suits overlays).
    pub depth: Option<DepthTarget>,
    /// Samples per pixel of every attachment: 1, or 2/4/8/16 for MSAA where the formats allow it
    /// (4 is guaranteed for the common renderable formats). The host resolves.
    pub sample_count: u32,
}

impl TargetDesc {
    /// One colour attachment of `format` ([`ColorTarget::new`]), no depth, one sample.
    pub fn new(format: wgpu::TextureFormat) -> TargetDesc {
        TargetDesc { color: ColorTarget::new(format), extra_color_formats: Vec::new(), depth: None, sample_count: 1 }
    }

    /// This description with a depth attachment of `format`, compared with `compare`.
    pub fn with_depth(self, format: wgpu::TextureFormat, compare: wgpu::CompareFunction) -> TargetDesc {
        TargetDesc { depth: Some(DepthTarget { format, compare }), ..self }
    }

    /// This description with `sample_count` samples per pixel.
    pub fn with_samples(self, sample_count: u32) -> TargetDesc {
        TargetDesc { sample_count, ..self }
    }

    /// Checks that `device` can draw into such a pass: every colour format renderable (and
    /// attachment 0 blendable when `blended`, i.e. when some stage alpha-blends), the depth
    /// format a depth format, every format supporting the sample count, and no format needing a
    /// feature the device lacks. `adapter` is consulted only when the device was created with
    /// `Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES` (then the adapter's table applies, not
    /// the guaranteed one). Errors are [`RenderError::UnsupportedTarget`] naming the format and
    /// what it lacks.
    pub fn validate(
        &self,
        device: &wgpu::Device,
        adapter: Option<&wgpu::Adapter>,
        blended: bool,
    ) -> Result<(), RenderError> {
        let unsupported = |what: String| Err(RenderError::UnsupportedTarget { what });
        let n = self.sample_count;
        if !matches!(n, 1 | 2 | 4 | 8 | 16) {
            return unsupported(format!("sample count {n} (1, 2, 4, 8 or 16)"));
        }
        let features = |format: wgpu::TextureFormat| {
            let adapter_specific = device.features().contains(wgpu::Features::TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES);
            match adapter.filter(|_| adapter_specific) {
                Some(a) => a.get_texture_format_features(format),
                None => format.guaranteed_format_features(device.features()),
            }
        };
        let check = |format: wgpu::TextureFormat, role: &str| -> Result<wgpu::TextureFormatFeatures, RenderError> {
            let missing = format.required_features() - device.features();
            if !missing.is_empty() {
                return Err(RenderError::UnsupportedTarget {
                    what: format!("{role} format {format:?} needs device features {missing:?}"),
                });
            }
            let f = features(format);
            if !f.allowed_usages.contains(wgpu::TextureUsages::RENDER_ATTACHMENT) {
                return Err(RenderError::UnsupportedTarget {
                    what: format!("{role} format {format:?} is not renderable on this device"),
                });
            }
            if !f.flags.sample_count_supported(n) {
                return Err(RenderError::UnsupportedTarget {
                    what: format!(
                        "{role} format {format:?} does not support {n} samples on this device (supported: {:?})",
                        f.flags.supported_sample_counts()
                    ),
                });
            }
            Ok(f)
        };
        let colors = std::iter::once(&self.color.format).chain(&self.extra_color_formats);
        for (i, &format) in colors.enumerate() {
            if format.is_depth_stencil_format() {
                return unsupported(format!("colour attachment {i} has the depth format {format:?}"));
            }
            let f = check(format, &format!("colour attachment {i}"))?;
            if i == 0 && blended && !f.flags.contains(wgpu::TextureFormatFeatureFlags::BLENDABLE) {
                return unsupported(format!(
                    "colour format {format:?} is not blendable on this device; draw the shells with \
                     ShellBlend::AlphaTest or use a blendable format"
                ));
            }
        }
        if let Some(depth) = &self.depth {
            if !depth.format.has_depth_aspect() {
                return unsupported(format!("depth attachment format {:?} has no depth aspect", depth.format));
            }
            check(depth.format, "depth attachment")?;
        }
        Ok(())
    }

    /// The multisample state of every pipeline (no alpha-to-coverage).
    pub(crate) fn multisample(&self) -> wgpu::MultisampleState {
        wgpu::MultisampleState { count: self.sample_count, mask: !0, alpha_to_coverage_enabled: false }
    }

    /// The depth-stencil state of a stage that writes depth or only tests it.
    pub(crate) fn depth_stencil(&self, write: bool) -> Option<wgpu::DepthStencilState> {
        self.depth.map(|d| wgpu::DepthStencilState {
            format: d.format,
            depth_write_enabled: Some(write),
            depth_compare: Some(d.compare),
            stencil: Default::default(),
            bias: Default::default(),
        })
    }

    /// The colour target states of a stage: attachment 0 with `blend` (`None`: replace), the
    /// others listed and left unwritten.
    pub(crate) fn color_states(&self, blend: Option<wgpu::BlendState>) -> Vec<Option<wgpu::ColorTargetState>> {
        let first = wgpu::ColorTargetState { format: self.color.format, blend, write_mask: self.color.write_mask };
        let rest = self.extra_color_formats.iter().map(|&format| wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask: wgpu::ColorWrites::empty(),
        });
        std::iter::once(first).chain(rest).map(Some).collect()
    }
}

/// Colour format of [`RenderTarget`]s (sRGB-encoded 8-bit RGBA; shaders write linear colour).
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format of [`RenderTarget`]s.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// An offscreen colour + depth target of a given size: the headless host's pass.
pub struct RenderTarget {
    /// Colour texture ([`COLOR_FORMAT`], copyable to a buffer).
    pub color: wgpu::Texture,
    /// Depth texture ([`DEPTH_FORMAT`]).
    pub depth: wgpu::Texture,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl RenderTarget {
    /// The pass every render target makes: [`COLOR_FORMAT`] with straight alpha blending,
    /// [`DEPTH_FORMAT`] compared `LessEqual`, one sample. Renderers drawn by this host are built
    /// for it.
    pub fn desc() -> TargetDesc {
        TargetDesc::new(COLOR_FORMAT).with_depth(DEPTH_FORMAT, wgpu::CompareFunction::LessEqual)
    }

    /// Creates a `width × height` target; fails when a side is 0 or above the device's limit.
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Result<RenderTarget, RenderError> {
        let max = device.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::Parameter {
                what: format!("target size {width}×{height} (each side in 1..={max})"),
            });
        }
        crate::gpu_scope(device, &format!("creating a {width}×{height} render target"), || {
            Ok(Self::create(device, width, height))
        })
    }

    fn create(device: &wgpu::Device, width: u32, height: u32) -> RenderTarget {
        let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
        let make = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = make(
            "furbake color target",
            COLOR_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        // Readable by a depth pyramid (grass occlusion culling).
        let depth = make(
            "furbake depth target",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        RenderTarget { color, depth, width, height }
    }

    /// Width / height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// Begins a render pass into this target's colour and depth textures: cleared to the linear
    /// RGBA `clear` (depth to 1), or, with `None`, over what earlier passes left.
    pub fn begin_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        clear: Option<[f32; 4]>,
    ) -> wgpu::RenderPass<'e> {
        let color_view = self.color.create_view(&Default::default());
        let depth_view = self.depth.create_view(&Default::default());
        let (color_load, depth_load) = match clear {
            Some(c) => {
                let [r, g, b, a] = c.map(f64::from);
                (wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }), wgpu::LoadOp::Clear(1.0))
            }
            None => (wgpu::LoadOp::Load, wgpu::LoadOp::Load),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations { load: color_load, store: wgpu::StoreOp::Store },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth_view,
                depth_ops: Some(wgpu::Operations { load: depth_load, store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// Refuses a renderer built for another pass than this host's.
    pub(crate) fn check_renderer(&self, renderer_target: &TargetDesc) -> Result<(), RenderError> {
        if *renderer_target != Self::desc() {
            return Err(RenderError::Parameter {
                what: format!(
                    "a renderer built for {renderer_target:?} drawn into a headless RenderTarget (built for RenderTarget::desc())"
                ),
            });
        }
        Ok(())
    }
}
