/* gim_rsm_vpls_twin, the VPLs of clustered visibility (Dong et al. sec. 4) taken from an RSM at
   Halton points: their flux sums to the RSM's total over the lit texels (per channel), each
   sits on the texel its Halton point falls in, unlit texels give dark VPLs, the zero-sum guard
   leaves no NaN, the result scales with the flux unit, bad arguments fail and leave the
   outputs untouched. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define W 37
#define H 23
#define N 300

/* gim_rsm_vpls_twin and gim_cluster_paraboloids_twin with their descs filled from arguments,
   the form the many calls here take. */
static gim_result vpls_of(const gim_rsm_data *rsm, uint32_t count, gim_vpl_sequence sequence, const float *offsets,
                          float *positions, float *normals, float *flux, gim_env env) {
    gim_rsm_vpls_desc d;
    memset(&d, 0, sizeof d);
    d.rsm = rsm; d.count = count; d.sequence = sequence; d.offsets = offsets; d.env = env;
    return gim_rsm_vpls_twin(&d, positions, normals, flux, NULL);
}
static gim_result paraboloids_of(const gim_vpl *vpls, uint32_t vpl_count, const uint32_t *cluster, const float *centres,
                                 const float *normals, uint32_t cluster_count, float scene_scale, gim_paraboloid *out,
                                 gim_env env) {
    gim_cluster_desc d;
    memset(&d, 0, sizeof d);
    d.vpls = vpls; d.vpl_count = vpl_count; d.cluster = cluster; d.centres = centres; d.normals = normals;
    d.cluster_count = cluster_count; d.scene_scale = scene_scale; d.env = env;
    return gim_cluster_paraboloids_twin(&d, out);
}

/* Texel (x, y) at position (x + 0.5, y + 0.5, 7) so a VPL's position names its texel; random
   unit-ish normals, random flux; every 9th texel unlit. */
typedef struct vpl_rsm {
    float pos[W * H * 3], nrm[W * H * 3], flux[W * H * 3], area[W * H], valid[W * H];
    gim_rsm_data rsm;
} vpl_rsm;

static void make_rsm(vpl_rsm *r) {
    int x, y;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int t = y * W + x;
            r->pos[t * 3] = x + 0.5f; r->pos[t * 3 + 1] = y + 0.5f; r->pos[t * 3 + 2] = 7.0f;
            r->nrm[t * 3] = 0.0f; r->nrm[t * 3 + 1] = 0.6f; r->nrm[t * 3 + 2] = 0.8f;
            r->flux[t * 3] = (float)test_rand01();
            r->flux[t * 3 + 1] = (float)(2.0 * test_rand01());
            r->flux[t * 3 + 2] = (float)(0.1 * test_rand01());
            r->area[t] = 1.0f;
            r->valid[t] = t % 9 == 4 ? 0.0f : 1.0f;
        }
    memset(&r->rsm, 0, sizeof r->rsm);
    r->rsm.position = r->pos; r->rsm.normal = r->nrm; r->rsm.flux = r->flux; r->rsm.area = r->area;
    r->rsm.valid = r->valid;
    r->rsm.width = W; r->rsm.height = H;
}

/* The RSM's total over the lit texels, in double. */
static void total_flux(const vpl_rsm *r, double out[3]) {
    int t, a;
    out[0] = out[1] = out[2] = 0.0;
    for (t = 0; t < W * H; ++t)
        if (r->valid[t] > 0.0f)
            for (a = 0; a < 3; ++a) out[a] += r->flux[t * 3 + a];
}

static vpl_rsm g_rsm;
static float g_p[N * 3], g_n[N * 3], g_f[N * 3];

/* The VPLs' flux sums to the lit total per channel (1e-6 relative: float rounding of each
   share), with and without a Cranley-Patterson rotation, and every VPL's flux is its texel's
   times one factor per channel. Same input twice: the same bits. */
