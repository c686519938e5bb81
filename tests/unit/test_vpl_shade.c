/* VPL shading of the clustered-visibility and SSVP methods (Dong et al. sec. 4-6; Krivanek's
   clamping): gim_paraboloid_visibility_twin (PCSS on a paraboloid map), gim_vpl_shade_twin (a VPL
   against the closed form, clamping, interleaved sampling, visibility per cluster) and
   gim_geometry_blur_twin; bad input, leaks and out-of-memory. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"
#include "vplshade_util.h"

/* A receiver at p with normal n looking from view. */
static gim_receiver rec(gim_vec3 p, gim_vec3 n, gim_vec3 view) {
    gim_receiver r;
    memset(&r, 0, sizeof r);
    r.position[0] = p.x; r.position[1] = p.y; r.position[2] = p.z;
    n = gim_v3_normalize(n); view = gim_v3_normalize(view);
    r.normal[0] = n.x; r.normal[1] = n.y; r.normal[2] = n.z;
    r.view[0] = view.x; r.view[1] = view.y; r.view[2] = view.z;
    r.albedo[0] = 0.5f; r.albedo[1] = 0.25f; r.albedo[2] = 0.75f;
    r.glossy[0] = 0.2f; r.glossy[1] = 0.3f; r.glossy[2] = 0.1f;
    r.exponent = 10.0f;
    return r;
}

static gim_vpl vpl(gim_vec3 p, gim_vec3 n, float r, float g, float b) {
    gim_vpl v;
    memset(&v, 0, sizeof v);
    n = gim_v3_normalize(n);
    v.position[0] = p.x; v.position[1] = p.y; v.position[2] = p.z; v.lit = 1.0f;
    v.normal[0] = n.x; v.normal[1] = n.y; v.normal[2] = n.z;
    v.flux[0] = r; v.flux[1] = g; v.flux[2] = b;
    return v;
}

/* L of one VPL at a receiver, in double (gimany.h "twins of the VPL methods"). */
static void closed_form(const gim_vpl *v, const gim_receiver *r, double dc, double out[3]) {
    double w[3], d2 = 0.0, d, cl = 0.0, cx = 0.0, re = 0.0, e;
    int a;
    for (a = 0; a < 3; ++a) { w[a] = (double)r->position[a] - v->position[a]; d2 += w[a] * w[a]; }
    d = sqrt(d2);
    for (a = 0; a < 3; ++a) { w[a] /= d; cl += v->normal[a] * w[a]; cx -= r->normal[a] * w[a]; }
    for (a = 0; a < 3; ++a) re += (2.0 * cx * r->normal[a] + w[a]) * r->view[a];
    e = (cl > 0 ? cl : 0) * (cx > 0 ? cx : 0) / (GIM__PI * (d2 > dc * dc ? d2 : dc * dc));
    for (a = 0; a < 3; ++a)
        out[a] = v->flux[a] * e * (r->albedo[a] / GIM__PI + r->glossy[a] * (r->exponent + 2.0) / (2.0 * GIM__PI) *
                                   (re > 0 ? pow(re, r->exponent) : 0.0));
}

static gim_vpl_shade_desc shade_desc(const gim_vpl *v, uint32_t n, const gim_receiver *r, uint32_t w, uint32_t h,
                                     gim_env env) {
    gim_vpl_shade_desc d;
    memset(&d, 0, sizeof d);
    d.vpls = v; d.vpl_count = n; d.receivers = r; d.width = w; d.height = h; d.scene_scale = 1.0f; d.env = env;
    return d;
}

/* One VPL: the closed form at receivers around it, in metres and in kilometres (unit-free:
   a length unit 1000 times bigger divides the radiance of the same flux by 1e6). */
static void single_vpl_closed_form(void **state) {
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_vpl v = vpl(gim_v3(0.1f, -0.2f, 0.3f), gim_v3(0.2f, 0.1f, 1.0f), 1.0f, 2.0f, 3.0f), vk = v;
    gim_receiver r[8], rk[8];
    float out[24], outk[24];
    int i, a;
    (void)state;
    for (i = 0; i < 8; ++i) {
        r[i] = rec(gim_v3(test_rnd(-1, 1), test_rnd(-1, 1), test_rnd(1.0f, 3.0f)),
                   gim_v3(test_rnd(-0.5f, 0.5f), test_rnd(-0.5f, 0.5f), -1.0f), gim_v3(test_rnd(-1, 1), 0.3f, -1.0f));
        rk[i] = r[i];
        for (a = 0; a < 3; ++a) rk[i].position[a] = r[i].position[a] * 1e3f;
    }
    for (a = 0; a < 3; ++a) vk.position[a] = v.position[a] * 1e3f;
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 4, 2, env), dk = shade_desc(&vk, 1, rk, 4, 2, env);
        dk.scene_scale = 1e3f;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        assert_int_equal(gim_vpl_shade_twin(&dk, outk), GIM_OK);
    }
    for (i = 0; i < 8; ++i) {
        double ref[3];
        closed_form(&v, &r[i], 0.0, ref);
        for (a = 0; a < 3; ++a) {
            assert_true(ref[a] > 0.0);
            assert_true(fabs(out[i * 3 + a] - ref[a]) <= 1e-5 * ref[a]);
            assert_true(fabs(outk[i * 3 + a] * 1e6 - ref[a]) <= 1e-4 * ref[a]);
        }
    }
    /* behind the VPL, behind the receiver, unlit: dark */
    r[0] = rec(gim_v3(0, 0, -1), gim_v3(0, 0, 1), gim_v3(0, 0, 1));       /* below the VPL's plane */
    r[1] = rec(gim_v3(0, 0, 2), gim_v3(0, 0, 1), gim_v3(0, 0, 1));        /* faces away */
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 2, 1, env);
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        for (a = 0; a < 6; ++a) assert_true(out[a] == 0.0f);
        v.lit = 0.0f;
        r[0] = rec(gim_v3(0, 0, 2), gim_v3(0, 0, -1), gim_v3(0, 0, 1));
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        for (a = 0; a < 6; ++a) assert_true(out[a] == 0.0f);
    }
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
}

