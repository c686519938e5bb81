/* The VAL gather (Bischoff 2017 sec. 3-4): GPU pass against its CPU twin gim_vals_gather_twin, FULL
   (every texel of a 512^2 and a 1024^2 RSM) and BRSM (2048 and 65536 selected). Medians of
   wall time around glFinish; on llvmpipe only the ratios within one run mean anything. */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define RUNS 7

static GLuint texture_rgba32f(int s, const float *t) {
    GLuint tex = 0;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, s, s);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, s, s, GL_RGBA, GL_FLOAT, t);
    glBindTexture(GL_TEXTURE_2D, 0);
    return tex;
}

int main(void) {
    static const int sizes[2] = {512, 1024};
    static const uint32_t selected[2] = {2048, 65536};
    gim_context *ctx = NULL;
    gim_desc desc;
    int si;
    if (!gltest_init()) {
        printf("bench_gather: no GL context (%s)\n", gltest.why);
        return 0;
    }
    memset(&desc, 0, sizeof desc);
    desc.get_proc_address = gltest_get_proc;
    if (gim_create(&desc, &ctx) != GIM_OK) return 1;
    for (si = 0; si < 2; ++si) {
        const int S = sizes[si];
        const size_t n = (size_t)S * S;
        float *p4 = (float *)malloc(n * 16), *n4 = (float *)malloc(n * 16), *f4 = (float *)malloc(n * 16);
        float *p3 = (float *)malloc(n * 12), *n3 = (float *)malloc(n * 12), *f3 = (float *)malloc(n * 12);
        float *area = (float *)malloc(n * 4), *valid = (float *)malloc(n * 4);
        gim_val *cpu = (gim_val *)malloc(n * sizeof(gim_val));
        gim_selected_val *sel = (gim_selected_val *)malloc(65536 * sizeof *sel);
        gim_rsm_data d;
        GLuint tex[3], out, bsel;
        double t[RUNS], gpu_full, cpu_full;
        size_t i;
        int r, k, a;
        for (i = 0; i < n; ++i) {
            for (a = 0; a < 3; ++a) {
                p4[i * 4 + a] = p3[i * 3 + a] = (float)test_rand01() * 10.0f;
                n4[i * 4 + a] = n3[i * 3 + a] = a == 1 ? 1.0f : 0.0f;
                f4[i * 4 + a] = f3[i * 3 + a] = (float)test_rand01();
            }
            p4[i * 4 + 3] = valid[i] = test_rand01() < 0.8 ? 1.0f : 0.0f;
            n4[i * 4 + 3] = area[i] = 1e-4f;
            f4[i * 4 + 3] = 0.0f;
        }
        for (i = 0; i < 65536; ++i) {
            sel[i].x = (uint32_t)(test_rand01() * S);
            sel[i].y = (uint32_t)(test_rand01() * S);
            sel[i].pdf = (float)(1.0 / (double)n);
        }
        memset(&d, 0, sizeof d);
        d.position = p3; d.normal = n3; d.flux = f3; d.area = area; d.valid = valid;
        d.width = d.height = (uint32_t)S;
        tex[0] = texture_rgba32f(S, p4);
        tex[1] = texture_rgba32f(S, n4);
        tex[2] = texture_rgba32f(S, f4);
        out = gltest_ssbo(n * sizeof(gim_val), NULL);
        bsel = gltest_ssbo(65536 * sizeof *sel, sel);
        if (gim__gl_vals_gather(ctx, tex[0], tex[1], tex[2], (uint32_t)S, 0, 0, out, 0) != GIM_OK) return 1; /* builds */
        glFinish();
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim__gl_vals_gather(ctx, tex[0], tex[1], tex[2], (uint32_t)S, 0, 0, out, 0);
            glFinish();
            t[r] = now_ms() - t0;
        }
        gpu_full = median(t, RUNS);
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim_vals_gather_twin(&d, NULL, 0, cpu, desc.env);
            t[r] = now_ms() - t0;
        }
        cpu_full = median(t, RUNS);
        printf("VAL gather FULL %dx%d: GPU %.2f ms, CPU twin %.2f ms (medians of %d), GPU %.1f M VALs/s\n", S, S, gpu_full,
               cpu_full, RUNS, (double)n / (gpu_full * 1e3));
        for (k = 0; k < 2; ++k) {
            double gpu_sel, cpu_sel;
            for (r = 0; r < RUNS; ++r) {
                double t0 = now_ms();
                gim__gl_vals_gather(ctx, tex[0], tex[1], tex[2], (uint32_t)S, bsel, selected[k], out, 0);
                glFinish();
                t[r] = now_ms() - t0;
            }
            gpu_sel = median(t, RUNS);
            for (r = 0; r < RUNS; ++r) {
                double t0 = now_ms();
                gim_vals_gather_twin(&d, sel, selected[k], cpu, desc.env);
                t[r] = now_ms() - t0;
            }
            cpu_sel = median(t, RUNS);
            printf("VAL gather BRSM %u of %dx%d: GPU %.3f ms, CPU twin %.3f ms (medians of %d); FULL / BRSM on the GPU %.1fx\n",
                   (unsigned)selected[k], S, S, gpu_sel, cpu_sel, RUNS, gpu_full / gpu_sel);
        }
        glDeleteTextures(3, tex);
        glDeleteBuffers(1, &out);
        glDeleteBuffers(1, &bsel);
        free(p4); free(n4); free(f4); free(p3); free(n3); free(f3); free(area); free(valid); free(cpu); free(sel);
    }
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
