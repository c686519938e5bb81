/* gimany.h - real-time global illumination with many-light methods, single header, OpenGL 4.3
   version 0.1.0, MIT licence (see the end of this file)

   WHAT IT IS
     One and two bounces of indirect light (diffuse and glossy) for hobby engines, from
     reflective shadow maps (RSM), LightSkin light caches, bidirectional importance sampling of
     the RSM, clustered visibility and screen-space VPL propagation. Every GPU pass has a CPU
     twin in this header that computes the same numbers; the twins are what the tests compare
     the GPU against, and they serve hosts without GL 4.3.

   USE
     In exactly one C or C++ file:
         #define GIMANY_IMPLEMENTATION
         #include "gimany.h"
     Everywhere else just #include "gimany.h".

   CONFIG MACROS (define before the include that has GIMANY_IMPLEMENTATION)
     GIMANY_NO_GL          drop the GL runtime: only the CPU parts, no GL header needed
     GIMANY_STATIC         make every function static (private to one translation unit)
     GIMANY_API            linkage of public functions (default: extern)
     GIMANY_MALLOC(sz,u) / GIMANY_FREE(p,u)
                           fallback allocator (both or neither; default malloc/free);
                           a gim_env allocator in a call's descriptor takes precedence
     GIMANY_ASSERT(x)      internal invariants (default assert)
     GIMANY_DEBUG          GL error checks after every pass (default on when !NDEBUG)

   ERRORS
     Every function that can fail returns a gim_result (GIM_OK == 0) and writes one line
     through the log callback of the gim_env it was given ("gimany: <function>: <what>").
     Nothing in gimany calls exit() or abort(); outputs are left untouched on error unless a
     function says otherwise.

   UNITS (see DESIGN.md sec. 4)
     Linear radiometry in float. Lengths are in the host's unit; every length threshold is
     relative to a scene scale (the diagonal of the scene bounds unless given), so the same
     scene in millimetres or kilometres gives the same numbers.

   EXAMPLE (CPU parts)
         float pts[2 * 256];
         gim_halton_points(pts, 256, 2, 0, NULL);            first 256 2D Halton points

         gim_kmeans_desc kd = {0};                           zero means default
         kd.positions = vpl_pos; kd.normals = vpl_nrm; kd.flux = vpl_flux;
         kd.vpl_count = 1024; kd.cluster_count = 30; kd.scene_scale = 10.0f;
         gim_kmeans_result kr;                                caller-owned arrays, sized by counts
         ...
         if (gim_kmeans(&kd, &kr) != GIM_OK) { ... }

   METHODS (each one setting of the same runtime)
     RSM gather          fixed RSM samples per pixel, no visibility (Dachsbacher 2005; baseline)
     LightSkin full      every RSM texel is a VAL accumulated into per-cache proxy lights
     LightSkin + BRSM    importance map -> cumulative sums -> N selected VALs weighted by 1/P
     Clustered           k-means of VPLs into VALs with paraboloid soft shadow maps (Dong)
     SSVP                two bounces from paraboloid maps per cluster (Aranha et al.)

   TABLE OF CONTENTS (search for the tag)
     @section config       config macros, version, linkage
     @section common       result codes, allocator, log, environment
     @section math         vectors, matrices, colour helpers
     @section samplers     radical inverse, Halton, Hammersley, disk, hemisphere, rotation
     @section kmeans       k-means of VPLs into clusters (Dong metric, SSVP metric)
     @section caches       LightSkin light-cache generator, neighbour caches, blobs
     @section importance   importance map (eq. 10-11), cumulative sums (eq. 12), selection
     @section twins        CPU twins of the GPU passes
     @section gl           the GL 4.3 runtime (absent with GIMANY_NO_GL)
   The implementation follows under GIMANY_IMPLEMENTATION in the same order, each part tagged
   @impl <name>.
*/

/* @section config ========================================================================= */
#ifndef GIMANY_H
#define GIMANY_H

#define GIMANY_VERSION 100              /* major * 10000 + minor * 100 + patch */
#define GIMANY_VERSION_STRING "0.1.0"

#include <stddef.h>
#include <stdint.h>

#ifndef GIMANY_API
#ifdef GIMANY_STATIC
#define GIMANY_API static
#else
#define GIMANY_API extern
#endif
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* @section common ========================================================================= */

/* Result of every call that can fail; GIM_OK is zero. */
typedef enum gim_result {
    GIM_OK = 0,
    GIM_ERROR_INVALID_ARGUMENT,   /* NULL, zero count, out-of-range value, NaN/Inf input */
    GIM_ERROR_OUT_OF_MEMORY,      /* the allocator returned NULL */
    GIM_ERROR_CORRUPT_DATA,       /* a blob failed its version, size or checksum test */
    GIM_ERROR_OUT_OF_RANGE,       /* valid input outside the documented supported range */
    GIM_ERROR_UNSUPPORTED,        /* the GL context lacks a version or feature gimany needs */
    GIM_ERROR_GL,                 /* a GL call, shader compile or link failed */
    GIM_RESULT_COUNT
} gim_result;

/* Severity of a log message. */
typedef enum gim_log_level {
    GIM_LOG_ERROR = 0,
    GIM_LOG_WARNING,
    GIM_LOG_INFO
} gim_log_level;

/* Allocation callbacks; zero-filled means GIMANY_MALLOC/GIMANY_FREE. */
typedef struct gim_allocator {
    void *(*alloc)(size_t size, void *user_data);
    void (*free)(void *ptr, void *user_data);
    void *user_data;
} gim_allocator;

/* Log callback; NULL means silent (results still carry the error). */
typedef struct gim_logger {
    void (*func)(gim_log_level level, const char *message, void *user_data);
    void *user_data;
} gim_logger;

/* The host environment every descriptor carries: allocator and log. Zero means defaults. */
typedef struct gim_env {
    gim_allocator allocator;
    gim_logger logger;
} gim_env;

/* A short English name of a result code ("GIM_ERROR_INVALID_ARGUMENT"). */
GIMANY_API const char *gim_result_string(gim_result r);

/* A ready-made logger body that prints to stderr; use as gim_logger.func. */
GIMANY_API void gim_log_stderr(gim_log_level level, const char *message, void *user_data);

/* @section math =========================================================================== */

/* Plain vector and matrix types; matrices are column-major like OpenGL. */
typedef struct gim_vec2 { float x, y; } gim_vec2;
typedef struct gim_vec3 { float x, y, z; } gim_vec3;
typedef struct gim_vec4 { float x, y, z, w; } gim_vec4;
typedef struct gim_mat4 { float m[16]; } gim_mat4;  /* m[col * 4 + row] */

GIMANY_API gim_vec3 gim_v3(float x, float y, float z);             /* constructor */
GIMANY_API gim_vec3 gim_v3_add(gim_vec3 a, gim_vec3 b);            /* a + b */
GIMANY_API gim_vec3 gim_v3_sub(gim_vec3 a, gim_vec3 b);            /* a - b */
GIMANY_API gim_vec3 gim_v3_scale(gim_vec3 a, float s);             /* a * s */
GIMANY_API gim_vec3 gim_v3_mul(gim_vec3 a, gim_vec3 b);            /* component-wise a * b */
GIMANY_API float gim_v3_dot(gim_vec3 a, gim_vec3 b);               /* a . b */
GIMANY_API gim_vec3 gim_v3_cross(gim_vec3 a, gim_vec3 b);          /* a x b */
GIMANY_API float gim_v3_length(gim_vec3 a);                        /* |a| */
GIMANY_API gim_vec3 gim_v3_normalize(gim_vec3 a);                  /* a / |a|; (0,0,0) stays zero */
GIMANY_API float gim_v3_luminance(gim_vec3 rgb);                   /* Rec. 709 luminance */
GIMANY_API int gim_v3_isfinite(gim_vec3 a);                        /* 1 when no NaN/Inf */
GIMANY_API void gim_basis(gim_vec3 n, gim_vec3 *t, gim_vec3 *b);   /* orthonormal t, b around unit n */

GIMANY_API gim_mat4 gim_mat4_identity(void);                                  /* I */
GIMANY_API gim_mat4 gim_mat4_mul(gim_mat4 a, gim_mat4 b);                     /* a * b */
GIMANY_API gim_vec3 gim_mat4_point(gim_mat4 m, gim_vec3 p);                   /* m * (p,1), divided by w */
GIMANY_API gim_vec3 gim_mat4_dir(gim_mat4 m, gim_vec3 d);                     /* m * (d,0) */
GIMANY_API gim_vec4 gim_mat4_vec4(gim_mat4 m, gim_vec4 v);                    /* m * v */
GIMANY_API int gim_mat4_invert(gim_mat4 m, gim_mat4 *out);                    /* 0 when singular */
GIMANY_API gim_mat4 gim_mat4_transpose(gim_mat4 m);                           /* m^T */
GIMANY_API gim_mat4 gim_mat4_normal(gim_mat4 model);                          /* inverse transpose of the 3x3 */
GIMANY_API gim_mat4 gim_mat4_look_at(gim_vec3 eye, gim_vec3 target, gim_vec3 up);     /* gluLookAt */
GIMANY_API gim_mat4 gim_mat4_perspective(float fovy_rad, float aspect, float znear, float zfar); /* gluPerspective */
GIMANY_API gim_mat4 gim_mat4_ortho(float l, float r, float b, float t, float n, float f); /* glOrtho */
GIMANY_API int gim_mat4_isfinite(gim_mat4 m);                                 /* 1 when no NaN/Inf */

/* @section samplers ======================================================================= */
/* Low-discrepancy points. Radical inverses are computed with integer digit reversal and one
   final division in double, so they are exact (correctly rounded) for every index up to
   2^32-1; no float accumulates along the index. Dimension d of Halton uses the d-th prime
   (2, 3, 5, ...), up to GIM_MAX_HALTON_DIMENSIONS. */

#define GIM_MAX_HALTON_DIMENSIONS 64

GIMANY_API uint32_t gim_prime(uint32_t dim);                            /* the dim-th prime from 0; 0 past the table */
GIMANY_API double gim_radical_inverse(uint32_t base, uint32_t index);   /* digits of index mirrored at the point; base 2..65535 */
GIMANY_API double gim_van_der_corput(uint32_t index);                   /* radical inverse in base 2 */
GIMANY_API double gim_halton(uint32_t index, uint32_t dim);             /* dim-th Halton coordinate of point index */
GIMANY_API double gim_hammersley(uint32_t index, uint32_t count, uint32_t dim); /* dim 0: index/count; dim d: Halton dim d-1 */

/* count points of dims coordinates into out[count * dims]: Halton points start..start+count-1.
   offsets (dims values in [0,1), or NULL) applies a Cranley-Patterson rotation. */
GIMANY_API gim_result gim_halton_points(float *out, uint32_t count, uint32_t dims, uint32_t start,
                                        const float *offsets);
/* The same for the Hammersley set of count points. */
GIMANY_API gim_result gim_hammersley_points(float *out, uint32_t count, uint32_t dims,
                                            const float *offsets);
/* Per-frame Cranley-Patterson offsets in [0,1): a decorrelating hash of (frame, dim). */
GIMANY_API void gim_rotation_offsets(float *out, uint32_t dims, uint32_t frame);
/* frac(u + offset): the rotation itself, kept in [0,1) even when rounding would give 1. */
GIMANY_API float gim_rotate01(float u, float offset);

/* Area-preserving map of the unit square to the unit disk (Shirley-Chiu concentric map). */
GIMANY_API gim_vec2 gim_square_to_disk(float u, float v);
/* Cosine-weighted direction on the hemisphere around +Z (Malley: disk lifted to the sphere);
   pdf = cos(theta)/pi. */
GIMANY_API gim_vec3 gim_square_to_cosine_hemisphere(float u, float v);

/* @section kmeans ========================================================================= */
/* k-means of VPLs (position, normal, flux) into clusters, each standing for a virtual area
   light (Dong et al. sec. 5; SSVP sec. 3). Deterministic: same input, same output. */

/* Distance between a VPL and a cluster centre. */
typedef enum gim_kmeans_metric {
    GIM_KMEANS_METRIC_DEFAULT = 0,  /* = DONG */
    GIM_KMEANS_METRIC_DONG,         /* w_x * |x_i - c_j| / scene_scale + w_a * acos(n_i . n_j) / pi */
    GIM_KMEANS_METRIC_SSVP          /* w_x * |x_i - c_j|^2 / scene_scale^2 + w_a * (1 - n_i . n_j): SSVP eq. 2 with its slip corrected */
} gim_kmeans_metric;

