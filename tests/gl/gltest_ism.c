/* The GPU imperfect shadow maps (ism.comp, Ritschel et al. 2008) against gim_ism_render_twin, and
   the proxy-light pass with the maps' visibility per VAL against gim_proxy_lights_twin with
   gim_ism_visibility_twin's matrix; bad settings refused before any GL work; GL state restored. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

/* A quad at corner c spanned by u, v as two triangles. */
static uint32_t quad(float *pos, float *alb, uint32_t t, const float c[3], const float u[3], const float v[3]) {
    int k;
    for (k = 0; k < 3; ++k) {
        pos[t * 9 + k] = c[k]; pos[t * 9 + 3 + k] = c[k] + u[k]; pos[t * 9 + 6 + k] = c[k] + u[k] + v[k];
        pos[t * 9 + 9 + k] = c[k]; pos[t * 9 + 12 + k] = c[k] + u[k] + v[k]; pos[t * 9 + 15 + k] = c[k] + v[k];
    }
    for (k = 0; k < 6; ++k) alb[t * 3 + k] = 0.5f;
    return t + 2;
}

#define NC 40u
#define NV 256u
#define NP 8192u

/* Floor [0, 4]^2, a back wall at z = 0, a plate 1 x 1 at height 1.2 over the floor's middle;
   caches on the floor, the wall and the plate's underside, VALs on the floor and the wall. */
typedef struct ism_scene {
    float pos[6 * 9], alb[6 * 3];
    uint32_t tris;
    gim_cache caches[NC];
    gim_val vals[NV];
    float *points;
} ism_scene;

static void make_scene(ism_scene *s) {
    float c0[3] = {0, 0, 0}, u0[3] = {0, 0, 4}, v0[3] = {4, 0, 0};
    float c1[3] = {0, 0, 0}, u1[3] = {4, 0, 0}, v1[3] = {0, 3, 0};
    float c2[3] = {1.5f, 1.2f, 1.5f}, u2[3] = {0, 0, 1}, v2[3] = {1, 0, 0};
    gim_twin_scene ts;
    uint32_t i;
    memset(s, 0, sizeof *s);
    s->tris = quad(s->pos, s->alb, 0, c0, u0, v0);
    s->tris = quad(s->pos, s->alb, s->tris, c1, u1, v1);
    s->tris = quad(s->pos, s->alb, s->tris, c2, u2, v2);
    for (i = 0; i < NC; ++i) {
        gim_cache *c = s->caches + i;
        switch (i % 3) {
        case 0: c->position[0] = test_rnd(0.1f, 3.9f); c->position[2] = test_rnd(0.1f, 3.9f); c->normal[1] = 1.0f; break;
        case 1: c->position[0] = test_rnd(0.1f, 3.9f); c->position[1] = test_rnd(0.1f, 2.9f); c->normal[2] = 1.0f; break;
        default: c->position[0] = test_rnd(1.6f, 2.4f); c->position[1] = 1.2f; c->position[2] = test_rnd(1.6f, 2.4f); c->normal[1] = -1.0f; break;
        }
        c->area = 0.05f;
        c->reflectance = 0.5f;
    }
    for (i = 0; i < NV; ++i) {
        gim_val *v = s->vals + i;
        if (i % 2) { v->position[0] = test_rnd(0, 4); v->position[2] = test_rnd(0, 4); v->normal[1] = 1.0f; }
        else { v->position[0] = test_rnd(0, 4); v->position[1] = test_rnd(0, 3); v->normal[2] = 1.0f; }
        v->area = 0.05f;
        v->weight = 1.0f;
        v->flux[0] = test_rnd(0.1f, 1); v->flux[1] = test_rnd(0.1f, 1); v->flux[2] = test_rnd(0.1f, 1);
    }
    ts.positions = s->pos; ts.normals = NULL; ts.albedo = s->alb; ts.triangle_count = s->tris;
    s->points = (float *)malloc(NP * 8 * sizeof(float));
    assert_int_equal(gim_ism_points(&ts, NP, s->points), GIM_OK);
}

/* The GPU maps, 16 bits a texel two to a uint, decoded: bit for bit the twin's, but for at most
   0.5% of the texels (a point on a texel border that float rounding puts on the other side);
   and the storage is half of 32-bit floats' */
static void read_maps(GLuint b, size_t texels, float *out) { gltest_read_ism(b, texels, out); }

