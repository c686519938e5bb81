/* Shared benchmark helpers: a monotonic clock and the median of a set of timings.
   Include first (it sets _POSIX_C_SOURCE for clock_gettime under -std=c99). */
#ifndef GIMANY_BENCHUTIL_H
#define GIMANY_BENCHUTIL_H
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 199309L
#endif
#include <stdlib.h>
#include <time.h>

static inline double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
static inline double now_ms(void) { return now_s() * 1e3; }
static inline int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
/* Sorts v in place and returns its median (the upper one for even n). */
static inline double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return v[n / 2];
}
#endif