/* Clamping (Krivanek): no change beyond d_c; below it the 1/d^2 becomes 1/d_c^2, and the
   energy removed is exactly that (the ratio d^2 / d_c^2). */
static void clamping_bites_below_dc(void **state) {
    gim_env env = test_env(NULL, NULL);
    gim_vpl v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1.0f, 1.0f, 1.0f);
    gim_receiver r[16];
    float un[48], cl[48];
    const float dc = 0.5f;
    int i, a;
    double lost = 0.0, total = 0.0;
    (void)state;
    for (i = 0; i < 16; ++i) r[i] = rec(gim_v3(0.0f, 0.0f, 0.05f + 0.06f * (float)i), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 16, 1, env);
        assert_int_equal(gim_vpl_shade_twin(&d, un), GIM_OK);
        d.clamp_distance = dc;
        assert_int_equal(gim_vpl_shade_twin(&d, cl), GIM_OK);
    }
    for (i = 0; i < 16; ++i) {
        double z = r[i].position[2];
        for (a = 0; a < 3; ++a) {
            if (z >= dc) assert_true(cl[i * 3 + a] == un[i * 3 + a]);
            else assert_true(fabs(cl[i * 3 + a] / un[i * 3 + a] - z * z / (dc * dc)) < 1e-5);
        }
        total += un[i * 3];
        lost += un[i * 3] - cl[i * 3];
    }
    print_message("clamping at d_c = %.2f removes %.1f %% of the energy along the axis\n", (double)dc, 100.0 * lost / total);
    assert_true(lost > 0.0 && lost < total);
}

/* Interleaved sampling: k = 1 is every VPL; with k = 2 the four pixels of a block take
   disjoint quarters scaled by 4, so on one receiver point their mean is the full sum. */
static void interleave_block_mean_is_full_sum(void **state) {
    enum { N = 64, W = 6, H = 4 };
    gim_env env = test_env(NULL, NULL);
    gim_vpl v[N];
    gim_receiver r[W * H];
    float full[W * H * 3], k1[W * H * 3], k2[W * H * 3];
    int i, a, bx, by;
    (void)state;
    for (i = 0; i < N; ++i)
        v[i] = vpl(gim_v3(test_rnd(-2, 2), test_rnd(-2, 2), 0.0f), gim_v3(test_rnd(-.3f, .3f), test_rnd(-.3f, .3f), 1.0f),
                   test_rnd(0, 1), test_rnd(0, 1), test_rnd(0, 1));
    v[5].lit = 0.0f;   /* an unlit one counts in its subset's n_s but adds nothing */
    for (i = 0; i < W * H; ++i) r[i] = rec(gim_v3(0.2f, 0.1f, 1.5f), gim_v3(0.1f, 0, -1), gim_v3(0.3f, 0.2f, -1));
    {
        gim_vpl_shade_desc d = shade_desc(v, N, r, W, H, env);
        assert_int_equal(gim_vpl_shade_twin(&d, full), GIM_OK);
        d.interleave = 1;
        assert_int_equal(gim_vpl_shade_twin(&d, k1), GIM_OK);
        d.interleave = 2;
        assert_int_equal(gim_vpl_shade_twin(&d, k2), GIM_OK);
    }
    assert_memory_equal(full, k1, sizeof full);
    for (by = 0; by < H; by += 2)
        for (bx = 0; bx < W; bx += 2)
            for (a = 0; a < 3; ++a) {
                double m = 0.25 * (k2[(by * W + bx) * 3 + a] + k2[(by * W + bx + 1) * 3 + a] +
                                   k2[((by + 1) * W + bx) * 3 + a] + k2[((by + 1) * W + bx + 1) * 3 + a]);
                double f = full[(by * W + bx) * 3 + a];
                assert_true(f > 0.0);
                assert_true(fabs(m - f) <= 1e-5 * f);
                /* and the subsets differ (the pixel is not the full sum itself) */
                assert_true(fabs(k2[(by * W + bx) * 3 + a] - f) > 1e-3 * f);
            }
}

static gim_paraboloid test_map(float size) {
    gim_paraboloid m;
    gim_vec3 n = gim_v3_normalize(gim_v3(0.3f, -0.2f, 1.0f));
    memset(&m, 0, sizeof m);
    m.origin[0] = 1.0f; m.origin[1] = 2.0f; m.origin[2] = -0.5f;
    m.normal[0] = n.x; m.normal[1] = n.y; m.normal[2] = n.z;
    m.size = size;
    m.near_distance = size / 2;
    return m;
}

/* Visibility: 1 with an empty map and behind the plane; 0 deep under a big plate; fractional
   in its penumbra and monotone as the receiver moves out; a bigger VAL (Delta) gives a wider
   penumbra. */
