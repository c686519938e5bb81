/* The bounding volume hierarchy of neighbour_rays (gim_bvh_build, gim_bvh_occluded) and the
   pixels' neighbour test (gim_neighbour_rays_twin): the traversal answers what testing every
   triangle answers (every triangle of the hierarchy tested without a box), on random soups and
   on degenerate ones; the triangle test
   against an exact (double) segment-triangle test away from edges and ends (each triangle is
   grown by 1e-4 of itself so that a segment through a shared edge hits one of the two); closed forms (a
   wall between two points, a segment stopping short of it, grazing along it); the same answers
   from 1e-15 to 1e15 and far from the origin; the depth bound on the worst layouts;
   the neighbour rows (the hidden dropped in order, d_cmax the farthest kept, a receiver that
   sees none keeps its row); the caches' visibility matrix of GIM_VISIBILITY_RAYS against a
   plate's exact shadow; the nearest crossing (gim_bvh_nearest) against every triangle; the second
   bounce by rays (gim_second_bounce_rays_twin) against closed forms; bad input refused; no
   leak, allocation failures handled. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* A quad at corner c spanned by u, v as two triangles into pos (18 floats) from triangle t. */
static uint32_t quad(float *pos, uint32_t t, const float c[3], const float u[3], const float v[3]) {
    int k;
    for (k = 0; k < 3; ++k) {
        pos[t * 9 + k] = c[k]; pos[t * 9 + 3 + k] = c[k] + u[k]; pos[t * 9 + 6 + k] = c[k] + u[k] + v[k];
        pos[t * 9 + 9 + k] = c[k]; pos[t * 9 + 12 + k] = c[k] + u[k] + v[k]; pos[t * 9 + 15 + k] = c[k] + v[k];
    }
    return t + 2;
}

static gim_bvh build(const float *pos, uint32_t n, gim_env env) {
    gim_twin_scene s;
    gim_bvh b;
    memset(&s, 0, sizeof s);
    s.positions = pos;
    s.triangle_count = n;
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_OK);
    return b;
}

/* Every node's box holds its triangles; inner nodes' children in range; each triangle in one leaf. */
static void check_tree(const gim_bvh *b) {
    uint32_t i, covered = 0, k;
    assert_true(b->depth < GIM_BVH_MAX_DEPTH);
    assert_true(b->node_count <= 2u * b->triangle_count);
    for (i = 0; i < b->node_count; ++i) {
        const gim_bvh_node *nd = b->nodes + i;
        if (nd->count == 0) {
            assert_true(nd->index > i + 1u && nd->index < b->node_count);
            continue;
        }
        assert_true(nd->count <= GIM_BVH_LEAF);
        assert_true(nd->index + nd->count <= b->triangle_count);
        covered += nd->count;
        for (k = 0; k < nd->count; ++k) {
            const float *t = b->triangles + (size_t)(nd->index + k) * 12u;
            int a, v;
            for (v = 0; v < 3; ++v)
                for (a = 0; a < 3; ++a) {
                    float x = t[a] + (v ? t[4 * v + a] : 0.0f);
                    assert_true(x >= nd->lo[a] && x <= nd->hi[a]);
                }
        }
    }
    assert_int_equal(covered, b->triangle_count);
}

/* Every triangle of the hierarchy tested, no box: what the walk must answer. */
static int brute(const gim_bvh *bvh, gim_vec3 a, gim_vec3 b) {
    float o[3], d[3];
    uint32_t t;
    if (!bvh->node_count || !gim__bvh_segment(bvh, a, b, o, d)) return 0;
    for (t = 0; t < bvh->triangle_count; ++t)
        if (gim__bvh_triangle(bvh->triangles + (size_t)t * 12u, o, d)) return 1;
    return 0;
}

static gim_vec3 rnd_point(float lo, float hi) { return gim_v3(test_rnd(lo, hi), test_rnd(lo, hi), test_rnd(lo, hi)); }

/* n random triangles around points of the unit cube into pos: every big_every-th of half-size
   big, the others small; every flat_every-th flat in z (0: none). */
static void random_soup(float *pos, uint32_t n, uint32_t big_every, float big, float small, uint32_t flat_every) {
    uint32_t t;
    for (t = 0; t < n; ++t) {
        gim_vec3 c = rnd_point(0.0f, 1.0f);
        float s = t % big_every == 0 ? big : small;
        int k;
        for (k = 0; k < 3; ++k) {
            pos[t * 9 + k * 3] = c.x + test_rnd(-s, s);
            pos[t * 9 + k * 3 + 1] = c.y + test_rnd(-s, s);
            pos[t * 9 + k * 3 + 2] = c.z + (flat_every && t % flat_every == 0 ? 0.0f : test_rnd(-s, s));
        }
    }
}

