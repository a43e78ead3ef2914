struct NagaConstants {
    int first_vertex;
    int first_instance;
    uint other;
};
ConstantBuffer<NagaConstants> _NagaConstants: register(b0, space8);

struct SkinningUniforms {
    uint vertex_count;
    uint influences_per_vertex;
    uint target_count;
    uint pad0_;
};

struct SkinnedVertex {
    float4 position;
    float4 normal;
};

static const bool SKIN = true;
static const bool MORPH = true;
static const bool MORPH_NORMALS = true;

cbuffer params : register(b0) { SkinningUniforms params; }
ByteAddressBuffer bind_vertices : register(t1);
ByteAddressBuffer influence_binds : register(t2);
ByteAddressBuffer influence_weights : register(t3);
ByteAddressBuffer morph_deltas : register(t4);
ByteAddressBuffer skinning_matrices : register(t5);
ByteAddressBuffer morph_weights : register(t6);
RWByteAddressBuffer skinned_out : register(u7);

float3 morph_delta(uint i)
{
    float _e5 = asfloat(morph_deltas.Load((3u * i)*4));
    float _e12 = asfloat(morph_deltas.Load(((3u * i) + 1u)*4));
    float _e19 = asfloat(morph_deltas.Load(((3u * i) + 2u)*4));
    return float3(_e5, _e12, _e19);
}

uint influence_bind(uint slot)
{
    uint _e5 = asuint(influence_binds.Load((slot >> 1u)*4));
    return ((_e5 >> ((slot & 1u) * 16u)) & 65535u);
}

SkinnedVertex ConstructSkinnedVertex(float4 arg0, float4 arg1) {
    SkinnedVertex ret = (SkinnedVertex)0;
    ret.position = arg0;
    ret.normal = arg1;
    return ret;
}

float4x4 ZeroValuefloat4x4() {
    return (float4x4)0;
}

[numthreads(64, 1, 1)]
void cs_skin(uint3 gid : SV_DispatchThreadID, uint3 groups : SV_GroupID)
{
    float3 p = (float3)0;
    float3 n = (float3)0;
    uint t = 0u;
    float4x4 m = ZeroValuefloat4x4();
    uint s = 0u;

    uint v = (gid.x + ((gid.y * uint3(_NagaConstants.first_vertex, _NagaConstants.first_instance, _NagaConstants.other).x) * 64u));
    uint _e11 = params.vertex_count;
    if ((v >= _e11)) {
        return;
    }
    SkinnedVertex bind = ConstructSkinnedVertex(asfloat(bind_vertices.Load4(v*32+0)), asfloat(bind_vertices.Load4(v*32+16)));
    p = bind.position.xyz;
    n = bind.normal.xyz;
    if (MORPH) {
        uint _e25 = params.target_count;
        uint _e28 = params.vertex_count;
        uint normal_base = (_e25 * _e28);
        uint2 loop_bound = uint2(4294967295u, 4294967295u);
        bool loop_init = true;
        while(true) {
            if (all(loop_bound == uint2(0u, 0u))) { break; }
            loop_bound -= uint2(loop_bound.y == 0u, 1u);
            if (!loop_init) {
                uint _e60 = t;
                t = (_e60 + 1u);
            }
            loop_init = false;
            uint _e32 = t;
            uint _e35 = params.target_count;
            if ((_e32 < _e35)) {
            } else {
                break;
            }
            {
                uint _e38 = t;
                float w = asfloat(morph_weights.Load(_e38*4));
                if ((w != 0.0)) {
                    uint _e43 = t;
                    uint _e46 = params.vertex_count;
                    uint i_1 = ((_e43 * _e46) + v);
                    float3 _e49 = p;
                    const float3 _e50 = morph_delta(i_1);
                    p = (_e49 + (w * _e50));
                    if (MORPH_NORMALS) {
                        float3 _e54 = n;
                        const float3 _e56 = morph_delta((normal_base + i_1));
                        n = (_e54 + (w * _e56));
                    }
                }
            }
        }
    }
    if (SKIN) {
        uint _e67 = params.influences_per_vertex;
        uint first = (v * _e67);
        uint2 loop_bound_1 = uint2(4294967295u, 4294967295u);
        bool loop_init_1 = true;
        while(true) {
            if (all(loop_bound_1 == uint2(0u, 0u))) { break; }
            loop_bound_1 -= uint2(loop_bound_1.y == 0u, 1u);
            if (!loop_init_1) {
                uint _e93 = s;
                s = (_e93 + 1u);
            }
            loop_init_1 = false;
            uint _e71 = s;
            uint _e74 = params.influences_per_vertex;
            if ((_e71 < _e74)) {
            } else {
                break;
            }
            {
                uint _e77 = s;
                float w_1 = asfloat(influence_weights.Load((first + _e77)*4));
                if ((w_1 != 0.0)) {
                    float4x4 _e83 = m;
                    uint _e85 = s;
                    const uint _e87 = influence_bind((first + _e85));
                    float4x4 _e89 = float4x4(asfloat(skinning_matrices.Load4(_e87*64+0)), asfloat(skinning_matrices.Load4(_e87*64+16)), asfloat(skinning_matrices.Load4(_e87*64+32)), asfloat(skinning_matrices.Load4(_e87*64+48)));
                    m = (_e83 + mul(w_1, _e89));
                }
            }
        }
        float4x4 _e95 = m;
        float3 _e96 = p;
        p = mul(float4(_e96, 1.0), _e95).xyz;
        float4 _e102 = m[0];
        float3 c0_ = _e102.xyz;
        float4 _e105 = m[1];
        float3 c1_ = _e105.xyz;
        float4 _e108 = m[2];
        float3 c2_ = _e108.xyz;
        float3x3 cofactor = float3x3(cross(c1_, c2_), cross(c2_, c0_), cross(c0_, c1_));
        float det = dot(c0_, cross(c1_, c2_));
        float det_sign = (((asuint(det) & 2147483648u) != 0u) ? -1.0 : 1.0);
        float3 _e124 = n;
        n = (mul(_e124, cofactor) * det_sign);
    }
    float3 _e127 = n;
    float len = length(_e127);
    if ((len > 0.0)) {
        float3 _e131 = n;
        n = (_e131 / (len).xxx);
    } else {
        n = bind.normal.xyz;
    }
    float3 _e138 = p;
    float3 _e141 = n;
    {
        SkinnedVertex _value2 = ConstructSkinnedVertex(float4(_e138, 1.0), float4(_e141, 0.0));
        skinned_out.Store4(v*32+0, asuint(_value2.position));
        skinned_out.Store4(v*32+16, asuint(_value2.normal));
    }
    return;
}