static void visibility_umbra_penumbra(void **state) {
    enum { S = 128 };
    static float dist[S * S];
    gim_paraboloid m = test_map(0.4f);
    float v, prev = 0.0f;
    int i, frac = 0, frac_big = 0, drops = 0;
    (void)state;
    vs_plate_map(dist, S, 1.0f, 0.0f, 0.0f, 10.0f);
    for (i = 0; i < S * S; ++i) dist[i] = GIM_PARABOLOID_EMPTY;
    assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, 0.3f, 0.2f, 2.0f), NULL, &v), GIM_OK);
    assert_true(v == 1.0f);
    /* a plate at height 1, 2 x 2: under its centre at height 2 every tap is blocked */
    vs_plate_map(dist, S, 1.0f, 0.0f, 0.0f, 1.0f);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, 0.0f, 0.0f, 2.0f), NULL, &v), GIM_OK);
    assert_true(v == 0.0f);
    /* between the VAL and the plate: lit */
    assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, 0.1f, 0.0f, 0.7f), NULL, &v), GIM_OK);
    assert_true(v == 1.0f);
    /* behind the VAL's plane: 1 whatever the map */
    assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, 0.0f, 0.0f, -2.0f), NULL, &v), GIM_OK);
    assert_true(v == 1.0f);
    /* out of the shadow along t at height 2: the shadow of the plate's edge (x = 1 at h = 1)
       from the VAL's centre is at x = 2, the exact penumbra [2 - Delta / 2, 2 + Delta / 2]
       (VAL of side Delta); PCSS's z_avg (a mean over the plate, nearer than its edge) widens
       it: the big VAL's reaches x = 3.3 */
    for (i = 0; i <= 60; ++i) {
        float x = 1.0f + 3.5f * (float)i / 60.0f, vb;
        gim_paraboloid big = test_map(1.2f);
        assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, x, 0.05f, 2.0f), NULL, &v), GIM_OK);
        assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &big, vs_local(&big, x, 0.05f, 2.0f), NULL, &vb), GIM_OK);
        if (v > 0.0f && v < 1.0f) ++frac;
        if (vb > 0.0f && vb < 1.0f) ++frac_big;
        if (v < prev) ++drops;
        if (i == 0) assert_true(v == 0.0f);
        if (i == 60) assert_true(v == 1.0f && vb == 1.0f);
        prev = v;
    }
    print_message("penumbra: %d of 61 receivers fractional (Delta 0.4), %d (Delta 1.2); %d drops moving out\n", frac,
                  frac_big, drops);
    assert_int_equal(drops, 0);
    assert_true(frac >= 3);
    assert_true(frac_big > frac);
}

/* The exact from-area visibility of a square VAL of side D (in its plane, centred on the
   origin of the map's frame) at local x = (a, b, c) behind a plate at height h: the fraction
   of 64 x 64 points of the VAL whose segment to x misses the plate. */
static double exact_visibility(double D, double h, double cx, double cy, double half, double a, double b, double c) {
    int i, j, n = 64, vis = 0;
    for (i = 0; i < n; ++i)
        for (j = 0; j < n; ++j) {
            double px = D * ((i + 0.5) / n - 0.5), py = D * ((j + 0.5) / n - 0.5), t = h / c;
            double qx = px + (a - px) * t, qy = py + (b - py) * t;
            if (!(c > h && fabs(qx - cx) <= half && fabs(qy - cy) <= half)) ++vis;
        }
    return (double)vis / (n * n);
}

/* PCSS against the exact visibility of random plates, VALs and receivers (up to ~70 degrees
   off the VAL's axis): the soft shadow is an approximation (Dong sec. 4.2.1), close on
   average and never wrong by much in the mean. */
static void visibility_near_exact(void **state) {
    enum { S = 128 };
    static float dist[S * S];
    gim_paraboloid m = test_map(0.5f);
    double err = 0.0, signed_err = 0.0;
    int trial, n = 0, pen = 0;
    (void)state;
    test_rng_state = 0xab5u;   /* its own cases, whatever ran before */
    for (trial = 0; trial < 1500; ++trial) {
        double D = test_rnd(0.05f, 1.0f), h = test_rnd(0.2f, 1.0f), half = test_rnd(0.1f, 0.6f);
        double cx = test_rnd(-0.3f, 0.3f), cy = test_rnd(-0.3f, 0.3f), c = h + test_rnd(0.2f, 2.0f);
        double a = test_rnd(-2.5f, 2.5f), b = test_rnd(-2.5f, 2.5f), ex;
        float v;
        m.size = (float)D;
        vs_plate_map(dist, S, (float)h, (float)cx, (float)cy, (float)half);
        ex = exact_visibility(D, h, cx, cy, half, a, b, c);
        assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, (float)a, (float)b, (float)c), NULL, &v), GIM_OK);
        assert_true(v >= 0.0f && v <= 1.0f);
        if (ex > 0.999 && v > 0.999f) continue;   /* far from any shadow */
        ++n;
        if (ex > 0.001 && ex < 0.999) ++pen;
        err += fabs(v - ex);
        signed_err += v - ex;
    }
    print_message("PCSS against exact from-area visibility: %d receivers near a shadow (%d in a penumbra), mean |V - exact| "
                  "%.4f, mean signed %.4f\n", n, pen, err / n, signed_err / n);
    assert_true(n > 200 && pen > 100);
    assert_true(err / n < 0.055);   /* Dong's unforeshortened Delta: 0.058 here */
    assert_true(fabs(signed_err / n) < 0.03);
}

/* Unit-free: the same plate, VAL and receivers in millimetres and kilometres (and moved off
   the origin) give the same visibility (a receiver on a texel edge may flip one tap). */
