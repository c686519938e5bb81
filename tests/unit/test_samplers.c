/* Samplers and math: known values, exactness up to 2^32-1, stratification, uniformity. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

static void radical_inverse_known_values(void **state) {
    (void)state;
    /* base 2: 0, 1/2, 1/4, 3/4, 1/8, 5/8 */
    assert_true(gim_van_der_corput(0) == 0.0);
    assert_true(gim_van_der_corput(1) == 0.5);
    assert_true(gim_van_der_corput(2) == 0.25);
    assert_true(gim_van_der_corput(3) == 0.75);
    assert_true(gim_van_der_corput(4) == 0.125);
    assert_true(gim_van_der_corput(5) == 0.625);
    /* base 3: 1/3, 2/3, 1/9, 4/9, 7/9 */
    assert_true(gim_radical_inverse(3, 1) == 1.0 / 3.0);
    assert_true(gim_radical_inverse(3, 2) == 2.0 / 3.0);
    assert_true(gim_radical_inverse(3, 3) == 1.0 / 9.0);
    assert_true(gim_radical_inverse(3, 4) == 4.0 / 9.0);
    assert_true(gim_radical_inverse(3, 5) == 7.0 / 9.0);
    /* base 5, index 7 = 12_5 -> 0.21_5 = 2/5 + 1/25 */
    assert_true(gim_radical_inverse(5, 7) == 11.0 / 25.0);
    /* Halton dims 0..2 use bases 2, 3, 5 */
    assert_true(gim_halton(6, 0) == gim_radical_inverse(2, 6));
    assert_true(gim_halton(6, 1) == gim_radical_inverse(3, 6));
    assert_true(gim_halton(6, 2) == gim_radical_inverse(5, 6));
    assert_int_equal(gim_prime(0), 2);
    assert_int_equal(gim_prime(9), 29);
    assert_int_equal(gim_prime(GIM_MAX_HALTON_DIMENSIONS - 1), 311);
    assert_int_equal(gim_prime(GIM_MAX_HALTON_DIMENSIONS), 0);
    /* out-of-range bases give 0, not garbage */
    assert_true(gim_radical_inverse(0, 5) == 0.0);
    assert_true(gim_radical_inverse(1, 5) == 0.0);
}

/* Exactness: the double times base^digits must be an integer whose digits, reversed, give
   the index back; any float drift would break the integer or its digits. */
static void radical_inverse_exact_at_2_32(void **state) {
    static const uint32_t idx[] = {0xffffffffu, 0xfffffffeu, 0x80000000u, 0x7fffffffu, 4000000000u, 123456789u};
    static const uint32_t bases[] = {2, 3, 5, 7, 311, 65521};
    size_t i, j;
    (void)state;
    for (i = 0; i < sizeof idx / sizeof idx[0]; ++i)
        for (j = 0; j < sizeof bases / sizeof bases[0]; ++j) {
            uint32_t b = bases[j], n = idx[i], k = 0;
            uint64_t den = 1, num;
            double u = gim_radical_inverse(b, n);
            uint32_t m = n;
            while (m) { den *= b; m /= b; ++k; }
            assert_true(u >= 0.0 && u < 1.0);
            num = (uint64_t)llround(u * (double)den); /* den < 2^53: u*den is exact */
            assert_true((double)num / (double)den == u);
            /* mirror back: reversing num's k digits must give n again */
            {
                uint64_t r = num, back = 0;
                uint32_t t, kk = 0;
                m = n;
                while (m) { ++kk; m /= b; }
                for (t = 0; t < kk; ++t) { back = back * b + r % b; r /= b; }
                assert_true(back == n);
            }
        }
    /* base 2 at the top index: 0.11..1 (32 ones) = 1 - 2^-32, exactly */
    assert_true(gim_van_der_corput(0xffffffffu) == 1.0 - 1.0 / 4294967296.0);
    assert_true(gim_radical_inverse(2, 0xffffffffu) == gim_van_der_corput(0xffffffffu));
}

