//! The pipelines target: the `furbake` binary as a build pipeline meets it, with hostile file
//! systems around it (docs/design.md "Safe outputs", "Depfiles" and "Bounded reads";
//! `tests/cli/hostile.rs` and `tests/cli/depfile.rs` pin each attack once, this target draws
//! them at random). Every case runs the real binary in a fresh private temporary directory,
//! under a wall-time limit (a hang is a failure) and an address-space limit, on one of four
//! surfaces:
//!
//! 1. [`Spec::Output`] — a hostile output path: `bake -o`/`--depfile`/`--report`, `simulate
//!    -o`/`--state-out`, `preview -o` (of a pack or a scene), `export -o`, `keyframes -o` or a
//!    batch asset's `output` is a private character device, a FIFO, a directory, a symlink
//!    to one of them, one of the command's inputs (spelled as it is, `./x`, `sub/../x`,
//!    `x/../x`, through a directory symlink, absolute, a symlink, a hard link) or another of its
//!    outputs. The command must refuse (exit 2, or 1 where the rules say so: a file the glTF
//!    names is known only once it is read) with one line naming the flag, and leave every file
//!    as it was: special files keep their type, inputs their bytes, no temporary file stays.
//! 2. [`Spec::Depfile`] — a hostile file name (an alphabet rich in what GNU make, Ninja and the
//!    shell treat specially) as the external buffer's name and/or the pack's: the bake's
//!    accept/refuse decision must match the table in docs/design.md "Depfiles" (an independent
//!    re-statement, [`depfile_refusal`]); a refusal exits 1 with one line and writes nothing; an
//!    accepted depfile is driven through the real GNU make (`include`, a marker recipe) and the
//!    real ninja (`deps = gcc`): no command hidden in a name ever runs, a second run does
//!    nothing, touching the buffer rebakes, and `ninja -t deps` records the exact paths.
//! 3. [`Spec::Manifest`] — a baked pack whose manifest gets a planted input (`../x`, absolute
//!    paths, symlinks out, FIFOs and devices inside, very long names, odd names) with the true
//!    size and hash of a real file outside: `batch` must not hang and must warn and rebake,
//!    never skip; a planted name of a regular file inside the asset roots is the control, which
//!    must be skipped (so the planting itself is known to work).
//! 4. [`Spec::Input`] — a FIFO, `/dev/zero` (or a private node with its numbers), a directory
//!    or a sparse 3 GiB file as an input: the glTF, `--config`, the external buffer, a scene, a
//!    pack a scene names, the pack of `verify`/`inspect`/`export`/`extract`, a batch file, a
//!    batch asset's config, glTF or buffer. Exit 1 within the time limit, naming the file, and
//!    nothing written.
//!
//! Case `i` of seed `s` is the same case everywhere ([`PipelineCase::generate`] draws it from
//! [`Rng::for_case`]); its reproducer is its description ([`PipelineCase::describe`]), whose first
//! line names the seed and the case ([`PipelineCase::from_description`]).
//!
//! A rule the product is known to break while its fix is still to come is listed in
//! [`OPEN_FINDINGS`]: a case that breaks it is counted as `…/open:NAME` rather than failed, so
//! that campaigns stay useful meanwhile; the entry goes with the fix.

use std::collections::BTreeMap;
use std::ffi::CString;
use std::io::Read;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

use crate::rng::Rng;

/// Known breaches of the rules, by name, whose fix is still to come (see the module doc); none
/// now. (`batch-other-asset-buffer` — a batch asset's `output` that was another asset's
/// external buffer got written over it — was closed by the batch plan reading every asset's
/// buffer and image names before anything is baked.)
pub const OPEN_FINDINGS: &[&str] = &[];

/// The four surfaces, as outcome labels start.
pub const SURFACES: [&str; 4] = ["outputs", "depfiles", "manifests", "inputs"];

/// Limits every child process runs under.
#[derive(Clone, Debug)]
pub struct Limits {
    /// Address-space limit, MiB.
    pub max_memory_mib: u64,
    /// Wall-time limit of one command (`furbake`, `make`, `ninja`); past it the command counts
    /// as hung and the case fails.
    pub command: Duration,
}

// ---------------------------------------------------------------------------------------------
// Cases

/// One case: its seed and number (which determine it) and what it does.
#[derive(Clone, Debug)]
pub struct PipelineCase {
    /// Campaign seed.
    pub seed: u64,
    /// Case number.
    pub case: u64,
    /// What is run.
    pub spec: Spec,
}

/// What a case runs, by surface (see the module doc).
#[derive(Clone, Debug)]
pub enum Spec {
    /// A hostile output path.
    Output(OutputCase),
    /// Hostile file names in a depfile.
    Depfile(DepfileCase),
    /// A planted manifest under `batch`.
    Manifest(ManifestCase),
    /// A special file as an input.
    Input(InputCase),
}

/// The commands whose outputs are drawn as hostile targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputCommand {
    /// `furbake bake` (`-o`, `--depfile`, `--report`).
    Bake,
    /// `furbake keyframes -o`.
    Keyframes,
    /// `furbake batch` (an asset's `output`).
    Batch,
    /// `furbake simulate scene.toml` (`-o`, `--state-out`).
    Simulate,
    /// `furbake preview` of a pack or a scene (`-o`).
    Preview,
    /// `furbake export pack -o`.
    Export,
}

/// Which output of the command is hostile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputSlot {
    /// `-o` (bake, keyframes).
    Output,
    /// `--depfile` (bake).
    Depfile,
    /// `--report` (bake).
    Report,
    /// `--state-out` (simulate).
    StateOut,
    /// Asset `n`'s `output` (batch).
    Asset(usize),
}

/// What the hostile output target is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OutputTarget {
    /// A private character device (`/dev/null`'s numbers made with mknod inside the case's
    /// directory, or a symlink to `/dev/null` where mknod is not permitted).
    Device,
    /// A symlink to that device.
    DeviceLink,
    /// A FIFO.
    Fifo,
    /// A symlink to a FIFO.
    FifoLink,
    /// A directory (holding a file).
    Directory,
    /// `file`, another file of the command, spelled `spelling`.
    Same {
        /// The file's plain name.
        file: String,
        /// What the file is to the command.
        role: Role,
        /// How the output names it.
        spelling: Spelling,
    },
}

/// What a file an output is spelled as is to the command.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// An input named on the command line or in the batch file (glTF, config, batch file).
    Input,
    /// The external buffer of the glTF whose output this is (known once the glTF is read).
    OwnBuffer,
    /// The external buffer of another asset of the batch.
    OtherBuffer,
    /// Another output of the command.
    Output,
}

/// How an output path names another file `x`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Spelling {
    /// `x`.
    Plain,
    /// `./x`.
    DotSlash,
    /// `sub/../x`.
    SubDotDot,
    /// `x/../x`.
    SelfDotDot,
    /// `here/x`, `here` a symlink to `.`.
    DirLink,
    /// The absolute path.
    Absolute,
    /// `link-x`, a symlink to `x` (dangling when `x` does not exist yet).
    Symlink,
    /// `hard-x`, a hard link to `x`.
    HardLink,
}

const SPELLINGS: [Spelling; 8] = [
    Spelling::Plain,
    Spelling::DotSlash,
    Spelling::SubDotDot,
    Spelling::SelfDotDot,
    Spelling::DirLink,
    Spelling::Absolute,
    Spelling::Symlink,
    Spelling::HardLink,
];

/// A hostile output case.
#[derive(Clone, Debug)]
pub struct OutputCase {
    /// The command.
    pub command: OutputCommand,
    /// Its hostile output.
    pub slot: OutputSlot,
    /// What that output is.
    pub target: OutputTarget,
    /// Bake: `--config bake.toml`; batch: asset 0 has `config = "bake.toml"`.
    pub config: bool,
    /// Bake: a `--depfile out.d` (when not the hostile slot).
    pub depfile: bool,
    /// Bake: a `--report report.json` (when not the hostile slot).
    pub report: bool,
    /// Batch: a second asset (`b.gltf` → `out1.fbk`).
    pub two_assets: bool,
    /// The command's other outputs exist already (regular files with old bytes).
    pub existing_outputs: bool,
    /// Batch: `-j`.
    pub jobs: u8,
    /// Simulate: an `-o` (when not the hostile slot); preview: of the scene, not the pack.
    pub second: bool,
}

/// Hostile depfile names: the external buffer's file name and the pack's.
#[derive(Clone, Debug)]
pub struct DepfileCase {
    /// The buffer's file name (its glTF URI is this, percent-encoded).
    pub buffer: String,
    /// The pack's path (`--output=`; the depfile's target).
    pub output: String,
}

/// A planted manifest input.
#[derive(Clone, Debug)]
pub struct ManifestCase {
    /// The name planted.
    pub planted: Planted,
    /// Replaces the buffer's entry (else is added after the recorded inputs).
    pub replace_buffer: bool,
}

