/* The speed/accuracy trade of the many-light methods (Bischoff 2017 Fig. 3 and 5): whole
   gim_update frames of every method in `methods` below against LightSkin FULL (every RSM texel
   a VAL, the paper's own reference) and against the Embree ground truth of the same view
   (build/gimany-reference), side by side in one run, on the procedural street (the paper's
   open-world case), the measured Cornell box and two views inside Sponza's atrium
   (../shared/scenes, when present; the file has no camera, and the loader's framing looks at an
   outer wall that gets no indirect light).

   Two sweeps (the CSV's `sweep` column, the README's table between its markers):
     ci    (`make bench`, default): 160x90 frames (64x36 on Sponza), RSM 128^2 and 256^2,
           1024 / 4096 VALs, 256 view samples, reference at 16384 paths per pixel; a few minutes
           on a 2-core llvmpipe machine once the references are cached. Writes
           bench/results.csv and the plots.
     full  (`make bench-full`): 320x180 frames, RSM 128^2 .. 2048^2 (street; Cornell box to
           512^2, Sponza to 256^2), 2048 / 4096 / 8192 VALs, 256 / 512 view samples, reference at
           16384 paths per pixel. Writes bench/full/results.csv and bench/full/PLOT.png.
   References are cached in build/bench_ref/, one folder per scene, view, size, paths per pixel
   and bounces, and rendered again only when build/gimany-reference is newer than the cache.
   Per configuration: the median frame time (wall clock around gim_update + glFinish, untimed
   frames), then per-pass medians from separate frames with gim_frame.timing = 2 (glFinish after
   each pass and the CPU's clock: the only per-pass times that mean something on llvmpipe, whose
   GL timestamps charge queued work to later passes); memory; the ratio FULL : this; the mean
   relative difference to FULL's image (the paper's Fig. 3/5 comparison); the relative MAE
   against the reference and the reference's own noise floor (ref_noise_mae: the MAE its
   standard error alone gives against the true image); flicker; for a row with visibility
   (brsm-ism: imperfect shadow maps per cache; brsm-rays: rays through the scene's hierarchy at the
   caches and from the pixels, on the street in `make bench` only: its frames take 6-23 s here;
   clustered-ism, ssvp-ism: one map per VPL) its frame over
   the same method's frame without (visibility_over_off: the maps' lookups; the maps are reused
   while the scene and the light stand still) and the time of the frame that makes the maps'
   pass (ism_build_ms, timing 2: GIM_PASS_ISM, the VPL methods' GIM_PASS_PARABOLOID; on the row of
   the first VAL count of each RSM size, the others reuse the maps).
   brsm-anew: BRSM at the default VAL count with gim_frame.lightskin.temporal_steps 1, new offsets
   every frame (its flicker against the default's drift, the brsm rows); clustered-ism-anew,
   ssvp-ism-anew: gim_frame.vpl.redraw 1, every VPL and its map made anew every frame (against
   the default, which follows the last frame's VPLs: incremental instant radiosity).
   clustered-imp, clustered-ism-imp, ssvp-imp, ssvp-ism-imp: the VPL rows with their VPLs drawn
   where the light reaches the view (gim_frame_vpl.importance: BRSM's importance, 256 view
   samples; no VPL is followed, a pick that stays on its point keeps its map).
   The VPL rows run the interleave of a 720-row frame (CLUSTERED 4 x 4, SSVP 8 x 8), the
   library's default from 720 rows up: at these sizes its default is every VPL at every pixel
   (gim_vpl_default_interleave), 3-15x the frame here (one demo frame: the street's SSVP
   1.5 -> 20 s, clustered 3.7 -> 12 s; the Cornell box's 0.4 -> 3.3 and 6.8 s), so the
   errors below carry a blur that spans more of these small images than of a frame's
   (docs/methods.md, "The interleave by the view").
   clustered-sm, clustered-sm-imp, ssvp-sm, ssvp-sm-imp: the same with one shadow map per VPL
   drawn from the triangles (GIM_VISIBILITY_SHADOW_MAPS) instead of its ISM; the -imp ones only in
   bench-full (while the sun turns every pick's map is made again, a draw of the street per map:
   about a minute a frame on llvmpipe, for the 30 frames of the flicker and the turned sun).
   On the street at the flicker size, each row also prints its error after the sun turned 24
   degrees, a degree a frame, against a reference rendered at that sun (moved_error): followed as
   by default, and drawn anew there.
   Usage: bench_frame [ci|full [SCENE[:MIN_RSM]...]]: with scenes, only those (from RSM
   MIN_RSM^2 on), appended to the sweep's results.csv in place of their rows there from
   MIN_RSM^2 on (to finish or redo part of a sweep); a
   prefix up to a '-' names every view of a scene ("sponza": sponza-atrium and sponza-gallery);
   the scenes of named_scenes (the courtyard) run only so. GIMANY_BENCH_ROWS=NAME[,NAME...]: only
   the rows of those methods (FULL always: the flicker and the ratios are against it), written to
   the sweep's rows.csv (made anew) instead of results.csv: a quick look at a few rows. */
#include "benchutil.h"
#include <sys/stat.h>
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"
#define COMPARE_NO_MAIN
#include "../tools/compare.c"

#define CORNELL_GLTF "../shared/scenes/cornell_box/CornellBox.gltf"
#define SPONZA_GLB "../shared/scenes/sponza_lod4/sponza_lod4.glb"
#define MAX_RUNS 9

/* --- the methods: one row each ----------------------------------------------------------- */

/* A method of the sweep with its parameters. LightSkin FULL is the baseline every row is
   compared with (run first at each RSM size, one frame: it takes up to minutes here). A row with
   per_val is swept over the sweep's VAL and view-sample counts; one without runs once per RSM
   size. clusters, second_bounce_vpls and bounces are written to the CSV (0: the method has no
   such parameter); setup sets the frame fields the row needs beyond method, val_count and
   view_sample_count (NULL: none). To add a method or a parameter value, add a row, e.g.
     {"clustered", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_clustered},
     {"ssvp", GIM_METHOD_SSVP, 0, 16, 256, 2, setup_ssvp},
   with setup_clustered copying m->clusters (and setup_ssvp m->second_bounce_vpls, m->bounces)
   into their gim_frame fields. */
