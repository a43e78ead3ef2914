//! Running cases: the worker (in-process, each case under `catch_unwind` and timed) and the
//! supervisor (spawns a worker per target under a memory limit, reads one line per case event,
//! and turns a worker that dies or falls silent into a failure of the case it was running, then
//! resumes after it). Every failure prints its target, seed and case, and saves the mutant as a
//! reproducer file with a `.txt` beside it saying what happened.
//!
//! Worker protocol, one line each on stdout: `start I`, `done I OUTCOME MS`, `fail I KIND
//! MESSAGE` (KIND: `panic`, `slow`, `property`), and `finished` at the end.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read, Write};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Mutex;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::corpus::{self, Seed};
use crate::packs::{self, PackModel};
use crate::rng::Rng;
use crate::{gltf, scenes};

/// What is fuzzed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Target {
    /// Mutated packs.
    Packs,
    /// Mutated glTF files.
    Gltf,
    /// Mutated scenes.
    Scenes,
    /// The `furbake` binary in hostile build pipelines ([`crate::pipelines`]; needs `--cli`).
    Pipelines,
    /// Cases that fail on purpose (panic, abort, exhaust memory, hang), to test the supervisor.
    Canary,
}

impl Target {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::Packs => "packs",
            Target::Gltf => "gltf",
            Target::Scenes => "scenes",
            Target::Pipelines => "pipelines",
            Target::Canary => "canary",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        [Target::Packs, Target::Gltf, Target::Scenes, Target::Pipelines, Target::Canary]
            .into_iter()
            .find(|t| t.name() == name)
    }
}

/// Settings of a campaign (the worker gets the same).
#[derive(Clone, Debug)]
pub struct Config {
    /// Campaign seed.
    pub seed: u64,
    /// A case slower than this is a failure (`slow`); glTF cases get four times as long.
    pub slow: Duration,
    /// A worker silent this long is killed and its case is a failure (`hang`).
    pub hang: Duration,
    /// Address-space limit of the worker, MiB.
    pub max_memory_mib: u64,
    /// The `furbake` binary for the glTF target's child-process sample and the pipelines target.
    pub cli: Option<PathBuf>,
    /// Every how many glTF cases one also goes through the binary.
    pub cli_every: u64,
    /// World steps per pack or scene case.
    pub steps: u32,
    /// Where reproducers go.
    pub out_dir: PathBuf,
}

/// The inputs a worker mutates, made once.
pub struct Corpus {
    bases: Vec<PackModel>,
    gltf: Vec<Seed>,
    scenes: Vec<String>,
    /// Holds the base packs the scenes name.
    scene_dir: Option<tempfile::TempDir>,
    /// The pipelines target's mesh.
    #[cfg(unix)]
    pipelines: Option<crate::pipelines::Fixture>,
}

impl Corpus {
    /// Makes what `target` needs (baking the base packs takes a few seconds).
    pub fn new(target: Target) -> Result<Corpus, String> {
        let mut c = Corpus {
            bases: Vec::new(),
            gltf: Vec::new(),
            scenes: Vec::new(),
            scene_dir: None,
            #[cfg(unix)]
            pipelines: None,
        };
        match target {
            Target::Packs | Target::Scenes => {
                let baked = corpus::base_packs()?;
                c.bases = baked.iter().filter_map(|s| PackModel::parse(&s.bytes)).collect();
                if c.bases.len() != baked.len() {
                    return Err("a base pack does not parse".into());
                }
                if target == Target::Scenes {
                    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
                    for (name, seed) in scenes::PACK_FILES.iter().zip(&baked) {
                        std::fs::write(dir.path().join(name), &seed.bytes).map_err(|e| e.to_string())?;
                    }
                    c.scene_dir = Some(dir);
                    for s in corpus::scene_seeds().map_err(|e| e.to_string())? {
                        let text = String::from_utf8_lossy(&s.bytes).into_owned();
                        c.scenes.push(scenes::point_at_base_packs(&text).ok_or(format!("{}: not TOML", s.name))?);
                    }
                }
            }
            Target::Gltf => {
                c.gltf = corpus::gltf_json_seeds();
                c.gltf.extend(corpus::glb_seeds().map_err(|e| e.to_string())?);
            }
            #[cfg(unix)]
            Target::Pipelines => c.pipelines = Some(crate::pipelines::Fixture::new()?),
            #[cfg(not(unix))]
            Target::Pipelines => return Err("the pipelines target needs a Unix system".into()),
            Target::Canary => {}
        }
        Ok(c)
    }