/// The name a planted manifest records (all NUL-free), with the size and hash of the file it
/// stands for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Planted {
    /// `../secret.bin`: outside the asset roots, a real file with the buffer's bytes.
    ParentSecret,
    /// `sub/…/../../secret.bin`, `depth` levels deep and out again.
    DeepParent(usize),
    /// The secret's absolute path.
    AbsoluteSecret,
    /// The secret's absolute path through `/tmp/../`.
    DottedAbsolute,
    /// `leak.bin`, a symlink inside the asset directory to the secret outside.
    LinkOut,
    /// `up/secret.bin`, `up` a directory symlink to `..`.
    DirLinkOut,
    /// A special file inside the asset directory (size 0, the empty hash).
    Special(Special),
    /// A name of `len` bytes (`a/a/…` when `slashes`), naming nothing.
    Long {
        /// Length in bytes.
        len: usize,
        /// Made of `a/` pairs (deep) rather than one component.
        slashes: bool,
    },
    /// A name of specials naming nothing.
    Odd(String),
    /// Control: a regular file inside the asset directory with this name and the buffer's
    /// bytes — up to date, must be skipped.
    Inside(String),
    /// Control: `../common/x.bin`, inside the batch's `asset_root` — must be skipped.
    SharedRoot,
}

/// A special file kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Special {
    /// A FIFO.
    Fifo,
    /// A symlink to a FIFO.
    FifoLink,
    /// A private character device with `/dev/null`'s numbers.
    Null,
    /// A private character device with `/dev/zero`'s numbers.
    Zero,
    /// A directory.
    Directory,
}

/// The input a special file stands in for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputSlot {
    /// `bake MESH`.
    BakeMesh,
    /// `bake --config`.
    BakeConfig,
    /// The glTF's external buffer under `bake`.
    BakeBuffer,
    /// `simulate SCENE`.
    SimulateScene,
    /// `preview SCENE -o`.
    PreviewScene,
    /// The pack a scene names, under `simulate`.
    SimulatePack,
    /// The pack a scene names, under `preview`.
    PreviewPack,
    /// `verify PACK`.
    Verify,
    /// `inspect PACK`.
    Inspect,
    /// `export PACK -o`.
    Export,
    /// `extract PACK -o`.
    Extract,
    /// `batch FILE`.
    BatchFile,
    /// A batch asset's `config`.
    BatchConfig,
    /// A batch asset's `input`.
    BatchMesh,
    /// A batch asset's glTF's external buffer.
    BatchBuffer,
}

const INPUT_SLOTS: [InputSlot; 15] = [
    InputSlot::BakeMesh,
    InputSlot::BakeConfig,
    InputSlot::BakeBuffer,
    InputSlot::SimulateScene,
    InputSlot::PreviewScene,
    InputSlot::SimulatePack,
    InputSlot::PreviewPack,
    InputSlot::Verify,
    InputSlot::Inspect,
    InputSlot::Export,
    InputSlot::Extract,
    InputSlot::BatchFile,
    InputSlot::BatchConfig,
    InputSlot::BatchMesh,
    InputSlot::BatchBuffer,
];

impl OutputSlot {
    /// The flag (the batch file's key) that names this output, as messages say it.
    fn flag(self) -> &'static str {
        match self {
            OutputSlot::Output => "--output",
            OutputSlot::Depfile => "--depfile",
            OutputSlot::Report => "--report",
            OutputSlot::StateOut => "--state-out",
            OutputSlot::Asset(_) => "output",
        }
    }
}

impl InputSlot {
    /// The file name the slot's input has in the case's directory.
    fn file(self) -> &'static str {
        match self {
            InputSlot::BakeMesh | InputSlot::BatchMesh => "in.gltf",
            InputSlot::BakeConfig | InputSlot::BatchConfig => "bake.toml",
            InputSlot::BakeBuffer | InputSlot::BatchBuffer => "in.bin",
            InputSlot::SimulateScene | InputSlot::PreviewScene => "scene.toml",
            InputSlot::SimulatePack
            | InputSlot::PreviewPack
            | InputSlot::Verify
            | InputSlot::Inspect
            | InputSlot::Export
            | InputSlot::Extract => "a.fbk",
            InputSlot::BatchFile => "assets.toml",
        }
    }

    /// Whether the slot is a path on the command line (so `/dev/zero` itself can be named).
    fn on_command_line(self) -> bool {
        !matches!(
            self,
            InputSlot::BakeBuffer
                | InputSlot::SimulatePack
                | InputSlot::PreviewPack
                | InputSlot::BatchConfig
                | InputSlot::BatchMesh
                | InputSlot::BatchBuffer
        )
    }

    /// Whether batch reports the failure per asset (several lines) rather than refusing the plan.
    fn per_asset(self) -> bool {
        matches!(self, InputSlot::BatchMesh | InputSlot::BatchBuffer)
    }

    fn name(self) -> String {
        let s = format!("{self:?}");
        let mut out = String::new();
        for (i, c) in s.chars().enumerate() {
            if c.is_ascii_uppercase() && i > 0 {
                out.push('-');
            }
            out.push(c.to_ascii_lowercase());
        }
        out
    }
}

/// What stands in for an input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputKind {
    /// A FIFO.
    Fifo,
    /// `/dev/zero` itself (on the command line), or a private node with its numbers.
    Zero,
    /// A directory.
    Directory,
    /// A sparse file of 3 GiB.
    Sparse,
}

/// A special file as an input.
#[derive(Clone, Debug)]
pub struct InputCase {
    /// Which input.
    pub slot: InputSlot,
    /// What stands there.
    pub kind: InputKind,
    /// For [`InputKind::Zero`] on a command-line slot: name `/dev/zero` itself.
    pub literal_dev_zero: bool,
}

/// Everything the depfile names are drawn from: what make, Ninja and the shell treat specially
/// (all of the table's refused and escaped characters), plain characters, non-ASCII ones and
/// control characters.
const SPECIAL_CHARS: &str = ";:|=%*?[]\\#$ \t~()\"'&<>^`";
const PLAIN_CHARS: &str = "abcxyzABZ019!+,-.@_{}";
const NON_ASCII: [char; 8] = ['é', 'ü', 'ß', '日', '\u{a0}', '\u{85}', '\u{2028}', '\u{feff}'];
const CONTROL_CHARS: [char; 7] = ['\x01', '\x08', '\x1b', '\x7f', '\n', '\r', '\t'];
/// What the table writes (as itself or escaped).
const WRITTEN_CHARS: &str = "abcxyzABZ019!+,-.@_{}()]~ #$";
/// Commands hidden in names: none may ever run (each would create `PWNED`).
const INJECTIONS: [&str; 10] = [
    "$(shell touch PWNED)",
    "$$(touch PWNED)",
    "$(touch PWNED)",
    "`touch PWNED`",
    ";touch PWNED",
    "|touch PWNED",
    "&touch PWNED",
    "\ntouch PWNED\n",
    "${IFS}touch${IFS}PWNED",
    " $(shell touch PWNED) ",
];
/// Names with a special meaning to make at their start or end.
const EDGE_NAMES: [&str; 10] =
    [".PHONY", ".SECONDEXPANSION", "~root", "~", "lib(x.bin)", "x.bin ", " lead", "./~x", "a\\ b", "x\\"];

impl PipelineCase {
    /// Case `case` of the campaign seeded `seed`.
    pub fn generate(seed: u64, case: u64) -> PipelineCase {
        let mut rng = Rng::for_case(seed, case);
        let spec = match rng.below(4) {
            0 => Spec::Output(output_case(&mut rng)),
            1 => Spec::Depfile(depfile_case(&mut rng)),
            2 => Spec::Manifest(manifest_case(&mut rng)),
            _ => Spec::Input(input_case(&mut rng)),
        };
        PipelineCase { seed, case, spec }
    }

    /// The surface: one of [`SURFACES`].
    pub fn surface(&self) -> &'static str {
        match self.spec {
            Spec::Output(_) => SURFACES[0],
            Spec::Depfile(_) => SURFACES[1],
            Spec::Manifest(_) => SURFACES[2],
            Spec::Input(_) => SURFACES[3],
        }
    }

    /// The reproducer text: `furbake-fuzz pipelines seed S case I`, then the case spelled out.
    pub fn describe(&self) -> String {
        format!("furbake-fuzz pipelines seed {} case {}\n{:#?}\n", self.seed, self.case, self.spec)
    }

    /// The seed and case a [`PipelineCase::describe`] text names on its first line.
    pub fn from_description(text: &str) -> Option<(u64, u64)> {
        let words: Vec<&str> = text.lines().next()?.split_whitespace().collect();
        match words[..] {
            ["furbake-fuzz", "pipelines", "seed", s, "case", c] => Some((s.parse().ok()?, c.parse().ok()?)),
            _ => None,
        }
    }
}

