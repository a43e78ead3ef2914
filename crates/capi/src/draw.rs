//! What a host's own renderer uploads to draw a pack with the shaders `furbake shaders` exports,
//! as furbake's renderer does (`furbake_draw`): the skin's triangle corners with their shell
//! UVs, the fin quads, the interior edges the silhouette fin selection reads, every mip level of
//! the shell and fin atlases, the shells' stacking exponents, the `Fur` uniform block for a
//! look, and the shell level of detail of a view. Each is built on first request and kept with
//! the pack (valid while it lives); their layouts are `furbake_draw::layout`'s, the structs the
//! manifest of `furbake shaders` lays out.

use std::ffi::c_void;
use std::sync::OnceLock;

use furbake_draw::layout::{FinVertex, FurUniforms, SilhouetteEdge, SurfaceVertex};
use furbake_draw::lod::{ShellLevel, ShellLod};
use furbake_draw::{FurLook, FurShading, geometry, mips, stacking};
use furbake_formats::SectionKind;
use glam::{Mat4, Vec3};

use crate::error::{Error, FurbakeResult, guard};
use crate::pack::{FurbakePack, missing, pack_ref};
use crate::views::{Zeroed, read_desc, write_grown_view, write_view};
use crate::world::{FurbakeWorld, world_mut};

/// A pack's draw data, each part built on its first request.
#[derive(Default)]
pub(crate) struct DrawCache {
    surface: OnceLock<(Vec<SurfaceVertex>, u32)>,
    fin_quads: OnceLock<Vec<FinVertex>>,
    silhouette_edges: OnceLock<Vec<SilhouetteEdge>>,
    /// Per atlas (shell, fin): every mip level, all layers of a level together.
    levels: [OnceLock<Vec<AtlasLevel>>; 2],
    stacking: OnceLock<Vec<f32>>,
}

struct AtlasLevel {
    width: u32,
    height: u32,
    texels: Vec<u8>,
}

/// `furbake_pack_atlas_level`'s atlas: the shell atlas (a 2D array texture, one layer per shell).
pub const FURBAKE_ATLAS_SHELL: u32 = 0;
/// `furbake_pack_atlas_level`'s atlas: the fin atlas (one 2D texture).
pub const FURBAKE_ATLAS_FIN: u32 = 1;

/// The skin's triangle corners as the skin and shell vertex stages read them (vertex buffer 0:
/// the manifest's `vertex_inputs` of `vs_skin` and `vs_shell`), furry triangles first.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeSurfaceView {
    /// `sizeof(FurbakeSurfaceView)`, set by the caller.
    pub size: u32,
    /// Corners: 3 per skin triangle. The skin draws them all.
    pub vertex_count: u32,
    /// The furry triangles' corners, the first of `vertices`: what the shells draw, instanced once
    /// per shell layer.
    pub furry_vertex_count: u32,
    /// Bytes per corner (60): position (3 floats), normal (3), colour (4), shell UV (2), welded
    /// vertex index (uint), flags (uint; bit 0 furry), corner id `3 × triangle + corner` (uint).
    pub stride: u32,
    /// `vertex_count × stride` bytes.
    pub vertices: *const c_void,
}

/// An array of fixed-size records (fin quad corners, silhouette edges).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeArrayView {
    /// `sizeof(FurbakeArrayView)`, set by the caller.
    pub size: u32,
    /// Records.
    pub count: u32,
    /// Bytes per record.
    pub stride: u32,
    /// `count × stride` bytes (null when `count` is 0).
    pub data: *const c_void,
}

/// One mip level of an atlas, box-filtered from the level above as furbake's renderer and its
/// stacking table see it (`furbake_draw::mips`).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeAtlasLevelView {
    /// `sizeof(FurbakeAtlasLevelView)`, set by the caller.
    pub size: u32,
    /// Levels of the atlas's chain, level 0 the atlas itself, down to 1×1.
    pub level_count: u32,
    /// This level's width and height, texels.
    pub width: u32,
    /// Height, texels.
    pub height: u32,
    /// Layers (the shells' count; 1 for the fin atlas).
    pub layers: u32,
    /// `layers × width × height` bytes of alpha (R8 unorm), layer-major, rows top to bottom.
    pub texels: *const u8,
}

