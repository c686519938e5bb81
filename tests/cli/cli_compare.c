/* gimany-compare: the metrics on images with known answers, and the command line (two PFMs,
   --json, --diff, bad input). */
#define _POSIX_C_SOURCE 200809L
#define COMPARE_NO_MAIN
#include "testutil.h"
#include "scene.h"
#include "../tools/compare.c"
#include <sys/stat.h>

#ifndef COMPARE_BIN
#define COMPARE_BIN "build/gimany-compare"
#endif

static void known_answers(void **state) {
    enum { W = 10, H = 10 };
    float a[W * H * 3], b[W * H * 3], pp[W * H];
    compare_result r;
    int i;
    (void)state;
    for (i = 0; i < W * H * 3; ++i) b[i] = 1.0f;
    memcpy(a, b, sizeof a);
    assert_int_equal(compare_images(a, b, W, H, &r, pp), 0);
    assert_true(r.rel_mae == 0.0 && r.rmse == 0.0 && r.p99 == 0.0 && r.max == 0.0);
    assert_int_equal(r.covered, W * H);
    /* a = 1.1 b everywhere: rel_mae 0.1, rmse 0.1, p99 0.1 */
    for (i = 0; i < W * H * 3; ++i) a[i] = 1.1f;
    assert_int_equal(compare_images(a, b, W, H, &r, pp), 0);
    assert_true(fabs(r.rel_mae - 0.1) < 1e-6 && fabs(r.rmse - 0.1) < 1e-6 && fabs(r.p99 - 0.1) < 1e-6);
    /* one pixel off by 3 in every channel: rel_mae 9 / 300, rmse sqrt(27 / 300), max 3, p99 0 */
    memcpy(a, b, sizeof a);
    a[0] = a[1] = a[2] = 4.0f;
    assert_int_equal(compare_images(a, b, W, H, &r, pp), 0);
    assert_true(fabs(r.rel_mae - 0.03) < 1e-9);
    assert_true(fabs(r.rmse - sqrt(27.0 / 300.0)) < 1e-9);
    assert_true(r.max == 3.0 && r.p99 == 0.0 && pp[0] == 3.0f && pp[1] == 0.0f);
    /* uncovered pixels (both 0) do not count; a pixel dark in b but lit in a does */
    for (i = 0; i < 50 * 3; ++i) a[i] = b[i] = 0.0f;
    a[0] = 2.0f;
    assert_int_equal(compare_images(a, b, W, H, &r, NULL), 0);
    assert_int_equal(r.covered, 51);
    assert_true(fabs(r.rel_mae - 2.0 / 150.0) < 1e-9);
    /* b all zero: relative error infinite when a is not */
    memset(b, 0, sizeof b);
    assert_int_equal(compare_images(a, b, W, H, &r, NULL), 0);
    assert_true(isinf(r.rel_mae));
}

static int run(const char *args, char *out, size_t cap) {
    char cmd[1024];
    FILE *p;
    size_t n;
    int status;
    snprintf(cmd, sizeof cmd, "%s %s 2>&1", COMPARE_BIN, args);
    p = popen(cmd, "r");
    assert_non_null(p);
    n = fread(out, 1, cap - 1, p);
    out[n] = 0;
    status = pclose(p);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void command_line(void **state) {
    enum { W = 8, H = 6 };
    float a[W * H * 3], b[W * H * 3], c[4 * 4 * 3];
    char err[256], out[2048];
    struct stat st;
    int i;
    (void)state;
    for (i = 0; i < W * H * 3; ++i) { b[i] = 0.5f; a[i] = 0.6f; }
    memset(c, 0, sizeof c);
    assert_int_equal(scene_make_dir("build/cli_compare", err, sizeof err), 0);
    assert_int_equal(scene_write_pfm("build/cli_compare/a.pfm", a, W, H, err, sizeof err), 0);
    assert_int_equal(scene_write_pfm("build/cli_compare/b.pfm", b, W, H, err, sizeof err), 0);
    assert_int_equal(scene_write_pfm("build/cli_compare/c.pfm", c, 4, 4, err, sizeof err), 0);
    remove("build/cli_compare/diff.png");
    assert_int_equal(run("build/cli_compare/a.pfm build/cli_compare/b.pfm --json --diff build/cli_compare/diff.png", out,
                         sizeof out), 0);
    assert_non_null(strstr(out, "\"rel_mae\": 0.2"));
    assert_non_null(strstr(out, "\"covered\": 48"));
    assert_int_equal(stat("build/cli_compare/diff.png", &st), 0);
    assert_true(st.st_size > 0);
    assert_int_equal(run("build/cli_compare/a.pfm build/cli_compare/b.pfm", out, sizeof out), 0);
    assert_non_null(strstr(out, "rel_mae 0.2000"));
    /* bad input: one line, non-zero exit */
    assert_int_equal(run("build/cli_compare/a.pfm build/cli_compare/c.pfm", out, sizeof out), 1);
    assert_non_null(strstr(out, "sizes differ"));
    assert_int_equal(run("build/cli_compare/a.pfm build/cli_compare/missing.pfm", out, sizeof out), 1);
    assert_int_equal(run("build/cli_compare/a.pfm", out, sizeof out), 1);
    assert_int_equal(run("build/cli_compare/a.pfm build/cli_compare/b.pfm --bogus", out, sizeof out), 1);
    assert_non_null(strstr(out, "unknown option"));
    assert_int_equal(run("tests/cli/cli_compare.c build/cli_compare/b.pfm", out, sizeof out), 1);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(known_answers),
        cmocka_unit_test(command_line),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
