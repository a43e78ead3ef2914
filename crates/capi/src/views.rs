//! The structs that cross the boundary: descriptors the host fills and views the library fills.
//! Each begins with `size`, which the caller sets to `sizeof` of its own copy of the struct;
//! the library reads or writes only that many bytes, so a host built against an older header
//! (a shorter struct) keeps working when fields are added at the end.
//!
//! Arrays are given as a pointer to the first element and a count in elements of the named
//! shape (`positions`: `vertex_count × 3` floats). A view's pointers borrow from the pack (baked
//! data: valid while the pack lives) or from the world (per-frame data: valid until the next
//! call that changes the world: a step, a `set_*`, a release).

use std::ffi::{c_char, c_void};

use crate::error::Error;

/// The pack holds a skin mesh ([`FurbakeSkinMeshView`]).
pub const FURBAKE_HAS_SKIN_MESH: u32 = 1 << 0;
/// The pack holds a shell atlas ([`FurbakeShellAtlasView`]): it has fur.
pub const FURBAKE_HAS_SHELL_ATLAS: u32 = 1 << 1;
/// The pack holds a fin atlas ([`FurbakeFinAtlasView`]).
pub const FURBAKE_HAS_FIN_ATLAS: u32 = 1 << 2;
/// The pack holds fin edges ([`FurbakeFinEdgesView`]).
pub const FURBAKE_HAS_FIN_EDGES: u32 = 1 << 3;
/// The pack holds a blade field ([`FurbakeBladeFieldView`]): it has grass blades.
pub const FURBAKE_HAS_BLADE_FIELD: u32 = 1 << 4;
/// The pack holds a keyframe table ([`FurbakeKeyframeTableView`]).
pub const FURBAKE_HAS_KEYFRAME_TABLE: u32 = 1 << 5;
/// The pack holds a skeleton ([`FurbakeSkeletonView`]).
pub const FURBAKE_HAS_SKELETON: u32 = 1 << 6;
/// The pack holds skin weights ([`FurbakeSkinWeightsView`]).
pub const FURBAKE_HAS_SKIN_WEIGHTS: u32 = 1 << 7;
/// The pack holds morph targets ([`FurbakeMorphTargetsView`]).
pub const FURBAKE_HAS_MORPH_TARGETS: u32 = 1 << 8;
/// The pack holds animation clips ([`FurbakeClipInfo`]).
pub const FURBAKE_HAS_CLIPS: u32 = 1 << 9;
/// The pack holds at least one spring topology: its fur can be simulated.
pub const FURBAKE_HAS_SPRING_TOPOLOGY: u32 = 1 << 10;

/// What a pack holds. Filled by `furbake_pack_info`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakePackInfo {
    /// `sizeof(FurbakePackInfo)`, set by the caller.
    pub size: u32,
    /// `FURBAKE_HAS_*` bits.
    pub contents: u32,
    /// The container's size in bytes.
    pub file_size: u64,
    /// Sections in the container.
    pub section_count: u32,
    /// Welded skin vertices (0 without a skin mesh).
    pub vertex_count: u32,
    /// Skin triangles (0 without a skin mesh).
    pub triangle_count: u32,
    /// Skeleton joints (0 without a skeleton).
    pub joint_count: u32,
    /// Animation clips.
    pub clip_count: u32,
    /// Morph targets.
    pub morph_target_count: u32,
}

/// The baked skin: what the host draws the skin, the shells and the fins on. Struct of arrays,
/// indexed by welded vertex or by triangle. Metres, the mesh's own frame.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeSkinMeshView {
    /// `sizeof(FurbakeSkinMeshView)`, set by the caller.
    pub size: u32,
    /// Welded vertices.
    pub vertex_count: u32,
    /// Triangles.
    pub triangle_count: u32,
    /// `vertex_count × 3` floats: positions, metres.
    pub positions: *const f32,
    /// `vertex_count × 3` floats: unit normals.
    pub normals: *const f32,
    /// `vertex_count × 4` floats: linear RGBA colour (vertex colour × base colour factor).
    pub colors: *const f32,
    /// `triangle_count × 3` vertex indices.
    pub triangles: *const u32,
    /// `triangle_count` bytes: 1 where the triangle carries fur, 0 where it is bare.
    pub fur_mask: *const u8,
    /// `triangle_count × 3 × 2` floats: each corner's TEXCOORD_0; null when the mesh had none.
    pub corner_texcoords: *const f32,
}