typedef struct bench_method bench_method;
struct bench_method {
    const char *name;             /* the CSV's method column */
    gim_method method;
    int per_val;                  /* 1: swept over VAL and view-sample counts */
    uint32_t clusters;            /* Dong / SSVP clusters */
    uint32_t second_bounce_vpls;  /* SSVP's second-bounce VPLs */
    uint32_t bounces;             /* 1 or 2 */
    void (*setup)(gim_frame *f, const bench_method *m);
    int ci;                       /* in `make bench`: 1 on every scene, 2 on the Cornell box only, 3 on every scene
                                     but Sponza's views (whose frame that makes the maps takes minutes on
                                     llvmpipe), 4 on the street only and never in bench-full (a frame of
                                     rays takes 6-23 s there, the Cornell box's 8,980 caches 2.7x that),
                                     0 not (bench-full) */
    int vpl;                      /* 1: a VPL method (no caches, VPLs from the RSM): run at one RSM size, the
                                     flicker size; its reference has its bounces */
};

static void setup_gather(gim_frame *f, const bench_method *m) {
    (void)m;
    f->gather.samples = 256;   /* over gather_radius 0: 0.15 of the RSM */
}

/* the VPL methods: clusters, second-bounce VPLs and bounces of the row, the rest at
   the library's defaults (2048 Halton VPLs at 4 x 4 interleaving for clustered, 4096
   Hammersley at 8 x 8 for SSVP; 256^2 paraboloid maps) */
static void setup_vpl(gim_frame *f, const bench_method *m) {
    f->vpl.cluster_count = m->clusters;
    f->vpl.second_bounce_vpls = m->second_bounce_vpls;
    f->vpl.bounces = m->bounces;
}

/* LightSkin with imperfect shadow maps per cache (Ritschel et al. 2008) at the library's
   defaults; the row right after the same method without them, whose frame its
   visibility_over_off column divides by */
static void setup_ism(gim_frame *f, const bench_method *m) {
    (void)m;
    f->visibility.mode = GIM_VISIBILITY_ISM;
}

/* the VPL methods with one imperfect shadow map per VPL (Keller's instant radiosity with
   Ritschel's maps) instead of the clusters' paraboloid maps, right after the same row without */
static void setup_vpl_ism(gim_frame *f, const bench_method *m) {
    setup_vpl(f, m);
    f->visibility.mode = GIM_VISIBILITY_ISM;
}

/* LightSkin with rays through the scene's hierarchy on both sides of the interpolation: each
   VAL at each cache (GIM_VISIBILITY_RAYS) and each pixel to its neighbour caches
   (neighbour_rays); its visibility_over_off against the same method's row without visibility */
static void setup_rays(gim_frame *f, const bench_method *m) {
    (void)m;
    f->visibility.mode = GIM_VISIBILITY_RAYS;
    f->visibility.neighbour_rays = 1;
}

static void setup_anew(gim_frame *f, const bench_method *m) {
    (void)m;
    f->lightskin.temporal_steps = 1;   /* new offsets every frame (the default drifts 1/32 of their spacing) */
}

/* the VPL rows with ISMs, their VPLs (and maps) drawn anew every frame instead of followed
   (gim_frame_vpl.redraw; the default follows them: incremental instant radiosity) */
static void setup_vpl_ism_anew(gim_frame *f, const bench_method *m) {
    setup_vpl_ism(f, m);
    f->vpl.redraw = 1;
}

/* the VPL rows with their first-bounce VPLs drawn by BRSM's importance (gim_frame_vpl.importance),
   with the library's other defaults; the ISM row right after the one without */
static void setup_vpl_imp(gim_frame *f, const bench_method *m) {
    setup_vpl(f, m);
    f->vpl.importance = 1;
}

static void setup_vpl_ism_imp(gim_frame *f, const bench_method *m) {
    setup_vpl_ism(f, m);
    f->vpl.importance = 1;
}

/* the VPL rows with one shadow map per VPL drawn from the triangles (GIM_VISIBILITY_SHADOW_MAPS)
   instead of its ISM: at the sequence's VPLs (followed) and drawn by importance */
/* SSVP's second bounce from the clusters' attribute maps (GIM_SECOND_BOUNCE_MAPS, SSVP's paper)
   instead of by rays from the first-bounce VPLs (the default), right after the default's row */
static void setup_vpl_maps(gim_frame *f, const bench_method *m) {
    setup_vpl(f, m);
    f->vpl.second_bounce = GIM_SECOND_BOUNCE_MAPS;
}

static void setup_vpl_sm(gim_frame *f, const bench_method *m) {
    setup_vpl(f, m);
    f->visibility.mode = GIM_VISIBILITY_SHADOW_MAPS;
}

static void setup_vpl_sm_imp(gim_frame *f, const bench_method *m) {
    setup_vpl_sm(f, m);
    f->vpl.importance = 1;
}

static const bench_method baseline = {"full", GIM_METHOD_LIGHTSKIN_FULL, 0, 0, 0, 1, NULL, 1, 0};
static const bench_method methods[] = {
    {"gather", GIM_METHOD_RSM_GATHER, 0, 0, 0, 1, setup_gather, 1, 0},
    {"brsm", GIM_METHOD_LIGHTSKIN_BRSM, 1, 0, 0, 1, NULL, 1, 0},
    {"brsm-ism", GIM_METHOD_LIGHTSKIN_BRSM, 1, 0, 0, 1, setup_ism, 1, 0},
    {"brsm-rays", GIM_METHOD_LIGHTSKIN_BRSM, 1, 0, 0, 1, setup_rays, 4, 0},
    {"brsm-anew", GIM_METHOD_LIGHTSKIN_BRSM, 0, 0, 0, 1, setup_anew, 1, 0},
    /* Dong et al.: clusters 4 / 8 / 16 / 32 (30 is the library's default) */
    {"clustered", GIM_METHOD_CLUSTERED, 0, 4, 0, 1, setup_vpl, 2, 1},
    {"clustered", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl, 1, 1},
    {"clustered-ism", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_ism, 1, 1},
    {"clustered-ism-anew", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_ism_anew, 1, 1},
    {"clustered-imp", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_imp, 1, 1},
    {"clustered-ism-imp", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_ism_imp, 1, 1},
    {"clustered-sm", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_sm, 3, 1},
    {"clustered-sm-imp", GIM_METHOD_CLUSTERED, 0, 8, 0, 1, setup_vpl_sm_imp, 0, 1},
    {"clustered", GIM_METHOD_CLUSTERED, 0, 16, 0, 1, setup_vpl, 2, 1},
    {"clustered", GIM_METHOD_CLUSTERED, 0, 32, 0, 1, setup_vpl, 1, 1},
    /* SSVP Table I's grid: clusters 4 / 8 / 16 / 32 x second-bounce VPLs 64 / 256 / 1024, two bounces;
       and its first bounce alone */
    {"ssvp", GIM_METHOD_SSVP, 0, 8, 0, 1, setup_vpl, 1, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 4, 64, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 4, 256, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 4, 1024, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 8, 64, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl, 1, 1},
    {"ssvp-maps", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_maps, 1, 1},
    {"ssvp-ism", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_ism, 1, 1},
    {"ssvp-ism-anew", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_ism_anew, 1, 1},
    {"ssvp-imp", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_imp, 1, 1},
    {"ssvp-ism-imp", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_ism_imp, 1, 1},
    {"ssvp-sm", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_sm, 3, 1},
    {"ssvp-sm-imp", GIM_METHOD_SSVP, 0, 8, 256, 2, setup_vpl_sm_imp, 0, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 8, 1024, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 16, 64, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 16, 256, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 16, 1024, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 32, 64, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 32, 256, 2, setup_vpl, 2, 1},
    {"ssvp", GIM_METHOD_SSVP, 0, 32, 1024, 2, setup_vpl, 2, 1},
};
#define METHOD_COUNT (sizeof methods / sizeof methods[0])

