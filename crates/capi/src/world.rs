//! Worlds: packs placed in a scene, stepped by the host, posed by the host's animation system or
//! by their own clips; after each step, views of what the shaders read.

use std::ffi::c_char;
use std::path::Path;
use std::sync::Arc;

use furbake_runtime::{
    Effects, Pack, RuntimeError, Scene, SceneBuilder, ScenePack, ShellVertexLayout, World, WorldOptions, WorldPlan,
    scene::{PackAnimation, Wind},
};
use glam::Mat4;

use crate::error::{Error, FurbakeResult, guard, optional_text, out, slice, text};
use crate::pack::{FurbakePack, pack_ref};
use crate::views::{Zeroed, read_desc, write_view};

/// World flag: compute energy, its budget and the largest displacement every step (the
/// statistics in [`FurbakeFurFrame`]; costs a pass over the masses).
pub const FURBAKE_WORLD_STEP_STATISTICS: u32 = 1 << 0;

/// A pack entry without animation.
pub const FURBAKE_ANIMATION_NONE: u32 = 0;
/// A pack entry animated by its own clip player (`clip` names the clip).
pub const FURBAKE_ANIMATION_CLIP: u32 = 1;
/// A pack entry posed by the host (`furbake_world_set_joint_matrices`); it stands in its rest
/// pose until the first matrices arrive.
pub const FURBAKE_ANIMATION_HOST: u32 = 2;

/// How a world is made (`furbake_world_create`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeWorldDesc {
    /// `sizeof(FurbakeWorldDesc)`, set by the caller.
    pub size: u32,
    /// `FURBAKE_WORLD_*` bits.
    pub flags: u32,
    /// Simulation time step in seconds; 0 keeps the settings' (or the default 1/60 s).
    pub time_step_s: f32,
    /// Null, or a scene file's text without `[[packs]]` (NUL-terminated UTF-8): `time_step_s`,
    /// `[solver]`, `[effects]`, `[[events]]` as in README "Scenes" and
    /// docs/schemas/scene.schema.json. Packs are added with `furbake_world_add_pack`.
    pub settings_toml: *const c_char,
    /// Null, or a name for the settings in error messages (a file name, an asset id).
    pub settings_name: *const c_char,
}

/// One pack placed in a world (`furbake_world_add_pack`): the fields of a scene's `[[packs]]`
/// entry a host sets.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeEntryDesc {
    /// `sizeof(FurbakeEntryDesc)`, set by the caller.
    pub size: u32,
    /// `FURBAKE_ANIMATION_*`.
    pub animation: u32,
    /// The entry's name (unique in the world; NUL-terminated UTF-8).
    pub name: *const c_char,
    /// With `FURBAKE_ANIMATION_CLIP`: the clip to play.
    pub clip: *const c_char,
    /// With `FURBAKE_ANIMATION_CLIP`: playback speed (1 real time).
    pub speed: f32,
    /// With `FURBAKE_ANIMATION_CLIP`: nonzero to loop.
    pub looping: u32,
    /// With `FURBAKE_ANIMATION_CLIP`: where the clip starts, seconds.
    pub start_s: f32,
    /// Placement at the start: translation in metres.
    pub translation: [f32; 3],
    /// Placement at the start: rotation about X, then Y, then Z, degrees.
    pub rotation_deg: [f32; 3],
    /// Placement at the start: uniform scale (> 0).
    pub scale: f32,
}

/// Wind (`furbake_world_set_wind`): the scene's `[effects.wind]`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeWind {
    /// `sizeof(FurbakeWind)`, set by the caller.
    pub size: u32,
    /// Mean wind velocity, m/s, world frame.
    pub velocity_m_per_s: [f32; 3],
    /// Relative gust strength (0 steady).
    pub gust_amplitude: f32,
    /// Gust frequency, Hz.
    pub gust_frequency_hz: f32,
}

impl Zeroed for FurbakeWorldDesc {}
impl Zeroed for FurbakeEntryDesc {}
impl Zeroed for FurbakeWind {}

