//! Cross-section consistency: the sections of one pack agree with one another — every artifact
//! with the skin mesh it was baked from (UV map, fin edges, spring topologies: fur thesis §3.2,
//! §3.4.1), the fin atlas with the shells, and a blade field with the keyframe table that poses
//! its blades (grass thesis §3.2–3.3), and the animation sections with the skin and one another
//! (glTF 2.0 specification, "Skins", "Morph Targets", "Animations"). Each section's own decoder has already checked the section
//! alone; this checks pairs. One function, [`check_consistency`], called by `furbake verify` and
//! `inspect` on every section, and by the runtime and the renderer on the sections they loaded.

use crate::SectionKind;
use crate::container::SectionEntry;
use crate::error::{FormatError, Result};
use crate::sections::animation_clips::{AnimationClips, ChannelTarget};
use crate::sections::blade_field::BladeField;
use crate::sections::fin_atlas::FinAtlas;
use crate::sections::fin_edges::FinEdges;
use crate::sections::keyframe_table::KeyframeTable;
use crate::sections::morph_targets::MorphTargets;
use crate::sections::shell_atlas::ShellAtlas;
use crate::sections::skeleton::Skeleton;
use crate::sections::skin_mesh::SkinMesh;
use crate::sections::skin_weights::SkinWeights;
use crate::sections::spring_topology::SpringTopology;
use crate::sections::triangle_uv_map::TriangleUvMap;

/// The decoded sections a caller has at hand; `None` / empty for those it did not load (a check
/// needs both sides of a pair and is skipped otherwise).
#[derive(Clone, Copy, Debug, Default)]
pub struct PackSections<'a> {
    /// The skin mesh.
    pub mesh: Option<&'a SkinMesh>,
    /// The shell atlas.
    pub shells: Option<&'a ShellAtlas>,
    /// The fin atlas.
    pub fins: Option<&'a FinAtlas>,
    /// The per-triangle UV map.
    pub uv_map: Option<&'a TriangleUvMap>,
    /// The fin edges.
    pub fin_edges: Option<&'a FinEdges>,
    /// Spring topologies.
    pub topologies: &'a [&'a SpringTopology],
    /// Blade fields.
    pub blade_fields: &'a [&'a BladeField],
    /// Keyframe tables.
    pub keyframe_tables: &'a [&'a KeyframeTable],
    /// The skeleton.
    pub skeleton: Option<&'a Skeleton>,
    /// The skin weights.
    pub skin_weights: Option<&'a SkinWeights>,
    /// The morph targets.
    pub morph_targets: Option<&'a MorphTargets>,
    /// The animation clips.
    pub clips: Option<&'a AnimationClips>,
}

