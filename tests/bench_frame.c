/* The main method's trade (paper 000 Fig. 3 and 5): whole gim_update frames of LightSkin +
   BRSM against LightSkin FULL at equal settings, side by side in one run, on the procedural
   street (the paper's open-world case) lit by its sun: RSM 256^2, 512^2, 1024^2; 2048, 4096,
   8192 VALs; 256 and 512 view samples. Per configuration: the median frame time (wall clock
   around gim_update + glFinish) and RSM gather (the baseline) at each RSM size, the per-pass
   GPU times of the median frame's configuration
   (GL timestamps), the FULL : BRSM ratio and the mean relative difference of the indirect
   image to FULL's. On llvmpipe only the ratios mean anything.
   Usage: bench_frame [max_rsm] (default 1024; CI-sized machines may pass 512). */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"
#define COMPARE_NO_MAIN
#include "../tools/compare.c"

#define W 320
#define H 180
#define REF_SPP 1024
#define CORNELL_GLTF "../shared/scenes/cornell_box/CornellBox.gltf"
#define SPONZA_GLB "../shared/scenes/sponza_lod4/sponza_lod4.glb"

static double frame_ms(gim_context *ctx, const gim_frame *f, int runs, gim_stats *st) {
    double t[9];
    int r;
    gim_frame timed = *f;
    if (runs < 0) {   /* one frame, timed per pass (GL timestamps), no warm-up: the caller made one */
        double t0 = now_ms();
        timed.timing = 1;
        if (gim_update(ctx, &timed) != GIM_OK) { fprintf(stderr, "gim_update failed\n"); exit(1); }
        glFinish();
        t[0] = now_ms() - t0;
        gim_frame_stats(ctx, st);
        return t[0];
    }
    if (gim_update(ctx, f) != GIM_OK) { fprintf(stderr, "gim_update failed\n"); exit(1); }   /* warm-up */
    glFinish();
    for (r = 0; r < runs; ++r) {
        double t0 = now_ms();
        gim_update(ctx, f);
        glFinish();
        t[r] = now_ms() - t0;
    }
    timed.timing = 2;   /* one more, timed per pass (glFinish between passes: llvmpipe runs queued work at flushes) */
    gim_update(ctx, &timed);
    gim_frame_stats(ctx, st);
    return median(t, runs);
}

static void read_image(gim_context *ctx, float *rgba) {
    gltest_read_texture(gim_outputs(ctx).indirect, GL_RGBA, rgba);
}

/* rel. MAE of the indirect image (RGBA, GL rows bottom first) against the reference (RGB, top
   row first); -1 without a reference */
static double error_vs(const float *rgba, const float *ref) {
    static float rgb[W * H * 3];
    compare_result r;
    int x, y, c;
    if (!ref) return -1.0;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x)
            for (c = 0; c < 3; ++c) rgb[(y * W + x) * 3 + c] = rgba[((H - 1 - y) * W + x) * 4 + c];
    compare_images(rgb, ref, W, H, &r, NULL);
    return r.rel_mae;
}

static double mean_rel_diff(const float *a, const float *b) {
    double d = 0.0, m = 0.0;
    int i, c;
    for (i = 0; i < W * H; ++i) {
        if (b[i * 4 + 3] != 1.0f) continue;
        for (c = 0; c < 3; ++c) { d += fabs((double)a[i * 4 + c] - b[i * 4 + c]); m += b[i * 4 + c]; }
    }
    return m > 0.0 ? d / m : 0.0;
}

/* Temporal flicker (issue 7): K frames while the sun turns by STEP_DEG about the vertical per
   frame; the mean absolute frame-to-frame change of the image over its mean. FULL has no
   sampling noise, so its change is what the moving light itself causes; a method's flicker is
   its change minus FULL's. The reference's own change would need far more paths per pixel
   than its noise allows at this step. */
#define FLICKER_FRAMES 8
static FILE *csv;   /* bench/results.csv: one row per configuration */
#define STEP_DEG 0.25
static double image_change(gim_context *ctx, scene_gimany *g, gim_frame f) {
    static float prev[W * H * 4], cur[W * H * 4];
    gim_vec3 d0 = g->lights[0].direction;
    double change = 0.0;
    int k, i;
    for (k = 0; k < FLICKER_FRAMES; ++k) {
        double a = k * STEP_DEG * 3.14159265358979 / 180.0, num = 0.0, den = 0.0;
        g->lights[0].direction = gim_v3((float)(cos(a) * d0.x + sin(a) * d0.z), d0.y, (float)(-sin(a) * d0.x + cos(a) * d0.z));
        gim_set_lights(ctx, g->lights, g->light_count);
        f.frame_index = (uint32_t)k + 1u;
        f.rotate_view_samples = 1;
        gim_update(ctx, &f);
        read_image(ctx, cur);
        if (k > 0) {
            for (i = 0; i < W * H * 4; ++i)
                if (i % 4 != 3) { num += fabs((double)cur[i] - prev[i]); den += cur[i]; }
            change += den > 0.0 ? num / den : 0.0;
        }
        memcpy(prev, cur, sizeof cur);
    }
    g->lights[0].direction = d0;
    gim_set_lights(ctx, g->lights, g->light_count);
    return change / (FLICKER_FRAMES - 1);
}

