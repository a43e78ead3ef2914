//! `furbake preview`: render headless into PNGs, in two forms:
//!
//! - `furbake preview PACK -o out.png [--size WxH]`: one pack, framed automatically
//!   (three-quarter view): skin, shells, fins (fur thesis §3.2) and its grass blades.
//! - `furbake preview SCENE.toml (-o out.png | --frames N --out-dir DIR) [--size WxH]
//!   [--settle SECONDS]`: a runtime scene. A `furbake_runtime::World` runs the stages the scene's
//!   effects call for, and a `furbake_render::SceneRenderer` built from that world draws its
//!   state (`SceneRenderer::render_world`: model matrices, fur scale vectors, grass forces with
//!   delayed-attenuation sources per blade) — the same library call any host makes. A still is the world after `--settle` seconds (default 0.5); an
//!   animation steps the world once (`time_step_s`) before each frame.
//!
//! Arguments become a validated [`PreviewPlan`] before any work starts. Every PNG is written
//! atomically (`furbake_formats::write_file_atomic`); a failed animation removes the frames it had written, so
//! a failure never leaves a partial sequence behind.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, anyhow};
use furbake_render::headless::{HeadlessGpu, RenderTarget, read_back, render_preview};
use furbake_render::{RenderError, SceneRenderer};
use furbake_runtime::RenderOptions;
use furbake_runtime::{Scene, World, WorldOptions, WorldPlan};

use crate::args::PreviewArgs;
use crate::failure::{self, Classify, Failure};

/// Scene time simulated before a still image when `--settle` is not given, seconds.
const DEFAULT_STILL_SETTLE_S: f64 = 0.5;
/// Longest `--settle`, seconds of scene time (a typo guard: an hour is ~200k steps at 60 Hz).
const MAX_SETTLE_S: f64 = 3600.0;

/// What `furbake preview` will do, validated.
#[derive(Debug)]
enum PreviewPlan {
    /// One still image of a pack.
    Pack { pack: PathBuf, output: PathBuf, size: (u32, u32), render: RenderOptions },
    /// A runtime scene, as a still or as numbered frames.
    Scene {
        scene: PathBuf,
        output: SceneOutput,
        size: (u32, u32),
        settle_s: f64,
        max_memory: u64,
        render: RenderOptions,
    },
}

/// Where a scene's images go.
#[derive(Debug)]
enum SceneOutput {
    Still(PathBuf),
    Frames { dir: PathBuf, count: u32 },
}

/// What the positional argument of `preview` and `view` is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum InputKind {
    Pack,
    Scene,
}

/// Runs `furbake preview`.
pub fn run(args: PreviewArgs, quiet: bool) -> Result<(), Failure> {
    match plan(args)? {
        PreviewPlan::Pack { pack, output, size, render } => run_pack(&pack, &output, size, &render, quiet),
        PreviewPlan::Scene { scene, output, size, settle_s, max_memory, render } => {
            run_scene(&scene, &output, size, settle_s, max_memory, &render, quiet)
        }
    }
}

