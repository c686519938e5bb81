/* The host's packed G-buffer into the layout every pass reads (gim_frame.gbuffer_encoding):
   world normals in .xyz (w = 1 where drawn) and window depth in [0, 1] (1: nothing drawn).
   Normals: signed xyz, xyz * 0.5 + 0.5, or the octahedral map (Cigolle et al. 2014) in [-1, 1]
   or * 0.5 + 0.5; in view space they are turned back by the inverse view's rotation. Depth:
   the window depth, or the positive view-space distance along -z, projected by proj's z and w
   rows (0, negative or not finite: nothing drawn). Runs only when the encoding is not gimany's
   own (a host that writes float world normals and window depth pays nothing). Twin:
   gim_gbuffer_decode_twin. */
#include "common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

layout(binding = 0) uniform sampler2D host_depth;
layout(binding = 1) uniform sampler2D host_normal;
layout(rgba16f, binding = 0) uniform writeonly image2D out_normal;
layout(r32f, binding = 1) uniform writeonly image2D out_depth;

layout(location = 0) uniform uvec2 size;
layout(location = 1) uniform int normal_encoding;   /* gim_normal_encoding */
layout(location = 2) uniform int view_space;        /* 1: rotate by view_to_world */
layout(location = 3) uniform mat4 view_to_world;   /* its 3x3: the transpose of view's */
layout(location = 7) uniform int depth_view_z;      /* 1: host_depth.r is the distance along -z */
layout(location = 8) uniform vec4 proj_zw;          /* proj[2][2], proj[3][2], proj[2][3], proj[3][3] */

vec3 decode_normal(vec4 e) {
    if (normal_encoding == 1) return e.xyz * 2.0 - 1.0;
    if (normal_encoding == 2 || normal_encoding == 3) {
        vec2 f = normal_encoding == 3 ? e.xy * 2.0 - 1.0 : e.xy;
        vec3 n = vec3(f, 1.0 - abs(f.x) - abs(f.y));
        if (n.z < 0.0) n.xy = (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
        return n;
    }
    return e.xyz;
}

void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= int(size.x) || px.y >= int(size.y)) return;
    float d = texelFetch(host_depth, px, 0).r;
    vec3 n = decode_normal(texelFetch(host_normal, px, 0));
    if (depth_view_z != 0) {
        /* a point at view z = -d: ndc z = (P22 z + P32) / (P23 z + P33) */
        float z = -d, w = proj_zw.z * z + proj_zw.w;
        float ndc = (proj_zw.x * z + proj_zw.y) / w;
        d = d > 0.0 && w > 0.0 && ndc <= 1.0 ? ndc * 0.5 + 0.5 : 1.0;
        if (!(d == d)) d = 1.0;
    }
    if (view_space != 0) n = mat3(view_to_world) * n;
    bool drawn = d < 1.0 && finite3(n) && dot(n, n) > 0.0;
    imageStore(out_normal, px, drawn ? vec4(normalize(n), 1.0) : vec4(0.0));
    imageStore(out_depth, px, vec4(drawn ? d : 1.0, 0.0, 0.0, 0.0));
}
