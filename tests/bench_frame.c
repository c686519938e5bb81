/* The main method's trade (paper 000 Fig. 3 and 5): whole gim_update frames of LightSkin +
   BRSM against LightSkin FULL at equal settings, side by side in one run, on the procedural
   street (the paper's open-world case) lit by its sun: RSM 256^2, 512^2, 1024^2; 2048, 4096,
   8192 VALs; 256 and 512 view samples. Per configuration: the median frame time (wall clock
   around gim_update + glFinish), the per-pass GPU times of the median frame's configuration
   (GL timestamps), the FULL : BRSM ratio and the mean relative difference of the indirect
   image to FULL's. On llvmpipe only the ratios mean anything.
   Usage: bench_frame [max_rsm] (default 1024; CI-sized machines may pass 512). */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 320
#define H 180

static double frame_ms(gim_context *ctx, const gim_frame *f, int runs, gim_stats *st) {
    double t[9];
    int r;
    gim_frame timed = *f;
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

static double mean_rel_diff(const float *a, const float *b) {
    double d = 0.0, m = 0.0;
    int i, c;
    for (i = 0; i < W * H; ++i) {
        if (b[i * 4 + 3] != 1.0f) continue;
        for (c = 0; c < 3; ++c) { d += fabs((double)a[i * 4 + c] - b[i * 4 + c]); m += b[i * 4 + c]; }
    }
    return m > 0.0 ? d / m : 0.0;
}

int main(int argc, char **argv) {
    static const uint32_t rsm_sizes[3] = {256, 512, 1024}, val_counts[3] = {2048, 4096, 8192}, vs_counts[2] = {256, 512};
    uint32_t max_rsm = argc > 1 ? (uint32_t)atoi(argv[1]) : 1024u;
    gim_desc d;
    gim_context *ctx = NULL;
    scene s;
    scene_gimany g;
    gim_frame f;
    gim_stats st;
    char err[256];
    float *full = (float *)malloc(W * H * 16), *img = (float *)malloc(W * H * 16);
    int ri, vi, si;
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_frame: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env.logger.func = gim_log_stderr;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    if (scene_builtin("street", &s, err, sizeof err)) { fprintf(stderr, "%s\n", err); return 1; }
    s.camera.width = W;
    s.camera.height = H;
    if (scene_gimany_load(ctx, &s, 1.0f / 32.0f, 256, d.env, &g) != GIM_OK) return 1;
    memset(&f, 0, sizeof f);
    scene_gimany_camera(&s, &f.view, &f.proj);
    f.width = W;
    f.height = H;
    printf("renderer: %s\n", (const char *)glGetString(GL_RENDERER));
    {
        uint32_t tris = 0, m;
        for (m = 0; m < s.mesh_count; ++m) tris += s.meshes[m].triangle_count;
        printf("scene: street, %u triangles, %u caches, %ux%u pixels, sun\n", tris, g.cache_count, W, H);
    }
    printf("| RSM | method | VALs | view samples | frame ms (median) | FULL : this | mean rel. diff to FULL | importance ms | proxy ms | shade ms |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|\n");
    for (ri = 0; ri < 3 && rsm_sizes[ri] <= max_rsm; ++ri) {
        double t_full;
        int runs = rsm_sizes[ri] >= 1024 ? 3 : 5;
        g.lights[0].rsm_size = rsm_sizes[ri];
        gim_set_lights(ctx, g.lights, g.light_count);
        f.method = GIM_METHOD_LIGHTSKIN_FULL;
        t_full = frame_ms(ctx, &f, runs, &st);
        read_image(ctx, full);
        printf("| %u^2 | FULL | %u | - | %.1f | 1.0 | 0 | - | %.1f | %.1f |\n", rsm_sizes[ri], st.val_count, t_full,
               st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE]);
        fflush(stdout);
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        for (vi = 0; vi < 3; ++vi)
            for (si = 0; si < 2; ++si) {
                double t;
                f.val_count = val_counts[vi];
                f.view_sample_count = vs_counts[si];
                t = frame_ms(ctx, &f, runs, &st);
                read_image(ctx, img);
                printf("| %u^2 | BRSM | %u | %u | %.1f | %.1f | %.4f | %.1f | %.1f | %.1f |\n", rsm_sizes[ri], val_counts[vi],
                       vs_counts[si], t, t_full / t, mean_rel_diff(img, full),
                       st.pass_ms[GIM_PASS_IMPORTANCE_MAP] + st.pass_ms[GIM_PASS_CUMSUM] + st.pass_ms[GIM_PASS_SELECT],
                       st.pass_ms[GIM_PASS_PROXY_LIGHTS], st.pass_ms[GIM_PASS_SHADE]);
                fflush(stdout);
            }
    }
    printf("GPU memory of the last frame: %.1f MiB\n", (double)st.gpu_bytes / 1048576.0);
    scene_gimany_free(ctx, &g);
    scene_free(&s);
    gim_destroy(ctx);
    free(full);
    free(img);
    gltest_shutdown();
    return 0;
}
