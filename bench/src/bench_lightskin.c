/* LightSkin twins benchmarks (medians, CPU, one thread): the proxy-light pass for 5000 caches
   with FULL LightSkin (every texel of a 128^2 RSM is a VAL) against BRSM (2048 selected VALs),
   diffuse only and diffuse + glossy; then the shading pass (interpolation, 16 neighbours).
   The BRSM VALs come from the library's own importance
   map, cumulative sums, selection and gather, in the order the selection makes them. The FULL / BRSM ratio is the cost model's
   texels / selected VALs: 16384 / 2048 = 8. */
#define _POSIX_C_SOURCE 199309L
#ifndef GIMANY_NO_GL
#define GIMANY_NO_GL
#endif
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
static double median(double *t, int n) {
    qsort(t, (size_t)n, sizeof(double), cmp_double);
    return t[n / 2];
}
static uint64_t rng = 0x9e3779b97f4a7c15ull;
static double rand01(void) { /* splitmix64 */
    uint64_t z = (rng += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return (double)((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
}

enum { NC = 5000, RSM = 128, NT = RSM * RSM, NSEL = 2048, NR = 100000, NB = 16 };

/* CPU time of this thread: the machine may be shared, and descheduled time is not ours */
static double cpu_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* FULL and BRSM runs interleaved (one FULL, then BRSM_PER_FULL BRSM), so both see the same load;
   medians of thread CPU time (ms) into full_ms and brsm_ms, wall-clock medians beside them. */
#define FULL_REPS 3
#define BRSM_PER_FULL 4
static void time_pair(gim_proxy_desc *d, const gim_val *full, uint32_t nfull, const gim_val *sel, uint32_t nsel,
                      gim_proxy_light *pd, gim_proxy_light *pg, double *ms) {
    double tf[FULL_REPS], tb[FULL_REPS * BRSM_PER_FULL], wf[FULL_REPS], wb[FULL_REPS * BRSM_PER_FULL];
    int r, b;
    for (r = 0; r < FULL_REPS; ++r) {
        double c0, w0;
        d->vals = full; d->val_count = nfull;
        c0 = cpu_s(); w0 = now_s();
        if (gim_proxy_lights_twin(d, pd, pg) != GIM_OK) { fprintf(stderr, "gim_proxy_lights_twin failed\n"); exit(1); }
        tf[r] = cpu_s() - c0; wf[r] = now_s() - w0;
        d->vals = sel; d->val_count = nsel;
        for (b = 0; b < BRSM_PER_FULL; ++b) {
            c0 = cpu_s(); w0 = now_s();
            if (gim_proxy_lights_twin(d, pd, pg) != GIM_OK) { fprintf(stderr, "gim_proxy_lights_twin failed\n"); exit(1); }
            tb[r * BRSM_PER_FULL + b] = cpu_s() - c0; wb[r * BRSM_PER_FULL + b] = now_s() - w0;
        }
    }
    ms[0] = median(tf, FULL_REPS) * 1e3; ms[1] = median(tb, FULL_REPS * BRSM_PER_FULL) * 1e3;
    ms[2] = median(wf, FULL_REPS) * 1e3; ms[3] = median(wb, FULL_REPS * BRSM_PER_FULL) * 1e3;
}

int main(void) {
    gim_cache *c = (gim_cache *)malloc(NC * sizeof *c);
    gim_val *full = (gim_val *)malloc(NT * sizeof *full), *sel = (gim_val *)malloc(NSEL * sizeof *sel);
    gim_proxy_light *pd = (gim_proxy_light *)malloc(NC * sizeof *pd), *pg = (gim_proxy_light *)malloc(NC * sizeof *pg);
    gim_receiver *rc = (gim_receiver *)malloc(NR * sizeof *rc);
    uint32_t *idx = (uint32_t *)malloc((size_t)NR * NB * sizeof *idx);
    float *dcm = (float *)malloc(NR * sizeof *dcm), *L = (float *)malloc((size_t)NR * 3 * sizeof *L);
    gim_proxy_desc d;
    gim_shade_desc sd;
    double ms[4], ts, t[15], chk;
    int i, r, a;
    if (!c || !full || !sel || !pd || !pg || !rc || !idx || !dcm || !L) return 1;
    /* caches on a 100 x 100 ground facing up and on a 20 high wall x = 50 facing -x */
    for (i = 0; i < NC; ++i) {
        memset(c + i, 0, sizeof c[i]);
        if (i % 4) { c[i].position[0] = (float)(100 * rand01() - 50); c[i].position[1] = (float)(100 * rand01() - 50); c[i].normal[2] = 1; }
        else { c[i].position[0] = 50; c[i].position[1] = (float)(100 * rand01() - 50); c[i].position[2] = (float)(20 * rand01()); c[i].normal[0] = -1; }
        c[i].area = 2.0f;
    }
    /* a sun RSM of the ground (lower half of the texels) and the wall (upper half): every texel a VAL */
    for (i = 0; i < NT; ++i) {
        float u = ((i % RSM) + 0.5f) / RSM, w = ((i / RSM) + 0.5f) / (RSM / 2);
        gim_val *v = full + i;
        memset(v, 0, sizeof *v);
        if (w < 1.0f) { v->position[0] = 100 * w - 50; v->position[1] = 100 * u - 50; v->normal[2] = 1; v->area = 100.0f * 100.0f / (NT / 2); }
        else { v->position[0] = 50; v->position[1] = 100 * u - 50; v->position[2] = 20 * (w - 1); v->normal[0] = -1; v->area = 100.0f * 20.0f / (NT / 2); }
        v->weight = 1;
        for (a = 0; a < 3; ++a) v->flux[a] = v->area * (float)(0.2 + 0.6 * rand01());
    }
    {   /* BRSM: the library's own selection (eq. 10-12) from 256 view samples on the caches */
        float *pos = (float *)malloc(NT * 3 * sizeof(float)), *nrm = (float *)malloc(NT * 3 * sizeof(float));
        float *flux = (float *)malloc(NT * 3 * sizeof(float)), *area = (float *)malloc(NT * sizeof(float));
        float *map = (float *)malloc(NT * sizeof(float));
        double *col = (double *)malloc(NT * sizeof(double)), *row = (double *)malloc(RSM * sizeof(double));
        gim_selected_val *pick = (gim_selected_val *)malloc(NSEL * sizeof *pick);
        gim_view_sample vs[256];
        gim_importance_desc id;
        gim_select_desc seld;
        gim_rsm_data rsm;
        gim_env env;
        memset(&env, 0, sizeof env);
        if (!pos || !nrm || !flux || !area || !map || !col || !row || !pick) return 1;
        for (i = 0; i < NT; ++i) {
            memcpy(pos + i * 3, full[i].position, 12); memcpy(nrm + i * 3, full[i].normal, 12);
            memcpy(flux + i * 3, full[i].flux, 12); area[i] = full[i].area;
        }
        for (i = 0; i < 256; ++i) {
            const gim_cache *cc = c + (size_t)(rand01() * NC);
            vs[i].position = gim_v3(cc->position[0], cc->position[1], cc->position[2]);
            vs[i].normal = gim_v3(cc->normal[0], cc->normal[1], cc->normal[2]);
        }
        memset(&id, 0, sizeof id);
        id.rsm_position = pos; id.rsm_normal = nrm; id.rsm_flux = flux; id.width = RSM; id.height = RSM;
        id.view_samples = vs; id.view_sample_count = 256; id.scene_scale = 150;
        memset(&rsm, 0, sizeof rsm);
        rsm.position = pos; rsm.normal = nrm; rsm.flux = flux; rsm.area = area; rsm.width = RSM; rsm.height = RSM;
        memset(&seld, 0, sizeof seld);
        seld.column = col; seld.row = row; seld.width = RSM; seld.height = RSM; seld.count = NSEL; seld.seed = 1; seld.env = env;
        if (gim_importance_map(&id, map) != GIM_OK || gim_importance_cumsum(map, RSM, RSM, col, row, env) != GIM_OK ||
            gim_importance_select(&seld, pick) != GIM_OK ||
            gim_vals_gather_twin(&rsm, pick, NSEL, sel, env) != GIM_OK) return 1;
        free(pos); free(nrm); free(flux); free(area); free(map); free(col); free(row); free(pick);
    }
    memset(&d, 0, sizeof d);
    d.caches = c; d.cache_count = NC; d.eye = gim_v3(-60, -60, 40); d.glossy_exponent = 32; d.scene_scale = 150;
    printf("proxy lights, %d caches, median thread CPU ms (wall ms in brackets):\n", NC);
    time_pair(&d, full, NT, sel, NSEL, pd, NULL, ms);
    printf("  diffuse:          FULL %d^2 texels %7.1f (%7.1f)   BRSM %d VALs %6.1f (%6.1f)   ratio %.2f\n",
           RSM, ms[0], ms[2], NSEL, ms[1], ms[3], ms[0] / ms[1]);
    time_pair(&d, full, NT, sel, NSEL, pd, pg, ms);
    printf("  diffuse + glossy: FULL %d^2 texels %7.1f (%7.1f)   BRSM %d VALs %6.1f (%6.1f)   ratio %.2f\n",
           RSM, ms[0], ms[2], NSEL, ms[1], ms[3], ms[0] / ms[1]);
    printf("  (cost model: %d / %d = %.1f)\n", NT, NSEL, (double)NT / NSEL);
    chk = pd[NC / 2].flux[1];
    /* shading: receivers near caches, 16 neighbours each (random nearby caches) */
    for (i = 0; i < NR; ++i) {
        const gim_cache *cc = c + (i % NC);
        gim_receiver *q = rc + i;
        memset(q, 0, sizeof *q);
        for (a = 0; a < 3; ++a) { q->position[a] = cc->position[a]; q->normal[a] = cc->normal[a]; q->albedo[a] = 0.5f; q->glossy[a] = 0.2f; }
        q->view[2] = 1; q->exponent = 32;
        for (a = 0; a < NB; ++a) idx[(size_t)i * NB + a] = (uint32_t)((i + 7 * a) % NC);
        dcm[i] = 10.0f;
    }
    memset(&sd, 0, sizeof sd);
    sd.caches = c; sd.cache_count = NC; sd.diffuse = pd; sd.glossy = pg; sd.receivers = rc; sd.receiver_count = NR;
    sd.neighbour_index = idx; sd.neighbour_stride = NB; sd.d_cmax = dcm; sd.scene_scale = 150;
    for (r = 0; r < 7; ++r) {
        double t0 = cpu_s();
        if (gim_lightskin_shade_twin(&sd, L) != GIM_OK) return 1;
        t[r] = cpu_s() - t0;
    }
    ts = median(t, 7) * 1e3;
    printf("shading, %d receivers x %d neighbours, diffuse + glossy: %.1f CPU ms\n", NR, NB, ts);
    printf("(check %g %g)\n", chk, L[3]);
    free(c); free(full); free(sel); free(pd); free(pg); free(rc); free(idx); free(dcm); free(L);
    return 0;
}
