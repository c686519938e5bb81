/* The GL runtime: create/destroy, bad descriptors, missing functions, old contexts, shader
   failures reaching the logger, and the GL state left exactly as the host set it. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

/* --- fake loaders: the real one, with one function withheld or wrapped --------------------- */
static const char *withheld_name;
static gim_gl_proc withholding_get_proc(const char *name) {
    if (withheld_name && strcmp(name, withheld_name) == 0) return NULL;
    return gltest_get_proc(name);
}

static void APIENTRY get_integerv_reporting_3_3(GLenum pname, GLint *data) {
    if (pname == GL_MAJOR_VERSION) { *data = 3; return; }
    if (pname == GL_MINOR_VERSION) { *data = 3; return; }
    glGetIntegerv(pname, data);
}
static gim_gl_proc gl33_get_proc(const char *name) {
    if (strcmp(name, "glGetIntegerv") == 0) return (gim_gl_proc)get_integerv_reporting_3_3;
    return gltest_get_proc(name);
}

static gim_desc make_desc(test_alloc_stats *stats, test_log *log) {
    gim_desc d;
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env = test_env(stats, log);
    return d;
}

/* The harness sees a GL error (so GLTEST_END can fail), and under GIMANY_DEBUG gimany's
   check turns one into GIM_ERROR_GL while a host's pending error is only a warning. */
static void errors_are_seen(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    (void)state;
    GLTEST_BEGIN();
    gltest.quiet = 1;
    glBindBuffer(0x1234, 0); /* GL_INVALID_ENUM */
    assert_int_equal(gltest.gl_errors, 1);
    gltest_reset_errors();
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
#ifdef GIMANY_DEBUG
    glBindBuffer(0x1234, 0);           /* left pending by the host */
    gim__gl_enter(ctx, "test");
    assert_int_equal(log.warnings, 1);
    assert_int_equal(gim__gl_check(ctx, "test pass"), GIM_OK);
    glBindBuffer(0x1234, 0);           /* raised inside the call */
    assert_int_equal(gim__gl_check(ctx, "test pass"), GIM_ERROR_GL);
    assert_non_null(strstr(log.last, "test pass"));
    assert_non_null(strstr(log.last, "0x0500"));
    gim__gl_leave(ctx, GIM_OK);
    assert_int_equal(gltest.gl_errors, 2);
    gltest_reset_errors();
#endif
    gltest.quiet = 0;
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    GLTEST_END();
}

static void create_destroy(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    (void)state;
    GLTEST_BEGIN();
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    assert_non_null(ctx);
    assert_int_equal(log.errors, 0);
    assert_true(log.infos >= 1); /* renderer and version at info level */
    assert_non_null(strstr(log.last, "renderer"));
    assert_true(stats.live >= 1);
    gim_destroy(ctx);
    gim_destroy(NULL);
    assert_int_equal(stats.live, 0);
    /* out of memory: nothing leaks, out untouched */
    d = make_desc(&stats, &log);
    stats.fail_after = 0;
    ctx = (gim_context *)&stats;
    assert_int_equal(gim_create(&d, &ctx), GIM_ERROR_OUT_OF_MEMORY);
    assert_ptr_equal(ctx, (gim_context *)&stats);
    assert_int_equal(log.errors, 1);
    assert_int_equal(stats.live, 0);
    GLTEST_END();
}

static void invalid_desc(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    (void)state;
    GLTEST_BEGIN();
    assert_int_equal(gim_create(NULL, &ctx), GIM_ERROR_INVALID_ARGUMENT);
    assert_null(ctx);
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(log.errors, 1);
    d = make_desc(&stats, &log);
    d.get_proc_address = NULL;
    assert_int_equal(gim_create(&d, &ctx), GIM_ERROR_INVALID_ARGUMENT);
    assert_null(ctx);
    assert_int_equal(log.errors, 1);
    assert_non_null(strstr(log.last, "get_proc_address"));
    assert_int_equal(stats.allocs, 0);
    GLTEST_END();
}

/* Each withheld function is named in the log and makes gim_create UNSUPPORTED. */
static void missing_function(void **state) {
    static const char *names[] = {"glDispatchCompute", "glBindImageTexture", "glGetError", "glMemoryBarrier"};
    size_t i;
    (void)state;
    GLTEST_BEGIN();
    for (i = 0; i < sizeof names / sizeof names[0]; ++i) {
        test_alloc_stats stats;
        test_log log;
        gim_desc d = make_desc(&stats, &log);
        gim_context *ctx = NULL;
        d.get_proc_address = withholding_get_proc;
        withheld_name = names[i];
        assert_int_equal(gim_create(&d, &ctx), GIM_ERROR_UNSUPPORTED);
        withheld_name = NULL;
        assert_null(ctx);
        assert_int_equal(log.errors, 2); /* the function by name, then the summary naming it */
        assert_non_null(strstr(log.last, names[i]));
        assert_int_equal(stats.live, 0);
    }
    GLTEST_END();
}

static void old_context(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    (void)state;
    GLTEST_BEGIN();
    d = make_desc(&stats, &log);
    d.get_proc_address = gl33_get_proc;
    assert_int_equal(gim_create(&d, &ctx), GIM_ERROR_UNSUPPORTED);
    assert_null(ctx);
    assert_int_equal(log.errors, 1);
    assert_non_null(strstr(log.last, "3.3"));
    assert_non_null(strstr(log.last, "4.3"));
    assert_int_equal(stats.allocs, 0);
    GLTEST_END();
}

/* A broken shader: GIM_ERROR_GL, the compiler's message in the log, no GL error, no program
   left behind; a link failure likewise. Then every embedded shader builds. */
