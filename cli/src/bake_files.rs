//! What `furbake bake` writes for build systems beside the pack: the Make/Ninja depfile
//! (`--depfile`) and the machine-readable bake report (`--report`, fields documented in
//! `docs/schemas/bake-report.schema.json`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context;
use furbake_bake::{BakeSettings, BakedPack};
use furbake_formats::PackWriter;
use furbake_import::ImportedMesh;
use serde::Serialize;
use sha2::{Digest, Sha256};

/// Version of the report's layout; a field is only ever added, with a new version.
pub const REPORT_SCHEMA: &str = "furbake-bake-report/1";

/// Lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The hash of the resolved settings: SHA-256 of the manifest's `settings_json`, so equal plans
/// hash equal whichever flags, presets or config files produced them.
pub fn settings_sha256(settings: &BakeSettings) -> String {
    sha256_hex(serde_json::to_string(settings).expect("settings are plain serde structs").as_bytes())
}

/// How one character of a path is spelled in a depfile so that GNU make and Ninja both read it
/// back exactly, or why it cannot be (docs/design.md "Depfiles"; measured with GNU make 4.3 and
/// ninja 1.11, and driven through both by `tests/cli/depfile.rs`).
enum Spelling {
    Plain,
    Escaped(&'static str),
    Refused(&'static str),
}

fn spelling(c: char) -> Spelling {
    use Spelling::*;
    match c {
        // As GCC's `-MF` writes them. A backslash before them never reaches here: it is refused.
        ' ' => Escaped("\\ "),
        '#' => Escaped("\\#"),
        '$' => Escaped("$$"),
        '\n' | '\r' => Refused("a line break ends the rule"),
        '\t' => Refused("GNU make reads an escaped TAB as a space, Ninja keeps the backslash"),
        '\0'..='\x1f' | '\x7f' => Refused("Ninja ends a path at a control character"),
        ';' => Refused("GNU make reads it as the start of a recipe"),
        ':' => Refused("GNU make reads it as the end of the targets"),
        '|' => Refused("GNU make reads it as the order-only separator"),
        '=' => Refused("GNU make reads the rule as a variable assignment"),
        '%' => Refused("GNU make reads it as a pattern rule's stem"),
        '*' | '?' | '[' => Refused("GNU make expands it as a file name wildcard"),
        '\\' => Refused("GNU make and Ninja disagree on what a backslash escapes"),
        '"' | '\'' | '&' | '<' | '>' | '^' | '`' => Refused("Ninja ends a path at it"),
        // ASCII letters and digits, `! ( ) + , - . / @ ] _ { } ~`, and every non-ASCII character.
        _ => Plain,
    }
}

/// What keeps a path out of a depfile.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Offence {
    /// The path is not UTF-8.
    NotUtf8,
    /// The path is empty.
    Empty,
    /// A character refused wherever it stands.
    Char(char),
    /// A character refused as the path's first (after any `./`; a target's byte-order mark as
    /// the depfile's very first character).
    Leading(char),
    /// A character refused as the path's last.
    Trailing(char),
    /// The target is named like a GNU make special target (`.PHONY`, `.SECONDEXPANSION`).
    SpecialTarget,
}

/// A path that cannot be written into a depfile safely. `furbake bake` refuses it as bad input
/// (exit 1) before it writes anything.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DepfileRefusal {
    /// The path (lossily when it is not UTF-8).
    pub path: String,
    pub offence: Offence,
    /// What GNU make or Ninja would read instead.
    pub why: &'static str,
}

impl std::fmt::Display for DepfileRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (path, why) = (&self.path, self.why);
        match self.offence {
            Offence::NotUtf8 => write!(f, "{path:?}: the path is not UTF-8 ({why})"),
            Offence::Empty => write!(f, "an empty path cannot be written into a depfile ({why})"),
            Offence::Char(c) => write!(f, "{path:?}: {c:?} cannot be written into a depfile safely ({why})"),
            Offence::Leading(c) => {
                write!(f, "{path:?}: a leading {c:?} cannot be written into a depfile safely ({why})")
            }
            Offence::Trailing(c) => {
                write!(f, "{path:?}: a trailing {c:?} cannot be written into a depfile safely ({why})")
            }
            Offence::SpecialTarget => write!(f, "{path:?} cannot be a depfile's target ({why})"),
        }
    }
}