/// Stage two of argument parsing: which form, and whether its flags fit it.
fn plan(args: PreviewArgs) -> Result<PreviewPlan, Failure> {
    let kind = input_kind(&args.input)?;
    let render = render_options(&args.render)?;
    match kind {
        InputKind::Pack => {
            if args.frames.is_some() || args.settle.is_some() {
                return Err(Failure::Usage(anyhow!(
                    "{}: --frames and --settle animate a runtime scene (.toml); a pack renders one still with -o",
                    args.input.display()
                )));
            }
            let output = args.output.ok_or_else(|| Failure::Usage(anyhow!("a pack preview needs -o OUT.png")))?;
            crate::files::Files::with_inputs([args.input.as_path()]).stream_output("--output", &output)?;
            Ok(PreviewPlan::Pack { pack: args.input, output, size: args.size, render })
        }
        InputKind::Scene => {
            let output = match (args.output, args.frames, args.out_dir) {
                (Some(png), None, None) => SceneOutput::Still(png),
                (None, Some(count), Some(dir)) => SceneOutput::Frames { dir, count },
                // clap enforces the pairs; this is the message should that ever change.
                _ => return Err(Failure::Usage(anyhow!("give either -o OUT.png or --frames N --out-dir DIR"))),
            };
            // The image may replace neither the scene nor a pack it names (docs/design.md "Safe
            // outputs"); frames go into a directory.
            let scene = furbake_runtime::Scene::load(&args.input).map_err(failure::scene)?;
            let mut files = crate::files::Files::with_inputs(
                std::iter::once(args.input.as_path()).chain(scene.packs().iter().map(|p| p.path.as_path())),
            );
            match &output {
                SceneOutput::Still(png) => files.stream_output("--output", png)?,
                SceneOutput::Frames { dir, .. } => {
                    if std::fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
                        return Err(Failure::Usage(anyhow!(
                            "--out-dir {}: exists and is not a directory",
                            dir.display()
                        )));
                    }
                }
            }
            let default = if matches!(output, SceneOutput::Still(_)) { DEFAULT_STILL_SETTLE_S } else { 0.0 };
            let settle_s = args.settle.unwrap_or(default);
            if !(settle_s.is_finite() && (0.0..=MAX_SETTLE_S).contains(&settle_s)) {
                return Err(Failure::Usage(anyhow!("--settle {settle_s}: seconds in 0..={MAX_SETTLE_S}")));
            }
            Ok(PreviewPlan::Scene {
                scene: args.input,
                output,
                size: args.size,
                settle_s,
                max_memory: args.max_memory,
                render,
            })
        }
    }
}

/// `.toml` is a scene and `.fbk` a pack; anything else by its content: the container magic is a
/// pack, TOML with a `packs` array a scene. A missing file with another extension is treated as
/// a pack (so the error names it as one); a readable file that is neither is a usage error.
pub(crate) fn input_kind(path: &Path) -> Result<InputKind, Failure> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("toml") => return Ok(InputKind::Scene),
        Some("fbk") => return Ok(InputKind::Pack),
        _ => {}
    }
    // Read bounded and never blocking: a FIFO, a device or a huge file is handed to the pack
    // reader, whose error says what it is.
    let Ok(bytes) = furbake_formats::input::read_bounded(path, furbake_formats::input::MAX_TEXT_BYTES, "a scene")
    else {
        return Ok(InputKind::Pack);
    };
    if bytes.starts_with(&furbake_formats::MAGIC) {
        return Ok(InputKind::Pack);
    }
    let is_scene = std::str::from_utf8(&bytes)
        .ok()
        .and_then(|text| toml::from_str::<toml::Table>(text).ok())
        .is_some_and(|table| table.get("packs").is_some_and(|p| p.is_array()));
    if is_scene {
        return Ok(InputKind::Scene);
    }
    Err(Failure::Usage(anyhow!(
        "{}: neither a pack (no furbake container magic) nor a runtime scene (TOML with [[packs]]); \
         expected PACK.fbk or SCENE.toml",
        path.display()
    )))
}

/// The render options of `--shells`, `--no-fins`, … (exit 2 naming the flag on a bad value).
pub(crate) fn render_options(flags: &crate::args::RenderFlags) -> Result<RenderOptions, Failure> {
    flags.options().map_err(|(flag, what)| Failure::Usage(anyhow!("{flag}: {what}")))
}

fn run_pack(
    pack: &Path,
    output: &Path,
    (w, h): (u32, u32),
    render: &RenderOptions,
    quiet: bool,
) -> Result<(), Failure> {
    let opened = crate::describe::open_verified(pack)?;
    let image = match render_preview(&opened, w, h, render) {
        Ok(img) => img,
        Err(e @ RenderError::Parameter { .. }) => return Err(Failure::Usage(e.into())),
        Err(e) => {
            return Err(Failure::Input(anyhow::Error::new(e).context(format!("{}: cannot render", pack.display()))));
        }
    };
    write_png(output, &image)?;
    if !quiet {
        eprintln!("rendered {} → {} ({w}×{h})", pack.display(), output.display());
    }
    Ok(())
}

/// What rendering a scene frame needs: the scene file (for messages), its running world, and the
/// headless host that draws it.
struct SceneRun {
    path: PathBuf,
    world: World,
    gpu: HeadlessGpu,
    renderer: SceneRenderer,
    target: RenderTarget,
}