static void shader_failures(void **state) {
    static const char broken[] = "layout(local_size_x = 1) in;\nvoid main() { float x = ; }\n";
    /* a vertex shader without main() compiles and cannot link on any driver (an input the
       vertex stage never writes was tried first: NVIDIA links it) */
    static const char vs[] = "out vec3 v_a;\nvoid not_main() { v_a = vec3(1.0); gl_Position = vec4(0.0); }\n";
    static const char fs[] = "in vec3 v_a;\nout vec4 colour;\nvoid main() { colour = vec4(v_a, 1.0); }\n";
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    gim__shader_stage st[2];
    GLuint prog = 12345;
    int i;
    (void)state;
    GLTEST_BEGIN();
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    st[0].type = GIM__GL_COMPUTE_SHADER;
    st[0].name = "broken.comp";
    st[0].source = broken;
    log.errors = 0;
    assert_int_equal(gim__gl_build_program(ctx, "broken", st, 1, &prog), GIM_ERROR_GL);
    assert_int_equal(prog, 12345);
    assert_true(log.errors >= 2); /* at least one info-log line, then the summary */
    assert_non_null(strstr(log.last, "broken.comp"));
    assert_non_null(strstr(log.last, "GIM_ERROR_GL"));

    st[0].type = GIM__GL_VERTEX_SHADER;
    st[0].name = "a.vert";
    st[0].source = vs;
    st[1].type = GIM__GL_FRAGMENT_SHADER;
    st[1].name = "a.frag";
    st[1].source = fs;
    log.errors = 0;
    assert_int_equal(gim__gl_build_program(ctx, "mismatch", st, 2, &prog), GIM_ERROR_GL);
    assert_int_equal(prog, 12345);
    assert_true(log.errors >= 1);
    assert_non_null(strstr(log.last, "does not link"));

    /* every program the runtime has compiles and links on this driver; lazily: none yet */
    for (i = 0; i < GIM__PROGRAM_COUNT; ++i) assert_int_equal(ctx->programs[i], 0);
    for (i = 0; i < GIM__PROGRAM_COUNT; ++i) {
        GLuint p = 0;
        assert_int_equal(gim__gl_program(ctx, (gim__program_id)i, &p), GIM_OK);
        assert_true(p != 0 && glIsProgram(p));
        assert_int_equal(ctx->programs[i], p);
    }
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    GLTEST_END();
}

/* --- the state-restore test ---------------------------------------------------------------- */

#define HOST_UBO_BINDINGS 4   /* uniform buffer bindings the host sets (gimany uses none) */

typedef struct host_objects {
    GLuint program, vao, buffers[16], fbo[2], tex2d[GIM__GL_TEXTURE_UNITS], tex2d_array[GIM__GL_TEXTURE_UNITS];
    GLuint samplers[GIM__GL_TEXTURE_UNITS], image_tex;
    GLint ssbo_align, ubo_align;
} host_objects;

static const GLenum caps[] = {GL_BLEND, GL_CULL_FACE, GL_DEPTH_TEST, GL_STENCIL_TEST, GL_SCISSOR_TEST,
                              GL_PRIMITIVE_RESTART, GL_RASTERIZER_DISCARD, GL_POLYGON_OFFSET_FILL,
                              GL_FRAMEBUFFER_SRGB, GL_DEPTH_CLAMP, GL_CLIP_DISTANCE0, GL_CLIP_DISTANCE3,
                              GL_CLIP_DISTANCE7, GL_POLYGON_SMOOTH, GL_COLOR_LOGIC_OP,
                              GL_PRIMITIVE_RESTART_FIXED_INDEX};
/* every pixel-store parameter with a value away from its default (unpack 3 + i, pack 5 + i) */
static const GLenum pixel_store[][2] = {
    {GL_UNPACK_ROW_LENGTH, GL_PACK_ROW_LENGTH}, {GL_UNPACK_SKIP_ROWS, GL_PACK_SKIP_ROWS},
    {GL_UNPACK_SKIP_PIXELS, GL_PACK_SKIP_PIXELS}, {GL_UNPACK_IMAGE_HEIGHT, GL_PACK_IMAGE_HEIGHT},
    {GL_UNPACK_SKIP_IMAGES, GL_PACK_SKIP_IMAGES}};
#define N_PIXEL_STORE (sizeof pixel_store / sizeof pixel_store[0])
static const GLenum buffer_targets[][2] = {
    {GL_ARRAY_BUFFER, GL_ARRAY_BUFFER_BINDING}, {GL_DISPATCH_INDIRECT_BUFFER, GL_DISPATCH_INDIRECT_BUFFER_BINDING},
    {GL_DRAW_INDIRECT_BUFFER, GL_DRAW_INDIRECT_BUFFER_BINDING}, {GL_PIXEL_PACK_BUFFER, GL_PIXEL_PACK_BUFFER_BINDING},
    {GL_PIXEL_UNPACK_BUFFER, GL_PIXEL_UNPACK_BUFFER_BINDING}, {GL_COPY_READ_BUFFER, GL_COPY_READ_BUFFER_BINDING},
    {GL_COPY_WRITE_BUFFER, GL_COPY_WRITE_BUFFER_BINDING}, {GL_SHADER_STORAGE_BUFFER, GL_SHADER_STORAGE_BUFFER_BINDING},
    {GL_UNIFORM_BUFFER, GL_UNIFORM_BUFFER_BINDING}};
#define N_BUFFER_TARGETS (sizeof buffer_targets / sizeof buffer_targets[0])
/* buffers[] use: 0..8 the generic targets, 9 the VAO's element array, 10 the SSBO ranges, 11 the UBO ranges */

static GLuint host_compute_program(void) {
    static const char *src = "#version 430 core\nlayout(local_size_x = 1) in;\nvoid main() {}\n";
    GLuint s = glCreateShader(GL_COMPUTE_SHADER), p = glCreateProgram();
    GLint ok = 0;
    glShaderSource(s, 1, &src, NULL);
    glCompileShader(s);
    glAttachShader(p, s);
    glLinkProgram(p);
    glDeleteShader(s);
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    assert_true(ok);
    return p;
}

