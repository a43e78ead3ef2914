//! The grass part of `docs/accuracy.md` (the user's first explicit ask, for grass): what accuracy
//! costs in time, measured, not estimated; section numbers are the grass thesis's.
//!
//! 1. Pose error against the unquantised, uninterpolated simulation (the blade settled directly
//!    under each query force, §3.2.4) for keyframe counts × selection (nearest / linear eq. 3.13 /
//!    spherical eq. 3.14), against the CPU decode time per blade.
//! 2. Quantisation (§4.4.1): error and size of the thesis's table (8 segments, 1000 poses, every
//!    stage) for every encoding.
//! 3. Per-blade force error against the exact field (eq. 4.1 evaluated at each blade, fig. 4.7 (d))
//!    for cluster sizes, with and without delayed attenuation (fig. 4.7 vs 4.8), against the CPU
//!    time per frame.
//!
//! Times are wall-clock on the machine that runs the report (shared machines are noisy: the
//! report says how many threads it had).

use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, Symmetry};
use glam::{DVec3, Vec2, Vec3};

use furbake_grass::rng::SplitMix64;
use furbake_grass::{
    BladeFieldSettings, BladeSimulator, BladeSoa, BladeWindSource, ForceField, ForceScene, GrassError, KeyframeDecoder,
    KeyframeSettings, PoseGridSettings, PoseInterpolation, ReferenceBlade, build_reference_blade, compress_poses,
    ground_grid_mesh, scatter_blades, simulate_poses,
};

/// Timed batches per measurement; the fastest is reported (the least disturbed by other load).
const TIMING_BATCHES: usize = 5;

/// Nanoseconds of the fastest of `batches` runs of `f`.
fn best_of(batches: usize, mut f: impl FnMut()) -> f64 {
    (0..batches.max(1))
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_nanos() as f64
        })
        .fold(f64::INFINITY, f64::min)
}

/// What the report measures.
#[derive(Clone, Debug, PartialEq)]
pub struct GrassAccuracyOptions {
    /// Keyframe counts (represented poses, xz symmetry). Default 12, 100, 1000, 10,000.
    pub pose_counts: Vec<u32>,
    /// Displacement encodings of the pose table. Default: every encoding.
    pub encodings: Vec<DisplacementEncoding>,
    /// Random query forces per keyframe count. Default 200.
    pub queries: usize,
    /// Decode repetitions per query when timing. Default 50.
    pub timing_repeats: usize,
    /// Cluster edge lengths, metres. Default 0.25, 0.5, 1, 2, 4.
    pub cluster_sizes_m: Vec<f32>,
    /// Blades per m² of the 20 m × 20 m force test field. Default 100 (40,000 blades).
    pub field_density_per_m2: f32,
}

impl Default for GrassAccuracyOptions {
    fn default() -> Self {
        GrassAccuracyOptions {
            pose_counts: vec![12, 100, 1000, 10_000],
            encodings: DisplacementEncoding::ALL.to_vec(),
            queries: 200,
            timing_repeats: 50,
            cluster_sizes_m: vec![0.25, 0.5, 1.0, 2.0, 4.0],
            field_density_per_m2: 100.0,
        }
    }
}

/// One row of the pose table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseErrorRow {
    /// Represented poses.
    pub poses: u32,
    /// Selection mode.
    pub interpolation: PoseInterpolation,
    /// Displacement encoding of the table.
    pub encoding: DisplacementEncoding,
    /// Largest vertex error, blade lengths.
    pub error_max: f32,
    /// RMS vertex error, blade lengths.
    pub error_rms: f32,
    /// CPU decode time per blade (selection + every vertex), nanoseconds.
    pub ns_per_blade: f64,
}

