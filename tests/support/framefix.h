/* The whole-frame fixture of the GL frame tests: a scene (a glTF file, or the built-in Cornell
   box) loaded into a context through the examples' scene layer, its camera, the indirect image,
   the G-buffer's pixels as gim_receivers for the CPU twins, and image comparisons. The test
   defines W and H (the frame's size) before including it. */
#ifndef GIMANY_TESTS_FRAMEFIX_H
#define GIMANY_TESTS_FRAMEFIX_H
#include "gltest.h"
#include "scene_gimany.h"

#if defined(__GNUC__) || defined(__clang__)
#define FRAMEFIX_UNUSED __attribute__((unused))   /* each test uses some of them */
#else
#define FRAMEFIX_UNUSED
#endif

typedef struct frame_fixture {
    gltest_fixture f;
    scene s;
    scene_gimany g;
    gim_frame fr;
} frame_fixture;

/* 0: loaded; 1: the file is absent (skip) */
static FRAMEFIX_UNUSED int frame_begin(frame_fixture *ff, const char *gltf, uint32_t rsm_size) {
    char err[256];
    memset(ff, 0, sizeof *ff);
    if (gltf) {
        FILE *fp = fopen(gltf, "rb");
        if (!fp) return 1;
        fclose(fp);
        assert_int_equal(scene_load_gltf(gltf, &ff->s, err, sizeof err), 0);
    } else {
        assert_int_equal(scene_builtin("cornell", &ff->s, err, sizeof err), 0);
    }
    ff->s.camera.width = W;
    ff->s.camera.height = H;
    gltest_fixture_begin(&ff->f);
    assert_int_equal(scene_gimany_load(ff->f.ctx, &ff->s, 1.0f / 24.0f, rsm_size, ff->f.env, &ff->g), GIM_OK);
    assert_true(ff->g.light_count >= 1 && ff->g.lights[0].type == GIM_LIGHT_SPOT);
    memset(&ff->fr, 0, sizeof ff->fr);
    scene_gimany_camera(&ff->s, &ff->fr.view, &ff->fr.proj);
    ff->fr.width = W;
    ff->fr.height = H;
    ff->fr.lightskin.view_sample_count = 128;
    ff->fr.indirect_float32 = 1;   /* RGBA16F rounds to 2^-11: compared once, in its own case */
    return 0;
}

/* Method m at sizes small enough for llvmpipe (every method's pass runs, little work each). */
static FRAMEFIX_UNUSED void frame_small(frame_fixture *ff, gim_method m) {
    ff->fr.method = m;
    ff->fr.lightskin.view_sample_count = 16;
    ff->fr.lightskin.val_count = 64;
    ff->fr.gather.samples = 16;
    ff->fr.vpl.count = 64;
    ff->fr.vpl.cluster_count = 4;
    ff->fr.vpl.paraboloid_size = 16;
    ff->fr.vpl.second_bounce_vpls = 16;
    ff->fr.vpl.interleave = 2;
}

static FRAMEFIX_UNUSED void frame_end(frame_fixture *ff) {
    scene_gimany_free(ff->f.ctx, &ff->g);
    scene_free(&ff->s);
    gltest_fixture_end(&ff->f);
}

static FRAMEFIX_UNUSED void read_indirect(const gim_frame_outputs *o, float *rgba) {
    int i;
    assert_true(o->indirect != 0);
    gltest_read_texture(o->indirect, GL_RGBA, rgba);
    for (i = 0; i < W * H * 4; ++i) assert_true(isfinite(rgba[i]) && rgba[i] >= 0.0f);
}

/* The frame's pixels with a surface as gim_receivers (unprojected from its G-buffer, albedo and
   material from it, the view towards the eye): rec[nrec], map[k] = its pixel. */
