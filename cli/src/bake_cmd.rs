//! `furbake bake`: flags → validated [`BakeSettings`] plan → import → memory budget → bake →
//! atomic write.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use anyhow::anyhow;
use furbake_bake::validate::check_against_mesh;
use furbake_bake::{
    BakePlan, BakeSettings, BakedPack, Progress, Stage, bake, estimate_bake_memory, settings::dotted_override,
};
use furbake_import::{ImportError, ImportedMesh, import_gltf, import_gltf_with_asset_root};
use indicatif::{ProgressBar, ProgressStyle};

use crate::args::{BakeArgs, format_bytes};
use crate::bake_files::{ReportInputs, StageTime, depfile_text, report_json, write_text};
use crate::failure::{Classify, Failure};
use crate::files::Files;

/// Stage two of argument parsing: the preset, the config file, `--set` and the named flags,
/// merged in that order and validated as a whole, plus the output paths. Runs before the input is
/// read: a bad setting exits 2 with a message that starts with its key, and nothing is written.
/// A config file that cannot be read or is not TOML is bad input (exit 1); its keys and values are
/// settings (exit 2).
pub fn plan(args: &BakeArgs) -> Result<BakePlan, Failure> {
    let mut settings = BakeSettings::preset(&args.preset).usage()?;
    if let Some(path) = &args.config {
        let text = crate::files::read_text(path, "the config")?;
        let value = crate::files::toml_overrides(&text, path)?;
        settings = settings.with_overrides(&value).map_err(|e| anyhow!("{e} (in {})", path.display())).usage()?;
    }
    let mut sets: Vec<String> = args.set.clone();
    let mut named = |key: &str, v: Option<String>| {
        if let Some(v) = v {
            sets.push(format!("{key}={v}"));
        }
    };
    named("seed", args.seed.map(|v| v.to_string()));
    named("volume.layers", args.layers.map(|v| v.to_string()));
    named("volume.resolution", args.resolution.map(|v| v.to_string()));
    named("shells.fur_length_m", args.fur_length.map(|v| v.to_string()));
    named("uv.repeat_m", args.repeat.map(|v| v.to_string()));
    named("volume.fin_slices", args.fin_slices.map(|v| v.to_string()));
    named("blades.field.density_per_m2", args.blades.map(|v| v.to_string()));
    if !args.topologies.is_empty() {
        let list = serde_json::to_string(&args.topologies).expect("strings serialise");
        sets.push(format!("topologies={list}"));
    }
    if args.no_undercoat {
        sets.push("volume.undercoat=null".into());
    }
    for s in &sets {
        settings =
            settings.with_overrides(&dotted_override(s).usage()?).map_err(|e| anyhow!("{e} (in --set {s})")).usage()?;
    }
    settings.import.strict_inputs = args.strict_inputs;
    let plan = settings.plan().usage()?;
    check_output_paths(args)?;
    Ok(plan)
}

/// The bake's files: its glTF and config as inputs; the pack (`-o -`: stdout), the depfile and
/// the report as outputs, each a regular file or new, none an input or another output
/// ([`crate::files::Files`]). The glTF's own buffers and images join the check once it is read
/// ([`bake_job`]).
pub fn plan_files(args: &BakeArgs) -> Result<Files, Failure> {
    let mut files = Files::with_inputs(std::iter::once(args.mesh.as_path()).chain(args.config.as_deref()));
    files.stream_output("--output", &args.output)?;
    if let Some(d) = &args.depfile {
        if crate::files::is_stdout(&args.output) {
            return Err(Failure::Usage(anyhow!("--depfile needs a pack file to name: --output - is stdout")));
        }
        files.output("--depfile", d)?;
    }
    if let Some(r) = &args.report {
        files.stream_output("--report", r)?;
    }
    Ok(files)
}

/// The pack goes into an existing directory and is not one; `--png-dir`, when it exists, is a
/// directory; `--asset-root` is an existing directory. Checked with the settings, so a typo costs
/// no bake.
fn check_output_paths(args: &BakeArgs) -> Result<(), Failure> {
    if let Some(root) = &args.asset_root {
        match std::fs::metadata(root) {
            Ok(m) if m.is_dir() => {}
            Ok(_) => return Err(Failure::Usage(anyhow!("--asset-root {}: is not a directory", root.display()))),
            Err(e) => return Err(Failure::Usage(anyhow!("--asset-root {}: {e}", root.display()))),
        }
    }
    let out = &args.output;
    if crate::files::is_stdout(out) {
        return Ok(());
    }
    if out.is_dir() {
        return Err(Failure::Usage(anyhow!("--output {}: is a directory, not a pack file", out.display())));
    }
    if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            return Err(Failure::Usage(anyhow!(
                "--output {}: directory {} does not exist",
                out.display(),
                parent.display()
            )));
        }
    }
    if let Some(dir) = &args.png_dir {
        if dir.exists() && !dir.is_dir() {
            return Err(Failure::Usage(anyhow!("--png-dir {}: exists and is not a directory", dir.display())));
        }
    }
    Ok(())
}