impl SceneRun {
    /// Loads the scene, builds its world, checks the renderers' estimated GPU memory against
    /// `max_memory` before creating anything on the GPU, and builds a renderer that shares the
    /// world's packs.
    fn start(path: &Path, (w, h): (u32, u32), max_memory: u64, render: &RenderOptions) -> Result<SceneRun, Failure> {
        // The headless target: colour and depth, 4 bytes a pixel each.
        let world = open_scene_world(path, 8 * w as u64 * h as u64, max_memory)?;
        let gpu = HeadlessGpu::new().map_err(|e| render_failure(e, path))?;
        let mut renderer = SceneRenderer::for_target_with(
            gpu.pipelines(),
            &gpu.queue,
            &world,
            &RenderTarget::desc(),
            &furbake_render::headless::options_for_adapter(render, &gpu.info, Some(world.scene())),
        )
        .map_err(|e| render_failure(e, path))?;
        // Grass hidden behind the scene's fur is culled against the depth the fur leaves
        // (docs/design.md "Depth pyramid and occlusion culling"): the same picture, fewer blades.
        if renderer.packs().iter().any(|p| p.blades.is_some()) {
            renderer.set_grass_occlusion(gpu.pipelines(), Some((w, h))).map_err(|e| render_failure(e, path))?;
        }
        let target = RenderTarget::new(&gpu.device, w, h).map_err(|e| render_failure(e, path))?;
        Ok(SceneRun { path: path.to_path_buf(), world, gpu, renderer, target })
    }

    /// Advances the world one step.
    fn step(&mut self) -> Result<(), Failure> {
        self.world.step().map_err(|e| failure::runtime(e, &self.path))
    }

    /// Draws the world's current state (`SceneRenderer::render_world`) and writes it as a PNG.
    fn render_to(&self, png: &Path) -> Result<(), Failure> {
        let g = &self.gpu;
        let image = self
            .renderer
            .render_world(&g.device, &g.queue, &self.target, &self.world)
            .and_then(|_| read_back(&g.device, &g.queue, &self.target))
            .and_then(|image| g.check().map(|()| image))
            .map_err(|e| render_failure(e, &self.path))?;
        write_png(png, &image)
    }

    /// Steps and renders `count` frames into `dir`. On failure the frames already written are
    /// removed: each file was whole, but the sequence is not.
    fn render_frames(&mut self, dir: &Path, count: u32) -> Result<(), Failure> {
        let mut written: Vec<PathBuf> = Vec::with_capacity(count as usize);
        let mut frames = || -> Result<(), Failure> {
            for i in 0..count {
                self.step()?;
                let file = dir.join(frame_name(i, count));
                self.render_to(&file)?;
                written.push(file);
            }
            Ok(())
        };
        let result = frames();
        if result.is_err() {
            for file in &written {
                let _ = std::fs::remove_file(file);
            }
        }
        result
    }
}

/// Loads the runtime scene at `path`, validates its packs and builds its world (`furbake preview`
/// and `furbake view`).
/// The renderers' GPU memory is then checked against `max_memory` before anything is created on
/// the GPU ([`check_gpu_memory`]).
pub(crate) fn open_scene_world(path: &Path, target_bytes: u64, max_memory: u64) -> Result<World, Failure> {
    let world = plan_scene_world(path)?.build().map_err(|e| failure::runtime(e, path))?;
    check_gpu_memory(&world, path, target_bytes, max_memory)?;
    Ok(world)
}

/// The world of the runtime scene at `path` as `preview` and `view` plan it: every pack validated
/// as `verify` does before the world reads it (docs/design.md "Runtime: packs") and planned as
/// `simulate` plans it ([`crate::describe::plan_scene`]); the world and the renderers share what
/// verification decoded.
pub(crate) fn plan_scene_world(path: &Path) -> Result<WorldPlan, Failure> {
    let scene = Scene::load(path).map_err(failure::scene)?;
    crate::describe::plan_scene(scene, path, WorldOptions::default())
}

