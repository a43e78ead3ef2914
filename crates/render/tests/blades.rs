//! GPU grass blades (`BladeRenderer`, `shaders/blades.wgsl`) against furbake-grass's CPU reference
//! (grass thesis §3.2.5–3.2.6, §4.2): the compute pass's world-space vertex positions are read
//! back and compared with `KeyframeDecoder::world_positions` at `ForceField::blade_force` for a
//! few hundred blades under nonuniform force fields (global wind + one point source; global wind +
//! three point sources, eq. 4.1; the same with two delayed-attenuation sources, fig. 4.8, and a
//! windless area, uploaded with `set_force_scene`), for every displacement encoding,
//! every symmetry and both GPU interpolation modes; and a rendered grass patch is green and bends
//! downwind. Runs on whatever adapter the machine has (lavapipe without a GPU) and never skips:
//! without an adapter the tests fail with the command that installs lavapipe.

use std::sync::OnceLock;

use crate::common::gpu;
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, KeyframeTable, Symmetry};
use furbake_grass::keyframes::{PoseGridSettings, SimulatedPoses};
use furbake_grass::{
    BladeFieldSettings, BladeMaterial, BladeShape, BladeWindSource, ForceField, ForceScene, KeyframeDecoder,
    PoseInterpolation, build_reference_blade, compress_poses, ground_grid_mesh, scatter_blades, simulate_poses,
};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::{BladeRenderSettings, BladeRenderer, BladeShading, View};
use furbake_runtime::{Camera, Light};
use glam::{Vec2, Vec3, Vec3Swizzles};
use image::RgbaImage;

/// 400 poses (10 magnitudes × 40 angles) of the default 8-segment blade, simulated once.
fn poses() -> &'static SimulatedPoses {
    static POSES: OnceLock<SimulatedPoses> = OnceLock::new();
    POSES.get_or_init(|| {
        let grid = PoseGridSettings { poses: 400, ..Default::default() }.resolve(Symmetry::XZ).unwrap();
        let blade = build_reference_blade(&BladeShape::default()).unwrap();
        simulate_poses(&blade, &BladeMaterial::default(), grid).unwrap()
    })
}

fn table(symmetry: Symmetry, encoding: DisplacementEncoding) -> KeyframeTable {
    let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
    compress_poses(poses(), symmetry, stages, encoding).unwrap()
}

/// A 2 m × 2 m patch, 80 blades/m² (≈ 320 blades), clusters of 0.5 m.
fn patch() -> BladeField {
    let settings = BladeFieldSettings { density_per_m2: 80.0, cluster_size_m: 0.5, ..Default::default() };
    scatter_blades(&ground_grid_mesh([2.0, 2.0], [4, 4]), &settings).unwrap()
}

/// Global wind along +x plus a point source near a corner: force varies in size and direction
/// over the patch and spans the whole pose grid (up to and past `max_force` = 4).
fn gusty_scene() -> ForceScene {
    ForceScene {
        global_wind: Vec2::new(1.5, 0.4),
        sources: vec![BladeWindSource {
            position_m: Vec3::new(-0.6, 0.1, 0.5),
            power: 1.2,
            falloff_exponent: 1.0,
            delayed: false,
        }],
        ..ForceScene::default()
    }
}

/// Fraction of a grid cell within which a CPU grid coordinate counts as on a nearest-pose
/// rounding boundary (where a 1-ulp difference in the force may legitimately pick the neighbour).
const BOUNDARY: f32 = 1e-4;

/// Global wind plus three point sources of different power and falloff_exponent (eq. 4.1), one
/// inside the patch, one at its edge and one far away: the per-blade force (four cluster corner
/// forces × bilinear weights, eq. 3.6) varies in size and direction across every cluster.
fn three_source_scene() -> ForceScene {
    let source = |x, z, power, falloff_exponent| BladeWindSource {
        position_m: Vec3::new(x, 0.2, z),
        power,
        falloff_exponent,
        delayed: false,
    };
    ForceScene {
        global_wind: Vec2::new(0.3, -0.5),
        sources: vec![source(0.3, -0.2, 0.6, 1.5), source(-1.1, 0.9, 1.5, 1.0), source(-6.0, 4.0, 20.0, 1.2)],
        ..ForceScene::default()
    }
}

#[test]
fn gpu_blade_positions_match_the_cpu_reference() {
    compare_with_cpu(&gusty_scene(), "gusty", false);
}

