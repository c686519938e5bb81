/* Helpers of the command-line tests (cli_*.c): run a program and capture what it prints, read
   files and PNGs back. Include after <cmocka.h>; everything here is static. Needs
   _POSIX_C_SOURCE for popen and -isystem /usr/include/stb (Debian's libstb-dev). */
#ifndef GIMANY_CLIUTIL_H
#define GIMANY_CLIUTIL_H
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>

#define CLI_PI 3.14159265358979323846
#if defined(__GNUC__) || defined(__clang__)
#define CLI_FN static __attribute__((unused))
#else
#define CLI_FN static
#endif

/* stb_image: the implementation comes from scene/scene.cpp (tinygltf) when the test links
   scene.o; a test without it defines CLI_STB_IMAGE_IMPLEMENTATION first. */
#ifdef CLI_STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#endif
#include <stb_image.h>

/* Runs cmd through the shell with stderr joined to stdout; *out gets what it printed (malloc'ed,
   NUL-terminated). Returns the exit status, or -1 when it did not exit normally. */
CLI_FN int cli_run(const char *cmd, char **out) {
    char full[4096], buf[1024];
    size_t len = 0, cap = 4096, n;
    int st;
    FILE *p;
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    *out = (char *)malloc(cap);
    if (!*out) return -1;
    (*out)[0] = 0;
    p = popen(full, "r");
    if (!p) return -1;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) {
        if (len + n + 1 > cap) {
            char *q;
            while (len + n + 1 > cap) cap *= 2;
            q = (char *)realloc(*out, cap);
            if (!q) break;
            *out = q;
        }
        memcpy(*out + len, buf, n);
        len += n;
        (*out)[len] = 0;
    }
    st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Each of count bad option strings given to bin (with no display: option errors need no
   window) must fail with exit status 2 and one line that starts with "name: ". */
CLI_FN void cli_expect_bad_options(const char *bin, const char *name, const char *const *bad, size_t count) {
    size_t k, n = strlen(name);
    for (k = 0; k < count; ++k) {
        char cmd[512], *out = NULL;
        int rc;
        snprintf(cmd, sizeof cmd, "DISPLAY= %s %s", bin, bad[k]);
        rc = cli_run(cmd, &out);
        print_message("%s -> %d: %s", bad[k], rc, out);
        assert_int_equal(rc, 2);
        assert_true(strncmp(out, name, n) == 0 && out[n] == ':' && out[n + 1] == ' ');
        assert_true(strchr(out, '\n') == out + strlen(out) - 1);
        free(out);
    }
}

CLI_FN int cli_exists(const char *path) {
    struct stat s;
    return stat(path, &s) == 0;
}

/* The whole file, NUL-terminated (malloc'ed), or NULL. */
CLI_FN char *cli_read_file(const char *path) {
    FILE *f = fopen(path, "rb");
    char *s;
    long n;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    s = (char *)malloc((size_t)(n > 0 ? n : 0) + 1);
    if (s) s[fread(s, 1, (size_t)(n > 0 ? n : 0), f)] = 0;
    fclose(f);
    return s;
}

/* A PNG as 8-bit RGB (malloc'ed) or NULL. */
CLI_FN unsigned char *cli_read_png(const char *path, uint32_t *w, uint32_t *h) {
    int x = 0, y = 0, c = 0;
    unsigned char *px = stbi_load(path, &x, &y, &c, 3);
    unsigned char *copy;
    if (!px) return NULL;
    copy = (unsigned char *)malloc((size_t)x * y * 3);
    if (copy) memcpy(copy, px, (size_t)x * y * 3);
    stbi_image_free(px);
    *w = (uint32_t)x;
    *h = (uint32_t)y;
    return copy;
}

/* Mean of every 8-bit value of an RGB image. */
CLI_FN double cli_png_mean(const unsigned char *rgb, uint32_t w, uint32_t h) {
    double s = 0.0;
    size_t i;
    for (i = 0; i < (size_t)w * h * 3; ++i) s += rgb[i];
    return s / ((double)w * h * 3);
}

#endif
