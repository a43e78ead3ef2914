//! `furbake simulate SCENE.toml [--frames N] [--json] [-o FILE] [--state-out FILE] [--record-every N]`:
//! a runtime scene (`furbake_runtime::Scene`) runs headless in a `furbake_runtime::World` — only
//! the stages its effects call for (docs/design.md "Runtime: scenes and stages"), with its timed events (teleports,
//! forces switched off and on) — and the per-stage timings (name, pack, runs, total ms, mean µs)
//! are printed as a table. `--json` prints, and `-o` writes, the whole report as JSON: the
//! timings plus per-step statistics of every simulated pack (energy and its budget, largest
//! displacement, substeps, CG iterations, guard triggers). `--state-out` writes the final state
//! of every pack in world space (README "`simulate --state-out`").
//!
//! The former `simulate PACK --scene SIM.toml` form is retired: it and a furbake-sim scene file
//! exit 2 with a one-line message saying how to write the scene now.

use std::path::Path;
use std::time::Instant;

use anyhow::anyhow;
use furbake_runtime::{PackState, Scene, World, WorldOptions};
use serde::Serialize;

use crate::args::SimulateArgs;
use crate::failure::{self, Classify, Failure};

/// Scene time a scene without `duration_s` runs for when `--frames` is not given, seconds.
const DEFAULT_SCENE_TIME_S: f64 = 2.0;
/// Most frames one run may take (a typo guard: 10⁷ steps is hours of scene time).
const MAX_FRAMES: u64 = 10_000_000;
/// Most step records a report keeps per pack; longer runs record every k-th step (the report's
/// `record_every`), so memory stays bounded whatever `--frames` is.
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
    let dt = scene.time_step_s;
    let frames = match args.frames {
        Some(n) if n > MAX_FRAMES => return Err(Failure::Usage(anyhow!("--frames {n} is above {MAX_FRAMES}"))),
        Some(n) => n,
        None => {
            let steps = (scene.duration_s.unwrap_or(DEFAULT_SCENE_TIME_S) / dt as f64 - 1e-9).ceil().max(1.0);
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
    let options = WorldOptions { step_statistics: wants_report, ..WorldOptions::default() };
    let mut world = World::with_options(scene, options).map_err(|e| failure::runtime(e, path))?;
    let simulated: Vec<usize> =
        (0..world.pack_count()).filter(|&i| world.fur(i).is_some_and(|f| f.simulation.is_some())).collect();
    let mut steps = Vec::new();
    let started = Instant::now();
    for step in 0..frames {
        world.step().map_err(|e| failure::runtime(e, path))?;
        if wants_report && (step % record_every == 0 || step + 1 == frames) {
            for &i in &simulated {
                steps.push(StepRecord::of(&world, i, step));
            }
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    if let Some(out) = &args.state_out {
        let packs = (0..world.pack_count())
            .map(|i| world.pack_state(i))
            .collect::<Result<Vec<PackState>, _>>()
            .map_err(|e| failure::runtime(e, path))?;
        let state = StateFile { scene: path.display().to_string(), time_s: world.time_s(), steps: frames, packs };
        let json = serde_json::to_string_pretty(&state).expect("the state is plain serde data");
        furbake_formats::write_file_atomic(out, format!("{json}\n").as_bytes()).input()?;
    }
    let report = build_report(&world, path, frames, wall_s, record_every, steps);
    if wants_report {
        let json = serde_json::to_string_pretty(&report).expect("the report is plain serde data");
        if let Some(out) = &args.output {
            furbake_formats::write_file_atomic(out, format!("{json}\n").as_bytes()).input()?;
        }
        if args.json {
            crate::stdout::line(&json)?;
        }
    }
    if !args.json {
        crate::stdout::write(&stage_table(&report))?;
    }
    if !quiet {
        eprintln!(
            "simulated {} for {frames} steps of {dt} s ({:.3} s scene time) in {wall_s:.3} s wall",
            path.display(),
            report.scene_time_s,
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
            pack: world.scene().packs[pack].name.clone(),
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

/// The JSON report of a scene run.
#[derive(Serialize)]
struct SceneReport {
    scene: String,
    frames: u64,
    time_step_s: f32,
    scene_time_s: f64,
    wall_s: f64,
    packs: Vec<PackRow>,
    stages: Vec<StageRow>,
    /// Steps between two step records (the last step is always recorded).
    record_every: u64,
    /// One record per simulated pack per recorded step, in step order.
    steps: Vec<StepRecord>,
}

/// What `--state-out` writes.
#[derive(Serialize)]
struct StateFile {
    scene: String,
    time_s: f64,
    steps: u64,
    packs: Vec<PackState>,
}

/// True when `path` starts with the container's magic (a pack passed where a scene belongs).
fn looks_like_a_pack(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == furbake_formats::MAGIC
}

fn build_report(
    world: &World,
    path: &Path,
    frames: u64,
    wall_s: f64,
    record_every: u64,
    steps: Vec<StepRecord>,
) -> SceneReport {
    let packs = (0..world.pack_count())
        .map(|i| {
            let sp = &world.scene().packs[i];
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
    SceneReport {
        scene: path.display().to_string(),
        frames,
        time_step_s: world.scene().time_step_s,
        scene_time_s: world.time_s(),
        wall_s,
        packs,
        stages,
        record_every,
        steps,
    }
}

fn stage_table(r: &SceneReport) -> String {
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
        r.frames,
        total_ms,
        if r.frames > 0 { total_ms * 1e3 / r.frames as f64 } else { 0.0 }
    ));
    out
}