/* --- the sweeps -------------------------------------------------------------------------- */

typedef struct bench_scene {
    const char *name, *source;    /* a built-in name or a glTF path */
    const char *fallback;         /* the built-in scene when the file is absent; NULL: skipped */
    const char *camera;           /* "EX,EY,EZ,TX,TY,TZ,FOVY_DEG" (--camera's form); NULL: the scene's own */
    uint32_t max_rsm[2];          /* largest RSM side (FULL's frame grows with it): ci, full */
    int width[2], height[2];      /* frame: ci, full */
} bench_scene;

/* Sponza's views under its default sun, at 64x36: the atrium along its length (4% of the
   pixels sunlit, 99% with indirect light), and the court from above a gallery at the other end
   (29% sunlit, 98% with indirect light). */
static const bench_scene scenes[] = {
    {"street", "street", NULL, NULL, {256, 2048}, {160, 320}, {90, 180}},
    {"cornell", CORNELL_GLTF, "cornell", NULL, {256, 512}, {160, 320}, {90, 180}},
    {"sponza-atrium", SPONZA_GLB, NULL, "-11,2.5,0.5,12,5,0,60", {128, 256}, {64, 320}, {36, 180}},
    {"sponza-gallery", SPONZA_GLB, NULL, "12,8,5,-10,1,-3,60", {128, 256}, {64, 320}, {36, 180}},
};
#define SCENE_COUNT (sizeof scenes / sizeof scenes[0])

/* Scenes run only when named on the command line, in no whole sweep. The courtyard (the scene
   layer's pillar between a sunlit floor and a wall; tests/gl/gltest_reference.c checks its indirect
   shadow): `bench_frame ci courtyard` took 140 s on 2 cores with its references cached (FULL at
   256^2 19 s a frame), too much to add to `make bench`. */
static const bench_scene named_scenes[] = {
    {"courtyard", "courtyard", NULL, NULL, {256, 512}, {160, 320}, {90, 180}},
};
#define NAMED_COUNT (sizeof named_scenes / sizeof named_scenes[0])

typedef struct bench_sweep {
    const char *name, *dir;       /* CSV sweep column; where results.csv goes */
    uint32_t rsm[5], vals[3], view_samples[2];
    int rsm_n, vals_n, vs_n;
    int ref_spp, runs;            /* reference paths per pixel; frames per median */
    int full_runs;                /* FULL's frames per median (its frame takes up to minutes; 1 timed) */
    uint32_t flicker_rsm;         /* flicker measured at this RSM size (street only) */
    int flicker_frames;
} bench_sweep;

static const bench_sweep sweeps[2] = {
    {"ci", "bench", {128, 256, 0, 0, 0}, {1024, 4096, 0}, {256, 0}, 2, 2, 1, 16384, 3, 3, 128, 6},
    {"full", "bench/full", {128, 256, 512, 1024, 2048}, {2048, 4096, 8192}, {256, 512}, 5, 3, 2, 16384, 3, 1, 256, 8},
};

/* --- measuring --------------------------------------------------------------------------- */

static FILE *csv;
static const bench_sweep *sw;
static int W, H;

static const char *const pass_names[GIM_PASS_COUNT] = {"rsm",  "gbuffer", "view_samples", "importance", "cumsum", "select",
                                                       "caches", "vals", "proxy", "shade", "vpls",
                                                       "kmeans", "paraboloid", "second_bounce", "blur", "ism"};

typedef struct measure {
    double frame_ms;              /* median of untimed frames */
    double pass_ms[GIM_PASS_COUNT]; /* medians of timing-2 frames */
    int pass_clock;               /* gim_stats.cpu_clock of those */
    double gpu_mib;
    uint32_t vals;                /* VALs the frame used */
} measure;

static void update(gim_context *ctx, const gim_frame *f) {
    if (gim_update(ctx, f) != GIM_OK) { fprintf(stderr, "gim_update failed\n"); exit(1); }
}

/* runs untimed frames (after a warm-up frame when warm), then timed_runs frames with timing 2
   for the per-pass medians. 0 when the first frame fails (FULL past the GL's limits: its VALs
   at 2048^2 exceed llvmpipe's 128 MiB storage blocks), 1 when measured. */
static int measure_frames(gim_context *ctx, const gim_frame *f, int warm, int runs, int timed_runs, measure *m) {
    double t[MAX_RUNS], p[GIM_PASS_COUNT][MAX_RUNS];
    gim_stats st;
    gim_frame timed = *f;
    int r, k;
    memset(&st, 0, sizeof st);
    if (warm) {
        if (gim_update(ctx, f) != GIM_OK) return 0;
        glFinish();
    }
    for (r = 0; r < runs; ++r) {
        double t0 = now_ms();
        if (r == 0 && !warm) {
            if (gim_update(ctx, f) != GIM_OK) return 0;
        } else {
            update(ctx, f);
        }
        glFinish();
        t[r] = now_ms() - t0;
    }
    m->frame_ms = median(t, runs);
    gim_frame_stats(ctx, &st);
    m->gpu_mib = (double)st.gpu_bytes / 1048576.0;
    m->vals = st.val_count;
    timed.timing = 2;
    for (r = 0; r < timed_runs; ++r) {
        update(ctx, &timed);
        gim_frame_stats(ctx, &st);
        for (k = 0; k < GIM_PASS_COUNT; ++k) p[k][r] = st.pass_ms[k];
    }
    for (k = 0; k < GIM_PASS_COUNT; ++k) m->pass_ms[k] = median(p[k], timed_runs);
    m->pass_clock = st.cpu_clock;
    return 1;
}

