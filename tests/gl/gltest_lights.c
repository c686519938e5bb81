/* Many lights: a street at night, 32 spots -- 24 lamps lighting the street, 4
   pointing up into the empty sky (their frusta meet no instance: culled, no RSM) and 4 lighting
   a canopy above and behind the camera (an RSM, but its VALs face up, away from every view
   sample: importance 0, no VALs).
     - FULL with all 32 against the sum of the 32 single-light FULL frames;
     - BRSM with the shared budget (val_count in all, split by importance) against the same,
       its mean over rotated selections within a statistical tolerance, and against the
       per-light budget of the same total (the shared one must not be worse);
     - the culled and the zero lights measurably skipped (no textures, no VALs, stats.rsm_count,
       fewer GPU bytes than with every RSM rendered);
     - 40 RSMs (six point lights and four spots), above the old limit of 16;
     - gim_set_lights_buffer: the same lights from a GL buffer (gim_light_std430) give the same
       image bit for bit; bad buffers refused.
   Checked to fail when broken (a copy of the header, run 2026-11-24): the culling off
   (gim__light_meets_instances returning 1) fails skipped_lights (32 RSMs, not 28),
   above_old_limit (40, not 34) and brsm_shared_matches_sum (640 VALs per light budget, not
   560); one VAL to each rendered light whose importance total is 0 fails skipped_lights
   (val_light_count 28, not 24). */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "room.h"
#include "lamps.h"

#define W 48
#define H 32
#define NL 32
#define RSM 24

typedef struct street_fix {
    gltest_fixture f;
    gim_mesh mesh[4];
    gim_cache_set set[4];
    gim_frame fr;
    gim_light lights[NL];
} street_fix;

/* The lamp street (lamps.h): four meshes, four instances, each with its caches. */
static void street_begin(street_fix *s) {
    room r[4];
    gim_instance in[4];
    int k;
    memset(s, 0, sizeof *s);
    gltest_fixture_begin(&s->f);
    lamps_quads(r);
    for (k = 0; k < 4; ++k) {
        gim_cache_desc cd;
        gim_mesh_desc md;
        memset(&cd, 0, sizeof cd);
        cd.mesh = room_arrays(&r[k]);
        cd.d_eps = 0.7f;
        assert_int_equal(gim_cache_generate(&cd, &s->set[k]), GIM_OK);
        memset(&md, 0, sizeof md);
        md.data = room_arrays(&r[k]);
        md.caches = &s->set[k];
        assert_int_equal(gim_add_mesh(s->f.ctx, &md, &s->mesh[k]), GIM_OK);
        in[k].mesh = s->mesh[k];
        in[k].model = gim_mat4_identity();
    }
    assert_int_equal(gim_set_materials(s->f.ctx, room_materials, 3), GIM_OK);
    assert_int_equal(gim_set_instances(s->f.ctx, in, 4), GIM_OK);
    for (k = 0; k < NL; ++k) s->lights[k] = lamps_light(k, RSM);
    memset(&s->fr, 0, sizeof s->fr);
    lamps_view(&s->fr, W, H);
    s->fr.indirect_float32 = 1;
    s->fr.lightskin.view_sample_count = 128;
}

static void street_end(street_fix *s) {
    int k;
    for (k = 0; k < 4; ++k) gim_cache_set_free(&s->set[k]);
    gltest_fixture_end(&s->f);
}

/* The frame's indirect rgb into out (W x H x 4); all zero when the frame has none. */
static void frame_image(street_fix *s, float *out) {
    gim_frame_outputs o;
    assert_int_equal(gim_update(s->f.ctx, &s->fr), GIM_OK);
    o = gim_outputs(s->f.ctx);
    if (o.indirect) gltest_read_texture(o.indirect, GL_RGBA, out);
    else memset(out, 0, (size_t)W * H * 16);
}

