//! The headless host of the rendering report: furbake's own frame (`FurRenderer::prepare` and
//! `render` into a `RenderTarget`'s pass, as `FurRenderer::render_to` does), on a device of its
//! own that asks for `Features::PIPELINE_STATISTICS_QUERY` when the adapter has it, so that the
//! pass can be wrapped in a pipeline-statistics query counting fragment-shader invocations — the
//! cost of a setting that does not depend on the machine's load — beside the wall time of a frame
//! (submit to finished, median of several).

use std::time::Instant;

use furbake_render::{FurAsset, FurRenderer, HeadlessGpu, RenderError, RenderSettings, RenderTarget, View};

/// A device made for measuring: furbake's headless device with pipeline statistics where the
/// adapter has them.
pub struct MeasuringGpu {
    /// The adapter's name, backend and driver.
    pub info: wgpu::AdapterInfo,
    gpu: HeadlessGpu,
    /// Whether the device counts fragment invocations (the adapter had the feature).
    pub pipeline_statistics: bool,
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
    /// has the default limits and, when available, pipeline statistics queries.
    pub fn new() -> Result<MeasuringGpu, RenderError> {
        let wanted = wgpu::Features::PIPELINE_STATISTICS_QUERY;
        let gpu = HeadlessGpu::with_optional_features(wanted)?;
        let pipeline_statistics = gpu.device.features().contains(wanted);
        Ok(MeasuringGpu { info: gpu.info.clone(), gpu, pipeline_statistics })
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
        let renderer = FurRenderer::new(self.gpu.pipelines(), &self.gpu.queue, asset, settings, &RenderTarget::desc())?;
        let target = RenderTarget::new(&self.gpu.device, width, height)?;
        let frame = view.uniforms(target.width, target.height);
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
                let mut pass = target.begin_pass(&mut encoder, "measured fur pass", Some(background));
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
        let image = furbake_render::read_back(&self.gpu.device, &self.gpu.queue, &target)?;
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
