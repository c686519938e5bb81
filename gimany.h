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
    uint32_t triangles_degenerate;   /* zero area or collinear */
    uint32_t triangles_nonfinite;    /* a NaN/Inf coordinate */
    uint32_t triangles_duplicate;    /* same three vertex positions as an earlier triangle */
    uint32_t voxels;                 /* occupied voxels */
    uint32_t caches_before_merge;
    uint32_t caches_snapped;         /* floating caches moved onto the nearest triangle */
    double surface_area;             /* of the used triangles */
} gim_cache_report;

/* Input of gim_cache_generate; zero means default. */
typedef struct gim_cache_desc {
    gim_mesh_data mesh;
    float d_eps;          /* max cache-to-surface distance; default scene_scale / 32 */
    float theta_eps;      /* max normal deviation in radians; default 30 degrees */
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

/* Generate caches for one mesh; out is written only on GIM_OK. */
GIMANY_API gim_result gim_cache_generate(const gim_cache_desc *desc, gim_cache_set *out);
/* Free what gim_cache_generate or gim_cache_blob_read allocated; NULL or zeroed is fine. */
GIMANY_API void gim_cache_set_free(gim_cache_set *set);

/* Largest neighbour count per vertex (eq. 8 interpolation). */
#define GIM_MAX_NEIGHBOUR_CACHES 16

/* Input of gim_cache_neighbours: for every vertex, the n nearest caches whose normal is within
   theta_eps (default: the set's) of the vertex normal, and d_c,max, the largest of their
   distances, for the weights of eq. 8.
   - compatible: n_v . n_c >= cos(theta_eps), both normalised (theta_eps = pi: every cache);
   - order: Euclidean distance, ties by cache index; the result is exactly the O(V x C) one;
   - fewer than n compatible caches anywhere: count < n, the rest of the row UINT32_MAX;
   - a vertex normal that is zero or not finite (or, with normals NULL, a vertex on no
     non-degenerate triangle): the n nearest caches of any normal; a vertex position that is
     not finite: count 0, d_cmax 0. Both are counted in one warning, neither is an error.
   The set's caches must have finite positions and non-zero finite normals. */
typedef struct gim_neighbour_desc {
    gim_mesh_data mesh;          /* positions and normals (normals NULL: area-weighted face normals) */
    const gim_cache_set *caches;
    uint32_t n;                  /* 1..GIM_MAX_NEIGHBOUR_CACHES, default 16 */
    float theta_eps;             /* (0, pi]; default: caches->theta_eps, or 30 degrees if that is 0 */
    gim_env env;
} gim_neighbour_desc;

/* Caller-owned output of gim_cache_neighbours, sized by the mesh's vertex count; all three
   required. Row v of index is index[v * n .. v * n + n - 1] (n after its default). */
typedef struct gim_neighbour_result {
    uint32_t *index;   /* vertex_count * n cache indices, nearest first; UINT32_MAX pads */
    uint32_t *count;   /* vertex_count: how many of the n were found (compatible caches may be fewer) */
    float *d_cmax;     /* vertex_count: distance of the farthest found cache (0 when none) */
} gim_neighbour_result;

/* Per-vertex neighbour caches through a spatial grid (not O(V x C)): cells sized from the
   caches' bounds and count, rings of cells grown until no unvisited cell can hold a nearer one. */
GIMANY_API gim_result gim_cache_neighbours(const gim_neighbour_desc *desc, gim_neighbour_result *out);

/* Versioned, checksummed byte blob of a cache set (little-endian, CRC-32; layout at @impl
   caches "blobs"), to precompute once: 92 + 32 * count bytes; 0 for NULL. */
GIMANY_API size_t gim_cache_blob_size(const gim_cache_set *set);
/* Write the blob into out (capacity bytes, at least gim_cache_blob_size). A set the reader
   would reject (NaN, negative area, non-unit normal, reflectance outside [0,1]) is refused. */
GIMANY_API gim_result gim_cache_blob_write(const gim_cache_set *set, void *out, size_t capacity);
/* Read a blob; a truncated, corrupt or foreign one is GIM_ERROR_CORRUPT_DATA. On GIM_OK out
   owns caches allocated through env (free with gim_cache_set_free); else out is untouched. */
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

/* neighbours: spatial grid, per-vertex nearest compatible caches */
/* Compatibility: cache c may light vertex v when n_v . n_c >= cos(theta_eps), both normals
   normalised, the dot product in double (eq. 8 weighs a cache by sqrt((n_x . n_c)^+), and a
   cache only stands for surface within theta_eps of its normal). A vertex whose normal is
   zero or not finite takes the nearest caches whatever their normal; a vertex whose position
   is not finite gets none (count 0); both are counted in one warning. Order: squared distance
   in double from the input floats, then cache index, so the grid answers exactly what the
   O(V x C) loop would. */

/* Direction bins: the 6 cube-map faces split 3 x 3, 54 bins, one bit each in a uint64_t. A
   cell keeps the bits of its caches and a vertex the bits that can hold compatible normals,
   so most incompatible caches (the far side of a thin wall) are skipped without a test. */
#define GIM__NB_BINS 54u      /* also the vertex "bin" of a zero normal: every bin a candidate */

static uint32_t gim__nb_bin(gim_vec3 d) {
    float ax = fabsf(d.x), ay = fabsf(d.y), az = fabsf(d.z), m, u, v, s;
    uint32_t face, iu, iv;
    if (ax >= ay && ax >= az) { face = 0; m = ax; s = d.x; u = d.y; v = d.z; }
    else if (ay >= az) { face = 2; m = ay; s = d.y; u = d.z; v = d.x; }
    else { face = 4; m = az; s = d.z; u = d.x; v = d.y; }
    if (s < 0.0f) face += 1;
    u = (u / m + 1.0f) * 1.5f;
    v = (v / m + 1.0f) * 1.5f;
    iu = u >= 2.0f ? 2u : (u >= 1.0f ? 1u : 0u);
    iv = v >= 2.0f ? 2u : (v >= 1.0f ? 1u : 0u);
    return face * 9u + iv * 3u + iu;
}

/* Direction of cube-face point (u, v) in [-1,1]^2 of a bin's face, in double. */
static void gim__nb_face_dir(uint32_t face, double u, double v, double *out) {
    double s = (face & 1u) ? -1.0 : 1.0, l;
    uint32_t a = face >> 1;
    out[a] = s;
    out[(a + 1u) % 3u] = u;
    out[(a + 2u) % 3u] = v;
    l = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    out[0] /= l; out[1] /= l; out[2] /= l;
}

static double gim__nb_angle(const double *a, const double *b) {
    double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c));
}