static void read_image(gim_context *ctx, float *rgba) {
    gltest_read_texture(gim_outputs(ctx).indirect, GL_RGBA, rgba);
}

/* rel. MAE of the indirect image (RGBA, GL rows bottom first) against the reference (RGB, top
   row first); -1 without a reference */
static double error_vs(const float *rgba, const float *ref) {
    float *rgb;
    compare_result r;
    int x, y, c;
    if (!ref) return -1.0;
    rgb = (float *)malloc((size_t)W * H * 12);
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x)
            for (c = 0; c < 3; ++c) rgb[(y * W + x) * 3 + c] = rgba[((H - 1 - y) * W + x) * 4 + c];
    compare_images(rgb, ref, (uint32_t)W, (uint32_t)H, &r, NULL);
    free(rgb);
    return r.rel_mae;
}

/* The reference's own noise as a rel. MAE against the true image: sum sqrt(2/pi) sigma / sum
   ref (E|X - mu| of a normal mean). Every "vs reference" figure carries about this much. */
static double reference_noise(const float *ref, const float *sigma) {
    double s = 0.0, m = 0.0;
    int i;
    for (i = 0; i < W * H * 3; ++i) { s += sigma[i]; m += fabs((double)ref[i]); }
    return m > 0.0 ? 0.7978845608 * s / m : -1.0;
}

static double mean_rel_diff(const float *a, const float *b) {
    double d = 0.0, m = 0.0;
    int i, c;
    for (i = 0; i < W * H; ++i) {
        if (b[i * 4 + 3] != 1.0f) continue;
        for (c = 0; c < 3; ++c) { d += fabs((double)a[i * 4 + c] - b[i * 4 + c]); m += b[i * 4 + c]; }
    }
    return m > 0.0 ? d / m : 0.0;
}

/* Whether GIMANY_BENCH_ROWS (a comma-separated list of row names; unset: every row) names this
   row's method. */
static int row_wanted(const char *name) {
    const char *list = getenv("GIMANY_BENCH_ROWS"), *p;
    size_t n = strlen(name);
    if (!list) return 1;
    for (p = list; *p; ) {
        const char *e = strchr(p, ',');
        size_t k = e ? (size_t)(e - p) : strlen(p);
        if (k == n && strncmp(p, name, n) == 0) return 1;
        if (!e) break;
        p = e + 1;
    }
    return 0;
}

/* Temporal flicker: sw->flicker_frames frames while the sun turns by STEP_DEG about
   the vertical per frame; the mean absolute frame-to-frame change of the image over its mean.
   FULL has no sampling noise, so its change is what the moving light itself causes; a method's
   flicker is its change minus FULL's. (The reference's own change would need far more paths
   per pixel than its noise allows at this step.) Also the median frame while the light moves
   (wall clock around gim_update + glFinish) and the mean imperfect shadow maps made a frame,
   into moving_ms and maps (frames 1 on: frame 0 follows the still frames before). */
#define STEP_DEG 0.25
static double image_change(gim_context *ctx, scene_gimany *g, gim_frame f, double *moving_ms, double *maps) {
    float *prev = (float *)malloc((size_t)W * H * 16), *cur = (float *)malloc((size_t)W * H * 16);
    double *t = (double *)malloc(sizeof(double) * (size_t)sw->flicker_frames);
    gim_vec3 d0 = g->lights[0].direction;
    double change = 0.0;
    int k, i;
    *maps = 0.0;
    for (k = 0; k < sw->flicker_frames; ++k) {
        double a = k * STEP_DEG * 3.14159265358979 / 180.0, num = 0.0, den = 0.0, t0;
        gim_stats st;
        g->lights[0].direction = gim_v3((float)(cos(a) * d0.x + sin(a) * d0.z), d0.y, (float)(-sin(a) * d0.x + cos(a) * d0.z));
        gim_set_lights(ctx, g->lights, g->light_count);
        f.frame_index = (uint32_t)k + 1u;
        f.lightskin.rotate_view_samples = 1;
        t0 = now_ms();
        update(ctx, &f);
        glFinish();
        t[k] = now_ms() - t0;
        gim_frame_stats(ctx, &st);
        if (k > 0) *maps += st.ism_maps_made;
        read_image(ctx, cur);
        if (k > 0) {
            for (i = 0; i < W * H * 4; ++i)
                if (i % 4 != 3) { num += fabs((double)cur[i] - prev[i]); den += cur[i]; }
            change += den > 0.0 ? num / den : 0.0;
        }
        memcpy(prev, cur, (size_t)W * H * 16);
    }
    g->lights[0].direction = d0;
    gim_set_lights(ctx, g->lights, g->light_count);
    *moving_ms = median(t + 1, sw->flicker_frames - 1);
    *maps /= sw->flicker_frames - 1;
    free(prev);
    free(cur);
    free(t);
    return change / (sw->flicker_frames - 1);
}

/* The error after a long move: the sun turned MOVE_DEG about the vertical, a degree a frame,
   the method following the light as it does by default (VPLs and their maps kept where still
   valid, Laine et al. 2007; BRSM's offsets drifting), and the last frame against the reference
   rendered at the turned sun (ref_moved); then the same frame made from nothing there (anew:
   vpl.redraw 1, lightskin.temporal_steps 1). The flicker rows measure change between frames;
   this measures whether what was kept stays right. follow 0: only the last frame (FULL, which
   keeps nothing). One frame each: a single draw of a sampled method varies (BRSM, 1024 VALs,
   the street: 0.245-0.271 over 12 draws, one at 0.551; docs/methods.md). */
