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
   theta_eps of the vertex normal, and d_c,max, the largest of their distances, for the
   weights of eq. 8.
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
    float theta_eps;             /* (0, pi]; default: 2 x caches->theta_eps (30 degrees if 0), at most 90
                                    degrees, so smooth-shaded edges and corners find caches */
    gim_env env;
} gim_neighbour_desc;

/* Caller-owned output of gim_cache_neighbours, sized by the mesh's vertex count; all three
   required. Row v of index is index[v * n .. v * n + n - 1] (n after its default). */
typedef struct gim_neighbour_result {
    uint32_t *index;   /* vertex_count * n cache indices, nearest first; UINT32_MAX pads */
    uint32_t *count;   /* vertex_count: how many of the n were found (compatible caches may be fewer) */
    float *d_cmax;     /* vertex_count: distance of the farthest found cache (0 when none) */
} gim_neighbour_result;

/* Per-vertex neighbour caches through a k-d tree over the caches (not O(V x C)): median splits
   adapt to any density with no unit; nodes farther than the n-th best found, or whose normal
   bounds admit no compatible normal, are skipped. Exact: the O(V x C) answer, bit for bit. */
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
   in double from the input floats, then cache index, so the search answers exactly what the
   O(V x C) loop would.
   Search: a k-d tree over the cache positions (median splits, so it adapts to any density and
   needs no unit), each node also bounding its caches' normals. Depth first, nearer child
   first; a node is skipped when its box is farther than the n-th best found, or when no
   normal in its bounds can be compatible. So the faces of a thin wall, and a flipped mesh
   whose only compatible caches are across the room, cost a few nodes, not a scan. */

/* A cache as the search reads it: 32 bytes, two per cache line. */
typedef struct gim__nb_slot {
    float pos[3], nrm[3];        /* position, normalised normal */
    uint32_t id;                 /* index in the set */
    uint32_t pad;
} gim__nb_slot;

typedef struct gim__nb_node {
    float plo[3], phi[3];        /* bounds of the positions below */
    float nlo[3], nhi[3];        /* bounds of the normals below */
    uint32_t begin, end;         /* range of slots */
    uint32_t left;               /* first of two children; 0 for a leaf */
} gim__nb_node;

typedef struct gim__nb_tree {
    gim__nb_node *node;
    gim__nb_slot *slot;          /* the caches in node order */
} gim__nb_tree;

#define GIM__NB_LEAF 8u
#define GIM__NB_STACK 160u

/* Quickselect: put the k-th smallest of keys key[perm[i] * 3 + axis], i in [lo, hi), at k,
   smaller or equal ones before it, greater or equal after. */
static void gim__nb_select(const float *key, uint32_t *perm, uint32_t lo, uint32_t hi, uint32_t k, int axis) {
    while (hi - lo > 1u) {
        uint32_t i = lo, j = hi - 1u, t;
        float pivot = key[(size_t)perm[lo + (hi - lo) / 2u] * 3u + (uint32_t)axis];
        while (i <= j) {
            while (key[(size_t)perm[i] * 3u + (uint32_t)axis] < pivot) ++i;
            while (key[(size_t)perm[j] * 3u + (uint32_t)axis] > pivot) --j;
            if (i <= j) {
                t = perm[i]; perm[i] = perm[j]; perm[j] = t;
                ++i;
                if (j == 0) break;
                --j;
            }
        }
        /* now [lo, j] <= pivot <= [i, hi), and what lies between equals the pivot */
        if (k <= j && j + 1u > lo) hi = j + 1u;
        else if (k >= i) lo = i;
        else return;
    }
}