/* masks[b]: bins that may hold a normal within theta of a normal in bin b. By the triangle
   inequality on the sphere, bin j qualifies when angle(centre_b, centre_j) <= theta + r_b + r_j,
   r the largest angle from a bin's centre to its corners (the farthest point of a small convex
   spherical quad). masks[GIM__NB_BINS] is every bin. */
static void gim__nb_bin_masks(double theta, uint64_t *masks) {
    double centre[GIM__NB_BINS][3], radius[GIM__NB_BINS];
    uint32_t b, j, k;
    for (b = 0; b < GIM__NB_BINS; ++b) {
        uint32_t face = b / 9u, iu = b % 3u, iv = (b / 3u) % 3u;
        double u0 = -1.0 + iu * (2.0 / 3.0), v0 = -1.0 + iv * (2.0 / 3.0), corner[3];
        gim__nb_face_dir(face, u0 + 1.0 / 3.0, v0 + 1.0 / 3.0, centre[b]);
        radius[b] = 0.0;
        for (k = 0; k < 4u; ++k) {
            double a;
            gim__nb_face_dir(face, u0 + (k & 1u) * (2.0 / 3.0), v0 + (k >> 1) * (2.0 / 3.0), corner);
            a = gim__nb_angle(centre[b], corner);
            if (a > radius[b]) radius[b] = a;
        }
    }
    for (b = 0; b < GIM__NB_BINS; ++b) {
        masks[b] = 0;
        for (j = 0; j < GIM__NB_BINS; ++j)
            if (gim__nb_angle(centre[b], centre[j]) <= theta + radius[b] + radius[j] + 1e-6)
                masks[b] |= (uint64_t)1 << j;
    }
    masks[GIM__NB_BINS] = ((uint64_t)1 << GIM__NB_BINS) - 1u;
}

/* The three floats at base + i * stride, without alignment assumptions. */
static gim_vec3 gim__nb_load3(const float *base, uint32_t stride, uint32_t i) {
    float f[3];
    memcpy(f, (const unsigned char *)base + (size_t)i * stride, sizeof f);
    return gim_v3(f[0], f[1], f[2]);
}

static uint32_t gim__nb_index(const gim_mesh_data *m, uint32_t k) {
    if (m->index_type == GIM_INDEX_U16) {
        uint16_t s;
        memcpy(&s, (const unsigned char *)m->indices + (size_t)k * 2u, 2);
        return s;
    } else {
        uint32_t s;
        memcpy(&s, (const unsigned char *)m->indices + (size_t)k * 4u, 4);
        return s;
    }
}

/* Keep the n best (squared distance, index) pairs sorted ascending. */
static void gim__nb_insert(double *bd, uint32_t *bi, uint32_t *found, uint32_t n, double d2, uint32_t idx) {
    uint32_t k = *found;
    if (k == n) {
        if (d2 > bd[n - 1] || (d2 == bd[n - 1] && idx > bi[n - 1])) return;
        k = n - 1;
    } else {
        *found = k + 1;
    }
    while (k > 0 && (bd[k - 1] > d2 || (bd[k - 1] == d2 && bi[k - 1] > idx))) {
        bd[k] = bd[k - 1];
        bi[k] = bi[k - 1];
        --k;
    }
    bd[k] = d2;
    bi[k] = idx;
}

/* A cache as the search reads it: 32 bytes, one cache line holds two. */
typedef struct gim__nb_slot {
    float pos[3], nrm[3];        /* position, normalised normal */
    uint32_t id;                 /* index in the set */
    uint32_t bin;                /* direction bin of nrm */
} gim__nb_slot;

/* The uniform grid over the caches' bounds: cells of edge h, positions relative to the
   bounds' minimum (in double) so a scene far from the origin keeps its precision. */
typedef struct gim__nb_grid {
    double min[3], h;
    int64_t dim[3];
    uint32_t *cell_start;        /* ncells + 1 */
    uint64_t *cell_bins;         /* ncells: union of the caches' bin bits */
    gim__nb_slot *slot;          /* the caches sorted by cell, by index within a cell */
} gim__nb_grid;

