/* Headless GL for tests: an EGL desktop GL 4.3+ core context with no surface, and a KHR_debug
   callback that counts GL errors so every GL test can assert there were none.

   Display: EGL_PLATFORM_DEVICE_EXT on a hardware device when a GPU driver offers one, else
   Mesa's EGL_PLATFORM_SURFACELESS_MESA (llvmpipe in CI). If no context can be had the tests
   FAIL, unless GIMANY_SKIP_GL=1 is set (then they are skipped).

   Include after `#define GIMANY_IMPLEMENTATION` in place of testutil.h. The test calls GL
   directly through libGL (GL_GLEXT_PROTOTYPES); gimany loads its own table through
   eglGetProcAddress, so gimany.h here also proves it coexists with a host's GL header. */
#ifndef GIMANY_GLTEST_H
#define GIMANY_GLTEST_H
#include <EGL/egl.h>
#include <EGL/eglext.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#include "testutil.h"

typedef struct gltest_state {
    EGLDisplay display;
    EGLContext context;
    int ready;            /* 1: a context is current */
    int tried;
    char why[256];        /* why there is no context */
    const char *platform; /* "device" or "surfaceless" */
    long gl_errors;       /* GL_DEBUG_TYPE_ERROR messages since gltest_reset_errors */
    int quiet;            /* 1 while a test provokes errors on purpose */
    char last_error[512];
} gltest_state;

static gltest_state gltest;

static void APIENTRY gltest_debug_callback(GLenum source, GLenum type, GLuint id, GLenum severity,
                                             GLsizei length, const GLchar *message, const void *user) {
    (void)id; (void)length; (void)user; (void)severity;
    /* a failed shader compile is reported through the info log, not as a GL error */
    if (type != GL_DEBUG_TYPE_ERROR || source == GL_DEBUG_SOURCE_SHADER_COMPILER) return;
    gltest.gl_errors++;
    snprintf(gltest.last_error, sizeof gltest.last_error, "%s", message);
    if (!gltest.quiet) fprintf(stderr, "gltest: GL error: %s\n", message);
}

static int gltest_has_ext(const char *list, const char *ext) {
    size_t n = strlen(ext);
    const char *p = list;
    while (p && (p = strstr(p, ext)) != NULL) {
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == 0)) return 1;
        p += n;
    }
    return 0;
}

/* A hardware EGL device's display, or EGL_NO_DISPLAY. */
static EGLDisplay gltest_device_display(PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display) {
    PFNEGLQUERYDEVICESEXTPROC query_devices =
        (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    PFNEGLQUERYDEVICESTRINGEXTPROC query_string =
        (PFNEGLQUERYDEVICESTRINGEXTPROC)eglGetProcAddress("eglQueryDeviceStringEXT");
    EGLDeviceEXT devices[16];
    EGLint count = 0, i;
    if (!query_devices || !query_string || !query_devices(16, devices, &count)) return EGL_NO_DISPLAY;
    for (i = 0; i < count; ++i) {
        const char *ext = query_string(devices[i], EGL_EXTENSIONS);
        if (ext && gltest_has_ext(ext, "EGL_MESA_device_software")) continue; /* llvmpipe: use surfaceless */
        {
            EGLDisplay d = get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL);
            if (d != EGL_NO_DISPLAY) return d;
        }
    }
    return EGL_NO_DISPLAY;
}

static int gltest_try_display(EGLDisplay d) {
    static const EGLint ctx_attribs[] = {
        EGL_CONTEXT_MAJOR_VERSION, 4, EGL_CONTEXT_MINOR_VERSION, 3,
        EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
        EGL_CONTEXT_OPENGL_DEBUG, EGL_TRUE, EGL_NONE};
    static const EGLint cfg_attribs[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0, EGL_NONE};
    EGLint major, minor, n = 0;
    EGLConfig cfg = (EGLConfig)0;
    const char *ext;
    if (d == EGL_NO_DISPLAY || !eglInitialize(d, &major, &minor)) return 0;
    ext = eglQueryString(d, EGL_EXTENSIONS);
    if (!eglBindAPI(EGL_OPENGL_API)) { eglTerminate(d); return 0; }
    if (!(ext && gltest_has_ext(ext, "EGL_KHR_no_config_context"))) {
        if (!eglChooseConfig(d, cfg_attribs, &cfg, 1, &n) || n < 1) { eglTerminate(d); return 0; }
    }
    gltest.context = eglCreateContext(d, cfg, EGL_NO_CONTEXT, ctx_attribs);
    if (gltest.context == EGL_NO_CONTEXT) { eglTerminate(d); return 0; }
    if (!eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, gltest.context)) {
        eglDestroyContext(d, gltest.context);
        eglTerminate(d);
        return 0;
    }
    gltest.display = d;
    return 1;
}

