/* The GPU VAL gather (Bischoff 2017 sec. 3: every RSM texel a VAL; sec. 4 eq. 13-15: 1 / (N P)
   weights) against its CPU twin gim_vals_gather_twin, element by element: FULL and BRSM, several
   lights laid end to end with `first`, every invalid-texel rule, the selected entries the
   twin rejects, zero GL errors and the GL state restored around every pass.

   Tolerances: position, normal, area and flux are bit for bit (both sides copy the texel's
   32 bits; -0, denormals and a non-unit normal included), and so is every weight 1 and every
   weight 0. A BRSM weight 1 / (N P) is computed in double on both sides, the same two
   operations in the same order, then rounded to float; GLSL promises double division and
   the double-to-float conversion only "at least single precision", so the bound allowed is
   the float one: <= 2.5 ulp division + 0.5 ulp product + 1 ulp rounding, < 4.2 ulp = 5e-7
   relative, checked at 1e-6. Seen on llvmpipe: 0 (every weight bit for bit). */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

static const double TOL_WEIGHT = 1e-6;

static float from_bits(uint32_t b) { float f; memcpy(&f, &b, 4); return f; }
static uint32_t bits_of(float f) { uint32_t b; memcpy(&b, &f, 4); return b; }

/* --- an RSM: the three RGBA32F textures' texels, and the twin's view of them ------------------ */

typedef struct rsm {
    uint32_t size;
    float *position4, *normal4, *flux4;   /* size^2 RGBA texels, row 0 first */
    float *position, *normal, *flux, *area, *valid;   /* gim_rsm_data arrays */
    GLuint tex[3];
} rsm;

/* Texels the tests know: every rule of the twin's validity, each at a fixed texel. */
enum {
    T_UNLIT = 0,          /* w = 0 */
    T_W_NEGATIVE,         /* w = -1 */
    T_W_NAN,              /* w = NaN */
    T_W_HALF,             /* w = 0.5: lit */
    T_W_INF,              /* w = +Inf: lit (> 0) */
    T_W_DENORMAL,         /* w = smallest denormal: lit (> 0) */
    T_POSITION_NAN,
    T_NORMAL_INF,
    T_FLUX_NAN,
    T_FLUX_NEGATIVE,      /* -0.1 */
    T_FLUX_NEG_DENORMAL,  /* -1e-40: negative, invalid */
    T_FLUX_NEG_ZERO,      /* -0: not negative, valid, copied as -0 */
    T_FLUX_DENORMAL,      /* 1e-40: valid, copied bit for bit */
    T_AREA_NEGATIVE,
    T_AREA_ZERO,          /* valid: a VAL of area 0 */
    T_AREA_NEG_ZERO,      /* valid, -0 */
    T_AREA_INF,
    T_NORMAL_NONUNIT,     /* (0, 3, 0): the twin copies it, so does the GPU */
    T_POSITION_DENORMAL,  /* x = 1e-42: valid, copied */
    T_SPECIAL_COUNT
};

