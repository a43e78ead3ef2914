// The hierarchical depth (Hi-Z) pyramid of the host's depth buffer: level 0 is the depth itself,
// each further level the farthest depth of the texels of the level below that it covers, so a
// bound whose nearest depth is farther than one texel of a level is hidden behind everything
// that texel covers (the occlusion test of grass culling; Jahrmann & Wimmer 2017's fourth test).
// The CPU twin is `crates/render/src/depth_pyramid.rs` `reduce_level`. Levels follow the texture
// mip sizes (floor halving): an output texel on the last row or column of an odd-sized input
// also covers the input's extra row or column, so no input texel is left out.

struct PyramidLevel {
    // input width and height, output width and height
    sizes: vec4<u32>,
    // x: 1 when larger depths are nearer (reversed depth: farthest = smallest), else 0
    flags: vec4<u32>,
}

@group(0) @binding(0) var<uniform> level: PyramidLevel;
// The host's depth, read as an unfilterable float texture (what every depth format allows, and
// what the GLSL, HLSL and MSL exports can read with a plain texel fetch).
@group(0) @binding(1) var depth_in: texture_2d<f32>;
@group(0) @binding(2) var level_in: texture_2d<f32>;
@group(0) @binding(3) var level_out: texture_storage_2d<r32float, write>;

fn farther(a: f32, b: f32) -> f32 {
    return select(max(a, b), min(a, b), level.flags.x != 0u);
}

// Level 0: the depth buffer as it is.
@compute @workgroup_size(8, 8)
fn cs_depth_copy(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= level.sizes.z || gid.y >= level.sizes.w {
        return;
    }
    textureStore(level_out, vec2<i32>(gid.xy), vec4<f32>(textureLoad(depth_in, vec2<i32>(gid.xy), 0).r, 0.0, 0.0, 1.0));
}

// Level i + 1 from level i: the farthest of the 2×2 input texels (3 wide or tall at an odd edge).
@compute @workgroup_size(8, 8)
fn cs_depth_reduce(@builtin(global_invocation_id) gid: vec3<u32>) {
    let out_size = level.sizes.zw;
    if gid.x >= out_size.x || gid.y >= out_size.y {
        return;
    }
    let in_size = level.sizes.xy;
    let base = gid.xy * 2u;
    // One more column (row) for the last output texel of an odd input width (height).
    let extra = vec2<u32>(
        select(0u, 1u, gid.x + 1u == out_size.x && (in_size.x & 1u) == 1u),
        select(0u, 1u, gid.y + 1u == out_size.y && (in_size.y & 1u) == 1u),
    );
    var d = textureLoad(level_in, vec2<i32>(base), 0).r;
    for (var y = 0u; y <= 1u + extra.y; y++) {
        for (var x = 0u; x <= 1u + extra.x; x++) {
            let p = min(base + vec2<u32>(x, y), in_size - 1u);
            d = farther(d, textureLoad(level_in, vec2<i32>(p), 0).r);
        }
    }
    textureStore(level_out, vec2<i32>(gid.xy), vec4<f32>(d, 0.0, 0.0, 1.0));
}