/// The shell atlas: one alpha layer per shell (fur thesis §3.2), innermost first.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeShellAtlasView {
    /// `sizeof(FurbakeShellAtlasView)`, set by the caller.
    pub size: u32,
    /// Width and height of a layer, texels.
    pub resolution: u32,
    /// Layers (shells).
    pub layers: u32,
    /// Distance from the skin to the outermost shell, metres.
    pub fur_length_m: f32,
    /// `layers × resolution × resolution` bytes of alpha (R8 unorm), layer-major, rows top to
    /// bottom: a 2D array texture.
    pub alpha: *const u8,
    /// `layers` floats: the self-shadow factor of each layer in (0, 1].
    pub shadow: *const f32,
    /// `layers` floats: the fraction of each layer's texels with non-zero alpha.
    pub coverage: *const f32,
}

/// The shells' texture coordinates: three `(u, v)` per triangle, one texture repeat covering
/// `repeat_m` of surface (fur thesis §3.2, fig. 3.18–3.19).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeTriangleUvMapView {
    /// `sizeof(FurbakeTriangleUvMapView)`, set by the caller.
    pub size: u32,
    /// Triangles (the skin mesh's, in its order).
    pub triangle_count: u32,
    /// Surface length one texture repeat covers, metres.
    pub repeat_m: f32,
    /// `triangle_count × 3 × 2` floats: each corner's `(u, v)` in the shell atlas.
    pub corners: *const f32,
}

/// The fin atlas: the texture of the fins standing on fin and silhouette edges (§3.2).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeFinAtlasView {
    /// `sizeof(FurbakeFinAtlasView)`, set by the caller.
    pub size: u32,
    /// Width in texels (along the edge; one texture repeat).
    pub width: u32,
    /// Height in texels (skin at the bottom row, fur tip at the top).
    pub height: u32,
    /// Vertical slices composed.
    pub slices: u32,
    /// `height × width` bytes of alpha (R8 unorm), rows top (tip) to bottom (root).
    pub alpha: *const u8,
}

/// The edges that always carry a fin (borders and fur boundaries).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeFinEdgesView {
    /// `sizeof(FurbakeFinEdgesView)`, set by the caller.
    pub size: u32,
    /// Edges.
    pub edge_count: u32,
    /// `edge_count × 2` welded vertex indices, in the winding order of the edge's triangle.
    pub vertices: *const u32,
    /// `edge_count` indices of the furry triangle each fin grows from.
    pub triangles: *const u32,
    /// `edge_count` bytes: 0 a mesh border, 1 between a furry and a bare triangle.
    pub kinds: *const u8,
}

/// The grass blade field (grass thesis §3.2): where every blade stands and how it is clustered.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeBladeFieldView {
    /// `sizeof(FurbakeBladeFieldView)`, set by the caller.
    pub size: u32,
    /// Blades.
    pub blade_count: u32,
    /// World `(x, z)` of the cluster grid's corner `(0, 0)`, metres.
    pub grid_origin_m: [f32; 2],
    /// Cluster cell size along x and z, metres.
    pub grid_cell_size_m: [f32; 2],
    /// Cells along x.
    pub grid_cells_x: u32,
    /// Cells along z.
    pub grid_cells_z: u32,
    /// Shortest blade, metres.
    pub height_min_m: f32,
    /// Tallest blade, metres.
    pub height_max_m: f32,
    /// `blade_count × 3` floats: root positions, metres.
    pub positions: *const f32,
    /// `blade_count` floats: yaw, radians.
    pub yaw_rad: *const f32,
    /// `blade_count` floats: metres per blade length.
    pub height_scale: *const f32,
    /// `blade_count` cluster (cell) indices.
    pub cluster: *const u32,
    /// `blade_count × 4` floats: bilinear weights over the cell's corners, summing to 1.
    pub weights: *const f32,
}

