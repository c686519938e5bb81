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
