//! Synthetic topologies of exact sizes, for benchmarks and the accuracy report: the five
//! mass–spring sizes of the fur thesis's table 4.5 and multiples of them. Half the masses are
//! anchored roots on a flat square grid, half are tips above them; the first `masses/2` links join
//! each root to its tip (springs, or sticks for the stick variant) and the remaining springs join
//! tips to grid neighbours at fixed offsets (like prism edges), so every count is exact.

use furbake_formats::sections::spring_topology::{SpringTopology, TopologyKind, TopologyParams};

/// (masses, springs) of the fur thesis's table 4.5.
pub const THESIS_TABLE_4_5: [(usize, usize); 5] =
    [(3744, 1872), (3744, 6952), (5664, 15056), (9978, 25892), (18152, 36292)];

/// Builds a synthetic topology with exactly `masses` masses (even) and `links` links, of which
/// `masses/2` are root–tip links (sticks when `sticks`, else springs) and the rest tip–tip springs.
/// `links` must be at least `masses/2`. Returns `None` when the sizes are impossible.
pub fn synthetic_topology(
    masses: usize,
    links: usize,
    sticks: bool,
    params: &TopologyParams,
) -> Option<SpringTopology> {
    if masses < 2 || !masses.is_multiple_of(2) || links < masses / 2 || masses >= u32::MAX as usize / 2 {
        return None;
    }
    let n = masses / 2;
    let extra = links - n;
    if n < 2 && extra > 0 {
        return None;
    }
    let w = (n as f64).sqrt().ceil() as usize;
    let cell = 0.01f32;
    let len = params.fur_length_m;
    let kind = if sticks {
        TopologyKind::STICKS
    } else if extra > 0 {
        TopologyKind::PRISMS
    } else {
        TopologyKind::SPRING_STICKS
    };
    let mut t = crate::topology::empty(kind, params);
    t.mass_rest_positions.reserve(masses);
    t.mass_kg.reserve(masses);
    t.mass_anchored.reserve(masses);
    t.shell_vertex_masses.reserve(n);
    for i in 0..n {
        let (gx, gz) = ((i % w) as f32 * cell, (i / w) as f32 * cell);
        t.mass_rest_positions.push([gx, 0.0, gz]);
        t.mass_kg.push(params.root_mass_kg);
        t.mass_anchored.push(1);
        t.mass_rest_positions.push([gx, len, gz]);
        t.mass_kg.push(params.hair_mass_kg);
        t.mass_anchored.push(0);
        let (r, tip) = (2 * i as u32, 2 * i as u32 + 1);
        t.shell_vertex_masses.push([r, tip]);
        if sticks {
            t.stick_ends.push([r, tip]);
            t.stick_lengths_m.push(len);
        } else {
            t.spring_ends.push([r, tip]);
            t.spring_rest_lengths_m.push(len);
            t.spring_stiffness_n_per_m.push(params.stiffness_n_per_m);
            t.spring_damping_n_s_per_m.push(params.damping_n_s_per_m);
        }
    }
    // Neighbour offsets in grid order; each round adds one spring per tip until `extra` are made.
    let offsets = [1, w, w + 1, w.saturating_sub(1).max(2), 2, 2 * w, 2 * w + 1, 2 * w + 2, 3, 3 * w];
    let mut made = 0;
    'outer: for round in 0.. {
        let off = offsets[round % offsets.len()] + (round / offsets.len()) * (w * 3 + 4);
        let off = off % n;
        if off == 0 {
            continue;
        }
        for i in 0..n {
            if made == extra {
                break 'outer;
            }
            let j = (i + off) % n;
            let (a, b) = (2 * i as u32 + 1, 2 * j as u32 + 1);
            let pa = t.mass_rest_positions[a as usize];
            let pb = t.mass_rest_positions[b as usize];
            let d = ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
            t.spring_ends.push([a, b]);
            t.spring_rest_lengths_m.push(d);
            t.spring_stiffness_n_per_m.push(params.edge_stiffness_n_per_m);
            t.spring_damping_n_s_per_m.push(params.edge_damping_n_s_per_m);
            made += 1;
        }
        if round > 10_000 {
            return None;
        }
    }
    Some(t)
}
