/* The paraboloid-map texel twin (Dong sec. 4.2, SSVP sec. 3.C; conventions in gimany.h
   @section twins) against hand-derived cases: a plane at a known distance (every texel's
   distance h / w.z, the centre texel exactly h, tilted maps), texels outside the unit disk,
   near_distance skipping the nearer of two planes, two-sided normals towards the origin,
   interpolated normals and the triangle's albedo, unit-free scaling, bad input. And the
   second-bounce VPLs: the per-map split of the count, the texels of the Hammersley points,
   energy (the estimator's flux sums to albedo * Phi_m when the hemisphere is closed, half of
   it when half is), unlit VPLs where nothing or broken data is hit, bad input. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define PI_D 3.14159265358979323846

/* A square [-L, L]^2 at height z (two triangles), winding flipped when flip; albedo rgb. */
static void square(float *pos, float *alb, float L, float z, int flip, const float rgb[3]) {
    const float q[4][3] = {{-L, -L, z}, {L, -L, z}, {L, L, z}, {-L, L, z}};
    const int tri[2][3] = {{0, 1, 2}, {0, 2, 3}};
    int t, k;
    for (t = 0; t < 2; ++t) {
        for (k = 0; k < 3; ++k) memcpy(pos + t * 9 + k * 3, q[tri[t][flip ? 2 - k : k]], 3 * sizeof(float));
        memcpy(alb + t * 3, rgb, 3 * sizeof(float));
    }
}

static gim_paraboloid map_at(float ox, float oy, float oz, float nx, float ny, float nz, float near_d) {
    gim_paraboloid m;
    float l = sqrtf(nx * nx + ny * ny + nz * nz);
    memset(&m, 0, sizeof m);
    m.origin[0] = ox; m.origin[1] = oy; m.origin[2] = oz;
    m.normal[0] = nx / l; m.normal[1] = ny / l; m.normal[2] = nz / l;
    m.near_distance = near_d;
    m.flux[0] = 1.0f; m.flux[1] = 2.0f; m.flux[2] = 0.5f;
    return m;
}

/* The world direction of texel (x, y), derived from the header's convention. */
static void texel_dir(const gim_paraboloid *m, uint32_t size, uint32_t x, uint32_t y, double d[3], double *r2) {
    double u = (2.0 * x + 1.0) / size - 1.0, v = (2.0 * y + 1.0) / size - 1.0, w[3];
    gim_vec3 t, b, n = gim_v3(m->normal[0], m->normal[1], m->normal[2]);
    int i;
    *r2 = u * u + v * v;
    w[0] = 2.0 * u / (1.0 + *r2); w[1] = 2.0 * v / (1.0 + *r2); w[2] = (1.0 - *r2) / (1.0 + *r2);
    gim__basis(gim_v3_normalize(n), &t, &b);
    n = gim_v3_normalize(n);
    for (i = 0; i < 3; ++i) d[i] = w[0] * (&t.x)[i] + w[1] * (&b.x)[i] + w[2] * (&n.x)[i];
}