/* Every item of the state list set away from its default. */
static void set_distinctive_state(host_objects *h) {
    unsigned i;
    memset(h, 0, sizeof *h);
    glGetIntegerv(GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT, &h->ssbo_align);
    glGetIntegerv(GL_UNIFORM_BUFFER_OFFSET_ALIGNMENT, &h->ubo_align);
    h->program = host_compute_program();
    glUseProgram(h->program);
    glGenVertexArrays(1, &h->vao);
    glBindVertexArray(h->vao);
    glGenBuffers(16, h->buffers);
    for (i = 0; i < 12; ++i) {
        glBindBuffer(GL_COPY_WRITE_BUFFER, h->buffers[i]);
        glBufferData(GL_COPY_WRITE_BUFFER, 64 * 1024, NULL, GL_DYNAMIC_DRAW);
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, h->buffers[9]);
    for (i = 0; i < GIM__GL_SSBO_BINDINGS; ++i)
        glBindBufferRange(GL_SHADER_STORAGE_BUFFER, i, h->buffers[10], (GLintptr)(i + 1) * h->ssbo_align, 256 + 16 * i);
    for (i = 0; i < HOST_UBO_BINDINGS; ++i)
        glBindBufferRange(GL_UNIFORM_BUFFER, i, h->buffers[11], (GLintptr)(i + 1) * h->ubo_align, 512 + 16 * i);
    for (i = 0; i < N_BUFFER_TARGETS; ++i) glBindBuffer(buffer_targets[i][0], h->buffers[i]);
    glGenFramebuffers(2, h->fbo);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, h->fbo[0]);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, h->fbo[1]);
    glViewport(3, 5, 17, 19);
    glScissor(1, 2, 7, 9);
    for (i = 0; i < sizeof caps / sizeof caps[0]; ++i) glEnable(caps[i]);
    glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_DST_COLOR, GL_SRC_COLOR);
    glBlendEquationSeparate(GL_FUNC_SUBTRACT, GL_MAX);
    glDepthFunc(GL_GREATER);
    glDepthMask(GL_FALSE);
    glColorMask(GL_TRUE, GL_FALSE, GL_TRUE, GL_FALSE);
    glColorMaski(3, GL_FALSE, GL_TRUE, GL_FALSE, GL_TRUE); /* per draw buffer: 3 and 6 differ */
    glDisablei(GL_BLEND, 6);
    glBlendFuncSeparatei(6, GL_ONE, GL_ONE, GL_ZERO, GL_ONE);
    glBlendEquationSeparatei(3, GL_MIN, GL_FUNC_REVERSE_SUBTRACT);
    glFrontFace(GL_CW);
    glCullFace(GL_FRONT);
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    glClearColor(0.125f, 0.25f, 0.375f, 0.5f);
    glClearDepth(0.25);
    glDepthRange(0.125, 0.75);
    glGenTextures(GIM__GL_TEXTURE_UNITS, h->tex2d);
    glGenTextures(GIM__GL_TEXTURE_UNITS, h->tex2d_array);
    glGenSamplers(GIM__GL_TEXTURE_UNITS, h->samplers);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        glActiveTexture(GL_TEXTURE0 + i);
        glBindTexture(GL_TEXTURE_2D, h->tex2d[i]);
        glBindTexture(GL_TEXTURE_2D_ARRAY, h->tex2d_array[i]);
        glBindSampler(i, h->samplers[i]);
    }
    glActiveTexture(GL_TEXTURE5);
    glGenTextures(1, &h->image_tex);
    glBindTexture(GL_TEXTURE_2D_ARRAY, h->image_tex);
    glTexStorage3D(GL_TEXTURE_2D_ARRAY, 2, GL_RGBA32F, 4, 4, 3);
    glBindTexture(GL_TEXTURE_2D_ARRAY, h->tex2d_array[5]);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i)
        glBindImageTexture(i, h->image_tex, (GLint)(i & 1u), (i & 2u) ? GL_TRUE : GL_FALSE, (GLint)(i % 3u),
                           GL_WRITE_ONLY, GL_RGBA32F);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 2);
    glPixelStorei(GL_PACK_ROW_LENGTH, 7);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 9);
    for (i = 1; i < N_PIXEL_STORE; ++i) {
        glPixelStorei(pixel_store[i][0], (GLint)(3 + i));
        glPixelStorei(pixel_store[i][1], (GLint)(5 + i));
    }
    glPixelStorei(GL_UNPACK_SWAP_BYTES, GL_TRUE);
    glPixelStorei(GL_PACK_LSB_FIRST, GL_TRUE);
    glProvokingVertex(GL_FIRST_VERTEX_CONVENTION);
    glClipControl(GL_UPPER_LEFT, GL_ZERO_TO_ONE);
    assert_int_equal(gltest_errors(), 0);
}

