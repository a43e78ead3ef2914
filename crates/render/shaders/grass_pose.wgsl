// grass_pose.wgsl — the expensive half of a blade's pose, shared by the blade draw (blades.wgsl:
// `cs_blades`) and the culling passes (blade_cull.wgsl, which evaluate it once per drawn blade
// and store it in the instance list, so the vertex shader only picks keys and decodes): the
// blade's force from its cluster's corner forces and the delayed wind sources, turned into
// continuous pose-grid coordinates. Prepended after grass_common.wgsl; each module declares the
// bindings it reads (`params`, `blades`, `corner_forces`, `delayed`, `delayed_directions`).

struct BladeUniforms {
    // Linear RGB blade colour; a unused.
    color: vec4<f32>,
    blade_count: u32,
    // Vertices per blade.
    vertex_count: u32,
    // Stored vectors per stored pose.
    stored_vectors: u32,
    // Stored angles per magnitude (angles / symmetry factor).
    stored_angles: u32,
    // Magnitude samples (zero force excluded).
    magnitudes: u32,
    // Angle samples over the full circle.
    angles: u32,
    // 1: angles in the mirrored half are stored negated in x.
    mirror_x: u32,
    // 1: angles in the mirrored quarter are stored negated in z.
    mirror_z: u32,
    // magnitudes / max_force.
    magnitude_per_force: f32,
    // angles / 2π.
    angle_per_radian: f32,
    // Dequantisation scale of the payload (1 for the float encodings).
    scale: f32,
    // 0 f32, 1 snorm16, 2 f16, 3 unorm8, 4 snorm8.
    encoding: u32,
    // 0 nearest, 1 linear.
    interpolation: u32,
    // 1: Lambert diffuse; 0: unlit colour.
    lambert: u32,
    // Wind sources with delayed attenuation this frame (grass thesis §4.5, fig. 4.8).
    delayed_sources: u32,
    // Cluster grid corners (stride of `delayed_directions`).
    corner_count: u32,
    // Cells along x of the cluster grid.
    cells_x: u32,
    // Seed of the per-blade and per-clump colour variation (the blade field's bake seed).
    seed: u32,
    // 1: the blade shading of `BladeShading` (blades.wgsl `fs_blade`); 0: flat colour × Lambert.
    shading: u32,
    pad0: u32,
    // rgb: linear colour at the tip (the root takes `color`).
    tip_color: vec4<f32>,
    // x root occlusion, y blade variation, z clump variation, w translucency (all 0..1).
    shade: vec4<f32>,
    // x gloss (0..1), y gloss exponent, z normal rounding (0..1), w edge darkening (0..1).
    gloss: vec4<f32>,
};

// A wind source with delayed attenuation (eq. 4.1 evaluated per blade).
struct DelayedSource {
    // xyz: position W in metres; w: emissive power ω.
    position_power: vec4<f32>,
    // x: concentration σ; y: lower clamp of distances in metres; zw unused.
    params: vec4<f32>,
};

const PI: f32 = 3.14159265358979;
const TAU: f32 = 6.28318530717959;

// The same minimax polynomial as furbake-grass's `fast_atan2` (to within 2e-5 rad).
fn fast_atan2(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    let lo = min(ax, ay);
    let hi = max(ax, ay);
    if hi == 0.0 {
        return 0.0;
    }
    let a = lo / hi;
    let s = a * a;
    var r = ((((0.0208351 * s - 0.085133) * s + 0.180141) * s - 0.3302995) * s + 0.999866) * a;
    if ay > ax {
        r = PI * 0.5 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        r = -r;
    }
    return r;
}

// eq. 3.6 and eq. 3.10–3.11: the blade's force from its cluster's four corner forces (plus the
// delayed sources), in blade-local coordinates, as continuous grid coordinates: magnitude
// μ ∈ [0, magnitudes] and angle α (sample j at j), as `KeyframeDecoder::grid_coordinates`.
fn blade_grid(b: u32) -> vec2<f32> {
    let blade = blades[b];
    let corners = cluster_corners(blade.cluster, params.cells_x);
    var f = vec2<f32>(0.0);
    for (var k = 0u; k < 4u; k++) {
        f += corner_forces[corners[k]] * blade.weights[k];
    }
    // Delayed attenuation (as `ForceField::blade_force`): the interpolated direction, normalised,
    // times the magnitude of the source's exact wind at the blade root.
    for (var i = 0u; i < params.delayed_sources; i++) {
        var dir = vec2<f32>(0.0);
        for (var k = 0u; k < 4u; k++) {
            dir += delayed_directions[i * params.corner_count + corners[k]] * blade.weights[k];
        }
        let len = length(dir);
        let rcp = 1.0 / len;
        if len > 0.0 && rcp < 3.0e38 {
            dir = dir * rcp;
        } else {
            dir = vec2<f32>(0.0);
        }
        let src = delayed[i];
        let wp = blade.root.xyz - src.position_power.xyz;
        let d = length(wp);
        if d != 0.0 {
            let unit = wp / d;
            let strength = src.position_power.w / pow(max(d, src.params.y), src.params.x);
            f += dir * length(unit.xz * strength);
        }
    }
    let c = blade.yaw.x;
    let s = blade.yaw.y;
    // Force along the width axis and along the normal.
    let lx = f.x * c - f.y * s;
    let ly = f.x * s + f.y * c;
    let mag = length(vec2<f32>(lx, ly));
    let mu = clamp(mag * params.magnitude_per_force, 0.0, f32(params.magnitudes));
    var theta = fast_atan2(lx, ly);
    if theta < 0.0 {
        theta += TAU;
    }
    return vec2<f32>(mu, theta * params.angle_per_radian - 0.5);
}
