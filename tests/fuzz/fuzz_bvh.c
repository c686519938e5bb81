/* libFuzzer target: arbitrary triangles into gim_bvh_build (raw float bits: NaN, Inf, huge,
   denormal; or small integer grids: duplicates, degenerates, coplanar walls) and arbitrary
   segments into gim_bvh_occluded and gim_bvh_nearest. A refused scene must have a non-finite vertex; a built one
   must hold every triangle in one leaf inside its node's box, stay within the depth bound, hit
   only where some triangle's test hits, and answer every segment whose verdict is clear in
   double (no triangle within float's error of it) as the exact test does; bounds wider than a
   float are refused; nothing may leak. */
#define GIMANY_IMPLEMENTATION
#ifndef GIMANY_NO_GL
#define GIMANY_NO_GL
#endif
#include "gimany.h"
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "fuzzutil.h"

/* the next float from data: raw bits (flags & 1) or a small integer grid value */
static float fz_float(const uint8_t *data, size_t size, size_t *at, unsigned flags) {
    float f = 0.0f;
    if (flags & 1u) {
        uint32_t b = 0;
        if (*at + 4 <= size) memcpy(&b, data + *at, 4);
        *at += 4;
        memcpy(&f, &b, 4);
    } else {
        f = *at < size ? (float)((int)data[*at] % 9 - 4) * ((flags & 2u) ? 1e-20f : (flags & 4u) ? 1e20f : 1.0f) : 0.0f;
        *at += 1;
    }
    return f;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    float pos[48 * 9];
    uint32_t n, i, t;
    size_t at = 2;
    unsigned flags;
    int finite = 1;
    double diag = 0.0;
    fz_alloc al = {0};
    gim_env env;
    gim_twin_scene s;
    gim_bvh b;
    gim_result r;
    if (size < 2) return 0;
    flags = data[0];
    n = data[1] % 49u;
    for (i = 0; i < n * 9u; ++i) {
        pos[i] = fz_float(data, size, &at, flags);
        finite &= pos[i] == pos[i] && pos[i] - pos[i] == 0.0f;
    }
    memset(&env, 0, sizeof env);
    env.allocator.alloc = fz_malloc;
    env.allocator.free = fz_free;
    env.allocator.user_data = &al;
    memset(&s, 0, sizeof s);
    s.positions = pos;
    s.triangle_count = n;
    r = gim_bvh_build(&s, env, &b);
    if (!finite) {
        FZ_CHECK(r == GIM_ERROR_INVALID_ARGUMENT && al.live == 0);
        return 0;
    }
    if (r == GIM_ERROR_OUT_OF_RANGE) {   /* bounds wider than a float */
        FZ_CHECK(al.live == 0);
        return 0;
    }
    FZ_CHECK(r == GIM_OK);
    FZ_CHECK(b.triangle_count == n && b.depth < GIM_BVH_MAX_DEPTH && b.node_count <= (n ? 2u * n - 1u : 0u));
    {   /* every triangle in one leaf, inside its box */
        uint32_t covered = 0;
        for (i = 0; i < b.node_count; ++i) {
            const gim_bvh_node *nd = b.nodes + i;
            if (nd->count == 0) { FZ_CHECK(nd->index > i + 1u && nd->index < b.node_count); continue; }
            FZ_CHECK(nd->count <= GIM_BVH_LEAF && nd->index + nd->count <= n);
            covered += nd->count;
            for (t = nd->index; t < nd->index + nd->count; ++t) {
                const float *q = b.triangles + (size_t)t * 12u;
                int a;
                for (a = 0; a < 3; ++a) FZ_CHECK(q[a] >= nd->lo[a] && q[a] <= nd->hi[a]);
            }
        }
        FZ_CHECK(covered == n);
    }
    {
        double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
        for (i = 0; i < n * 9u; ++i) {
            if (pos[i] < lo[i % 3u]) lo[i % 3u] = pos[i];
            if (pos[i] > hi[i % 3u]) hi[i % 3u] = pos[i];
        }
        for (i = 0; i < 3u && n; ++i) diag += (hi[i] - lo[i]) * (hi[i] - lo[i]);
        diag = sqrt(diag);
    }
    for (i = 0; i < 8u && at + 6 <= size + 24; ++i) {   /* segments */
        gim_vec3 p, q;
        float o[3], d[3];
        int h, any = 0, clear = 1, exact = 0;
        p.x = fz_float(data, size, &at, flags); p.y = fz_float(data, size, &at, flags); p.z = fz_float(data, size, &at, flags);
        q.x = fz_float(data, size, &at, flags); q.y = fz_float(data, size, &at, flags); q.z = fz_float(data, size, &at, flags);
        h = gim_bvh_occluded(&b, p, q);
        if (n && gim__bvh_segment(&b, p, q, o, d))
            for (t = 0; t < n && !any; ++t) any = gim__bvh_triangle(b.triangles + (size_t)t * 12u, o, d);
        FZ_CHECK(!h || any);   /* the walk tests some of the triangles: its hit is one of theirs */
        {   /* the nearest crossing: found exactly where the walk finds one, a crossing of its own slot */
            gim_bvh_hit hh;
            int hn = gim_bvh_nearest(&b, p, q, &hh);
            FZ_CHECK(hn == h);
            if (hn) {
                float tt, dt;
                FZ_CHECK(hh.slot < n && hh.triangle < n && hh.t >= 0.0f && hh.t <= 1.0f);
                FZ_CHECK(gim__bvh_segment(&b, p, q, o, d) &&
                         gim__bvh_triangle_at(b.triangles + (size_t)hh.slot * 12u, o, d, &tt, &dt));
            }
        }
        /* where every triangle's verdict is clear in double (the hit inside or outside by more
           than float's error on it: 1e-4 of the condition C = (|s| + |d| + the bounds' diagonal) /
           (sin x the shortest of the edges and the segment)),
           the walk answers it: the boxes lose no clear hit and the growth adds no clear miss */
        for (t = 0; t < n && clear; ++t) {
            const float *v = pos + t * 9u;
            double e1[3], e2[3], dd[3], sv[3], pv[3], qv[3], det, u, w, tt, l1 = 0, l2 = 0, ld = 0, ls = 0, m, cond;
            int a;
            for (a = 0; a < 3; ++a) {
                e1[a] = (double)v[3 + a] - v[a];
                e2[a] = (double)v[6 + a] - v[a];
                sv[a] = (double)(a == 0 ? p.x : a == 1 ? p.y : p.z) - v[a];
                dd[a] = (double)(a == 0 ? q.x : a == 1 ? q.y : q.z) - (a == 0 ? p.x : a == 1 ? p.y : p.z);
                l1 += e1[a] * e1[a]; l2 += e2[a] * e2[a]; ld += dd[a] * dd[a]; ls += sv[a] * sv[a];
            }
            l1 = sqrt(l1); l2 = sqrt(l2); ld = sqrt(ld); ls = sqrt(ls);
            if (!(l1 > 0.0 && l2 > 0.0 && ld > 0.0) || !(l1 < 1e30 && l2 < 1e30 && ld < 1e30 && ls < 1e30)) { clear = l1 > 0.0 && l2 > 0.0 && ld > 0.0 ? 0 : clear; continue; }
            pv[0] = dd[1] * e2[2] - dd[2] * e2[1]; pv[1] = dd[2] * e2[0] - dd[0] * e2[2]; pv[2] = dd[0] * e2[1] - dd[1] * e2[0];
            det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
            /* positions are floats in a frame of the bounds' size: known to float's error of it */
            cond = (ls + ld + diag) / (fabs(det) / (l1 * l2 * ld) * (l1 < l2 ? (l1 < ld ? l1 : ld) : (l2 < ld ? l2 : ld)));
            if (!(cond < 1e3)) { clear = 0; break; }   /* a degenerate triangle or a grazing segment: float decides */
            qv[0] = sv[1] * e1[2] - sv[2] * e1[1]; qv[1] = sv[2] * e1[0] - sv[0] * e1[2]; qv[2] = sv[0] * e1[1] - sv[1] * e1[0];
            u = (sv[0] * pv[0] + sv[1] * pv[1] + sv[2] * pv[2]) / det;
            w = (dd[0] * qv[0] + dd[1] * qv[1] + dd[2] * qv[2]) / det;
            tt = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
            m = u < w ? u : w;
            if (1.0 - u - w < m) m = 1.0 - u - w;
            if (tt < m) m = tt;
            if (1.0 - tt < m) m = 1.0 - tt;
            if (fabs(m) < 1e-4 * cond + 2e-4) { clear = 0; break; }
            exact |= m > 0.0;
        }
        if (clear && n && gim__bvh_segment(&b, p, q, o, d)) FZ_CHECK(h == exact);
    }
    gim_bvh_free(&b);
    FZ_CHECK(al.live == 0);
    return 0;
}
