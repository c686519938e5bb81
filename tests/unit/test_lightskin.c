/* LightSkin cache lighting twins (Bischoff 2017 sec. 3-4): eq. 3/4 by hand, eq. 7's guard, BRSM
   weights 1/(N P) converging to FULL like 1/sqrt(N), low variance with P ~ contribution,
   guards (grazing, coincident, zero flux, k = 0/1/1e4, coincident caches), interpolation at a
   cache, scale invariance, energy against an analytic form factor, errors, memory. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define PI_D 3.14159265358979323846

static gim_cache mk_cache(float x, float y, float z, float nx, float ny, float nz, float area) {
    gim_cache c;
    gim_vec3 n = gim_v3_normalize(gim_v3(nx, ny, nz));
    memset(&c, 0, sizeof c);
    c.position[0] = x; c.position[1] = y; c.position[2] = z;
    c.normal[0] = n.x; c.normal[1] = n.y; c.normal[2] = n.z;
    c.area = area; c.reflectance = 1.0f;
    return c;
}
static gim_val mk_val(float x, float y, float z, float nx, float ny, float nz, float area, float r, float g, float b) {
    gim_val v;
    gim_vec3 n = gim_v3_normalize(gim_v3(nx, ny, nz));
    memset(&v, 0, sizeof v);
    v.position[0] = x; v.position[1] = y; v.position[2] = z;
    v.normal[0] = n.x; v.normal[1] = n.y; v.normal[2] = n.z;
    v.area = area; v.weight = 1.0f;
    v.flux[0] = r; v.flux[1] = g; v.flux[2] = b;
    return v;
}
static gim_receiver mk_recv(const gim_cache *c, float vx, float vy, float vz, float albedo, float glossy, float k) {
    gim_receiver r;
    gim_vec3 v = gim_v3_normalize(gim_v3(vx, vy, vz));
    int a;
    memset(&r, 0, sizeof r);
    for (a = 0; a < 3; ++a) { r.position[a] = c->position[a]; r.normal[a] = c->normal[a]; r.albedo[a] = albedo; r.glossy[a] = glossy; }
    r.view[0] = v.x; r.view[1] = v.y; r.view[2] = v.z;
    r.exponent = k;
    return r;
}
static gim_proxy_desc proxy_desc(const gim_cache *c, uint32_t nc, const gim_val *v, uint32_t nv, gim_env env) {
    gim_proxy_desc d;
    memset(&d, 0, sizeof d);
    d.caches = c; d.cache_count = nc; d.vals = v; d.val_count = nv; d.env = env;
    return d;
}
static int all_ok_light(const gim_proxy_light *p) {
    int a;
    for (a = 0; a < 3; ++a)
        if (!isfinite(p->position[a]) || !isfinite(p->flux[a]) || !isfinite(p->sigma[a]) || p->flux[a] < 0.0f || p->sigma[a] < 0.0f)
            return 0;
    return isfinite(p->radius) && p->radius >= 0.0f && p->visibility >= 0.0f && p->visibility <= 1.0f;
}

/* Radiance at each cache's own position with itself as the only neighbour (d_c,max = 0):
   the receiver sees exactly the cache's proxy lights. out[nc * 3]. */
static void radiance_at_caches(const gim_cache *c, uint32_t nc, const gim_proxy_light *d, const gim_proxy_light *g,
                               const gim_receiver *recv, float scale, float *out) {
    gim_shade_desc sd;
    uint32_t *idx = (uint32_t *)malloc(nc * sizeof(uint32_t)), i;
    float *dc = (float *)calloc(nc, sizeof(float));
    assert_non_null(idx); assert_non_null(dc);
    for (i = 0; i < nc; ++i) idx[i] = i;
    memset(&sd, 0, sizeof sd);
    sd.caches = c; sd.cache_count = nc; sd.diffuse = d; sd.glossy = g;
    sd.receivers = recv; sd.receiver_count = nc;
    sd.neighbour_index = idx; sd.neighbour_stride = 1; sd.d_cmax = dc; sd.scene_scale = scale;
    assert_int_equal(gim_lightskin_shade_twin(&sd, out), GIM_OK);
    free(idx); free(dc);
}

/* eq. 3 by hand: one VAL facing a cache on axis at distance d: E = Phi A / (A + pi d^2) / A, the
   disk form factor A / (A + pi d^2) times the VAL's exitance Phi / A; then off axis. */
static void eq3_hand_computed(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    gim_cache c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    gim_val v = mk_val(0, 0, 2, 0, 0, -1, 0.5f, 1, 2, 3);
    gim_proxy_light pd;
    gim_proxy_desc d = proxy_desc(&c, 1, &v, 1, env);
    gim_receiver r = mk_recv(&c, 0, 0, 1, 0.6f, 0, 1);
    float L[3];
    double F = 0.5 / (0.5 + PI_D * 4.0), ex;
    int a;
    (void)state;
    assert_int_equal(gim_proxy_lights_twin(&d, &pd, NULL), GIM_OK);
    assert_float_equal(pd.position[2], 2.0f, 1e-6f);
    assert_float_equal(pd.radius, 0.0f, 1e-6f);
    assert_float_equal(pd.visibility, 1.0f, 0.0f);
    for (a = 0; a < 3; ++a) {
        ex = (a + 1.0) / 0.5 * F;                               /* E = M F */
        assert_true(fabs(pd.flux[a] - 4.0 * PI_D * 4.0 * ex) <= 1e-5 * 4.0 * PI_D * 4.0 * ex);   /* eq. 7 */
    }
    radiance_at_caches(&c, 1, &pd, NULL, &r, 10.0f, L);
    for (a = 0; a < 3; ++a) {
        ex = 0.6 / PI_D * (a + 1.0) * 0.5 / 0.5 * 1.0 / (0.5 + PI_D * 4.0);   /* eq. 3 */
        assert_true(fabs(L[a] - ex) <= 1e-5 * ex);
    }
    /* off axis: VAL at (3,0,4) facing down: d = 5, cos_x = cos_l = 0.8 */
    v = mk_val(3, 0, 4, 0, 0, -1, 0.25f, 2, 2, 2);
    assert_int_equal(gim_proxy_lights_twin(&d, &pd, NULL), GIM_OK);
    radiance_at_caches(&c, 1, &pd, NULL, &r, 10.0f, L);
    ex = 0.6 / PI_D * 2.0 * 0.64 / (0.25 + PI_D * 25.0);
    assert_true(fabs(L[0] - ex) <= 1e-5 * ex);
    assert_true(fabs(pd.flux[0] - 4.0 * PI_D * 25.0 * 2.0 * 0.64 / (0.25 + PI_D * 25.0) / 0.8) <= 1e-5 * pd.flux[0]);
    assert_int_equal(lg.errors, 0);
    assert_int_equal(as.live, 0);
}

/* eq. 4 by hand: the same VAL off axis, an eye off the mirror direction, k = 1, 10, 100. */
static void eq4_hand_computed(void **state) {
    static const float ks[] = {1.0f, 10.0f, 100.0f};
    gim_cache c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    gim_val v = mk_val(3, 0, 4, -3, 0, -4, 0.25f, 1, 1, 1);    /* facing the cache: cos_l = 1 */
    gim_proxy_light pd, pg;
    gim_proxy_desc d = proxy_desc(&c, 1, &v, 1, test_env(NULL, NULL));
    size_t i;
    (void)state;
    d.eye = gim_v3(-5.0f, 1.0f, 9.0f);
    for (i = 0; i < 3; ++i) {
        gim_vec3 vv = gim_v3_normalize(d.eye);
        gim_receiver r = mk_recv(&c, vv.x, vv.y, vv.z, 0.0f, 0.7f, ks[i]);
        double re = -0.6 * vv.x + 0.8 * vv.z;                    /* r = (-0.6, 0, 0.8) */
        double e = 0.8 / (0.25 + PI_D * 25.0);
        double ex = 0.7 * (ks[i] + 2.0) / (2.0 * PI_D) * pow(re, ks[i]) * e;
        float L[3];
        d.glossy_exponent = ks[i];
        assert_int_equal(gim_proxy_lights_twin(&d, &pd, &pg), GIM_OK);
        radiance_at_caches(&c, 1, &pd, &pg, &r, 10.0f, L);
        assert_true(fabs(L[1] - ex) <= 2e-5 * ex);
        assert_true(ex > 1e-6);
    }
}