/* Where the iteration starts. */
typedef enum gim_kmeans_init {
    GIM_KMEANS_INIT_DEFAULT = 0,    /* = FIXED */
    GIM_KMEANS_INIT_FIXED,          /* cluster k seeded by VPL floor(k * N / M): the same every frame (Dong 5.2) */
    GIM_KMEANS_INIT_WARM            /* start from init_centres/init_normals (the previous frame's) */
} gim_kmeans_init;

/* Input of gim_kmeans; zero means default. Arrays are float3 per VPL. */
typedef struct gim_kmeans_desc {
    const float *positions;     /* vpl_count * 3 */
    const float *normals;       /* vpl_count * 3, unit length (renormalised internally) */
    const float *flux;          /* vpl_count * 3, rgb, >= 0; NULL: every VPL weighs 1 */
    uint32_t vpl_count;         /* N > 0 */
    uint32_t cluster_count;     /* M > 0; M > N gives N non-empty clusters and M - N empty ones */
    gim_kmeans_metric metric;
    gim_kmeans_init init;
    const float *init_centres;  /* WARM: cluster_count * 3 */
    const float *init_normals;  /* WARM: cluster_count * 3 */
    float w_x, w_a;             /* metric weights, default 0.7 / 0.3 */
    float scene_scale;          /* length unit of the position term; default: diagonal of the VPL bounds */
    uint32_t max_iterations;    /* default 16 */
    gim_env env;
} gim_kmeans_desc;

/* Output of gim_kmeans: caller-owned arrays sized by the desc's counts. */
typedef struct gim_kmeans_result {
    float *centres;        /* M * 3: flux-weighted mean position (required) */
    float *normals;        /* M * 3: normalised flux-weighted mean normal (required) */
    float *flux;           /* M * 3: summed flux, or NULL */
    uint32_t *counts;      /* M: VPLs per cluster, or NULL */
    uint32_t *assignment;  /* N: cluster of each VPL, or NULL */
    float *area;           /* M: area of the 2D bounding rectangle in the plane of the mean normal, or NULL */
    float *sigma;          /* M * 3: positional standard deviation per world axis, or NULL */
    uint32_t iterations;   /* written: iterations run */
    uint32_t empty_repaired; /* written: clusters re-seeded because they went empty */
} gim_kmeans_result;

/* Cluster the VPLs; see the desc for defaults. */
GIMANY_API gim_result gim_kmeans(const gim_kmeans_desc *desc, gim_kmeans_result *result);

/* @section caches ========================================================================= */
/* LightSkin light caches (paper 000 sec. 3 "Cache Distribution"; Lensing 2013): sparse points
   on the surface where indirect light is accumulated, then interpolated per pixel. Built once
   per mesh in model space. d_eps bounds the cache-to-surface distance (voxels of edge d_eps/2),
   theta_eps the normal deviation a cache may represent. */

/* Index width of a mesh. */
typedef enum gim_index_type {
    GIM_INDEX_DEFAULT = 0,   /* = U32 */
    GIM_INDEX_U32,
    GIM_INDEX_U16
} gim_index_type;

/* A triangle mesh in model space; shared by the cache generator and the neighbour search. */
typedef struct gim_mesh_data {
    const float *positions;           /* vertex_count * 3 (or position_stride bytes apart) */
    uint32_t vertex_count;
    uint32_t position_stride;         /* bytes between vertices; 0 = 12 */
    const float *normals;             /* vertex_count * 3, or NULL (face normals are used) */
    uint32_t normal_stride;           /* bytes; 0 = 12 */
    const void *indices;              /* index_count indices, 3 per triangle */
    uint32_t index_count;
    gim_index_type index_type;
    const uint32_t *triangle_material; /* index_count / 3 material ids, or NULL (all material 0) */
    const float *material_reflectance; /* material_count reflection coefficients in [0,1], or NULL (all 1) */
    uint32_t material_count;
} gim_mesh_data;

/* One light cache: two RGBA32F texels in the paper's layout (position + area, normal + rho). */
typedef struct gim_cache {
    float position[3];
    float area;          /* surface area it represents; the areas of a mesh's caches sum to its area */
    float normal[3];     /* unit */
    float reflectance;   /* area-weighted reflection coefficient of the surface it represents */
} gim_cache;

/* What the generator skipped or did, for the host's log. */
typedef struct gim_cache_report {
    uint32_t triangles_used;
    uint32_t triangles_degenerate;   /* zero area or collinear (area < 1e-7 x longest edge^2 / 2) */
    uint32_t triangles_nonfinite;    /* a NaN/Inf coordinate */
    uint32_t triangles_duplicate;    /* same three vertex positions as an earlier triangle, same
                                        winding (the reversed one is the other face of a wall) */
    uint32_t voxels;                 /* occupied voxels */
    uint32_t caches_before_merge;
    uint32_t caches_snapped;         /* floating caches moved onto the nearest triangle */
    double surface_area;             /* of the used triangles */
} gim_cache_report;

/* Input of gim_cache_generate; zero means default. */
typedef struct gim_cache_desc {
    gim_mesh_data mesh;
    float d_eps;          /* max cache-to-surface distance; default scene_scale / 32 */
    float theta_eps;      /* max normal deviation in radians, (0, pi/2]; default 30 degrees */
    float scene_scale;    /* default: diagonal of the mesh bounds */
    int no_snap;          /* 1: keep floating caches where averaging put them */
    int no_merge;         /* 1: skip joining similar caches of neighbouring voxels */
    gim_env env;
} gim_cache_desc;

/* A generated (or loaded) set of caches; owns its array (free with gim_cache_set_free). */
typedef struct gim_cache_set {
    gim_cache *caches;
    uint32_t count;
    float d_eps, theta_eps;  /* the values used (after defaults) */
    gim_cache_report report;
    gim_env env;             /* allocator that owns caches */
} gim_cache_set;

/* Generate caches for one mesh; out is written only on GIM_OK. Every surface point lies within
   d_eps of a cache whose normal is within theta_eps of its own; the cache areas partition the
   used surface; degenerate, non-finite and duplicate triangles are skipped and counted, an
   out-of-range index or material is GIM_ERROR_INVALID_ARGUMENT, a d_eps too small for the
   mesh extent GIM_ERROR_OUT_OF_RANGE. Deterministic; single-threaded; memory linear in the
   voxel pieces (about one per triangle, plus one per voxel a large triangle crosses). */
GIMANY_API gim_result gim_cache_generate(const gim_cache_desc *desc, gim_cache_set *out);
/* Free what gim_cache_generate or gim_cache_blob_read allocated; NULL or zeroed is fine. */
GIMANY_API void gim_cache_set_free(gim_cache_set *set);

/* Largest neighbour count per vertex (eq. 8 interpolation). */
#define GIM_MAX_NEIGHBOUR_CACHES 16

/* Input of gim_cache_neighbours: for every vertex, the n nearest caches whose normal is within
   theta_eps (default: the set's) of the vertex normal, and d_c,max, the largest of their
   distances, for the weights of eq. 8. */
typedef struct gim_neighbour_desc {
    gim_mesh_data mesh;          /* positions and normals (normals NULL: area-weighted face normals) */
    const gim_cache_set *caches;
    uint32_t n;                  /* 1..GIM_MAX_NEIGHBOUR_CACHES, default 16 */
    float theta_eps;             /* default: caches->theta_eps */
    gim_env env;
} gim_neighbour_desc;

/* Caller-owned output of gim_cache_neighbours, sized by the mesh's vertex count. */
typedef struct gim_neighbour_result {
    uint32_t *index;   /* vertex_count * n cache indices, nearest first; UINT32_MAX pads */
    uint32_t *count;   /* vertex_count: how many of the n were found (compatible caches may be fewer) */
    float *d_cmax;     /* vertex_count: distance of the farthest found cache (0 when none) */
} gim_neighbour_result;

/* Per-vertex neighbour caches through a spatial grid (not O(V x C)). */
GIMANY_API gim_result gim_cache_neighbours(const gim_neighbour_desc *desc, gim_neighbour_result *out);

/* Versioned, checksummed byte blob of a cache set (little-endian), to precompute once. */
GIMANY_API size_t gim_cache_blob_size(const gim_cache_set *set);
/* Write the blob into out (capacity bytes, at least gim_cache_blob_size). */
GIMANY_API gim_result gim_cache_blob_write(const gim_cache_set *set, void *out, size_t capacity);
/* Read a blob; a truncated, corrupt or foreign one is GIM_ERROR_CORRUPT_DATA. */
GIMANY_API gim_result gim_cache_blob_read(const void *blob, size_t size, gim_env env, gim_cache_set *out);

/* @section importance ===================================================================== */
/* Bidirectional importance sampling of the RSM (paper 000 sec. 4, after Ritschel 2011).
   Every RSM texel is a VAL; its importance is its flux luminance times a geometry term
   averaged over view samples (eq. 10), with the squared distance clamped below at
   (clamp * scene_scale)^2 (eq. 11 made unit-free). */

/* One view sample: a visible surface point and its normal (from the G-buffer). */
typedef struct gim_view_sample {
    gim_vec3 position;
    gim_vec3 normal;
} gim_view_sample;

/* Input of gim_importance_map. The RSM arrays are width * height, row-major, row 0 first. */
typedef struct gim_importance_desc {
    const float *rsm_position;  /* width * height * 3: world position of each texel */
    const float *rsm_normal;    /* width * height * 3: unit normal */
    const float *rsm_flux;      /* width * height * 3: reflected flux, rgb */
    const float *rsm_valid;     /* width * height, or NULL: 0 where the RSM saw nothing */
    uint32_t width, height;
    const gim_view_sample *view_samples;
    uint32_t view_sample_count;
    float scene_scale;          /* > 0 */
    float clamp;                /* eq. 11 clamp distance in scene scales; default 1/64 */
    gim_env env;
} gim_importance_desc;

/* eq. 10-11: importance of every texel into out[width * height]. */
GIMANY_API gim_result gim_importance_map(const gim_importance_desc *desc, float *out);

/* The two tables of eq. 12, built in double so P stays exact at 4096^2:
   column[y * width + x] = sum over rows 0..y of map(x, .)   (vertical, per column),
   row[x] = sum over columns 0..x of column[(height-1) * width + .] (horizontal totals). */
GIMANY_API gim_result gim_importance_cumsum(const float *map, uint32_t width, uint32_t height,
                                            double *column, double *row, gim_env env);

/* One selected VAL: its texel and the probability it had of being picked. */
typedef struct gim_selected_val {
    uint32_t x, y;
    float pdf;                  /* P_VAL = map(x,y) / total; > 0 for every selected texel */
} gim_selected_val;

/* Pick count texels with probability proportional to the map by binary search in the
   cumulative sums, one stratified sample each: u_i = (i + xi) / count with xi the Halton
   sequence rotated by seed. An all-zero (or all-invalid) map selects the texels uniformly
   (pdf = 1 / (width * height)) and logs a warning: the estimator stays unbiased. */
GIMANY_API gim_result gim_importance_select(const double *column, const double *row,
                                            uint32_t width, uint32_t height, uint32_t count,
                                            uint32_t seed, gim_selected_val *out, gim_env env);

/* @section twins ========================================================================== */

#ifdef __cplusplus
}
#endif

/* @section gl ============================================================================= */
#ifndef GIMANY_NO_GL
#endif /* GIMANY_NO_GL */

#endif /* GIMANY_H */

/* ========================================================================================= */
/*                                   IMPLEMENTATION                                          */
/* ========================================================================================= */
#ifdef GIMANY_IMPLEMENTATION
#ifndef GIMANY_IMPLEMENTATION_DONE
#define GIMANY_IMPLEMENTATION_DONE

#include <math.h>
#include <string.h>
#include <stdio.h>
#include <stdarg.h>
#include <float.h>

#if defined(GIMANY_MALLOC) != defined(GIMANY_FREE)
#error "gimany: define both GIMANY_MALLOC and GIMANY_FREE, or neither"
#endif
#ifndef GIMANY_MALLOC
#include <stdlib.h>
#define GIMANY_MALLOC(sz, u) ((void)(u), malloc(sz))
#define GIMANY_FREE(p, u) ((void)(u), free(p))
#endif
#ifndef GIMANY_ASSERT
#include <assert.h>
#define GIMANY_ASSERT(x) assert(x)
#endif
#if !defined(GIMANY_DEBUG) && !defined(NDEBUG)
#define GIMANY_DEBUG 1
#endif

