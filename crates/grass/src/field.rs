//! Blade field bake (grass thesis §3.2.2, §4.3): blades scattered over the furry triangles of a
//! mesh or terrain at a density per square metre, each with a random orientation and height, then
//! grouped into clusters (the cells of a regular `xz` grid) and given their four bilinear weights
//! over the cluster's corners (eq. 3.6–3.8). Every triangle draws from its own seeded stream, so
//! the field is identical whatever the thread count.

use furbake_formats::sections::blade_field::{BladeField, BladeFieldParams, ClusterGrid, bilinear_weights};
use furbake_formats::sections::skin_mesh::SkinMesh;
use glam::Vec3;
use rayon::prelude::*;

use crate::GrassError;
use crate::rng::{SplitMix64, derive_seed};

/// Largest number of blades a bake may produce.
pub const MAX_BLADES: u64 = 1 << 26;
/// Largest number of clusters.
pub const MAX_CLUSTERS: u64 = 1 << 24;
const STAGE_SCATTER: u64 = 0x0067_7261_7373; // "grass"

/// Blade field settings.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct BladeFieldSettings {
    /// Blades per square metre of furry surface. Default 400.
    pub density_per_m2: f32,
    /// Seed. Default 1.
    pub seed: u64,
    /// Smallest blade height, metres (the height scale: metres per blade length). Default 0.15.
    pub height_min_m: f32,
    /// Largest blade height, metres. Default 0.35.
    pub height_max_m: f32,
    /// Cluster (grid cell) edge length, metres. Default 1.0.
    pub cluster_size_m: f32,
}

impl Default for BladeFieldSettings {
    fn default() -> Self {
        BladeFieldSettings {
            density_per_m2: 400.0,
            seed: 1,
            height_min_m: 0.15,
            height_max_m: 0.35,
            cluster_size_m: 1.0,
        }
    }
}

