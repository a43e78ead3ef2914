//! `furbake simulate SCENE.toml [--frames N] [--json] [-o FILE] [--state-out FILE] [--record-every N]`:
//! a runtime scene (`furbake_runtime::Scene`) runs headless in a `furbake_runtime::World` — only
//! the stages its effects call for (docs/design.md "Runtime: scenes and stages"), with its timed events (teleports,
//! forces switched off and on) — and the per-stage timings (name, pack, runs, total ms, mean µs)
//! are printed as a table. `--json` prints, and `-o` writes, the whole report as JSON: the
//! timings plus per-step statistics of every simulated pack (energy and its budget, largest
//! displacement, substeps, CG iterations, guard triggers). `--state-out` writes the final state
//! of every pack in world space (README "`simulate --state-out`").
//!
//! Before the world is built, every pack of the scene is validated as `verify` does (a pack
//! `verify` rejects exits 1) and the world is planned (`furbake_runtime::WorldPlan`, as `preview`
//! and `view` plan theirs: [`crate::describe::plan_scene`]); a run whose planned memory is above
//! `--max-memory` exits 2 naming what drives it.
//!
//! The former `simulate PACK --scene SIM.toml` form is retired: it and a furbake-sim scene file
//! exit 2 with a one-line message saying how to write the scene now.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::anyhow;
use furbake_formats::SectionKind;
use furbake_runtime::{PackState, RuntimeError, Scene, World, WorldOptions, WorldPlan};
use serde::Serialize;

use crate::args::{SimulateArgs, format_bytes};
use crate::failure::{self, Failure};

/// Scene time a scene without `duration_s` runs for when `--frames` is not given, seconds.
const DEFAULT_SCENE_TIME_S: f64 = 2.0;
/// Most frames one run may take ([`crate::args::MAX_STEPS`]).
const MAX_FRAMES: u64 = crate::args::MAX_STEPS;
/// Most step records a report writes per pack by default; longer runs record every k-th step
/// (the report's `record_every`), so the report's size stays bounded whatever `--frames` is (its
/// records are streamed, never kept, so memory does not grow with it either).
const MAX_STEP_RECORDS: u64 = 100_000;

