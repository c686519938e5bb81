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
   light (Dong et al. sec. 5; SSVP sec. 3). Deterministic: same input, same output, bit for bit.

   Structure (the CPU twin of a GPU pass): each iteration is an assignment step, an independent
   argmin over the M centres per VPL, then an update step, per-cluster sums in double in VPL
   index order. A VPL changes cluster only for a strictly smaller distance (ties keep it; with
   no previous cluster the lowest index wins), so coincident points settle.
   Means: a VPL weighs its mean rgb flux (r+g+b)/3 (all 1 when flux is NULL); centre, normal
     and sigma of a cluster are weighted means, so a VAL sits where its light comes from and
     unlit VPLs do not drag it (Dong averages unweighted); a cluster whose VPLs all have zero
     flux falls back to the plain mean (weights 1). The normal is the normalised weighted mean
     normal; where the normals cancel (|sum| <= 1e-9 * sum of weights) it keeps its previous
     normal. Positions are taken relative to the centre of the VPL bounds, in double, so a
     scene far from the origin loses no precision.
   Empty clusters are repaired, never lost: for each empty cluster (index order) the cluster
     with the largest error (sum of its VPLs' distances; ties: more VPLs, then lower index)
     among those with two or more VPLs gives up its farthest VPL (ties: lowest index), which
     seeds the empty cluster. Every returned cluster has count >= 1.
   Convergence: stops when an assignment step changes no VPL, or after max_iterations steps.
     The outputs are always consistent: centres, normals, flux, counts, area and sigma are
     those of the returned assignment.
   Area (Dong 6): the smallest rectangle, over all in-plane rotations, bounding the cluster's
     VPLs projected on the plane of its normal; a rectangle aligned to some tangent frame would
     jump whenever the frame flips, and the soft shadows with it.
   M > N is an error (GIM_ERROR_INVALID_ARGUMENT): every cluster needs a VPL; M == N gives one
     VPL per cluster (when their positions/normals differ). Summed flux beyond FLT_MAX or VPL
     bounds wider than 1.8e19 (areas beyond FLT_MAX) give GIM_ERROR_OUT_OF_RANGE. */

/* Distance between a VPL and a cluster centre; s is the scene scale. */
typedef enum gim_kmeans_metric {
    GIM_KMEANS_METRIC_DEFAULT = 0,  /* = DONG */
    GIM_KMEANS_METRIC_DONG,         /* Dong 5.1: w_x * |x_i - c_j| / s + w_a * acos(n_i . n_j) / pi; default w 0.7 / 0.3 */
    GIM_KMEANS_METRIC_SSVP          /* SSVP eq. 2, its sign slip corrected: w_x * |x_i - c_j| / s + w_a * (1 - max(n_i . n_j, 0));
                                       default w 0.6 / 0.4 (the paper's) */
} gim_kmeans_metric;

/* Where the iteration starts. */
typedef enum gim_kmeans_init {
    GIM_KMEANS_INIT_DEFAULT = 0,    /* = FIXED */
    GIM_KMEANS_INIT_FIXED,          /* cluster k seeded by VPL floor(k * N / M): the same every frame (Dong 5.2, 6) */
    GIM_KMEANS_INIT_WARM            /* start from init_centres/init_normals (the previous frame's; SSVP 3.B) */
} gim_kmeans_init;

/* Input of gim_kmeans; zero means default. Arrays are float3 per VPL. */
typedef struct gim_kmeans_desc {
    const float *positions;     /* vpl_count * 3, finite */
    const float *normals;       /* vpl_count * 3, non-zero (renormalised internally) */
    const float *flux;          /* vpl_count * 3, rgb, finite, >= 0; NULL: every VPL weighs 1 */
    uint32_t vpl_count;         /* N > 0 */
    uint32_t cluster_count;     /* M, 0 < M <= N */
    gim_kmeans_metric metric;
    gim_kmeans_init init;
    const float *init_centres;  /* WARM: cluster_count * 3 */
    const float *init_normals;  /* WARM: cluster_count * 3, non-zero */
    float w_x, w_a;             /* metric weights >= 0; both 0: the metric's defaults (one may be 0) */
    float scene_scale;          /* length unit of the position term; 0: diagonal of the VPL bounds */
    uint32_t max_iterations;    /* cap on assignment steps, <= 4096; 0: 16 */
    gim_env env;
} gim_kmeans_desc;

/* Output of gim_kmeans: caller-owned arrays sized by the desc's counts; untouched on error. */
typedef struct gim_kmeans_result {
    float *centres;        /* M * 3: weighted mean position (required) */
    float *normals;        /* M * 3: normalised weighted mean normal (required) */
    float *flux;           /* M * 3: summed flux (zero when the desc's flux is NULL), or NULL */
    uint32_t *counts;      /* M: VPLs per cluster (>= 1), or NULL */
    uint32_t *assignment;  /* N: cluster of each VPL, or NULL */
    float *area;           /* M: area of the VAL's rectangle (see above); VPLs of zero flux emit
                              nothing and count only in a cluster without flux; or NULL */
    float *sigma;          /* M * 3: weighted positional standard deviation per world axis, or NULL */
    uint32_t iterations;   /* written: assignment steps run (below the cap, the last changed nothing) */
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
   (clamp * scene_scale)^2 (eq. 11 made unit-free). Three steps, each the CPU twin of a GPU
   pass with the same structure:
     gim_importance_map     one independent value per texel (a compute thread per texel)
     gim_importance_cumsum  a scan down every column, then a scan along the column totals
     gim_importance_select  one independent binary search per selected VAL
   Distances are measured in scene scales, so the map is in units of flux and the same scene
   in millimetres or kilometres gives the same map (bit for bit for power-of-two scalings).

   Default clamp, 1/64 of the scene scale: the paper clamps at 1 world unit in an urban scene a
   few hundred metres across (about 1/300 of its diagonal), which is a unit, not a choice. The
   importance only steers which VALs reach the caches, and the light is gathered at caches
   spaced d_eps = scene_scale / 32 (the cache default), so distances below about d_eps / 2 are
   not resolved by any receiver. A smaller clamp only sharpens the 1/d^2 peak of texels lying
   next to one of the few hundred view samples: at 1/64 one such pair adds at most
   64^2 = 4096 to the sum of eq. 10, a few times what a typical texel collects from all 512
   samples (~512 x 0.3 / 0.1 at a third of the scene away); at 1/300 it would add 90000, and
   those few texels would soak up the selections (and flicker as the view samples move)
   without lighting the caches any better. */

/* One view sample: a visible surface point and its normal (from the G-buffer). */
typedef struct gim_view_sample {
    gim_vec3 position;
    gim_vec3 normal;
} gim_view_sample;

/* Input of gim_importance_map. The RSM arrays are width * height, row-major, row 0 first. */
typedef struct gim_importance_desc {
    const float *rsm_position;  /* width * height * 3: world position of each texel */
    const float *rsm_normal;    /* width * height * 3: unit normal (renormalised; zero: no importance) */
    const float *rsm_flux;      /* width * height * 3: reflected flux, rgb */
    const float *rsm_valid;     /* width * height, or NULL: a texel counts only where > 0 */
    uint32_t width, height;
    const gim_view_sample *view_samples; /* a NaN/Inf or zero-normal sample sees nothing (warning) */
    uint32_t view_sample_count;
    float scene_scale;          /* > 0 */
    float clamp;                /* eq. 11 clamp distance in scene scales; default 1/64 (see above) */
    gim_env env;
} gim_importance_desc;

/* eq. 10-11: importance of every texel into out[width * height]:
     I = lum(Phi)+ / N_VS * sum_j (n_l . d)+ (n_VS . -d)+ / max(|l|^2 / scene_scale^2, clamp^2)
   with l = VS_j - VAL, d = l / |l|. An invalid texel (rsm_valid <= 0, a NaN/Inf in its
   position, normal or flux, a zero normal) gets 0, so does a view sample at the texel itself;
   every output is finite and >= 0 (clamped at FLT_MAX). */
GIMANY_API gim_result gim_importance_map(const gim_importance_desc *desc, float *out);

/* The two tables of eq. 12, built in double so P stays exact at 4096^2:
   column[y * width + x] = sum over rows 0..y of map(x, .)   (vertical, per column),
   row[x] = sum over columns 0..x of column[(height-1) * width + .] (horizontal totals).
   Every map value must be finite and >= 0; otherwise GIM_ERROR_INVALID_ARGUMENT and the
   tables' contents are unspecified. The only rounding that matters: a texel (a column) below
   2^-53 of the running sum it joins may add nothing to it; it can then never be picked, which
   keeps the selection consistent with the pdf, and the mass lost is below
   (width + height) x 2^-53 of the total. */
GIMANY_API gim_result gim_importance_cumsum(const float *map, uint32_t width, uint32_t height,
                                            double *column, double *row, gim_env env);

/* One selected VAL: its texel and the probability it had of being picked. */
typedef struct gim_selected_val {
    uint32_t x, y;
    float pdf;                  /* P_VAL = map(x,y) / total; > 0 for every selected texel */
} gim_selected_val;

/* Pick count texels with probability proportional to the map. Sample i takes the point
     u_i = frac(i / count + o_0),  v_i = frac(radical_inverse_2(i) + o_1)
   of the Hammersley set, Cranley-Patterson rotated by per-seed 48-bit offsets
   o_d = f[d] + f[d+2] * 2^-24 (f from gim_rotation_offsets(f, 4, seed)). u_i picks the
   column (first x with row[x] > u_i * total), v_i the texel in it (first y with
   column(x, y) > v_i * column total). Over the seeds every u_i and v_i alone is uniform, so
   every sample is distributed exactly as P; within one call the u_i are stratified, so
   column x gets count * P(column x) samples rounded up or down.
   pdf is the probability the tables realise, from their differences:
     P = (row[x] - row[x-1]) / total * (column(x, y) - column(x, y-1)) / column total,
   > 0 (a texel of importance 0 is never picked), clamped below at FLT_MIN so 1/pdf stays
   finite. An all-zero (or all-invalid) map selects the texels uniformly,
   (floor(u_i * width), floor(v_i * height)) with pdf = 1 / (width * height), and logs a
   warning: the estimator stays unbiased. Tables that are not cumulative sums are
   GIM_ERROR_INVALID_ARGUMENT: the row and the column totals are checked (O(width): NaN/Inf,
   negative, decreasing); inside a column, a NaN a search meets or a picked texel with no
   positive difference (out is then partly written). */
GIMANY_API gim_result gim_importance_select(const double *column, const double *row,
                                            uint32_t width, uint32_t height, uint32_t count,
                                            uint32_t seed, gim_selected_val *out, gim_env env);

/* @section twins ========================================================================== */

/* twins of the scene passes: RSM texel, G-buffer, view samples ------------------------------
   The scene description the GL runtime takes (gim_set_materials, gim_set_lights) and the CPU
   twins of the shared passes of the frame (DESIGN.md sec. 5): each casts the ray through one
   texel centre against a world-space triangle soup (brute force: for tests and small scenes)
   and computes what the GPU pass writes at that texel.

   Units (DESIGN.md sec. 4). Lengths in the host's unit L; a directional light's irradiance E
   is power per unit area perpendicular to its direction (W / L^2); a spot's intensity I is
   power per steradian (W / sr) inside its cone and 0 outside. An RSM texel is a VAL:
     footprint area A (L^2): for the spot the texel's solid angle w at the light times d^2
       over the cosine at the surface, A = w d^2 / cos (eq. 1 of paper 000 is the on-axis
       case w = s^2, with s the texel side on the plane at distance 1; the exact
       w = s^2 / (1 + u^2 + v^2)^(3/2) at image-plane point (u, v) makes the texels' w sum to
       the cone's solid angle); for the orthographic sun A = a / cos with a = (2 extent /
       size)^2 the texel's area perpendicular to the light. cos is clamped below at
       GIM_RSM_MIN_COS so a grazing texel's A stays finite.
     flux Phi (W) = albedo x the power arriving on the footprint: the sun's E x a (E cos on
       an area a / cos: the tilt cancels), the spot's I x w (I w over A = w d^2 / cos is
       irradiance I cos / d^2 on A). Summed over the texels that see a diffuse plane of
       albedo rho: rho E (projected area) for the sun, rho I (solid angle of the plane
       within the cone) for the spot.
   Normals face the light (the RSM) or the eye (the G-buffer): a surface seen from its back
   is lit and seen on that side (two-sided). */

/* Kind of light. */
typedef enum gim_light_type {
    GIM_LIGHT_DEFAULT = 0,     /* = DIRECTIONAL */
    GIM_LIGHT_DIRECTIONAL,     /* the sun: parallel light, orthographic RSM */
    GIM_LIGHT_SPOT             /* a point light in a cone, perspective RSM */
} gim_light_type;

#define GIM_MAX_LIGHTS 8              /* lights per context */
#define GIM_RSM_MIN_COS (1.0f / 64.0f) /* floor of the cosine in a VAL's area A = ... / cos */

/* A light; zero means default. */
typedef struct gim_light {
    gim_light_type type;
    float color[3];         /* rgb factor of the power, >= 0; all zero: (1, 1, 1) */
    float irradiance;       /* DIRECTIONAL: E, per unit area perpendicular to direction, >= 0 */
    float intensity;        /* SPOT: I, per steradian inside the cone, >= 0 */
    gim_vec3 position;      /* SPOT: where the light is */
    gim_vec3 direction;     /* DIRECTIONAL: towards the light; SPOT: the cone's axis, away from
                               the light; non-zero (normalised internally) */
    float cone_angle;       /* SPOT: half-angle in radians, in (0, 1.5] (below 90 degrees) */
    float extent;           /* DIRECTIONAL: half-width of the orthographic RSM (lengths);
                               0: the radius of the scene bounds' sphere, so it covers the scene */
    uint32_t rsm_size;      /* RSM side in texels; 0: 512 */
} gim_light;

/* One material; zero is black. Diffuse and glossy albedo rgb, Phong-like exponent k. */
typedef struct gim_material {
    float diffuse[3];       /* >= 0 */
    float glossy[3];        /* >= 0 */
    float exponent;         /* k >= 0 */
} gim_material;

/* The light's camera: a look-at view and a projection fitted to the scene bounds (bmin, bmax:
   the world bounds of everything that casts or receives). SPOT: perspective of field of view
   2 x cone_angle, aspect 1, far just past the farthest bounds corner, near at the bounds (or
   far / 10^4 when the light is inside them). DIRECTIONAL: orthographic +-extent around the
   bounds' centre, the bounds' sphere inside its depth range. The GL runtime uses the same. */
GIMANY_API gim_result gim_light_camera(const gim_light *light, const float bmin[3], const float bmax[3],
                                       gim_mat4 *view, gim_mat4 *proj);

/* A world-space triangle soup for the twins. */
typedef struct gim_twin_scene {
    const float *positions;  /* triangle_count * 9: three world-space vertices per triangle */
    const float *normals;    /* triangle_count * 9 vertex normals (any length, interpolated then
                                normalised, as the GPU does), or NULL: face normals */
    const float *albedo;     /* triangle_count * 3: diffuse rgb, >= 0 */
    uint32_t triangle_count;
} gim_twin_scene;

/* What the RSM pass writes at one texel. */
typedef struct gim_rsm_texel {
    float position[3];
    float normal[3];         /* unit, towards the light */
    float flux[3];           /* Phi (see the units above); 0 where not lit */
    float area;              /* A */
    float depth;             /* window depth in [0, 1]; 1 where nothing is hit */
    int lit;                 /* 1: a VAL (a surface inside the cone); the GPU's position.w */
    uint32_t triangle;       /* the triangle hit, UINT32_MAX: none */
} gim_rsm_texel;

/* Twin of the RSM pass at texel (x, y) of the light's rsm_size^2 RSM (row 0 at the bottom of
   its clip space, as GL stores it); bounds as for gim_light_camera. */
GIMANY_API gim_result gim_rsm_texel_twin(const gim_twin_scene *scene, const gim_light *light, const float bmin[3],
                                         const float bmax[3], uint32_t x, uint32_t y, gim_rsm_texel *out);

/* What the G-buffer pass writes at one pixel. */
typedef struct gim_gbuffer_texel {
    float position[3];       /* world */
    float normal[3];         /* unit, towards the eye; 0 where nothing is hit */
    float albedo[3];         /* diffuse rgb */
    float depth;             /* window depth in [0, 1]; 1 where nothing is hit */
    uint32_t triangle;       /* UINT32_MAX: none */
} gim_gbuffer_texel;

/* Twin of the G-buffer pass at pixel (x, y) of a width x height view through view, proj. */
GIMANY_API gim_result gim_gbuffer_texel_twin(const gim_twin_scene *scene, gim_mat4 view, gim_mat4 proj,
                                             uint32_t width, uint32_t height, uint32_t x, uint32_t y,
                                             gim_gbuffer_texel *out);

/* The pixels of the view samples (paper 000 sec. 4): Halton points 1..count in bases 2 and 3
   (point 0 is the corner), Cranley-Patterson rotated by offsets (2 values in [0,1), e.g. from
   gim_rotation_offsets(off, 2, frame), or NULL), scaled to the width x height G-buffer:
   pixels[2 i] = min(floor(u_i width), width - 1), pixels[2 i + 1] likewise with v_i, height. */
GIMANY_API gim_result gim_view_sample_pixels(uint32_t count, uint32_t width, uint32_t height, const float *offsets,
                                             uint32_t *pixels);

/* Twin of the view-sample pass: the G-buffer at each pixel as a gim_view_sample. depth:
   width * height window depths in [0, 1] (row-major, row 0 at the bottom); normal: width *
   height * 4 (xyz used: world normal). The position is unprojected through the inverses of
   proj and view (in double). Where depth >= 1 (nothing drawn) or the normal is zero or not
   finite the sample is unusable: position and normal are written as zero (the importance
   pass skips a zero normal). */
GIMANY_API gim_result gim_view_samples_twin(const float *depth, const float *normal, uint32_t width, uint32_t height,
                                            gim_mat4 view, gim_mat4 proj, const uint32_t *pixels, uint32_t count,
                                            gim_view_sample *out);

#ifdef __cplusplus
}
#endif

/* @section gl ============================================================================= */
/* The GL 4.3 runtime. gimany includes no GL header: it loads the functions it uses from the
   host's get_proc_address into a table inside the context (or, with GIMANY_EXTERNAL_GL, takes
   the host loader's gl* functions). A GL 4.3 context must be current on the calling thread for
   every call below. Every call that touches GL leaves the GL state as it found it.

   A frame, step by step (zero means default everywhere):
         gim_context *ctx;
         gim_desc d = {0}; d.get_proc_address = glfwGetProcAddress;
         gim_create(&d, &ctx);
         gim_mesh_desc md = {0};                      once per mesh, model space
         md.data.positions = p; md.data.vertex_count = nv;
         md.data.indices = idx; md.data.index_count = ni; md.data.index_type = GIM_INDEX_U16;
         md.data.triangle_material = mat_ids;         NULL: material 0
         gim_mesh mesh; gim_add_mesh(ctx, &md, &mesh);
         gim_set_materials(ctx, mats, nmats);         diffuse, glossy, k
         gim_instance in = {mesh, model};
         gim_set_instances(ctx, &in, 1);              every frame for moving objects
         gim_light sun = {0}; sun.irradiance = 3.0f; sun.direction = towards_sun; sun.rsm_size = 1024;
         gim_set_lights(ctx, &sun, 1);
         gim_frame f = {0}; f.view = v; f.proj = p; f.width = w; f.height = h;
         gim_update(ctx, &f);                         RSM, G-buffer, view samples, importance, selection
         gim_frame_outputs o = gim_outputs(ctx);      GL names of what the passes wrote
         ...
         gim_destroy(ctx); */
#ifndef GIMANY_NO_GL
#ifdef __cplusplus
extern "C" {
#endif

/* A GL function as a loader returns it: matches eglGetProcAddress and glfwGetProcAddress. */
typedef void (*gim_gl_proc)(void);

/* Input of gim_create; zero means default. */
typedef struct gim_desc {
    gim_gl_proc (*get_proc_address)(const char *name); /* required unless GIMANY_EXTERNAL_GL */
    gim_env env;                                        /* allocator and log of the context */
} gim_desc;

/* The runtime: GL functions, programs and buffers. Opaque; one per GL context. */
typedef struct gim_context gim_context;

/* Create a context for the current GL context: loads the GL functions, checks for GL 4.3
   (GIM_ERROR_UNSUPPORTED, with what is missing logged), logs the renderer. Shaders are
   compiled lazily on first use. *out is written only on GIM_OK. */
GIMANY_API gim_result gim_create(const gim_desc *desc, gim_context **out);
/* Delete every GL object and allocation of ctx (its GL context must be current); NULL is fine. */
GIMANY_API void gim_destroy(gim_context *ctx);

/* --- the scene the host hands over (DESIGN.md sec. 2) --------------------------------------
   Meshes are uploaded once; materials, instances and lights are set whenever they change
   (instances every frame for moving objects); sizes may change between frames without
   recreating the context. Every call validates all its input before touching anything: on an
   error the scene is as it was before the call. */

/* A mesh handle; id 0 is never a mesh. */
typedef struct gim_mesh { uint32_t id; } gim_mesh;

/* Input of gim_add_mesh; zero means default. */
typedef struct gim_mesh_desc {
    gim_mesh_data data;         /* model space: positions (finite), normals (non-zero, finite; NULL:
                                   area-weighted vertex normals are computed), 16/32-bit indices
                                   (< vertex_count), triangle_material (ids into gim_set_materials'
                                   array, checked at gim_update; NULL: all 0); material_reflectance
                                   and material_count are not used here */
    const gim_cache_set *caches; /* model-space LightSkin caches of the mesh, or NULL; copied */
} gim_mesh_desc;

/* Upload a mesh (vertex, index and per-triangle material buffers). *out written on GIM_OK. */
GIMANY_API gim_result gim_add_mesh(gim_context *ctx, const gim_mesh_desc *desc, gim_mesh *out);
/* Delete a mesh; instances still naming it make gim_update fail until they are replaced. */
GIMANY_API gim_result gim_remove_mesh(gim_context *ctx, gim_mesh mesh);

/* Materials by index (gim_material: diffuse rgb, glossy rgb, exponent k; see @section twins);
   count 0 clears them. Replaces the previous set. */
GIMANY_API gim_result gim_set_materials(gim_context *ctx, const gim_material *materials, uint32_t count);

/* One placed mesh. */
typedef struct gim_instance {
    gim_mesh mesh;
    gim_mat4 model;             /* model to world; finite and invertible */
} gim_instance;

/* The instances of the frame (copied); count 0 clears them. */
GIMANY_API gim_result gim_set_instances(gim_context *ctx, const gim_instance *instances, uint32_t count);

/* The lights (gim_light, see @section twins; copied), at most GIM_MAX_LIGHTS; count 0 clears
   them. rsm_size must fit GL_MAX_TEXTURE_SIZE and GL_MAX_VIEWPORT_DIMS. */
GIMANY_API gim_result gim_set_lights(gim_context *ctx, const gim_light *lights, uint32_t count);

/* --- the frame ------------------------------------------------------------------------------ */

/* Input of gim_update; zero means default. */
typedef struct gim_frame {
    gim_mat4 view, proj;        /* the host's camera; finite, invertible; depth range [0, 1] */
    uint32_t width, height;     /* G-buffer size in pixels (the host's viewport), > 0 */
    uint32_t gbuffer_depth;     /* the host's G-buffer instead of gimany's: a 2D depth texture of
                                   the same view (window depth in [0, 1], 1 = nothing) ... */
    uint32_t gbuffer_normal;    /* ... and a 2D float texture with the world normal in .xyz;
                                   both >= width x height, or both 0 (gimany draws one) */
    uint32_t view_sample_count; /* Halton view samples over the G-buffer; 0: 256; at most 65536 */
    uint32_t frame_index;       /* seeds the rotation of the view samples and the selection */
    int rotate_view_samples;    /* 1: Cranley-Patterson rotate them by gim_rotation_offsets(frame_index) */
    uint32_t val_count;         /* VALs selected per light (paper 000 sec. 4); 0: 2048 */
    float scene_scale;          /* length of the unit-free thresholds; 0: diagonal of the world
                                   bounds of the instances */
    float importance_clamp;     /* eq. 11 clamp in scene scales; 0: 1/64 (see @section importance) */
} gim_frame;

/* Run the frame's passes. Today the shared passes of DESIGN.md sec. 5 and the importance
   sampling of paper 000 sec. 4: RSM per light -> G-buffer (or the host's) -> view samples ->
   per light: importance map (eq. 10-11) -> cumulative sums (eq. 12) -> selection of val_count
   VALs. Needs at least one instance; every material id of an instanced mesh must be below the
   material count. */
GIMANY_API gim_result gim_update(gim_context *ctx, const gim_frame *frame);

/* What one light's passes wrote (GL names; valid until the next gim_update or gim_set_lights). */
typedef struct gim_light_outputs {
    uint32_t rsm_size;
    uint32_t rsm_position;      /* RGBA32F: world xyz; w = 1 where the texel is a VAL (lit) */
    uint32_t rsm_normal;        /* RGBA32F: unit normal towards the light; w = footprint area A */
    uint32_t rsm_flux;          /* RGBA32F: reflected flux Phi rgb (units in @section twins) */
    uint32_t rsm_depth;         /* DEPTH_COMPONENT32F */
    gim_mat4 view, proj;        /* the light's camera (gim_light_camera) */
    uint32_t importance;        /* SSBO: rsm_size^2 floats, eq. 10-11, row-major, row 0 first */
    uint32_t column, row;       /* SSBOs: the eq. 12 tables in double (gim_importance_cumsum's) */
    uint32_t selected;          /* SSBO: selected_count gim_selected_val {x, y, pdf} */
    uint32_t selected_count;
} gim_light_outputs;

/* Everything the last successful gim_update left for the host and for later passes. */
typedef struct gim_frame_outputs {
    int valid;                  /* 0 before the first successful gim_update, or after a failed one */
    uint32_t width, height;
    uint32_t gbuffer_depth;     /* DEPTH_COMPONENT32F (or the host's) */
    uint32_t gbuffer_normal;    /* RGBA16F world normal towards the eye, w = 1 where drawn (or the host's) */
    uint32_t gbuffer_albedo;    /* RGBA8 diffuse albedo, clamped to [0, 1] (0 with the host's G-buffer) */
    uint32_t view_samples;      /* SSBO: view_sample_count {vec4 position; vec4 normal} */
    uint32_t view_sample_count;
    float scene_scale;
    float bounds_min[3], bounds_max[3]; /* world bounds of the instances */
    uint32_t light_count;
    gim_light_outputs lights[GIM_MAX_LIGHTS];
} gim_frame_outputs;

/* The outputs of the last gim_update (all zero for NULL). */
GIMANY_API gim_frame_outputs gim_outputs(const gim_context *ctx);

#ifdef __cplusplus
}
#endif
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

/* The digit loop with base as a literal, so the compiler turns / and % into multiplies. */
#define GIM__RADICAL_INVERSE_LOOP(B)                                                         \
    while (index) {                                                                          \
        uint32_t q = index / (B);                                                            \
        num = num * (B) + (index - q * (B));                                                 \
        den *= (B);                                                                          \
        index = q;                                                                           \
    }

GIMANY_DEF double gim_radical_inverse(uint32_t base, uint32_t index) {
    /* Reverse the digits into an integer numerator over base^digits. For base <= 65535 and
       index < 2^32 both stay below 2^53 (base^digits < base * 2^32 <= 2^48), so the one
       division is correctly rounded: exact, with no drift along the index. */
    uint64_t num = 0, den = 1;
    switch (base) {
    case 2: return gim_van_der_corput(index);
    case 3: GIM__RADICAL_INVERSE_LOOP(3u) break;
    case 5: GIM__RADICAL_INVERSE_LOOP(5u) break;
    case 7: GIM__RADICAL_INVERSE_LOOP(7u) break;
    case 11: GIM__RADICAL_INVERSE_LOOP(11u) break;
    case 13: GIM__RADICAL_INVERSE_LOOP(13u) break;
    default:
        if (base < 2u || base > 65535u) return 0.0;
        GIM__RADICAL_INVERSE_LOOP(base)
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

#define GIM__KMEANS_NONE 0xffffffffu

/* Working state of one gim_kmeans call; positions relative to the anchor (bounds centre). */
typedef struct gim__kmeans {
    uint32_t n, m;
    int dong;              /* 1: Dong's angle term, 0: SSVP's (1 - max(cos, 0)) */
    double wx_s, wa;       /* w_x / scene_scale; w_a (/ pi for Dong) */
    double *p, *nrm, *w;   /* n*3, n*3 unit, n weights */
    double *best;          /* n: distance of each VPL to its cluster, from the last assignment */
    double *cen, *cnrm;    /* m*3 centres (relative), m*3 unit normals */
    double *acc;           /* m * GIM__KMEANS_ACC sums of the update step */
    uint32_t *assign, *count;
} gim__kmeans;

enum { GIM__KMEANS_ACC = 14 }; /* W, sum w p[3], sum w n[3], sum p[3], sum n[3], error */

/* The direction term of the metric for cos = n_i . n_j. */
static double gim__kmeans_dir(const gim__kmeans *k, double c) {
    if (k->dong) return k->wa * acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c)); /* Dong 5.1: angle */
    return k->wa * (1.0 - (c > 0.0 ? c : 0.0));                            /* SSVP eq. 2, slip fixed */
}

/* Assignment step: for each VPL independently, the centre at the smallest distance; it leaves
   its current cluster only for a strictly smaller one. Returns the number of VPLs that moved.
   The position term alone bounds the distance from below (the direction term is >= 0), so a
   centre whose position term already reaches the best is skipped without changing the result. */
static uint32_t gim__kmeans_assign(gim__kmeans *k) {
    uint32_t i, j, moved = 0;
    for (i = 0; i < k->n; ++i) {
        const double *x = k->p + (size_t)i * 3, *nx = k->nrm + (size_t)i * 3;
        uint32_t cur = k->assign[i], arg = cur;
        const double x0 = x[0], x1 = x[1], x2 = x[2], wx_s = k->wx_s;
        double bd = HUGE_VAL, r2 = HUGE_VAL; /* best distance; squared distance of sure losers */
        if (cur != GIM__KMEANS_NONE) {
            const double *c = k->cen + (size_t)cur * 3, *cn = k->cnrm + (size_t)cur * 3;
            double dx = x0 - c[0], dy = x1 - c[1], dz = x2 - c[2];
            bd = wx_s * sqrt(dx * dx + dy * dy + dz * dz) +
                 gim__kmeans_dir(k, nx[0] * cn[0] + nx[1] * cn[1] + nx[2] * cn[2]);
            if (wx_s > 0.0) r2 = (bd / wx_s) * (bd / wx_s) * (1.0 + 1e-9); /* margin: skip only sure losers */
        }
        for (j = 0; j < k->m; ++j) {
            const double *c = k->cen + (size_t)j * 3, *cn;
            double dx = x0 - c[0], dy = x1 - c[1], dz = x2 - c[2];
            double d2 = dx * dx + dy * dy + dz * dz, pos, d;
            if (d2 > r2 || j == cur) continue;
            pos = wx_s * sqrt(d2);
            if (!(pos < bd)) continue;
            cn = k->cnrm + (size_t)j * 3;
            d = pos + gim__kmeans_dir(k, nx[0] * cn[0] + nx[1] * cn[1] + nx[2] * cn[2]);
            if (d < bd) {
                bd = d; arg = j;
                if (wx_s > 0.0) r2 = (bd / wx_s) * (bd / wx_s) * (1.0 + 1e-9);
            }
        }
        if (arg != cur) ++moved;
        k->assign[i] = arg;
        k->best[i] = bd;
    }
    return moved;
}

/* Counts and errors per cluster, then the repair of empty clusters (see the header).
   Returns the number of clusters re-seeded. */
static uint32_t gim__kmeans_repair(gim__kmeans *k) {
    uint32_t i, j, c, repaired = 0;
    double *err = k->acc; /* column 13 of acc holds the error */
    for (j = 0; j < k->m; ++j) { k->count[j] = 0; err[(size_t)j * GIM__KMEANS_ACC + 13] = 0.0; }
    for (i = 0; i < k->n; ++i) {
        k->count[k->assign[i]]++;
        err[(size_t)k->assign[i] * GIM__KMEANS_ACC + 13] += k->best[i];
    }
    for (j = 0; j < k->m; ++j) {
        uint32_t donor = GIM__KMEANS_NONE, far = GIM__KMEANS_NONE;
        double de = -1.0, fd = -1.0;
        if (k->count[j] != 0) continue;
        for (c = 0; c < k->m; ++c) {
            double e = err[(size_t)c * GIM__KMEANS_ACC + 13];
            if (k->count[c] < 2) continue;
            if (donor == GIM__KMEANS_NONE || e > de || (e == de && k->count[c] > k->count[donor])) {
                donor = c; de = e;
            }
        }
        GIMANY_ASSERT(donor != GIM__KMEANS_NONE); /* M <= N: some cluster has two VPLs */
        if (donor == GIM__KMEANS_NONE) break;
        for (i = 0; i < k->n; ++i)
            if (k->assign[i] == donor && k->best[i] > fd) { fd = k->best[i]; far = i; }
        k->assign[far] = j;
        k->count[donor]--; k->count[j] = 1;
        de -= fd;
        err[(size_t)donor * GIM__KMEANS_ACC + 13] = de > 0.0 ? de : 0.0;
        /* it seeds the cluster: the centre moves onto it in the update step */
        k->best[far] = 0.0;
        ++repaired;
    }
    return repaired;
}

/* Update step: per-cluster sums in VPL index order, then weighted means (sec. "Means"). */
static void gim__kmeans_update(gim__kmeans *k) {
    uint32_t i, j;
    int a;
    for (j = 0; j < k->m; ++j) {
        double *s = k->acc + (size_t)j * GIM__KMEANS_ACC;
        for (a = 0; a < 13; ++a) s[a] = 0.0;
    }
    for (i = 0; i < k->n; ++i) {
        double *s = k->acc + (size_t)k->assign[i] * GIM__KMEANS_ACC;
        const double *x = k->p + (size_t)i * 3, *nx = k->nrm + (size_t)i * 3;
        double w = k->w[i];
        s[0] += w;
        for (a = 0; a < 3; ++a) {
            s[1 + a] += w * x[a]; s[4 + a] += w * nx[a];
            s[7 + a] += x[a];     s[10 + a] += nx[a];
        }
    }
    for (j = 0; j < k->m; ++j) {
        const double *s = k->acc + (size_t)j * GIM__KMEANS_ACC;
        double *c = k->cen + (size_t)j * 3, *cn = k->cnrm + (size_t)j * 3;
        int plain = !(s[0] > 0.0); /* all-zero flux: plain mean */
        double wsum = plain ? (double)k->count[j] : s[0], len;
        const double *sp = plain ? s + 7 : s + 1, *sn = plain ? s + 10 : s + 4;
        if (k->count[j] == 0) continue; /* cannot happen after the repair; keep the old centre */
        for (a = 0; a < 3; ++a) c[a] = sp[a] / wsum;
        len = sqrt(sn[0] * sn[0] + sn[1] * sn[1] + sn[2] * sn[2]);
        if (len > 1e-9 * wsum)
            for (a = 0; a < 3; ++a) cn[a] = sn[a] / len;
        /* else the normals cancel: keep the previous normal */
    }
}

/* A VPL's weight in the means: its mean rgb flux. */
static double gim__kmeans_weight(const float *flux, uint32_t i) {
    if (!flux) return 1.0;
    return ((double)flux[(size_t)i * 3] + flux[(size_t)i * 3 + 1] + flux[(size_t)i * 3 + 2]) / 3.0;
}

static int gim__kmeans_cmp2(const void *a, const void *b) {
    const double *u = (const double *)a, *v = (const double *)b;
    if (u[0] != v[0]) return u[0] < v[0] ? -1 : 1;
    if (u[1] != v[1]) return u[1] < v[1] ? -1 : 1;
    return 0;
}

/* Area of the smallest rectangle enclosing the n 2D points pts (sorted in place): convex hull
   (monotone chain) into hull[4 * (n + 1)], then rotating calipers over the hull edges, since
   the smallest rectangle has a side on a hull edge (Freeman and Shapira 1975); O(n log n). */
static double gim__min_area_rect(double *pts, uint32_t n, double *hull) {
    uint32_t i, e, h = 0, lower, a, b, c;
    double best = HUGE_VAL;
    if (n < 3) return 0.0;
    qsort(pts, n, 2 * sizeof(double), gim__kmeans_cmp2);
#define GIM__CROSS(o, p, q) (((p)[0] - (o)[0]) * ((q)[1] - (o)[1]) - ((p)[1] - (o)[1]) * ((q)[0] - (o)[0]))
    for (i = 0; i < n; ++i) {
        while (h >= 2 && GIM__CROSS(hull + 2 * (h - 2), hull + 2 * (h - 1), pts + 2 * i) <= 0.0) --h;
        hull[2 * h] = pts[2 * i]; hull[2 * h + 1] = pts[2 * i + 1]; ++h;
    }
    lower = h + 1;
    for (i = n - 1; i-- > 0;) {
        while (h >= lower && GIM__CROSS(hull + 2 * (h - 2), hull + 2 * (h - 1), pts + 2 * i) <= 0.0) --h;
        hull[2 * h] = pts[2 * i]; hull[2 * h + 1] = pts[2 * i + 1]; ++h;
    }
#undef GIM__CROSS
    --h; /* the last point repeats the first; the hull is counter-clockwise, no collinear points */
    if (h < 3) return 0.0; /* all points on a line (or one point): no area */
    /* for edge e with direction u and inward normal v: b is the point farthest along u, a the
       farthest along v, c the farthest along -u; all three only move forward as e turns */
    b = 1; a = 1; c = 1;
    for (e = 0; e < h; ++e) {
        const double *p0 = hull + 2 * e, *p1 = hull + 2 * ((e + 1) % h);
        double ux = p1[0] - p0[0], uy = p1[1] - p0[1], len = sqrt(ux * ux + uy * uy), area;
        uint32_t steps;
#define GIM__U(k) ((hull[2 * ((k) % h)] - p0[0]) * ux + (hull[2 * ((k) % h) + 1] - p0[1]) * uy)
#define GIM__V(k) ((hull[2 * ((k) % h) + 1] - p0[1]) * ux - (hull[2 * ((k) % h)] - p0[0]) * uy)
        if (!(len > 0.0)) continue;
        ux /= len; uy /= len;
        if (e == 0 || b == e) b = (e + 1) % h;
        for (steps = 0; steps < h && GIM__U(b + 1) > GIM__U(b); ++steps) b = (b + 1) % h;
        if (e == 0 || a == e || a == (e + 1) % h) a = b; /* guards rounding on near-flat hulls */
        for (steps = 0; steps < h && GIM__V(a + 1) > GIM__V(a); ++steps) a = (a + 1) % h;
        if (e == 0) c = a;
        for (steps = 0; steps < h && GIM__U(c + 1) < GIM__U(c); ++steps) c = (c + 1) % h;
        area = (GIM__U(b) - GIM__U(c)) * GIM__V(a);
#undef GIM__U
#undef GIM__V
        if (area < best) best = area;
    }
    return best < HUGE_VAL ? best : 0.0;
}

/* Validate, allocate, iterate, write the outputs. */
GIMANY_DEF gim_result gim_kmeans(const gim_kmeans_desc *desc, gim_kmeans_result *result) {
    static const char *fn = "gim_kmeans";
    const gim_env *env = desc ? &desc->env : NULL;
    gim__kmeans k;
    uint32_t n, m, i, j, it, max_it, repaired = 0;
    double lo[3], hi[3], anchor[3], diag, scale, wx, wa, fsum[3] = {0.0, 0.0, 0.0};
    int a, warm, want_area;
    size_t off[12], total = 0, sz[12];
    unsigned char *mem;
    double *pts = NULL, *hull = NULL;
    uint32_t *order = NULL, *start = NULL;

    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc is NULL");
    if (!result) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "result is NULL");
    if (!result->centres || !result->normals)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "result->centres and result->normals are required");
    if (!desc->positions || !desc->normals)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "positions and normals are required");
    n = desc->vpl_count; m = desc->cluster_count;
    if (n == 0 || m == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "vpl_count (%u) and cluster_count (%u) must be > 0", n, m);
    if (m > n) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "cluster_count %u > vpl_count %u: every cluster needs a VPL", m, n);
    if ((unsigned)desc->metric > (unsigned)GIM_KMEANS_METRIC_SSVP)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "unknown metric %d", (int)desc->metric);
    if ((unsigned)desc->init > (unsigned)GIM_KMEANS_INIT_WARM)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "unknown init %d", (int)desc->init);
    warm = desc->init == GIM_KMEANS_INIT_WARM;
    if (warm && (!desc->init_centres || !desc->init_normals))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "warm start needs init_centres and init_normals");
    if (!gim__isfinitef(desc->w_x) || !gim__isfinitef(desc->w_a) || desc->w_x < 0.0f || desc->w_a < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "weights w_x %g, w_a %g must be finite and >= 0", (double)desc->w_x, (double)desc->w_a);
    if (!gim__isfinitef(desc->scene_scale) || desc->scene_scale < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale %g must be finite and >= 0", (double)desc->scene_scale);
    if (desc->max_iterations > 4096)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "max_iterations %u > 4096", desc->max_iterations);
    max_it = desc->max_iterations ? desc->max_iterations : 16;

    for (a = 0; a < 3; ++a) { lo[a] = HUGE_VAL; hi[a] = -HUGE_VAL; }
    for (i = 0; i < n; ++i) {
        const float *x = desc->positions + (size_t)i * 3, *nx = desc->normals + (size_t)i * 3;
        if (!gim__all_finite(x, 3)) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "position of VPL %u is not finite", i);
        if (!gim__all_finite(nx, 3)) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "normal of VPL %u is not finite", i);
        if (nx[0] == 0.0f && nx[1] == 0.0f && nx[2] == 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "normal of VPL %u is zero", i);
        for (a = 0; a < 3; ++a) {
            if (x[a] < lo[a]) lo[a] = x[a];
            if (x[a] > hi[a]) hi[a] = x[a];
        }
        if (desc->flux) {
            const float *f = desc->flux + (size_t)i * 3;
            if (!gim__all_finite(f, 3) || f[0] < 0.0f || f[1] < 0.0f || f[2] < 0.0f)
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "flux of VPL %u must be finite and >= 0", i);
            for (a = 0; a < 3; ++a) fsum[a] += f[a];
        }
    }
    if (fsum[0] > FLT_MAX || fsum[1] > FLT_MAX || fsum[2] > FLT_MAX)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "the summed flux exceeds the float range");
    diag = 0.0;
    for (a = 0; a < 3; ++a) { anchor[a] = 0.5 * (lo[a] + hi[a]); diag += (hi[a] - lo[a]) * (hi[a] - lo[a]); }
    diag = sqrt(diag);
    if (diag * diag > FLT_MAX) /* areas must fit in a float */
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "VPL bounds diagonal %g exceeds 1.8e19", diag);
    if (warm)
        for (j = 0; j < m; ++j) {
            const float *nx = desc->init_normals + (size_t)j * 3;
            if (!gim__all_finite(desc->init_centres + (size_t)j * 3, 3) || !gim__all_finite(nx, 3))
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "init centre or normal %u is not finite", j);
            if (nx[0] == 0.0f && nx[1] == 0.0f && nx[2] == 0.0f)
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "init normal %u is zero", j);
        }
    /* all VPLs at one point: any unit will do, the position term is zero for them */
    scale = desc->scene_scale > 0.0f ? (double)desc->scene_scale : (diag > 0.0 ? diag : 1.0);
    wx = desc->w_x; wa = desc->w_a;
    if (wx == 0.0 && wa == 0.0) {
        int ssvp = desc->metric == GIM_KMEANS_METRIC_SSVP;
        wx = ssvp ? 0.6 : 0.7; wa = ssvp ? 0.4 : 0.3;
    }

    /* one block: doubles first, then uint32 arrays */
    want_area = result->area != NULL;
    sz[0] = gim__array_size(n, 3 * sizeof(double));            /* p */
    sz[1] = sz[0];                                             /* nrm */
    sz[2] = gim__array_size(n, sizeof(double));                /* w */
    sz[3] = sz[2];                                             /* best */
    sz[4] = gim__array_size(m, 3 * sizeof(double));            /* cen */
    sz[5] = sz[4];                                             /* cnrm */
    sz[6] = gim__array_size(m, GIM__KMEANS_ACC * sizeof(double)); /* acc */
    sz[7] = want_area ? gim__array_size((size_t)n + 1, 6 * sizeof(double)) : 0; /* pts, hull (2n+2 points) */
    sz[8] = gim__array_size(n, sizeof(uint32_t));              /* assign */
    sz[9] = gim__array_size((size_t)m + 1, sizeof(uint32_t));  /* count */
    sz[10] = want_area ? sz[8] : 0;                            /* order */
    sz[11] = want_area ? sz[9] : 0;                            /* start */
    for (j = 0; j < 12; ++j) {
        if ((sz[j] == 0 && j != 7 && j < 10) || total > (size_t)-1 - sz[j] - 16)
            return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "size overflow for %u VPLs", n);
        off[j] = total;
        total += (sz[j] + 7) & ~(size_t)7;
    }
    mem = (unsigned char *)gim__alloc(env, total);
    if (!mem) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "%lu bytes for %u VPLs", (unsigned long)total, n);
    k.n = n; k.m = m;
    k.dong = desc->metric != GIM_KMEANS_METRIC_SSVP;
    k.wx_s = wx / scale;
    k.wa = k.dong ? wa / 3.14159265358979323846 : wa;
    k.p = (double *)(void *)(mem + off[0]);
    k.nrm = (double *)(void *)(mem + off[1]);
    k.w = (double *)(void *)(mem + off[2]);
    k.best = (double *)(void *)(mem + off[3]);
    k.cen = (double *)(void *)(mem + off[4]);
    k.cnrm = (double *)(void *)(mem + off[5]);
    k.acc = (double *)(void *)(mem + off[6]);
    k.assign = (uint32_t *)(void *)(mem + off[8]);
    k.count = (uint32_t *)(void *)(mem + off[9]);
    if (want_area) {
        pts = (double *)(void *)(mem + off[7]);
        hull = pts + 2 * ((size_t)n + 1);
        order = (uint32_t *)(void *)(mem + off[10]);
        start = (uint32_t *)(void *)(mem + off[11]);
    }

    /* VPLs relative to the anchor, unit normals, weights; zero flux everywhere -> weights 1 */
    for (i = 0; i < n; ++i) {
        const float *x = desc->positions + (size_t)i * 3, *nx = desc->normals + (size_t)i * 3;
        double len = sqrt((double)nx[0] * nx[0] + (double)nx[1] * nx[1] + (double)nx[2] * nx[2]);
        for (a = 0; a < 3; ++a) {
            k.p[(size_t)i * 3 + a] = (double)x[a] - anchor[a];
            k.nrm[(size_t)i * 3 + a] = nx[a] / len;
        }
        k.w[i] = gim__kmeans_weight(desc->flux, i);
        k.assign[i] = GIM__KMEANS_NONE;
    }
    /* seeds: Dong 6 (VPL k*N/M is cluster k's first centre) or the previous frame's centres */
    for (j = 0; j < m; ++j) {
        if (warm) {
            const float *c = desc->init_centres + (size_t)j * 3, *cn = desc->init_normals + (size_t)j * 3;
            double len = sqrt((double)cn[0] * cn[0] + (double)cn[1] * cn[1] + (double)cn[2] * cn[2]);
            for (a = 0; a < 3; ++a) {
                k.cen[(size_t)j * 3 + a] = (double)c[a] - anchor[a];
                k.cnrm[(size_t)j * 3 + a] = cn[a] / len;
            }
        } else {
            size_t s = (size_t)((uint64_t)j * n / m);
            for (a = 0; a < 3; ++a) {
                k.cen[(size_t)j * 3 + a] = k.p[s * 3 + a];
                k.cnrm[(size_t)j * 3 + a] = k.nrm[s * 3 + a];
            }
        }
    }

    /* Lloyd iteration: assign, repair, update; converged when an assignment moves no VPL */
    for (it = 1;; ++it) {
        uint32_t moved = gim__kmeans_assign(&k);
        if (it > 1 && moved == 0) break;
        repaired += gim__kmeans_repair(&k);
        gim__kmeans_update(&k);
        if (it >= max_it) break;
    }

    /* outputs: flux, sigma (two-pass, about the final centres), then area; nothing can fail now */
    for (j = 0; j < m; ++j) {
        double *s = k.acc + (size_t)j * GIM__KMEANS_ACC;
        for (a = 0; a < 13; ++a) s[a] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        uint32_t c = k.assign[i];
        double *s = k.acc + (size_t)c * GIM__KMEANS_ACC;
        double w = k.w[i];
        s[0] += w;
        for (a = 0; a < 3; ++a) {
            double d = k.p[(size_t)i * 3 + a] - k.cen[(size_t)c * 3 + a];
            s[1 + a] += w * d * d;
            s[4 + a] += d * d;
            if (desc->flux) s[7 + a] += desc->flux[(size_t)i * 3 + a];
        }
    }
    for (j = 0; j < m; ++j) {
        const double *s = k.acc + (size_t)j * GIM__KMEANS_ACC;
        int plain = !(s[0] > 0.0);
        double wsum = plain ? (double)k.count[j] : s[0];
        for (a = 0; a < 3; ++a) {
            result->centres[(size_t)j * 3 + a] = (float)(k.cen[(size_t)j * 3 + a] + anchor[a]);
            result->normals[(size_t)j * 3 + a] = (float)k.cnrm[(size_t)j * 3 + a];
            if (result->flux) result->flux[(size_t)j * 3 + a] = (float)s[7 + a];
            if (result->sigma) result->sigma[(size_t)j * 3 + a] = (float)sqrt((plain ? s[4 + a] : s[1 + a]) / wsum);
        }
    }
    if (result->counts) memcpy(result->counts, k.count, (size_t)m * sizeof(uint32_t));
    if (result->assignment) memcpy(result->assignment, k.assign, (size_t)n * sizeof(uint32_t));
    if (want_area) {
        /* counting sort of the VPLs that emit (all of a cluster's when it has no flux) by
           cluster, then each cluster's points in the plane of its normal */
#define GIM__EMITS(i) (k.w[i] > 0.0 || !(k.acc[(size_t)k.assign[i] * GIM__KMEANS_ACC] > 0.0))
        for (j = 0; j <= m; ++j) start[j] = 0;
        for (i = 0; i < n; ++i) if (GIM__EMITS(i)) start[k.assign[i] + 1]++;
        for (j = 0; j < m; ++j) start[j + 1] += start[j];
        for (i = 0; i < n; ++i) if (GIM__EMITS(i)) order[start[k.assign[i]]++] = i;
#undef GIM__EMITS
        for (j = m; j > 0; --j) start[j] = start[j - 1];
        start[0] = 0;
        for (j = 0; j < m; ++j) {
            const double *c = k.cen + (size_t)j * 3, *cn = k.cnrm + (size_t)j * 3;
            /* tangent frame (Duff et al. 2017); the rectangle does not depend on its rotation */
            double sg = cn[2] >= 0.0 ? 1.0 : -1.0, q = -1.0 / (sg + cn[2]), r = cn[0] * cn[1] * q;
            double t[3], b[3];
            uint32_t cnt = start[j + 1] - start[j], e;
            t[0] = 1.0 + sg * cn[0] * cn[0] * q; t[1] = sg * r; t[2] = -sg * cn[0];
            b[0] = r; b[1] = sg + cn[1] * cn[1] * q; b[2] = -cn[1];
            for (e = 0; e < cnt; ++e) {
                const double *x = k.p + (size_t)order[start[j] + e] * 3;
                double d0 = x[0] - c[0], d1 = x[1] - c[1], d2 = x[2] - c[2];
                pts[2 * e] = d0 * t[0] + d1 * t[1] + d2 * t[2];
                pts[2 * e + 1] = d0 * b[0] + d1 * b[1] + d2 * b[2];
            }
            result->area[j] = (float)gim__min_area_rect(pts, cnt, hull);
        }
    }
    result->iterations = it;
    result->empty_repaired = repaired;
    gim__free(env, mem);
    return GIM_OK;
}

