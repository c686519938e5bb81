/* LightSkin cache generator (Bischoff 2017 sec. 3): coverage, area partition, density, invariance,
   robustness, determinism. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"
#include "street.h"

/* ---- meshes --------------------------------------------------------------------------- */

typedef struct tmesh {
    float *pos, *nrm;
    uint32_t *idx, *mat;
    uint32_t nv, nt;
} tmesh;

static void tm_free(tmesh *m) { free(m->pos); free(m->nrm); free(m->idx); free(m->mat); memset(m, 0, sizeof *m); }
static void tm_alloc(tmesh *m, uint32_t nv, uint32_t nt) {
    memset(m, 0, sizeof *m);
    m->pos = (float *)calloc((size_t)nv * 3u, sizeof(float));
    m->idx = (uint32_t *)calloc((size_t)nt * 3u, sizeof(uint32_t));
    m->mat = (uint32_t *)calloc(nt, sizeof(uint32_t));
    m->nv = nv;
    m->nt = nt;
    assert_non_null(m->pos);
    assert_non_null(m->idx);
    assert_non_null(m->mat);
}
/* Append b to a (indices shifted). */
static void tm_append(tmesh *a, const tmesh *b) {
    tmesh r;
    uint32_t i;
    tm_alloc(&r, a->nv + b->nv, a->nt + b->nt);
    memcpy(r.pos, a->pos, (size_t)a->nv * 12u);
    memcpy(r.pos + (size_t)a->nv * 3u, b->pos, (size_t)b->nv * 12u);
    memcpy(r.idx, a->idx, (size_t)a->nt * 12u);
    for (i = 0; i < b->nt * 3u; ++i) r.idx[a->nt * 3u + i] = b->idx[i] + a->nv;
    memcpy(r.mat, a->mat, (size_t)a->nt * 4u);
    memcpy(r.mat + a->nt, b->mat, (size_t)b->nt * 4u);
    tm_free(a);
    *a = r;
}

/* A w x h rectangle in the plane z = z0, from (x0, y0), n x n cells of two triangles, facing +z. */
static tmesh tm_plane(float x0, float y0, float z0, float w, float h, uint32_t n) {
    tmesh m;
    uint32_t i, j, t = 0;
    tm_alloc(&m, (n + 1) * (n + 1), 2 * n * n);
    for (j = 0; j <= n; ++j)
        for (i = 0; i <= n; ++i) {
            float *p = &m.pos[(j * (n + 1) + i) * 3];
            p[0] = x0 + w * (float)i / (float)n;
            p[1] = y0 + h * (float)j / (float)n;
            p[2] = z0;
        }
    for (j = 0; j < n; ++j)
        for (i = 0; i < n; ++i) {
            uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            uint32_t *x = &m.idx[t * 3];
            x[0] = a; x[1] = b; x[2] = d; x[3] = a; x[4] = d; x[5] = c;
            t += 2;
        }
    return m;
}

/* Axis-aligned box [lo, hi], outward faces, each face n x n cells. */
static tmesh tm_box(const float lo[3], const float hi[3], uint32_t n) {
    tmesh m, f;
    int axis, side;
    uint32_t i;
    memset(&m, 0, sizeof m);
    tm_alloc(&m, 0, 0);
    for (axis = 0; axis < 3; ++axis)
        for (side = 0; side < 2; ++side) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            f = tm_plane(0, 0, 0, 1, 1, n);
            for (i = 0; i < f.nv; ++i) {
                float s = f.pos[i * 3], t = f.pos[i * 3 + 1], q[3];
                q[axis] = side ? hi[axis] : lo[axis];
                q[u] = lo[u] + s * (hi[u] - lo[u]);
                q[v] = lo[v] + t * (hi[v] - lo[v]);
                memcpy(&f.pos[i * 3], q, sizeof q);
            }
            /* (u, v, axis) is right-handed: the grid faces +axis; flip for the low side */
            if (!side)
                for (i = 0; i < f.nt; ++i) { uint32_t x = f.idx[i * 3 + 1]; f.idx[i * 3 + 1] = f.idx[i * 3 + 2]; f.idx[i * 3 + 2] = x; }
            tm_append(&m, &f);
            tm_free(&f);
        }
    return m;
}

