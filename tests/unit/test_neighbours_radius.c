/* gim_cache_neighbours with a search radius (max_distance): exactly the unlimited O(V x C)
   answer cut to the caches within the radius, bit for bit, at several radii, scales and
   offsets; the boundary is inclusive; receivers that are points with normals and no mesh;
   bad radii are errors; no leaks, out-of-memory handled. The CPU twin of a per-pixel
   neighbour search on the GPU. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* ---- the reference: every receiver against every cache (the header's definitions), then
   the row cut to squared distance <= max_distance^2 ---- */

typedef struct nb_rows {
    uint32_t *index, *count;
    float *dmax;
    double *d2;              /* the reference's squared distances, row-major like index */
    gim_neighbour_result r;
} nb_rows;

static void rows_alloc(nb_rows *o, uint32_t V, uint32_t n) {
    o->index = (uint32_t *)malloc(sizeof(uint32_t) * V * n);
    o->count = (uint32_t *)malloc(sizeof(uint32_t) * V);
    o->dmax = (float *)malloc(sizeof(float) * V);
    o->d2 = (double *)malloc(sizeof(double) * V * n);
    assert_non_null(o->index); assert_non_null(o->count); assert_non_null(o->dmax); assert_non_null(o->d2);
    o->r.index = o->index; o->r.count = o->count; o->r.d_cmax = o->dmax;
}
static void rows_free(nb_rows *o) { free(o->index); free(o->count); free(o->dmax); free(o->d2); }

/* Unlimited: the n nearest compatible caches by (squared distance in double, index). */
static void brute_force(const float *pos, const float *nrm, uint32_t V, const gim_cache *caches, uint32_t C,
                        uint32_t n, double theta, nb_rows *out) {
    double cos_t = theta >= 3.14159265358979 ? -2.0 : cos(theta);
    uint32_t v, c, k;
    gim_vec3 *cn = (gim_vec3 *)malloc(sizeof(gim_vec3) * C);
    for (c = 0; c < C; ++c) cn[c] = gim_v3_normalize(gim_v3(caches[c].normal[0], caches[c].normal[1], caches[c].normal[2]));
    for (v = 0; v < V; ++v) {
        double bd[GIM_MAX_NEIGHBOUR_CACHES];
        uint32_t bi[GIM_MAX_NEIGHBOUR_CACHES], found = 0;
        gim_vec3 nv = gim_v3_normalize(gim_v3(nrm[v * 3], nrm[v * 3 + 1], nrm[v * 3 + 2]));
        int any = nv.x == 0.0f && nv.y == 0.0f && nv.z == 0.0f;
        int finite = isfinite(pos[v * 3]) && isfinite(pos[v * 3 + 1]) && isfinite(pos[v * 3 + 2]);
        for (c = 0; finite && c < C; ++c) {
            gim_vec3 nc = cn[c];
            double dx = (double)pos[v * 3] - caches[c].position[0];
            double dy = (double)pos[v * 3 + 1] - caches[c].position[1];
            double dz = (double)pos[v * 3 + 2] - caches[c].position[2];
            double d2 = dx * dx + dy * dy + dz * dz;
            if (!any && (double)nv.x * nc.x + (double)nv.y * nc.y + (double)nv.z * nc.z < cos_t) continue;
            /* caches come by index, so a tie keeps the earlier */
            k = found < n ? found++ : n;
            if (k == n) { if (!(d2 < bd[n - 1])) continue; k = n - 1; }
            while (k > 0 && bd[k - 1] > d2) { bd[k] = bd[k - 1]; bi[k] = bi[k - 1]; --k; }
            bd[k] = d2; bi[k] = c;
        }
        for (k = 0; k < n; ++k) {
            out->index[v * n + k] = k < found ? bi[k] : UINT32_MAX;
            out->d2[v * n + k] = k < found ? bd[k] : HUGE_VAL;
        }
        out->count[v] = found;
        out->dmax[v] = found ? (float)sqrt(bd[found - 1]) : 0.0f;
    }
    free(cn);
}

