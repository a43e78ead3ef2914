//! The C interface called as a C host calls it: packs from files and from memory and their
//! views against the Rust reader's sections, worlds against the Rust runtime's, host-driven
//! poses, and every refusal (codes and messages).

use std::ffi::{CStr, CString};
use std::path::Path;
use std::ptr::{null, null_mut};

use furbake_capi::*;
use furbake_runtime::{Pack, Scene, World, WorldOptions};

use crate::common::packs;

/// A view or descriptor with every field zero and `size` set, as a C host makes it.
fn sized<T>() -> T {
    // SAFETY: the capi structs are numbers and raw pointers, valid zeroed.
    let mut v: T = unsafe { std::mem::zeroed() };
    // SAFETY: every capi struct begins with its u32 `size`.
    unsafe { *(&mut v as *mut T).cast::<u32>() = std::mem::size_of::<T>() as u32 };
    v
}

fn last_error() -> String {
    // SAFETY: the library's message is NUL-terminated and lives until the next failure.
    unsafe { CStr::from_ptr(furbake_last_error()) }.to_string_lossy().into_owned()
}

fn c(s: &str) -> CString {
    CString::new(s).unwrap()
}

fn open(path: &Path) -> *mut FurbakePack {
    let mut pack = null_mut();
    let path = c(path.to_str().unwrap());
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_pack_open_file(path.as_ptr(), &mut pack) }, FurbakeResult::Ok, "{}", last_error());
    pack
}

/// # Safety
/// `ptr` holds `n` elements.
unsafe fn floats<'a>(ptr: *const f32, n: usize) -> &'a [f32] {
    unsafe { std::slice::from_raw_parts(ptr, n) }
}

#[test]
fn the_library_states_its_version() {
    assert_eq!(furbake_abi_version(), FURBAKE_ABI_VERSION);
    // SAFETY: a static NUL-terminated string.
    let version = unsafe { CStr::from_ptr(furbake_version()) }.to_str().unwrap();
    assert_eq!(version, env!("CARGO_PKG_VERSION"));
    assert_eq!(furbake_check_version(FURBAKE_ABI_VERSION), FurbakeResult::Ok);
    assert_eq!(furbake_check_version(FURBAKE_ABI_VERSION + 1), FurbakeResult::Version);
    assert!(last_error().contains("built against version 2"), "{}", last_error());
}

