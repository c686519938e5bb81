/* Imperfect shadow maps against exact visibility, CPU twins only (no GL): the LightSkin frame
   (gim_lightskin_frame_twin, FULL: every RSM texel a VAL) with no visibility, with the ISM
   (gim_ism_render_twin + gim_ism_visibility_twin) and with exact per-VAL visibility (every cache-VAL
   segment ray-cast against every triangle), on
     closed  a sealed box with 0.3-thick walls, floor and roof on a sunlit ground, camera
             inside: the exact indirect light inside is 0; reported as the mean inside over
             the sunlit ground's radiance (rho E cos / pi)
     cornell the measured Cornell box with its spot (../shared/scenes, the scene layer)
   and the visibility error itself: sum over (cache, VAL) of e_j |V_ism - V_exact| / sum e_j,
   e_j the VAL's unoccluded irradiance at the cache (how much light the ISM gets wrong).
   Usage: build/bench/bench_ism [size points_per_map]; ISM_BIAS, ISM_SLOPE in the environment
   override gim_ism_desc's bias and slope. */
#define _POSIX_C_SOURCE 199309L
#define GIMANY_IMPLEMENTATION
#define GIMANY_NO_GL
#include "gimany.h"
#include "scene.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define RSM 48u
#define W 64u
#define H 48u
#define POOL 65536u

typedef struct soup {
    float *pos, *nrm, *alb;  /* per triangle: 9, 9, 3 */
    uint32_t *idx;
    uint32_t n;
} soup;

static double now_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void soup_from_scene(const scene *s, soup *o) {
    uint32_t m, t, k = 0, a;
    o->n = 0;
    for (m = 0; m < s->mesh_count; ++m) o->n += s->meshes[m].triangle_count;
    o->pos = (float *)malloc((size_t)o->n * 9 * sizeof(float));
    o->nrm = (float *)malloc((size_t)o->n * 9 * sizeof(float));
    o->alb = (float *)malloc((size_t)o->n * 3 * sizeof(float));
    o->idx = (uint32_t *)malloc((size_t)o->n * 3 * sizeof(uint32_t));
    for (m = 0; m < s->mesh_count; ++m) {
        const scene_mesh *sm = s->meshes + m;
        for (t = 0; t < sm->triangle_count; ++t, ++k) {
            for (a = 0; a < 3; ++a) {
                uint32_t v = sm->indices[t * 3 + a];
                memcpy(o->pos + (size_t)k * 9 + a * 3, sm->positions + (size_t)v * 3, 12);
                memcpy(o->nrm + (size_t)k * 9 + a * 3, sm->normals + (size_t)v * 3, 12);
                o->idx[k * 3 + a] = k * 3 + a;
            }
            memcpy(o->alb + (size_t)k * 3, s->materials[sm->triangle_material[t]].diffuse, 12);
        }
    }
}

static void soup_free(soup *o) {
    free(o->pos); free(o->nrm); free(o->alb); free(o->idx);
}

/* 1 where the segment a -> b meets no triangle strictly between (ends excluded by 1e-4 of
   its length). */
static int segment_clear(const soup *s, const float a[3], const float b[3]) {
    double d[3], len2 = 0.0;
    uint32_t t;
    int i;
    for (i = 0; i < 3; ++i) { d[i] = (double)b[i] - a[i]; len2 += d[i] * d[i]; }
    if (!(len2 > 0.0)) return 1;
    for (t = 0; t < s->n; ++t) {
        const float *v = s->pos + (size_t)t * 9;
        double e1[3], e2[3], pv[3], tv[3], qv[3], det, u, w, tt;
        for (i = 0; i < 3; ++i) { e1[i] = (double)v[3 + i] - v[i]; e2[i] = (double)v[6 + i] - v[i]; tv[i] = a[i] - (double)v[i]; }
        pv[0] = d[1] * e2[2] - d[2] * e2[1]; pv[1] = d[2] * e2[0] - d[0] * e2[2]; pv[2] = d[0] * e2[1] - d[1] * e2[0];
        det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (det == 0.0) continue;
        u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
        if (u < 0.0 || u > 1.0) continue;
        qv[0] = tv[1] * e1[2] - tv[2] * e1[1]; qv[1] = tv[2] * e1[0] - tv[0] * e1[2]; qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
        w = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
        if (w < 0.0 || u + w > 1.0) continue;
        tt = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (tt > 1e-4 && tt < 1.0 - 1e-4) return 0;
    }
    return 1;
}

