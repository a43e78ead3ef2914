//! Scattered grass blades grouped in clusters (grass thesis §3.2.2, eq. 3.6–3.8): each blade
//! stores its root position, its orientation (yaw about `+y`), its height scale and, for the force
//! interpolation, its cluster and four bilinear weights over the cluster's corners.
//!
//! Clusters are the cells of a regular grid in the `xz` plane. Cell `(i, j)` (`i` along x, `j`
//! along z) has index `j × cells_x + i`; corner `(i, j)` has index `j × (cells_x + 1) + i`. The
//! corners of a cell, in weight order, are `P1 = (i, j)`, `P2 = (i + 1, j)`, `P3 = (i, j + 1)`,
//! `P4 = (i + 1, j + 1)`, and a blade at local coordinates `(u, v) ∈ [0, 1]²` has the weights
//! `(1 − u)(1 − v), u(1 − v), (1 − u)v, uv` — each weight is the area of the sub-rectangle
//! opposite its corner (eq. 3.7 written with the diagonally opposite corner), and the blade's
//! force is `Σ δᵢ fᵢ` (eq. 3.6, 3.8).

use serde::{Deserialize, Serialize};

use super::{MAX_COORDINATE_M, Section, check_coordinates, check_indices, check_param, check_range, checked_count};
use crate::error::Result;
use crate::record::{Record, RecordWriter};
use crate::{FormatError, SectionKind};

/// Largest number of clusters a reader accepts.
pub const MAX_CLUSTERS: u64 = 1 << 26;
/// Tolerance on the sum of a blade's four weights (they are stored as binary32).
pub const WEIGHT_SUM_TOLERANCE: f32 = 1e-4;
/// Cluster corners a field may have regardless of its blade count (a 255² grid).
pub const FREE_CORNERS: u64 = 1 << 16;
/// Cluster corners a field may have per blade beyond [`FREE_CORNERS`]. The force field costs
/// work and memory per corner every step, so a grid far larger than its blades need is refused:
/// a small pack cannot declare much more work than its data justifies. (A bake's grid covers the
/// mesh's bounds with cells of `cluster_size_m`; 256 corners per blade is a field thinner than
/// one blade per 16 × 16 cells.)
pub const CORNERS_PER_BLADE: u64 = 256;
/// Distance a blade's root may lie from the point its weights interpolate, as a fraction of the
/// cell size (the weights are rounded to binary32).
pub const WEIGHT_POSITION_TOLERANCE: f32 = 1e-3;

/// The cluster grid in the `xz` plane.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClusterGrid {
    /// World `(x, z)` of corner `(0, 0)`, in metres.
    pub origin_m: [f32; 2],
    /// Cell size along x and z, in metres (> 0).
    pub cell_size_m: [f32; 2],
    /// Cells along x (≥ 1).
    pub cells_x: u32,
    /// Cells along z (≥ 1).
    pub cells_z: u32,
}

impl ClusterGrid {
    /// Number of clusters (cells).
    pub fn clusters(&self) -> usize {
        self.cells_x as usize * self.cells_z as usize
    }

    /// Number of cluster corners (`(cells_x + 1) × (cells_z + 1)`).
    pub fn corners(&self) -> usize {
        (self.cells_x as usize + 1) * (self.cells_z as usize + 1)
    }

    /// The corner indices `[P1, P2, P3, P4]` of cluster `c` (which must be below
    /// [`ClusterGrid::clusters`]).
    pub fn corner_indices(&self, c: u32) -> [u32; 4] {
        let (i, j) = (c % self.cells_x, c / self.cells_x);
        let row = self.cells_x + 1;
        let p1 = j * row + i;
        [p1, p1 + 1, p1 + row, p1 + row + 1]
    }

    /// World `(x, z)` of corner `index`.
    pub fn corner_position(&self, index: u32) -> [f32; 2] {
        let row = self.cells_x + 1;
        let (i, j) = (index % row, index / row);
        [self.origin_m[0] + i as f32 * self.cell_size_m[0], self.origin_m[1] + j as f32 * self.cell_size_m[1]]
    }

    /// The cluster containing world `(x, z)` (clamped to the grid) and the local coordinates
    /// `(u, v) ∈ [0, 1]²` inside it.
    pub fn locate(&self, x: f32, z: f32) -> (u32, [f32; 2]) {
        let fx = (x - self.origin_m[0]) / self.cell_size_m[0];
        let fz = (z - self.origin_m[1]) / self.cell_size_m[1];
        let i = (fx.floor().max(0.0) as u32).min(self.cells_x - 1);
        let j = (fz.floor().max(0.0) as u32).min(self.cells_z - 1);
        let u = (fx - i as f32).clamp(0.0, 1.0);
        let v = (fz - j as f32).clamp(0.0, 1.0);
        (j * self.cells_x + i, [u, v])
    }

