/* gimany-demo - the main job, headless: loads a scene (scene/scene.h), hands it to gimany
   (scene/scene_gimany.h), runs --frames frames of the chosen method on an EGL context with
   no window (examples/egl_headless.h), adds the direct light and tone maps
   (examples/display.h), and writes into --out:
     final.png     direct + indirect, Reinhard tone mapped, sRGB
     indirect.pfm  gimany's indirect output: linear RGB radiance towards the eye, 0 where no geometry
     direct.pfm    the direct light, likewise
     stats.json    method, parameters, GL renderer, per-pass median ms (--timing), frame median ms, counts
   and prints a table of the passes. Every image is of the last frame; timings are medians over
   the frames. Run with --help for the options. Exit status: 0 done, 2 bad options, 1 anything
   else (file missing or malformed, no GL 4.3, a GL failure), with one line on stderr. */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "egl_headless.h"
#include "scene_gimany.h"
#include "display.h"
#include "options.h"
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-prototypes"
#endif
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb_image_write.h>
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic pop
#endif

#define PROG "gimany-demo"

/* Log only warnings and errors of gimany, one line each. */
static void demo_log(gim_log_level level, const char *message, void *user) {
    (void)user;
    if (level == GIM_LOG_INFO) return;
    fprintf(stderr, PROG ": %s: %s\n", level == GIM_LOG_ERROR ? "error" : "warning", message);
}

static double now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median(double *v, uint32_t n) {
    if (n == 0) return 0.0;
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* GL rows bottom first, RGBA -> top row first, RGB; 0 where a != 1 (no surface). */
static void to_rgb_top_first(const float *rgba, uint32_t w, uint32_t h, float *rgb) {
    uint32_t x, y;
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            const float *s = rgba + ((size_t)(h - 1u - y) * w + x) * 4;
            float *d = rgb + ((size_t)y * w + x) * 3;
            int c;
            for (c = 0; c < 3; ++c) d[c] = s[3] == 1.0f && isfinite(s[c]) ? s[c] : 0.0f;
        }
}

/* JSON string body: quotes, backslashes and control characters escaped. */
static void json_string(FILE *f, const char *s) {
    fputc('"', f);
    for (; s && *s; ++s) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(f, "\\%c", c);
        else if (c < 0x20) fprintf(f, "\\u%04x", c);
        else fputc(c, f);
    }
    fputc('"', f);
}

static const char *pass_names[GIM_PASS_COUNT] = {"rsm", "gbuffer", "view_samples", "importance_map", "cumsum", "select",
                                                 "caches", "vals", "proxy_lights", "shade", "vpls",
                                                 "kmeans", "paraboloid", "second_bounce", "blur", "ism"};

typedef struct demo_run {
    scene s;
    demo_options d;
    scene_options o;
    uint64_t triangles;
    const char *renderer;
    double pass_ms[GIM_PASS_COUNT], direct_ms, compose_ms, gimany_ms, frame_ms;
    gim_stats st;
    uint32_t cache_count;
    float exposure;
} demo_run;

static int write_stats(const demo_run *r, const char *path, char *err, size_t cap) {
    FILE *f = fopen(path, "w");
    uint32_t p;
    if (!f) { snprintf(err, cap, "cannot write %.300s: %.100s", path, strerror(errno)); return 1; }
    fprintf(f, "{\n  \"method\": ");
    json_string(f, r->d.method);
    fprintf(f, ",\n  \"scene\": ");
    json_string(f, r->o.scene);
    fprintf(f, ",\n  \"renderer\": ");
    json_string(f, r->renderer);
    fprintf(f, ",\n  \"pass_timing\": ");
    json_string(f, r->d.timing == 2 ? "cpu: glFinish after each pass, CPU clock" : r->d.timing == 1 ? "gl: timestamps" : "off");
    fprintf(f,
            ",\n  \"parameters\": {\"width\": %u, \"height\": %u, \"rsm\": %u, \"vals\": %u, \"view_samples\": %u, "
            "\"vpls\": %u, \"clusters\": %u, \"bounces\": %d, \"ism\": %s, \"glossy\": %s, \"frames\": %u, "
            "\"exposure\": %.6g},\n",
            (unsigned)r->o.width, (unsigned)r->o.height, (unsigned)r->d.rsm, (unsigned)r->d.vals, (unsigned)r->d.view_samples,
            (unsigned)r->d.vpls, (unsigned)r->d.clusters, r->o.bounces, r->d.ism ? "true" : "false",
            r->d.glossy ? "true" : "false", (unsigned)r->d.frames, (double)r->exposure);
    fprintf(f, "  \"pass_ms\": {");
    for (p = 0; p < GIM_PASS_COUNT; ++p) fprintf(f, "\"%s\": %.4f, ", pass_names[p], r->pass_ms[p]);
    fprintf(f, "\"direct\": %.4f, \"compose\": %.4f},\n", r->direct_ms, r->compose_ms);
    fprintf(f, "  \"gimany_frame_ms\": %.4f,\n  \"frame_ms\": %.4f,\n", r->gimany_ms, r->frame_ms);
    fprintf(f,
            "  \"counts\": {\"triangles\": %llu, \"caches\": %u, \"vals\": %u, \"view_samples\": %u, \"vpls\": %u, "
            "\"clusters\": %u, \"lights\": %u, \"pixels\": %u, \"gpu_bytes\": %llu}\n}\n",
            (unsigned long long)r->triangles, (unsigned)r->cache_count, (unsigned)r->st.val_count,
            (unsigned)r->st.view_sample_count, (unsigned)r->st.vpl_count, (unsigned)r->st.cluster_count,
            (unsigned)r->s.light_count, (unsigned)(r->o.width * r->o.height),
            (unsigned long long)r->st.gpu_bytes);
    if (fclose(f) != 0) { snprintf(err, cap, "cannot write %.400s", path); return 1; }
    return 0;
}