/* A random scene: nc caches near the floor facing up, nv VALs above on a tilted ceiling. */
static void random_scene(gim_cache *c, uint32_t nc, gim_val *v, uint32_t nv) {
    uint32_t i;
    for (i = 0; i < nc; ++i)
        c[i] = mk_cache((float)(4.0 * test_rand01() - 2.0), (float)(4.0 * test_rand01() - 2.0), (float)(0.2 * test_rand01()),
                        (float)(0.4 * test_rand01() - 0.2), (float)(0.4 * test_rand01() - 0.2), 1.0f, 0.3f);
    for (i = 0; i < nv; ++i) {
        float x = (float)(8.0 * test_rand01() - 4.0), y = (float)(8.0 * test_rand01() - 4.0);
        float z = 2.0f + 0.3f * x + (float)(0.5 * test_rand01());
        v[i] = mk_val(x, y, z, (float)(0.6 * test_rand01() - 0.3), (float)(0.6 * test_rand01() - 0.3), -1.0f,
                      0.01f, (float)test_rand01(), (float)test_rand01(), (float)test_rand01());
    }
}

/* Draw n VALs i.i.d. with probabilities p (cumulative cdf), weighted 1/(n P). */
static void draw_brsm(const gim_val *all, const double *p, const double *cdf, uint32_t nv, uint32_t n, gim_val *out) {
    uint32_t i;
    for (i = 0; i < n; ++i) {
        double u = test_rand01() * cdf[nv - 1];
        uint32_t lo = 0, hi = nv - 1;
        while (lo < hi) { uint32_t mid = (lo + hi) / 2; if (cdf[mid] > u) hi = mid; else lo = mid + 1; }
        out[i] = all[lo];
        out[i].weight = (float)(1.0 / ((double)n * p[lo]));
    }
}

/* Diffuse radiance (albedo 1, green channel) at every cache from the given VALs. */
static void cache_radiance(const gim_cache *c, uint32_t nc, const gim_val *v, uint32_t nv, double *out) {
    gim_proxy_light pd[16];
    gim_receiver r[16];
    float L[16 * 3];
    gim_proxy_desc d = proxy_desc(c, nc, v, nv, test_env(NULL, NULL));
    uint32_t i;
    assert_true(nc <= 16);
    d.scene_scale = 10.0f;
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    for (i = 0; i < nc; ++i) r[i] = mk_recv(c + i, 0, 0, 1, 1.0f, 0.0f, 1.0f);
    radiance_at_caches(c, nc, pd, NULL, r, 10.0f, L);
    for (i = 0; i < nc; ++i) out[i] = L[i * 3 + 1];
}

/* BRSM with weights 1/(N P), P non-uniform and unrelated to the light: unbiased, and the error
   against FULL falls like 1/sqrt(N). */
static void brsm_converges_to_full(void **state) {
    enum { NC = 8, NV = 4096, TRIALS = 24 };
    static const uint32_t ns[] = {64, 256, 1024, 4096};
    gim_cache c[NC];
    gim_val *all = (gim_val *)malloc(NV * sizeof(gim_val)), *sel = (gim_val *)malloc(4096 * sizeof(gim_val));
    double *p = (double *)malloc(NV * sizeof(double)), *cdf = (double *)malloc(NV * sizeof(double));
    double full[NC], est[NC], err[4], sum = 0.0;
    uint32_t i, t, k, j;
    (void)state;
    test_rng_state = 42;
    random_scene(c, NC, all, NV);
    for (i = 0; i < NV; ++i) { double u = test_rand01(); p[i] = 0.05 + u * u; sum += p[i]; }
    for (i = 0; i < NV; ++i) { p[i] /= sum; cdf[i] = (i ? cdf[i - 1] : 0.0) + p[i]; }
    cache_radiance(c, NC, all, NV, full);
    for (i = 0; i < NC; ++i) assert_true(full[i] > 0.0);
    for (k = 0; k < 4; ++k) {
        double se = 0.0, mean[NC];
        memset(mean, 0, sizeof mean);
        for (t = 0; t < TRIALS; ++t) {
            draw_brsm(all, p, cdf, NV, ns[k], sel);
            cache_radiance(c, NC, sel, ns[k], est);
            for (j = 0; j < NC; ++j) {
                double rel = est[j] / full[j] - 1.0;
                se += rel * rel;
                mean[j] += est[j] / full[j] / TRIALS;
            }
        }
        err[k] = sqrt(se / (TRIALS * NC));
        /* unbiased: the mean over the trials is within 4 standard errors of FULL */
        for (j = 0; j < NC; ++j) assert_true(fabs(mean[j] - 1.0) <= 4.0 * err[k] / sqrt((double)TRIALS) + 1e-4);
        print_message("N = %4u: relative RMS error %.4f (x sqrt(N) = %.3f)\n", ns[k], err[k], err[k] * sqrt((double)ns[k]));
    }
    for (k = 1; k < 4; ++k) assert_true(err[k] / err[k - 1] > 0.35 && err[k] / err[k - 1] < 0.7);   /* 1/2 per 4x */
    assert_true(err[3] / err[0] > 1.0 / 16.0 && err[3] / err[0] < 1.0 / 5.0);                       /* 1/8 */
    free(all); free(sel); free(p); free(cdf);
}

/* P proportional to each VAL's contribution to cache 0: its estimate has (nearly) no variance,
   far below uniform P's. */
static void proportional_pdf_low_variance(void **state) {
    enum { NV = 1024, N = 64, TRIALS = 16 };
    gim_cache c[1];
    gim_val *all = (gim_val *)malloc(NV * sizeof(gim_val)), sel[N];
    double p[NV], cdf[NV], pu[NV], cdfu[NV], full, est, sum = 0.0, se_p = 0.0, se_u = 0.0;
    uint32_t i, t;
    (void)state;
    test_rng_state = 7;
    random_scene(c, 1, all, NV);
    for (i = 0; i < NV; ++i) {   /* grey flux so every channel is proportional */
        gim_val *v = all + i;
        double dx = v->position[0] - c[0].position[0], dy = v->position[1] - c[0].position[1], dz = v->position[2] - c[0].position[2];
        double d2 = dx * dx + dy * dy + dz * dz, dl = sqrt(d2);
        double cx = (c[0].normal[0] * dx + c[0].normal[1] * dy + c[0].normal[2] * dz) / dl;
        double cl = -(v->normal[0] * dx + v->normal[1] * dy + v->normal[2] * dz) / dl;
        v->flux[1] = v->flux[2] = v->flux[0];
        p[i] = (cx > 0 && cl > 0) ? v->flux[0] * cx * cl / (v->area + PI_D * d2) : 0.0;
        sum += p[i];
        pu[i] = 1.0 / NV; cdfu[i] = (i + 1.0) / NV;
    }
    for (i = 0; i < NV; ++i) { p[i] /= sum; cdf[i] = (i ? cdf[i - 1] : 0.0) + p[i]; }
    cache_radiance(c, 1, all, NV, &full);
    for (t = 0; t < TRIALS; ++t) {
        draw_brsm(all, p, cdf, NV, N, sel);
        cache_radiance(c, 1, sel, N, &est);
        se_p += (est / full - 1.0) * (est / full - 1.0);
        draw_brsm(all, pu, cdfu, NV, N, sel);
        cache_radiance(c, 1, sel, N, &est);
        se_u += (est / full - 1.0) * (est / full - 1.0);
    }
    se_p = sqrt(se_p / TRIALS); se_u = sqrt(se_u / TRIALS);
    print_message("P ~ contribution: %.2e, uniform P: %.2e\n", se_p, se_u);
    assert_true(se_p < 1e-4);
    assert_true(se_u > 1e-2);
    free(all);
}

/* eq. 7's guard: the proxy's normal irradiance Phi_p / (4 pi d_p^2) never exceeds E_n, the
   irradiance its VALs deliver perpendicular to their directions; exact for one VAL. */
