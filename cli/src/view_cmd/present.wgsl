// `furbake view`'s present pass: copies the frame the world was drawn into (an RGBA8 texture of
// the window's size) onto the window's surface texture, texel for texel. One triangle covers the
// surface; each fragment loads the texel under it (no sampler, no filtering). The Rust side binds
// the frame through an sRGB view when the surface format is sRGB (decode here, encode on store:
// the stored bytes come back unchanged) and through a plain view otherwise (the stored, already
// encoded bytes are copied as they are).

@group(0) @binding(0) var frame: texture_2d<f32>;

@vertex
fn vs_cover(@builtin(vertex_index) index: u32) -> @builtin(position) vec4<f32> {
    // (0,0), (2,0), (0,2) in units of the half surface: a triangle holding the whole surface.
    let corner = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    return vec4<f32>(corner * 2.0 - 1.0, 0.0, 1.0);
}

@fragment
fn fs_copy(@builtin(position) position: vec4<f32>) -> @location(0) vec4<f32> {
    let texel = textureLoad(frame, vec2<i32>(position.xy), 0);
    // The window is opaque whatever the frame's alpha.
    return vec4<f32>(texel.rgb, 1.0);
}
