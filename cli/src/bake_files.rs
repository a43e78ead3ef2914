//! What `furbake bake` writes for build systems beside the pack: the Make/Ninja depfile
//! (`--depfile`) and the machine-readable bake report (`--report`, fields documented in
//! `docs/schemas/bake-report.schema.json`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{Context, anyhow};
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

/// One path in depfile syntax (the subset GNU Make and Ninja both read): spaces and `#`
/// backslash-escaped, `$` doubled. A path with a newline cannot be written (bad input).
fn depfile_path(p: &Path) -> anyhow::Result<String> {
    let s = p.to_str().ok_or_else(|| anyhow!("{}: the path is not UTF-8", p.display()))?;
    if s.contains(['\n', '\r']) {
        return Err(anyhow!("{s:?}: a path with a line break cannot go into a depfile"));
    }
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            ' ' => out.push_str("\\ "),
            '#' => out.push_str("\\#"),
            '$' => out.push_str("$$"),
            c => out.push(c),
        }
    }
    Ok(out)
}

/// The depfile text: `OUTPUT: INPUT…`, one input per continued line, each file once, in the
/// order the bake read them (the glTF, its buffers, its images), then the config file.
pub fn depfile_text(output: &Path, imported: &ImportedMesh, config: Option<&Path>) -> anyhow::Result<String> {
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
    let mut text = format!("{}:", depfile_path(output)?);
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

    #[test]
    fn depfile_paths_escape_what_make_and_ninja_treat_specially() {
        assert_eq!(depfile_path(Path::new("a b/c#d$e.png")).unwrap(), "a\\ b/c\\#d$$e.png");
        assert!(depfile_path(Path::new("bad\nname")).is_err());
    }
}