/// Runs `furbake simulate`.
pub fn run(args: SimulateArgs, quiet: bool) -> Result<(), Failure> {
    if args.scene.is_some() || args.topology.is_some() {
        return Err(Failure::Usage(anyhow!(
            "`simulate PACK --scene SIM.toml [--topology KIND]` is retired: write a runtime scene that names \
             the pack (`[[packs]] name, path`), its effects and `[[events]]`, and run `furbake simulate \
             SCENE.toml --json` (see README \"Scenes\")"
        )));
    }
    let path = &args.input;
    if looks_like_a_pack(path) {
        return Err(Failure::Usage(anyhow!(
            "{}: this is a pack; simulate takes a runtime scene (.toml) whose [[packs]] names it",
            path.display()
        )));
    }
    let scene = Scene::load(path).map_err(failure::scene)?;
    plan_files(&args, &scene)?;
    let dt = scene.time_step_s();
    let frames = match args.frames {
        Some(n) if n > MAX_FRAMES => return Err(Failure::Usage(anyhow!("--frames {n} is above {MAX_FRAMES}"))),
        Some(n) => n,
        None => {
            let steps = (scene.duration_s().unwrap_or(DEFAULT_SCENE_TIME_S) / dt as f64 - 1e-9).ceil().max(1.0);
            if steps > MAX_FRAMES as f64 {
                return Err(Failure::Usage(anyhow!(
                    "{}: duration_s / time_step_s is {steps} steps, above {MAX_FRAMES}; shorten duration_s, \
                     lengthen time_step_s or pass --frames",
                    path.display()
                )));
            }
            steps as u64
        }
    };
    let record_every = match args.record_every {
        Some(0) => return Err(Failure::Usage(anyhow!("--record-every must be at least 1"))),
        Some(k) => k,
        None => frames.div_ceil(MAX_STEP_RECORDS).max(1),
    };
    let wants_report = args.json || args.output.is_some();
    // Every pack is validated as `verify` does before anything else reads it, so a corrupt pack
    // is bad input (exit 1) even when the estimate below would refuse the run too
    // (docs/design.md "Runtime: packs").
    let plan = plan_world(scene, path, wants_report)?;
    check_memory_budget(&plan, path, args.state_out.is_some(), args.max_memory)?;
    let mut world = plan.build().map_err(|e| failure::runtime(e, path))?;
    if let Some(i) = (0..world.pack_count()).find(|&i| world.gpu_physics(i).is_some()) {
        return Err(Failure::Usage(anyhow!(
            "{}: pack {:?} runs its fur physics on the GPU ([solver] device = \"gpu\"), and simulate runs on the \
             CPU only; write device = \"cpu\" to simulate it here, or run the scene with `furbake preview` or \
             `furbake view`, which step it on the GPU",
            path.display(),
            world.scene().packs()[i].name
        )));
    }
    // The report streams — its head, each step record as it is taken, then its tail — into the
    // -o file (named only once the run succeeds) and to stdout with --json; nothing is kept.
    let head = ReportHead {
        scene: path.display().to_string(),
        frames,
        time_step_s: world.scene().time_step_s(),
        record_every,
    };
    let mut failed: Option<Failure> = None;
    let mut wall_s = 0.0;
    let mut produce = |sink: &mut dyn Write| -> std::io::Result<()> {
        match run_streaming(&mut world, path, &head, wants_report, sink) {
            Ok(w) => {
                wall_s = w;
                Ok(())
            }
            Err(Streamed::Io(e)) => Err(e),
            Err(Streamed::Run(f)) => {
                failed = Some(f);
                Err(std::io::Error::other("the run failed"))
            }
        }
    };
    let written = match &args.output {
        Some(out) if crate::files::is_stdout(out) => produce(&mut std::io::stdout().lock()),
        Some(out) => furbake_formats::write_file_atomic_from(out, &mut |file| {
            if args.json { produce(&mut Tee { file, stdout: std::io::stdout().lock() }) } else { produce(file) }
        })
        .map_err(|e| match e {
            furbake_formats::FormatError::Io { source, .. } => source,
            other => std::io::Error::other(other.to_string()),
        }),
        None if args.json => produce(&mut std::io::stdout().lock()),
        None => produce(&mut std::io::sink()),
    };
    if let Some(f) = failed {
        return Err(f);
    }
    written.map_err(|e| match e.kind() {
        std::io::ErrorKind::BrokenPipe => Failure::StdoutClosed,
        _ => Failure::Input(anyhow!(
            "cannot write the report{}: {e}",
            args.output.as_ref().map_or(String::new(), |o| format!(" to {}", o.display()))
        )),
    })?;
    if let Some(out) = &args.state_out {
        let packs = (0..world.pack_count())
            .map(|i| world.pack_state(i))
            .collect::<Result<Vec<PackState>, _>>()
            .map_err(|e| failure::runtime(e, path))?;
        let state = StateFile { scene: path.display().to_string(), time_s: world.time_s(), steps: frames, packs };
        let json = serde_json::to_string_pretty(&state).expect("the state is plain serde data");
        crate::files::write_output(out, format!("{json}\n").as_bytes(), "the state")?;
    }
    let tail = report_tail(&world, wall_s);
    if !args.json && !streams_to_stdout(&args) {
        crate::stdout::write(&stage_table(&tail, frames))?;
    }
    if !quiet {
        eprintln!(
            "simulated {} for {frames} steps of {dt} s ({:.3} s scene time) in {wall_s:.3} s wall",
            path.display(),
            tail.scene_time_s,
        );
    }
    Ok(())
}

/// One stage's timings in the report.
#[derive(Serialize)]
struct StageRow {
    name: &'static str,
    pack: String,
    runs: u64,
    total_ms: f64,
    mean_us: f64,
}

/// What one pack of the scene did.
#[derive(Serialize)]
struct PackRow {
    name: String,
    path: String,
    /// Simulated topology and solver; absent when the fur stays at rest or the pack has none.
    topology: Option<String>,
    solver: Option<String>,
    shell_vertices: Option<usize>,
    grass_corners: Option<usize>,
    sections_read: Vec<String>,
}

