//! Welding the triangle soup into the skin: positions within the weld tolerance become one vertex
//! (so UV seams and hard-normal splits do not cut the surface the fur thesis's topologies are
//! built on, §3.4.1), degenerate triangles are skipped and counted, and per-vertex normals and
//! colours are averaged over each welded vertex's members (area-weighted face normals where the
//! file had none). Deterministic: a spatial hash with cells one tolerance wide, neighbour cells
//! searched, the lowest matching welded index wins, vertex order = first occurrence.
//!
//! Skinning stays consistent (glTF 2.0 specification, "Skins", "Morph Targets"): two vertices weld
//! only when their influences agree (same binds, weights within [`WEIGHT_TOLERANCE`]) and their
//! morph deltas agree (same group, deltas within the weld tolerance), so every welded vertex
//! carries its members' one set.

use std::collections::HashMap;

use furbake_formats::sections::skin_mesh::{SkinMesh, SkinMeshStats};
use glam::DVec3;

use crate::WeldTolerance;
use crate::scene::Soup;

/// A triangle is degenerate when twice its area is at most this fraction of its longest edge
/// squared (the sine of its largest angle is ~0 at `f32` precision), or when two corners weld
/// to the same vertex.
const DEGENERATE_SINE: f64 = 1e-10;

/// Largest difference of two influence weights that still counts as the same influence.
pub(crate) const WEIGHT_TOLERANCE: f32 = 1e-4;

/// The result of welding, before it is wrapped with file-level data.
pub(crate) struct Welded {
    pub mesh: SkinMesh,
    pub warnings: Vec<String>,
    /// A raw vertex of each welded vertex (its first member).
    pub representatives: Vec<u32>,
}

/// Whether raw vertices `a` and `b` may weld: their influences and morph deltas agree.
fn same_rig(soup: &Soup, a: usize, b: usize, tol: f64) -> bool {
    if !soup.influences.is_empty() {
        let (x, y) = (&soup.influences[a], &soup.influences[b]);
        if x.iter().zip(y).any(|(p, q)| p.0 != q.0 && (p.1 > 0.0 || q.1 > 0.0) || (p.1 - q.1).abs() > WEIGHT_TOLERANCE)
        {
            return false;
        }
    }
    if soup.morph_group.is_empty() {
        return true;
    }
    let (g, h) = (soup.morph_group[a], soup.morph_group[b]);
    if g != h {
        return false;
    }
    if g == crate::animation::NO_GROUP {
        return true;
    }
    // Same group: both vertices store the group's 2t deltas at their offsets.
    let t2 = soup.morph_group_len.get(g as usize).copied().unwrap_or(0);
    let (sa, sb) = (soup.morph_at[a] as usize, soup.morph_at[b] as usize);
    soup.morph_deltas[sa..sa + t2].iter().zip(&soup.morph_deltas[sb..sb + t2]).enumerate().all(|(k, (p, q))| {
        let limit = if k < t2 / 2 { tol + 1e-9 } else { 1e-3 };
        (0..3).all(|i| f64::from((p[i] - q[i]).abs()) <= limit)
    })
}

/// Why welding produced no mesh.
pub(crate) struct NoTriangles {
    pub details: String,
}

/// Maps each raw vertex to a welded vertex. `tol == 0` welds only identical positions.
/// Returns `(raw → welded, representative raw vertex per welded vertex)`; unused raw vertices
/// map to `u32::MAX`.
fn weld_positions(
    positions: &[DVec3],
    used: &[bool],
    tol: f64,
    compatible: &dyn Fn(usize, usize) -> bool,
) -> (Vec<u32>, Vec<u32>) {
    let mut map = vec![u32::MAX; positions.len()];
    let mut reps: Vec<u32> = Vec::new();
    if tol > 0.0 {
        let inv = 1.0 / tol;
        let tol2 = tol * tol;
        let cell = |p: DVec3| -> [i64; 3] {
            let c = (p * inv).floor();
            // `as` saturates for out-of-range values; saturated keys only cost extra distance checks.
            [c.x as i64, c.y as i64, c.z as i64]
        };
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, &p) in positions.iter().enumerate() {
            if !used[i] {
                continue;
            }
            let k = cell(p);
            let mut best = u32::MAX;
            for dx in -1i64..=1 {
                for dy in -1i64..=1 {
                    for dz in -1i64..=1 {
                        let key = [k[0].saturating_add(dx), k[1].saturating_add(dy), k[2].saturating_add(dz)];
                        if let Some(list) = grid.get(&key) {
                            for &w in list {
                                let r = reps[w as usize] as usize;
                                if w < best && positions[r].distance_squared(p) <= tol2 && compatible(r, i) {
                                    best = w;
                                }
                            }
                        }
                    }
                }
            }
            if best == u32::MAX {
                best = reps.len() as u32;
                reps.push(i as u32);
                grid.entry(k).or_default().push(best);
            }
            map[i] = best;
        }
    } else {
        let key = |p: DVec3| p.to_array().map(|x| if x == 0.0 { 0u64 } else { x.to_bits() });
        let mut exact: HashMap<[u64; 3], Vec<u32>> = HashMap::new();
        for (i, &p) in positions.iter().enumerate() {
            if !used[i] {
                continue;
            }
            let list = exact.entry(key(p)).or_default();
            let w = match list.iter().find(|&&w| compatible(reps[w as usize] as usize, i)) {
                Some(&w) => w,
                None => {
                    let w = reps.len() as u32;
                    reps.push(i as u32);
                    list.push(w);
                    w
                }
            };
            map[i] = w;
        }
    }
    (map, reps)
}

