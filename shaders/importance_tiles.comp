/* Two-level importance, first level: eq. 10-11 once per plane of each tile of tile x tile RSM
   texels, the twin of gim_importance_tile_map. Each invocation walks its tile's VALs (lit,
   finite, a non-zero normal, luminance > 0) in raster order and splits them into at most PLANES
   planes: a VAL lies on a plane when its normal is within acos(0.9) of the plane's seed (the
   plane's first VAL) and it is within `plane` world units of the seed's plane; a VAL on no plane
   seeds a new one, and the last plane takes every VAL left. Each plane's aggregate: its summed
   luminance, flux-weighted mean position (kept relative to the seed, so a scene far from the
   origin keeps the precision of its float positions) and normalised mean normal; then
       G_plane = 1/S * sum over view samples of cos+(n_P, l) cos+(n_vs, -l) / max(|l|^2, clamp^2)
   with l = (x_vs - x_P) / scene_scale, as importance_map.comp per texel. A second walk writes
   each texel's weight, luminance * G of its plane (0 for a texel that is no VAL), for
   importance_select.comp's pick inside the tile; the tile's importance is their sum. The sum
   over view samples runs PLANES * texels / tile^2 times instead of texels times. One aggregate
   per tile was not enough: where a wall meets the ground or a roof edge lies over the street,
   the mean point floats between the surfaces and sees the view samples wrongly (the street at
   1024^2: 10x the per-texel map's variance and texels of P = 0; with planes +4%, none). With
   luminance_out, the same two outputs of the texels' luminance alone (lum_weight per texel, 0
   where no VAL; lum_tile their sum): the tables of the selection's defensive share. */
#include "common.glsl"
#define GROUP 64
#define PLANES 4
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D rsm_position;   /* xyz; w > 0 where the RSM saw a surface */
layout(binding = 1) uniform sampler2D rsm_normal;     /* xyz */
layout(binding = 2) uniform sampler2D rsm_flux;       /* rgb */

struct ViewSample { vec4 position; vec4 normal; };   /* xyz used */
layout(std430, binding = 0) readonly buffer ViewSamples { ViewSample view_sample[]; };
layout(std430, binding = 1) writeonly buffer TileMap { float tile_map[]; };   /* tiles.x * tiles.y */
layout(std430, binding = 2) writeonly buffer Weights { float weight[]; };     /* width * height */
layout(std430, binding = 3) writeonly buffer LuminanceTiles { float lum_tile[]; };     /* with luminance_out */
layout(std430, binding = 4) writeonly buffer LuminanceWeights { float lum_weight[]; }; /* with luminance_out */

layout(location = 0) uniform uvec2 size;             /* RSM width, height */
layout(location = 1) uniform uint view_sample_count;
layout(location = 2) uniform float inv_scene_scale;
layout(location = 3) uniform float clamp2;           /* (clamp in scene scales)^2 */
layout(location = 4) uniform uint tile;              /* tile side in texels */
layout(location = 5) uniform float plane;            /* a plane's thickness in world units (0.01 scene scales) */
layout(location = 6) uniform uint luminance_out;     /* 1: lum_tile and lum_weight written */

shared vec3 tile_position[GROUP];
shared vec3 tile_normal[GROUP];                      /* zero: the sample sees nothing */

/* The texel's luminance if it is a VAL (else 0), its position and unit normal. */
float val(ivec2 t, out vec3 x, out vec3 n) {
    vec4 x_l = texelFetch(rsm_position, t, 0);
    vec3 n_l = texelFetch(rsm_normal, t, 0).xyz;
    vec3 flux = texelFetch(rsm_flux, t, 0).rgb;
    float phi = dot(vec3(0.2126, 0.7152, 0.0722), flux);
    bool lit = x_l.w > 0.0 && finite3(x_l.xyz) && finite3(n_l) && finite3(flux) && phi > 0.0 && dot(n_l, n_l) > 0.0;
    x = x_l.xyz;
    n = lit ? normalize(n_l) : vec3(0.0);
    return lit ? min(phi, FLT_MAX) : 0.0;
}

vec3 seed_x[PLANES], seed_n[PLANES];
uint seeds = 0u;

