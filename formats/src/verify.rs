//! [`Pack::verify`]: the one full validation of a pack, what `furbake verify` does and what every
//! command that reads a pack does before it uses it (docs/design.md "Runtime: packs"): every
//! section of a known kind decoded with its typed decoder (its checksum checked on the way),
//! every section of an unknown kind read and checksummed, and [`check_consistency`] over all of
//! them.
//!
//! The sections are decoded through the pack's shared cache ([`Pack::sections_of`]), so a world,
//! a renderer or an exporter that uses the same `Pack` afterwards decodes nothing again. A host
//! that wants the runtime's lazy reads (only the sections a scene needs: `Pack::read_counts`)
//! simply does not call it.

use std::sync::Arc;

use crate::SectionKind;
use crate::consistency::{PackSections, check_consistency};
use crate::error::{FormatError, Result};
use crate::pack::Pack;
use crate::sections::animation_clips::AnimationClips;
use crate::sections::blade_field::BladeField;
use crate::sections::fin_atlas::FinAtlas;
use crate::sections::fin_edges::FinEdges;
use crate::sections::keyframe_table::KeyframeTable;
use crate::sections::manifest::BakeManifest;
use crate::sections::morph_targets::MorphTargets;
use crate::sections::shell_atlas::ShellAtlas;
use crate::sections::skeleton::Skeleton;
use crate::sections::skin_mesh::SkinMesh;
use crate::sections::skin_weights::SkinWeights;
use crate::sections::spring_topology::SpringTopology;
use crate::sections::triangle_uv_map::TriangleUvMap;

/// What [`Pack::verify`] checked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VerifySummary {
    /// Sections in the table, every one checksummed.
    pub sections: usize,
    /// Sections of a known kind, decoded with their typed decoder.
    pub decoded: usize,
    /// Cross-section checks made ([`check_consistency`]).
    pub checks: usize,
}

/// Every decoded section of a pack, shared with the pack's cache: the first section of each kind
/// that a pack holds once, and every spring topology, blade field and keyframe table.
#[derive(Clone, Debug, Default)]
pub struct DecodedSections {
    /// The bake manifest.
    pub manifest: Option<Arc<BakeManifest>>,
    /// The skin mesh.
    pub mesh: Option<Arc<SkinMesh>>,
    /// The shell atlas.
    pub shells: Option<Arc<ShellAtlas>>,
    /// The fin atlas.
    pub fins: Option<Arc<FinAtlas>>,
    /// The per-triangle UV map.
    pub uv_map: Option<Arc<TriangleUvMap>>,
    /// The fin edges.
    pub fin_edges: Option<Arc<FinEdges>>,
    /// Spring topologies, in table order.
    pub topologies: Vec<Arc<SpringTopology>>,
    /// Blade fields, in table order.
    pub blade_fields: Vec<Arc<BladeField>>,
    /// Keyframe tables, in table order.
    pub keyframe_tables: Vec<Arc<KeyframeTable>>,
    /// The skeleton.
    pub skeleton: Option<Arc<Skeleton>>,
    /// The skin weights.
    pub skin_weights: Option<Arc<SkinWeights>>,
    /// The morph targets.
    pub morph_targets: Option<Arc<MorphTargets>>,
    /// The animation clips.
    pub clips: Option<Arc<AnimationClips>>,
}

