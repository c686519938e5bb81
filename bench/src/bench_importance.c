/* Importance sampling benchmarks (medians): the eq. 10-11 map at 256^2 x 256 view samples,
   and selecting 8192 VALs from a 2048^2 map (eq. 12 tables and the binary searches timed
   separately). CPU only. */
#include "benchutil.h"
#ifndef GIMANY_NO_GL
#define GIMANY_NO_GL
#endif
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static uint64_t rng = 0x9e3779b97f4a7c15ull;
static double rand01(void) { /* splitmix64 */
    uint64_t z = (rng += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return (double)((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
}

#define REPS 15

static int bench_map(void) {
    const uint32_t w = 256, h = 256, nvs = 256;
    size_t n = (size_t)w * h, i;
    float *pos = (float *)malloc(n * 3 * sizeof(float)), *nrm = (float *)malloc(n * 3 * sizeof(float));
    float *flux = (float *)malloc(n * 3 * sizeof(float)), *out = (float *)malloc(n * sizeof(float));
    gim_view_sample *vs = (gim_view_sample *)malloc(nvs * sizeof(gim_view_sample));
    float pts[2 * 256];
    gim_importance_desc d;
    double t[REPS], sink = 0.0, med;
    int r;
    if (!pos || !nrm || !flux || !out || !vs) return 1;
    /* a street-like RSM: ground and facades of a 100-unit scene seen from above */
    for (i = 0; i < n; ++i) {
        float x = (float)(i % w) * (100.0f / w), z = (float)(i / w) * (100.0f / h);
        int facade = (i % w) % 32 < 4;
        pos[i * 3] = x; pos[i * 3 + 1] = facade ? (float)(rand01() * 20.0) : 0.0f; pos[i * 3 + 2] = z;
        nrm[i * 3] = facade ? 1.0f : 0.0f; nrm[i * 3 + 1] = facade ? 0.0f : 1.0f; nrm[i * 3 + 2] = 0.0f;
        flux[i * 3] = (float)rand01(); flux[i * 3 + 1] = (float)rand01(); flux[i * 3 + 2] = (float)rand01();
    }
    gim_halton_points(pts, nvs, 2, 1, NULL);
    for (i = 0; i < nvs; ++i) { /* Halton view samples on the ground and a facade */
        int up = i % 3 != 0;
        vs[i].position = up ? gim_v3(pts[2 * i] * 100.0f, 0.0f, pts[2 * i + 1] * 100.0f)
                            : gim_v3(64.0f, pts[2 * i] * 20.0f, pts[2 * i + 1] * 100.0f);
        vs[i].normal = up ? gim_v3(0, 1, 0) : gim_v3(-1, 0, 0);
    }
    memset(&d, 0, sizeof d);
    d.rsm_position = pos; d.rsm_normal = nrm; d.rsm_flux = flux;
    d.width = w; d.height = h; d.view_samples = vs; d.view_sample_count = nvs;
    d.scene_scale = 145.0f;
    for (r = 0; r < REPS / 3; ++r) {
        double t0 = now_s();
        if (gim_importance_map(&d, out) != GIM_OK) return 1;
        t[r] = now_s() - t0;
        sink += out[r];
    }
    med = median(t, REPS / 3);
    printf("importance map %ux%u x %u view samples: median %.2f ms, %.0f M texel-sample interactions/s (sink %g)\n",
           (unsigned)w, (unsigned)h, (unsigned)nvs, med * 1e3, (double)n * nvs / med * 1e-6, sink);
    free(pos); free(nrm); free(flux); free(out); free(vs);
    return 0;
}

static int bench_select(void) {
    const uint32_t w = 2048, h = 2048, count = 8192;
    size_t n = (size_t)w * h, i;
    float *map = (float *)malloc(n * sizeof(float));
    double *col = (double *)malloc(n * sizeof(double)), *row = (double *)malloc(w * sizeof(double));
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof(gim_selected_val));
    gim_env env;
    gim_select_desc sd;
    double tc[REPS], ts[REPS], sink = 0.0;
    int r;
    if (!map || !col || !row || !sel) return 1;
    memset(&env, 0, sizeof env);
    memset(&sd, 0, sizeof sd);
    sd.column = col; sd.row = row; sd.width = w; sd.height = h; sd.count = count; sd.env = env;
    for (i = 0; i < n; ++i) map[i] = (i % 20 == 7) ? 0.0f : (float)exp(-11.5 * rand01());
    for (r = 0; r < REPS; ++r) {
        double t0 = now_s(), t1;
        if (gim_importance_cumsum(map, w, h, col, row, env) != GIM_OK) return 1;
        t1 = now_s();
        sd.seed = (uint32_t)r;
        if (gim_importance_select(&sd, sel) != GIM_OK) return 1;
        ts[r] = now_s() - t1;
        tc[r] = t1 - t0;
        sink += sel[r].pdf;
    }
    printf("eq. 12 tables %ux%u (double): median %.2f ms (%.0f M texels/s)\n", (unsigned)w, (unsigned)h,
           median(tc, REPS) * 1e3, (double)n / median(tc, REPS) * 1e-6);
    printf("select %u VALs from %ux%u: median %.3f ms (%.1f M selections/s) (sink %g)\n", (unsigned)count,
           (unsigned)w, (unsigned)h, median(ts, REPS) * 1e3, count / median(ts, REPS) * 1e-6, sink);
    free(map); free(col); free(row); free(sel);
    return 0;
}

int main(void) {
    if (bench_map() || bench_select()) { fprintf(stderr, "bench_importance: failed\n"); return 1; }
    return 0;
}
