/* Benchmark: neighbour caches (n = 16) for 1M vertices x 10k caches on the faces of a box
   (a room), the same with flipped vertex normals (a hard case: the nearest compatible caches
   are on the opposite wall), and blob write/read of the 10k caches. Prints medians. */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static uint32_t rng = 12345u;
static float rnd(void) { rng = rng * 1664525u + 1013904223u; return (float)(rng >> 8) * (1.0f / 16777216.0f); }

/* count points on the 6 faces of [0,10]^3 as a g x g grid per face (jittered), face normals */
static uint32_t box_points(float *pos, float *nrm, uint32_t g, float jitter) {
    uint32_t face, i, j, k = 0;
    for (face = 0; face < 6; ++face)
        for (j = 0; j < g; ++j)
            for (i = 0; i < g; ++i, ++k) {
                uint32_t a = face >> 1;
                float q[3], n[3] = {0, 0, 0};
                q[(a + 1) % 3] = 10.0f * ((float)i + 0.5f + jitter * (rnd() - 0.5f)) / (float)g;
                q[(a + 2) % 3] = 10.0f * ((float)j + 0.5f + jitter * (rnd() - 0.5f)) / (float)g;
                q[a] = (face & 1) ? 10.0f : 0.0f;
                n[a] = (face & 1) ? 1.0f : -1.0f;
                memcpy(pos + (size_t)k * 3, q, sizeof q);
                memcpy(nrm + (size_t)k * 3, n, sizeof n);
            }
    return k;
}

int main(void) {
    enum { CG = 41, VG = 409, RUNS = 5, BLOB_RUNS = 101 };
    uint32_t C = 6 * CG * CG, V = 6 * VG * VG, i, n = 16;
    float *cpos = (float *)malloc(sizeof(float) * 3 * C), *cnrm = (float *)malloc(sizeof(float) * 3 * C);
    float *vpos = (float *)malloc(sizeof(float) * 3 * V), *vnrm = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache *caches = (gim_cache *)malloc(sizeof(gim_cache) * C);
    uint32_t *index = (uint32_t *)malloc(sizeof(uint32_t) * V * n), *count = (uint32_t *)malloc(sizeof(uint32_t) * V);
    float *dmax = (float *)malloc(sizeof(float) * V);
    double t[BLOB_RUNS], sum = 0.0;
    gim_cache_set set, back;
    gim_neighbour_desc d;
    gim_neighbour_result r;
    unsigned char *blob;
    size_t size;
    gim_env env;
    int k;
    box_points(cpos, cnrm, CG, 0.8f);
    box_points(vpos, vnrm, VG, 0.0f);
    for (i = 0; i < C; ++i) {
        memcpy(caches[i].position, cpos + i * 3, 12);
        memcpy(caches[i].normal, cnrm + i * 3, 12);
        caches[i].area = 600.0f / (float)C;
        caches[i].reflectance = 0.5f;
    }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.d_eps = 10.0f * 1.7320508f / 32.0f; set.theta_eps = 0.5235988f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = vpos; d.mesh.normals = vnrm; d.mesh.vertex_count = V;
    d.caches = &set; d.n = n;
    d.env.logger.func = gim_log_stderr;
    r.index = index; r.count = count; r.d_cmax = dmax;
    for (k = 0; k < RUNS; ++k) {
        double t0 = now_s();
        if (gim_cache_neighbours(&d, &r) != GIM_OK) return 1;
        t[k] = now_s() - t0;
    }
    for (i = 0; i < V; ++i) sum += dmax[i];
    printf("neighbours: %u vertices x %u caches, n = %u: median %.1f ms over %d runs (%.0f ns/vertex; mean d_c,max %.4f)\n",
           V, C, n, 1e3 * median(t, RUNS), RUNS, 1e9 * median(t, RUNS) / V, sum / V);
    /* the same mesh with flipped normals: the only compatible caches are across the room */
    for (i = 0; i < 3 * V; ++i) vnrm[i] = -vnrm[i];
    for (k = 0; k < RUNS; ++k) {
        double t0 = now_s();
        if (gim_cache_neighbours(&d, &r) != GIM_OK) return 1;
        t[k] = now_s() - t0;
    }
    sum = 0.0;
    for (i = 0; i < V; ++i) sum += dmax[i];
    printf("neighbours, flipped normals (compatible caches only across the room): median %.1f ms over %d runs (mean d_c,max %.4f)\n",
           1e3 * median(t, RUNS), RUNS, sum / V);
    size = gim_cache_blob_size(&set);
    blob = (unsigned char *)malloc(size);
    for (k = 0; k < BLOB_RUNS; ++k) {
        double t0 = now_s();
        if (gim_cache_blob_write(&set, blob, size) != GIM_OK) return 1;
        t[k] = now_s() - t0;
    }
    printf("blob write: %u caches, %zu bytes: median %.3f ms over %d runs\n", C, size, 1e3 * median(t, BLOB_RUNS), BLOB_RUNS);
    memset(&env, 0, sizeof env);
    for (k = 0; k < BLOB_RUNS; ++k) {
        double t0 = now_s();
        if (gim_cache_blob_read(blob, size, &back, env) != GIM_OK) return 1;
        t[k] = now_s() - t0;
        free(back.caches);
    }
    printf("blob read: %u caches, %zu bytes: median %.3f ms over %d runs\n", C, size, 1e3 * median(t, BLOB_RUNS), BLOB_RUNS);
    free(cpos); free(cnrm); free(vpos); free(vnrm); free(caches); free(index); free(count); free(dmax); free(blob);
    return 0;
}
