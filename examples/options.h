/* options.h - the options of build/gimany-demo and build/gimany-viewer beyond the scene layer's
   (examples/scene.h: --scene, --sun-dir, --sun-irradiance, --spot, --camera, --size, --out,
   --bounces): the method and its parameters. demo_parse takes them out of argv and leaves the
   rest for scene_parse_args, so scene.cpp's parser stays the one the reference uses.
   Everything here is static. */
#ifndef GIMANY_EXAMPLES_OPTIONS_H
#define GIMANY_EXAMPLES_OPTIONS_H

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdint.h>

#if defined(__GNUC__) || defined(__clang__)
#define DEMO_OPTIONS_FN static __attribute__((unused))
#else
#define DEMO_OPTIONS_FN static
#endif

typedef struct demo_options {
    const char *method;      /* gather|full|brsm|clustered|ssvp|none */
    uint32_t rsm;            /* RSM side per light */
    uint32_t vals;           /* VALs per light (BRSM) */
    uint32_t view_samples;
    uint32_t vpls, clusters; /* clustered, ssvp: VPLs per light and clusters; 0: the method's defaults */
    int occlusion;
    int no_visibility;       /* clustered, ssvp: 1 skips the paraboloid visibility */
    int ism;                 /* brsm, full: 1 turns on gim_frame.visibility = ISM */
    uint32_t ism_size;       /* its map side (0: gimany's default) */
    int glossy;
    uint32_t frames;         /* demo: frames rendered, timings are medians; viewer: 0 = until closed */
    float exposure;          /* 0: automatic */
    const char *screenshot;  /* viewer: --screenshot FILE */
} demo_options;

#define DEMO_PARSE_VIEWER 1u /* accept --screenshot; --frames defaults to 0 (run until closed) */

static const char demo_usage_text[] =
    "  --method M            brsm (default: LightSkin + bidirectional RSM importance sampling), full (LightSkin,\n"
    "                        every RSM texel a VAL), gather (RSM gather, Dachsbacher 2005: the baseline),\n"
    "                        clustered (Dong et al.: k-means VALs with paraboloid soft shadows), ssvp (two\n"
    "                        bounces from paraboloid maps, Aranha et al.), none (direct light only)\n"
    "  --rsm N               RSM side per light in texels (default 256)\n"
    "  --vals N              VALs per light for brsm (default 2048)\n"
    "  --view-samples N      view samples for the importance map (default 128)\n"
    "  --vpls N, --clusters N  clustered, ssvp: VPLs per light and clusters (default 1024, 30 clustered;\n"
    "                        256, 8 ssvp); --bounces 2 (a scene option, default 1 as for the reference) adds\n"
    "                        the second bounce to either\n"
    "  --no-occlusion        no occlusion of the proxy lights (default: on)\n"
    "  --no-visibility       clustered, ssvp: VPLs shade unshadowed, no paraboloid depth maps\n"
    "  --ism                 brsm, full: imperfect shadow maps per cache, no light through walls (default: off);\n"
    "                        --ism-size N their side, a power of two in 4..64 (default 32)\n"
    "  --no-glossy           every material's glossy colour set to 0\n"
    "  --exposure A          tone-mapping exposure (default: automatic, key 0.18 / log-average luminance)\n";

DEMO_OPTIONS_FN void demo_defaults(demo_options *d, unsigned flags) {
    memset(d, 0, sizeof *d);
    d->method = "brsm";
    d->rsm = 256;
    d->vals = 2048;
    d->view_samples = 128;
    d->occlusion = 1;
    d->glossy = 1;
    d->frames = (flags & DEMO_PARSE_VIEWER) ? 0 : 3;
}

DEMO_OPTIONS_FN int demo_parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out) {
    char *end;
    unsigned long long v;
    if (!s || *s < '0' || *s > '9') return 0;
    errno = 0;
    v = strtoull(s, &end, 10);
    if (*end || errno == ERANGE || v < lo || v > hi) return 0;
    *out = (uint32_t)v;
    return 1;
}

/* Takes the demo's options out of argv (--name VALUE or --name=VALUE); what is left, argv[0]
   first, goes to rest (argc + 1 entries) for scene_parse_args. 0 on success; -1 with one line in
   err; 1 for --help. */
