/* Bischoff 2017 eq. 10-11: the importance of every RSM texel (a VAL) for the view, the twin of
   gim_importance_map. I = lum(flux) * 1/S * sum over view samples of
       cos+(n_l, l) cos+(n_vs, -l) / max(|l|^2, clamp^2),   l = (x_vs - x_l) / scene_scale.
   One invocation per texel; the view samples pass through shared memory in tiles, one sample
   loaded per invocation. Positions are subtracted before scaling, so a scene far from the
   origin keeps the precision of its float positions. With luminance_out, each texel's luminance
   (0 where it is no VAL) also goes to lum_map: the map of the selection's defensive share. */
#include "common.glsl"
#define TILE 256
layout(local_size_x = 16, local_size_y = 16) in;

layout(binding = 0) uniform sampler2D rsm_position;   /* xyz; w > 0 where the RSM saw a surface */
layout(binding = 1) uniform sampler2D rsm_normal;     /* xyz */
layout(binding = 2) uniform sampler2D rsm_flux;       /* rgb */

struct ViewSample { vec4 position; vec4 normal; };   /* xyz used */
layout(std430, binding = 0) readonly buffer ViewSamples { ViewSample view_sample[]; };
layout(std430, binding = 1) writeonly buffer ImportanceMap { float map[]; };   /* width * height */
layout(std430, binding = 2) writeonly buffer LuminanceMap { float lum_map[]; }; /* width * height, with luminance_out */

layout(location = 0) uniform uvec2 size;             /* RSM width, height */
layout(location = 1) uniform uint view_sample_count;
layout(location = 2) uniform float inv_scene_scale;
layout(location = 3) uniform float clamp2;           /* (clamp in scene scales)^2 */
layout(location = 4) uniform uint luminance_out;     /* 1: lum_map written */

shared vec3 tile_position[TILE];
shared vec3 tile_normal[TILE];                       /* zero: the sample sees nothing */

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    bool inside = p.x < size.x && p.y < size.y;
    ivec2 t = ivec2(min(p, size - 1u));
    vec4 x_l = texelFetch(rsm_position, t, 0);
    vec3 n_l = texelFetch(rsm_normal, t, 0).xyz;
    vec3 flux = texelFetch(rsm_flux, t, 0).rgb;
    float phi = dot(vec3(0.2126, 0.7152, 0.0722), flux);   /* luminance of the flux */
    bool lit = inside && x_l.w > 0.0 && finite3(x_l.xyz) && finite3(n_l) && finite3(flux) && phi > 0.0 &&
               dot(n_l, n_l) > 0.0;
    n_l = lit ? normalize(n_l) : vec3(0.0);
    phi = min(phi, FLT_MAX);
    float sum = 0.0;
    uint local = gl_LocalInvocationIndex;
    for (uint base = 0u; base < view_sample_count; base += uint(TILE)) {
        uint j = base + local;
        vec3 xs = vec3(0.0), ns = vec3(0.0);
        if (j < view_sample_count) {
            xs = view_sample[j].position.xyz;
            ns = view_sample[j].normal.xyz;
            bool usable = finite3(xs) && finite3(ns) && dot(ns, ns) > 0.0;
            xs = usable ? xs : vec3(0.0);
            ns = usable ? normalize(ns) : vec3(0.0);
        }
        tile_position[local] = xs;
        tile_normal[local] = ns;
        barrier();
        uint n = min(uint(TILE), view_sample_count - base);
        if (lit)
            for (uint k = 0u; k < n; ++k) {
                vec3 l = (tile_position[k] - x_l.xyz) * inv_scene_scale;   /* eq. 10: l in scene scales */
                float d2 = dot(l, l);
                if (d2 > 1e-36) {
                    float r = inversesqrt(d2);
                    float cos_l = max(dot(n_l, l) * r, 0.0);
                    float cos_v = max(-dot(tile_normal[k], l) * r, 0.0);
                    sum += cos_l * cos_v / max(d2, clamp2);                  /* eq. 11: clamped distance */
                }
            }
        barrier();
    }
    if (inside) map[p.y * size.x + p.x] = lit ? min(phi * (sum / float(view_sample_count)), FLT_MAX) : 0.0;
    if (inside && luminance_out != 0u) lum_map[p.y * size.x + p.x] = lit ? phi : 0.0;
}