/* Cell edge adapted to the cache density: prod_a max(ext_a / h, 1) = C / 2 (about two caches
   per cell over the bounds' volume, a plane's or a line's area or length when flat), solved by
   bisection in log h. Only ratios of the bounds enter: no absolute unit. */
static double gim__nb_cell_size(const double *ext, uint32_t count) {
    double emax = ext[0] > ext[1] ? ext[0] : ext[1], target = count > 2u ? count / 2.0 : 1.0, lo, hi;
    int it, a;
    if (ext[2] > emax) emax = ext[2];
    if (!(emax > 0.0)) return 1.0; /* every cache at one point: any h gives one cell */
    lo = emax / target; hi = emax;
    for (it = 0; it < 64; ++it) {
        double mid = sqrt(lo * hi), g = 1.0;
        for (a = 0; a < 3; ++a) g *= ext[a] / mid > 1.0 ? ext[a] / mid : 1.0;
        if (g > target) lo = mid; else hi = mid;
    }
    return hi;
}

/* Gap in cells between relative coordinate f and cell k along one axis, less 1e-6 cells for
   the rounding of f (so it never exceeds the true gap); 0 inside. */
static double gim__nb_gap(double f, int64_t k) {
    double gap = f < (double)k ? (double)k - f : (f > (double)(k + 1) ? f - (double)(k + 1) : 0.0);
    return gap > 1e-6 ? gap - 1e-6 : 0.0;
}

/* Cell coordinate along axis a of relative coordinate f, clamped to [lo, hi]. */
static int64_t gim__nb_cellc(double f, int64_t lo, int64_t hi) {
    if (!(f >= (double)lo)) return lo;
    if (f >= (double)hi) return hi;
    return (int64_t)floor(f);
}

static void gim__nb_grid_free(const gim_env *env, gim__nb_grid *g) {
    gim__free(env, g->cell_start); gim__free(env, g->cell_bins); gim__free(env, g->slot);
}

/* Build the grid; nrm holds the normalised cache normals. */
static gim_result gim__nb_grid_build(const gim_env *env, const gim_cache_set *set, const float *unit_nrm, gim__nb_grid *g) {
    static const char *where = "gim_cache_neighbours";
    double mx[3], ext[3];
    uint32_t c, C = set->count, *cellof = NULL;
    size_t ncells, k;
    int a;
    memset(g, 0, sizeof *g);
    for (a = 0; a < 3; ++a) { g->min[a] = set->caches[0].position[a]; mx[a] = g->min[a]; }
    for (c = 1; c < C; ++c)
        for (a = 0; a < 3; ++a) {
            double p = set->caches[c].position[a];
            if (p < g->min[a]) g->min[a] = p;
            if (p > mx[a]) mx[a] = p;
        }
    for (a = 0; a < 3; ++a) ext[a] = mx[a] - g->min[a];
    g->h = gim__nb_cell_size(ext, C);
    for (;;) { /* dims = floor(ext / h) + 1 holds the maximum; at most ~8x the target cells */
        double total = 1.0;
        for (a = 0; a < 3; ++a) {
            double d = floor(ext[a] / g->h) + 1.0;
            g->dim[a] = d < 4294967295.0 ? (int64_t)d : 4294967295;
            total *= (double)g->dim[a];
        }
        if (total <= 8.0 * C + 64.0) break;
        g->h *= 1.25;
    }
    if ((uint64_t)g->dim[0] * (uint64_t)g->dim[1] * (uint64_t)g->dim[2] >= 0xffffffffu)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, where, "%u caches need more grid cells than 32-bit offsets hold", C);
    ncells = (size_t)((uint64_t)g->dim[0] * (uint64_t)g->dim[1] * (uint64_t)g->dim[2]);
    g->cell_start = (uint32_t *)gim__alloc_array(env, ncells + 1u, sizeof(uint32_t));
    g->cell_bins = (uint64_t *)gim__alloc_array(env, ncells, sizeof(uint64_t));
    g->slot = (gim__nb_slot *)gim__alloc_array(env, C, sizeof(gim__nb_slot));
    cellof = (uint32_t *)gim__alloc_array(env, C, sizeof(uint32_t));
    if (!g->cell_start || !g->cell_bins || !g->slot || !cellof) {
        gim__free(env, cellof);
        gim__nb_grid_free(env, g);
        return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "grid of %u caches", C);
    }
    memset(g->cell_start, 0, (ncells + 1u) * sizeof(uint32_t));
    memset(g->cell_bins, 0, ncells * sizeof(uint64_t));
    for (c = 0; c < C; ++c) { /* counting sort by cell; stable, so a cell lists its caches by index */
        int64_t q[3];
        for (a = 0; a < 3; ++a)
            q[a] = gim__nb_cellc(((double)set->caches[c].position[a] - g->min[a]) / g->h, 0, g->dim[a] - 1);
        cellof[c] = (uint32_t)((q[2] * g->dim[1] + q[1]) * g->dim[0] + q[0]);
        g->cell_start[cellof[c] + 1u]++;
    }
    for (k = 0; k < ncells; ++k) g->cell_start[k + 1u] += g->cell_start[k];
    for (c = 0; c < C; ++c) {
        gim__nb_slot *sl = &g->slot[g->cell_start[cellof[c]]++];
        const float *n = unit_nrm + (size_t)c * 3u;
        memcpy(sl->pos, set->caches[c].position, 3u * sizeof(float));
        memcpy(sl->nrm, n, 3u * sizeof(float));
        sl->id = c;
        sl->bin = gim__nb_bin(gim_v3(n[0], n[1], n[2]));
        g->cell_bins[cellof[c]] |= (uint64_t)1 << sl->bin;
    }
    for (k = ncells; k > 0; --k) g->cell_start[k] = g->cell_start[k - 1u];
    g->cell_start[0] = 0;
    gim__free(env, cellof);
    return GIM_OK;
}