/// Measures pose error and decode time (table 1 of the report).
pub fn measure_pose_error(options: &GrassAccuracyOptions) -> Result<Vec<PoseErrorRow>, GrassError> {
    let base = KeyframeSettings::thesis();
    let blade = build_reference_blade(&base.shape)?;
    let sim = BladeSimulator::new(&blade, &base.material)?;
    let max_force = base.grid.max_force;
    // Query forces and their exact (directly simulated) poses.
    let mut rng = SplitMix64::new(0x5eed_a11c);
    let mut queries = Vec::with_capacity(options.queries);
    for _ in 0..options.queries {
        let mag = max_force * rng.next_f32();
        let theta = std::f32::consts::TAU * rng.next_f32();
        let force = Vec2::new(theta.sin(), theta.cos()) * mag;
        let eq = sim.settle(DVec3::new(force.x as f64, 0.0, force.y as f64), None)?;
        let exact: Vec<Vec3> = (0..blade.vertex_count())
            .map(|v| {
                let level = ReferenceBlade::level_of_vertex(v);
                Vec3::from(blade.positions[v]) + (eq.nodes[level] - blade.nodes[level]).as_vec3()
            })
            .collect();
        queries.push((force, exact));
    }
    let mut rows = Vec::new();
    for &poses in &options.pose_counts {
        let grid = PoseGridSettings { poses, ..base.grid }.resolve(Symmetry::XZ)?;
        let simulated = simulate_poses(&blade, &base.material, grid)?;
        for encoding in options.encodings.iter().copied() {
            let table = compress_poses(&simulated, Symmetry::XZ, base.stages, encoding)?;
            let decoder = KeyframeDecoder::new(&table)?;
            let mut pose = vec![Vec3::ZERO; decoder.vertex_count()];
            for mode in PoseInterpolation::ALL {
                let (mut max, mut sum, mut n) = (0.0f32, 0.0f64, 0u64);
                for (force, exact) in &queries {
                    decoder.pose_positions(&decoder.select(*force, mode), mode, &mut pose);
                    for (p, e) in pose.iter().zip(exact) {
                        let err = (*p - *e).length();
                        max = max.max(err);
                        sum += (err as f64).powi(2);
                        n += 1;
                    }
                }
                let ns = best_of(TIMING_BATCHES, || {
                    for _ in 0..options.timing_repeats {
                        for (force, _) in &queries {
                            let blend = decoder.select(black_box(*force), mode);
                            decoder.pose_positions(&blend, mode, &mut pose);
                            black_box(&pose);
                        }
                    }
                });
                let blades = (options.timing_repeats * queries.len()).max(1);
                rows.push(PoseErrorRow {
                    poses,
                    interpolation: mode,
                    encoding,
                    error_max: max,
                    error_rms: (sum / n.max(1) as f64).sqrt() as f32,
                    ns_per_blade: ns / blades as f64,
                });
            }
        }
    }
    Ok(rows)
}

/// Where the decode time of each selection goes (the spherical selection's cost, measured).
#[derive(Clone, Debug, PartialEq)]
pub struct SelectionCost {
    /// Keyframes of the table measured.
    pub poses: u32,
    /// Vertices per blade.
    pub vertices: usize,
    /// Per selection: (mode, ns per blade of `select`, ns per blade of `pose_positions`).
    pub per_mode: Vec<(PoseInterpolation, f64, f64)>,
    /// ns per call of `furbake_grass::decode::slerp` on the vector pairs the spherical decode slerps.
    pub slerp_ns: f64,
    /// ns per call of the same slerp written with libm (`acos` and three `sin`, as before the
    /// polynomial version), on the same pairs.
    pub slerp_libm_ns: f64,
    /// `slerp` calls per blade (three per vertex: two along the angle, one along the magnitude).
    pub slerps_per_blade: usize,
}

impl SelectionCost {
    fn ns(&self, mode: PoseInterpolation) -> (f64, f64) {
        self.per_mode.iter().find(|m| m.0 == mode).map_or((0.0, 0.0), |m| (m.1, m.2))
    }

