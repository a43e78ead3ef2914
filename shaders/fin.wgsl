// fin.wgsl — fins (fur thesis §3.2, fig. 3.16; Lengyel et al.): one quad per fin edge, standing
// on the edge and extruded along the vertex normals (sheared like the shells, eq. 3.36) so that
// it is perpendicular to the surface and as tall as the outermost shell. Alpha from the fin atlas
// (u along the edge in texture repeats, v from tip (0) to root (1)), faded by how much the
// surface faces the viewer: fins fill the gaps between shells where the surface is seen
// edge-on, and vanish where the shells already read well.
// An animated pack's fins stand on the skinning pass's posed vertices, and their face normal is
// computed here from the posed corners of the triangle they grow from (a bind-pose face normal
// would fade them by the wrong facing once the skin moves).
// Prepended at load time: fur_common.wgsl (uniforms, switches, bindings 0–3 and 8, SurfaceIn,
// posed_vertex, shell_offset, lambert).

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
    return out;
}

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
    let alpha = texel * (1.0 - facing);
    if alpha <= fur.alpha_threshold {
        discard;
    }
    var shade = lambert(in.normal);
    if SHADOW {
        let layer = min(fur.atlas_layers - 1u, u32(in.height * f32(fur.atlas_layers)));
        shade = shade * shadow[layer];
    }
    let rgb = in.color.rgb * fur.tint.rgb * shade;
    if ALPHA_BLEND {
        return vec4<f32>(rgb, alpha);
    }
    return vec4<f32>(rgb, 1.0);
}
