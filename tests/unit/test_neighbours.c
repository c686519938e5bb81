/* Neighbour caches (eq. 8): the grid search equals an O(V x C) brute force, bit for bit, at
   any scale and offset; incompatible normals are excluded; errors, allocations, out-of-memory. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define PI_F 3.14159265358979f

/* ---- the reference: every vertex against every cache, same definitions as the header ---- */
static gim_vec3 ref_vertex_normal(const float *normals, uint32_t v) {
    return gim_v3_normalize(gim_v3(normals[v * 3], normals[v * 3 + 1], normals[v * 3 + 2]));
}

static void brute_force(const float *pos, const float *nrm, uint32_t V, const gim_cache *caches, uint32_t C,
                        uint32_t n, double theta, uint32_t *index, uint32_t *count, float *dmax) {
    double cos_t = theta >= 3.14159265358979 ? -2.0 : cos(theta);
    uint32_t v, c, k;
    gim_vec3 *cn = (gim_vec3 *)malloc(sizeof(gim_vec3) * C);
    for (c = 0; c < C; ++c) cn[c] = gim_v3_normalize(gim_v3(caches[c].normal[0], caches[c].normal[1], caches[c].normal[2]));
    for (v = 0; v < V; ++v) {
        double bd[16];
        uint32_t bi[16], found = 0;
        gim_vec3 nv = ref_vertex_normal(nrm, v);
        int any = nv.x == 0.0f && nv.y == 0.0f && nv.z == 0.0f;
        int finite = isfinite(pos[v * 3]) && isfinite(pos[v * 3 + 1]) && isfinite(pos[v * 3 + 2]);
        for (c = 0; finite && c < C; ++c) {
            gim_vec3 nc = cn[c];
            double dx = (double)pos[v * 3] - caches[c].position[0];
            double dy = (double)pos[v * 3 + 1] - caches[c].position[1];
            double dz = (double)pos[v * 3 + 2] - caches[c].position[2];
            double d2 = dx * dx + dy * dy + dz * dz;
            if (!any && (double)nv.x * nc.x + (double)nv.y * nc.y + (double)nv.z * nc.z < cos_t) continue;
            /* insertion into the sorted (d2, index) list: caches come by index, so a tie keeps the earlier */
            k = found < n ? found++ : n;
            if (k == n) { if (!(d2 < bd[n - 1])) continue; k = n - 1; }
            while (k > 0 && bd[k - 1] > d2) { bd[k] = bd[k - 1]; bi[k] = bi[k - 1]; --k; }
            bd[k] = d2; bi[k] = c;
        }
        for (k = 0; k < n; ++k) index[v * n + k] = k < found ? bi[k] : UINT32_MAX;
        count[v] = found;
        dmax[v] = found ? (float)sqrt(bd[found - 1]) : 0.0f;
    }
    free(cn);
}

static float urand(float a, float b) { return a + (b - a) * (float)test_rand01(); }

/* caches on the six faces of the box [o, o + s]^3 (jittered), normals of the faces with a
   little noise; plus a few with random normals anywhere inside */
