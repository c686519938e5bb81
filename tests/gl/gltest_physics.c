/* Physics of the whole GPU frame: every method through gim_update, at default settings (small
   image and RSM), on the closed-form scenes of tests/support/physics.h, each pixel against the exact
   one-bounce radiance of the surface it shows (the G-buffer twin gives the point, its normal
   towards the eye and its quad). Counted are the pixels whose exact radiance is above 1% of
   the image's largest; the statistics are the median of gimany / exact and the fractions of
   pixels within 10% and 20%.
   Tolerances (what a user may expect at defaults; measured figures are printed):
     LightSkin FULL and BRSM   median within 5%, 90% of pixels within 10%;
     CLUSTERED and SSVP        median within 10%, 80% of pixels within 20% (the scenes are open:
                               visibility changes nothing here, so this is the VPL estimate,
                               the clamp, the interleaving and the blur);
     RSM gather                median within 5%, 60% of pixels within 20%: a 256-sample estimate
                               of every texel's light, without visibility (the baseline; open
                               scenes need none), noisier per pixel than the methods that
                               share or blur their samples.
   The near-edge band, the corner's pixels within 0.1 of its contact edge (115 pixels), median
   gimany / exact, printed for every method: LightSkin FULL >= 0.89, BRSM's mean over four
   independent draws of its VALs >= 0.875 (one draw's band reads 0.880-0.914, mean 0.89,
   whether a share of the VALs is drawn by luminance or none: 2026-11-29) (sun 0.928 / 0.906,
   spot 0.963 / 0.966; 0.869 / 0.863 and 0.921 / 0.928 before VALs within 2 sqrt(A) of a cache
   were evaluated as patches), asserted at scale 1 only: the band is a strip of pixels one or
   two wide, and at the other scales it reads 0.894 (sun, scale 1e-3, BRSM) and 0.852 / 0.871
   (sun, scale 100, 1.5e5 from the origin, FULL / BRSM: 0.832 / 0.842 before; spot 1e3:
   0.963 / 0.966) with the whole image's median unchanged. The VPL methods and the RSM gather read 0.67-0.87 there,
   unchanged and not asserted: with the RSM's texel centres as points, the clamp (d_c = 0.01 of
   the scene scale, 0.086) never bites at the wall's lowest texels (0.095 above the floor and
   more); what they lack is the wall's strip below those centres, which the RSM 128^2 gives to
   floor texels (0.17 of the wall's light at a floor point 0.067 from the wall, sun). */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "physics.h"

#define W 64
#define H 48
#define RSM 128u

typedef struct phys_frame {
    gltest_fixture f;
    phys_scene s;
    float tri[PHYS_MAX_QUADS * 18], alb[PHYS_MAX_QUADS * 6];
    gim_twin_scene ts;
    gim_cache_set caches;
    gim_mesh mesh;
    gim_frame fr;
    double exact[W * H];
    double edge[W * H];        /* distance of the pixel's point to the contact edge (-1: none) */
    double top;
} phys_frame;

/* The camera of each scene: it looks at the receiver quads from their open side. */
static void phys_camera(phys_which which, double scale, const double *offset, gim_mat4 *view, gim_mat4 *proj) {
    double eye[3] = {2.6, 1.4, 0.4}, at[3] = {0.4, 0.3, 0.0};
    int a;
    if (which == PHYS_PLATES_SUN) { eye[0] = 0.7; eye[1] = 0.05; eye[2] = 0.5; at[0] = 0.0; at[1] = 0.5; at[2] = 0.0; }
    if (which == PHYS_PATCH_SUN || which == PHYS_PATCH_SPOT) {
        eye[0] = 0.1; eye[1] = 0.16; eye[2] = 0.05; at[0] = -0.02; at[1] = 0.3; at[2] = 0.0;
    }
    for (a = 0; a < 3; ++a) { eye[a] = eye[a] * scale + offset[a]; at[a] = at[a] * scale + offset[a]; }
    *view = gim_mat4_look_at(gim_v3((float)eye[0], (float)eye[1], (float)eye[2]), gim_v3((float)at[0], (float)at[1], (float)at[2]),
                             gim_v3(0.0f, 1.0f, 0.0f));
    *proj = gim_mat4_perspective(1.1f, (float)W / H, (float)(0.01 * scale), (float)(20.0 * scale));
}

