/* Many lights against the sum of per-light frames, side by side in one run: the
   street of gltest_lights (ground, two facades, a canopy behind the camera) at night with 32
   spots -- 24 lamps, 4 into the sky (culled: no RSM), 4 onto the canopy (importance 0: no
   VALs). Rows: one frame with all 32 lights against 32 single-light frames summed, for FULL
   and for BRSM (shared budget, per-light budget of the same total, and 32 single-light BRSM
   frames of the same VALs per light); error is the relative MAE against the FULL 32-light
   image (BRSM: the mean over 8 rotated selections of the one-frame error); time is the median
   of 3 gim_update calls with timing = 2 (glFinish after every pass), llvmpipe in CI: only the
   ratios within one run mean anything. */
#define _POSIX_C_SOURCE 199309L
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "room.h"
#include "lamps.h"

#define W 96
#define H 64
#define NL 32
#define RSM 48
#define RUNS 3
#define SEEDS 8

static gim_context *ctx;
static gim_light lights[NL];
static gim_frame fr;
static double full_img[W * H * 3];
static double sum_proxy_ms;   /* row_sum: the proxy-light pass summed over the single-light frames */

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* One frame (its image into img when not NULL) and its stats. */
static int frame(float *img, gim_stats *st) {
    gim_frame_outputs o;
    if (gim_update(ctx, &fr) != GIM_OK || gim_frame_stats(ctx, st) != GIM_OK) return -1;
    o = gim_outputs(ctx);
    if (img) {
        if (o.indirect) gltest_read_texture(o.indirect, GL_RGBA, img);
        else memset(img, 0, (size_t)W * H * 16);
    }
    return 0;
}

/* Median frame time of RUNS frames (after one to warm up), the last image in img. */
static double timed(float *img, gim_stats *st) {
    double t[RUNS];
    int i;
    if (frame(NULL, st)) return -1.0;
    for (i = 0; i < RUNS; ++i) {
        if (frame(i == RUNS - 1 ? img : NULL, st)) return -1.0;
        t[i] = st->frame_ms;
    }
    qsort(t, RUNS, sizeof *t, cmp_double);
    return t[RUNS / 2];
}

static double rel_mae(const double *img, const double *ref) {
    double d = 0.0, t = 0.0;
    int p;
    for (p = 0; p < W * H * 3; ++p) { d += fabs(img[p] - ref[p]); t += fabs(ref[p]); }
    return t > 0.0 ? d / t : 0.0;
}

static void to_rgb(const float *img, double *rgb, double scale, int add) {
    int p;
    for (p = 0; p < W * H; ++p) {
        int c;
        for (c = 0; c < 3; ++c) rgb[p * 3 + c] = (add ? rgb[p * 3 + c] : 0.0) + scale * img[p * 4 + c];
    }
}

/* All 32 in one frame: time, error (BRSM: mean over SEEDS selections). */
static void row_all(const char *name, gim_method m, int per_light, uint32_t vals, double *ms, double *err, gim_stats *st) {
    static float img[W * H * 4];
    static double rgb[W * H * 3];
    int s;
    fr.method = m;
    fr.per_light_budget = per_light;
    fr.lightskin.val_count = vals;
    fr.frame_index = 0;
    gim_set_lights(ctx, lights, NL);
    *ms = timed(img, st);
    *err = 0.0;
    for (s = 0; s < (m == GIM_METHOD_LIGHTSKIN_FULL ? 1 : SEEDS); ++s) {
        gim_stats st2;
        fr.frame_index = (uint32_t)s;
        if (frame(img, &st2)) { *err = -1.0; return; }
        to_rgb(img, rgb, 1.0, 0);
        if (m == GIM_METHOD_LIGHTSKIN_FULL && !per_light && vals == 0) memcpy(full_img, rgb, sizeof rgb);
        *err += rel_mae(rgb, full_img) / (m == GIM_METHOD_LIGHTSKIN_FULL ? 1 : SEEDS);
    }
    (void)name;
}

/* The 32 single-light frames summed: total time, error (BRSM: mean over SEEDS). */
static void row_sum(gim_method m, uint32_t vals, double *ms, double *err, uint32_t *vals_used) {
    static float img[W * H * 4];
    static double rgb[W * H * 3];
    int k, s, seeds = m == GIM_METHOD_LIGHTSKIN_FULL ? 1 : SEEDS;
    gim_stats st;
    fr.method = m;
    fr.per_light_budget = 0;
    fr.lightskin.val_count = vals;
    *ms = 0.0;
    *err = 0.0;
    *vals_used = 0;
    for (s = 0; s < seeds; ++s) {
        memset(rgb, 0, sizeof rgb);
        fr.frame_index = (uint32_t)s;
        for (k = 0; k < NL; ++k) {
            gim_set_lights(ctx, &lights[k], 1);
            if (s == 0) {
                *ms += timed(img, &st);
                *vals_used += st.val_count;
                sum_proxy_ms += st.pass_ms[GIM_PASS_PROXY_LIGHTS];
            }
            else if (frame(img, &st)) return;
            to_rgb(img, rgb, 1.0, 1);
        }
        *err += rel_mae(rgb, full_img) / seeds;
    }
}

