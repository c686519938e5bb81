/* build/gimany-demo from the outside, as a user runs it: the files it writes and what they hold
   (the PFM rows in order, 0 where no geometry, the direct light against its closed form), the
   methods, the statistics, and one clear line with a non-zero exit for bad input. Runs the
   binary named by DEMO_BIN (built by the Makefile before this test); needs a GL 4.3 context
   through EGL like the GL tests (llvmpipe is enough). */
#define _POSIX_C_SOURCE 200809L /* popen */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <time.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <cmocka.h>
#include "scene.h"
#include "cliutil.h"

#ifndef DEMO_BIN
#define DEMO_BIN "build/gimany-demo"
#endif
#define OUT "build/cli_demo"
#define CORNELL_GLTF "../shared/scenes/cornell_box/CornellBox.gltf"

/* Runs the demo with args into dir; returns its exit status, output in *out (free it). */
static int demo(const char *args, const char *dir, char **out) {
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "rm -rf %s && %s %s --out %s", dir, DEMO_BIN, args, dir);
    return cli_run(cmd, out);
}

/* The PFM at dir/name, checked w x h, finite and non-negative; caller frees. */
static float *read_image(const char *dir, const char *name, uint32_t w, uint32_t h) {
    char path[512], err[256];
    float *rgb = NULL;
    uint32_t iw = 0, ih = 0, i;
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (scene_read_pfm(path, &rgb, &iw, &ih, err, sizeof err) != 0) fail_msg("%s", err);
    assert_int_equal(iw, w);
    assert_int_equal(ih, h);
    for (i = 0; i < w * h * 3; ++i) assert_true(isfinite(rgb[i]) && rgb[i] >= 0.0f);
    return rgb;
}

static double pixel_sum(const float *rgb, uint32_t w, uint32_t x, uint32_t y) {
    const float *p = rgb + ((size_t)y * w + x) * 3;
    return (double)p[0] + p[1] + p[2];
}

/* Mean of the rgb sums over rows [y0, y1). */
static double rows_mean(const float *rgb, uint32_t w, uint32_t y0, uint32_t y1) {
    double s = 0.0;
    uint32_t x, y;
    for (y = y0; y < y1; ++y)
        for (x = 0; x < w; ++x) s += pixel_sum(rgb, w, x, y);
    return s / ((double)(y1 - y0) * w);
}

/* The default run on the built-in Cornell box: the four files, sane images in the right row
   order, the stats. */