static void flux_guard_bound(void **state) {
    static const float ks[] = {0.0f, 1.0f, 50.0f, 1e4f};
    gim_cache c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    gim_val v[2];
    gim_proxy_light pd, pg;
    gim_proxy_desc d;
    size_t i;
    (void)state;
    /* two VALs on opposite sides, low: the mean direction is steep, the lobe sees one side */
    v[0] = mk_val(-4, 0, 1, 4, 0, -1, 0.1f, 1, 1, 1);
    v[1] = mk_val(4, 0, 1, -4, 0, -1, 0.1f, 1, 1, 1);
    d = proxy_desc(&c, 1, v, 2, test_env(NULL, NULL));
    d.eye = gim_v3(-8, 0, 2.0f);                     /* mirror of VAL 1's direction */
    for (i = 0; i < 4; ++i) {
        double en = 0.0, dp2 = 0.0;
        int j, a;
        d.glossy_exponent = ks[i];
        assert_int_equal(gim_proxy_lights_twin(&d, &pd, &pg), GIM_OK);
        assert_true(all_ok_light(&pd) && all_ok_light(&pg));
        for (j = 0; j < 2; ++j) {
            double dx = v[j].position[0], dz = v[j].position[2], d2 = dx * dx + dz * dz, dl = sqrt(d2);
            double cl = -(v[j].normal[0] * dx + v[j].normal[2] * dz) / dl;
            en += cl / (v[j].area + PI_D * d2);
        }
        for (a = 0; a < 3; ++a) dp2 += (double)pg.position[a] * pg.position[a];
        assert_true(pg.flux[0] / (4.0 * PI_D * dp2) <= en * (1.0 + 1e-5));
        dp2 = 0.0;
        for (a = 0; a < 3; ++a) dp2 += (double)pd.position[a] * pd.position[a];
        assert_true(pd.flux[0] / (4.0 * PI_D * dp2) <= en * (1.0 + 1e-5));
        assert_true(pd.flux[0] > 0.0f);
    }
    /* k = 1e4 straight at VAL 1: the glossy proxy sits on VAL 1, flux of VAL 1 alone */
    d.glossy_exponent = 1e4f;
    assert_int_equal(gim_proxy_lights_twin(&d, &pd, &pg), GIM_OK);
    assert_float_equal(pg.position[0], 4.0f, 1e-3f);
    assert_true(pg.flux[0] > 0.0f && isfinite(pg.flux[0]));
}

/* How much eq. 7's guard costs: a room corner (floor and wall VALs, floor and wall caches),
   the caches' own radiance reproduced from their proxy lights against the exact sums of eq. 3
   and 4. Diffuse: the guard never bites. Glossy: where it bites the cache's lobe sees little
   light, so the glossy energy over all caches stays within 2 %. Caches and VALs keep 0.3 from
   the contact edge, beyond the near field (2 sqrt(A) = 0.25), where eq. 3 is the disk formula. */
static void guard_bias(void **state) {
    enum { NC = 64, NV = 1024 };
    static const float ks[] = {8.0f, 100.0f, 1000.0f};
    gim_cache c[NC];
    gim_val *v = (gim_val *)malloc(NV * sizeof(gim_val));
    gim_proxy_light pd[NC], pg[NC];
    gim_receiver rd[NC], rg[NC];
    float Ld[NC * 3], Lg[NC * 3];
    gim_vec3 eye = gim_v3(-3, -2, 4);
    uint32_t i, j, ki;
    int a;
    (void)state;
    test_rng_state = 5;
    for (i = 0; i < NC; ++i)
        c[i] = (i % 2) ? mk_cache((float)(4 * test_rand01() - 2), (float)(4 * test_rand01() - 2), 0, 0, 0, 1, 0.1f)
                       : mk_cache(2, (float)(4 * test_rand01() - 2), (float)(0.3 + 1.7 * test_rand01()), -1, 0, 0, 0.1f);
    for (i = 0; i < NV; ++i)
        v[i] = (i % 2) ? mk_val((float)(3.7 * test_rand01() - 2), (float)(4 * test_rand01() - 2), 0, 0, 0, 1, 0.016f, 0, 0, 0)
                       : mk_val(-2, (float)(4 * test_rand01() - 2), (float)(0.3 + 1.7 * test_rand01()), 1, 0, 0, 0.016f, 0, 0, 0);
    for (i = 0; i < NV; ++i) v[i].flux[0] = v[i].flux[1] = v[i].flux[2] = (float)(0.016 * test_rand01());
    for (ki = 0; ki < 3; ++ki) {
        gim_proxy_desc d = proxy_desc(c, NC, v, NV, test_env(NULL, NULL));
        double ge = 0.0, gx = 0.0;
        int bites = 0;
        d.eye = eye; d.glossy_exponent = ks[ki];
        assert_int_equal(gim_proxy_lights_twin(&d, pd, pg), GIM_OK);
        for (i = 0; i < NC; ++i) {
            gim_vec3 vv = gim_v3_normalize(gim_v3(eye.x - c[i].position[0], eye.y - c[i].position[1], eye.z - c[i].position[2]));
            rd[i] = mk_recv(c + i, vv.x, vv.y, vv.z, 1.0f, 0.0f, ks[ki]);
            rg[i] = mk_recv(c + i, vv.x, vv.y, vv.z, 0.0f, 1.0f, ks[ki]);
        }
        radiance_at_caches(c, NC, pd, NULL, rd, 5.0f, Ld);
        radiance_at_caches(c, NC, pd, pg, rg, 5.0f, Lg);
        for (i = 0; i < NC; ++i) {
            double S = 0.0, G = 0.0, vv3[3];
            gim_vec3 vv = gim_v3_normalize(gim_v3(eye.x - c[i].position[0], eye.y - c[i].position[1], eye.z - c[i].position[2]));
            vv3[0] = vv.x; vv3[1] = vv.y; vv3[2] = vv.z;
            for (j = 0; j < NV; ++j) {
                double dx[3], d2 = 0.0, dl, cx = 0.0, cl = 0.0, re = 0.0, e;
                for (a = 0; a < 3; ++a) { dx[a] = (double)v[j].position[a] - c[i].position[a]; d2 += dx[a] * dx[a]; }
                dl = sqrt(d2);
                for (a = 0; a < 3; ++a) { cx += c[i].normal[a] * dx[a] / dl; cl -= v[j].normal[a] * dx[a] / dl; }
                if (cx <= 0.0 || cl <= 0.0) continue;
                e = v[j].flux[1] * cx * cl / (v[j].area + PI_D * d2);
                for (a = 0; a < 3; ++a) re += (2.0 * cx * c[i].normal[a] - dx[a] / dl) * vv3[a];
                S += e;
                G += re > 0.0 ? e * pow(re, ks[ki]) : 0.0;
            }
            assert_true(fabs(Ld[i * 3 + 1] - S / PI_D) <= 1e-4 * S / PI_D);                 /* eq. 3, no bias */
            G *= (ks[ki] + 2.0) / (2.0 * PI_D);
            assert_true(Lg[i * 3 + 1] <= G * (1.0 + 1e-4 + 1e-6 * ks[ki]) + 1e-12);   /* never more (float lobe: k eps) */
            bites += Lg[i * 3 + 1] < G * (1.0 - 1e-4);
            ge += Lg[i * 3 + 1]; gx += G;
        }
        print_message("k = %4g: glossy guard bites at %d of %d caches, glossy energy %.4f of exact\n", ks[ki], bites, NC, ge / gx);
        assert_true(ge >= 0.98 * gx);
    }
    free(v);
}

