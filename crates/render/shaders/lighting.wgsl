// lighting.wgsl — the frame uniforms every drawing shader reads (checked against their Rust twin
// `FrameUniforms` in crates/render/src/shaders.rs) and what they are lit by: up to four
// directional and point lights and a hemisphere ambient term (docs/design.md "Lights"). The
// renderer prepends this file to the skin, shell, fin and blade shaders, each of which binds
// `frame` at group 0, binding 0.

// One light source. Directional: `vector.xyz` is the unit vector from the surface towards the
// light and `vector.w` 0. Point: `vector.xyz` is its position in world metres and `vector.w` 1.
struct Light {
    vector: vec4<f32>,
    // rgb: colour × intensity; a: a point light's range in metres (0: unbounded).
    radiance: vec4<f32>,
};

struct Frame {
    view_proj: mat4x4<f32>,
    // xyz: eye position in metres; w unused.
    camera_pos: vec4<f32>,
    // rgb: ambient light from above (+Y) and from below; a unused.
    ambient_sky: vec4<f32>,
    ambient_ground: vec4<f32>,
    // x: how many of `lights` are lit (at most 4); yzw unused.
    light_count: vec4<u32>,
    lights: array<Light, 4>,
    // Model matrix of the drawn object (object/pack frame → world): rotation, translation and a
    // uniform positive scale. Identity for a single object.
    model: mat4x4<f32>,
    // xy: the target's width and height in pixels (0: not given); zw unused.
    viewport: vec4<f32>,
    // The shell level of detail of this view, written by the fur renderer (docs/design.md "Shell
    // level of detail"): x = shell layers drawn, y = opacity of the layers a transition is adding
    // (1 outside a transition), z = the continuous layer count the stacking reads; w unused. All
    // zero in the blade shaders.
    shells: vec4<f32>,
};

// The light `i` arriving at world position `world`: the unit vector towards it and its radiance
// there (a point light's falls off as 1/d², windowed to zero at its range by (1 − (d/range)⁴)²,
// Karis 2013).
struct LightSample {
    l: vec3<f32>,
    radiance: vec3<f32>,
};

fn light_count() -> u32 {
    return min(frame.light_count.x, 4u);
}

fn light_at(i: u32, world: vec3<f32>) -> LightSample {
    let light = frame.lights[i];
    if light.vector.w == 0.0 {
        return LightSample(light.vector.xyz, light.radiance.rgb);
    }
    let d = light.vector.xyz - world;
    let dist2 = max(dot(d, d), 1e-8);
    var falloff = 1.0 / dist2;
    if light.radiance.a > 0.0 {
        let r = dist2 / (light.radiance.a * light.radiance.a);
        let window = saturate(1.0 - r * r);
        falloff *= window * window;
    }
    return LightSample(d * inverseSqrt(dist2), light.radiance.rgb * falloff);
}

// The hemisphere ambient light on a surface with unit normal `n`.
fn ambient_at(n: vec3<f32>) -> vec3<f32> {
    return mix(frame.ambient_ground.rgb, frame.ambient_sky.rgb, 0.5 + 0.5 * n.y);
}