/// A world's clock and size (`furbake_world_info`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeWorldInfo {
    /// `sizeof(FurbakeWorldInfo)`, set by the caller.
    pub size: u32,
    /// Packs in the world.
    pub pack_count: u32,
    /// Steps taken.
    pub steps: u64,
    /// Scene time, seconds.
    pub time_s: f64,
    /// The time step, seconds.
    pub time_step_s: f32,
}

/// One pack's fur after the latest step: what the shell and fin shaders read.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeFurFrame {
    /// `sizeof(FurbakeFurFrame)`, set by the caller.
    pub size: u32,
    /// 0: one scale vector per skin vertex; 1: one per triangle corner (`3 × triangle + corner`,
    /// fur that can part).
    pub layout: u32,
    /// Scale vectors.
    pub count: u32,
    /// 1 when a solver moves this pack's fur, 0 when it stands at rest (`s = n`).
    pub simulated: u32,
    /// `count × 3` floats: the unit scale vectors (fur thesis eq. 3.35, after the wrong-side
    /// guard), mesh frame.
    pub scale_vectors: *const f32,
    /// Substeps of the latest solver step.
    pub substeps: u32,
    /// Wrong-side guard triggers in the latest step.
    pub guard_triggers: u32,
    /// Scale vectors the guard holds still.
    pub frozen_scale_vectors: u32,
    /// Largest mass displacement of the latest step, metres (with `FURBAKE_WORLD_STEP_STATISTICS`).
    pub max_displacement_m: f32,
}

/// One pack's grass forces after the latest step: what the blade shaders read.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeGrassFrame {
    /// `sizeof(FurbakeGrassFrame)`, set by the caller.
    pub size: u32,
    /// Cluster-grid corners (`(cells_x + 1) × (cells_z + 1)`).
    pub corner_count: u32,
    /// `corner_count × 2` floats: the force `(x, z)` at each corner, mesh frame.
    pub corner_forces: *const f32,
    /// 1 when wind sources with delayed attenuation act, which the corner forces leave out (a
    /// renderer evaluates them per blade).
    pub has_delayed_sources: u32,
}

/// An animated pack's pose after the latest step (or an animator's): the posed skin, and the
/// matrices a GPU skinning pass reads.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeSkinPose {
    /// `sizeof(FurbakeSkinPose)`, set by the caller.
    pub size: u32,
    /// Skin vertices.
    pub vertex_count: u32,
    /// `vertex_count × 3` floats: posed positions, mesh frame, metres.
    pub positions: *const f32,
    /// `vertex_count × 3` floats: posed unit normals.
    pub normals: *const f32,
    /// Skeleton joints.
    pub joint_count: u32,
    /// `joint_count × 16` floats, column-major: each joint's transform in the skinned mesh's
    /// frame (what `furbake_world_set_joint_matrices` takes).
    pub joint_matrices: *const f32,
    /// Palette entries.
    pub bind_count: u32,
    /// `bind_count × 16` floats, column-major: joint matrix × inverse bind.
    pub skinning_matrices: *const f32,
    /// Morph targets.
    pub morph_count: u32,
    /// `morph_count` weights.
    pub morph_weights: *const f32,
}

enum State {
    /// Packs are being added; the world is built by the first call that needs it.
    Adding {
        builder: Box<SceneBuilder>,
        packs: Vec<Arc<Pack>>,
        name: String,
    },
    Built(Box<World>),
    /// A step failed; the world is mid-step and refuses further use.
    Failed(String),
    /// Only while building.
    Empty,
}

/// A world (opaque): made by `furbake_world_create` or `furbake_world_open_scene`, freed by
/// `furbake_world_release`. Not thread-safe: one thread at a time (its steps use furbake's own
/// worker threads).
pub struct FurbakeWorld {
    state: State,
    options: WorldOptions,
    /// The host's joint matrices of the latest `furbake_world_set_joint_matrices`, reused.
    joints: Vec<Mat4>,
    /// Per pack, its fur's bounding sphere and length once `furbake_world_shell_level` has
    /// measured them (`crate::draw`): each frame's level of detail reuses them.
    pub(crate) fur_bounds: Vec<Option<crate::draw::FurBounds>>,
}