    /// The document's explanation, with the numbers.
    pub fn markdown(&self) -> String {
        let (ls, lp) = self.ns(PoseInterpolation::Linear);
        let (ss, sp) = self.ns(PoseInterpolation::Spherical);
        let (ns, np) = self.ns(PoseInterpolation::Nearest);
        let slerp_total = self.slerp_ns * self.slerps_per_blade as f64;
        format!(
            "Measured on the {}-keyframe f32 table with the queries above (ns per blade, one thread): \
             selection (`select`: grid coordinates, the four neighbouring keys, their weights) costs {ns:.0} / \
             {ls:.0} / {ss:.0} ns for nearest / linear / spherical, building the pose (`pose_positions`, {} vertices) \
             {np:.0} / {lp:.0} / {sp:.0} ns — spherical is {:.1}× linear. Selection is the same work for linear and \
             spherical; the difference is the pose. Linear blends the four keys' displacements with fixed weights (four \
             table reads and four multiply-adds per vertex). Spherical reads the same four, then slerps root→vertex \
             vectors three times per vertex (eq. 3.14: along the angle at both magnitudes, then along the magnitude): \
             {} slerps per blade, each an angle and two sines. A slerp measured alone on the same vector pairs \
             costs {:.1} ns written with libm (`acosf`, three `sinf`, two square roots, as `furbake-grass` had it) \
             and {:.1} ns as `furbake_grass::decode::slerp` now evaluates it (polynomial arccosine and sines accurate \
             to f32 round-off, at least as close to an f64 slerp): {:.0} ns against {slerp_total:.0} ns per blade, that is \
             {:.0} % of today's spherical pose. The rest of the gap to linear was not broken down further here (the \
             three slerps of a vertex are a dependent chain of square roots and divisions, which a replay of \
             independent slerps does not show). A shader evaluates these on its transcendental units.\n",
            self.poses,
            self.vertices,
            sp / lp.max(1e-9),
            self.slerps_per_blade,
            self.slerp_libm_ns,
            self.slerp_ns,
            self.slerp_libm_ns * self.slerps_per_blade as f64,
            100.0 * slerp_total / sp.max(1e-9),
        )
    }
}

/// Measures where each selection's decode time goes on a 1000-keyframe f32 table (or the largest
/// count of `options` below it).
pub fn measure_selection_cost(options: &GrassAccuracyOptions) -> Result<SelectionCost, GrassError> {
    let base = KeyframeSettings::thesis();
    let poses = options.pose_counts.iter().copied().filter(|&n| n <= 1000).max().unwrap_or(12);
    let blade = build_reference_blade(&base.shape)?;
    let grid = PoseGridSettings { poses, ..base.grid }.resolve(Symmetry::XZ)?;
    let simulated = simulate_poses(&blade, &base.material, grid)?;
    let table = compress_poses(&simulated, Symmetry::XZ, base.stages, DisplacementEncoding::F32)?;
    let decoder = KeyframeDecoder::new(&table)?;
    let mut rng = SplitMix64::new(0x5e1e_c7ed);
    let forces: Vec<Vec2> = (0..options.queries.max(1))
        .map(|_| {
            let mag = base.grid.max_force * rng.next_f32();
            let theta = std::f32::consts::TAU * rng.next_f32();
            Vec2::new(theta.sin(), theta.cos()) * mag
        })
        .collect();
    let repeats = options.timing_repeats.max(1);
    let blades = (repeats * forces.len()) as f64;
    let mut pose = vec![Vec3::ZERO; decoder.vertex_count()];
    let mut per_mode = Vec::new();
    for mode in PoseInterpolation::ALL {
        let select = best_of(TIMING_BATCHES, || {
            for _ in 0..repeats {
                for f in &forces {
                    black_box(decoder.select(black_box(*f), mode));
                }
            }
        }) / blades;
        let blends: Vec<_> = forces.iter().map(|f| decoder.select(*f, mode)).collect();
        let build = best_of(TIMING_BATCHES, || {
            for _ in 0..repeats {
                for b in &blends {
                    decoder.pose_positions(black_box(b), mode, &mut pose);
                    black_box(&pose);
                }
            }
        }) / blades;
        per_mode.push((mode, select, build));
    }
    // The slerps of the spherical decode, replayed alone.
    let mut pairs = Vec::new();
    for f in &forces {
        let b = decoder.select(*f, PoseInterpolation::Spherical);
        for v in 0..decoder.vertex_count() {
            let r = decoder.reference()[v];
            let p = b.keys.map(|k| r + decoder.displacement(k, v));
            pairs.push((p[0], p[1], b.t_angle));
        }
    }
    let slerp_ns = best_of(TIMING_BATCHES, || {
        for _ in 0..repeats {
            for &(a, b, t) in &pairs {
                black_box(furbake_grass::decode::slerp(black_box(a), black_box(b), t));
            }
        }
    }) / (repeats * pairs.len().max(1)) as f64;
    let slerp_libm_ns = best_of(TIMING_BATCHES, || {
        for _ in 0..repeats {
            for &(a, b, t) in &pairs {
                black_box(slerp_libm(black_box(a), black_box(b), t));
            }
        }
    }) / (repeats * pairs.len().max(1)) as f64;
    Ok(SelectionCost {
        poses,
        vertices: decoder.vertex_count(),
        per_mode,
        slerp_ns,
        slerp_libm_ns,
        slerps_per_blade: 3 * decoder.vertex_count(),
    })
}