static FRAMEFIX_UNUSED uint32_t frame_receivers(frame_fixture *ff, gim_receiver *rec, uint32_t *map, gim_vec3 *eye_out) {
    gim_frame_outputs o = gim_outputs(ff->f.ctx);
    float *depth = (float *)malloc(W * H * 4), *nrm = (float *)malloc(W * H * 16), *alb = (float *)malloc(W * H * 16),
          *mat = (float *)malloc(W * H * 4);
    gim_view_sample *vs = (gim_view_sample *)malloc(W * H * sizeof *vs);
    uint32_t *pix = (uint32_t *)malloc(W * H * 8), i, nrec = 0;
    gim_mat4 inv;
    gim_vec3 eye;
    gim_camera cam;
    gltest_read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, depth);
    gltest_read_texture(o.gbuffer_normal, GL_RGBA, nrm);
    gltest_read_texture(o.gbuffer_albedo, GL_RGBA, alb);
    gltest_read_texture(o.gbuffer_material, GL_RED, mat);
    assert_true(gim_mat4_invert(ff->fr.view, &inv));
    eye = gim_v3(inv.m[12], inv.m[13], inv.m[14]);
    for (i = 0; i < W * H; ++i) { pix[i * 2] = i % W; pix[i * 2 + 1] = i / W; }
    cam.view = ff->fr.view; cam.proj = ff->fr.proj; cam.width = W; cam.height = H;
    assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, pix, W * H, vs), GIM_OK);
    for (i = 0; i < W * H; ++i) {
        gim_receiver *rc = rec + nrec;
        double v[3], l;
        const scene_material *m;
        int a;
        if (vs[i].normal.x == 0.0f && vs[i].normal.y == 0.0f && vs[i].normal.z == 0.0f) continue;
        memset(rc, 0, sizeof *rc);
        rc->position[0] = vs[i].position.x; rc->position[1] = vs[i].position.y; rc->position[2] = vs[i].position.z;
        rc->normal[0] = vs[i].normal.x; rc->normal[1] = vs[i].normal.y; rc->normal[2] = vs[i].normal.z;
        v[0] = (double)eye.x - rc->position[0]; v[1] = (double)eye.y - rc->position[1]; v[2] = (double)eye.z - rc->position[2];
        l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (a = 0; a < 3; ++a) rc->view[a] = (float)(v[a] / l);
        memcpy(rc->albedo, alb + i * 4, 12);
        m = &ff->s.materials[(int)mat[i]];
        memcpy(rc->glossy, m->glossy, 12);
        rc->exponent = m->exponent;
        map[nrec++] = i;
    }
    free(depth); free(nrm); free(alb); free(mat); free(vs); free(pix);
    *eye_out = eye;
    return nrec;
}

/* Largest relative difference of gpu (RGBA pixels) against cpu (rgb per receiver), floored at
   1e-3 of cpu's largest value, and how many receivers exceed tol. */
/* Whose light each receiver takes in the frame's shading blocks (gim_shade_sources), for
   gim_lightskin_desc.source. */
static FRAMEFIX_UNUSED void frame_sources(frame_fixture *ff, const gim_receiver *rec, const uint32_t *map, uint32_t nrec,
                                          uint32_t *source) {
    gim_debug_outputs od = gim_debug(ff->f.ctx);
    uint32_t *pix = (uint32_t *)malloc((size_t)nrec * 8 + 8), i;
    gim_shade_blocks_desc bd;
    for (i = 0; i < nrec; ++i) { pix[i * 2] = map[i] % W; pix[i * 2 + 1] = map[i] / W; }
    memset(&bd, 0, sizeof bd);
    bd.receivers = rec; bd.receiver_count = nrec; bd.pixels = pix;
    bd.width = W; bd.height = H; bd.block = od.shade_block; bd.cell = od.neighbour_cell;
    bd.env = ff->f.env;
    assert_true(od.shade_block == 1u || od.shade_block == 2u);
    assert_int_equal(gim_shade_sources(&bd, source), GIM_OK);
    free(pix);
}

static FRAMEFIX_UNUSED uint32_t compare_pixels(const float *gpu, const float *cpu, const uint32_t *map, uint32_t nrec, double tol,
                               double *max_rel) {
    double ref_max = 0.0;
    uint32_t i, bad = 0;
    for (i = 0; i < nrec * 3; ++i) if (cpu[i] > ref_max) ref_max = cpu[i];
    assert_true(ref_max > 0.0);
    *max_rel = 0.0;
    for (i = 0; i < nrec; ++i) {
        int a;
        double e = 0.0;
        for (a = 0; a < 3; ++a) {
            double ref = cpu[i * 3 + a], den = ref > 1e-3 * ref_max ? ref : 1e-3 * ref_max;
            double rel = fabs((double)gpu[map[i] * 4 + a] - ref) / den;
            if (rel > e) e = rel;
        }
        if (e > tol) bad++;
        else if (e > *max_rel) *max_rel = e;
    }
    return bad;
}

/* Mean |a - b| / mean b over the pixels with a surface. */
static FRAMEFIX_UNUSED double mean_rel_diff(const float *a, const float *b) {
    double d = 0.0, m = 0.0;
    int i, c;
    for (i = 0; i < W * H; ++i) {
        if (b[i * 4 + 3] != 1.0f) continue;
        for (c = 0; c < 3; ++c) { d += fabs((double)a[i * 4 + c] - b[i * 4 + c]); m += b[i * 4 + c]; }
    }
    assert_true(m > 0.0);
    return d / m;
}

#endif
