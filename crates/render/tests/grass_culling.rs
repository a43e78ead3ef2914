//! Grass culling and level of detail (grass thesis §5.3; `shaders/blade_cull.wgsl`) read back from
//! the GPU against the CPU reference (`CullReference`) and against independent checks in f64: for
//! fixed cameras the instance lists per level of detail are the reference's blade for blade (blades
//! whose decision rests within a relative 1e-5 of a threshold excepted, and counted); no blade
//! outside the view frustum is drawn (its box of any pose transformed to clip space lies outside
//! one clip plane); culling only by the frustum loses no blade that has a posed vertex in view and
//! draws the same image as no culling, byte for byte; levels change only inside their dither bands;
//! with every mechanism on, the image stays close to the unculled one where blades are visible.
//! Runs on whatever adapter the machine has (lavapipe without a GPU).

use std::sync::OnceLock;

use crate::common::gpu;
use furbake_formats::sections::blade_field::BladeField;
use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, KeyframeTable, Symmetry};
use furbake_grass::keyframes::PoseGridSettings;
use furbake_grass::{
    BladeFieldSettings, BladeMaterial, BladeShape, ForceField, ForceScene, KeyframeDecoder, PoseInterpolation,
    build_reference_blade, compress_poses, ground_grid_mesh, scatter_blades, simulate_poses,
};
use furbake_render::FrameUniforms;
use furbake_render::headless::{RenderTarget, read_back};
use furbake_render::testing::{CullLists, CullReference};
use furbake_render::{BladeRenderSettings, BladeRenderer, GrassCulling, View};
use furbake_runtime::Camera;
use glam::{DMat4, DVec4, Mat4, Vec2, Vec3};
use image::RgbaImage;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 200;

/// The default 8-segment blade over 100 poses, snorm16.
fn table() -> &'static KeyframeTable {
    static TABLE: OnceLock<KeyframeTable> = OnceLock::new();
    TABLE.get_or_init(|| {
        let grid = PoseGridSettings { poses: 100, ..Default::default() }.resolve(Symmetry::XZ).unwrap();
        let blade = build_reference_blade(&BladeShape::default()).unwrap();
        let poses = simulate_poses(&blade, &BladeMaterial::default(), grid).unwrap();
        let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
        compress_poses(&poses, Symmetry::XZ, stages, DisplacementEncoding::Snorm16).unwrap()
    })
}

/// A 30 m × 30 m field centred on the origin, 30 blades/m² (≈ 27,000 blades), 1 m clusters.
fn field() -> &'static BladeField {
    static FIELD: OnceLock<BladeField> = OnceLock::new();
    FIELD.get_or_init(|| {
        let settings = BladeFieldSettings { density_per_m2: 30.0, cluster_size_m: 1.0, ..Default::default() };
        let mut field = scatter_blades(&ground_grid_mesh([30.0, 30.0], [30, 30]), &settings).unwrap();
        assert!((20_000..35_000).contains(&field.blade_count()), "{} blades", field.blade_count());
        // Taller blades than the default so they are visible from across the field.
        for h in &mut field.height_scale {
            *h *= 2.0;
        }
        field
    })
}

/// Every mechanism within the field's 30 m: LOD 1 from 5 m, LOD 2 from 12 m, thinning from
/// 8 m, nothing beyond 22 m.
fn tight() -> GrassCulling {
    GrassCulling {
        max_distance_m: 22.0,
        lod_distances_m: [5.0, 12.0],
        lod_transition: 0.3,
        thinning_start_m: 8.0,
        min_density: 0.25,
        ..GrassCulling::default()
    }
}

fn wind() -> ForceField {
    let mut forces = ForceField::new(field().grid);
    forces.update(&ForceScene { global_wind: Vec2::new(1.2, 0.5), ..ForceScene::default() });
    forces
}

/// The posed world positions of blade `b` of [`field`] in `forces`, as the blade shader poses it
/// (nearest keyframe), into `posed`.
fn pose_blade(decoder: &KeyframeDecoder, forces: &ForceField, b: usize, posed: &mut [Vec3]) {
    let f = field();
    let root = Vec3::from(f.positions[b]);
    let force = forces.blade_force(f.grid.corner_indices(f.cluster[b]), f.weights[b], root);
    let force = Vec3::new(force.x, 0.0, force.y);
    decoder.world_positions(root, f.yaw_rad[b], f.height_scale[b], force, PoseInterpolation::Nearest, posed);
}

