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

struct LightSample {
    float3 l;
    int _pad1_0;
    float3 radiance;
    int _end_pad_0;
};

struct Fur {
    float4 tint;
    float fur_length_m;
    float shear_exponent;
    float alpha_threshold;
    uint atlas_layers;
    uint drawn_layers;
    float fin_repeat_m;
    uint scale_layout;
    uint pad1_;
    float4 tip_color;
    float4 secondary_tint;
    float4 specular;
    float4 strand;
    float4 stacking;
};

struct ShellOut {
    float4 clip_ : SV_Position;
    float3 normal : LOC0;
    float4 color : LOC1;
    float2 uv : LOC2;
    nointerpolation uint slice : LOC3;
    float3 tangent : LOC4;
    float3 world : LOC5;
    nointerpolation float height : LOC6;
    nointerpolation float fade : LOC7;
};

static const uint STACK_ANGLES = 9u;
static const uint STACK_MIPS = 6u;
static const uint STACK_COUNTS = 7u;
static const bool LAMBERT = true;
static const bool SHADOW = true;
static const bool STRAND = true;
static const bool ALPHA_BLEND = true;
static const bool ALPHA_TO_COVERAGE = false;
static const uint LIGHT_SLOTS = 2u;

cbuffer frame : register(b0) { Frame frame; }
cbuffer fur : register(b1) { Fur fur; }
ByteAddressBuffer shadow : register(t3);
Texture2DArray<float4> shell_alpha : register(t4);
SamplerState nagaSamplerHeap[2048]: register(s0, space0);
SamplerComparisonState nagaComparisonSamplerHeap[2048]: register(s0, space1);
StructuredBuffer<uint> nagaGroup0SamplerIndexArray : register(t0, space255);
static const SamplerState repeat_sampler = nagaSamplerHeap[nagaGroup0SamplerIndexArray[5]];
ByteAddressBuffer stacking : register(t9);

struct FragmentInput_fs_shell {
    float3 normal : LOC0;
    float4 color : LOC1;
    float2 uv : LOC2;
    nointerpolation uint slice : LOC3;
    float3 tangent_2 : LOC4;
    float3 world_3 : LOC5;
    nointerpolation float height : LOC6;
    nointerpolation float fade : LOC7;
    float4 clip_ : SV_Position;
};

uint light_count()
{
    uint _e3 = frame.light_count.x;
    return min(_e3, 4u);
}

LightSample ConstructLightSample(float3 arg0, float3 arg1) {
    LightSample ret = (LightSample)0;
    ret.l = arg0;
    ret.radiance = arg1;
    return ret;
}

LightSample light_at(uint i, float3 world)
{
    float falloff = (float)0;

    Light light_1 = frame.lights[i];
    if ((light_1.vector_.w == 0.0)) {
        const LightSample lightsample = ConstructLightSample(light_1.vector_.xyz, light_1.radiance.xyz);
        return lightsample;
    }
    float3 d = (light_1.vector_.xyz - world);
    float dist2_ = max(dot(d, d), 1e-8);
    falloff = (1.0 / dist2_);
    if ((light_1.radiance.w > 0.0)) {
        float r = (dist2_ / (light_1.radiance.w * light_1.radiance.w));
        float window = saturate((1.0 - (r * r)));
        float _e38 = falloff;
        falloff = (_e38 * (window * window));
    }
    float _e45 = falloff;
    const LightSample lightsample_1 = ConstructLightSample((d * rsqrt(dist2_)), (light_1.radiance.xyz * _e45));
    return lightsample_1;
}

float3 ambient_at(float3 n)
{
    float4 _e3 = frame.ambient_ground;
    float4 _e7 = frame.ambient_sky;
    return lerp(_e3.xyz, _e7.xyz, (0.5 + (0.5 * n.y)));
}

float coverage_alpha(float alpha_1, float edge_1)
{
    float _e4 = fur.alpha_threshold;
    return saturate((((alpha_1 - _e4) / max(edge_1, 0.0001)) + 0.5));
}