static gim_cache *box_caches(uint32_t C, float o, float s, gim_env *env) {
    gim_cache *c = (gim_cache *)gim__alloc_array(env, C, sizeof(gim_cache));
    uint32_t i;
    if (!c) return NULL;
    for (i = 0; i < C; ++i) {
        gim_vec3 nrm, p;
        if (i % 10 == 9) {
            nrm = gim_v3_normalize(gim_v3(urand(-1, 1), urand(-1, 1), urand(-1, 1)));
            p = gim_v3(urand(0, 1), urand(0, 1), urand(0, 1));
        } else {
            int face = (int)(test_rand01() * 6), a = face >> 1;
            float side = (face & 1) ? 1.0f : 0.0f, q[3], nn[3] = {0, 0, 0};
            q[0] = urand(0, 1); q[1] = urand(0, 1); q[2] = urand(0, 1);
            q[a] = side;
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

/* vertices: near the box faces with face normals (some noisy), some anywhere in and around
   the box (up to half a box outside) with random normals, a few far away */
static void random_vertices(float *pos, float *nrm, uint32_t V, float o, float s) {
    uint32_t v;
    for (v = 0; v < V; ++v) {
        gim_vec3 p, n;
        if (v % 4 == 3) {
            p = gim_v3(urand(-0.5f, 1.5f), urand(-0.5f, 1.5f), urand(-0.5f, 1.5f));
            n = gim_v3_normalize(gim_v3(urand(-1, 1), urand(-1, 1), urand(-1, 1)));
            if (v % 64 == 7) p = gim_v3(urand(-20, 20), urand(-20, 20), 30.0f);
        } else {
            int face = (int)(test_rand01() * 6), a = face >> 1;
            float q[3], nn[3] = {0, 0, 0};
            q[0] = urand(0, 1); q[1] = urand(0, 1); q[2] = urand(0, 1);
            q[a] = (face & 1) ? 1.0f : 0.0f;
            nn[a] = (face & 1) ? 1.0f : -1.0f;
            nn[(a + 2) % 3] += urand(-0.3f, 0.3f);
            p = gim_v3(q[0], q[1], q[2]);
            n = gim_v3(nn[0], nn[1], nn[2]); /* not normalised: the search normalises */
        }
        pos[v * 3] = o + s * p.x; pos[v * 3 + 1] = o + s * p.y; pos[v * 3 + 2] = o + s * p.z;
        nrm[v * 3] = n.x; nrm[v * 3 + 1] = n.y; nrm[v * 3 + 2] = n.z;
    }
}

typedef struct nb_out {
    uint32_t *index, *count;
    float *dmax;
    gim_neighbour_result r;
} nb_out;

static void nb_out_alloc(nb_out *o, uint32_t V, uint32_t n) {
    o->index = (uint32_t *)malloc(sizeof(uint32_t) * V * n);
    o->count = (uint32_t *)malloc(sizeof(uint32_t) * V);
    o->dmax = (float *)malloc(sizeof(float) * V);
    assert_non_null(o->index); assert_non_null(o->count); assert_non_null(o->dmax);
    o->r.index = o->index; o->r.count = o->count; o->r.d_cmax = o->dmax;
}
static void nb_out_free(nb_out *o) { free(o->index); free(o->count); free(o->dmax); }

static void expect_equal(const nb_out *a, const nb_out *b, uint32_t V, uint32_t n) {
    uint32_t v;
    for (v = 0; v < V; ++v) {
        if (a->count[v] != b->count[v] || memcmp(a->index + v * n, b->index + v * n, n * sizeof(uint32_t)) != 0 ||
            memcmp(&a->dmax[v], &b->dmax[v], sizeof(float)) != 0) {
            print_error("vertex %u: count %u vs %u, first %u vs %u, d %.9g vs %.9g\n", v, a->count[v], b->count[v],
                        a->index[v * n], b->index[v * n], a->dmax[v], b->dmax[v]);
            fail();
        }
    }
}

/* One random scene at offset o and scale s against the brute force. */
static void compare_scene(uint32_t C, uint32_t V, uint32_t n, float theta, float o, float s) {
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    float *pos = (float *)malloc(sizeof(float) * 3 * V), *nrm = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out got, want;
    uint32_t v, found_total = 0;
    memset(&set, 0, sizeof set);
    set.caches = box_caches(C, o, s, &env);
    set.count = C;
    set.theta_eps = 0.5f;
    set.env = env;
    assert_non_null(set.caches);
    random_vertices(pos, nrm, V, o, s);
    nb_out_alloc(&got, V, n);
    nb_out_alloc(&want, V, n);
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V;
    d.caches = &set; d.n = n; d.theta_eps = theta; d.env = env;
    assert_int_equal(gim_cache_neighbours(&d, &got.r), GIM_OK);
    /* the default: twice the set's theta_eps, at most 90 degrees */
    brute_force(pos, nrm, V, set.caches, C, n, theta > 0.0f ? theta : fmin(2.0 * set.theta_eps, 1.57079632679489662),
                want.index, want.count, want.dmax);
    expect_equal(&got, &want, V, n);
    for (v = 0; v < V; ++v) {
        assert_true(isfinite(got.dmax[v]) && got.dmax[v] >= 0.0f);
        found_total += got.count[v];
    }
    assert_true(found_total > 0);
    if (C >= 500) assert_true(found_total > V * n / 2); /* the scene is not trivially empty */
    assert_int_equal(lg.errors, 0);
    gim__free(&env, set.caches);
    assert_int_equal(st.live, 0);
    nb_out_free(&got); nb_out_free(&want);
    free(pos); free(nrm);
}

static void equals_brute_force(void **state) {
    (void)state;
    compare_scene(2000, 3000, 16, 0.0f, 0.0f, 1.0f);       /* default theta from the set */
    compare_scene(500, 2000, 1, 0.3f, 0.0f, 1.0f);
    compare_scene(3000, 2000, 7, 1.2f, -3.0f, 2.0f);
    compare_scene(37, 1000, 16, 0.8f, 0.0f, 1.0f);         /* few caches: many vertices short of n */
    compare_scene(1, 100, 16, PI_F, 0.0f, 1.0f);           /* one cache, every normal compatible */
}
static void equals_brute_force_far_and_scaled(void **state) {
    (void)state;
    compare_scene(2000, 2000, 16, 0.6f, 1e5f, 1.0f);        /* far from the origin */
    compare_scene(2000, 2000, 16, 0.6f, -1e5f, 30.0f);
    compare_scene(2000, 2000, 16, 0.6f, 0.0f, 1e-3f);       /* millimetres */
    compare_scene(2000, 2000, 16, 0.6f, 0.0f, 1e4f);        /* kilometres */
    compare_scene(1000, 1000, 16, 0.6f, 1e5f, 1e-3f);       /* small and far: float spacing matters */
}

/* The same scene scaled by a power of two (exact in float) gives the same indices. */
static void unit_free(void **state) {
    enum { C = 800, V = 1000, N = 16 };
    float *pos = (float *)malloc(sizeof(float) * 3 * V), *nrm = (float *)malloc(sizeof(float) * 3 * V);
    float *pos2 = (float *)malloc(sizeof(float) * 3 * V);
    gim_cache *c2 = (gim_cache *)malloc(sizeof(gim_cache) * C);
    gim_cache_set set, set2;
    gim_neighbour_desc d;
    nb_out a, b;
    uint32_t i;
    (void)state;
    memset(&set, 0, sizeof set);
    set.caches = box_caches(C, 0.0f, 1.0f, NULL);
    set.count = C; set.theta_eps = 0.5f;
    random_vertices(pos, nrm, V, 0.0f, 1.0f);
    for (i = 0; i < C; ++i) {
        c2[i] = set.caches[i];
        c2[i].position[0] *= 1024.0f; c2[i].position[1] *= 1024.0f; c2[i].position[2] *= 1024.0f;
    }
    for (i = 0; i < 3 * V; ++i) pos2[i] = pos[i] * 1024.0f;
    set2 = set; set2.caches = c2;
    nb_out_alloc(&a, V, N); nb_out_alloc(&b, V, N);
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V; d.caches = &set;
    assert_int_equal(gim_cache_neighbours(&d, &a.r), GIM_OK);
    d.mesh.positions = pos2; d.caches = &set2;
    assert_int_equal(gim_cache_neighbours(&d, &b.r), GIM_OK);
    assert_memory_equal(a.index, b.index, sizeof(uint32_t) * V * N);
    assert_memory_equal(a.count, b.count, sizeof(uint32_t) * V);
    for (i = 0; i < V; ++i) assert_true(b.dmax[i] == a.dmax[i] * 1024.0f);
    /* and twice the same call: the same bits */
    assert_int_equal(gim_cache_neighbours(&d, &a.r), GIM_OK);
    assert_memory_equal(a.index, b.index, sizeof(uint32_t) * V * N);
    nb_out_free(&a); nb_out_free(&b);
    free(set.caches); free(c2); free(pos); free(nrm); free(pos2);
}

/* A thin wall: two faces 1e-3 of the grid spacing apart with opposite normals. A vertex on
   either face only ever gets its own face's caches, even though the other face's are nearer. */
static void thin_wall(void **state) {
    enum { G = 20, C = 2 * G * G, V = 400, N = 16 };
    gim_cache caches[C];
    float pos[V * 3], nrm[V * 3];
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    uint32_t i, k;
    (void)state;
    for (i = 0; i < C; ++i) {
        uint32_t side = i & 1u, cell = i >> 1;
        caches[i].position[0] = ((float)(cell % G) + 0.5f) / G;
        caches[i].position[1] = ((float)(cell / G) + 0.5f) / G;
        caches[i].position[2] = side ? 0.00005f : 0.0f;
        caches[i].normal[0] = 0.0f; caches[i].normal[1] = 0.0f; caches[i].normal[2] = side ? 1.0f : -1.0f;
        caches[i].area = 1.0f / (G * G); caches[i].reflectance = 1.0f;
    }
    for (i = 0; i < V; ++i) {
        uint32_t side = i & 1u;
        pos[i * 3] = urand(0, 1); pos[i * 3 + 1] = urand(0, 1);
        pos[i * 3 + 2] = side ? 0.00005f : 0.0f;
        nrm[i * 3] = 0.0f; nrm[i * 3 + 1] = 0.0f; nrm[i * 3 + 2] = side ? 1.0f : -1.0f;
    }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.5f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V; d.caches = &set;
    nb_out_alloc(&o, V, N);
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < V; ++i) {
        assert_int_equal(o.count[i], N);
        for (k = 0; k < N; ++k) assert_int_equal(o.index[i * N + k] & 1u, i & 1u);
        assert_true(o.dmax[i] > 1.0f / G && o.dmax[i] < 6.0f / G);
    }
    /* with theta_eps = pi both faces count, and the nearest come from both */
    d.theta_eps = PI_F;
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < V; ++i) {
        uint32_t odd = 0;
        for (k = 0; k < N; ++k) odd += o.index[i * N + k] & 1u;
        if (!(odd > 0 && odd < N)) { print_error("v %u odd %u count %u first %u\n", i, odd, o.count[i], o.index[i*N]); }
        assert_true(odd > 0 && odd < N);
    }
    nb_out_free(&o);
}

/* A smooth-shaded box: the vertex on an edge has a normal 45 degrees off both faces, the
   corner 54.7 degrees off all three. The default compatibility (2 x theta_eps = 60 degrees)
   finds caches on the adjacent faces; theta_eps itself (30 degrees) would find none. */
static void smooth_shaded_edges_and_corners(void **state) {
    enum { G = 8, C = 3 * G * G, N = 16 };
    gim_cache caches[C];
    float s3 = 0.57735027f, s2 = 0.70710678f;
    float pos[2 * 3] = {1.0f, 0.5f, 1.0f, 1.0f, 1.0f, 1.0f};
    float nrm[2 * 3];
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    uint32_t i, k, face_seen[2][3] = {{0, 0, 0}, {0, 0, 0}};
    (void)state;
    nrm[0] = s2; nrm[1] = 0.0f; nrm[2] = s2;
    nrm[3] = s3; nrm[4] = s3; nrm[5] = s3;
    for (i = 0; i < C; ++i) { /* G x G caches on each of the +x, +y, +z faces of the unit cube */
        uint32_t a = i / (G * G), c = i % (G * G);
        float q[3];
        q[a] = 1.0f;
        q[(a + 1) % 3] = ((float)(c % G) + 0.5f) / G;
        q[(a + 2) % 3] = ((float)(c / G) + 0.5f) / G;
        memcpy(caches[i].position, q, sizeof q);
        caches[i].normal[0] = caches[i].normal[1] = caches[i].normal[2] = 0.0f;
        caches[i].normal[a] = 1.0f;
        caches[i].area = 1.0f / (G * G); caches[i].reflectance = 1.0f;
    }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.5235988f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 2; d.caches = &set;
    nb_out_alloc(&o, 2, N);
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < 2; ++i) {
        assert_int_equal(o.count[i], N);
        for (k = 0; k < N; ++k) face_seen[i][o.index[i * N + k] / (G * G)]++;
    }
    assert_true(face_seen[0][0] > 0 && face_seen[0][2] > 0 && face_seen[0][1] == 0); /* edge: +x and +z */
    assert_true(face_seen[1][0] > 0 && face_seen[1][1] > 0 && face_seen[1][2] > 0);  /* corner: all three */
    d.theta_eps = set.theta_eps; /* explicitly 30 degrees: nothing is compatible */
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    assert_int_equal(o.count[0], 0); assert_int_equal(o.count[1], 0);
    assert_int_equal(o.index[0], UINT32_MAX);
    assert_true(o.dmax[0] == 0.0f);
    nb_out_free(&o);
}