/* The closed room: ground 40 x 40 at y = 0; box [-2, 2] x [0, 3] x [-2, 2] with walls, roof
   and floor 0.3 thick (outer faces outwards, inner faces inwards); the sun (0.4, 1, 0.3). */
static void quad(scene_mesh *m, uint32_t *q, const float c[3], const float u[3], const float v[3]) {
    float n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    uint32_t k, b = *q * 4;
    for (k = 0; k < 3; ++k) {
        m->positions[b * 3 + k] = c[k];
        m->positions[b * 3 + 3 + k] = c[k] + u[k];
        m->positions[b * 3 + 6 + k] = c[k] + u[k] + v[k];
        m->positions[b * 3 + 9 + k] = c[k] + v[k];
    }
    for (k = 0; k < 12; ++k) m->normals[b * 3 + k] = n[k % 3] / l;
    m->indices[*q * 6 + 0] = b; m->indices[*q * 6 + 1] = b + 1; m->indices[*q * 6 + 2] = b + 2;
    m->indices[*q * 6 + 3] = b; m->indices[*q * 6 + 4] = b + 2; m->indices[*q * 6 + 5] = b + 3;
    m->triangle_material[*q * 2] = m->triangle_material[*q * 2 + 1] = 0;
    ++*q;
}

/* An axis-aligned box [lo, hi] as 6 quads (5 without the bottom), normals out (in: inwards). */
static void box(scene_mesh *m, uint32_t *q, const float lo[3], const float hi[3], int in, int bottom) {
    float e[3] = {hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]};
    float X[3] = {e[0], 0, 0}, Y[3] = {0, e[1], 0}, Z[3] = {0, 0, e[2]};
    float c[3];
    /* each face from a corner with (u, v) ordered so u x v points out; in swaps them */
#define FACE(cx, cy, cz, U, V) do { c[0] = cx; c[1] = cy; c[2] = cz; if (in) quad(m, q, c, V, U); else quad(m, q, c, U, V); } while (0)
    FACE(lo[0], lo[1], lo[2], Z, Y);          /* -x */
    FACE(hi[0], lo[1], lo[2], Y, Z);          /* +x */
    if (bottom) FACE(lo[0], lo[1], lo[2], X, Z); /* -y */
    FACE(lo[0], hi[1], lo[2], Z, X);          /* +y */
    FACE(lo[0], lo[1], lo[2], Y, X);          /* -z */
    FACE(lo[0], lo[1], hi[2], X, Y);          /* +z */
#undef FACE
}

