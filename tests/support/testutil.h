/* Shared test helpers: cmocka, an allocation-counting allocator and a log catcher. */
#ifndef GIMANY_TESTUTIL_H
#define GIMANY_TESTUTIL_H
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>
#include "gimany.h"

/* Counts live allocations and bytes; every test that allocates checks live == 0 at the end. */
typedef struct test_alloc_stats {
    long allocs, frees, live;
    size_t bytes, peak_bytes;
    long fail_after; /* >= 0: the allocation after this many succeeds returns NULL */
} test_alloc_stats;

static inline void *counting_alloc(size_t size, void *user) {
    test_alloc_stats *s = (test_alloc_stats *)user;
    size_t *p;
    if (s->fail_after >= 0 && s->allocs >= s->fail_after) return NULL;
    p = (size_t *)malloc(size + sizeof(size_t) * 2);
    if (!p) return NULL;
    p[0] = size;
    s->allocs++; s->live++; s->bytes += size;
    if (s->bytes > s->peak_bytes) s->peak_bytes = s->bytes;
    return p + 2;
}
static inline void counting_free(void *ptr, void *user) {
    test_alloc_stats *s = (test_alloc_stats *)user;
    size_t *p = (size_t *)ptr - 2;
    s->frees++; s->live--; s->bytes -= p[0];
    free(p);
}

/* Keeps the last message and counts them per level. */
typedef struct test_log {
    char last[512];
    int errors, warnings, infos;
} test_log;

static inline void test_log_func(gim_log_level level, const char *msg, void *user) {
    test_log *l = (test_log *)user;
    snprintf(l->last, sizeof l->last, "%s", msg);
    if (level == GIM_LOG_ERROR) l->errors++;
    else if (level == GIM_LOG_WARNING) l->warnings++;
    else l->infos++;
}

/* An env with the counting allocator and the log catcher. */
static inline gim_env test_env(test_alloc_stats *a, test_log *l) {
    gim_env e;
    memset(&e, 0, sizeof e);
    if (a) {
        memset(a, 0, sizeof *a);
        a->fail_after = -1;
        e.allocator.alloc = counting_alloc;
        e.allocator.free = counting_free;
        e.allocator.user_data = a;
    }
    if (l) {
        memset(l, 0, sizeof *l);
        e.logger.func = test_log_func;
        e.logger.user_data = l;
    }
    return e;
}

/* Deterministic test RNG (splitmix64). */
static uint64_t test_rng_state = 0x1234567u;
static inline double test_rand01(void) {
    uint64_t z = (test_rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    z ^= z >> 31;
    return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

/* Uniform in [lo, hi) from test_rand01. */
static inline float test_rnd(float lo, float hi) { return lo + (hi - lo) * (float)test_rand01(); }

/* A random unit vector (rejection from the cube: uniform on the sphere). */
static inline void test_random_unit(float *n) {
    float l;
    do {
        n[0] = test_rnd(-1.0f, 1.0f); n[1] = test_rnd(-1.0f, 1.0f); n[2] = test_rnd(-1.0f, 1.0f);
        l = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    } while (l < 0.05f || l > 1.0f);
    l = 1.0f / sqrtf(l);
    n[0] *= l; n[1] *= l; n[2] *= l;
}

/* Upper tail of the chi-square distribution with k degrees of freedom (Wilson-Hilferty). */
static inline double test_chi2_pvalue(double x, double k) {
    double z = (pow(x / k, 1.0 / 3.0) - (1.0 - 2.0 / (9.0 * k))) / sqrt(2.0 / (9.0 * k));
    return 0.5 * erfc(z / sqrt(2.0));
}

#endif
