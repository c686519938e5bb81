/* Quads for the GL tests' rooms: a triangle soup of big quads (two triangles each) with face
   normals and a material per triangle, uploaded with gim_add_mesh. */
#ifndef GIMANY_TESTS_ROOM_H
#define GIMANY_TESTS_ROOM_H
#include <math.h>
#include <stdint.h>

#define MAX_Q 16
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

#endif