/// Refuses a plan whose estimated peak memory ([`estimate_bake_memory`]) is above
/// `--max-memory`, after the limits that need the mesh ([`check_against_mesh`]) and before any
/// stage runs: exit 2, naming the mesh, the estimate, the budget and the setting behind the
/// largest part.
fn check_memory_budget(job: &Job, settings: &BakeSettings, imported: &ImportedMesh) -> Result<(), Failure> {
    check_against_mesh(settings, &imported.mesh).usage()?;
    let estimate = estimate_bake_memory(settings, imported);
    let need = estimate.total_bytes();
    if need <= job.max_memory {
        return Ok(());
    }
    let budget = format!("--max-memory {}", format_bytes(job.max_memory));
    let head = format!(
        "{}: the bake needs about {} at its peak ({}), above {budget}",
        job.mesh.display(),
        format_bytes(need),
        estimate.peak_at
    );
    let Some(part) = estimate.largest() else {
        return Err(Failure::Usage(anyhow!("{head}; raise --max-memory")));
    };
    let share = format_bytes(part.bytes);
    Err(Failure::Usage(match &part.key {
        Some(key) => anyhow!(
            "{head}; most of it ({share}) is the {}, driven by {key} = {}: lower {key}{} or raise --max-memory",
            part.name,
            part.value,
            flag_for(key).map(|f| format!(" ({f})")).unwrap_or_default(),
        ),
        None => anyhow!(
            "{head}; most of it ({share}) is the {} ({}), which only the mesh's size drives: bake a smaller \
             mesh or raise --max-memory",
            part.name,
            part.value
        ),
    }))
}

/// The named flag that sets a settings key, when there is one.
fn flag_for(key: &str) -> Option<&'static str> {
    Some(match key {
        "volume.layers" => "--layers",
        "volume.resolution" => "--resolution",
        "blades.field.density_per_m2" => "--blades",
        "topologies" => "--topology",
        _ => return None,
    })
}

/// The progress bar (on a terminal) and the start time of each part of the bake (for
/// `--report`).
struct Bar(Option<ProgressBar>, Vec<(&'static str, Instant)>);

impl Progress for Bar {
    fn stage(&mut self, stage: Stage) {
        self.1.push((stage.id(), Instant::now()));
        if let Some(bar) = &self.0 {
            bar.inc(1);
            bar.set_message(stage.name());
        }
    }
}

impl Bar {
    /// Wall time of each part, from the starts recorded so far up to `end`.
    fn stage_times(&self, end: Instant) -> Vec<StageTime> {
        let ends = self.1.iter().skip(1).map(|&(_, t)| t).chain(std::iter::once(end));
        self.1
            .iter()
            .zip(ends)
            .map(|(&(stage, start), end)| StageTime { stage, wall_s: (end - start).as_secs_f64() })
            .collect()
    }
}

/// One bake: where its input and outputs are, and its limits. `furbake bake` makes one from
/// its flags, `furbake batch` one per asset.
pub struct Job<'a> {
    pub mesh: &'a Path,
    pub output: &'a Path,
    pub asset_root: Option<&'a Path>,
    /// The `--config` file the settings came from (a depfile lists it).
    pub config: Option<&'a Path>,
    pub png_dir: Option<&'a Path>,
    pub depfile: Option<&'a Path>,
    pub report: Option<&'a Path>,
    pub max_memory: u64,
    /// Every output of the command (of the whole batch for `furbake batch`), checked against the
    /// files the glTF names once it is read.
    pub files: &'a Files,
}

impl<'a> Job<'a> {
    fn of(args: &'a BakeArgs, files: &'a Files) -> Job<'a> {
        Job {
            files,
            mesh: &args.mesh,
            output: &args.output,
            asset_root: args.asset_root.as_deref(),
            config: args.config.as_deref(),
            png_dir: args.png_dir.as_deref(),
            depfile: args.depfile.as_deref(),
            report: args.report.as_deref(),
            max_memory: args.max_memory,
        }
    }
}

/// What a finished bake leaves for its summary.
pub struct Done {
    pub imported: ImportedMesh,
    pub baked: BakedPack,
}