    fn validate(&self) -> Result<()> {
        let sizes_ok = self.cell_size_m.iter().all(|s| s.is_finite() && *s > 0.0 && *s <= MAX_COORDINATE_M);
        let origin_ok = self.origin_m.iter().all(|o| o.is_finite() && o.abs() <= MAX_COORDINATE_M);
        if !sizes_ok || !origin_ok || self.cells_x == 0 || self.cells_z == 0 {
            return Err(FormatError::invalid(format!("cluster grid {self:?} is not a valid grid")));
        }
        let corners = (self.cells_x as u64 + 1).saturating_mul(self.cells_z as u64 + 1);
        if corners > MAX_CLUSTERS {
            return Err(FormatError::Limit {
                path: None,
                what: "cluster corners",
                value: corners,
                limit: MAX_CLUSTERS,
            });
        }
        Ok(())
    }
}

/// The bilinear weights `[P1, P2, P3, P4]` of local coordinates `(u, v)` (eq. 3.7).
pub fn bilinear_weights(u: f32, v: f32) -> [f32; 4] {
    [(1.0 - u) * (1.0 - v), u * (1.0 - v), (1.0 - u) * v, u * v]
}

/// The parameters the field was scattered with (kept for `inspect`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BladeFieldParams {
    /// Blades per square metre of (furry) surface.
    pub density_per_m2: f32,
    /// Seed of the scatter.
    pub seed: u64,
    /// Smallest height scale (metres per blade length).
    pub height_min_m: f32,
    /// Largest height scale (metres per blade length).
    pub height_max_m: f32,
}

/// Scattered blades, struct of arrays (one entry per blade in every array).
#[derive(Clone, Debug, PartialEq)]
pub struct BladeField {
    /// The cluster grid.
    pub grid: ClusterGrid,
    /// Scatter parameters.
    pub params: BladeFieldParams,
    /// Root position in metres.
    pub positions: Vec<[f32; 3]>,
    /// Rotation about `+y` in radians: the blade normal is `(sin yaw, 0, cos yaw)`, the width axis
    /// `(cos yaw, 0, −sin yaw)`.
    pub yaw_rad: Vec<f32>,
    /// Metres per blade length (> 0).
    pub height_scale: Vec<f32>,
    /// Cluster index.
    pub cluster: Vec<u32>,
    /// Bilinear weights over the cluster's corners `[P1, P2, P3, P4]`, summing to 1.
    pub weights: Vec<[f32; 4]>,
}

#[derive(Serialize, Deserialize)]
struct Meta {
    grid: ClusterGrid,
    params: BladeFieldParams,
    blades: u64,
}

impl BladeField {
    /// Number of blades.
    pub fn blade_count(&self) -> usize {
        self.positions.len()
    }

    /// Bytes stored per blade (position, yaw, height scale, cluster, four weights).
    pub const BYTES_PER_BLADE: usize = 12 + 4 + 4 + 4 + 16;
}

impl Section for BladeField {
    const KIND: SectionKind = SectionKind::BLADE_FIELD;
    const VERSION: u16 = 1;

    fn encode(&self) -> Vec<u8> {
        let meta = Meta { grid: self.grid, params: self.params, blades: self.positions.len() as u64 };
        RecordWriter::new(&meta)
            .array::<f32>(self.positions.as_flattened())
            .array::<f32>(&self.yaw_rad)
            .array::<f32>(&self.height_scale)
            .array::<u32>(&self.cluster)
            .array::<f32>(self.weights.as_flattened())
            .finish()
    }