    /// Case `case` of `target` under `seed`: the mutant's bytes and its file extension.
    pub fn case(&self, target: Target, seed: u64, case: u64) -> (Vec<u8>, &'static str) {
        let mut rng = Rng::for_case(seed, case);
        match target {
            Target::Packs => (packs::mutate_pack(&mut rng, &self.bases), "fbk"),
            Target::Gltf => {
                let s = rng.pick(&self.gltf);
                let ext = if s.name.ends_with(".glb") { "glb" } else { "gltf" };
                (gltf::mutate_gltf(&mut rng, &s.bytes), ext)
            }
            Target::Scenes => {
                let seed = self.scenes[rng.below(self.scenes.len())].clone();
                (scenes::mutate_scene(&mut rng, &seed).into_bytes(), "toml")
            }
            // The case's description (its first line names the seed and the case); not `.txt`,
            // which is what the reproducer's note is called.
            #[cfg(unix)]
            Target::Pipelines => (crate::pipelines::PipelineCase::generate(seed, case).describe().into_bytes(), "case"),
            #[cfg(not(unix))]
            Target::Pipelines => (Vec::new(), "case"),
            Target::Canary => (case.to_le_bytes().to_vec(), "bin"),
        }
    }

    /// Runs one case in-process (no `catch_unwind`: see [`run_caught`]); `Ok` names the
    /// outcome, `Err` is a property violation.
    pub fn run(
        &self,
        target: Target,
        config: &Config,
        seed: u64,
        case: u64,
        bytes: &[u8],
        ext: &str,
    ) -> Result<String, String> {
        let dir = self.scene_dir.as_ref().map_or_else(std::env::temp_dir, |d| d.path().to_path_buf());
        match target {
            Target::Packs => {
                let scene = packs::pack_scene(&mut Rng::for_case(seed ^ 0x5CE2E, case), &dir);
                let (p, w) = packs::run_pack(bytes, scene, config.steps);
                Ok(match w {
                    Some(w) => format!("{p:?}/{w:?}"),
                    None => format!("{p:?}"),
                })
            }
            Target::Gltf => {
                let name = format!("fuzz.{ext}");
                let outcome = gltf::run_gltf(bytes, &name)?;
                let mut label = format!("{outcome:?}");
                if let Some(cli) = config.cli.as_ref().filter(|_| case.is_multiple_of(config.cli_every.max(1))) {
                    let o = gltf::run_cli_bake(cli, bytes, &name, 2048, config.hang / 2)?;
                    label += &format!("/cli-exit-{}", o.code);
                }
                Ok(label)
            }
            Target::Scenes => {
                let text = String::from_utf8_lossy(bytes);
                Ok(format!("{:?}", scenes::run_scene(&text, &dir, config.steps)))
            }
            Target::Pipelines => self.run_pipelines(config, bytes),
            Target::Canary => canary(case),
        }
    }

    /// A pipelines case, regenerated from the seed and case its description names (so a saved
    /// reproducer replays), run with `config.cli` under a 2 GiB address-space limit and a time
    /// limit per command of four times `config.slow`.
    #[cfg(unix)]
    fn run_pipelines(&self, config: &Config, bytes: &[u8]) -> Result<String, String> {
        use crate::pipelines::{Limits, PipelineCase, run_case};
        let cli = config.cli.as_ref().ok_or("the pipelines target needs --cli PATH/TO/furbake")?;
        let fixture = self.pipelines.as_ref().ok_or("no pipelines fixture")?;
        let text = String::from_utf8_lossy(bytes);
        let (seed, case) = PipelineCase::from_description(&text).ok_or("not a pipelines case description")?;
        let limits = Limits { max_memory_mib: 2048, command: config.slow * 4 };
        run_case(cli, fixture, &PipelineCase::generate(seed, case), &limits)
    }

    #[cfg(not(unix))]
    fn run_pipelines(&self, _config: &Config, _bytes: &[u8]) -> Result<String, String> {
        Err("the pipelines target needs a Unix system".into())
    }
}

/// The canary target's cases: 0 mod 5 succeed, 1 panics, 2 aborts, 3 allocates past any memory
/// limit, 4 hangs. The supervisor must report exactly cases 1–4 of every five.
fn canary(case: u64) -> Result<String, String> {
    match case % 5 {
        1 => panic!("canary panic in case {case}"),
        2 => std::process::abort(),
        3 => {
            let v = vec![1u8; 1 << 40];
            Ok(format!("allocated {}", v.len()))
        }
        4 => loop {
            std::thread::sleep(Duration::from_secs(1));
        },
        _ => Ok("fine".into()),
    }
}

static PANIC_MESSAGE: Mutex<String> = Mutex::new(String::new());