/* The unlimited rows `all` cut to the entries within radius (0: no cut). */
static void truncate_rows(const nb_rows *all, uint32_t V, uint32_t n, float radius, nb_rows *out) {
    double r2 = radius > 0.0f ? (double)radius * radius : HUGE_VAL;
    uint32_t v, k;
    for (v = 0; v < V; ++v) {
        uint32_t keep = 0;
        while (keep < all->count[v] && all->d2[v * n + keep] <= r2) ++keep;
        for (k = 0; k < n; ++k) {
            out->index[v * n + k] = k < keep ? all->index[v * n + k] : UINT32_MAX;
            out->d2[v * n + k] = k < keep ? all->d2[v * n + k] : HUGE_VAL;
        }
        out->count[v] = keep;
        out->dmax[v] = keep ? (float)sqrt(all->d2[v * n + keep - 1]) : 0.0f;
    }
}

static void expect_equal(const nb_rows *got, const nb_rows *want, uint32_t V, uint32_t n) {
    uint32_t v;
    for (v = 0; v < V; ++v) {
        if (got->count[v] != want->count[v] || memcmp(got->index + v * n, want->index + v * n, n * sizeof(uint32_t)) != 0 ||
            memcmp(&got->dmax[v], &want->dmax[v], sizeof(float)) != 0) {
            print_error("receiver %u: count %u vs %u, first %u vs %u, d %.9g vs %.9g\n", v, got->count[v], want->count[v],
                        got->index[v * n], want->index[v * n], (double)got->dmax[v], (double)want->dmax[v]);
            fail();
        }
    }
}

/* ---- scenes ---- */

static float urand(float a, float b) { return a + (b - a) * (float)test_rand01(); }

/* caches on the faces of the box [o, o + s]^3 (normals with a little noise), every 10th
   anywhere inside with a random normal */
static gim_cache *box_caches(uint32_t C, float o, float s) {
    gim_cache *c = (gim_cache *)malloc(sizeof(gim_cache) * C);
    uint32_t i;
    for (i = 0; i < C; ++i) {
        gim_vec3 nrm, p;
        if (i % 10 == 9) {
            nrm = gim_v3_normalize(gim_v3(urand(-1, 1), urand(-1, 1), urand(-1, 1)));
            p = gim_v3(urand(0, 1), urand(0, 1), urand(0, 1));
        } else {
            int face = (int)(test_rand01() * 6), a = face >> 1;
            float q[3], nn[3] = {0, 0, 0};
            q[0] = urand(0, 1); q[1] = urand(0, 1); q[2] = urand(0, 1);
            q[a] = (face & 1) ? 1.0f : 0.0f;
            nn[a] = (face & 1) ? 1.0f : -1.0f;
            nn[(a + 1) % 3] += urand(-0.2f, 0.2f);
            p = gim_v3(q[0], q[1], q[2]);
            nrm = gim_v3_normalize(gim_v3(nn[0], nn[1], nn[2]));
        }
        c[i].position[0] = o + s * p.x; c[i].position[1] = o + s * p.y; c[i].position[2] = o + s * p.z;
        c[i].normal[0] = nrm.x; c[i].normal[1] = nrm.y; c[i].normal[2] = nrm.z;
        c[i].area = s * s * 6.0f / (float)C;
        c[i].reflectance = 0.5f;
    }
    return c;
}

/* Receivers: 3 in 4 on the box faces with face normals (noisy, unnormalised); the rest in and
   around the box with random normals, every 64th far away; every 50th a zero normal (any
   cache). The last 200 are a raster of one face in scanline order, as G-buffer pixels come,
   so consecutive receivers share caches (the previous-receiver bound of the search). */
