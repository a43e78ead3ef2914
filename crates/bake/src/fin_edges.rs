//! Fin edge extraction (fur thesis §3.2, fig. 3.16): fins grow on mesh borders and on the borders
//! between furry and bare regions. An edge of a furry triangle carries a fin when no other furry
//! triangle shares it: either nothing else does (a border) or only bare triangles do.

use std::collections::HashMap;

use furbake_formats::sections::fin_edges::{FinEdgeKind, FinEdges};
use furbake_formats::sections::skin_mesh::SkinMesh;

/// Use counts of one undirected edge.
#[derive(Default, Clone, Copy)]
struct EdgeUse {
    furry: u32,
    bare: u32,
}

/// Finds the fin edges of `mesh`, in triangle order then corner order (deterministic).
pub fn find_fin_edges(mesh: &SkinMesh) -> FinEdges {
    let mut uses: HashMap<(u32, u32), EdgeUse> = HashMap::with_capacity(mesh.triangles.len() * 3 / 2);
    for (tri, &fur) in mesh.triangles.iter().zip(&mesh.fur_mask) {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let e = uses.entry((a.min(b), a.max(b))).or_default();
            if fur != 0 {
                e.furry += 1;
            } else {
                e.bare += 1;
            }
        }
    }
    let mut out = FinEdges::default();
    for (t, (tri, &fur)) in mesh.triangles.iter().zip(&mesh.fur_mask).enumerate() {
        if fur == 0 {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let e = uses[&(a.min(b), a.max(b))];
            let kind = match (e.furry, e.bare) {
                (1, 0) => FinEdgeKind::Border,
                (1, _) => FinEdgeKind::FurBoundary,
                _ => continue,
            };
            out.vertices.push([a, b]);
            out.triangles.push(t as u32);
            out.kinds.push(kind);
        }
    }
    out
}

/// Number of distinct undirected edges of `mesh` (E in the topology counts of docs/design.md).
pub fn count_edges(mesh: &SkinMesh) -> usize {
    let mut set = std::collections::HashSet::with_capacity(mesh.triangles.len() * 3 / 2);
    for tri in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            set.insert((a.min(b), a.max(b)));
        }
    }
    set.len()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2×1 strip of quads (4 triangles); `fur` marks which triangles are furry.
    fn strip(fur: [u8; 4]) -> SkinMesh {
        SkinMesh {
            positions: (0..6).map(|i| [(i % 3) as f32, (i / 3) as f32, 0.0]).collect(),
            normals: vec![[0.0, 0.0, 1.0]; 6],
            colors: vec![[1.0; 4]; 6],
            triangles: vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]],
            fur_mask: fur.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn all_furry_strip_has_only_border_fins() {
        let f = find_fin_edges(&strip([1, 1, 1, 1]));
        // The strip's outline: 2 + 2 (long sides) + 1 + 1 (short sides) = 6 border edges.
        assert_eq!(f.count(FinEdgeKind::Border), 6);
        assert_eq!(f.count(FinEdgeKind::FurBoundary), 0);
        assert_eq!(count_edges(&strip([1; 4])), 9);
    }

    #[test]
    fn furry_bare_boundary_gets_fins_on_the_furry_side() {
        let f = find_fin_edges(&strip([1, 1, 0, 0]));
        // Left quad furry: 3 border edges of its outline + the shared edge 1–4 as a boundary.
        assert_eq!(f.count(FinEdgeKind::Border), 3);
        assert_eq!(f.count(FinEdgeKind::FurBoundary), 1);
        let i = f.kinds.iter().position(|&k| k == FinEdgeKind::FurBoundary).unwrap();
        let [a, b] = f.vertices[i];
        assert_eq!((a.min(b), a.max(b)), (1, 4));
        assert!(f.triangles.iter().all(|&t| t < 2), "fins grow from furry triangles only");
    }
}