/* Build over the caches; unit_nrm holds their normalised normals. */
static gim_result gim__nb_tree_build(const gim_env *env, const gim_cache_set *set, const float *unit_nrm, gim__nb_tree *t) {
    uint32_t C = set->count, *perm, stack[GIM__NB_STACK], top = 0, count = 1, c;
    float *key;
    t->node = (gim__nb_node *)gim__alloc_array(env, 2u * (size_t)C, sizeof(gim__nb_node));
    t->slot = (gim__nb_slot *)gim__alloc_array(env, C, sizeof(gim__nb_slot));
    perm = (uint32_t *)gim__alloc_array(env, C, sizeof(uint32_t));
    key = (float *)gim__alloc_array(env, C, 3u * sizeof(float));
    if (!t->node || !t->slot || !perm || !key) {
        gim__free(env, t->node); gim__free(env, t->slot); gim__free(env, perm); gim__free(env, key);
        t->node = NULL; t->slot = NULL;
        return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, "gim_cache_neighbours", "search tree of %u caches", C);
    }
    for (c = 0; c < C; ++c) { perm[c] = c; memcpy(key + (size_t)c * 3u, set->caches[c].position, 3u * sizeof(float)); }
    t->node[0].begin = 0; t->node[0].end = C;
    stack[top++] = 0;
    while (top) { /* median splits: depth <= log2(C) + 1, the stack holds at most 2 per level */
        gim__nb_node *nd = &t->node[stack[--top]];
        uint32_t i, a, axis = 0, mid;
        for (a = 0; a < 3u; ++a) { nd->plo[a] = FLT_MAX; nd->phi[a] = -FLT_MAX; nd->nlo[a] = 2.0f; nd->nhi[a] = -2.0f; }
        for (i = nd->begin; i < nd->end; ++i)
            for (a = 0; a < 3u; ++a) {
                float p = key[(size_t)perm[i] * 3u + a], q = unit_nrm[(size_t)perm[i] * 3u + a];
                if (p < nd->plo[a]) nd->plo[a] = p;
                if (p > nd->phi[a]) nd->phi[a] = p;
                if (q < nd->nlo[a]) nd->nlo[a] = q;
                if (q > nd->nhi[a]) nd->nhi[a] = q;
            }
        /* widest axis, its extent in double (a float difference can overflow) */
        for (a = 1; a < 3u; ++a)
            if ((double)nd->phi[a] - nd->plo[a] > (double)nd->phi[axis] - nd->plo[axis]) axis = a;
        nd->left = 0;
        if (nd->end - nd->begin <= GIM__NB_LEAF || !(nd->phi[axis] > nd->plo[axis]) || top + 2u > GIM__NB_STACK - 2u)
            continue; /* leaf: few caches, all at one point, or (never with median splits) too deep */
        mid = nd->begin + (nd->end - nd->begin) / 2u;
        gim__nb_select(key, perm, nd->begin, nd->end, mid, (int)axis);
        nd->left = count;
        t->node[count].begin = nd->begin; t->node[count].end = mid;
        t->node[count + 1u].begin = mid; t->node[count + 1u].end = nd->end;
        stack[top++] = count; stack[top++] = count + 1u;
        count += 2u;
    }
    for (c = 0; c < C; ++c) {
        gim__nb_slot *sl = &t->slot[c];
        memcpy(sl->pos, set->caches[perm[c]].position, 3u * sizeof(float));
        memcpy(sl->nrm, unit_nrm + (size_t)perm[c] * 3u, 3u * sizeof(float));
        sl->id = perm[c];
        sl->pad = 0;
    }
    gim__free(env, perm);
    gim__free(env, key);
    return GIM_OK;
}

/* Squared distance from p to a node's box, shrunk by a relative 1e-9 so that rounding never
   lifts it above the distance of a cache inside: a lower bound. */
static double gim__nb_box_d2(const double *p, const gim__nb_node *nd) {
    double d2 = 0.0;
    int a;
    for (a = 0; a < 3; ++a) {
        double g = p[a] < nd->plo[a] ? (double)nd->plo[a] - p[a] : (p[a] > nd->phi[a] ? p[a] - (double)nd->phi[a] : 0.0);
        d2 += g * g;
    }
    return d2 * (1.0 - 1e-9);
}

/* 1 when no normal inside the node's bounds can pass nv . m >= cos_theta: the interval
   bound of the dot product, with 1e-9 to spare for the rounding of the exact test. */