/* Fewer compatible caches than n: count says how many, the rest is UINT32_MAX, d_c,max is
   the farthest found; ties are ordered by index. */
static void fewer_than_n_and_ties(void **state) {
    enum { C = 300, N = 16 };
    gim_cache caches[C];
    float pos[2 * 3] = {0.5f, 0.5f, 0.0f, 100.0f, -50.0f, 7.0f};
    float nrm[2 * 3] = {0.0f, 1.0f, 0.0f, 0.0f, 1.0f, 0.0f};
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    uint32_t i, k;
    (void)state;
    for (i = 0; i < C; ++i) { /* a plane of -y caches, with 5 +y caches among them */
        caches[i].position[0] = urand(0, 1); caches[i].position[1] = urand(0, 1); caches[i].position[2] = 0.0f;
        caches[i].normal[0] = 0.0f; caches[i].normal[1] = -1.0f; caches[i].normal[2] = 0.0f;
        caches[i].area = 1.0f; caches[i].reflectance = 0.5f;
    }
    for (i = 0; i < 5; ++i) caches[50 * i + 3].normal[1] = 1.0f;
    /* two of them at the very same place: a tie */
    memcpy(caches[103].position, caches[53].position, sizeof caches[53].position);
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.3f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 2; d.caches = &set;
    nb_out_alloc(&o, 2, N);
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < 2; ++i) {
        double dmax = 0.0;
        assert_int_equal(o.count[i], 5);
        for (k = 0; k < 5; ++k) {
            uint32_t c = o.index[i * N + k];
            double dx = (double)pos[i * 3] - caches[c].position[0], dy = (double)pos[i * 3 + 1] - caches[c].position[1];
            double dz = (double)pos[i * 3 + 2] - caches[c].position[2], dd = sqrt(dx * dx + dy * dy + dz * dz);
            assert_int_equal((c - 3) % 50, 0);
            assert_true(dd >= dmax);
            dmax = dd;
        }
        for (k = 5; k < N; ++k) assert_int_equal(o.index[i * N + k], UINT32_MAX);
        assert_true(o.dmax[i] == (float)dmax);
        /* the tie: 53 before 103, next to each other */
        for (k = 0; k < 4; ++k)
            if (o.index[i * N + k] == 53) assert_int_equal(o.index[i * N + k + 1], 103);
    }
    nb_out_free(&o);
}

