/* The GPU VPLs of an RSM (Dong et al. sec. 4) against their CPU twin gim_rsm_vpls_twin, on uploaded
   random RSM textures (some texels unlit, some broken: NaN position, Inf normal, negative or
   NaN flux), with and without Cranley-Patterson offsets, at sizes with partial work groups,
   more VPLs than texels, and several blocks of GIM_RSM_VPL_BLOCK VPLs; zero GL errors and
   the GL state restored.

   Tolerances: positions and normals bit for bit (both copy the texel's bits, or write 0);
   position.w is the lit flag (1 exactly where the twin's texel is lit). The flux is Phi T / S
   in double on both sides, in the same order of sums, then rounded to float; GLSL promises
   double arithmetic only to "at least single precision" in places, so flux is checked to
   1e-6 relative (of the VPL's flux; a zero must be exactly zero). Seen on llvmpipe: printed. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

static const double TOL_FLUX = 1e-6;

static float rnd(float lo, float hi) { return lo + (hi - lo) * (float)test_rand01(); }

typedef struct vpl_rsm {
    uint32_t size;
    float *position4, *normal4, *flux4;
    float *position, *normal, *flux, *area, *valid;
    GLuint tex[3];
} vpl_rsm;

static GLuint texture_rgba(uint32_t size, const float *texels) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, (GLsizei)size, (GLsizei)size);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, (GLsizei)size, (GLsizei)size, GL_RGBA, GL_FLOAT, texels);
    glBindTexture(GL_TEXTURE_2D, 0);
    return t;
}

/* A random RSM around origin of extent L; 10% unlit, and a few broken texels. */
static void rsm_make(vpl_rsm *r, uint32_t size, const float origin[3], float L) {
    size_t n = (size_t)size * size, t;
    memset(r, 0, sizeof *r);
    r->size = size;
    r->position4 = (float *)calloc(n * 4, sizeof(float));
    r->normal4 = (float *)calloc(n * 4, sizeof(float));
    r->flux4 = (float *)calloc(n * 4, sizeof(float));
    r->position = (float *)malloc(n * 3 * sizeof(float));
    r->normal = (float *)malloc(n * 3 * sizeof(float));
    r->flux = (float *)malloc(n * 3 * sizeof(float));
    r->area = (float *)malloc(n * sizeof(float));
    r->valid = (float *)malloc(n * sizeof(float));
    for (t = 0; t < n; ++t) {
        float *x = r->position4 + t * 4, *nn = r->normal4 + t * 4, *f = r->flux4 + t * 4;
        int a;
        for (a = 0; a < 3; ++a) x[a] = origin[a] + rnd(0.0f, L);
        x[3] = test_rand01() < 0.1 ? 0.0f : 1.0f;
        nn[0] = rnd(-1, 1); nn[1] = rnd(-1, 1); nn[2] = 1.0f;
        nn[3] = rnd(0.01f, 1.0f) * L * L / (float)n;
        f[0] = rnd(0, 2); f[1] = rnd(0, 1); f[2] = rnd(0, 0.5f);
        f[3] = rnd(-5, 5);   /* ignored */
        switch (t % 97) {
        case 3: x[1] = NAN; break;
        case 11: nn[2] = INFINITY; break;
        case 17: f[0] = -0.5f; break;
        case 29: f[2] = NAN; break;
        case 41: x[3] = NAN; break;
        case 53: x[3] = -1.0f; break;
        case 61: nn[3] = -1.0f; break;   /* a footprint that is not > 0: a point VPL (area 0) */
        case 71: nn[3] = NAN; break;
        default: break;
        }
    }
    for (t = 0; t < n; ++t) {
        memcpy(r->position + t * 3, r->position4 + t * 4, 12);
        memcpy(r->normal + t * 3, r->normal4 + t * 4, 12);
        memcpy(r->flux + t * 3, r->flux4 + t * 4, 12);
        r->area[t] = r->normal4[t * 4 + 3];
        r->valid[t] = r->position4[t * 4 + 3];
    }
    r->tex[0] = texture_rgba(size, r->position4);
    r->tex[1] = texture_rgba(size, r->normal4);
    r->tex[2] = texture_rgba(size, r->flux4);
}

static gim_rsm_data rsm_data(const vpl_rsm *r) {
    gim_rsm_data d;
    memset(&d, 0, sizeof d);
    d.position = r->position; d.normal = r->normal; d.flux = r->flux; d.area = r->area; d.valid = r->valid;
    d.width = d.height = r->size;
    return d;
}

static void rsm_free(vpl_rsm *r) {
    glDeleteTextures(3, r->tex);
    free(r->position4); free(r->normal4); free(r->flux4);
    free(r->position); free(r->normal); free(r->flux); free(r->area); free(r->valid);
}

typedef struct vpl_stats {
    double flux;        /* largest relative flux error */
    uint32_t unlit;     /* VPLs on unlit texels */
    uint32_t lit_area;  /* lit VPLs with an area */
    uint32_t vpls;
} vpl_stats;

/* One pass of count VPLs against the twin; the buffer holds count + 3 VPLs, the last 3 must
   keep their sentinel. */