#ifdef GIMANY_STATIC
#define GIMANY_DEF static
#else
#define GIMANY_DEF
#endif
/* private helpers that a build (GIMANY_NO_GL, say) may leave unused */
#if defined(__GNUC__) || defined(__clang__)
#define GIM__UNUSED __attribute__((unused))
#else
#define GIM__UNUSED
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* @impl common ============================================================================ */

GIMANY_DEF const char *gim_result_string(gim_result r) {
    switch (r) {
    case GIM_OK: return "GIM_OK";
    case GIM_ERROR_INVALID_ARGUMENT: return "GIM_ERROR_INVALID_ARGUMENT";
    case GIM_ERROR_OUT_OF_MEMORY: return "GIM_ERROR_OUT_OF_MEMORY";
    case GIM_ERROR_CORRUPT_DATA: return "GIM_ERROR_CORRUPT_DATA";
    case GIM_ERROR_OUT_OF_RANGE: return "GIM_ERROR_OUT_OF_RANGE";
    case GIM_ERROR_UNSUPPORTED: return "GIM_ERROR_UNSUPPORTED";
    case GIM_ERROR_GL: return "GIM_ERROR_GL";
    default: return "GIM_ERROR_UNKNOWN";
    }
}

GIMANY_DEF void gim_log_stderr(gim_log_level level, const char *message, void *user_data) {
    static const char *names[] = {"error", "warning", "info"};
    (void)user_data;
    fprintf(stderr, "[%s] %s\n", names[(unsigned)level < 3u ? (unsigned)level : 0u], message);
}

/* printf-style message through the env's logger, prefixed with "gimany: <where>: ". */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((format(printf, 4, 5)))
#endif
static GIM__UNUSED void gim__log(const gim_env *env, gim_log_level level, const char *where, const char *fmt, ...) {
    char buf[512];
    int n;
    va_list ap;
    if (!env || !env->logger.func) return;
    n = snprintf(buf, sizeof buf, "gimany: %s: ", where);
    if (n < 0 || n >= (int)sizeof buf) n = 0;
    va_start(ap, fmt);
    vsnprintf(buf + n, sizeof buf - (size_t)n, fmt, ap);
    va_end(ap);
    env->logger.func(level, buf, env->logger.user_data);
}

/* Log an error and return its code, so checks read `return gim__fail(...)`. */
#if defined(__GNUC__) || defined(__clang__)
__attribute__((format(printf, 4, 5)))
#endif
static GIM__UNUSED gim_result gim__fail(const gim_env *env, gim_result r, const char *where, const char *fmt, ...) {
    char buf[448];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    gim__log(env, GIM_LOG_ERROR, where, "%s (%s)", buf, gim_result_string(r));
    return r;
}

/* Allocation through the env's allocator or GIMANY_MALLOC; NULL for size 0 or overflow. */
static GIM__UNUSED void *gim__alloc(const gim_env *env, size_t size) {
    if (size == 0) return NULL;
    if (env && env->allocator.alloc) return env->allocator.alloc(size, env->allocator.user_data);
    return GIMANY_MALLOC(size, env ? env->allocator.user_data : NULL);
}
static GIM__UNUSED void gim__free(const gim_env *env, void *p) {
    if (!p) return;
    if (env && env->allocator.free) { env->allocator.free(p, env->allocator.user_data); return; }
    GIMANY_FREE(p, env ? env->allocator.user_data : NULL);
}
/* count * size with overflow check; 0 on overflow (gim__alloc then fails). */
static GIM__UNUSED size_t gim__array_size(size_t count, size_t size) {
    if (size != 0 && count > (size_t)-1 / size) return 0;
    return count * size;
}
static GIM__UNUSED void *gim__alloc_array(const gim_env *env, size_t count, size_t size) {
    return gim__alloc(env, gim__array_size(count, size));
}

static GIM__UNUSED int gim__isfinitef(float x) { return x == x && x - x == 0.0f; }
/* 1 when all n floats are finite. */
static GIM__UNUSED int gim__all_finite(const float *v, size_t n) {
    size_t i;
    for (i = 0; i < n; ++i) if (!gim__isfinitef(v[i])) return 0;
    return 1;
}

/* @impl math ============================================================================== */