/* Read every item back with the test's own GL calls and compare with what was set. */
static void check_distinctive_state(const host_objects *h) {
    GLint v, v4[4];
    GLint64 v64;
    GLboolean b4[4];
    GLfloat f4[4];
    unsigned i;
    glGetIntegerv(GL_CURRENT_PROGRAM, &v); assert_int_equal(v, h->program);
    glGetIntegerv(GL_VERTEX_ARRAY_BINDING, &v); assert_int_equal(v, h->vao);
    glGetIntegerv(GL_ELEMENT_ARRAY_BUFFER_BINDING, &v); assert_int_equal(v, h->buffers[9]);
    for (i = 0; i < N_BUFFER_TARGETS; ++i) {
        glGetIntegerv(buffer_targets[i][1], &v);
        assert_int_equal(v, h->buffers[i]);
    }
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &v); assert_int_equal(v, h->fbo[0]);
    glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &v); assert_int_equal(v, h->fbo[1]);
    glGetIntegerv(GL_VIEWPORT, v4);
    assert_true(v4[0] == 3 && v4[1] == 5 && v4[2] == 17 && v4[3] == 19);
    glGetIntegerv(GL_SCISSOR_BOX, v4);
    assert_true(v4[0] == 1 && v4[1] == 2 && v4[2] == 7 && v4[3] == 9);
    for (i = 0; i < sizeof caps / sizeof caps[0]; ++i) assert_true(glIsEnabled(caps[i]));
    glGetIntegerv(GL_BLEND_SRC_RGB, &v); assert_int_equal(v, GL_SRC_ALPHA);
    glGetIntegerv(GL_BLEND_DST_RGB, &v); assert_int_equal(v, GL_ONE_MINUS_SRC_ALPHA);
    glGetIntegerv(GL_BLEND_SRC_ALPHA, &v); assert_int_equal(v, GL_DST_COLOR);
    glGetIntegerv(GL_BLEND_DST_ALPHA, &v); assert_int_equal(v, GL_SRC_COLOR);
    glGetIntegerv(GL_BLEND_EQUATION_RGB, &v); assert_int_equal(v, GL_FUNC_SUBTRACT);
    glGetIntegerv(GL_BLEND_EQUATION_ALPHA, &v); assert_int_equal(v, GL_MAX);
    glGetIntegerv(GL_DEPTH_FUNC, &v); assert_int_equal(v, GL_GREATER);
    glGetBooleanv(GL_DEPTH_WRITEMASK, b4); assert_int_equal(b4[0], GL_FALSE);
    glGetBooleanv(GL_COLOR_WRITEMASK, b4);
    assert_true(b4[0] == GL_TRUE && b4[1] == GL_FALSE && b4[2] == GL_TRUE && b4[3] == GL_FALSE);
    glGetBooleani_v(GL_COLOR_WRITEMASK, 3, b4);
    assert_true(b4[0] == GL_FALSE && b4[1] == GL_TRUE && b4[2] == GL_FALSE && b4[3] == GL_TRUE);
    assert_true(glIsEnabledi(GL_BLEND, 5) && !glIsEnabledi(GL_BLEND, 6));
    glGetIntegeri_v(GL_BLEND_SRC_RGB, 6, &v); assert_int_equal(v, GL_ONE);
    glGetIntegeri_v(GL_BLEND_SRC_ALPHA, 6, &v); assert_int_equal(v, GL_ZERO);
    glGetIntegeri_v(GL_BLEND_SRC_RGB, 5, &v); assert_int_equal(v, GL_SRC_ALPHA);
    glGetIntegeri_v(GL_BLEND_EQUATION_RGB, 3, &v); assert_int_equal(v, GL_MIN);
    glGetIntegeri_v(GL_BLEND_EQUATION_ALPHA, 3, &v); assert_int_equal(v, GL_FUNC_REVERSE_SUBTRACT);
    glGetIntegerv(GL_FRONT_FACE, &v); assert_int_equal(v, GL_CW);
    glGetIntegerv(GL_CULL_FACE_MODE, &v); assert_int_equal(v, GL_FRONT);
    glGetIntegerv(GL_POLYGON_MODE, v4); assert_int_equal(v4[0], GL_LINE);
    glGetFloatv(GL_COLOR_CLEAR_VALUE, f4);
    assert_true(f4[0] == 0.125f && f4[1] == 0.25f && f4[2] == 0.375f && f4[3] == 0.5f);
    glGetFloatv(GL_DEPTH_CLEAR_VALUE, f4); assert_true(f4[0] == 0.25f);
    glGetFloatv(GL_DEPTH_RANGE, f4); assert_true(f4[0] == 0.125f && f4[1] == 0.75f);
    glGetIntegerv(GL_ACTIVE_TEXTURE, &v); assert_int_equal(v, GL_TEXTURE5);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        glActiveTexture(GL_TEXTURE0 + i);
        glGetIntegerv(GL_TEXTURE_BINDING_2D, &v); assert_int_equal(v, h->tex2d[i]);
        glGetIntegerv(GL_TEXTURE_BINDING_2D_ARRAY, &v); assert_int_equal(v, h->tex2d_array[i]);
        glGetIntegerv(GL_SAMPLER_BINDING, &v); assert_int_equal(v, h->samplers[i]);
    }
    glActiveTexture(GL_TEXTURE5);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) {
        glGetIntegeri_v(GL_IMAGE_BINDING_NAME, i, &v); assert_int_equal(v, h->image_tex);
        glGetIntegeri_v(GL_IMAGE_BINDING_LEVEL, i, &v); assert_int_equal(v, (GLint)(i & 1u));
        glGetBooleani_v(GL_IMAGE_BINDING_LAYERED, i, b4); assert_int_equal(b4[0], (i & 2u) ? GL_TRUE : GL_FALSE);
        glGetIntegeri_v(GL_IMAGE_BINDING_LAYER, i, &v); assert_int_equal(v, (GLint)(i % 3u));
        glGetIntegeri_v(GL_IMAGE_BINDING_ACCESS, i, &v); assert_int_equal(v, GL_WRITE_ONLY);
        glGetIntegeri_v(GL_IMAGE_BINDING_FORMAT, i, &v); assert_int_equal(v, GL_RGBA32F);
    }
    for (i = 0; i < GIM__GL_SSBO_BINDINGS; ++i) {
        glGetIntegeri_v(GL_SHADER_STORAGE_BUFFER_BINDING, i, &v); assert_int_equal(v, h->buffers[10]);
        glGetInteger64i_v(GL_SHADER_STORAGE_BUFFER_START, i, &v64); assert_true(v64 == (GLint64)(i + 1) * h->ssbo_align);
        glGetInteger64i_v(GL_SHADER_STORAGE_BUFFER_SIZE, i, &v64); assert_true(v64 == 256 + 16 * (GLint64)i);
    }
    for (i = 0; i < HOST_UBO_BINDINGS; ++i) {
        glGetIntegeri_v(GL_UNIFORM_BUFFER_BINDING, i, &v); assert_int_equal(v, h->buffers[11]);
        glGetInteger64i_v(GL_UNIFORM_BUFFER_START, i, &v64); assert_true(v64 == (GLint64)(i + 1) * h->ubo_align);
        glGetInteger64i_v(GL_UNIFORM_BUFFER_SIZE, i, &v64); assert_true(v64 == 512 + 16 * (GLint64)i);
    }
    glGetIntegerv(GL_PACK_ALIGNMENT, &v); assert_int_equal(v, 1);
    glGetIntegerv(GL_UNPACK_ALIGNMENT, &v); assert_int_equal(v, 2);
    glGetIntegerv(GL_PACK_ROW_LENGTH, &v); assert_int_equal(v, 7);
    glGetIntegerv(GL_UNPACK_ROW_LENGTH, &v); assert_int_equal(v, 9);
    for (i = 1; i < N_PIXEL_STORE; ++i) {
        glGetIntegerv(pixel_store[i][0], &v); assert_int_equal(v, (GLint)(3 + i));
        glGetIntegerv(pixel_store[i][1], &v); assert_int_equal(v, (GLint)(5 + i));
    }
    glGetIntegerv(GL_UNPACK_SWAP_BYTES, &v); assert_int_equal(v, GL_TRUE);
    glGetIntegerv(GL_PACK_SWAP_BYTES, &v); assert_int_equal(v, GL_FALSE);
    glGetIntegerv(GL_PACK_LSB_FIRST, &v); assert_int_equal(v, GL_TRUE);
    glGetIntegerv(GL_PROVOKING_VERTEX, &v); assert_int_equal(v, GL_FIRST_VERTEX_CONVENTION);
    glGetIntegerv(GL_CLIP_ORIGIN, &v); assert_int_equal(v, GL_UPPER_LEFT);
    glGetIntegerv(GL_CLIP_DEPTH_MODE, &v); assert_int_equal(v, GL_ZERO_TO_ONE);
}

