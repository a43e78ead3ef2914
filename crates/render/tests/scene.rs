//! Scene frames (`SceneRenderer`, `SceneFrame`): several packs — a furry sphere and a grass patch
//! — drawn into one target from a runtime `Scene`'s camera and light, each placed by its model
//! matrix, with per-frame physics inputs (scale vectors, blade corner forces). Checked as
//! properties: each object lands where its model matrix puts it (centroid shift against the
//! pinhole projection), objects do not disturb one another, per-frame forces bend the grass
//! downwind in world space, a wind source with delayed attenuation reaches the rendered blades as
//! the CPU reference computes it, and bad inputs are refused before drawing. Runs on whatever adapter
//! the machine has (lavapipe without a GPU) and never skips.

use std::path::Path;
use std::sync::OnceLock;

use crate::common::gpu;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, Symmetry};
use furbake_grass::keyframes::PoseGridSettings;
use furbake_grass::{
    BladeFieldSettings, BladeMaterial, BladeShape, build_reference_blade, compress_poses, ground_grid_mesh,
    scatter_blades, simulate_poses,
};
use furbake_import::{ImportSettings, import_gltf_slice, testmesh};
use furbake_render::SceneFrame;
use furbake_render::headless::{RenderTarget, SceneObject, read_back};
use furbake_render::{BladeForces, PackInput, SceneRenderer};
use furbake_runtime::{Scene, ShellVertexLayout, World};
use glam::{Mat4, Vec3};
use image::RgbaImage;

const SIZE: u32 = 160;
const FOV_DEG: f32 = 40.0;
const EYE_Z: f32 = 6.0;

/// A scene with two packs written to a temporary folder: `fur` (a unit sphere, 16 layers, 0.12 m
/// fur) at x = −1.3 m and `grass` (a 1 m patch) at x = +1.3 m, y = −0.4 m, seen from +Z.
fn scene() -> &'static (tempfile::TempDir, Scene) {
    static SCENE: OnceLock<(tempfile::TempDir, Scene)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let gltf = testmesh::uv_sphere(16, 24, 1.0).gltf;
        let imported = import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
        let mut settings = BakeSettings::preset("fur").unwrap();
        settings.volume.layers = 16;
        settings.volume.resolution = 64;
        settings.shells.fur_length_m = Some(0.12);
        // The scene declares wind, so the world simulates the fur: it needs a topology.
        settings.topologies = vec!["prisms".into()];
        let baked = bake(&imported, "sphere", &settings.plan().unwrap(), &mut NoProgress).unwrap();
        baked.to_writer().write_atomic(&dir.path().join("fur.fbk")).unwrap();

        let grid = PoseGridSettings { poses: 400, ..Default::default() }.resolve(Symmetry::XZ).unwrap();
        let blade = build_reference_blade(&BladeShape::default()).unwrap();
        let poses = simulate_poses(&blade, &BladeMaterial::default(), grid).unwrap();
        let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        let table = compress_poses(&poses, Symmetry::XZ, stages, DisplacementEncoding::Snorm16).unwrap();
        let field_settings = BladeFieldSettings { density_per_m2: 150.0, cluster_size_m: 0.5, ..Default::default() };
        let field = scatter_blades(&ground_grid_mesh([1.0, 1.0], [2, 2]), &field_settings).unwrap();
        furbake_formats::PackWriter::new()
            .push_section(&field)
            .push_section(&table)
            .write_atomic(&dir.path().join("grass.fbk"))
            .unwrap();

        let toml = format!(
            r#"
[camera]
eye = [0.0, 0.0, {EYE_Z}]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = {FOV_DEG}

[[packs]]
name = "fur"
path = "fur.fbk"
translation = [-1.3, 0.0, 0.0]

[[packs]]
name = "grass"
path = "grass.fbk"
translation = [1.3, -0.4, 0.0]
scale = 1.5

[effects.wind]
velocity_m_per_s = [1.0, 0.0, 0.0]
"#
        );
        let scene = Scene::from_toml_str(&toml, Path::new("test.toml"), dir.path()).unwrap();
        (dir, scene)
    })
}

fn is_green(p: &image::Rgba<u8>) -> bool {
    p[1] as i32 > p[0] as i32 + 10 && p[1] as i32 > p[2] as i32 + 10
}