    fn decode(payload: &[u8]) -> Result<Self> {
        let r = Record::parse(payload)?;
        let m: Meta = r.meta()?;
        m.grid.validate()?;
        // The arrays below are checked against the payload's real length, so a lying blade count
        // fails there before anything is allocated.
        let n = usize::try_from(m.blades).map_err(|_| FormatError::invalid("blade count overflows"))?;
        let positions = r.array_exact::<f32>(0, checked_count(n, 3, "positions")?, "positions")?;
        let yaw = r.array_exact::<f32>(1, n, "yaw_rad")?;
        let height = r.array_exact::<f32>(2, n, "height_scale")?;
        let cluster = r.array_exact::<u32>(3, n, "cluster")?;
        let weights = r.array_exact::<f32>(4, checked_count(n, 4, "weights")?, "weights")?;
        // The work a field declares is bounded by its data: the grid may not be far larger than
        // its blades need (docs/design.md "Runtime: packs").
        let corners = m.grid.corners() as u64;
        let allowed = FREE_CORNERS.saturating_add(CORNERS_PER_BLADE.saturating_mul(n as u64));
        if corners > allowed {
            return Err(FormatError::Limit {
                path: None,
                what: "cluster corners for the blade count",
                value: corners,
                limit: allowed,
            });
        }
        let p = &m.params;
        check_param(p.density_per_m2, 0.0, 1e6, "density_per_m2")?;
        check_param(p.height_min_m, 0.0, MAX_COORDINATE_M, "height_min_m")?;
        check_param(p.height_max_m, p.height_min_m, MAX_COORDINATE_M, "height_max_m")?;
        check_coordinates(&positions, "positions")?;
        check_range(&yaw, -1e3, 1e3, "yaw_rad")?;
        if let Some(i) = height.iter().position(|h| !(h.is_finite() && *h > 0.0 && *h <= MAX_COORDINATE_M)) {
            return Err(FormatError::invalid(format!("height_scale[{i}] = {} is not a positive length", height[i])));
        }
        check_indices(&cluster, m.grid.clusters(), "cluster")?;
        let cell = m.grid.cell_size_m;
        for (i, w) in weights.chunks_exact(4).enumerate() {
            let in_range = w.iter().all(|x| x.is_finite() && (-1e-6..=1.0 + 1e-6).contains(x));
            if !in_range || (w.iter().sum::<f32>() - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
                return Err(FormatError::invalid(format!("weights of blade {i} {w:?} are not bilinear weights")));
            }
            // The weights must place the blade where it stands (eq. 3.6–3.8): interpolating the
            // corners' positions gives its root's (x, z).
            let mut at = [0.0f32; 2];
            for (c, wk) in m.grid.corner_indices(cluster[i]).into_iter().zip(w) {
                let q = m.grid.corner_position(c);
                at = [at[0] + wk * q[0], at[1] + wk * q[1]];
            }
            let (x, z) = (positions[3 * i], positions[3 * i + 2]);
            let off = [(at[0] - x).abs() / cell[0], (at[1] - z).abs() / cell[1]];
            if !(off[0] <= WEIGHT_POSITION_TOLERANCE && off[1] <= WEIGHT_POSITION_TOLERANCE) {
                return Err(FormatError::invalid(format!(
                    "blade {i} stands at ({x}, {z}) but its cluster {} and weights place it at ({}, {})",
                    cluster[i], at[0], at[1]
                )));
            }
        }
        Ok(BladeField {
            grid: m.grid,
            params: m.params,
            positions: positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            yaw_rad: yaw.into_owned(),
            height_scale: height.into_owned(),
            cluster: cluster.into_owned(),
            weights: weights.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
        })
    }