static void delete_host_objects(host_objects *h) {
    glUseProgram(0);
    glBindVertexArray(0);
    glDeleteProgram(h->program);
    glDeleteVertexArrays(1, &h->vao);
    glDeleteBuffers(16, h->buffers);
    glDeleteFramebuffers(2, h->fbo);
    glDeleteTextures(GIM__GL_TEXTURE_UNITS, h->tex2d);
    glDeleteTextures(GIM__GL_TEXTURE_UNITS, h->tex2d_array);
    glDeleteSamplers(GIM__GL_TEXTURE_UNITS, h->samplers);
    glDeleteTextures(1, &h->image_tex);
}

/* The library's own snapshot must also be unchanged: it covers the whole list at once. */
static void assert_snapshot_equal(const gim__gl_state *a, const gim__gl_state *b) {
    assert_memory_equal(a, b, sizeof *a);
}

/* State gimany never sets, so outside its save list: back to GL's initial values. */
static void set_default_unlisted(void) {
    unsigned i;
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glPixelStorei(GL_PACK_ROW_LENGTH, 0);
    for (i = 1; i < N_PIXEL_STORE; ++i) glPixelStorei(pixel_store[i][1], 0);
    glPixelStorei(GL_PACK_LSB_FIRST, GL_FALSE);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    for (i = 1; i < N_PIXEL_STORE; ++i) glPixelStorei(pixel_store[i][0], 0);
    glPixelStorei(GL_UNPACK_SWAP_BYTES, GL_FALSE);
    for (i = 0; i < sizeof caps / sizeof caps[0]; ++i) glDisable(caps[i]);   /* blending and clip planes too */
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);                          /* every draw buffer's */
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, 0);
    for (i = 0; i < HOST_UBO_BINDINGS; ++i) glBindBufferBase(GL_UNIFORM_BUFFER, i, 0);
    for (i = 0; i < N_BUFFER_TARGETS; ++i) glBindBuffer(buffer_targets[i][0], 0);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        glActiveTexture(GL_TEXTURE0 + i);
        glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
    }
    glActiveTexture(GL_TEXTURE0);
    glScissor(0, 0, 1, 1);
    glBlendFuncSeparate(GL_ONE, GL_ZERO, GL_ONE, GL_ZERO);
    glBlendEquationSeparate(GL_FUNC_ADD, GL_FUNC_ADD);
    glFrontFace(GL_CCW);
    glCullFace(GL_BACK);
    glClearColor(0.0f, 0.0f, 0.0f, 0.0f);
    glClearDepth(1.0);
}

/* Every item of the save list back to GL's initial value (and every binding to 0), away from
   the distinctive state; the items as gimany sets them (its draw buffers one by one, the 2D
   arrays of its array units), so what is outside the list keeps the distinctive state. */
static void set_default_listed(void) {
    unsigned i;
    glUseProgram(0);
    glBindVertexArray(0);
    for (i = 0; i < GIM__GL_SSBO_BINDINGS; ++i) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, i, 0);
    for (i = 0; i < GIM__GL_STATE_BUFFERS; ++i) glBindBuffer(gim__gl_state_buffers[i][0], 0);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glViewport(0, 0, 1, 1);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) glDisable(gim__gl_state_caps[i]);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        glDisablei(GL_BLEND, i);
        glColorMaski(i, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    glDepthRange(0.0, 1.0);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        glActiveTexture(GL_TEXTURE0 + i);
        glBindTexture(GL_TEXTURE_2D, 0);
        if (GIM__GL_TEXTURE_ARRAY_UNITS >> i & 1u) glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
        glBindSampler(i, 0);
    }
    glActiveTexture(GL_TEXTURE0);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) glBindImageTexture(i, 0, 0, GL_FALSE, 0, GL_READ_ONLY, GL_R8);
    glProvokingVertex(GL_LAST_VERTEX_CONVENTION);
    glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
}

