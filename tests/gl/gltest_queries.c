/* Per-frame overheads of gim_update with timing 0, as a release build runs it (NDEBUG, so no
   GIMANY_DEBUG error checks): every method asks GL at most GLTEST_MAX_QUERIES questions a frame
   (GLTEST_MAX_QUERIES_RESET with gim_desc.gl_state = GIM_GL_STATE_RESET; each glGet / glIs /
   glGetError / sync wait is a round trip on a threaded driver), and a
   second frame identical to the first allocates nothing through the context's allocator and
   creates, resizes or uploads no buffer or texture. The counts come from wrapping the entries
   of the context's loaded GL table. gim_prepare builds every program the frame then uses. */
#ifndef NDEBUG
#define NDEBUG 1
#endif
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 16
#define H 16
#include "framefix.h"

/* The goal is 30. The state save asks 63: 10 capabilities, 7 texture units x 2 + 4 units' 2D
   arrays, 4 draw buffers x 2, 8 SSBO and 3 image bindings, 4 buffer bindings, program, VAO,
   framebuffer, viewport, depth func, mask and range, polygon mode, active texture, provoking
   vertex, clip control; gim_update asks 1-3 more. 64-66 measured a frame (106-108 before the save
   list was trimmed to what gimany changes, 66-68 before the stencil test and sRGB left it), so
   this is the bound. */
#define GLTEST_MAX_QUERIES 66
/* GIM_GL_STATE_RESET queries nothing to save: issue #15's bound, 30 */
#define GLTEST_MAX_QUERIES_RESET 30

static long queries, uploads;   /* since the last reset */
static gim__gl real;            /* the table gimany loaded */

/* Questions to GL: each returns a value, so the driver must catch up to answer. */
static gim__GLenum GIM__APIENTRY q_GetError(void) { queries++; return real.GetError(); }
static const unsigned char *GIM__APIENTRY q_GetString(gim__GLenum n) { queries++; return real.GetString(n); }
static void GIM__APIENTRY q_GetIntegerv(gim__GLenum p, gim__GLint *d) { queries++; real.GetIntegerv(p, d); }
static void GIM__APIENTRY q_GetIntegeri_v(gim__GLenum t, gim__GLuint i, gim__GLint *d) { queries++; real.GetIntegeri_v(t, i, d); }
static void GIM__APIENTRY q_GetInteger64i_v(gim__GLenum t, gim__GLuint i, gim__GLint64 *d) { queries++; real.GetInteger64i_v(t, i, d); }
static void GIM__APIENTRY q_GetInteger64v(gim__GLenum p, gim__GLint64 *d) { queries++; real.GetInteger64v(p, d); }
static void GIM__APIENTRY q_GetBooleanv(gim__GLenum p, gim__GLboolean *d) { queries++; real.GetBooleanv(p, d); }
static void GIM__APIENTRY q_GetBooleani_v(gim__GLenum t, gim__GLuint i, gim__GLboolean *d) { queries++; real.GetBooleani_v(t, i, d); }
static void GIM__APIENTRY q_GetFloatv(gim__GLenum p, gim__GLfloat *d) { queries++; real.GetFloatv(p, d); }
static void GIM__APIENTRY q_GetDoublev(gim__GLenum p, double *d) { queries++; real.GetDoublev(p, d); }
static gim__GLboolean GIM__APIENTRY q_IsEnabled(gim__GLenum c) { queries++; return real.IsEnabled(c); }
static gim__GLboolean GIM__APIENTRY q_IsEnabledi(gim__GLenum c, gim__GLuint i) { queries++; return real.IsEnabledi(c, i); }
static gim__GLboolean GIM__APIENTRY q_IsBuffer(gim__GLuint b) { queries++; return real.IsBuffer(b); }
static gim__GLboolean GIM__APIENTRY q_IsTexture(gim__GLuint t) { queries++; return real.IsTexture(t); }
static void GIM__APIENTRY q_GetBufferParameteri64v(gim__GLenum t, gim__GLenum p, gim__GLint64 *d) { queries++; real.GetBufferParameteri64v(t, p, d); }
static void GIM__APIENTRY q_GetTexLevelParameteriv(gim__GLenum t, gim__GLint l, gim__GLenum p, gim__GLint *d) { queries++; real.GetTexLevelParameteriv(t, l, p, d); }
static void GIM__APIENTRY q_GetTexParameteriv(gim__GLenum t, gim__GLenum p, gim__GLint *d) { queries++; real.GetTexParameteriv(t, p, d); }
static void GIM__APIENTRY q_GetTextureParameteriv(gim__GLuint t, gim__GLenum p, gim__GLint *d) { queries++; real.GetTextureParameteriv(t, p, d); }
static void GIM__APIENTRY q_GetShaderiv(gim__GLuint s, gim__GLenum p, gim__GLint *d) { queries++; real.GetShaderiv(s, p, d); }
static void GIM__APIENTRY q_GetProgramiv(gim__GLuint s, gim__GLenum p, gim__GLint *d) { queries++; real.GetProgramiv(s, p, d); }
static gim__GLint GIM__APIENTRY q_GetUniformLocation(gim__GLuint p, const gim__GLchar *n) { queries++; return real.GetUniformLocation(p, n); }
static gim__GLenum GIM__APIENTRY q_CheckFramebufferStatus(gim__GLenum t) { queries++; return real.CheckFramebufferStatus(t); }
static void GIM__APIENTRY q_GetQueryObjectui64v(gim__GLuint i, gim__GLenum p, uint64_t *d) { queries++; real.GetQueryObjectui64v(i, p, d); }
static void GIM__APIENTRY q_GetBufferSubData(gim__GLenum t, gim__GLintptr o, gim__GLsizeiptr s, void *d) { queries++; real.GetBufferSubData(t, o, s, d); }
static gim__GLenum GIM__APIENTRY q_ClientWaitSync(gim__GLsync s, gim__GLbitfield f, uint64_t t) { queries++; return real.ClientWaitSync(s, f, t); }