fn renderer(culling: GrassCulling) -> BladeRenderer {
    let settings = BladeRenderSettings { culling, ..BladeRenderSettings::default() };
    let r = BladeRenderer::new(gpu().pipelines(), &gpu().queue, field(), table(), &settings, &RenderTarget::desc())
        .unwrap();
    r.set_force_field(&gpu().queue, &wind()).unwrap();
    r
}

fn view(eye: [f32; 3], target: [f32; 3]) -> View {
    let mut v = View::framing([0.0, 0.5, 0.0], 22.0);
    v.camera = Camera { eye, target, up: [0.0, 1.0, 0.0], fov_y_deg: 50.0 };
    v
}

/// Named cameras with their model matrices: at eye height across the field, looking down on a
/// corner, looking away from the field, and the field placed elsewhere rotated and scaled.
fn cameras() -> Vec<(&'static str, View, Mat4)> {
    let placed = Mat4::from_translation(Vec3::new(100.0, 2.0, -40.0))
        * Mat4::from_rotation_y(35f32.to_radians())
        * Mat4::from_scale(Vec3::splat(1.5));
    let placed_eye = placed.transform_point3(Vec3::new(-4.0, 1.0, -14.0));
    let placed_target = placed.transform_point3(Vec3::new(2.0, 0.0, 6.0));
    vec![
        ("eye height", view([0.0, 1.7, -16.0], [0.0, 0.2, 6.0]), Mat4::IDENTITY),
        ("from above", view([8.0, 9.0, 6.0], [9.0, 0.0, 9.0]), Mat4::IDENTITY),
        ("looking away", view([0.0, 1.0, -20.0], [0.0, 1.0, -40.0]), Mat4::IDENTITY),
        (
            "placed",
            {
                let mut v = view(placed_eye.to_array(), placed_target.to_array());
                // Near and far planes around the placed field.
                v.bounds_center = placed.transform_point3(Vec3::new(0.0, 0.5, 0.0)).to_array();
                v.bounds_radius = 22.0 * 1.5;
                v
            },
            placed,
        ),
    ]
}

fn frame(view: &View, model: Mat4) -> FrameUniforms {
    view.uniforms_with_model(WIDTH, HEIGHT, model)
}

/// Renders one frame of `r` (clear to black) and reads back the image.
fn draw(r: &BladeRenderer, frame: &FrameUniforms) -> RgbaImage {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let target = RenderTarget::new(device, WIDTH, HEIGHT).unwrap();
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("test frame") });
    r.prepare(queue, &mut encoder, frame);
    r.render(&mut target.begin_pass(&mut encoder, "test pass", Some([0.0, 0.0, 0.0, 1.0])));
    queue.submit([encoder.finish()]);
    read_back(device, queue, &target).unwrap()
}

/// GPU lists equal the reference's except for blades near a threshold, which may sit in either.
fn assert_lists_match(gpu: &CullLists, cpu: &CullLists, near: &[u32], what: &str) {
    for l in 0..3 {
        let (g, c) = (&gpu.lods[l], &cpu.lods[l]);
        assert!(g.windows(2).all(|w| w[0] < w[1]), "{what}: LOD {l} list is not in blade order");
        let only_gpu: Vec<u32> = g.iter().filter(|b| c.binary_search(b).is_err()).copied().collect();
        let only_cpu: Vec<u32> = c.iter().filter(|b| g.binary_search(b).is_err()).copied().collect();
        let unexplained: Vec<&u32> = only_gpu.iter().chain(&only_cpu).filter(|b| !near.contains(b)).collect();
        assert!(
            unexplained.is_empty(),
            "{what}: LOD {l}: {} blades only on the GPU, {} only on the CPU, not near a threshold: {unexplained:?}",
            only_gpu.len(),
            only_cpu.len()
        );
    }
}

