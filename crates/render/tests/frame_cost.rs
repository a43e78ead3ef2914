//! Per-frame CPU cost of the middleware path on the demo scene: the packs baked as the Makefile's
//! `demo` target bakes them (the Fox with the `fur` preset and prism topology, the grass patch with
//! the `grass` preset, 400 blades/m² and prism topology), the scene
//! `fixtures/scenes/demo_fox_and_grass.toml`, and each frame the whole of furbake's part: the
//! `furbake_runtime::World`'s step (on a thread pool of the test's own, as a host runs it),
//! `SceneRenderer::prepare_world` and `SceneRenderer::render` into a host's encoder and pass,
//! timed and watched by a counting global allocator (per thread, as in
//! `crates/runtime/tests/animation_alloc.rs`, and on every worker of that pool). The host's pass,
//! submission and wait are outside the measurement. Prints the figures (`--nocapture`) for
//! docs/performance.md and checks that furbake neither submits nor waits during the frames, that
//! the world's step allocates nothing on any thread and that the allocations per frame stay at the
//! measured level; a second test (release builds only) takes a backtrace of every allocation of
//! one frame and checks that each happens inside a wgpu call: furbake's own code allocates
//! nothing.

use std::alloc::{GlobalAlloc, Layout, System};
use std::backtrace::Backtrace;
use std::cell::{Cell, RefCell};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use furbake_bake::settings::dotted_override;
use furbake_bake::{BakeSettings, NoProgress, bake};
use furbake_import::{ImportSettings, import_gltf};
use furbake_render::headless::{HeadlessGpu, RenderTarget};
use furbake_render::testing::blocking_calls_on_this_thread;
use furbake_render::{PipelineCache, SceneRenderer};
use furbake_runtime::{Scene, World};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    /// While set, every allocation on this thread records a backtrace in `TRACES`.
    static TRACING: Cell<bool> = const { Cell::new(false) };
    /// Set while a backtrace is being recorded (its own allocations are not traced).
    static IN_TRACE: Cell<bool> = const { Cell::new(false) };
    static TRACES: RefCell<Vec<Backtrace>> = const { RefCell::new(Vec::new()) };
    /// Set on the workers of the demo's thread pool, whose allocations count in
    /// `WORKER_ALLOCATIONS`.
    static DEMO_WORKER: Cell<bool> = const { Cell::new(false) };
}

/// Allocations on the workers of every demo's thread pool (only one demo runs at a time: the
/// tests that build one hold `DEMO_LOCK`).
static WORKER_ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
static DEMO_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Counts an allocation, and records its backtrace while tracing.
fn note_allocation() {
    if DEMO_WORKER.try_with(Cell::get).unwrap_or(false) {
        WORKER_ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        return;
    }
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
    let tracing = TRACING.try_with(Cell::get).unwrap_or(false);
    if tracing && !IN_TRACE.try_with(Cell::get).unwrap_or(true) {
        IN_TRACE.with(|t| t.set(true));
        let trace = Backtrace::force_capture();
        TRACES.with(|t| t.borrow_mut().push(trace));
        IN_TRACE.with(|t| t.set(false));
    }
}

// SAFETY: forwards every call to the system allocator unchanged; only counts allocations (and,
// while tracing, records where they came from, with its own allocations excluded).
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_allocation();
        // SAFETY: the caller's contract for `alloc` is passed through.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract for `dealloc` is passed through.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_allocation();
        // SAFETY: the caller's contract for `realloc` is passed through.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations so far on this thread and on the demo's workers.
fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get) + WORKER_ALLOCATIONS.load(Ordering::Relaxed)
}

/// Bakes `gltf` (relative to the workspace) with `preset` and the `--set`-style `sets` into
/// `dir/name`.
fn bake_pack(dir: &Path, gltf: &str, preset: &str, sets: &[&str], name: &str) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mesh = import_gltf(&root.join(gltf), &ImportSettings::default()).unwrap();
    let mut settings = BakeSettings::preset(preset).unwrap();
    for set in sets {
        settings = settings.with_overrides(&dotted_override(set).unwrap()).unwrap();
    }
    let baked = bake(&mesh, name, &settings.plan().unwrap(), &mut NoProgress).unwrap();
    baked.to_writer().write_atomic(&dir.join(name)).unwrap();
}

