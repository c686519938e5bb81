/* Absolute frame times on a real GPU: every method at the sizes a game runs (1920x1080, RSM
   2048^2, 8192 VALs, 256 view samples), on the inside of Sponza's atrium and on the procedural
   street, whole frame and per pass. `make bench-gpu` runs it and writes the table between the
   README's <!-- bench:gpu --> markers with the GL renderer's name and the date.

   On llvmpipe these sizes take hours, so without a hardware EGL device it refuses to run; the
   option --small (160x90, RSM 128^2, 1024 VALs, one frame each) checks the whole code path there, and `make bench`
   runs it that way. Times: the median of untimed frames (wall clock around gim_update and
   glFinish, after warm-up frames) and per-pass medians from frames with gim_frame.timing = 1
   (GL timestamps: on a GPU they charge each pass its own work; llvmpipe's do not, which is why
   bench_frame uses timing = 2 and why --small's per-pass figures mean nothing). A row whose
   frame is slow measures fewer frames (about 3 s of frames, at least 3), and --budget-s S skips the
   rows that would start after S seconds (each skipped row says so), so one call fits a lease.
   --only TEXT measures only the rows whose "scene, method" holds TEXT. --dump-programs DIR first
   writes every program's driver binary (glGetProgramBinary) to DIR/NAME.bin: NVIDIA's holds the
   assembly it compiled to, with its temporaries and local-memory arrays, to read offline.
   Usage: bench_gpu [--small] [--out FILE] [--sponza GLB] [--budget-s S] [--only TEXT] [--dump-programs DIR] */
#include "benchutil.h"
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define SPONZA_GLB "../shared/scenes/sponza_lod4/sponza_lod4.glb"
#define MAX_FRAMES 31

typedef struct gpu_method {
    const char *name;
    gim_method method;
    gim_visibility visibility;
    uint32_t bounces;
    uint32_t importance_tile;   /* 0: the library's default */
    uint32_t neighbours;        /* LightSkin's caches per pixel; 0: the default (16) */
    uint32_t shade_block;       /* LightSkin's shading blocks; 0: the default (2 x 2) */
} gpu_method;

/* every method at its library defaults but for the sizes above, each with imperfect shadow maps
   right after it (the cost of visibility: the ISM row over the row before), the VPL methods
   also with a shadow map per VPL from the triangles (GIM_VISIBILITY_SHADOW_MAPS; their maps
   kept over the timed frames, the light being still: the first frame's build is what costs); LightSkin + BRSM is
   the default method, also with the two-level importance map's measured tile (8), with fewer
   caches per pixel (what the shading pass's neighbour search costs) and shaded per pixel
   instead of in 2 x 2 blocks */
static const gpu_method methods[] = {
    {"RSM gather", GIM_METHOD_RSM_GATHER, GIM_VISIBILITY_OFF, 0, 0, 0, 0},
    {"LightSkin + BRSM", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 0, 0, 0, 0},
    {"LightSkin + BRSM, ISM", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_ISM, 0, 0, 0, 0},
    {"LightSkin + BRSM, tile 8", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 0, 8, 0, 0},
    {"LightSkin + BRSM, 4 caches a pixel", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 0, 0, 4, 0},
    {"LightSkin + BRSM, 1 cache a pixel", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 0, 0, 1, 0},
    {"LightSkin + BRSM, shaded per pixel", GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_OFF, 0, 0, 0, 1},
    {"LightSkin FULL", GIM_METHOD_LIGHTSKIN_FULL, GIM_VISIBILITY_OFF, 0, 0, 0, 0},
    {"LightSkin FULL, ISM", GIM_METHOD_LIGHTSKIN_FULL, GIM_VISIBILITY_ISM, 0, 0, 0, 0},
    {"clustered", GIM_METHOD_CLUSTERED, GIM_VISIBILITY_OFF, 1, 0, 0, 0},
    {"clustered, ISM", GIM_METHOD_CLUSTERED, GIM_VISIBILITY_ISM, 1, 0, 0, 0},
    {"clustered, shadow maps", GIM_METHOD_CLUSTERED, GIM_VISIBILITY_SHADOW_MAPS, 1, 0, 0, 0},
    {"SSVP, 2 bounces", GIM_METHOD_SSVP, GIM_VISIBILITY_OFF, 2, 0, 0, 0},
    {"SSVP, 2 bounces, ISM", GIM_METHOD_SSVP, GIM_VISIBILITY_ISM, 2, 0, 0, 0},
    {"SSVP, 2 bounces, shadow maps", GIM_METHOD_SSVP, GIM_VISIBILITY_SHADOW_MAPS, 2, 0, 0, 0},
};
#define METHOD_COUNT (sizeof methods / sizeof methods[0])