static void cornell_default(void **state) {
    char *out = NULL, *js;
    float *ind, *dir;
    double top, bottom, any = 0.0;
    uint32_t i;
    (void)state;
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 2", OUT "/a", &out), 0);
    assert_non_null(strstr(out, "proxy_lights"));   /* the table */
    free(out);
    assert_true(cli_exists(OUT "/a/final.png") && cli_exists(OUT "/a/direct.pfm"));
    ind = read_image(OUT "/a", "indirect.pfm", 64, 48);
    dir = read_image(OUT "/a", "direct.pfm", 64, 48);
    for (i = 0; i < 64 * 48 * 3; ++i) any += ind[i];
    assert_true(any > 0.0);
    /* the spot hangs under the ceiling pointing down: the floor (bottom rows, top row first)
       gets direct light, the ceiling none; the ceiling still gets indirect light */
    top = rows_mean(dir, 64, 0, 4);
    bottom = rows_mean(dir, 64, 44, 48);
    print_message("direct: top rows %.4f, bottom rows %.4f; indirect top rows %.4f\n", top, bottom, rows_mean(ind, 64, 0, 4));
    assert_true(top == 0.0 && bottom > 0.01);
    assert_true(rows_mean(ind, 64, 0, 4) > 0.0);
    free(ind);
    free(dir);
    js = cli_read_file(OUT "/a/stats.json");
    assert_non_null(js);
    assert_non_null(strstr(js, "\"method\": \"brsm\""));
    assert_non_null(strstr(js, "\"renderer\": \""));
    assert_non_null(strstr(js, "\"proxy_lights\": "));
    assert_non_null(strstr(js, "\"shade\": "));
    assert_non_null(strstr(js, "\"direct\": "));
    assert_non_null(strstr(js, "\"frame_ms\": "));
    assert_non_null(strstr(js, "\"triangles\": 30"));
    assert_non_null(strstr(js, "\"vals\": 2048"));
    assert_non_null(strstr(js, "\"frames\": 2"));
    assert_non_null(strstr(js, "\"pass_timing\": \"cpu")); /* the default: glFinish per pass, CPU clock */
    free(js);
    /* deterministic: the same command gives the same files, bit for bit */
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 2", OUT "/a2", &out), 0);
    free(out);
    {
        static const char *files[] = {"indirect.pfm", "direct.pfm", "final.png"};
        for (i = 0; i < 3; ++i) {
            char cmd[300], *c1 = NULL;
            int rc;
            snprintf(cmd, sizeof cmd, "cmp " OUT "/a/%s " OUT "/a2/%s", files[i], files[i]);
            rc = cli_run(cmd, &c1);
            if (rc != 0) fail_msg("%s differs between two runs: %s", files[i], c1);
            free(c1);
        }
    }
    /* stats.json: equal but for its three timing lines (the README says so) */
    {
        char *a = cli_read_file(OUT "/a/stats.json"), *b = cli_read_file(OUT "/a2/stats.json");
        char *pa, *pb, *la, *lb;
        int timing = 0;
        assert_true(a && b);
        for (la = strtok_r(a, "\n", &pa), lb = strtok_r(b, "\n", &pb); la || lb;
             la = strtok_r(NULL, "\n", &pa), lb = strtok_r(NULL, "\n", &pb)) {
            assert_true(la && lb);
            if (!strncmp(la, "  \"pass_ms\"", 11) || !strncmp(la, "  \"gimany_frame_ms\"", 19) ||
                !strncmp(la, "  \"frame_ms\"", 12)) {
                assert_int_equal(strncmp(la, lb, 12), 0);
                timing++;
                continue;
            }
            if (strcmp(la, lb)) fail_msg("stats.json differs outside the timings: '%s' against '%s'", la, lb);
        }
        assert_int_equal(timing, 3);
        free(a);
        free(b);
    }
    /* the PNG is not black */
    {
        uint32_t w, h;
        unsigned char *png = cli_read_png(OUT "/a/final.png", &w, &h);
        assert_non_null(png);
        assert_int_equal(w, 64);
        assert_int_equal(h, 48);
        assert_true(cli_png_mean(png, w, h) > 10.0);
        free(png);
    }
}

/* A camera far in front of the open box: the corners see nothing, so both images are exactly
   0 there (indirect.pfm carries gimany's output only where its G-buffer has a surface). */
static void sky_is_zero(void **state) {
    char *out = NULL;
    float *ind, *dir;
    static const uint32_t corners[4][2] = {{0, 0}, {63, 0}, {0, 47}, {63, 47}};
    uint32_t k, x, y, zero = 0;
    (void)state;
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 1 --rsm 64 --vals 256 --camera 0.278,0.27,3,0.278,0.27,-0.28,30", OUT "/b", &out), 0);
    free(out);
    ind = read_image(OUT "/b", "indirect.pfm", 64, 48);
    dir = read_image(OUT "/b", "direct.pfm", 64, 48);
    for (k = 0; k < 4; ++k) {
        assert_true(pixel_sum(ind, 64, corners[k][0], corners[k][1]) == 0.0);
        assert_true(pixel_sum(dir, 64, corners[k][0], corners[k][1]) == 0.0);
    }
    assert_true(pixel_sum(ind, 64, 32, 24) > 0.0);   /* the back wall in the middle */
    /* where the indirect image is 0 the direct one is too (the same empty pixels) and vice versa
       the box's inside is never exactly 0 indirect */
    for (y = 0; y < 48; ++y)
        for (x = 0; x < 64; ++x)
            if (pixel_sum(ind, 64, x, y) == 0.0) { zero++; assert_true(pixel_sum(dir, 64, x, y) == 0.0); }
    print_message("pixels with no surface: %u of %u\n", zero, 64 * 48);
    assert_true(zero > 64 * 48 / 4 && zero < 64 * 48);
    free(ind);
    free(dir);
}

