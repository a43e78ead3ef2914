//! The headless host of the rendering report: furbake's own frame (`FurRenderer::prepare` and
//! `render` into a `RenderTarget`'s pass, as `FurRenderer::render_to` does), on a device of its
//! own that asks for `Features::PIPELINE_STATISTICS_QUERY` when the adapter has it, so that the
//! pass can be wrapped in a pipeline-statistics query counting fragment-shader invocations — the
//! cost of a setting that does not depend on the machine's load — beside the wall time of a frame
//! (submit to finished, median of several).

use std::time::Instant;

use furbake_render::headless::{HeadlessGpu, RenderTarget};
use furbake_render::{FurAsset, FurRenderer, RenderError, RenderSettings, View};

/// A device made for measuring: furbake's headless device with pipeline statistics and blendable
/// 32-bit float targets where the adapter has them.
pub struct MeasuringGpu {
    /// The adapter's name, backend and driver.
    pub info: wgpu::AdapterInfo,
    gpu: HeadlessGpu,
    /// Whether the device counts fragment invocations (the adapter had the feature).
    pub pipeline_statistics: bool,
    /// Whether the device blends into `Rgba32Float` (`Features::FLOAT32_BLENDABLE`).
    pub float32_blendable: bool,
    /// What the frames are drawn into. Default [`ReportTarget::Srgb8`], the headless host's.
    pub target: ReportTarget,
}

/// The colour target furbake's frames are drawn into; every frame is read back encoded to sRGB
/// 8-bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReportTarget {
    /// `Rgba32Float`: the blending rounds no layer away, so the measured error is the slicing's.
    Float32,
    /// `Rgba16Float`, as HDR hosts draw.
    Float16,
    /// The headless host's `Rgba8UnormSrgb`.
    Srgb8,
}

impl ReportTarget {
    /// Its colour format, `None` for the headless host's own target.
    fn format(self) -> Option<wgpu::TextureFormat> {
        match self {
            ReportTarget::Float32 => Some(wgpu::TextureFormat::Rgba32Float),
            ReportTarget::Float16 => Some(wgpu::TextureFormat::Rgba16Float),
            ReportTarget::Srgb8 => None,
        }
    }

    /// How the document names it.
    pub fn describe(self) -> &'static str {
        match self {
            ReportTarget::Float32 => {
                "an `Rgba32Float` target, so that the blending of many faint layers rounds nothing away (`--f16-target` draws into `Rgba16Float`, as HDR hosts do), read back encoded to sRGB 8-bit"
            }
            ReportTarget::Float16 => "an `Rgba16Float` target, as HDR hosts draw, read back encoded to sRGB 8-bit",
            ReportTarget::Srgb8 => "the headless host's `Rgba8UnormSrgb` target",
        }
    }
}

/// A float colour target and the headless host's depth, for [`MeasuringGpu::measure`].
struct FloatTarget {
    color: wgpu::Texture,
    depth: wgpu::Texture,
}

impl FloatTarget {
    fn new(device: &wgpu::Device, format: wgpu::TextureFormat, width: u32, height: u32) -> FloatTarget {
        let make = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color =
            make("report float colour", format, wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC);
        let depth =
            make("report float depth", furbake_render::headless::DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
        FloatTarget { color, depth }
    }

    fn desc(format: wgpu::TextureFormat) -> furbake_render::TargetDesc {
        furbake_render::TargetDesc::new(format)
            .with_depth(furbake_render::headless::DEPTH_FORMAT, wgpu::CompareFunction::LessEqual)
    }

    fn begin_pass<'e>(&self, encoder: &'e mut wgpu::CommandEncoder, clear: [f32; 4]) -> wgpu::RenderPass<'e> {
        let color = self.color.create_view(&Default::default());
        let depth = self.depth.create_view(&Default::default());
        let [r, g, b, a] = clear.map(f64::from);
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("report float pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &depth,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// The frame, linear half or single floats encoded to sRGB 8-bit.
    fn read_back(&self, gpu: &MeasuringGpu) -> Result<image::RgbaImage, RenderError> {
        let (w, h) = (self.color.width(), self.color.height());
        let single = self.color.format() == wgpu::TextureFormat::Rgba32Float;
        let texel = if single { 16 } else { 8 };
        let row = w * texel;
        let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let device = &gpu.gpu.device;
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("report float readback"),
            size: padded as u64 * h as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(padded), rows_per_image: Some(h) },
            },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
        gpu.gpu.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        gpu.wait()?;
        rx.recv().map_err(gpu_error)?.map_err(gpu_error)?;
        let mut image = image::RgbaImage::new(w, h);
        {
            let view = buffer.get_mapped_range(..).map_err(gpu_error)?;
            for y in 0..h {
                for x in 0..w {
                    let at = (y * padded + x * texel) as usize;
                    let px: [u8; 4] = std::array::from_fn(|c| {
                        let v = if single {
                            let b = at + 4 * c;
                            f32::from_le_bytes([view[b], view[b + 1], view[b + 2], view[b + 3]])
                        } else {
                            half_to_f32(u16::from_le_bytes([view[at + 2 * c], view[at + 2 * c + 1]]))
                        };
                        let v = if c == 3 { v } else { linear_to_srgb(v) };
                        (v.clamp(0.0, 1.0) * 255.0).round() as u8
                    });
                    image.put_pixel(x, y, image::Rgba(px));
                }
            }
        }
        buffer.unmap();
        Ok(image)
    }
}

/// An IEEE half float's value.
fn half_to_f32(h: u16) -> f32 {
    let (sign, exp, frac) = ((h >> 15) as u32, ((h >> 10) & 0x1f) as i32, (h & 0x3ff) as f32);
    let magnitude = match exp {
        0 => frac * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    };
    if sign == 1 { -magnitude } else { magnitude }
}