/* @impl caches ============================================================================ */
/* generator: voxels, normal bins, averaging, snapping, merging, area partition */

/* neighbours: spatial grid, per-vertex nearest compatible caches */

/* blobs: versioned, checksummed serialisation */

/* @impl importance ======================================================================== */

#define GIM__IMPORTANCE_DEFAULT_CLAMP (1.0f / 64.0f)

/* eq. 10-11 for one texel; vs holds 6 doubles per view sample: position / scene_scale and a
   unit normal (zero for a sample that sees nothing). Per texel independent: a GPU thread. */
static float gim__importance_texel(const float *p, const float *nrm, const float *flux,
                                   const double *vs, uint32_t vs_count, double inv_scale, double clamp2) {
    double nx, ny, nz, len, px, py, pz, phi, sum = 0.0, r;
    uint32_t j;
    if (!gim__all_finite(p, 3) || !gim__all_finite(nrm, 3) || !gim__all_finite(flux, 3)) return 0.0f;
    phi = gim_v3_luminance(gim_v3(flux[0], flux[1], flux[2]));
    if (!(phi > 0.0)) return 0.0f;                 /* black, or negative (non-physical) flux */
    if (phi > FLT_MAX) phi = FLT_MAX;              /* the float luminance of huge rgb overflowed */
    len = sqrt((double)nrm[0] * nrm[0] + (double)nrm[1] * nrm[1] + (double)nrm[2] * nrm[2]);
    if (!(len > 0.0)) return 0.0f;
    nx = nrm[0] / len; ny = nrm[1] / len; nz = nrm[2] / len;
    px = p[0] * inv_scale; py = p[1] * inv_scale; pz = p[2] * inv_scale;
    for (j = 0; j < vs_count; ++j) {
        const double *s = vs + (size_t)j * 6u;
        double mx = s[0] - px, my = s[1] - py, mz = s[2] - pz;   /* l in scene scales */
        double d2 = mx * mx + my * my + mz * mz;
        double cl = nx * mx + ny * my + nz * mz;                 /* (n_l . d)+ |l| */
        double cv = -(s[3] * mx + s[4] * my + s[5] * mz);        /* (n_VS . -d)+ |l| */
        cl = cl > 0.0 ? cl : 0.0;
        cv = cv > 0.0 ? cv : 0.0;
        /* cos cos / max(d2, clamp^2) = cl cv / (d2 max(d2, clamp^2)); cl cv <= d2, so a sample
           at the texel itself (d2 = 0, cl = cv = 0) gives 0 through the DBL_MIN guard */
        sum += cl * cv / ((d2 > clamp2 ? d2 : clamp2) * (d2 > DBL_MIN ? d2 : DBL_MIN));
    }
    r = phi * sum / (double)vs_count;
    return r < FLT_MAX ? (float)r : FLT_MAX;
}

