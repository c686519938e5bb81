/* libFuzzer: hostile triangle soups, lights, cameras and G-buffers through the scene twins
   (gim_light_camera, gim_rsm_texel_twin, gim_gbuffer_texel_twin, gim_view_sample_pixels,
   gim_view_samples_twin). Whatever the bytes, a call returns a code; on GIM_OK every output is
   finite, fluxes and areas are >= 0, normals are unit or zero, pixels are inside. */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include "fuzzutil.h"
#include <stdlib.h>
#include <string.h>

static int finite_n(const float *v, int n) {
    int i;
    for (i = 0; i < n; ++i) if (!(v[i] == v[i] && v[i] - v[i] == 0.0f)) return 0;
    return 1;
}
static void check_unit_or_zero(const float *n) {
    float l = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (!(l == 0.0f || (l > 0.99f && l < 1.01f))) abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    reader r;
    float pos[8 * 9], nrm[8 * 9], alb[8 * 3], bmin[3], bmax[3], depth[16], gnrm[64];
    gim_twin_scene s;
    gim_light l;
    gim_mat4 view, proj;
    gim_camera cam;
    gim_view_sample vs[8];
    uint32_t pixels[16], ntri, x, y, w, h;
    gim_result res;
    r.p = data; r.n = size;
    ntri = take_u32(&r) % 9u;
    take_bytes(&r, pos, sizeof pos);
    take_bytes(&r, nrm, sizeof nrm);
    take_bytes(&r, alb, sizeof alb);
    take_bytes(&r, &l, sizeof l);
    l.rsm_size %= 64u;
    take_bytes(&r, bmin, sizeof bmin);
    take_bytes(&r, bmax, sizeof bmax);
    take_bytes(&r, &view, sizeof view);
    take_bytes(&r, &proj, sizeof proj);
    x = take_u32(&r) % 70u;
    y = take_u32(&r) % 70u;
    memset(&s, 0, sizeof s);
    s.positions = pos;
    s.normals = (ntri & 1u) ? nrm : NULL;
    s.albedo = alb;
    s.triangle_count = ntri;
    res = gim_light_camera(&l, bmin, bmax, &view, &proj) == GIM_OK ? GIM_OK : GIM_ERROR_INVALID_ARGUMENT;
    if (res == GIM_OK && (!finite_n(view.m, 16) || !finite_n(proj.m, 16))) abort();
    {
        gim_rsm_texel t;
        gim_rsm_view rv;
        rv.light = &l; rv.bmin = bmin; rv.bmax = bmax;
        if (gim_rsm_texel_twin(&s, &rv, x, y, &t) == GIM_OK) {
            if (!finite_n(t.flux, 3) || !(t.area >= 0.0f) || !finite_n(&t.area, 1) || !(t.depth >= -1e-3f)) abort();
            if (t.flux[0] < 0.0f || t.flux[1] < 0.0f || t.flux[2] < 0.0f) abort();
            if (t.triangle != UINT32_MAX && (t.triangle >= ntri || !finite_n(t.position, 3))) abort();
            check_unit_or_zero(t.normal);
        }
    }
    w = 1u + take_u32(&r) % 8u;
    h = 1u + take_u32(&r) % 8u;
    cam.view = view; cam.proj = proj; cam.width = w; cam.height = h;
    {
        gim_gbuffer_texel t;
        if (gim_gbuffer_texel_twin(&s, &cam, x % w, y % h, &t) == GIM_OK) {
            if (t.triangle != UINT32_MAX && (t.triangle >= ntri || !finite_n(t.position, 3))) abort();
            check_unit_or_zero(t.normal);
        }
    }
    take_bytes(&r, depth, sizeof depth);
    take_bytes(&r, gnrm, sizeof gnrm);
    {
        float off[2];
        take_bytes(&r, off, sizeof off);
        if (gim_view_sample_pixels(8, w, h, (x & 1u) ? off : NULL, pixels) == GIM_OK) {
            uint32_t i;
            for (i = 0; i < 8; ++i)
                if (pixels[2 * i] >= w || pixels[2 * i + 1] >= h) abort();
            if (w * h <= 16 && gim_view_samples_twin(depth, gnrm, &cam, pixels, 8, vs) == GIM_OK) {
                for (i = 0; i < 8; ++i) {
                    float n[3];
                    n[0] = vs[i].normal.x; n[1] = vs[i].normal.y; n[2] = vs[i].normal.z;
                    check_unit_or_zero(n);
                }
            }
        }
    }
    return 0;
}