#[test]
fn views_of_a_pack_from_a_file_and_from_memory_are_its_sections() {
    let path = packs().join("fox.fbk");
    let rust = Pack::open(&path).unwrap();
    let from_file = open(&path);
    let bytes = std::fs::read(&path).unwrap();
    let mut from_memory = null_mut();
    let name = c("assets/fox");
    // SAFETY: valid arguments; the bytes may be freed on return.
    let r = unsafe { furbake_pack_open_memory(bytes.as_ptr(), bytes.len(), name.as_ptr(), &mut from_memory) };
    assert_eq!(r, FurbakeResult::Ok, "{}", last_error());
    drop(bytes);
    let mesh = rust.skin_mesh().unwrap();
    let atlas = rust.shell_atlas().unwrap();
    let skeleton = rust.skeleton().unwrap().unwrap();
    for pack in [from_file, from_memory] {
        let mut info: FurbakePackInfo = sized();
        // SAFETY: live handle, sized view.
        assert_eq!(unsafe { furbake_pack_info(pack, &mut info) }, FurbakeResult::Ok);
        let wanted = FURBAKE_HAS_SKIN_MESH
            | FURBAKE_HAS_SHELL_ATLAS
            | FURBAKE_HAS_SKELETON
            | FURBAKE_HAS_SKIN_WEIGHTS
            | FURBAKE_HAS_CLIPS
            | FURBAKE_HAS_SPRING_TOPOLOGY;
        assert_eq!(info.contents & wanted, wanted, "{:#x}", info.contents);
        assert_eq!(info.contents & FURBAKE_HAS_BLADE_FIELD, 0);
        assert_eq!(
            (info.vertex_count as usize, info.triangle_count as usize),
            (mesh.positions.len(), mesh.triangles.len())
        );
        assert_eq!(info.joint_count as usize, skeleton.joint_count());
        assert_eq!(info.file_size, rust.file_size());

        let mut m: FurbakeSkinMeshView = sized();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_skin_mesh(pack, &mut m) }, FurbakeResult::Ok);
        // SAFETY: the view's arrays hold the counts it states while the pack lives.
        let (positions, triangles) = unsafe {
            (
                floats(m.positions, 3 * m.vertex_count as usize),
                std::slice::from_raw_parts(m.triangles, 3 * m.triangle_count as usize),
            )
        };
        assert_eq!(positions, mesh.positions.as_flattened());
        assert_eq!(triangles, mesh.triangles.as_flattened());
        assert!(!m.corner_texcoords.is_null(), "the Fox has texture coordinates");

        let mut a: FurbakeShellAtlasView = sized();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_shell_atlas(pack, &mut a) }, FurbakeResult::Ok);
        assert_eq!((a.resolution, a.layers), (16, 4));
        // SAFETY: as above.
        let alpha = unsafe { std::slice::from_raw_parts(a.alpha, (a.layers * a.resolution * a.resolution) as usize) };
        assert_eq!(alpha, &atlas.alpha[..]);

        let mut s: FurbakeSkeletonView = sized();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_skeleton(pack, &mut s) }, FurbakeResult::Ok);
        // SAFETY: as above.
        let nodes = unsafe { std::slice::from_raw_parts(s.nodes, s.joint_count as usize) };
        assert_eq!(nodes, &skeleton.nodes[..], "joints carry their glTF nodes");
        let mut name = null();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_joint_name(pack, 1, &mut name) }, FurbakeResult::Ok);
        // SAFETY: NUL-terminated, lives with the pack.
        assert_eq!(unsafe { CStr::from_ptr(name) }.to_str().unwrap(), skeleton.names[1]);

        let mut clip: FurbakeClipInfo = sized();
        let clips = rust.animation_clips().unwrap().unwrap();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_clip(pack, 2, &mut clip) }, FurbakeResult::Ok);
        // SAFETY: as above.
        assert_eq!(unsafe { CStr::from_ptr(clip.name) }.to_str().unwrap(), clips.clips[2].name);
        assert_eq!(clip.duration_s, clips.clips[2].duration_s);

        // A fur pack has no blades: Missing, and the message names the pack.
        let mut field: FurbakeBladeFieldView = sized();
        // SAFETY: as above.
        assert_eq!(unsafe { furbake_pack_blade_field(pack, &mut field) }, FurbakeResult::Missing);
        let message = last_error();
        assert!(
            message.contains("blade") && (message.contains("fox.fbk") || message.contains("assets/fox")),
            "{message}"
        );
        // SAFETY: live handle, released once.
        unsafe { furbake_pack_release(pack) };
    }
}

#[test]
fn grass_views_are_the_blade_field_and_keyframe_table() {
    let path = packs().join("grass.fbk");
    let rust = Pack::open(&path).unwrap();
    let pack = open(&path);
    let (field, table) = (rust.blade_field().unwrap(), rust.keyframe_table().unwrap());
    let mut f: FurbakeBladeFieldView = sized();
    let mut k: FurbakeKeyframeTableView = sized();
    // SAFETY: live handle, sized views.
    unsafe {
        assert_eq!(furbake_pack_blade_field(pack, &mut f), FurbakeResult::Ok);
        assert_eq!(furbake_pack_keyframe_table(pack, &mut k), FurbakeResult::Ok);
    }
    assert_eq!(f.blade_count as usize, field.positions.len());
    assert_eq!((f.grid_cells_x, f.grid_cells_z), (field.grid.cells_x, field.grid.cells_z));
    // SAFETY: the view's arrays hold the counts it states.
    unsafe {
        assert_eq!(floats(f.positions, 3 * f.blade_count as usize), field.positions.as_flattened());
        assert_eq!(floats(f.weights, 4 * f.blade_count as usize), field.weights.as_flattened());
    }
    assert_eq!((k.segments, k.vertex_count as usize), (table.segments, table.reference_positions.len()));
    assert_eq!(k.displacement_encoding, 1, "snorm16 by default");
    assert_eq!(k.displacement_count as usize, table.displacements.len());
    // SAFETY: live handle, released once.
    unsafe { furbake_pack_release(pack) };
}