/// Count and mean x of pixels that differ from `background` and satisfy `keep`.
fn centroid(image: &RgbaImage, background: [u8; 4], keep: impl Fn(&image::Rgba<u8>) -> bool) -> (usize, f64) {
    let (mut n, mut sx) = (0usize, 0.0f64);
    for (x, _, p) in image.enumerate_pixels() {
        if p.0 != background && keep(p) {
            n += 1;
            sx += x as f64;
        }
    }
    (n, sx / n.max(1) as f64)
}

fn background_rgba(image: &RgbaImage) -> [u8; 4] {
    image.get_pixel(0, 0).0
}

#[test]
fn every_pack_is_drawn_where_its_model_matrix_puts_it() {
    let (_, scene) = scene();
    let g = gpu();
    let renderer = SceneRenderer::new(&g.device, &g.queue, &World::new(scene.clone()).unwrap()).unwrap();
    assert_eq!(renderer.packs().len(), 2);
    assert!(renderer.packs()[0].fur.is_some() && renderer.packs()[0].blades.is_none());
    assert!(renderer.packs()[1].fur.is_none() && renderer.packs()[1].blades.is_some());
    // The scene declares wind, so shearing is compiled in.
    assert!(renderer.packs()[0].fur.as_ref().unwrap().settings().shearing);
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    let view = renderer.render_frame(&g.device, &g.queue, &target, &[]).unwrap();
    assert_eq!(view.camera, scene.camera().unwrap());
    let both = read_back(&g.device, &g.queue, &target).unwrap();
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    both.save(dir.join("scene_fur_and_grass.png")).unwrap();
    let bg = background_rgba(&both);
    let (n_fur, x_fur) = centroid(&both, bg, |p| !is_green(p));
    let (n_grass, x_grass) = centroid(&both, bg, is_green);
    println!("fur {n_fur} px at mean x {x_fur:.1}; grass {n_grass} px at mean x {x_grass:.1}");
    // Pinhole projection of the translations: x_px = W/2 + x/(z_eye − z) · (H/2)/tan(fov/2).
    let focal = SIZE as f64 * 0.5 / (FOV_DEG as f64 * 0.5).to_radians().tan();
    let expect_fur = SIZE as f64 * 0.5 - 1.3 / EYE_Z as f64 * focal;
    assert!(n_fur > 2000, "{n_fur} fur pixels");
    assert!((x_fur - expect_fur).abs() < 3.0, "fur centroid {x_fur:.1}, expected ≈ {expect_fur:.1}");
    assert!(n_grass > 300, "{n_grass} grass pixels");
    assert!(x_grass > SIZE as f64 * 0.5 + 0.6 / EYE_Z as f64 * focal, "grass centroid {x_grass:.1}");

    // The same fur object alone (one SceneObject, same camera): the left half of the frame is
    // unchanged by the grass pass.
    let fur = renderer.packs()[0].fur.as_ref().unwrap();
    let alone = SceneFrame::from_scene(scene);
    let model = Mat4::from_translation(Vec3::new(-1.3, 0.0, 0.0));
    alone
        .render(
            &g.device,
            &g.queue,
            &target,
            &[SceneObject::Fur {
                renderer: fur,
                model,
                scale_vectors: None,
                scale_layout: ShellVertexLayout::PerVertex,
            }],
        )
        .unwrap();
    let fur_only = read_back(&g.device, &g.queue, &target).unwrap();
    let (mut same, mut total) = (0usize, 0usize);
    for (x, y, p) in both.enumerate_pixels().filter(|(x, _, _)| *x < SIZE / 2) {
        total += 1;
        same += (fur_only.get_pixel(x, y) == p) as usize;
    }
    assert_eq!(same, total, "{} of {total} left-half pixels changed by the grass pack", total - same);
}

