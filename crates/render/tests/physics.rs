//! The renderer against the CPU physics reference (fur thesis §3.4.2–3.4.3, eq. 3.35–3.37):
//! scale vectors come from a real `furbake_sim::Simulator` run (gravity + steady wind on the
//! baked prisms topology of a sphere and of a plane), go into `FurRenderer::set_scale_vectors`,
//! and (1) the sheared shell positions the shell vertex shader draws — read back through the
//! same WGSL function (`shell_vertex`, compute entry `cs_shell_positions`) — match
//! `furbake_sim::shell_vertex_position`, also for scale vectors pointing into the surface, where
//! both drop exactly the inward component; (2) rendered, the fur bends towards
//! the wind and never appears below the surface. Runs on whatever adapter the machine has
//! (lavapipe without a GPU) and never skips.

use std::sync::{Arc, OnceLock};

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::{FurAsset, FurRenderer, RenderSettings, View};
use furbake_runtime::{Camera, Light};
use furbake_sim::{
    ForceSet, Simulator, SolverKind, SolverSettings, SpringTopology, WindForce, shell_offset, shell_vertex_position,
};
use glam::Vec3;
use image::RgbaImage;

/// Bakes `gltf` with 16 layers of 64² shells, the given fur length and the prisms topology.
fn bake_with_prisms(gltf: &[u8], name: &str, fur_length_m: f32) -> (FurAsset, SpringTopology) {
    let imported = import_gltf_slice(gltf, name, None, &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset("fur").unwrap();
    settings.volume.layers = 16;
    settings.volume.resolution = 64;
    settings.shells.fur_length_m = Some(fur_length_m);
    settings.topologies = vec!["prisms".into()];
    let mut baked = bake(&imported, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    let topology = baked.topologies.pop().expect("the prisms topology was asked for");
    let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
    let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins).unwrap();
    (asset, topology)
}

/// A unit sphere with 0.15 m fur and its prisms topology.
fn sphere() -> &'static (FurAsset, SpringTopology) {
    static SPHERE: OnceLock<(FurAsset, SpringTopology)> = OnceLock::new();
    SPHERE.get_or_init(|| bake_with_prisms(&testmesh::uv_sphere(16, 24, 1.0).gltf, "sphere.gltf", 0.15))
}

/// A 2 m plane (normal +Y, partly bare) with 0.3 m fur and its prisms topology.
fn plane() -> &'static (FurAsset, SpringTopology) {
    static PLANE: OnceLock<(FurAsset, SpringTopology)> = OnceLock::new();
    PLANE.get_or_init(|| bake_with_prisms(&testmesh::plane_with_bare_region(8, 2.0).gltf, "plane.gltf", 0.3))
}

/// Scale vectors after `steps` implicit steps of 1/60 s under gravity and a steady wind along
/// +X of `wind_n` newtons per mass.
fn simulated_scale_vectors(topology: &SpringTopology, wind_n: f32, steps: u32) -> Vec<[f32; 3]> {
    let mut sim = Simulator::new(topology, SolverSettings::of(SolverKind::Implicit)).unwrap();
    let wind = WindForce { direction: [1.0, 0.0, 0.0], force_n: wind_n, gust_amplitude: 0.0, ..WindForce::default() };
    sim.set_forces(ForceSet { wind: Some(wind), ..ForceSet::default() }).unwrap();
    for _ in 0..steps {
        sim.step(1.0 / 60.0).unwrap();
    }
    sim.scale_vectors()
}

/// Whether the wrong-side guard (§3.4.3) has work to do at a shell position: the unguarded
/// eq. 3.36 offset (normal step plus shear) points below the skin's tangent plane.
fn guard_fires(n: Vec3, s: Vec3, layer: u32, layers: u32, k: f32) -> bool {
    let t = layer as f32 / layers as f32;
    (n * t + shell_offset(layer, layers, k, s, n)).dot(n) < 0.0
}

/// What one probe comparison saw.
#[derive(Default, Debug)]
struct Compared {
    positions: usize,
    guarded: usize,
    worst_m: f32,
    worst_over_tolerance: f32,
    below_surface: usize,
}

