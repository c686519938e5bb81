/* GL pass timings (medians, wall time around glFinish) on whatever EGL gives: llvmpipe in CI,
   where only ratios within one run mean anything. Also the case for the double scan of eq. 12:
   the same three shaders with double replaced by float, timed, and the error they make. */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include <time.h>

#define RUNS 7





static GLuint texture_rgba32f(int w, int h, const float *t) {
    GLuint tex = 0;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, w, h);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGBA, GL_FLOAT, t);
    glBindTexture(GL_TEXTURE_2D, 0);
    return tex;
}

/* A copy of src with every "double" made "float" and the LF suffixes dropped. */
static char *to_float_source(const char *src) {
    size_t n = strlen(src), i = 0, o = 0;
    char *out = (char *)malloc(n + 1);
    while (i < n) {
        if (strncmp(src + i, "double", 6) == 0) { memcpy(out + o, "float", 5); o += 5; i += 6; }
        else if (strncmp(src + i, "LF", 2) == 0 && i > 0 && src[i - 1] >= '0' && src[i - 1] <= '9') i += 2;
        else out[o++] = src[i++];
    }
    out[o] = 0;
    return out;
}

/* Swap the context's scan programs for float versions (1) or back (0). */
static void use_float_scan(gim_context *ctx, int on, GLuint saved[3]) {
    static const gim__program_id ids[3] = {GIM__PROGRAM_SCAN_COLUMNS, GIM__PROGRAM_SCAN_TOTALS, GIM__PROGRAM_SCAN_OFFSETS};
    int k;
    for (k = 0; k < 3; ++k) {
        if (on) {
            gim__shader_stage st;
            char *src = to_float_source(gim__embedded_source(gim__program_files[ids[k]][0]));
            GLuint p = 0;
            st.type = GIM__GL_COMPUTE_SHADER;
            st.name = gim__program_files[ids[k]][0];
            st.source = src;
            if (gim__gl_build_program(ctx, "float scan", &st, 1, &p) != GIM_OK) { fprintf(stderr, "float scan\n"); exit(1); }
            free(src);
            saved[k] = ctx->programs[ids[k]];
            ctx->programs[ids[k]] = p;
        } else {
            glDeleteProgram(ctx->programs[ids[k]]);
            ctx->programs[ids[k]] = saved[k];
        }
    }
}

/* Median ms of the scan at w x h; float_scan: with the float shaders (buffers sized alike). */
static double time_scan(gim_context *ctx, uint32_t w, uint32_t h, const float *map) {
    double t[RUNS];
    GLuint bm = gltest_ssbo((size_t)w * h * 4, map), bc = gltest_ssbo((size_t)w * h * 8, NULL), br = gltest_ssbo((size_t)w * 8, NULL);
    int r;
    gim__gl_importance_cumsum(ctx, bm, bc, br, w, h, 0); /* warm: programs, scratch */
    glFinish();
    for (r = 0; r < RUNS; ++r) {
        double t0 = now_ms();
        gim__gl_importance_cumsum(ctx, bm, bc, br, w, h, 0);
        glFinish();
        t[r] = now_ms() - t0;
    }
    glDeleteBuffers(1, &bm);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    return median(t, RUNS);
}

/* Of the texels of one w x h scan, how many get a selection frequency (the difference of the
   table) more than 1% away from their map value: the bias a float table would bring. */
static void float_scan_error(gim_context *ctx, uint32_t w, uint32_t h, const float *map) {
    GLuint bm = gltest_ssbo((size_t)w * h * 4, map), bc = gltest_ssbo((size_t)w * h * 8, NULL), br = gltest_ssbo((size_t)w * 8, NULL);
    float *col = (float *)malloc((size_t)w * h * 4);
    size_t bad = 0, x, y;
    gim__gl_importance_cumsum(ctx, bm, bc, br, w, h, 0);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, bc);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, (GLsizeiptr)w * h * 4, col);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    for (x = 0; x < w; ++x)
        for (y = 1; y < h; ++y) {
            double d = (double)col[y * w + x] - col[(y - 1) * w + x], m = map[y * w + x];
            if (fabs(d - m) > 0.01 * m) ++bad;
        }
    printf("float scan %ux%u: %zu of %zu texels (%.1f%%) would be selected >1%% off their importance\n",
           (unsigned)w, (unsigned)h, bad, (size_t)w * (h - 1), 100.0 * (double)bad / ((double)w * (h - 1)));
    glDeleteBuffers(1, &bm);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    free(col);
}