/// The slerp of eq. 3.14 written with libm, as `furbake-grass` had it before its polynomial
/// version: the yardstick of [`SelectionCost::slerp_libm_ns`].
fn slerp_libm(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    let (la, lb) = (a.length(), b.length());
    if la == 0.0 || lb == 0.0 {
        return a.lerp(b, t);
    }
    let cos = (a.dot(b) / (la * lb)).clamp(-1.0, 1.0);
    let omega = cos.acos();
    let s = omega.sin();
    if s < 1e-6 {
        return a.lerp(b, t);
    }
    a * (((1.0 - t) * omega).sin() / s) + b * ((t * omega).sin() / s)
}

/// One row of the quantisation table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuantisationRow {
    /// Encoding.
    pub encoding: DisplacementEncoding,
    /// Stored displacement bits.
    pub payload_bits: u64,
    /// Uncompressed bits as the thesis counts them.
    pub raw_bits: u64,
    /// Largest vertex error against the unquantised poses, blade lengths.
    pub error_max: f32,
    /// RMS vertex error, blade lengths.
    pub error_rms: f32,
}

/// Measures every encoding of the thesis's table (table 2 of the report).
pub fn measure_quantisation() -> Result<Vec<QuantisationRow>, GrassError> {
    let s = KeyframeSettings::thesis();
    let blade = build_reference_blade(&s.shape)?;
    let poses = simulate_poses(&blade, &s.material, s.grid.resolve(s.symmetry)?)?;
    let all = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
    DisplacementEncoding::ALL
        .into_iter()
        .map(|encoding| {
            let t = compress_poses(&poses, s.symmetry, all, encoding)?;
            Ok(QuantisationRow {
                encoding,
                payload_bits: t.payload_bits(),
                raw_bits: t.raw_bits(),
                error_max: t.stats.error_max,
                error_rms: t.stats.error_rms,
            })
        })
        .collect()
}

/// One row of the force table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceErrorRow {
    /// Cluster edge, metres.
    pub cluster_size_m: f32,
    /// Delayed attenuation on.
    pub delayed: bool,
    /// Clusters in the field.
    pub clusters: usize,
    /// Largest per-blade force error, relative to the largest exact force.
    pub error_max_rel: f32,
    /// RMS per-blade force error, relative to the largest exact force.
    pub error_rms_rel: f32,
    /// CPU time of the corner update per frame, microseconds.
    pub update_us: f64,
    /// CPU time of the per-blade interpolation per frame (the GPU's work, on the CPU), microseconds.
    pub blades_us: f64,
    /// Blades in the field.
    pub blades: usize,
}

/// The force test scene: a concentrated source (σ = 2) in the middle of a 20 m × 20 m field and a
/// weaker, spread one (σ = 1) in a corner.
pub fn force_test_scene(delayed: bool) -> ForceScene {
    ForceScene {
        global_wind: Vec2::ZERO,
        sources: vec![
            BladeWindSource { position_m: Vec3::new(0.7, 0.3, -0.4), power: 3.0, falloff_exponent: 2.0, delayed },
            BladeWindSource { position_m: Vec3::new(-8.0, 0.5, 7.0), power: 2.0, falloff_exponent: 1.0, delayed },
        ],
        min_distance_m: 0.25,
        ..ForceScene::default()
    }
}