/* The plane of a VAL: the first seed's plane it lies on (the last plane takes any), or a new one. */
uint plane_of(vec3 x, vec3 n, bool may_seed) {
    uint c = uint(PLANES);
    for (uint k = 0u; k < uint(PLANES); ++k) {
        bool on = k < seeds && (k + 1u == uint(PLANES) ||
                                (dot(n, seed_n[k]) >= 0.9 && abs(dot(seed_n[k], x - seed_x[k])) <= plane));
        c = c == uint(PLANES) && on ? k : c;
    }
    if (c == uint(PLANES) && may_seed) {
        c = seeds;
        for (uint k = 0u; k < uint(PLANES); ++k)
            if (k == c) { seed_x[k] = x; seed_n[k] = n; }
        seeds = seeds + 1u;
    }
    return c;
}

void main() {
    uvec2 tiles = (size + tile - 1u) / tile;
    uvec2 tp = gl_GlobalInvocationID.xy;
    bool inside = tp.x < tiles.x && tp.y < tiles.y;
    uvec2 t0 = tp * tile, t1 = inside ? min(t0 + tile, size) : t0;
    float phi_p[PLANES], g[PLANES];
    vec3 x_p[PLANES], n_p[PLANES];   /* running means; x_p relative to the plane's seed */
    for (uint k = 0u; k < uint(PLANES); ++k) { phi_p[k] = 0.0; g[k] = 0.0; x_p[k] = vec3(0.0); n_p[k] = vec3(0.0); }
    for (uint y = t0.y; y < t1.y; ++y)
        for (uint x = t0.x; x < t1.x; ++x) {
            vec3 x_l, n_l;
            float w = val(ivec2(x, y), x_l, n_l);
            if (w > 0.0) {
                uint c = plane_of(x_l, n_l, true);
                for (uint k = 0u; k < uint(PLANES); ++k)
                    if (k == c) {
                        phi_p[k] = min(phi_p[k] + w, FLT_MAX);
                        float a = w / phi_p[k];
                        x_p[k] += a * ((x_l - seed_x[k]) - x_p[k]);
                        n_p[k] += a * (n_l - n_p[k]);
                    }
            }
        }
    bool any = false;
    for (uint k = 0u; k < uint(PLANES); ++k) {
        bool ok = phi_p[k] > 0.0 && dot(n_p[k], n_p[k]) > 0.0;
        n_p[k] = ok ? normalize(n_p[k]) : vec3(0.0);
        any = any || ok;
    }
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
        if (any)
            for (uint i = 0u; i < n; ++i)
                for (uint k = 0u; k < uint(PLANES); ++k) {
                    vec3 l = ((tile_position[i] - seed_x[k]) - x_p[k]) * inv_scene_scale;   /* eq. 10 of the plane's aggregate */
                    float d2 = dot(l, l);
                    if (k < seeds && d2 > 1e-36) {
                        float r = inversesqrt(d2);
                        float cos_l = max(dot(n_p[k], l) * r, 0.0);
                        float cos_v = max(-dot(tile_normal[i], l) * r, 0.0);
                        g[k] += cos_l * cos_v / max(d2, clamp2);                 /* eq. 11: clamped distance */
                    }
                }
        barrier();
    }
    float sum = 0.0, lum_sum = 0.0;
    for (uint y = t0.y; y < t1.y; ++y)
        for (uint x = t0.x; x < t1.x; ++x) {
            vec3 x_l, n_l;
            float w = val(ivec2(x, y), x_l, n_l), gk = 0.0;
            uint c = w > 0.0 ? plane_of(x_l, n_l, false) : uint(PLANES);
            if (luminance_out != 0u) {
                lum_weight[y * size.x + x] = w;
                lum_sum = min(lum_sum + w, FLT_MAX);
            }
            for (uint k = 0u; k < uint(PLANES); ++k) gk = k == c ? g[k] : gk;
            w = min(w * (gk / float(view_sample_count)), FLT_MAX);
            weight[y * size.x + x] = w;
            sum = min(sum + w, FLT_MAX);
        }
    if (inside) tile_map[tp.y * tiles.x + tp.x] = sum;
    if (inside && luminance_out != 0u) lum_tile[tp.y * tiles.x + tp.x] = lum_sum;
}
