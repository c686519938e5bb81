/* Importance sampling of the RSM: eq. 10-11 by hand, unit-free clamp, invalid texels,
   selection frequencies (chi-square), stratification, all-zero maps, precision at 4096^2. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* A small RSM owned by the test. */
typedef struct test_rsm {
    float *pos, *nrm, *flux, *valid;
    uint32_t w, h;
} test_rsm;

static test_rsm rsm_new(uint32_t w, uint32_t h) {
    test_rsm r;
    size_t n = (size_t)w * h;
    r.w = w; r.h = h;
    r.pos = (float *)calloc(n * 3, sizeof(float));
    r.nrm = (float *)calloc(n * 3, sizeof(float));
    r.flux = (float *)calloc(n * 3, sizeof(float));
    r.valid = (float *)calloc(n, sizeof(float));
    assert_non_null(r.pos); assert_non_null(r.nrm); assert_non_null(r.flux); assert_non_null(r.valid);
    return r;
}
static void rsm_free(test_rsm *r) { free(r->pos); free(r->nrm); free(r->flux); free(r->valid); }
static void set3(float *a, size_t i, float x, float y, float z) { a[i * 3] = x; a[i * 3 + 1] = y; a[i * 3 + 2] = z; }

static gim_importance_desc desc_for(const test_rsm *r, const gim_view_sample *vs, uint32_t n, float scale, gim_env env) {
    gim_importance_desc d;
    memset(&d, 0, sizeof d);
    d.rsm_position = r->pos; d.rsm_normal = r->nrm; d.rsm_flux = r->flux; d.rsm_valid = r->valid;
    d.width = r->w; d.height = r->h;
    d.view_samples = vs; d.view_sample_count = n;
    d.scene_scale = scale;
    d.env = env;
    return d;
}

/* gim_importance_select with the offsets drawn from seed (gim_select_desc.offsets NULL), the
   form most tests here take. */
static gim_result select_seed(const double *column, const double *row, uint32_t w, uint32_t h, uint32_t count,
                              uint32_t seed, gim_selected_val *out, gim_env env) {
    gim_select_desc d;
    memset(&d, 0, sizeof d);
    d.column = column; d.row = row; d.width = w; d.height = h; d.count = count; d.seed = seed; d.env = env;
    return gim_importance_select(&d, out);
}

static gim_view_sample vsample(float px, float py, float pz, float nx, float ny, float nz) {
    gim_view_sample s;
    s.position = gim_v3(px, py, pz);
    s.normal = gim_v3(nx, ny, nz);
    return s;
}

static int rel_close(double a, double b, double tol) { return fabs(a - b) <= tol * fabs(b); }

/* eq. 10 by hand: one VAL at the origin facing +z, flux (2,2,2) (luminance 2), two view samples:
   VS1 at (0,0,2) facing down: d = (0,0,1), cos_l = cos_vs = 1, |l|^2 = 4;
   VS2 at (3,0,4) facing down: |l| = 5, d = (0.6,0,0.8), cos_l = 0.8, cos_vs = 0.8.
   With scene_scale 10 the squared distances are 0.04 and 0.25 scene scales. */
static void eq10_hand_computed(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    test_rsm r = rsm_new(1, 1);
    gim_view_sample vs[2];
    gim_importance_desc d;
    float out = -1.0f;
    double lum = 2.0 * ((double)0.2126f + (double)0.7152f + (double)0.0722f);
    (void)state;
    set3(r.pos, 0, 0, 0, 0); set3(r.nrm, 0, 0, 0, 1); set3(r.flux, 0, 2, 2, 2); r.valid[0] = 1;
    vs[0] = vsample(0, 0, 2, 0, 0, -1);
    vs[1] = vsample(3, 0, 4, 0, 0, -1);
    d = desc_for(&r, vs, 2, 10.0f, env);
    d.clamp = 0.01f; /* clamp^2 = 1e-4: below both distances */
    assert_int_equal(gim_importance_map(&d, &out), GIM_OK);
    /* (1*1/0.04 + 0.8*0.8/0.25) / 2 = (25 + 2.56) / 2 */
    assert_true(rel_close(out, lum * (25.0 + 2.56) / 2.0, 1e-6));
    /* eq. 11 clamp at 0.3 scene scales (0.09): VS1 is clamped, VS2 is not */
    d.clamp = 0.3f;
    assert_int_equal(gim_importance_map(&d, &out), GIM_OK);
    assert_true(rel_close(out, lum * (1.0 / 0.09 + 2.56) / 2.0, 1e-6));
    /* the default clamp is 1/64 scene scales: 0.04 > (1/64)^2, so nothing is clamped */
    d.clamp = 0.0f;
    assert_int_equal(gim_importance_map(&d, &out), GIM_OK);
    assert_true(rel_close(out, lum * (25.0 + 2.56) / 2.0, 1e-6));
    /* a non-unit normal is renormalised: same value */
    set3(r.nrm, 0, 0, 0, 7);
    assert_int_equal(gim_importance_map(&d, &out), GIM_OK);
    assert_true(rel_close(out, lum * (25.0 + 2.56) / 2.0, 1e-6));
    assert_int_equal(lg.errors, 0);
    assert_int_equal(lg.warnings, 0);
    assert_true(as.live == 0 && as.allocs > 0);
    rsm_free(&r);
}

/* eq. 11: a view sample straight above the VAL at distance t scene scales gives 1/max(t^2, c^2):
   it rises as 1/t^2 down to t = c and stays flat below, whatever the unit. */
static void eq11_clamp(void **state) {
    test_rsm r = rsm_new(1, 1);
    gim_view_sample vs;
    gim_importance_desc d;
    const float c = 0.05f, scales[3] = {1e-3f, 1.0f, 1e5f};
    const float ts[5] = {0.4f, 0.1f, 0.05f, 0.025f, 0.001f};
    int si, ti;
    (void)state;
    for (si = 0; si < 3; ++si) {
        float s = scales[si];
        set3(r.pos, 0, 0, 0, 0); set3(r.nrm, 0, 0, 0, 1); set3(r.flux, 0, 1, 1, 1); r.valid[0] = 1;
        for (ti = 0; ti < 5; ++ti) {
            float out, t = ts[ti];
            double expect = (double)gim__v3_luminance(gim_v3(1, 1, 1)) / ((double)t * t > (double)c * c ? (double)t * t : (double)c * c);
            vs = vsample(0, 0, t * s, 0, 0, -1);
            d = desc_for(&r, &vs, 1, s, test_env(NULL, NULL));
            d.clamp = c;
            assert_int_equal(gim_importance_map(&d, &out), GIM_OK);
            assert_true(rel_close(out, expect, 1e-5));
        }
    }
    rsm_free(&r);
}

/* A random scene: texels on a floor and a wall, view samples on both, some of them very close
   to texels (inside the clamp). */
static void random_scene(test_rsm *r, gim_view_sample *vs, uint32_t nvs, float s) {
    size_t i, n = (size_t)r->w * r->h;
    for (i = 0; i < n; ++i) {
        float a = (float)test_rand01(), b = (float)test_rand01();
        if (i % 3 == 0) { set3(r->pos, i, a * s, 0.0f, b * s); set3(r->nrm, i, 0, 1, 0); }
        else { set3(r->pos, i, a * s, b * s, 0.0f); set3(r->nrm, i, 0, 0, 1); }
        set3(r->flux, i, (float)test_rand01(), (float)test_rand01(), (float)test_rand01());
        r->valid[i] = 1.0f;
    }
    for (i = 0; i < nvs; ++i) {
        float a = (float)test_rand01(), b = (float)test_rand01();
        if (i % 4 == 0) { /* right next to a texel: inside the default clamp */
            size_t k = (size_t)(test_rand01() * (double)n);
            const float *p = r->pos + k * 3, *q = r->nrm + k * 3;
            vs[i] = vsample(p[0] + q[0] * 0.003f * s, p[1] + q[1] * 0.003f * s + 0.002f * s, p[2] + q[2] * 0.003f * s, 0, 0, 1);
        } else if (i % 2) vs[i] = vsample(a * s, 0.0f, b * s, 0, 1, 0);
        else vs[i] = vsample(a * s, b * s, 0.0f, 0, 0, 1);
    }
}