/// Scatters blades over the furry triangles of `mesh` (every triangle when the fur mask is all 0
/// is *not* assumed: bare triangles get no grass).
pub fn scatter_blades(mesh: &SkinMesh, settings: &BladeFieldSettings) -> Result<BladeField, GrassError> {
    let s = settings;
    let positive = |v: f32| v.is_finite() && v > 0.0;
    let valid = s.density_per_m2.is_finite()
        && s.density_per_m2 >= 0.0
        && positive(s.height_min_m)
        && positive(s.height_max_m)
        && s.height_max_m >= s.height_min_m
        && positive(s.cluster_size_m);
    if !valid {
        return Err(GrassError::parameter(format!("blade field settings {s:?} out of range")));
    }
    if mesh.fur_mask.len() != mesh.triangles.len() {
        return Err(GrassError::Mesh {
            what: format!("{} fur mask entries for {} triangles", mesh.fur_mask.len(), mesh.triangles.len()),
        });
    }
    let vcount = mesh.positions.len();
    let mut tris = Vec::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if mesh.fur_mask[t] == 0 {
            continue;
        }
        if tri.iter().any(|&i| i as usize >= vcount) {
            return Err(GrassError::Mesh { what: format!("triangle {t} has an index past {vcount} vertices") });
        }
        let p = tri.map(|i| Vec3::from(mesh.positions[i as usize]));
        if !p.iter().all(|v| v.is_finite()) {
            return Err(GrassError::Mesh { what: format!("triangle {t} has a non-finite vertex") });
        }
        tris.push((t as u64, p));
    }
    let area: f64 = tris.iter().map(|(_, p)| 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64).sum();
    let expected = area * s.density_per_m2 as f64;
    if expected > MAX_BLADES as f64 {
        return Err(GrassError::Limit { what: "blades", value: expected as u64, limit: MAX_BLADES });
    }
    // Cluster grid over the furry triangles' xz bounds.
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (_, p) in &tris {
        for v in p {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if tris.is_empty() {
        (lo, hi) = (Vec3::ZERO, Vec3::ZERO);
    }
    let cells = |extent: f32| ((extent / s.cluster_size_m).ceil() as u64).max(1);
    let (cx, cz) = (cells(hi.x - lo.x), cells(hi.z - lo.z));
    if cx * cz > MAX_CLUSTERS {
        return Err(GrassError::Limit { what: "clusters", value: cx * cz, limit: MAX_CLUSTERS });
    }
    let grid = ClusterGrid {
        origin_m: [lo.x, lo.z],
        cell_size_m: [s.cluster_size_m; 2],
        cells_x: cx as u32,
        cells_z: cz as u32,
    };
    // Scatter, one seeded stream per triangle.
    let per_tri: Vec<Vec<(Vec3, f32, f32)>> = tris
        .par_iter()
        .map(|(t, p)| {
            let mut rng = SplitMix64::new(derive_seed(s.seed, STAGE_SCATTER, *t));
            let a = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() as f64 * s.density_per_m2 as f64;
            let n = (a + rng.next_f32() as f64).floor() as usize;
            (0..n)
                .map(|_| {
                    let (r1, r2) = (rng.next_f32().sqrt(), rng.next_f32());
                    let pos = p[0] * (1.0 - r1) + p[1] * (r1 * (1.0 - r2)) + p[2] * (r1 * r2);
                    let yaw = rng.next_f32() * std::f32::consts::TAU;
                    let h = s.height_min_m + (s.height_max_m - s.height_min_m) * rng.next_f32();
                    (pos, yaw, h)
                })
                .collect()
        })
        .collect();
    let mut blades: Vec<(u32, Vec3, f32, f32, [f32; 4])> = per_tri
        .into_iter()
        .flatten()
        .map(|(pos, yaw, h)| {
            let (c, [u, v]) = grid.locate(pos.x, pos.z);
            (c, pos, yaw, h, bilinear_weights(u, v))
        })
        .collect();
    blades.sort_by_key(|b| b.0); // stable: clusters contiguous, scatter order inside
    Ok(BladeField {
        grid,
        params: BladeFieldParams {
            density_per_m2: s.density_per_m2,
            seed: s.seed,
            height_min_m: s.height_min_m,
            height_max_m: s.height_max_m,
        },
        positions: blades.iter().map(|b| b.1.to_array()).collect(),
        yaw_rad: blades.iter().map(|b| b.2).collect(),
        height_scale: blades.iter().map(|b| b.3).collect(),
        cluster: blades.iter().map(|b| b.0).collect(),
        weights: blades.iter().map(|b| b.4).collect(),
    })
}

/// A flat ground grid in the `xz` plane at `y = 0`, centred on the origin, `size_m` wide, cut into
/// `cells` quads (two triangles each, all furry, normals `+y`) — a terrain for tests and demos.
pub fn ground_grid_mesh(size_m: [f32; 2], cells: [u32; 2]) -> SkinMesh {
    let (nx, nz) = (cells[0].max(1), cells[1].max(1));
    let mut m = SkinMesh::default();
    for j in 0..=nz {
        for i in 0..=nx {
            let x = (i as f32 / nx as f32 - 0.5) * size_m[0];
            let z = (j as f32 / nz as f32 - 0.5) * size_m[1];
            m.positions.push([x, 0.0, z]);
            m.normals.push([0.0, 1.0, 0.0]);
            m.colors.push([1.0; 4]);
        }
    }
    let row = nx + 1;
    for j in 0..nz {
        for i in 0..nx {
            let a = j * row + i;
            m.triangles.push([a, a + row, a + 1]);
            m.triangles.push([a + 1, a + row, a + row + 1]);
            m.fur_mask.extend([1, 1]);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::Section;

    #[test]
    fn density_grid_and_weights_are_right() {
        let mesh = ground_grid_mesh([10.0, 6.0], [5, 3]);
        let s = BladeFieldSettings { density_per_m2: 50.0, cluster_size_m: 2.0, ..Default::default() };
        let f = scatter_blades(&mesh, &s).expect("scatters");
        let n = f.blade_count() as f64;
        assert!((n - 3000.0).abs() < 60.0, "{n} blades for 60 m² at 50/m²");
        assert_eq!((f.grid.cells_x, f.grid.cells_z), (5, 3));
        let mut checked = 0;
        for b in 0..f.blade_count() {
            let p = f.positions[b];
            assert!(p[0].abs() <= 5.0 && p[2].abs() <= 3.0 && p[1] == 0.0);
            assert!((0.15..=0.35).contains(&f.height_scale[b]));
            // Weights reproduce the blade's own position from the corner positions (eq. 3.6).
            let corners = f.grid.corner_indices(f.cluster[b]);
            let mut x = 0.0;
            let mut z = 0.0;
            for (k, corner) in corners.iter().enumerate() {
                let c = f.grid.corner_position(*corner);
                x += f.weights[b][k] * c[0];
                z += f.weights[b][k] * c[1];
            }
            assert!((x - p[0]).abs() < 1e-4 && (z - p[2]).abs() < 1e-4, "blade {b}");
            checked += 1;
        }
        assert_eq!(checked, f.blade_count());
        assert!(f.cluster.windows(2).all(|w| w[0] <= w[1]), "blades are grouped by cluster");
        assert_eq!(BladeField::decode(&f.encode()).expect("decodes"), f);
    }

    #[test]
    fn scatter_is_seeded_thread_independent_and_respects_the_mask() {
        let mut mesh = ground_grid_mesh([4.0, 4.0], [4, 4]);
        let s = BladeFieldSettings { density_per_m2: 30.0, ..Default::default() };
        let a = scatter_blades(&mesh, &s).expect("scatters");
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
        let b = pool.install(|| scatter_blades(&mesh, &s)).expect("scatters");
        assert_eq!(a, b);
        let c = scatter_blades(&mesh, &BladeFieldSettings { seed: 2, ..s }).expect("scatters");
        assert_ne!(a.positions, c.positions);
        // Bare triangles get no grass: mark the x < 0 half bare.
        for (t, tri) in mesh.triangles.clone().iter().enumerate() {
            let cx: f32 = tri.iter().map(|&i| mesh.positions[i as usize][0]).sum::<f32>() / 3.0;
            mesh.fur_mask[t] = (cx > 0.0) as u8;
        }
        let half = scatter_blades(&mesh, &s).expect("scatters");
        assert!(half.positions.iter().all(|p| p[0] >= 0.0));
        assert!(half.blade_count() > 100);
        mesh.fur_mask.pop();
        assert!(scatter_blades(&mesh, &s).is_err(), "mask length mismatch");
        assert!(scatter_blades(&ground_grid_mesh([1e4, 1e4], [1, 1]), &s).is_err(), "too many blades");
    }
}
