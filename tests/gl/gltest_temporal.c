/* Temporal coherence, gim_frame.lightskin.temporal_steps L (the aim of Laine et al.'s incremental instant
   radiosity, 2007): the BRSM selection's and the view samples' offsets move by 1/L of their
   points' spacing a frame instead of jumping. On the built-in Cornell box:
   - the selection is the twin's (gim_importance_select with gim_drift_offsets), and
     from one frame to the next most VALs keep their texel;
   - a static scene: each frame is as near FULL as with new offsets every frame (the same
     stratified set, moved), and the frame-to-frame change falls several-fold;
   - a light that moves or goes out: every VAL is read from this frame's RSM, so the frame right
     after it is as near FULL of the new light as one with new offsets (no ghost of the old
     light), and a light switched off gives a black image at once.
   Measured first (128 VALs, the view samples fixed, L = 8), replacing 1/L of the VALs a frame
   (Laine's scheme taken literally, each kept VAL with the pdf it was drawn with): the change fell
   to 0.31 of new offsets every frame, but each frame's error against FULL rose from 0.063 to
   0.084 (kept and new VALs no longer form one stratified set). Moving the offsets keeps the
   set: with the view samples moving too (below), L = 32: change 0.15 of it, error 0.067 against
   0.064; L = 128: 0.034, 0.073. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"
#define W 40
#define H 30
#include "framefix.h"

enum { N = 64, RSM = 32 };

static void read_selected(gim_context *ctx, gim_selected_val *s, uint32_t n) {
    gim_frame_outputs oo = gim_outputs(ctx), *o = &oo;
    assert_int_equal(o->lights[0].selected_count, n);
    gltest_read_buffer(o->lights[0].selected, n * sizeof *s, s);
}

/* The twin's selection from this frame's tables: light 0's offsets of frame_index, drifting by
   1 / (n steps) a frame (steps > 1) or drawn from the frame's seed. */
static void twin_selected(gim_context *ctx, uint32_t frame_index, uint32_t steps, gim_selected_val *s, uint32_t n,
                          gim_env env) {
    gim_frame_outputs oo = gim_outputs(ctx), *o = &oo;
    uint32_t rsm = o->lights[0].rsm_size, tile = o->lights[0].importance_tile;
    uint32_t size = (rsm - 1u) / tile + 1u;   /* the tables' side: texels, or tiles of the two-level map */
    double *column = (double *)malloc((size_t)size * size * sizeof(double)), *row = (double *)malloc(size * sizeof(double));
    double *lcol = NULL, *lrow = NULL;
    float off[4], *weight = NULL, *lum = NULL;
    gim_select_desc sd;
    assert_true(tile >= 1u);
    if (steps > 1)
        gim_drift_offsets(off, 2, gim__select_seed(0, 0), frame_index, 1.0 / ((double)n * steps));
    else
        gim_rotation_offsets(off, 4, gim__select_seed(frame_index, 0));
    gltest_read_buffer(o->lights[0].column, (size_t)size * size * sizeof(double), column);
    gltest_read_buffer(o->lights[0].row, size * sizeof(double), row);
    memset(&sd, 0, sizeof sd);
    sd.column = column; sd.row = row; sd.width = size; sd.height = size; sd.count = n; sd.offsets = off; sd.env = env;
    if (tile > 1u) {   /* the two-level map: the texel weights too */
        weight = (float *)malloc((size_t)rsm * rsm * sizeof(float));
        gltest_read_buffer(o->lights[0].importance, (size_t)rsm * rsm * sizeof(float), weight);
        sd.tile = tile; sd.weight = weight; sd.rsm_width = sd.rsm_height = rsm;
    }
    if (o->lights[0].defensive_count) {   /* the defensive share (the default): the luminance's tables too */
        assert_true(o->lights[0].luminance && o->lights[0].luminance_column && o->lights[0].luminance_row);
        lcol = (double *)malloc((size_t)size * size * sizeof(double));
        lrow = (double *)malloc(size * sizeof(double));
        gltest_read_buffer(o->lights[0].luminance_column, (size_t)size * size * sizeof(double), lcol);
        gltest_read_buffer(o->lights[0].luminance_row, size * sizeof(double), lrow);
        sd.defensive_count = o->lights[0].defensive_count;
        sd.lum_column = lcol;
        sd.lum_row = lrow;
        if (tile > 1u) {
            lum = (float *)malloc((size_t)rsm * rsm * sizeof(float));
            gltest_read_buffer(o->lights[0].luminance, (size_t)rsm * rsm * sizeof(float), lum);
            sd.lum_weight = lum;
        }
    }
    assert_int_equal(gim_importance_select(&sd, s), GIM_OK);
    free(column);
    free(row);
    free(weight);
    free(lcol);
    free(lrow);
    free(lum);
}

