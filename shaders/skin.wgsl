// skin.wgsl — the bare skin of a furry mesh (fur thesis §3.2: "the initial surface is rendered
// first"). Lambert diffuse (Lambert's cosine law, §3.2) with an ambient term, colour from the
// vertex colour; under fur the skin takes the innermost layer's self-shadow factor, so gaps
// between hairs read as the dark bottom of the coat.
// Prepended at load time: fur_common.wgsl (uniforms, switches, bindings 0–3 and 8, SurfaceIn,
// posed_vertex, shell_offset, lambert).

struct SkinOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) @interpolate(flat) flags: u32,
};

@vertex
fn vs_skin(v: SurfaceIn) -> SkinOut {
    var out: SkinOut;
    let root = posed_vertex(v.vertex_index, v.position, v.normal);
    out.clip = frame.view_proj * vec4<f32>(to_world(root.position.xyz), 1.0);
    out.normal = normal_to_world(root.normal.xyz);
    out.color = v.color;
    out.flags = v.flags;
    return out;
}

@fragment
fn fs_skin(in: SkinOut) -> @location(0) vec4<f32> {
    var shade = lambert(in.normal);
    if SHADOW && (in.flags & 1u) != 0u {
        shade = shade * shadow[0];
    }
    return vec4<f32>(in.color.rgb * fur.tint.rgb * shade, 1.0);
}
