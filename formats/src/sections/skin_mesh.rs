//! The skin: the imported mesh after node transforms, welding and normal generation — the surface
//! the shells are extruded from and the topology is built on. Struct of arrays, one entry per
//! welded vertex or per triangle.

use serde::{Deserialize, Serialize};

use super::{Section, check_coordinates, check_indices, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// The welded, triangulated skin mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SkinMesh {
    /// Vertex positions in metres (scene units), `xyz` per welded vertex.
    pub positions: Vec<[f32; 3]>,
    /// Unit vertex normals, area-weighted over the welded fan when the input had none.
    pub normals: Vec<[f32; 3]>,
    /// Linear RGBA vertex colour (vertex colour × material base colour factor; white when absent).
    pub colors: Vec<[f32; 4]>,
    /// Triangles as welded vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle: 1 when it carries fur, 0 when bare.
    pub fur_mask: Vec<u8>,
    /// Per triangle corner: the input's TEXCOORD_0 (empty when the input had none).
    pub corner_texcoords: Vec<[[f32; 2]; 3]>,
    /// Statistics of the import that produced the mesh.
    pub stats: SkinMeshStats,
}

/// Import statistics kept with the mesh (shown by `inspect`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SkinMeshStats {
    /// Mesh primitives read from the default scene.
    pub primitives: u32,
    /// Vertices before welding.
    pub input_vertices: u32,
    /// Triangles skipped because they had zero area or repeated a vertex.
    pub degenerate_triangles_skipped: u32,
    /// Whether normals were generated (at least one primitive had none).
    pub generated_normals: bool,
    /// Whether any primitive had vertex colours.
    pub had_vertex_colors: bool,
    /// Welding tolerance used, in metres.
    pub weld_tolerance_m: f32,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    vertex_count: u32,
    triangle_count: u32,
    has_corner_texcoords: bool,
    stats: SkinMeshStats,
}

impl SkinMesh {
    /// Axis-aligned bounds `(min, max)` of the positions (zeros for an empty mesh).
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        if self.positions.is_empty() {
            return ([0.0; 3], [0.0; 3]);
        }
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Number of triangles that carry fur.
    pub fn furry_triangles(&self) -> usize {
        self.fur_mask.iter().filter(|&&m| m != 0).count()
    }
}

impl Section for SkinMesh {
    const KIND: SectionKind = SectionKind::SKIN_MESH;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta {
            vertex_count: self.positions.len() as u32,
            triangle_count: self.triangles.len() as u32,
            has_corner_texcoords: !self.corner_texcoords.is_empty(),
            stats: self.stats.clone(),
        };
        RecordWriter::new(&meta)
            .array::<f32>(self.positions.as_flattened())
            .array::<f32>(self.normals.as_flattened())
            .array::<f32>(self.colors.as_flattened())
            .array::<u32>(self.triangles.as_flattened())
            .array::<u8>(&self.fur_mask)
            .array::<f32>(self.corner_texcoords.as_flattened().as_flattened())
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        let v = m.vertex_count as usize;
        let f = m.triangle_count as usize;
        let positions = r.array_exact::<f32>(0, checked_count(v, 3, "positions")?, "positions")?;
        let normals = r.array_exact::<f32>(1, checked_count(v, 3, "normals")?, "normals")?;
        let colors = r.array_exact::<f32>(2, checked_count(v, 4, "colors")?, "colors")?;
        let tris = r.array_exact::<u32>(3, checked_count(f, 3, "triangles")?, "triangles")?;
        let fur = r.array_exact::<u8>(4, f, "fur_mask")?;
        let uv_len = if m.has_corner_texcoords { checked_count(f, 6, "corner_texcoords")? } else { 0 };
        let uvs = r.array_exact::<f32>(5, uv_len, "corner_texcoords")?;
        check_coordinates(&positions, "positions")?;
        // Unit normals (the importer normalises; a vertex of only skipped triangles keeps a unit
        // fallback), colours in [0, 1] (glTF colours and base colours are normalised).
        check_range(&normals, -1.0 - 1e-3, 1.0 + 1e-3, "normals")?;
        if let Some(i) =
            normals.chunks_exact(3).position(|n| ((n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) - 1.0).abs() > 1e-2)
        {
            return Err(FormatError::invalid(format!("normals[{i}] is not a unit vector")));
        }
        check_range(&colors, 0.0, 1.0, "colors")?;
        check_coordinates(&uvs, "corner_texcoords")?;
        check_indices(&tris, v, "triangles")?;
        if let Some(i) = fur.iter().position(|&x| x > 1) {
            return Err(FormatError::invalid(format!("fur_mask[{i}] = {} (must be 0 or 1)", fur[i])));
        }
        let tolerance = m.stats.weld_tolerance_m;
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(FormatError::invalid(format!(
                "stats.weld_tolerance_m = {tolerance} (must be a finite distance, at least 0)"
            )));
        }
        Ok(SkinMesh {
            positions: positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            normals: normals.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            colors: colors.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
            triangles: tris.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            fur_mask: fur.into_owned(),
            corner_texcoords: uvs.chunks_exact(6).map(|c| [[c[0], c[1]], [c[2], c[3]], [c[4], c[5]]]).collect(),
            stats: m.stats,
        })
    }

    fn summary(&self) -> serde_json::Value {
        let (lo, hi) = self.bounds();
        serde_json::json!({
            "vertices": self.positions.len(),
            "triangles": self.triangles.len(),
            "furry_triangles": self.furry_triangles(),
            "bounds_min_m": lo,
            "bounds_max_m": hi,
            "has_corner_texcoords": !self.corner_texcoords.is_empty(),
            "primitives": self.stats.primitives,
            "input_vertices": self.stats.input_vertices,
            "degenerate_triangles_skipped": self.stats.degenerate_triangles_skipped,
            "generated_normals": self.stats.generated_normals,
            "had_vertex_colors": self.stats.had_vertex_colors,
            "weld_tolerance_m": self.stats.weld_tolerance_m,
        })
    }
}