#[test]
fn a_view_declares_its_size_so_the_struct_can_grow() {
    let pack = open(&packs().join("fox.fbk"));
    // Too small (a caller that did not set `size`): refused, naming the field.
    let mut info: FurbakePackInfo = sized();
    info.size = 4;
    // SAFETY: live handle; the view is writable.
    assert_eq!(unsafe { furbake_pack_info(pack, &mut info) }, FurbakeResult::InvalidArgument);
    assert!(last_error().contains("info.size is 4"), "{}", last_error());
    // A caller built against a later header (a longer struct): the fields this library knows are
    // written, the rest left alone.
    #[repr(C)]
    struct Later {
        info: FurbakePackInfo,
        later_field: u64,
    }
    let mut later = Later { info: sized(), later_field: 0xDEAD_BEEF };
    later.info.size = std::mem::size_of::<Later>() as u32;
    // SAFETY: `Later` begins with the library's struct and is larger.
    assert_eq!(unsafe { furbake_pack_info(pack, &mut later.info) }, FurbakeResult::Ok);
    assert_eq!(later.info.size as usize, std::mem::size_of::<Later>(), "size is the caller's");
    assert_eq!(later.later_field, 0xDEAD_BEEF);
    assert!(later.info.vertex_count > 0);
    // SAFETY: live handle, released once.
    unsafe { furbake_pack_release(pack) };
}

#[test]
fn bad_packs_and_arguments_get_codes_and_messages_naming_the_problem() {
    let mut pack = null_mut();
    let missing = c("/nonexistent/dir/fox.fbk");
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_pack_open_file(missing.as_ptr(), &mut pack) }, FurbakeResult::Io);
    assert!(last_error().contains("/nonexistent/dir/fox.fbk"), "{}", last_error());
    assert!(pack.is_null(), "nothing stored on failure");

    let mut bytes = std::fs::read(packs().join("fox.fbk")).unwrap();
    let n = bytes.len();
    bytes[n / 2] ^= 0x55; // inside some section: its checksum fails
    let name = c("fox-in-archive");
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_pack_open_memory(bytes.as_ptr(), n, name.as_ptr(), &mut pack) }, FurbakeResult::Format);
    assert!(last_error().starts_with("fox-in-archive: "), "{}", last_error());
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_pack_open_memory(b"nonsense".as_ptr(), 8, null(), &mut pack) }, FurbakeResult::Format);

    // SAFETY: null pointers are what is tested.
    unsafe {
        assert_eq!(furbake_pack_open_file(null(), &mut pack), FurbakeResult::InvalidArgument);
        assert!(last_error().contains("path is a null pointer"));
        assert_eq!(furbake_pack_open_file(missing.as_ptr(), null_mut()), FurbakeResult::InvalidArgument);
        assert_eq!(furbake_pack_open_memory(null(), 10, null(), &mut pack), FurbakeResult::InvalidArgument);
        let mut info: FurbakePackInfo = sized();
        assert_eq!(furbake_pack_info(null(), &mut info), FurbakeResult::InvalidArgument);
        furbake_pack_release(null_mut());
        furbake_world_release(null_mut());
        furbake_animator_release(null_mut());
    }
    let bad_utf8 = [0xFFu8, 0xFE, 0];
    // SAFETY: NUL-terminated bytes.
    assert_eq!(unsafe { furbake_pack_open_file(bad_utf8.as_ptr().cast(), &mut pack) }, FurbakeResult::InvalidArgument);
    assert!(last_error().contains("not UTF-8"));
}

/// The demo's settings without packs: gravity, wind, the guard.
const SETTINGS: &str = "time_step_s = 0.01\n[effects.gravity]\n[effects.wind]\nvelocity_m_per_s = [1.5, 0.0, 0.5]\ngust_amplitude = 0.3\n[effects.wrong_side_guard]\n";

