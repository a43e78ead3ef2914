//! A compressed grass-blade keyframe table (grass thesis §3.2.3–3.3, §4.1, §4.4.1): the reference
//! blade (eq. 3.4, 3.9: pose = reference + displacements), the grid of horizontal forces the poses
//! were simulated for (force magnitude × angle between force and blade normal, eq. 3.10–3.12), the
//! compression stages that were applied (static vertices dropped, one vector per rigid segment
//! pair, mirror symmetry in x and/or z, quantisation) and the stored displacement payload.
//!
//! Conventions (shared with the baker in `furbake-grass` and the vertex shader):
//! - Blade-local frame, unit = one blade length: `+y` along the blade, `+x` across it (the width
//!   axis), `+z` the blade normal (the front face looks towards `+z`). The root centre is the origin.
//! - Vertices: segment `k` is one quad with its own four vertices `4k..4k+4` = left-bottom,
//!   right-bottom, left-top, right-top (so `vertices = 4 × segments`, as the thesis counts: 8
//!   segments ⇒ 32 vertices). `triangles` are the front faces; back faces reuse the same vertices
//!   with the winding reversed.
//! - Pose grid: `magnitudes` force magnitudes `max_force × (i + 1) / magnitudes` (zero force is the
//!   reference itself) × `angles` angles over the full circle, `θ_j = (j + ½) · 2π / angles`,
//!   measured from the blade normal (`+z`) towards the width axis (`+x`). With symmetry only the
//!   angles in `(0, π)` (x) or `(0, π/2)` (xz) are stored; the others are their mirror images
//!   (negate the x and/or z component of every displacement, thesis fig. 3.8–3.9).
//! - Stored pose `p = magnitude_index × stored_angles + angle_index`; the payload holds
//!   `stored_poses × stored_vectors × 3` components, pose-major. `vertex_map[v]` is the stored
//!   vector of vertex `v`, or [`STATIC_VERTEX`] for a vertex that never moves.

use serde::{Deserialize, Serialize};

use super::{Section, check_finite, check_indices, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// `vertex_map` value of a vertex whose displacement is zero in every pose (dropped from storage).
pub const STATIC_VERTEX: u32 = u32::MAX;
/// Largest segment count a reader accepts (a blade is a handful of quads; this bounds allocations).
pub const MAX_SEGMENTS: u32 = 1024;
/// Largest number of represented poses a reader accepts.
pub const MAX_POSES: u64 = 1 << 24;

/// Which mirror symmetries of the animation are exploited (thesis fig. 3.8–3.9).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum Symmetry {
    /// Every pose of the full circle of angles is stored.
    #[default]
    None,
    /// Mirror in the plane `x = 0`: half the angles are stored.
    X,
    /// Mirror in `x = 0` and `z = 0`: a quarter of the angles are stored.
    XZ,
}

impl Symmetry {
    /// How many represented poses each stored pose stands for (1, 2 or 4).
    pub fn factor(self) -> u32 {
        match self {
            Symmetry::None => 1,
            Symmetry::X => 2,
            Symmetry::XZ => 4,
        }
    }

    /// Whether the x mirror (plane `x = 0`) is exploited.
    pub fn mirrors_x(self) -> bool {
        matches!(self, Symmetry::X | Symmetry::XZ)
    }

    /// Whether the z mirror (plane `z = 0`) is exploited.
    pub fn mirrors_z(self) -> bool {
        matches!(self, Symmetry::XZ)
    }

    /// `none`, `x` or `xz` (the CLI and `inspect` spelling).
    pub fn name(self) -> &'static str {
        match self {
            Symmetry::None => "none",
            Symmetry::X => "x",
            Symmetry::XZ => "xz",
        }
    }

    /// Parses [`Symmetry::name`].
    pub fn from_name(name: &str) -> Option<Symmetry> {
        [Symmetry::None, Symmetry::X, Symmetry::XZ].into_iter().find(|s| s.name() == name)
    }

    fn code(self) -> u8 {
        match self {
            Symmetry::None => 0,
            Symmetry::X => 1,
            Symmetry::XZ => 2,
        }
    }

    fn from_code(code: u8) -> Option<Symmetry> {
        [Symmetry::None, Symmetry::X, Symmetry::XZ].into_iter().find(|s| s.code() == code)
    }
}

