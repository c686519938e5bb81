/* Benchmark: Halton and Hammersley throughput (points per second, median of runs). */
#define _POSIX_C_SOURCE 200809L /* clock_gettime under -std=c99 */
#define GIMANY_IMPLEMENTATION
#define GIMANY_NO_GL
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

enum { RUNS = 11, N = 1 << 20 };

int main(void) {
    static float pts[N * 3];
    double t[RUNS], sink = 0.0;
    int r, dims;
    for (dims = 2; dims <= 3; ++dims) {
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_s();
            if (gim_halton_points(pts, N, (uint32_t)dims, 1, NULL) != GIM_OK) return 1;
            t[r] = now_s() - t0;
            sink += pts[N - 1];
        }
        qsort(t, RUNS, sizeof t[0], cmp_double);
        printf("halton %dD: %d points, median %.2f ms, %.1f M points/s\n", dims, N, t[RUNS / 2] * 1e3,
               N / t[RUNS / 2] * 1e-6);
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_s();
            if (gim_hammersley_points(pts, N, (uint32_t)dims, NULL) != GIM_OK) return 1;
            t[r] = now_s() - t0;
            sink += pts[N - 1];
        }
        qsort(t, RUNS, sizeof t[0], cmp_double);
        printf("hammersley %dD: %d points, median %.2f ms, %.1f M points/s\n", dims, N, t[RUNS / 2] * 1e3,
               N / t[RUNS / 2] * 1e-6);
    }
    return sink < 0.0; /* keeps the work observable */
}
