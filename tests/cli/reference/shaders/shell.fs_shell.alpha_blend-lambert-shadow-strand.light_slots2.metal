// language: metal2.0
#include <metal_stdlib>
#include <simd/simd.h>

using metal::uint;

struct _mslBufferSizes {
    uint size2;
    uint size5;
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
struct LightSample {
    metal::float3 l;
    metal::float3 radiance;
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
typedef float type_8[1];
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
struct type_13 {
    uint inner[16];
};
constant uint STACK_ANGLES = 9u;
constant uint STACK_MIPS = 6u;
constant uint STACK_COUNTS = 7u;
constant bool LAMBERT = true;
constant bool SHADOW = true;
constant bool STRAND = true;
constant bool ALPHA_BLEND = true;
constant bool ALPHA_TO_COVERAGE = false;
constant uint LIGHT_SLOTS = 2u;

uint light_count(
    constant Frame& frame
) {
    uint _e3 = frame.light_count.x;
    return metal::min(_e3, 4u);
}

LightSample light_at(
    uint i,
    metal::float3 world,
    constant Frame& frame
) {
    float falloff = {};
    Light light_1 = frame.lights.inner[i];
    if (light_1.vector.w == 0.0) {
        return LightSample {light_1.vector.xyz, light_1.radiance.xyz};
    }
    metal::float3 d = light_1.vector.xyz - world;
    float dist2_ = metal::max(metal::dot(d, d), 0.00000001);
    falloff = 1.0 / dist2_;
    if (light_1.radiance.w > 0.0) {
        float r = dist2_ / (light_1.radiance.w * light_1.radiance.w);
        float window = metal::saturate(1.0 - (r * r));
        float _e38 = falloff;
        falloff = _e38 * (window * window);
    }
    float _e45 = falloff;
    return LightSample {d * metal::rsqrt(dist2_), light_1.radiance.xyz * _e45};
}

metal::float3 ambient_at(
    metal::float3 n,
    constant Frame& frame
) {
    metal::float4 _e3 = frame.ambient_ground;
    metal::float4 _e7 = frame.ambient_sky;
    return metal::mix(_e3.xyz, _e7.xyz, 0.5 + (0.5 * n.y));
}

float coverage_alpha(
    float alpha_1,
    float edge_1,
    constant Fur& fur
) {
    float _e4 = fur.alpha_threshold;
    return metal::saturate(((alpha_1 - _e4) / metal::max(edge_1, 0.0001)) + 0.5);
}

bool alpha_discarded(
    float alpha_2,
    float edge_2,
    constant Fur& fur
) {
    if (ALPHA_TO_COVERAGE) {
        float _e3 = coverage_alpha(alpha_2, edge_2, fur);
        return _e3 <= 0.0;
    }
    float _e8 = fur.alpha_threshold;
    return alpha_2 <= _e8;
}

metal::float3 lambert(
    metal::float3 n_in,
    metal::float3 world_1,
    constant Frame& frame
) {
    metal::float3 rgb_1 = {};
    uint i_1 = 0u;
    if (false) {
        return metal::float3(1.0);
    }
    metal::float3 n_2 = metal::normalize(n_in);
    metal::float3 _e8 = ambient_at(n_2, frame);
    rgb_1 = _e8;
    uint _e10 = light_count(frame);
    uint2 loop_bound = uint2(4294967295u);
    bool loop_init = true;
    while(true) {
        if (metal::all(loop_bound == uint2(0u))) { break; }
        loop_bound -= uint2(loop_bound.y == 0u, 1u);
        if (!loop_init) {
            uint _e29 = i_1;
            i_1 = _e29 + 1u;
        }
        loop_init = false;
        uint _e13 = i_1;
        if (_e13 < LIGHT_SLOTS) {
        } else {
            break;
        }
        {
            uint _e16 = i_1;
            if (_e16 < _e10) {
                uint _e18 = i_1;
                LightSample _e19 = light_at(_e18, world_1, frame);
                metal::float3 _e20 = rgb_1;
                rgb_1 = _e20 + (_e19.radiance * metal::max(metal::dot(n_2, _e19.l), 0.0));
            }
        }
    }
    metal::float3 _e31 = rgb_1;
    return _e31;
}

float cell_noise(
    int x,
    int y
) {
    uint h = {};
    h = (as_type<uint>(x) * 747796405u) + 2891336453u;
    uint _e8 = h;
    h = _e8 ^ (as_type<uint>(y) * 277803737u);
    uint _e13 = h;
    uint _e14 = h;
    uint _e20 = h;
    h = ((_e13 >> ((_e14 >> 28u) + 4u)) ^ _e20) * 277803737u;
    uint _e24 = h;
    uint _e27 = h;
    h = (_e24 >> 22u) ^ _e27;
    uint _e29 = h;
    return static_cast<float>(_e29 >> 8u) / 16777216.0;
}

float strand_lobe(
    float th,
    float sin_th,
    float shift,
    float exponent
) {
    float shifted = (th + (shift * sin_th)) * metal::rsqrt(1.0 + (shift * shift));
    float sin2_ = metal::max(1.0 - (shifted * shifted), 0.0);
    return ((exponent + 2.0) * 0.15915494) * metal::pow(sin2_, 0.5 * exponent);
}

metal::float3 strand_light(
    LightSample light,
    metal::float3 n_1,
    metal::float3 t,
    metal::float3 v,
    metal::float3 colour,
    float sin2_tv,
    float mask,
    constant Fur& fur
) {
    metal::float3 half_vector = {};
    metal::float3 l = light.l;
    float nl = metal::dot(n_1, l);
    float body = metal::saturate((nl + 0.15) / 1.15);
    float wrap = 0.5 + (0.5 * nl);
    float tl = metal::dot(t, l);
    float kajiya_kay = metal::sqrt(metal::max(1.0 - (tl * tl), 0.0));
    float _e31 = fur.strand.w;
    float diffuse = metal::mix(metal::max(nl, 0.0), kajiya_kay * body, _e31);
    half_vector = n_1;
    metal::float3 lv = l + v;
    if (metal::dot(lv, lv) > 0.00000001) {
        half_vector = metal::normalize(lv);
    }
    metal::float3 _e39 = half_vector;
    float th_1 = metal::dot(t, _e39);
    float sin_th_1 = metal::sqrt(metal::max(1.0 - (th_1 * th_1), 0.0));
    float _e50 = fur.specular.x;
    float _e54 = fur.strand.x;
    float _e58 = fur.specular.y;
    float _e59 = strand_lobe(th_1, sin_th_1, _e54, _e58);
    float primary = _e50 * _e59;
    float _e64 = fur.specular.z;
    float _e68 = fur.strand.y;
    float _e72 = fur.specular.w;
    float _e73 = strand_lobe(th_1, sin_th_1, _e68, _e72);
    float secondary = (_e64 * _e73) * mask;
    metal::float4 _e79 = fur.secondary_tint;
    metal::float3 specular = body * (metal::float3(primary) + ((secondary * _e79.xyz) * colour));
    float behind = 0.5 - (0.5 * metal::dot(v, l));
    float behind2_ = behind * behind;
    float _e94 = fur.strand.z;
    metal::float3 back = (((_e94 * colour) * (behind2_ * behind2_)) * sin2_tv) * wrap;
    return light.radiance * (((colour * diffuse) + specular) + back);
}

metal::float3 strand_shade(
    metal::float3 albedo,
    metal::float3 n_in_1,
    metal::float3 tangent,
    metal::float3 world_2,
    metal::float3 to_eye,
    float h_1,
    float direct_1,
    float mask_1,
    constant Frame& frame,
    constant Fur& fur
) {
    metal::float3 t_1 = {};
    metal::float3 rgb_2 = {};
    uint i_2 = 0u;
    metal::float3 n_3 = metal::normalize(n_in_1);
    t_1 = n_3;
    if (metal::dot(tangent, tangent) > 0.000000000001) {
        t_1 = metal::normalize(tangent);
    }
    metal::float4 _e18 = fur.tip_color;
    metal::float3 colour_1 = albedo * metal::mix(metal::float3(1.0), _e18.xyz, h_1);
    float _e25 = fur.tip_color.w;
    float occlusion = 1.0 - (_e25 * (1.0 - h_1));
    metal::float3 _e31 = ambient_at(n_3, frame);
    rgb_2 = (colour_1 * _e31) * occlusion;
    metal::float3 _e35 = t_1;
    float tv = metal::dot(_e35, to_eye);
    float sin2_tv_1 = metal::max(1.0 - (tv * tv), 0.0);
    uint _e42 = light_count(frame);
    uint2 loop_bound_1 = uint2(4294967295u);
    bool loop_init_1 = true;
    while(true) {
        if (metal::all(loop_bound_1 == uint2(0u))) { break; }
        loop_bound_1 -= uint2(loop_bound_1.y == 0u, 1u);
        if (!loop_init_1) {
            uint _e58 = i_2;
            i_2 = _e58 + 1u;
        }
        loop_init_1 = false;
        uint _e45 = i_2;
        if (_e45 < LIGHT_SLOTS) {
        } else {
            break;
        }
        {
            uint _e48 = i_2;
            if (_e48 < _e42) {
                metal::float3 _e50 = rgb_2;
                uint _e51 = i_2;
                LightSample _e52 = light_at(_e51, world_2, frame);
                metal::float3 _e53 = t_1;
                metal::float3 _e54 = strand_light(_e52, n_3, _e53, to_eye, colour_1, sin2_tv_1, mask_1, fur);
                rgb_2 = _e50 + (direct_1 * _e54);
            }
        }
    }
    metal::float3 _e60 = rgb_2;
    return _e60;
}

float strand_mask(
    int x_1,
    int y_1,
    constant Fur& fur
) {
    float _e5 = fur.secondary_tint.w;
    float _e6 = cell_noise(x_1, y_1);
    return 1.0 - (_e5 * _e6);
}

float stacking_at(
    uint angle,
    uint mip,
    uint count,
    device type_8 const& stacking,
    constant _mslBufferSizes& _buffer_sizes
) {
    float _e11 = stacking[(((angle * STACK_MIPS) + mip) * STACK_COUNTS) + count];
    return _e11;
}

uint naga_f2u32(float value) {
    return static_cast<uint>(metal::clamp(value, 0.0, 4294967000.0));
}

float stacked_alpha(
    float alpha_3,
    metal::float3 to_eye_1,
    metal::float3 tangent_1,
    float lod_1,
    constant Frame& frame,
    constant Fur& fur,
    device type_8 const& stacking,
    constant _mslBufferSizes& _buffer_sizes
) {
    bool local_3 = {};
    float e = 0.0;
    uint i_3 = 0u;
    float _e7 = fur.stacking.x;
    if (!((_e7 == 0.0))) {
        local_3 = alpha_3 >= 1.0;
    } else {
        local_3 = true;
    }
    bool _e16 = local_3;
    if (_e16) {
        return alpha_3;
    }
    float angle_1 = metal::clamp(((metal::acos(metal::clamp(metal::abs(metal::dot(to_eye_1, tangent_1)), 0.0, 1.0))) * 57.295779513082322865) / 10.0, 0.0, 8.0);
    float mip_1 = metal::clamp(lod_1, 0.0, 5.0);
    float _e35 = frame.shells.z;
    float count_1 = metal::clamp(metal::log2(metal::max(_e35, 1.0)), 0.0, 6.0);
    uint a0_ = metal::min(naga_f2u32(angle_1), 7u);
    uint m0_ = metal::min(naga_f2u32(mip_1), 4u);
    uint c0_ = metal::min(naga_f2u32(count_1), 5u);
    float fa = angle_1 - static_cast<float>(a0_);
    float fm = mip_1 - static_cast<float>(m0_);
    float fc = count_1 - static_cast<float>(c0_);
    uint2 loop_bound_2 = uint2(4294967295u);
    bool loop_init_2 = true;
    while(true) {
        if (metal::all(loop_bound_2 == uint2(0u))) { break; }
        loop_bound_2 -= uint2(loop_bound_2.y == 0u, 1u);
        if (!loop_init_2) {
            uint _e103 = i_3;
            i_3 = _e103 + 1u;
        }
        loop_init_2 = false;
        uint _e61 = i_3;
        if (_e61 < 8u) {
        } else {
            break;
        }
        {
            uint _e64 = i_3;
            uint da = _e64 & 1u;
            uint _e67 = i_3;
            uint dm = (_e67 >> 1u) & 1u;
            uint _e72 = i_3;
            uint dc = (_e72 >> 2u) & 1u;
            float w = (((da == 1u) ? fa : (1.0 - fa)) * ((dm == 1u) ? fm : (1.0 - fm))) * ((dc == 1u) ? fc : (1.0 - fc));
            float _e94 = e;
            float _e98 = stacking_at(a0_ + da, m0_ + dm, c0_ + dc, stacking, _buffer_sizes);
            e = _e94 + (w * metal::log2(_e98));
        }
    }
    float _e107 = e;
    return 1.0 - metal::pow(1.0 - alpha_3, metal::exp2(_e107));
}

metal::uint2 naga_f2u32(metal::float2 value) {
    return static_cast<metal::uint2>(metal::clamp(value, 0.0, 4294967000.0));
}

metal::uint2 naga_mod(metal::uint2 lhs, metal::uint2 rhs) {
    return lhs % metal::select(rhs, 1u, rhs == 0u);
}

float dither_4x4_(
    metal::float2 xy
) {
    metal::uint2 p = naga_mod(naga_f2u32(xy), metal::uint2(4u));
    type_13 bayer = type_13 {{0u, 8u, 2u, 10u, 12u, 4u, 14u, 6u, 3u, 11u, 1u, 9u, 15u, 7u, 13u, 5u}};
    return (static_cast<float>(bayer.inner[(p.y * 4u) + p.x]) + 0.5) / 16.0;
}
metal::int2 naga_f2i32(metal::float2 value) {
    return static_cast<metal::int2>(metal::clamp(value, -2147483600.0, 2147483500.0));
}


struct fs_shellInput {
    metal::float3 normal [[user(loc0), center_perspective]];
    metal::float4 color [[user(loc1), center_perspective]];
    metal::float2 uv [[user(loc2), center_perspective]];
    uint slice [[user(loc3), flat]];
    metal::float3 tangent_2 [[user(loc4), center_perspective]];
    metal::float3 world_3 [[user(loc5), center_perspective]];
    float height [[user(loc6), flat]];
    float fade [[user(loc7), flat]];
};
struct fs_shellOutput {
    metal::float4 member [[color(0)]];
};
fragment fs_shellOutput fs_shell(
  fs_shellInput varyings [[stage_in]]
, metal::float4 clip [[position]]
, constant Frame& frame [[buffer(0)]]
, constant Fur& fur [[buffer(1)]]
, device type_8 const& shadow [[buffer(2)]]
, metal::texture2d_array<float, metal::access::sample> shell_alpha [[texture(0)]]
, metal::sampler repeat_sampler [[sampler(0)]]
, device type_8 const& stacking [[buffer(3)]]
, constant _mslBufferSizes& _buffer_sizes [[buffer(4)]]
) {
    const ShellOut in = { clip, varyings.normal, varyings.color, varyings.uv, varyings.slice, {}, varyings.tangent_2, varyings.world_3, varyings.height, varyings.fade };
    float alpha = {};
    float edge = 0.0;
    float lod = 0.0;
    bool local = {};
    bool local_1 = {};
    metal::float3 rgb = {};
    bool local_2 = {};
    float direct = 1.0;
    metal::float3 shade = {};
    if (ALPHA_BLEND) {
        metal::float4 _e7 = shell_alpha.sample(repeat_sampler, in.uv, in.slice);
        alpha = _e7.x;
    } else {
        metal::float4 _e14 = shell_alpha.sample(repeat_sampler, in.uv, in.slice, metal::level(0.0));
        alpha = _e14.x;
    }
    if (ALPHA_TO_COVERAGE) {
        float _e19 = alpha;
        float _e20 = metal::fwidth(_e19);
        edge = _e20;
    }
    if (ALPHA_BLEND) {
        metal::float2 texel = in.uv * static_cast<metal::float2>(metal::uint2(shell_alpha.get_width(), shell_alpha.get_height()));
        metal::float2 _e29 = metal::dfdx(texel);
        float across = metal::length(_e29);
        metal::float2 _e31 = metal::dfdy(texel);
        float down = metal::length(_e31);
        float _e38 = fur.stacking.y;
        lod = metal::log2(metal::max(metal::max(metal::min(across, down), metal::max(across, down) / metal::max(_e38, 1.0)), 0.000001));
    }
    float _e46 = alpha;
    float _e47 = edge;
    bool _e48 = alpha_discarded(_e46, _e47, fur);
    if (_e48) {
        metal::discard_fragment();
    }
    if (in.fade < 1.0) {
        local = false;
    } else {
        local = false;
    }
    bool _e58 = local;
    if (_e58) {
        float _e64 = dither_4x4_(in.clip.xy);
        local_1 = in.fade <= _e64;
    } else {
        local_1 = false;
    }
    bool _e67 = local_1;
    if (_e67) {
        metal::discard_fragment();
    }
    metal::float4 _e70 = frame.camera_pos;
    metal::float3 to_eye_2 = metal::normalize(_e70.xyz - in.world);
    if (ALPHA_BLEND) {
        float _e76 = alpha;
        float _e79 = lod;
        float _e80 = stacked_alpha(_e76, to_eye_2, metal::normalize(in.tangent), _e79, frame, fur, stacking, _buffer_sizes);
        alpha = _e80 * in.fade;
    }
    if (STRAND) {
        local_2 = LAMBERT;
    } else {
        local_2 = false;
    }
    bool _e89 = local_2;
    if (_e89) {
        if (SHADOW) {
            float _e96 = shadow[in.slice];
            direct = _e96;
        }
        metal::float2 size = static_cast<metal::float2>(metal::uint2(shell_alpha.get_width(), shell_alpha.get_height()));
        metal::int2 cell = naga_f2i32(metal::min(metal::floor(metal::fract(in.uv) * size), size - metal::float2(1.0)));
        metal::float4 _e113 = fur.tint;
        metal::float3 albedo_1 = in.color.xyz * _e113.xyz;
        float _e120 = direct;
        float _e123 = strand_mask(cell.x, cell.y, fur);
        metal::float3 _e124 = strand_shade(albedo_1, in.normal, in.tangent, in.world, to_eye_2, in.height, _e120, _e123, frame, fur);
        rgb = _e124;
    } else {
        metal::float3 _e127 = lambert(in.normal, in.world, frame);
        shade = _e127;
        if (SHADOW) {
            metal::float3 _e130 = shade;
            float _e134 = shadow[in.slice];
            shade = _e130 * _e134;
        }
        metal::float4 _e140 = fur.tint;
        metal::float3 _e143 = shade;
        rgb = (in.color.xyz * _e140.xyz) * _e143;
    }
    if (ALPHA_BLEND) {
        metal::float3 _e146 = rgb;
        float _e147 = alpha;
        return fs_shellOutput { metal::float4(_e146, _e147) };
    }
    if (ALPHA_TO_COVERAGE) {
        metal::float3 _e150 = rgb;
        float _e151 = alpha;
        float _e152 = edge;
        float _e153 = coverage_alpha(_e151, _e152, fur);
        return fs_shellOutput { metal::float4(_e150, _e153) };
    }
    metal::float3 _e155 = rgb;
    return fs_shellOutput { metal::float4(_e155, 1.0) };
}