bool alpha_discarded(float alpha_2, float edge_2)
{
    if (ALPHA_TO_COVERAGE) {
        const float _e3 = coverage_alpha(alpha_2, edge_2);
        return (_e3 <= 0.0);
    }
    float _e8 = fur.alpha_threshold;
    return (alpha_2 <= _e8);
}

float3 lambert(float3 n_in, float3 world_1)
{
    float3 rgb_1 = (float3)0;
    uint i_1 = 0u;

    if (false) {
        return (1.0).xxx;
    }
    float3 n_2 = normalize(n_in);
    const float3 _e8 = ambient_at(n_2);
    rgb_1 = _e8;
    const uint _e10 = light_count();
    uint2 loop_bound = uint2(4294967295u, 4294967295u);
    bool loop_init = true;
    while(true) {
        if (all(loop_bound == uint2(0u, 0u))) { break; }
        loop_bound -= uint2(loop_bound.y == 0u, 1u);
        if (!loop_init) {
            uint _e29 = i_1;
            i_1 = (_e29 + 1u);
        }
        loop_init = false;
        uint _e13 = i_1;
        if ((_e13 < LIGHT_SLOTS)) {
        } else {
            break;
        }
        {
            uint _e16 = i_1;
            if ((_e16 < _e10)) {
                uint _e18 = i_1;
                const LightSample _e19 = light_at(_e18, world_1);
                float3 _e20 = rgb_1;
                rgb_1 = (_e20 + (_e19.radiance * max(dot(n_2, _e19.l), 0.0)));
            }
        }
    }
    float3 _e31 = rgb_1;
    return _e31;
}

float cell_noise(int x, int y)
{
    uint h = (uint)0;

    h = ((asuint(x) * 747796405u) + 2891336453u);
    uint _e8 = h;
    h = (_e8 ^ (asuint(y) * 277803737u));
    uint _e13 = h;
    uint _e14 = h;
    uint _e20 = h;
    h = (((_e13 >> ((_e14 >> 28u) + 4u)) ^ _e20) * 277803737u);
    uint _e24 = h;
    uint _e27 = h;
    h = ((_e24 >> 22u) ^ _e27);
    uint _e29 = h;
    return (float((_e29 >> 8u)) / 16777216.0);
}

float strand_lobe(float th, float sin_th, float shift, float exponent)
{
    float shifted = ((th + (shift * sin_th)) * rsqrt((1.0 + (shift * shift))));
    float sin2_ = max((1.0 - (shifted * shifted)), 0.0);
    return (((exponent + 2.0) * 0.15915494) * pow(sin2_, (0.5 * exponent)));
}

float3 strand_light(LightSample light, float3 n_1, float3 t, float3 v, float3 colour, float sin2_tv, float mask)
{
    float3 half_vector = (float3)0;

    float3 l = light.l;
    float nl = dot(n_1, l);
    float body = saturate(((nl + 0.15) / 1.15));
    float wrap = (0.5 + (0.5 * nl));
    float tl = dot(t, l);
    float kajiya_kay = sqrt(max((1.0 - (tl * tl)), 0.0));
    float _e31 = fur.strand.w;
    float diffuse = lerp(max(nl, 0.0), (kajiya_kay * body), _e31);
    half_vector = n_1;
    float3 lv = (l + v);
    if ((dot(lv, lv) > 1e-8)) {
        half_vector = normalize(lv);
    }
    float3 _e39 = half_vector;
    float th_1 = dot(t, _e39);
    float sin_th_1 = sqrt(max((1.0 - (th_1 * th_1)), 0.0));
    float _e50 = fur.specular.x;
    float _e54 = fur.strand.x;
    float _e58 = fur.specular.y;
    const float _e59 = strand_lobe(th_1, sin_th_1, _e54, _e58);
    float primary = (_e50 * _e59);
    float _e64 = fur.specular.z;
    float _e68 = fur.strand.y;
    float _e72 = fur.specular.w;
    const float _e73 = strand_lobe(th_1, sin_th_1, _e68, _e72);
    float secondary = ((_e64 * _e73) * mask);
    float4 _e79 = fur.secondary_tint;
    float3 specular = (body * ((primary).xxx + ((secondary * _e79.xyz) * colour)));
    float behind = (0.5 - (0.5 * dot(v, l)));
    float behind2_ = (behind * behind);
    float _e94 = fur.strand.z;
    float3 back = ((((_e94 * colour) * (behind2_ * behind2_)) * sin2_tv) * wrap);
    return (light.radiance * (((colour * diffuse) + specular) + back));
}

