/* GL timings of the VPL shading pass and the geometry-aware blur (medians, wall time around
   glFinish; on llvmpipe only ratios within one run mean anything): 128^2 pixels of a floor
   seen from above (a G-buffer written directly, the host's kind), 1024 VPLs on two walls in 32
   clusters with 128^2 paraboloid maps of plates; interleave k = 2 and 4, without and with
   visibility (computed per VPL: a per-pixel cache of the clusters' visibility in a local array,
   Dong's sharing, ran 2-4x slower on llvmpipe, which lowers the array's dynamic indexing, even
   where nothing was cached), and the 4 x 4 blur. */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "vplshade_util.h"

#define RUNS 5
enum { W = 128, H = 128, N = 1024, M = 32, S = 128 };

static GLuint texture(GLenum format, GLenum data_format, int w, int h, const float *t) {
    GLuint tex = 0;
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, format, w, h);
    if (t) glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, data_format, GL_FLOAT, t);
    glBindTexture(GL_TEXTURE_2D, 0);
    return tex;
}

static double time_shade(gim_context *ctx, const gim__vpl_shade_args *a) {
    double t[RUNS];
    int r;
    gim__gl_enter(ctx, "bench");
    if (gim__gl_vpl_shade(ctx, a) != GIM_OK) exit(1);   /* warm: program, buffers */
    glFinish();
    for (r = 0; r < RUNS; ++r) {
        double t0 = now_ms();
        gim__gl_vpl_shade(ctx, a);
        glFinish();
        t[r] = now_ms() - t0;
    }
    gim__gl_leave(ctx, GIM_OK);
    return median(t, RUNS);
}

int main(void) {
    gim_desc d;
    gim_context *ctx = NULL;
    static float depth[W * H], normal[W * H * 4], dist[M * S * S];
    static gim_vpl vpl[N];
    static uint32_t cluster[N];
    static gim_paraboloid maps[M];
    GLuint t_depth, t_normal, t_out, t_blur, t_dist, b_vpl, b_cluster, b_maps;
    gim__vpl_shade_args a;
    gim__blur_args ba;
    uint32_t i, m, ks[2] = {2, 4};
    int k;
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_vpl_shade_gl: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    printf("renderer: %s\n", (const char *)glGetString(GL_RENDERER));
    for (i = 0; i < W * H; ++i) { depth[i] = 0.5f; normal[i * 4 + 1] = 1.0f; normal[i * 4 + 3] = 1.0f; }
    for (m = 0; m < M; ++m) {
        int wall_x = m % 2 == 0;
        memset(&maps[m], 0, sizeof maps[m]);
        maps[m].origin[0] = wall_x ? 1e-4f : 0.1f + 0.8f * (float)test_rand01();
        maps[m].origin[1] = 0.1f + 0.5f * (float)test_rand01();
        maps[m].origin[2] = wall_x ? 0.1f + 0.8f * (float)test_rand01() : 1e-4f;
        maps[m].normal[0] = wall_x ? 1.0f : 0.0f;
        maps[m].normal[2] = wall_x ? 0.0f : 1.0f;
        maps[m].size = 0.15f;
        vs_plate_map(dist + (size_t)m * S * S, S, 0.2f + 0.3f * (float)test_rand01(), 0.0f, 0.0f, 0.1f);
    }
    for (i = 0; i < N; ++i) {
        gim_vec3 p;
        m = i % M;
        p = vs_local(&maps[m], 0.14f * (float)test_rand01() - 0.07f, 0.14f * (float)test_rand01() - 0.07f, 0.0f);
        memset(&vpl[i], 0, sizeof vpl[i]);
        vpl[i].position[0] = p.x; vpl[i].position[1] = p.y; vpl[i].position[2] = p.z;
        vpl[i].lit = 1.0f;
        memcpy(vpl[i].normal, maps[m].normal, sizeof vpl[i].normal);
        vpl[i].flux[0] = vpl[i].flux[1] = vpl[i].flux[2] = 1.0f / N;
        cluster[i] = m;
    }
    t_depth = texture(GL_R32F, GL_RED, W, H, depth);
    t_normal = texture(GL_RGBA32F, GL_RGBA, W, H, normal);
    t_out = texture(GL_RGBA32F, GL_RGBA, W, H, NULL);
    t_blur = texture(GL_RGBA32F, GL_RGBA, W, H, NULL);
    glGenTextures(1, &t_dist);
    glBindTexture(GL_TEXTURE_2D_ARRAY, t_dist);
    glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_R32F, S, S, M);
    glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, S, S, M, GL_RED, GL_FLOAT, dist);
    glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
    b_vpl = gltest_ssbo(sizeof vpl, vpl);
    b_cluster = gltest_ssbo(sizeof cluster, cluster);
    b_maps = gltest_ssbo(sizeof maps, maps);
    memset(&a, 0, sizeof a);
    a.depth = t_depth; a.normal = t_normal; a.width = W; a.height = H;
    a.view = gim_mat4_look_at(gim_v3(0.5f, 2.0f, 0.5f), gim_v3(0.5f, 0.0f, 0.5f), gim_v3(0, 0, -1));
    a.proj = gim_mat4_ortho(-0.5f, 0.5f, -0.5f, 0.5f, 1.0f, 3.0f);
    a.vpls = b_vpl; a.vpl_count = N; a.maps = b_maps; a.map_count = M; a.map_size = S;
    a.clamp_distance = 0.01f; a.scene_scale = 1.7320508f; a.output = t_out; a.format = GL_RGBA32F;
    for (k = 0; k < 2; ++k) {
        double t_none, t_vis;
        a.interleave = ks[k];
        a.cluster = 0; a.distance = 0;
        t_none = time_shade(ctx, &a);
        a.cluster = b_cluster; a.distance = t_dist;
        t_vis = time_shade(ctx, &a);
        printf("vpl_shade %dx%d, %d VPLs, k=%u (%u per pixel): no visibility %.1f ms, with visibility (%d maps %d^2) %.1f ms "
               "(medians of %d)\n", W, H, N, ks[k], N / (ks[k] * ks[k]), t_none, M, S, t_vis, RUNS);
    }
    memset(&ba, 0, sizeof ba);
    ba.depth = t_depth; ba.normal = t_normal; ba.width = W; ba.height = H; ba.view = a.view; ba.proj = a.proj;
    ba.input = t_out; ba.window = 4; ba.position_tolerance = 0.17f; ba.output = t_blur; ba.format = GL_RGBA32F;
    {
        double t[RUNS];
        int r;
        gim__gl_enter(ctx, "bench");
        if (gim__gl_geometry_blur(ctx, &ba) != GIM_OK) return 1;
        glFinish();
        for (r = 0; r < RUNS; ++r) {
            double t0 = now_ms();
            gim__gl_geometry_blur(ctx, &ba);
            glFinish();
            t[r] = now_ms() - t0;
        }
        gim__gl_leave(ctx, GIM_OK);
        printf("geometry_blur %dx%d, window 4: %.2f ms (median of %d)\n", W, H, median(t, RUNS), RUNS);
    }
    glDeleteTextures(1, &t_depth); glDeleteTextures(1, &t_normal); glDeleteTextures(1, &t_out);
    glDeleteTextures(1, &t_blur); glDeleteTextures(1, &t_dist);
    glDeleteBuffers(1, &b_vpl); glDeleteBuffers(1, &b_cluster); glDeleteBuffers(1, &b_maps);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
