//! Small skin meshes built in code, for tests, benchmarks and the accuracy report: the fur
//! thesis's grass patch (V=13, E=28, F=16), flat grids and icospheres. All triangles are furry.

use furbake_formats::sections::skin_mesh::SkinMesh;
use glam::Vec3;

fn mesh(positions: Vec<Vec3>, normals: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> SkinMesh {
    SkinMesh {
        colors: vec![[1.0; 4]; positions.len()],
        positions: positions.iter().map(|p| p.to_array()).collect(),
        normals: normals.iter().map(|n| n.to_array()).collect(),
        fur_mask: vec![1; triangles.len()],
        triangles,
        ..Default::default()
    }
}

/// The thesis's grass patch: a 3×3 vertex grid (spacing `cell_m`, in the XZ plane, normals +Y)
/// plus the centre of each of its 4 cells, each cell split into 4 triangles around its centre:
/// V = 13, E = 28, F = 16.
pub fn grass_patch(cell_m: f32) -> SkinMesh {
    let mut p: Vec<Vec3> = (0..9).map(|i| Vec3::new((i % 3) as f32 * cell_m, 0.0, (i / 3) as f32 * cell_m)).collect();
    let mut tris = Vec::new();
    for cz in 0..2u32 {
        for cx in 0..2u32 {
            let c = p.len() as u32;
            p.push(Vec3::new((cx as f32 + 0.5) * cell_m, 0.0, (cz as f32 + 0.5) * cell_m));
            let (a, b, d, e) = (cz * 3 + cx, cz * 3 + cx + 1, cz * 3 + cx + 4, cz * 3 + cx + 3);
            // Counter-clockwise seen from +Y.
            for [u, v] in [[a, e], [e, d], [d, b], [b, a]] {
                tris.push([c, u, v]);
            }
        }
    }
    let n = vec![Vec3::Y; p.len()];
    mesh(p, n, tris)
}

/// A flat `nx × nz` vertex grid in the XZ plane, spacing `cell_m`, normals +Y, two triangles
/// per cell: V = nx·nz, F = 2(nx−1)(nz−1).
pub fn grid(nx: u32, nz: u32, cell_m: f32) -> SkinMesh {
    let p: Vec<Vec3> =
        (0..nx * nz).map(|i| Vec3::new((i % nx) as f32 * cell_m, 0.0, (i / nx) as f32 * cell_m)).collect();
    let mut tris = Vec::new();
    for z in 0..nz.saturating_sub(1) {
        for x in 0..nx.saturating_sub(1) {
            let a = z * nx + x;
            tris.push([a, a + nx, a + 1]);
            tris.push([a + 1, a + nx, a + nx + 1]);
        }
    }
    let n = vec![Vec3::Y; p.len()];
    mesh(p, n, tris)
}

/// An icosphere of `radius_m` after `subdivisions` midpoint subdivisions (0: the icosahedron,
/// V=12, F=20; 1: V=42, F=80; 2: V=162, F=320), outward unit normals.
pub fn icosphere(subdivisions: u32, radius_m: f32) -> SkinMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut p: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|c| Vec3::from(*c).normalize())
    .collect();
    let mut tris: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(tris.len() * 4);
        for tri in &tris {
            let mut m = [0u32; 3];
            for c in 0..3 {
                let (a, b) = (tri[c], tri[(c + 1) % 3]);
                m[c] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                    (p.len() - 1) as u32
                });
            }
            next.extend([[tri[0], m[0], m[2]], [tri[1], m[1], m[0]], [tri[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        tris = next;
    }
    let n = p.clone();
    mesh(p.iter().map(|q| *q * radius_m).collect(), n, tris)
}