#define MOVE_DEG 24
static void moved_error(gim_context *ctx, scene_gimany *g, gim_frame f, const float *ref_moved, int follow,
                        double *followed, double *anew) {
    float *img = (float *)malloc((size_t)W * H * 16);
    gim_vec3 d0 = g->lights[0].direction;
    int k;
    f.lightskin.rotate_view_samples = 1;
    for (k = follow ? 1 : MOVE_DEG; k <= MOVE_DEG; ++k) {
        double a = k * 3.14159265358979 / 180.0;
        g->lights[0].direction = gim_v3((float)(cos(a) * d0.x + sin(a) * d0.z), d0.y, (float)(-sin(a) * d0.x + cos(a) * d0.z));
        gim_set_lights(ctx, g->lights, g->light_count);
        f.frame_index = 1000u + (uint32_t)k;
        update(ctx, &f);
    }
    read_image(ctx, img);
    *followed = error_vs(img, ref_moved);
    f.vpl.redraw = 1;
    f.lightskin.temporal_steps = 1;
    update(ctx, &f);
    read_image(ctx, img);
    *anew = error_vs(img, ref_moved);
    g->lights[0].direction = d0;
    gim_set_lights(ctx, g->lights, g->light_count);
    free(img);
}

/* The energy VPL clamping removes (Krivanek's bias for variance): the image's sum at the
   default clamp against the same frame unclamped, from the same clusters (k-means restarted
   from its seeds in both). Printed; the README quotes it. */
static void clamp_loss(gim_context *ctx, gim_frame f, const float *img_default, const char *scene_name) {
    float *a = (float *)malloc((size_t)W * H * 16), *b = (float *)malloc((size_t)W * H * 16);
    double sa = 0.0, sb = 0.0;
    int i;
    (void)img_default;
    f.vpl.kmeans_restart = 1;
    update(ctx, &f);
    read_image(ctx, a);
    f.vpl.clamp_distance = -1.0f;
    update(ctx, &f);
    read_image(ctx, b);
    for (i = 0; i < W * H * 4; ++i) if (i % 4 != 3) { sa += a[i]; sb += b[i]; }
    printf("clamping (clustered, 8 clusters, %s): d_c = 0.01 scene scales removes %.2f%% of the indirect energy\n",
           scene_name, sb > 0.0 ? 100.0 * (1.0 - sa / sb) : 0.0);
    free(a);
    free(b);
}

/* The renderer's name without commas (a CSV field). */
static const char *renderer_name(void) {
    static char name[256];
    const char *r = (const char *)glGetString(GL_RENDERER);
    size_t i;
    snprintf(name, sizeof name, "%s", r ? r : "?");
    for (i = 0; name[i]; ++i) if (name[i] == ',') name[i] = ';';
    return name;
}

static void csv_header(void) {
    int k;
    fprintf(csv, "sweep,scene,width,height,method,rsm,vals,view_samples,clusters,second_bounce_vpls,bounces,frame_ms,"
                 "full_over_this,rel_diff_full,rel_mae_reference,ref_spp,ref_noise_mae");
    for (k = 0; k < GIM_PASS_COUNT; ++k) fprintf(csv, ",%s_ms", pass_names[k]);
    fprintf(csv, ",pass_clock,gpu_mib,image_change,flicker,visibility_over_off,ism_build_ms,renderer\n");
}

/* One row: printed and written to the CSV. t_full 0: no FULL at this size (its columns empty);
   change, flicker < -1: not measured. t_off: the frame of the same method without visibility
   (visibility_over_off = this frame / that), ism_build: the ISM pass of the frame that made the
   maps (timing 2); either <= 0: none (empty columns). */
static void row(const char *scene_name, const bench_method *bm, uint32_t rsm, uint32_t vs, const measure *m, double t_full,
                double diff_full, double err_ref, double ref_noise, double change, double flicker, double t_off,
                double ism_build) {
    int k;
    printf("| %-7s | %5u^2 | %-8s | %7u | %4u | %9.1f | %6.1f | %.4f | %6.3f | %5.2f |", scene_name, rsm, bm->name, m->vals, vs,
           m->frame_ms, t_full > 0.0 ? t_full / m->frame_ms : -1.0, t_full > 0.0 ? diff_full : -1.0, err_ref,
           t_off > 0.0 ? m->frame_ms / t_off : 1.0);
    for (k = 0; k < GIM_PASS_COUNT; ++k) if (m->pass_ms[k] > 0.0) printf(" %s %.1f", pass_names[k], m->pass_ms[k]);
    if (ism_build > 0.0) printf(" (ISM build %.1f)", ism_build);
    printf(" |\n");
    fflush(stdout);
    if (!csv) return;
    fprintf(csv, "%s,%s,%d,%d,%s,%u,%u,%u,%u,%u,%u,%.2f,", sw->name, scene_name, W, H, bm->name, rsm, m->vals, vs,
            bm->clusters, bm->second_bounce_vpls, bm->bounces, m->frame_ms);
    if (t_full > 0.0) fprintf(csv, "%.3f,%.5f,", t_full / m->frame_ms, diff_full);
    else fprintf(csv, ",,");
    if (err_ref >= 0.0) fprintf(csv, "%.5f,%d,%.5f", err_ref, sw->ref_spp, ref_noise);
    else fprintf(csv, ",,");
    for (k = 0; k < GIM_PASS_COUNT; ++k) fprintf(csv, ",%.3f", m->pass_ms[k]);
    fprintf(csv, ",%d,%.2f,", m->pass_clock, m->gpu_mib);
    if (change >= -1.0) fprintf(csv, "%.5f,%.5f", change, flicker);
    else fprintf(csv, ",");
    if (t_off > 0.0) fprintf(csv, ",%.3f", m->frame_ms / t_off);
    else fprintf(csv, ",");
    if (ism_build > 0.0) fprintf(csv, ",%.2f", ism_build);
    else fprintf(csv, ",");
    fprintf(csv, ",%s\n", renderer_name());
    fflush(csv);
}

/* mtime of path, 0 when absent */
static double file_time(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (double)st.st_mtime : 0.0;
}

/* The ground truth of the same view (Embree, tools/reference) when it is built: the image and
   its per-pixel standard error (both RGB, top row first), or NULL. Rendered once per scene,
   view, size, paths per pixel and bounces into build/bench_ref/ (the folder's name holds a hash
   of the command), and again when the renderer (which links the scene loader) is newer. extra:
   more options of the renderer ("" or, e.g., " --sun-dir X,Y,Z"). */
