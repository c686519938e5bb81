/* k-means of VPLs: recovery of known clusters, both metrics term by term, determinism,
   temporal coherence, warm start, empty-cluster repair, degenerate inputs, area and sigma,
   unit-freeness, argument errors, allocation. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* ---- helpers ---------------------------------------------------------------------------- */

/* Outputs of one call, every optional array present. */
typedef struct km_out {
    uint32_t n, m;
    float *centres, *normals, *flux, *area, *sigma;
    uint32_t *counts, *assignment;
    gim_kmeans_result r;
} km_out;

static void km_out_init(km_out *o, uint32_t n, uint32_t m) {
    memset(o, 0, sizeof *o);
    o->n = n; o->m = m;
    o->centres = (float *)calloc((size_t)m * 3, sizeof(float));
    o->normals = (float *)calloc((size_t)m * 3, sizeof(float));
    o->flux = (float *)calloc((size_t)m * 3, sizeof(float));
    o->sigma = (float *)calloc((size_t)m * 3, sizeof(float));
    o->area = (float *)calloc(m, sizeof(float));
    o->counts = (uint32_t *)calloc(m, sizeof(uint32_t));
    o->assignment = (uint32_t *)calloc(n, sizeof(uint32_t));
    assert_non_null(o->centres); assert_non_null(o->normals); assert_non_null(o->flux);
    assert_non_null(o->sigma); assert_non_null(o->area); assert_non_null(o->counts);
    assert_non_null(o->assignment);
    o->r.centres = o->centres; o->r.normals = o->normals; o->r.flux = o->flux;
    o->r.sigma = o->sigma; o->r.area = o->area; o->r.counts = o->counts;
    o->r.assignment = o->assignment;
}
static void km_out_free(km_out *o) {
    free(o->centres); free(o->normals); free(o->flux); free(o->sigma);
    free(o->area); free(o->counts); free(o->assignment);
}

/* Runs gim_kmeans with the counting allocator; checks success, no leak, the invariants every
   result must meet (finite, unit normals, counts >= 1 summing to N, assignment consistent). */
static void km_run(gim_kmeans_desc *d, km_out *o) {
    test_alloc_stats st;
    test_log lg;
    uint32_t i, j, *cnt;
    d->env = test_env(&st, &lg);
    assert_int_equal(gim_kmeans(d, &o->r), GIM_OK);
    assert_int_equal(st.live, 0);
    assert_int_equal(lg.errors, 0);
    cnt = (uint32_t *)calloc(o->m, sizeof(uint32_t));
    assert_non_null(cnt);
    for (i = 0; i < o->n; ++i) {
        assert_true(o->assignment[i] < o->m);
        cnt[o->assignment[i]]++;
    }
    for (j = 0; j < o->m; ++j) {
        const float *nn = o->normals + j * 3;
        assert_true(o->counts[j] >= 1);
        assert_int_equal(o->counts[j], cnt[j]);
        assert_true(gim__all_finite(o->centres + j * 3, 3) && gim__all_finite(o->normals + j * 3, 3));
        assert_true(gim__all_finite(o->flux + j * 3, 3) && gim__all_finite(o->sigma + j * 3, 3));
        assert_true(gim__isfinitef(o->area[j]) && o->area[j] >= 0.0f);
        assert_true(fabs(sqrt((double)nn[0] * nn[0] + (double)nn[1] * nn[1] + (double)nn[2] * nn[2]) - 1.0) < 1e-6);
    }
    assert_true(o->r.iterations >= 1);
    free(cnt);
}

/* VPLs of a room (10 units) with a tilted box inside: points on 8 planes, one normal and
   one colour each, flux varying along the surface like a spot light's footprint. */
typedef struct km_scene { uint32_t n; float *pos, *nrm, *flux; } km_scene;

static void scene_make(km_scene *s, uint32_t n, uint64_t seed) {
    static const float org[8][3] = {{0, 0, 0}, {0, 10, 10}, {0, 0, 10}, {0, 10, 0}, {10, 0, 0}, {3, 0.01f, 4}, {3, 0.01f, 4}, {6, 3, 4}};
    static const float du[8][3] = {{10, 0, 0}, {10, 0, 0}, {10, 0, 0}, {0, 0, 10}, {0, 0, 10}, {3, 0, 1}, {3, 0, 1}, {-3, 0, -1}};
    static const float dv[8][3] = {{0, 0, 10}, {0, 0, -10}, {0, 10, 0}, {0, -10, 0}, {0, 10, 0}, {0, 3, 0}, {-1, 0, 3}, {0, -3, 0}};
    static const float alb[8][3] = {{.8f, .8f, .8f}, {.8f, .8f, .8f}, {.7f, .7f, .7f}, {.8f, .1f, .1f}, {.1f, .8f, .1f}, {.5f, .5f, .9f}, {.9f, .9f, .2f}, {.5f, .5f, .9f}};
    uint32_t i;
    s->n = n;
    s->pos = (float *)malloc((size_t)n * 3 * sizeof(float));
    s->nrm = (float *)malloc((size_t)n * 3 * sizeof(float));
    s->flux = (float *)malloc((size_t)n * 3 * sizeof(float));
    assert_non_null(s->pos); assert_non_null(s->nrm); assert_non_null(s->flux);
    test_rng_state = seed;
    for (i = 0; i < n; ++i) {
        int p = (int)(test_rand01() * 8.0), a;
        float u = (float)test_rand01(), v = (float)test_rand01(), fall;
        gim_vec3 nn = gim_v3_normalize(gim__v3_cross(gim_v3(du[p][0], du[p][1], du[p][2]), gim_v3(dv[p][0], dv[p][1], dv[p][2])));
        fall = 1.0f / (1.0f + 4.0f * ((u - 0.4f) * (u - 0.4f) + (v - 0.6f) * (v - 0.6f)));
        for (a = 0; a < 3; ++a) {
            s->pos[i * 3 + a] = org[p][a] + u * du[p][a] + v * dv[p][a];
            s->flux[i * 3 + a] = alb[p][a] * fall;
        }
        s->nrm[i * 3 + 0] = nn.x; s->nrm[i * 3 + 1] = nn.y; s->nrm[i * 3 + 2] = nn.z;
    }
}
static void scene_free(km_scene *s) { free(s->pos); free(s->nrm); free(s->flux); }

static gim_kmeans_desc scene_desc(const km_scene *s, uint32_t m) {
    gim_kmeans_desc d;
    memset(&d, 0, sizeof d);
    d.positions = s->pos; d.normals = s->nrm; d.flux = s->flux;
    d.vpl_count = s->n; d.cluster_count = m;
    return d;
}

/* 1 when a and b are the same partition up to the labels. */
static int same_partition(const uint32_t *a, const uint32_t *b, uint32_t n, uint32_t m) {
    uint32_t *ab = (uint32_t *)malloc(m * sizeof(uint32_t)), *ba = (uint32_t *)malloc(m * sizeof(uint32_t)), i;
    int ok = 1;
    assert_non_null(ab); assert_non_null(ba);
    for (i = 0; i < m; ++i) ab[i] = ba[i] = 0xffffffffu;
    for (i = 0; i < n && ok; ++i) {
        if (ab[a[i]] == 0xffffffffu && ba[b[i]] == 0xffffffffu) { ab[a[i]] = b[i]; ba[b[i]] = a[i]; }
        ok = ab[a[i]] == b[i] && ba[b[i]] == a[i];
    }
    free(ab); free(ba);
    return ok;
}