typedef struct gpu_scene {
    const char *name, *source;    /* a built-in name or a glTF path */
    const char *camera;           /* "EX,EY,EZ,TX,TY,TZ,FOVY_DEG"; NULL: the scene's own */
} gpu_scene;

static gpu_scene scenes[] = {
    {"sponza-atrium", SPONZA_GLB, "-11,2.5,0.5,12,5,0,60"},
    {"street", "street", NULL},
};

static int W = 1920, H = 1080, frames = 21, warm_frames = 3;
static uint32_t rsm_size = 2048, val_count = 8192;

static const char *pass_name(int k) {
    static const char *const names[GIM_PASS_COUNT] = {
        "rsm", "gbuffer", "view samples", "importance", "cumsum", "select", "caches", "vals",
        "proxy", "shade", "vpls", "kmeans", "paraboloid", "second bounce", "blur", "ism"};
    return names[k];
}

/* The first frame alone (programs built, maps made: what a host sees once), warm-up, then n
   untimed frames (median wall clock) and n timed ones (per-pass medians, GL timestamps), n =
   `frames` or fewer for a slow frame (about 3 s of frames, at least 3); 0 when gim_update refuses
   the frame */
static int measure(gim_context *ctx, const gim_frame *f, double *first_ms, double *frame_ms, double *pass_ms,
                   double *mib, int *measured) {
    double t[MAX_FRAMES], p[GIM_PASS_COUNT][MAX_FRAMES], t0, warm_ms = 0.0;
    gim_frame timed = *f;
    gim_stats st;
    int r, k, n = frames;
    t0 = now_ms();
    if (gim_update(ctx, f) != GIM_OK) return 0;
    glFinish();
    *first_ms = now_ms() - t0;
    for (r = 0; r < warm_frames; ++r) {
        t0 = now_ms();
        if (gim_update(ctx, f) != GIM_OK) return 0;
        glFinish();
        warm_ms = now_ms() - t0;
    }
    if (warm_ms * n > 3000.0) n = warm_ms * 3.0 > 3000.0 ? 3 : (int)(3000.0 / warm_ms);
    if (n < 1) n = 1;
    for (r = 0; r < n; ++r) {
        t0 = now_ms();
        if (gim_update(ctx, f) != GIM_OK) return 0;
        glFinish();
        t[r] = now_ms() - t0;
    }
    *frame_ms = median(t, n);
    memset(&st, 0, sizeof st);
    gim_frame_stats(ctx, &st);
    *mib = (double)st.gpu_bytes / 1048576.0;
    timed.timing = 1;
    for (r = 0; r < n; ++r) {
        if (gim_update(ctx, &timed) != GIM_OK || gim_frame_stats(ctx, &st) != GIM_OK) return 0;
        for (k = 0; k < GIM_PASS_COUNT; ++k) p[k][r] = st.pass_ms[k];
    }
    for (k = 0; k < GIM_PASS_COUNT; ++k) pass_ms[k] = median(p[k], n);
    *measured = n;
    return 1;
}

static double budget_s = 0.0, start_s;

