/* build/gimany-minimal (examples/minimal.c) under Xvfb: --frames N --pfm FILE renders and exits
   0; the PFM holds gimany's indirect light at the window's size, every value finite and >= 0,
   its mean > 1e-4 and the one the program prints; the window is not black. Bad options fail
   with one line and exit 2 before any window opens. Skipped when xvfb-run is absent.
   Checked to fail: with the spot's intensity set to 0 in the example the indirect is black
   (mean 0) and `frames` fails. */
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
#include "cliutil.h"

#ifndef MINIMAL_BIN
#define MINIMAL_BIN "build/gimany-minimal"
#endif
#define OUT "build/cli_minimal"

static int have_xvfb(void) {
    char *out = NULL;
    int rc = cli_run("command -v xvfb-run", &out);
    free(out);
    return rc == 0;
}

/* A little-endian PFM ("PF", w h, -1.0, rgb floats): its pixels, or NULL. */
static float *read_pfm(const char *path, int *w, int *h) {
    FILE *f = fopen(path, "rb");
    float *px = NULL;
    double scale = 0.0;
    char magic[3] = {0};
    if (!f) return NULL;
    if (fscanf(f, "%2s %d %d %lf", magic, w, h, &scale) == 4 && !strcmp(magic, "PF") && scale < 0.0 && *w > 0 &&
        *h > 0 && fgetc(f) == '\n' && (px = (float *)malloc((size_t)*w * *h * 12)) != NULL &&
        fread(px, 12, (size_t)*w * *h, f) != (size_t)*w * *h) {
        free(px);
        px = NULL;
    }
    fclose(f);
    return px;
}

static void frames(void **state) {
    char *out = NULL;
    const char *at;
    float *px;
    int w = 0, h = 0;
    size_t k, n;
    double printed = -1.0, window = -1.0, sum = 0.0;
    (void)state;
    if (!have_xvfb()) {
        print_message("xvfb-run absent: skipped (tools/install-deps.sh examples)\n");
        skip();
    }
    assert_int_equal(cli_run("rm -rf " OUT " && mkdir -p " OUT, &out), 0);
    free(out);
    if (cli_run("xvfb-run -a -s '-screen 0 320x240x24' " MINIMAL_BIN " --size 96x72 --frames 3 --pfm " OUT "/indirect.pfm", &out) != 0)
        fail_msg("minimal: %s", out);
    at = strstr(out, "indirect mean ");
    assert_non_null(at);
    assert_int_equal(sscanf(at, "indirect mean %lf", &printed), 1);
    at = strstr(out, "window mean ");
    assert_non_null(at);
    assert_int_equal(sscanf(at, "window mean %lf", &window), 1);
    free(out);
    px = read_pfm(OUT "/indirect.pfm", &w, &h);
    assert_non_null(px);
    assert_int_equal(w, 96);
    assert_int_equal(h, 72);
    n = (size_t)w * h * 3;
    for (k = 0; k < n; ++k) {
        assert_true(isfinite(px[k]) && px[k] >= 0.0f);
        sum += px[k];
    }
    free(px);
    print_message("indirect mean %g (printed %g), window mean %.3f\n", sum / (double)n, printed, window);
    assert_true(sum / (double)n > 1e-4);
    assert_true(fabs(sum / (double)n - printed) <= 1e-4 * printed);
    assert_true(window > 0.04);
}

/* Option errors need no window: one line, exit 2. */
static void bad_options(void **state) {
    static const char *const bad[] = {"--bogus", "--frames x", "--pfm a.pfm", "--size 3x3", "--frames"};
    (void)state;
    cli_expect_bad_options(MINIMAL_BIN, "gimany-minimal", bad, sizeof bad / sizeof bad[0]);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(frames), cmocka_unit_test(bad_options)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