/* ---- tests ------------------------------------------------------------------------------ */

/* Six blobs far apart, interleaved in index order (blob = i % 6) so every fixed seed
   (VPL 49k) lands in a different blob but at a random point of it; both metrics must recover
   the blobs exactly and put each centre on its blob's flux-weighted mean. */
static void blobs_recovered(void **state) {
    enum { M = 6, N = 6 * 49 };
    static const float bc[M][3] = {{0, 0, 0}, {8, 0, 0}, {0, 8, 0}, {0, 0, 8}, {8, 8, 8}, {8, 0, 8}};
    static float pos[N * 3], nrm[N * 3], flux[N * 3];
    uint32_t i, b, metric;
    (void)state;
    test_rng_state = 99;
    for (i = 0; i < N; ++i) {
        int a;
        b = i % M;
        for (a = 0; a < 3; ++a) {
            pos[i * 3 + a] = bc[b][a] + (float)(test_rand01() - 0.5);
            nrm[i * 3 + a] = (float)(test_rand01() - 0.5) * 0.2f + (a == (int)(b % 3) ? 1.0f : 0.0f);
            flux[i * 3 + a] = (float)test_rand01() * 3.0f;
        }
    }
    for (metric = GIM_KMEANS_METRIC_DONG; metric <= GIM_KMEANS_METRIC_SSVP; ++metric) {
        gim_kmeans_desc d;
        km_out o;
        uint32_t truth[N];
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.flux = flux;
        d.vpl_count = N; d.cluster_count = M; d.metric = (gim_kmeans_metric)metric;
        km_out_init(&o, N, M);
        km_run(&d, &o);
        for (i = 0; i < N; ++i) truth[i] = i % M;
        assert_true(same_partition(o.assignment, truth, N, M));
        assert_true(o.r.iterations < 16); /* converged, not capped */
        assert_int_equal(o.r.empty_repaired, 0);
        for (b = 0; b < M; ++b) {
            double sw = 0, sp[3] = {0, 0, 0}, sf[3] = {0, 0, 0};
            uint32_t c = o.assignment[b];
            int a;
            for (i = b; i < N; i += M) {
                double w = ((double)flux[i * 3] + flux[i * 3 + 1] + flux[i * 3 + 2]) / 3.0;
                sw += w;
                for (a = 0; a < 3; ++a) { sp[a] += w * pos[i * 3 + a]; sf[a] += flux[i * 3 + a]; }
            }
            assert_int_equal(o.counts[c], 49);
            for (a = 0; a < 3; ++a) {
                assert_true(fabs(o.centres[c * 3 + a] - sp[a] / sw) < 1e-5);
                assert_true(fabs(o.flux[c * 3 + a] - sf[a]) < 1e-4 * sf[a]);
            }
            /* the blob's mean normal points along its axis */
            assert_true(o.normals[c * 3 + b % 3] > 0.99f);
        }
        km_out_free(&o);
    }
}

/* Two sides of a thin sheet: the same positions (interleaved), opposite normals. The
   position term cannot tell them apart; the normal term must split them exactly. */
static void normals_split_coplanar_sets(void **state) {
    enum { N = 202 };
    static float pos[N * 3], nrm[N * 3];
    uint32_t i, metric;
    (void)state;
    test_rng_state = 7;
    for (i = 0; i < N; ++i) {
        pos[i * 3] = (float)test_rand01(); pos[i * 3 + 1] = 0.0f; pos[i * 3 + 2] = (float)test_rand01();
        nrm[i * 3] = 0.0f; nrm[i * 3 + 1] = (i & 1) ? -1.0f : 1.0f; nrm[i * 3 + 2] = 0.0f;
    }
    for (metric = GIM_KMEANS_METRIC_DONG; metric <= GIM_KMEANS_METRIC_SSVP; ++metric) {
        gim_kmeans_desc d;
        km_out o;
        uint32_t up;
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.vpl_count = N; d.cluster_count = 2;
        d.metric = (gim_kmeans_metric)metric;
        km_out_init(&o, N, 2);
        km_run(&d, &o);
        up = o.assignment[0];
        for (i = 0; i < N; ++i) assert_int_equal(o.assignment[i] == up, (i & 1) == 0);
        assert_true(o.normals[up * 3 + 1] == 1.0f && o.normals[(1 - up) * 3 + 1] == -1.0f);
        /* the VAL of one side is the whole sheet: same area for both sides */
        assert_true(fabsf(o.area[0] - o.area[1]) < 0.2f * o.area[0]);
        /* position only (w_a = 0): some cluster mixes the two sides */
        d.w_x = 1.0f; d.w_a = 0.0f;
        km_run(&d, &o);
        {
            int mixed = 0;
            for (i = 2; i < N; ++i) mixed |= (o.assignment[i] == o.assignment[0]) != ((i & 1) == 0);
            assert_true(mixed);
        }
        km_out_free(&o);
    }
}

/* Which of two warm centres c1, c2 a probe VPL (at the origin, normal +z) picks, with
   scene_scale 1 and one assignment step. VPLs 1..3 sit exactly on centres 0..2 so no cluster
   empties and the probe's choice is the metric's verdict alone. */
static uint32_t probe(gim_kmeans_metric metric, float wx, float wa, float d1, float a1_deg, float d2, float a2_deg) {
    float pos[4 * 3], nrm[4 * 3], cen[3 * 3], cn[3 * 3];
    const float deg = 3.14159265f / 180.0f;
    gim_kmeans_desc d;
    km_out o;
    uint32_t r;
    memset(pos, 0, sizeof pos); memset(nrm, 0, sizeof nrm);
    /* centre 0 far away, centres 1 and 2 along -x and +x with tilted normals */
    cen[0] = 0; cen[1] = 50; cen[2] = 0; cn[0] = 0; cn[1] = 1; cn[2] = 0;
    cen[3] = -d1; cen[4] = 0; cen[5] = 0; cn[3] = sinf(a1_deg * deg); cn[4] = 0; cn[5] = cosf(a1_deg * deg);
    cen[6] = d2; cen[7] = 0; cen[8] = 0; cn[6] = 0; cn[7] = sinf(a2_deg * deg); cn[8] = cosf(a2_deg * deg);
    nrm[2] = 1.0f;
    memcpy(pos + 3, cen, sizeof cen); memcpy(nrm + 3, cn, sizeof cn);
    memset(&d, 0, sizeof d);
    d.positions = pos; d.normals = nrm; d.vpl_count = 4; d.cluster_count = 3;
    d.metric = metric; d.init = GIM_KMEANS_INIT_WARM; d.init_centres = cen; d.init_normals = cn;
    d.w_x = wx; d.w_a = wa; d.scene_scale = 1.0f; d.max_iterations = 1;
    km_out_init(&o, 4, 3);
    km_run(&d, &o);
    assert_int_equal(o.assignment[1], 0); assert_int_equal(o.assignment[2], 1); assert_int_equal(o.assignment[3], 2);
    r = o.assignment[0];
    km_out_free(&o);
    return r;
}