#[test]
fn gpu_instance_lists_equal_the_cpu_reference_for_fixed_cameras() {
    let reference = CullReference::new(field(), table());
    for culling in [tight(), GrassCulling::default(), GrassCulling::frustum_only()] {
        let r = renderer(culling);
        for (name, view, model) in cameras() {
            let f = frame(&view, model);
            draw(&r, &f);
            let got = r.read_culling(&gpu().device, &gpu().queue).unwrap();
            let want = reference.classify(&f, &culling);
            let what = format!("{name}, {culling:?}");
            assert_lists_match(&got, &want.lists, &want.near_boundary, &what);
            let (g, c) = (got.counts(), want.lists.counts());
            println!(
                "{name}: {} clusters visible of {}, drawn per LOD GPU {g:?} CPU {c:?} of {} blades, {} near a threshold",
                want.visible_clusters,
                field().grid.clusters(),
                field().blade_count(),
                want.near_boundary.len()
            );
            for l in 0..3 {
                assert!(g[l].abs_diff(c[l]) <= want.near_boundary.len(), "{what}: LOD {l} counts {g:?} vs {c:?}");
            }
            match name {
                "looking away" => assert_eq!(got.drawn(), 0, "{what}: blades behind the camera were drawn"),
                "eye height" | "placed" if culling == tight() => {
                    // Every mechanism at work: all three levels, and most blades culled.
                    assert!(g.iter().all(|&n| n > 100), "{what}: {g:?}");
                    assert!(got.drawn() * 3 < field().blade_count(), "{what}: {g:?}");
                }
                _ => assert!(got.drawn() > 500, "{what}: {g:?}"),
            }
        }
    }
}

/// The corners of a box holding every pose of blade `b` (root ± reach × height, widened as
/// thinning may widen it), in the pack frame.
fn blade_box(b: usize, reach: f64) -> [DVec4; 8] {
    let f = field();
    let [x, y, z] = f.positions[b].map(f64::from);
    let r = reach * f.height_scale[b] as f64;
    std::array::from_fn(|k| {
        let s = |bit: usize| if k >> bit & 1 == 1 { r } else { -r };
        DVec4::new(x + s(0), y + s(1), z + s(2), 1.0)
    })
}

#[test]
fn no_blade_outside_the_frustum_is_drawn() {
    let reach = {
        let r = renderer(tight());
        // Thinning widens a kept blade by up to 1 / min density.
        r.lods().reach as f64 + (1.0 / 0.25 - 1.0) * r.lods().half_width as f64
    };
    for culling in [tight(), GrassCulling::frustum_only()] {
        let r = renderer(culling);
        for (name, view, model) in cameras() {
            let f = frame(&view, model);
            draw(&r, &f);
            let lists = r.read_culling(&gpu().device, &gpu().queue).unwrap();
            let m = DMat4::from_cols_array_2d(&f.view_proj().to_cols_array_2d().map(|c| c.map(f64::from)))
                * DMat4::from_cols_array_2d(&f.model().to_cols_array_2d().map(|c| c.map(f64::from)));
            let mut outside = 0;
            for (b, _) in (0..field().blade_count()).map(|b| (b, ())) {
                let clip = blade_box(b, reach).map(|p| m * p);
                let out = [
                    clip.iter().all(|c| c.x < -c.w),
                    clip.iter().all(|c| c.x > c.w),
                    clip.iter().all(|c| c.y < -c.w),
                    clip.iter().all(|c| c.y > c.w),
                    clip.iter().all(|c| c.z < 0.0),
                    clip.iter().all(|c| c.z > c.w),
                ]
                .contains(&true);
                if out {
                    outside += 1;
                    for l in 0..3 {
                        assert!(
                            lists.lods[l].binary_search(&(b as u32)).is_err(),
                            "{name}: blade {b} is outside but drawn"
                        );
                    }
                }
            }
            println!("{name}: {outside} blades wholly outside the frustum, none drawn");
            if name == "looking away" {
                assert_eq!(outside, field().blade_count());
            }
        }
    }
}

