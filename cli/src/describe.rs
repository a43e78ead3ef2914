//! `furbake inspect` and `furbake verify`: validate a file as `Pack::verify` does (every section
//! decoded with its typed decoder, every checksum, cross-section consistency) and describe it
//! (human table or stable JSON); [`open_verified`], the same validation for the commands that use
//! a pack.
//!
//! JSON layout (stable; documented in the README):
//! `{ "file", "format_version", "file_size", "sections": [ { "index", "kind", "version",
//! "offset", "size", "crc32", ...the section's own named fields } ], "statistics": {...} }`.
//! A section's own field that would collide with a generic one is prefixed with the kind name
//! (e.g. a topology's `kind` becomes `spring_topology_kind`).

use std::path::Path;
use std::sync::Arc;

use furbake_formats::sections::animation_clips::AnimationClips;
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::fin_atlas::FinAtlas;
use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::keyframe_table::KeyframeTable;
use furbake_formats::sections::manifest::BakeManifest;
use furbake_formats::sections::morph_targets::MorphTargets;
use furbake_formats::sections::shell_atlas::ShellAtlas;
use furbake_formats::sections::skeleton::Skeleton;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::skin_weights::SkinWeights;
use furbake_formats::sections::spring_topology::SpringTopology;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use furbake_formats::{DecodedSections, Pack, Section, SectionKind, VerifySummary};
use furbake_runtime::{Scene, World, WorldOptions, WorldPlan};
use serde_json::{Map, Value, json};

use crate::args::{InspectArgs, VerifyArgs};
use crate::failure::{self, Classify, Failure};

/// Every section of a pack, decoded (shared with the pack's cache), and one summary per section.
pub struct Decoded {
    /// The decoded sections (`Pack::decoded_sections`).
    pub sections: DecodedSections,
    /// One summary per section, in table order (`None` for unknown kinds).
    pub summaries: Vec<Option<Value>>,
    /// What `Pack::verify` checked.
    pub verified: VerifySummary,
}

impl std::ops::Deref for Decoded {
    type Target = DecodedSections;
    fn deref(&self) -> &DecodedSections {
        &self.sections
    }
}

/// Validates `pack` as `verify` does (`Pack::verify`: every known section decoded, every
/// checksum, `furbake_formats::check_consistency`) and describes every section from the decoded
/// sections it leaves in the pack's cache (nothing is decoded twice; unknown kinds are listed, not
/// decoded).
pub fn decode_all(pack: &Pack) -> furbake_formats::Result<Decoded> {
    let verified = pack.verify()?;
    let sections = pack.decoded_sections()?;
    let mut summaries = Vec::with_capacity(pack.sections().len());
    for (i, e) in pack.sections().iter().enumerate() {
        let summary = match e.kind {
            SectionKind::BAKE_MANIFEST => summary::<BakeManifest>(pack, i)?,
            SectionKind::SKIN_MESH => summary::<SkinMesh>(pack, i)?,
            SectionKind::SHELL_ATLAS => summary::<ShellAtlas>(pack, i)?,
            SectionKind::FIN_ATLAS => summary::<FinAtlas>(pack, i)?,
            SectionKind::TRIANGLE_UV_MAP => summary::<TriangleUvMap>(pack, i)?,
            SectionKind::FIN_EDGES => summary::<FinEdges>(pack, i)?,
            SectionKind::BLADE_FIELD => summary::<BladeField>(pack, i)?,
            SectionKind::KEYFRAME_TABLE => summary::<KeyframeTable>(pack, i)?,
            SectionKind::SPRING_TOPOLOGY => summary::<SpringTopology>(pack, i)?,
            SectionKind::SKELETON => summary::<Skeleton>(pack, i)?,
            SectionKind::SKIN_WEIGHTS => summary::<SkinWeights>(pack, i)?,
            SectionKind::MORPH_TARGETS => summary::<MorphTargets>(pack, i)?,
            SectionKind::ANIMATION_CLIPS => summary::<AnimationClips>(pack, i)?,
            _ => None,
        };
        summaries.push(summary);
    }
    Ok(Decoded { sections, summaries, verified })
}

/// The summary of section `index` (of `S`'s kind), from the pack's cache.
fn summary<S: Section + Send + Sync + 'static>(pack: &Pack, index: usize) -> furbake_formats::Result<Option<Value>> {
    let Some(n) = pack.find(S::KIND).position(|i| i == index) else { return Ok(None) };
    Ok(pack.sections_of::<S>()?.get(n).map(|s| s.summary()))
}

