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
