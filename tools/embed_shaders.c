/* embed_shaders OUT.h FILE... : writes the GLSL files as NUL-terminated byte arrays
   (no string-literal length limits), one `gim__shader_<name>_<stage>` each, plus a table.
   Output is deterministic: same files, same bytes. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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
    if (argc < 2) { fprintf(stderr, "usage: embed_shaders OUT.h FILE...\n"); return 2; }
    o = fopen(argv[1], "wb");
    if (!o) { perror(argv[1]); return 1; }
    fprintf(o, "/* shaders_embedded.h - generated from shaders/ by `make shaders`; do not edit. */\n"
               "#ifndef GIMANY_SHADERS_EMBEDDED_H\n#define GIMANY_SHADERS_EMBEDDED_H\n\n");
    for (i = 2; i < argc; ++i) {
        char name[256];
        FILE *f = fopen(argv[i], "rb");
        int c, col = 0;
        if (!f) { perror(argv[i]); fclose(o); return 1; }
        ident(argv[i], name, sizeof name);
        fprintf(o, "/* %s */\nstatic const unsigned char gim__shader_%s[] = {\n", argv[i], name);
        while ((c = fgetc(f)) != EOF) {
            if (c == '\r') continue;
            fprintf(o, "%s%d,", col == 0 ? "    " : "", c);
            if (++col == 24) { fputc('\n', o); col = 0; }
        }
        fprintf(o, "%s0};\n\n", col == 0 ? "    " : "");
        fclose(f);
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
