// language: metal2.0
#include <metal_stdlib>
#include <simd/simd.h>

using metal::uint;

struct _mslBufferSizes {
    uint size2;
    uint size3;
};

struct Light {
    metal::float4 vector;
    metal::float4 radiance;
};
struct type_5 {
    Light inner[4];
};
struct Frame {
    metal::float4x4 view_proj;
    metal::float4 camera_pos;
    metal::float4 ambient_sky;
    metal::float4 ambient_ground;
    metal::uint4 light_count;
    type_5 lights;
    metal::float4x4 model;
    metal::float4 viewport;
    metal::float4 shells;
};
struct Fur {
    metal::float4 tint;
    float fur_length_m;
    float shear_exponent;
    float alpha_threshold;
    uint atlas_layers;
    uint drawn_layers;
    float fin_repeat_m;
    uint scale_layout;
    uint pad1_;
    metal::float4 tip_color;
    metal::float4 secondary_tint;
    metal::float4 specular;
    metal::float4 strand;
    metal::float4 stacking;
};
typedef metal::float4 type_8[1];
struct SkinnedVertex {
    metal::float4 position;
    metal::float4 normal;
};
typedef SkinnedVertex type_9[1];
struct SurfaceIn {
    metal::float3 position;
    metal::float3 normal;
    metal::float4 color;
    metal::float2 uv;
    uint vertex_index;
    uint flags;
    uint corner_index;
    char _pad7[12];
};
struct ShellOut {
    metal::float4 clip;
    metal::float3 normal;
    metal::float4 color;
    metal::float2 uv;
    uint slice;
    char _pad5[4];
    metal::float3 tangent;
    metal::packed_float3 world;
    float height;
    float fade;
    char _pad9[12];
};
constant uint STACK_ANGLES = 9u;
constant uint STACK_MIPS = 6u;
constant uint STACK_COUNTS = 7u;
constant bool STRAND = true;
constant bool SHEAR = true;
constant bool SKINNED = true;

uint scale_index(
    uint vertex_index,
    uint corner_index,
    constant Fur& fur
) {
    uint _e4 = fur.scale_layout;
    return (_e4 == 1u) ? corner_index : vertex_index;
}

SkinnedVertex posed_vertex(
    uint vertex_index_1,
    metal::float3 position,
    metal::float3 normal,
    device type_9 const& skinned,
    constant _mslBufferSizes& _buffer_sizes
) {
    if (SKINNED) {
        SkinnedVertex _e6 = skinned[vertex_index_1];
        return _e6;
    }
    return SkinnedVertex {metal::float4(position, 1.0), metal::float4(normal, 0.0)};
}

metal::float3 shell_offset(
    metal::float3 n,
    metal::float3 s,
    float t,
    constant Fur& fur
) {
    metal::float3 offset = {};
    offset = n * t;
    if (SHEAR) {
        metal::float3 _e6 = offset;
        float _e9 = fur.shear_exponent;
        offset = _e6 + (metal::pow(t, _e9) * (s - n));
        metal::float3 _e14 = offset;
        metal::float3 _e15 = offset;
        offset = _e14 - (metal::min(metal::dot(_e15, n), 0.0) * n);
    }
    metal::float3 _e21 = offset;
    float _e24 = fur.fur_length_m;
    return _e21 * _e24;
}

metal::float3 strand_tangent(
    metal::float3 n_1,
    metal::float3 s_1,
    float t_1,
    constant Fur& fur
) {
    metal::float3 d = {};
    if (false) {
        return n_1;
    }
    float k = fur.shear_exponent;
    d = n_1 + ((k * metal::pow(metal::max(t_1, 0.0001), k - 1.0)) * (s_1 - n_1));
    if (metal::dot((n_1 * t_1) + (metal::pow(t_1, k) * (s_1 - n_1)), n_1) < 0.0) {
        metal::float3 _e27 = d;
        metal::float3 _e28 = d;
        d = _e27 - (metal::dot(_e28, n_1) * n_1);
    }
    metal::float3 _e32 = d;
    metal::float3 _e33 = d;
    float len2_ = metal::dot(_e32, _e33);
    if (!((len2_ > 0.000000000001))) {
        return n_1;
    }
    metal::float3 _e38 = d;
    return _e38 * metal::rsqrt(len2_);
}

metal::float3 to_world(
    metal::float3 p,
    constant Frame& frame
) {
    metal::float4x4 _e3 = frame.model;
    return (_e3 * metal::float4(p, 1.0)).xyz;
}

metal::float3 normal_to_world(
    metal::float3 n_2,
    constant Frame& frame
) {
    metal::float4x4 _e3 = frame.model;
    return metal::normalize((_e3 * metal::float4(n_2, 0.0)).xyz);
}

metal::float3 shell_vertex(
    uint vertex_index_2,
    metal::float3 position_1,
    metal::float3 normal_1,
    uint scale_at,
    uint layer,
    uint layers,
    constant Fur& fur,
    device type_8 const& scale_vectors,
    device type_9 const& skinned,
    constant _mslBufferSizes& _buffer_sizes
) {
    float t_2 = static_cast<float>(layer + 1u) / static_cast<float>(layers);
    SkinnedVertex _e11 = posed_vertex(vertex_index_2, position_1, normal_1, skinned, _buffer_sizes);
    metal::float3 n_3 = metal::normalize(_e11.normal.xyz);
    metal::float4 _e17 = scale_vectors[scale_at];
    metal::float3 s_2 = _e17.xyz;
    metal::float3 _e21 = shell_offset(n_3, s_2, t_2, fur);
    return _e11.position.xyz + _e21;
}