/* Degenerate VALs, caches and exponents: finite, non-negative outputs everywhere. */
static void guards_finite(void **state) {
    static const float ks[] = {0.0f, 1.0f, 1e4f};
    gim_cache c[3];
    gim_val v[6];
    gim_proxy_light pd[3], pg[3];
    gim_receiver r[3];
    gim_proxy_desc d;
    uint32_t idx[3 * 3], i, k;
    float dc[3], L[9];
    gim_shade_desc sd;
    (void)state;
    c[0] = mk_cache(0, 0, 0, 0, 0, 1, 1);
    c[1] = mk_cache(0, 0, 0, 0, 0, 1, 1);              /* coincident with cache 0 */
    c[2] = mk_cache(1, 0, 0, 0, 0, 1, 0);
    v[0] = mk_val(2, 0, 0, -1, 0, 0, 0.1f, 1, 1, 1);   /* in the cache's plane: cos_x = 0 */
    v[1] = mk_val(0, 0, 2, 1, 0, 0, 0.1f, 1, 1, 1);    /* grazing: cos_l = 0 */
    v[2] = mk_val(0, 0, 0, 0, 0, -1, 0.1f, 1, 1, 1);   /* at the cache */
    v[3] = mk_val(0, 0, 1e-30f, 0, 0, -1, 0.0f, 1, 1, 1); /* nearly at the cache, zero area */
    v[4] = mk_val(0, 0, 1e-3f, 0, 0, -1, 0.0f, 5, 5, 5); /* close, zero area */
    v[5] = mk_val(0, 1, 1, 0, -1, -1, 0.1f, 0, 0, 0);  /* zero flux */
    for (k = 0; k < 3; ++k) {
        uint32_t nv;
        for (nv = 1; nv <= 6; ++nv) {
            uint32_t first = nv - 1;          /* each VAL alone, then all six */
            uint32_t cnt = 1;
            if (nv == 6) { first = 0; cnt = 6; }
            d = proxy_desc(c, 3, v + first, cnt, test_env(NULL, NULL));
            d.eye = gim_v3(0, 3, 3); d.glossy_exponent = ks[k]; d.scene_scale = 4.0f;
            assert_int_equal(gim_proxy_lights_twin(&d, pd, pg), GIM_OK);
            for (i = 0; i < 3; ++i) assert_true(all_ok_light(pd + i) && all_ok_light(pg + i));
            if (nv <= 3) for (i = 0; i < 2; ++i) assert_true(pd[i].flux[0] == 0.0f);   /* caches 0, 1: dark */
            for (i = 0; i < 3; ++i) {
                r[i] = mk_recv(c + i, 0, 1, 1, 0.5f, 0.5f, ks[k]);
                idx[i * 3] = 0; idx[i * 3 + 1] = 1; idx[i * 3 + 2] = 2;
                dc[i] = i == 2 ? 1.0f : 0.0f;            /* coincident caches: d_c,max = 0 */
            }
            r[2].position[0] = 0.5f;
            memset(&sd, 0, sizeof sd);
            sd.caches = c; sd.cache_count = 3; sd.diffuse = pd; sd.glossy = pg;
            sd.receivers = r; sd.receiver_count = 3; sd.neighbour_index = idx; sd.neighbour_stride = 3;
            sd.d_cmax = dc; sd.scene_scale = 4.0f;
            assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);
            for (i = 0; i < 9; ++i) assert_true(isfinite(L[i]) && L[i] >= 0.0f);
        }
    }
    /* the in-plane and grazing VALs give no light; the coincident VAL none; zero flux none */
    for (i = 0; i < 3; ++i) {
        uint32_t which[] = {0, 1, 2};
        d = proxy_desc(c, 1, v + which[i], 1, test_env(NULL, NULL));
        d.scene_scale = 4.0f;
        assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
        assert_true(pd[0].flux[0] == 0.0f && all_ok_light(pd));
    }
    d = proxy_desc(c, 1, v + 5, 1, test_env(NULL, NULL));
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    assert_true(pd[0].flux[0] == 0.0f && all_ok_light(pd));
    assert_float_equal(pd[0].position[1], 1.0f, 1e-5f);        /* placed by the form factor alone */
    /* the zero-area VAL at 1e-3: irradiance Phi / (pi d^2), finite */
    d = proxy_desc(c, 1, v + 4, 1, test_env(NULL, NULL));
    d.scene_scale = 4.0f;
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    assert_true(all_ok_light(pd));
    assert_true(fabs(pd[0].flux[0] / (4.0 * PI_D * 1e-6) - 5.0 / (PI_D * 1e-6)) <= 1e-3 * 5.0 / (PI_D * 1e-6));
    /* no VAL at all: dark, not an error */
    d = proxy_desc(c, 3, NULL, 0, test_env(NULL, NULL));
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    for (i = 0; i < 3; ++i) assert_true(pd[i].flux[0] == 0.0f && pd[i].position[0] == c[i].position[0]);
}

/* Extreme but valid inputs: weights and flux near FLT_MAX, positions near FLT_MAX, a tiny
   scene scale: every output finite and >= 0. */
static void extreme_values(void **state) {
    gim_cache c[2];
    gim_val v[4];
    gim_proxy_light pd[2], pg[2];
    gim_receiver r[2];
    gim_proxy_desc d;
    gim_shade_desc sd;
    uint32_t idx[4] = {0, 1, 1, 0}, i;
    float dc[2] = {1e-30f, 0.0f}, L[6];
    float scales[] = {0.0f, 1e-30f, 1e30f};
    size_t si;
    (void)state;
    c[0] = mk_cache(0, 0, 0, 0, 0, 1, 1e30f);
    c[1] = mk_cache(1e-30f, 0, 0, 0, 0, 1, 0);
    v[0] = mk_val(0, 0, 1, 0, 0, -1, 0, 3e38f, 3e38f, 3e38f);
    v[0].weight = FLT_MAX;
    v[1] = mk_val(-3e38f, 0, 3e38f, 1, 0, -1, 3e38f, 1, 1, 1);
    v[2] = mk_val(0, 0, 1e-30f, 0, 0, -1, 0, 1e30f, 0, 0);
    v[3] = mk_val(3e38f, 3e38f, 3e38f, -1, -1, -1, 0, 1, 1, 1);
    for (si = 0; si < 3; ++si) {
        d = proxy_desc(c, 2, v, 4, test_env(NULL, NULL));
        d.eye = gim_v3(0, 0, 3e38f); d.glossy_exponent = 1e6f; d.scene_scale = scales[si];
        assert_int_equal(gim_proxy_lights_twin(&d, pd, pg), GIM_OK);
        for (i = 0; i < 2; ++i) assert_true(all_ok_light(pd + i) && all_ok_light(pg + i));
        for (i = 0; i < 2; ++i) r[i] = mk_recv(c + i, 0, 0, 1, 1e30f, 1e30f, 1e6f);
        memset(&sd, 0, sizeof sd);
        sd.caches = c; sd.cache_count = 2; sd.diffuse = pd; sd.glossy = pg; sd.receivers = r; sd.receiver_count = 2;
        sd.neighbour_index = idx; sd.neighbour_stride = 2; sd.d_cmax = dc; sd.scene_scale = scales[si] > 0 ? scales[si] : 1e-30f;
        assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);
        for (i = 0; i < 6; ++i) assert_true(isfinite(L[i]) && L[i] >= 0.0f);
    }
}

/* At a cache position, with the other neighbours at d_c,max (weight 0) or incompatible, the
   interpolation reproduces the cache's own radiance (eq. 3) exactly; in between it blends. */
