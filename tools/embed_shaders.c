/* embed_shaders OUT.h FILE... : writes the GLSL files as NUL-terminated byte arrays
   (no string-literal length limits), one `gim__shader_<name>_<stage>` each, plus a table.
   embed_shaders --expand FILE : writes FILE as it is embedded to stdout (for glslangValidator).
   A line `#include "NAME"` in a shader is replaced by the file NAME beside it (shaders/
   common.glsl: the helpers several shaders share), one level deep. #line directives around it
   keep the compiler's line numbers what they were: the shader's lines one past the file's (the
   runtime prepends #version), the k-th included file's lines reported as k * 10000 + its line.
   Output is deterministic: same files, same bytes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define INCLUDED_LINE0 10000 /* the k-th included file's line n is reported as k INCLUDED_LINE0 + n */

typedef struct text { char *p; size_t n, cap; } text;

static int put(text *t, const char *s, size_t n) {
    if (t->n + n + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 4096;
        char *p;
        while (cap < t->n + n + 1) cap *= 2;
        p = (char *)realloc(t->p, cap);
        if (!p) { fprintf(stderr, "embed_shaders: out of memory\n"); return 0; }
        t->p = p;
        t->cap = cap;
    }
    memcpy(t->p + t->n, s, n);
    t->n += n;
    t->p[t->n] = 0;
    return 1;
}

/* The whole file, carriage returns dropped. */
static int load(const char *path, text *t) {
    FILE *f = fopen(path, "rb");
    int c;
    if (!f) { perror(path); return 0; }
    while ((c = fgetc(f)) != EOF) {
        char ch = (char)c;
        if (c != '\r' && !put(t, &ch, 1)) { fclose(f); return 0; }
    }
    fclose(f);
    return put(t, "", 0);
}

/* NAME of a line `#include "NAME"` (spaces allowed around the tokens), or 0. */
static int include_name(const char *line, size_t n, char *name, size_t cap) {
    size_t i = 0, k = 0;
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= n || line[i++] != '#') return 0;
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (n - i < 7 || strncmp(line + i, "include", 7) != 0) return 0;
    i += 7;
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= n || line[i++] != '"') return 0;
    while (i < n && line[i] != '"' && k + 1 < cap) name[k++] = line[i++];
    if (i >= n || line[i++] != '"' || k == 0) return 0;
    while (i < n && (line[i] == ' ' || line[i] == '\t')) ++i;
    name[k] = 0;
    return i == n;
}

static int has_include(const text *t) {
    size_t at = 0;
    char name[256];
    while (at < t->n) {
        const char *s = t->p + at, *nl = memchr(s, '\n', t->n - at);
        size_t len = nl ? (size_t)(nl - s) : t->n - at;
        if (include_name(s, len, name, sizeof name)) return 1;
        at += len + 1;
    }
    return 0;
}

/* The shader at path as it is embedded: its #include lines expanded. */
static int expand(const char *path, text *out) {
    text src = {0, 0, 0};
    size_t at = 0;
    long line = 0, included = 0;
    int ok = load(path, &src);
    while (ok && at < src.n) {
        const char *s = src.p + at, *nl = memchr(s, '\n', src.n - at);
        size_t len = nl ? (size_t)(nl - s) : src.n - at;
        char name[256], inc[1024], dir[64];
        ++line;
        at += len + (nl ? 1u : 0u);
        if (!include_name(s, len, name, sizeof name)) {
            ok = put(out, s, len + (nl ? 1u : 0u));
            continue;
        }
        {
            const char *slash = strrchr(path, '/');
            text t = {0, 0, 0};
            int dlen = slash ? (int)(slash - path + 1) : 0;
            snprintf(inc, sizeof inc, "%.*s%s", dlen, path, name);
            ok = load(inc, &t);
            if (ok && has_include(&t)) {
                fprintf(stderr, "%s: includes are one level deep (%s includes a file)\n", path, inc);
                ok = 0;
            }
            snprintf(dir, sizeof dir, "#line %ld\n", ++included * INCLUDED_LINE0 + 1);
            ok = ok && put(out, dir, strlen(dir)) && put(out, t.p, t.n) &&
                 (t.n == 0 || t.p[t.n - 1] == '\n' || put(out, "\n", 1));
            /* the next line of the shader is file line `line + 1`, reported one past it */
            snprintf(dir, sizeof dir, "#line %ld\n", line + 2);
            ok = ok && put(out, dir, strlen(dir));
            free(t.p);
        }
    }
    free(src.p);
    return ok;
}

static void ident(const char *path, char *out, size_t cap) {
    const char *base = strrchr(path, '/');
    size_t n = 0;
    base = base ? base + 1 : path;
    for (; *base && n + 1 < cap; ++base)
        out[n++] = (char)((*base >= 'a' && *base <= 'z') || (*base >= 'A' && *base <= 'Z') ||
                                  (*base >= '0' && *base <= '9') ? *base : '_');
    out[n] = 0;
}

int main(int argc, char **argv) {
    FILE *o;
    int i;
    if (argc == 3 && strcmp(argv[1], "--expand") == 0) {
        text t = {0, 0, 0};
        int ok = expand(argv[2], &t) && fwrite(t.p, 1, t.n, stdout) == t.n;
        free(t.p);
        return ok ? 0 : 1;
    }
    if (argc < 2) { fprintf(stderr, "usage: embed_shaders OUT.h FILE... | embed_shaders --expand FILE\n"); return 2; }
    o = fopen(argv[1], "wb");
    if (!o) { perror(argv[1]); return 1; }
    fprintf(o, "/* shaders_embedded.h - generated from shaders/ by `make shaders`; do not edit. */\n"
               "#ifndef GIMANY_SHADERS_EMBEDDED_H\n#define GIMANY_SHADERS_EMBEDDED_H\n\n");
    for (i = 2; i < argc; ++i) {
        char name[256];
        text t = {0, 0, 0};
        size_t k;
        int col = 0;
        if (!expand(argv[i], &t)) { free(t.p); fclose(o); remove(argv[1]); return 1; }   /* no half header */
        ident(argv[i], name, sizeof name);
        fprintf(o, "/* %s */\nstatic const unsigned char gim__shader_%s[] = {\n", argv[i], name);
        for (k = 0; k < t.n; ++k) {
            fprintf(o, "%s%d,", col == 0 ? "    " : "", (unsigned char)t.p[k]);
            if (++col == 24) { fputc('\n', o); col = 0; }
        }
        fprintf(o, "%s0};\n\n", col == 0 ? "    " : "");
        free(t.p);
    }
    fprintf(o, "/* name -> source, for lookups by file name */\n"
               "typedef struct gim__embedded_shader { const char *name; const unsigned char *source; } gim__embedded_shader;\n"
               "static const gim__embedded_shader gim__embedded_shaders[] = {\n");
    for (i = 2; i < argc; ++i) {
        char name[256];
        const char *base = strrchr(argv[i], '/');
        ident(argv[i], name, sizeof name);
        fprintf(o, "    {\"%s\", gim__shader_%s},\n", base ? base + 1 : argv[i], name);
    }
    fprintf(o, "    {0, 0}};\n\n#endif\n");
    return fclose(o) == 0 ? 0 : 1;
}
