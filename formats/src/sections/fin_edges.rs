//! Fin edges (fur thesis §3.2, fig. 3.16): the edges that carry a fin — mesh border edges of
//! furry triangles, and edges between a furry and a bare triangle.

use serde::{Deserialize, Serialize};

use super::{Section, check_indices, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Why an edge carries a fin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum FinEdgeKind {
    /// The edge belongs to exactly one triangle (a mesh border).
    Border = 0,
    /// The edge separates a furry triangle from a bare one.
    FurBoundary = 1,
}

/// The fin-carrying edges, struct of arrays.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FinEdges {
    /// Welded vertex indices of each edge, in the winding order of `triangles`.
    pub vertices: Vec<[u32; 2]>,
    /// The furry triangle the fin grows from.
    pub triangles: Vec<u32>,
    /// Why each edge carries a fin.
    pub kinds: Vec<FinEdgeKind>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    edge_count: u32,
    vertex_count: u32,
    triangle_count: u32,
}

impl FinEdges {
    /// Number of edges of `kind`.
    pub fn count(&self, kind: FinEdgeKind) -> usize {
        self.kinds.iter().filter(|&&k| k == kind).count()
    }

    /// Encodes with the bounds the indices must respect (vertex and triangle counts of the skin).
    pub fn encode_with_bounds(&self, vertex_count: usize, triangle_count: usize) -> Vec<u8> {
        let meta = Meta {
            edge_count: self.vertices.len() as u32,
            vertex_count: vertex_count as u32,
            triangle_count: triangle_count as u32,
        };
        let kinds: Vec<u8> = self.kinds.iter().map(|&k| k as u8).collect();
        RecordWriter::new(&meta)
            .array::<u32>(self.vertices.as_flattened())
            .array::<u32>(&self.triangles)
            .array::<u8>(&kinds)
            .finish()
    }
}

impl Section for FinEdges {
    const KIND: SectionKind = SectionKind::FIN_EDGES;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let v = self.vertices.as_flattened().iter().max().map_or(0, |&m| m as usize + 1);
        let t = self.triangles.iter().max().map_or(0, |&m| m as usize + 1);
        self.encode_with_bounds(v, t)
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let e = m.edge_count as usize;
        let verts = r.array_exact::<u32>(0, checked_count(e, 2, "edge vertices")?, "edge vertices")?;
        let tris = r.array_exact::<u32>(1, e, "edge triangles")?;
        let kinds = r.array_exact::<u8>(2, e, "edge kinds")?;
        check_indices(&verts, m.vertex_count as usize, "edge vertices")?;
        check_indices(&tris, m.triangle_count as usize, "edge triangles")?;
        let kinds = kinds
            .iter()
            .enumerate()
            .map(|(i, &k)| match k {
                0 => Ok(FinEdgeKind::Border),
                1 => Ok(FinEdgeKind::FurBoundary),
                _ => Err(FormatError::invalid(format!("edge kind[{i}] = {k} is not 0 (border) or 1 (fur boundary)"))),
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(FinEdges {
            vertices: verts.chunks_exact(2).map(|c| [c[0], c[1]]).collect(),
            triangles: tris.into_owned(),
            kinds,
        })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "edges": self.vertices.len(),
            "border_edges": self.count(FinEdgeKind::Border),
            "fur_boundary_edges": self.count(FinEdgeKind::FurBoundary),
        })
    }
}
