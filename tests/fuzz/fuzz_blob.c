/* libFuzzer target for gim_cache_blob_read: any input is either rejected cleanly or is a
   canonical blob (written back byte for byte) whose caches pass the reader's own checks.
   Under ASan this proves the reader never reads outside the input. The first input byte is a
   mode, the rest the blob: with an odd mode the blob first gets a correct CRC in its last 4
   bytes, so the fuzzer also reaches the field checks behind the checksum. */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include <stdlib.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    gim_env env;
    gim_cache_set set;
    gim_result r;
    unsigned char *in, mode;
    if (size == 0) return 0;
    mode = data[0];
    ++data; --size;
    in = (unsigned char *)malloc(size ? size : 1); /* exact size: ASan sees an overread */
    if (!in) return 0;
    if (size) memcpy(in, data, size);
    if ((mode & 1u) && size >= 4) gim__put32(in + size - 4, gim__crc32(in, size - 4));
    memset(&env, 0, sizeof env);
    r = gim_cache_blob_read(in, size, &set, env);
    if (r == GIM_OK) {
        size_t n = gim_cache_blob_size(&set);
        unsigned char *again = (unsigned char *)malloc(n ? n : 1);
        uint32_t i;
        if (!again || n != size) abort();
        for (i = 0; i < set.count; ++i)
            if (gim__blob_check_cache(&set.caches[i])) abort();
        if (gim_cache_blob_write(&set, again, n) != GIM_OK || memcmp(again, in, n) != 0) abort();
        free(again);
        gim_cache_set_free(&set);
    } else if (r != GIM_ERROR_CORRUPT_DATA && r != GIM_ERROR_OUT_OF_MEMORY) {
        abort();
    }
    free(in);
    return 0;
}
