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

struct SkinnedVertex {
    float4 position;
    float4 normal;
};

struct SurfaceIn {
    float3 position : LOC0;
    float3 normal : LOC1;
    float4 color : LOC2;
    float2 uv : LOC3;
    uint vertex_index : LOC4;
    uint flags : LOC5;
    uint corner_index : LOC6;
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
static const bool STRAND = true;
static const bool SHEAR = true;
static const bool SKINNED = true;

cbuffer frame : register(b0) { Frame frame; }
cbuffer fur : register(b1) { Fur fur; }
ByteAddressBuffer scale_vectors : register(t2);
ByteAddressBuffer skinned : register(t8);

struct VertexOutput_vs_shell {
    float3 normal_3 : LOC0;
    float4 color : LOC1;
    float2 uv : LOC2;
    nointerpolation uint slice : LOC3;
    float3 tangent : LOC4;
    float3 world : LOC5;
    nointerpolation float height : LOC6;
    nointerpolation float fade : LOC7;
    float4 clip_ : SV_Position;
};

uint scale_index(uint vertex_index, uint corner_index)
{
    uint _e4 = fur.scale_layout;
    return ((_e4 == 1u) ? corner_index : vertex_index);
}

SkinnedVertex ConstructSkinnedVertex(float4 arg0, float4 arg1) {
    SkinnedVertex ret = (SkinnedVertex)0;
    ret.position = arg0;
    ret.normal = arg1;
    return ret;
}

SkinnedVertex posed_vertex(uint vertex_index_1, float3 position, float3 normal)
{
    if (SKINNED) {
        SkinnedVertex _e6 = ConstructSkinnedVertex(asfloat(skinned.Load4(vertex_index_1*32+0)), asfloat(skinned.Load4(vertex_index_1*32+16)));
        const SkinnedVertex skinnedvertex = _e6;
        return skinnedvertex;
    }
    const SkinnedVertex skinnedvertex_1 = ConstructSkinnedVertex(float4(position, 1.0), float4(normal, 0.0));
    return skinnedvertex_1;
}

float3 shell_offset(float3 n, float3 s, float t)
{
    float3 offset = (float3)0;

    offset = (n * t);
    if (SHEAR) {
        float3 _e6 = offset;
        float _e9 = fur.shear_exponent;
        offset = (_e6 + (pow(t, _e9) * (s - n)));
        float3 _e14 = offset;
        float3 _e15 = offset;
        offset = (_e14 - (min(dot(_e15, n), 0.0) * n));
    }
    float3 _e21 = offset;
    float _e24 = fur.fur_length_m;
    return (_e21 * _e24);
}

float3 strand_tangent(float3 n_1, float3 s_1, float t_1)
{
    float3 d = (float3)0;

    if (false) {
        return n_1;
    }
    float k = fur.shear_exponent;
    d = (n_1 + ((k * pow(max(t_1, 0.0001), (k - 1.0))) * (s_1 - n_1)));
    if ((dot(((n_1 * t_1) + (pow(t_1, k) * (s_1 - n_1))), n_1) < 0.0)) {
        float3 _e27 = d;
        float3 _e28 = d;
        d = (_e27 - (dot(_e28, n_1) * n_1));
    }
    float3 _e32 = d;
    float3 _e33 = d;
    float len2_ = dot(_e32, _e33);
    if (!((len2_ > 1e-12))) {
        return n_1;
    }
    float3 _e38 = d;
    return (_e38 * rsqrt(len2_));
}

float3 to_world(float3 p)
{
    float4x4 _e3 = frame.model;
    return mul(float4(p, 1.0), _e3).xyz;
}

float3 normal_to_world(float3 n_2)
{
    float4x4 _e3 = frame.model;
    return normalize(mul(float4(n_2, 0.0), _e3).xyz);
}

float3 shell_vertex(uint vertex_index_2, float3 position_1, float3 normal_1, uint scale_at, uint layer, uint layers)
{
    float t_2 = (float((layer + 1u)) / float(layers));
    const SkinnedVertex _e11 = posed_vertex(vertex_index_2, position_1, normal_1);
    float3 n_3 = normalize(_e11.normal.xyz);
    float4 _e17 = asfloat(scale_vectors.Load4(scale_at*16));
    float3 s_2 = _e17.xyz;
    const float3 _e21 = shell_offset(n_3, s_2, t_2);
    return (_e11.position.xyz + _e21);
}

float3 shell_tangent(uint vertex_index_3, float3 position_2, float3 normal_2, uint scale_at_1, uint layer_1, uint layers_1)
{
    float t_3 = (float((layer_1 + 1u)) / float(layers_1));
    const SkinnedVertex _e11 = posed_vertex(vertex_index_3, position_2, normal_2);
    float3 n_4 = normalize(_e11.normal.xyz);
    float4 _e17 = asfloat(scale_vectors.Load4(scale_at_1*16));
    const float3 _e19 = strand_tangent(n_4, _e17.xyz, t_3);
    return _e19;
}

uint naga_div(uint lhs, uint rhs) {
    return lhs / (rhs == 0u ? 1u : rhs);
}

uint shell_slice(uint layer_2, uint layers_2)
{
    uint a = fur.atlas_layers;
    return min((a - 1u), (naga_div(((((layer_2 + 1u) * a) + layers_2) - 1u), layers_2) - 1u));
}

uint naga_mod(uint lhs, uint rhs) {
    return lhs % (rhs == 0u ? 1u : rhs);
}

uint naga_f2u32(float value) {
    return uint(clamp(value, 0.0, 4294967000.0));
}

VertexOutput_vs_shell vs_shell(SurfaceIn v, uint instance : SV_InstanceID)
{
    ShellOut out_ = (ShellOut)0;

    float _e5 = frame.shells.x;
    uint layers_3 = max(naga_f2u32(_e5), 1u);
    uint layer_3 = (((_NagaConstants.first_instance + instance) >= layers_3) ? (((2u * layers_3) - 1u) - (_NagaConstants.first_instance + instance)) : (_NagaConstants.first_instance + instance));
    const uint _e18 = scale_index(v.vertex_index, v.corner_index);
    const float3 _e22 = shell_vertex(v.vertex_index, v.position, v.normal, _e18, layer_3, layers_3);
    const float3 _e23 = to_world(_e22);
    float4x4 _e28 = frame.view_proj;
    out_.clip_ = mul(float4(_e23, 1.0), _e28);
    const SkinnedVertex _e36 = posed_vertex(v.vertex_index, v.position, v.normal);
    const float3 _e39 = normal_to_world(_e36.normal.xyz);
    out_.normal = _e39;
    out_.color = v.color;
    out_.uv = v.uv;
    const uint _e45 = shell_slice(layer_3, layers_3);
    out_.slice = _e45;
    out_.world = _e23;
    float _e56 = frame.shells.z;
    out_.height = ((float((layer_3 + 1u)) / float(layers_3)) - (0.5 / max(_e56, 1.0)));
    float _e66 = frame.shells.y;
    out_.fade = ((naga_mod(layer_3, 2u) == 0u) ? _e66 : 1.0);
    if (STRAND) {
        const float3 _e78 = shell_tangent(v.vertex_index, v.position, v.normal, _e18, layer_3, layers_3);
        const float3 _e79 = normal_to_world(_e78);
        out_.tangent = _e79;
    } else {
        float3 _e82 = out_.normal;
        out_.tangent = _e82;
    }
    ShellOut _e83 = out_;
    const ShellOut shellout = _e83;
    const VertexOutput_vs_shell shellout_1 = { shellout.normal, shellout.color, shellout.uv, shellout.slice, shellout.tangent, shellout.world, shellout.height, shellout.fade, shellout.clip_ };
    return shellout_1;
}
