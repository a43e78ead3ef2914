// skinning.wgsl — the GPU skinning pass (glTF 2.0 specification, "Morph Targets", then "Skins" →
// "Skinned Mesh Attributes"): once per pack per frame, every welded skin vertex is morphed
// (p + Σ w_t·Δp_t, n + Σ w_t·Δn_t) and then skinned by linear blend skinning with up to eight
// influences (p' = (Σ w_i·M_i)·p; n' = normalize(cof(Σ w_i·M_i)·n · sign(det))), falling back to
// the bind normal when the skinned normal collapses (a joint scaled to zero). The rules are
// exactly those of the CPU reference `furbake_runtime::animation::morph_and_skin`; the skin,
// shell and fin shaders then read `skinned_out` (bound there as `skinned`) by welded vertex index
// instead of re-skinning per shell layer. Input layouts are the pack's sections as stored
// (docs/format.md "11 `skin_weights`", "12 `morph_targets`"). Not prepended with
// fur_common.wgsl: this file stands alone. Rust twins of its structs: crates/render/src/shaders.rs.

// Counts of this pack's skin (written once, when the pass is created).
struct SkinningUniforms {
    // Welded skin vertices (= entries of bind_vertices and skinned_out).
    vertex_count: u32,
    // Influence slots per vertex: 4 or 8 (SkinWeights::influences_per_vertex).
    influences_per_vertex: u32,
    // Morph targets (= entries of morph_weights).
    target_count: u32,
    pad0: u32,
};

// One welded skin vertex: xyz position in metres (w = 1) and xyz unit normal (w = 0). The layout
// of both the bind pose input and the skinned output.
struct SkinnedVertex {
    position: vec4<f32>,
    normal: vec4<f32>,
};

// The pack has skin weights (else only the morph is applied).
override SKIN: bool = true;
// The pack has morph targets (else only the skinning is applied).
override MORPH: bool = false;
// The morph targets carry normal deltas (MorphTargets::normal_deltas is not empty).
override MORPH_NORMALS: bool = false;

@group(0) @binding(0) var<uniform> params: SkinningUniforms;
@group(0) @binding(1) var<storage, read> bind_vertices: array<SkinnedVertex>;
// Bind index per influence slot, vertex-major, two u16 per word (slot 2j in the low half of word j,
// the little-endian order of SkinWeights::binds).
@group(0) @binding(2) var<storage, read> influence_binds: array<u32>;
// Weight per influence slot, vertex-major (SkinWeights::weights).
@group(0) @binding(3) var<storage, read> influence_weights: array<f32>;
// Morph deltas as xyz triples: position deltas target-major (target · vertex_count + vertex), then,
// with MORPH_NORMALS, the normal deltas in the same order.
@group(0) @binding(4) var<storage, read> morph_deltas: array<f32>;
// Per frame: one skinning matrix per bind, world(joint) × inverseBind (column-major).
@group(0) @binding(5) var<storage, read> skinning_matrices: array<mat4x4<f32>>;
// Per frame: one weight per morph target.
@group(0) @binding(6) var<storage, read> morph_weights: array<f32>;
@group(0) @binding(7) var<storage, read_write> skinned_out: array<SkinnedVertex>;

// Delta triple `i` (xyz) of morph_deltas.
fn morph_delta(i: u32) -> vec3<f32> {
    return vec3<f32>(morph_deltas[3u * i], morph_deltas[3u * i + 1u], morph_deltas[3u * i + 2u]);
}

// Bind index of influence slot `slot` (vertex-major, over all vertices).
fn influence_bind(slot: u32) -> u32 {
    return (influence_binds[slot >> 1u] >> ((slot & 1u) * 16u)) & 0xffffu;
}

@compute @workgroup_size(64)
fn cs_skin(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let v = gid.x + gid.y * groups.x * 64u;
    if v >= params.vertex_count {
        return;
    }
    let bind = bind_vertices[v];
    var p = bind.position.xyz;
    var n = bind.normal.xyz;
    if MORPH {
        // Zero weights are skipped, as on the CPU (the sum is the same; skipping saves the loads).
        let normal_base = params.target_count * params.vertex_count;
        for (var t = 0u; t < params.target_count; t++) {
            let w = morph_weights[t];
            if w != 0.0 {
                let i = t * params.vertex_count + v;
                p = p + w * morph_delta(i);
                if MORPH_NORMALS {
                    n = n + w * morph_delta(normal_base + i);
                }
            }
        }
    }
    if SKIN {
        var m = mat4x4<f32>();
        let first = v * params.influences_per_vertex;
        for (var s = 0u; s < params.influences_per_vertex; s++) {
            let w = influence_weights[first + s];
            if w != 0.0 {
                m = m + skinning_matrices[influence_bind(first + s)] * w;
            }
        }
        p = (m * vec4<f32>(p, 1.0)).xyz;
        // Normals by the inverse transpose of the blended matrix, as its cofactor matrix times the
        // sign of its determinant: defined even when the matrix is singular. The sign is taken
        // from the sign bit, like Rust's f32::signum (+1 for a zero determinant, not 0).
        let c0 = m[0].xyz;
        let c1 = m[1].xyz;
        let c2 = m[2].xyz;
        let cofactor = mat3x3<f32>(cross(c1, c2), cross(c2, c0), cross(c0, c1));
        let det = dot(c0, cross(c1, c2));
        let det_sign = select(1.0, -1.0, (bitcast<u32>(det) & 0x80000000u) != 0u);
        n = cofactor * n * det_sign;
    }
    // A collapsed normal (a joint scaled to zero) keeps the bind normal rather than NaN.
    let len = length(n);
    if len > 0.0 {
        n = n / len;
    } else {
        n = bind.normal.xyz;
    }
    skinned_out[v] = SkinnedVertex(vec4<f32>(p, 1.0), vec4<f32>(n, 0.0));
}
