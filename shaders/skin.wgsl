// skin.wgsl — the bare skin of a furry mesh (fur thesis §3.2: "the initial surface is rendered
// first"). Lambert diffuse (Lambert's cosine law, §3.2) with an ambient term, colour from the
// vertex colour; under fur the skin takes the innermost layer's self-shadow factor, so gaps
// between hairs read as the dark bottom of the coat.

struct Frame {
    view_proj: mat4x4<f32>,
    // xyz: eye position in metres; w unused.
    camera_pos: vec4<f32>,
    // xyz: unit vector from the surface towards the light; w unused.
    light_dir: vec4<f32>,
    // rgb: light colour × intensity; a: ambient term in [0, 1].
    light_color: vec4<f32>,
};

struct Fur {
    // rgb: colour multiplier applied to every vertex colour; a unused.
    tint: vec4<f32>,
    fur_length_m: f32,
    shear_exponent: f32,
    alpha_threshold: f32,
    atlas_layers: u32,
    drawn_layers: u32,
    fin_repeat_m: f32,
    pad0: u32,
    pad1: u32,
};

// Effect switches (pipeline-overridable constants, set from the scene's effects).
override LAMBERT: bool = true;
override SHADOW: bool = true;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> fur: Fur;
@group(0) @binding(3) var<storage, read> shadow: array<f32>;

struct SurfaceIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) vertex_index: u32,
    // bit 0: the triangle carries fur.
    @location(5) flags: u32,
};

struct SkinOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) @interpolate(flat) flags: u32,
};

@vertex
fn vs_skin(v: SurfaceIn) -> SkinOut {
    var out: SkinOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    out.flags = v.flags;
    return out;
}

fn lambert(n: vec3<f32>) -> vec3<f32> {
    if !LAMBERT {
        return vec3<f32>(1.0);
    }
    let d = max(dot(normalize(n), frame.light_dir.xyz), 0.0);
    let ambient = frame.light_color.a;
    return frame.light_color.rgb * (ambient + (1.0 - ambient) * d);
}

@fragment
fn fs_skin(in: SkinOut) -> @location(0) vec4<f32> {
    var shade = lambert(in.normal);
    if SHADOW && (in.flags & 1u) != 0u {
        shade = shade * shadow[0];
    }
    return vec4<f32>(in.color.rgb * fur.tint.rgb * shade, 1.0);
}
