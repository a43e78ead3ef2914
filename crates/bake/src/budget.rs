//! The memory a bake plan will take, estimated before any stage runs (a memory budget decided
//! before work: docs/design.md "Memory budget"). [`estimate_bake_memory`] reads the validated
//! settings and the imported mesh — nothing is baked — and models what [`crate::bake`] and the pack
//! write hold at each moment:
//!
//! - every stage keeps the input and the outputs of the stages before it, plus its own output and
//!   scratch: the hairs while the volume is sliced, the edge table of the fin-edge search, the
//!   scatter lists of the blade field, the simulated poses of the keyframe table, the normals and
//!   edge set of a topology build;
//! - the write holds every output three times (the typed sections, their encoded payloads, and the
//!   file image assembled before the atomic write) and the mesh four times (the import, the
//!   pack's copy, payload and image).
//!
//! The estimate is the largest of those moments, returned as a breakdown ([`MemoryEstimate`]) whose
//! parts name the setting that drives them, so a refusal can say what to lower. Sizes are the
//! element sizes of the stage code (a blade is 40 bytes, a mass 17, a spring 20; see each part)
//! times the counts the stages will produce: blades are the furry area × density, topology counts
//! follow the topology builder's formulas (`chain`: L·V masses, `prisms`: 2V masses and V+E
//! springs, separable kinds 6F masses, with V, E, F the furry vertices, edges and triangles).
//!
//! What it leaves out: the program itself (code, libraries, thread stacks) and the import, which
//! has run when the estimate is made — together about 5–30 MiB on the usual inputs. Measured
//! against the peak resident size of real bakes of 100 MiB to 1 GiB, the estimate falls within
//! 0.8–1.2 of it (docs/design.md "Memory budget").

use std::fmt::Write as _;

use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::DisplacementEncoding;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::spring_topology::TopologyKind;
use furbake_grass::KeyframeSettings;
use furbake_import::{ImportedAnimation, ImportedMesh};

use crate::settings::BakeSettings;
use crate::validate::furry_area_and_xz_bounds;

/// Bytes of one hair of the volume stage (`HairSet`: root x and y, length, bend and radius as
/// `f32`, direction and coat as `u8`).
pub const BYTES_PER_HAIR: u64 = 5 * 4 + 2;
/// Bytes of one blade in the blade field (position, yaw, height, cluster, four weights).
pub const BYTES_PER_BLADE: u64 = BladeField::BYTES_PER_BLADE as u64;
/// Bytes of one mass of a spring topology (rest position, mass, anchored flag).
pub const BYTES_PER_MASS: u64 = 12 + 4 + 1;
/// Bytes of one spring (two ends, rest length, stiffness, damping).
pub const BYTES_PER_SPRING: u64 = 8 + 3 * 4;
/// Bytes of one stick (two ends, length).
pub const BYTES_PER_STICK: u64 = 8 + 4;
/// Bytes of one shell vertex's (root, tip) mass pair.
pub const BYTES_PER_SHELL_VERTEX: u64 = 8;

/// One part of a plan's memory at the moment of its peak.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryPart {
    /// What it is (`"hair volume and shell atlas"`).
    pub name: &'static str,
    /// The setting that drives it, as `inspect` shows it under the manifest's `settings`
    /// (`volume.resolution`); `None` when the input mesh alone decides its size.
    pub key: Option<String>,
    /// The setting's value and what it combines with (`128 with volume.layers = 16`), or the
    /// mesh's size for a part without a key.
    pub value: String,
    /// Bytes held at the peak.
    pub bytes: u64,
}

/// The estimated peak memory of a bake plan, part by part (see the module documentation).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    /// When the peak happens (`"writing the pack"`, or a stage's name).
    pub peak_at: &'static str,
    /// Every part held then, largest first (parts of zero bytes left out).
    pub parts: Vec<MemoryPart>,
}