/// The grass keyframe table (grass thesis §4.4): a blade's precomputed poses on a force grid.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeKeyframeTableView {
    /// `sizeof(FurbakeKeyframeTableView)`, set by the caller.
    pub size: u32,
    /// Blade segments (quads).
    pub segments: u32,
    /// Reference vertices (`4 × segments`).
    pub vertex_count: u32,
    /// Front-face triangles (two per segment).
    pub triangle_count: u32,
    /// `vertex_count × 3` floats: neutral positions, blade lengths.
    pub reference_positions: *const f32,
    /// `vertex_count × 2` floats: `u` across the blade, `v` from root 0 to tip 1.
    pub reference_uvs: *const f32,
    /// `triangle_count × 3` vertex indices.
    pub triangles: *const u32,
    /// Force magnitudes on the grid.
    pub grid_magnitudes: u32,
    /// Force angles on the grid (of the full circle, before symmetry).
    pub grid_angles: u32,
    /// The largest force on the grid.
    pub max_force: f32,
    /// 0: every angle stored; 1: mirrored in `x = 0`; 2: mirrored in `x = 0` and `z = 0`.
    pub symmetry: u32,
    /// Bit 0: static vertices dropped; bit 1: rigid segment pairs merged.
    pub stages: u32,
    /// Stored displacement vectors per pose.
    pub stored_vectors: u32,
    /// `vertex_count` indices: each vertex's stored vector, or `0xFFFFFFFF` for a static vertex.
    pub vertex_map: *const u32,
    /// 0 f32, 1 snorm16 (`q / 32767 × scale`), 2 f16, 3 unorm8 (`(2q / 255 − 1) × scale`),
    /// 4 snorm8 (`q / 127 × scale`).
    pub displacement_encoding: u32,
    /// The scale of the normalised encodings (blade lengths; 1 for f32 and f16).
    pub displacement_scale: f32,
    /// Stored components (`stored poses × stored_vectors × 3`, pose-major).
    pub displacement_count: u64,
    /// The components, in `displacement_encoding`.
    pub displacements: *const c_void,
}

/// The skeleton: joints in parent-before-child order, their glTF nodes and rest pose, and the
/// skinning palette (binds).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeSkeletonView {
    /// `sizeof(FurbakeSkeletonView)`, set by the caller.
    pub size: u32,
    /// Joints.
    pub joint_count: u32,
    /// Palette entries (binds).
    pub bind_count: u32,
    /// `joint_count` parent joint indices (`0xFFFFFFFF` for a root).
    pub parents: *const u32,
    /// `joint_count` glTF node indices; null for a pack baked before they were recorded.
    pub nodes: *const u32,
    /// `joint_count × 3` floats: rest local translations.
    pub translations: *const f32,
    /// `joint_count × 4` floats: rest local rotations, unit quaternions `xyzw`.
    pub rotations: *const f32,
    /// `joint_count × 3` floats: rest local scales.
    pub scales: *const f32,
    /// `bind_count` joint indices: the joint each bind follows.
    pub bind_joints: *const u32,
    /// `bind_count × 16` floats: inverse bind matrices, column-major.
    pub inverse_binds: *const f32,
}

/// Skin weights: a fixed number of influences per welded vertex.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeSkinWeightsView {
    /// `sizeof(FurbakeSkinWeightsView)`, set by the caller.
    pub size: u32,
    /// Vertices.
    pub vertex_count: u32,
    /// Influences per vertex.
    pub influences_per_vertex: u32,
    /// `vertex_count × influences_per_vertex` bind (palette) indices.
    pub binds: *const u16,
    /// `vertex_count × influences_per_vertex` weights, summing to 1 per vertex.
    pub weights: *const f32,
}

