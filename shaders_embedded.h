/* shaders_embedded.h - generated from shaders/ by `make shaders`; do not edit. */
#ifndef GIMANY_SHADERS_EMBEDDED_H
#define GIMANY_SHADERS_EMBEDDED_H

/* name -> source, for lookups by file name */
typedef struct gim__embedded_shader { const char *name; const unsigned char *source; } gim__embedded_shader;
static const gim__embedded_shader gim__embedded_shaders[] = {
    {0, 0}};

#endif
