//! The per-triangle UV map (fur thesis §3.2, fig. 3.18–3.19): every triangle is mapped into the
//! shell texture on its own, its edge lengths preserved (a constant texel density: `repeat_m`
//! metres of surface per texture repeat), then shifted by a seeded random offset so that the
//! triangles do not all start at the same texel.

use serde::{Deserialize, Serialize};

use super::{Section, check_coordinates, check_param, checked_count};
use crate::SectionKind;
use crate::error::Result;
use crate::record::{Record, RecordWriter};

/// Per-triangle corner UVs in texture repeats (1.0 = one shell texture; the sampler wraps).
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleUvMap {
    /// Surface length covered by one texture repeat, in metres.
    pub repeat_m: f32,
    /// Seed of the random offsets.
    pub seed: u64,
    /// Three `(u, v)` corners per triangle, in the skin mesh's triangle order.
    pub corners: Vec<[[f32; 2]; 3]>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    triangle_count: u32,
    repeat_m: f32,
    seed: u64,
}

impl Section for TriangleUvMap {
    const KIND: SectionKind = SectionKind::TRIANGLE_UV_MAP;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta { triangle_count: self.corners.len() as u32, repeat_m: self.repeat_m, seed: self.seed };
        RecordWriter::new(&meta).array::<f32>(self.corners.as_flattened().as_flattened()).finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let (lo, hi) = crate::sections::spring_topology::FUR_LENGTH_RANGE_M;
        check_param(m.repeat_m, lo, hi, "repeat_m")?;
        let uv = r.array_exact::<f32>(0, checked_count(m.triangle_count as usize, 6, "uv corners")?, "uv corners")?;
        check_coordinates(&uv, "uv corners")?;
        Ok(TriangleUvMap {
            repeat_m: m.repeat_m,
            seed: m.seed,
            corners: uv.chunks_exact(6).map(|c| [[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]]).collect(),
        })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "triangles": self.corners.len(),
            "repeat_m": self.repeat_m,
            "seed": self.seed,
        })
    }
}
