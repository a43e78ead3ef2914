//! The crowd benchmark (docs/performance.md "A herd on a field"): N walking Foxes on a field of
//! grass blades, their fur physics on the CPU or on the GPU, grass culled by frustum and distance
//! alone or also against the depth of the Foxes, one frame per world step at 60 Hz. Per
//! configuration: the host's CPU time for furbake's part of a frame (World::step, prepare, the
//! passes recorded into the host's encoder and wgpu's encoding of them in `finish`), the GPU
//! time of the frame (timestamp queries, where the adapter has them), the whole frame with its
//! submission and wait, blades considered / drawn / occluded, and the host part's allocations
//! (wgpu's own included). Medians over the measured frames after warm-up frames.
//!
//! ```text
//! cargo bench -p furbake-render --bench crowd -- --foxes 1,10,100 --blades 1000000 --size 1920x1080
//! ```
//!
//! Options: `--foxes LIST` (default 1,10), `--blades N` (default 1,000,000: a square field at 400
//! blades/m²), `--size WxH` (default 1920x1080), `--frames N` measured after 5 warm-up frames
//! (default 20), `--physics cpu,gpu`, `--occlusion off,on`, `--png-dir DIR` (each configuration's
//! last frame). Prints one Markdown table.

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use furbake_bake::{BakeSettings, BladeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf, import_gltf_slice, testmesh};
use furbake_render::SceneRenderer;
use furbake_render::headless::{HeadlessGpu, RenderTarget};
use furbake_runtime::{Scene, World};

/// Counts every allocation of the process (the frame's host part is single-threaded apart from
/// rayon's workers, whose allocations count too).
struct Counting;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const DENSITY_PER_M2: f32 = 400.0;
const WARM_UP: usize = 5;

struct Options {
    foxes: Vec<usize>,
    blades: u64,
    size: (u32, u32),
    frames: usize,
    physics: Vec<String>,
    occlusion: Vec<bool>,
    /// Where to write the last frame of each configuration (`--png-dir`), if anywhere.
    png_dir: Option<std::path::PathBuf>,
}

fn options() -> Options {
    let mut o = Options {
        foxes: vec![1, 10],
        blades: 1_000_000,
        size: (1920, 1080),
        frames: 20,
        physics: vec!["cpu".into(), "gpu".into()],
        occlusion: vec![false, true],
        png_dir: None,
    };
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        let value = args.get(i + 1).cloned().unwrap_or_default();
        let list = || value.split(',').map(str::to_string).collect::<Vec<_>>();
        match args[i].as_str() {
            "--foxes" => o.foxes = list().iter().map(|s| s.parse().expect("--foxes: numbers")).collect(),
            "--blades" => o.blades = value.parse().expect("--blades: a number"),
            "--size" => {
                let (w, h) = value.split_once('x').expect("--size WxH");
                o.size = (w.parse().expect("width"), h.parse().expect("height"));
            }
            "--frames" => o.frames = value.parse().expect("--frames: a number"),
            "--physics" => o.physics = list(),
            "--occlusion" => o.occlusion = list().iter().map(|s| s == "on").collect(),
            "--png-dir" => o.png_dir = Some(value.into()),
            // `cargo bench` passes `--bench`.
            _ => {
                i += 1;
                continue;
            }
        }
        i += 2;
    }
    o
}

/// Bakes the Fox (the fur preset, prisms) and a square field of `blades` grass blades into `dir`.
fn bake_packs(dir: &Path, blades: u64) -> f32 {
    let fox = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let mut fur = BakeSettings::preset("fur").expect("the fur preset");
    fur.topologies = vec!["prisms".into()];
    let imported = import_gltf(&fox, &ImportSettings::default()).expect("the bundled Fox");
    bake(&imported, "fox", &fur.plan().expect("a plan"), &mut NoProgress)
        .expect("the Fox bakes")
        .to_writer()
        .write_atomic(&dir.join("fox.fbk"))
        .expect("fox.fbk");
    let side_m = (blades as f32 / DENSITY_PER_M2).sqrt();
    let mut grass = BakeSettings::preset("grass").expect("the grass preset");
    grass.topologies = vec!["prisms".into()];
    let mut field = BladeSettings::default();
    field.field.density_per_m2 = DENSITY_PER_M2;
    grass.blades = Some(field);
    let patch = testmesh::grass_patch(side_m).gltf;
    let imported = import_gltf_slice(&patch, "field.gltf", None, &ImportSettings::default()).expect("the field");
    bake(&imported, "field.gltf", &grass.plan().expect("a plan"), &mut NoProgress)
        .expect("the field bakes")
        .to_writer()
        .write_atomic(&dir.join("field.fbk"))
        .expect("field.fbk");
    side_m
}