GIMANY_DEF gim_result gim_importance_map(const gim_importance_desc *desc, float *out) {
    static const char fn[] = "gim_importance_map";
    const gim_env *env;
    size_t texels, i;
    uint32_t j, unusable = 0;
    double *vs, inv_scale, clamp;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT; /* no env to log through */
    env = &desc->env;
    if (!out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "out is NULL");
    if (!desc->rsm_position || !desc->rsm_normal || !desc->rsm_flux)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm_position, rsm_normal and rsm_flux are required");
    if (desc->width == 0 || desc->height == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "RSM size %ux%u is empty",
                         (unsigned)desc->width, (unsigned)desc->height);
    texels = gim__array_size(desc->width, desc->height);
    if (texels == 0 || gim__array_size(texels, 3u * sizeof(float)) == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "RSM size %ux%u overflows size_t",
                         (unsigned)desc->width, (unsigned)desc->height);
    if (!desc->view_samples || desc->view_sample_count == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no view samples");
    if (!(desc->scene_scale > 0.0f) || !gim__isfinitef(desc->scene_scale))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale %g must be finite and > 0",
                         (double)desc->scene_scale);
    clamp = desc->clamp == 0.0f ? GIM__IMPORTANCE_DEFAULT_CLAMP : desc->clamp;
    if (!(clamp > 0.0) || !gim__isfinitef((float)clamp))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "clamp %g must be finite and > 0 (0: default)",
                         (double)desc->clamp);
    vs = (double *)gim__alloc_array(env, desc->view_sample_count, 6u * sizeof(double));
    if (!vs) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "%u view samples", (unsigned)desc->view_sample_count);
    /* view samples once: scaled positions, unit normals; unusable ones see nothing */
    inv_scale = 1.0 / (double)desc->scene_scale;
    for (j = 0; j < desc->view_sample_count; ++j) {
        gim_view_sample s = desc->view_samples[j];
        double *o = vs + (size_t)j * 6u;
        double len = sqrt((double)s.normal.x * s.normal.x + (double)s.normal.y * s.normal.y +
                          (double)s.normal.z * s.normal.z);
        if (!gim_v3_isfinite(s.position) || !gim_v3_isfinite(s.normal) || !(len > 0.0) || len > DBL_MAX) {
            o[0] = o[1] = o[2] = o[3] = o[4] = o[5] = 0.0;
            ++unusable;
            continue;
        }
        o[0] = s.position.x * inv_scale; o[1] = s.position.y * inv_scale; o[2] = s.position.z * inv_scale;
        o[3] = s.normal.x / len; o[4] = s.normal.y / len; o[5] = s.normal.z / len;
    }
    if (unusable)
        gim__log(env, GIM_LOG_WARNING, fn, "%u of %u view samples are NaN/Inf or have a zero normal; they see nothing",
                 (unsigned)unusable, (unsigned)desc->view_sample_count);
    for (i = 0; i < texels; ++i) {
        if (desc->rsm_valid && !(desc->rsm_valid[i] > 0.0f)) { out[i] = 0.0f; continue; }
        out[i] = gim__importance_texel(desc->rsm_position + i * 3u, desc->rsm_normal + i * 3u,
                                       desc->rsm_flux + i * 3u, vs, desc->view_sample_count,
                                       inv_scale, clamp * clamp);
    }
    gim__free(env, vs);
    return GIM_OK;
}

/* Table size checks shared by cumsum and select. */
static gim_result gim__importance_tables_check(const gim_env *env, const char *fn, uint32_t width, uint32_t height) {
    size_t texels;
    if (width == 0 || height == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "map size %ux%u is empty", (unsigned)width, (unsigned)height);
    texels = gim__array_size(width, height);
    if (texels == 0 || gim__array_size(texels, sizeof(double)) == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "map size %ux%u overflows size_t",
                         (unsigned)width, (unsigned)height);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_importance_cumsum(const float *map, uint32_t width, uint32_t height,
                                            double *column, double *row, gim_env env) {
    static const char fn[] = "gim_importance_cumsum";
    uint32_t x, y;
    double acc;
    gim_result r;
    if (!map || !column || !row) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "map, column and row are required");
    r = gim__importance_tables_check(&env, fn, width, height);
    if (r != GIM_OK) return r;
    /* eq. 12, vertical: every column an independent sequential scan from row 0 down (one GPU
       thread or scan per column; y outer here only for the cache). Doubles: a column of 4096
       floats sums with a relative error near 4096 * 2^-53 instead of 4096 * 2^-24. */
    for (y = 0; y < height; ++y) {
        const float *m = map + (size_t)y * width;
        double *c = column + (size_t)y * width;
        const double *above = y ? c - width : NULL;
        for (x = 0; x < width; ++x) {
            float v = m[x];
            if (!(v >= 0.0f && v <= FLT_MAX))
                return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "map(%u, %u) = %g is not finite and >= 0",
                                 (unsigned)x, (unsigned)y, (double)v);
            c[x] = above ? above[x] + (double)v : (double)v;
        }
    }
    /* eq. 12, horizontal: one scan along the column totals (the last row) */
    acc = 0.0;
    for (x = 0; x < width; ++x) {
        acc += column[(size_t)(height - 1u) * width + x];
        row[x] = acc;
    }
    return GIM_OK;
}

/* First index k in [0, n) with a[k * stride] > t, for t < a[(n-1) * stride] (so k < n). Branch
   free (the compare becomes a select), so independent searches overlap in the pipeline.
   When k > 0, a[k-1] <= t was seen, so a[k] - a[k-1] > 0 for a monotone table; a NaN met on
   the way shows up as a NaN difference, which the caller rejects. */
static uint32_t gim__first_above(const double *a, size_t stride, uint32_t n, double t) {
    uint32_t base = 0;
    while (n > 1u) {
        uint32_t half = n / 2u;
#if defined(__GNUC__) || defined(__clang__)
        /* both possible next probes: large strided tables are bound by memory latency */
        __builtin_prefetch(a + (size_t)(base + (n - half) / 2u) * stride);
        __builtin_prefetch(a + (size_t)(base + half + (n - half) / 2u) * stride);
#endif
        base = a[(size_t)(base + half) * stride] <= t ? base + half : base;
        n -= half;
    }
    return base + (a[(size_t)base * stride] <= t ? 1u : 0u);
}

/* The largest double below total, for u * total rounding up to total. */
static double gim__below(double t, double total) {
    return t < total ? t : nextafter(total, 0.0);
}

GIMANY_DEF gim_result gim_importance_select(const double *column, const double *row,
                                            uint32_t width, uint32_t height, uint32_t count,
                                            uint32_t seed, gim_selected_val *out, gim_env env) {
    static const char fn[] = "gim_importance_select";
    const double *totals; /* the last row of column: per-column totals */
    double total, prev, o0, o1;
    float off[4];
    uint32_t i, x;
    gim_result r;
    if (!column || !row || !out) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "column, row and out are required");
    if (count == 0) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "count is 0");
    r = gim__importance_tables_check(&env, fn, width, height);
    if (r != GIM_OK) return r;
    totals = column + (size_t)(height - 1u) * width;
    /* O(width) check of what every search relies on; the interior of the columns is checked
       per sample (a NaN there shows as a non-positive difference) */
    for (x = 0, prev = 0.0; x < width; ++x) {
        if (!(row[x] >= prev && row[x] <= DBL_MAX) || !(totals[x] >= 0.0 && totals[x] <= DBL_MAX) ||
            (row[x] > prev && !(totals[x] > 0.0)))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "tables are not cumulative sums at column %u (row %g, column total %g)",
                             (unsigned)x, row[x], totals[x]);
        prev = row[x];
    }
    total = row[width - 1u];
    /* 48-bit Cranley-Patterson offsets, two 24-bit ones per dimension: over all seeds u_i
       only takes values on the offsets' lattice, so with 24 bits a column holding less than
       2^-24 of the total would be picked with the wrong frequency (never, or far too often) */
    gim_rotation_offsets(off, 4u, seed);
    o0 = (double)off[0] + (double)off[2] * (1.0 / 16777216.0);
    o1 = (double)off[1] + (double)off[3] * (1.0 / 16777216.0);
    if (!(total > 0.0))
        gim__log(&env, GIM_LOG_WARNING, fn, "the importance map is all zero: %u texels selected uniformly",
                 (unsigned)count);
    for (i = 0; i < count; ++i) {
        double u = (double)i / (double)count + o0, v = gim_van_der_corput(i) + o1;
        uint32_t sx, sy;
        u = u < 1.0 ? u : u - 1.0;
        v = v < 1.0 ? v : v - 1.0;
        if (!(total > 0.0)) { /* documented fallback: uniform, pdf 1 / texels */
            sx = (uint32_t)(u * width); sy = (uint32_t)(v * height);
            out[i].x = sx < width ? sx : width - 1u;
            out[i].y = sy < height ? sy : height - 1u;
            out[i].pdf = (float)(1.0 / ((double)width * (double)height));
            continue;
        }
        {
            double col_total, p_col, p_row, p;
            sx = gim__first_above(row, 1u, width, gim__below(u * total, total));
            col_total = totals[sx];
            sy = gim__first_above(column + sx, width, height, gim__below(v * col_total, col_total));
            p_col = (row[sx] - (sx ? row[sx - 1u] : 0.0)) / total;
            p_row = (column[(size_t)sy * width + sx] - (sy ? column[(size_t)(sy - 1u) * width + sx] : 0.0)) / col_total;
            p = p_col * p_row;
            if (!(p > 0.0 && p <= 1.0))
                return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn,
                                 "column %u of the tables is not a cumulative sum (texel %u has P = %g)",
                                 (unsigned)sx, (unsigned)sy, p);
            out[i].x = sx;
            out[i].y = sy;
            out[i].pdf = p > FLT_MIN ? (float)p : FLT_MIN;
        }
    }
    return GIM_OK;
}

/* @impl twins ============================================================================= */

/* twins of the scene passes: RSM texel, G-buffer, view samples ---------------------------- */

/* A light the runtime and the twins accept; index names it in the message. */
static gim_result gim__light_check(const gim_light *l, const gim_env *env, const char *where, uint32_t index) {
    if (l->type != GIM_LIGHT_DEFAULT && l->type != GIM_LIGHT_DIRECTIONAL && l->type != GIM_LIGHT_SPOT)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: unknown type %d", (unsigned)index, (int)l->type);
    if (!gim__all_finite(l->color, 3) || l->color[0] < 0.0f || l->color[1] < 0.0f || l->color[2] < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: color must be finite and >= 0", (unsigned)index);
    if (!gim_v3_isfinite(l->direction) || gim_v3_length(gim_v3_normalize(l->direction)) == 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: direction must be finite and non-zero",
                         (unsigned)index);
    if (l->rsm_size > 16384u)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: rsm_size %u above 16384", (unsigned)index,
                         (unsigned)l->rsm_size);
    if (l->type == GIM_LIGHT_SPOT) {
        if (!gim__isfinitef(l->intensity) || l->intensity < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: intensity %g must be finite and >= 0",
                             (unsigned)index, (double)l->intensity);
        if (!gim_v3_isfinite(l->position))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: position is not finite", (unsigned)index);
        if (!(l->cone_angle > 0.0f && l->cone_angle <= 1.5f))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: cone_angle %g outside (0, 1.5] radians",
                             (unsigned)index, (double)l->cone_angle);
    } else {
        if (!gim__isfinitef(l->irradiance) || l->irradiance < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: irradiance %g must be finite and >= 0",
                             (unsigned)index, (double)l->irradiance);
        if (!gim__isfinitef(l->extent) || l->extent < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: extent %g must be finite and >= 0",
                             (unsigned)index, (double)l->extent);
    }
    return GIM_OK;
}

/* min(a, b) where a may be +inf: the twins' outputs stay finite, as the shaders' do */
static double gim__min_d(double a, double b) { return a < b ? a : b; }

static uint32_t gim__light_rsm_size(const gim_light *l) { return l->rsm_size ? l->rsm_size : 512u; }

/* The light's colour times its power: E for the sun, I for the spot (all-zero colour: white). */
static void gim__light_power(const gim_light *l, float out[3]) {
    int white = l->color[0] == 0.0f && l->color[1] == 0.0f && l->color[2] == 0.0f, i;
    float p = l->type == GIM_LIGHT_SPOT ? l->intensity : l->irradiance;
    for (i = 0; i < 3; ++i) out[i] = (white ? 1.0f : l->color[i]) * p;
}

/* World axis least aligned with d: an up vector look_at cannot fold onto d. */
static gim_vec3 gim__up_for(gim_vec3 d) {
    float ax = fabsf(d.x), ay = fabsf(d.y), az = fabsf(d.z);
    if (ay <= ax && ay <= az) return gim_v3(0.0f, 1.0f, 0.0f);
    if (az <= ax) return gim_v3(0.0f, 0.0f, 1.0f);
    return gim_v3(1.0f, 0.0f, 0.0f);
}

GIMANY_DEF gim_result gim_light_camera(const gim_light *light, const float bmin[3], const float bmax[3],
                                       gim_mat4 *view, gim_mat4 *proj) {
    static const char where[] = "gim_light_camera";
    double c[3], radius = 0.0;
    gim_result r;
    int i;
    if (!light || !bmin || !bmax || !view || !proj)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL argument");
    r = gim__light_check(light, NULL, where, 0);
    if (r != GIM_OK) return r;
    for (i = 0; i < 3; ++i) {
        double h = 0.5 * ((double)bmax[i] - (double)bmin[i]);
        if (!gim__isfinitef(bmin[i]) || !gim__isfinitef(bmax[i]) || !(h >= 0.0))
            return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "bounds not finite or min > max");
        c[i] = 0.5 * ((double)bmin[i] + (double)bmax[i]);
        radius += h * h;
    }
    radius = sqrt(radius);
    if (!(radius > 0.0) || radius > 1e30)
        return gim__fail(NULL, GIM_ERROR_OUT_OF_RANGE, where, "scene bounds of radius %g", radius);
    if (light->type == GIM_LIGHT_SPOT) {
        gim_vec3 p = light->position, d = gim_v3_normalize(light->direction);
        double far_d = 0.0, box = 0.0, near_d;
        int k;
        for (k = 0; k < 8; ++k) { /* the farthest corner bounds every depth */
            double dx = ((k & 1) ? bmax[0] : bmin[0]) - (double)p.x, dy = ((k & 2) ? bmax[1] : bmin[1]) - (double)p.y,
                   dz = ((k & 4) ? bmax[2] : bmin[2]) - (double)p.z, dd = sqrt(dx * dx + dy * dy + dz * dz);
            if (dd > far_d) far_d = dd;
        }
        for (i = 0; i < 3; ++i) { /* distance from the light to the box (0 inside) */
            double pv = i == 0 ? p.x : i == 1 ? p.y : p.z, e = 0.0;
            if (pv < bmin[i]) e = bmin[i] - pv;
            else if (pv > bmax[i]) e = pv - bmax[i];
            box += e * e;
        }
        /* a lit point at distance >= box within the cone has view depth >= box cos(cone) */
        far_d *= 1.01;
        near_d = sqrt(box) * cos((double)light->cone_angle) * 0.99;
        if (near_d < far_d * 1e-4) near_d = far_d * 1e-4;
        *view = gim_mat4_look_at(p, gim_v3_add(p, d), gim__up_for(d));
        *proj = gim_mat4_perspective(2.0f * light->cone_angle, 1.0f, (float)near_d, (float)far_d);
    } else {
        gim_vec3 l = gim_v3_normalize(light->direction);
        gim_vec3 centre = gim_v3((float)c[0], (float)c[1], (float)c[2]);
        float e = light->extent > 0.0f ? light->extent : (float)radius, R = (float)radius;
        /* the eye 2R out along the light: the bounds' sphere lies between depths R and 3R */
        *view = gim_mat4_look_at(gim_v3_add(centre, gim_v3_scale(l, 2.0f * R)), centre, gim__up_for(l));
        *proj = gim_mat4_ortho(-e, e, -e, e, 0.5f * R, 3.5f * R);
    }
    if (!gim_mat4_isfinite(*view) || !gim_mat4_isfinite(*proj))
        return gim__fail(NULL, GIM_ERROR_OUT_OF_RANGE, where, "the light's camera is not finite");
    return GIM_OK;
}

/* m * (x, y, z, w) in double. */
static void gim__mat4_apply_d(const gim_mat4 *m, const double v[4], double out[4]) {
    int r;
    for (r = 0; r < 4; ++r)
        out[r] = m->m[r] * v[0] + m->m[4 + r] * v[1] + m->m[8 + r] * v[2] + m->m[12 + r] * v[3];
}

/* Nearest hit of the ray through the centre of pixel (x, y) of a width x height view with
   view * proj. Returns 1 on a hit between the near and far planes, 0 on none, -1 when the
   camera's rays or the hit leave the float range (a degenerate camera); p: hit point, n: the
   interpolated normal normalised and turned towards the ray's origin, toward: unit vector to
   the eye (or the light), depth: window depth. */
typedef struct gim__twin_hit {
    double p[3], n[3], toward[3], depth, ndc[2];
    uint32_t triangle;
} gim__twin_hit;