fn output_case(rng: &mut Rng) -> OutputCase {
    use OutputCommand::*;
    let command = *rng.pick(&[Bake, Bake, Bake, Batch, Batch, Simulate, Simulate, Preview, Export, Keyframes]);
    let mut c = OutputCase {
        command,
        slot: OutputSlot::Output,
        target: OutputTarget::Device,
        config: rng.chance(1, 2),
        depfile: rng.chance(1, 2),
        report: rng.chance(1, 2),
        two_assets: rng.chance(2, 3),
        existing_outputs: rng.chance(1, 3),
        jobs: 1 + rng.below(2) as u8,
        second: rng.chance(1, 2),
    };
    let specials = [
        OutputTarget::Device,
        OutputTarget::DeviceLink,
        OutputTarget::Fifo,
        OutputTarget::FifoLink,
        OutputTarget::Directory,
    ];
    match command {
        OutputCommand::Keyframes => {
            c.target = rng.pick(&specials).clone();
        }
        OutputCommand::Bake => {
            c.slot = *rng.pick(&[OutputSlot::Output, OutputSlot::Depfile, OutputSlot::Report]);
            let mut same: Vec<(String, Role)> =
                vec![("in.gltf".into(), Role::Input), ("in.bin".into(), Role::OwnBuffer)];
            if c.config {
                same.push(("bake.toml".into(), Role::Input));
            }
            for (slot, name, on) in [
                (OutputSlot::Output, "out.fbk", true),
                (OutputSlot::Depfile, "out.d", c.depfile),
                (OutputSlot::Report, "report.json", c.report),
            ] {
                if slot != c.slot && on {
                    same.push((name.into(), Role::Output));
                }
            }
            c.target = hostile_target(rng, &specials, &same);
        }
        OutputCommand::Batch => {
            let asset = if c.two_assets { rng.below(2) } else { 0 };
            c.slot = OutputSlot::Asset(asset);
            let mut same: Vec<(String, Role)> =
                vec![("assets.toml".into(), Role::Input), (batch_mesh(asset).into(), Role::Input)];
            same.push((batch_buffer(asset).into(), Role::OwnBuffer));
            if c.config {
                same.push(("bake.toml".into(), Role::Input));
            }
            if c.two_assets {
                same.push((batch_mesh(1 - asset).into(), Role::Input));
                same.push((batch_buffer(1 - asset).into(), Role::OtherBuffer));
                same.push((batch_output(1 - asset).into(), Role::Output));
            }
            c.target = hostile_target(rng, &specials, &same);
        }
        OutputCommand::Simulate => {
            c.slot = *rng.pick(&[OutputSlot::Output, OutputSlot::StateOut]);
            let mut same: Vec<(String, Role)> = vec![("scene.toml".into(), Role::Input), ("a.fbk".into(), Role::Input)];
            if c.second {
                same.push((if c.slot == OutputSlot::Output { "state.json" } else { "sim.json" }.into(), Role::Output));
            }
            c.target = hostile_target(rng, &specials, &same);
        }
        OutputCommand::Preview | OutputCommand::Export => {
            let mut same: Vec<(String, Role)> = vec![("a.fbk".into(), Role::Input)];
            if command == OutputCommand::Preview && c.second {
                same.push(("scene.toml".into(), Role::Input));
            }
            c.target = hostile_target(rng, &specials, &same);
        }
    }
    // A hard link needs its file to exist.
    if let OutputTarget::Same { role: Role::Output, spelling: Spelling::HardLink, .. } = c.target {
        c.existing_outputs = true;
    }
    c
}

fn hostile_target(rng: &mut Rng, specials: &[OutputTarget], same: &[(String, Role)]) -> OutputTarget {
    if rng.chance(1, 3) {
        return rng.pick(specials).clone();
    }
    let (file, role) = rng.pick(same).clone();
    OutputTarget::Same { file, role, spelling: *rng.pick(&SPELLINGS) }
}

fn batch_mesh(asset: usize) -> &'static str {
    ["in.gltf", "b.gltf"][asset]
}

fn batch_buffer(asset: usize) -> &'static str {
    ["in.bin", "b.bin"][asset]
}

fn batch_output(asset: usize) -> &'static str {
    ["out0.fbk", "out1.fbk"][asset]
}

/// A random hostile name (see [`SPECIAL_CHARS`]); never empty, `-`-led, all dots or one of the
/// case's fixed names.
fn hostile_name(rng: &mut Rng, extension: &str) -> String {
    let mut name = String::new();
    match rng.below(10) {
        // Anything.
        0..=3 => {
            for _ in 0..1 + rng.below(10) {
                name.push(match rng.below(10) {
                    0..=3 => rng_char(rng, SPECIAL_CHARS),
                    4..=6 => rng_char(rng, PLAIN_CHARS),
                    7 | 8 => *rng.pick(&NON_ASCII),
                    _ => *rng.pick(&CONTROL_CHARS),
                });
            }
        }
        // Only what the table writes: mostly accepted, but leading `~`, trailing space or `)`.
        4..=6 => {
            for _ in 0..1 + rng.below(10) {
                name.push(if rng.chance(1, 6) { *rng.pick(&NON_ASCII) } else { rng_char(rng, WRITTEN_CHARS) });
            }
        }
        7 | 8 => {
            name.push_str(if rng.chance(1, 2) { "a" } else { "" });
            name.push_str(rng.pick::<&str>(&INJECTIONS));
            if rng.chance(1, 2) {
                name.push(rng_char(rng, WRITTEN_CHARS));
            }
        }
        _ => name.push_str(rng.pick::<&str>(&EDGE_NAMES)),
    }
    if rng.chance(1, 2) {
        name.push_str(extension);
    }
    if name.starts_with('-') || name.chars().all(|c| c == '.') {
        name.insert(0, 'x');
    }
    if ["in.gltf", "pack.d", "pack.fbk", "Makefile", "build.ninja", ".ninja_log", ".ninja_deps", "PWNED", "PWNED.bin"]
        .contains(&name.as_str())
    {
        name.insert(0, 'x');
    }
    name
}

fn rng_char(rng: &mut Rng, chars: &str) -> char {
    let chars: Vec<char> = chars.chars().collect();
    *rng.pick(&chars)
}

fn depfile_case(rng: &mut Rng) -> DepfileCase {
    let (mut buffer, mut output) = ("in.bin".to_owned(), "pack.fbk".to_owned());
    match rng.below(3) {
        0 => buffer = hostile_name(rng, ".bin"),
        1 => output = hostile_name(rng, ".fbk"),
        _ => {
            buffer = hostile_name(rng, ".bin");
            output = hostile_name(rng, ".fbk");
        }
    }
    if output == buffer || output == "in.bin" {
        output.insert(0, 'o');
    }
    DepfileCase { buffer, output }
}

fn manifest_case(rng: &mut Rng) -> ManifestCase {
    let specials = [Special::Fifo, Special::FifoLink, Special::Null, Special::Zero, Special::Directory];
    let planted = match rng.below(12) {
        0 => Planted::ParentSecret,
        1 => Planted::DeepParent(1 + rng.below(4)),
        2 => Planted::AbsoluteSecret,
        3 => Planted::DottedAbsolute,
        4 => Planted::LinkOut,
        5 => Planted::DirLinkOut,
        6 | 7 => Planted::Special(*rng.pick(&specials)),
        8 => Planted::Long { len: *rng.pick(&[256, 300, 1000, 4097, 20_000]), slashes: rng.chance(1, 2) },
        9 => {
            let mut name = String::new();
            for _ in 0..1 + rng.below(12) {
                name.push(match rng.below(4) {
                    0 => *rng.pick(&NON_ASCII),
                    1 => *rng.pick(&CONTROL_CHARS),
                    _ => rng_char(rng, SPECIAL_CHARS),
                });
            }
            Planted::Odd(format!("{name}.missing"))
        }
        10 => {
            // Specials Linux allows in one file name.
            let mut name = String::from("in");
            for _ in 0..1 + rng.below(8) {
                name.push(if rng.chance(1, 4) { *rng.pick(&NON_ASCII) } else { rng_char(rng, SPECIAL_CHARS) });
            }
            // The confined reader reads a manifest's names as it reads URIs: a `:` makes a
            // scheme and `\` a Windows separator, both refused (rebaked, which is safe); the
            // control keeps to names it reads.
            Planted::Inside(format!("{}.bin", name.replace(['\\', ':'], "_")))
        }
        _ => Planted::SharedRoot,
    };
    ManifestCase { planted, replace_buffer: rng.chance(1, 2) }
}

fn input_case(rng: &mut Rng) -> InputCase {
    let slot = *rng.pick(&INPUT_SLOTS);
    let kind = *rng.pick(&[InputKind::Fifo, InputKind::Zero, InputKind::Directory, InputKind::Sparse]);
    InputCase { slot, kind, literal_dev_zero: kind == InputKind::Zero && slot.on_command_line() && rng.chance(1, 2) }
}

// ---------------------------------------------------------------------------------------------
// The documented depfile table, stated again

/// Why the table in docs/design.md "Depfiles" refuses `path` in a depfile (`target`: as the
/// rule's target), or `None` when it is written (as itself or escaped). Stated from the table,
/// not from the CLI's code, so the two are checked against each other.
pub fn depfile_refusal(path: &str, target: bool) -> Option<String> {
    if path.is_empty() {
        return Some("empty".into());
    }
    for c in path.chars() {
        if c.is_ascii_control() {
            return Some(format!("{c:?} is a control character"));
        }
        if ";:|=%*?[\\\"'&<>^`".contains(c) {
            return Some(format!("{c:?} is refused anywhere"));
        }
    }
    let mut name = path;
    while let Some(rest) = name.strip_prefix("./") {
        name = rest.trim_start_matches('/');
    }
    if name.starts_with('~') {
        return Some("a leading '~'".into());
    }
    if path.ends_with(' ') || path.ends_with(')') {
        return Some("a trailing space or ')'".into());
    }
    if target && path.starts_with('\u{feff}') {
        return Some("a leading byte-order mark, the depfile's first character".into());
    }
    if target
        && name.len() > 1
        && name.starts_with('.')
        && name[1..].bytes().all(|b| b.is_ascii_uppercase() || b == b'_')
    {
        return Some("a make special target".into());
    }
    None
}

// ---------------------------------------------------------------------------------------------
// The base input: a small glTF with an external buffer

/// The mesh every case bakes: the grass patch (13 vertices, 16 triangles) with its buffer in an
/// external file.
pub struct Fixture {
    gltf: Value,
    bin: Vec<u8>,
}

