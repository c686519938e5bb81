/* k-means assignment step on the GPU (Dong et al. sec. 5.1; SSVP sec. 3), the twin of
   gim_kmeans' assignment: one invocation per VPL, an argmin over the M centres in index order.
   A VPL leaves its cluster only for a strictly smaller distance; with no cluster yet
   (0xffffffff) the lowest index wins a tie. Distance, s the scene scale (wx_s = w_x / s):
     Dong: w_x |x - c| / s + w_a angle(n, n_c) / pi   (wa = w_a / pi)
     SSVP: w_x |x - c| / s + w_a (1 - max(n . n_c, 0))  (eq. 2, its sign slip corrected)
   The angle is 2 atan(|n - n_c|, |n + n_c|), not acos(n . n_c): the same angle, but accurate
   in float where the normals are nearly parallel (acos loses ~3e-4 rad there), the common
   case on a wall. A VPL of zero normal (the unlit VPLs of rsm_vpls.comp may have one) is
   taken as perpendicular to every centre (n . n_c = 0); so is a centre of zero normal.
   Reset mode (reset = 1): every assignment [0, vpl_count) set to none, nothing read; gimany's
   GPU clear that takes no clear value from client memory (no host pixel store applies). */
#include "common.glsl"
layout(local_size_x = 64) in;

struct Vpl { vec4 position; vec4 normal; vec4 flux; };
layout(std430, binding = 0) readonly buffer Vpls { Vpl vpl[]; };
struct Centre { vec4 position; vec4 normal; };   /* position.w: VPL count of the last update */
layout(std430, binding = 1) readonly buffer Centres { Centre centre[]; };
layout(std430, binding = 2) buffer Assignment { uint assignment[]; };

layout(location = 0) uniform uint vpl_count;
layout(location = 1) uniform uint cluster_count;
layout(location = 2) uniform float wx_s;
layout(location = 3) uniform float wa;
layout(location = 4) uniform uint ssvp;   /* 0: Dong's metric, 1: SSVP's */
layout(location = 5) uniform uint reset;  /* 1: set every assignment to NONE */

const uint NONE = 0xffffffffu;

float dist(vec3 x, vec3 n, uint j) {
    vec3 c = centre[j].position.xyz, cn = centre[j].normal.xyz;
    float dir, lc = length(cn);
    cn = lc > 0.0 ? cn / lc : vec3(0.0);   /* the twin renormalises its init normals */
    if (ssvp != 0u) dir = wa * (1.0 - max(dot(n, cn), 0.0));
    else if (n == vec3(0.0) || cn == vec3(0.0)) dir = wa * (0.5 * PI);
    else dir = wa * (2.0 * atan(length(n - cn), length(n + cn)));
    return wx_s * length(x - c) + dir;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= vpl_count) return;
    if (reset != 0u) { assignment[i] = NONE; return; }
    vec3 x = vpl[i].position.xyz, n = vpl[i].normal.xyz;
    float len = length(n);
    n = len > 0.0 ? n / len : vec3(0.0);
    uint cur = assignment[i], arg = cur;
    float best = 1.0 / 0.0;
    if (cur != NONE) best = dist(x, n, cur);
    for (uint j = 0u; j < cluster_count; ++j) {
        if (j == cur) continue;
        float d = dist(x, n, j);
        if (d < best) { best = d; arg = j; }
    }
    assignment[i] = arg;
}
