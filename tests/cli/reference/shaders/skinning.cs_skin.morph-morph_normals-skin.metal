// language: metal2.0
#include <metal_stdlib>
#include <simd/simd.h>

using metal::uint;

struct _mslBufferSizes {
    uint size1;
    uint size2;
    uint size3;
    uint size4;
    uint size5;
    uint size6;
    uint size7;
};

struct SkinningUniforms {
    uint vertex_count;
    uint influences_per_vertex;
    uint target_count;
    uint pad0_;
};
struct SkinnedVertex {
    metal::float4 position;
    metal::float4 normal;
};
typedef SkinnedVertex type_4[1];
typedef uint type_5[1];
typedef float type_6[1];
typedef metal::float4x4 type_8[1];
constant bool SKIN = true;
constant bool MORPH = true;
constant bool MORPH_NORMALS = true;

metal::float3 morph_delta(
    uint i,
    device type_6 const& morph_deltas,
    constant _mslBufferSizes& _buffer_sizes
) {
    float _e5 = morph_deltas[3u * i];
    float _e12 = morph_deltas[(3u * i) + 1u];
    float _e19 = morph_deltas[(3u * i) + 2u];
    return metal::float3(_e5, _e12, _e19);
}

uint influence_bind(
    uint slot,
    device type_5 const& influence_binds,
    constant _mslBufferSizes& _buffer_sizes
) {
    uint _e5 = influence_binds[slot >> 1u];
    return (_e5 >> ((slot & 1u) * 16u)) & 65535u;
}

struct cs_skinInput {
};
kernel void cs_skin(
  metal::uint3 gid [[thread_position_in_grid]]
, metal::uint3 groups [[threadgroups_per_grid]]
, constant SkinningUniforms& params [[buffer(0)]]
, device type_4 const& bind_vertices [[buffer(1)]]
, device type_5 const& influence_binds [[buffer(2)]]
, device type_6 const& influence_weights [[buffer(3)]]
, device type_6 const& morph_deltas [[buffer(4)]]
, device type_8 const& skinning_matrices [[buffer(5)]]
, device type_6 const& morph_weights [[buffer(6)]]
, device type_4& skinned_out [[buffer(7)]]
, constant _mslBufferSizes& _buffer_sizes [[buffer(8)]]
) {
    metal::float3 p = {};
    metal::float3 n = {};
    uint t = 0u;
    metal::float4x4 m = metal::float4x4 {};
    uint s = 0u;
    uint v = gid.x + ((gid.y * groups.x) * 64u);
    uint _e11 = params.vertex_count;
    if (v >= _e11) {
        return;
    }
    SkinnedVertex bind = bind_vertices[v];
    p = bind.position.xyz;
    n = bind.normal.xyz;
    if (MORPH) {
        uint _e25 = params.target_count;
        uint _e28 = params.vertex_count;
        uint normal_base = _e25 * _e28;
        uint2 loop_bound = uint2(4294967295u);
        bool loop_init = true;
        while(true) {
            if (metal::all(loop_bound == uint2(0u))) { break; }
            loop_bound -= uint2(loop_bound.y == 0u, 1u);
            if (!loop_init) {
                uint _e60 = t;
                t = _e60 + 1u;
            }
            loop_init = false;
            uint _e32 = t;
            uint _e35 = params.target_count;
            if (_e32 < _e35) {
            } else {
                break;
            }
            {
                uint _e38 = t;
                float w = morph_weights[_e38];
                if (w != 0.0) {
                    uint _e43 = t;
                    uint _e46 = params.vertex_count;
                    uint i_1 = (_e43 * _e46) + v;
                    metal::float3 _e49 = p;
                    metal::float3 _e50 = morph_delta(i_1, morph_deltas, _buffer_sizes);
                    p = _e49 + (w * _e50);
                    if (MORPH_NORMALS) {
                        metal::float3 _e54 = n;
                        metal::float3 _e56 = morph_delta(normal_base + i_1, morph_deltas, _buffer_sizes);
                        n = _e54 + (w * _e56);
                    }
                }
            }
        }
    }
    if (SKIN) {
        uint _e67 = params.influences_per_vertex;
        uint first = v * _e67;
        uint2 loop_bound_1 = uint2(4294967295u);
        bool loop_init_1 = true;
        while(true) {
            if (metal::all(loop_bound_1 == uint2(0u))) { break; }
            loop_bound_1 -= uint2(loop_bound_1.y == 0u, 1u);
            if (!loop_init_1) {
                uint _e93 = s;
                s = _e93 + 1u;
            }
            loop_init_1 = false;
            uint _e71 = s;
            uint _e74 = params.influences_per_vertex;
            if (_e71 < _e74) {
            } else {
                break;
            }
            {
                uint _e77 = s;
                float w_1 = influence_weights[first + _e77];
                if (w_1 != 0.0) {
                    metal::float4x4 _e83 = m;
                    uint _e85 = s;
                    uint _e87 = influence_bind(first + _e85, influence_binds, _buffer_sizes);
                    metal::float4x4 _e89 = skinning_matrices[_e87];
                    m = _e83 + (_e89 * w_1);
                }
            }
        }
        metal::float4x4 _e95 = m;
        metal::float3 _e96 = p;
        p = (_e95 * metal::float4(_e96, 1.0)).xyz;
        metal::float4 _e102 = m[0];
        metal::float3 c0_ = _e102.xyz;
        metal::float4 _e105 = m[1];
        metal::float3 c1_ = _e105.xyz;
        metal::float4 _e108 = m[2];
        metal::float3 c2_ = _e108.xyz;
        metal::float3x3 cofactor = metal::float3x3(metal::cross(c1_, c2_), metal::cross(c2_, c0_), metal::cross(c0_, c1_));
        float det = metal::dot(c0_, metal::cross(c1_, c2_));
        float det_sign = ((as_type<uint>(det) & 2147483648u) != 0u) ? -1.0 : 1.0;
        metal::float3 _e124 = n;
        n = (cofactor * _e124) * det_sign;
    }
    metal::float3 _e127 = n;
    float len = metal::length(_e127);
    if (len > 0.0) {
        metal::float3 _e131 = n;
        n = _e131 / metal::float3(len);
    } else {
        n = bind.normal.xyz;
    }
    metal::float3 _e138 = p;
    metal::float3 _e141 = n;
    skinned_out[v] = SkinnedVertex {metal::float4(_e138, 1.0), metal::float4(_e141, 0.0)};
    return;
}