static void rsm_make(rsm *r, uint32_t size, const float origin[3], float L) {
    size_t n = (size_t)size * size, t;
    memset(r, 0, sizeof *r);
    r->size = size;
    r->position4 = (float *)calloc(n * 4, sizeof(float));
    r->normal4 = (float *)calloc(n * 4, sizeof(float));
    r->flux4 = (float *)calloc(n * 4, sizeof(float));
    for (t = 0; t < n; ++t) {
        float *x = r->position4 + t * 4, *nn = r->normal4 + t * 4, *f = r->flux4 + t * 4, l;
        int a;
        for (a = 0; a < 3; ++a) x[a] = origin[a] + test_rnd(0.0f, L);
        x[3] = test_rand01() < 0.1 ? 0.0f : 1.0f;   /* some texels saw nothing */
        do {
            nn[0] = test_rnd(-1, 1); nn[1] = test_rnd(-1, 1); nn[2] = test_rnd(-1, 1);
            l = nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2];
        } while (l < 0.05f || l > 1.0f);
        l = 1.0f / sqrtf(l);
        nn[0] *= l; nn[1] *= l; nn[2] *= l;
        nn[3] = test_rnd(0.01f, 1.0f) * L * L / (float)n;
        f[0] = test_rnd(0, 2); f[1] = test_rnd(0, 2); f[2] = test_rnd(0, 2);
        f[3] = test_rnd(-5, 5);   /* ignored */
    }
    if (n >= T_SPECIAL_COUNT) {
        float *p = r->position4, *nm = r->normal4, *fl = r->flux4;
        p[T_UNLIT * 4 + 3] = 0.0f;
        p[T_W_NEGATIVE * 4 + 3] = -1.0f;
        p[T_W_NAN * 4 + 3] = NAN;
        p[T_W_HALF * 4 + 3] = 0.5f;
        p[T_W_INF * 4 + 3] = INFINITY;
        p[T_W_DENORMAL * 4 + 3] = from_bits(1u);
        for (t = T_POSITION_NAN; t < T_SPECIAL_COUNT; ++t) p[t * 4 + 3] = 1.0f;
        p[T_POSITION_NAN * 4 + 1] = NAN;
        nm[T_NORMAL_INF * 4 + 2] = -INFINITY;
        fl[T_FLUX_NAN * 4 + 0] = NAN;
        fl[T_FLUX_NEGATIVE * 4 + 1] = -0.1f;
        fl[T_FLUX_NEG_DENORMAL * 4 + 2] = -1e-40f;
        fl[T_FLUX_NEG_ZERO * 4 + 0] = -0.0f;
        fl[T_FLUX_DENORMAL * 4 + 1] = 1e-40f;
        nm[T_AREA_NEGATIVE * 4 + 3] = -0.5f;
        nm[T_AREA_ZERO * 4 + 3] = 0.0f;
        nm[T_AREA_NEG_ZERO * 4 + 3] = -0.0f;
        nm[T_AREA_INF * 4 + 3] = INFINITY;
        nm[T_NORMAL_NONUNIT * 4 + 0] = 0.0f; nm[T_NORMAL_NONUNIT * 4 + 1] = 3.0f; nm[T_NORMAL_NONUNIT * 4 + 2] = 0.0f;
        p[T_POSITION_DENORMAL * 4 + 0] = 1e-42f;
    }
    /* the twin's arrays */
    r->position = (float *)malloc(n * 3 * sizeof(float));
    r->normal = (float *)malloc(n * 3 * sizeof(float));
    r->flux = (float *)malloc(n * 3 * sizeof(float));
    r->area = (float *)malloc(n * sizeof(float));
    r->valid = (float *)malloc(n * sizeof(float));
    for (t = 0; t < n; ++t) {
        memcpy(r->position + t * 3, r->position4 + t * 4, 12);
        memcpy(r->normal + t * 3, r->normal4 + t * 4, 12);
        memcpy(r->flux + t * 3, r->flux4 + t * 4, 12);
        r->area[t] = r->normal4[t * 4 + 3];
        r->valid[t] = r->position4[t * 4 + 3];
    }
}

static GLuint texture_rgba(GLenum format, uint32_t size, const float *texels) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, format, (GLsizei)size, (GLsizei)size);
    if (texels) glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, (GLsizei)size, (GLsizei)size, GL_RGBA, GL_FLOAT, texels);
    glBindTexture(GL_TEXTURE_2D, 0);   /* the fixture's state again */
    return t;
}

static void rsm_upload(rsm *r) {
    r->tex[0] = texture_rgba(GL_RGBA32F, r->size, r->position4);
    r->tex[1] = texture_rgba(GL_RGBA32F, r->size, r->normal4);
    r->tex[2] = texture_rgba(GL_RGBA32F, r->size, r->flux4);
}

static gim_rsm_data rsm_data(const rsm *r) {
    gim_rsm_data d;
    memset(&d, 0, sizeof d);
    d.position = r->position; d.normal = r->normal; d.flux = r->flux; d.area = r->area; d.valid = r->valid;
    d.width = d.height = r->size;
    return d;
}

static void rsm_free(rsm *r) {
    glDeleteTextures(3, r->tex);
    free(r->position4); free(r->normal4); free(r->flux4);
    free(r->position); free(r->normal); free(r->flux); free(r->area); free(r->valid);
}

/* count random selections with random pdfs in (1e-6, 1]; every 7th repeats an earlier pick,
   the first T_SPECIAL_COUNT pick the special texels (when the RSM holds them). */
static gim_selected_val *random_selection(uint32_t size, uint32_t count) {
    gim_selected_val *s = (gim_selected_val *)calloc(count, sizeof *s);
    uint32_t i;
    for (i = 0; i < count; ++i) {
        if (i > 0 && i % 7 == 0) {
            s[i] = s[(uint32_t)(test_rand01() * i)];
            continue;
        }
        if (i < T_SPECIAL_COUNT && (size_t)size * size >= T_SPECIAL_COUNT) {
            s[i].x = i % size;
            s[i].y = i / size;
        } else {
            s[i].x = (uint32_t)(test_rand01() * size) % size;
            s[i].y = (uint32_t)(test_rand01() * size) % size;
        }
        s[i].pdf = (float)(1e-6 + (1.0 - 1e-6) * test_rand01() * test_rand01());
    }
    return s;
}

/* --- comparison --------------------------------------------------------------------------------- */

typedef struct gather_stats {
    double weight;        /* largest relative weight error */
    uint32_t weight_bits; /* weights that differ in any bit */
    uint32_t zero;        /* VALs of weight 0 */
} gather_stats;

