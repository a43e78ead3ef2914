//! `furbake batch ASSETS.toml [-j N] [--shard K/N]`: many bakes from one file — shared defaults, per-asset
//! overrides — planned as a whole first (a bad setting anywhere exits 2 before anything is
//! baked), then baked `-j` at a time. An asset whose pack is up to date (its manifest records the
//! same tool version, the same resolved settings and the same bytes for every input file) is
//! skipped. One progress bar over the assets on a terminal, then one summary line per asset in
//! file order; exit 1 when any asset failed, after every other asset was written. Packs do not
//! depend on `-j`. `--shard K/N` bakes one deterministic slice (by output path) after checking
//! the whole batch, so N machines of a CI matrix or a farm split a batch between them.

use std::io::{IsTerminal, Read};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::anyhow;
use furbake_bake::{BakePlan, BakeSettings};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use serde::Deserialize;
use sha2::{Digest, Sha256};

use crate::args::BatchArgs;
use crate::bake_cmd::{Job, bake_job};
use crate::failure::{Classify, Failure};
use crate::files::Files;

/// Declares a batch table with the keys `[defaults]` and every `[[asset]]` share, written here
/// once, as plain fields (not a `#[serde(flatten)]`ed struct, whose buffered keys lose their name,
/// line and column in errors and escape `deny_unknown_fields`), plus the table's own fields; its
/// `common()` collects the shared keys.
macro_rules! batch_table {
    ($(#[$meta:meta])* struct $name:ident { $($own:tt)* }) => {
        $(#[$meta])*
        #[derive(Deserialize, schemars::JsonSchema)]
        #[serde(deny_unknown_fields)]
        pub(crate) struct $name {
            $($own)*
            /// The preset the settings start from (`fur`, `grass`).
            preset: Option<String>,
            /// A bake config TOML (the `--config` file), relative to the batch file.
            config: Option<PathBuf>,
            /// Extra directory external files may come from (`--asset-root`), relative to the batch file.
            asset_root: Option<PathBuf>,
            /// Settings overrides (the keys of a `--config` file); an asset's are applied after the
            /// defaults'.
            #[schemars(with = "Option<BakeSettings>")]
            settings: Option<toml::Table>,
            /// Write `<pack>.d` depfiles.
            depfile: Option<bool>,
            /// Most memory a bake may plan for (`--max-memory`), e.g. "2G".
            max_memory: Option<String>,
        }

        impl $name {
            /// The keys shared by `[defaults]` and every `[[asset]]`.
            fn common(&self) -> Common<'_> {
                Common {
                    preset: self.preset.as_deref(),
                    config: self.config.as_deref(),
                    asset_root: self.asset_root.as_deref(),
                    settings: self.settings.as_ref(),
                    depfile: self.depfile,
                    max_memory: self.max_memory.as_deref(),
                }
            }
        }
    };
}

/// The keys shared by `[defaults]` and every `[[asset]]` (documented in [`batch_table`]).
#[derive(Clone, Copy, Default)]
struct Common<'a> {
    preset: Option<&'a str>,
    config: Option<&'a Path>,
    asset_root: Option<&'a Path>,
    settings: Option<&'a toml::Table>,
    depfile: Option<bool>,
    max_memory: Option<&'a str>,
}

batch_table! {
    /// `[defaults]`: what every asset starts from.
    #[derive(Default)]
    struct Defaults {
        /// Where packs go when an asset names no `output` (default: beside the batch file).
        out_dir: Option<PathBuf>,
    }
}

batch_table! {
    /// `[[asset]]`: one glTF to bake.
    struct AssetEntry {
        /// The glTF, relative to the batch file.
        input: PathBuf,
        /// The pack, relative to the batch file (default: `out_dir/<input stem>.fbk`).
        output: Option<PathBuf>,
    }
}

/// A batch file: shared defaults and the assets to bake (`furbake batch FILE`).
#[derive(Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub(crate) struct BatchFile {
    /// What every asset starts from.
    #[serde(default)]
    defaults: Defaults,
    /// The assets to bake, at least one.
    #[serde(default, rename = "asset")]
    assets: Vec<AssetEntry>,
}

