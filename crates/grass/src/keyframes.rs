//! Keyframe generation and compression (grass thesis §3.2.3–3.2.4, §3.3, §4.4.1).
//!
//! 1. [`simulate_poses`]: the reference blade settled by [`BladeSimulator`] under every force of a
//!    grid of magnitudes × angles to the blade normal (eq. 3.10–3.12); each pose is stored as the
//!    displacement of every centre-line node from the reference (eq. 3.4–3.5, 3.9).
//! 2. [`compress_poses`]: the switchable stages — drop the vertices that never move, one vector per
//!    rigid segment pair (fig. 3.7), keep only the poses of `(0, π)` or `(0, π/2)` and mirror the
//!    rest (fig. 3.8–3.9), quantise (snorm16 with a stored scale as §4.4.1, f16, or 8-bit for
//!    comparison) — and the reconstruction error of the result against the unquantised poses.
//!
//! The bit counts follow the thesis (§3.3): raw = poses × vertices × 3 × 32; compressed = stored
//! poses × stored vectors × 3 × bits. For 8 segments (32 vertices: 4 per quad), 1000 poses and
//! every stage: the two root vertices are static, the other 30 form 15 rigid pairs, xz symmetry
//! keeps 250 poses: `250 × 15 × 3 × 16 = 180,000` bits (720,000 without symmetry) against
//! `1000 × 32 × 3 × 32 = 3,072,000` raw.

use furbake_formats::sections::keyframe_table::{
    CompressionStages, DisplacementEncoding, Displacements, KeyframeStats, KeyframeTable, PoseGrid, STATIC_VERTEX,
    Symmetry,
};
use glam::{DVec2, DVec3, Vec3};
use rayon::prelude::*;

use crate::GrassError;
use crate::blade::{BladeShape, ReferenceBlade, build_reference_blade};
use crate::decode::{KeyframeDecoder, PoseKey};
use crate::simulate::{BladeMaterial, BladeSimulator};

/// Largest number of represented poses the baker accepts.
pub const MAX_POSES: u32 = 1 << 20;

/// The force grid to simulate.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct PoseGridSettings {
    /// Represented poses, `magnitudes × angles` (the thesis's "1000 poses"). Default 1000.
    pub poses: u32,
    /// Force magnitudes; `None` picks the divisor of `poses` nearest `√(poses / 10)` that leaves a
    /// whole number of angles per mirror quadrant (1000 ⇒ 10 magnitudes × 100 angles).
    pub magnitudes: Option<u32>,
    /// Largest force magnitude (force units of [`BladeMaterial`]). Default 4.0: the tip of the
    /// default blade then moves about 0.5 blade lengths when pushed onto its face.
    pub max_force: f32,
}

impl Default for PoseGridSettings {
    fn default() -> Self {
        PoseGridSettings { poses: 1000, magnitudes: None, max_force: 4.0 }
    }
}

impl PoseGridSettings {
    /// The validated grid for `symmetry`.
    pub fn resolve(&self, symmetry: Symmetry) -> Result<PoseGrid, GrassError> {
        let n = self.poses;
        if n == 0 || n > MAX_POSES {
            return Err(GrassError::parameter(format!("poses = {n} (must be 1..={MAX_POSES})")));
        }
        if !(self.max_force.is_finite() && self.max_force > 0.0) {
            return Err(GrassError::parameter(format!("max force {} must be positive", self.max_force)));
        }
        let f = symmetry.factor();
        let fits = |m: u32| m > 0 && n.is_multiple_of(m) && (n / m).is_multiple_of(f);
        let magnitudes = match self.magnitudes {
            Some(m) if fits(m) => m,
            Some(m) => {
                return Err(GrassError::parameter(format!(
                    "{n} poses over {m} magnitudes do not leave a multiple of {f} angles (symmetry {})",
                    symmetry.name()
                )));
            }
            None => {
                let target = (n as f64 / 10.0).sqrt();
                (1..=n)
                    .filter(|&m| fits(m))
                    .min_by(|a, b| (*a as f64 - target).abs().total_cmp(&(*b as f64 - target).abs()))
                    .ok_or_else(|| {
                        GrassError::parameter(format!("{n} poses cannot be split into a multiple of {f} angles"))
                    })?
            }
        };
        Ok(PoseGrid { magnitudes, angles: n / magnitudes, max_force: self.max_force })
    }
}