/// Reads and validates `path` as `verify` does, and decodes it for a description.
pub fn load(path: &Path) -> Result<(Pack, Decoded), Failure> {
    let pack = Pack::read(path).input()?;
    let decoded = decode_all(&pack).map_err(|e| e.with_path(path)).input()?;
    Ok((pack, decoded))
}

/// Opens the pack at `path` for a command that uses it (`export`, `preview`, `view`) and
/// validates it as `verify` does before anything reads it (docs/design.md "Runtime: packs"):
/// a pack `verify` rejects is bad input (exit 1), its one-line message naming the file. The
/// sections stay decoded in the pack, so the command decodes nothing again.
pub fn open_verified(path: &Path) -> Result<Pack, Failure> {
    let pack = Pack::open(path).input()?;
    pack.verify().map_err(|e| e.with_path(path)).input()?;
    Ok(pack)
}

/// The plan of a scene's world, as `simulate`, `preview` and `view` make it: every pack file
/// opened once and validated as `verify` does ([`open_scene_packs`]), then the stages and memory
/// planned by `furbake_runtime::WorldPlan`.
pub fn plan_scene(scene: Scene, scene_path: &Path, options: WorldOptions) -> Result<WorldPlan, Failure> {
    let packs = open_scene_packs(&scene, scene_path)?;
    WorldPlan::with_packs(scene, packs, options).map_err(|e| failure::runtime(e, scene_path))
}

/// The packs of the runtime scene at `scene_path`, opened once per file (`World::open_packs`) and
/// each validated as `verify` does (see [`open_verified`]) before the world reads them
/// (`simulate`, `preview`, `view`). A pack `verify` rejects is bad input (exit 1), the message
/// naming the scene and the pack.
fn open_scene_packs(scene: &Scene, scene_path: &Path) -> Result<Vec<Arc<Pack>>, Failure> {
    let packs = World::open_packs(scene).map_err(|e| failure::runtime(e, scene_path))?;
    for (i, pack) in packs.iter().enumerate() {
        if !packs[..i].iter().any(|p| Arc::ptr_eq(p, pack)) {
            pack.verify().map_err(|e| failure::runtime(e.into(), scene_path))?;
        }
    }
    Ok(packs)
}

/// The JSON description of a pack (the `inspect --json` document).
pub fn describe(path: &Path, pack: &Pack, d: &Decoded) -> Value {
    let mut sections = Vec::new();
    for (i, (e, summary)) in pack.sections().iter().zip(&d.summaries).enumerate() {
        let mut obj = Map::new();
        obj.insert("index".into(), json!(i));
        obj.insert("kind".into(), json!(e.kind.to_string()));
        obj.insert("version".into(), json!(e.version));
        obj.insert("offset".into(), json!(e.offset));
        obj.insert("size".into(), json!(e.length));
        obj.insert("crc32".into(), json!(format!("{:08x}", e.crc32)));
        if let Some(Value::Object(fields)) = summary {
            for (k, v) in fields {
                let key = if obj.contains_key(k) { format!("{}_{k}", e.kind) } else { k.clone() };
                obj.insert(key, v.clone());
            }
        }
        if e.kind == SectionKind::TRIANGLE_UV_MAP {
            if let (Some(uv), Some(shells)) = (&d.uv_map, &d.shells) {
                obj.insert("texels_per_m".into(), json!(shells.params.resolution as f32 / uv.repeat_m));
            }
        }
        sections.push(Value::Object(obj));
    }
    let mut stats = Map::new();
    if let Some(m) = &d.mesh {
        stats.insert("triangles".into(), json!(m.triangles.len()));
        stats.insert("furry_triangles".into(), json!(m.furry_triangles()));
        stats.insert("vertices".into(), json!(m.positions.len()));
        stats.insert("degenerate_triangles_skipped".into(), json!(m.stats.degenerate_triangles_skipped));
    }
    if let (Some(uv), Some(s)) = (&d.uv_map, &d.shells) {
        stats.insert("texels_per_m".into(), json!(s.params.resolution as f32 / uv.repeat_m));
    }
    if let Some(s) = &d.shells {
        stats.insert("hair_coverage_per_layer".into(), json!(s.coverage));
        stats.insert("fur_length_m".into(), json!(s.fur_length_m));
    }
    if let Some(f) = &d.fin_edges {
        stats.insert("fin_edges".into(), json!(f.vertices.len()));
    }
    if let Some(s) = &d.skeleton {
        stats.insert("joints".into(), json!(s.joint_count()));
    }
    if let Some(w) = &d.skin_weights {
        stats.insert("renormalised_weight_vertices".into(), json!(w.stats.renormalised_vertices));
    }
    if let Some(m) = &d.morph_targets {
        stats.insert("morph_targets".into(), json!(m.target_count()));
    }
    if let Some(c) = &d.clips {
        stats.insert("clips".into(), json!(c.clips.len()));
    }
    let of_kind = |kind: SectionKind| -> Vec<Value> {
        pack.sections()
            .iter()
            .zip(&d.summaries)
            .filter(|(e, _)| e.kind == kind)
            .filter_map(|(_, s)| s.clone())
            .collect()
    };
    let mut doc = json!({
        "file": path.display().to_string(),
        "format_version": format!("{}.{}", furbake_formats::VERSION_MAJOR, pack.minor_version()),
        "file_size": pack.file_size(),
        "sections": sections,
        "statistics": stats,
        "topologies": of_kind(SectionKind::SPRING_TOPOLOGY),
        "keyframe_tables": of_kind(SectionKind::KEYFRAME_TABLE),
        "blade_fields": of_kind(SectionKind::BLADE_FIELD),
    });
    // Clips and joints at the top level too, like topologies (fields are only ever added).
    if let Some(c) = &d.clips {
        doc["clips"] = c.summary()["clips"].clone();
    }
    if let Some(s) = &d.skeleton {
        doc["joints"] = json!(
            s.names
                .iter()
                .zip(&s.parents)
                .map(|(n, &p)| json!({
                    "name": n,
                    "parent": (p != Skeleton::NO_PARENT).then_some(p),
                }))
                .collect::<Vec<_>>()
        );
    }
    tidy_f32(&mut doc);
    doc
}

