//! Morph targets (glTF 2.0 specification, "Morph Targets"): per target a `POSITION` and a
//! `NORMAL` displacement for every welded skin vertex (zero for vertices of other meshes), and
//! the default weights. Targets come in *groups*, one per glTF mesh instance (node) with targets:
//! an animation's `weights` channel drives one group, `group.target_count` weights per key.
//! The morphed position is `p + Σ wᵢ·Δpᵢ` (the same for normals, renormalised), applied before
//! skinning.
//!
//! Layout (record, see `docs/format.md` "12 `morph_targets`"): metadata `vertex_count: u32,
//! target_count: u32, has_normals: bool, names: Vec<String>, groups: Vec<MorphGroup>`; arrays
//! 0 position deltas `f32 × 3·T·V` (target-major), 1 normal deltas `f32 × 3·T·V` or empty,
//! 2 default weights `f32 × T`.

use serde::{Deserialize, Serialize};

use super::{Section, check_coordinates, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Largest magnitude of a stored morph weight (glTF weights are usually in `[0, 1]`; the
/// specification does not bound them, so readers allow a generous range).
pub const MAX_MORPH_WEIGHT: f32 = 1e3;

/// The targets of one glTF mesh instance: `target_count` consecutive targets.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MorphGroup {
    /// The glTF node name (or mesh name) the group came from.
    pub name: String,
    /// Index of its first target.
    pub first_target: u32,
    /// Number of its targets.
    pub target_count: u32,
}

/// Every morph target of the skin, struct of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTargets {
    /// Welded skin vertices each target displaces.
    pub vertex_count: u32,
    /// Target names (the mesh's `extras.targetNames` when present, else empty).
    pub names: Vec<String>,
    /// Groups partitioning the targets in order.
    pub groups: Vec<MorphGroup>,
    /// Position deltas, `vertex_count` per target, target-major (metres).
    pub position_deltas: Vec<[f32; 3]>,
    /// Normal deltas in the same order, or empty when no target moves normals.
    pub normal_deltas: Vec<[f32; 3]>,
    /// Default weight per target (the node's or mesh's `weights`, else 0).
    pub default_weights: Vec<f32>,
}

impl MorphTargets {
    /// Number of targets.
    pub fn target_count(&self) -> usize {
        self.default_weights.len()
    }

    /// The position deltas of target `t`, one per vertex.
    pub fn positions_of(&self, t: usize) -> &[[f32; 3]] {
        let v = self.vertex_count as usize;
        &self.position_deltas[t * v..(t + 1) * v]
    }

    /// The normal deltas of target `t` (empty when the section has none).
    pub fn normals_of(&self, t: usize) -> &[[f32; 3]] {
        let v = self.vertex_count as usize;
        if self.normal_deltas.is_empty() { &[] } else { &self.normal_deltas[t * v..(t + 1) * v] }
    }
}

#[derive(Serialize, Deserialize)]
struct Meta {
    vertex_count: u32,
    target_count: u32,
    has_normals: bool,
    names: Vec<String>,
    groups: Vec<MorphGroup>,
}

impl Section for MorphTargets {
    const KIND: SectionKind = SectionKind::MORPH_TARGETS;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            vertex_count: self.vertex_count,
            target_count: self.default_weights.len() as u32,
            has_normals: !self.normal_deltas.is_empty(),
            names: self.names.clone(),
            groups: self.groups.clone(),
        };
        RecordWriter::new(&meta)
            .array::<f32>(self.position_deltas.as_flattened())
            .array::<f32>(self.normal_deltas.as_flattened())
            .array::<f32>(&self.default_weights)
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let t = m.target_count as usize;
        let deltas = checked_count(checked_count(t, m.vertex_count as usize, "morph deltas")?, 3, "morph deltas")?;
        let pos = r.array_exact::<f32>(0, deltas, "position deltas")?;
        let nrm = r.array_exact::<f32>(1, if m.has_normals { deltas } else { 0 }, "normal deltas")?;
        let defaults = r.array_exact::<f32>(2, t, "default weights")?;
        if m.names.len() != t {
            return Err(FormatError::invalid(format!("{} target names for {t} targets", m.names.len())));
        }
        let mut next = 0u64;
        for (i, g) in m.groups.iter().enumerate() {
            if u64::from(g.first_target) != next || g.target_count == 0 {
                return Err(FormatError::invalid(format!(
                    "groups[{i}] starts at target {} with {} targets; groups must partition the targets in order",
                    g.first_target, g.target_count
                )));
            }
            next += u64::from(g.target_count);
        }
        if next != t as u64 {
            return Err(FormatError::invalid(format!("the groups cover {next} targets of {t}")));
        }
        check_coordinates(&pos, "position deltas")?;
        check_coordinates(&nrm, "normal deltas")?;
        check_range(&defaults, -MAX_MORPH_WEIGHT, MAX_MORPH_WEIGHT, "default weights")?;
        Ok(MorphTargets {
            vertex_count: m.vertex_count,
            names: m.names,
            groups: m.groups,
            position_deltas: pos.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            normal_deltas: nrm.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            default_weights: defaults.into_owned(),
        })
    }

    fn summary(&self) -> serde_json::Value {
        let groups: Vec<serde_json::Value> = self
            .groups
            .iter()
            .map(|g| serde_json::json!({ "name": g.name, "first_target": g.first_target, "targets": g.target_count }))
            .collect();
        serde_json::json!({
            "vertices": self.vertex_count,
            "targets": self.target_count(),
            "has_normal_deltas": !self.normal_deltas.is_empty(),
            "target_names": self.names,
            "default_weights": self.default_weights,
            "groups": groups,
        })
    }
}