/* Creates the context once per process; 1 when one is current. */
static int gltest_init(void) {
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display;
    const char *client_ext;
    if (gltest.tried) return gltest.ready;
    gltest.tried = 1;
    client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    get_platform_display = (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!client_ext || !get_platform_display) {
        snprintf(gltest.why, sizeof gltest.why, "EGL has no client extensions / eglGetPlatformDisplayEXT");
        return 0;
    }
    if (gltest_has_ext(client_ext, "EGL_EXT_platform_device") &&
        gltest_try_display(gltest_device_display(get_platform_display))) {
        gltest.platform = "device";
    } else if (gltest_has_ext(client_ext, "EGL_MESA_platform_surfaceless") &&
               gltest_try_display(get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL))) {
        gltest.platform = "surfaceless";
    } else {
        snprintf(gltest.why, sizeof gltest.why, "no EGL display gives a desktop GL 4.3 core context (EGL error 0x%x)",
                 (unsigned)eglGetError());
        return 0;
    }
    glEnable(GL_DEBUG_OUTPUT);
    glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS);
    glDebugMessageCallback(gltest_debug_callback, NULL);
    glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, NULL, GL_TRUE);
    gltest.ready = 1;
    fprintf(stderr, "gltest: %s platform, %s, %s\n", gltest.platform, (const char *)glGetString(GL_RENDERER),
            (const char *)glGetString(GL_VERSION));
    return 1;
}

/* The display is left initialised: Mesa 22.3's llvmpipe loses 112 bytes in eglTerminate
   once anything was drawn (a draw-module leak; a plain draw into an FBO shows it), which
   LeakSanitizer would pin on the test. The process ends right after. */
static void gltest_shutdown(void) {
    if (!gltest.ready) return;
    eglMakeCurrent(gltest.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(gltest.display, gltest.context);
    gltest.ready = 0;
}

/* GL errors since the last reset: debug-callback errors plus anything glGetError still holds. */
static GIM__UNUSED long gltest_errors(void) {
    GLenum e;
    int guard = 0;
    while ((e = glGetError()) != GL_NO_ERROR && guard++ < 64) {
        fprintf(stderr, "gltest: glGetError 0x%x\n", (unsigned)e);
        gltest.gl_errors++;
    }
    return gltest.gl_errors;
}
static GIM__UNUSED void gltest_reset_errors(void) {
    while (glGetError() != GL_NO_ERROR) {}
    gltest.gl_errors = 0;
    gltest.last_error[0] = 0;
}

/* The get_proc_address a host hands to gimany. */
static GIM__UNUSED gim_gl_proc gltest_get_proc(const char *name) { return (gim_gl_proc)eglGetProcAddress(name); }

/* A shader storage buffer holding bytes of data (NULL: uninitialised). */
static GIM__UNUSED GLuint gltest_ssbo(size_t bytes, const void *data) {
    GLuint b = 0;
    glGenBuffers(1, &b);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, b);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)bytes, data, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    return b;
}
/* Imperfect shadow maps (float depths, texels of them) as the GPU stores them: 16 bits a
   texel (gim_ism_quantize), two to a uint, texel 2k in the low half. */
static GIM__UNUSED GLuint gltest_ism_ssbo(const float *maps, size_t texels) {
    uint32_t *w = (uint32_t *)calloc(texels / 2 + 1, 4);
    size_t q;
    GLuint b;
    for (q = 0; q < texels; ++q) w[q / 2] |= (uint32_t)gim_ism_quantize(maps[q]) << (q & 1u ? 16 : 0);
    b = gltest_ssbo((texels / 2 + 1) * 4, w);
    free(w);
    return b;
}
/* The reverse: texels of packed maps read back from b as floats (gim_ism_dequantize). */
static GIM__UNUSED void gltest_read_ism(GLuint b, size_t texels, float *out);
/* Read the first bytes of buffer b back. */
static GIM__UNUSED void gltest_read_buffer(GLuint b, size_t bytes, void *out) {
    glBindBuffer(GL_COPY_READ_BUFFER, b);
    glGetBufferSubData(GL_COPY_READ_BUFFER, 0, (GLsizeiptr)bytes, out);
    glBindBuffer(GL_COPY_READ_BUFFER, 0);
}
static GIM__UNUSED void gltest_read_ism(GLuint b, size_t texels, float *out) {
    uint32_t *w = (uint32_t *)malloc(texels * 2 + 4);
    size_t q;
    gltest_read_buffer(b, (texels + 1) / 2 * 4, w);
    for (q = 0; q < texels; ++q) out[q] = gim_ism_dequantize((uint16_t)(q & 1u ? w[q / 2] >> 16 : w[q / 2] & 0xffffu));
    free(w);
}

