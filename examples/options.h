/* options.h - the options of build/gimany-demo and build/gimany-viewer beyond the scene layer's
   (scene/scene.h: --scene, --sun-dir, --sun-irradiance, --spot, --camera, --size, --out,
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
    uint32_t importance_tile; /* brsm: the two-level importance map's tile side (0: gimany's default; 1: per texel) */
    uint32_t shade_block;    /* brsm, full: the shading pass's block side (0: gimany's default; 1: per pixel) */
    uint32_t neighbours;     /* brsm, full: caches interpolated per pixel (0: gimany's default, 16) */
    float defensive_share;   /* brsm: VALs drawn by luminance alone (0: gimany's default; < 0: none) */
    uint32_t vpls, clusters; /* clustered, ssvp: VPLs per light and clusters; 0: the method's defaults */
    uint32_t interleave;     /* clustered, ssvp: k of the k x k interleaved subsets (0: the library's, by the image) */
    uint32_t second_vpls;    /* --bounces 2: second-bounce VPLs in all (0: the library's default, 256) */
    int second_rays;         /* --bounces 2: 1 by rays from the first-bounce VPLs (GIM_SECOND_BOUNCE_RAYS, the
                                default), -1 from the clusters' maps (MAPS), 0 the library's default */
    int no_visibility;       /* clustered, ssvp: 1 skips the paraboloid visibility */
    int vpl_importance;      /* clustered, ssvp: 1 draws the VPLs by BRSM's importance (gim_frame_vpl.importance) */
    int ism;                 /* 1 turns on gim_frame.visibility.mode = ISM, 2 SHADOW_MAPS, 3 RAYS */
    int neighbour_rays;      /* brsm, full: 1 turns on gim_frame.visibility.neighbour_rays */
    uint32_t ism_size;       /* its map side (0: gimany's default) */
    uint32_t ism_points;     /* points splatted per map (0: gimany's default) */
    int glossy;
    uint32_t frames;         /* demo: frames rendered, timings are medians; viewer: 0 = until closed */
    float exposure;          /* 0: automatic */
    int timing;              /* demo: gim_frame.timing, 2 (--timing cpu, default), 1 (gl) or 0 (off) */
    const char *screenshot;  /* viewer: --screenshot FILE */
    int allow_slow;          /* --allow-slow: run settings above demo_cost_check's limits */
} demo_options;

#define DEMO_PARSE_VIEWER 1u /* accept --screenshot; --frames defaults to 0 (run until closed) */

/* the usage, in two strings (C99 guarantees 4095 characters a literal), printed one after the other */
static const char demo_usage_text[] =
    "  --method M            brsm (default: LightSkin + bidirectional RSM importance sampling), full (LightSkin,\n"
    "                        every RSM texel a VAL), gather (RSM gather, Dachsbacher 2005: the baseline),\n"
    "                        clustered (Dong et al.: k-means VALs with paraboloid soft shadows), ssvp (two\n"
    "                        bounces from paraboloid maps, Aranha et al.), none (direct light only)\n"
    "  --rsm N               RSM side per light in texels (default 256)\n"
    "  --vals N              VALs per light for brsm (default 2048)\n"
    "  --view-samples N      view samples for the importance map (default 128)\n"
    "  --importance-tile T   brsm: the importance map per plane of each T x T texel tile, the VAL picked inside\n"
    "                        its tile (1..32; 1: per texel; default: gimany's, GIM_DEFAULT_IMPORTANCE_TILE)\n"
    "  --shade-block B       brsm, full: neighbours and interpolation once per B x B pixel block, shared by\n"
    "                        the block's pixels on one surface (1: per pixel; 2; default: GIM_DEFAULT_SHADE_BLOCK)\n"
    "  --neighbours N        brsm, full: nearest caches interpolated per pixel (1..16; default 16)\n"
    "  --defensive-share S   brsm: the share of the VALs drawn by the texels' luminance alone, a bound on\n"
    "                        any VAL's weight (0..0.5; 0: none; default: GIM_DEFAULT_DEFENSIVE_SHARE)\n"
    "  --vpls N, --clusters N  clustered, ssvp: VPLs per light and clusters (default 2048, 30 clustered;\n"
    "                        4096, 8 ssvp); --bounces 2 (a scene option, default 1 as for the reference) adds\n"
    "                        the second bounce to either\n"
    "  --interleave K        clustered, ssvp: each pixel of a K x K block shades its own subset of the VPLs,\n"
    "                        a geometry-aware K x K blur joins them (1..32; 1: every VPL at every pixel;\n"
    "                        default 4 clustered, 8 ssvp from 720 rows up, in proportion below)\n"
    "  --second-bounce-vpls N  with --bounces 2: the second bounce's VPLs in all, split over the clusters\n"
    "                        (1..65536; default 256)\n"
    "  --second-bounce-maps  with --bounces 2: second-bounce VPLs from the clusters' attribute maps (SSVP's\n"
    "                        paper) instead of by rays from the first-bounce VPLs (--second-bounce-rays, default)\n"
    ;