static float *reference(const bench_scene *bs, const char *source, int bounces, const char *extra, float **sigma) {
    char cmd[1024], dir[512], path[600], err[256];
    float *ref = NULL;
    uint32_t rw = 0, rh = 0, sw_ = 0, sh = 0, hash = 2166136261u;
    double bin = file_time("build/gimany-reference");
    size_t i;
    *sigma = NULL;
    if (bin == 0.0) return NULL;
    snprintf(cmd, sizeof cmd, "--scene %s%s%s --size %dx%d --spp %d --bounces %d --seed 1%s", source,
             bs->camera ? " --camera " : "", bs->camera ? bs->camera : "", W, H, sw->ref_spp, bounces, extra);
    for (i = 0; cmd[i]; ++i) hash = (hash ^ (unsigned char)cmd[i]) * 16777619u;
    snprintf(dir, sizeof dir, "build/bench_ref/%s_%dx%d_%dspp_%db_%08x", bs->name, W, H, sw->ref_spp, bounces, hash);
    snprintf(path, sizeof path, "%s/reference_stderr.pfm", dir);
    if (file_time(path) < bin) {
        char run[1600];
        double t0 = now_s();
        snprintf(run, sizeof run, "build/gimany-reference %s --out %s >/dev/null", cmd, dir);
        if (system(run) != 0) return NULL;
        printf("reference: rendered %s in %.0f s\n", dir, now_s() - t0);
    } else {
        printf("reference: cached %s\n", dir);
    }
    snprintf(path, sizeof path, "%s/reference.pfm", dir);
    if (scene_read_pfm(path, &ref, &rw, &rh, err, sizeof err) != 0 || rw != (uint32_t)W || rh != (uint32_t)H) {
        free(ref);
        return NULL;
    }
    snprintf(path, sizeof path, "%s/reference_stderr.pfm", dir);
    if (scene_read_pfm(path, sigma, &sw_, &sh, err, sizeof err) != 0 || sw_ != (uint32_t)W || sh != (uint32_t)H) {
        free(*sigma);
        *sigma = NULL;
    }
    return ref;
}

/* The reference at the sun of moved_error's last frame (bounces 1 or 2), or NULL. */
static float *moved_reference(const bench_scene *bs, const char *source, const scene_gimany *g, int bounces) {
    char extra[128];
    float *ref, *sigma = NULL;
    gim_vec3 d0 = g->lights[0].direction;
    double a = MOVE_DEG * 3.14159265358979 / 180.0;
    snprintf(extra, sizeof extra, " --sun-dir %.9g,%.9g,%.9g", cos(a) * d0.x + sin(a) * d0.z, (double)d0.y,
             -sin(a) * d0.x + cos(a) * d0.z);
    ref = reference(bs, source, bounces, extra, &sigma);
    free(sigma);
    return ref;
}

/* The fraction of pixels whose reference indirect light is not zero: a view that measures
   something has most of them. */
static double lit_fraction(const float *ref) {
    int i, n = 0;
    for (i = 0; i < W * H; ++i) n += ref[i * 3] + ref[i * 3 + 1] + ref[i * 3 + 2] > 0.0f;
    return (double)n / (W * H);
}