/* Values of two demo runs' 32x24 indirect images that differ: base alone into OUT/dir_a, base
   and extra into OUT/dir_b. */
static uint32_t option_changes(const char *base, const char *extra, const char *dir_a, const char *dir_b) {
    char *out = NULL, args[512], da[128], db[128];
    float *a, *b;
    uint32_t i, differ = 0;
    snprintf(da, sizeof da, OUT "/%s", dir_a);
    snprintf(db, sizeof db, OUT "/%s", dir_b);
    snprintf(args, sizeof args, "%s %s", base, extra);
    assert_int_equal(demo(base, da, &out), 0);
    free(out);
    assert_int_equal(demo(args, db, &out), 0);
    free(out);
    a = read_image(da, "indirect.pfm", 32, 24);
    b = read_image(db, "indirect.pfm", 32, 24);
    for (i = 0; i < 32 * 24 * 3; ++i) differ += a[i] != b[i];
    free(a);
    free(b);
    return differ;
}

/* Options reach the frame: each changes the image of the same draw (frame 1 of the same
   settings) against its default: one cache per pixel against 16 (--neighbours), clustered
   with 4 x 4 subsets against every VPL at every pixel (--interleave; the default at 24 rows),
   SSVP's two bounces
   with 16 second-bounce VPLs against 256 (--second-bounce-vpls), and from the clusters' maps
   against the default, by rays (--second-bounce-maps). */
static void options_reach_the_frame(void **state) {
    static const char *const cases[][4] = {
        {"--scene cornell --size 32x24 --frames 1 --rsm 32 --vals 64", "--neighbours 1", "n16", "n1"},
        {"--scene cornell --size 32x24 --frames 1 --rsm 32 --method clustered --vpls 256 --clusters 4", "--interleave 4",
         "k1", "k4"},
        {"--scene cornell --size 32x24 --frames 1 --rsm 32 --method ssvp --vpls 256 --bounces 2",
         "--second-bounce-vpls 16", "s256", "s16"},
        {"--scene cornell --size 32x24 --frames 1 --rsm 32 --method ssvp --vpls 256 --bounces 2",
         "--second-bounce-maps", "srays", "smaps"},
    };
    size_t k;
    (void)state;
    for (k = 0; k < sizeof cases / sizeof cases[0]; ++k) {
        uint32_t differ = option_changes(cases[k][0], cases[k][1], cases[k][2], cases[k][3]);
        print_message("%s against the default: %u of %u values differ\n", cases[k][1], differ, 32 * 24 * 3);
        assert_true(differ > 32 * 24);
    }
}

/* The direct light against its closed form: a spot of our own at p = (0.12, 0.5, -0.12) (away
   from the blocks) pointing down, and a camera at p looking straight down: the middle pixels see
   the white floor under it lit at normal incidence from d = 0.5 m, L = rho / pi I / d^2. A
   second spot with the same axis but a 10 degree cone, seen from the side of its cone, lights
   nothing outside it. */