static void traversal_equals_every_triangle(void **state) {
    test_alloc_stats as;
    gim_env env = test_env(&as, NULL);
    enum { N = 400, SEGMENTS = 1500 };
    float *pos = (float *)malloc(N * 9 * sizeof(float));
    uint32_t i, hits = 0;
    gim_bvh b;
    (void)state;
    test_rng_state = 7;
    random_soup(pos, N, 17, 0.5f, 0.06f, 5);   /* small triangles in the unit cube, some sliver, some large */
    b = build(pos, N, env);
    check_tree(&b);
    for (i = 0; i < SEGMENTS; ++i) {
        gim_vec3 p = rnd_point(-0.2f, 1.2f), q = rnd_point(-0.2f, 1.2f);
        int h = gim_bvh_occluded(&b, p, q);
        assert_int_equal(h, brute(&b, p, q));
        assert_int_equal(gim_bvh_occluded(&b, q, p), brute(&b, q, p));
        hits += (uint32_t)h;
    }
    assert_true(hits > SEGMENTS / 5 && hits < SEGMENTS * 4 / 5);   /* both answers exercised */
    gim_bvh_free(&b);
    assert_int_equal(as.live, 0);
    free(pos);
}

/* The nearest crossing (gim_bvh_nearest) is what every triangle tested answers: the smallest
   e2 . q / det of the crossings, its scene index the triangle whose vertices the slot holds. */
static void nearest_equals_every_triangle(void **state) {
    test_alloc_stats as;
    gim_env env = test_env(&as, NULL);
    enum { N = 400, SEGMENTS = 1500 };
    float *pos = (float *)malloc(N * 9 * sizeof(float));
    uint32_t i, hits = 0;
    gim_bvh b;
    (void)state;
    test_rng_state = 11;
    random_soup(pos, N, 13, 0.4f, 0.07f, 0);
    b = build(pos, N, env);
    for (i = 0; i < SEGMENTS; ++i) {
        gim_vec3 p = rnd_point(-0.2f, 1.2f), q = rnd_point(-0.2f, 1.2f);
        gim_bvh_hit h;
        float o[3], d[3], best = 2.0f;
        uint32_t k, arg = UINT32_MAX, scene;
        int got = gim_bvh_nearest(&b, p, q, &h);
        assert_true(gim__bvh_segment(&b, p, q, o, d));
        for (k = 0; k < b.triangle_count; ++k) {
            float tt, dd;
            if (gim__bvh_triangle_at(b.triangles + (size_t)k * 12u, o, d, &tt, &dd) && tt / dd < best) {
                best = tt / dd;
                arg = k;
            }
        }
        assert_int_equal(got, arg != UINT32_MAX);
        assert_int_equal(got, gim_bvh_occluded(&b, p, q));
        if (!got) continue;
        ++hits;
        assert_true(h.t > 0.0f && h.t < 1.0f);
        assert_true(fabsf(h.t - best) <= 1e-6f);   /* the same crossing, or one tied with it */
        memcpy(&scene, b.triangles + (size_t)h.slot * 12u + 3u, sizeof scene);
        assert_int_equal(scene, h.triangle);
        assert_true(scene < N);
        for (k = 0; k < 3; ++k)   /* the slot holds that scene triangle (in the hierarchy's frame) */
            assert_true(fabsf(b.triangles[(size_t)h.slot * 12u + k] - (pos[scene * 9 + k] - b.origin[k]) * b.scale) <= 1e-6f);
    }
    assert_true(hits > SEGMENTS / 5 && hits < SEGMENTS * 4 / 5);
    {   /* a wall between: the hit's point on it */
        float w[18], c[3] = {-1, -1, 0.5f}, u[3] = {2, 0, 0}, v[3] = {0, 2, 0};
        gim_bvh wb;
        gim_bvh_hit h;
        quad(w, 0, c, u, v);
        wb = build(w, 2, env);
        assert_true(gim_bvh_nearest(&wb, gim_v3(0.1f, 0.2f, 0.0f), gim_v3(0.1f, 0.2f, 2.0f), &h));
        assert_true(fabsf(h.t - 0.25f) < 1e-6f && h.triangle < 2u);
        assert_false(gim_bvh_nearest(&wb, gim_v3(0.1f, 0.2f, 0.0f), gim_v3(0.1f, 0.2f, 0.4f), &h));
        assert_false(gim_bvh_nearest(&wb, gim_v3(0.1f, 0.2f, NAN), gim_v3(0.1f, 0.2f, 2.0f), &h));
        gim_bvh_free(&wb);
    }
    gim_bvh_free(&b);
    assert_int_equal(as.live, 0);
    free(pos);
}

/* gim_second_bounce_rays_twin's closed forms: a cosine emitter under a large ceiling of albedo
   rho returns rho Phi in all, R^2 / (R^2 + h^2) of it within R of the point above it; of four
   VPLs (flux 3, 1, unlit, not finite) each owns a quarter of the rays (its stratum), the unlit
   and non-finite ones send none, the others carry rho Phi_i / (S / 4) each; a closed box keeps
   every ray, and for grey VPLs its flux is the walls' albedo times sum Phi exactly for any N
   and S (sum_j W_j = sum_i w_i); fluxes changed by 1% move few rays (the strata), where one
   pick over all VPLs' running sums moved nearly all. Each ray's area is one over the landings'
   density had every VPL sent its flux's share of the rays (closed form); where the strata
   share them so, the areas tile the ceiling (their sum over a disc its area). Bad input
   refused. */
