/* libFuzzer: hostile and extreme input through the VPL shading twins (gim_paraboloid_visibility_twin,
   gim_vpl_shade_twin, gim_geometry_blur_twin). Values are read as floats; unless the mode says raw they
   are made valid (finite, unit normals, non-negative colours), so the fuzzer reaches the maths
   with extreme magnitudes; the distance maps stay raw (NaN, negative, Inf texels included).
   Whatever the bytes, a call returns a code; on GIM_OK every visibility is in [0, 1] and every
   radiance finite (and >= 0 from valid, non-negative input). */
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
    gim_vec3 v;
    int a;
    for (a = 0; a < 3; ++a) n[a] = take_f(r, raw);
    if (raw) return;
    v = gim_v3_normalize(gim_v3(n[0], n[1], n[2]));
    if (v.x == 0.0f && v.y == 0.0f && v.z == 0.0f) v.z = 1.0f;
    n[0] = v.x; n[1] = v.y; n[2] = v.z;
}
static float take_pos(reader *r, int raw) { float f = take_f(r, raw); return raw ? f : (f < 0.0f ? -f : f); }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    enum { MAXW = 4, MAXV = 16, MAXM = 3, MAXS = 8 };
    reader r;
    gim_vpl v[MAXV];
    gim_paraboloid maps[MAXM];
    gim_receiver rc[MAXW * MAXW];
    uint32_t cluster[MAXV], mode, w, h, nv, nm, ms, i;
    float dist[MAXM * MAXS * MAXS], out[MAXW * MAXW * 3], blurred[MAXW * MAXW * 3];
    gim_vpl_shade_desc d;
    gim_blur_desc b;
    gim_result res;
    int raw, a;
    r.p = data; r.n = size;
    mode = take_u32(&r);
    raw = (mode & 1u) != 0;
    w = 1u + take_u32(&r) % MAXW;
    h = 1u + take_u32(&r) % MAXW;
    nv = take_u32(&r) % (MAXV + 1u);
    nm = 1u + take_u32(&r) % MAXM;
    ms = 1u + take_u32(&r) % MAXS;
    for (i = 0; i < nm; ++i) {
        for (a = 0; a < 3; ++a) maps[i].origin[a] = take_f(&r, raw);
        take_unit(&r, raw, maps[i].normal);
        maps[i].size = take_pos(&r, raw);
        maps[i].near_distance = take_f(&r, 1);
        for (a = 0; a < 3; ++a) maps[i].flux[a] = take_f(&r, 1);
        maps[i].attribute_near = 0.0f;
    }
    for (i = 0; i < nm * ms * ms; ++i) dist[i] = take_f(&r, 1);
    for (i = 0; i < nv; ++i) {
        for (a = 0; a < 3; ++a) v[i].position[a] = take_f(&r, raw);
        v[i].lit = take_f(&r, raw);
        take_unit(&r, raw, v[i].normal);
        for (a = 0; a < 3; ++a) v[i].flux[a] = take_pos(&r, raw);
        v[i].area = take_pos(&r, raw);   /* the near field: its patch */
        v[i].kept = 0.0f;
        cluster[i] = take_u32(&r) % (nm + 2u);
        if (cluster[i] == nm + 1u) cluster[i] = UINT32_MAX;
        else if (!raw && cluster[i] == nm) cluster[i] = 0u;
    }
    for (i = 0; i < w * h; ++i) {
        memset(&rc[i], 0, sizeof rc[i]);
        for (a = 0; a < 3; ++a) rc[i].position[a] = take_f(&r, raw);
        if (take_u32(&r) % 5u == 0u) continue;   /* no surface */
        take_unit(&r, raw, rc[i].normal);
        take_unit(&r, raw, rc[i].view);
        for (a = 0; a < 3; ++a) { rc[i].albedo[a] = take_pos(&r, raw); rc[i].glossy[a] = take_pos(&r, raw); }
        rc[i].exponent = take_pos(&r, raw);
        if (!raw && rc[i].exponent > 1e6f) rc[i].exponent = 1e6f;
    }
    /* visibility of every receiver from every map */
    for (i = 0; i < w * h; ++i) {
        uint32_t m;
        for (m = 0; m < nm; ++m) {
            float vis = -1.0f;
            gim_vec3 nrm = gim_v3(rc[i].normal[0], rc[i].normal[1], rc[i].normal[2]);
            res = gim_paraboloid_visibility_twin(dist + (size_t)m * ms * ms, ms, &maps[m],
                                            gim_v3(rc[i].position[0], rc[i].position[1], rc[i].position[2]), NULL, &vis);
            if (res == GIM_OK && !(vis >= 0.0f && vis <= 1.0f)) abort();
            res = gim_paraboloid_visibility_twin(dist + (size_t)m * ms * ms, ms, &maps[m],
                                            gim_v3(rc[i].position[0], rc[i].position[1], rc[i].position[2]), &nrm, &vis);
            if (res == GIM_OK && !(vis >= 0.0f && vis <= 1.0f)) abort();
        }
    }
    memset(&d, 0, sizeof d);
    d.vpls = v; d.vpl_count = nv; d.cluster = (mode & 2u) ? cluster : NULL;
    d.maps = maps; d.map_count = nm; d.distance = dist; d.map_size = ms;
    d.receivers = rc; d.width = w; d.height = h;
    d.interleave = take_u32(&r) % 6u;
    d.clamp_distance = take_pos(&r, raw);
    d.scene_scale = take_pos(&r, raw);
    if (!raw && !(d.scene_scale > 0.0f)) d.scene_scale = 1.0f;
    res = gim_vpl_shade_twin(&d, out);
    if (res != GIM_OK) return 0;
    for (i = 0; i < w * h * 3; ++i)
        if (!(out[i] == out[i] && out[i] - out[i] == 0.0f) || (!raw && !(out[i] >= 0.0f))) abort();
    memset(&b, 0, sizeof b);
    b.radiance = out; b.receivers = rc; b.width = w; b.height = h;
    b.window = take_u32(&r) % 6u;
    b.position_tolerance = take_pos(&r, raw);
    b.normal_tolerance = raw ? take_f(&r, 1) : 0.0f;
    if (!raw && !(b.position_tolerance > 0.0f)) b.position_tolerance = 1.0f;
    res = gim_geometry_blur_twin(&b, blurred);
    if (res != GIM_OK) return 0;
    for (i = 0; i < w * h * 3; ++i)
        if (!(blurred[i] == blurred[i] && blurred[i] - blurred[i] == 0.0f) || !(blurred[i] >= 0.0f)) abort();
    return 0;
}