static void receivers(float *pos, float *nrm, uint32_t V, float o, float s) {
    uint32_t v, raster = V > 400 ? 200 : 0;
    for (v = 0; v < V; ++v) {
        gim_vec3 p, n;
        if (v >= V - raster) {
            uint32_t k = v - (V - raster);
            p = gim_v3((float)(k % 20) / 19.0f, (float)(k / 20) / 9.0f, 0.0f);
            n = gim_v3(0.0f, 0.0f, -1.0f);
        } else if (v % 4 == 3) {
            p = gim_v3(urand(-0.5f, 1.5f), urand(-0.5f, 1.5f), urand(-0.5f, 1.5f));
            n = gim_v3_normalize(gim_v3(urand(-1, 1), urand(-1, 1), urand(-1, 1)));
            if (v % 64 == 7) p = gim_v3(urand(-20, 20), urand(-20, 20), 30.0f);
        } else {
            int face = (int)(test_rand01() * 6), a = face >> 1;
            float q[3], nn[3] = {0, 0, 0};
            q[0] = urand(0, 1); q[1] = urand(0, 1); q[2] = urand(0, 1);
            q[a] = (face & 1) ? 1.0f : 0.0f;
            nn[a] = (face & 1) ? 2.0f : -2.0f;
            nn[(a + 2) % 3] += urand(-0.3f, 0.3f);
            p = gim_v3(q[0], q[1], q[2]);
            n = gim_v3(nn[0], nn[1], nn[2]);
        }
        if (v % 50 == 49) n = gim_v3(0.0f, 0.0f, 0.0f);
        pos[v * 3] = o + s * p.x; pos[v * 3 + 1] = o + s * p.y; pos[v * 3 + 2] = o + s * p.z;
        nrm[v * 3] = n.x; nrm[v * 3 + 1] = n.y; nrm[v * 3 + 2] = n.z;
    }
}

/* One scene (offset o, scale s) at radii given in box sides: each against the cut brute force.
   Radius "below all" is half the smallest receiver-to-cache distance: every row empty (not
   possible, and skipped, when float rounding puts a receiver exactly on a cache); returns 1
   when it ran. */
static int compare_scene(uint32_t C, uint32_t V, uint32_t n, float theta, float o, float s) {
    static const float radii[] = {0.0f, 0.02f, 0.08f, 0.25f, 0.6f, 100.0f};
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    float *pos = (float *)malloc(sizeof(float) * 3 * V), *nrm = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_rows all, want, got;
    uint32_t v, c, ri, total_all = 0;
    double min_d2 = HUGE_VAL;
    memset(&set, 0, sizeof set);
    set.caches = box_caches(C, o, s);
    set.count = C;
    set.theta_eps = 0.5f;
    receivers(pos, nrm, V, o, s);
    rows_alloc(&all, V, n); rows_alloc(&want, V, n); rows_alloc(&got, V, n);
    brute_force(pos, nrm, V, set.caches, C, n, theta, &all);
    for (v = 0; v < V; ++v) {
        total_all += all.count[v];
        for (c = 0; c < C; ++c) {
            double dx = (double)pos[v * 3] - set.caches[c].position[0], dy = (double)pos[v * 3 + 1] - set.caches[c].position[1];
            double dz = (double)pos[v * 3 + 2] - set.caches[c].position[2], d2 = dx * dx + dy * dy + dz * dz;
            if (d2 < min_d2) min_d2 = d2;
        }
    }
    if (C >= 500) assert_true(total_all > V * n / 2);   /* the scene is not trivially empty */
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V;
    d.caches = &set; d.n = n; d.theta_eps = theta; d.env = env;
    for (ri = 0; ri <= sizeof radii / sizeof radii[0] - (min_d2 > 0.0 ? 0u : 1u); ++ri) {
        uint32_t total = 0;
        int below_all = ri == sizeof radii / sizeof radii[0];
        float radius = below_all ? (float)(0.5 * sqrt(min_d2)) : radii[ri] * s;
        d.max_distance = radius;
        assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_OK);
        truncate_rows(&all, V, n, radius, &want);
        expect_equal(&got, &want, V, n);
        for (v = 0; v < V; ++v) total += got.count[v];
        if (!below_all && (ri == 0 || radii[ri] >= 100.0f)) assert_int_equal(total, total_all); /* no limit / all within */
        else if (!below_all) assert_true(total < total_all && (radii[ri] < 0.05f || total > 0));
        else {
            assert_true(radius > 0.0f);
            for (v = 0; v < V; ++v) {
                assert_int_equal(got.count[v], 0);
                assert_true(got.dmax[v] == 0.0f);
                for (c = 0; c < n; ++c) assert_int_equal(got.index[v * n + c], UINT32_MAX);
            }
        }
    }
    assert_int_equal(lg.errors, 0);
    assert_int_equal(st.live, 0);
    rows_free(&all); rows_free(&want); rows_free(&got);
    free(set.caches); free(pos); free(nrm);
    return min_d2 > 0.0;
}

