/* CPU twins of the scene passes (no GL): the light's camera, the RSM texel (units and flux
   totals fixed by the physics, unit-free under a change of length unit), the G-buffer texel,
   the view-sample pixels and their unprojection, and argument errors. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define PI_D 3.14159265358979323846

/* A square [-h, h]^2 at y = 0 as two triangles, albedo (0.5, 0.25, 1), face normals. */
static void square(float h, float pos[18], float alb[6], gim_twin_scene *s) {
    const float p[18] = {-h, 0, -h, -h, 0, h, h, 0, h, -h, 0, -h, h, 0, h, h, 0, -h};
    int i;
    memcpy(pos, p, sizeof p);
    for (i = 0; i < 2; ++i) { alb[i * 3] = 0.5f; alb[i * 3 + 1] = 0.25f; alb[i * 3 + 2] = 1.0f; }
    memset(s, 0, sizeof *s);
    s->positions = pos;
    s->albedo = alb;
    s->triangle_count = 2;
}

/* Sum of the twin's green flux over the whole RSM, and of the area of lit texels. */
static double twin_total(const gim_twin_scene *s, const gim_light *l, float h, double *area) {
    float bmin[3], bmax[3];
    gim_rsm_view rv;
    uint32_t x, y, n = l->rsm_size;
    double sum = 0.0;
    bmin[0] = -h; bmin[1] = 0.0f; bmin[2] = -h;
    bmax[0] = h; bmax[1] = 0.0f; bmax[2] = h;
    rv.light = l; rv.bmin = bmin; rv.bmax = bmax;
    *area = 0.0;
    for (y = 0; y < n; ++y)
        for (x = 0; x < n; ++x) {
            gim_rsm_texel t;
            assert_int_equal(gim_rsm_texel_twin(s, &rv, x, y, &t), GIM_OK);
            sum += t.flux[1];
            if (t.lit) *area += t.area;
            assert_true(t.lit ? t.triangle < 2 : t.flux[1] == 0.0f);
        }
    return sum;
}

/* rho E (projected area) for the sun, tilted or not; rho I Omega for the spot; and the lit
   texels' areas A tile the surface (sun: the plane's area; spot: the area inside the cone). */
static void flux_totals(void **state) {
    float pos[18], alb[6];
    gim_twin_scene s;
    gim_light l;
    double t, area;
    (void)state;
    square(1.0f, pos, alb, &s);
    memset(&l, 0, sizeof l);
    l.irradiance = 3.0f;
    l.direction = gim_v3(0.0f, 1.0f, 0.0f);
    l.extent = 2.0f;
    l.rsm_size = 32;
    t = twin_total(&s, &l, 1.0f, &area);
    assert_true(fabs(t - 0.25 * 3.0 * 4.0) < 1e-5);
    assert_true(fabs(area - 4.0) < 1e-5);
    l.direction = gim_v3(0.0f, 0.75f, sqrtf(1.0f - 0.5625f));
    t = twin_total(&s, &l, 1.0f, &area);
    assert_true(fabs(t - 0.25 * 3.0 * 3.0) < 1e-5);   /* projected area 4 x 0.75 */
    assert_true(fabs(area - 4.0) < 1e-4);             /* A = a / cos tiles the plane */
    square(0.5f, pos, alb, &s);
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.intensity = 7.0f;
    l.position = gim_v3(0.0f, 1.0f, 0.0f);
    l.direction = gim_v3(0.0f, -1.0f, 0.0f);
    l.cone_angle = (float)(PI_D / 4.0);
    l.rsm_size = 64;
    t = twin_total(&s, &l, 0.5f, &area);
    assert_true(fabs(t - 0.25 * 7.0 * 4.0 * asin(0.2)) < 1e-3 * t);
    assert_true(fabs(area - 1.0) < 1e-3);              /* the square's area */
    /* a coarser RSM is further off: the test above is not loose */
    l.rsm_size = 4;
    t = twin_total(&s, &l, 0.5f, &area);
    assert_true(fabs(t - 0.25 * 7.0 * 4.0 * asin(0.2)) > 1e-3 * t);
}

/* The same scene in millimetres: positions and areas scale, irradiance per mm^2 is 10^-6 of
   per m^2, so the flux is the same; the spot's intensity per sr is unit-free. */
