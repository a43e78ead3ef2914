// grass_common.wgsl — what the blade draw (blades.wgsl) and the blade culling passes
// (blade_cull.wgsl) share: one blade instance, the culling parameters of the frame and the
// per-blade decisions both sides must take identically (the random thresholds of distance
// thinning and of the dithered level-of-detail switch, and thinning's kept fraction). Prepended
// to both files; `crates/render/src/culling.rs` mirrors every function on the CPU.

struct Blade {
    // xyz: root position in metres; w: height scale (metres per blade length).
    root: vec4<f32>,
    // cos yaw, sin yaw: the width axis is (cos, 0, −sin), the normal (sin, 0, cos).
    yaw: vec2<f32>,
    // The blade's cluster (grid cell) index: its corners follow from the grid (`cluster_corners`).
    cluster: u32,
    pad: u32,
    // The bilinear weights of the cluster's corners [P1, P2, P3, P4].
    weights: vec4<f32>,
};

// The corner indices [P1, P2, P3, P4] of cluster `c` in a grid `cells_x` cells wide (as
// `ClusterGrid::corner_indices`).
fn cluster_corners(c: u32, cells_x: u32) -> vec4<u32> {
    let row = cells_x + 1u;
    let p1 = (c / cells_x) * row + c % cells_x;
    return vec4<u32>(p1, p1 + 1u, p1 + row, p1 + row + 1u);
}

// The frame's culling parameters, all in the pack frame (the blade field's own metres; the host's
// world distances are divided by the model matrix's scale on the CPU).
struct CullUniforms {
    // The six clip planes of view_proj × model (left, right, bottom, top, near, far), normalised
    // so that dot(xyz, p) + w is a signed distance; a degenerate plane is (0, 0, 0, 1).
    planes: array<vec4<f32>, 6>,
    // xyz: the eye in the pack frame; w: 1 when culling is on.
    eye: vec4<f32>,
    // x, y: distances where LOD 1 and LOD 2 start; z, w: their dither bands.
    lod: vec4<f32>,
    // x: max distance²; y: thinning start; z: min density; w: 1 − min visible width² (1: off).
    distance: vec4<f32>,
    // x: reach of any pose in blade lengths; y: largest reference half-width in blade lengths; z:
    // the share of its width an edge-on blade is thickened to (`culling::EDGE_ON_WIDTH`).
    shape: vec4<f32>,
    // Per LOD: index count and first index in the index buffer.
    index_count: vec4<u32>,
    first_index: vec4<u32>,
    // Blades, clusters, 256-blade blocks, levels of detail.
    counts: vec4<u32>,
    // view_proj × model: the pack frame to clip space (the occlusion test's projection).
    clip: mat4x4<f32>,
    // The depth pyramid of this view (crates/render/src/depth_pyramid.rs): width, height, levels,
    // flags (1: test against it, 2: reversed depth).
    occlusion: vec4<u32>,
};

// Salts of the two per-blade random numbers.
const SALT_THINNING: u32 = 0x68e31da4u;
const SALT_LOD: u32 = 0xb5297a4du;
// The LOD code of a culled blade.
const CULLED: u32 = 0xffffffffu;
// A blade (or, in a cluster's decision, 2) hidden behind the host's depth: not drawn, counted apart.
const OCCLUDED: u32 = 0xfffffffeu;

// A fixed uniform number in [0, 1) per blade and salt (24 bits, exact in f32).
fn blade_random(b: u32, salt: u32) -> f32 {
    var x = (b * 0x9e3779b9u) ^ salt;
    x ^= x >> 16u;
    x *= 0x7feb352du;
    x ^= x >> 15u;
    x *= 0x846ca68bu;
    x ^= x >> 16u;
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

// Fraction of blades distance thinning keeps at distance d (pack metres): (start / d)², at least
// `min_density`, at most 1.
fn thinning_keep(start: f32, min_density: f32, d: f32) -> f32 {
    let s = start / max(d, 1e-30);
    return min(max(s * s, min_density), 1.0);
}
