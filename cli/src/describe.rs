//! `furbake inspect` and `furbake verify`: decode every section of a file with its typed decoder,
//! describe it (human table or stable JSON), and check cross-section consistency.
//!
//! JSON layout (stable; documented in the README):
//! `{ "file", "format_version", "file_size", "sections": [ { "index", "kind", "version",
//! "offset", "size", "crc32", ...the section's own named fields } ], "statistics": {...} }`.
//! A section's own field that would collide with a generic one is prefixed with the kind name
//! (e.g. a topology's `kind` becomes `spring_topology_kind`).

use std::path::Path;

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
use furbake_formats::{Pack, PackSections, Section, SectionKind};
use serde_json::{Map, Value, json};

use crate::args::{InspectArgs, VerifyArgs};
use crate::failure::{Classify, Failure};

/// Every section of a pack, decoded.
#[derive(Default)]
pub struct Decoded {
    pub manifest: Option<BakeManifest>,
    pub mesh: Option<SkinMesh>,
    pub shells: Option<ShellAtlas>,
    pub fins: Option<FinAtlas>,
    pub uv_map: Option<TriangleUvMap>,
    pub fin_edges: Option<FinEdges>,
    pub blade_fields: Vec<BladeField>,
    pub keyframe_tables: Vec<KeyframeTable>,
    pub topologies: Vec<SpringTopology>,
    pub skeleton: Option<Skeleton>,
    pub skin_weights: Option<SkinWeights>,
    pub morph_targets: Option<MorphTargets>,
    pub clips: Option<AnimationClips>,
    /// One summary per section, in table order (`None` for unknown kinds).
    pub summaries: Vec<Option<Value>>,
}

/// Decodes every known section of `pack` (unknown kinds are listed, not decoded).
pub fn decode_all(pack: &Pack) -> furbake_formats::Result<Decoded> {
    let mut d = Decoded::default();
    for (i, e) in pack.sections().iter().enumerate() {
        let summary = match e.kind {
            SectionKind::BAKE_MANIFEST => keep(&mut d.manifest, pack.decode(i)?),
            SectionKind::SKIN_MESH => keep(&mut d.mesh, pack.decode(i)?),
            SectionKind::SHELL_ATLAS => keep(&mut d.shells, pack.decode(i)?),
            SectionKind::FIN_ATLAS => keep(&mut d.fins, pack.decode(i)?),
            SectionKind::TRIANGLE_UV_MAP => keep(&mut d.uv_map, pack.decode(i)?),
            SectionKind::FIN_EDGES => keep(&mut d.fin_edges, pack.decode(i)?),
            SectionKind::BLADE_FIELD => push(&mut d.blade_fields, pack.decode(i)?),
            SectionKind::KEYFRAME_TABLE => push(&mut d.keyframe_tables, pack.decode(i)?),
            SectionKind::SPRING_TOPOLOGY => push(&mut d.topologies, pack.decode(i)?),
            SectionKind::SKELETON => keep(&mut d.skeleton, pack.decode(i)?),
            SectionKind::SKIN_WEIGHTS => keep(&mut d.skin_weights, pack.decode(i)?),
            SectionKind::MORPH_TARGETS => keep(&mut d.morph_targets, pack.decode(i)?),
            SectionKind::ANIMATION_CLIPS => keep(&mut d.clips, pack.decode(i)?),
            _ => None,
        };
        d.summaries.push(summary);
    }
    Ok(d)
}

fn keep<S: Section>(slot: &mut Option<S>, value: S) -> Option<Value> {
    let s = value.summary();
    if slot.is_none() {
        *slot = Some(value);
    }
    Some(s)
}

fn push<S: Section>(list: &mut Vec<S>, value: S) -> Option<Value> {
    let s = value.summary();
    list.push(value);
    Some(s)
}

/// Cross-section checks (`furbake_formats::check_consistency`, the one place they live): every
/// artifact agrees with the skin mesh it was baked from, a blade field has its keyframe table,
/// skin weights, morph targets and clips agree with the skeleton and the skin.
/// Returns the number of checks made.
pub fn check_consistency(pack: &Pack, d: &Decoded) -> furbake_formats::Result<usize> {
    let topologies: Vec<&SpringTopology> = d.topologies.iter().collect();
    let blade_fields: Vec<&BladeField> = d.blade_fields.iter().collect();
    let keyframe_tables: Vec<&KeyframeTable> = d.keyframe_tables.iter().collect();
    let sections = PackSections {
        mesh: d.mesh.as_ref(),
        shells: d.shells.as_ref(),
        fins: d.fins.as_ref(),
        uv_map: d.uv_map.as_ref(),
        fin_edges: d.fin_edges.as_ref(),
        topologies: &topologies,
        blade_fields: &blade_fields,
        keyframe_tables: &keyframe_tables,
        skeleton: d.skeleton.as_ref(),
        skin_weights: d.skin_weights.as_ref(),
        morph_targets: d.morph_targets.as_ref(),
        clips: d.clips.as_ref(),
    };
    furbake_formats::check_consistency(pack.sections(), &sections)
}

/// Reads, validates and decodes `path`.
pub fn load(path: &Path) -> Result<(Pack, Decoded), Failure> {
    let pack = Pack::read(path).input()?;
    let decoded = decode_all(&pack).map_err(|e| e.with_path(path)).input()?;
    check_consistency(&pack, &decoded).map_err(|e| e.with_path(path)).input()?;
    Ok((pack, decoded))
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
            let items: Vec<String> =
                a.iter().map(|x| x.as_f64().map_or(x.to_string(), |f| format!("{f:.3}"))).collect();
            format!("[{}]", items.join(" "))
        }
        Value::Number(n) if n.is_f64() => format!("{:.6}", n.as_f64().unwrap_or(0.0)),
        other => other.to_string(),
    }
}

/// Runs `furbake verify`.
pub fn run_verify(args: VerifyArgs, quiet: bool) -> Result<(), Failure> {
    let (pack, decoded) = load(&args.file)?;
    let checks = check_consistency(&pack, &decoded).map_err(|e| e.with_path(&args.file)).input()?;
    if !quiet {
        crate::stdout::line(format_args!(
            "{}: ok ({} sections decoded and checksummed, {checks} cross-section checks)",
            args.file.display(),
            pack.sections().len()
        ))?;
    }
    Ok(())
}