/* Unit-free: scaling positions and scene_scale together changes nothing (1e-4, 1e4: float
   rounding of the scaled positions only; powers of two: bit for bit); flux scales the map. */
static void scale_invariance(void **state) {
    const uint32_t w = 16, h = 16, nvs = 64;
    test_rsm r = rsm_new(w, h), r2 = rsm_new(w, h);
    gim_view_sample vs[64], vs2[64];
    float *m0 = (float *)malloc(w * h * sizeof(float)), *m1 = (float *)malloc(w * h * sizeof(float));
    const float factors[4] = {1e-4f, 1e4f, 1.0f / 16384.0f, 16384.0f};
    gim_importance_desc d;
    size_t i, n = (size_t)w * h;
    int f, clamped = 0;
    (void)state;
    random_scene(&r, vs, nvs, 1.0f);
    d = desc_for(&r, vs, nvs, 1.0f, test_env(NULL, NULL));
    assert_int_equal(gim_importance_map(&d, m0), GIM_OK);
    for (i = 0; i < n; ++i) assert_true(m0[i] >= 0.0f && isfinite(m0[i]));
    /* the scene really exercises the clamp: some texel-sample pairs are inside 1/64 */
    for (i = 0; i < n && !clamped; ++i) {
        uint32_t j;
        for (j = 0; j < nvs; ++j) {
            double dx = vs[j].position.x - r.pos[i * 3], dy = vs[j].position.y - r.pos[i * 3 + 1], dz = vs[j].position.z - r.pos[i * 3 + 2];
            if (dx * dx + dy * dy + dz * dz < 1.0 / 4096.0) { clamped = 1; break; }
        }
    }
    assert_true(clamped);
    for (f = 0; f < 4; ++f) {
        float k = factors[f];
        double maxrel = 0.0;
        for (i = 0; i < n * 3; ++i) { r2.pos[i] = r.pos[i] * k; r2.nrm[i] = r.nrm[i]; r2.flux[i] = r.flux[i]; }
        for (i = 0; i < n; ++i) r2.valid[i] = r.valid[i];
        for (i = 0; i < nvs; ++i) vs2[i] = vsample(vs[i].position.x * k, vs[i].position.y * k, vs[i].position.z * k,
                                                   vs[i].normal.x, vs[i].normal.y, vs[i].normal.z);
        d = desc_for(&r2, vs2, nvs, k, test_env(NULL, NULL));
        assert_int_equal(gim_importance_map(&d, m1), GIM_OK);
        for (i = 0; i < n; ++i) {
            double rel = m0[i] > 0.0f ? fabs((double)m1[i] - m0[i]) / m0[i] : fabs((double)m1[i]);
            if (rel > maxrel) maxrel = rel;
        }
        if (f >= 2) assert_memory_equal(m0, m1, n * sizeof(float));
        else {
            print_message("positions and scene_scale x %g: max relative change of the map %.3g\n", (double)k, maxrel);
            assert_true(maxrel < 1e-4); /* positions moved by float rounding, ~1e-7 relative */
        }
    }
    /* flux x 3 -> map x 3; the map is linear in the flux luminance */
    for (i = 0; i < n * 3; ++i) r2.pos[i] = r.pos[i], r2.flux[i] = r.flux[i] * 3.0f;
    d = desc_for(&r2, vs, nvs, 1.0f, test_env(NULL, NULL));
    assert_int_equal(gim_importance_map(&d, m1), GIM_OK);
    for (i = 0; i < n; ++i) assert_true(fabs((double)m1[i] - 3.0 * m0[i]) <= 1e-5 * 3.0 * m0[i] + 1e-30);
    free(m0); free(m1); rsm_free(&r); rsm_free(&r2);
}

/* Back-facing pairs, invalid texels, NaN/Inf data, a view sample at the texel: 0, never NaN. */
static void backfacing_and_invalid(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    test_rsm r = rsm_new(10, 1);
    gim_view_sample vs[3];
    gim_importance_desc d;
    float out[10], ref;
    int i;
    (void)state;
    for (i = 0; i < 10; ++i) { set3(r.pos, (size_t)i, (float)i * 0.1f, 0, 0); set3(r.nrm, (size_t)i, 0, 0, 1); set3(r.flux, (size_t)i, 1, 1, 1); r.valid[i] = 1; }
    vs[0] = vsample(0.45f, 0, 1, 0, 0, -1);   /* above, facing down: sees the texels */
    set3(r.nrm, 1, 0, 0, -1);                 /* texel 1 faces away from the view sample */
    r.valid[2] = 0.0f;                        /* texel 2: the RSM saw nothing */
    r.pos[3 * 3 + 1] = NAN;                   /* texel 3: NaN position */
    r.flux[4 * 3 + 2] = INFINITY;             /* texel 4: Inf flux */
    set3(r.nrm, 5, 0, 0, 0);                  /* texel 5: zero normal */
    set3(r.flux, 6, -1, -1, -1);              /* texel 6: negative flux */
    r.valid[7] = NAN;                         /* texel 7: NaN validity counts as invalid */
    set3(r.flux, 8, 0, 0, 0);                 /* texel 8: black */
    d = desc_for(&r, vs, 1, 1.0f, env);
    assert_int_equal(gim_importance_map(&d, out), GIM_OK);
    assert_true(out[0] > 0.0f && out[9] > 0.0f);
    for (i = 1; i <= 8; ++i) assert_true(out[i] == 0.0f);
    ref = out[0];
    /* the view sample faces away (up): 0 everywhere */
    vs[0] = vsample(0.45f, 0, 1, 0, 0, 1);
    assert_int_equal(gim_importance_map(&d, out), GIM_OK);
    for (i = 0; i < 10; ++i) assert_true(out[i] == 0.0f);
    /* a view sample exactly at texel 0, and one below the surface: no NaN, no contribution */
    vs[0] = vsample(0, 0, 0, 0, 0, -1);
    vs[1] = vsample(0.45f, 0, -1, 0, 0, 1);
    d.view_sample_count = 2;
    assert_int_equal(gim_importance_map(&d, out), GIM_OK);
    assert_true(out[0] == 0.0f);
    for (i = 0; i < 10; ++i) assert_true(isfinite(out[i]) && out[i] >= 0.0f);
    /* NaN and zero-normal view samples see nothing (a warning), the others count as before,
       averaged over all N_VS */
    vs[0] = vsample(0.45f, 0, 1, 0, 0, -1);
    vs[1] = vsample(NAN, 0, 1, 0, 0, -1);
    vs[2] = vsample(0.45f, 0, 1, 0, 0, 0);
    d.view_sample_count = 3;
    assert_int_equal(gim_importance_map(&d, out), GIM_OK);
    assert_int_equal(lg.warnings, 1);
    assert_non_null(strstr(lg.last, "2 of 3 view samples"));
    assert_true(rel_close(out[0], ref / 3.0, 1e-6));
    /* huge flux: clamped at FLT_MAX, not Inf */
    set3(r.flux, 0, 3e38f, 3e38f, 3e38f);
    d.view_sample_count = 1;
    d.clamp = 1e-6f;
    vs[0] = vsample(0, 0, 1e-6f, 0, 0, -1);
    assert_int_equal(gim_importance_map(&d, out), GIM_OK);
    assert_true(out[0] == FLT_MAX);
    assert_int_equal(lg.errors, 0);
    assert_true(as.live == 0);
    rsm_free(&r);
}

/* Tables of a map, test-owned. */
typedef struct test_tables { double *col, *row; } test_tables;
static test_tables tables_of(const float *map, uint32_t w, uint32_t h) {
    test_tables t;
    t.col = (double *)malloc((size_t)w * h * sizeof(double));
    t.row = (double *)malloc(w * sizeof(double));
    assert_non_null(t.col); assert_non_null(t.row);
    assert_int_equal(gim_importance_cumsum(map, w, h, t.col, t.row, test_env(NULL, NULL)), GIM_OK);
    return t;
}
static void tables_free(test_tables *t) { free(t->col); free(t->row); }