static void flux_sums_to_the_total(void **state) {
    static const float off[2] = {0.3f, 0.71f};
    double tot[3];
    int pass, i, a;
    test_log log;
    gim_env env = test_env(NULL, &log);
    (void)state;
    make_rsm(&g_rsm);
    total_flux(&g_rsm, tot);
    for (pass = 0; pass < 2; ++pass) {
        double sum[3] = {0.0, 0.0, 0.0}, factor[3] = {0.0, 0.0, 0.0};
        float p2[N * 3], n2[N * 3], f2[N * 3];
        const float *o = pass ? off : NULL;
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, o, g_p, g_n, g_f, env), GIM_OK);
        for (i = 0; i < N; ++i) {
            int x = (int)g_p[i * 3], y = (int)g_p[i * 3 + 1], t = y * W + x;
            for (a = 0; a < 3; ++a) {
                sum[a] += g_f[i * 3 + a];
                if (g_rsm.valid[t] > 0.0f && g_rsm.flux[t * 3 + a] > 0.0f) {
                    double q = g_f[i * 3 + a] / (double)g_rsm.flux[t * 3 + a];
                    if (factor[a] == 0.0) factor[a] = q;
                    assert_true(fabs(q - factor[a]) <= 1e-6 * factor[a]);
                }
            }
        }
        for (a = 0; a < 3; ++a) {
            assert_true(tot[a] > 0.0);
            assert_true(fabs(sum[a] - tot[a]) <= 1e-6 * tot[a]);
            assert_true(factor[a] > 1.0);   /* N < lit texels: each VPL stands for several */
        }
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, o, p2, n2, f2, env), GIM_OK);
        assert_memory_equal(p2, g_p, sizeof p2);
        assert_memory_equal(n2, g_n, sizeof n2);
        assert_memory_equal(f2, g_f, sizeof f2);
    }
    assert_int_equal(log.errors, 0);
}

/* VPL i sits on texel (floor(u W), floor(v H)) of Halton point i + 1 (bases 2, 3), rotated by
   the offsets when given; its normal is the texel's. */
static void halton_placement(void **state) {
    static const float off[2] = {0.9f, 0.05f};
    int pass, i;
    gim_env env = test_env(NULL, NULL);
    (void)state;
    make_rsm(&g_rsm);
    for (pass = 0; pass < 2; ++pass) {
        float pts[N * 2];
        const float *o = pass ? off : NULL;
        assert_int_equal(gim_halton_points(pts, N, 2, 1, o), GIM_OK);
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, o, g_p, g_n, g_f, env), GIM_OK);
        for (i = 0; i < N; ++i) {
            double u = o ? gim_rotate01((float)gim_halton((uint32_t)i + 1, 0), o[0]) : gim_halton((uint32_t)i + 1, 0);
            int x = (int)floor((double)pts[i * 2] * W), y = (int)floor((double)pts[i * 2 + 1] * H);
            assert_true(fabs(u - pts[i * 2]) < 1e-6);   /* the helper is Halton base 2 */
            assert_true(g_p[i * 3] == x + 0.5f);
            assert_true(g_p[i * 3 + 1] == y + 0.5f);
            assert_true(g_p[i * 3 + 2] == 7.0f);
            assert_true(g_n[i * 3 + 1] == 0.6f && g_n[i * 3 + 2] == 0.8f);
        }
        /* the first point, (1/2, 1/3) unrotated */
        if (!o) {
            assert_true(g_p[0] == (float)(W / 2) + 0.5f);
            assert_true(g_p[1] == (float)(H / 3) + 0.5f);
        }
    }
}

/* Unlit and broken texels give zero flux and take no part in the total; a non-finite position
   or normal is written as zero; a channel no sampled texel carries stays zero (no NaN), while
   the others still sum to the total. A 1 x 1 RSM: every VPL on its one texel. */
