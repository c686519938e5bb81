/* scene.h - the scenes, lights, camera and command line shared by the demo (build/gimany-demo)
   and the ground-truth renderer (build/gimany-reference). Plain C API (C99 and C++11); the
   implementation, scene/scene.cpp, is C++ because the glTF loader (tinygltf) is.

   A scene is what both programs render:
     meshes     triangles in WORLD space (node transforms applied), unit vertex normals,
                one material id per triangle
     materials  diffuse albedo rho_d and a normalised Phong glossy lobe (Bischoff 2017 eq. 3-4):
                  f_r(wi, wo) = rho_d / pi + rho_g (k + 2) / (2 pi) cos+^k(theta_e)
                theta_e is the angle between the mirror direction of wi and wo
     lights     directional (a sun: direction TOWARDS it, irradiance E on a surface facing it)
                or spot (position, axis, hard-edged cone of half-angle theta, intensity I per
                steradian inside it), each times an rgb colour
     camera     eye, target, vertical field of view, up +Y, image size
   Surfaces are two-sided: a surface seen from its back reflects as seen from its front.
   Emission in glTF files is not light: the lights are the only sources.

   Typical use (both programs):
       scene_options opt;
       scene_options_defaults(&opt, "out/demo");
       char err[256];
       int r = scene_parse_args(argc, argv, 0, &opt, err, sizeof err);
       if (r == SCENE_ARGS_HELP) return 0;
       if (r != SCENE_ARGS_OK) { fprintf(stderr, "gimany-demo: %s\n", err); return 2; }
       scene s;
       if (scene_load(&opt, &s, err, sizeof err) != 0) { fprintf(stderr, "...: %s\n", err); return 1; }
       ... render s ...
       scene_free(&s);
*/
#ifndef GIMANY_EXAMPLES_SCENE_H
#define GIMANY_EXAMPLES_SCENE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* f_r = rho_d / pi + rho_g (k + 2) / (2 pi) cos+^k(theta_e). */
typedef struct scene_material {
    float diffuse[3];   /* rho_d, each in [0,1] */
    float glossy[3];    /* rho_g, each in [0,1]; zero: no glossy lobe */
    float exponent;     /* k >= 0 */
} scene_material;

/* One triangle mesh in world space; the scene owns the arrays. */
typedef struct scene_mesh {
    float *positions;             /* vertex_count * 3 */
    float *normals;               /* vertex_count * 3, unit length */
    uint32_t vertex_count;
    uint32_t *indices;            /* triangle_count * 3, each < vertex_count */
    uint32_t *triangle_material;  /* triangle_count, each < scene.material_count */
    uint32_t triangle_count;
} scene_mesh;

typedef enum scene_light_type {
    SCENE_LIGHT_DIRECTIONAL = 1,
    SCENE_LIGHT_SPOT = 2
} scene_light_type;

typedef struct scene_light {
    scene_light_type type;
    float color[3];      /* rgb factor of E or I (1,1,1: white) */
    float direction[3];  /* unit; directional: TOWARDS the sun; spot: the axis it shines along */
    float irradiance;    /* directional: E on a surface facing the sun */
    float position[3];   /* spot */
    float half_angle;    /* spot: cone half-angle in radians, (0, pi]; hard edge, pi = point light */
    float intensity;     /* spot: I per steradian inside the cone */
} scene_light;

typedef struct scene_camera {
    float eye[3], target[3];
    float up[3];         /* +Y (the basis falls back to -Z when looking straight up or down) */
    float fovy;          /* vertical field of view, radians */
    uint32_t width, height;
} scene_camera;

typedef struct scene {
    scene_mesh *meshes;
    uint32_t mesh_count;
    scene_material *materials;
    uint32_t material_count;
    scene_light *lights;
    uint32_t light_count;
    scene_camera camera;
    float bounds_min[3], bounds_max[3];  /* of all vertices */
    float scale;         /* diagonal of the bounds: the scene scale relative lengths use */
    uint32_t warning_count;
    char warning[256];   /* the first warning (a part skipped, normals recomputed, ...) */
    char name[64];
} scene;

/* ---- command line ------------------------------------------------------------------------ */

/* The options of both programs; scene_options_defaults fills the defaults. */
typedef struct scene_options {
    const char *scene;            /* "street" (default), "cornell", "courtyard", or a .gltf/.glb path */
    int has_sun_dir;              /* --sun-dir X,Y,Z (towards the sun; normalised here) */
    float sun_dir[3];
    int has_sun_irradiance;       /* --sun-irradiance E (default 1) */
    float sun_irradiance;
    int has_spot;                 /* --spot PX,PY,PZ,DX,DY,DZ,HALF_ANGLE_DEG,INTENSITY */
    float spot_position[3], spot_direction[3], spot_half_angle_deg, spot_intensity;
    int has_camera;               /* --camera EX,EY,EZ,TX,TY,TZ,FOVY_DEG */
    float camera_eye[3], camera_target[3], camera_fovy_deg;
    uint32_t width, height;       /* --size WxH (default 640x360) */
    const char *out_dir;          /* --out DIR */
    int bounces;                  /* --bounces 1|2 (default 1) */
    uint32_t spp;                 /* --spp N (reference only; default 256) */
    uint32_t seed;                /* --seed N (reference only; default 1) */
} scene_options;