/* Chi-square of observed counts against expected probabilities (bins with p > 0). */
static double chi2_of(const long *obs, const double *p, size_t bins, double total, double *dof) {
    double x = 0.0;
    size_t i, k = 0;
    for (i = 0; i < bins; ++i) {
        double e = p[i] * total;
        if (p[i] <= 0.0) continue;
        x += ((double)obs[i] - e) * ((double)obs[i] - e) / e;
        ++k;
    }
    *dof = (double)k - 1.0;
    return x;
}

/* Selection frequencies match the map: 64x64 map with zero texels, 50 seeds x 4000 VALs,
   chi-square per texel and per quadrant. The same tests must reject wrong distributions: the
   counts of an off-by-one search (every pick one row lower), a uniform selection, and a map
   with one quadrant 10% heavier (caught by the quadrant bins). */
static void chi_square_frequencies(void **state) {
    const uint32_t w = 64, h = 64, count = 4000, seeds = 50;
    const double N = (double)count * seeds;
    size_t n = (size_t)w * h, i;
    float *map = (float *)malloc(n * sizeof(float));
    double *p = (double *)malloc(n * sizeof(double)), *pu = (double *)malloc(n * sizeof(double));
    long *obs = (long *)calloc(n, sizeof(long)), *shifted = (long *)calloc(n, sizeof(long));
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof(gim_selected_val));
    long qobs[4] = {0, 0, 0, 0};
    double q[4] = {0, 0, 0, 0}, qw[4], total = 0.0, x, dof, pv, pv_shift, pv_uni, pv_q, pv_qw;
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    test_tables t;
    uint32_t s, k;
    (void)state;
    for (i = 0; i < n; ++i) {
        map[i] = (i % 10 == 3) ? 0.0f : (float)(0.1 + 0.9 * test_rand01());
        total += map[i];
    }
    t = tables_of(map, w, h);
    for (i = 0; i < n; ++i) {
        int qi = ((i % w) < w / 2 ? 0 : 1) + ((i / w) < h / 2 ? 0 : 2);
        p[i] = map[i] / total;
        pu[i] = 1.0 / (double)n;
        q[qi] += p[i];
    }
    for (k = 0; k < 4; ++k) qw[k] = q[k] * (k == 0 ? 1.1 : 1.0) / (1.0 + 0.1 * q[0]);
    for (s = 0; s < seeds; ++s) {
        assert_int_equal(select_seed(t.col, t.row, w, h, count, 1000u + s, sel, env), GIM_OK);
        for (k = 0; k < count; ++k) {
            size_t idx = (size_t)sel[k].y * w + sel[k].x;
            assert_true(sel[k].x < w && sel[k].y < h);
            assert_true(map[idx] > 0.0f);                     /* a zero texel is never picked */
            assert_true(rel_close(sel[k].pdf, p[idx], 1e-6)); /* P = map / total */
            obs[idx]++;
            shifted[(size_t)((sel[k].y + 1u) % h) * w + sel[k].x]++;
            qobs[(sel[k].x < w / 2 ? 0 : 1) + (sel[k].y < h / 2 ? 0 : 2)]++;
        }
    }
    x = chi2_of(obs, p, n, N, &dof);
    pv = test_chi2_pvalue(x, dof);
    print_message("per texel: chi2 %.1f (dof %.0f, p %.3f; stratified, so below dof)\n", x, dof, pv);
    assert_true(pv > 1e-3);
    x = chi2_of(shifted, p, n, N, &dof);
    pv_shift = test_chi2_pvalue(x, dof);
    x = chi2_of(obs, pu, n, N, &dof);
    pv_uni = test_chi2_pvalue(x, dof);
    x = chi2_of(qobs, q, 4, N, &dof);
    pv_q = x > 0.0 ? test_chi2_pvalue(x, dof) : 1.0;
    print_message("per quadrant: chi2 %.2f (p %.3f); wrong: off-by-one p %.2g, uniform p %.2g", x, pv_q, pv_shift, pv_uni);
    x = chi2_of(qobs, qw, 4, N, &dof);
    pv_qw = test_chi2_pvalue(x, dof);
    print_message(", quadrant +10%% chi2 %.0f p %.2g\n", x, pv_qw);
    assert_true(pv_q > 1e-3);
    assert_true(pv_shift < 1e-9);
    assert_true(pv_uni < 1e-9);
    assert_true(pv_qw < 1e-9);
    assert_int_equal(lg.errors + lg.warnings, 0);
    assert_true(as.live == 0);
    tables_free(&t);
    free(map); free(p); free(pu); free(obs); free(shifted); free(sel);
}

/* count 1 over many seeds: every sample alone is distributed as P (the rotation makes each
   u_i, v_i uniform), so single selections over 20000 seeds pass chi-square on an 8x8 map. */
static void count_one(void **state) {
    const uint32_t w = 8, h = 8, seeds = 20000;
    float map[64];
    double p[64], total = 0.0, x, dof, pv;
    long obs[64];
    gim_selected_val sel;
    test_tables t;
    uint32_t s;
    int i;
    (void)state;
    for (i = 0; i < 64; ++i) { map[i] = (float)(1 + (i * 7) % 13); total += map[i]; obs[i] = 0; }
    map[10] = 0.0f; total -= 1 + (10 * 7) % 13;
    t = tables_of(map, w, h);
    for (i = 0; i < 64; ++i) p[i] = map[i] / total;
    for (s = 0; s < seeds; ++s) {
        assert_int_equal(select_seed(t.col, t.row, w, h, 1, s, &sel, test_env(NULL, NULL)), GIM_OK);
        assert_true(sel.x < w && sel.y < h);
        assert_true(rel_close(sel.pdf, p[sel.y * w + sel.x], 1e-6));
        obs[sel.y * w + sel.x]++;
    }
    assert_int_equal(obs[10], 0);
    x = chi2_of(obs, p, 64, seeds, &dof);
    pv = test_chi2_pvalue(x, dof);
    print_message("count 1 over %u seeds: chi2 %.1f (dof %.0f, p %.3f)\n", (unsigned)seeds, x, dof, pv);
    assert_true(pv > 1e-3);
    tables_free(&t);
}

/* A huge count shows the stratification: every column gets count * P(column) selections
   rounded up or down, every texel within a few of count * P. */
static void huge_count(void **state) {
    const uint32_t w = 32, h = 32, count = 1u << 20;
    size_t n = (size_t)w * h, i;
    float *map = (float *)malloc(n * sizeof(float));
    long *obs = (long *)calloc(n, sizeof(long)), colobs[32] = {0};
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof(gim_selected_val));
    double total = 0.0, coltot[32] = {0}, maxdev_col = 0.0, maxdev = 0.0;
    test_tables t;
    uint32_t k, x;
    (void)state;
    assert_non_null(sel);
    for (i = 0; i < n; ++i) {
        map[i] = (i % 17 == 5) ? 0.0f : (float)(0.01 + test_rand01());
        total += map[i];
        coltot[i % w] += map[i];
    }
    t = tables_of(map, w, h);
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 7u, sel, test_env(NULL, NULL)), GIM_OK);
    for (k = 0; k < count; ++k) {
        obs[(size_t)sel[k].y * w + sel[k].x]++;
        colobs[sel[k].x]++;
    }
    for (x = 0; x < w; ++x) {
        double dev = fabs((double)colobs[x] - (double)count * coltot[x] / total);
        if (dev > maxdev_col) maxdev_col = dev;
    }
    for (i = 0; i < n; ++i) {
        double dev = fabs((double)obs[i] - (double)count * map[i] / total);
        if (map[i] == 0.0f) assert_int_equal(obs[i], 0);
        if (dev > maxdev) maxdev = dev;
    }
    print_message("2^20 VALs on 32x32: max |count - N P| per column %.3f, per texel %.2f (N P ~ %.0f)\n",
                  maxdev_col, maxdev, (double)count / (double)n);
    assert_true(maxdev_col < 1.0 + 1e-6);
    /* consecutive van der Corput points in a column: discrepancy O(log N); a binomial spread
       would be ~sqrt(1000) = 32 */
    assert_true(maxdev < 12.0);
    tables_free(&t);
    free(map); free(obs); free(sel);
}

