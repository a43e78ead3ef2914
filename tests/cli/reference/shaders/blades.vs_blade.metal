// language: metal2.0
#include <metal_stdlib>
#include <simd/simd.h>

using metal::uint;

struct _mslBufferSizes {
    uint size1;
    uint size3;
    uint size4;
    uint size5;
    uint size7;
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
struct Blade {
    metal::float4 root;
    metal::float2 yaw;
    uint cluster;
    uint pad;
    metal::float4 weights;
};
struct type_8 {
    metal::float4 inner[6];
};
struct CullUniforms {
    type_8 planes;
    metal::float4 eye;
    metal::float4 lod;
    metal::float4 distance;
    metal::float4 shape;
    metal::uint4 index_count;
    metal::uint4 first_index;
    metal::uint4 counts;
    metal::float4x4 clip;
    metal::uint4 occlusion;
};
struct BladeUniforms {
    metal::float4 color;
    uint blade_count;
    uint vertex_count;
    uint stored_vectors;
    uint stored_angles;
    uint magnitudes;
    uint angles;
    uint mirror_x;
    uint mirror_z;
    float magnitude_per_force;
    float angle_per_radian;
    float scale;
    uint encoding;
    uint interpolation;
    uint lambert;
    uint delayed_sources;
    uint corner_count;
    uint cells_x;
    uint seed;
    uint shading;
    uint pad0_;
    metal::float4 tip_color;
    metal::float4 shade;
    metal::float4 gloss;
};
typedef Blade type_9[1];
typedef uint type_11[1];
typedef metal::float4 type_12[1];
struct Pose {
    metal::uint4 keys_m;
    metal::uint4 keys_j;
    metal::float4 weights;
    uint count;
    char _pad4[12];
    metal::packed_float3 root;
    float height;
    metal::float3 width;
    metal::float3 normal;
};
struct BladeOut {
    metal::float4 clip;
    metal::float3 world;
    metal::float2 uv;
    char _pad3[8];
    metal::float3 width_axis;
    metal::uint2 ids;
    float fade;
    char _pad6[4];
};
constant uint SALT_THINNING = 1759714724u;
constant uint SALT_LOD = 3039394381u;
constant uint CULLED = 4294967295u;
constant uint OCCLUDED = 4294967294u;
constant float PI = 3.1415927;
constant float TAU = 6.2831855;
constant uint STATIC_VERTEX = 4294967295u;
constant float FADE_START = 0.6;

float thinning_keep(
    float start,
    float min_density,
    float d
) {
    float s = start / metal::max(d, 0.000000000000000000000000000001);
    return metal::min(metal::max(s * s, min_density), 1.0);
}

float f16_to_f32_(
    uint h
) {
    uint sign = (h & 32768u) << 16u;
    uint e = (h >> 10u) & 31u;
    uint m_1 = h & 1023u;
    if (e == 0u) {
        float v_3 = static_cast<float>(m_1) * 0.000000059604645;
        return (sign != 0u) ? -(v_3) : v_3;
    }
    if (e == 31u) {
        return as_type<float>((sign | 2139095040u) | (m_1 << 13u));
    }
    return as_type<float>((sign | ((e + 112u) << 23u)) | (m_1 << 13u));
}

float component(
    uint i,
    constant BladeUniforms& params,
    device type_11 const& payload,
    constant _mslBufferSizes& _buffer_sizes
) {
    uint _e3 = params.encoding;
    switch(_e3) {
        case 1u: {
            uint _e8 = payload[i >> 1u];
            uint bits = (_e8 >> ((i & 1u) * 16u)) & 65535u;
            int q = as_type<int>(bits << 16u) >> 16u;
            float _e26 = params.scale;
            return (static_cast<float>(q) / 32767.0) * _e26;
        }
        case 2u: {
            uint _e32 = payload[i >> 1u];
            float _e40 = f16_to_f32_((_e32 >> ((i & 1u) * 16u)) & 65535u);
            return _e40;
        }
        case 3u: {
            uint _e45 = payload[i >> 2u];
            uint q_1 = (_e45 >> ((i & 3u) * 8u)) & 255u;
            float _e60 = params.scale;
            return ((static_cast<float>(q_1) * 0.007843138) - 1.0) * _e60;
        }
        case 4u: {
            uint _e66 = payload[i >> 2u];
            uint bits_1 = (_e66 >> ((i & 3u) * 8u)) & 255u;
            int q_2 = as_type<int>(bits_1 << 24u) >> 24u;
            float _e84 = params.scale;
            return (static_cast<float>(q_2) / 127.0) * _e84;
        }
        default: {
            uint _e88 = payload[i];
            return as_type<float>(_e88);
        }
    }
}

uint naga_div(uint lhs, uint rhs) {
    return lhs / metal::select(rhs, 1u, rhs == 0u);
}

metal::float3 displacement(
    uint m,
    uint j_full,
    uint v,
    constant BladeUniforms& params,
    device type_11 const& payload,
    device type_11 const& vertex_map,
    constant _mslBufferSizes& _buffer_sizes
) {
    uint j = {};
    bool flip_x = false;
    bool flip_z = false;
    bool local_1 = {};
    bool local_2 = {};
    metal::float3 d_1 = {};
    if (m == 0u) {
        return metal::float3(0.0);
    }
    uint mapped = vertex_map[v];
    if (mapped == STATIC_VERTEX) {
        return metal::float3(0.0);
    }
    uint a = params.angles;
    j = j_full;
    uint _e24 = params.mirror_x;
    if (_e24 != 0u) {
        uint _e29 = j;
        local_1 = _e29 >= naga_div(a, 2u);
    } else {
        local_1 = false;
    }
    bool _e34 = local_1;
    if (_e34) {
        uint _e37 = j;
        j = (a - 1u) - _e37;
        flip_x = true;
    }
    uint _e42 = params.mirror_z;
    if (_e42 != 0u) {
        uint _e47 = j;
        local_2 = _e47 >= naga_div(a, 4u);
    } else {
        local_2 = false;
    }
    bool _e52 = local_2;
    if (_e52) {
        uint _e57 = j;
        j = (naga_div(a, 2u) - 1u) - _e57;
        flip_z = true;
    }
    uint _e64 = params.stored_angles;
    uint _e66 = j;
    uint pose_2 = ((m - 1u) * _e64) + _e66;
    uint _e70 = params.stored_vectors;
    uint base = ((pose_2 * _e70) + mapped) * 3u;
    float _e75 = component(base, params, payload, _buffer_sizes);
    float _e78 = component(base + 1u, params, payload, _buffer_sizes);
    float _e81 = component(base + 2u, params, payload, _buffer_sizes);
    d_1 = metal::float3(_e75, _e78, _e81);
    bool _e84 = flip_x;
    if (_e84) {
        float _e87 = d_1.x;
        d_1.x = -(_e87);
    }
    bool _e89 = flip_z;
    if (_e89) {
        float _e92 = d_1.z;
        d_1.z = -(_e92);
    }
    metal::float3 _e94 = d_1;
    return _e94;
}

int naga_mod(int lhs, int rhs) {
    int divisor = metal::select(rhs, 1, (lhs == (-2147483647 - 1) & rhs == -1) | (rhs == 0));
    return lhs - (lhs / divisor) * divisor;
}

uint wrap_angle(
    int j_1,
    constant BladeUniforms& params
) {
    uint _e3 = params.angles;
    int a_1 = static_cast<int>(_e3);
    return static_cast<uint>(naga_mod(as_type<int>(as_type<uint>(naga_mod(j_1, a_1)) + as_type<uint>(a_1)), a_1));
}

uint naga_f2u32(float value) {
    return static_cast<uint>(metal::clamp(value, 0.0, 4294967000.0));
}

int naga_f2i32(float value) {
    return static_cast<int>(metal::clamp(value, -2147483600.0, 2147483500.0));
}

Pose pose_from(
    uint b,
    metal::float2 grid,
    device type_9 const& blades,
    constant BladeUniforms& params,
    constant _mslBufferSizes& _buffer_sizes
) {
    Pose pose = {};
    uint j_2 = {};
    Blade blade = blades[b];
    float c = blade.yaw.x;
    float s_1 = blade.yaw.y;
    pose.width = metal::float3(c, 0.0, -(s_1));
    pose.normal = metal::float3(s_1, 0.0, c);
    pose.root = blade.root.xyz;
    pose.height = blade.root.w;
    float mu = grid.x;
    float alpha = grid.y;
    pose.keys_m = metal::uint4(0u);
    pose.keys_j = metal::uint4(0u);
    pose.weights = metal::float4(1.0, 0.0, 0.0, 0.0);
    pose.count = 1u;
    uint _e41 = params.interpolation;
    if (_e41 == 0u) {
        j_2 = naga_f2u32(alpha + 0.5);
        uint _e48 = j_2;
        uint _e51 = params.angles;
        if (_e48 >= _e51) {
            uint _e53 = j_2;
            uint _e56 = params.angles;
            j_2 = _e53 - _e56;
        }
        uint _e65 = params.magnitudes;
        pose.keys_m.x = metal::min(naga_f2u32(mu + 0.5), _e65);
        uint _e69 = j_2;
        pose.keys_j.x = _e69;
    } else {
        uint _e73 = params.magnitudes;
        float m0_ = metal::max(metal::min(metal::floor(mu), static_cast<float>(_e73) - 1.0), 0.0);
        float tm = metal::clamp(mu - m0_, 0.0, 1.0);
        float j0f = metal::floor(alpha);
        float ta = metal::clamp(alpha - j0f, 0.0, 1.0);
        uint m0u = naga_f2u32(m0_);
        uint _e91 = wrap_angle(naga_f2i32(j0f), params);
        uint _e95 = wrap_angle(as_type<int>(as_type<uint>(naga_f2i32(j0f)) + as_type<uint>(1)), params);
        pose.keys_m = metal::uint4(m0u, m0u, m0u + 1u, m0u + 1u);
        pose.keys_j = metal::uint4(_e91, _e95, _e91, _e95);
        pose.weights = metal::float4((1.0 - tm) * (1.0 - ta), (1.0 - tm) * ta, tm * (1.0 - ta), tm * ta);
        pose.count = 4u;
    }
    Pose _e120 = pose;
    return _e120;
}

metal::float3 vertex_position(
    Pose pose_1,
    uint v_1,
    float widen_1,
    constant BladeUniforms& params,
    device type_11 const& payload,
    device type_11 const& vertex_map,
    device type_12 const& reference,
    constant _mslBufferSizes& _buffer_sizes
) {
    metal::float3 d_2 = metal::float3(0.0);
    uint k = 0u;
    uint2 loop_bound = uint2(4294967295u);
    bool loop_init = true;
    while(true) {
        if (metal::all(loop_bound == uint2(0u))) { break; }
        loop_bound -= uint2(loop_bound.y == 0u, 1u);
        if (!loop_init) {
            uint _e25 = k;
            k = _e25 + 1u;
        }
        loop_init = false;
        uint _e8 = k;
        if (_e8 < pose_1.count) {
        } else {
            break;
        }
        {
            metal::float3 _e11 = d_2;
            uint _e13 = k;
            uint _e16 = k;
            metal::float3 _e18 = displacement(pose_1.keys_m[_e13], pose_1.keys_j[_e16], v_1, params, payload, vertex_map, _buffer_sizes);
            uint _e20 = k;
            d_2 = _e11 + (_e18 * pose_1.weights[_e20]);
        }
    }
    metal::float4 _e29 = reference[v_1];
    metal::float3 r = _e29.xyz;
    metal::float3 _e31 = d_2;
    metal::float3 p = (r + _e31) + metal::float3(r.x * (widen_1 - 1.0), 0.0, 0.0);
    return pose_1.root + ((((pose_1.width * p.x) + metal::float3(0.0, p.y, 0.0)) + (pose_1.normal * p.z)) * pose_1.height);
}

uint naga_mod(uint lhs, uint rhs) {
    return lhs % metal::select(rhs, 1u, rhs == 0u);
}

metal::float2 blade_uv(
    uint v_2,
    constant BladeUniforms& params
) {
    uint _e3 = params.vertex_count;
    uint segments = metal::max(naga_div(_e3, 4u), 1u);
    uint level = naga_div(v_2, 4u) + naga_div(naga_mod(v_2, 4u), 2u);
    return metal::float2(static_cast<float>(v_2 & 1u), static_cast<float>(level) / static_cast<float>(segments));
}

struct vs_bladeInput {
};
struct vs_bladeOutput {
    metal::float4 clip [[position]];
    metal::float3 world [[user(loc0), center_perspective]];
    metal::float2 uv [[user(loc1), center_perspective]];
    metal::float3 width_axis [[user(loc2), center_perspective]];
    metal::uint2 ids [[user(loc3), flat]];
    float fade [[user(loc4), flat]];
};
vertex vs_bladeOutput vs_blade(
  uint vi [[vertex_id]]
, uint instance [[instance_id]]
, constant Frame& frame [[buffer(0)]]
, device type_9 const& blades [[buffer(2)]]
, constant BladeUniforms& params [[buffer(1)]]
, device type_11 const& payload [[buffer(3)]]
, device type_11 const& vertex_map [[buffer(4)]]
, device type_12 const& reference [[buffer(5)]]
, constant CullUniforms& cull [[buffer(6)]]
, device type_11 const& instances [[buffer(7)]]
, constant _mslBufferSizes& _buffer_sizes [[buffer(8)]]
) {
    float widen = 1.0;
    float fade = 0.0;
    metal::float3 thicken = metal::float3(0.0);
    bool local = {};
    BladeOut out = {};
    uint _e4 = params.vertex_count;
    uint lod = naga_div(vi, _e4);
    uint _e8 = params.vertex_count;
    uint v_4 = vi - (lod * _e8);
    uint _e15 = instances[lod];
    uint entry = 4u + (3u * (_e15 + instance));
    uint b_1 = instances[entry];
    uint _e26 = instances[entry + 1u];
    uint _e32 = instances[entry + 2u];
    metal::float2 grid_1 = metal::float2(as_type<float>(_e26), as_type<float>(_e32));
    Pose _e35 = pose_from(b_1, grid_1, blades, params, _buffer_sizes);
    metal::float4 _e39 = frame.model[0];
    metal::float4 _e44 = frame.model[1];
    metal::float4 _e49 = frame.model[2];
    metal::float3x3 m3_ = metal::float3x3(_e39.xyz, _e44.xyz, _e49.xyz);
    metal::float4 _e55 = frame.camera_pos;
    metal::float4 _e60 = frame.model[3];
    metal::float3 eye = (metal::transpose(m3_) * (_e55.xyz - _e60.xyz)) / metal::float3(metal::max(metal::dot(m3_[0], m3_[0]), 0.000000000001));
    metal::float4 _e74 = blades[b_1].root;
    metal::float3 to_eye = eye - _e74.xyz;
    float d_3 = metal::length(to_eye);
    float _e85 = cull.eye.w;
    if (_e85 != 0.0) {
        float _e91 = cull.distance.y;
        float _e95 = cull.distance.z;
        float _e96 = thinning_keep(_e91, _e95, d_3);
        widen = 1.0 / _e96;
        float _e102 = cull.distance.x;
        float far = metal::sqrt(_e102);
        fade = metal::smoothstep(FADE_START * far, far, d_3);
    }
    metal::float3 view = to_eye / metal::float3(metal::max(d_3, 0.000001));
    metal::float3 width_axis = metal::normalize(_e35.width);
    float along = metal::dot(width_axis, view);
    float seen = metal::sqrt(metal::max(1.0 - (along * along), 0.0));
    metal::float3 side = metal::cross(metal::float3(0.0, 1.0, 0.0), view);
    float _e131 = cull.shape.z;
    if (seen < _e131) {
        local = metal::dot(side, side) > 0.00000001;
    } else {
        local = false;
    }
    bool _e139 = local;
    if (_e139) {
        metal::float3 s_2 = metal::normalize(side) * metal::sign(metal::dot(side, width_axis) + 0.000000001);
        float _e149 = reference[v_4].x;
        float _e150 = widen;
        float _e157 = cull.shape.z;
        thicken = s_2 * (((_e149 * _e150) * _e35.height) * (_e157 - seen));
    }
    metal::float4x4 _e163 = frame.model;
    float _e164 = widen;
    metal::float3 _e165 = vertex_position(_e35, v_4, _e164, params, payload, vertex_map, reference, _buffer_sizes);
    metal::float3 _e166 = thicken;
    metal::float3 world = (_e163 * metal::float4(_e165 + _e166, 1.0)).xyz;
    metal::float4x4 _e176 = frame.view_proj;
    out.clip = _e176 * metal::float4(world, 1.0);
    out.world = world;
    metal::float2 _e182 = blade_uv(v_4, params);
    out.uv = _e182;
    metal::float4x4 _e186 = frame.model;
    out.width_axis = metal::normalize((_e186 * metal::float4(_e35.width, 0.0)).xyz);
    uint _e197 = blades[b_1].cluster;
    out.ids = metal::uint2(b_1, _e197);
    float _e200 = fade;
    out.fade = _e200;
    BladeOut _e201 = out;
    const auto _tmp = _e201;
    return vs_bladeOutput { _tmp.clip, _tmp.world, _tmp.uv, _tmp.width_axis, _tmp.ids, _tmp.fade };
}
