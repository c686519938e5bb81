/* The host's G-buffer in the encodings engines keep (gim_frame.gbuffer.normal_encoding,
   gbuffer_view_space, gbuffer_depth_view_z): normals as unorm xyz (GL_RGB10_A2), octahedral in
   GL_RG16_SNORM and GL_RG16, in view space; depth as the view-space distance in GL_R32F. Each
   gives the image of the float world-normal G-buffer within its quantisation; the decode pass
   equals its twin (gim_gbuffer_decode_twin); the default layout runs no decode pass and keeps
   no decode textures; a format that does not fit the encoding is refused with one message. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "room.h"

enum { W = 40, H = 30 };

typedef struct fx {
    gltest_fixture f;
    room r;
    gim_cache_set set;
    gim_mesh mesh;
    gim_frame fr;
    float depth[W * H], normal[W * H * 4];   /* gimany's own G-buffer of the view */
} fx;

static void setup(fx *x) {
    gim_cache_desc cd;
    gim_mesh_desc md;
    gim_instance in;
    gim_light sun;
    gim_frame_outputs o;
    memset(x, 0, sizeof *x);
    gltest_fixture_begin(&x->f);
    room_open_box(&x->r);
    memset(&cd, 0, sizeof cd);
    cd.mesh = room_arrays(&x->r);
    cd.d_eps = 0.5f;
    assert_int_equal(gim_cache_generate(&cd, &x->set), GIM_OK);
    memset(&md, 0, sizeof md);
    md.data = room_arrays(&x->r);
    md.caches = &x->set;
    assert_int_equal(gim_add_mesh(x->f.ctx, &md, &x->mesh), GIM_OK);
    assert_int_equal(gim_set_materials(x->f.ctx, room_materials, 4), GIM_OK);
    in.mesh = x->mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(x->f.ctx, &in, 1), GIM_OK);
    sun = room_sun();
    assert_int_equal(gim_set_lights(x->f.ctx, &sun, 1), GIM_OK);
    memset(&x->fr, 0, sizeof x->fr);
    x->fr.view = gim_mat4_look_at(gim_v3(0.5f, 1.2f, 3.5f), gim_v3(-0.3f, 0.8f, -2.0f), gim_v3(0, 1, 0));
    x->fr.proj = gim_mat4_perspective(1.2f, (float)W / H, 0.05f, 50.0f);
    x->fr.width = W;
    x->fr.height = H;
    x->fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    assert_int_equal(gim_update(x->f.ctx, &x->fr), GIM_OK);   /* gimany's own G-buffer, read as the host's */
    o = gim_outputs(x->f.ctx);
    gltest_read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, x->depth);
    gltest_read_texture(o.gbuffer_normal, GL_RGBA, x->normal);
}

static void teardown(fx *x) {
    gim_cache_set_free(&x->set);
    gltest_fixture_end(&x->f);
}

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static GLuint texture(GLenum internal, GLenum format, const float *data) {
    GLuint t;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, internal, W, H);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, W, H, format, GL_FLOAT, data);
    glBindTexture(GL_TEXTURE_2D, 0);
    return t;
}

/* n (unit) on the octahedron, folded into [-1, 1]^2 (Cigolle et al. 2014) */
static void oct_encode(const float *n, float *e) {
    float s = fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2]), x = n[0] / s, y = n[1] / s;
    if (n[2] < 0.0f) {
        float ox = (1.0f - fabsf(y)) * (x >= 0.0f ? 1.0f : -1.0f), oy = (1.0f - fabsf(x)) * (y >= 0.0f ? 1.0f : -1.0f);
        x = ox;
        y = oy;
    }
    e[0] = x;
    e[1] = y;
}

typedef struct variant {
    const char *name;
    gim_normal_encoding encoding;
    GLenum internal, format;
    int view_space, view_z;
    double median_tol, max_tol;   /* of the indirect image against the float G-buffer's */
} variant;