/// One asset, planned: its paths resolved and its settings validated.
struct Planned {
    input: PathBuf,
    output: PathBuf,
    /// The output path as the batch file spells it, relative to the batch file, with `/`
    /// separators: what decides the asset's shard.
    shard_key: String,
    config: Option<PathBuf>,
    asset_root: Option<PathBuf>,
    depfile: Option<PathBuf>,
    max_memory: u64,
    settings: BakePlan,
}

/// How one asset ended.
enum Outcome {
    Baked(f64),
    Skipped,
    Failed(Failure),
}

/// Runs `furbake batch`.
pub fn run(args: BatchArgs, quiet: bool) -> Result<(), Failure> {
    let text = crate::files::read_text(&args.file, "the batch file")?;
    let invalid = |key: &str, e: toml::de::Error| {
        let message = furbake_formats::input::located_message(&text, key, e.message(), e.span());
        Failure::Input(anyhow!("{}: invalid batch file: {message}", args.file.display()))
    };
    let de = toml::Deserializer::parse(&text).map_err(|e| invalid("", e))?;
    let file: BatchFile = serde_path_to_error::deserialize(de).map_err(|e| {
        let key = e.path().to_string();
        invalid(&key, e.into_inner())
    })?;
    let base = match args.file.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        // The current directory: paths stay as the file spells them (`Fox.glb`, not `./Fox.glb`).
        _ => PathBuf::new(),
    };
    if file.assets.is_empty() {
        return Err(Failure::Input(anyhow!("{}: lists no [[asset]]", args.file.display())));
    }
    let (mut plans, files) = plan(&file, &base, &args.file)?;
    let whole = plans.len();
    if let Some(shard) = args.shard {
        plans.retain(|p| shard_of(&p.shard_key, shard.count) == shard.index);
    }
    let jobs = args.jobs.map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), usize::from);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| Failure::Input(anyhow!("cannot start {jobs} threads: {e}")))?;
    let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = ProgressBar::new(plans.len() as u64);
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{bar:20}] {pos}/{len} assets {msg}")
                .expect("static template is valid")
                .progress_chars("=> "),
        );
        bar
    });
    let outcomes: Vec<Outcome> = pool.install(|| {
        plans
            .par_iter()
            .map(|p| {
                let outcome = run_one(p, &files, args.force);
                if let Some(bar) = &bar {
                    bar.inc(1);
                    bar.set_message(file_name(&p.output));
                }
                outcome
            })
            .collect()
    });
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    let (mut baked, mut skipped, mut failed) = (0, 0, 0);
    for (p, outcome) in plans.iter().zip(&outcomes) {
        match outcome {
            Outcome::Baked(s) => {
                baked += 1;
                if !quiet {
                    eprintln!("baked    {} → {} ({s:.2} s)", p.input.display(), p.output.display());
                }
            }
            Outcome::Skipped => {
                skipped += 1;
                if !quiet {
                    eprintln!("skipped  {} (up to date)", p.output.display());
                }
            }
            Outcome::Failed(e) => {
                failed += 1;
                eprintln!("failed   {}: {}", p.input.display(), e.message());
            }
        }
    }
    if !quiet || failed > 0 {
        let of = args.shard.map_or_else(String::new, |s| format!(" (shard {}/{} of {whole})", s.index, s.count));
        eprintln!("{} assets{of}: {baked} baked, {skipped} skipped, {failed} failed", plans.len());
    }
    if failed > 0 {
        return Err(Failure::Input(anyhow!("{}: {failed} of {} assets failed", args.file.display(), plans.len())));
    }
    Ok(())
}

