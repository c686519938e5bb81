/* Paraboloid maps and second-bounce VPLs on the GPU (medians of wall time around glFinish, on
   whatever EGL gives: llvmpipe in CI, where only ratios within one run mean anything): the
   layered pass over a Cornell box of huge triangles and over the same box with a floor of
   3200 small triangles, at several map counts and sizes: the distance maps alone, both kinds
   (two passes, each with its own near skip: SSVP with paraboloid visibility) and the attribute
   maps alone; the second-bounce pass at two VPL counts. */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define RUNS 5
#define GRID 40

static float cb_pos[20 * 3];
static uint16_t cb_idx[30];
static float fl_pos[(GRID + 1) * (GRID + 1) * 3];
static uint32_t fl_idx[GRID * GRID * 6];

static void make_meshes(void) {
    static const float cb[5][4][3] = {{{-1, 0, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, 1}},
                                      {{-1, 2, -1}, {-1, 2, 1}, {1, 2, 1}, {1, 2, -1}},
                                      {{-1, 0, -1}, {-1, 2, -1}, {1, 2, -1}, {1, 0, -1}},
                                      {{-1, 0, -1}, {-1, 0, 1}, {-1, 2, 1}, {-1, 2, -1}},
                                      {{1, 0, -1}, {1, 2, -1}, {1, 2, 1}, {1, 0, 1}}};
    int f, v, x, z;
    for (f = 0; f < 5; ++f) {
        for (v = 0; v < 4; ++v) memcpy(cb_pos + (f * 4 + v) * 3, cb[f][v], 12);
        cb_idx[f * 6] = (uint16_t)(f * 4); cb_idx[f * 6 + 1] = (uint16_t)(f * 4 + 1); cb_idx[f * 6 + 2] = (uint16_t)(f * 4 + 2);
        cb_idx[f * 6 + 3] = (uint16_t)(f * 4); cb_idx[f * 6 + 4] = (uint16_t)(f * 4 + 2); cb_idx[f * 6 + 5] = (uint16_t)(f * 4 + 3);
    }
    for (z = 0; z <= GRID; ++z)
        for (x = 0; x <= GRID; ++x) {
            float *p = fl_pos + (z * (GRID + 1) + x) * 3;
            p[0] = -1.0f + 2.0f * x / GRID; p[1] = 0.001f; p[2] = -1.0f + 2.0f * z / GRID;
        }
    for (z = 0; z < GRID; ++z)
        for (x = 0; x < GRID; ++x) {
            uint32_t a = (uint32_t)(z * (GRID + 1) + x), *t = fl_idx + (z * GRID + x) * 6;
            t[0] = a; t[1] = a + GRID + 1; t[2] = a + 1; t[3] = a + 1; t[4] = a + GRID + 1; t[5] = a + GRID + 2;
        }
}

static double time_maps(gim_context *ctx, GLuint ssbo, uint32_t count, uint32_t size, int attributes) {
    double t[RUNS];
    int r;
    if (gim__gl_paraboloids(ctx, ssbo, count, size, attributes, 2.0f) != GIM_OK) exit(1);  /* targets, program */
    glFinish();
    for (r = 0; r < RUNS; ++r) {
        double t0 = now_ms();
        if (gim__gl_paraboloids(ctx, ssbo, count, size, attributes, 2.0f) != GIM_OK) exit(1);
        glFinish();
        t[r] = now_ms() - t0;
    }
    return median(t, RUNS);
}

int main(void) {
    static const uint32_t counts[2] = {16, 64}, sizes[2] = {64, 128};
    gim_desc d;
    gim_context *ctx = NULL;
    gim_mesh_desc md;
    gim_mesh box, floor_mesh;
    gim_instance inst[2];
    gim_material mat = {{0.7f, 0.7f, 0.7f}, {0, 0, 0}, 0};
    gim_paraboloid maps[64];
    GLuint ssbo, vpls;
    uint32_t i, c, s;
    int scene, a;
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_paraboloid: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    printf("renderer: %s\n", (const char *)glGetString(GL_RENDERER));
    make_meshes();
    memset(&md, 0, sizeof md);
    md.data.positions = cb_pos; md.data.vertex_count = 20;
    md.data.indices = cb_idx; md.data.index_count = 30; md.data.index_type = GIM_INDEX_U16;
    if (gim_add_mesh(ctx, &md, &box) != GIM_OK) return 1;
    memset(&md, 0, sizeof md);
    md.data.positions = fl_pos; md.data.vertex_count = (GRID + 1) * (GRID + 1);
    md.data.indices = fl_idx; md.data.index_count = GRID * GRID * 6;
    if (gim_add_mesh(ctx, &md, &floor_mesh) != GIM_OK) return 1;
    if (gim_set_materials(ctx, &mat, 1) != GIM_OK) return 1;
    /* maps spread through the box, normals spread over the sphere */
    for (i = 0; i < 64; ++i) {
        float n[3];
        memset(&maps[i], 0, sizeof maps[i]);
        maps[i].origin[0] = -0.9f + 1.8f * (float)test_rand01();
        maps[i].origin[1] = 0.1f + 1.8f * (float)test_rand01();
        maps[i].origin[2] = -0.9f + 1.8f * (float)test_rand01();
        test_random_unit(n);
        memcpy(maps[i].normal, n, sizeof n);
        maps[i].near_distance = 0.01f;
        maps[i].flux[0] = maps[i].flux[1] = maps[i].flux[2] = 1.0f;
    }
    ssbo = gltest_ssbo(sizeof maps, maps);
    for (scene = 0; scene < 2; ++scene) {
        inst[0].mesh = box; inst[0].model = gim_mat4_identity();
        inst[1].mesh = floor_mesh; inst[1].model = gim_mat4_identity();
        if (gim_set_instances(ctx, inst, scene ? 2u : 1u) != GIM_OK) return 1;
        for (c = 0; c < 2; ++c)
            for (s = 0; s < 2; ++s)
                for (a = 0; a < 3; ++a) {
                    static const int whats[3] = {GIM__PARA_DISTANCE, GIM__PARA_BOTH, GIM__PARA_ATTRIBUTES};
                    static const char *const names[3] = {"distance", "both (two passes)", "attributes"};
                    printf("paraboloid maps, %s (%u triangles): %u maps of %u^2, %s: %.2f ms (median of %d)\n",
                           scene ? "box + tessellated floor" : "Cornell box", scene ? 10u + GRID * GRID * 2u : 10u,
                           (unsigned)counts[c], (unsigned)sizes[s], names[a],
                           time_maps(ctx, ssbo, counts[c], sizes[s], whats[a]), RUNS);
                }
    }
    vpls = gltest_ssbo(4096 * sizeof(gim_vpl), NULL);
    if (gim__gl_paraboloids(ctx, ssbo, 64, 128, GIM__PARA_ATTRIBUTES, 2.0f) != GIM_OK) return 1;
    for (c = 1024; c <= 4096; c *= 4) {
        double t[RUNS];
        int r;
        for (r = 0; r < RUNS; ++r) {
            double t0;
            glFinish();
            t0 = now_ms();
            if (gim__gl_second_bounce(ctx, ssbo, 64, 128, c, vpls, 0) != GIM_OK) return 1;
            glFinish();
            t[r] = now_ms() - t0;
        }
        printf("second-bounce VPLs: %u from 64 maps of 128^2: %.3f ms (median of %d; the first call uploads the texels)\n",
               (unsigned)c, median(t, RUNS), RUNS);
    }
    glDeleteBuffers(1, &ssbo);
    glDeleteBuffers(1, &vpls);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
