//! Packs: open from a file or from memory, what they hold, and views of the baked data a host
//! uploads (docs/format.md describes each section).

use std::ffi::{CString, c_char};
use std::sync::{Arc, OnceLock};

use furbake_formats::SectionKind;
use furbake_formats::sections::keyframe_table::{Displacements, Symmetry};
use furbake_runtime::Pack;

use crate::error::{Error, FurbakeResult, c_string, guard, out, text};
use crate::views::*;

/// An opened pack (opaque). Made by `furbake_pack_open_file` or `furbake_pack_open_memory`,
/// freed by `furbake_pack_release`; a world that uses it keeps its own reference, so a pack may
/// be released while worlds built from it live on. Its views stay valid while it lives.
pub struct FurbakePack {
    pub(crate) pack: Arc<Pack>,
    /// The joint and clip names as C strings, made on first request.
    joint_names: OnceLock<Vec<CString>>,
    clip_names: OnceLock<Vec<CString>>,
    /// What drawing the pack takes (`crate::draw`), built on first request.
    pub(crate) draw: crate::draw::DrawCache,
}

impl FurbakePack {
    fn new(pack: Pack) -> FurbakePack {
        FurbakePack {
            pack: Arc::new(pack),
            joint_names: OnceLock::new(),
            clip_names: OnceLock::new(),
            draw: Default::default(),
        }
    }
}

/// Borrows a pack handle.
pub(crate) fn pack_ref<'a>(what: &str, pack: *const FurbakePack) -> Result<&'a FurbakePack, Error> {
    // SAFETY: a non-null handle is one this library made and the caller has not released.
    unsafe { pack.as_ref() }.ok_or_else(|| Error::argument(format!("{what} is a null pointer")))
}

/// Opens the pack file at `path` (UTF-8), validating its header, section table and every
/// section (as `furbake verify` does), and stores a new handle in `*out_pack`.
///
/// # Safety
/// `path` is a NUL-terminated string; `out_pack` points to writable storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_open_file(path: *const c_char, out_pack: *mut *mut FurbakePack) -> FurbakeResult {
    guard(|| {
        let path = text("path", path)?;
        let slot = out("out_pack", out_pack)?;
        let pack = Pack::open(path)?;
        pack.verify()?;
        *slot = Box::into_raw(Box::new(FurbakePack::new(pack)));
        Ok(())
    })
}

/// Reads a pack from `size` bytes at `bytes` (copied; the caller may free them on return),
/// validating it as `furbake_pack_open_file` does. `name` (UTF-8, may be null) labels error
/// messages in place of a file name.
///
/// # Safety
/// `bytes` points to `size` readable bytes; `name` is null or NUL-terminated; `out_pack` points
/// to writable storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_open_memory(
    bytes: *const u8,
    size: usize,
    name: *const c_char,
    out_pack: *mut *mut FurbakePack,
) -> FurbakeResult {
    guard(|| {
        let bytes = crate::error::slice("bytes", bytes, size)?;
        let name = crate::error::optional_text("name", name)?.unwrap_or("<memory>");
        let slot = out("out_pack", out_pack)?;
        let pack = Pack::from_bytes_named(bytes, name)?;
        pack.verify()?;
        *slot = Box::into_raw(Box::new(FurbakePack::new(pack)));
        Ok(())
    })
}

/// Frees a pack handle (null is ignored). Views of it become invalid; worlds built from it keep
/// working.
///
/// # Safety
/// `pack` is null or a handle from this library, not used again.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_release(pack: *mut FurbakePack) {
    if !pack.is_null() {
        // SAFETY: a handle made by `Box::into_raw` in this module, released once.
        let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| drop(unsafe { Box::from_raw(pack) })));
    }
}

