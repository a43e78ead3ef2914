struct NagaConstants {
    int first_vertex;
    int first_instance;
    uint other;
};
ConstantBuffer<NagaConstants> _NagaConstants: register(b0, space8);

struct Light {
    float4 vector_;
    float4 radiance;
};

struct Frame {
    row_major float4x4 view_proj;
    float4 camera_pos;
    float4 ambient_sky;
    float4 ambient_ground;
    uint4 light_count;
    Light lights[4];
    row_major float4x4 model;
    float4 viewport;
    float4 shells;
};

struct Blade {
    float4 root;
    float2 yaw;
    uint cluster;
    uint pad;
    float4 weights;
};

struct CullUniforms {
    float4 planes[6];
    float4 eye;
    float4 lod;
    float4 distance_;
    float4 shape;
    uint4 index_count;
    uint4 first_index;
    uint4 counts;
    row_major float4x4 clip_;
    uint4 occlusion;
};

struct BladeUniforms {
    float4 color;
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
    float4 tip_color;
    float4 shade;
    float4 gloss;
};

struct Pose {
    uint4 keys_m;
    uint4 keys_j;
    float4 weights;
    uint count;
    int _pad4_0;
    int _pad4_1;
    int _pad4_2;
    float3 root;
    float height;
    float3 width;
    int _pad7_0;
    float3 normal;
    int _end_pad_0;
};

struct BladeOut {
    float4 clip_ : SV_Position;
    float3 world : LOC0;
    float2 uv : LOC1;
    float3 width_axis : LOC2;
    nointerpolation uint2 ids : LOC3;
    nointerpolation float fade : LOC4;
};

static const uint SALT_THINNING = 1759714724u;
static const uint SALT_LOD = 3039394381u;
static const uint CULLED = 4294967295u;
static const uint OCCLUDED = 4294967294u;
static const float PI = 3.1415927;
static const float TAU = 6.2831855;
static const uint STATIC_VERTEX = 4294967295u;
static const float FADE_START = 0.6;

cbuffer frame : register(b0) { Frame frame; }
ByteAddressBuffer blades : register(t2);
cbuffer params : register(b1) { BladeUniforms params; }
ByteAddressBuffer payload_ : register(t4);
ByteAddressBuffer vertex_map : register(t5);
ByteAddressBuffer reference : register(t6);
cbuffer cull : register(b9) { CullUniforms cull; }
ByteAddressBuffer instances : register(t10);

struct VertexOutput_vs_blade {
    float3 world : LOC0;
    float2 uv : LOC1;
    float3 width_axis : LOC2;
    nointerpolation uint2 ids : LOC3;
    nointerpolation float fade_1 : LOC4;
    float4 clip_ : SV_Position;
};

float thinning_keep(float start, float min_density, float d)
{
    float s = (start / max(d, 1e-30));
    return min(max((s * s), min_density), 1.0);
}

float f16_to_f32_(uint h)
{
    uint sign_ = ((h & 32768u) << 16u);
    uint e = ((h >> 10u) & 31u);
    uint m_1 = (h & 1023u);
    if ((e == 0u)) {
        float v_3 = (float(m_1) * 5.9604645e-8);
        return ((sign_ != 0u) ? -(v_3) : v_3);
    }
    if ((e == 31u)) {
        return asfloat(((sign_ | 2139095040u) | (m_1 << 13u)));
    }
    return asfloat(((sign_ | ((e + 112u) << 23u)) | (m_1 << 13u)));
}