static void frame_begin(phys_frame *p, phys_which which, double scale, const double *offset) {
    gim_material mats[PHYS_MAX_QUADS];
    uint32_t mat_of[PHYS_MAX_QUADS * 2], idx[PHYS_MAX_QUADS * 6], t, x, y;
    gim_cache_desc cd;
    gim_mesh_desc md;
    gim_instance in;
    gim_light light;
    gim_camera cam;
    int q;
    memset(p, 0, sizeof *p);
    phys_scene_make(which, scale, offset, &p->s);
    p->ts.triangle_count = phys_triangles(&p->s, p->tri, p->alb);
    p->ts.positions = p->tri;
    p->ts.albedo = p->alb;
    gltest_fixture_begin(&p->f);
    memset(mats, 0, sizeof mats);
    for (q = 0; q < p->s.quad_count; ++q) {
        mats[q].diffuse[0] = mats[q].diffuse[1] = mats[q].diffuse[2] = p->s.quad[q].albedo;
        mat_of[q * 2] = mat_of[q * 2 + 1] = (uint32_t)q;
    }
    for (t = 0; t < p->ts.triangle_count * 3u; ++t) idx[t] = t;
    memset(&cd, 0, sizeof cd);
    cd.mesh.positions = p->tri;
    cd.mesh.vertex_count = p->ts.triangle_count * 3u;
    cd.mesh.indices = idx;
    cd.mesh.index_count = p->ts.triangle_count * 3u;
    cd.mesh.triangle_material = mat_of;
    cd.env = p->f.env;
    assert_int_equal(gim_cache_generate(&cd, &p->caches), GIM_OK);
    if (getenv("GIMANY_PHYS_CACHE_FRAC")) { /* to measure error against cache count: d_eps = frac x diagonal */
        cd.d_eps = p->caches.d_eps * 32.0f * (float)atof(getenv("GIMANY_PHYS_CACHE_FRAC"));
        gim_cache_set_free(&p->caches);
        assert_int_equal(gim_cache_generate(&cd, &p->caches), GIM_OK);
    }
    memset(&md, 0, sizeof md);
    md.data = cd.mesh;
    md.caches = &p->caches;
    assert_int_equal(gim_add_mesh(p->f.ctx, &md, &p->mesh), GIM_OK);
    assert_int_equal(gim_set_materials(p->f.ctx, mats, (uint32_t)p->s.quad_count), GIM_OK);
    in.mesh = p->mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(p->f.ctx, &in, 1), GIM_OK);
    light = phys_light(&p->s, RSM);
    assert_int_equal(gim_set_lights(p->f.ctx, &light, 1), GIM_OK);
    memset(&p->fr, 0, sizeof p->fr);
    phys_camera(which, scale, offset, &p->fr.view, &p->fr.proj);
    p->fr.width = W;
    p->fr.height = H;
    p->fr.indirect_float32 = 1;
    cam.view = p->fr.view; cam.proj = p->fr.proj; cam.width = W; cam.height = H;
    /* the exact radiance at every pixel's surface point */
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            gim_gbuffer_texel g;
            double pt[3], n[3];
            int a;
            assert_int_equal(gim_gbuffer_texel_twin(&p->ts, &cam, x, y, &g), GIM_OK);
            p->exact[y * W + x] = 0.0;
            p->edge[y * W + x] = -1.0;
            if (g.triangle == UINT32_MAX) continue;
            q = (int)(g.triangle / 2u);
            for (a = 0; a < 3; ++a) { pt[a] = g.position[a]; n[a] = g.normal[a]; }
            p->exact[y * W + x] = p->s.quad[q].albedo / PHYS_PI * phys_exact_irradiance(&p->s, q, pt, n);
            p->edge[y * W + x] = phys_contact_distance(&p->s, pt);
            if (p->exact[y * W + x] > p->top) p->top = p->exact[y * W + x];
        }
    assert_true(p->top > 0.0);
}

static void frame_end(phys_frame *p) {
    gim_cache_set_free(&p->caches);
    gltest_fixture_end(&p->f);
}

typedef struct phys_stats { double median, within10, within20, edge_median; uint32_t counted, edge_counted; } phys_stats;