fn world(settings: &str, flags: u32) -> *mut FurbakeWorld {
    let mut desc: FurbakeWorldDesc = sized();
    let (text, name) = (c(settings), c("settings.toml"));
    (desc.flags, desc.settings_toml, desc.settings_name) = (flags, text.as_ptr(), name.as_ptr());
    let mut world = null_mut();
    // SAFETY: valid descriptor.
    assert_eq!(unsafe { furbake_world_create(&desc, &mut world) }, FurbakeResult::Ok, "{}", last_error());
    world
}

fn add(
    world: *mut FurbakeWorld,
    pack: *mut FurbakePack,
    name: &str,
    animation: u32,
    clip: Option<&str>,
    speed: f32,
) -> u32 {
    let mut entry: FurbakeEntryDesc = sized();
    let (name, clip) = (c(name), clip.map(c));
    entry.name = name.as_ptr();
    entry.animation = animation;
    entry.clip = clip.as_ref().map_or(null(), |c| c.as_ptr());
    (entry.speed, entry.looping, entry.scale) = (speed, 1, 0.01);
    let mut index = u32::MAX;
    // SAFETY: live handles, valid descriptor.
    assert_eq!(
        unsafe { furbake_world_add_pack(world, pack, &entry, &mut index) },
        FurbakeResult::Ok,
        "{}",
        last_error()
    );
    index
}

fn step(world: *mut FurbakeWorld) {
    // SAFETY: live handle.
    assert_eq!(unsafe { furbake_world_step(world) }, FurbakeResult::Ok, "{}", last_error());
}

fn fur(world: *mut FurbakeWorld, index: u32) -> Vec<u32> {
    let mut frame: FurbakeFurFrame = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_world_fur_frame(world, index, &mut frame) }, FurbakeResult::Ok, "{}", last_error());
    // SAFETY: the frame's array holds `count × 3` floats until the next step.
    unsafe { floats(frame.scale_vectors, 3 * frame.count as usize) }.iter().map(|v| v.to_bits()).collect()
}

fn pose(world: *mut FurbakeWorld, index: u32) -> (Vec<f32>, Vec<u32>) {
    let mut p: FurbakeSkinPose = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_world_skin_pose(world, index, &mut p) }, FurbakeResult::Ok, "{}", last_error());
    // SAFETY: the view's arrays hold the counts it states until the next step.
    unsafe {
        let joints = floats(p.joint_matrices, 16 * p.joint_count as usize).to_vec();
        let skin = floats(p.positions, 3 * p.vertex_count as usize).iter().map(|v| v.to_bits()).collect();
        (joints, skin)
    }
}

/// A world built through the C interface steps exactly as the Rust runtime's world of the same
/// scene; an entry posed by the host with the clip entry's own joint matrices has its fur and
/// skin bit for bit (the clip held still, as `animated::host_joint_matrices_…` in the runtime).
#[test]
fn a_c_world_steps_as_the_runtime_and_host_poses_match_the_clips() {
    let pack = open(&packs().join("fox.fbk"));
    let (w, puppet) = (world(SETTINGS, 0), world(SETTINGS, 0));
    assert_eq!(add(w, pack, "walker", FURBAKE_ANIMATION_CLIP, Some("Walk"), 1.0), 0);
    assert_eq!(add(puppet, pack, "puppet", FURBAKE_ANIMATION_CLIP, Some("Walk"), 0.0), 0);
    // SAFETY: the worlds hold their own references to the pack.
    unsafe { furbake_pack_release(pack) };

    let text = format!(
        "{SETTINGS}[[packs]]\nname = \"walker\"\npath = \"fox.fbk\"\nscale = 0.01\nanimation = {{ clip = \"Walk\" }}\n"
    );
    let scene = Scene::from_toml_str(&text, Path::new("t.toml"), packs()).unwrap();
    let mut rust = World::with_options(scene, WorldOptions { host_placement: true, ..Default::default() }).unwrap();
    let rust_bits =
        |r: &World| r.fur(0).unwrap().scale_vectors.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();

    for k in 0..30 {
        step(w);
        rust.step().unwrap();
        assert_eq!(fur(w, 0), rust_bits(&rust), "step {k}: the C world's walker is the runtime's");
        let (joints, skin) = pose(w, 0);
        // SAFETY: live handle; 16 floats per joint.
        let r = unsafe {
            furbake_world_set_joint_matrices(puppet, 0, joints.as_ptr(), (joints.len() / 16) as u32, null(), 0)
        };
        assert_eq!(r, FurbakeResult::Ok, "{}", last_error());
        step(puppet);
        assert_eq!(fur(puppet, 0), fur(w, 0), "step {k}: the host-posed fur");
        assert_eq!(pose(puppet, 0).1, skin, "step {k}: the host-posed skin");
    }
    let mut info: FurbakeWorldInfo = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_world_info(w, &mut info) }, FurbakeResult::Ok);
    assert_eq!((info.pack_count, info.steps, info.time_step_s), (1, 30, 0.01));
    // SAFETY: live handles, released once.
    unsafe {
        furbake_world_release(w);
        furbake_world_release(puppet);
    }
}

