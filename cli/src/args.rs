//! Raw command-line flags (stage one of two: `bake_cmd` turns them into a validated plan).

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

const EXIT_CODES: &str = "Exit codes: 0 success, 1 bad input or invalid file (the message names the file and the \
problem), 2 usage error.";

/// Bake real-time fur and grass assets from glTF meshes, and inspect the baked packs.
#[derive(Parser, Debug)]
#[command(name = "furbake", version, after_help = EXIT_CODES)]
pub struct Cli {
    /// Print nothing but errors (no progress bar, no summaries).
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// Worker threads (default: one per core). Output is identical for any value.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(usize))]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Bake a glTF mesh (.glb, or .gltf with external buffers) into one pack file.
    #[command(after_help = EXIT_CODES)]
    Bake(BakeArgs),
    /// Bake many assets listed in a TOML file (shared defaults, per-asset overrides), skipping
    /// those whose pack is up to date.
    #[command(after_help = BATCH_HELP)]
    Batch(BatchArgs),
    /// Describe a pack or single-artifact file: sections, sizes, parameters, statistics.
    #[command(after_help = EXIT_CODES)]
    Inspect(InspectArgs),
    /// Check everything in a file (header, table, checksums, every section's contents);
    /// exit 0 when valid, 1 otherwise.
    #[command(after_help = EXIT_CODES)]
    Verify(VerifyArgs),
    /// Bake a grass-blade keyframe table alone into a single-section file (grass thesis §3.2–3.3).
    #[command(after_help = EXIT_CODES)]
    Keyframes(KeyframesArgs),
    /// Render a pack (skin, shells, fins, blades) or a runtime scene (its packs placed, lit and
    /// animated by the scene's effects) headless into PNGs, on a GPU or on Mesa's software Vulkan
    /// driver (lavapipe) when there is none.
    #[command(after_help = PREVIEW_HELP)]
    Preview(PreviewArgs),
    /// Show a runtime scene (or a pack in a default scene) live in a window, on any adapter
    /// (lavapipe included): orbit, pan and zoom the camera, play, pause and scrub time, switch
    /// clips, switch effects off and on; `--frames N --screenshot FILE.png` runs unattended.
    #[command(after_help = VIEW_HELP)]
    View(ViewArgs),
    /// Run a runtime scene headless: per-stage timings, per-step statistics (`--json`) and the
    /// final state in world space (`--state-out`).
    #[command(after_help = EXIT_CODES)]
    Simulate(SimulateArgs),
    /// Regenerate a measured report (`accuracy`: docs/accuracy.md and its plots).
    #[command(after_help = EXIT_CODES)]
    Report(ReportArgs),
    /// Write a file's atlases as PNG images and its description as JSON into a directory.
    #[command(after_help = EXIT_CODES)]
    Extract(ExtractArgs),
    /// Export a pack as a self-contained binary glTF 2.0 (.glb) any viewer opens: the skin, one
    /// alpha-blended mesh per shell layer, the fins, the atlases as PNG textures, and for an
    /// animated pack the skeleton, skin and clips.
    #[command(after_help = EXIT_CODES)]
    Export(ExportArgs),
    /// Print the JSON Schema of a file people write by hand (`scene`: runtime scenes; `config`:
    /// bake configs; `batch`: batch files), for editors that validate and complete TOML against
    /// it (docs/schemas/).
    #[command(after_help = EXIT_CODES)]
    Schema(SchemaArgs),
    /// Write the renderer's shaders for another graphics API — every entry point and switch
    /// combination, translated by naga into SPIR-V, GLSL 4.50, HLSL or MSL — and manifest.json:
    /// each file's bindings (with what the C interface gives for each), vertex inputs, switches,
    /// and the layouts of its structs (docs/c-api.md "Shaders").
    #[command(after_help = EXIT_CODES)]
    Shaders(ShadersArgs),
}

/// What `--max-memory` defaults to, in bytes (2 GiB).
pub const DEFAULT_MAX_MEMORY: u64 = 2 << 30;

/// Most scene steps one command may take: `simulate`'s frames, `preview`'s settle and frames (a
/// typo guard: 10⁶ steps are 4.6 hours of scene time at 60 Hz, while `time_step_s = 1e-7` would
/// make half a second of settling 5,000,000 steps).
pub const MAX_STEPS: u64 = 1_000_000;