/* Exact ties beyond n: 40 caches at one point (indices scattered over the set, so over the
   tree's leaves), vertices at that point and near it: the 16 smallest indices, ascending. */
static void ties_beyond_n(void **state) {
    enum { C = 1000, N = 16 };
    gim_cache *caches = box_caches(C, 0.0f, 1.0f, NULL);
    float pos[2 * 3] = {0.25f, 0.5f, 0.0f, 0.25f, 0.5f, 0.001f}, nrm[2 * 3] = {0, 0, 1, 0, 0, 1};
    uint32_t i, k, dup[40];
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    (void)state;
    for (i = 0; i < 40; ++i) {
        dup[i] = 7 + i * 24;
        caches[dup[i]].position[0] = 0.25f; caches[dup[i]].position[1] = 0.5f; caches[dup[i]].position[2] = 0.0f;
        caches[dup[i]].normal[0] = 0.0f; caches[dup[i]].normal[1] = 0.0f; caches[dup[i]].normal[2] = 1.0f;
    }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.3f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 2; d.caches = &set;
    nb_out_alloc(&o, 2, N);
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < 2; ++i) {
        for (k = 0; k < N; ++k) assert_int_equal(o.index[i * N + k], dup[k]);
        assert_true(o.dmax[i] == (i ? 0.001f : 0.0f));
    }
    nb_out_free(&o);
    free(caches);
}