/* The four files of --out; rgb images top row first. */
static int write_outputs(const demo_run *r, const float *direct, const float *indirect, const unsigned char *final_rgb,
                         char *err, size_t cap) {
    char path[4096];
    uint32_t w = r->o.width, h = r->o.height;
    if (scene_make_dir(r->o.out_dir, err, cap)) return 1;
    snprintf(path, sizeof path, "%s/final.png", r->o.out_dir);
    if (!stbi_write_png(path, (int)w, (int)h, 3, final_rgb, (int)w * 3)) {
        snprintf(err, cap, "cannot write %.400s", path);
        return 1;
    }
    snprintf(path, sizeof path, "%s/indirect.pfm", r->o.out_dir);
    if (scene_write_pfm(path, indirect, w, h, err, cap)) return 1;
    snprintf(path, sizeof path, "%s/direct.pfm", r->o.out_dir);
    if (scene_write_pfm(path, direct, w, h, err, cap)) return 1;
    snprintf(path, sizeof path, "%s/stats.json", r->o.out_dir);
    return write_stats(r, path, err, cap);
}

static void print_table(const demo_run *r) {
    uint32_t p;
    printf("gimany-demo: %s, %s, %ux%u, %llu triangles, %u caches, %u VALs, %u view samples, %u light(s)\n", r->o.scene,
           r->d.method, (unsigned)r->o.width, (unsigned)r->o.height, (unsigned long long)r->triangles,
           (unsigned)r->cache_count, (unsigned)r->st.val_count, (unsigned)r->st.view_sample_count, (unsigned)r->s.light_count);
    printf("renderer: %s; medians of %u frame(s); pass times: %s\n", r->renderer, (unsigned)r->d.frames,
           r->d.timing == 2 ? "glFinish after each pass, CPU clock" : r->d.timing == 1 ? "GL timestamps" : "off");
    printf("%-16s %10s\n", "pass", "ms");
    for (p = 0; p < GIM_PASS_COUNT; ++p)
        if (r->pass_ms[p] > 0.0) printf("%-16s %10.2f\n", pass_names[p], r->pass_ms[p]);
    if (r->d.timing) { /* off: no pass is timed, gimany's frame neither */
        printf("%-16s %10.2f\n", "direct", r->direct_ms);
        printf("%-16s %10.2f\n", "compose", r->compose_ms);
        printf("%-16s %10.2f\n", "gimany frame", r->gimany_ms);
    }
    printf("%-16s %10.2f   (wall clock: gim_update + direct + compose + glFinish)\n", "frame", r->frame_ms);
    printf("wrote %s/final.png, indirect.pfm, direct.pfm, stats.json\n", r->o.out_dir);
}