DEMO_OPTIONS_FN int demo_parse(int argc, char **argv, unsigned flags, demo_options *d, char **rest, int *rest_count, char *err,
                      size_t cap) {
    static const struct { const char *name; uint32_t lo, hi; } nums[] = {
        {"--rsm", 16, 8192}, {"--vals", 1, 1u << 20}, {"--view-samples", 1, 65536},
        {"--vpls", 1, 32768}, {"--clusters", 1, 256}, {"--frames", 1, 100000}, {"--ism-size", 4, 64}};
    int i, n = 0;
    rest[n++] = argv[0];
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i], *eq = strchr(a, '='), *v = NULL;
        size_t len = eq ? (size_t)(eq - a) : strlen(a), k;
        int flag = -1, num = -1, is_method, is_exposure, is_shot;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) return 1;
        if (len == 14 && !strncmp(a, "--no-occlusion", 14)) flag = 0;
        else if (len == 11 && !strncmp(a, "--no-glossy", 11)) flag = 1;
        else if (len == 15 && !strncmp(a, "--no-visibility", 15)) flag = 2;
        else if (len == 5 && !strncmp(a, "--ism", 5)) flag = 3;
        if (flag >= 0) {
            if (eq) { snprintf(err, cap, "%.*s takes no value", (int)len, a); return -1; }
            if (flag == 0) d->occlusion = 0; else if (flag == 1) d->glossy = 0; else if (flag == 2) d->no_visibility = 1;
            else d->ism = 1;
            continue;
        }
        for (k = 0; k < sizeof nums / sizeof nums[0]; ++k)
            if (strlen(nums[k].name) == len && !strncmp(a, nums[k].name, len)) num = (int)k;
        is_method = len == 8 && !strncmp(a, "--method", 8);
        is_exposure = len == 10 && !strncmp(a, "--exposure", 10);
        is_shot = (flags & DEMO_PARSE_VIEWER) && len == 12 && !strncmp(a, "--screenshot", 12);
        if (num < 0 && !is_method && !is_exposure && !is_shot) {
            /* the scene layer's: every one of them takes one value */
            rest[n++] = argv[i];
            if (!strncmp(a, "--", 2) && !eq && i + 1 < argc) rest[n++] = argv[++i];
            continue;
        }
        if (eq) v = eq + 1;
        else if (i + 1 < argc) v = argv[++i];
        else { snprintf(err, cap, "option %.*s needs a value (see --help)", (int)len, a); return -1; }
        if (num >= 0) {
            uint32_t x, *dst[7];
            dst[0] = &d->rsm; dst[1] = &d->vals; dst[2] = &d->view_samples;
            dst[3] = &d->vpls; dst[4] = &d->clusters; dst[5] = &d->frames; dst[6] = &d->ism_size;
            if (!demo_parse_u32(v, nums[num].lo, nums[num].hi, &x)) {
                snprintf(err, cap, "%s wants an integer in %u..%u, got '%.200s'", nums[num].name, (unsigned)nums[num].lo,
                         (unsigned)nums[num].hi, v);
                return -1;
            }
            *dst[num] = x;
        } else if (is_method) {
            static const char *methods[] = {"gather", "full", "brsm", "clustered", "ssvp", "none"};
            int ok = 0;
            for (k = 0; k < 6; ++k) ok |= !strcmp(v, methods[k]);
            if (!ok) { snprintf(err, cap, "--method wants gather|full|brsm|clustered|ssvp|none, got '%.200s'", v); return -1; }
            d->method = v;
        } else if (is_exposure) {
            char *end;
            double e;
            errno = 0;
            e = strtod(v, &end);
            if (end == v || *end || errno == ERANGE || !(e > 0.0) || e > 1e30) {
                snprintf(err, cap, "--exposure wants a finite number > 0, got '%.200s'", v);
                return -1;
            }
            d->exposure = (float)e;
        } else {
            if (!*v) { snprintf(err, cap, "--screenshot needs a file name"); return -1; }
            d->screenshot = v;
        }
    }
    *rest_count = n;
    return 0;
}

/* The gimany method of a --method name (none: the same meshes without caches, see the demo). */
DEMO_OPTIONS_FN gim_method demo_method(const demo_options *d) {
    return !strcmp(d->method, "full")        ? GIM_METHOD_LIGHTSKIN_FULL
           : !strcmp(d->method, "gather")    ? GIM_METHOD_RSM_GATHER
           : !strcmp(d->method, "clustered") ? GIM_METHOD_CLUSTERED
           : !strcmp(d->method, "ssvp")      ? GIM_METHOD_SSVP
                                             : GIM_METHOD_LIGHTSKIN_BRSM;
}

/* One line refusing a --bounces the method cannot give, or NULL. */
DEMO_OPTIONS_FN const char *demo_bounces_unavailable(const demo_options *d, int bounces) {
    if (bounces != 1 && strcmp(d->method, "clustered") && strcmp(d->method, "ssvp"))
        return "needs --method clustered or ssvp (the other methods give one bounce)";
    return NULL;
}

#endif
