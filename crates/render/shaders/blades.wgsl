// blades.wgsl — instanced grass blades (grass thesis §3.2.5–3.2.6, §4.2), the GPU twin of
// furbake-grass's `KeyframeDecoder::world_positions`. A compute pass (`cs_blades`, one thread per
// blade) interpolates the blade's force from its four cluster corner forces (eq. 3.6; plus the
// wind sources with delayed attenuation, fig. 4.8, evaluated at the blade), turns it into
// blade-local grid coordinates (`blade_grid`, grass_pose.wgsl), selects the keyframe pose from
// its magnitude and its angle to the blade normal (`pose_from`: eq. 3.10–3.12, nearest, or linear
// in-betweening eq. 3.13), decodes the stored displacements from packed u32 words (f32, snorm16,
// f16, unorm8 or snorm8) with the mirror flags of fig. 3.8–3.9, and writes world-space vertex
// positions to a storage buffer. The draw (`vs_blade` / `fs_blade`) takes each instance's blade
// and grid coordinates from the instance lists (blade_cull.wgsl), poses its vertices with the
// same functions (`pose_from`, `vertex_position`) and shades it (`fs_blade`: the grass thesis's
// fig. 4.1 pipeline and what shipped grass adds, docs/design.md "Grass blade shading"), or, with
// shading off, two-sided Lambert diffuse of a flat colour. lighting.wgsl (the frame uniforms and the lights), grass_common.wgsl (the Blade struct, the culling parameters) and
// grass_pose.wgsl (the uniform and source structs, `blade_grid`) are prepended.

const STATIC_VERTEX: u32 = 0xffffffffu;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> params: BladeUniforms;
@group(0) @binding(2) var<storage, read> blades: array<Blade>;
@group(0) @binding(3) var<storage, read> corner_forces: array<vec2<f32>>;
@group(0) @binding(4) var<storage, read> payload: array<u32>;
@group(0) @binding(5) var<storage, read> vertex_map: array<u32>;
@group(0) @binding(6) var<storage, read> reference: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> delayed: array<DelayedSource>;
// Per delayed source, per grid corner: the source's unit horizontal direction (x, z) at the
// corner (zero where blocked), source-major.
@group(0) @binding(8) var<storage, read> delayed_directions: array<vec2<f32>>;

// The frame's culling parameters and the instance lists of the culling passes (blade_cull.wgsl):
// words 0..4 the start of each LOD's list (in entries), then the entries (blade, μ, α).
@group(0) @binding(9) var<uniform> cull: CullUniforms;
@group(0) @binding(10) var<storage, read> instances: array<u32>;

// Written by the compute pass only.
@group(1) @binding(0) var<storage, read_write> positions_out: array<vec4<f32>>;

// IEEE binary16 bits → f32, exactly (no shader-f16 feature or unpack builtin needed).
fn f16_to_f32(h: u32) -> f32 {
    let sign = (h & 0x8000u) << 16u;
    let e = (h >> 10u) & 0x1fu;
    let m = h & 0x3ffu;
    if e == 0u {
        // Zero or subnormal: m × 2^-24.
        let v = f32(m) * 5.9604645e-8;
        return select(v, -v, sign != 0u);
    }
    if e == 31u {
        return bitcast<f32>(sign | 0x7f800000u | (m << 13u));
    }
    return bitcast<f32>(sign | ((e + 112u) << 23u) | (m << 13u));
}

// Stored displacement component `i` (pose-major, vector-major, xyz), dequantised.
fn component(i: u32) -> f32 {
    switch params.encoding {
        case 1u: {
            let bits = (payload[i >> 1u] >> ((i & 1u) * 16u)) & 0xffffu;
            let q = bitcast<i32>(bits << 16u) >> 16u;
            return f32(q) / 32767.0 * params.scale;
        }
        case 2u: {
            return f16_to_f32((payload[i >> 1u] >> ((i & 1u) * 16u)) & 0xffffu);
        }
        case 3u: {
            let q = (payload[i >> 2u] >> ((i & 3u) * 8u)) & 0xffu;
            return (f32(q) * (2.0 / 255.0) - 1.0) * params.scale;
        }
        case 4u: {
            let bits = (payload[i >> 2u] >> ((i & 3u) * 8u)) & 0xffu;
            let q = bitcast<i32>(bits << 24u) >> 24u;
            return f32(q) / 127.0 * params.scale;
        }
        default: {
            return bitcast<f32>(payload[i]);
        }
    }
}