/* Renders; 0 on success, else err says why. */
static int demo_render(demo_run *r, char *err, size_t cap) {
    egl_headless eh;
    gim_desc gd;
    gim_context *ctx = NULL;
    scene_gimany g;
    display dp;
    gim_frame f;
    gim_mesh *plain = NULL;
    gim_instance *plain_inst = NULL;
    uint32_t w = r->o.width, h = r->o.height, i, fr, p;
    size_t npx = (size_t)w * h;
    float *direct = NULL, *indirect = NULL, *rgb_d = NULL, *rgb_i = NULL;
    unsigned char *final_rgb = NULL;
    double *samples = NULL;
    GLint max_tex = 0, max_vp[2] = {0, 0};
    int rc = 1, have_g = 0, have_dp = 0;
    char why[256];
    memset(&g, 0, sizeof g);
    if (!egl_headless_open(&eh, why, sizeof why)) { snprintf(err, cap, "%s", why); return 1; }
    r->renderer = (const char *)glGetString(GL_RENDERER);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    glGetIntegerv(GL_MAX_VIEWPORT_DIMS, max_vp);
    if (w > (uint32_t)max_tex || h > (uint32_t)max_tex || w > (uint32_t)max_vp[0] || h > (uint32_t)max_vp[1]) {
        snprintf(err, cap, "--size %ux%u is more than this GL can draw (%d x %d)", (unsigned)w, (unsigned)h,
                 max_tex < max_vp[0] ? max_tex : max_vp[0], max_tex < max_vp[1] ? max_tex : max_vp[1]);
        goto done;
    }
    if (r->d.rsm > (uint32_t)max_tex || r->d.rsm > (uint32_t)max_vp[0] || r->d.rsm > (uint32_t)max_vp[1]) {
        snprintf(err, cap, "--rsm %u is more than this GL can draw (%d)", (unsigned)r->d.rsm, max_tex);
        goto done;
    }
    memset(&gd, 0, sizeof gd);
    gd.get_proc_address = egl_headless_proc;
    gd.env.logger.func = demo_log;
    if (gim_create(&gd, &ctx) != GIM_OK) { snprintf(err, cap, "gimany cannot run on %s (logged above)", r->renderer); goto done; }
    if (scene_gimany_load(ctx, &r->s, 0.0f, r->d.rsm, gd.env, &g) != GIM_OK) {
        snprintf(err, cap, "cannot hand the scene to gimany (logged above)");
        goto done;
    }
    have_g = 1;
    r->cache_count = g.cache_count;
    if (demo_cost_check(&r->d, w, h, r->s.light_count, strcmp(r->d.method, "none") ? g.cache_count : 0u, r->o.bounces, err,
                        cap))
        goto done;
    if (!strcmp(r->d.method, "none")) { /* the same meshes without caches: gimany runs its shared passes only */
        plain = (gim_mesh *)calloc(g.mesh_count + 1u, sizeof *plain);
        plain_inst = (gim_instance *)calloc(g.mesh_count + 1u, sizeof *plain_inst);
        if (!plain || !plain_inst) { snprintf(err, cap, "out of memory"); goto done; }
        if (scene_gimany_add_plain(ctx, &r->s, plain, plain_inst) != GIM_OK) {
            memset(plain, 0, (g.mesh_count + 1u) * sizeof *plain);
            snprintf(err, cap, "cannot upload the meshes (logged above)");
            goto done;
        }
        if (gim_set_instances(ctx, plain_inst, g.mesh_count) != GIM_OK) { snprintf(err, cap, "cannot set instances"); goto done; }
        r->cache_count = 0;
    }
    if (!display_init(&dp)) { snprintf(err, cap, "display shaders: %.400s", dp.error); goto done; }
    have_dp = 1;
    {
        gim_material *mats = (gim_material *)calloc(r->s.material_count + 1u, sizeof *mats);
        if (!mats) { snprintf(err, cap, "out of memory"); goto done; }
        for (i = 0; i < r->s.material_count; ++i) {
            memcpy(mats[i].diffuse, r->s.materials[i].diffuse, sizeof mats[i].diffuse);
            memcpy(mats[i].glossy, r->s.materials[i].glossy, sizeof mats[i].glossy);
            mats[i].exponent = r->s.materials[i].exponent;
        }
        display_set_materials(&dp, mats, r->s.material_count);
        free(mats);
    }
    memset(&f, 0, sizeof f);
    scene_gimany_camera(&r->s, &f.view, &f.proj);
    f.width = w;
    f.height = h;
    demo_frame_settings(&r->d, r->o.bounces, &f);
    f.indirect_float32 = 1;
    f.timing = r->d.timing;
    samples = (double *)calloc((size_t)r->d.frames * (GIM_PASS_COUNT + 4), sizeof *samples);
    direct = (float *)malloc(npx * 16);
    indirect = (float *)calloc(npx, 16);
    rgb_d = (float *)malloc(npx * 12);
    rgb_i = (float *)malloc(npx * 12);
    final_rgb = (unsigned char *)malloc(npx * 3);
    if (!samples || !direct || !indirect || !rgb_d || !rgb_i || !final_rgb) { snprintf(err, cap, "out of memory for %ux%u", w, h); goto done; }
    {   /* every shader the frame needs, before the first frame (what a loading screen hides) */
        double t0 = now_ms();
        if (gim_prepare(ctx, &f) != GIM_OK) { snprintf(err, cap, "gim_prepare failed (logged above)"); goto done; }
        printf("shaders built in %.0f ms (gim_prepare)\n", now_ms() - t0);
    }
    for (fr = 0; fr < r->d.frames; ++fr) {
        gim_frame_outputs o;
        gim_debug_outputs od;
        double t0 = now_ms(), *row = samples + (size_t)fr * (GIM_PASS_COUNT + 4);
        f.frame_index = fr;
        if (gim_update(ctx, &f) != GIM_OK) { snprintf(err, cap, "gim_update failed (logged above)"); goto done; }
        o = gim_outputs(ctx); od = gim_debug(ctx);
        if (od.cluster_count) {   /* the VPL methods: report what ran, the defaults resolved */
            r->d.vpls = od.first_bounce_count / (o.light_count ? o.light_count : 1u);
            r->d.clusters = od.cluster_count;
        }
        if (f.timing == 2) { /* as gimany's passes: finish, then the CPU's clock */
            double t1, t2;
            glFinish();
            t1 = now_ms();
            display_direct(&dp, &o, f.view, f.proj, 0);
            glFinish();
            t2 = now_ms();
            display_compose(&dp, o.indirect, 1.0f);
            glFinish();
            row[GIM_PASS_COUNT] = t2 - t1;
            row[GIM_PASS_COUNT + 1] = now_ms() - t2;
        } else {
            display_direct(&dp, &o, f.view, f.proj, f.timing == 1);
            display_compose(&dp, o.indirect, 1.0f);
            glFinish();
        }
        row[GIM_PASS_COUNT + 3] = now_ms() - t0;
        if (gim_frame_stats(ctx, &r->st) != GIM_OK) { snprintf(err, cap, "gim_frame_stats failed"); goto done; }
        for (p = 0; p < GIM_PASS_COUNT; ++p) row[p] = r->st.pass_ms[p];
        if (f.timing == 1) display_timings(&dp, &row[GIM_PASS_COUNT], &row[GIM_PASS_COUNT + 1]);
        row[GIM_PASS_COUNT + 2] = r->st.frame_ms;
    }
    {   /* medians, one column at a time */
        double *col = (double *)malloc(r->d.frames * sizeof *col), med[GIM_PASS_COUNT + 4];
        if (!col) { snprintf(err, cap, "out of memory"); goto done; }
        for (p = 0; p < GIM_PASS_COUNT + 4; ++p) {
            for (fr = 0; fr < r->d.frames; ++fr) col[fr] = samples[(size_t)fr * (GIM_PASS_COUNT + 4) + p];
            med[p] = median(col, r->d.frames);
        }
        free(col);
        memcpy(r->pass_ms, med, sizeof r->pass_ms);
        r->direct_ms = med[GIM_PASS_COUNT];
        r->compose_ms = med[GIM_PASS_COUNT + 1];
        r->gimany_ms = med[GIM_PASS_COUNT + 2];
        r->frame_ms = med[GIM_PASS_COUNT + 3];
    }
    {   /* the last frame's images; the exposure from them, then the final image once more */
        gim_frame_outputs o = gim_outputs(ctx);
        display_read(dp.direct, direct);
        if (o.indirect) display_read(o.indirect, indirect);
        r->exposure = r->d.exposure > 0.0f ? r->d.exposure : display_auto_exposure(direct, o.indirect ? indirect : NULL, (uint32_t)npx);
        display_compose(&dp, o.indirect, r->exposure);
        display_read_final(&dp, final_rgb);
        for (i = 0; i < npx; ++i) indirect[i * 4 + 3] = direct[i * 4 + 3]; /* 0 where no geometry */
        to_rgb_top_first(direct, w, h, rgb_d);
        to_rgb_top_first(indirect, w, h, rgb_i);
    }
    if (glGetError() != GL_NO_ERROR) { snprintf(err, cap, "a GL error in the display passes"); goto done; }
    rc = write_outputs(r, rgb_d, rgb_i, final_rgb, err, cap);
done:
    if (have_dp) display_free(&dp);
    if (plain && ctx)
        for (i = 0; i < g.mesh_count; ++i)
            if (plain[i].id) gim_remove_mesh(ctx, plain[i]);
    if (have_g) scene_gimany_free(ctx, &g);
    gim_destroy(ctx);
    egl_headless_close(&eh);
    free(plain); free(plain_inst); free(samples); free(direct); free(indirect); free(rgb_d); free(rgb_i); free(final_rgb);
    return rc;
}

