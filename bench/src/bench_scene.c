/* The shared passes of the frame (RSM, G-buffer, view samples) and a whole gim_update, medians
   of wall time around glFinish, on whatever EGL gives (llvmpipe in CI: only ratios within one
   run mean anything). Scene: a floor and 64 boxes (641 triangles), one sun. */
#define _POSIX_C_SOURCE 199309L
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include <time.h>

#define RUNS 5

static double now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}
static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}
static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return v[n / 2];
}

static const float quad[12] = {-10, 0, -10, -10, 0, 10, 10, 0, 10, 10, 0, -10};
static const uint32_t quad_idx[6] = {0, 1, 2, 0, 2, 3};

static void box(float *p, uint32_t *idx) {
    static const int f[5][4][3] = {{{-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}, {1, 1, -1}},
                                   {{-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}},
                                   {{1, -1, -1}, {-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}},
                                   {{1, -1, 1}, {1, -1, -1}, {1, 1, -1}, {1, 1, 1}},
                                   {{-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}}};
    int i, v, k;
    for (i = 0; i < 5; ++i) {
        for (v = 0; v < 4; ++v)
            for (k = 0; k < 3; ++k) p[(i * 4 + v) * 3 + k] = (float)f[i][v][k];
        idx[i * 6] = (uint32_t)i * 4; idx[i * 6 + 1] = (uint32_t)i * 4 + 1; idx[i * 6 + 2] = (uint32_t)i * 4 + 2;
        idx[i * 6 + 3] = (uint32_t)i * 4; idx[i * 6 + 4] = (uint32_t)i * 4 + 2; idx[i * 6 + 5] = (uint32_t)i * 4 + 3;
    }
}

int main(void) {
    static const uint32_t rsm_sizes[] = {256, 512};
    gim_desc d;
    gim_context *ctx;
    gim_mesh_desc md;
    gim_mesh floor_mesh, box_mesh;
    gim_material m;
    gim_instance inst[65];
    gim_light sun;
    gim_frame fr;
    float bp[60];
    uint32_t bi[30];
    double t[RUNS];
    int i, r;
    size_t s;
    if (!gltest_init()) { printf("bench_scene: no GL (%s)\n", gltest.why); return 0; }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    memset(&md, 0, sizeof md);
    md.data.positions = quad; md.data.vertex_count = 4; md.data.indices = quad_idx; md.data.index_count = 6;
    gim_add_mesh(ctx, &md, &floor_mesh);
    box(bp, bi);
    md.data.positions = bp; md.data.vertex_count = 20; md.data.indices = bi; md.data.index_count = 30;
    gim_add_mesh(ctx, &md, &box_mesh);
    memset(&m, 0, sizeof m);
    m.diffuse[0] = m.diffuse[1] = m.diffuse[2] = 0.6f;
    gim_set_materials(ctx, &m, 1);
    inst[0].mesh = floor_mesh;
    inst[0].model = gim_mat4_identity();
    for (i = 0; i < 64; ++i) {
        gim_mat4 mm = gim_mat4_identity();
        mm.m[0] = 0.5f; mm.m[5] = 0.3f + 0.1f * (float)(i % 5); mm.m[10] = 0.5f;
        mm.m[12] = -7.0f + 2.0f * (float)(i % 8); mm.m[13] = mm.m[5]; mm.m[14] = -7.0f + 2.0f * (float)(i / 8);
        inst[i + 1].mesh = box_mesh;
        inst[i + 1].model = mm;
    }
    gim_set_instances(ctx, inst, 65);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim_v3(8.0f, 6.0f, 12.0f), gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(1.0f, 16.0f / 9.0f, 0.5f, 60.0f);
    fr.width = 320;
    fr.height = 180;
    fr.lightskin.view_sample_count = 256;
    fr.lightskin.val_count = 1024;
    printf("bench_scene (%s): floor + 64 boxes, G-buffer %ux%u, %u view samples, %u VALs; median of %d, ms\n",
           (const char *)glGetString(GL_RENDERER), fr.width, fr.height, fr.lightskin.view_sample_count, fr.lightskin.val_count, RUNS);
    for (s = 0; s < sizeof rsm_sizes / sizeof rsm_sizes[0]; ++s) {
        float bmin[3], bmax[3], fmin[3], fmax[3];
        gim_light fitted;
        gim_fit_view_desc fd;
        memset(&sun, 0, sizeof sun);
        sun.irradiance = 3.0f;
        sun.direction = gim_v3(0.3f, 1.0f, 0.2f);
        sun.rsm_size = rsm_sizes[s];
        gim_set_lights(ctx, &sun, 1);
        if (gim_update(ctx, &fr) != GIM_OK) return 1; /* warm: programs, textures */
        glFinish();
        memcpy(bmin, gim_outputs(ctx).bounds_min, sizeof bmin);
        memcpy(bmax, gim_outputs(ctx).bounds_max, sizeof bmax);
        /* the light as gim_update renders it (fitted to the view) */
        memset(&fd, 0, sizeof fd);
        fd.light = &sun; fd.scene_min = bmin; fd.scene_max = bmax;
        fd.view = fr.view; fd.proj = fr.proj; fd.view_distance = fr.view_distance;
        if (gim_light_fit_view(&fd, &fitted, fmin, fmax) != GIM_OK) return 1;
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim__gl_enter(ctx, "bench");
            gim__gl_rsm(ctx, 0, &fitted, fmin, fmax);
            gim__gl_leave(ctx, GIM_OK);
            glFinish();
            t[r] = now_ms() - t0;
        }
        printf("  RSM %4u^2                 %8.2f\n", rsm_sizes[s], median(t, RUNS));
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim_update(ctx, &fr);
            glFinish();
            t[r] = now_ms() - t0;
        }
        printf("  gim_update, RSM %4u^2     %8.2f\n", rsm_sizes[s], median(t, RUNS));
    }
    for (r = 0; r < RUNS; ++r) {
        double t0 = now_ms();
        gim__gl_enter(ctx, "bench");
        gim__gl_gbuffer(ctx, &fr);
        gim__gl_leave(ctx, GIM_OK);
        glFinish();
        t[r] = now_ms() - t0;
    }
    printf("  G-buffer %ux%u           %8.2f\n", fr.width, fr.height, median(t, RUNS));
    for (r = 0; r < RUNS; ++r) {
        double t0 = now_ms();
        gim__gl_enter(ctx, "bench");
        gim__gl_view_samples(ctx, &fr, gim_outputs(ctx).gbuffer_depth, gim_outputs(ctx).gbuffer_normal, 256);
        gim__gl_leave(ctx, GIM_OK);
        glFinish();
        t[r] = now_ms() - t0;
    }
    printf("  view samples (256)         %8.2f\n", median(t, RUNS));
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