/// The shard (1-based, of `count`) an asset with output `key` belongs to: the first eight bytes
/// of the key's SHA-256 as a little-endian number, modulo `count` — the same on every machine and
/// for any order of the batch file, and even in expectation.
fn shard_of(key: &str, count: u64) -> u64 {
    let digest = Sha256::digest(key.as_bytes());
    let first: [u8; 8] = digest[..8].try_into().expect("a SHA-256 digest has 32 bytes");
    u64::from_le_bytes(first) % count + 1
}

/// Resolves every asset's paths and settings before anything is baked, and checks the outputs
/// of the whole batch ([`Files`]): no pack or depfile is the batch file, any asset's input or
/// config, or another output (compared as resolved files), or a device, FIFO or directory.
fn plan(file: &BatchFile, base: &Path, batch: &Path) -> Result<(Vec<Planned>, Files), Failure> {
    let d = file.defaults.common();
    let mut plans: Vec<Planned> = Vec::with_capacity(file.assets.len());
    for (i, a) in file.assets.iter().enumerate() {
        let c = a.common();
        let what = || format!("{} asset {} ({})", batch.display(), i + 1, a.input.display());
        let preset = c.preset.or(d.preset).unwrap_or("fur");
        let mut settings = BakeSettings::preset(preset).map_err(|e| anyhow!("{}: {e}", what())).usage()?;
        let config = c.config.as_ref().or(d.config.as_ref()).map(|p| base.join(p));
        if let Some(path) = &config {
            let in_asset = |f: Failure| match f {
                Failure::Input(e) => Failure::Input(e.context(what())),
                Failure::Usage(e) => Failure::Usage(e.context(what())),
                other => other,
            };
            let text = crate::files::read_text(path, "the config").map_err(in_asset)?;
            let value = crate::files::toml_overrides(&text, path).map_err(in_asset)?;
            settings = settings.with_overrides(&value).map_err(|e| anyhow!("{}: {e}", what())).usage()?;
        }
        for table in [&d.settings, &c.settings].into_iter().flatten() {
            let value =
                crate::files::table_overrides(table).map_err(|e| anyhow!("{}: settings.{e}", what())).usage()?;
            settings = settings.with_overrides(&value).map_err(|e| anyhow!("{}: {e}", what())).usage()?;
        }
        let settings = settings.plan().map_err(|e| anyhow!("{}: {e}", what())).usage()?;
        let input = base.join(&a.input);
        let relative_output = match &a.output {
            Some(o) => o.clone(),
            None => {
                let stem = a.input.file_stem().ok_or_else(|| anyhow!("{}: input has no file name", what())).usage()?;
                let name = format!("{}.fbk", stem.to_string_lossy());
                file.defaults.out_dir.as_ref().map_or_else(|| PathBuf::from(&name), |o| o.join(&name))
            }
        };
        let output = base.join(&relative_output);
        let shard_key =
            relative_output.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/");
        let max_memory = match c.max_memory.or(d.max_memory) {
            Some(v) => crate::args::parse_bytes(v).map_err(|e| anyhow!("{}: max_memory: {e}", what())).usage()?,
            None => crate::args::DEFAULT_MAX_MEMORY,
        };
        let depfile =
            c.depfile.or(d.depfile).unwrap_or(false).then(|| PathBuf::from(format!("{}.d", output.display())));
        let asset_root = c.asset_root.as_ref().or(d.asset_root.as_ref()).map(|p| base.join(p));
        plans.push(Planned { input, output, shard_key, config, asset_root, depfile, max_memory, settings });
    }
    let mut files = Files::with_inputs(std::iter::once(batch));
    for p in &plans {
        files.input(&p.input);
        if let Some(c) = &p.config {
            files.input(c);
        }
        // Its buffers and images too: one asset's pack must not land on another's texture.
        for named in furbake_import::referenced_files(&p.input) {
            files.input(&named);
        }
    }
    for (i, p) in plans.iter().enumerate() {
        let in_asset = |f: Failure| match f {
            Failure::Usage(e) => {
                Failure::Usage(e.context(format!("{} asset {} ({})", batch.display(), i + 1, p.input.display())))
            }
            other => other,
        };
        files.output("output", &p.output).map_err(in_asset)?;
        if let Some(d) = &p.depfile {
            files.output("depfile", d).map_err(in_asset)?;
        }
    }
    Ok((plans, files))
}

