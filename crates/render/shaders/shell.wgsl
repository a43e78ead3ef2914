// shell.wgsl — shell layers (fur thesis §3.2, fig. 3.10–3.12) drawn instanced, one instance per
// layer, innermost first (instances rasterise in order, so blending is back-to-front along each
// hair). Blended shells are drawn twice (docs/design.md "Shell order"): first their back faces
// (front faces culled) as instances layers … 2·layers − 1, outermost first, then their front faces
// (back faces culled) as instances 0 … layers − 1, innermost first — so that where a ray grazes a
// silhouette and crosses the coat twice, the far side blends before the near side. Each corner is
// extruded along its normal by t·fur_length (t = (layer+1)/layers) and sheared towards its
// scale vector s by t^k·(s − n)·fur_length (eq. 3.35–3.36, §3.4.2); the scale vectors live in a
// storage buffer the physics rewrites every frame (initially s = n, i.e. no shear), one per welded
// vertex or — separable topologies, parted fur (§3.4.1) — one per triangle corner, so two
// triangles sharing a vertex can shear apart. Fragment: alpha from the
// shell texture array; colour = the strand shading (fur_common.wgsl `strand_shade`, docs/design.md
// "Fur shading") of vertex colour × tint along the layer's hair direction (`strand_tangent`, the
// eq. 3.36 derivative), at the layer's height, with its self-shadow factor and the noise of the
// hair's texel — or, with STRAND off, vertex colour × tint × per-layer self-shadow × Lambert.
// An animated pack's shells grow from the skinning pass's posed vertices (fur_common.wgsl
// `posed_vertex`), so every layer reads one skinned root instead of re-skinning; its scale
// vectors are already in the posed mesh frame (the runtime poses the physics on the skinned
// surface, docs/design.md "Animated skins in the runtime").
// Prepended at load time: fur_common.wgsl (uniforms, switches, bindings 0–3 and 8, SurfaceIn,
// posed_vertex, shell_offset, strand_tangent, to_world, lambert, strand_shade). Also a compute
// entry point, `cs_shell_positions`, that reads back `shell_vertex` and `shell_tangent` for
// tests.

@group(0) @binding(4) var shell_alpha: texture_2d_array<f32>;
@group(0) @binding(5) var repeat_sampler: sampler;

struct ShellOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) slice: u32,
    // World-space hair direction (unit before interpolation).
    @location(4) tangent: vec3<f32>,
    @location(5) world: vec3<f32>,
    // Relative height the layer is shaded at: the middle of the slab it stands for,
    // (layer + 1)/layers − 0.5/count with count the view's continuous layer count (docs/design.md
    // "Rendering accuracy"), as the reference shades a hair at the height the ray meets it.
    @location(6) @interpolate(flat) height: f32,
    // Opacity of the layer in a level-of-detail transition (1 outside one).
    @location(7) @interpolate(flat) fade: f32,
};

// Object-space position of a skin vertex (welded index, bind position and normal, scale-vector
// index) on shell `layer` of `layers` (0 = innermost, t = (layer + 1)/layers): the extrusion and
// eq. 3.36 shear from the vertex's posed root. Used by the draw (`vs_shell`) and by the readback
// probe (`cs_shell_positions`), so tests compare exactly what is drawn with the CPU reference
// `furbake_sim::shell_vertex_position`.
fn shell_vertex(vertex_index: u32, position: vec3<f32>, normal: vec3<f32>, scale_at: u32, layer: u32, layers: u32) -> vec3<f32> {
    let t = f32(layer + 1u) / f32(layers);
    let root = posed_vertex(vertex_index, position, normal);
    let n = normalize(root.normal.xyz);
    let s = scale_vectors[scale_at].xyz;
    return root.position.xyz + shell_offset(n, s, t);
}

// Object-space hair direction at that shell vertex (`strand_tangent` at the layer's t); shared
// by the draw and the probe like `shell_vertex`.
fn shell_tangent(vertex_index: u32, position: vec3<f32>, normal: vec3<f32>, scale_at: u32, layer: u32, layers: u32) -> vec3<f32> {
    let t = f32(layer + 1u) / f32(layers);
    let n = normalize(posed_vertex(vertex_index, position, normal).normal.xyz);
    return strand_tangent(n, scale_vectors[scale_at].xyz, t);
}