static void vpls_one(gltest_fixture *f, const vpl_rsm *r, uint32_t count, gim_vpl_sequence seq, const float *offsets,
                     vpl_stats *st) {
    gim_rsm_data d = rsm_data(r);
    gim_rsm_vpls_desc vd;
    float *p = (float *)malloc(count * 12), *n = (float *)malloc(count * 12), *fl = (float *)malloc(count * 12);
    float *ar = (float *)malloc(count * 4);
    float *gpu = (float *)malloc((count + 3) * 48);
    double sum[3] = {0, 0, 0}, gsum[3] = {0, 0, 0};
    uint32_t i, a;
    GLuint out;
    for (i = 0; i < (count + 3) * 12; ++i) gpu[i] = -7.0f;
    out = gltest_ssbo((count + 3) * 48, gpu);
    memset(&vd, 0, sizeof vd);
    vd.rsm = &d; vd.count = count; vd.sequence = seq; vd.offsets = offsets; vd.env = f->env;
    assert_int_equal(gim_rsm_vpls_twin(&vd, p, n, fl, ar), GIM_OK);
    assert_int_equal(gim__gl_rsm_vpls(f->ctx, r->tex[0], r->tex[1], r->tex[2], r->size, count, seq, offsets, out), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(out, (count + 3) * 48, gpu);
    for (i = count * 12; i < (count + 3) * 12; ++i) assert_true(gpu[i] == -7.0f);
    for (i = 0; i < count; ++i) {
        const float *g = gpu + i * 12;
        int lit = fl[i * 3] > 0.0f || fl[i * 3 + 1] > 0.0f || fl[i * 3 + 2] > 0.0f;
        if (memcmp(g, p + i * 3, 12) != 0 || memcmp(g + 4, n + i * 3, 12) != 0)
            fail_msg("VPL %u: position/normal (%g %g %g / %g %g %g), the twin's (%g %g %g / %g %g %g)", i, (double)g[0],
                     (double)g[1], (double)g[2], (double)g[4], (double)g[5], (double)g[6], (double)p[i * 3],
                     (double)p[i * 3 + 1], (double)p[i * 3 + 2], (double)n[i * 3], (double)n[i * 3 + 1],
                     (double)n[i * 3 + 2]);
        assert_true(g[11] == 0.0f);
        /* the area (the near field's patch): the twin's within the flux's tolerance, 0 where unlit */
        if (ar[i] == 0.0f) assert_true(g[7] == 0.0f);
        else if (!(fabs(g[7] - ar[i]) <= TOL_FLUX * ar[i]))
            fail_msg("VPL %u: area %.9g, the twin's %.9g", i, (double)g[7], (double)ar[i]);
        if (lit) { assert_true(g[3] == 1.0f); st->lit_area += ar[i] > 0.0f; }
        else st->unlit++;
        for (a = 0; a < 3; ++a) {
            double c = fl[i * 3 + a], e;
            if (c == 0.0) {
                if (g[8 + a] != 0.0f) fail_msg("VPL %u channel %u: flux %g, the twin's 0", i, a, (double)g[8 + a]);
                continue;
            }
            e = fabs(g[8 + a] - c) / c;
            if (e > st->flux) st->flux = e;
            if (!(e <= TOL_FLUX)) fail_msg("VPL %u channel %u: flux %.9g, the twin's %.9g", i, a, (double)g[8 + a], c);
            sum[a] += c;
            gsum[a] += g[8 + a];
        }
    }
    {   /* both sum to the RSM's lit total */
        double tot[3] = {0, 0, 0};
        size_t t;
        for (t = 0; t < (size_t)r->size * r->size; ++t) {
            const float *x = r->position4 + t * 4, *nn = r->normal4 + t * 4, *fx = r->flux4 + t * 4;
            if (x[3] > 0.0f && gim__all_finite(x, 3) && gim__all_finite(nn, 3) && gim__all_finite(fx, 3) &&
                fx[0] >= 0.0f && fx[1] >= 0.0f && fx[2] >= 0.0f)
                for (a = 0; a < 3; ++a) tot[a] += fx[a];
        }
        for (a = 0; a < 3; ++a)
            if (sum[a] > 0.0) {
                assert_true(fabs(sum[a] - tot[a]) <= 1e-5 * tot[a]);
                assert_true(fabs(gsum[a] - tot[a]) <= 1e-5 * tot[a]);
            }
    }
    st->vpls += count;
    glDeleteBuffers(1, &out);
    free(p); free(n); free(fl); free(ar); free(gpu);
}

/* Sizes 64 (whole groups), 37 (partial), 5 (more VPLs than texels) and 1; counts 1, 100,
   1024 and 2500 (three blocks of the final sum); far from the origin too; with offsets. */
static void matches_twin(void **state) {
    static const uint32_t sizes[4] = {64, 37, 5, 1};
    static const uint32_t counts[4] = {1, 100, 1024, 2500};
    static const float origins[2][3] = {{0.0f, 0.0f, 0.0f}, {3.0e3f, -2.0e3f, 1.0e4f}};
    static const float off[2] = {0.37f, 0.81f};
    gltest_fixture f;
    vpl_stats st;
    int s, c, o;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    for (s = 0; s < 4; ++s)
        for (o = 0; o < 2; ++o) {
            vpl_rsm r;
            rsm_make(&r, sizes[s], origins[o], o ? 50.0f : 4.0f);
            if (sizes[s] == 1) r.position4[3] = r.valid[0] = 1.0f;   /* one lit texel */
            if (sizes[s] == 1) { glDeleteTextures(3, r.tex); r.tex[0] = texture_rgba(1, r.position4);
                                 r.tex[1] = texture_rgba(1, r.normal4); r.tex[2] = texture_rgba(1, r.flux4); }
            for (c = 0; c < 4; ++c)
                vpls_one(&f, &r, counts[c], c % 2 ? GIM_VPL_SEQUENCE_HAMMERSLEY : GIM_VPL_SEQUENCE_HALTON,
                         (c + o) % 2 ? off : NULL, &st);
            rsm_free(&r);
        }
    print_message("RSM VPLs: %u VPLs (%u unlit, %u lit with an area), largest relative flux error %.3g\n", st.vpls,
                  st.unlit, st.lit_area, st.flux);
    assert_true(st.unlit > 100);
    assert_true(st.lit_area > st.vpls / 2);   /* the areas were compared, not all zero */
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Bad arguments: errors before any GL work, the GL state as it was, nothing written. */
static void bad_arguments(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f}, bad_off[2] = {1.0f, 0.0f};
    gltest_fixture f;
    vpl_rsm r;
    GLuint out, small, r8;
    float fill[12 * 4];
    int k;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    rsm_make(&r, 8, zero, 1.0f);
    for (k = 0; k < 48; ++k) fill[k] = -7.0f;
    out = gltest_ssbo(sizeof fill, fill);
    small = gltest_ssbo(48, fill);
    glGenTextures(1, &r8);
    glBindTexture(GL_TEXTURE_2D, r8);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, 8, 8);
    glBindTexture(GL_TEXTURE_2D, 0);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, 0, r.tex[1], r.tex[2], 8, 4, GIM_VPL_SEQUENCE_HALTON, NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 8, 4, GIM_VPL_SEQUENCE_HALTON, NULL, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 8, 0, GIM_VPL_SEQUENCE_HALTON, NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 0, 4, GIM_VPL_SEQUENCE_HALTON, NULL, out), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 8, 4, GIM_VPL_SEQUENCE_HALTON, bad_off, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 9, 4, GIM_VPL_SEQUENCE_HALTON, NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r8, r.tex[2], 8, 4, GIM_VPL_SEQUENCE_HALTON, NULL, out), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], 8, 4, GIM_VPL_SEQUENCE_HALTON, NULL, small), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(f.log.errors, 8);
    f.log.errors = 0;
    gltest_state_unchanged(&f);
    gltest_read_buffer(out, sizeof fill, fill);
    for (k = 0; k < 48; ++k) assert_true(fill[k] == -7.0f);
    glDeleteTextures(1, &r8);
    glDeleteBuffers(1, &out);
    glDeleteBuffers(1, &small);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* --- one GPU k-means step against gim_kmeans ------------------------------------------------ */

