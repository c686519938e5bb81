/* The CPU side of deforming meshes (no GL): gim_cache_bind and gim_caches_follow_twin on a bent
   strip, against closed forms; and their refusals. The GPU pass against this twin, and the
   runtime, are in gltest_deform.c. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* Two triangles: the unit square in the xz-plane at y = 0, normal +y. */
static const float sq[12] = {0, 0, 0, 1, 0, 0, 1, 0, -1, 0, 0, -1};
static const uint32_t sq_idx[6] = {0, 1, 2, 0, 2, 3};

/* gim_caches_follow_twin with its desc filled from arguments. */
static gim_result follow(const gim_cache *rest, const gim_cache_binding *bind, uint32_t count, const float *positions,
                         uint32_t vertex_count, gim_cache *out, gim_env env) {
    gim_follow_desc d;
    memset(&d, 0, sizeof d);
    d.rest = rest; d.bind = bind; d.count = count; d.positions = positions; d.vertex_count = vertex_count; d.env = env;
    return gim_caches_follow_twin(&d, out);
}

static gim_mesh_data square(const float *p) {
    gim_mesh_data d;
    memset(&d, 0, sizeof d);
    d.positions = p;
    d.vertex_count = 4;
    d.indices = sq_idx;
    d.index_count = 6;
    d.index_type = GIM_INDEX_U32;
    return d;
}

/* Caches on, above and tilted from the square come back where they were at rest; a rotation
   with uneven scale of the vertices moves them as gim_caches_to_world does (closed form for an
   affine map: A p, A^-T n normalised, area |det A| |A^-T n|), the tilted one included. */
static void rest_and_affine(void **state) {
    gim_cache c[3], out[3], want[3];
    gim_cache_binding b[3];
    gim_mesh_data d = square(sq);
    gim_mat4 a = gim_mat4_identity();
    gim_env env0;
    float moved[12];
    double s = 1.0 / sqrt(2.0);
    int i, k;
    (void)state;
    memset(&env0, 0, sizeof env0);   /* zero: the default allocator, no log */
    memset(c, 0, sizeof c);
    c[0].position[0] = 0.3f; c[0].position[2] = -0.6f; c[0].normal[1] = 1.0f; c[0].area = 0.5f; c[0].reflectance = 0.7f;
    c[1] = c[0];
    c[1].position[1] = 0.05f;   /* floating above the surface: h = 0.05 */
    c[2] = c[0];
    c[2].position[0] = 0.8f; c[2].position[2] = -0.2f;
    c[2].normal[0] = (float)s; c[2].normal[1] = (float)s;   /* tilted 45 degrees from its triangle */
    assert_int_equal(gim_cache_bind(&d, c, 3, b, env0), GIM_OK);
    assert_true(fabsf(b[1].h - 0.05f) < 1e-7f);
    assert_int_equal(follow(c, b, 3, sq, 4, out, env0), GIM_OK);
    for (i = 0; i < 3; ++i)
        for (k = 0; k < 3; ++k) {
            assert_true(fabsf(out[i].position[k] - c[i].position[k]) < 1e-6f);
            assert_true(fabsf(out[i].normal[k] - c[i].normal[k]) < 1e-6f);
        }
    /* A: rotate 30 degrees about z, scale x by 2, y by 0.5, shear z by x */
    a.m[0] = 2.0f * 0.8660254f; a.m[1] = 2.0f * 0.5f; a.m[2] = 0.3f;
    a.m[4] = -0.5f * 0.5f; a.m[5] = 0.5f * 0.8660254f;
    a.m[10] = 1.0f;
    a.m[12] = 4.0f; a.m[13] = -1.0f; a.m[14] = 2.0f;
    for (i = 0; i < 4; ++i) {
        gim_vec3 p = gim_mat4_point(a, gim_v3(sq[i * 3], sq[i * 3 + 1], sq[i * 3 + 2]));
        moved[i * 3] = p.x; moved[i * 3 + 1] = p.y; moved[i * 3 + 2] = p.z;
    }
    assert_int_equal(follow(c, b, 3, moved, 4, out, env0), GIM_OK);
    assert_int_equal(gim_caches_to_world(c, 3, a, want, env0), GIM_OK);
    for (i = 0; i < 3; ++i) {
        for (k = 0; k < 3; ++k) {
            /* the tilted one: a triangle does not fix how A acts off its plane (below) */
            if (i != 2) assert_true(fabsf(out[i].normal[k] - want[i].normal[k]) < 1e-5f);
            /* cache 1's height is kept unscaled (h along the new unit normal), not A's */
            if (i != 1) assert_true(fabsf(out[i].position[k] - want[i].position[k]) < 1e-5f);
        }
        if (i != 2) assert_true(fabsf(out[i].area - want[i].area) < 1e-5f * want[i].area);   /* the tilted one: the
            triangle's area ratio, not |det A||A^-T n| of its own normal */
        assert_true(out[i].reflectance == 0.7f);
    }
    {   /* the tilted normal keeps its place in the triangle's frame: n'.(b'-a') : n'.(c'-a') : n'.n'_face
           = n.(b-a) : n.(c-a) : n.n_face, one factor for the three (the dual basis) */
        const uint32_t *v = b[2].vertex;
        gim_vec3 pa = gim_v3(moved[v[0] * 3], moved[v[0] * 3 + 1], moved[v[0] * 3 + 2]);
        gim_vec3 e1 = gim__v3_sub(gim_v3(moved[v[1] * 3], moved[v[1] * 3 + 1], moved[v[1] * 3 + 2]), pa);
        gim_vec3 e2 = gim__v3_sub(gim_v3(moved[v[2] * 3], moved[v[2] * 3 + 1], moved[v[2] * 3 + 2]), pa);
        gim_vec3 nf = gim_v3_normalize(gim__v3_cross(e1, e2)), n = gim_v3(out[2].normal[0], out[2].normal[1], out[2].normal[2]);
        double f1 = gim__v3_dot(n, e1) / b[2].frame[0], f2 = gim__v3_dot(n, e2) / b[2].frame[1], f3 = gim__v3_dot(n, nf) / b[2].frame[2];
        assert_true(fabs(b[2].frame[0]) > 0.1 && fabs(b[2].frame[2]) > 0.1);
        assert_true(fabs(f1 - f3) < 1e-5 * fabs(f3));
        if (fabs(b[2].frame[1]) > 0.1) assert_true(fabs(f2 - f3) < 1e-5 * fabs(f3));
        /* and differs from the rest normal: it turned with the triangle */
        assert_true(fabsf(out[2].normal[0] - c[2].normal[0]) > 0.1f || fabsf(out[2].normal[1] - c[2].normal[1]) > 0.1f);
    }
    {   /* cache 1 sits 0.05 above the moved plane along its unit normal */
        gim_vec3 n = gim_v3(want[0].normal[0], want[0].normal[1], want[0].normal[2]);
        gim_vec3 dp = gim__v3_sub(gim_v3(out[1].position[0], out[1].position[1], out[1].position[2]),
                                 gim_v3(out[0].position[0], out[0].position[1], out[0].position[2]));
        assert_true(fabsf(gim__v3_dot(dp, n) - 0.05f) < 1e-6f);
    }
}