static int gim__twin_cast(const gim_twin_scene *s, gim_mat4 view, gim_mat4 proj, uint32_t width, uint32_t height,
                          uint32_t x, uint32_t y, gim__twin_hit *h) {
    gim_mat4 vp = gim_mat4_mul(proj, view), inv;
    double a[4], b[4], o[3], d[3], best = 2.0, bu = 0.0, bv = 0.0, len, clip[4], hp[4];
    uint32_t t, best_t = UINT32_MAX;
    int i;
    memset(h, 0, sizeof *h);
    h->triangle = UINT32_MAX;
    h->depth = 1.0;
    h->ndc[0] = (2.0 * x + 1.0) / width - 1.0;
    h->ndc[1] = (2.0 * y + 1.0) / height - 1.0;
    if (!gim_mat4_invert(vp, &inv)) return 0;
    a[0] = b[0] = h->ndc[0];
    a[1] = b[1] = h->ndc[1];
    a[2] = -1.0; b[2] = 1.0;
    a[3] = b[3] = 1.0;
    gim__mat4_apply_d(&inv, a, clip); for (i = 0; i < 3; ++i) o[i] = clip[i] / clip[3];
    gim__mat4_apply_d(&inv, b, clip); for (i = 0; i < 3; ++i) d[i] = clip[i] / clip[3] - o[i];
    for (t = 0; t < s->triangle_count; ++t) { /* Moller-Trumbore, t in [0, 1] from near to far */
        const float *v = s->positions + (size_t)t * 9;
        double e1[3], e2[3], pv[3], tv[3], qv[3], det, u, w, tt;
        for (i = 0; i < 3; ++i) { e1[i] = (double)v[3 + i] - v[i]; e2[i] = (double)v[6 + i] - v[i]; tv[i] = o[i] - v[i]; }
        pv[0] = d[1] * e2[2] - d[2] * e2[1]; pv[1] = d[2] * e2[0] - d[0] * e2[2]; pv[2] = d[0] * e2[1] - d[1] * e2[0];
        det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
        if (det == 0.0) continue;
        u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
        if (u < 0.0 || u > 1.0) continue;
        qv[0] = tv[1] * e1[2] - tv[2] * e1[1]; qv[1] = tv[2] * e1[0] - tv[0] * e1[2]; qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
        w = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
        if (w < 0.0 || u + w > 1.0) continue;
        tt = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
        if (tt < 0.0 || tt > 1.0 || tt >= best) continue;
        best = tt; best_t = t; bu = u; bv = w;
    }
    if (best_t == UINT32_MAX) return 0;
    h->triangle = best_t;
    for (i = 0; i < 3; ++i) { h->p[i] = o[i] + best * d[i]; h->toward[i] = -d[i]; }
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (i = 0; i < 3; ++i) h->toward[i] /= len;
    {
        const float *v = s->positions + (size_t)best_t * 9;
        double nn[3];
        if (s->normals) {
            const float *n = s->normals + (size_t)best_t * 9;
            for (i = 0; i < 3; ++i) nn[i] = (1.0 - bu - bv) * n[i] + bu * n[3 + i] + bv * n[6 + i];
        } else {
            double e1[3], e2[3];
            for (i = 0; i < 3; ++i) { e1[i] = (double)v[3 + i] - v[i]; e2[i] = (double)v[6 + i] - v[i]; }
            nn[0] = e1[1] * e2[2] - e1[2] * e2[1]; nn[1] = e1[2] * e2[0] - e1[0] * e2[2]; nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
        }
        len = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        if (len > 0.0) {
            double side = nn[0] * h->toward[0] + nn[1] * h->toward[1] + nn[2] * h->toward[2];
            for (i = 0; i < 3; ++i) h->n[i] = (side < 0.0 ? -nn[i] : nn[i]) / len; /* two-sided */
        }
    }
    hp[0] = h->p[0]; hp[1] = h->p[1]; hp[2] = h->p[2]; hp[3] = 1.0;
    {
        double vv[4];
        gim_mat4 m = vp;
        gim__mat4_apply_d(&m, hp, vv);
        h->depth = 0.5 * vv[2] / vv[3] + 0.5;
    }
    for (i = 0; i < 3; ++i)
        if (!(fabs(h->p[i]) <= FLT_MAX) || !(fabs(h->n[i]) <= 1.0 + 1e-6)) return -1;
    if (!(fabs(h->depth) <= FLT_MAX)) return -1;
    /* window depth is clamped to [0, 1] as the GPU's is (an ill-conditioned camera's float
       inverse can put a hit between its planes slightly outside) */
    h->depth = h->depth < 0.0 ? 0.0 : h->depth > 1.0 ? 1.0 : h->depth;
    return 1;
}

static gim_result gim__twin_scene_check(const gim_twin_scene *s, const char *where) {
    size_t i;
    if (!s || !s->positions || !s->albedo || s->triangle_count == 0)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "scene without positions, albedo or triangles");
    if (!gim__all_finite(s->positions, (size_t)s->triangle_count * 9) ||
        (s->normals && !gim__all_finite(s->normals, (size_t)s->triangle_count * 9)) ||
        !gim__all_finite(s->albedo, (size_t)s->triangle_count * 3))
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "a NaN/Inf in the scene");
    for (i = 0; i < (size_t)s->triangle_count * 3; ++i)
        if (s->albedo[i] < 0.0f) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "a negative albedo");
    return GIM_OK;
}

GIMANY_DEF gim_result gim_rsm_texel_twin(const gim_twin_scene *scene, const gim_light *light, const float bmin[3],
                                         const float bmax[3], uint32_t x, uint32_t y, gim_rsm_texel *out) {
    static const char where[] = "gim_rsm_texel_twin";
    gim_mat4 view, proj;
    gim__twin_hit h;
    uint32_t size;
    float power[3];
    double a_perp, cosv, omega = 0.0;
    gim_result r;
    int i, hit;
    if (!out) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL");
    r = gim__twin_scene_check(scene, where);
    if (r == GIM_OK) r = gim_light_camera(light, bmin, bmax, &view, &proj);
    if (r != GIM_OK) return r;
    size = gim__light_rsm_size(light);
    if (x >= size || y >= size) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "texel outside the RSM");
    memset(out, 0, sizeof *out);
    out->depth = 1.0f;
    out->triangle = UINT32_MAX;
    hit = gim__twin_cast(scene, view, proj, size, size, x, y, &h);
    if (hit < 0) return gim__fail(NULL, GIM_ERROR_OUT_OF_RANGE, where, "the light's rays leave the float range");
    if (hit == 0) return GIM_OK;
    gim__light_power(light, power);
    out->triangle = h.triangle;
    out->depth = (float)h.depth;
    for (i = 0; i < 3; ++i) { out->position[i] = (float)h.p[i]; out->normal[i] = (float)h.n[i]; }
    cosv = h.n[0] * h.toward[0] + h.n[1] * h.toward[1] + h.n[2] * h.toward[2];
    if (cosv < GIM_RSM_MIN_COS) cosv = GIM_RSM_MIN_COS;
    if (light->type == GIM_LIGHT_SPOT) {
        /* texel side s on the image plane at distance 1; solid angle at image point (u, v) */
        double th = 1.0 / proj.m[5], s = 2.0 * th / size, u = h.ndc[0] * th, v = h.ndc[1] * th, dd = 0.0;
        gim_vec3 axis = gim_v3_normalize(light->direction);
        double inside = -(h.toward[0] * axis.x + h.toward[1] * axis.y + h.toward[2] * axis.z);
        for (i = 0; i < 3; ++i) {
            double e = h.p[i] - (i == 0 ? light->position.x : i == 1 ? light->position.y : light->position.z);
            dd += e * e;
        }
        omega = s * s / pow(1.0 + u * u + v * v, 1.5);
        out->area = (float)gim__min_d(omega * dd / cosv, FLT_MAX);
        out->lit = inside >= cos((double)light->cone_angle);
        a_perp = omega;
    } else {
        double side = 2.0 / proj.m[0] / size; /* 2 extent / size */
        a_perp = side * side;
        out->area = (float)gim__min_d(a_perp / cosv, FLT_MAX);
        out->lit = 1;
    }
    if (out->lit) {
        const float *al = scene->albedo + (size_t)h.triangle * 3;
        for (i = 0; i < 3; ++i) out->flux[i] = (float)gim__min_d((double)al[i] * power[i] * a_perp, FLT_MAX);
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_gbuffer_texel_twin(const gim_twin_scene *scene, gim_mat4 view, gim_mat4 proj,
                                             uint32_t width, uint32_t height, uint32_t x, uint32_t y,
                                             gim_gbuffer_texel *out) {
    static const char where[] = "gim_gbuffer_texel_twin";
    gim__twin_hit h;
    gim_result r;
    int i, hit;
    if (!out) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL");
    r = gim__twin_scene_check(scene, where);
    if (r != GIM_OK) return r;
    if (!gim_mat4_isfinite(view) || !gim_mat4_isfinite(proj) || x >= width || y >= height)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "matrices not finite or pixel outside the view");
    memset(out, 0, sizeof *out);
    out->depth = 1.0f;
    out->triangle = UINT32_MAX;
    hit = gim__twin_cast(scene, view, proj, width, height, x, y, &h);
    if (hit < 0) return gim__fail(NULL, GIM_ERROR_OUT_OF_RANGE, where, "the camera's rays leave the float range");
    if (hit == 0) return GIM_OK;
    out->triangle = h.triangle;
    out->depth = (float)h.depth;
    for (i = 0; i < 3; ++i) {
        out->position[i] = (float)h.p[i];
        out->normal[i] = (float)h.n[i];
        out->albedo[i] = scene->albedo[(size_t)h.triangle * 3 + i];
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_view_sample_pixels(uint32_t count, uint32_t width, uint32_t height, const float *offsets,
                                             uint32_t *pixels) {
    uint32_t i;
    if (!pixels || count == 0 || width == 0 || height == 0)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, "gim_view_sample_pixels", "NULL output or zero count/size");
    if (offsets && !(offsets[0] >= 0.0f && offsets[0] < 1.0f && offsets[1] >= 0.0f && offsets[1] < 1.0f))
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, "gim_view_sample_pixels", "offsets outside [0,1)");
    for (i = 0; i < count; ++i) {
        float u = (float)gim_halton(i + 1u, 0), v = (float)gim_halton(i + 1u, 1);
        double px, py;
        if (offsets) { u = gim_rotate01(u, offsets[0]); v = gim_rotate01(v, offsets[1]); }
        px = floor((double)u * width);
        py = floor((double)v * height);
        pixels[2 * i] = px < (double)width ? (uint32_t)px : width - 1u;
        pixels[2 * i + 1] = py < (double)height ? (uint32_t)py : height - 1u;
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_view_samples_twin(const float *depth, const float *normal, uint32_t width, uint32_t height,
                                            gim_mat4 view, gim_mat4 proj, const uint32_t *pixels, uint32_t count,
                                            gim_view_sample *out) {
    static const char where[] = "gim_view_samples_twin";
    gim_mat4 inv_view, inv_proj;
    uint32_t i;
    if (!depth || !normal || !pixels || !out || count == 0 || width == 0 || height == 0)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL array or zero count/size");
    if (!gim_mat4_isfinite(view) || !gim_mat4_isfinite(proj) || !gim_mat4_invert(view, &inv_view) ||
        !gim_mat4_invert(proj, &inv_proj))
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj not finite or singular");
    for (i = 0; i < count; ++i) {
        uint32_t x = pixels[2 * i], y = pixels[2 * i + 1];
        size_t k;
        const float *n;
        double ndc[4], v[4], w[4], len;
        int j;
        if (x >= width || y >= height) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "pixel %u outside", (unsigned)i);
        k = (size_t)y * width + x;
        n = normal + k * 4;
        memset(&out[i], 0, sizeof out[i]);
        len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (!(depth[k] < 1.0f) || !gim__isfinitef(depth[k]) || !gim__all_finite(n, 3) || !(len > 0.0)) continue;
        ndc[0] = (2.0 * x + 1.0) / width - 1.0;
        ndc[1] = (2.0 * y + 1.0) / height - 1.0;
        ndc[2] = 2.0 * depth[k] - 1.0;
        ndc[3] = 1.0;
        gim__mat4_apply_d(&inv_proj, ndc, v);
        for (j = 0; j < 3; ++j) v[j] /= v[3];
        v[3] = 1.0;
        gim__mat4_apply_d(&inv_view, v, w);
        out[i].position = gim_v3((float)w[0], (float)w[1], (float)w[2]);
        out[i].normal = gim_v3((float)(n[0] / len), (float)(n[1] / len), (float)(n[2] / len));
    }
    return GIM_OK;
}

#ifdef __cplusplus
}
#endif

/* @impl gl ================================================================================ */
#ifndef GIMANY_NO_GL
#include "shaders_embedded.h"