static int closed_room(scene *s) {
    static float pos[16 * 12], nrm[16 * 12];
    static uint32_t idx[16 * 6], mat[16 * 2];
    static scene_mesh mesh;
    static scene_material matl = {{0.8f, 0.8f, 0.8f}, {0.0f, 0.0f, 0.0f}, 0.0f};
    static scene_light sun;
    char err[256];
    uint32_t q = 0;
    float g0[3] = {-20.0f, 0.0f, -20.0f}, gu[3] = {0.0f, 0.0f, 40.0f}, gv[3] = {40.0f, 0.0f, 0.0f};
    float olo[3] = {-2.0f, 0.0f, -2.0f}, ohi[3] = {2.0f, 3.0f, 2.0f};
    float ilo[3] = {-1.7f, 0.3f, -1.7f}, ihi[3] = {1.7f, 2.7f, 1.7f};
    memset(s, 0, sizeof *s);
    mesh.positions = pos; mesh.normals = nrm; mesh.indices = idx; mesh.triangle_material = mat;
    quad(&mesh, &q, g0, gu, gv);
    box(&mesh, &q, olo, ohi, 0, 0);
    box(&mesh, &q, ilo, ihi, 1, 1);
    mesh.vertex_count = q * 4;
    mesh.triangle_count = q * 2;
    sun.type = SCENE_LIGHT_DIRECTIONAL;
    sun.color[0] = sun.color[1] = sun.color[2] = 1.0f;
    sun.direction[0] = 0.4f; sun.direction[1] = 1.0f; sun.direction[2] = 0.3f;
    sun.irradiance = 1.0f;
    s->meshes = &mesh; s->mesh_count = 1;
    s->materials = &matl; s->material_count = 1;
    s->lights = &sun; s->light_count = 1;
    s->camera.eye[0] = 0.0f; s->camera.eye[1] = 1.5f; s->camera.eye[2] = 1.4f;
    s->camera.target[0] = 0.2f; s->camera.target[1] = 0.9f; s->camera.target[2] = -1.7f;
    s->camera.fovy = 1.4f;
    s->camera.width = W; s->camera.height = H;
    if (scene_validate(s, err, sizeof err) != 0) { fprintf(stderr, "closed room: %s\n", err); return 1; }
    return 0;
}

typedef struct frame {
    gim_cache_set caches;
    gim_val *vals;
    uint32_t val_count;
    gim_receiver *rc;
    uint32_t rc_count;
    uint32_t *nidx, *ncnt;
    float *dcmax;
    float scale;
    gim_vec3 eye;
} frame;