#[test]
fn model_matrices_translate_and_scale_a_furry_object() {
    let (_, scene) = scene();
    let g = gpu();
    let renderer = SceneRenderer::new(&g.device, &g.queue, &World::new(scene.clone()).unwrap()).unwrap();
    let fur = renderer.packs()[0].fur.as_ref().unwrap();
    let frame = SceneFrame::from_scene(scene);
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    let render = |model: Mat4| {
        frame
            .render(
                &g.device,
                &g.queue,
                &target,
                &[SceneObject::Fur {
                    renderer: fur,
                    model,
                    scale_vectors: None,
                    scale_layout: ShellVertexLayout::PerVertex,
                }],
            )
            .unwrap();
        let image = read_back(&g.device, &g.queue, &target).unwrap();
        centroid(&image, background_rgba(&image), |_| true)
    };
    let (n0, x0) = render(Mat4::IDENTITY);
    let (n1, x1) = render(Mat4::from_translation(Vec3::new(0.8, 0.0, 0.0)));
    let (n2, _) = render(Mat4::from_scale(Vec3::splat(0.5)));
    let (n3, x3) = render(Mat4::from_rotation_y(1.0) * Mat4::from_translation(Vec3::new(0.0, 0.0, 0.0)));
    let focal = SIZE as f64 * 0.5 / (FOV_DEG as f64 * 0.5).to_radians().tan();
    let expected_shift = 0.8 / EYE_Z as f64 * focal;
    println!(
        "identity {n0} px at {x0:.1}; +0.8 m x: {n1} px at {x1:.1} (expected +{expected_shift:.1}); half scale {n2} px"
    );
    assert!(((x1 - x0) - expected_shift).abs() < 1.5, "shift {:.1} px, expected {expected_shift:.1}", x1 - x0);
    assert!(n1.abs_diff(n0) * 20 < n0, "translation changed the covered area: {n0} → {n1}");
    // Half the size: a quarter of the area (fur ring and perspective make it not exact).
    let ratio = n2 as f64 / n0 as f64;
    assert!((0.18..0.32).contains(&ratio), "half scale covers {ratio:.2} of the full size");
    // A sphere rotated about Y keeps its silhouette (normals rotate with it; lighting changes).
    assert!(n3.abs_diff(n0) * 50 < n0 && (x3 - x0).abs() < 1.0, "rotation moved the sphere: {n3} px at {x3:.1}");
}

#[test]
fn per_frame_corner_forces_bend_the_grass_in_world_space() {
    let (_, scene) = scene();
    let g = gpu();
    let mut renderer = SceneRenderer::new(&g.device, &g.queue, &World::new(scene.clone()).unwrap()).unwrap();
    // Seen from above and in front of the patch (edge-on, bending mostly lowers the tips).
    renderer.frame_mut().camera = Some(furbake_runtime::Camera {
        eye: [1.3, 1.8, 2.2],
        target: [1.3, -0.3, 0.0],
        up: [0.0, 1.0, 0.0],
        fov_y_deg: 30.0,
    });
    let renderer = renderer;
    let blades = renderer.packs()[1].blades.as_ref().unwrap();
    let corners = blades.corner_count() as usize;
    let target = RenderTarget::new(&g.device, SIZE, SIZE).unwrap();
    let calm = vec![[0.0f32; 2]; corners];
    let windy = vec![[4.0f32, 0.0]; corners];
    let grass_x = |forces: &[[f32; 2]], model: Option<Mat4>| {
        let inputs = [
            PackInput::default(),
            PackInput { model, blade_forces: Some(BladeForces::Corners(forces)), ..Default::default() },
        ];
        renderer.render_frame(&g.device, &g.queue, &target, &inputs).unwrap();
        let image = read_back(&g.device, &g.queue, &target).unwrap();
        let name = format!("scene_grass_{}_{}.png", forces[0][0], model.is_some());
        image.save(std::env::temp_dir().join("furbake-render-tests").join(name)).unwrap();
        image
    };
    // Mean x of the green pixels above `row` (the upper half of the calm blades, where the
    // displacement is largest: near the roots, bending barely moves anything).
    let upper = |image: &RgbaImage, row: u32| {
        let xs: Vec<f64> =
            image.enumerate_pixels().filter(|(_, y, p)| *y < row && is_green(p)).map(|(x, _, _)| x as f64).collect();
        xs.iter().sum::<f64>() / xs.len().max(1) as f64
    };
    let median_row = |image: &RgbaImage| {
        let rows: Vec<u32> = image.enumerate_pixels().filter(|(_, _, p)| is_green(p)).map(|(_, y, _)| y).collect();
        rows[rows.len() / 2]
    };
    let (calm_image, windy_image) = (grass_x(&calm, None), grass_x(&windy, None));
    let row = median_row(&calm_image);
    let (x_calm, x_windy) = (upper(&calm_image, row), upper(&windy_image, row));
    // The same field turned 180° about Y: pack-frame wind +X blows towards world −X.
    let turned = Mat4::from_translation(Vec3::new(1.3, -0.4, 0.0))
        * Mat4::from_rotation_y(std::f32::consts::PI)
        * Mat4::from_scale(Vec3::splat(1.5));
    let (calm_image, windy_image) = (grass_x(&calm, Some(turned)), grass_x(&windy, Some(turned)));
    let row = median_row(&calm_image);
    let (x_turned_calm, x_turned_windy) = (upper(&calm_image, row), upper(&windy_image, row));
    println!(
        "grass mean x: calm {x_calm:.1}, wind {x_windy:.1}; turned calm {x_turned_calm:.1}, wind {x_turned_windy:.1}"
    );
    assert!(x_windy > x_calm + 1.0, "wind +X: {x_calm:.1} → {x_windy:.1}");
    assert!(x_turned_windy < x_turned_calm - 1.0, "turned field: {x_turned_calm:.1} → {x_turned_windy:.1}");
}