const BATCH_HELP: &str = "The batch file (paths relative to it):

  [defaults]                  # all optional
  preset = \"fur\"              # fur | grass
  config = \"fur.toml\"         # a bake config file, as --config
  out_dir = \"packs\"           # packs go to out_dir/<input stem>.fbk unless an asset says output
  depfile = true              # also write <pack>.d
  max_memory = \"2G\"
  asset_root = \"textures\"     # as --asset-root
  [defaults.settings]         # any bake setting, as in a config file
  volume.resolution = 64

  [[asset]]
  input = \"models/Fox.glb\"
  output = \"packs/fox.fbk\"    # optional; preset, config, depfile, max_memory, asset_root too
  [asset.settings]            # applied after the defaults' settings
  topologies = [\"prisms\"]

An asset is skipped when its pack's manifest records this furbake version, the same resolved
settings and the same bytes for every file the bake read (--force bakes anyway). Every asset's
settings are checked before anything is baked (exit 2). `--shard K/N` then bakes only the assets
whose output path (as the batch file spells it) hashes to slice K of N: run it with K = 1..N on N
machines and together they bake the whole batch. Exit codes: 0 all baked or skipped,
1 some asset failed (the others are still written) or the batch file is bad, 2 bad flags or
settings.";

/// `furbake batch`
#[derive(Args, Debug)]
pub struct BatchArgs {
    /// The batch file (TOML; see below).
    pub file: PathBuf,
    /// Bakes run at once (default: one per core). Packs are identical for any value.
    #[arg(short = 'j', long = "jobs", value_name = "N", value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub jobs: Option<u16>,
    /// Bake every asset, even those whose pack is up to date.
    #[arg(long)]
    pub force: bool,
    /// Bake only shard K of N (1 ≤ K ≤ N), e.g. `--shard 2/4` on the second of four machines:
    /// an asset's shard follows from its output path alone (relative to the batch file), so it
    /// stays put when other assets are added, removed or reordered, and the N shards together
    /// bake every asset once. The whole batch is still checked first.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
}

/// `furbake bake`
#[derive(Args, Debug)]
pub struct BakeArgs {
    /// Input mesh (.glb or .gltf).
    pub mesh: PathBuf,
    /// Output pack file (written atomically: a failed bake leaves nothing behind).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Starting settings: `fur` (16 layers of 128², undercoat) or `grass` (64 layers of 64²).
    #[arg(long, default_value = "fur")]
    pub preset: String,
    /// TOML file overriding any setting (same keys as the manifest's settings, e.g.
    /// `[volume] layers = 32`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Override one setting, e.g. `--set volume.coat.density=0.1` (repeatable; applied after
    /// --config).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Master seed of every stochastic stage.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Shell layers (volume.layers).
    #[arg(long)]
    pub layers: Option<u32>,
    /// Shell texture size in texels (volume.resolution).
    #[arg(long)]
    pub resolution: Option<u32>,
    /// Fur length in scene units, skin to outermost shell (shells.fur_length_m).
    #[arg(long, value_name = "METRES")]
    pub fur_length: Option<f32>,
    /// Surface length per texture repeat in scene units (uv.repeat_m): the texel density.
    #[arg(long, value_name = "METRES")]
    pub repeat: Option<f32>,
    /// Vertical slices composed onto the fin texture (volume.fin_slices).
    #[arg(long)]
    pub fin_slices: Option<u32>,
    /// Bake without the undercoat pass.
    #[arg(long)]
    pub no_undercoat: bool,
    /// Also scatter grass blades over the furry triangles, this many per square metre (scene
    /// units²), and bake their keyframe table into the pack (blades.field.density_per_m2).
    #[arg(long, value_name = "PER_M2")]
    pub blades: Option<f32>,
    /// Also bake this mass–spring topology (fur thesis §3.4.1); repeatable.
    #[arg(long = "topology", value_name = "KIND", value_parser = topology_names())]
    pub topologies: Vec<String>,
    /// Also write the atlases as PNG images into this directory.
    #[arg(long, value_name = "DIR")]
    pub png_dir: Option<PathBuf>,
    /// Also read external buffers and images from inside DIR (besides the glTF's own directory),
    /// e.g. textures in a shared folder named as `../textures/fur.png`. URIs stay relative to the
    /// glTF; a file outside both, a symlink leading out of them, an absolute path or a scheme is
    /// refused (exit 1).
    #[arg(long, value_name = "DIR")]
    pub asset_root: Option<PathBuf>,
    /// Every external file the glTF names must be read: a missing or unreadable image is an
    /// error naming the file (exit 1) instead of a warning and a pack without it. For build
    /// systems, where a texture left out of an action's declared inputs must fail the action.
    /// Changes no pack that is written.
    #[arg(long)]
    pub strict_inputs: bool,
    /// Most memory the bake may take, estimated from the settings and the imported mesh before
    /// any stage runs (bytes, or with a K, M or G suffix: powers of 1024). A plan above it exits 2
    /// naming the setting that drives most of it. Default 2G.
    #[arg(long, value_name = "SIZE", default_value = "2G", value_parser = parse_bytes)]
    pub max_memory: u64,
    /// Also write a Make/Ninja depfile: the pack depends on every file the bake read (the glTF,
    /// its external buffers, the images it sampled, the --config file). Written after the pack.
    #[arg(long, value_name = "FILE")]
    pub depfile: Option<PathBuf>,
    /// Also write a JSON report for machines: per-stage wall times, section sizes, warnings,
    /// input and settings hashes, tool version (docs/schemas/bake-report.schema.json).
    #[arg(long, value_name = "FILE")]
    pub report: Option<PathBuf>,
}

/// `furbake inspect`
#[derive(Args, Debug)]
pub struct InspectArgs {
    /// The file to describe.
    pub file: PathBuf,
    /// Print JSON (stable field names; see README) instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `furbake verify`
#[derive(Args, Debug)]
pub struct VerifyArgs {
    /// The file to check.
    pub file: PathBuf,
}

/// `furbake extract`
#[derive(Args, Debug)]
pub struct ExtractArgs {
    /// The file to extract.
    pub file: PathBuf,
    /// Output directory (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// `furbake export`
#[derive(Args, Debug)]
pub struct ExportArgs {
    /// The pack to export.
    pub file: PathBuf,
    /// The .glb to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Shell layers to write (default: one per atlas layer; 0: the skin and fins alone).
    #[arg(long, value_name = "N")]
    pub layers: Option<u32>,
    /// Leave the fins out.
    #[arg(long)]
    pub no_fins: bool,
    /// Leave the skeleton, skin and clips out (the rest pose as static meshes).
    #[arg(long)]
    pub no_animation: bool,
    /// Alpha-test the shells and fins at this cutoff (glTF alphaMode MASK: order-independent,
    /// harder edges) instead of blending them.
    #[arg(long, value_name = "CUTOFF")]
    pub alpha_mask: Option<f32>,
}

/// `furbake keyframes`
#[derive(Args, Debug)]
pub struct KeyframesArgs {
    /// Output file (a container with one keyframe_table section).
    #[arg(short, long)]
    pub output: std::path::PathBuf,
    /// Blade segments (level of detail); vertices = 4 × segments.
    #[arg(long, default_value_t = 8)]
    pub segments: u32,
    /// Represented poses (force magnitudes × angles over the full circle).
    #[arg(long, default_value_t = 1000)]
    pub poses: u32,
    /// Force magnitudes in the grid (default: chosen from --poses, 1000 ⇒ 10 × 100 angles).
    #[arg(long)]
    pub magnitudes: Option<u32>,
    /// Largest simulated force magnitude.
    #[arg(long, default_value_t = 4.0)]
    pub max_force: f32,
    /// Mirror symmetry exploited: none, x (half the poses) or xz (a quarter).
    #[arg(long, default_value = "xz", value_parser = ["none", "x", "xz"])]
    pub symmetry: String,
    /// Component encoding: snorm16 (thesis), f16, unorm8, snorm8 or f32 (no quantisation).
    #[arg(long, default_value = "snorm16", value_parser = ["snorm16", "f16", "unorm8", "snorm8", "f32"])]
    pub encoding: String,
    /// Keep vertices that never move (skip the static-vertex stage).
    #[arg(long)]
    pub no_drop_static: bool,
    /// Store both vertices of each rigid segment edge (skip the rigid-pair stage).
    #[arg(long)]
    pub no_rigid_pairs: bool,
}

/// `furbake preview`
#[derive(Args, Debug)]
pub struct PreviewArgs {
    /// A pack (rendered as a still, framed automatically) or a runtime scene `.toml` (its
    /// `[[packs]]` with paths relative to the scene file, `[camera]`, `[light]`, `[effects]`).
    /// Decided by the extension (`.toml` scene, `.fbk` pack), else by the content.
    #[arg(value_name = "PACK_OR_SCENE")]
    pub input: PathBuf,
    /// Output PNG of a still image (written atomically). Not with --frames.
    #[arg(short, long, required_unless_present = "frames", conflicts_with = "frames")]
    pub output: Option<PathBuf>,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Scene only: render N frames, one scene time step apart, as DIR/frame_0000.png … (the
    /// number is zero-padded to the width of N-1, at least 4 digits). Needs --out-dir.
    #[arg(long, value_name = "N", requires = "out_dir", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,
    /// Directory for --frames (created if missing; existing frame files are replaced).
    #[arg(long, value_name = "DIR", requires = "frames")]
    pub out_dir: Option<PathBuf>,
    /// Scene only: seconds of scene time simulated before the first image (default 0.5 for a
    /// still, so wind and gravity have bent the fur and grass; 0 for --frames, which start from
    /// the rest pose and step once before each frame).
    #[arg(long, value_name = "SECONDS")]
    pub settle: Option<f64>,
    /// Scene only: most GPU memory the scene's renderers may take, estimated from the packs
    /// before anything is created (bytes, or with a K, M or G suffix: powers of 1024). A scene
    /// above it exits 2 naming this flag. Default 2G.
    #[arg(long, value_name = "SIZE", default_value = "2G", value_parser = parse_bytes)]
    pub max_memory: u64,
    #[command(flatten)]
    pub render: RenderFlags,
}

/// How `furbake preview` and `furbake view` draw (over a scene's `[render]` and `[packs.render]`;
/// a pack alone starts from the renderer's defaults).
#[derive(Args, Debug, Clone, Default)]
pub struct RenderFlags {
    /// Shell layers drawn (0: the bare skin). Default: one per atlas slice.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=1024))]
    pub shells: Option<u32>,
    /// Draw no fins (neither on fin edges nor on the silhouette).
    #[arg(long)]
    pub no_fins: bool,
    /// Draw no silhouette fins (fins on the pack's fin edges stay).
    #[arg(long)]
    pub no_silhouette_fins: bool,
    /// Half-width of the silhouette fin band in units of n·v, in [0, 1].
    #[arg(long, value_name = "X")]
    pub silhouette_band: Option<f32>,
    /// How shells and fins combine with what is behind them: alpha-blend (soft, default) or
    /// alpha-test (hard, order-free; alpha to coverage on multisampled targets).
    #[arg(long, value_enum)]
    pub blend: Option<BlendFlag>,
    /// Shell and fin fragments with alpha at or below this are discarded, in [0, 1). Default
    /// 0 blending (only empty texels are skipped), 0.4 with --blend alpha-test.
    #[arg(long, value_name = "X")]
    pub alpha_threshold: Option<f32>,
    /// Draw the earlier flat look: fur Lambert × self-shadow (no strand shading), grass a flat
    /// colour with two-sided Lambert (no blade shading).
    #[arg(long)]
    pub flat: bool,
    /// Draw every shell layer at any distance (no level of detail).
    #[arg(long)]
    pub no_lod: bool,
    /// Anisotropic filtering of the blended shell and fin atlases: 1 (off), 2, 4, 8 or 16.
    /// Default 16 on a GPU, 1 on a software adapter such as lavapipe (where it costs 1.2–5× a
    /// fur frame).
    #[arg(long, value_name = "N")]
    pub anisotropy: Option<u16>,
}

/// `--blend`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlendFlag {
    AlphaBlend,
    AlphaTest,
}

impl RenderFlags {
    /// The render options these flags set (keys left out keep the scene's or the default), or
    /// the flag and what is wrong with its value.
    pub fn options(&self) -> Result<furbake_runtime::RenderOptions, (String, String)> {
        use furbake_runtime::ShellBlendMode;
        let options = furbake_runtime::RenderOptions {
            shell_layers: self.shells,
            fins: self.no_fins.then_some(false),
            silhouette_fins: (self.no_fins || self.no_silhouette_fins).then_some(false),
            silhouette_band: self.silhouette_band,
            blend: self.blend.map(|b| match b {
                BlendFlag::AlphaBlend => ShellBlendMode::AlphaBlend,
                BlendFlag::AlphaTest => ShellBlendMode::AlphaTest,
            }),
            alpha_threshold: self.alpha_threshold,
            strand_shading: self.flat.then_some(false),
            blade_shading: self.flat.then_some(false),
            lod: self.no_lod.then_some(false),
            anisotropy: self.anisotropy,
        };
        options.validate().map_err(|(key, what)| {
            let flag =
                if key == "shell_layers" { "--shells".to_owned() } else { format!("--{}", key.replace('_', "-")) };
            (flag, what)
        })?;
        Ok(options)
    }
}

/// `furbake view`
#[derive(Args, Debug)]
pub struct ViewArgs {
    /// A runtime scene `.toml` (its camera, light, packs, effects and events) or a pack, shown
    /// alone at the origin like `furbake preview PACK` (framed automatically, no effects; an
    /// animated pack plays its first clip). Decided by the extension (`.toml` scene, `.fbk`
    /// pack), else by the content.
    #[arg(value_name = "SCENE_OR_PACK")]
    pub input: PathBuf,
    /// Window size in pixels, WIDTHxHEIGHT (the screenshot's size).
    #[arg(long, default_value = "960x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Run unattended: render N frames, stepping the world one `time_step_s` before each (no
    /// real-time pacing), then exit 0. With --screenshot, the last frame is written as a PNG.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    pub frames: Option<u32>,
    /// With --frames: write the last frame, exactly what the window shows, to this PNG
    /// (atomically).
    #[arg(long, value_name = "FILE.png", requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// Most GPU memory the scene's renderers and the window's targets may take, estimated
    /// before anything is created (bytes, or with a K, M or G suffix: powers of 1024). A scene
    /// above it exits 2 naming this flag. Default 2G.
    #[arg(long, value_name = "SIZE", default_value = "2G", value_parser = parse_bytes)]
    pub max_memory: u64,
    #[command(flatten)]
    pub render: RenderFlags,
}

const VIEW_HELP: &str = "Controls (also printed on stderr at start):
  left drag            orbit the camera around its target
  right or shift-drag  pan
  wheel                zoom
  Space                play / pause
  Right                pause and step forward one time step (10 with Shift)
  Left                 pause and step back one time step (10 with Shift): physics cannot run
                       backwards, so the world restarts from time 0 and re-simulates to the
                       earlier time, with the effects and clips as they are now
  C                    next animation clip of every animated pack (0.25 s cross-fade)
  1-9                  switch the scene's n-th declared effect off / on: gravity, wind, wind
                       sources, object motion and interaction have a strength that is set to zero
                       and restored; collisions, windless areas, parting and the wrong-side guard
                       cannot be switched from the viewer
  S                    shading off / on: flat fur (Lambert × self-shadow) and flat grass, to
                       compare with the strand and blade shading
  F                    every fin off / on (fin edges and silhouette fins)
  T                    alpha blending / alpha test of shells and fins
  [ ]                  halve / double the shells drawn
  G                    grass culling and distance LOD off / on
  R                    reset: time 0, the scene's camera, effects and clips
  Esc, Q               quit

The window title shows the frame time (ms, smoothed), the scene time, play state, the clip, the
effects switched off, the first fur pack's drawn shells and render switches, and the slowest
simulation stage's mean time per step. The world steps at the
scene's time_step_s in real time (at most 4 steps per frame; a slower machine runs slow motion).

Needs a display: DISPLAY (X11) or WAYLAND_DISPLAY. Without one, run it under a virtual X server:
xvfb-run -a furbake view SCENE.toml --frames 30 --screenshot shot.png

Exit codes: 0 success, 1 bad input or invalid file (the message names the file and the problem), or no display or
GPU, 2 usage error.";

/// One slice of a batch: shard `index` (1-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

/// `K/N` with `1 ≤ K ≤ N` → a [`Shard`].
pub fn parse_shard(s: &str) -> Result<Shard, String> {
    let bad = || format!("{s:?} is not K/N with 1 ≤ K ≤ N (e.g. 2/4)");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let (index, count): (u64, u64) = (k.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if index == 0 || index > count {
        return Err(bad());
    }
    Ok(Shard { index, count })
}

/// `4096`, `64K`, `512M`, `2G` (powers of 1024) → bytes.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let (digits, shift) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 10),
        Some('M') => (&t[..t.len() - 1], 20),
        Some('G') => (&t[..t.len() - 1], 30),
        _ => (t, 0),
    };
    digits
        .trim()
        .parse::<u64>()
        .ok()
        .and_then(|n| n.checked_mul(1u64 << shift))
        .filter(|&n| n > 0)
        .ok_or_else(|| format!("{s:?} is not a size: a positive whole number of bytes, or with K, M or G"))
}

/// Bytes as people read them in a message: `512 bytes`, `12 KiB`, `340 MiB` (rounded up).
pub fn format_bytes(bytes: u64) -> String {
    match bytes {
        0..1024 => format!("{bytes} bytes"),
        1024..0x10_0000 => format!("{} KiB", bytes.div_ceil(1024)),
        _ => format!("{} MiB", bytes.div_ceil(1 << 20)),
    }
}

const PREVIEW_HELP: &str =
    "A pack renders one still image with -o. A runtime scene renders a still with -o (after --settle \
seconds of simulation, default 0.5), or with --frames N --out-dir DIR an animation: the world steps once (the scene's \
time_step_s) before each frame, so frame i shows scene time settle + (i+1)·time_step_s. --frames on a pack is a usage \
error (a pack has no time). Every PNG is written atomically; a failed --frames run removes the frames it wrote.

Exit codes: 0 success, 1 bad input or invalid file (the message names the file and the problem), 2 usage error.";

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(|| format!("{s:?} is not WIDTHxHEIGHT, e.g. 512x512"))?;
    let parse = |v: &str| v.trim().parse::<u32>().ok().filter(|&n| (1..=16384).contains(&n));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("{s:?}: width and height must be whole numbers from 1 to 16384")),
    }
}

