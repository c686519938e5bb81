/* Every method of gim_update against the ground truth, inside `make test`: whole frames at their
   defaults against tools/reference (Embree path tracing, rendered in-process, unbiased), with
   the error metric and the conventions of bench/src/bench_frame.c (rel. MAE of tools/compare.c over
   the pixels where either image has light; the scene layer's camera; the indirect texture's
   rows flipped to the reference's top-first order), at a size llvmpipe renders in seconds.

     cornell_methods  the measured Cornell box (../shared/scenes/cornell_box, its spot; skipped
                      when absent), 80x45, RSM 128^2 (bench_frame's ci size): RSM gather,
                      LightSkin BRSM and FULL, Dong et al.'s clustered VPLs, SSVP (two bounces,
                      against a two-bounce reference; with its paraboloid maps' visibility and
                      with imperfect shadow maps) and LightSkin BRSM with imperfect shadow
                      maps (Ritschel et al. 2008), and with rays (each pixel's neighbour caches,
                      GIM_VISIBILITY_RAYS at the caches); each one's rel. MAE and its image mean
                      against the reference's (energy).
     courtyard_pillar the built-in courtyard (scene/scene.cpp): a pillar between a sunlit
                      floor and a wall the sun does not reach. The wall behind the pillar gets
                      less of the floor's light; with visibility (ISM) LightSkin BRSM must
                      show that shadow and match the reference there, without it it cannot;
                      so must it with the rays (neighbour rays with ISM, and with RAYS).

   The references are cached in build/refcheck/ (one folder per scene, size, paths, bounces and
   seed) and rendered again when this binary is newer than the cache: a clean build renders
   them (45 s of the test's 1m53 on two busy cores; 1m01 with them cached), later runs read
   them. Each reference's own noise is printed
   as a rel. MAE against the true image (sqrt(2/pi) sigma / mean, as bench_frame's
   ref_noise_mae; two seeds' images differ by sqrt(2) times it, measured when the tolerances
   below were set) and must stay below a fifth of the tightest tolerance. */
#define _POSIX_C_SOURCE 199309L   /* clock_gettime */
#include <sys/stat.h>
#include <time.h>
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"
#include "reference.h"
#define COMPARE_NO_MAIN
#include "../tools/compare.c"

#define CORNELL_GLTF "../shared/scenes/cornell_box/CornellBox.gltf"
#define RSM 128u

/* --- the reference ------------------------------------------------------------------------ */

/* A reference image, all arrays w x h x 3, top row first. */
typedef struct refimg {
    uint32_t w, h;
    float *rgb, *sigma, *position, *normal;
} refimg;

static void refimg_free(refimg *r) {
    free(r->rgb); free(r->sigma); free(r->position); free(r->normal);
    memset(r, 0, sizeof *r);
}

static double wall_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

static double mtime(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (double)st.st_mtime : 0.0;
}

static const char *const ref_files[4] = {"reference.pfm", "stderr.pfm", "position.pfm", "normal.pfm"};

/* The cached reference of s (name, its camera's size, spp, bounces, seed) when it is newer than
   this binary (/proc/self/exe; the binary links the scene layer and the renderer, so a change
   to either renders it again); else rendered (Embree) and cached. */
static void reference(const scene *s, const char *name, uint32_t spp, int bounces, uint32_t seed, refimg *out) {
    char dir[256], path[320], err[256];
    float **arr[4];
    uint32_t w = s->camera.width, h = s->camera.height, k;
    double exe = mtime("/proc/self/exe"), t0 = wall_ms();
    int cached = 1;
    memset(out, 0, sizeof *out);
    arr[0] = &out->rgb; arr[1] = &out->sigma; arr[2] = &out->position; arr[3] = &out->normal;
    snprintf(dir, sizeof dir, "build/refcheck/%s_%ux%u_%uspp_%db_seed%u", name, w, h, spp, bounces, seed);
    for (k = 0; k < 4 && cached; ++k) {
        uint32_t rw = 0, rh = 0;
        snprintf(path, sizeof path, "%s/%s", dir, ref_files[k]);
        cached = mtime(path) > exe && scene_read_pfm(path, arr[k], &rw, &rh, err, sizeof err) == 0 && rw == w && rh == h;
    }
    if (!cached) {
        ref_settings st;
        ref_image img;
        refimg_free(out);
        memset(&st, 0, sizeof st);
        st.spp = spp;
        st.seed = seed;
        st.bounces = bounces;
        assert_int_equal(ref_render(s, &st, &img, err, sizeof err), 0);
        assert_int_equal(img.nonfinite_samples, 0);
        out->rgb = img.radiance; out->sigma = img.std_error; out->position = img.position; out->normal = img.normal;
        img.radiance = img.std_error = img.position = img.normal = NULL;
        ref_image_free(&img);
        if (scene_make_dir(dir, err, sizeof err) == 0)
            for (k = 0; k < 4; ++k) {
                snprintf(path, sizeof path, "%s/%s", dir, ref_files[k]);
                if (scene_write_pfm(path, *arr[k], w, h, err, sizeof err) != 0) print_message("reference: not cached: %s\n", err);
            }
    }
    out->w = w;
    out->h = h;
    print_message("reference %s: %s in %.1f s\n", dir, cached ? "read from the cache" : "rendered", (wall_ms() - t0) / 1000.0);
}