/// The animator samples a clip as the world plays it (to f32 rounding of the clip time).
#[test]
fn the_animator_samples_the_clip_the_world_plays() {
    let pack = open(&packs().join("fox.fbk"));
    let w = world(SETTINGS, 0);
    add(w, pack, "walker", FURBAKE_ANIMATION_CLIP, Some("Walk"), 1.0);
    let mut animator = null_mut();
    let walk = c("Walk");
    // SAFETY: live handle, valid arguments.
    assert_eq!(
        unsafe { furbake_animator_create(pack, walk.as_ptr(), &mut animator) },
        FurbakeResult::Ok,
        "{}",
        last_error()
    );
    for k in 1..=20 {
        step(w);
        let (world_joints, _) = pose(w, 0);
        let mut p: FurbakeSkinPose = sized();
        // SAFETY: live handle, sized view.
        assert_eq!(
            unsafe { furbake_animator_pose(animator, k as f64 * 0.01, &mut p) },
            FurbakeResult::Ok,
            "{}",
            last_error()
        );
        // SAFETY: as the view states.
        let sampled = unsafe { floats(p.joint_matrices, 16 * p.joint_count as usize) };
        let worst = sampled.iter().zip(&world_joints).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-3, "step {k}: the sampled Walk is {worst} off the world's");
    }
    let nope = c("Moonwalk");
    let mut other = null_mut();
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_animator_create(pack, nope.as_ptr(), &mut other) }, FurbakeResult::InvalidArgument);
    assert!(last_error().contains("Moonwalk"), "{}", last_error());
    // SAFETY: live handles, released once.
    unsafe {
        furbake_animator_release(animator);
        furbake_world_release(w);
        furbake_pack_release(pack);
    }
}

#[test]
fn a_world_whose_physics_asks_for_the_gpu_is_refused() {
    // The C interface steps fur on the CPU: `[solver] device = "gpu"` is a scene error naming the
    // pack, at the step that builds the world.
    let pack = open(&packs().join("plane.fbk"));
    let w = world(&format!("{SETTINGS}[solver]\nkind = \"xpbd\"\ndevice = \"gpu\"\n"), 0);
    add(w, pack, "plane", FURBAKE_ANIMATION_NONE, None, 1.0);
    // SAFETY: live handle.
    assert_eq!(unsafe { furbake_world_step(w) }, FurbakeResult::Scene);
    assert!(last_error().contains("\"plane\"") && last_error().contains("device = \"cpu\""), "{}", last_error());
    // SAFETY: live handles, released once.
    unsafe {
        furbake_world_release(w);
        furbake_pack_release(pack);
    }
}