/// Installs a panic hook that records the message and location instead of printing them (the
/// worker reports them on its protocol line).
pub fn capture_panics() {
    std::panic::set_hook(Box::new(|info| {
        let msg = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        *PANIC_MESSAGE.lock().unwrap_or_else(|p| p.into_inner()) = format!("{msg}{at}");
    }));
}

/// Runs one case under `catch_unwind`: `Ok(outcome)`, or `Err((kind, message))` with kind
/// `panic` or `property`.
pub fn run_caught(
    corpus: &Corpus,
    target: Target,
    config: &Config,
    case: u64,
    bytes: &[u8],
    ext: &str,
) -> Result<String, (&'static str, String)> {
    match catch_unwind(AssertUnwindSafe(|| corpus.run(target, config, config.seed, case, bytes, ext))) {
        Ok(Ok(o)) => Ok(o),
        Ok(Err(e)) => Err(("property", e)),
        Err(_) => Err(("panic", std::mem::take(&mut *PANIC_MESSAGE.lock().unwrap_or_else(|p| p.into_inner())))),
    }
}

fn one_line(s: &str) -> String {
    s.replace(['\n', '\r'], " ⏎ ")
}

/// Saves case `case`'s mutant and what happened to it; returns the reproducer's path.
pub fn save_reproducer(config: &Config, target: Target, case: u64, bytes: &[u8], ext: &str, what: &str) -> PathBuf {
    let stem = format!("{}-seed{}-case{case}", target.name(), config.seed);
    let path = config.out_dir.join(format!("{stem}.{ext}"));
    let _ = std::fs::create_dir_all(&config.out_dir);
    let _ = std::fs::write(&path, bytes);
    let _ = std::fs::write(config.out_dir.join(format!("{stem}.txt")), format!("{what}\n"));
    path
}

/// The worker: runs cases `from..to` of `target`, one protocol line per event on stdout.
pub fn worker(target: Target, config: &Config, from: u64, to: u64) -> Result<(), String> {
    capture_panics();
    let corpus = Corpus::new(target)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut say = |line: String| {
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    };
    // A glTF case imports, bakes and may run the binary, a pipelines case runs several
    // commands: four times the budget.
    let budget = if matches!(target, Target::Gltf | Target::Pipelines) { config.slow * 4 } else { config.slow };
    for case in from..to {
        say(format!("start {case}"));
        let (bytes, ext) = corpus.case(target, config.seed, case);
        let started = Instant::now();
        let result = run_caught(&corpus, target, config, case, &bytes, ext);
        let took = started.elapsed();
        match result {
            Ok(outcome) if took <= budget => say(format!("done {case} {outcome} {}", took.as_millis())),
            Ok(outcome) => {
                let what = format!("{outcome} took {took:?} (limit {budget:?})");
                let path = save_reproducer(config, target, case, &bytes, ext, &what);
                say(format!("fail {case} slow {} ({})", one_line(&what), path.display()));
            }
            Err((kind, msg)) => {
                let what = format!("{kind}: {msg}");
                let path = save_reproducer(config, target, case, &bytes, ext, &what);
                say(format!("fail {case} {kind} {} ({})", one_line(&msg), path.display()));
            }
        }
    }
    say("finished".into());
    Ok(())
}

/// One failure the supervisor saw.
#[derive(Clone, Debug)]
pub struct Failure {
    /// The target.
    pub target: Target,
    /// The case.
    pub case: u64,
    /// `panic`, `slow`, `property`, `crash` (the worker died: abort, signal, memory) or `hang`.
    pub kind: String,
    /// What happened.
    pub message: String,
}

/// What a supervised campaign of one target did.
#[derive(Clone, Debug, Default)]
pub struct Report {
    /// Cases run (failed ones included).
    pub cases: u64,
    /// Outcome counts.
    pub outcomes: BTreeMap<String, u64>,
    /// Failures.
    pub failures: Vec<Failure>,
    /// Wall time.
    pub wall: Duration,
    /// Slowest case, ms.
    pub slowest_ms: u64,
}

enum Event {
    Line(String),
    Eof,
}

fn spawn_worker(exe: &Path, target: Target, config: &Config, from: u64, to: u64) -> Result<Child, String> {
    let mut cmd = Command::new(exe);
    cmd.args(["worker", target.name(), &from.to_string(), &to.to_string()])
        .args(config_args(config))
        .env("RAYON_NUM_THREADS", "2")
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    crate::limit_memory(&mut cmd, config.max_memory_mib);
    cmd.spawn().map_err(|e| format!("spawn {}: {e}", exe.display()))
}

