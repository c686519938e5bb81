/* Benchmark of gim_kmeans: 8192 VPLs into 32 clusters, medians over 15 runs.
   VPLs as Dong sec. 6 makes them: Halton samples of what a spot light sees in a room with a
   tilted box (8 planes, one normal and albedo each; flux falls off from the spot's centre).
   The timed frame is the next one: the spot moved by 1% of the room, the same Halton points
   (as Dong and SSVP keep them) slid by 0.5% across each surface. "warm" starts from the
   previous frame's converged centres, "fixed" from the fixed seeds. */
#include "benchutil.h"
#define GIMANY_NO_GL
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { N = 8192, M = 32, RUNS = 15 };



/* One frame of VPLs: spot centre (sx, sy) in each plane's (u, v); the points slide by slide. */
static void make_vpls(float *pos, float *nrm, float *flux, float sx, float sy, float slide) {
    static const float org[8][3] = {{0, 0, 0}, {0, 10, 10}, {0, 0, 10}, {0, 10, 0}, {10, 0, 0}, {3, 0.01f, 4}, {3, 0.01f, 4}, {6, 3, 4}};
    static const float du[8][3] = {{10, 0, 0}, {10, 0, 0}, {10, 0, 0}, {0, 0, 10}, {0, 0, 10}, {3, 0, 1}, {3, 0, 1}, {-3, 0, -1}};
    static const float dv[8][3] = {{0, 0, 10}, {0, 0, -10}, {0, 10, 0}, {0, -10, 0}, {0, 10, 0}, {0, 3, 0}, {-1, 0, 3}, {0, -3, 0}};
    static const float alb[8][3] = {{.8f, .8f, .8f}, {.8f, .8f, .8f}, {.7f, .7f, .7f}, {.8f, .1f, .1f}, {.1f, .8f, .1f}, {.5f, .5f, .9f}, {.9f, .9f, .2f}, {.5f, .5f, .9f}};
    static float pts[N * 3];
    uint32_t i;
    int a;
    gim_halton_points(pts, N, 3, 1, NULL);
    for (i = 0; i < N; ++i) {
        int p = (int)(pts[i * 3] * 8.0f);
        float u = gim_rotate01(pts[i * 3 + 1], slide), v = gim_rotate01(pts[i * 3 + 2], slide), fall;
        gim_vec3 n;
        if (p > 7) p = 7;
        n = gim_v3_normalize(gim__v3_cross(gim_v3(du[p][0], du[p][1], du[p][2]), gim_v3(dv[p][0], dv[p][1], dv[p][2])));
        for (a = 0; a < 3; ++a) pos[i * 3 + a] = org[p][a] + u * du[p][a] + v * dv[p][a];
        /* the spot's footprint: falls off with distance from its centre in the plane's (u, v) */
        fall = 1.0f / (1.0f + 6.0f * ((u - sx) * (u - sx) + (v - sy) * (v - sy)));
        for (a = 0; a < 3; ++a) flux[i * 3 + a] = alb[p][a] * fall;
        nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z;
    }
}

static float pos0[N * 3], nrm0[N * 3], flux0[N * 3], pos1[N * 3], nrm1[N * 3], flux1[N * 3];
static float cen[M * 3], cn[M * 3], fl[M * 3], area[M], sigma[M * 3];
static uint32_t counts[M], assign[N];
static float cen0[M * 3], cn0[M * 3];

static void bench(const char *name, gim_kmeans_desc *d) {
    double t[RUNS];
    gim_kmeans_result r;
    int i;
    memset(&r, 0, sizeof r);
    r.centres = cen; r.normals = cn; r.flux = fl; r.counts = counts; r.assignment = assign;
    r.area = area; r.sigma = sigma;
    for (i = 0; i < RUNS; ++i) {
        double t0 = now_ms();
        if (gim_kmeans(d, &r) != GIM_OK) { fprintf(stderr, "gim_kmeans failed\n"); exit(1); }
        t[i] = now_ms() - t0;
    }
    qsort(t, RUNS, sizeof t[0], cmp_double);
    printf("kmeans %-34s N=%d M=%d: median %8.3f ms (min %.3f, max %.3f), %u iterations, %u repaired\n",
           name, N, M, t[RUNS / 2], t[0], t[RUNS - 1], r.iterations, r.empty_repaired);
}

int main(void) {
    gim_kmeans_desc d;
    gim_kmeans_result r;
    int metric;
    make_vpls(pos0, nrm0, flux0, 0.40f, 0.60f, 0.0f);
    make_vpls(pos1, nrm1, flux1, 0.41f, 0.61f, 0.005f);
    for (metric = GIM_KMEANS_METRIC_DONG; metric <= GIM_KMEANS_METRIC_SSVP; ++metric) {
        const char *mn = metric == GIM_KMEANS_METRIC_DONG ? "dong" : "ssvp";
        char name[64];
        memset(&d, 0, sizeof d);
        d.positions = pos0; d.normals = nrm0; d.flux = flux0;
        d.vpl_count = N; d.cluster_count = M; d.metric = (gim_kmeans_metric)metric;
        /* frame 0 to convergence: the previous frame's centres for the warm start */
        d.max_iterations = 200;
        memset(&r, 0, sizeof r);
        r.centres = cen0; r.normals = cn0;
        if (gim_kmeans(&d, &r) != GIM_OK) return 1;
        d.positions = pos1; d.normals = nrm1; d.flux = flux1;
        d.max_iterations = 0;
        snprintf(name, sizeof name, "%s fixed init (cap 16)", mn);
        bench(name, &d);
        d.max_iterations = 200;
        snprintf(name, sizeof name, "%s fixed init (to convergence)", mn);
        bench(name, &d);
        d.max_iterations = 0;
        d.init = GIM_KMEANS_INIT_WARM; d.init_centres = cen0; d.init_normals = cn0;
        snprintf(name, sizeof name, "%s warm start (cap 16)", mn);
        bench(name, &d);
        d.max_iterations = 1;
        snprintf(name, sizeof name, "%s one iteration (assign+update)", mn);
        bench(name, &d);
    }
    return 0;
}