/* Dong: 0.7 d + 0.3 angle/pi. Equal-cost angle for c1 at 0.2 (same normal) vs c2 at 0.1:
   0.3 a/pi = 0.07 -> a = 42 deg. */
static void dong_metric_terms(void **state) {
    (void)state;
    assert_int_equal(probe(GIM_KMEANS_METRIC_DONG, 0, 0, 0.2f, 0, 0.1f, 30), 2);
    assert_int_equal(probe(GIM_KMEANS_METRIC_DONG, 0, 0, 0.2f, 0, 0.1f, 50), 1);
    /* defaults 0.7/0.3 are the metric's: the same with explicit weights */
    assert_int_equal(probe(GIM_KMEANS_METRIC_DEFAULT, 0.7f, 0.3f, 0.2f, 0, 0.1f, 40), 2);
    assert_int_equal(probe(GIM_KMEANS_METRIC_DEFAULT, 0.7f, 0.3f, 0.2f, 0, 0.1f, 44), 1);
    /* the angle keeps counting beyond 90 deg: 100 deg beats 170 deg at nearly equal distance */
    assert_int_equal(probe(GIM_KMEANS_METRIC_DONG, 0, 0, 0.101f, 100, 0.1f, 170), 1);
    /* pure position */
    assert_int_equal(probe(GIM_KMEANS_METRIC_DONG, 1, 0, 0.2f, 0, 0.1f, 170), 2);
}

/* SSVP eq. 2 with the slip fixed: 0.6 d + 0.4 (1 - max(cos, 0)). Similar normals are closer
   (the printed + (n.n) would send the probe to the tilted centre); the distance is linear,
   not squared; the clamp makes every angle past 90 deg cost the same. */
static void ssvp_metric_terms(void **state) {
    (void)state;
    /* equal distances: the similar normal wins, whichever side it is on */
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.1f, 0, 0.1f, 60), 1);
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.1f, 60, 0.1f, 0), 2);
    /* c1 at 0.2 same normal (0.12) vs c2 at 0.1 tilted (0.06 + 0.4 (1 - cos)): break-even 31.8 deg */
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.2f, 0, 0.1f, 29), 2);
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.2f, 0, 0.1f, 35), 1);
    /* linear distance: c1 at 0.4 same normal (0.24) vs c2 at 0.2 with 1 - cos = 0.2 (0.20):
       c2. Squared distances would give 0.096 vs 0.104: c1. */
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.4f, 0, 0.2f, 36.87f), 2);
    /* clamp: 100 and 170 deg both cost 0.4, so the nearer centre wins (Dong picks the other) */
    assert_int_equal(probe(GIM_KMEANS_METRIC_SSVP, 0, 0, 0.101f, 100, 0.1f, 170), 2);
}

/* Same input, same output, bit for bit, for both metrics and inits. */
static void deterministic(void **state) {
    km_scene s;
    km_out a, b;
    gim_kmeans_desc d;
    int metric;
    (void)state;
    scene_make(&s, 2048, 11);
    d = scene_desc(&s, 24);
    km_out_init(&a, s.n, 24); km_out_init(&b, s.n, 24);
    for (metric = 0; metric < 2; ++metric) {
        d.metric = metric ? GIM_KMEANS_METRIC_SSVP : GIM_KMEANS_METRIC_DONG;
        d.init = GIM_KMEANS_INIT_FIXED;
        km_run(&d, &a);
        km_run(&d, &b);
        assert_memory_equal(a.centres, b.centres, 24 * 3 * sizeof(float));
        assert_memory_equal(a.normals, b.normals, 24 * 3 * sizeof(float));
        assert_memory_equal(a.flux, b.flux, 24 * 3 * sizeof(float));
        assert_memory_equal(a.sigma, b.sigma, 24 * 3 * sizeof(float));
        assert_memory_equal(a.area, b.area, 24 * sizeof(float));
        assert_memory_equal(a.assignment, b.assignment, s.n * sizeof(uint32_t));
        assert_int_equal(a.r.iterations, b.r.iterations);
        /* warm start from those centres: again bit-identical twice */
        {
            float *c = (float *)malloc(24 * 3 * sizeof(float)), *cn = (float *)malloc(24 * 3 * sizeof(float));
            assert_non_null(c); assert_non_null(cn);
            memcpy(c, a.centres, 24 * 3 * sizeof(float)); memcpy(cn, a.normals, 24 * 3 * sizeof(float));
            d.init = GIM_KMEANS_INIT_WARM; d.init_centres = c; d.init_normals = cn;
            km_run(&d, &a);
            km_run(&d, &b);
            assert_memory_equal(a.centres, b.centres, 24 * 3 * sizeof(float));
            assert_memory_equal(a.assignment, b.assignment, s.n * sizeof(uint32_t));
            free(c); free(cn);
        }
    }
    km_out_free(&a); km_out_free(&b);
    scene_free(&s);
}

/* Largest and median distance between centre j of a and centre j of b. */
static void centre_moves(const km_out *a, const km_out *b, double *maxmove, double *median) {
    double mv[64], t;
    uint32_t j, k;
    assert_true(a->m <= 64);
    for (j = 0; j < a->m; ++j) {
        double dd = 0;
        for (k = 0; k < 3; ++k) dd += (a->centres[j * 3 + k] - b->centres[j * 3 + k]) * (double)(a->centres[j * 3 + k] - b->centres[j * 3 + k]);
        mv[j] = sqrt(dd);
    }
    for (j = 1; j < a->m; ++j) /* insertion sort */
        for (k = j; k > 0 && mv[k - 1] > mv[k]; --k) { t = mv[k]; mv[k] = mv[k - 1]; mv[k - 1] = t; }
    *maxmove = mv[a->m - 1];
    *median = mv[a->m / 2];
}

/* Dong 5.2: the fixed initial assignment makes small input changes give small changes of
   the VALs, cluster k staying cluster k. Move every VPL by up to 1e-3 of the room and change
   its flux by up to 5%: most VPLs keep their cluster, every centre moves little. The same
   input in another order (other seeds) gives centres that differ by whole clusters. */
