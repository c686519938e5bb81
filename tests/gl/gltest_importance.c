/* The GPU importance-sampling passes (Bischoff 2017 eq. 10-12 and the selection) against their CPU
   twins gim_importance_map / gim_importance_cumsum / gim_importance_select, and the two-level map
   against gim_importance_tile_map and the two-level selection, on small inputs,
   with zero GL errors and the GL state restored around every pass. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

/* --- inputs ---------------------------------------------------------------------------------- */

/* A w x h RSM of a box corner seen by a light: the lower half of the texels on the floor
   (y = 0, normal +y), the upper half on the back wall (z = 0, normal +z), size L, shifted by
   origin. Flux random in [0, 1)^3; a few texels invalid, black, or NaN. */
typedef struct rsm_data {
    int w, h;
    float *position, *normal, *flux, *valid; /* valid: the twin's rsm_valid (position.w on the GPU) */
} rsm_data;

static void make_rsm(rsm_data *r, int w, int h, float L, const float origin[3], int damaged) {
    int x, y;
    r->w = w;
    r->h = h;
    r->position = (float *)calloc((size_t)w * h * 3, sizeof(float));
    r->normal = (float *)calloc((size_t)w * h * 3, sizeof(float));
    r->flux = (float *)calloc((size_t)w * h * 3, sizeof(float));
    r->valid = (float *)calloc((size_t)w * h, sizeof(float));
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            size_t i = (size_t)y * w + x;
            float u = ((float)x + 0.5f) / (float)w, v = ((float)(y % (h / 2)) + 0.5f) / (float)(h / 2);
            float *p = r->position + i * 3, *n = r->normal + i * 3, *f = r->flux + i * 3;
            if (y < h / 2) { p[0] = u * L; p[1] = 0.0f; p[2] = v * L; n[1] = 1.0f; }
            else { p[0] = u * L; p[1] = v * L; p[2] = 0.0f; n[2] = 1.0f; }
            p[0] += origin[0]; p[1] += origin[1]; p[2] += origin[2];
            f[0] = (float)test_rand01(); f[1] = (float)test_rand01(); f[2] = (float)test_rand01();
            r->valid[i] = 1.0f;
        }
    if (damaged) {
        r->valid[5] = 0.0f;                              /* the RSM saw nothing */
        r->flux[7 * 3] = r->flux[7 * 3 + 1] = r->flux[7 * 3 + 2] = 0.0f; /* black */
        r->position[11 * 3 + 1] = NAN;                   /* a NaN position */
        r->normal[13 * 3] = r->normal[13 * 3 + 1] = r->normal[13 * 3 + 2] = 0.0f; /* no normal */
        r->flux[17 * 3 + 2] = INFINITY;                  /* an Inf flux */
    }
}

static void free_rsm(rsm_data *r) {
    free(r->position);
    free(r->normal);
    free(r->flux);
    free(r->valid);
}

/* n view samples in the box (on its floor and walls, facing in), one unusable (NaN normal). */
static gim_view_sample *make_view_samples(int n, float L, const float origin[3]) {
    gim_view_sample *s = (gim_view_sample *)calloc((size_t)n, sizeof *s);
    int i;
    for (i = 0; i < n; ++i) {
        float a = (float)test_rand01() * L, b = (float)test_rand01() * L;
        switch (i % 3) {
        case 0: s[i].position = gim_v3(a, 0.0f, b); s[i].normal = gim_v3(0.0f, 1.0f, 0.0f); break;
        case 1: s[i].position = gim_v3(0.0f, a, b); s[i].normal = gim_v3(1.0f, 0.0f, 0.0f); break;
        default: s[i].position = gim_v3(L, a, b); s[i].normal = gim_v3(-1.0f, 0.2f, 0.1f); break; /* not unit */
        }
        s[i].position = gim__v3_add(s[i].position, gim_v3(origin[0], origin[1], origin[2]));
    }
    if (n > 3) s[3].normal.y = NAN;
    return s;
}

/* --- GL objects -------------------------------------------------------------------------- */

static GLuint texture_rgba32f(int w, int h, const float *rgb, const float *alpha) {
    float *t = (float *)malloc((size_t)w * h * 4 * sizeof(float));
    GLuint tex = 0;
    int i;
    for (i = 0; i < w * h; ++i) {
        t[i * 4] = rgb[i * 3];
        t[i * 4 + 1] = rgb[i * 3 + 1];
        t[i * 4 + 2] = rgb[i * 3 + 2];
        t[i * 4 + 3] = alpha ? alpha[i] : 0.0f;
    }
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, w, h);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, w, h, GL_RGBA, GL_FLOAT, t);
    glBindTexture(GL_TEXTURE_2D, 0);
    free(t);
    return tex;
}



/* View samples as the GPU pass takes them: {vec4 position; vec4 normal}. */
static GLuint view_sample_buffer(const gim_view_sample *s, int n) {
    float *v = (float *)calloc((size_t)n * 8, sizeof(float));
    GLuint b;
    int i;
    for (i = 0; i < n; ++i) {
        v[i * 8] = s[i].position.x; v[i * 8 + 1] = s[i].position.y; v[i * 8 + 2] = s[i].position.z;
        v[i * 8 + 4] = s[i].normal.x; v[i * 8 + 5] = s[i].normal.y; v[i * 8 + 6] = s[i].normal.z;
    }
    b = gltest_ssbo((size_t)n * 32, v);
    free(v);
    return b;
}