/* Every program gimany has, built, and its binary as the driver gives it, one file each. */
static void dump_programs(gim_context *ctx, const char *dir) {
    int id;
    for (id = 0; id < GIM__PROGRAM_COUNT; ++id) {
        GLuint p = 0;
        GLint len = 0, got = 0;
        GLenum format = 0;
        char path[512];
        void *buf;
        FILE *fp;
        if (gim__gl_program(ctx, (gim__program_id)id, &p) != GIM_OK) continue;
        glGetProgramiv(p, GL_PROGRAM_BINARY_LENGTH, &len);
        if (len <= 0 || !(buf = malloc((size_t)len))) {
            fprintf(stderr, "bench_gpu: %s: no program binary\n", gim__program_files[id][0]);
            continue;
        }
        glGetProgramBinary(p, len, &got, &format, buf);
        snprintf(path, sizeof path, "%s/%s%s.bin", dir, gim__program_files[id][0],
                 gim__program_files[id][1] ? gim__program_files[id][1] : "");
        if ((fp = fopen(path, "wb")) != NULL && fwrite(buf, 1, (size_t)got, fp) == (size_t)got)
            fprintf(stderr, "bench_gpu: %s: %d bytes, format 0x%x\n", path, (int)got, (unsigned)format);
        else
            fprintf(stderr, "bench_gpu: cannot write %s\n", path);
        if (fp) fclose(fp);
        free(buf);
    }
}
static const char *only = NULL;   /* --only: rows whose "scene, method" holds it */

/* 1 if --only asks for method mi of scene gs (every row without --only) */
static int wanted(const gpu_scene *gs, size_t mi) {
    char row[160];
    if (!only) return 1;
    snprintf(row, sizeof row, "%s, %s", gs->name, methods[mi].name);
    return strstr(row, only) != NULL;
}

static void run_scene(gim_context *ctx, gim_env env, const gpu_scene *gs, FILE *out) {
    const char *source = gs->source;
    scene s;
    scene_gimany g;
    gim_frame f;
    char err[256];
    size_t mi;
    for (mi = 0; mi < METHOD_COUNT && !wanted(gs, mi); ++mi) {}
    if (mi == METHOD_COUNT) return;   /* no row of this scene asked for: not even loaded */
    if (strchr(source, '.')) {
        FILE *fp = fopen(source, "rb");
        if (!fp) {
            fprintf(out, "| %s | (scene file absent: skipped) | | | | | |\n", gs->name);
            return;
        }
        fclose(fp);
    }
    if ((strchr(source, '.') ? scene_load_gltf(source, &s, err, sizeof err) : scene_builtin(source, &s, err, sizeof err)) != 0) {
        fprintf(out, "| %s | (%s: skipped) | | | | | |\n", gs->name, err);
        return;
    }
    s.camera.width = (uint32_t)W;
    s.camera.height = (uint32_t)H;
    if (gs->camera) {
        float v[7];
        if (sscanf(gs->camera, "%f,%f,%f,%f,%f,%f,%f", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]) == 7) {
            memcpy(s.camera.eye, v, sizeof s.camera.eye);
            memcpy(s.camera.target, v + 3, sizeof s.camera.target);
            s.camera.fovy = v[6] * 3.14159265f / 180.0f;
        }
    }
    if (scene_gimany_load(ctx, &s, 1.0f / 32.0f, rsm_size, env, &g) != GIM_OK || g.light_count == 0) {
        fprintf(out, "| %s | (no caches or no light: skipped) | | | | | |\n", gs->name);
        scene_gimany_free(ctx, &g);
        scene_free(&s);
        return;
    }
    memset(&f, 0, sizeof f);
    scene_gimany_camera(&s, &f.view, &f.proj);
    f.width = (uint32_t)W;
    f.height = (uint32_t)H;
    f.lightskin.val_count = val_count;
    f.lightskin.view_sample_count = 256;
    for (mi = 0; mi < METHOD_COUNT; ++mi) {
        double first_ms, frame_ms, pass_ms[GIM_PASS_COUNT], mib;
        char passes[512];
        size_t used = 0;
        int k, n;
        if (!wanted(gs, mi)) continue;
        if (budget_s > 0.0 && now_s() - start_s > budget_s) {
            fprintf(out, "| %s | %s | skipped: past --budget-s %.0f | | | | |\n", gs->name, methods[mi].name, budget_s);
            continue;
        }
        f.method = methods[mi].method;
        f.visibility.mode = methods[mi].visibility;
        f.vpl.bounces = methods[mi].bounces;
        f.lightskin.importance_tile = methods[mi].importance_tile;
        f.lightskin.neighbour_count = methods[mi].neighbours;
        f.lightskin.shade_block = methods[mi].shade_block;
        fprintf(stderr, "bench_gpu: %.0f s: %s, %s\n", now_s() - start_s, gs->name, methods[mi].name);
        if (!measure(ctx, &f, &first_ms, &frame_ms, pass_ms, &mib, &n)) {
            fprintf(out, "| %s | %s | refused (see the log line above) | | | | |\n", gs->name, methods[mi].name);
            continue;
        }
        passes[0] = 0;
        for (k = 0; k < GIM_PASS_COUNT; ++k)
            if (pass_ms[k] >= 0.005 && used < sizeof passes - 40)
                used += (size_t)snprintf(passes + used, sizeof passes - used, "%s%s %.2f", used ? ", " : "", pass_name(k),
                                         pass_ms[k]);
        fprintf(out, "| %s | %s | %.2f | %d | %.0f | %.0f | %s |\n", gs->name, methods[mi].name, frame_ms, n, first_ms,
                mib, passes);
        fflush(out);
    }
    scene_gimany_free(ctx, &g);
    scene_free(&s);
}