/* Per-vertex normals: the given ones normalised, or the area-weighted sum of the adjacent
   triangles' normals (cross products of the edges, in double). Zero where undefined. */
static gim_result gim__nb_vertex_normals(const gim_mesh_data *m, const gim_env *env, float *out) {
    uint32_t v, t, pstride = m->position_stride ? m->position_stride : 12u;
    if (m->normals) {
        uint32_t nstride = m->normal_stride ? m->normal_stride : 12u;
        for (v = 0; v < m->vertex_count; ++v) {
            gim_vec3 n = gim_v3_normalize(gim__nb_load3(m->normals, nstride, v));
            out[(size_t)v * 3u] = n.x; out[(size_t)v * 3u + 1u] = n.y; out[(size_t)v * 3u + 2u] = n.z;
        }
        return GIM_OK;
    } else {
        double *acc = (double *)gim__alloc_array(env, m->vertex_count, 3u * sizeof(double));
        if (!acc) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, "gim_cache_neighbours", "face normals of %u vertices", m->vertex_count);
        memset(acc, 0, (size_t)m->vertex_count * 3u * sizeof(double));
        for (t = 0; t + 3u <= m->index_count; t += 3u) {
            uint32_t i[3], k;
            gim_vec3 p[3];
            double e1[3], e2[3], c[3];
            for (k = 0; k < 3u; ++k) { i[k] = gim__nb_index(m, t + k); p[k] = gim__nb_load3(m->positions, pstride, i[k]); }
            if (!gim_v3_isfinite(p[0]) || !gim_v3_isfinite(p[1]) || !gim_v3_isfinite(p[2])) continue;
            e1[0] = (double)p[1].x - p[0].x; e1[1] = (double)p[1].y - p[0].y; e1[2] = (double)p[1].z - p[0].z;
            e2[0] = (double)p[2].x - p[0].x; e2[1] = (double)p[2].y - p[0].y; e2[2] = (double)p[2].z - p[0].z;
            c[0] = e1[1] * e2[2] - e1[2] * e2[1];
            c[1] = e1[2] * e2[0] - e1[0] * e2[2];
            c[2] = e1[0] * e2[1] - e1[1] * e2[0];
            for (k = 0; k < 3u; ++k) {
                acc[(size_t)i[k] * 3u] += c[0]; acc[(size_t)i[k] * 3u + 1u] += c[1]; acc[(size_t)i[k] * 3u + 2u] += c[2];
            }
        }
        for (v = 0; v < m->vertex_count; ++v) {
            double *a = acc + (size_t)v * 3u, s = fabs(a[0]), l;
            if (fabs(a[1]) > s) s = fabs(a[1]);
            if (fabs(a[2]) > s) s = fabs(a[2]);
            out[(size_t)v * 3u] = out[(size_t)v * 3u + 1u] = out[(size_t)v * 3u + 2u] = 0.0f;
            if (!(s > 0.0) || s > DBL_MAX) continue;
            l = sqrt((a[0] / s) * (a[0] / s) + (a[1] / s) * (a[1] / s) + (a[2] / s) * (a[2] / s));
            out[(size_t)v * 3u] = (float)(a[0] / s / l);
            out[(size_t)v * 3u + 1u] = (float)(a[1] / s / l);
            out[(size_t)v * 3u + 2u] = (float)(a[2] / s / l);
        }
        gim__free(env, acc);
        return GIM_OK;
    }
}