/* Run the frame with method m and compare its indirect image with the exact radiance. */
static phys_stats run_method(phys_frame *p, gim_method m) {
    float *img = (float *)malloc(W * H * 16);
    double *ratio = (double *)malloc(W * H * sizeof(double)), *edge = (double *)malloc(W * H * sizeof(double));
    phys_stats st = {0, 0, 0, 0, 0, 0};
    uint32_t i;
    p->fr.method = m;
    assert_int_equal(gim_update(p->f.ctx, &p->fr), GIM_OK);
    gltest_read_texture(gim_outputs(p->f.ctx).indirect, GL_RGBA, img);
    for (i = 0; i < W * H; ++i) {
        double v;
        assert_true(isfinite(img[i * 4]) && img[i * 4] >= 0.0f);
        if (!(p->exact[i] > 0.01 * p->top)) continue;
        v = (img[i * 4] + img[i * 4 + 1] + img[i * 4 + 2]) / 3.0 / p->exact[i];
        ratio[st.counted++] = v;
        if (p->edge[i] >= 0.0 && p->edge[i] <= 0.1) edge[st.edge_counted++] = v;   /* the near-edge band */
        if (fabs(v - 1.0) <= 0.1) st.within10 += 1.0;
        if (fabs(v - 1.0) <= 0.2) st.within20 += 1.0;
    }
    assert_true(st.counted > W * H / 10);   /* the scene fills a good part of the view */
    st.within10 /= st.counted;
    st.within20 /= st.counted;
    st.median = phys_median(ratio, st.counted);
    st.edge_median = phys_median(edge, st.edge_counted);
    free(img);
    free(ratio);
    free(edge);
    return st;
}

static const char *method_name(gim_method m) {
    switch (m) {
    case GIM_METHOD_LIGHTSKIN_FULL: return "LightSkin FULL";
    case GIM_METHOD_LIGHTSKIN_BRSM: return "LightSkin BRSM";
    case GIM_METHOD_CLUSTERED: return "clustered";
    case GIM_METHOD_SSVP: return "SSVP";
    case GIM_METHOD_RSM_GATHER: return "RSM gather";
    default: return "?";
    }
}

/* edge_band: assert the near-edge band (see the top) */
static void check_scene(phys_which which, double scale, const double *offset, int edge_band) {
    /* the VPL methods twice: their VPLs at the RSM's sequence, then drawn by importance (vpl.importance) */
    static const gim_method methods[] = {GIM_METHOD_LIGHTSKIN_FULL, GIM_METHOD_LIGHTSKIN_BRSM, GIM_METHOD_CLUSTERED,
                                         GIM_METHOD_SSVP, GIM_METHOD_RSM_GATHER, GIM_METHOD_CLUSTERED, GIM_METHOD_SSVP};
    phys_frame *p = (phys_frame *)calloc(1, sizeof *p);
    size_t k;
    frame_begin(p, which, scale, offset);
    for (k = 0; k < sizeof methods / sizeof methods[0]; ++k) {
        phys_stats st;
        if (methods[k] == GIM_METHOD_SSVP) p->fr.vpl.bounces = 1;   /* the closed forms are one bounce */
        p->fr.vpl.importance = k >= 5;
        st = run_method(p, methods[k]);
        p->fr.vpl.bounces = 0;
        p->fr.vpl.importance = 0;
        print_message("%-13s scale %-6g %-15s median %.3f, %3.0f%% within 10%%, %3.0f%% within 20%% (%u pixels, %u caches)\n",
                      p->s.name, scale, k >= 5 ? (k == 5 ? "clustered, imp." : "SSVP, imp.") : method_name(methods[k]),
                      st.median, 100.0 * st.within10, 100.0 * st.within20, st.counted, p->caches.count);
        if (st.edge_counted > 0)
            print_message("%-13s %-12s %-15s within 0.1 of the contact edge: median %.3f (%u pixels)\n", "", "",
                          method_name(methods[k]), st.edge_median, st.edge_counted);
        if (methods[k] == GIM_METHOD_LIGHTSKIN_BRSM && edge_band && st.edge_counted > 0) {
            /* the band of one draw of the VALs varies (0.880-0.914 over ten draws, 2026-11-29):
               its mean over four independent draws */
            uint32_t d;
            double band = 0.0;
            p->fr.lightskin.temporal_steps = 1;
            for (d = 1; d <= 4; ++d) {
                p->fr.frame_index = d;
                band += run_method(p, methods[k]).edge_median / 4.0;
            }
            p->fr.lightskin.temporal_steps = 0;
            p->fr.frame_index = 0;
            print_message("%-13s %-12s %-15s the band over four draws of the VALs: mean of the medians %.3f\n", "", "",
                          method_name(methods[k]), band);
            assert_true(band >= 0.875);
        }
        if (methods[k] == GIM_METHOD_LIGHTSKIN_FULL || methods[k] == GIM_METHOD_LIGHTSKIN_BRSM) {
            assert_true(fabs(st.median - 1.0) <= 0.05);
            assert_true(st.within10 >= 0.90);
            if (edge_band && st.edge_counted > 0 && methods[k] == GIM_METHOD_LIGHTSKIN_FULL)
                assert_true(st.edge_median >= 0.89);   /* the near-edge band (BRSM: above) */
        } else if (methods[k] == GIM_METHOD_CLUSTERED || methods[k] == GIM_METHOD_SSVP) {
            assert_true(fabs(st.median - 1.0) <= 0.10);
            assert_true(st.within20 >= 0.80);
        } else {
            assert_true(fabs(st.median - 1.0) <= 0.05);
            assert_true(st.within20 >= 0.60);
        }
    }
    frame_end(p);
    free(p);
}

