/* VPL shading twins (clustered visibility, Dong et al. sec. 6), medians of thread CPU time,
   one thread: gim_vpl_shade_twin on 128^2 receivers in a unit box (floor and left wall) from 1024
   VPLs on the box's other walls in 32 clusters with 128^2 paraboloid maps (synthetic plates),
   every VPL per pixel (k = 1) against interleaved sampling (k = 4: 64 per pixel), with and
   without visibility; gim_geometry_blur_twin with a 4 x 4 window. And what clamping costs in
   energy (Krivanek): the share of the unclamped light that d_c = 1 %, 5 %, 10 % of the scene
   diagonal removes from the same receivers. */
#include "benchutil.h"
#ifndef GIMANY_NO_GL
#define GIMANY_NO_GL
#endif
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>
#include "vplshade_util.h"

enum { W = 128, H = 128, N = 1024, M = 32, S = 128, REPS = 5 };

static double cpu_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static uint64_t rng = 0x2545f4914f6cdd1dull;
static float rnd(float lo, float hi) {
    uint64_t z = (rng += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return lo + (hi - lo) * (float)((double)((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0));
}

static double time_shade(gim_vpl_shade_desc *d, float *out) {
    double t[REPS];
    int r;
    for (r = 0; r < REPS; ++r) {
        double c0 = cpu_s();
        if (gim_vpl_shade_twin(d, out) != GIM_OK) { fprintf(stderr, "gim_vpl_shade_twin failed\n"); exit(1); }
        t[r] = (cpu_s() - c0) * 1e3;
    }
    return median(t, REPS);
}

static double total(const float *v, size_t n) {
    double s = 0.0;
    size_t i;
    for (i = 0; i < n; ++i) s += v[i];
    return s;
}

int main(void) {
    static gim_vpl vpl[N];
    static uint32_t cluster[N];
    static gim_paraboloid maps[M];
    static gim_receiver rec[W * H];
    float *dist = (float *)malloc((size_t)M * S * S * sizeof(float));
    float *out = (float *)malloc((size_t)W * H * 3 * sizeof(float)), *ref = (float *)malloc((size_t)W * H * 3 * sizeof(float));
    gim_vpl_shade_desc d;
    gim_blur_desc b;
    const float diag = 1.7320508f;
    uint32_t i, m;
    double ms_k1, ms_k4, ms_k1_vis, ms_k4_vis, tb[REPS];
    int r;
    /* receivers: the left half of the image on the floor (y = 0), the right half on the left wall (x = 0) */
    for (i = 0; i < W * H; ++i) {
        float u = ((float)(i % W) + 0.5f) / W, v = ((float)(i / W) + 0.5f) / H;
        gim_receiver *rc = rec + i;
        memset(rc, 0, sizeof *rc);
        if (u < 0.5f) { rc->position[0] = 2.0f * u; rc->position[2] = v; rc->normal[1] = 1.0f; }
        else { rc->position[1] = 2.0f * (u - 0.5f); rc->position[2] = v; rc->normal[0] = 1.0f; }
        rc->view[0] = 0.6f; rc->view[1] = 0.8f;
        rc->albedo[0] = rc->albedo[1] = rc->albedo[2] = 0.7f;
    }
    /* clusters on the right wall (x = 1) and the back wall (z = 0); plates in front of them */
    for (m = 0; m < M; ++m) {
        int right = m % 2 == 0;
        memset(&maps[m], 0, sizeof maps[m]);
        maps[m].origin[0] = right ? 1.0f - 1e-4f : rnd(0.1f, 0.9f);
        maps[m].origin[1] = rnd(0.1f, 0.9f);
        maps[m].origin[2] = right ? rnd(0.1f, 0.9f) : 1e-4f;
        maps[m].normal[0] = right ? -1.0f : 0.0f;
        maps[m].normal[2] = right ? 0.0f : 1.0f;
        maps[m].size = 0.15f;
        vs_plate_map(dist + (size_t)m * S * S, S, rnd(0.2f, 0.5f), rnd(-0.2f, 0.2f), rnd(-0.2f, 0.2f), 0.1f);
    }
    for (i = 0; i < N; ++i) {
        gim_vec3 p;
        m = i % M;
        p = vs_local(&maps[m], rnd(-0.07f, 0.07f), rnd(-0.07f, 0.07f), 0.0f);
        memset(&vpl[i], 0, sizeof vpl[i]);
        vpl[i].position[0] = p.x; vpl[i].position[1] = p.y; vpl[i].position[2] = p.z;
        vpl[i].lit = 1.0f;
        memcpy(vpl[i].normal, maps[m].normal, sizeof vpl[i].normal);
        vpl[i].flux[0] = vpl[i].flux[1] = vpl[i].flux[2] = 1.0f / N;
        cluster[i] = m;
    }
    memset(&d, 0, sizeof d);
    d.vpls = vpl; d.vpl_count = N; d.receivers = rec; d.width = W; d.height = H; d.scene_scale = diag;
    d.maps = maps; d.map_count = M; d.distance = dist; d.map_size = S;
    ms_k1 = time_shade(&d, out);
    d.interleave = 4;
    ms_k4 = time_shade(&d, out);
    d.cluster = cluster;
    ms_k4_vis = time_shade(&d, out);
    d.interleave = 1;
    ms_k1_vis = time_shade(&d, out);
    printf("gim_vpl_shade_twin %dx%d, %d VPLs: k=1 %.1f ms, k=4 %.1f ms (%.1fx); with visibility (%d maps %d^2): k=1 %.1f ms, "
           "k=4 %.1f ms (%.1fx) (medians of %d, thread CPU)\n", W, H, N, ms_k1, ms_k4, ms_k1 / ms_k4, M, S, ms_k1_vis, ms_k4_vis,
           ms_k1_vis / ms_k4_vis, REPS);
    memset(&b, 0, sizeof b);
    b.radiance = out; b.receivers = rec; b.width = W; b.height = H; b.window = 4; b.position_tolerance = 0.1f * diag;
    for (r = 0; r < REPS; ++r) {
        double c0 = cpu_s();
        if (gim_geometry_blur_twin(&b, ref) != GIM_OK) { fprintf(stderr, "gim_geometry_blur_twin failed\n"); return 1; }
        tb[r] = (cpu_s() - c0) * 1e3;
    }
    printf("gim_geometry_blur_twin %dx%d, window 4: %.2f ms (median of %d)\n", W, H, median(tb, REPS), REPS);
    /* clamping's energy: no visibility, every VPL */
    d.cluster = NULL;
    d.clamp_distance = 0.0f;
    if (gim_vpl_shade_twin(&d, ref) != GIM_OK) return 1;
    {
        static const float frac[3] = {0.01f, 0.05f, 0.1f};
        double all = total(ref, (size_t)W * H * 3);
        for (i = 0; i < 3; ++i) {
            d.clamp_distance = frac[i] * diag;
            if (gim_vpl_shade_twin(&d, out) != GIM_OK) return 1;
            printf("clamping at d_c = %.0f %% of the diagonal removes %.2f %% of the indirect light\n", 100.0 * frac[i],
                   100.0 * (1.0 - total(out, (size_t)W * H * 3) / all));
        }
    }
    free(dist); free(out); free(ref);
    return 0;
}
