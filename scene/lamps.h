/* The lamp street of the many-light test and bench (tests/gl/gltest_lights.c, bench_lights.c):
   ground (white) x in [-8, 8], z in [-2, 2]; facades at z = -2 (red, facing +z) and z = 2
   (green, facing -z), 3 high; a canopy (white, facing up) at y = 5, x in [-12, -9], behind
   the camera: four meshes. Lights 0-23 are lamps over the street pointing down, 24-27 point
   into the sky (their frusta meet no instance), 28-31 shine down onto the canopy (its VALs
   face up, every view sample is below). Needs room.h. */
#ifndef GIMANY_TESTS_LAMPS_H
#define GIMANY_TESTS_LAMPS_H
#include <math.h>
#include <string.h>

static ROOM_UNUSED void lamps_quads(room r[4]) {
#define SET3(a, x, y, z) ((a)[0] = (x), (a)[1] = (y), (a)[2] = (z))
    float c[3], u[3], v[3];
    memset(r, 0, 4 * sizeof *r);
    SET3(c, -8, 0, 2); SET3(u, 16, 0, 0); SET3(v, 0, 0, -4); add_quad(&r[0], c, u, v, 0);
    SET3(c, -8, 0, -2); SET3(u, 16, 0, 0); SET3(v, 0, 3, 0); add_quad(&r[1], c, u, v, 1);
    SET3(c, -8, 0, 2); SET3(u, 0, 3, 0); SET3(v, 16, 0, 0); add_quad(&r[2], c, u, v, 2);
    SET3(c, -12, 5, 2); SET3(u, 3, 0, 0); SET3(v, 0, 0, -4); add_quad(&r[3], c, u, v, 0);
#undef SET3
}

static ROOM_UNUSED gim_light lamps_light(int k, uint32_t rsm) {
    gim_light l;
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.rsm_size = rsm;
    l.color[0] = 1.0f; l.color[1] = 0.8f + 0.1f * (float)(k % 3); l.color[2] = 0.5f + 0.5f * (float)(k % 2);
    if (k < 24) {
        l.intensity = 0.5f + 0.25f * (float)(k % 7);
        l.position = gim_v3(-6.0f + 0.5f * (float)k, 2.7f, (k & 1) ? 1.0f : -1.0f);
        l.direction = gim_v3(0.2f * sinf((float)k), -1.0f, (k & 1) ? 0.3f : -0.3f);
        l.cone_angle = 0.6f;
    } else if (k < 28) {
        l.intensity = 3.0f;
        l.position = gim_v3(-4.0f + 2.5f * (float)(k - 24), 2.8f, 0.0f);
        l.direction = gim_v3(0.05f, 1.0f, 0.0f);
        l.cone_angle = 0.5f;
    } else {
        l.intensity = 3.0f;
        l.position = gim_v3(-11.5f + 0.6f * (float)(k - 28), 6.0f, (k & 1) ? 0.5f : -0.5f);
        l.direction = gim_v3(0.0f, -1.0f, 0.0f);
        l.cone_angle = 0.4f;
    }
    return l;
}

/* The camera at the street's west end, looking east. */
static ROOM_UNUSED void lamps_view(gim_frame *fr, uint32_t w, uint32_t h) {
    fr->view = gim_mat4_look_at(gim_v3(-7.0f, 1.6f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr->proj = gim_mat4_perspective(1.1f, (float)w / (float)h, 0.1f, 30.0f);
    fr->width = w;
    fr->height = h;
}
#endif
