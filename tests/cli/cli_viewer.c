/* build/gimany-viewer under Xvfb (xvfb-run, Debian's xvfb): --frames N --screenshot FILE
   renders and exits; the screenshot is not black and is the picture build/gimany-demo makes
   with the same options (both use examples/display.h); bad options fail with one line before
   any window opens. Skipped when xvfb-run is absent. */
#define _POSIX_C_SOURCE 200809L /* popen */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>
#define CLI_STB_IMAGE_IMPLEMENTATION
#include "cliutil.h"

#ifndef VIEWER_BIN
#define VIEWER_BIN "build/gimany-viewer"
#endif
#ifndef DEMO_BIN
#define DEMO_BIN "build/gimany-demo"
#endif
#define OUT "build/cli_viewer"

static int have_xvfb(void) {
    char *out = NULL;
    int rc = cli_run("command -v xvfb-run", &out);
    free(out);
    return rc == 0;
}

static void screenshot(void **state) {
    char *out = NULL;
    unsigned char *shot, *ref;
    uint32_t w = 0, h = 0, rw = 0, rh = 0;
    size_t i, differ = 0;
    double diff = 0.0;
    (void)state;
    if (!have_xvfb()) {
        print_message("xvfb-run absent: skipped (tools/install-deps.sh examples)\n");
        skip();
    }
    assert_int_equal(cli_run("rm -rf " OUT " && mkdir -p " OUT, &out), 0);
    free(out);
    if (cli_run("xvfb-run -a -s '-screen 0 320x240x24' " VIEWER_BIN " --scene cornell --size 96x72 --frames 3 --rsm 64 --vals 512 --screenshot " OUT
                "/shot.png",
                &out) != 0)
        fail_msg("viewer: %s", out);
    free(out);
    shot = cli_read_png(OUT "/shot.png", &w, &h);
    assert_non_null(shot);
    assert_int_equal(w, 96);
    assert_int_equal(h, 72);
    print_message("screenshot mean %.1f of 255\n", cli_png_mean(shot, w, h));
    assert_true(cli_png_mean(shot, w, h) > 10.0);
    /* the demo's final.png of the same frames */
    if (cli_run(DEMO_BIN " --scene cornell --size 96x72 --frames 3 --rsm 64 --vals 512 --out " OUT "/demo", &out) != 0) fail_msg("demo: %s", out);
    free(out);
    ref = cli_read_png(OUT "/demo/final.png", &rw, &rh);
    assert_non_null(ref);
    assert_int_equal(rw, w);
    assert_int_equal(rh, h);
    for (i = 0; i < (size_t)w * h * 3; ++i) {
        int d = abs((int)shot[i] - (int)ref[i]);
        diff += d;
        differ += d > 2;
    }
    print_message("viewer vs demo: mean |difference| %.3f, %zu values differ by more than 2\n", diff / ((double)w * h * 3), differ);
    assert_true(diff / ((double)w * h * 3) < 0.5);
    assert_true(differ < (size_t)w * h * 3 / 100);
    free(shot);
    free(ref);
}

/* Option errors need no window: one line, exit 2. */
static void bad_options(void **state) {
    static const char *const bad[] = {"--bogus", "--vals x", "--bounces 2", "--screenshot", "--size 3"};
    (void)state;
    cli_expect_bad_options(VIEWER_BIN, "gimany-viewer", bad, sizeof bad / sizeof bad[0]);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(screenshot), cmocka_unit_test(bad_options)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