static void unlit_texels(void **state) {
    float p[N * 3], n[N * 3], f[N * 3];
    double tot[3], sum[3] = {0.0, 0.0, 0.0};
    int i, a, unlit = 0;
    gim_env env = test_env(NULL, NULL);
    (void)state;
    make_rsm(&g_rsm);
    /* texel of VPL 0 (x = W / 2, y = H / 3): NaN position and flux */
    {
        int t = (H / 3) * W + W / 2;
        g_rsm.pos[t * 3] = NAN;
        g_rsm.nrm[t * 3 + 2] = INFINITY;
        g_rsm.flux[t * 3 + 1] = NAN;
    }
    for (i = 0; i < W * H; ++i) g_rsm.flux[i * 3 + 2] = 0.0f;   /* blue: dark everywhere */
    g_rsm.flux[(W * H - 1) * 3 + 2] = 1.0f;                        /* but for a corner texel no VPL takes */
    g_rsm.valid[W * H - 1] = 1.0f;
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_OK);
    assert_true(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f);
    assert_true(n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f);
    assert_true(f[0] == 0.0f && f[1] == 0.0f && f[2] == 0.0f);
    total_flux(&g_rsm, tot);
    {   /* the broken texel is unlit for the total too */
        int t = (H / 3) * W + W / 2;
        for (a = 0; a < 3; ++a) tot[a] -= g_rsm.flux[t * 3 + a] == g_rsm.flux[t * 3 + a] ? g_rsm.flux[t * 3 + a] : 0.0;
        tot[1] = 0.0;
        for (i = 0; i < W * H; ++i)
            if (g_rsm.valid[i] > 0.0f && i != t) tot[1] += g_rsm.flux[i * 3 + 1];
    }
    for (i = 0; i < N; ++i) {
        int t;
        for (a = 0; a < 3; ++a) {
            assert_true(gim__isfinitef(f[i * 3 + a]) && f[i * 3 + a] >= 0.0f);
            sum[a] += f[i * 3 + a];
        }
        if (i == 0) continue;
        t = (int)p[i * 3 + 1] * W + (int)p[i * 3];
        assert_true(t != W * H - 1);
        if (g_rsm.valid[t] <= 0.0f) {
            ++unlit;
            assert_true(f[i * 3] == 0.0f && f[i * 3 + 1] == 0.0f);
            assert_true(p[i * 3 + 2] == 7.0f);   /* the position is still copied */
        }
    }
    assert_true(unlit > 10);
    assert_true(fabs(sum[0] - tot[0]) <= 1e-6 * tot[0]);
    assert_true(fabs(sum[1] - tot[1]) <= 1e-6 * tot[1]);
    assert_true(sum[2] == 0.0);   /* S = 0: the guard, not 0 / 0 */
    {   /* 1 x 1 */
        gim_rsm_data one = g_rsm.rsm;
        float fl[3] = {3.0f, 0.0f, 1.5f};
        one.flux = fl; one.valid = NULL; one.position = g_rsm.pos + 3; one.normal = g_rsm.nrm + 3;
        one.width = one.height = 1;
        assert_int_equal(vpls_of(&one, 4, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_OK);
        for (i = 0; i < 4; ++i) {
            assert_true(p[i * 3] == 1.5f);
            assert_true(f[i * 3] == 0.75f && f[i * 3 + 1] == 0.0f && f[i * 3 + 2] == 0.375f);
        }
    }
}

/* Unit-free: flux in another unit (x 1000) scales every VPL's flux by 1000; positions in
   another unit (x 1e-3) leave texels and flux alone. */
static void units(void **state) {
    float p2[N * 3], n2[N * 3], f2[N * 3];
    int i;
    gim_env env = test_env(NULL, NULL);
    (void)state;
    make_rsm(&g_rsm);
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, g_p, g_n, g_f, env), GIM_OK);
    for (i = 0; i < W * H * 3; ++i) { g_rsm.flux[i] *= 1000.0f; g_rsm.pos[i] *= 1e-3f; }
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p2, n2, f2, env), GIM_OK);
    for (i = 0; i < N * 3; ++i) {
        assert_true(fabs(f2[i] - 1000.0 * g_f[i]) <= 1e-5 * 1000.0 * g_f[i]);
        assert_true(p2[i] == g_p[i] * 1e-3f);
    }
}

/* Bad arguments: an error through the logger, the outputs untouched. */
/* A VPL's area (its near field's patch) is its texel's footprint times the texels it stands
   for, so the patch leaves the texel's exitance: on a uniform RSM the areas sum to the lit
   area. An unlit texel, a footprint that is not > 0 and an RSM without areas give 0. */