impl MemoryEstimate {
    /// The whole estimate, bytes.
    pub fn total_bytes(&self) -> u64 {
        self.parts.iter().map(|p| p.bytes).sum()
    }

    /// The largest part (the first: parts are sorted).
    pub fn largest(&self) -> Option<&MemoryPart> {
        self.parts.first()
    }

    /// The largest part that a setting drives (the one to lower), if any.
    pub fn largest_setting(&self) -> Option<&MemoryPart> {
        self.parts.iter().find(|p| p.key.is_some())
    }
}

/// Counts of the imported mesh that the stages' sizes depend on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct MeshCounts {
    vertices: u64,
    triangles: u64,
    /// Furry triangles (F of the topology formulas).
    furry_triangles: u64,
    /// Vertices of furry triangles (V).
    furry_vertices: u64,
    /// Distinct edges of furry triangles, degenerate ones left out (E).
    furry_edges: u64,
    /// Edges used by exactly one furry triangle: the fin edges.
    fin_edges: u64,
    /// Furry surface, m².
    furry_area_m2: f64,
}

impl MeshCounts {
    /// One pass over the mesh; the edge counts sort one `u64` per furry corner (24 bytes per
    /// furry triangle, freed before returning).
    fn of(mesh: &SkinMesh) -> MeshCounts {
        let furry = |t: usize| mesh.fur_mask.get(t).is_some_and(|&m| m != 0);
        let mut has_fur = vec![false; mesh.positions.len()];
        let mut keys = Vec::with_capacity(3 * mesh.furry_triangles());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if !furry(t) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if let Some(f) = has_fur.get_mut(a as usize) {
                    *f = true;
                }
                keys.push((u64::from(a.min(b)) << 32) | u64::from(a.max(b)));
            }
        }
        keys.sort_unstable();
        let (mut furry_edges, mut fin_edges) = (0, 0);
        for run in keys.chunk_by(|a, b| a == b) {
            let (a, b) = (run[0] >> 32, run[0] & 0xFFFF_FFFF);
            furry_edges += u64::from(a != b);
            fin_edges += u64::from(run.len() == 1);
        }
        MeshCounts {
            vertices: mesh.positions.len() as u64,
            triangles: mesh.triangles.len() as u64,
            furry_triangles: (keys.len() / 3) as u64,
            furry_vertices: has_fur.iter().filter(|&&f| f).count() as u64,
            furry_edges,
            fin_edges,
            furry_area_m2: furry_area_and_xz_bounds(mesh).0,
        }
    }
}

/// Bytes of the skin mesh's arrays: per vertex position, normal, colour (40); per triangle
/// indices and fur mask (13), plus the per-corner texture coordinates when present.
fn mesh_bytes(mesh: &SkinMesh) -> u64 {
    mesh.positions.len() as u64 * 40 + mesh.triangles.len() as u64 * 13 + mesh.corner_texcoords.len() as u64 * 24
}

/// Bytes of the skeleton, skin weights, morph targets and clips.
fn animation_bytes(a: &ImportedAnimation) -> u64 {
    let strings = |names: &[String]| names.iter().map(|n| n.len() as u64 + 24).sum::<u64>();
    let mut bytes = 0;
    if let Some(s) = &a.skeleton {
        bytes += strings(&s.names) + s.parents.len() as u64 * (4 + 12 + 16 + 12) + s.bind_joints.len() as u64 * 68;
    }
    if let Some(w) = &a.skin_weights {
        bytes += w.binds.len() as u64 * 2 + w.weights.len() as u64 * 4;
    }
    if let Some(m) = &a.morph_targets {
        bytes += (m.position_deltas.len() + m.normal_deltas.len()) as u64 * 12
            + m.default_weights.len() as u64 * 4
            + strings(&m.names)
            + m.groups.iter().map(|g| g.name.len() as u64 + 32).sum::<u64>();
    }
    if let Some(c) = &a.clips {
        for clip in &c.clips {
            bytes += clip.name.len() as u64 + 48;
            bytes += clip.channels.iter().map(|ch| (ch.times_s.len() + ch.values.len()) as u64 * 4 + 64).sum::<u64>();
        }
    }
    bytes
}

