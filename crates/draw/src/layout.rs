//! The memory layouts furbake's shaders read (`crates/render/shaders/*.wgsl`), as `#[repr(C)]`
//! plain-old-data structs: vertex buffers and uniform and storage blocks, byte for byte what a
//! renderer uploads. `furbake-render` checks each against the WGSL it belongs to (its
//! `shaders` tests); `furbake shaders` writes the same offsets into its manifest for engines.

/// Per-asset fur uniforms (`Fur` in every shader; binding 1).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FurUniforms {
    /// Colour multiplier for every vertex colour (rgb; a unused).
    pub tint: [f32; 4],
    /// Distance from the skin to the outermost shell, in metres.
    pub fur_length_m: f32,
    /// Exponent k of the shell shearing, eq. 3.36.
    pub shear_exponent: f32,
    /// Shell and fin fragments with alpha at or below this are discarded.
    pub alpha_threshold: f32,
    /// Slices in the shell texture array.
    pub atlas_layers: u32,
    /// Shell layers drawn.
    pub drawn_layers: u32,
    /// Metres of edge per fin texture repeat.
    pub fin_repeat_m: f32,
    /// How the scale-vector buffer is indexed: 0 = one per welded skin vertex (`vertex_index`),
    /// 1 = one per triangle corner, `3 × triangle + corner` (`corner_index`; separable
    /// topologies, where fur parts along triangle edges, fur thesis §3.4.1).
    pub scale_layout: u32,
    /// Padding to 16 bytes.
    pub pad1: u32,
    /// The strand shading (`FurShading`, `fur_common.wgsl` `strand_shade`): tip colour
    /// multiplier (rgb) and root occlusion (a).
    pub tip_color: [f32; 4],
    /// Secondary highlight tint (rgb) and noise depth (a).
    pub secondary_tint: [f32; 4],
    /// Primary strength and exponent, secondary strength and exponent.
    pub specular: [f32; 4],
    /// Primary shift, secondary shift, back-light strength, Kajiya–Kay share of the diffuse term.
    pub strand: [f32; 4],
    /// x: 1 to blend the shells with the stacking exponents (`shell.wgsl` `stacked_alpha`,
    /// docs/design.md "Shell opacity"), 0 to blend each layer's alpha as it is; y: the anisotropy
    /// clamp of the atlas samplers (1 to 16), which `shell.wgsl` follows in picking the mip level
    /// of its exponents; zw unused.
    pub stacking: [f32; 4],
}

/// One corner of a skin/shell triangle (vertex buffer 0 of the skin and shell pipelines).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SurfaceVertex {
    /// Position in metres.
    pub position: [f32; 3],
    /// Unit vertex normal.
    pub normal: [f32; 3],
    /// Linear RGBA vertex colour.
    pub color: [f32; 4],
    /// Per-triangle shell UV of this corner, in texture repeats.
    pub uv: [f32; 2],
    /// Welded vertex index (into the scale-vector buffer when it holds one vector per vertex).
    pub vertex_index: u32,
    /// Bit 0: the triangle carries fur.
    pub flags: u32,
    /// `3 × triangle + corner` in the skin mesh's triangle order (into the scale-vector buffer
    /// when it holds one vector per triangle corner).
    pub corner_index: u32,
}

/// One corner of a fin quad (vertex buffer 0 of the fin pipeline).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FinVertex {
    /// Root position (an edge end) in metres.
    pub position: [f32; 3],
    /// Vertex normal at that edge end.
    pub normal: [f32; 3],
    /// Normal of the furry triangle the fin grows from.
    pub face_normal: [f32; 3],
    /// Linear RGBA vertex colour.
    pub color: [f32; 4],
    /// Distance along the edge in metres.
    pub along_m: f32,
    /// 0 at the root, 1 at the tip.
    pub height: f32,
    /// Welded vertex index (into the scale-vector buffer when it holds one vector per vertex).
    pub vertex_index: u32,
    /// `3 × triangle + corner` of this edge end in the furry triangle the fin grows from (into
    /// the scale-vector buffer when it holds one vector per triangle corner).
    pub corner_index: u32,
    /// Welded vertex indices of that triangle's corners: an animated pack's fin computes its
    /// face normal from their posed positions.
    pub face_vertices: [u32; 3],
}

/// One interior edge (`SilhouetteEdge` in `silhouette.wgsl` and `fin.wgsl`): ends `a`, `b`; `c`
/// the third corner of face 0, wound a → b → c; `d` the third corner of face 1, wound b → a → d
/// (`flags` bit 0 clear) or a → b → d (bit 0 set, the faces disagree in orientation);
/// `corner_a`, `corner_b` the ends' corner ids `3 × triangle + corner` in face 0.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SilhouetteEdge {
    /// First end (welded vertex).
    pub a: u32,
    /// Second end.
    pub b: u32,
    /// Third corner of face 0.
    pub c: u32,
    /// Third corner of face 1.
    pub d: u32,
    /// Corner id of `a` in face 0.
    pub corner_a: u32,
    /// Corner id of `b` in face 0.
    pub corner_b: u32,
    /// Bit 0: face 1 is wound a → b → d.
    pub flags: u32,
    /// Padding.
    pub pad0: u32,
}

/// This frame's selection parameters (`SilhouetteParams` in `silhouette.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SilhouetteParams {
    /// The eye in the pack's (object) frame, metres (w unused).
    pub camera_obj: [f32; 4],
    /// Half-width of the band around the silhouette, in units of n·v.
    pub band: f32,
    /// Interior edges to select from.
    pub edge_count: u32,
    /// Padding to 16 bytes.
    pub pad0: u32,
    /// Padding to 16 bytes.
    pub pad1: u32,
}