/// Checks that the pack whose section table is `entries` holds sections that belong together,
/// and that the decoded `sections` agree pairwise. The table checks need no section read: at most
/// one section of each single kind, spring topologies of distinct kinds, a keyframe table beside
/// every blade field. Returns the number of checks made; the first failure is an
/// [`FormatError::Invalid`] naming the section and what disagrees (the path is added by the caller
/// with [`FormatError::with_path`]).
pub fn check_consistency(entries: &[SectionEntry], sections: &PackSections<'_>) -> Result<usize> {
    let mut checks = 0;
    let index_of = |kind: SectionKind| entries.iter().position(|e| e.kind == kind);
    let bad = |kind: SectionKind, what: String| FormatError::Invalid {
        path: None,
        section: index_of(kind),
        offset: None,
        what: format!("{kind}: {what}"),
    };
    // The section table.
    for kind in [
        SectionKind::BAKE_MANIFEST,
        SectionKind::SKIN_MESH,
        SectionKind::SHELL_ATLAS,
        SectionKind::FIN_ATLAS,
        SectionKind::TRIANGLE_UV_MAP,
        SectionKind::FIN_EDGES,
        SectionKind::BLADE_FIELD,
        SectionKind::KEYFRAME_TABLE,
        SectionKind::SKELETON,
        SectionKind::SKIN_WEIGHTS,
        SectionKind::MORPH_TARGETS,
        SectionKind::ANIMATION_CLIPS,
    ] {
        checks += 1;
        let n = entries.iter().filter(|e| e.kind == kind).count();
        if n > 1 {
            return Err(bad(kind, format!("{n} sections of this kind; a pack holds at most one")));
        }
    }
    checks += 1;
    if index_of(SectionKind::BLADE_FIELD).is_some() && index_of(SectionKind::KEYFRAME_TABLE).is_none() {
        return Err(bad(SectionKind::BLADE_FIELD, "a blade field needs a keyframe table to pose its blades".into()));
    }
    checks += 1;
    if index_of(SectionKind::SKIN_WEIGHTS).is_some() != index_of(SectionKind::SKELETON).is_some() {
        return Err(bad(SectionKind::SKIN_WEIGHTS, "skin weights and a skeleton come together or not at all".into()));
    }
    for (i, t) in sections.topologies.iter().enumerate() {
        checks += 1;
        if sections.topologies[..i].iter().any(|u| u.kind == t.kind) {
            return Err(bad(SectionKind::SPRING_TOPOLOGY, format!("two {} topologies", t.kind)));
        }
    }
    // Every artifact against the skin mesh it was baked from.
    if let Some(mesh) = sections.mesh {
        let (v, f) = (mesh.positions.len(), mesh.triangles.len());
        if let Some(uv) = sections.uv_map {
            checks += 1;
            if uv.corners.len() != f {
                return Err(bad(
                    SectionKind::TRIANGLE_UV_MAP,
                    format!("{} triangles, the skin mesh has {f}", uv.corners.len()),
                ));
            }
        }
        if let Some(fe) = sections.fin_edges {
            checks += 1;
            if fe.triangles.len() != fe.vertices.len() {
                return Err(bad(
                    SectionKind::FIN_EDGES,
                    format!("{} edges but {} triangles", fe.vertices.len(), fe.triangles.len()),
                ));
            }
            checks += 1;
            if let Some(i) = fe.vertices.iter().flatten().find(|&&i| i as usize >= v) {
                return Err(bad(SectionKind::FIN_EDGES, format!("vertex {i} is outside the skin mesh's {v} vertices")));
            }
            checks += 1;
            for (edge, &t) in fe.vertices.iter().zip(&fe.triangles) {
                let Some(tri) = mesh.triangles.get(t as usize) else {
                    return Err(bad(SectionKind::FIN_EDGES, format!("triangle {t} is outside the skin mesh's {f}")));
                };
                if !(tri.contains(&edge[0]) && tri.contains(&edge[1])) {
                    return Err(bad(SectionKind::FIN_EDGES, format!("edge {edge:?} is not an edge of triangle {t}")));
                }
                if mesh.fur_mask.get(t as usize).is_none_or(|&m| m == 0) {
                    return Err(bad(SectionKind::FIN_EDGES, format!("edge {edge:?} grows from bare triangle {t}")));
                }
            }
        }
        for t in sections.topologies {
            checks += 1;
            let s = &t.stats;
            if s.source_vertices as usize != v || s.source_triangles as usize != f {
                return Err(bad(
                    SectionKind::SPRING_TOPOLOGY,
                    format!(
                        "the {} topology was built on {} vertices / {} triangles; the skin mesh has {v} / {f}",
                        t.kind, s.source_vertices, s.source_triangles
                    ),
                ));
            }
            checks += 1;
            let want = if t.kind.is_separable() { 3 * f } else { v };
            if t.shell_vertex_masses.len() != want {
                return Err(bad(
                    SectionKind::SPRING_TOPOLOGY,
                    format!(
                        "the {} topology maps {} shell vertices; the skin mesh has {want}",
                        t.kind,
                        t.shell_vertex_masses.len()
                    ),
                ));
            }
        }
    }
    let in_table = (index_of(SectionKind::SKELETON).is_some(), index_of(SectionKind::MORPH_TARGETS).is_some());
    let clips_in_table = index_of(SectionKind::ANIMATION_CLIPS).is_some();
    checks += check_animation(sections, clips_in_table.then_some(in_table), &bad)?;
    if let (Some(s), Some(fins)) = (sections.shells, sections.fins) {
        checks += 1;
        if s.params.resolution != fins.width {
            return Err(bad(
                SectionKind::FIN_ATLAS,
                format!("{} texels wide but the shells are {}", fins.width, s.params.resolution),
            ));
        }
    }
    // A blade field against the keyframe table that poses its blades.
    for (field, table) in sections.blade_fields.iter().zip(sections.keyframe_tables) {
        checks += 1;
        if table.vertex_count() == 0 {
            return Err(bad(SectionKind::KEYFRAME_TABLE, "a blade field needs a table with vertices".into()));
        }
        checks += 1;
        let blades = field.positions.len();
        if blades > 0 && table.stored_poses() == 0 {
            return Err(bad(SectionKind::KEYFRAME_TABLE, format!("no poses for a field of {blades} blades")));
        }
    }
    Ok(checks)
}

