//! Geometry built once from a pack's sections for drawing: the skin's triangle corners
//! de-indexed with their shell UVs (the shell UV map is per triangle corner, fur thesis §3.2,
//! fig. 3.18–3.19), fin quads on the fin edges (§3.2, fig. 3.16) and the interior edges that may
//! carry a silhouette fin (§4.1). The builders trust their inputs to belong together
//! (`furbake_formats::check_consistency`: UV map and fin edges index this skin).

use furbake_formats::sections::fin_edges::FinEdges;
use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use glam::Vec3;

use crate::layout::{FinVertex, SilhouetteEdge, SurfaceVertex};

/// Every triangle corner of `mesh`, furry triangles first (so the shells draw the prefix
/// `0..3·furry_triangles` of the same buffer the skin draws whole), with its shell UV from
/// `uv_map`. Returns the corners and the furry triangle count.
pub fn surface_vertices(mesh: &SkinMesh, uv_map: &TriangleUvMap) -> (Vec<SurfaceVertex>, u32) {
    let m = mesh;
    let mut order: Vec<usize> = (0..m.triangles.len()).filter(|&t| m.fur_mask[t] != 0).collect();
    let furry = order.len() as u32;
    order.extend((0..m.triangles.len()).filter(|&t| m.fur_mask[t] == 0));
    let mut out = Vec::with_capacity(order.len() * 3);
    for t in order {
        for (c, &vi) in m.triangles[t].iter().enumerate() {
            let i = vi as usize;
            out.push(SurfaceVertex {
                position: m.positions[i],
                normal: m.normals[i],
                color: m.colors[i],
                uv: uv_map.corners[t][c],
                vertex_index: vi,
                flags: u32::from(m.fur_mask[t] != 0),
                corner_index: (3 * t + c) as u32,
            });
        }
    }
    (out, furry)
}

/// A sphere holding `mesh` and fur `fur_length_m` long on it: the centre of the skin's bounding
/// box, radius = the farthest vertex from it plus the fur length (metres, the pack's frame).
pub fn bounding_sphere(mesh: &SkinMesh, fur_length_m: f32) -> ([f32; 3], f32) {
    let (lo, hi) = mesh.bounds();
    let center = (Vec3::from(lo) + Vec3::from(hi)) * 0.5;
    let far = mesh.positions.iter().map(|&p| Vec3::from(p).distance(center)).fold(0.0f32, f32::max);
    (center.to_array(), far + fur_length_m)
}

/// Six corners (two triangles) per fin edge of `edges`: roots at the edge ends, tips at height 1.
pub fn fin_vertices(mesh: &SkinMesh, edges: &FinEdges) -> Vec<FinVertex> {
    let m = mesh;
    let mut out = Vec::with_capacity(edges.vertices.len() * 6);
    for (&[a, b], &t) in edges.vertices.iter().zip(&edges.triangles) {
        let [i, j, k] = m.triangles[t as usize].map(|x| Vec3::from(m.positions[x as usize]));
        let face_normal = (j - i).cross(k - i).normalize_or_zero().to_array();
        let (pa, pb) = (Vec3::from(m.positions[a as usize]), Vec3::from(m.positions[b as usize]));
        let length = pa.distance(pb);
        // The edge ends' corners in triangle t (an edge of t: both ends are among its corners).
        let corner_of = |v: u32| {
            let c = m.triangles[t as usize].iter().position(|&x| x == v).unwrap_or(0);
            3 * t + c as u32
        };
        let corner = |v: u32, along_m: f32, height: f32| FinVertex {
            position: m.positions[v as usize],
            normal: m.normals[v as usize],
            face_normal,
            color: m.colors[v as usize],
            along_m,
            height,
            vertex_index: v,
            corner_index: corner_of(v),
            face_vertices: m.triangles[t as usize],
        };
        let (a0, b0, a1, b1) =
            (corner(a, 0.0, 0.0), corner(b, length, 0.0), corner(a, 0.0, 1.0), corner(b, length, 1.0));
        out.extend_from_slice(&[a0, b0, b1, a0, b1, a1]);
    }
    out
}

/// The interior edges of `mesh` that may carry a silhouette fin: edges shared by exactly two
/// furry triangles, minus the pack's always-on fin edges (`fin_edges`). Sorted by (a, b) of
/// their first occurrence, deterministic.
pub fn interior_edges(mesh: &SkinMesh, fin_edges: Option<&FinEdges>) -> Vec<SilhouetteEdge> {
    use std::collections::{HashMap, HashSet};
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let fins: HashSet<(u32, u32)> =
        fin_edges.map(|f| f.vertices.iter().map(|&[a, b]| key(a, b)).collect()).unwrap_or_default();
    // Edge → the (triangle, corner of the edge's start) of each furry triangle using it.
    let mut faces: HashMap<(u32, u32), Vec<(u32, usize)>> = HashMap::with_capacity(mesh.triangles.len() * 2);
    let mut order = Vec::with_capacity(mesh.triangles.len() * 2);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if mesh.fur_mask.get(t).copied().unwrap_or(0) == 0 || tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            continue;
        }
        for c in 0..3 {
            let k = key(tri[c], tri[(c + 1) % 3]);
            let entry = faces.entry(k).or_default();
            if entry.is_empty() {
                order.push(k);
            }
            entry.push((t as u32, c));
        }
    }
    let mut out = Vec::new();
    for k in order {
        let list = &faces[&k];
        if list.len() != 2 || fins.contains(&k) {
            continue;
        }
        let (t0, c0) = list[0];
        let (t1, c1) = list[1];
        let tri0 = mesh.triangles[t0 as usize];
        let tri1 = mesh.triangles[t1 as usize];
        let (a, b, c) = (tri0[c0], tri0[(c0 + 1) % 3], tri0[(c0 + 2) % 3]);
        let d = tri1[(c1 + 2) % 3];
        if c == d {
            continue; // two triangles on the same three vertices
        }
        // Face 1 starts its edge at b (consistent orientation) or at a (flipped).
        let flags = u32::from(tri1[c1] == a);
        out.push(SilhouetteEdge {
            a,
            b,
            c,
            d,
            corner_a: 3 * t0 + c0 as u32,
            corner_b: 3 * t0 + ((c0 + 1) % 3) as u32,
            flags,
            pad0: 0,
        });
    }
    out
}