static void unit_free(void **state) {
    float pos[18], alb[6], posmm[18], bmin[3] = {-1, 0, -1}, bmax[3] = {1, 0, 1}, bminmm[3], bmaxmm[3];
    gim_twin_scene s, smm;
    gim_light l, lmm;
    gim_rsm_texel a, b;
    int i, k;
    (void)state;
    square(1.0f, pos, alb, &s);
    smm = s;
    for (i = 0; i < 18; ++i) posmm[i] = pos[i] * 1000.0f;
    for (i = 0; i < 3; ++i) { bminmm[i] = bmin[i] * 1000.0f; bmaxmm[i] = bmax[i] * 1000.0f; }
    smm.positions = posmm;
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.intensity = 2.0f;
    l.position = gim_v3(0.3f, 1.5f, -0.2f);
    l.direction = gim_v3(-0.2f, -1.0f, 0.1f);
    l.cone_angle = 0.6f;
    l.rsm_size = 16;
    lmm = l;
    lmm.position = gim__v3_scale(l.position, 1000.0f);
    for (k = 0; k < 2; ++k) {
        if (k) { /* the sun */
            memset(&l, 0, sizeof l);
            l.irradiance = 5.0f;
            l.direction = gim_v3(0.3f, 1.0f, 0.4f);
            l.rsm_size = 16;
            lmm = l;
            lmm.irradiance = 5e-6f;
        }
        for (i = 0; i < 256; ++i) {
            gim_rsm_view rv = {&l, bmin, bmax}, rvmm = {&lmm, bminmm, bmaxmm};
            assert_int_equal(gim_rsm_texel_twin(&s, &rv, (uint32_t)i % 16, (uint32_t)i / 16, &a), GIM_OK);
            assert_int_equal(gim_rsm_texel_twin(&smm, &rvmm, (uint32_t)i % 16, (uint32_t)i / 16, &b), GIM_OK);
            assert_int_equal(a.lit, b.lit);
            assert_int_equal(a.triangle, b.triangle);
            if (a.triangle == UINT32_MAX) continue;
            assert_true(fabsf(a.flux[1] - b.flux[1]) <= 1e-4f * a.flux[1]);
            assert_true(fabsf(a.area * 1e6f - b.area) <= 1e-4f * b.area);
            assert_true(fabsf(a.position[0] * 1000.0f - b.position[0]) <= 1e-3f);
            assert_true(fabsf(a.depth - b.depth) <= 1e-5f);
        }
    }
}

/* The light's camera looks where it should: the spot's axis through the RSM centre, the
   sun's view along -direction, the bounds inside the depth range. */
