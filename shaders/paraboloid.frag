/* One texel of a paraboloid map (gimany.h @section twins, gim_paraboloid_texel_twin): the ray
   from the map's origin through the texel centre's direction against the triangle
   paraboloid.geom passed (Moller-Trumbore, vertices relative to the origin); a miss, a hit
   nearer than the pass's skip or a texel outside the unit disk is discarded. The skip: the
   visibility pass's near_distance (the VAL's own surface, Dong fig. 7), the attribute pass's
   attribute_near (only the surface under the origin: a second-bounce ray lands on the first
   surface it meets). Depth d / (d + scene_scale), monotone in d, keeps the nearest hit.
   Outputs: distance d (the visibility pass); position (w = 1), the normal turned towards the
   origin, and the triangle's diffuse albedo (the attribute pass). */
#include "common.glsl"
flat in vec3 tri_v0;
flat in vec3 tri_v1;
flat in vec3 tri_v2;
flat in vec3 tri_n0;
flat in vec3 tri_n1;
flat in vec3 tri_n2;
flat in vec3 tri_albedo;
flat in vec3 tri_origin;
flat in vec3 tri_axis;
flat in float tri_near;
flat in float tri_attribute_near;

layout(location = 0) out float out_distance;
layout(location = 1) out vec4 out_position;
layout(location = 2) out vec4 out_normal;
layout(location = 3) out vec4 out_albedo;

layout(location = 5) uniform uint size;
layout(location = 6) uniform float scene_scale;
layout(location = 7) uniform uint attribute_pass;   /* 1: skip attribute_near (flux.w), 0: near_distance */

void main() {
    vec2 uv = (2.0 * floor(gl_FragCoord.xy) + 1.0) / float(size) - 1.0;
    float r2 = dot(uv, uv);
    if (r2 > 1.0) discard;
    vec3 w = vec3(2.0 * uv, 1.0 - r2) / (1.0 + r2);
    vec3 n = tri_axis, t, b;
    basis(n, t, b);
    vec3 d = normalize(w.x * t + w.y * b + w.z * n);
    vec3 e1 = tri_v1 - tri_v0, e2 = tri_v2 - tri_v0, tv = -tri_v0;
    vec3 pv = cross(d, e2);
    float det = dot(e1, pv);
    if (det == 0.0) discard;
    float u = dot(tv, pv) / det;
    if (u < 0.0 || u > 1.0) discard;
    vec3 qv = cross(tv, e1);
    float v = dot(d, qv) / det;
    if (v < 0.0 || u + v > 1.0) discard;
    float s = dot(e2, qv) / det;
    if (!(s > (attribute_pass != 0u ? tri_attribute_near : tri_near))) discard;
    gl_FragDepth = s / (s + scene_scale);
    out_distance = s;
    out_position = vec4(tri_origin + s * d, 1.0);
    vec3 nn = (1.0 - u - v) * tri_n0 + u * tri_n1 + v * tri_n2;
    float len = length(nn);
    nn = len > 0.0 ? nn / len : vec3(0.0);
    out_normal = vec4(dot(nn, d) > 0.0 ? -nn : nn, 0.0);
    out_albedo = vec4(tri_albedo, 1.0);
}