impl Fixture {
    /// Made in-process (deterministic).
    pub fn new() -> Result<Fixture, String> {
        let mesh = furbake_import::testmesh::grass_patch(2.0);
        let gltf: Value = serde_json::from_slice(&mesh.gltf).map_err(|e| format!("test mesh: {e}"))?;
        let uri = gltf["buffers"][0]["uri"].as_str().ok_or("test mesh: no buffer URI")?;
        let b64 = uri.split_once("base64,").ok_or("test mesh: not a data URI")?.1;
        let bin = crate::gltf::base64_decode(b64).ok_or("test mesh: bad base64")?;
        Ok(Fixture { gltf, bin })
    }

    /// The glTF JSON with its buffer at `buffer` (percent-encoded into the URI).
    pub fn gltf_naming(&self, buffer: &str) -> Vec<u8> {
        let mut g = self.gltf.clone();
        g["buffers"][0]["uri"] = Value::String(percent_encode(buffer));
        serde_json::to_vec(&g).unwrap_or_default()
    }

    /// Writes `gltf` naming `buffer` and the buffer itself into `dir`.
    fn write(&self, dir: &Path, gltf: &str, buffer: &str) -> Result<(), String> {
        write(&dir.join(gltf), &self.gltf_naming(buffer))?;
        write(&dir.join(buffer), &self.bin)
    }
}

/// Percent-encodes a file name for a glTF URI (everything but ASCII letters, digits, `-._~`).
pub fn percent_encode(name: &str) -> String {
    name.bytes()
        .map(|b| match b {
            b'a'..=b'z' | b'A'..=b'Z' | b'0'..=b'9' | b'-' | b'.' | b'_' | b'~' => (b as char).to_string(),
            b => format!("%{b:02X}"),
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Running

/// Runs `case` with the `furbake` binary at `furbake` (absolute: it runs in the case's
/// directory). `Ok` is the outcome label (`SURFACE/…/…`, no spaces); `Err` says which rule was
/// broken, with the command and its stderr.
pub fn run_case(furbake: &Path, fixture: &Fixture, case: &PipelineCase, limits: &Limits) -> Result<String, String> {
    let dir = tempfile::Builder::new().prefix("furbake-pipelines-").tempdir().map_err(|e| format!("tempdir: {e}"))?;
    let ctx = Ctx { furbake, fixture, limits, dir: dir.path() };
    let label = match &case.spec {
        Spec::Output(c) => ctx.output(c),
        Spec::Depfile(c) => ctx.depfile(c),
        Spec::Manifest(c) => ctx.manifest(c),
        Spec::Input(c) => ctx.input(c),
    }?;
    Ok(format!("{}/{label}", case.surface()))
}

struct Ctx<'a> {
    furbake: &'a Path,
    fixture: &'a Fixture,
    limits: &'a Limits,
    dir: &'a Path,
}

/// What a command did.
#[derive(Debug)]
pub struct Ran {
    /// Exit code.
    pub code: i32,
    /// Standard output.
    pub stdout: String,
    /// Standard error.
    pub stderr: String,
}

impl Ran {
    fn one_line(&self) -> bool {
        self.stderr.trim_end().lines().count() == 1
    }
}

/// Runs `program args` in `dir` in its own process group, under `limits` (the address-space
/// limit and the wall-time limit: past it the whole group is killed and the run is an `Err`).
/// Make's variables from a surrounding `make` are not passed on.
pub fn exec(program: &Path, args: &[&str], dir: &Path, limits: &Limits) -> Result<Ran, String> {
    let mut cmd = Command::new(program);
    cmd.args(args)
        .current_dir(dir)
        .env_remove("MAKEFLAGS")
        .env_remove("MFLAGS")
        .env_remove("MAKELEVEL")
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0);
    crate::limit_memory(&mut cmd, limits.max_memory_mib);
    let what = || format!("{} {:?}", program.display(), args);
    let mut child = cmd.spawn().map_err(|e| format!("cannot run {}: {e}", what()))?;
    let pipe = |r: Option<Box<dyn Read + Send>>| {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut r) = r {
                let _ = r.read_to_end(&mut bytes);
            }
            String::from_utf8_lossy(&bytes).into_owned()
        })
    };
    let out = pipe(child.stdout.take().map(|s| Box::new(s) as Box<dyn Read + Send>));
    let err = pipe(child.stderr.take().map(|s| Box::new(s) as Box<dyn Read + Send>));
    let started = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break status,
            Ok(None) if started.elapsed() > limits.command => {
                kill_group(child.id());
                let _ = child.wait();
                let stderr = err.join().unwrap_or_default();
                return Err(format!("hang: {} still ran after {:?}: {stderr:?}", what(), limits.command));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(3)),
            Err(e) => return Err(format!("wait for {}: {e}", what())),
        }
    };
    // The group's other members (a make's recipe) must not outlive it either.
    kill_group(child.id());
    let (stdout, stderr) = (out.join().unwrap_or_default(), err.join().unwrap_or_default());
    match status.code() {
        Some(code) => Ok(Ran { code, stdout, stderr }),
        None => Err(format!("{} was killed by a signal ({status}): {stderr:?}", what())),
    }
}

fn kill_group(pid: u32) {
    if let Ok(pid) = libc::pid_t::try_from(pid) {
        // SAFETY: kill has no memory preconditions; a group that is gone gives ESRCH.
        unsafe {
            libc::kill(-pid, libc::SIGKILL);
        }
    }
}