static void direct_closed_form(void **state) {
    char *out = NULL, err[256];
    float *dir;
    scene s;
    double expect[3];
    int c;
    uint32_t x, y;
    (void)state;
    assert_int_equal(scene_builtin("cornell", &s, err, sizeof err), 0);
    for (c = 0; c < 3; ++c) expect[c] = s.materials[0].diffuse[c] / CLI_PI * 0.5 / (0.5 * 0.5);
    scene_free(&s);
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 1 --vals 64 --spot 0.12,0.5,-0.12,0,-1,0,60,0.5 "
                          "--camera 0.12,0.5,-0.12,0.12,0,-0.12,20", OUT "/c", &out), 0);
    free(out);
    dir = read_image(OUT "/c", "direct.pfm", 64, 48);
    for (y = 22; y < 26; ++y)
        for (x = 30; x < 34; ++x)
            for (c = 0; c < 3; ++c) {
                double v = dir[((size_t)y * 64 + x) * 3 + c];
                /* 0.5%: the G-buffer albedo is 8-bit; the pixels are < 0.3 degrees off the axis */
                if (fabs(v - expect[c]) > 0.005 * expect[c]) fail_msg("pixel %u,%u channel %d: %g, expected %g", x, y, c, v, expect[c]);
            }
    free(dir);
    /* a 10 degree cone lights a disc of radius 0.5 tan(10 deg) = 8.8 cm: the image (+-8.8 cm
       across at fovy 20) is lit in the middle, dark in the corners */
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 1 --vals 64 --spot 0.12,0.5,-0.12,0,-1,0,10,0.5 "
                          "--camera 0.12,0.5,-0.12,0.12,0,-0.12,20", OUT "/c", &out), 0);
    free(out);
    dir = read_image(OUT "/c", "direct.pfm", 64, 48);
    assert_true(fabs(dir[(24 * 64 + 32) * 3] - expect[0]) < 0.005 * expect[0]);
    assert_true(pixel_sum(dir, 64, 0, 0) == 0.0 && pixel_sum(dir, 64, 63, 47) == 0.0);
    free(dir);
}

/* The glossy lobe of the direct light: a grey plane (baseColor 0.5, metallic 0, roughness 0.5:
   rho_g = F0 = 0.04, rho_d = 0.5 (1 - F0) = 0.48 (the base gets what the specular layer leaves),
   k = 2 / 0.25^2 - 2 = 30, scene/scene.cpp's mapping) under
   a spot of I = 1 at height 1, seen from the spot: the mirror direction is the view direction, so
   L = (rho_d / pi + rho_g (k + 2) / (2 pi)) I / d^2; with --no-glossy only rho_d / pi I / d^2. */
static const char glossy_plane[] = "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1,\"material\":0}]}],\"materials\":[{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.5,0.5,1],\"metallicFactor\":0,\"roughnessFactor\":0.5}}],\"buffers\":[{\"byteLength\":60,\"uri\":\"data:application/octet-stream;base64,AACAvwAAAAAAAIC/AACAvwAAAAAAAIA/AACAPwAAAAAAAIA/AACAPwAAAAAAAIC/AAABAAIAAAACAAMA\"}],\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48},{\"buffer\":0,\"byteOffset\":48,\"byteLength\":12}],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\",\"min\":[-1,0,-1],\"max\":[1,0,1]},{\"bufferView\":1,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"}]}";
static void direct_glossy(void **state) {
    static const char *variants[2] = {"", " --no-glossy"};
    double rho_d = floor(0.5 * 0.96 * 255.0 + 0.5) / 255.0;   /* the G-buffer albedo is RGBA8 */
    int v;
    FILE *f;
    (void)state;
    mkdir("build", 0777);
    mkdir(OUT, 0777);
    f = fopen(OUT "/glossy.gltf", "w");
    assert_non_null(f);
    fputs(glossy_plane, f);
    fclose(f);
    for (v = 0; v < 2; ++v) {
        char args[512], *out = NULL;
        float *dir;
        double expect = (rho_d / CLI_PI + (v == 0 ? 0.04 * 32.0 / (2.0 * CLI_PI) : 0.0)) * 1.0, got;
        snprintf(args, sizeof args, "--scene " OUT "/glossy.gltf --size 64x48 --frames 1 --rsm 64 --vals 64 "
                                    "--spot 0,1,0,0,-1,0,60,1 --camera 0,1,0,0,0,0,20%s", variants[v]);
        assert_int_equal(demo(args, OUT "/gl", &out), 0);
        free(out);
        dir = read_image(OUT "/gl", "direct.pfm", 64, 48);
        got = dir[(24 * 64 + 32) * 3 + 1];
        print_message("glossy plane%s: direct %.5f, expected %.5f\n", variants[v], got, expect);
        assert_true(fabs(got - expect) < 0.005 * expect);
        free(dir);
    }
}