/* The host's normal texture data of variant v (rgba floats as uploaded) and its depth. */
static void encode(const fx *x, const variant *v, float *nrm, float *dep) {
    int i, k;
    for (i = 0; i < W * H; ++i) {
        float n[3], e[2];
        memcpy(n, x->normal + i * 4, sizeof n);
        if (v->view_space) {   /* world to view: view's 3x3 */
            float w[3];
            for (k = 0; k < 3; ++k) w[k] = x->fr.view.m[k] * n[0] + x->fr.view.m[4 + k] * n[1] + x->fr.view.m[8 + k] * n[2];
            memcpy(n, w, sizeof n);
        }
        for (k = 0; k < 4; ++k) nrm[i * 4 + k] = 0.0f;
        if (v->encoding == GIM_NORMAL_XYZ) memcpy(nrm + i * 4, n, sizeof n);
        if (v->encoding == GIM_NORMAL_XYZ_UNORM)
            for (k = 0; k < 3; ++k) nrm[i * 4 + k] = n[k] * 0.5f + 0.5f;
        if (v->encoding == GIM_NORMAL_OCTAHEDRAL || v->encoding == GIM_NORMAL_OCTAHEDRAL_UNORM) {
            if (n[0] != 0.0f || n[1] != 0.0f || n[2] != 0.0f) oct_encode(n, e);
            else e[0] = e[1] = 0.0f;
            for (k = 0; k < 2; ++k) nrm[i * 4 + k] = v->encoding == GIM_NORMAL_OCTAHEDRAL_UNORM ? e[k] * 0.5f + 0.5f : e[k];
        }
        dep[i] = x->depth[i];
        if (v->view_z) {   /* window depth to the distance along -z; nothing drawn: 0 */
            gim_mat4 inv;
            gim_vec3 p;
            float ndc = x->depth[i] * 2.0f - 1.0f;
            assert_true(gim_mat4_invert(x->fr.proj, &inv));
            p = gim_mat4_point(inv, gim_v3(0.0f, 0.0f, ndc));
            dep[i] = x->depth[i] < 1.0f ? -p.z : 0.0f;
        }
    }
}

/* Renders with the host's G-buffer (depth, normal, settings of v) into img. */
static void render(fx *x, GLuint depth, GLuint normal, const variant *v, float *img) {
    gim_frame f = x->fr;
    f.gbuffer.depth = depth;
    f.gbuffer.normal = normal;
    f.gbuffer.normal_encoding = v ? v->encoding : GIM_NORMAL_XYZ;
    f.gbuffer.view_space = v ? v->view_space : 0;
    f.gbuffer.depth_view_z = v ? v->view_z : 0;
    assert_int_equal(gim_update(x->f.ctx, &f), GIM_OK);
    gltest_read_texture(gim_outputs(x->f.ctx).indirect, GL_RGBA, img);
}

static const variant variants[] = {
    {"xyz unorm, GL_RGB10_A2", GIM_NORMAL_XYZ_UNORM, GL_RGB10_A2, GL_RGBA, 0, 0, 2e-3, 2e-2},
    {"octahedral, GL_RG16_SNORM", GIM_NORMAL_OCTAHEDRAL, GL_RG16_SNORM, GL_RG, 0, 0, 1e-3, 2e-2},
    {"octahedral unorm, GL_RG16", GIM_NORMAL_OCTAHEDRAL_UNORM, GL_RG16, GL_RG, 0, 0, 1e-3, 2e-2},
    {"view-space xyz, GL_RGBA16F", GIM_NORMAL_XYZ, GL_RGBA16F, GL_RGBA, 1, 0, 2e-3, 2e-2},
    {"octahedral + view z in GL_R32F", GIM_NORMAL_OCTAHEDRAL, GL_RG16_SNORM, GL_RG, 0, 1, 1e-3, 2e-2},
};