static void visibility_unit_free(void **state) {
    enum { S = 96 };
    static float dist[S * S], dist_s[S * S];
    static const float scales[2] = {1e-3f, 1e3f};
    int si, i, j, differ = 0, total = 0;
    (void)state;
    vs_plate_map(dist, S, 1.0f, 0.1f, -0.2f, 0.8f);
    for (si = 0; si < 2; ++si) {
        float k = scales[si];
        gim_paraboloid m = test_map(0.6f), ms = m;
        for (j = 0; j < 3; ++j) ms.origin[j] = m.origin[j] * k + 5.0f * k;
        ms.size = m.size * k;
        for (i = 0; i < S * S; ++i) dist_s[i] = dist[i] < GIM_PARABOLOID_EMPTY ? dist[i] * k : dist[i];
        for (i = 0; i < 200; ++i) {
            float a = test_rnd(-3, 3), b = test_rnd(-3, 3), c = test_rnd(0.2f, 3.0f), v, vs;
            assert_int_equal(gim_paraboloid_visibility_twin(dist, S, &m, vs_local(&m, a, b, c), NULL, &v), GIM_OK);
            assert_int_equal(gim_paraboloid_visibility_twin(dist_s, S, &ms, vs_local(&ms, a * k, b * k, c * k), NULL, &vs), GIM_OK);
            if (fabsf(v - vs) > 1.0f / 16.0f + 1e-6f) fail_msg("scale %g: V %g against %g", (double)k, (double)v, (double)vs);
            differ += v != vs;
            ++total;
        }
    }
    print_message("unit-free visibility: %d of %d receivers differ (by one tap) between metres and mm / km\n", differ, total);
    assert_true(differ <= total / 50);
}

/* The kernel's table is the declared Vogel disk. */
static void vogel_table(void **state) {
    int j;
    (void)state;
    for (j = 0; j < GIM__VIS_TAPS; ++j) {
        double r = sqrt((j + 0.5) / 16.0), p = j * GIM__PI * (3.0 - sqrt(5.0));
        assert_true(fabs(gim__vogel16[j][0] - r * cos(p)) < 1e-7 && fabs(gim__vogel16[j][1] - r * sin(p)) < 1e-7);
    }
}

/* Visibility in the shading: a receiver under the plate gets nothing from the clustered VPLs,
   everything from an unclustered one; the maps are per cluster (layer m for cluster m). */
static void shade_uses_cluster_visibility(void **state) {
    enum { S = 64 };
    static float dist[2 * S * S];
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_paraboloid maps[2];
    gim_vpl v[3];
    gim_receiver r[2];
    uint32_t cl[3] = {1, 1, UINT32_MAX};
    float out[6], ref[6];
    gim_vec3 p;
    int i;
    (void)state;
    maps[0] = test_map(0.3f);
    maps[1] = test_map(0.3f);
    for (i = 0; i < S * S; ++i) dist[i] = GIM_PARABOLOID_EMPTY;       /* map 0: nothing */
    vs_plate_map(dist + S * S, S, 1.0f, 0.0f, 0.0f, 1.0f);             /* map 1: the plate */
    p = vs_local(&maps[1], 0.0f, 0.0f, 0.0f);
    v[0] = vpl(p, gim_v3(maps[1].normal[0], maps[1].normal[1], maps[1].normal[2]), 1, 1, 1);
    v[1] = v[0]; v[2] = v[0];
    r[0] = rec(vs_local(&maps[1], 0.0f, 0.0f, 2.0f), gim_v3(-maps[1].normal[0], -maps[1].normal[1], -maps[1].normal[2]),
               gim_v3(0, 0, 1));
    r[1] = rec(vs_local(&maps[1], 2.5f, 0.0f, 2.0f), gim_v3(-maps[1].normal[0], -maps[1].normal[1], -maps[1].normal[2]),
               gim_v3(0, 0, 1));
    {
        gim_vpl_shade_desc d = shade_desc(v, 3, r, 2, 1, env);
        d.cluster = cl; d.maps = maps; d.map_count = 2; d.distance = dist; d.map_size = S;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        d.cluster = NULL;
        d.vpl_count = 1;
        assert_int_equal(gim_vpl_shade_twin(&d, ref), GIM_OK);   /* one unshadowed VPL */
        for (i = 0; i < 3; ++i) {
            assert_true(fabs(out[i] - ref[i]) <= 1e-6 * ref[i]);              /* under the plate: only v[2] */
            assert_true(fabs(out[3 + i] - 3.0f * ref[3 + i]) <= 1e-5 * ref[3 + i]); /* out of it: all three */
        }
        /* cluster 0 (the empty map) for all: unshadowed */
        cl[0] = cl[1] = 0;
        d.cluster = cl; d.vpl_count = 3;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        for (i = 0; i < 3; ++i) assert_true(fabs(out[i] - 3.0f * ref[i]) <= 1e-5 * ref[i]);
        /* out of memory for the per-map cache: an error, nothing leaked */
        st.fail_after = st.allocs;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_ERROR_OUT_OF_MEMORY);
        st.fail_after = -1;
    }
    assert_int_equal(lg.errors, 1);
    assert_int_equal(st.live, 0);
}

/* One imperfect shadow map per VPL (gim_vpl_shade_desc.ism): a plate z = 1 over [-1, 1]^2
   under a ceiling z = 2 hides the ceiling straight above a VPL at the origin and leaves it lit
   beside the plate, exactly as much as without visibility; the VPL's map of the points of both
   by gim_ism_render_twin. (Without the ceiling the map's pull-push fills the sky with the plate's
   depth: a receiver must lie on the scene the points sample.) */