impl Ctx<'_> {
    fn furbake(&self, args: &[&str]) -> Result<Ran, String> {
        self.furbake_in(self.dir, args)
    }

    fn furbake_in(&self, dir: &Path, args: &[&str]) -> Result<Ran, String> {
        let mut all = vec!["--threads", "1"];
        all.extend_from_slice(args);
        let ran = exec(self.furbake, &all, dir, self.limits)?;
        if ran.stderr.contains("panicked") || !matches!(ran.code, 0..=2) {
            return Err(format!("furbake {args:?} exited {} with: {:?}", ran.code, ran.stderr));
        }
        Ok(ran)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    // --- surface 1 ---------------------------------------------------------------------------

    fn output(&self, c: &OutputCase) -> Result<String, String> {
        let d = self.dir;
        std::fs::create_dir(d.join("sub")).map_err(|e| format!("setup: {e}"))?;
        symlink(Path::new("."), &d.join("here"))?;
        // The command's files, and its outputs by flag with their plain names.
        let mut outputs: Vec<(OutputSlot, &str)> = Vec::new();
        match c.command {
            OutputCommand::Bake => {
                self.fixture.write(d, "in.gltf", "in.bin")?;
                if c.config {
                    write(&d.join("bake.toml"), b"seed = 3\n")?;
                }
                outputs.push((OutputSlot::Output, "out.fbk"));
                if c.depfile || c.slot == OutputSlot::Depfile {
                    outputs.push((OutputSlot::Depfile, "out.d"));
                }
                if c.report || c.slot == OutputSlot::Report {
                    outputs.push((OutputSlot::Report, "report.json"));
                }
            }
            OutputCommand::Keyframes => outputs.push((OutputSlot::Output, "out.fbk")),
            OutputCommand::Batch => {
                for a in 0..1 + c.two_assets as usize {
                    self.fixture.write(d, batch_mesh(a), batch_buffer(a))?;
                    outputs.push((OutputSlot::Asset(a), batch_output(a)));
                }
                if c.config {
                    write(&d.join("bake.toml"), b"seed = 3\n")?;
                }
                // Written in full below, in place (a hard link to it stays one).
                write(&d.join("assets.toml"), b"")?;
            }
            OutputCommand::Simulate | OutputCommand::Preview | OutputCommand::Export => {
                // A real pack and a scene naming it, so that only the output can be refused.
                self.fixture.write(d, "in.gltf", "in.bin")?;
                let baked =
                    self.furbake(&["bake", "in.gltf", "-o", "a.fbk", "--resolution", "8", "--layers", "2", "-q"])?;
                if baked.code != 0 {
                    return Err(format!("setup: bake a.fbk: {:?}", baked.stderr));
                }
                write(&d.join("scene.toml"), b"[[packs]]\nname = \"a\"\npath = \"a.fbk\"\n")?;
                if c.command == OutputCommand::Simulate {
                    if c.second || c.slot == OutputSlot::Output {
                        outputs.push((OutputSlot::Output, "sim.json"));
                    }
                    if c.second || c.slot == OutputSlot::StateOut {
                        outputs.push((OutputSlot::StateOut, "state.json"));
                    }
                } else {
                    outputs.push((OutputSlot::Output, "out.png"));
                }
            }
        }
        if c.existing_outputs {
            for (slot, name) in &outputs {
                if *slot != c.slot {
                    write(&d.join(name), b"old bytes\n")?;
                }
            }
        }
        let hostile = self.place_output_target(&c.target)?;
        let path_of = |slot: OutputSlot, plain: &str| if slot == c.slot { hostile.clone() } else { plain.to_owned() };
        let mut args: Vec<String> = Vec::new();
        match c.command {
            OutputCommand::Bake => {
                args.extend(["bake", "in.gltf", "--resolution", "8", "--layers", "2", "-q"].map(String::from));
                if c.config {
                    args.extend(["--config".into(), "bake.toml".into()]);
                }
                for (slot, plain) in &outputs {
                    args.push(format!("{}={}", slot.flag(), path_of(*slot, plain)));
                }
            }
            OutputCommand::Simulate => {
                args.extend(["simulate", "scene.toml", "--frames", "1", "-q"].map(String::from));
                for (slot, plain) in &outputs {
                    args.push(format!("{}={}", slot.flag(), path_of(*slot, plain)));
                }
            }
            OutputCommand::Preview => {
                let input = if c.second { "scene.toml" } else { "a.fbk" };
                args.extend(["preview", input, "--size", "16x16", "-q"].map(String::from));
                args.push(format!("--output={hostile}"));
            }
            OutputCommand::Export => {
                args.extend(["export", "a.fbk", "-q"].map(String::from));
                args.push(format!("--output={hostile}"));
            }
            OutputCommand::Keyframes => {
                args.extend(["keyframes", "--poses", "40", "-q"].map(String::from));
                args.push(format!("--output={hostile}"));
            }
            OutputCommand::Batch => {
                let mut toml = String::from("[defaults.settings]\nvolume.resolution = 8\nvolume.layers = 2\n");
                for (slot, plain) in &outputs {
                    let OutputSlot::Asset(a) = *slot else { continue };
                    toml += &format!(
                        "[[asset]]\ninput = {}\noutput = {}\n",
                        toml_str(batch_mesh(a)),
                        toml_str(&path_of(*slot, plain))
                    );
                    if a == 0 && c.config {
                        toml += "config = \"bake.toml\"\n";
                    }
                }
                write(&d.join("assets.toml"), toml.as_bytes())?;
                args.extend(["batch".into(), "assets.toml".into(), "-j".into(), c.jobs.to_string()]);
            }
        }
        let before = snapshot(d)?;
        let argv: Vec<&str> = args.iter().map(String::as_str).collect();
        let ran = self.furbake(&argv)?;
        let after = snapshot(d)?;
        let fail = |why: &str| format!("{why}: furbake {args:?} exited {}: {:?}", ran.code, ran.stderr);
        let class = match &c.target {
            OutputTarget::Same { role: Role::Input, .. } => "input",
            OutputTarget::Same { role: Role::OwnBuffer | Role::OtherBuffer, .. } => "buffer",
            OutputTarget::Same { role: Role::Output, .. } => "output",
            _ => "special",
        };
        let command = format!("{:?}", c.command).to_lowercase();
        let label = format!("{command}/{class}/exit-{}", ran.code);
        let expect = expected_output_refusal(c);
        let open =
            |finding: &str| OPEN_FINDINGS.contains(&finding).then(|| format!("{command}/{class}/open:{finding}"));
        // The known breach: the pack written to another asset's buffer, or over the link that
        // names it.
        let overwritten = match &c.target {
            OutputTarget::Same { file, role: Role::OtherBuffer, .. } => {
                [PathBuf::from(file), PathBuf::from(&hostile)].iter().any(|f| before.get(f) != after.get(f))
            }
            _ => false,
        };
        // Another output through a symlink that dangles until that output is written: two files
        // in the end, so writing both is fine as long as each is its own file.
        let Some(expect) = expect else {
            if ran.code == 0 {
                self.check_written(c, &outputs, &hostile, &before, &after).map_err(|e| fail(&e))?;
                return Ok(format!("{command}/{class}/written-apart"));
            }
            if ran.code != 2 || !ran.stderr.contains("is the same file as") {
                return Err(fail(
                    "another output through a dangling symlink: neither refused as that output nor written apart",
                ));
            }
            unchanged(&before, &after).map_err(|e| fail(&e))?;
            return Ok(label);
        };
        let checked = self.check_refusal(c, &ran, &outputs, &before, &after, expect, class);
        match checked {
            Err(e) if overwritten => open("batch-other-asset-buffer").ok_or(e),
            Err(e) => Err(e),
            Ok(()) => Ok(label),
        }
    }

    /// The checks of a refused hostile output (see [`expected_output_refusal`]).
    #[allow(clippy::too_many_arguments)]
    fn check_refusal(
        &self,
        c: &OutputCase,
        ran: &Ran,
        outputs: &[(OutputSlot, &str)],
        before: &Snapshot,
        after: &Snapshot,
        (code, says): (i32, Vec<&'static str>),
        class: &str,
    ) -> Result<(), String> {
        let fail = |why: &str| format!("{why}: furbake ({c:?}) exited {}: {:?}", ran.code, ran.stderr);
        if ran.code != code {
            return Err(fail(&format!("expected exit {code} (docs/design.md \"Safe outputs\")")));
        }
        if !says.iter().any(|s| ran.stderr.contains(s)) {
            return Err(fail(&format!("the message says none of {says:?}")));
        }
        let per_asset = c.command == OutputCommand::Batch && code == 1;
        if !per_asset && !ran.one_line() {
            return Err(fail("not one line"));
        }
        let flag = c.slot.flag();
        // Another output: the message names whichever of the two flags came second. A batch
        // that cannot make `x/..` for a pack says so about the directory.
        let no_directory = per_asset && matches!(c.target, OutputTarget::Same { spelling: Spelling::SelfDotDot, .. });
        let names_flag = ran.stderr.contains(flag) || class == "output" || no_directory;
        if !names_flag {
            return Err(fail(&format!("the message does not name {flag}")));
        }
        if per_asset {
            // The other asset may be baked; nothing else may change.
            let other: Vec<PathBuf> =
                outputs.iter().filter(|(s, _)| *s != c.slot).map(|(_, n)| PathBuf::from(n)).collect();
            unchanged_but(before, after, &other).map_err(|e| fail(&e))?;
        } else {
            unchanged(before, after).map_err(|e| fail(&e))?;
        }
        Ok(())
    }

    /// Creates what the hostile output target needs; returns its path as the command gets it.
    fn place_output_target(&self, target: &OutputTarget) -> Result<String, String> {
        let d = self.dir;
        Ok(match target {
            OutputTarget::Device => {
                private_device(&d.join("node"), 3)?;
                "node".into()
            }
            OutputTarget::DeviceLink => {
                private_device(&d.join("node"), 3)?;
                symlink(Path::new("node"), &d.join("nodelink"))?;
                "nodelink".into()
            }
            OutputTarget::Fifo => {
                mkfifo(&d.join("pipe"))?;
                "pipe".into()
            }
            OutputTarget::FifoLink => {
                mkfifo(&d.join("pipe"))?;
                symlink(Path::new("pipe"), &d.join("pipelink"))?;
                "pipelink".into()
            }
            OutputTarget::Directory => {
                std::fs::create_dir(d.join("dir")).map_err(|e| format!("setup: {e}"))?;
                write(&d.join("dir/keep"), b"keep\n")?;
                "dir".into()
            }
            OutputTarget::Same { file, spelling, .. } => match spelling {
                Spelling::Plain => file.clone(),
                Spelling::DotSlash => format!("./{file}"),
                Spelling::SubDotDot => format!("sub/../{file}"),
                Spelling::SelfDotDot => format!("{file}/../{file}"),
                Spelling::DirLink => format!("here/{file}"),
                Spelling::Absolute => d.join(file).to_string_lossy().into_owned(),
                Spelling::Symlink => {
                    symlink(Path::new(file), &d.join(format!("link-{file}")))?;
                    format!("link-{file}")
                }
                Spelling::HardLink => {
                    std::fs::hard_link(d.join(file), d.join(format!("hard-{file}")))
                        .map_err(|e| format!("setup: hard link to {file}: {e}"))?;
                    format!("hard-{file}")
                }
            },
        })
    }

    /// After a run that wrote through a dangling symlink: every output is a file of its own
    /// with its own kind of contents, the packs verify, and nothing else changed.
    fn check_written(
        &self,
        c: &OutputCase,
        outputs: &[(OutputSlot, &str)],
        hostile: &str,
        before: &Snapshot,
        after: &Snapshot,
    ) -> Result<(), String> {
        let mut inodes = Vec::new();
        let mut written = vec![PathBuf::from(hostile)];
        for (slot, plain) in outputs {
            let name = if *slot == c.slot { hostile } else { plain };
            written.push(PathBuf::from(plain));
            let path = self.path(name);
            let m = std::fs::metadata(&path).map_err(|e| format!("output {name}: {e}"))?;
            if !m.is_file() {
                return Err(format!("output {name} is not a regular file"));
            }
            inodes.push((m.dev(), m.ino(), name));
            let bytes = std::fs::read(&path).map_err(|e| format!("{name}: {e}"))?;
            match slot {
                // Simulate's report and state, bake's report: JSON.
                OutputSlot::Output if c.command == OutputCommand::Simulate => {
                    serde_json::from_slice::<Value>(&bytes).map_err(|e| format!("the report {name}: {e}"))?;
                }
                OutputSlot::Report | OutputSlot::StateOut => {
                    serde_json::from_slice::<Value>(&bytes).map_err(|e| format!("{name}: {e}"))?;
                }
                OutputSlot::Output | OutputSlot::Asset(_) => {
                    let v = self.furbake(&["verify", name])?;
                    if v.code != 0 {
                        return Err(format!("the pack {name} does not verify: {:?}", v.stderr));
                    }
                }
                OutputSlot::Depfile => {
                    if !String::from_utf8_lossy(&bytes).contains(": \\\n  in.gltf") {
                        return Err(format!("the depfile {name} is not a depfile: {bytes:?}"));
                    }
                }
            }
        }
        inodes.sort();
        if inodes.windows(2).any(|w| (w[0].0, w[0].1) == (w[1].0, w[1].1)) {
            return Err(format!("two outputs are one file: {inodes:?}"));
        }
        unchanged_but(before, after, &written)
    }

    // --- surface 2 ---------------------------------------------------------------------------

    fn depfile(&self, c: &DepfileCase) -> Result<String, String> {
        let role = match (c.buffer == "in.bin", c.output == "pack.fbk") {
            (false, true) => "buffer",
            (true, false) => "output",
            _ => "both",
        };
        let expected = depfile_refusal(&c.output, true)
            .map(|w| (c.output.clone(), w))
            .or_else(|| depfile_refusal(&c.buffer, false).map(|w| (c.buffer.clone(), w)));
        let direct = self.path("direct");
        std::fs::create_dir(&direct).map_err(|e| format!("setup: {e}"))?;
        self.fixture.write(&direct, "in.gltf", &c.buffer)?;
        let before = snapshot(&direct)?;
        let output_arg = format!("--output={}", c.output);
        let args = ["bake", "in.gltf", &output_arg, "--depfile=pack.d", "--resolution", "8", "--layers", "2", "-q"];
        let ran = self.furbake_in(&direct, &args)?;
        let fail = |why: String| format!("{why}: furbake {args:?} exited {}: {:?}", ran.code, ran.stderr);
        match (ran.code, &expected) {
            (0, Some((name, why))) => {
                return Err(fail(format!("wrote {name:?} into a depfile, which the Depfiles table refuses ({why})")));
            }
            (0, None) => {}
            (1, Some(_)) => {
                if !ran.one_line() {
                    return Err(fail("a refusal of more than one line".into()));
                }
                // The importer reads the buffer's URI before the depfile is made: with both
                // names hostile, either may be the one named.
                let refused = [(&c.output, true), (&c.buffer, false)]
                    .into_iter()
                    .filter(|(n, target)| depfile_refusal(n, *target).is_some());
                let named = refused.clone().any(|(name, _)| {
                    let quoted = format!("{name:?}");
                    ran.stderr.contains(quoted.trim_matches('"')) || ran.stderr.contains(&percent_encode(name))
                });
                if !named {
                    let names: Vec<&String> = refused.map(|(n, _)| n).collect();
                    return Err(fail(format!("the refusal names none of {names:?}")));
                }
                unchanged(&before, &snapshot(&direct)?).map_err(fail)?;
                no_marker(self.dir).map_err(fail)?;
                return Ok(format!("{role}/refused"));
            }
            (1, None) => return Err(fail("refused names the Depfiles table writes".into())),
            _ => return Err(fail("expected exit 0 or 1".into())),
        }
        if !direct.join(&c.output).is_file() || !direct.join("pack.d").is_file() {
            return Err(fail("exit 0 without the pack and the depfile".into()));
        }
        self.through_make(c)?;
        self.through_ninja(c)?;
        no_marker(self.dir)?;
        Ok(format!("{role}/read-back"))
    }

    fn tool(&self, tool: &str, args: &[&str], dir: &Path, what: &str) -> Result<String, String> {
        let program = which(tool).ok_or_else(|| format!("{tool} is not installed (Debian: make, ninja-build)"))?;
        let ran = exec(&program, args, dir, self.limits)?;
        if ran.code != 0 {
            return Err(format!("{what}: {tool} {args:?} exited {}: {}{}", ran.code, ran.stdout, ran.stderr));
        }
        Ok(ran.stdout)
    }

    /// A Makefile that includes the depfile and bakes with a marker recipe: the first make
    /// bakes, the second finds the pack up to date, touching the buffer rebakes. The goal is a
    /// phony `all` (make never takes a target led by `.` as its default goal).
    fn through_make(&self, c: &DepfileCase) -> Result<(), String> {
        let m = self.path("make");
        std::fs::create_dir(&m).map_err(|e| format!("setup: {e}"))?;
        self.fixture.write(&m, "in.gltf", &c.buffer)?;
        let furbake = self.furbake.to_string_lossy().replace('$', "$$");
        let target = c.output.replace('$', "$$").replace('#', "\\#").replace(' ', "\\ ");
        let makefile = format!(
            "FURBAKE := {furbake}\n.PHONY: all\nall: {target}\n{target}: in.gltf\n\t@echo BAKED\n\t@'$(FURBAKE)' --threads 1 bake in.gltf \
             -o '$@' --resolution 8 --layers 2 -q --depfile pack.d\n-include pack.d\n"
        );
        write(&m.join("Makefile"), makefile.as_bytes())?;
        let what = format!("{c:?} through GNU make");
        let make = |step: &str| self.tool("make", &["-r", "--no-print-directory"], &m, &format!("{what}: {step}"));
        let baked = |out: &str| out.lines().filter(|l| *l == "BAKED").count();
        let runs = [make("first make")?, make("second make")?];
        touch(&m.join(&c.buffer))?;
        let third = make("make after touching the buffer")?;
        if baked(&runs[0]) != 1 || baked(&runs[1]) != 0 || baked(&third) != 1 {
            return Err(format!(
                "{what}: bakes {} / {} / {} times (want 1, then 0 with the depfile read, then 1 after touching \
                 the buffer): {runs:?} {third:?}",
                baked(&runs[0]),
                baked(&runs[1]),
                baked(&third)
            ));
        }
        Ok(())
    }

    /// A build.ninja with `deps = gcc`: `ninja -t deps` records exactly the glTF and the buffer,
    /// a second run has no work, touching the buffer rebakes.
    fn through_ninja(&self, c: &DepfileCase) -> Result<(), String> {
        let n = self.path("ninja");
        std::fs::create_dir(&n).map_err(|e| format!("setup: {e}"))?;
        self.fixture.write(&n, "in.gltf", &c.buffer)?;
        let furbake = self.furbake.to_string_lossy().replace('$', "$$");
        let pack = c.output.replace('$', "$$").replace(' ', "$ ");
        let build = format!(
            "pack = {pack}\nrule bake\n  command = '{furbake}' --threads 1 bake $in -o $out --resolution 8 --layers 2 \
             -q --depfile pack.d\n  depfile = pack.d\n  deps = gcc\n  description = BAKE\n\nbuild $pack: bake in.gltf\n"
        );
        write(&n.join("build.ninja"), build.as_bytes())?;
        let what = format!("{c:?} through ninja");
        let ninja = |step: &str| self.tool("ninja", &[], &n, &format!("{what}: {step}"));
        let baked = |out: &str| out.lines().filter(|l| l.ends_with("BAKE")).count();
        let first = ninja("first ninja")?;
        let deps = self.tool("ninja", &["-t", "deps", &c.output], &n, &format!("{what}: ninja -t deps"))?;
        let recorded: Vec<&str> = deps.lines().filter_map(|l| l.strip_prefix("    ")).collect();
        if recorded != ["in.gltf", c.buffer.as_str()] {
            return Err(format!(
                "{what}: ninja -t deps records {recorded:?}, not [\"in.gltf\", {:?}]: {deps:?}",
                c.buffer
            ));
        }
        let second = ninja("second ninja")?;
        touch(&n.join(&c.buffer))?;
        let third = ninja("ninja after touching the buffer")?;
        if baked(&first) != 1 || baked(&second) != 0 || !second.contains("no work to do") || baked(&third) != 1 {
            return Err(format!("{what}: runs {first:?} / {second:?} / {third:?} (want a bake, no work, a bake)"));
        }
        Ok(())
    }

    // --- surface 3 ---------------------------------------------------------------------------

    fn manifest(&self, c: &ManifestCase) -> Result<String, String> {
        let d = self.dir;
        let assets = d.join("assets");
        let common = d.join("common");
        for sub in [&assets, &common] {
            std::fs::create_dir(sub).map_err(|e| format!("setup: {e}"))?;
        }
        self.fixture.write(&assets, "in.gltf", "in.bin")?;
        let bin = &self.fixture.bin;
        write(&d.join("secret.bin"), bin)?;
        write(&common.join("x.bin"), bin)?;
        write(
            &assets.join("assets.toml"),
            b"[defaults]\nasset_root = \"../common\"\n[defaults.settings]\nvolume.resolution = 8\nvolume.layers = 2\n\
              [[asset]]\ninput = \"in.gltf\"\n",
        )?;
        let first = self.furbake_in(&assets, &["batch", "assets.toml", "-j", "1"])?;
        if first.code != 0 || !first.stderr.contains("1 baked") {
            return Err(format!("setup: the first batch did not bake: {:?}", first.stderr));
        }
        let secret = d.join("secret.bin").to_string_lossy().into_owned();
        // The name, its recorded size and hash, and what it is.
        const EMPTY_SHA256: &str = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";
        let (name, category, special): (String, &str, bool) = match &c.planted {
            Planted::ParentSecret => ("../secret.bin".into(), "outside", false),
            Planted::DeepParent(n) => {
                let mut p = PathBuf::from(&assets);
                let mut name = String::new();
                for i in 0..*n {
                    p.push(format!("s{i}"));
                    name += &format!("s{i}/");
                }
                std::fs::create_dir_all(&p).map_err(|e| format!("setup: {e}"))?;
                (format!("{name}{}secret.bin", "../".repeat(n + 1)), "outside", false)
            }
            Planted::AbsoluteSecret => (secret.clone(), "outside", false),
            Planted::DottedAbsolute => (format!("/tmp/..{secret}"), "outside", false),
            Planted::LinkOut => {
                symlink(Path::new("../secret.bin"), &assets.join("leak.bin"))?;
                ("leak.bin".into(), "outside", false)
            }
            Planted::DirLinkOut => {
                symlink(Path::new(".."), &assets.join("up"))?;
                ("up/secret.bin".into(), "outside", false)
            }
            Planted::Special(kind) => {
                let name = match kind {
                    Special::Fifo => {
                        mkfifo(&assets.join("pipe"))?;
                        "pipe"
                    }
                    Special::FifoLink => {
                        mkfifo(&assets.join("pipe"))?;
                        symlink(Path::new("pipe"), &assets.join("pipelink"))?;
                        "pipelink"
                    }
                    Special::Null => {
                        private_device(&assets.join("null"), 3)?;
                        "null"
                    }
                    Special::Zero => {
                        private_device(&assets.join("zero"), 5)?;
                        "zero"
                    }
                    Special::Directory => {
                        std::fs::create_dir(assets.join("dir")).map_err(|e| format!("setup: {e}"))?;
                        "dir"
                    }
                };
                (name.into(), "special", true)
            }
            Planted::Long { len, slashes } => {
                let name = if *slashes { "a/".repeat(len / 2) + "a" } else { "a".repeat(*len) };
                (name, "long", false)
            }
            Planted::Odd(name) => (name.clone(), "odd", false),
            Planted::Inside(name) => {
                write(&assets.join(name), bin)?;
                (name.clone(), "inside", false)
            }
            Planted::SharedRoot => ("../common/x.bin".into(), "inside", false),
        };
        let entry = furbake_formats::sections::manifest::ManifestInput {
            name: name.clone(),
            bytes: if special { 0 } else { bin.len() as u64 },
            sha256: if special { EMPTY_SHA256.into() } else { self.buffer_sha256(&assets.join("in.fbk"))? },
        };
        plant(&assets.join("in.fbk"), entry, c.replace_buffer)?;
        let before = snapshot(d)?;
        let ran = self.furbake_in(&assets, &["batch", "assets.toml", "-j", "1"])?;
        let after = snapshot(d)?;
        let fail =
            |why: &str| format!("{why}: batch over a manifest naming {name:?} exited {}: {:?}", ran.code, ran.stderr);
        if ran.code != 0 {
            return Err(fail("expected exit 0 (the real inputs are intact)"));
        }
        let (skipped, baked) = (ran.stderr.contains("1 skipped"), ran.stderr.contains("1 baked"));
        let warned = ran.stderr.contains("warning") && ran.stderr.contains("not up to date");
        let outcome = match category {
            "inside" => {
                if !skipped || warned {
                    return Err(fail(
                        "the control (a regular file inside the asset roots, same bytes) was not skipped",
                    ));
                }
                "skipped"
            }
            "outside" | "special" => {
                if skipped || !baked {
                    return Err(fail(
                        "skipped over a name outside the asset roots or not a regular file (docs/design.md \"Bounded reads\")",
                    ));
                }
                if !warned {
                    return Err(fail(
                        "rebaked without the warning that the manifest names what the bake could not read",
                    ));
                }
                "warned-rebaked"
            }
            _ => {
                if skipped || !baked {
                    return Err(fail("skipped over a name that names nothing"));
                }
                if warned { "warned-rebaked" } else { "rebaked" }
            }
        };
        unchanged_but(&before, &after, &[PathBuf::from("assets/in.fbk")]).map_err(|e| fail(&e))?;
        Ok(format!("{category}/{outcome}"))
    }

    /// The SHA-256 the pack at `pack` records for the buffer (the secret outside is a copy).
    fn buffer_sha256(&self, pack: &Path) -> Result<String, String> {
        let m = manifest_of(pack)?;
        m.inputs
            .iter()
            .find(|f| f.name == "in.bin")
            .map(|f| f.sha256.clone())
            .ok_or("setup: no in.bin in the manifest".into())
    }

    // --- surface 4 ---------------------------------------------------------------------------

    fn input(&self, c: &InputCase) -> Result<String, String> {
        let d = self.dir;
        self.fixture.write(d, "in.gltf", "in.bin")?;
        write(&d.join("bake.toml"), b"seed = 3\n")?;
        write(&d.join("scene.toml"), b"[[packs]]\nname = \"a\"\npath = \"a.fbk\"\n")?;
        write(
            &d.join("assets.toml"),
            b"[defaults.settings]\nvolume.resolution = 8\nvolume.layers = 2\n[[asset]]\ninput = \"in.gltf\"\n\
              config = \"bake.toml\"\noutput = \"out.fbk\"\n",
        )?;
        let file = c.slot.file();
        let path = d.join(file);
        if path.exists() {
            std::fs::remove_file(&path).map_err(|e| format!("setup: {e}"))?;
        }
        let named = if c.literal_dev_zero { "/dev/zero" } else { file };
        if !c.literal_dev_zero {
            match c.kind {
                InputKind::Fifo => mkfifo(&path)?,
                InputKind::Zero => {
                    private_device(&path, 5)?;
                }
                InputKind::Directory => std::fs::create_dir(&path).map_err(|e| format!("setup: {e}"))?,
                InputKind::Sparse => std::fs::File::create(&path)
                    .and_then(|f| f.set_len(3 << 30))
                    .map_err(|e| format!("setup: sparse file: {e}"))?,
            }
        }
        let arg = |default: &'static str| if c.slot.on_command_line() { named } else { default };
        let args: Vec<&str> = match c.slot {
            InputSlot::BakeMesh | InputSlot::BakeConfig | InputSlot::BakeBuffer => {
                let mesh = if c.slot == InputSlot::BakeMesh { named } else { "in.gltf" };
                let config = if c.slot == InputSlot::BakeConfig { named } else { "bake.toml" };
                vec!["bake", mesh, "-o", "out.fbk", "--config", config, "--resolution", "8", "-q"]
            }
            InputSlot::SimulateScene | InputSlot::SimulatePack => {
                vec!["simulate", arg("scene.toml"), "--frames", "1", "-o", "sim.json"]
            }
            InputSlot::PreviewScene | InputSlot::PreviewPack => {
                vec!["preview", arg("scene.toml"), "-o", "p.png", "--size", "16x16"]
            }
            InputSlot::Verify => vec!["verify", named],
            InputSlot::Inspect => vec!["inspect", named, "--json"],
            InputSlot::Export => vec!["export", named, "-o", "out.glb"],
            InputSlot::Extract => vec!["extract", named, "-o", "exdir"],
            InputSlot::BatchFile | InputSlot::BatchConfig | InputSlot::BatchMesh | InputSlot::BatchBuffer => {
                vec!["batch", arg("assets.toml"), "-j", "1"]
            }
        };
        let before = snapshot(d)?;
        let ran = self.furbake(&args)?;
        let after = snapshot(d)?;
        let fail = |why: &str| format!("{why}: furbake {args:?} ({c:?}) exited {}: {:?}", ran.code, ran.stderr);
        if ran.code != 1 {
            return Err(fail("expected exit 1 (docs/design.md \"Bounded reads\")"));
        }
        if !c.slot.per_asset() && !ran.one_line() {
            return Err(fail("not one line"));
        }
        // A sparse buffer is read only as far as its glTF says (all zeros: no usable triangle),
        // so the message names the glTF.
        let names = ran.stderr.contains(named)
            || (c.kind == InputKind::Sparse
                && matches!(c.slot, InputSlot::BakeBuffer | InputSlot::BatchBuffer)
                && ran.stderr.contains("in.gltf"));
        if !names {
            return Err(fail(&format!("the message does not name {named}")));
        }
        let says: &[&str] = match c.kind {
            InputKind::Fifo => &["a FIFO"],
            InputKind::Zero => &["a character device", "outside the asset root"],
            InputKind::Directory => &["a directory"],
            InputKind::Sparse => &[""],
        };
        if !says.iter().any(|s| ran.stderr.contains(s)) {
            return Err(fail(&format!("the message says none of {says:?}")));
        }
        unchanged(&before, &after).map_err(|e| fail(&e))?;
        Ok(format!("{}/exit-1", c.slot.name()))
    }
}

/// The exit code and the phrases (any one) a refusal of hostile output `c` must have; `None`
/// for another output through a dangling symlink, which may also be written apart.
fn expected_output_refusal(c: &OutputCase) -> Option<(i32, Vec<&'static str>)> {
    let batch = c.command == OutputCommand::Batch;
    Some(match &c.target {
        OutputTarget::Device | OutputTarget::DeviceLink => (2, vec!["a character device"]),
        OutputTarget::Fifo | OutputTarget::FifoLink => (2, vec!["a FIFO"]),
        OutputTarget::Directory => (2, vec!["a directory"]),
        OutputTarget::Same { role, spelling, .. } => {
            // `x/../x` as `-o`: its directory `x/..` does not exist (x is a file).
            if c.command == OutputCommand::Bake && c.slot == OutputSlot::Output && *spelling == Spelling::SelfDotDot {
                return Some((2, vec!["does not exist"]));
            }
            match role {
                Role::Input => (2, vec!["is the input"]),
                Role::Output if *spelling == Spelling::Symlink && !c.existing_outputs => return None,
                Role::Output => (2, vec!["is the same file as"]),
                // A batch's plan reads every asset's buffer and image names first
                // (`furbake_import::referenced_files`), however the output spells them.
                Role::OwnBuffer | Role::OtherBuffer if batch => (2, vec!["is the input"]),
                // Known once the glTF is read (docs/design.md "Safe outputs": `bake scene.gltf
                // -o scene.bin` exits 1).
                Role::OwnBuffer | Role::OtherBuffer => (1, vec!["is the input"]),
            }
        }
    })
}

// ---------------------------------------------------------------------------------------------
// File-system helpers

fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    std::fs::write(path, bytes).map_err(|e| format!("setup: write {}: {e}", path.display()))
}