/* gpu[0..n) against the twin's cpu[0..n): bit for bit but the BRSM weights (TOL_WEIGHT). */
static void compare(const gim_val *cpu, const gim_val *gpu, size_t n, gather_stats *st) {
    size_t i;
    for (i = 0; i < n; ++i) {
        const gim_val *c = cpu + i, *g = gpu + i;
        if (memcmp(c->position, g->position, 12) != 0 || memcmp(c->normal, g->normal, 12) != 0 ||
            memcmp(c->flux, g->flux, 12) != 0 || bits_of(c->area) != bits_of(g->area) || bits_of(g->unused) != 0u)
            fail_msg("VAL %zu differs: cpu (%g %g %g | %g | %g %g %g) gpu (%g %g %g | %g | %g %g %g)", i,
                     (double)c->position[0], (double)c->position[1], (double)c->position[2], (double)c->area,
                     (double)c->flux[0], (double)c->flux[1], (double)c->flux[2], (double)g->position[0],
                     (double)g->position[1], (double)g->position[2], (double)g->area, (double)g->flux[0],
                     (double)g->flux[1], (double)g->flux[2]);
        if (c->weight == 0.0f || c->weight == 1.0f) {
            if (bits_of(c->weight) != bits_of(g->weight))
                fail_msg("VAL %zu: weight %g, the twin's %g", i, (double)g->weight, (double)c->weight);
        } else {
            double e = fabs((double)g->weight - (double)c->weight) / (double)c->weight;
            if (e > st->weight) st->weight = e;
            if (bits_of(c->weight) != bits_of(g->weight)) st->weight_bits++;
            if (!(e <= TOL_WEIGHT)) fail_msg("VAL %zu: weight %.9g, the twin's %.9g", i, (double)g->weight, (double)c->weight);
        }
        if (c->weight == 0.0f) st->zero++;
    }
}

#define SENTINEL 0xdeadbeefu

static GLuint sentinel_buffer(size_t vals) {
    uint32_t *fill = (uint32_t *)malloc(vals * sizeof(gim_val));
    size_t i;
    GLuint b;
    for (i = 0; i < vals * 12; ++i) fill[i] = SENTINEL;
    b = gltest_ssbo(vals * sizeof(gim_val), fill);
    free(fill);
    return b;
}

static void assert_sentinel(const gim_val *v, size_t n) {
    const uint32_t *w = (const uint32_t *)(const void *)v;
    size_t i;
    for (i = 0; i < n * 12; ++i)
        if (w[i] != SENTINEL) fail_msg("word %zu outside the written range was overwritten", i);
}

/* One pass on r (selected NULL: FULL) into a buffer of first + count + 5 sentinel VALs, the
   twin alongside; every VAL compared, the sentinels around the range untouched. */