/// `furbake simulate`
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// A runtime scene (TOML: `time_step_s`, `duration_s`, `[solver]`, `[[packs]]`, `[effects]`,
    /// `[[events]]`) to run headless.
    #[arg(value_name = "SCENE")]
    pub input: std::path::PathBuf,
    /// Time steps to run (default: the scene's `duration_s`, else 2 s of scene time).
    #[arg(long)]
    pub frames: Option<u64>,
    /// Print the report as JSON (stage timings and per-step statistics) instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Write the JSON report here.
    #[arg(short, long)]
    pub output: Option<std::path::PathBuf>,
    /// Write every pack's final state in world space as JSON here (skin vertices, mass positions
    /// and velocities, scale vectors; metres and m/s).
    #[arg(long, value_name = "FILE")]
    pub state_out: Option<std::path::PathBuf>,
    /// Record per-step statistics every N steps (default 1, or fewer records on runs above
    /// 100,000 steps; the last step is always recorded).
    #[arg(long, value_name = "N")]
    pub record_every: Option<u64>,
    /// Most memory the run may take, estimated from the scene and its packs' section tables
    /// before the world is built (bytes, or with a K, M or G suffix: powers of 1024): decoded
    /// sections, solver state, kept step records and the `--state-out` text. A run above it exits
    /// 2 naming what drives most of it. Default 2G.
    #[arg(long, value_name = "SIZE", default_value = "2G", value_parser = parse_bytes)]
    pub max_memory: u64,
    /// Retired (`simulate PACK --scene SIM.toml`): exits 2 saying how to write a runtime scene.
    #[arg(long, hide = true)]
    pub scene: Option<std::path::PathBuf>,
    /// Retired with `--scene`.
    #[arg(long, hide = true)]
    pub topology: Option<String>,
}

