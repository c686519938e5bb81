/* gimany-reference: the ground truth of the indirect light, for the demo and the benchmarks.
     build/gimany-reference [--scene street|cornell|FILE.gltf|FILE.glb] [--sun-dir X,Y,Z]
         [--sun-irradiance E] [--spot PX,PY,PZ,DX,DY,DZ,HALF_ANGLE_DEG,INTENSITY]
         [--camera EX,EY,EZ,TX,TY,TZ,FOVY_DEG] [--size WxH] [--out DIR] [--bounces 1|2]
         [--spp N] [--seed N]
   writes DIR/reference.pfm (linear RGB indirect radiance, PFM row order), DIR/reference_stderr.pfm
   (per-pixel standard error of each channel) and DIR/reference.json (settings and statistics). */
#include "reference.h"
#include "scene.h"

#include <cstdio>
#include <cstring>
#include <string>
#include <thread>

static const char *prog = "gimany-reference";

static std::string json_escape(const char *s) {
    std::string o;
    for (; *s; ++s) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') { o += '\\'; o += (char)c; }
        else if (c < 0x20) { char b[8]; std::snprintf(b, sizeof b, "\\u%04x", c); o += b; }
        else o += (char)c;
    }
    return o;
}

int main(int argc, char **argv) {
    scene_options opt;
    scene_options_defaults(&opt, "out/reference");
    char err[512] = "";
    int r = scene_parse_args(argc, argv, SCENE_ARGS_REFERENCE, &opt, err, sizeof err);
    if (r == SCENE_ARGS_HELP) return 0;
    if (r != SCENE_ARGS_OK) {
        std::fprintf(stderr, "%s: %s\n", prog, err);
        return 2;
    }
    scene s;
    if (scene_load(&opt, &s, err, sizeof err) != 0) {
        std::fprintf(stderr, "%s: %s\n", prog, err);
        return 1;
    }
    if (s.warning_count) std::fprintf(stderr, "%s: %u warning(s), first: %s\n", prog, s.warning_count, s.warning);
    if (scene_make_dir(opt.out_dir, err, sizeof err) != 0) {
        std::fprintf(stderr, "%s: %s\n", prog, err);
        scene_free(&s);
        return 1;
    }
    ref_settings st;
    std::memset(&st, 0, sizeof st);
    st.spp = opt.spp;
    st.seed = opt.seed;
    st.bounces = opt.bounces;
    st.threads = 0;
    ref_image img;
    if (ref_render(&s, &st, &img, err, sizeof err) != 0) {
        std::fprintf(stderr, "%s: %s\n", prog, err);
        scene_free(&s);
        return 1;
    }
    std::string dir(opt.out_dir), pfm = dir + "/reference.pfm", sep = dir + "/reference_stderr.pfm",
                                  js = dir + "/reference.json";
    int rc = 0;
    if (scene_write_pfm(pfm.c_str(), img.radiance, img.width, img.height, err, sizeof err) != 0 ||
        scene_write_pfm(sep.c_str(), img.std_error, img.width, img.height, err, sizeof err) != 0) {
        std::fprintf(stderr, "%s: %s\n", prog, err);
        rc = 1;
    }
    unsigned threads = std::max(1u, std::thread::hardware_concurrency());
    if (!rc) {
        FILE *f = std::fopen(js.c_str(), "w");
        if (!f) {
            std::fprintf(stderr, "%s: cannot write %s\n", prog, js.c_str());
            rc = 1;
        } else {
            const scene_camera &c = s.camera;
            std::fprintf(f,
                         "{\n  \"scene\": \"%s\",\n  \"width\": %u,\n  \"height\": %u,\n  \"bounces\": %d,\n"
                         "  \"spp\": %u,\n  \"seed\": %u,\n"
                         "  \"camera\": {\"eye\": [%.9g, %.9g, %.9g], \"target\": [%.9g, %.9g, %.9g], \"fovy_deg\": %.9g},\n"
                         "  \"lights\": %u,\n  \"triangles\": %llu,\n  \"covered_pixels\": %u,\n"
                         "  \"mean_radiance\": %.9g,\n  \"mean_std_error\": %.9g,\n  \"relative_std_error\": %.9g,\n"
                         "  \"relative_std_error_image_mean\": %.9g,\n  \"rays\": %llu,\n  \"nonfinite_samples\": %llu,\n  \"threads\": %u,\n"
                         "  \"build_seconds\": %.6f,\n  \"seconds\": %.6f,\n"
                         "  \"files\": {\"radiance\": \"reference.pfm\", \"std_error\": \"reference_stderr.pfm\"}\n}\n",
                         json_escape(opt.scene).c_str(), img.width, img.height, opt.bounces, opt.spp, opt.seed,
                         c.eye[0], c.eye[1], c.eye[2], c.target[0], c.target[1], c.target[2], c.fovy * 57.29577951308232,
                         s.light_count,
                         [&] { unsigned long long t = 0; for (uint32_t i = 0; i < s.mesh_count; ++i) t += s.meshes[i].triangle_count; return t; }(),
                         img.covered_pixels, img.mean_radiance, img.mean_std_error, img.relative_std_error,
                         img.relative_std_error_image, (unsigned long long)img.rays,
                         (unsigned long long)img.nonfinite_samples, threads, img.build_seconds,
                         img.seconds);
            if (std::fclose(f) != 0) rc = 1;
        }
    }
    if (!rc && img.nonfinite_samples)
        std::fprintf(stderr, "%s: warning: %llu paths gave a non-finite value (counted as 0)\n", prog,
                     (unsigned long long)img.nonfinite_samples);
    if (!rc)
        std::printf("%s: %s %ux%u, %d bounce(s), %u spp: mean radiance %.6g, relative standard error %.4f%% "
                    "(per pixel, mean) / %.5f%% (image mean), %.2f s (%.1f Mrays/s), wrote %s\n",
                    prog, opt.scene, img.width, img.height, opt.bounces, opt.spp, img.mean_radiance,
                    100.0 * img.relative_std_error, 100.0 * img.relative_std_error_image, img.seconds,
                    img.seconds > 0 ? img.rays / img.seconds * 1e-6 : 0.0, pfm.c_str());
    ref_image_free(&img);
    scene_free(&s);
    return rc;
}