/// Compares the GPU's shell positions with the CPU reference for `scale_vectors` under
/// `settings`.
fn compare_shell_positions(asset: &FurAsset, settings: &RenderSettings, scale_vectors: &[[f32; 3]]) -> Compared {
    let g = gpu();
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, asset, settings, &RenderTarget::desc()).unwrap();
    renderer.set_scale_vectors(&g.queue, scale_vectors).unwrap();
    let gpu_positions = renderer.shell_positions(&g.device, &g.queue, asset).unwrap();
    let mesh = asset.mesh();
    let (vertices, layers) = (mesh.positions.len(), renderer.drawn_layers());
    assert_eq!(gpu_positions.len(), vertices * layers as usize);
    let length = asset.shells().fur_length_m;
    let k = settings.shear_exponent;
    let mut out = Compared::default();
    for layer in 0..layers {
        for v in 0..vertices {
            let skin = Vec3::from(mesh.positions[v]);
            let n = Vec3::from(mesh.normals[v]).normalize();
            let s = Vec3::from(scale_vectors[v]);
            // Shell instance `layer` sits at t = (layer + 1)/layers: CPU layer index layer + 1.
            // The reference includes the guard: the inward part of the offset is dropped.
            let expected = shell_vertex_position(skin, n, s, layer + 1, layers, length, k);
            let fired = guard_fires(n, s, layer + 1, layers, k);
            let got = Vec3::from(gpu_positions[layer as usize * vertices + v]);
            // Tolerance: the GPU evaluates the same f32 formula in another order
            // (`(n t + t^k (s − n)) L + p` against `p + n (L t) + t^k (s − n) L`), with a driver
            // `normalize` (inverseSqrt, 2 ulp in Vulkan) and `pow` (exp2(k·log2 t): Vulkan allows
            // an absolute 2^-21 error on log2 near 1, i.e. a relative error ≈ k·2^-21·ln 2 on t^k).
            // Each rounding is at most half an ulp of a value below |p| + 2L, so allow 16 ulps of
            // that plus the pow bound on the shear term |t^k (s − n)| L ≤ 2L: for the unit
            // sphere with L = 0.15 m that is 2.5e-6 m + 1.7e-7·k m — far below a texel (2 mm).
            let tolerance = 16.0 * f32::EPSILON * (skin.length() + 2.0 * length) + k * 2f32.powi(-20) * 2.0 * length;
            let err = got.distance(expected);
            assert!(
                err <= tolerance,
                "k = {k}, layer {layer}, vertex {v}: GPU {got} vs CPU {expected}, error {err:e} m > {tolerance:e} m"
            );
            out.positions += 1;
            out.guarded += fired as usize;
            out.worst_m = out.worst_m.max(err);
            out.worst_over_tolerance = out.worst_over_tolerance.max(err / tolerance);
            // Never below the skin's tangent plane (within the tolerance).
            if (got - skin).dot(n) < -tolerance {
                out.below_surface += 1;
            }
        }
    }
    out
}

#[test]
fn gpu_shell_shearing_matches_the_cpu_reference_for_simulated_scale_vectors() {
    let (asset, topology) = sphere();
    let scale_vectors = simulated_scale_vectors(topology, 2e-3, 30);
    let mesh = asset.mesh();
    assert_eq!(scale_vectors.len(), mesh.positions.len(), "prisms: one shell vertex per welded vertex");
    // The physics really moved the fur: most scale vectors left their normal, and towards +X.
    let (mut bent, mut towards_wind, mut furry) = (0, 0, 0);
    for (s, n) in scale_vectors.iter().zip(&mesh.normals) {
        let (s, n) = (Vec3::from(*s), Vec3::from(*n));
        if s == Vec3::ZERO {
            continue; // a vertex without fur
        }
        furry += 1;
        if s.angle_between(n).to_degrees() > 2.0 {
            bent += 1;
        }
        if (s - n).x > 0.0 {
            towards_wind += 1;
        }
    }
    println!("{furry} furry vertices, {bent} bent more than 2°, {towards_wind} towards +X");
    assert!(furry > 300 && bent * 2 > furry, "{bent} of {furry} scale vectors bent by more than 2°");
    assert!(towards_wind * 3 > furry * 2, "{towards_wind} of {furry} bent towards the wind");

    let mut total = 0;
    for k in [2.0, 1.0, 3.5] {
        let settings = RenderSettings { shell_layers: Some(16), shear_exponent: k, ..Default::default() };
        let c = compare_shell_positions(asset, &settings, &scale_vectors);
        println!("k = {k}: {c:?}");
        assert_eq!(c.positions, 16 * mesh.positions.len());
        // The simulator's own guard (n·s ≥ cos 80°) keeps its scale vectors on the right side,
        // where the shader's guard never fires for k ≥ 1: GPU = CPU reference, unmodified.
        assert_eq!(c.guarded, 0, "k = {k}: the shader guard changed simulated positions");
        assert_eq!(c.below_surface, 0);
        total += c.positions;
    }
    assert_eq!(total, 3 * 16 * mesh.positions.len());
}