static void shade_uses_vpl_ism(void **state) {
    enum { NPT = 4096, IS = 32 };
    static float pts[NPT * 8], ism[IS * IS];
    float pos[36] = {-1, -1, 1, 1, 1, 1, 1, -1, 1, -1, -1, 1, -1, 1, 1, 1, 1, 1,
                     -4, -4, 2, 4, 4, 2, 4, -4, 2, -4, -4, 2, -4, 4, 2, 4, 4, 2}, alb[12];
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_twin_scene ts;
    gim_cache c;
    gim_ism_desc id;
    gim_vpl v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1);
    gim_receiver r[2];
    float out[6], ref[6];
    int i;
    (void)state;
    for (i = 0; i < 12; ++i) alb[i] = 0.5f;
    ts.positions = pos; ts.normals = NULL; ts.albedo = alb; ts.triangle_count = 4;
    assert_int_equal(gim_ism_points(&ts, NPT, pts), GIM_OK);
    memset(&c, 0, sizeof c);
    c.normal[2] = 1.0f; c.area = 1.0f; c.reflectance = 0.5f;
    memset(&id, 0, sizeof id);
    id.caches = &c; id.cache_count = 1; id.points = pts; id.point_count = NPT; id.size = IS; id.splat = GIM_ISM_VPL_SPLAT; id.scene_scale = 4.0f;
    id.env = env;
    assert_int_equal(gim_ism_render_twin(&id, ism), GIM_OK);
    r[0] = rec(gim_v3(0, 0, 2), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    r[1] = rec(gim_v3(3, 0, 2), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 2, 1, env);
        d.scene_scale = 4.0f;
        assert_int_equal(gim_vpl_shade_twin(&d, ref), GIM_OK);
        d.ism = ism; d.ism_size = IS; d.ism_bias = GIM_ISM_VPL_BIAS; d.ism_slope = GIM_ISM_VPL_SLOPE;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        for (i = 0; i < 3; ++i) {
            assert_true(ref[i] > 0.0f && out[i] == 0.0f);   /* above the plate: shadowed */
            assert_true(ref[3 + i] > 0.0f && out[3 + i] == ref[3 + i]);
        }
        d.ism_size = 24;   /* refused: not a power of two */
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        d.ism_size = IS; d.ism_bias = 2.0f;
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        d.ism_bias = 0.0f;
        {   /* one visibility per VPL: the cluster's or its own map's, not both */
            uint32_t cl = 0;
            gim_paraboloid m = test_map(0.2f);
            float dist[4] = {1, 1, 1, 1};
            d.cluster = &cl; d.maps = &m; d.map_count = 1; d.distance = dist; d.map_size = 2;
            assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        }
    }
    assert_int_equal(lg.errors, 3);
    assert_int_equal(st.live, 0);
}

/* Blur: a constant image stays constant; a normal edge and a depth edge are not crossed;
   pixels without a surface are 0 and do not count. */
static void blur_keeps_edges(void **state) {
    enum { W = 12, H = 8 };
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_receiver r[W * H];
    float in[W * H * 3], out[W * H * 3];
    gim_blur_desc d;
    int x, y, a;
    (void)state;
    memset(&d, 0, sizeof d);
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int i = y * W + x;
            /* left: floor (normal +y); right half: wall (normal -x); top-right block far behind */
            if (x < 6) r[i] = rec(gim_v3(0.1f * x, 0.0f, 0.1f * y), gim_v3(0, 1, 0), gim_v3(0, 1, 1));
            else if (y < 4) r[i] = rec(gim_v3(0.6f, 0.1f * x, 0.1f * y), gim_v3(-1, 0, 0), gim_v3(-1, 0, 1));
            else r[i] = rec(gim_v3(5.6f, 0.1f * x, 0.1f * y), gim_v3(-1, 0, 0), gim_v3(-1, 0, 1));
            for (a = 0; a < 3; ++a) in[i * 3 + a] = 0.7f + 0.1f * a;
        }
    memset(r[0].normal, 0, sizeof r[0].normal);   /* no surface */
    d.radiance = in; d.receivers = r; d.width = W; d.height = H; d.window = 4; d.position_tolerance = 0.5f; d.env = env;
    assert_int_equal(gim_geometry_blur_twin(&d, out), GIM_OK);
    for (x = 0; x < W * H * 3; ++x) {
        if (x < 3) assert_true(out[x] == 0.0f);
        else assert_true(fabs(out[x] - in[x]) <= 1e-6f * in[x]);
    }
    /* three regions of different values: blurred, each keeps its own */
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int i = y * W + x;
            float base = x < 6 ? 1.0f : (y < 4 ? 10.0f : 100.0f);
            for (a = 0; a < 3; ++a) in[i * 3 + a] = base * (1.0f + 0.05f * (float)((x + y) % 3));
        }
    assert_int_equal(gim_geometry_blur_twin(&d, out), GIM_OK);
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int i = y * W + x;
            float base = x < 6 ? 1.0f : (y < 4 ? 10.0f : 100.0f);
            if (i == 0) continue;
            assert_true(out[i * 3] >= base * 0.999f && out[i * 3] <= base * 1.101f);
        }
    /* window 0: a copy */
    d.window = 0;
    assert_int_equal(gim_geometry_blur_twin(&d, out), GIM_OK);
    assert_memory_equal(out + 3, in + 3, (W * H - 1) * 3 * sizeof(float));
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
}

/* The blur averages light, not materials: a plane under uniform light, half of it albedo 0.2
   grey, half (0.8, 0.4, 0) (a channel with no albedo carries no light), one glossy pixel among
   them. Each diffuse pixel keeps its own albedo x the light however the window straddles the
   edge (blurring radiance gave 0.5 on both sides of it); the glossy one keeps its own
   radiance (no other glossy pixel in reach). */