/* The renderer's name without commas (a CSV field). */
static const char *renderer_name(void) {
    static char name[256];
    const char *r = (const char *)glGetString(GL_RENDERER);
    size_t i;
    snprintf(name, sizeof name, "%s", r ? r : "?");
    for (i = 0; name[i]; ++i) if (name[i] == ',') name[i] = ';';
    return name;
}

/* One scene's sweep: FULL, RSM gather and BRSM at each RSM size up to max_rsm, each against
   FULL and against the reference; the flicker figures when flicker is set. source: a built-in
   name or a glTF path. */
static void bench_scene(gim_context *ctx, gim_env env, const char *name, const char *source, uint32_t max_rsm,
                        int flicker) {
    static const uint32_t rsm_sizes[3] = {256, 512, 1024}, val_counts[3] = {2048, 4096, 8192}, vs_counts[2] = {256, 512};
    scene s;
    scene_gimany g;
    gim_frame f;
    gim_stats st;
    char err[256];
    float *full = (float *)malloc(W * H * 16), *img = (float *)malloc(W * H * 16), *ref = NULL;
    int ri, vi, si, builtin = strchr(source, '.') == NULL;
    memset(&st, 0, sizeof st);
    if ((builtin ? scene_builtin(source, &s, err, sizeof err) : scene_load_gltf(source, &s, err, sizeof err)) != 0) {
        printf("scene %s: %s (skipped)\n", name, err);
        free(full); free(img);
        return;
    }
    s.camera.width = W;
    s.camera.height = H;
    if (scene_gimany_load(ctx, &s, 1.0f / 32.0f, 256, env, &g) != GIM_OK || g.light_count == 0) {
        printf("scene %s: no caches or no light (skipped)\n", name);
        scene_gimany_free(ctx, &g);
        scene_free(&s);
        free(full); free(img);
        return;
    }
    memset(&f, 0, sizeof f);
    scene_gimany_camera(&s, &f.view, &f.proj);
    f.width = W;
    f.height = H;
    {
        uint32_t tris = 0, m;
        for (m = 0; m < s.mesh_count; ++m) tris += s.meshes[m].triangle_count;
        printf("\nscene: %s (%s), %u triangles, %u caches, %ux%u pixels, %u light(s)\n", name, source, tris, g.cache_count, W,
               H, g.light_count);
    }
    {   /* the ground truth of the same view (Embree, tools/reference), when it is built */
        FILE *fp = fopen("build/gimany-reference", "rb");
        char cmd[1024];
        uint32_t rw, rh;
        if (fp) {
            fclose(fp);
            snprintf(cmd, sizeof cmd, "build/gimany-reference --scene %s --size %dx%d --spp %d --out build/bench_frame_ref_%s >/dev/null",
                     source, W, H, REF_SPP, name);
            snprintf(err, sizeof err, "build/bench_frame_ref_%s/reference.pfm", name);
            if (system(cmd) == 0 && scene_read_pfm(err, &ref, &rw, &rh, err, sizeof err) == 0 && rw == W && rh == H)
                printf("reference: build/gimany-reference, %d paths per pixel\n", REF_SPP);
            else { free(ref); ref = NULL; }
        }
        if (!ref) printf("reference: none (make reference builds it)\n");
    }
    printf("| RSM | method | VALs | view samples | frame ms (median) | FULL : this | mean rel. diff to FULL | rel. MAE vs reference | importance ms | proxy ms | shade ms |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (ri = 0; ri < 3 && rsm_sizes[ri] <= max_rsm; ++ri) {
        double t_full;
        int runs = 3;
        g.lights[0].rsm_size = rsm_sizes[ri];
        gim_set_lights(ctx, g.lights, g.light_count);
        /* FULL once (a frame at 1024^2 takes minutes on llvmpipe), after a BRSM frame at this
           size has built every program and buffer FULL shares */
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        f.val_count = 2048;
        gim_update(ctx, &f);
        f.method = GIM_METHOD_LIGHTSKIN_FULL;
        t_full = frame_ms(ctx, &f, -1, &st);
        read_image(ctx, full);
        printf("| %u^2 | FULL | %u | - | %.1f | 1.0 | 0 | %.3f | - | %.1f | %.1f |\n", rsm_sizes[ri], st.val_count, t_full,
               error_vs(full, ref), st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE]);
        if (csv)
            fprintf(csv, "%s,full,%u,%u,0,%.2f,1,0,%.5f,0,%.2f,%.2f,,%s\n", name, rsm_sizes[ri], st.val_count, t_full,
                    error_vs(full, ref), st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE], renderer_name());
        fflush(stdout);
        {   /* the baseline at the same RSM: RSM gather, 256 samples over 0.15 of the RSM */
            double t;
            f.method = GIM_METHOD_RSM_GATHER;
            f.gather_samples = 256;
            t = frame_ms(ctx, &f, runs, &st);
            read_image(ctx, img);
            printf("| %u^2 | gather | 256 | - | %.1f | %.1f | %.4f | %.3f | - | - | %.1f |\n", rsm_sizes[ri], t, t_full / t,
                   mean_rel_diff(img, full), error_vs(img, ref), st.pass_ms[GIM_PASS_SHADE]);
            if (csv)
                fprintf(csv, "%s,gather,%u,256,0,%.2f,%.3f,%.5f,%.5f,0,0,%.2f,,%s\n", name, rsm_sizes[ri], t, t_full / t,
                        mean_rel_diff(img, full), error_vs(img, ref), st.pass_ms[GIM_PASS_SHADE], renderer_name());
        }
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        for (vi = 0; vi < 3; ++vi)
            for (si = 0; si < 2; ++si) {
                double t;
                f.val_count = val_counts[vi];
                f.view_sample_count = vs_counts[si];
                t = frame_ms(ctx, &f, runs, &st);
                read_image(ctx, img);
                printf("| %u^2 | BRSM | %u | %u | %.1f | %.1f | %.4f | %.3f | %.1f | %.1f | %.1f |\n", rsm_sizes[ri], val_counts[vi],
                       vs_counts[si], t, t_full / t, mean_rel_diff(img, full), error_vs(img, ref),
                       st.pass_ms[GIM_PASS_IMPORTANCE_MAP] + st.pass_ms[GIM_PASS_CUMSUM] + st.pass_ms[GIM_PASS_SELECT],
                       st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE]);
                if (csv)
                    fprintf(csv, "%s,brsm,%u,%u,%u,%.2f,%.3f,%.5f,%.5f,%.2f,%.2f,%.2f,,%s\n", name, rsm_sizes[ri], val_counts[vi],
                            vs_counts[si], t, t_full / t, mean_rel_diff(img, full), error_vs(img, ref),
                            st.pass_ms[GIM_PASS_IMPORTANCE_MAP] + st.pass_ms[GIM_PASS_CUMSUM] + st.pass_ms[GIM_PASS_SELECT],
                            st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE], renderer_name());
                fflush(stdout);
            }
    }
    printf("GPU memory of the last frame: %.1f MiB\n", (double)st.gpu_bytes / 1048576.0);
    if (flicker) {   /* at RSM 256^2 */
        double c_full, c;
        static const uint32_t fv[3] = {2048, 4096, 8192};
        int k;
        g.lights[0].rsm_size = 256;
        f.method = GIM_METHOD_LIGHTSKIN_FULL;
        c_full = image_change(ctx, &g, f);
        printf("flicker (sun turning %.2f deg a frame, %d frames, RSM 256^2): FULL's own change %.4f of the mean; "
               "BRSM minus FULL:", STEP_DEG, FLICKER_FRAMES, c_full);
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        f.view_sample_count = 256;
        for (k = 0; k < 3; ++k) {
            f.val_count = fv[k];
            c = image_change(ctx, &g, f);
            printf(" %u VALs %.4f;", fv[k], c - c_full);
            if (csv) fprintf(csv, "%s,brsm-flicker,256,%u,256,,,,,,,,%.5f,%s\n", name, fv[k], c - c_full, renderer_name());
        }
        printf("\n");
        if (csv) fprintf(csv, "%s,full-change,256,65536,0,,,,,,,,%.5f,%s\n", name, c_full, renderer_name());
    }
    scene_gimany_free(ctx, &g);
    scene_free(&s);
    free(full);
    free(img);
    free(ref);
}