/// Measures per-blade force error and CPU time per frame (table 3 of the report).
pub fn measure_force_error(options: &GrassAccuracyOptions) -> Result<Vec<ForceErrorRow>, GrassError> {
    let mesh = ground_grid_mesh([20.0, 20.0], [4, 4]);
    let mut rows = Vec::new();
    for &size in &options.cluster_sizes_m {
        let settings = BladeFieldSettings {
            density_per_m2: options.field_density_per_m2,
            cluster_size_m: size,
            ..BladeFieldSettings::default()
        };
        let field = scatter_blades(&mesh, &settings)?;
        let soa = BladeSoa::from_field(&field);
        for delayed in [false, true] {
            let scene = force_test_scene(delayed);
            let exact_scene = force_test_scene(false);
            let mut forces = ForceField::new(field.grid);
            let update_us = best_of(4 * TIMING_BATCHES, || forces.update(black_box(&scene))) / 1e3;
            let mut out = vec![Vec2::ZERO; soa.len()];
            let blades_us = best_of(TIMING_BATCHES, || {
                for (b, o) in out.iter_mut().enumerate() {
                    let p = Vec3::new(soa.x[b], soa.y[b], soa.z[b]);
                    *o = forces.blade_force(soa.corners[b], soa.weights[b], p);
                }
                black_box(&out);
            }) / 1e3;
            let (mut max, mut sum, mut peak) = (0.0f32, 0.0f64, 0.0f32);
            for (b, f) in out.iter().enumerate() {
                let p = Vec3::new(soa.x[b], soa.y[b], soa.z[b]);
                let e = exact_scene.force_at(p);
                peak = peak.max(e.length());
                let err = (*f - e).length();
                max = max.max(err);
                sum += (err as f64).powi(2);
            }
            let peak = peak.max(f32::MIN_POSITIVE);
            rows.push(ForceErrorRow {
                cluster_size_m: size,
                delayed,
                clusters: field.grid.clusters(),
                error_max_rel: max / peak,
                error_rms_rel: (sum / out.len().max(1) as f64).sqrt() as f32 / peak,
                update_us,
                blades_us,
                blades: out.len(),
            });
        }
    }
    Ok(rows)
}

/// The grass part of the document: its markdown (starts with a `## Grass` heading) and its chart.
#[derive(Clone, Debug)]
pub struct GrassReport {
    /// The markdown.
    pub markdown: String,
    /// (file name, SVG text) of the plots the markdown links to.
    pub plots: Vec<(String, String)>,
    /// The pose rows.
    pub poses: Vec<PoseErrorRow>,
    /// Point labels left out of the chart for lack of room.
    pub labels_omitted: usize,
}

/// The chart file of the grass pose table.
pub const POSE_CHART: &str = "accuracy_grass_pose.svg";

/// Pose error against decode time: two panels (max, RMS), colour by selection, marker by
/// encoding, each point labelled with its keyframe count, the Pareto front drawn.
pub fn pose_chart(rows: &[PoseErrorRow]) -> (String, usize) {
    use crate::svg::{COLORS, Figure, Marker, Panel, Point, Series, render};
    let mut panels = Vec::new();
    for (metric, get) in
        [("max", (|r: &PoseErrorRow| r.error_max) as fn(&PoseErrorRow) -> f32), ("RMS", |r| r.error_rms)]
    {
        let mut series = Vec::new();
        for (si, mode) in PoseInterpolation::ALL.into_iter().enumerate() {
            for (ei, enc) in DisplacementEncoding::ALL.into_iter().enumerate() {
                let points: Vec<Point> = rows
                    .iter()
                    .filter(|r| r.interpolation == mode && r.encoding == enc)
                    .map(|r| Point { x: r.ns_per_blade, y: get(r) as f64, label: r.poses.to_string() })
                    .collect();
                if points.is_empty() {
                    continue;
                }
                series.push(Series {
                    name: format!("{} · {}", mode.name(), enc.name()),
                    color: COLORS[si % COLORS.len()].to_owned(),
                    marker: Marker::ALL[ei % Marker::ALL.len()],
                    filled: ei % 2 == 0,
                    line: false,
                    points,
                });
            }
        }
        panels.push(Panel {
            title: format!("{metric} vertex error"),
            x_title: "decode time per blade, one CPU thread (ns)".into(),
            y_title: format!("{metric} vertex error (blade lengths)"),
            series,
            pareto: true,
        });
    }
    render(&Figure {
        title: "Grass keyframes: pose error against decode cost".into(),
        columns: 2,
        panels,
        legend_notes: vec!["colour: selection; marker: encoding".into(), "labels: keyframe count".into()],
    })
}