#[test]
fn frustum_culling_keeps_every_blade_in_view_and_draws_the_same_image() {
    let decoder = KeyframeDecoder::new(table()).unwrap();
    let forces = wind();
    let culled = renderer(GrassCulling::frustum_only());
    let unculled = renderer(GrassCulling::off());
    let mut posed = vec![Vec3::ZERO; table().vertex_count()];
    for (name, view, model) in cameras() {
        let f = frame(&view, model);
        let image_culled = draw(&culled, &f);
        let lists = culled.read_culling(&gpu().device, &gpu().queue).unwrap();
        assert_eq!(lists.counts()[1..], [0, 0], "{name}: frustum-only culling keeps every blade at full detail");
        let image_unculled = draw(&unculled, &f);
        assert!(image_culled == image_unculled, "{name}: culling by the frustum changed the image");
        // Every blade with a posed vertex inside the clip volume is drawn.
        let m = f.view_proj() * model;
        let f_ = field();
        let mut in_view = 0;
        for b in 0..f_.blade_count() {
            pose_blade(&decoder, &forces, b, &mut posed);
            let visible = posed.iter().any(|p| {
                let c = m * p.extend(1.0);
                c.x.abs() < c.w * 0.999 && c.y.abs() < c.w * 0.999 && c.z > 0.0 && c.z < c.w
            });
            if visible {
                in_view += 1;
                assert!(lists.lods[0].binary_search(&(b as u32)).is_ok(), "{name}: blade {b} is in view but culled");
            }
        }
        println!("{name}: {in_view} blades in view, {} drawn after frustum culling", lists.drawn());
        assert!(lists.drawn() >= in_view);
    }
}

#[test]
fn levels_change_only_inside_their_dither_bands() {
    let culling = tight();
    let r = renderer(culling);
    let (_, view, model) = &cameras()[0];
    let f = frame(view, *model);
    draw(&r, &f);
    let lists = r.read_culling(&gpu().device, &gpu().queue).unwrap();
    let eye = Vec3::from(view.camera.eye);
    let [d1, d2] = culling.lod_distances_m;
    let half = culling.lod_transition * 0.5;
    let band = |d: f32, at: f32| d >= at * (1.0 - half) - 1e-3 && d <= at * (1.0 + half) + 1e-3;
    // Per band: blades at the nearer and at the farther level inside it.
    let mut in_band = [[0usize; 2]; 2];
    for (l, list) in lists.lods.iter().enumerate() {
        for &b in list {
            let d = eye.distance(Vec3::from(field().positions[b as usize]));
            let allowed = match l {
                0 => d <= d1 * (1.0 + half) + 1e-3,
                1 => d >= d1 * (1.0 - half) - 1e-3 && d <= d2 * (1.0 + half) + 1e-3,
                _ => d >= d2 * (1.0 - half) - 1e-3,
            };
            assert!(allowed, "blade {b} at {d:.3} m drawn at LOD {l} (bands around {d1} and {d2} m, ±{half})");
            for (k, at) in [d1, d2].into_iter().enumerate() {
                if band(d, at) && (l == k || l == k + 1) {
                    in_band[k][l - k] += 1;
                }
            }
        }
    }
    // Both bands hold blades of both levels (the dither), not a hard edge.
    for (k, n) in in_band.iter().enumerate() {
        assert!(n[0] > 20 && n[1] > 20, "band {k}: {n:?} blades at its nearer and farther level");
    }
    println!("blades at the nearer and farther level inside each dither band: {in_band:?}");
}

#[test]
fn culled_and_simplified_grass_stays_close_to_the_full_image() {
    let full = renderer(GrassCulling::off());
    // Distances of the default kind (LOD from 10 m and 30 m is beyond this 30 m field, so the
    // bands are pulled in to show each mechanism's effect), nothing beyond the field.
    let culling = GrassCulling {
        max_distance_m: 60.0,
        lod_distances_m: [6.0, 14.0],
        thinning_start_m: 10.0,
        ..GrassCulling::default()
    };
    let culled = renderer(culling);
    let (name, view, model) = &cameras()[0];
    let f = frame(view, *model);
    let a = draw(&full, &f);
    let b = draw(&culled, &f);
    let counts = culled.read_culling(&gpu().device, &gpu().queue).unwrap().counts();
    let dir = std::env::temp_dir().join("furbake-render-tests");
    std::fs::create_dir_all(&dir).unwrap();
    a.save(dir.join("grass_unculled.png")).unwrap();
    b.save(dir.join("grass_culled.png")).unwrap();
    // Coverage (pixels with grass) and mean colour difference over pixels grass covers in
    // either image, per band of rows (near rows at the bottom, far rows at the top).
    let grass = |p: &image::Rgba<u8>| p[0] > 0 || p[1] > 0 || p[2] > 0;
    let rows = HEIGHT / 4;
    for band in 0..4 {
        let (mut cov_a, mut cov_b, mut diff, mut n) = (0usize, 0usize, 0.0f64, 0usize);
        for y in band * rows..(band + 1) * rows {
            for x in 0..WIDTH {
                let (pa, pb) = (a.get_pixel(x, y), b.get_pixel(x, y));
                cov_a += grass(pa) as usize;
                cov_b += grass(pb) as usize;
                if grass(pa) || grass(pb) {
                    n += 1;
                    diff += (0..3).map(|c| (pa[c] as f64 - pb[c] as f64).abs()).sum::<f64>() / 3.0;
                }
            }
        }
        let mean = diff / n.max(1) as f64;
        println!(
            "{name}, rows {}..{}: coverage full {cov_a} culled {cov_b}, mean |Δ| {mean:.1} over {n} pixels",
            band * rows,
            (band + 1) * rows
        );
        if cov_a > 200 {
            let ratio = cov_b as f64 / cov_a as f64;
            assert!((0.95..=1.05).contains(&ratio), "rows {band}: coverage changed by {ratio:.3}");
        }
    }
    println!("drawn per LOD {counts:?} of {}", field().blade_count());
}