/* The sum of the 32 single-light frames (method FULL). */
static void single_light_sum(street_fix *s, double *sum, double *ms) {
    float *img = (float *)malloc((size_t)W * H * 16);
    int k, p;
    gim_method m = s->fr.method;
    memset(sum, 0, (size_t)W * H * 3 * sizeof *sum);
    s->fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    if (ms) *ms = 0.0;
    for (k = 0; k < NL; ++k) {
        assert_int_equal(gim_set_lights(s->f.ctx, &s->lights[k], 1), GIM_OK);
        frame_image(s, img);
        if (ms) {
            gim_stats st;
            assert_int_equal(gim_frame_stats(s->f.ctx, &st), GIM_OK);
            *ms += st.frame_ms;
        }
        for (p = 0; p < W * H; ++p) {
            sum[p * 3] += img[p * 4]; sum[p * 3 + 1] += img[p * 4 + 1]; sum[p * 3 + 2] += img[p * 4 + 2];
        }
    }
    s->fr.method = m;
    free(img);
}

/* Relative mean absolute difference and the largest difference over the largest value. */
static void compare(const float *img, const double *ref, double *rel_mae, double *rel_max) {
    double d = 0.0, t = 0.0, mx = 0.0, top = 0.0;
    int p, c;
    for (p = 0; p < W * H; ++p)
        for (c = 0; c < 3; ++c) {
            double e = fabs((double)img[p * 4 + c] - ref[p * 3 + c]);
            d += e;
            t += fabs(ref[p * 3 + c]);
            if (e > mx) mx = e;
            if (fabs(ref[p * 3 + c]) > top) top = fabs(ref[p * 3 + c]);
        }
    *rel_mae = t > 0.0 ? d / t : 0.0;
    *rel_max = top > 0.0 ? mx / top : 0.0;
}

/* FULL is deterministic: every texel a VAL of weight 1, so the 32-light frame sums the same
   VALs' contributions per cache (eq. 3-7) as the 32 frames do one light at a time; only the
   order of the float sums differs. */
static void full_matches_sum(void **state) {
    street_fix s;
    double *sum = (double *)malloc((size_t)W * H * 3 * sizeof(double)), mae, mx, total = 0.0;
    float *img = (float *)malloc((size_t)W * H * 16);
    int p;
    (void)state;
    GLTEST_BEGIN();
    street_begin(&s);
    single_light_sum(&s, sum, NULL);
    for (p = 0; p < W * H * 3; ++p) total += sum[p];
    assert_true(total > 0.0);
    s.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    frame_image(&s, img);
    compare(img, sum, &mae, &mx);
    print_message("FULL, 32 lights vs the sum of 32 single-light frames: rel. MAE %.2e, max %.2e of the peak\n", mae, mx);
    assert_true(mae < 1e-5);   /* measured 4e-7 (float sums in another order) */
    assert_true(mx < 1e-4);
    free(img);
    free(sum);
    street_end(&s);
    GLTEST_END();
}

/* BRSM's mean over rotated selections, shared budget and per-light budget of the same total,
   against the FULL 32-light frame (the same proxy-light aggregation, so only the selection's
   noise is left). */
