/* Geometry-aware blur (Dong sec. 6 after Laine et al.), the GPU twin of gim_geometry_blur_twin: each
   pixel with a surface becomes the mean of the pixels with a surface in its k x k window
   [x - k/2, x - k/2 + k - 1]^2 (clipped to the image) that lie within position_tolerance of it
   and whose normal has n . n_x >= normal_cos (the pixel itself always counts), and that are,
   like it, diffuse-only or glossy; a diffuse-only pixel averages radiance / albedo per channel
   and applies its own albedo (the light is blurred, not the materials), a glossy one averages
   radiance; summed in float rows first as the twin. Positions are unprojected from the
   G-buffer as in vpl_shade.comp. */
#include "common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D gbuffer_depth;
layout(binding = 1) uniform sampler2D gbuffer_normal;    /* world normal in xyz */
layout(binding = 2) uniform sampler2D gbuffer_albedo;    /* unused when material_count is 0 */
layout(binding = 3) uniform sampler2D gbuffer_material;
layout(binding = 4) uniform sampler2D radiance;          /* rgb input */

struct Material { vec4 diffuse; vec4 glossy; };
layout(std430, binding = 0) readonly buffer Materials { Material material[]; };
layout(binding = 0) writeonly uniform image2D blurred;   /* RGBA16F or RGBA32F */

layout(location = 0) uniform uvec2 size;
layout(location = 1) uniform mat4 inv_proj;
layout(location = 2) uniform mat4 inv_view;
layout(location = 4) uniform uint k;             /* window, >= 1 */
layout(location = 5) uniform float tol2;         /* position tolerance squared */
layout(location = 6) uniform float normal_cos;
layout(location = 7) uniform float max_value;
layout(location = 8) uniform uint material_count;   /* 0: the host's G-buffer (albedo 1, no glossy) */

/* The pixel's surface: position in xyz, w = 1; w = 0 where there is none. */
vec4 surface(ivec2 px, out vec3 n) {
    float depth = texelFetch(gbuffer_depth, px, 0).r;
    vec4 nw = texelFetch(gbuffer_normal, px, 0);
    n = vec3(0.0);
    if (!(depth < 1.0) || !finite3(nw.xyz) || !(dot(nw.xyz, nw.xyz) > 0.0)) return vec4(0.0);
    vec3 x = unproject(px, depth, size, inv_proj, inv_view);
    n = normalize(nw.xyz);
    return vec4(x, 1.0);
}

/* The pixel's albedo, and whether its material is glossy (gim__receiver_glossy). */
vec3 reflectance(ivec2 q, out bool glossy) {
    glossy = false;
    if (material_count == 0u) return vec3(1.0);
    uint id = min(uint(max(texelFetch(gbuffer_material, q, 0).r, 0.0)), material_count - 1u);
    glossy = any(greaterThan(material[id].glossy.rgb, vec3(0.0)));
    return texelFetch(gbuffer_albedo, q, 0).rgb;
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= int(size.x) || px.y >= int(size.y)) return;
    vec3 nx;
    vec4 x = surface(px, nx);
    if (x.w == 0.0) {
        imageStore(blurred, px, vec4(0.0));
        return;
    }
    bool gx;
    vec3 ax = reflectance(px, gx);
    ivec2 lo = px - ivec2(int(k / 2u)), hi = lo + ivec2(int(k)) - 1;
    precise vec3 sum = vec3(0.0), cnt = vec3(0.0);
    for (int yy = max(lo.y, 0); yy <= min(hi.y, int(size.y) - 1); ++yy)
        for (int xx = max(lo.x, 0); xx <= min(hi.x, int(size.x) - 1); ++xx) {
            ivec2 q = ivec2(xx, yy);
            bool gq = gx;
            vec3 aq = ax;
            if (q != px) {
                vec3 nq;
                vec4 y = surface(q, nq);
                if (y.w == 0.0) continue;
                aq = reflectance(q, gq);
                if (gq != gx) continue;
                precise float dx = y.x - x.x, dy = y.y - x.y, dz = y.z - x.z;
                precise float d2 = dx * dx + dy * dy + dz * dz;
                if (!(d2 <= tol2)) continue;
                precise float c = nq.x * nx.x + nq.y * nx.y + nq.z * nx.z;
                if (!(c >= normal_cos)) continue;
            }
            vec3 l = texelFetch(radiance, q, 0).rgb;
            for (int c = 0; c < 3; ++c) {
                if (gx) {
                    sum[c] += l[c];
                    cnt[c] += 1.0;
                } else if (aq[c] > 0.0) {   /* the light, without the neighbour's albedo */
                    precise float e = l[c] / aq[c];
                    sum[c] += e;
                    cnt[c] += 1.0;
                }
            }
        }
    precise vec3 o;
    for (int c = 0; c < 3; ++c) {
        precise float m = cnt[c] > 0.0 ? sum[c] / cnt[c] : 0.0;
        o[c] = gx ? m : (ax[c] > 0.0 ? ax[c] * m : 0.0);   /* no albedo: no light (gim_geometry_blur_twin) */
    }
    imageStore(blurred, px, vec4(clamp(o, vec3(-max_value), vec3(max_value)), 1.0));
}