static void bench_scene_run(gim_context *ctx, gim_env env, const bench_scene *bs, uint32_t min_rsm) {
    int which = sw == &sweeps[0] ? 0 : 1, ri, mi, vi, si;
    const char *source = bs->source;
    uint32_t max_rsm = bs->max_rsm[which];
    scene s;
    scene_gimany g;
    gim_frame f;
    char err[256];
    float *full, *img, *ref, *sigma = NULL, *ref2 = NULL, *sigma2 = NULL, *refm = NULL, *refm2 = NULL;
    double ref_noise = -1.0, ref2_noise = -1.0;
    float cache_frac = 1.0f / 32.0f;
    W = bs->width[which];
    H = bs->height[which];
    if (strchr(source, '.')) {
        FILE *fp = fopen(source, "rb");
        if (fp) fclose(fp);
        else if (bs->fallback) source = bs->fallback;
        else {
            printf("\nscene %s: %s absent (skipped)\n", bs->name, source);
            return;
        }
    }
    if ((strchr(source, '.') ? scene_load_gltf(source, &s, err, sizeof err) : scene_builtin(source, &s, err, sizeof err)) != 0) {
        printf("scene %s: %s (skipped)\n", bs->name, err);
        return;
    }
    s.camera.width = (uint32_t)W;
    s.camera.height = (uint32_t)H;
    if (bs->camera) {
        float v[7];
        if (sscanf(bs->camera, "%f,%f,%f,%f,%f,%f,%f", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]) != 7) {
            fprintf(stderr, "scene %s: bad camera %s\n", bs->name, bs->camera);
            exit(1);
        }
        memcpy(s.camera.eye, v, sizeof s.camera.eye);
        memcpy(s.camera.target, v + 3, sizeof s.camera.target);
        s.camera.fovy = v[6] * 3.14159265f / 180.0f;
    }
    /* GIMANY_BENCH_CACHE_FRAC: cache spacing d_eps as a fraction of the scene's scale (default
       1/32; below 0: each mesh's own diagonal / 32, what gim_cache_generate alone gives) */
    if (getenv("GIMANY_BENCH_CACHE_FRAC")) cache_frac = (float)atof(getenv("GIMANY_BENCH_CACHE_FRAC"));
    if (scene_gimany_load(ctx, &s, cache_frac, 256, env, &g) != GIM_OK || g.light_count == 0) {
        printf("scene %s: no caches or no light (skipped)\n", bs->name);
        scene_gimany_free(ctx, &g);
        scene_free(&s);
        return;
    }
    full = (float *)malloc((size_t)W * H * 16);
    img = (float *)malloc((size_t)W * H * 16);
    memset(&f, 0, sizeof f);
    scene_gimany_camera(&s, &f.view, &f.proj);
    f.width = (uint32_t)W;
    f.height = (uint32_t)H;
    {
        uint32_t tris = 0, m;
        for (m = 0; m < s.mesh_count; ++m) tris += s.meshes[m].triangle_count;
        printf("\nscene: %s (%s%s%s), %u triangles, %u caches, %dx%d pixels, %u light(s); sweep %s\n", bs->name, source,
               bs->camera ? ", camera " : "", bs->camera ? bs->camera : "", tris, g.cache_count, W, H, g.light_count, sw->name);
    }
    ref = reference(bs, source, 1, "", &sigma);
    if (ref && sigma) ref_noise = reference_noise(ref, sigma);
    ref2 = reference(bs, source, 2, "", &sigma2);   /* the two-bounce rows' ground truth */
    if (ref2 && sigma2) ref2_noise = reference_noise(ref2, sigma2);
    if (ref)
        printf("reference: build/gimany-reference, %d paths per pixel; %.1f%% of the pixels carry indirect light; its noise "
               "alone is a rel. MAE of %.4f (%.4f two bounces)\n", sw->ref_spp, 100.0 * lit_fraction(ref), ref_noise, ref2_noise);
    else
        printf("reference: none (make reference builds it)\n");
    printf("| scene | RSM | method | VALs | view samples | frame ms | FULL : this | rel. diff to FULL | rel. MAE vs ref. | "
           "frame / no visibility | pass ms (timing 2 medians) |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (ri = 0; ri < sw->rsm_n && sw->rsm[ri] <= max_rsm; ++ri) {
        uint32_t rsm = sw->rsm[ri];
        int flick = strcmp(bs->name, "street") == 0 && rsm == sw->flicker_rsm, have_full;
        double c_full = -2.0, off_ms[3][2] = {{0.0}};
        measure m, mf;
        if (rsm < min_rsm) continue;
        g.lights[0].rsm_size = rsm;
        gim_set_lights(ctx, g.lights, g.light_count);
        /* FULL (no warm-up: a BRSM frame at this size has built every program and buffer it shares) */
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        f.lightskin.val_count = sw->vals[0];
        f.lightskin.view_sample_count = sw->view_samples[0];
        update(ctx, &f);
        f.method = baseline.method;
        have_full = measure_frames(ctx, &f, 0, sw->full_runs, 1, &mf);
        if (have_full) {
            read_image(ctx, full);
            if (flick) {
                double mov, maps, e1, e2;
                c_full = image_change(ctx, &g, f, &mov, &maps);
                if (!refm) refm = moved_reference(bs, source, &g, 1);
                if (!refm2) refm2 = moved_reference(bs, source, &g, 2);
                if (refm) {
                    moved_error(ctx, &g, f, refm, 0, &e1, &e2);
                    printf("  full: the sun turned %d degrees: rel. MAE %.4f against the reference there\n", MOVE_DEG, e1);
                }
            }
            row(bs->name, &baseline, rsm, 0, &mf, mf.frame_ms, 0.0, error_vs(full, ref), ref_noise, c_full, 0.0, 0.0, 0.0);
        } else {
            printf("| %-7s | %5u^2 | full   | does not run here (see the error above): no FULL columns at this size |\n", bs->name, rsm);
            mf.frame_ms = 0.0;
            flick = 0;
        }
        for (mi = 0; mi < (int)METHOD_COUNT; ++mi) {
            const bench_method *bm = &methods[mi];
            int nv = bm->per_val ? sw->vals_n : 1, ns = bm->per_val ? sw->vs_n : 1;
            if (bm->ci == 4 && (which != 0 || strcmp(bs->name, "street") != 0)) continue;
            if (which == 0 && (bm->ci == 0 || (bm->ci == 2 && strcmp(bs->name, "cornell") != 0) ||
                               (bm->ci == 3 && strncmp(bs->name, "sponza", 6) == 0)))
                continue;
            if (bm->vpl && rsm != sw->flicker_rsm) continue;   /* VPL methods: one RSM size */
            if (!row_wanted(bm->name)) continue;
            for (vi = 0; vi < nv; ++vi)
                for (si = 0; si < ns; ++si) {
                    gim_frame fm = f;
                    double c = -2.0, t_off = 0.0, ism_build = 0.0;
                    fm.method = bm->method;
                    fm.lightskin.val_count = bm->per_val ? sw->vals[vi] : 0;
                    fm.lightskin.view_sample_count = bm->per_val ? sw->view_samples[si] : 0;
                    if (bm->setup) bm->setup(&fm, bm);
                    if ((fm.method == GIM_METHOD_CLUSTERED || fm.method == GIM_METHOD_SSVP) && fm.vpl.interleave == 0)
                        fm.vpl.interleave = gim_vpl_default_interleave(fm.method, 1280, 720, fm.vpl.count);   /* 720 rows' */
                    if (fm.visibility.mode != GIM_VISIBILITY_OFF && fm.visibility.mode != GIM_VISIBILITY_DEFAULT) {
                        /* the maps' own pass, once per RSM size (the other VAL counts reuse the maps):
                           a frame without them frees them, the next makes them (RAYS: the hierarchy's
                           build, stamped GIM_PASS_ISM) */
                        if (vi == 0 && si == 0) {
                            gim_frame off = fm, build = fm;
                            gim_stats st;
                            off.visibility.mode = GIM_VISIBILITY_OFF;
                            off.visibility.neighbour_rays = 0;
                            update(ctx, &off);
                            build.timing = 2;
                            update(ctx, &build);
                            gim_frame_stats(ctx, &st);
                            /* the VPL methods' maps are GIM_PASS_PARABOLOID's (SSVP's with its attribute maps) */
                            ism_build = st.pass_ms[bm->vpl ? GIM_PASS_PARABOLOID : GIM_PASS_ISM];
                        }
                        if (mi > 0 && methods[mi - 1].method == bm->method &&
                            (!methods[mi - 1].setup || (bm->vpl && methods[mi - 1].setup == setup_vpl) ||
                             (bm->setup == setup_rays && methods[mi - 1].setup == setup_ism) ||
                             (bm->setup == setup_vpl_ism_imp && methods[mi - 1].setup == setup_vpl_imp)))
                            t_off = off_ms[vi][si];
                    }
                    if (bm->vpl) {   /* VPLs drawn at their texels, not followed from the row before (a still
                                        light then keeps them: the row's frame is the one drawn anew) */
                        gim_frame fresh = fm;
                        fresh.vpl.redraw = 1;
                        update(ctx, &fresh);
                    }
                    if (!measure_frames(ctx, &fm, 1, sw->runs, sw->runs, &m)) { fprintf(stderr, "gim_update failed\n"); exit(1); }
                    if ((bm->per_val && !bm->setup) || bm->setup == setup_vpl || bm->setup == setup_vpl_imp)
                        off_ms[vi][si] = m.frame_ms;
                    read_image(ctx, img);
                    if (flick && si == 0) {
                        double mov, maps;
                        c = image_change(ctx, &g, fm, &mov, &maps);
                        printf("  %s, vals %u: the light moving, median frame %.2f ms (still %.2f), %.1f maps made a "
                               "frame\n", bm->name, fm.lightskin.val_count, mov, m.frame_ms, maps);
                        if (vi == 0 && bm->setup != setup_anew && bm->setup != setup_vpl_ism_anew &&
                            (bm->bounces == 2 ? refm2 : refm)) {
                            double e1, e2;
                            moved_error(ctx, &g, fm, bm->bounces == 2 ? refm2 : refm, 1, &e1, &e2);
                            printf("  %s, vals %u: the sun turned %d degrees, a degree a frame: rel. MAE %.4f followed, "
                                   "%.4f drawn anew, against the reference there\n", bm->name, fm.lightskin.val_count,
                                   MOVE_DEG, e1, e2);
                        }
                    }
                    if (bm->setup == setup_vpl && bm->clusters == 8 && bm->bounces == 1 && bm->method == GIM_METHOD_CLUSTERED)
                        clamp_loss(ctx, fm, img, bs->name);
                    row(bs->name, bm, rsm, fm.lightskin.view_sample_count, &m, mf.frame_ms, have_full ? mean_rel_diff(img, full) : 0.0,
                        error_vs(img, bm->bounces == 2 ? ref2 : ref), bm->bounces == 2 ? ref2_noise : ref_noise, c,
                        c > -1.0 ? c - c_full : 0.0, t_off, ism_build);
                }
        }
    }
    scene_gimany_free(ctx, &g);
    scene_free(&s);
    free(full);
    free(img);
    free(ref);
    free(sigma);
    free(ref2);
    free(sigma2);
    free(refm);
    free(refm2);
}