static void equals_truncated_brute_force(void **state) {
    int below_all = 0;
    (void)state;
    below_all += compare_scene(1500, 1500, 16, 1.0f, 0.0f, 1.0f);
    below_all += compare_scene(600, 1200, 1, 0.5f, 0.0f, 1.0f);
    below_all += compare_scene(2000, 1000, 7, 3.14159265f, -3.0f, 2.0f);   /* every normal compatible */
    below_all += compare_scene(40, 800, 16, 0.8f, 0.0f, 1.0f);             /* few caches: rows short of n */
    assert_int_equal(below_all, 4);
}

static void equals_truncated_far_and_scaled(void **state) {
    int below_all = 0;
    (void)state;
    below_all += compare_scene(1200, 1000, 16, 0.7f, 1e5f, 1.0f);          /* far from the origin */
    below_all += compare_scene(1200, 1000, 16, 0.7f, 0.0f, 1e-3f);         /* millimetres */
    below_all += compare_scene(1200, 1000, 16, 0.7f, 0.0f, 1e4f);          /* kilometres */
    below_all += compare_scene(800, 800, 16, 0.7f, 1e5f, 1e-3f);           /* small and far */
    assert_true(below_all >= 2);
}

/* The radius is inclusive, and exact: caches at integer offsets 3, 4 and 5 along an axis
   (d2 = 9, 16, 25 exactly); radius 4 keeps two, the float just below 4 keeps one. */
static void boundary_inclusive(void **state) {
    gim_cache caches[3];
    float pos[3] = {10.0f, -2.0f, 7.0f}, nrm[3] = {0.0f, 1.0f, 0.0f};
    gim_cache_set set;
    gim_neighbour_desc d;
    uint32_t index[4], count;
    float dmax;
    gim_neighbour_result r;
    int i;
    (void)state;
    memset(caches, 0, sizeof caches);
    for (i = 0; i < 3; ++i) {
        caches[i].position[0] = 10.0f; caches[i].position[1] = -2.0f; caches[i].position[2] = 7.0f;
        caches[i].normal[1] = 1.0f;
        caches[i].area = 1.0f;
    }
    caches[0].position[2] += 5.0f;   /* index 0 farthest, so the order is by distance */
    caches[1].position[0] -= 3.0f;
    caches[2].position[1] += 4.0f;
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = 3;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 1;   /* a point, no triangles */
    d.caches = &set; d.n = 4; d.theta_eps = 0.1f;
    r.index = index; r.count = &count; r.d_cmax = &dmax;
    d.max_distance = 4.0f;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count, 2);
    assert_int_equal(index[0], 1); assert_int_equal(index[1], 2);
    assert_int_equal(index[2], UINT32_MAX); assert_int_equal(index[3], UINT32_MAX);
    assert_true(dmax == 4.0f);
    d.max_distance = nextafterf(4.0f, 0.0f);
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count, 1);
    assert_true(dmax == 3.0f);
    d.max_distance = 5.0f;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count, 3);
    assert_int_equal(index[2], 0);
    d.max_distance = 2.0f;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count, 0);
    assert_true(dmax == 0.0f);
    for (i = 0; i < 4; ++i) assert_int_equal(index[i], UINT32_MAX);
    /* two caches at the same distance on the boundary: both in, by index */
    caches[0].position[2] = 7.0f; caches[0].position[0] = 13.0f;   /* now 3 away, like cache 1 */
    d.max_distance = 3.0f;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count, 2);
    assert_int_equal(index[0], 0); assert_int_equal(index[1], 1);
}

