//! Frame time of the renderer on whatever adapter the machine has, waiting for the GPU after every
//! frame (no readback); prints Markdown tables.
//!
//! Fur (skin + shells + fins, fur thesis §3.2): bakes a glTF mesh with 16, 32, 64 and 128 shell
//! layers (or the listed ones) and times frames at 256² and 1920×1080, with the silhouette fins
//! on and off, alternating frame by frame so both see the same machine load:
//! `cargo run --release -p furbake-render --example frame_time -- [MESH.glb | sphere] [FRAMES] [LAYERS...]`
//! (default mesh: the bundled `fixtures/real/Fox.glb`; `sphere`: a generated 3,120-triangle UV
//! sphere of radius 1 m, the bake target's "~3,000-triangle mesh"; default 10 frames per cell).
//!
//! Grass (grass thesis §4.2, §5.3): a generated square field of about BLADES blades (default
//! 1,000,000; 400 per m², 8-segment blades, 1 m clusters, snorm16 keyframes over 400 poses) under
//! global wind plus three moving wind sources (eq. 4.1): each frame updates the CPU force field,
//! uploads the corner forces and draws the field at 1920×1080, once with culling and distance LOD
//! (the default `GrassCulling`) and once without (every blade at full detail), alternating frame by
//! frame, from two cameras: at eye height (1.7 m) at the field's edge looking across it, and high
//! over it looking down across it. Prints the blades considered, the clusters and blades drawn
//! per level of detail (read back after the timed frames), both frame times and their ratio:
//! `cargo run --release -p furbake-render --example frame_time -- blades [BLADES] [FRAMES] [WxH]`
//! (default 1920x1080; a tiny size shows what the frame costs without the fill).

use std::sync::Arc;
use std::time::Instant;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::headless::{HeadlessGpu, RenderTarget};
use furbake_render::{FurAsset, FurRenderer, RenderSettings, View};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("blades") {
        return blades(&args[1..]);
    }
    let mesh = args
        .first()
        .cloned()
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/Fox.glb").into());
    let frames: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(10);
    let layer_counts: Vec<u32> = if args.len() > 2 {
        args[2..].iter().map(|s| s.parse()).collect::<Result<_, _>>()?
    } else {
        vec![16, 32, 64, 128]
    };
    let gpu = HeadlessGpu::new()?;
    let imported = if mesh == "sphere" {
        let gltf = furbake_import::testmesh::uv_sphere(40, 40, 1.0).gltf;
        furbake_import::import_gltf_slice(&gltf, "sphere.gltf", None, &ImportSettings::default())?
    } else {
        import_gltf(mesh.as_ref(), &ImportSettings::default())?
    };
    println!(
        "adapter: {} ({:?}, {:?}, driver {} {})",
        gpu.info.name, gpu.info.device_type, gpu.info.backend, gpu.info.driver, gpu.info.driver_info
    );
    println!(
        "mesh: {mesh} — {} vertices, {} triangles ({} furry); {frames} frames per cell, median\n",
        imported.mesh.positions.len(),
        imported.mesh.triangles.len(),
        imported.mesh.furry_triangles()
    );
    println!(
        "| shells | 256×256 (ms) | 256×256, no silhouette fins (ms) | 1920×1080 (ms) | 1920×1080, no silhouette fins (ms) |"
    );
    println!("|---:|---:|---:|---:|---:|");
    for layers in layer_counts {
        let mut settings = BakeSettings::preset("fur")?;
        settings.volume.layers = layers;
        let baked = bake(&imported, "mesh", &settings.plan()?, &mut NoProgress)?;
        let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
        let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins)?;
        let (center, radius) = asset.bounding_sphere();
        let view = View::framing(center, radius);
        let with = RenderSettings::default();
        let without = RenderSettings { silhouette_fins: false, ..RenderSettings::default() };
        let renderers =
            [with, without].map(|s| FurRenderer::new(gpu.pipelines(), &gpu.queue, &asset, &s, &RenderTarget::desc()));
        let [with, without] = renderers;
        let (with, without) = (with?, without?);
        let mut cells = Vec::new();
        for (w, h) in [(256u32, 256u32), (1920, 1080)] {
            let target = RenderTarget::new(&gpu.device, w, h)?;
            let mut times = [Vec::with_capacity(frames), Vec::with_capacity(frames)];
            for i in 0..frames + 2 {
                for (k, renderer) in [&with, &without].into_iter().enumerate() {
                    let start = Instant::now();
                    renderer.render_to(&gpu.device, &gpu.queue, &target, &view)?;
                    gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
                    if i >= 2 {
                        times[k].push(start.elapsed().as_secs_f64() * 1e3);
                    }
                }
            }
            for mut t in times {
                t.sort_by(f64::total_cmp);
                cells.push(t[t.len() / 2]);
            }
        }
        println!("| {layers} | {:.1} | {:.1} | {:.1} | {:.1} |", cells[0], cells[1], cells[2], cells[3]);
    }
    Ok(())
}