static void maps_match(void **state) {
    gltest_fixture f;
    ism_scene s;
    gim_ism_desc d;
    uint32_t sizes[3] = {8, 32, 64}, k;
    GLuint bc, bp, bm;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_scene(&s);
    bc = gltest_ssbo(sizeof s.caches, s.caches);
    bp = gltest_ssbo(NP * 32u, s.points);
    for (k = 0; k < 3; ++k) {
        uint32_t n = sizes[k], per = k == 1 ? 2048u : NP, q, off = 0, holes = 0;
        size_t texels = (size_t)NC * n * n;
        float *cpu = (float *)malloc(texels * 4), *gpu = (float *)malloc(texels * 4);
        memset(&d, 0, sizeof d);
        d.caches = s.caches; d.cache_count = NC; d.points = s.points; d.point_count = NP;
        d.size = n; d.points_per_map = per; d.scene_scale = 6.0f; d.env = f.env;
        assert_int_equal(gim_ism_render_twin(&d, cpu), GIM_OK);
        bm = gltest_ssbo(texels * 2, NULL);
        assert_int_equal(gim__gl_ism_render(f.ctx, bc, NC, bp, NP, n, per, 6.0f, bm), GIM_OK);
        gltest_state_unchanged(&f);
        read_maps(bm, texels, gpu);
        for (q = 0; q < texels; ++q) {
            assert_true(cpu[q] == gim_ism_dequantize(gim_ism_quantize(cpu[q])));   /* the twin's maps are 16-bit too */
            if (memcmp(gpu + q, cpu + q, 4) != 0) ++off;
            holes += cpu[q] >= GIM_PARABOLOID_EMPTY;
        }
        print_message("%u^2, %u points a map: %u of %zu texels differ, %u empty\n", n, per, off, texels, holes);
        assert_true(off <= texels / 200u);
        assert_true(holes < texels / 2u);   /* the maps hold the scene */
        glDeleteBuffers(1, &bm);
        free(cpu); free(gpu);
    }
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &bp);
    free(s.points);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* One map per VPL (the VPL methods' visibility): ism.comp reads its origins from a gim_vpl
   buffer (3 vec4 apart) as from the caches, with the VPLs' surfels (GIM_ISM_VPL_SPLAT); the maps
   are gim_ism_render_twin's on the VPLs taken as caches. */
static void maps_of_vpls_match(void **state) {
    gltest_fixture f;
    ism_scene s;
    gim_ism_desc d;
    gim_vpl vpls[NC];
    uint32_t n = 16, per = 1024, q, off = 0, i;
    size_t texels = (size_t)NC * n * n;
    float *cpu = (float *)malloc(texels * 4), *gpu = (float *)malloc(texels * 4);
    GLuint bv, bp, bm;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_scene(&s);
    memset(vpls, 0, sizeof vpls);
    for (i = 0; i < NC; ++i) {
        memcpy(vpls[i].position, s.caches[i].position, 12);
        memcpy(vpls[i].normal, s.caches[i].normal, 12);
        vpls[i].lit = 1.0f;
        vpls[i].flux[0] = vpls[i].flux[1] = vpls[i].flux[2] = 0.25f;
    }
    bv = gltest_ssbo(sizeof vpls, vpls);
    bp = gltest_ssbo(NP * 32u, s.points);
    bm = gltest_ssbo(texels * 4, NULL);
    memset(&d, 0, sizeof d);
    d.caches = s.caches; d.cache_count = NC; d.points = s.points; d.point_count = NP;
    d.size = n; d.points_per_map = per; d.splat = GIM_ISM_VPL_SPLAT; d.scene_scale = 6.0f; d.env = f.env;
    assert_int_equal(gim_ism_render_twin(&d, cpu), GIM_OK);
    gim__gl_enter(f.ctx, "test");
    assert_int_equal(gim__gl_ism_render_of(f.ctx, bv, 3u, 0u, 0u, NC, bp, NP, n, per, 6.0f, bm), GIM_OK);
    /* a buffer too small for NC VPLs of 48 bytes is refused, so is one too small for the maps
       from source_first on, and a maps buffer too small for map_first + NC maps */
    assert_int_equal(gim__gl_ism_render_of(f.ctx, bp, 3u, 0u, 0u, NP * 2u / 3u + 1u, bp, NP, n, per, 6.0f, bm),
                     GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render_of(f.ctx, bv, 3u, 1u, 0u, NC, bp, NP, n, per, 6.0f, bm), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render_of(f.ctx, bv, 3u, 0u, 1u, NC, bp, NP, n, per, 6.0f, bm), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
    f.log.errors = 0;
    read_maps(bm, texels, gpu);
    for (q = 0; q < texels; ++q) off += !(fabsf(gpu[q] - cpu[q]) <= 1e-4f * cpu[q]);
    print_message("%u VPLs' maps of %u^2: %u of %zu texels differ from the twin\n", NC, n, off, texels);
    assert_true(off <= texels / 200u);
    /* maps of the VPLs from the 3rd on (SSVP's second bounce: source_first), map m from VPL
       3 + m with map m's points, as the twin's on those VPLs taken as caches */
    d.caches = s.caches + 3; d.cache_count = NC - 3;
    assert_int_equal(gim_ism_render_twin(&d, cpu), GIM_OK);
    gim__gl_enter(f.ctx, "test");
    assert_int_equal(gim__gl_ism_render_of(f.ctx, bv, 3u, 3u, 0u, NC - 3u, bp, NP, n, per, 6.0f, bm), GIM_OK);
    assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
    read_maps(bm, (size_t)(NC - 3) * n * n, gpu);
    for (q = 0, off = 0; q < (NC - 3) * n * n; ++q) off += !(fabsf(gpu[q] - cpu[q]) <= 1e-4f * cpu[q]);
    print_message("maps from VPL 3 on: %u of %u texels differ from the twin\n", off, (NC - 3) * n * n);
    assert_true(off <= (NC - 3) * n * n / 200u);
    /* only maps k.. made (map_first, the VPL maps kept while nothing moves): the maps before k
       keep what the buffer held, the rest are the twin's maps k.. of all NC VPLs */
    {
        uint32_t k = gim__ism_align_maps(f.ctx, n) * 2u;
        uint32_t *fill = (uint32_t *)malloc(texels * 2u);
        assert_true(k < NC);
        memset(fill, 0x5a, texels * 2u);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, bm);
        glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, (GLsizeiptr)(texels * 2u), fill);
        d.caches = s.caches; d.cache_count = NC;
        assert_int_equal(gim_ism_render_twin(&d, cpu), GIM_OK);
        gim__gl_enter(f.ctx, "test");
        assert_int_equal(gim__gl_ism_render_of(f.ctx, bv, 3u, 0u, k, NC - k, bp, NP, n, per, 6.0f, bm), GIM_OK);
        assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, bm);
        glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, (GLsizeiptr)(k * n * n * 2u), fill);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
        for (q = 0, off = 0; q < k * n * n / 2u; ++q) off += fill[q] != 0x5a5a5a5au;
        assert_int_equal(off, 0);
        read_maps(bm, texels, gpu);
        for (q = k * n * n, off = 0; q < texels; ++q) off += !(fabsf(gpu[q] - cpu[q]) <= 1e-4f * cpu[q]);
        print_message("maps %u.. made alone: %u of %zu texels differ from the twin; the %u before untouched\n", k, off,
                      (size_t)(NC - k) * n * n, k);
        assert_true(off <= (NC - k) * n * n / 200u);
        free(fill);
    }
    gltest_state_unchanged(&f);
    glDeleteBuffers(1, &bv); glDeleteBuffers(1, &bp); glDeleteBuffers(1, &bm);
    free(cpu); free(gpu); free(s.points);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Proxy lights with the maps' visibility: the GPU pass against gim_proxy_lights_twin with the twin's
   lookups of the same (GPU) maps; flux within 2e-4 of the largest, positions within 1e-4 of the
   scene, for all but 1 cache of 40 (a lookup on a texel border); and the plate must shadow:
   caches whose light changes by over 10% against no visibility. */