/// Masses, springs, sticks and shell vertices of a topology of `kind` on `m`, as the topology
/// builder makes them (chains of `chain_len` masses for the chain kinds, 2 otherwise).
fn topology_counts(kind: TopologyKind, chain_len: u64, m: &MeshCounts) -> (u64, u64, u64, u64) {
    let (v, e, f) = (m.furry_vertices, m.furry_edges, m.furry_triangles);
    match kind {
        TopologyKind::CHAIN | TopologyKind::REDUCED_CHAIN => {
            (chain_len * v, chain_len.saturating_sub(1) * v, 0, m.vertices)
        }
        TopologyKind::STICKS => (2 * v, 0, v, m.vertices),
        TopologyKind::SPRING_STICKS => (2 * v, v, 0, m.vertices),
        TopologyKind::PRISMS => (2 * v, v + e, 0, m.vertices),
        TopologyKind::SEPARABLE_STICKS => (6 * f, 0, 3 * f, 3 * m.triangles),
        TopologyKind::SEPARABLE_SPRING_STICKS => (6 * f, 3 * f, 0, 3 * m.triangles),
        _ => (6 * f, 6 * f, 0, 3 * m.triangles),
    }
}

/// Bytes per stored displacement component of `encoding`.
fn component_bytes(encoding: DisplacementEncoding) -> u64 {
    match encoding {
        DisplacementEncoding::F32 => 4,
        DisplacementEncoding::Snorm16 | DisplacementEncoding::F16 => 2,
        DisplacementEncoding::Unorm8 | DisplacementEncoding::Snorm8 => 1,
    }
}

/// The keyframe table's bytes and its stage's scratch: every represented pose's centre-line node
/// displacements (`Vec3`, twice while the columns are gathered), the stored vectors unquantised,
/// quantised and decoded again to measure the error.
fn keyframe_bytes(k: &KeyframeSettings) -> (u64, u64) {
    let poses = u64::from(k.grid.poses);
    let segments = u64::from(k.shape.segments);
    let nodes = poses * (segments + 1) * 12;
    let unit = if k.stages.rigid_segment_pairs { 2 } else { 1 };
    let stored = poses / u64::from(k.symmetry.factor()) * (4 * segments / unit) * 3;
    let table = stored * component_bytes(k.encoding) + segments * (4 * (12 + 8 + 4) + 2 * 12);
    let scratch = (2 * nodes).max(nodes + 3 * stored * 4);
    (table, scratch)
}

/// Which of two settings that multiply into one size to blame: the one furthest above its
/// preset's value (`ratio_a` and `ratio_b` are value / preset value, already squared for a
/// side length).
fn blame<'a>(a: &'a str, ratio_a: f64, b: &'a str, ratio_b: f64) -> &'a str {
    if ratio_b > ratio_a { b } else { a }
}

/// A part of the plan, and what it holds at each moment.
struct Part {
    name: &'static str,
    key: Option<String>,
    value: String,
    /// Bytes once built (held to the end).
    resident: u64,
    /// Scratch bytes while its stage runs.
    scratch: u64,
    /// Copies held while the pack is written (3: typed, payload, file image).
    copies_at_write: u64,
}