/// How each displacement component is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum DisplacementEncoding {
    /// IEEE binary32, uncompressed.
    F32,
    /// Signed 16-bit normalised with a stored scale: `x = q / 32767 × scale` (thesis §4.4.1).
    #[default]
    Snorm16,
    /// IEEE binary16.
    F16,
    /// Unsigned 8-bit normalised, the thesis's `e1/d1`: `x = (2q / 255 − 1) × scale`.
    Unorm8,
    /// Signed 8-bit normalised: `x = q / 127 × scale`.
    Snorm8,
}

impl DisplacementEncoding {
    /// Every encoding, in code order.
    pub const ALL: [DisplacementEncoding; 5] = [Self::F32, Self::Snorm16, Self::F16, Self::Unorm8, Self::Snorm8];

    /// Bits per stored component.
    pub fn bits(self) -> u32 {
        match self {
            Self::F32 => 32,
            Self::Snorm16 | Self::F16 => 16,
            Self::Unorm8 | Self::Snorm8 => 8,
        }
    }

    /// `f32`, `snorm16`, `f16`, `unorm8` or `snorm8` (the CLI and `inspect` spelling).
    pub fn name(self) -> &'static str {
        match self {
            Self::F32 => "f32",
            Self::Snorm16 => "snorm16",
            Self::F16 => "f16",
            Self::Unorm8 => "unorm8",
            Self::Snorm8 => "snorm8",
        }
    }

    /// Parses [`DisplacementEncoding::name`].
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.name() == name)
    }

    fn code(self) -> u8 {
        match self {
            Self::F32 => 0,
            Self::Snorm16 => 1,
            Self::F16 => 2,
            Self::Unorm8 => 3,
            Self::Snorm8 => 4,
        }
    }

    fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|e| e.code() == code)
    }
}

/// The stored displacement components (`stored_poses × stored_vectors × 3`, pose-major).
#[derive(Clone, Debug, PartialEq)]
pub enum Displacements {
    /// Raw binary32 components, in blade lengths.
    F32(Vec<f32>),
    /// `x = q / 32767 × scale`, `scale` in blade lengths.
    Snorm16 {
        /// Largest absolute component, in blade lengths (> 0).
        scale: f32,
        /// Quantised components in `[-32767, 32767]`.
        values: Vec<i16>,
    },
    /// IEEE binary16 bit patterns, in blade lengths.
    F16(Vec<u16>),
    /// `x = (2q / 255 − 1) × scale`.
    Unorm8 {
        /// Largest absolute component, in blade lengths (> 0).
        scale: f32,
        /// Quantised components.
        values: Vec<u8>,
    },
    /// `x = q / 127 × scale`.
    Snorm8 {
        /// Largest absolute component, in blade lengths (> 0).
        scale: f32,
        /// Quantised components in `[-127, 127]`.
        values: Vec<i8>,
    },
}

impl Displacements {
    /// The encoding of this payload.
    pub fn encoding(&self) -> DisplacementEncoding {
        match self {
            Displacements::F32(_) => DisplacementEncoding::F32,
            Displacements::Snorm16 { .. } => DisplacementEncoding::Snorm16,
            Displacements::F16(_) => DisplacementEncoding::F16,
            Displacements::Unorm8 { .. } => DisplacementEncoding::Unorm8,
            Displacements::Snorm8 { .. } => DisplacementEncoding::Snorm8,
        }
    }