/// Everything a keyframe table bake needs.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct KeyframeSettings {
    /// Reference blade shape (segments = level of detail).
    pub shape: BladeShape,
    /// Simulated material.
    pub material: BladeMaterial,
    /// Force grid.
    pub grid: PoseGridSettings,
    /// Exploited mirror symmetry. Default: xz (a quarter of the poses).
    pub symmetry: Symmetry,
    /// Lossless stages. Default: both on.
    pub stages: CompressionStages,
    /// Component encoding. Default: snorm16.
    pub encoding: DisplacementEncoding,
}

impl Default for KeyframeSettings {
    fn default() -> Self {
        KeyframeSettings {
            shape: BladeShape::default(),
            material: BladeMaterial::default(),
            grid: PoseGridSettings::default(),
            symmetry: Symmetry::XZ,
            stages: CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true },
            encoding: DisplacementEncoding::Snorm16,
        }
    }
}

impl KeyframeSettings {
    /// The thesis's configuration (also the default): 8 segments, 1000 poses, every stage, xz
    /// symmetry, snorm16.
    pub fn thesis() -> Self {
        KeyframeSettings::default()
    }
}

/// The unquantised simulated poses over the full circle of angles.
#[derive(Clone, Debug)]
pub struct SimulatedPoses {
    /// The grid.
    pub grid: PoseGrid,
    /// The reference blade.
    pub blade: ReferenceBlade,
    /// Node displacements, `(S + 1)` per represented pose, pose `m × angles + j`.
    pub node_displacements: Vec<Vec3>,
    /// Most Newton iterations any pose needed.
    pub max_iterations: u32,
}

impl SimulatedPoses {
    /// Displacement of vertex `v` in the represented pose at `key` (zero for zero force).
    pub fn vertex_displacement(&self, key: PoseKey, v: usize) -> Vec3 {
        if key.magnitude == 0 {
            return Vec3::ZERO;
        }
        let levels = self.blade.nodes.len();
        let pose = (key.magnitude as usize - 1) * self.grid.angles as usize + key.angle as usize;
        self.node_displacements[pose * levels + ReferenceBlade::level_of_vertex(v)]
    }
}

/// Settles `blade` under every force of `grid` (angles over the full circle; each angle's
/// magnitudes are swept upwards, warm-starting from the previous one). Parallel over angles, and
/// identical whatever the thread count.
pub fn simulate_poses(
    blade: &ReferenceBlade,
    material: &BladeMaterial,
    grid: PoseGrid,
) -> Result<SimulatedPoses, GrassError> {
    let sim = BladeSimulator::new(blade, material)?;
    let levels = blade.nodes.len();
    let columns: Vec<(Vec<Vec3>, u32)> = (0..grid.angles)
        .into_par_iter()
        .map(|j| {
            let theta = (j as f64 + 0.5) * std::f64::consts::TAU / grid.angles as f64;
            let mut warm: Option<Vec<DVec2>> = None;
            let mut out = Vec::with_capacity(grid.magnitudes as usize * levels);
            let mut iterations = 0;
            for i in 0..grid.magnitudes {
                let mag = grid.max_force as f64 * (i + 1) as f64 / grid.magnitudes as f64;
                let force = DVec3::new(mag * theta.sin(), 0.0, mag * theta.cos());
                let eq = sim.settle(force, warm.as_deref())?;
                iterations = iterations.max(eq.iterations);
                out.extend(eq.nodes.iter().zip(&blade.nodes).map(|(p, r)| (*p - *r).as_vec3()));
                warm = Some(eq.tilts);
            }
            Ok((out, iterations))
        })
        .collect::<Result<_, GrassError>>()?;
    let mut node_displacements = vec![Vec3::ZERO; grid.represented_poses() as usize * levels];
    let mut max_iterations = 0;
    for (j, (col, its)) in columns.iter().enumerate() {
        max_iterations = max_iterations.max(*its);
        for m in 0..grid.magnitudes as usize {
            let dst = (m * grid.angles as usize + j) * levels;
            node_displacements[dst..dst + levels].copy_from_slice(&col[m * levels..(m + 1) * levels]);
        }
    }
    Ok(SimulatedPoses { grid, blade: blade.clone(), node_displacements, max_iterations })
}