/* A plane z = h far wider than the map sees (untilted) or tilted: distance h / d.z. */
static void plane_distance(void **state) {
    static const float rgb[3] = {0.3f, 0.6f, 0.9f};
    const float h = 2.5f, L = 1e4f;
    float pos[18], alb[6];
    gim_twin_scene s;
    gim_paraboloid maps[3];
    uint32_t size = 17, x, y, inside = 0, hits = 0, mi;
    (void)state;
    square(pos, alb, L, h, 0, rgb);
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.triangle_count = 2;
    maps[0] = map_at(0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f);
    maps[1] = map_at(0.3f, -0.2f, 0.5f, 0.3f, 0.1f, 1.0f, 0.0f);
    maps[2] = map_at(0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.2f, 0.0f);  /* grazing: most of the map misses */
    for (mi = 0; mi < 3; ++mi) {
        const gim_paraboloid *m = &maps[mi];
        for (y = 0; y < size; ++y)
            for (x = 0; x < size; ++x) {
                gim_paraboloid_texel o;
                double d[3], r2, dist;
                int i;
                assert_int_equal(gim_paraboloid_texel_twin(&s, m, size, x, y, &o), GIM_OK);
                texel_dir(m, size, x, y, d, &r2);
                if (r2 > 1.0) {
                    assert_int_equal(o.hit, 0);
                    assert_true(o.distance == GIM_PARABOLOID_EMPTY);
                    assert_int_equal(o.triangle, UINT32_MAX);
                    continue;
                }
                inside++;
                dist = (h - m->origin[2]) / d[2];
                if (!(d[2] > 1e-9) || fabs(m->origin[0] + dist * d[0]) > L * 0.999 || fabs(m->origin[1] + dist * d[1]) > L * 0.999) {
                    if (d[2] <= 0.0) assert_int_equal(o.hit, 0);
                    continue;
                }
                assert_int_equal(o.hit, 1);
                hits++;
                assert_true(o.triangle < 2);
                if (fabs(o.distance - dist) > 1e-6 * dist) fail_msg("map %u texel %u %u: %.9g, expected %.9g", mi, x, y, (double)o.distance, dist);
                for (i = 0; i < 3; ++i) {
                    assert_true(fabs(o.position[i] - (m->origin[i] + dist * d[i])) <= 1e-6 * (dist + 1.0));
                    assert_true(o.albedo[i] == rgb[i]);
                }
                /* the face normal, turned towards the origin (below the plane): -z */
                assert_true(o.normal[0] == 0.0f && o.normal[1] == 0.0f && o.normal[2] == -1.0f);
            }
    }
    assert_true(hits > inside / 2);
    { /* the centre texel of the untilted map looks straight up: exactly h */
        gim_paraboloid_texel o;
        assert_int_equal(gim_paraboloid_texel_twin(&s, &maps[0], size, 8, 8, &o), GIM_OK);
        assert_true(o.hit && o.distance == h && o.position[0] == 0.0f && o.position[1] == 0.0f && o.position[2] == h);
    }
}

/* Texels outside the unit disk hold nothing even with geometry everywhere around; the count
   of texels inside is the disk's share of the square. */
static void outside_disk(void **state) {
    static const float rgb[3] = {1, 1, 1};
    float pos[36], alb[12];
    gim_twin_scene s;
    gim_paraboloid m = map_at(0, 0, 0, 0, 0, 1, 0);
    uint32_t size = 32, x, y, hits = 0;
    (void)state;
    square(pos, alb, 1e4f, 1.0f, 0, rgb);   /* wide enough for the texel nearest the rim (w.z ~ 0.003) */
    square(pos + 18, alb + 6, 1e4f, -1e-3f, 1, rgb);  /* the horizon: z slightly below the origin */
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.triangle_count = 4;
    for (y = 0; y < size; ++y)
        for (x = 0; x < size; ++x) {
            gim_paraboloid_texel o;
            double u = (2.0 * x + 1.0) / size - 1.0, v = (2.0 * y + 1.0) / size - 1.0;
            assert_int_equal(gim_paraboloid_texel_twin(&s, &m, size, x, y, &o), GIM_OK);
            assert_int_equal(o.hit, u * u + v * v <= 1.0);
            if (o.hit) { hits++; assert_true(o.triangle < 2); }   /* the floor below is never seen */
        }
    assert_true(fabs(hits / (double)(size * size) - PI_D / 4.0) < 0.02);
}

/* Two planes at 1 and 2: near_distance below 1 sees the first, between them the second,
   beyond both nothing, and attribute_near the same for the attributes, each on its own; a
   plane behind the origin's plane is never seen. */
