// host.wgsl — the example host's own shaders (not furbake's): its world geometry (a ground plane
// and a box, flat colours with Lambert diffuse from the same light the fur sees) drawn into its
// HDR target, and the tonemap pass that turns the resolved HDR image into an sRGB one.

struct Camera {
    view_proj: mat4x4<f32>,
    // xyz: unit vector from the surface towards the light; w: ambient term.
    light_dir: vec4<f32>,
};

@group(0) @binding(0) var<uniform> camera: Camera;

struct GeometryIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec3<f32>,
};

struct GeometryOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec3<f32>,
};

@vertex
fn vs_geometry(v: GeometryIn) -> GeometryOut {
    var out: GeometryOut;
    out.clip = camera.view_proj * vec4<f32>(v.position, 1.0);
    out.normal = v.normal;
    out.color = v.color;
    return out;
}

@fragment
fn fs_geometry(in: GeometryOut) -> @location(0) vec4<f32> {
    let diffuse = max(dot(normalize(in.normal), camera.light_dir.xyz), 0.0);
    let ambient = camera.light_dir.w;
    return vec4<f32>(in.color * (ambient + (1.0 - ambient) * diffuse), 1.0);
}

// Tonemap: one full-screen triangle reading the resolved HDR texel under each pixel. Identity up
// to KNEE (so an LDR image passes through unchanged), then an exponential shoulder that maps
// [KNEE, ∞) onto [KNEE, 1).
@group(0) @binding(1) var hdr: texture_2d<f32>;

const KNEE: f32 = 0.8;

@vertex
fn vs_fullscreen(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

fn shoulder(x: f32) -> f32 {
    if x <= KNEE {
        return max(x, 0.0);
    }
    return KNEE + (1.0 - KNEE) * (1.0 - exp(-(x - KNEE) / (1.0 - KNEE)));
}

@fragment
fn fs_tonemap(@builtin(position) pixel: vec4<f32>) -> @location(0) vec4<f32> {
    let c = textureLoad(hdr, vec2<i32>(pixel.xy), 0);
    return vec4<f32>(shoulder(c.r), shoulder(c.g), shoulder(c.b), clamp(c.a, 0.0, 1.0));
}