static void gather_one(gltest_fixture *f, const rsm *r, const gim_selected_val *sel, uint32_t count, uint32_t first,
                       gather_stats *st) {
    gim_rsm_data d = rsm_data(r);
    size_t n = sel ? count : (size_t)r->size * r->size, total = first + n + 5;
    gim_val *cpu = (gim_val *)calloc(n, sizeof *cpu), *gpu = (gim_val *)calloc(total, sizeof *gpu);
    GLuint out = sentinel_buffer(total), bsel = 0;
    assert_int_equal(gim_vals_gather_twin(&d, sel, count, cpu, f->env), GIM_OK);
    if (sel) bsel = gltest_ssbo(count * sizeof(gim_selected_val), sel);
    assert_int_equal(gim__gl_vals_gather(f->ctx, r->tex[0], r->tex[1], r->tex[2], r->size, bsel, sel ? count : 0u, out,
                                         first),
                     GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(out, total * sizeof(gim_val), gpu);
    assert_sentinel(gpu, first);
    assert_sentinel(gpu + first + n, 5);
    compare(cpu, gpu + first, n, st);
    glDeleteBuffers(1, &out);
    if (bsel) glDeleteBuffers(1, &bsel);
    free(cpu);
    free(gpu);
}

/* --- tests --------------------------------------------------------------------------------------- */

/* FULL and BRSM on RSMs of 64^2 (whole groups), 37^2 (a partial last group), 4^2 and 1^2,
   far from the origin as well, at first 0 and at an odd offset. */
static void matches_twin(void **state) {
    static const uint32_t sizes[4] = {64, 37, 4, 1};
    static const float origins[2][3] = {{0.0f, 0.0f, 0.0f}, {3.0e3f, -2.0e3f, 1.0e4f}};
    gltest_fixture f;
    gather_stats st;
    int s, o;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    for (s = 0; s < 4; ++s)
        for (o = 0; o < 2; ++o) {
            rsm r;
            gim_selected_val *sel;
            uint32_t count = sizes[s] * sizes[s] < 100u ? 50u : 1500u;
            rsm_make(&r, sizes[s], origins[o], o ? 50.0f : 4.0f);
            rsm_upload(&r);
            gather_one(&f, &r, NULL, 0, 0, &st);
            gather_one(&f, &r, NULL, 0, 13, &st);
            sel = random_selection(sizes[s], count);
            gather_one(&f, &r, sel, count, 0, &st);
            gather_one(&f, &r, sel, count, 5, &st);
            free(sel);
            rsm_free(&r);
        }
    print_message("VAL gather: largest relative weight error %.3g (%u weights not bit for bit), %u weight-0 VALs\n",
                  st.weight, st.weight_bits, st.zero);
    assert_true(st.zero > 100);   /* the invalid texels were there */
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Every special texel: as the twin, and the twin's verdict is the one each rule says (so a
   rule both sides got wrong the same way fails here too). */
static void validity_rules(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    static const int valid[T_SPECIAL_COUNT] = {0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 1, 1, 0, 1, 1, 0, 1, 1};
    gltest_fixture f;
    gather_stats st;
    rsm r;
    gim_rsm_data d;
    gim_val cpu[16 * 16];
    int t;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&r, 16, zero, 1.0f);
    rsm_upload(&r);
    d = rsm_data(&r);
    assert_int_equal(gim_vals_gather_twin(&d, NULL, 0, cpu, f.env), GIM_OK);
    for (t = 0; t < T_SPECIAL_COUNT; ++t) {
        static const gim_val none = {{0, 0, 0}, 0, {0, 0, 0}, 0, {0, 0, 0}, 0};
        if (valid[t]) {
            assert_true(cpu[t].weight == 1.0f);
            assert_memory_equal(cpu[t].position, r.position4 + t * 4, 12);
        } else {
            assert_memory_equal(&cpu[t], &none, sizeof none);
        }
    }
    assert_true(bits_of(cpu[T_FLUX_NEG_ZERO].flux[0]) == 0x80000000u);
    assert_true(bits_of(cpu[T_AREA_NEG_ZERO].area) == 0x80000000u);
    assert_true(cpu[T_NORMAL_NONUNIT].normal[1] == 3.0f);
    gather_one(&f, &r, NULL, 0, 0, &st);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Weights at the ends of the pdf range, in the twin's double then its clamp: a denormal pdf
   (1 / (N P) above FLT_MAX: clamped to FLT_MAX; or 2^-130, still a float), a pdf above 1
   (not a probability, but finite and > 0) whose weight is a float denormal, pdf FLT_MIN (the
   smallest gim__gl_importance_select writes) and 1. */
static void extreme_pdfs(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    gather_stats st;
    rsm r;
    gim_selected_val sel[8];
    gim_val cpu[8];
    gim_rsm_data d;
    uint32_t i;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&r, 8, zero, 1.0f);
    for (i = 0; i < 8 * 8; ++i) r.position4[i * 4 + 3] = r.valid[i] = 1.0f;   /* all lit */
    rsm_upload(&r);
    for (i = 0; i < 8; ++i) { sel[i].x = i; sel[i].y = 7 - i; }
    sel[0].pdf = from_bits(1u);               /* 2^-149 */
    sel[1].pdf = ldexpf(1.0f, -130);
    sel[2].pdf = 1e38f;                       /* weight 1 / (8e38): a float denormal */
    sel[3].pdf = FLT_MAX;
    sel[4].pdf = FLT_MIN;
    sel[5].pdf = 1.0f;
    sel[6].pdf = 0.125f;                      /* weight exactly 1 */
    sel[7].pdf = 3.0f;
    d = rsm_data(&r);
    assert_int_equal(gim_vals_gather_twin(&d, sel, 8, cpu, f.env), GIM_OK);
    assert_true(cpu[0].weight == FLT_MAX);
    assert_true(cpu[1].weight < FLT_MAX && cpu[1].weight > 1e37f);
    assert_true(cpu[2].weight > 0.0f && cpu[2].weight < FLT_MIN);
    assert_true(cpu[6].weight == 1.0f);
    gather_one(&f, &r, sel, 8, 3, &st);
    print_message("extreme pdfs: largest relative weight error %.3g\n", st.weight);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Where the two differ by design: a selected texel outside the RSM, or a pdf not finite and
   > 0, is GIM_ERROR_INVALID_ARGUMENT for the twin; the GPU writes an all-zero VAL there and
   the rest as the twin. The reference is the twin on the same list with each bad entry
   pointed at an unlit texel (same N, so the same weights elsewhere). */
static void bad_selections(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    gather_stats st;
    rsm r;
    gim_rsm_data d;
    gim_selected_val *sel, *ref, one;
    gim_val *cpu, *gpu, dummy;
    GLuint bsel, out;
    const uint32_t count = 300, size = 20;
    const uint32_t bad[9] = {17, 40, 41, 99, 150, 151, 200, 250, 299};
    uint32_t i;
    float pdfs[9];
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&r, size, zero, 1.0f);
    rsm_upload(&r);
    d = rsm_data(&r);
    sel = random_selection(size, count);
    ref = (gim_selected_val *)calloc(count, sizeof *ref);
    cpu = (gim_val *)calloc(count, sizeof *cpu);
    gpu = (gim_val *)calloc(count, sizeof *gpu);
    pdfs[0] = 0.0f; pdfs[1] = -0.0f; pdfs[2] = -0.5f; pdfs[3] = NAN; pdfs[4] = INFINITY; pdfs[5] = -from_bits(1u);
    memcpy(ref, sel, count * sizeof *sel);
    for (i = 0; i < 9; ++i) {
        gim_selected_val *s = sel + bad[i];
        if (i < 6) s->pdf = pdfs[i];
        else if (i == 6) s->x = size;                 /* one past the edge */
        else if (i == 7) s->y = size + 1000u;
        else { s->x = UINT32_MAX; s->y = UINT32_MAX; }
        /* the twin refuses each alone */
        one = *s;
        f.log.errors = 0;
        assert_int_equal(gim_vals_gather_twin(&d, &one, 1, &dummy, f.env), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(f.log.errors, 1);
        ref[bad[i]].x = T_UNLIT; ref[bad[i]].y = 0; ref[bad[i]].pdf = 0.5f;
    }
    f.log.errors = 0;
    assert_int_equal(gim_vals_gather_twin(&d, ref, count, cpu, f.env), GIM_OK);
    bsel = gltest_ssbo(count * sizeof *sel, sel);
    out = sentinel_buffer(count);
    assert_int_equal(gim__gl_vals_gather(f.ctx, r.tex[0], r.tex[1], r.tex[2], size, bsel, count, out, 0), GIM_OK);
    gltest_state_unchanged(&f);
    gltest_read_buffer(out, count * sizeof(gim_val), gpu);
    compare(cpu, gpu, count, &st);
    for (i = 0; i < 9; ++i) assert_true(gpu[bad[i]].weight == 0.0f && gpu[bad[i]].flux[0] == 0.0f);
    glDeleteBuffers(1, &bsel);
    glDeleteBuffers(1, &out);
    free(sel); free(ref); free(cpu); free(gpu);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Two lights in one buffer (the runtime's layout): light A FULL at [0, 64^2), light B BRSM
   at [64^2, 64^2 + 700) from a 32^2 RSM, and light A again BRSM after that; one read-back,
   each range against its own twin, nothing written past the end. */
static void lights_end_to_end(void **state) {
    static const float oa[3] = {0.0f, 0.0f, 0.0f}, ob[3] = {-10.0f, 5.0f, 2.0f};
    gltest_fixture f;
    gather_stats st;
    rsm a, b;
    gim_rsm_data da, db;
    gim_selected_val *sb, *sa;
    gim_val *cpu, *gpu;
    GLuint out, bsa, bsb;
    const uint32_t na = 64 * 64, nb = 700, nc = 333, total = na + nb + nc + 3;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&a, 64, oa, 3.0f);
    rsm_make(&b, 32, ob, 7.0f);
    rsm_upload(&a);
    rsm_upload(&b);
    da = rsm_data(&a);
    db = rsm_data(&b);
    sb = random_selection(32, nb);
    sa = random_selection(64, nc);
    cpu = (gim_val *)calloc(total, sizeof *cpu);
    gpu = (gim_val *)calloc(total, sizeof *gpu);
    assert_int_equal(gim_vals_gather_twin(&da, NULL, 0, cpu, f.env), GIM_OK);
    assert_int_equal(gim_vals_gather_twin(&db, sb, nb, cpu + na, f.env), GIM_OK);
    assert_int_equal(gim_vals_gather_twin(&da, sa, nc, cpu + na + nb, f.env), GIM_OK);
    out = sentinel_buffer(total);
    bsb = gltest_ssbo(nb * sizeof *sb, sb);
    bsa = gltest_ssbo(nc * sizeof *sa, sa);
    assert_int_equal(gim__gl_vals_gather(f.ctx, a.tex[0], a.tex[1], a.tex[2], 64, 0, 0, out, 0), GIM_OK);
    assert_int_equal(gim__gl_vals_gather(f.ctx, b.tex[0], b.tex[1], b.tex[2], 32, bsb, nb, out, na), GIM_OK);
    assert_int_equal(gim__gl_vals_gather(f.ctx, a.tex[0], a.tex[1], a.tex[2], 64, bsa, nc, out, na + nb), GIM_OK);
    gltest_state_unchanged(&f);
    gltest_read_buffer(out, total * sizeof(gim_val), gpu);
    compare(cpu, gpu, na + nb + nc, &st);
    assert_sentinel(gpu + na + nb + nc, 3);
    glDeleteBuffers(1, &out); glDeleteBuffers(1, &bsa); glDeleteBuffers(1, &bsb);
    free(sa); free(sb); free(cpu); free(gpu);
    rsm_free(&a);
    rsm_free(&b);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* The real producers: gim_update's RSM pass and GPU selection on a small scene (a floor and a
   wall, a sun), their textures and selected buffer fed to the gather as the
   runtime will; the twin reads the same textures back. Proves the formats and layouts meet
   (RGBA32F storage the image units accept, lit flag in position.w, area in normal.w, the
   12-byte selection), FULL and BRSM, and that the scene gives both lit and unlit texels. */
static void runtime_rsm_and_selection(void **state) {
    static const float quad_n[12] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
    static const uint16_t quad_i[6] = {0, 1, 2, 0, 2, 3};
    static const float quad_p[12] = {-1, 0, -1, -1, 0, 1, 1, 0, 1, 1, 0, -1};
    static const gim_material mat = {{0.7f, 0.6f, 0.5f}, {0.0f, 0.0f, 0.0f}, 0.0f};
    enum { N = 32, VALS = 200 };
    gltest_fixture f;
    gather_stats st;
    gim_mesh_desc md;
    gim_mesh quad;
    gim_instance inst[2];
    gim_light light;
    gim_frame fr;
    gim_frame_outputs o;
    float *pos4 = (float *)malloc(N * N * 16), *nrm4 = (float *)malloc(N * N * 16), *flux4 = (float *)malloc(N * N * 16);
    float p3[N * N * 3], n3[N * N * 3], f3[N * N * 3], area[N * N], valid[N * N];
    gim_selected_val sel[VALS];
    gim_val *cpu = (gim_val *)calloc(N * N, sizeof(gim_val)), *gpu = (gim_val *)calloc(N * N + VALS, sizeof(gim_val));
    gim_rsm_data d;
    GLuint out;
    int i, k, lit = 0;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    memset(&md, 0, sizeof md);
    md.data.positions = quad_p; md.data.vertex_count = 4; md.data.normals = quad_n;
    md.data.indices = quad_i; md.data.index_count = 6; md.data.index_type = GIM_INDEX_U16;
    assert_int_equal(gim_add_mesh(f.ctx, &md, &quad), GIM_OK);
    assert_int_equal(gim_set_materials(f.ctx, &mat, 1), GIM_OK);
    inst[0].mesh = quad;
    inst[0].model = gim_mat4_identity();
    inst[1].mesh = quad;
    inst[1].model = gim_mat4_identity();
    /* the second one a wall at x = -0.6 facing +x (the floor's light bounces onto it, and
       the camera sees it), half size, standing on the floor */
    inst[1].model.m[0] = 0.0f; inst[1].model.m[1] = -0.5f;
    inst[1].model.m[4] = 0.5f; inst[1].model.m[5] = 0.0f;
    inst[1].model.m[10] = 0.5f;
    inst[1].model.m[12] = -0.6f; inst[1].model.m[13] = 0.5f;
    assert_int_equal(gim_set_instances(f.ctx, inst, 2), GIM_OK);
    memset(&light, 0, sizeof light);
    light.irradiance = 3.0f;
    light.direction = gim_v3(0.3f, 1.0f, 0.2f);
    light.rsm_size = N;
    assert_int_equal(gim_set_lights(f.ctx, &light, 1), GIM_OK);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim_v3(2.0f, 2.5f, 3.0f), gim_v3(0.0f, 0.2f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(0.9f, 1.0f, 0.5f, 20.0f);
    fr.width = fr.height = 32;
    fr.lightskin.view_sample_count = 64;
    fr.lightskin.val_count = VALS;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    o = gim_outputs(f.ctx);
    assert_int_equal(o.lights[0].selected_count, VALS);
    /* the twin's view of the textures */
    for (i = 0; i < 3; ++i) {
        GLuint t = i == 0 ? o.lights[0].rsm_position : i == 1 ? o.lights[0].rsm_normal : o.lights[0].rsm_flux;
        glBindTexture(GL_TEXTURE_2D, t);
        glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, i == 0 ? pos4 : i == 1 ? nrm4 : flux4);
    }
    glBindTexture(GL_TEXTURE_2D, 0);
    for (i = 0; i < N * N; ++i) {
        for (k = 0; k < 3; ++k) { p3[i * 3 + k] = pos4[i * 4 + k]; n3[i * 3 + k] = nrm4[i * 4 + k]; f3[i * 3 + k] = flux4[i * 4 + k]; }
        area[i] = nrm4[i * 4 + 3];
        valid[i] = pos4[i * 4 + 3];
        lit += valid[i] > 0.0f;
    }
    assert_true(lit > N * N / 4 && lit < N * N);   /* both kinds of texel */
    gltest_read_buffer(o.lights[0].selected, sizeof sel, sel);
    memset(&d, 0, sizeof d);
    d.position = p3; d.normal = n3; d.flux = f3; d.area = area; d.valid = valid; d.width = d.height = N;
    gltest_state_unchanged(&f);   /* gim_update restored it too */
    out = sentinel_buffer(N * N + VALS);
    assert_int_equal(gim__gl_vals_gather(f.ctx, o.lights[0].rsm_position, o.lights[0].rsm_normal, o.lights[0].rsm_flux, N,
                                         0, 0, out, 0), GIM_OK);
    assert_int_equal(gim__gl_vals_gather(f.ctx, o.lights[0].rsm_position, o.lights[0].rsm_normal, o.lights[0].rsm_flux, N,
                                         o.lights[0].selected, VALS, out, N * N), GIM_OK);
    gltest_state_unchanged(&f);
    gltest_read_buffer(out, (N * N + VALS) * sizeof(gim_val), gpu);
    assert_int_equal(gim_vals_gather_twin(&d, NULL, 0, cpu, f.env), GIM_OK);
    compare(cpu, gpu, N * N, &st);
    assert_int_equal(gim_vals_gather_twin(&d, sel, VALS, cpu, f.env), GIM_OK);
    compare(cpu, gpu + N * N, VALS, &st);
    for (i = 0; i < VALS; ++i) assert_true(cpu[i].weight > 0.0f);   /* the selection picks lit texels only */
    print_message("runtime RSM %dx%d (%d lit) and %d selected: largest relative weight error %.3g\n", N, N, lit, VALS,
                  st.weight);
    glDeleteBuffers(1, &out);
    free(pos4); free(nrm4); free(flux4); free(cpu); free(gpu);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* More VALs than one row of work groups holds (65535 groups of 64): the pass dispatches a
   second row (65536 groups here), and the VAL index spans both. BRSM on a small RSM, so the
   test is one 200 MB buffer, not a 2048^2 RSM. Only reachable where GL_MAX_SHADER_STORAGE_BLOCK_SIZE
   holds 200 MB (GPUs; llvmpipe has 128 MB): there the VALs must be the twin's; elsewhere the
   pass must refuse with GIM_ERROR_OUT_OF_RANGE before touching the buffers. */
static void two_dispatch_rows(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    const uint32_t count = 65535u * 64u + 70u;
    gltest_fixture f;
    gather_stats st;
    rsm r;
    gim_rsm_data d;
    gim_selected_val *sel;
    gim_val *cpu, *gpu;
    GLuint bsel, out;
    uint32_t i;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&st, 0, sizeof st);
    rsm_make(&r, 16, zero, 1.0f);
    rsm_upload(&r);
    if ((uint64_t)f.ctx->max_ssbo_bytes < (uint64_t)count * sizeof(gim_val)) {
        /* refused on the sizes alone, before any buffer is looked at */
        bsel = gltest_ssbo(64, NULL);
        out = gltest_ssbo(64, NULL);
        assert_int_equal(gim__gl_vals_gather(f.ctx, r.tex[0], r.tex[1], r.tex[2], 16, bsel, count, out, 0),
                         GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(f.log.errors, 1);
        f.log.errors = 0;
        print_message("two dispatch rows: GL_MAX_SHADER_STORAGE_BLOCK_SIZE %lld < %llu bytes, refused as it must be\n",
                      (long long)f.ctx->max_ssbo_bytes, (unsigned long long)count * sizeof(gim_val));
    } else {
        d = rsm_data(&r);
        sel = (gim_selected_val *)malloc(count * sizeof *sel);
        cpu = (gim_val *)malloc(count * sizeof *cpu);
        gpu = (gim_val *)malloc(count * sizeof *gpu);
        for (i = 0; i < count; ++i) {   /* a pattern the index decides, cheaper than the RNG */
            uint32_t h = gim__hash32(i);
            sel[i].x = h & 15u;
            sel[i].y = (h >> 4) & 15u;
            sel[i].pdf = (float)((h >> 8) + 1u) * (1.0f / 16777216.0f);
        }
        assert_int_equal(gim_vals_gather_twin(&d, sel, count, cpu, f.env), GIM_OK);
        bsel = gltest_ssbo(count * sizeof *sel, sel);
        out = gltest_ssbo(count * sizeof(gim_val), NULL);
        assert_int_equal(gim__gl_vals_gather(f.ctx, r.tex[0], r.tex[1], r.tex[2], 16, bsel, count, out, 0), GIM_OK);
        gltest_read_buffer(out, count * sizeof(gim_val), gpu);
        compare(cpu, gpu, count, &st);
        print_message("two dispatch rows: %u VALs, largest relative weight error %.3g\n", count, st.weight);
        free(sel); free(cpu); free(gpu);
    }
    gltest_state_unchanged(&f);
    glDeleteBuffers(1, &bsel);
    glDeleteBuffers(1, &out);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Bad arguments: an error through the logger before any dispatch, nothing written, no GL
   error (the 2D-array texture's failed bind is cleared), the state restored. */
static void pass_arguments(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    rsm r;
    GLuint out, small, bsel, bsel_small, t16f, tsmall, tarray, *t;
    gim_selected_val sel[4];
    gim_val back[16 * 16 + 4];
    int errors = 0, i;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    rsm_make(&r, 16, zero, 1.0f);
    rsm_upload(&r);
    t = r.tex;
    for (i = 0; i < 4; ++i) { sel[i].x = (uint32_t)i; sel[i].y = 1; sel[i].pdf = 0.25f; }
    out = sentinel_buffer(16 * 16 + 4);
    small = sentinel_buffer(16 * 16 - 1);
    bsel = gltest_ssbo(sizeof sel, sel);
    bsel_small = gltest_ssbo(sizeof sel - 1, sel);
    t16f = texture_rgba(GL_RGBA16F, 16, NULL);
    tsmall = texture_rgba(GL_RGBA32F, 8, NULL);
    glGenTextures(1, &tarray);
    glBindTexture(GL_TEXTURE_2D_ARRAY, tarray);
    glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_RGBA32F, 16, 16, 2);
    glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
#define BAD(expect, call) do { assert_int_equal(call, expect); ++errors; assert_int_equal(f.log.errors, errors); } while (0)
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, 0, t[1], t[2], 16, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], 0, t[2], 16, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], 0, 16, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 0, 0, 0));
    BAD(GIM_ERROR_OUT_OF_RANGE, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 0, 0, 0, out, 0));
    BAD(GIM_ERROR_OUT_OF_RANGE, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16385, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 4, out, 0));
    BAD(GIM_ERROR_OUT_OF_RANGE, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 0, out, UINT32_MAX - 100u));
    BAD(GIM_ERROR_OUT_OF_RANGE, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel, UINT32_MAX, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel, 4, bsel, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 0, small, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 0, out, 5)); /* 256 + 5 > 260 */
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel_small, 4, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel, 5, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, 999999u, t[1], t[2], 16, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t[1], tsmall, 16, 0, 0, out, 0));
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, t[0], t16f, t[2], 16, 0, 0, out, 0));
    assert_non_null(strstr(f.log.last, "RGBA32F"));
    gltest.quiet = 1;   /* a 2D array texture is no 2D texture: GL 4.5 asks its target (no error); before,
                           the failed bind is one error, cleared by gimany */
    BAD(GIM_ERROR_INVALID_ARGUMENT, gim__gl_vals_gather(f.ctx, tarray, t[1], t[2], 16, 0, 0, out, 0));
    gltest.quiet = 0;
    assert_non_null(strstr(f.log.last, "not a 2D texture"));
    assert_int_equal(glGetError(), GL_NO_ERROR);
    assert_int_equal(gltest_errors(), f.ctx->gl.GetTextureParameteriv ? 0 : 1); /* 1: seen by the callback */
    gltest_reset_errors();
