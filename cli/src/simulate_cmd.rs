//! `furbake simulate`, two forms:
//!
//! - `furbake simulate SCENE.toml [--frames N] [--json] [-o FILE]`: a runtime scene
//!   (`furbake_runtime::Scene`) runs headless in a `furbake_runtime::World` — only the stages its
//!   effects call for (SPEC "Runtime: Scenes") — and the per-stage timings (name, pack, runs,
//!   total ms, mean µs) are printed as a table, or as JSON with `--json` / `-o`.
//! - `furbake simulate PACK --scene SIM.toml [--topology KIND] [-o FILE]`: one topology of a pack
//!   under a furbake-sim scene, with per-step statistics and the final state as JSON (for
//!   checking results from outside).
//!
//! The form is chosen by `--scene`: with it the positional argument is a pack, without it a
//! runtime scene (a pack given alone is a usage error that says so).

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, anyhow};
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind};
use furbake_formats::{Pack, SectionKind};
use furbake_runtime::{RuntimeError, Scene, World};
use furbake_sim::{SimError, SimScene, run_scene};
use serde::Serialize;

use crate::args::SimulateArgs;
use crate::failure::{Classify, Failure};

/// Scene time a runtime scene runs for when `--frames` is not given, seconds.
const DEFAULT_SCENE_TIME_S: f64 = 2.0;
/// Most frames one run may take (a typo guard: 10⁷ steps is hours of scene time).
const MAX_FRAMES: u64 = 10_000_000;

/// Runs `furbake simulate`.
pub fn run(args: SimulateArgs, quiet: bool) -> Result<(), Failure> {
    match args.scene.clone() {
        Some(scene) => {
            if args.frames.is_some() || args.json {
                return Err(Failure::Usage(anyhow!("--frames and --json apply to runtime scenes, not to --scene")));
            }
            run_topology(&args.input, &scene, args.topology.as_deref(), args.output.as_deref(), quiet)
        }
        None => run_runtime_scene(args, quiet),
    }
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

/// What one pack of a runtime scene did.
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

/// The JSON report of a runtime scene.
#[derive(Serialize)]
struct SceneReport {
    scene: String,
    frames: u64,
    time_step_s: f32,
    scene_time_s: f64,
    wall_s: f64,
    packs: Vec<PackRow>,
    stages: Vec<StageRow>,
}

fn run_runtime_scene(args: SimulateArgs, quiet: bool) -> Result<(), Failure> {
    let path = &args.input;
    if args.topology.is_some() {
        return Err(Failure::Usage(anyhow!("--topology applies to `simulate PACK --scene SIM.toml`")));
    }
    if looks_like_a_pack(path) {
        return Err(Failure::Usage(anyhow!(
            "{}: a pack needs --scene SIM.toml; to run a runtime scene, pass the scene file",
            path.display()
        )));
    }
    // A scene that cannot be read or does not validate is bad input, like a bad pack.
    let scene = Scene::load(path).input()?;
    let dt = scene.time_step_s;
    let frames = match args.frames {
        Some(n) if n > MAX_FRAMES => return Err(Failure::Usage(anyhow!("--frames {n} is above {MAX_FRAMES}"))),
        Some(n) => n,
        None => (DEFAULT_SCENE_TIME_S / dt as f64 - 1e-9).ceil().max(1.0) as u64,
    };
    let mut world = World::new(scene).map_err(|e| runtime_failure(e, path))?;
    let started = Instant::now();
    for _ in 0..frames {
        world.step().map_err(|e| runtime_failure(e, path))?;
    }
    let wall_s = started.elapsed().as_secs_f64();
    let report = build_report(&world, path, frames, wall_s);
    let json = serde_json::to_string_pretty(&report).expect("the report is plain serde data");
    if let Some(out) = &args.output {
        furbake_formats::write_file_atomic(out, format!("{json}\n").as_bytes()).input()?;
    }
    if args.json {
        println!("{json}");
    } else {
        print!("{}", stage_table(&report));
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

/// True when `path` starts with the container's magic (a pack passed where a scene belongs).
fn looks_like_a_pack(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 8];
    std::fs::File::open(path).and_then(|mut f| f.read_exact(&mut magic)).is_ok() && magic == furbake_formats::MAGIC
}

fn runtime_failure(e: RuntimeError, scene: &Path) -> Failure {
    // Every runtime error blames a file (the scene, a pack, a bake without the topology the
    // scene needs) or the simulation of one: bad input.
    Failure::Input(anyhow::Error::new(e).context(scene.display().to_string()))
}

fn build_report(world: &World, path: &Path, frames: u64, wall_s: f64) -> SceneReport {
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

/// The `--scene` form: one topology of a pack under a furbake-sim scene.
fn run_topology(
    pack_path: &Path,
    scene_path: &Path,
    topology: Option<&str>,
    output: Option<&Path>,
    quiet: bool,
) -> Result<(), Failure> {
    let text = std::fs::read_to_string(scene_path)
        .with_context(|| format!("{}: cannot read scene", scene_path.display()))
        .input()?;
    let scene: SimScene =
        toml::from_str(&text).with_context(|| format!("{}: invalid scene", scene_path.display())).input()?;
    let pack = Pack::read(pack_path).input()?;
    let mesh: SkinMesh = pack.decode_first().map_err(|e| e.with_path(pack_path)).input()?;
    let wanted = topology.map(str::to_owned).or_else(|| scene.topology.clone());
    if let Some(name) = &wanted {
        if TopologyKind::from_name(name).is_none() {
            return Err(Failure::Usage(anyhow!("unknown topology {name:?}")));
        }
    }
    let mut chosen: Option<SpringTopology> = None;
    let mut available = Vec::new();
    for i in pack.find(SectionKind::SPRING_TOPOLOGY).collect::<Vec<_>>() {
        let t: SpringTopology = pack.decode(i).map_err(|e| e.with_path(pack_path)).input()?;
        let name = t.kind.to_string();
        available.push(name.clone());
        if chosen.is_none() && wanted.as_deref().is_none_or(|w| w == name) {
            chosen = Some(t);
        }
    }
    let topology = chosen.ok_or_else(|| {
        Failure::Input(anyhow!(
            "{}: no {} topology in the pack (it has: {}); bake with --topology KIND",
            pack_path.display(),
            wanted.as_deref().unwrap_or("spring"),
            if available.is_empty() { "none".to_string() } else { available.join(", ") }
        ))
    })?;
    let started = Instant::now();
    let report = match run_scene(&topology, &mesh, &scene) {
        Ok(r) => r,
        Err(e @ SimError::Parameter { .. }) => {
            return Err(Failure::Usage(anyhow::Error::new(e).context(scene_path.display().to_string())));
        }
        Err(e) => return Err(Failure::Input(anyhow::Error::new(e).context(pack_path.display().to_string()))),
    };
    let seconds = started.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&report).expect("the report is plain serde data");
    match output {
        Some(path) => furbake_formats::write_file_atomic(path, json.as_bytes()).input()?,
        None => println!("{json}"),
    }
    if !quiet {
        let steps = (scene.duration_s / scene.dt_s).ceil().max(0.0);
        eprintln!(
            "simulated {} ({} masses, {} springs, {} sticks) for {} s in {steps} steps: {:.3} s wall, {:.1} µs per step",
            topology.kind,
            topology.mass_kg.len(),
            topology.spring_ends.len(),
            topology.stick_ends.len(),
            scene.duration_s,
            seconds,
            if steps > 0.0 { seconds * 1e6 / steps } else { 0.0 },
        );
    }
    Ok(())
}