static void areas_cover_the_lit_surface(void **state) {
    enum { S = 8, T = S * S, C = 24 };
    float pos[T * 3], nrm[T * 3], flux[T * 3], area[T], valid[T], p[C * 3], n[C * 3], f[C * 3], a[C];
    gim_rsm_data rsm;
    gim_rsm_vpls_desc d;
    double sum = 0.0, lit_area = 0.0;
    uint32_t t, i, unlit = 0;
    (void)state;
    for (t = 0; t < T; ++t) {
        pos[t * 3] = (float)(t % S); pos[t * 3 + 1] = (float)(t / S); pos[t * 3 + 2] = 0.0f;
        nrm[t * 3] = 0.0f; nrm[t * 3 + 1] = 0.0f; nrm[t * 3 + 2] = 1.0f;
        flux[t * 3] = flux[t * 3 + 1] = flux[t * 3 + 2] = 0.25f;
        area[t] = 0.5f;
        valid[t] = t % 3 == 1 ? 0.0f : 1.0f;
        if (valid[t] > 0.0f) lit_area += area[t];
    }
    memset(&rsm, 0, sizeof rsm);
    rsm.position = pos; rsm.normal = nrm; rsm.flux = flux; rsm.area = area; rsm.valid = valid; rsm.width = rsm.height = S;
    memset(&d, 0, sizeof d);
    d.rsm = &rsm; d.count = C; d.sequence = GIM_VPL_SEQUENCE_HALTON;
    assert_int_equal(gim_rsm_vpls_twin(&d, p, n, f, a), GIM_OK);
    for (i = 0; i < C; ++i) {
        sum += a[i];
        if (f[i * 3] == 0.0f) { assert_true(a[i] == 0.0f); ++unlit; }
    }
    assert_true(unlit > 0 && unlit < C);
    print_message("areas: %.6f, lit area %.6f\n", sum, lit_area);
    assert_true(fabs(sum - lit_area) <= 1e-6 * lit_area);
    area[5] = -1.0f; area[6] = NAN;   /* not > 0: a point */
    rsm.area = area;
    assert_int_equal(gim_rsm_vpls_twin(&d, p, n, f, a), GIM_OK);
    for (i = 0; i < C; ++i) assert_true(a[i] >= 0.0f && isfinite(a[i]));
    rsm.area = NULL;
    assert_int_equal(gim_rsm_vpls_twin(&d, p, n, f, a), GIM_OK);
    for (i = 0; i < C; ++i) assert_true(a[i] == 0.0f);
}