GIMANY_DEF gim_result gim_cache_neighbours(const gim_neighbour_desc *desc, gim_neighbour_result *out) {
    static const char *where = "gim_cache_neighbours";
    const gim_env *env;
    const gim_mesh_data *m;
    const gim_cache_set *set;
    uint32_t n, v, c, pstride, nstride, no_normal = 0, no_position = 0;
    uint64_t masks[GIM__NB_BINS + 1u];
    uint32_t cand_total[GIM__NB_BINS + 1u], bin_count[GIM__NB_BINS];
    double theta, cos_theta;
    float *vn = NULL, *cn = NULL;
    gim__nb_grid g;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    m = &desc->mesh;
    set = desc->caches;
    if (!out || !out->index || !out->count || !out->d_cmax)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "result or one of its arrays (index, count, d_cmax) is NULL");
    n = desc->n ? desc->n : GIM_MAX_NEIGHBOUR_CACHES;
    if (n > GIM_MAX_NEIGHBOUR_CACHES)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "n = %u, not in 1..%d", n, GIM_MAX_NEIGHBOUR_CACHES);
    if (!set || !set->caches || set->count == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "no caches");
    if (!m->positions || m->vertex_count == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "no vertex positions");
    pstride = m->position_stride ? m->position_stride : 12u;
    nstride = m->normal_stride ? m->normal_stride : 12u;
    if (pstride < 12u || nstride < 12u)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "stride below 12 bytes");
    if (!m->normals) {
        uint32_t k;
        if (!m->indices || m->index_count == 0 || m->index_count % 3u)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "no normals and no whole triangles to take face normals from");
        if (m->index_type != GIM_INDEX_DEFAULT && m->index_type != GIM_INDEX_U32 && m->index_type != GIM_INDEX_U16)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown index type %d", (int)m->index_type);
        for (k = 0; k < m->index_count; ++k)
            if (gim__nb_index(m, k) >= m->vertex_count)
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "index %u (at %u) >= vertex count %u",
                                 gim__nb_index(m, k), k, m->vertex_count);
    }
    /* theta_eps: the desc's, else the set's, else the generator's default of 30 degrees */
    theta = desc->theta_eps != 0.0f ? desc->theta_eps : (set->theta_eps != 0.0f ? set->theta_eps : 0.52359877559829887);
    if (!(theta > 0.0 && theta <= (double)3.14159265358979324f)) /* pi rounded to float is a little above pi */
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "theta_eps %g not in (0, pi]", theta);
    /* theta_eps = pi (float pi is slightly above) admits every normal, opposite ones included */
    cos_theta = theta >= 3.14159265358979 ? -2.0 : cos(theta);
    /* the caches: finite positions, normals that normalise */
    cn = (float *)gim__alloc_array(env, set->count, 3u * sizeof(float));
    if (!cn) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "normals of %u caches", set->count);
    for (c = 0; c < set->count; ++c) {
        const gim_cache *k = &set->caches[c];
        gim_vec3 nn = gim_v3_normalize(gim_v3(k->normal[0], k->normal[1], k->normal[2]));
        if (!gim__all_finite(k->position, 3) || !gim__all_finite(k->normal, 3) || (nn.x == 0.0f && nn.y == 0.0f && nn.z == 0.0f)) {
            gim__free(env, cn);
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "cache %u has a non-finite position or an unusable normal", c);
        }
        cn[(size_t)c * 3u] = nn.x; cn[(size_t)c * 3u + 1u] = nn.y; cn[(size_t)c * 3u + 2u] = nn.z;
    }
    vn = (float *)gim__alloc_array(env, m->vertex_count, 3u * sizeof(float));
    if (!vn) { gim__free(env, cn); return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "normals of %u vertices", m->vertex_count); }
    r = gim__nb_vertex_normals(m, env, vn);
    if (r == GIM_OK) r = gim__nb_grid_build(env, set, cn, &g);
    gim__free(env, cn);
    if (r != GIM_OK) { gim__free(env, vn); return r; }

    gim__nb_bin_masks(theta, masks);
    memset(bin_count, 0, sizeof bin_count);
    for (c = 0; c < set->count; ++c) bin_count[g.slot[c].bin]++;
    for (v = 0; v <= GIM__NB_BINS; ++v) { /* how many caches a vertex of bin v may have to look at */
        uint32_t j;
        cand_total[v] = 0;
        for (j = 0; j < GIM__NB_BINS; ++j)
            if ((masks[v] >> j) & 1u) cand_total[v] += bin_count[j];
    }

    for (v = 0; v < m->vertex_count; ++v) {
        double bd[GIM_MAX_NEIGHBOUR_CACHES], fx[3], pd[3];
        uint32_t bi[GIM_MAX_NEIGHBOUR_CACHES], found = 0, seen = 0, vb, total, k;
        uint64_t vmask;
        int64_t q[3], r0 = 0, rr;
        gim_vec3 p = gim__nb_load3(m->positions, pstride, v), nv;
        int a, any_normal;
        uint32_t *oi = out->index + (size_t)v * n;
        if (!gim_v3_isfinite(p)) {
            ++no_position;
            for (k = 0; k < n; ++k) oi[k] = UINT32_MAX;
            out->count[v] = 0;
            out->d_cmax[v] = 0.0f;
            continue;
        }
        nv = gim_v3(vn[(size_t)v * 3u], vn[(size_t)v * 3u + 1u], vn[(size_t)v * 3u + 2u]);
        any_normal = nv.x == 0.0f && nv.y == 0.0f && nv.z == 0.0f;
        if (any_normal) ++no_normal;
        vb = any_normal ? GIM__NB_BINS : gim__nb_bin(nv);
        vmask = masks[vb];
        total = cand_total[vb];
        pd[0] = p.x; pd[1] = p.y; pd[2] = p.z;
        for (a = 0; a < 3; ++a) {
            fx[a] = (pd[a] - g.min[a]) / g.h;
            q[a] = gim__nb_cellc(fx[a], -1, g.dim[a]);
            /* rings nearer than the grid are empty: start at the Chebyshev distance to it */
            if (q[a] < 0 && -q[a] > r0) r0 = -q[a];
            if (q[a] >= g.dim[a] && q[a] - g.dim[a] + 1 > r0) r0 = q[a] - g.dim[a] + 1;
        }
        for (rr = r0; total > 0; ++rr) {
            int64_t z0 = q[2] - rr > 0 ? q[2] - rr : 0, z1 = q[2] + rr < g.dim[2] - 1 ? q[2] + rr : g.dim[2] - 1;
            int64_t y0 = q[1] - rr > 0 ? q[1] - rr : 0, y1 = q[1] + rr < g.dim[1] - 1 ? q[1] + rr : g.dim[1] - 1;
            int64_t z, y, lb_cells = -1;
            double lb = -1.0;
            for (z = z0; z <= z1; ++z)
                for (y = y0; y <= y1; ++y) {
                    int shell = (z == q[2] - rr || z == q[2] + rr || y == q[1] - rr || y == q[1] + rr);
                    double gz = gim__nb_gap(fx[2], z), gy = gim__nb_gap(fx[1], y), gzy = gz * gz + gy * gy;
                    /* on the ring's shell every x of the row, inside it only its two ends */
                    int64_t x, xa = q[0] - rr, xb = q[0] + rr, step = rr > 0 ? 2 * rr : 1;
                    if (shell) { xa = xa > 0 ? xa : 0; xb = xb < g.dim[0] - 1 ? xb : g.dim[0] - 1; step = 1; }
                    for (x = xa; x <= xb; x += step) {
                        size_t cell;
                        uint32_t s, s1;
                        if (x < 0 || x >= g.dim[0]) continue;
                        cell = (size_t)((z * g.dim[1] + y) * g.dim[0] + x);
                        if (!(g.cell_bins[cell] & vmask)) continue;
                        s1 = g.cell_start[cell + 1u];
                        if (found == n) { /* a cell wholly beyond the n-th best cannot improve it (seen
                                             only matters while fewer than n are found) */
                            double gx = gim__nb_gap(fx[0], x);
                            if ((gzy + gx * gx) * g.h * g.h > bd[n - 1]) continue;
                        }
                        for (s = g.cell_start[cell]; s < s1; ++s) {
                            const gim__nb_slot *sl = &g.slot[s];
                            double dx, dy, dz, d2;
                            if (!((vmask >> sl->bin) & 1u)) continue;
                            ++seen;
                            dx = pd[0] - sl->pos[0]; dy = pd[1] - sl->pos[1]; dz = pd[2] - sl->pos[2];
                            d2 = dx * dx + dy * dy + dz * dz;
                            if (found == n && d2 > bd[n - 1]) continue;
                            if (!any_normal && (double)nv.x * sl->nrm[0] + (double)nv.y * sl->nrm[1] + (double)nv.z * sl->nrm[2] < cos_theta) continue;
                            gim__nb_insert(bd, bi, &found, n, d2, sl->id);
                        }
                    }
                }
            if (seen == total) break; /* every candidate cache has been looked at */
            /* lower bound (in cells) on the distance to any cell outside the visited box */
            for (a = 0; a < 3; ++a) {
                if (q[a] - rr > 0) { double gap = fx[a] - (double)(q[a] - rr); if (lb < 0.0 || gap < lb) lb = gap; lb_cells = 1; }
                if (q[a] + rr < g.dim[a] - 1) { double gap = (double)(q[a] + rr + 1) - fx[a]; if (lb < 0.0 || gap < lb) lb = gap; lb_cells = 1; }
            }
            if (lb_cells < 0) break; /* the whole grid is visited */
            /* 1e-6 cells absorbs the rounding of fx; stop only when no unvisited cache can be nearer or tie */
            lb -= 1e-6;
            if (found == n && lb > 0.0 && bd[n - 1] < (lb * g.h) * (lb * g.h)) break;
        }
        for (k = 0; k < found; ++k) oi[k] = bi[k];
        for (; k < n; ++k) oi[k] = UINT32_MAX;
        out->count[v] = found;
        out->d_cmax[v] = found ? (float)sqrt(bd[found - 1]) : 0.0f;
    }
    if (no_normal || no_position)
        gim__log(env, GIM_LOG_WARNING, where, "%u vertices without a usable normal took the nearest caches of any normal; "
                 "%u vertices with a non-finite position got none", no_normal, no_position);
    gim__nb_grid_free(env, &g);
    gim__free(env, vn);
    return GIM_OK;
}