/* The twins' desc of an RSM and its view samples. */
static gim_importance_desc importance_desc(const rsm_data *r, const gim_view_sample *vs, int n, float scene_scale,
                                           gim_env env) {
    gim_importance_desc d;
    memset(&d, 0, sizeof d);
    d.rsm_position = r->position; d.rsm_normal = r->normal; d.rsm_flux = r->flux; d.rsm_valid = r->valid;
    d.width = (uint32_t)r->w; d.height = (uint32_t)r->h; d.view_samples = vs; d.view_sample_count = (uint32_t)n;
    d.scene_scale = scene_scale; d.env = env;
    return d;
}

/* The RSM's three textures and the view samples' buffer, as the GPU passes read them. */
static void rsm_upload(const rsm_data *r, const gim_view_sample *vs, int n, GLuint *tp, GLuint *tn, GLuint *tf,
                       GLuint *bvs) {
    *tp = texture_rgba32f(r->w, r->h, r->position, r->valid);
    *tn = texture_rgba32f(r->w, r->h, r->normal, NULL);
    *tf = texture_rgba32f(r->w, r->h, r->flux, NULL);
    *bvs = view_sample_buffer(vs, n);
}

/* --- eq. 10-11 ------------------------------------------------------------------------------ */

/* GPU map of (rsm, samples) against the twin; returns the largest relative error. */
static double compare_map(gltest_fixture *f, const rsm_data *r, const gim_view_sample *vs, int n, float scene_scale,
                          float clamp, float *cpu_out) {
    gim_importance_desc d;
    GLuint tp, tn, tf, bvs, bmap;
    size_t texels = (size_t)r->w * r->h, i;
    float *gpu = (float *)malloc(texels * sizeof(float));
    float *cpu = cpu_out ? cpu_out : (float *)malloc(texels * sizeof(float));
    double worst = 0.0, max_cpu = 0.0;
    d = importance_desc(r, vs, n, scene_scale, f->env);
    d.clamp = clamp;
    assert_int_equal(gim_importance_map(&d, cpu), GIM_OK);
    rsm_upload(r, vs, n, &tp, &tn, &tf, &bvs);
    bmap = gltest_ssbo(texels * sizeof(float), NULL);
    assert_int_equal(gim__gl_importance_map(f->ctx, tp, tn, tf, (uint32_t)r->w, (uint32_t)r->h, bvs, (uint32_t)n,
                                            scene_scale, clamp, bmap),
                     GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(bmap, texels * sizeof(float), gpu);
    for (i = 0; i < texels; ++i) max_cpu = cpu[i] > max_cpu ? cpu[i] : max_cpu;
    assert_true(max_cpu > 0.0);
    for (i = 0; i < texels; ++i) {
        double e = fabs((double)gpu[i] - cpu[i]) / (cpu[i] > 1e-3 * max_cpu ? cpu[i] : 1e-3 * max_cpu);
        assert_true(gpu[i] >= 0.0f && gim__isfinitef(gpu[i]));
        if (cpu[i] == 0.0f) assert_true(gpu[i] == 0.0f); /* invalid, black, NaN texels and back-facing ones */
        if (e > worst) worst = e;
    }
    glDeleteTextures(1, &tp);
    glDeleteTextures(1, &tn);
    glDeleteTextures(1, &tf);
    glDeleteBuffers(1, &bvs);
    glDeleteBuffers(1, &bmap);
    free(gpu);
    if (!cpu_out) free(cpu);
    return worst;
}

/* The GPU map is the twin's within 1e-4 relative (floats against doubles: ~1e-6 seen). What
   breaks it: a missing clamp (eq. 11) or cosine, the flux luminance weights, dividing by S,
   the texel/sample order, normals left unnormalised (the third wall's are not unit), scaling
   positions before subtracting them (the far-from-origin case: ~1e-3 off), or an invalid/NaN
   texel getting a non-zero value. */
static void map_matches_twin(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    static const float far_away[3] = {2.0e4f, -1.0e4f, 3.0e4f};
    gltest_fixture f;
    rsm_data r;
    gim_view_sample *vs;
    double e;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);

    make_rsm(&r, 64, 64, 4.0f, zero, 1);
    vs = make_view_samples(48, 4.0f, zero);
    e = compare_map(&f, &r, vs, 48, 4.0f * 1.7320508f, 0.0f, NULL);
    print_message("importance map, 64x64 x 48 view samples: max relative error %.3g\n", e);
    assert_true(e < 1e-4);
    e = compare_map(&f, &r, vs, 48, 4.0f * 1.7320508f, 0.25f, NULL); /* a wide clamp shapes the map */
    assert_true(e < 1e-4);
    free(vs);
    free_rsm(&r);

    /* 300 view samples: more than one shared-memory tile (256), a partial last tile; and an
       RSM size that is no multiple of the 16x16 work group */
    make_rsm(&r, 40, 26, 4.0f, zero, 0);
    vs = make_view_samples(300, 4.0f, zero);
    e = compare_map(&f, &r, vs, 300, 7.0f, 0.0f, NULL);
    assert_true(e < 1e-4);
    free(vs);
    free_rsm(&r);

    /* the same box in millimetres and in kilometres: the twin's map, so the same map */
    {
        static const float scales[2] = {1e-3f, 1e3f};
        int k;
        for (k = 0; k < 2; ++k) {
            float L = 4.0f * scales[k];
            make_rsm(&r, 24, 24, L, zero, 0);
            vs = make_view_samples(16, L, zero);
            e = compare_map(&f, &r, vs, 16, L * 1.7320508f, 0.0f, NULL);
            assert_true(e < 1e-4);
            free(vs);
            free_rsm(&r);
        }
    }

    /* the same box 3e4 units from the origin (unit 1 m, box 50 m): float positions, same map */
    make_rsm(&r, 32, 32, 50.0f, far_away, 0);
    vs = make_view_samples(16, 50.0f, far_away);
    e = compare_map(&f, &r, vs, 16, 87.0f, 0.0f, NULL);
    print_message("importance map, 3e4 from the origin: max relative error %.3g\n", e);
    assert_true(e < 1e-4);
    free(vs);
    free_rsm(&r);

    gltest_fixture_end(&f);
    GLTEST_END();
}