// Displacement of vertex `v` in the represented pose (magnitude key `m`, 0 = zero force; angle
// sample `j` of the full circle), with the symmetry mirror of fig. 3.8.
fn displacement(m: u32, j_full: u32, v: u32) -> vec3<f32> {
    if m == 0u {
        return vec3<f32>(0.0);
    }
    let mapped = vertex_map[v];
    if mapped == STATIC_VERTEX {
        return vec3<f32>(0.0);
    }
    let a = params.angles;
    var j = j_full;
    var flip_x = false;
    var flip_z = false;
    if params.mirror_x != 0u && j >= a / 2u {
        j = a - 1u - j;
        flip_x = true;
    }
    if params.mirror_z != 0u && j >= a / 4u {
        j = a / 2u - 1u - j;
        flip_z = true;
    }
    let pose = (m - 1u) * params.stored_angles + j;
    let base = (pose * params.stored_vectors + mapped) * 3u;
    var d = vec3<f32>(component(base), component(base + 1u), component(base + 2u));
    if flip_x {
        d.x = -d.x;
    }
    if flip_z {
        d.z = -d.z;
    }
    return d;
}

fn wrap_angle(j: i32) -> u32 {
    let a = i32(params.angles);
    return u32(((j % a) + a) % a);
}

// A blade's pose for this frame: the keys and weights of the selected keyframes and the blade's
// frame (root, height scale, width axis, normal).
struct Pose {
    keys_m: vec4<u32>,
    keys_j: vec4<u32>,
    weights: vec4<f32>,
    // Keys used: 1 (nearest) or 4 (linear).
    count: u32,
    root: vec3<f32>,
    height: f32,
    width: vec3<f32>,
    normal: vec3<f32>,
};

// eq. 3.10–3.13: the poses around the blade's grid coordinates `grid` (magnitude μ, angle α from
// `blade_grid`) and the blade's frame (as `KeyframeDecoder::select`).
fn pose_from(b: u32, grid: vec2<f32>) -> Pose {
    let blade = blades[b];
    let c = blade.yaw.x;
    let s = blade.yaw.y;
    var pose: Pose;
    pose.width = vec3<f32>(c, 0.0, -s);
    pose.normal = vec3<f32>(s, 0.0, c);
    pose.root = blade.root.xyz;
    pose.height = blade.root.w;
    let mu = grid.x;
    let alpha = grid.y;
    pose.keys_m = vec4<u32>(0u);
    pose.keys_j = vec4<u32>(0u);
    pose.weights = vec4<f32>(1.0, 0.0, 0.0, 0.0);
    pose.count = 1u;
    if params.interpolation == 0u {
        // Nearest (ties round up); alpha ≥ −0.5, so truncation after + 0.5 rounds.
        var j = u32(alpha + 0.5);
        if j >= params.angles {
            j -= params.angles;
        }
        pose.keys_m.x = min(u32(mu + 0.5), params.magnitudes);
        pose.keys_j.x = j;
    } else {
        let m0 = max(min(floor(mu), f32(params.magnitudes) - 1.0), 0.0);
        let tm = clamp(mu - m0, 0.0, 1.0);
        let j0f = floor(alpha);
        let ta = clamp(alpha - j0f, 0.0, 1.0);
        let m0u = u32(m0);
        let j0 = wrap_angle(i32(j0f));
        let j1 = wrap_angle(i32(j0f) + 1);
        pose.keys_m = vec4<u32>(m0u, m0u, m0u + 1u, m0u + 1u);
        pose.keys_j = vec4<u32>(j0, j1, j0, j1);
        pose.weights = vec4<f32>((1.0 - tm) * (1.0 - ta), (1.0 - tm) * ta, tm * (1.0 - ta), tm * ta);
        pose.count = 4u;
    }
    return pose;
}

// World position of vertex `v` of a posed blade (as `KeyframeDecoder::world_positions`), its
// width across the blade (the reference's x) times `widen`.
fn vertex_position(pose: Pose, v: u32, widen: f32) -> vec3<f32> {
    var d = vec3<f32>(0.0);
    for (var k = 0u; k < pose.count; k++) {
        d += displacement(pose.keys_m[k], pose.keys_j[k], v) * pose.weights[k];
    }
    let r = reference[v].xyz;
    let p = r + d + vec3<f32>(r.x * (widen - 1.0), 0.0, 0.0);
    return pose.root + (pose.width * p.x + vec3<f32>(0.0, p.y, 0.0) + pose.normal * p.z) * pose.height;
}

