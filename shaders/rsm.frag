/* Reflective shadow map of one light (Bischoff 2017 sec. 3; units in gimany.h @section twins):
   every texel a VAL with world position (w = 1 where lit), normal towards the light with the
   footprint area A in w, and reflected flux Phi = albedo x the power arriving on the footprint.
     spot: w = s^2 / (1 + u^2 + v^2)^(3/2), the texel's solid angle at image-plane point (u, v);
           Phi = albedo I w; A = w d^2 / cos (eq. 1 of Bischoff 2017, exact off the axis)
     sun:  a = (width / size) (height / size), the texel's area perpendicular to the light;
           Phi = albedo E a (E cos on a / cos); A = a / cos
   cos is clamped below at min_cos so A stays finite at grazing angles. */
#include "common.glsl"
in vec3 world_position;
in vec3 world_normal;

layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_flux;

struct Material { vec4 diffuse; vec4 glossy; };      /* rgb; glossy.w = exponent k */
layout(std430, binding = 0) readonly buffer Materials { Material material[]; };
layout(std430, binding = 1) readonly buffer TriangleMaterial { uint triangle_material[]; };

layout(location = 3) uniform uint material_count;
layout(location = 4) uniform vec4 eye;       /* spot: (position, 1); sun: (unit direction to the light, 0) */
layout(location = 5) uniform int is_spot;
layout(location = 6) uniform vec3 power;     /* spot: colour I; sun: colour E a */
layout(location = 7) uniform vec4 axis_cos;  /* spot: unit axis, cos(cone half-angle) */
layout(location = 8) uniform vec4 rsm;       /* size, tan(half fov) (spot), s^2 (spot) or a (sun) */
layout(location = 9) uniform float min_cos;

void main() {
    uint id = min(triangle_material[gl_PrimitiveID], material_count - 1u);
    vec3 albedo = material[id].diffuse.rgb;
    vec3 toward = eye.w > 0.0 ? eye.xyz - world_position : eye.xyz;
    float d2 = dot(toward, toward);
    toward = normalize(toward);
    vec3 n = normalize(world_normal);
    n = dot(n, toward) < 0.0 ? -n : n;                 /* two-sided: the lit side */
    float c = max(dot(n, toward), min_cos);
    float lit = 1.0, area, share;
    if (is_spot != 0) {
        vec2 uv = (gl_FragCoord.xy / rsm.x * 2.0 - 1.0) * rsm.y;
        float q = 1.0 + dot(uv, uv);
        float omega = rsm.z / (q * sqrt(q));
        lit = dot(-toward, axis_cos.xyz) >= axis_cos.w ? 1.0 : 0.0;
        area = omega * d2 / c;
        share = omega;
    } else {
        area = rsm.z / c;
        share = 1.0;
    }
    /* finite whatever the scale (lengths near 1e19 overflow d^2): clamp at FLT_MAX */
    out_position = vec4(world_position, lit);
    out_normal = vec4(n, min(area, FLT_MAX));
    out_flux = vec4(min(albedo * power * (share * lit), vec3(FLT_MAX)), 0.0);
}
