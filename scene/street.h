/* street.h - a procedural open-world street after the urban test scene of Bischoff 2017:
   a road along +x between two rows of box buildings on a ground plane, with red, green and
   blue panels beside the road for colour bleeding. Faces are subdivided evenly so the mesh
   reaches a requested triangle count (1M for the benchmarks). C99 and C++11, header only,
   static functions; y is up, lengths in metres times params.unit.

       street_params sp = {0};             zero means default
       street_mesh sm;
       sp.target_triangles = 1000000;
       if (street_build(&sp, &sm) != 0) ...;   0 on success, -1 on bad params or no memory
       ... sm.positions, sm.normals, sm.indices, sm.triangle_material, sm.reflectance ...
       street_free(&sm);
*/
#ifndef GIMANY_STREET_H
#define GIMANY_STREET_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum {
    STREET_GROUND = 0, STREET_ROAD, STREET_WALL_BEIGE, STREET_WALL_WHITE, STREET_WALL_BRICK,
    STREET_ROOF, STREET_PANEL_RED, STREET_PANEL_GREEN, STREET_PANEL_BLUE,
    STREET_MATERIAL_COUNT
};

typedef struct street_params {
    uint32_t target_triangles;   /* at least this many (within a few percent over); 0: 100000 */
    uint32_t buildings_per_side; /* 0: 16 */
    uint32_t seed;               /* building sizes; the same seed gives the same street */
    float unit;                  /* length of one metre in mesh units; 0: 1 */
    float offset[3];             /* added to every position (far-from-origin tests) */
} street_params;

typedef struct street_mesh {
    float *positions;            /* vertex_count * 3 */
    float *normals;              /* vertex_count * 3, unit, flat per face */
    uint32_t *indices;           /* triangle_count * 3, counter-clockwise seen from outside */
    uint32_t *triangle_material; /* triangle_count material ids */
    uint32_t vertex_count, triangle_count;
    uint32_t material_count;     /* STREET_MATERIAL_COUNT */
    float albedo[STREET_MATERIAL_COUNT][3];   /* diffuse rgb per material */
    float reflectance[STREET_MATERIAL_COUNT]; /* Rec. 709 luminance of the albedo */
    float bounds_min[3], bounds_max[3];
    float sun_direction[3];      /* a suggested direction towards the sun (unit) */
} street_mesh;

/* One planar rectangle before subdivision: o + s u + t v for s, t in [0,1]; u x v faces out. */
typedef struct street__quad { float o[3], u[3], v[3]; uint32_t material; } street__quad;

typedef struct street__list { street__quad *q; uint32_t count, cap; } street__list;

static int street__add(street__list *l, float ox, float oy, float oz, float ux, float uy, float uz,
                       float vx, float vy, float vz, uint32_t material) {
    street__quad *q;
    if (l->count == l->cap) {
        uint32_t ncap = l->cap ? l->cap * 2u : 64u;
        street__quad *n = (street__quad *)realloc(l->q, ncap * sizeof *n);
        if (!n) return -1;
        l->q = n;
        l->cap = ncap;
    }
    q = &l->q[l->count++];
    q->o[0] = ox; q->o[1] = oy; q->o[2] = oz;
    q->u[0] = ux; q->u[1] = uy; q->u[2] = uz;
    q->v[0] = vx; q->v[1] = vy; q->v[2] = vz;
    q->material = material;
    return 0;
}

/* A box standing on the ground (no bottom face): x in [x0,x1], z in [z0,z1], height h. */
static int street__box(street__list *l, float x0, float x1, float z0, float z1, float h, uint32_t wall) {
    float dx = x1 - x0, dz = z1 - z0;
    int r = 0;
    r |= street__add(l, x0, 0, z1, dx, 0, 0, 0, h, 0, wall);      /* +z */
    r |= street__add(l, x1, 0, z0, -dx, 0, 0, 0, h, 0, wall);     /* -z */
    r |= street__add(l, x1, 0, z1, 0, 0, -dz, 0, h, 0, wall);     /* +x */
    r |= street__add(l, x0, 0, z0, 0, 0, dz, 0, h, 0, wall);      /* -x */
    r |= street__add(l, x0, h, z1, dx, 0, 0, 0, 0, -dz, STREET_ROOF); /* top */
    return r;
}

static float street__rand(uint32_t *s) { /* xorshift32 in [0,1) */
    uint32_t x = *s ? *s : 0x9e3779b9u;
    x ^= x << 13; x ^= x >> 17; x ^= x << 5;
    *s = x;
    return (float)(x >> 8) * (1.0f / 16777216.0f);
}