/* blobs: versioned, checksummed serialisation */
/* Layout, version 1, every field little-endian, floats as their IEEE-754 bits:
     offset  size  field
          0     8  magic "GIMCACHE"
          8     4  version (1)
         12     4  header size (88)
         16     4  record size (32)
         20     4  count
         24     8  payload size (count * 32)
         32     4  d_eps (f32)          36  4  theta_eps (f32)
         40    28  report: triangles_used, _degenerate, _nonfinite, _duplicate, voxels,
                   caches_before_merge, caches_snapped (u32 each)
         68     4  reserved (0)
         72     8  report.surface_area (f64)
         80     8  reserved (0)
         88  32 * count  caches: position xyz, area, normal xyz, reflectance (f32 each)
    88 + payload  4  CRC-32 (IEEE 802.3, as zlib's crc32) of every byte before it
   Bytes are packed one by one: no struct is dumped, nothing assumes alignment or host order. */
#define GIM__BLOB_VERSION 1u
#define GIM__BLOB_HEADER 88u
#define GIM__BLOB_RECORD 32u
#define GIM__BLOB_TAIL 4u

static void gim__put32(unsigned char *p, uint32_t v) {
    p[0] = (unsigned char)v; p[1] = (unsigned char)(v >> 8); p[2] = (unsigned char)(v >> 16); p[3] = (unsigned char)(v >> 24);
}
static void gim__put64(unsigned char *p, uint64_t v) { gim__put32(p, (uint32_t)v); gim__put32(p + 4, (uint32_t)(v >> 32)); }
static uint32_t gim__get32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint64_t gim__get64(const unsigned char *p) { return (uint64_t)gim__get32(p) | (uint64_t)gim__get32(p + 4) << 32; }
static void gim__putf(unsigned char *p, float f) { uint32_t u; memcpy(&u, &f, 4); gim__put32(p, u); }
static float gim__getf(const unsigned char *p) { uint32_t u = gim__get32(p); float f; memcpy(&f, &u, 4); return f; }