float3 strand_shade(float3 albedo, float3 n_in_1, float3 tangent, float3 world_2, float3 to_eye, float h_1, float direct_1, float mask_1)
{
    float3 t_1 = (float3)0;
    float3 rgb_2 = (float3)0;
    uint i_2 = 0u;

    float3 n_3 = normalize(n_in_1);
    t_1 = n_3;
    if ((dot(tangent, tangent) > 1e-12)) {
        t_1 = normalize(tangent);
    }
    float4 _e18 = fur.tip_color;
    float3 colour_1 = (albedo * lerp((1.0).xxx, _e18.xyz, h_1));
    float _e25 = fur.tip_color.w;
    float occlusion = (1.0 - (_e25 * (1.0 - h_1)));
    const float3 _e31 = ambient_at(n_3);
    rgb_2 = ((colour_1 * _e31) * occlusion);
    float3 _e35 = t_1;
    float tv = dot(_e35, to_eye);
    float sin2_tv_1 = max((1.0 - (tv * tv)), 0.0);
    const uint _e42 = light_count();
    uint2 loop_bound_1 = uint2(4294967295u, 4294967295u);
    bool loop_init_1 = true;
    while(true) {
        if (all(loop_bound_1 == uint2(0u, 0u))) { break; }
        loop_bound_1 -= uint2(loop_bound_1.y == 0u, 1u);
        if (!loop_init_1) {
            uint _e58 = i_2;
            i_2 = (_e58 + 1u);
        }
        loop_init_1 = false;
        uint _e45 = i_2;
        if ((_e45 < LIGHT_SLOTS)) {
        } else {
            break;
        }
        {
            uint _e48 = i_2;
            if ((_e48 < _e42)) {
                float3 _e50 = rgb_2;
                uint _e51 = i_2;
                const LightSample _e52 = light_at(_e51, world_2);
                float3 _e53 = t_1;
                const float3 _e54 = strand_light(_e52, n_3, _e53, to_eye, colour_1, sin2_tv_1, mask_1);
                rgb_2 = (_e50 + (direct_1 * _e54));
            }
        }
    }
    float3 _e60 = rgb_2;
    return _e60;
}

float strand_mask(int x_1, int y_1)
{
    float _e5 = fur.secondary_tint.w;
    const float _e6 = cell_noise(x_1, y_1);
    return (1.0 - (_e5 * _e6));
}

float stacking_at(uint angle, uint mip, uint count)
{
    float _e11 = asfloat(stacking.Load(((((angle * STACK_MIPS) + mip) * STACK_COUNTS) + count)*4));
    return _e11;
}

uint naga_f2u32(float value) {
    return uint(clamp(value, 0.0, 4294967000.0));
}