/// Statistics of one simulated pack after one recorded step.
#[derive(Serialize)]
struct StepRecord {
    /// Step index (0-based).
    step: u64,
    /// Scene time at the end of the step, seconds.
    time_s: f64,
    /// The pack's scene name.
    pack: String,
    /// Kinetic + spring energy, joules (mesh units: metres when the mesh is in metres).
    energy_j: f64,
    kinetic_j: f64,
    spring_j: f64,
    restoring_j: f64,
    /// Initial energy plus external work, guard impulses and teleports so far, joules.
    energy_budget_j: f64,
    /// Largest distance of a free mass from its rest position, mesh units.
    max_displacement_m: f32,
    substeps: u32,
    cg_iterations: u32,
    guard_triggers: u32,
    frozen_scale_vectors: u32,
}

impl StepRecord {
    fn of(world: &World, pack: usize, step: u64) -> StepRecord {
        let s = world.fur(pack).map(|f| f.last_step).unwrap_or_default();
        StepRecord {
            step,
            time_s: world.time_s(),
            pack: world.scene().packs()[pack].name.clone(),
            energy_j: s.energy.total_j(),
            kinetic_j: s.energy.kinetic_j,
            spring_j: s.energy.spring_j,
            restoring_j: s.energy.restoring_j,
            energy_budget_j: s.energy_budget_j,
            max_displacement_m: s.max_displacement_m,
            substeps: s.substeps,
            cg_iterations: s.cg_iterations,
            guard_triggers: s.guard_triggers,
            frozen_scale_vectors: s.frozen_scale_vectors,
        }
    }
}

/// The JSON report of a scene run, as streamed: the head's fields, `"steps": [ … ]` (one record
/// per simulated pack per recorded step, in step order, written as they are taken), then the
/// tail's fields.
#[derive(Serialize)]
struct ReportHead {
    scene: String,
    frames: u64,
    time_step_s: f32,
    /// Steps between two step records (the last step is always recorded).
    record_every: u64,
}

/// The fields known once the run has ended.
#[derive(Serialize)]
struct ReportTail {
    scene_time_s: f64,
    wall_s: f64,
    packs: Vec<PackRow>,
    stages: Vec<StageRow>,
}

/// Why a streamed run stopped.
enum Streamed {
    /// Writing the report failed.
    Io(std::io::Error),
    /// The run itself failed.
    Run(Failure),
}

impl From<std::io::Error> for Streamed {
    fn from(e: std::io::Error) -> Self {
        Streamed::Io(e)
    }
}

/// The report written to the -o file and to stdout at once.
struct Tee<'a, S: Write> {
    file: &'a mut dyn Write,
    stdout: S,
}

impl<S: Write> Write for Tee<'_, S> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.file.write_all(buf)?;
        self.stdout.write_all(buf)?;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()?;
        self.stdout.flush()
    }
}