#[test]
fn gpu_guard_drops_the_inward_part_of_wrong_side_scale_vectors() {
    let (asset, _) = sphere();
    let mesh = asset.mesh();
    // Wrong-side scale vectors (§3.4.3): straight into the surface, and tilted 60° and 100° away
    // from the normal towards a tangent — the cases the simulator's guard would freeze, handed
    // to the renderer anyway.
    let tangent = |n: Vec3| n.cross(Vec3::Z).try_normalize().unwrap_or(Vec3::X);
    type ScaleOf = Box<dyn Fn(Vec3) -> Vec3>;
    let cases: [(&str, ScaleOf); 3] = [
        ("s = −n", Box::new(|n: Vec3| -n)),
        (
            "100° from n",
            Box::new(move |n: Vec3| tangent(n) * 100f32.to_radians().sin() + n * 100f32.to_radians().cos()),
        ),
        (
            "170° from n",
            Box::new(move |n: Vec3| tangent(n) * 170f32.to_radians().sin() + n * 170f32.to_radians().cos()),
        ),
    ];
    let mut checked = 0;
    for (name, make) in &cases {
        let scale_vectors: Vec<[f32; 3]> =
            mesh.normals.iter().map(|n| make(Vec3::from(*n).normalize()).normalize().to_array()).collect();
        for k in [2.0, 0.5] {
            let settings = RenderSettings { shell_layers: Some(16), shear_exponent: k, ..Default::default() };
            let c = compare_shell_positions(asset, &settings, &scale_vectors);
            println!("{name}, k = {k}: {c:?}");
            // Unguarded, eq. 3.36 enters the surface for the outer layers (for s = −n with k = 2,
            // every layer with t^2·2 > t, i.e. t > 1/2); the guard fires there, and the GPU
            // equals the CPU reference, which drops the inward part the same way.
            assert!(c.guarded >= mesh.positions.len(), "{name}, k = {k}: only {} guarded positions", c.guarded);
            assert_eq!(c.below_surface, 0, "{name}, k = {k}: shell vertices below the skin");
            checked += c.positions;
        }
    }
    assert_eq!(checked, 6 * 16 * mesh.positions.len());
}

const SIZE: u32 = 128;
const TRANSPARENT: [f32; 4] = [0.0, 0.0, 0.0, 0.0];

/// The plane seen exactly edge-on from +Z (+X to the right): the plane projects onto the horizon
/// row, so anything drawn below it is fur under the surface.
fn edge_on(settings: &RenderSettings, scale_vectors: Option<&[[f32; 3]]>) -> RgbaImage {
    let (asset, _) = plane();
    let view = View {
        camera: Camera { eye: [0.0, 0.0, 4.0], target: [0.0, 0.0, 0.0], up: [0.0, 1.0, 0.0], fov_y_deg: 40.0 },
        lighting: Light::default().into(),
        bounds_center: [0.0, 0.0, 0.0],
        bounds_radius: 1.6,
    };
    let g = gpu();
    let renderer = FurRenderer::new(g.pipelines(), &g.queue, asset, settings, &RenderTarget::desc()).unwrap();
    if let Some(s) = scale_vectors {
        renderer.set_scale_vectors(&g.queue, s).unwrap();
    }
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    renderer.render_to(&g.device, &g.queue, &target, &view).unwrap();
    read_back(&g.device, &g.queue, &target).unwrap()
}

/// Mean x and count of covered pixels, and the lowest covered row.
fn coverage(image: &RgbaImage) -> (f64, usize, u32) {
    let (mut sx, mut n, mut bottom) = (0.0f64, 0usize, 0u32);
    for (x, y, p) in image.enumerate_pixels() {
        if p[3] > 0 {
            sx += x as f64;
            n += 1;
            bottom = bottom.max(y);
        }
    }
    (sx / n.max(1) as f64, n, bottom)
}

#[test]
fn simulated_wind_bends_the_rendered_fur_and_never_below_the_surface() {
    let (_, topology) = plane();
    // Gravity pulls the plane's fur (normal +Y) straight into the surface and the wind pushes it
    // along +X: the hardest case for the wrong-side guard.
    let bent = simulated_scale_vectors(topology, 5e-3, 40);
    let mean_dx = bent.iter().map(|s| s[0] as f64).sum::<f64>() / bent.len() as f64;
    assert!(mean_dx > 0.1, "the wind bent the fur only by mean s.x = {mean_dx:.3}");
    let base = RenderSettings { background: TRANSPARENT, ..Default::default() };
    let skin_only = edge_on(&RenderSettings { shell_layers: Some(0), ..base }, None);
    let rest = edge_on(&base, None);
    let windy = edge_on(&base, Some(&bent));
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    windy.save(dir.join("plane_edge_on_simulated_wind.png")).unwrap();
    let ((_, n_skin, skin_bottom), (x_rest, n_rest, rest_bottom), (x_windy, n_windy, windy_bottom)) =
        (coverage(&skin_only), coverage(&rest), coverage(&windy));
    println!(
        "skin-only {n_skin} px to row {skin_bottom}; rest {n_rest} px, mean x {x_rest:.1}, to row {rest_bottom}; wind {n_windy} px, mean x {x_windy:.1}, to row {windy_bottom}"
    );
    // Edge-on, the bare skin is (at most) a line on the horizon; fur adds pixels above it.
    assert!(
        n_rest > n_skin + 100 && n_windy > n_skin + 100,
        "fur pixels: rest {n_rest}, wind {n_windy}, skin {n_skin}"
    );
    // No fur pixel lower than the lowest skin pixel (the horizon, SIZE/2): nothing inside the
    // surface, at rest or bent by gravity and wind.
    let horizon = skin_bottom.max(SIZE / 2);
    assert!(
        rest_bottom <= horizon && windy_bottom <= horizon,
        "fur below the surface: rows {rest_bottom}, {windy_bottom} > {horizon}"
    );
    // The silhouette moves downwind (+X, to the right).
    assert!(x_windy > x_rest + 1.0, "mean x: rest {x_rest:.1}, wind {x_windy:.1}");
}