static void near_distance(void **state) {
    static const float a[3] = {1, 0, 0}, b[3] = {0, 1, 0};
    float pos[36], alb[12];
    gim_twin_scene s;
    gim_paraboloid_texel o;
    gim_paraboloid m = map_at(0, 0, 0, 0, 0, 1, 0.5f);
    (void)state;
    square(pos, alb, 10.0f, 1.0f, 0, a);
    square(pos + 18, alb + 6, 10.0f, 2.0f, 1, b);
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.triangle_count = 4;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.hit && o.distance == 1.0f && o.albedo[0] == 1.0f && o.triangle < 2);
    assert_true(o.attribute_hit && o.attribute_distance == 1.0f && o.attribute_triangle < 2);
    m.near_distance = 1.5f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.hit && o.distance == 2.0f && o.triangle >= 2);
    /* the attribute maps keep their own skip (0 here): the nearer plane */
    assert_true(o.attribute_hit && o.attribute_distance == 1.0f && o.albedo[0] == 1.0f && o.attribute_triangle < 2);
    m.attribute_near = 1.5f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.attribute_hit && o.attribute_distance == 2.0f && o.albedo[1] == 1.0f && o.attribute_triangle >= 2);
    assert_true(o.normal[2] == -1.0f);  /* wound the other way: still towards the origin */
    m.near_distance = m.attribute_near = 1.0f;   /* strictly beyond: a hit at exactly near is skipped */
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.hit && o.distance == 2.0f && o.attribute_distance == 2.0f);
    m.near_distance = 2.5f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(!o.hit && o.distance == GIM_PARABOLOID_EMPTY && o.triangle == UINT32_MAX && o.attribute_hit);
    m.attribute_near = 2.5f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(!o.attribute_hit && o.attribute_distance == GIM_PARABOLOID_EMPTY && o.attribute_triangle == UINT32_MAX);
    m.attribute_near = -1.0f;           /* refused, as a negative near_distance */
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_ERROR_INVALID_ARGUMENT);
    /* looking down at them from above: the nearer is 2 (z = 2 from z = 3), its normal +z */
    m = map_at(0, 0, 3, 0, 0, -1, 0);
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.hit && o.distance == 1.0f && o.normal[2] == 1.0f);
    /* behind the map's plane: nothing, in any texel */
    m = map_at(0, 0, 2.5f, 0, 0, 1, 0);
    {
        uint32_t x, y;
        for (y = 0; y < 9; ++y)
            for (x = 0; x < 9; ++x) {
                assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, x, y, &o), GIM_OK);
                assert_int_equal(o.hit, 0);
            }
    }
}

/* Vertex normals interpolated at the hit, normalised and turned to the origin. */
static void vertex_normals(void **state) {
    static const float rgb[3] = {0.5f, 0.5f, 0.5f};
    float pos[18], alb[6], nrm[18];
    gim_twin_scene s;
    gim_paraboloid_texel o;
    gim_paraboloid m = map_at(0, 0, 0, 0, 0, 1, 0);
    int k;
    (void)state;
    square(pos, alb, 1.0f, 1.0f, 0, rgb);
    /* normals (x, 0, 3) at vertex x: at the centre (0, 0, 1) the interpolation is (0, 0, 3) for
       the triangle through it (not normalised: the twin does) */
    for (k = 0; k < 6; ++k) { nrm[k * 3] = pos[k * 3]; nrm[k * 3 + 1] = 0.0f; nrm[k * 3 + 2] = 3.0f; }
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.normals = nrm; s.triangle_count = 2;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 4, 4, &o), GIM_OK);
    assert_true(o.hit);
    assert_true(fabsf(o.normal[0]) < 1e-6f && fabsf(o.normal[1]) < 1e-6f && fabsf(o.normal[2] + 1.0f) < 1e-6f);
    /* texel right of the centre: hit at x > 0, the normal leans to +x before the flip */
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 9, 5, 4, &o), GIM_OK);
    assert_true(o.hit && o.position[0] > 0.0f && o.normal[0] < 0.0f && o.normal[2] < 0.0f);
    assert_true(fabsf(o.normal[0] * o.normal[0] + o.normal[1] * o.normal[1] + o.normal[2] * o.normal[2] - 1.0f) < 1e-6f);
    assert_true(fabsf(o.normal[0] / o.normal[2] - o.position[0] / 3.0f) < 1e-5f);
}