metal::float3 shell_tangent(
    uint vertex_index_3,
    metal::float3 position_2,
    metal::float3 normal_2,
    uint scale_at_1,
    uint layer_1,
    uint layers_1,
    constant Fur& fur,
    device type_8 const& scale_vectors,
    device type_9 const& skinned,
    constant _mslBufferSizes& _buffer_sizes
) {
    float t_3 = static_cast<float>(layer_1 + 1u) / static_cast<float>(layers_1);
    SkinnedVertex _e11 = posed_vertex(vertex_index_3, position_2, normal_2, skinned, _buffer_sizes);
    metal::float3 n_4 = metal::normalize(_e11.normal.xyz);
    metal::float4 _e17 = scale_vectors[scale_at_1];
    metal::float3 _e19 = strand_tangent(n_4, _e17.xyz, t_3, fur);
    return _e19;
}

uint naga_div(uint lhs, uint rhs) {
    return lhs / metal::select(rhs, 1u, rhs == 0u);
}

uint shell_slice(
    uint layer_2,
    uint layers_2,
    constant Fur& fur
) {
    uint a = fur.atlas_layers;
    return metal::min(a - 1u, naga_div((((layer_2 + 1u) * a) + layers_2) - 1u, layers_2) - 1u);
}
uint naga_f2u32(float value) {
    return static_cast<uint>(metal::clamp(value, 0.0, 4294967000.0));
}

uint naga_mod(uint lhs, uint rhs) {
    return lhs % metal::select(rhs, 1u, rhs == 0u);
}


struct vs_shellInput {
    metal::float3 position_3 [[attribute(0)]];
    metal::float3 normal_3 [[attribute(1)]];
    metal::float4 color [[attribute(2)]];
    metal::float2 uv [[attribute(3)]];
    uint vertex_index_4 [[attribute(4)]];
    uint flags [[attribute(5)]];
    uint corner_index_1 [[attribute(6)]];
};
struct vs_shellOutput {
    metal::float4 clip [[position]];
    metal::float3 normal [[user(loc0), center_perspective]];
    metal::float4 color [[user(loc1), center_perspective]];
    metal::float2 uv [[user(loc2), center_perspective]];
    uint slice [[user(loc3), flat]];
    metal::float3 tangent [[user(loc4), center_perspective]];
    metal::float3 world [[user(loc5), center_perspective]];
    float height [[user(loc6), flat]];
    float fade [[user(loc7), flat]];
};
vertex vs_shellOutput vs_shell(
  vs_shellInput varyings [[stage_in]]
, uint instance [[instance_id]]
, constant Frame& frame [[buffer(0)]]
, constant Fur& fur [[buffer(1)]]
, device type_8 const& scale_vectors [[buffer(2)]]
, device type_9 const& skinned [[buffer(3)]]
, constant _mslBufferSizes& _buffer_sizes [[buffer(4)]]
) {
    const SurfaceIn v = { varyings.position_3, varyings.normal_3, varyings.color, varyings.uv, varyings.vertex_index_4, varyings.flags, varyings.corner_index_1 };
    ShellOut out = {};
    float _e5 = frame.shells.x;
    uint layers_3 = metal::max(naga_f2u32(_e5), 1u);
    uint layer_3 = (instance >= layers_3) ? (((2u * layers_3) - 1u) - instance) : instance;
    uint _e18 = scale_index(v.vertex_index, v.corner_index, fur);
    metal::float3 _e22 = shell_vertex(v.vertex_index, v.position, v.normal, _e18, layer_3, layers_3, fur, scale_vectors, skinned, _buffer_sizes);
    metal::float3 _e23 = to_world(_e22, frame);
    metal::float4x4 _e28 = frame.view_proj;
    out.clip = _e28 * metal::float4(_e23, 1.0);
    SkinnedVertex _e36 = posed_vertex(v.vertex_index, v.position, v.normal, skinned, _buffer_sizes);
    metal::float3 _e39 = normal_to_world(_e36.normal.xyz, frame);
    out.normal = _e39;
    out.color = v.color;
    out.uv = v.uv;
    uint _e45 = shell_slice(layer_3, layers_3, fur);
    out.slice = _e45;
    out.world = _e23;
    float _e56 = frame.shells.z;
    out.height = (static_cast<float>(layer_3 + 1u) / static_cast<float>(layers_3)) - (0.5 / metal::max(_e56, 1.0));
    float _e66 = frame.shells.y;
    out.fade = (naga_mod(layer_3, 2u) == 0u) ? _e66 : 1.0;
    if (STRAND) {
        metal::float3 _e78 = shell_tangent(v.vertex_index, v.position, v.normal, _e18, layer_3, layers_3, fur, scale_vectors, skinned, _buffer_sizes);
        metal::float3 _e79 = normal_to_world(_e78, frame);
        out.tangent = _e79;
    } else {
        metal::float3 _e82 = out.normal;
        out.tangent = _e82;
    }
    ShellOut _e83 = out;
    const auto _tmp = _e83;
    return vs_shellOutput { _tmp.clip, _tmp.normal, _tmp.color, _tmp.uv, _tmp.slice, _tmp.tangent, _tmp.world, _tmp.height, _tmp.fade };
}
