/* gim_rsm_gather_twin, the CPU RSM gather (Dachsbacher 2005): with a pattern that covers the RSM it
   is an unbiased estimate of the sum over every texel (checked against that sum), its own
   texel weighs nothing, glossy follows the lobe, bad arguments fail. */
#define GIMANY_IMPLEMENTATION
#include "testutil.h"

#define S 48

/* A lit floor seen by a sun straight above: S x S texels over [0, 4]^2, normal up, random flux. */
typedef struct rsm_fixture {
    float pos[S * S * 3], nrm[S * S * 3], flux[S * S * 3], area[S * S], valid[S * S];
    gim_rsm_data rsm;
    gim_mat4 vp;
} rsm_fixture;

static void make_rsm(rsm_fixture *f) {
    int x, y;
    for (y = 0; y < S; ++y)
        for (x = 0; x < S; ++x) {
            int t = y * S + x;
            f->pos[t * 3] = (x + 0.5f) * 4.0f / S; f->pos[t * 3 + 1] = 0.0f; f->pos[t * 3 + 2] = (y + 0.5f) * 4.0f / S;
            f->nrm[t * 3] = 0.0f; f->nrm[t * 3 + 1] = 1.0f; f->nrm[t * 3 + 2] = 0.0f;
            f->flux[t * 3] = (float)(0.5 + test_rand01()) / (S * S);
            f->flux[t * 3 + 1] = (float)(0.5 + test_rand01()) / (S * S);
            f->flux[t * 3 + 2] = (float)(0.5 + test_rand01()) / (S * S);
            f->area[t] = 16.0f / (S * S);
            f->valid[t] = (x + y) % 17 == 0 ? 0.0f : 1.0f;   /* some unlit texels */
        }
    f->rsm.position = f->pos; f->rsm.normal = f->nrm; f->rsm.flux = f->flux; f->rsm.area = f->area; f->rsm.valid = f->valid;
    f->rsm.width = f->rsm.height = S;
    /* orthographic from above: x -> [-1, 1] over [0, 4], z likewise (texel row = z) */
    f->vp = gim_mat4_identity();
    f->vp.m[0] = 0.5f; f->vp.m[12] = -1.0f;   /* clip x = x / 2 - 1 */
    f->vp.m[5] = 0.0f; f->vp.m[9] = 0.5f; f->vp.m[13] = -1.0f;   /* clip y = z / 2 - 1 */
    f->vp.m[10] = 0.0f; f->vp.m[6] = 1.0f;   /* clip z = y */
}

/* The exact sum over every lit texel at a receiver (the FULL sum of the same VALs). */
static void full_sum(const rsm_fixture *f, const gim_receiver *rc, double out[3]) {
    int t, a;
    out[0] = out[1] = out[2] = 0.0;
    for (t = 0; t < S * S; ++t) {
        double d[3], d2 = 0.0, cx = 0.0, cl = 0.0, e;
        if (!(f->valid[t] > 0.0f)) continue;
        for (a = 0; a < 3; ++a) { d[a] = (double)f->pos[t * 3 + a] - rc->position[a]; d2 += d[a] * d[a]; }
        for (a = 0; a < 3; ++a) { cx += rc->normal[a] * d[a] / sqrt(d2); cl -= f->nrm[t * 3 + a] * d[a] / sqrt(d2); }
        if (cx <= 0.0 || cl <= 0.0) continue;
        e = cl * cx / (f->area[t] + 3.14159265358979 * d2);
        for (a = 0; a < 3; ++a) out[a] += rc->albedo[a] / 3.14159265358979 * e * f->flux[t * 3 + a];
    }
}

