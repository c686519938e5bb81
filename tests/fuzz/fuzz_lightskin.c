/* libFuzzer: hostile and extreme scenes through the LightSkin twins (proxy lights,
   shading, the whole frame). Inputs are read as floats; unless the mode says raw, they are
   made valid (finite, unit normals, non-negative areas, weights and colours), so the fuzzer
   reaches the maths with extreme magnitudes instead of stopping at the checks. Whatever the
   bytes, a call returns a code; on GIM_OK every proxy light and every radiance is finite and
   >= 0 and every visibility in [0,1]. */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include "fuzzutil.h"
#include <stdlib.h>
#include <string.h>

static float take_f(reader *r, int raw) {
    uint32_t u = take_u32(r);
    float f;
    memcpy(&f, &u, sizeof f);
    if (!raw && !(f == f && f - f == 0.0f)) f = 0.0f;
    return f;
}
static void take_unit(reader *r, int raw, float *n) {
    int a;
    gim_vec3 v;
    for (a = 0; a < 3; ++a) n[a] = take_f(r, raw);
    if (raw) return;
    v = gim_v3_normalize(gim_v3(n[0], n[1], n[2]));
    if (v.x == 0.0f && v.y == 0.0f && v.z == 0.0f) v.z = 1.0f;
    n[0] = v.x; n[1] = v.y; n[2] = v.z;
}
static float take_pos(reader *r, int raw) { float f = take_f(r, raw); return raw ? f : (f < 0.0f ? -f : f); }

static void check_lights(const gim_proxy_light *p, uint32_t n) {
    uint32_t i;
    int a;
    for (i = 0; i < n; ++i) {
        for (a = 0; a < 3; ++a)
            if (!gim__isfinitef(p[i].position[a]) || !gim__isfinitef(p[i].flux[a]) || !(p[i].flux[a] >= 0.0f) ||
                !gim__isfinitef(p[i].sigma[a]) || !(p[i].sigma[a] >= 0.0f)) abort();
        if (!gim__isfinitef(p[i].radius) || !(p[i].radius >= 0.0f) || !(p[i].visibility >= 0.0f && p[i].visibility <= 1.0f)) abort();
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    reader r;
    gim_cache c[8];
    gim_val v[32];
    gim_receiver rc[8];
    gim_proxy_light pd[8], pg[8];
    uint32_t idx[8 * 4], mode, nc, nv, nr, stride, i, j;
    float dcm[8], L[8 * 3], scale;
    gim_lightskin_desc d;
    gim_proxy_desc pdsc;
    gim_env env;
    gim_result res;
    int raw, a;
    r.p = data; r.n = size;
    mode = take_u32(&r);
    raw = (mode & 1u) != 0;
    nc = 1u + take_u32(&r) % 8u;
    nv = take_u32(&r) % 33u;
    nr = 1u + take_u32(&r) % 8u;
    stride = 1u + take_u32(&r) % 4u;
    memset(c, 0, sizeof c); memset(v, 0, sizeof v); memset(rc, 0, sizeof rc);
    for (i = 0; i < nc; ++i) {
        for (a = 0; a < 3; ++a) c[i].position[a] = take_f(&r, raw);
        take_unit(&r, raw, c[i].normal);
        c[i].area = take_pos(&r, raw);
    }
    for (i = 0; i < nv; ++i) {
        for (a = 0; a < 3; ++a) v[i].position[a] = take_f(&r, raw);
        if (mode & 2u) for (a = 0; a < 3; ++a) v[i].normal[a] = 0.0f;
        else take_unit(&r, raw, v[i].normal);
        v[i].area = take_pos(&r, raw);
        v[i].weight = take_pos(&r, raw);
        for (a = 0; a < 3; ++a) v[i].flux[a] = take_pos(&r, raw);
    }
    for (i = 0; i < nr; ++i) {
        for (a = 0; a < 3; ++a) rc[i].position[a] = take_f(&r, raw);
        take_unit(&r, raw, rc[i].normal);
        take_unit(&r, raw, rc[i].view);
        for (a = 0; a < 3; ++a) { rc[i].albedo[a] = take_pos(&r, raw); rc[i].glossy[a] = take_pos(&r, raw); }
        rc[i].exponent = take_pos(&r, raw);
        if (!raw && rc[i].exponent > 1e6f) rc[i].exponent = 1e6f;
        dcm[i] = take_pos(&r, raw);
        for (j = 0; j < stride; ++j) {
            uint32_t k = take_u32(&r) % (nc + 1u);
            idx[i * stride + j] = (k == nc && !raw) ? UINT32_MAX : k;
        }
    }
    memset(&env, 0, sizeof env);
    memset(&d, 0, sizeof d);
    d.caches = c; d.cache_count = nc; d.vals = nv ? v : NULL; d.val_count = nv;
    d.eye = gim_v3(take_f(&r, raw), take_f(&r, raw), take_f(&r, raw));
    d.glossy = (mode & 4u) != 0;
    d.glossy_exponent = take_pos(&r, raw);
    if (!raw && d.glossy_exponent > 1e6f) d.glossy_exponent = 1e6f;
    d.receivers = rc; d.receiver_count = nr; d.neighbour_index = idx; d.neighbour_stride = stride; d.d_cmax = dcm;
    scale = take_pos(&r, raw);
    d.scene_scale = (mode & 16u) ? scale : 0.0f;
    d.env = env;
    res = gim_lightskin_frame_twin(&d, L);
    if ((unsigned)res >= (unsigned)GIM_RESULT_COUNT) abort();
    if (res == GIM_OK)
        for (i = 0; i < nr * 3; ++i) if (!gim__isfinitef(L[i]) || !(L[i] >= 0.0f)) abort();
    /* the passes on their own */
    memset(&pdsc, 0, sizeof pdsc);
    pdsc.caches = c; pdsc.cache_count = nc; pdsc.vals = nv ? v : NULL; pdsc.val_count = nv;
    pdsc.eye = d.eye; pdsc.glossy_exponent = d.glossy_exponent; pdsc.scene_scale = d.scene_scale; pdsc.env = env;
    res = gim_proxy_lights_twin(&pdsc, pd, pg);
    if (res == GIM_OK) { check_lights(pd, nc); check_lights(pg, nc); }
    return 0;
}
