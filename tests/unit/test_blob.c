/* Cache blobs: bit-exact round trip; every single-byte corruption and every truncation is
   rejected; hand-made blobs with a valid checksum but bad fields are rejected; allocations. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

/* A small set with awkward but valid values (subnormal, negative zero, huge coordinates). */
static void make_set(gim_cache_set *set, gim_cache *caches, uint32_t count) {
    uint32_t i;
    memset(set, 0, sizeof *set);
    for (i = 0; i < count; ++i) {
        gim_vec3 n = gim_v3_normalize(gim_v3((float)test_rand01() - 0.5f, (float)test_rand01() - 0.5f, (float)test_rand01() - 0.5f));
        caches[i].position[0] = (float)(test_rand01() * 2e5 - 1e5);
        caches[i].position[1] = i == 1 ? -0.0f : (float)test_rand01();
        caches[i].position[2] = i == 2 ? 1e-40f : (float)(test_rand01() * 1e-3);
        caches[i].area = i == 0 ? 0.0f : (float)test_rand01() * 3.0f;
        caches[i].normal[0] = n.x; caches[i].normal[1] = n.y; caches[i].normal[2] = n.z;
        caches[i].reflectance = i == 3 ? 1.0f : (float)test_rand01();
    }
    set->caches = caches;
    set->count = count;
    set->d_eps = 0.03125f;
    set->theta_eps = 0.5235988f;
    set->report.triangles_used = 100; set->report.triangles_degenerate = 2; set->report.triangles_nonfinite = 3;
    set->report.triangles_duplicate = 4; set->report.voxels = 55; set->report.caches_before_merge = count + 9;
    set->report.caches_snapped = 7; set->report.surface_area = 12.345678901234;
}

static void crc_known_value(void **state) {
    (void)state;
    assert_int_equal(gim__crc32((const unsigned char *)"123456789", 9), 0xCBF43926u); /* the CRC-32 check value */
    assert_int_equal(gim__crc32((const unsigned char *)"", 0), 0u);
}

static void round_trip_bit_exact(void **state) {
    enum { C = 37 };
    gim_cache caches[C];
    gim_cache_set set, back;
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    size_t size;
    unsigned char *blob, *blob2;
    (void)state;
    make_set(&set, caches, C);
    size = gim_cache_blob_size(&set);
    assert_int_equal(size, 88 + 32 * C + 4);
    blob = (unsigned char *)malloc(size + 1);
    blob2 = (unsigned char *)malloc(size);
    assert_int_equal(gim_cache_blob_write(&set, blob, size), GIM_OK);
    assert_memory_equal(blob, "GIMCACHE", 8);
    assert_int_equal(blob[8], 1); /* version 1, little-endian */
    assert_int_equal(blob[20], C); assert_int_equal(blob[21], 0);
    assert_int_equal(gim_cache_blob_read(blob, size, &back, env), GIM_OK);
    assert_int_equal(back.count, C);
    assert_memory_equal(back.caches, caches, sizeof caches); /* every bit, -0 and subnormals too */
    assert_true(memcmp(&back.d_eps, &set.d_eps, 4) == 0 && memcmp(&back.theta_eps, &set.theta_eps, 4) == 0);
    assert_memory_equal(&back.report, &set.report, sizeof set.report);
    assert_ptr_equal(back.env.allocator.user_data, &st);
    assert_int_equal(st.live, 1);
    /* written again: the same bytes */
    assert_int_equal(gim_cache_blob_write(&back, blob2, size), GIM_OK);
    assert_memory_equal(blob, blob2, size);
    gim_cache_set_free(&back);
    assert_int_equal(st.live, 0);
    assert_null(back.caches);
    assert_int_equal(back.count, 0);
    /* one trailing byte is a size mismatch */
    blob[size] = 0;
    assert_int_equal(gim_cache_blob_read(blob, size + 1, &back, env), GIM_ERROR_CORRUPT_DATA);
    assert_non_null(strstr(lg.last, "size mismatch"));
    /* an empty set round-trips too */
    set.count = 0; set.caches = NULL;
    assert_int_equal(gim_cache_blob_size(&set), 92);
    assert_int_equal(gim_cache_blob_write(&set, blob, 92), GIM_OK);
    assert_int_equal(gim_cache_blob_read(blob, 92, &back, env), GIM_OK);
    assert_int_equal(back.count, 0);
    assert_null(back.caches);
    assert_int_equal(st.live, 0);
    assert_int_equal(lg.errors, 1);
    free(blob); free(blob2);
}

