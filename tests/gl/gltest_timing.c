/* Per-pass times of gim_frame_stats with timing 2 (glFinish after each pass, then the CPU's
   clock): every pass that ran has a time > 0, passes that did not run have 0, the times add up
   to the frame's (they tile it) and stay within the wall time measured around gim_update by the
   same clock, and the heaviest pass of a FULL frame (proxy lights: every RSM texel against
   every cache) is the one charged most. Timing 1 reports GL timestamps (cpu_clock 0), timing 0
   nothing. Built with -DGLTEST_TIMING_GL_CLOCK (no POSIX clock), it checks gimany's fallback
   clock, the GL's own (cpu_clock 2), against that same clock. */
#if !defined(_POSIX_C_SOURCE) && !defined(GLTEST_TIMING_GL_CLOCK)
#define _POSIX_C_SOURCE 199309L   /* before any system header: clock_gettime, as gimany.h's clock */
#endif
#include <time.h>
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define GRID 24   /* caches per side of each quad */

static double wall_ms(void) {
#ifdef CLOCK_MONOTONIC
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
#else
    GLint64 t = 0;
    glGetInteger64v(GL_TIMESTAMP, &t);
    return (double)t * 1e-6;
#endif
}

/* A quad of side 4 in the plane through origin spanned by u and v (normal n), with GRID^2
   caches on it. */
static void add_quad(gim_context *ctx, gim_vec3 origin, gim_vec3 u, gim_vec3 v, gim_vec3 n, gim_mesh *out) {
    static const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    static gim_cache caches[GRID * GRID];
    float pos[12], nrm[12];
    gim_mesh_desc md;
    gim_cache_set set;
    int k, i, j;
    for (k = 0; k < 4; ++k) {
        float a = (k == 1 || k == 2) ? 4.0f : 0.0f, b = (k >= 2) ? 4.0f : 0.0f;
        pos[k * 3 + 0] = origin.x + a * u.x + b * v.x;
        pos[k * 3 + 1] = origin.y + a * u.y + b * v.y;
        pos[k * 3 + 2] = origin.z + a * u.z + b * v.z;
        nrm[k * 3 + 0] = n.x; nrm[k * 3 + 1] = n.y; nrm[k * 3 + 2] = n.z;
    }
    memset(caches, 0, sizeof caches);
    for (i = 0; i < GRID; ++i)
        for (j = 0; j < GRID; ++j) {
            gim_cache *c = &caches[i * GRID + j];
            float a = 4.0f * ((float)i + 0.5f) / GRID, b = 4.0f * ((float)j + 0.5f) / GRID;
            c->position[0] = origin.x + a * u.x + b * v.x;
            c->position[1] = origin.y + a * u.y + b * v.y;
            c->position[2] = origin.z + a * u.z + b * v.z;
            c->normal[0] = n.x; c->normal[1] = n.y; c->normal[2] = n.z;
            c->area = 16.0f / (GRID * GRID);
            c->reflectance = 0.6f;
        }
    memset(&md, 0, sizeof md);
    md.data.positions = pos;
    md.data.normals = nrm;
    md.data.vertex_count = 4;
    md.data.indices = idx;
    md.data.index_count = 6;
    memset(&set, 0, sizeof set);   /* gim_add_mesh reads the set's other fields too */
    set.caches = caches;
    set.count = GRID * GRID;
    md.caches = &set;
    assert_int_equal(gim_add_mesh(ctx, &md, out), GIM_OK);
}