#undef BAD
    f.log.errors = 0;
    gltest_state_unchanged(&f);
    gltest_read_buffer(out, sizeof back, back);   /* nothing dispatched */
    assert_sentinel(back, 16 * 16 + 4);
    /* the limits are not off by one: first + count = 260 fits, 8^2 of a 16^2 texture is fine */
    assert_int_equal(gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, 0, 0, out, 4), GIM_OK);
    assert_int_equal(gim__gl_vals_gather(f.ctx, t[0], t[1], t[2], 16, bsel, 4, out, 256), GIM_OK);
    assert_int_equal(gim__gl_vals_gather(f.ctx, t[0], t[1], tsmall, 8, 0, 0, out, 0), GIM_OK);
    gltest_state_unchanged(&f);
    glDeleteBuffers(1, &out); glDeleteBuffers(1, &small); glDeleteBuffers(1, &bsel); glDeleteBuffers(1, &bsel_small);
    glDeleteTextures(1, &t16f); glDeleteTextures(1, &tsmall); glDeleteTextures(1, &tarray);
    rsm_free(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(matches_twin),
        cmocka_unit_test(validity_rules),
        cmocka_unit_test(extreme_pdfs),
        cmocka_unit_test(bad_selections),
        cmocka_unit_test(lights_end_to_end),
        cmocka_unit_test(two_dispatch_rows),
        cmocka_unit_test(runtime_rsm_and_selection),
        cmocka_unit_test(pass_arguments),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