/* Buffer and texture creation, (re)sizing and uploads. */
static void GIM__APIENTRY u_GenBuffers(gim__GLsizei n, gim__GLuint *b) { uploads++; real.GenBuffers(n, b); }
static void GIM__APIENTRY u_GenTextures(gim__GLsizei n, gim__GLuint *t) { uploads++; real.GenTextures(n, t); }
static void GIM__APIENTRY u_BufferData(gim__GLenum t, gim__GLsizeiptr s, const void *d, gim__GLenum u) { uploads++; real.BufferData(t, s, d, u); }
static void GIM__APIENTRY u_BufferSubData(gim__GLenum t, gim__GLintptr o, gim__GLsizeiptr s, const void *d) { uploads++; real.BufferSubData(t, o, s, d); }
static void GIM__APIENTRY u_TexStorage2D(gim__GLenum t, gim__GLsizei l, gim__GLenum f, gim__GLsizei w, gim__GLsizei h) { uploads++; real.TexStorage2D(t, l, f, w, h); }
static void GIM__APIENTRY u_TexStorage3D(gim__GLenum t, gim__GLsizei l, gim__GLenum f, gim__GLsizei w, gim__GLsizei h, gim__GLsizei d) { uploads++; real.TexStorage3D(t, l, f, w, h, d); }

static void wrap(gim_context *ctx) {
    gim__gl *g = &ctx->gl;
    real = *g;
#define Q(name) g->name = q_##name
    Q(GetError); Q(GetString); Q(GetIntegerv); Q(GetIntegeri_v); Q(GetInteger64i_v); Q(GetInteger64v);
    Q(GetBooleanv); Q(GetBooleani_v); Q(GetFloatv); Q(GetDoublev); Q(IsEnabled); Q(IsEnabledi); Q(IsBuffer);
    Q(IsTexture); Q(GetBufferParameteri64v); Q(GetTexLevelParameteriv); Q(GetTexParameteriv); Q(GetShaderiv);
    Q(GetProgramiv); Q(GetUniformLocation); Q(CheckFramebufferStatus); Q(GetQueryObjectui64v);
    Q(GetBufferSubData); Q(ClientWaitSync);
    if (g->GetTextureParameteriv) Q(GetTextureParameteriv);
#undef Q
#define U(name) g->name = u_##name
    U(GenBuffers); U(GenTextures); U(BufferData); U(BufferSubData); U(TexStorage2D); U(TexStorage3D);
#undef U
}