impl FurbakeWorld {
    fn built(&mut self) -> Result<&mut World, Error> {
        if let State::Adding { .. } = self.state {
            let State::Adding { builder, packs, name } = std::mem::replace(&mut self.state, State::Empty) else {
                unreachable!()
            };
            match build(builder, packs, self.options, &name) {
                Ok(world) => self.state = State::Built(Box::new(world)),
                Err(e) => {
                    self.state = State::Failed(e.message.clone());
                    return Err(e);
                }
            }
        }
        match &mut self.state {
            State::Built(world) => Ok(&mut **world),
            State::Failed(why) => {
                Err(Error::new(FurbakeResult::State, format!("the world failed earlier ({why}); release it")))
            }
            State::Adding { .. } | State::Empty => unreachable!("built above"),
        }
    }
}

impl FurbakeWorld {
    /// The built world and the checked index of its pack `index`.
    pub(crate) fn built_pack(&mut self, index: u32) -> Result<(&mut World, usize), Error> {
        let world = self.built()?;
        let count = world.pack_count();
        if index as usize >= count {
            return Err(Error::argument(format!("pack {index} of a world of {count}")));
        }
        Ok((world, index as usize))
    }
}

fn build(builder: Box<SceneBuilder>, packs: Vec<Arc<Pack>>, options: WorldOptions, name: &str) -> Result<World, Error> {
    if packs.is_empty() {
        return Err(Error::new(
            FurbakeResult::State,
            format!("{name}: the world has no packs (add them with furbake_world_add_pack)"),
        ));
    }
    let scene = (*builder).build().map_err(RuntimeError::from)?;
    cpu_physics_only(WorldPlan::with_packs(scene, packs, options)?.build()?, name)
}

/// `world`, unless a pack's fur physics runs on the GPU (`[solver] device = "gpu"`): the C
/// interface hands the host CPU-stepped scale vectors (`furbake_world_fur_frame`) and has no GPU
/// physics, so such a world is refused rather than left with fur that never moves.
fn cpu_physics_only(world: World, name: &str) -> Result<World, Error> {
    match (0..world.pack_count()).find(|&i| world.gpu_physics(i).is_some()) {
        Some(i) => Err(Error::new(
            FurbakeResult::Scene,
            format!(
                "{name}: pack {:?} asks for [solver] device = \"gpu\"; the C interface steps fur on the CPU \
                 (write device = \"cpu\")",
                world.scene().packs()[i].name
            ),
        )),
        None => Ok(world),
    }
}

pub(crate) fn world_mut<'a>(world: *mut FurbakeWorld) -> Result<&'a mut FurbakeWorld, Error> {
    // SAFETY: a non-null handle is one this library made and the caller has not released.
    unsafe { world.as_mut() }.ok_or_else(|| Error::argument("world is a null pointer"))
}

fn new_world(state: State, options: WorldOptions) -> *mut FurbakeWorld {
    Box::into_raw(Box::new(FurbakeWorld { state, options, joints: Vec::new(), fur_bounds: Vec::new() }))
}

fn options(flags: u32) -> Result<WorldOptions, Error> {
    if flags & !FURBAKE_WORLD_STEP_STATISTICS != 0 {
        return Err(Error::argument(format!("flags {flags:#x} has bits this library does not know")));
    }
    // The host places packs frame by frame (`furbake_world_set_model_matrix`).
    Ok(WorldOptions { step_statistics: flags & FURBAKE_WORLD_STEP_STATISTICS != 0, host_placement: true })
}