/* Every byte, three ways (low bit, high bit, all bits), and every truncation: rejected with
   CORRUPT_DATA, a message, nothing allocated left over, out untouched. */
static void every_corruption_and_truncation(void **state) {
    enum { C = 5 };
    gim_cache caches[C];
    gim_cache_set set, back;
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    static const unsigned char flips[3] = {0x01, 0x80, 0xff};
    unsigned char blob[88 + 32 * C + 4], bad[sizeof blob];
    size_t i, f, len;
    (void)state;
    make_set(&set, caches, C);
    assert_int_equal(gim_cache_blob_write(&set, blob, sizeof blob), GIM_OK);
    for (i = 0; i < sizeof blob; ++i)
        for (f = 0; f < 3; ++f) {
            int e0 = lg.errors;
            memcpy(bad, blob, sizeof blob);
            bad[i] ^= flips[f];
            memset(&back, 0x5a, sizeof back);
            if (gim_cache_blob_read(bad, sizeof bad, &back, env) != GIM_ERROR_CORRUPT_DATA) {
                print_error("byte %zu ^ 0x%02x accepted\n", i, flips[f]);
                fail();
            }
            assert_int_equal(lg.errors, e0 + 1);
            assert_int_equal(st.live, 0);
            assert_int_equal(back.count, 0x5a5a5a5au);
        }
    for (len = 0; len < sizeof blob; ++len) {
        unsigned char *cut = (unsigned char *)malloc(len ? len : 1); /* exact size: ASan sees any overread */
        memcpy(cut, blob, len);
        if (gim_cache_blob_read(cut, len, &back, env) != GIM_ERROR_CORRUPT_DATA) {
            print_error("truncation to %zu accepted\n", len);
            fail();
        }
        free(cut);
    }
    assert_int_equal(st.live, 0);
    assert_int_equal(gim_cache_blob_read(blob, sizeof blob, &back, env), GIM_OK);
    gim_cache_set_free(&back);
    assert_int_equal(st.live, 0);
}

/* Fields that pass the checksum (recomputed, as a buggy or hostile writer would) but are
   invalid: each one rejected with its own message. */
static void reseal(unsigned char *b, size_t size) { gim__put32(b + size - 4, gim__crc32(b, size - 4)); }

static void valid_checksum_invalid_fields(void **state) {
    enum { C = 3, S = 88 + 32 * C + 4 };
    gim_cache caches[C];
    gim_cache_set set, back;
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    unsigned char blob[S], bad[S];
    (void)state;
    make_set(&set, caches, C);
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_OK);
#define EXPECT_BAD(what, edit) do { memcpy(bad, blob, S); edit; reseal(bad, S); \
        assert_int_equal(gim_cache_blob_read(bad, S, &back, env), GIM_ERROR_CORRUPT_DATA); \
        if (!strstr(lg.last, what)) { print_error("'%s' not in '%s'\n", what, lg.last); fail(); } \
        assert_int_equal(st.live, 0); } while (0)
    EXPECT_BAD("magic", bad[0] = 'X');
    EXPECT_BAD("unknown version 2", gim__put32(bad + 8, 2));
    EXPECT_BAD("header size", gim__put32(bad + 12, 96));
    EXPECT_BAD("record size", gim__put32(bad + 16, 36));
    EXPECT_BAD("does not match", gim__put32(bad + 20, C + 1));                        /* count vs payload */
    EXPECT_BAD("truncated", (gim__put32(bad + 20, C + 1), gim__put64(bad + 24, 32 * (C + 1))));
    EXPECT_BAD("truncated", (gim__put32(bad + 20, 0xffffffffu), gim__put64(bad + 24, 32ull * 0xffffffffu)));
    EXPECT_BAD("does not match", gim__put64(bad + 24, 0xffffffffffffffe0ull));           /* payload would overflow */
    EXPECT_BAD("size mismatch", (gim__put32(bad + 20, C - 1), gim__put64(bad + 24, 32 * (C - 1))));
    EXPECT_BAD("reserved", bad[70] = 1);
    EXPECT_BAD("reserved", bad[87] = 1);
    EXPECT_BAD("d_eps", gim__putf(bad + 32, -1.0f));
    EXPECT_BAD("d_eps", gim__putf(bad + 32, NAN));
    EXPECT_BAD("theta_eps", gim__putf(bad + 36, 4.0f));
    EXPECT_BAD("theta_eps", gim__putf(bad + 36, INFINITY));
    EXPECT_BAD("surface area", { double x = -1.0; uint64_t u; memcpy(&u, &x, 8); gim__put64(bad + 72, u); });
    EXPECT_BAD("cache 1: position", gim__putf(bad + 88 + 32 + 4, NAN));
    EXPECT_BAD("cache 2: area", gim__putf(bad + 88 + 64 + 12, -0.5f));
    EXPECT_BAD("cache 0: area", gim__putf(bad + 88 + 12, INFINITY));
    EXPECT_BAD("cache 0: normal not finite", gim__putf(bad + 88 + 20, NAN));
    EXPECT_BAD("cache 2: normal not of unit", gim__putf(bad + 88 + 64 + 16, caches[2].normal[0] * 1.01f + 0.01f));
    EXPECT_BAD("cache 1: normal not of unit", { gim__putf(bad + 88 + 32 + 16, 0); gim__putf(bad + 88 + 32 + 20, 0); gim__putf(bad + 88 + 32 + 24, 0); });
    EXPECT_BAD("cache 1: reflectance", gim__putf(bad + 88 + 32 + 28, 1.5f));
