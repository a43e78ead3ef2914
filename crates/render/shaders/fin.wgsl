// fin.wgsl — fins (fur thesis §3.2, fig. 3.16; Lengyel et al.): one quad per fin edge, standing
// on the edge and extruded along the vertex normals (sheared like the shells, eq. 3.36) so that
// it is perpendicular to the surface and as tall as the outermost shell. Alpha from the fin atlas
// (u along the edge in texture repeats, v from tip (0) to root (1)), faded by how much the
// surface faces the viewer: fins fill the gaps between shells where the surface is seen
// edge-on, and vanish where the shells already read well. Shaded as the shells are (fur_common.wgsl
// `strand_shade`, docs/design.md "Fur shading"): the hair direction of eq. 3.36 at the fin
// vertex's height, the self-shadow of the layer at that height, the noise of the fin texel's
// column (one hair), so fins and shells match where they meet.
// An animated pack's fins stand on the skinning pass's posed vertices, and their face normal is
// computed here from the posed corners of the triangle they grow from (a bind-pose face normal
// would fade them by the wrong facing once the skin moves).
// Prepended at load time: fur_common.wgsl (uniforms, switches, bindings 0–3 and 8, SurfaceIn,
// posed_vertex, shell_offset, strand_tangent, lambert, strand_shade).

@group(0) @binding(6) var fin_alpha: texture_2d<f32>;
@group(0) @binding(7) var fin_sampler: sampler;

struct FinIn {
    // Root position of this corner (an edge end) in metres.
    @location(0) position: vec3<f32>,
    // Vertex normal at that edge end (direction of extrusion).
    @location(1) normal: vec3<f32>,
    // Normal of the furry triangle the fin grows from (for the view fade).
    @location(2) face_normal: vec3<f32>,
    @location(3) color: vec4<f32>,
    // Distance along the edge in metres.
    @location(4) along_m: f32,
    // 0 at the root, 1 at the tip.
    @location(5) height: f32,
    @location(6) vertex_index: u32,
    // 3·triangle + corner of this edge end in the furry triangle the fin grows from.
    @location(7) corner_index: u32,
    // Welded vertex indices of that triangle's corners (its posed face normal when SKINNED).
    @location(8) face_vertices: vec3<u32>,
};

struct FinOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec4<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) world: vec3<f32>,
    @location(4) face_normal: vec3<f32>,
    @location(5) height: f32,
    // Multiplies the fin's alpha: 1 for the always-on fins, the selection's fade for the
    // silhouette fins.
    @location(6) fade: f32,
    // World-space hair direction (unit before interpolation).
    @location(7) tangent: vec3<f32>,
};

// Normal (not necessarily unit) of the furry triangle a fin grows from: the bind-pose face normal
// from the vertex attributes, or when SKINNED the cross product of its posed edges (the CPU's
// (j − i) × (k − i)), falling back to the posed vertex normal `n` where the posed triangle has
// collapsed.
fn fin_face_normal(v: FinIn, n: vec3<f32>) -> vec3<f32> {
    if !SKINNED {
        return v.face_normal;
    }
    let i = skinned[v.face_vertices.x].position.xyz;
    let j = skinned[v.face_vertices.y].position.xyz;
    let k = skinned[v.face_vertices.z].position.xyz;
    let face = cross(j - i, k - i);
    if dot(face, face) > 0.0 {
        return face;
    }
    return n;
}

@vertex
fn vs_fin(v: FinIn) -> FinOut {
    let root = posed_vertex(v.vertex_index, v.position, v.normal);
    let n = normalize(root.normal.xyz);
    let s = scale_vectors[scale_index(v.vertex_index, v.corner_index)].xyz;
    let world = to_world(root.position.xyz + shell_offset(n, s, v.height));
    var out: FinOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = normal_to_world(n);
    out.color = v.color;
    out.uv = vec2<f32>(v.along_m / fur.fin_repeat_m, 1.0 - v.height);
    out.world = world;
    out.face_normal = normal_to_world(fin_face_normal(v, n));
    out.height = v.height;
    out.fade = 1.0;
    out.tangent = out.normal;
    if STRAND {
        out.tangent = normal_to_world(strand_tangent(n, s, v.height));
    }
    return out;
}

// Silhouette fins (fur thesis §4.1): one instance per interior edge that silhouette.wgsl selected
// this frame (drawn with draw_indirect, 6 vertices per instance), standing on this frame's posed
// (or rest) vertices exactly as the always-on fins do, with the mean of the two face normals as the
// fin's facing and the selection's fade on its alpha. The structs are silhouette_common.wgsl's
// (checked against their Rust twins in shaders.rs).
@group(1) @binding(0) var<storage, read> sil_edges: array<SilhouetteEdge>;
@group(1) @binding(1) var<storage, read> sil_instances: array<SilhouetteInstance>;
// The posed vertices (the skinning pass's output) or the bind pose of a static pack.
@group(1) @binding(2) var<storage, read> sil_vertices: array<SkinnedVertex>;
// Linear RGBA colour per welded vertex.
@group(1) @binding(3) var<storage, read> sil_colors: array<vec4<f32>>;