/* The same scene and map in millimetres or kilometres: the same hits, distances scaled. */
static void unit_free(void **state) {
    static const float rgb[3] = {1, 1, 1};
    const float scales[2] = {1e-3f, 1e4f};
    float pos[36], alb[12], big[36];
    gim_twin_scene s, sb;
    gim_paraboloid m = map_at(0.1f, 0.2f, 0.3f, 0.2f, 0.3f, 1.0f, 0.01f), mb;
    uint32_t x, y, i, k;
    (void)state;
    square(pos, alb, 3.0f, 1.0f, 0, rgb);
    square(pos + 18, alb + 6, 0.5f, 0.6f, 0, rgb);
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.triangle_count = 4;
    for (k = 0; k < 2; ++k) {
        for (i = 0; i < 36; ++i) big[i] = pos[i] * scales[k];
        sb = s; sb.positions = big;
        mb = m;
        for (i = 0; i < 3; ++i) mb.origin[i] *= scales[k];
        mb.near_distance *= scales[k];
        for (y = 0; y < 16; ++y)
            for (x = 0; x < 16; ++x) {
                gim_paraboloid_texel a, b;
                assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 16, x, y, &a), GIM_OK);
                assert_int_equal(gim_paraboloid_texel_twin(&sb, &mb, 16, x, y, &b), GIM_OK);
                assert_int_equal(a.hit, b.hit);
                assert_int_equal(a.triangle, b.triangle);
                if (a.hit) assert_true(fabs(b.distance / scales[k] - a.distance) <= 1e-5 * a.distance);
            }
    }
}