#[test]
fn culling_off_draws_every_blade_and_bad_settings_are_refused() {
    let mut r = renderer(GrassCulling::off());
    let (_, view, model) = &cameras()[0];
    draw(&r, &frame(view, *model));
    let lists = r.read_culling(&gpu().device, &gpu().queue).unwrap();
    assert_eq!(lists.lods[0], (0..field().blade_count() as u32).collect::<Vec<_>>());
    assert!(lists.lods[1].is_empty() && lists.lods[2].is_empty());
    // Switched on, the same renderer culls.
    r.set_culling(&gpu().queue, tight()).unwrap();
    draw(&r, &frame(view, *model));
    assert!(r.read_culling(&gpu().device, &gpu().queue).unwrap().drawn() * 3 < field().blade_count());
    // Out-of-range settings name the key, at creation and when changed.
    let bad = GrassCulling { min_density: 0.0, ..GrassCulling::default() };
    let settings = BladeRenderSettings { culling: bad, ..BladeRenderSettings::default() };
    let err = BladeRenderer::new(gpu().pipelines(), &gpu().queue, field(), table(), &settings, &RenderTarget::desc())
        .err()
        .expect("min_density 0 is refused");
    assert!(err.to_string().contains("grass_culling.min_density"), "{err}");
    let err = r
        .set_culling(&gpu().queue, GrassCulling { lod_distances_m: [f32::NAN, 1.0], ..GrassCulling::default() })
        .unwrap_err();
    assert!(err.to_string().contains("grass_culling.lod_distances_m"), "{err}");
    assert_eq!(*r.culling(), tight(), "a refused setting leaves the last one");
}

/// The preview of `gltf` baked with the grass preset (4 layers of 16², so it is quick; 2 m fur),
/// with blades 15–25 m tall at `density` per m² or without.
fn preview_of(gltf: &[u8], density: Option<f32>) -> RgbaImage {
    let mesh = furbake_import::import_gltf_slice(gltf, "mesh.gltf", None, &Default::default()).unwrap();
    let mut settings = furbake_bake::BakeSettings::preset("grass").unwrap();
    (settings.volume.layers, settings.volume.resolution) = (4, 16);
    // Short fur, tall blades: the blades stand out of the shells.
    settings.shells.fur_length_m = Some(2.0);
    settings.blades = density.map(|d| {
        let mut b = furbake_bake::BladeSettings::default();
        b.field.density_per_m2 = d;
        (b.field.height_min_m, b.field.height_max_m) = (15.0, 25.0);
        b.keyframes.grid.poses = 40;
        b
    });
    let baked = furbake_bake::bake(&mesh, "mesh", &settings.plan().unwrap(), &mut furbake_bake::NoProgress).unwrap();
    if let Some((field, _)) = &baked.blades {
        let h = field.height_scale.iter().copied().fold(0.0f32, f32::max);
        println!("{} blades, tallest {h} m, fur {} m", field.blade_count(), baked.shells.fur_length_m);
    }
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mesh.fbk");
    baked.to_writer().write_atomic(&path).unwrap();
    furbake_render::headless::render_preview(
        &furbake_runtime::Pack::open(&path).unwrap(),
        160,
        120,
        &Default::default(),
    )
    .unwrap()
}