/* A collapsed triangle keeps the rest normal, area 0; bad input is refused with one message. */
static void refusals(void **state) {
    test_alloc_stats st;
    test_log log;
    gim_env env;
    gim_cache c, out;
    gim_cache_binding b;
    gim_mesh_data d = square(sq);
    float flat[12], nan_pos[12];
    int errors = 0;
    (void)state;
    memset(&st, 0, sizeof st);
    memset(&log, 0, sizeof log);
    env = test_env(&st, &log);
    memset(&c, 0, sizeof c);
    c.position[0] = 0.3f; c.position[2] = -0.6f; c.normal[1] = 1.0f; c.area = 0.5f;
    assert_int_equal(gim_cache_bind(&d, &c, 1, &b, env), GIM_OK);
    memcpy(flat, sq, sizeof flat);
    flat[6] = 0.0f; flat[8] = 0.0f;   /* vertex 2 onto vertex 0: both triangles collapse */
    assert_int_equal(follow(&c, &b, 1, flat, 4, &out, env), GIM_OK);
    assert_true(out.area == 0.0f && out.normal[1] == 1.0f);
#define EXPECT(call) do { assert_int_equal((call), GIM_ERROR_INVALID_ARGUMENT); assert_int_equal(log.errors, ++errors); } while (0)
    EXPECT(gim_cache_bind(NULL, &c, 1, &b, env));
    EXPECT(gim_cache_bind(&d, NULL, 1, &b, env));
    memcpy(nan_pos, sq, sizeof nan_pos);
    nan_pos[7] = NAN;   /* vertex 2, on the cache's triangle */
    d.positions = nan_pos;
    EXPECT(gim_cache_bind(&d, &c, 1, &b, env));             /* non-finite position */
    d.positions = flat;
    EXPECT(gim_cache_bind(&d, &c, 1, &b, env));             /* no triangle with an area */
    d = square(sq);
    d.vertex_count = 3;
    EXPECT(gim_cache_bind(&d, &c, 1, &b, env));             /* index 3 out of range */
    EXPECT(follow(&c, &b, 1, sq, 2, &out, env)); /* a binding past the vertices */
    EXPECT(follow(&c, &b, 1, nan_pos, 4, &out, env));   /* non-finite positions */
    EXPECT(follow(&c, NULL, 1, sq, 4, &out, env));
#undef EXPECT
    assert_int_equal(gim_caches_follow_twin(NULL, &out), GIM_ERROR_INVALID_ARGUMENT); /* no env to log through */
    assert_int_equal(st.live, 0);
}