/* A floor and a wall lit by a sun, seen from the front. */
static void corner_scene(gim_context *ctx, gim_frame *fr) {
    gim_mesh floor_mesh, wall_mesh;
    gim_instance inst[2];
    gim_material mat;
    gim_light sun;
    add_quad(ctx, gim_v3(-2.0f, 0.0f, -2.0f), gim_v3(0.0f, 0.0f, 1.0f), gim_v3(1.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f),
             &floor_mesh);
    add_quad(ctx, gim_v3(-2.0f, 0.0f, -2.0f), gim_v3(1.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f), gim_v3(0.0f, 0.0f, 1.0f),
             &wall_mesh);
    memset(&mat, 0, sizeof mat);
    mat.diffuse[0] = mat.diffuse[1] = mat.diffuse[2] = 0.6f;
    assert_int_equal(gim_set_materials(ctx, &mat, 1), GIM_OK);
    inst[0].mesh = floor_mesh;
    inst[0].model = gim_mat4_identity();
    inst[1].mesh = wall_mesh;
    inst[1].model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(ctx, inst, 2), GIM_OK);
    memset(&sun, 0, sizeof sun);
    sun.irradiance = 3.0f;
    sun.direction = gim_v3(0.4f, 1.0f, 0.7f);
    sun.rsm_size = 128;
    assert_int_equal(gim_set_lights(ctx, &sun, 1), GIM_OK);
    memset(fr, 0, sizeof *fr);
    fr->view = gim_mat4_look_at(gim_v3(1.5f, 2.5f, 5.0f), gim_v3(0.0f, 0.8f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr->proj = gim_mat4_perspective(1.0f, 1.5f, 0.1f, 20.0f);
    fr->width = 96;
    fr->height = 64;
    fr->lightskin.view_sample_count = 256;
    fr->lightskin.val_count = 1024;
}

/* One frame with timing t: its stats and the wall time around gim_update + glFinish. */
static double timed_frame(gim_context *ctx, gim_frame fr, int t, gim_stats *st) {
    double t0, wall;
    fr.timing = t;
    glFinish();
    t0 = wall_ms();
    assert_int_equal(gim_update(ctx, &fr), GIM_OK);
    glFinish();
    wall = wall_ms() - t0;
    memset(st, 0xff, sizeof *st);
    assert_int_equal(gim_frame_stats(ctx, st), GIM_OK);
    return wall;
}

static double pass_sum(const gim_stats *st) {
    double s = 0.0;
    int p;
    for (p = 0; p < GIM_PASS_COUNT; ++p) s += st->pass_ms[p];
    return s;
}

static const char *const pass_names[GIM_PASS_COUNT] = {"rsm",  "gbuffer", "view_samples", "importance", "cumsum", "select",
                                                       "caches", "vals", "proxy", "shade", "vpls", "kmeans", "paraboloid",
                                                       "second_bounce", "blur", "ism"};

static void print_passes(const char *what, const gim_stats *st, double wall) {
    int p;
    print_message("%s (clock %d): wall %.2f ms, frame %.2f ms, passes sum %.2f:", what, st->cpu_clock, wall, st->frame_ms,
                  pass_sum(st));
    for (p = 0; p < GIM_PASS_COUNT; ++p) print_message(" %s %.2f", pass_names[p], st->pass_ms[p]);
    print_message("\n");
}

/* The times of a timing-2 frame with the passes `ran` (bit p: pass p ran) */
static void check_timing2(const gim_stats *st, double wall, unsigned ran) {
    double sum = pass_sum(st);
    int p;
    assert_int_equal(st->timed, 1);
#ifdef CLOCK_MONOTONIC
    assert_int_equal(st->cpu_clock, 1);
#else
    assert_int_equal(st->cpu_clock, 2);
#endif
    for (p = 0; p < GIM_PASS_COUNT; ++p) {
        assert_true(isfinite(st->pass_ms[p]));
        if (ran & (1u << p)) assert_true(st->pass_ms[p] > 0.0);
        else assert_true(st->pass_ms[p] == 0.0);
    }
    /* the stamps tile the frame: the passes add up to it */
    assert_true(fabs(sum - st->frame_ms) <= 1e-9 * st->frame_ms + 1e-9);
    /* within the wall time around the call, by the same clock, and most of it (what lies
       outside the first and last stamps is argument checks and the state restore) */
    assert_true(st->frame_ms <= wall);
    assert_true(st->frame_ms >= 0.5 * wall);
}

#define RAN(p) (1u << (p))
static const unsigned shared_passes = RAN(GIM_PASS_RSM) | RAN(GIM_PASS_GBUFFER) | RAN(GIM_PASS_CACHES) | RAN(GIM_PASS_VALS) |
                                      RAN(GIM_PASS_PROXY_LIGHTS) | RAN(GIM_PASS_SHADE);
/* BRSM only: the view samples feed the importance map */
static const unsigned importance_passes = RAN(GIM_PASS_VIEW_SAMPLES) | RAN(GIM_PASS_IMPORTANCE_MAP) | RAN(GIM_PASS_CUMSUM) |
                                          RAN(GIM_PASS_SELECT);

static void timing2_per_pass(void **state) {
    gltest_fixture f;
    gim_frame fr;
    gim_stats st;
    double wall;
    int p, heaviest = 0;
    (void)state;
    GLTEST_BEGIN();
    memset(&f, 0, sizeof f);
    gltest_fixture_begin(&f);
    corner_scene(f.ctx, &fr);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);   /* builds programs and buffers */

    /* BRSM: every LightSkin pass runs */
    wall = timed_frame(f.ctx, fr, 2, &st);
    print_passes("BRSM, timing 2", &st, wall);
    check_timing2(&st, wall, shared_passes | importance_passes);
    gltest_state_unchanged(&f);

    /* with imperfect shadow maps: their pass in the frame that makes them, none in the next */
    fr.visibility.mode = GIM_VISIBILITY_ISM;
    fr.visibility.ism_points = 1024;
    wall = timed_frame(f.ctx, fr, 2, &st);
    print_passes("BRSM + ISM (maps made), timing 2", &st, wall);
    check_timing2(&st, wall, shared_passes | importance_passes | RAN(GIM_PASS_ISM));
    wall = timed_frame(f.ctx, fr, 2, &st);
    check_timing2(&st, wall, shared_passes | importance_passes);
    fr.visibility.mode = GIM_VISIBILITY_OFF;

    /* FULL: no view samples, no importance passes; 16384 VALs against 1152 caches make the proxy pass the heaviest */
    fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    wall = timed_frame(f.ctx, fr, 2, &st);
    print_passes("FULL, timing 2", &st, wall);
    check_timing2(&st, wall, shared_passes);
    for (p = 0; p < GIM_PASS_COUNT; ++p)
        if (st.pass_ms[p] > st.pass_ms[heaviest]) heaviest = p;
    assert_int_equal(heaviest, GIM_PASS_PROXY_LIGHTS);

    /* timing 1: GL timestamps; timing 0: nothing timed */
    wall = timed_frame(f.ctx, fr, 1, &st);
    print_passes("FULL, timing 1 (GL timestamps)", &st, wall);
    assert_int_equal(st.timed, 1);
    assert_int_equal(st.cpu_clock, 0);
    for (p = 0; p < GIM_PASS_COUNT; ++p) assert_true(isfinite(st.pass_ms[p]) && st.pass_ms[p] >= 0.0);
    assert_true(st.frame_ms > 0.0);
    timed_frame(f.ctx, fr, 0, &st);
    assert_int_equal(st.timed, 0);
    assert_int_equal(st.cpu_clock, 0);
    for (p = 0; p < GIM_PASS_COUNT; ++p) assert_true(st.pass_ms[p] == 0.0);
    assert_true(st.frame_ms == 0.0);
    gltest_state_unchanged(&f);
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(timing2_per_pass),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