int main(int argc, char **argv) {
    uint32_t max_rsm = argc > 1 ? (uint32_t)atoi(argv[1]) : 1024u;
    gim_desc d;
    gim_context *ctx = NULL;
    char err[256];
    FILE *fp;
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_frame: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env.logger.func = gim_log_stderr;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    printf("renderer: %s\n", renderer_name());
    if (scene_make_dir("bench", err, sizeof err) == 0) csv = fopen("bench/results.csv", "w");
    if (csv)
        fprintf(csv, "scene,method,rsm,vals,view_samples,frame_ms,full_over_this,rel_diff_full,rel_mae_reference,"
                     "importance_ms,proxy_ms,shade_ms,flicker,renderer\n");
    bench_scene(ctx, d.env, "street", "street", max_rsm, 1);
    fp = fopen(CORNELL_GLTF, "rb");   /* the measured Cornell box when present, else the built-in one */
    if (fp) fclose(fp);
    bench_scene(ctx, d.env, "cornell", fp ? CORNELL_GLTF : "cornell", max_rsm < 512u ? max_rsm : 512u, 0);
    fp = fopen(SPONZA_GLB, "rb");
    if (fp) {
        fclose(fp);
        bench_scene(ctx, d.env, "sponza", SPONZA_GLB, 256u, 0);
    } else {
        printf("\nscene: sponza absent (%s): skipped\n", SPONZA_GLB);
    }
    if (csv) { fclose(csv); printf("wrote bench/results.csv\n"); }
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