#[test]
fn gpu_blade_forces_match_the_cpu_field_with_three_wind_sources() {
    compare_with_cpu(&three_source_scene(), "three sources", false);
}

#[test]
fn gpu_delayed_attenuation_matches_the_cpu_field() {
    // The same three sources, two of them with delayed attenuation (fig. 4.8), plus a windless
    // area over a corner of the patch: the GPU evaluates the delayed sources per blade.
    let mut scene = three_source_scene();
    scene.sources[0].delayed = true;
    scene.sources[1].delayed = true;
    scene.blockers.push(furbake_grass::WindBlocker { min_m: Vec2::new(-1.5, -1.5), max_m: Vec2::new(-0.7, -0.7) });
    compare_with_cpu(&scene, "three sources, two delayed", true);
    // Without them (set_force_field drops delayed sources) the GPU would differ.
    let field = patch();
    let mut forces = ForceField::new(field.grid);
    forces.update(&scene);
    let differs = (0..field.blade_count())
        .filter(|&b| {
            let corners = field.grid.corner_indices(field.cluster[b]);
            let undelayed: Vec2 = (0..4).map(|k| forces.corner_forces[corners[k] as usize] * field.weights[b][k]).sum();
            let full = forces.blade_force(corners, field.weights[b], Vec3::from(field.positions[b]));
            (full - undelayed).length() > 0.05
        })
        .count();
    assert!(differs * 2 > field.blade_count(), "delayed sources change only {differs} blade forces");
}

/// Reads back every blade's GPU positions under the field of `scene` and compares them with
/// the CPU decode at `ForceField::blade_force` for every encoding, symmetry and GPU interpolation.
/// `with_scene`: upload through `set_force_scene` (delayed sources on the GPU), else
/// `set_force_field`.
fn compare_with_cpu(scene: &ForceScene, name: &str, with_scene: bool) {
    let field = patch();
    let n = field.blade_count();
    assert!((250..=400).contains(&n), "{n} blades");
    let mut forces = ForceField::new(field.grid);
    forces.update(scene);
    let cases = [
        (Symmetry::XZ, DisplacementEncoding::Snorm16),
        (Symmetry::X, DisplacementEncoding::F16),
        (Symmetry::None, DisplacementEncoding::Snorm8),
        (Symmetry::XZ, DisplacementEncoding::Unorm8),
        (Symmetry::None, DisplacementEncoding::F32),
    ];
    let (mut compared, mut boundary_blades, mut worst) = (0usize, 0usize, 0.0f32);
    let mut moved = 0usize;
    let mut poses_seen = std::collections::HashSet::new();
    for (symmetry, encoding) in cases {
        let table = table(symmetry, encoding);
        let decoder = KeyframeDecoder::new(&table).unwrap();
        let vc = decoder.vertex_count();
        for interpolation in [PoseInterpolation::Nearest, PoseInterpolation::Linear] {
            let settings = BladeRenderSettings { interpolation, ..Default::default() };
            let blades =
                BladeRenderer::new(gpu().pipelines(), &gpu().queue, &field, &table, &settings, &RenderTarget::desc())
                    .unwrap();
            assert_eq!((blades.blade_count() as usize, blades.vertex_count() as usize), (n, vc));
            if with_scene {
                blades.set_force_scene(&gpu().queue, &forces, scene).unwrap();
            } else {
                blades.set_force_field(&gpu().queue, &forces).unwrap();
            }
            blades.compute(&gpu().device, &gpu().queue).unwrap();
            let got = blades.read_positions(&gpu().device, &gpu().queue).unwrap();
            assert_eq!(got.len(), n * vc);
            let mut cpu = vec![Vec3::ZERO; vc];
            let mut rest = vec![Vec3::ZERO; vc];
            for b in 0..n {
                let root = Vec3::from(field.positions[b]);
                let corners = field.grid.corner_indices(field.cluster[b]);
                let f = forces.blade_force(corners, field.weights[b], root);
                let (yaw, h) = (field.yaw_rad[b], field.height_scale[b]);
                decoder.world_positions(root, yaw, h, f.extend(0.0).xzy(), interpolation, &mut cpu);
                decoder.world_positions(root, yaw, h, Vec3::ZERO, interpolation, &mut rest);
                if cpu[vc - 1].distance(rest[vc - 1]) > 0.01 {
                    moved += 1;
                }
                let (s, c) = yaw.sin_cos();
                let local = Vec2::new(f.x * c - f.y * s, f.x * s + f.y * c);
                let (mu, alpha) = decoder.grid_coordinates(local);
                poses_seen.insert((mu.round() as u32, alpha.round() as i32));
                let err = (0..vc).map(|v| Vec3::from(got[b * vc + v]).distance(cpu[v])).fold(0.0f32, f32::max);
                // A zero force (all four corners in a windless area) is no boundary: magnitude 0
                // selects the rest pose whatever the angle.
                let on_boundary = interpolation == PoseInterpolation::Nearest
                    && f != Vec2::ZERO
                    && [mu + 0.5, alpha + 0.5].iter().any(|x| {
                        let fr = x - x.floor();
                        !(BOUNDARY..=1.0 - BOUNDARY).contains(&fr)
                    });
                if on_boundary {
                    boundary_blades += 1;
                    continue;
                }
                // Tolerance 1e-5 m: the GPU runs the same f32 operations in the same order as the
                // CPU (force gather, blade-local projection, fast_atan2 polynomial, dequantisation,
                // the weighted sum, the yaw/height transform); what differs is the GPU's freedom to
                // fuse multiply-adds and WGSL's 2.5-ulp division, i.e. a few ulps of values below
                // ~2 m. Measured on lavapipe (Mesa llvmpipe): max 0 m, bit-identical, over all 3200 comparisons
                // (printed below); 1e-5 m leaves room for FMA-contracting hardware drivers.
                assert!(
                    err < 1e-5,
                    "{symmetry:?}/{encoding:?}/{interpolation:?}: blade {b} differs by {err} m (force {f})"
                );
                worst = worst.max(err);
                compared += 1;
            }
        }
    }
    println!(
        "{name}: compared {compared} blade poses, {boundary_blades} on a rounding boundary, max error {worst:e} m, {} grid cells",
        poses_seen.len()
    );
    // Everything but a handful of boundary cases was compared, and the field really posed blades.
    assert!(boundary_blades <= 5, "{boundary_blades} blades on a nearest-pose boundary");
    assert!(compared >= 10 * n - 5, "{compared} comparisons");
    assert!(moved >= 10 * n * 9 / 10, "only {moved} of {} blade poses moved visibly", 10 * n);
    assert!(poses_seen.len() >= 20, "the scene reaches {} distinct grid cells", poses_seen.len());
}