/// Estimates the peak bytes [`crate::bake`] and the pack write will hold for `settings` on
/// `input` (see the module documentation). Expects settings that passed
/// [`BakeSettings::plan`](crate::BakeSettings::plan) and [`crate::validate::check_against_mesh`] (their
/// counts are then bounded); nothing is allocated beyond one `u64` per furry triangle corner.
///
/// ```
/// use furbake_bake::{BakeSettings, budget::estimate_bake_memory};
/// use furbake_import::{import_gltf_slice, testmesh};
///
/// let gltf = testmesh::uv_sphere(8, 12, 1.0).gltf;
/// let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &Default::default())?;
/// let mut settings = BakeSettings::preset("fur")?;
/// let small = estimate_bake_memory(&settings, &imported).total_bytes();
/// settings.volume.resolution = 1024;
/// let large = estimate_bake_memory(&settings, &imported);
/// assert!(large.total_bytes() > 32 * small);
/// assert_eq!(large.largest_setting().unwrap().key.as_deref(), Some("volume.resolution"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn estimate_bake_memory(settings: &BakeSettings, input: &ImportedMesh) -> MemoryEstimate {
    let mesh = &input.mesh;
    let m = MeshCounts::of(mesh);
    let preset = BakeSettings::preset(&settings.preset).unwrap_or_else(|_| settings.clone());
    let shape = format!("{} vertices, {} triangles", m.vertices, m.triangles);
    let mut parts = Vec::new();

    // The input stays loaded; the pack gets a copy of the mesh and animation, both encoded.
    parts.push(Part {
        name: "input mesh",
        key: None,
        value: shape.clone(),
        resident: mesh_bytes(mesh) + animation_bytes(&input.animation),
        scratch: 0,
        copies_at_write: 4,
    });

    // Volume: the hairs live while the shells and fins are sliced.
    let v = &settings.volume;
    let texels = u64::from(v.resolution).pow(2);
    let densities = v.coat.density as f64 + v.undercoat.as_ref().map_or(0.0, |u| u.density as f64);
    let hairs = (texels as f64 * densities).ceil() as u64;
    let res_ratio = (f64::from(v.resolution) / f64::from(preset.volume.resolution.max(1))).powi(2);
    let layer_ratio = f64::from(v.layers) / f64::from(preset.volume.layers.max(1));
    let (key, value) = match blame("volume.resolution", res_ratio, "volume.layers", layer_ratio) {
        "volume.layers" => ("volume.layers", format!("{} with volume.resolution = {}", v.layers, v.resolution)),
        _ => ("volume.resolution", format!("{} with volume.layers = {}", v.resolution, v.layers)),
    };
    parts.push(Part {
        name: "hair volume and shell atlas",
        key: Some(key.into()),
        value,
        resident: u64::from(v.layers) * (texels + 8),
        scratch: hairs * BYTES_PER_HAIR,
        copies_at_write: 3,
    });
    parts.push(Part {
        name: "fin atlas",
        key: Some("volume.fin_height".into()),
        value: format!("{} with volume.resolution = {}", v.fin_height, v.resolution),
        resident: u64::from(v.resolution) * u64::from(v.fin_height),
        scratch: 0,
        copies_at_write: 3,
    });

    // UV map and fin edges: the mesh alone decides (the search keeps a hash map of edges, about
    // 40 bytes per triangle).
    parts.push(Part {
        name: "per-triangle UV map",
        key: None,
        value: shape.clone(),
        resident: m.triangles * 24,
        scratch: 0,
        copies_at_write: 3,
    });
    parts.push(Part {
        name: "fin edges",
        key: None,
        value: shape.clone(),
        resident: m.fin_edges * 13,
        scratch: m.triangles * 40,
        copies_at_write: 3,
    });

    if let Some(b) = &settings.blades {
        // Scatter: the furry triangles (48 bytes each, with a list header of 24), then every
        // blade as a 40-byte tuple beside the 40-byte output while the arrays are split out.
        let blades = (m.furry_area_m2 * b.field.density_per_m2 as f64).ceil() as u64;
        parts.push(Part {
            name: "grass blade field",
            key: Some("blades.field.density_per_m2".into()),
            value: format!(
                "{} on {:.3} m² of furry surface ({blades} blades)",
                b.field.density_per_m2, m.furry_area_m2
            ),
            resident: blades * BYTES_PER_BLADE + 64,
            scratch: blades * 40 + m.furry_triangles * 72,
            copies_at_write: 3,
        });
        let k = &b.keyframes;
        let (table, scratch) = keyframe_bytes(k);
        let pose_ratio = f64::from(k.grid.poses) / 1000.0;
        let segment_ratio = f64::from(k.shape.segments) / 8.0;
        let key = blame("blades.keyframes.grid.poses", pose_ratio, "blades.keyframes.shape.segments", segment_ratio);
        let value = if key.ends_with("poses") {
            format!("{} with blades.keyframes.shape.segments = {}", k.grid.poses, k.shape.segments)
        } else {
            format!("{} with blades.keyframes.grid.poses = {}", k.shape.segments, k.grid.poses)
        };
        parts.push(Part {
            name: "keyframe table",
            key: Some(key.into()),
            value,
            resident: table,
            scratch,
            copies_at_write: 3,
        });
    }

    for name in &settings.topologies {
        let Some(kind) = TopologyKind::from_name(name) else { continue };
        let (key, chain_len) = match kind {
            TopologyKind::CHAIN => ("volume.layers".to_owned(), u64::from(v.layers)),
            TopologyKind::REDUCED_CHAIN => {
                ("topology.reduced_chain_masses".to_owned(), u64::from(settings.topology.reduced_chain_masses))
            }
            _ => ("topologies".to_owned(), 2),
        };
        let (masses, springs, sticks, shell) = topology_counts(kind, chain_len, &m);
        let mut value = String::new();
        if key != "topologies" {
            let _ = write!(value, "{chain_len} with topology {name}, ");
        } else {
            let _ = write!(value, "[.., \"{name}\", ..]: ");
        }
        let _ = write!(value, "{masses} masses, {springs} springs, {sticks} sticks");
        // Scratch: unit normals and their face sums (24 bytes per vertex), the furry-vertex
        // flags, and for prisms the sorted edge set (about 22 bytes per edge).
        let edges = if kind == TopologyKind::PRISMS { m.furry_edges * 22 } else { 0 };
        parts.push(Part {
            name: "spring topology",
            key: Some(key),
            value,
            resident: masses * BYTES_PER_MASS
                + springs * BYTES_PER_SPRING
                + sticks * BYTES_PER_STICK
                + shell * BYTES_PER_SHELL_VERTEX,
            scratch: m.vertices * 25 + edges,
            copies_at_write: 3,
        });
    }

    peak(parts)
}