/// The sRGB encoding of a linear value in [0, 1].
fn linear_to_srgb(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// One measured frame.
#[derive(Clone, Debug)]
pub struct MeasuredFrame {
    /// The frame read back (sRGB-encoded RGBA8).
    pub image: image::RgbaImage,
    /// Fragment-shader invocations of the fur pass (skin, shells, fins), when counted.
    pub fragments: Option<u64>,
    /// Median wall time of a frame in milliseconds (record, submit, wait), over the timed frames.
    pub frame_ms: f64,
}

fn gpu_error(what: impl std::fmt::Display) -> RenderError {
    RenderError::Gpu { what: what.to_string() }
}

impl MeasuringGpu {
    /// A hardware adapter, else a fallback (software) one, as `HeadlessGpu::new` picks; the device
    /// has the default limits and, when available, pipeline statistics queries and blendable
    /// 32-bit float targets.
    pub fn new() -> Result<MeasuringGpu, RenderError> {
        let statistics = wgpu::Features::PIPELINE_STATISTICS_QUERY;
        let blendable = wgpu::Features::FLOAT32_BLENDABLE;
        let gpu = HeadlessGpu::with_optional_features(statistics | blendable)?;
        let features = gpu.device.features();
        Ok(MeasuringGpu {
            info: gpu.info.clone(),
            pipeline_statistics: features.contains(statistics),
            float32_blendable: features.contains(blendable),
            gpu,
            target: ReportTarget::Srgb8,
        })
    }

    /// Draws into `wanted` from now on, or into `Float16` where it is `Float32` and the adapter
    /// does not blend into that; returns the target drawn into.
    pub fn set_target(&mut self, wanted: ReportTarget) -> ReportTarget {
        self.target = match wanted {
            ReportTarget::Float32 if !self.float32_blendable => ReportTarget::Float16,
            t => t,
        };
        self.target
    }

    fn check(&self) -> Result<(), RenderError> {
        self.gpu.check()
    }

    fn wait(&self) -> Result<(), RenderError> {
        self.gpu.device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(gpu_error)
    }

    /// Renders `asset` with `settings` from `view` into a `width × height` target: one frame with
    /// the statistics query (when available) that is read back, then `timed_frames` more timed
    /// (at least one; the first, which builds pipelines, is not among them).
    pub fn measure(
        &self,
        asset: &FurAsset,
        settings: &RenderSettings,
        view: &View,
        width: u32,
        height: u32,
        timed_frames: u32,
    ) -> Result<MeasuredFrame, RenderError> {
        let format = self.target.format();
        let desc = format.map_or_else(RenderTarget::desc, FloatTarget::desc);
        let renderer = FurRenderer::new(self.gpu.pipelines(), &self.gpu.queue, asset, settings, &desc)?;
        let target = RenderTarget::new(&self.gpu.device, width, height)?;
        let float = format.map(|f| FloatTarget::new(&self.gpu.device, f, width, height));
        let frame = view.uniforms(width, height);
        let query = self.pipeline_statistics.then(|| {
            let set = self.gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("fur pass statistics"),
                ty: wgpu::QueryType::PipelineStatistics(wgpu::PipelineStatisticsTypes::FRAGMENT_SHADER_INVOCATIONS),
                count: 1,
            });
            let resolve = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("statistics resolve"),
                size: 8,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("statistics readback"),
                size: 8,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            (set, resolve, read)
        });
        let background = settings.background;
        let record = |with_query: bool| {
            let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
            renderer.prepare(&self.gpu.queue, &mut encoder, &frame);
            {
                let mut pass = match &float {
                    Some(f) => f.begin_pass(&mut encoder, background),
                    None => target.begin_pass(&mut encoder, "measured fur pass", Some(background)),
                };
                match (&query, with_query) {
                    (Some((set, _, _)), true) => {
                        pass.begin_pipeline_statistics_query(set, 0);
                        renderer.render(&mut pass);
                        pass.end_pipeline_statistics_query();
                    }
                    _ => renderer.render(&mut pass),
                }
            }
            if let (Some((set, resolve, read)), true) = (&query, with_query) {
                encoder.resolve_query_set(set, 0..1, resolve, 0);
                encoder.copy_buffer_to_buffer(resolve, 0, read, 0, 8);
            }
            encoder.finish()
        };
        self.gpu.queue.submit([record(true)]);
        self.wait()?;
        let fragments = match &query {
            Some((_, _, read)) => {
                let (tx, rx) = std::sync::mpsc::channel();
                read.map_async(wgpu::MapMode::Read, .., move |r| {
                    let _ = tx.send(r);
                });
                self.wait()?;
                rx.recv().map_err(gpu_error)?.map_err(gpu_error)?;
                let value = {
                    let view = read.get_mapped_range(..).map_err(gpu_error)?;
                    u64::from_le_bytes(view[..8].try_into().map_err(gpu_error)?)
                };
                read.unmap();
                Some(value)
            }
            None => None,
        };
        let image = match &float {
            Some(f) => f.read_back(self)?,
            None => furbake_render::headless::read_back(&self.gpu.device, &self.gpu.queue, &target)?,
        };
        let mut times = Vec::new();
        for _ in 0..timed_frames.max(1) {
            let start = Instant::now();
            self.gpu.queue.submit([record(false)]);
            self.wait()?;
            times.push(start.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        self.check()?;
        Ok(MeasuredFrame { image, fragments, frame_ms: times[times.len() / 2] })
    }
}