static void brsm_shared_matches_sum(void **state) {
    enum { FRAMES = 12, RENDERED = 28, TOTAL = RENDERED * 20 };
    street_fix s;
    double *full = (double *)malloc((size_t)W * H * 3 * sizeof(double)), *mean[2], mae[2], mx[2], one[2] = {0.0, 0.0};
    float *img = (float *)malloc((size_t)W * H * 16), *mf = (float *)malloc((size_t)W * H * 16);
    int p, b, fi;
    (void)state;
    GLTEST_BEGIN();
    street_begin(&s);
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    s.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    frame_image(&s, img);
    for (p = 0; p < W * H; ++p) { full[p * 3] = img[p * 4]; full[p * 3 + 1] = img[p * 4 + 1]; full[p * 3 + 2] = img[p * 4 + 2]; }
    s.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    s.fr.lightskin.temporal_steps = 1;   /* independent selections, so that their mean converges */
    for (b = 0; b < 2; ++b) {   /* 0: shared (the default), 1: per rendered light, TOTAL / 28 */
        mean[b] = (double *)calloc((size_t)W * H * 3, sizeof(double));
        s.fr.per_light_budget = b;
        s.fr.lightskin.val_count = b ? TOTAL / RENDERED : TOTAL;
        for (fi = 0; fi < FRAMES; ++fi) {
            double e, m;
            s.fr.frame_index = (uint32_t)fi;
            frame_image(&s, img);
            compare(img, full, &e, &m);
            one[b] += e / FRAMES;
            for (p = 0; p < W * H; ++p) {
                mean[b][p * 3] += img[p * 4] / FRAMES;
                mean[b][p * 3 + 1] += img[p * 4 + 1] / FRAMES;
                mean[b][p * 3 + 2] += img[p * 4 + 2] / FRAMES;
            }
            if (fi == 0) {
                gim_stats st;
                uint32_t k, n = 0;
                gim_frame_outputs o = gim_outputs(s.f.ctx);
                assert_int_equal(gim_frame_stats(s.f.ctx, &st), GIM_OK);
                for (k = 0; k < NL; ++k) n += o.lights[k].selected_count;
                if (b == 0) assert_int_equal(n, TOTAL);   /* the total, exactly */
                else assert_int_equal(n, TOTAL);   /* 20 to each of the 28 rendered, the zero ones too */
            }
        }
        for (p = 0; p < W * H; ++p) { mf[p * 4] = (float)mean[b][p * 3]; mf[p * 4 + 1] = (float)mean[b][p * 3 + 1];
                                       mf[p * 4 + 2] = (float)mean[b][p * 3 + 2]; mf[p * 4 + 3] = 1.0f; }
        compare(mf, full, &mae[b], &mx[b]);
    }
    print_message("BRSM, %d VALs in all, one frame vs FULL: rel. MAE shared %.4f, per light %.4f (ratio %.2f)\n", TOTAL,
                  one[0], one[1], one[0] / one[1]);
    print_message("BRSM, mean of %d frames vs FULL: rel. MAE shared %.4f, per light %.4f\n", FRAMES, mae[0], mae[1]);
    /* the mean converges on FULL: its error is the one-frame error over about sqrt(FRAMES) (the
       frames' selections are rotated, not independent, so allow a factor 2 over that) */
    assert_true(mae[0] < 2.0 * one[0] / sqrt((double)FRAMES) + 0.01);
    assert_true(mae[0] < 0.08);
    assert_true(one[0] <= one[1]);   /* sharing by importance does not do worse than per light */
    for (b = 0; b < 2; ++b) free(mean[b]);
    free(full);
    free(img);
    free(mf);
    street_end(&s);
    GLTEST_END();
}

/* The sky lights cost no RSM, the facade's back lights no VAL; with every light forced to
   render (the same lights turned down towards the street) the frame holds more GPU memory. */