static void second_bounce_rays_closed_forms(void **state) {
    test_alloc_stats as;
    gim_env env = test_env(&as, NULL);
    enum { S = 8192 };
    float ceil_[18], box[12 * 9], alb[12 * 3], c[3] = {-500, 1, -500}, u[3] = {1000, 0, 0}, v[3] = {0, 0, 1000};
    gim_vpl vp[4], *out = (gim_vpl *)malloc(S * sizeof(gim_vpl));
    gim_second_bounce_rays_desc d;
    gim_twin_scene sc;
    gim_bvh b;
    double total, inside, from0, want;
    uint32_t j, k, lit;
    (void)state;
    quad(ceil_, 0, c, u, v);
    for (k = 0; k < 12 * 3; ++k) alb[k] = k % 3 == 0 ? 0.5f : k % 3 == 1 ? 0.25f : 0.75f;
    memset(&sc, 0, sizeof sc);
    sc.positions = ceil_; sc.triangle_count = 2; sc.albedo = alb;
    assert_int_equal(gim_bvh_build(&sc, env, &b), GIM_OK);
    memset(vp, 0, sizeof vp);
    vp[0].lit = 1.0f; vp[0].normal[1] = 1.0f; vp[0].flux[0] = vp[0].flux[1] = vp[0].flux[2] = 3.0f;
    vp[1] = vp[0]; vp[1].position[0] = 0.25f; vp[1].flux[0] = vp[1].flux[1] = vp[1].flux[2] = 1.0f;
    vp[2] = vp[0]; vp[2].lit = 0.0f;                 /* unlit: never picked */
    vp[3] = vp[0]; vp[3].flux[1] = NAN;              /* not finite: never picked */
    memset(&d, 0, sizeof d);
    d.bvh = &b; d.albedo = alb; d.vpls = vp; d.vpl_count = 4; d.count = S; d.scene_scale = 10.0f; d.env = env;
    assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_OK);
    total = inside = from0 = 0.0;
    for (j = 0, lit = 0; j < S; ++j) {
        double x, z, f = out[j].flux[0];
        if (!(out[j].lit > 0.0f)) continue;
        ++lit;
        assert_true(fabsf(out[j].position[1] - 1.0f) < 1e-5f && out[j].normal[1] == -1.0f);
        assert_true(fabsf(out[j].flux[1] / out[j].flux[0] - 0.5f) < 1e-5f);   /* the albedo's colour */
        assert_true(j < S / 2u);                                           /* strata 2, 3: unlit, not finite */
        want = 0.5 * (j < S / 4u ? 3.0 : 1.0) * 4.0 / S;                   /* rho Phi_i / (S / 4) */
        assert_true(fabs(f - want) < 1e-6 * want);
        x = out[j].position[0] - (j < S / 4u ? 0.0 : 0.25);               /* stratum 0: VPL 0 */
        z = out[j].position[2];
        total += f;
        if (x * x + z * z < 1.0) inside += f;
        if (j < S / 4u) from0 += f;
    }
    want = 0.5 * 4.0;   /* rho (Phi_0 + Phi_1) */
    print_message("ceiling: %u of %u rays land, flux %.5f (closed form %.5f), within 1 of the point above %.4f "
                  "(1 / 2), from the brighter VPL %.4f (3 / 4)\n", lit, (unsigned)S, total, want, inside / total,
                  from0 / total);
    assert_true(lit >= S / 2u - 4u);   /* a few leave parallel to the ceiling, past its edge */
    assert_true(fabs(total / want - 1.0) < 2e-3);
    assert_true(fabs(inside / total - 0.5) < 0.01);
    assert_true(fabs(from0 / total - 0.75) < 1e-3);
    /* the areas: one over the landings' density as if each VPL sent its flux's share S w_i / W
       of the rays, S (9 / d_0^4 + 3 / d_1^4) / (pi 12) at h = 1 */
    for (j = 0; j < S; ++j) {
        double x0 = out[j].position[0], x1 = x0 - 0.25, z = out[j].position[2], d0, d1, a;
        if (!(out[j].lit > 0.0f)) continue;
        d0 = x0 * x0 + z * z + 1.0;
        d1 = x1 * x1 + z * z + 1.0;
        a = 3.14159265358979 * 12.0 / (S * (9.0 / (d0 * d0) + 3.0 / (d1 * d1)));
        if (fabs(out[j].area - a) > 2e-4 * a) print_message("ray %u: area %.6g, closed form %.6g\n", j, out[j].area, a);
        assert_true(fabs(out[j].area - a) < 2e-4 * a);
    }
    /* where the strata share the rays by flux (two VPLs of one flux, S / 2 rays each) the areas
       tile the ceiling: those landing within 1 of the point above VPL 0 sum to pi */
    vp[0].flux[0] = vp[0].flux[1] = vp[0].flux[2] = 1.0f;
    d.vpl_count = 2;
    assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_OK);
    for (j = 0, inside = 0.0, lit = 0; j < S; ++j) {
        double x0 = out[j].position[0], z = out[j].position[2];
        if (out[j].lit > 0.0f && x0 * x0 + z * z < 1.0) inside += out[j].area, ++lit;
    }
    print_message("ceiling, two VPLs of one flux: the areas of the %u rays landing within 1 of the point above "
                  "VPL 0 sum to %.4f (pi)\n", lit, inside);
    assert_true(fabs(inside / 3.14159265358979 - 1.0) < 0.02);
    vp[0].flux[0] = vp[0].flux[1] = vp[0].flux[2] = 3.0f;
    d.vpl_count = 4;
    gim_bvh_free(&b);
    {   /* a closed box [-1, 1]^3 (12 triangles): every ray lands, the flux is the walls' albedo times Phi */
        float cs[6][9] = {{-1, -1, -1, 2, 0, 0, 0, 2, 0}, {-1, -1, 1, 2, 0, 0, 0, 2, 0}, {-1, -1, -1, 0, 2, 0, 0, 0, 2},
                          {1, -1, -1, 0, 2, 0, 0, 0, 2},  {-1, -1, -1, 2, 0, 0, 0, 0, 2}, {-1, 1, -1, 2, 0, 0, 0, 0, 2}};
        static const uint32_t ns[4] = {1, 5, 64, 4096}, ss[5] = {1, 3, 7, 256, 1024};
        gim_vpl *many = (gim_vpl *)calloc(4096, sizeof(gim_vpl)), *again = (gim_vpl *)malloc(S * sizeof(gim_vpl));
        uint32_t ni, si, moved = 0;
        double got = 0.0;
        for (k = 0; k < 6; ++k) quad(box, 2 * k, cs[k], cs[k] + 3, cs[k] + 6);
        sc.positions = box; sc.triangle_count = 12;
        assert_int_equal(gim_bvh_build(&sc, env, &b), GIM_OK);
        test_rng_state = 11;
        for (k = 0; k < 4096u; ++k) {   /* grey VPLs on the floor, fluxes 0.5..1.5 */
            gim_vpl *m = many + k;
            m->lit = 1.0f; m->normal[1] = 1.0f;
            m->position[0] = test_rnd(-0.9f, 0.9f); m->position[1] = -1.0f; m->position[2] = test_rnd(-0.9f, 0.9f);
            m->flux[0] = m->flux[1] = m->flux[2] = test_rnd(0.5f, 1.5f);
        }
        d.vpls = many; d.scene_scale = 3.5f;
        for (ni = 0; ni < 4u; ++ni)
            for (si = 0; si < 5u; ++si) {
                double sum = 0.0;
                got = 0.0;
                d.vpl_count = ns[ni]; d.count = ss[si];
                for (k = 0; k < ns[ni]; ++k) sum += many[k].flux[2];
                assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_OK);
                for (j = 0; j < ss[si]; ++j) {
                    assert_true(out[j].lit == 1.0f);
                    got += out[j].flux[2];
                }
                if (fabs(got / (0.75 * sum) - 1.0) >= 1e-4)
                    print_message("closed box, %u VPLs, %u rays: flux %.6f (closed form %.6f)\n", (unsigned)ns[ni],
                                  (unsigned)ss[si], got, 0.75 * sum);
                assert_true(fabs(got / (0.75 * sum) - 1.0) < 1e-4);
            }
        /* 4096 VPLs, 256 rays: every flux changed by up to 1% moves few rays */
        d.vpl_count = 4096; d.count = 256;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_OK);
        for (k = 0; k < 4096u; ++k) many[k].flux[0] = many[k].flux[1] = many[k].flux[2] *= test_rnd(0.99f, 1.01f);
        assert_int_equal(gim_second_bounce_rays_twin(&d, again), GIM_OK);
        for (j = 0; j < 256u; ++j) moved += memcmp(out[j].position, again[j].position, sizeof out[j].position) != 0;
        print_message("closed box: fluxes changed by up to 1%%: %u of 256 rays moved\n", (unsigned)moved);
        assert_true(moved < 26u);
        free(many);
        free(again);
        d.vpls = vp;
        d.vpl_count = 1; d.count = 1024;
        /* bad input */
        d.count = 0;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_ERROR_OUT_OF_RANGE);
        d.count = 16; d.vpl_count = 0;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_ERROR_OUT_OF_RANGE);
        d.vpl_count = 1; d.scene_scale = 0.0f;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        d.scene_scale = 1.0f; d.albedo = NULL;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        alb[4] = -1.0f; d.albedo = alb;
        assert_int_equal(gim_second_bounce_rays_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim_second_bounce_rays_twin(&d, NULL), GIM_ERROR_INVALID_ARGUMENT);
        gim_bvh_free(&b);
    }
    assert_int_equal(as.live, 0);
    free(out);
}

