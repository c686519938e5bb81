/* RSM gather (Dachsbacher and Stamminger 2005), the baseline method, the GPU twin of
   gim_rsm_gather_twin: one invocation per G-buffer pixel gathers the fixed sample pattern of RSM
   texels around its projection into one light's RSM (see gim_rsm_gather_twin for the weights).
   One dispatch per light: the first starts the sum, the others add to it (an SSBO of one vec4
   a pixel), the last writes the indirect texture. Sums in float (double in the twin). */
#include "common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D gbuffer_depth;
layout(binding = 1) uniform sampler2D gbuffer_normal;    /* world normal in xyz */
layout(binding = 2) uniform sampler2D gbuffer_albedo;    /* unused with the host's G-buffer */
layout(binding = 3) uniform sampler2D gbuffer_material;
layout(binding = 4) uniform sampler2D rsm_position;      /* xyz, w = lit */
layout(binding = 5) uniform sampler2D rsm_normal;        /* xyz, w = area */
layout(binding = 6) uniform sampler2D rsm_flux;
layout(binding = 0) writeonly uniform image2D indirect;

struct Material { vec4 diffuse; vec4 glossy; };
layout(std430, binding = 0) readonly buffer Samples { vec4 sample_[]; };   /* texel offset xy, weight z (gim__gather_offsets) */
layout(std430, binding = 1) buffer Sum { vec4 sum[]; };                 /* the lights so far, a pixel each */
layout(std430, binding = 2) readonly buffer Materials { Material material[]; };

layout(location = 0) uniform uvec2 size;
layout(location = 1) uniform mat4 inv_proj;
layout(location = 2) uniform mat4 inv_view;
layout(location = 3) uniform vec4 eye;            /* perspective: (position, 1); orthographic: (direction, 0) */
layout(location = 4) uniform mat4 light_view_proj;
layout(location = 5) uniform uint sample_count;
layout(location = 7) uniform float near2;         /* (1e-6 scene_scale)^2 */
layout(location = 8) uniform uint flags;          /* 1: first light; 2: last light; 4: host G-buffer */
layout(location = 9) uniform uint material_count;
layout(location = 10) uniform float max_value;    /* the indirect format's largest finite value */

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= int(size.x) || px.y >= int(size.y)) return;
    uint pi_ = uint(px.y) * size.x + uint(px.x);
    vec3 outc = vec3(0.0);
    float depth = texelFetch(gbuffer_depth, px, 0).r;
    vec4 nw = texelFetch(gbuffer_normal, px, 0);
    bool surface = depth < 1.0 && finite3(nw.xyz) && dot(nw.xyz, nw.xyz) > 0.0;
    if (surface) {
        vec3 x = unproject(px, depth, size, inv_proj, inv_view);
        vec3 nx = normalize(nw.xyz);
        vec3 view = normalize(eye.w > 0.0 ? eye.xyz - x : eye.xyz);
        vec3 albedo = vec3(1.0), gcol = vec3(0.0);
        float k = 0.0;
        if ((flags & 4u) == 0u) {
            albedo = texelFetch(gbuffer_albedo, px, 0).rgb;
            uint id = min(uint(max(texelFetch(gbuffer_material, px, 0).r, 0.0)), material_count - 1u);
            gcol = material[id].glossy.rgb;
            k = material[id].glossy.w;
        }
        bool glossy = any(greaterThan(gcol, vec3(0.0)));
        vec4 clip = light_view_proj * vec4(x, 1.0);
        ivec2 rsize = textureSize(rsm_position, 0);
        vec3 sd = vec3(0.0), sg = vec3(0.0);
        {
            /* off the map: its nearest point; behind the light's eye: its centre (gim_rsm_gather_twin) */
            vec2 p = clip.w > 0.0 ? clamp((clip.xy / clip.w * 0.5 + 0.5) * vec2(rsize), vec2(0.0), vec2(rsize))
                                  : 0.5 * vec2(rsize);
            for (uint j = 0u; j < sample_count; ++j) {
                vec2 t = floor(p + sample_[j].xy);
                if (any(lessThan(t, vec2(0.0))) || any(greaterThanEqual(t, vec2(rsize)))) continue;
                ivec2 ti = ivec2(t);
                vec4 xl = texelFetch(rsm_position, ti, 0), nl = texelFetch(rsm_normal, ti, 0);
                vec3 fl = texelFetch(rsm_flux, ti, 0).rgb;
                if (!(xl.w > 0.0) || !finite3(xl.xyz) || !finite3(nl.xyz) || !finite3(fl) || !finite3(vec3(nl.w)) ||
                    !(nl.w >= 0.0) || any(lessThan(fl, vec3(0.0))))
                    continue;
                vec3 d = xl.xyz - x;
                float d2 = dot(d, d);
                if (!(d2 > near2)) continue;
                vec3 w = d * inversesqrt(d2);
                float cx = dot(nx, w), cl = -dot(nl.xyz, w);
                if (!(cx > 0.0) || !(cl > 0.0)) continue;
                float e = sample_[j].z * cl * cx / (nl.w + PI * d2);
                sd += e * fl;
                if (glossy) {
                    float re = dot(2.0 * cx * nx - w, view);
                    float g = k == 0.0 ? 1.0 : (re > 0.0 ? pow(re, k) : 0.0);
                    sg += g * e * fl;
                }
            }
        }
        outc = albedo / PI * sd + gcol * ((k + 2.0) / (2.0 * PI)) * sg;
    }
    if ((flags & 1u) == 0u) outc += sum[pi_].rgb;
    if ((flags & 2u) != 0u) imageStore(indirect, px, surface ? vec4(min(outc, vec3(max_value)), 1.0) : vec4(0.0));
    else sum[pi_] = vec4(outc, 0.0);
}