float stacked_alpha(float alpha_3, float3 to_eye_1, float3 tangent_1, float lod_1)
{
    bool local_3 = (bool)0;
    float e = 0.0;
    uint i_3 = 0u;

    float _e7 = fur.stacking.x;
    if (!((_e7 == 0.0))) {
        local_3 = (alpha_3 >= 1.0);
    } else {
        local_3 = true;
    }
    bool _e16 = local_3;
    if (_e16) {
        return alpha_3;
    }
    float angle_1 = clamp((degrees(acos(clamp(abs(dot(to_eye_1, tangent_1)), 0.0, 1.0))) / 10.0), 0.0, 8.0);
    float mip_1 = clamp(lod_1, 0.0, 5.0);
    float _e35 = frame.shells.z;
    float count_1 = clamp(log2(max(_e35, 1.0)), 0.0, 6.0);
    uint a0_ = min(naga_f2u32(angle_1), 7u);
    uint m0_ = min(naga_f2u32(mip_1), 4u);
    uint c0_ = min(naga_f2u32(count_1), 5u);
    float fa = (angle_1 - float(a0_));
    float fm = (mip_1 - float(m0_));
    float fc = (count_1 - float(c0_));
    uint2 loop_bound_2 = uint2(4294967295u, 4294967295u);
    bool loop_init_2 = true;
    while(true) {
        if (all(loop_bound_2 == uint2(0u, 0u))) { break; }
        loop_bound_2 -= uint2(loop_bound_2.y == 0u, 1u);
        if (!loop_init_2) {
            uint _e103 = i_3;
            i_3 = (_e103 + 1u);
        }
        loop_init_2 = false;
        uint _e61 = i_3;
        if ((_e61 < 8u)) {
        } else {
            break;
        }
        {
            uint _e64 = i_3;
            uint da = (_e64 & 1u);
            uint _e67 = i_3;
            uint dm = ((_e67 >> 1u) & 1u);
            uint _e72 = i_3;
            uint dc = ((_e72 >> 2u) & 1u);
            float w = ((((da == 1u) ? fa : (1.0 - fa)) * ((dm == 1u) ? fm : (1.0 - fm))) * ((dc == 1u) ? fc : (1.0 - fc)));
            float _e94 = e;
            const float _e98 = stacking_at((a0_ + da), (m0_ + dm), (c0_ + dc));
            e = (_e94 + (w * log2(_e98)));
        }
    }
    float _e107 = e;
    return (1.0 - pow((1.0 - alpha_3), exp2(_e107)));
}

uint2 naga_mod(uint2 lhs, uint2 rhs) {
    return lhs % (rhs == 0u ? 1u : rhs);
}

typedef uint ret_Constructarray16_uint_[16];
ret_Constructarray16_uint_ Constructarray16_uint_(uint arg0, uint arg1, uint arg2, uint arg3, uint arg4, uint arg5, uint arg6, uint arg7, uint arg8, uint arg9, uint arg10, uint arg11, uint arg12, uint arg13, uint arg14, uint arg15) {
    uint ret[16] = { arg0, arg1, arg2, arg3, arg4, arg5, arg6, arg7, arg8, arg9, arg10, arg11, arg12, arg13, arg14, arg15 };
    return ret;
}

uint2 naga_f2u32(float2 value) {
    return uint2(clamp(value, 0.0, 4294967000.0));
}

float dither_4x4_(float2 xy)
{
    uint2 p = naga_mod(naga_f2u32(xy), (4u).xx);
    uint bayer[16] = Constructarray16_uint_(0u, 8u, 2u, 10u, 12u, 4u, 14u, 6u, 3u, 11u, 1u, 9u, 15u, 7u, 13u, 5u);
    return ((float(bayer[min(uint(((p.y * 4u) + p.x)), 15u)]) + 0.5) / 16.0);
}

int2 naga_f2i32(float2 value) {
    return int2(clamp(value, -2147483600.0, 2147483500.0));
}

uint2 NagaDimensions2DArray(Texture2DArray<float4> tex)
{
    uint4 ret;
    tex.GetDimensions(0, ret.x, ret.y, ret.z, ret.w);
    return ret.xy;
}