/// Makes an empty world from `*desc`; add packs with `furbake_world_add_pack`, then step.
///
/// # Safety
/// `desc` points to a descriptor whose `size` is set; `out_world` to storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_create(
    desc: *const FurbakeWorldDesc,
    out_world: *mut *mut FurbakeWorld,
) -> FurbakeResult {
    guard(|| {
        let desc = read_desc("desc", desc)?;
        let slot = out("out_world", out_world)?;
        let name = optional_text("desc.settings_name", desc.settings_name)?.unwrap_or("<world settings>").to_string();
        let mut builder = match optional_text("desc.settings_toml", desc.settings_toml)? {
            Some(toml) => SceneBuilder::from_toml_str(toml, Path::new(&name)).map_err(RuntimeError::from)?,
            None => Scene::builder(Vec::new()),
        };
        if !builder.packs().is_empty() {
            return Err(Error::new(
                FurbakeResult::Scene,
                format!("{name}: packs are added with furbake_world_add_pack, not in the settings"),
            ));
        }
        if desc.time_step_s != 0.0 {
            builder = builder.time_step_s(desc.time_step_s);
        }
        let options = options(desc.flags)?;
        *slot = new_world(State::Adding { builder: Box::new(builder), packs: Vec::new(), name }, options);
        Ok(())
    })
}

/// Opens the scene file at `path` (TOML, README "Scenes"), its packs (paths relative to the
/// file) and builds its world at once.
///
/// # Safety
/// `path` is NUL-terminated; `out_world` points to storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_open_scene(
    path: *const c_char,
    flags: u32,
    out_world: *mut *mut FurbakeWorld,
) -> FurbakeResult {
    guard(|| {
        let path = text("path", path)?;
        let slot = out("out_world", out_world)?;
        let options = options(flags)?;
        let scene = Scene::load(path).map_err(RuntimeError::from)?;
        let plan = WorldPlan::new(scene, options)?;
        for pack in plan.packs() {
            pack.verify()?;
        }
        *slot = new_world(State::Built(Box::new(cpu_physics_only(plan.build()?, path)?)), options);
        Ok(())
    })
}

/// Frees a world (null is ignored). Its views become invalid.
///
/// # Safety
/// `world` is null or a handle from this library, not used again.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_release(world: *mut FurbakeWorld) {
    if !world.is_null() {
        // SAFETY: a handle made by `Box::into_raw` in this module, released once.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| drop(unsafe { Box::from_raw(world) })));
    }
}

/// Adds `pack` to the world as `*entry` says and stores its index in `*out_index` (may be
/// null). Only before the world's first step or first `set_*` call (which build it).
///
/// # Safety
/// `world` and `pack` are live handles; `entry` points to a descriptor whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_add_pack(
    world: *mut FurbakeWorld,
    pack: *const FurbakePack,
    entry: *const FurbakeEntryDesc,
    out_index: *mut u32,
) -> FurbakeResult {
    guard(|| {
        let w = world_mut(world)?;
        let pack = pack_ref("pack", pack)?.pack.clone();
        let e = read_desc("entry", entry)?;
        let State::Adding { builder, packs, .. } = &mut w.state else {
            return Err(Error::new(
                FurbakeResult::State,
                "packs are added before the world's first step or set_* call",
            ));
        };
        let name = text("entry.name", e.name)?;
        let mut sp = ScenePack::new(name, pack.display_path());
        (sp.translation, sp.rotation_deg, sp.scale) = (e.translation, e.rotation_deg, e.scale);
        sp.animation = match e.animation {
            FURBAKE_ANIMATION_NONE => None,
            FURBAKE_ANIMATION_HOST => Some(PackAnimation::posed_by_host()),
            FURBAKE_ANIMATION_CLIP => {
                let mut a = PackAnimation::new(text("entry.clip", e.clip)?);
                (a.speed, a.looping, a.start_s) = (e.speed, e.looping != 0, e.start_s);
                Some(a)
            }
            other => return Err(Error::argument(format!("entry.animation is {other}; expected 0, 1 or 2"))),
        };
        let index = packs.len() as u32;
        **builder = std::mem::replace(&mut **builder, Scene::builder(Vec::new())).pack(sp);
        packs.push(pack);
        if !out_index.is_null() {
            // SAFETY: checked non-null; the caller passes writable storage.
            unsafe { *out_index = index };
        }
        Ok(())
    })
}

