/* reference.h - the ground truth: indirect light of a scene by unbiased Monte Carlo path tracing
   on Intel Embree 3, exact visibility, deterministic for a fixed seed.

   For each pixel the primary hit x0 is found through the pixel centre (scene_camera_ray, as
   the demo does). Then spp paths x0 -> x1 [-> x2] estimate the INDIRECT radiance leaving x0
   towards the camera:
     bounce 1:  lights -> x1 -> x0 -> camera   (next-event estimation at x1, shadow rays)
     bounce 2:  lights -> x2 -> x1 -> x0 -> camera  (with bounces = 2, added to bounce 1)
   Light that reaches x0 directly from a light is NOT included. Every vertex reflects with the
   full BRDF of scene.h (rho_d / pi + normalised Phong, Bischoff 2017 eq. 3-4); directions are
   sampled from a one-sample mixture of the cosine lobe and the Phong lobe (probabilities by
   mean albedo) and weighted by f cos / pdf of the mixture. Surfaces are two-sided. Rays that
   leave the scene carry nothing (no sky). Each pixel has its own random stream (seed, pixel
   index), so the image does not depend on the thread count. */
#ifndef GIMANY_REFERENCE_H
#define GIMANY_REFERENCE_H

#include <stddef.h>
#include <stdint.h>
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ref_settings {
    uint32_t spp;       /* paths per pixel, >= 1 (>= 2 for a standard error) */
    uint32_t seed;
    int bounces;        /* 1 or 2 */
    unsigned threads;   /* 0: every hardware thread */
} ref_settings;

typedef struct ref_image {
    uint32_t width, height;
    float *radiance;    /* width * height * 3, top row first; 0 where the pixel sees no geometry */
    float *std_error;   /* width * height * 3: standard error of each pixel's mean */
    float *position;    /* width * height * 3: the primary hit x0 (0 where none) */
    float *normal;      /* width * height * 3: its shading normal, facing the camera (0 where none) */
    unsigned char *covered; /* width * height: 1 where the pixel sees geometry */
    uint32_t covered_pixels;
    double mean_radiance;            /* mean luminance over covered pixels */
    double mean_std_error;           /* mean of the per-pixel standard errors of luminance */
    double relative_std_error;       /* mean_std_error / mean_radiance (0 when the image is black) */
    double relative_std_error_image; /* standard error of the image mean, relative */
    double seconds;                  /* tracing time (BVH build excluded) */
    double build_seconds;
    uint64_t rays;                   /* all rays traced, shadow rays included */
    uint64_t nonfinite_samples;      /* paths that gave NaN/Inf, counted as 0 (expected: none) */
} ref_image;

/* Renders s (its camera sets the size). Returns 0, or non-zero with one line in err. */
int ref_render(const scene *s, const ref_settings *settings, ref_image *out, char *err, size_t err_cap);
void ref_image_free(ref_image *img);
/* Luminance weights used for the statistics (Rec. 709). */
double ref_luminance(const float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