#ifdef __cplusplus
extern "C" {
#endif

/* --- GL declarations without a GL header -------------------------------------------------
   Private type and constant names (GIM__GL_*), so that no host GL header or loader, included
   before or after gimany.h, can clash with them (typedefs cannot be guarded with #ifndef). */
#if defined(_WIN32) && !defined(__CYGWIN__)
#define GIM__APIENTRY __stdcall
#else
#define GIM__APIENTRY
#endif
typedef unsigned int gim__GLenum;
typedef unsigned int gim__GLuint;
typedef unsigned int gim__GLbitfield;
typedef int gim__GLint;
typedef int gim__GLsizei;
typedef unsigned char gim__GLboolean;
typedef char gim__GLchar;
typedef float gim__GLfloat;
typedef ptrdiff_t gim__GLsizeiptr;
typedef ptrdiff_t gim__GLintptr;
typedef int64_t gim__GLint64;

enum {
    GIM__GL_NO_ERROR = 0,
    GIM__GL_FALSE = 0,
    GIM__GL_TRUE = 1,
    GIM__GL_VENDOR = 0x1F00,
    GIM__GL_RENDERER = 0x1F01,
    GIM__GL_VERSION = 0x1F02,
    GIM__GL_SHADING_LANGUAGE_VERSION = 0x8B8C,
    GIM__GL_MAJOR_VERSION = 0x821B,
    GIM__GL_MINOR_VERSION = 0x821C,
    GIM__GL_CURRENT_PROGRAM = 0x8B8D,
    GIM__GL_VERTEX_ARRAY_BINDING = 0x85B5,
    GIM__GL_ARRAY_BUFFER = 0x8892,
    GIM__GL_ARRAY_BUFFER_BINDING = 0x8894,
    GIM__GL_ELEMENT_ARRAY_BUFFER = 0x8893,
    GIM__GL_ELEMENT_ARRAY_BUFFER_BINDING = 0x8895,
    GIM__GL_DISPATCH_INDIRECT_BUFFER = 0x90EE,
    GIM__GL_DISPATCH_INDIRECT_BUFFER_BINDING = 0x90EF,
    GIM__GL_DRAW_INDIRECT_BUFFER = 0x8F3F,
    GIM__GL_DRAW_INDIRECT_BUFFER_BINDING = 0x8F43,
    GIM__GL_PIXEL_PACK_BUFFER = 0x88EB,
    GIM__GL_PIXEL_PACK_BUFFER_BINDING = 0x88ED,
    GIM__GL_PIXEL_UNPACK_BUFFER = 0x88EC,
    GIM__GL_PIXEL_UNPACK_BUFFER_BINDING = 0x88EF,
    GIM__GL_COPY_READ_BUFFER = 0x8F36,
    GIM__GL_COPY_READ_BUFFER_BINDING = 0x8F36,
    GIM__GL_COPY_WRITE_BUFFER = 0x8F37,
    GIM__GL_COPY_WRITE_BUFFER_BINDING = 0x8F37,
    GIM__GL_SHADER_STORAGE_BUFFER = 0x90D2,
    GIM__GL_SHADER_STORAGE_BUFFER_BINDING = 0x90D3,
    GIM__GL_SHADER_STORAGE_BUFFER_START = 0x90D4,
    GIM__GL_SHADER_STORAGE_BUFFER_SIZE = 0x90D5,
    GIM__GL_UNIFORM_BUFFER = 0x8A11,
    GIM__GL_UNIFORM_BUFFER_BINDING = 0x8A28,
    GIM__GL_UNIFORM_BUFFER_START = 0x8A29,
    GIM__GL_UNIFORM_BUFFER_SIZE = 0x8A2A,
    GIM__GL_DRAW_FRAMEBUFFER = 0x8CA9,
    GIM__GL_READ_FRAMEBUFFER = 0x8CA8,
    GIM__GL_DRAW_FRAMEBUFFER_BINDING = 0x8CA6,
    GIM__GL_READ_FRAMEBUFFER_BINDING = 0x8CAA,
    GIM__GL_VIEWPORT = 0x0BA2,
    GIM__GL_SCISSOR_BOX = 0x0C10,
    GIM__GL_BLEND = 0x0BE2,
    GIM__GL_CULL_FACE = 0x0B44,
    GIM__GL_DEPTH_TEST = 0x0B71,
    GIM__GL_STENCIL_TEST = 0x0B90,
    GIM__GL_SCISSOR_TEST = 0x0C11,
    GIM__GL_PRIMITIVE_RESTART = 0x8F9D,
    GIM__GL_RASTERIZER_DISCARD = 0x8C89,
    GIM__GL_POLYGON_OFFSET_FILL = 0x8037,
    GIM__GL_FRAMEBUFFER_SRGB = 0x8DB9,
    GIM__GL_DEPTH_CLAMP = 0x864F,
    GIM__GL_BLEND_SRC_RGB = 0x80C9,
    GIM__GL_BLEND_DST_RGB = 0x80C8,
    GIM__GL_BLEND_SRC_ALPHA = 0x80CB,
    GIM__GL_BLEND_DST_ALPHA = 0x80CA,
    GIM__GL_BLEND_EQUATION_RGB = 0x8009,
    GIM__GL_BLEND_EQUATION_ALPHA = 0x883D,
    GIM__GL_DEPTH_FUNC = 0x0B74,
    GIM__GL_DEPTH_WRITEMASK = 0x0B72,
    GIM__GL_COLOR_WRITEMASK = 0x0C23,
    GIM__GL_FRONT_FACE = 0x0B46,
    GIM__GL_CULL_FACE_MODE = 0x0B45,
    GIM__GL_POLYGON_MODE = 0x0B40,
    GIM__GL_FRONT_AND_BACK = 0x0408,
    GIM__GL_ACTIVE_TEXTURE = 0x84E0,
    GIM__GL_TEXTURE0 = 0x84C0,
    GIM__GL_TEXTURE_2D = 0x0DE1,
    GIM__GL_TEXTURE_2D_ARRAY = 0x8C1A,
    GIM__GL_TEXTURE_BINDING_2D = 0x8069,
    GIM__GL_TEXTURE_BINDING_2D_ARRAY = 0x8C1D,
    GIM__GL_SAMPLER_BINDING = 0x8919,
    GIM__GL_IMAGE_BINDING_NAME = 0x8F3A,
    GIM__GL_IMAGE_BINDING_LEVEL = 0x8F3B,
    GIM__GL_IMAGE_BINDING_LAYERED = 0x8F3C,
    GIM__GL_IMAGE_BINDING_LAYER = 0x8F3D,
    GIM__GL_IMAGE_BINDING_ACCESS = 0x8F3E,
    GIM__GL_IMAGE_BINDING_FORMAT = 0x906E,
    GIM__GL_PACK_ALIGNMENT = 0x0D05,
    GIM__GL_UNPACK_ALIGNMENT = 0x0CF5,
    GIM__GL_PACK_ROW_LENGTH = 0x0D02,
    GIM__GL_UNPACK_ROW_LENGTH = 0x0CF2,
    GIM__GL_COLOR_CLEAR_VALUE = 0x0C22,
    GIM__GL_DEPTH_CLEAR_VALUE = 0x0B73,
    GIM__GL_COMPUTE_SHADER = 0x91B9,
    GIM__GL_VERTEX_SHADER = 0x8B31,
    GIM__GL_FRAGMENT_SHADER = 0x8B30,
    GIM__GL_GEOMETRY_SHADER = 0x8DD9,
    GIM__GL_COMPILE_STATUS = 0x8B81,
    GIM__GL_LINK_STATUS = 0x8B82,
    GIM__GL_MAX_COMPUTE_SHARED_MEMORY_SIZE = 0x8262,
    GIM__GL_MAX_IMAGE_UNITS = 0x8F38,
    GIM__GL_MAX_COMBINED_TEXTURE_IMAGE_UNITS = 0x8B4D,
    GIM__GL_SHADER_STORAGE_BARRIER_BIT = 0x00002000,
    GIM__GL_TEXTURE_FETCH_BARRIER_BIT = 0x00000008,
    GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT = 0x00000020,
    GIM__GL_BUFFER_UPDATE_BARRIER_BIT = 0x00000200,
    GIM__GL_DYNAMIC_COPY = 0x88EA,
    GIM__GL_STREAM_READ = 0x88E1,
    GIM__GL_R32F = 0x822E,
    GIM__GL_RGBA32F = 0x8814,
    GIM__GL_READ_ONLY = 0x88B8,
    GIM__GL_RED = 0x1903,
    GIM__GL_RGBA = 0x1908,
    GIM__GL_FLOAT = 0x1406,
    GIM__GL_MAX_SHADER_STORAGE_BLOCK_SIZE = 0x90DE,
    GIM__GL_BUFFER_SIZE = 0x8764,
    GIM__GL_TEXTURE_WIDTH = 0x1000,
    GIM__GL_TEXTURE_HEIGHT = 0x1001,
    GIM__GL_INVALID_ENUM = 0x0500,
    GIM__GL_TEXTURE_MIN_FILTER = 0x2801,
    GIM__GL_TEXTURE_MAG_FILTER = 0x2800,
    GIM__GL_NEAREST = 0x2600,
    GIM__GL_TEXTURE_WRAP_S = 0x2802,
    GIM__GL_TEXTURE_WRAP_T = 0x2803,
    GIM__GL_CLAMP_TO_EDGE = 0x812F,
    GIM__GL_TEXTURE_COMPARE_MODE = 0x884C,
    GIM__GL_NONE = 0,
    GIM__GL_DEPTH_COMPONENT32F = 0x8CAC,
    GIM__GL_RGBA16F = 0x881A,
    GIM__GL_RGBA8 = 0x8058,
    GIM__GL_FRAMEBUFFER = 0x8D40,
    GIM__GL_COLOR_ATTACHMENT0 = 0x8CE0,
    GIM__GL_DEPTH_ATTACHMENT = 0x8D00,
    GIM__GL_FRAMEBUFFER_COMPLETE = 0x8CD5,
    GIM__GL_COLOR = 0x1800,
    GIM__GL_DEPTH = 0x1801,
    GIM__GL_TRIANGLES = 0x0004,
    GIM__GL_UNSIGNED_INT = 0x1405,
    GIM__GL_UNSIGNED_SHORT = 0x1403,
    GIM__GL_STATIC_DRAW = 0x88E4,
    GIM__GL_LESS = 0x0201,
    GIM__GL_FILL = 0x1B02,
    GIM__GL_DEPTH_RANGE = 0x0B70,
    GIM__GL_MAX_TEXTURE_SIZE = 0x0D33,
    GIM__GL_MAX_VIEWPORT_DIMS = 0x0D3A,
    GIM__GL_CLIP_DISTANCE0 = 0x3000,
    GIM__GL_POLYGON_SMOOTH = 0x0B41
};

/* Every GL function gimany calls: X(return type, name without "gl", parameter list). */
#define GIM__GL_FUNCS(X)                                                                          \
    X(gim__GLenum, GetError, (void))                                                              \
    X(const unsigned char *, GetString, (gim__GLenum name))                                      \
    X(void, GetIntegerv, (gim__GLenum pname, gim__GLint *data))                                  \
    X(void, GetIntegeri_v, (gim__GLenum target, gim__GLuint index, gim__GLint *data))            \
    X(void, GetInteger64i_v, (gim__GLenum target, gim__GLuint index, gim__GLint64 *data))        \
    X(void, GetInteger64v, (gim__GLenum pname, gim__GLint64 *data))                             \
    X(void, GetBooleanv, (gim__GLenum pname, gim__GLboolean *data))                              \
    X(void, GetFloatv, (gim__GLenum pname, gim__GLfloat *data))                                  \
    X(gim__GLboolean, IsEnabled, (gim__GLenum cap))                                              \
    X(void, Enable, (gim__GLenum cap))                                                           \
    X(void, Disable, (gim__GLenum cap))                                                          \
    X(void, UseProgram, (gim__GLuint program))                                                   \
    X(void, BindVertexArray, (gim__GLuint array))                                                \
    X(void, BindBuffer, (gim__GLenum target, gim__GLuint buffer))                                \
    X(void, BindBufferBase, (gim__GLenum target, gim__GLuint index, gim__GLuint buffer))         \
    X(void, BindBufferRange, (gim__GLenum target, gim__GLuint index, gim__GLuint buffer,         \
                              gim__GLintptr offset, gim__GLsizeiptr size))                       \
    X(void, BindFramebuffer, (gim__GLenum target, gim__GLuint framebuffer))                      \
    X(void, Viewport, (gim__GLint x, gim__GLint y, gim__GLsizei width, gim__GLsizei height))     \
    X(void, Scissor, (gim__GLint x, gim__GLint y, gim__GLsizei width, gim__GLsizei height))      \
    X(void, BlendFuncSeparate, (gim__GLenum src_rgb, gim__GLenum dst_rgb, gim__GLenum src_alpha, \
                                gim__GLenum dst_alpha))                                          \
    X(void, BlendEquationSeparate, (gim__GLenum mode_rgb, gim__GLenum mode_alpha))               \
    X(void, DepthFunc, (gim__GLenum func))                                                       \
    X(void, DepthMask, (gim__GLboolean flag))                                                    \
    X(void, ColorMask, (gim__GLboolean r, gim__GLboolean g, gim__GLboolean b, gim__GLboolean a)) \
    X(void, FrontFace, (gim__GLenum mode))                                                       \
    X(void, CullFace, (gim__GLenum mode))                                                        \
    X(void, PolygonMode, (gim__GLenum face, gim__GLenum mode))                                   \
    X(void, ClearColor, (gim__GLfloat r, gim__GLfloat g, gim__GLfloat b, gim__GLfloat a))        \
    X(void, ClearDepth, (double depth))                                                          \
    X(void, ActiveTexture, (gim__GLenum texture))                                                \
    X(void, BindTexture, (gim__GLenum target, gim__GLuint texture))                              \
    X(void, BindSampler, (gim__GLuint unit, gim__GLuint sampler))                                \
    X(void, BindImageTexture, (gim__GLuint unit, gim__GLuint texture, gim__GLint level,          \
                               gim__GLboolean layered, gim__GLint layer, gim__GLenum access,     \
                               gim__GLenum format))                                              \
    X(void, PixelStorei, (gim__GLenum pname, gim__GLint param))                                  \
    X(gim__GLuint, CreateShader, (gim__GLenum type))                                             \
    X(void, ShaderSource, (gim__GLuint shader, gim__GLsizei count,                               \
                           const gim__GLchar *const *string, const gim__GLint *length))          \
    X(void, CompileShader, (gim__GLuint shader))                                                 \
    X(void, GetShaderiv, (gim__GLuint shader, gim__GLenum pname, gim__GLint *params))            \
    X(void, GetShaderInfoLog, (gim__GLuint shader, gim__GLsizei size, gim__GLsizei *length,      \
                               gim__GLchar *log))                                                \
    X(void, DeleteShader, (gim__GLuint shader))                                                  \
    X(gim__GLuint, CreateProgram, (void))                                                        \
    X(void, AttachShader, (gim__GLuint program, gim__GLuint shader))                             \
    X(void, DetachShader, (gim__GLuint program, gim__GLuint shader))                             \
    X(void, LinkProgram, (gim__GLuint program))                                                  \
    X(void, GetProgramiv, (gim__GLuint program, gim__GLenum pname, gim__GLint *params))          \
    X(void, GetProgramInfoLog, (gim__GLuint program, gim__GLsizei size, gim__GLsizei *length,    \
                                gim__GLchar *log))                                               \
    X(void, DeleteProgram, (gim__GLuint program))                                                \
    X(gim__GLint, GetUniformLocation, (gim__GLuint program, const gim__GLchar *name))            \
    X(void, Uniform1i, (gim__GLint location, gim__GLint v0))                                     \
    X(void, Uniform1ui, (gim__GLint location, gim__GLuint v0))                                   \
    X(void, Uniform1f, (gim__GLint location, gim__GLfloat v0))                                   \
    X(void, Uniform2ui, (gim__GLint location, gim__GLuint v0, gim__GLuint v1))                   \
    X(void, Uniform2d, (gim__GLint location, double v0, double v1))                              \
    X(void, GenBuffers, (gim__GLsizei n, gim__GLuint *buffers))                                  \
    X(gim__GLboolean, IsBuffer, (gim__GLuint buffer))                                           \
    X(void, GetBufferParameteri64v, (gim__GLenum target, gim__GLenum pname, gim__GLint64 *data)) \
    X(gim__GLboolean, IsTexture, (gim__GLuint texture))                                         \
    X(void, GetTexLevelParameteriv, (gim__GLenum target, gim__GLint level, gim__GLenum pname,    \
                                     gim__GLint *params))                                        \
    X(void, DeleteBuffers, (gim__GLsizei n, const gim__GLuint *buffers))                         \
    X(void, BufferData, (gim__GLenum target, gim__GLsizeiptr size, const void *data,             \
                         gim__GLenum usage))                                                     \
    X(void, DispatchCompute, (gim__GLuint x, gim__GLuint y, gim__GLuint z))                      \
    X(void, MemoryBarrier, (gim__GLbitfield barriers))                                           \
    X(void, GetDoublev, (gim__GLenum pname, double *data))                                       \
    X(void, DepthRange, (double n, double f))                                                    \
    X(void, GenTextures, (gim__GLsizei n, gim__GLuint *textures))                                \
    X(void, DeleteTextures, (gim__GLsizei n, const gim__GLuint *textures))                       \
    X(void, TexStorage2D, (gim__GLenum target, gim__GLsizei levels, gim__GLenum format,          \
                           gim__GLsizei width, gim__GLsizei height))                             \
    X(void, TexParameteri, (gim__GLenum target, gim__GLenum pname, gim__GLint param))            \
    X(void, GenSamplers, (gim__GLsizei n, gim__GLuint *samplers))                                \
    X(void, DeleteSamplers, (gim__GLsizei n, const gim__GLuint *samplers))                       \
    X(void, SamplerParameteri, (gim__GLuint sampler, gim__GLenum pname, gim__GLint param))       \
    X(void, GenFramebuffers, (gim__GLsizei n, gim__GLuint *framebuffers))                        \
    X(void, DeleteFramebuffers, (gim__GLsizei n, const gim__GLuint *framebuffers))               \
    X(void, FramebufferTexture2D, (gim__GLenum target, gim__GLenum attachment, gim__GLenum textarget, \
                                   gim__GLuint texture, gim__GLint level))                       \
    X(void, DrawBuffers, (gim__GLsizei n, const gim__GLenum *bufs))                              \
    X(gim__GLenum, CheckFramebufferStatus, (gim__GLenum target))                                 \
    X(void, ClearBufferfv, (gim__GLenum buffer, gim__GLint drawbuffer, const gim__GLfloat *value)) \
    X(void, GenVertexArrays, (gim__GLsizei n, gim__GLuint *arrays))                              \
    X(void, DeleteVertexArrays, (gim__GLsizei n, const gim__GLuint *arrays))                     \
    X(void, VertexAttribPointer, (gim__GLuint index, gim__GLint size, gim__GLenum type,          \
                                  gim__GLboolean normalized, gim__GLsizei stride, const void *pointer)) \
    X(void, EnableVertexAttribArray, (gim__GLuint index))                                        \
    X(void, DrawElements, (gim__GLenum mode, gim__GLsizei count, gim__GLenum type, const void *indices)) \
    X(void, UniformMatrix4fv, (gim__GLint location, gim__GLsizei count, gim__GLboolean transpose, \
                               const gim__GLfloat *value))                                       \
    X(void, Uniform3f, (gim__GLint location, gim__GLfloat v0, gim__GLfloat v1, gim__GLfloat v2)) \
    X(void, Uniform4f, (gim__GLint location, gim__GLfloat v0, gim__GLfloat v1, gim__GLfloat v2,  \
                        gim__GLfloat v3))                                                        \
    X(void, BufferSubData, (gim__GLenum target, gim__GLintptr offset, gim__GLsizeiptr size,      \
                            const void *data))                                                   \
    X(gim__GLboolean, IsEnabledi, (gim__GLenum cap, gim__GLuint index))                          \
    X(void, Enablei, (gim__GLenum cap, gim__GLuint index))                                       \
    X(void, Disablei, (gim__GLenum cap, gim__GLuint index))                                      \
    X(void, GetBooleani_v, (gim__GLenum target, gim__GLuint index, gim__GLboolean *data))        \
    X(void, ColorMaski, (gim__GLuint buf, gim__GLboolean r, gim__GLboolean g, gim__GLboolean b,  \
                         gim__GLboolean a))                                                      \
    X(void, BlendFuncSeparatei, (gim__GLuint buf, gim__GLenum src_rgb, gim__GLenum dst_rgb,      \
                                 gim__GLenum src_alpha, gim__GLenum dst_alpha))                  \
    X(void, BlendEquationSeparatei, (gim__GLuint buf, gim__GLenum mode_rgb, gim__GLenum mode_alpha))

/* The function table, filled by gim__gl_load. */
typedef struct gim__gl {
#define GIM__X(ret, name, args) ret(GIM__APIENTRY *name) args;
    GIM__GL_FUNCS(GIM__X)
#undef GIM__X
    int unused_; /* keeps the struct non-empty whatever the list holds */
} gim__gl;

/* Fill the table; a function the loader does not have is GIM_ERROR_UNSUPPORTED, each one
   logged by name. With GIMANY_EXTERNAL_GL the host's own gl* functions (from its loader's
   header, included before the implementation) fill it and get_proc_address is unused. */
static gim_result gim__gl_load(gim__gl *gl, gim_gl_proc (*get_proc_address)(const char *), const gim_env *env) {
    int missing = 0;
    const char *first = NULL;
    memset(gl, 0, sizeof *gl);
#ifdef GIMANY_EXTERNAL_GL
    (void)get_proc_address;
#define GIM__X(ret, name, args) gl->name = (ret(GIM__APIENTRY *) args)gl##name;
#else
#define GIM__X(ret, name, args) gl->name = (ret(GIM__APIENTRY *) args)get_proc_address("gl" #name);
#endif
    GIM__GL_FUNCS(GIM__X)
#undef GIM__X
#define GIM__X(ret, name, args)                                                                  \
    if (!gl->name) {                                                                             \
        gim__log(env, GIM_LOG_ERROR, "gim_create", "GL function gl%s not found", #name);        \
        if (!missing++) first = #name;                                                           \
    }
    GIM__GL_FUNCS(GIM__X)
#undef GIM__X
    if (missing)
        return gim__fail(env, GIM_ERROR_UNSUPPORTED, "gim_create",
                         "gl%s not found (%d GL function%s missing): gimany needs OpenGL 4.3", first, missing,
                         missing == 1 ? "" : "s");
    return GIM_OK;
}

/* --- GL state save/restore ----------------------------------------------------------------
   The GL state gimany may touch, in one place. gim__gl_enter saves it on the way into the
   outermost call that touches GL, gim__gl_leave restores it on the way out; what is not listed
   here gimany must not change. Units and bindings are those gimany's passes use (within
   GL 4.3's minimums: 8 image units, 8 SSBO bindings, 36 UBO bindings, 80 texture units). */
#define GIM__GL_TEXTURE_UNITS 8
#define GIM__GL_IMAGE_UNITS 8
#define GIM__GL_SSBO_BINDINGS 8
#define GIM__GL_UBO_BINDINGS 4
#define GIM__GL_DRAW_BUFFERS 8   /* per-draw-buffer blend and colour mask (GL 4.3 has >= 8) */

/* glEnable/glDisable capabilities */
static const gim__GLenum gim__gl_state_caps[] = {
    GIM__GL_BLEND, GIM__GL_CULL_FACE, GIM__GL_DEPTH_TEST, GIM__GL_STENCIL_TEST, GIM__GL_SCISSOR_TEST,
    GIM__GL_PRIMITIVE_RESTART, GIM__GL_RASTERIZER_DISCARD, GIM__GL_POLYGON_OFFSET_FILL,
    GIM__GL_FRAMEBUFFER_SRGB, GIM__GL_DEPTH_CLAMP,
    /* a host's clip planes would cut gimany's draws (its vertex shader writes no clip
       distance); polygon smoothing would scale the RSM's alpha (the lit flag) at edges */
    GIM__GL_CLIP_DISTANCE0, GIM__GL_CLIP_DISTANCE0 + 1, GIM__GL_CLIP_DISTANCE0 + 2, GIM__GL_CLIP_DISTANCE0 + 3,
    GIM__GL_CLIP_DISTANCE0 + 4, GIM__GL_CLIP_DISTANCE0 + 5, GIM__GL_CLIP_DISTANCE0 + 6, GIM__GL_CLIP_DISTANCE0 + 7,
    GIM__GL_POLYGON_SMOOTH};
#define GIM__GL_STATE_CAPS (sizeof gim__gl_state_caps / sizeof gim__gl_state_caps[0])

/* Non-indexed buffer bindings: {target, its binding query}. ELEMENT_ARRAY_BUFFER is VAO state
   and restored with the VAO. The generic SSBO/UBO bindings come after the indexed ones on
   restore, because glBindBufferBase/Range also sets them. */
static const gim__GLenum gim__gl_state_buffers[][2] = {
    {GIM__GL_ARRAY_BUFFER, GIM__GL_ARRAY_BUFFER_BINDING},
    {GIM__GL_DISPATCH_INDIRECT_BUFFER, GIM__GL_DISPATCH_INDIRECT_BUFFER_BINDING},
    {GIM__GL_DRAW_INDIRECT_BUFFER, GIM__GL_DRAW_INDIRECT_BUFFER_BINDING},
    {GIM__GL_PIXEL_PACK_BUFFER, GIM__GL_PIXEL_PACK_BUFFER_BINDING},
    {GIM__GL_PIXEL_UNPACK_BUFFER, GIM__GL_PIXEL_UNPACK_BUFFER_BINDING},
    {GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_READ_BUFFER_BINDING},
    {GIM__GL_COPY_WRITE_BUFFER, GIM__GL_COPY_WRITE_BUFFER_BINDING},
    {GIM__GL_SHADER_STORAGE_BUFFER, GIM__GL_SHADER_STORAGE_BUFFER_BINDING},
    {GIM__GL_UNIFORM_BUFFER, GIM__GL_UNIFORM_BUFFER_BINDING}};
#define GIM__GL_STATE_BUFFERS (sizeof gim__gl_state_buffers / sizeof gim__gl_state_buffers[0])

/* glPixelStorei parameters */
static const gim__GLenum gim__gl_state_pixel_store[] = {
    GIM__GL_PACK_ALIGNMENT, GIM__GL_UNPACK_ALIGNMENT, GIM__GL_PACK_ROW_LENGTH, GIM__GL_UNPACK_ROW_LENGTH};
#define GIM__GL_STATE_PIXEL_STORE (sizeof gim__gl_state_pixel_store / sizeof gim__gl_state_pixel_store[0])

/* One image unit (glBindImageTexture's arguments). */
typedef struct gim__gl_image_binding {
    gim__GLint texture, level, layered, layer, access, format;
} gim__gl_image_binding;

/* One indexed buffer binding; size 0 means the whole buffer (glBindBufferBase). */
typedef struct gim__gl_indexed_buffer {
    gim__GLint buffer;
    gim__GLint64 start, size;
} gim__gl_indexed_buffer;

typedef struct gim__gl_state {
    gim__GLint program, vertex_array, element_array_buffer;
    gim__GLint draw_framebuffer, read_framebuffer;
    gim__GLint viewport[4], scissor_box[4];
    gim__GLboolean caps[GIM__GL_STATE_CAPS];
    gim__GLint buffers[GIM__GL_STATE_BUFFERS];
    gim__GLint blend_src_rgb, blend_dst_rgb, blend_src_alpha, blend_dst_alpha;
    gim__GLint blend_equation_rgb, blend_equation_alpha;
    gim__GLint depth_func;
    gim__GLboolean depth_mask, color_mask[4];
    /* per draw buffer (glEnablei/glBlendFunci/glColorMaski), restored after the global ones */
    gim__GLboolean blend_i[GIM__GL_DRAW_BUFFERS], color_mask_i[GIM__GL_DRAW_BUFFERS][4];
    gim__GLint blend_func_i[GIM__GL_DRAW_BUFFERS][6];  /* src/dst rgb, src/dst alpha, equations */
    gim__GLint front_face, cull_face_mode, polygon_mode[2];
    gim__GLfloat color_clear[4], depth_clear;
    double depth_range[2];
    gim__GLint active_texture;
    gim__GLint texture_2d[GIM__GL_TEXTURE_UNITS], texture_2d_array[GIM__GL_TEXTURE_UNITS];
    gim__GLint sampler[GIM__GL_TEXTURE_UNITS];
    gim__gl_image_binding image[GIM__GL_IMAGE_UNITS];
    gim__gl_indexed_buffer ssbo[GIM__GL_SSBO_BINDINGS], ubo[GIM__GL_UBO_BINDINGS];
    gim__GLint pixel_store[GIM__GL_STATE_PIXEL_STORE];
} gim__gl_state;

static void gim__gl_indexed_save(const gim__gl *gl, gim__GLenum binding, gim__GLenum start, gim__GLenum size,
                                 gim__gl_indexed_buffer *b, unsigned count) {
    unsigned i;
    for (i = 0; i < count; ++i) {
        gl->GetIntegeri_v(binding, i, &b[i].buffer);
        gl->GetInteger64i_v(start, i, &b[i].start);
        gl->GetInteger64i_v(size, i, &b[i].size);
    }
}

static void gim__gl_indexed_restore(const gim__gl *gl, gim__GLenum target, const gim__gl_indexed_buffer *b,
                                    unsigned count) {
    unsigned i;
    for (i = 0; i < count; ++i) {
        if (b[i].buffer && b[i].size > 0)
            gl->BindBufferRange(target, i, (gim__GLuint)b[i].buffer, (gim__GLintptr)b[i].start,
                                (gim__GLsizeiptr)b[i].size);
        else
            gl->BindBufferBase(target, i, (gim__GLuint)b[i].buffer);
    }
}

static void gim__gl_state_save(const gim__gl *gl, gim__gl_state *s) {
    unsigned i;
    memset(s, 0, sizeof *s);
    gl->GetIntegerv(GIM__GL_CURRENT_PROGRAM, &s->program);
    gl->GetIntegerv(GIM__GL_VERTEX_ARRAY_BINDING, &s->vertex_array);
    gl->GetIntegerv(GIM__GL_ELEMENT_ARRAY_BUFFER_BINDING, &s->element_array_buffer);
    gl->GetIntegerv(GIM__GL_DRAW_FRAMEBUFFER_BINDING, &s->draw_framebuffer);
    gl->GetIntegerv(GIM__GL_READ_FRAMEBUFFER_BINDING, &s->read_framebuffer);
    gl->GetIntegerv(GIM__GL_VIEWPORT, s->viewport);
    gl->GetIntegerv(GIM__GL_SCISSOR_BOX, s->scissor_box);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) s->caps[i] = gl->IsEnabled(gim__gl_state_caps[i]);
    for (i = 0; i < GIM__GL_STATE_BUFFERS; ++i) gl->GetIntegerv(gim__gl_state_buffers[i][1], &s->buffers[i]);
    gl->GetIntegerv(GIM__GL_BLEND_SRC_RGB, &s->blend_src_rgb);
    gl->GetIntegerv(GIM__GL_BLEND_DST_RGB, &s->blend_dst_rgb);
    gl->GetIntegerv(GIM__GL_BLEND_SRC_ALPHA, &s->blend_src_alpha);
    gl->GetIntegerv(GIM__GL_BLEND_DST_ALPHA, &s->blend_dst_alpha);
    gl->GetIntegerv(GIM__GL_BLEND_EQUATION_RGB, &s->blend_equation_rgb);
    gl->GetIntegerv(GIM__GL_BLEND_EQUATION_ALPHA, &s->blend_equation_alpha);
    gl->GetIntegerv(GIM__GL_DEPTH_FUNC, &s->depth_func);
    gl->GetBooleanv(GIM__GL_DEPTH_WRITEMASK, &s->depth_mask);
    gl->GetBooleanv(GIM__GL_COLOR_WRITEMASK, s->color_mask);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        s->blend_i[i] = gl->IsEnabledi(GIM__GL_BLEND, i);
        gl->GetBooleani_v(GIM__GL_COLOR_WRITEMASK, i, s->color_mask_i[i]);
        gl->GetIntegeri_v(GIM__GL_BLEND_SRC_RGB, i, &s->blend_func_i[i][0]);
        gl->GetIntegeri_v(GIM__GL_BLEND_DST_RGB, i, &s->blend_func_i[i][1]);
        gl->GetIntegeri_v(GIM__GL_BLEND_SRC_ALPHA, i, &s->blend_func_i[i][2]);
        gl->GetIntegeri_v(GIM__GL_BLEND_DST_ALPHA, i, &s->blend_func_i[i][3]);
        gl->GetIntegeri_v(GIM__GL_BLEND_EQUATION_RGB, i, &s->blend_func_i[i][4]);
        gl->GetIntegeri_v(GIM__GL_BLEND_EQUATION_ALPHA, i, &s->blend_func_i[i][5]);
    }
    gl->GetIntegerv(GIM__GL_FRONT_FACE, &s->front_face);
    gl->GetIntegerv(GIM__GL_CULL_FACE_MODE, &s->cull_face_mode);
    gl->GetIntegerv(GIM__GL_POLYGON_MODE, s->polygon_mode); /* front and back; core has one mode */
    gl->GetFloatv(GIM__GL_COLOR_CLEAR_VALUE, s->color_clear);
    gl->GetFloatv(GIM__GL_DEPTH_CLEAR_VALUE, &s->depth_clear);
    gl->GetDoublev(GIM__GL_DEPTH_RANGE, s->depth_range);
    gl->GetIntegerv(GIM__GL_ACTIVE_TEXTURE, &s->active_texture);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->GetIntegerv(GIM__GL_TEXTURE_BINDING_2D, &s->texture_2d[i]);
        gl->GetIntegerv(GIM__GL_TEXTURE_BINDING_2D_ARRAY, &s->texture_2d_array[i]);
        gl->GetIntegerv(GIM__GL_SAMPLER_BINDING, &s->sampler[i]);
    }
    gl->ActiveTexture((gim__GLenum)s->active_texture);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) {
        gim__gl_image_binding *b = &s->image[i];
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_NAME, i, &b->texture);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LEVEL, i, &b->level);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LAYERED, i, &b->layered);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LAYER, i, &b->layer);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_ACCESS, i, &b->access);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_FORMAT, i, &b->format);
    }
    gim__gl_indexed_save(gl, GIM__GL_SHADER_STORAGE_BUFFER_BINDING, GIM__GL_SHADER_STORAGE_BUFFER_START,
                         GIM__GL_SHADER_STORAGE_BUFFER_SIZE, s->ssbo, GIM__GL_SSBO_BINDINGS);
    gim__gl_indexed_save(gl, GIM__GL_UNIFORM_BUFFER_BINDING, GIM__GL_UNIFORM_BUFFER_START,
                         GIM__GL_UNIFORM_BUFFER_SIZE, s->ubo, GIM__GL_UBO_BINDINGS);
    for (i = 0; i < GIM__GL_STATE_PIXEL_STORE; ++i) gl->GetIntegerv(gim__gl_state_pixel_store[i], &s->pixel_store[i]);
}