GIMANY_DEF gim_vec3 gim_v3(float x, float y, float z) { gim_vec3 r; r.x = x; r.y = y; r.z = z; return r; }
GIMANY_DEF gim_vec3 gim_v3_add(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
GIMANY_DEF gim_vec3 gim_v3_sub(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
GIMANY_DEF gim_vec3 gim_v3_scale(gim_vec3 a, float s) { return gim_v3(a.x * s, a.y * s, a.z * s); }
GIMANY_DEF gim_vec3 gim_v3_mul(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
GIMANY_DEF float gim_v3_dot(gim_vec3 a, gim_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
GIMANY_DEF gim_vec3 gim_v3_cross(gim_vec3 a, gim_vec3 b) {
    return gim_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
GIMANY_DEF float gim_v3_length(gim_vec3 a) { return sqrtf(gim_v3_dot(a, a)); }
GIMANY_DEF gim_vec3 gim_v3_normalize(gim_vec3 a) {
    /* in double so tiny (1e-30) and huge (1e30) vectors still normalise */
    double l = sqrt((double)a.x * a.x + (double)a.y * a.y + (double)a.z * a.z);
    if (!(l > 0.0) || l > DBL_MAX) return gim_v3(0.0f, 0.0f, 0.0f);
    return gim_v3((float)(a.x / l), (float)(a.y / l), (float)(a.z / l));
}
GIMANY_DEF float gim_v3_luminance(gim_vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
GIMANY_DEF int gim_v3_isfinite(gim_vec3 a) { return gim__isfinitef(a.x) && gim__isfinitef(a.y) && gim__isfinitef(a.z); }
GIMANY_DEF void gim_basis(gim_vec3 n, gim_vec3 *t, gim_vec3 *b) {
    /* Duff et al. 2017, "Building an orthonormal basis, revisited": no branch on a threshold */
    float s = n.z >= 0.0f ? 1.0f : -1.0f;
    float a = -1.0f / (s + n.z);
    float c = n.x * n.y * a;
    *t = gim_v3(1.0f + s * n.x * n.x * a, s * c, -s * n.x);
    *b = gim_v3(c, s + n.y * n.y * a, -n.y);
}

GIMANY_DEF gim_mat4 gim_mat4_identity(void) {
    gim_mat4 r;
    int i;
    for (i = 0; i < 16; ++i) r.m[i] = (i % 5 == 0) ? 1.0f : 0.0f;
    return r;
}
GIMANY_DEF gim_mat4 gim_mat4_mul(gim_mat4 a, gim_mat4 b) {
    gim_mat4 r;
    int c, rr, k;
    for (c = 0; c < 4; ++c)
        for (rr = 0; rr < 4; ++rr) {
            float s = 0.0f;
            for (k = 0; k < 4; ++k) s += a.m[k * 4 + rr] * b.m[c * 4 + k];
            r.m[c * 4 + rr] = s;
        }
    return r;
}
GIMANY_DEF gim_vec4 gim_mat4_vec4(gim_mat4 m, gim_vec4 v) {
    gim_vec4 r;
    r.x = m.m[0] * v.x + m.m[4] * v.y + m.m[8] * v.z + m.m[12] * v.w;
    r.y = m.m[1] * v.x + m.m[5] * v.y + m.m[9] * v.z + m.m[13] * v.w;
    r.z = m.m[2] * v.x + m.m[6] * v.y + m.m[10] * v.z + m.m[14] * v.w;
    r.w = m.m[3] * v.x + m.m[7] * v.y + m.m[11] * v.z + m.m[15] * v.w;
    return r;
}
GIMANY_DEF gim_vec3 gim_mat4_point(gim_mat4 m, gim_vec3 p) {
    gim_vec4 v, r;
    v.x = p.x; v.y = p.y; v.z = p.z; v.w = 1.0f;
    r = gim_mat4_vec4(m, v);
    if (r.w != 1.0f && r.w != 0.0f) return gim_v3(r.x / r.w, r.y / r.w, r.z / r.w);
    return gim_v3(r.x, r.y, r.z);
}
GIMANY_DEF gim_vec3 gim_mat4_dir(gim_mat4 m, gim_vec3 d) {
    return gim_v3(m.m[0] * d.x + m.m[4] * d.y + m.m[8] * d.z,
                  m.m[1] * d.x + m.m[5] * d.y + m.m[9] * d.z,
                  m.m[2] * d.x + m.m[6] * d.y + m.m[10] * d.z);
}
GIMANY_DEF gim_mat4 gim_mat4_transpose(gim_mat4 m) {
    gim_mat4 r;
    int c, rr;
    for (c = 0; c < 4; ++c)
        for (rr = 0; rr < 4; ++rr) r.m[c * 4 + rr] = m.m[rr * 4 + c];
    return r;
}
GIMANY_DEF int gim_mat4_invert(gim_mat4 m, gim_mat4 *out) {
    /* cofactor expansion in double: matrices of open-world scenes mix 1e5 and 1e-3 terms */
    double a[16], inv[16], det;
    int i;
    for (i = 0; i < 16; ++i) a[i] = m.m[i];
    inv[0] = a[5] * a[10] * a[15] - a[5] * a[11] * a[14] - a[9] * a[6] * a[15] + a[9] * a[7] * a[14] + a[13] * a[6] * a[11] - a[13] * a[7] * a[10];
    inv[4] = -a[4] * a[10] * a[15] + a[4] * a[11] * a[14] + a[8] * a[6] * a[15] - a[8] * a[7] * a[14] - a[12] * a[6] * a[11] + a[12] * a[7] * a[10];
    inv[8] = a[4] * a[9] * a[15] - a[4] * a[11] * a[13] - a[8] * a[5] * a[15] + a[8] * a[7] * a[13] + a[12] * a[5] * a[11] - a[12] * a[7] * a[9];
    inv[12] = -a[4] * a[9] * a[14] + a[4] * a[10] * a[13] + a[8] * a[5] * a[14] - a[8] * a[6] * a[13] - a[12] * a[5] * a[10] + a[12] * a[6] * a[9];
    inv[1] = -a[1] * a[10] * a[15] + a[1] * a[11] * a[14] + a[9] * a[2] * a[15] - a[9] * a[3] * a[14] - a[13] * a[2] * a[11] + a[13] * a[3] * a[10];
    inv[5] = a[0] * a[10] * a[15] - a[0] * a[11] * a[14] - a[8] * a[2] * a[15] + a[8] * a[3] * a[14] + a[12] * a[2] * a[11] - a[12] * a[3] * a[10];
    inv[9] = -a[0] * a[9] * a[15] + a[0] * a[11] * a[13] + a[8] * a[1] * a[15] - a[8] * a[3] * a[13] - a[12] * a[1] * a[11] + a[12] * a[3] * a[9];
    inv[13] = a[0] * a[9] * a[14] - a[0] * a[10] * a[13] - a[8] * a[1] * a[14] + a[8] * a[2] * a[13] + a[12] * a[1] * a[10] - a[12] * a[2] * a[9];
    inv[2] = a[1] * a[6] * a[15] - a[1] * a[7] * a[14] - a[5] * a[2] * a[15] + a[5] * a[3] * a[14] + a[13] * a[2] * a[7] - a[13] * a[3] * a[6];
    inv[6] = -a[0] * a[6] * a[15] + a[0] * a[7] * a[14] + a[4] * a[2] * a[15] - a[4] * a[3] * a[14] - a[12] * a[2] * a[7] + a[12] * a[3] * a[6];
    inv[10] = a[0] * a[5] * a[15] - a[0] * a[7] * a[13] - a[4] * a[1] * a[15] + a[4] * a[3] * a[13] + a[12] * a[1] * a[7] - a[12] * a[3] * a[5];
    inv[14] = -a[0] * a[5] * a[14] + a[0] * a[6] * a[13] + a[4] * a[1] * a[14] - a[4] * a[2] * a[13] - a[12] * a[1] * a[6] + a[12] * a[2] * a[5];
    inv[3] = -a[1] * a[6] * a[11] + a[1] * a[7] * a[10] + a[5] * a[2] * a[11] - a[5] * a[3] * a[10] - a[9] * a[2] * a[7] + a[9] * a[3] * a[6];
    inv[7] = a[0] * a[6] * a[11] - a[0] * a[7] * a[10] - a[4] * a[2] * a[11] + a[4] * a[3] * a[10] + a[8] * a[2] * a[7] - a[8] * a[3] * a[6];
    inv[11] = -a[0] * a[5] * a[11] + a[0] * a[7] * a[9] + a[4] * a[1] * a[11] - a[4] * a[3] * a[9] - a[8] * a[1] * a[7] + a[8] * a[3] * a[5];
    inv[15] = a[0] * a[5] * a[10] - a[0] * a[6] * a[9] - a[4] * a[1] * a[10] + a[4] * a[2] * a[9] + a[8] * a[1] * a[6] - a[8] * a[2] * a[5];
    det = a[0] * inv[0] + a[1] * inv[4] + a[2] * inv[8] + a[3] * inv[12];
    if (det == 0.0 || det != det) return 0;
    for (i = 0; i < 16; ++i) {
        double v = inv[i] / det;
        if (!(v == v) || v > FLT_MAX || v < -FLT_MAX) return 0;
        out->m[i] = (float)v;
    }
    return 1;
}
GIMANY_DEF gim_mat4 gim_mat4_normal(gim_mat4 model) {
    gim_mat4 inv, r;
    if (!gim_mat4_invert(model, &inv)) return gim_mat4_identity();
    r = gim_mat4_transpose(inv);
    r.m[3] = r.m[7] = r.m[11] = 0.0f;
    r.m[12] = r.m[13] = r.m[14] = 0.0f;
    r.m[15] = 1.0f;
    return r;
}
GIMANY_DEF gim_mat4 gim_mat4_look_at(gim_vec3 eye, gim_vec3 target, gim_vec3 up) {
    gim_vec3 f = gim_v3_normalize(gim_v3_sub(target, eye));
    gim_vec3 s = gim_v3_normalize(gim_v3_cross(f, up));
    gim_vec3 u = gim_v3_cross(s, f);
    gim_mat4 r = gim_mat4_identity();
    r.m[0] = s.x; r.m[4] = s.y; r.m[8] = s.z;
    r.m[1] = u.x; r.m[5] = u.y; r.m[9] = u.z;
    r.m[2] = -f.x; r.m[6] = -f.y; r.m[10] = -f.z;
    r.m[12] = -gim_v3_dot(s, eye);
    r.m[13] = -gim_v3_dot(u, eye);
    r.m[14] = gim_v3_dot(f, eye);
    return r;
}
GIMANY_DEF gim_mat4 gim_mat4_perspective(float fovy_rad, float aspect, float znear, float zfar) {
    gim_mat4 r;
    float f = 1.0f / tanf(0.5f * fovy_rad);
    memset(&r, 0, sizeof r);
    r.m[0] = f / aspect;
    r.m[5] = f;
    r.m[10] = (zfar + znear) / (znear - zfar);
    r.m[11] = -1.0f;
    r.m[14] = 2.0f * zfar * znear / (znear - zfar);
    return r;
}
GIMANY_DEF gim_mat4 gim_mat4_ortho(float l, float r, float b, float t, float n, float f) {
    gim_mat4 m = gim_mat4_identity();
    m.m[0] = 2.0f / (r - l);
    m.m[5] = 2.0f / (t - b);
    m.m[10] = -2.0f / (f - n);
    m.m[12] = -(r + l) / (r - l);
    m.m[13] = -(t + b) / (t - b);
    m.m[14] = -(f + n) / (f - n);
    return m;
}
GIMANY_DEF int gim_mat4_isfinite(gim_mat4 m) { return gim__all_finite(m.m, 16); }

/* @impl samplers ========================================================================== */

static const uint16_t gim__primes[GIM_MAX_HALTON_DIMENSIONS] = {
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89,
    97, 101, 103, 107, 109, 113, 127, 131, 137, 139, 149, 151, 157, 163, 167, 173, 179, 181,
    191, 193, 197, 199, 211, 223, 227, 229, 233, 239, 241, 251, 257, 263, 269, 271, 277, 281,
    283, 293, 307, 311};

GIMANY_DEF uint32_t gim_prime(uint32_t dim) {
    return dim < GIM_MAX_HALTON_DIMENSIONS ? gim__primes[dim] : 0u;
}

GIMANY_DEF double gim_radical_inverse(uint32_t base, uint32_t index) {
    /* Reverse the digits into an integer numerator over base^digits. For base <= 65535 and
       index < 2^32 both stay below 2^53 (base^digits < base * 2^32 <= 2^48), so the one
       division is correctly rounded: exact, with no drift along the index. */
    uint64_t num = 0, den = 1;
    if (base < 2u || base > 65535u) return 0.0;
    while (index) {
        num = num * base + index % base;
        den *= base;
        index /= base;
    }
    return (double)num / (double)den;
}

GIMANY_DEF double gim_van_der_corput(uint32_t index) {
    /* bit reversal: exact */
    uint32_t b = index;
    b = (b << 16) | (b >> 16);
    b = ((b & 0x00ff00ffu) << 8) | ((b & 0xff00ff00u) >> 8);
    b = ((b & 0x0f0f0f0fu) << 4) | ((b & 0xf0f0f0f0u) >> 4);
    b = ((b & 0x33333333u) << 2) | ((b & 0xccccccccu) >> 2);
    b = ((b & 0x55555555u) << 1) | ((b & 0xaaaaaaaau) >> 1);
    return (double)b * (1.0 / 4294967296.0);
}

GIMANY_DEF double gim_halton(uint32_t index, uint32_t dim) {
    if (dim == 0) return gim_van_der_corput(index);
    return gim_radical_inverse(gim_prime(dim), index);
}

GIMANY_DEF double gim_hammersley(uint32_t index, uint32_t count, uint32_t dim) {
    if (dim == 0) return count ? (double)index / (double)count : 0.0;
    return gim_halton(index, dim - 1);
}

/* Round to float without reaching 1.0: a coordinate in [0,1) stays in [0,1). */
static float gim__to_unit_float(double u) {
    float f = (float)u;
    return f < 1.0f ? f : 0.99999994f; /* 1 - 2^-24, the largest float below 1 */
}

GIMANY_DEF float gim_rotate01(float u, float offset) {
    float r = u + offset;
    r -= floorf(r);
    return r < 1.0f ? r : 0.0f;
}

/* Arguments shared by the point generators; they have no env, so only the code reports. */
static gim_result gim__check_points(const float *out, uint32_t count, uint32_t dims, uint32_t max_dims,
                                    const float *offsets) {
    uint32_t d;
    if (!out || count == 0 || dims == 0 || dims > max_dims) return GIM_ERROR_INVALID_ARGUMENT;
    if (offsets)
        for (d = 0; d < dims; ++d)
            if (!(offsets[d] >= 0.0f && offsets[d] < 1.0f)) return GIM_ERROR_INVALID_ARGUMENT;
    return GIM_OK;
}

GIMANY_DEF gim_result gim_halton_points(float *out, uint32_t count, uint32_t dims, uint32_t start,
                                        const float *offsets) {
    uint32_t i, d;
    gim_result r = gim__check_points(out, count, dims, GIM_MAX_HALTON_DIMENSIONS, offsets);
    if (r != GIM_OK) return r;
    if ((uint64_t)start + count - 1u > 0xffffffffull) return GIM_ERROR_INVALID_ARGUMENT;
    for (i = 0; i < count; ++i)
        for (d = 0; d < dims; ++d) {
            float u = gim__to_unit_float(gim_halton(start + i, d));
            out[(size_t)i * dims + d] = offsets ? gim_rotate01(u, offsets[d]) : u;
        }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_hammersley_points(float *out, uint32_t count, uint32_t dims, const float *offsets) {
    uint32_t i, d;
    gim_result r = gim__check_points(out, count, dims, GIM_MAX_HALTON_DIMENSIONS + 1u, offsets);
    if (r != GIM_OK) return r;
    for (i = 0; i < count; ++i)
        for (d = 0; d < dims; ++d) {
            float u = gim__to_unit_float(gim_hammersley(i, count, d));
            out[(size_t)i * dims + d] = offsets ? gim_rotate01(u, offsets[d]) : u;
        }
    return GIM_OK;
}

/* 32-bit integer hash (Wellons' lowbias32): decorrelates frames without global state. */
static GIM__UNUSED uint32_t gim__hash32(uint32_t x) {
    x ^= x >> 16; x *= 0x7feb352du;
    x ^= x >> 15; x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

GIMANY_DEF void gim_rotation_offsets(float *out, uint32_t dims, uint32_t frame) {
    uint32_t d;
    if (!out) return;
    for (d = 0; d < dims; ++d) {
        uint32_t h = gim__hash32(frame * 0x9e3779b9u ^ gim__hash32(d + 0x632be5abu));
        out[d] = (float)(h >> 8) * (1.0f / 16777216.0f); /* 24 bits: exact in float, < 1 */
    }
}

GIMANY_DEF gim_vec2 gim_square_to_disk(float u, float v) {
    /* Shirley-Chiu concentric map, in Shirley's single-branch form */
    const double quarter_pi = 0.78539816339744830962;
    double a = 2.0 * u - 1.0, b = 2.0 * v - 1.0, r, phi;
    gim_vec2 p;
    if (a == 0.0 && b == 0.0) { p.x = 0.0f; p.y = 0.0f; return p; }
    if (a * a > b * b) { r = a; phi = quarter_pi * (b / a); }
    else { r = b; phi = 2.0 * quarter_pi - quarter_pi * (a / b); }
    p.x = (float)(r * cos(phi));
    p.y = (float)(r * sin(phi));
    return p;
}

GIMANY_DEF gim_vec3 gim_square_to_cosine_hemisphere(float u, float v) {
    gim_vec2 d = gim_square_to_disk(u, v);
    double z2 = 1.0 - (double)d.x * d.x - (double)d.y * d.y;
    return gim_v3(d.x, d.y, (float)sqrt(z2 > 0.0 ? z2 : 0.0));
}

/* @impl kmeans ============================================================================ */

/* @impl caches ============================================================================ */
/* generator: voxels, normal bins, averaging, snapping, merging, area partition */

/* The generator works in voxel units: lengths divided by the voxel edge h = d_eps/2 and
   measured from the minimum of the mesh bounds (in double), so nothing depends on where the
   mesh sits or on its unit of length; only the final positions and areas are scaled back. */

/* One piece of a used triangle clipped to one voxel. */
typedef struct gim__cg_frag {
    uint64_t key;       /* voxel: (ix * ny + iy) * nz + iz */
    double area;        /* double: a triangle may be 1e-30 of a voxel face and still count */
    float c[3];         /* centroid */
    float n[3];         /* unit surface normal at the centroid */
    float radius;       /* every point of the piece lies within radius of c */
    float rho;          /* reflection coefficient of its material */
    uint32_t tri;       /* the triangle it was cut from (snapping) */
} gim__cg_frag;

/* A cache while it is built; the bounds radius and spread keep the coverage guarantee
   through merging: every represented point lies within radius of p, every represented
   normal within spread (radians) of n. */
typedef struct gim__cg_cache {
    double p[3], n[3];
    double area, rho_area;
    double radius, spread;
    uint64_t key;
    uint32_t parent;    /* itself while alive; the cache that absorbed it after a merge */
} gim__cg_cache;

typedef struct gim__cg_pair { uint64_t key; uint32_t idx; } gim__cg_pair;

/* Generator state shared by the steps. */
typedef struct gim__cg {
    const gim_mesh_data *mesh;
    const gim_env *env;
    double origin[3];       /* minimum of the bounds of the finite triangles */
    double h, inv_h;        /* voxel edge d_eps/2 */
    uint64_t dim[3];        /* voxels per axis */
    double theta, cos_theta;
    double limit;           /* largest joint radius of a merged or snapped cache: d_eps (2 voxel
                               units) less the float rounding of the output positions */
    gim__cg_frag *frags;
    size_t frag_count, frag_cap;
    gim__cg_cache *caches;
    size_t cache_count, cache_cap;
} gim__cg;

static uint32_t gim__cg_index(const gim_mesh_data *m, size_t i) {
    if (m->index_type == GIM_INDEX_U16) return ((const uint16_t *)m->indices)[i];
    return ((const uint32_t *)m->indices)[i];
}
static const float *gim__cg_position(const gim_mesh_data *m, uint32_t v) {
    return (const float *)((const char *)m->positions + (size_t)v * (m->position_stride ? m->position_stride : 12u));
}
static const float *gim__cg_normal(const gim_mesh_data *m, uint32_t v) {
    return (const float *)((const char *)m->normals + (size_t)v * (m->normal_stride ? m->normal_stride : 12u));
}
/* A vertex in voxel units. */
static void gim__cg_vertex(const gim__cg *g, uint32_t v, double *out) {
    const float *p = gim__cg_position(g->mesh, v);
    int k;
    for (k = 0; k < 3; ++k) out[k] = ((double)p[k] - g->origin[k]) * g->inv_h;
}
static double gim__cg_dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void gim__cg_cross(const double *a, const double *b, double *r) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
static double gim__cg_dist(const double *a, const double *b) {
    double d[3];
    d[0] = a[0] - b[0]; d[1] = a[1] - b[1]; d[2] = a[2] - b[2];
    return sqrt(gim__cg_dot(d, d));
}
/* Normalise in place (scaled first: area-weighted sums of tiny pieces reach 1e-160); 0 when
   the vector has no direction. */
static int gim__cg_normalize(double *v) {
    double m = fabs(v[0]), l;
    if (fabs(v[1]) > m) m = fabs(v[1]);
    if (fabs(v[2]) > m) m = fabs(v[2]);
    if (!(m > 0.0) || m > DBL_MAX) return 0;
    v[0] /= m; v[1] /= m; v[2] /= m;
    l = sqrt(gim__cg_dot(v, v));
    v[0] /= l; v[1] /= l; v[2] /= l;
    return 1;
}
static double gim__cg_angle(const double *a, const double *b) {
    double d = gim__cg_dot(a, b);
    return acos(d > 1.0 ? 1.0 : (d < -1.0 ? -1.0 : d));
}

/* Grow an array by half (the env allocator has no realloc): the array to use from now on,
   or NULL (the old one still valid) when memory ran out. */
static void *gim__cg_grow(const gim_env *env, void *arr, size_t *cap, size_t need, size_t elem) {
    size_t ncap = *cap ? *cap : 1024u;
    void *n;
    if (need <= *cap) return arr;
    while (ncap < need) {
        if (ncap > ((size_t)-1 / 2u) / elem) return NULL;
        ncap += ncap / 2u;
    }
    n = gim__alloc_array(env, ncap, elem);
    if (!n) return NULL;
    if (arr) memcpy(n, arr, *cap * elem);
    gim__free(env, arr);
    *cap = ncap;
    return n;
}

/* Voxel coordinate of a voxel-unit coordinate along axis k, inside the grid. */
static uint64_t gim__cg_cell(const gim__cg *g, double q, int k) {
    double f = floor(q);
    if (!(f > 0.0)) return 0;
    if (f >= (double)(g->dim[k] - 1u)) return g->dim[k] - 1u;
    return (uint64_t)f;
}

/* Split a convex polygon (n points, xyz) by the plane x[axis] = plane into the part below
   and the part above; points on the plane go to both. At most n + 1 points each. */
#define GIM__CG_MAXPOLY 16
static void gim__cg_split(const double (*in)[3], int n, int axis, double plane,
                          double (*lo)[3], int *nlo, double (*hi)[3], int *nhi) {
    int i, a = 0, b = 0;
    for (i = 0; i < n; ++i) {
        const double *p = in[i], *q = in[(i + 1) % n];
        double dp = p[axis] - plane, dq = q[axis] - plane;
        if (dp <= 0.0 && a < GIM__CG_MAXPOLY) { memcpy(lo[a++], p, sizeof lo[0]); }
        if (dp >= 0.0 && b < GIM__CG_MAXPOLY) { memcpy(hi[b++], p, sizeof hi[0]); }
        if ((dp < 0.0 && dq > 0.0) || (dp > 0.0 && dq < 0.0)) {
            double t = dp / (dp - dq), x[3];
            int k;
            for (k = 0; k < 3; ++k) x[k] = p[k] + t * (q[k] - p[k]);
            x[axis] = plane; /* exactly on the voxel face */
            if (a < GIM__CG_MAXPOLY) memcpy(lo[a++], x, sizeof x);
            if (b < GIM__CG_MAXPOLY) memcpy(hi[b++], x, sizeof x);
        }
    }
    *nlo = a;
    *nhi = b;
}

/* Per-triangle data the clipper hands to each piece. */
typedef struct gim__cg_tri {
    double v[3][3];     /* vertices, voxel units */
    double face_n[3];   /* unit face normal */
    double area;        /* voxel units^2 */
    float rho;
    uint32_t tri;
    int smooth;         /* vertex normals usable */
    double vn[3][3];
} gim__cg_tri;

/* Emit one convex piece (already inside voxel ix, iy, iz). 0 on out of memory. */
static int gim__cg_emit(gim__cg *g, const gim__cg_tri *t, const double (*poly)[3], int n,
                        uint64_t ix, uint64_t iy, uint64_t iz) {
    double area = 0.0, c[3] = {0.0, 0.0, 0.0}, r = 0.0, nrm[3];
    gim__cg_frag *f;
    int i, k;
    if (n < 3) return 1;
    for (i = 1; i + 1 < n; ++i) {
        double e1[3], e2[3], cr[3], a;
        for (k = 0; k < 3; ++k) { e1[k] = poly[i][k] - poly[0][k]; e2[k] = poly[i + 1][k] - poly[0][k]; }
        gim__cg_cross(e1, e2, cr);
        a = 0.5 * sqrt(gim__cg_dot(cr, cr));
        area += a;
        for (k = 0; k < 3; ++k) c[k] += a * (poly[0][k] + poly[i][k] + poly[i + 1][k]) * (1.0 / 3.0);
    }
    /* slivers of rounding on a voxel face carry no surface */
    if (!(area > 1e-9 * t->area)) return 1;
    for (k = 0; k < 3; ++k) c[k] = (double)(float)(c[k] / area); /* the centroid as stored */
    for (i = 0; i < n; ++i) {
        double d = gim__cg_dist(poly[i], c);
        if (d > r) r = d;
    }
    memcpy(nrm, t->face_n, sizeof nrm);
    if (t->smooth) {
        /* vertex normals interpolated at the centroid (barycentric) */
        double e0[3], e1[3], e2[3], d00, d01, d11, d20, d21, den, bv, bw, bu, s[3];
        for (k = 0; k < 3; ++k) {
            e0[k] = t->v[1][k] - t->v[0][k]; e1[k] = t->v[2][k] - t->v[0][k]; e2[k] = c[k] - t->v[0][k];
        }
        d00 = gim__cg_dot(e0, e0); d01 = gim__cg_dot(e0, e1); d11 = gim__cg_dot(e1, e1);
        d20 = gim__cg_dot(e2, e0); d21 = gim__cg_dot(e2, e1);
        den = d00 * d11 - d01 * d01;
        if (den > 0.0) {
            bv = (d11 * d20 - d01 * d21) / den;
            bw = (d00 * d21 - d01 * d20) / den;
            bu = 1.0 - bv - bw;
            for (k = 0; k < 3; ++k) s[k] = bu * t->vn[0][k] + bv * t->vn[1][k] + bw * t->vn[2][k];
            if (gim__cg_normalize(s)) memcpy(nrm, s, sizeof nrm);
        }
    }
    if (g->frag_count >= 0xffffffffu) return 0;
    {
        void *grown = gim__cg_grow(g->env, g->frags, &g->frag_cap, g->frag_count + 1u, sizeof(gim__cg_frag));
        if (!grown) return 0;
        g->frags = (gim__cg_frag *)grown;
    }
    f = &g->frags[g->frag_count++];
    f->key = (ix * g->dim[1] + iy) * g->dim[2] + iz;
    for (k = 0; k < 3; ++k) { f->c[k] = (float)c[k]; f->n[k] = (float)nrm[k]; }
    f->area = area;
    f->radius = (float)(r * (1.0 + 1e-6)); /* rounded up: the bound survives float */
    f->rho = t->rho;
    f->tri = t->tri;
    return 1;
}

/* Step 1: clip a triangle into the voxels it passes through (slabs in x, then y, then z). */
static int gim__cg_clip(gim__cg *g, const gim__cg_tri *t) {
    double lo[3], hi[3];
    uint64_t c0[3], c1[3], ix, iy, iz;
    double slab[GIM__CG_MAXPOLY][3], restx[GIM__CG_MAXPOLY][3], row[GIM__CG_MAXPOLY][3];
    double resty[GIM__CG_MAXPOLY][3], cell[GIM__CG_MAXPOLY][3], restz[GIM__CG_MAXPOLY][3];
    double tmp[GIM__CG_MAXPOLY][3];
    int k, nx, ny, nz, nslab, nrow, ncell, ntmp;
    for (k = 0; k < 3; ++k) {
        lo[k] = hi[k] = t->v[0][k];
        if (t->v[1][k] < lo[k]) lo[k] = t->v[1][k];
        if (t->v[1][k] > hi[k]) hi[k] = t->v[1][k];
        if (t->v[2][k] < lo[k]) lo[k] = t->v[2][k];
        if (t->v[2][k] > hi[k]) hi[k] = t->v[2][k];
        c0[k] = gim__cg_cell(g, lo[k], k);
        c1[k] = gim__cg_cell(g, hi[k], k);
    }
    if (c0[0] == c1[0] && c0[1] == c1[1] && c0[2] == c1[2])
        return gim__cg_emit(g, t, (const double (*)[3])t->v, 3, c0[0], c0[1], c0[2]);
    memcpy(restx, t->v, sizeof t->v);
    nx = 3;
    for (ix = c0[0]; ix <= c1[0] && nx >= 3; ++ix) {
        if (ix < c1[0]) {
            gim__cg_split((const double (*)[3])restx, nx, 0, (double)(ix + 1u), slab, &nslab, tmp, &ntmp);
            memcpy(restx, tmp, sizeof tmp);
            nx = ntmp;
        } else {
            memcpy(slab, restx, sizeof restx);
            nslab = nx;
        }
        if (nslab < 3) continue;
        memcpy(resty, slab, sizeof slab);
        ny = nslab;
        for (iy = c0[1]; iy <= c1[1] && ny >= 3; ++iy) {
            if (iy < c1[1]) {
                gim__cg_split((const double (*)[3])resty, ny, 1, (double)(iy + 1u), row, &nrow, tmp, &ntmp);
                memcpy(resty, tmp, sizeof tmp);
                ny = ntmp;
            } else {
                memcpy(row, resty, sizeof resty);
                nrow = ny;
            }
            if (nrow < 3) continue;
            memcpy(restz, row, sizeof row);
            nz = nrow;
            for (iz = c0[2]; iz <= c1[2] && nz >= 3; ++iz) {
                if (iz < c1[2]) {
                    gim__cg_split((const double (*)[3])restz, nz, 2, (double)(iz + 1u), cell, &ncell, tmp, &ntmp);
                    memcpy(restz, tmp, sizeof tmp);
                    nz = ntmp;
                } else {
                    memcpy(cell, restz, sizeof restz);
                    ncell = nz;
                }
                if (!gim__cg_emit(g, t, (const double (*)[3])cell, ncell, ix, iy, iz)) return 0;
            }
        }
    }
    return 1;
}

/* Stable LSD radix sort of (key, index) pairs, 11 bits a pass over the bits keys use. */
static void gim__cg_radix(gim__cg_pair *a, gim__cg_pair *tmp, size_t n, uint64_t max_key) {
    size_t count[2048];
    gim__cg_pair *src = a, *dst = tmp, *t;
    int shift;
    for (shift = 0; shift < 64 && (shift == 0 || (max_key >> shift) != 0); shift += 11) {
        size_t i, sum = 0;
        memset(count, 0, sizeof count);
        for (i = 0; i < n; ++i) count[(src[i].key >> shift) & 2047u]++;
        for (i = 0; i < 2048; ++i) { size_t c = count[i]; count[i] = sum; sum += c; }
        for (i = 0; i < n; ++i) dst[count[(src[i].key >> shift) & 2047u]++] = src[i];
        t = src; src = dst; dst = t;
    }
    if (src != a) memcpy(a, src, n * sizeof *a);
}

/* Cube-map normal bin: face of the major axis, then a bins x bins grid on it. */
static uint32_t gim__cg_bin(const float *n, uint32_t bins) {
    float ax = fabsf(n[0]), ay = fabsf(n[1]), az = fabsf(n[2]), m, u, v;
    uint32_t face, iu, iv;
    if (ax >= ay && ax >= az) { face = n[0] >= 0.0f ? 0u : 1u; m = ax; u = n[1]; v = n[2]; }
    else if (ay >= az) { face = n[1] >= 0.0f ? 2u : 3u; m = ay; u = n[0]; v = n[2]; }
    else { face = n[2] >= 0.0f ? 4u : 5u; m = az; u = n[0]; v = n[1]; }
    if (!(m > 0.0f)) return 0;
    u = (u / m + 1.0f) * 0.5f * (float)bins;
    v = (v / m + 1.0f) * 0.5f * (float)bins;
    iu = u >= (float)bins ? bins - 1u : (u > 0.0f ? (uint32_t)u : 0u);
    iv = v >= (float)bins ? bins - 1u : (v > 0.0f ? (uint32_t)v : 0u);
    return (face * bins + iu) * bins + iv;
}

static double gim__cg_fdot(const float *n, const double *m) { return n[0] * m[0] + n[1] * m[1] + n[2] * m[2]; }

/* Steps 2-3 for one voxel (the k fragments listed in frag): normal bins, then repeatedly the bin
   of the largest surface, its normal refined to the mean of the surface within theta_eps
   (a few mean-shift steps, so every member stays within theta_eps of the cache normal), the
   cache at the area-weighted mean position, that surface removed. */
static int gim__cg_voxel(gim__cg *g, const gim__cg_pair *frag, size_t k, uint32_t bins, double *bin_area,
                         uint32_t *touched, uint32_t *rem, uint32_t *rem_bin, uint32_t *frag_cache) {
    size_t nrem = k, i;
    for (i = 0; i < k; ++i) {
        rem[i] = frag[i].idx;
        rem_bin[i] = gim__cg_bin(g->frags[frag[i].idx].n, bins);
    }
    while (nrem > 0) {
        size_t ntouched = 0, j, kept;
        uint32_t best = 0;
        double best_area = -1.0, m[3] = {0.0, 0.0, 0.0}, sum[3], p[3] = {0.0, 0.0, 0.0};
        double area = 0.0, rho_area = 0.0, radius = 0.0, min_dot = 1.0;
        int it, have = 0;
        gim__cg_cache *c;
        uint32_t cid;
        for (j = 0; j < nrem; ++j) {
            uint32_t b = rem_bin[j];
            if (bin_area[b] == 0.0) touched[ntouched++] = b;
            bin_area[b] += (double)g->frags[rem[j]].area + 1e-300; /* touched even at zero area */
        }
        for (j = 0; j < ntouched; ++j) {
            if (bin_area[touched[j]] > best_area) { best_area = bin_area[touched[j]]; best = touched[j]; }
        }
        for (j = 0; j < ntouched; ++j) bin_area[touched[j]] = 0.0;
        /* the bin's centre normal: the mean normal of its surface */
        for (j = 0; j < nrem; ++j)
            if (rem_bin[j] == best) {
                const gim__cg_frag *f = &g->frags[rem[j]];
                m[0] += (double)f->area * f->n[0]; m[1] += (double)f->area * f->n[1]; m[2] += (double)f->area * f->n[2];
            }
        have = gim__cg_normalize(m);
        for (it = 0; have && it < 4; ++it) {
            sum[0] = sum[1] = sum[2] = 0.0;
            for (j = 0; j < nrem; ++j) {
                const gim__cg_frag *f = &g->frags[rem[j]];
                if (gim__cg_fdot(f->n, m) >= g->cos_theta) {
                    sum[0] += (double)f->area * f->n[0]; sum[1] += (double)f->area * f->n[1]; sum[2] += (double)f->area * f->n[2];
                }
            }
            if (!gim__cg_normalize(sum)) break;
            if (sum[0] == m[0] && sum[1] == m[1] && sum[2] == m[2]) break;
            memcpy(m, sum, sizeof m);
        }
        /* the selection must hold the largest fragment's direction at least: fall back to it */
        {
            int any = 0;
            if (have)
                for (j = 0; j < nrem && !any; ++j) any = gim__cg_fdot(g->frags[rem[j]].n, m) >= g->cos_theta;
            if (!any) {
                size_t big = 0;
                for (j = 1; j < nrem; ++j) if (g->frags[rem[j]].area > g->frags[rem[big]].area) big = j;
                m[0] = g->frags[rem[big]].n[0]; m[1] = g->frags[rem[big]].n[1]; m[2] = g->frags[rem[big]].n[2];
                if (!gim__cg_normalize(m)) { m[0] = 0.0; m[1] = 0.0; m[2] = 1.0; }
                rem_bin[big] = 0xffffffffu; /* marks it as selected whatever the rounding */
            }
        }
        if (g->cache_count >= 0xfffffffeu) return 0;
        {
            void *grown = gim__cg_grow(g->env, g->caches, &g->cache_cap, g->cache_count + 1u, sizeof(gim__cg_cache));
            if (!grown) return 0;
            g->caches = (gim__cg_cache *)grown;
        }
        cid = (uint32_t)g->cache_count;
        for (j = 0; j < nrem; ++j) {
            const gim__cg_frag *f = &g->frags[rem[j]];
            double d = gim__cg_fdot(f->n, m);
            if (d >= g->cos_theta || rem_bin[j] == 0xffffffffu) {
                area += f->area;
                rho_area += (double)f->area * f->rho;
                p[0] += (double)f->area * f->c[0]; p[1] += (double)f->area * f->c[1]; p[2] += (double)f->area * f->c[2];
                if (d < min_dot) min_dot = d;
                frag_cache[rem[j]] = cid;
            }
        }
        if (area > 0.0) { p[0] /= area; p[1] /= area; p[2] /= area; }
        else { const gim__cg_frag *f = &g->frags[rem[0]]; p[0] = f->c[0]; p[1] = f->c[1]; p[2] = f->c[2]; }
        kept = 0;
        for (j = 0; j < nrem; ++j) {
            const gim__cg_frag *f = &g->frags[rem[j]];
            if (frag_cache[rem[j]] == cid) {
                double c3[3], d;
                c3[0] = f->c[0]; c3[1] = f->c[1]; c3[2] = f->c[2];
                d = gim__cg_dist(p, c3) + f->radius;
                if (d > radius) radius = d;
            } else {
                rem[kept] = rem[j];
                rem_bin[kept] = rem_bin[j];
                ++kept;
            }
        }
        nrem = kept;
        c = &g->caches[cid];
        g->cache_count++;
        memcpy(c->p, p, sizeof p);
        memcpy(c->n, m, sizeof m);
        c->area = area;
        c->rho_area = rho_area;
        c->radius = radius;
        c->spread = acos(min_dot > 1.0 ? 1.0 : (min_dot < -1.0 ? -1.0 : min_dot));
        c->key = frag[0].key;
        c->parent = cid;
    }
    return 1;
}

/* Step 5: join similar caches of neighbouring voxels. Similar: close (under half a voxel
   apart) or one of them small (under a quarter of a voxel face); joined only when the joint
   cache keeps every represented point within d_eps (g->limit) and every represented
   normal within theta_eps, so merging never breaks coverage, and opposite faces of a thin
   wall never join. Greedy in voxel order: deterministic. */
static void gim__cg_merge(gim__cg *g) {
    size_t i, n = g->cache_count;
    gim__cg_cache *cs = g->caches;
    for (i = 0; i < n; ++i) {
        gim__cg_cache *a = &cs[i];
        uint64_t v[3], key = a->key;
        int dx, dy, dz;
        if (a->parent != (uint32_t)i) continue;
        v[2] = key % g->dim[2];
        v[1] = (key / g->dim[2]) % g->dim[1];
        v[0] = key / g->dim[2] / g->dim[1];
        for (dx = -1; dx <= 1; ++dx)
            for (dy = -1; dy <= 1; ++dy)
                for (dz = -1; dz <= 1; ++dz) {
                    uint64_t nk;
                    size_t lo = 0, hi = n, j;
                    if ((dx < 0 && v[0] == 0) || (dx > 0 && v[0] + 1u >= g->dim[0])) continue;
                    if ((dy < 0 && v[1] == 0) || (dy > 0 && v[1] + 1u >= g->dim[1])) continue;
                    if ((dz < 0 && v[2] == 0) || (dz > 0 && v[2] + 1u >= g->dim[2])) continue;
                    nk = ((v[0] + (uint64_t)(int64_t)dx) * g->dim[1] + (v[1] + (uint64_t)(int64_t)dy)) * g->dim[2] +
                         (v[2] + (uint64_t)(int64_t)dz);
                    if (nk < key) continue; /* caches of earlier voxels had their turn */
                    while (lo < hi) { /* first cache of voxel nk */
                        size_t mid = lo + (hi - lo) / 2u;
                        if (cs[mid].key < nk) lo = mid + 1u; else hi = mid;
                    }
                    for (j = lo > i ? lo : i + 1u; j < n && cs[j].key == nk; ++j) {
                        gim__cg_cache *b = &cs[j];
                        double d, m[3], p[3], w, spread, radius;
                        int k;
                        if (b->parent != (uint32_t)j) continue;
                        d = gim__cg_dist(a->p, b->p);
                        if (!(d < 0.5 || (a->area < b->area ? a->area : b->area) < 0.25)) continue;
                        if (gim__cg_dot(a->n, b->n) <= 0.0) continue;
                        for (k = 0; k < 3; ++k) m[k] = a->area * a->n[k] + b->area * b->n[k];
                        if (!gim__cg_normalize(m)) continue;
                        spread = gim__cg_angle(m, a->n) + a->spread;
                        w = gim__cg_angle(m, b->n) + b->spread;
                        if (w > spread) spread = w;
                        if (spread > g->theta) continue;
                        w = a->area + b->area;
                        if (!(w > 0.0)) continue;
                        for (k = 0; k < 3; ++k) p[k] = (a->area * a->p[k] + b->area * b->p[k]) / w;
                        radius = gim__cg_dist(p, a->p) + a->radius;
                        w = gim__cg_dist(p, b->p) + b->radius;
                        if (w > radius) radius = w;
                        if (radius > g->limit) continue;
                        memcpy(a->p, p, sizeof p);
                        memcpy(a->n, m, sizeof m);
                        a->area += b->area;
                        a->rho_area += b->rho_area;
                        a->radius = radius;
                        a->spread = spread;
                        b->parent = (uint32_t)i;
                    }
                }
    }
}

/* Closest point on triangle abc to p (Ericson, Real-Time Collision Detection 5.1.5). */
static void gim__cg_closest(const double *p, const double *a, const double *b, const double *c, double *out) {
    double ab[3], ac[3], ap[3], bp[3], cp[3], d1, d2, d3, d4, d5, d6, va, vb, vc, v, w, den;
    int k;
    for (k = 0; k < 3; ++k) { ab[k] = b[k] - a[k]; ac[k] = c[k] - a[k]; ap[k] = p[k] - a[k]; }
    d1 = gim__cg_dot(ab, ap); d2 = gim__cg_dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) { memcpy(out, a, 3 * sizeof(double)); return; }
    for (k = 0; k < 3; ++k) bp[k] = p[k] - b[k];
    d3 = gim__cg_dot(ab, bp); d4 = gim__cg_dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) { memcpy(out, b, 3 * sizeof(double)); return; }
    vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        v = d1 / (d1 - d3);
        for (k = 0; k < 3; ++k) out[k] = a[k] + v * ab[k];
        return;
    }
    for (k = 0; k < 3; ++k) cp[k] = p[k] - c[k];
    d5 = gim__cg_dot(ab, cp); d6 = gim__cg_dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) { memcpy(out, c, 3 * sizeof(double)); return; }
    vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        w = d2 / (d2 - d6);
        for (k = 0; k < 3; ++k) out[k] = a[k] + w * ac[k];
        return;
    }
    va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (k = 0; k < 3; ++k) out[k] = b[k] + w * (c[k] - b[k]);
        return;
    }
    den = 1.0 / (va + vb + vc);
    v = vb * den;
    w = vc * den;
    for (k = 0; k < 3; ++k) out[k] = a[k] + ab[k] * v + ac[k] * w;
}

/* Step 4: a cache farther than a thousandth of a voxel from every triangle it represents
   floats (averaging a bent surface puts it inside the bend); move it to the nearest point
   of those triangles when every represented point stays within d_eps of it. */
static void gim__cg_snap(gim__cg *g, const uint32_t *order, const uint32_t *start, size_t count, uint32_t *snapped) {
    size_t c, j;
    *snapped = 0;
    for (c = 0; c < count; ++c) {
        gim__cg_cache *cc = &g->caches[c];
        double best[3], best_d = DBL_MAX, q[3];
        uint32_t last_tri = 0xffffffffu;
        int ok = 1;
        for (j = start[c]; j < start[c + 1]; ++j) {
            const gim__cg_frag *f = &g->frags[order[j]];
            double v[3][3], d;
            if (f->tri == last_tri) continue;
            last_tri = f->tri;
            gim__cg_vertex(g, gim__cg_index(g->mesh, (size_t)f->tri * 3u), v[0]);
            gim__cg_vertex(g, gim__cg_index(g->mesh, (size_t)f->tri * 3u + 1u), v[1]);
            gim__cg_vertex(g, gim__cg_index(g->mesh, (size_t)f->tri * 3u + 2u), v[2]);
            gim__cg_closest(cc->p, v[0], v[1], v[2], q);
            d = gim__cg_dist(q, cc->p);
            if (d < best_d) { best_d = d; memcpy(best, q, sizeof q); }
        }
        if (!(best_d > 1e-3) || best_d == DBL_MAX) continue;
        for (j = start[c]; j < start[c + 1] && ok; ++j) {
            const gim__cg_frag *f = &g->frags[order[j]];
            double fc[3];
            fc[0] = f->c[0]; fc[1] = f->c[1]; fc[2] = f->c[2];
            ok = gim__cg_dist(best, fc) + f->radius <= g->limit;
        }
        if (!ok) continue;
        memcpy(cc->p, best, sizeof best);
        ++*snapped;
    }
}

/* Duplicate test key: the triangle's positions rotated to start at the smallest vertex
   (same winding only: the reversed triangle is the other face of a zero-thickness wall). */
static void gim__cg_canonical(const gim_mesh_data *m, uint32_t t, float out[9]) {
    float p[3][3];
    int i, k, s = 0;
    for (i = 0; i < 3; ++i) {
        const float *v = gim__cg_position(m, gim__cg_index(m, (size_t)t * 3u + (size_t)i));
        for (k = 0; k < 3; ++k) p[i][k] = v[k] + 0.0f; /* -0 and +0 are one point */
    }
    for (i = 1; i < 3; ++i) {
        for (k = 0; k < 3 && p[i][k] == p[s][k]; ++k) {}
        if (k < 3 && p[i][k] < p[s][k]) s = i;
    }
    for (i = 0; i < 3; ++i)
        for (k = 0; k < 3; ++k) out[i * 3 + k] = p[(s + i) % 3][k];
}
static uint32_t gim__cg_hash9(const float v[9]) {
    uint32_t h = 0x811c9dc5u, b;
    int i;
    for (i = 0; i < 9; ++i) {
        memcpy(&b, &v[i], sizeof b);
        h = gim__hash32(h ^ b) + 0x9e3779b9u;
    }
    return h;
}

/* Triangle status during generation. */
enum { GIM__CG_USED = 0, GIM__CG_NONFINITE, GIM__CG_DEGENERATE, GIM__CG_DUPLICATE };

static gim_result gim__cg_check(const gim_cache_desc *d) {
    const gim_mesh_data *m = &d->mesh;
    const gim_env *env = &d->env;
    const char *fn = "gim_cache_generate";
    size_t t, tris, i;
    if (!m->positions || m->vertex_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no positions");
    if (!m->indices || m->index_count == 0 || m->index_count % 3u != 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "index_count must be a positive multiple of 3 (got %u)", m->index_count);
    if (m->index_type != GIM_INDEX_DEFAULT && m->index_type != GIM_INDEX_U32 && m->index_type != GIM_INDEX_U16)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "unknown index_type %d", (int)m->index_type);
    if ((m->position_stride && (m->position_stride < 12u || m->position_stride % 4u)) ||
        (m->normal_stride && (m->normal_stride < 12u || m->normal_stride % 4u)))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "strides must be 0 or a multiple of 4 of at least 12");
    if (!(d->d_eps >= 0.0f) || !gim__isfinitef(d->d_eps) || !(d->scene_scale >= 0.0f) || !gim__isfinitef(d->scene_scale))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "d_eps and scene_scale must be finite and >= 0 (0 = default)");
    if (!(d->theta_eps >= 0.0f && d->theta_eps <= 1.5707964f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "theta_eps must be in (0, pi/2] (0 = default)");
    tris = m->index_count / 3u;
    if (m->material_reflectance) {
        if (m->material_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "material_reflectance without material_count");
        for (i = 0; i < m->material_count; ++i)
            if (!(m->material_reflectance[i] >= 0.0f && m->material_reflectance[i] <= 1.0f))
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "material %u: reflectance must be in [0,1]", (unsigned)i);
        if (m->triangle_material)
            for (t = 0; t < tris; ++t)
                if (m->triangle_material[t] >= m->material_count)
                    return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "triangle %u: material %u out of range (%u materials)",
                                     (unsigned)t, m->triangle_material[t], m->material_count);
    }
    for (i = 0; i < m->index_count; ++i)
        if (gim__cg_index(m, i) >= m->vertex_count)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "index %u (triangle %u) is %u, past vertex_count %u",
                             (unsigned)i, (unsigned)(i / 3u), gim__cg_index(m, i), m->vertex_count);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_cache_generate(const gim_cache_desc *desc, gim_cache_set *out) {
    const char *fn = "gim_cache_generate";
    const gim_env *env;
    const gim_mesh_data *m;
    gim__cg g;
    gim_cache_report rep;
    gim_result res = GIM_OK;
    uint8_t *status = NULL;
    uint32_t *frag_cache = NULL, *rem = NULL, *rem_bin = NULL, *touched = NULL;
    uint32_t *order = NULL, *start = NULL, *remap = NULL;
    double *bin_area = NULL;
    gim__cg_pair *pairs = NULL, *ptmp = NULL;
    gim_cache *result = NULL;
    size_t tris, t, i, j, final_count = 0, max_run = 0;
    double lo[3], hi[3], scale, d_eps, ext[3], cells, area_total = 0.0, est = 0.0;
    uint32_t bins, snapped = 0;
    int k, any = 0;

    if (!desc || !out) return gim__fail(desc ? &desc->env : NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc and out must not be NULL");
    env = &desc->env;
    m = &desc->mesh;
    res = gim__cg_check(desc);
    if (res != GIM_OK) return res;
    memset(&g, 0, sizeof g);
    memset(&rep, 0, sizeof rep);
    g.mesh = m;
    g.env = env;
    tris = m->index_count / 3u;

    /* triangles with a NaN/Inf coordinate are skipped; the rest give the bounds */
    status = (uint8_t *)gim__alloc(env, tris);
    if (!status) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
    for (k = 0; k < 3; ++k) { lo[k] = DBL_MAX; hi[k] = -DBL_MAX; }
    for (t = 0; t < tris; ++t) {
        const float *p[3];
        int v;
        for (v = 0; v < 3; ++v) p[v] = gim__cg_position(m, gim__cg_index(m, t * 3u + (size_t)v));
        if (!gim__all_finite(p[0], 3) || !gim__all_finite(p[1], 3) || !gim__all_finite(p[2], 3)) {
            status[t] = GIM__CG_NONFINITE;
            rep.triangles_nonfinite++;
            continue;
        }
        status[t] = GIM__CG_USED;
        any = 1;
        for (v = 0; v < 3; ++v)
            for (k = 0; k < 3; ++k) {
                if (p[v][k] < lo[k]) lo[k] = p[v][k];
                if (p[v][k] > hi[k]) hi[k] = p[v][k];
            }
    }
    if (!any) for (k = 0; k < 3; ++k) lo[k] = hi[k] = 0.0;
    for (k = 0; k < 3; ++k) { g.origin[k] = lo[k]; ext[k] = hi[k] - lo[k]; }
    scale = desc->scene_scale > 0.0f ? (double)desc->scene_scale : sqrt(ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]);
    d_eps = desc->d_eps > 0.0f ? (double)desc->d_eps : scale / 32.0;
    g.theta = desc->theta_eps > 0.0f ? (double)desc->theta_eps : 30.0 * 3.14159265358979323846 / 180.0;
    g.cos_theta = cos(g.theta);
    if (!(d_eps > 0.0)) d_eps = 1.0; /* a mesh of one point: nothing has area anyway */
    if (!((float)d_eps > 0.0f) || !gim__isfinitef((float)d_eps)) {
        res = gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "d_eps %g is outside float range", d_eps);
        goto fail;
    }
    g.h = 0.5 * d_eps;
    g.inv_h = 1.0 / g.h;
    {
        double big = 0.0;
        for (k = 0; k < 3; ++k) {
            if (fabs(lo[k]) > big) big = fabs(lo[k]);
            if (fabs(hi[k]) > big) big = fabs(hi[k]);
        }
        g.limit = 2.0 - 2.0 * big * (double)FLT_EPSILON * g.inv_h - 1e-6;
        if (g.limit < 0.0) g.limit = 0.0;
    }
    cells = 1.0;
    for (k = 0; k < 3; ++k) {
        double nk = floor(ext[k] * g.inv_h) + 1.0;
        g.dim[k] = nk < 4e18 ? (uint64_t)nk : (uint64_t)4e18;
        cells *= nk;
    }
    if (!(cells < 4.0e18)) {
        res = gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "d_eps %g is too small for a mesh of extent %g: %.3g voxels",
                        d_eps, sqrt(ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]), cells);
        goto fail;
    }

    /* degenerate triangles; the rest hashed by their positions and sorted by hash (stable, so
       equal hashes keep triangle order and the first of a set of duplicates stays) */
    pairs = (gim__cg_pair *)gim__alloc_array(env, tris, sizeof *pairs);
    ptmp = (gim__cg_pair *)gim__alloc_array(env, tris, sizeof *ptmp);
    if (!pairs || !ptmp) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
    for (t = 0, j = 0; t < tris; ++t) {
        double v[3][3], e1[3], e2[3], e3[3], cr[3], l1, l2, l3, lmax;
        float key[9];
        if (status[t] != GIM__CG_USED) continue;
        for (k = 0; k < 3; ++k) gim__cg_vertex(&g, gim__cg_index(m, t * 3u + (size_t)k), v[k]);
        for (k = 0; k < 3; ++k) { e1[k] = v[1][k] - v[0][k]; e2[k] = v[2][k] - v[0][k]; e3[k] = v[2][k] - v[1][k]; }
        gim__cg_cross(e1, e2, cr);
        l1 = gim__cg_dot(e1, e1); l2 = gim__cg_dot(e2, e2); l3 = gim__cg_dot(e3, e3);
        lmax = l1 > l2 ? l1 : l2;
        if (l3 > lmax) lmax = l3;
        /* zero area, or thinner than float precision across its longest edge */
        if (!(sqrt(gim__cg_dot(cr, cr)) > 1e-7 * lmax)) { status[t] = GIM__CG_DEGENERATE; rep.triangles_degenerate++; continue; }
        gim__cg_canonical(m, (uint32_t)t, key);
        pairs[j].key = gim__cg_hash9(key);
        pairs[j].idx = (uint32_t)t;
        ++j;
    }
    gim__cg_radix(pairs, ptmp, j, 0xffffffffu);
    gim__free(env, ptmp);
    ptmp = NULL;
    for (i = 0; i < j;) { /* duplicates: same canonical positions within a run of one hash */
        size_t e = i + 1u, x, y;
        while (e < j && pairs[e].key == pairs[i].key) ++e;
        for (x = i + 1u; x < e; ++x) {
            float key[9], other[9];
            gim__cg_canonical(m, pairs[x].idx, key);
            for (y = i; y < x; ++y) {
                if (status[pairs[y].idx] != GIM__CG_USED) continue;
                gim__cg_canonical(m, pairs[y].idx, other);
                if (memcmp(key, other, sizeof key) == 0) { status[pairs[x].idx] = GIM__CG_DUPLICATE; break; }
            }
        }
        i = e;
    }
    gim__free(env, pairs);
    pairs = NULL;
    /* the used surface; an estimate of the voxel pieces guards the work */
    for (t = 0; t < tris; ++t) {
        double v[3][3], e1[3], e2[3], e3[3], cr[3], a2;
        if (status[t] == GIM__CG_DUPLICATE) rep.triangles_duplicate++;
        if (status[t] != GIM__CG_USED) continue;
        for (k = 0; k < 3; ++k) gim__cg_vertex(&g, gim__cg_index(m, t * 3u + (size_t)k), v[k]);
        for (k = 0; k < 3; ++k) { e1[k] = v[1][k] - v[0][k]; e2[k] = v[2][k] - v[0][k]; e3[k] = v[2][k] - v[1][k]; }
        gim__cg_cross(e1, e2, cr);
        a2 = sqrt(gim__cg_dot(cr, cr));
        rep.triangles_used++;
        area_total += 0.5 * a2;
        est += 0.5 * a2 * 3.0 + 2.0 * (sqrt(gim__cg_dot(e1, e1)) + sqrt(gim__cg_dot(e2, e2)) + sqrt(gim__cg_dot(e3, e3))) + 1.0;
    }
    rep.surface_area = area_total * g.h * g.h;
    if (est > 1.0e9) {
        res = gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "d_eps %g is too small for this mesh: about %.3g voxel pieces",
                        d_eps, est);
        goto fail;
    }

    /* step 1: voxelize (at least one piece per used triangle) */
    g.frag_cap = (size_t)rep.triangles_used + rep.triangles_used / 4u + 64u;
    g.frags = (gim__cg_frag *)gim__alloc_array(env, g.frag_cap, sizeof(gim__cg_frag));
    if (!g.frags) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
    for (t = 0; t < tris; ++t) {
        gim__cg_tri tri;
        double e1[3], e2[3];
        uint32_t idx[3];
        if (status[t] != GIM__CG_USED) continue;
        for (k = 0; k < 3; ++k) {
            idx[k] = gim__cg_index(m, t * 3u + (size_t)k);
            gim__cg_vertex(&g, idx[k], tri.v[k]);
        }
        for (k = 0; k < 3; ++k) { e1[k] = tri.v[1][k] - tri.v[0][k]; e2[k] = tri.v[2][k] - tri.v[0][k]; }
        gim__cg_cross(e1, e2, tri.face_n);
        tri.area = 0.5 * sqrt(gim__cg_dot(tri.face_n, tri.face_n));
        gim__cg_normalize(tri.face_n);
        tri.rho = 1.0f;
        if (m->material_reflectance) tri.rho = m->material_reflectance[m->triangle_material ? m->triangle_material[t] : 0u];
        tri.tri = (uint32_t)t;
        tri.smooth = 0;
        if (m->normals) {
            tri.smooth = 1;
            for (k = 0; k < 3 && tri.smooth; ++k) {
                const float *n = gim__cg_normal(m, idx[k]);
                tri.smooth = gim__all_finite(n, 3);
                tri.vn[k][0] = tri.smooth ? n[0] : 0.0; tri.vn[k][1] = tri.smooth ? n[1] : 0.0; tri.vn[k][2] = tri.smooth ? n[2] : 0.0;
                if (tri.smooth) tri.smooth = gim__cg_normalize(tri.vn[k]);
            }
        }
        if (!gim__cg_clip(&g, &tri)) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
    }
    gim__free(env, status);
    status = NULL;

    /* group the pieces by voxel: a stable radix sort of (key, piece) keeps triangle order
       within a voxel; the pieces stay where they are (a permutation costs more than it saves) */
    if (g.frag_count > 0) {
        size_t n = g.frag_count;
        pairs = (gim__cg_pair *)gim__alloc_array(env, n, sizeof *pairs);
        ptmp = (gim__cg_pair *)gim__alloc_array(env, n, sizeof *ptmp);
        if (!pairs || !ptmp) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
        for (i = 0; i < n; ++i) { pairs[i].key = g.frags[i].key; pairs[i].idx = (uint32_t)i; }
        gim__cg_radix(pairs, ptmp, n, g.dim[0] * g.dim[1] * g.dim[2] - 1u);
        gim__free(env, ptmp);
        ptmp = NULL;
    }

    /* steps 2-3: normal bins and averaging, voxel by voxel */
    bins = (uint32_t)ceil(3.14159265358979323846 / g.theta);
    if (bins < 2u) bins = 2u;
    if (bins > 64u) bins = 64u;
    for (i = 0; i < g.frag_count; i = j) {
        for (j = i + 1u; j < g.frag_count && pairs[j].key == pairs[i].key; ++j) {}
        if (j - i > max_run) max_run = j - i;
        rep.voxels++;
    }
    if (g.frag_count > 0) {
        bin_area = (double *)gim__alloc_array(env, (size_t)6u * bins * bins, sizeof(double));
        touched = (uint32_t *)gim__alloc_array(env, (size_t)6u * bins * bins, sizeof(uint32_t));
        rem = (uint32_t *)gim__alloc_array(env, max_run, sizeof(uint32_t));
        rem_bin = (uint32_t *)gim__alloc_array(env, max_run, sizeof(uint32_t));
        frag_cache = (uint32_t *)gim__alloc_array(env, g.frag_count, sizeof(uint32_t));
        if (!bin_area || !touched || !rem || !rem_bin || !frag_cache) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
        memset(frag_cache, 0xff, g.frag_count * sizeof(uint32_t)); /* no cache yet */
        for (i = 0; i < (size_t)6u * bins * bins; ++i) bin_area[i] = 0.0;
        for (i = 0; i < g.frag_count; i = j) {
            for (j = i + 1u; j < g.frag_count && pairs[j].key == pairs[i].key; ++j) {}
            if (!gim__cg_voxel(&g, pairs + i, j - i, bins, bin_area, touched, rem, rem_bin, frag_cache)) {
                res = GIM_ERROR_OUT_OF_MEMORY;
                goto fail;
            }
        }
        gim__free(env, bin_area); bin_area = NULL;
        gim__free(env, touched); touched = NULL;
        gim__free(env, rem); rem = NULL;
        gim__free(env, rem_bin); rem_bin = NULL;
        gim__free(env, pairs); pairs = NULL;
    }
    rep.caches_before_merge = (uint32_t)g.cache_count;

    /* step 5 (before snapping, so a snap sees everything its cache represents) */
    if (!desc->no_merge) gim__cg_merge(&g);

    /* compact the surviving caches and group the pieces by their final cache */
    if (g.cache_count > 0) {
        remap = (uint32_t *)gim__alloc_array(env, g.cache_count, sizeof(uint32_t));
        if (!remap) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
        for (i = 0; i < g.cache_count; ++i) {
            if (g.caches[i].parent == (uint32_t)i) {
                remap[i] = (uint32_t)final_count;
                g.caches[final_count] = g.caches[i];
                g.caches[final_count].parent = (uint32_t)final_count;
                final_count++;
            } else {
                uint32_t r = g.caches[i].parent;
                remap[i] = remap[r]; /* absorbers come earlier and are never absorbed later */
            }
        }
        g.cache_count = final_count;
        start = (uint32_t *)gim__alloc_array(env, final_count + 1u, sizeof(uint32_t));
        order = (uint32_t *)gim__alloc_array(env, g.frag_count, sizeof(uint32_t));
        if (!start || !order) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
        memset(start, 0, (final_count + 1u) * sizeof(uint32_t));
        for (i = 0; i < g.frag_count; ++i) { frag_cache[i] = remap[frag_cache[i]]; start[frag_cache[i] + 1u]++; }
        for (i = 0; i < final_count; ++i) start[i + 1u] += start[i];
        for (i = 0; i < g.frag_count; ++i) order[start[frag_cache[i]]++] = (uint32_t)i;
        for (i = final_count; i > 0; --i) start[i] = start[i - 1u];
        start[0] = 0;
        gim__free(env, remap); remap = NULL;
        /* step 4 */
        if (!desc->no_snap) gim__cg_snap(&g, order, start, final_count, &snapped);
        rep.caches_snapped = snapped;
    }

    /* the caches in the paper's layout, back in model units */
    if (final_count > 0) {
        result = (gim_cache *)gim__alloc_array(env, final_count, sizeof(gim_cache));
        if (!result) { res = GIM_ERROR_OUT_OF_MEMORY; goto fail; }
        for (i = 0; i < final_count; ++i) {
            const gim__cg_cache *c = &g.caches[i];
            gim_cache *o = &result[i];
            for (k = 0; k < 3; ++k) {
                o->position[k] = (float)(g.origin[k] + c->p[k] * g.h);
                o->normal[k] = (float)c->n[k];
            }
            o->area = (float)(c->area * g.h * g.h);
            o->reflectance = c->area > 0.0 ? (float)(c->rho_area / c->area) : 0.0f;
            if (o->reflectance > 1.0f) o->reflectance = 1.0f;
            if (!gim__all_finite(o->position, 3) || !gim__isfinitef(o->area)) {
                res = gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "cache %u does not fit in float (mesh area %g)",
                                (unsigned)i, rep.surface_area);
                goto fail;
            }
        }
    } else {
        gim__log(env, GIM_LOG_WARNING, fn, "no usable triangle (%u degenerate, %u non-finite, %u duplicate): no caches",
                 rep.triangles_degenerate, rep.triangles_nonfinite, rep.triangles_duplicate);
    }
    gim__free(env, start);
    gim__free(env, order);
    gim__free(env, frag_cache);
    gim__free(env, g.frags);
    gim__free(env, g.caches);
    memset(out, 0, sizeof *out);
    out->caches = result;
    out->count = (uint32_t)final_count;
    out->d_eps = (float)d_eps;
    out->theta_eps = (float)g.theta;
    out->report = rep;
    out->env = *env;
    return GIM_OK;

