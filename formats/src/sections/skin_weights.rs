//! Per-vertex skin weights (glTF 2.0 specification, "Skins" → "Skinned Mesh Attributes":
//! `JOINTS_n` / `WEIGHTS_n`): for every welded skin vertex up to eight influences, each a bind of
//! the [`Skeleton`](super::skeleton::Skeleton) palette and a weight; weights are normalised (sum
//! to 1) on import. Struct of arrays, vertex-major with a fixed slot count; unused slots hold
//! bind 0 with weight 0.
//!
//! Layout (record, see `docs/format.md` "11 `skin_weights`"): metadata `vertex_count: u32,
//! influences_per_vertex: u32 (4 or 8), bind_count: u32, stats: SkinWeightStats`; arrays 0 binds
//! `u16 × k·V`, 1 weights `f32 × k·V`.

use serde::{Deserialize, Serialize};

use super::{Section, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Largest deviation of a vertex's weight sum from 1 a reader accepts (the importer normalises
/// in `f64`, so stored sums are within `f32` rounding of 1).
pub const WEIGHT_SUM_TOLERANCE: f32 = 1e-3;

/// The skin weights of every welded vertex, struct of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinWeights {
    /// Influence slots per vertex: 4, or 8 when some vertex has more than four influences.
    pub influences_per_vertex: u32,
    /// Number of binds in the skeleton's palette (every stored bind index is below it).
    pub bind_count: u32,
    /// Bind index per slot, `influences_per_vertex` per vertex, largest weight first.
    pub binds: Vec<u16>,
    /// Weight per slot (in `[0, 1]`, summing to 1 per vertex).
    pub weights: Vec<f32>,
    /// What the import repaired (shown by `inspect`).
    pub stats: SkinWeightStats,
}

/// Repairs and counts of the skin-weight import.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SkinWeightStats {
    /// Input vertices whose weights did not sum to 1 (±1e-3) and were renormalised; a vertex whose
    /// weights sum to 0 is bound wholly to its skin's first joint and counted here too.
    pub renormalised_vertices: u32,
    /// Influences dropped: a `JOINTS_2`/`WEIGHTS_2` set or beyond, or negative weights.
    pub dropped_influences: u32,
    /// Input vertices of unskinned meshes bound rigidly to their node (one influence).
    pub rigid_vertices: u32,
    /// Input vertices of skinned meshes (bound through `JOINTS_n`/`WEIGHTS_n`).
    pub skinned_vertices: u32,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    vertex_count: u32,
    influences_per_vertex: u32,
    bind_count: u32,
    stats: SkinWeightStats,
}

impl SkinWeights {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        match self.influences_per_vertex {
            0 => 0,
            k => self.binds.len() / k as usize,
        }
    }

    /// The `(bind, weight)` slots of vertex `v`.
    pub fn influences(&self, v: usize) -> impl Iterator<Item = (u16, f32)> + '_ {
        let k = self.influences_per_vertex as usize;
        let range = v * k..(v + 1) * k;
        self.binds[range.clone()].iter().copied().zip(self.weights[range].iter().copied())
    }
}

impl Section for SkinWeights {
    const KIND: SectionKind = SectionKind::SKIN_WEIGHTS;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            vertex_count: self.vertex_count() as u32,
            influences_per_vertex: self.influences_per_vertex,
            bind_count: self.bind_count,
            stats: self.stats.clone(),
        };
        RecordWriter::new(&meta).array::<u16>(&self.binds).array::<f32>(&self.weights).finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let k = m.influences_per_vertex as usize;
        if k != 4 && k != 8 {
            return Err(FormatError::invalid(format!("influences_per_vertex = {k} (must be 4 or 8)")));
        }
        let n = checked_count(m.vertex_count as usize, k, "influences")?;
        let binds = r.array_exact::<u16>(0, n, "binds")?;
        let weights = r.array_exact::<f32>(1, n, "weights")?;
        if let Some(i) = binds.iter().position(|&b| u32::from(b) >= m.bind_count.max(1)) {
            return Err(FormatError::invalid(format!(
                "binds[{i}] = {} is out of range (must be below {})",
                binds[i], m.bind_count
            )));
        }
        check_range(&weights, 0.0, 1.0, "weights")?;
        if let Some(v) =
            weights.chunks_exact(k).position(|w| (w.iter().sum::<f32>() - 1.0).abs() > WEIGHT_SUM_TOLERANCE)
        {
            return Err(FormatError::invalid(format!("weights of vertex {v} do not sum to 1")));
        }
        Ok(SkinWeights {
            influences_per_vertex: m.influences_per_vertex,
            bind_count: m.bind_count,
            binds: binds.into_owned(),
            weights: weights.into_owned(),
            stats: m.stats,
        })
    }

    fn summary(&self) -> serde_json::Value {
        let max_used =
            (0..self.vertex_count()).map(|v| self.influences(v).filter(|&(_, w)| w > 0.0).count()).max().unwrap_or(0);
        serde_json::json!({
            "vertices": self.vertex_count(),
            "influences_per_vertex": self.influences_per_vertex,
            "max_influences_used": max_used,
            "binds": self.bind_count,
            "renormalised_vertices": self.stats.renormalised_vertices,
            "dropped_influences": self.stats.dropped_influences,
            "rigid_vertices": self.stats.rigid_vertices,
            "skinned_vertices": self.stats.skinned_vertices,
        })
    }
}