/* Removes from the CSV at path the rows of sweep and scene_name whose RSM side is at least
   min_rsm (columns sweep, scene, width, height, method, rsm, ...). 0 on success. */
static int csv_drop_rows(const char *path, const char *sweep, const char *scene_name, uint32_t min_rsm) {
    FILE *fp = fopen(path, "rb");
    char *text, *line, *out;
    long size;
    size_t n = 0, dropped = 0;
    if (!fp) return 1;
    fseek(fp, 0, SEEK_END);
    size = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    text = (char *)malloc((size_t)size + 1);
    out = (char *)malloc((size_t)size + 1);
    if (!text || !out || size < 0 || fread(text, 1, (size_t)size, fp) != (size_t)size) {
        fclose(fp); free(text); free(out);
        return 1;
    }
    fclose(fp);
    text[size] = 0;
    for (line = text; *line;) {
        char *end = strchr(line, '\n');
        size_t len = end ? (size_t)(end - line) + 1 : strlen(line);
        size_t ls = strlen(sweep), lc = strlen(scene_name);
        int drop = 0;
        if (len > ls + lc + 2 && strncmp(line, sweep, ls) == 0 && line[ls] == ',' && strncmp(line + ls + 1, scene_name, lc) == 0 &&
            line[ls + 1 + lc] == ',') {
            const char *f = line;
            int k;
            for (k = 0; k < 5 && f; ++k) { f = strchr(f, ','); if (f) ++f; }   /* the 6th column: rsm */
            drop = f && (uint32_t)strtoul(f, NULL, 10) >= min_rsm;
        }
        if (drop) ++dropped;
        else { memcpy(out + n, line, len); n += len; }
        line += len;
    }
    fp = fopen(path, "wb");
    if (!fp || fwrite(out, 1, n, fp) != n) {
        if (fp) fclose(fp);
        free(text); free(out);
        return 1;
    }
    fclose(fp);
    free(text); free(out);
    if (dropped) printf("%s: %lu rows of %s / %s replaced\n", path, (unsigned long)dropped, sweep, scene_name);
    return 0;
}

int main(int argc, char **argv) {
    gim_desc d;
    gim_context *ctx = NULL;
    char err[256], path[256];
    size_t i;
    double t0 = now_s();
    int a, append = argc > 2;
    sw = &sweeps[argc > 1 && strcmp(argv[1], "full") == 0 ? 1 : 0];
    if (argc > 1 && strcmp(argv[1], "full") != 0 && strcmp(argv[1], "ci") != 0) {
        fprintf(stderr, "usage: bench_frame [ci|full [SCENE[:MIN_RSM]...]]\n");
        return 2;
    }
    if (!gltest_init()) {
        const char *skip = getenv("GIMANY_SKIP_GL");
        printf("bench_frame: no GL 4.3 context: %s\n", gltest.why);
        return skip && strcmp(skip, "1") == 0 ? 0 : 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env.logger.func = gim_log_stderr;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    printf("renderer: %s; sweep %s\n", renderer_name(), sw->name);
    snprintf(path, sizeof path, "%s/%s.csv", sw->dir, getenv("GIMANY_BENCH_ROWS") ? "rows" : "results");
    if (getenv("GIMANY_BENCH_ROWS")) append = 0;
    if (scene_make_dir(sw->dir, err, sizeof err) == 0) csv = fopen(path, append ? "a" : "w");
    if (csv) fseek(csv, 0, SEEK_END);
    if (csv && ftell(csv) == 0) csv_header();
    for (i = 0; i < SCENE_COUNT + NAMED_COUNT; ++i) {
        const bench_scene *bs = i < SCENE_COUNT ? &scenes[i] : &named_scenes[i - SCENE_COUNT];
        uint32_t min_rsm = 0;
        int run = argc <= 2 && i < SCENE_COUNT;
        for (a = 2; a < argc; ++a) {
            const char *colon = strchr(argv[a], ':');
            size_t n = colon ? (size_t)(colon - argv[a]) : strlen(argv[a]);
            /* the whole name, or a prefix that ends where the name has a '-' */
            if (n > 0 && strncmp(argv[a], bs->name, n) == 0 && (bs->name[n] == 0 || bs->name[n] == '-')) {
                run = 1;
                if (colon) min_rsm = (uint32_t)atoi(colon + 1);
            }
        }
        if (run && append && csv) {   /* a scene run again replaces its rows of this sweep from min_rsm on */
            fclose(csv);
            csv = csv_drop_rows(path, sw->name, bs->name, min_rsm) == 0 ? fopen(path, "a") : NULL;
        }
        if (run) bench_scene_run(ctx, d.env, bs, min_rsm);
    }
    if (csv) { fclose(csv); printf("wrote %s\n", path); }
    printf("sweep %s took %.0f s\n", sw->name, now_s() - t0);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