static const char demo_usage_text2[] =
    "  --no-visibility       clustered, ssvp: VPLs shade unshadowed, no paraboloid depth maps\n"
    "  --vpl-importance      clustered, ssvp: the VPLs drawn where their light reaches the view (BRSM's\n"
    "                        importance with --view-samples, --importance-tile, --defensive-share), each\n"
    "                        weighted 1 / (N P), instead of evenly over the RSM\n"
    "  --ism                 imperfect shadow maps, no light through walls (default: off): brsm, full one per\n"
    "                        cache, clustered, ssvp one per VPL; --ism-size N their side, a power of two in\n"
    "                        4..64 (default 64; LightSkin halves it where the maps exceed 256 MiB);\n"
    "                        --ism-points N\n"
    "                        the points splatted into each, 1..65536 (default 16384; clustered, ssvp 65536)\n"
    "  --shadow-maps         clustered, ssvp: one shadow map per VPL rendered from the triangles instead\n"
    "                        of its ISM (exact at each texel; a draw of the scene per map made);\n"
    "                        --ism-size N their side\n"
    "  --rays                brsm, full: each VAL's light at each cache tested by a ray through a bounding\n"
    "                        volume hierarchy of the scene instead of the caches' ISMs (--ism)\n"
    "  --neighbour-rays      brsm, full: each pixel interpolates only the neighbour caches it sees, by rays\n"
    "                        through a bounding volume hierarchy of the scene (with or without --ism)\n"
    "  --no-glossy           every material's glossy colour set to 0\n"
    "  --exposure A          tone-mapping exposure (default: automatic, key 0.18 / log-average luminance)\n"
    "  --allow-slow          run a frame estimated above 2e9 terms (about a minute on llvmpipe) or 2 GiB\n"
    "  --timing cpu|gl|off   demo: per-pass times from the CPU's clock after a glFinish per pass (cpu,\n"
    "                        default: right on any driver), from GL timestamps (gl: no stalls, but llvmpipe\n"
    "                        charges queued work to later passes), or none (off: the frame time only)\n";