/// Runs `head.frames` steps of `world`, streaming the report into `sink` when `report` (else
/// writing nothing); returns the wall time of the steps, seconds.
fn run_streaming(
    world: &mut World,
    path: &Path,
    head: &ReportHead,
    report: bool,
    sink: &mut dyn Write,
) -> Result<f64, Streamed> {
    let json = |e: serde_json::Error| Streamed::Io(std::io::Error::other(e));
    let simulated: Vec<usize> =
        (0..world.pack_count()).filter(|&i| world.fur(i).is_some_and(|f| f.simulation.is_some())).collect();
    let (frames, record_every) = (head.frames, head.record_every);
    if report {
        let text = serde_json::to_string_pretty(head).map_err(json)?;
        // The head without its closing brace, then the steps array.
        write!(sink, "{},\n  \"steps\": [", text.trim_end().trim_end_matches('}').trim_end())?;
    }
    let mut first = true;
    let started = Instant::now();
    for step in 0..frames {
        world.step().map_err(|e| Streamed::Run(failure::runtime(e, path)))?;
        if report && (step % record_every == 0 || step + 1 == frames) {
            for &i in &simulated {
                sink.write_all(if first { b"\n    " } else { b",\n    " })?;
                serde_json::to_writer(&mut *sink, &StepRecord::of(world, i, step)).map_err(json)?;
                first = false;
            }
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    if report {
        let tail = serde_json::to_string_pretty(&report_tail(world, wall_s)).map_err(json)?;
        // The tail's fields after the steps array, closing the one object.
        writeln!(sink, "\n  ],{}", tail.trim_start().trim_start_matches('{'))?;
    }
    Ok(wall_s)
}

/// What `--state-out` writes.
#[derive(Serialize)]
struct StateFile {
    scene: String,
    time_s: f64,
    steps: u64,
    packs: Vec<PackState>,
}

/// The run's files (docs/design.md "Safe outputs"): the report (`-o`) and the state
/// (`--state-out`) may be neither the scene nor a pack it names nor each other, nor anything but
/// a regular file; `-` is stdout, which only one of `--json`, `-o -` and `--state-out -` may use.
fn plan_files(args: &SimulateArgs, scene: &Scene) -> Result<(), Failure> {
    let mut files = crate::files::Files::with_inputs(
        std::iter::once(args.input.as_path()).chain(scene.packs().iter().map(|p| p.path.as_path())),
    );
    let on_stdout = [
        ("--json", args.json),
        ("-o -", args.output.as_deref().is_some_and(crate::files::is_stdout)),
        ("--state-out -", args.state_out.as_deref().is_some_and(crate::files::is_stdout)),
    ];
    let users: Vec<&str> = on_stdout.iter().filter(|(_, on)| *on).map(|(name, _)| *name).collect();
    if users.len() > 1 {
        return Err(Failure::Usage(anyhow!("{} all write to stdout; choose one", users.join(" and "))));
    }
    if let Some(o) = &args.output {
        files.stream_output("--output", o)?;
    }
    if let Some(o) = &args.state_out {
        files.stream_output("--state-out", o)?;
    }
    Ok(())
}

/// Whether a file output of the run is stdout (the stage table then stays off it).
fn streams_to_stdout(args: &SimulateArgs) -> bool {
    [&args.output, &args.state_out].into_iter().flatten().any(|p| crate::files::is_stdout(p))
}

/// True when `path` starts with the container's magic (a pack passed where a scene belongs).
fn looks_like_a_pack(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    // Never blocks: a FIFO or device is no pack, and the scene reader then says what it is.
    furbake_formats::input::open_regular(path).and_then(|(mut f, _)| f.read_exact(&mut magic)).is_ok()
        && magic == furbake_formats::MAGIC
}

/// The report's fields known once the run has ended.
fn report_tail(world: &World, wall_s: f64) -> ReportTail {
    let packs = (0..world.pack_count())
        .map(|i| {
            let sp = &world.scene().packs()[i];
            let fur = world.fur(i);
            let sim = fur.and_then(|f| f.simulation);
            PackRow {
                name: sp.name.clone(),
                path: sp.path.display().to_string(),
                topology: sim.map(|(t, _)| t.to_string()),
                solver: sim.map(|(_, s)| s.name().to_owned()),
                shell_vertices: fur.map(|f| f.scale_vectors.len()),
                grass_corners: world.grass(i).map(|g| g.corner_forces.len()),
                sections_read: world.pack(i).kinds_read().iter().map(|k| k.to_string()).collect(),
            }
        })
        .collect();
    let stages = world
        .stage_stats()
        .into_iter()
        .map(|s| StageRow {
            name: s.name,
            pack: s.pack.clone(),
            runs: s.runs,
            total_ms: s.total.as_secs_f64() * 1e3,
            mean_us: s.mean().as_secs_f64() * 1e6,
        })
        .collect();
    ReportTail { scene_time_s: world.time_s(), wall_s, packs, stages }
}

/// The per-stage table printed without `--json` (`frames` steps ran).
fn stage_table(r: &ReportTail, frames: u64) -> String {
    let mut out = String::new();
    let pack_w = r.stages.iter().map(|s| s.pack.len()).chain([4]).max().unwrap_or(4);
    out.push_str(&format!(
        "{:<18}  {:<pack_w$}  {:>8}  {:>11}  {:>10}\n",
        "stage", "pack", "runs", "total ms", "mean µs"
    ));
    for s in &r.stages {
        out.push_str(&format!(
            "{:<18}  {:<pack_w$}  {:>8}  {:>11.3}  {:>10.2}\n",
            s.name, s.pack, s.runs, s.total_ms, s.mean_us
        ));
    }
    if r.stages.is_empty() {
        out.push_str("(no stage: the scene declares no effect that moves anything)\n");
    }
    let total_ms: f64 = r.stages.iter().map(|s| s.total_ms).sum();
    out.push_str(&format!(
        "{:<18}  {:<pack_w$}  {:>8}  {:>11.3}  {:>10.2}\n",
        "all stages",
        "",
        frames,
        total_ms,
        if frames > 0 { total_ms * 1e3 / frames as f64 } else { 0.0 }
    ));
    out
}

// ---------------------------------------------------------------------------------------------
// Memory budget
// ---------------------------------------------------------------------------------------------

/// One `[x, y, z]` of `--state-out`: the world-space copy and its pretty JSON text (about 80
/// bytes) held twice while it is written, measured.
const BYTES_PER_STATE_VECTOR: u64 = 180;

/// One part of a run's estimated memory.
#[derive(Debug)]
struct RunPart {
    /// What it is, for the message.
    what: String,
    /// What to change to shrink it.
    advice: String,
    bytes: u64,
}

/// The world `simulate` runs: the scene's packs verified and planned as `preview` and `view` plan
/// them ([`crate::describe::plan_scene`]), with step statistics kept when a report is asked for.
pub(crate) fn plan_world(scene: Scene, path: &Path, wants_report: bool) -> Result<WorldPlan, Failure> {
    let options = WorldOptions { step_statistics: wants_report, ..WorldOptions::default() };
    crate::describe::plan_scene(scene, path, options)
}

/// Refuses a run whose estimated memory ([`run_parts`]) is above `max_memory`: exit 2 naming the
/// scene, the estimate, the budget and what drives the largest part.
fn check_memory_budget(plan: &WorldPlan, path: &Path, state_out: bool, max_memory: u64) -> Result<(), Failure> {
    let mut parts = run_parts(plan, state_out).map_err(|e| failure::runtime(e, path))?;
    let need: u64 = parts.iter().map(|p| p.bytes).sum();
    if need <= max_memory {
        return Ok(());
    }
    parts.sort_by_key(|p| std::cmp::Reverse(p.bytes));
    let largest = &parts[0];
    Err(Failure::Usage(anyhow!(
        "{}: the run needs about {}, above --max-memory {}; most of it ({}) is {}: {}",
        path.display(),
        format_bytes(need),
        format_bytes(max_memory),
        format_bytes(largest.bytes),
        largest.what,
        largest.advice
    )))
}

/// The parts of a run's memory: per scene entry what the world plan estimates it holds
/// (`WorldPlan::memory`; the largest section payload, held once more while it is decoded, with
/// the largest entry), and the `--state-out` text (the report's step records are streamed, never
/// kept), which reports every pack's skin besides its simulated state.
fn run_parts(plan: &WorldPlan, state_out: bool) -> Result<Vec<RunPart>, RuntimeError> {
    let mut parts: Vec<RunPart> = plan
        .memory()
        .iter()
        .zip(plan.scene().packs())
        .map(|(m, sp)| RunPart {
            what: match m.masses {
                0 => format!(
                    "pack entry `{}` ({}, {} vertices, {} triangles)",
                    m.name,
                    sp.path.display(),
                    m.vertices,
                    m.triangles
                ),
                masses => format!("pack entry `{}` ({}, {masses} simulated masses)", m.name, sp.path.display()),
            },
            advice: "place fewer or smaller packs in the scene, or raise --max-memory".into(),
            bytes: m.bytes,
        })
        .collect();
    if let Some(largest) = parts.iter_mut().max_by_key(|p| p.bytes) {
        largest.bytes = largest.bytes.saturating_add(plan.largest_payload());
    }
    if state_out {
        let mut vectors = 0u64;
        for (m, pack) in plan.memory().iter().zip(plan.packs()) {
            let skin = match m.vertices {
                0 if pack.has(SectionKind::SKIN_MESH) => pack.skin_mesh()?.positions.len() as u64,
                v => v,
            };
            vectors += m.state_vectors + skin;
        }
        parts.push(RunPart {
            what: format!("the --state-out text ({vectors} vectors)"),
            advice: "leave out --state-out or raise --max-memory".into(),
            bytes: vectors * BYTES_PER_STATE_VECTOR,
        });
    }
    Ok(parts)
}
