// fur_common.wgsl — what the skin, shell and fin shaders share after lighting.wgsl (the frame
// uniforms and the lights): the fur uniforms (checked against its #[repr(C)] Rust twin in
// crates/render/src/shaders.rs), the effect switches
// (pipeline-overridable constants, set from the scene's effects), the bindings of group 0, the
// surface vertex layout, the posed root of a vertex (the bind pose, or the skinning pass's output
// for an animated pack), the eq. 3.36 shell offset and the strand tangent (its derivative along
// the hair), the object→world model transform, Lambert shading and the strand shading
// (docs/design.md "Fur shading"). The renderer prepends this file to each of them (WGSL has no
// includes).

struct Fur {
    // rgb: colour multiplier applied to every vertex colour; a unused.
    tint: vec4<f32>,
    fur_length_m: f32,
    // Exponent k of eq. 3.36.
    shear_exponent: f32,
    // Fragments with alpha at or below this are discarded.
    alpha_threshold: f32,
    // Slices in the shell texture array.
    atlas_layers: u32,
    // The most shell layers a view draws (a view draws Frame.shells.x of them); the readback
    // probe evaluates this many.
    drawn_layers: u32,
    // Metres of edge per fin texture repeat (the shell texture's texel density).
    fin_repeat_m: f32,
    // How scale_vectors is indexed: 0 = per welded vertex (vertex_index), 1 = per triangle
    // corner, 3·triangle + corner (corner_index; separable topologies, where fur parts).
    scale_layout: u32,
    pad1: u32,
    // The strand shading's parameters (FurShading in crates/render/src/shading.rs; read only when
    // STRAND). rgb: colour multiplier at the hair tips (1 at the roots); a: ambient occlusion at
    // the roots (none at the tips).
    tip_color: vec4<f32>,
    // rgb: tint of the secondary highlight (× the fur colour); a: depth of its noise mask.
    secondary_tint: vec4<f32>,
    // x, y: primary highlight strength and exponent; z, w: secondary strength and exponent.
    specular: vec4<f32>,
    // x, y: primary and secondary shift; z: back-light strength; w: Kajiya–Kay share of the
    // diffuse term.
    strand: vec4<f32>,
    // x: 1 to blend the shells with the stacking exponents (shell.wgsl `stacked_alpha`,
    // docs/design.md "Shell opacity"), 0 to blend each layer's alpha as it is; yzw unused.
    stacking: vec4<f32>,
};

override LAMBERT: bool = true;
override SHADOW: bool = true;
// The strand shading (`strand_shade`) instead of Lambert × self-shadow; needs LAMBERT (unlit fur
// stays unlit). Off: exactly the earlier Lambert path.
override STRAND: bool = true;
// Eq. 3.36 shearing from the scale-vector buffer; off for static fur (s = n everywhere).
override SHEAR: bool = true;
// true: alpha-blended output; false: alpha-tested (opaque) output.
override ALPHA_BLEND: bool = true;
// With the alpha test on a multisampled target: the shells and fins write a coverage alpha
// (`coverage_alpha`) that the multisample mask turns into partial coverage of each pixel.
override ALPHA_TO_COVERAGE: bool = false;
// The pack is animated (skin weights or morph targets, glTF 2.0 "Skins", "Morph Targets"): the
// skinning pass (skinning.wgsl) writes this frame's posed welded vertices into `skinned`, and
// every stage reads its roots there by welded vertex index (no re-skinning per shell layer).
// false: the bind pose from the vertex attributes, exactly as for an unanimated pack.
override SKINNED: bool = false;
// How many of the frame's lights the fur's shading evaluates (`RenderSettings::light_slots`, a
// pipeline constant so the loop over them is unrolled: a loop over the frame's own count costs
// half again per fragment on lavapipe even when it runs once). Lights beyond it are not drawn.
override LIGHT_SLOTS: u32 = 2u;

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> fur: Fur;
// Per shell vertex (welded vertex or triangle corner, see Fur.scale_layout): xyz = unit scale
// vector s (eq. 3.35); w unused.
@group(0) @binding(2) var<storage, read> scale_vectors: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> shadow: array<f32>;

// One welded skin vertex as posed by the skinning pass: xyz position in metres (w = 1), xyz unit
// normal (w = 0). The same struct as skinning.wgsl's.
struct SkinnedVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
};

// This frame's posed welded vertices (the skinning pass's output), read only when SKINNED; a
// one-entry placeholder otherwise.
@group(0) @binding(8) var<storage, read> skinned: array<SkinnedVertex>;

struct SurfaceIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) vertex_index: u32,
    // bit 0: the triangle carries fur.
    @location(5) flags: u32,
    // 3·triangle + corner in the skin mesh's triangle order.
    @location(6) corner_index: u32,
};