/* The reference's noise as a rel. MAE against the true image: sum sqrt(2/pi) sigma / sum ref
   (E|X - mu| of a normal mean; bench_frame's ref_noise_mae). */
static double reference_noise(const refimg *r) {
    double s = 0.0, m = 0.0;
    uint32_t i;
    for (i = 0; i < r->w * r->h * 3; ++i) { s += r->sigma[i]; m += fabs((double)r->rgb[i]); }
    return m > 0.0 ? 0.7978845608 * s / m : 0.0;
}

/* A condition that must hold: printed when it does not, and counted, so the test frees what it
   holds before it fails. */
#define CHECK(failed, cond)                                                       \
    do {                                                                          \
        if (!(cond)) { print_message("  failed: %s\n", #cond); (failed)++; }     \
    } while (0)

/* --- a frame ------------------------------------------------------------------------------ */

typedef struct frame_run {
    gltest_fixture f;
    scene s;
    scene_gimany g;
    gim_frame fr;
} frame_run;

/* s (already loaded, its camera sized) into a fresh context, caches at d_eps_frac of the scene
   scale (0: scene_gimany's 1/32, bench_frame's), RSM 128^2. */
static void run_begin(frame_run *r, float d_eps_frac) {
    gltest_fixture_begin(&r->f);
    assert_int_equal(scene_gimany_load(r->f.ctx, &r->s, d_eps_frac, RSM, r->f.env, &r->g), GIM_OK);
    assert_true(r->g.light_count >= 1);
    memset(&r->fr, 0, sizeof r->fr);
    scene_gimany_camera(&r->s, &r->fr.view, &r->fr.proj);
    r->fr.width = r->s.camera.width;
    r->fr.height = r->s.camera.height;
    r->fr.indirect_float32 = 1;
}

static void run_end(frame_run *r) {
    scene_gimany_free(r->f.ctx, &r->g);
    scene_free(&r->s);
    gltest_fixture_end(&r->f);
}

/* frames of f (VPL methods: three, their k-means warm from the last frame's centres as in
   bench_frame's measured frames), then the indirect image as RGB, top row first. */
static void render(frame_run *r, const gim_frame *f, int frames, float *rgb) {
    uint32_t w = f->width, h = f->height, x, y, c;
    float *rgba = (float *)malloc((size_t)w * h * 16);
    int k;
    for (k = 0; k < frames; ++k) assert_int_equal(gim_update(r->f.ctx, f), GIM_OK);
    gltest_read_texture(gim_outputs(r->f.ctx).indirect, GL_RGBA, rgba);
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x)
            for (c = 0; c < 3; ++c) {
                float v = rgba[((h - 1 - y) * w + x) * 4 + c];
                assert_true(isfinite(v) && v >= 0.0f);
                rgb[(y * w + x) * 3 + c] = v;
            }
    free(rgba);
}

static double rel_mae(const float *a, const refimg *ref) {
    compare_result cr;
    assert_int_equal(compare_images(a, ref->rgb, ref->w, ref->h, &cr, NULL), 0);
    assert_true(cr.covered > 0);
    return cr.rel_mae;
}

/* sum of a over sum of the reference, every pixel and channel: the image's energy against the
   reference's */
static double mean_ratio(const float *a, const refimg *ref) {
    double sa = 0.0, sb = 0.0;
    uint32_t i;
    for (i = 0; i < ref->w * ref->h * 3; ++i) { sa += a[i]; sb += ref->rgb[i]; }
    assert_true(sb > 0.0);
    return sa / sb;
}

/* --- every method on the Cornell box ------------------------------------------------------ */

#define CW 80
#define CH 45

/* One method at its defaults (the frame's zero fields), with the visibility of the row; its
   reference has its bounces. max_mae: the tolerance on the rel. MAE; max_energy: on
   |image mean / reference mean - 1|. */
typedef struct method_row {
    const char *name;
    gim_method method;
    gim_visibility visibility;
    int bounces;
    double max_mae, max_energy;
    uint32_t neighbour_rays;   /* gim_frame_visibility.neighbour_rays */
    gim_second_bounce second_bounce;   /* gim_frame_vpl.second_bounce (0: the default, the maps) */
    uint32_t interleave;       /* gim_frame_vpl.interleave (0: the default, by the view: 1 at 80x45) */
} method_row;

/* Measured 2026-11-24 on llvmpipe at 80x45, RSM 128^2, caches at 1/32 of the scene scale,
   references at 16384 paths (one bounce) and 8192 (two): rel. MAE (bench_frame's at 160x90 in
   brackets) and image mean over the reference's:
     RSM gather        0.184 (0.186)          1.139
     LightSkin BRSM    0.157 (0.161)          1.148
     LightSkin FULL    0.157 (0.160)          1.151
     The VPL methods at their default interleave, by the view since 2026-12-02 (every VPL at
     every pixel at 80x45; before, CLUSTERED's 4 x 4 and SSVP's 8 x 8 and their blur, the
     figures in brackets after the arrow, now the rows with an interleave):
     clustered, 30     0.058 <- 0.116 (0.092-0.175)  0.977 <- 0.994 (0.150 at 4096 VPLs, 8 x 8)
     SSVP, 8, 2 bounces 0.092 <- 0.147 (0.125)  0.953 <- 0.978 (its second bounce by rays, one per
                                                       stratum of the VPLs, the default; 0.154, 1.009 with
                                                       one pick over all VPLs' running sums)
     SSVP + ISM        0.096 <- 0.141           0.939 <- 0.956 (0.152, 0.994 with that pick)
     SSVP, the second bounce from the maps (GIM_SECOND_BOUNCE_MAPS)  0.125 <- 0.167 (0.157)  1.014 <- 1.025
                                                       (1.020 before the sun's window fit; 0.169, 1.063
                                                       before its near field and second-bounce ISMs)
     SSVP + ISM, from the maps                                      0.125 <- 0.158  0.994 <- 1.003
     The blur added about 1-2% of the light (the means above); what is missing at every pixel
     is the first bounce's (6% with ISM: docs/methods.md, "The VPLs' near field").
     A near VPL past the shader's 8 (GIM__VPL_NEAR_CAP) takes the far field: at every pixel
     SSVP + ISM has single pixels to 0.092 (0.046 with no cap, rel. MAE 0.096 -> 0.092).
     BRSM + ISM        0.040 (64^2 maps; 0.075 at 32^2)  0.974
     BRSM + ISM, each pixel's neighbour rays (2026-12-01)  0.040  0.974 (every neighbour in sight)
     BRSM + RAYS (a ray per VAL and cache) + neighbour rays (2026-12-01)  0.031  0.996 (the
                       exact-visibility floor of LightSkin here: 0.023, docs/methods.md)
   SSVP's second bounce lands on the first surface its ray meets since the attribute maps have
   their own near skip (before, they skipped the visibility's Delta / 2 and 0.175 of
   the second bounce's flux landed behind a nearer surface): SSVP with ISM went from 0.163 and
   0.890 of the energy (the ISM dropped the hits it saw behind a surface) to the figures above;
   SSVP with its paraboloid maps from 0.148 and 1.008 to 0.169 and 1.061, as its second-bounce
   VPLs shade unshadowed and now sit on the surfaces next to the clusters, whose light goes
   through the blocks (without any visibility SSVP went from 0.185, 1.124 to 0.223, 1.181).
   The references' noise adds 0.014 (one bounce) and 0.016 (two) to these at most. MAE
   tolerances: 1.25 x the measured error, rounded up to 0.005; the frames are deterministic
   (the same figures run after run), the margin is for other drivers and the methods' tuning.
   Energy: without visibility LightSkin and the gather send light through the blocks (14-15%
   too much), so 0.2 for them; 0.1 for the VPL methods (their paraboloid maps' visibility) and
   for ISM; 0.075 for SSVP + ISM, which the second bounce's old skip fails (0.890). The ISM row's tolerance is below BRSM's measured error, so ISM turned off fails it
   (checked below), and every row fails its tolerances with its image scaled by 1.3 (checked). */
static const method_row cornell_rows[] = {
    {"RSM gather", GIM_METHOD_RSM_GATHER, GIM_VISIBILITY_OFF, 1, 0.230, 0.2, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"LightSkin BRSM", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 1, 0.200, 0.2, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"LightSkin FULL", GIM_METHOD_LIGHTSKIN_FULL, GIM_VISIBILITY_OFF, 1, 0.200, 0.2, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"clustered", GIM_METHOD_CLUSTERED, GIM_VISIBILITY_OFF, 1, 0.075, 0.1, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"clustered, 4 x 4", GIM_METHOD_CLUSTERED, GIM_VISIBILITY_OFF, 1, 0.145, 0.1, 0, GIM_SECOND_BOUNCE_DEFAULT, 4},
    {"SSVP", GIM_METHOD_SSVP, GIM_VISIBILITY_OFF, 2, 0.115, 0.1, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"SSVP, 8 x 8", GIM_METHOD_SSVP, GIM_VISIBILITY_OFF, 2, 0.185, 0.1, 0, GIM_SECOND_BOUNCE_DEFAULT, 8},
    {"SSVP + ISM", GIM_METHOD_SSVP, GIM_VISIBILITY_ISM, 2, 0.120, 0.075, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"SSVP, 2nd from maps", GIM_METHOD_SSVP, GIM_VISIBILITY_OFF, 2, 0.160, 0.1, 0, GIM_SECOND_BOUNCE_MAPS, 0},
    {"SSVP + ISM, from maps", GIM_METHOD_SSVP, GIM_VISIBILITY_ISM, 2, 0.160, 0.075, 0, GIM_SECOND_BOUNCE_MAPS, 0},
    {"LightSkin BRSM + ISM", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_ISM, 1, 0.050, 0.1, 0, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"BRSM + ISM + rays", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_ISM, 1, 0.050, 0.1, 1, GIM_SECOND_BOUNCE_DEFAULT, 0},
    {"BRSM + RAYS + rays", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_RAYS, 1, 0.040, 0.1, 1, GIM_SECOND_BOUNCE_DEFAULT, 0},
};
#define ROW_COUNT (sizeof cornell_rows / sizeof cornell_rows[0])

static void cornell_methods(void **state) {
    frame_run r;
    refimg ref1, ref2;
    char err[256];
    float *img = (float *)malloc(CW * CH * 12);
    double noise1, noise2, t0, brsm_mae = 0.0, ism_max = 1.0;
    size_t i;
    int failed = 0;
    FILE *fp;
    (void)state;
    GLTEST_BEGIN();
    fp = fopen(CORNELL_GLTF, "rb");
    if (!fp) {
        print_message("%s absent: skipped\n", CORNELL_GLTF);
        free(img);
        skip();
    }
    fclose(fp);
    memset(&r, 0, sizeof r);
    assert_int_equal(scene_load_gltf(CORNELL_GLTF, &r.s, err, sizeof err), 0);
    assert_true(r.s.light_count >= 1 && r.s.lights[0].type == SCENE_LIGHT_SPOT);
    r.s.camera.width = CW;
    r.s.camera.height = CH;
    reference(&r.s, "cornell", 16384, 1, 1, &ref1);
    reference(&r.s, "cornell", 8192, 2, 1, &ref2);
    noise1 = reference_noise(&ref1);
    noise2 = reference_noise(&ref2);
    print_message("reference noise (rel. MAE against the true image): %.4f one bounce (16384 paths), %.4f two (8192)\n",
                  noise1, noise2);
    assert_true(noise1 < 0.050 / 3.0 && noise2 < 0.19 / 5.0);   /* a third of the tightest tolerance */
    run_begin(&r, 0.0f);
    print_message("| method | rel. MAE | tolerance | mean / ref. mean | tolerance (+-) | ms |\n");
    for (i = 0; i < ROW_COUNT; ++i) {
        const method_row *m = &cornell_rows[i];
        const refimg *ref = m->bounces == 2 ? &ref2 : &ref1;
        gim_frame f = r.fr;
        double mae, ratio;
        int vpl = m->method == GIM_METHOD_CLUSTERED || m->method == GIM_METHOD_SSVP;
        f.method = m->method;
        f.visibility.mode = m->visibility;
        f.visibility.neighbour_rays = m->neighbour_rays;
        f.vpl.second_bounce = m->second_bounce;
        f.vpl.interleave = m->interleave;
        t0 = wall_ms();
        render(&r, &f, vpl ? 3 : 1, img);
        mae = rel_mae(img, ref);
        ratio = mean_ratio(img, ref);
        print_message("| %-20s | %.3f | %.3f | %.3f | %.3f | %.0f |\n", m->name, mae, m->max_mae, ratio, m->max_energy,
                      wall_ms() - t0);
        CHECK(failed, mae < m->max_mae);
        CHECK(failed, fabs(ratio - 1.0) < m->max_energy);
        if (m->method == GIM_METHOD_LIGHTSKIN_BRSM && m->visibility == GIM_VISIBILITY_OFF) brsm_mae = mae;
        if (m->method == GIM_METHOD_LIGHTSKIN_BRSM && m->visibility == GIM_VISIBILITY_ISM && !m->neighbour_rays)
            ism_max = m->max_mae;
        /* the tolerances can fail: the same image with 30% more light is outside them */
        {
            size_t k;
            for (k = 0; k < CW * CH * 3; ++k) img[k] *= 1.3f;
            CHECK(failed, !(rel_mae(img, ref) < m->max_mae && fabs(mean_ratio(img, ref) - 1.0) < m->max_energy));
        }
    }
    /* ... and the ISM row's tolerance is tighter than the error without visibility */
    CHECK(failed, brsm_mae > ism_max);
    run_end(&r);
    refimg_free(&ref1);
    refimg_free(&ref2);
    free(img);
    assert_int_equal(failed, 0);
    GLTEST_END();
}

/* --- the courtyard's pillar ---------------------------------------------------------------- */

#define YW 80
#define YH 45

/* Mean luminance of rgb over the wall's pixels (the reference's primary hit on the plane z = 0,
   normal +z) whose hit lies in x0 <= |x| < x1, y < 0.8 m: |x| < 0.4 is behind the pillar (its
   footprint is |x| < 0.4, 0.8 <= z < 1.6, 1.2 m high), |x| >= 1.6 the open wall beside it. */
static double wall_mean(const float *rgb, const refimg *ref, double x0, double x1, uint32_t *count) {
    double s = 0.0;
    uint32_t i, n = 0;
    for (i = 0; i < ref->w * ref->h; ++i) {
        const float *p = ref->position + i * 3, *nr = ref->normal + i * 3;
        double ax = fabs((double)p[0]);
        if (!(nr[2] > 0.99f && fabsf(p[2]) < 1e-3f && p[1] < 0.8f && ax >= x0 && ax < x1)) continue;
        s += ref_luminance(rgb + i * 3);
        n++;
    }
    assert_true(n > 0);
    if (count) *count = n;
    return s / n;
}

/* The pillar's indirect shadow on the wall: LightSkin BRSM with ISM against without visibility
   and against the reference (16384 paths), in the wall's region behind the pillar. */
static void courtyard_pillar(void **state) {
    frame_run r;
    refimg ref;
    char err[256];
    float *on = (float *)malloc(YW * YH * 12), *off = (float *)malloc(YW * YH * 12), *rays = (float *)malloc(YW * YH * 12);
    float *exact = (float *)malloc(YW * YH * 12);
    double ref_sh, ref_open, on_sh, on_open, off_sh, off_open, rays_sh, rays_open, ex_sh, ex_open;
    uint32_t n_sh, n_open;
    gim_frame f;
    int failed = 0;
    (void)state;
    GLTEST_BEGIN();
    memset(&r, 0, sizeof r);
    assert_int_equal(scene_builtin("courtyard", &r.s, err, sizeof err), 0);
    r.s.camera.width = YW;
    r.s.camera.height = YH;
    reference(&r.s, "courtyard", 16384, 1, 1, &ref);
    print_message("reference noise: %.4f\n", reference_noise(&ref));
    run_begin(&r, 0.0f);
    f = r.fr;
    f.method = GIM_METHOD_LIGHTSKIN_BRSM;
    f.visibility.mode = GIM_VISIBILITY_ISM;
    render(&r, &f, 1, on);
    f.visibility.neighbour_rays = 1;
    render(&r, &f, 1, rays);
    f.visibility.mode = GIM_VISIBILITY_RAYS;
    render(&r, &f, 1, exact);
    f.visibility.neighbour_rays = 0;
    f.visibility.mode = GIM_VISIBILITY_OFF;
    render(&r, &f, 1, off);
    run_end(&r);
    ref_sh = wall_mean(ref.rgb, &ref, 0.0, 0.4, &n_sh);
    ref_open = wall_mean(ref.rgb, &ref, 1.6, 10.0, &n_open);
    on_sh = wall_mean(on, &ref, 0.0, 0.4, NULL);
    on_open = wall_mean(on, &ref, 1.6, 10.0, NULL);
    off_sh = wall_mean(off, &ref, 0.0, 0.4, NULL);
    off_open = wall_mean(off, &ref, 1.6, 10.0, NULL);
    rays_sh = wall_mean(rays, &ref, 0.0, 0.4, NULL);
    rays_open = wall_mean(rays, &ref, 1.6, 10.0, NULL);
    ex_sh = wall_mean(exact, &ref, 0.0, 0.4, NULL);
    ex_open = wall_mean(exact, &ref, 1.6, 10.0, NULL);
    print_message("wall behind the pillar (%u px) / open wall (%u px), mean luminance: reference %.4g / %.4g (%.3f), "
                  "ISM %.4g / %.4g (%.3f), no visibility %.4g / %.4g (%.3f)\n", n_sh, n_open, ref_sh, ref_open,
                  ref_sh / ref_open, on_sh, on_open, on_sh / on_open, off_sh, off_open, off_sh / off_open);
    print_message("ISM + neighbour rays %.4g / %.4g (%.3f), RAYS + neighbour rays %.4g / %.4g (%.3f)\n", rays_sh, rays_open,
                  rays_sh / rays_open, ex_sh, ex_open, ex_sh / ex_open);
    print_message("whole image rel. MAE: ISM %.3f, ISM + neighbour rays %.3f, RAYS + neighbour rays %.3f, no visibility %.3f\n",
                  rel_mae(on, &ref), rel_mae(rays, &ref), rel_mae(exact, &ref), rel_mae(off, &ref));
    /* Measured 2026-11-24 (llvmpipe, 80x45, RSM 128^2, caches at 1/32 of the scene scale): the
       reference's wall is 0.862 as bright behind the pillar as beside it; ISM 0.872, within 1.0%
       of the reference behind the pillar (0.0494 against 0.0499); without visibility 1.001, 15%
       too bright there. Tolerances: the shadow exists (below 0.93 of the open wall in the
       reference, and ISM below 0.93 of no visibility behind the pillar), ISM within 6% of the
       reference there and its contrast within 0.04; no visibility must miss by more than 6%
       (the tolerance tells the two apart). */
    CHECK(failed, ref_sh < 0.93 * ref_open);
    CHECK(failed, on_sh < 0.93 * off_sh);
    CHECK(failed, fabs(on_sh / ref_sh - 1.0) < 0.06);
    CHECK(failed, fabs(on_sh / on_open - ref_sh / ref_open) < 0.04);
    CHECK(failed, off_sh / ref_sh - 1.0 > 0.06);
    /* the pixels' own rays keep the shadow and the contrast */
    CHECK(failed, fabs(rays_sh / ref_sh - 1.0) < 0.06);
    CHECK(failed, fabs(rays_sh / rays_open - ref_sh / ref_open) < 0.04);
    CHECK(failed, fabs(ex_sh / ref_sh - 1.0) < 0.06);
    CHECK(failed, fabs(ex_sh / ex_open - ref_sh / ref_open) < 0.04);
    refimg_free(&ref);
    free(on);
    free(off);
    free(rays);
    free(exact);
    assert_int_equal(failed, 0);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cornell_methods),
        cmocka_unit_test(courtyard_pillar),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