/* Receivers that are points with normals (G-buffer pixels, probes): positions and normals,
   indices NULL and index_count 0 - accepted, the brute force's answer. With normals NULL the
   face normals need triangles: an error. */
static void points_without_mesh(void **state) {
    enum { C = 500, V = 700, N = 8 };
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    float *pos = (float *)malloc(sizeof(float) * 3 * V), *nrm = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_rows all, want, got;
    (void)state;
    memset(&set, 0, sizeof set);
    set.caches = box_caches(C, 2.0f, 3.0f);
    set.count = C;
    receivers(pos, nrm, V, 2.0f, 3.0f);
    rows_alloc(&all, V, N); rows_alloc(&want, V, N); rows_alloc(&got, V, N);
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V;
    d.mesh.indices = NULL; d.mesh.index_count = 0;
    d.caches = &set; d.n = N; d.theta_eps = 0.9f; d.env = env;
    brute_force(pos, nrm, V, set.caches, C, N, 0.9, &all);
    assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_OK);
    expect_equal(&got, &all, V, N);
    d.max_distance = 0.3f * 3.0f;
    assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_OK);
    truncate_rows(&all, V, N, d.max_distance, &want);
    expect_equal(&got, &want, V, N);
    assert_int_equal(lg.errors, 0);
    d.mesh.normals = NULL;
    assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 1);
    assert_int_equal(st.live, 0);
    rows_free(&all); rows_free(&want); rows_free(&got);
    free(set.caches); free(pos); free(nrm);
}

/* Bad radii: GIM_ERROR_INVALID_ARGUMENT through the logger, nothing allocated; -0 is 0 (no
   limit). Out of memory with a radius: GIM_ERROR_OUT_OF_MEMORY, nothing leaked. */
static void bad_radius_and_memory(void **state) {
    static const float bad[] = {-1.0f, -1e-30f, -FLT_MIN, NAN, INFINITY, -INFINITY};
    enum { C = 300, V = 200, N = 4 };
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    float *pos = (float *)malloc(sizeof(float) * 3 * V), *nrm = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_rows all, got;
    uint32_t i;
    long k;
    (void)state;
    memset(&set, 0, sizeof set);
    set.caches = box_caches(C, 0.0f, 1.0f);
    set.count = C;
    receivers(pos, nrm, V, 0.0f, 1.0f);
    rows_alloc(&all, V, N); rows_alloc(&got, V, N);
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V;
    d.caches = &set; d.n = N; d.theta_eps = 0.9f; d.env = env;
    for (i = 0; i < sizeof bad / sizeof bad[0]; ++i) {
        d.max_distance = bad[i];
        assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(lg.errors, (int)i + 1);
        assert_non_null(strstr(lg.last, "max_distance"));
    }
    assert_int_equal(st.allocs, 0);
    lg.errors = 0;
    brute_force(pos, nrm, V, set.caches, C, N, 0.9, &all);
    d.max_distance = -0.0f;
    assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_OK);
    expect_equal(&got, &all, V, N);
    d.max_distance = 0.2f;
    for (k = 0;; ++k) {
        gim_result r;
        st.fail_after = k;
        st.allocs = 0;
        r = gim_cache_neighbours(&d, &got.r);
        assert_int_equal(st.live, 0);
        if (r == GIM_OK) break;
        assert_int_equal(r, GIM_ERROR_OUT_OF_MEMORY);
        assert_true(k < 100);
    }
    assert_true(k > 0);
    rows_free(&all); rows_free(&got);
    free(set.caches); free(pos); free(nrm);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(equals_truncated_brute_force),
        cmocka_unit_test(equals_truncated_far_and_scaled),
        cmocka_unit_test(boundary_inclusive),
        cmocka_unit_test(points_without_mesh),
        cmocka_unit_test(bad_radius_and_memory),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