static void blur_light_not_albedo(void **state) {
    enum { W = 16, H = 8 };
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_receiver r[W * H];
    float in[W * H * 3], out[W * H * 3];
    gim_blur_desc d;
    int x, y, a;
    (void)state;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int i = y * W + x;
            r[i] = rec(gim_v3(0.1f * x, 0.0f, 0.1f * y), gim_v3(0, 1, 0), gim_v3(0, 1, 1));
            memset(r[i].glossy, 0, sizeof r[i].glossy);
            for (a = 0; a < 3; ++a) r[i].albedo[a] = x < W / 2 ? 0.2f : (a == 0 ? 0.8f : a == 1 ? 0.4f : 0.0f);
            for (a = 0; a < 3; ++a) in[i * 3 + a] = r[i].albedo[a] * 1.5f;   /* albedo x the light */
        }
    r[3 * W + 4].glossy[1] = 0.5f;
    in[(3 * W + 4) * 3] = in[(3 * W + 4) * 3 + 1] = in[(3 * W + 4) * 3 + 2] = 5.0f;
    memset(&d, 0, sizeof d);
    d.radiance = in; d.receivers = r; d.width = W; d.height = H; d.window = 8; d.position_tolerance = 10.0f; d.env = env;
    assert_int_equal(gim_geometry_blur_twin(&d, out), GIM_OK);
    for (x = 0; x < W * H * 3; ++x) assert_true(fabs(out[x] - in[x]) <= 1e-5f);
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
}

/* Interleaved sampling then the blur (Dong sec. 6): on a smooth floor lit by VPLs on a wall,
   the k = 4 image is noisy (each pixel sees a sixteenth of the VPLs) and the 4 x 4 blur brings
   it back near the full sum; a window that does not hold every subset leaves more noise. */
static void blur_undoes_interleaving(void **state) {
    enum { N = 256, W = 32, H = 32 };
    gim_env env = test_env(NULL, NULL);
    static gim_vpl v[N];
    static gim_receiver r[W * H];
    static float full[W * H * 3], k4[W * H * 3], blurred[W * H * 3], blurred2[W * H * 3];
    double e_raw = 0.0, e_blur = 0.0, e_blur2 = 0.0;
    int i, x, y, n = 0;
    gim_blur_desc b;
    (void)state;
    test_rng_state = 0x5eedu;   /* its own VPLs, whatever ran before */
    for (i = 0; i < N; ++i)   /* a wall x = 0 lit in a patch, facing +x */
        v[i] = vpl(gim_v3(0.0f, test_rnd(0.1f, 0.6f), test_rnd(0.2f, 0.8f)), gim_v3(1, 0, 0), test_rnd(0, 2.0f / N),
                   test_rnd(0, 2.0f / N), test_rnd(0, 2.0f / N));
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x)
            r[y * W + x] = rec(gim_v3(0.2f + 0.6f * (x + 0.5f) / W, 0.0f, (y + 0.5f) / H), gim_v3(0, 1, 0), gim_v3(0, 1, 1));
    {
        gim_vpl_shade_desc d = shade_desc(v, N, r, W, H, env);
        assert_int_equal(gim_vpl_shade_twin(&d, full), GIM_OK);
        d.interleave = 4;
        assert_int_equal(gim_vpl_shade_twin(&d, k4), GIM_OK);
    }
    memset(&b, 0, sizeof b);
    b.radiance = k4; b.receivers = r; b.width = W; b.height = H; b.window = 4; b.position_tolerance = 0.2f; b.env = env;
    assert_int_equal(gim_geometry_blur_twin(&b, blurred), GIM_OK);
    b.window = 2;
    assert_int_equal(gim_geometry_blur_twin(&b, blurred2), GIM_OK);
    /* interior pixels (the window is whole there) */
    for (y = 2; y < H - 2; ++y)
        for (x = 2; x < W - 2; ++x) {
            int p = (y * W + x) * 3;
            e_raw += fabs(k4[p + 1] - full[p + 1]) / full[p + 1];
            e_blur += fabs(blurred[p + 1] - full[p + 1]) / full[p + 1];
            e_blur2 += fabs(blurred2[p + 1] - full[p + 1]) / full[p + 1];
            ++n;
        }
    print_message("interleaved k = 4 against all VPLs: mean rel error %.4f raw, %.4f after the 2 x 2 blur, %.4f after 4 x 4\n",
                  e_raw / n, e_blur2 / n, e_blur / n);
    /* what is left is mostly the light's gradient over the window (the floor near the wall) */
    assert_true(e_blur / n < 0.05);
    assert_true(e_raw / n > 3.0 * e_blur / n);
    assert_true(e_blur2 / n > 1.5 * e_blur / n);
}

/* Bad input: an error with a message, never a crash; outputs are not required to be kept. */
/* The near field: a VPL of area A lights a receiver within 1.5 sqrt(A) as the patch it stands
   for, a regular octagon of area A in its plane (gim__basis axes). Against the octagon's
   irradiance integrated point by point (1000^2 cells, the point VPL's term on each, clipped to
   the receiver's hemisphere): a receiver over the patch facing it and one beside it at right
   angles (a contact edge), whose plane cuts the octagon. The point VPL is far off at both. */