    fn summary(&self) -> serde_json::Value {
        serde_json::json!({
            "blades": self.blade_count(),
            "clusters": self.grid.clusters(),
            "corners": self.grid.corners(),
            "cells_x": self.grid.cells_x,
            "cells_z": self.grid.cells_z,
            "cell_size_m": self.grid.cell_size_m,
            "origin_m": self.grid.origin_m,
            "bytes_per_blade": Self::BYTES_PER_BLADE,
            "density_per_m2": self.params.density_per_m2,
            "seed": self.params.seed,
            "height_min_m": self.params.height_min_m,
            "height_max_m": self.params.height_max_m,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> BladeField {
        let grid = ClusterGrid { origin_m: [-1.0, -2.0], cell_size_m: [0.5, 0.25], cells_x: 4, cells_z: 8 };
        let mut f = BladeField {
            grid,
            params: BladeFieldParams { density_per_m2: 10.0, seed: 7, height_min_m: 0.2, height_max_m: 0.4 },
            positions: Vec::new(),
            yaw_rad: Vec::new(),
            height_scale: Vec::new(),
            cluster: Vec::new(),
            weights: Vec::new(),
        };
        for k in 0..20 {
            let (x, z) = (-1.0 + 0.099 * k as f32, -2.0 + 0.0987 * k as f32);
            let (c, [u, v]) = grid.locate(x, z);
            f.positions.push([x, 0.1, z]);
            f.yaw_rad.push(k as f32 * 0.3);
            f.height_scale.push(0.2 + 0.01 * k as f32);
            f.cluster.push(c);
            f.weights.push(bilinear_weights(u, v));
        }
        f
    }

    #[test]
    fn round_trips_and_reports() {
        let f = sample();
        let bytes = f.encode();
        let back = BladeField::decode(&bytes).expect("a freshly encoded field decodes");
        assert_eq!(back, f);
        assert_eq!(back.encode(), bytes);
        let s = f.summary();
        assert_eq!(s["blades"], 20);
        assert_eq!(s["clusters"], 32);
        assert_eq!(s["bytes_per_blade"], 40);
    }

    #[test]
    fn corners_and_weights_reproduce_a_linear_field() {
        // A linear field f(x, z) = 3x − 2z + 1 is reproduced exactly by bilinear interpolation.
        let f = sample();
        let field = |p: [f32; 2]| 3.0 * p[0] - 2.0 * p[1] + 1.0;
        let mut checked = 0;
        for b in 0..f.blade_count() {
            let corners = f.grid.corner_indices(f.cluster[b]);
            let interp: f32 =
                corners.iter().zip(f.weights[b]).map(|(&c, w)| w * field(f.grid.corner_position(c))).sum();
            let p = f.positions[b];
            assert!((interp - field([p[0], p[2]])).abs() < 1e-4, "blade {b}: {interp}");
            checked += 1;
        }
        assert_eq!(checked, 20);
    }

    #[test]
    fn a_grid_far_larger_than_its_blades_need_is_refused() {
        // Cause: a 556 KB pack declared an 8191² cluster grid for its few thousand blades; it
        // passed `verify` and made `simulate` take 20 s and 1.6 GB on the force field.
        let mut f = sample();
        let cell = f.grid.cell_size_m;
        f.grid = ClusterGrid { cells_x: 8191, cells_z: 8191, ..f.grid };
        assert_eq!(f.grid.cell_size_m, cell);
        // Keep every blade consistent with the bigger grid, so only the size is to blame.
        for b in 0..f.blade_count() {
            let p = f.positions[b];
            let (c, [u, v]) = f.grid.locate(p[0], p[2]);
            f.cluster[b] = c;
            f.weights[b] = bilinear_weights(u, v);
        }
        match BladeField::decode(&f.encode()) {
            Err(FormatError::Limit { what, value, limit, .. }) => {
                assert_eq!(what, "cluster corners for the blade count");
                assert_eq!((value, limit), (8192 * 8192, FREE_CORNERS + 20 * CORNERS_PER_BLADE));
            }
            other => panic!("expected a limit error, got {other:?}"),
        }
        // A grid within the allowance for its blades decodes.
        let mut ok = sample();
        ok.grid = ClusterGrid { cells_x: 200, cells_z: 200, ..ok.grid };
        for b in 0..ok.blade_count() {
            let p = ok.positions[b];
            let (c, [u, v]) = ok.grid.locate(p[0], p[2]);
            ok.cluster[b] = c;
            ok.weights[b] = bilinear_weights(u, v);
        }
        assert!(BladeField::decode(&ok.encode()).is_ok());
    }

    #[test]
    fn weights_must_place_the_blade_where_it_stands() {
        let mut f = sample();
        f.cluster[4] = (f.cluster[4] + 1) % f.grid.clusters() as u32;
        let err = BladeField::decode(&f.encode()).unwrap_err();
        assert!(err.to_string().contains("blade 4 stands at"), "{err}");
        let mut f = sample();
        f.params.height_max_m = f32::NAN;
        assert!(BladeField::decode(&f.encode()).unwrap_err().to_string().contains("height_max_m"));
    }

    #[test]
    fn truncations_corruptions_and_bad_values_are_rejected() {
        let bytes = sample().encode();
        for len in 0..bytes.len() {
            assert!(BladeField::decode(&bytes[..len]).is_err(), "prefix of {len} bytes decoded");
        }
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0x5A;
            let _ = BladeField::decode(&b);
        }
        let mut bad = Vec::new();
        let mut f = sample();
        f.cluster[3] = 32;
        bad.push(f);
        let mut f = sample();
        f.weights[2] = [0.5, 0.5, 0.5, 0.0];
        bad.push(f);
        let mut f = sample();
        f.height_scale[0] = 0.0;
        bad.push(f);
        let mut f = sample();
        f.grid.cells_x = 0;
        bad.push(f);
        let mut f = sample();
        f.grid.cells_x = u32::MAX;
        f.grid.cells_z = u32::MAX;
        bad.push(f);
        let mut f = sample();
        f.positions[1][0] = f32::INFINITY;
        bad.push(f);
        let n = bad.len();
        for f in bad {
            assert!(BladeField::decode(&f.encode()).is_err(), "{:?} accepted", f.grid);
        }
        assert_eq!(n, 6);
    }
}