/* The triangle test against an exact one in double where the hit is clear of the triangle's
   edges and the segment's ends (by 3e-4 in barycentrics and t: the triangles grow by 1e-4). */
static void triangle_test_is_exact_away_from_edges(void **state) {
    gim_env env = test_env(NULL, NULL);
    uint32_t i, checked = 0;
    (void)state;
    test_rng_state = 11;
    for (i = 0; i < 20000; ++i) {
        float tri[9];
        gim_vec3 p = rnd_point(-1.0f, 1.0f), q = rnd_point(-1.0f, 1.0f);
        double e1[3], e2[3], d[3], s[3], pv[3], qv[3], det, u, v, t;
        int k;
        gim_bvh b;
        for (k = 0; k < 9; ++k) tri[k] = test_rnd(-1.0f, 1.0f);
        for (k = 0; k < 3; ++k) {
            e1[k] = (double)tri[3 + k] - tri[k];
            e2[k] = (double)tri[6 + k] - tri[k];
            s[k] = (double)(k == 0 ? p.x : k == 1 ? p.y : p.z) - tri[k];
        }
        d[0] = (double)q.x - p.x; d[1] = (double)q.y - p.y; d[2] = (double)q.z - p.z;
        pv[0] = d[1] * e2[2] - d[2] * e2[1]; pv[1] = d[2] * e2[0] - d[0] * e2[2]; pv[2] = d[0] * e2[1] - d[1] * e2[0];
        det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (fabs(det) < 1e-3) continue;
        qv[0] = s[1] * e1[2] - s[2] * e1[1]; qv[1] = s[2] * e1[0] - s[0] * e1[2]; qv[2] = s[0] * e1[1] - s[1] * e1[0];
        u = (s[0] * pv[0] + s[1] * pv[1] + s[2] * pv[2]) / det;
        v = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
        t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (fabs(u) < 3e-4 || fabs(v) < 3e-4 || fabs(1.0 - u - v) < 3e-4 || fabs(t) < 3e-4 || fabs(1.0 - t) < 3e-4) continue;
        b = build(tri, 1, env);
        assert_int_equal(gim_bvh_occluded(&b, p, q), u > 0.0 && v > 0.0 && u + v < 1.0 && t > 0.0 && t < 1.0);
        gim_bvh_free(&b);
        ++checked;
    }
    assert_true(checked > 15000);
}

