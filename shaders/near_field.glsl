/* The near field of a VAL or VPL (Bischoff 2017's VALs as the patches they stand for; the VPLs'
   likewise), shared by proxy_lights.comp and vpl_shade.comp. tools/embed_shaders.c puts this
   file in place of a shader's line `#include "near_field.glsl"`, after common.glsl's. */
/* The patch of a VAL or VPL near a receiver (gim__octagon_phi, the same float steps): a regular
   octagon of area A around d (the light's centre relative to the receiver) in the plane of
   normal nl, clipped to the receiver's hemisphere n . y >= 0; phi is 2 pi times its vector form
   factor by Lambert's contour formula, turned so that n . phi >= 0, returned f = n . phi. Every
   loop has a constant trip count, which the compiler unrolls (llvmpipe counts every loop
   iteration of an invocation against its 65535). */
const float VAL_NEAR = 2.0;   /* GIM__VAL_NEAR: the near field reaches 2 sqrt(A) */
float octagon_phi(vec3 d, vec3 n, vec3 nl, float area, out vec3 phi) {
    float s = nl.z >= 0.0 ? 1.0 : -1.0, a = -1.0 / (s + nl.z), k = nl.x * nl.y * a;   /* gim_basis */
    vec3 t = vec3(1.0 + s * nl.x * nl.x * a, s * k, -s * nl.x), b = vec3(k, s + nl.y * nl.y * a, -nl.y);
    float r = sqrt(area / (2.0 * 1.41421356));   /* octagon of area 2 sqrt(2) r^2 = A */
    vec3 v[8];
    float h[8];
    vec3 poly[16];   /* each corner and each crossing: rounding can cross the plane more than twice */
    for (int q = 0; q < 16; ++q) poly[q] = vec3(0.0);
    int m = 0;
    const float S = 0.70710678;
    const vec2 dirs[8] = vec2[8](vec2(1.0, 0.0), vec2(S, S), vec2(0.0, 1.0), vec2(-S, S), vec2(-1.0, 0.0), vec2(-S, -S),
                                 vec2(0.0, -1.0), vec2(S, -S));
    for (int q = 0; q < 8; ++q) {
        v[q] = d + r * (dirs[q].x * t + dirs[q].y * b);
        h[q] = dot(n, v[q]);
    }
    for (int q = 0; q < 8; ++q) {   /* clipped to n . y >= 0 (Sutherland-Hodgman) */
        int q1 = (q + 1) & 7;
        if (h[q] >= 0.0) poly[m++] = v[q];
        if ((h[q] >= 0.0) != (h[q1] >= 0.0)) poly[m++] = v[q] + h[q] / (h[q] - h[q1]) * (v[q1] - v[q]);
    }
    phi = vec3(0.0);
    for (int q = 0; q < 16; ++q) {   /* Lambert's contour formula, as a vector */
        vec3 p0 = poly[q], p1 = poly[q + 1 < m ? q + 1 : 0];
        float l0 = length(p0), l1 = length(p1);
        vec3 c = cross(p0, p1) / (l0 * l1);
        float lc = length(c);
        if (q < m && l0 > 0.0 && l1 > 0.0 && lc > 0.0) phi += atan(lc, dot(p0, p1) / (l0 * l1)) / lc * c;
    }
    float f = dot(n, phi);
    if (f < 0.0) { f = -f; phi = -phi; }   /* the winding faces n */
    return f;
}

/* gim__near_weight: 1 within 1.5 sqrt(A), 0 from 2 sqrt(A), linear in d^2 between */
float near_weight(float d2, float area) {
    return min((VAL_NEAR * VAL_NEAR - d2 / area) / ((1.0 - 0.5625) * VAL_NEAR * VAL_NEAR), 1.0);
}

/* gim__near_patch: the near field's weight where the patch applies (with phi, f = n . phi,
   fv = |phi|), 0 where the far field stands: beyond 2 sqrt(A), a receiver within
   GIM__VPL_NEAR_LIFT (0.01) sqrt(A) of the patch's plane (a thin surface's other side, whose
   octagon rounding puts all in or all out of its hemisphere), nothing above its horizon. */
float near_patch(vec3 d, float d2, vec3 n, vec3 nl, float area, out vec3 phi, out float f, out float fv) {
    phi = vec3(0.0);
    f = 0.0;
    fv = 0.0;
    float w = near_weight(d2, area);
    if (!(w > 0.0)) return 0.0;
    if (!(-dot(nl, d) > 0.01 * sqrt(area))) return 0.0;
    f = octagon_phi(d, n, nl, area, phi);
    fv = length(phi);
    if (!(f > 0.0) || !(fv > 0.0) || !(fv <= 3.402823466e+38) || !(area > 0.0)) return 0.0;
    return w;
}