/// Applies the compression stages to `poses` and measures the result's reconstruction error.
pub fn compress_poses(
    poses: &SimulatedPoses,
    symmetry: Symmetry,
    stages: CompressionStages,
    encoding: DisplacementEncoding,
) -> Result<KeyframeTable, GrassError> {
    let grid = poses.grid;
    if !grid.angles.is_multiple_of(symmetry.factor()) {
        return Err(GrassError::parameter(format!(
            "{} angles are not a multiple of {} (symmetry {})",
            grid.angles,
            symmetry.factor(),
            symmetry.name()
        )));
    }
    let blade = &poses.blade;
    let vertices = blade.vertex_count();
    let represented = |m: u32, j: u32| PoseKey { magnitude: m + 1, angle: j };
    // Stage 1: static vertices never move in any represented pose.
    let is_static: Vec<bool> = (0..vertices)
        .map(|v| {
            (0..grid.magnitudes)
                .all(|m| (0..grid.angles).all(|j| poses.vertex_displacement(represented(m, j), v) == Vec3::ZERO))
        })
        .collect();
    // Stage 2: units are rigid pairs (the two vertices of a quad edge) or single vertices.
    let unit_size = if stages.rigid_segment_pairs { 2 } else { 1 };
    let mut vertex_map = vec![0u32; vertices];
    let mut unit_vertex = Vec::new(); // representative vertex of each stored vector
    for unit in 0..vertices / unit_size {
        let members = unit * unit_size..(unit + 1) * unit_size;
        if stages.drop_static_vertices && members.clone().all(|v| is_static[v]) {
            members.for_each(|v| vertex_map[v] = STATIC_VERTEX);
        } else {
            members.for_each(|v| vertex_map[v] = unit_vertex.len() as u32);
            unit_vertex.push(unit * unit_size);
        }
    }
    // Stage 3: the stored angles are the first `angles / factor` of the full circle.
    let stored_angles = grid.stored_angles(symmetry);
    let mut exact = Vec::with_capacity(grid.stored_poses(symmetry) as usize * unit_vertex.len() * 3);
    for m in 0..grid.magnitudes {
        for j in 0..stored_angles {
            for &v in &unit_vertex {
                exact.extend_from_slice(&poses.vertex_displacement(represented(m, j), v).to_array());
            }
        }
    }
    // Stage 4: quantisation.
    let displacements = quantise(&exact, encoding);
    let mut table = KeyframeTable {
        segments: blade.segments,
        reference_positions: blade.positions.clone(),
        reference_uvs: blade.uvs.clone(),
        triangles: blade.triangles.clone(),
        grid,
        symmetry,
        stages,
        stored_vectors: unit_vertex.len() as u32,
        vertex_map,
        displacements,
        stats: KeyframeStats::default(),
    };
    table.stats = measure_error(&table, poses)?;
    Ok(table)
}

/// Quantises components with `encoding` (scale = largest magnitude, 1 when all are zero).
pub fn quantise(values: &[f32], encoding: DisplacementEncoding) -> Displacements {
    let max = values.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let scale = if max > 0.0 { max } else { 1.0 };
    match encoding {
        DisplacementEncoding::F32 => Displacements::F32(values.to_vec()),
        DisplacementEncoding::F16 => {
            Displacements::F16(values.iter().map(|v| half::f16::from_f32(*v).to_bits()).collect())
        }
        DisplacementEncoding::Snorm16 => Displacements::Snorm16 {
            scale,
            values: values.iter().map(|v| (v / scale * 32767.0).round().clamp(-32767.0, 32767.0) as i16).collect(),
        },
        DisplacementEncoding::Unorm8 => Displacements::Unorm8 {
            scale,
            values: values.iter().map(|v| ((v / scale + 1.0) * 127.5).round().clamp(0.0, 255.0) as u8).collect(),
        },
        DisplacementEncoding::Snorm8 => Displacements::Snorm8 {
            scale,
            values: values.iter().map(|v| (v / scale * 127.0).round().clamp(-127.0, 127.0) as i8).collect(),
        },
    }
}