/// The shells' stacking exponents (docs/design.md "Shell opacity"), the storage buffer the
/// shell fragment stage reads when the look blends with stacking correction.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeStackingTableView {
    /// `sizeof(FurbakeStackingTableView)`, set by the caller.
    pub size: u32,
    /// View-angle bins (0° to 80° between the view ray and the hair).
    pub angle_bins: u32,
    /// Mip-level bins.
    pub mip_bins: u32,
    /// Drawn-layer-count bins (1, 2, 4, …).
    pub count_bins: u32,
    /// `angle_bins × mip_bins × count_bins` floats, `[(angle · mip_bins + mip) · count_bins +
    /// count]`.
    pub exponents: *const f32,
}

/// How fur is drawn, as far as the `Fur` uniform block carries it: what an engine's fur
/// material holds. `furbake_fur_look_default` fills furbake's defaults (what `furbake preview`
/// draws); docs/design.md "Fur shading" gives each parameter's meaning and range.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeFurLook {
    /// `sizeof(FurbakeFurLook)`, set by the caller.
    pub size: u32,
    /// Linear RGB multiplier of the vertex colours.
    pub tint: [f32; 3],
    /// Exponent k of the shell shearing (eq. 3.36).
    pub shear_exponent: f32,
    /// Fragments with alpha at or below this are discarded, in [0, 1).
    pub alpha_threshold: f32,
    /// 1: blend each shell with the stacking exponents; 0: with its alpha as it is.
    pub stacking_correction: u32,
    /// Share of Kajiya–Kay's diffuse term, in [0, 1].
    pub kajiya_kay_diffuse: f32,
    /// Primary highlight: strength, exponent, shift.
    pub primary_strength: f32,
    /// Primary exponent.
    pub primary_exponent: f32,
    /// Primary shift.
    pub primary_shift: f32,
    /// Secondary highlight: strength, exponent, shift, tint, noise depth.
    pub secondary_strength: f32,
    /// Secondary exponent.
    pub secondary_exponent: f32,
    /// Secondary shift.
    pub secondary_shift: f32,
    /// Secondary tint (RGB).
    pub secondary_tint: [f32; 3],
    /// Secondary noise depth.
    pub secondary_noise: f32,
    /// Back-light (transmission) strength.
    pub back_light: f32,
    /// Ambient occlusion at the roots.
    pub root_occlusion: f32,
    /// Colour multiplier at the tips (RGB).
    pub tip_color: [f32; 3],
    /// The anisotropy clamp of the host's shell and fin atlas samplers, in [1, 16] (1 for the
    /// alpha test, which reads level 0; furbake's default 16 for blended fur); the shell shader
    /// picks the mip level of its stacking exponents as such a sampler does. 0, or a struct from
    /// before this field (a smaller `size`), means 16.
    pub anisotropy: f32,
}

/// A host's view, for the shell level of detail.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeCamera {
    /// `sizeof(FurbakeCamera)`, set by the caller.
    pub size: u32,
    /// World → clip, column-major, depth in [0, 1] (the `Frame` block's `view_proj`).
    pub view_proj: [f32; 16],
    /// Eye position, world metres.
    pub eye: [f32; 3],
    /// The target's width and height in pixels.
    pub viewport: [f32; 2],
}

/// How the shell count follows the fur's projected length (docs/design.md "Shell level of
/// detail"); zeroed fields take furbake's defaults.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeShellLod {
    /// `sizeof(FurbakeShellLod)`, set by the caller.
    pub size: u32,
    /// Shell layers per pixel of projected fur length (0: the default, 1).
    pub layers_per_px: f32,
    /// The fewest layers drawn (0: the default, 16).
    pub min_layers: u32,
}