/* Every item back to GL's initial value. */
static void set_default_state(void) {
    set_default_listed();
    set_default_unlisted();
}

/* The save/restore pair itself covers the whole list, whatever a pass happens to touch:
   host state A saved, every item changed, restored -> A (checked item by item); and the
   reverse, from GL's defaults (zero bindings restored too). */
static void save_restore_covers_list(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    host_objects h;
    gim__gl_state s0, s1;
    (void)state;
    GLTEST_BEGIN();
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    set_distinctive_state(&h);
    gim__gl_enter(ctx, "test");
    gim__gl_enter(ctx, "test nested"); /* only the outermost saves and restores */
    set_default_listed();
    assert_int_equal(gim__gl_leave(ctx, GIM_OK), GIM_OK);
    glViewport(0, 0, 2, 2); /* still inside the outer call: must not have been restored yet */
    {
        GLint v4[4];
        glGetIntegerv(GL_VIEWPORT, v4);
        assert_int_equal(v4[2], 2);
    }
    assert_int_equal(gim__gl_leave(ctx, GIM_ERROR_GL), GIM_ERROR_GL);
    check_distinctive_state(&h);
    set_default_state();
    delete_host_objects(&h);

    gim__gl_state_save(&ctx->gl, &s0);
    gim__gl_enter(ctx, "test");
    set_distinctive_state(&h);
    gim__gl_leave(ctx, GIM_OK);
    gim__gl_state_save(&ctx->gl, &s1);
    assert_snapshot_equal(&s0, &s1);
    set_default_unlisted();   /* not restored: gimany never sets it */
    delete_host_objects(&h);
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    GLTEST_END();
}

/* A small RSM (w x h RGBA32F position with w = 1, normal, flux), view samples and buffers. */
typedef struct pass_objects {
    GLuint tex[3], view_samples, map, column, row, selected;
} pass_objects;

static void make_pass_objects(pass_objects *o, int w, int h) {
    float *t = (float *)calloc((size_t)w * h * 4, sizeof(float));
    float vs[4 * 8 * 2];
    int i, k;
    glGenTextures(3, o->tex);
    for (k = 0; k < 3; ++k) {
        for (i = 0; i < w * h; ++i) {
            float *p = t + i * 4;
            if (k == 0) { p[0] = (float)(i % w); p[1] = 0.0f; p[2] = (float)(i / w); p[3] = 1.0f; }
            else if (k == 1) { p[0] = 0.0f; p[1] = 1.0f; p[2] = 0.0f; p[3] = 0.0f; }
            else { p[0] = p[1] = p[2] = 1.0f; p[3] = 0.0f; }
        }
        glBindTexture(GL_TEXTURE_2D, o->tex[k]);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, w, h);
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGBA, GL_FLOAT, t);
    }
    glBindTexture(GL_TEXTURE_2D, 0);
    for (i = 0; i < 8; ++i) { /* view samples above the floor, facing down */
        float *v = vs + i * 8;
        v[0] = (float)i; v[1] = 3.0f; v[2] = (float)(i % 3); v[3] = 1.0f;
        v[4] = 0.0f; v[5] = -1.0f; v[6] = 0.0f; v[7] = 0.0f;
    }
    glGenBuffers(1, &o->view_samples);
    glGenBuffers(1, &o->map);
    glGenBuffers(1, &o->column);
    glGenBuffers(1, &o->row);
    glGenBuffers(1, &o->selected);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, o->view_samples);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof vs, vs, GL_STATIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, o->map);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)w * h * 4, NULL, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, o->column);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)w * h * 8, NULL, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, o->row);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)w * 8, NULL, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, o->selected);
    glBufferData(GL_SHADER_STORAGE_BUFFER, 64 * 12, NULL, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    free(t);
}

static void delete_pass_objects(pass_objects *o) {
    glDeleteTextures(3, o->tex);
    glDeleteBuffers(1, &o->view_samples);
    glDeleteBuffers(1, &o->map);
    glDeleteBuffers(1, &o->column);
    glDeleteBuffers(1, &o->row);
    glDeleteBuffers(1, &o->selected);
}

/* Every entry point that touches GL (gim_create, the passes with their lazy program builds and
   scratch buffers, failing calls, gim_destroy) leaves the host's distinctive state as it was. */