static void hammersley_values(void **state) {
    float pts[16 * 3];
    int i;
    (void)state;
    assert_int_equal(gim_hammersley_points(pts, 16, 3, NULL), GIM_OK);
    for (i = 0; i < 16; ++i) {
        assert_true(pts[i * 3 + 0] == (float)i / 16.0f);
        assert_true(pts[i * 3 + 1] == (float)gim_van_der_corput((uint32_t)i));
        assert_true(pts[i * 3 + 2] == (float)gim_radical_inverse(3, (uint32_t)i));
    }
}

/* Every 2^k aligned block of base-2 points and every (1/2^a x 1/3^b) box of 2D Halton points
   holds exactly the expected count: the (0,m,2) / stratification property. */
static void stratification(void **state) {
    enum { N = 4096 };
    static float pts[N * 2];
    int cells2[64], i;
    (void)state;
    /* Hammersley in base 2 x base 2 is a (0,12,2)-net: each elementary box of area 1/N holds one */
    assert_int_equal(gim_hammersley_points(pts, N, 2, NULL), GIM_OK);
    {
        int a;
        for (a = 0; a <= 12; ++a) {
            int nx = 1 << a, ny = N / nx;
            static unsigned char seen[N];
            memset(seen, 0, sizeof seen);
            for (i = 0; i < N; ++i) {
                int cx = (int)(pts[i * 2] * (float)nx), cy = (int)(pts[i * 2 + 1] * (float)ny);
                int c = cy * nx + cx;
                assert_true(c >= 0 && c < N);
                assert_int_equal(seen[c], 0);
                seen[c] = 1;
            }
        }
    }
    /* Halton 2D: the first 2^3 * 3^2 = 72 points put one in each 1/8 x 1/9 cell */
    assert_int_equal(gim_halton_points(pts, 72, 2, 0, NULL), GIM_OK);
    {
        static unsigned char seen[72];
        memset(seen, 0, sizeof seen);
        for (i = 0; i < 72; ++i) {
            int c = (int)(pts[i * 2 + 1] * 9.0f) * 8 + (int)(pts[i * 2] * 8.0f);
            assert_int_equal(seen[c], 0);
            seen[c] = 1;
        }
    }
    /* van der Corput: any 64 consecutive points from a multiple of 64 fill the 64 bins once */
    memset(cells2, 0, sizeof cells2);
    for (i = 640; i < 704; ++i) cells2[(int)(gim_van_der_corput((uint32_t)i) * 64.0)]++;
    for (i = 0; i < 64; ++i) assert_int_equal(cells2[i], 1);
}

/* Chi-square on a 16x16 grid: low discrepancy means far *less* spread than random; a broken
   generator (e.g. a coordinate stuck or correlated) fails the upper bound. */
static void uniformity_chi_square(void **state) {
    enum { N = 25600, G = 16 };
    static float pts[N * 4];
    int bins[G * G], i, d;
    (void)state;
    assert_int_equal(gim_halton_points(pts, N, 4, 1, NULL), GIM_OK);
    for (d = 0; d < 3; ++d) {
        double chi = 0.0, e = (double)N / (G * G);
        memset(bins, 0, sizeof bins);
        for (i = 0; i < N; ++i) {
            int x = (int)(pts[i * 4 + d] * G), y = (int)(pts[i * 4 + d + 1] * G);
            bins[y * G + x]++;
        }
        for (i = 0; i < G * G; ++i) chi += (bins[i] - e) * (bins[i] - e) / e;
        assert_true(test_chi2_pvalue(chi, G * G - 1) > 0.01);
    }
}

/* gim_drift_offsets: frame 0 is the seed's 48-bit rotation; frame k moved by k step (g = 1,
   0.618...) modulo 1, to 2^-48; always in [0, 1), through the wrap and at frame 2^32 - 1. */