/// The grass section of `docs/accuracy.md`, as markdown (starts with a `## Grass` heading).
pub fn grass_accuracy_markdown(options: &GrassAccuracyOptions) -> Result<String, GrassError> {
    Ok(grass_accuracy(options)?.markdown)
}

/// Runs every grass measurement and renders the grass part of the document.
pub fn grass_accuracy(options: &GrassAccuracyOptions) -> Result<GrassReport, GrassError> {
    let poses = measure_pose_error(options)?;
    let quant = measure_quantisation()?;
    let forces = measure_force_error(options)?;
    let spherical = measure_selection_cost(options)?;
    let (chart, labels_omitted) = pose_chart(&poses);
    let machine = crate::fur::machine();
    let mut md = String::new();
    let w = &mut md;
    // `write!` into a String cannot fail.
    let _ = writeln!(w, "## Grass\n");
    let _ = writeln!(
        w,
        "Measured by `furbake-report` on `furbake-grass`. Machine: {machine}. Times are the fastest of \
         {TIMING_BATCHES} wall-clock batches and still move with machine load.\n"
    );
    let _ = writeln!(w, "### Pose error against the direct simulation, by keyframe count, selection and encoding\n");
    let _ = writeln!(
        w,
        "Scene: the thesis's reference blade (`KeyframeSettings::thesis()`, 8 segments, 32 vertices), xz symmetry, \
         every compression stage; {} random query forces (magnitude uniform in [0, max], any angle). Metric: each \
         decoded pose is compared with the blade settled directly under that force (the reference: \
         `BladeSimulator::settle`, no keyframes, no quantisation); **max** = the largest vertex distance over all \
         vertices of all queries, **RMS** = root mean square over them, in blade lengths. Floor: the settle's own \
         tolerance, far below every cell. Cost: selection plus all 32 vertices of one blade on one CPU thread, ns. \
         The decoder dequantises the table once when it is built, so the decode time does not depend on the \
         encoding (the cells differ by noise only).\n",
        options.queries
    );
    let _ = writeln!(w, "![grass pose error against decode time]({POSE_CHART})\n");
    let _ = writeln!(w, "| keyframes | selection | encoding | max error | RMS error | decode ns/blade |");
    let _ = writeln!(w, "|---:|---|---|---:|---:|---:|");
    for r in &poses {
        let _ = writeln!(
            w,
            "| {} | {} | {} | {:.2e} | {:.2e} | {:.0} |",
            r.poses,
            r.interpolation.name(),
            r.encoding.name(),
            r.error_max,
            r.error_rms,
            r.ns_per_blade
        );
    }
    let _ = writeln!(w, "\n### Why spherical selection costs more than linear\n");
    let _ = writeln!(w, "{}", spherical.markdown());
    let _ = writeln!(w, "\n### Quantisation (8 segments, 1000 poses, every stage, xz symmetry)\n");
    let _ = writeln!(w, "Error against the unquantised poses, in blade lengths.\n");
    let _ = writeln!(w, "| encoding | payload bits | bytes | of raw | max error | RMS error |");
    let _ = writeln!(w, "|---|---:|---:|---:|---:|---:|");
    for r in &quant {
        let _ = writeln!(
            w,
            "| {} | {} | {} | {:.2}% | {:.2e} | {:.2e} |",
            r.encoding.name(),
            r.payload_bits,
            r.payload_bits / 8,
            100.0 * r.payload_bits as f64 / r.raw_bits as f64,
            r.error_max,
            r.error_rms
        );
    }
    let _ = writeln!(w, "\n### Per-blade force error by cluster size (fig. 4.7 vs 4.8)\n");
    let blades = forces.first().map_or(0, |r| r.blades);
    let _ = writeln!(
        w,
        "{blades} blades on 20 m × 20 m, a concentrated source (σ = 2) and a spread one (σ = 1). Error relative \
         to the largest exact force; the max error comes from the blades in the concentrated source's own \
         cluster, where the corners' directions disagree (delayed attenuation then scales a meaningless direction \
         by a large magnitude), the RMS error from the whole field. The corner update is the CPU's work per \
         frame; the per-blade interpolation is the vertex shader's, timed here on one CPU thread.\n"
    );
    let _ =
        writeln!(w, "| cluster m | clusters | delayed | max error | RMS error | update µs/frame | blades µs/frame |");
    let _ = writeln!(w, "|---:|---:|---|---:|---:|---:|---:|");
    for r in &forces {
        let _ = writeln!(
            w,
            "| {} | {} | {} | {:.3} | {:.4} | {:.1} | {:.0} |",
            r.cluster_size_m,
            r.clusters,
            if r.delayed { "yes" } else { "no" },
            r.error_max_rel,
            r.error_rms_rel,
            r.update_us,
            r.blades_us
        );
    }
    Ok(GrassReport { markdown: md, plots: vec![(POSE_CHART.to_owned(), chart)], poses, labels_omitted })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_small_report_has_every_table_and_sensible_trends() {
        let options = GrassAccuracyOptions {
            pose_counts: vec![12, 400],
            encodings: vec![DisplacementEncoding::F32, DisplacementEncoding::Unorm8],
            queries: 30,
            timing_repeats: 2,
            cluster_sizes_m: vec![0.5, 4.0],
            field_density_per_m2: 5.0,
        };
        let poses = measure_pose_error(&options).expect("measures");
        assert_eq!(poses.len(), 2 * 2 * 3);
        let err = |n, m| {
            let f32_row =
                |r: &&PoseErrorRow| r.poses == n && r.interpolation == m && r.encoding == DisplacementEncoding::F32;
            poses.iter().find(f32_row).expect("row").error_rms
        };
        // 8-bit encoding adds error to the f32 table's.
        let coarse = poses
            .iter()
            .find(|r| {
                r.poses == 400
                    && r.interpolation == PoseInterpolation::Linear
                    && r.encoding == DisplacementEncoding::Unorm8
            })
            .expect("row");
        assert!(coarse.error_rms >= err(400, PoseInterpolation::Linear));
        for m in PoseInterpolation::ALL {
            assert!(err(400, m) < err(12, m), "{m:?}: more keyframes, less error");
        }
        assert!(err(400, PoseInterpolation::Linear) < err(400, PoseInterpolation::Nearest));
        let forces = measure_force_error(&options).expect("measures");
        assert_eq!(forces.len(), 4);
        let f = |size: f32, delayed| {
            forces.iter().find(|r| r.cluster_size_m == size && r.delayed == delayed).expect("row").error_rms_rel
        };
        assert!(f(0.5, false) < f(4.0, false), "smaller clusters, less error");
        assert!(f(4.0, true) < f(4.0, false), "delayed attenuation removes cluster artefacts");
        let md = grass_accuracy_markdown(&GrassAccuracyOptions { pose_counts: vec![12], ..options.clone() })
            .expect("writes");
        assert!(md.starts_with("## Grass"));
        assert_eq!(md.matches("\n### ").count(), 4);
        assert!(md.contains("Why spherical selection costs more than linear"));
        for enc in DisplacementEncoding::ALL {
            assert!(md.contains(&format!("| {} |", enc.name())), "{enc:?} row");
        }
        assert!(md.contains("| 180000 | 22500 |"), "the thesis's 180,000 bits appear");
        let cost = measure_selection_cost(&options).expect("measures");
        assert_eq!((cost.poses, cost.slerps_per_blade), (400, 3 * cost.vertices));
        assert!(cost.slerp_ns > 0.0 && cost.per_mode.len() == 3);
    }
}