/* n = 1 gives each vertex its nearest compatible cache; a zero or NaN normal takes the nearest
   of any normal (warning); a NaN position gets nothing (count 0, no NaN out). */
static void n1_and_degenerate_vertices(void **state) {
    gim_cache caches[3];
    float pos[4 * 3] = {0.1f, 0, 0, 0.1f, 0, 0, 0.1f, 0, 0, NAN, 0, 0};
    float nrm[4 * 3] = {0, 0, 1, 0, 0, 0, NAN, 0, 1, 0, 0, 1};
    uint32_t index[4], count[4];
    float dmax[4];
    gim_neighbour_result r;
    gim_cache_set set;
    gim_neighbour_desc d;
    test_alloc_stats st;
    test_log lg;
    int i;
    (void)state;
    memset(caches, 0, sizeof caches);
    for (i = 0; i < 3; ++i) { caches[i].position[0] = (float)i; caches[i].area = 1.0f; }
    caches[0].normal[2] = -1.0f; /* nearest, facing away */
    caches[1].normal[2] = 1.0f;
    caches[2].normal[2] = 1.0f;
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = 3;  /* theta_eps 0: the default of 30 degrees */
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 4; d.caches = &set; d.n = 1;
    d.env = test_env(&st, &lg);
    r.index = index; r.count = count; r.d_cmax = dmax;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(index[0], 1); assert_int_equal(count[0], 1); assert_true(dmax[0] == 0.9f);
    assert_int_equal(index[1], 0); assert_true(dmax[1] == 0.1f);  /* zero normal: any */
    assert_int_equal(index[2], 0);                                /* NaN normal: any */
    assert_int_equal(index[3], UINT32_MAX); assert_int_equal(count[3], 0); assert_true(dmax[3] == 0.0f);
    assert_int_equal(lg.warnings, 1);
    assert_non_null(strstr(lg.last, "2 vertices without a usable normal"));
    assert_int_equal(st.live, 0);
}

/* normals NULL: area-weighted face normals from the triangles; a flat grid's vertices then
   get what explicit +z normals give. Interleaved positions (stride 24) and u16 indices too. */