static void texel_bad_input(void **state) {
    static const float rgb[3] = {1, 1, 1};
    float pos[18], alb[6];
    gim_twin_scene s;
    gim_paraboloid m = map_at(0, 0, 0, 0, 0, 1, 0), b;
    gim_paraboloid_texel o;
    (void)state;
    square(pos, alb, 1.0f, 1.0f, 0, rgb);
    memset(&s, 0, sizeof s);
    s.positions = pos; s.albedo = alb; s.triangle_count = 2;
    assert_int_equal(gim_paraboloid_texel_twin(NULL, &m, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_texel_twin(&s, NULL, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 0, 0, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 0, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 8, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 0, 8, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.origin[1] = NAN;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.origin[0] = INFINITY;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.normal[2] = 2.0f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.normal[2] = 0.0f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.normal[0] = NAN;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.near_distance = -1e-6f;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.near_distance = NAN;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    b = m; b.near_distance = INFINITY;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &b, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    pos[4] = NAN;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    pos[4] = -1.0f;
    s.triangle_count = 0;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 0, 0, &o), GIM_ERROR_INVALID_ARGUMENT);
    s.triangle_count = 2;
    assert_int_equal(gim_paraboloid_texel_twin(&s, &m, 8, 3, 4, &o), GIM_OK);
}

/* --- second-bounce VPLs --------------------------------------------------------------------- */

/* The maps' attribute arrays from the twin, as the GPU pass writes them. */
typedef struct bounce_maps {
    uint32_t count, size;
    float *position, *normal, *albedo;
} bounce_maps;

static void bounce_fill(bounce_maps *b, const gim_twin_scene *s, const gim_paraboloid *maps, uint32_t count, uint32_t size) {
    size_t n = (size_t)count * size * size, t;
    uint32_t m, x, y;
    b->count = count; b->size = size;
    b->position = (float *)calloc(n * 4, sizeof(float));
    b->normal = (float *)calloc(n * 4, sizeof(float));
    b->albedo = (float *)calloc(n * 4, sizeof(float));
    for (m = 0; m < count; ++m)
        for (y = 0; y < size; ++y)
            for (x = 0; x < size; ++x) {
                gim_paraboloid_texel o;
                t = ((size_t)m * size * size + (size_t)y * size + x) * 4;
                assert_int_equal(gim_paraboloid_texel_twin(s, &maps[m], size, x, y, &o), GIM_OK);
                if (!o.hit) continue;
                memcpy(b->position + t, o.position, 12); b->position[t + 3] = 1.0f;
                memcpy(b->normal + t, o.normal, 12);
                memcpy(b->albedo + t, o.albedo, 12); b->albedo[t + 3] = 1.0f;
            }
}
static void bounce_free(bounce_maps *b) { free(b->position); free(b->normal); free(b->albedo); }

static gim_second_bounce_desc bounce_desc(const bounce_maps *b, const gim_paraboloid *maps, uint32_t vpl_count,
                                          gim_env env) {
    gim_second_bounce_desc d;
    memset(&d, 0, sizeof d);
    d.maps = maps; d.map_count = b->count; d.size = b->size;
    d.position = b->position; d.normal = b->normal; d.albedo = b->albedo;
    d.vpl_count = vpl_count;
    d.env = env;
    return d;
}

/* An open box around the origin that every upward direction hits: four walls from z = -0.5
   to 1.5 and a ceiling, albedo rgb; half: only the walls and ceiling part with x > 0 exist. */
static void closed_scene(float *pos, float *alb, uint32_t *count, const float rgb[3], int half) {
    const float lo = half ? 0.0f : -1.0f;
    const float quads[5][4][3] = {{{lo, -1, 1.5f}, {1, -1, 1.5f}, {1, 1, 1.5f}, {lo, 1, 1.5f}},
                                  {{1, -1, -0.5f}, {1, 1, -0.5f}, {1, 1, 1.5f}, {1, -1, 1.5f}},
                                  {{lo, -1, -0.5f}, {1, -1, -0.5f}, {1, -1, 1.5f}, {lo, -1, 1.5f}},
                                  {{lo, 1, -0.5f}, {1, 1, -0.5f}, {1, 1, 1.5f}, {lo, 1, 1.5f}},
                                  {{-1, -1, -0.5f}, {-1, 1, -0.5f}, {-1, 1, 1.5f}, {-1, -1, 1.5f}}};
    uint32_t q, t, k, n = 0;
    for (q = 0; q < (half ? 4u : 5u); ++q)
        for (t = 0; t < 2; ++t) {
            const int idx[2][3] = {{0, 1, 2}, {0, 2, 3}};
            for (k = 0; k < 3; ++k) memcpy(pos + n * 9 + k * 3, quads[q][idx[t][k]], 12);
            memcpy(alb + n * 3, rgb, 12);
            n++;
        }
    *count = n;
}

/* The estimator is unbiased: with the hemisphere closed the VPLs' flux sums to albedo Phi_m
   (within a few % at a few hundred samples, closer at more); with only the half x > 0 present,
   to half of it (the cosine-weighted share of a half hemisphere); every lit VPL lies on the
   scene with its normal towards the origin. */
static void energy(void **state) {
    static const float rgb[3] = {0.6f, 0.5f, 0.25f};
    const uint32_t counts[3] = {300, 1000, 4000};
    float pos[10 * 9], alb[10 * 3];
    gim_twin_scene s;
    gim_paraboloid maps[2];
    bounce_maps b;
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    int half;
    uint32_t c, i, a;
    (void)state;
    maps[0] = map_at(0.0f, 0.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f);
    maps[1] = map_at(0.2f, -0.3f, 0.4f, 0.3f, -0.2f, 1.0f, 0.05f);  /* tilted: still inside the closed box */
    maps[1].flux[0] = 4.0f; maps[1].flux[1] = 0.0f; maps[1].flux[2] = 1.0f;
    for (half = 0; half < 2; ++half) {
        memset(&s, 0, sizeof s);
        closed_scene(pos, alb, &s.triangle_count, rgb, half);
        s.positions = pos; s.albedo = alb;
        bounce_fill(&b, &s, maps, half ? 1u : 2u, 64);
        for (c = 0; c < 3; ++c) {
            gim_vpl *v = (gim_vpl *)malloc(counts[c] * sizeof(gim_vpl));
            gim_second_bounce_desc d = bounce_desc(&b, maps, counts[c], env);
            double sum[2][3] = {{0, 0, 0}, {0, 0, 0}}, tol = c == 0 ? 0.04 : 0.015;
            uint32_t first1 = half ? counts[c] : (counts[c] + 1) / 2, lit = 0;
            assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_OK);
            for (i = 0; i < counts[c]; ++i) {
                uint32_t m = i < first1 ? 0 : 1;
                if (v[i].lit == 0.0f) {
                    assert_true(v[i].flux[0] == 0.0f && v[i].position[0] == 0.0f && v[i].normal[2] == 0.0f);
                    continue;
                }
                lit++;
                assert_true(v[i].lit == 1.0f);
                for (a = 0; a < 3; ++a) sum[m][a] += v[i].flux[a];
                /* the normal faces the map's origin */
                assert_true((maps[m].origin[0] - v[i].position[0]) * v[i].normal[0] +
                                (maps[m].origin[1] - v[i].position[1]) * v[i].normal[1] +
                                (maps[m].origin[2] - v[i].position[2]) * v[i].normal[2] > 0.0f);
            }
            for (i = 0; i < (half ? 1u : 2u); ++i)
                for (a = 0; a < 3; ++a) {
                    double want = (half ? 0.5 : 1.0) * rgb[a] * maps[i].flux[a];
                    if (a == 0) print_message("energy: half %d, %u VPLs, map %u: sum / expected = %.4f\n", half, counts[c], i,
                                              sum[i][a] / want);
                    if (fabs(sum[i][a] - want) > tol * want + 1e-12)
                        fail_msg("half %d, %u VPLs, map %u channel %u: %.6g, expected %.6g", half, counts[c], i, a,
                                 sum[i][a], want);
                }
            /* closed: every sample hits, but for the few whose disk point falls in a rim texel
               with its centre outside the disk (an empty texel by the convention) */
            if (!half) assert_true(lit >= counts[c] - counts[c] / 100u);
            else assert_true(fabs(lit / (double)counts[c] - 0.5) < 0.05);
            free(v);
        }
        bounce_free(&b);
    }
    assert_int_equal(st.live, 0);
    assert_int_equal(lg.errors, 0);
}