// The stacking exponents of this asset (crates/render/src/stacking.rs, docs/design.md "Shell
// opacity"): [(angle · STACK_MIPS + mip) · STACK_COUNTS + count], angles 0°, 10°, …, 80° between
// the view and the hair, mips 0…5, drawn layer counts 1, 2, 4, …, 64.
@group(0) @binding(9) var<storage, read> stacking: array<f32>;
const STACK_ANGLES: u32 = 9u;
const STACK_MIPS: u32 = 6u;
const STACK_COUNTS: u32 = 7u;

fn stacking_at(angle: u32, mip: u32, count: u32) -> f32 {
    return stacking[(angle * STACK_MIPS + mip) * STACK_COUNTS + count];
}

// The alpha one shell layer blends for texel alpha `alpha`, seen along `to_eye` on a hair running
// along `tangent`, sampled at mip level `lod`: 1 − (1 − α)^e with e interpolated from the table
// between angles, mip levels and log2 of this view's continuous layer count, so that the stack
// lets through, on average, what the hair volume does.
fn stacked_alpha(alpha: f32, to_eye: vec3<f32>, tangent: vec3<f32>, lod: f32) -> f32 {
    if fur.stacking.x == 0.0 || alpha >= 1.0 {
        return alpha;
    }
    let angle = clamp(degrees(acos(clamp(abs(dot(to_eye, tangent)), 0.0, 1.0))) / 10.0, 0.0, f32(STACK_ANGLES - 1u));
    let mip = clamp(lod, 0.0, f32(STACK_MIPS - 1u));
    let count = clamp(log2(max(frame.shells.z, 1.0)), 0.0, f32(STACK_COUNTS - 1u));
    let a0 = min(u32(angle), STACK_ANGLES - 2u);
    let m0 = min(u32(mip), STACK_MIPS - 2u);
    let c0 = min(u32(count), STACK_COUNTS - 2u);
    let fa = angle - f32(a0);
    let fm = mip - f32(m0);
    let fc = count - f32(c0);
    var e = 0.0;
    for (var i = 0u; i < 8u; i++) {
        let da = i & 1u;
        let dm = (i >> 1u) & 1u;
        let dc = (i >> 2u) & 1u;
        let w = select(1.0 - fa, fa, da == 1u) * select(1.0 - fm, fm, dm == 1u) * select(1.0 - fc, fc, dc == 1u);
        e += w * log2(stacking_at(a0 + da, m0 + dm, c0 + dc));
    }
    return 1.0 - pow(1.0 - alpha, exp2(e));
}

// The 4×4 Bayer threshold of pixel `xy`, in (0, 1).
fn dither_4x4(xy: vec2<f32>) -> f32 {
    let p = vec2<u32>(xy) % vec2<u32>(4u);
    let bayer = array<u32, 16>(0u, 8u, 2u, 10u, 12u, 4u, 14u, 6u, 3u, 11u, 1u, 9u, 15u, 7u, 13u, 5u);
    return (f32(bayer[p.y * 4u + p.x]) + 0.5) / 16.0;
}

// The atlas slice shell `layer` of `layers` samples: the slab that holds its height
// t = (layer + 1)/layers, so a layer keeps its slice when the level of detail halves the count
// (layer 2i + 1 of 2N is layer i of N). The CPU twin is `ShellAtlas::slice_for`.
fn shell_slice(layer: u32, layers: u32) -> u32 {
    let a = fur.atlas_layers;
    return min(a - 1u, ((layer + 1u) * a + layers - 1u) / layers - 1u);
}