static void encodings_match_float(void **state) {
    fx *x = (fx *)calloc(1, sizeof *x);
    float *ref = (float *)malloc(W * H * 16), *img = (float *)malloc(W * H * 16), *nrm = (float *)malloc(W * H * 16);
    float dep[W * H];
    GLuint d0, n0;
    size_t vi;
    (void)state;
    GLTEST_BEGIN();
    setup(x);
    d0 = texture(GL_DEPTH_COMPONENT32F, GL_DEPTH_COMPONENT, x->depth);
    n0 = texture(GL_RGBA16F, GL_RGBA, x->normal);
    render(x, d0, n0, NULL, ref);
    assert_int_equal(x->f.ctx->decoded_normal, 0);   /* gimany's own layout: no decode pass, no textures */
    assert_int_equal(x->f.ctx->programs[GIM__PROGRAM_GBUFFER_DECODE], 0);
    for (vi = 0; vi < sizeof variants / sizeof variants[0]; ++vi) {
        const variant *v = &variants[vi];
        double rel[W * H], top = 0.0, med;
        float host_n[W * H * 4], dec_n[W * H * 4], dec_d[W * H];
        GLuint d, n;
        int i, lit = 0, twin_bad = 0;
        gim_decode_desc dd;
        encode(x, v, nrm, dep);
        d = v->view_z ? texture(GL_R32F, GL_RED, dep) : d0;
        if (v->format == GL_RG) {   /* two floats a texel as uploaded */
            for (i = 0; i < W * H; ++i) { nrm[i * 2] = nrm[i * 4]; nrm[i * 2 + 1] = nrm[i * 4 + 1]; }
        }
        n = texture(v->internal, v->format, nrm);
        render(x, d, n, v, img);
        for (i = 0; i < W * H; ++i) {
            double a = ref[i * 4] + ref[i * 4 + 1] + ref[i * 4 + 2], b = img[i * 4] + img[i * 4 + 1] + img[i * 4 + 2];
            if (a > 1e-6) rel[lit++] = fabs(b - a) / a;
            else assert_true(b <= 1e-6);
        }
        qsort(rel, (size_t)lit, sizeof rel[0], cmp_d);
        med = rel[lit / 2];
        for (i = 0; i < lit; ++i) top = rel[i] > top ? rel[i] : top;
        /* the decode pass against its twin, fed what the GPU read from the host's textures */
        gltest_read_texture(n, GL_RGBA, host_n);
        if (v->format == GL_RG)
            for (i = 0; i < W * H; ++i) host_n[i * 4 + 2] = host_n[i * 4 + 3] = 0.0f;
        gltest_read_texture(gim_outputs(x->f.ctx).gbuffer_normal, GL_RGBA, dec_n);
        gltest_read_texture(gim_outputs(x->f.ctx).gbuffer_depth, GL_RED, dec_d);
        memset(&dd, 0, sizeof dd);
        dd.encoding = v->encoding; dd.view_space = v->view_space; dd.depth_view_z = v->view_z;
        dd.view = x->fr.view; dd.proj = x->fr.proj;
        for (i = 0; i < W * H; ++i) {
            float tn[4], td;
            int k;
            assert_int_equal(gim_gbuffer_decode_twin(&dd, host_n + i * 4, v->view_z ? dep[i] : x->depth[i], tn, &td), GIM_OK);
            for (k = 0; k < 4; ++k) twin_bad += fabsf(tn[k] - dec_n[i * 4 + k]) > 1e-3f;
            twin_bad += fabsf(td - dec_d[i]) > 1e-6f;
        }
        {
            float tn[4], td;
            assert_int_equal(gim_gbuffer_decode_twin(NULL, host_n, 0.5f, tn, &td), GIM_ERROR_INVALID_ARGUMENT);
        }
        print_message("%-32s median %.2e, max %.2e relative to the float G-buffer's image (%d lit pixels); "
                      "decode vs twin: %d values off\n", v->name, med, top, lit, twin_bad);
        assert_true(lit > W * H / 2);
        assert_true(med <= v->median_tol && top <= v->max_tol);
        assert_int_equal(twin_bad, 0);
        if (d != d0) glDeleteTextures(1, &d);
        glDeleteTextures(1, &n);
    }
    glDeleteTextures(1, &d0);
    glDeleteTextures(1, &n0);
    gltest_state_unchanged(&x->f);
    teardown(x);
    free(ref); free(img); free(nrm); free(x);
    GLTEST_END();
}

/* Formats that do not hold the encoding, an unknown encoding, and encodings without a host
   G-buffer are refused before any pass, with one message each and no GL error. */
static void refused(void **state) {
    fx *x = (fx *)calloc(1, sizeof *x);
    float zero[W * H * 4];
    GLuint d, rg16, r32;
    gim_frame f;
    int errors = 0;
    (void)state;
    GLTEST_BEGIN();
    setup(x);
    memset(zero, 0, sizeof zero);
    d = texture(GL_DEPTH_COMPONENT32F, GL_DEPTH_COMPONENT, x->depth);
    rg16 = texture(GL_RG16, GL_RG, zero);
    r32 = texture(GL_R32F, GL_RED, zero);
#define EXPECT(call, code) do { assert_int_equal((call), (code)); assert_int_equal(x->f.log.errors, ++errors); \
        assert_int_equal(glGetError(), GL_NO_ERROR); } while (0)
    f = x->fr;
    f.gbuffer.depth = d;
    f.gbuffer.normal = rg16;                         /* unorm RG as signed xyz */
    EXPECT(gim_update(x->f.ctx, &f), GIM_ERROR_INVALID_ARGUMENT);
    f.gbuffer.normal_encoding = (gim_normal_encoding)7;
    EXPECT(gim_update(x->f.ctx, &f), GIM_ERROR_INVALID_ARGUMENT);
    f.gbuffer.normal_encoding = GIM_NORMAL_OCTAHEDRAL_UNORM;
    f.gbuffer.depth_view_z = 1;                      /* a depth texture as view z */
    EXPECT(gim_update(x->f.ctx, &f), GIM_ERROR_INVALID_ARGUMENT);
    f.gbuffer.depth = r32;
    f.gbuffer.depth_view_z = 0;                      /* R32F as window depth */
    EXPECT(gim_update(x->f.ctx, &f), GIM_ERROR_INVALID_ARGUMENT);
    f = x->fr;
    f.gbuffer.view_space = 1;                        /* no host G-buffer */
    EXPECT(gim_update(x->f.ctx, &f), GIM_ERROR_INVALID_ARGUMENT);
#undef EXPECT
    x->f.log.errors = 0;
    glDeleteTextures(1, &d);
    glDeleteTextures(1, &rg16);
    glDeleteTextures(1, &r32);
    gltest_state_unchanged(&x->f);
    teardown(x);
    free(x);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(encodings_match_float),
        cmocka_unit_test(refused),
    };
    int r;
    (void)room_receiver;
    r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