#[test]
fn bad_frame_inputs_are_refused() {
    let (_, scene) = scene();
    let g = gpu();
    let renderer = SceneRenderer::new(&g.device, &g.queue, &World::new(scene.clone()).unwrap()).unwrap();
    let target = RenderTarget::new(&g.device, 32, 32).unwrap();
    let short = vec![[0.0f32, 1.0, 0.0]; 3];
    let forces = vec![[0.0f32; 2]; renderer.packs()[1].blades.as_ref().unwrap().corner_count() as usize];
    let cases = [
        vec![PackInput { scale_vectors: Some(&short), ..Default::default() }],
        vec![PackInput::default(), PackInput { scale_vectors: Some(&short), ..Default::default() }],
        vec![PackInput { blade_forces: Some(BladeForces::Corners(&forces)), ..Default::default() }],
        vec![PackInput { model: Some(Mat4::ZERO), ..Default::default() }],
        vec![PackInput { model: Some(Mat4::from_scale(Vec3::splat(f32::NAN))), ..Default::default() }],
        vec![PackInput::default(); 3],
    ];
    let mut refused = 0;
    for inputs in &cases {
        assert!(renderer.render_frame(&g.device, &g.queue, &target, inputs).is_err(), "{inputs:?} was accepted");
        refused += 1;
    }
    assert_eq!(refused, cases.len());
    // One renderer twice in one frame (one uniform buffer, one model matrix per frame).
    let fur = renderer.packs()[0].fur.as_ref().unwrap();
    let twice = [
        SceneObject::Fur {
            renderer: fur,
            model: Mat4::IDENTITY,
            scale_vectors: None,
            scale_layout: ShellVertexLayout::PerVertex,
        },
        SceneObject::Fur {
            renderer: fur,
            model: Mat4::from_translation(Vec3::X),
            scale_vectors: None,
            scale_layout: ShellVertexLayout::PerVertex,
        },
    ];
    assert!(renderer.frame().render(&g.device, &g.queue, &target, &twice).is_err());
    assert!(renderer.render_frame(&g.device, &g.queue, &target, &[PackInput::default(); 2]).is_ok());
}