/* CRC-32, reflected polynomial 0xEDB88320: detects every error burst up to 32 bits, so every
   single-byte corruption. The table lives on the stack (no global state). */
static GIM__UNUSED uint32_t gim__crc32(const unsigned char *p, size_t size) {
    uint32_t table[256], crc = 0xffffffffu, k, b;
    size_t i;
    for (k = 0; k < 256u; ++k) {
        uint32_t c = k;
        for (b = 0; b < 8u; ++b) c = (c & 1u) ? 0xedb88320u ^ (c >> 1) : c >> 1;
        table[k] = c;
    }
    for (i = 0; i < size; ++i) crc = table[(crc ^ p[i]) & 0xffu] ^ (crc >> 8);
    return crc ^ 0xffffffffu;
}

/* What a stored set may hold; the writer refuses what the reader would reject. NULL: valid. */
static const char *gim__blob_check_set(float d_eps, float theta_eps, double surface_area) {
    if (!(gim__isfinitef(d_eps) && d_eps >= 0.0f)) return "d_eps is negative or not finite";
    if (!(gim__isfinitef(theta_eps) && theta_eps >= 0.0f && theta_eps <= 3.14159265358979324f)) return "theta_eps is not in [0, pi]";
    if (!(surface_area >= 0.0 && surface_area <= DBL_MAX)) return "surface area is negative or not finite";
    return NULL;
}
static const char *gim__blob_check_cache(const gim_cache *c) {
    double l2;
    if (!gim__all_finite(c->position, 3)) return "position not finite";
    if (!(gim__isfinitef(c->area) && c->area >= 0.0f)) return "area negative or not finite";
    if (!gim__all_finite(c->normal, 3)) return "normal not finite";
    l2 = (double)c->normal[0] * c->normal[0] + (double)c->normal[1] * c->normal[1] + (double)c->normal[2] * c->normal[2];
    if (!(fabs(sqrt(l2) - 1.0) <= 1e-3)) return "normal not of unit length";
    if (!(c->reflectance >= 0.0f && c->reflectance <= 1.0f)) return "reflectance not in [0, 1]";
    return NULL;
}

/* Free a set's caches with its own allocator and zero it (gim_cache_set_free's body). */
static GIM__UNUSED void gim__cache_set_release(gim_cache_set *set) {
    gim_env env;
    if (!set) return;
    env = set->env;
    gim__free(&env, set->caches);
    memset(set, 0, sizeof *set);
}

GIMANY_DEF size_t gim_cache_blob_size(const gim_cache_set *set) {
    uint64_t total;
    if (!set) return 0;
    total = GIM__BLOB_HEADER + (uint64_t)set->count * GIM__BLOB_RECORD + GIM__BLOB_TAIL;
    if (total > (uint64_t)(size_t)-1) return 0;
    return (size_t)total;
}