static int make_frame(const scene *s, const soup *sp, frame *f) {
    gim_twin_scene ts = {sp->pos, sp->nrm, sp->alb, sp->n};
    gim_cache_desc cd;
    gim_light light;
    gim_rsm_data rsm;
    float *rp, *rn, *rf, *ra, *rv, view[16], proj[16];
    gim_camera cam;
    uint32_t x, y;
    gim_neighbour_desc nd;
    gim_neighbour_result nr;
    gim_mesh_data md;
    float *ppos, *pnrm;
    const scene_light *l = s->lights;
    memset(f, 0, sizeof *f);
    f->scale = s->scale;
    memset(&cd, 0, sizeof cd);
    cd.mesh.positions = sp->pos; cd.mesh.vertex_count = sp->n * 3;
    cd.mesh.normals = sp->nrm;
    cd.mesh.indices = sp->idx; cd.mesh.index_count = sp->n * 3;
    cd.scene_scale = s->scale;
    if (gim_cache_generate(&cd, &f->caches) != GIM_OK) return 1;
    memset(&light, 0, sizeof light);
    light.color[0] = l->color[0]; light.color[1] = l->color[1]; light.color[2] = l->color[2];
    light.rsm_size = RSM;
    if (l->type == SCENE_LIGHT_SPOT) {
        light.type = GIM_LIGHT_SPOT;
        light.intensity = l->intensity;
        light.position = gim_v3(l->position[0], l->position[1], l->position[2]);
        light.direction = gim_v3(l->direction[0], l->direction[1], l->direction[2]);
        light.cone_angle = l->half_angle < 1.5f ? l->half_angle : 1.5f;
    } else {
        light.type = GIM_LIGHT_DIRECTIONAL;
        light.irradiance = l->irradiance;
        light.direction = gim_v3(l->direction[0], l->direction[1], l->direction[2]);
    }
    rp = (float *)calloc(RSM * RSM * 3, sizeof(float)); rn = (float *)calloc(RSM * RSM * 3, sizeof(float));
    rf = (float *)calloc(RSM * RSM * 3, sizeof(float)); ra = (float *)calloc(RSM * RSM, sizeof(float));
    rv = (float *)calloc(RSM * RSM, sizeof(float));
    for (y = 0; y < RSM; ++y)
        for (x = 0; x < RSM; ++x) {
            gim_rsm_texel t;
            gim_rsm_view lv = {&light, s->bounds_min, s->bounds_max};
            uint32_t k = y * RSM + x;
            if (gim_rsm_texel_twin(&ts, &lv, x, y, &t) != GIM_OK) return 1;
            memcpy(rp + k * 3, t.position, 12); memcpy(rn + k * 3, t.normal, 12); memcpy(rf + k * 3, t.flux, 12);
            ra[k] = t.area; rv[k] = (float)t.lit;
        }
    rsm.position = rp; rsm.normal = rn; rsm.flux = rf; rsm.area = ra; rsm.valid = rv;
    rsm.width = rsm.height = RSM;
    f->val_count = RSM * RSM;
    f->vals = (gim_val *)malloc(f->val_count * sizeof(gim_val));
    if (gim_vals_gather_twin(&rsm, NULL, 0, f->vals, f->caches.env) != GIM_OK) return 1;
    free(rp); free(rn); free(rf); free(ra); free(rv);
    /* receivers: the camera's G-buffer */
    scene_camera_matrices(&s->camera, 0.01f * s->scale, 4.0f * s->scale, view, proj);
    memcpy(cam.view.m, view, sizeof view); memcpy(cam.proj.m, proj, sizeof proj);
    cam.width = W; cam.height = H;
    f->eye = gim_v3(s->camera.eye[0], s->camera.eye[1], s->camera.eye[2]);
    f->rc = (gim_receiver *)calloc(W * H, sizeof(gim_receiver));
    ppos = (float *)calloc(W * H * 3, sizeof(float)); pnrm = (float *)calloc(W * H * 3, sizeof(float));
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            gim_gbuffer_texel g;
            gim_receiver *r = f->rc + f->rc_count;
            double vl = 0.0;
            int a;
            if (gim_gbuffer_texel_twin(&ts, &cam, x, y, &g) != GIM_OK) return 1;
            if (g.triangle == UINT32_MAX) continue;
            memcpy(r->position, g.position, 12); memcpy(r->normal, g.normal, 12); memcpy(r->albedo, g.albedo, 12);
            for (a = 0; a < 3; ++a) { r->view[a] = s->camera.eye[a] - g.position[a]; vl += (double)r->view[a] * r->view[a]; }
            for (a = 0; a < 3; ++a) r->view[a] = (float)(r->view[a] / sqrt(vl));
            memcpy(ppos + f->rc_count * 3, g.position, 12); memcpy(pnrm + f->rc_count * 3, g.normal, 12);
            ++f->rc_count;
        }
    memset(&md, 0, sizeof md);
    md.positions = ppos; md.vertex_count = f->rc_count; md.normals = pnrm;
    memset(&nd, 0, sizeof nd);
    nd.mesh = md; nd.caches = &f->caches; nd.n = GIM_MAX_NEIGHBOUR_CACHES;
    f->nidx = (uint32_t *)malloc((size_t)f->rc_count * GIM_MAX_NEIGHBOUR_CACHES * 4);
    f->ncnt = (uint32_t *)malloc((size_t)f->rc_count * 4);
    f->dcmax = (float *)malloc((size_t)f->rc_count * 4);
    nr.index = f->nidx; nr.count = f->ncnt; nr.d_cmax = f->dcmax;
    if (gim_cache_neighbours(&nd, &nr) != GIM_OK) return 1;
    free(ppos); free(pnrm);
    return 0;
}

static void frame_free(frame *f) {
    gim_cache_set_free(&f->caches);
    free(f->vals); free(f->rc); free(f->nidx); free(f->ncnt); free(f->dcmax);
}