static void proxy_with_ism(void **state) {
    gltest_fixture f;
    ism_scene s;
    gim_ism_desc d;
    gim_proxy_desc pd;
    gim_proxy_light cpu[NC], gpu[NC], none[NC];
    gim__gl_ism gi;
    float *maps, *vis, fmax = 0.0f;
    uint32_t i, bad = 0, shadowed = 0, n = 32;
    GLuint bc, bp, bm, bv, bd;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_scene(&s);
    bc = gltest_ssbo(sizeof s.caches, s.caches);
    bp = gltest_ssbo(NP * 32u, s.points);
    bv = gltest_ssbo(sizeof s.vals, s.vals);
    bd = gltest_ssbo(sizeof gpu, NULL);
    bm = gltest_ssbo((size_t)NC * n * n * 2, NULL);
    assert_int_equal(gim__gl_ism_render(f.ctx, bc, NC, bp, NP, n, NP, 6.0f, bm), GIM_OK);
    maps = (float *)malloc((size_t)NC * n * n * 4);
    vis = (float *)malloc((size_t)NC * NV * 4);
    read_maps(bm, (size_t)NC * n * n, maps);
    memset(&d, 0, sizeof d);
    d.caches = s.caches; d.cache_count = NC; d.size = n; d.scene_scale = 6.0f; d.env = f.env;
    assert_int_equal(gim_ism_visibility_twin(&d, maps, s.vals, NV, vis), GIM_OK);
    memset(&pd, 0, sizeof pd);
    pd.caches = s.caches; pd.cache_count = NC; pd.vals = s.vals; pd.val_count = NV; pd.scene_scale = 6.0f; pd.env = f.env;
    assert_int_equal(gim_proxy_lights_twin(&pd, none, NULL), GIM_OK);
    pd.visibility = vis;
    assert_int_equal(gim_proxy_lights_twin(&pd, cpu, NULL), GIM_OK);
    memset(&gi, 0, sizeof gi);
    gi.maps = bm; gi.size = n;
    assert_int_equal(gim__gl_proxy_lights_ism(f.ctx, bc, NC, bv, NV, gim_v3(0, 0, 0), 0.0f, 0u, 6.0f, bd, 0, &gi), GIM_OK);
    gltest_state_unchanged(&f);
    gltest_read_buffer(bd, sizeof gpu, gpu);
    for (i = 0; i < NC; ++i) fmax = fmaxf(fmax, cpu[i].flux[1]);
    for (i = 0; i < NC; ++i) {
        int a, ok = 1;
        for (a = 0; a < 3; ++a) {
            ok &= fabsf(gpu[i].flux[a] - cpu[i].flux[a]) <= 2e-4f * fmax;
            ok &= fabsf(gpu[i].position[a] - cpu[i].position[a]) <= 1e-4f * 6.0f;
        }
        bad += !ok;
        shadowed += fabsf(cpu[i].flux[1] - none[i].flux[1]) > 0.1f * none[i].flux[1];
    }
    print_message("%u of %u caches differ; %u shadowed by over 10%%\n", bad, NC, shadowed);
    assert_true(bad <= 1u);
    assert_true(shadowed >= 4u);
    glDeleteBuffers(1, &bc); glDeleteBuffers(1, &bp); glDeleteBuffers(1, &bv); glDeleteBuffers(1, &bd); glDeleteBuffers(1, &bm);
    free(maps); free(vis); free(s.points);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Bad settings: refused with a message and no GL call (no GL error, state untouched). */
static void bad_settings(void **state) {
    gltest_fixture f;
    GLuint b;
    gim__gl_ism gi;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    b = gltest_ssbo(4096, NULL);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1, b, 1, 0, 16, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1, b, 1, 128, 16, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1, b, 1, 24, 16, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1, b, 1, 16, 0, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 0, b, 1, 16, 16, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1, b, 1, 16, 16, 0.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_ism_render(f.ctx, b, 1u << 30, b, 1, 64, 16, 1.0f, b), GIM_ERROR_OUT_OF_RANGE);
    /* 64^2 maps of 9,000 caches fit a 128 MiB block at 16 bits a texel: refused here for the
       small buffer, not for the size */
    if (f.ctx->max_ssbo_bytes >= 134217728)
        assert_int_equal(gim__gl_ism_render(f.ctx, b, 9000, b, 1, 64, 16, 1.0f, b), GIM_ERROR_INVALID_ARGUMENT);
    memset(&gi, 0, sizeof gi);
    gi.maps = b; gi.size = 3;
    assert_int_equal(gim__gl_proxy_lights_ism(f.ctx, b, 1, b, 1, gim_v3(0, 0, 0), 0.0f, 0u, 1.0f, b, 0, &gi),
                     GIM_ERROR_INVALID_ARGUMENT);
    assert_true(f.log.errors >= 8);
    f.log.errors = 0;
    gltest_state_unchanged(&f);
    glDeleteBuffers(1, &b);
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(maps_match),
        cmocka_unit_test(maps_of_vpls_match),
        cmocka_unit_test(proxy_with_ism),
        cmocka_unit_test(bad_settings),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
