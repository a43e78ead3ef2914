//! Per-triangle UV mapping (fur thesis §3.2, fig. 3.18–3.19). Each triangle is laid into the
//! texture plane on its own: its first edge along +u, its third vertex placed by trigonometry so
//! all three edge lengths are preserved, everything scaled so that `repeat_m` metres of surface
//! span one texture repeat (a constant texel density on every triangle). A seeded random offset
//! in [0, 1)² per triangle breaks the pattern that identical starting corners would show.

use furbake_formats::sections::skin_mesh::SkinMesh;
use furbake_formats::sections::triangle_uv_map::TriangleUvMap;
use glam::Vec3;
use rayon::prelude::*;

use crate::rng::{SplitMix64, derive_seed, stage};

/// Settings of the UV stage.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct UvSettings {
    /// Metres of surface per texture repeat; `None` = 4 × the fur length.
    pub repeat_m: Option<f32>,
    /// Shift each triangle's map by a random offset (thesis fig. 3.19). Default true.
    pub random_offset: bool,
}

impl Default for UvSettings {
    fn default() -> Self {
        UvSettings { repeat_m: None, random_offset: true }
    }
}

/// Maps every triangle of `mesh` alone, preserving edge lengths, with `repeat_m` metres per repeat.
pub fn map_triangles(mesh: &SkinMesh, repeat_m: f32, random_offset: bool, seed: u64) -> TriangleUvMap {
    let inv = 1.0 / repeat_m;
    let corners = mesh
        .triangles
        .par_iter()
        .enumerate()
        .map(|(t, tri)| {
            let [a, b, c] = tri.map(|i| Vec3::from(mesh.positions[i as usize]));
            let mut uv = layout_triangle(a, b, c).map(|p| [p[0] * inv, p[1] * inv]);
            if random_offset {
                let mut rng = SplitMix64::new(derive_seed(seed, stage::UV_OFFSETS, t as u64));
                let (du, dv) = (rng.next_f32(), rng.next_f32());
                for p in &mut uv {
                    p[0] += du;
                    p[1] += dv;
                }
            }
            uv
        })
        .collect();
    TriangleUvMap { repeat_m, seed, corners }
}

/// Places triangle `abc` in the plane: `a` at the origin, `b` on +u, `c` above the u axis, so that
/// |ab|, |bc| and |ca| keep their lengths (in metres).
pub fn layout_triangle(a: Vec3, b: Vec3, c: Vec3) -> [[f32; 2]; 3] {
    let ab = b - a;
    let ac = c - a;
    let len_ab = ab.length();
    if len_ab <= f32::MIN_POSITIVE {
        return [[0.0, 0.0], [0.0, 0.0], [0.0, ac.length()]];
    }
    let axis = ab / len_ab;
    let cu = ac.dot(axis);
    let cv = (ac - axis * cu).length();
    [[0.0, 0.0], [len_ab, 0.0], [cu, cv]]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dist(p: [f32; 2], q: [f32; 2]) -> f32 {
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
    }

    #[test]
    fn edge_lengths_are_preserved_for_any_triangle() {
        let mut rng = SplitMix64::new(5);
        let mut checked = 0;
        for _ in 0..1000 {
            let mut v =
                || Vec3::new(rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0);
            let (a, b, c) = (v(), v(), v());
            let uv = layout_triangle(a, b, c);
            for (i, j, pi, pj) in [(0, 1, a, b), (1, 2, b, c), (2, 0, c, a)] {
                let want = (pi - pj).length();
                assert!((dist(uv[i], uv[j]) - want).abs() <= 1e-4 * (1.0 + want), "edge {i}{j}");
                checked += 1;
            }
        }
        assert_eq!(checked, 3000);
    }

    #[test]
    fn sliver_triangles_stay_finite() {
        let uv = layout_triangle(Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, 1e-9, 0.0));
        assert!(uv.iter().flatten().all(|x| x.is_finite()));
        let uv = layout_triangle(Vec3::ZERO, Vec3::ZERO, Vec3::X);
        assert!(uv.iter().flatten().all(|x| x.is_finite()));
    }
}
