/* libFuzzer target: arbitrary meshes into gim_cache_generate. Raw float bits (NaN, Inf, huge,
   denormal) or small integer grids (duplicates, degenerates, thin walls), 16/32-bit indices,
   out-of-range indices and materials, strides, normals. On success the caches must be sane,
   partition the surface, come out the same twice, and bind to the mesh and follow it at rest
   (gim_cache_bind, gim_caches_follow_twin) to finite caches or a clear refusal; nothing may leak. */
#define GIMANY_IMPLEMENTATION
#ifndef GIMANY_NO_GL
#define GIMANY_NO_GL
#endif
#include "gimany.h"
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "fuzzutil.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    static const float refl[3] = {0.1f, 0.5f, 0.9f};
    float pos[64 * 4], nrm[64 * 3];
    uint32_t idx32[96], mat[32];
    uint16_t idx16[96];
    uint32_t nv, ni, nt, i, k, flags, stride;
    size_t at = 4;
    int out_of_range = 0, bad_mat = 0;
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300}, diag = 0.0;
    fz_alloc al = {0};
    gim_cache_desc d;
    gim_cache_set s, s2;
    gim_result r;
    if (size < 4) return 0;
    flags = data[0];
    nv = 1u + data[3] % 64u;
    stride = (flags & 32u) ? 4u : 3u;
    memset(pos, 0, sizeof pos);
    for (i = 0; i < nv; ++i)
        for (k = 0; k < 3; ++k) {
            float f = 0.0f;
            if (flags & 64u) { /* small integer grid */
                if (at < size) f = (float)(int8_t)data[at++] * 0.25f;
            } else if (at + 4 <= size) {
                memcpy(&f, data + at, 4);
                at += 4;
            }
            pos[i * stride + k] = f;
        }
    for (i = 0; i < nv * 3; ++i) nrm[i] = (i % 3 == 2) ? 1.0f : 0.0f;
    if ((flags & 2u) && at < size) nrm[(data[at++] % nv) * 3] = NAN; /* a broken vertex normal */
    ni = (uint32_t)((size > at ? size - at : 0) / 2u);
    ni -= ni % 3u;
    if (ni > 96) ni = 96;
    nt = ni / 3u;
    for (i = 0; i < ni; ++i) {
        uint32_t v = data[at++] % (nv + 1u); /* nv itself is out of range */
        idx32[i] = v;
        idx16[i] = (uint16_t)v;
        if (v >= nv) out_of_range = 1;
    }
    for (i = 0; i < nt; ++i) {
        mat[i] = at < size ? data[at++] % 4u : 0u; /* 3 is out of range */
        if (mat[i] >= 3u) bad_mat = 1;
    }
    for (i = 0; i < nt; ++i) { /* bounds of the finite triangles, as the generator takes them */
        int fin = 1;
        for (k = 0; k < 3 && !out_of_range; ++k) fin &= gim__all_finite(&pos[idx32[i * 3 + k] * stride], 3);
        if (!fin || out_of_range) continue;
        for (k = 0; k < 9; ++k) {
            double c = pos[idx32[i * 3 + k / 3] * stride + k % 3];
            if (c < lo[k % 3]) lo[k % 3] = c;
            if (c > hi[k % 3]) hi[k % 3] = c;
        }
    }
    if (hi[0] >= lo[0]) diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));

    memset(&d, 0, sizeof d);
    d.env.allocator.alloc = fz_malloc;
    d.env.allocator.free = fz_free;
    d.env.allocator.user_data = &al;
    d.mesh.positions = pos;
    d.mesh.position_stride = stride * 4u;
    d.mesh.vertex_count = nv;
    d.mesh.normals = (flags & 2u) ? nrm : NULL;
    d.mesh.indices = (flags & 1u) ? (const void *)idx16 : (const void *)idx32;
    d.mesh.index_type = (flags & 1u) ? GIM_INDEX_U16 : GIM_INDEX_U32;
    d.mesh.index_count = ni;
    if (flags & 4u) {
        d.mesh.triangle_material = mat;
        d.mesh.material_reflectance = refl;
        d.mesh.material_count = 3;
    }
    d.no_snap = (flags & 8u) != 0;
    d.no_merge = (flags & 16u) != 0;
    /* d_eps from diag / 32 (the default) to diag / 4: bounded work */
    if (data[1] && diag > 0.0 && diag / 4.0 < 3e38) d.d_eps = (float)(diag / (4.0 + 28.0 * (data[1] / 255.0)));
    d.theta_eps = (float)((data[2] + 1) / 256.0 * 1.5707963);

    r = gim_cache_generate(&d, &s);
    if (ni == 0 || out_of_range || ((flags & 4u) && bad_mat)) FZ_CHECK(r == GIM_ERROR_INVALID_ARGUMENT);
    FZ_CHECK(r == GIM_OK || r == GIM_ERROR_INVALID_ARGUMENT || r == GIM_ERROR_OUT_OF_RANGE);
    if (r == GIM_OK) {
        double sum = 0.0;
        FZ_CHECK(s.report.triangles_used + s.report.triangles_degenerate + s.report.triangles_nonfinite +
                 s.report.triangles_duplicate == nt);
        FZ_CHECK(s.count <= s.report.caches_before_merge);
        FZ_CHECK((s.count == 0) == (s.report.triangles_used == 0));
        for (i = 0; i < s.count; ++i) {
            const gim_cache *c = &s.caches[i];
            float l = sqrtf(c->normal[0] * c->normal[0] + c->normal[1] * c->normal[1] + c->normal[2] * c->normal[2]);
            FZ_CHECK(gim__all_finite(c->position, 3) && gim__all_finite(c->normal, 3));
            FZ_CHECK(fabsf(l - 1.0f) < 1e-4f);
            FZ_CHECK(c->area >= 0.0f && gim__isfinitef(c->area));
            FZ_CHECK(c->reflectance >= 0.0f && c->reflectance <= 1.0f);
            for (k = 0; k < 3; ++k) /* inside the bounds, up to float rounding */
                FZ_CHECK(c->position[k] >= lo[k] - 1e-5 * (diag + fabs(lo[k])) && c->position[k] <= hi[k] + 1e-5 * (diag + fabs(hi[k])));
            sum += c->area;
        }
        if (s.report.surface_area > 1e-30 && s.report.surface_area < 1e30)
            FZ_CHECK(fabs(sum - s.report.surface_area) <= 1e-4 * s.report.surface_area);
        if (s.count) {   /* the caches bound to the mesh (gim_cache_bind) and followed at rest */
            gim_cache_binding *bd = (gim_cache_binding *)malloc(s.count * sizeof(gim_cache_binding));
            gim_cache *fl = (gim_cache *)malloc(s.count * sizeof(gim_cache));
            float tight[64 * 3];
            FZ_CHECK(bd && fl);
            for (i = 0; i < nv; ++i)
                for (k = 0; k < 3; ++k) tight[i * 3 + k] = pos[i * stride + k];
            r = gim_cache_bind(&d.mesh, s.caches, s.count, bd, d.env);
            FZ_CHECK(r == GIM_OK || r == GIM_ERROR_INVALID_ARGUMENT);   /* a non-finite vertex anywhere */
            if (r == GIM_OK) {
                for (i = 0; i < s.count; ++i) {
                    FZ_CHECK(bd[i].vertex[0] < nv && bd[i].vertex[1] < nv && bd[i].vertex[2] < nv);
                    FZ_CHECK(bd[i].u >= 0.0f && bd[i].v >= 0.0f && bd[i].u + bd[i].v <= 1.0f + 1e-6f);
                    FZ_CHECK(gim__isfinitef(bd[i].h) && gim__all_finite(bd[i].frame, 3) && bd[i].area2 >= 0.0f);
                }
                gim_follow_desc fd;
                memset(&fd, 0, sizeof fd);
                fd.rest = s.caches; fd.bind = bd; fd.count = s.count; fd.positions = tight; fd.vertex_count = nv;
                fd.env = d.env;
                r = gim_caches_follow_twin(&fd, fl);
                FZ_CHECK(r == GIM_OK || r == GIM_ERROR_INVALID_ARGUMENT);   /* float overflow of huge vertices */
                for (i = 0; r == GIM_OK && i < s.count; ++i) {
                    const gim_cache *c = &fl[i];
                    FZ_CHECK(gim__all_finite(c->position, 3) && gim__all_finite(c->normal, 3) && c->area >= 0.0f);
                    FZ_CHECK(c->reflectance == s.caches[i].reflectance);
                }
            }
            free(bd);
            free(fl);
        }
        /* determinism */
        FZ_CHECK(gim_cache_generate(&d, &s2) == GIM_OK);
        FZ_CHECK(s2.count == s.count);
        FZ_CHECK(s.count == 0 || memcmp(s.caches, s2.caches, sizeof(gim_cache) * s.count) == 0);
        gim_cache_set_free(&s2);
        gim_cache_set_free(&s);
    }
    FZ_CHECK(al.live == 0);
    return 0;
}