static void bad_arguments(void **state) {
    static const float bad_off[3][2] = {{1.0f, 0.0f}, {0.0f, -0.1f}, {NAN, 0.5f}};
    float p[N * 3], n[N * 3], f[N * 3];
    gim_rsm_data d;
    test_log log;
    int k;
    gim_env env = test_env(NULL, &log);
    (void)state;
    make_rsm(&g_rsm);
    for (k = 0; k < N * 3; ++k) p[k] = n[k] = f[k] = -5.0f;
    assert_int_equal(vpls_of(NULL, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, NULL, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, NULL, f, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, NULL, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(vpls_of(&g_rsm.rsm, 0, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    for (k = 0; k < 3; ++k)
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, bad_off[k], p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    d = g_rsm.rsm; d.width = 0;
    assert_int_equal(vpls_of(&d, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    d = g_rsm.rsm; d.flux = NULL;
    assert_int_equal(vpls_of(&d, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    d = g_rsm.rsm; d.position = NULL;
    assert_int_equal(vpls_of(&d, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_INVALID_ARGUMENT);
    /* a total beyond FLT_MAX */
    g_rsm.flux[0] = g_rsm.flux[3] = 3e38f; g_rsm.valid[0] = g_rsm.valid[1] = 1.0f;
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(log.errors, 12);
    assert_int_equal(gim_rsm_vpls_twin(NULL, p, n, f, NULL), GIM_ERROR_INVALID_ARGUMENT); /* no env to log through */
    for (k = 0; k < N * 3; ++k) assert_true(p[k] == -5.0f && n[k] == -5.0f && f[k] == -5.0f);
}

/* SSVP's first bounce (eq. 1): Hammersley point i of N is ((i + 0.5) / N, radical inverse of
   i in base 2); the same flux normalisation as the Halton VPLs. */
static void hammersley_placement(void **state) {
    static const float off[2] = {0.3f, 0.77f};
    int pass, i, c;
    gim_env env = test_env(NULL, NULL);
    double total[3], sum[3];
    (void)state;
    make_rsm(&g_rsm);
    total_flux(&g_rsm, total);
    for (pass = 0; pass < 2; ++pass) {
        const float *o = pass ? off : NULL;
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HAMMERSLEY, o, g_p, g_n, g_f, env), GIM_OK);
        sum[0] = sum[1] = sum[2] = 0.0;
        for (i = 0; i < N; ++i) {
            float u = (float)((i + 0.5) / N), v = (float)gim_van_der_corput((uint32_t)i);
            if (o) { u = gim_rotate01(u, o[0]); v = gim_rotate01(v, o[1]); }
            assert_true(g_p[i * 3] == (float)floor((double)u * W) + 0.5f);
            assert_true(g_p[i * 3 + 1] == (float)floor((double)v * H) + 0.5f);
            for (c = 0; c < 3; ++c) sum[c] += g_f[i * 3 + c];
        }
        for (c = 0; c < 3; ++c) assert_true(fabs(sum[c] - total[c]) <= 1e-5 * total[c]);
    }
    /* the first two points unrotated: (0.5 / N, 0) and (1.5 / N, 1/2) */
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HAMMERSLEY, NULL, g_p, g_n, g_f, env), GIM_OK);
    assert_true(g_p[0] == 0.5f && g_p[1] == 0.5f);
    assert_true(g_p[4] == (float)(H / 2) + 0.5f);
    /* DEFAULT is HALTON */
    {
        static float p2[N * 3], n2[N * 3], f2[N * 3];
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, off, g_p, g_n, g_f, env), GIM_OK);
        assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_DEFAULT, off, p2, n2, f2, env), GIM_OK);
        assert_memory_equal(g_p, p2, sizeof p2);
        assert_memory_equal(g_f, f2, sizeof f2);
    }
    assert_int_equal(vpls_of(&g_rsm.rsm, N, (gim_vpl_sequence)7, NULL, g_p, g_n, g_f, env),
                     GIM_ERROR_INVALID_ARGUMENT);
}

/* gim_cluster_paraboloids_twin: a k x k grid of VPLs filling a square of side a on a tilted plane
   has the side of its uniform rectangle, a sqrt(1 - 1/k^2); the size does not change when the
   square turns in its plane; flux sums; the origin is lifted along the normal; near is half
   the side; a cluster of one VPL is a point; bad input fails. */
static void cluster_paraboloids(void **state) {
    enum { K = 12, NV = K * K + 1 };
    static gim_vpl v[NV];
    static uint32_t cl[NV];
    gim_env env = test_env(NULL, NULL);
    gim_vec3 n = gim_v3_normalize(gim_v3(0.3f, 0.8f, -0.5f)), t, b;
    float centres[6], normals[6];
    gim_paraboloid out[2];
    double a = 0.6, expect = a * sqrt(1.0 - 1.0 / (K * K)), sizes[2];
    int turn, i, j;
    (void)state;
    gim__basis(n, &t, &b);
    for (turn = 0; turn < 2; ++turn) {
        double ang = turn ? 0.7 : 0.0, ca = cos(ang), sa = sin(ang);
        for (i = 0; i < K; ++i)
            for (j = 0; j < K; ++j) {
                gim_vpl *p = &v[i * K + j];
                double s0 = ((i + 0.5) / K - 0.5) * a, t0 = ((j + 0.5) / K - 0.5) * a;
                double s1 = ca * s0 - sa * t0, t1 = sa * s0 + ca * t0;
                memset(p, 0, sizeof *p);
                p->position[0] = (float)(2.0 + s1 * t.x + t1 * b.x);
                p->position[1] = (float)(-1.0 + s1 * t.y + t1 * b.y);
                p->position[2] = (float)(5.0 + s1 * t.z + t1 * b.z);
                p->normal[0] = n.x; p->normal[1] = n.y; p->normal[2] = n.z;
                p->flux[0] = 1.0f; p->flux[1] = 2.0f; p->flux[2] = 0.5f;
                p->lit = 1.0f;
                cl[i * K + j] = 0;
            }
        memset(&v[NV - 1], 0, sizeof v[0]);   /* one lone VPL in cluster 1 */
        v[NV - 1].position[0] = 9.0f; v[NV - 1].normal[1] = 1.0f; v[NV - 1].flux[0] = 3.0f; v[NV - 1].lit = 1.0f;
        cl[NV - 1] = 1;
        centres[0] = 2.0f; centres[1] = -1.0f; centres[2] = 5.0f;
        centres[3] = 9.0f; centres[4] = 0.0f; centres[5] = 0.0f;
        normals[0] = n.x; normals[1] = n.y; normals[2] = n.z;
        normals[3] = 0.0f; normals[4] = 2.0f; normals[5] = 0.0f;   /* renormalised */
        assert_int_equal(paraboloids_of(v, NV, cl, centres, normals, 2, 10.0f, out, env), GIM_OK);
        sizes[turn] = out[0].size;
        assert_true(fabs(out[0].size - expect) < 1e-4 * expect);
        assert_true(fabs(out[0].flux[0] - K * K) < 1e-3 && fabs(out[0].flux[1] - 2 * K * K) < 1e-3);
        assert_true(fabs(out[0].near_distance - 0.5 * out[0].size) < 1e-6);
        /* min(1e-2 scene scales, near_distance): 0.1 for the big one, the lone VPL's lift */
        assert_true(fabs(out[0].attribute_near - 0.1) < 1e-7 && out[0].near_distance > 0.1f);
        assert_true(out[1].attribute_near == out[1].near_distance);
        assert_true(fabs(out[0].origin[0] - (2.0 + 1e-3 * n.x)) < 1e-5);
        assert_true(fabs(out[0].origin[2] - (5.0 + 1e-3 * n.z)) < 1e-5);
        assert_true(out[1].size == 0.0f && out[1].flux[0] == 3.0f && out[1].normal[1] == 1.0f);
        assert_true(fabs(out[1].near_distance - 1e-3) < 1e-9 && fabs(out[1].origin[1] - 1e-3) < 1e-9);
    }
    assert_true(fabs(sizes[0] - sizes[1]) < 1e-5 * sizes[0]);
    /* bad input */
    cl[3] = 2;
    assert_int_equal(paraboloids_of(v, NV, cl, centres, normals, 2, 10.0f, out, env), GIM_ERROR_INVALID_ARGUMENT);
    cl[3] = 0;
    assert_int_equal(paraboloids_of(v, NV, cl, centres, normals, 2, 0.0f, out, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(paraboloids_of(NULL, NV, cl, centres, normals, 2, 1.0f, out, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cluster_paraboloids_twin(NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    normals[4] = 0.0f;
    assert_int_equal(paraboloids_of(v, NV, cl, centres, normals, 2, 1.0f, out, env), GIM_ERROR_INVALID_ARGUMENT);
    normals[4] = 1.0f;
    v[5].flux[1] = -1.0f;
    assert_int_equal(paraboloids_of(v, NV, cl, centres, normals, 2, 1.0f, out, env), GIM_ERROR_INVALID_ARGUMENT);
}

/* Incremental instant radiosity (gim_rsm_vpls_desc.previous; Laine et al. 2007) on make_rsm's
   RSM, seen by the camera that puts texel (x, y)'s point at its centre: the last frame's VPLs on
   the same RSM are all kept where lit, and the result is the VPLs drawn anew bit for bit; moved
   by 0.3 texel they are kept with their own positions and the same flux; one that was dark, not
   finite, turned away (normal), hidden (the texel sees a point 5 texels off) or a texel past its
   radius is drawn anew at its texel. A camera that is not finite is refused. */
static void follow_previous(void **state) {
    static float p[N * 3], n[N * 3], f[N * 3], p2[N * 3], n2[N * 3], f2[N * 3];
    static gim_vpl prev[N];
    static unsigned char kept[N];
    gim_rsm_vpls_desc d;
    test_log log;
    gim_env env = test_env(NULL, &log);
    uint32_t i, lit = 0, k;
    (void)state;
    make_rsm(&g_rsm);
    assert_int_equal(vpls_of(&g_rsm.rsm, N, GIM_VPL_SEQUENCE_HALTON, NULL, p, n, f, env), GIM_OK);
    for (i = 0; i < N; ++i) {
        memcpy(prev[i].position, p + i * 3, 12);
        memcpy(prev[i].normal, n + i * 3, 12);
        memcpy(prev[i].flux, f + i * 3, 12);
        prev[i].lit = f[i * 3] > 0.0f || f[i * 3 + 1] > 0.0f ? 1.0f : 0.0f;
        prev[i].area = 0.0f;
        prev[i].kept = 0.0f;
        lit += prev[i].lit == 1.0f;
    }
    memset(&d, 0, sizeof d);
    d.rsm = &g_rsm.rsm; d.count = N; d.sequence = GIM_VPL_SEQUENCE_HALTON; d.env = env;
    d.previous = prev; d.kept = kept;
    d.view_proj = gim_mat4_identity();
    d.view_proj.m[0] = 2.0f / W; d.view_proj.m[5] = 2.0f / H; d.view_proj.m[12] = -1.0f; d.view_proj.m[13] = -1.0f;
    assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_OK);
    for (i = 0, k = 0; i < N; ++i) k += kept[i];
    assert_int_equal(k, lit);
    assert_true(lit > N / 2u && lit < N);
    assert_memory_equal(p, p2, sizeof p);
    assert_memory_equal(n, n2, sizeof n);
    assert_memory_equal(f, f2, sizeof f);
    /* moved 0.3 texel, and the five ways to drop one */
    for (i = 0; i < N; ++i) prev[i].position[0] += 0.3f;
    prev[0].lit = 0.0f;
    prev[1].position[1] = NAN;
    prev[2].normal[1] = -0.6f; prev[2].normal[2] = -0.8f;
    assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_OK);
    for (i = 0; i < N; ++i) {
        int want = prev[i].lit == 1.0f && i > 2u;
        assert_int_equal(kept[i], want);
        if (want) assert_memory_equal(p2 + i * 3, prev[i].position, 12);
        else assert_memory_equal(p2 + i * 3, p + i * 3, 12);
        assert_true(f2[i * 3 + 1] == f[i * 3 + 1] || (i <= 2u && prev[i].lit == 1.0f));   /* same texels but three */
    }
    {   /* hidden: its texel sees a point 5 texels nearer the light; past its radius (0.4-0.8 texel
           here): one texel on, where the texel sees a point 0.3 texel from it */
        uint32_t a = 3, b, t;
        float z;
        while (prev[a].lit != 1.0f) ++a;
        b = a + 1u;
        while (prev[b].lit != 1.0f || prev[b].position[0] + 1.0f >= (float)W) ++b;
        t = (uint32_t)prev[a].position[1] * W + (uint32_t)prev[a].position[0];
        z = g_rsm.pos[t * 3 + 2];
        g_rsm.pos[t * 3 + 2] = z - 5.0f;
        prev[b].position[0] += 1.0f;
        assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_OK);
        assert_int_equal(kept[a], 0);
        assert_int_equal(kept[b], 0);
        prev[b].position[0] -= 2.0f;   /* the other way: the same */
        assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_OK);
        assert_int_equal(kept[b], 0);
        prev[b].position[0] += 1.0f;
        g_rsm.pos[t * 3 + 2] = z;
        assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_OK);
        assert_int_equal(kept[a], 1);
        assert_int_equal(kept[b], 1);
    }
    d.view_proj.m[5] = NAN;
    for (i = 0; i < N * 3; ++i) p2[i] = -5.0f;
    assert_int_equal(gim_rsm_vpls_twin(&d, p2, n2, f2, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(log.errors, 1);
    for (i = 0; i < N * 3; ++i) assert_true(p2[i] == -5.0f);
}

/* gim_vpls_from_vals (vpl.importance): picks of a known pdf (proportional to the green flux
   plus a floor, so every lit texel can be drawn, and the unlit texels too) through
   gim_vals_gather_twin make VPLs whose flux and area are the VAL's times its weight, bit for
   bit, lit 1 and kept 0 (kept 1 where the slot's last VPL stood at the same point), an invalid
   texel's all zero; the sum of their flux estimates the lit
   total without bias (the mean over 400 draws of 64 within 1.5% per channel, where the same
   VPLs weighted 1 / P instead of 1 / (N P) are 64x off) and the areas the lit area. */
static void vpls_from_importance_picks(void **state) {
    enum { PICKS = 64, DRAWS = 400 };
    static double cdf[W * H];
    static gim_selected_val sel[PICKS];
    static gim_val vals[PICKS];
    static gim_vpl vpls[PICKS];
    double tot[3], mean[3] = {0.0, 0.0, 0.0}, area = 0.0, lit_area = 0.0, sum = 0.0;
    int t, i, a, draw, unlit_seen = 0;
    test_log log;
    gim_env env = test_env(NULL, &log);
    (void)state;
    make_rsm(&g_rsm);
    total_flux(&g_rsm, tot);
    for (t = 0; t < W * H; ++t) {
        sum += g_rsm.flux[t * 3 + 1] + 0.2;
        cdf[t] = sum;
        if (g_rsm.valid[t] > 0.0f) lit_area += g_rsm.area[t];
    }
    for (draw = 0; draw < DRAWS; ++draw) {
        for (i = 0; i < PICKS; ++i) {
            double u = test_rand01() * sum;
            int lo = 0, hi = W * H - 1;
            while (lo < hi) {
                int mid = (lo + hi) / 2;
                if (cdf[mid] > u) hi = mid; else lo = mid + 1;
            }
            sel[i].x = (uint32_t)(lo % W);
            sel[i].y = (uint32_t)(lo / W);
            sel[i].pdf = (float)((g_rsm.flux[lo * 3 + 1] + 0.2) / sum);
        }
        assert_int_equal(gim_vals_gather_twin(&g_rsm.rsm, sel, PICKS, vals, env), GIM_OK);
        assert_int_equal(gim_vpls_from_vals(vals, PICKS, NULL, vpls, env), GIM_OK);
        for (i = 0; i < PICKS; ++i) {
            const gim_val *v = vals + i;
            const gim_vpl *p = vpls + i;
            if (v->weight == 0.0f) {   /* an unlit texel: nothing */
                static const gim_vpl zero;
                assert_memory_equal(p, &zero, sizeof zero);
                ++unlit_seen;
                continue;
            }
            assert_true(p->lit == 1.0f && p->kept == 0.0f);
            assert_memory_equal(p->position, v->position, 12);
            assert_memory_equal(p->normal, v->normal, 12);
            assert_true(p->area == v->area * v->weight);
            for (a = 0; a < 3; ++a) {
                assert_true(p->flux[a] == v->flux[a] * v->weight);
                mean[a] += p->flux[a] / DRAWS;
            }
            area += p->area / DRAWS;
        }
    }
    assert_true(unlit_seen > 0);
    for (a = 0; a < 3; ++a) assert_true(fabs(mean[a] / tot[a] - 1.0) < 0.015);
    assert_true(fabs(area / lit_area - 1.0) < 0.015);
    assert_int_equal(log.errors, 0);
    {   /* kept: the slot's last VPL lit at the same point and normal; moved by an ulp, turned, or unlit: not */
        static gim_vpl prev[PICKS], again[PICKS];
        int lit_kept = 0;
        memcpy(prev, vpls, sizeof prev);
        prev[1].position[2] = nextafterf(prev[1].position[2], 1e30f);
        prev[2].normal[0] = nextafterf(prev[2].normal[0], 1e30f);
        prev[3].lit = 0.0f;
        prev[4].flux[0] *= 2.0f;   /* another light's power: the point and its map stay */
        assert_int_equal(gim_vpls_from_vals(vals, PICKS, prev, again, env), GIM_OK);
        for (i = 0; i < PICKS; ++i) {
            int want = vpls[i].lit == 1.0f && i != 1 && i != 2 && i != 3;
            assert_true(again[i].kept == (want ? 1.0f : 0.0f));
            lit_kept += want;
            again[i].kept = 0.0f;
            assert_memory_equal(again + i, vpls + i, sizeof *vpls);   /* nothing else changes */
        }
        assert_true(lit_kept > PICKS / 2);
    }
    /* bad arguments: one line each, out untouched */
    memset(vpls, 0x5a, sizeof vpls);
    assert_int_equal(gim_vpls_from_vals(NULL, 1, NULL, vpls, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_vpls_from_vals(vals, 1, NULL, NULL, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_vpls_from_vals(vals, 2, NULL, (gim_vpl *)(void *)vals, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_vpls_from_vals(vals, 2, vpls, vpls, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(log.errors, 4);
    assert_int_equal(gim_vpls_from_vals(NULL, 0, NULL, NULL, env), GIM_OK);
    for (i = 0; i < (int)sizeof vpls; ++i) assert_int_equal(((unsigned char *)vpls)[i], 0x5a);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(flux_sums_to_the_total),
        cmocka_unit_test(halton_placement),
        cmocka_unit_test(hammersley_placement),
        cmocka_unit_test(cluster_paraboloids),
        cmocka_unit_test(unlit_texels),
        cmocka_unit_test(units),
        cmocka_unit_test(bad_arguments),
        cmocka_unit_test(areas_cover_the_lit_surface),
        cmocka_unit_test(follow_previous),
        cmocka_unit_test(vpls_from_importance_picks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