/// The animation sections against the skin mesh and one another: weights and morph deltas for
/// every skin vertex, weights naming binds of the skeleton, clip channels naming existing joints
/// and morph groups with the group's weight count. Returns the number of checks made.
///
/// `table` is `(skeleton, morph targets)` present in the section table when the table lists the
/// clips: a clip driving joints needs a skeleton in the pack even when the caller did not load it.
fn check_animation(
    s: &PackSections<'_>,
    table: Option<(bool, bool)>,
    bad: &dyn Fn(SectionKind, String) -> FormatError,
) -> Result<usize> {
    let (skeleton_in_table, morphs_in_table) = table.unwrap_or((true, true));
    let mut checks = 0;
    if let (Some(mesh), Some(w)) = (s.mesh, s.skin_weights) {
        checks += 1;
        if w.vertex_count() != mesh.positions.len() {
            return Err(bad(
                SectionKind::SKIN_WEIGHTS,
                format!("{} vertices, the skin mesh has {}", w.vertex_count(), mesh.positions.len()),
            ));
        }
    }
    if let (Some(sk), Some(w)) = (s.skeleton, s.skin_weights) {
        checks += 1;
        if w.bind_count as usize != sk.bind_count() {
            return Err(bad(
                SectionKind::SKIN_WEIGHTS,
                format!("written for {} binds, the skeleton has {}", w.bind_count, sk.bind_count()),
            ));
        }
        if let Some(b) = w.binds.iter().find(|&&b| b as usize >= sk.bind_count()) {
            return Err(bad(
                SectionKind::SKIN_WEIGHTS,
                format!("bind {b} is outside the skeleton's {}", sk.bind_count()),
            ));
        }
    }
    if let (Some(mesh), Some(m)) = (s.mesh, s.morph_targets) {
        checks += 1;
        if m.vertex_count as usize != mesh.positions.len() {
            return Err(bad(
                SectionKind::MORPH_TARGETS,
                format!("{} vertices, the skin mesh has {}", m.vertex_count, mesh.positions.len()),
            ));
        }
    }
    if let Some(clips) = s.clips {
        for (ci, clip) in clips.clips.iter().enumerate() {
            for (k, ch) in clip.channels.iter().enumerate() {
                checks += 1;
                let at = format!("clip {ci} \"{}\" channel {k} ({})", clip.name, ch.target.path_name());
                match ch.target {
                    ChannelTarget::MorphWeights(g) => {
                        let Some(m) = s.morph_targets else {
                            if !morphs_in_table {
                                return Err(bad(
                                    SectionKind::ANIMATION_CLIPS,
                                    format!("{at}: the pack has no morph targets"),
                                ));
                            }
                            continue;
                        };
                        match m.groups.get(g as usize) {
                            None => {
                                return Err(bad(
                                    SectionKind::ANIMATION_CLIPS,
                                    format!("{at}: morph group {g} is outside the {} groups", m.groups.len()),
                                ));
                            }
                            Some(group) if group.target_count != ch.components => {
                                return Err(bad(
                                    SectionKind::ANIMATION_CLIPS,
                                    format!(
                                        "{at}: {} weights per key, the group has {} targets",
                                        ch.components, group.target_count
                                    ),
                                ));
                            }
                            Some(_) => {}
                        }
                    }
                    _ => {
                        let joint = ch.target.index();
                        let Some(sk) = s.skeleton else {
                            if !skeleton_in_table {
                                return Err(bad(
                                    SectionKind::ANIMATION_CLIPS,
                                    format!("{at}: the pack has no skeleton"),
                                ));
                            }
                            continue;
                        };
                        if joint as usize >= sk.joint_count() {
                            return Err(bad(
                                SectionKind::ANIMATION_CLIPS,
                                format!("{at}: joint {joint} is outside the skeleton's {}", sk.joint_count()),
                            ));
                        }
                    }
                }
            }
        }
    }
    Ok(checks)
}
