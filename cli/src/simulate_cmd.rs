//! `furbake simulate`: run one topology of a pack under a TOML scene, headless, and write the
//! per-step statistics and final state as JSON (for checking results from outside).

use std::time::Instant;

use anyhow::{Context, anyhow};
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind};
use furbake_formats::{Pack, SectionKind};
use furbake_sim::{SimError, SimScene, run_scene};

use crate::args::SimulateArgs;
use crate::failure::{Classify, Failure};

/// Runs `furbake simulate`.
pub fn run(args: SimulateArgs, quiet: bool) -> Result<(), Failure> {
    let text = std::fs::read_to_string(&args.scene)
        .with_context(|| format!("{}: cannot read scene", args.scene.display()))
        .input()?;
    let scene: SimScene =
        toml::from_str(&text).with_context(|| format!("{}: invalid scene", args.scene.display())).input()?;
    let pack = Pack::read(&args.pack).input()?;
    let mesh: SkinMesh = pack.decode_first().map_err(|e| e.with_path(&args.pack)).input()?;
    let wanted = args.topology.clone().or_else(|| scene.topology.clone());
    if let Some(name) = &wanted {
        if TopologyKind::from_name(name).is_none() {
            return Err(Failure::Usage(anyhow!("unknown topology {name:?}")));
        }
    }
    let mut chosen: Option<SpringTopology> = None;
    let mut available = Vec::new();
    for i in pack.find(SectionKind::SPRING_TOPOLOGY).collect::<Vec<_>>() {
        let t: SpringTopology = pack.decode(i).map_err(|e| e.with_path(&args.pack)).input()?;
        let name = t.kind.to_string();
        available.push(name.clone());
        if chosen.is_none() && wanted.as_deref().is_none_or(|w| w == name) {
            chosen = Some(t);
        }
    }
    let topology = chosen.ok_or_else(|| {
        Failure::Input(anyhow!(
            "{}: no {} topology in the pack (it has: {}); bake with --topology KIND",
            args.pack.display(),
            wanted.as_deref().unwrap_or("spring"),
            if available.is_empty() { "none".to_string() } else { available.join(", ") }
        ))
    })?;
    let started = Instant::now();
    let report = match run_scene(&topology, &mesh, &scene) {
        Ok(r) => r,
        Err(e @ SimError::Parameter { .. }) => {
            return Err(Failure::Usage(anyhow::Error::new(e).context(args.scene.display().to_string())));
        }
        Err(e) => return Err(Failure::Input(anyhow::Error::new(e).context(args.pack.display().to_string()))),
    };
    let seconds = started.elapsed().as_secs_f64();
    let json = serde_json::to_string_pretty(&report).expect("the report is plain serde data");
    match &args.output {
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
