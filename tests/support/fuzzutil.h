/* Shared libFuzzer helpers: read the input as a stream of values, zero-filled past its end; an
   allocator that counts live blocks (gim_env's, for the leak checks); a check that traps. */
#ifndef GIMANY_FUZZUTIL_H
#define GIMANY_FUZZUTIL_H
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct fz_alloc { long live; } fz_alloc;
static inline void *fz_malloc(size_t n, void *u) { ((fz_alloc *)u)->live++; return malloc(n); }
static inline void fz_free(void *p, void *u) { ((fz_alloc *)u)->live--; free(p); }

#define FZ_CHECK(x) do { if (!(x)) __builtin_trap(); } while (0)

typedef struct reader { const uint8_t *p; size_t n; } reader;

static inline uint32_t take_u32(reader *r) {
    uint32_t v = 0;
    size_t k = r->n < 4 ? r->n : 4;
    memcpy(&v, r->p, k);
    r->p += k; r->n -= k;
    return v;
}
static inline void take_bytes(reader *r, void *out, size_t size) {
    size_t k = r->n < size ? r->n : size;
    memset(out, 0, size);
    memcpy(out, r->p, k);
    r->p += k; r->n -= k;
}
#endif