/* FULL and none run; none has no indirect light; --no-glossy is taken. */
static void methods(void **state) {
    char *out = NULL, *js;
    float *ind;
    uint32_t i;
    double sum = 0.0;
    (void)state;
    assert_int_equal(demo("--scene cornell --size 64x48 --frames 2 --method full --rsm 16", OUT "/d", &out), 0);
    free(out);
    js = cli_read_file(OUT "/d/stats.json");
    assert_non_null(js);
    assert_non_null(strstr(js, "\"method\": \"full\""));
    assert_non_null(strstr(js, "\"vals\": 256"));       /* FULL: every texel of the 16^2 RSM */
    assert_non_null(strstr(js, "\"ism\": false"));
    free(js);
    ind = read_image(OUT "/d", "indirect.pfm", 64, 48);
    for (i = 0; i < 64 * 48 * 3; ++i) sum += ind[i];
    assert_true(sum > 0.0);
    free(ind);
    /* RSM gather: the baseline, lit where the others are */
    assert_int_equal(demo("--scene cornell --size 32x24 --frames 1 --method gather --rsm 16", OUT "/g", &out), 0);
    free(out);
    js = cli_read_file(OUT "/g/stats.json");
    assert_non_null(js);
    assert_non_null(strstr(js, "\"method\": \"gather\""));
    free(js);
    ind = read_image(OUT "/g", "indirect.pfm", 32, 24);
    sum = 0.0;
    for (i = 0; i < 32 * 24 * 3; ++i) { assert_true(isfinite(ind[i]) && ind[i] >= 0.0f); sum += ind[i]; }
    assert_true(sum > 0.0);
    free(ind);
    assert_int_equal(demo("--scene cornell --size 32x24 --frames 1 --method none --no-glossy", OUT "/e", &out), 0);
    free(out);
    ind = read_image(OUT "/e", "indirect.pfm", 32, 24);
    for (i = 0; i < 32 * 24 * 3; ++i) assert_true(ind[i] == 0.0f);
    free(ind);
    js = cli_read_file(OUT "/e/stats.json");
    assert_non_null(strstr(js, "\"caches\": 0"));
    free(js);
}

/* Bad input: one line on stderr naming the problem, a non-zero exit, no output folder. */
static void bad_input(void **state) {
    static const char *bad[][2] = {
        {"--bogus", "--bogus"},
        {"--size 12", "--size"},
        {"--size 0x10", "--size"},
        {"--size 100000x10", "--size"},
        {"--vals 12abc", "--vals"},
        {"--rsm 3", "--rsm"},
        {"--frames 0", "--frames"},
        {"--view-samples -4", "--view-samples"},
        {"--neighbours 0", "--neighbours"},
        {"--neighbours 17", "--neighbours"},
        {"--method clustered --interleave 0", "--interleave"},
        {"--method clustered --interleave 33", "--interleave"},
        {"--method ssvp --second-bounce-vpls 0", "--second-bounce-vpls"},
        {"--method nope", "--method"},
        {"--bounces 2", "--bounces 2 needs --method clustered or ssvp"},
        {"--method gather --bounces 2", "--bounces 2 needs"},
        {"--method ssvp --bounces 3", "--bounces"},
        {"--method clustered --clusters 300", "--clusters"},
        {"--method clustered --vpls 40000", "--vpls"},
        {"--no-glossy=1", "--no-glossy"},
        {"--timing gpu", "--timing"},
        {"--scene /nonexistent/x.gltf", "/nonexistent/x.gltf"},
        {"--scene nosuch", "nosuch"},
        {"--scene tests/cli/cli_demo.c", "tests/cli/cli_demo.c"},
        {"--scene build/cli_demo/broken.gltf", "broken.gltf"},
    };
    size_t k;
    FILE *f;
    (void)state;
    mkdir("build", 0777);
    mkdir(OUT, 0777);
    f = fopen(OUT "/broken.gltf", "w");   /* truncated JSON */
    assert_non_null(f);
    fputs("{\"asset\": {\"version\": \"2.0\"}, \"meshes\": [", f);
    fclose(f);
    for (k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        char *out = NULL;
        int rc = demo(bad[k][0], OUT "/bad", &out);
        print_message("%s -> %d: %s", bad[k][0], rc, out);
        assert_int_not_equal(rc, 0);
        assert_true(strncmp(out, "gimany-demo: ", 13) == 0);
        assert_true(strchr(out, '\n') == out + strlen(out) - 1);   /* exactly one line */
        assert_non_null(strstr(out, bad[k][1]));
        assert_false(cli_exists(OUT "/bad/stats.json"));
        free(out);
    }
}