static void near_field_is_the_patch(void **state) {
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    const float area = 0.01f;
    const double rr = sqrt(area / (2.0 * sqrt(2.0)));   /* the octagon's circumradius */
    gim_vpl v = vpl(gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 0.0f, 1.0f), 1.0f, 1.0f, 1.0f);
    gim_receiver r[2];
    gim_vec3 t, b;
    float out[6], point[6];
    int i, a;
    (void)state;
    r[0] = rec(gim_v3(0.01f, -0.02f, 0.03f), gim_v3(0.1f, 0.0f, -1.0f), gim_v3(0, 0, 1));
    r[1] = rec(gim_v3(0.04f, 0.01f, 0.02f), gim_v3(-1.0f, 0.0f, 0.0f), gim_v3(-1, 0, 0));
    for (i = 0; i < 2; ++i) { r[i].glossy[0] = r[i].glossy[1] = r[i].glossy[2] = 0.0f; }
    gim__basis(gim_v3(0.0f, 0.0f, 1.0f), &t, &b);
    v.area = area;
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 2, 1, env);
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        v.area = 0.0f;
        assert_int_equal(gim_vpl_shade_twin(&d, point), GIM_OK);
    }
    for (i = 0; i < 2; ++i) {
        const int n = 1000;
        double e = 0.0, cell = 2.0 * rr / n, x[3], nx[3];
        int p, q;
        for (a = 0; a < 3; ++a) { x[a] = r[i].position[a]; nx[a] = r[i].normal[a]; }
        for (p = 0; p < n; ++p)
            for (q = 0; q < n; ++q) {
                double u = -rr + (p + 0.5) * cell, w = -rr + (q + 0.5) * cell, y[3], dv[3], d2 = 0.0, cl, cx;
                double ang = atan2(w, u), k = floor(ang / (GIM__PI / 4.0)), a0 = k * GIM__PI / 4.0;
                /* inside the octagon: on the inner side of the edge between its corners at a0, a0 + 45 deg */
                double ex = rr * (cos(a0 + GIM__PI / 4.0) - cos(a0)), ey = rr * (sin(a0 + GIM__PI / 4.0) - sin(a0));
                if (ex * (w - rr * sin(a0)) - ey * (u - rr * cos(a0)) < 0.0) continue;
                for (a = 0; a < 3; ++a) {
                    y[a] = u * (&t.x)[a] + w * (&b.x)[a];
                    dv[a] = x[a] - y[a];
                    d2 += dv[a] * dv[a];
                }
                cl = dv[2] / sqrt(d2);                                               /* the patch's normal: +z */
                cx = -(nx[0] * dv[0] + nx[1] * dv[1] + nx[2] * dv[2]) / sqrt(d2);
                if (cl > 0.0 && cx > 0.0) e += cl * cx / (GIM__PI * d2) * cell * cell;
            }
        e /= area;   /* E / Phi */
        for (a = 0; a < 3; ++a) {
            double ref = r[i].albedo[a] / GIM__PI * e;
            print_message("receiver %d channel %d: near field %.6g, integrated %.6g (%.2e), point %.6g\n", i, a,
                          (double)out[i * 3 + a], ref, fabs(out[i * 3 + a] - ref) / ref, (double)point[i * 3 + a]);
            assert_true(fabs(out[i * 3 + a] - ref) <= 1e-4 * ref);   /* measured 1e-6 */
            assert_true(fabs(point[i * 3 + a] - ref) > 0.1 * ref);
        }
    }
    /* the other side of a thin plate: a receiver in the patch's plane, inside the octagon,
       facing away from the VPL's side (a rounding above or below the plane) gets the point's
       nearly nothing, not the patch's F = 1 (plates, sun in gltest_physics: 56% of pixels
       within 10% before the guard, 93% after) */
    v = vpl(gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 0.0f, 1.0f), 1.0f, 1.0f, 1.0f);
    v.area = area;
    r[0] = rec(gim_v3(0.02f, 0.01f, 1e-7f), gim_v3(0.0f, 0.0f, -1.0f), gim_v3(0, 0, -1));
    r[1] = rec(gim_v3(0.01f, -0.02f, 0.0f), gim_v3(0.0f, 0.0f, -1.0f), gim_v3(0, 0, -1));
    {
        gim_vpl_shade_desc d = shade_desc(&v, 1, r, 2, 1, env);
        assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
        for (i = 0; i < 6; ++i) assert_true(out[i] < 1e-3f);
    }
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
}