fail:
    if (res == GIM_ERROR_OUT_OF_MEMORY) gim__fail(env, res, fn, "allocation failed");
    gim__free(env, status);
    gim__free(env, pairs);
    gim__free(env, ptmp);
    gim__free(env, bin_area);
    gim__free(env, touched);
    gim__free(env, rem);
    gim__free(env, rem_bin);
    gim__free(env, frag_cache);
    gim__free(env, remap);
    gim__free(env, start);
    gim__free(env, order);
    gim__free(env, result);
    gim__free(env, g.frags);
    gim__free(env, g.caches);
    return res;
}

GIMANY_DEF void gim_cache_set_free(gim_cache_set *set) {
    if (!set) return;
    gim__free(&set->env, set->caches);
    memset(set, 0, sizeof *set);
}

/* neighbours: spatial grid, per-vertex nearest compatible caches */

/* blobs: versioned, checksummed serialisation */

/* @impl importance ======================================================================== */

/* @impl twins ============================================================================= */

#ifdef __cplusplus
}
#endif

/* @impl gl ================================================================================ */
#ifndef GIMANY_NO_GL
#endif /* GIMANY_NO_GL */

#endif /* GIMANY_IMPLEMENTATION_DONE */
#endif /* GIMANY_IMPLEMENTATION */

/*
MIT License

Copyright (c) 2026 the gimany.h authors

Permission is hereby granted, free of charge, to any person obtaining a copy of this software
and associated documentation files (the "Software"), to deal in the Software without
restriction, including without limitation the rights to use, copy, modify, merge, publish,
distribute, sublicense, and/or sell copies of the Software, and to permit persons to whom the
Software is furnished to do so, subject to the following conditions:

The above copyright notice and this permission notice shall be included in all copies or
substantial portions of the Software.

THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND, EXPRESS OR IMPLIED, INCLUDING
BUT NOT LIMITED TO THE WARRANTIES OF MERCHANTABILITY, FITNESS FOR A PARTICULAR PURPOSE AND
NONINFRINGEMENT. IN NO EVENT SHALL THE AUTHORS OR COPYRIGHT HOLDERS BE LIABLE FOR ANY CLAIM,
DAMAGES OR OTHER LIABILITY, WHETHER IN AN ACTION OF CONTRACT, TORT OR OTHERWISE, ARISING FROM,
OUT OF OR IN CONNECTION WITH THE SOFTWARE OR THE USE OR OTHER DEALINGS IN THE SOFTWARE.
*/
