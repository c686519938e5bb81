/* The image metrics of gimany-compare (tools/compare.c), for its tests and the benchmarks. */
#ifndef GIMANY_COMPARE_H
#define GIMANY_COMPARE_H
#include <stdint.h>

typedef struct compare_result {
    double rel_mae;      /* sum |a - b| / sum |b| */
    double rmse;         /* sqrt(mean (a - b)^2) over channels */
    double p99;          /* 99th percentile of the per-pixel mean |a - b| */
    double max;          /* largest per-pixel mean |a - b| */
    double mean_b;       /* mean |b| over channels */
    uint32_t covered;    /* pixels where a or b is non-zero */
} compare_result;

/* a, b: w x h linear RGB; per_pixel (w x h, or NULL) receives the per-pixel mean |a - b|
   (0 where not covered). 0 on success, 1 when out of memory. */
int compare_images(const float *a, const float *b, uint32_t w, uint32_t h, compare_result *out, float *per_pixel);

#endif