/// Runs `furbake bake`.
pub fn run(args: BakeArgs, quiet: bool) -> Result<(), Failure> {
    let settings = plan(&args)?;
    let files = plan_files(&args)?;
    let show = !quiet && std::io::stderr().is_terminal();
    let bar = show.then(|| {
        let bar = ProgressBar::new(Stage::ALL.len() as u64 + 2);
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{bar:20}] {pos}/{len} {msg}")
                .expect("static template is valid")
                .progress_chars("=> "),
        );
        bar.set_message("importing glTF");
        bar
    });
    let job = Job::of(&args, &files);
    let done = bake_job(&job, &settings, bar)?;
    if !quiet {
        for w in &done.imported.warnings {
            eprintln!("furbake: warning: {w}");
        }
        let (m, baked) = (&done.baked.mesh, &done.baked);
        eprintln!(
            "baked {} → {}: {} triangles ({} furry, {} degenerate skipped), {} vertices, {} layers of {}², {} fin edges",
            args.mesh.display(),
            args.output.display(),
            m.triangles.len(),
            m.furry_triangles(),
            m.stats.degenerate_triangles_skipped,
            m.positions.len(),
            baked.shells.params.layers,
            baked.shells.params.resolution,
            baked.fin_edges.vertices.len(),
        );
        for t in &baked.topologies {
            eprintln!(
                "  topology {}: {} masses, {} springs, {} sticks",
                t.kind,
                t.mass_kg.len(),
                t.spring_ends.len(),
                t.stick_ends.len()
            );
        }
        if let Some((field, _)) = &baked.blades {
            eprintln!("  {} grass blades in {} clusters", field.blade_count(), field.grid.clusters());
        }
    }
    Ok(())
}

/// Imports, checks the memory budget, bakes and writes the pack, then the PNGs, the depfile and
/// the report the job asks for. `bar` (a terminal's progress bar) is advanced stage by stage.
pub fn bake_job(job: &Job, settings: &BakePlan, bar: Option<ProgressBar>) -> Result<Done, Failure> {
    let started = Instant::now();
    let imported = match job.asset_root {
        Some(root) => import_gltf_with_asset_root(job.mesh, root, &settings.import),
        None => import_gltf(job.mesh, &settings.import),
    };
    let imported = match imported {
        Ok(m) => m,
        // Invalid import settings and asset roots are the caller's mistake (exit 2); everything
        // else (a refused external file included) is the file's.
        Err(e @ (ImportError::Settings { .. } | ImportError::AssetRoot { .. })) => {
            return Err(Failure::Usage(e.into()));
        }
        Err(e) => return Err(Failure::Input(e.into())),
    };
    job.files.check_inputs(imported.inputs.iter().map(|f| f.path.as_path()).filter(|p| !p.as_os_str().is_empty()))?;
    check_memory_budget(job, settings, &imported)?;
    // The depfile's text before anything is written: a path it cannot hold leaves no pack behind
    // (docs/design.md "Depfiles").
    let depfile = match job.depfile {
        Some(path) => Some((path, depfile_text(job.output, &imported, job.config).input()?)),
        None => None,
    };
    let mut progress = Bar(bar, vec![("import", started)]);
    progress.stage_done_import();
    let name = file_name(job.mesh);
    let baked = bake(&imported, &name, settings, &mut progress).map_err(|e| {
        // A setting refused against this mesh (too many blades for its area, ...) is still the
        // settings' fault; anything else is the mesh's.
        if e.is_settings_error() {
            Failure::Usage(e.into())
        } else {
            Failure::Input(anyhow!("{}: {e}", job.mesh.display()))
        }
    })?;
    if let Some(bar) = &progress.0 {
        bar.set_message("writing pack");
    }
    progress.1.push(("write", Instant::now()));
    let writer = baked.to_writer();
    let pack_bytes = writer.to_bytes();
    crate::files::write_output(job.output, &pack_bytes, "the pack")?;
    if let Some(dir) = job.png_dir {
        crate::png::write_atlases(dir, &baked.shells, &baked.fins).input()?;
    }
    if let Some((path, text)) = &depfile {
        write_text(path, text, "the depfile").input()?;
    }
    if let Some(path) = job.report {
        let end = Instant::now();
        let stages = progress.stage_times(end);
        let report = report_json(&ReportInputs {
            mesh_path: job.mesh,
            output: job.output,
            imported: &imported,
            settings,
            baked: &baked,
            writer: &writer,
            pack_bytes: &pack_bytes,
            stages: &stages,
            total: end - started,
        });
        crate::files::write_output(path, report.as_bytes(), "the bake report")?;
    }
    if let Some(bar) = &progress.0 {
        bar.finish_and_clear();
    }
    Ok(Done { imported, baked })
}

impl Bar {
    fn stage_done_import(&mut self) {
        if let Some(bar) = &self.0 {
            bar.inc(1);
        }
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| p.display().to_string())
}
