/* gimany-compare A.pfm B.pfm [--diff OUT.png] [--json]
   Error of an image A (a method's indirect.pfm) against B (the reference, or LightSkin FULL),
   both linear RGB PFMs of the same size (scene/scene.h reads them):
     rel_mae = sum |a - b| / sum |b|          over covered pixels and channels
     rmse    = sqrt(mean (a - b)^2)           over covered pixels and channels
     p99     = 99th percentile of |a - b| per pixel (mean of its channels), covered pixels
     max     = largest |a - b| per pixel
   A pixel is covered when either image is non-zero there (the demo and the reference write 0
   where no geometry is). --diff writes a false-colour PNG of |a - b| per pixel, black 0 to
   white at 4 x the mean |b| (blue, cyan, green, yellow, red, white). Prints one line of text,
   or one JSON object with --json. Exit 0; 1 with one line on stderr for bad input. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "scene.h"
#include "compare.h"

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

int compare_images(const float *a, const float *b, uint32_t w, uint32_t h, compare_result *out, float *per_pixel) {
    double sum_d = 0.0, sum_b = 0.0, sum_sq = 0.0;
    uint32_t i, covered = 0;
    float *err = (float *)malloc((size_t)w * h * sizeof(float) + 1);
    if (!err) return 1;
    memset(out, 0, sizeof *out);
    for (i = 0; i < w * h; ++i) {
        const float *p = a + (size_t)i * 3, *q = b + (size_t)i * 3;
        double e = 0.0;
        int c;
        if (per_pixel) per_pixel[i] = 0.0f;
        if (p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f && q[0] == 0.0f && q[1] == 0.0f && q[2] == 0.0f) continue;
        for (c = 0; c < 3; ++c) {
            double d = (double)p[c] - q[c];
            sum_d += fabs(d);
            sum_b += fabs((double)q[c]);
            sum_sq += d * d;
            e += fabs(d) / 3.0;
        }
        err[covered++] = (float)e;
        if (per_pixel) per_pixel[i] = (float)e;
        if (e > out->max) out->max = e;
    }
    out->covered = covered;
    out->mean_b = covered ? sum_b / (3.0 * covered) : 0.0;
    out->rel_mae = sum_b > 0.0 ? sum_d / sum_b : (sum_d > 0.0 ? INFINITY : 0.0);
    out->rmse = covered ? sqrt(sum_sq / (3.0 * covered)) : 0.0;
    if (covered) {
        qsort(err, covered, sizeof(float), cmp_float);
        out->p99 = err[(size_t)floor(0.99 * (covered - 1))];
    }
    free(err);
    return 0;
}

#ifndef COMPARE_NO_MAIN
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#endif
#include <stb_image_write.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

/* black -> blue -> cyan -> green -> yellow -> red -> white over t in [0, 1] */
static void false_colour(float t, unsigned char rgb[3]) {
    static const float k[7][3] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}, {1, 1, 1}};
    float x = (t < 0.0f ? 0.0f : t > 1.0f ? 1.0f : t) * 6.0f;
    int i = (int)x, c;
    float f;
    if (i > 5) i = 5;
    f = x - (float)i;
    for (c = 0; c < 3; ++c) rgb[c] = (unsigned char)(255.0f * (k[i][c] + f * (k[i + 1][c] - k[i][c])) + 0.5f);
}

int main(int argc, char **argv) {
    const char *pa = NULL, *pb = NULL, *diff = NULL;
    int json = 0, i;
    float *a = NULL, *b = NULL, *pp;
    uint32_t wa, ha, wb, hb;
    char err[256];
    compare_result r;
    for (i = 1; i < argc; ++i) {
        if (strcmp(argv[i], "--diff") == 0 && i + 1 < argc) diff = argv[++i];
        else if (strcmp(argv[i], "--json") == 0) json = 1;
        else if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
            printf("usage: gimany-compare A.pfm B.pfm [--diff OUT.png] [--json]\n"
                   "  error of A against B: rel_mae, rmse, p99, max over covered pixels\n");
            return 0;
        } else if (argv[i][0] == '-' && argv[i][1] == '-') {
            fprintf(stderr, "gimany-compare: unknown option %s\n", argv[i]);
            return 1;
        } else if (!pa) pa = argv[i];
        else if (!pb) pb = argv[i];
        else {
            fprintf(stderr, "gimany-compare: more than two images (%s)\n", argv[i]);
            return 1;
        }
    }
    if (!pa || !pb) {
        fprintf(stderr, "gimany-compare: need two images: gimany-compare A.pfm B.pfm [--diff OUT.png] [--json]\n");
        return 1;
    }
    if (scene_read_pfm(pa, &a, &wa, &ha, err, sizeof err)) { fprintf(stderr, "gimany-compare: %s\n", err); return 1; }
    if (scene_read_pfm(pb, &b, &wb, &hb, err, sizeof err)) { fprintf(stderr, "gimany-compare: %s\n", err); free(a); return 1; }
    if (wa != wb || ha != hb) {
        fprintf(stderr, "gimany-compare: sizes differ: %s is %ux%u, %s is %ux%u\n", pa, wa, ha, pb, wb, hb);
        free(a); free(b);
        return 1;
    }
    for (i = 0; i < (int)(wa * ha * 3); ++i)
        if (!isfinite(a[i]) || !isfinite(b[i])) {
            fprintf(stderr, "gimany-compare: %s has a NaN or Inf at pixel %d\n", isfinite(a[i]) ? pb : pa, i / 3);
            free(a); free(b);
            return 1;
        }
    pp = (float *)malloc((size_t)wa * ha * sizeof(float));
    if (!pp || compare_images(a, b, wa, ha, &r, pp)) { fprintf(stderr, "gimany-compare: out of memory\n"); return 1; }
    if (json)
        printf("{\"a\": \"%s\", \"b\": \"%s\", \"width\": %u, \"height\": %u, \"covered\": %u, \"rel_mae\": %.6g, "
               "\"rmse\": %.6g, \"p99\": %.6g, \"max\": %.6g, \"mean_b\": %.6g}\n",
               pa, pb, wa, ha, r.covered, r.rel_mae, r.rmse, r.p99, r.max, r.mean_b);
    else
        printf("rel_mae %.4f  rmse %.4g  p99 %.4g  max %.4g  (%u covered pixels, mean %.4g)\n", r.rel_mae, r.rmse, r.p99,
               r.max, r.covered, r.mean_b);
    if (diff) {
        unsigned char *png = (unsigned char *)malloc((size_t)wa * ha * 3);
        float top = (float)(4.0 * r.mean_b);
        uint32_t k;
        for (k = 0; k < wa * ha; ++k) false_colour(top > 0.0f ? pp[k] / top : 0.0f, png + (size_t)k * 3);
        if (!stbi_write_png(diff, (int)wa, (int)ha, 3, png, (int)wa * 3)) {
            fprintf(stderr, "gimany-compare: cannot write %s\n", diff);
            free(png); free(pp); free(a); free(b);
            return 1;
        }
        free(png);
    }
    free(pp); free(a); free(b);
    return 0;
}
#endif