static void indirect_of(gim_context *ctx, float *img) {
    gim_frame_outputs o = gim_outputs(ctx);
    read_indirect(&o, img);
}

static int same(const gim_selected_val *a, const gim_selected_val *b) {
    return a->x == b->x && a->y == b->y && a->pdf == b->pdf;
}

static void update(frame_fixture *ff) {
    assert_int_equal(gim_update(ff->f.ctx, &ff->fr), GIM_OK);
}

static void selection_moves(void **state) {
    frame_fixture ff;
    gim_selected_val *prev = (gim_selected_val *)calloc(N, sizeof *prev), *cur = (gim_selected_val *)calloc(N, sizeof *cur),
                     *twin = (gim_selected_val *)calloc(N, sizeof *twin);
    uint32_t i, k, q, tt, changed[2] = {0, 0};
    static const uint32_t steps[2] = {1, 32};   /* 1: new offsets every frame */
    (void)state;
    GLTEST_BEGIN();
    frame_begin(&ff, NULL, RSM);
    frame_small(&ff, GIM_METHOD_LIGHTSKIN_BRSM);
    ff.fr.lightskin.val_count = N;
    ff.fr.lightskin.rotate_view_samples = 1;
    ff.fr.lightskin.defensive_share = 0.125f;   /* the selection with its luminance share (off by default) */
    /* per texel, then the two-level map of tile 8 (4x4 tiles of this RSM), whose
       pick inside a tile follows the residual of v that the drift moves by drift / P(tile | column):
       measured 32 and 66 changes with 32 steps, 314-315 with new offsets */
    for (tt = 0; tt < 2; ++tt) {
    ff.fr.lightskin.importance_tile = tt ? 8u : 0u;   /* 0: the default, 1 */
    changed[0] = changed[1] = 0;
    for (q = 0; q < 2; ++q) {
        ff.fr.lightskin.temporal_steps = steps[q];
        for (k = 0; k < 6; ++k) {
            ff.fr.frame_index = 10 + k;
            update(&ff);
            read_selected(ff.f.ctx, cur, N);
            assert_int_equal(gim_outputs(ff.f.ctx).lights[0].defensive_count, N / 8);   /* 1/8 of 64 */
            twin_selected(ff.f.ctx, ff.fr.frame_index, steps[q], twin, N, ff.f.env);
            for (i = 0; i < N; ++i) {
                assert_true(same(cur + i, twin + i));
                changed[q] += k > 0 && (cur[i].x != prev[i].x || cur[i].y != prev[i].y);
            }
            memcpy(prev, cur, N * sizeof *cur);
        }
    }
    print_message("tile %u: VALs on another texel than last frame's, over 5 frames of %u: %u with new offsets, %u with 32 steps\n",
                  tt ? 8u : 1u, N, changed[0], changed[1]);
    assert_true(changed[0] > 4 * N && changed[1] < (tt ? 5u * N / 4u : N));
    }
    /* without the defensive share no luminance buffer is kept; a share outside (0, 0.5] is refused */
    ff.fr.lightskin.defensive_share = -1.0f;
    update(&ff);
    assert_int_equal(gim_outputs(ff.f.ctx).lights[0].defensive_count, 0);
    assert_int_equal(gim_outputs(ff.f.ctx).lights[0].luminance, 0);
    assert_int_equal(ff.f.ctx->light_gpu[0].lum_map, 0);
    assert_int_equal(ff.f.ctx->light_gpu[0].lum_column, 0);
    ff.fr.lightskin.defensive_share = 0.7f;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
    ff.fr.lightskin.defensive_share = NAN;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
    ff.fr.lightskin.defensive_share = 0.0f;   /* the default: none */
    update(&ff);
    assert_int_equal(gim_outputs(ff.f.ctx).lights[0].defensive_count, 0);
    ff.fr.lightskin.temporal_steps = GIM_MAX_TEMPORAL_STEPS + 1u;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(ff.f.log.errors, 3);
    ff.f.log.errors = 0;   /* those refusals' one line each */
    free(prev);
    free(cur);
    free(twin);
    frame_end(&ff);
    GLTEST_END();
}

/* Frames 1..count with temporal_steps L: the mean over them of each frame's rel. MAE against
   full in *err, the mean frame-to-frame change (over the image's mean) returned. */
