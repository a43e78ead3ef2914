//! Section kinds: an open set of `u32` codes. An unknown code is kept and printed as
//! `unknown(N)`; it never makes a reader fail, so newer writers can add kinds that older readers
//! skip.

use std::fmt;

/// The kind of one section of a container (stored as a little-endian `u32`).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize)]
#[serde(transparent)]
pub struct SectionKind(pub u32);

impl SectionKind {
    /// Every parameter, seed, tool version and input hash of the bake that wrote the pack.
    pub const BAKE_MANIFEST: SectionKind = SectionKind(1);
    /// The welded skin mesh (positions, normals, colours, triangles, fur mask).
    pub const SKIN_MESH: SectionKind = SectionKind(2);
    /// Shell alpha slices (`layers × height × width`) and the per-layer self-shadow table.
    pub const SHELL_ATLAS: SectionKind = SectionKind(3);
    /// The fin texture composed from K vertical slices of the volume.
    pub const FIN_ATLAS: SectionKind = SectionKind(4);
    /// Per-triangle local UVs (three corners per triangle), fur thesis §3.2.
    pub const TRIANGLE_UV_MAP: SectionKind = SectionKind(5);
    /// Border edges and furry/bare boundary edges that carry fins.
    pub const FIN_EDGES: SectionKind = SectionKind(6);
    /// One mass–spring topology (fur thesis §3.4.1).
    pub const SPRING_TOPOLOGY: SectionKind = SectionKind(7);
    /// A compressed grass-blade keyframe table (grass thesis §3.3).
    pub const KEYFRAME_TABLE: SectionKind = SectionKind(8);
    /// Scattered grass blades grouped in clusters (grass thesis eq. 3.6–3.8).
    pub const BLADE_FIELD: SectionKind = SectionKind(9);
    /// The joint hierarchy (rest TRS) and the skinning palette (glTF 2.0 "Skins").
    pub const SKELETON: SectionKind = SectionKind(10);
    /// Up to eight joint influences per welded skin vertex (glTF 2.0 "Skins").
    pub const SKIN_WEIGHTS: SectionKind = SectionKind(11);
    /// Morph-target position and normal deltas per welded vertex (glTF 2.0 "Morph Targets").
    pub const MORPH_TARGETS: SectionKind = SectionKind(12);
    /// Every animation clip: channels, interpolation, key times and values (glTF 2.0 "Animations").
    pub const ANIMATION_CLIPS: SectionKind = SectionKind(13);

    /// Every kind this version of the crate knows, in code order.
    pub const KNOWN: [SectionKind; 13] = [
        Self::BAKE_MANIFEST,
        Self::SKIN_MESH,
        Self::SHELL_ATLAS,
        Self::FIN_ATLAS,
        Self::TRIANGLE_UV_MAP,
        Self::FIN_EDGES,
        Self::SPRING_TOPOLOGY,
        Self::KEYFRAME_TABLE,
        Self::BLADE_FIELD,
        Self::SKELETON,
        Self::SKIN_WEIGHTS,
        Self::MORPH_TARGETS,
        Self::ANIMATION_CLIPS,
    ];

    /// The stable snake_case name used by `furbake inspect --json`, or `None` for unknown codes.
    pub fn name(self) -> Option<&'static str> {
        Some(match self {
            Self::BAKE_MANIFEST => "bake_manifest",
            Self::SKIN_MESH => "skin_mesh",
            Self::SHELL_ATLAS => "shell_atlas",
            Self::FIN_ATLAS => "fin_atlas",
            Self::TRIANGLE_UV_MAP => "triangle_uv_map",
            Self::FIN_EDGES => "fin_edges",
            Self::SPRING_TOPOLOGY => "spring_topology",
            Self::KEYFRAME_TABLE => "keyframe_table",
            Self::BLADE_FIELD => "blade_field",
            Self::SKELETON => "skeleton",
            Self::SKIN_WEIGHTS => "skin_weights",
            Self::MORPH_TARGETS => "morph_targets",
            Self::ANIMATION_CLIPS => "animation_clips",
            _ => return None,
        })
    }

    /// Parses a name produced by [`SectionKind::name`].
    pub fn from_name(name: &str) -> Option<SectionKind> {
        Self::KNOWN.into_iter().find(|k| k.name() == Some(name))
    }
}

impl fmt::Display for SectionKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(n) => f.write_str(n),
            None => write!(f, "unknown({})", self.0),
        }
    }
}

impl fmt::Debug for SectionKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}