#[test]
fn bad_inputs_are_refused() {
    let field = patch();
    let table = table(Symmetry::XZ, DisplacementEncoding::Snorm16);
    let (device, queue, pipelines) = (&gpu().device, &gpu().queue, gpu().pipelines());
    let spherical = BladeRenderSettings { interpolation: PoseInterpolation::Spherical, ..Default::default() };
    assert!(BladeRenderer::new(pipelines, queue, &field, &table, &spherical, &RenderTarget::desc()).is_err());
    let mut broken = table.clone();
    broken.vertex_map[3] = broken.stored_vectors + 7;
    assert!(
        BladeRenderer::new(pipelines, queue, &field, &broken, &BladeRenderSettings::default(), &RenderTarget::desc())
            .is_err()
    );
    let mut short = field.clone();
    short.yaw_rad.pop();
    assert!(
        BladeRenderer::new(pipelines, queue, &short, &table, &BladeRenderSettings::default(), &RenderTarget::desc())
            .is_err()
    );
    let mut lost = field.clone();
    lost.cluster[0] = lost.grid.clusters() as u32;
    assert!(
        BladeRenderer::new(pipelines, queue, &lost, &table, &BladeRenderSettings::default(), &RenderTarget::desc())
            .is_err()
    );
    let blades =
        BladeRenderer::new(pipelines, queue, &field, &table, &BladeRenderSettings::default(), &RenderTarget::desc())
            .unwrap();
    assert!(blades.read_positions(device, queue).is_err(), "nothing computed yet");
    let corners = field.grid.corners();
    assert!(blades.set_corner_forces(queue, &vec![[0.0; 2]; corners - 1]).is_err());
    assert!(blades.set_corner_forces(queue, &vec![[f32::NAN, 0.0]; corners]).is_err());
    assert!(blades.set_corner_forces(queue, &vec![[0.5, 0.0]; corners]).is_ok());
}