/// The flags that give a worker the same [`Config`].
pub fn config_args(config: &Config) -> Vec<String> {
    let mut a = vec![
        "--seed".into(),
        config.seed.to_string(),
        "--slow-ms".into(),
        config.slow.as_millis().to_string(),
        "--hang-s".into(),
        config.hang.as_secs().to_string(),
        "--max-memory-mib".into(),
        config.max_memory_mib.to_string(),
        "--steps".into(),
        config.steps.to_string(),
        "--out".into(),
        config.out_dir.display().to_string(),
        "--cli-every".into(),
        config.cli_every.to_string(),
    ];
    if let Some(cli) = &config.cli {
        a.push("--cli".into());
        a.push(cli.display().to_string());
    }
    a
}

/// Runs `cases` cases of `target` in worker processes of the binary `exe` (see the module doc).
pub fn supervise(exe: &Path, target: Target, config: &Config, cases: u64, progress: bool) -> Result<Report, String> {
    let started = Instant::now();
    let mut report = Report::default();
    let mut next = 0;
    let mut corpus: Option<Corpus> = None;
    while next < cases {
        let mut child = spawn_worker(exe, target, config, next, cases)?;
        let (tx, rx) = mpsc::channel();
        let stdout = child.stdout.take().ok_or("worker stdout")?;
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                match line {
                    Ok(l) => {
                        if tx.send(Event::Line(l)).is_err() {
                            return;
                        }
                    }
                    Err(_) => break,
                }
            }
            let _ = tx.send(Event::Eof);
        });
        let mut stderr = child.stderr.take().ok_or("worker stderr")?;
        let errs = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = stderr.read_to_string(&mut s);
            s
        });
        let mut current: Option<u64> = None;
        let mut finished = false;
        // The corpus is made before the first case: allow it time.
        let mut wait = config.hang * 4;
        let died: Option<(&str, String)> = loop {
            match rx.recv_timeout(wait) {
                Ok(Event::Line(line)) => {
                    wait = config.hang;
                    let mut parts = line.splitn(4, ' ');
                    match (parts.next(), parts.next().and_then(|c| c.parse::<u64>().ok())) {
                        (Some("start"), Some(c)) => current = Some(c),
                        (Some("done"), Some(_)) => {
                            let outcome = parts.next().unwrap_or("").to_owned();
                            let ms: u64 = parts.next().and_then(|m| m.parse().ok()).unwrap_or(0);
                            report.slowest_ms = report.slowest_ms.max(ms);
                            *report.outcomes.entry(outcome).or_default() += 1;
                            report.cases += 1;
                            next = current.map_or(next, |c| c + 1);
                            current = None;
                            if progress && report.cases % 10_000 == 0 {
                                eprintln!("  {} {} cases, {:.0?}", target.name(), report.cases, started.elapsed());
                            }
                        }
                        (Some("fail"), Some(c)) => {
                            let kind = parts.next().unwrap_or("").to_owned();
                            let message = parts.next().unwrap_or("").to_owned();
                            eprintln!("FAIL {} seed {} case {c}: {kind}: {message}", target.name(), config.seed);
                            report.failures.push(Failure { target, case: c, kind, message });
                            report.cases += 1;
                            next = c + 1;
                            current = None;
                        }
                        (Some("finished"), _) => {
                            finished = true;
                            break None;
                        }
                        _ => {}
                    }
                }
                Ok(Event::Eof) => break Some(("crash", String::new())),
                Err(_) => {
                    let _ = child.kill();
                    break Some(("hang", format!("no progress for {wait:?}")));
                }
            }
        };
        let status = child.wait().map_err(|e| e.to_string())?;
        let _ = reader.join();
        let stderr = errs.join().unwrap_or_default();
        if finished && status.success() {
            break;
        }
        let (kind, mut message) = died.unwrap_or(("crash", String::new()));
        let Some(case) = current else {
            return Err(format!("the {} worker failed outside a case ({status}): {stderr}", target.name()));
        };
        let tail: String = stderr.lines().take(3).collect::<Vec<_>>().join(" | ");
        message = format!("{message} {status} {tail}").trim().to_owned();
        if corpus.is_none() {
            corpus = Some(Corpus::new(target)?);
        }
        let c = corpus.as_ref().ok_or("corpus")?;
        let (bytes, ext) = c.case(target, config.seed, case);
        let path = save_reproducer(config, target, case, &bytes, ext, &format!("{kind}: {message}"));
        eprintln!("FAIL {} seed {} case {case}: {kind}: {message} ({})", target.name(), config.seed, path.display());
        report.failures.push(Failure { target, case, kind: kind.into(), message });
        report.cases += 1;
        next = case + 1;
    }
    report.wall = started.elapsed();
    Ok(report)
}