static int shade(const frame *f, const float *vis, float *out) {
    gim_lightskin_desc d;
    memset(&d, 0, sizeof d);
    d.caches = f->caches.caches; d.cache_count = f->caches.count;
    d.vals = f->vals; d.val_count = f->val_count;
    d.eye = f->eye;
    d.receivers = f->rc; d.receiver_count = f->rc_count;
    d.neighbour_index = f->nidx; d.neighbour_count = f->ncnt; d.neighbour_stride = GIM_MAX_NEIGHBOUR_CACHES;
    d.d_cmax = f->dcmax;
    d.scene_scale = f->scale;
    d.visibility = vis;
    return gim_lightskin_frame_twin(&d, out) != GIM_OK;
}

static double rel_mae(const float *a, const float *b, size_t n) {
    double sd = 0.0, sb = 0.0;
    size_t i;
    for (i = 0; i < n; ++i) { sd += fabs((double)a[i] - b[i]); sb += fabs((double)b[i]); }
    return sb > 0.0 ? sd / sb : sd;
}

static double mean_lum(const float *a, uint32_t n) {
    double s = 0.0;
    uint32_t i;
    for (i = 0; i < n; ++i) s += 0.2126 * a[i * 3] + 0.7152 * a[i * 3 + 1] + 0.0722 * a[i * 3 + 2];
    return n ? s / n : 0.0;
}