static void fixed_init_temporal_coherence(void **state) {
    km_scene s, t;
    km_out a, b;
    gim_kmeans_desc d;
    uint32_t i, same = 0;
    double maxmove, median;
    (void)state;
    scene_make(&s, 2048, 5);
    scene_make(&t, 2048, 5);
    test_rng_state = 1234;
    for (i = 0; i < t.n * 3; ++i) {
        t.pos[i] += (float)(test_rand01() - 0.5) * 0.02f;
        t.flux[i] *= 1.0f + (float)(test_rand01() - 0.5) * 0.1f;
    }
    d = scene_desc(&s, 32);
    d.max_iterations = 64;
    km_out_init(&a, s.n, 32); km_out_init(&b, s.n, 32);
    km_run(&d, &a);
    km_run(&d, &b);
    assert_memory_equal(a.centres, b.centres, 32 * 3 * sizeof(float)); /* no state between calls */
    d.positions = t.pos; d.flux = t.flux;
    km_run(&d, &b);
    for (i = 0; i < s.n; ++i) same += a.assignment[i] == b.assignment[i];
    centre_moves(&a, &b, &maxmove, &median);
    print_message("fixed init, perturbed input: %u/%u VPLs kept their cluster, centre moves: median %.4f, max %.4f (room 10)\n", same, s.n, median, maxmove);
    assert_true(same >= s.n * 97 / 100);
    assert_true(median < 0.02 && maxmove < 1.0);
    /* the same VPLs rotated by 1000 places: other seeds, other clusters */
    for (i = 0; i < t.n * 3; ++i) {
        uint32_t from = (i + 1000 * 3) % (t.n * 3);
        t.pos[i] = s.pos[from]; t.nrm[i] = s.nrm[from]; t.flux[i] = s.flux[from];
    }
    d.positions = t.pos; d.normals = t.nrm; d.flux = t.flux;
    km_run(&d, &b);
    centre_moves(&a, &b, &maxmove, &median);
    print_message("other seeds: centre moves: median %.4f, max %.4f\n", median, maxmove);
    assert_true(median > 0.5);
    km_out_free(&a); km_out_free(&b);
    scene_free(&s); scene_free(&t);
}

/* SSVP 3.B: starting from the previous frame's centres converges in fewer steps than the
   fixed init on a slightly changed input, to a clustering of similar quality. */
static void warm_start_fewer_iterations(void **state) {
    km_scene s, t;
    km_out a, b, c;
    gim_kmeans_desc d;
    uint32_t i;
    (void)state;
    scene_make(&s, 4096, 21);
    scene_make(&t, 4096, 21);
    for (i = 0; i < t.n * 3; ++i) t.pos[i] += 0.01f * (float)((i % 3) == 0); /* the scene slides 1e-3 */
    d = scene_desc(&s, 32);
    d.max_iterations = 100;
    km_out_init(&a, s.n, 32); km_out_init(&b, s.n, 32); km_out_init(&c, s.n, 32);
    km_run(&d, &a);
    d.positions = t.pos;
    km_run(&d, &b); /* fixed init on the new frame */
    d.init = GIM_KMEANS_INIT_WARM; d.init_centres = a.centres; d.init_normals = a.normals;
    km_run(&d, &c); /* warm start on the new frame */
    print_message("iterations: fixed %u, warm %u\n", b.r.iterations, c.r.iterations);
    assert_true(b.r.iterations < 100 && c.r.iterations < 100);
    assert_true(c.r.iterations * 2 < b.r.iterations);
    assert_true(c.r.iterations <= 8);
    km_out_free(&a); km_out_free(&b); km_out_free(&c);
    scene_free(&s); scene_free(&t);
}

/* Dong fig. 8: warm centres on the wall while the VPLs are all on the ceiling; the wall
   clusters empty at once and must be re-seeded, not lost. And the re-seeding takes from the
   worst cluster: a wide blob and a tight one, a third centre far away: the wide one splits. */
static void empty_clusters_repaired(void **state) {
    enum { N = 400, M = 8 };
    static float pos[N * 3], nrm[N * 3];
    float cen[M * 3], cn[M * 3];
    gim_kmeans_desc d;
    km_out o;
    uint32_t i, j;
    (void)state;
    test_rng_state = 3;
    for (i = 0; i < N; ++i) { /* ceiling y = 10, normal -y */
        pos[i * 3] = (float)test_rand01() * 10.0f; pos[i * 3 + 1] = 10.0f; pos[i * 3 + 2] = (float)test_rand01() * 10.0f;
        nrm[i * 3] = 0; nrm[i * 3 + 1] = -1; nrm[i * 3 + 2] = 0;
    }
    for (j = 0; j < M; ++j) {
        if (j < 4) { cen[j * 3] = 2.5f + 5.0f * (float)(j & 1); cen[j * 3 + 1] = 10; cen[j * 3 + 2] = 2.5f + 5.0f * (float)(j >> 1); cn[j * 3] = 0; cn[j * 3 + 1] = -1; cn[j * 3 + 2] = 0; }
        else { cen[j * 3] = 0; cen[j * 3 + 1] = 2.0f * (float)(j - 3); cen[j * 3 + 2] = 5; cn[j * 3] = 1; cn[j * 3 + 1] = 0; cn[j * 3 + 2] = 0; }
    }
    memset(&d, 0, sizeof d);
    d.positions = pos; d.normals = nrm; d.vpl_count = N; d.cluster_count = M;
    d.init = GIM_KMEANS_INIT_WARM; d.init_centres = cen; d.init_normals = cn; d.max_iterations = 64;
    km_out_init(&o, N, M);
    km_run(&d, &o); /* counts >= 1 checked there */
    assert_true(o.r.empty_repaired >= 4);
    for (j = 0; j < M; ++j) {
        assert_true(fabsf(o.centres[j * 3 + 1] - 10.0f) < 1e-5f); /* every VAL now on the ceiling */
        assert_true(o.normals[j * 3 + 1] == -1.0f);
        assert_true(o.counts[j] >= N / M / 4);
    }
    km_out_free(&o);

    /* tight blob (radius 0.1) at x = 10, wide blob (radius 2) at x = 0, centre 2 far away;
       the tight one comes first so that "lowest index" would pick it as the donor */
    memset(pos, 0, sizeof pos);
    for (i = 0; i < 200; ++i) {
        float r = (i & 1) ? 2.0f : 0.1f, x0 = (i & 1) ? 0.0f : 10.0f;
        pos[i * 3] = x0 + r * (float)(test_rand01() * 2 - 1);
        pos[i * 3 + 2] = r * (float)(test_rand01() * 2 - 1);
        nrm[i * 3] = 0; nrm[i * 3 + 1] = 1; nrm[i * 3 + 2] = 0;
    }
    cen[0] = 10; cen[1] = 0; cen[2] = 0; cen[3] = 0; cen[4] = 0; cen[5] = 0; cen[6] = 5; cen[7] = 40; cen[8] = 0;
    for (j = 0; j < 3; ++j) { cn[j * 3] = 0; cn[j * 3 + 1] = 1; cn[j * 3 + 2] = 0; }
    d.positions = pos; d.normals = nrm; d.vpl_count = 200; d.cluster_count = 3;
    d.scene_scale = 10.0f;
    km_out_init(&o, 200, 3);
    km_run(&d, &o);
    assert_int_equal(o.r.empty_repaired, 1);
    {
        uint32_t tight = o.assignment[0];
        for (i = 0; i < 200; i += 2) assert_int_equal(o.assignment[i], tight); /* tight blob whole */
        for (i = 1; i < 200; i += 2) assert_int_not_equal(o.assignment[i], tight);
        assert_int_equal(o.counts[tight], 100);
        assert_true(o.centres[2 * 3] < 2.5f); /* the far centre moved into the wide blob */
    }
    /* one step: the re-seeded cluster holds exactly the wide blob's farthest VPL from its centre */
    d.max_iterations = 1;
    km_run(&d, &o);
    {
        uint32_t far = 0;
        double fd = -1;
        for (i = 1; i < 200; i += 2) {
            double dd = (double)pos[i * 3] * pos[i * 3] + (double)pos[i * 3 + 2] * pos[i * 3 + 2];
            if (dd > fd) { fd = dd; far = i; }
        }
        assert_int_equal(o.counts[2], 1);
        assert_int_equal(o.assignment[far], 2);
        assert_true(o.centres[6] == pos[far * 3] && o.centres[8] == pos[far * 3 + 2]);
    }
    km_out_free(&o);
}

