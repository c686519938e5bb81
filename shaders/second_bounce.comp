/* Second-bounce VPLs (SSVP sec. 3.C), the GPU twin of gim_second_bounce_vpls: VPL i is map
   sample[i].x's texel (sample[i].y, sample[i].z), one of its S_m = sample[i].w samples (the
   texels are computed on the CPU by the twin's own function). A hit (position.w > 0, data
   finite, albedo >= 0, centre inside the unit disk) carries
     Phi = albedo Phi_m w.z / (pi S_m pdf) = albedo Phi_m 4 (1 - r^2) / (S_m (1 + r^2)^3),
   r^2 = u^2 + v^2 of the texel centre; anything else is an unlit VPL (all zero). */
#include "common.glsl"
layout(local_size_x = 64) in;

struct Paraboloid { vec4 origin_near; vec4 normal_size; vec4 flux; };
layout(std430, binding = 0) readonly buffer Maps { Paraboloid map[]; };
layout(std430, binding = 1) readonly buffer Samples { uvec4 sample_texel[]; };   /* map, x, y, S_m */
struct Vpl { vec4 position; vec4 normal; vec4 flux; };                         /* w: lit 1 / 0; 0; 0 */
layout(std430, binding = 2) writeonly buffer Vpls { Vpl vpl[]; };

layout(binding = 0) uniform sampler2DArray hit_position;  /* xyz; w = 1 where hit */
layout(binding = 1) uniform sampler2DArray hit_normal;
layout(binding = 2) uniform sampler2DArray hit_albedo;

layout(location = 0) uniform uint count;
layout(location = 1) uniform uint first;   /* index of the first VPL written */
layout(location = 2) uniform uint size;

/* ism_size > 0: each hit is looked up in its cluster's imperfect shadow map (Ritschel et al.
   2008; gim_ism_visibility's lookup, the hit as the VAL, in its float steps) and dropped where
   the map does not see it: the paraboloid map skips what lies within near_distance of its
   origin (gim_second_bounce_desc.ism) */
layout(std430, binding = 3) readonly buffer IsmMaps { uint ism[]; };   /* 16-bit depths, two to a uint (gim_ism_dequantize) */
layout(location = 3) uniform uint ism_size;
layout(location = 4) uniform float ism_bias;
layout(location = 5) uniform float ism_texel;   /* slope 2 / size */
layout(location = 6) uniform float ism_lift;    /* GIM_ISM_LIFT scene_scale */

float ism_visibility(uint m, vec3 c, vec3 nv, vec3 x, vec3 nl) {
    precise vec3 n = nv;
    precise float sg = n.z >= 0.0 ? 1.0 : -1.0;          /* gim_basis (Duff et al. 2017) */
    precise float a = -1.0 / (sg + n.z);
    precise float k_ = n.x * n.y * a;
    precise vec3 t = vec3(1.0 + sg * n.x * n.x * a, sg * k_, -sg * n.x);
    precise vec3 b = vec3(k_, sg + n.y * n.y * a, -n.y);
    precise vec3 o = vec3(c.x + ism_lift * n.x, c.y + ism_lift * n.y, c.z + ism_lift * n.z);
    precise vec3 d = vec3(x.x - o.x, x.y - o.y, x.z - o.z);
    precise float dist = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(dist > 0.0)) return 1.0;
    precise float wz = (d.x * n.x + d.y * n.y + d.z * n.z) / dist;
    if (!(wz > 0.0)) return 1.0;
    precise float wx = (d.x * t.x + d.y * t.y + d.z * t.z) / dist;
    precise float wy = (d.x * b.x + d.y * b.y + d.z * b.z) / dist;
    precise float fs = float(ism_size);
    precise float fx = floor((wx / (1.0 + wz) + 1.0) * 0.5 * fs);
    precise float fy = floor((wy / (1.0 + wz) + 1.0) * 0.5 * fs);
    int ix = fx < 0.0 ? 0 : fx > float(ism_size - 1u) ? int(ism_size) - 1 : int(fx);
    int iy = fy < 0.0 ? 0 : fy > float(ism_size - 1u) ? int(ism_size) - 1 : int(fy);
    uint zi = m * ism_size * ism_size + uint(iy * int(ism_size) + ix);
    uint zw = ism[zi >> 1u];
    float z = ism_unpack(zw, zi);
    precise float u = (2.0 * float(ix) + 1.0) / fs - 1.0;   /* the texel's centre ray */
    precise float v = (2.0 * float(iy) + 1.0) / fs - 1.0;
    precise float r2 = u * u + v * v;
    precise float q = 1.0 / (1.0 + r2);
    precise vec3 w = vec3(2.0 * u * q, 2.0 * v * q, (1.0 - r2) * q);
    precise vec3 dir = vec3(w.x * t.x + w.y * b.x + w.z * n.x, w.x * t.y + w.y * b.y + w.z * n.y,
                            w.x * t.z + w.y * b.z + w.z * n.z);
    precise float dref = dist;
    precise float den = dir.x * nl.x + dir.y * nl.y + dir.z * nl.z;
    if (den >= 1e-3 || den <= -1e-3) {
        precise float s = (d.x * nl.x + d.y * nl.y + d.z * nl.z) / den;
        if (s > 0.0 && s < 2.0 * dist) dref = s;
    }
    precise float cl = -(nl.x * d.x + nl.y * d.y + nl.z * d.z) / dist;
    cl = cl < 0.0 ? -cl : cl;
    precise float sn = sqrt(1.0 - (cl < 1.0 ? cl * cl : 1.0));
    precise float tn = cl * ISM_MAX_TAN > sn ? sn / cl : ISM_MAX_TAN;
    return z < ISM_EMPTY && dref > z + dist * (ism_bias + ism_texel * tn) ? 0.0 : 1.0;
}


void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    uvec4 s = sample_texel[i];
    ivec3 c = ivec3(int(s.y), int(s.z), int(s.x));
    vec4 p = texelFetch(hit_position, c, 0), n = texelFetch(hit_normal, c, 0), a = texelFetch(hit_albedo, c, 0);
    vec2 uv = (2.0 * vec2(s.yz) + 1.0) / float(size) - 1.0;
    float r2 = dot(uv, uv);
    uint pw = floatBitsToUint(p.w);
    Vpl o;
    o.position = vec4(0.0);
    o.normal = vec4(0.0);
    o.flux = vec4(0.0);
    if (positive(pw) && finite3(floatBitsToUint(p.xyz)) && finite3(floatBitsToUint(n.xyz)) &&
        finite3(floatBitsToUint(a.rgb)) && nonneg3(a.rgb) && r2 <= 1.0) {
        float q = 1.0 + r2;
        float scale = 4.0 * (1.0 - r2) / (float(s.w) * q * q * q);
        o.position = vec4(p.xyz, 1.0);
        o.normal = vec4(n.xyz, 0.0);
        o.flux = vec4(min(a.rgb * map[s.x].flux.rgb * scale, vec3(FLT_MAX)), 0.0);
        if (ism_size != 0u && ism_visibility(s.x, map[s.x].origin_near.xyz, map[s.x].normal_size.xyz, p.xyz, n.xyz) == 0.0) {
            o.position = vec4(0.0);
            o.normal = vec4(0.0);
            o.flux = vec4(0.0);
        }
    }
    vpl[first + i] = o;
}