// Index into scale_vectors of a corner with welded vertex `vertex_index` and triangle-corner id
// `corner_index`, for the buffer's current layout (Fur.scale_layout).
fn scale_index(vertex_index: u32, corner_index: u32) -> u32 {
    return select(vertex_index, corner_index, fur.scale_layout == 1u);
}

// The root of welded vertex `vertex_index` this frame: its skinned position and normal when
// SKINNED, else the bind pose `position` and `normal` from the vertex attributes.
fn posed_vertex(vertex_index: u32, position: vec3<f32>, normal: vec3<f32>) -> SkinnedVertex {
    if SKINNED {
        return skinned[vertex_index];
    }
    return SkinnedVertex(vec4<f32>(position, 1.0), vec4<f32>(normal, 0.0));
}

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

// Unit direction of the hair at relative height t above a vertex with unit normal n and scale
// vector s: the derivative of `shell_offset` along t, n + k·t^(k−1)·(s − n) (eq. 3.36), so it
// follows the fur as the physics moves it, and is n at rest (s = n) or without SHEAR. Where
// `shell_offset` lays the hair flat (an inward scale vector), the inward part is dropped here as
// well. The CPU twin is `furbake_render::shading::strand_tangent`.
fn strand_tangent(n: vec3<f32>, s: vec3<f32>, t: f32) -> vec3<f32> {
    if !SHEAR {
        return n;
    }
    let k = fur.shear_exponent;
    // t^(k−1) is unbounded at the root for k < 1; the skin side of a fin (t = 0) takes t = 1e-4.
    var d = n + k * pow(max(t, 1e-4), k - 1.0) * (s - n);
    if dot(n * t + pow(t, k) * (s - n), n) < 0.0 {
        d = d - dot(d, n) * n;
    }
    let len2 = dot(d, d);
    if !(len2 > 1e-12) {
        return n;
    }
    return d * inverseSqrt(len2);
}

// Object → world position.
fn to_world(p: vec3<f32>) -> vec3<f32> {
    return (frame.model * vec4<f32>(p, 1.0)).xyz;
}

// Alpha to coverage: the alpha test's step at the threshold widened to one pixel's change of
// alpha (`edge`, fwidth taken where control flow is still uniform), so the multisample coverage
// mask antialiases each hair's edge inside the shells instead of cutting it per pixel (the
// "sharpened alpha to coverage" of foliage renderers).
fn coverage_alpha(alpha: f32, edge: f32) -> f32 {
    return saturate((alpha - fur.alpha_threshold) / max(edge, 1e-4) + 0.5);
}

// Whether the fragment with this alpha is discarded: at or below the threshold, or with alpha
// to coverage where even its widened step covers nothing.
fn alpha_discarded(alpha: f32, edge: f32) -> bool {
    if ALPHA_TO_COVERAGE {
        return coverage_alpha(alpha, edge) <= 0.0;
    }
    return alpha <= fur.alpha_threshold;
}

// Object → world direction of a normal (exact for rotation + uniform scale).
fn normal_to_world(n: vec3<f32>) -> vec3<f32> {
    return normalize((frame.model * vec4<f32>(n, 0.0)).xyz);
}

// Lambert diffuse (fur thesis §3.2) of every light at `world` plus the ambient term.
fn lambert(n_in: vec3<f32>, world: vec3<f32>) -> vec3<f32> {
    if !LAMBERT {
        return vec3<f32>(1.0);
    }
    let n = normalize(n_in);
    var rgb = ambient_at(n);
    let count = light_count();
    for (var i = 0u; i < LIGHT_SLOTS; i++) {
        if i < count {
            let light = light_at(i, world);
            rgb += light.radiance * max(dot(n, light.l), 0.0);
        }
    }
    return rgb;
}

// A deterministic number in [0, 1) per integer cell (the PCG hash of Jarzynski & Olano 2020,
// "Hash Functions for GPU Rendering"): the per-hair noise of the secondary highlight, keyed by
// the shell or fin texel a hair stands on, so one hair is masked alike on every layer.
fn cell_noise(x: i32, y: i32) -> f32 {
    var h = bitcast<u32>(x) * 747796405u + 2891336453u;
    h = h ^ (bitcast<u32>(y) * 277803737u);
    h = ((h >> ((h >> 28u) + 4u)) ^ h) * 277803737u;
    h = (h >> 22u) ^ h;
    return f32(h >> 8u) / 16777216.0;
}

// One highlight lobe of the strand specular (th = T·H, sin_th = sin(T, H)): Kajiya–Kay's
// sin(T', H)^p of the tangent T' shifted by `shift` (Scheuermann 2004: T' = normalize(T +
// shift·N)), where N is the strand's normal on H's side, the unit vector perpendicular to T in
// the plane of T and H (on a hair lying in the surface and lit from outside, that is the surface
// normal), so T'·H = (T·H + shift·sin(T, H)) / √(1 + shift²) and the lobe is defined for hair
// standing along the normal too. Normalised by
// (p + 2)/(2π), as Unity HDRP's Kajiya–Kay lobe, so a narrower highlight is brighter, not dimmer.
fn strand_lobe(th: f32, sin_th: f32, shift: f32, exponent: f32) -> f32 {
    let shifted = (th + shift * sin_th) * inverseSqrt(1.0 + shift * shift);
    let sin2 = max(1.0 - shifted * shifted, 0.0);
    return (exponent + 2.0) * 0.15915494 * pow(sin2, 0.5 * exponent);
}

