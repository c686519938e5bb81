/* Settings that used to give a black or saturated image with GIM_OK are refused or warned
   about, with the valid range in the message; a refused host G-buffer leaves no GL error for
   the host; LightSkin warns when most of the G-buffer shows the back of its surfaces. Built with NDEBUG: no GIMANY_DEBUG error checks clean up after a pass here. */
#ifndef NDEBUG
#define NDEBUG
#endif
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 16
#define H 16
#include "framefix.h"

static void begin(frame_fixture *ff) {
    assert_int_equal(frame_begin(ff, NULL, 16), 0);
    ff->fr.lightskin.view_sample_count = 16;
    ff->fr.lightskin.val_count = 64;
}

/* The result, one error logged with `text` in it (then forgotten, so frame_end passes). */
static void expect_error(frame_fixture *ff, gim_result got, gim_result want, const char *text) {
    assert_int_equal(got, want);
    assert_int_equal(ff->f.log.errors, 1);
    if (!strstr(ff->f.log.last, text)) fail_msg("'%s' not in '%s'", text, ff->f.log.last);
    ff->f.log.errors = 0;
}

static void timing_and_scale(void **state) {
    frame_fixture ff;
    gim_frame fr;
    (void)state;
    GLTEST_BEGIN();
    begin(&ff);
    fr = ff.fr;
    fr.timing = 7;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "0 (off), 1 (GL timestamps) or 2");
    fr.timing = -1;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "timing -1");
    fr.timing = 2;
    assert_int_equal(gim_update(ff.f.ctx, &fr), GIM_OK);
    fr = ff.fr;
    fr.lightskin.shade_block = 3;   /* 1 or 2 */
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "shade_block 3: 1 (per pixel) or 2");
    fr.lightskin.shade_block = 1;
    assert_int_equal(gim_update(ff.f.ctx, &fr), GIM_OK);
    fr = ff.fr;
    fr.vpl.second_bounce = (gim_second_bounce)3;   /* DEFAULT, RAYS or MAPS, refused in any method's frame */
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "vpl.second_bounce 3: DEFAULT, RAYS or MAPS");
    fr.vpl.second_bounce = (gim_second_bounce)-1;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "vpl.second_bounce -1");
    fr.vpl.second_bounce = GIM_SECOND_BOUNCE_MAPS;
    assert_int_equal(gim_update(ff.f.ctx, &fr), GIM_OK);
    fr = ff.fr;
    fr.scene_scale = 1e30f;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "valid within 0.001..1000 diagonals");
    fr.scene_scale = 1e-6f;   /* the box is about 1.7 across */
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE, "valid within");
    fr.scene_scale = 10.0f;
    assert_int_equal(gim_update(ff.f.ctx, &fr), GIM_OK);
    frame_end(&ff);
    GLTEST_END();
}

/* 1^2 and 3^2 RSMs stay accepted (the twins test them) with a warning; 16^2 has none. */
static void small_rsm_warns(void **state) {
    static const uint32_t sizes[3] = {1, 3, 16};
    frame_fixture ff;
    int k;
    (void)state;
    GLTEST_BEGIN();
    begin(&ff);
    for (k = 0; k < 3; ++k) {
        gim_light l = ff.g.lights[0];
        int w = ff.f.log.warnings;
        l.rsm_size = sizes[k];
        assert_int_equal(gim_set_lights(ff.f.ctx, &l, 1), GIM_OK);
        assert_int_equal(ff.f.log.warnings - w, sizes[k] < 16 ? 1 : 0);
        if (sizes[k] < 16) assert_non_null(strstr(ff.f.log.last, "good: 16..16384"));
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    }
    frame_end(&ff);
    GLTEST_END();
}

/* A material that reflects more than it receives (diffuse + glossy > 1 in a channel) is taken
   with one warning naming it; 1 exactly is fine. */
static void energy_gaining_material_warns(void **state) {
    frame_fixture ff;
    gim_material m[2];
    int w;
    (void)state;
    GLTEST_BEGIN();
    begin(&ff);
    memset(m, 0, sizeof m);
    m[0].diffuse[0] = m[0].diffuse[1] = m[0].diffuse[2] = 0.6f;
    m[0].glossy[0] = m[0].glossy[1] = m[0].glossy[2] = 0.4f;   /* sums to 1: fine */
    m[0].exponent = 10.0f;
    m[1] = m[0];
    w = ff.f.log.warnings;
    assert_int_equal(gim_set_materials(ff.f.ctx, m, 2), GIM_OK);
    assert_int_equal(ff.f.log.warnings - w, 0);
    m[1].glossy[2] = 0.5f;
    assert_int_equal(gim_set_materials(ff.f.ctx, m, 2), GIM_OK);
    assert_int_equal(ff.f.log.warnings - w, 1);
    assert_non_null(strstr(ff.f.log.last, "material 1"));
    frame_end(&ff);
    GLTEST_END();
}

/* A spot bright enough to saturate RGBA16F: the image does clamp at 65504 (measured here), a
   warning says so once, and RGBA32F holds the values. */