static void state_restored(void **state) {
    enum { W = 32, H = 20 };
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    host_objects h;
    pass_objects o;
    gim__gl_state before, after;
    int i;
    (void)state;
    GLTEST_BEGIN();
    make_pass_objects(&o, W, H); /* gimany's inputs, made before the host state is set */
    set_distinctive_state(&h);
    check_distinctive_state(&h);
    d = make_desc(&stats, &log);
    memset(&before, 0, sizeof before);
    memset(&after, 0, sizeof after);

    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    check_distinctive_state(&h);
    gim__gl_state_save(&ctx->gl, &before);
    assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], o.tex[1], o.tex[2], W, H, o.view_samples, 8, 10.0f, 0.0f, o.map),
                     GIM_OK);
    check_distinctive_state(&h);
    assert_int_equal(gim__gl_importance_cumsum(ctx, o.map, o.column, o.row, W, H, 8), GIM_OK);
    check_distinctive_state(&h);
    assert_int_equal(gim__gl_importance_select(ctx, o.column, o.row, W, H, 64, 7, o.selected), GIM_OK);
    check_distinctive_state(&h);
    gim__gl_state_save(&ctx->gl, &after);
    assert_snapshot_equal(&before, &after);
    /* failing calls restore too (the argument checks come before any GL; a failed program
       build inside a call is covered by save_restore_covers_list's error path) */
    assert_int_equal(gim__gl_importance_cumsum(ctx, o.map, o.column, o.row, 0, H, 8), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim__gl_importance_select(ctx, o.column, o.row, W, H, 0, 7, o.selected), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], o.tex[1], o.tex[2], W, H, o.view_samples, 8, -1.0f, 0.0f, o.map),
                     GIM_ERROR_INVALID_ARGUMENT);
    check_distinctive_state(&h);
    gim_destroy(ctx);
    check_distinctive_state(&h);
    assert_int_equal(log.errors, 3);
    assert_int_equal(stats.live, 0);

    /* the passes ran under that state and did their work: the floor texels under the view
       samples are important, every pick has a positive pdf */
    {
        float map[W * H];
        double rw[W];
        uint32_t sel[64 * 3];
        glBindBuffer(GL_COPY_READ_BUFFER, o.map);
        glGetBufferSubData(GL_COPY_READ_BUFFER, 0, sizeof map, map);
        glBindBuffer(GL_COPY_READ_BUFFER, o.row);
        glGetBufferSubData(GL_COPY_READ_BUFFER, 0, sizeof rw, rw);
        glBindBuffer(GL_COPY_READ_BUFFER, o.selected);
        glGetBufferSubData(GL_COPY_READ_BUFFER, 0, sizeof sel, sel);
        glBindBuffer(GL_COPY_READ_BUFFER, h.buffers[5]);
        for (i = 0; i < W * H; ++i) assert_true(map[i] > 0.0f);
        assert_true(rw[W - 1] > 0.0);
        for (i = 0; i < 64; ++i) {
            float pdf;
            memcpy(&pdf, &sel[i * 3 + 2], sizeof pdf);
            assert_true(sel[i * 3] < W && sel[i * 3 + 1] < H && pdf > 0.0f && pdf <= 1.0f);
        }
    }
    delete_host_objects(&h);
    delete_pass_objects(&o);
    GLTEST_END();
}

/* Host buffers and textures too small for a pass, or not GL objects at all: an argument error
   before any dispatch (no SSBO access past the end), no GL error, the state restored. */
static void pass_objects_checked(void **state) {
    enum { W = 16, H = 8 };
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    pass_objects o;
    gim__gl_state before, after;
    GLuint small = 0, small_tex = 0;
    (void)state;
    GLTEST_BEGIN();
    make_pass_objects(&o, W, H);
    glGenBuffers(1, &small);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, small);
    glBufferData(GL_SHADER_STORAGE_BUFFER, W * H * 4 - 4, NULL, GL_DYNAMIC_COPY); /* one float short */
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    glGenTextures(1, &small_tex);
    glBindTexture(GL_TEXTURE_2D, small_tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, W, H - 1);
    glBindTexture(GL_TEXTURE_2D, 0);
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    gim__gl_state_save(&ctx->gl, &before);
    /* map one float short; column sized for fewer rows; not a buffer; out too short */
    assert_int_equal(gim__gl_importance_cumsum(ctx, small, o.column, o.row, W, H, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(log.last, "map"));
    assert_int_equal(gim__gl_importance_cumsum(ctx, o.map, o.column, o.row, W, H + 1, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_cumsum(ctx, o.map, 987654u, o.row, W, H, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(log.last, "not a buffer"));
    assert_int_equal(gim__gl_importance_select(ctx, o.column, o.row, W, H, 65, 0, o.selected), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(log.last, "out"));
    assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], small_tex, o.tex[2], W, H, o.view_samples, 8, 1.0f, 0.0f, o.map),
                     GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(log.last, "rsm_normal"));
    assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], o.tex[1], 987654u, W, H, o.view_samples, 8, 1.0f, 0.0f, o.map),
                     GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(log.last, "not a texture"));
    assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], o.tex[1], o.tex[2], W, H, o.view_samples, 9, 1.0f, 0.0f, o.map),
                     GIM_ERROR_INVALID_ARGUMENT); /* 8 view samples in the buffer */
    {   /* a 2D array texture is no 2D texture: GL 4.5 asks its target, no GL error; before,
           the failed bind is one error, cleared by gimany with or without GIMANY_DEBUG */
        GLuint array_tex = 0;
        glGenTextures(1, &array_tex);
        glBindTexture(GL_TEXTURE_2D_ARRAY, array_tex);
        glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_RGBA32F, W, H, 2);
        glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
        gim__gl_state_save(&ctx->gl, &before);
        gltest.quiet = 1;
        assert_int_equal(gim__gl_importance_map(ctx, o.tex[0], o.tex[1], array_tex, W, H, o.view_samples, 8, 1.0f, 0.0f,
                                                o.map),
                         GIM_ERROR_INVALID_ARGUMENT);
        gltest.quiet = 0;
        assert_non_null(strstr(log.last, "not a 2D texture"));
        assert_int_equal(glGetError(), GL_NO_ERROR);
        assert_int_equal(gltest_errors(), ctx->gl.GetTextureParameteriv ? 0 : 1); /* 1: seen by the callback */
        gltest_reset_errors();
        glDeleteTextures(1, &array_tex);
    }
    assert_int_equal(log.errors, 8);
    gim__gl_state_save(&ctx->gl, &after);
    assert_memory_equal(&before, &after, sizeof before);
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    glDeleteBuffers(1, &small);
    glDeleteTextures(1, &small_tex);
    delete_pass_objects(&o);
    GLTEST_END();
}

/* The scene API and the frame (gim_add_mesh, gim_set_materials, gim_set_instances,
   gim_set_lights, gim_update with gimany's G-buffer and with the host's, gim_remove_mesh,
   failing calls among them, gim_destroy) leave the host's distinctive state as it was. */