static int gim__nb_normals_out(const double *nv, const gim__nb_node *nd, double cos_theta) {
    double dmax = 0.0;
    int a;
    for (a = 0; a < 3; ++a) {
        double p = nv[a] * nd->nlo[a], q = nv[a] * nd->nhi[a];
        dmax += p > q ? p : q;
    }
    return dmax < cos_theta - 1e-9;
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

/* The n nearest compatible caches of one vertex into bd/bi; returns how many. any: every
   normal is compatible. bound: a squared distance the n-th nearest is known not to exceed
   (from n compatible caches that near), or HUGE_VAL. */
static uint32_t gim__nb_query(const gim__nb_tree *t, const double *p, const double *nv, int any, double cos_theta,
                              uint32_t n, double bound, double *bd, uint32_t *bi) {
    uint32_t stack[GIM__NB_STACK], top = 0, found = 0;
    double sd[GIM__NB_STACK];
    stack[top] = 0; sd[top++] = 0.0;
    while (top) {
        const gim__nb_node *nd;
        double d = sd[--top];
        nd = &t->node[stack[top]];
        if (d > bound) continue; /* ties with a smaller index stay in */
        if (!any && gim__nb_normals_out(nv, nd, cos_theta)) continue;
        if (nd->left) {
            const gim__nb_node *l = &t->node[nd->left], *r = l + 1;
            double dl = gim__nb_box_d2(p, l), dr = gim__nb_box_d2(p, r);
            /* the nearer child is popped first */
            if (dl <= dr) { stack[top] = nd->left + 1u; sd[top++] = dr; stack[top] = nd->left; sd[top++] = dl; }
            else { stack[top] = nd->left; sd[top++] = dl; stack[top] = nd->left + 1u; sd[top++] = dr; }
        } else {
            uint32_t s;
            for (s = nd->begin; s < nd->end; ++s) {
                const gim__nb_slot *sl = &t->slot[s];
                double dx = p[0] - sl->pos[0], dy = p[1] - sl->pos[1], dz = p[2] - sl->pos[2];
                double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 > bound) continue;
                if (!any && nv[0] * sl->nrm[0] + nv[1] * sl->nrm[1] + nv[2] * sl->nrm[2] < cos_theta) continue;
                gim__nb_insert(bd, bi, &found, n, d2, sl->id);
                if (found == n && bd[n - 1] < bound) bound = bd[n - 1];
            }
        }
    }
    return found;
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
    gim__nb_tree tree;
    double theta, cos_theta;
    float *vn = NULL, *cn = NULL;
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
    /* theta_eps: the desc's; by default the set's (0: the generator's 30 degrees) doubled, up to
       90 degrees. A cache stands for normals within theta_eps of its own, but a smooth-shaded
       vertex averages the faces around it: 45 degrees off either face on a box edge, 54.7 at a
       corner, where theta_eps itself would find no cache at all and leave the vertex unlit.
       Below 90 degrees the far side of a thin wall, and every cache eq. 8 weighs zero, stay out. */
    theta = desc->theta_eps != 0.0f ? desc->theta_eps : (set->theta_eps != 0.0f ? set->theta_eps : 0.52359877559829887);
    if (!(theta > 0.0 && theta <= (double)3.14159265358979324f)) /* pi rounded to float is a little above pi */
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "theta_eps %g not in (0, pi]", theta);
    if (desc->theta_eps == 0.0f && theta < 1.57079632679489662)
        theta = 2.0 * theta < 1.57079632679489662 ? 2.0 * theta : 1.57079632679489662;
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
    tree.node = NULL; tree.slot = NULL;
    r = gim__nb_vertex_normals(m, env, vn);
    if (r == GIM_OK) r = gim__nb_tree_build(env, set, cn, &tree);
    if (r != GIM_OK) { gim__free(env, cn); gim__free(env, vn); return r; }

    for (v = 0; v < m->vertex_count; ++v) {
        double bd[GIM_MAX_NEIGHBOUR_CACHES], pd[3], nd[3];
        uint32_t bi[GIM_MAX_NEIGHBOUR_CACHES], found = 0, k;
        gim_vec3 p = gim__nb_load3(m->positions, pstride, v);
        uint32_t *oi = out->index + (size_t)v * n;
        int any;
        if (gim_v3_isfinite(p)) {
            double bound = HUGE_VAL;
            pd[0] = p.x; pd[1] = p.y; pd[2] = p.z;
            nd[0] = vn[(size_t)v * 3u]; nd[1] = vn[(size_t)v * 3u + 1u]; nd[2] = vn[(size_t)v * 3u + 2u];
            any = nd[0] == 0.0 && nd[1] == 0.0 && nd[2] == 0.0;
            no_normal += (uint32_t)any;
            /* Neighbouring vertices share caches: if the previous vertex's n caches are all
               compatible here too, the farthest of them bounds the search from the start. The
               bound only prunes, so the answer stays exact. */
            if (v > 0 && out->count[v - 1] == n) {
                const uint32_t *prev = out->index + (size_t)(v - 1) * n;
                for (k = 0; k < n; ++k) {
                    const float *cp = set->caches[prev[k]].position, *cq = cn + (size_t)prev[k] * 3u;
                    double dx = pd[0] - cp[0], dy = pd[1] - cp[1], dz = pd[2] - cp[2];
                    double d2 = dx * dx + dy * dy + dz * dz;
                    if (!any && nd[0] * cq[0] + nd[1] * cq[1] + nd[2] * cq[2] < cos_theta) break;
                    if (k == 0 || d2 > bound) bound = d2;
                }
                if (k < n) bound = HUGE_VAL;
            }
            found = gim__nb_query(&tree, pd, nd, any, cos_theta, n, bound, bd, bi);
        } else {
            ++no_position;
        }
        for (k = 0; k < found; ++k) oi[k] = bi[k];
        for (; k < n; ++k) oi[k] = UINT32_MAX;
        out->count[v] = found;
        out->d_cmax[v] = found ? (float)sqrt(bd[found - 1]) : 0.0f;
    }
    if (no_normal || no_position)
        gim__log(env, GIM_LOG_WARNING, where, "%u vertices without a usable normal took the nearest caches of any normal; "
                 "%u vertices with a non-finite position got none", no_normal, no_position);
    gim__free(env, tree.node);
    gim__free(env, tree.slot);
    gim__free(env, cn);
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