const WARM_UP_FRAMES: usize = 5;
const FRAMES: usize = 48;

/// The demo scene, its world and a headless host for it.
struct Demo {
    _dir: tempfile::TempDir,
    world: World,
    gpu: HeadlessGpu,
    renderer: SceneRenderer,
    target: RenderTarget,
    /// The host's thread pool the world steps on (two workers: the packs run side by side).
    pool: rayon::ThreadPool,
    _lock: std::sync::MutexGuard<'static, ()>,
}

impl Demo {
    fn new() -> Demo {
        let lock = DEMO_LOCK.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .start_handler(|_| DEMO_WORKER.with(|w| w.set(true)))
            .build()
            .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        bake_pack(dir.path(), "fixtures/real/Fox.glb", "fur", &[r#"topologies=["prisms"]"#], "fox.fbk");
        bake_pack(
            dir.path(),
            "fixtures/generated/grass_patch.gltf",
            "grass",
            &["blades.field.density_per_m2=400", r#"topologies=["prisms"]"#],
            "grass-patch.fbk",
        );
        let scene_path = dir.path().join("fox_and_grass.toml");
        std::fs::copy(root.join("fixtures/scenes/demo_fox_and_grass.toml"), &scene_path).unwrap();
        let world = World::new(Scene::load(&scene_path).unwrap()).unwrap();
        let gpu = HeadlessGpu::new().unwrap();
        let pipelines = PipelineCache::new(&gpu.device);
        let renderer = SceneRenderer::for_target(&pipelines, &gpu.queue, &world, &RenderTarget::desc()).unwrap();
        let target = RenderTarget::new(&gpu.device, 320, 240).unwrap();
        Demo { _dir: dir, world, gpu, renderer, target, pool, _lock: lock }
    }

    /// Runs one host frame; `measure` wraps each of furbake's parts of it, told which: the
    /// world's step (on the demo's pool), then the view and `prepare_world`, then — with the
    /// host's pass begun — `render`.
    fn frame(&mut self, mut measure: impl FnMut(Part, &mut dyn FnMut())) {
        let (pool, world) = (&self.pool, &mut self.world);
        measure(Part::Step, &mut || pool.install(|| world.step().unwrap()));
        let (gpu, renderer, world, target) = (&self.gpu, &self.renderer, &self.world, &self.target);
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        measure(Part::Draw, &mut || {
            let view = renderer.world_view(world);
            renderer
                .prepare_world(&gpu.queue, &mut encoder, world, &view.uniforms(target.width, target.height))
                .unwrap();
        });
        {
            let mut pass = target.begin_pass(&mut encoder, "host pass", Some(renderer.frame().background));
            measure(Part::Draw, &mut || renderer.render(&mut pass));
        }
        gpu.queue.submit([encoder.finish()]);
        gpu.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    }
}

/// A part of furbake's frame.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Part {
    /// `World::step`.
    Step,
    /// `world_view`, `prepare_world` and `render`.
    Draw,
}

#[test]
fn demo_scene_frame_cost_and_allocations() {
    let mut demo = Demo::new();
    let (mut times_us, mut counts, mut step_times_us) = (Vec::new(), Vec::new(), Vec::new());
    let mut step_allocations = 0;
    for frame in 0..WARM_UP_FRAMES + FRAMES {
        let calls = blocking_calls_on_this_thread();
        let (mut elapsed, mut count) = (std::time::Duration::ZERO, 0);
        let (mut step_elapsed, mut step_count) = (std::time::Duration::ZERO, 0);
        demo.frame(|part, work| {
            let (start, before) = (Instant::now(), allocations());
            work();
            let (time, n) = (start.elapsed(), allocations() - before);
            match part {
                Part::Step => (step_elapsed, step_count) = (time, n),
                Part::Draw => (elapsed, count) = (elapsed + time, count + n),
            }
        });
        // The host's submit and wait above are the test's; only furbake's part must not move it.
        assert_eq!(blocking_calls_on_this_thread(), calls, "frame {frame}: furbake submitted or waited");
        if frame >= WARM_UP_FRAMES {
            times_us.push(elapsed.as_secs_f64() * 1e6);
            step_times_us.push(step_elapsed.as_secs_f64() * 1e6);
            counts.push(count);
            step_allocations += step_count;
        }
    }
    let Demo { gpu, target, renderer, .. } = &demo;
    gpu.check().unwrap();
    let image = furbake_render::headless::read_back(&gpu.device, &gpu.queue, target).unwrap();
    let bg = image.get_pixel(0, 0).0;
    assert!(image.pixels().filter(|p| p.0 != bg).count() > 320 * 240 / 20, "the demo frame is nearly empty");

    // What wgpu itself allocates per upload, for the attribution in docs/performance.md.
    let probe = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 256,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let before = allocations();
    for _ in 0..10 {
        gpu.queue.write_buffer(&probe, 0, &[0u8; 240]);
    }
    let per_write = (allocations() - before) as f64 / 10.0;
    gpu.queue.submit([]);

    times_us.sort_by(f64::total_cmp);
    step_times_us.sort_by(f64::total_cmp);
    let median = times_us[times_us.len() / 2];
    let mean = times_us.iter().sum::<f64>() / times_us.len() as f64;
    let (lo, hi) = (counts.iter().min().unwrap(), counts.iter().max().unwrap());
    println!(
        "demo scene, {} packs ({}), over {FRAMES} frames: world step on 2 workers median {:.0} µs, {step_allocations} \
         allocations in all; world_view + prepare_world + render median {median:.0} µs, mean {mean:.0} µs, p90 {:.0} µs, \
         allocations per frame {lo}–{hi}; wgpu allocates {per_write:.1} per queue.write_buffer",
        renderer.packs().len(),
        if cfg!(debug_assertions) { "debug build" } else { "release build" },
        step_times_us[step_times_us.len() / 2],
        times_us[times_us.len() * 9 / 10],
    );
    assert_eq!(counts.len(), FRAMES);
    assert_eq!(step_allocations, 0, "the world's step allocated");
    assert!(*hi <= MAX_ALLOCATIONS_PER_FRAME, "{hi} allocations in a frame (bound {MAX_ALLOCATIONS_PER_FRAME})");
}

/// The bound the test holds the frame to: measured 32 in the debug build (wgpu-core's debug
/// lock tracing captures a backtrace per lock, which allocates) and 28 in release, every one
/// inside wgpu's calls (`every_allocation_of_a_frame_is_inside_wgpu`): the frame's one upload
/// (docs/design.md "One upload per frame") and the recording of the copies, compute passes and
/// draws. The margin is for wgpu's pools growing now and then.
const MAX_ALLOCATIONS_PER_FRAME: u64 = 48;

#[test]
#[cfg_attr(
    debug_assertions,
    ignore = "wgpu-core captures a backtrace per lock in debug builds, and a capture inside it deadlocks; \
              run with --release"
)]
fn every_allocation_of_a_frame_is_inside_wgpu() {
    let mut demo = Demo::new();
    for _ in 0..WARM_UP_FRAMES {
        demo.frame(|_, work| work());
    }
    demo.frame(|_, work| {
        TRACING.with(|t| t.set(true));
        work();
        TRACING.with(|t| t.set(false));
    });
    let traces = TRACES.with(|t| std::mem::take(&mut *t.borrow_mut()));
    // A frame's symbol name follows its number (`  12: wgpu_core::device::queue::...`).
    let in_wgpu = |trace: &str| {
        trace.lines().any(|l| l.trim_start().split_once(": ").is_some_and(|(_, f)| f.starts_with("wgpu")))
    };
    let texts: Vec<String> = traces.iter().map(|t| t.to_string()).collect();
    let ours: Vec<&String> = texts.iter().filter(|t| !in_wgpu(t)).collect();
    println!("{} allocations traced in one frame, {} outside any wgpu call", texts.len(), ours.len());
    assert!(!texts.is_empty() && texts.iter().any(|t| t.contains("prepare_world")), "the tracer saw nothing");
    assert!(
        ours.is_empty(),
        "furbake allocated in the frame:\n{}",
        ours.iter().map(|t| t.as_str()).collect::<Vec<_>>().join("\n----\n")
    );
}
