/* GIMANY_EXTERNAL_GL: a host with its own loader (here libGL's prototypes from glcorearb.h)
   gets gim* calling its gl* functions, no get_proc_address needed. */
#define GIMANY_EXTERNAL_GL
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

static void external_loader(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    GLuint map = 0, column = 0, row = 0;
    float m[3 * 5] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
    double col[15], rw[3];
    int i;
    (void)state;
    GLTEST_BEGIN();
    memset(&d, 0, sizeof d);
    d.env = test_env(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    assert_true(ctx->gl.DispatchCompute == (void (*)(GLuint, GLuint, GLuint))glDispatchCompute);
    glGenBuffers(1, &map);
    glGenBuffers(1, &column);
    glGenBuffers(1, &row);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, map);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof m, m, GL_STATIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, column);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof col, NULL, GL_DYNAMIC_COPY);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, row);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof rw, NULL, GL_DYNAMIC_COPY);
    assert_int_equal(gim__gl_importance_cumsum(ctx, map, column, row, 3, 5, 2), GIM_OK);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof rw, rw);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, column);
    glGetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof col, col);
    /* column x sums 1+x, 4+x, ...: rows 0..4 of column 0 are 1, 5, 12, 22, 35 */
    assert_true(col[0] == 1 && col[3] == 5 && col[6] == 12 && col[9] == 22 && col[12] == 35);
    for (i = 0; i < 3; ++i) assert_true(col[12 + i] == 35.0 + 5.0 * i);
    assert_true(rw[0] == 35 && rw[1] == 75 && rw[2] == 120);
    glDeleteBuffers(1, &map);
    glDeleteBuffers(1, &column);
    glDeleteBuffers(1, &row);
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    assert_int_equal(log.errors, 0);
    GLTEST_END();
}

/* Without get_proc_address the optional GL 4.5 glClipControl is not loaded, so gimany cannot
   set the clip state: a host's non-default glClipControl is refused (it would flip or blacken
   the image), the default one passes that check. */
static void external_clip_control(void **state) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_frame fr;
    gim_context *ctx = NULL;
    (void)state;
    GLTEST_BEGIN();
    memset(&d, 0, sizeof d);
    d.env = test_env(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    assert_null(ctx->gl.ClipControl);
    memset(&fr, 0, sizeof fr);
    glClipControl(GL_UPPER_LEFT, GL_ZERO_TO_ONE);
    assert_int_equal(gim_update(ctx, &fr), GIM_ERROR_UNSUPPORTED);
    assert_non_null(strstr(log.last, "glClipControl"));
    glClipControl(GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE);
    assert_int_equal(gim_update(ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);   /* past it: the zero view */
    assert_int_equal(log.errors, 2);
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(external_loader), cmocka_unit_test(external_clip_control)};
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
