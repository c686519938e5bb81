/* Segment visibility and nearest crossings through the scene's bounding volume hierarchy
   (gim_bvh_occluded, gim_bvh_nearest: their float steps in their order, `precise` so that no multiply-add is fused). tools/embed_shaders.c puts
   this file in place of a shader's line `#include "bvh.glsl"`, which must come after the
   shader's declaration of the hierarchy, `vec4 bvh[]` (gim_bvh's nodes, two vec4 each: lo and
   the index bits, hi and the count bits; then from vec4 bvh_triangles on its triangles, three
   vec4 each: v0 (w: the triangle's material id bits), v1 - v0, v2 - v0, all in the frame (x - bvh_origin) bvh_scale), and of the
   uniforms bvh_triangles, bvh_nodes (0: an empty hierarchy, nothing blocks), bvh_origin and
   bvh_scale (gim_bvh.origin, scale). lightskin_shade.comp tests a pixel's neighbour caches,
   proxy_lights.comp each VAL at each cache, second_bounce_rays.comp finds where each
   second-bounce ray lands (bvh_nearest). */
#define BVH_STACK 48   /* GIM_BVH_MAX_DEPTH */

/* The open segment o + t d, 0 < t < 1, against the triangle from vec4 at on (Moller and
   Trumbore 1997 without the division; gim__bvh_triangle_at): on a hit tt and dd are the
   crossing's e2 . q and det (sign-flipped where det < 0). */
bool bvh_triangle_at(uint at, vec3 o, vec3 d, out float tt, out float dd) {
    precise vec3 v0 = bvh[at].xyz, e1 = bvh[at + 1u].xyz, e2 = bvh[at + 2u].xyz;
    precise float px = d.y * e2.z - d.z * e2.y;
    precise float py = d.z * e2.x - d.x * e2.z;
    precise float pz = d.x * e2.y - d.y * e2.x;
    precise float det = e1.x * px + e1.y * py + e1.z * pz;
    tt = 0.0;
    dd = 0.0;
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
    tt = t;
    dd = det;
    return u >= -g && v >= -g && uv <= dg && t > 0.0 && t < det;
}

bool bvh_triangle(uint at, vec3 o, vec3 d) {
    float t, det;
    return bvh_triangle_at(at, o, d, t, det);
}

/* The slab test of node `node` against o + t d, 0 <= t <= reach (gim__bvh_box): inv 0 on an
   axis along which the segment barely moves, tested by its extent there; each t within 3
   rounding steps (Ize 2013). */
bool bvh_box(uint node, vec3 o, vec3 d, vec3 inv, float reach) {
    vec4 lo = bvh[2u * node], hi = bvh[2u * node + 1u];
    float tn = 0.0, tf = reach;
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
    precise float slack = tf * 1.000001;
    return tn <= slack;
}

/* The segment from -> to in the hierarchy's frame (gim__bvh_segment): false where an end is
   not finite. */
bool bvh_segment(vec3 from, vec3 to, out vec3 o, out vec3 d, out vec3 inv) {
    precise vec3 po = vec3((from.x - bvh_origin.x) * bvh_scale, (from.y - bvh_origin.y) * bvh_scale,
                           (from.z - bvh_origin.z) * bvh_scale);
    precise vec3 e = vec3((to.x - bvh_origin.x) * bvh_scale, (to.y - bvh_origin.y) * bvh_scale,
                          (to.z - bvh_origin.z) * bvh_scale);
    precise vec3 pd = vec3(e.x - po.x, e.y - po.y, e.z - po.z);
    o = po;
    d = pd;
    for (int a = 0; a < 3; ++a) inv[a] = abs(pd[a]) >= 1e-30 ? 1.0 / pd[a] : 0.0;
    return finite3(po) && finite3(pd);
}

/* true when a triangle crosses the open segment from -> to */
bool bvh_occluded(vec3 from, vec3 to) {
    if (bvh_nodes == 0u) return false;
    vec3 o, d, inv;   /* inv 0: an axis along which the segment barely moves, tested by its extent */
    if (!bvh_segment(from, to, o, d, inv)) return false;
    uint stack[BVH_STACK];
    uint sp = 0u, node = 0u;
    for (;;) {
        if (bvh_box(node, o, d, inv, 1.0)) {
            uint index = floatBitsToUint(bvh[2u * node].w), count = floatBitsToUint(bvh[2u * node + 1u].w);
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

/* gim_bvh_nearest: the slot of the nearest triangle the segment from -> to crosses (0xffffffff:
   none) and its place hit_t along it; the walk's segment cut at each nearer crossing, which is
   compared by the products e2 . q det' < e2 . q' det (no division decides). */
uint bvh_nearest(vec3 from, vec3 to, out float hit_t) {
    hit_t = 1.0;
    if (bvh_nodes == 0u) return 0xffffffffu;
    vec3 o, d, inv;
    if (!bvh_segment(from, to, o, d, inv)) return 0xffffffffu;
    uint stack[BVH_STACK];
    uint sp = 0u, node = 0u, best = 0xffffffffu;
    precise float bt = 1.0, bd = 1.0;
    float reach = 1.0;
    for (;;) {
        if (bvh_box(node, o, d, inv, reach)) {
            uint index = floatBitsToUint(bvh[2u * node].w), count = floatBitsToUint(bvh[2u * node + 1u].w);
            if (count == 0u) {
                stack[sp++] = index;
                node += 1u;
                continue;
            }
            for (uint k = 0u; k < count; ++k) {
                float t, det;
                if (bvh_triangle_at(bvh_triangles + 3u * (index + k), o, d, t, det)) {
                    precise float lhs = t * bd, rhs = bt * det;
                    if (lhs < rhs) {
                        bt = t;
                        bd = det;
                        best = index + k;
                        reach = bt / bd;
                    }
                }
            }
        }
        if (sp == 0u) break;
        node = stack[--sp];
    }
    hit_t = bt / bd;
    return best;
}