/// The shells one view draws: the `Frame` block's `shells` vector is `(layers, fade,
/// continuous, 0)`, and each shell draw has `layers` instances (blended shells are two draws:
/// back faces with first instance `layers`, then front faces with first instance 0; docs/c-api.md).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeShellLevel {
    /// `sizeof(FurbakeShellLevel)`, set by the caller.
    pub size: u32,
    /// Instances of each shell draw; layer i sits at height (i + 1)/layers.
    pub layers: u32,
    /// Opacity in (0, 1] of the layers a transition between two levels adds.
    pub fade: f32,
    /// The continuous layer count between the two levels.
    pub continuous: f32,
}

impl Zeroed for FurbakeFurLook {
    // `anisotropy` was added at the end: a host built before it passes the smaller struct.
    const MIN_SIZE: usize = std::mem::offset_of!(FurbakeFurLook, anisotropy);
}
impl Zeroed for FurbakeCamera {}
impl Zeroed for FurbakeShellLod {}

/// The value `cell` holds, built by `build` on the first call (a failed build leaves it empty).
fn cached<T>(cell: &OnceLock<T>, build: impl FnOnce() -> Result<T, Error>) -> Result<&T, Error> {
    if let Some(value) = cell.get() {
        return Ok(value);
    }
    let value = build()?;
    Ok(cell.get_or_init(|| value))
}

/// Borrows a pack handle whose pack has fur (skin, shell atlas, triangle UV map); missing
/// otherwise.
fn fur_pack<'a>(pack: *const FurbakePack) -> Result<&'a FurbakePack, Error> {
    let handle = pack_ref("pack", pack)?;
    for kind in [SectionKind::SKIN_MESH, SectionKind::SHELL_ATLAS, SectionKind::TRIANGLE_UV_MAP] {
        if !handle.pack.has(kind) {
            return Err(missing(&handle.pack, kind));
        }
    }
    Ok(handle)
}

/// A pack's fur bounds for the level of detail: the bounding sphere's centre and radius and the
/// fur length (metres, the pack's frame).
#[derive(Clone, Copy)]
pub(crate) struct FurBounds {
    center: Vec3,
    radius: f32,
    fur_length_m: f32,
}

fn array_view<T>(records: &[T]) -> FurbakeArrayView {
    FurbakeArrayView {
        size: 0,
        count: records.len() as u32,
        stride: std::mem::size_of::<T>() as u32,
        data: if records.is_empty() { std::ptr::null() } else { records.as_ptr().cast() },
    }
}