/// Largest and RMS vertex error of `table` against `poses` over every represented pose, and the
/// largest displacement, in blade lengths.
pub fn measure_error(table: &KeyframeTable, poses: &SimulatedPoses) -> Result<KeyframeStats, GrassError> {
    let decoder = KeyframeDecoder::new(table)?;
    let grid = poses.grid;
    let (mut max, mut sum, mut count, mut max_disp) = (0.0f64, 0.0f64, 0u64, 0.0f32);
    for m in 1..=grid.magnitudes {
        for j in 0..grid.angles {
            let key = PoseKey { magnitude: m, angle: j };
            for v in 0..table.vertex_count() {
                let exact = poses.vertex_displacement(key, v);
                let err = (decoder.displacement(key, v) - exact).length() as f64;
                max = max.max(err);
                sum += err * err;
                count += 1;
                max_disp = max_disp.max(exact.length());
            }
        }
    }
    Ok(KeyframeStats {
        error_max: max as f32,
        error_rms: (sum / count.max(1) as f64).sqrt() as f32,
        max_displacement: max_disp,
    })
}

/// Bakes a keyframe table: reference blade, simulation, compression.
pub fn bake_keyframe_table(settings: &KeyframeSettings) -> Result<KeyframeTable, GrassError> {
    if settings.symmetry.mirrors_z() && settings.shape.curl != 0.0 {
        return Err(GrassError::parameter(format!(
            "a blade with curl {} is not symmetric in z = 0; use symmetry none or x",
            settings.shape.curl
        )));
    }
    let grid = settings.grid.resolve(settings.symmetry)?;
    let blade = build_reference_blade(&settings.shape)?;
    let poses = simulate_poses(&blade, &settings.material, grid)?;
    compress_poses(&poses, settings.symmetry, settings.stages, settings.encoding)
}

#[cfg(test)]
mod tests {
    use super::*;
    use furbake_formats::Section;

    fn poses(n: u32, symmetry: Symmetry) -> SimulatedPoses {
        let grid = PoseGridSettings { poses: n, ..PoseGridSettings::default() }.resolve(symmetry).expect("valid grid");
        let blade = build_reference_blade(&BladeShape::default()).expect("default blade");
        simulate_poses(&blade, &BladeMaterial::default(), grid).expect("settles")
    }

    #[test]
    fn the_thesis_example_comes_out_exactly() {
        // 8 segments ⇒ 32 vertices; 1000 poses. §3.3: 3,072,000 bits raw, 720,000 compressed
        // without symmetry, 180,000 with.
        let p = poses(1000, Symmetry::XZ);
        assert_eq!((p.grid.magnitudes, p.grid.angles), (10, 100));
        let all = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        let with = compress_poses(&p, Symmetry::XZ, all, DisplacementEncoding::Snorm16).expect("compresses");
        let without = compress_poses(&p, Symmetry::None, all, DisplacementEncoding::Snorm16).expect("compresses");
        assert_eq!(with.vertex_count(), 32);
        assert_eq!(with.stored_vectors, 15);
        assert_eq!(with.raw_bits(), 3_072_000);
        assert_eq!(without.raw_bits(), 3_072_000);
        assert_eq!(with.payload_bits(), 180_000);
        assert_eq!(without.payload_bits(), 720_000);
        let s = with.summary();
        assert_eq!((s["raw_bits"].as_u64(), s["payload_bits"].as_u64()), (Some(3_072_000), Some(180_000)));
        // Each stage alone, counted the same way.
        let none = CompressionStages::default();
        let cases = [
            (none, Symmetry::None, DisplacementEncoding::F32, 1000 * 32 * 3 * 32),
            (
                CompressionStages { drop_static_vertices: true, ..none },
                Symmetry::None,
                DisplacementEncoding::F32,
                1000 * 30 * 96,
            ),
            (
                CompressionStages { rigid_segment_pairs: true, ..none },
                Symmetry::None,
                DisplacementEncoding::F32,
                1000 * 16 * 96,
            ),
            (none, Symmetry::X, DisplacementEncoding::F32, 500 * 32 * 96),
            (none, Symmetry::None, DisplacementEncoding::Unorm8, 1000 * 32 * 24),
        ];
        for (stages, sym, enc, bits) in cases {
            let t = compress_poses(&p, sym, stages, enc).expect("compresses");
            assert_eq!(t.payload_bits(), bits, "{stages:?} {sym:?} {enc:?}");
            assert_eq!(t.raw_bits(), 3_072_000);
        }
    }