/* S / M per map, one more for the first S mod M maps, in map order; each VPL at the texel of
   its Hammersley point through gim_square_to_disk; broken texel data gives unlit VPLs; the
   output is deterministic. */
static void split_and_texels(void **state) {
    const uint32_t M = 3, size = 16, S = 10;
    const uint32_t share[3] = {4, 3, 3};
    gim_paraboloid maps[3];
    bounce_maps b;
    gim_vpl v[10], v2[10];
    gim_second_bounce_desc d;
    test_alloc_stats st;
    test_log lg;
    uint32_t m, x, y, i = 0, j;
    (void)state;
    for (m = 0; m < M; ++m) maps[m] = map_at(0, 0, 0, 0, 0, 1, 0);
    /* every texel hit; its position names (map, x, y), albedo 1 */
    b.count = M; b.size = size;
    b.position = (float *)calloc(M * size * size * 4, sizeof(float));
    b.normal = (float *)calloc(M * size * size * 4, sizeof(float));
    b.albedo = (float *)calloc(M * size * size * 4, sizeof(float));
    for (m = 0; m < M; ++m)
        for (y = 0; y < size; ++y)
            for (x = 0; x < size; ++x) {
                float *p = b.position + ((m * size + y) * size + x) * 4;
                p[0] = (float)m; p[1] = (float)x; p[2] = (float)y; p[3] = 1.0f;
                b.normal[((m * size + y) * size + x) * 4 + 2] = -1.0f;
                for (j = 0; j < 3; ++j) b.albedo[((m * size + y) * size + x) * 4 + j] = 1.0f;
            }
    d = bounce_desc(&b, maps, S, test_env(&st, &lg));
    assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_OK);
    for (m = 0; m < M; ++m)
        for (j = 0; j < share[m]; ++j, ++i) {
            gim_vec2 p = gim_square_to_disk((float)((j + 0.5) / share[m]), (float)gim_van_der_corput(j));
            uint32_t ex = (uint32_t)floor((p.x + 1.0) * size / 2), ey = (uint32_t)floor((p.y + 1.0) * size / 2);
            double u = (2.0 * ex + 1.0) / size - 1.0, vv = (2.0 * ey + 1.0) / size - 1.0, r2 = u * u + vv * vv;
            double want = 4.0 * (1.0 - r2) / (share[m] * pow(1.0 + r2, 3.0));
            if (ex >= size) ex = size - 1;
            if (ey >= size) ey = size - 1;
            assert_true(v[i].position[0] == (float)m && v[i].position[1] == (float)ex && v[i].position[2] == (float)ey);
            if (r2 > 1.0) { assert_true(v[i].lit == 0.0f); continue; }
            assert_true(v[i].lit == 1.0f && v[i].normal[2] == -1.0f);
            assert_true(fabs(v[i].flux[0] - want * maps[m].flux[0]) <= 1e-6 * want * maps[m].flux[0]);
            assert_true(fabs(v[i].flux[1] - want * maps[m].flux[1]) <= 1e-6 * want * maps[m].flux[1]);
        }
    assert_int_equal(i, S);
    assert_int_equal(gim_second_bounce_vpls_twin(&d, v2), GIM_OK);
    assert_memory_equal(v, v2, sizeof v);
    /* broken data at every texel of map 1: its VPLs are unlit, the others unchanged */
    for (y = 0; y < size * size; ++y) {
        size_t t = ((size_t)1 * size * size + y) * 4;
        switch (y % 4) {
        case 0: b.position[t] = NAN; break;
        case 1: b.normal[t + 1] = INFINITY; break;
        case 2: b.albedo[t] = -0.1f; break;
        default: b.position[t + 3] = 0.0f; break;
        }
    }
    assert_int_equal(gim_second_bounce_vpls_twin(&d, v2), GIM_OK);
    for (i = 0; i < S; ++i) {
        if (i >= 4 && i < 7) {
            assert_true(v2[i].lit == 0.0f && v2[i].flux[0] == 0.0f && v2[i].flux[1] == 0.0f && v2[i].position[0] == 0.0f);
        } else {
            assert_memory_equal(&v[i], &v2[i], sizeof v[i]);
        }
    }
    /* more maps than VPLs: the first S maps take one each */
    d.vpl_count = 2;
    assert_int_equal(gim_second_bounce_vpls_twin(&d, v2), GIM_OK);
    assert_true(v2[0].lit == 1.0f && v2[0].position[0] == 0.0f);
    assert_true(v2[1].lit == 0.0f);  /* map 1's one VPL: map 1 is broken now */
    assert_int_equal(st.live, 0);
    assert_int_equal(lg.errors, 0);
    bounce_free(&b);
}