/* Settings a frame cannot finish in reasonable time or memory are refused up front from the
   cost model (examples/options.h demo_cost), one line naming --allow-slow, in seconds. */
static void too_slow(void **state) {
    static const char *slow[] = {
        "--vals 1048576",                     /* 3330 caches x 2^20 VALs */
        "--method full --rsm 1024",           /* 3330 caches x 2^20 texels */
        "--method gather --rsm 8192",         /* 3.3 GiB of RSM */
        "--method gather --size 8192x8192",   /* 1.7e10 gather terms */
        "--size 16384x16384",                 /* 35 GiB of frame */
    };
    size_t k;
    char *out = NULL;
    (void)state;
    for (k = 0; k < sizeof slow / sizeof slow[0]; ++k) {
        struct timespec t0, t1;
        double s;
        int rc;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        rc = demo(slow[k], OUT "/slow", &out);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
        print_message("%s -> %d in %.1f s: %s", slow[k], rc, s, out);
        assert_int_equal(rc, 1);
        assert_true(strncmp(out, "gimany-demo: ", 13) == 0);
        assert_true(strchr(out, '\n') == out + strlen(out) - 1);
        assert_non_null(strstr(out, "pass --allow-slow"));
        assert_false(cli_exists(OUT "/slow/stats.json"));
        assert_true(s < 60.0);
        free(out);
    }
    /* the flag is accepted (a cheap frame runs as before) */
    assert_int_equal(demo("--scene cornell --size 16x8 --frames 1 --rsm 16 --vals 64 --allow-slow", OUT "/slow", &out), 0);
    free(out);
}

/* A glTF that loads but has no triangle: black images, a warning, exit 0. */
static void no_triangles(void **state) {
    char *out = NULL;
    float *ind;
    uint32_t i;
    FILE *f;
    (void)state;
    mkdir("build", 0777);
    mkdir(OUT, 0777);
    f = fopen(OUT "/empty.gltf", "w");
    assert_non_null(f);
    fputs("{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": []}], \"scene\": 0}", f);
    fclose(f);
    assert_int_equal(demo("--scene " OUT "/empty.gltf --size 16x8", OUT "/f", &out), 0);
    assert_non_null(strstr(out, "warning"));
    free(out);
    ind = read_image(OUT "/f", "indirect.pfm", 16, 8);
    for (i = 0; i < 16 * 8 * 3; ++i) assert_true(ind[i] == 0.0f);
    free(ind);
    assert_true(cli_exists(OUT "/f/final.png") && cli_exists(OUT "/f/stats.json"));
}

/* Debian's assimp-testmodels broken glTF files (tools/install-deps.sh examples): each one
   either renders (exit 0; black with a warning when nothing in it is a triangle) or fails with
   one line and exit 1; never a crash. */