/* Tolerances of the k-means comparison (see gim__gl_kmeans_step): the GPU's distances are
   float, the twin's double, so a VPL whose two nearest centres are within TOL_TIE (in the
   metric's units, scene-scale relative, plus the centres' float ulp over the scale far from
   the origin) may go either way: a "near tie". Where no VPL differs, centres agree to
   TOL_CENTRE * scale (+ the float ulp of the coordinates), normals to TOL_NORMAL. */
static const double TOL_TIE = 1e-5, TOL_CENTRE = 1e-5, TOL_NORMAL = 1e-5;

typedef struct kmeans_stats {
    uint32_t runs, compared, skipped_empty;   /* runs; runs with every VPL as the twin; runs the twin repaired */
    uint32_t vpls, mismatches, near_ties;     /* VPLs compared; assigned differently; of which near ties */
    double centre, normal;                    /* largest centre error (scale-relative), normal error */
} kmeans_stats;

/* n random VPLs in a box of side L at o: a third on one wall (the same normal: nearly
   parallel normals everywhere), the rest random unit normals; every 10th of zero flux. vpl:
   the 48-byte GPU layout. */
static void make_vpls(uint32_t n, const float o[3], float L, float *vpl, float *p, float *nn, float *f) {
    uint32_t i;
    int a;
    for (i = 0; i < n; ++i) {
        float l;
        for (a = 0; a < 3; ++a) p[i * 3 + a] = o[a] + rnd(0.0f, L);
        if (i % 3 == 0) {
            p[i * 3 + 2] = o[2];
            nn[i * 3] = 0.0f; nn[i * 3 + 1] = 0.0f; nn[i * 3 + 2] = 1.0f;
        } else {
            do {
                nn[i * 3] = rnd(-1, 1); nn[i * 3 + 1] = rnd(-1, 1); nn[i * 3 + 2] = rnd(-1, 1);
                l = nn[i * 3] * nn[i * 3] + nn[i * 3 + 1] * nn[i * 3 + 1] + nn[i * 3 + 2] * nn[i * 3 + 2];
            } while (l < 0.05f || l > 1.0f);
            l = 1.0f / sqrtf(l);
            for (a = 0; a < 3; ++a) nn[i * 3 + a] *= l;
        }
        for (a = 0; a < 3; ++a) f[i * 3 + a] = i % 10 == 7 ? 0.0f : rnd(0.0f, 1.0f);
        for (a = 0; a < 3; ++a) {
            vpl[i * 12 + a] = p[i * 3 + a];
            vpl[i * 12 + 4 + a] = nn[i * 3 + a];
            vpl[i * 12 + 8 + a] = f[i * 3 + a];
        }
        vpl[i * 12 + 3] = 1.0f; vpl[i * 12 + 7] = 0.0f; vpl[i * 12 + 11] = 0.0f;
    }
}