static void gim__gl_state_restore(const gim__gl *gl, const gim__gl_state *s) {
    unsigned i;
    gl->UseProgram((gim__GLuint)s->program);
    gl->BindVertexArray((gim__GLuint)s->vertex_array);
    if (s->vertex_array) gl->BindBuffer(GIM__GL_ELEMENT_ARRAY_BUFFER, (gim__GLuint)s->element_array_buffer);
    gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, (gim__GLuint)s->draw_framebuffer);
    gl->BindFramebuffer(GIM__GL_READ_FRAMEBUFFER, (gim__GLuint)s->read_framebuffer);
    gl->Viewport(s->viewport[0], s->viewport[1], s->viewport[2], s->viewport[3]);
    gl->Scissor(s->scissor_box[0], s->scissor_box[1], s->scissor_box[2], s->scissor_box[3]);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) {
        if (s->caps[i]) gl->Enable(gim__gl_state_caps[i]);
        else gl->Disable(gim__gl_state_caps[i]);
    }
    gl->BlendFuncSeparate((gim__GLenum)s->blend_src_rgb, (gim__GLenum)s->blend_dst_rgb,
                          (gim__GLenum)s->blend_src_alpha, (gim__GLenum)s->blend_dst_alpha);
    gl->BlendEquationSeparate((gim__GLenum)s->blend_equation_rgb, (gim__GLenum)s->blend_equation_alpha);
    gl->DepthFunc((gim__GLenum)s->depth_func);
    gl->DepthMask(s->depth_mask);
    gl->ColorMask(s->color_mask[0], s->color_mask[1], s->color_mask[2], s->color_mask[3]);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        const gim__GLint *b = s->blend_func_i[i];
        if (s->blend_i[i]) gl->Enablei(GIM__GL_BLEND, i);
        else gl->Disablei(GIM__GL_BLEND, i);
        gl->ColorMaski(i, s->color_mask_i[i][0], s->color_mask_i[i][1], s->color_mask_i[i][2], s->color_mask_i[i][3]);
        gl->BlendFuncSeparatei(i, (gim__GLenum)b[0], (gim__GLenum)b[1], (gim__GLenum)b[2], (gim__GLenum)b[3]);
        gl->BlendEquationSeparatei(i, (gim__GLenum)b[4], (gim__GLenum)b[5]);
    }
    gl->FrontFace((gim__GLenum)s->front_face);
    gl->CullFace((gim__GLenum)s->cull_face_mode);
    gl->PolygonMode(GIM__GL_FRONT_AND_BACK, (gim__GLenum)s->polygon_mode[0]);
    gl->ClearColor(s->color_clear[0], s->color_clear[1], s->color_clear[2], s->color_clear[3]);
    gl->ClearDepth(s->depth_clear);
    gl->DepthRange(s->depth_range[0], s->depth_range[1]);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->BindTexture(GIM__GL_TEXTURE_2D, (gim__GLuint)s->texture_2d[i]);
        gl->BindTexture(GIM__GL_TEXTURE_2D_ARRAY, (gim__GLuint)s->texture_2d_array[i]);
        gl->BindSampler(i, (gim__GLuint)s->sampler[i]);
    }
    gl->ActiveTexture((gim__GLenum)s->active_texture);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) {
        const gim__gl_image_binding *b = &s->image[i];
        gl->BindImageTexture(i, (gim__GLuint)b->texture, b->level, (gim__GLboolean)(b->layered != 0), b->layer,
                             (gim__GLenum)b->access, (gim__GLenum)b->format);
    }
    gim__gl_indexed_restore(gl, GIM__GL_SHADER_STORAGE_BUFFER, s->ssbo, GIM__GL_SSBO_BINDINGS);
    gim__gl_indexed_restore(gl, GIM__GL_UNIFORM_BUFFER, s->ubo, GIM__GL_UBO_BINDINGS);
    for (i = 0; i < GIM__GL_STATE_BUFFERS; ++i)
        gl->BindBuffer(gim__gl_state_buffers[i][0], (gim__GLuint)s->buffers[i]);
    for (i = 0; i < GIM__GL_STATE_PIXEL_STORE; ++i) gl->PixelStorei(gim__gl_state_pixel_store[i], s->pixel_store[i]);
}

/* --- the context ----------------------------------------------------------------------- */

/* Programs, compiled on first use from shaders_embedded.h. */
typedef enum gim__program_id {
    GIM__PROGRAM_IMPORTANCE_MAP = 0, /* eq. 10-11 */
    GIM__PROGRAM_SCAN_COLUMNS,       /* eq. 12: block-local vertical sums */
    GIM__PROGRAM_SCAN_TOTALS,        /* eq. 12: block offsets, horizontal sums of column totals */
    GIM__PROGRAM_SCAN_OFFSETS,       /* eq. 12: block offsets added to the vertical sums */
    GIM__PROGRAM_SELECT,             /* binary-search selection of VALs */
    GIM__PROGRAM_RSM,                /* RSM of a light: position, normal + area, flux */
    GIM__PROGRAM_GBUFFER,            /* G-buffer: normal, albedo, depth */
    GIM__PROGRAM_VIEW_SAMPLES,       /* G-buffer at the Halton pixels -> view samples */
    GIM__PROGRAM_COUNT
} gim__program_id;

/* Shader files of each program (compute: one file; draw programs: vertex, fragment). */
static const char *const gim__program_files[GIM__PROGRAM_COUNT][2] = {
    {"importance_map.comp", NULL},
    {"importance_scan_columns.comp", NULL},
    {"importance_scan_totals.comp", NULL},
    {"importance_scan_offsets.comp", NULL},
    {"importance_select.comp", NULL},
    {"scene.vert", "rsm.frag"},
    {"scene.vert", "gbuffer.frag"},
    {"view_samples.comp", NULL}};

/* One uploaded mesh (a slot; used == 0: free). */
typedef struct gim__mesh {
    int used;
    uint32_t generation;          /* bumped when the slot is freed, so old handles fail */
    gim__GLuint vao, positions, normals, indices, triangle_material;
    uint32_t index_count, triangle_count;
    gim__GLenum index_type;
    uint32_t max_material;        /* largest material id of its triangles */
    float bmin[3], bmax[3];       /* model-space bounds */
    gim_cache *caches;            /* the host's model-space caches (copied), for later passes */
    uint32_t cache_count;
} gim__mesh;

/* One light's GL objects, sized to its last frame. */
typedef struct gim__light_gpu {
    uint32_t size;                /* side of the RSM textures; 0: none yet */
    gim__GLuint position, normal, flux, depth, fbo;
    gim__GLuint map, column, row, selected;
    uint64_t map_bytes, column_bytes, row_bytes, selected_bytes;
    gim_mat4 view, proj;
} gim__light_gpu;

struct gim_context {
    gim_env env;
    gim__gl gl;
    int gl_major, gl_minor;
    int gl_depth;               /* nesting of gim__gl_enter: only the outermost saves/restores */
    gim__gl_state saved;
    gim__GLint64 max_ssbo_bytes;  /* GL_MAX_SHADER_STORAGE_BLOCK_SIZE */
    gim__GLuint programs[GIM__PROGRAM_COUNT];
    gim__GLuint scan_blocks;      /* eq. 12 scratch: per-block column totals, then offsets */
    size_t scan_blocks_bytes;
    gim__GLint max_texture_size, max_viewport[2];
    /* the scene (see "the scene" below) */
    gim__mesh *meshes;            /* slots; a handle is slot + 1 | generation << 16 */
    uint32_t mesh_slots;
    gim_instance *instances;
    uint32_t instance_count, instance_capacity;
    gim_light lights[GIM_MAX_LIGHTS];
    uint32_t light_count;
    gim__GLuint materials;        /* SSBO: per material vec4 diffuse, vec4 (glossy, k) */
    uint32_t material_count;
    /* the frame's resources, sized to what the last frame used */
    gim__light_gpu light_gpu[GIM_MAX_LIGHTS];
    uint32_t gbuffer_width, gbuffer_height;
    gim__GLuint gbuffer_depth, gbuffer_normal, gbuffer_albedo, gbuffer_fbo;
    gim__GLuint nearest_sampler;  /* texelFetch of a depth texture needs compare mode NONE */
    gim__GLuint view_sample_pixels, view_samples;
    uint64_t view_sample_pixels_bytes, view_samples_bytes;
    gim_frame_outputs outputs;
};

/* Enter a call that touches GL: the outermost saves the host's state. Under GIMANY_DEBUG an
   error the host left pending is logged and cleared, so it is not blamed on gimany. */
static void gim__gl_enter(gim_context *ctx, const char *where) {
    if (ctx->gl_depth++ != 0) return;
#ifdef GIMANY_DEBUG
    {
        gim__GLenum e;
        int guard = 0;
        while ((e = ctx->gl.GetError()) != GIM__GL_NO_ERROR && guard++ < 16)
            gim__log(&ctx->env, GIM_LOG_WARNING, where, "GL error 0x%04x was pending before the call (left by the host)",
                     (unsigned)e);
    }
#else
    (void)where;
#endif
    gim__gl_state_save(&ctx->gl, &ctx->saved);
}

/* Leave it: the outermost restores the host's state. Returns r, so calls end `return gim__gl_leave(ctx, r);`. */
static gim_result gim__gl_leave(gim_context *ctx, gim_result r) {
    GIMANY_ASSERT(ctx->gl_depth > 0);
    if (--ctx->gl_depth == 0) gim__gl_state_restore(&ctx->gl, &ctx->saved);
    return r;
}

/* Under GIMANY_DEBUG: GIM_ERROR_GL (logged) when the pass just run raised a GL error. */
static gim_result gim__gl_check(gim_context *ctx, const char *where) {
#ifdef GIMANY_DEBUG
    gim__GLenum e, first = GIM__GL_NO_ERROR;
    int guard = 0;
    while ((e = ctx->gl.GetError()) != GIM__GL_NO_ERROR && guard++ < 16) {
        if (first == GIM__GL_NO_ERROR) first = e;
        gim__log(&ctx->env, GIM_LOG_ERROR, where, "GL error 0x%04x", (unsigned)e);
    }
    if (first != GIM__GL_NO_ERROR) return gim__fail(&ctx->env, GIM_ERROR_GL, where, "GL error 0x%04x", (unsigned)first);
#else
    (void)ctx; (void)where;
#endif
    return GIM_OK;
}

/* --- shaders --------------------------------------------------------------------------- */

/* One stage of a program to build: its GL type, a name for the log, its source (no #version). */
typedef struct gim__shader_stage {
    gim__GLenum type;
    const char *name;
    const char *source;
} gim__shader_stage;

/* Send an info log through the logger, one message per line (a message holds ~450 chars). */
static void gim__gl_log_info(const gim_context *ctx, const char *where, const char *log) {
    while (*log) {
        const char *end = strchr(log, '\n');
        int n = end ? (int)(end - log) : (int)strlen(log);
        if (n > 0) gim__log(&ctx->env, GIM_LOG_ERROR, where, "%.*s", n, log);
        log += n + (end ? 1 : 0);
    }
}

/* Compile and link stages into a program. The runtime prepends "#version 430 core\n", so
   the compiler's line numbers are one more than the file's. Failure: GIM_ERROR_GL with the
   info log through the logger, nothing left behind. */
static gim_result gim__gl_build_program(gim_context *ctx, const char *program_name, const gim__shader_stage *stages,
                                        int stage_count, gim__GLuint *out) {
    static const char version[] = "#version 430 core\n";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint shaders[3] = {0, 0, 0}, program = 0;
    gim__GLint ok = 0;
    char log[2048];
    gim_result r = GIM_OK;
    int i;
    GIMANY_ASSERT(stage_count >= 1 && stage_count <= 3);
    for (i = 0; i < stage_count && r == GIM_OK; ++i) {
        const gim__GLchar *src[2];
        src[0] = version;
        src[1] = stages[i].source;
        shaders[i] = gl->CreateShader(stages[i].type);
        if (!shaders[i]) {
            r = gim__fail(&ctx->env, GIM_ERROR_GL, program_name, "glCreateShader failed for %s", stages[i].name);
            break;
        }
        gl->ShaderSource(shaders[i], 2, src, NULL);
        gl->CompileShader(shaders[i]);
        gl->GetShaderiv(shaders[i], GIM__GL_COMPILE_STATUS, &ok);
        if (!ok) {
            log[0] = 0;
            gl->GetShaderInfoLog(shaders[i], (gim__GLsizei)sizeof log, NULL, log);
            log[sizeof log - 1] = 0;
            gim__gl_log_info(ctx, stages[i].name, log);
            r = gim__fail(&ctx->env, GIM_ERROR_GL, program_name, "%s does not compile (line numbers above are one past the file's)",
                          stages[i].name);
        }
    }
    if (r == GIM_OK) {
        program = gl->CreateProgram();
        if (!program) r = gim__fail(&ctx->env, GIM_ERROR_GL, program_name, "glCreateProgram failed");
    }
    if (r == GIM_OK) {
        for (i = 0; i < stage_count; ++i) gl->AttachShader(program, shaders[i]);
        gl->LinkProgram(program);
        for (i = 0; i < stage_count; ++i) gl->DetachShader(program, shaders[i]);
        gl->GetProgramiv(program, GIM__GL_LINK_STATUS, &ok);
        if (!ok) {
            log[0] = 0;
            gl->GetProgramInfoLog(program, (gim__GLsizei)sizeof log, NULL, log);
            log[sizeof log - 1] = 0;
            gim__gl_log_info(ctx, program_name, log);
            r = gim__fail(&ctx->env, GIM_ERROR_GL, program_name, "program does not link");
        }
    }
    for (i = 0; i < stage_count; ++i)
        if (shaders[i]) gl->DeleteShader(shaders[i]);
    if (r != GIM_OK) {
        if (program) gl->DeleteProgram(program);
        return r;
    }
    *out = program;
    return GIM_OK;
}

/* Source of an embedded shader file, or NULL. */
static const char *gim__embedded_source(const char *file) {
    const gim__embedded_shader *e;
    for (e = gim__embedded_shaders; e->name; ++e)
        if (strcmp(e->name, file) == 0) return (const char *)e->source;
    return NULL;
}

/* The program id, built on first use (a feature never used costs nothing). */
static gim_result gim__gl_program(gim_context *ctx, gim__program_id id, gim__GLuint *out) {
    gim__shader_stage stages[2];
    int n = 0, i;
    gim_result r;
    GIMANY_ASSERT((unsigned)id < GIM__PROGRAM_COUNT);
    if (ctx->programs[id]) { *out = ctx->programs[id]; return GIM_OK; }
    for (i = 0; i < 2 && gim__program_files[id][i]; ++i) {
        const char *file = gim__program_files[id][i], *dot = strrchr(file, '.');
        stages[n].name = file;
        stages[n].source = gim__embedded_source(file);
        if (!stages[n].source)
            return gim__fail(&ctx->env, GIM_ERROR_GL, file, "not in shaders_embedded.h (run `make shaders`)");
        if (dot && strcmp(dot, ".comp") == 0) stages[n].type = GIM__GL_COMPUTE_SHADER;
        else if (dot && strcmp(dot, ".vert") == 0) stages[n].type = GIM__GL_VERTEX_SHADER;
        else if (dot && strcmp(dot, ".geom") == 0) stages[n].type = GIM__GL_GEOMETRY_SHADER;
        else stages[n].type = GIM__GL_FRAGMENT_SHADER;
        ++n;
    }
    r = gim__gl_build_program(ctx, gim__program_files[id][0], stages, n, &ctx->programs[id]);
    if (r == GIM_OK) *out = ctx->programs[id];
    return r;
}

/* --- importance sampling passes (paper 000 sec. 4) -----------------------------------
   The shape of every pass: argument checks (no GL) -> gim__gl_enter -> the host objects it
   reads or writes checked (gim__gl_check_buffer/_texture) -> gim__gl_program (built on first
   use) -> bindings on the units/bindings of the state list only -> dispatch -> barrier for how
   the output is read next -> gim__gl_leave(ctx, gim__gl_check(ctx, where)). Every return after
   the enter goes through the leave. A new binding point or state item goes into the state list
   first (and into tests/gltest_runtime.c's distinctive state). */

#define GIM__SCAN_MAX_SIZE 16384u  /* largest RSM side the scan takes */

/* Make the context's scratch buffer at least bytes long (contents undefined). */
static gim_result gim__gl_scratch(gim_context *ctx, gim__GLuint *buffer, size_t *have, size_t bytes, const char *where) {
    const gim__gl *gl = &ctx->gl;
    if (*buffer && *have >= bytes) return GIM_OK;
    if (!*buffer) gl->GenBuffers(1, buffer);
    if (!*buffer) return gim__fail(&ctx->env, GIM_ERROR_GL, where, "glGenBuffers failed");
    gl->BindBuffer(GIM__GL_SHADER_STORAGE_BUFFER, *buffer);
    gl->BufferData(GIM__GL_SHADER_STORAGE_BUFFER, (gim__GLsizeiptr)bytes, NULL, GIM__GL_DYNAMIC_COPY);
    *have = bytes;
    return gim__gl_check(ctx, where);
}

/* A host buffer a pass reads or writes must exist and hold bytes: the shaders index it up to
   there, and an SSBO access past the end is undefined. Binds it to COPY_WRITE_BUFFER, so call
   between gim__gl_enter and gim__gl_leave. */
static gim_result gim__gl_check_buffer(gim_context *ctx, const char *where, const char *what, gim__GLuint buffer,
                                       uint64_t bytes) {
    gim__GLint64 size = 0;
    if (!buffer || !ctx->gl.IsBuffer(buffer))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s (%u) is not a buffer object", what, (unsigned)buffer);
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, buffer);
    ctx->gl.GetBufferParameteri64v(GIM__GL_COPY_WRITE_BUFFER, GIM__GL_BUFFER_SIZE, &size);
    if (size < 0 || (uint64_t)size < bytes)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s holds %lld bytes, the pass needs %llu", what,
                         (long long)size, (unsigned long long)bytes);
    return GIM_OK;
}

/* A host 2D texture a pass reads must exist, be 2D and be at least width x height at level 0.
   Binds it to TEXTURE_2D of the active unit (call between enter and leave). A texture of
   another target raises GL_INVALID_OPERATION in the bind; under GIMANY_DEBUG it is cleared,
   otherwise the host will see it. */
static gim_result gim__gl_check_texture(gim_context *ctx, const char *where, const char *what, gim__GLuint texture,
                                        uint32_t width, uint32_t height) {
    gim__GLint w = 0, h = 0;
    if (!texture || !ctx->gl.IsTexture(texture))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s (%u) is not a texture", what, (unsigned)texture);
    ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, texture);
    ctx->gl.GetIntegerv(GIM__GL_TEXTURE_BINDING_2D, &w);
    if ((gim__GLuint)w != texture) { /* GL 4.3 cannot ask a texture's target: the bind failed */
#ifdef GIMANY_DEBUG
        ctx->gl.GetError(); /* that GL_INVALID_OPERATION is ours (enter cleared the host's) */
#endif
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s (%u) is not a 2D texture", what,
                         (unsigned)texture);
    }
    ctx->gl.GetTexLevelParameteriv(GIM__GL_TEXTURE_2D, 0, GIM__GL_TEXTURE_WIDTH, &w);
    ctx->gl.GetTexLevelParameteriv(GIM__GL_TEXTURE_2D, 0, GIM__GL_TEXTURE_HEIGHT, &h);
    if (w < 0 || h < 0 || (uint32_t)w < width || (uint32_t)h < height)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s is %dx%d, the pass reads %ux%u", what, (int)w,
                         (int)h, (unsigned)width, (unsigned)height);
    return GIM_OK;
}

/* eq. 10-11 on the GPU, the twin of gim_importance_map. rsm_position, rsm_normal, rsm_flux:
   2D float textures of width x height (position.xyz with .w > 0 where the RSM saw a surface,
   the twin's rsm_valid; normal.xyz; flux.rgb), read with texelFetch on units 0-2.
   view_samples: SSBO of view_sample_count {vec4 position; vec4 normal} (xyz used). map: SSBO
   of width * height floats (row-major, row 0 first), written. clamp 0 means 1/64 of scene_scale.
   Cost: width * height * view_sample_count terms. */
static GIM__UNUSED gim_result gim__gl_importance_map(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                                     gim__GLuint rsm_flux, uint32_t width, uint32_t height,
                                                     gim__GLuint view_samples, uint32_t view_sample_count,
                                                     float scene_scale, float clamp, gim__GLuint map) {
    static const char where[] = "importance map (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0, textures[3];
    gim_result r;
    unsigned i;
    if (!rsm_position || !rsm_normal || !rsm_flux || !view_samples || !map)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a texture or buffer is 0");
    if (width == 0 || height == 0 || width > GIM__SCAN_MAX_SIZE || height > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..%u", (unsigned)width,
                         (unsigned)height, GIM__SCAN_MAX_SIZE);
    if (view_sample_count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no view samples");
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if (clamp == 0.0f) clamp = GIM__IMPORTANCE_DEFAULT_CLAMP;
    if (!(clamp > 0.0f) || !gim__isfinitef(clamp) || !gim__isfinitef(clamp * clamp))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "clamp %g must be finite and > 0", (double)clamp);
    gim__gl_enter(ctx, where);
    textures[0] = rsm_position;
    textures[1] = rsm_normal;
    textures[2] = rsm_flux;
    r = gim__gl_check_texture(ctx, where, "rsm_position", rsm_position, width, height);
    if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "rsm_normal", rsm_normal, width, height);
    if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "rsm_flux", rsm_flux, width, height);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "view_samples", view_samples, (uint64_t)view_sample_count * 32u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "map", map, (uint64_t)width * height * 4u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_IMPORTANCE_MAP, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    for (i = 0; i < 3; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->BindTexture(GIM__GL_TEXTURE_2D, textures[i]);
        gl->BindSampler(i, 0); /* a host sampler with mip filtering would make the texture incomplete */
    }
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, view_samples);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, map);
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, view_sample_count);
    gl->Uniform1f(2, (float)(1.0 / (double)scene_scale));
    gl->Uniform1f(3, clamp * clamp);
    gl->DispatchCompute((width + 15u) / 16u, (height + 15u) / 16u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* eq. 12 on the GPU, the twin of gim_importance_cumsum. map: SSBO of width * height floats
   (row-major, row 0 first); column: SSBO of width * height doubles, written with
   column[y * width + x] = sum of map(x, 0..y); row: SSBO of width doubles, written with
   row[x] = sum of the column totals 0..x. block_rows: rows per block of the first level
   (0: chosen from the size). Three dispatches, O(width * height) adds, in double like the twin: a float
   table at 1024^2 of uniform random importance already gives 0.1% of the texels a selection
   frequency more than 1% away from their P (tests/bench_gl.c), a bias the 1/P weights do not
   undo. The cost is memory, not arithmetic: 8 bytes per texel (128 MB at 4096^2, checked
   against GL_MAX_SHADER_STORAGE_BLOCK_SIZE); consumer GPUs' slow fp64 is ~3 adds per texel.
   On llvmpipe (2 shared, loaded cores) the double scan took 0.8-3x the time of the same
   shaders in float over several runs; a real GPU is bound by the memory traffic. */
static GIM__UNUSED gim_result gim__gl_importance_cumsum(gim_context *ctx, gim__GLuint map, gim__GLuint column,
                                                        gim__GLuint row, uint32_t width, uint32_t height,
                                                        uint32_t block_rows) {
    static const char where[] = "importance cumsum (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint p_columns = 0, p_totals = 0, p_offsets = 0;
    uint32_t blocks;
    gim_result r;
    if (!map || !column || !row) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (width == 0 || height == 0 || width > GIM__SCAN_MAX_SIZE || height > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..%u", (unsigned)width,
                         (unsigned)height, GIM__SCAN_MAX_SIZE);
    if (block_rows == 0) {
        /* ~64k (column, block) invocations in the first level, enough to fill a GPU; the second
           level then runs ~64k / 256 serial steps per invocation whatever the size */
        uint32_t want = (65536u + width - 1u) / width;
        block_rows = (height + want - 1u) / want;
        if (block_rows < 16u) block_rows = 16u;
    }
    blocks = (height + block_rows - 1u) / block_rows;
    if ((gim__GLint64)width * height * 8 > ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "%ux%u doubles exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes)", (unsigned)width,
                         (unsigned)height, (long long)ctx->max_ssbo_bytes);
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "map", map, (uint64_t)width * height * 4u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "column", column, (uint64_t)width * height * 8u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "row", row, (uint64_t)width * 8u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SCAN_COLUMNS, &p_columns);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SCAN_TOTALS, &p_totals);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SCAN_OFFSETS, &p_offsets);
    if (r == GIM_OK)
        r = gim__gl_scratch(ctx, &ctx->scan_blocks, &ctx->scan_blocks_bytes, (size_t)blocks * width * 8u, where);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, map);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, column);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, ctx->scan_blocks);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, row);

    gl->UseProgram(p_columns);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, block_rows);
    gl->DispatchCompute((width + 63u) / 64u, blocks, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);

    gl->UseProgram(p_totals);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, block_rows);
    gl->DispatchCompute(1u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);

    if (blocks > 1u) { /* one block: its offsets are 0 */
        gl->UseProgram(p_offsets);
        gl->Uniform2ui(0, width, height);
        gl->Uniform1ui(1, block_rows);
        gl->DispatchCompute((width + 15u) / 16u, (height + 15u) / 16u, 1u);
    }
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* Selection on the GPU, the twin of gim_importance_select: count VALs from the eq. 12 tables
   (column, row: SSBOs as gim__gl_importance_cumsum writes them) into out, an SSBO of count
   gim_selected_val (12 bytes each: x, y, pdf). Same seed, same picks as the twin. An all-zero
   map selects uniformly (the twin also logs a warning, which the GPU cannot without a read-back);
   pdf 0 marks a pick from tables that are not cumulative sums (the twin returns an error). */