static void half_saturation_warns(void **state) {
    frame_fixture ff;
    gim_light l;
    gim_frame_outputs o;
    float img[W * H * 4];
    double peak16 = 0.0, peak32 = 0.0;
    int i, w;
    (void)state;
    GLTEST_BEGIN();
    begin(&ff);
    ff.fr.method = GIM_METHOD_RSM_GATHER;
    l = ff.g.lights[0];
    l.intensity *= 1e8f;
    assert_int_equal(gim_set_lights(ff.f.ctx, &l, 1), GIM_OK);
    ff.fr.indirect_float32 = 0;
    w = ff.f.log.warnings;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    assert_int_equal(ff.f.log.warnings - w, 1);
    assert_non_null(strstr(ff.f.log.last, "RGBA16F holds up to 65504"));
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);   /* once, not every frame */
    assert_int_equal(ff.f.log.warnings - w, 1);
    o = gim_outputs(ff.f.ctx);
    gltest_read_texture(o.indirect, GL_RGBA, img);
    for (i = 0; i < W * H * 4; ++i) if ((i & 3) != 3 && img[i] > peak16) peak16 = img[i];
    ff.fr.indirect_float32 = 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    assert_int_equal(ff.f.log.warnings - w, 1);
    o = gim_outputs(ff.f.ctx);
    gltest_read_texture(o.indirect, GL_RGBA, img);
    for (i = 0; i < W * H * 4; ++i) if ((i & 3) != 3 && img[i] > peak32) peak32 = img[i];
    print_message("peak indirect: RGBA16F %g, RGBA32F %g\n", peak16, peak32);
    assert_true(peak16 == 65504.0 && peak32 > 65504.0);
    frame_end(&ff);
    GLTEST_END();
}

static GLuint texture(GLenum target, GLenum format) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(target, t);
    if (target == GL_TEXTURE_2D_ARRAY) glTexStorage3D(target, 1, format, W, H, 2);
    else glTexStorage2D(target, 1, format, W, H);
    glBindTexture(target, 0);
    return t;
}

/* RGBA8 normals, a colour texture as depth, a 2D-array depth: refused by name, and no GL
   error left in the host's queue (the array texture's failed bind raises one inside). */
static void host_gbuffer_formats(void **state) {
    frame_fixture ff;
    gim_frame fr;
    GLuint depth, normal, rgba8, colour, array;
    (void)state;
    GLTEST_BEGIN();
    begin(&ff);
    depth = texture(GL_TEXTURE_2D, GL_DEPTH_COMPONENT32F);
    normal = texture(GL_TEXTURE_2D, GL_RGBA16F);
    rgba8 = texture(GL_TEXTURE_2D, GL_RGBA8);
    colour = texture(GL_TEXTURE_2D, GL_RGBA32F);
    array = texture(GL_TEXTURE_2D_ARRAY, GL_DEPTH_COMPONENT32F);
    fr = ff.fr;
    fr.gbuffer.depth = depth;
    fr.gbuffer.normal = rgba8;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "GIM_NORMAL_XYZ needs signed values");
    assert_int_equal(glGetError(), GL_NO_ERROR);
    fr.gbuffer.depth = colour;
    fr.gbuffer.normal = normal;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "must be a depth format");
    assert_int_equal(glGetError(), GL_NO_ERROR);
    fr.gbuffer.depth = array;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "is not a 2D texture");
    assert_int_equal(glGetError(), GL_NO_ERROR);
    fr.gbuffer.depth = depth;   /* the right formats pass */
    assert_int_equal(gim_update(ff.f.ctx, &fr), GIM_OK);
    /* texture state that texelFetch obeys: a swizzle, a base level, stencil reads */
    glBindTexture(GL_TEXTURE_2D, normal);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_SWIZZLE_G, GL_RED);
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "gbuffer_normal has a texture swizzle");
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_SWIZZLE_G, GL_GREEN);
    glDeleteTextures(1, &normal);   /* a base level needs a second level (immutable storage clamps it) */
    glGenTextures(1, &normal);
    glBindTexture(GL_TEXTURE_2D, normal);
    glTexStorage2D(GL_TEXTURE_2D, 2, GL_RGBA16F, 2 * W, 2 * H);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_BASE_LEVEL, 1);
    fr.gbuffer.normal = normal;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "GL_TEXTURE_BASE_LEVEL 1");
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_BASE_LEVEL, 0);
    glDeleteTextures(1, &depth);
    glGenTextures(1, &depth);
    glBindTexture(GL_TEXTURE_2D, depth);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_DEPTH24_STENCIL8, W, H);
    glTexParameteri(GL_TEXTURE_2D, GL_DEPTH_STENCIL_TEXTURE_MODE, GL_STENCIL_INDEX);
    glBindTexture(GL_TEXTURE_2D, 0);
    fr.gbuffer.depth = depth;
    expect_error(&ff, gim_update(ff.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT, "would read stencil");
    assert_int_equal(glGetError(), GL_NO_ERROR);
    glDeleteTextures(1, &depth);
    glDeleteTextures(1, &normal);
    glDeleteTextures(1, &rgba8);
    glDeleteTextures(1, &colour);
    glDeleteTextures(1, &array);
    frame_end(&ff);
    GLTEST_END();
}