static float street__len(const float *a) { return sqrtf(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]); }

/* Cells of a quad along u and v at s cells per metre. */
static void street__cells(const street__quad *q, double s, uint32_t *nu, uint32_t *nv) {
    double a = ceil(street__len(q->u) * s), b = ceil(street__len(q->v) * s);
    *nu = a < 1.0 ? 1u : (a > 65535.0 ? 65535u : (uint32_t)a);
    *nv = b < 1.0 ? 1u : (b > 65535.0 ? 65535u : (uint32_t)b);
}
static double street__triangles(const street__list *l, double s) {
    double t = 0.0;
    uint32_t i, nu, nv;
    for (i = 0; i < l->count; ++i) { street__cells(&l->q[i], s, &nu, &nv); t += 2.0 * nu * nv; }
    return t;
}

static void street_free(street_mesh *m) {
    if (!m) return;
    free(m->positions); free(m->normals); free(m->indices); free(m->triangle_material);
    memset(m, 0, sizeof *m);
}

#ifdef GIMANY_H
/* The street as gimany's mesh input: positions, flat normals, indices, materials. */
static inline gim_mesh_data street_mesh_data(const street_mesh *m) {
    gim_mesh_data d;
    memset(&d, 0, sizeof d);
    d.positions = m->positions;
    d.normals = m->normals;
    d.vertex_count = m->vertex_count;
    d.indices = m->indices;
    d.index_count = m->triangle_count * 3;
    d.triangle_material = m->triangle_material;
    d.material_reflectance = m->reflectance;
    d.material_count = m->material_count;
    return d;
}
#endif