/* The outputs of an earlier run in the same folder go first, so a run that fails leaves none
   behind to be taken for its own. */
static void remove_outputs(const char *dir) {
    static const char *names[] = {"final.png", "indirect.pfm", "direct.pfm", "stats.json"};
    char path[4096];
    size_t k;
    for (k = 0; k < sizeof names / sizeof names[0]; ++k) {
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        remove(path);   /* absent: nothing to do */
    }
}

/* A scene with no triangles: black images, zero counts, and a warning. */
static int demo_black(demo_run *r, const char *why, char *err, size_t cap) {
    size_t npx = (size_t)r->o.width * r->o.height;
    float *zero = (float *)calloc(npx * 3, sizeof *zero);
    unsigned char *black = (unsigned char *)calloc(npx * 3, 1);
    int rc;
    if (!zero || !black) { free(zero); free(black); snprintf(err, cap, "out of memory"); return 1; }
    fprintf(stderr, PROG ": warning: %s: the images are black\n", why);
    r->renderer = "none (nothing to draw)";
    r->exposure = 1.0f;
    rc = write_outputs(r, zero, zero, black, err, cap);
    free(zero);
    free(black);
    return rc;
}

int main(int argc, char **argv) {
    demo_run r;
    char err[512] = "", **rest;
    int rest_count = 0, pr;
    uint32_t i;
    memset(&r, 0, sizeof r);
    demo_defaults(&r.d, 0);
    scene_options_defaults(&r.o, "out/demo");
    rest = (char **)calloc((size_t)argc + 1u, sizeof *rest);
    if (!rest) return 1;
    pr = demo_parse(argc, argv, 0, &r.d, rest, &rest_count, err, sizeof err);
    if (pr == 1) {
        fputs("usage: gimany-demo [options]\n", stdout);
        fputs(demo_usage_text, stdout);
        fputs(demo_usage_text2, stdout);
        fputs("  --frames N            frames to render; timings are medians over them (default 3)\n", stdout);
        fputs(scene_usage(0), stdout);
        free(rest);
        return 0;
    }
    if (pr == 0) pr = scene_parse_args(rest_count, rest, 0, &r.o, err, sizeof err) == SCENE_ARGS_OK ? 0 : -1;
    free(rest);
    if (pr != 0) { fprintf(stderr, PROG ": %s\n", err); return 2; }
    remove_outputs(r.o.out_dir);
    if (demo_bounces_unavailable(&r.d, r.o.bounces)) {
        fprintf(stderr, PROG ": --bounces %d %s\n", r.o.bounces, demo_bounces_unavailable(&r.d, r.o.bounces));
        return 2;
    }
    pr = scene_load(&r.o, &r.s, err, sizeof err);
    if (pr == SCENE_NO_TRIANGLES) { /* loads, but nothing to draw: black, with a warning */
        char why[512];
        memcpy(why, err, sizeof why);
        pr = demo_black(&r, why, err, sizeof err);
        if (pr != 0) fprintf(stderr, PROG ": %s\n", err);
        else printf("wrote %s/final.png, indirect.pfm, direct.pfm, stats.json (black)\n", r.o.out_dir);
        return pr != 0;
    }
    if (pr != 0) { fprintf(stderr, PROG ": %s\n", err); return 1; }
    if (r.s.warning_count) fprintf(stderr, PROG ": warning: %s\n", r.s.warning);
    for (i = 0; i < r.s.mesh_count; ++i) r.triangles += r.s.meshes[i].triangle_count;
    if (!r.d.glossy)
        for (i = 0; i < r.s.material_count; ++i) memset(r.s.materials[i].glossy, 0, sizeof r.s.materials[i].glossy);
    pr = r.triangles == 0 ? demo_black(&r, "the scene has no triangles", err, sizeof err) : demo_render(&r, err, sizeof err);
    if (pr != 0) fprintf(stderr, PROG ": %s\n", err);
    else print_table(&r);
    scene_free(&r.s);
    return pr != 0;
}