static void bad_input(void **state) {
    test_log lg;
    gim_env env = test_env(NULL, &lg);
    gim_vpl v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1);
    gim_receiver r = rec(gim_v3(0, 0, 1), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    gim_paraboloid m = test_map(0.2f);
    uint32_t cl = 3;
    float out[3], dist[4] = {1, 1, 1, 1}, v0;
    gim_vpl_shade_desc d;
    gim_blur_desc b;
    int errors = 0;
    (void)state;
    assert_int_equal(gim_vpl_shade_twin(NULL, out), GIM_ERROR_INVALID_ARGUMENT);
#define BAD(expr) do { assert_int_equal(expr, GIM_ERROR_INVALID_ARGUMENT); assert_int_equal(lg.errors, ++errors); } while (0)
#define RESET() (d = shade_desc(&v, 1, &r, 1, 1, env))
    RESET(); BAD(gim_vpl_shade_twin(&d, NULL));
    RESET(); d.receivers = NULL; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.width = 0; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.vpls = NULL; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.scene_scale = 0.0f; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.clamp_distance = -1.0f; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.clamp_distance = NAN; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.interleave = 65; BAD(gim_vpl_shade_twin(&d, out));
    RESET(); d.cluster = &cl; BAD(gim_vpl_shade_twin(&d, out));                       /* no maps */
    RESET(); d.cluster = &cl; d.maps = &m; d.map_count = 1; d.distance = dist; d.map_size = 2;
    BAD(gim_vpl_shade_twin(&d, out));                                                /* cluster 3 of 1 */
    cl = 0; m.normal[0] = 5.0f; BAD(gim_vpl_shade_twin(&d, out));                    /* map normal not unit */
    m = test_map(0.2f); m.size = -1.0f; BAD(gim_vpl_shade_twin(&d, out));
    m = test_map(0.2f);
    assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
    RESET(); v.position[1] = INFINITY; BAD(gim_vpl_shade_twin(&d, out));
    v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1); v.flux[2] = -1.0f; BAD(gim_vpl_shade_twin(&d, out));
    v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1); v.area = -1.0f; BAD(gim_vpl_shade_twin(&d, out));
    v.area = NAN; BAD(gim_vpl_shade_twin(&d, out));
    v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1);
    RESET(); d.cluster = &cl; d.maps = &m; d.map_count = 1; d.distance = dist; d.map_size = 2; d.ism = dist;
    BAD(gim_vpl_shade_twin(&d, out));                                                /* ISMs with clusters: no ism_first */
    d.ism = NULL; d.ism_first = 1; BAD(gim_vpl_shade_twin(&d, out));                 /* ism_first without ISMs */
    RESET();
    r.normal[0] = 0.5f; BAD(gim_vpl_shade_twin(&d, out));
    r = rec(gim_v3(0, 0, 1), gim_v3(0, 0, -1), gim_v3(0, 0, -1)); r.exponent = -1.0f; BAD(gim_vpl_shade_twin(&d, out));
    r = rec(gim_v3(0, 0, 1), gim_v3(0, 0, -1), gim_v3(0, 0, -1)); r.albedo[1] = NAN; BAD(gim_vpl_shade_twin(&d, out));
    r = rec(gim_v3(0, 0, 1), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    RESET(); d.vpl_count = 0; d.vpls = NULL;
    assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);                            /* no VPLs: dark */
    assert_true(out[0] == 0.0f && out[1] == 0.0f && out[2] == 0.0f);
    /* huge flux at a tiny distance: finite, clamped at FLT_MAX */
    RESET(); v.flux[0] = 3e38f; r.position[2] = 1e-5f;
    assert_int_equal(gim_vpl_shade_twin(&d, out), GIM_OK);
    assert_true(isfinite(out[0]) && out[0] > 0.0f && isfinite(out[1]));
    v = vpl(gim_v3(0, 0, 0), gim_v3(0, 0, 1), 1, 1, 1);
    r = rec(gim_v3(0, 0, 1), gim_v3(0, 0, -1), gim_v3(0, 0, -1));
    /* visibility (it has no env: errors are results only) */
    assert_int_equal(gim_paraboloid_visibility_twin(NULL, 2, &m, gim_v3(0, 0, 1), NULL, &v0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 0, &m, gim_v3(0, 0, 1), NULL, &v0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, NULL, gim_v3(0, 0, 1), NULL, &v0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(NAN, 0, 1), NULL, &v0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(0, 0, 1), NULL, NULL), GIM_ERROR_INVALID_ARGUMENT);
    {
        gim_vec3 bad = gim_v3(0, 0, 2), nan_ = gim_v3(NAN, 0, 1);
        assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(0, 0, 1), &bad, &v0), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(0, 0, 1), &nan_, &v0), GIM_ERROR_INVALID_ARGUMENT);
    }
    m.origin[0] = INFINITY;
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(0, 0, 1), NULL, &v0), GIM_ERROR_INVALID_ARGUMENT);
    m = test_map(0.2f);
    /* NaN and negative texels block nothing; a receiver at the origin or far away is lit */
    dist[0] = NAN; dist[1] = -1.0f; dist[2] = 0.0f; dist[3] = NAN;
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, vs_local(&m, 0.1f, 0.1f, 1.0f), NULL, &v0), GIM_OK);
    assert_true(v0 == 1.0f);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, vs_local(&m, 0, 0, 0), NULL, &v0), GIM_OK);
    assert_true(v0 == 1.0f);
    assert_int_equal(gim_paraboloid_visibility_twin(dist, 2, &m, gim_v3(3e38f, -3e38f, 3e38f), NULL, &v0), GIM_OK);
    assert_true(v0 >= 0.0f && v0 <= 1.0f);
    /* blur */
    memset(&b, 0, sizeof b);
    b.radiance = out; b.receivers = &r; b.width = 1; b.height = 1; b.position_tolerance = 1.0f; b.env = env;
    out[0] = out[1] = out[2] = 1.0f;
    assert_int_equal(gim_geometry_blur_twin(&b, dist), GIM_OK);
    assert_int_equal(gim_geometry_blur_twin(NULL, dist), GIM_ERROR_INVALID_ARGUMENT);
    BAD(gim_geometry_blur_twin(&b, NULL));
    BAD(gim_geometry_blur_twin(&b, out));                      /* in place */
    b.position_tolerance = 0.0f; BAD(gim_geometry_blur_twin(&b, dist));
    b.position_tolerance = 1.0f; b.normal_tolerance = 2.0f; BAD(gim_geometry_blur_twin(&b, dist));
    b.normal_tolerance = 0.0f; b.window = 100; BAD(gim_geometry_blur_twin(&b, dist));
    b.window = 2; out[1] = NAN; BAD(gim_geometry_blur_twin(&b, dist));
    out[1] = 1.0f; b.height = 0; BAD(gim_geometry_blur_twin(&b, dist));
#undef BAD
#undef RESET
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(single_vpl_closed_form),
        cmocka_unit_test(clamping_bites_below_dc),
        cmocka_unit_test(interleave_block_mean_is_full_sum),
        cmocka_unit_test(vogel_table),
        cmocka_unit_test(visibility_umbra_penumbra),
        cmocka_unit_test(visibility_near_exact),
        cmocka_unit_test(visibility_unit_free),
        cmocka_unit_test(shade_uses_cluster_visibility),
        cmocka_unit_test(shade_uses_vpl_ism),
        cmocka_unit_test(blur_keeps_edges),
        cmocka_unit_test(blur_light_not_albedo),
        cmocka_unit_test(blur_undoes_interleaving),
        cmocka_unit_test(bad_input),
        cmocka_unit_test(near_field_is_the_patch),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