// Poses every blade once and writes its vertices (for readback and for callers that reuse them).
@compute @workgroup_size(64)
fn cs_blades(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let b = gid.x + gid.y * groups.x * 64u;
    if b >= params.blade_count {
        return;
    }
    let pose = pose_from(b, blade_grid(b));
    let vc = params.vertex_count;
    for (var v = 0u; v < vc; v++) {
        positions_out[b * vc + v] = vec4<f32>(vertex_position(pose, v, 1.0), 1.0);
    }
}

struct BladeOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    // u across the blade (0 left … 1 right), v along it (0 root … 1 tip).
    @location(1) uv: vec2<f32>,
    // The blade's width axis in world space (the direction of increasing u).
    @location(2) width_axis: vec3<f32>,
    // x: the blade, y: its clump (cluster).
    @location(3) @interpolate(flat) ids: vec2<u32>,
    // 0 near, rising to 1 at the culling distance: how far the blade's normal and colour have
    // faded towards the ground's (a far field neither shimmers nor shows a seam where it ends).
    @location(4) @interpolate(flat) fade: f32,
};

// Where the distance fade starts, as a share of the culling distance.
const FADE_START: f32 = 0.6;

// (u, v) of reference vertex `v` (furbake-grass `ReferenceBlade`: segment k owns vertices 4k..4k+4
// = left-bottom, right-bottom, left-top, right-top; level k + (v mod 4)/2 of `segments`).
fn blade_uv(v: u32) -> vec2<f32> {
    let segments = max(params.vertex_count / 4u, 1u);
    let level = v / 4u + (v % 4u) / 2u;
    return vec2<f32>(f32(v & 1u), f32(level) / f32(segments));
}

// The draw reads each instance's blade and its pose-grid coordinates from the instance lists the
// compute passes wrote (blade_cull.wgsl: once per drawn blade), so each vertex only picks its
// keys and decodes its own displacement. The index buffer holds one index list per level of
// detail, LOD l's indices offset by l × vertex_count, so the vertex index names both; only the
// vertices a level draws are decoded. Instance i of LOD l is the entry at list start
// `instances[l]` + i: (blade, μ, α) in three words. With culling on, a blade is drawn wider by the
// inverse of the fraction distance thinning kept.
@vertex
fn vs_blade(@builtin(vertex_index) vi: u32, @builtin(instance_index) instance: u32) -> BladeOut {
    let lod = vi / params.vertex_count;
    let v = vi - lod * params.vertex_count;
    let entry = 4u + 3u * (instances[lod] + instance);
    let b = instances[entry];
    let grid = vec2<f32>(bitcast<f32>(instances[entry + 1u]), bitcast<f32>(instances[entry + 2u]));
    let pose = pose_from(b, grid);
    // The eye in the pack frame (the model matrix is a rotation, a translation and a uniform
    // scale s: its inverse on points is M₃ᵀ(p − t)/s²), with culling on or off alike.
    let m3 = mat3x3<f32>(frame.model[0].xyz, frame.model[1].xyz, frame.model[2].xyz);
    let eye = transpose(m3) * (frame.camera_pos.xyz - frame.model[3].xyz) / max(dot(m3[0], m3[0]), 1e-12);
    let to_eye = eye - blades[b].root.xyz;
    let d = length(to_eye);
    var widen = 1.0;
    var fade = 0.0;
    if cull.eye.w != 0.0 {
        widen = 1.0 / thinning_keep(cull.distance.y, cull.distance.z, d);
        let far = sqrt(cull.distance.x);
        fade = smoothstep(FADE_START * far, far, d);
    }
    // The share of the width seen from the eye, and the view-space side to thicken along.
    var thicken = vec3<f32>(0.0);
    let view = to_eye / max(d, 1e-6);
    let width_axis = normalize(pose.width);
    let along = dot(width_axis, view);
    let seen = sqrt(max(1.0 - along * along, 0.0));
    let side = cross(vec3<f32>(0.0, 1.0, 0.0), view);
    // Thickened to the share `cull.shape.z` of the width (`culling::EDGE_ON_WIDTH`).
    if seen < cull.shape.z && dot(side, side) > 1e-8 {
        let s = normalize(side) * sign(dot(side, width_axis) + 1e-9);
        thicken = s * (reference[v].x * widen * pose.height * (cull.shape.z - seen));
    }
    let world = (frame.model * vec4<f32>(vertex_position(pose, v, widen) + thicken, 1.0)).xyz;
    var out: BladeOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.world = world;
    out.uv = blade_uv(v);
    out.width_axis = normalize((frame.model * vec4<f32>(pose.width, 0.0)).xyz);
    out.ids = vec2<u32>(b, blades[b].cluster);
    out.fade = fade;
    return out;
}