/// `furbake report`
#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Which report: `accuracy` (error against a converged reference vs time, fur and grass).
    #[arg(value_parser = ["accuracy"])]
    pub which: String,
    /// Directory to write into (`accuracy.md` and its SVG charts).
    #[arg(short, long, default_value = "docs")]
    pub output: std::path::PathBuf,
}

/// `furbake schema`
#[derive(Args, Debug)]
pub struct SchemaArgs {
    /// Which file: `scene` (a runtime scene, `furbake simulate|preview|view SCENE.toml`) or
    /// `config` (a bake config, `furbake bake --config FILE`) or `batch` (`furbake batch FILE`).
    #[arg(value_parser = ["scene", "config", "batch"])]
    pub which: String,
}

/// `furbake shaders`
#[derive(Args, Debug)]
pub struct ShadersArgs {
    /// The shading language.
    #[arg(long, value_parser = ["spirv", "glsl", "hlsl", "msl"])]
    pub target: String,
    /// Output directory (created if missing); files of the same names are replaced.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// The topology kind names, from the format's own list (so the CLI never drifts from it).
fn topology_names() -> clap::builder::PossibleValuesParser {
    use furbake_formats::sections::spring_topology::TopologyKind;
    clap::builder::PossibleValuesParser::new(TopologyKind::KNOWN.iter().filter_map(|k| k.name()))
}