#[test]
fn a_pack_preview_draws_its_grass_whatever_its_units() {
    // A sphere of radius 100 with blades of 15–25 (a glTF in centimetres reads so): the preview
    // frames it from about 340 "metres", past the default max distance of 150 m. A pack alone has no scene to say its
    // units, so its preview culls only by the frustum and the blades are drawn.
    let gltf = furbake_import::testmesh::uv_sphere(12, 16, 100.0).gltf;
    let with = preview_of(&gltf, Some(0.05));
    let without = preview_of(&gltf, None);
    let differ = with.pixels().zip(without.pixels()).filter(|(a, b)| a != b).count();
    println!("{differ} of {} pixels differ with the blades", 160 * 120);
    assert!(differ > 500, "the blades of a large pack are missing from its preview ({differ} pixels differ)");
}

/// An opaque box the host draws before the grass (its occluder): a pipeline of the test's own
/// into the headless target's pass, writing depth.
struct Occluder {
    pipeline: wgpu::RenderPipeline,
    vertices: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    group: wgpu::BindGroup,
    lo: Vec3,
    hi: Vec3,
}

impl Occluder {
    fn new(lo: Vec3, hi: Vec3) -> Occluder {
        use wgpu::util::DeviceExt;
        let device = &gpu().device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("test occluder"),
            source: wgpu::ShaderSource::Wgsl(
                "@group(0) @binding(0) var<uniform> view_proj: mat4x4<f32>;
                 @vertex fn vs(@location(0) p: vec3<f32>) -> @builtin(position) vec4<f32> {
                     return view_proj * vec4<f32>(p, 1.0);
                 }
                 @fragment fn fs() -> @location(0) vec4<f32> { return vec4<f32>(0.5, 0.3, 0.2, 1.0); }"
                    .into(),
            ),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: None,
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("test occluder"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: 12,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &wgpu::vertex_attr_array![0 => Float32x3],
                })],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: furbake_render::headless::DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(furbake_render::headless::COLOR_FORMAT.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        // The box's 12 triangles (no face culling).
        let c = |i: usize| {
            Vec3::new(
                if i & 1 != 0 { hi.x } else { lo.x },
                if i & 2 != 0 { hi.y } else { lo.y },
                if i & 4 != 0 { hi.z } else { lo.z },
            )
        };
        let faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]];
        let mut v: Vec<[f32; 3]> = Vec::new();
        for f in faces {
            for i in [0, 1, 2, 0, 2, 3] {
                v.push(c(f[i]).to_array());
            }
        }
        let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents: bytemuck::cast_slice(&v),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: 64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: uniforms.as_entire_binding() }],
        });
        Occluder { pipeline, vertices, uniforms, group, lo, hi }
    }

    /// True when the segment from `eye` to `p` passes through the box shrunk by `margin`.
    fn hides(&self, eye: Vec3, p: Vec3, margin: f32) -> bool {
        let (lo, hi) = (self.lo + Vec3::splat(margin), self.hi - Vec3::splat(margin));
        let d = p - eye;
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for a in 0..3 {
            if d[a].abs() < 1e-12 {
                if eye[a] < lo[a] || eye[a] > hi[a] {
                    return false;
                }
                continue;
            }
            let (mut ta, mut tb) = ((lo[a] - eye[a]) / d[a], (hi[a] - eye[a]) / d[a]);
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            t0 = t0.max(ta);
            t1 = t1.min(tb);
        }
        t0 < t1
    }
}