fn symlink(target: &Path, link: &Path) -> Result<(), String> {
    std::os::unix::fs::symlink(target, link).map_err(|e| format!("setup: symlink {}: {e}", link.display()))
}

fn c_path(path: &Path) -> Result<CString, String> {
    CString::new(path.as_os_str().as_bytes()).map_err(|e| format!("setup: {e}"))
}

/// Makes a FIFO at `path`.
pub fn mkfifo(path: &Path) -> Result<(), String> {
    let c = c_path(path)?;
    // SAFETY: a valid NUL-terminated path; mkfifo keeps nothing.
    if unsafe { libc::mkfifo(c.as_ptr(), 0o600) } != 0 {
        return Err(format!("setup: mkfifo {}: {}", path.display(), std::io::Error::last_os_error()));
    }
    Ok(())
}

/// A private character device at `path` with the numbers of `/dev/null` (minor 3) or
/// `/dev/zero` (minor 5), made with mknod where this process may (root), else a symlink to the
/// real one: either way nothing outside the case's directory can be replaced if a check fails.
pub fn private_device(path: &Path, minor: u32) -> Result<&'static str, String> {
    let c = c_path(path)?;
    // SAFETY: a valid NUL-terminated path; mknod keeps nothing.
    if unsafe { libc::mknod(c.as_ptr(), libc::S_IFCHR | 0o666, libc::makedev(1, minor)) } == 0 {
        return Ok("a private device node");
    }
    let real = if minor == 5 { "/dev/zero" } else { "/dev/null" };
    symlink(Path::new(real), path)?;
    Ok("a symlink to the device")
}