/// Advances the world by one time step: applies due events, poses animated skins (from their
/// clips or the host's matrices), moves the fur and the grass forces. Builds the world first if
/// packs were just added.
///
/// # Safety
/// `world` is a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_step(world: *mut FurbakeWorld) -> FurbakeResult {
    guard(|| {
        let w = world_mut(world)?;
        let result = w.built()?.step();
        if let Err(e) = result {
            let e = Error::from(e);
            w.state = State::Failed(e.message.clone());
            return Err(e);
        }
        Ok(())
    })
}

/// Fills `*info` with the world's clock and pack count (builds the world if packs were just added).
///
/// # Safety
/// `world` is a live handle; `info` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_info(world: *mut FurbakeWorld, info: *mut FurbakeWorldInfo) -> FurbakeResult {
    guard(|| {
        let w = world_mut(world)?.built()?;
        let value = FurbakeWorldInfo {
            size: 0,
            pack_count: w.pack_count() as u32,
            steps: w.steps(),
            time_s: w.time_s(),
            time_step_s: w.scene().time_step_s(),
        };
        write_view("info", info, value)
    })
}

/// Stores the index of the entry named `name` in `*out_index`.
///
/// # Safety
/// `world` is a live handle; `name` is NUL-terminated; `out_index` points to storage.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_pack_index(
    world: *mut FurbakeWorld,
    name: *const c_char,
    out_index: *mut u32,
) -> FurbakeResult {
    guard(|| {
        let w = world_mut(world)?.built()?;
        let name = text("name", name)?;
        let slot = out("out_index", out_index)?;
        let index =
            w.pack_index(name).ok_or_else(|| Error::argument(format!("the world has no pack named {name:?}")))?;
        *slot = index as u32;
        Ok(())
    })
}

/// Places pack `index` at `model` (16 floats, column-major: rotation, translation and a positive
/// uniform scale, world metres) for the end of the next step — a game's transform update; the
/// fur feels the motion between placements when the settings declare `[effects.object_motion]`.
///
/// # Safety
/// `world` is a live handle; `model` points to 16 floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_set_model_matrix(
    world: *mut FurbakeWorld,
    index: u32,
    model: *const f32,
) -> FurbakeResult {
    guard(|| {
        let m = slice("model", model, 16)?;
        let (w, i) = world_mut(world)?.built_pack(index)?;
        Ok(w.set_model_matrix(i, Mat4::from_cols_slice(m))?)
    })
}

/// Stores pack `index`'s model matrix (16 floats, column-major) in `out_model`.
///
/// # Safety
/// `world` is a live handle; `out_model` points to 16 writable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_model_matrix(
    world: *mut FurbakeWorld,
    index: u32,
    out_model: *mut f32,
) -> FurbakeResult {
    guard(|| {
        let (w, i) = world_mut(world)?.built_pack(index)?;
        if out_model.is_null() {
            return Err(Error::argument("out_model is a null pointer"));
        }
        let cols = w.model_matrix(i).to_cols_array();
        // SAFETY: the caller passes 16 writable floats.
        unsafe { std::ptr::copy_nonoverlapping(cols.as_ptr(), out_model, 16) };
        Ok(())
    })
}