#[test]
fn refused_world_calls_change_nothing_and_say_why() {
    let pack = open(&packs().join("fox.fbk"));
    // Settings that are not a scene: the key is named.
    let mut desc: FurbakeWorldDesc = sized();
    let (bad, name) = (c("time_step_s = \"fast\"\n"), c("game/fur.toml"));
    (desc.settings_toml, desc.settings_name) = (bad.as_ptr(), name.as_ptr());
    let mut w = null_mut();
    // SAFETY: valid descriptor.
    assert_eq!(unsafe { furbake_world_create(&desc, &mut w) }, FurbakeResult::Scene);
    assert!(last_error().contains("game/fur.toml") && last_error().contains("time_step_s"), "{}", last_error());

    let w = world(SETTINGS, FURBAKE_WORLD_STEP_STATISTICS);
    // Stepping an empty world: a state error.
    // SAFETY: live handle.
    assert_eq!(unsafe { furbake_world_step(w) }, FurbakeResult::State);
    // SAFETY: live handle.
    unsafe { furbake_world_release(w) };

    let w = world(SETTINGS, 0);
    add(w, pack, "fox", FURBAKE_ANIMATION_HOST, None, 1.0);
    // Effects that are not a table of effects.
    for (text, key) in
        [("[effects.wind]\nvelocity_m_per_s = 3\n", "velocity_m_per_s"), ("time_step_s = 1\n", "time_step_s")]
    {
        let t = c(text);
        // SAFETY: live handle, NUL-terminated text.
        assert_eq!(unsafe { furbake_world_set_effects(w, t.as_ptr()) }, FurbakeResult::Scene, "{text}");
        assert!(last_error().contains(key), "{}", last_error());
    }
    step(w);
    let before = fur(w, 0);
    let (joints, _) = pose(w, 0);
    let n = (joints.len() / 16) as u32;
    let mut nan = joints.clone();
    nan[20] = f32::NAN;
    // SAFETY: live handle; the arrays hold the counts given.
    unsafe {
        assert_eq!(
            furbake_world_set_joint_matrices(w, 0, joints.as_ptr(), n - 1, null(), 0),
            FurbakeResult::InvalidArgument
        );
        assert!(last_error().contains("joint matrices"), "{}", last_error());
        assert_eq!(furbake_world_set_joint_matrices(w, 0, nan.as_ptr(), n, null(), 0), FurbakeResult::InvalidArgument);
        assert_eq!(
            furbake_world_set_joint_matrices(w, 7, joints.as_ptr(), n, null(), 0),
            FurbakeResult::InvalidArgument
        );
        assert!(last_error().contains("pack 7 of a world of 1"), "{}", last_error());
        let mut entry: FurbakeEntryDesc = sized();
        let second = c("second");
        (entry.name, entry.scale) = (second.as_ptr(), 1.0);
        assert_eq!(furbake_world_add_pack(w, pack, &entry, null_mut()), FurbakeResult::State);
        let calm = FurbakeWind {
            size: std::mem::size_of::<FurbakeWind>() as u32,
            velocity_m_per_s: [0.0; 3],
            gust_amplitude: 0.0,
            gust_frequency_hz: 0.5,
        };
        assert_eq!(furbake_world_set_wind(w, &calm), FurbakeResult::Ok, "{}", last_error());
        let bad = FurbakeWind { velocity_m_per_s: [f32::INFINITY, 0.0, 0.0], ..calm };
        assert_eq!(furbake_world_set_wind(w, &bad), FurbakeResult::InvalidArgument);
        let mut model = glam::Mat4::from_scale(glam::Vec3::new(1.0, 2.0, 1.0)).to_cols_array();
        assert_eq!(
            furbake_world_set_model_matrix(w, 0, model.as_ptr()),
            FurbakeResult::InvalidArgument,
            "non-uniform scale"
        );
        model = glam::Mat4::from_translation(glam::Vec3::X).to_cols_array();
        assert_eq!(furbake_world_set_model_matrix(w, 0, model.as_ptr()), FurbakeResult::Ok);
    }
    assert_eq!(fur(w, 0), before, "refused calls change nothing");
    step(w);
    let mut out = [0.0f32; 16];
    // SAFETY: live handle, 16 writable floats.
    assert_eq!(unsafe { furbake_world_model_matrix(w, 0, out.as_mut_ptr()) }, FurbakeResult::Ok);
    assert_eq!(out[12], 1.0, "the host's placement took");
    // A world of a scene file with no gravity declared refuses gravity.
    let mut grass_frame: FurbakeGrassFrame = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_world_grass_frame(w, 0, &mut grass_frame) }, FurbakeResult::Missing);
    // SAFETY: live handles, released once.
    unsafe {
        furbake_world_release(w);
        furbake_pack_release(pack);
    }
}