fn touch(path: &Path) -> Result<(), String> {
    std::fs::File::options()
        .append(true)
        .open(path)
        .and_then(|f| f.set_modified(std::time::SystemTime::now()))
        .map_err(|e| format!("touch {}: {e}", path.display()))
}

fn which(tool: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path).map(|d| d.join(tool)).find(|p| p.is_file())
}

/// `s` as a TOML basic string.
fn toml_str(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One entry of a directory tree, as a check compares it.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Entry {
    /// A regular file: its length and CRC-32 (only the length and mtime past 64 MiB).
    File(u64, u32),
    Big(u64, i64),
    Dir,
    Fifo,
    CharDevice(u64),
    Symlink(PathBuf),
    Other,
}

type Snapshot = BTreeMap<PathBuf, Entry>;

/// Every entry under `dir` (symlinks not followed), by relative path.
fn snapshot(dir: &Path) -> Result<Snapshot, String> {
    let mut out = BTreeMap::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let entries = std::fs::read_dir(dir.join(&rel)).map_err(|e| format!("list {}: {e}", rel.display()))?;
        for e in entries {
            let e = e.map_err(|e| format!("list: {e}"))?;
            let rel = rel.join(e.file_name());
            let path = dir.join(&rel);
            let m = std::fs::symlink_metadata(&path).map_err(|e| format!("stat {}: {e}", rel.display()))?;
            let t = m.file_type();
            let entry = if t.is_symlink() {
                Entry::Symlink(std::fs::read_link(&path).unwrap_or_default())
            } else if t.is_dir() {
                stack.push(rel.clone());
                Entry::Dir
            } else if t.is_file() && m.len() > 64 << 20 {
                Entry::Big(m.len(), m.mtime())
            } else if t.is_file() {
                let bytes = std::fs::read(&path).map_err(|e| format!("read {}: {e}", rel.display()))?;
                Entry::File(m.len(), crc32fast::hash(&bytes))
            } else if t.is_fifo() {
                Entry::Fifo
            } else if t.is_char_device() {
                Entry::CharDevice(m.rdev())
            } else {
                Entry::Other
            };
            out.insert(rel, entry);
        }
    }
    Ok(out)
}