/// Rewrites numbers that are exactly an `f32` with the shortest decimal of that `f32`, so a
/// stored 0.2f32 prints as 0.2 rather than 0.20000000298023224.
fn tidy_f32(v: &mut Value) {
    match v {
        Value::Number(n) if n.is_f64() => {
            let f = n.as_f64().unwrap_or(0.0);
            let g = f as f32;
            if g as f64 == f {
                if let Some(m) = g.to_string().parse::<f64>().ok().and_then(serde_json::Number::from_f64) {
                    *n = m;
                }
            }
        }
        Value::Array(a) => a.iter_mut().for_each(tidy_f32),
        Value::Object(o) => o.values_mut().for_each(tidy_f32),
        _ => {}
    }
}

/// Runs `furbake inspect`.
pub fn run_inspect(args: InspectArgs) -> Result<(), Failure> {
    let (pack, decoded) = load(&args.file)?;
    let doc = describe(&args.file, &pack, &decoded);
    let text = if args.json {
        serde_json::to_string_pretty(&doc).expect("JSON values always serialise") + "\n"
    } else {
        table(&doc)
    };
    crate::stdout::write(&text)
}

/// The `inspect` table, one line per row.
fn table(doc: &Value) -> String {
    use std::fmt::Write;
    // Writing into a `String` cannot fail; the results are ignored for that reason.
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}  (furbake format {}, {} bytes)",
        doc["file"].as_str().unwrap_or(""),
        doc["format_version"].as_str().unwrap_or(""),
        doc["file_size"]
    );
    let _ = writeln!(out);
    let _ = writeln!(out, "{:>3}  {:<16} {:>3} {:>10} {:>10}  crc32", "#", "kind", "ver", "offset", "size");
    let empty = Vec::new();
    let sections = doc["sections"].as_array().unwrap_or(&empty);
    for s in sections {
        let _ = writeln!(
            out,
            "{:>3}  {:<16} {:>3} {:>10} {:>10}  {}",
            s["index"].as_u64().unwrap_or(0),
            s["kind"].as_str().unwrap_or("?"),
            s["version"].as_u64().unwrap_or(0),
            s["offset"].as_u64().unwrap_or(0),
            s["size"].as_u64().unwrap_or(0),
            s["crc32"].as_str().unwrap_or("")
        );
    }
    for s in sections {
        let _ = writeln!(out);
        let _ = writeln!(out, "[{}] {}", s["index"], s["kind"].as_str().unwrap_or("?"));
        if let Value::Object(fields) = s {
            for (k, v) in fields {
                if matches!(k.as_str(), "index" | "kind" | "version" | "offset" | "size" | "crc32") {
                    continue;
                }
                let _ = writeln!(out, "  {k:<30} {}", compact(v));
            }
        }
    }
    let _ = writeln!(out);
    let _ = writeln!(out, "statistics");
    if let Value::Object(fields) = &doc["statistics"] {
        for (k, v) in fields {
            let _ = writeln!(out, "  {k:<30} {}", compact(v));
        }
    }
    out
}