/// The moment holding the most: each stage (its part's scratch on top of everything built so
/// far), then the write.
fn peak(parts: Vec<Part>) -> MemoryEstimate {
    let mut best: (&'static str, Vec<u64>) = ("", Vec::new());
    let mut consider = |at: &'static str, bytes: Vec<u64>| {
        if bytes.iter().sum::<u64>() > best.1.iter().sum::<u64>() {
            best = (at, bytes);
        }
    };
    for stage in 1..parts.len() {
        let bytes = parts
            .iter()
            .enumerate()
            .map(|(i, p)| match i.cmp(&stage) {
                std::cmp::Ordering::Less => p.resident,
                std::cmp::Ordering::Equal => p.resident + p.scratch,
                std::cmp::Ordering::Greater => 0,
            })
            .collect();
        consider(parts[stage].name, bytes);
    }
    consider("writing the pack", parts.iter().map(|p| p.resident * p.copies_at_write).collect());
    let (peak_at, bytes) = best;
    let mut out: Vec<MemoryPart> = parts
        .into_iter()
        .zip(bytes)
        .filter(|(_, b)| *b > 0)
        .map(|(p, bytes)| MemoryPart { name: p.name, key: p.key, value: p.value, bytes })
        .collect();
    out.sort_by_key(|p| std::cmp::Reverse(p.bytes));
    MemoryEstimate { peak_at, parts: out }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::settings::dotted_override;

    fn sphere() -> ImportedMesh {
        furbake_import::import_gltf_slice(
            &furbake_import::testmesh::uv_sphere(16, 24, 1.0).gltf,
            "sphere.gltf",
            None,
            &Default::default(),
        )
        .unwrap()
    }

    fn with(sets: &[&str]) -> BakeSettings {
        let mut s = BakeSettings::preset("fur").unwrap();
        for set in sets {
            s = s.with_overrides(&dotted_override(set).unwrap()).unwrap();
        }
        s.plan().unwrap().into_settings()
    }

    #[test]
    fn the_estimate_grows_with_resolution_layers_and_blades() {
        let input = sphere();
        let base = estimate_bake_memory(&with(&[]), &input).total_bytes();
        let mut checked = 0;
        for (sets, key) in [
            (&["volume.resolution=1024"][..], "volume.resolution"),
            (&["volume.layers=512"][..], "volume.layers"),
            (&["blades.field.density_per_m2=1000000"][..], "blades.field.density_per_m2"),
            (
                &["blades.keyframes.grid.poses=1048576", "blades.keyframes.shape.segments=64"][..],
                "blades.keyframes.grid.poses",
            ),
            (&["blades.keyframes.shape.segments=256"][..], "blades.keyframes.shape.segments"),
        ] {
            let e = estimate_bake_memory(&with(sets), &input);
            assert!(e.total_bytes() > 8 * base, "{sets:?}: {} vs {base}", e.total_bytes());
            assert_eq!(e.largest().and_then(|p| p.key.as_deref()), Some(key), "{sets:?}: {e:?}");
            checked += 1;
        }
        assert_eq!(checked, 5);
        // Monotonic in the blade density.
        let blades =
            |d: u32| estimate_bake_memory(&with(&[&format!("blades.field.density_per_m2={d}")]), &input).total_bytes();
        assert!(blades(1000) < blades(10_000) && blades(10_000) < blades(100_000));
    }

    #[test]
    fn topology_counts_follow_the_builder() {
        let input = sphere();
        let m = MeshCounts::of(&input.mesh);
        let mut checked = 0;
        for name in crate::settings::topology_names() {
            let kind = TopologyKind::from_name(name).unwrap();
            let params =
                furbake_formats::sections::spring_topology::TopologyParams { chain_layers: 16, ..Default::default() };
            let built = furbake_sim::build_topology(&input.mesh, kind, &params).unwrap();
            let chain = match kind {
                TopologyKind::CHAIN => 16,
                TopologyKind::REDUCED_CHAIN => u64::from(params.reduced_chain_masses),
                _ => 2,
            };
            let counts = topology_counts(kind, chain, &m);
            let real = (
                built.mass_kg.len() as u64,
                built.spring_ends.len() as u64,
                built.stick_ends.len() as u64,
                built.shell_vertex_masses.len() as u64,
            );
            assert_eq!(counts, real, "{name}");
            checked += 1;
        }
        assert_eq!(checked, 8);
        let fins = crate::fin_edges::find_fin_edges(&input.mesh);
        assert_eq!(m.fin_edges, fins.vertices.len() as u64);
    }

    #[test]
    fn a_topology_part_names_its_kind_and_the_write_is_the_usual_peak() {
        let input = sphere();
        let e = estimate_bake_memory(&with(&["topologies=[\"separable-prisms\"]"]), &input);
        assert_eq!(e.peak_at, "writing the pack");
        let topo = e.parts.iter().find(|p| p.name == "spring topology").expect("a topology part");
        assert_eq!(topo.key.as_deref(), Some("topologies"));
        assert!(topo.value.contains("separable-prisms"), "{topo:?}");
        let chain = estimate_bake_memory(&with(&["topologies=[\"chain\"]", "volume.layers=1024"]), &input);
        let part = chain.parts.iter().find(|p| p.name == "spring topology").unwrap();
        assert_eq!(part.key.as_deref(), Some("volume.layers"));
    }
}