/* A wall x in [-1, 1], y in [0, 2] at z = 0 (two triangles), at scale s around origin o. */
static void wall_answers(float s, float ox, float oy, float oz) {
    gim_env env = test_env(NULL, NULL);
    float pos[18], c[3] = {-1, 0, 0}, u[3] = {2, 0, 0}, v[3] = {0, 2, 0};
    int k;
    gim_bvh b;
    gim_vec3 a;
#define P(x, y, z) gim_v3(ox + s * (x), oy + s * (y), oz + s * (z))
    for (k = 0; k < 3; ++k) { c[k] *= s; u[k] *= s; v[k] *= s; }
    c[0] += ox; c[1] += oy; c[2] += oz;
    quad(pos, 0, c, u, v);
    b = build(pos, 2, env);
    a = P(0.3f, 1.1f, -1.0f);
    assert_true(gim_bvh_occluded(&b, a, P(0.3f, 1.1f, 1.0f)));        /* through the wall */
    assert_true(gim_bvh_occluded(&b, a, P(-0.9f, 0.2f, 0.5f)));       /* obliquely through it */
    assert_true(gim_bvh_occluded(&b, a, P(0.0f, 1.0f, 1.0f)));        /* across the diagonal shared by its triangles */
    assert_false(gim_bvh_occluded(&b, a, P(0.3f, 1.1f, -0.01f)));     /* stops short of it */
    assert_false(gim_bvh_occluded(&b, a, P(2.5f, 1.1f, 1.0f)));       /* passes beside it (z = 0 at x = 1.4) */
    assert_false(gim_bvh_occluded(&b, a, P(0.3f, 4.0f, 1.0f)));       /* over it (z = 0 at y = 2.55) */
    assert_false(gim_bvh_occluded(&b, P(-0.5f, 1.0f, 0.001f), P(0.5f, 1.0f, 0.001f)));   /* along it, just off */
    assert_false(gim_bvh_occluded(&b, P(-0.5f, 1.0f, -0.5f), P(0.5f, 1.0f, -0.2f)));    /* both ends on one side */
    assert_false(gim_bvh_occluded(&b, a, a));                                          /* no length */
    for (k = 0; k < 200; ++k) {   /* through points of the shared diagonal y = x + 1: none slips between */
        float x = -0.95f + 1.9f * (float)k / 199.0f, y = x + 1.0f;
        assert_true(gim_bvh_occluded(&b, P(x + 0.2f, y + 0.3f, -1.0f), P(x - 0.2f, y - 0.3f, 1.0f)));
        assert_true(gim_bvh_occluded(&b, P(x - 0.7f, y + 0.1f, 0.6f), P(x + 0.7f, y - 0.1f, -0.6f)));
    }
#undef P
    gim_bvh_free(&b);
}

static void closed_forms_at_any_scale(void **state) {
    (void)state;
    wall_answers(1.0f, 0.0f, 0.0f, 0.0f);
    wall_answers(1e-3f, 0.0f, 0.0f, 0.0f);
    wall_answers(1e3f, 0.0f, 0.0f, 0.0f);
    wall_answers(1e-12f, 0.0f, 0.0f, 0.0f);
    wall_answers(1e12f, 0.0f, 0.0f, 0.0f);
    wall_answers(1e-15f, 0.0f, 0.0f, 0.0f);   /* the library's range: its triple products would under- and */
    wall_answers(1e15f, 0.0f, 0.0f, 0.0f);    /* overflow float but for the hierarchy's frame */
    wall_answers(1.0f, 500.0f, -300.0f, 200.0f);    /* far from the origin: hundreds of walls away */
    wall_answers(1e3f, -4e5f, 2e5f, 1e5f);
}