// Linear colour of a blade before lighting: `color` at the root to `tip_color` at the tip, its
// clump turned towards a dry green and its brightness spread, both from the bake's seed.
fn blade_albedo(ids: vec2<u32>, v: f32) -> vec3<f32> {
    var albedo = mix(params.color.rgb, params.tip_color.rgb, v);
    // grass_common.wgsl's per-blade random numbers, salted by the bake's seed (a clump's by its
    // cluster index).
    let clump = blade_random(ids.y, params.seed ^ 0x1b873593u);
    let dry = vec3<f32>(0.50, 0.52, 0.16) * dot(albedo, vec3<f32>(0.35, 0.55, 0.10)) * 2.2;
    albedo = mix(albedo, dry, params.shade.z * clump * clump);
    let blade = blade_random(ids.x, params.seed ^ 0x632be5abu);
    return albedo * (1.0 + params.shade.y * (blade - 0.5));
}

@fragment
fn fs_blade(in: BladeOut) -> @location(0) vec4<f32> {
    if params.shading != 0u {
        return vec4<f32>(shade_blade(in), 1.0);
    }
    var shade = vec3<f32>(1.0);
    if params.lambert != 0u {
        // Flat face normal from the screen-space derivatives; blades are two-sided, so the side
        // facing each light is lit, and the ambient comes from the side facing up.
        let n = normalize(cross(dpdx(in.world), dpdy(in.world)));
        shade = ambient_at(select(n, -n, n.y < 0.0));
        for (var i = 0u; i < light_count(); i++) {
            let light = light_at(i, in.world);
            shade += light.radiance * abs(dot(n, light.l));
        }
    }
    return vec4<f32>(params.color.rgb * shade, 1.0);
}

// The blade shading (docs/design.md "Grass blade shading"). The face normal comes from the
// screen-space derivatives, turned towards the viewer (blades are two-sided) and rounded
// outwards across the width; diffuse is Lambert on the side facing the light plus translucency
// when the light is behind the blade; v-shadowing darkens the root, edge darkening the sides
// (fig. 4.1's alpha × diffuse); a normalised Blinn–Phong gloss rises towards the tip.
fn shade_blade(in: BladeOut) -> vec3<f32> {
    let v = clamp(in.uv.y, 0.0, 1.0);
    let across = clamp(in.uv.x, 0.0, 1.0) * 2.0 - 1.0;
    let albedo = blade_albedo(in.ids, v);
    if params.lambert == 0u {
        return albedo;
    }
    let to_eye = normalize(frame.camera_pos.xyz - in.world);
    var n = normalize(cross(dpdx(in.world), dpdy(in.world)));
    n = select(n, -n, dot(n, to_eye) < 0.0);
    n = normalize(n + in.width_axis * (across * params.gloss.z));
    // Far blades fade towards the ground under them: its normal (up) and its colour (the root
    // colour at half the root occlusion, `BladeSettings::ground_tint`).
    n = normalize(mix(n, vec3<f32>(0.0, 1.0, 0.0), in.fade));
    let albedo_faded = mix(albedo, params.color.rgb, in.fade);
    // Light through the blade (from behind: the side away from the viewer is lit) is stronger
    // towards the thinner tip and looking into the light.
    let occlusion = mix(1.0 - params.shade.x * (1.0 - smoothstep(0.0, 1.0, v)), 1.0 - 0.5 * params.shade.x, in.fade);
    let edge = mix(1.0 - params.gloss.w * pow(abs(across), 3.0), 1.0, in.fade);
    let e = params.gloss.y;
    let gloss_scale = params.gloss.x * v * v * (e + 8.0) / 25.1327412;
    var lit = vec3<f32>(0.0);
    for (var i = 0u; i < light_count(); i++) {
        let light = light_at(i, in.world);
        let l = light.l;
        let front = max(dot(n, l), 0.0);
        let forward = max(dot(-to_eye, l), 0.0);
        let back = max(dot(-n, l), 0.0) * params.shade.w * (0.4 + 0.6 * v) * (0.6 + 0.4 * forward * forward);
        let h = normalize(l + to_eye);
        let gloss = gloss_scale * pow(max(dot(n, h), 0.0), e) * front;
        lit += light.radiance * (albedo_faded * (front + 1.2 * back) * edge + vec3<f32>(gloss * (1.0 - in.fade)));
    }
    return (albedo_faded * ambient_at(n) * edge + lit) * occlusion;
}