@vertex
fn vs_silhouette_fin(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> FinOut {
    let inst = sil_instances[ii];
    let e = sil_edges[inst.edge];
    // The quad a0 b0 b1, a0 b1 a1 (as FurAsset::fin_vertices).
    let at_b = vi == 1u || vi == 2u || vi == 4u;
    let height = select(0.0, 1.0, vi == 2u || vi == 4u || vi == 5u);
    let vertex = select(e.a, e.b, at_b);
    let corner = select(e.corner_a, e.corner_b, at_b);
    let root = sil_vertices[vertex];
    let n = normalize(root.normal.xyz);
    let s = scale_vectors[scale_index(vertex, corner)].xyz;
    let world = to_world(root.position.xyz + shell_offset(n, s, height));
    let pa = sil_vertices[e.a].position.xyz;
    let pb = sil_vertices[e.b].position.xyz;
    let pc = sil_vertices[e.c].position.xyz;
    let pd = sil_vertices[e.d].position.xyz;
    let n0 = normalize(cross(pb - pa, pc - pa));
    var n1 = normalize(cross(pa - pb, pd - pb));
    if (e.flags & 1u) != 0u {
        n1 = normalize(cross(pb - pa, pd - pa));
    }
    var face = n0 + n1;
    if dot(face, face) <= 1e-12 {
        face = n;
    }
    var out: FinOut;
    out.clip = frame.view_proj * vec4<f32>(world, 1.0);
    out.normal = normal_to_world(n);
    out.color = sil_colors[vertex];
    out.uv = vec2<f32>(select(0.0, distance(pa, pb), at_b) / fur.fin_repeat_m, 1.0 - height);
    out.world = world;
    out.face_normal = normal_to_world(face);
    out.height = height;
    out.fade = inst.fade;
    out.tangent = out.normal;
    if STRAND {
        out.tangent = normal_to_world(strand_tangent(n, s, height));
    }
    if inst.fade <= 0.0 {
        // An unselected edge inside the drawn prefix: a degenerate quad outside the clip volume.
        out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
    }
    return out;
}

// cos 80°: the last view angle of the shells' stacking table (shell.wgsl `STACK_ANGLES`, 10°
// apart from 0°).
const FIN_FACING: f32 = 0.17364818;

@fragment
fn fs_fin(in: FinOut) -> @location(0) vec4<f32> {
    var texel: f32;
    if ALPHA_BLEND {
        texel = textureSample(fin_alpha, fin_sampler, in.uv).r;
    } else {
        texel = textureSampleLevel(fin_alpha, fin_sampler, in.uv, 0.0).r;
    }
    let to_eye = normalize(frame.camera_pos.xyz - in.world);
    let facing = abs(dot(normalize(in.face_normal), to_eye));
    // Fins take over where the shells' stacking table ends (docs/design.md "Fin opacity"): the
    // table is calibrated for views up to 80° from the hair, so a fin fades in only as the skin
    // turns beyond that (|n·v| below cos 80°), and is faded towards the root by height²: there
    // the view crosses the shells' whole stack, which the stacking already makes as opaque as the
    // hair volume; the fin adds the hair the shells miss towards the tips. Fins over the whole
    // range (1 − |n·v|) doubled the coat the shells already drew at 70°; unfaded towards the
    // root they drew a dark, self-shadowed root line along every silhouette and crease.
    let alpha = texel * (1.0 - smoothstep(0.0, FIN_FACING, facing)) * in.fade * in.height * in.height;
    // One pixel's change of alpha, for alpha to coverage only (taken where control flow is
    // still uniform).
    var edge = 0.0;
    if ALPHA_TO_COVERAGE {
        edge = fwidth(alpha);
    }
    if alpha_discarded(alpha, edge) {
        discard;
    }
    // Shaded as the coat's top: a ray grazing a silhouette travels down through the sparse outer
    // coat and meets its first hair there, near the tips, whatever the fin's own height (shaded
    // at it, the fins darkened the sphere's limb where the hair volume is bright).
    var direct = 1.0;
    if SHADOW {
        direct = shadow[fur.atlas_layers - 1u];
    }
    var rgb: vec3<f32>;
    if STRAND && LAMBERT {
        // A fin texel column is one hair (u along the edge, v root to tip).
        let width = f32(textureDimensions(fin_alpha).x);
        let column = i32(min(floor(fract(in.uv.x) * width), width - 1.0));
        rgb = strand_shade(in.color.rgb * fur.tint.rgb, in.normal, in.tangent, in.world, to_eye, 1.0, direct, strand_mask(column, -1));
    } else {
        rgb = in.color.rgb * fur.tint.rgb * lambert(in.normal, in.world) * direct;
    }
    if ALPHA_BLEND {
        return vec4<f32>(rgb, alpha);
    }
    if ALPHA_TO_COVERAGE {
        return vec4<f32>(rgb, coverage_alpha(alpha, edge));
    }
    return vec4<f32>(rgb, 1.0);
}