float component(uint i)
{
    uint _e3 = params.encoding;
    switch(_e3) {
        case 1u: {
            uint _e8 = asuint(payload_.Load((i >> 1u)*4));
            uint bits = ((_e8 >> ((i & 1u) * 16u)) & 65535u);
            int q = (asint((bits << 16u)) >> 16u);
            float _e26 = params.scale;
            return ((float(q) / 32767.0) * _e26);
        }
        case 2u: {
            uint _e32 = asuint(payload_.Load((i >> 1u)*4));
            const float _e40 = f16_to_f32_(((_e32 >> ((i & 1u) * 16u)) & 65535u));
            return _e40;
        }
        case 3u: {
            uint _e45 = asuint(payload_.Load((i >> 2u)*4));
            uint q_1 = ((_e45 >> ((i & 3u) * 8u)) & 255u);
            float _e60 = params.scale;
            return (((float(q_1) * 0.007843138) - 1.0) * _e60);
        }
        case 4u: {
            uint _e66 = asuint(payload_.Load((i >> 2u)*4));
            uint bits_1 = ((_e66 >> ((i & 3u) * 8u)) & 255u);
            int q_2 = (asint((bits_1 << 24u)) >> 24u);
            float _e84 = params.scale;
            return ((float(q_2) / 127.0) * _e84);
        }
        default: {
            uint _e88 = asuint(payload_.Load(i*4));
            return asfloat(_e88);
        }
    }
}

uint naga_div(uint lhs, uint rhs) {
    return lhs / (rhs == 0u ? 1u : rhs);
}

float3 displacement(uint m, uint j_full, uint v)
{
    uint j = (uint)0;
    bool flip_x = false;
    bool flip_z = false;
    bool local_1 = (bool)0;
    bool local_2 = (bool)0;
    float3 d_1 = (float3)0;

    if ((m == 0u)) {
        return (0.0).xxx;
    }
    uint mapped = asuint(vertex_map.Load(v*4));
    if ((mapped == STATIC_VERTEX)) {
        return (0.0).xxx;
    }
    uint a = params.angles;
    j = j_full;
    uint _e24 = params.mirror_x;
    if ((_e24 != 0u)) {
        uint _e29 = j;
        local_1 = (_e29 >= naga_div(a, 2u));
    } else {
        local_1 = false;
    }
    bool _e34 = local_1;
    if (_e34) {
        uint _e37 = j;
        j = ((a - 1u) - _e37);
        flip_x = true;
    }
    uint _e42 = params.mirror_z;
    if ((_e42 != 0u)) {
        uint _e47 = j;
        local_2 = (_e47 >= naga_div(a, 4u));
    } else {
        local_2 = false;
    }
    bool _e52 = local_2;
    if (_e52) {
        uint _e57 = j;
        j = ((naga_div(a, 2u) - 1u) - _e57);
        flip_z = true;
    }
    uint _e64 = params.stored_angles;
    uint _e66 = j;
    uint pose_2 = (((m - 1u) * _e64) + _e66);
    uint _e70 = params.stored_vectors;
    uint base = (((pose_2 * _e70) + mapped) * 3u);
    const float _e75 = component(base);
    const float _e78 = component((base + 1u));
    const float _e81 = component((base + 2u));
    d_1 = float3(_e75, _e78, _e81);
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
    float3 _e94 = d_1;
    return _e94;
}

int naga_mod(int lhs, int rhs) {
    int divisor = ((lhs == int(-2147483647 - 1) & rhs == -1) | (rhs == 0)) ? 1 : rhs;
    return lhs - (lhs / divisor) * divisor;
}

uint wrap_angle(int j_1)
{
    uint _e3 = params.angles;
    int a_1 = int(_e3);
    return uint(naga_mod(asint(asuint(naga_mod(j_1, a_1)) + asuint(a_1)), a_1));
}

uint naga_f2u32(float value) {
    return uint(clamp(value, 0.0, 4294967000.0));
}

int naga_f2i32(float value) {
    return int(clamp(value, -2147483600.0, 2147483500.0));
}

Blade ConstructBlade(float4 arg0, float2 arg1, uint arg2, uint arg3, float4 arg4) {
    Blade ret = (Blade)0;
    ret.root = arg0;
    ret.yaw = arg1;
    ret.cluster = arg2;
    ret.pad = arg3;
    ret.weights = arg4;
    return ret;
}