static void unbiased_against_the_full_sum(void **state) {
    static rsm_fixture f;
    gim_receiver rc[3];
    gim_gather_desc d;
    enum { N = 16384 };
    float *pattern = (float *)malloc(N * 2 * sizeof(float)), out[9];
    int i, a;
    (void)state;
    make_rsm(&f);
    memset(rc, 0, sizeof rc);
    for (i = 0; i < 3; ++i) { /* receivers on a wall at x = 4.5 facing -x, and one above the floor facing down */
        rc[i].position[0] = i < 2 ? 4.5f : 2.0f; rc[i].position[1] = i < 2 ? 0.5f + i : 1.0f; rc[i].position[2] = 1.0f + i;
        rc[i].normal[0] = i < 2 ? -1.0f : 0.0f; rc[i].normal[1] = i < 2 ? 0.0f : -1.0f;
        rc[i].view[1] = 1.0f;
        rc[i].albedo[0] = 0.8f; rc[i].albedo[1] = 0.5f; rc[i].albedo[2] = 0.3f;
    }
    assert_int_equal(gim_hammersley_points(pattern, N, 2, NULL), GIM_OK);
    memset(&d, 0, sizeof d);
    d.rsm = &f.rsm; d.light_view_proj = f.vp; d.samples = pattern; d.sample_count = N;
    d.radius = 2.0f * S;   /* covers the RSM from anywhere on it */
    d.receivers = rc; d.receiver_count = 3; d.scene_scale = 6.0f;
    assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_OK);
    for (i = 0; i < 3; ++i) {
        double ref[3];
        full_sum(&f, &rc[i], ref);
        for (a = 0; a < 3; ++a) {
            print_message("receiver %d channel %d: gather %.6g, full sum %.6g (%.2f%%)\n", i, a, (double)out[i * 3 + a], ref[a],
                          100.0 * (out[i * 3 + a] - ref[a]) / ref[a]);
            assert_true(ref[a] > 0.0);
            assert_true(fabs(out[i * 3 + a] - ref[a]) < 0.03 * ref[a]);
        }
    }
    /* a small radius sees a part: less light, never more than the whole */
    d.radius = 4.0f;
    assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_OK);
    for (i = 0; i < 3; ++i) {
        double ref[3];
        full_sum(&f, &rc[i], ref);
        assert_true(out[i * 3] < ref[0]);
    }
    /* glossy: a mirror-like lobe towards the viewer adds light, one away from it adds none */
    d.radius = 2.0f * S;
    assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_OK);   /* diffuse only */
    rc[2].glossy[0] = rc[2].glossy[1] = rc[2].glossy[2] = 0.5f;
    rc[2].exponent = 50.0f;
    rc[2].view[0] = 0.0f; rc[2].view[1] = -1.0f; rc[2].view[2] = 0.0f;   /* looking up at the floor's mirror: lobe lit */
    {
        float with[9], lit;
        assert_int_equal(gim_rsm_gather_twin(&d, with), GIM_OK);
        lit = with[6];
        assert_true(lit > out[6] * 1.01f);
        rc[2].view[0] = 0.0f; rc[2].view[1] = 0.0f; rc[2].view[2] = 1.0f;   /* a grazing view: the lobe misses the floor */
        assert_int_equal(gim_rsm_gather_twin(&d, with), GIM_OK);
        assert_true(with[6] >= out[6] && with[6] - out[6] < 0.05f * (lit - out[6]));
    }
    free(pattern);
}

static void bad_arguments(void **state) {
    static rsm_fixture f;
    gim_receiver rc;
    gim_gather_desc d;
    float pattern[8] = {0.1f, 0.2f, 0.3f, 0.4f, 0.5f, 0.6f, 0.7f, 0.8f}, out[3];
    test_alloc_stats st;
    test_log lg;
    (void)state;
    make_rsm(&f);
    memset(&rc, 0, sizeof rc);
    rc.normal[1] = 1.0f; rc.view[1] = 1.0f;
    memset(&d, 0, sizeof d);
    d.rsm = &f.rsm; d.light_view_proj = f.vp; d.samples = pattern; d.sample_count = 4; d.radius = 3.0f;
    d.receivers = &rc; d.receiver_count = 1; d.scene_scale = 1.0f; d.env = test_env(&st, &lg);
    assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_OK);
    assert_int_equal(gim_rsm_gather_twin(NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_rsm_gather_twin(&d, NULL), GIM_ERROR_INVALID_ARGUMENT);
    d.radius = 0.0f; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); d.radius = 3.0f;
    d.radius = NAN; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); d.radius = 3.0f;
    d.sample_count = 0; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); d.sample_count = 4;
    d.scene_scale = -1.0f; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); d.scene_scale = 1.0f;
    pattern[3] = INFINITY; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); pattern[3] = 0.4f;
    rc.normal[1] = 2.0f; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT); rc.normal[1] = 1.0f;
    d.light_view_proj.m[3] = NAN; assert_int_equal(gim_rsm_gather_twin(&d, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(lg.errors, 8);
    assert_int_equal(st.live, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(unbiased_against_the_full_sum),
        cmocka_unit_test(bad_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