/// The grass half: see the module documentation.
fn blades(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, Symmetry};
    use furbake_grass::keyframes::PoseGridSettings;
    use furbake_grass::{
        BladeFieldSettings, BladeMaterial, BladeShape, BladeWindSource, ForceField, ForceScene, build_reference_blade,
        compress_poses, ground_grid_mesh, scatter_blades, simulate_poses,
    };
    use furbake_render::{BladeRenderSettings, BladeRenderer, GrassCulling};
    use glam::{Vec2, Vec3};

    let target_blades: f64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(1_000_000.0);
    let frames: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(5);
    let gpu = HeadlessGpu::with_large_buffers()?;
    println!(
        "adapter: {} ({:?}, {:?}, driver {} {})",
        gpu.info.name, gpu.info.device_type, gpu.info.backend, gpu.info.driver, gpu.info.driver_info
    );
    let t = Instant::now();
    let grid = PoseGridSettings { poses: 400, ..Default::default() }.resolve(Symmetry::XZ)?;
    let shape = BladeShape { segments: 8, ..Default::default() };
    let poses = simulate_poses(&build_reference_blade(&shape)?, &BladeMaterial::default(), grid)?;
    let stages = CompressionStages { drop_static_vertices: true, rigid_segment_pairs: true };
    let table = compress_poses(&poses, Symmetry::XZ, stages, DisplacementEncoding::Snorm16)?;
    let density = 400.0f32;
    let side = (target_blades as f32 / density).sqrt();
    let cells = (side.ceil() as u32).max(1);
    let settings = BladeFieldSettings { density_per_m2: density, cluster_size_m: 1.0, ..Default::default() };
    let field = scatter_blades(&ground_grid_mesh([side, side], [cells, cells]), &settings)?;
    println!(
        "field: {} blades on {side:.1} m × {side:.1} m, {} vertices and {} triangles per blade, {} cluster corners (built in {:.1} s)",
        field.blade_count(),
        table.vertex_count(),
        table.triangles.len(),
        field.grid.corners(),
        t.elapsed().as_secs_f64()
    );
    let mut blades = BladeRenderer::new(
        gpu.pipelines(),
        &gpu.queue,
        &field,
        &table,
        &BladeRenderSettings::default(),
        &RenderTarget::desc(),
    )?;
    let culling = *blades.culling();
    let (center, radius) = blades.bounding_sphere();
    let (w, h) = match args.get(2) {
        Some(size) => {
            let (w, h) = size.split_once('x').ok_or("size must be WIDTHxHEIGHT")?;
            (w.parse::<u32>()?, h.parse::<u32>()?)
        }
        None => (1920, 1080),
    };
    let target = RenderTarget::new(&gpu.device, w, h)?;
    let mut forces = ForceField::new(field.grid);
    let half = side * 0.5;
    let scene_at = |time_s: f32| ForceScene {
        global_wind: Vec2::new(0.8, 0.2),
        sources: (0..3)
            .map(|k| {
                let a = time_s * 0.7 + k as f32 * 2.1;
                BladeWindSource {
                    position_m: Vec3::new(center[0] + a.cos() * half * 0.6, 0.3, center[2] + a.sin() * half * 0.6),
                    power: 3.0,
                    falloff_exponent: 1.0,
                    delayed: false,
                }
            })
            .collect(),
        ..ForceScene::default()
    };
    println!(
        "culling: max {} m, LOD from {:?} m (±{:.0} %), thinning from {} m to {:.0} %, edge-on below {:.0} % width; \
         levels of {:?} segments",
        culling.max_distance_m,
        culling.lod_distances_m,
        culling.lod_transition * 50.0,
        culling.thinning_start_m,
        culling.min_density * 100.0,
        culling.min_visible_width * 100.0,
        &blades.lods().segments[..blades.lods().count as usize]
    );
    println!(
        "\n| camera | blades considered | clusters drawn | drawn at 8 / 4 / 2 segments | force update (ms, CPU) | \
         culling pass alone (ms) | frame culled (ms) | frame unculled (ms) | unculled / culled |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    let cameras = [
        // At eye height at the middle of one edge, looking across the field.
        ("eye height, at the edge", [center[0], 1.7, center[2] + half], [center[0], 0.5, center[2] - half * 0.2]),
        // High over one edge looking down across it (most blades in view, many small on screen).
        ("high, across", [center[0], center[1] + side * 0.25, center[2] + side * 0.75], center),
    ];
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut coverage = Vec::new();
    // The CPU reference, for the visible-cluster count.
    let reference = furbake_render::testing::CullReference::new(&field, &table);
    for (name, eye, look_at) in cameras {
        let mut view = View::framing(center, radius);
        view.camera.eye = eye;
        view.camera.target = look_at;
        let (mut update_ms, mut culled_ms, mut unculled_ms) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..frames + 1 {
            for on in [true, false] {
                blades.set_culling(&gpu.queue, if on { culling } else { GrassCulling::off() })?;
                let start = Instant::now();
                forces.update(&scene_at(i as f32 / 60.0));
                let updated = start.elapsed().as_secs_f64() * 1e3;
                blades.set_force_field(&gpu.queue, &forces)?;
                blades.render_to(&gpu.device, &gpu.queue, &target, &view, Some([0.5, 0.6, 0.8, 1.0]))?;
                gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
                if i >= 1 {
                    update_ms.push(updated);
                    if on { &mut culled_ms } else { &mut unculled_ms }.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
        }
        // One more culled frame, read back: what the timed culled frames drew.
        blades.set_culling(&gpu.queue, culling)?;
        blades.render_to(&gpu.device, &gpu.queue, &target, &view, Some([0.5, 0.6, 0.8, 1.0]))?;
        let lists = blades.read_culling(&gpu.device, &gpu.queue)?;
        let image = furbake_render::headless::read_back(&gpu.device, &gpu.queue, &target)?;
        let sky = image.get_pixel(0, 0).0;
        coverage.push((name, image.pixels().filter(|p| p.0 != sky).count() as f64 / (w * h) as f64));
        let frame_uniforms = view.uniforms(target.width, target.height);
        // The culling pass alone: prepare (uniforms + the four dispatches), submit, wait.
        let mut pass_ms = Vec::with_capacity(frames);
        for _ in 0..frames {
            let start = Instant::now();
            let mut encoder = gpu.device.create_command_encoder(&Default::default());
            blades.prepare(&gpu.queue, &mut encoder, &frame_uniforms);
            gpu.queue.submit([encoder.finish()]);
            gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
            pass_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let clusters = reference.classify(&frame_uniforms, &culling);
        let [c, u] = [median(&mut culled_ms), median(&mut unculled_ms)];
        let n = lists.counts();
        println!(
            "| {name} | {} | {} of {} | {} ({} / {} / {}) | {:.2} | {:.1} | {c:.0} | {u:.0} | {:.1} |",
            field.blade_count(),
            clusters.visible_clusters,
            field.grid.clusters(),
            lists.drawn(),
            n[0],
            n[1],
            n[2],
            median(&mut update_ms),
            median(&mut pass_ms),
            u / c
        );
    }
    println!(
        "\n({frames} frames of each after one warm-up, alternating, median; blades cover {} of the culled frame)",
        coverage.iter().map(|(n, c)| format!("{:.0} % ({n})", c * 100.0)).collect::<Vec<_>>().join(", ")
    );
    Ok(())
}