static int run(const char *name, const scene *s, uint32_t size, uint32_t per_map, int closed) {
    soup sp;
    frame f;
    gim_twin_scene ts;
    gim_ism_desc id;
    float *pts, *maps, *vis_i, *vis_e, *img[3];
    size_t cv, q;
    uint32_t c, j;
    double t0, t_pts, t_maps, t_look, t_exact, wrong = 0.0, total = 0.0, leak = 0.0;
    soup_from_scene(s, &sp);
    if (make_frame(s, &sp, &f) != 0) { fprintf(stderr, "%s: frame setup failed\n", name); return 1; }
    ts.positions = sp.pos; ts.normals = sp.nrm; ts.albedo = sp.alb; ts.triangle_count = sp.n;
    cv = (size_t)f.caches.count * f.val_count;
    pts = (float *)malloc((size_t)POOL * 8 * sizeof(float));
    maps = (float *)malloc((size_t)f.caches.count * size * size * sizeof(float));
    vis_i = (float *)malloc(cv * sizeof(float));
    vis_e = (float *)malloc(cv * sizeof(float));
    for (j = 0; j < 3; ++j) img[j] = (float *)malloc((size_t)f.rc_count * 3 * sizeof(float));
    t0 = now_s();
    if (gim_ism_points(&ts, POOL, pts) != GIM_OK) return 1;
    t_pts = now_s() - t0;
    memset(&id, 0, sizeof id);
    id.caches = f.caches.caches; id.cache_count = f.caches.count;
    id.points = pts; id.point_count = POOL;
    id.size = size; id.points_per_map = per_map;
    id.scene_scale = f.scale;
    id.bias = getenv("ISM_BIAS") ? (float)atof(getenv("ISM_BIAS")) : 0.0f;
    id.slope = getenv("ISM_SLOPE") ? (float)atof(getenv("ISM_SLOPE")) : 0.0f;
    t0 = now_s();
    if (gim_ism_render_twin(&id, maps) != GIM_OK) return 1;
    t_maps = now_s() - t0;
    t0 = now_s();
    if (gim_ism_visibility_twin(&id, maps, f.vals, f.val_count, vis_i) != GIM_OK) return 1;
    t_look = now_s() - t0;
    /* exact: the segment from the map's origin to the VAL lifted 1e-4 scales off its surface */
    t0 = now_s();
    for (c = 0; c < f.caches.count; ++c) {
        const gim_cache *cc = f.caches.caches + c;
        float o[3];
        int a;
        for (a = 0; a < 3; ++a) o[a] = cc->position[a] + GIM_ISM_LIFT * f.scale * cc->normal[a];
        for (j = 0; j < f.val_count; ++j) {
            const gim_val *l = f.vals + j;
            float x[3], d[3], d2, cx, cl, e;
            for (a = 0; a < 3; ++a) { x[a] = l->position[a] + 1e-4f * f.scale * l->normal[a]; d[a] = l->position[a] - cc->position[a]; }
            d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            cx = (d[0] * cc->normal[0] + d[1] * cc->normal[1] + d[2] * cc->normal[2]);
            cl = -(d[0] * l->normal[0] + d[1] * l->normal[1] + d[2] * l->normal[2]);
            q = (size_t)c * f.val_count + j;
            if (!(l->weight > 0.0f) || !(cx > 0.0f) || !(cl > 0.0f) || !(d2 > 0.0f)) { vis_e[q] = 1.0f; continue; }
            vis_e[q] = (float)segment_clear(&sp, o, x);
            e = l->weight * (0.2126f * l->flux[0] + 0.7152f * l->flux[1] + 0.0722f * l->flux[2]) * cx * cl /
                (sqrtf(d2) * sqrtf(d2) * (l->area + 3.14159265f * d2));
            total += e;
            wrong += e * fabs((double)vis_i[q] - vis_e[q]);
            leak += e * (vis_i[q] > vis_e[q] ? 1.0 : 0.0);
        }
    }
    t_exact = now_s() - t0;
    if (shade(&f, NULL, img[0]) || shade(&f, vis_i, img[1]) || shade(&f, vis_e, img[2])) return 1;
    printf("%-8s %3u caches %5u VALs %4u receivers  ISM %2u^2 x %5u points: points %.3f s, maps %.3f s, lookups %.3f s "
           "(exact casts %.1f s)\n",
           name, f.caches.count, f.val_count, f.rc_count, size, per_map, t_pts, t_maps, t_look, t_exact);
    printf("         visibility error (light-weighted): %.4f (leaks %.4f, false shadow %.4f)\n",
           total > 0.0 ? wrong / total : 0.0, total > 0.0 ? leak / total : 0.0, total > 0.0 ? (wrong - leak) / total : 0.0);
    if (closed) {
        const scene_light *l = s->lights;
        double ground = 0.8 * l->irradiance * l->direction[1] / 3.14159265358979;  /* rho E cos / pi */
        printf("         mean indirect inside / sunlit ground: none %.4f  ISM %.4f  exact %.4f\n",
               mean_lum(img[0], f.rc_count) / ground, mean_lum(img[1], f.rc_count) / ground,
               mean_lum(img[2], f.rc_count) / ground);
    } else {
        printf("         LightSkin image against exact visibility (rel MAE): none %.4f  ISM %.4f\n",
               rel_mae(img[0], img[2], (size_t)f.rc_count * 3), rel_mae(img[1], img[2], (size_t)f.rc_count * 3));
    }
    for (j = 0; j < 3; ++j) free(img[j]);
    free(pts); free(maps); free(vis_i); free(vis_e);
    frame_free(&f);
    soup_free(&sp);
    return 0;
}

int main(int argc, char **argv) {
    scene room, cornell;
    char err[256];
    uint32_t size = argc > 2 ? (uint32_t)atoi(argv[1]) : GIM_ISM_DEFAULT_SIZE;
    uint32_t per = argc > 2 ? (uint32_t)atoi(argv[2]) : GIM_ISM_DEFAULT_POINTS;
    int rc = 0;
    printf("imperfect shadow maps (CPU twins) against exact visibility; RSM %u^2 (FULL), %ux%u pixels\n", RSM, W, H);
    if (closed_room(&room) == 0) rc |= run("closed", &room, size, per, 1);
    else rc = 1;
    if (scene_builtin("cornell", &cornell, err, sizeof err) == 0) {
        cornell.camera.width = W; cornell.camera.height = H;
        rc |= run("cornell", &cornell, size, per, 0);
        scene_free(&cornell);
    } else {
        printf("cornell: %s (skipped)\n", err);
    }
    return rc;
}
