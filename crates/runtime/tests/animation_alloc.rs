//! The animation CPU reference allocates nothing per frame once its buffers exist: a counting
//! global allocator (per thread, so other tests running in parallel do not count) watches one
//! frame of advance → pose → joint matrices → skinning matrices → morph-then-skin on the Fox, a
//! world's `Animator` update, and a host's per-frame edit of the effects.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

use furbake_import::{ImportSettings, import_gltf};
use furbake_runtime::animation::{AnimationPlayer, Pose, joint_world_matrices, morph_and_skin, skinning_matrices};
use glam::Mat4;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
    /// This thread's allocations also count in `WATCHED_ALLOCATIONS` (the workers of a test's
    /// own thread pool, and the test's thread).
    static WATCHED: Cell<bool> = const { Cell::new(false) };
}

/// Allocations on every watched thread.
static WATCHED_ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards every call to the system allocator unchanged; only counts allocations.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        if WATCHED.try_with(Cell::get).unwrap_or(false) {
            WATCHED_ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: the caller's contract for `alloc` is passed through.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract for `dealloc` is passed through.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_frame_of_animation_allocates_nothing() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let fox = import_gltf(&path, &ImportSettings::default()).unwrap();
    let a = &fox.animation;
    let (sk, weights, clips) = (a.skeleton.as_ref().unwrap(), a.skin_weights.as_ref(), a.clips.as_ref().unwrap());
    let mut player = AnimationPlayer::new(clips, "Walk", 1.0, true, Some(sk), None).unwrap();
    let mut pose = Pose::rest(Some(sk), None);
    let mut world = vec![Mat4::IDENTITY; sk.joint_count()];
    let mut palette = vec![Mat4::IDENTITY; sk.bind_count()];
    let v = fox.mesh.positions.len();
    let (mut p, mut n) = (vec![[0.0; 3]; v], vec![[0.0; 3]; v]);
    player.play(clips, "Run", 0.3).unwrap(); // a cross-fade uses the player's scratch poses
    let before = ALLOCATIONS.with(Cell::get);
    for _ in 0..10 {
        player.advance(clips, 1.0 / 60.0);
        player.pose(clips, &[], &mut pose).unwrap();
        joint_world_matrices(sk, &pose, &mut world).unwrap();
        skinning_matrices(sk, &world, &mut palette).unwrap();
        morph_and_skin(&fox.mesh, weights, None, &palette, &mut p, &mut n).unwrap();
    }
    let after = ALLOCATIONS.with(Cell::get);
    assert_eq!(after - before, 0, "allocations during 10 frames");
    assert!(p.iter().flatten().all(|x| x.is_finite()));
    assert!(before > 0, "the counter counts (the import allocated)");
}