static void bounce_bad_input(void **state) {
    gim_paraboloid maps[2], keep;
    float buf[2 * 4 * 4 * 4];
    gim_vpl v[4];
    gim_second_bounce_desc d, e;
    test_alloc_stats st;
    test_log lg;
    (void)state;
    memset(buf, 0, sizeof buf);
    maps[0] = maps[1] = map_at(0, 0, 0, 0, 0, 1, 0);
    memset(&d, 0, sizeof d);
    d.maps = maps; d.map_count = 2; d.size = 4; d.position = buf; d.normal = buf; d.albedo = buf; d.vpl_count = 4;
    d.env = test_env(&st, &lg);
    assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_OK);
    assert_int_equal(gim_second_bounce_vpls_twin(NULL, v), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_second_bounce_vpls_twin(&d, NULL), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.maps = NULL; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.position = NULL; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.normal = NULL; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.albedo = NULL; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.map_count = 0; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.size = 0; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.vpl_count = 0; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_INVALID_ARGUMENT);
    e = d; e.size = 70000; assert_int_equal(gim_second_bounce_vpls_twin(&e, v), GIM_ERROR_OUT_OF_RANGE);
    keep = maps[1];
    maps[1].flux[1] = NAN; assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_ERROR_INVALID_ARGUMENT); maps[1] = keep;
    maps[1].flux[2] = -1.0f; assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_ERROR_INVALID_ARGUMENT); maps[1] = keep;
    maps[1].normal[0] = 1.0f; assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_ERROR_INVALID_ARGUMENT); maps[1] = keep;
    maps[1].origin[0] = INFINITY; assert_int_equal(gim_second_bounce_vpls_twin(&d, v), GIM_ERROR_INVALID_ARGUMENT); maps[1] = keep;
    assert_int_equal(lg.errors, 13);  /* all but the NULL desc, which has no env */
    assert_true(strstr(lg.last, "map 1") != NULL);
    assert_int_equal(st.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(plane_distance),
        cmocka_unit_test(outside_disk),
        cmocka_unit_test(near_distance),
        cmocka_unit_test(vertex_normals),
        cmocka_unit_test(unit_free),
        cmocka_unit_test(texel_bad_input),
        cmocka_unit_test(energy),
        cmocka_unit_test(split_and_texels),
        cmocka_unit_test(bounce_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