static const double origin[3] = {0.0, 0.0, 0.0};

/* The VPL methods' maps per VPL, imperfect (ISM) and drawn from the triangles (SHADOW_MAPS), on
   the open corners: nothing occludes, so the maps must remove almost no light, on the floor and
   the wall up to their contact edge, where a map's texels straddle both planes (false
   self-shadowing): the image's sum within 2% of the same frame with no visibility at all, and
   no pixel darker by over 20%. */
static void corner_ism_removes_nothing(void **state) {
    static const phys_which which[2] = {PHYS_CORNER_SUN, PHYS_CORNER_SPOT};
    int w, m;
    (void)state;
    GLTEST_BEGIN();
    for (w = 0; w < 2; ++w) {
        phys_frame *p = (phys_frame *)calloc(1, sizeof *p);
        frame_begin(p, which[w], 1.0, origin);
        p->fr.vpl.count = 1024;
        p->fr.vpl.interleave = 4;
        p->fr.vpl.bounces = 1;
        p->fr.visibility.ism_size = 0;   /* the default maps, 64^2 x 65536 points */
        p->fr.visibility.ism_points = 0;
        for (m = 0; m < 4; ++m) {
            float *none = (float *)malloc(W * H * 16), *ism = (float *)malloc(W * H * 16);
            double sn = 0.0, si = 0.0;
            uint32_t i, dark = 0, counted = 0;
            gim_visibility mode = m < 2 ? GIM_VISIBILITY_ISM : GIM_VISIBILITY_SHADOW_MAPS;
            p->fr.method = m & 1 ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED;
            p->fr.visibility.mode = GIM_VISIBILITY_OFF;
            p->fr.vpl.no_visibility = 1;
            assert_int_equal(gim_update(p->f.ctx, &p->fr), GIM_OK);
            gltest_read_texture(gim_outputs(p->f.ctx).indirect, GL_RGBA, none);
            p->fr.visibility.mode = mode;
            p->fr.vpl.no_visibility = 0;
            assert_int_equal(gim_update(p->f.ctx, &p->fr), GIM_OK);
            gltest_read_texture(gim_outputs(p->f.ctx).indirect, GL_RGBA, ism);
            for (i = 0; i < W * H; ++i) {
                double a = none[i * 4] + none[i * 4 + 1] + none[i * 4 + 2], b = ism[i * 4] + ism[i * 4 + 1] + ism[i * 4 + 2];
                if (!(p->exact[i] > 0.01 * p->top)) continue;
                sn += a; si += b; ++counted;
                dark += b < 0.8 * a;
            }
            print_message("%-13s %-9s %s per VPL: %.2f %% of the light removed, %u of %u pixels darker by over 20 %%\n",
                          p->s.name, m & 1 ? "SSVP" : "clustered", m < 2 ? "ISM" : "shadow map",
                          100.0 * (1.0 - si / sn), dark, counted);
            assert_true(si >= 0.98 * sn && si <= 1.0001 * sn);
            assert_true(dark == 0u);
            free(none); free(ism);
        }
        frame_end(p);
        free(p);
    }
    GLTEST_END();
}