/* flags of scene_parse_args */
#define SCENE_ARGS_REFERENCE 1u   /* accept --spp and --seed */

/* results of scene_parse_args */
#define SCENE_ARGS_OK 0
#define SCENE_ARGS_HELP 1          /* --help / -h: usage printed to stdout, exit 0 */
#define SCENE_ARGS_ERROR (-1)      /* err holds one line saying what is wrong */

void scene_options_defaults(scene_options *opt, const char *default_out_dir);
/* Parses argv[1..argc-1] into opt (strings point into argv). */
int scene_parse_args(int argc, char *const *argv, unsigned flags, scene_options *opt,
                     char *err, size_t err_cap);
/* Usage text for --help. */
const char *scene_usage(unsigned flags);

/* ---- scenes ------------------------------------------------------------------------------ */
/* Every function returns 0 on success; on failure it returns non-zero, writes one line into
   err (when err_cap > 0) and leaves *out zeroed (nothing to free). The glTF loaders (and
   scene_load with a glTF) return SCENE_NO_TRIANGLES for a well-formed file whose scene holds no
   triangle: nothing to render, which the demo draws as a black image rather than an error. */
#define SCENE_NO_TRIANGLES 2

/* Loads opt->scene and applies the light, camera and size options:
   lights: none of --sun-dir/--sun-irradiance/--spot -> the scene's own lights;
           otherwise a sun when --sun-dir or --sun-irradiance is given (direction defaulting to
           the scene's sun, or to (0.4, 1, 0.3) normalised) plus the --spot light when given. */
int scene_load(const scene_options *opt, scene *out, char *err, size_t err_cap);
/* Built-in scenes by name, with their default lights and camera (image 640x360):
     "cornell"  the measured Cornell box in metres, a spot 1 cm under the ceiling light pointing
                down (60 deg half-angle, I = 0.3), the measured camera
     "street"   scene/street.h's street (about 100k triangles, metres), its sun (E = 1), a
                camera at the start of the road looking down it
     "courtyard" a sunlit floor, a wall the sun shines along and a free-standing pillar
                between them (14 triangles, metres), its sun (E = 1), a camera looking down
                at the wall over the pillar: the pillar's indirect shadow on the wall */
int scene_builtin(const char *name, scene *out, char *err, size_t err_cap);
/* What the glTF loaders accept (a file beyond is refused with one line, before the expensive
   step): JSON nested at most SCENE_MAX_JSON_DEPTH levels (the parser recurses per level);
   the file and its external buffers and images regular files (no FIFO, device or directory)
   of at most SCENE_MAX_FILE_BYTES, read by their size; a node graph expanding to at most
   SCENE_MAX_INSTANCES mesh instances and SCENE_MAX_TRIANGLES declared triangles. Images above
   SCENE_MAX_IMAGE_PIXELS, or past SCENE_MAX_DECODED_BYTES decoded in one file, are skipped
   with a warning (their materials keep the factors). */
#define SCENE_MAX_JSON_DEPTH 128u
#define SCENE_MAX_FILE_BYTES (1ull << 31)
#define SCENE_MAX_INSTANCES 65536.0
#define SCENE_MAX_TRIANGLES 16777216.0
#define SCENE_MAX_IMAGE_PIXELS (4096ull * 4096ull)
#define SCENE_MAX_DECODED_BYTES (256ull << 20)
/* A glTF 2.0 file (.gltf or .glb). See scene.cpp for the material mapping and the lights. */
int scene_load_gltf(const char *path, scene *out, char *err, size_t err_cap);
/* The same from memory; base_dir resolves external URIs (NULL: none allowed). */
int scene_load_gltf_memory(const void *data, size_t size, const char *base_dir, scene *out,
                           char *err, size_t err_cap);
/* Checks every invariant listed above (finite numbers, ranges, unit normals, ids in range);
   hand-built scenes call it, the loaders already do. Recomputes bounds and scale, normalises
   light directions and sets camera.up to +Y. */
int scene_validate(scene *s, char *err, size_t err_cap);
/* Frees what a loader allocated; a zeroed scene is fine. */
void scene_free(scene *s);

/* ---- camera ------------------------------------------------------------------------------ */
/* The ray through pixel (px, py) of the image, in pixels from the top-left corner (pixel
   centres are at +0.5): origin = eye, dir unit. Both programs use it for the same pixels. */
void scene_camera_ray(const scene_camera *cam, float px, float py, float origin[3], float dir[3]);
/* Column-major OpenGL view and projection matrices for the same camera (depth range -1..1). */
void scene_camera_matrices(const scene_camera *cam, float znear, float zfar, float view[16],
                           float proj[16]);

/* ---- images ------------------------------------------------------------------------------ */
/* Creates dir and its parents (like mkdir -p). */
int scene_make_dir(const char *dir, char *err, size_t err_cap);
/* Writes w x h linear RGB floats given top row first as a little-endian PFM (rows bottom first,
   as PFM wants). */
int scene_write_pfm(const char *path, const float *rgb, uint32_t w, uint32_t h, char *err,
                    size_t err_cap);
/* Reads an RGB PFM written by anyone (either endianness) into *rgb (malloc'ed, top row first). */
int scene_read_pfm(const char *path, float **rgb, uint32_t *w, uint32_t *h, char *err,
                   size_t err_cap);

#ifdef __cplusplus
}
#endif
#endif