/// Nothing under the directory changed: no file added (a temporary `.furbake-*.tmp` included),
/// removed, rewritten or changed in type.
fn unchanged(before: &Snapshot, after: &Snapshot) -> Result<(), String> {
    unchanged_but(before, after, &[])
}

/// As [`unchanged`], except that the regular files `allowed` may be written (created or
/// replaced by a regular file).
fn unchanged_but(before: &Snapshot, after: &Snapshot, allowed: &[PathBuf]) -> Result<(), String> {
    let mut changes = Vec::new();
    for (path, was) in before {
        match after.get(path) {
            None => changes.push(format!("{} ({was:?}) was removed", path.display())),
            Some(now) if now == was => {}
            Some(Entry::File(..) | Entry::Big(..)) if allowed.contains(path) => {}
            Some(now) => changes.push(format!("{} changed from {was:?} to {now:?}", path.display())),
        }
    }
    for (path, now) in after {
        if before.contains_key(path) {
            continue;
        }
        let ok = allowed.contains(path) && matches!(now, Entry::File(..));
        if !ok || path.to_string_lossy().contains(".furbake-") {
            changes.push(format!("{} ({now:?}) appeared", path.display()));
        }
    }
    if changes.is_empty() { Ok(()) } else { Err(changes.join("; ")) }
}

/// No marker command (`touch PWNED`) ran anywhere under `dir`.
fn no_marker(dir: &Path) -> Result<(), String> {
    let names = snapshot(dir)?;
    match names.keys().find(|p| p.file_name().is_some_and(|n| n == "PWNED")) {
        Some(p) => Err(format!("a command hidden in a name ran: {} exists", p.display())),
        None => Ok(()),
    }
}

fn manifest_of(pack: &Path) -> Result<std::sync::Arc<furbake_formats::sections::manifest::BakeManifest>, String> {
    let pack = furbake_formats::Pack::read(pack).map_err(|e| format!("setup: read the baked pack: {e}"))?;
    pack.manifest().map_err(|e| format!("setup: the baked pack's manifest: {e}"))
}

/// Rewrites the pack at `path` with `entry` in its manifest's inputs (replacing the buffer's
/// entry, or added after the others).
fn plant(
    path: &Path,
    entry: furbake_formats::sections::manifest::ManifestInput,
    replace_buffer: bool,
) -> Result<(), String> {
    use furbake_formats::sections::manifest::BakeManifest;
    use furbake_formats::{Pack, PackWriter, Section, SectionKind};
    let err = |e: furbake_formats::FormatError| format!("setup: plant the manifest: {e}");
    let pack = Pack::read(path).map_err(err)?;
    let mut writer = PackWriter::new();
    for (i, e) in pack.sections().iter().enumerate() {
        if e.kind == SectionKind::BAKE_MANIFEST {
            let mut m: BakeManifest = pack.decode(i).map_err(err)?;
            match m.inputs.iter_mut().find(|f| f.name == "in.bin").filter(|_| replace_buffer) {
                Some(f) => *f = entry.clone(),
                None => m.inputs.push(entry.clone()),
            }
            writer.push(e.kind, e.version, m.encode());
        } else {
            writer.push(e.kind, e.version, pack.payload(i).map_err(err)?.to_vec());
        }
    }
    writer.write_atomic(path).map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_reproducible_and_reach_every_surface() {
        let a = PipelineCase::generate(7, 3).describe();
        assert_eq!(a, PipelineCase::generate(7, 3).describe());
        assert_eq!(PipelineCase::from_description(&a), Some((7, 3)));
        let mut surfaces = BTreeMap::new();
        for case in 0..400 {
            *surfaces.entry(PipelineCase::generate(1, case).surface()).or_insert(0) += 1;
        }
        assert_eq!(surfaces.len(), 4, "{surfaces:?}");
        assert!(surfaces.values().all(|&n| n > 60), "{surfaces:?}");
    }

    #[test]
    fn the_table_restated() {
        for ok in ["a b.bin", "#x", "a$b", "é", "a(b", "x.PHONY", "]", ".Phony"] {
            assert_eq!(depfile_refusal(ok, true), None, "{ok:?}");
        }
        for bad in ["a;b", "a:b", "a\tb", "~x", "./~x", "x ", "lib(x)", "a\\b", "a`b", "\u{7f}", "a[b"] {
            assert!(depfile_refusal(bad, false).is_some(), "{bad:?}");
        }
        assert!(depfile_refusal(".PHONY", true).is_some());
        assert_eq!(depfile_refusal(".PHONY", false), None, "only a target is special");
        assert!(depfile_refusal("\u{feff}x", true).is_some());
        assert_eq!(depfile_refusal("\u{feff}x", false), None, "a prerequisite is not the file's start");
    }

    #[test]
    fn the_fixture_names_its_buffer_percent_encoded() {
        let f = Fixture::new().unwrap();
        let g: Value = serde_json::from_slice(&f.gltf_naming("a b;#é.bin")).unwrap();
        assert_eq!(g["buffers"][0]["uri"], "a%20b%3B%23%C3%A9.bin");
        assert_eq!(f.bin.len() as u64, g["buffers"][0]["byteLength"].as_u64().unwrap());
    }

    #[test]
    fn snapshots_see_every_change() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("a"), b"1").unwrap();
        mkfifo(&d.join("p")).unwrap();
        let before = snapshot(d).unwrap();
        assert!(unchanged(&before, &snapshot(d).unwrap()).is_ok());
        std::fs::write(d.join("a"), b"2").unwrap();
        std::fs::write(d.join(".furbake-1-x.tmp"), b"").unwrap();
        let after = snapshot(d).unwrap();
        let e = unchanged(&before, &after).unwrap_err();
        assert!(e.contains("a changed") && e.contains(".furbake-1-x.tmp"), "{e}");
        assert!(unchanged_but(&before, &after, &[PathBuf::from("a")]).unwrap_err().contains(".furbake-"));
    }
}
