/* Quads for the GL tests' rooms: a triangle soup of big quads (two triangles each) with face
   normals and a material per triangle, uploaded with gim_add_mesh. */
#ifndef GIMANY_TESTS_ROOM_H
#define GIMANY_TESTS_ROOM_H
#include <math.h>
#include <stdint.h>
#include <string.h>

#define MAX_Q 16
#if defined(__GNUC__) || defined(__clang__)
#define ROOM_UNUSED __attribute__((unused))
#else
#define ROOM_UNUSED
#endif
typedef struct room {
    float pos[MAX_Q * 12], nrm[MAX_Q * 12];
    uint32_t idx[MAX_Q * 6], mat[MAX_Q * 2];
    uint32_t quads;
} room;

/* A quad at corner c spanned by u and v (normal u x v). */
static void add_quad(room *r, const float c[3], const float u[3], const float v[3], uint32_t material) {
    uint32_t q = r->quads++, k;
    float n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (k = 0; k < 3; ++k) {
        r->pos[q * 12 + k] = c[k];
        r->pos[q * 12 + 3 + k] = c[k] + u[k];
        r->pos[q * 12 + 6 + k] = c[k] + u[k] + v[k];
        r->pos[q * 12 + 9 + k] = c[k] + v[k];
    }
    for (k = 0; k < 12; ++k) r->nrm[q * 12 + k] = n[k % 3] / l;
    r->idx[q * 6 + 0] = q * 4; r->idx[q * 6 + 1] = q * 4 + 1; r->idx[q * 6 + 2] = q * 4 + 2;
    r->idx[q * 6 + 3] = q * 4; r->idx[q * 6 + 4] = q * 4 + 2; r->idx[q * 6 + 5] = q * 4 + 3;
    r->mat[q * 2] = r->mat[q * 2 + 1] = material;
}

/* An open box of five quads under the sky: floor, three walls, a roof over the back half. */
static ROOM_UNUSED void room_open_box(room *r) {
    float c[3], u[3], v[3];
#define Q(cx, cy, cz, ux, uy, uz, vx, vy, vz, m) do { c[0] = cx; c[1] = cy; c[2] = cz; u[0] = ux; u[1] = uy; u[2] = uz; \
        v[0] = vx; v[1] = vy; v[2] = vz; add_quad(r, c, u, v, m); } while (0)
    memset(r, 0, sizeof *r);
    Q(-2, 0, 2, 4, 0, 0, 0, 0, -4, 0);      /* floor, +y */
    Q(-2, 0, -2, 0, 2, 0, 0, 0, 4, 1);      /* left wall, +x */
    Q(2, 0, 2, 0, 2, 0, 0, 0, -4, 2);       /* right wall, -x */
    Q(-2, 0, -2, 4, 0, 0, 0, 2, 0, 3);      /* back wall, +z */
    Q(-2, 2, -2, 0, 0, 2.5f, 4, 0, 0, 0);   /* roof over the back half, -y */
#undef Q
}

/* The room as gim_mesh_data (32-bit indices, its materials). */
static ROOM_UNUSED gim_mesh_data room_arrays(const room *r) {
    gim_mesh_data m;
    memset(&m, 0, sizeof m);
    m.positions = r->pos;
    m.vertex_count = r->quads * 4;
    m.normals = r->nrm;
    m.indices = r->idx;
    m.index_count = r->quads * 6;
    m.index_type = GIM_INDEX_U32;
    m.triangle_material = r->mat;
    return m;
}

/* The rooms' materials: floor white, left wall red, right wall green, back wall glossy. */
static const gim_material room_materials[4] = {
    {{0.8f, 0.8f, 0.8f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.8f, 0.1f, 0.1f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.1f, 0.8f, 0.1f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.3f, 0.3f, 0.3f}, {0.4f, 0.4f, 0.4f}, 12.0f}};

/* A G-buffer pixel (its view sample vs, albedo rgba, material id) as a gim_receiver seen from
   eye: 0 where nothing is drawn. host: the host's G-buffer (albedo 1, no glossy term). */
static ROOM_UNUSED int room_receiver(const gim_view_sample *vs, gim_vec3 eye, const float *albedo, float material, int host,
                         gim_receiver *rc) {
    double l = 0.0;
    int k;
    if (!(vs->normal.x != 0.0f || vs->normal.y != 0.0f || vs->normal.z != 0.0f)) return 0;
    rc->position[0] = vs->position.x; rc->position[1] = vs->position.y; rc->position[2] = vs->position.z;
    rc->normal[0] = vs->normal.x; rc->normal[1] = vs->normal.y; rc->normal[2] = vs->normal.z;
    for (k = 0; k < 3; ++k) {
        double d = (k == 0 ? eye.x : k == 1 ? eye.y : eye.z) - (double)rc->position[k];
        rc->view[k] = (float)d;
        l += d * d;
    }
    for (k = 0; k < 3; ++k) rc->view[k] = (float)(rc->view[k] / sqrt(l));
    if (host) {
        rc->albedo[0] = rc->albedo[1] = rc->albedo[2] = 1.0f;
    } else {
        const gim_material *m = &room_materials[(int)material];
        memcpy(rc->albedo, albedo, 12);
        memcpy(rc->glossy, m->glossy, 12);
        rc->exponent = m->exponent;
    }
    return 1;
}

/* The sun of the room tests: irradiance 1 from (0.3, 1, 0.6), a 64^2 RSM. */
static ROOM_UNUSED gim_light room_sun(void) {
    gim_light sun;
    memset(&sun, 0, sizeof sun);
    sun.type = GIM_LIGHT_DIRECTIONAL;
    sun.irradiance = 1.0f;
    sun.direction = gim_v3(0.3f, 1.0f, 0.6f);
    sun.rsm_size = 64;
    return sun;
}

#endif