fn run_one(p: &Planned, files: &Files, force: bool) -> Outcome {
    if !force && p.depfile.as_ref().is_none_or(|d| d.is_file()) {
        match up_to_date(&p.output, &p.input, p.asset_root.as_deref(), &p.settings) {
            Freshness::UpToDate => return Outcome::Skipped,
            Freshness::Stale => {}
            Freshness::Refused(why) => eprintln!("furbake: warning: {}: not up to date: {why}", p.output.display()),
        }
    }
    if let Some(dir) = p.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        if let Err(e) = std::fs::create_dir_all(dir) {
            return Outcome::Failed(Failure::Input(anyhow!("{}: cannot create directory: {e}", dir.display())));
        }
    }
    let started = Instant::now();
    let job = Job {
        mesh: &p.input,
        output: &p.output,
        asset_root: p.asset_root.as_deref(),
        config: p.config.as_deref(),
        png_dir: None,
        depfile: p.depfile.as_deref(),
        report: None,
        max_memory: p.max_memory,
        files,
    };
    match bake_job(&job, &p.settings, None) {
        Ok(_) => Outcome::Baked(started.elapsed().as_secs_f64()),
        Err(e) => Outcome::Failed(e),
    }
}

/// Whether a pack is up to date with its inputs.
pub enum Freshness {
    /// The manifest records this tool version, these settings and, for every input file, the
    /// bytes it holds now.
    UpToDate,
    /// Something differs, or the pack is missing or unreadable: bake.
    Stale,
    /// The manifest names a file the bake could not have read (outside the asset roots, not a
    /// regular file, …): bake, and say why (a planted manifest must not make batch read it).
    Refused(String),
}

/// Whether `output` is a pack whose manifest records this tool version, these resolved
/// settings, `input`'s file name first and, for every input file, the same bytes now (named
/// relative to the glTF's directory). Each recorded file is opened through the importer's
/// confined reader (`furbake_import::open_recorded_input`: inside the glTF's directory or
/// `asset_root`, a regular file, opened without blocking) and read at most as far as the
/// recorded size; a file longer than recorded counts as changed (a buffer file with bytes past
/// its `byteLength` is then always rebaked: safe, rare).
pub fn up_to_date(output: &Path, input: &Path, asset_root: Option<&Path>, settings: &BakeSettings) -> Freshness {
    let Ok(pack) = furbake_formats::Pack::open(output) else { return Freshness::Stale };
    let Ok(m) = pack.manifest() else { return Freshness::Stale };
    let settings_json = serde_json::to_string(settings).expect("settings are plain serde structs");
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned());
    if m.tool != "furbake"
        || m.tool_version != env!("CARGO_PKG_VERSION")
        || m.settings_json != settings_json
        || m.inputs.first().map(|f| &f.name) != name.as_ref()
    {
        return Freshness::Stale;
    }
    let dir = match input.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    for f in &m.inputs {
        let file = match furbake_import::open_recorded_input(dir, asset_root, &f.name) {
            Ok((file, len)) if len == f.bytes => file,
            Ok(_) => return Freshness::Stale,
            Err(e) if e.is_refusal() => {
                return Freshness::Refused(format!("its manifest names {:?}, which {e}", f.name));
            }
            Err(_) => return Freshness::Stale,
        };
        if !same_bytes(file, f.bytes, &f.sha256) {
            return Freshness::Stale;
        }
    }
    Freshness::UpToDate
}

fn same_bytes(file: std::fs::File, bytes: u64, sha256: &str) -> bool {
    let mut hasher = Sha256::new();
    let mut reader = file.take(bytes);
    if std::io::copy(&mut reader, &mut hasher).ok() != Some(bytes) {
        return false;
    }
    hasher.finalize().iter().map(|b| format!("{b:02x}")).collect::<String>() == sha256
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}