static void skipped_lights(void **state) {
    street_fix s;
    gim_frame_outputs o;
    gim_stats st, st_all;
    uint32_t k;
    (void)state;
    GLTEST_BEGIN();
    street_begin(&s);
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    s.fr.lightskin.val_count = 512;
    s.fr.timing = 2;
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_OK);   /* builds the programs */
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_OK);
    o = gim_outputs(s.f.ctx);
    assert_int_equal(gim_frame_stats(s.f.ctx, &st), GIM_OK);
    assert_int_equal(o.light_count, NL);
    assert_int_equal(st.light_count, NL);
    assert_int_equal(st.rsm_count, 28);        /* the 4 sky lights culled */
    assert_int_equal(st.val_light_count, 24);  /* the 4 facade lights get no VALs */
    for (k = 0; k < NL; ++k) {
        const gim_light_outputs *lo = &o.lights[k];
        if (k >= 24 && k < 28) {
            assert_int_equal(lo->rendered, 0);
            assert_true(lo->rsm_position == 0 && lo->rsm_flux == 0 && lo->importance == 0 && lo->selected == 0);
            assert_int_equal(lo->selected_count, 0);
        } else if (k >= 28) {
            assert_int_equal(lo->rendered, 1);
            assert_true(lo->rsm_position != 0);
            assert_true(lo->importance_total == 0.0);
            assert_int_equal(lo->selected_count, 0);
            assert_true(lo->selected == 0);
        } else {
            assert_int_equal(lo->rendered, 1);
            assert_true(lo->importance_total > 0.0);
            assert_true(lo->selected_count > 0);
        }
    }
    print_message("32 lights: %u RSMs rendered, %u given VALs; RSM pass %.1f ms, frame %.1f ms, %.2f MiB\n",
                  (unsigned)st.rsm_count, (unsigned)st.val_light_count, st.pass_ms[GIM_PASS_RSM], st.frame_ms,
                  (double)st.gpu_bytes / 1048576.0);
    /* the same frame with the sky lights turned down: 32 RSMs and their memory */
    for (k = 24; k < 28; ++k) s.lights[k].direction = gim_v3(0.05f, -1.0f, 0.0f);
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_OK);
    assert_int_equal(gim_frame_stats(s.f.ctx, &st_all), GIM_OK);
    assert_int_equal(st_all.rsm_count, 32);
    print_message("all 32 rendered: RSM pass %.1f ms, frame %.1f ms, %.2f MiB\n", st_all.pass_ms[GIM_PASS_RSM],
                  st_all.frame_ms, (double)st_all.gpu_bytes / 1048576.0);
    /* 4 RSMs more: 4 x 24^2 texels x 52 bytes at least */
    assert_true(st_all.gpu_bytes >= st.gpu_bytes + 4u * RSM * RSM * 52u);
    street_end(&s);
    GLTEST_END();
}

/* 40 RSMs: six point lights (36 faces) and four spots, every method; the old code refused
   more than 16. */
static void above_old_limit(void **state) {
    street_fix s;
    gim_light l[10];
    gim_frame_outputs o;
    gim_debug_outputs od;
    gim_stats st;
    gim_method m[4] = {GIM_METHOD_LIGHTSKIN_BRSM, GIM_METHOD_LIGHTSKIN_FULL, GIM_METHOD_RSM_GATHER, GIM_METHOD_CLUSTERED};
    float *img = (float *)malloc((size_t)W * H * 16);
    int k, p;
    (void)state;
    GLTEST_BEGIN();
    street_begin(&s);
    for (k = 0; k < 10; ++k) {
        l[k] = s.lights[k * 2];
        l[k].rsm_size = 16;
        if (k < 6) l[k].type = GIM_LIGHT_POINT;
    }
    assert_int_equal(gim_set_lights(s.f.ctx, l, 10), GIM_OK);
    for (k = 0; k < 4; ++k) {
        double sum = 0.0;
        s.fr.method = m[k];
        s.fr.lightskin.val_count = 400;
        s.fr.vpl.count = 400;
        s.fr.gather.samples = 64;
        s.fr.vpl.paraboloid_size = 16;
        frame_image(&s, img);
        o = gim_outputs(s.f.ctx); od = gim_debug(s.f.ctx);
        assert_int_equal(gim_frame_stats(s.f.ctx, &st), GIM_OK);
        assert_int_equal(o.light_count, 40);
        /* the point lights' +y faces see only sky */
        assert_int_equal(st.rsm_count, 34);
        for (p = 0; p < W * H * 4; ++p) {
            assert_true(img[p] == img[p] && img[p] >= 0.0f);
            sum += img[p];
        }
        assert_true(sum > 0.0);
        if (m[k] == GIM_METHOD_CLUSTERED) assert_int_equal(od.first_bounce_count, 400);   /* the total, shared */
    }
    free(img);
    street_end(&s);
    GLTEST_END();
}