static void face_normals_and_strides(void **state) {
    enum { G = 12, V = G * G, T = (G - 1) * (G - 1) * 2, N = 8 };
    float inter[V * 6], nrm[V * 3];
    uint16_t idx[T * 3];
    gim_cache *caches = box_caches(400, 0.0f, 1.0f, NULL);
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out a, b;
    uint32_t i, t = 0, x, y;
    (void)state;
    for (i = 0; i < V; ++i) {
        inter[i * 6] = (float)(i % G) / (G - 1); inter[i * 6 + 1] = (float)(i / G) / (G - 1); inter[i * 6 + 2] = 1.0f;
        inter[i * 6 + 3] = inter[i * 6 + 4] = inter[i * 6 + 5] = -7.0f; /* not positions */
        nrm[i * 3] = 0; nrm[i * 3 + 1] = 0; nrm[i * 3 + 2] = 1;
    }
    for (y = 0; y + 1 < G; ++y)
        for (x = 0; x + 1 < G; ++x) { /* counter-clockwise seen from +z */
            uint16_t v0 = (uint16_t)(y * G + x);
            idx[t++] = v0; idx[t++] = (uint16_t)(v0 + 1); idx[t++] = (uint16_t)(v0 + G + 1);
            idx[t++] = v0; idx[t++] = (uint16_t)(v0 + G + 1); idx[t++] = (uint16_t)(v0 + G);
        }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = 400; set.theta_eps = 0.4f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = inter; d.mesh.position_stride = 24; d.mesh.vertex_count = V;
    d.mesh.indices = idx; d.mesh.index_count = T * 3; d.mesh.index_type = GIM_INDEX_U16;
    d.caches = &set; d.n = N; d.theta_eps = 0.4f;
    nb_out_alloc(&a, V, N); nb_out_alloc(&b, V, N);
    assert_int_equal(gim_cache_neighbours(&d, &a.r), GIM_OK);
    d.mesh.normals = nrm;
    assert_int_equal(gim_cache_neighbours(&d, &b.r), GIM_OK);
    expect_equal(&a, &b, V, N);
    for (i = 0; i < V; ++i) { /* only caches of the +z face (or the random tenth near +z) */
        assert_true(a.count[i] == N);
        assert_true(caches[a.index[i * N]].normal[2] > 0.9f);
    }
    nb_out_free(&a); nb_out_free(&b);
    free(caches);
}

static void errors(void **state) {
    gim_cache caches[2];
    float pos[3] = {0, 0, 0}, nrm[3] = {0, 0, 1};
    uint32_t index[17], count[1], tri[3] = {0, 0, 5};
    float dmax[1];
    gim_neighbour_result r;
    gim_cache_set set;
    gim_neighbour_desc d;
    test_log lg;
    (void)state;
    memset(caches, 0, sizeof caches);
    caches[0].normal[2] = 1.0f; caches[1].normal[2] = 1.0f; caches[1].position[0] = 1.0f;
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = 2;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = 1; d.caches = &set;
    d.env = test_env(NULL, &lg);
    r.index = index; r.count = count; r.d_cmax = dmax;
#define EXPECT_ERR(code) do { int e0 = lg.errors; assert_int_equal(gim_cache_neighbours(&d, &r), code); \
        assert_int_equal(lg.errors, e0 + 1); } while (0)
    assert_int_equal(gim_cache_neighbours(NULL, &r), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(count[0], 2);
    assert_int_equal(gim_cache_neighbours(&d, NULL), GIM_ERROR_INVALID_ARGUMENT);
    r.index = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); r.index = index;
    r.count = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); r.count = count;
    r.d_cmax = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); r.d_cmax = dmax;
    d.n = 17; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "n = 17"));
    d.n = 16; assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK);
    assert_int_equal(index[2], UINT32_MAX);
    d.n = 0;
    d.caches = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); d.caches = &set;
    set.count = 0; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); set.count = 2;
    set.caches = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); set.caches = caches;
    d.mesh.positions = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); d.mesh.positions = pos;
    d.mesh.vertex_count = 0; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); d.mesh.vertex_count = 1;
    d.mesh.position_stride = 8; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); d.mesh.position_stride = 0;
    d.mesh.normal_stride = 4; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); d.mesh.normal_stride = 0;
    d.theta_eps = -0.1f; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.theta_eps = NAN; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.theta_eps = 3.2f; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.theta_eps = 0.0f; set.theta_eps = INFINITY; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); set.theta_eps = 0.0f;
    caches[1].position[1] = NAN; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); caches[1].position[1] = 0.0f;
    caches[1].normal[2] = 0.0f; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); caches[1].normal[2] = 1.0f;
    caches[1].normal[0] = INFINITY; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT); caches[1].normal[0] = 0.0f;
    /* no normals: need whole triangles with indices in range */
    d.mesh.normals = NULL; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.mesh.indices = tri; d.mesh.index_count = 3; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "index 5"));
    tri[2] = 0; d.mesh.index_count = 2; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.mesh.index_count = 3; d.mesh.index_type = (gim_index_type)7; EXPECT_ERR(GIM_ERROR_INVALID_ARGUMENT);
    d.mesh.index_type = GIM_INDEX_U32;
    assert_int_equal(gim_cache_neighbours(&d, &r), GIM_OK); /* degenerate triangle: zero normal, any cache */
    assert_int_equal(count[0], 2);
