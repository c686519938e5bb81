/* Segment visibility through the scene's bounding volume hierarchy (gim_bvh_occluded, its float
   steps in its order, `precise` so that no multiply-add is fused). tools/embed_shaders.c puts
   this file in place of a shader's line `#include "bvh.glsl"`, which must come after the
   shader's declaration of the hierarchy, `vec4 bvh[]` (gim_bvh's nodes, two vec4 each: lo and
   the index bits, hi and the count bits; then from vec4 bvh_triangles on its triangles, three
   vec4 each: v0, v1 - v0, v2 - v0), and of the uniforms bvh_triangles and bvh_nodes (0: an
   empty hierarchy, nothing blocks). lightskin_shade.comp tests a pixel's neighbour caches. */
#define BVH_STACK 48   /* GIM_BVH_MAX_DEPTH */

/* The open segment o + t d, 0 < t < 1, against the triangle from vec4 at on (Moller and
   Trumbore 1997 without the division; gim__bvh_triangle). */
bool bvh_triangle(uint at, vec3 o, vec3 d) {
    precise vec3 v0 = bvh[at].xyz, e1 = bvh[at + 1u].xyz, e2 = bvh[at + 2u].xyz;
    precise float px = d.y * e2.z - d.z * e2.y;
    precise float py = d.z * e2.x - d.x * e2.z;
    precise float pz = d.x * e2.y - d.y * e2.x;
    precise float det = e1.x * px + e1.y * py + e1.z * pz;
    if (det == 0.0) return false;
    precise float sx = o.x - v0.x, sy = o.y - v0.y, sz = o.z - v0.z;
    precise float u = sx * px + sy * py + sz * pz;
    precise float qx = sy * e1.z - sz * e1.y;
    precise float qy = sz * e1.x - sx * e1.z;
    precise float qz = sx * e1.y - sy * e1.x;
    precise float v = d.x * qx + d.y * qy + d.z * qz;
    precise float t = e2.x * qx + e2.y * qy + e2.z * qz;
    if (det < 0.0) { det = -det; u = -u; v = -v; t = -t; }
    precise float g = 1e-4 * det;   /* GIM__BVH_GROW: a ray along a shared edge hits one of the two */
    precise float uv = u + v, dg = det + g;
    return u >= -g && v >= -g && uv <= dg && t > 0.0 && t < det;
}

/* true when a triangle crosses the open segment from -> to */
bool bvh_occluded(vec3 from, vec3 to) {
    if (bvh_nodes == 0u) return false;
    precise vec3 o = from;
    precise vec3 d = vec3(to.x - from.x, to.y - from.y, to.z - from.z);
    vec3 inv;
    for (int a = 0; a < 3; ++a) {   /* never infinite: no slab gives 0 x inf */
        float da = d[a] >= 0.0 ? (d[a] > 1e-30 ? d[a] : 1e-30) : (d[a] < -1e-30 ? d[a] : -1e-30);
        inv[a] = 1.0 / da;
    }
    uint stack[BVH_STACK];
    uint sp = 0u, node = 0u;
    for (;;) {
        vec4 lo = bvh[2u * node], hi = bvh[2u * node + 1u];
        precise vec3 t0 = vec3((lo.x - o.x) * inv.x, (lo.y - o.y) * inv.y, (lo.z - o.z) * inv.z);
        precise vec3 t1 = vec3((hi.x - o.x) * inv.x, (hi.y - o.y) * inv.y, (hi.z - o.z) * inv.z);
        vec3 tlo = min(t0, t1), thi = max(t0, t1);
        float tn = max(max(max(tlo.x, 0.0), tlo.y), tlo.z);
        float tf = min(min(min(thi.x, 1.0), thi.y), thi.z);
        if (tn <= tf) {
            uint index = floatBitsToUint(lo.w), count = floatBitsToUint(hi.w);
            if (count == 0u) {
                stack[sp++] = index;
                node += 1u;
                continue;
            }
            for (uint k = 0u; k < count; ++k)
                if (bvh_triangle(bvh_triangles + 3u * (index + k), o, d)) return true;
        }
        if (sp == 0u) return false;
        node = stack[--sp];
    }
    return false;
}