/* The built-in Cornell box with every normal and winding flipped (a common export mistake):
   from inside, every surface shows its back. */
static void flipped_begin(frame_fixture *ff, int flipped, gim_method m) {
    char err[256];
    uint32_t k, i;
    memset(ff, 0, sizeof *ff);
    assert_int_equal(scene_builtin("cornell", &ff->s, err, sizeof err), 0);
    for (k = 0; k < ff->s.mesh_count && flipped; ++k) {
        scene_mesh *me = &ff->s.meshes[k];
        for (i = 0; i < me->vertex_count * 3; ++i) me->normals[i] = -me->normals[i];
        for (i = 0; i < me->triangle_count; ++i) {
            uint32_t t = me->indices[3 * i + 1];
            me->indices[3 * i + 1] = me->indices[3 * i + 2];
            me->indices[3 * i + 2] = t;
        }
    }
    ff->s.camera.width = W;
    ff->s.camera.height = H;
    gltest_fixture_begin(&ff->f);
    assert_int_equal(scene_gimany_load(ff->f.ctx, &ff->s, 1.0f / 24.0f, 16, ff->f.env, &ff->g), GIM_OK);
    scene_gimany_camera(&ff->s, &ff->fr.view, &ff->fr.proj);
    ff->fr.width = W;
    ff->fr.height = H;
    ff->fr.indirect_float32 = 1;
    ff->fr.method = m;
    ff->fr.lightskin.view_sample_count = 16;
    ff->fr.lightskin.val_count = 64;
    ff->fr.vpl.count = 64;
    ff->fr.vpl.cluster_count = 4;
    ff->fr.vpl.paraboloid_size = 16;
    ff->fr.vpl.interleave = 2;
    ff->fr.vpl.kmeans_restart = 1;
}

/* Two frames: the image's mean and the warnings of both (the count is read once its frame is done). */
static double flipped_frames(frame_fixture *ff, int *warnings, char *last) {
    gim_frame_outputs o;
    float img[W * H * 4];
    double sum = 0.0;
    int i, w = ff->f.log.warnings;
    assert_int_equal(gim_update(ff->f.ctx, &ff->fr), GIM_OK);
    glFinish();   /* the counted frame's fence has passed: the next frame reads the count */
    assert_int_equal(gim_update(ff->f.ctx, &ff->fr), GIM_OK);
    *warnings = ff->f.log.warnings - w;
    strcpy(last, ff->f.log.last);
    o = gim_outputs(ff->f.ctx);
    gltest_read_texture(o.indirect, GL_RGBA, img);
    for (i = 0; i < W * H * 4; ++i) if ((i & 3) != 3) sum += img[i];
    return sum / (W * H);
}

/* LightSkin's caches receive on their normal's side only: with every normal flipped it goes
   nearly black (measured below) while the two-sided methods give the same mean within 1%; LightSkin
   warns with the count, and says nothing on the correct box or for the other methods. */
static void flipped_normals_warn(void **state) {
    static const gim_method methods[] = {GIM_METHOD_LIGHTSKIN_BRSM, GIM_METHOD_LIGHTSKIN_FULL, GIM_METHOD_RSM_GATHER,
                                         GIM_METHOD_CLUSTERED};
    frame_fixture ff;
    char last[512];
    int k, w0, w1;
    (void)state;
    GLTEST_BEGIN();
    for (k = 0; k < 4; ++k) {
        double m0, m1;
        int ls = k < 2;
        flipped_begin(&ff, 0, methods[k]);
        m0 = flipped_frames(&ff, &w0, last);
        frame_end(&ff);
        flipped_begin(&ff, 1, methods[k]);
        m1 = flipped_frames(&ff, &w1, last);
        print_message("method %d: mean %g, flipped %g (%.1f%%); warnings %d, flipped %d\n", (int)methods[k], m0, m1,
                      100.0 * m1 / m0, w0, w1);
        assert_int_equal(w0, 0);
        if (ls) {
            assert_true(m1 < 0.1 * m0);   /* the failure the warning names */
            assert_int_equal(w1, 1);
            assert_non_null(strstr(last, "G-buffer fragments show the back of their surface"));
        } else {
            assert_true(fabs(m1 - m0) < 1e-2 * m0);   /* the flipped winding rasterises slightly differently */
            assert_int_equal(w1, 0);
        }
        frame_end(&ff);
    }
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(timing_and_scale), cmocka_unit_test(small_rsm_warns),
                                       cmocka_unit_test(half_saturation_warns), cmocka_unit_test(host_gbuffer_formats),
                                       cmocka_unit_test(flipped_normals_warn), cmocka_unit_test(energy_gaining_material_warns)};
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