impl std::error::Error for DepfileRefusal {}

/// `s` as GNU make names the file: without leading `./` (make strips them before it expands a
/// `~` or looks for a special target).
fn without_dot_slash(mut s: &str) -> &str {
    while let Some(rest) = s.strip_prefix("./") {
        s = rest.trim_start_matches('/');
    }
    s
}

/// One path in depfile syntax: the characters of [`spelling`] escaped, anything else that GNU
/// make and Ninja would not both read back as this exact path refused (docs/design.md
/// "Depfiles").
fn depfile_path(p: &Path) -> Result<String, DepfileRefusal> {
    let refuse = |offence, why| Err(DepfileRefusal { path: p.to_string_lossy().into_owned(), offence, why });
    let Some(s) = p.to_str() else {
        return refuse(Offence::NotUtf8, "a depfile is UTF-8 text");
    };
    if s.is_empty() {
        return refuse(Offence::Empty, "it names no file");
    }
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match spelling(c) {
            Spelling::Plain => out.push(c),
            Spelling::Escaped(e) => out.push_str(e),
            Spelling::Refused(why) => return refuse(Offence::Char(c), why),
        }
    }
    if without_dot_slash(s).starts_with('~') {
        return refuse(Offence::Leading('~'), "GNU make expands it to a home directory");
    }
    if s.ends_with(' ') {
        return refuse(Offence::Trailing(' '), "GNU make drops the spaces before a line break, escaped or not");
    }
    if s.ends_with(')') {
        return refuse(Offence::Trailing(')'), "GNU make reads `name(member)` as a member of the archive `name`");
    }
    Ok(out)
}

/// The target's path in depfile syntax: [`depfile_path`], not a GNU make special target
/// (`.PHONY: inputs` would make the inputs phony, `.SECONDEXPANSION:` expand later rules twice),
/// and not led by a byte-order mark (the target is the depfile's first text, and GNU make skips
/// a BOM at the start of a makefile it reads, so the rule would name another file; found by the
/// pipelines fuzzer, `crates/fuzz/src/pipelines.rs`).
fn depfile_target(p: &Path) -> Result<String, DepfileRefusal> {
    let out = depfile_path(p)?;
    if out.starts_with('\u{feff}') {
        return Err(DepfileRefusal {
            path: p.to_string_lossy().into_owned(),
            offence: Offence::Leading('\u{feff}'),
            why: "GNU make skips a byte-order mark at the start of the depfile, so the rule would name another file",
        });
    }
    let name = without_dot_slash(&out);
    if name.len() > 1 && name.starts_with('.') && name[1..].bytes().all(|b| b.is_ascii_uppercase() || b == b'_') {
        let path = p.to_string_lossy().into_owned();
        return Err(DepfileRefusal {
            path,
            offence: Offence::SpecialTarget,
            why: "GNU make reads it as a special target",
        });
    }
    Ok(out)
}

/// The depfile text: `OUTPUT: INPUT…`, one input per continued line, each file once, in the
/// order the bake read them (the glTF, its buffers, its images), then the config file. Refuses
/// (before anything is written) any path that cannot be written safely.
pub fn depfile_text(output: &Path, imported: &ImportedMesh, config: Option<&Path>) -> Result<String, DepfileRefusal> {
    let mut inputs: Vec<PathBuf> = Vec::new();
    for f in &imported.inputs {
        if !f.path.as_os_str().is_empty() && !inputs.contains(&f.path) {
            inputs.push(f.path.clone());
        }
    }
    if let Some(c) = config {
        if !inputs.iter().any(|p| p == c) {
            inputs.push(c.to_path_buf());
        }
    }
    let mut text = format!("{}:", depfile_target(output)?);
    for p in &inputs {
        text.push_str(" \\\n  ");
        text.push_str(&depfile_path(p)?);
    }
    text.push('\n');
    Ok(text)
}

/// Wall time of one part of the bake.
#[derive(Serialize)]
pub struct StageTime {
    /// `import`, a bake stage's name (`volume`, `uv_map`, `fin_edges`, `blades`, `topologies`),
    /// or `write`.
    pub stage: &'static str,
    /// Seconds.
    pub wall_s: f64,
}