/// Poses animated pack `index` from the host's animation system from the next step on:
/// `joint_count` matrices at `joint_matrices` (16 floats each, column-major; one per skeleton
/// joint in the pack's joint order, each the joint's transform in the skinned mesh's frame —
/// glTF: the joint node's global transform with the mesh node's taken out) and `morph_count`
/// weights. The same matrices give the same skin and fur as the pack's own clips would. Refused
/// (changing nothing) on a wrong count or a non-finite value. Allocates nothing after the first
/// call.
///
/// # Safety
/// `world` is a live handle; the arrays hold the counts given.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_set_joint_matrices(
    world: *mut FurbakeWorld,
    index: u32,
    joint_matrices: *const f32,
    joint_count: u32,
    morph_weights: *const f32,
    morph_count: u32,
) -> FurbakeResult {
    guard(|| {
        let fw = world_mut(world)?;
        let floats = slice("joint_matrices", joint_matrices, joint_count as usize * 16)?;
        let weights = slice("morph_weights", morph_weights, morph_count as usize)?;
        let mut joints = std::mem::take(&mut fw.joints);
        joints.clear();
        joints.extend(floats.chunks_exact(16).map(Mat4::from_cols_slice));
        let result = (|| {
            let (w, i) = fw.built_pack(index)?;
            let path = w.pack(i).display_path();
            let anim = w
                .animation_mut(i)
                .ok_or_else(|| Error::argument(format!("{}: pack {index} is not animated", path.display())))?;
            anim.set_joint_matrices(&joints, weights)
                .map_err(|source| Error::from(RuntimeError::Animation { path, source }))
        })();
        fw.joints = joints;
        result
    })
}

/// Hands animated pack `index` back to its own clip player after `furbake_world_set_joint_matrices`.
///
/// # Safety
/// `world` is a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_resume_clips(world: *mut FurbakeWorld, index: u32) -> FurbakeResult {
    guard(|| {
        let (w, i) = world_mut(world)?.built_pack(index)?;
        w.animation_mut(i).ok_or_else(|| Error::argument(format!("pack {index} is not animated")))?.resume_clips();
        Ok(())
    })
}

/// Replaces the world's effects with those of `effects_toml`: scene TOML holding only an
/// `[effects]` table (e.g. `[effects.wind]\nvelocity_m_per_s = [2, 0, 0]`). Before the world is
/// built this declares them; afterwards it may change their values, not which are declared
/// (declare an effect at zero strength to drive it later). Refused, changing nothing, when
/// invalid; the message names the key.
///
/// # Safety
/// `world` is a live handle; `effects_toml` is NUL-terminated.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_set_effects(
    world: *mut FurbakeWorld,
    effects_toml: *const c_char,
) -> FurbakeResult {
    guard(|| {
        let w = world_mut(world)?;
        let toml = text("effects_toml", effects_toml)?;
        let effects = parse_effects(toml)?;
        match &mut w.state {
            State::Adding { builder, .. } => {
                **builder = std::mem::replace(&mut **builder, Scene::builder(Vec::new())).effects(effects);
                Ok(())
            }
            _ => Ok(w.built()?.update_effects(|e| *e = effects)?),
        }
    })
}

fn parse_effects(text: &str) -> Result<Effects, Error> {
    // Anything beside `[effects]` would be dropped without a word: refuse it.
    if let Ok(table) = toml::from_str::<toml::Table>(text)
        && let Some(key) = table.keys().find(|k| *k != "effects")
    {
        return Err(Error::new(
            FurbakeResult::Scene,
            format!("<effects>: {key}: the text may hold only an [effects] table"),
        ));
    }
    let scene = SceneBuilder::from_toml_str(text, Path::new("<effects>"))
        .and_then(|b| b.pack(ScenePack::new("effects", "effects")).build())
        .map_err(RuntimeError::from)?;
    Ok(scene.effects().clone())
}

/// Sets the wind (`[effects.wind]`, which the world must declare) for the next steps.
///
/// # Safety
/// `world` is a live handle; `wind` points to a descriptor whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_set_wind(world: *mut FurbakeWorld, wind: *const FurbakeWind) -> FurbakeResult {
    guard(|| {
        let d = read_desc("wind", wind)?;
        let w = world_mut(world)?.built()?;
        if w.effects().wind.is_none() {
            return Err(Error::new(
                FurbakeResult::State,
                "the world declares no wind ([effects.wind] in its settings)",
            ));
        }
        let wind = Wind {
            velocity_m_per_s: d.velocity_m_per_s,
            gust_amplitude: d.gust_amplitude,
            gust_frequency_hz: d.gust_frequency_hz,
        };
        Ok(w.update_effects(|e| e.wind = Some(wind))?)
    })
}