#undef EXPECT_ERR
}

/* Every allocation is freed, and each one failing in turn gives OUT_OF_MEMORY with nothing
   leaked and the outputs untouched. */
static void allocations_and_oom(void **state) {
    enum { C = 300, V = 200, N = 16 };
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    gim_cache *caches = box_caches(C, 0.0f, 1.0f, NULL);
    float pos[V * 3], nrm[V * 3];
    uint32_t tri[V / 3 * 3], i;
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    int mode;
    long k, total;
    (void)state;
    random_vertices(pos, nrm, V, 0.0f, 1.0f);
    for (i = 0; i < V / 3 * 3; ++i) tri[i] = i;
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.5f;
    nb_out_alloc(&o, V, N);
    for (mode = 0; mode < 2; ++mode) { /* given normals; face normals (one more allocation) */
        memset(&d, 0, sizeof d);
        d.mesh.positions = pos; d.mesh.normals = mode ? NULL : nrm; d.mesh.vertex_count = V;
        d.mesh.indices = tri; d.mesh.index_count = V / 3 * 3;
        d.caches = &set; d.env = env;
        st.fail_after = -1;
        assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
        total = st.allocs;
        assert_true(total >= 3);
        assert_int_equal(st.live, 0);
        for (k = 0; k < total; ++k) {
            memset(o.count, 0xab, sizeof(uint32_t) * V);
            st.allocs = 0; st.fail_after = k; lg.errors = 0;
            assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_ERROR_OUT_OF_MEMORY);
            assert_int_equal(st.live, 0);
            assert_int_equal(lg.errors, 1);
            assert_int_equal(o.count[0], 0xabababab);
        }
        st.allocs = 0; st.fail_after = -1;
    }
    nb_out_free(&o);
    free(caches);
}

/* The search tree: quickselect puts the k-th key at k; every cache lies in its nodes' position
   and normal bounds; the leaves hold every cache once; median splits keep it shallow. */
static void search_tree_invariants(void **state) {
    enum { M = 3000 };
    float *key = (float *)malloc(sizeof(float) * 3 * M), *un = (float *)malloc(sizeof(float) * 3 * M);
    uint32_t perm[M], i, k, trial, *seen = (uint32_t *)calloc(M, sizeof(uint32_t));
    uint32_t stack[64], depth[64], top = 0, maxdepth = 0;
    gim_cache_set set;
    gim__nb_tree t;
    (void)state;
    for (trial = 0; trial < 20; ++trial) {
        uint32_t lo = trial * 7, hi = M - trial * 11;
        for (i = 0; i < 3 * M; ++i) key[i] = trial % 3 == 0 ? (float)(int)(test_rand01() * 5) : (float)test_rand01();
        for (i = 0; i < M; ++i) perm[i] = i;
        k = lo + (uint32_t)(test_rand01() * (hi - lo));
        gim__nb_select(key, perm, lo, hi, k, (int)(trial % 3));
        for (i = lo; i < hi; ++i) {
            float a = key[perm[i] * 3 + trial % 3], b = key[perm[k] * 3 + trial % 3];
            if (i < k) assert_true(a <= b);
            if (i > k) assert_true(a >= b);
        }
    }
    memset(&set, 0, sizeof set);
    set.caches = box_caches(M, 5.0f, 2.0f, NULL);
    set.count = M;
    for (i = 0; i < 30; ++i) set.caches[i] = set.caches[100]; /* duplicates */
    for (i = 0; i < M; ++i) {
        gim_vec3 n = gim_v3_normalize(gim_v3(set.caches[i].normal[0], set.caches[i].normal[1], set.caches[i].normal[2]));
        un[i * 3] = n.x; un[i * 3 + 1] = n.y; un[i * 3 + 2] = n.z;
    }
    assert_int_equal(gim__nb_tree_build(NULL, &set, un, &t), GIM_OK);
    stack[top] = 0; depth[top++] = 1;
    while (top) {
        const gim__nb_node *nd = &t.node[stack[--top]];
        uint32_t d = depth[top], s, a;
        if (d > maxdepth) maxdepth = d;
        for (s = nd->begin; s < nd->end; ++s)
            for (a = 0; a < 3; ++a) {
                assert_true(t.slot[s].pos[a] >= nd->plo[a] && t.slot[s].pos[a] <= nd->phi[a]);
                assert_true(t.slot[s].nrm[a] >= nd->nlo[a] && t.slot[s].nrm[a] <= nd->nhi[a]);
            }
        if (nd->left) {
            assert_int_equal(t.node[nd->left].begin, nd->begin);
            assert_int_equal(t.node[nd->left].end, t.node[nd->left + 1].begin);
            assert_int_equal(t.node[nd->left + 1].end, nd->end);
            stack[top] = nd->left; depth[top++] = d + 1;
            stack[top] = nd->left + 1; depth[top++] = d + 1;
        } else {
            for (s = nd->begin; s < nd->end; ++s) seen[t.slot[s].id]++;
        }
    }
    for (i = 0; i < M; ++i) assert_int_equal(seen[i], 1);
    assert_true(maxdepth <= 12); /* ceil(log2(3000 / 8)) + 1 = 10 */
    free(t.node); free(t.slot); free(set.caches); free(key); free(un); free(seen);
}