    /// Number of stored components.
    pub fn len(&self) -> usize {
        match self {
            Displacements::F32(v) => v.len(),
            Displacements::Snorm16 { values, .. } => values.len(),
            Displacements::F16(v) => v.len(),
            Displacements::Unorm8 { values, .. } => values.len(),
            Displacements::Snorm8 { values, .. } => values.len(),
        }
    }

    /// True when no component is stored.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The dequantisation scale (1 for the float encodings).
    pub fn scale(&self) -> f32 {
        match self {
            Displacements::Snorm16 { scale, .. }
            | Displacements::Unorm8 { scale, .. }
            | Displacements::Snorm8 { scale, .. } => *scale,
            Displacements::F32(_) | Displacements::F16(_) => 1.0,
        }
    }
}

/// The force grid the poses were simulated on.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseGrid {
    /// Number of force magnitudes (zero force excluded: it is the reference pose).
    pub magnitudes: u32,
    /// Number of angles over the full circle (a multiple of the symmetry factor).
    pub angles: u32,
    /// Largest force magnitude, in the simulation's force unit (newtons on a 1-length blade).
    pub max_force: f32,
}

impl PoseGrid {
    /// Poses the table represents (`magnitudes × angles`; the thesis's "1000 poses").
    pub fn represented_poses(&self) -> u64 {
        self.magnitudes as u64 * self.angles as u64
    }

    /// Angles stored under `symmetry`.
    pub fn stored_angles(&self, symmetry: Symmetry) -> u32 {
        self.angles / symmetry.factor()
    }

    /// Poses stored under `symmetry`.
    pub fn stored_poses(&self, symmetry: Symmetry) -> u64 {
        self.magnitudes as u64 * self.stored_angles(symmetry) as u64
    }

    /// Force magnitude of magnitude sample `i`.
    pub fn magnitude(&self, i: u32) -> f32 {
        self.max_force * (i + 1) as f32 / self.magnitudes as f32
    }

    /// Angle (radians, from the normal towards the width axis) of full-circle angle sample `j`.
    pub fn angle(&self, j: u32) -> f32 {
        (j as f32 + 0.5) * std::f32::consts::TAU / self.angles as f32
    }
}

/// Which lossless compression stages were applied (quantisation is the payload's encoding and
/// symmetry is [`KeyframeTable::symmetry`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct CompressionStages {
    /// Vertices that never move are not stored (`vertex_map` = [`STATIC_VERTEX`]).
    pub drop_static_vertices: bool,
    /// The two vertices of a rigid segment edge share one stored vector (thesis fig. 3.7).
    pub rigid_segment_pairs: bool,
}

/// Reconstruction statistics measured by the baker against the unquantised simulated poses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct KeyframeStats {
    /// Largest vertex position error over every vertex of every represented pose, in blade lengths.
    pub error_max: f32,
    /// Root-mean-square vertex position error, in blade lengths.
    pub error_rms: f32,
    /// Largest displacement length of any vertex, in blade lengths.
    pub max_displacement: f32,
}

/// A compressed keyframe table (see the module documentation for the layout conventions).
#[derive(Clone, Debug, PartialEq)]
pub struct KeyframeTable {
    /// Blade segments (quads), the level-of-detail parameter S.
    pub segments: u32,
    /// Reference (neutral) vertex positions in blade lengths, `4 × segments` of them.
    pub reference_positions: Vec<[f32; 3]>,
    /// Texture coordinates per vertex (`u` across, `v` from root 0 to tip 1).
    pub reference_uvs: Vec<[f32; 2]>,
    /// Front-face triangles (two per segment).
    pub triangles: Vec<[u32; 3]>,
    /// The force grid.
    pub grid: PoseGrid,
    /// Exploited mirror symmetries.
    pub symmetry: Symmetry,
    /// Applied lossless stages.
    pub stages: CompressionStages,
    /// Stored vectors per pose.
    pub stored_vectors: u32,
    /// Per vertex: its stored vector, or [`STATIC_VERTEX`].
    pub vertex_map: Vec<u32>,
    /// The stored displacement components.
    pub displacements: Displacements,
    /// Reconstruction statistics.
    pub stats: KeyframeStats,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    segments: u32,
    grid: PoseGrid,
    symmetry: u8,
    encoding: u8,
    scale: f32,
    stages: CompressionStages,
    stored_vectors: u32,
    stats: KeyframeStats,
}