/// A temporary folder holding `ball.fbk`: a small UV sphere baked by [`bake_small_prisms`].
fn ball_pack() -> tempfile::TempDir {
    use furbake_import::{import_gltf_slice, testmesh};
    let sphere = testmesh::uv_sphere(6, 8, 0.5);
    let mesh = import_gltf_slice(&sphere.gltf, "sphere.gltf", None, &ImportSettings::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    bake_small_prisms(&mesh, &dir.path().join("ball.fbk"));
    dir
}

/// Bakes `mesh` into `pack` with small atlases (16² × 4 layers) and the prisms topology.
fn bake_small_prisms(mesh: &furbake_import::ImportedMesh, pack: &std::path::Path) {
    use furbake_bake::{BakeSettings, NoProgress, bake};
    let mut settings = BakeSettings::preset("fur").unwrap();
    (settings.volume.resolution, settings.volume.layers) = (16, 4);
    settings.topologies = vec!["prisms".into()];
    let name = pack.file_name().unwrap().to_str().unwrap();
    bake(mesh, name, &settings.plan().unwrap(), &mut NoProgress).unwrap().to_writer().write_atomic(pack).unwrap();
}

#[test]
fn an_animator_update_and_a_host_effects_edit_allocate_nothing() {
    use furbake_runtime::{Scene, World, scene::Collider};
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/real/Fox.glb");
    let fox = import_gltf(&path, &ImportSettings::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    bake_small_prisms(&fox, &dir.path().join("fox.fbk"));
    let text = "[[packs]]\nname = \"fox\"\npath = \"fox.fbk\"\nanimation = { clip = \"Run\" }\n\
                [effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.0]\n[[effects.collisions]]\nshape = \"sphere\"\ncenter = [0.0, 0.0, 0.0]\nradius_m = 0.5\n";
    let mut world = World::new(Scene::from_toml_str(text, "t.toml".as_ref(), dir.path()).unwrap()).unwrap();
    let frame = |world: &mut World, k: f32| {
        let a = world.animation_mut(0).unwrap();
        a.advance(1.0 / 60.0);
        a.update().unwrap();
        world
            .update_effects(|e| {
                e.wind.as_mut().unwrap().velocity_m_per_s = [k, 0.0, 0.0];
                if let Collider::Sphere { center, .. } = &mut e.collisions[0] {
                    center[0] = k;
                }
            })
            .unwrap();
    };
    frame(&mut world, 0.5); // the first edit sizes the backup's lists
    let before = ALLOCATIONS.with(Cell::get);
    for k in 0..10 {
        frame(&mut world, k as f32 * 0.1);
    }
    let allocated = ALLOCATIONS.with(Cell::get) - before;
    assert_eq!(allocated, 0, "ten frames of animation and effect edits allocated {allocated} times");
}

/// A world step of a moving, furry pack under every fur force allocates nothing once the world
/// runs: the force stages write the fur's force set in place, the solver copies it into its own
/// (`Simulator::set_forces_from`) and reads the local forces where it evaluates them, the solver
/// and the scale vectors reuse their buffers.
#[test]
fn a_world_step_of_moving_fur_allocates_nothing() {
    use furbake_runtime::{Scene, World};
    let dir = ball_pack();
    let text = "time_step_s = 0.02\n[[packs]]\nname = \"ball\"\npath = \"ball.fbk\"\n\
                [[packs.motion]]\ntime_s = 0.0\n[[packs.motion]]\ntime_s = 1.0\ntranslation = [1.0, 0.0, 0.0]\n\
                rotation_deg = [0.0, 90.0, 0.0]\n\
                [effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.5]\ngust_amplitude = 0.3\n\
                [effects.object_motion]\n[effects.wrong_side_guard]\n\
                [effects.interaction]\nposition = [0.4, 0.0, 0.0]\nradius_m = 0.3\nstrength_n = 0.001\n";
    let mut world = World::new(Scene::from_toml_str(text, "t.toml".as_ref(), dir.path()).unwrap()).unwrap();
    world.step().unwrap();
    let before = ALLOCATIONS.with(Cell::get);
    for _ in 0..20 {
        world.step().unwrap();
    }
    let allocated = ALLOCATIONS.with(Cell::get) - before;
    assert_eq!(allocated, 0, "twenty world steps allocated {allocated} times");
    assert!(world.fur(0).unwrap().scale_vectors.iter().flatten().all(|c| c.is_finite()));
}

/// A world of several packs steps them side by side on the thread pool's workers; the step still
/// allocates nothing on any of them (allocations are counted on the test's thread and on the
/// workers of a pool of its own, whatever other tests do meanwhile).
#[test]
fn a_world_step_of_packs_side_by_side_allocates_nothing_on_any_worker() {
    use furbake_runtime::{Scene, World};
    let dir = ball_pack();
    let mut text = String::from("time_step_s = 0.02\n");
    for i in 0..4 {
        text += &format!(
            "[[packs]]\nname = \"ball{i}\"\npath = \"ball.fbk\"\n[[packs.motion]]\ntime_s = 0.0\n\
             translation = [{x}, 0.0, 0.0]\n[[packs.motion]]\ntime_s = 1.0\ntranslation = [{x}, 1.0, 0.0]\n",
            x = 2 * i
        );
    }
    text += "[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [1.0, 0.0, 0.5]\n[effects.object_motion]\n\
             [effects.wrong_side_guard]\n";
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .start_handler(|_| WATCHED.with(|w| w.set(true)))
        .build()
        .unwrap();
    let mut world = World::new(Scene::from_toml_str(&text, "t.toml".as_ref(), dir.path()).unwrap()).unwrap();
    // Ten warm-up steps, so that each worker has run each pack's stages before the count starts
    // (with one, fresh-clone CI runs under load counted one allocation in the twenty steps in two
    // runs of three; the steady state is what this test holds to zero).
    pool.install(|| (0..10).try_for_each(|_| world.step())).unwrap();
    WATCHED.with(|w| w.set(true));
    let before = WATCHED_ALLOCATIONS.load(Ordering::Relaxed);
    // One entry into the pool for all twenty steps: a host thread outside the pool hands each
    // step to the pool through rayon's injector queue, which allocates a block of slots every 63
    // entries (measured: one allocation in twenty steps entered one by one) — rayon's, not the
    // world's.
    pool.install(|| (0..20).try_for_each(|_| world.step())).unwrap();
    let allocated = WATCHED_ALLOCATIONS.load(Ordering::Relaxed) - before;
    WATCHED.with(|w| w.set(false));
    assert_eq!(allocated, 0, "twenty world steps of four packs allocated {allocated} times");
    assert!((0..4).all(|i| world.fur(i).unwrap().scale_vectors.iter().flatten().all(|c| c.is_finite())));
}