static void light_camera(void **state) {
    float bmin[3] = {-3, -1, -2}, bmax[3] = {5, 2, 4};
    gim_light l;
    gim_mat4 v, p, vp;
    gim_vec3 c;
    int k;
    (void)state;
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.intensity = 1.0f;
    l.position = gim_v3(1.0f, 8.0f, 1.0f);
    l.direction = gim_v3(0.0f, -1.0f, 0.0f); /* along an axis: the up vector must not fold */
    l.cone_angle = 1.2f;
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_OK);
    vp = gim_mat4_mul(p, v);
    c = gim_mat4_point(vp, gim_v3(1.0f, 0.0f, 1.0f));
    assert_true(fabsf(c.x) < 1e-5f && fabsf(c.y) < 1e-5f && c.z > -1.0f && c.z < 1.0f);
    for (k = 0; k < 8; ++k) { /* every corner in front of the near plane and before the far one */
        gim_vec4 q, w;
        q.x = (k & 1) ? bmax[0] : bmin[0]; q.y = (k & 2) ? bmax[1] : bmin[1]; q.z = (k & 4) ? bmax[2] : bmin[2]; q.w = 1.0f;
        w = gim__mat4_vec4(vp, q);
        assert_true(w.w > 0.0f && w.z / w.w > -1.0f && w.z / w.w < 1.0f);
    }
    memset(&l, 0, sizeof l);
    l.irradiance = 1.0f;
    l.direction = gim_v3(0.2f, 1.0f, -0.3f);
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_OK);
    vp = gim_mat4_mul(p, v);
    for (k = 0; k < 8; ++k) {
        gim_vec3 q = gim_mat4_point(vp, gim_v3((k & 1) ? bmax[0] : bmin[0], (k & 2) ? bmax[1] : bmin[1], (k & 4) ? bmax[2] : bmin[2]));
        assert_true(q.x > -1.0f && q.x < 1.0f && q.y > -1.0f && q.y < 1.0f && q.z > -1.0f && q.z < 1.0f);
    }
    {   /* the view looks along -direction */
        gim_vec3 d = gim_v3_normalize(l.direction), f = gim_v3(-v.m[2], -v.m[6], -v.m[10]);
        assert_true(fabsf(gim__v3_dot(d, f) + 1.0f) < 1e-5f);
    }
    {   /* extent 0: the window is the bounds' shadow, a rectangle the corners touch on all four
           sides (within the margin, 0.1% of the bounds' radius): a long street under a high sun fills it, where the
           sphere's square left 78% of it empty; extent > 0 a square of that half-width */
        float lmin[3] = {-50, 0, -4}, lmax[3] = {50, 6, 4}, lo[2] = {2, 2}, hi[2] = {-2, -2};
        l.direction = gim_v3(0.1f, 1.0f, 0.05f);
        assert_int_equal(gim_light_camera(&l, lmin, lmax, &v, &p), GIM_OK);
        vp = gim_mat4_mul(p, v);
        for (k = 0; k < 8; ++k) {
            gim_vec3 q = gim_mat4_point(vp, gim_v3((k & 1) ? lmax[0] : lmin[0], (k & 2) ? lmax[1] : lmin[1],
                                                   (k & 4) ? lmax[2] : lmin[2]));
            if (q.x < lo[0]) lo[0] = q.x;
            if (q.x > hi[0]) hi[0] = q.x;
            if (q.y < lo[1]) lo[1] = q.y;
            if (q.y > hi[1]) hi[1] = q.y;
        }
        for (k = 0; k < 2; ++k) assert_true(lo[k] > -1.0f && lo[k] < -0.98f && hi[k] < 1.0f && hi[k] > 0.98f);
        /* the window: 100.x long, 8.x wide (the street seen from above), not the sphere's 100.9 square */
        {
            float w = 2.0f / p.m[0], h = 2.0f / p.m[5], big = w > h ? w : h, small = w > h ? h : w;
            print_message("sun window %.3f x %.3f\n", w, h);
            assert_true(big > 100.0f && big < 104.0f && small > 8.0f && small < 20.0f);
        }
        l.extent = 30.0f;
        assert_int_equal(gim_light_camera(&l, lmin, lmax, &v, &p), GIM_OK);
        assert_true(fabsf(2.0f / p.m[0] - 60.0f) < 1e-3f && fabsf(2.0f / p.m[5] - 60.0f) < 1e-3f);
        l.extent = 0.0f;
        l.direction = gim_v3(0.2f, 1.0f, -0.3f);
    }
    /* errors: NULL, empty or non-finite bounds, bad light */
    assert_int_equal(gim_light_camera(NULL, bmin, bmax, &v, &p), GIM_ERROR_INVALID_ARGUMENT);
    bmin[0] = NAN;
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_ERROR_INVALID_ARGUMENT);
    bmin[0] = 6.0f;
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_ERROR_INVALID_ARGUMENT);
    bmin[0] = bmax[0]; bmin[1] = bmax[1]; bmin[2] = bmax[2];
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_ERROR_OUT_OF_RANGE);
    bmin[0] = -3;
    l.direction = gim_v3(0.0f, 0.0f, 0.0f);
    assert_int_equal(gim_light_camera(&l, bmin, bmax, &v, &p), GIM_ERROR_INVALID_ARGUMENT);
}

