//! Frame time of the fur renderer (skin + shells + fins, fur thesis §3.2) on whatever adapter the
//! machine has: bakes a glTF mesh with 16, 32 and 64 shell layers and times frames at 256² and
//! 1920×1080, waiting for the GPU after every frame (no readback). Prints a Markdown table.
//!
//! `cargo run --release -p furbake-render --example frame_time -- [MESH.glb | sphere] [FRAMES]`
//! (default mesh: the bundled `fixtures/real/Fox.glb`; `sphere`: a generated 3,120-triangle UV
//! sphere of radius 1 m, the "~3,000-triangle mesh"; default 10 frames per cell).

use std::sync::Arc;
use std::time::Instant;

use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::{FurAsset, FurRenderer, HeadlessGpu, RenderSettings, RenderTarget, View};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mesh = args
        .first()
        .cloned()
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/real/Fox.glb").into());
    let frames: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(10);
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
    for layers in [16u32, 32, 64] {
        let mut settings = BakeSettings::preset("fur")?;
        settings.volume.layers = layers;
        let baked = bake(&imported, "mesh", &settings, &mut NoProgress)?;
        let fins = Some((Arc::new(baked.fins), Arc::new(baked.fin_edges)));
        let asset = FurAsset::new(Arc::new(baked.mesh), Arc::new(baked.shells), Arc::new(baked.uv_map), fins)?;
        let (center, radius) = asset.bounding_sphere();
        let view = View::framing(center, radius);
        let renderer = FurRenderer::new(&gpu.device, &gpu.queue, &asset, &RenderSettings::default())?;
        let mut cells = Vec::new();
        for (w, h) in [(256u32, 256u32), (1920, 1080)] {
            let target = RenderTarget::new(&gpu.device, w, h)?;
            let mut times = Vec::with_capacity(frames);
            for i in 0..frames + 2 {
                let start = Instant::now();
                renderer.render(&gpu.device, &gpu.queue, &target, &view);
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