/* Each cache carries its own surface's glossy lobe: the corner's floor k = 1 and wall k = 50,
   and every floor cache (normal +y) reads 1, every wall cache (+x) 50. */
static void caches_take_their_material(void **state) {
    phys_frame *p = (phys_frame *)calloc(1, sizeof *p);
    gim_material m[2];
    gim_debug_outputs od;
    gim_cache *caches;
    float *k;
    uint32_t i, floor_ = 0, wall = 0;
    (void)state;
    GLTEST_BEGIN();
    frame_begin(p, PHYS_CORNER_SUN, 1.0, origin);
    memset(m, 0, sizeof m);
    for (i = 0; i < 2; ++i) {
        m[i].diffuse[0] = m[i].diffuse[1] = m[i].diffuse[2] = 0.5f;
        m[i].glossy[0] = m[i].glossy[1] = m[i].glossy[2] = 0.2f;
    }
    m[0].exponent = 1.0f;
    m[1].exponent = 50.0f;
    assert_int_equal(gim_set_materials(p->f.ctx, m, 2), GIM_OK);
    p->fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    assert_int_equal(gim_update(p->f.ctx, &p->fr), GIM_OK);
    od = gim_debug(p->f.ctx);
    assert_true(od.cache_exponents != 0 && od.cache_count > 0);
    caches = (gim_cache *)malloc(od.cache_count * sizeof *caches);
    k = (float *)malloc(od.cache_count * sizeof *k);
    gltest_read_buffer(od.caches, od.cache_count * sizeof *caches, caches);
    gltest_read_buffer(od.cache_exponents, od.cache_count * sizeof *k, k);
    for (i = 0; i < od.cache_count; ++i) {
        if (caches[i].normal[1] > 0.9f) { assert_true(k[i] == 1.0f); ++floor_; }
        if (caches[i].normal[0] > 0.9f) { assert_true(k[i] == 50.0f); ++wall; }
    }
    assert_true(floor_ > 0 && wall > 0 && floor_ + wall == od.cache_count);
    free(caches);
    free(k);
    frame_end(p);
    free(p);
    GLTEST_END();
}

static void corner_sun(void **state) {
    (void)state;
    GLTEST_BEGIN();
    check_scene(PHYS_CORNER_SUN, 1.0, origin, 1);
    GLTEST_END();
}

static void corner_spot(void **state) {
    (void)state;
    GLTEST_BEGIN();
    check_scene(PHYS_CORNER_SPOT, 1.0, origin, 1);
    GLTEST_END();
}

/* a point light: six cube-face RSMs, their seams on the floor and wall */
static void corner_point(void **state) {
    (void)state;
    GLTEST_BEGIN();
    check_scene(PHYS_CORNER_POINT, 1.0, origin, 1);
    GLTEST_END();
}

static void corner_scales(void **state) {
    static const double far_[3] = {1e5, -1e5, 5e4};   /* 174 diagonals at scale 100 (the range is 1024) */
    (void)state;
    GLTEST_BEGIN();
    check_scene(PHYS_CORNER_SUN, 1e-3, origin, 0);
    check_scene(PHYS_CORNER_SPOT, 1e3, origin, 0);
    check_scene(PHYS_CORNER_SUN, 100.0, far_, 0);
    GLTEST_END();
}

static void plates_and_patch(void **state) {
    (void)state;
    GLTEST_BEGIN();
    check_scene(PHYS_PLATES_SUN, 1.0, origin, 0);
    check_scene(PHYS_PATCH_SUN, 1.0, origin, 0);
    check_scene(PHYS_PATCH_SPOT, 1.0, origin, 0);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(corner_sun),
        cmocka_unit_test(corner_spot),
        cmocka_unit_test(corner_point),
        cmocka_unit_test(corner_scales),
        cmocka_unit_test(plates_and_patch),
        cmocka_unit_test(corner_ism_removes_nothing),
        cmocka_unit_test(caches_take_their_material),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