static void hostile_gltf(void **state) {
    static const char *files[] = {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", "IndexOutOfRange/IndexOutOfRange.gltf",
                                  "MissingBin/BoxTextured.gltf", "RecursiveNodes/RecursiveNodes.gltf",
                                  "wrongTypes/badArray.gltf", "TestNoRootNode/SceneWithoutNodes.gltf",
                                  "IncorrectVertexArrays/Cube.gltf", "BoxBadNormals-glTF-Binary/BoxBadNormals.glb"};
    const char *dir = "/usr/share/assimp/models/glTF2/";
    size_t k;
    (void)state;
    if (!cli_exists(dir)) {
        print_message("%s absent: skipped\n", dir);
        skip();
    }
    for (k = 0; k < sizeof files / sizeof files[0]; ++k) {
        char args[512], *out = NULL;
        int rc;
        snprintf(args, sizeof args, "--scene %s%s --size 16x8 --frames 1 --rsm 16 --vals 64", dir, files[k]);
        rc = demo(args, OUT "/h", &out);
        print_message("%s -> %d: %s", files[k], rc, out);
        assert_true(rc == 0 || rc == 1);
        if (rc == 1) {
            assert_true(strncmp(out, "gimany-demo: ", 13) == 0);
            assert_true(strchr(out, '\n') == out + strlen(out) - 1);
        } else {
            assert_true(cli_exists(OUT "/h/final.png"));
            free(read_image(OUT "/h", "indirect.pfm", 16, 8));
        }
        free(out);
    }
}

/* The measured Cornell box as glTF, when ../shared is there. */
static void cornell_gltf(void **state) {
    char *out = NULL;
    float *ind;
    double sum = 0.0;
    uint32_t i;
    (void)state;
    if (!cli_exists(CORNELL_GLTF)) {
        print_message("%s absent: skipped\n", CORNELL_GLTF);
        skip();
    }
    assert_int_equal(demo("--scene " CORNELL_GLTF " --size 64x48 --frames 1 --rsm 64 --vals 256", OUT "/g", &out), 0);
    free(out);
    ind = read_image(OUT "/g", "indirect.pfm", 64, 48);
    for (i = 0; i < 64 * 48 * 3; ++i) sum += ind[i];
    assert_true(sum > 0.0);
    free(ind);
}

/* A run that fails after its options parsed leaves no output of an earlier run in its folder
   (a stale image would pass for its own). */
static void stale_outputs_removed(void **state) {
    static const char *names[] = {"final.png", "indirect.pfm", "direct.pfm", "stats.json"};
    char cmd[512], path[256], *out = NULL;
    size_t k;
    (void)state;
    mkdir("build", 0777);
    mkdir(OUT, 0777);
    mkdir(OUT "/stale", 0777);
    for (k = 0; k < 4; ++k) {
        FILE *f;
        snprintf(path, sizeof path, OUT "/stale/%s", names[k]);
        f = fopen(path, "w");
        assert_non_null(f);
        fputs("stale", f);
        fclose(f);
    }
    snprintf(cmd, sizeof cmd, "%s --scene /nonexistent/x.gltf --out " OUT "/stale", DEMO_BIN);
    assert_int_equal(cli_run(cmd, &out), 1);
    free(out);
    for (k = 0; k < 4; ++k) {
        snprintf(path, sizeof path, OUT "/stale/%s", names[k]);
        assert_false(cli_exists(path));
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cornell_default), cmocka_unit_test(sky_is_zero),     cmocka_unit_test(options_reach_the_frame),
        cmocka_unit_test(direct_closed_form), cmocka_unit_test(direct_glossy), cmocka_unit_test(methods),
        cmocka_unit_test(bad_input),       cmocka_unit_test(no_triangles),    cmocka_unit_test(hostile_gltf),
        cmocka_unit_test(cornell_gltf),    cmocka_unit_test(too_slow),        cmocka_unit_test(stale_outputs_removed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