#undef EXPECT_BAD
    /* not resealed: a payload byte, then the stored CRC itself */
    memcpy(bad, blob, S); bad[100] ^= 0x10;
    assert_int_equal(gim_cache_blob_read(bad, S, &back, env), GIM_ERROR_CORRUPT_DATA);
    assert_non_null(strstr(lg.last, "checksum mismatch"));
    memcpy(bad, blob, S); bad[S - 1] ^= 0x10;
    assert_int_equal(gim_cache_blob_read(bad, S, &back, env), GIM_ERROR_CORRUPT_DATA);
    assert_non_null(strstr(lg.last, "checksum mismatch"));
    assert_int_equal(st.live, 0);
}

/* The writer refuses what the reader would reject, and bad arguments are errors. */
static void writer_and_argument_errors(void **state) {
    enum { C = 4, S = 88 + 32 * C + 4 };
    gim_cache caches[C];
    gim_cache_set set, back;
    test_alloc_stats st;
    test_log lg;
    unsigned char blob[S];
    long k;
    (void)state;
    make_set(&set, caches, C);
    set.env = test_env(&st, &lg);
    assert_int_equal(gim_cache_blob_size(NULL), 0);
    assert_int_equal(gim_cache_blob_write(NULL, blob, S), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_blob_write(&set, NULL, S), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_blob_write(&set, blob, S - 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "capacity"));
    caches[2].area = -1.0f;
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(lg.last, "cache 2: area"));
    caches[2].area = 1.0f; caches[3].normal[1] += 0.1f;
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_ERROR_INVALID_ARGUMENT);
    caches[3].normal[1] -= 0.1f; set.theta_eps = -1.0f;
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_ERROR_INVALID_ARGUMENT);
    set.theta_eps = 0.5f; set.caches = NULL;
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_ERROR_INVALID_ARGUMENT);
    set.caches = caches;
    assert_int_equal(lg.errors, 6);
    assert_int_equal(gim_cache_blob_write(&set, blob, S), GIM_OK);
    assert_int_equal(gim_cache_blob_read(NULL, S, &back, set.env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_cache_blob_read(blob, S, NULL, set.env), GIM_ERROR_INVALID_ARGUMENT);
    /* out of memory on read: an error, nothing leaked, out untouched */
    st.fail_after = 0;
    memset(&back, 0x5a, sizeof back);
    assert_int_equal(gim_cache_blob_read(blob, S, &back, set.env), GIM_ERROR_OUT_OF_MEMORY);
    assert_int_equal(back.count, 0x5a5a5a5au);
    assert_int_equal(st.live, 0);
    st.fail_after = -1;
    k = st.allocs;
    assert_int_equal(gim_cache_blob_read(blob, S, &back, set.env), GIM_OK);
    assert_int_equal(st.allocs - k, 1);
    gim_cache_set_free(&back);
    gim_cache_set_free(NULL);
    assert_int_equal(st.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(crc_known_value),
        cmocka_unit_test(round_trip_bit_exact),
        cmocka_unit_test(every_corruption_and_truncation),
        cmocka_unit_test(valid_checksum_invalid_fields),
        cmocka_unit_test(writer_and_argument_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