/* The documented scheme, recomputed by linear scans: the spec a GPU twin must match. */
static void documented_scheme(void **state) {
    const uint32_t w = 16, h = 8, count = 100;
    float map[128], f[4];
    gim_selected_val sel[100];
    double col[128], row[16], o0, o1, total = 0.0;
    uint32_t i, x, y, seed;
    (void)state;
    for (i = 0; i < w * h; ++i) { map[i] = (i % 7 == 2) ? 0.0f : (float)test_rand01(); }
    for (x = 0; x < w; ++x) /* the tables by their definition, column by column */
        for (y = 0; y < h; ++y) col[y * w + x] = map[y * w + x] + (y ? col[(y - 1) * w + x] : 0.0);
    for (x = 0; x < w; ++x) { total += col[(h - 1) * w + x]; row[x] = total; }
    {
        double c2[128], r2[16];
        assert_int_equal(gim_importance_cumsum(map, w, h, c2, r2, test_env(NULL, NULL)), GIM_OK);
        assert_memory_equal(c2, col, sizeof col);
        assert_memory_equal(r2, row, sizeof row);
    }
    for (seed = 0; seed < 4; ++seed) {
        gim_rotation_offsets(f, 4, seed);
        o0 = (double)f[0] + (double)f[2] / 16777216.0;
        o1 = (double)f[1] + (double)f[3] / 16777216.0;
        assert_int_equal(select_seed(col, row, w, h, count, seed, sel, test_env(NULL, NULL)), GIM_OK);
        for (i = 0; i < count; ++i) {
            double u = fmod((double)i / count + o0, 1.0), v = fmod(gim_radical_inverse(2, i) + o1, 1.0), ct, p;
            for (x = 0; !(row[x] > u * total); ++x) {}
            ct = col[(h - 1) * w + x];
            for (y = 0; !(col[y * w + x] > v * ct); ++y) {}
            p = (row[x] - (x ? row[x - 1] : 0.0)) / total * (col[y * w + x] - (y ? col[(y - 1) * w + x] : 0.0)) / ct;
            assert_int_equal(sel[i].x, x);
            assert_int_equal(sel[i].y, y);
            assert_true(sel[i].pdf == (float)p);
        }
    }
}

/* Width or height 1: the scans and searches degenerate to one dimension. */
static void width_or_height_one(void **state) {
    float map[37];
    gim_selected_val sel[3700];
    long obs[37];
    double total = 0.0;
    int pass, i;
    (void)state;
    for (i = 0; i < 37; ++i) { map[i] = (float)(i % 5); total += map[i]; }
    for (pass = 0; pass < 2; ++pass) {
        uint32_t w = pass ? 1u : 37u, h = pass ? 37u : 1u;
        test_tables t = tables_of(map, w, h);
        assert_true(t.row[w - 1] == total);
        assert_int_equal(select_seed(t.col, t.row, w, h, 3700, 3, sel, test_env(NULL, NULL)), GIM_OK);
        memset(obs, 0, sizeof obs);
        for (i = 0; i < 3700; ++i) {
            uint32_t idx = sel[i].x + sel[i].y * w;
            assert_true(sel[i].x < w && sel[i].y < h);
            assert_true(rel_close(sel[i].pdf, map[idx] / total, 1e-6));
            obs[idx]++;
        }
        /* 3700 * P is an integer multiple of 50 here: the counts are exact for h == 1 (u alone
           is a stratified lattice) and within the van der Corput discrepancy for w == 1 */
        for (i = 0; i < 37; ++i) {
            double e = 3700.0 * map[i] / total;
            assert_true(fabs((double)obs[i] - e) <= (pass ? 6.0 : 1.0));
        }
        tables_free(&t);
    }
    /* a single texel */
    {
        float one = 2.5f;
        double c, r;
        assert_int_equal(gim_importance_cumsum(&one, 1, 1, &c, &r, test_env(NULL, NULL)), GIM_OK);
        assert_int_equal(select_seed(&c, &r, 1, 1, 5, 9, sel, test_env(NULL, NULL)), GIM_OK);
        for (i = 0; i < 5; ++i) assert_true(sel[i].x == 0 && sel[i].y == 0 && sel[i].pdf == 1.0f);
    }
}

/* All-zero map: uniform fallback, pdf = 1/texels, a warning, no NaN; also from an all-invalid RSM. */
static void all_zero_map(void **state) {
    const uint32_t w = 16, h = 8, count = 1024;
    float map[128];
    gim_selected_val sel[1024];
    long colobs[16] = {0};
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    test_rsm r = rsm_new(w, h);
    gim_view_sample vs = vsample(0, 0, 1, 0, 0, -1);
    gim_importance_desc d = desc_for(&r, &vs, 1, 1.0f, env);
    test_tables t;
    uint32_t i;
    (void)state;
    for (i = 0; i < w * h; ++i) { set3(r.nrm, i, 0, 0, 1); set3(r.flux, i, 1, 1, 1); r.valid[i] = 0.0f; }
    assert_int_equal(gim_importance_map(&d, map), GIM_OK);
    for (i = 0; i < w * h; ++i) assert_true(map[i] == 0.0f);
    t = tables_of(map, w, h);
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 11, sel, env), GIM_OK);
    assert_int_equal(lg.warnings, 1);
    assert_non_null(strstr(lg.last, "all zero"));
    for (i = 0; i < count; ++i) {
        assert_true(sel[i].x < w && sel[i].y < h);
        assert_true(sel[i].pdf == 1.0f / 128.0f);
        colobs[sel[i].x]++;
    }
    for (i = 0; i < w; ++i) assert_true(colobs[i] == 64); /* uniform and stratified */
    tables_free(&t);
    rsm_free(&r);
}

/* Same seed: same selection, bit for bit; another seed: a different one. */
static void reproducible(void **state) {
    const uint32_t w = 32, h = 16, count = 512;
    float map[512];
    gim_selected_val a[512], b[512], c[512];
    test_tables t;
    int i, differ = 0;
    (void)state;
    for (i = 0; i < 512; ++i) map[i] = (float)test_rand01();
    t = tables_of(map, w, h);
    memset(a, 0, sizeof a); memset(b, 0xff, sizeof b);
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 42, a, test_env(NULL, NULL)), GIM_OK);
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 42, b, test_env(NULL, NULL)), GIM_OK);
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 43, c, test_env(NULL, NULL)), GIM_OK);
    for (i = 0; i < 512; ++i) {
        assert_true(a[i].x == b[i].x && a[i].y == b[i].y && a[i].pdf == b[i].pdf);
        differ += a[i].x != c[i].x || a[i].y != c[i].y;
    }
    assert_true(differ > 256);
    { /* offsets given: seed 42's own offsets pick as seed 42 does (one call, two ways in) */
        gim_select_desc d;
        float off[4];
        memset(&d, 0, sizeof d);
        gim_rotation_offsets(off, 4u, 42u);
        d.column = t.col; d.row = t.row; d.width = w; d.height = h; d.count = count;
        d.seed = 43u; /* ignored: offsets win */
        d.offsets = off;
        memset(b, 0xff, sizeof b);
        assert_int_equal(gim_importance_select(&d, b), GIM_OK);
        for (i = 0; i < 512; ++i) assert_true(a[i].x == b[i].x && a[i].y == b[i].y && a[i].pdf == b[i].pdf);
    }
    tables_free(&t);
}