DEMO_OPTIONS_FN void demo_defaults(demo_options *d, unsigned flags) {
    memset(d, 0, sizeof *d);
    d->method = "brsm";
    d->rsm = 256;
    d->vals = 2048;
    d->view_samples = 128;
    d->glossy = 1;
    d->frames = (flags & DEMO_PARSE_VIEWER) ? 0 : 3;
    d->timing = 2;
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
        {"--vpls", 1, 32768}, {"--clusters", 1, 256}, {"--frames", 1, 100000}, {"--ism-size", 4, 64},
        {"--ism-points", 1, 65536}, {"--importance-tile", 1, 32}, {"--shade-block", 1, 2},
        {"--neighbours", 1, GIM_MAX_NEIGHBOUR_CACHES}, {"--interleave", 1, 32},
        {"--second-bounce-vpls", 1, 65536}};
    int i, n = 0;
    rest[n++] = argv[0];
    for (i = 1; i < argc; ++i) {
        const char *a = argv[i], *eq = strchr(a, '='), *v = NULL;
        size_t len = eq ? (size_t)(eq - a) : strlen(a), k;
        int flag = -1, num = -1, is_method, is_exposure, is_shot, is_timing, is_share;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) return 1;
        if (len == 11 && !strncmp(a, "--no-glossy", 11)) flag = 1;
        else if (len == 15 && !strncmp(a, "--no-visibility", 15)) flag = 2;
        else if (len == 12 && !strncmp(a, "--allow-slow", 12)) flag = 3;
        else if (len == 5 && !strncmp(a, "--ism", 5)) flag = 4;
        else if (len == 16 && !strncmp(a, "--vpl-importance", 16)) flag = 5;
        else if (len == 13 && !strncmp(a, "--shadow-maps", 13)) flag = 6;
        else if (len == 16 && !strncmp(a, "--neighbour-rays", 16)) flag = 7;
        else if (len == 6 && !strncmp(a, "--rays", 6)) flag = 8;
        else if (len == 20 && !strncmp(a, "--second-bounce-rays", 20)) flag = 9;
        else if (len == 20 && !strncmp(a, "--second-bounce-maps", 20)) flag = 10;
        if (flag >= 0) {
            if (eq) { snprintf(err, cap, "%.*s takes no value", (int)len, a); return -1; }
            if (flag == 1) d->glossy = 0;
            else if (flag == 2) d->no_visibility = 1;
            else if (flag == 3) d->allow_slow = 1;
            else if (flag == 4) d->ism = 1;
            else if (flag == 6) d->ism = 2;
            else if (flag == 7) d->neighbour_rays = 1;
            else if (flag == 8) d->ism = 3;
            else if (flag == 9) d->second_rays = 1;
            else if (flag == 10) d->second_rays = -1;
            else d->vpl_importance = 1;
            continue;
        }
        for (k = 0; k < sizeof nums / sizeof nums[0]; ++k)
            if (strlen(nums[k].name) == len && !strncmp(a, nums[k].name, len)) num = (int)k;
        is_method = len == 8 && !strncmp(a, "--method", 8);
        is_exposure = len == 10 && !strncmp(a, "--exposure", 10);
        is_shot = (flags & DEMO_PARSE_VIEWER) && len == 12 && !strncmp(a, "--screenshot", 12);
        is_timing = !(flags & DEMO_PARSE_VIEWER) && len == 8 && !strncmp(a, "--timing", 8);
        is_share = len == 17 && !strncmp(a, "--defensive-share", 17);
        if (num < 0 && !is_method && !is_exposure && !is_shot && !is_timing && !is_share) {
            /* the scene layer's: every one of them takes one value */
            rest[n++] = argv[i];
            if (!strncmp(a, "--", 2) && !eq && i + 1 < argc) rest[n++] = argv[++i];
            continue;
        }
        if (eq) v = eq + 1;
        else if (i + 1 < argc) v = argv[++i];
        else { snprintf(err, cap, "option %.*s needs a value (see --help)", (int)len, a); return -1; }
        if (num >= 0) {
            uint32_t x, *dst[13];
            dst[0] = &d->rsm; dst[1] = &d->vals; dst[2] = &d->view_samples;
            dst[3] = &d->vpls; dst[4] = &d->clusters; dst[5] = &d->frames; dst[6] = &d->ism_size; dst[7] = &d->ism_points;
            dst[8] = &d->importance_tile; dst[9] = &d->shade_block; dst[10] = &d->neighbours;
            dst[11] = &d->interleave; dst[12] = &d->second_vpls;
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
        } else if (is_timing) {
            if (!strcmp(v, "cpu")) d->timing = 2;
            else if (!strcmp(v, "gl")) d->timing = 1;
            else if (!strcmp(v, "off")) d->timing = 0;
            else { snprintf(err, cap, "--timing wants cpu|gl|off, got '%.200s'", v); return -1; }
        } else if (is_share) {
            char *end;
            double e;
            errno = 0;
            e = strtod(v, &end);
            if (end == v || *end || errno == ERANGE || !(e >= 0.0 && e <= 0.5)) {
                snprintf(err, cap, "--defensive-share wants a number in 0..0.5, got '%.200s'", v);
                return -1;
            }
            d->defensive_share = e > 0.0 ? (float)e : -1.0f;
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

/* The gim_frame fields these options set, for the demo's frame and the viewer's alike (a zero
   leaves gimany's default); bounces: the scene option's. */
DEMO_OPTIONS_FN void demo_frame_settings(const demo_options *d, int bounces, gim_frame *f) {
    f->method = demo_method(d);
    f->vpl.count = d->vpls;
    f->vpl.cluster_count = d->clusters;
    if (d->interleave) f->vpl.interleave = d->interleave;
    f->vpl.second_bounce_vpls = d->second_vpls;
    if (d->second_rays) f->vpl.second_bounce = d->second_rays > 0 ? GIM_SECOND_BOUNCE_RAYS : GIM_SECOND_BOUNCE_MAPS;
    f->vpl.bounces = (uint32_t)bounces;
    f->vpl.no_visibility = d->no_visibility;
    f->vpl.importance = d->vpl_importance;
    f->lightskin.val_count = d->vals;
    f->lightskin.view_sample_count = d->view_samples;
    f->lightskin.importance_tile = d->importance_tile;
    f->lightskin.defensive_share = d->defensive_share;
    f->lightskin.shade_block = d->shade_block;
    f->lightskin.neighbour_count = d->neighbours;
    f->lightskin.rotate_view_samples = 1;
    f->visibility.mode = d->ism == 3   ? GIM_VISIBILITY_RAYS
                         : d->ism == 2 ? GIM_VISIBILITY_SHADOW_MAPS
                         : d->ism      ? GIM_VISIBILITY_ISM
                                       : GIM_VISIBILITY_OFF;
    f->visibility.ism_size = d->ism_size;
    f->visibility.ism_points = d->ism_points;
    f->visibility.neighbour_rays = d->neighbour_rays ? 1u : 0u;
}

/* A frame's work from the cost model, in terms (one VAL or VPL or texel
   evaluated for one cache, pixel or view sample) and bytes of GL and CPU memory:
     brsm      importance rsm^2 x 4 / T^2 x view samples (T > 1: --importance-tile, 4 planes a tile) + accumulation
               caches x VALs, per light
     full      caches x rsm^2 per light
     gather    pixels x 256 pattern texels per light
     clustered, ssvp   pixels x VPLs / k^2 (--interleave k; 0: gim_vpl_default_interleave), second bounce included
     LightSkin interpolation pixels x 16 neighbours; with --ism the maps' surfels, caches x 16384;
               with --rays 64 a ray, caches x VALs
   memory: 52 bytes an RSM texel (+ 12 with brsm's tables) per light, about 140 a pixel.
   Measured on llvmpipe (2 cores): 3.9e7 terms/s (full, the Cornell box's 8960 caches x 256^2
   in 15 s), so DEMO_MAX_TERMS is about a minute a frame; a GPU is 100x faster: --allow-slow. */
#define DEMO_MAX_TERMS 2e9
#define DEMO_MAX_BYTES 2147483648.0
DEMO_OPTIONS_FN void demo_cost(const demo_options *d, uint32_t width, uint32_t height, uint32_t lights, uint32_t caches,
                               int bounces, double *terms, double *bytes) {
    double px = (double)width * height, texels = (double)d->rsm * d->rsm, L = lights ? lights : 1, t = 0.0;
    int ls = !strcmp(d->method, "brsm") || !strcmp(d->method, "full");
    if (!strcmp(d->method, "brsm")) {   /* the importance map per tile of T x T texels (T = 1: per texel) */
        double tile = d->importance_tile ? d->importance_tile : GIM_DEFAULT_IMPORTANCE_TILE;
        t = L * (texels * d->view_samples * (tile > 1.0 ? 4.0 : 1.0) / (tile * tile) + (double)caches * d->vals);
    }
    else if (!strcmp(d->method, "full")) t = L * (double)caches * texels;
    else if (!strcmp(d->method, "gather")) t = L * px * 256.0;
    else if (!strcmp(d->method, "clustered") || !strcmp(d->method, "ssvp")) {
        int cl = !strcmp(d->method, "clustered");
        double v = d->vpls ? d->vpls : cl ? 2048.0 : 4096.0;   /* the library's defaults: VPLs and */
        double k = d->interleave ? d->interleave                      /* interleave k^2 */
                                 : gim_vpl_default_interleave(cl ? GIM_METHOD_CLUSTERED : GIM_METHOD_SSVP, width, height,
                                                              (uint32_t)v),
               k2 = k * k;
        double second = d->second_vpls ? d->second_vpls : 256.0;   /* the library's default */
        t = px * (L * v + (bounces == 2 || (!cl && bounces != 1) ? second : 0.0)) / k2;
    }
    if (ls) t += px * 16.0 + (d->ism == 1 ? (double)caches * 16384.0 : 0.0);   /* the library's default points per map */
    if (ls && d->ism == 3)   /* --rays: a walk of the hierarchy per VAL and cache, counted as 64 terms */
        t += 64.0 * L * (double)caches * (!strcmp(d->method, "full") ? texels : (double)d->vals);
    *terms = t;
    *bytes = L * texels * (52.0 + (!strcmp(d->method, "brsm") ? 12.0 : 0.0)) + px * 140.0;
}

/* 0, or 1 with one line in err: the frame's estimate is above a limit and --allow-slow is off. */
DEMO_OPTIONS_FN int demo_cost_check(const demo_options *d, uint32_t width, uint32_t height, uint32_t lights, uint32_t caches,
                                    int bounces, char *err, size_t cap) {
    double terms, bytes;
    if (d->allow_slow) return 0;
    demo_cost(d, width, height, lights, caches, bounces, &terms, &bytes);
    if (terms <= DEMO_MAX_TERMS && bytes <= DEMO_MAX_BYTES) return 0;
    snprintf(err, cap,
             "%s at --rsm %u, --vals %u, %ux%u, %u caches is estimated at %.2g terms and %.2g GiB a frame, above %.0g terms "
             "(about a minute on llvmpipe) or %.0f GiB: lower them, or pass --allow-slow",
             d->method, (unsigned)d->rsm, (unsigned)d->vals, (unsigned)width, (unsigned)height, (unsigned)caches, terms,
             bytes / 1073741824.0, DEMO_MAX_TERMS, DEMO_MAX_BYTES / 1073741824.0);
    return 1;
}

/* One line refusing a --bounces the method cannot give, or NULL. */
DEMO_OPTIONS_FN const char *demo_bounces_unavailable(const demo_options *d, int bounces) {
    if (bounces != 1 && strcmp(d->method, "clustered") && strcmp(d->method, "ssvp"))
        return "needs --method clustered or ssvp (the other methods give one bounce)";
    return NULL;
}

#endif