    #[test]
    fn encodings_reconstruct_within_their_precision() {
        let p = poses(200, Symmetry::XZ);
        let all = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        let mut checked = 0;
        for (enc, bound) in [
            (DisplacementEncoding::F32, 1e-6),
            (DisplacementEncoding::Snorm16, 1e-4),
            (DisplacementEncoding::F16, 2e-3),
            (DisplacementEncoding::Snorm8, 2e-2),
            (DisplacementEncoding::Unorm8, 2e-2),
        ] {
            let t = compress_poses(&p, Symmetry::XZ, all, enc).expect("compresses");
            assert!(t.stats.error_max <= bound, "{enc:?}: {} > {bound}", t.stats.error_max);
            assert!(t.stats.error_rms <= t.stats.error_max);
            assert!(t.stats.max_displacement > 0.3, "poses bend: {}", t.stats.max_displacement);
            // And the section survives a round trip.
            assert_eq!(KeyframeTable::decode(&t.encode()).expect("decodes"), t);
            checked += 1;
        }
        assert_eq!(checked, 5);
    }

    #[test]
    fn symmetric_tables_reproduce_the_full_simulation() {
        // The mirrored poses are decoded, not simulated: their error against the full-circle
        // simulation shows the mirroring is right (f32 ⇒ only the simulation's rounding remains).
        let p = poses(400, Symmetry::XZ);
        let all = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        for sym in [Symmetry::None, Symmetry::X, Symmetry::XZ] {
            let t = compress_poses(&p, sym, all, DisplacementEncoding::F32).expect("compresses");
            assert!(t.stats.error_max < 1e-6, "{sym:?}: {}", t.stats.error_max);
        }
    }

    #[test]
    fn grids_and_settings_are_validated() {
        let g = PoseGridSettings::default().resolve(Symmetry::XZ).expect("1000 poses fit xz");
        assert_eq!((g.magnitudes, g.angles), (10, 100));
        assert!(PoseGridSettings { poses: 10, ..Default::default() }.resolve(Symmetry::XZ).is_err());
        assert!(PoseGridSettings { poses: 10, ..Default::default() }.resolve(Symmetry::None).is_ok());
        assert!(
            PoseGridSettings { poses: 100, magnitudes: Some(3), ..Default::default() }.resolve(Symmetry::None).is_err()
        );
        assert!(PoseGridSettings { max_force: 0.0, ..Default::default() }.resolve(Symmetry::None).is_err());
        let curled =
            KeyframeSettings { shape: BladeShape { curl: 0.2, ..BladeShape::default() }, ..KeyframeSettings::thesis() };
        assert!(bake_keyframe_table(&curled).is_err(), "curl with z symmetry is refused");
    }

    #[test]
    fn bake_is_identical_whatever_the_thread_count() {
        let s = KeyframeSettings {
            grid: PoseGridSettings { poses: 80, ..Default::default() },
            ..KeyframeSettings::thesis()
        };
        let a = bake_keyframe_table(&s).expect("bakes").encode();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a 1-thread pool");
        let b = pool.install(|| bake_keyframe_table(&s)).expect("bakes").encode();
        assert_eq!(a, b);
    }
}