/// Sets gravity (`[effects.gravity]`, which the world must declare): 3 floats, m/s².
///
/// # Safety
/// `world` is a live handle; `acceleration` points to 3 floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_set_gravity(
    world: *mut FurbakeWorld,
    acceleration: *const f32,
) -> FurbakeResult {
    guard(|| {
        let a = slice("acceleration", acceleration, 3)?;
        let w = world_mut(world)?.built()?;
        let Some(mut gravity) = w.effects().gravity else {
            return Err(Error::new(
                FurbakeResult::State,
                "the world declares no gravity ([effects.gravity] in its settings)",
            ));
        };
        gravity.acceleration_m_per_s2 = [a[0], a[1], a[2]];
        Ok(w.update_effects(|e| e.gravity = Some(gravity))?)
    })
}

/// Fills `*frame` with pack `index`'s fur after the latest step. Missing when the pack has no fur.
///
/// # Safety
/// `world` is a live handle; `frame` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_fur_frame(
    world: *mut FurbakeWorld,
    index: u32,
    frame: *mut FurbakeFurFrame,
) -> FurbakeResult {
    guard(|| {
        let (w, i) = world_mut(world)?.built_pack(index)?;
        let fur = w.fur(i).ok_or_else(|| {
            Error::new(FurbakeResult::Missing, format!("{}: the pack has no fur", w.pack(i).display_path().display()))
        })?;
        let value = FurbakeFurFrame {
            size: 0,
            layout: match fur.layout {
                ShellVertexLayout::PerVertex => 0,
                ShellVertexLayout::PerCorner => 1,
            },
            count: fur.scale_vectors.len() as u32,
            simulated: u32::from(fur.simulation.is_some()),
            scale_vectors: fur.scale_vectors.as_ptr().cast(),
            substeps: fur.last_step.substeps,
            guard_triggers: fur.last_step.guard_triggers,
            frozen_scale_vectors: fur.last_step.frozen_scale_vectors,
            max_displacement_m: fur.last_step.max_displacement_m,
        };
        write_view("frame", frame, value)
    })
}

/// Fills `*frame` with pack `index`'s grass forces after the latest step. Missing when the pack
/// has no blades.
///
/// # Safety
/// `world` is a live handle; `frame` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_grass_frame(
    world: *mut FurbakeWorld,
    index: u32,
    frame: *mut FurbakeGrassFrame,
) -> FurbakeResult {
    guard(|| {
        let (w, i) = world_mut(world)?.built_pack(index)?;
        let grass = w.grass(i).ok_or_else(|| {
            Error::new(
                FurbakeResult::Missing,
                format!("{}: the pack has no grass blades", w.pack(i).display_path().display()),
            )
        })?;
        let value = FurbakeGrassFrame {
            size: 0,
            corner_count: grass.corner_forces.len() as u32,
            corner_forces: grass.corner_forces.as_ptr().cast(),
            has_delayed_sources: u32::from(grass.has_delayed_sources()),
        };
        write_view("frame", frame, value)
    })
}

/// Fills `*pose` with animated pack `index`'s pose after the latest step. Missing when the pack
/// entry is not animated.
///
/// # Safety
/// `world` is a live handle; `pose` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_skin_pose(
    world: *mut FurbakeWorld,
    index: u32,
    pose: *mut FurbakeSkinPose,
) -> FurbakeResult {
    guard(|| {
        let (w, i) = world_mut(world)?.built_pack(index)?;
        let a = w.animation(i).ok_or_else(|| {
            Error::new(
                FurbakeResult::Missing,
                format!("{}: the pack entry is not animated", w.pack(i).display_path().display()),
            )
        })?;
        write_view("pose", pose, crate::animator::skin_pose(a))
    })
}