/// One frame as a host with occluders draws it: the box, then (with `pyramid`) the depth pyramid
/// of that depth, the grass's culling and the grass, depth-tested against the box.
fn draw_behind(
    r: &BladeRenderer,
    frame: &FrameUniforms,
    occluder: &Occluder,
    pyramid: Option<&furbake_render::DepthPyramid>,
) -> RgbaImage {
    let (device, queue) = (&gpu().device, &gpu().queue);
    let target = RenderTarget::new(device, WIDTH, HEIGHT).unwrap();
    queue.write_buffer(&occluder.uniforms, 0, bytemuck::cast_slice(&frame.view_proj().to_cols_array()));
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = target.begin_pass(&mut encoder, "occluders", Some([0.0, 0.0, 0.0, 1.0]));
        pass.set_pipeline(&occluder.pipeline);
        pass.set_bind_group(0, &occluder.group, &[]);
        pass.set_vertex_buffer(0, occluder.vertices.slice(..));
        pass.draw(0..36, 0..1);
    }
    if let Some(p) = pyramid {
        p.record(device, &mut encoder, &target.depth).unwrap();
    }
    r.prepare(queue, &mut encoder, frame);
    r.render(&mut target.begin_pass(&mut encoder, "grass", None));
    queue.submit([encoder.finish()]);
    read_back(device, queue, &target).unwrap()
}

#[test]
fn blades_behind_a_box_are_not_drawn_and_the_image_is_unchanged() {
    // A 10 m × 2.5 m wall across the field, drawn by the host before the grass. With the wall's
    // depth pyramid bound, blades wholly behind it are culled (counted as occluded), and the frame
    // equals the one without the occlusion test byte for byte: no blade that shows is lost. The
    // pyramid is this frame's, so a camera that moves past the wall loses nothing either.
    let (device, queue) = (&gpu().device, &gpu().queue);
    let wall = Occluder::new(Vec3::new(-5.0, 0.0, -8.0), Vec3::new(5.0, 2.5, -7.6));
    let pyramid = furbake_render::DepthPyramid::new(device, WIDTH, HEIGHT, false).unwrap();
    let mut occluding = renderer(GrassCulling::frustum_only());
    occluding.set_occlusion(gpu().pipelines(), 0, Some(&pyramid)).unwrap();
    let plain = renderer(GrassCulling::frustum_only());
    let decoder = KeyframeDecoder::new(table()).unwrap();
    let forces = wind();
    let f_ = field();
    let mut posed = vec![Vec3::ZERO; table().vertex_count()];
    let cameras = [
        ("behind the wall", [0.0, 1.7, -16.0], [0.0, 0.2, 6.0], true),
        ("over the wall", [0.0, 4.0, -16.0], [0.0, 0.0, 4.0], true),
        ("moving past it, left", [-6.0, 1.7, -15.0], [-1.0, 0.2, 6.0], true),
        ("moving past it, right", [6.0, 1.7, -15.0], [1.0, 0.2, 6.0], true),
        ("the wall behind the camera", [0.0, 1.7, -5.0], [0.0, 0.2, 10.0], false),
    ];
    for (name, eye, target, hidden_expected) in cameras {
        let f = frame(&view(eye, target), Mat4::IDENTITY);
        let with = draw_behind(&occluding, &f, &wall, Some(&pyramid));
        let lists = occluding.read_culling(device, queue).unwrap();
        let occluded = occluding.read_occluded(device, queue).unwrap() as usize;
        let without = draw_behind(&plain, &f, &wall, None);
        let all = plain.read_culling(device, queue).unwrap();
        assert!(with == without, "{name}: the occlusion test changed the image");
        assert!(lists.drawn() + occluded >= all.drawn(), "{name}: blades went missing besides the occluded");
        // Independent check: a blade every posed vertex of which lies behind the wall (the ray
        // from the eye passes through it, 5 cm inside its faces) is hidden.
        let eye = Vec3::from(eye);
        let (mut hidden, mut hidden_drawn) = (0, 0);
        for b in 0..f_.blade_count() {
            pose_blade(&decoder, &forces, b, &mut posed);
            if all.lods[0].binary_search(&(b as u32)).is_ok() && posed.iter().all(|&p| wall.hides(eye, p, 0.05)) {
                hidden += 1;
                hidden_drawn += usize::from(lists.lods[0].binary_search(&(b as u32)).is_ok());
            }
        }
        println!(
            "{name}: {} blades after frustum culling, {occluded} occluded, {} drawn; {hidden} hidden behind the \
             wall, {hidden_drawn} of them still drawn (conservative bounds)",
            all.drawn(),
            lists.drawn()
        );
        if hidden_expected {
            assert!(hidden > 1000, "{name}: the wall hides {hidden} blades");
            // A blade is tested by a box around every pose it may take, so near the wall's top
            // edge a hidden blade's box may show above it and the blade is kept.
            assert!(hidden_drawn * 2 <= hidden, "{name}: {hidden_drawn} of {hidden} hidden blades are still drawn");
        } else {
            assert_eq!((hidden, occluded), (0, 0), "{name}: nothing is behind the wall");
        }
    }
}

