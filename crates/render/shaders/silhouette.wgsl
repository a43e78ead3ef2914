// silhouette.wgsl — selection of the silhouette fins (fur thesis §4.1: fins belong on
// the silhouette, which the bake cannot know). One invocation per interior furry edge of the skin
// (crates/render/src/silhouette.rs derives them at load time): both face normals from this frame's
// posed (or rest) vertices, the view vector from the camera (in the object frame) to the edge
// midpoint, d0 = n0·v and d1 = n1·v. The edge is a silhouette edge when d0 and d1 differ in sign,
// and near the silhouette when min(|d0|, |d1|) < band. Every edge writes its own slot, instance i
// = (i, fade) with fade 0 when unselected (the vertex shader collapses those), and a selected edge
// raises the indirect draw's instance count to at least i + 1 (atomicMax: order-independent), so
// the fins are drawn in edge order every frame — blending them gives the same image whatever the
// order the invocations ran in (an atomic append would not). fade = 1 on the
// silhouette, 1 − min(|d|)/band in the band, so a fin fades in as it nears the silhouette instead
// of popping. The CPU twin is `furbake_render::silhouette_edges`.
// Prepended by silhouette_common.wgsl (the edge and instance structs it shares with fin.wgsl).

struct SilhouetteParams {
    // xyz: the eye in the object (pack) frame, i.e. inverse(model) · eye; w unused.
    camera_obj: vec4<f32>,
    // Half-width of the band around the silhouette, in units of n·v (0: sign change only).
    band: f32,
    edge_count: u32,
    pad0: u32,
    pad1: u32,
};

// The posed (or rest) welded vertices: the skinning pass's output, or the bind pose.
struct SkinnedVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
};

// wgpu's DrawIndirectArgs; instance_count is the selection's counter.
struct DrawArgs {
    vertex_count: u32,
    instance_count: atomic<u32>,
    first_vertex: u32,
    first_instance: u32,
};

@group(0) @binding(0) var<uniform> params: SilhouetteParams;
@group(0) @binding(1) var<storage, read> edges: array<SilhouetteEdge>;
@group(0) @binding(2) var<storage, read> vertices: array<SkinnedVertex>;
@group(0) @binding(3) var<storage, read_write> instances: array<SilhouetteInstance>;
@group(0) @binding(4) var<storage, read_write> args: DrawArgs;

// Unit normals of an edge's two faces (zero where a face has collapsed).
fn silhouette_face_normals(e: SilhouetteEdge) -> array<vec3<f32>, 2> {
    let pa = vertices[e.a].position.xyz;
    let pb = vertices[e.b].position.xyz;
    let pc = vertices[e.c].position.xyz;
    let pd = vertices[e.d].position.xyz;
    let n0 = cross(pb - pa, pc - pa);
    var n1 = cross(pa - pb, pd - pb);
    if (e.flags & 1u) != 0u {
        n1 = cross(pb - pa, pd - pa);
    }
    return array<vec3<f32>, 2>(safe_normalize(n0), safe_normalize(n1));
}

fn safe_normalize(v: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if l > 0.0 {
        return v / l;
    }
    return vec3<f32>(0.0);
}

@compute @workgroup_size(64)
fn cs_silhouette(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = id.x + id.y * groups.x * 64u;
    if i >= params.edge_count {
        return;
    }
    let e = edges[i];
    let n = silhouette_face_normals(e);
    // A collapsed face has no facing: its edge is left to the shells.
    if dot(n[0], n[0]) == 0.0 || dot(n[1], n[1]) == 0.0 {
        instances[i] = SilhouetteInstance(i, 0.0);
        return;
    }
    let mid = 0.5 * (vertices[e.a].position.xyz + vertices[e.b].position.xyz);
    let v = safe_normalize(params.camera_obj.xyz - mid);
    let d0 = dot(n[0], v);
    let d1 = dot(n[1], v);
    let m = min(abs(d0), abs(d1));
    var fade = 0.0;
    if (d0 > 0.0) != (d1 > 0.0) {
        fade = 1.0;
    } else if m < params.band {
        fade = 1.0 - m / params.band;
    }
    fade = max(fade, 0.0);
    instances[i] = SilhouetteInstance(i, fade);
    if fade > 0.0 {
        atomicMax(&args.instance_count, i + 1u);
    }
}