static GIM__UNUSED gim_result gim__gl_importance_select(gim_context *ctx, gim__GLuint column, gim__GLuint row,
                                                        uint32_t width, uint32_t height, uint32_t count,
                                                        uint32_t seed, gim__GLuint out) {
    static const char where[] = "importance select (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    float off[4];
    gim_result r;
    if (!column || !row || !out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "count is 0");
    if (width == 0 || height == 0 || width > GIM__SCAN_MAX_SIZE || height > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..%u", (unsigned)width,
                         (unsigned)height, GIM__SCAN_MAX_SIZE);
    if (count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "count %u above %u", (unsigned)count, 65535u * 64u);
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "column", column, (uint64_t)width * height * 8u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "row", row, (uint64_t)width * 8u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "out", out, (uint64_t)count * 12u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SELECT, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    /* the twin's 48-bit rotation: two 24-bit offsets per dimension */
    gim_rotation_offsets(off, 4u, seed);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, column);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, row);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, out);
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, count);
    gl->Uniform2d(2, (double)off[0] + (double)off[2] * (1.0 / 16777216.0),
                  (double)off[1] + (double)off[3] * (1.0 / 16777216.0));
    gl->DispatchCompute((count + 63u) / 64u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* --- the scene (DESIGN.md sec. 2) ----------------------------------------------------------
   Meshes live in GL buffers (one VAO each); instances, lights and materials are small CPU
   copies (materials also an SSBO). Every setter checks all of its input first, so an error
   leaves the scene as it was. */

#define GIM__MAX_MESHES 65535u
#define GIM__MAX_VIEW_SAMPLES 65536u
#define GIM__DEFAULT_VIEW_SAMPLES 256u
#define GIM__DEFAULT_VAL_COUNT 2048u

static gim__mesh *gim__mesh_get(gim_context *ctx, gim_mesh m) {
    uint32_t slot = (m.id & 0xFFFFu), gen = m.id >> 16;
    if (slot == 0 || slot > ctx->mesh_slots) return NULL;
    if (!ctx->meshes[slot - 1].used || (ctx->meshes[slot - 1].generation & 0xFFFFu) != gen) return NULL;
    return &ctx->meshes[slot - 1];
}

static void gim__mesh_release(gim_context *ctx, gim__mesh *m) {
    const gim__gl *gl = &ctx->gl;
    if (m->vao) gl->DeleteVertexArrays(1, &m->vao);
    if (m->positions) gl->DeleteBuffers(1, &m->positions);
    if (m->normals) gl->DeleteBuffers(1, &m->normals);
    if (m->indices) gl->DeleteBuffers(1, &m->indices);
    if (m->triangle_material) gl->DeleteBuffers(1, &m->triangle_material);
    gim__free(&ctx->env, m->caches);
    {
        uint32_t gen = m->generation + 1u;
        memset(m, 0, sizeof *m);
        m->generation = gen;
    }
}

/* A buffer object holding bytes from data (bound to COPY_WRITE_BUFFER; call inside enter/leave). */
static gim__GLuint gim__gl_buffer_with(gim_context *ctx, const void *data, size_t bytes, gim__GLenum usage) {
    gim__GLuint b = 0;
    ctx->gl.GenBuffers(1, &b);
    if (!b) return 0;
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, b);
    ctx->gl.BufferData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLsizeiptr)bytes, data, usage);
    return b;
}

static uint32_t gim__index_at(const void *indices, gim_index_type type, size_t i) {
    if (type == GIM_INDEX_U16) return ((const uint16_t *)indices)[i];
    return ((const uint32_t *)indices)[i];
}

GIMANY_DEF gim_result gim_add_mesh(gim_context *ctx, const gim_mesh_desc *desc, gim_mesh *out) {
    static const char where[] = "gim_add_mesh";
    const gim_mesh_data *d;
    const gim__gl *gl;
    uint32_t pstride, nstride, i, slot, tri_count, max_material = 0;
    float *pos = NULL, *nrm = NULL;
    uint32_t *tri_material = NULL;
    gim_cache *caches = NULL;
    gim__mesh m;
    gim_result r = GIM_OK;
    size_t index_bytes;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!desc || !out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "desc or out is NULL");
    d = &desc->data;
    gl = &ctx->gl;
    pstride = d->position_stride ? d->position_stride : 12u;
    nstride = d->normal_stride ? d->normal_stride : 12u;
    if (!d->positions || d->vertex_count == 0 || !d->indices || d->index_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no positions or no indices");
    if (d->index_count % 3u != 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "index_count %u is not a multiple of 3",
                         (unsigned)d->index_count);
    if (pstride < 12u || pstride % 4u != 0 || nstride < 12u || nstride % 4u != 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "strides must be >= 12 and multiples of 4");
    if (d->index_type != GIM_INDEX_DEFAULT && d->index_type != GIM_INDEX_U32 && d->index_type != GIM_INDEX_U16)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown index_type %d", (int)d->index_type);
    if (d->vertex_count > 0x7FFFFFFFu / 3u || d->index_count > 0x7FFFFFFFu)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u vertices / %u indices: too many",
                         (unsigned)d->vertex_count, (unsigned)d->index_count);
    if (desc->caches && desc->caches->count && !desc->caches->caches)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "caches->caches is NULL with count %u",
                         (unsigned)desc->caches->count);
    tri_count = d->index_count / 3u;
    for (i = 0; i < d->index_count; ++i) {
        uint32_t v = gim__index_at(d->indices, d->index_type, i);
        if (v >= d->vertex_count)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "index %u is %u, vertex_count %u", (unsigned)i,
                             (unsigned)v, (unsigned)d->vertex_count);
    }
    for (slot = 0; slot < ctx->mesh_slots && ctx->meshes[slot].used; ++slot) {}
    if (slot == GIM__MAX_MESHES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "more than %u meshes", GIM__MAX_MESHES);
    memset(&m, 0, sizeof m);
    for (i = 0; i < 3; ++i) { m.bmin[i] = FLT_MAX; m.bmax[i] = -FLT_MAX; }
    /* tight float3 copies: positions checked as they are read */
    pos = (float *)gim__alloc_array(&ctx->env, (size_t)d->vertex_count * 3u, sizeof(float));
    nrm = (float *)gim__alloc_array(&ctx->env, (size_t)d->vertex_count * 3u, sizeof(float));
    tri_material = (uint32_t *)gim__alloc_array(&ctx->env, tri_count, sizeof(uint32_t));
    if (desc->caches && desc->caches->count)
        caches = (gim_cache *)gim__alloc_array(&ctx->env, desc->caches->count, sizeof(gim_cache));
    if (!pos || !nrm || !tri_material || (desc->caches && desc->caches->count && !caches)) {
        r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "copies of %u vertices", (unsigned)d->vertex_count);
        goto done;
    }
    for (i = 0; i < d->vertex_count; ++i) {
        const float *p = (const float *)(const void *)((const char *)d->positions + (size_t)i * pstride);
        int k;
        if (!gim__all_finite(p, 3)) {
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "position %u is not finite", (unsigned)i);
            goto done;
        }
        for (k = 0; k < 3; ++k) {
            pos[i * 3 + k] = p[k];
            if (p[k] < m.bmin[k]) m.bmin[k] = p[k];
            if (p[k] > m.bmax[k]) m.bmax[k] = p[k];
        }
    }
    if (d->normals) {
        for (i = 0; i < d->vertex_count; ++i) {
            const float *n = (const float *)(const void *)((const char *)d->normals + (size_t)i * nstride);
            if (!gim__all_finite(n, 3) || (n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f)) {
                r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "normal %u is zero or not finite", (unsigned)i);
                goto done;
            }
            memcpy(nrm + i * 3, n, 3 * sizeof(float));
        }
    } else {
        /* area-weighted vertex normals: the sum of the unnormalised face normals around it */
        memset(nrm, 0, (size_t)d->vertex_count * 3u * sizeof(float));
        for (i = 0; i < tri_count; ++i) {
            uint32_t a = gim__index_at(d->indices, d->index_type, i * 3u),
                     b = gim__index_at(d->indices, d->index_type, i * 3u + 1u),
                     c = gim__index_at(d->indices, d->index_type, i * 3u + 2u);
            gim_vec3 pa = gim_v3(pos[a * 3], pos[a * 3 + 1], pos[a * 3 + 2]);
            gim_vec3 fn = gim_v3_cross(gim_v3_sub(gim_v3(pos[b * 3], pos[b * 3 + 1], pos[b * 3 + 2]), pa),
                                       gim_v3_sub(gim_v3(pos[c * 3], pos[c * 3 + 1], pos[c * 3 + 2]), pa));
            uint32_t v[3];
            int k;
            v[0] = a; v[1] = b; v[2] = c;
            if (!gim_v3_isfinite(fn)) continue;
            for (k = 0; k < 3; ++k) {
                nrm[v[k] * 3] += fn.x;
                nrm[v[k] * 3 + 1] += fn.y;
                nrm[v[k] * 3 + 2] += fn.z;
            }
        }
        for (i = 0; i < d->vertex_count; ++i) {
            gim_vec3 n = gim_v3_normalize(gim_v3(nrm[i * 3], nrm[i * 3 + 1], nrm[i * 3 + 2]));
            if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) n = gim_v3(0.0f, 0.0f, 1.0f); /* only on degenerate triangles */
            nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z;
        }
    }
    for (i = 0; i < tri_count; ++i) {
        tri_material[i] = d->triangle_material ? d->triangle_material[i] : 0u;
        if (tri_material[i] > max_material) max_material = tri_material[i];
    }
    if (caches) {
        for (i = 0; i < desc->caches->count; ++i) {
            const gim_cache *c = &desc->caches->caches[i];
            if (!gim__all_finite(c->position, 3) || !gim__all_finite(c->normal, 3) || !gim__isfinitef(c->area) ||
                !gim__isfinitef(c->reflectance)) {
                r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "cache %u is not finite", (unsigned)i);
                goto done;
            }
        }
        memcpy(caches, desc->caches->caches, (size_t)desc->caches->count * sizeof(gim_cache));
    }
    if (slot == ctx->mesh_slots) { /* grow the slot array */
        uint32_t n = ctx->mesh_slots ? ctx->mesh_slots * 2u : 8u;
        gim__mesh *grown;
        if (n > GIM__MAX_MESHES) n = GIM__MAX_MESHES;
        grown = (gim__mesh *)gim__alloc_array(&ctx->env, n, sizeof(gim__mesh));
        if (!grown) {
            r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u mesh slots", (unsigned)n);
            goto done;
        }
        memset(grown, 0, (size_t)n * sizeof(gim__mesh));
        if (ctx->mesh_slots) memcpy(grown, ctx->meshes, (size_t)ctx->mesh_slots * sizeof(gim__mesh));
        gim__free(&ctx->env, ctx->meshes);
        ctx->meshes = grown;
        ctx->mesh_slots = n;
    }
    m.generation = ctx->meshes[slot].generation;
    m.index_count = d->index_count;
    m.triangle_count = tri_count;
    m.max_material = max_material;
    m.index_type = d->index_type == GIM_INDEX_U16 ? GIM__GL_UNSIGNED_SHORT : GIM__GL_UNSIGNED_INT;
    index_bytes = (size_t)d->index_count * (d->index_type == GIM_INDEX_U16 ? 2u : 4u);
    gim__gl_enter(ctx, where);
    m.positions = gim__gl_buffer_with(ctx, pos, (size_t)d->vertex_count * 12u, GIM__GL_STATIC_DRAW);
    m.normals = gim__gl_buffer_with(ctx, nrm, (size_t)d->vertex_count * 12u, GIM__GL_STATIC_DRAW);
    m.indices = gim__gl_buffer_with(ctx, d->indices, index_bytes, GIM__GL_STATIC_DRAW);
    m.triangle_material = gim__gl_buffer_with(ctx, tri_material, (size_t)tri_count * 4u, GIM__GL_STATIC_DRAW);
    gl->GenVertexArrays(1, &m.vao);
    if (m.vao && m.positions && m.normals && m.indices) {
        gl->BindVertexArray(m.vao);
        gl->BindBuffer(GIM__GL_ARRAY_BUFFER, m.positions);
        gl->VertexAttribPointer(0, 3, GIM__GL_FLOAT, GIM__GL_FALSE, 12, NULL);
        gl->EnableVertexAttribArray(0);
        gl->BindBuffer(GIM__GL_ARRAY_BUFFER, m.normals);
        gl->VertexAttribPointer(1, 3, GIM__GL_FLOAT, GIM__GL_FALSE, 12, NULL);
        gl->EnableVertexAttribArray(1);
        gl->BindBuffer(GIM__GL_ELEMENT_ARRAY_BUFFER, m.indices); /* VAO state */
    }
    r = gim__gl_check(ctx, where);
    if (r == GIM_OK && !(m.vao && m.positions && m.normals && m.indices && m.triangle_material))
        r = gim__fail(&ctx->env, GIM_ERROR_GL, where, "glGen* returned 0");
    m.caches = caches;
    m.cache_count = caches ? desc->caches->count : 0u;
    if (r != GIM_OK) {
        gl->BindVertexArray(0); /* not the host's: leave restores it */
        gim__mesh_release(ctx, &m); /* frees caches too */
        caches = NULL;
        gim__gl_leave(ctx, r);
        goto done;
    }
    gim__gl_leave(ctx, r);
    m.used = 1;
    ctx->meshes[slot] = m;
    caches = NULL;
    out->id = (slot + 1u) | ((m.generation & 0xFFFFu) << 16);
done:
    gim__free(&ctx->env, pos);
    gim__free(&ctx->env, nrm);
    gim__free(&ctx->env, tri_material);
    gim__free(&ctx->env, caches);
    return r;
}

GIMANY_DEF gim_result gim_remove_mesh(gim_context *ctx, gim_mesh mesh) {
    gim__mesh *m;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    m = gim__mesh_get(ctx, mesh);
    if (!m) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, "gim_remove_mesh", "mesh %u is not a mesh", (unsigned)mesh.id);
    gim__gl_enter(ctx, "gim_remove_mesh");
    gim__mesh_release(ctx, m);
    return gim__gl_leave(ctx, gim__gl_check(ctx, "gim_remove_mesh"));
}

GIMANY_DEF gim_result gim_set_materials(gim_context *ctx, const gim_material *materials, uint32_t count) {
    static const char where[] = "gim_set_materials";
    float *packed;
    uint32_t i;
    gim_result r;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (count && !materials) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "materials is NULL");
    if ((uint64_t)count * 32u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u materials exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE",
                         (unsigned)count);
    for (i = 0; i < count; ++i) {
        const gim_material *m = &materials[i];
        if (!gim__all_finite(m->diffuse, 3) || !gim__all_finite(m->glossy, 3) || !gim__isfinitef(m->exponent) ||
            m->diffuse[0] < 0.0f || m->diffuse[1] < 0.0f || m->diffuse[2] < 0.0f || m->glossy[0] < 0.0f ||
            m->glossy[1] < 0.0f || m->glossy[2] < 0.0f || m->exponent < 0.0f)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "material %u: values must be finite and >= 0",
                             (unsigned)i);
    }
    if (count == 0) {
        gim__gl_enter(ctx, where);
        if (ctx->materials) ctx->gl.DeleteBuffers(1, &ctx->materials);
        ctx->materials = 0;
        ctx->material_count = 0;
        return gim__gl_leave(ctx, gim__gl_check(ctx, where));
    }
    packed = (float *)gim__alloc_array(&ctx->env, count, 8u * sizeof(float));
    if (!packed) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u materials", (unsigned)count);
    for (i = 0; i < count; ++i) {
        float *p = packed + (size_t)i * 8u;
        memcpy(p, materials[i].diffuse, 3 * sizeof(float));
        p[3] = 0.0f;
        memcpy(p + 4, materials[i].glossy, 3 * sizeof(float));
        p[7] = materials[i].exponent;
    }
    gim__gl_enter(ctx, where);
    if (!ctx->materials) ctx->gl.GenBuffers(1, &ctx->materials);
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->materials);
    ctx->gl.BufferData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLsizeiptr)count * 32, packed, GIM__GL_STATIC_DRAW);
    gim__free(&ctx->env, packed);
    r = gim__gl_check(ctx, where);
    ctx->material_count = r == GIM_OK ? count : 0u;
    return gim__gl_leave(ctx, r);
}

GIMANY_DEF gim_result gim_set_instances(gim_context *ctx, const gim_instance *instances, uint32_t count) {
    static const char where[] = "gim_set_instances";
    uint32_t i;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (count && !instances) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instances is NULL");
    for (i = 0; i < count; ++i) {
        gim_mat4 inv;
        if (!gim__mesh_get(ctx, instances[i].mesh))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instance %u: mesh %u is not a mesh", (unsigned)i,
                             (unsigned)instances[i].mesh.id);
        if (!gim_mat4_isfinite(instances[i].model) || !gim_mat4_invert(instances[i].model, &inv))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instance %u: model matrix not finite or singular",
                             (unsigned)i);
    }
    if (count > ctx->instance_capacity) {
        gim_instance *grown = (gim_instance *)gim__alloc_array(&ctx->env, count, sizeof(gim_instance));
        if (!grown) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u instances", (unsigned)count);
        gim__free(&ctx->env, ctx->instances);
        ctx->instances = grown;
        ctx->instance_capacity = count;
    }
    if (count) memcpy(ctx->instances, instances, (size_t)count * sizeof(gim_instance));
    ctx->instance_count = count;
    return GIM_OK;
}

/* Delete one light's GL objects. */
static void gim__light_gpu_release(gim_context *ctx, gim__light_gpu *g) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint t[4], b[4];
    t[0] = g->position; t[1] = g->normal; t[2] = g->flux; t[3] = g->depth;
    b[0] = g->map; b[1] = g->column; b[2] = g->row; b[3] = g->selected;
    gl->DeleteTextures(4, t); /* 0 names are ignored */
    gl->DeleteBuffers(4, b);
    if (g->fbo) gl->DeleteFramebuffers(1, &g->fbo);
    memset(g, 0, sizeof *g);
}

GIMANY_DEF gim_result gim_set_lights(gim_context *ctx, const gim_light *lights, uint32_t count) {
    static const char where[] = "gim_set_lights";
    uint32_t i, limit;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (count && !lights) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "lights is NULL");
    if (count > GIM_MAX_LIGHTS)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u lights, at most %u", (unsigned)count, GIM_MAX_LIGHTS);
    limit = (uint32_t)ctx->max_texture_size;
    if ((uint32_t)ctx->max_viewport[0] < limit) limit = (uint32_t)ctx->max_viewport[0];
    if ((uint32_t)ctx->max_viewport[1] < limit) limit = (uint32_t)ctx->max_viewport[1];
    for (i = 0; i < count; ++i) {
        gim_result r = gim__light_check(&lights[i], &ctx->env, where, i);
        if (r != GIM_OK) return r;
        if (gim__light_rsm_size(&lights[i]) > limit)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: rsm_size %u above the GL limit %u",
                             (unsigned)i, (unsigned)gim__light_rsm_size(&lights[i]), (unsigned)limit);
    }
    if (count) memcpy(ctx->lights, lights, (size_t)count * sizeof(gim_light));
    if (count < ctx->light_count) { /* buffers sized to what is used: drop the removed lights' */
        gim__gl_enter(ctx, where);
        for (i = count; i < ctx->light_count; ++i) gim__light_gpu_release(ctx, &ctx->light_gpu[i]);
        ctx->light_count = count;
        ctx->outputs.valid = 0;
        return gim__gl_leave(ctx, gim__gl_check(ctx, where));
    }
    ctx->light_count = count;
    return GIM_OK;
}

static void gim__scene_destroy(gim_context *ctx) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i;
    gim__GLuint t[3];
    for (i = 0; i < ctx->mesh_slots; ++i)
        if (ctx->meshes[i].used) gim__mesh_release(ctx, &ctx->meshes[i]);
    gim__free(&ctx->env, ctx->meshes);
    gim__free(&ctx->env, ctx->instances);
    for (i = 0; i < GIM_MAX_LIGHTS; ++i) gim__light_gpu_release(ctx, &ctx->light_gpu[i]);
    t[0] = ctx->gbuffer_depth; t[1] = ctx->gbuffer_normal; t[2] = ctx->gbuffer_albedo;
    gl->DeleteTextures(3, t);
    if (ctx->gbuffer_fbo) gl->DeleteFramebuffers(1, &ctx->gbuffer_fbo);
    if (ctx->nearest_sampler) gl->DeleteSamplers(1, &ctx->nearest_sampler);
    if (ctx->materials) gl->DeleteBuffers(1, &ctx->materials);
    if (ctx->view_sample_pixels) gl->DeleteBuffers(1, &ctx->view_sample_pixels);
    if (ctx->view_samples) gl->DeleteBuffers(1, &ctx->view_samples);
}

/* --- the shared passes of the frame (DESIGN.md sec. 5) ------------------------------------- */

/* A width x height single-level texture of format, nearest, clamped (replaces *tex). */
static void gim__gl_texture(gim_context *ctx, gim__GLuint *tex, gim__GLenum format, uint32_t w, uint32_t h) {
    const gim__gl *gl = &ctx->gl;
    if (*tex) gl->DeleteTextures(1, tex);
    *tex = 0;
    gl->GenTextures(1, tex);
    gl->ActiveTexture(GIM__GL_TEXTURE0);
    gl->BindTexture(GIM__GL_TEXTURE_2D, *tex);
    gl->TexStorage2D(GIM__GL_TEXTURE_2D, 1, format, (gim__GLsizei)w, (gim__GLsizei)h);
    gl->TexParameteri(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_MIN_FILTER, GIM__GL_NEAREST);
    gl->TexParameteri(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_MAG_FILTER, GIM__GL_NEAREST);
    gl->TexParameteri(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_WRAP_S, GIM__GL_CLAMP_TO_EDGE);
    gl->TexParameteri(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_WRAP_T, GIM__GL_CLAMP_TO_EDGE);
}

/* An FBO with colour attachments color[0..n-1] and depth (replaces *fbo). */
static gim_result gim__gl_framebuffer(gim_context *ctx, gim__GLuint *fbo, const gim__GLuint *color, int n,
                                      gim__GLuint depth, const char *where) {
    const gim__gl *gl = &ctx->gl;
    gim__GLenum bufs[4];
    gim__GLenum status;
    int i;
    if (*fbo) gl->DeleteFramebuffers(1, fbo);
    *fbo = 0;
    gl->GenFramebuffers(1, fbo);
    gl->BindFramebuffer(GIM__GL_FRAMEBUFFER, *fbo);
    for (i = 0; i < n; ++i) {
        gl->FramebufferTexture2D(GIM__GL_FRAMEBUFFER, GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i, GIM__GL_TEXTURE_2D,
                                 color[i], 0);
        bufs[i] = GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i;
    }
    gl->FramebufferTexture2D(GIM__GL_FRAMEBUFFER, GIM__GL_DEPTH_ATTACHMENT, GIM__GL_TEXTURE_2D, depth, 0);
    gl->DrawBuffers(n, bufs);
    status = gl->CheckFramebufferStatus(GIM__GL_FRAMEBUFFER);
    if (status != GIM__GL_FRAMEBUFFER_COMPLETE)
        return gim__fail(&ctx->env, GIM_ERROR_GL, where, "framebuffer incomplete (0x%04x)", (unsigned)status);
    return gim__gl_check(ctx, where);
}

/* A buffer of at least bytes (exactly bytes when it grows or shrinks by half or more). */
static gim_result gim__gl_sized_buffer(gim_context *ctx, gim__GLuint *b, uint64_t *have, uint64_t bytes, const char *where) {
    if (*b && *have >= bytes && *have / 2u < bytes) return GIM_OK;
    if (!*b) ctx->gl.GenBuffers(1, b);
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, *b);
    ctx->gl.BufferData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLsizeiptr)bytes, NULL, GIM__GL_DYNAMIC_COPY);
    *have = 0; /* unknown until the check passes (a failed glBufferData leaves the store undefined) */
    if (gim__gl_check(ctx, where) != GIM_OK) return GIM_ERROR_GL;
    *have = bytes;
    return GIM_OK;
}