/* Layouts that defeat the surface-area splits (every centroid in one spot, or spaced
   geometrically) stay within the depth bound and still answer as every triangle does. */
static void degenerate_layouts(void **state) {
    test_alloc_stats as;
    gim_env env = test_env(&as, NULL);
    enum { N = 3000 };
    float *pos = (float *)calloc(N * 9, sizeof(float));
    uint32_t t, i;
    gim_bvh b;
    gim_twin_scene s;
    (void)state;
    for (t = 0; t < N; ++t) {   /* one triangle repeated */
        pos[t * 9 + 3] = 1.0f; pos[t * 9 + 7] = 1.0f;
    }
    b = build(pos, N, env);
    check_tree(&b);
    assert_true(gim_bvh_occluded(&b, gim_v3(0.2f, 0.2f, -1.0f), gim_v3(0.2f, 0.2f, 1.0f)));
    assert_false(gim_bvh_occluded(&b, gim_v3(0.8f, 0.8f, -1.0f), gim_v3(0.8f, 0.8f, 1.0f)));
    gim_bvh_free(&b);
    for (t = 0; t < N; ++t) {   /* geometric spacing: each a tenth smaller and nearer the origin */
        float x = (float)pow(0.9, (double)t);
        memset(pos + t * 9, 0, 9 * sizeof(float));
        pos[t * 9] = x; pos[t * 9 + 3] = x * 1.01f; pos[t * 9 + 7] = x * 0.01f; pos[t * 9 + 2] = 0.0f;
    }
    b = build(pos, N, env);
    check_tree(&b);
    test_rng_state = 3;
    for (i = 0; i < 200; ++i) {
        gim_vec3 p = gim_v3(test_rnd(0.0f, 1.1f), test_rnd(-0.01f, 0.02f), -1.0f), q = gim_v3(p.x, p.y, 1.0f);
        assert_int_equal(gim_bvh_occluded(&b, p, q), brute(&b, p, q));
    }
    gim_bvh_free(&b);
    /* degenerate triangles (a point, a line) are kept and block nothing */
    memset(pos, 0, 18 * sizeof(float));
    pos[3] = 1.0f; pos[6] = 2.0f;
    b = build(pos, 2, env);
    assert_false(gim_bvh_occluded(&b, gim_v3(0.0f, 0.0f, -1.0f), gim_v3(0.0f, 0.0f, 1.0f)));
    assert_false(gim_bvh_occluded(&b, gim_v3(1.0f, -1.0f, 0.0f), gim_v3(1.0f, 1.0f, 0.0f)));
    gim_bvh_free(&b);
    /* no triangle: nothing blocks */
    memset(&s, 0, sizeof s);
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_OK);
    assert_int_equal(b.node_count, 0);
    assert_false(gim_bvh_occluded(&b, gim_v3(0, 0, -1), gim_v3(0, 0, 1)));
    gim_bvh_free(&b);
    assert_int_equal(as.live, 0);
    free(pos);
}

static void bad_input(void **state) {
    test_alloc_stats as;
    test_log lg;
    gim_env env = test_env(&as, &lg);
    float pos[18], c[3] = {0, 0, 0}, u[3] = {1, 0, 0}, v[3] = {0, 1, 0};
    gim_twin_scene s;
    gim_bvh b;
    long k;
    (void)state;
    quad(pos, 0, c, u, v);
    memset(&s, 0, sizeof s);
    s.positions = pos;
    s.triangle_count = 2;
    assert_int_equal(gim_bvh_build(NULL, env, &b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_bvh_build(&s, env, NULL), GIM_ERROR_INVALID_ARGUMENT);
    pos[13] = NAN;
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "triangle 1"));
    pos[13] = INFINITY;
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_INVALID_ARGUMENT);
    pos[13] = 1.0f;
    s.triangle_count = GIM_BVH_MAX_TRIANGLES + 1u;
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_OUT_OF_RANGE);
    s.triangle_count = 2;
    pos[13] = 3e38f; pos[4] = -3e38f;   /* bounds wider than a float */
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_OUT_OF_RANGE);
    pos[13] = 1.0f; pos[4] = 0.0f;
    s.triangle_count = 2;
    s.positions = NULL;
    assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_INVALID_ARGUMENT);
    s.positions = pos;
    for (k = 0; k < 6; ++k) {   /* each allocation failing in turn: an error, nothing left */
        as.fail_after = as.allocs + k;
        assert_int_equal(gim_bvh_build(&s, env, &b), GIM_ERROR_OUT_OF_MEMORY);
        assert_int_equal(as.live, 0);
    }
    as.fail_after = -1;
    b = build(pos, 2, env);
    assert_false(gim_bvh_occluded(NULL, gim_v3(0, 0, -1), gim_v3(0, 0, 1)));
    assert_false(gim_bvh_occluded(&b, gim_v3(0.2f, 0.2f, NAN), gim_v3(0.2f, 0.2f, 1)));
    assert_false(gim_bvh_occluded(&b, gim_v3(0.2f, 0.2f, -1), gim_v3(0.2f, 0.2f, INFINITY)));
    assert_true(gim_bvh_occluded(&b, gim_v3(0.2f, 0.2f, -1), gim_v3(0.2f, 0.2f, 1)));
    gim_bvh_free(&b);
    gim_bvh_free(&b);   /* twice, and NULL: fine */
    gim_bvh_free(NULL);
    assert_int_equal(as.live, 0);
}