/* Unit icosphere of radius r around c, subdivided s times (20 * 4^s triangles), outward. */
static tmesh tm_sphere(const float c[3], float r, int s) {
    static const float ico_v[12][3] = {{-1, 1.618034f, 0}, {1, 1.618034f, 0}, {-1, -1.618034f, 0}, {1, -1.618034f, 0},
                                       {0, -1, 1.618034f}, {0, 1, 1.618034f}, {0, -1, -1.618034f}, {0, 1, -1.618034f},
                                       {1.618034f, 0, -1}, {1.618034f, 0, 1}, {-1.618034f, 0, -1}, {-1.618034f, 0, 1}};
    static const uint32_t ico_f[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                          {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                          {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    /* triangle soup subdivision, vertices duplicated (fine for the generator) */
    uint32_t nt = 20, i, k, level;
    float *tri = (float *)malloc(sizeof(float) * 9 * 20);
    tmesh m;
    for (i = 0; i < 20; ++i)
        for (k = 0; k < 3; ++k) memcpy(&tri[i * 9 + k * 3], ico_v[ico_f[i][k]], 12);
    for (level = 0; level < (uint32_t)s; ++level) {
        float *nt4 = (float *)malloc(sizeof(float) * 9 * nt * 4);
        for (i = 0; i < nt; ++i) {
            float *a = &tri[i * 9], *b = a + 3, *cc = a + 6, ab[3], bc[3], ca[3];
            float *o = &nt4[i * 36];
            for (k = 0; k < 3; ++k) { ab[k] = 0.5f * (a[k] + b[k]); bc[k] = 0.5f * (b[k] + cc[k]); ca[k] = 0.5f * (cc[k] + a[k]); }
            memcpy(o, a, 12); memcpy(o + 3, ab, 12); memcpy(o + 6, ca, 12);
            memcpy(o + 9, ab, 12); memcpy(o + 12, b, 12); memcpy(o + 15, bc, 12);
            memcpy(o + 18, ca, 12); memcpy(o + 21, bc, 12); memcpy(o + 24, cc, 12);
            memcpy(o + 27, ab, 12); memcpy(o + 30, bc, 12); memcpy(o + 33, ca, 12);
        }
        free(tri);
        tri = nt4;
        nt *= 4;
    }
    tm_alloc(&m, nt * 3, nt);
    m.nrm = (float *)malloc(sizeof(float) * 9 * nt);
    for (i = 0; i < nt * 3; ++i) {
        float *p = &tri[i * 3], l = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        for (k = 0; k < 3; ++k) { m.nrm[i * 3 + k] = p[k] / l; m.pos[i * 3 + k] = c[k] + r * p[k] / l; }
        m.idx[i] = i;
    }
    free(tri);
    return m;
}

static void tm_rotate(tmesh *m, float ax, float ay) {
    uint32_t i;
    float cx = cosf(ax), sx = sinf(ax), cy = cosf(ay), sy = sinf(ay);
    for (i = 0; i < m->nv; ++i) {
        float *p = &m->pos[i * 3], y = p[1] * cx - p[2] * sx, z = p[1] * sx + p[2] * cx, x;
        p[1] = y; p[2] = z;
        x = p[0] * cy + p[2] * sy; z = -p[0] * sy + p[2] * cy;
        p[0] = x; p[2] = z;
    }
}

static gim_cache_desc tm_desc(const tmesh *m, float d_eps) {
    gim_cache_desc d;
    memset(&d, 0, sizeof d);
    d.mesh.positions = m->pos;
    d.mesh.vertex_count = m->nv;
    d.mesh.indices = m->idx;
    d.mesh.index_count = m->nt * 3;
    d.d_eps = d_eps;
    return d;
}

/* ---- property checks ------------------------------------------------------------------ */

static void tri_vertex(const gim_mesh_data *md, uint32_t t, int k, double *out) {
    uint32_t stride = md->position_stride ? md->position_stride : 12;
    uint32_t i = md->index_type == GIM_INDEX_U16 ? ((const uint16_t *)md->indices)[t * 3 + k]
                                                 : ((const uint32_t *)md->indices)[t * 3 + k];
    const float *p = (const float *)((const char *)md->positions + (size_t)i * stride);
    out[0] = p[0]; out[1] = p[1]; out[2] = p[2];
}

static double tri_area_normal(const gim_mesh_data *md, uint32_t t, double n[3]) {
    double a[3], b[3], c[3], e1[3], e2[3], l;
    int k;
    tri_vertex(md, t, 0, a); tri_vertex(md, t, 1, b); tri_vertex(md, t, 2, c);
    for (k = 0; k < 3; ++k) { e1[k] = b[k] - a[k]; e2[k] = c[k] - a[k]; }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (l > 0) for (k = 0; k < 3; ++k) n[k] /= l;
    return 0.5 * l;
}

/* Caches bucketed in a grid of cells of edge d_eps, so coverage checks stay fast. */
typedef struct cgrid {
    double lo[3], cell;
    long dim[3];
    long *head, *next;
} cgrid;

static void cgrid_build(cgrid *g, const gim_cache_set *s) {
    long i, total;
    int k;
    for (k = 0; k < 3; ++k) g->lo[k] = 1e300;
    for (i = 0; i < (long)s->count; ++i)
        for (k = 0; k < 3; ++k) if (s->caches[i].position[k] < g->lo[k]) g->lo[k] = s->caches[i].position[k];
    g->cell = s->d_eps;
    for (;;) {
        double hi[3] = {-1e300, -1e300, -1e300};
        for (i = 0; i < (long)s->count; ++i)
            for (k = 0; k < 3; ++k) if (s->caches[i].position[k] > hi[k]) hi[k] = s->caches[i].position[k];
        total = 1;
        for (k = 0; k < 3; ++k) { g->dim[k] = s->count ? (long)((hi[k] - g->lo[k]) / g->cell) + 1 : 1; total *= g->dim[k]; }
        if (total <= 4000000) break;
        g->cell *= 2;
    }
    g->head = (long *)malloc(sizeof(long) * (size_t)total);
    g->next = (long *)malloc(sizeof(long) * (s->count + 1));
    for (i = 0; i < total; ++i) g->head[i] = -1;
    for (i = 0; i < (long)s->count; ++i) {
        long c[3], key;
        for (k = 0; k < 3; ++k) c[k] = (long)((s->caches[i].position[k] - g->lo[k]) / g->cell);
        key = (c[0] * g->dim[1] + c[1]) * g->dim[2] + c[2];
        g->next[i] = g->head[key];
        g->head[key] = i;
    }
}

/* Coverage: points on every triangle (corners, edge midpoints, random interior points) must lie
   within d_eps of a cache whose normal is within theta_eps of the face normal. Returns the
   number of uncovered points; *worst gets the largest distance to a compatible cache / d_eps. */
static uint32_t coverage_failures(const gim_mesh_data *md, const gim_cache_set *s, uint32_t samples, double *worst) {
    uint32_t t, fails = 0, k;
    double cos_t = cos((double)s->theta_eps) - 1e-6, lim = (double)s->d_eps * (1.0 + 1e-5);
    cgrid g;
    cgrid_build(&g, s);
    *worst = 0.0;
    for (t = 0; t < md->index_count / 3; ++t) {
        double a[3], b[3], cc[3], n[3];
        double area = tri_area_normal(md, t, n), lmax = 0;
        tri_vertex(md, t, 0, a); tri_vertex(md, t, 1, b); tri_vertex(md, t, 2, cc);
        for (k = 0; k < 3; ++k) {
            const double *p = k == 0 ? a : (k == 1 ? b : cc), *q = k == 0 ? b : (k == 1 ? cc : a);
            double l = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
            if (l > lmax) lmax = l;
        }
        if (!(2.0 * area > 1e-7 * lmax)) continue; /* the generator skips it as degenerate */
        for (k = 0; k < samples + 6; ++k) {
            double u, v, p[3], best = 1e300;
            long c[3], x, y, z;
            int j;
            if (k < 3) { u = k == 1; v = k == 2; }
            else if (k < 6) { u = k == 3 ? 0.5 : (k == 4 ? 0.5 : 0.0); v = k == 3 ? 0.0 : 0.5; }
            else { u = test_rand01(); v = test_rand01(); if (u + v > 1) { u = 1 - u; v = 1 - v; } }
            for (j = 0; j < 3; ++j) { p[j] = a[j] + u * (b[j] - a[j]) + v * (cc[j] - a[j]); c[j] = (long)floor((p[j] - g.lo[j]) / g.cell); }
            for (x = c[0] - 1; x <= c[0] + 1; ++x)
                for (y = c[1] - 1; y <= c[1] + 1; ++y)
                    for (z = c[2] - 1; z <= c[2] + 1; ++z) {
                        long i;
                        if (x < 0 || y < 0 || z < 0 || x >= g.dim[0] || y >= g.dim[1] || z >= g.dim[2]) continue;
                        for (i = g.head[(x * g.dim[1] + y) * g.dim[2] + z]; i >= 0; i = g.next[i]) {
                            const gim_cache *q = &s->caches[i];
                            double d2 = 0, dn = 0;
                            for (j = 0; j < 3; ++j) { d2 += (q->position[j] - p[j]) * (q->position[j] - p[j]); dn += q->normal[j] * n[j]; }
                            if (dn >= cos_t && d2 < best) best = d2;
                        }
                    }
            best = sqrt(best);
            if (best / s->d_eps > *worst) *worst = best / s->d_eps;
            if (!(best <= lim)) fails++;
        }
    }
    free(g.head);
    free(g.next);
    return fails;
}

static double mesh_area(const gim_mesh_data *md) {
    double a = 0, n[3];
    uint32_t t;
    for (t = 0; t < md->index_count / 3; ++t) a += tri_area_normal(md, t, n);
    return a;
}
static double cache_area(const gim_cache_set *s) {
    double a = 0;
    uint32_t i;
    for (i = 0; i < s->count; ++i) a += s->caches[i].area;
    return a;
}
/* Every cache finite, unit normal, area > 0, reflectance in [0,1]. */
static void check_sane(const gim_cache_set *s) {
    uint32_t i;
    for (i = 0; i < s->count; ++i) {
        const gim_cache *c = &s->caches[i];
        float l = sqrtf(c->normal[0] * c->normal[0] + c->normal[1] * c->normal[1] + c->normal[2] * c->normal[2]);
        assert_true(gim__all_finite(c->position, 3) && gim__all_finite(c->normal, 3));
        assert_true(fabsf(l - 1.0f) < 1e-5f);
        assert_true(c->area > 0.0f && gim__isfinitef(c->area));
        assert_true(c->reflectance >= 0.0f && c->reflectance <= 1.0f);
    }
}

/* ---- tests ---------------------------------------------------------------------------- */

/* One cache per voxel the plane crosses: A / (d_eps/2)^2, four times as many at half d_eps,
   the same for 2 big triangles (clipped) and for many small ones. */
static void density_plane(void **state) {
    test_alloc_stats st;
    gim_env env = test_env(&st, NULL);
    uint32_t n, grid;
    (void)state;
    for (grid = 1; grid <= 32; grid *= 32)
        for (n = 8; n <= 16; n *= 2) {
            tmesh m = tm_plane(0, 0, 0, 4, 4, grid);
            gim_cache_desc d = tm_desc(&m, 2.0f * 4.0f / (float)n);
            gim_cache_set s;
            uint32_t i;
            d.env = env;
            assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
            assert_int_equal(s.count, n * n);
            assert_int_equal(s.report.voxels, n * n);
            assert_int_equal(s.report.caches_snapped, 0);
            for (i = 0; i < s.count; ++i) {
                /* at the voxel centre of the plane, area h^2 */
                float h = 4.0f / (float)n, fx = s.caches[i].position[0] / h - 0.5f, fy = s.caches[i].position[1] / h - 0.5f;
                assert_true(fabsf(fx - roundf(fx)) < 1e-4f && fabsf(fy - roundf(fy)) < 1e-4f);
                assert_true(s.caches[i].position[2] == 0.0f && s.caches[i].normal[2] == 1.0f);
                assert_true(fabsf(s.caches[i].area - h * h) < 1e-5f * h * h);
            }
            gim_cache_set_free(&s);
            tm_free(&m);
        }
    /* not aligned to the voxels: about A/h^2 (the partial border voxels keep their own cache) */
    {
        tmesh m = tm_plane(0.13f, -0.71f, 0.3f, 10.3f, 7.9f, 5);
        gim_cache_desc d = tm_desc(&m, 1.0f);
        gim_cache_set s;
        double expect = 10.3 * 7.9 / 0.25;
        d.env = env;
        assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
        assert_true(s.count >= expect * 0.95 && s.count <= expect * 1.12);
        gim_cache_set_free(&s);
        tm_free(&m);
    }
    assert_int_equal(st.live, 0);
}

/* Tilted planes cross more voxels; halving d_eps still roughly quadruples the count. */
static void density_tilted(void **state) {
    tmesh m = tm_plane(-3, -3, 0, 6, 6, 4);
    gim_cache_desc d;
    gim_cache_set s1, s2;
    double r;
    (void)state;
    tm_rotate(&m, 0.5f, 0.3f);
    d = tm_desc(&m, 0.5f);
    assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
    d.d_eps = 0.25f;
    assert_int_equal(gim_cache_generate(&d, &s2), GIM_OK);
    r = (double)s2.count / s1.count;
    assert_true(r > 3.4 && r < 4.6);
    assert_true(s1.count >= 36.0 / 0.0625 * 0.9 && s1.count <= 36.0 / 0.0625 * 2.0);
    gim_cache_set_free(&s1);
    gim_cache_set_free(&s2);
    tm_free(&m);
}

/* A cube gives caches with exactly its six face normals, on its faces, one area per face. */
static void cube_normals(void **state) {
    const float lo[3] = {-1.3f, 0.2f, 5.0f}, hi[3] = {0.7f, 2.2f, 7.0f};
    uint32_t sub;
    (void)state;
    for (sub = 1; sub <= 4; sub *= 4) {
        tmesh m = tm_box(lo, hi, sub);
        gim_cache_desc d = tm_desc(&m, 0.3f);
        gim_cache_set s;
        double face_area[6] = {0, 0, 0, 0, 0, 0};
        uint32_t i;
        int f;
        assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
        check_sane(&s);
        for (i = 0; i < s.count; ++i) {
            const gim_cache *c = &s.caches[i];
            int axis = -1, k, nonzero = 0;
            for (k = 0; k < 3; ++k)
                if (c->normal[k] != 0.0f) { axis = k; nonzero++; }
            assert_int_equal(nonzero, 1);
            assert_true(fabsf(c->normal[axis]) == 1.0f);
            f = axis * 2 + (c->normal[axis] > 0);
            face_area[f] += c->area;
            assert_true(fabsf(c->position[axis] - (c->normal[axis] > 0 ? hi[axis] : lo[axis])) < 1e-5f);
        }
        for (f = 0; f < 6; ++f) assert_true(fabs(face_area[f] - 4.0) < 1e-4);
        assert_int_equal(s.report.triangles_used, m.nt);
        gim_cache_set_free(&s);
        tm_free(&m);
    }
    /* the paper's two RGBA32F texels: position + area, normal + reflection coefficient */
    assert_int_equal(sizeof(gim_cache), 32);
    assert_int_equal(offsetof(gim_cache, area), 12);
    assert_int_equal(offsetof(gim_cache, normal), 16);
    assert_int_equal(offsetof(gim_cache, reflectance), 28);
}

static void coverage_case(tmesh *m, float d_eps, int no_merge, int no_snap, const float *normals) {
    gim_cache_desc d = tm_desc(m, d_eps);
    gim_cache_set s;
    double worst, a;
    d.no_merge = no_merge;
    d.no_snap = no_snap;
    d.mesh.normals = normals;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    check_sane(&s);
    assert_int_equal(coverage_failures(&d.mesh, &s, 12, &worst), 0);
    assert_true(worst <= 1.0 + 1e-5);
    a = mesh_area(&d.mesh);
    assert_true(fabs(cache_area(&s) - a) <= 1e-4 * a);
    assert_true(fabs(s.report.surface_area - a) <= 1e-6 * a);
    gim_cache_set_free(&s);
}

/* Every surface point within d_eps of a compatible cache: tilted planes, a rotated box, a
   sphere (curved: averaging floats, snapping moves), a random triangle soup; merged or not. */
static void coverage(void **state) {
    const float c0[3] = {0.3f, -0.2f, 0.1f}, lo[3] = {0, 0, 0}, hi[3] = {1.7f, 0.9f, 1.1f};
    int merge, snap;
    (void)state;
    for (merge = 0; merge < 2; ++merge)
        for (snap = 0; snap < 2; ++snap) {
            tmesh p = tm_plane(-2, -2, 0, 4, 4, 3), b = tm_box(lo, hi, 2), sp = tm_sphere(c0, 1.0f, 3), soup;
            uint32_t i;
            tm_rotate(&p, 0.7f, 0.4f);
            tm_rotate(&b, 0.3f, 1.1f);
            coverage_case(&p, 0.37f, !merge, !snap, NULL);
            coverage_case(&b, 0.21f, !merge, !snap, NULL);
            coverage_case(&sp, 0.3f, !merge, !snap, NULL);
            coverage_case(&sp, 0.8f, !merge, !snap, NULL);
            tm_alloc(&soup, 300, 100);
            for (i = 0; i < 300 * 3; ++i) soup.pos[i] = (float)test_rand01() * 3.0f;
            for (i = 0; i < 300; ++i) soup.idx[i] = i;
            coverage_case(&soup, 0.4f, !merge, !snap, NULL);
            tm_free(&p); tm_free(&b); tm_free(&sp); tm_free(&soup);
        }
}

/* Snapping: caches of a sphere float inside it after averaging; snapped ones sit on the
   surface, and the count matches the report. */
static void snapping(void **state) {
    const float c0[3] = {0, 0, 0};
    tmesh sp = tm_sphere(c0, 1.0f, 4);
    gim_cache_desc d = tm_desc(&sp, 0.4f);
    gim_cache_set s0, s1;
    double err0 = 0, err1 = 0;
    uint32_t i, on = 0;
    (void)state;
    d.no_snap = 1;
    assert_int_equal(gim_cache_generate(&d, &s0), GIM_OK);
    d.no_snap = 0;
    assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
    assert_int_equal(s0.count, s1.count);
    assert_int_equal(s0.report.caches_snapped, 0);
    assert_true(s1.report.caches_snapped > s1.count / 2);
    for (i = 0; i < s1.count; ++i) {
        const float *p0 = s0.caches[i].position, *p1 = s1.caches[i].position;
        double r0 = sqrt(p0[0] * p0[0] + p0[1] * p0[1] + p0[2] * p0[2]), r1 = sqrt(p1[0] * p1[0] + p1[1] * p1[1] + p1[2] * p1[2]);
        err0 += fabs(1.0 - r0);
        err1 += fabs(1.0 - r1);
        if (r1 > 0.99) on++; /* the faceted sphere of level 4 lies within 1% of the unit sphere */
    }
    assert_true(err1 < 0.3 * err0);
    assert_true(on >= s1.report.caches_snapped);
    gim_cache_set_free(&s0);
    gim_cache_set_free(&s1);
    tm_free(&sp);
}

/* Vertex normals: a smooth sphere's caches point radially. */
static void vertex_normals(void **state) {
    const float c0[3] = {1, 2, 3};
    tmesh sp = tm_sphere(c0, 2.0f, 3);
    gim_cache_desc d = tm_desc(&sp, 0.5f);
    gim_cache_set s;
    uint32_t i;
    (void)state;
    d.mesh.normals = sp.nrm;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    check_sane(&s);
    for (i = 0; i < s.count; ++i) {
        double r[3], l, dot;
        int k;
        for (k = 0; k < 3; ++k) r[k] = s.caches[i].position[k] - c0[k];
        l = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
        dot = (r[0] * s.caches[i].normal[0] + r[1] * s.caches[i].normal[1] + r[2] * s.caches[i].normal[2]) / l;
        assert_true(dot > cos(0.35));
    }
    gim_cache_set_free(&s);
    tm_free(&sp);
}

/* Areas: the caches partition the surface (total within 1%, in fact 1e-4), per material too:
   two boxes of different materials give caches of one reflectance each, summing to each box. */
static void area_partition(void **state) {
    const float lo1[3] = {0, 0, 0}, hi1[3] = {1, 1, 1}, lo2[3] = {0.2f, 0.3f, 1.5f}, hi2[3] = {2.2f, 0.8f, 2.5f};
    const float refl[2] = {0.25f, 0.75f};
    tmesh a = tm_box(lo1, hi1, 3), b = tm_box(lo2, hi2, 1);
    gim_cache_desc d;
    gim_cache_set s;
    double area[2] = {0, 0};
    uint32_t i, nt1 = a.nt;
    (void)state;
    tm_append(&a, &b);
    for (i = nt1; i < a.nt; ++i) a.mat[i] = 1;
    d = tm_desc(&a, 0.35f);
    d.mesh.triangle_material = a.mat;
    d.mesh.material_reflectance = refl;
    d.mesh.material_count = 2;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    for (i = 0; i < s.count; ++i) {
        assert_true(s.caches[i].reflectance == 0.25f || s.caches[i].reflectance == 0.75f);
        area[s.caches[i].reflectance == 0.75f] += s.caches[i].area;
    }
    assert_true(fabs(area[0] - 6.0) < 1e-4 && fabs(area[1] - 2 * (2 * 0.5 + 2 * 1 + 0.5 * 1)) < 1e-4);
    gim_cache_set_free(&s);
    tm_free(&a);
    tm_free(&b);

    /* the street: reflectance-weighted area is conserved (mixed caches average their surface) */
    {
        street_params sp;
        street_mesh sm;
        double want = 0, got = 0, total = 0, n[3];
        memset(&sp, 0, sizeof sp);
        sp.target_triangles = 20000;
        sp.buildings_per_side = 6;
        assert_int_equal(street_build(&sp, &sm), 0);
        memset(&d, 0, sizeof d);
        d.mesh.positions = sm.positions;
        d.mesh.vertex_count = sm.vertex_count;
        d.mesh.indices = sm.indices;
        d.mesh.index_count = sm.triangle_count * 3;
        d.mesh.triangle_material = sm.triangle_material;
        d.mesh.material_reflectance = sm.reflectance;
        d.mesh.material_count = sm.material_count;
        assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
        check_sane(&s);
        for (i = 0; i < sm.triangle_count; ++i) {
            double ta = tri_area_normal(&d.mesh, i, n);
            want += ta * sm.reflectance[sm.triangle_material[i]];
            total += ta;
        }
        for (i = 0; i < s.count; ++i) got += (double)s.caches[i].area * s.caches[i].reflectance;
        assert_true(fabs(got - want) < 1e-3 * want);
        assert_true(fabs(cache_area(&s) - total) < 1e-3 * total);
        assert_int_equal(s.report.triangles_used, sm.triangle_count);
        gim_cache_set_free(&s);
        street_free(&sm);
    }
}

/* Translation by a power of two (vertices stay exact) changes only positions; scaling the mesh
   and d_eps by 2^k scales positions and areas exactly; far from the origin (1e5) the
   properties still hold; millimetres and kilometres give the same count. */
static void invariance(void **state) {
    street_params sp;
    street_mesh sm;
    gim_cache_desc d;
    gim_cache_set s0, s1;
    float *pos;
    uint32_t i, k;
    double worst;
    (void)state;
    memset(&sp, 0, sizeof sp);
    sp.target_triangles = 4000;
    sp.buildings_per_side = 3;
    assert_int_equal(street_build(&sp, &sm), 0);
    pos = (float *)malloc(sizeof(float) * 3 * sm.vertex_count);
    /* a 1/64 grid: exact in float up to 2^17 */
    for (i = 0; i < sm.vertex_count * 3; ++i) sm.positions[i] = roundf(sm.positions[i] * 64.0f) / 64.0f;
    memset(&d, 0, sizeof d);
    d.mesh.positions = sm.positions;
    d.mesh.vertex_count = sm.vertex_count;
    d.mesh.indices = sm.indices;
    d.mesh.index_count = sm.triangle_count * 3;
    d.d_eps = 3.0f;
    assert_int_equal(gim_cache_generate(&d, &s0), GIM_OK);
    assert_true(s0.count > 100);
    d.mesh.positions = pos;
    for (i = 0; i < sm.vertex_count; ++i) {
        pos[i * 3] = sm.positions[i * 3] + 131072.0f;
        pos[i * 3 + 1] = sm.positions[i * 3 + 1] - 65536.0f;
        pos[i * 3 + 2] = sm.positions[i * 3 + 2] + 98304.0f;
    }
    assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
    assert_int_equal(s0.count, s1.count);
    for (i = 0; i < s0.count; ++i) {
        const gim_cache *a = &s0.caches[i], *b = &s1.caches[i];
        assert_true(memcmp(a->normal, b->normal, 12) == 0 && a->area == b->area && a->reflectance == b->reflectance);
        assert_true(fabsf(b->position[0] - 131072.0f - a->position[0]) <= 0.008f);
        assert_true(fabsf(b->position[1] + 65536.0f - a->position[1]) <= 0.004f);
        assert_true(fabsf(b->position[2] - 98304.0f - a->position[2]) <= 0.008f);
    }
    /* coverage and area hold there too */
    assert_int_equal(coverage_failures(&d.mesh, &s1, 2, &worst), 0);
    assert_true(fabs(cache_area(&s1) - mesh_area(&d.mesh)) < 1e-3 * mesh_area(&d.mesh));
    gim_cache_set_free(&s1);
    /* 2^-12 and 2^12 */
    for (k = 0; k < 2; ++k) {
        float f = k ? 4096.0f : 1.0f / 4096.0f;
        for (i = 0; i < sm.vertex_count * 3; ++i) pos[i] = sm.positions[i] * f;
        d.d_eps = 3.0f * f;
        assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
        assert_int_equal(s0.count, s1.count);
        assert_int_equal(s0.report.caches_snapped, s1.report.caches_snapped);
        for (i = 0; i < s0.count; ++i) {
            const gim_cache *a = &s0.caches[i], *b = &s1.caches[i];
            assert_true(memcmp(a->normal, b->normal, 12) == 0 && a->reflectance == b->reflectance);
            assert_true(b->area == a->area * f * f);
            assert_true(b->position[0] == a->position[0] * f && b->position[1] == a->position[1] * f &&
                        b->position[2] == a->position[2] * f);
        }
        gim_cache_set_free(&s1);
    }
    /* default d_eps follows the scene: millimetres and kilometres agree (not bit for bit:
       1000 is not a power of two, so a rounding may move a piece across a voxel face) */
    {
        uint32_t counts[2];
        double deps[2];
        d.d_eps = 0.0f;
        for (k = 0; k < 2; ++k) {
            float f = k ? 1000.0f : 0.001f;
            for (i = 0; i < sm.vertex_count * 3; ++i) pos[i] = sm.positions[i] * f;
            assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
            counts[k] = s1.count;
            deps[k] = s1.d_eps / f;
            assert_true(fabs(cache_area(&s1) / (f * f) - cache_area(&s0)) < 1e-3 * cache_area(&s0));
            gim_cache_set_free(&s1);
        }
        assert_true(abs((int)counts[0] - (int)counts[1]) <= (int)(counts[0] / 50u) + 1);
        assert_true(fabs(deps[0] - deps[1]) < 1e-5 * deps[0]);
    }
    gim_cache_set_free(&s0);
    free(pos);
    street_free(&sm);
}

/* Both faces of a thin wall keep their own caches; opposite normals never merge. */
static void thin_wall(void **state) {
    const float lo[3] = {0, 0, 0}, hi[3] = {2, 2, 0.01f};
    tmesh b = tm_box(lo, hi, 1), z = tm_plane(0, 0, 0, 2, 2, 2), back = tm_plane(0, 0, 0, 2, 2, 2);
    gim_cache_desc d;
    gim_cache_set s;
    uint32_t i, up = 0, down = 0;
    (void)state;
    d = tm_desc(&b, 1.0f);
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    for (i = 0; i < s.count; ++i) {
        if (s.caches[i].normal[2] == 1.0f) up++;
        if (s.caches[i].normal[2] == -1.0f) down++;
        assert_true(fabsf(s.caches[i].normal[2]) == 1.0f || s.caches[i].normal[2] == 0.0f);
    }
    assert_int_equal(up, 16);
    assert_int_equal(down, 16);
    gim_cache_set_free(&s);
    /* zero thickness: the same quad with reversed winding is the other face, not a duplicate */
    for (i = 0; i < back.nt; ++i) { uint32_t x = back.idx[i * 3 + 1]; back.idx[i * 3 + 1] = back.idx[i * 3 + 2]; back.idx[i * 3 + 2] = x; }
    tm_append(&z, &back);
    d = tm_desc(&z, 1.0f);
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_int_equal(s.report.triangles_duplicate, 0);
    up = down = 0;
    for (i = 0; i < s.count; ++i) {
        if (s.caches[i].normal[2] == 1.0f) up++;
        if (s.caches[i].normal[2] == -1.0f) down++;
    }
    assert_int_equal(up, 16);
    assert_int_equal(down, 16);
    assert_int_equal(s.count, 32);
    gim_cache_set_free(&s);
    tm_free(&b); tm_free(&z); tm_free(&back);
}

/* Skipped triangles are counted: degenerate, non-finite, duplicate (any rotation of the
   corners); the rest still give their caches. 16-bit indices and strided positions. */
static void robustness_report(void **state) {
    /* interleaved: xyz + one float of padding */
    float v[] = {0, 0, 0, 9, 1, 0, 0, 9, 1, 1, 0, 9, 0, 1, 0, 9, /* a unit square */
                 2, 0, 0, 9, 3, 0, 0, 9, 4, 0, 0, 9,             /* collinear */
                 NAN, 0, 0, 9, INFINITY, 1, 0, 9, 0, -INFINITY, 0, 9};
    uint16_t idx[] = {0, 1, 2, 0, 2, 3, /* used */
                      1, 2, 0,          /* duplicate of the first (rotated) */
                      0, 2, 3,          /* duplicate */
                      4, 5, 6,          /* collinear */
                      0, 0, 1,          /* repeated index: zero area */
                      7, 1, 2, 8, 9, 0, /* NaN, Inf */
                      2, 1, 0};         /* reversed: the back face, used */
    test_alloc_stats st;
    test_log lg;
    gim_cache_desc d;
    gim_cache_set s;
    (void)state;
    memset(&d, 0, sizeof d);
    d.env = test_env(&st, &lg);
    d.mesh.positions = v;
    d.mesh.position_stride = 16;
    d.mesh.vertex_count = 10;
    d.mesh.indices = idx;
    d.mesh.index_type = GIM_INDEX_U16;
    d.mesh.index_count = sizeof idx / sizeof idx[0];
    d.d_eps = 1.0f;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_int_equal(s.report.triangles_used, 3);
    assert_int_equal(s.report.triangles_duplicate, 2);
    assert_int_equal(s.report.triangles_degenerate, 2);
    assert_int_equal(s.report.triangles_nonfinite, 2);
    assert_true(fabs(s.report.surface_area - 1.5) < 1e-6);
    assert_true(fabs(cache_area(&s) - 1.5) < 1e-5);
    check_sane(&s);
    assert_int_equal(s.count, 7); /* front: 4 voxels; back (half the square): 3 voxels */
    gim_cache_set_free(&s);
    assert_int_equal(st.live, 0);
    assert_int_equal(lg.errors, 0);

    /* nothing usable: OK, no caches, a warning */
    {
        uint16_t bad[] = {7, 8, 9, 4, 5, 6};
        d.mesh.indices = bad;
        d.mesh.index_count = 6;
        assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
        assert_int_equal(s.count, 0);
        assert_null(s.caches);
        assert_int_equal(lg.warnings, 1);
        gim_cache_set_free(&s);
        assert_int_equal(st.live, 0);
    }
}

/* Bad input is an error with a message, out untouched, nothing leaked. */
static void invalid_input(void **state) {
    float v[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t idx[] = {0, 1, 2}, big[] = {0, 1, 3}, mat_bad[] = {2};
    float refl[2] = {0.5f, 1.5f};
    test_alloc_stats st;
    test_log lg;
    gim_cache_desc d, base;
    gim_cache_set s, untouched;
    int i;
    (void)state;
    memset(&base, 0, sizeof base);
    base.env = test_env(&st, &lg);
    base.mesh.positions = v;
    base.mesh.vertex_count = 3;
    base.mesh.indices = idx;
    base.mesh.index_count = 3;
    memset(&untouched, 0x5a, sizeof untouched);
    for (i = 0; i < 15; ++i) {
        gim_result want = GIM_ERROR_INVALID_ARGUMENT;
        d = base;
        switch (i) {
        case 0: d.mesh.positions = NULL; break;
        case 1: d.mesh.indices = NULL; break;
        case 2: d.mesh.index_count = 4; break;
        case 3: d.mesh.vertex_count = 0; break;
        case 4: d.mesh.indices = big; break; /* out-of-range index */
        case 5: d.d_eps = -1.0f; break;
        case 6: d.d_eps = NAN; break;
        case 7: d.theta_eps = 2.0f; break;
        case 8: d.theta_eps = -0.1f; break;
        case 9: d.mesh.position_stride = 8; break;
        case 10: d.mesh.index_type = (gim_index_type)7; break;
        case 11: d.mesh.triangle_material = mat_bad; d.mesh.material_reflectance = refl; d.mesh.material_count = 1; break;
        case 12: d.mesh.material_reflectance = refl; d.mesh.material_count = 2; break; /* 1.5 > 1 */
        case 13: d.scene_scale = INFINITY; break;
        case 14: d.d_eps = 1e-30f; want = GIM_ERROR_OUT_OF_RANGE; break; /* 1e90 voxels */
        }
        lg.errors = 0;
        memcpy(&s, &untouched, sizeof s);
        assert_int_equal(gim_cache_generate(&d, &s), want);
        assert_int_equal(lg.errors, 1);
        assert_true(strstr(lg.last, "gim_cache_generate") != NULL);
        assert_memory_equal(&s, &untouched, sizeof s);
        assert_int_equal(st.live, 0);
    }
    assert_int_equal(gim_cache_generate(NULL, &s), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_generate(&base, NULL), GIM_ERROR_INVALID_ARGUMENT);
    gim_cache_set_free(NULL);
    memset(&s, 0, sizeof s);
    gim_cache_set_free(&s);
}

/* Out of memory at every allocation: GIM_ERROR_OUT_OF_MEMORY, nothing leaked. */
static void out_of_memory(void **state) {
    const float c0[3] = {0, 0, 0};
    tmesh sp = tm_sphere(c0, 1.0f, 3);
    test_alloc_stats st;
    test_log lg;
    gim_cache_desc d = tm_desc(&sp, 0.1f);
    gim_cache_set s;
    long n, total;
    (void)state;
    d.env = test_env(&st, &lg);
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    total = st.allocs;
    gim_cache_set_free(&s);
    assert_int_equal(st.live, 0);
    assert_true(total > 5);
    for (n = 0; n < total; ++n) {
        st.fail_after = st.allocs + n;
        assert_int_equal(gim_cache_generate(&d, &s), GIM_ERROR_OUT_OF_MEMORY);
        assert_int_equal(st.live, 0);
    }
    tm_free(&sp);
}

/* Same input, same caches, bit for bit; also after another generation in between. */
static void determinism(void **state) {
    street_params sp;
    street_mesh sm;
    gim_cache_desc d;
    gim_cache_set a, b, c;
    (void)state;
    memset(&sp, 0, sizeof sp);
    sp.target_triangles = 10000;
    sp.seed = 7;
    assert_int_equal(street_build(&sp, &sm), 0);
    memset(&d, 0, sizeof d);
    d.mesh = street_mesh_data(&sm);
    d.d_eps = 1.5f;
    assert_int_equal(gim_cache_generate(&d, &a), GIM_OK);
    d.d_eps = 2.5f;
    assert_int_equal(gim_cache_generate(&d, &c), GIM_OK);
    d.d_eps = 1.5f;
    assert_int_equal(gim_cache_generate(&d, &b), GIM_OK);
    assert_int_equal(a.count, b.count);
    assert_memory_equal(a.caches, b.caches, sizeof(gim_cache) * a.count);
    assert_memory_equal(&a.report, &b.report, sizeof a.report);
    assert_true(c.count < a.count);
    gim_cache_set_free(&a);
    gim_cache_set_free(&b);
    gim_cache_set_free(&c);
    street_free(&sm);
}

/* Merging joins the slivers that tilted surfaces leave in voxel corners, and only those. */
static void merging(void **state) {
    const float c0[3] = {0, 0, 0};
    tmesh p = tm_plane(-3, -3, 0, 6, 6, 4), sp = tm_sphere(c0, 1.0f, 3);
    gim_cache_desc d;
    gim_cache_set s;
    (void)state;
    tm_rotate(&p, 0.5f, 0.3f);
    d = tm_desc(&p, 0.5f);
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_true(s.count < s.report.caches_before_merge);
    gim_cache_set_free(&s);
    d.no_merge = 1;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_int_equal(s.count, s.report.caches_before_merge);
    gim_cache_set_free(&s);
    d = tm_desc(&sp, 0.5f);
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_true(s.count < s.report.caches_before_merge);
    gim_cache_set_free(&s);
    tm_free(&p);
    tm_free(&sp);
}

/* Interleaved position + normal (stride 24); a NaN and a zero vertex normal fall back to the
   face normal. */
static void interleaved_normals(void **state) {
    tmesh p = tm_plane(0, 0, 0, 2, 2, 4);
    float *buf = (float *)malloc(sizeof(float) * 6 * p.nv);
    gim_cache_desc d;
    gim_cache_set s;
    uint32_t i;
    (void)state;
    for (i = 0; i < p.nv; ++i) {
        memcpy(&buf[i * 6], &p.pos[i * 3], 12);
        buf[i * 6 + 3] = 0; buf[i * 6 + 4] = 0; buf[i * 6 + 5] = 1;
    }
    buf[3 * 6 + 3] = NAN;
    buf[7 * 6 + 5] = 0;
    d = tm_desc(&p, 1.0f);
    d.mesh.positions = buf;
    d.mesh.position_stride = 24;
    d.mesh.normals = buf + 3;
    d.mesh.normal_stride = 24;
    assert_int_equal(gim_cache_generate(&d, &s), GIM_OK);
    assert_int_equal(s.count, 16);
    for (i = 0; i < s.count; ++i) assert_true(s.caches[i].normal[2] == 1.0f && s.caches[i].position[2] == 0.0f);
    assert_true(fabs(cache_area(&s) - 4.0) < 1e-5);
    gim_cache_set_free(&s);
    free(buf);
    tm_free(&p);
}

/* theta_eps controls the normal spread: a tighter one gives more caches on a sphere, and
   coverage holds for each. */
static void theta_controls(void **state) {
    const float c0[3] = {0, 0, 0};
    tmesh sp = tm_sphere(c0, 1.0f, 3);
    gim_cache_desc d = tm_desc(&sp, 0.6f);
    gim_cache_set s1, s2;
    double worst;
    (void)state;
    d.theta_eps = 0.15f;
    assert_int_equal(gim_cache_generate(&d, &s1), GIM_OK);
    assert_true(fabsf(s1.theta_eps - 0.15f) < 1e-7f);
    assert_int_equal(coverage_failures(&d.mesh, &s1, 4, &worst), 0);
    d.theta_eps = 0.6f;
    assert_int_equal(gim_cache_generate(&d, &s2), GIM_OK);
    assert_int_equal(coverage_failures(&d.mesh, &s2, 4, &worst), 0);
    assert_true(s1.count > 2 * s2.count);
    gim_cache_set_free(&s1);
    gim_cache_set_free(&s2);
    tm_free(&sp);
}

/* Caches per world area, in units of the spacing: count x d_eps^2 / area. */
static double scene_density(const gim_cache_set *s, double world_per_model) {
    double d = (double)s->d_eps * world_per_model;
    return (double)s->count * d * d / (s->report.surface_area * world_per_model * world_per_model);
}

/* A 1 m prop in a 10 x 10 x 4 m room: generated for the scene, both get the room's spacing and
   the same caches per area, placed in world space or through a scaled model matrix; each
   mesh's own default gives the prop its own, far finer, spacing. */
static void scene_spacing(void **state) {
    test_alloc_stats st;
    gim_env env = test_env(&st, NULL);
    const float rlo[3] = {0, 0, 0}, rhi[3] = {10, 10, 4}, plo[3] = {4.5f, 4.5f, 0}, phi[3] = {5.5f, 5.5f, 1};
    const float mlo[3] = {0, 0, 0}, mhi[3] = {0.5f, 0.5f, 0.5f};
    tmesh room = tm_box(rlo, rhi, 4), prop = tm_box(plo, phi, 2), small = tm_box(mlo, mhi, 2);
    gim_cache_desc md[2];
    gim_mat4 models[2];
    gim_cache_scene_desc sd;
    gim_cache_set sets[2], own, placed[2];
    double want = sqrt(10.0 * 10.0 + 10.0 * 10.0 + 4.0 * 4.0) / 32.0, dr, dp;
    (void)state;
    md[0] = tm_desc(&room, 0.0f);
    md[1] = tm_desc(&prop, 0.0f);
    md[0].env = md[1].env = env;
    memset(&sd, 0, sizeof sd);
    sd.meshes = md;
    sd.count = 2;
    sd.env = env;
    assert_int_equal(gim_cache_generate_scene(&sd, sets), GIM_OK);
    assert_true(fabs(sets[0].d_eps - want) < 1e-5 * want && fabs(sets[1].d_eps - want) < 1e-5 * want);
    dr = scene_density(&sets[0], 1.0);
    dp = scene_density(&sets[1], 1.0);
    assert_true(dp > 0.5 * dr && dp < 2.0 * dr);
    /* the old way: the prop alone, defaults, is spaced by its own diagonal */
    assert_int_equal(gim_cache_generate(&md[1], &own), GIM_OK);
    assert_true(own.d_eps < 0.2f * sets[1].d_eps && own.count > 10u * sets[1].count);
    gim_cache_set_free(&own);

    /* the prop in model space, placed at twice its size: d_eps halves in model units */
    models[0] = gim_mat4_identity();
    models[1] = gim_mat4_identity();
    models[1].m[0] = models[1].m[5] = models[1].m[10] = 2.0f;
    models[1].m[12] = 4.5f; models[1].m[13] = 4.5f;
    md[1] = tm_desc(&small, 0.0f);
    md[1].env = env;
    sd.models = models;
    assert_int_equal(gim_cache_generate_scene(&sd, placed), GIM_OK);
    assert_true(fabs(placed[1].d_eps - 0.5 * want) < 1e-5 * want);
    assert_true(placed[0].count == sets[0].count);
    assert_true(fabs((double)placed[1].count - (double)sets[1].count) <= 0.1 * (double)sets[1].count);
    assert_true(fabs(scene_density(&placed[1], 2.0) - dp) < 0.1 * dp);
    gim_cache_set_free(&placed[0]);
    gim_cache_set_free(&placed[1]);

    /* an error writes nothing and frees what it made */
    models[1].m[0] = 0.0f; models[1].m[5] = 0.0f; models[1].m[10] = 0.0f;
    memset(placed, 0x5a, sizeof placed);
    assert_int_equal(gim_cache_generate_scene(&sd, placed), GIM_ERROR_INVALID_ARGUMENT);
    assert_true(placed[0].count == 0x5a5a5a5au);
    models[1].m[0] = models[1].m[5] = models[1].m[10] = 2.0f;
    sd.d_eps = 1e-30f;
    assert_int_equal(gim_cache_generate_scene(&sd, placed), GIM_ERROR_OUT_OF_RANGE);
    assert_true(placed[0].count == 0x5a5a5a5au);
    sd.d_eps = -1.0f;
    assert_int_equal(gim_cache_generate_scene(&sd, placed), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_generate_scene(NULL, placed), GIM_ERROR_INVALID_ARGUMENT);

    gim_cache_set_free(&sets[0]);
    gim_cache_set_free(&sets[1]);
    tm_free(&room); tm_free(&prop); tm_free(&small);
    assert_int_equal(st.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(density_plane),
        cmocka_unit_test(density_tilted),
        cmocka_unit_test(cube_normals),
        cmocka_unit_test(coverage),
        cmocka_unit_test(snapping),
        cmocka_unit_test(vertex_normals),
        cmocka_unit_test(area_partition),
        cmocka_unit_test(invariance),
        cmocka_unit_test(thin_wall),
        cmocka_unit_test(robustness_report),
        cmocka_unit_test(invalid_input),
        cmocka_unit_test(out_of_memory),
        cmocka_unit_test(determinism),
        cmocka_unit_test(merging),
        cmocka_unit_test(interleaved_normals),
        cmocka_unit_test(theta_controls),
        cmocka_unit_test(scene_spacing),
    };
    return cmocka_run_group_tests_name("caches", tests, NULL, NULL);
}