#[derive(Serialize)]
struct InputEntry<'a> {
    name: &'a str,
    bytes: u64,
    sha256: &'a str,
}

#[derive(Serialize)]
struct SectionEntry {
    kind: String,
    version: u16,
    bytes: usize,
}

#[derive(Serialize)]
struct MeshEntry {
    triangles: usize,
    furry_triangles: usize,
    vertices: usize,
    degenerate_triangles_skipped: u32,
}

#[derive(Serialize)]
struct Report<'a> {
    schema: &'static str,
    tool: &'static str,
    tool_version: &'static str,
    input: String,
    output: String,
    input_sha256: &'a str,
    input_bytes: u64,
    inputs: Vec<InputEntry<'a>>,
    preset: &'a str,
    seed: u64,
    settings_sha256: String,
    pack_bytes: usize,
    pack_sha256: String,
    sections: Vec<SectionEntry>,
    stages: &'a [StageTime],
    total_wall_s: f64,
    mesh: MeshEntry,
    warnings: &'a [String],
}

/// What the report needs beyond the bake itself.
pub struct ReportInputs<'a> {
    pub mesh_path: &'a Path,
    pub output: &'a Path,
    pub imported: &'a ImportedMesh,
    pub settings: &'a BakeSettings,
    pub baked: &'a BakedPack,
    pub writer: &'a PackWriter,
    pub pack_bytes: &'a [u8],
    pub stages: &'a [StageTime],
    pub total: Duration,
}

/// The report as pretty JSON (keys in a fixed order; only the wall times change between runs).
pub fn report_json(r: &ReportInputs) -> String {
    let m = &r.baked.mesh;
    let report = Report {
        schema: REPORT_SCHEMA,
        tool: "furbake",
        tool_version: env!("CARGO_PKG_VERSION"),
        input: r.mesh_path.display().to_string(),
        output: r.output.display().to_string(),
        input_sha256: &r.imported.input_sha256,
        input_bytes: r.imported.input_bytes,
        inputs: r
            .imported
            .inputs
            .iter()
            .map(|f| InputEntry { name: &f.name, bytes: f.bytes, sha256: &f.sha256 })
            .collect(),
        preset: &r.settings.preset,
        seed: r.settings.seed,
        settings_sha256: settings_sha256(r.settings),
        pack_bytes: r.pack_bytes.len(),
        pack_sha256: sha256_hex(r.pack_bytes),
        sections: r
            .writer
            .sections()
            .map(|(kind, version, bytes)| SectionEntry { kind: kind.to_string(), version, bytes })
            .collect(),
        stages: r.stages,
        total_wall_s: r.total.as_secs_f64(),
        mesh: MeshEntry {
            triangles: m.triangles.len(),
            furry_triangles: m.furry_triangles(),
            vertices: m.positions.len(),
            degenerate_triangles_skipped: m.stats.degenerate_triangles_skipped,
        },
        warnings: &r.imported.warnings,
    };
    serde_json::to_string_pretty(&report).expect("the report is plain serde data") + "\n"
}