static int street_build(const street_params *p, street_mesh *m) {
    static const float albedo[STREET_MATERIAL_COUNT][3] = {
        {0.35f, 0.35f, 0.33f}, {0.08f, 0.08f, 0.09f}, {0.72f, 0.63f, 0.50f}, {0.80f, 0.80f, 0.78f},
        {0.55f, 0.26f, 0.18f}, {0.30f, 0.30f, 0.32f}, {0.80f, 0.08f, 0.08f}, {0.10f, 0.70f, 0.15f},
        {0.10f, 0.20f, 0.80f}};
    street__list l = {NULL, 0, 0};
    uint32_t target = p && p->target_triangles ? p->target_triangles : 100000u;
    uint32_t per_side = p && p->buildings_per_side ? p->buildings_per_side : 16u;
    uint32_t seed = (p ? p->seed : 0u) * 2654435761u + 12345u;
    float unit = p && p->unit > 0.0f ? p->unit : 1.0f;
    float off[3] = {0.0f, 0.0f, 0.0f};
    float x, length;
    double lo = 0.0, hi = 1.0, s;
    uint32_t side, i, b, k, vtx = 0, tri = 0;
    int err = 0;
    if (!m) return -1;
    memset(m, 0, sizeof *m);
    if (p) memcpy(off, p->offset, sizeof off);
    if (per_side > 4096u || !(unit < 1e30f)) return -1;

    /* two rows of buildings along the road, coloured panels in some of the gaps */
    for (side = 0; side < 2; ++side) {
        x = 0.0f;
        for (b = 0; b < per_side; ++b) {
            float w = 8.0f + 8.0f * street__rand(&seed), d = 8.0f + 6.0f * street__rand(&seed);
            float h = 6.0f + 24.0f * street__rand(&seed), gap = 2.0f + 3.0f * street__rand(&seed);
            uint32_t wall = STREET_WALL_BEIGE + (uint32_t)(3.0f * street__rand(&seed)) % 3u;
            if (side == 0) err |= street__box(&l, x, x + w, 9.0f, 9.0f + d, h, wall);
            else err |= street__box(&l, x, x + w, -9.0f - d, -9.0f, h, wall);
            if (b % 3u == 1u) { /* a 3 x 2.5 m panel in the gap, facing the road */
                uint32_t mat = STREET_PANEL_RED + (b / 3u + side) % 3u;
                float px = x + w + 0.5f * gap - 1.5f;
                if (side == 0) err |= street__add(&l, px + 3.0f, 0.5f, 7.5f, -3.0f, 0, 0, 0, 2.5f, 0, mat);
                else err |= street__add(&l, px, 0.5f, -7.5f, 3.0f, 0, 0, 0, 2.5f, 0, mat);
            }
            x += w + gap;
        }
    }
    length = x;
    for (i = 0; i < l.count; ++i) /* the longer row sets the street's length */
        if (l.q[i].o[0] > length) length = l.q[i].o[0];
    /* road and ground strips, side by side (no overlapping coplanar surfaces) */
    err |= street__add(&l, -10.0f, 0, 6.0f, length + 20.0f, 0, 0, 0, 0, -12.0f, STREET_ROAD);
    err |= street__add(&l, -10.0f, 0, 40.0f, length + 20.0f, 0, 0, 0, 0, -34.0f, STREET_GROUND);
    err |= street__add(&l, -10.0f, 0, -6.0f, length + 20.0f, 0, 0, 0, 0, -34.0f, STREET_GROUND);
    if (err) { free(l.q); return -1; }

    /* the smallest density whose subdivision reaches the target */
    while (street__triangles(&l, hi) < (double)target && hi < 1e6) hi *= 2.0;
    for (k = 0; k < 60; ++k) {
        double mid = 0.5 * (lo + hi);
        if (street__triangles(&l, mid) >= (double)target) hi = mid; else lo = mid;
    }
    s = hi;
    {
        double tv = 0.0, tt = 0.0;
        for (i = 0; i < l.count; ++i) {
            uint32_t nu, nv;
            street__cells(&l.q[i], s, &nu, &nv);
            tv += (double)(nu + 1u) * (nv + 1u);
            tt += 2.0 * nu * nv;
        }
        if (tv > 4e9 || tt > 1.4e9) { free(l.q); return -1; }
        m->vertex_count = (uint32_t)tv;
        m->triangle_count = (uint32_t)tt;
    }
    m->positions = (float *)malloc((size_t)m->vertex_count * 3u * sizeof(float));
    m->normals = (float *)malloc((size_t)m->vertex_count * 3u * sizeof(float));
    m->indices = (uint32_t *)malloc((size_t)m->triangle_count * 3u * sizeof(uint32_t));
    m->triangle_material = (uint32_t *)malloc((size_t)m->triangle_count * sizeof(uint32_t));
    if (!m->positions || !m->normals || !m->indices || !m->triangle_material) {
        free(l.q);
        street_free(m);
        return -1;
    }
    for (k = 0; k < 3; ++k) { m->bounds_min[k] = 1e30f; m->bounds_max[k] = -1e30f; }
    for (i = 0; i < l.count; ++i) {
        const street__quad *q = &l.q[i];
        uint32_t nu, nv, a, c, base = vtx;
        float n[3], ln;
        street__cells(q, s, &nu, &nv);
        n[0] = q->u[1] * q->v[2] - q->u[2] * q->v[1];
        n[1] = q->u[2] * q->v[0] - q->u[0] * q->v[2];
        n[2] = q->u[0] * q->v[1] - q->u[1] * q->v[0];
        ln = street__len(n);
        for (k = 0; k < 3; ++k) n[k] /= ln;
        for (c = 0; c <= nv; ++c)
            for (a = 0; a <= nu; ++a) {
                float su = (float)a / (float)nu, sv = (float)c / (float)nv;
                for (k = 0; k < 3; ++k) {
                    float pk = (q->o[k] + su * q->u[k] + sv * q->v[k]) * unit + off[k];
                    m->positions[vtx * 3u + k] = pk;
                    m->normals[vtx * 3u + k] = n[k];
                    if (pk < m->bounds_min[k]) m->bounds_min[k] = pk;
                    if (pk > m->bounds_max[k]) m->bounds_max[k] = pk;
                }
                ++vtx;
            }
        for (c = 0; c < nv; ++c)
            for (a = 0; a < nu; ++a) {
                uint32_t v00 = base + c * (nu + 1u) + a, v10 = v00 + 1u, v01 = v00 + nu + 1u, v11 = v01 + 1u;
                uint32_t *ix = &m->indices[(size_t)tri * 3u];
                ix[0] = v00; ix[1] = v10; ix[2] = v11;
                ix[3] = v00; ix[4] = v11; ix[5] = v01;
                m->triangle_material[tri] = q->material;
                m->triangle_material[tri + 1u] = q->material;
                tri += 2u;
            }
    }
    free(l.q);
    m->material_count = STREET_MATERIAL_COUNT;
    for (i = 0; i < STREET_MATERIAL_COUNT; ++i) {
        for (k = 0; k < 3; ++k) m->albedo[i][k] = albedo[i][k];
        m->reflectance[i] = 0.2126f * albedo[i][0] + 0.7152f * albedo[i][1] + 0.0722f * albedo[i][2];
    }
    m->sun_direction[0] = 0.3f; m->sun_direction[1] = 0.8f; m->sun_direction[2] = 0.52f;
    {
        float ls = street__len(m->sun_direction);
        for (k = 0; k < 3; ++k) m->sun_direction[k] /= ls;
    }
    return 0;
}

#endif