/* gim_cache_bind's grid search binds each cache to the triangle testing every triangle in
   order gives (nearest, ties to the lower index): caches scattered on and around a bumpy sheet
   and a flat one (the grid one cell thick), on its vertices and edges (ties), and outside the
   mesh's bounds. */
static void grid_is_brute_force(void **state) {
    enum { NQ = 20, NC = 1500 };
    static float p[(NQ + 1) * (NQ + 1) * 3];
    static uint32_t idx[NQ * NQ * 6];
    static gim_cache cs[NC];
    static gim_cache_binding b[NC];
    gim_mesh_data d;
    gim_env env;
    uint32_t t, c, flat;
    int i, j, bad = 0;
    (void)state;
    memset(&env, 0, sizeof env);
    for (flat = 0; flat < 2; ++flat) {
        t = 0;
        for (j = 0; j <= NQ; ++j)
            for (i = 0; i <= NQ; ++i) {
                float *v = p + 3 * (j * (NQ + 1) + i);
                v[0] = (float)i / NQ; v[2] = (float)j / NQ;
                v[1] = flat ? 0.0f : 0.1f * sinf(6.0f * v[0]) * cosf(5.0f * v[2]);
            }
        for (j = 0; j < NQ; ++j)
            for (i = 0; i < NQ; ++i) {
                uint32_t a = (uint32_t)(j * (NQ + 1) + i);
                idx[t++] = a; idx[t++] = a + NQ + 1; idx[t++] = a + NQ + 2; idx[t++] = a; idx[t++] = a + NQ + 2; idx[t++] = a + 1;
            }
        memset(&d, 0, sizeof d);
        d.positions = p; d.vertex_count = (NQ + 1) * (NQ + 1); d.indices = idx; d.index_count = t; d.index_type = GIM_INDEX_U32;
        srand(7);
        memset(cs, 0, sizeof cs);
        for (c = 0; c < NC; ++c) {
            for (i = 0; i < 3; ++i) cs[c].position[i] = -0.3f + 1.6f * (float)rand() / (float)RAND_MAX;
            if (c % 3 == 0) cs[c].position[1] = 0.0f;
            if (c % 5 == 0) {
                cs[c].position[0] = (float)(rand() % (NQ + 1)) / NQ;
                cs[c].position[2] = (float)(rand() % (NQ + 1)) / NQ;
            }
            cs[c].normal[1] = 1.0f;
        }
        assert_int_equal(gim_cache_bind(&d, cs, NC, b, env), GIM_OK);
        for (c = 0; c < NC; ++c) {
            double pp[3], best = DBL_MAX, u, v;
            uint32_t bt = 0, tt;
            for (i = 0; i < 3; ++i) pp[i] = cs[c].position[i];
            for (tt = 0; tt < t / 3; ++tt) {
                double q[3][3], d2 = 0.0;
                uint32_t vi[3];
                gim__bind_triangle(&d, 12, tt, vi, q);
                gim__closest_on_triangle(pp, q[0], q[1], q[2], &u, &v);
                for (i = 0; i < 3; ++i) {
                    double e = pp[i] - ((1 - u - v) * q[0][i] + u * q[1][i] + v * q[2][i]);
                    d2 += e * e;
                }
                if (d2 < best) { best = d2; bt = tt; }
            }
            bad += b[c].vertex[0] != idx[bt * 3] || b[c].vertex[1] != idx[bt * 3 + 1] || b[c].vertex[2] != idx[bt * 3 + 2];
        }
    }
    assert_int_equal(bad, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rest_and_affine),
        cmocka_unit_test(refusals),
        cmocka_unit_test(grid_is_brute_force),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