/* Raster state of the RSM and G-buffer passes, everything from the state list. */
static void gim__gl_raster_state(const gim__gl *gl, gim__GLuint fbo, uint32_t w, uint32_t h) {
    static const gim__GLenum off[] = {GIM__GL_BLEND, GIM__GL_CULL_FACE, GIM__GL_STENCIL_TEST, GIM__GL_SCISSOR_TEST,
                                      GIM__GL_PRIMITIVE_RESTART, GIM__GL_RASTERIZER_DISCARD,
                                      GIM__GL_POLYGON_OFFSET_FILL, GIM__GL_FRAMEBUFFER_SRGB, GIM__GL_DEPTH_CLAMP,
                                      GIM__GL_CLIP_DISTANCE0, GIM__GL_CLIP_DISTANCE0 + 1, GIM__GL_CLIP_DISTANCE0 + 2,
                                      GIM__GL_CLIP_DISTANCE0 + 3, GIM__GL_CLIP_DISTANCE0 + 4, GIM__GL_CLIP_DISTANCE0 + 5,
                                      GIM__GL_CLIP_DISTANCE0 + 6, GIM__GL_CLIP_DISTANCE0 + 7, GIM__GL_POLYGON_SMOOTH};
    unsigned i;
    gl->BindFramebuffer(GIM__GL_FRAMEBUFFER, fbo);
    gl->Viewport(0, 0, (gim__GLsizei)w, (gim__GLsizei)h);
    for (i = 0; i < sizeof off / sizeof off[0]; ++i) gl->Disable(off[i]);
    gl->Enable(GIM__GL_DEPTH_TEST);
    gl->DepthFunc(GIM__GL_LESS);
    gl->DepthMask(GIM__GL_TRUE);
    gl->ColorMask(GIM__GL_TRUE, GIM__GL_TRUE, GIM__GL_TRUE, GIM__GL_TRUE);
    gl->PolygonMode(GIM__GL_FRONT_AND_BACK, GIM__GL_FILL);
    gl->DepthRange(0.0, 1.0);
}

/* Clear n colour attachments to 0 and depth to 1. */
static void gim__gl_clear_targets(const gim__gl *gl, int n) {
    static const float zero[4] = {0.0f, 0.0f, 0.0f, 0.0f}, one = 1.0f;
    int i;
    for (i = 0; i < n; ++i) gl->ClearBufferfv(GIM__GL_COLOR, i, zero);
    gl->ClearBufferfv(GIM__GL_DEPTH, 0, &one);
}

/* Draw every instance with program (scene.vert's uniforms: 0 model, 1 normal matrix,
   2 view_proj; SSBO 0 materials, 1 the mesh's triangle materials). */
static void gim__gl_draw_instances(gim_context *ctx, gim_mat4 view_proj) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i;
    gl->UniformMatrix4fv(2, 1, GIM__GL_FALSE, view_proj.m);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->materials);
    for (i = 0; i < ctx->instance_count; ++i) {
        const gim_instance *in = &ctx->instances[i];
        const gim__mesh *m = gim__mesh_get(ctx, in->mesh);
        gim_mat4 nm = gim_mat4_normal(in->model);
        gl->UniformMatrix4fv(0, 1, GIM__GL_FALSE, in->model.m);
        gl->UniformMatrix4fv(1, 1, GIM__GL_FALSE, nm.m);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, m->triangle_material);
        gl->BindVertexArray(m->vao);
        gl->DrawElements(GIM__GL_TRIANGLES, (gim__GLsizei)m->index_count, m->index_type, NULL);
    }
}

/* The eye of a camera as the fragment shaders take it: (position, 1) for a perspective
   projection, (unit direction towards the eye, 0) for an orthographic one. */
static void gim__camera_eye(gim_mat4 view, gim_mat4 proj, float eye[4]) {
    gim_mat4 inv;
    if (!gim_mat4_invert(view, &inv)) inv = gim_mat4_identity();
    if (proj.m[11] != 0.0f) {
        eye[0] = inv.m[12]; eye[1] = inv.m[13]; eye[2] = inv.m[14]; eye[3] = 1.0f;
    } else {
        gim_vec3 z = gim_v3_normalize(gim_v3(inv.m[8], inv.m[9], inv.m[10])); /* the view's +z */
        eye[0] = z.x; eye[1] = z.y; eye[2] = z.z; eye[3] = 0.0f;
    }
}

/* RSM of light i (paper 000 sec. 3; units in @section twins): position (w = lit),
   normal (w = A), flux, depth. */
static gim_result gim__gl_rsm(gim_context *ctx, uint32_t i, const float bmin[3], const float bmax[3]) {
    static const char where[] = "RSM (GL)";
    const gim__gl *gl = &ctx->gl;
    const gim_light *l = &ctx->lights[i];
    gim__light_gpu *g = &ctx->light_gpu[i];
    uint32_t size = gim__light_rsm_size(l);
    gim__GLuint program = 0;
    float power[3], eye[4];
    gim_result r = gim_light_camera(l, bmin, bmax, &g->view, &g->proj);
    if (r != GIM_OK) return gim__fail(&ctx->env, r, where, "light %u: no camera for the scene bounds", (unsigned)i);
    r = gim__gl_program(ctx, GIM__PROGRAM_RSM, &program);
    if (r != GIM_OK) return r;
    if (g->size != size) {
        gim__GLuint color[3];
        gim__gl_texture(ctx, &g->position, GIM__GL_RGBA32F, size, size);
        gim__gl_texture(ctx, &g->normal, GIM__GL_RGBA32F, size, size);
        gim__gl_texture(ctx, &g->flux, GIM__GL_RGBA32F, size, size);
        gim__gl_texture(ctx, &g->depth, GIM__GL_DEPTH_COMPONENT32F, size, size);
        color[0] = g->position; color[1] = g->normal; color[2] = g->flux;
        g->size = 0;
        r = gim__gl_framebuffer(ctx, &g->fbo, color, 3, g->depth, where);
        if (r != GIM_OK) return r;
        g->size = size;
    }
    gim__light_power(l, power);
    gim__camera_eye(g->view, g->proj, eye);
    gim__gl_raster_state(gl, g->fbo, size, size);
    gim__gl_clear_targets(gl, 3);
    gl->UseProgram(program);
    gl->Uniform1ui(3, ctx->material_count);
    gl->Uniform4f(4, eye[0], eye[1], eye[2], eye[3]);
    if (l->type == GIM_LIGHT_SPOT) {
        gim_vec3 axis = gim_v3_normalize(l->direction);
        float tan_half = 1.0f / g->proj.m[5], s = 2.0f * tan_half / (float)size;
        gl->Uniform1i(5, 1);
        gl->Uniform3f(6, power[0], power[1], power[2]);                   /* flux = albedo I w */
        gl->Uniform4f(7, axis.x, axis.y, axis.z, cosf(l->cone_angle));
        gl->Uniform4f(8, (float)size, tan_half, s * s, 0.0f);
    } else {
        float side = 2.0f / g->proj.m[0] / (float)size, a = side * side;  /* perpendicular texel area */
        gl->Uniform1i(5, 0);
        gl->Uniform3f(6, power[0] * a, power[1] * a, power[2] * a);     /* flux = albedo E a */
        gl->Uniform4f(7, 0.0f, 0.0f, 0.0f, -2.0f);
        gl->Uniform4f(8, (float)size, 0.0f, a, 0.0f);
    }
    gl->Uniform1f(9, GIM_RSM_MIN_COS);
    gim__gl_draw_instances(ctx, gim_mat4_mul(g->proj, g->view));
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* gimany's own G-buffer: depth (32-bit float), world normal towards the eye (RGBA16F, w = 1
   where drawn), diffuse albedo (RGBA8). */
static gim_result gim__gl_gbuffer(gim_context *ctx, const gim_frame *f) {
    static const char where[] = "G-buffer (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    float eye[4];
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_GBUFFER, &program);
    if (r != GIM_OK) return r;
    if (ctx->gbuffer_width != f->width || ctx->gbuffer_height != f->height || !ctx->gbuffer_fbo) {
        gim__GLuint color[2];
        gim__gl_texture(ctx, &ctx->gbuffer_depth, GIM__GL_DEPTH_COMPONENT32F, f->width, f->height);
        /* 12 bytes a pixel: half normals (~5e-4) are plenty for the cosines of eq. 10, 8-bit
           albedo is what engines keep; positions come from the 32-bit depth */
        gim__gl_texture(ctx, &ctx->gbuffer_normal, GIM__GL_RGBA16F, f->width, f->height);
        gim__gl_texture(ctx, &ctx->gbuffer_albedo, GIM__GL_RGBA8, f->width, f->height);
        color[0] = ctx->gbuffer_normal; color[1] = ctx->gbuffer_albedo;
        ctx->gbuffer_width = ctx->gbuffer_height = 0;
        r = gim__gl_framebuffer(ctx, &ctx->gbuffer_fbo, color, 2, ctx->gbuffer_depth, where);
        if (r != GIM_OK) return r;
        ctx->gbuffer_width = f->width;
        ctx->gbuffer_height = f->height;
    }
    gim__camera_eye(f->view, f->proj, eye);
    gim__gl_raster_state(gl, ctx->gbuffer_fbo, f->width, f->height);
    gim__gl_clear_targets(gl, 2);
    gl->UseProgram(program);
    gl->Uniform1ui(3, ctx->material_count);
    gl->Uniform4f(4, eye[0], eye[1], eye[2], eye[3]);
    gim__gl_draw_instances(ctx, gim_mat4_mul(f->proj, f->view));
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* View samples (paper 000 sec. 4): the G-buffer at count Halton pixels (gim_view_sample_pixels,
   computed here and uploaded: the same pixels as the twin, bit for bit), unprojected. */
static gim_result gim__gl_view_samples(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                       uint32_t count) {
    static const char where[] = "view samples (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_mat4 inv_view, inv_proj;
    uint32_t *pixels;
    float off[2];
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_VIEW_SAMPLES, &program);
    if (r != GIM_OK) return r;
    if (!gim_mat4_invert(f->view, &inv_view) || !gim_mat4_invert(f->proj, &inv_proj))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj is singular");
    pixels = (uint32_t *)gim__alloc_array(&ctx->env, count, 2u * sizeof(uint32_t));
    if (!pixels) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u view samples", (unsigned)count);
    if (f->rotate_view_samples) gim_rotation_offsets(off, 2u, f->frame_index);
    gim_view_sample_pixels(count, f->width, f->height, f->rotate_view_samples ? off : NULL, pixels);
    r = gim__gl_sized_buffer(ctx, &ctx->view_sample_pixels, &ctx->view_sample_pixels_bytes, (uint64_t)count * 8u, where);
    if (r == GIM_OK)
        r = gim__gl_sized_buffer(ctx, &ctx->view_samples, &ctx->view_samples_bytes, (uint64_t)count * 32u, where);
    if (r == GIM_OK) {
        gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->view_sample_pixels);
        gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)count * 8, pixels);
    }
    gim__free(&ctx->env, pixels);
    if (r != GIM_OK) return r;
    if (!ctx->nearest_sampler) {
        gl->GenSamplers(1, &ctx->nearest_sampler);
        gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_MIN_FILTER, GIM__GL_NEAREST);
        gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_MAG_FILTER, GIM__GL_NEAREST);
        gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_COMPARE_MODE, GIM__GL_NONE);
    }
    gl->ActiveTexture(GIM__GL_TEXTURE0);
    gl->BindTexture(GIM__GL_TEXTURE_2D, depth);
    gl->BindSampler(0, ctx->nearest_sampler);
    gl->ActiveTexture(GIM__GL_TEXTURE0 + 1);
    gl->BindTexture(GIM__GL_TEXTURE_2D, normal);
    gl->BindSampler(1, ctx->nearest_sampler);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->view_sample_pixels);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, ctx->view_samples);
    gl->UseProgram(program);
    gl->Uniform1ui(0, count);
    gl->Uniform2ui(1, f->width, f->height);
    gl->UniformMatrix4fv(2, 1, GIM__GL_FALSE, inv_proj.m);
    gl->UniformMatrix4fv(3, 1, GIM__GL_FALSE, inv_view.m);
    gl->DispatchCompute((count + 63u) / 64u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* Argument checks of gim_update that need no GL. */
static gim_result gim__frame_check(gim_context *ctx, const gim_frame *f, float bmin[3], float bmax[3]) {
    static const char where[] = "gim_update";
    gim_mat4 inv;
    uint32_t i, limit;
    if (!gim_mat4_isfinite(f->view) || !gim_mat4_isfinite(f->proj) || !gim_mat4_invert(f->view, &inv) ||
        !gim_mat4_invert(f->proj, &inv))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj is not finite or singular");
    limit = (uint32_t)ctx->max_texture_size;
    if (f->width == 0 || f->height == 0 || f->width > limit || f->height > limit ||
        f->width > (uint32_t)ctx->max_viewport[0] || f->height > (uint32_t)ctx->max_viewport[1])
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..GL limits (%d, viewport %dx%d)",
                         (unsigned)f->width, (unsigned)f->height, (int)ctx->max_texture_size, (int)ctx->max_viewport[0],
                         (int)ctx->max_viewport[1]);
    if ((f->gbuffer_depth == 0) != (f->gbuffer_normal == 0))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "gbuffer_depth and gbuffer_normal: both or neither");
    if (f->view_sample_count > GIM__MAX_VIEW_SAMPLES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "view_sample_count %u above %u",
                         (unsigned)f->view_sample_count, GIM__MAX_VIEW_SAMPLES);
    if (f->val_count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "val_count %u above %u", (unsigned)f->val_count,
                         65535u * 64u);
    if (!gim__isfinitef(f->scene_scale) || f->scene_scale < 0.0f || !gim__isfinitef(f->importance_clamp) ||
        f->importance_clamp < 0.0f)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale and importance_clamp: finite, >= 0");
    if (ctx->instance_count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no instances");
    for (i = 0; i < 3; ++i) { bmin[i] = FLT_MAX; bmax[i] = -FLT_MAX; }
    for (i = 0; i < ctx->instance_count; ++i) {
        const gim_instance *in = &ctx->instances[i];
        const gim__mesh *m = gim__mesh_get(ctx, in->mesh);
        int k, j;
        if (!m)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instance %u: mesh %u was removed", (unsigned)i,
                             (unsigned)in->mesh.id);
        if (m->max_material >= ctx->material_count)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                             "instance %u: its mesh uses material %u, %u materials are set", (unsigned)i,
                             (unsigned)m->max_material, (unsigned)ctx->material_count);
        for (k = 0; k < 8; ++k) { /* world bounds from the 8 corners of the model bounds */
            gim_vec3 c = gim_mat4_point(in->model, gim_v3((k & 1) ? m->bmax[0] : m->bmin[0], (k & 2) ? m->bmax[1] : m->bmin[1],
                                                          (k & 4) ? m->bmax[2] : m->bmin[2]));
            float cv[3];
            cv[0] = c.x; cv[1] = c.y; cv[2] = c.z;
            for (j = 0; j < 3; ++j) {
                if (cv[j] < bmin[j]) bmin[j] = cv[j];
                if (cv[j] > bmax[j]) bmax[j] = cv[j];
            }
        }
    }
    if (!gim__all_finite(bmin, 3) || !gim__all_finite(bmax, 3))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "the world bounds of the instances are not finite");
    return GIM_OK;
}

GIMANY_DEF gim_result gim_update(gim_context *ctx, const gim_frame *frame) {
    static const char where[] = "gim_update";
    gim_frame_outputs o;
    float bmin[3], bmax[3], scale;
    uint32_t i, vs_count, val_count;
    gim__GLuint depth, normal;
    gim_result r;
    double diag;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!frame) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "frame is NULL");
    r = gim__frame_check(ctx, frame, bmin, bmax);
    if (r != GIM_OK) return r;
    diag = sqrt(((double)bmax[0] - bmin[0]) * ((double)bmax[0] - bmin[0]) +
                ((double)bmax[1] - bmin[1]) * ((double)bmax[1] - bmin[1]) +
                ((double)bmax[2] - bmin[2]) * ((double)bmax[2] - bmin[2]));
    scale = frame->scene_scale > 0.0f ? frame->scene_scale : (float)diag;
    if (!(scale > 0.0f) || !gim__isfinitef(scale))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "scene scale %g (the scene has no extent)", (double)scale);
    vs_count = frame->view_sample_count ? frame->view_sample_count : GIM__DEFAULT_VIEW_SAMPLES;
    val_count = frame->val_count ? frame->val_count : GIM__DEFAULT_VAL_COUNT;
    ctx->outputs.valid = 0;
    gim__gl_enter(ctx, where);
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) r = gim__gl_rsm(ctx, i, bmin, bmax);
    if (r == GIM_OK && frame->gbuffer_depth) {
        depth = frame->gbuffer_depth;
        normal = frame->gbuffer_normal;
        r = gim__gl_check_texture(ctx, where, "gbuffer_depth", depth, frame->width, frame->height);
        if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "gbuffer_normal", normal, frame->width, frame->height);
    } else if (r == GIM_OK) {
        r = gim__gl_gbuffer(ctx, frame);
        depth = ctx->gbuffer_depth;
        normal = ctx->gbuffer_normal;
    } else {
        depth = normal = 0;
    }
    if (r == GIM_OK) r = gim__gl_view_samples(ctx, frame, depth, normal, vs_count);
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) {
        gim__light_gpu *g = &ctx->light_gpu[i];
        uint64_t texels = (uint64_t)g->size * g->size;
        if (texels * 8u > (uint64_t)ctx->max_ssbo_bytes)
            r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: a %u^2 RSM's eq. 12 table exceeds "
                          "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", (unsigned)i, (unsigned)g->size);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->map, &g->map_bytes, texels * 4u, where);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->column, &g->column_bytes, texels * 8u, where);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->row, &g->row_bytes, (uint64_t)g->size * 8u, where);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->selected, &g->selected_bytes, (uint64_t)val_count * 12u, where);
        if (r == GIM_OK)
            r = gim__gl_importance_map(ctx, g->position, g->normal, g->flux, g->size, g->size, ctx->view_samples, vs_count,
                                       scale, frame->importance_clamp, g->map);
        if (r == GIM_OK) r = gim__gl_importance_cumsum(ctx, g->map, g->column, g->row, g->size, g->size, 0u);
        if (r == GIM_OK)
            r = gim__gl_importance_select(ctx, g->column, g->row, g->size, g->size, val_count,
                                          frame->frame_index * GIM_MAX_LIGHTS + i, g->selected);
    }
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    memset(&o, 0, sizeof o);
    o.valid = 1;
    o.width = frame->width;
    o.height = frame->height;
    o.gbuffer_depth = depth;
    o.gbuffer_normal = normal;
    o.gbuffer_albedo = frame->gbuffer_depth ? 0u : ctx->gbuffer_albedo;
    o.view_samples = ctx->view_samples;
    o.view_sample_count = vs_count;
    o.scene_scale = scale;
    memcpy(o.bounds_min, bmin, sizeof bmin);
    memcpy(o.bounds_max, bmax, sizeof bmax);
    o.light_count = ctx->light_count;
    for (i = 0; i < ctx->light_count; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        gim_light_outputs *lo = &o.lights[i];
        lo->rsm_size = g->size;
        lo->rsm_position = g->position;
        lo->rsm_normal = g->normal;
        lo->rsm_flux = g->flux;
        lo->rsm_depth = g->depth;
        lo->view = g->view;
        lo->proj = g->proj;
        lo->importance = g->map;
        lo->column = g->column;
        lo->row = g->row;
        lo->selected = g->selected;
        lo->selected_count = val_count;
    }
    ctx->outputs = o;
    return gim__gl_leave(ctx, GIM_OK);
}

GIMANY_DEF gim_frame_outputs gim_outputs(const gim_context *ctx) {
    gim_frame_outputs o;
    if (ctx) return ctx->outputs;
    memset(&o, 0, sizeof o);
    return o;
}

/* --- create / destroy ------------------------------------------------------------------ */

/* "4.6 (Core Profile) Mesa ..." or "OpenGL ES 3.2 ...": the major.minor a legacy context
   (no GL_MAJOR_VERSION query) reports in its version string. */
static void gim__gl_parse_version(const char *s, int *major, int *minor) {
    *major = *minor = 0;
    if (!s) return;
    while (*s && (*s < '0' || *s > '9')) ++s;
    while (*s >= '0' && *s <= '9') *major = *major * 10 + (*s++ - '0');
    if (*s == '.') ++s;
    while (*s >= '0' && *s <= '9') *minor = *minor * 10 + (*s++ - '0');
}

GIMANY_DEF gim_result gim_create(const gim_desc *desc, gim_context **out) {
    gim__gl gl;
    gim_context *ctx;
    gim__GLint major = 0, minor = 0;
    const char *version, *renderer, *vendor, *glsl;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT; /* no env to log through */
    if (!out) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, "gim_create", "out is NULL");
#ifndef GIMANY_EXTERNAL_GL
    if (!desc->get_proc_address)
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, "gim_create",
                         "desc.get_proc_address is NULL (pass eglGetProcAddress, glfwGetProcAddress, ...)");
#endif
    r = gim__gl_load(&gl, desc->get_proc_address, &desc->env);
    if (r != GIM_OK) return r;

    version = (const char *)gl.GetString(GIM__GL_VERSION);
    renderer = (const char *)gl.GetString(GIM__GL_RENDERER);
    vendor = (const char *)gl.GetString(GIM__GL_VENDOR);
    if (!version)
        return gim__fail(&desc->env, GIM_ERROR_UNSUPPORTED, "gim_create", "glGetString(GL_VERSION) is NULL: is a GL context current?");
    gl.GetIntegerv(GIM__GL_MAJOR_VERSION, &major);
    gl.GetIntegerv(GIM__GL_MINOR_VERSION, &minor);
    if (major < 3) { /* before 3.0 the query is GL_INVALID_ENUM: clear it, read the string */
        int guard = 0;
        while (gl.GetError() != GIM__GL_NO_ERROR && guard++ < 16) {}
        gim__gl_parse_version(version, &major, &minor);
    }
    if (strncmp(version, "OpenGL ES", 9) == 0 || major < 4 || (major == 4 && minor < 3))
        return gim__fail(&desc->env, GIM_ERROR_UNSUPPORTED, "gim_create",
                         "the context is %s %d.%d (\"%s\", %s): gimany needs desktop OpenGL 4.3",
                         strncmp(version, "OpenGL ES", 9) == 0 ? "OpenGL ES" : "OpenGL", (int)major, (int)minor, version,
                         renderer ? renderer : "?");
    glsl = (const char *)gl.GetString(GIM__GL_SHADING_LANGUAGE_VERSION);
    gim__log(&desc->env, GIM_LOG_INFO, "gim_create", "OpenGL %s; renderer %s; vendor %s; GLSL %s", version,
             renderer ? renderer : "?", vendor ? vendor : "?", glsl ? glsl : "?");

    ctx = (gim_context *)gim__alloc(&desc->env, sizeof *ctx);
    if (!ctx) return gim__fail(&desc->env, GIM_ERROR_OUT_OF_MEMORY, "gim_create", "context (%u bytes)", (unsigned)sizeof *ctx);
    memset(ctx, 0, sizeof *ctx);
    ctx->env = desc->env;
    ctx->gl = gl;
    ctx->gl_major = (int)major;
    ctx->gl_minor = (int)minor;
    gl.GetInteger64v(GIM__GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &ctx->max_ssbo_bytes);
    gl.GetIntegerv(GIM__GL_MAX_TEXTURE_SIZE, &ctx->max_texture_size);
    gl.GetIntegerv(GIM__GL_MAX_VIEWPORT_DIMS, ctx->max_viewport);
    *out = ctx;
    return GIM_OK;
}

GIMANY_DEF void gim_destroy(gim_context *ctx) {
    gim_env env;
    int i;
    if (!ctx) return;
    for (i = 0; i < GIM__PROGRAM_COUNT; ++i)
        if (ctx->programs[i]) ctx->gl.DeleteProgram(ctx->programs[i]);
    if (ctx->scan_blocks) ctx->gl.DeleteBuffers(1, &ctx->scan_blocks);
    gim__scene_destroy(ctx);
    env = ctx->env;
    gim__free(&env, ctx);
}

#ifdef __cplusplus
}
#endif
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