/// Welds `soup` with `tolerance` and builds the skin mesh.
pub(crate) fn weld_soup(soup: &Soup, tolerance: WeldTolerance) -> Result<Welded, NoTriangles> {
    let mut warnings = Vec::new();
    let mut used = vec![false; soup.positions.len()];
    for t in &soup.triangles {
        for &i in t {
            used[i as usize] = true;
        }
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for (p, _) in soup.positions.iter().zip(&used).filter(|(_, u)| **u) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if soup.triangles.is_empty() {
        return Err(NoTriangles {
            details: format!(
                "{} triangle primitives, {} point/line primitives skipped",
                soup.primitives, soup.skipped_primitives
            ),
        });
    }
    let diagonal = (hi - lo).length();
    let tol = match tolerance {
        WeldTolerance::Relative(f) => f64::from(f) * diagonal,
        WeldTolerance::AbsoluteM(m) => f64::from(m),
    };
    let (map, reps) = weld_positions(&soup.positions, &used, tol, &|a, b| same_rig(soup, a, b, tol));

    // Triangles over welded vertices, degenerate ones skipped.
    let mut kept: Vec<usize> = Vec::with_capacity(soup.triangles.len());
    let mut degenerate = 0u32;
    let mut face_cross: Vec<DVec3> = Vec::with_capacity(soup.triangles.len());
    for (t, raw) in soup.triangles.iter().enumerate() {
        let w = raw.map(|i| map[i as usize]);
        if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
            degenerate += 1;
            continue;
        }
        let p = w.map(|i| soup.positions[reps[i as usize] as usize]);
        let cross = (p[1] - p[0]).cross(p[2] - p[0]);
        let longest2 = p[0].distance_squared(p[1]).max(p[1].distance_squared(p[2])).max(p[2].distance_squared(p[0]));
        // `partial_cmp` so that a NaN length also counts as degenerate.
        if cross.length().partial_cmp(&(DEGENERATE_SINE * longest2)) != Some(std::cmp::Ordering::Greater) {
            degenerate += 1;
            continue;
        }
        kept.push(t);
        face_cross.push(cross);
    }
    if kept.is_empty() {
        return Err(NoTriangles {
            details: format!(
                "all {} triangles of {} primitives are degenerate after welding with tolerance {tol:e}",
                soup.triangles.len(),
                soup.primitives
            ),
        });
    }

    // Compact: keep welded vertices used by kept triangles, in first-occurrence order.
    let mut referenced = vec![false; reps.len()];
    for &t in &kept {
        for &i in &soup.triangles[t] {
            referenced[map[i as usize] as usize] = true;
        }
    }
    let mut new_index = vec![u32::MAX; reps.len()];
    let mut count = 0u32;
    for (w, &r) in referenced.iter().enumerate() {
        if r {
            new_index[w] = count;
            count += 1;
        }
    }
    let v = count as usize;
    let dropped = reps.len() - v;
    if dropped > 0 {
        warnings.push(format!("{dropped} vertices used only by degenerate triangles were dropped"));
    }
    let raw_to_final = |i: u32| new_index[map[i as usize] as usize];

    let mut positions = vec![[0.0f32; 3]; v];
    for (w, &r) in reps.iter().enumerate() {
        if new_index[w] != u32::MAX {
            positions[new_index[w] as usize] = soup.positions[r as usize].as_vec3().to_array();
        }
    }
    let triangles: Vec<[u32; 3]> = kept.iter().map(|&t| soup.triangles[t].map(raw_to_final)).collect();

    // Per-vertex sums over welded members.
    let mut file_normal = vec![DVec3::ZERO; v];
    let mut has_file_normal = vec![false; v];
    let mut color_sum = vec![[0.0f64; 4]; v];
    let mut members = vec![0u32; v];
    for (i, &u) in used.iter().enumerate() {
        if !u {
            continue;
        }
        let f = new_index[map[i] as usize];
        if f == u32::MAX {
            continue;
        }
        let f = f as usize;
        if let Some(n) = soup.normals[i] {
            file_normal[f] += n;
            has_file_normal[f] = true;
        }
        for (s, c) in color_sum[f].iter_mut().zip(soup.colors[i]) {
            *s += f64::from(c);
        }
        members[f] += 1;
    }
    let mut area_normal = vec![DVec3::ZERO; v];
    let mut first_face = vec![DVec3::ZERO; v];
    for (t, cross) in triangles.iter().zip(&face_cross) {
        for &i in t {
            area_normal[i as usize] += *cross;
            if first_face[i as usize] == DVec3::ZERO {
                first_face[i as usize] = cross.normalize_or_zero();
            }
        }
    }
    let mut generated = 0usize;
    let mut fallbacks = 0usize;
    let normals: Vec<[f32; 3]> = (0..v)
        .map(|i| {
            let from_file = if has_file_normal[i] { file_normal[i].normalize_or_zero() } else { DVec3::ZERO };
            let n = if from_file != DVec3::ZERO {
                from_file
            } else {
                generated += 1;
                let a = area_normal[i].normalize_or_zero();
                if a != DVec3::ZERO {
                    a
                } else {
                    fallbacks += 1;
                    // Every kept triangle has a non-zero cross product, so a vertex that belongs
                    // to one has a unit face normal; +y stands in for one that belongs to none.
                    if first_face[i] != DVec3::ZERO { first_face[i] } else { DVec3::Y }
                }
            };
            n.as_vec3().to_array()
        })
        .collect();
    if fallbacks > 0 {
        warnings.push(format!(
            "{fallbacks} vertices had cancelling normals (e.g. two-sided sheets); each uses one adjacent face's normal"
        ));
    }
    let colors: Vec<[f32; 4]> =
        (0..v).map(|i| color_sum[i].map(|s| (s / f64::from(members[i].max(1))) as f32)).collect();
    let corner_texcoords = if soup.all_have_texcoords {
        kept.iter().map(|&t| soup.triangles[t].map(|i| soup.texcoords[i as usize])).collect()
    } else {
        Vec::new()
    };
    let fur_mask: Vec<u8> = kept.iter().map(|&t| soup.fur[t]).collect();

    let stats = SkinMeshStats {
        primitives: soup.primitives,
        input_vertices: soup.positions.len() as u32,
        degenerate_triangles_skipped: degenerate,
        generated_normals: soup.missing_normals || generated > 0,
        had_vertex_colors: soup.had_vertex_colors,
        weld_tolerance_m: tol as f32,
    };
    let mut representatives = vec![0u32; v];
    for (w, &r) in reps.iter().enumerate() {
        if new_index[w] != u32::MAX {
            representatives[new_index[w] as usize] = r;
        }
    }
    Ok(Welded {
        mesh: SkinMesh { positions, normals, colors, triangles, fur_mask, corner_texcoords, stats },
        warnings,
        representatives,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn welding_is_first_occurrence_ordered_and_respects_the_tolerance() {
        let p = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0 + 4e-4, 0.0, 0.0), // within 1e-3 of vertex 1
            DVec3::new(0.0, 2e-3, 0.0),       // outside 1e-3 of vertex 0
            DVec3::new(-5e-4, 0.0, 5e-4),     // within 1e-3 of vertex 0, across a cell border
        ];
        let used = vec![true; p.len()];
        let any = |_: usize, _: usize| true;
        let (map, reps) = weld_positions(&p, &used, 1e-3, &any);
        assert_eq!(map, vec![0, 1, 1, 2, 0]);
        assert_eq!(reps, vec![0, 1, 3]);
        let (map0, reps0) = weld_positions(&p, &used, 0.0, &any);
        assert_eq!(map0, vec![0, 1, 2, 3, 4]);
        assert_eq!(reps0.len(), 5);
        let (map_neg, _) =
            weld_positions(&[DVec3::new(-0.0, 0.0, 1.0), DVec3::new(0.0, -0.0, 1.0)], &[true; 2], 0.0, &any);
        assert_eq!(map_neg, vec![0, 0], "-0.0 and 0.0 are the same position");
    }
}