/* Frames of method m on the Cornell box: the first builds what the frame needs (programs,
   buffers); later ones are counted. mode: the context's gim_desc.gl_state. */
static void frame_overheads(gim_method m, gim_gl_state mode) {
    frame_fixture ff;
    long allocs, frame_queries[3], frame_uploads[3], frame_allocs[3];
    int i;
    GLTEST_BEGIN();
    assert_int_equal(frame_begin(&ff, NULL, 16), 0);
    frame_small(&ff, m);
    ff.fr.timing = 0;
    ff.f.ctx->gl_state = mode;   /* as gim_create sets it from gim_desc.gl_state */
    wrap(ff.f.ctx);
    for (i = 0; i < 3; ++i) {
        queries = uploads = 0;
        allocs = ff.f.stats.allocs;
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        frame_queries[i] = queries;
        frame_uploads[i] = uploads;
        frame_allocs[i] = ff.f.stats.allocs - allocs;
    }
    print_message("method %d%s: GL queries per frame %ld, %ld, %ld; buffer/texture creations and uploads %ld, %ld, %ld; "
                  "CPU allocations %ld, %ld, %ld\n", (int)m, mode == GIM_GL_STATE_RESET ? " (RESET)" : "", frame_queries[0], frame_queries[1], frame_queries[2],
                  frame_uploads[0], frame_uploads[1], frame_uploads[2], frame_allocs[0], frame_allocs[1], frame_allocs[2]);
    for (i = 1; i < 3; ++i) {
        assert_true(frame_queries[i] <= (mode == GIM_GL_STATE_RESET ? GLTEST_MAX_QUERIES_RESET : GLTEST_MAX_QUERIES));
        assert_int_equal(frame_allocs[i], 0);
        assert_int_equal(frame_uploads[i], 0);
    }
    ff.f.ctx->gl = real;
    frame_end(&ff);
    GLTEST_END();
}

static int programs_built(const gim_context *ctx) {
    int i, n = 0;
    for (i = 0; i < GIM__PROGRAM_COUNT; ++i) n += ctx->programs[i] != 0;
    return n;
}

/* gim_prepare builds every program the frame then uses: the first gim_update after it builds
   none (variant: 0 defaults, 1 visibility ISM, 2 one bounce without visibility or blur, 3 two
   bounces, 4 VPLs drawn by importance, vpl.importance: BRSM's selection, no rsm_vpls.comp; 5 a shadow map per VPL,
   SHADOW_MAPS: no ism.comp (SSVP's second bounce by rays, the default); 6 the same with the second bounce from the maps, whose hits its ISMs check). A bad frame is refused before any program is built. */