/* The metric in double, as gim_kmeans (absolute positions: the test's reference for ties). */
static double metric_d(gim_kmeans_metric m, double wx_s, double wa, const float *x, const float *n, const float *c,
                       const float *cn) {
    double d2 = 0.0, dot = 0.0, ln = 0.0, lc = 0.0;
    int a;
    for (a = 0; a < 3; ++a) {
        d2 += ((double)x[a] - c[a]) * ((double)x[a] - c[a]);
        dot += (double)n[a] * cn[a]; ln += (double)n[a] * n[a]; lc += (double)cn[a] * cn[a];
    }
    dot /= sqrt(ln * lc);
    if (m == GIM_KMEANS_METRIC_SSVP) return wx_s * sqrt(d2) + wa * (1.0 - (dot > 0.0 ? dot : 0.0));
    return wx_s * sqrt(d2) + wa / 3.14159265358979323846 * acos(dot > 1.0 ? 1.0 : (dot < -1.0 ? -1.0 : dot));
}

/* K GPU steps from the centres of VPLs floor(j N / M) against gim_kmeans WARM with
   max_iterations K from the same centres, on the VPLs p, nn, fl (the twin's arrays) and bv
   (the same in the GPU layout); o, L: where they lie (for the float tolerance). */
static void kmeans_compare(gltest_fixture *f, GLuint bv, const float *p, const float *nn, const float *fl, uint32_t n,
                           uint32_t m, uint32_t k, gim_kmeans_metric metric, const float o[3], float L, kmeans_stats *st) {
    float *init = (float *)calloc(m, 32), *gc = (float *)malloc((size_t)m * 32);
    float *prev = (float *)malloc((size_t)m * 32), *ic = (float *)malloc((size_t)m * 12), *in = (float *)malloc((size_t)m * 12);
    float *cc = (float *)malloc((size_t)m * 12), *cn = (float *)malloc((size_t)m * 12);
    uint32_t *ga = (uint32_t *)malloc((size_t)n * 4), *ca = (uint32_t *)malloc((size_t)n * 4), *cnt = (uint32_t *)malloc((size_t)m * 4);
    const float scale = L * 1.7320508f;
    double wx = metric == GIM_KMEANS_METRIC_SSVP ? 0.6 : 0.7, wa = metric == GIM_KMEANS_METRIC_SSVP ? 0.4 : 0.3;
    double ulp = ldexp(1.0, -23) * (fabs(o[0]) + fabs(o[1]) + fabs(o[2]) + L) / scale;
    gim_kmeans_desc d;
    gim_kmeans_result res;
    GLuint bc, ba;
    uint32_t i, j, s, mism = 0, ties = 0;
    int a;
    for (j = 0; j < m; ++j) {
        uint32_t v = (uint32_t)((uint64_t)j * n / m);
        for (a = 0; a < 3; ++a) {
            ic[j * 3 + a] = init[j * 8 + a] = p[v * 3 + a];
            in[j * 3 + a] = init[j * 8 + 4 + a] = nn[v * 3 + a];
        }
    }
    memset(&d, 0, sizeof d);
    d.positions = p; d.normals = nn; d.flux = fl; d.vpl_count = n; d.cluster_count = m; d.metric = metric;
    d.init = GIM_KMEANS_INIT_WARM; d.init_centres = ic; d.init_normals = in; d.scene_scale = scale;
    d.max_iterations = k; d.env = f->env;
    memset(&res, 0, sizeof res);
    res.centres = cc; res.normals = cn; res.counts = cnt; res.assignment = ca;
    assert_int_equal(gim_kmeans(&d, &res), GIM_OK);
    st->runs++;
    if (res.empty_repaired > 0) { st->skipped_empty++; goto done; }
    bc = gltest_ssbo((size_t)m * 32, init);
    for (i = 0; i < n; ++i) ga[i] = 0xffffffffu;
    ba = gltest_ssbo((size_t)n * 4, ga);
    for (s = 0; s < k; ++s) {
        gltest_read_buffer(bc, (size_t)m * 32, prev);
        assert_int_equal(gim__gl_kmeans_step(f->ctx, bv, n, bc, m, ba, metric, 0.0f, 0.0f, scale), GIM_OK);
    }
    gltest_state_unchanged(f);
    gltest_read_buffer(bc, (size_t)m * 32, gc);
    gltest_read_buffer(ba, (size_t)n * 4, ga);
    /* the assignment: as the twin's but near ties, judged with the centres of the last step */
    for (i = 0; i < n; ++i) {
        double dg, dc;
        assert_true(ga[i] < m);
        if (ga[i] == ca[i]) continue;
        ++mism;
        dg = metric_d(metric, wx / scale, wa, p + i * 3, nn + i * 3, prev + ga[i] * 8, prev + ga[i] * 8 + 4);
        dc = metric_d(metric, wx / scale, wa, p + i * 3, nn + i * 3, prev + ca[i] * 8, prev + ca[i] * 8 + 4);
        if (fabs(dg - dc) <= TOL_TIE + 4.0 * ulp) ++ties;
        else print_message("VPL %u: GPU cluster %u (d %.9g), the twin's %u (d %.9g)\n", i, ga[i], dg, ca[i], dc);
    }
    st->vpls += n; st->mismatches += mism; st->near_ties += ties;
    if (mism == 0) {
        st->compared++;
        for (j = 0; j < m; ++j) {
            assert_true(gc[j * 8 + 3] == (float)cnt[j]);
            for (a = 0; a < 3; ++a) {
                double ec = fabs((double)gc[j * 8 + a] - cc[j * 3 + a]) / scale, en = fabs((double)gc[j * 8 + 4 + a] - cn[j * 3 + a]);
                if (ec > st->centre) st->centre = ec;
                if (en > st->normal) st->normal = en;
                if (!(ec <= TOL_CENTRE + 4.0 * ulp) || !(en <= TOL_NORMAL))
                    fail_msg("cluster %u axis %d: centre %.9g / normal %.9g, the twin's %.9g / %.9g", j, a,
                             (double)gc[j * 8 + a], (double)gc[j * 8 + 4 + a], (double)cc[j * 3 + a], (double)cn[j * 3 + a]);
            }
        }
    }
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &ba);
done:
    free(init); free(gc); free(prev); free(ic); free(in); free(cc); free(cn);
    free(ga); free(ca); free(cnt);
}