/* Read a whole texture back as floats (format GL_RGBA, GL_RED or GL_DEPTH_COMPONENT). */
static GIM__UNUSED void gltest_read_texture(GLuint tex, GLenum format, float *out) {
    GLint pack = 4;
    glGetIntegerv(GL_PACK_ALIGNMENT, &pack);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glBindTexture(GL_TEXTURE_2D, tex);
    glGetTexImage(GL_TEXTURE_2D, 0, format, GL_FLOAT, out);
    glBindTexture(GL_TEXTURE_2D, 0);
    glPixelStorei(GL_PACK_ALIGNMENT, pack);
}

/* An RSM of size x size texels read back from gim__gl_rsm's RGBA32F textures as the twins'
   gim_rsm_data (area from normal.w, valid from position.w); free it with gltest_rsm_free. */
static GIM__UNUSED gim_rsm_data gltest_rsm_read(GLuint position, GLuint normal, GLuint flux, uint32_t size) {
    size_t n = (size_t)size * size, t;
    float *x4 = (float *)malloc(n * 16), *n4 = (float *)malloc(n * 16), *f4 = (float *)malloc(n * 16);
    gim_rsm_data d;
    memset(&d, 0, sizeof d);
    d.width = d.height = size;
    d.position = (float *)malloc(n * 12); d.normal = (float *)malloc(n * 12); d.flux = (float *)malloc(n * 12);
    d.area = (float *)malloc(n * 4); d.valid = (float *)malloc(n * 4);
    gltest_read_texture(position, GL_RGBA, x4);
    gltest_read_texture(normal, GL_RGBA, n4);
    gltest_read_texture(flux, GL_RGBA, f4);
    for (t = 0; t < n; ++t) {
        memcpy((float *)d.position + t * 3, x4 + t * 4, 12);
        memcpy((float *)d.normal + t * 3, n4 + t * 4, 12);
        memcpy((float *)d.flux + t * 3, f4 + t * 4, 12);
        ((float *)d.area)[t] = n4[t * 4 + 3];
        ((float *)d.valid)[t] = x4[t * 4 + 3];
    }
    free(x4); free(n4); free(f4);
    return d;
}

static GIM__UNUSED void gltest_rsm_free(gim_rsm_data *d) {
    free((void *)d->position); free((void *)d->normal); free((void *)d->flux); free((void *)d->area);
    free((void *)d->valid);
}

#ifndef GIMANY_EXTERNAL_GL
/* A context with the counting allocator and the log catcher, and the GL state it started
   with, for tests of single passes. */
typedef struct gltest_fixture {
    test_alloc_stats stats;
    test_log log;
    gim_env env;
    gim_context *ctx;
    gim__gl_state before;
} gltest_fixture;

/* Model matrices for the scenes of the tests (column-major, as gimany's). */
static GIM__UNUSED gim_mat4 translate(float x, float y, float z) {
    gim_mat4 m = gim_mat4_identity();
    m.m[12] = x; m.m[13] = y; m.m[14] = z;
    return m;
}
static GIM__UNUSED gim_mat4 scale3(float x, float y, float z) {
    gim_mat4 m = gim_mat4_identity();
    m.m[0] = x; m.m[5] = y; m.m[10] = z;
    return m;
}
static GIM__UNUSED gim_mat4 rotate_y(float a) {
    gim_mat4 m = gim_mat4_identity();
    m.m[0] = cosf(a); m.m[8] = sinf(a); m.m[2] = -sinf(a); m.m[10] = cosf(a);
    return m;
}

static GIM__UNUSED void gltest_fixture_begin(gltest_fixture *f) {
    gim_desc d;
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env = f->env = test_env(&f->stats, &f->log);
    assert_int_equal(gim_create(&d, &f->ctx), GIM_OK);
    gim__gl_state_save(&f->ctx->gl, &f->before);
}
/* After every pass: the whole state list as it was (gltest_runtime checks it item by item). */
static GIM__UNUSED void gltest_state_unchanged(gltest_fixture *f) {
    gim__gl_state now;
    gim__gl_state_save(&f->ctx->gl, &now);
    assert_memory_equal(&f->before, &now, sizeof now);
}
static GIM__UNUSED void gltest_fixture_end(gltest_fixture *f) {
    gim_destroy(f->ctx);
    assert_int_equal(f->stats.live, 0);
    assert_int_equal(f->log.errors, 0);
}
#endif

/* First line of every GL test: a current context with no pending errors, or FAIL (skip only
   with GIMANY_SKIP_GL=1). */
#define GLTEST_BEGIN()                                                                          \
    do {                                                                                        \
        if (!gltest_init()) {                                                                   \
            const char *skip_ = getenv("GIMANY_SKIP_GL");                                       \
            if (skip_ && strcmp(skip_, "1") == 0) { print_message("GL skipped: %s\n", gltest.why); skip(); } \
            fail_msg("no GL 4.3 context: %s (set GIMANY_SKIP_GL=1 to skip GL tests)", gltest.why); \
        }                                                                                       \
        gltest_reset_errors();                                                                  \
    } while (0)

/* Last line of every GL test. */
#define GLTEST_END() assert_int_equal(gltest_errors(), 0)

#endif