/* Flipped vertex normals: no cache is compatible anywhere; every vertex gets count 0. */
static void flipped_normals_find_nothing(void **state) {
    enum { C = 2000, V = 500, N = 16 };
    gim_cache *caches = box_caches(C, 0.0f, 1.0f, NULL);
    float pos[V * 3], nrm[V * 3];
    gim_cache_set set;
    gim_neighbour_desc d;
    nb_out o;
    uint32_t i;
    (void)state;
    for (i = 0; i < C; ++i) { /* only axis-aligned face caches, then vertices facing inwards */
        gim_vec3 nn = gim_v3_normalize(gim_v3(caches[i].normal[0], caches[i].normal[1], caches[i].normal[2]));
        float ax = fabsf(nn.x), ay = fabsf(nn.y), az = fabsf(nn.z);
        caches[i].normal[0] = ax >= ay && ax >= az ? (nn.x > 0 ? 1.0f : -1.0f) : 0.0f;
        caches[i].normal[1] = !(ax >= ay && ax >= az) && ay >= az ? (nn.y > 0 ? 1.0f : -1.0f) : 0.0f;
        caches[i].normal[2] = !(ax >= ay && ax >= az) && !(ay >= az) ? (nn.z > 0 ? 1.0f : -1.0f) : 0.0f;
    }
    for (i = 0; i < V; ++i) { /* vertices on the faces, normal (1,1,1) or (-1,-1,-1): 54.7 degrees off every face */
        pos[i * 3] = urand(0, 1); pos[i * 3 + 1] = urand(0, 1); pos[i * 3 + 2] = (float)(i & 1);
        nrm[i * 3] = nrm[i * 3 + 1] = nrm[i * 3 + 2] = (i & 2) ? 1.0f : -1.0f;
    }
    memset(&set, 0, sizeof set);
    set.caches = caches; set.count = C; set.theta_eps = 0.5f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = pos; d.mesh.normals = nrm; d.mesh.vertex_count = V; d.caches = &set; d.theta_eps = 0.9f;
    nb_out_alloc(&o, V, N);
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < V; ++i) { assert_int_equal(o.count[i], 0); assert_true(o.dmax[i] == 0.0f); }
    d.theta_eps = 1.0f; /* 57 degrees: now every vertex finds caches of the three faces */
    assert_int_equal(gim_cache_neighbours(&d, &o.r), GIM_OK);
    for (i = 0; i < V; ++i) assert_int_equal(o.count[i], N);
    nb_out_free(&o);
    free(caches);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(equals_brute_force),
        cmocka_unit_test(equals_brute_force_far_and_scaled),
        cmocka_unit_test(unit_free),
        cmocka_unit_test(thin_wall),
        cmocka_unit_test(smooth_shaded_edges_and_corners),
        cmocka_unit_test(fewer_than_n_and_ties),
        cmocka_unit_test(ties_beyond_n),
        cmocka_unit_test(n1_and_degenerate_vertices),
        cmocka_unit_test(face_normals_and_strides),
        cmocka_unit_test(search_tree_invariants),
        cmocka_unit_test(flipped_normals_find_nothing),
        cmocka_unit_test(errors),
        cmocka_unit_test(allocations_and_oom),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