#[test]
fn a_scene_culls_its_grass_behind_its_fur() {
    // The demo's Fox standing on its grass patch, seen from above its flank: with grass occlusion on,
    // the scene renderer draws the fur, builds the pyramid of its depth, culls the grass against
    // it and draws the grass: the same frame, byte for byte, with the blades behind the Fox not
    // drawn.
    use furbake_bake::{BakeSettings, NoProgress, bake};
    use furbake_import::{ImportSettings, import_gltf, import_gltf_slice, testmesh};
    use furbake_render::SceneRenderer;
    use furbake_runtime::World;
    let (device, queue) = (&gpu().device, &gpu().queue);
    let dir = tempfile::tempdir().unwrap();
    let fox = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let mut fur = BakeSettings::preset("fur").unwrap();
    fur.volume.layers = 8;
    fur.volume.resolution = 32;
    fur.topologies = vec!["prisms".into()];
    let imported = import_gltf(&fox, &ImportSettings::default()).unwrap();
    bake(&imported, "fox", &fur.plan().unwrap(), &mut NoProgress)
        .unwrap()
        .to_writer()
        .write_atomic(&dir.path().join("fox.fbk"))
        .unwrap();
    let mut grass = BakeSettings::preset("grass").unwrap();
    grass.volume.layers = 8;
    grass.volume.resolution = 32;
    grass.topologies = vec!["prisms".into()];
    let mut blades = furbake_bake::BladeSettings::default();
    blades.field.density_per_m2 = 400.0;
    grass.blades = Some(blades);
    let patch = testmesh::grass_patch(4.0).gltf;
    let imported = import_gltf_slice(&patch, "patch.gltf", None, &ImportSettings::default()).unwrap();
    bake(&imported, "patch.gltf", &grass.plan().unwrap(), &mut NoProgress)
        .unwrap()
        .to_writer()
        .write_atomic(&dir.path().join("grass.fbk"))
        .unwrap();
    let toml = r#"
[camera]
eye = [-0.8, 0.75, 0.0]
target = [0.6, 0.0, 0.0]
fov_y_deg = 50.0
[[packs]]
name = "fox"
path = "fox.fbk"
scale = 0.01
[[packs]]
name = "grass"
path = "grass.fbk"
scale = 0.5
[effects.wind]
velocity_m_per_s = [2.0, 0.0, 0.5]
"#;
    let scene = furbake_runtime::Scene::from_toml_str(toml, std::path::Path::new("s.toml"), dir.path()).unwrap();
    let mut world = World::new(scene).unwrap();
    world.step().unwrap();
    let target = RenderTarget::new(device, WIDTH, HEIGHT).unwrap();
    let mut plain = SceneRenderer::new(device, queue, &world).unwrap();
    plain.render_world(device, queue, &target, &world).unwrap();
    let without = read_back(device, queue, &target).unwrap();
    let drawn_without = plain.packs()[1].blades.as_ref().unwrap().read_culling(device, queue).unwrap().drawn();
    plain.set_grass_occlusion(gpu().pipelines(), Some((WIDTH, HEIGHT))).unwrap();
    plain.render_world(device, queue, &target, &world).unwrap();
    let with = read_back(device, queue, &target).unwrap();
    let blades = plain.packs()[1].blades.as_ref().unwrap();
    let (drawn, occluded) =
        (blades.read_culling(device, queue).unwrap().drawn(), blades.read_occluded(device, queue).unwrap());
    println!("scene: {drawn_without} blades drawn without the test, {drawn} with, {occluded} occluded by the Fox");
    assert!(with == without, "grass occlusion changed the scene's frame");
    assert!(occluded > 100 && drawn + occluded as usize >= drawn_without, "{drawn} drawn, {occluded} occluded");
    // A target of another size than the pyramid's is refused.
    let small = RenderTarget::new(device, 64, 64).unwrap();
    let e = plain.render_world(device, queue, &small, &world).unwrap_err().to_string();
    assert!(e.contains("occlusion"), "{e}");
}