impl KeyframeTable {
    /// Number of reference vertices.
    pub fn vertex_count(&self) -> usize {
        self.reference_positions.len()
    }

    /// Stored poses (`magnitudes × stored angles`).
    pub fn stored_poses(&self) -> u64 {
        self.grid.stored_poses(self.symmetry)
    }

    /// Bits of the uncompressed table as the thesis counts them (§3.3): every represented pose
    /// stores every vertex as three binary32 components. 8 segments (32 vertices) × 1000 poses ⇒
    /// `1000 × 32 × 3 × 32 = 3,072,000`.
    pub fn raw_bits(&self) -> u64 {
        self.grid.represented_poses() * self.vertex_count() as u64 * 3 * 32
    }

    /// Bits of the stored displacement data: `stored poses × stored vectors × 3 × bits per
    /// component` (the thesis's `250 × 15 × 3 × 16 = 180,000` with every stage on).
    pub fn payload_bits(&self) -> u64 {
        self.displacements.len() as u64 * self.displacements.encoding().bits() as u64
    }
}

impl Section for KeyframeTable {
    const KIND: SectionKind = SectionKind::KEYFRAME_TABLE;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            segments: self.segments,
            grid: self.grid,
            symmetry: self.symmetry.code(),
            encoding: self.displacements.encoding().code(),
            scale: self.displacements.scale(),
            stages: self.stages,
            stored_vectors: self.stored_vectors,
            stats: self.stats,
        };
        let w = RecordWriter::new(&meta)
            .array::<f32>(self.reference_positions.as_flattened())
            .array::<f32>(self.reference_uvs.as_flattened())
            .array::<u32>(self.triangles.as_flattened())
            .array::<u32>(&self.vertex_map);
        match &self.displacements {
            Displacements::F32(v) => w.array::<f32>(v),
            Displacements::Snorm16 { values, .. } => w.array::<i16>(values),
            Displacements::F16(v) => w.array_f16_bits(v),
            Displacements::Unorm8 { values, .. } => w.array::<u8>(values),
            Displacements::Snorm8 { values, .. } => w.array::<i8>(values),
        }
        .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        if m.segments == 0 || m.segments > MAX_SEGMENTS {
            return Err(FormatError::invalid(format!(
                "keyframe table with {} segments (must be 1..={MAX_SEGMENTS})",
                m.segments
            )));
        }
        let symmetry = Symmetry::from_code(m.symmetry)
            .ok_or_else(|| FormatError::invalid(format!("unknown keyframe symmetry code {}", m.symmetry)))?;
        let encoding = DisplacementEncoding::from_code(m.encoding)
            .ok_or_else(|| FormatError::invalid(format!("unknown displacement encoding code {}", m.encoding)))?;
        let g = m.grid;
        if g.magnitudes == 0 || g.angles == 0 || !g.angles.is_multiple_of(symmetry.factor()) {
            return Err(FormatError::invalid(format!(
                "pose grid {} magnitudes × {} angles does not fit symmetry {}",
                g.magnitudes,
                g.angles,
                symmetry.name()
            )));
        }
        if g.represented_poses() > MAX_POSES {
            return Err(FormatError::Limit {
                path: None,
                what: "keyframe poses",
                value: g.represented_poses(),
                limit: MAX_POSES,
            });
        }
        if !(g.max_force.is_finite() && g.max_force > 0.0) {
            return Err(FormatError::invalid(format!("pose grid max_force {} is not positive", g.max_force)));
        }
        let stats = [m.stats.error_max, m.stats.error_rms, m.stats.max_displacement];
        if stats.iter().any(|s| !(s.is_finite() && *s >= 0.0)) {
            return Err(FormatError::invalid(format!("keyframe statistics {stats:?} are not finite and ≥ 0")));
        }
        let v = 4 * m.segments as usize;
        let positions = r.array_exact::<f32>(0, v * 3, "reference_positions")?;
        let uvs = r.array_exact::<f32>(1, v * 2, "reference_uvs")?;
        let tris = r.array::<u32>(2)?;
        let map = r.array_exact::<u32>(3, v, "vertex_map")?;
        check_finite(&positions, "reference_positions")?;
        check_finite(&uvs, "reference_uvs")?;
        if tris.len() % 3 != 0 {
            return Err(FormatError::invalid(format!("triangles: {} indices, not a multiple of 3", tris.len())));
        }
        check_indices(&tris, v, "triangles")?;
        let sv = m.stored_vectors as usize;
        if sv > v {
            return Err(FormatError::invalid(format!("{sv} stored vectors for {v} vertices")));
        }
        if let Some(i) = map.iter().position(|&x| x != STATIC_VERTEX && x as usize >= sv) {
            return Err(FormatError::invalid(format!("vertex_map[{i}] = {} is not below {sv}", map[i])));
        }
        if !m.stages.drop_static_vertices && map.contains(&STATIC_VERTEX) {
            return Err(FormatError::invalid("vertex_map has static vertices but the stage is off"));
        }
        if m.stages.rigid_segment_pairs && map.chunks_exact(2).any(|p| p[0] != p[1]) {
            return Err(FormatError::invalid("rigid segment pairs map the two vertices of an edge apart"));
        }
        let stored_poses = g.stored_poses(symmetry) as usize;
        let n = checked_count(checked_count(stored_poses, sv, "displacements")?, 3, "displacements")?;
        let scale_ok = m.scale.is_finite() && m.scale > 0.0;
        if !scale_ok {
            return Err(FormatError::invalid(format!("displacement scale {} is not positive", m.scale)));
        }
        let displacements = match encoding {
            DisplacementEncoding::F32 => {
                let a = r.array_exact::<f32>(4, n, "displacements")?;
                check_finite(&a, "displacements")?;
                Displacements::F32(a.into_owned())
            }
            DisplacementEncoding::Snorm16 => {
                let a = r.array_exact::<i16>(4, n, "displacements")?;
                if let Some(i) = a.iter().position(|&q| q == i16::MIN) {
                    return Err(FormatError::invalid(format!("displacements[{i}] = -32768 is outside snorm16")));
                }
                Displacements::Snorm16 { scale: m.scale, values: a.into_owned() }
            }
            DisplacementEncoding::F16 => {
                let a = r.array_f16_bits(4)?;
                if a.len() != n {
                    return Err(FormatError::invalid(format!("displacements: {} elements, expected {n}", a.len())));
                }
                if let Some(i) = a.iter().position(|&b| b & 0x7c00 == 0x7c00) {
                    return Err(FormatError::invalid(format!("displacements[{i}] is not a finite f16")));
                }
                Displacements::F16(a.into_owned())
            }
            DisplacementEncoding::Unorm8 => {
                let a = r.array_exact::<u8>(4, n, "displacements")?;
                Displacements::Unorm8 { scale: m.scale, values: a.into_owned() }
            }
            DisplacementEncoding::Snorm8 => {
                let a = r.array_exact::<i8>(4, n, "displacements")?;
                if let Some(i) = a.iter().position(|&q| q == i8::MIN) {
                    return Err(FormatError::invalid(format!("displacements[{i}] = -128 is outside snorm8")));
                }
                Displacements::Snorm8 { scale: m.scale, values: a.into_owned() }
            }
        };
        Ok(KeyframeTable {
            segments: m.segments,
            reference_positions: positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            reference_uvs: uvs.chunks_exact(2).map(|c| [c[0], c[1]]).collect(),
            triangles: tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            grid: g,
            symmetry,
            stages: m.stages,
            stored_vectors: m.stored_vectors,
            vertex_map: map.into_owned(),
            displacements,
            stats: m.stats,
        })
    }

    fn summary(&self) -> serde_json::Value {
        let raw = self.raw_bits();
        let payload = self.payload_bits();
        let encoding = self.displacements.encoding();
        serde_json::json!({
            "segments": self.segments,
            "vertices": self.vertex_count(),
            "magnitudes": self.grid.magnitudes,
            "angles": self.grid.angles,
            "max_force": self.grid.max_force,
            "poses": self.grid.represented_poses(),
            "stored_poses": self.stored_poses(),
            "stored_vectors": self.stored_vectors,
            "symmetry": self.symmetry.name(),
            "encoding": encoding.name(),
            "scale": self.displacements.scale(),
            "drop_static_vertices": self.stages.drop_static_vertices,
            "rigid_segment_pairs": self.stages.rigid_segment_pairs,
            "symmetry_x": self.symmetry.mirrors_x(),
            "symmetry_z": self.symmetry.mirrors_z(),
            "quantised": encoding != DisplacementEncoding::F32,
            "raw_bits": raw,
            "payload_bits": payload,
            "compression_percent": if raw == 0 { 0.0 } else { 100.0 * (1.0 - payload as f64 / raw as f64) },
            "error_max_blade_lengths": self.stats.error_max,
            "error_rms_blade_lengths": self.stats.error_rms,
            "max_displacement_blade_lengths": self.stats.max_displacement,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small but complete table: 2 segments, every stage on, xz symmetry.
    fn sample(displacements: Displacements) -> KeyframeTable {
        let segments = 2u32;
        let mut reference_positions = Vec::new();
        let mut reference_uvs = Vec::new();
        let mut triangles = Vec::new();
        for k in 0..segments {
            for (dy, side) in [(0.0, -1.0), (0.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
                let y = (k as f32 + dy) / segments as f32;
                reference_positions.push([side * 0.05, y, 0.0]);
                reference_uvs.push([(side + 1.0) / 2.0, y]);
            }
            let b = 4 * k;
            triangles.push([b, b + 1, b + 3]);
            triangles.push([b, b + 3, b + 2]);
        }
        // Vertices 0,1 static; pairs (2,3) (4,5) (6,7) → vectors 0, 1, 2.
        let vertex_map = vec![STATIC_VERTEX, STATIC_VERTEX, 0, 0, 1, 1, 2, 2];
        KeyframeTable {
            segments,
            reference_positions,
            reference_uvs,
            triangles,
            grid: PoseGrid { magnitudes: 2, angles: 8, max_force: 3.0 },
            symmetry: Symmetry::XZ,
            stages: CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true },
            stored_vectors: 3,
            vertex_map,
            displacements,
            stats: KeyframeStats { error_max: 1e-5, error_rms: 4e-6, max_displacement: 0.7 },
        }
    }

    fn payloads() -> Vec<Displacements> {
        let n = 2 * 2 * 3 * 3; // stored poses × vectors × 3
        vec![
            Displacements::F32((0..n).map(|i| i as f32 * 0.01 - 0.1).collect()),
            Displacements::Snorm16 { scale: 0.7, values: (0..n).map(|i| (i as i16 - 18) * 900).collect() },
            Displacements::F16((0..n).map(|i| 0x3c00 - i as u16).collect()),
            Displacements::Unorm8 { scale: 0.7, values: (0..n).map(|i| (i * 7) as u8).collect() },
            Displacements::Snorm8 { scale: 0.7, values: (0..n).map(|i| i as i8 - 9).collect() },
        ]
    }

    #[test]
    fn every_encoding_round_trips_and_reencodes_identically() {
        let mut checked = 0;
        for d in payloads() {
            let t = sample(d);
            let bytes = t.encode();
            let back = KeyframeTable::decode(&bytes).expect("a freshly encoded table decodes");
            assert_eq!(back, t);
            assert_eq!(back.encode(), bytes, "encoding is deterministic");
            checked += 1;
        }
        assert_eq!(checked, DisplacementEncoding::ALL.len());
    }

    #[test]
    fn summary_counts_bits_as_the_thesis_does() {
        let t = sample(payloads().swap_remove(1));
        let s = t.summary();
        // raw: 16 represented poses × 8 vertices × 3 × 32; payload: 4 stored poses × 3 vectors × 3 × 16.
        assert_eq!(s["raw_bits"], 16 * 8 * 3 * 32);
        assert_eq!(s["payload_bits"], 4 * 3 * 3 * 16);
        assert_eq!(s["symmetry"], "xz");
        assert_eq!(s["encoding"], "snorm16");
        assert_eq!(s["drop_static_vertices"], true);
        assert_eq!(s["rigid_segment_pairs"], true);
        assert_eq!(s["symmetry_x"], true);
        assert_eq!(s["symmetry_z"], true);
        assert_eq!(s["quantised"], true);
        assert!(s["error_max_blade_lengths"].as_f64().expect("a number") > 0.0);
        assert!(s["error_rms_blade_lengths"].is_number());
    }

    #[test]
    fn every_truncation_and_most_corruptions_give_errors_not_panics() {
        let mut truncations = 0;
        for d in payloads() {
            let bytes = sample(d).encode();
            for len in 0..bytes.len() {
                // Truncation may keep a valid prefix only if nothing after it mattered; the arrays
                // sit at the end, so every strict prefix must fail.
                assert!(KeyframeTable::decode(&bytes[..len]).is_err(), "prefix of {len} bytes decoded");
                truncations += 1;
            }
            // Flip every byte: decoding must never panic (it may succeed when a payload byte changes).
            for i in 0..bytes.len() {
                let mut b = bytes.clone();
                b[i] ^= 0xA5;
                let _ = KeyframeTable::decode(&b);
            }
        }
        assert!(truncations > 500, "checked {truncations} truncations");
    }

    #[test]
    fn inconsistent_tables_are_rejected() {
        let base = sample(payloads().swap_remove(0));
        let mut cases: Vec<(&str, KeyframeTable)> = Vec::new();
        let mut t = base.clone();
        t.vertex_map[3] = 7;
        cases.push(("map index out of range", t));
        let mut t = base.clone();
        t.vertex_map[3] = 1;
        cases.push(("pair split", t));
        let mut t = base.clone();
        t.stages.drop_static_vertices = false;
        cases.push(("static without stage", t));
        let mut t = base.clone();
        t.grid.angles = 6;
        cases.push(("angles not a multiple of 4", t));
        let mut t = base.clone();
        t.triangles[0][1] = 99;
        cases.push(("triangle index", t));
        let mut t = base.clone();
        t.displacements = Displacements::F32(vec![0.0; 5]);
        cases.push(("payload length", t));
        let mut t = base.clone();
        t.displacements = Displacements::F32(vec![f32::NAN; 36]);
        cases.push(("non-finite payload", t));
        let mut t = base.clone();
        t.grid.magnitudes = u32::MAX;
        t.grid.angles = 4 * (u32::MAX / 4);
        cases.push(("absurd pose count", t));
        let mut t = base.clone();
        t.displacements = Displacements::Snorm16 { scale: 0.0, values: vec![0; 36] };
        cases.push(("zero scale", t));
        let mut t = base.clone();
        t.displacements = Displacements::F16(vec![0x7c00; 36]);
        cases.push(("f16 infinity", t));
        let n = cases.len();
        for (what, t) in cases {
            assert!(KeyframeTable::decode(&t.encode()).is_err(), "{what} was accepted");
        }
        assert_eq!(n, 10);
    }
}