/// A frame refused for one pack's input writes nothing for any pack (every input is checked
/// before the frame's one upload): after a refused frame that would have laid the fur flat, the
/// next frame (which keeps the last inputs) draws exactly what the last accepted frame drew.
#[test]
fn a_refused_frame_uploads_nothing() {
    let (_, scene) = scene();
    let g = gpu();
    let renderer = SceneRenderer::new(&g.device, &g.queue, &World::new(scene.clone()).unwrap()).unwrap();
    let target = RenderTarget::new(&g.device, 64, 64).unwrap();
    let fur = renderer.packs()[0].fur.as_ref().unwrap();
    let corners = renderer.packs()[1].blades.as_ref().unwrap().corner_count() as usize;
    // Sheared sideways, then (refused) flat along +X with non-finite blade forces beside it.
    let sheared = vec![Vec3::new(0.7, 0.7, 0.0).normalize().to_array(); fur.vertex_count() as usize];
    let flat = vec![[1.0f32, 0.0, 0.0]; fur.vertex_count() as usize];
    let bad = vec![[f32::NAN, 0.0]; corners];
    let keep = [PackInput::default(); 2];
    let draw = |inputs: &[PackInput<'_>]| {
        renderer.render_frame(&g.device, &g.queue, &target, inputs)?;
        Ok::<_, furbake_render::RenderError>(read_back(&g.device, &g.queue, &target).unwrap())
    };
    let accepted = draw(&[PackInput { scale_vectors: Some(&sheared), ..Default::default() }]).unwrap();
    let refused = [
        PackInput { scale_vectors: Some(&flat), ..Default::default() },
        PackInput { blade_forces: Some(BladeForces::Corners(&bad)), ..Default::default() },
    ];
    assert!(draw(&refused).is_err(), "non-finite corner forces were accepted");
    assert_eq!(draw(&keep).unwrap(), accepted, "the refused frame changed what is drawn");
    // The flat fur draws differently, so the comparison above can fail.
    let flat_frame = draw(&[PackInput { scale_vectors: Some(&flat), ..Default::default() }]).unwrap();
    assert_ne!(flat_frame, accepted, "flat and sheared fur draw alike: the test sees nothing");
}

/// A grass-only scene around the test patch (`grass.fbk`): a global breeze and one point wind
/// source 0.4 m beside the patch, with or without delayed attenuation (grass thesis §4.2).
fn source_scene(dir: &Path, delayed: bool) -> Scene {
    let toml = format!(
        r#"
[[packs]]
name = "grass"
path = "grass.fbk"
translation = [1.3, -0.4, 0.0]
scale = 1.5

[effects.wind]
velocity_m_per_s = [0.5, 0.0, 0.0]

[[effects.wind_sources]]
position = [0.4, -0.3, 0.2]
power = 3.0
falloff_exponent = 1.0
delayed_attenuation = {delayed}
"#
    );
    Scene::from_toml_str(&toml, Path::new("sources.toml"), dir).unwrap()
}

/// Renders the world of `scene` once through `SceneRenderer::render_world` and returns the
/// posed blade vertices the GPU computed for that frame (pack frame, blade-major), with the world.
fn rendered_blade_positions(scene: Scene) -> (Vec<[f32; 3]>, World) {
    let g = gpu();
    let mut world = World::new(scene).unwrap();
    world.step().unwrap();
    let renderer = SceneRenderer::new(&g.device, &g.queue, &world).unwrap();
    let target = RenderTarget::new(&g.device, 64, 64).unwrap();
    renderer.render_world(&g.device, &g.queue, &target, &world).unwrap();
    let blades = renderer.packs()[0].blades.as_ref().unwrap();
    blades.compute(&g.device, &g.queue).unwrap();
    (blades.read_positions(&g.device, &g.queue).unwrap(), world)
}

#[test]
fn a_delayed_wind_source_reaches_the_rendered_blades() {
    // Cause of the bug this pins: `furbake preview SCENE` passed only the grass corner forces to
    // the GPU, and those leave delayed-attenuation sources out, so a delayed source had no
    // effect on the picture. The frame must pose every blade under `ForceField::blade_force`.
    use furbake_formats::sections::keyframe_table::KeyframeTable;
    use furbake_grass::{KeyframeDecoder, PoseInterpolation};
    use glam::Vec3Swizzles;
    let (dir, _) = scene();
    let (delayed, world) = rendered_blade_positions(source_scene(dir.path(), true));
    let grass = world.grass(0).unwrap();
    assert!(grass.has_delayed_sources());
    let field = world.pack(0).blade_field().unwrap();
    let table = world.pack(0).section::<KeyframeTable>().unwrap();
    let decoder = KeyframeDecoder::new(&table).unwrap();
    let (n, vc) = (field.blade_count(), decoder.vertex_count());
    assert_eq!(delayed.len(), n * vc);
    let mut cpu = vec![Vec3::ZERO; vc];
    let (mut compared, mut worst) = (0usize, 0.0f32);
    for b in 0..n {
        let root = Vec3::from(field.positions[b]);
        let corners = field.grid.corner_indices(field.cluster[b]);
        let f = grass.field.blade_force(corners, field.weights[b], root);
        let (yaw, h) = (field.yaw_rad[b], field.height_scale[b]);
        decoder.world_positions(root, yaw, h, f.extend(0.0).xzy(), PoseInterpolation::Nearest, &mut cpu);
        let err = (0..vc).map(|v| Vec3::from(delayed[b * vc + v]).distance(cpu[v])).fold(0.0f32, f32::max);
        // Nearest-pose selection: a force within rounding of a pose-cell boundary may pick the
        // neighbouring pose on either side; such blades are counted, not compared.
        if err > 1e-5 {
            continue;
        }
        worst = worst.max(err);
        compared += 1;
    }
    println!("delayed source: {compared} of {n} blades match the CPU reference, max error {worst:e} m");
    assert!(compared + 3 >= n, "only {compared} of {n} blades match the CPU reference with delay");
    // The same scene without delay poses the blades differently.
    let (instant, _) = rendered_blade_positions(source_scene(dir.path(), false));
    let differing = (0..n)
        .filter(|&b| (0..vc).any(|v| Vec3::from(delayed[b * vc + v]).distance(Vec3::from(instant[b * vc + v])) > 1e-3))
        .count();
    println!("{differing} of {n} blades differ with and without delayed attenuation");
    assert!(differing * 4 > n, "delay changes only {differing} of {n} blades");
}