/// Writes `text` to `path` atomically, naming `what` in the error.
pub fn write_text(path: &Path, text: &str, what: &str) -> anyhow::Result<()> {
    furbake_formats::write_file_atomic(path, text.as_bytes())
        .with_context(|| format!("{}: cannot write {what}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(s: &str) -> Result<String, DepfileRefusal> {
        depfile_path(Path::new(s))
    }

    #[test]
    fn depfile_paths_escape_what_make_and_ninja_treat_specially() {
        assert_eq!(path("a b/c#d$e.png").unwrap(), "a\\ b/c\\#d$$e.png");
        assert_eq!(path(" lead/#x  y$(shell z).png").unwrap(), "\\ lead/\\#x\\ \\ y$$(shell\\ z).png");
        assert!(path("bad\nname").is_err());
    }

    #[test]
    fn every_ascii_character_is_plain_escaped_or_refused_as_measured() {
        // docs/design.md "Depfiles": the table GNU make 4.3 and ninja 1.11 were measured against.
        let plain = "!()+,-./@]_{}~";
        for b in 1..=0x7fu8 {
            let c = b as char;
            let got = path(&format!("a{c}b"));
            if c.is_ascii_alphanumeric() || plain.contains(c) {
                assert_eq!(got.unwrap(), format!("a{c}b"), "{c:?}");
            } else if let Some(e) = [(' ', "\\ "), ('#', "\\#"), ('$', "$$")].iter().find(|(k, _)| *k == c) {
                assert_eq!(got.unwrap(), format!("a{}b", e.1), "{c:?}");
            } else {
                let e = got.unwrap_err();
                assert_eq!(e.offence, Offence::Char(c), "{c:?}");
                assert!(!e.to_string().contains('\n') && !e.why.is_empty(), "{e}");
            }
        }
        for s in ["é.png", "日本語/テクスチャ.png", "a\u{a0}b", "a\u{2028}b", "a\u{85}b", "😀"] {
            assert_eq!(path(s).unwrap(), s);
        }
    }

    #[test]
    fn refusals_name_the_path_the_character_and_the_reason_on_one_line() {
        assert_eq!(
            path("a;b.bin").unwrap_err().to_string(),
            "\"a;b.bin\": ';' cannot be written into a depfile safely (GNU make reads it as the start of a recipe)"
        );
        let e = path("dir/in\tname.png").unwrap_err().to_string();
        assert!(e.starts_with("\"dir/in\\tname.png\": '\\t' cannot be written"), "{e}");
        let e = path("a\nb").unwrap_err().to_string();
        assert!(!e.contains('\n') && e.contains("line break"), "{e}");
    }

    #[test]
    fn where_a_character_stands_matters_for_tilde_space_and_parenthesis() {
        for s in ["~x.bin", "~/x.bin", "./~root/x", ".//./~x"] {
            assert_eq!(path(s).unwrap_err().offence, Offence::Leading('~'), "{s}");
        }
        assert_eq!(path("a/~x").unwrap(), "a/~x");
        assert_eq!(path("x.bin ").unwrap_err().offence, Offence::Trailing(' '));
        assert_eq!(path("dir /x").unwrap(), "dir\\ /x");
        assert_eq!(path("lib(member)").unwrap_err().offence, Offence::Trailing(')'));
        assert_eq!(path("Copy (2).png").unwrap(), "Copy\\ (2).png");
        assert_eq!(path("").unwrap_err().offence, Offence::Empty);
    }

    #[test]
    fn a_target_named_like_a_make_special_target_is_refused() {
        for s in [".PHONY", "./.SECONDEXPANSION", ".DEFAULT"] {
            assert_eq!(depfile_target(Path::new(s)).unwrap_err().offence, Offence::SpecialTarget, "{s}");
            // As a prerequisite it is only a file.
            assert_eq!(path(s).unwrap(), s);
        }
        for s in [".hidden.fbk", "packs/.PHONY", ".Phony", "."] {
            assert_eq!(depfile_target(Path::new(s)).unwrap(), s);
        }
    }

    #[test]
    fn a_target_led_by_a_byte_order_mark_is_refused() {
        // GNU make 4.3 skips a UTF-8 BOM at the start of an included makefile and files the rule
        // under `x.fbk`; ninja keeps it.
        let e = depfile_target(Path::new("\u{feff}x.fbk")).unwrap_err();
        assert_eq!(e.offence, Offence::Leading('\u{feff}'));
        assert!(e.to_string().contains("byte-order mark") && !e.to_string().contains('\n'), "{e}");
        // Anywhere else, and in a prerequisite, it is an ordinary character.
        assert_eq!(depfile_target(Path::new("x\u{feff}.fbk")).unwrap(), "x\u{feff}.fbk");
        assert_eq!(depfile_target(Path::new("./\u{feff}x.fbk")).unwrap(), "./\u{feff}x.fbk");
        assert_eq!(path("\u{feff}x.bin").unwrap(), "\u{feff}x.bin");
    }

    #[cfg(unix)]
    #[test]
    fn a_path_that_is_not_utf8_is_refused() {
        use std::os::unix::ffi::OsStrExt;
        let p = Path::new(std::ffi::OsStr::from_bytes(b"a\xffb.png"));
        let e = depfile_path(p).unwrap_err();
        assert_eq!(e.offence, Offence::NotUtf8);
        assert!(e.to_string().contains("not UTF-8"), "{e}");
    }
}