/* The G-buffer twin sees the square through a camera; the view samples unproject back onto it. */
static void gbuffer_and_view_samples(void **state) {
    enum { W = 32, H = 24, N = 64 };
    float pos[18], alb[6], depth[W * H], nrm[W * H * 4], off[2];
    gim_twin_scene s;
    gim_mat4 v = gim_mat4_look_at(gim_v3(0.5f, 2.0f, 1.5f), gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    gim_mat4 p = gim_mat4_perspective(1.0f, (float)W / H, 0.1f, 10.0f);
    gim_camera cam = {v, p, W, H}, flat = {v, gim_mat4_ortho(0, 0, 0, 1, 0, 1), W, H};
    gim_view_sample vs[N];
    uint32_t px[N * 2], px2[N * 2];
    int i, hits = 0;
    (void)state;
    square(1.0f, pos, alb, &s);
    for (i = 0; i < W * H; ++i) {
        gim_gbuffer_texel t;
        assert_int_equal(gim_gbuffer_texel_twin(&s, &cam, (uint32_t)(i % W), (uint32_t)(i / W), &t), GIM_OK);
        depth[i] = t.depth;
        memcpy(nrm + i * 4, t.normal, 3 * sizeof(float));
        nrm[i * 4 + 3] = t.triangle == UINT32_MAX ? 0.0f : 1.0f;
        if (t.triangle != UINT32_MAX) {
            hits++;
            assert_true(fabsf(t.position[1]) < 1e-5f && t.normal[1] == 1.0f && t.albedo[1] == 0.25f);
        } else {
            assert_true(t.depth == 1.0f && t.normal[1] == 0.0f);
        }
    }
    assert_true(hits > W * H / 4 && hits < W * H);
    assert_int_equal(gim_view_sample_pixels(N, W, H, NULL, px), GIM_OK);
    for (i = 0; i < N; ++i) { /* Halton points 1.. in bases 2 and 3 */
        assert_int_equal(px[2 * i], (uint32_t)floor(gim_halton((uint32_t)i + 1, 0) * W));
        assert_int_equal(px[2 * i + 1], (uint32_t)floor(gim_halton((uint32_t)i + 1, 1) * H));
    }
    gim_rotation_offsets(off, 2, 9);
    assert_int_equal(gim_view_sample_pixels(N, W, H, off, px2), GIM_OK);
    assert_memory_not_equal(px, px2, sizeof px);
    assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, px2, N, vs), GIM_OK);
    for (i = 0; i < N; ++i) {
        uint32_t k = px2[2 * i + 1] * W + px2[2 * i];
        if (depth[k] >= 1.0f) {
            assert_true(vs[i].normal.y == 0.0f && vs[i].position.x == 0.0f);
            continue;
        }
        assert_true(fabsf(vs[i].position.y) < 1e-4f); /* back on the plane */
        assert_true(fabsf(vs[i].position.x) <= 1.0f + 1e-4f && fabsf(vs[i].position.z) <= 1.0f + 1e-4f);
        assert_true(vs[i].normal.y == 1.0f);
    }
    /* errors */
    off[0] = 1.0f;
    assert_int_equal(gim_view_sample_pixels(N, W, H, off, px2), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_view_sample_pixels(0, W, H, NULL, px2), GIM_ERROR_INVALID_ARGUMENT);
    px2[0] = W;
    assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, px2, N, vs), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_view_samples_twin(depth, nrm, &flat, px, N, vs), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_view_samples_twin(depth, nrm, NULL, px, N, vs), GIM_ERROR_INVALID_ARGUMENT);
    {
        gim_gbuffer_texel t;
        pos[4] = NAN;
        assert_int_equal(gim_gbuffer_texel_twin(&s, &cam, 0, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
        pos[4] = 0.0f;
        assert_int_equal(gim_gbuffer_texel_twin(&s, &cam, W, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim_gbuffer_texel_twin(NULL, &cam, 0, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim_gbuffer_texel_twin(&s, NULL, 0, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
    }
}

/* Bad lights logged through the env with the light's index. */
static void light_checks_log(void **state) {
    test_log log;
    gim_env env = test_env(NULL, &log);
    gim_light l;
    float bmin[3] = {0, 0, 0}, bmax[3] = {1, 1, 1}, pos[18], alb[6];
    gim_twin_scene s;
    gim_rsm_texel t;
    gim_rsm_view rv = {&l, bmin, bmax};
    (void)state;
    memset(&l, 0, sizeof l);
    l.direction = gim_v3(0.0f, 1.0f, 0.0f);
    l.irradiance = INFINITY;
    assert_int_equal(gim__light_check(&l, &env, "test", 3), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(log.errors, 1);
    assert_non_null(strstr(log.last, "light 3"));
    l.irradiance = 1.0f;
    l.color[1] = -1.0f;
    assert_int_equal(gim__light_check(&l, &env, "test", 0), GIM_ERROR_INVALID_ARGUMENT);
    l.color[1] = 0.0f;
    l.extent = NAN;
    assert_int_equal(gim__light_check(&l, &env, "test", 0), GIM_ERROR_INVALID_ARGUMENT);
    l.extent = 0.0f;
    assert_int_equal(gim__light_check(&l, &env, "test", 0), GIM_OK);
    square(1.0f, pos, alb, &s);
    l.rsm_size = 8;
    assert_int_equal(gim_rsm_texel_twin(&s, &rv, 8, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_rsm_texel_twin(&s, &rv, 0, 0, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_rsm_texel_twin(&s, NULL, 0, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
    s.triangle_count = 0;
    assert_int_equal(gim_rsm_texel_twin(&s, &rv, 0, 0, &t), GIM_ERROR_INVALID_ARGUMENT);
    /* a scene 1e25 across: areas and fluxes beyond float clamp at FLT_MAX, never inf */
    square(1e25f, pos, alb, &s);
    bmin[0] = bmin[2] = -1e25f; bmax[0] = bmax[2] = 1e25f; bmax[1] = 0.0f;
    assert_int_equal(gim_rsm_texel_twin(&s, &rv, 4, 4, &t), GIM_OK);
    assert_true(t.lit && t.area == FLT_MAX && t.flux[1] == FLT_MAX && gim__all_finite(t.position, 3));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(flux_totals),
        cmocka_unit_test(unit_free),
        cmocka_unit_test(light_camera),
        cmocka_unit_test(gbuffer_and_view_samples),
        cmocka_unit_test(light_checks_log),
    };
    return cmocka_run_group_tests_name("scene twins", tests, NULL, NULL);
}