#[test]
fn from_pack_uploads_the_packs_blade_field_and_keyframe_table() {
    let field = patch();
    let table = table(Symmetry::XZ, DisplacementEncoding::Snorm16);
    let dir = tempfile::tempdir().unwrap();
    let grass = dir.path().join("grass.fbk");
    furbake_formats::PackWriter::new().push_section(&field).push_section(&table).write_atomic(&grass).unwrap();
    let bare = dir.path().join("table_only.fbk");
    furbake_formats::PackWriter::new().push_section(&table).write_atomic(&bare).unwrap();
    let (device, queue, pipelines) = (&gpu().device, &gpu().queue, gpu().pipelines());
    let settings = BladeRenderSettings::default();
    let pack = furbake_runtime::Pack::open(&bare).unwrap();
    assert!(
        BladeRenderer::from_pack(pipelines, queue, &pack, &settings, &RenderTarget::desc()).unwrap().is_none(),
        "no blade field"
    );
    let pack = furbake_runtime::Pack::open(&grass).unwrap();
    let from_pack = BladeRenderer::from_pack(pipelines, queue, &pack, &settings, &RenderTarget::desc())
        .unwrap()
        .expect("a blade field");
    let direct = BladeRenderer::new(pipelines, queue, &field, &table, &settings, &RenderTarget::desc()).unwrap();
    let mut forces = ForceField::new(field.grid);
    forces.update(&gusty_scene());
    let mut positions = Vec::new();
    for blades in [&from_pack, &direct] {
        blades.set_force_field(queue, &forces).unwrap();
        blades.compute(device, queue).unwrap();
        positions.push(blades.read_positions(device, queue).unwrap());
    }
    assert_eq!(positions[0].len(), field.blade_count() * table.vertex_count());
    assert_eq!(positions[0], positions[1]);
    // Every computed vertex lies inside the advertised bounding sphere.
    let (center, radius) = from_pack.bounding_sphere();
    let outside = positions[0].iter().filter(|p| Vec3::from(**p).distance(Vec3::from(center)) > radius).count();
    assert_eq!(outside, 0, "vertices outside the bounding sphere ({center:?}, {radius})");
}

const SIZE: u32 = 192;

/// A 1 m × 1 m patch, 150 blades/m², for the render tests.
fn small_patch() -> BladeField {
    let settings = BladeFieldSettings { density_per_m2: 150.0, cluster_size_m: 0.5, ..Default::default() };
    scatter_blades(&ground_grid_mesh([1.0, 1.0], [2, 2]), &settings).unwrap()
}