@vertex
fn vs_shell(v: SurfaceIn, @builtin(instance_index) instance: u32) -> ShellOut {
    // This view's level of detail (docs/design.md "Shell level of detail").
    let layers = max(u32(frame.shells.x), 1u);
    // Instances past the layer count are the back faces' pass, outermost layer first.
    let layer = select(instance, 2u * layers - 1u - instance, instance >= layers);
    let scale_at = scale_index(v.vertex_index, v.corner_index);
    let world = to_world(shell_vertex(v.vertex_index, v.position, v.normal, scale_at, layer, layers));
    var out: ShellOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = normal_to_world(posed_vertex(v.vertex_index, v.position, v.normal).normal.xyz);
    out.color = v.color;
    out.uv = v.uv;
    out.slice = shell_slice(layer, layers);
    out.world = world;
    out.height = f32(layer + 1u) / f32(layers) - 0.5 / max(frame.shells.z, 1.0);
    // A transition between two levels draws the upper level's layers and fades in those the
    // lower one lacks (the even-indexed ones).
    out.fade = select(1.0, frame.shells.y, layer % 2u == 0u);
    if STRAND {
        out.tangent = normal_to_world(shell_tangent(v.vertex_index, v.position, v.normal, scale_at, layer, layers));
    } else {
        out.tangent = out.normal;
    }
    return out;
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
    // One pixel's change of alpha, for alpha to coverage only (taken where control flow is
    // still uniform).
    var edge = 0.0;
    if ALPHA_TO_COVERAGE {
        edge = fwidth(alpha);
    }
    // The mip level the blending samples at (taken where control flow is still uniform): an
    // anisotropic sampler (clamp fur.stacking.y, `RenderSettings::anisotropy`) takes it from the
    // pixel footprint's short axis, unless the footprint is longer than the clamp times that.
    var lod = 0.0;
    if ALPHA_BLEND {
        let texel = in.uv * vec2<f32>(textureDimensions(shell_alpha));
        let across = length(dpdx(texel));
        let down = length(dpdy(texel));
        lod = log2(max(max(min(across, down), max(across, down) / max(fur.stacking.y, 1.0)), 1e-6));
    }
    if alpha_discarded(alpha, edge) {
        discard;
    }
    // A layer fading in or out with the level of detail: blended shells scale its alpha, opaque
    // ones keep an ordered-dither share of its pixels.
    if in.fade < 1.0 && !ALPHA_BLEND && in.fade <= dither_4x4(in.clip.xy) {
        discard;
    }
    let to_eye = normalize(frame.camera_pos.xyz - in.world);
    if ALPHA_BLEND {
        alpha = stacked_alpha(alpha, to_eye, normalize(in.tangent), lod) * in.fade;
    }
    var rgb: vec3<f32>;
    if STRAND && LAMBERT {
        var direct = 1.0;
        if SHADOW {
            direct = shadow[in.slice];
        }
        // The hair on this texel (the same texel on every layer: the same hair).
        let size = vec2<f32>(textureDimensions(shell_alpha));
        let cell = vec2<i32>(min(floor(fract(in.uv) * size), size - 1.0));
        let albedo = in.color.rgb * fur.tint.rgb;
        rgb = strand_shade(albedo, in.normal, in.tangent, in.world, to_eye, in.height, direct, strand_mask(cell.x, cell.y));
    } else {
        var shade = lambert(in.normal, in.world);
        if SHADOW {
            shade = shade * shadow[in.slice];
        }
        rgb = in.color.rgb * fur.tint.rgb * shade;
    }
    if ALPHA_BLEND {
        return vec4<f32>(rgb, alpha);
    }
    if ALPHA_TO_COVERAGE {
        return vec4<f32>(rgb, coverage_alpha(alpha, edge));
    }
    return vec4<f32>(rgb, 1.0);
}

// Readback probe: one shell vertex (bind position and normal, xyz of each; w unused, and its
// welded vertex index for the posed root), in the scale-vector buffer's order (welded vertices,
// or triangle corners when Fur.scale_layout = 1).
struct ProbeVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
    vertex_index: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(1) @binding(0) var<storage, read> probe_vertices: array<ProbeVertex>;
// Output, layer-major: probe_out[layer · vertices + vertex] = object-space shell position.
@group(1) @binding(1) var<storage, read_write> probe_out: array<vec4<f32>>;
// Output, in the same order: probe_tangents[i] = object-space hair direction (`shell_tangent`).
@group(1) @binding(2) var<storage, read_write> probe_tangents: array<vec4<f32>>;

// Evaluates `shell_vertex` and `shell_tangent` for every (layer, vertex) pair, in object space
// (no model transform).
@compute @workgroup_size(64)
fn cs_shell_positions(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    let count = arrayLength(&probe_vertices);
    if count == 0u || i >= count * fur.drawn_layers {
        return;
    }
    let v = i % count;
    let layer = i / count;
    let p = probe_vertices[v];
    probe_out[i] = vec4<f32>(shell_vertex(p.vertex_index, p.position.xyz, p.normal.xyz, v, layer, fur.drawn_layers), 1.0);
    probe_tangents[i] = vec4<f32>(shell_tangent(p.vertex_index, p.position.xyz, p.normal.xyz, v, layer, fur.drawn_layers), 0.0);
}
