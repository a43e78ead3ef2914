// fur_common.wgsl — what the skin, shell and fin shaders share: the frame and fur uniforms (each
// checked against its #[repr(C)] Rust twin in crates/render/src/shaders.rs), the effect switches
// (pipeline-overridable constants, set from the scene's effects), the bindings of group 0, the
// surface vertex layout, the posed root of a vertex (the bind pose, or the skinning pass's output
// for an animated pack), the eq. 3.36 shell offset, the object→world model transform and Lambert
// shading. The renderer prepends this file to each of them (WGSL has no includes).

struct Frame {
    view_proj: mat4x4<f32>,
    // xyz: eye position in metres; w unused.
    camera_pos: vec4<f32>,
    // xyz: unit vector from the surface towards the light; w unused.
    light_dir: vec4<f32>,
    // rgb: light colour × intensity; a: ambient term in [0, 1].
    light_color: vec4<f32>,
    // Model matrix of the drawn object (object/pack frame → world): rotation, translation and a
    // uniform positive scale. Identity for a single object.
    model: mat4x4<f32>,
};

struct Fur {
    // rgb: colour multiplier applied to every vertex colour; a unused.
    tint: vec4<f32>,
    fur_length_m: f32,
    // Exponent k of eq. 3.36.
    shear_exponent: f32,
    // Fragments with alpha at or below this are discarded.
    alpha_threshold: f32,
    // Slices in the shell texture array.
    atlas_layers: u32,
    // Shell layers drawn (instances); slice = layer·atlas_layers/drawn_layers.
    drawn_layers: u32,
    // Metres of edge per fin texture repeat (the shell texture's texel density).
    fin_repeat_m: f32,
    // How scale_vectors is indexed: 0 = per welded vertex (vertex_index), 1 = per triangle
    // corner, 3·triangle + corner (corner_index; separable topologies, where fur parts).
    scale_layout: u32,
    pad1: u32,
};

override LAMBERT: bool = true;
override SHADOW: bool = true;
// Eq. 3.36 shearing from the scale-vector buffer; off for static fur (s = n everywhere).
override SHEAR: bool = true;
// true: alpha-blended output; false: alpha-tested (opaque) output.
override ALPHA_BLEND: bool = true;
// The pack is animated (skin weights or morph targets, glTF 2.0 "Skins", "Morph Targets"): the
// skinning pass (skinning.wgsl) writes this frame's posed welded vertices into `skinned`, and
// every stage reads its roots there by welded vertex index (no re-skinning per shell layer).
// false: the bind pose from the vertex attributes, exactly as for an unanimated pack.
override SKINNED: bool = false;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> fur: Fur;
// Per shell vertex (welded vertex or triangle corner, see Fur.scale_layout): xyz = unit scale
// vector s (eq. 3.35); w unused.
@group(0) @binding(2) var<storage, read> scale_vectors: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> shadow: array<f32>;

// One welded skin vertex as posed by the skinning pass: xyz position in metres (w = 1), xyz unit
// normal (w = 0). The same struct as skinning.wgsl's.
struct SkinnedVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
};

// This frame's posed welded vertices (the skinning pass's output), read only when SKINNED; a
// one-entry placeholder otherwise.
@group(0) @binding(8) var<storage, read> skinned: array<SkinnedVertex>;

struct SurfaceIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) vertex_index: u32,
    // bit 0: the triangle carries fur.
    @location(5) flags: u32,
    // 3·triangle + corner in the skin mesh's triangle order.
    @location(6) corner_index: u32,
};

// Index into scale_vectors of a corner with welded vertex `vertex_index` and triangle-corner id
// `corner_index`, for the buffer's current layout (Fur.scale_layout).
fn scale_index(vertex_index: u32, corner_index: u32) -> u32 {
    return select(vertex_index, corner_index, fur.scale_layout == 1u);
}

// The root of welded vertex `vertex_index` this frame: its skinned position and normal when
// SKINNED, else the bind pose `position` and `normal` from the vertex attributes.
fn posed_vertex(vertex_index: u32, position: vec3<f32>, normal: vec3<f32>) -> SkinnedVertex {
    if SKINNED {
        return skinned[vertex_index];
    }
    return SkinnedVertex(vec4<f32>(position, 1.0), vec4<f32>(normal, 0.0));
}

// Offset of a point at relative height t in [0, 1] above a vertex with unit normal n and scale
// vector s: vertical displacement along n plus the horizontal shear h(t) = t^k (s − n) of
// eq. 3.36, both in units of the fur length.
fn shell_offset(n: vec3<f32>, s: vec3<f32>, t: f32) -> vec3<f32> {
    var offset = n * t;
    if SHEAR {
        offset = offset + pow(t, fur.shear_exponent) * (s - n);
        // A scale vector pointing into the surface (the wrong-side-scale problem, §3.4.3) would
        // shear the outer layers below the skin; drop the inward component so that fur lies
        // flat instead of rendering inside the surface.
        offset = offset - min(dot(offset, n), 0.0) * n;
    }
    return offset * fur.fur_length_m;
}

// Object → world position.
fn to_world(p: vec3<f32>) -> vec3<f32> {
    return (frame.model * vec4<f32>(p, 1.0)).xyz;
}

// Object → world direction of a normal (exact for rotation + uniform scale).
fn normal_to_world(n: vec3<f32>) -> vec3<f32> {
    return normalize((frame.model * vec4<f32>(n, 0.0)).xyz);
}

// Lambert diffuse (fur thesis §3.2) with an ambient term.
fn lambert(n: vec3<f32>) -> vec3<f32> {
    if !LAMBERT {
        return vec3<f32>(1.0);
    }
    let d = max(dot(normalize(n), frame.light_dir.xyz), 0.0);
    let ambient = frame.light_color.a;
    return frame.light_color.rgb * (ambient + (1.0 - ambient) * d);
}