/// Side view of the patch: camera on +z looking at −z, so +x (downwind) is to the right.
fn side_view() -> View {
    View {
        camera: Camera { eye: [0.0, 0.5, 1.8], target: [0.0, 0.12, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 35.0 },
        lighting: Light::default().into(),
        bounds_center: [0.0, 0.12, 0.0],
        bounds_radius: 1.0,
    }
}

fn render(field: &BladeField, table: &KeyframeTable, scene: &ForceScene) -> RgbaImage {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let blades = BladeRenderer::new(
        gpu().pipelines(),
        queue,
        field,
        table,
        &BladeRenderSettings::default(),
        &RenderTarget::desc(),
    )
    .unwrap();
    let mut forces = ForceField::new(field.grid);
    forces.update(scene);
    blades.set_force_field(queue, &forces).unwrap();
    let target = RenderTarget::new(device, SIZE, SIZE).unwrap();
    blades.render_to(device, queue, &target, &side_view(), Some([0.0, 0.0, 0.0, 0.0])).unwrap();
    read_back(device, queue, &target).unwrap()
}

/// Count and mean x of drawn pixels (alpha > 0) in rows `rows`.
fn coverage(image: &RgbaImage, rows: std::ops::Range<u32>) -> (usize, f64) {
    let (mut n, mut sx) = (0usize, 0.0f64);
    for (x, y, p) in image.enumerate_pixels() {
        if p[3] > 0 && rows.contains(&y) {
            n += 1;
            sx += x as f64;
        }
    }
    (n, sx / n.max(1) as f64)
}

/// The row above which half of the drawn pixels lie.
fn median_row(image: &RgbaImage) -> u32 {
    let rows: Vec<u32> = image.enumerate_pixels().filter(|(_, _, p)| p[3] > 0).map(|(_, y, _)| y).collect();
    rows.get(rows.len() / 2).copied().unwrap_or(0)
}

#[test]
fn a_grass_patch_renders_green_and_bends_downwind() {
    let field = small_patch();
    let table = table(Symmetry::XZ, DisplacementEncoding::Snorm16);
    let calm = render(&field, &table, &ForceScene::default());
    let windy = render(&field, &table, &ForceScene { global_wind: Vec2::new(4.0, 0.0), ..ForceScene::default() });
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    calm.save(dir.join("grass_calm.png")).unwrap();
    windy.save(dir.join("grass_wind.png")).unwrap();
    let (n_calm, x_calm) = coverage(&calm, 0..SIZE);
    let (n_windy, x_windy) = coverage(&windy, 0..SIZE);
    // Blades are drawn, and every drawn pixel is green (Lambert only scales the colour).
    assert!(n_calm > 1500 && n_windy > 1500, "{n_calm} calm and {n_windy} windy blade pixels");
    let mut green = 0;
    for p in calm.pixels().chain(windy.pixels()).filter(|p| p[3] > 0) {
        assert!(p[1] > p[0] && p[1] > p[2], "blade pixel {p:?} is not green");
        green += 1;
    }
    assert_eq!(green, n_calm + n_windy);
    // Wind along +x (to the right in this view) moves blade pixels right. Displacement grows
    // towards the tips (≈ 0.2 blade lengths ≈ 0.05 m ≈ 8 px here, averaged over yaw), so compare
    // the upper half of the calm grass's rows too.
    let top = 0..median_row(&calm);
    let (_, top_calm) = coverage(&calm, top.clone());
    let (_, top_windy) = coverage(&windy, top);
    println!(
        "centroid x: calm {x_calm:.1} px, windy {x_windy:.1} px; upper half calm {top_calm:.1}, windy {top_windy:.1}; {n_calm} / {n_windy} pixels"
    );
    assert!(x_windy > x_calm + 1.0, "centroid x: calm {x_calm:.1}, windy {x_windy:.1}");
    assert!(top_windy > top_calm + 2.0, "upper-half centroid x: calm {top_calm:.1}, windy {top_windy:.1}");
}

#[test]
fn blades_draw_over_what_the_target_holds_without_a_clear() {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let table = table(Symmetry::XZ, DisplacementEncoding::Snorm16);
    let left = small_patch();
    // The same patch moved 0.6 m to the right (x), drawn teal.
    let mut right = left.clone();
    right.grid.origin_m[0] += 0.6;
    for p in &mut right.positions {
        p[0] += 0.6;
    }
    let target = RenderTarget::new(device, SIZE, SIZE).unwrap();
    let view =
        View { camera: Camera { eye: [0.3, 0.5, 2.2], target: [0.3, 0.12, 0.0], ..side_view().camera }, ..side_view() };
    // Flat shading: this test is about compositing, and a flat teal is recognisable exactly.
    let flat_green = BladeRenderSettings { shading: BladeShading::FLAT, ..Default::default() };
    let first =
        BladeRenderer::new(gpu().pipelines(), queue, &left, &table, &flat_green, &RenderTarget::desc()).unwrap();
    first.render_to(device, queue, &target, &view, Some([0.0, 0.0, 1.0, 1.0])).unwrap();
    let teal = BladeRenderSettings { color: [0.0, 0.5, 0.5], shading: BladeShading::FLAT, ..Default::default() };
    let second = BladeRenderer::new(gpu().pipelines(), queue, &right, &table, &teal, &RenderTarget::desc()).unwrap();
    second.render_to(device, queue, &target, &view, None).unwrap();
    let image = read_back(device, queue, &target).unwrap();
    image.save(std::env::temp_dir().join("furbake-render-tests").join("grass_two_patches.png")).ok();
    // Background stays blue, the first patch's green blades survive the second pass, and the
    // second patch's teal (equal green and blue) blades are added.
    let (mut blue, mut green, mut teal_px) = (0, 0, 0);
    for p in image.pixels() {
        if p[0] == 0 && p[1] == 0 && p[2] == 255 {
            blue += 1;
        } else if p[1] > p[0] && p[1] > p[2] {
            green += 1;
        } else if p[0] == 0 && p[1] > 0 && p[1].abs_diff(p[2]) <= 1 {
            teal_px += 1;
        }
    }
    assert!(blue > 10_000 && green > 1000 && teal_px > 1000, "{blue} blue, {green} green, {teal_px} teal pixels");
}