fn compact(v: &Value) -> String {
    match v {
        Value::Array(a) if a.iter().all(|x| x.is_number()) => {
            let items: Vec<String> = a
                .iter()
                .map(|x| if x.is_f64() { format!("{:.3}", x.as_f64().unwrap_or(0.0)) } else { x.to_string() })
                .collect();
            format!("[{}]", items.join(" "))
        }
        Value::Number(n) if n.is_f64() => format!("{:.6}", n.as_f64().unwrap_or(0.0)),
        other => other.to_string(),
    }
}

/// Runs `furbake verify`.
pub fn run_verify(args: VerifyArgs, quiet: bool) -> Result<(), Failure> {
    let (_, decoded) = load(&args.file)?;
    if !quiet {
        let v = decoded.verified;
        crate::stdout::line(format_args!(
            "{}: ok ({} sections decoded and checksummed, {} cross-section checks)",
            args.file.display(),
            v.sections,
            v.checks
        ))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use furbake_bake::{BakeSettings, NoProgress, bake, settings::dotted_override};
    use furbake_import::{ImportSettings, import_gltf};
    use furbake_runtime::{Scene, StageKind};

    use crate::{preview_cmd, simulate_cmd};

    /// Bakes `gltf` (under the repository root) with `preset` and `sets` into `dir/name`.
    fn bake_into(dir: &Path, gltf: &str, preset: &str, sets: &[&str], name: &str) {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let mesh = import_gltf(&root.join(gltf), &ImportSettings::default()).unwrap();
        let mut settings = BakeSettings::preset(preset).unwrap();
        for set in sets {
            settings = settings.with_overrides(&dotted_override(set).unwrap()).unwrap();
        }
        let baked = bake(&mesh, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
        baked.to_writer().write_atomic(&dir.join(name)).unwrap();
    }

    /// `simulate`, `preview` and `view` plan `make demo`'s scene alike: the same stages, the same
    /// memory estimate per entry and in all, each pack file opened once and shared by its entries.
    /// (`view` opens a scene through `preview_cmd::open_scene_world`, which plans with
    /// `preview_cmd::plan_scene_world`.)
    #[test]
    fn simulate_preview_and_view_plan_the_demo_scene_alike() {
        let dir = tempfile::tempdir().unwrap();
        let small = ["volume.resolution=16", "volume.layers=4", "topologies=[\"prisms\"]"];
        bake_into(dir.path(), "fixtures/real/Fox.glb", "fur", &small, "fox.fbk");
        let grass = [&small[..], &["blades.field.density_per_m2=400"]].concat();
        bake_into(dir.path(), "fixtures/generated/grass_patch.gltf", "grass", &grass, "grass-patch.fbk");
        let scene_path = dir.path().join("fox_and_grass.toml");
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        std::fs::copy(root.join("fixtures/scenes/demo_fox_and_grass.toml"), &scene_path).unwrap();

        let shown = preview_cmd::plan_scene_world(&scene_path).unwrap();
        let kinds: Vec<StageKind> = shown.stages().iter().map(|s| s.kind).collect();
        for kind in [StageKind::Animation, StageKind::FurSolver] {
            assert!(kinds.contains(&kind), "the demo scene animates the Fox and simulates its fur: {kinds:?}");
        }
        let files = |plan: &furbake_runtime::WorldPlan| {
            let mut distinct: Vec<*const furbake_runtime::Pack> =
                plan.packs().iter().map(|p| &**p as *const _).collect();
            distinct.sort();
            distinct.dedup();
            (plan.packs().len(), distinct.len())
        };
        let scene = Scene::load(&scene_path).unwrap();
        assert_eq!(files(&shown), (scene.packs().len(), 2), "two pack files, each opened once");
        for report in [false, true] {
            let simulated = simulate_cmd::plan_world(scene.clone(), &scene_path, report).unwrap();
            assert_eq!(simulated.scene(), shown.scene());
            assert_eq!(simulated.stages(), shown.stages(), "report {report}");
            assert_eq!(simulated.memory(), shown.memory(), "report {report}");
            assert_eq!(simulated.estimated_bytes(), shown.estimated_bytes());
            assert_eq!(simulated.largest_payload(), shown.largest_payload());
            assert_eq!(files(&simulated), files(&shown));
        }
    }
}
