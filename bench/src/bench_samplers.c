/* Benchmark: Halton and Hammersley throughput (points per second, median of runs). */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#define GIMANY_NO_GL
#include "gimany.h"
#include <stdio.h>
#include <stdlib.h>
#include <time.h>


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