/* A floor z = 0 in [-4, 4]^2 split by a wall x = 0 (y from -4 to 4, z up to 2); caches on both
   sides of the wall, receivers on its left. */
static void neighbour_rows(void **state) {
    test_alloc_stats as;
    test_log lg;
    gim_env env = test_env(&as, &lg);
    float pos[18], c[3] = {0, -4, 0}, u[3] = {0, 8, 0}, v[3] = {0, 0, 2};
    gim_cache caches[6];
    gim_receiver rc[3];
    uint32_t idx[3 * 4], cnt[3], oi[3 * 4], oc[3], i;
    float od[3];
    gim_neighbour_rays_desc d;
    gim_neighbour_result out;
    gim_bvh b;
    (void)state;
    quad(pos, 0, c, u, v);
    b = build(pos, 2, env);
    memset(caches, 0, sizeof caches);
    for (i = 0; i < 6; ++i) {   /* left at x = -0.5, -1.5, -2.5; right at x = 0.5, 1.5, 2.5 */
        caches[i].position[0] = i < 3 ? -0.5f - (float)i : 0.5f + (float)(i - 3);
        caches[i].position[1] = 0.25f * (float)i;
        caches[i].normal[2] = 1.0f;
        caches[i].area = 1.0f;
    }
    memset(rc, 0, sizeof rc);
    rc[0].position[0] = -0.25f; rc[0].normal[2] = 1.0f;   /* beside the wall, on its left */
    rc[1].position[0] = -2.0f; rc[1].position[1] = 1.0f; rc[1].normal[2] = 1.0f;
    rc[2].position[0] = 0.25f; rc[2].normal[2] = 1.0f;    /* on the right, its row all on the left */
    /* rows nearest first, mixed sides */
    idx[0] = 0; idx[1] = 3; idx[2] = 1; idx[3] = 4; cnt[0] = 4;
    idx[4] = 1; idx[5] = 2; idx[6] = 0; idx[7] = 3; cnt[1] = 4;
    idx[8] = 0; idx[9] = 1; idx[10] = UINT32_MAX; idx[11] = UINT32_MAX; cnt[2] = 2;
    memset(&d, 0, sizeof d);
    d.bvh = &b; d.caches = caches; d.cache_count = 6; d.receivers = rc; d.receiver_count = 3;
    d.neighbour_index = idx; d.neighbour_count = cnt; d.neighbour_stride = 4; d.scene_scale = 10.0f; d.env = env;
    out.index = oi; out.count = oc; out.d_cmax = od;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_OK);
    assert_int_equal(oc[0], 2);
    assert_int_equal(oi[0], 0); assert_int_equal(oi[1], 1); assert_int_equal(oi[2], UINT32_MAX);
    assert_float_equal(od[0], (float)sqrt(1.25 * 1.25 + 0.25 * 0.25), 1e-6f);   /* cache 1 at (-1.5, 0.25) */
    assert_int_equal(oc[1], 3);
    assert_int_equal(oi[4], 1); assert_int_equal(oi[5], 2); assert_int_equal(oi[6], 0); assert_int_equal(oi[7], UINT32_MAX);
    assert_int_equal(oc[2], 2);   /* sees neither: keeps both */
    assert_int_equal(oi[8], 0); assert_int_equal(oi[9], 1);
    assert_float_equal(od[2], (float)sqrt(1.75 * 1.75 + 0.25 * 0.25), 1e-6f);
    /* in place */
    out.index = idx; out.count = cnt;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_OK);
    assert_memory_equal(idx, oi, sizeof oi);
    assert_memory_equal(cnt, oc, sizeof oc);
    /* an empty hierarchy hides nothing */
    {
        gim_bvh none;
        memset(&none, 0, sizeof none);
        idx[0] = 0; idx[1] = 3; idx[2] = 1; idx[3] = 4; cnt[0] = 4;
        d.bvh = &none;
        d.receiver_count = 1;
        assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_OK);
        assert_int_equal(cnt[0], 4);
        assert_int_equal(idx[1], 3);
        d.bvh = &b;
        d.receiver_count = 3;
    }
    /* bad input: refused with a line */
    out.index = oi; out.count = oc;
    idx[0] = 6; cnt[0] = 4;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "cache 6"));
    idx[0] = 0; cnt[0] = 5;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    cnt[0] = 4;
    d.scene_scale = 0.0f;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    d.scene_scale = 10.0f;
    d.neighbour_stride = GIM_MAX_NEIGHBOUR_CACHES + 1u;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    d.neighbour_stride = 4;
    d.bvh = NULL;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    d.bvh = &b;
    out.d_cmax = NULL;
    assert_int_equal(gim_neighbour_rays_twin(&d, &out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_neighbour_rays_twin(NULL, &out), GIM_ERROR_INVALID_ARGUMENT);
    gim_bvh_free(&b);
    assert_int_equal(as.live, 0);
}