impl Pack {
    /// Validates the whole pack as `furbake verify` does (see the module doc) and returns what it
    /// checked. The first failure is returned as the decoder or [`check_consistency`] reports it,
    /// with the pack's path. Sections are decoded in table order (each kind the first time it
    /// appears, with every section of that kind) and stay in the pack's cache.
    pub fn verify(&self) -> Result<VerifySummary> {
        let mut decoded = 0;
        let mut kinds: Vec<SectionKind> = Vec::new();
        for e in self.sections() {
            if kinds.contains(&e.kind) {
                continue;
            }
            kinds.push(e.kind);
            decoded += match e.kind {
                SectionKind::BAKE_MANIFEST => self.sections_of::<BakeManifest>()?.len(),
                SectionKind::SKIN_MESH => self.sections_of::<SkinMesh>()?.len(),
                SectionKind::SHELL_ATLAS => self.sections_of::<ShellAtlas>()?.len(),
                SectionKind::FIN_ATLAS => self.sections_of::<FinAtlas>()?.len(),
                SectionKind::TRIANGLE_UV_MAP => self.sections_of::<TriangleUvMap>()?.len(),
                SectionKind::FIN_EDGES => self.sections_of::<FinEdges>()?.len(),
                SectionKind::BLADE_FIELD => self.sections_of::<BladeField>()?.len(),
                SectionKind::KEYFRAME_TABLE => self.sections_of::<KeyframeTable>()?.len(),
                SectionKind::SPRING_TOPOLOGY => self.sections_of::<SpringTopology>()?.len(),
                SectionKind::SKELETON => self.sections_of::<Skeleton>()?.len(),
                SectionKind::SKIN_WEIGHTS => self.sections_of::<SkinWeights>()?.len(),
                SectionKind::MORPH_TARGETS => self.sections_of::<MorphTargets>()?.len(),
                SectionKind::ANIMATION_CLIPS => self.sections_of::<AnimationClips>()?.len(),
                _ => {
                    // A kind this reader does not know is kept as bytes: its checksum is all
                    // there is to check (a pack read into memory checked it already).
                    for j in self.find(e.kind).collect::<Vec<_>>() {
                        self.payload(j)?;
                    }
                    0
                }
            };
        }
        let d = self.decoded_sections()?;
        let checks = d.with_pack_sections(|s| check_consistency(self.sections(), s)).map_err(|e| self.blame(e))?;
        Ok(VerifySummary { sections: self.sections().len(), decoded, checks })
    }

    /// The decoded sections (see [`DecodedSections`]), decoded now or taken from the cache (after
    /// [`Pack::verify`], nothing is decoded again). Fails as the first section that does not
    /// decode.
    pub fn decoded_sections(&self) -> Result<DecodedSections> {
        Ok(DecodedSections {
            manifest: self.optional_section()?,
            mesh: self.optional_section()?,
            shells: self.optional_section()?,
            fins: self.optional_section()?,
            uv_map: self.optional_section()?,
            fin_edges: self.optional_section()?,
            topologies: self.sections_of()?,
            blade_fields: self.sections_of()?,
            keyframe_tables: self.sections_of()?,
            skeleton: self.optional_section()?,
            skin_weights: self.optional_section()?,
            morph_targets: self.optional_section()?,
            clips: self.optional_section()?,
        })
    }

    fn blame(&self, e: FormatError) -> FormatError {
        match self.path() {
            Some(p) => e.with_path(p),
            None => e,
        }
    }
}

impl DecodedSections {
    /// The sections as [`check_consistency`] takes them. The lists of references live in `self`'s
    /// borrow, hence the closure.
    pub fn with_pack_sections<T>(&self, f: impl FnOnce(&PackSections<'_>) -> T) -> T {
        let topologies: Vec<&SpringTopology> = self.topologies.iter().map(|t| &**t).collect();
        let blade_fields: Vec<&BladeField> = self.blade_fields.iter().map(|b| &**b).collect();
        let keyframe_tables: Vec<&KeyframeTable> = self.keyframe_tables.iter().map(|k| &**k).collect();
        f(&PackSections {
            mesh: self.mesh.as_deref(),
            shells: self.shells.as_deref(),
            fins: self.fins.as_deref(),
            uv_map: self.uv_map.as_deref(),
            fin_edges: self.fin_edges.as_deref(),
            topologies: &topologies,
            blade_fields: &blade_fields,
            keyframe_tables: &keyframe_tables,
            skeleton: self.skeleton.as_deref(),
            skin_weights: self.skin_weights.as_deref(),
            morph_targets: self.morph_targets.as_deref(),
            clips: self.clips.as_deref(),
        })
    }
}