static void interpolation_at_cache(void **state) {
    gim_cache c[3];
    gim_val v[2];
    gim_proxy_light pd[3];
    gim_receiver r[3];
    gim_shade_desc sd;
    gim_proxy_desc d;
    uint32_t idx[9] = {0, 1, 2, 1, 0, 2, 0, 1, UINT32_MAX}, cnt[3] = {3, 3, 2};
    float dc[3], L[9], own[6];
    double e0;
    int a;
    (void)state;
    c[0] = mk_cache(0, 0, 0, 0, 0, 1, 1);
    c[1] = mk_cache(2, 0, 0, 0, 0, 1, 1);
    c[2] = mk_cache(1, 0, 0.5f, 0, 0, -1, 1);          /* faces away: normal term 0 */
    v[0] = mk_val(0, 0, 2, 0, 0, -1, 0.5f, 1, 1, 1);
    v[1] = mk_val(2, 1, 3, 0, 0, -1, 0.5f, 0, 3, 0);
    d = proxy_desc(c, 3, v, 2, test_env(NULL, NULL));
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    r[0] = mk_recv(c + 0, 0, 0, 1, 0.8f, 0, 1);
    r[1] = mk_recv(c + 1, 0, 0, 1, 0.8f, 0, 1);
    r[2] = mk_recv(c + 0, 0, 0, 1, 0.8f, 0, 1);
    r[2].position[0] = 1.0f;                             /* midway */
    dc[0] = 2.0f; dc[1] = 2.0f; dc[2] = 2.0f;
    memset(&sd, 0, sizeof sd);
    sd.caches = c; sd.cache_count = 3; sd.diffuse = pd;
    sd.receivers = r; sd.receiver_count = 3; sd.neighbour_index = idx; sd.neighbour_count = cnt;
    sd.neighbour_stride = 3; sd.d_cmax = dc; sd.scene_scale = 5.0f;
    assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);
    radiance_at_caches(c, 2, pd, NULL, r, 5.0f, own);
    for (a = 0; a < 3; ++a) {
        assert_float_equal(L[a], own[a], 1e-6f * own[a] + 1e-12f);
        assert_float_equal(L[3 + a], own[3 + a], 1e-6f * own[3 + a] + 1e-12f);
    }
    /* by hand for cache 0: eq. 3 from both VALs */
    e0 = 1.0 * 1.0 / (0.5 + PI_D * 4.0);
    {
        double dx = 2, dy = 1, dz = 3, d2 = dx * dx + dy * dy + dz * dz, cs = dz / sqrt(d2);
        double e1 = 3.0 * cs * cs / (0.5 + PI_D * d2);
        assert_true(fabs(L[1] - 0.8 / PI_D * (e0 + e1)) <= 1e-5 * L[1]);
        assert_true(fabs(L[0] - 0.8 / PI_D * e0) <= 1e-5 * L[0]);
    }
    /* midway: both caches weigh 1/2 (the third faces away), the red light of cache 0 halves
       and the green one of cache 1 is in between */
    assert_true(L[6] > 0.0f && L[6] < own[0]);
    assert_true(L[7] > 0.0f);
}

/* Same scene in other units: positions x s, areas x s^2, flux x s^2 (the same exitance and
   irradiance): the same radiance, through the whole frame with glossy and a visibility
   matrix (the blocker's cache and every third VAL of each cache unseen). */
static void run_scene(float s, float *L, int visibility) {
    enum { NC = 12, NV = 300, NR = 6 };
    gim_cache c[NC];
    gim_val v[NV];
    gim_receiver r[NR];
    uint32_t idx[NR * 4], i, j;
    float dc[NR];
    gim_lightskin_desc d;
    static float vis[NC * NV];
    test_rng_state = 99;
    random_scene(c, NC, v, NV);
    for (i = 0; i < NV; ++i) { v[i].position[0] *= 0.15f; v[i].position[1] *= 0.15f; v[i].position[2] += 1.0f; }  /* a lamp */
    c[NC - 1] = mk_cache(0.3f, 0.2f, 1.0f, 0, 0, -1, 0.5f);   /* a blocker below it */
    for (i = 0; i < NC; ++i) { for (j = 0; j < 3; ++j) c[i].position[j] *= s; c[i].area *= s * s; }
    for (i = 0; i < NV; ++i) { for (j = 0; j < 3; ++j) { v[i].position[j] *= s; v[i].flux[j] *= s * s; } v[i].area *= s * s; }
    for (i = 0; i < NR; ++i) {
        r[i] = mk_recv(c + i, 0.2f, 0.1f, 1.0f, 0.5f, 0.4f, 20.0f);
        r[i].position[0] += 0.1f * s;
        for (j = 0; j < 4; ++j) idx[i * 4 + j] = (i + j) % (NC - 1);
        dc[i] = 3.0f * s;
    }
    memset(&d, 0, sizeof d);
    d.caches = c; d.cache_count = NC; d.vals = v; d.val_count = NV;
    d.eye = gim_v3(1.0f * s, 2.0f * s, 5.0f * s); d.glossy = 1; d.glossy_exponent = 20.0f;
    for (i = 0; i < NC * NV; ++i) vis[i] = i / NV == NC - 1 || i % 3 == 0 ? 0.0f : 1.0f;
    d.visibility = visibility ? vis : NULL;
    d.receivers = r; d.receiver_count = NR; d.neighbour_index = idx; d.neighbour_stride = 4; d.d_cmax = dc;
    assert_int_equal(gim_lightskin_frame_twin(&d, L), GIM_OK);
}
static void scale_invariance(void **state) {
    float a[18], b[18], c[18], o[18];
    double mx = 0.0;
    int i, occluded = 0;
    (void)state;
    run_scene(1.0f, a, 1);
    run_scene(1e-3f, b, 1);
    run_scene(1e4f, c, 1);
    run_scene(1.0f, o, 0);
    double sa = 0.0, so = 0.0;
    for (i = 0; i < 18; ++i) mx = a[i] > mx ? a[i] : mx;
    assert_true(mx > 0.0);
    for (i = 0; i < 18; ++i) {
        assert_true(fabs(b[i] - a[i]) <= 1e-4 * mx);
        assert_true(fabs(c[i] - a[i]) <= 1e-4 * mx);
        occluded += fabsf(o[i] - a[i]) > 1e-4f * a[i];
        sa += a[i]; so += o[i];
    }
    /* the unseen VALs take light away: less light in all (one receiver may get more, as the
       proxy lights move with what their caches see) */
    assert_true(occluded > 0 && sa < 0.97 * so);
}

/* A cache facing a large uniformly lit Lambertian square wall (exitance M) at height h gets
   L = rho / pi M F, F the analytic form factor of the square (Howell's parallel rectangle). */
static double ff_corner(double a, double b, double h) {
    double X = a / h, Y = b / h;
    return 1.0 / (2.0 * PI_D) * (X / sqrt(1 + X * X) * atan(Y / sqrt(1 + X * X)) + Y / sqrt(1 + Y * Y) * atan(X / sqrt(1 + Y * Y)));
}
static void energy_wall(void **state) {
    enum { G = 96 };
    const float h = 1.5f, W = 6.0f, M = 2.0f, rho = 0.5f;
    gim_cache c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    gim_val *v = (gim_val *)malloc(G * G * sizeof(gim_val));
    gim_proxy_light pd;
    gim_proxy_desc d;
    gim_receiver r = mk_recv(&c, 0, 0, 1, rho, 0, 1);
    float L[3], cell = W / G;
    double F = 4.0 * ff_corner(W / 2, W / 2, h), ex = rho / PI_D * M * F;
    uint32_t i, j;
    (void)state;
    for (i = 0; i < G; ++i)
        for (j = 0; j < G; ++j)
            v[i * G + j] = mk_val(-W / 2 + (i + 0.5f) * cell, -W / 2 + (j + 0.5f) * cell, h, 0, 0, -1, cell * cell,
                                  M * cell * cell, M * cell * cell, M * cell * cell);
    d = proxy_desc(&c, 1, v, G * G, test_env(NULL, NULL));
    assert_int_equal(gim_proxy_lights_twin(&d, &pd, NULL), GIM_OK);
    radiance_at_caches(&c, 1, &pd, NULL, &r, W, L);
    print_message("wall: L = %.5f, rho/pi M F = %.5f (F = %.4f)\n", L[0], ex, F);
    assert_true(fabs(L[0] - ex) <= 0.02 * ex);
    assert_float_equal(pd.position[0], 0.0f, 1e-4f);
    assert_float_equal(pd.position[2], h, 1e-4f);
    assert_true(pd.sigma[0] > 0.3f && pd.sigma[0] < W / 2);
    assert_float_equal(pd.sigma[0], pd.sigma[1], 1e-3f);
    free(v);
}

/* gim_shade_sources: the shading pass's 2 x 2 blocks share their first receiver's light only on
   its surface, near it, with its exponent; gim_lightskin_shade_twin's source gives a receiver
   that light times its own albedo. A 4 x 2 image, two blocks, cell 1. */