/// Fills `*info` with what the pack holds.
///
/// # Safety
/// `pack` is a live handle; `info` points to a `FurbakePackInfo` whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_info(pack: *const FurbakePack, info: *mut FurbakePackInfo) -> FurbakeResult {
    guard(|| {
        let p = &pack_ref("pack", pack)?.pack;
        let bits = [
            (SectionKind::SKIN_MESH, FURBAKE_HAS_SKIN_MESH),
            (SectionKind::SHELL_ATLAS, FURBAKE_HAS_SHELL_ATLAS),
            (SectionKind::FIN_ATLAS, FURBAKE_HAS_FIN_ATLAS),
            (SectionKind::FIN_EDGES, FURBAKE_HAS_FIN_EDGES),
            (SectionKind::BLADE_FIELD, FURBAKE_HAS_BLADE_FIELD),
            (SectionKind::KEYFRAME_TABLE, FURBAKE_HAS_KEYFRAME_TABLE),
            (SectionKind::SKELETON, FURBAKE_HAS_SKELETON),
            (SectionKind::SKIN_WEIGHTS, FURBAKE_HAS_SKIN_WEIGHTS),
            (SectionKind::MORPH_TARGETS, FURBAKE_HAS_MORPH_TARGETS),
            (SectionKind::ANIMATION_CLIPS, FURBAKE_HAS_CLIPS),
            (SectionKind::SPRING_TOPOLOGY, FURBAKE_HAS_SPRING_TOPOLOGY),
        ];
        let contents = bits.iter().filter(|(kind, _)| p.has(*kind)).fold(0, |acc, (_, bit)| acc | bit);
        let mesh = p.optional_section::<furbake_formats::sections::skin_mesh::SkinMesh>()?;
        let value = FurbakePackInfo {
            size: 0,
            contents,
            file_size: p.file_size(),
            section_count: p.sections().len() as u32,
            vertex_count: mesh.as_ref().map_or(0, |m| m.positions.len() as u32),
            triangle_count: mesh.as_ref().map_or(0, |m| m.triangles.len() as u32),
            joint_count: p.skeleton()?.map_or(0, |s| s.joint_count() as u32),
            clip_count: p.animation_clips()?.map_or(0, |c| c.clips.len() as u32),
            morph_target_count: p.morph_targets()?.map_or(0, |m| m.target_count() as u32),
        };
        write_view("info", info, value)
    })
}

