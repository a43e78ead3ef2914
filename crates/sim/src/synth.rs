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

/// Columns and rows of [`stiff_net`]: the top row is anchored.
const NET_COLUMNS: usize = 10;
const NET_ROWS: usize = 5;

/// The stiff small system of the accuracy report and the convergence tests: 50 masses of 1 g on a
/// 10 × 5 grid with 1 cm spacing hanging below its anchored top row (10 anchored, 40 free), and 100
/// springs of 100 N/m with 0.01 N·s/m damping: 40 vertical, 36 horizontal and 24 diagonals (the
/// "\" diagonal of the first eight cells of each of the top three rows of cells). Every spring
/// starts at its rest length, so the net starts at rest and [`stiff_net_forces`] sets it swinging.
/// `h·ω` of its stiffest mode is ≈ 25 at 1/30 s: a stiff system for every solver. Its kind is
/// `PRISMS` (free springs between free masses); the shell-vertex map names each column's
/// anchor and bottom mass, so the rest direction points down.
pub fn stiff_net() -> SpringTopology {
    let params = TopologyParams {
        fur_length_m: 0.01 * (NET_ROWS - 1) as f32,
        hair_mass_kg: 1e-3,
        stiffness_n_per_m: 100.0,
        damping_n_s_per_m: 0.01,
        edge_stiffness_n_per_m: 100.0,
        edge_damping_n_s_per_m: 0.01,
        ..TopologyParams::default()
    };
    let mut t = crate::topology::empty(TopologyKind::PRISMS, &params);
    let spacing = 0.01f32;
    let index = |c: usize, r: usize| (r * NET_COLUMNS + c) as u32;
    for r in 0..NET_ROWS {
        for c in 0..NET_COLUMNS {
            t.mass_rest_positions.push([c as f32 * spacing, -(r as f32) * spacing, 0.0]);
            t.mass_kg.push(if r == 0 { params.root_mass_kg } else { 1e-3 });
            t.mass_anchored.push(u8::from(r == 0));
        }
    }
    let mut spring = |a: u32, b: u32| {
        let (pa, pb) = (t.mass_rest_positions[a as usize], t.mass_rest_positions[b as usize]);
        let d = ((pa[0] - pb[0]).powi(2) + (pa[1] - pb[1]).powi(2) + (pa[2] - pb[2]).powi(2)).sqrt();
        t.spring_ends.push([a, b]);
        t.spring_rest_lengths_m.push(d);
        t.spring_stiffness_n_per_m.push(100.0);
        t.spring_damping_n_s_per_m.push(0.01);
    };
    for r in 0..NET_ROWS - 1 {
        for c in 0..NET_COLUMNS {
            spring(index(c, r), index(c, r + 1));
        }
    }
    for r in 1..NET_ROWS {
        for c in 0..NET_COLUMNS - 1 {
            spring(index(c, r), index(c + 1, r));
        }
    }
    for r in 0..3 {
        for c in 0..8 {
            spring(index(c, r), index(c + 1, r + 1));
        }
    }
    for c in 0..NET_COLUMNS {
        t.shell_vertex_masses.push([index(c, 0), index(c, NET_ROWS - 1)]);
    }
    t
}

/// The forces on [`stiff_net`]: gravity and a gusty wind across the net, no restoring force (the
/// net is not fur).
pub fn stiff_net_forces() -> crate::ForceSet {
    crate::ForceSet {
        restoring_weight_n: 0.0,
        wind: Some(crate::WindForce {
            direction: [0.3, 0.0, 1.0],
            force_n: 5e-3,
            gust_amplitude: 0.5,
            gust_frequency_hz: 1.5,
            gust_wavelength_m: 0.1,
        }),
        ..crate::ForceSet::default()
    }
}

/// The forces of the accuracy report's fur scenes (the thesis's grass patch, the Fox): a gusty
/// wind and the restoring force of eq. 3.37, no gravity — with gravity along the hair, eq. 3.37
/// cannot hold fur upright (its pull grows with the cube of the tilt, gravity's torque
/// linearly), so which way each hair falls depends on round-off and no step size converges, a
/// poor yardstick.
pub fn fur_wind_forces() -> crate::ForceSet {
    crate::ForceSet {
        gravity_m_per_s2: [0.0; 3],
        wind: Some(crate::WindForce {
            direction: [1.0, 0.0, 0.4],
            force_n: 3e-4,
            gust_amplitude: 0.8,
            gust_frequency_hz: 2.0,
            gust_wavelength_m: 0.05,
        }),
        ..crate::ForceSet::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stiff_net_has_fifty_masses_and_a_hundred_springs() {
        let t = stiff_net();
        assert_eq!((t.mass_kg.len(), t.spring_ends.len()), (50, 100));
        assert_eq!(t.mass_anchored.iter().filter(|&&a| a != 0).count(), 10);
        assert!(t.spring_rest_lengths_m.iter().all(|&l| l > 0.009 && l < 0.015));
        let sim = crate::Simulator::new(&t, crate::SolverSettings::default());
        assert!(sim.is_ok(), "{:?}", sim.err());
    }
}