static void shade_blocks(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    gim_cache c[2];
    gim_val v = mk_val(-0.5f, 0.2f, 1, 0, 0, -1, 0.5f, 1, 1, 1);
    gim_proxy_light pd[2];
    gim_proxy_desc d;
    gim_receiver r[7];
    gim_shade_blocks_desc bd;
    gim_shade_desc sd;
    /* block 0: (0,0) (1,0) (0,1) (1,1); block 1: (3,0) first ((2,0) has no receiver), (2,1), (3,1) */
    uint32_t pix[14] = {1, 0, 0, 0, 0, 1, 1, 1, 3, 0, 2, 1, 3, 1}, src[7], idx[14], cnt[7], i, k;
    float dc[7], L[21], own[21];
    (void)state;
    c[0] = mk_cache(0, 0, 0, 0, 0, 1, 1);
    c[1] = mk_cache(0.6f, 0, 0, 0, 0, 1, 1);
    for (i = 0; i < 7; ++i) r[i] = mk_recv(c, 0, 0, 1, 0.5f + 0.05f * (float)i, 0, 1);
    r[0].position[0] = 0.2f;                        /* (1,0), within cell / 4 */
    r[2].position[1] = 0.01f;                       /* (0,1) */
    r[3].position[0] = 0.01f; r[3].position[1] = 0.01f;
    r[4].position[0] = 0.5f;                        /* block 1's first, (3,0) */
    r[5].position[0] = 0.45f; r[5].normal[2] = 0.0f; r[5].normal[0] = 1.0f;   /* another surface */
    r[6].position[0] = 0.5f; r[6].position[1] = 0.3f;                          /* beyond cell / 4 */
    memset(&bd, 0, sizeof bd);
    bd.receivers = r; bd.receiver_count = 7; bd.pixels = pix; bd.width = 4; bd.height = 2; bd.block = 2; bd.cell = 1.0f;
    bd.env = env;
    assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
    assert_int_equal(src[0], 1);   /* (0,0) is receiver 1, block 0's first */
    assert_int_equal(src[1], 1);
    assert_int_equal(src[2], 1);
    assert_int_equal(src[3], 1);
    assert_int_equal(src[4], 4);
    assert_int_equal(src[5], 5);
    assert_int_equal(src[6], 6);
    r[2].exponent = 2.0f;                           /* another lobe: its own */
    r[3].position[2] = 0.002f;                      /* 8 degrees off the plane: its own */
    assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
    assert_int_equal(src[0], 1);
    assert_int_equal(src[2], 2);
    assert_int_equal(src[3], 3);
    r[2].exponent = 1.0f;
    r[3].position[2] = 0.0f;
    bd.block = 1;                                   /* per pixel */
    assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
    for (i = 0; i < 7; ++i) assert_int_equal(src[i], i);
    bd.block = 0;                                   /* the default, GIM_DEFAULT_SHADE_BLOCK */
    assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
    assert_int_equal(src[0], GIM_DEFAULT_SHADE_BLOCK == 2 ? 1u : 0u);
    bd.block = 3;
    assert_int_equal(gim_shade_sources(&bd, src), GIM_ERROR_OUT_OF_RANGE);
    bd.block = 2; bd.cell = 0.0f;
    assert_int_equal(gim_shade_sources(&bd, src), GIM_ERROR_INVALID_ARGUMENT);
    bd.cell = 1.0f; pix[8] = 4;                     /* outside the image */
    assert_int_equal(gim_shade_sources(&bd, src), GIM_ERROR_INVALID_ARGUMENT);
    pix[8] = 3;
    assert_int_equal(lg.errors, 3);
    assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
    /* the twin: each receiver its own light, then its block's */
    d = proxy_desc(c, 2, &v, 1, env);
    assert_int_equal(gim_proxy_lights_twin(&d, pd, NULL), GIM_OK);
    for (i = 0; i < 7; ++i) { idx[2 * i] = 0; idx[2 * i + 1] = 1; cnt[i] = 2; dc[i] = 0.7f; }
    memset(&sd, 0, sizeof sd);
    sd.caches = c; sd.cache_count = 2; sd.diffuse = pd;
    sd.receivers = r; sd.receiver_count = 7; sd.neighbour_index = idx; sd.neighbour_count = cnt;
    sd.neighbour_stride = 2; sd.d_cmax = dc; sd.scene_scale = 2.0f; sd.env = env;
    assert_int_equal(gim_lightskin_shade_twin(&sd, own), GIM_OK);
    sd.source = src;
    assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);
    for (i = 0; i < 7; ++i)
        for (k = 0; k < 3; ++k) {
            double want = (double)own[src[i] * 3 + k] * r[i].albedo[k] / r[src[i]].albedo[k];
            assert_true(own[i * 3 + k] > 0.0f || i == 5);   /* 5 faces along the plane: no light */
            assert_true(fabs(L[i * 3 + k] - want) <= 1e-6 * want);
        }
    assert_true(fabs(L[0] - own[0]) > 1e-4 * own[0]);   /* (1,0) took (0,0)'s light, not its own */
    src[0] = 7;
    assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 4);
    assert_int_equal(as.live, 0);
}

static void argument_errors(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    gim_cache c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    gim_val v = mk_val(0, 0, 1, 0, 0, -1, 1, 1, 1, 1);
    gim_proxy_light pd, pg;
    gim_proxy_desc d;
    gim_receiver r = mk_recv(&c, 0, 0, 1, 1, 0, 1);
    gim_shade_desc sd;
    gim_lightskin_desc ld;
    gim_rsm_data rsm;
    gim_selected_val sel;
    gim_val out[4];
    float L[3], dc = 1.0f, fv[12] = {0}, nv[12] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1}, av[4] = {1, 1, 1, 1};
    uint32_t idx = 0;
    int errors = 0;
    (void)state;