// The strand shading (docs/design.md "Fur shading") at world position `world` of fur with colour
// `albedo` (vertex colour × tint), surface normal `n`, hair direction `tangent`
// (`strand_tangent`), unit vector `to_eye`, relative height `h` in [0, 1] (0 at the roots), the
// bake's self-shadow factor `direct` of that layer (1 without SHADOW) and the secondary
// highlight's noise mask `mask` in [0, 1]. For each light (`light_at`: L towards it, E its
// radiance), with V the eye, H = normalize(L + V) and body = saturate((N·L + 0.15)/1.15) (the
// body's own shadow on its coat: Lambert's cosine wrapped a little past the terminator, where hair
// tips still stand in the light):
//   colour    = albedo · mix(1, tip_color, h)
//   diffuse   = mix(max(N·L, 0), sin(T, L) · body, kajiya_kay_diffuse)
//   specular  = body · (primary · lobe₁ + secondary · lobe₂ · secondary_tint · colour · mask)
//   back      = back_light · colour · ((1 − V·L)/2)⁴ · sin²(T, V) · (1 + N·L)/2
//   rgb       = colour · A(N) · occlusion + Σ E · direct · (colour · diffuse + specular + back)
// with A the hemisphere ambient (`ambient_at`) and occlusion = 1 − root_occlusion · (1 − h). The
// self-shadow table darkens the direct light (diffuse, highlights, transmission) and the root
// occlusion the ambient light, so no term is darkened twice for the same depth in the coat.
fn strand_shade(albedo: vec3<f32>, n_in: vec3<f32>, tangent: vec3<f32>, world: vec3<f32>, to_eye: vec3<f32>, h: f32, direct: f32, mask: f32) -> vec3<f32> {
    let n = normalize(n_in);
    var t = n;
    if dot(tangent, tangent) > 1e-12 {
        t = normalize(tangent);
    }
    let v = to_eye;
    let colour = albedo * mix(vec3<f32>(1.0), fur.tip_color.rgb, h);
    let occlusion = 1.0 - fur.tip_color.a * (1.0 - h);
    var rgb = colour * ambient_at(n) * occlusion;
    let tv = dot(t, v);
    let sin2_tv = max(1.0 - tv * tv, 0.0);
    let count = light_count();
    for (var i = 0u; i < LIGHT_SLOTS; i++) {
        if i < count {
            rgb += direct * strand_light(light_at(i, world), n, t, v, colour, sin2_tv, mask);
        }
    }
    return rgb;
}

// One light's direct terms of `strand_shade` (diffuse, highlights, back-light), before the
// self-shadow factor.
fn strand_light(light: LightSample, n: vec3<f32>, t: vec3<f32>, v: vec3<f32>, colour: vec3<f32>, sin2_tv: f32, mask: f32) -> vec3<f32> {
    let l = light.l;
    let nl = dot(n, l);
    let body = saturate((nl + 0.15) / 1.15);
    let wrap = 0.5 + 0.5 * nl;
    let tl = dot(t, l);
    let kajiya_kay = sqrt(max(1.0 - tl * tl, 0.0));
    let diffuse = mix(max(nl, 0.0), kajiya_kay * body, fur.strand.w);
    // L = −V (the light straight behind the eye's line) has no half vector: take N's.
    var half_vector = n;
    let lv = l + v;
    if dot(lv, lv) > 1e-8 {
        half_vector = normalize(lv);
    }
    let th = dot(t, half_vector);
    let sin_th = sqrt(max(1.0 - th * th, 0.0));
    let primary = fur.specular.x * strand_lobe(th, sin_th, fur.strand.x, fur.specular.y);
    let secondary = fur.specular.z * strand_lobe(th, sin_th, fur.strand.y, fur.specular.w) * mask;
    let specular = body * (vec3<f32>(primary) + secondary * fur.secondary_tint.rgb * colour);
    let behind = 0.5 - 0.5 * dot(v, l);
    let behind2 = behind * behind;
    let back = fur.strand.z * colour * (behind2 * behind2) * sin2_tv * wrap;
    return light.radiance * (colour * diffuse + specular + back);
}

// The mask of the secondary highlight for the hair on integer texel (x, y): 1 − depth·noise.
fn strand_mask(x: i32, y: i32) -> f32 {
    return 1.0 - fur.secondary_tint.a * cell_noise(x, y);
}