/// Fills `*view` with the skin's triangle corners (`FurbakeSurfaceView`). Missing without fur.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_surface_vertices(
    pack: *const FurbakePack,
    view: *mut FurbakeSurfaceView,
) -> FurbakeResult {
    guard(|| {
        let handle = fur_pack(pack)?;
        let p = &handle.pack;
        let surface =
            cached(&handle.draw.surface, || Ok(geometry::surface_vertices(&*p.skin_mesh()?, &*p.triangle_uv_map()?)))?;
        let (corners, furry_triangles) = (&surface.0, surface.1);
        let value = FurbakeSurfaceView {
            size: 0,
            vertex_count: corners.len() as u32,
            furry_vertex_count: 3 * furry_triangles,
            stride: std::mem::size_of::<SurfaceVertex>() as u32,
            vertices: corners.as_ptr().cast(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the fin quads: six corners (two triangles) per fin edge, roots at the edge
/// ends and tips at height 1 — vertex buffer 0 of the fin draw (`vs_fin`'s `vertex_inputs`):
/// 80 bytes each, position, normal and face normal (3 floats each), colour (4), metres along the
/// edge, height, welded vertex index, corner id, and the face's three welded vertices (uints).
/// An empty array when the pack has no fin edges. Missing without fur.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_fin_quads(
    pack: *const FurbakePack,
    view: *mut FurbakeArrayView,
) -> FurbakeResult {
    guard(|| {
        let handle = fur_pack(pack)?;
        let p = &handle.pack;
        let quads = cached(&handle.draw.fin_quads, || match p.has(SectionKind::FIN_EDGES) {
            true => Ok(geometry::fin_vertices(&*p.skin_mesh()?, &*p.fin_edges()?)),
            false => Ok(Vec::new()),
        })?;
        write_view("view", view, array_view(quads))
    })
}

/// Fills `*view` with the interior edges a silhouette fin may grow on (edges between two furry
/// triangles, the pack's fin edges left out; fur thesis §4.1): the `edges` storage buffer of
/// `silhouette.cs_silhouette` and `fin.vs_silhouette_fin`, 32 bytes each (ends a and b, the
/// third corners c and d of the two faces, the ends' corner ids in face 0, flags, padding).
/// Missing without fur.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_silhouette_edges(
    pack: *const FurbakePack,
    view: *mut FurbakeArrayView,
) -> FurbakeResult {
    guard(|| {
        let handle = fur_pack(pack)?;
        let p = &handle.pack;
        let edges = cached(&handle.draw.silhouette_edges, || {
            let fin_edges = if p.has(SectionKind::FIN_EDGES) { Some(p.fin_edges()?) } else { None };
            Ok(geometry::interior_edges(&*p.skin_mesh()?, fin_edges.as_deref()))
        })?;
        write_view("view", view, array_view(edges))
    })
}

/// Fills `*view` with mip level `level` of `atlas` (`FURBAKE_ATLAS_SHELL` or
/// `FURBAKE_ATLAS_FIN`), box-filtered as furbake's renderer uploads it. A level past the chain
/// is an invalid argument; an atlas the pack lacks is missing.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_atlas_level(
    pack: *const FurbakePack,
    atlas: u32,
    level: u32,
    view: *mut FurbakeAtlasLevelView,
) -> FurbakeResult {
    guard(|| {
        let handle = pack_ref("pack", pack)?;
        let p = &handle.pack;
        let (kind, slot) = match atlas {
            FURBAKE_ATLAS_SHELL => (SectionKind::SHELL_ATLAS, 0),
            FURBAKE_ATLAS_FIN => (SectionKind::FIN_ATLAS, 1),
            other => return Err(Error::argument(format!("atlas {other} is neither FURBAKE_ATLAS_SHELL nor _FIN"))),
        };
        if !p.has(kind) {
            return Err(missing(p, kind));
        }
        let levels = cached(&handle.draw.levels[slot], || {
            let (w, h, layers): (u32, u32, Vec<&[u8]>);
            let (shells, fins);
            if slot == 0 {
                shells = p.shell_atlas()?;
                (w, h) = (shells.params.resolution, shells.params.resolution);
                layers = (0..shells.layers()).map(|s| shells.layer(s)).collect();
            } else {
                fins = p.fin_atlas()?;
                (w, h) = (fins.width, fins.height);
                layers = vec![&fins.alpha[..]];
            }
            let chains: Vec<Vec<(u32, u32, Vec<u8>)>> =
                layers.iter().map(|texels| mips::mip_chain(w, h, texels)).collect();
            let count = chains.first().map_or(0, Vec::len);
            Ok((0..count)
                .map(|l| AtlasLevel {
                    width: chains[0][l].0,
                    height: chains[0][l].1,
                    texels: chains.iter().flat_map(|c| c[l].2.iter().copied()).collect(),
                })
                .collect())
        })?;
        let Some(l) = levels.get(level as usize) else {
            return Err(Error::argument(format!(
                "{}: level {level} of an atlas with {} mip levels",
                p.display_path().display(),
                levels.len()
            )));
        };
        let layers = (l.texels.len() / (l.width as usize * l.height as usize).max(1)) as u32;
        let value = FurbakeAtlasLevelView {
            size: 0,
            level_count: levels.len() as u32,
            width: l.width,
            height: l.height,
            layers,
            texels: l.texels.as_ptr(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the shells' stacking exponents, computed from the shell atlas on the first
/// request (0.15 s for the `fur` preset's atlas, debug build) and kept. Missing without fur.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_stacking_table(
    pack: *const FurbakePack,
    view: *mut FurbakeStackingTableView,
) -> FurbakeResult {
    guard(|| {
        let handle = fur_pack(pack)?;
        let p = &handle.pack;
        let table = cached(&handle.draw.stacking, || {
            Ok(stacking::shell_stacking_table(&*p.shell_atlas()?, p.triangle_uv_map()?.repeat_m))
        })?;
        let value = FurbakeStackingTableView {
            size: 0,
            angle_bins: stacking::ANGLE_BINS as u32,
            mip_bins: stacking::MIP_BINS as u32,
            count_bins: stacking::COUNT_BINS as u32,
            exponents: table.as_ptr(),
        };
        write_view("view", view, value)
    })
}

fn to_c(look: &FurLook) -> FurbakeFurLook {
    let s = &look.shading;
    FurbakeFurLook {
        size: 0,
        tint: look.tint,
        shear_exponent: look.shear_exponent,
        alpha_threshold: look.alpha_threshold,
        stacking_correction: u32::from(look.stacking_correction),
        kajiya_kay_diffuse: s.kajiya_kay_diffuse,
        primary_strength: s.primary_strength,
        primary_exponent: s.primary_exponent,
        primary_shift: s.primary_shift,
        secondary_strength: s.secondary_strength,
        secondary_exponent: s.secondary_exponent,
        secondary_shift: s.secondary_shift,
        secondary_tint: s.secondary_tint,
        secondary_noise: s.secondary_noise,
        back_light: s.back_light,
        root_occlusion: s.root_occlusion,
        tip_color: s.tip_color,
        anisotropy: look.anisotropy,
    }
}

fn from_c(c: &FurbakeFurLook) -> Result<FurLook, Error> {
    let shading = FurShading {
        kajiya_kay_diffuse: c.kajiya_kay_diffuse,
        primary_strength: c.primary_strength,
        primary_exponent: c.primary_exponent,
        primary_shift: c.primary_shift,
        secondary_strength: c.secondary_strength,
        secondary_exponent: c.secondary_exponent,
        secondary_shift: c.secondary_shift,
        secondary_tint: c.secondary_tint,
        secondary_noise: c.secondary_noise,
        back_light: c.back_light,
        root_occlusion: c.root_occlusion,
        tip_color: c.tip_color,
        ..FurShading::default()
    };
    shading.validate().map_err(|(field, what)| Error::argument(format!("look.{field}: {what}")))?;
    let bad = |what: &str| Err(Error::argument(format!("look.{what}")));
    if !(c.shear_exponent.is_finite() && c.shear_exponent > 0.0) {
        return bad("shear_exponent must be positive");
    }
    if !(0.0..1.0).contains(&c.alpha_threshold) {
        return bad("alpha_threshold must be in [0, 1)");
    }
    if c.tint.iter().any(|t| !t.is_finite() || *t < 0.0) {
        return bad("tint must be finite and non-negative");
    }
    let anisotropy = if c.anisotropy == 0.0 { FurLook::default().anisotropy } else { c.anisotropy };
    if !(1.0..=16.0).contains(&anisotropy) {
        return bad("anisotropy must be 0 (the default) or in [1, 16]");
    }
    Ok(FurLook {
        tint: c.tint,
        shear_exponent: c.shear_exponent,
        alpha_threshold: c.alpha_threshold,
        shading,
        stacking_correction: c.stacking_correction != 0,
        anisotropy,
    })
}

/// Fills `*look` with furbake's default look (what `furbake preview` draws).
///
/// # Safety
/// `look` points to a `FurbakeFurLook` whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_fur_look_default(look: *mut FurbakeFurLook) -> FurbakeResult {
    guard(|| write_grown_view("look", look, to_c(&FurLook::default())))
}

/// Writes the `Fur` uniform block (the manifest's struct `Fur`, 128 bytes) for `*look` and the
/// pack's shells, drawing `drawn_layers` layers (the most a view draws; at least 1 is written)
/// with one scale vector per welded vertex: `out_size` must be the block's size. A look out of
/// range is an invalid argument naming the field; missing without fur.
///
/// # Safety
/// `pack` is a live handle; `look` points to a `FurbakeFurLook` whose `size` is set; `out`
/// points to `out_size` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_fur_block(
    pack: *const FurbakePack,
    look: *const FurbakeFurLook,
    drawn_layers: u32,
    out: *mut c_void,
    out_size: u32,
) -> FurbakeResult {
    guard(|| {
        let handle = fur_pack(pack)?;
        let look = from_c(&read_desc("look", look)?)?;
        let block_size = std::mem::size_of::<FurUniforms>();
        if out_size as usize != block_size {
            return Err(Error::argument(format!("out_size is {out_size}; the Fur block is {block_size} bytes")));
        }
        if out.is_null() {
            return Err(Error::argument("out is a null pointer"));
        }
        let p = &handle.pack;
        let block = look.fur_uniforms(&*p.shell_atlas()?, p.triangle_uv_map()?.repeat_m, drawn_layers);
        let bytes = bytemuck::bytes_of(&block);
        // SAFETY: the caller passes `out_size` (= the block's size) writable bytes at `out`.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), out.cast::<u8>(), bytes.len()) };
        Ok(())
    })
}

/// Fills `*level` with the shells pack `index` draws in `*camera`'s view, of at most
/// `max_layers` (the atlas's layer count, or the host's choice), by `*lod` (null: furbake's
/// default curve), from the fur's projected length at the nearest point of the pack's bounds
/// placed by its model matrix (`furbake_draw::lod`). Every layer when the camera gives no
/// viewport or is inside the bounds. Missing without fur.
///
/// # Safety
/// `world` is a live handle; `camera` and `level` point to structs whose `size` is set; `lod` is
/// null or points to one whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_world_shell_level(
    world: *mut FurbakeWorld,
    index: u32,
    camera: *const FurbakeCamera,
    lod: *const FurbakeShellLod,
    max_layers: u32,
    level: *mut FurbakeShellLevel,
) -> FurbakeResult {
    guard(|| {
        let camera = read_desc("camera", camera)?;
        let mut rule = ShellLod::default();
        if !lod.is_null() {
            let l = read_desc("lod", lod)?;
            if l.layers_per_px != 0.0 {
                rule.layers_per_px = l.layers_per_px;
            }
            if l.min_layers != 0 {
                rule.min_layers = l.min_layers;
            }
            rule.validate().map_err(Error::argument)?;
        }
        if camera.view_proj.iter().chain(&camera.eye).chain(&camera.viewport).any(|x| !x.is_finite()) {
            return Err(Error::argument("camera has a value that is not finite"));
        }
        let handle = world_mut(world)?;
        let (model, pack) = {
            let (w, i) = handle.built_pack(index)?;
            (w.model_matrix(i), w.pack(i).clone())
        };
        let slot = index as usize;
        if handle.fur_bounds.len() <= slot {
            handle.fur_bounds.resize(slot + 1, None);
        }
        let b = match handle.fur_bounds[slot] {
            Some(b) => b,
            None => {
                if !(pack.has(SectionKind::SKIN_MESH) && pack.has(SectionKind::SHELL_ATLAS)) {
                    return Err(missing(&pack, SectionKind::SHELL_ATLAS));
                }
                let fur_length_m = pack.shell_atlas()?.fur_length_m;
                let (center, radius) = geometry::bounding_sphere(&*pack.skin_mesh()?, fur_length_m);
                let b = FurBounds { center: Vec3::from(center), radius, fur_length_m };
                *handle.fur_bounds[slot].insert(b)
            }
        };
        let px = furbake_draw::lod::projected_fur_px(
            Mat4::from_cols_slice(&camera.view_proj),
            Vec3::from(camera.eye),
            camera.viewport,
            model,
            b.center,
            b.radius,
            b.fur_length_m,
        );
        let l = match px {
            Some(px) => ShellLevel::of(max_layers, &rule, px),
            None => ShellLevel::full(max_layers),
        };
        let value = FurbakeShellLevel { size: 0, layers: l.layers, fade: l.fade, continuous: l.continuous };
        write_view("level", level, value)
    })
}