/// Morph targets (glTF 2.0 "Morph Targets"): per target a position and a normal delta for every
/// welded skin vertex, applied before skinning (`p + Σ wᵢ·Δpᵢ`, normals renormalised).
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeMorphTargetsView {
    /// `sizeof(FurbakeMorphTargetsView)`, set by the caller.
    pub size: u32,
    /// Targets.
    pub target_count: u32,
    /// Welded skin vertices each target displaces.
    pub vertex_count: u32,
    /// `target_count × vertex_count × 3` floats: position deltas, target-major, metres.
    pub position_deltas: *const f32,
    /// Normal deltas in the same order; null when no target moves normals.
    pub normal_deltas: *const f32,
    /// `target_count` floats: the default weights.
    pub default_weights: *const f32,
}

/// One animation clip of a pack.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct FurbakeClipInfo {
    /// `sizeof(FurbakeClipInfo)`, set by the caller.
    pub size: u32,
    /// Length, seconds.
    pub duration_s: f32,
    /// The clip's name, NUL-terminated UTF-8, valid while the pack lives.
    pub name: *const c_char,
}

/// Checks an output view's `size` and writes `value` into the caller's bytes: at most the
/// caller's `size`, which must cover the struct's first version (today: all of it, but for the
/// structs [`write_grown_view`] writes); the caller's `size` field is left as it was.
pub(crate) fn write_view<T: Copy>(what: &str, dst: *mut T, value: T) -> Result<(), Error> {
    write_view_from(what, dst, value, std::mem::size_of::<T>())
}

/// [`write_view`] for a struct that has grown fields at its end since its first version
/// ([`Zeroed::MIN_SIZE`]): a caller built before them gets the fields it knows.
pub(crate) fn write_grown_view<T: Copy + Zeroed>(what: &str, dst: *mut T, value: T) -> Result<(), Error> {
    write_view_from(what, dst, value, T::MIN_SIZE)
}

fn write_view_from<T: Copy>(what: &str, dst: *mut T, value: T, min_size: usize) -> Result<(), Error> {
    if dst.is_null() {
        return Err(Error::argument(format!("{what} is a null pointer")));
    }
    // SAFETY: the struct begins with a u32 `size` the caller set; read unaligned in case the
    // caller's allocation is packed.
    let size = unsafe { (dst as *const u32).read_unaligned() } as usize;
    check_size(what, size, min_size)?;
    let n = size.min(std::mem::size_of::<T>());
    // SAFETY: the caller owns `size` writable bytes at `dst`; `value` is a plain C struct.
    unsafe {
        let src = (&value as *const T).cast::<u8>();
        std::ptr::copy_nonoverlapping(src.add(4), dst.cast::<u8>().add(4), n - 4);
    }
    Ok(())
}

/// Reads a descriptor the caller filled: `size` bytes of it, the fields past the caller's
/// `size` (added by a later version) left zero.
pub(crate) fn read_desc<T: Copy + Zeroed>(what: &str, src: *const T) -> Result<T, Error> {
    if src.is_null() {
        return Err(Error::argument(format!("{what} is a null pointer")));
    }
    // SAFETY: as in `write_view`.
    let size = unsafe { (src as *const u32).read_unaligned() } as usize;
    check_size(what, size, T::MIN_SIZE)?;
    let mut value = T::zeroed();
    let n = size.min(std::mem::size_of::<T>());
    // SAFETY: the caller owns `size` readable bytes at `src`; every field of `T` is valid zeroed.
    unsafe { std::ptr::copy_nonoverlapping(src.cast::<u8>(), (&mut value as *mut T).cast::<u8>(), n) };
    Ok(value)
}

/// A struct's `size` must hold at least its first version ([`Zeroed::MIN_SIZE`]); fields added at
/// its end since then read as zero.
fn check_size(what: &str, size: usize, needed: usize) -> Result<(), Error> {
    if size < needed {
        return Err(Error::argument(format!(
            "{what}.size is {size}; this library needs at least {needed} (set it to sizeof the struct)"
        )));
    }
    Ok(())
}

/// Structs whose every field may be zero (numbers and pointers).
pub(crate) trait Zeroed: Sized {
    /// The size of the struct's first version: a caller's `size` below it is an error.
    const MIN_SIZE: usize = std::mem::size_of::<Self>();
    fn zeroed() -> Self {
        // SAFETY: implemented only for C structs of numbers, arrays of numbers and raw pointers.
        unsafe { std::mem::zeroed() }
    }
}