int main(void) {
    gim_desc d;
    room r[4];
    gim_instance in[4];
    gim_cache_set set[4];
    gim_stats st;
    double ms_full, e_full, ms_full_sum, e_full_sum, ms_sh, e_sh, ms_pl, e_pl, ms_bsum, e_bsum;
    gim_stats st_sh, st_pl;
    uint32_t v_full_sum, v_bsum;
    int k;
    const uint32_t per = 64, total = 24u * 64u;   /* 64 VALs per lamp */
    if (!gltest_init()) { printf("bench_lights: no GL (%s)\n", gltest.why); return 0; }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    lamps_quads(r);
    for (k = 0; k < 4; ++k) {
        gim_cache_desc cd;
        gim_mesh_desc md;
        memset(&cd, 0, sizeof cd);
        cd.mesh = room_arrays(&r[k]);
        cd.d_eps = 0.5f;
        if (gim_cache_generate(&cd, &set[k]) != GIM_OK) return 1;
        memset(&md, 0, sizeof md);
        md.data = room_arrays(&r[k]);
        md.caches = &set[k];
        if (gim_add_mesh(ctx, &md, &in[k].mesh) != GIM_OK) return 1;
        in[k].model = gim_mat4_identity();
    }
    if (gim_set_materials(ctx, room_materials, 3) != GIM_OK || gim_set_instances(ctx, in, 4) != GIM_OK) return 1;
    for (k = 0; k < NL; ++k) lights[k] = lamps_light(k, RSM);
    memset(&fr, 0, sizeof fr);
    lamps_view(&fr, W, H);
    fr.indirect_float32 = 1;
    fr.lightskin.view_sample_count = 256;
    fr.timing = 2;
    printf("bench_lights: street, %d spots (24 lamps, 4 into the sky, 4 onto an unseen canopy), RSM %d^2, %dx%d, %s\n",
           NL, RSM, W, H, (const char *)glGetString(GL_RENDERER));
    row_all("FULL", GIM_METHOD_LIGHTSKIN_FULL, 0, 0, &ms_full, &e_full, &st);
    printf("  RSMs rendered %u of %u; GPU %.2f MiB\n", (unsigned)st.rsm_count, (unsigned)st.light_count,
           (double)st.gpu_bytes / 1048576.0);
    sum_proxy_ms = 0.0;
    row_sum(GIM_METHOD_LIGHTSKIN_FULL, 0, &ms_full_sum, &e_full_sum, &v_full_sum);
    printf("FULL proxy-light pass: %.1f ms with 32 in one frame, %.1f ms summed over the 32 single-light frames\n",
           st.pass_ms[GIM_PASS_PROXY_LIGHTS], sum_proxy_ms);
    row_all("BRSM shared", GIM_METHOD_LIGHTSKIN_BRSM, 0, total, &ms_sh, &e_sh, &st_sh);
    row_all("BRSM per light", GIM_METHOD_LIGHTSKIN_BRSM, 1, total / 28u, &ms_pl, &e_pl, &st_pl);
    row_sum(GIM_METHOD_LIGHTSKIN_BRSM, per, &ms_bsum, &e_bsum, &v_bsum);
    printf("| frame | VALs | time ms | x the per-light sum | rel. MAE vs FULL (32 in one) |\n|---|---|---|---|---|\n");
    printf("| FULL, 32 lights in one frame | %u | %.1f | %.2f | 0 (the reference) |\n", (unsigned)st.val_count, ms_full,
           ms_full / ms_full_sum);
    printf("| FULL, sum of 32 single-light frames | %u | %.1f | 1 | %.2e |\n", (unsigned)v_full_sum, ms_full_sum, e_full_sum);
    printf("| BRSM shared budget, 32 in one | %u | %.1f | %.2f | %.4f |\n", (unsigned)st_sh.val_count, ms_sh,
           ms_sh / ms_bsum, e_sh);
    printf("| BRSM per-light budget (%u x 28), 32 in one | %u | %.1f | %.2f | %.4f |\n", total / 28u,
           (unsigned)st_pl.val_count, ms_pl, ms_pl / ms_bsum, e_pl);
    printf("| BRSM, sum of 32 single-light frames (%u each) | %u | %.1f | 1 | %.4f |\n", per, (unsigned)v_bsum, ms_bsum,
           e_bsum);
    printf("BRSM shared, per pass (ms): RSM %.1f, view samples %.1f, importance %.1f, cumsum %.1f, select %.1f, "
           "VALs %.1f, proxy %.1f, shade %.1f; frame %.1f\n",
           st_sh.pass_ms[GIM_PASS_RSM], st_sh.pass_ms[GIM_PASS_VIEW_SAMPLES], st_sh.pass_ms[GIM_PASS_IMPORTANCE_MAP],
           st_sh.pass_ms[GIM_PASS_CUMSUM], st_sh.pass_ms[GIM_PASS_SELECT], st_sh.pass_ms[GIM_PASS_VALS],
           st_sh.pass_ms[GIM_PASS_PROXY_LIGHTS], st_sh.pass_ms[GIM_PASS_SHADE], st_sh.frame_ms);
    for (k = 0; k < 4; ++k) gim_cache_set_free(&set[k]);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