Pose pose_from(uint b, float2 grid)
{
    Pose pose = (Pose)0;
    uint j_2 = (uint)0;

    Blade blade = ConstructBlade(asfloat(blades.Load4(b*48+0)), asfloat(blades.Load2(b*48+16)), asuint(blades.Load(b*48+24)), asuint(blades.Load(b*48+28)), asfloat(blades.Load4(b*48+32)));
    float c = blade.yaw.x;
    float s_1 = blade.yaw.y;
    pose.width = float3(c, 0.0, -(s_1));
    pose.normal = float3(s_1, 0.0, c);
    pose.root = blade.root.xyz;
    pose.height = blade.root.w;
    float mu = grid.x;
    float alpha = grid.y;
    pose.keys_m = (0u).xxxx;
    pose.keys_j = (0u).xxxx;
    pose.weights = float4(1.0, 0.0, 0.0, 0.0);
    pose.count = 1u;
    uint _e41 = params.interpolation;
    if ((_e41 == 0u)) {
        j_2 = naga_f2u32((alpha + 0.5));
        uint _e48 = j_2;
        uint _e51 = params.angles;
        if ((_e48 >= _e51)) {
            uint _e53 = j_2;
            uint _e56 = params.angles;
            j_2 = (_e53 - _e56);
        }
        uint _e65 = params.magnitudes;
        pose.keys_m.x = min(naga_f2u32((mu + 0.5)), _e65);
        uint _e69 = j_2;
        pose.keys_j.x = _e69;
    } else {
        uint _e73 = params.magnitudes;
        float m0_ = max(min(floor(mu), (float(_e73) - 1.0)), 0.0);
        float tm = clamp((mu - m0_), 0.0, 1.0);
        float j0f = floor(alpha);
        float ta = clamp((alpha - j0f), 0.0, 1.0);
        uint m0u = naga_f2u32(m0_);
        const uint _e91 = wrap_angle(naga_f2i32(j0f));
        const uint _e95 = wrap_angle(asint(asuint(naga_f2i32(j0f)) + asuint(int(1))));
        pose.keys_m = uint4(m0u, m0u, (m0u + 1u), (m0u + 1u));
        pose.keys_j = uint4(_e91, _e95, _e91, _e95);
        pose.weights = float4(((1.0 - tm) * (1.0 - ta)), ((1.0 - tm) * ta), (tm * (1.0 - ta)), (tm * ta));
        pose.count = 4u;
    }
    Pose _e120 = pose;
    const Pose pose_3 = _e120;
    return pose_3;
}

float3 vertex_position(Pose pose_1, uint v_1, float widen_1)
{
    float3 d_2 = (0.0).xxx;
    uint k = 0u;

    uint2 loop_bound = uint2(4294967295u, 4294967295u);
    bool loop_init = true;
    while(true) {
        if (all(loop_bound == uint2(0u, 0u))) { break; }
        loop_bound -= uint2(loop_bound.y == 0u, 1u);
        if (!loop_init) {
            uint _e25 = k;
            k = (_e25 + 1u);
        }
        loop_init = false;
        uint _e8 = k;
        if ((_e8 < pose_1.count)) {
        } else {
            break;
        }
        {
            float3 _e11 = d_2;
            uint _e13 = k;
            uint _e16 = k;
            const float3 _e18 = displacement(pose_1.keys_m[min(uint(_e13), 3u)], pose_1.keys_j[min(uint(_e16), 3u)], v_1);
            uint _e20 = k;
            d_2 = (_e11 + (_e18 * pose_1.weights[min(uint(_e20), 3u)]));
        }
    }
    float4 _e29 = asfloat(reference.Load4(v_1*16));
    float3 r = _e29.xyz;
    float3 _e31 = d_2;
    float3 p = ((r + _e31) + float3((r.x * (widen_1 - 1.0)), 0.0, 0.0));
    return (pose_1.root + ((((pose_1.width * p.x) + float3(0.0, p.y, 0.0)) + (pose_1.normal * p.z)) * pose_1.height));
}

uint naga_mod(uint lhs, uint rhs) {
    return lhs % (rhs == 0u ? 1u : rhs);
}

float2 blade_uv(uint v_2)
{
    uint _e3 = params.vertex_count;
    uint segments = max(naga_div(_e3, 4u), 1u);
    uint level = (naga_div(v_2, 4u) + naga_div(naga_mod(v_2, 4u), 2u));
    return float2(float((v_2 & 1u)), (float(level) / float(segments)));
}