/// Fills `*view` with the pack's skin mesh.
///
/// # Safety
/// `pack` is a live handle; `view` points to a view whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_skin_mesh(
    pack: *const FurbakePack,
    view: *mut FurbakeSkinMeshView,
) -> FurbakeResult {
    guard(|| {
        let m = pack_ref("pack", pack)?.pack.skin_mesh()?;
        let value = FurbakeSkinMeshView {
            size: 0,
            vertex_count: m.positions.len() as u32,
            triangle_count: m.triangles.len() as u32,
            positions: m.positions.as_ptr().cast(),
            normals: m.normals.as_ptr().cast(),
            colors: m.colors.as_ptr().cast(),
            triangles: m.triangles.as_ptr().cast(),
            fur_mask: m.fur_mask.as_ptr(),
            corner_texcoords: if m.corner_texcoords.is_empty() {
                std::ptr::null()
            } else {
                m.corner_texcoords.as_ptr().cast()
            },
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's shell atlas.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_shell_atlas(
    pack: *const FurbakePack,
    view: *mut FurbakeShellAtlasView,
) -> FurbakeResult {
    guard(|| {
        let a = pack_ref("pack", pack)?.pack.shell_atlas()?;
        let value = FurbakeShellAtlasView {
            size: 0,
            resolution: a.params.resolution,
            layers: a.params.layers,
            fur_length_m: a.fur_length_m,
            alpha: a.alpha.as_ptr(),
            shadow: a.shadow.as_ptr(),
            coverage: a.coverage.as_ptr(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the shells' texture coordinates (the pack's triangle UV map).
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_triangle_uv_map(
    pack: *const FurbakePack,
    view: *mut FurbakeTriangleUvMapView,
) -> FurbakeResult {
    guard(|| {
        let m = pack_ref("pack", pack)?.pack.triangle_uv_map()?;
        let value = FurbakeTriangleUvMapView {
            size: 0,
            triangle_count: m.corners.len() as u32,
            repeat_m: m.repeat_m,
            corners: m.corners.as_ptr().cast(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's fin atlas.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_fin_atlas(
    pack: *const FurbakePack,
    view: *mut FurbakeFinAtlasView,
) -> FurbakeResult {
    guard(|| {
        let a = pack_ref("pack", pack)?.pack.fin_atlas()?;
        let value = FurbakeFinAtlasView {
            size: 0,
            width: a.width,
            height: a.height,
            slices: a.slices,
            alpha: a.alpha.as_ptr(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's fin edges.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_fin_edges(
    pack: *const FurbakePack,
    view: *mut FurbakeFinEdgesView,
) -> FurbakeResult {
    guard(|| {
        let e = pack_ref("pack", pack)?.pack.fin_edges()?;
        let value = FurbakeFinEdgesView {
            size: 0,
            edge_count: e.vertices.len() as u32,
            vertices: e.vertices.as_ptr().cast(),
            triangles: e.triangles.as_ptr(),
            // `FinEdgeKind` is `repr(u8)`: 0 border, 1 fur boundary.
            kinds: e.kinds.as_ptr().cast(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's blade field.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_blade_field(
    pack: *const FurbakePack,
    view: *mut FurbakeBladeFieldView,
) -> FurbakeResult {
    guard(|| {
        let f = pack_ref("pack", pack)?.pack.blade_field()?;
        let value = FurbakeBladeFieldView {
            size: 0,
            blade_count: f.positions.len() as u32,
            grid_origin_m: f.grid.origin_m,
            grid_cell_size_m: f.grid.cell_size_m,
            grid_cells_x: f.grid.cells_x,
            grid_cells_z: f.grid.cells_z,
            height_min_m: f.params.height_min_m,
            height_max_m: f.params.height_max_m,
            positions: f.positions.as_ptr().cast(),
            yaw_rad: f.yaw_rad.as_ptr(),
            height_scale: f.height_scale.as_ptr(),
            cluster: f.cluster.as_ptr(),
            weights: f.weights.as_ptr().cast(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's keyframe table.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_keyframe_table(
    pack: *const FurbakePack,
    view: *mut FurbakeKeyframeTableView,
) -> FurbakeResult {
    guard(|| {
        let k = pack_ref("pack", pack)?.pack.keyframe_table()?;
        let (encoding, scale, count, ptr): (u32, f32, usize, *const std::ffi::c_void) = match &k.displacements {
            Displacements::F32(v) => (0, 1.0, v.len(), v.as_ptr().cast()),
            Displacements::Snorm16 { scale, values } => (1, *scale, values.len(), values.as_ptr().cast()),
            Displacements::F16(v) => (2, 1.0, v.len(), v.as_ptr().cast()),
            Displacements::Unorm8 { scale, values } => (3, *scale, values.len(), values.as_ptr().cast()),
            Displacements::Snorm8 { scale, values } => (4, *scale, values.len(), values.as_ptr().cast()),
        };
        let value = FurbakeKeyframeTableView {
            size: 0,
            segments: k.segments,
            vertex_count: k.reference_positions.len() as u32,
            triangle_count: k.triangles.len() as u32,
            reference_positions: k.reference_positions.as_ptr().cast(),
            reference_uvs: k.reference_uvs.as_ptr().cast(),
            triangles: k.triangles.as_ptr().cast(),
            grid_magnitudes: k.grid.magnitudes,
            grid_angles: k.grid.angles,
            max_force: k.grid.max_force,
            symmetry: match k.symmetry {
                Symmetry::None => 0,
                Symmetry::X => 1,
                Symmetry::XZ => 2,
            },
            stages: u32::from(k.stages.drop_static_vertices) | (u32::from(k.stages.rigid_segment_pairs) << 1),
            stored_vectors: k.stored_vectors,
            vertex_map: k.vertex_map.as_ptr(),
            displacement_encoding: encoding,
            displacement_scale: scale,
            displacement_count: count as u64,
            displacements: ptr,
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's skeleton.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_skeleton(
    pack: *const FurbakePack,
    view: *mut FurbakeSkeletonView,
) -> FurbakeResult {
    guard(|| {
        let p = &pack_ref("pack", pack)?.pack;
        let s = p.skeleton()?.ok_or_else(|| missing(p, SectionKind::SKELETON))?;
        let value = FurbakeSkeletonView {
            size: 0,
            joint_count: s.joint_count() as u32,
            bind_count: s.bind_count() as u32,
            parents: s.parents.as_ptr(),
            nodes: if s.nodes.is_empty() { std::ptr::null() } else { s.nodes.as_ptr() },
            translations: s.translations.as_ptr().cast(),
            rotations: s.rotations.as_ptr().cast(),
            scales: s.scales.as_ptr().cast(),
            bind_joints: s.bind_joints.as_ptr(),
            inverse_binds: s.inverse_binds.as_ptr().cast(),
        };
        write_view("view", view, value)
    })
}

/// Stores joint `index`'s name (its glTF node's name; empty when unnamed) in `*out_name`:
/// NUL-terminated UTF-8, valid while the pack lives.
///
/// # Safety
/// `pack` is a live handle; `out_name` points to writable storage for a pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_joint_name(
    pack: *const FurbakePack,
    index: u32,
    out_name: *mut *const c_char,
) -> FurbakeResult {
    guard(|| {
        let handle = pack_ref("pack", pack)?;
        let slot = out("out_name", out_name)?;
        let p = &handle.pack;
        let s = p.skeleton()?.ok_or_else(|| missing(p, SectionKind::SKELETON))?;
        let names = handle.joint_names.get_or_init(|| s.names.iter().map(|n| c_string(n)).collect());
        let name = names.get(index as usize).ok_or_else(|| {
            Error::argument(format!("{}: joint {index} of a skeleton of {}", p.display_path().display(), names.len()))
        })?;
        *slot = name.as_ptr();
        Ok(())
    })
}

/// Fills `*view` with the pack's skin weights.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_skin_weights(
    pack: *const FurbakePack,
    view: *mut FurbakeSkinWeightsView,
) -> FurbakeResult {
    guard(|| {
        let p = &pack_ref("pack", pack)?.pack;
        let w = p.skin_weights()?.ok_or_else(|| missing(p, SectionKind::SKIN_WEIGHTS))?;
        let per = w.influences_per_vertex.max(1) as usize;
        let value = FurbakeSkinWeightsView {
            size: 0,
            vertex_count: (w.binds.len() / per) as u32,
            influences_per_vertex: w.influences_per_vertex,
            binds: w.binds.as_ptr(),
            weights: w.weights.as_ptr(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*view` with the pack's morph targets.
///
/// # Safety
/// As `furbake_pack_skin_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_morph_targets(
    pack: *const FurbakePack,
    view: *mut FurbakeMorphTargetsView,
) -> FurbakeResult {
    guard(|| {
        let p = &pack_ref("pack", pack)?.pack;
        let m = p.morph_targets()?.ok_or_else(|| missing(p, SectionKind::MORPH_TARGETS))?;
        let value = FurbakeMorphTargetsView {
            size: 0,
            target_count: m.target_count() as u32,
            vertex_count: m.vertex_count,
            position_deltas: m.position_deltas.as_ptr().cast(),
            normal_deltas: if m.normal_deltas.is_empty() { std::ptr::null() } else { m.normal_deltas.as_ptr().cast() },
            default_weights: m.default_weights.as_ptr(),
        };
        write_view("view", view, value)
    })
}

/// Fills `*info` with clip `index`'s name and length.
///
/// # Safety
/// `pack` is a live handle; `info` points to a `FurbakeClipInfo` whose `size` is set.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn furbake_pack_clip(
    pack: *const FurbakePack,
    index: u32,
    info: *mut FurbakeClipInfo,
) -> FurbakeResult {
    guard(|| {
        let handle = pack_ref("pack", pack)?;
        let p = &handle.pack;
        let clips = p.animation_clips()?.ok_or_else(|| missing(p, SectionKind::ANIMATION_CLIPS))?;
        let names = handle.clip_names.get_or_init(|| clips.clips.iter().map(|c| c_string(&c.name)).collect());
        let clip = clips.clips.get(index as usize).ok_or_else(|| {
            Error::argument(format!("{}: clip {index} of {}", p.display_path().display(), clips.clips.len()))
        })?;
        let value = FurbakeClipInfo { size: 0, duration_s: clip.duration_s, name: names[index as usize].as_ptr() };
        write_view("info", info, value)
    })
}

pub(crate) fn missing(p: &Pack, kind: SectionKind) -> Error {
    Error::new(FurbakeResult::Missing, format!("{}: the pack has no {kind} section", p.display_path().display()))
}