GIMANY_DEF gim_result gim_cache_blob_write(const gim_cache_set *set, void *out, size_t capacity) {
    static const char *where = "gim_cache_blob_write";
    unsigned char *p = (unsigned char *)out;
    const char *why;
    size_t size;
    uint32_t i;
    if (!set) return GIM_ERROR_INVALID_ARGUMENT;
    if (!out) return gim__fail(&set->env, GIM_ERROR_INVALID_ARGUMENT, where, "output is NULL");
    if (set->count && !set->caches) return gim__fail(&set->env, GIM_ERROR_INVALID_ARGUMENT, where, "%u caches but no array", set->count);
    size = gim_cache_blob_size(set);
    if (size == 0) return gim__fail(&set->env, GIM_ERROR_OUT_OF_RANGE, where, "%u caches do not fit in size_t bytes", set->count);
    if (capacity < size) return gim__fail(&set->env, GIM_ERROR_INVALID_ARGUMENT, where, "capacity %zu < blob size %zu", capacity, size);
    why = gim__blob_check_set(set->d_eps, set->theta_eps, set->report.surface_area);
    if (why) return gim__fail(&set->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s", why);
    for (i = 0; i < set->count; ++i)
        if ((why = gim__blob_check_cache(&set->caches[i])) != NULL)
            return gim__fail(&set->env, GIM_ERROR_INVALID_ARGUMENT, where, "cache %u: %s", i, why);
    memset(p, 0, GIM__BLOB_HEADER);
    memcpy(p, "GIMCACHE", 8);
    gim__put32(p + 8, GIM__BLOB_VERSION);
    gim__put32(p + 12, GIM__BLOB_HEADER);
    gim__put32(p + 16, GIM__BLOB_RECORD);
    gim__put32(p + 20, set->count);
    gim__put64(p + 24, (uint64_t)set->count * GIM__BLOB_RECORD);
    gim__putf(p + 32, set->d_eps);
    gim__putf(p + 36, set->theta_eps);
    gim__put32(p + 40, set->report.triangles_used);
    gim__put32(p + 44, set->report.triangles_degenerate);
    gim__put32(p + 48, set->report.triangles_nonfinite);
    gim__put32(p + 52, set->report.triangles_duplicate);
    gim__put32(p + 56, set->report.voxels);
    gim__put32(p + 60, set->report.caches_before_merge);
    gim__put32(p + 64, set->report.caches_snapped);
    {
        uint64_t u;
        memcpy(&u, &set->report.surface_area, 8);
        gim__put64(p + 72, u);
    }
    for (i = 0; i < set->count; ++i) {
        unsigned char *r = p + GIM__BLOB_HEADER + (size_t)i * GIM__BLOB_RECORD;
        const gim_cache *c = &set->caches[i];
        gim__putf(r, c->position[0]); gim__putf(r + 4, c->position[1]); gim__putf(r + 8, c->position[2]);
        gim__putf(r + 12, c->area);
        gim__putf(r + 16, c->normal[0]); gim__putf(r + 20, c->normal[1]); gim__putf(r + 24, c->normal[2]);
        gim__putf(r + 28, c->reflectance);
    }
    gim__put32(p + size - GIM__BLOB_TAIL, gim__crc32(p, size - GIM__BLOB_TAIL));
    return GIM_OK;
}

GIMANY_DEF gim_result gim_cache_blob_read(const void *blob, size_t size, gim_env env, gim_cache_set *out) {
    static const char *where = "gim_cache_blob_read";
    const unsigned char *p = (const unsigned char *)blob;
    uint32_t version, count, i;
    uint64_t payload, expected;
    gim_cache_set set;
    const char *why;
    if (!blob || !out) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "blob or out is NULL");
    if (size < GIM__BLOB_HEADER + GIM__BLOB_TAIL)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "truncated: %zu bytes, less than the %u of header and checksum",
                         size, GIM__BLOB_HEADER + GIM__BLOB_TAIL);
    if (memcmp(p, "GIMCACHE", 8) != 0) return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "not a gimany cache blob (magic)");
    version = gim__get32(p + 8);
    if (version != GIM__BLOB_VERSION)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "unknown version %u (this reader knows %u)", version, GIM__BLOB_VERSION);
    if (gim__get32(p + 12) != GIM__BLOB_HEADER || gim__get32(p + 16) != GIM__BLOB_RECORD)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "header size %u or record size %u is not version 1's",
                         gim__get32(p + 12), gim__get32(p + 16));
    count = gim__get32(p + 20);
    payload = gim__get64(p + 24);
    if (payload != (uint64_t)count * GIM__BLOB_RECORD)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "payload size %llu does not match %u caches",
                         (unsigned long long)payload, count);
    expected = GIM__BLOB_HEADER + payload + GIM__BLOB_TAIL;
    if ((uint64_t)size < expected)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "truncated: %zu bytes of %llu", size, (unsigned long long)expected);
    if ((uint64_t)size > expected)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "size mismatch: %zu bytes, %u caches need %llu",
                         size, count, (unsigned long long)expected);
    if (gim__crc32(p, size - GIM__BLOB_TAIL) != gim__get32(p + size - GIM__BLOB_TAIL))
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "checksum mismatch");
    if (gim__get32(p + 68) != 0 || gim__get64(p + 80) != 0)
        return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "reserved fields are not zero");
    memset(&set, 0, sizeof set);
    set.env = env;
    set.count = count;
    set.d_eps = gim__getf(p + 32);
    set.theta_eps = gim__getf(p + 36);
    set.report.triangles_used = gim__get32(p + 40);
    set.report.triangles_degenerate = gim__get32(p + 44);
    set.report.triangles_nonfinite = gim__get32(p + 48);
    set.report.triangles_duplicate = gim__get32(p + 52);
    set.report.voxels = gim__get32(p + 56);
    set.report.caches_before_merge = gim__get32(p + 60);
    set.report.caches_snapped = gim__get32(p + 64);
    {
        uint64_t u = gim__get64(p + 72);
        memcpy(&set.report.surface_area, &u, 8);
    }
    why = gim__blob_check_set(set.d_eps, set.theta_eps, set.report.surface_area);
    if (why) return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "%s", why);
    if (count) {
        set.caches = (gim_cache *)gim__alloc_array(&env, count, sizeof(gim_cache));
        if (!set.caches) return gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, where, "%u caches", count);
    }
    for (i = 0; i < count; ++i) {
        const unsigned char *r = p + GIM__BLOB_HEADER + (size_t)i * GIM__BLOB_RECORD;
        gim_cache *c = &set.caches[i];
        c->position[0] = gim__getf(r); c->position[1] = gim__getf(r + 4); c->position[2] = gim__getf(r + 8);
        c->area = gim__getf(r + 12);
        c->normal[0] = gim__getf(r + 16); c->normal[1] = gim__getf(r + 20); c->normal[2] = gim__getf(r + 24);
        c->reflectance = gim__getf(r + 28);
        if ((why = gim__blob_check_cache(c)) != NULL) {
            gim__cache_set_release(&set);
            return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "cache %u: %s", i, why);
        }
    }
    *out = set;
    return GIM_OK;
}

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