/* --- eq. 12 ------------------------------------------------------------------------------- */

/* GPU tables of map against the twin's; returns the largest relative error of any entry. */
static double compare_cumsum(gltest_fixture *f, const float *map, uint32_t w, uint32_t h, uint32_t block_rows) {
    size_t texels = (size_t)w * h, i;
    double *cc = (double *)malloc(texels * sizeof(double)), *cr = (double *)malloc(w * sizeof(double));
    double *gc = (double *)malloc(texels * sizeof(double)), *gr = (double *)malloc(w * sizeof(double));
    GLuint bmap = gltest_ssbo(texels * sizeof(float), map), bc = gltest_ssbo(texels * sizeof(double), NULL),
           br = gltest_ssbo(w * sizeof(double), NULL);
    double worst = 0.0;
    assert_int_equal(gim_importance_cumsum(map, w, h, cc, cr, f->env), GIM_OK);
    assert_int_equal(gim__gl_importance_cumsum(f->ctx, bmap, bc, br, w, h, block_rows), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(bc, texels * sizeof(double), gc);
    gltest_read_buffer(br, w * sizeof(double), gr);
    for (i = 0; i < texels; ++i) {
        double e = fabs(gc[i] - cc[i]) / (cc[i] > 0.0 ? cc[i] : 1.0);
        if (e > worst) worst = e;
    }
    for (i = 0; i < w; ++i) {
        double e = fabs(gr[i] - cr[i]) / (cr[i] > 0.0 ? cr[i] : 1.0);
        if (e > worst) worst = e;
    }
    glDeleteBuffers(1, &bmap);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    free(cc); free(cr); free(gc); free(gr);
    return worst;
}

/* Tables within 1e-13 relative of the twin's (both double; only the order of the adds
   differs: ~1e-16 seen). A float scan is ~1e-7 off and fails; so do a lost block offset, an
   exclusive scan, a column/row mix-up, or a thread's run of columns added twice. */
static void cumsum_matches_twin(void **state) {
    static const uint32_t sizes[][3] = {
        {64, 64, 64},  /* one block: no offsets pass */
        {64, 64, 0},   /* default: 16 rows, 4 blocks */
        {300, 70, 0},  /* 5 blocks of 16, the last partial; 300 columns: 2 per thread, uneven */
        {1, 1, 0}, {1, 130, 7}, {700, 3, 1}};
    gltest_fixture f;
    size_t k, i;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    for (k = 0; k < sizeof sizes / sizeof sizes[0]; ++k) {
        uint32_t w = sizes[k][0], h = sizes[k][1];
        float *map = (float *)malloc((size_t)w * h * sizeof(float));
        double e;
        for (i = 0; i < (size_t)w * h; ++i) /* 12 decades, some zeros */
            map[i] = test_rand01() < 0.1 ? 0.0f : (float)pow(10.0, 12.0 * test_rand01() - 6.0);
        e = compare_cumsum(&f, map, w, h, sizes[k][2]);
        if (k == 2) print_message("cumsum 300x70: max relative error %.3g\n", e);
        assert_true(e < 1e-13);
        free(map);
    }
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Why double: a 4096-row column with 1e8 on top and ones below. In float every 1 is lost
   (1e8 + 1 == 1e8), so those texels would never be selected; in double the differences of
   the table are the map again, exactly. */
static void cumsum_keeps_small_texels(void **state) {
    enum { W = 4, H = 4096 };
    gltest_fixture f;
    float *map = (float *)malloc((size_t)W * H * sizeof(float));
    double *col = (double *)malloc((size_t)W * H * sizeof(double)), row[W];
    GLuint bmap, bc, br;
    int i, x, y;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    for (i = 0; i < W * H; ++i) map[i] = i < W ? 1e8f : 1.0f;
    bmap = gltest_ssbo(sizeof(float) * W * H, map);
    bc = gltest_ssbo(sizeof(double) * W * H, NULL);
    br = gltest_ssbo(sizeof row, NULL);
    assert_int_equal(gim__gl_importance_cumsum(f.ctx, bmap, bc, br, W, H, 0), GIM_OK);
    gltest_read_buffer(bc, sizeof(double) * W * H, col);
    gltest_read_buffer(br, sizeof row, row);
    for (x = 0; x < W; ++x)
        for (y = 1; y < H; ++y) assert_true(col[y * W + x] - col[(y - 1) * W + x] == 1.0);
    assert_true(row[W - 1] == W * (1e8 + (H - 1)));
    glDeleteBuffers(1, &bmap);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    free(map);
    free(col);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* --- selection ------------------------------------------------------------------------------ */

/* GPU selection from the given tables against the twin's; returns the number of picks that
   differ (and checks pdfs where they agree). */
static int compare_select(gltest_fixture *f, const double *column, const double *row, GLuint bc, GLuint br, uint32_t w,
                          uint32_t h, uint32_t count, uint32_t seed, test_log *warn_log) {
    gim_selected_val *cpu = (gim_selected_val *)malloc(count * sizeof *cpu);
    gim_selected_val *gpu = (gim_selected_val *)malloc(count * sizeof *gpu);
    GLuint bout = gltest_ssbo(count * sizeof *gpu, NULL);
    gim_select_desc sd;
    uint32_t i;
    int differ = 0;
    memset(&sd, 0, sizeof sd);
    sd.column = column; sd.row = row; sd.width = w; sd.height = h; sd.count = count; sd.seed = seed;
    sd.env = warn_log ? test_env(NULL, warn_log) : f->env;
    assert_int_equal(gim_importance_select(&sd, cpu), GIM_OK);
    assert_int_equal(gim__gl_importance_select(f->ctx, bc, br, w, h, count, seed, bout), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(bout, count * sizeof *gpu, gpu);
    for (i = 0; i < count; ++i) {
        assert_true(gpu[i].x < w && gpu[i].y < h);
        assert_true(gpu[i].pdf > 0.0f && gpu[i].pdf <= 1.0f);
        if (gpu[i].x != cpu[i].x || gpu[i].y != cpu[i].y) { ++differ; continue; }
        assert_true(fabs((double)gpu[i].pdf - cpu[i].pdf) <= 1e-6 * cpu[i].pdf);
    }
    glDeleteBuffers(1, &bout);
    free(cpu);
    free(gpu);
    return differ;
}

/* From the same tables the GPU picks exactly the twin's texels (same u, v, same search) with
   the same pdf (1e-6 relative). What breaks it: another sample sequence or rotation, an
   off-by-one in the search, P from the wrong differences, or the u * total == total case. */
static void select_matches_twin(void **state) {
    enum { W = 64, H = 64, N = 256 };
    gltest_fixture f;
    float *map = (float *)malloc(sizeof(float) * W * H);
    double *col = (double *)malloc(sizeof(double) * W * H), row[W];
    GLuint bc, br;
    uint32_t seed;
    int i;
    test_log wl;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    /* a peaked map with empty columns and rows: the search must step over zero-width entries */
    for (i = 0; i < W * H; ++i) {
        int x = i % W, y = i / W;
        map[i] = (x % 7 == 3 || y % 5 == 1) ? 0.0f : (float)(test_rand01() * (x == 40 ? 1000.0 : 1.0));
    }
    assert_int_equal(gim_importance_cumsum(map, W, H, col, row, f.env), GIM_OK);
    bc = gltest_ssbo(sizeof(double) * W * H, col);
    br = gltest_ssbo(sizeof row, row);
    for (seed = 0; seed < 4; ++seed) assert_int_equal(compare_select(&f, col, row, bc, br, W, H, N, seed, NULL), 0);
    assert_int_equal(compare_select(&f, col, row, bc, br, W, H, 1, 9, NULL), 0);
    assert_int_equal(compare_select(&f, col, row, bc, br, W, H, 1000, 9, NULL), 0);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);

    /* all-zero map: both select uniformly with pdf 1 / texels (the twin also warns) */
    for (i = 0; i < W * H; ++i) map[i] = 0.0f;
    assert_int_equal(gim_importance_cumsum(map, W, H, col, row, f.env), GIM_OK);
    bc = gltest_ssbo(sizeof(double) * W * H, col);
    br = gltest_ssbo(sizeof row, row);
    assert_int_equal(compare_select(&f, col, row, bc, br, W, H, N, 3, &wl), 0);
    assert_int_equal(wl.warnings, 1);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    free(map);
    free(col);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* The whole chain on the GPU (map -> tables -> selection) against the whole chain on the CPU.
   The maps differ by float rounding (~1e-6), which can move a pick whose u lands that close to
   a boundary: at most 1 of 512 may differ; a wrong pass makes most of them differ. */
static void chain_matches_twin(void **state) {
    enum { W = 64, H = 64, S = 32, N = 512 };
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    rsm_data r;
    gim_view_sample *vs;
    float *map = (float *)malloc(sizeof(float) * W * H);
    double *col = (double *)malloc(sizeof(double) * W * H), row[W];
    gim_selected_val cpu[N], gpu[N];
    gim_select_desc sd;
    GLuint tp, tn, tf, bvs, bmap, bc, br, bout;
    int i, differ = 0;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_rsm(&r, W, H, 3.0f, zero, 1);
    vs = make_view_samples(S, 3.0f, zero);
    assert_true(compare_map(&f, &r, vs, S, 5.0f, 0.0f, map) < 1e-4);
    assert_int_equal(gim_importance_cumsum(map, W, H, col, row, f.env), GIM_OK);
    memset(&sd, 0, sizeof sd);
    sd.column = col; sd.row = row; sd.width = W; sd.height = H; sd.count = N; sd.seed = 11; sd.env = f.env;
    assert_int_equal(gim_importance_select(&sd, cpu), GIM_OK);

    tp = texture_rgba32f(W, H, r.position, r.valid);
    tn = texture_rgba32f(W, H, r.normal, NULL);
    tf = texture_rgba32f(W, H, r.flux, NULL);
    bvs = view_sample_buffer(vs, S);
    bmap = gltest_ssbo(sizeof(float) * W * H, NULL);
    bc = gltest_ssbo(sizeof(double) * W * H, NULL);
    br = gltest_ssbo(sizeof row, NULL);
    bout = gltest_ssbo(sizeof gpu, NULL);
    assert_int_equal(gim__gl_importance_map(f.ctx, tp, tn, tf, W, H, bvs, S, 5.0f, 0.0f, bmap), GIM_OK);
    assert_int_equal(gim__gl_importance_cumsum(f.ctx, bmap, bc, br, W, H, 0), GIM_OK);
    assert_int_equal(gim__gl_importance_select(f.ctx, bc, br, W, H, N, 11, bout), GIM_OK);
    gltest_state_unchanged(&f);
    gltest_read_buffer(bout, sizeof gpu, gpu);
    for (i = 0; i < N; ++i) {
        if (gpu[i].x != cpu[i].x || gpu[i].y != cpu[i].y) { ++differ; continue; }
        assert_true(fabs((double)gpu[i].pdf - cpu[i].pdf) <= 1e-4 * cpu[i].pdf);
    }
    print_message("GPU chain vs CPU chain: %d of %d picks differ\n", differ, N);
    assert_true(differ <= 1);
    glDeleteTextures(1, &tp);
    glDeleteTextures(1, &tn);
    glDeleteTextures(1, &tf);
    glDeleteBuffers(1, &bvs);
    glDeleteBuffers(1, &bmap);
    glDeleteBuffers(1, &bc);
    glDeleteBuffers(1, &br);
    glDeleteBuffers(1, &bout);
    free(vs);
    free_rsm(&r);
    free(map);
    free(col);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* --- two-level map (gim_importance_tile_map, gim_importance_select with tile > 1) -------------- */



/* The GPU tile map and texel weights against the twin's, then the GPU's two-level selection
   from the same tables and weights against the twin's (exactly the same texels, pdf 1e-6), and
   the whole GPU chain (tile map -> tables -> selection) against the CPU chain (at most 1 of 512
   picks may move by float rounding). Returns the largest relative error of the tile map and the
   weights. What breaks
   it: a wrong aggregate (unweighted mean position or normal, the normal left unnormalised, the
   invalid texels counted), the weights' validity, a wrong tile's texel range at the edges, the
   residual or the running sum of the pick, P without weight / sum, a texel given the wrong
   plane (the 40x26 box's tiles of 4 and 7 in the row where the floor meets the wall hold both). */
static double compare_tiles(gltest_fixture *f, const rsm_data *r, const gim_view_sample *vs, int n, float scene_scale,
                            uint32_t T) {
    enum { N = 512 };
    uint32_t w = (uint32_t)r->w, h = (uint32_t)r->h, tw = (w - 1) / T + 1, th = (h - 1) / T + 1;
    size_t texels = (size_t)w * h, cells = (size_t)tw * th, i;
    float *ct = (float *)malloc(cells * sizeof(float)), *gt = (float *)malloc(cells * sizeof(float));
    float *cw = (float *)malloc(texels * sizeof(float)), *gw = (float *)malloc(texels * sizeof(float));
    double *col = (double *)malloc(cells * sizeof(double)), *row = (double *)malloc(tw * sizeof(double));
    double worst = 0.0, max_cpu = 0.0;
    gim_selected_val cpu[N], gpu[N], chain_cpu[N];
    gim_importance_desc d;
    gim_select_desc sd;
    GLuint tp, tn, tf, bvs, btiles, bweight, bc, br, bout;
    float off[4];
    int differ = 0;
    d = importance_desc(r, vs, n, scene_scale, f->env);
    assert_int_equal(gim_importance_tile_map(&d, T, ct, cw), GIM_OK);
    rsm_upload(r, vs, n, &tp, &tn, &tf, &bvs);
    btiles = gltest_ssbo(cells * sizeof(float), NULL);
    bweight = gltest_ssbo(texels * sizeof(float), NULL);
    assert_int_equal(gim__gl_importance_tile_map(f->ctx, tp, tn, tf, w, h, T, bvs, (uint32_t)n, scene_scale, 0.0f,
                                                 btiles, bweight), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(btiles, cells * sizeof(float), gt);
    gltest_read_buffer(bweight, texels * sizeof(float), gw);
    for (i = 0; i < texels; ++i) {   /* weights: luminance x eq. 10 of the texel's plane, float against double */
        double e = fabs((double)gw[i] - cw[i]) / (cw[i] > 0.0f ? cw[i] : 1.0f);
        if (cw[i] == 0.0f) assert_true(gw[i] == 0.0f);
        if (e > worst) worst = e;
    }
    for (i = 0; i < cells; ++i) max_cpu = ct[i] > max_cpu ? ct[i] : max_cpu;
    assert_true(max_cpu > 0.0);
    for (i = 0; i < cells; ++i) {
        double e = fabs((double)gt[i] - ct[i]) / (ct[i] > 1e-3 * max_cpu ? ct[i] : 1e-3 * max_cpu);
        assert_true(gt[i] >= 0.0f && gim__isfinitef(gt[i]));
        if (ct[i] == 0.0f) assert_true(gt[i] == 0.0f);
        if (e > worst) worst = e;
    }
    /* the selection from the GPU's map and weights: the twin's picks exactly */
    gim_rotation_offsets(off, 4u, 5u);
    memset(&sd, 0, sizeof sd);
    sd.width = tw; sd.height = th; sd.count = N; sd.offsets = off; sd.tile = T; sd.rsm_width = w; sd.rsm_height = h;
    sd.env = f->env;
    assert_int_equal(gim_importance_cumsum(gt, tw, th, col, row, f->env), GIM_OK);
    sd.column = col; sd.row = row; sd.weight = gw;
    assert_int_equal(gim_importance_select(&sd, cpu), GIM_OK);
    bc = gltest_ssbo(cells * sizeof(double), col);
    br = gltest_ssbo(tw * sizeof(double), row);
    bout = gltest_ssbo(sizeof gpu, NULL);
    assert_int_equal(gim__gl_importance_select_tiles(f->ctx, bc, br, tw, th, N, off, T, bweight, w, h, bout), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(bout, sizeof gpu, gpu);
    for (i = 0; i < N; ++i) {
        assert_true(gpu[i].x == cpu[i].x && gpu[i].y == cpu[i].y);
        assert_true(gpu[i].pdf > 0.0f && fabs((double)gpu[i].pdf - cpu[i].pdf) <= 1e-6 * cpu[i].pdf);
        assert_true(cw[(size_t)gpu[i].y * w + gpu[i].x] > 0.0f);
    }
    /* the whole chain on each side */
    assert_int_equal(gim_importance_cumsum(ct, tw, th, col, row, f->env), GIM_OK);
    sd.weight = cw;
    assert_int_equal(gim_importance_select(&sd, chain_cpu), GIM_OK);
    assert_int_equal(gim__gl_importance_cumsum(f->ctx, btiles, bc, br, tw, th, 0), GIM_OK);
    assert_int_equal(gim__gl_importance_select_tiles(f->ctx, bc, br, tw, th, N, off, T, bweight, w, h, bout), GIM_OK);
    gltest_read_buffer(bout, sizeof gpu, gpu);
    for (i = 0; i < N; ++i) {
        if (gpu[i].x != chain_cpu[i].x || gpu[i].y != chain_cpu[i].y) { ++differ; continue; }
        assert_true(fabs((double)gpu[i].pdf - chain_cpu[i].pdf) <= 1e-4 * chain_cpu[i].pdf);
    }
    assert_true(differ <= 1);
    glDeleteTextures(1, &tp); glDeleteTextures(1, &tn); glDeleteTextures(1, &tf);
    glDeleteBuffers(1, &bvs); glDeleteBuffers(1, &btiles); glDeleteBuffers(1, &bweight);
    glDeleteBuffers(1, &bc); glDeleteBuffers(1, &br); glDeleteBuffers(1, &bout);
    free(ct); free(gt); free(cw); free(gw); free(col); free(row);
    return worst;
}

/* The two-level passes against their twins: tiles of 8 on the damaged 64x64 box (invalid, black,
   NaN, Inf texels), tiles of 4 and 7 on a 40x26 RSM (partial edge tiles) with 300 view samples
   (several shared-memory chunks of 64), tile 1, and the box 3e4 units from the origin. The tile
   map and the weights are within 1e-4 of the twin's (floats against doubles), the selections as
   compare_tiles says. */
static void tiles_match_twin(void **state) {
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    static const float far_away[3] = {2.0e4f, -1.0e4f, 3.0e4f};
    gltest_fixture f;
    rsm_data r;
    gim_view_sample *vs;
    double e;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_rsm(&r, 64, 64, 4.0f, zero, 1);
    vs = make_view_samples(48, 4.0f, zero);
    e = compare_tiles(&f, &r, vs, 48, 4.0f * 1.7320508f, 8);
    print_message("tile map, 64x64 in tiles of 8 x 48 view samples: max relative error %.3g\n", e);
    assert_true(e < 1e-4);
    free(vs);
    free_rsm(&r);
    make_rsm(&r, 40, 26, 4.0f, zero, 0);
    vs = make_view_samples(300, 4.0f, zero);
    assert_true(compare_tiles(&f, &r, vs, 300, 7.0f, 4) < 1e-4);
    assert_true(compare_tiles(&f, &r, vs, 300, 7.0f, 7) < 1e-4);
    assert_true(compare_tiles(&f, &r, vs, 300, 7.0f, 1) < 1e-4);
    free(vs);
    free_rsm(&r);
    make_rsm(&r, 32, 32, 50.0f, far_away, 0);
    vs = make_view_samples(16, 50.0f, far_away);
    e = compare_tiles(&f, &r, vs, 16, 87.0f, 8);
    print_message("tile map, 3e4 from the origin: max relative error %.3g\n", e);
    assert_true(e < 1e-4);
    free(vs);
    free_rsm(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* The defensive share on the GPU against its twins (tile 1 and T): the luminance map
   (gim__gl_importance_map_lum / gim__gl_importance_tile_map_lum) is gim_importance_luminance's
   (1e-6, zero exactly where zero), and the mixture selection from the GPU's importance and
   luminance (tables made on the CPU from them) gives the twin's texels exactly and its pdf
   within 1e-6, with an eighth of the picks by luminance. Returns the picks of texels whose
   importance is 0. Breaks with: the luminance of an invalid texel, a tile sum of the wrong
   texels, the two sets' Hammersley points or offsets, the other set's pdf left out. */
static uint32_t compare_defensive(gltest_fixture *f, const rsm_data *r, const gim_view_sample *vs, int n,
                                  float scene_scale, uint32_t T) {
    enum { N = 512 };
    uint32_t w = (uint32_t)r->w, h = (uint32_t)r->h, tw = (w - 1) / T + 1, th = (h - 1) / T + 1, zero = 0;
    size_t texels = (size_t)w * h, cells = (size_t)tw * th, i;
    float *cl = (float *)malloc(cells * sizeof(float)), *gl_ = (float *)malloc(cells * sizeof(float));
    float *clw = (float *)malloc(texels * sizeof(float)), *glw = (float *)malloc(texels * sizeof(float));
    float *gm = (float *)malloc(cells * sizeof(float)), *gw = (float *)malloc(texels * sizeof(float));
    double *col = (double *)malloc(cells * sizeof(double)), *row = (double *)malloc(tw * sizeof(double));
    double *lcol = (double *)malloc(cells * sizeof(double)), *lrow = (double *)malloc(tw * sizeof(double));
    gim_selected_val cpu[N], gpu[N];
    gim_importance_desc d;
    gim_select_desc sd;
    gim__gl_defensive dfs;
    GLuint tp, tn, tf, bvs, bm, bw, blt, blw, bc, br, blc, blr, bout;
    float off[4];
    d = importance_desc(r, vs, n, scene_scale, f->env);
    assert_int_equal(gim_importance_luminance(&d, T, cl, clw), GIM_OK);
    rsm_upload(r, vs, n, &tp, &tn, &tf, &bvs);
    bm = gltest_ssbo(cells * sizeof(float), NULL);      /* importance: tile map or per-texel map */
    bw = gltest_ssbo(texels * sizeof(float), NULL);     /* T > 1: importance weights */
    blt = gltest_ssbo(cells * sizeof(float), NULL);     /* luminance per tile (T > 1) */
    blw = gltest_ssbo(texels * sizeof(float), NULL);    /* luminance per texel */
    if (T > 1)
        assert_int_equal(gim__gl_importance_tile_map_lum(f->ctx, tp, tn, tf, w, h, T, bvs, (uint32_t)n, scene_scale, 0.0f,
                                                         bm, bw, blt, blw), GIM_OK);
    else
        assert_int_equal(gim__gl_importance_map_lum(f->ctx, tp, tn, tf, w, h, bvs, (uint32_t)n, scene_scale, 0.0f, bm,
                                                    blw), GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(blw, texels * sizeof(float), glw);
    gltest_read_buffer(bm, cells * sizeof(float), gm);
    if (T > 1) {
        gltest_read_buffer(blt, cells * sizeof(float), gl_);
        gltest_read_buffer(bw, texels * sizeof(float), gw);
    } else {
        memcpy(gl_, glw, cells * sizeof(float));
        memcpy(gw, gm, texels * sizeof(float));
    }
    for (i = 0; i < texels; ++i) assert_true(clw[i] == 0.0f ? glw[i] == 0.0f : fabs((double)glw[i] - clw[i]) <= 1e-6 * clw[i]);
    for (i = 0; i < cells; ++i) assert_true(cl[i] == 0.0f ? gl_[i] == 0.0f : fabs((double)gl_[i] - cl[i]) <= 1e-5 * cl[i]);
    /* a fifth of the texels without importance (as where no view sample sees them), the tile
       sums made again from the weights: the luminance's picks land there too */
    for (i = 0; i < texels; ++i)
        if ((i % w + 3u * (i / w)) % 5u == 2u) gw[i] = 0.0f;
    if (T > 1) {
        memset(gm, 0, cells * sizeof(float));
        for (i = 0; i < texels; ++i) gm[((i / w) / T) * tw + (i % w) / T] += gw[i];
    } else {
        memcpy(gm, gw, texels * sizeof(float));
    }
    glDeleteBuffers(1, &bw);
    bw = gltest_ssbo(texels * sizeof(float), gw);
    /* the mixture's selection from the GPU's maps, both sides on the same tables */
    assert_int_equal(gim_importance_cumsum(gm, tw, th, col, row, f->env), GIM_OK);
    assert_int_equal(gim_importance_cumsum(gl_, tw, th, lcol, lrow, f->env), GIM_OK);
    gim_rotation_offsets(off, 4u, 9u);
    memset(&sd, 0, sizeof sd);
    sd.column = col; sd.row = row; sd.width = tw; sd.height = th; sd.count = N; sd.offsets = off; sd.tile = T;
    sd.weight = T > 1 ? gw : NULL; sd.rsm_width = w; sd.rsm_height = h; sd.env = f->env;
    sd.defensive_count = N / 8; sd.lum_column = lcol; sd.lum_row = lrow; sd.lum_weight = T > 1 ? glw : NULL;
    assert_int_equal(gim_importance_select(&sd, cpu), GIM_OK);
    bc = gltest_ssbo(cells * sizeof(double), col);
    br = gltest_ssbo(tw * sizeof(double), row);
    blc = gltest_ssbo(cells * sizeof(double), lcol);
    blr = gltest_ssbo(tw * sizeof(double), lrow);
    bout = gltest_ssbo(sizeof gpu, NULL);
    dfs.count = N / 8; dfs.lum_column = blc; dfs.lum_row = blr; dfs.lum_weight = T > 1 ? blw : 0u;
    assert_int_equal(gim__gl_importance_select_mix(f->ctx, bc, br, tw, th, N, off, T, T > 1 ? bw : 0u, w, h, &dfs, bout),
                     GIM_OK);
    gltest_state_unchanged(f);
    gltest_read_buffer(bout, sizeof gpu, gpu);
    for (i = 0; i < N; ++i) {
        size_t idx = (size_t)gpu[i].y * w + gpu[i].x;
        assert_true(gpu[i].x == cpu[i].x && gpu[i].y == cpu[i].y);
        assert_true(gpu[i].pdf > 0.0f && fabs((double)gpu[i].pdf - cpu[i].pdf) <= 1e-6 * cpu[i].pdf);
        assert_true(glw[idx] > 0.0f);
        zero += gw[idx] == 0.0f;
    }
    /* refused before any GL work: a share of every pick, the tables missing */
    dfs.count = N;
    assert_int_equal(gim__gl_importance_select_mix(f->ctx, bc, br, tw, th, N, off, T, T > 1 ? bw : 0u, w, h, &dfs, bout),
                     GIM_ERROR_INVALID_ARGUMENT);
    dfs.count = N / 8; dfs.lum_row = 0u;
    assert_int_equal(gim__gl_importance_select_mix(f->ctx, bc, br, tw, th, N, off, T, T > 1 ? bw : 0u, w, h, &dfs, bout),
                     GIM_ERROR_INVALID_ARGUMENT);
    glDeleteTextures(1, &tp); glDeleteTextures(1, &tn); glDeleteTextures(1, &tf);
    glDeleteBuffers(1, &bvs); glDeleteBuffers(1, &bm); glDeleteBuffers(1, &bw); glDeleteBuffers(1, &blt);
    glDeleteBuffers(1, &blw); glDeleteBuffers(1, &bc); glDeleteBuffers(1, &br); glDeleteBuffers(1, &blc);
    glDeleteBuffers(1, &blr); glDeleteBuffers(1, &bout);
    free(cl); free(gl_); free(clw); free(glw); free(gm); free(gw); free(col); free(row); free(lcol); free(lrow);
    return zero;
}

/* The defensive share's passes against their twins on the damaged 64x64 box (invalid, black,
   NaN, Inf texels; back-facing ones of importance 0): per texel and in tiles of 8 and 7. */
static void defensive_matches_twin(void **state) {
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    gltest_fixture f;
    rsm_data r;
    gim_view_sample *vs;
    uint32_t z1, z8, z7;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    make_rsm(&r, 64, 64, 4.0f, origin, 1);
    vs = make_view_samples(48, 4.0f, origin);
    z1 = compare_defensive(&f, &r, vs, 48, 4.0f * 1.7320508f, 1);
    z8 = compare_defensive(&f, &r, vs, 48, 4.0f * 1.7320508f, 8);
    z7 = compare_defensive(&f, &r, vs, 48, 4.0f * 1.7320508f, 7);
    print_message("defensive share: 512 picks, 64 by luminance; picks of importance 0: %u (per texel), %u (tiles of 8), "
                  "%u (tiles of 7)\n", z1, z8, z7);
    assert_true(z1 > 0u && z8 > 0u && z7 > 0u);
    assert_int_equal(f.log.errors, 6);   /* the refusals, one line each */
    f.log.errors = 0;
    free(vs);
    free_rsm(&r);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* Bad arguments: an error through the logger, no GL touched, no GL error. */
static void pass_arguments(void **state) {
    gltest_fixture f;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    assert_int_equal(gim__gl_importance_map(f.ctx, 0, 1, 1, 4, 4, 1, 1, 1.0f, 0.0f, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_map(f.ctx, 1, 1, 1, 4, 4, 1, 0, 1.0f, 0.0f, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_map(f.ctx, 1, 1, 1, 4, 4, 1, 1, NAN, 0.0f, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_map(f.ctx, 1, 1, 1, 4, 4, 1, 1, 1.0f, -1.0f, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_map(f.ctx, 1, 1, 1, 0, 4, 1, 1, 1.0f, 0.0f, 1), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim__gl_importance_cumsum(f.ctx, 1, 1, 1, 4, 40000, 0), GIM_ERROR_OUT_OF_RANGE);
    assert_int_equal(gim__gl_importance_cumsum(f.ctx, 1, 0, 1, 4, 4, 0), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_select(f.ctx, 1, 1, 4, 4, 0, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_importance_select(f.ctx, 1, 0, 4, 4, 8, 0, 1), GIM_ERROR_INVALID_ARGUMENT);
    {   /* the two-level passes */
        static const float off[4] = {0.0f, 0.0f, 0.0f, 0.0f};
        assert_int_equal(gim__gl_importance_tile_map(f.ctx, 1, 1, 1, 4, 4, 0, 1, 1, 1.0f, 0.0f, 1, 1), GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(gim__gl_importance_tile_map(f.ctx, 1, 1, 1, 4, 4, GIM_MAX_IMPORTANCE_TILE + 1, 1, 1, 1.0f, 0.0f, 1, 1),
                         GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(gim__gl_importance_tile_map(f.ctx, 1, 1, 1, 4, 4, 2, 1, 1, 1.0f, 0.0f, 1, 0), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim__gl_importance_select_tiles(f.ctx, 1, 1, 2, 2, 8, off, 2, 0, 4, 4, 1), GIM_ERROR_INVALID_ARGUMENT);
        assert_int_equal(gim__gl_importance_select_tiles(f.ctx, 1, 1, 2, 2, 8, off, 2, 1, 5, 4, 1), GIM_ERROR_INVALID_ARGUMENT);
    }
    assert_int_equal(f.log.errors, 14);
    f.log.errors = 0;
    gltest_state_unchanged(&f);
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(map_matches_twin),
        cmocka_unit_test(cumsum_matches_twin),
        cmocka_unit_test(cumsum_keeps_small_texels),
        cmocka_unit_test(select_matches_twin),
        cmocka_unit_test(chain_matches_twin),
        cmocka_unit_test(tiles_match_twin),
        cmocka_unit_test(defensive_matches_twin),
        cmocka_unit_test(pass_arguments),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