/* The caches' side (gim_val_rays_twin): a plate [-0.5, 0.5]^2 at y = 1 over VALs on the floor
   y = 0, caches at y = 2 facing down; each entry against the exact crossing of the lifted
   segment with the plate, where it lies clear of the plate's edges. */
static void val_rays_matrix(void **state) {
    test_alloc_stats as;
    test_log lg;
    gim_env env = test_env(&as, &lg);
    float pos[18], c[3] = {-0.5f, 1.0f, -0.5f}, u[3] = {0, 0, 1}, v[3] = {1, 0, 0};
    enum { C = 20, V = 60 };
    gim_cache caches[C];
    gim_val vals[V];
    float m[C * V];
    uint32_t i, j, checked = 0, hidden = 0;
    gim_bvh b;
    (void)state;
    quad(pos, 0, c, u, v);
    b = build(pos, 2, env);
    test_rng_state = 5;
    memset(caches, 0, sizeof caches);
    memset(vals, 0, sizeof vals);
    for (i = 0; i < C; ++i) {
        caches[i].position[0] = test_rnd(-1.0f, 1.0f); caches[i].position[1] = 2.0f; caches[i].position[2] = test_rnd(-1.0f, 1.0f);
        caches[i].normal[1] = -1.0f;
        caches[i].area = 0.1f;
    }
    for (j = 0; j < V; ++j) {
        vals[j].position[0] = test_rnd(-2.0f, 2.0f); vals[j].position[2] = test_rnd(-2.0f, 2.0f);
        vals[j].normal[1] = 1.0f;
        vals[j].area = 0.1f; vals[j].weight = 1.0f; vals[j].flux[0] = vals[j].flux[1] = vals[j].flux[2] = 1.0f;
    }
    assert_int_equal(gim_val_rays_twin(&b, caches, C, vals, V, 1.0f, env, m), GIM_OK);
    for (i = 0; i < C; ++i)
        for (j = 0; j < V; ++j) {
            double y0 = 2.0 - 1e-3, y1 = 1e-3, t = (y0 - 1.0) / (y0 - y1);
            double x = caches[i].position[0] + t * (vals[j].position[0] - caches[i].position[0]);
            double z = caches[i].position[2] + t * (vals[j].position[2] - caches[i].position[2]);
            double edge = fmin(0.5 - fabs(x), 0.5 - fabs(z));
            assert_true(m[i * V + j] == 0.0f || m[i * V + j] == 1.0f);
            if (fabs(edge) < 1e-3) continue;
            assert_true(m[i * V + j] == (edge > 0.0 ? 0.0f : 1.0f));
            hidden += edge > 0.0;
            ++checked;
        }
    assert_true(checked > C * V * 9 / 10 && hidden > 50 && hidden < checked - 50);
    /* the same scene a million times larger, far from the origin: the same matrix */
    {
        float big[18], m2[C * V];
        gim_cache c2[C];
        gim_val v2[V];
        gim_bvh b2;
        uint32_t k;
        for (k = 0; k < 18; ++k) big[k] = pos[k] * 1e6f + (k % 3 == 0 ? 3e8f : 0.0f);
        memcpy(c2, caches, sizeof c2);
        memcpy(v2, vals, sizeof v2);
        for (i = 0; i < C; ++i) for (k = 0; k < 3; ++k) c2[i].position[k] = c2[i].position[k] * 1e6f + (k == 0 ? 3e8f : 0.0f);
        for (j = 0; j < V; ++j) for (k = 0; k < 3; ++k) v2[j].position[k] = v2[j].position[k] * 1e6f + (k == 0 ? 3e8f : 0.0f);
        b2 = build(big, 2, env);
        assert_int_equal(gim_val_rays_twin(&b2, c2, C, v2, V, 1e6f, env, m2), GIM_OK);
        for (k = 0, checked = 0; k < C * V; ++k) checked += m2[k] != m[k];
        assert_true(checked <= C * V / 200);   /* only where a crossing lies within float rounding of an edge */
        gim_bvh_free(&b2);
    }
    assert_int_equal(gim_val_rays_twin(NULL, caches, C, vals, V, 1.0f, env, m), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_val_rays_twin(&b, caches, C, vals, V, 0.0f, env, m), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_val_rays_twin(&b, caches, C, NULL, V, 1.0f, env, m), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_val_rays_twin(&b, caches, C, NULL, 0, 1.0f, env, m), GIM_OK);   /* no VAL: nothing to test */
    gim_bvh_free(&b);
    assert_int_equal(as.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(traversal_equals_every_triangle),
        cmocka_unit_test(nearest_equals_every_triangle),
        cmocka_unit_test(second_bounce_rays_closed_forms),
        cmocka_unit_test(triangle_test_is_exact_away_from_edges),
        cmocka_unit_test(closed_forms_at_any_scale),
        cmocka_unit_test(degenerate_layouts),
        cmocka_unit_test(bad_input),
        cmocka_unit_test(neighbour_rows),
        cmocka_unit_test(val_rays_matrix),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