static void scene_state_restored(void **state) {
    static const float quad[12] = {-1, 0, -1, -1, 0, 1, 1, 0, 1, 1, 0, -1};
    static const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    host_objects h;
    gim_mesh_desc md;
    gim_mesh mesh, box;
    gim_material mat;
    gim_instance inst[2];
    gim_light l[2];
    gim_frame fr;
    gim_frame_outputs o;
    gim_debug_outputs od;
    gim__gl_state before, after;
    (void)state;
    GLTEST_BEGIN();
    set_distinctive_state(&h);
    d = make_desc(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    gim__gl_state_save(&ctx->gl, &before);
    memset(&md, 0, sizeof md);
    md.data.positions = quad;
    md.data.vertex_count = 4;
    md.data.indices = idx;
    md.data.index_count = 6;
    assert_int_equal(gim_add_mesh(ctx, &md, &mesh), GIM_OK);
    check_distinctive_state(&h);
    { /* the second mesh has caches: the LightSkin passes run too */
        static gim_cache caches[4];
        static gim_cache_set set;
        int k;
        for (k = 0; k < 4; ++k) {
            caches[k].position[0] = (k & 1) ? 0.5f : -0.5f;
            caches[k].position[2] = (k & 2) ? 0.5f : -0.5f;
            caches[k].normal[1] = 1.0f;
            caches[k].area = 1.0f;
            caches[k].reflectance = 0.5f;
        }
        set.caches = caches;
        set.count = 4;
        md.caches = &set;
    }
    assert_int_equal(gim_add_mesh(ctx, &md, &box), GIM_OK);
    md.caches = NULL;
    md.data.index_count = 4;
    assert_int_equal(gim_add_mesh(ctx, &md, &box), GIM_ERROR_INVALID_ARGUMENT);
    check_distinctive_state(&h);
    memset(&mat, 0, sizeof mat);
    mat.diffuse[0] = mat.diffuse[1] = mat.diffuse[2] = 0.5f;
    mat.glossy[0] = 0.2f; mat.exponent = 8.0f;   /* the glossy passes run too */
    assert_int_equal(gim_set_materials(ctx, &mat, 1), GIM_OK);
    check_distinctive_state(&h);
    inst[0].mesh = mesh;
    inst[0].model = gim_mat4_identity();
    inst[1].mesh = box;
    inst[1].model = gim_mat4_identity();
    inst[1].model.m[13] = 0.5f;
    assert_int_equal(gim_set_instances(ctx, inst, 2), GIM_OK);
    memset(l, 0, sizeof l);
    l[0].irradiance = 1.0f;
    l[0].direction = gim_v3(0.3f, 1.0f, 0.2f);
    l[0].rsm_size = 16;
    l[1].type = GIM_LIGHT_SPOT;
    l[1].intensity = 1.0f;
    l[1].position = gim_v3(0.0f, 2.0f, 0.0f);
    l[1].direction = gim_v3(0.0f, -1.0f, 0.0f);
    l[1].cone_angle = 0.6f;
    l[1].rsm_size = 16;
    assert_int_equal(gim_set_lights(ctx, l, 2), GIM_OK);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim_v3(1.0f, 2.0f, 2.0f), gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(1.0f, 1.5f, 0.1f, 10.0f);
    fr.width = 24;
    fr.height = 16;
    fr.lightskin.view_sample_count = 32;
    fr.lightskin.val_count = 16;
    fr.timing = 1;
    assert_int_equal(gim_update(ctx, &fr), GIM_OK);
    check_distinctive_state(&h);
    o = gim_outputs(ctx); od = gim_debug(ctx);
    assert_true(o.valid && o.light_count == 2);
    assert_true(o.indirect != 0 && od.proxy_glossy != 0 && od.cache_count == 4);
    {
        gim_stats st;
        assert_int_equal(gim_frame_stats(ctx, &st), GIM_OK);
        check_distinctive_state(&h);
        assert_true(st.timed && st.frame_ms > 0.0);
    }
    fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    assert_int_equal(gim_update(ctx, &fr), GIM_OK);
    check_distinctive_state(&h);
    fr.method = GIM_METHOD_DEFAULT;
    fr.timing = 0;
    fr.gbuffer.depth = o.gbuffer_depth; /* the host's G-buffer path */
    fr.gbuffer.normal = o.gbuffer_normal;
    assert_int_equal(gim_update(ctx, &fr), GIM_OK);
    check_distinctive_state(&h);
    fr.width = 25; /* larger than those textures: fails after the RSM passes ran */
    assert_int_equal(gim_update(ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    check_distinctive_state(&h);
    fr.gbuffer.depth = fr.gbuffer.normal = 0;
    fr.lightskin.rotate_view_samples = 1;
    fr.frame_index = 3;
    assert_int_equal(gim_set_lights(ctx, l, 1), GIM_OK); /* frees light 1's objects */
    check_distinctive_state(&h);
    assert_int_equal(gim_update(ctx, &fr), GIM_OK); /* a new G-buffer size */
    check_distinctive_state(&h);
    assert_int_equal(gim_set_materials(ctx, NULL, 0), GIM_OK);
    assert_int_equal(gim_update(ctx, &fr), GIM_ERROR_INVALID_ARGUMENT); /* no materials */
    assert_int_equal(gim_remove_mesh(ctx, box), GIM_OK);
    check_distinctive_state(&h);
    gim__gl_state_save(&ctx->gl, &after);
    assert_snapshot_equal(&before, &after);
    gim_destroy(ctx);
    check_distinctive_state(&h);
    assert_int_equal(log.errors, 3);
    assert_int_equal(stats.live, 0);
    delete_host_objects(&h);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(errors_are_seen),
        cmocka_unit_test(create_destroy),
        cmocka_unit_test(invalid_desc),
        cmocka_unit_test(missing_function),
        cmocka_unit_test(old_context),
        cmocka_unit_test(shader_failures),
        cmocka_unit_test(save_restore_covers_list),
        cmocka_unit_test(state_restored),
        cmocka_unit_test(pass_objects_checked),
        cmocka_unit_test(scene_state_restored),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