float4 fs_shell(FragmentInput_fs_shell fragmentinput_fs_shell) : SV_Target0
{
    ShellOut in_ = { fragmentinput_fs_shell.clip_, fragmentinput_fs_shell.normal, fragmentinput_fs_shell.color, fragmentinput_fs_shell.uv, fragmentinput_fs_shell.slice, fragmentinput_fs_shell.tangent_2, fragmentinput_fs_shell.world_3, fragmentinput_fs_shell.height, fragmentinput_fs_shell.fade };
    float alpha = (float)0;
    float edge = 0.0;
    float lod = 0.0;
    bool local = (bool)0;
    bool local_1 = (bool)0;
    float3 rgb = (float3)0;
    bool local_2 = (bool)0;
    float direct = 1.0;
    float3 shade = (float3)0;

    if (ALPHA_BLEND) {
        float4 _e7 = shell_alpha.Sample(repeat_sampler, float3(in_.uv, in_.slice));
        alpha = _e7.x;
    } else {
        float4 _e14 = shell_alpha.SampleLevel(repeat_sampler, float3(in_.uv, in_.slice), 0.0);
        alpha = _e14.x;
    }
    if (ALPHA_TO_COVERAGE) {
        float _e19 = alpha;
        float _e20 = fwidth(_e19);
        edge = _e20;
    }
    if (ALPHA_BLEND) {
        float2 texel = (in_.uv * float2(NagaDimensions2DArray(shell_alpha)));
        float2 _e29 = ddx(texel);
        float across = length(_e29);
        float2 _e31 = ddy(texel);
        float down = length(_e31);
        float _e38 = fur.stacking.y;
        lod = log2(max(max(min(across, down), (max(across, down) / max(_e38, 1.0))), 1e-6));
    }
    float _e46 = alpha;
    float _e47 = edge;
    const bool _e48 = alpha_discarded(_e46, _e47);
    if (_e48) {
        discard;
    }
    if ((in_.fade < 1.0)) {
        local = false;
    } else {
        local = false;
    }
    bool _e58 = local;
    if (_e58) {
        const float _e64 = dither_4x4_(in_.clip_.xy);
        local_1 = (in_.fade <= _e64);
    } else {
        local_1 = false;
    }
    bool _e67 = local_1;
    if (_e67) {
        discard;
    }
    float4 _e70 = frame.camera_pos;
    float3 to_eye_2 = normalize((_e70.xyz - in_.world));
    if (ALPHA_BLEND) {
        float _e76 = alpha;
        float _e79 = lod;
        const float _e80 = stacked_alpha(_e76, to_eye_2, normalize(in_.tangent), _e79);
        alpha = (_e80 * in_.fade);
    }
    if (STRAND) {
        local_2 = LAMBERT;
    } else {
        local_2 = false;
    }
    bool _e89 = local_2;
    if (_e89) {
        if (SHADOW) {
            float _e96 = asfloat(shadow.Load(in_.slice*4));
            direct = _e96;
        }
        float2 size = float2(NagaDimensions2DArray(shell_alpha));
        int2 cell = naga_f2i32(min(floor((frac(in_.uv) * size)), (size - (1.0).xx)));
        float4 _e113 = fur.tint;
        float3 albedo_1 = (in_.color.xyz * _e113.xyz);
        float _e120 = direct;
        const float _e123 = strand_mask(cell.x, cell.y);
        const float3 _e124 = strand_shade(albedo_1, in_.normal, in_.tangent, in_.world, to_eye_2, in_.height, _e120, _e123);
        rgb = _e124;
    } else {
        const float3 _e127 = lambert(in_.normal, in_.world);
        shade = _e127;
        if (SHADOW) {
            float3 _e130 = shade;
            float _e134 = asfloat(shadow.Load(in_.slice*4));
            shade = (_e130 * _e134);
        }
        float4 _e140 = fur.tint;
        float3 _e143 = shade;
        rgb = ((in_.color.xyz * _e140.xyz) * _e143);
    }
    if (ALPHA_BLEND) {
        float3 _e146 = rgb;
        float _e147 = alpha;
        return float4(_e146, _e147);
    }
    if (ALPHA_TO_COVERAGE) {
        float3 _e150 = rgb;
        float _e151 = alpha;
        float _e152 = edge;
        const float _e153 = coverage_alpha(_e151, _e152);
        return float4(_e150, _e153);
    }
    float3 _e155 = rgb;
    return float4(_e155, 1.0);
}