static double run_frames(frame_fixture *ff, uint32_t steps, int count, const float *full, double *err) {
    float *img = (float *)malloc(W * H * 16), *prev = (float *)malloc(W * H * 16);
    double change = 0.0;
    int k;
    *err = 0.0;
    ff->fr.lightskin.temporal_steps = steps;
    for (k = 0; k < count; ++k) {
        ff->fr.frame_index = (uint32_t)k + 1u;
        update(ff);
        indirect_of(ff->f.ctx, img);
        if (k > 0) change += mean_rel_diff(img, prev);
        *err += mean_rel_diff(img, full) / count;
        memcpy(prev, img, W * H * 16);
    }
    free(img);
    free(prev);
    return change / (count - 1);
}

static void static_scene(void **state) {
    enum { FRAMES = 16 };
    static const uint32_t steps[3] = {1, 32, 128};   /* 1: new offsets every frame */
    frame_fixture ff;
    float *full = (float *)malloc(W * H * 16);
    double c[3], e[3];
    int q;
    (void)state;
    GLTEST_BEGIN();
    frame_begin(&ff, NULL, RSM);
    ff.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    update(&ff);
    indirect_of(ff.f.ctx, full);
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    ff.fr.lightskin.val_count = 128;
    ff.fr.lightskin.view_sample_count = 32;
    ff.fr.lightskin.rotate_view_samples = 1;
    for (q = 0; q < 3; ++q) {
        c[q] = run_frames(&ff, steps[q], FRAMES, full, &e[q]);
        print_message("%d frames, 128 VALs, temporal_steps %u: each frame vs FULL %.4f, frame-to-frame change %.4f\n", FRAMES,
                      steps[q], e[q], c[q]);
    }
    assert_true(e[1] < 1.2 * e[0] + 0.005 && e[2] < 1.3 * e[0] + 0.005);   /* as good a frame */
    assert_true(c[1] < 0.4 * c[0] && c[2] < c[1]);                          /* steadier */
    {   /* 0, the default, is 32 steps: the same frames bit for bit */
        double e0, c0 = run_frames(&ff, 0, FRAMES, full, &e0);
        assert_true(c0 == c[1] && e0 == e[1]);
    }
    free(full);
    frame_end(&ff);
    GLTEST_END();
}

static void moving_light(void **state) {
    frame_fixture ff;
    float *full = (float *)malloc(W * H * 16), *img = (float *)malloc(W * H * 16), *fresh = (float *)malloc(W * H * 16);
    gim_light l;
    double e_kept, e_fresh;
    int k, i;
    (void)state;
    GLTEST_BEGIN();
    frame_begin(&ff, NULL, RSM);
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    ff.fr.lightskin.val_count = 256;
    ff.fr.lightskin.view_sample_count = 32;
    ff.fr.lightskin.rotate_view_samples = 1;
    ff.fr.lightskin.temporal_steps = 32;
    for (k = 0; k < 8; ++k) {   /* every entry drawn for the light where it is */
        ff.fr.frame_index = (uint32_t)k + 1u;
        update(&ff);
    }
    /* the spot moves to a side wall's corner and turns (a new RSM: other texels lit) */
    l = ff.g.lights[0];
    l.position = gim_v3(l.position.x * 0.5f + 0.2f * ff.s.scale, l.position.y * 0.9f, l.position.z);
    l.direction = gim_v3_normalize(gim_v3(0.5f, -1.0f, 0.2f));
    assert_int_equal(gim_set_lights(ff.f.ctx, &l, 1), GIM_OK);
    ff.fr.frame_index = 9;
    update(&ff);
    indirect_of(ff.f.ctx, img);
    ff.fr.lightskin.temporal_steps = 1;   /* the same frame with new offsets */
    update(&ff);
    indirect_of(ff.f.ctx, fresh);
    ff.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    update(&ff);
    indirect_of(ff.f.ctx, full);
    e_kept = mean_rel_diff(img, full);
    e_fresh = mean_rel_diff(fresh, full);
    print_message("spot moved: the next frame vs FULL %.4f with 32 temporal steps, %.4f with new offsets\n", e_kept, e_fresh);
    assert_true(e_kept < 1.5 * e_fresh + 0.02);
    /* switched off: black at once */
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    ff.fr.lightskin.temporal_steps = 32;
    for (k = 0; k < 8; ++k) {
        ff.fr.frame_index = 20u + (uint32_t)k;
        update(&ff);
    }
    l.intensity = 0.0f;
    assert_int_equal(gim_set_lights(ff.f.ctx, &l, 1), GIM_OK);
    ff.fr.frame_index = 28;
    update(&ff);
    indirect_of(ff.f.ctx, img);
    for (i = 0; i < W * H; ++i) assert_true(img[i * 4] == 0.0f && img[i * 4 + 1] == 0.0f && img[i * 4 + 2] == 0.0f);
    free(full);
    free(img);
    free(fresh);
    frame_end(&ff);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(selection_moves),
        cmocka_unit_test(static_scene),
        cmocka_unit_test(moving_light),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