#define EXPECT_ERR(call, code, name) do { \
        assert_int_equal((call), (code)); \
        assert_int_equal(lg.errors, ++errors); \
        assert_non_null(strstr(lg.last, name)); \
    } while (0)
    assert_int_equal(gim_proxy_lights_twin(NULL, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT);
    d = proxy_desc(&c, 1, &v, 1, env);
    EXPECT_ERR(gim_proxy_lights_twin(&d, NULL, NULL), GIM_ERROR_INVALID_ARGUMENT, "gim_proxy_lights_twin: diffuse_out is NULL");
    d.cache_count = 0;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "no caches");
    d = proxy_desc(&c, 1, NULL, 1, env);
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "vals is NULL");
    d = proxy_desc(&c, 1, &v, 1, env); d.scene_scale = -1.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    d = proxy_desc(&c, 1, &v, 1, env); d.glossy_exponent = -1.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, &pg), GIM_ERROR_INVALID_ARGUMENT, "glossy_exponent");
    d.glossy_exponent = NAN;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, &pg), GIM_ERROR_INVALID_ARGUMENT, "glossy_exponent");
    d.glossy_exponent = 2e6f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, &pg), GIM_ERROR_INVALID_ARGUMENT, "glossy_exponent");
    d.glossy_exponent = 1.0f; d.eye.x = INFINITY;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, &pg), GIM_ERROR_INVALID_ARGUMENT, "eye");
    d = proxy_desc(&c, 1, &v, 1, env);
    v.position[1] = NAN;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "VAL 0");
    v = mk_val(0, 0, 1, 0, 0, -1, 1, 1, -1, 1);
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "VAL 0");
    v = mk_val(0, 0, 1, 0, 0, -1, 1, 1, 1, 1); v.normal[2] = -2.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "VAL 0");
    v = mk_val(0, 0, 1, 0, 0, -1, 1, 1, 1, 1); v.weight = -1.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "VAL 0");
    v = mk_val(0, 0, 1, 0, 0, -1, 1, 1, 1, 1); c.normal[2] = 0.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "cache 0");
    c = mk_cache(0, 0, 0, 0, 0, 1, 1); c.area = -1.0f;
    EXPECT_ERR(gim_proxy_lights_twin(&d, &pd, NULL), GIM_ERROR_INVALID_ARGUMENT, "cache 0");
    c = mk_cache(0, 0, 0, 0, 0, 1, 1);
    assert_int_equal(gim_proxy_lights_twin(&d, &pd, NULL), GIM_OK);
    /* shading */
    assert_int_equal(gim_lightskin_shade_twin(NULL, L), GIM_ERROR_INVALID_ARGUMENT);
    memset(&sd, 0, sizeof sd);
    sd.caches = &c; sd.cache_count = 1; sd.diffuse = &pd; sd.receivers = &r; sd.receiver_count = 1;
    sd.neighbour_index = &idx; sd.neighbour_stride = 1; sd.d_cmax = &dc; sd.scene_scale = 1.0f; sd.env = env;
    assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, NULL), GIM_ERROR_INVALID_ARGUMENT, "radiance_out is NULL");
    sd.neighbour_stride = 17;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "neighbour_stride");
    sd.neighbour_stride = 1; idx = 5;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "cache 5 of 1");
    idx = UINT32_MAX;
    assert_int_equal(gim_lightskin_shade_twin(&sd, L), GIM_OK);          /* a pad: no neighbour, dark */
    assert_true(L[0] == 0.0f && L[1] == 0.0f && L[2] == 0.0f);
    idx = 0; dc = NAN;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "d_cmax[0]");
    dc = 1.0f; r.exponent = -2.0f;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "receiver 0");
    r.exponent = 1.0f; r.view[0] = 1.0f;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "receiver 0");
    r = mk_recv(&c, 0, 0, 1, 1, 0, 1);
    sd.diffuse = NULL;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "diffuse proxy lights");
    sd.diffuse = &pd; pg = pd; pg.flux[0] = -1.0f; sd.glossy = &pg;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "proxy light 0");
    sd.glossy = NULL; sd.receiver_count = 0;
    EXPECT_ERR(gim_lightskin_shade_twin(&sd, L), GIM_ERROR_INVALID_ARGUMENT, "no receivers");
    /* the whole frame */
    assert_int_equal(gim_lightskin_frame_twin(NULL, L), GIM_ERROR_INVALID_ARGUMENT);
    memset(&ld, 0, sizeof ld);
    ld.caches = &c; ld.cache_count = 1; ld.vals = &v; ld.val_count = 1; ld.receivers = &r; ld.receiver_count = 1;
    ld.neighbour_index = &idx; ld.neighbour_stride = 1; ld.d_cmax = &dc; ld.env = env;
    EXPECT_ERR(gim_lightskin_frame_twin(&ld, NULL), GIM_ERROR_INVALID_ARGUMENT, "gim_lightskin_frame_twin: radiance_out is NULL");
    ld.scene_scale = INFINITY;
    EXPECT_ERR(gim_lightskin_frame_twin(&ld, L), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    ld.scene_scale = 0.0f; ld.receivers = NULL;
    EXPECT_ERR(gim_lightskin_frame_twin(&ld, L), GIM_ERROR_INVALID_ARGUMENT, "gim_lightskin_frame_twin: no receivers");
    assert_int_equal(as.allocs, 0);                 /* refused before the proxy pass */
    ld.receivers = &r; ld.d_cmax = NULL;
    EXPECT_ERR(gim_lightskin_frame_twin(&ld, L), GIM_ERROR_INVALID_ARGUMENT, "gim_lightskin_frame_twin: neighbour_index and d_cmax");
    /* gather */
    memset(&rsm, 0, sizeof rsm);
    rsm.position = fv; rsm.normal = nv; rsm.flux = fv; rsm.area = av; rsm.width = 2; rsm.height = 2;
    EXPECT_ERR(gim_vals_gather_twin(NULL, NULL, 0, out, env), GIM_ERROR_INVALID_ARGUMENT, "gim_vals_gather_twin: rsm is NULL");
    EXPECT_ERR(gim_vals_gather_twin(&rsm, NULL, 0, NULL, env), GIM_ERROR_INVALID_ARGUMENT, "out is NULL");
    sel.x = 2; sel.y = 0; sel.pdf = 0.25f;
    EXPECT_ERR(gim_vals_gather_twin(&rsm, &sel, 1, out, env), GIM_ERROR_INVALID_ARGUMENT, "outside");
    sel.x = 1; sel.pdf = 0.0f;
    EXPECT_ERR(gim_vals_gather_twin(&rsm, &sel, 1, out, env), GIM_ERROR_INVALID_ARGUMENT, "pdf");
    EXPECT_ERR(gim_vals_gather_twin(&rsm, &sel, 0, out, env), GIM_ERROR_INVALID_ARGUMENT, "selected_count");
    rsm.area = NULL;
    EXPECT_ERR(gim_vals_gather_twin(&rsm, NULL, 0, out, env), GIM_ERROR_INVALID_ARGUMENT, "required");
#undef EXPECT_ERR
    assert_int_equal(as.live, 0);
}

/* gim_vals_gather_twin: FULL weights 1, BRSM weights 1/(N pdf), invalid texels weigh 0. */
static void gather(void **state) {
    float pos[12] = {0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1}, nrm[12] = {0, 0, -1, 0, 0, -1, 0, 0, -1, 0, 0, -1};
    float flux[12] = {1, 1, 1, 2, 2, 2, 3, 3, 3, 4, NAN, 4}, area[4] = {0.1f, 0.2f, 0.3f, 0.4f}, valid[4] = {1, 0, 1, 1};
    gim_rsm_data rsm;
    gim_selected_val sel[2];
    gim_val out[4];
    (void)state;
    memset(&rsm, 0, sizeof rsm);
    rsm.position = pos; rsm.normal = nrm; rsm.flux = flux; rsm.area = area; rsm.valid = valid; rsm.width = 2; rsm.height = 2;
    assert_int_equal(gim_vals_gather_twin(&rsm, NULL, 0, out, test_env(NULL, NULL)), GIM_OK);
    assert_float_equal(out[0].weight, 1.0f, 0.0f);
    assert_float_equal(out[0].area, 0.1f, 0.0f);
    assert_float_equal(out[1].weight, 0.0f, 0.0f);     /* valid = 0 */
    assert_float_equal(out[2].flux[0], 3.0f, 0.0f);
    assert_float_equal(out[2].position[1], 1.0f, 0.0f);
    assert_float_equal(out[3].weight, 0.0f, 0.0f);     /* NaN flux */
    assert_true(out[3].flux[1] == 0.0f);
    sel[0].x = 0; sel[0].y = 1; sel[0].pdf = 0.25f;
    sel[1].x = 1; sel[1].y = 0; sel[1].pdf = 0.5f;
    rsm.valid = NULL;
    assert_int_equal(gim_vals_gather_twin(&rsm, sel, 2, out, test_env(NULL, NULL)), GIM_OK);
    assert_float_equal(out[0].weight, 2.0f, 0.0f);     /* 1 / (2 * 0.25) */
    assert_float_equal(out[0].flux[0], 3.0f, 0.0f);
    assert_float_equal(out[1].weight, 1.0f, 0.0f);
    assert_float_equal(out[1].area, 0.2f, 0.0f);
}