/* M == N: every VPL its own cluster, exactly. */
static void m_equals_n(void **state) {
    enum { N = 64 };
    float pos[N * 3], nrm[N * 3];
    gim_kmeans_desc d;
    km_out o;
    uint32_t i;
    (void)state;
    test_rng_state = 17;
    for (i = 0; i < N * 3; ++i) { pos[i] = (float)test_rand01() * 4.0f; nrm[i] = (float)test_rand01() + 0.1f; }
    memset(&d, 0, sizeof d);
    d.positions = pos; d.normals = nrm; d.vpl_count = N; d.cluster_count = N;
    km_out_init(&o, N, N);
    km_run(&d, &o);
    for (i = 0; i < N; ++i) {
        gim_vec3 n = gim_v3_normalize(gim_v3(nrm[i * 3], nrm[i * 3 + 1], nrm[i * 3 + 2]));
        assert_int_equal(o.assignment[i], i);
        assert_int_equal(o.counts[i], 1);
        assert_true(o.centres[i * 3] == pos[i * 3] && o.centres[i * 3 + 1] == pos[i * 3 + 1] && o.centres[i * 3 + 2] == pos[i * 3 + 2]);
        assert_true(fabsf(o.normals[i * 3] - n.x) < 1e-6f && fabsf(o.normals[i * 3 + 2] - n.z) < 1e-6f);
        assert_true(o.area[i] == 0.0f && o.sigma[i * 3] == 0.0f);
    }
    assert_int_equal(o.r.iterations, 2);
    km_out_free(&o);
}

/* All VPLs at one point: clusters all survive (one VPL moved into each), converge at once,
   and sit exactly on the point. Same position with two normals: split by normal. */
static void coincident_points(void **state) {
    enum { N = 100, M = 5 };
    float pos[N * 3], nrm[N * 3], flux[N * 3];
    gim_kmeans_desc d;
    km_out o;
    uint32_t i, j;
    (void)state;
    for (i = 0; i < N; ++i) {
        pos[i * 3] = 1e5f; pos[i * 3 + 1] = -3.25f; pos[i * 3 + 2] = 7.0f;
        nrm[i * 3] = 0; nrm[i * 3 + 1] = 0; nrm[i * 3 + 2] = 2.0f;
        flux[i * 3] = flux[i * 3 + 1] = flux[i * 3 + 2] = 0.5f;
    }
    memset(&d, 0, sizeof d);
    d.positions = pos; d.normals = nrm; d.flux = flux; d.vpl_count = N; d.cluster_count = M;
    km_out_init(&o, N, M);
    km_run(&d, &o);
    assert_int_equal(o.r.empty_repaired, M - 1);
    assert_true(o.r.iterations <= 2);
    for (j = 0; j < M; ++j) {
        assert_true(o.centres[j * 3] == 1e5f && o.centres[j * 3 + 1] == -3.25f && o.centres[j * 3 + 2] == 7.0f);
        assert_true(o.normals[j * 3 + 2] == 1.0f);
        assert_true(o.area[j] == 0.0f && o.sigma[j * 3] == 0.0f && o.sigma[j * 3 + 1] == 0.0f);
    }
    km_out_free(&o);
    /* same point, normals +z / -z alternating: the two clusters are the two normals */
    for (i = 0; i < N; ++i) nrm[i * 3 + 2] = (i & 1) ? -1.0f : 1.0f;
    d.cluster_count = 2;
    d.metric = GIM_KMEANS_METRIC_SSVP;
    km_out_init(&o, N, 2);
    km_run(&d, &o);
    for (i = 0; i < N; ++i) assert_int_equal(o.assignment[i], (i & 1) ? o.assignment[1] : o.assignment[0]);
    assert_int_not_equal(o.assignment[0], o.assignment[1]);
    assert_int_equal(o.counts[0], N / 2);
    km_out_free(&o);
}

/* Zero flux: weights fall back to 1, so the result equals the unweighted (flux NULL) one
   bit for bit, with zero summed flux; a zero-flux cluster beside lit ones takes its plain mean. */