/* Random VPLs (dark: every flux zero, so every cluster takes the plain means). */
static void kmeans_one(gltest_fixture *f, uint32_t n, uint32_t m, uint32_t k, gim_kmeans_metric metric, const float o[3],
                       float L, int dark, kmeans_stats *st) {
    float *vpl = (float *)malloc((size_t)n * 48), *p = (float *)malloc((size_t)n * 12), *nn = (float *)malloc((size_t)n * 12);
    float *fl = (float *)malloc((size_t)n * 12);
    uint32_t i;
    GLuint bv;
    make_vpls(n, o, L, vpl, p, nn, fl);
    if (dark)
        for (i = 0; i < n * 3; ++i) fl[i] = vpl[(i / 3) * 12 + 8 + i % 3] = 0.0f;
    bv = gltest_ssbo((size_t)n * 48, vpl);
    kmeans_compare(f, bv, p, nn, fl, n, m, k, metric, o, L, st);
    glDeleteBuffers(1, &bv);
    free(vpl); free(p); free(nn); free(fl);
}

/* K = 1, 2, 4, 8 steps, N = 1024 / M = 30 (the defaults) and N = 700 / M = 8 in chunks
   of 97 VPLs (several update dispatches; at 8 steps with every flux zero: the plain means),
   both metrics, near the origin and far from it. */
