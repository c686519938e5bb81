/* Second-bounce VPLs (SSVP sec. 3.C), the GPU twin of gim_second_bounce_vpls_twin: VPL i is map
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
   2008; gim_ism_visibility_twin's lookup, the hit as the VAL, in its float steps) and dropped where
   the map does not see it: the paraboloid map skips what lies within near_distance of its
   origin (gim_second_bounce_desc.ism) */
layout(std430, binding = 3) readonly buffer IsmMaps { uint ism[]; };   /* 16-bit depths, two to a uint (gim_ism_dequantize) */
layout(location = 3) uniform uint ism_size;
layout(location = 4) uniform float ism_bias;
layout(location = 5) uniform float ism_texel;   /* slope 2 / size */
layout(location = 6) uniform float ism_lift;    /* GIM_ISM_LIFT scene_scale */

#include "ism_lookup.glsl"

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