static void zero_flux(void **state) {
    km_scene s;
    km_out a, b;
    gim_kmeans_desc d;
    uint32_t i;
    float *zero;
    (void)state;
    scene_make(&s, 1024, 8);
    zero = (float *)calloc((size_t)s.n * 3, sizeof(float));
    assert_non_null(zero);
    d = scene_desc(&s, 16);
    km_out_init(&a, s.n, 16); km_out_init(&b, s.n, 16);
    d.flux = zero;
    km_run(&d, &a);
    d.flux = NULL;
    km_run(&d, &b);
    assert_memory_equal(a.centres, b.centres, 16 * 3 * sizeof(float));
    assert_memory_equal(a.normals, b.normals, 16 * 3 * sizeof(float));
    assert_memory_equal(a.sigma, b.sigma, 16 * 3 * sizeof(float));
    assert_memory_equal(a.area, b.area, 16 * sizeof(float));
    assert_memory_equal(a.assignment, b.assignment, s.n * sizeof(uint32_t));
    for (i = 0; i < 16 * 3; ++i) assert_true(a.flux[i] == 0.0f && b.flux[i] == 0.0f); /* NULL flux: none summed */
    km_out_free(&a); km_out_free(&b);
    free(zero);
    scene_free(&s);
    {
        /* two blobs: lit one (flux 1 at x = 0, flux 3 at x = 4), dark one at x = 100, 101, 105 */
        float pos[5 * 3] = {0, 0, 0, 4, 0, 0, 100, 0, 0, 101, 0, 0, 105, 0, 0};
        float nrm[5 * 3] = {0, 1, 0, 0.6f, 0.8f, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
        float flux[5 * 3] = {1, 1, 1, 3, 3, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.flux = flux; d.vpl_count = 5; d.cluster_count = 2;
        km_out_init(&a, 5, 2);
        km_run(&d, &a);
        assert_int_equal(a.assignment[0], 0); assert_int_equal(a.assignment[4], 1);
        assert_true(a.centres[0] == 3.0f);                 /* (1*0 + 3*4) / 4 */
        assert_true(fabsf(a.sigma[0] - sqrtf(3.0f)) < 1e-6f); /* (1*9 + 3*1) / 4 = 3 */
        assert_true(fabsf(a.centres[3] - 102.0f) < 1e-5f);  /* plain mean of 100, 101, 105 */
        assert_true(fabsf(a.sigma[3] - sqrtf(14.0f / 3.0f)) < 1e-5f);
        assert_true(a.flux[0] == 4.0f && a.flux[3] == 0.0f);
        /* flux-weighted normal: 1 * (0, 1, 0) + 3 * (0.6, 0.8, 0) = (1.8, 3.4, 0) */
        assert_true(fabs(a.normals[0] - 1.8 / sqrt(1.8 * 1.8 + 3.4 * 3.4)) < 1e-6);
        km_out_free(&a);
    }
}

/* The smallest rectangle bounding points projected on the plane of the normal: a W x H grid
   rotated in a tilted plane has area W * H whatever the in-plane rotation; random points
   match a brute-force search over all point-pair directions. */
static void area_of_rectangle(void **state) {
    enum { G = 21, N = G * G };
    float pos[(N + 2) * 3], nrm[(N + 2) * 3];
    gim_vec3 n = gim_v3_normalize(gim_v3(0.3f, 0.8f, -0.5f)), t, b;
    gim_kmeans_desc d;
    km_out o;
    uint32_t i, k;
    const double W = 3.0, H = 1.25;
    (void)state;
    gim__basis(n, &t, &b);
    for (k = 0; k < 4; ++k) {
        double rot = 0.37 * k, ct = cos(rot), st = sin(rot);
        gim_vec3 u = gim__v3_add(gim__v3_scale(t, (float)ct), gim__v3_scale(b, (float)st));
        gim_vec3 v = gim__v3_cross(n, u);
        for (i = 0; i < N; ++i) {
            float su = (float)(W * ((i % G) / (double)(G - 1) - 0.5)), sv = (float)(H * ((i / G) / (double)(G - 1) - 0.5));
            gim_vec3 p = gim__v3_add(gim_v3(5, -2, 9), gim__v3_add(gim__v3_scale(u, su), gim__v3_scale(v, sv)));
            pos[i * 3] = p.x; pos[i * 3 + 1] = p.y; pos[i * 3 + 2] = p.z;
            nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z;
        }
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.vpl_count = N; d.cluster_count = 1;
        km_out_init(&o, N, 1);
        km_run(&d, &o);
        assert_true(fabs(o.area[0] - W * H) < 1e-5 * W * H);
        /* sigma of the uniform grid: spacing h, G points: h * sqrt((G^2 - 1) / 12) along u;
           per world axis it is the projection of the in-plane covariance */
        {
            double su2 = (W / (G - 1)) * (W / (G - 1)) * (G * G - 1) / 12.0, sv2 = (H / (G - 1)) * (H / (G - 1)) * (G * G - 1) / 12.0;
            double ex = sqrt(u.x * u.x * su2 + v.x * v.x * sv2), ey = sqrt(u.y * u.y * su2 + v.y * v.y * sv2);
            assert_true(fabs(o.sigma[0] - ex) < 1e-5 && fabs(o.sigma[1] - ey) < 1e-5);
        }
        km_out_free(&o);
        /* with flux, two more VPLs of zero flux outside the rectangle: they emit nothing and
           leave the VAL as it was; without flux they widen it */
        {
            static float flux[(N + 2) * 3];
            gim_vec3 q0 = gim__v3_add(gim_v3(5, -2, 9), gim__v3_scale(u, (float)W)), q1 = gim__v3_sub(gim_v3(5, -2, 9), gim__v3_scale(v, (float)H));
            for (i = 0; i < (N + 2) * 3; ++i) flux[i] = i < N * 3 ? 0.25f : 0.0f;
            pos[N * 3] = q0.x; pos[N * 3 + 1] = q0.y; pos[N * 3 + 2] = q0.z;
            pos[N * 3 + 3] = q1.x; pos[N * 3 + 4] = q1.y; pos[N * 3 + 5] = q1.z;
            for (i = N; i < N + 2; ++i) { nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z; }
            d.vpl_count = N + 2; d.flux = flux;
            km_out_init(&o, N + 2, 1);
            km_run(&d, &o);
            assert_true(fabs(o.area[0] - W * H) < 1e-5 * W * H);
            d.flux = NULL;
            km_run(&d, &o);
            assert_true(o.area[0] > 1.5 * W * H);
            d.vpl_count = N; d.flux = NULL;
        }
        km_out_free(&o);
    }
    /* random points on the plane vs brute force; the last sets lie on circles (every point on
       the hull: the rotating calipers turn all the way round) */
    test_rng_state = 44;
    for (k = 0; k < 8; ++k) {
        enum { R = 160 };
        double s2[R][2], best = 1e300;
        uint32_t p, q, r;
        for (i = 0; i < R; ++i) {
            double ang = 6.283185307179586 * test_rand01();
            float su = (float)(test_rand01() * 2 - 1), sv = (float)(test_rand01() * 2 - 1) * (float)(k + 1) * 0.3f;
            if (k >= 5) { su = (float)cos(ang); sv = (float)sin(ang) * (k == 7 ? 0.25f : 1.0f); }
            gim_vec3 pp = gim__v3_add(gim_v3(1, 2, 3), gim__v3_add(gim__v3_scale(t, su), gim__v3_scale(b, sv)));
            pos[i * 3] = pp.x; pos[i * 3 + 1] = pp.y; pos[i * 3 + 2] = pp.z;
            nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z;
        }
        for (i = 0; i < R; ++i) {
            gim_vec3 dd = gim__v3_sub(gim_v3(pos[i * 3], pos[i * 3 + 1], pos[i * 3 + 2]), gim_v3(1, 2, 3));
            s2[i][0] = gim__v3_dot(dd, t); s2[i][1] = gim__v3_dot(dd, b);
        }
        for (p = 0; p < R; ++p)
            for (q = p + 1; q < R; ++q) {
                double ux = s2[q][0] - s2[p][0], uy = s2[q][1] - s2[p][1], l = sqrt(ux * ux + uy * uy);
                double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
                ux /= l; uy /= l;
                for (r = 0; r < R; ++r) {
                    double uu = s2[r][0] * ux + s2[r][1] * uy, vv = s2[r][1] * ux - s2[r][0] * uy;
                    if (uu < u0) u0 = uu;
                    if (uu > u1) u1 = uu;
                    if (vv < v0) v0 = vv;
                    if (vv > v1) v1 = vv;
                }
                if ((u1 - u0) * (v1 - v0) < best) best = (u1 - u0) * (v1 - v0);
            }
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.vpl_count = R; d.cluster_count = 1;
        km_out_init(&o, R, 1);
        km_run(&d, &o);
        assert_true(fabs(o.area[0] - best) < 1e-5 * best);
        km_out_free(&o);
    }
}

/* Sigma of a known distribution: an axis-aligned 3D grid, spacing hx, hy, hz, with equal flux. */
static void sigma_of_grid(void **state) {
    enum { A = 5, B = 4, C = 3, N = A * B * C };
    float pos[N * 3], nrm[N * 3];
    gim_kmeans_desc d;
    km_out o;
    uint32_t i;
    (void)state;
    for (i = 0; i < N; ++i) {
        pos[i * 3] = 0.5f * (float)(i % A); pos[i * 3 + 1] = 2.0f * (float)((i / A) % B); pos[i * 3 + 2] = -100.0f + 0.25f * (float)(i / (A * B));
        nrm[i * 3] = 0; nrm[i * 3 + 1] = 1; nrm[i * 3 + 2] = 0;
    }
    memset(&d, 0, sizeof d);
    d.positions = pos; d.normals = nrm; d.vpl_count = N; d.cluster_count = 1;
    km_out_init(&o, N, 1);
    km_run(&d, &o);
    assert_true(fabs(o.sigma[0] - 0.5 * sqrt((A * A - 1) / 12.0)) < 1e-6);
    assert_true(fabs(o.sigma[1] - 2.0 * sqrt((B * B - 1) / 12.0)) < 1e-6);
    assert_true(fabs(o.sigma[2] - 0.25 * sqrt((C * C - 1) / 12.0)) < 1e-6);
    assert_true(fabs(o.centres[2] + 99.75) < 1e-5);
    /* normal +y: the plane is x-z, bounding rectangle 2 x 0.5 */
    assert_true(fabs(o.area[0] - 2.0 * 0.5) < 1e-6);
    km_out_free(&o);
}

/* Unit-free: positions and scene_scale times 1e-3 or 1e4, or positions moved by 1e5, give the
   same assignment; centres follow. Positions sit on a 1/64 grid so that the move is exact in
   float: the test asks for no precision loss beyond the input's own. */
static void scale_invariance(void **state) {
    static const double scales[3] = {1e-3, 1e4, 1.0};
    km_scene s;
    km_out ref, o;
    gim_kmeans_desc d;
    float *p2;
    uint32_t i, k, metric;
    (void)state;
    scene_make(&s, 2048, 31);
    for (i = 0; i < s.n * 3; ++i) s.pos[i] = floorf(s.pos[i] * 64.0f) / 64.0f;
    p2 = (float *)malloc((size_t)s.n * 3 * sizeof(float));
    assert_non_null(p2);
    km_out_init(&ref, s.n, 32); km_out_init(&o, s.n, 32);
    for (metric = GIM_KMEANS_METRIC_DONG; metric <= GIM_KMEANS_METRIC_SSVP; ++metric) {
        d = scene_desc(&s, 32);
        d.metric = (gim_kmeans_metric)metric; d.scene_scale = 17.3f; d.max_iterations = 64;
        km_run(&d, &ref);
        for (k = 0; k < 3; ++k) {
            double sc = scales[k], off = k == 2 ? 1e5 : 0.0;
            for (i = 0; i < s.n * 3; ++i) p2[i] = (float)(s.pos[i] * sc + off);
            d.positions = p2; d.scene_scale = (float)(17.3 * sc);
            km_run(&d, &o);
            assert_memory_equal(o.assignment, ref.assignment, s.n * sizeof(uint32_t));
            assert_int_equal(o.r.iterations, ref.r.iterations);
            for (i = 0; i < 32 * 3; ++i) {
                assert_true(fabs((o.centres[i] - off) / sc - ref.centres[i]) < (k == 2 ? 0.01 : 1e-4));
                assert_true(fabs(o.sigma[i] / sc - ref.sigma[i]) < 1e-4);
            }
            for (i = 0; i < 32; ++i) assert_true(fabs(o.area[i] / (sc * sc) - ref.area[i]) < 1e-4 * (1.0 + ref.area[i]));
        }
        /* the default scene scale (VPL bounds) is unit-free by itself */
        d.positions = s.pos; d.scene_scale = 0.0f;
        km_run(&d, &ref);
        for (i = 0; i < s.n * 3; ++i) p2[i] = (float)(s.pos[i] * 1e-3);
        d.positions = p2;
        km_run(&d, &o);
        assert_memory_equal(o.assignment, ref.assignment, s.n * sizeof(uint32_t));
    }
    free(p2);
    km_out_free(&ref); km_out_free(&o);
    scene_free(&s);
}

/* Every bad argument: an error code, one logged message naming gim_kmeans, outputs untouched. */
static void argument_errors(void **state) {
    float pos[4 * 3] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    float nrm[4 * 3] = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
    float flux[4 * 3] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    float cen[2 * 3] = {0, 0, 0, 1, 1, 0}, cn[2 * 3] = {0, 0, 1, 0, 0, 1};
    float bad[4 * 3];
    float out_c[2 * 3], out_n[2 * 3];
    gim_kmeans_result r;
    gim_kmeans_desc d, base;
    test_alloc_stats st;
    test_log lg;
    int c;
    (void)state;
    memset(&base, 0, sizeof base);
    base.positions = pos; base.normals = nrm; base.flux = flux; base.vpl_count = 4; base.cluster_count = 2;
    base.env = test_env(&st, &lg);
    for (c = 0; c < 24; ++c) {
        gim_result want = GIM_ERROR_INVALID_ARGUMENT, got;
        const char *what = "";
        d = base;
        memset(&r, 0, sizeof r);
        r.centres = out_c; r.normals = out_n; r.iterations = 77;
        memcpy(bad, pos, sizeof bad);
        memset(out_c, 0x5a, sizeof out_c); memset(out_n, 0x5a, sizeof out_n);
        switch (c) {
        case 0: d.positions = NULL; what = "positions"; break;
        case 1: d.normals = NULL; what = "normals"; break;
        case 2: d.vpl_count = 0; what = "vpl_count"; break;
        case 3: d.cluster_count = 0; what = "cluster_count"; break;
        case 4: d.cluster_count = 5; what = "cluster_count 5 > vpl_count 4"; break;
        case 5: bad[4] = NAN; d.positions = bad; what = "position of VPL 1"; break;
        case 6: bad[11] = INFINITY; d.positions = bad; what = "position of VPL 3"; break;
        case 7: bad[2] = NAN; d.normals = bad; what = "normal of VPL 0"; break;
        case 8: memset(bad, 0, sizeof bad); d.normals = bad; what = "normal of VPL 0 is zero"; break;
        case 9: memcpy(bad, flux, sizeof bad); bad[5] = -1.0f; d.flux = bad; what = "flux of VPL 1"; break;
        case 10: memcpy(bad, flux, sizeof bad); bad[0] = NAN; d.flux = bad; what = "flux of VPL 0"; break;
        case 11: d.metric = (gim_kmeans_metric)7; what = "metric"; break;
        case 12: d.init = (gim_kmeans_init)9; what = "init"; break;
        case 13: d.init = GIM_KMEANS_INIT_WARM; what = "init_centres"; break;
        case 14: d.init = GIM_KMEANS_INIT_WARM; d.init_centres = cen; d.init_normals = cn; cen[1] = NAN; what = "init centre"; break;
        case 15: cen[1] = 0; d.init = GIM_KMEANS_INIT_WARM; d.init_centres = cen; d.init_normals = bad; memset(bad, 0, sizeof bad); what = "init normal 0 is zero"; break;
        case 16: d.w_x = -1.0f; what = "weights"; break;
        case 17: d.w_a = NAN; what = "weights"; break;
        case 18: d.scene_scale = -2.0f; what = "scene_scale"; break;
        case 19: d.scene_scale = INFINITY; what = "scene_scale"; break;
        case 20: d.max_iterations = 100000; want = GIM_ERROR_OUT_OF_RANGE; what = "max_iterations"; break;
        case 21: memcpy(bad, flux, sizeof bad); bad[3] = 3e38f; bad[6] = 3e38f; d.flux = bad; want = GIM_ERROR_OUT_OF_RANGE; what = "flux"; break;
        case 22: bad[0] = -1e20f; bad[3] = 1e20f; d.positions = bad; want = GIM_ERROR_OUT_OF_RANGE; what = "diagonal"; break;
        case 23: r.normals = NULL; what = "result->normals"; break;
        }
        memset(&lg, 0, sizeof lg);
        got = gim_kmeans(&d, &r);
        assert_int_equal(got, want);
        assert_int_equal(lg.errors, 1);
        assert_non_null(strstr(lg.last, "gim_kmeans"));
        if (!strstr(lg.last, what)) fail_msg("case %d: '%s' lacks '%s'", c, lg.last, what);
        assert_int_equal(r.iterations, 77);
        {
            unsigned char pat[sizeof out_c];
            memset(pat, 0x5a, sizeof pat);
            assert_memory_equal(out_c, pat, sizeof out_c);
            assert_memory_equal(out_n, pat, sizeof out_n);
        }
        assert_int_equal(st.live, 0);
    }
    /* NULL desc or result: an error, no crash */
    assert_int_equal(gim_kmeans(NULL, &r), GIM_ERROR_INVALID_ARGUMENT);
    memset(&lg, 0, sizeof lg);
    assert_int_equal(gim_kmeans(&base, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 1);
    /* huge but valid values: 1e19 apart, flux near FLT_MAX in total: fine, finite outputs */
    {
        km_out o;
        float fp[4 * 3] = {-5e18f, 0, 0, 5e18f, 0, 0, 0, 1e-30f, 0, 1e-30f, 0, 0};
        float ff[4 * 3] = {1e38f, 0, 0, 1e38f, 0, 0, 1e38f, 1e-45f, 0, 0, 0, 0};
        d = base; d.positions = fp; d.flux = ff;
        km_out_init(&o, 4, 2);
        km_run(&d, &o);
        km_out_free(&o);
    }
}

/* Hostile but valid input: random mixes of denormal and huge coordinates, tiny normals,
   duplicates, zero and huge flux, both metrics and inits, odd weights and scales: every result
   keeps the invariants km_run checks (finite, unit normals, counts >= 1 consistent). */
static void extreme_values(void **state) {
    enum { NMAX = 97 };
    static const float mags[6] = {1e-38f, 1e-20f, 1.0f, 1e6f, 1e12f, 4e18f};
    float pos[NMAX * 3], nrm[NMAX * 3], flux[NMAX * 3], cen[NMAX * 3], cn[NMAX * 3];
    uint32_t round, i;
    (void)state;
    test_rng_state = 555;
    for (round = 0; round < 300; ++round) {
        gim_kmeans_desc d;
        km_out o;
        uint32_t n = 1 + (uint32_t)(test_rand01() * NMAX), m = 1 + (uint32_t)(test_rand01() * n);
        float mag = mags[(int)(test_rand01() * 6)];
        if (m > n) m = n;
        for (i = 0; i < n * 3; ++i) {
            double u = test_rand01();
            pos[i] = u < 0.2 && i >= 3 ? pos[i - 3] : (float)((test_rand01() - 0.5) * mag); /* duplicates */
            nrm[i] = (float)((test_rand01() - 0.5) * (u < 0.5 ? 1e-30 : 1.0));
            flux[i] = u < 0.3 ? 0.0f : (float)(test_rand01() * (u > 0.95 ? 1e36 : 1.0));
            cen[i] = (float)((test_rand01() - 0.5) * mag * 3.0);
            cn[i] = (float)(test_rand01() - 0.5);
        }
        for (i = 0; i < n; ++i) if (nrm[i * 3] == 0.0f && nrm[i * 3 + 1] == 0.0f && nrm[i * 3 + 2] == 0.0f) nrm[i * 3] = 1e-40f;
        for (i = 0; i < m; ++i) if (cn[i * 3] == 0.0f && cn[i * 3 + 1] == 0.0f && cn[i * 3 + 2] == 0.0f) cn[i * 3] = 1.0f;
        memset(&d, 0, sizeof d);
        d.positions = pos; d.normals = nrm; d.flux = (round & 1) ? flux : NULL;
        d.vpl_count = n; d.cluster_count = m;
        d.metric = (gim_kmeans_metric)(round % 3);
        d.init = (round & 2) ? GIM_KMEANS_INIT_WARM : GIM_KMEANS_INIT_FIXED;
        d.init_centres = cen; d.init_normals = cn;
        d.w_x = (round % 5 == 0) ? 0.0f : (float)test_rand01();
        d.w_a = (round % 7 == 0) ? 0.0f : (float)test_rand01();
        d.scene_scale = (round % 4 == 0) ? 0.0f : mag * (float)test_rand01() * 1e-3f + 1e-45f;
        d.max_iterations = 1 + round % 20;
        km_out_init(&o, n, m);
        km_run(&d, &o);
        km_out_free(&o);
    }
}

/* Allocation: nothing leaks, every allocation failing returns OUT_OF_MEMORY cleanly. */
static void allocation(void **state) {
    km_scene s;
    km_out o;
    gim_kmeans_desc d;
    test_alloc_stats st;
    test_log lg;
    long k, total;
    (void)state;
    scene_make(&s, 512, 2);
    d = scene_desc(&s, 8);
    km_out_init(&o, s.n, 8);
    d.env = test_env(&st, &lg);
    assert_int_equal(gim_kmeans(&d, &o.r), GIM_OK);
    total = st.allocs;
    assert_true(total >= 1);
    assert_int_equal(st.live, 0);
    for (k = 0; k < total; ++k) {
        d.env = test_env(&st, &lg);
        st.fail_after = k;
        o.r.iterations = 99;
        assert_int_equal(gim_kmeans(&d, &o.r), GIM_ERROR_OUT_OF_MEMORY);
        assert_int_equal(st.live, 0);
        assert_int_equal(lg.errors, 1);
        assert_non_null(strstr(lg.last, "GIM_ERROR_OUT_OF_MEMORY"));
        assert_int_equal(o.r.iterations, 99);
    }
    /* without area the work needs less memory; still no leak */
    d.env = test_env(&st, &lg);
    o.r.area = NULL;
    assert_int_equal(gim_kmeans(&d, &o.r), GIM_OK);
    assert_int_equal(st.live, 0);
    km_out_free(&o);
    scene_free(&s);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(blobs_recovered),
        cmocka_unit_test(normals_split_coplanar_sets),
        cmocka_unit_test(dong_metric_terms),
        cmocka_unit_test(ssvp_metric_terms),
        cmocka_unit_test(deterministic),
        cmocka_unit_test(fixed_init_temporal_coherence),
        cmocka_unit_test(warm_start_fewer_iterations),
        cmocka_unit_test(empty_clusters_repaired),
        cmocka_unit_test(m_equals_n),
        cmocka_unit_test(coincident_points),
        cmocka_unit_test(zero_flux),
        cmocka_unit_test(area_of_rectangle),
        cmocka_unit_test(sigma_of_grid),
        cmocka_unit_test(scale_invariance),
        cmocka_unit_test(argument_errors),
        cmocka_unit_test(extreme_values),
        cmocka_unit_test(allocation),
    };
    return cmocka_run_group_tests_name("kmeans", tests, NULL, NULL);
}