/// Refuses (exit 2) a world whose renderers' estimated GPU memory
/// (`SceneRenderer::estimate_gpu_bytes`) plus the host's `target_bytes` (its colour and depth
/// targets) is above `max_memory`.
pub(crate) fn check_gpu_memory(world: &World, path: &Path, target_bytes: u64, max_memory: u64) -> Result<(), Failure> {
    let need =
        SceneRenderer::estimate_gpu_bytes(world).map_err(|e| render_failure(e, path))?.saturating_add(target_bytes);
    if need > max_memory {
        return Err(Failure::Usage(anyhow!(
            "{}: the scene's {} pack entries need about {} MiB of GPU memory, above --max-memory {}; \
             place fewer entries or raise --max-memory",
            path.display(),
            world.pack_count(),
            need.div_ceil(1 << 20),
            crate::args::format_bytes(max_memory)
        )));
    }
    Ok(())
}

fn run_scene(
    path: &Path,
    output: &SceneOutput,
    (w, h): (u32, u32),
    settle_s: f64,
    max_memory: u64,
    render: &RenderOptions,
    quiet: bool,
) -> Result<(), Failure> {
    let started = Instant::now();
    let mut run = SceneRun::start(path, (w, h), max_memory, render)?;
    let step_s = run.world.scene().time_step_s();
    let settle_steps = (settle_s / step_s as f64 - 1e-9).ceil().max(0.0);
    let frames = match output {
        SceneOutput::Frames { count, .. } => u64::from(*count),
        SceneOutput::Still(_) => 1,
    };
    if settle_steps + frames as f64 > crate::args::MAX_STEPS as f64 {
        return Err(Failure::Usage(anyhow!(
            "{}: settling {settle_s} s at time_step_s = {step_s} and rendering {frames} frames is {} steps, above \
             {}; lengthen time_step_s, settle less (--settle) or render fewer frames",
            path.display(),
            settle_steps + frames as f64,
            crate::args::MAX_STEPS
        )));
    }
    for _ in 0..settle_steps as u64 {
        run.step()?;
    }
    let start_time_s = run.world.time_s();
    match output {
        SceneOutput::Still(png) => {
            run.render_to(png)?;
            if !quiet {
                eprintln!(
                    "rendered {} at {:.3} s scene time → {} ({w}×{h}, {:.2} s wall)",
                    path.display(),
                    start_time_s,
                    png.display(),
                    started.elapsed().as_secs_f64()
                );
            }
        }
        SceneOutput::Frames { dir, count } => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create directory", dir.display()))
                .input()?;
            run.render_frames(dir, *count)?;
            if !quiet {
                eprintln!(
                    "rendered {} for {count} frames of {step_s} s ({start_time_s:.3}–{:.3} s scene time) \
                     → {}/{} … ({w}×{h}, {:.2} s wall)",
                    path.display(),
                    run.world.time_s(),
                    dir.display(),
                    frame_name(0, *count),
                    started.elapsed().as_secs_f64()
                );
            }
        }
    }
    Ok(())
}

/// `frame_0007.png`: zero-padded to the digits of the last index, at least four.
fn frame_name(index: u32, count: u32) -> String {
    let width = count.saturating_sub(1).to_string().len().max(4);
    format!("frame_{index:0width$}.png")
}

/// Encodes `image` as a PNG and writes it atomically (`furbake_formats::write_file_atomic`).
pub(crate) fn write_png(path: &Path, image: &image::RgbaImage) -> Result<(), Failure> {
    let mut bytes = Vec::new();
    image
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot encode PNG", path.display()))
        .input()?;
    crate::files::write_output(path, &bytes, "the image")
}

/// A render error of the scene at `scene`: a bad parameter (the target size against the
/// device's limit) is a usage error, anything else bad input.
pub(crate) fn render_failure(e: RenderError, scene: &Path) -> Failure {
    match e {
        // The only caller-side parameter here is --size (checked against the device's limit).
        RenderError::Parameter { .. } => Failure::Usage(e.into()),
        e => Failure::Input(anyhow::Error::new(e).context(format!("{}: cannot render", scene.display()))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_names_pad_to_the_last_index() {
        assert_eq!(frame_name(0, 3), "frame_0000.png");
        assert_eq!(frame_name(9999, 10_000), "frame_9999.png");
        assert_eq!(frame_name(12, 10_001), "frame_00012.png");
        assert_eq!(frame_name(0, 1), "frame_0000.png");
    }
}
