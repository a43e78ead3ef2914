//! Frame time of the renderer on whatever adapter the machine has, waiting for the GPU after every
//! frame (no readback); prints Markdown tables.
//!
//! Fur (skin + shells + fins, fur thesis §3.2): bakes a glTF mesh with 16, 32, 64 and 128 shell
//! layers (or the listed ones) and times frames at 256² and 1920×1080:
//! `cargo run --release -p furbake-render --example frame_time -- [MESH.glb | sphere] [FRAMES] [LAYERS...]`
//! (default mesh: the bundled `fixtures/real/Fox.glb`; `sphere`: a generated 3,120-triangle UV
//! sphere of radius 1 m, the "~3,000-triangle mesh"; default 10 frames per cell).
//!
//! Grass (grass thesis §4.2): a generated square field of about BLADES blades (default 1,000,000;
//! 400 per m², 8-segment blades, 1 m clusters, snorm16 keyframes over 400 poses) under global wind
//! plus three moving wind sources (eq. 4.1): each frame updates the CPU force field, uploads the
//! corner forces and draws every blade instanced at 1920×1080, timing the CPU update and the
//! whole frame separately:
//! `cargo run --release -p furbake-render --example frame_time -- blades [BLADES] [FRAMES]`.

use std::sync::Arc;
use std::time::Instant;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::{FurAsset, FurRenderer, HeadlessGpu, RenderSettings, RenderTarget, View};

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
    println!("| shells | 256×256 (ms) | 1920×1080 (ms) |\n|---:|---:|---:|");
    for layers in layer_counts {
        let mut settings = BakeSettings::preset("fur")?;
        settings.volume.layers = layers;
        let baked = bake(&imported, "mesh", &settings, &mut NoProgress)?;
        let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
        let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins)?;
        let (center, radius) = asset.bounding_sphere();
        let view = View::framing(center, radius);
        let renderer =
            FurRenderer::new(gpu.pipelines(), &gpu.queue, &asset, &RenderSettings::default(), &RenderTarget::desc())?;
        let mut cells = Vec::new();
        for (w, h) in [(256u32, 256u32), (1920, 1080)] {
            let target = RenderTarget::new(&gpu.device, w, h)?;
            let mut times = Vec::with_capacity(frames);
            for i in 0..frames + 2 {
                let start = Instant::now();
                renderer.render_to(&gpu.device, &gpu.queue, &target, &view)?;
                gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
                if i >= 2 {
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                }
            }
            times.sort_by(f64::total_cmp);
            cells.push(times[times.len() / 2]);
        }
        println!("| {layers} | {:.1} | {:.1} |", cells[0], cells[1]);
    }
    Ok(())
}

/// The grass half: see the module documentation.
fn blades(args: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    use furbake_formats::sections::keyframe_table::{CompressionStages, DisplacementEncoding, Symmetry};
    use furbake_grass::keyframes::PoseGridSettings;
    use furbake_grass::{
        BladeFieldSettings, BladeMaterial, BladeShape, ForceField, ForceScene, WindSource, build_reference_blade,
        compress_poses, ground_grid_mesh, scatter_blades, simulate_poses,
    };
    use furbake_render::{BladeRenderer, BladeSettings};
    use glam::{Vec2, Vec3};

    let target_blades: f64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(1_000_000.0);
    let frames: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(5);
    let gpu = HeadlessGpu::new()?;
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
    let blades = BladeRenderer::new(
        gpu.pipelines(),
        &gpu.queue,
        &field,
        &table,
        &BladeSettings::default(),
        &RenderTarget::desc(),
    )?;
    let (center, radius) = blades.bounding_sphere();
    // Low over the field, looking across it (most blades in view, many small on screen).
    let mut view = View::framing(center, radius);
    view.camera.eye = [center[0], center[1] + side * 0.25, center[2] + side * 0.75];
    let (w, h) = (1920u32, 1080u32);
    let target = RenderTarget::new(&gpu.device, w, h)?;
    let mut forces = ForceField::new(field.grid);
    let half = side * 0.5;
    let scene_at = |time_s: f32| ForceScene {
        global_wind: Vec2::new(0.8, 0.2),
        sources: (0..3)
            .map(|k| {
                let a = time_s * 0.7 + k as f32 * 2.1;
                WindSource {
                    position_m: Vec3::new(center[0] + a.cos() * half * 0.6, 0.3, center[2] + a.sin() * half * 0.6),
                    power: 3.0,
                    concentration: 1.0,
                    delayed: false,
                }
            })
            .collect(),
        ..ForceScene::default()
    };
    let (mut update_ms, mut frame_ms) = (Vec::new(), Vec::new());
    for i in 0..frames + 1 {
        let start = Instant::now();
        forces.update(&scene_at(i as f32 / 60.0));
        let updated = start.elapsed().as_secs_f64() * 1e3;
        blades.set_force_field(&gpu.queue, &forces)?;
        blades.render_to(&gpu.device, &gpu.queue, &target, &view, Some([0.5, 0.6, 0.8, 1.0]))?;
        gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
        if i >= 1 {
            update_ms.push(updated);
            frame_ms.push(start.elapsed().as_secs_f64() * 1e3);
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!("\n| blades | segments | wind sources | force update (ms, CPU) | frame 1920×1080 (ms) |");
    println!("|---:|---:|---:|---:|---:|");
    println!(
        "| {} | {} | 3 + global | {:.2} | {:.0} |",
        field.blade_count(),
        shape.segments,
        median(&mut update_ms),
        median(&mut frame_ms)
    );
    // How much of the frame the blades cover (a frame that misses the field would be cheap).
    let image = furbake_render::read_back(&gpu.device, &gpu.queue, &target)?;
    let sky = image.get_pixel(0, 0).0;
    let covered = image.pixels().filter(|p| p.0 != sky).count() as f64 / (w * h) as f64;
    println!("({frames} frames after one warm-up, median; blades cover {:.0} % of the frame)", covered * 100.0);
    Ok(())
}