int main(int argc, char **argv) {
    gim_desc d;
    gim_context *ctx = NULL;
    FILE *out = stdout;
    const char *out_path = NULL, *dump_dir = NULL;
    int a, small = 0;
    size_t i;
    for (a = 1; a < argc; ++a) {
        if (strcmp(argv[a], "--small") == 0) small = 1;
        else if (strcmp(argv[a], "--out") == 0 && a + 1 < argc) out_path = argv[++a];
        else if (strcmp(argv[a], "--sponza") == 0 && a + 1 < argc) scenes[0].source = argv[++a];
        else if (strcmp(argv[a], "--budget-s") == 0 && a + 1 < argc) budget_s = atof(argv[++a]);
        else if (strcmp(argv[a], "--only") == 0 && a + 1 < argc) only = argv[++a];
        else if (strcmp(argv[a], "--dump-programs") == 0 && a + 1 < argc) dump_dir = argv[++a];
        else {
            fprintf(stderr, "usage: bench_gpu [--small] [--out FILE] [--sponza GLB] [--budget-s S] [--only TEXT] [--dump-programs DIR]\n");
            return 2;
        }
    }
    start_s = now_s();
    if (!gltest_init()) {
        printf("bench_gpu: no GL 4.3 context: %s\n", gltest.why);
        return 1;
    }
    if (small) {
        W = 160;
        H = 90;
        rsm_size = 128;
        val_count = 1024;
        frames = 1;
        warm_frames = 1;
    } else if (strcmp(gltest.platform, "device") != 0) {
        printf("bench_gpu: no hardware EGL device (renderer %s); these sizes would take hours here. "
               "--small checks the code path.\n", (const char *)glGetString(GL_RENDERER));
        gltest_shutdown();
        return 1;
    }
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env.logger.func = gim_log_stderr;
    if (gim_create(&d, &ctx) != GIM_OK) return 1;
    if (dump_dir) dump_programs(ctx, dump_dir);
    if (out_path && !(out = fopen(out_path, "w"))) {
        fprintf(stderr, "bench_gpu: cannot write %s\n", out_path);
        return 1;
    }
    {
        time_t now = time(NULL);
        char day[32];
        strftime(day, sizeof day, "%Y-%m-%d", gmtime(&now));
        fprintf(out, "%s (%s), %s: %dx%d, RSM %u^2, %u VALs, 256 view samples; medians of up to %d frames (the frames column: "
                "fewer where a frame is slow); per pass from GL timestamps (ms); the first frame builds the programs of "
                "the method and makes its maps\n\n", (const char *)glGetString(GL_RENDERER), (const char *)glGetString(GL_VERSION), day, W,
                H, rsm_size, val_count, frames);
    }
    fprintf(out, "| scene | method | frame ms | frames | first frame ms | GPU MiB | passes (ms) |\n"
                 "|---|---|---|---|---|---|---|\n");
    for (i = 0; i < sizeof scenes / sizeof scenes[0]; ++i) run_scene(ctx, d.env, &scenes[i], out);
    if (out != stdout) fclose(out);
    gim_destroy(ctx);
    gltest_shutdown();
    return 0;
}