static void prepared(gim_method m, int variant) {
    frame_fixture ff;
    int before;
    GLTEST_BEGIN();
    assert_int_equal(frame_begin(&ff, NULL, 16), 0);
    frame_small(&ff, m);
    if (variant == 1) ff.fr.visibility.mode = GIM_VISIBILITY_ISM;
    if (variant == 2) { ff.fr.vpl.no_visibility = 1; ff.fr.vpl.interleave = 1; ff.fr.vpl.bounces = 1; }
    if (variant == 3) ff.fr.vpl.bounces = 2;
    if (variant == 4) ff.fr.vpl.importance = 1;
    if (variant >= 5) ff.fr.visibility.mode = GIM_VISIBILITY_SHADOW_MAPS;
    if (variant == 6) ff.fr.vpl.second_bounce = GIM_SECOND_BOUNCE_MAPS;
    ff.fr.width = 0;
    assert_int_equal(gim_prepare(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(programs_built(ff.f.ctx), 0);
    assert_int_equal(ff.f.log.errors, 1);
    ff.f.log.errors = 0;
    ff.fr.width = W;
    assert_int_equal(gim_prepare(ff.f.ctx, &ff.fr), GIM_OK);
    before = programs_built(ff.f.ctx);
    assert_true(before > 0);
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    print_message("method %d variant %d: %d programs prepared, %d after the first frame\n", (int)m, variant, before,
                  programs_built(ff.f.ctx));
    assert_int_equal(programs_built(ff.f.ctx), before);
    if (variant == 4) assert_int_equal(ff.f.ctx->programs[GIM__PROGRAM_RSM_VPLS], 0);   /* only what the frame uses */
    if (variant >= 5) {   /* the ISM program only to check the second bounce's map hits (the maps') */
        assert_true(ff.f.ctx->programs[GIM__PROGRAM_ISM_FROM_PARABOLOID] != 0);
        assert_int_equal(ff.f.ctx->programs[GIM__PROGRAM_ISM] != 0, ff.fr.method == GIM_METHOD_SSVP && variant == 6);
    }
    if (ff.fr.method == GIM_METHOD_SSVP) {   /* the second bounce's one program: the maps', or rays */
        assert_int_equal(ff.f.ctx->programs[GIM__PROGRAM_SECOND_BOUNCE_RAYS] != 0, variant != 6);
        assert_int_equal(ff.f.ctx->programs[GIM__PROGRAM_SECOND_BOUNCE] != 0, variant == 6);
    }
    frame_end(&ff);
    GLTEST_END();
}

static void prepare_every_method(void **state) {
    (void)state;
    prepared(GIM_METHOD_LIGHTSKIN_BRSM, 0);
    prepared(GIM_METHOD_LIGHTSKIN_BRSM, 1);
    prepared(GIM_METHOD_LIGHTSKIN_FULL, 0);
    prepared(GIM_METHOD_RSM_GATHER, 0);
    prepared(GIM_METHOD_CLUSTERED, 0);
    prepared(GIM_METHOD_CLUSTERED, 2);
    prepared(GIM_METHOD_SSVP, 3);
    prepared(GIM_METHOD_CLUSTERED, 1);
    prepared(GIM_METHOD_SSVP, 1);
    prepared(GIM_METHOD_CLUSTERED, 4);
    prepared(GIM_METHOD_SSVP, 4);
    prepared(GIM_METHOD_CLUSTERED, 5);
    prepared(GIM_METHOD_SSVP, 5);
    prepared(GIM_METHOD_SSVP, 6);
}

static void lightskin_brsm(void **state) { (void)state; frame_overheads(GIM_METHOD_LIGHTSKIN_BRSM, GIM_GL_STATE_RESTORE); }
static void lightskin_full(void **state) { (void)state; frame_overheads(GIM_METHOD_LIGHTSKIN_FULL, GIM_GL_STATE_RESTORE); }
static void rsm_gather(void **state) { (void)state; frame_overheads(GIM_METHOD_RSM_GATHER, GIM_GL_STATE_RESTORE); }
static void clustered(void **state) { (void)state; frame_overheads(GIM_METHOD_CLUSTERED, GIM_GL_STATE_RESTORE); }
static void ssvp(void **state) { (void)state; frame_overheads(GIM_METHOD_SSVP, GIM_GL_STATE_RESTORE); }

/* GIM_GL_STATE_RESET: every method within issue #15's 30 queries a frame */
static void reset_every_method(void **state) {
    (void)state;
    frame_overheads(GIM_METHOD_LIGHTSKIN_BRSM, GIM_GL_STATE_RESET);
    frame_overheads(GIM_METHOD_LIGHTSKIN_FULL, GIM_GL_STATE_RESET);
    frame_overheads(GIM_METHOD_RSM_GATHER, GIM_GL_STATE_RESET);
    frame_overheads(GIM_METHOD_CLUSTERED, GIM_GL_STATE_RESET);
    frame_overheads(GIM_METHOD_SSVP, GIM_GL_STATE_RESET);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lightskin_brsm), cmocka_unit_test(lightskin_full), cmocka_unit_test(rsm_gather),
        cmocka_unit_test(clustered), cmocka_unit_test(ssvp), cmocka_unit_test(prepare_every_method),
        cmocka_unit_test(reset_every_method)};
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
