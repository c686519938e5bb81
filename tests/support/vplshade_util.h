/* Shared by test_vpl_shade.c and gltest_vpl_shade.c: a synthetic paraboloid distance map of a
   square blocker (a plate parallel to the VAL's plane), built from the declared convention. */
#ifndef GIMANY_VPLSHADE_UTIL_H
#define GIMANY_VPLSHADE_UTIL_H

/* Map m's size^2 distances: texel (x, y)'s centre direction w (gimany.h "Paraboloid maps");
   a plate at local height h covering |l.x|, |l.y| <= half (offset cx, cy in the map's t, b
   frame) is hit at h / w.z; elsewhere and outside the disk GIM_PARABOLOID_EMPTY. */
static void vs_plate_map(float *dist, uint32_t size, float h, float cx, float cy, float half) {
    uint32_t x, y;
    for (y = 0; y < size; ++y)
        for (x = 0; x < size; ++x) {
            double u = (2.0 * x + 1.0) / size - 1.0, v = (2.0 * y + 1.0) / size - 1.0, q = u * u + v * v;
            float out = GIM_PARABOLOID_EMPTY;
            if (q <= 1.0) {
                double wx = 2.0 * u / (1.0 + q), wy = 2.0 * v / (1.0 + q), wz = (1.0 - q) / (1.0 + q);
                if (wz > 1e-6) {
                    double t = h / wz, px = wx * t, py = wy * t;
                    if (fabs(px - cx) <= half && fabs(py - cy) <= half) out = (float)t;
                }
            }
            dist[(size_t)y * size + x] = out;
        }
}

/* The world point at local (a, b, c) of map m (origin + a t + b b + c n, gim__basis of n). */
static gim_vec3 vs_local(const gim_paraboloid *m, float a, float b, float c) {
    gim_vec3 n = gim_v3(m->normal[0], m->normal[1], m->normal[2]), t, bb;
    gim__basis(n, &t, &bb);
    return gim_v3(m->origin[0] + a * t.x + b * bb.x + c * n.x, m->origin[1] + a * t.y + b * bb.y + c * n.y,
                  m->origin[2] + a * t.z + b * bb.z + c * n.z);
}

#endif