#[test]
fn simulated_wind_shifts_the_sphere_silhouette_towards_plus_x() {
    let (asset, topology) = sphere();
    let bent = simulated_scale_vectors(topology, 2e-2, 60);
    let mean_dx = bent.iter().map(|s| s[0] as f64).sum::<f64>() / bent.len() as f64;
    let mean_angle = bent
        .iter()
        .zip(&asset.mesh().normals)
        .map(|(s, n)| Vec3::from(*s).angle_between(Vec3::from(*n)).to_degrees() as f64)
        .sum::<f64>()
        / bent.len() as f64;
    println!("sphere: mean s.x {mean_dx:.3}, mean angle to n {mean_angle:.1}°");
    let (center, radius) = asset.bounding_sphere();
    // Looking along −Z at the sphere's centre: +X is to the right.
    let view = View {
        camera: Camera {
            eye: [center[0], center[1], center[2] + 4.0 * radius],
            target: center,
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 35.0,
        },
        lighting: Light::default().into(),
        bounds_center: center,
        bounds_radius: radius,
    };
    let g = gpu();
    let settings = RenderSettings { background: TRANSPARENT, ..Default::default() };
    let render = |settings: &RenderSettings, s: Option<&[[f32; 3]]>| {
        let renderer = FurRenderer::new(g.pipelines(), &g.queue, asset, settings, &RenderTarget::desc()).unwrap();
        if let Some(s) = s {
            renderer.set_scale_vectors(&g.queue, s).unwrap();
        }
        let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
        renderer.render_to(&g.device, &g.queue, &target, &view).unwrap();
        read_back(&g.device, &g.queue, &target).unwrap()
    };
    let skin = render(&RenderSettings { shell_layers: Some(0), ..settings }, None);
    let rest = render(&settings, None);
    let windy = render(&settings, Some(&bent));
    // Fur-only pixels (outside the skin's coverage): their mean x moves right, the right fringe
    // gains pixels and the left fringe loses some.
    let fringe = |img: &RgbaImage| {
        let (mut left, mut right, mut sx) = (0usize, 0usize, 0.0f64);
        for (x, y, p) in img.enumerate_pixels() {
            if p[3] > 0 && skin.get_pixel(x, y)[3] == 0 {
                sx += x as f64;
                if x < SIZE / 2 {
                    left += 1;
                } else {
                    right += 1;
                }
            }
        }
        (left, right, sx / (left + right).max(1) as f64)
    };
    let ((l_rest, r_rest, x_rest), (l_wind, r_wind, x_wind)) = (fringe(&rest), fringe(&windy));
    println!("fringe rest: {l_rest} left / {r_rest} right, mean x {x_rest:.1}; wind: {l_wind} / {r_wind}, {x_wind:.1}");
    assert!(l_rest + r_rest > 200, "the fur fringe has {} pixels", l_rest + r_rest);
    // WindForce along +X lays the fur on the left side (normal −X) flat against the skin — the guard
    // keeps it out of the surface — while the right side's fur already points downwind: the
    // fringe's mean x moves right (≈ 0.9 px of a ≈ 8 px wide fur ring here; 0.5 asked) and the
    // right fringe outweighs the left one by more than at rest.
    assert!(x_wind > x_rest + 0.5, "fringe mean x: rest {x_rest:.1}, wind {x_wind:.1}");
    let (bias_rest, bias_wind) = (r_rest as i64 - l_rest as i64, r_wind as i64 - l_wind as i64);
    assert!(bias_wind > bias_rest + 20, "right − left fringe pixels: rest {bias_rest}, wind {bias_wind}");
    // The skin stays covered under the bent fur.
    let lost = skin.pixels().zip(windy.pixels()).filter(|(s, w)| s[3] > 0 && w[3] == 0).count();
    assert_eq!(lost, 0);
}