/// A scene that places one pack many times uploads its atlases and vertex buffers once: every
/// entry's fur renderer draws from one shared `FurGpuAsset`, and the estimate grows per entry by
/// the per-placement data only (before, 500 entries of the same packs needed 3.5 GB).
#[test]
fn entries_of_one_pack_share_its_gpu_asset() {
    let g = gpu();
    let dir = scene().0.path();
    let text = |n: usize| {
        let mut t = String::from("[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n");
        for k in 0..n {
            t.push_str(&format!("[[packs]]\nname = \"fur{k}\"\npath = \"fur.fbk\"\ntranslation = [{k}.0, 0.0, 0.0]\n"));
        }
        t.push_str("[[packs]]\nname = \"other\"\npath = \"grass.fbk\"\n");
        World::new(Scene::from_toml_str(&t, Path::new("t.toml"), dir).unwrap()).unwrap()
    };
    let world = text(3);
    let renderer = SceneRenderer::new(&g.device, &g.queue, &world).unwrap();
    let fur: Vec<_> = renderer.packs().iter().filter_map(|p| p.fur.as_ref()).collect();
    assert_eq!(fur.len(), 3);
    assert!(fur.windows(2).all(|w| std::sync::Arc::ptr_eq(w[0].gpu_asset(), w[1].gpu_asset())));
    assert_eq!(std::sync::Arc::strong_count(fur[0].gpu_asset()), 3, "one upload, three renderers");
    // Grass placed twice draws from one uploaded field.
    let mut t = String::new();
    for k in 0..2 {
        t.push_str(&format!("[[packs]]\nname = \"g{k}\"\npath = \"grass.fbk\"\n"));
    }
    let lawn = World::new(Scene::from_toml_str(&t, Path::new("g.toml"), dir).unwrap()).unwrap();
    let both = SceneRenderer::new(&g.device, &g.queue, &lawn).unwrap();
    let (a, b) = (both.packs()[0].blades.as_ref().unwrap(), both.packs()[1].blades.as_ref().unwrap());
    assert!(a.shares_data_with(b));
    let alone = SceneRenderer::new(&g.device, &g.queue, &text(1)).unwrap();
    assert!(!a.shares_data_with(alone.packs()[1].blades.as_ref().unwrap()), "another renderer set uploads its own");
    // The estimate: the shared part once, the per-placement part per entry.
    let (one, ten) =
        (SceneRenderer::estimate_gpu_bytes(&text(1)).unwrap(), SceneRenderer::estimate_gpu_bytes(&text(10)).unwrap());
    let asset = furbake_render::FurAsset::from_pack(world.pack(0), true).unwrap();
    let per_entry = asset.instance_gpu_bytes() + furbake_render::testing::RENDERER_OVERHEAD_BYTES;
    assert_eq!(ten - one, 9 * per_entry, "each extra entry costs its own data only");
    assert!(asset.shared_gpu_bytes(true) > asset.instance_gpu_bytes(), "the atlas is the bulk, and it is shared");
    g.check().unwrap();
}