/// `n` Foxes (1.55 m long) in rows 2 m apart across the middle of the field, walking 1.5 m/s
/// along +z with their Walk clip, fur on `physics`; gravity and a gusting breeze; the camera at
/// eye height behind them.
fn scene(dir: &Path, n: usize, side_m: f32, physics: &str) -> Scene {
    let per_row = ((n as f32).sqrt().ceil() as usize).max(1);
    let mut toml = format!(
        "time_step_s = {}\n[solver]\ndevice = \"{physics}\"\n[camera]\neye = [0.0, 1.7, {}]\ntarget = [0.0, 0.3, 0.0]\n\
         fov_y_deg = 50.0\n[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [2.0, 0.0, 0.5]\ngust_amplitude = 0.5\n\
         [grass_culling]\nmax_distance_m = {}\n\n[[packs]]\nname = \"field\"\npath = \"field.fbk\"\n",
        1.0 / 60.0,
        -0.5 * side_m - 2.0,
        side_m * 1.5
    );
    for i in 0..n {
        let x = (i % per_row) as f32 * 2.0 - (per_row - 1) as f32;
        let z = (i / per_row) as f32 * 2.0 - (n / per_row) as f32;
        toml += &format!(
            "\n[[packs]]\nname = \"fox{i}\"\npath = \"fox.fbk\"\nscale = 0.02\ntranslation = [{x}, 0.0, {z}]\n\
             animation = {{ clip = \"Walk\", speed = 1.0, loop = true, start_s = {} }}\n\
             [[packs.motion]]\ntime_s = 0.0\n[[packs.motion]]\ntime_s = 10.0\ntranslation = [0.0, 0.0, 15.0]\n",
            (i % 7) as f32 * 0.1
        );
    }
    Scene::from_toml_str(&toml, Path::new("crowd.toml"), dir).expect("the crowd scene")
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn main() {
    let o = options();
    let timestamps = wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
    let g = HeadlessGpu::with_optional_features(timestamps).expect("a GPU or lavapipe");
    let has_timestamps = g.device.features().contains(timestamps);
    let period_ns = g.queue.get_timestamp_period() as f64;
    let dir = tempfile::tempdir().expect("a temporary folder");
    let baked = Instant::now();
    let side_m = bake_packs(dir.path(), o.blades);
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "adapter: {} ({:?}); {cpus} CPU threads; {}×{}; field {side_m:.1} m square at {DENSITY_PER_M2} blades/m²; \
         packs baked in {:.1} s; medians of {} frames after {WARM_UP}",
        g.info.name,
        g.info.backend,
        o.size.0,
        o.size.1,
        baked.elapsed().as_secs_f64(),
        o.frames
    );
    println!(
        "\n| Foxes | fur physics | grass occlusion | host ms/frame (world step, encoder finish) | GPU ms/frame | frame ms (submit + wait) | blades considered | drawn | occluded | allocations/frame |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let target = RenderTarget::new(&g.device, o.size.0, o.size.1).expect("the target");
    let queries = g.device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("crowd frame"),
        ty: wgpu::QueryType::Timestamp,
        count: 2,
    });
    let resolve = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let read = g.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    for &n in &o.foxes {
        for physics in &o.physics {
            for &occlusion in &o.occlusion {
                let mut world = World::new(scene(dir.path(), n, side_m, physics)).expect("the world");
                let mut renderer = SceneRenderer::new(&g.device, &g.queue, &world).expect("the renderer");
                if occlusion {
                    renderer.set_grass_occlusion(g.pipelines(), Some(o.size)).expect("occlusion");
                }
                let (mut host, mut gpu, mut wall, mut allocs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
                let (mut stepping, mut finishing) = (Vec::new(), Vec::new());
                for f in 0..WARM_UP + o.frames {
                    let started = Instant::now();
                    let allocated = ALLOCATIONS.load(Ordering::Relaxed);
                    world.step().expect("a world step");
                    let stepped = started.elapsed().as_secs_f64() * 1e3;
                    let view = renderer.world_view(&world);
                    let frame = view.uniforms(o.size.0, o.size.1);
                    let mut encoder = g.device.create_command_encoder(&Default::default());
                    if has_timestamps {
                        encoder.write_timestamp(&queries, 0);
                    }
                    renderer.prepare_world(&g.queue, &mut encoder, &world, &frame).expect("prepare");
                    if occlusion {
                        renderer.render_fur(&mut target.begin_pass(
                            &mut encoder,
                            "crowd fur",
                            Some([0.1, 0.1, 0.12, 1.0]),
                        ));
                        renderer.prepare_grass(&g.device, &mut encoder, &target.depth).expect("grass culling");
                        renderer.render_grass(&mut target.begin_pass(&mut encoder, "crowd grass", None));
                    } else {
                        renderer.render(&mut target.begin_pass(&mut encoder, "crowd", Some([0.1, 0.1, 0.12, 1.0])));
                    }
                    if has_timestamps {
                        encoder.write_timestamp(&queries, 1);
                        encoder.resolve_query_set(&queries, 0..2, &resolve, 0);
                        encoder.copy_buffer_to_buffer(&resolve, 0, &read, 0, 16);
                    }
                    let recorded = started.elapsed().as_secs_f64() * 1e3;
                    // wgpu encodes the recorded commands for the backend in `finish`: host work
                    // that grows with the passes and dispatches recorded, so it counts here.
                    let commands = encoder.finish();
                    let hosted = started.elapsed().as_secs_f64() * 1e3;
                    let host_allocs = ALLOCATIONS.load(Ordering::Relaxed) - allocated;
                    g.queue.submit([commands]);
                    g.device.poll(wgpu::PollType::wait_indefinitely()).expect("the GPU");
                    let walled = started.elapsed().as_secs_f64() * 1e3;
                    let gpu_ms = if has_timestamps {
                        read.slice(..).map_async(wgpu::MapMode::Read, |_| {});
                        g.device.poll(wgpu::PollType::wait_indefinitely()).expect("the GPU");
                        let t: [u64; 2] =
                            bytemuck::pod_read_unaligned(&read.slice(..).get_mapped_range().expect("mapped")[..16]);
                        read.unmap();
                        t[1].saturating_sub(t[0]) as f64 * period_ns * 1e-6
                    } else {
                        f64::NAN
                    };
                    if f >= WARM_UP {
                        host.push(hosted);
                        stepping.push(stepped);
                        finishing.push(hosted - recorded);
                        wall.push(walled);
                        gpu.push(gpu_ms);
                        allocs.push(host_allocs as f64);
                    }
                }
                if let Some(png) = &o.png_dir {
                    std::fs::create_dir_all(png).expect("the PNG folder");
                    let name = format!("crowd-{n}-{physics}-{}.png", if occlusion { "occluded" } else { "plain" });
                    let image = furbake_render::headless::read_back(&g.device, &g.queue, &target).expect("the frame");
                    image.save(png.join(name)).expect("the PNG");
                }
                let field = renderer.packs()[0].blades.as_ref().expect("the field has blades");
                let drawn = field.read_culling(&g.device, &g.queue).expect("culling lists").drawn();
                let occluded = field.read_occluded(&g.device, &g.queue).expect("decisions");
                let gpu_ms = median(&mut gpu);
                println!(
                    "| {n} | {physics} | {} | {:.2} ({:.2}, {:.2}) | {} | {:.2} | {} | {drawn} | {occluded} | {:.0} |",
                    if occlusion { "on" } else { "off" },
                    median(&mut host),
                    median(&mut stepping),
                    median(&mut finishing),
                    if gpu_ms.is_nan() { "not measured (no timestamps)".to_string() } else { format!("{gpu_ms:.2}") },
                    median(&mut wall),
                    field.blade_count(),
                    median(&mut allocs)
                );
            }
        }
    }
}
