// skin.wgsl — the bare skin of a furry mesh (fur thesis §3.2: "the initial surface is rendered
// first"). Lambert diffuse (Lambert's cosine law, §3.2) with an ambient term, colour from the
// vertex colour; under fur the skin takes the innermost layer's self-shadow factor, so gaps
// between hairs read as the dark bottom of the coat. With STRAND, furry skin is shaded as the root
// of the innermost shell is (fur_common.wgsl `strand_shade` at height 0 with that factor, hair
// direction n — eq. 3.36's at t = 0 for k > 1 — and the mean noise mask); bare skin keeps Lambert.
// Prepended at load time: fur_common.wgsl (uniforms, switches, bindings 0–3 and 8, SurfaceIn,
// posed_vertex, shell_offset, lambert, strand_shade).

struct SkinOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) @interpolate(flat) flags: u32,
    @location(3) world: vec3<f32>,
};

@vertex
fn vs_skin(v: SurfaceIn) -> SkinOut {
    var out: SkinOut;
    let root = posed_vertex(v.vertex_index, v.position, v.normal);
    let world = to_world(root.position.xyz);
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.normal = normal_to_world(root.normal.xyz);
    out.color = v.color;
    out.flags = v.flags;
    return out;
}

@fragment
fn fs_skin(in: SkinOut) -> @location(0) vec4<f32> {
    if STRAND && LAMBERT && (in.flags & 1u) != 0u {
        var direct = 1.0;
        if SHADOW {
            direct = shadow[0];
        }
        let to_eye = normalize(frame.camera_pos.xyz - in.world);
        let mask = 1.0 - 0.5 * fur.secondary_tint.a;
        let rgb = strand_shade(in.color.rgb * fur.tint.rgb, in.normal, in.normal, in.world, to_eye, 0.0, direct, mask);
        return vec4<f32>(rgb, 1.0);
    }
    var shade = lambert(in.normal, in.world);
    if SHADOW && (in.flags & 1u) != 0u {
        shade = shade * shadow[0];
    }
    return vec4<f32>(in.color.rgb * fur.tint.rgb * shade, 1.0);
}