/* Bad arguments: an error code and one error message naming the function; no crash. */
static void argument_errors(void **state) {
    test_alloc_stats as; test_log lg;
    gim_env env = test_env(&as, &lg);
    test_rsm r = rsm_new(4, 4);
    gim_view_sample vs = vsample(0, 0, 1, 0, 0, -1);
    gim_importance_desc d;
    float map[16], bad[16];
    double col[16], row[4];
    gim_selected_val sel[8];
    int i, errors = 0;
    (void)state;
    for (i = 0; i < 16; ++i) { set3(r.nrm, (size_t)i, 0, 0, 1); set3(r.flux, (size_t)i, 1, 1, 1); r.valid[i] = 1; map[i] = 1.0f; }
#define EXPECT_ERR(call, code, name) do { \
        assert_int_equal((call), (code)); \
        assert_int_equal(lg.errors, ++errors); \
        assert_non_null(strstr(lg.last, name)); \
    } while (0)
    assert_int_equal(gim_importance_map(NULL, map), GIM_ERROR_INVALID_ARGUMENT);
    d = desc_for(&r, &vs, 1, 1.0f, env);
    EXPECT_ERR(gim_importance_map(&d, NULL), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_map: out is NULL");
    d.rsm_flux = NULL;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_map");
    d = desc_for(&r, &vs, 1, 1.0f, env); d.width = 0;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "empty");
    d = desc_for(&r, &vs, 1, 1.0f, env); d.view_sample_count = 0;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "no view samples");
    d = desc_for(&r, NULL, 1, 1.0f, env);
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "no view samples");
    d = desc_for(&r, &vs, 1, 0.0f, env);
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    d = desc_for(&r, &vs, 1, NAN, env);
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    d = desc_for(&r, &vs, 1, INFINITY, env);
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    d = desc_for(&r, &vs, 1, -2.0f, env);
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "scene_scale");
    d = desc_for(&r, &vs, 1, 1.0f, env); d.clamp = -0.1f;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "clamp");
    d.clamp = NAN;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "clamp");
    d = desc_for(&r, &vs, 1, 1.0f, env); d.width = 0xffffffffu; d.height = 0xffffffffu;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_INVALID_ARGUMENT, "overflows");
    /* outputs untouched on argument errors */
    for (i = 0; i < 16; ++i) assert_true(map[i] == 1.0f);
    /* out of memory: the view-sample table */
    d = desc_for(&r, &vs, 1, 1.0f, env);
    as.fail_after = 0;
    EXPECT_ERR(gim_importance_map(&d, map), GIM_ERROR_OUT_OF_MEMORY, "gim_importance_map");
    as.fail_after = -1;
    assert_true(as.live == 0);

    /* cumsum */
    EXPECT_ERR(gim_importance_cumsum(NULL, 4, 4, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_cumsum");
    EXPECT_ERR(gim_importance_cumsum(map, 4, 4, NULL, row, env), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_cumsum");
    EXPECT_ERR(gim_importance_cumsum(map, 0, 4, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "empty");
    EXPECT_ERR(gim_importance_cumsum(map, 0xffffffffu, 0xffffffffu, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "overflows");
    memcpy(bad, map, sizeof bad); bad[6] = NAN;
    EXPECT_ERR(gim_importance_cumsum(bad, 4, 4, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "map(2, 1)");
    bad[6] = -1.0f;
    EXPECT_ERR(gim_importance_cumsum(bad, 4, 4, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "map(2, 1)");
    bad[6] = INFINITY;
    EXPECT_ERR(gim_importance_cumsum(bad, 4, 4, col, row, env), GIM_ERROR_INVALID_ARGUMENT, "map(2, 1)");
    bad[6] = -0.0f; /* negative zero is zero */
    assert_int_equal(gim_importance_cumsum(bad, 4, 4, col, row, env), GIM_OK);

    /* select */
    assert_int_equal(gim_importance_cumsum(map, 4, 4, col, row, env), GIM_OK);
    assert_int_equal(gim_importance_select(NULL, sel), GIM_ERROR_INVALID_ARGUMENT); /* no env to log through */
    EXPECT_ERR(select_seed(NULL, row, 4, 4, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_select");
    EXPECT_ERR(select_seed(col, row, 4, 4, 8, 0, NULL, env), GIM_ERROR_INVALID_ARGUMENT, "gim_importance_select");
    EXPECT_ERR(select_seed(col, row, 4, 4, 0, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "count is 0");
    EXPECT_ERR(select_seed(col, row, 4, 0, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "empty");
    row[2] = NAN;
    EXPECT_ERR(select_seed(col, row, 4, 4, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "not cumulative sums");
    row[2] = 1.0; /* decreasing */
    EXPECT_ERR(select_seed(col, row, 4, 4, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "not cumulative sums");
    assert_int_equal(gim_importance_cumsum(map, 4, 4, col, row, env), GIM_OK);
    col[3 * 4 + 1] = 0.0; /* column 1 has no total but the row table gives it weight */
    EXPECT_ERR(select_seed(col, row, 4, 4, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "not cumulative sums");
    assert_int_equal(gim_importance_cumsum(map, 4, 4, col, row, env), GIM_OK);
    for (i = 0; i < 12; ++i) col[i] = NAN; /* NaN inside the columns: caught per sample */
    EXPECT_ERR(select_seed(col, row, 4, 4, 8, 0, sel, env), GIM_ERROR_INVALID_ARGUMENT, "is not a cumulative sum");
#undef EXPECT_ERR
    assert_int_equal(lg.warnings, 0);
    assert_true(as.live == 0);
    rsm_free(&r);
}

/* Implied per-texel probability of a pair of tables (double, or float when colf is given).
   Returns the max relative error against the exact P, and counts texels of importance > 0
   that the tables make unselectable (implied probability 0) and those off by more than 1%. */
static double implied_p_error(const float *map, uint32_t w, uint32_t h, const double *col, const double *row,
                              const float *colf, const float *rowf, double exact_total, size_t *unselectable,
                              size_t *off_1pc) {
    size_t x, y;
    double maxrel = 0.0;
    *unselectable = 0;
    *off_1pc = 0;
    for (x = 0; x < w; ++x) {
        double total = colf ? rowf[w - 1] : row[w - 1];
        double ct = colf ? colf[(h - 1) * w + x] : col[(h - 1) * w + x];
        double dr = colf ? rowf[x] - (x ? rowf[x - 1] : 0.0f) : row[x] - (x ? row[x - 1] : 0.0);
        for (y = 0; y < h; ++y) {
            size_t i = y * w + x;
            double dc, p, e;
            if (map[i] == 0.0f) continue;
            dc = colf ? (double)(colf[i] - (y ? colf[i - w] : 0.0f)) : col[i] - (y ? col[i - w] : 0.0);
            p = (dr > 0.0 && ct > 0.0) ? dr / total * dc / ct : 0.0;
            e = map[i] / exact_total;
            if (!(p > 0.0)) { ++*unselectable; continue; }
            if (fabs(p - e) / e > 0.01) ++*off_1pc;
            if (fabs(p - e) / e > maxrel) maxrel = fabs(p - e) / e;
        }
    }
    return maxrel;
}

/* 4096^2: P from the double tables stays exact; a plain float scan would not. */
static void precision_4096(void **state) {
    const uint32_t w = 4096, h = 4096, count = 1u << 20;
    size_t n = (size_t)w * h, i, unsel_d, unsel_f, unsel_flat = 0, off_d, off_f, nonzero = 0;
    float *map = (float *)malloc(n * sizeof(float));
    float *colf = (float *)malloc(n * sizeof(float)), *rowf = (float *)malloc(w * sizeof(float));
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof(gim_selected_val));
    long *obs = (long *)calloc(64 * 64, sizeof(long));
    double *pb = (double *)calloc(64 * 64, sizeof(double));
    long double exact = 0.0L;
    double total, err_d, err_f, maxsel = 0.0, x2, dof, pv;
    test_tables t;
    float flat = 0.0f;
    uint32_t k;
    (void)state;
    assert_non_null(map); assert_non_null(colf); assert_non_null(sel);
    /* importance over 5 decades, 5% zero texels, a bright corner as a sunlit patch would give */
    for (i = 0; i < n; ++i) {
        double r = test_rand01();
        size_t x = i % w, y = i / w;
        map[i] = (i % 20 == 7) ? 0.0f : (float)exp(-11.5 * r);
        if (x < 256 && y < 256) map[i] *= 50.0f;
        exact += map[i];
        nonzero += map[i] > 0.0f;
    }
    total = (double)exact;
    t = tables_of(map, w, h);
    assert_true(fabs(t.row[w - 1] - total) <= 1e-12 * total);
    err_d = implied_p_error(map, w, h, t.col, t.row, NULL, NULL, total, &unsel_d, &off_d);
    /* the same scans in float, as a naive GPU pass would run them */
    for (i = 0; i < n; ++i) colf[i] = map[i] + (i >= w ? colf[i - w] : 0.0f);
    for (k = 0; k < w; ++k) rowf[k] = colf[(size_t)(h - 1) * w + k] + (k ? rowf[k - 1] : 0.0f);
    err_f = implied_p_error(map, w, h, NULL, NULL, colf, rowf, total, &unsel_f, &off_f);
    /* and one flat float scan over all texels (one table, one search) */
    for (i = 0; i < n; ++i) {
        float next = flat + map[i];
        if (map[i] > 0.0f && next == flat) ++unsel_flat;
        flat = next;
    }
    print_message("4096^2 (%lu texels > 0): max relative error of the implied P: double tables %.3g "
                  "(%lu unselectable, %lu off by > 1%%); float column+row scans %.3g (%lu unselectable, %lu off by > 1%%); "
                  "flat float scan: %lu unselectable\n", (unsigned long)nonzero, err_d, (unsigned long)unsel_d,
                  (unsigned long)off_d, err_f, (unsigned long)unsel_f, (unsigned long)off_f, (unsigned long)unsel_flat);
    assert_true(err_d < 1e-9);
    assert_int_equal(unsel_d, 0);
    assert_int_equal(off_d, 0);
    assert_true(err_f > 1e3 * err_d); /* why the tables are double */
    /* selection: every pdf is the exact P, and 1M selections in 64x64 blocks pass chi-square */
    assert_int_equal(select_seed(t.col, t.row, w, h, count, 2024u, sel, test_env(NULL, NULL)), GIM_OK);
    for (k = 0; k < count; ++k) {
        size_t idx = (size_t)sel[k].y * w + sel[k].x;
        double e = map[idx] / total, rel = fabs(sel[k].pdf - e) / e;
        assert_true(map[idx] > 0.0f);
        if (rel > maxsel) maxsel = rel;
        obs[(sel[k].y / 64) * 64 + sel[k].x / 64]++;
    }
    for (i = 0; i < n; ++i) pb[((i / w) / 64) * 64 + (i % w) / 64] += map[i] / total;
    x2 = chi2_of(obs, pb, 64 * 64, count, &dof);
    pv = test_chi2_pvalue(x2, dof);
    print_message("4096^2, 2^20 VALs: max relative pdf error %.3g; 64x64 blocks chi2 %.1f (dof %.0f, p %.3f)\n",
                  maxsel, x2, dof, pv);
    assert_true(maxsel < 1e-6); /* float rounding of the pdf itself */
    assert_true(pv > 1e-3);
    tables_free(&t);
    free(map); free(colf); free(rowf); free(sel); free(obs); free(pb);
}

/* --- two-level importance (gim_importance_tile_map + gim_importance_select with tile > 1) --- */

/* The tile map by hand: a 7x5 RSM in tiles of 3 (3x2 tiles, the last column and row partial)
   holding texels on a floor (y = 0), a wall (z = 0) and a shelf (y = 0.3 s, above the floor: the
   same normal, another plane). Each texel's weight is its luminance times eq. 10 of its plane's
   aggregate in its tile (gim_importance_map of one texel at the plane's flux-weighted mean
   position and normal, luminance 1), 0 at invalid and black texels; the tile's value is the sum
   of its weights; tile 1 is the per-texel map. Merging the shelf into the floor (one aggregate
   in mid-air) or the wall into the floor changes the weights by far more than the tolerance. */
static void tile_map_aggregate(void **state) {
    const uint32_t w = 7, h = 5, T = 3, tw = 3, th = 2, nvs = 24;
    const float s = 3.0f;
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    test_rsm r = rsm_new(w, h), one = rsm_new(1, 1);
    gim_view_sample vs[24];
    float tiles[6], weight[35], per[35], single, tiles1[35], weight1[35];
    gim_importance_desc d;
    uint32_t i, tx, ty, x, y, c;
    (void)state;
    random_scene(&r, vs, nvs, s);
    for (i = 0; i < w * h; ++i)   /* planes: 0 floor, 1 wall, 2 shelf */
        if (i % 3 == 2) { set3(r.pos, i, r.pos[i * 3], 0.3f * s, r.pos[i * 3 + 1]); set3(r.nrm, i, 0, 1, 0); }
    r.valid[7] = 0.0f;                  /* an invalid texel: weight 0, out of the aggregate */
    set3(r.flux, 11, 0, 0, 0);          /* a black one */
    d = desc_for(&r, vs, nvs, s, env);
    assert_int_equal(gim_importance_tile_map(&d, T, tiles, weight), GIM_OK);
    for (ty = 0; ty < th; ++ty)
        for (tx = 0; tx < tw; ++tx) {
            double sum = 0.0;
            for (c = 0; c < 3; ++c) {   /* each plane of the tile */
                double phi = 0, p[3] = {0, 0, 0}, n[3] = {0, 0, 0}, len, g;
                gim_importance_desc d1;
                for (y = ty * T; y < ty * T + T && y < h; ++y)
                    for (x = tx * T; x < tx * T + T && x < w; ++x) {
                        uint32_t k = y * w + x, q;
                        double lum = 0.2126f * r.flux[k * 3] + 0.7152f * r.flux[k * 3 + 1] + 0.0722f * r.flux[k * 3 + 2];
                        if (k % 3 != c || k == 7 || k == 11) continue;
                        phi += lum;
                        for (q = 0; q < 3; ++q) { p[q] += lum * r.pos[k * 3 + q]; n[q] += lum * r.nrm[k * 3 + q]; }
                    }
                if (phi == 0.0) continue;
                len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
                set3(one.pos, 0, (float)(p[0] / phi), (float)(p[1] / phi), (float)(p[2] / phi));
                set3(one.nrm, 0, (float)(n[0] / len), (float)(n[1] / len), (float)(n[2] / len));
                set3(one.flux, 0, 1, 1, 1);
                one.valid[0] = 1.0f;
                d1 = desc_for(&one, vs, nvs, s, env);
                assert_int_equal(gim_importance_map(&d1, &single), GIM_OK);
                g = single / (0.2126f + 0.7152f + 0.0722f);   /* eq. 10's sum / N_VS of the plane */
                for (y = ty * T; y < ty * T + T && y < h; ++y)
                    for (x = tx * T; x < tx * T + T && x < w; ++x) {
                        uint32_t k = y * w + x;
                        double lum = 0.2126f * r.flux[k * 3] + 0.7152f * r.flux[k * 3 + 1] + 0.0722f * r.flux[k * 3 + 2];
                        if (k % 3 != c || k == 7 || k == 11) continue;
                        assert_true(weight[k] > 0.0f);
                        assert_true(rel_close(weight[k], lum * g, 1e-5));
                        sum += weight[k];
                    }
            }
            assert_true(rel_close(tiles[ty * tw + tx], sum, 1e-6));
        }
    assert_true(weight[7] == 0.0f && weight[11] == 0.0f);
    /* tile 1: the per-texel map */
    assert_int_equal(gim_importance_map(&d, per), GIM_OK);
    assert_int_equal(gim_importance_tile_map(&d, 1, tiles1, weight1), GIM_OK);
    for (i = 0; i < w * h; ++i) assert_true(rel_close(tiles1[i], per[i], 1e-6) || (per[i] == 0.0f && tiles1[i] == 0.0f));
    /* errors: one log line each, nothing written past the checks */
    assert_int_equal(gim_importance_tile_map(&d, 0, tiles, weight), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim_importance_tile_map(&d, GIM_MAX_IMPORTANCE_TILE + 1, tiles, weight), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim_importance_tile_map(&d, 2, NULL, weight), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_importance_tile_map(&d, 2, tiles, NULL), GIM_ERROR_INVALID_ARGUMENT);
    d.view_sample_count = 0;
    assert_int_equal(gim_importance_tile_map(&d, 2, tiles, weight), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 5);
    rsm_free(&r); rsm_free(&one);
}

/* P(texel) = P(tile) * weight / Phi_tile from the tile tables, as the pick computes it. */
static void two_level_p(const double *col, const double *row, const float *weight, uint32_t w, uint32_t h, uint32_t T,
                        double *p) {
    uint32_t tw = (w - 1) / T + 1, th = (h - 1) / T + 1, tx, ty, x, y;
    double total = row[tw - 1];
    for (ty = 0; ty < th; ++ty)
        for (tx = 0; tx < tw; ++tx) {
            double ct = col[(size_t)(th - 1) * tw + tx], pc = (row[tx] - (tx ? row[tx - 1] : 0.0)) / total;
            double pr = ct > 0.0 ? (col[(size_t)ty * tw + tx] - (ty ? col[(size_t)(ty - 1) * tw + tx] : 0.0)) / ct : 0.0;
            double sum = 0.0;
            for (y = ty * T; y < ty * T + T && y < h; ++y)
                for (x = tx * T; x < tx * T + T && x < w; ++x) sum += weight[y * w + x];
            for (y = ty * T; y < ty * T + T && y < h; ++y)
                for (x = tx * T; x < tx * T + T && x < w; ++x)
                    p[y * w + x] = sum > 0.0 ? pc * pr * weight[y * w + x] / sum : 0.0;
        }
}

static gim_result select_tiled(const test_tables *t, const float *weight, uint32_t w, uint32_t h, uint32_t T,
                               uint32_t count, uint32_t seed, gim_selected_val *out, gim_env env) {
    gim_select_desc d;
    memset(&d, 0, sizeof d);
    d.column = t->col; d.row = t->row; d.width = (w - 1) / T + 1; d.height = (h - 1) / T + 1;
    d.count = count; d.seed = seed; d.tile = T; d.weight = weight; d.rsm_width = w; d.rsm_height = h; d.env = env;
    return gim_importance_select(&d, out);
}

/* The two-level pick keeps its pdf exact: on a 22x13 RSM in tiles of 4 (6x4 tiles, partial
   at the edges) with invalid and black texels, every pick reports P = P(tile) w / Phi_tile from
   the tables (1e-6), the P of all texels sums to 1 (1e-12), and the frequencies over many seeds
   pass chi-square per texel, both with many VALs a call (stratified) and one VAL a call over
   20000 seeds (each sample alone is distributed as P). The same test rejects a pick whose
   texel inside the tile ignored the weights (uniform in the tile) and a pdf of P(tile) alone. */
static void two_level_frequencies(void **state) {
    const uint32_t w = 22, h = 13, T = 4, tw = 6, th = 4, nvs = 40, count = 3000, seeds = 60, singles = 20000;
    size_t n = (size_t)w * h, i;
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    test_rsm r = rsm_new(w, h);
    gim_view_sample vs[40];
    float tiles[24], weight[22 * 13], flat[22 * 13];
    double p[22 * 13], pflat[22 * 13], sum = 0.0, x, dof, pv, pv_flat, pv_one;
    long obs[22 * 13], obs_one[22 * 13];
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof *sel);
    gim_importance_desc d;
    test_tables t;
    uint32_t s, k;
    (void)state;
    random_scene(&r, vs, nvs, 2.0f);
    for (i = 0; i < n; i += 7) r.valid[i] = 0.0f;
    for (i = 3; i < n; i += 11) set3(r.flux, i, 0, 0, 0);
    for (i = 0; i < n; ++i) set3(r.flux, i, r.flux[i * 3] * (float)(1 + i % 5), r.flux[i * 3 + 1], r.flux[i * 3 + 2]);
    d = desc_for(&r, vs, nvs, 2.0f, env);
    assert_int_equal(gim_importance_tile_map(&d, T, tiles, weight), GIM_OK);
    t = tables_of(tiles, tw, th);
    two_level_p(t.col, t.row, weight, w, h, T, p);
    for (i = 0; i < n; ++i) { sum += p[i]; flat[i] = weight[i] > 0.0f ? 1.0f : 0.0f; obs[i] = obs_one[i] = 0; }
    print_message("two levels: sum of P over the texels - 1 = %.3g\n", sum - 1.0);
    assert_true(fabs(sum - 1.0) < 1e-12);
    two_level_p(t.col, t.row, flat, w, h, T, pflat);   /* the wrong pdf: uniform inside the tile */
    for (s = 0; s < seeds; ++s) {
        assert_int_equal(select_tiled(&t, weight, w, h, T, count, 500u + s, sel, env), GIM_OK);
        for (k = 0; k < count; ++k) {
            size_t idx = (size_t)sel[k].y * w + sel[k].x;
            assert_true(sel[k].x < w && sel[k].y < h);
            assert_true(weight[idx] > 0.0f);                       /* P > 0 for every selected texel */
            assert_true(rel_close(sel[k].pdf, p[idx], 1e-6));
            obs[idx]++;
        }
    }
    for (s = 0; s < singles; ++s) {
        assert_int_equal(select_tiled(&t, weight, w, h, T, 1, s, sel, env), GIM_OK);
        assert_true(rel_close(sel[0].pdf, p[(size_t)sel[0].y * w + sel[0].x], 1e-6));
        obs_one[(size_t)sel[0].y * w + sel[0].x]++;
    }
    x = chi2_of(obs, p, n, (double)count * seeds, &dof);
    pv = test_chi2_pvalue(x, dof);
    print_message("two levels, %u x %u: chi2 %.1f (dof %.0f, p %.3f)", (unsigned)seeds, (unsigned)count, x, dof, pv);
    x = chi2_of(obs, pflat, n, (double)count * seeds, &dof);
    pv_flat = test_chi2_pvalue(x, dof);
    x = chi2_of(obs_one, p, n, singles, &dof);
    pv_one = test_chi2_pvalue(x, dof);
    print_message("; one a call over %u seeds: chi2 %.1f (p %.3f); wrong pdf (uniform in the tile) p %.2g\n",
                  (unsigned)singles, x, pv_one, pv_flat);
    assert_true(pv > 1e-3);
    assert_true(pv_one > 1e-3);
    assert_true(pv_flat < 1e-9);
    assert_int_equal(lg.errors + lg.warnings, 0);
    tables_free(&t);
    rsm_free(&r);
    free(sel);
}

/* Two-level errors and the all-zero fallback: weights missing, an RSM size that is not the
   tables' in tiles, a picked tile whose weights are all 0 (weights not the tile map's) are
   refused with one log line; an all-zero tile map selects texels uniformly over the RSM. */
static void two_level_errors(void **state) {
    const uint32_t w = 10, h = 7, T = 4;
    float tiles[6] = {1, 2, 0, 3, 0, 1}, weight[70], zero[6] = {0, 0, 0, 0, 0, 0};
    gim_selected_val sel[256];
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    test_tables t = tables_of(tiles, 3, 2), tz = tables_of(zero, 3, 2);
    gim_select_desc d;
    uint32_t i;
    (void)state;
    for (i = 0; i < w * h; ++i) weight[i] = 1.0f + (float)(i % 3);
    assert_int_equal(select_tiled(&t, weight, w, h, T, 256, 3, sel, env), GIM_OK);
    memset(&d, 0, sizeof d);
    d.column = t.col; d.row = t.row; d.width = 3; d.height = 2; d.count = 8; d.tile = T; d.rsm_width = w;
    d.rsm_height = h; d.env = env;
    assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_INVALID_ARGUMENT);       /* no weight */
    d.weight = weight; d.rsm_width = 13;
    assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_INVALID_ARGUMENT);       /* 13 / 4: 4 tiles */
    d.rsm_width = w; d.tile = GIM_MAX_IMPORTANCE_TILE + 1;
    assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_OUT_OF_RANGE);
    for (i = 0; i < w * h; ++i) weight[i] = 0.0f;
    assert_int_equal(select_tiled(&t, weight, w, h, T, 256, 3, sel, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 4);
    assert_int_equal(select_tiled(&tz, weight, w, h, T, 256, 3, sel, env), GIM_OK);
    assert_non_null(strstr(lg.last, "all zero"));
    for (i = 0; i < 256; ++i) assert_true(sel[i].x < w && sel[i].y < h && sel[i].pdf == 1.0f / 70.0f);
    tables_free(&t); tables_free(&tz);
}

/* The defensive share (gim_select_desc.defensive_count; Hesterberg 1995, the balance heuristic):
   per texel (tile 1) and in tiles of 4 on a 22x13 RSM whose importance is 0 on a fifth of the
   texels that have light. Every pick reports the mixture's pdf, (N_1 P_imp + N_2 P_lum) / N
   (1e-6), frequencies over many seeds pass chi-square against it (and fail against P_imp alone),
   texels of importance 0 are picked, no pick weighs more than L_total / N_2 of luminance, and
   the estimate of sum f over many seeds is within 1% of the sum (f = luminance x a random
   term; importance alone misses a fifth of it). Refused: a share of all picks, the luminance
   tables missing or not cumulative. gim_importance_luminance: the texels' luminance, 0 where no
   VAL, and its tile sums. */
static void defensive_share(void **state) {
    const uint32_t w = 22, h = 13, count = 2000, seeds = 80;
    size_t n = (size_t)w * h, i;
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    float imp[22 * 13], lum[22 * 13], f[22 * 13];
    double pa[22 * 13], pb[22 * 13], pm[22 * 13], ltot = 0.0, ftot = 0.0, fimp = 0.0;
    long obs[22 * 13];
    gim_selected_val *sel = (gim_selected_val *)malloc(count * sizeof *sel);
    uint32_t T, s, k;
    (void)state;
    for (i = 0; i < n; ++i) {
        lum[i] = i % 13 == 5 ? 0.0f : (float)(0.2 + test_rand01());
        imp[i] = lum[i] > 0.0f && i % 5 != 2 ? lum[i] * (float)(0.01 + test_rand01()) : 0.0f;
        f[i] = lum[i] * (float)(0.5 + test_rand01());
        ltot += lum[i];
        ftot += f[i];
        if (imp[i] > 0.0f) fimp += f[i];
    }
    for (T = 1; T <= 4; T += 3) {
        uint32_t tw = (w - 1) / T + 1, th = (h - 1) / T + 1, n2 = count / 8, zero_picked = 0, x, y;
        float ti[6 * 4], tl[6 * 4];
        test_tables a, b;
        gim_select_desc d;
        double x2, dof, pv, pv_imp, est = 0.0, maxw = 0.0;
        memset(ti, 0, sizeof ti);
        memset(tl, 0, sizeof tl);
        for (y = 0; y < h && T > 1; ++y)
            for (x = 0; x < w; ++x) {
                ti[(y / T) * tw + x / T] += imp[y * w + x];
                tl[(y / T) * tw + x / T] += lum[y * w + x];
            }
        a = tables_of(T > 1 ? ti : imp, tw, th);
        b = tables_of(T > 1 ? tl : lum, tw, th);
        two_level_p(a.col, a.row, imp, w, h, T, pa);
        two_level_p(b.col, b.row, lum, w, h, T, pb);
        for (i = 0; i < n; ++i) { pm[i] = ((count - n2) * pa[i] + n2 * pb[i]) / count; obs[i] = 0; }
        memset(&d, 0, sizeof d);
        d.column = a.col; d.row = a.row; d.width = tw; d.height = th; d.count = count;
        d.tile = T; d.weight = T > 1 ? imp : NULL; d.rsm_width = w; d.rsm_height = h; d.env = env;
        d.defensive_count = n2; d.lum_column = b.col; d.lum_row = b.row; d.lum_weight = T > 1 ? lum : NULL;
        for (s = 0; s < seeds; ++s) {
            double e = 0.0;
            d.seed = 77u + s;
            assert_int_equal(gim_importance_select(&d, sel), GIM_OK);
            for (k = 0; k < count; ++k) {
                size_t idx = (size_t)sel[k].y * w + sel[k].x;
                double wl = lum[idx] / (count * (double)sel[k].pdf);
                assert_true(sel[k].x < w && sel[k].y < h);
                assert_true(lum[idx] > 0.0f);
                assert_true(rel_close(sel[k].pdf, pm[idx], 1e-6));
                zero_picked += imp[idx] == 0.0f;
                maxw = wl > maxw ? wl : maxw;
                e += f[idx] / (count * (double)sel[k].pdf);
                obs[idx]++;
            }
            est += e / seeds;
        }
        x2 = chi2_of(obs, pm, n, (double)count * seeds, &dof);
        pv = test_chi2_pvalue(x2, dof);
        x2 = chi2_of(obs, pa, n, (double)count * seeds, &dof);
        pv_imp = test_chi2_pvalue(x2, dof);
        print_message("defensive share %u of %u, tile %u: chi2 p %.3f (against importance alone %.2g); %u picks of "
                      "importance 0; heaviest pick %.3f of L_total / N_2; estimate / sum %.4f (importance alone "
                      "reaches %.3f)\n", (unsigned)n2, (unsigned)count, (unsigned)T, pv, pv_imp, (unsigned)zero_picked,
                      maxw / (ltot / n2), est / ftot, fimp / ftot);
        assert_true(pv > 1e-3);
        assert_true(pv_imp < 1e-9);
        assert_true(zero_picked > 0u);
        assert_true(maxw <= ltot / n2 * (1.0 + 1e-5));
        assert_true(fabs(est / ftot - 1.0) < 0.01);
        assert_true(fimp / ftot < 0.9);
        /* refused */
        d.defensive_count = count;
        assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_INVALID_ARGUMENT);
        d.defensive_count = n2; d.lum_row = NULL;
        assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_INVALID_ARGUMENT);
        d.lum_row = b.row; b.row[0] = -1.0;
        assert_int_equal(gim_importance_select(&d, sel), GIM_ERROR_INVALID_ARGUMENT);
        assert_non_null(strstr(lg.last, "luminance"));
        tables_free(&a); tables_free(&b);
    }
    assert_int_equal(lg.errors, 6);
    {   /* gim_importance_luminance: the luminance where gim_importance_map sees a VAL, and tile sums */
        test_rsm r = rsm_new(w, h);
        gim_view_sample vs[8];
        gim_importance_desc dd;
        float lw[22 * 13], lt[6 * 4], lm[22 * 13], m[22 * 13];
        random_scene(&r, vs, 8, 2.0f);
        for (i = 0; i < n; i += 7) r.valid[i] = 0.0f;
        for (i = 3; i < n; i += 11) set3(r.flux, i, 0, 0, 0);
        dd = desc_for(&r, vs, 8, 2.0f, env);
        assert_int_equal(gim_importance_map(&dd, m), GIM_OK);
        assert_int_equal(gim_importance_luminance(&dd, 1, lm, NULL), GIM_OK);
        assert_int_equal(gim_importance_luminance(&dd, 4, lt, lw), GIM_OK);
        for (i = 0; i < n; ++i) {
            double l = 0.2126 * r.flux[i * 3] + 0.7152 * r.flux[i * 3 + 1] + 0.0722 * r.flux[i * 3 + 2];
            int val = r.valid[i] > 0.0f && l > 0.0;
            assert_true(val ? rel_close(lm[i], l, 1e-6) : lm[i] == 0.0f);
            assert_true(lw[i] == lm[i]);
            if (m[i] > 0.0f) assert_true(lm[i] > 0.0f);   /* importance only where there is light */
        }
        for (k = 0; k < 24; ++k) {
            double sum = 0.0;
            uint32_t x, y;
            for (y = (k / 6) * 4; y < (k / 6) * 4 + 4 && y < h; ++y)
                for (x = (k % 6) * 4; x < (k % 6) * 4 + 4 && x < w; ++x) sum += lw[y * w + x];
            assert_true(rel_close(lt[k], sum, 1e-6));
        }
        assert_int_equal(gim_importance_luminance(&dd, 4, lt, NULL), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim_importance_luminance(&dd, 0, lt, lw), GIM_ERROR_OUT_OF_RANGE);
        rsm_free(&r);
    }
    free(sel);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(eq10_hand_computed),
        cmocka_unit_test(eq11_clamp),
        cmocka_unit_test(scale_invariance),
        cmocka_unit_test(backfacing_and_invalid),
        cmocka_unit_test(chi_square_frequencies),
        cmocka_unit_test(count_one),
        cmocka_unit_test(huge_count),
        cmocka_unit_test(documented_scheme),
        cmocka_unit_test(width_or_height_one),
        cmocka_unit_test(all_zero_map),
        cmocka_unit_test(reproducible),
        cmocka_unit_test(argument_errors),
        cmocka_unit_test(precision_4096),
        cmocka_unit_test(tile_map_aggregate),
        cmocka_unit_test(two_level_frequencies),
        cmocka_unit_test(two_level_errors),
        cmocka_unit_test(defensive_share),
    };
    return cmocka_run_group_tests_name("importance", tests, NULL, NULL);
}
