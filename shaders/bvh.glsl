/* Segment visibility through the scene's bounding volume hierarchy (gim_bvh_occluded, its float
   steps in its order, `precise` so that no multiply-add is fused). tools/embed_shaders.c puts
   this file in place of a shader's line `#include "bvh.glsl"`, which must come after the
   shader's declaration of the hierarchy, `vec4 bvh[]` (gim_bvh's nodes, two vec4 each: lo and
   the index bits, hi and the count bits; then from vec4 bvh_triangles on its triangles, three
   vec4 each: v0, v1 - v0, v2 - v0, all in the frame (x - bvh_origin) bvh_scale), and of the
   uniforms bvh_triangles, bvh_nodes (0: an empty hierarchy, nothing blocks), bvh_origin and
   bvh_scale (gim_bvh.origin, scale). lightskin_shade.comp tests a pixel's neighbour caches,
   proxy_lights.comp each VAL at each cache. */
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
    precise vec3 o = vec3((from.x - bvh_origin.x) * bvh_scale, (from.y - bvh_origin.y) * bvh_scale,
                          (from.z - bvh_origin.z) * bvh_scale);
    precise vec3 e = vec3((to.x - bvh_origin.x) * bvh_scale, (to.y - bvh_origin.y) * bvh_scale,
                          (to.z - bvh_origin.z) * bvh_scale);
    precise vec3 d = vec3(e.x - o.x, e.y - o.y, e.z - o.z);
    if (!finite3(o) || !finite3(d)) return false;
    vec3 inv;   /* 0: an axis along which the segment barely moves, tested by its extent */
    for (int a = 0; a < 3; ++a) inv[a] = abs(d[a]) >= 1e-30 ? 1.0 / d[a] : 0.0;
    uint stack[BVH_STACK];
    uint sp = 0u, node = 0u;
    for (;;) {
        vec4 lo = bvh[2u * node], hi = bvh[2u * node + 1u];
        float tn = 0.0, tf = 1.0;
        for (int a = 0; a < 3; ++a) {
            if (inv[a] != 0.0) {
                precise float t0 = (lo[a] - o[a]) * inv[a], t1 = (hi[a] - o[a]) * inv[a];
                tn = max(tn, min(t0, t1));
                tf = min(tf, max(t0, t1));
            } else {
                precise float e0 = o[a] + abs(d[a]), e1 = o[a] - abs(d[a]);
                if (e0 < lo[a] || e1 > hi[a]) tf = -1.0;
            }
        }
        precise float slack = tf * 1.000001;   /* each t within 3 rounding steps (Ize 2013) */
        if (tn <= slack) {
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