static void kmeans_matches_twin(void **state) {
    static const uint32_t steps[4] = {1, 2, 4, 8};
    static const float origins[2][3] = {{0.0f, 0.0f, 0.0f}, {3.0e3f, -2.0e3f, 1.0e4f}};
    gltest_fixture f;
    kmeans_stats st;
    int s, o, mt;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    for (mt = 0; mt < 2; ++mt)
        for (o = 0; o < 2; ++o)
            for (s = 0; s < 4; ++s) {
                gim_kmeans_metric metric = mt ? GIM_KMEANS_METRIC_SSVP : GIM_KMEANS_METRIC_DONG;
                f.ctx->proxy_chunk = GIM__PROXY_CHUNK;
                kmeans_one(&f, 1024, 30, steps[s], metric, origins[o], o ? 50.0f : 4.0f, 0, &st);
                f.ctx->proxy_chunk = 97;
                kmeans_one(&f, 700, 8, steps[s], metric, origins[o], o ? 50.0f : 4.0f, s == 3, &st);
            }
    f.ctx->proxy_chunk = GIM__PROXY_CHUNK;
    print_message("k-means step: %u runs (%u compared in full, %u skipped: the twin repaired an empty cluster), "
                  "%u VPLs, %u assigned differently (%u near ties); largest centre error %.3g scale, normal %.3g\n",
                  st.runs, st.compared, st.skipped_empty, st.vpls, st.mismatches, st.near_ties, st.centre, st.normal);
    assert_int_equal(st.mismatches, st.near_ties);
    assert_true(st.compared * 4 >= st.runs * 3);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* An empty cluster keeps its centre and normal and reports count 0; the twin re-seeds it. */
static void kmeans_empty_cluster(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    float vpl[64 * 12], p[64 * 3], nn[64 * 3], fl[64 * 3], c[4 * 8];
    uint32_t asg[64], i, total = 0;
    GLuint bv, bc, ba;
    int a;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_vpls(64, zero, 1.0f, vpl, p, nn, fl);
    memset(c, 0, sizeof c);
    for (i = 0; i < 4; ++i)
        for (a = 0; a < 3; ++a) {
            uint32_t v = i == 2 ? 16 : i * 16;   /* centre 2 = centre 1: ties go to 1, 2 stays empty */
            c[i * 8 + a] = p[v * 3 + a];
            c[i * 8 + 4 + a] = nn[v * 3 + a];
        }
    for (i = 0; i < 64; ++i) asg[i] = 0xffffffffu;
    bv = gltest_ssbo(sizeof vpl, vpl);
    bc = gltest_ssbo(sizeof c, c);
    ba = gltest_ssbo(sizeof asg, asg);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0.0f, 0.0f, 1.0f), GIM_OK);
    {
        float g[4 * 8];
        gltest_read_buffer(bc, sizeof g, g);
        gltest_read_buffer(ba, sizeof asg, asg);
        assert_true(g[2 * 8 + 3] == 0.0f);
        assert_memory_equal(g + 2 * 8, c + 2 * 8, 12);
        assert_memory_equal(g + 2 * 8 + 4, c + 2 * 8 + 4, 12);
        for (i = 0; i < 4; ++i) total += (uint32_t)g[i * 8 + 3];
        assert_int_equal(total, 64);
        for (i = 0; i < 64; ++i) assert_true(asg[i] != 2u && asg[i] < 4u);
    }
    /* bad arguments */
    assert_int_equal(gim__gl_kmeans_step(f.ctx, 0, 64, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bv, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 0, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 3, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bc, 4, ba, (gim_kmeans_metric)7, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bc, 4, ba, GIM_KMEANS_METRIC_DONG, -1, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 64, bc, 5, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_kmeans_step(f.ctx, bv, 65, bc, 4, ba, GIM_KMEANS_METRIC_DONG, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(f.log.errors, 9);
    f.log.errors = 0;
    gltest_state_unchanged(&f);
    glDeleteBuffers(1, &bv);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &ba);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* The pipeline of clustered visibility's first passes: the GPU VPLs of an RSM straight into
   GPU k-means steps (the 48-byte layout both take), against gim_rsm_vpls_twin -> gim_kmeans. The
   RSM has unlit texels (zero-flux VPLs: weight 0 in the means) but no broken ones (the twin's
   k-means refuses a zero normal). */
static void vpls_into_kmeans(void **state) {
    static const float origin[3] = {-20.0f, 5.0f, 300.0f};
    static const float off[2] = {0.25f, 0.6f};
    const uint32_t n = 1024, size = 48;
    gltest_fixture f;
    kmeans_stats st;
    vpl_rsm r;
    gim_rsm_data d;
    gim_rsm_vpls_desc vd;
    float *p = (float *)malloc(n * 12), *nn = (float *)malloc(n * 12), *fl = (float *)malloc(n * 12);
    uint32_t t, k;
    GLuint bv;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&r, size, origin, 10.0f);
    for (t = 0; t < size * size; ++t) {   /* no broken texels: finite everything, flux >= 0, w 0 or 1 */
        float *x = r.position4 + t * 4, *nm = r.normal4 + t * 4, *fx = r.flux4 + t * 4;
        if (!(x[1] == x[1])) x[1] = origin[1];
        if (!(nm[2] < 2.0f)) nm[2] = 1.0f;
        if (!(fx[0] >= 0.0f)) fx[0] = 0.5f;
        if (!(fx[2] == fx[2])) fx[2] = 0.25f;
        if (!(x[3] == 0.0f || x[3] == 1.0f)) x[3] = 0.0f;
        memcpy(r.position + t * 3, x, 12); memcpy(r.normal + t * 3, nm, 12); memcpy(r.flux + t * 3, fx, 12);
        r.valid[t] = x[3];
    }
    glDeleteTextures(3, r.tex);
    r.tex[0] = texture_rgba(size, r.position4);
    r.tex[1] = texture_rgba(size, r.normal4);
    r.tex[2] = texture_rgba(size, r.flux4);
    d = rsm_data(&r);
    memset(&vd, 0, sizeof vd);
    vd.rsm = &d; vd.count = n; vd.sequence = GIM_VPL_SEQUENCE_HALTON; vd.offsets = off; vd.env = f.env;
    assert_int_equal(gim_rsm_vpls_twin(&vd, p, nn, fl, NULL), GIM_OK);
    bv = gltest_ssbo(n * 48, NULL);
    assert_int_equal(gim__gl_rsm_vpls(f.ctx, r.tex[0], r.tex[1], r.tex[2], size, n, GIM_VPL_SEQUENCE_HALTON, off, bv), GIM_OK);
    for (k = 1; k <= 8; k *= 2) kmeans_compare(&f, bv, p, nn, fl, n, 30, k, GIM_KMEANS_METRIC_DONG, origin, 10.0f, &st);
    print_message("VPLs -> k-means: %u runs (%u compared in full, %u skipped), %u VPLs differently assigned (%u near ties); "
                  "centre error %.3g scale, normal %.3g\n", st.runs, st.compared, st.skipped_empty, st.mismatches,
                  st.near_ties, st.centre, st.normal);
    assert_int_equal(st.mismatches, st.near_ties);
    assert_true(st.compared >= 3);
    glDeleteBuffers(1, &bv);
    rsm_free(&r);
    free(p); free(nn); free(fl);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* A flat RSM that a light with camera vp (orthographic, world [0, L]^2 at z = 0 onto the whole
   map, shifted by (tx, ty) texels) sees: texel centres' points, normal +z, footprint (L / size)^2,
   random flux; 8% unlit, 8% hidden (their point 5 L above: a blocker), 5% normals turned away. */
static void flat_rsm(vpl_rsm *r, uint32_t size, float L, float tx, float ty, gim_mat4 *vp) {
    size_t n = (size_t)size * size, t;
    float h = L / (float)size;
    const float origin[3] = {0.0f, 0.0f, 0.0f};
    rsm_make(r, size, origin, L);   /* the arrays; overwritten */
    glDeleteTextures(3, r->tex);
    for (t = 0; t < n; ++t) {
        float *x = r->position4 + t * 4, *nn = r->normal4 + t * 4, *f = r->flux4 + t * 4;
        uint32_t i = (uint32_t)(t % size), j = (uint32_t)(t / size), k = (uint32_t)(test_rand01() * 100.0);
        x[0] = ((float)i + 0.5f - tx) * h; x[1] = ((float)j + 0.5f - ty) * h; x[2] = 0.0f; x[3] = 1.0f;
        nn[0] = 0.0f; nn[1] = 0.0f; nn[2] = 1.0f; nn[3] = h * h;
        f[0] = rnd(0.1f, 2); f[1] = rnd(0.1f, 1); f[2] = rnd(0.1f, 0.5f); f[3] = 0.0f;
        if (k < 8) x[3] = 0.0f;
        else if (k < 16) x[2] = 5.0f * L;
        else if (k < 21) nn[2] = -1.0f;
        memcpy(r->position + t * 3, x, 12); memcpy(r->normal + t * 3, nn, 12); memcpy(r->flux + t * 3, f, 12);
        r->area[t] = nn[3]; r->valid[t] = x[3];
    }
    r->tex[0] = texture_rgba(size, r->position4);
    r->tex[1] = texture_rgba(size, r->normal4);
    r->tex[2] = texture_rgba(size, r->flux4);
    *vp = gim_mat4_identity();
    vp->m[0] = 2.0f / L; vp->m[5] = 2.0f / L;
    vp->m[12] = -1.0f + 2.0f * tx / (float)size; vp->m[13] = -1.0f + 2.0f * ty / (float)size;
}

/* The twin's VPLs of r (previous: prev, or NULL) as gim_vpl, with the kept flags. */
static void twin_vpls(const vpl_rsm *r, uint32_t count, const gim_vpl *prev, gim_mat4 vp, gim_vpl *out,
                      unsigned char *kept, gim_env env) {
    gim_rsm_data d = rsm_data(r);
    gim_rsm_vpls_desc vd;
    float *p = (float *)malloc(count * 12), *n = (float *)malloc(count * 12), *fl = (float *)malloc(count * 12);
    float *ar = (float *)malloc(count * 4);
    uint32_t i;
    memset(&vd, 0, sizeof vd);
    vd.rsm = &d; vd.count = count; vd.sequence = GIM_VPL_SEQUENCE_HALTON; vd.env = env;
    vd.previous = prev; vd.view_proj = vp; vd.kept = kept;
    assert_int_equal(gim_rsm_vpls_twin(&vd, p, n, fl, ar), GIM_OK);
    for (i = 0; i < count; ++i) {
        memcpy(out[i].position, p + i * 3, 12);
        memcpy(out[i].normal, n + i * 3, 12);
        memcpy(out[i].flux, fl + i * 3, 12);
        out[i].lit = fl[i * 3] > 0.0f || fl[i * 3 + 1] > 0.0f || fl[i * 3 + 2] > 0.0f ? 1.0f : 0.0f;
        out[i].area = ar[i];
        out[i].kept = kept[i] ? 1.0f : 0.0f;
    }
    free(p); free(n); free(fl); free(ar);
}

/* Incremental instant radiosity (Laine et al. 2007): the pass that follows the last frame's VPLs
   (gim__gl_rsm_vpls_follow on a buffer holding them) against gim_rsm_vpls_twin with previous.
   The light moves by (tx, ty) texels between two flat RSMs (flat_rsm: hidden, turned and unlit
   texels): a VPL is kept exactly where the twin keeps it, never where its point is hidden,
   turned away or dark now, nor where the move takes it farther from its slot's texel than its
   radius; kept ones keep their position and normal bit for bit and take the new texel's flux.
   Then nothing moves: every lit VPL is kept and the pass gives its input back. Fails if the
   shader's projection, radius or tests are not the twin's. */
static void follows_twin(void **state) {
    static const struct { uint32_t size, count; float tx, ty; } cases[3] = {
        {64, 200, 1.3f, 0.2f},     /* radius 1.1-2.3 texels: a move of 1 keeps all the light sees */
        {48, 1500, 0.2f, 0.15f},   /* two blocks of the sum; radius 0.3-0.6: only VPLs that stay in their texel */
        {37, 300, -0.7f, 1.4f}};   /* radius 0.5-1.1, a move of 1: a few kept */
    gltest_fixture f;
    uint32_t c;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    for (c = 0; c < 3; ++c) {
        uint32_t n = cases[c].count, i, a, kept = 0, lit = 0, hidden = 0;
        vpl_rsm r0, r1;
        gim_mat4 vp0, vp1;
        gim_vpl *prev = (gim_vpl *)malloc(n * sizeof *prev), *twin = (gim_vpl *)malloc(n * sizeof *twin);
        gim_vpl *gpu = (gim_vpl *)malloc(n * sizeof *gpu);
        unsigned char *k0 = (unsigned char *)malloc(n), *k1 = (unsigned char *)malloc(n);
        GLuint out;
        int pass;
        flat_rsm(&r0, cases[c].size, 10.0f, 0.0f, 0.0f, &vp0);
        twin_vpls(&r0, n, NULL, vp0, prev, k0, f.env);
        flat_rsm(&r1, cases[c].size, 10.0f, cases[c].tx, cases[c].ty, &vp1);
        for (pass = 0; pass < 2; ++pass) {   /* the light moves, then stays */
            twin_vpls(&r1, n, prev, vp1, twin, k1, f.env);
            out = gltest_ssbo(n * sizeof *prev, prev);
            assert_int_equal(gim__gl_rsm_vpls_follow(f.ctx, r1.tex[0], r1.tex[1], r1.tex[2], r1.size, n,
                                                     GIM_VPL_SEQUENCE_HALTON, NULL, out, &vp1), GIM_OK);
            gltest_state_unchanged(&f);
            gltest_read_buffer(out, n * sizeof *gpu, gpu);
            glDeleteBuffers(1, &out);
            kept = lit = hidden = 0;
            for (i = 0; i < n; ++i) {
                if (gpu[i].kept != twin[i].kept)
                    fail_msg("case %u pass %d VPL %u: kept %g, the twin's %g", c, pass, i, (double)gpu[i].kept,
                             (double)twin[i].kept);
                assert_memory_equal(gpu[i].position, twin[i].position, 12);
                assert_memory_equal(gpu[i].normal, twin[i].normal, 12);
                assert_true(gpu[i].lit == twin[i].lit);
                for (a = 0; a < 3; ++a) {
                    double e = fabs((double)gpu[i].flux[a] - twin[i].flux[a]);
                    assert_true(twin[i].flux[a] == 0.0f ? gpu[i].flux[a] == 0.0f : e <= TOL_FLUX * twin[i].flux[a]);
                }
                assert_true(fabs((double)gpu[i].area - twin[i].area) <= TOL_FLUX * twin[i].area);
                lit += prev[i].lit == 1.0f;
                if (twin[i].kept == 1.0f) {
                    ++kept;
                    assert_memory_equal(twin[i].position, prev[i].position, 12);
                } else if (prev[i].lit == 1.0f) {
                    ++hidden;
                }
            }
            print_message("RSM %u^2, %u VPLs, the light %s: %u of %u lit VPLs kept\n", cases[c].size, n,
                          pass ? "still" : "moved", kept, lit);
            if (pass == 1) assert_int_equal(kept, lit);   /* nothing moved: every lit one stays */
            else assert_true(kept > (c == 0 ? lit / 2u : 0u) && hidden > lit / 10u);
            if (pass == 1)   /* its input back, but the flags of the VPLs drawn anew last time */
                for (i = 0; i < n; ++i) {
                    assert_memory_equal(gpu[i].position, prev[i].position, 12);
                    assert_memory_equal(gpu[i].normal, prev[i].normal, 12);
                }
            memcpy(prev, gpu, n * sizeof *prev);
            for (i = 0; i < n && pass == 1; ++i) assert_true(prev[i].lit != 1.0f || prev[i].kept == 1.0f);
        }
        free(prev); free(twin); free(gpu); free(k0); free(k1);
        rsm_free(&r0); rsm_free(&r1);
    }
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(matches_twin),
        cmocka_unit_test(bad_arguments),
        cmocka_unit_test(follows_twin),
        cmocka_unit_test(kmeans_matches_twin),
        cmocka_unit_test(kmeans_empty_cluster),
        cmocka_unit_test(vpls_into_kmeans),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
