// shell.wgsl — shell layers (fur thesis §3.2, fig. 3.10–3.12) drawn instanced, one instance per
// layer, innermost first (instances rasterise in order, so blending is back-to-front along each
// hair). Each corner is extruded along its normal by t·fur_length (t = (layer+1)/layers) and
// sheared towards its scale vector s by t^k·(s − n)·fur_length (eq. 3.35–3.36, §3.4.2); the
// scale vectors live in a per-vertex storage buffer the physics rewrites every frame (initially
// s = n, i.e. no shear). Fragment: alpha from the shell texture array, colour = vertex colour ×
// tint × per-layer self-shadow factor × Lambert.

struct Frame {
    view_proj: mat4x4<f32>,
    camera_pos: vec4<f32>,
    light_dir: vec4<f32>,
    light_color: vec4<f32>,
};

struct Fur {
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
    fin_repeat_m: f32,
    pad0: u32,
    pad1: u32,
};

override LAMBERT: bool = true;
override SHADOW: bool = true;
// Eq. 3.36 shearing from the scale-vector buffer; off for static fur (s = n everywhere).
override SHEAR: bool = true;
// true: alpha-blended output; false: alpha-tested (opaque) output.
override ALPHA_BLEND: bool = true;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> fur: Fur;
// Per welded vertex: xyz = unit scale vector s (eq. 3.35); w unused.
@group(0) @binding(2) var<storage, read> scale_vectors: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> shadow: array<f32>;
@group(0) @binding(4) var shell_alpha: texture_2d_array<f32>;
@group(0) @binding(5) var repeat_sampler: sampler;

struct SurfaceIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) vertex_index: u32,
    @location(5) flags: u32,
};

struct ShellOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) slice: u32,
};

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

@vertex
fn vs_shell(v: SurfaceIn, @builtin(instance_index) layer: u32) -> ShellOut {
    let t = f32(layer + 1u) / f32(fur.drawn_layers);
    let n = normalize(v.normal);
    let s = scale_vectors[v.vertex_index].xyz;
    let world = v.position + shell_offset(n, s, t);
    var out: ShellOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = n;
    out.color = v.color;
    out.uv = v.uv;
    out.slice = min(fur.atlas_layers - 1u, (layer * fur.atlas_layers) / fur.drawn_layers);
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
fn fs_shell(in: ShellOut) -> @location(0) vec4<f32> {
    // Blending uses the mip chain (sparse tips fade into a haze at a distance); an alpha test
    // reads level 0, because averaged mips would fall below the threshold and bald the tips.
    var alpha: f32;
    if ALPHA_BLEND {
        alpha = textureSample(shell_alpha, repeat_sampler, in.uv, in.slice).r;
    } else {
        alpha = textureSampleLevel(shell_alpha, repeat_sampler, in.uv, in.slice, 0.0).r;
    }
    if alpha <= fur.alpha_threshold {
        discard;
    }
    var shade = lambert(in.normal);
    if SHADOW {
        shade = shade * shadow[in.slice];
    }
    let rgb = in.color.rgb * fur.tint.rgb * shade;
    if ALPHA_BLEND {
        return vec4<f32>(rgb, alpha);
    }
    return vec4<f32>(rgb, 1.0);
}