#[test]
fn a_scene_file_opens_as_a_world_with_grass_forces() {
    let dir = packs();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        "time_step_s = 0.02\n[[packs]]\nname = \"grass\"\npath = \"grass.fbk\"\n[effects.wind]\nvelocity_m_per_s = [3.0, 0.0, 0.0]\n",
    )
    .unwrap();
    let path = c(scene.to_str().unwrap());
    let mut w = null_mut();
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_world_open_scene(path.as_ptr(), 0, &mut w) }, FurbakeResult::Ok, "{}", last_error());
    step(w);
    let mut g: FurbakeGrassFrame = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_world_grass_frame(w, 0, &mut g) }, FurbakeResult::Ok);
    // SAFETY: as the view states.
    let forces = unsafe { floats(g.corner_forces, 2 * g.corner_count as usize) };
    assert!(g.corner_count > 0 && forces.iter().any(|&f| f > 0.0), "the wind pushes along +x");
    let gravity = [0.0f32, -3.0, 0.0];
    // SAFETY: live handle, 3 floats.
    assert_eq!(unsafe { furbake_world_set_gravity(w, gravity.as_ptr()) }, FurbakeResult::State);
    assert!(last_error().contains("no gravity"), "{}", last_error());
    // SAFETY: live handle, released once.
    unsafe { furbake_world_release(w) };
    let missing = c(dir.join("nope.toml").to_str().unwrap());
    let mut w = null_mut();
    // SAFETY: valid arguments.
    assert_eq!(unsafe { furbake_world_open_scene(missing.as_ptr(), 0, &mut w) }, FurbakeResult::Io);
    assert!(last_error().contains("nope.toml"), "{}", last_error());
}

#[test]
fn morph_targets_are_viewed_and_weighted_by_the_host() {
    let path = packs().join("strip.fbk");
    let rust = Pack::open(&path).unwrap();
    let morphs = rust.morph_targets().unwrap().unwrap();
    let pack = open(&path);
    let mut m: FurbakeMorphTargetsView = sized();
    // SAFETY: live handle, sized view.
    assert_eq!(unsafe { furbake_pack_morph_targets(pack, &mut m) }, FurbakeResult::Ok, "{}", last_error());
    assert_eq!((m.target_count as usize, m.vertex_count), (morphs.target_count(), morphs.vertex_count));
    assert!(!m.normal_deltas.is_null(), "the strip's target moves normals");
    // SAFETY: as the view states.
    let deltas = unsafe { floats(m.position_deltas, 3 * (m.target_count * m.vertex_count) as usize) };
    assert_eq!(deltas, morphs.position_deltas.as_flattened());
    // A host-posed strip at weight 0.5 moves its lifted row half way (+0.5 in z).
    let w = world("time_step_s = 0.01\n[effects.gravity]\n", 0);
    add(w, pack, "strip", FURBAKE_ANIMATION_HOST, None, 1.0);
    step(w);
    let (joints, rest) = pose(w, 0);
    let weight = [0.5f32];
    // SAFETY: live handle; the arrays hold the counts given.
    let r = unsafe {
        furbake_world_set_joint_matrices(w, 0, joints.as_ptr(), (joints.len() / 16) as u32, weight.as_ptr(), 1)
    };
    assert_eq!(r, FurbakeResult::Ok, "{}", last_error());
    step(w);
    let (_, posed) = pose(w, 0);
    let moved: Vec<f32> = posed.iter().zip(&rest).map(|(a, b)| f32::from_bits(*a) - f32::from_bits(*b)).collect();
    let lifted = moved.chunks(3).filter(|d| (d[2] - 0.005).abs() < 1e-6 || (d[2] - 0.5).abs() < 1e-5).count();
    assert!(lifted > 0, "some vertices rise by half the target's delta: {moved:?}");
    // SAFETY: live handles, released once.
    unsafe {
        furbake_world_release(w);
        furbake_pack_release(pack);
    }
}
