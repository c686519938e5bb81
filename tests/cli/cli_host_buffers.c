/* build/gimany-host-buffers (examples/host_buffers.c) under Xvfb: gimany driven from the host's
   own vertex / index / light buffers and G-buffer renders --frames N, writes the screenshot at
   the window's size, and gimany's indirect light (printed as "indirect mean X") is finite and
   not black; a light gimany refuses fails gim_update with one line and exit 1; bad options
   fail with one line and exit 2 before any window opens. Skipped when xvfb-run is absent.
   Checked to fail: with the light buffer's intensity set to 0 in the example the indirect mean
   is 0 and `screenshot` fails. */
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

#ifndef HOST_BIN
#define HOST_BIN "build/gimany-host-buffers"
#endif
#define OUT "build/cli_host_buffers"

static int have_xvfb(void) {
    char *out = NULL;
    int rc = cli_run("command -v xvfb-run", &out);
    free(out);
    return rc == 0;
}

static void screenshot(void **state) {
    char *out = NULL;
    const char *at;
    unsigned char *shot;
    uint32_t w = 0, h = 0;
    double mean = -1.0;
    (void)state;
    if (!have_xvfb()) {
        print_message("xvfb-run absent: skipped (tools/install-deps.sh examples)\n");
        skip();
    }
    assert_int_equal(cli_run("rm -rf " OUT " && mkdir -p " OUT, &out), 0);
    free(out);
    if (cli_run("xvfb-run -a -s '-screen 0 320x240x24' " HOST_BIN " --size 96x72 --frames 3 --screenshot " OUT "/shot.png", &out) != 0)
        fail_msg("host-buffers: %s", out);
    at = strstr(out, "indirect mean ");
    assert_non_null(at);
    assert_int_equal(sscanf(at, "indirect mean %lf", &mean), 1);
    print_message("indirect mean %g\n", mean);
    free(out);
    assert_true(isfinite(mean));
    assert_true(mean > 1e-4);
    shot = cli_read_png(OUT "/shot.png", &w, &h);
    assert_non_null(shot);
    assert_int_equal(w, 96);
    assert_int_equal(h, 72);
    print_message("screenshot mean %.1f of 255\n", cli_png_mean(shot, w, h));
    assert_true(cli_png_mean(shot, w, h) > 10.0);
    free(shot);
}

/* A light gimany refuses (RSM side above GL_MAX_TEXTURE_SIZE, read from the light buffer at
   gim_update): one line naming the call and gimany's reason, exit 1. */
static void refused_light(void **state) {
    char *out = NULL;
    int rc;
    (void)state;
    if (!have_xvfb()) skip();
    rc = cli_run("xvfb-run -a -s '-screen 0 320x240x24' " HOST_BIN " --size 32x24 --frames 1 --rsm 1000000", &out);
    print_message("--rsm 1000000 -> %d: %s", rc, out);
    assert_int_equal(rc, 1);
    assert_true(strncmp(out, "gimany-host-buffers: gim_update", 31) == 0);
    assert_non_null(strstr(out, "rsm_size"));
    assert_true(strchr(out, '\n') == out + strlen(out) - 1);
    free(out);
}

/* Option errors need no window: one line, exit 2. */
static void bad_options(void **state) {
    static const char *const bad[] = {"--bogus", "--frames x", "--screenshot a.png", "--size 3x3", "--frames", "--rsm 0"};
    (void)state;
    cli_expect_bad_options(HOST_BIN, "gimany-host-buffers", bad, sizeof bad / sizeof bad[0]);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(screenshot), cmocka_unit_test(refused_light),
                                         cmocka_unit_test(bad_options)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