/* The real BRSM pipeline (importance map, cumulative sums, selection, gather) against FULL. */
static void brsm_pipeline(void **state) {
    enum { W = 32, NSEL = 512 };
    float *pos = (float *)malloc(W * W * 3 * sizeof(float)), *nrm = (float *)malloc(W * W * 3 * sizeof(float));
    float *flux = (float *)malloc(W * W * 3 * sizeof(float)), *area = (float *)malloc(W * W * sizeof(float));
    float *map = (float *)malloc(W * W * sizeof(float));
    double *col = (double *)malloc(W * W * sizeof(double)), row[W];
    gim_selected_val *sel = (gim_selected_val *)malloc(NSEL * sizeof(gim_selected_val));
    gim_val *full = (gim_val *)malloc(W * W * sizeof(gim_val)), *brsm = (gim_val *)malloc(NSEL * sizeof(gim_val));
    gim_cache c[4];
    gim_view_sample vs[4];
    gim_rsm_data rsm;
    gim_importance_desc id;
    double Lf[4], Lb[4], err = 0.0;
    uint32_t i, seed;
    (void)state;
    for (i = 0; i < W * W; ++i) {
        float x = -3.0f + 6.0f * (i % W + 0.5f) / W, y = -3.0f + 6.0f * (i / W + 0.5f) / W;
        pos[i * 3] = x; pos[i * 3 + 1] = y; pos[i * 3 + 2] = 2.0f;
        nrm[i * 3] = 0; nrm[i * 3 + 1] = 0; nrm[i * 3 + 2] = -1;
        flux[i * 3] = flux[i * 3 + 1] = flux[i * 3 + 2] = (x > 0 ? 1.0f : 0.2f) * 0.035f;
        area[i] = 0.035f;
    }
    for (i = 0; i < 4; ++i) {
        c[i] = mk_cache(-1.5f + i, 0.5f, 0, 0, 0, 1, 1);
        vs[i].position = gim_v3(c[i].position[0], c[i].position[1], 0); vs[i].normal = gim_v3(0, 0, 1);
    }
    memset(&rsm, 0, sizeof rsm);
    rsm.position = pos; rsm.normal = nrm; rsm.flux = flux; rsm.area = area; rsm.width = W; rsm.height = W;
    memset(&id, 0, sizeof id);
    id.rsm_position = pos; id.rsm_normal = nrm; id.rsm_flux = flux; id.width = W; id.height = W;
    id.view_samples = vs; id.view_sample_count = 4; id.scene_scale = 8.0f;
    assert_int_equal(gim_importance_map(&id, map), GIM_OK);
    assert_int_equal(gim_importance_cumsum(map, W, W, col, row, test_env(NULL, NULL)), GIM_OK);
    assert_int_equal(gim_vals_gather_twin(&rsm, NULL, 0, full, test_env(NULL, NULL)), GIM_OK);
    cache_radiance(c, 4, full, W * W, Lf);
    for (seed = 0; seed < 8; ++seed) {
        gim_select_desc sd;
        memset(&sd, 0, sizeof sd);
        sd.column = col; sd.row = row; sd.width = W; sd.height = W; sd.count = NSEL; sd.seed = seed;
        sd.env = test_env(NULL, NULL);
        assert_int_equal(gim_importance_select(&sd, sel), GIM_OK);
        assert_int_equal(gim_vals_gather_twin(&rsm, sel, NSEL, brsm, test_env(NULL, NULL)), GIM_OK);
        cache_radiance(c, 4, brsm, NSEL, Lb);
        for (i = 0; i < 4; ++i) err += fabs(Lb[i] / Lf[i] - 1.0) / 32.0;
    }
    print_message("BRSM pipeline, %d of %d VALs: mean relative error %.4f\n", NSEL, W * W, err);
    assert_true(err < 0.03);
    free(pos); free(nrm); free(flux); free(area); free(map); free(col); free(sel); free(full); free(brsm);
}

/* gim_lightskin_frame_twin: one allocation, freed; out of memory reported without leaks; deterministic;
   the diffuse-only frame equals the diffuse part of the glossy one. */
static void frame_memory_determinism(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    gim_cache c[2];
    gim_val v[3];
    gim_receiver r[2];
    uint32_t idx[4] = {0, 1, 1, 0};
    float dc[2] = {2, 2}, L1[6], L2[6], L3[6];
    gim_lightskin_desc d;
    int i;
    (void)state;
    c[0] = mk_cache(0, 0, 0, 0, 0, 1, 1); c[1] = mk_cache(1, 0, 0, 0, 0, 1, 1);
    v[0] = mk_val(0, 0, 2, 0, 0, -1, 0.5f, 1, 0.5f, 0.2f);
    v[1] = mk_val(1, 1, 2, 0, 0, -1, 0.5f, 0.2f, 0.5f, 1);
    v[2] = mk_val(-1, 0, 1, 1, 0, -1, 0.5f, 1, 1, 1);
    r[0] = mk_recv(c, 0, 0.5f, 1, 0.5f, 0.0f, 8); r[1] = mk_recv(c + 1, 0.2f, 0, 1, 0.5f, 0.0f, 8);
    r[1].position[0] = 0.6f;
    memset(&d, 0, sizeof d);
    d.caches = c; d.cache_count = 2; d.vals = v; d.val_count = 3; d.eye = gim_v3(0, 1, 4);
    d.glossy = 1; d.glossy_exponent = 8;
    d.receivers = r; d.receiver_count = 2; d.neighbour_index = idx; d.neighbour_stride = 2; d.d_cmax = dc; d.env = env;
    assert_int_equal(gim_lightskin_frame_twin(&d, L1), GIM_OK);
    assert_int_equal(as.allocs, 1);
    assert_int_equal(as.live, 0);
    assert_int_equal(gim_lightskin_frame_twin(&d, L2), GIM_OK);
    assert_memory_equal(L1, L2, sizeof L1);
    d.glossy = 0;
    assert_int_equal(gim_lightskin_frame_twin(&d, L3), GIM_OK);
    for (i = 0; i < 6; ++i) assert_float_equal(L3[i], L1[i], 1e-7f * L1[i]);   /* glossy colour 0 */
    r[0].glossy[1] = 1.0f; d.glossy = 1;
    assert_int_equal(gim_lightskin_frame_twin(&d, L2), GIM_OK);
    assert_true(L2[1] > L1[1]);                                             /* the glossy term adds */
    as.fail_after = as.allocs;
    assert_int_equal(gim_lightskin_frame_twin(&d, L2), GIM_ERROR_OUT_OF_MEMORY);
    assert_int_equal(lg.errors, 1);
    assert_non_null(strstr(lg.last, "gim_lightskin_frame_twin"));
    assert_int_equal(as.live, 0);
}

/* The near field and a thin plate: a VAL on the plate's top (normal +z) and a cache on its
   underside (normal -z) share the plane; rounding that lifts the cache by 1e-7 must not give it
   the patch's F = 1 (it sees nothing of the VAL), while a cache 0.1 sqrt(A) above the patch,
   facing it, does get its light (GIM__VPL_NEAR_LIFT: 0.01 sqrt(A)). */
static void near_field_thin_plate(void **state) {
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    const float zs[2] = {1e-7f, 0.01f};
    gim_proxy_light pl;
    int k;
    (void)state;
    for (k = 0; k < 2; ++k) {
        gim_cache c;
        gim_val v;
        gim_proxy_desc d;
        memset(&c, 0, sizeof c);
        memset(&v, 0, sizeof v);
        c.position[0] = 0.02f; c.position[1] = 0.01f; c.position[2] = zs[k]; c.normal[2] = -1.0f;
        c.area = 1e-4f; c.reflectance = 1.0f;
        v.normal[2] = 1.0f; v.area = 0.01f; v.weight = 1.0f; v.flux[0] = v.flux[1] = v.flux[2] = 1.0f;
        d = proxy_desc(&c, 1, &v, 1, env);
        d.scene_scale = 1.0f;
        assert_int_equal(gim_proxy_lights_twin(&d, &pl, NULL), GIM_OK);
        print_message("cache %g above the VAL's plane: proxy flux %g\n", (double)zs[k], (double)pl.flux[0]);
        if (k == 0) assert_true(pl.flux[0] < 1e-3f);   /* 0.63 without the guard */
        else assert_true(pl.flux[0] > 0.5f);
    }
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(eq3_hand_computed),
        cmocka_unit_test(eq4_hand_computed),
        cmocka_unit_test(brsm_converges_to_full),
        cmocka_unit_test(proportional_pdf_low_variance),
        cmocka_unit_test(flux_guard_bound),
        cmocka_unit_test(guard_bias),
        cmocka_unit_test(guards_finite),
        cmocka_unit_test(extreme_values),
        cmocka_unit_test(interpolation_at_cache),
        cmocka_unit_test(shade_blocks),
        cmocka_unit_test(scale_invariance),
        cmocka_unit_test(energy_wall),
        cmocka_unit_test(argument_errors),
        cmocka_unit_test(gather),
        cmocka_unit_test(brsm_pipeline),
        cmocka_unit_test(frame_memory_determinism),
        cmocka_unit_test(near_field_thin_plate),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
