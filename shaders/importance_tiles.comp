/* Two-level importance, first level: eq. 10-11 once per tile of tile x tile RSM texels, the twin
   of gim_importance_tile_map. Each invocation walks its tile's texels: every texel's weight is
   its flux luminance where it is a VAL (lit, finite, a non-zero normal), else 0, written for
   importance_select.comp's pick inside the tile; the tile's aggregate is the weights' sum Phi,
   their weighted mean position and the normalised weighted mean of their normals. Then
       I_tile = Phi * 1/S * sum over view samples of cos+(n_T, l) cos+(n_vs, -l) / max(|l|^2, clamp^2)
   with l = (x_vs - x_T) / scene_scale, as importance_map.comp per texel: the sum over view samples
   runs (texels / tile^2) times. Running means (not sums) keep the aggregate finite for any
   weights; the mean position is kept relative to the tile's first VAL (anchor), and l is
   (x_vs - anchor) - mean offset, so a scene far from the origin keeps the precision of its float
   positions (an absolute float mean there rounds at ~2^-24 of the distance per step: 2e-4 of the
   map at 3e4 units from the origin, tests/gl/gltest_importance.c). */
#include "common.glsl"
#define GROUP 64
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D rsm_position;   /* xyz; w > 0 where the RSM saw a surface */
layout(binding = 1) uniform sampler2D rsm_normal;     /* xyz */
layout(binding = 2) uniform sampler2D rsm_flux;       /* rgb */

struct ViewSample { vec4 position; vec4 normal; };   /* xyz used */
layout(std430, binding = 0) readonly buffer ViewSamples { ViewSample view_sample[]; };
layout(std430, binding = 1) writeonly buffer TileMap { float tile_map[]; };   /* tiles.x * tiles.y */
layout(std430, binding = 2) writeonly buffer Weights { float weight[]; };     /* width * height */

layout(location = 0) uniform uvec2 size;             /* RSM width, height */
layout(location = 1) uniform uint view_sample_count;
layout(location = 2) uniform float inv_scene_scale;
layout(location = 3) uniform float clamp2;           /* (clamp in scene scales)^2 */
layout(location = 4) uniform uint tile;              /* tile side in texels */

shared vec3 tile_position[GROUP];
shared vec3 tile_normal[GROUP];                      /* zero: the sample sees nothing */

void main() {
    uvec2 tiles = (size + tile - 1u) / tile;
    uvec2 tp = gl_GlobalInvocationID.xy;
    bool inside = tp.x < tiles.x && tp.y < tiles.y;
    float phi_t = 0.0;
    vec3 anchor = vec3(0.0), x_t = vec3(0.0), n_t = vec3(0.0);   /* x_t: the mean position - anchor */
    bool first = true;
    if (inside) {
        uvec2 t0 = tp * tile, t1 = min(t0 + tile, size);
        for (uint y = t0.y; y < t1.y; ++y)
            for (uint x = t0.x; x < t1.x; ++x) {
                ivec2 t = ivec2(x, y);
                vec4 x_l = texelFetch(rsm_position, t, 0);
                vec3 n_l = texelFetch(rsm_normal, t, 0).xyz;
                vec3 flux = texelFetch(rsm_flux, t, 0).rgb;
                float phi = dot(vec3(0.2126, 0.7152, 0.0722), flux);
                bool lit = x_l.w > 0.0 && finite3(x_l.xyz) && finite3(n_l) && finite3(flux) && phi > 0.0 &&
                           dot(n_l, n_l) > 0.0;
                float w = lit ? min(phi, FLT_MAX) : 0.0;
                weight[y * size.x + x] = w;
                if (lit) {
                    anchor = first ? x_l.xyz : anchor;
                    first = false;
                    phi_t = min(phi_t + w, FLT_MAX);
                    float a = w / phi_t;                     /* running weighted means */
                    x_t += a * ((x_l.xyz - anchor) - x_t);
                    n_t += a * (normalize(n_l) - n_t);
                }
            }
    }
    bool lit_t = inside && phi_t > 0.0 && dot(n_t, n_t) > 0.0;
    n_t = lit_t ? normalize(n_t) : vec3(0.0);
    float sum = 0.0;
    uint local = gl_LocalInvocationIndex;
    for (uint base = 0u; base < view_sample_count; base += uint(GROUP)) {
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
        uint n = min(uint(GROUP), view_sample_count - base);
        if (lit_t)
            for (uint k = 0u; k < n; ++k) {
                vec3 l = ((tile_position[k] - anchor) - x_t) * inv_scene_scale;   /* eq. 10 of the tile's aggregate */
                float d2 = dot(l, l);
                if (d2 > 1e-36) {
                    float r = inversesqrt(d2);
                    float cos_l = max(dot(n_t, l) * r, 0.0);
                    float cos_v = max(-dot(tile_normal[k], l) * r, 0.0);
                    sum += cos_l * cos_v / max(d2, clamp2);              /* eq. 11: clamped distance */
                }
            }
        barrier();
    }
    if (inside) tile_map[tp.y * tiles.x + tp.x] = lit_t ? min(phi_t * (sum / float(view_sample_count)), FLT_MAX) : 0.0;
}