VertexOutput_vs_blade vs_blade(uint vi : SV_VertexID, uint instance : SV_InstanceID)
{
    float widen = 1.0;
    float fade = 0.0;
    float3 thicken = (0.0).xxx;
    bool local = (bool)0;
    BladeOut out_ = (BladeOut)0;

    uint _e4 = params.vertex_count;
    uint lod = naga_div((_NagaConstants.first_vertex + vi), _e4);
    uint _e8 = params.vertex_count;
    uint v_4 = ((_NagaConstants.first_vertex + vi) - (lod * _e8));
    uint _e15 = asuint(instances.Load(lod*4));
    uint entry = (4u + (3u * (_e15 + (_NagaConstants.first_instance + instance))));
    uint b_1 = asuint(instances.Load(entry*4));
    uint _e26 = asuint(instances.Load((entry + 1u)*4));
    uint _e32 = asuint(instances.Load((entry + 2u)*4));
    float2 grid_1 = float2(asfloat(_e26), asfloat(_e32));
    const Pose _e35 = pose_from(b_1, grid_1);
    float4 _e39 = frame.model[0];
    float4 _e44 = frame.model[1];
    float4 _e49 = frame.model[2];
    float3x3 m3_ = float3x3(_e39.xyz, _e44.xyz, _e49.xyz);
    float4 _e55 = frame.camera_pos;
    float4 _e60 = frame.model[3];
    float3 eye = (mul((_e55.xyz - _e60.xyz), transpose(m3_)) / (max(dot(m3_[0], m3_[0]), 1e-12)).xxx);
    float4 _e74 = asfloat(blades.Load4(0+b_1*48));
    float3 to_eye = (eye - _e74.xyz);
    float d_3 = length(to_eye);
    float _e85 = cull.eye.w;
    if ((_e85 != 0.0)) {
        float _e91 = cull.distance_.y;
        float _e95 = cull.distance_.z;
        const float _e96 = thinning_keep(_e91, _e95, d_3);
        widen = (1.0 / _e96);
        float _e102 = cull.distance_.x;
        float far = sqrt(_e102);
        fade = smoothstep((FADE_START * far), far, d_3);
    }
    float3 view = (to_eye / (max(d_3, 1e-6)).xxx);
    float3 width_axis_1 = normalize(_e35.width);
    float along = dot(width_axis_1, view);
    float seen = sqrt(max((1.0 - (along * along)), 0.0));
    float3 side = cross(float3(0.0, 1.0, 0.0), view);
    float _e131 = cull.shape.z;
    if ((seen < _e131)) {
        local = (dot(side, side) > 1e-8);
    } else {
        local = false;
    }
    bool _e139 = local;
    if (_e139) {
        float3 s_2 = (normalize(side) * sign((dot(side, width_axis_1) + 1e-9)));
        float _e149 = asfloat(reference.Load(0+v_4*16));
        float _e150 = widen;
        float _e157 = cull.shape.z;
        thicken = (s_2 * (((_e149 * _e150) * _e35.height) * (_e157 - seen)));
    }
    float4x4 _e163 = frame.model;
    float _e164 = widen;
    const float3 _e165 = vertex_position(_e35, v_4, _e164);
    float3 _e166 = thicken;
    float3 world_1 = mul(float4((_e165 + _e166), 1.0), _e163).xyz;
    float4x4 _e176 = frame.view_proj;
    out_.clip_ = mul(float4(world_1, 1.0), _e176);
    out_.world = world_1;
    const float2 _e182 = blade_uv(v_4);
    out_.uv = _e182;
    float4x4 _e186 = frame.model;
    out_.width_axis = normalize(mul(float4(_e35.width, 0.0), _e186).xyz);
    uint _e197 = asuint(blades.Load(24+b_1*48));
    out_.ids = uint2(b_1, _e197);
    float _e200 = fade;
    out_.fade = _e200;
    BladeOut _e201 = out_;
    const BladeOut bladeout = _e201;
    const VertexOutput_vs_blade bladeout_1 = { bladeout.world, bladeout.uv, bladeout.width_axis, bladeout.ids, bladeout.fade, bladeout.clip_ };
    return bladeout_1;
}