static void drift(void **state) {
    float r[4], o[4];
    uint32_t k;
    static const uint32_t frames[5] = {0u, 1u, 7u, 1000003u, 0xffffffffu};
    (void)state;
    gim_rotation_offsets(r, 4, 123);
    for (k = 0; k < 5; ++k) {
        int d;
        double step = 1.0 / (2048.0 * 8.0);
        gim_drift_offsets(o, 2, 123, frames[k], step);
        for (d = 0; d < 2; ++d) {
            double g = d ? 0.61803398874989484820 : 1.0;
            double want = (double)r[d] + (double)r[d + 2] / 16777216.0 + (double)frames[k] * step * g;
            double got = (double)o[d] + (double)o[d + 2] / 16777216.0, e;
            want -= floor(want);
            e = fabs(got - want);
            e = e < 1.0 - e ? e : 1.0 - e;   /* on the circle */
            assert_true(o[d] >= 0.0f && o[d] < 1.0f && o[d + 2] >= 0.0f && o[d + 2] < 1.0f);
            assert_true(e < 1e-11 * (1.0 + (double)frames[k] * step));
            if (frames[k] == 0) assert_true(o[d] == r[d] && o[d + 2] == r[d + 2]);
        }
    }
}

static void rotation(void **state) {
    float off[4], off2[4], pts[64 * 2], rot[64 * 2];
    int i;
    (void)state;
    gim_rotation_offsets(off, 4, 7);
    gim_rotation_offsets(off2, 4, 8);
    for (i = 0; i < 4; ++i) {
        assert_true(off[i] >= 0.0f && off[i] < 1.0f);
        assert_true(off[i] != off2[i]);
    }
    assert_int_equal(gim_halton_points(pts, 64, 2, 0, NULL), GIM_OK);
    assert_int_equal(gim_halton_points(rot, 64, 2, 0, off), GIM_OK);
    for (i = 0; i < 64; ++i) {
        float e = pts[i * 2] + off[0];
        e -= floorf(e);
        assert_true(fabsf(rot[i * 2] - e) < 1e-6f);
        assert_true(rot[i * 2] >= 0.0f && rot[i * 2] < 1.0f);
    }
    /* rounding to 1.0 wraps to 0 */
    assert_true(gim_rotate01(0.99999994f, 0.00000006f) < 1.0f);
    /* invalid offsets and sizes are errors */
    off[1] = 1.0f;
    assert_int_equal(gim_halton_points(rot, 64, 2, 0, off), GIM_ERROR_INVALID_ARGUMENT);
    off[1] = NAN;
    assert_int_equal(gim_halton_points(rot, 64, 2, 0, off), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_halton_points(NULL, 64, 2, 0, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_halton_points(rot, 0, 2, 0, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_halton_points(rot, 1, GIM_MAX_HALTON_DIMENSIONS + 1, 0, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_halton_points(rot, 2, 1, 0xffffffffu, NULL), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_halton_points(rot, 1, 1, 0xffffffffu, NULL), GIM_OK);
}

/* Concentric map: inside the disk, area-preserving (equal counts in equal-area rings and
   sectors), and continuous at the square's centre. */
static void disk_and_hemisphere(void **state) {
    enum { N = 16384, R = 8, S = 8 };
    static float pts[N * 2];
    int rings[R] = {0}, sectors[S] = {0}, i;
    double mean_cos = 0.0;
    (void)state;
    assert_int_equal(gim_hammersley_points(pts, N, 2, NULL), GIM_OK);
    for (i = 0; i < N; ++i) {
        gim_vec2 p = gim_square_to_disk(pts[i * 2], pts[i * 2 + 1]);
        double r2 = (double)p.x * p.x + (double)p.y * p.y, a = atan2(p.y, p.x) + 3.14159265358979;
        int ring = (int)(r2 * R), sec = (int)(a / (2.0 * 3.14159265358979) * S);
        assert_true(r2 <= 1.0 + 1e-6);
        rings[ring < R ? ring : R - 1]++;
        sectors[sec < S ? sec : S - 1]++;
    }
    /* equal-area rings (r^2 uniform) and sectors hold N/R each, up to low-discrepancy error */
    for (i = 0; i < R; ++i) assert_true(abs(rings[i] - N / R) < N / R / 50);
    for (i = 0; i < S; ++i) assert_true(abs(sectors[i] - N / S) < N / S / 50);
    {
        gim_vec2 c = gim_square_to_disk(0.5f, 0.5f);
        assert_true(c.x == 0.0f && c.y == 0.0f);
    }
    /* cosine-weighted: unit length, z >= 0, E[cos] = 2/3 */
    for (i = 0; i < N; ++i) {
        gim_vec3 d = gim_square_to_cosine_hemisphere(pts[i * 2], pts[i * 2 + 1]);
        assert_true(fabsf(gim__v3_length(d) - 1.0f) < 1e-5f);
        assert_true(d.z >= 0.0f);
        mean_cos += d.z;
    }
    mean_cos /= N;
    assert_true(fabs(mean_cos - 2.0 / 3.0) < 2e-3);
}

static void math_basics(void **state) {
    gim_mat4 m = gim_mat4_mul(gim_mat4_look_at(gim_v3(1, 2, 3), gim_v3(0, 0, 0), gim_v3(0, 1, 0)),
                              gim_mat4_perspective(1.0f, 1.5f, 0.1f, 100.0f));
    gim_mat4 inv, id;
    gim_vec3 t, b, n = gim_v3_normalize(gim_v3(0.3f, -0.2f, -0.9f));
    int i;
    (void)state;
    assert_true(gim_mat4_invert(m, &inv));
    id = gim_mat4_mul(m, inv);
    for (i = 0; i < 16; ++i) assert_true(fabsf(id.m[i] - ((i % 5 == 0) ? 1.0f : 0.0f)) < 1e-4f);
    {
        gim_mat4 z;
        memset(&z, 0, sizeof z);
        assert_false(gim_mat4_invert(z, &inv));
    }
    gim__basis(n, &t, &b);
    assert_true(fabsf(gim__v3_dot(t, n)) < 1e-6f && fabsf(gim__v3_dot(b, n)) < 1e-6f && fabsf(gim__v3_dot(t, b)) < 1e-6f);
    assert_true(fabsf(gim__v3_length(t) - 1.0f) < 1e-6f);
    gim__basis(gim_v3(0, 0, -1), &t, &b);
    assert_true(gim__v3_isfinite(t) && gim__v3_isfinite(b));
    /* normalise at the float extremes */
    assert_true(fabsf(gim__v3_length(gim_v3_normalize(gim_v3(1e-30f, 0, 1e-30f))) - 1.0f) < 1e-6f);
    assert_true(fabsf(gim__v3_length(gim_v3_normalize(gim_v3(3e38f, 3e38f, 0))) - 1.0f) < 1e-6f);
    assert_true(gim__v3_length(gim_v3_normalize(gim_v3(0, 0, 0))) == 0.0f);
    assert_false(gim__v3_isfinite(gim_v3(0, NAN, 0)));
    assert_string_equal(gim_result_string(GIM_ERROR_CORRUPT_DATA), "GIM_ERROR_CORRUPT_DATA");
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(radical_inverse_known_values),
        cmocka_unit_test(radical_inverse_exact_at_2_32),
        cmocka_unit_test(hammersley_values),
        cmocka_unit_test(stratification),
        cmocka_unit_test(uniformity_chi_square),
        cmocka_unit_test(rotation),
        cmocka_unit_test(drift),
        cmocka_unit_test(disk_and_hemisphere),
        cmocka_unit_test(math_basics),
    };
    return cmocka_run_group_tests_name("samplers", tests, NULL, NULL);
}