int main(void) {
    gim_desc d;
    gim_context *ctx = NULL;
    uint32_t sizes[2] = {512, 1024};
    float *map;
    size_t i;
    int k;
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_gl: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    printf("renderer: %s\n", (const char *)glGetString(GL_RENDERER));
    map = (float *)malloc(sizeof(float) * 1024 * 1024);
    for (i = 0; i < 1024 * 1024; ++i) map[i] = (float)test_rand01();

    /* eq. 12: double (what gimany runs) against the float variant */
    for (k = 0; k < 2; ++k) {
        GLuint saved[3];
        uint32_t s = sizes[k];
        double td = time_scan(ctx, s, s, map), tf;
        use_float_scan(ctx, 1, saved);
        tf = time_scan(ctx, s, s, map);
        if (k == 1) float_scan_error(ctx, s, s, map);
        use_float_scan(ctx, 0, saved);
        printf("cumsum %ux%u: double %.2f ms, float %.2f ms (median of %d), ratio %.2f\n", (unsigned)s, (unsigned)s, td, tf,
               RUNS, td / tf);
    }

    /* eq. 10-11: 128x128 RSM x 64 view samples (1M interactions) */
    {
        enum { W = 128, H = 128, S = 64 };
        float *tex = (float *)malloc(sizeof(float) * W * H * 4), vs[S * 8];
        GLuint tp, tn, tf, bvs, bm;
        double t[RUNS], med;
        int r;
        for (i = 0; i < W * H; ++i) {
            tex[i * 4] = (float)(i % W); tex[i * 4 + 1] = 0.0f; tex[i * 4 + 2] = (float)(i / W); tex[i * 4 + 3] = 1.0f;
        }
        tp = texture_rgba32f(W, H, tex);
        for (i = 0; i < W * H; ++i) { tex[i * 4] = 0.0f; tex[i * 4 + 1] = 1.0f; tex[i * 4 + 2] = 0.0f; }
        tn = texture_rgba32f(W, H, tex);
        for (i = 0; i < W * H * 4; ++i) tex[i] = 0.5f;
        tf = texture_rgba32f(W, H, tex);
        for (i = 0; i < S; ++i) {
            vs[i * 8] = (float)(test_rand01() * W); vs[i * 8 + 1] = 20.0f; vs[i * 8 + 2] = (float)(test_rand01() * H);
            vs[i * 8 + 4] = 0.0f; vs[i * 8 + 5] = -1.0f; vs[i * 8 + 6] = 0.0f;
        }
        bvs = gltest_ssbo(sizeof vs, vs);
        bm = gltest_ssbo(sizeof(float) * W * H, NULL);
        gim__gl_importance_map(ctx, tp, tn, tf, W, H, bvs, S, 180.0f, 0.0f, bm);
        glFinish();
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim__gl_importance_map(ctx, tp, tn, tf, W, H, bvs, S, 180.0f, 0.0f, bm);
            glFinish();
            t[r] = now_ms() - t0;
        }
        med = median(t, RUNS);
        printf("importance map %dx%d x %d view samples: %.2f ms (median of %d), %.3f G interactions/s\n", W, H, S, med,
               RUNS, (double)W * H * S / (med * 1e6));
        glDeleteTextures(1, &tp);
        glDeleteTextures(1, &tn);
        glDeleteTextures(1, &tf);
        glDeleteBuffers(1, &bvs);
        glDeleteBuffers(1, &bm);
        free(tex);
    }

    /* selection: 4096 VALs from 1024x1024 tables */
    {
        enum { W = 1024, H = 1024, N = 4096 };
        GLuint bm = gltest_ssbo((size_t)W * H * 4, map), bc = gltest_ssbo((size_t)W * H * 8, NULL), br = gltest_ssbo(W * 8, NULL),
               bo = gltest_ssbo(N * 12, NULL);
        double t[RUNS];
        int r;
        gim__gl_importance_cumsum(ctx, bm, bc, br, W, H, 0);
        gim__gl_importance_select(ctx, bc, br, W, H, N, 0, bo);
        glFinish();
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim__gl_importance_select(ctx, bc, br, W, H, N, (uint32_t)r, bo);
            glFinish();
            t[r] = now_ms() - t0;
        }
        printf("select %d VALs from %dx%d: %.2f ms (median of %d)\n", N, W, H, median(t, RUNS), RUNS);
        glDeleteBuffers(1, &bm);
        glDeleteBuffers(1, &bc);
        glDeleteBuffers(1, &br);
        glDeleteBuffers(1, &bo);
    }
    /* LightSkin proxy lights (Bischoff 2017 eq. 3-7, 13-15): 5000 caches against BRSM's 2048 VALs
       and against FULL LightSkin's 128^2 = 16384; the cost is caches x VALs, so ~8x */
    {
        enum { C = 5000, NV = 16384 };
        gim_cache *caches = (gim_cache *)calloc(C, sizeof *caches);
        gim_val *vals = (gim_val *)calloc(NV, sizeof *vals);
        GLuint bc, bv, bd = gltest_ssbo((size_t)C * 48, NULL), bg = gltest_ssbo((size_t)C * 48, NULL);
        uint32_t counts[2] = {2048, NV};
        double med[2][2];
        int g, r;
        for (i = 0; i < C; ++i) { /* caches on a 10 x 10 floor, facing up */
            caches[i].position[0] = (float)(test_rand01() * 10.0);
            caches[i].position[2] = (float)(test_rand01() * 10.0);
            caches[i].normal[1] = 1.0f;
            caches[i].area = 0.02f;
        }
        for (i = 0; i < NV; ++i) { /* VALs on a back wall z = 0 */
            vals[i].position[0] = (float)(test_rand01() * 10.0);
            vals[i].position[1] = (float)(test_rand01() * 10.0);
            vals[i].normal[2] = 1.0f;
            vals[i].area = 100.0f / NV;
            vals[i].weight = 1.0f;
            vals[i].flux[0] = vals[i].flux[1] = vals[i].flux[2] = (float)test_rand01();
        }
        bc = gltest_ssbo((size_t)C * sizeof *caches, caches);
        bv = gltest_ssbo((size_t)NV * sizeof *vals, vals);
        for (k = 0; k < 2; ++k)
            for (g = 0; g < 2; ++g) {
                double t[RUNS];
                gim__gl_proxy_lights(ctx, bc, C, bv, counts[k], gim_v3(5.0f, 5.0f, 20.0f), 20.0f, 0u, 15.0f, bd, g ? bg : 0);
                glFinish();
                for (r = 0; r < RUNS; ++r) {
                    double t0 = now_ms();
                    gim__gl_proxy_lights(ctx, bc, C, bv, counts[k], gim_v3(5.0f, 5.0f, 20.0f), 20.0f, 0u, 15.0f, bd, g ? bg : 0);
                    glFinish();
                    t[r] = now_ms() - t0;
                }
                med[k][g] = median(t, RUNS);
                printf("proxy lights %d caches x %u VALs, %s: %.2f ms (median of %d), %.3f G interactions/s\n", C,
                       (unsigned)counts[k], g ? "diffuse + glossy" : "diffuse", med[k][g], RUNS,
                       (double)C * counts[k] / (med[k][g] * 1e6));
            }
        printf("proxy lights FULL 128^2 / BRSM 2048: %.2fx (diffuse), %.2fx (diffuse + glossy)\n", med[1][0] / med[0][0],
               med[1][1] / med[0][1]);
        glDeleteBuffers(1, &bc);
        glDeleteBuffers(1, &bv);
        glDeleteBuffers(1, &bd);
        glDeleteBuffers(1, &bg);
        free(caches);
        free(vals);
    }

    free(map);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