/* The lights from a GL buffer give the CPU array's image bit for bit; bad buffers refused. */
static void lights_buffer(void **state) {
    street_fix s;
    gim_light_std430 b[NL];
    float *a = (float *)malloc((size_t)W * H * 16), *c = (float *)malloc((size_t)W * H * 16);
    GLuint buf, small;
    uint32_t k;
    int errors;
    (void)state;
    GLTEST_BEGIN();
    street_begin(&s);
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    s.fr.lightskin.val_count = 300;
    frame_image(&s, a);
    memset(b, 0, sizeof b);
    for (k = 0; k < NL; ++k) {
        const gim_light *l = &s.lights[k];
        memcpy(b[k].color_power, l->color, 12);
        b[k].color_power[3] = l->type == GIM_LIGHT_DIRECTIONAL ? l->irradiance : l->intensity;
        b[k].position_cone[0] = l->position.x; b[k].position_cone[1] = l->position.y;
        b[k].position_cone[2] = l->position.z; b[k].position_cone[3] = l->cone_angle;
        b[k].direction_extent[0] = l->direction.x; b[k].direction_extent[1] = l->direction.y;
        b[k].direction_extent[2] = l->direction.z; b[k].direction_extent[3] = l->extent;
        b[k].type_square_size_fit[0] = (uint32_t)l->type;
        b[k].type_square_size_fit[1] = (uint32_t)l->square_cone;
        b[k].type_square_size_fit[2] = l->rsm_size;
        b[k].type_square_size_fit[3] = (uint32_t)l->fit_view;
    }
    buf = gltest_ssbo(sizeof b, b);
    assert_int_equal(gim_set_lights_buffer(s.f.ctx, buf, NL), GIM_OK);
    frame_image(&s, c);
    assert_memory_equal(a, c, (size_t)W * H * 16);
    assert_int_equal(gim_outputs(s.f.ctx).light_count, NL);
    /* the host changes its buffer: the next frame reads it again (one lamp off) */
    b[3].color_power[3] = 0.0f;
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buf);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof b, b);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    frame_image(&s, c);
    assert_memory_not_equal(a, c, (size_t)W * H * 16);
    s.lights[3].intensity = 0.0f;
    assert_int_equal(gim_set_lights(s.f.ctx, s.lights, NL), GIM_OK);
    frame_image(&s, a);
    assert_memory_equal(a, c, (size_t)W * H * 16);
    /* bad input: not a buffer, too small, a bad light (at gim_update) */
    errors = s.f.log.errors;
    assert_int_equal(gim_set_lights_buffer(s.f.ctx, 987654u, 4), GIM_ERROR_INVALID_ARGUMENT);
    small = gltest_ssbo(64, b);
    assert_int_equal(gim_set_lights_buffer(s.f.ctx, small, 2), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(s.f.log.errors, errors + 2);
    b[0].type_square_size_fit[0] = 9u;
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buf);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof b, b);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    assert_int_equal(gim_set_lights_buffer(s.f.ctx, buf, NL), GIM_OK);
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_ERROR_INVALID_ARGUMENT);
    b[0].type_square_size_fit[0] = (uint32_t)GIM_LIGHT_SPOT;
    b[0].position_cone[3] = 2.0f;   /* cone above 1.5 */
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, buf);
    glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof b, b);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(s.f.log.errors, errors + 4);
    s.f.log.errors = 0;   /* the expected ones */
    assert_int_equal(gim_set_lights_buffer(s.f.ctx, 0, 0), GIM_OK);   /* clears */
    assert_int_equal(gim_outputs(s.f.ctx).valid, 0);
    glDeleteBuffers(1, &buf);
    glDeleteBuffers(1, &small);
    free(a);
    free(c);
    street_end(&s);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(skipped_lights),
        cmocka_unit_test(lights_buffer),
        cmocka_unit_test(above_old_limit),
        cmocka_unit_test(full_matches_sum),
        cmocka_unit_test(brsm_shared_matches_sum),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
