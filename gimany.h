/* gimany.h - real-time global illumination with many-light methods, OpenGL 4.3
   version 0.1.0, MIT licence (see the end of this file)

   WHAT IT IS
     One and two bounces of indirect light (diffuse and glossy) for hobby engines. The host
     hands over meshes, materials, instances, lights and its camera and calls gim_update once
     a frame; gimany renders reflective shadow maps (RSMs), picks or clusters virtual lights,
     lights its caches and hands back a texture of indirect radiance to add to the host's
     direct light. Five many-light methods are settings of the same runtime, so a host trades
     speed for accuracy with parameters. Every GPU pass has a CPU twin in this header that
     computes the same numbers: the tests compare the GPU against them, and hosts without
     GL 4.3 can use them.

   THE TWO FILES
     gimany.h              this header: declarations, and the implementation under
                           GIMANY_IMPLEMENTATION
     shaders_embedded.h    the GLSL of every pass as C strings (generated from shaders/ by
                           `make shaders`); gimany.h includes it in the implementation unless
                           GIMANY_NO_GL. Keep both next to each other.
     In exactly one C or C++ file:
         #define GIMANY_IMPLEMENTATION
         #include "gimany.h"
     Everywhere else just #include "gimany.h". The library needs libc, libm and the host's GL.

   QUICK START (a GL 4.3 context current on this thread; zero means default everywhere)
         gim_desc d = {0};
         d.get_proc_address = (gim_gl_proc (*)(const char *))glfwGetProcAddress;
         d.env.logger.func = gim_log_stderr;                      errors: one line each
         gim_context *ctx;
      1  gim_create(&d, &ctx);                                    GIM_ERROR_UNSUPPORTED below GL 4.3
         gim_mesh_desc md = {0};                                  model space
         md.data.positions = p; md.data.vertex_count = nv;
         md.data.indices = idx; md.data.index_count = ni; md.data.index_type = GIM_INDEX_U32;
         gim_cache_desc cd = {0}; cd.mesh = md.data;              LightSkin's light caches, once
         gim_cache_scene_desc sd = {0}; sd.meshes = &cd; sd.count = 1;  (all meshes, one spacing)
         gim_cache_set caches;                                    (CPU; or a blob saved earlier)
      2  gim_cache_generate_scene(&sd, &caches);
         md.caches = &caches;                                     copied: gim_cache_set_free after
         gim_mesh mesh;
      3  gim_add_mesh(ctx, &md, &mesh);                           once per mesh
      4  gim_set_materials(ctx, mats, nmats);                     diffuse, glossy, exponent
         gim_instance in = {mesh, model};
      5  gim_set_instances(ctx, &in, 1);                          again when an object moves
         gim_light sun = {0}; sun.type = GIM_LIGHT_DIRECTIONAL;
         sun.direction = towards_sun; sun.irradiance = 3.0f;
      6  gim_set_lights(ctx, &sun, 1);                            again when a light changes
         every frame:
         gim_frame f = gim_frame_defaults(GIM_METHOD_LIGHTSKIN_BRSM);  or {0}: the same
         f.view = view; f.proj = proj; f.width = w; f.height = h; f.frame_index = n;
      7  gim_update(ctx, &f);                                     every pass of the frame
      8  gim_frame_outputs o = gim_outputs(ctx);
         ... in the host's shading: colour = direct + texture(o.indirect, uv).rgb
      9  gim_frame_stats(ctx, &stats);                            optional: per-pass times
     10  gim_destroy(ctx);                                        once; not twice (as free())
     A complete program of about 200 lines: examples/minimal.c.

   UNITS
     Lengths are in the host's unit. Every length threshold is relative to a scene scale (the
     diagonal of the instances' bounds unless gim_frame.scene_scale), so the same scene in
     millimetres or kilometres gives the same image. Radiometry is linear and in float: a sun's
     irradiance E (power per area facing it), a spot's or point light's intensity I (power per
     steradian), a material's albedo rho in [0, 1]. gim_frame_outputs.indirect holds radiance
     leaving each pixel's surface towards the eye, the albedo already applied (with the host's
     own G-buffer, albedo 1: the host multiplies by its albedo). It adds to direct light in the
     same units: a Lambertian surface lit directly by E at angle theta has radiance
     rho / pi x E cos(theta). A host whose direct term is rho x E cos(theta) (no 1 / pi, common
     in games) multiplies indirect by pi.

   CONFIG MACROS (define before the include that has GIMANY_IMPLEMENTATION)
     GIMANY_NO_GL          drop the GL runtime: only the CPU parts, no GL header needed
     GIMANY_EXTERNAL_GL    the host has its own GL loader: gimany calls its gl* functions
                           instead of loading them from gim_desc.get_proc_address
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
     function says otherwise. Every GL call leaves the host's GL state as it found it (or, with
     gim_desc.gl_state = GIM_GL_STATE_RESET, at GL's initial values, asking GL nothing).

   METHODS (gim_frame.method; each one setting of the same runtime)
     LIGHTSKIN_BRSM (default)  LightSkin light caches fed by val_count VALs drawn from the RSM
                           by bidirectional importance [1]; f.lightskin
     LIGHTSKIN_FULL        every RSM texel a VAL of weight 1: LightSkin's own reference [1]
     RSM_GATHER            each pixel gathers a fixed pattern of RSM texels [2]; the baseline,
                           no caches, no visibility; f.gather
     CLUSTERED             VPLs clustered by k-means into VALs with paraboloid soft shadow maps
                           [3]; f.vpl
     SSVP                  two bounces: clustered VPLs with one paraboloid map per cluster [4],
                           the second bounce by rays from the VPLs [6] (or from the clusters' maps,
                           [4]'s), shadowed by one imperfect shadow map [5] per second-bounce
                           VPL; f.vpl
     Visibility (f.visibility.mode = GIM_VISIBILITY_ISM): imperfect shadow maps [5], one per
     cache (LightSkin) or per VPL (instant radiosity [6] when vpl.count == vpl.cluster_count);
     GIM_VISIBILITY_SHADOW_MAPS: CLUSTERED's and SSVP's per VPL drawn from the triangles, as
     instant radiosity [6] has them; off by default, and off costs nothing.
     f.visibility.neighbour_rays (LightSkin): each pixel interpolates only the neighbour caches
     it sees, tested by rays through a bounding volume hierarchy of the scene (gim_bvh_build);
     GIM_VISIBILITY_RAYS (LightSkin): each VAL at each cache by such a ray instead of the ISMs. f.lightskin.temporal_steps (32 by default) keeps
     the VALs coherent from frame to frame (the aim of incremental instant radiosity [7]).
     Measured speed and error of each: README.md, docs/methods.md.

   BIBLIOGRAPHY
     [1] T. Bischoff, A. Schwandt, W. Broll. A Real-time Global Illumination Approach for High
         Resolution Reflective Shadow Maps in Open World Scenes. VISIGRAPP (GRAPP) 2017.
         Equation numbers in comments ("eq. 12") are this paper's.
     [2] C. Dachsbacher, M. Stamminger. Reflective Shadow Maps. I3D 2005.
     [3] Z. Dong, T. Grosch, T. Ritschel, J. Kautz, H.-P. Seidel. Real-time Indirect
         Illumination with Clustered Visibility. VMV 2009.
     [4] V. M. Aranha, M. C. F. Macedo, A. L. Apolinario Jr. Screen-space VPL propagation for
         real-time indirect lighting. SIBGRAPI 2020.
     [5] T. Ritschel, T. Grosch, M. H. Kim, H.-P. Seidel, C. Dachsbacher, J. Kautz. Imperfect
         Shadow Maps for Efficient Computation of Indirect Illumination. SIGGRAPH Asia 2008.
     [6] A. Keller. Instant Radiosity. SIGGRAPH 1997.
     [7] S. Laine, H. Saransaari, J. Kontkanen, J. Lehtinen, T. Aila. Incremental Instant
         Radiosity for Real-Time Indirect Illumination. EGSR 2007.
     [8] J. Krivanek et al. Global illumination with many-light methods (course slides):
         clamping, interleaved sampling, paraboloid maps.

   TABLE OF CONTENTS (search for the tag)
   Declarations, in the order a host meets them:
     @section config       version, linkage (GIMANY_API, GIMANY_STATIC)
     @section common       result codes, allocator, log, environment
     @section scene        what a host hands over: vector and matrix types, mesh data, lights,
                           materials, normal encodings of a host's G-buffer
     @section gl           the host API, the GL 4.3 runtime (absent with GIMANY_NO_GL): context,
                           meshes, materials, instances, lights, gim_frame (common settings,
                           then one sub-struct per method family) and gim_frame_defaults,
                           gim_update, gim_prepare, outputs, stats, gim_debug
   The CPU layer a host may use without GL:
     @section math         vector and matrix helpers
     @section samplers     radical inverse, Halton, Hammersley, disk, hemisphere, rotation
     @section kmeans       k-means of VPLs into clusters (Dong's metric, SSVP's metric)
     @section caches       LightSkin's light-cache generator, neighbour caches, blobs
     @section importance   importance map (eq. 10-11), cumulative sums (eq. 12), selection
   The reference layer:
     @section twins        the CPU twin of every GPU pass (gim_<pass>_twin; building blocks
                           the runtime itself runs on the CPU keep plain names: among them the
                           bounding volume hierarchy of neighbour_rays, gim_bvh_build)
   The implementation follows under GIMANY_IMPLEMENTATION, each part tagged @impl <name>: the
   CPU parts first (common, math, samplers, kmeans, caches, importance, twins), then gl, which
   uses them. Where each part is tested: tests/README.md; the design: docs/design.md.
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

/* @section scene ========================================================================== */
/* What a host hands over, shared by the GL runtime (@section gl) and the CPU layer: meshes,
   lights, materials, and how a host's own G-buffer holds its normals. */

/* Plain vector and matrix types; matrices are column-major like OpenGL. */
typedef struct gim_vec2 { float x, y; } gim_vec2;
typedef struct gim_vec3 { float x, y, z; } gim_vec3;
typedef struct gim_vec4 { float x, y, z, w; } gim_vec4;
typedef struct gim_mat4 { float m[16]; } gim_mat4;  /* m[col * 4 + row] */

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

/* LightSkin light caches of a mesh (@section caches: gim_cache_generate_scene, blobs). */
typedef struct gim_cache_set gim_cache_set;

/* Kind of light. */
typedef enum gim_light_type {
    GIM_LIGHT_DEFAULT = 0,     /* = DIRECTIONAL */
    GIM_LIGHT_DIRECTIONAL,     /* the sun: parallel light, orthographic RSM */
    GIM_LIGHT_SPOT,            /* a point light in a cone, perspective RSM */
    GIM_LIGHT_POINT            /* a point light in every direction: six square spots, the faces of
                                  a cube around it (gim_point_light_faces), each its own RSM */
} gim_light_type;

#define GIM_MAX_TEMPORAL_STEPS 65536u /* gim_frame.lightskin.temporal_steps */
#define GIM_DEFAULT_TEMPORAL_STEPS 32u /* its default: the street's frame-to-frame change 1.2-1.4x
                                          FULL's at 1024-4096 VALs, 2.0x drawn anew (docs/methods.md) */
#define GIM_MAX_LIGHTS 4096           /* RSMs per context (a point light takes six, others one): a bound
                                         on the arrays, not on memory; each RSM the frame renders has
                                         its own textures (52 bytes a texel), one it culls has none */
#define GIM_RSM_MIN_COS (1.0f / 64.0f) /* floor of the cosine in a VAL's area A = ... / cos */

/* A light; zero means default. */
typedef struct gim_light {
    gim_light_type type;
    float color[3];         /* rgb factor of the power, >= 0; all zero: (1, 1, 1) */
    float irradiance;       /* DIRECTIONAL: E, per unit area perpendicular to direction, >= 0 */
    float intensity;        /* SPOT, POINT: I, per steradian inside the cone (in every direction), >= 0 */
    gim_vec3 position;      /* SPOT, POINT: where the light is */
    gim_vec3 direction;     /* DIRECTIONAL: towards the light; SPOT: the cone's axis, away from
                               the light; non-zero (normalised internally); POINT: ignored */
    float cone_angle;       /* SPOT: half-angle in radians, in (0, 1.5] (below 90 degrees) */
    int square_cone;        /* SPOT: 1: every direction of its square RSM frustum (half-angle
                               cone_angle to the sides' middles) is lit, as on a cube face; 0: a
                               round cone. POINT: ignored */
    float extent;           /* DIRECTIONAL: half-width of a square orthographic RSM (lengths);
                               0: the rectangle the scene bounds' shadow fills on the light's plane */
    uint32_t rsm_size;      /* RSM side in texels (POINT: of each cube face); 0: 512; below 16 a
                               warning (few VALs) */
    int fit_view;           /* DIRECTIONAL: 1 centres the orthographic RSM on what the camera sees
                               (gim_light_fit_view), the open-world case: its texels go where the
                               view is, not over the whole world; 0: the scene bounds */
} gim_light;

/* One material; zero is black. Diffuse and glossy albedo rgb, Phong-like exponent k. */
typedef struct gim_material {
    float diffuse[3];       /* >= 0 */
    float glossy[3];        /* >= 0 */
    float exponent;         /* k >= 0 */
} gim_material;

/* How a host's G-buffer texture holds its normals (gim_frame.gbuffer.normal_encoding). */
typedef enum gim_normal_encoding {
    GIM_NORMAL_XYZ = 0,          /* signed xyz (float or snorm formats): gimany's own layout */
    GIM_NORMAL_XYZ_UNORM,        /* xyz * 0.5 + 0.5 (GL_RGB10_A2, GL_RGBA8, GL_RGBA16) */
    GIM_NORMAL_OCTAHEDRAL,       /* the octahedral map (Cigolle et al. 2014) in [-1, 1] in .xy
                                    (GL_RG16_SNORM, GL_RG16F, GL_RG32F, GL_RG8_SNORM) */
    GIM_NORMAL_OCTAHEDRAL_UNORM  /* the octahedral map * 0.5 + 0.5 in .xy (GL_RG16, GL_RG8, or the
                                    first two channels of GL_RGB10_A2, GL_RGBA8, GL_RGBA16) */
} gim_normal_encoding;

#ifdef __cplusplus
}
#endif

/* @section gl ============================================================================= */
/* The GL 4.3 runtime. gimany includes no GL header: it loads the functions it uses from the
   host's get_proc_address into a table inside the context (or, with GIMANY_EXTERNAL_GL, takes
   the host loader's gl* functions). A GL 4.3 context must be current on the calling thread for
   every call below. Every call that touches GL leaves the GL state as it found it (unless
   gim_desc.gl_state is GIM_GL_STATE_RESET: see gim_gl_state).

   The calls in a frame's order: the QUICK START at the top of this file. Caches come from
   gim_cache_generate_scene over all the meshes (or a blob) once, handed over per mesh in
   gim_mesh_desc.caches; without caches a LightSkin frame runs the shared passes only.
   gim_frame.method picks the method; each method family's settings are one sub-struct of
   gim_frame (lightskin, gather, vpl), and gim_frame_defaults shows every default. */
#ifndef GIMANY_NO_GL
#ifdef __cplusplus
extern "C" {
#endif

/* A GL function as a loader returns it: matches eglGetProcAddress and glfwGetProcAddress. */
typedef void (*gim_gl_proc)(void);

/* What gimany does with the host's GL state around each call that touches GL (gim_desc.gl_state).
   Either way a call sets, for itself, every item its passes depend on, so its results do not
   depend on the host's state; and either way it leaves alone what is not listed below. */
typedef enum gim_gl_state {
    /* The default: the outermost call saves the items it may change (about 63 GL queries, each
       a round trip on threaded drivers such as NVIDIA's threaded optimisation or Mesa's
       glthread) and restores them on return. */
    GIM_GL_STATE_RESTORE = 0,
    /* For hosts that set their own state before they draw: no query; on return every item gimany
       may change is at GL's initial value: program 0, vertex array 0, draw framebuffer 0;
       texture units 0-6: GL_TEXTURE_2D and GL_TEXTURE_2D_ARRAY 0, sampler 0; active texture
       GL_TEXTURE0; image units 0-2 unbound (level 0, layer 0, not layered, GL_READ_ONLY,
       GL_R8); shader storage bindings 0-7 and the generic GL_SHADER_STORAGE_BUFFER,
       GL_ARRAY_BUFFER, GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER bindings 0; disabled:
       GL_CULL_FACE, GL_DEPTH_TEST, GL_SCISSOR_TEST, GL_PRIMITIVE_RESTART,
       GL_PRIMITIVE_RESTART_FIXED_INDEX, GL_RASTERIZER_DISCARD, GL_POLYGON_OFFSET_FILL,
       GL_DEPTH_CLAMP, GL_POLYGON_SMOOTH, GL_COLOR_LOGIC_OP, and GL_BLEND
       of draw buffers 0-3; colour masks of draw buffers 0-3 all GL_TRUE; depth mask GL_TRUE,
       depth func GL_LESS, depth range 0..1; polygon mode GL_FILL; provoking vertex
       GL_LAST_VERTEX_CONVENTION; clip control GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE (GL 4.5 or
       GL_ARB_clip_control).
       The viewport is left as gimany's last pass set it (GL's initial viewport is the size of
       the first surface made current, which a library cannot know): set yours before you draw. */
    GIM_GL_STATE_RESET
} gim_gl_state;

/* Input of gim_create; zero means default. */
typedef struct gim_desc {
    gim_gl_proc (*get_proc_address)(const char *name); /* required unless GIMANY_EXTERNAL_GL */
    gim_env env;                                        /* allocator and log of the context */
    gim_gl_state gl_state;  /* GIM_GL_STATE_RESTORE (0): the host's GL state restored after each
                               call; GIM_GL_STATE_RESET: no GL query, GL's initial values left
                               (the list at gim_gl_state); another value: gim_create refuses */
} gim_desc;

/* The runtime: GL functions, programs and buffers. Opaque; one per GL context. */
typedef struct gim_context gim_context;

/* Create a context for the current GL context: loads the GL functions, checks for GL 4.3
   (GIM_ERROR_UNSUPPORTED, with what is missing logged), logs the renderer. Shaders are
   compiled lazily on first use. *out is written only on GIM_OK. */
GIMANY_API gim_result gim_create(const gim_desc *desc, gim_context **out);
/* Delete every GL object and allocation of ctx (its GL context must be current); NULL is fine.
   ctx is freed: destroying it again, or any later call with it, is the caller's error (as a
   double free() is; sokol's rule too). gimany keeps no global state to catch it, so the second
   call reads freed memory; set your pointer to NULL after the call. */
GIMANY_API void gim_destroy(gim_context *ctx);

/* --- the scene the host hands over --------------------------------------
   Meshes are uploaded once; materials, instances and lights are set whenever they change
   (instances every frame for moving objects; a skinned or morphing mesh is added with
   gim_mesh_desc.deforming and its vertices change through gim_update_mesh_vertices or the
   host's own buffers, its caches following its triangles on the GPU); sizes may change between frames without
   recreating the context. Every call validates all its input before touching anything: on an
   error the scene is as it was before the call. */

/* A mesh handle; id 0 is never a mesh. */
typedef struct gim_mesh { uint32_t id; } gim_mesh;

/* Input of gim_add_mesh; zero means default. */
/* A mesh in the host's own GL buffers, drawn from directly: no copy on the GPU. Positions and
   normals are float3 at offset + i * stride (interleaved layouts name the same buffer twice),
   indices of gim_mesh_data.index_type at index_offset. gim_add_mesh reads positions and
   indices back once (bounds, index checks, the caches' materials, ISM points); after that the
   host may change the buffers' contents only through gim_remove_mesh / gim_add_mesh again (a
   mesh flagged gim_mesh_desc.deforming: positions and normals at any time), and
   must keep them alive while the mesh exists (gimany never deletes them). */
typedef struct gim_mesh_buffers {
    uint32_t positions;         /* GL buffer name; 0: the mesh is uploaded from gim_mesh_data */
    uint32_t position_offset;   /* bytes, a multiple of 4 */
    uint32_t position_stride;   /* bytes, a multiple of 4; 0 = 12 */
    uint32_t normals;           /* GL buffer name (non-zero, unit normals; not checked) */
    uint32_t normal_offset, normal_stride;
    uint32_t indices;           /* GL buffer name */
    uint32_t index_offset;      /* bytes, a multiple of the index size */
} gim_mesh_buffers;

typedef struct gim_mesh_desc {
    gim_mesh_data data;         /* model space: positions (finite), normals (non-zero, finite; NULL:
                                   area-weighted vertex normals are computed), 16/32-bit indices
                                   (< vertex_count), triangle_material (ids into gim_set_materials'
                                   array, checked at gim_update; NULL: all 0); material_reflectance
                                   and material_count are not used here. With buffers: only
                                   vertex_count, index_count, index_type and triangle_material */
    const gim_cache_set *caches; /* model-space LightSkin caches of the mesh, or NULL; copied */
    gim_mesh_buffers buffers;   /* the host's GL buffers instead of data's arrays (zero: none) */
    int deforming;              /* 1: the vertices move every frame (skinning, morphing): the caches are
                                   bound to their triangles (gim_cache_bind) and follow them on the
                                   GPU each frame (gim_caches_follow_twin's pass). With buffers: gimany
                                   draws from the host's buffers, so they may change at any time, and
                                   every gim_update re-reads the positions on the GPU (bounds,
                                   caches); indices, vertex and index counts must stay. Without
                                   buffers: gim_update_mesh_vertices uploads new positions. Cost of
                                   a frame after a change: one dispatch per mesh, then the followed
                                   caches (32 bytes each) are read back (a sync point) because the
                                   caches' hash grid is built on the CPU; with GIM_VISIBILITY_ISM
                                   the scene's ISM points are remade from a read-back of the
                                   vertices and every cache's map is drawn again. A static mesh (0)
                                   pays nothing of this. */
} gim_mesh_desc;

/* Upload a mesh (vertex, index and per-triangle material buffers; with desc->buffers only the
   materials). *out written on GIM_OK. */
GIMANY_API gim_result gim_add_mesh(gim_context *ctx, const gim_mesh_desc *desc, gim_mesh *out);
/* Delete a mesh; instances still naming it make gim_update fail until they are replaced. */
GIMANY_API gim_result gim_remove_mesh(gim_context *ctx, gim_mesh mesh);
/* New model-space vertices of a mesh added with deforming = 1 and no buffers: vertex_count
   (as at gim_add_mesh) float3 positions, finite, in the mesh's units; normals vertex_count
   float3 (non-zero, finite) or NULL (area-weighted vertex normals, as gim_add_mesh computes
   them). Uploaded into gimany's copy, which the RSM, G-buffer and ISM points are drawn from;
   the bounds are made again, and the next gim_update moves the caches with their triangles
   (GPU) and remakes the imperfect shadow maps. A mesh not flagged deforming, one drawn from
   the host's buffers (change those instead), a wrong vertex_count or a non-finite value is
   GIM_ERROR_INVALID_ARGUMENT, the mesh unchanged. */
GIMANY_API gim_result gim_update_mesh_vertices(gim_context *ctx, gim_mesh mesh, const float *positions,
                                               const float *normals, uint32_t vertex_count);

/* Materials by index (gim_material: diffuse rgb, glossy rgb, exponent k; see @section scene);
   count 0 clears them. Replaces the previous set. */
GIMANY_API gim_result gim_set_materials(gim_context *ctx, const gim_material *materials, uint32_t count);

/* One placed mesh. */
typedef struct gim_instance {
    gim_mesh mesh;
    gim_mat4 model;             /* model to world; finite and invertible */
} gim_instance;

/* The instances of the frame (copied); count 0 clears them. */
GIMANY_API gim_result gim_set_instances(gim_context *ctx, const gim_instance *instances, uint32_t count);

/* The lights (gim_light, see @section twins; copied); count 0 clears them. Each light is one
   RSM, a POINT light six (its cube faces, gim_point_light_faces), at most GIM_MAX_LIGHTS RSMs;
   gim_frame_outputs.lights counts RSMs. A frame renders only the RSMs whose light frustum
   meets the bounds of an instance (the others would be empty: no pass, no texture, no VAL or
   VPL; gim_stats.rsm_count; when all would be, the last renders so the frame has its
   outputs); val_count and vpl_count are shared by the rendered RSMs (see
   gim_frame.per_light_budget). rsm_size must fit GL_MAX_TEXTURE_SIZE and GL_MAX_VIEWPORT_DIMS.
   Replaces a gim_set_lights_buffer. */
GIMANY_API gim_result gim_set_lights(gim_context *ctx, const gim_light *lights, uint32_t count);

/* One light in a host's GL buffer (gim_set_lights_buffer): std430, 64 bytes, the fields of
   gim_light as four vec4s. GLSL:
     struct GimLight {
         vec4  color_power;       // rgb: color; a: irradiance (DIRECTIONAL) or intensity (SPOT, POINT)
         vec4  position_cone;     // xyz: position; w: cone_angle (radians)
         vec4  direction_extent;  // xyz: direction; w: extent
         uvec4 type_square_size_fit; // x: gim_light_type, y: square_cone, z: rsm_size, w: fit_view
     };
     layout(std430) buffer Lights { GimLight lights[]; };
   The same units and ranges as gim_light. */
typedef struct gim_light_std430 {
    float color_power[4];
    float position_cone[4];
    float direction_extent[4];
    uint32_t type_square_size_fit[4];
} gim_light_std430;

/* The lights from a host's GL buffer of count gim_light_std430 (from offset 0), instead of a
   CPU array: for a host that keeps its lights on the GPU. The RSMs need each light's camera on
   the CPU, so every gim_update reads the buffer back (glGetBufferSubData of count x 64 bytes:
   a wait for the GPU work that writes it) and checks and uses the lights as gim_set_lights
   does; an invalid light fails that gim_update. buffer stays the host's (not deleted; it must
   live while set); buffer 0 or count 0 clears the lights. Replaced by gim_set_lights. */
GIMANY_API gim_result gim_set_lights_buffer(gim_context *ctx, uint32_t buffer, uint32_t count);

/* --- the frame ------------------------------------------------------------------------------ */

/* Which method lights the frame (docs/design.md sec. 3); each is one setting of the same runtime. */
typedef enum gim_method {
    GIM_METHOD_DEFAULT = 0,         /* = LIGHTSKIN_BRSM */
    GIM_METHOD_LIGHTSKIN_BRSM,      /* val_count VALs drawn by importance, shared by the lights (Bischoff 2017 sec. 4) */
    GIM_METHOD_LIGHTSKIN_FULL,      /* every RSM texel a VAL of weight 1: LightSkin, the paper's reference */
    GIM_METHOD_RSM_GATHER,          /* each pixel gathers a fixed pattern of RSM texels (Dachsbacher 2005;
                                       gim_rsm_gather_twin): the baseline, no caches, no visibility */
    GIM_METHOD_CLUSTERED,           /* Dong et al.: vpl_count Halton VPLs, k-means (Dong's metric) into
                                       cluster_count VALs, one paraboloid soft shadow map each; every VPL
                                       shades with its VAL's visibility */
    GIM_METHOD_SSVP                 /* Aranha et al.: vpl_count Hammersley VPLs, k-means (SSVP metric) into
                                       cluster_count clusters, a paraboloid map per cluster, second-bounce
                                       VPLs by rays from the VPLs (gim_frame_vpl.second_bounce: or, the
                                       paper's, from the clusters' maps of position, normal and albedo);
                                       both bounces shade (bounces = 2 by default) */
} gim_method;

/* Visibility of the indirect light (docs/design.md sec. 8). The VPL methods (CLUSTERED, SSVP) have
   their own exact visibility: DEFAULT and OFF keep it (one paraboloid depth map per cluster,
   rendered from the triangles, soft PCSS lookups; gim_frame.vpl.no_visibility turns it off); ISM
   replaces it with one imperfect shadow map per VPL, SHADOW_MAPS with one drawn from the triangles. */
typedef enum gim_visibility {
    GIM_VISIBILITY_DEFAULT = 0,     /* = OFF */
    GIM_VISIBILITY_OFF,             /* no pass, no memory */
    GIM_VISIBILITY_ISM,             /* LightSkin: one imperfect shadow map per cache (Ritschel et al. 2008),
                                       looked up per VAL in the proxy-light sum; made once per scene
                                       change (mesh, instance, a deforming mesh's vertices), not per frame. CLUSTERED, SSVP: one
                                       per VPL, both bounces (Keller's instant radiosity with Ritschel's
                                       maps), a first-bounce VPL's kept with the VPL while its light moves
                                       (gim_frame_vpl.redraw; gim_stats.ism_maps_made), the second bounce's
                                       made every frame; hard visibility per VPL in the shading instead of the
                                       clusters' paraboloid maps */
    GIM_VISIBILITY_SHADOW_MAPS,     /* CLUSTERED, SSVP: one paraboloid shadow map per VPL rendered from the
                                       triangles (Keller 1997's instant radiosity; exact at each texel's
                                       centre ray, where an ISM's surfels widen every silhouette), kept with
                                       the VPL as ISM's are (Laine et al. 2007); ism_size is their side,
                                       ism_points only SSVP's check of its clusters' hits. Costs a draw of
                                       the scene per map made. LightSkin: refused (its caches take ISM) */
    GIM_VISIBILITY_RAYS             /* LightSkin: each VAL's light at each cache tested by a ray through a
                                       bounding volume hierarchy of the scene's triangles (gim_val_rays_twin;
                                       the hierarchy of neighbour_rays, made when the scene changes), where ISM
                                       looks it up in the cache's map: exact where the maps' surfels widen or
                                       thin silhouettes, for a ray per VAL and cache every frame. CLUSTERED,
                                       SSVP: refused */
} gim_visibility;

/* Where the VPL methods' second bounce leaves from (gim_frame.vpl.second_bounce, with bounces 2). */
typedef enum gim_second_bounce {
    GIM_SECOND_BOUNCE_DEFAULT = 0,  /* = RAYS */
    GIM_SECOND_BOUNCE_RAYS,         /* rays from first-bounce VPLs, one per stratum of the VPL list picked by
                                       flux, to the nearest triangle (Keller 1997's instant radiosity;
                                       gim_second_bounce_rays_twin), through a bounding volume hierarchy of
                                       the scene's triangles built when the scene changes; no attribute maps.
                                       Less error than MAPS everywhere measured (mean over six second-bounce
                                       counts: street 0.430 -> 0.239, Cornell box 0.164 -> 0.130, the atrium
                                       1.216 -> 1.017), the same flicker (docs/methods.md, "The second bounce
                                       by rays") */
    GIM_SECOND_BOUNCE_MAPS          /* SSVP sec. 3.C: each cluster's paraboloid map of position, normal and
                                       albedo, its unit-disk samples the VPLs, the cluster's flux emitted
                                       from its centre (gim_second_bounce_vpls_twin), which lies on no
                                       surface: 2.5x the street's second bounce, 2-4x inside Sponza with VPLs
                                       by importance (docs/methods.md) */
} gim_second_bounce;

/* The host's G-buffer instead of gimany's (gim_frame.gbuffer; all 0: gimany draws one). */
typedef struct gim_frame_gbuffer {
    uint32_t depth;             /* a 2D depth texture of the frame's view (window depth in [0, 1], 1 =
                                   nothing) ... */
    uint32_t normal;            /* ... and a 2D float texture with the world normal in .xyz; both
                                   >= width x height, or both 0 */
    gim_normal_encoding normal_encoding; /* how normal holds it; not XYZ (or the two below set): one
                                   decode pass (gim_gbuffer_decode_twin) */
    int view_space;             /* 1: the host's normals are in view space */
    int depth_view_z;           /* 1: depth is a float texture (GL_R32F, GL_R16F) holding the positive
                                   view-space distance along -z (0: nothing drawn) */
} gim_frame_gbuffer;

/* Visibility of the indirect light (gim_frame.visibility). */
typedef struct gim_frame_visibility {
    gim_visibility mode;        /* OFF (default), ISM, SHADOW_MAPS or RAYS; the two below only with the maps. CLUSTERED,
                                   SSVP: OFF keeps their paraboloid maps, ISM and SHADOW_MAPS are one map per
                                   VPL (not with vpl.no_visibility; their VPLs x ism_size^2 16-bit depths
                                   within one shader storage block) */
    uint32_t ism_size;          /* map side, a power of two in 4..64; 0: GIM_ISM_DEFAULT_SIZE (64); LightSkin
                                   halves it until every cache's map fits GIM_ISM_BUDGET_BYTES (256 MiB: 64^2
                                   up to 32,768 caches, 32^2 up to 131,072) and refuses an explicit side whose
                                   maps exceed GIM_ISM_MAX_BYTES (1 GiB); CLUSTERED, SSVP keep 64 */
    uint32_t ism_points;        /* points per map; 0: GIM_ISM_DEFAULT_POINTS (16384; CLUSTERED, SSVP:
                                   GIM_ISM_DEFAULT_VPL_POINTS, 65536); at most GIM_ISM_MAX_POINTS */
    uint32_t neighbour_rays;    /* LightSkin, with any mode: 1 = each pixel interpolates only the neighbour
                                   caches it sees, tested by a ray through a bounding volume hierarchy of the
                                   scene's triangles (gim_neighbour_rays_twin; built when the scene changes,
                                   32 bytes a node and 48 a triangle on the GPU, up to GIM_BVH_MAX_TRIANGLES);
                                   16 rays per search in the shading pass. 0: off (no buffer). Other methods:
                                   refused */
} gim_frame_visibility;

/* LightSkin, LIGHTSKIN_BRSM and LIGHTSKIN_FULL (gim_frame.lightskin). */
typedef struct gim_frame_lightskin {
    uint32_t val_count;         /* VALs selected (Bischoff 2017 sec. 4), in all, shared by the rendered RSMs
                                   by importance (per_light_budget: per RSM); 0: 2048 */
    uint32_t temporal_steps;    /* L > 1: the random offsets of the BRSM selection (and, with
                                   rotate_view_samples, of the view samples) drift by 1/L of their points'
                                   spacing a frame (gim_drift_offsets) instead of being drawn anew, so each
                                   VAL moves to a nearby texel or stays (the aim of Laine et al. 2007); each
                                   frame is still unbiased and as stratified, and frame 0 is the frame
                                   drawn anew. 1: new offsets every frame (independent frames, for a host
                                   that averages them itself); 0: GIM_DEFAULT_TEMPORAL_STEPS (32); at most
                                   GIM_MAX_TEMPORAL_STEPS */
    uint32_t view_sample_count; /* Halton view samples over the G-buffer; 0: 256; at most 32768 (one
                                   importance-map invocation loops over them all; llvmpipe stops
                                   a loop after 65535 iterations) */
    int rotate_view_samples;    /* 1: Cranley-Patterson rotate them by gim_rotation_offsets(frame_index) */
    float importance_clamp;     /* eq. 11 clamp in scene scales; 0: 1/64 (see @section importance) */
    uint32_t neighbour_count;   /* caches interpolated per pixel (eq. 8-9), 1..GIM_MAX_NEIGHBOUR_CACHES; 0: 16 */
    uint32_t importance_tile;   /* BRSM: side T in RSM texels of the two-level importance map's tiles, 1..
                                   GIM_MAX_IMPORTANCE_TILE (gim_importance_tile_map): eq. 10-11 once per plane
                                   (at most 4) of each T x T tile, the VAL picked inside its tile by luminance x
                                   its plane's term, P exact, so the pass costs <= 4 texels / T^2 x view samples;
                                   1: eq. 10-11 per texel (the paper's map, the images of before); 0:
                                   GIM_DEFAULT_IMPORTANCE_TILE (docs/methods.md) */
    float defensive_share;      /* BRSM: the share of the VALs drawn by the texels' luminance alone, the rest by
                                   importance, every VAL weighted by the mixture's pdf (gim_select_desc.
                                   defensive_count): a texel the view samples barely see but that lights
                                   caches then weighs at most 1 / share times its share of the RSM's light
                                   (the paper's 1 / P alone gave one VAL of 1024 98% of a frame's light);
                                   in (0, 0.5], e.g. 0.125; negative: none (the paper's selection); 0:
                                   GIM_DEFAULT_DEFENSIVE_SHARE (none for now: it helps open views and
                                   costs interiors, docs/methods.md) */
    uint32_t shade_block;       /* B: the shading pass finds the neighbours and interpolates (eq. 8-9) once per
                                   B x B block of pixels, at its first receiver, and every pixel of the block on
                                   that receiver's surface (gim_shade_sources) takes that light times its own
                                   albedo; the others of the block their own. 1: per pixel; 2: 2 x 2 blocks;
                                   0: GIM_DEFAULT_SHADE_BLOCK */
} gim_frame_lightskin;

/* RSM_GATHER (gim_frame.gather). */
typedef struct gim_frame_gather {
    uint32_t samples;           /* texels per pixel and light; 0: 256; at most 16384 */
    float radius;               /* pattern radius as a fraction of the RSM side; 0: 1.5, the whole RSM from
                                   any point of it (Dachsbacher's 0.15 misses much of an open corner's light) */
} gim_frame_gather;

/* The VPL methods, CLUSTERED and SSVP (gim_frame.vpl; see their twins in @section twins). */
typedef struct gim_frame_vpl {
    uint32_t count;             /* first-bounce VPLs in all, split evenly over the rendered RSMs
                                   (per_light_budget: per RSM); 0: 2048 (CLUSTERED: 128 per pixel with its
                                   interleave of 4 at 720 rows) or 4096 (SSVP: 64 per pixel at 8);
                                   <= 32768 in all */
    uint32_t cluster_count;     /* VALs (k-means clusters, paraboloid maps); 0: 30 (CLUSTERED) or 8 (SSVP);
                                   <= 256 and <= the VPLs */
    uint32_t kmeans_iterations; /* k-means steps per frame; 0: 3 from the last frame's centres, 8 from seeds */
    int kmeans_restart;         /* 1: k-means restarts from the same seeds every frame (Dong sec. 5.2); 0: warm
                                   from the last frame's centres (SSVP sec. 3.B), an empty cluster re-seeded;
                                   warm keeps the clusters from jumping between frames */
    uint32_t paraboloid_size;   /* side of each paraboloid map; 0: 256 */
    int no_visibility;          /* 1: VPLs shade unshadowed and no depth maps exist (a second bounce from
                                   MAPS still renders its attribute maps) */
    uint32_t bounces;           /* 1 or 2; 0: 1 (CLUSTERED) or 2 (SSVP). 2: second-bounce VPLs (second_bounce) */
    uint32_t second_bounce_vpls; /* S, second-bounce VPLs in all (split over the clusters); 0: 256 */
    gim_second_bounce second_bounce; /* where the second bounce leaves from: RAYS (default: the first-bounce
                                   VPLs themselves) or MAPS (SSVP's paper: each cluster's centre) */
    uint32_t interleave;        /* k: interleaved sampling in k x k pixel blocks + geometry-aware blur over
                                   k x k; 1: every VPL at every pixel, no blur (docs/methods.md: the trade).
                                   0: by the view, k_m = 4 (CLUSTERED) or 8 (SSVP; Dong sec. 6 uses 8) from
                                   720 rows up (the shorter side), k_m x rows / 720 rounded up below (at
                                   least 1, k^2 at most vpl.count; gim_vpl_default_interleave): the window
                                   keeps its share of the view and the frame's VPL x pixel work stays at
                                   most 720 rows' (160x90: 1) */
    float clamp_distance;       /* d_c in scene scales: 1 / d^2 floored at 1 / d_c^2; 0: 0.01; < 0: none */
    float blur_distance;        /* blur's position tolerance in scene scales; 0: 0.1 (Dong sec. 6) */
    int redraw;                 /* 0: incremental instant radiosity (Laine et al. 2007): a first-bounce VPL of
                                   the last frame stays, with its imperfect shadow map, while its light still
                                   sees its point and it stays near its slot's texel (gim_rsm_vpls_desc.
                                   previous); the others are drawn anew. 1: every VPL drawn at its texel
                                   every frame (the frame of a light that moves depends on that frame only) */
    int importance;             /* 1: the first-bounce VPLs drawn where their light reaches the view, by
                                   BRSM's importance (Bischoff 2017 eq. 10-12, with f.lightskin's view
                                   samples, tile, clamp and defensive share): each light's even share N of
                                   vpl.count picked with probability P, each VPL weighing 1 / (N P)
                                   (gim_vpls_from_vals); no VPL is followed (redraw does not apply), but a
                                   pick on the same point as its slot's last VPL keeps its ISM. On large
                                   scenes far fewer VPLs are spent on what the view does not see; SSVP's
                                   second bounce, interiors whose importance lies behind walls and a
                                   moving light's flicker get worse (docs/methods.md: the trade).
                                   0: at their texels of the sequence */
} gim_frame_vpl;

/* Input of gim_update: the settings every method shares, then one sub-struct per method family
   (a method reads only its own). Zero means default everywhere; gim_frame_defaults writes every
   default out. */
typedef struct gim_frame {
    gim_mat4 view, proj;        /* the host's camera; finite, invertible; depth range [0, 1] */
    uint32_t width, height;     /* G-buffer size in pixels (the host's viewport), > 0 */
    gim_method method;          /* LightSkin with BRSM (default) or FULL, RSM gather, CLUSTERED, SSVP */
    uint32_t frame_index;       /* seeds the rotation of the view samples and the selection */
    float scene_scale;          /* length of the unit-free thresholds; 0: diagonal of the world
                                   bounds of the instances; else within 1e-3..1e3 of it */
    float view_distance;        /* fit_view suns: how far from the eye the RSM must cover; 0: the far plane */
    int per_light_budget;       /* 0: lightskin.val_count and vpl.count are totals for the frame: BRSM splits
                                   val_count over the rendered RSMs in proportion to their importance totals
                                   (each one's power reaching the view samples; one read-back), at least one
                                   VAL to each whose total is > 0, none to one whose total is 0; each light's
                                   VALs weigh 1 / (N_l P), so the image's expectation does not depend on the
                                   split. The VPL methods split vpl.count evenly. 1: every rendered RSM gets
                                   val_count VALs, vpl.count VPLs */
    int indirect_float32;       /* 1: the indirect texture is RGBA32F; 0: RGBA16F */
    int timing;                 /* 1: a GL timestamp after every pass, read by gim_frame_stats;
                                   2: glFinish after every pass, then the CPU's clock (see
                                   gim_stats.cpu_clock): a driver that runs queued work at a later
                                   flush (llvmpipe, even between timestamps) still charges it to
                                   its pass; it serialises the frame, for profiling only;
                                   other values: GIM_ERROR_OUT_OF_RANGE */
    gim_frame_gbuffer gbuffer;       /* the host's G-buffer (all 0: gimany draws one) */
    gim_frame_visibility visibility; /* indirect visibility: OFF or ISM */
    gim_frame_lightskin lightskin;   /* LIGHTSKIN_BRSM, LIGHTSKIN_FULL */
    gim_frame_gather gather;         /* RSM_GATHER */
    gim_frame_vpl vpl;               /* CLUSTERED, SSVP */
} gim_frame;

/* A frame with every default of `method` written out: the value each zero field stands for,
   the method-dependent ones (vpl.cluster_count, vpl.bounces, the ISM sizes and points) for
   this method (GIM_METHOD_DEFAULT: LIGHTSKIN_BRSM). Left 0: what only the host knows (view,
   proj, width, height, the G-buffer), what is measured every frame (scene_scale: the bounds'
   diagonal; view_distance: the far plane), the off switches, vpl.kmeans_iterations, whose
   default depends on the frame (3 from the last frame's centres, 8 from seeds), and
   vpl.interleave, whose default depends on the view's size (gim_frame_vpl). One more
   default depends on the scene: a zero visibility.ism_size is halved below 64 for LightSkin
   when the caches' maps would exceed GIM_ISM_BUDGET_BYTES (the 64 written here is the host's
   then, refused above GIM_ISM_MAX_BYTES). With view, proj, width and height set, it renders
   what the zero frame of the same method renders (tests/gl/gltest_frame.c). */
GIMANY_API gim_frame gim_frame_defaults(gim_method method);

/* The k a zero gim_frame_vpl.interleave takes in a width x height view with vpl_count VPLs (0:
   the method's default count): the method's k_m, 4 (CLUSTERED) or 8 (SSVP), from 720 rows of
   the shorter side up, below that k_m x rows / 720 rounded up (at least 1; k^2 at most
   vpl_count). */
GIMANY_API uint32_t gim_vpl_default_interleave(gim_method method, uint32_t width, uint32_t height, uint32_t vpl_count);

/* Run the frame's passes (docs/design.md sec. 3, Bischoff 2017): RSM per light whose frustum meets an
   instance's bounds (the others are culled) -> G-buffer (or the host's) -> view samples -> per
   rendered light (BRSM only): importance map (eq. 10-11) -> cumulative sums (eq. 12) -> its
   share of val_count (gim_frame.per_light_budget; one read-back of the totals) -> selection of
   that many VALs (none where its total is 0, unless it is the only one rendered; when no
   light has any, one zero VAL, so the image is made, black); then, when an instanced mesh has caches:
   caches to world space (gim_caches_to_world; a hash grid over them) -> the VALs of every
   light (FULL: every texel, weight 1; BRSM: the selected, 1 / (N P)) -> with visibility ISM,
   the caches' imperfect shadow maps when the scene changed (gim_ism_points of the instances'
   world triangles, read back from the meshes, pool 4 P; gim_ism_render_twin) -> diffuse proxy lights
   per cache (eq. 3-7, 13-15; with ISM each VAL times its visibility, gim_ism_visibility_twin), glossy ones too when a material has a glossy colour (one lobe
   exponent for all caches: the smallest of those materials, the widest lobe) -> per pixel: the n nearest caches whose normal is within 2 theta_eps (at most 90
   degrees) of the pixel's, within 3 grid cells (the cell is twice the mean spacing of the
   caches, sqrt of their mean area), interpolated (eq. 8-9) and shaded into the indirect
   texture, once per 2 x 2 block where its pixels lie on one surface (lightskin.shade_block;
   gim_lightskin_shade_twin with gim_shade_sources is the twin). A scene without caches gets no LightSkin passes
   and no indirect texture. The VPL methods (CLUSTERED, SSVP; no caches needed) instead run,
   after the RSMs and the G-buffer: vpl_count VPLs split over the lights (gim_rsm_vpls_twin; the
   last frame's kept where their light still sees them near their slot, gim_frame_vpl.redraw; or,
   with gim_frame_vpl.importance, BRSM's selection written as VPLs, gim_vpls_from_vals) -> k-means
   steps on the GPU (Dong's or SSVP's metric, warm from the last frame's centres or from the
   same seeds every frame; an empty cluster re-seeded from the farthest lit VPL) -> the clusters' VALs
   (gim_cluster_paraboloids_twin) -> layered passes of paraboloid maps (distance for visibility,
   past near_distance; position, normal and albedo at two bounces, past attribute_near: with
   both, two passes) -> second-bounce VPLs (by rays, gim_second_bounce_rays_twin; from the maps,
   gim_second_bounce_vpls_twin)
   -> every VPL shades each pixel of its interleaved subset with its cluster's soft visibility
   (gim_vpl_shade_twin) -> the geometry-aware blur (gim_geometry_blur_twin) into the indirect texture.
   With visibility ISM the VPL methods make no depth maps: one imperfect shadow map per VPL of
   both bounces (gim_ism_render_twin with the VPLs as caches and GIM_ISM_VPL_SPLAT; a
   first-bounce VPL's kept with the VPL, incremental instant radiosity after Laine et al. 2007; SSVP's second-bounce hits
   first checked in one map per cluster, gim_second_bounce_desc.ism), and each VPL shades with
   its own map's hard visibility (gim_vpl_shade_desc.ism; bias GIM_ISM_VPL_BIAS, _SLOPE).
   Needs at least one instance; every material id of an instanced
   mesh must be below the material count. Range (GIM_ERROR_OUT_OF_RANGE outside; README
   "Supported ranges"): the world bounds' diagonal within 1e-15..1e15 length units, the
   bounds at most 1024 diagonals from the origin (float positions are too coarse beyond), and
   each light's power into the scene (colour x E x diagonal^2, or colour x 4 pi I) <= 1e36.
   A host G-buffer needs a depth format and signed normals (GIM_ERROR_INVALID_ARGUMENT). The
   host's GL state is saved, set to what the passes need (clip control, provoking vertex and
   the raster state to GL's defaults) and restored (or reset: gim_desc.gl_state). Warnings:
   RGBA16F output a light can saturate (once); with LightSkin, a G-buffer that mostly shows the
   back of its surfaces (counted one frame in 32, read at a later frame once done). No current
   context: GIM_ERROR_GL. */
GIMANY_API gim_result gim_update(gim_context *ctx, const gim_frame *frame);

/* Builds every GL program a frame like `frame` needs (its method and settings; sizes do not
   matter), so the first gim_update does not stall compiling and linking shaders (LightSkin +
   BRSM's 11 programs: 132 ms on llvmpipe with Mesa's shader cache off, `gimany-demo` prints
   it): call it behind a loading screen, after the scene is set. A driver that compiles more at
   the first dispatch still does that there. The frame is checked as gim_update checks it;
   programs of other methods are built when first used. The host's GL state is saved and restored
   (or reset: gim_desc.gl_state). */
GIMANY_API gim_result gim_prepare(gim_context *ctx, const gim_frame *frame);

/* What one light's passes wrote (GL names; valid until the next gim_update or gim_set_lights). */
typedef struct gim_light_outputs {
    gim_light light;            /* the light of this RSM: the host's, or one face of its POINT light */
    uint32_t rsm_size;
    uint32_t rsm_position;      /* RGBA32F: world xyz; w = 1 where the texel is a VAL (lit) */
    uint32_t rsm_normal;        /* RGBA32F: unit normal towards the light; w = footprint area A */
    uint32_t rsm_flux;          /* RGBA32F: reflected flux Phi rgb (units in @section twins) */
    uint32_t rsm_depth;         /* DEPTH_COMPONENT32F */
    gim_mat4 view, proj;        /* the light's camera (gim_light_camera) */
    uint32_t importance;        /* SSBO: rsm_size^2 floats, row-major, row 0 first: importance_tile 1: eq. 10-11 per
                                   texel; T > 1: each texel's weight in its tile (gim_importance_tile_map's weight) */
    uint32_t importance_tiles;  /* importance_tile > 1: SSBO of ceil(rsm_size / T)^2 floats, eq. 10-11 per tile
                                   (gim_importance_tile_map's tile_map); 0 otherwise */
    uint32_t importance_tile;   /* BRSM: the tile side T the frame used (1: per texel); 0 otherwise */
    uint32_t column, row;       /* SSBOs: the eq. 12 tables in double (gim_importance_cumsum's), of the per-texel
                                   map (T = 1) or of the tile map (ceil(rsm_size / T) square) */
    uint32_t selected;          /* SSBO: selected_count gim_selected_val {x, y, pdf} */
    uint32_t selected_count;    /* its share of val_count (0: none, or not BRSM); with the VPL methods'
                                   vpl.importance its share of the VPLs, each pick VPL i of its share */
    uint32_t defensive_count;   /* BRSM: of those, the picks by luminance (gim_frame_lightskin.defensive_share);
                                   with the three below (0 without a share): */
    uint32_t luminance;         /* SSBO: rsm_size^2 floats, each texel's luminance (gim_importance_luminance's weight) */
    uint32_t luminance_column, luminance_row; /* SSBOs: its eq. 12 tables, the size of column and row (of the
                                   tile sums when importance_tile > 1) */
    int rendered;               /* 1: its RSM was rendered this frame; 0: culled (its frustum meets no
                                   instance's bounds): every GL name above is 0 */
    double importance_total;    /* BRSM, shared budget, more than one rendered RSM: the sum of its importance
                                   map (0: no VALs); 0 otherwise (not read back) */
} gim_light_outputs;

/* What the last successful gim_update left for the host. */
typedef struct gim_frame_outputs {
    int valid;                  /* 0 before the first successful gim_update, or after a failed one */
    uint32_t width, height;
    uint32_t indirect;          /* RGBA16F/32F, width x height: rgb indirect radiance leaving each pixel's
                                   surface towards the eye (diffuse + glossy, albedo applied; with the
                                   host's G-buffer albedo 1 and no glossy term), a = 1 where a surface is;
                                   0 when there is nothing to light (LightSkin: a scene without caches) */
    uint32_t gbuffer_depth;     /* DEPTH_COMPONENT32F (or the host's) */
    uint32_t gbuffer_normal;    /* RGBA16F world normal towards the eye, w = 1 where drawn (or the host's) */
    uint32_t gbuffer_albedo;    /* RGBA8 diffuse albedo, clamped to [0, 1] (0 with the host's G-buffer) */
    uint32_t gbuffer_material;  /* R32F material id (0 with the host's G-buffer) */
    float scene_scale;
    float bounds_min[3], bounds_max[3]; /* world bounds of the instances */
    uint32_t light_count;
    const gim_light_outputs *lights; /* light_count, one per RSM; the context's, valid as the rest */
} gim_frame_outputs;

/* The outputs of the last gim_update (all zero for NULL). */
GIMANY_API gim_frame_outputs gim_outputs(const gim_context *ctx);

/* The internal buffers of the last successful gim_update, for tests and tools that compare
   the passes with their twins (a host needs none of them; GL names, valid until the next
   gim_update; zero when the frame's method has no such buffer). */
typedef struct gim_debug_outputs {
    uint32_t view_samples;      /* SSBO: view_sample_count {vec4 position; vec4 normal} (BRSM) */
    uint32_t view_sample_count;
    /* LightSkin (0 when the scene has no caches) */
    uint32_t caches;            /* SSBO: cache_count world-space gim_cache, in hash-grid order */
    uint32_t cache_count;
    uint32_t vals;              /* SSBO: val_count gim_val, the lights' VALs one after the other */
    uint32_t val_count;
    uint32_t proxy_diffuse;     /* SSBO: cache_count gim_proxy_light */
    uint32_t proxy_glossy;      /* SSBO, or 0 when no material is glossy */
    float glossy_exponent;      /* the widest lobe of the glossy materials */
    uint32_t cache_exponents;   /* SSBO: float per cache, its material's k (the glossy proxy lights' lobes); 0 when
                                   no material is glossy */
    uint32_t neighbour_count;   /* n of the interpolation */
    float neighbour_cos;        /* cosine of the normal compatibility angle */
    float neighbour_radius;     /* farthest distance a neighbour cache may have (3 grid cells) */
    float neighbour_cell;       /* the hash grid's cell side h (gim_shade_blocks_desc.cell) */
    uint32_t shade_block;       /* the frame's gim_frame_lightskin.shade_block, resolved (1 or 2) */
    /* VPL methods (0 otherwise) */
    uint32_t vpls;              /* SSBO: vpl_count gim_vpl: the lights' first-bounce VPLs, then the second bounce */
    uint32_t vpl_count;
    uint32_t first_bounce_count; /* VPLs [0, first_bounce_count) are the first bounce */
    uint32_t vpl_clusters;      /* SSBO: vpl_count uint, each VPL's cluster (0xffffffff: none; the second
                                   bounce's, shadowed by their own ISMs, see ism_maps) */
    uint32_t clusters;          /* SSBO: cluster_count gim_paraboloid */
    uint32_t cluster_count;
    uint32_t kmeans_centres;    /* SSBO: cluster_count {vec4 centre (w: VPLs), vec4 normal} */
    uint32_t paraboloid_size;
    uint32_t paraboloid_distance; /* R32F 2D array, one layer per cluster (0 without visibility or maps) */
    uint32_t paraboloid_position, paraboloid_normal, paraboloid_albedo; /* RGBA32F arrays, bounces = 2 only */
    /* visibility ISM (0 otherwise) */
    uint32_t ism_maps;          /* SSBO: map i of cache i of caches (gim_ism_render_twin), ism_size^2 16-bit depths,
                                   two to a uint (texel 2k in the low half; gim_ism_dequantize); the VPL
                                   methods: map i of VPL i of vpls, or with their paraboloid maps (SSVP's
                                   second bounce) map i of VPL first_bounce_count + i */
    uint32_t ism_size;
} gim_debug_outputs;

/* The internal buffers of the last successful gim_update (all zero for NULL, or before one). */
GIMANY_API gim_debug_outputs gim_debug(const gim_context *ctx);

/* The passes a frame may run, for the timings of gim_frame_stats. */
typedef enum gim_pass {
    GIM_PASS_RSM = 0,
    GIM_PASS_GBUFFER,
    GIM_PASS_VIEW_SAMPLES,
    GIM_PASS_IMPORTANCE_MAP,    /* eq. 10-11 */
    GIM_PASS_CUMSUM,            /* eq. 12 */
    GIM_PASS_SELECT,
    GIM_PASS_CACHES,            /* caches to world space and the hash grid (CPU work + upload) */
    GIM_PASS_VALS,
    GIM_PASS_PROXY_LIGHTS,      /* eq. 3-7, 13-15 */
    GIM_PASS_SHADE,             /* neighbours, eq. 8-9, shading; the VPL methods' shading */
    GIM_PASS_VPLS,              /* VPLs from the RSMs */
    GIM_PASS_KMEANS,            /* k-means steps and the clusters' VALs */
    GIM_PASS_PARABOLOID,        /* the layered paraboloid maps */
    GIM_PASS_SECOND_BOUNCE,     /* second-bounce VPLs */
    GIM_PASS_BLUR,              /* geometry-aware blur */
    GIM_PASS_ISM,               /* LightSkin's imperfect shadow maps and neighbour_rays' hierarchy, in the
                                   frames that make them (a scene change or a setting); the maps' lookups
                                   are GIM_PASS_PROXY_LIGHTS', the rays GIM_PASS_SHADE's */
    GIM_PASS_COUNT
} gim_pass;

/* What the last gim_update did and cost. */
typedef struct gim_stats {
    int timed;                  /* 1: the frame ran with gim_frame.timing, pass_ms is measured */
    int cpu_clock;              /* the clock of pass_ms: 0 GL timestamps (timing 1); timing 2: 1 the
                                   CPU's monotonic clock (clock_gettime, where <time.h> declares
                                   CLOCK_MONOTONIC), 2 the GL's clock read now (glGetInteger64v
                                   GL_TIMESTAMP) where it does not; both after a glFinish */
    double pass_ms[GIM_PASS_COUNT]; /* time per pass (between the stamps after passes), summed over lights */
    double frame_ms;            /* time from the first stamp (frame start) to the last */
    uint32_t light_count, view_sample_count, cache_count, val_count, pixel_count;
    uint32_t vpl_count, cluster_count;   /* the VPL methods: VPLs of both bounces, clusters */
    uint64_t gpu_bytes;         /* GL buffers and textures gimany owns now (meshes included) */
    uint32_t rsm_count;         /* RSMs rendered (light_count less the culled) */
    uint32_t val_light_count;   /* BRSM: RSMs given VALs (importance total > 0) */
    uint32_t ism_maps_made;     /* visibility ISM: imperfect shadow maps rendered by this frame; the caches' are
                                   kept while the scene stays, a first-bounce VPL's with the VPL (gim_frame_vpl.
                                   redraw; 0 for CLUSTERED while nothing moves; SSVP makes its second bounce's
                                   every frame), an unlit VPL's never (no pass reads it). The VPLs' are counted
                                   on the GPU: gim_frame_stats then waits for the frame */
} gim_stats;

/* Stats of the last successful gim_update; waits for the GPU when it was timed. */
GIMANY_API gim_result gim_frame_stats(gim_context *ctx, gim_stats *out);

#ifdef __cplusplus
}
#endif
#endif /* GIMANY_NO_GL */

#ifdef __cplusplus
extern "C" {
#endif

/* The CPU layer (@section math .. @section twins) has one call style (sokol's and cgltf's
   descriptors; docs/design.md sec. 10):
   - parameters are the inputs, then the outputs (a buffer and its capacity together), then
     `gim_env env` by value, last, where the call allocates or logs and no input carries one
     (a desc, a gim_cache_set); a call with none logs nothing: its result code says it all;
   - at most six parameters: a call that needs more takes its inputs in one
     `const gim_<name>_desc *` (zero means default; sizes and env inside), then its outputs:
     gim_kmeans(&desc, &result), gim_importance_select(&desc, out). A desc that several
     calls share (gim_ism_desc) or that names a format (gim_decode_desc) may be followed by
     the inputs of that one call or pixel;
   - a per-texel twin takes what its pass renders from (a gim_camera, a gim_rsm_view, a
     gim_paraboloid and its size), then the texel (x, y);
   - one job, one call: a variant is a desc field (gim_select_desc.offsets), not a second
     function.
   The one exception: the samplers write their point set first, as memcpy does
   (gim_halton_points(out, count, ...), gim_rotation_offsets(out, dims, frame)). */

/* @section math =========================================================================== */
/* The vector and matrix helpers a host needs for cameras and placements (the types are in
   @section scene; the others the implementation uses are private, gim__v3_dot and the like). */

GIMANY_API gim_vec3 gim_v3(float x, float y, float z);             /* constructor */
GIMANY_API gim_vec3 gim_v3_normalize(gim_vec3 a);                  /* a / |a|; (0,0,0) stays zero */

GIMANY_API gim_mat4 gim_mat4_identity(void);                                  /* I */
GIMANY_API gim_mat4 gim_mat4_mul(gim_mat4 a, gim_mat4 b);                     /* a * b */
GIMANY_API gim_vec3 gim_mat4_point(gim_mat4 m, gim_vec3 p);                   /* m * (p,1), divided by w */
GIMANY_API int gim_mat4_invert(gim_mat4 m, gim_mat4 *out);                    /* 0 when singular */
GIMANY_API gim_mat4 gim_mat4_look_at(gim_vec3 eye, gim_vec3 target, gim_vec3 up);     /* gluLookAt */
GIMANY_API gim_mat4 gim_mat4_perspective(float fovy_rad, float aspect, float znear, float zfar); /* gluPerspective */
GIMANY_API gim_mat4 gim_mat4_ortho(float l, float r, float b, float t, float n, float f); /* glOrtho */

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
/* Offsets that move instead of jumping (gim_frame.lightskin.temporal_steps): 48-bit offsets for dims
   dimensions, o_d = frac(b_d + frame * step * g_d) with b_d = r[d] + r[d + dims] 2^-24 from
   r = gim_rotation_offsets(2 dims, seed) and g = (1, 0.618..., frac(d phi) ...) so the walk
   never repeats; written as out[d] + out[d + dims] 2^-24 (out holds 2 dims floats, each 24
   bits). Every o_d is uniform over the seeds, so a frame is as unbiased as with new offsets. */
GIMANY_API void gim_drift_offsets(float *out, uint32_t dims, uint32_t seed, uint32_t frame, double step);
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
/* LightSkin light caches (Bischoff 2017 sec. 3 "Cache Distribution"; Lensing 2013): sparse points
   on the surface where indirect light is accumulated, then interpolated per pixel. Built once
   per mesh in model space. d_eps bounds the cache-to-surface distance (voxels of edge d_eps/2),
   theta_eps the normal deviation a cache may represent. */

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
    float scene_scale;    /* default: diagonal of THIS mesh's bounds (a prop then gets as many
                             caches as a room): pass the scene's, or use gim_cache_generate_scene */
    int no_snap;          /* 1: keep floating caches where averaging put them */
    int no_merge;         /* 1: skip joining similar caches of neighbouring voxels */
    gim_env env;
} gim_cache_desc;

/* A generated (or loaded) set of caches; owns its array (free with gim_cache_set_free). */
struct gim_cache_set {
    gim_cache *caches;
    uint32_t count;
    float d_eps, theta_eps;  /* the values used (after defaults) */
    gim_cache_report report;
    gim_env env;             /* allocator that owns caches */
};

/* Generate caches for one mesh; out is written only on GIM_OK. Every surface point lies within
   d_eps of a cache whose normal is within theta_eps of its own; the cache areas partition the
   used surface; degenerate, non-finite and duplicate triangles are skipped and counted, an
   out-of-range index or material is GIM_ERROR_INVALID_ARGUMENT, a d_eps too small for the
   mesh extent GIM_ERROR_OUT_OF_RANGE. Deterministic; single-threaded; memory linear in the
   voxel pieces (about one per triangle, plus one per voxel a large triangle crosses). */
GIMANY_API gim_result gim_cache_generate(const gim_cache_desc *desc, gim_cache_set *out);
/* Input of gim_cache_generate_scene; zero means default. */
typedef struct gim_cache_scene_desc {
    const gim_cache_desc *meshes; /* count meshes in model space; their theta_eps, no_snap, no_merge
                                     and env are used, their d_eps and scene_scale are not */
    const gim_mat4 *models;       /* count model-to-world matrices placing them (finite), or NULL:
                                     the meshes are in world space. A mesh instanced at several
                                     scales: pass the placement with the largest */
    uint32_t count;
    float d_eps;                  /* world units; 0: scene_scale / 32 */
    float scene_scale;            /* world units; 0: diagonal of the world bounds of all the meshes */
    gim_env env;                  /* log of the scene-level checks */
} gim_cache_scene_desc;

/* Caches for every mesh of a scene at one world spacing (out: count sets, caller-owned array):
   gim_cache_generate with d_eps and scene_scale taken from the whole scene and divided by each
   placement's largest axis scale, so a small prop and the room around it get caches equally
   dense per world area (each mesh's own default would give the prop as many as the room).
   GIM_OK or the first error; out is written only on GIM_OK. */
GIMANY_API gim_result gim_cache_generate_scene(const gim_cache_scene_desc *desc, gim_cache_set *out);
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
     not finite: count 0, d_cmax 0. Both are counted in one warning, neither is an error;
   - max_distance > 0: exactly the unlimited row cut to the caches whose squared distance (the
     double the order uses) is <= max_distance^2, so the n nearest compatible caches within
     the radius, ties included; a vertex with none: count 0, d_cmax 0, row all UINT32_MAX.
   A receiver may be any point with a normal, not only a mesh vertex (a G-buffer pixel, a
   probe): with normals given, indices are not read and may be NULL (index_count 0).
   The set's caches must have finite positions and non-zero finite normals. */
typedef struct gim_neighbour_desc {
    gim_mesh_data mesh;          /* positions and normals (normals NULL: area-weighted face normals) */
    const gim_cache_set *caches;
    uint32_t n;                  /* 1..GIM_MAX_NEIGHBOUR_CACHES, default 16 */
    float theta_eps;             /* (0, pi]; default: 2 x caches->theta_eps (30 degrees if 0), at most 90
                                    degrees, so smooth-shaded edges and corners find caches */
    gim_env env;
    float max_distance;          /* > 0: only caches within this distance count (a receiver far from
                                    every compatible cache gets fewer, or none); 0: no limit. In the
                                    mesh's units, finite */
} gim_neighbour_desc;

/* Caller-owned output of gim_cache_neighbours, sized by the mesh's vertex count; all three
   required. Row v of index is index[v * n .. v * n + n - 1] (n after its default). */
typedef struct gim_neighbour_result {
    uint32_t *index;   /* vertex_count * n cache indices, nearest first; UINT32_MAX pads */
    uint32_t *count;   /* vertex_count: how many of the n were found (compatible caches may be fewer) */
    float *d_cmax;     /* vertex_count: distance of the farthest found cache (0 when none) */
} gim_neighbour_result;

/* Per-vertex neighbour caches through a k-d tree over the caches (not O(V x C)): median splits
   adapt to any density with no unit; nodes farther than the n-th best found (or than
   max_distance), or whose normal bounds admit no compatible normal, are skipped. Exact: the
   O(V x C) answer, bit for bit. */
GIMANY_API gim_result gim_cache_neighbours(const gim_neighbour_desc *desc, gim_neighbour_result *out);

/* Versioned, checksummed byte blob of a cache set (little-endian, CRC-32; layout at @impl
   caches "blobs"), to precompute once: 92 + 32 * count bytes; 0 for NULL. */
GIMANY_API size_t gim_cache_blob_size(const gim_cache_set *set);
/* Write the blob into out (capacity bytes, at least gim_cache_blob_size). A set the reader
   would reject (NaN, negative area, non-unit normal, reflectance outside [0,1]) is refused. */
GIMANY_API gim_result gim_cache_blob_write(const gim_cache_set *set, void *out, size_t capacity);
/* Read a blob; a truncated, corrupt or foreign one is GIM_ERROR_CORRUPT_DATA. On GIM_OK out
   owns caches allocated through env (free with gim_cache_set_free); else out is untouched. */
GIMANY_API gim_result gim_cache_blob_read(const void *blob, size_t size, gim_cache_set *out, gim_env env);

/* @section importance ===================================================================== */
/* Bidirectional importance sampling of the RSM (Bischoff 2017 sec. 4, after Ritschel 2011).
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

/* Largest tile side of the two-level map (gim_importance_tile_map, gim_frame_lightskin.importance_tile),
   and the frame's default side: 1 (the per-texel map) until the figures measured on BRSM (the
   README's table, docs/benchmarks.md) are re-run with tiles; 8 measured best (docs/methods.md,
   LightSkin: as good against FULL and the reference, the importance pass 7.5x cheaper). */
#define GIM_MAX_IMPORTANCE_TILE 32
#define GIM_DEFAULT_IMPORTANCE_TILE 1

/* BRSM's default defensive share (gim_frame_lightskin.defensive_share; docs/methods.md, LightSkin):
   none for now. 1/8 removes the rare frame that one heavy VAL takes over (the street at a turned
   sun: worst of 16 draws 0.551 -> 0.259) but costs the Sponza atrium's BRSM + ISM 0.32 -> 0.36
   on average, where the luminance's picks land in light the view barely gets. */
#define GIM_DEFAULT_DEFENSIVE_SHARE (-1.0f)

/* The shading pass's default block (gim_frame_lightskin.shade_block): 2 x 2 pixels, the pass
   2x cheaper on llvmpipe at the same error against the reference (docs/methods.md). */
#define GIM_DEFAULT_SHADE_BLOCK 2

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

/* Two-level importance (docs/methods.md, LightSkin): eq. 10-11 per plane of each tile of tile x
   tile texels instead of per texel, so the sum over view samples runs at most 4 x (texels /
   tile^2) times. tile_map[tiles_x * tiles_y], tiles_x = ceil(width / tile), tiles_y =
   ceil(height / tile), row-major: tile (i, j) covers texels [i tile, min((i+1) tile, width)) x
   [j tile, ...). A tile's VALs (valid as gim_importance_map counts them: rsm_valid > 0, finite,
   a non-zero normal, flux luminance > 0), in raster order, split into at most 4 planes: a VAL
   lies on a plane when its normal is within acos(0.9) = 26 degrees of the plane's first VAL's
   and it is within 0.01 scene scales of that VAL's plane; a VAL on none starts a plane, the
   fourth takes every VAL left. Per plane P, with Phi_P its luminance sum, x_P its flux-weighted
   mean position and n_P the normalised flux-weighted mean of its normals, l = VS_j - x_P:
     G_P = 1 / N_VS * sum_j (n_P . d)+ (n_VS . -d)+ / max(|l|^2 / scene_scale^2, clamp^2)
   (eq. 10 at the plane's aggregate). weight[width * height]: each VAL's luminance x G of its
   plane, 0 at the other texels; tile_map: the sum of the tile's weights. So a texel's weight is
   its eq. 10 value with the geometry of its plane's aggregate: one aggregate per tile was not
   enough (where a wall meets the ground or a roof edge lies over the street, its mean point floats
   between the surfaces: on the street at RSM 1024^2, 10x the per-texel map's variance and texels
   of P = 0 that light the view; with the planes +4% at tile 8 and none). gim_importance_cumsum of
   tile_map and gim_importance_select with the desc's tile and weight pick a tile by its sum, then
   a texel by its weight: P = P(tile) weight / (the tile's weight sum), exact and > 0 for every
   picked texel. Units: weights and tile_map as gim_importance_map's out (flux); every output
   finite and >= 0 (clamped at FLT_MAX). tile 1 gives gim_importance_map's map in both outputs (to
   rounding); tile in 1..GIM_MAX_IMPORTANCE_TILE. */
GIMANY_API gim_result gim_importance_tile_map(const gim_importance_desc *desc, uint32_t tile, float *tile_map,
                                              float *weight);

/* The tables' input of the selection's defensive share (gim_select_desc.defensive_count): each
   texel's flux luminance where gim_importance_map counts it as a VAL, else 0, into
   weight[width * height] (may be NULL when tile is 1), and its sum per tile of tile x tile
   texels into tile_map as gim_importance_tile_map's (tile 1: the luminances themselves). The view
   samples are not read (desc's may be NULL). Every output finite and >= 0 (clamped at FLT_MAX). */
GIMANY_API gim_result gim_importance_luminance(const gim_importance_desc *desc, uint32_t tile, float *tile_map,
                                               float *weight);

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

/* Input of gim_importance_select; zero means default. */
typedef struct gim_select_desc {
    const double *column;       /* width * height: eq. 12's column table (gim_importance_cumsum) */
    const double *row;          /* width: eq. 12's row table */
    uint32_t width, height;
    uint32_t count;             /* texels to pick, > 0 */
    uint32_t seed;              /* the rotation's seed (e.g. the frame) where offsets is NULL */
    const float *offsets;       /* 4 values in [0,1): o_d = offsets[d] + offsets[d + 2] 2^-24 (gim_rotation_offsets'
                                   4 values of a seed, or gim_drift_offsets' of dims 2), or NULL: from seed */
    uint32_t tile;              /* 0 or 1: the tables are per texel (width x height texels); T > 1: they are of
                                   gim_importance_tile_map's tile map (width x height tiles of T x T texels) and
                                   a texel is picked inside the tile by weight */
    const float *weight;        /* tile > 1: rsm_width * rsm_height texel weights (gim_importance_tile_map's),
                                   finite and >= 0 */
    uint32_t rsm_width, rsm_height; /* tile > 1: the RSM's size in texels; width = ceil(rsm_width / tile),
                                   height = ceil(rsm_height / tile) */
    /* Defensive share (Hesterberg 1995; Veach and Guibas 1995, the balance heuristic): the last
       defensive_count of the count picks come from a second set of tables, of the texels'
       luminance alone (gim_importance_luminance, then gim_importance_cumsum), as a Hammersley set
       of their own with the same offsets, and every pdf is the mixture's,
         pdf = ((count - defensive_count) P_importance + defensive_count P_luminance) / count,
       so 1 / (count pdf) <= L_total / (defensive_count L_texel): no texel that has light weighs
       more than count / defensive_count times its share of the RSM's luminance, and a texel of
       importance 0 that has light can still be picked. 0: none (the paper's selection). */
    uint32_t defensive_count;   /* < count */
    const double *lum_column;   /* defensive_count > 0: the luminance tables, the size of column and row */
    const double *lum_row;
    const float *lum_weight;    /* defensive_count > 0, tile > 1: rsm_width * rsm_height texel luminances */
    gim_env env;
} gim_select_desc;

/* Pick count texels with probability proportional to the map into out[count]. Sample i takes
   the point
     u_i = frac(i / count + o_0),  v_i = frac(radical_inverse_2(i) + o_1)
   of the Hammersley set, Cranley-Patterson rotated by 48-bit offsets o_d: the desc's offsets,
   or per seed o_d = f[d] + f[d+2] * 2^-24 (f from gim_rotation_offsets(f, 4, seed)). u_i picks the
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
   positive difference (out is then partly written).
   Two levels (tile > 1): the search above picks a tile with P(tile); the texel inside it is then
   picked by the residual of v_i in the tile's interval, r = (v_i c_y - c_(y-1)) / (c_y - c_(y-1))
   with c the column's sums (uniform in [0,1) over the seeds wherever v_i is, so no third
   random dimension is needed): the first texel of the tile, row-major, whose running weight sum
   (double) exceeds r * Phi_tile. out's x, y are RSM texels and
     pdf = P(tile) * weight(x, y) / Phi_tile,
   Phi_tile the tile's weight sum in the same order. The offsets' 48 bits leave r at least
   2^48 P(row | column) distinct values, plenty for tile^2 texels. An all-zero tile map selects texels
   uniformly over the RSM, pdf 1 / (rsm_width * rsm_height). A picked tile whose weights sum to 0 or
   NaN (weights that are not the tile map's) is GIM_ERROR_INVALID_ARGUMENT. */
GIMANY_API gim_result gim_importance_select(const gim_select_desc *desc, gim_selected_val *out);

/* @section twins ========================================================================== */
/* LightSkin cache lighting, CPU twins of its GPU passes (Bischoff 2017 sec. 3 "Cache Lighting",
   "Proxy Lights Generation", "Interpolation using the Proxy Lights"; sec. 4 eq. 13-15).
   Each function has the structure of its pass: one independent invocation per cache
   (gim_proxy_lights_twin; the GPU pass also splits a cache's VALs over lanes and merges
   their sums, gim__proxy_lanes) or per receiver pixel (gim_lightskin_shade_twin),
   each a loop in a fixed order, so the results are deterministic.

   Units (docs/design.md sec. 5): a VAL is an RSM texel, a Lambertian disk of area A_l with
   reflected flux Phi_l (rgb), so its radiance is Phi_l / (pi A_l). Per cache c (normal n_c)
   and VAL j, with w_j the VAL's estimator weight, d_j = |x_l,j - c|, omega_j = (x_l,j - c) / d_j:
     e_j = w_j Phi_j cos+theta_l cos+theta_x / (A_j + pi d_j^2)       irradiance at c (eq. 3
                                                                      without rho_d / pi)
     g_j = ((r_j . v_c)+)^k, r_j = omega_j mirrored at n_c            Phong lobe (eq. 4), v_c the
                                                                      unit direction c -> eye
   so L_o,d = rho_d / pi sum e_j (eq. 3/14) and L_o,g = rho_g (k+2) / (2 pi) sum g_j e_j
   (eq. 4/15, the `+` printed in eq. 4 is a product). Summed with w_j = 1 over every texel
   (FULL) or with w_j = 1 / (N P_VAL) over N VALs drawn with probability P_VAL (BRSM), which
   is an unbiased estimate of the FULL sum wherever P_VAL > 0 on every texel that lights the
   cache (eq. 14-15 print 1 / P without the 1 / N of the mean; gim_vals_gather_twin applies it).

   A proxy light is a point light (position x_p, flux Phi_p, isotropic) that gives the cache
   the same outgoing radiance (eq. 7): f_r(omega_p) Phi_p (n_c . omega_p)+ / (4 pi |x_p - c|^2)
   = L_o. The BRDF's constants (rho_d / pi, rho_g (k+2) / (2 pi)) cancel between eq. 3/4 and
   eq. 7, so a proxy light carries no cache material: the receiver applies its own albedo and
   glossy colour when it is shaded. */

/* One virtual area light (an RSM texel): three vec4 (std430 layout of the GPU buffer). */
typedef struct gim_val {
    float position[3];  /* x_l, world space */
    float area;         /* A_l >= 0, footprint on the surface (eq. 1) */
    float normal[3];    /* unit (|n|^2 within 1e-3 of 1), or zero: the VAL emits nothing */
    float weight;       /* estimator weight >= 0: 1 for FULL, 1 / (N P_VAL) for BRSM; 0 skips it */
    float flux[3];      /* Phi_l, rgb, >= 0 */
    float unused;       /* padding, ignored */
} gim_val;

/* One proxy light of a cache: three vec4. */
typedef struct gim_proxy_light {
    float position[3];  /* x_p (eq. 5 / 13) */
    float radius;       /* extent of the light: 2 max(sigma) (the AABB of extent 2 sigma) */
    float flux[3];      /* Phi_p, rgb (eq. 7 with the guard below) */
    float visibility;   /* in [0,1], scales the light where it is shaded; gim_proxy_lights_twin writes 1 (visibility
                           per VAL comes in through gim_proxy_desc.visibility) */
    float sigma[3];     /* weighted standard deviation of the VAL positions per world axis */
    float unused;       /* padding, 0 */
} gim_proxy_light;

/* An RSM as float arrays, width * height texels row-major, row 0 first (as gim_importance_desc). */
typedef struct gim_rsm_data {
    const float *position;  /* * 3: world position */
    const float *normal;    /* * 3: unit normal */
    const float *flux;      /* * 3: reflected flux Phi, rgb */
    const float *area;      /* * 1: footprint A (eq. 1; constant / cos for an orthographic RSM) */
    const float *valid;     /* * 1, or NULL: a texel counts only where > 0 */
    uint32_t width, height;
} gim_rsm_data;

/* The VAL list of one frame (the fetch at the start of the proxy pass):
   selected == NULL (FULL LightSkin): out[width * height], texel t with weight 1;
   selected != NULL (BRSM): out[selected_count], selected[i]'s texel with weight
   1 / (selected_count * pdf), the unbiased Monte Carlo weight of eq. 13-15.
   An invalid texel (valid <= 0, a NaN/Inf in its data, negative flux or area) becomes a VAL
   of weight 0 and zero flux: it lights nothing. A selected texel outside the RSM or a pdf that
   is not finite and > 0 is GIM_ERROR_INVALID_ARGUMENT (out partly written). */
GIMANY_API gim_result gim_vals_gather_twin(const gim_rsm_data *rsm, const gim_selected_val *selected,
                                      uint32_t selected_count, gim_val *out, gim_env env);

/* Input of gim_proxy_lights_twin; zero means default. */
typedef struct gim_proxy_desc {
    const gim_cache *caches;     /* world-space caches (unit normals) */
    uint32_t cache_count;        /* > 0 */
    const gim_val *vals;         /* the frame's VALs (gim_vals_gather_twin); val_count 0 is dark, not an error */
    uint32_t val_count;
    gim_vec3 eye;                /* camera position: v_c of the glossy lobe at each cache */
    float glossy_exponent;       /* k >= 0 of every cache (<= 1e6) */
    const float *cache_glossy_exponent; /* cache_count values of k, or NULL: glossy_exponent */
    float scene_scale;           /* > 0; 0: diagonal of the bounds of caches and VALs */
    const float *visibility;     /* cache_count * val_count V(c, x_j) in [0,1], row per cache (e.g.
                                    gim_ism_visibility_twin), or NULL: every VAL seen */
    gim_env env;
} gim_proxy_desc;

/* Proxy lights of every cache, one independent invocation per cache looping over the VALs:
   diffuse_out[cache_count] (required) and glossy_out[cache_count] (NULL skips the glossy
   pass: a scene without glossy materials pays nothing for it). Per cache:
   position (eq. 5/13): x_p = c + sum W_j (x_l,j - c) / sum W_j with the contribution weights
     W_j = lum(Phi_j) e_j (diffuse), lum(Phi_j) g_j e_j (glossy). The paper's eq. 6 weighs by
     the form factor alone (epsilon_p + F); weighing by what each VAL adds puts the proxy where
     the light comes from, and a black texel no longer drags it. They are equal when all VALs
     have the same radiance. Where no VAL lights the cache (sum W = 0), the paper's form factor
     weights F_j = w_j A_j cos cos / (A_j + pi d^2) place it, with zero flux, so the position
     an interpolating neighbour sees stays meaningful; with no VAL in front of the cache at
     all, x_p = c. A glossy lobe that sees none of the light takes the diffuse proxy's position
     and sigma, with zero flux. epsilon_p of eq. 6 is then never needed.
   sigma: sqrt(sum W (x - c)^2 / sum W - (x_p - c)^2) per axis (the same weights); radius = 2 max.
   flux (eq. 7): Phi_p = 4 pi |x_p - c|^2 S / max(D_p, lum(S) / lum(E_n)), with S = sum e_j
     (diffuse) or sum g_j e_j (glossy), D_p = f(omega_p) (n_c . omega_p)+ (f = 1 or the lobe
     g at the proxy's direction) and E_n = sum e_j / cos+theta_x,j, the irradiance the VALs
     deliver to c perpendicular to each of their directions. Guard: the proxy light may not
     carry more normal irradiance (Phi_p / 4 pi d_p^2) than all its VALs deliver, so eq. 7's
     division by the BRDF and the cosine stays finite. It never bites for one VAL (then
     D_p = lum(S) / lum(E_n) exactly) and rarely for diffuse light (the weighted mean direction
     rises above its VALs); where it bites the cache's own radiance is underestimated by
     D_p / floor (a glossy lobe narrower than the spread of the light around the mirror
     direction), never overestimated.
   Near field: a VAL nearer than 2 sqrt(A_j) to the cache (and in front of it) is evaluated
   as the patch it stands for: a regular octagon of area A_j around x_l,j in its plane,
   clipped to the cache's hemisphere, with vector form factor Phi_j (Lambert's contour
   formula): e_j = w_j n_c . Phi_j / A_j, its E_n term w_j |Phi_j| / A_j, and the direction of
   x_l,j - c turned to Phi_j's for the position and the lobe (faded in from 1.5 sqrt(A_j));
   elsewhere e_j is the disk formula above.
   With visibility, e_j (and its E_n term) is multiplied by V(c, x_j): a VAL the cache cannot
   see neither lights nor places the proxy. visibility = 1 (the proxy light's field). A VAL nearer than 1e-6 scene_scale to the cache (no direction) and one with
   weight 0 add nothing. Sums in double, per-VAL terms in float. Every output is finite
   (flux clamped at FLT_MAX). Errors: NULL, zero cache_count, a cache or VAL that is not finite
   or breaks the ranges above (the first offender is logged), k out of range. */
GIMANY_API gim_result gim_proxy_lights_twin(const gim_proxy_desc *desc, gim_proxy_light *diffuse_out,
                                       gim_proxy_light *glossy_out);

/* A receiver: a visible surface point (a G-buffer pixel) and its material. */
typedef struct gim_receiver {
    float position[3];
    float normal[3];    /* unit */
    float view[3];      /* unit direction from the point towards the viewer */
    float albedo[3];    /* diffuse rho_d, >= 0 */
    float glossy[3];    /* glossy rho_g, >= 0 (ignored without glossy proxy lights) */
    float exponent;     /* Phong k >= 0, <= 1e6 */
} gim_receiver;

/* Input of gim_lightskin_shade_twin; zero means default. */
typedef struct gim_shade_desc {
    const gim_cache *caches;
    uint32_t cache_count;
    const gim_proxy_light *diffuse;   /* cache_count proxy lights (required) */
    const gim_proxy_light *glossy;    /* cache_count, or NULL: no glossy term */
    const gim_receiver *receivers;
    uint32_t receiver_count;
    const uint32_t *neighbour_index;  /* receiver_count * neighbour_stride cache indices; UINT32_MAX pads */
    const uint32_t *neighbour_count;  /* receiver_count counts <= stride, or NULL: all stride entries */
    uint32_t neighbour_stride;        /* n of gim_cache_neighbours, 1..GIM_MAX_NEIGHBOUR_CACHES */
    const float *d_cmax;              /* receiver_count: d_c,max of eq. 8 (>= 0) */
    float scene_scale;                /* > 0 */
    const uint32_t *source;           /* receiver_count, or NULL (each its own): receiver i takes the light
                                         interpolated at receiver source[i] (its position, normal, view,
                                         exponent, neighbours and d_c,max) times its own albedo and glossy
                                         colour: the shading pass's blocks, from gim_shade_sources */
    gim_env env;
} gim_shade_desc;

/* Indirect radiance leaving each receiver towards its viewer, rgb into
   radiance_out[receiver_count * 3]; one independent invocation per receiver (pixel).
   eq. 8: w'_d = (1 - |x - c_j| / d_c,max)+ sqrt((n_x . n_c)+),
          w'_g = (1 - |x - c_j| / d_c,max)+ sqrt((r_x . r_c)+), r the direction towards the
          cache's glossy proxy mirrored at n_x and at n_c. Guards: d_c,max <= 1e-6 scene_scale
          (coincident caches) makes the distance factor 1; where every w' is 0 (a lone
          neighbour at exactly d_c,max) the distance factor is dropped, leaving the normal one.
   eq. 9, as irradiance: the proxies "move along with the surface point": neighbour j's proxy
          is seen at x + (x_p,j - c_j), so it delivers
            E_j = Phi_p,j visibility_j (n_x . l_j)+ / (4 pi |x_p,j - c_j|^2),  l_j its unit offset,
          (|x_p,j - c_j|^2 floored at (1e-6 scene_scale)^2) and the receiver takes
            E = sum w' E_j / sum w'            (diffuse),
            G = sum w' E_j f_j / sum w',  f_j = (k+2) / (2 pi) ((r_j . view)+)^k,
                                          r_j = l_j mirrored at n_x   (glossy, per neighbour).
          eq. 9 as printed averages flux and position and applies 1 / |l|^2 afterwards; eq. 7
          makes a proxy's flux grow with the square of its distance, so that is biased dark
          (0.5-0.85 of the light near contact edges) with flux-weighted positions and bright
          with eq. 9's w' alone. One neighbour at x = c_j, or neighbours that agree, give the
          cache's own radiance exactly.
   shading: L = rho_d / pi E + rho_g G.
   Receivers with no neighbour get 0. Errors: NULL arrays, zero counts, an index >= cache_count
   (other than the UINT32_MAX pad), NaN/Inf or out-of-range inputs (the first is logged). */
GIMANY_API gim_result gim_lightskin_shade_twin(const gim_shade_desc *desc, float *radiance_out);

/* Input of gim_shade_sources: the receivers of an image's pixels. */
typedef struct gim_shade_blocks_desc {
    const gim_receiver *receivers;
    uint32_t receiver_count;
    const uint32_t *pixels;           /* receiver_count (x, y) pairs, inside the image, each pixel at most once */
    uint32_t width, height;           /* the image */
    uint32_t block;                   /* B, 1 or 2; 0: GIM_DEFAULT_SHADE_BLOCK */
    float cell;                       /* the cache grid's cell side h (gim_debug_outputs.neighbour_cell), > 0 */
    gim_env env;
} gim_shade_blocks_desc;

/* Which receiver's interpolated light each receiver takes in the shading pass's B x B blocks
   (gim_frame_lightskin.shade_block): the pixels (B floor(x / B), B floor(y / B)) + (0,0), (1,0),
   (0,1), (1,1) form a block, its first receiver r in that order finds its neighbours, and a
   receiver x of the block takes r's light where it lies on r's surface near r, in float:
     n_x . n_r >= 0.995 (5.7 degrees),  |n_r . (x - r)| <= 0.05 |x - r| (2.9 degrees off r's
     plane),  |x - r| <= h / 4,  and the same Phong exponent,
   else its own. The light changes over a grid cell (the caches' spacing), so a block of one
   surface shares it with an error of the order of its gradient over h / 4; a depth or normal
   edge inside a block keeps each side its own. source_out[receiver_count]: the index of that
   receiver (its own index where it takes its own light), for gim_shade_desc.source. */
GIMANY_API gim_result gim_shade_sources(const gim_shade_blocks_desc *desc, uint32_t *source_out);

/* Input of gim_lightskin_frame_twin: one LightSkin frame, everything of the two descs above. */
typedef struct gim_lightskin_desc {
    const gim_cache *caches;
    uint32_t cache_count;
    const gim_val *vals;              /* FULL or BRSM, from gim_vals_gather_twin */
    uint32_t val_count;
    gim_vec3 eye;
    int glossy;                       /* 1: glossy proxy lights and the glossy term; 0: diffuse only */
    float glossy_exponent;
    const float *cache_glossy_exponent;
    const gim_receiver *receivers;
    uint32_t receiver_count;
    const uint32_t *neighbour_index;
    const uint32_t *neighbour_count;
    uint32_t neighbour_stride;
    const float *d_cmax;
    const uint32_t *source;           /* as gim_shade_desc.source */
    float scene_scale;                /* > 0; 0: diagonal of the bounds of caches and VALs */
    const float *visibility;          /* as gim_proxy_desc.visibility, or NULL */
    gim_env env;
} gim_lightskin_desc;

/* The whole CPU LightSkin frame, the twin of the GPU frame after the RSM (and selection):
   gim_proxy_lights_twin -> gim_lightskin_shade_twin. Allocates the
   proxy lights (cache_count, twice with glossy) through env and frees them before returning.
   radiance_out[receiver_count * 3]. */
GIMANY_API gim_result gim_lightskin_frame_twin(const gim_lightskin_desc *desc, float *radiance_out);

/* RSM gather (Dachsbacher and Stamminger 2005), the baseline method: each receiver gathers a
   fixed pattern of RSM texels around its own projection into the RSM, no caches, no
   visibility. Sample i at polar offset (r_i, phi_i) = (radius u_i, 2 pi v_i) texels from the
   receiver's texel-space projection p, (u_i, v_i) from samples (e.g. gim_hammersley_points):
   denser near p, as the paper's pattern. Each sampled texel is a VAL of the units above with
   the weight 1 / (N pdf) = 2 pi r_i radius / N, the inverse of the pattern's density per
   texel, so the sum is an unbiased estimate of the sum over every texel within radius of p
   (the FULL sum when the disk holds the RSM); the receiver's own texel (r -> 0) weighs ~0,
   which removes the singularity of the paper's weighting. A receiver that projects outside
   the RSM centres the pattern on the RSM's nearest point, one behind a perspective light's
   eye (w <= 0) on its centre (the Cornell box's ceiling, behind its spot, got nothing
   before), so with a radius of the whole RSM every receiver gets the FULL sum's estimate. A
   texel outside the RSM or unlit adds nothing.
     L = rho_d / pi sum e_j + rho_g (k+2) / (2 pi) sum g_j e_j, e_j as in gim_proxy_lights_twin with
     x for c, g_j = ((r_j . view)+)^k, r_j the direction to the VAL mirrored at the normal. */
typedef struct gim_gather_desc {
    const gim_rsm_data *rsm;          /* one light's RSM (valid: the lit flag) */
    gim_mat4 light_view_proj;         /* its camera: proj x view (gim_light_camera) */
    const float *samples;             /* sample_count x 2 values in [0, 1) */
    uint32_t sample_count;            /* > 0 */
    float radius;                     /* in texels, > 0 */
    const gim_receiver *receivers;
    uint32_t receiver_count;
    float scene_scale;                /* > 0: VALs nearer than 1e-6 of it add nothing */
    gim_env env;
} gim_gather_desc;

/* The gathered radiance of one light, rgb into radiance_out[receiver_count * 3] (one light:
   sum the calls of several). Errors: NULL arrays, zero counts, a radius or scale that is not
   finite and > 0, a receiver as gim_lightskin_shade_twin rejects it. */
GIMANY_API gim_result gim_rsm_gather_twin(const gim_gather_desc *desc, float *radiance_out);

/* Which low-discrepancy points pick the first-bounce VPLs' texels. */
typedef enum gim_vpl_sequence {
    GIM_VPL_SEQUENCE_DEFAULT = 0,   /* = HALTON */
    GIM_VPL_SEQUENCE_HALTON,        /* Halton points 1..count, bases 2, 3 (Dong sec. 6) */
    GIM_VPL_SEQUENCE_HAMMERSLEY     /* Hammersley points (i + 0.5) / count, radical inverse base 2 of i (SSVP eq. 1) */
} gim_vpl_sequence;

/* VPLs from an RSM, the twin of the runtime's VPL pass (Dong et al. 2009 sec. 4): count VPLs at the
   points of sequence: HALTON, the 2D Halton points 1..count (gim_halton_points, bases 2 and 3;
   point 0 is the corner); HAMMERSLEY, point i is ((i + 0.5) / count, gim_van_der_corput(i)).
   Both are Cranley-Patterson rotated by offsets (2 values in [0,1), or NULL). Point (u, v) takes the texel
   (min(floor(u width), width - 1), min(floor(v height), height - 1)); a texel may be taken
   twice. Each VPL gets its texel's position and normal, and flux such that the VPLs' flux sums
   to the RSM's total reflected flux over the lit texels, per channel c:
     flux_i,c = Phi_t(i),c * T_c / S_c,  T_c = sum of Phi_c over every lit texel,
                                         S_c = sum of Phi_t(i),c over the VPLs (repeats counted);
   where S_c = 0 (every sampled texel dark in c) the VPLs carry nothing in c. A texel is lit
   where valid is NULL or > 0 and its position, normal and flux are finite with flux >= 0
   (gim_vals_gather_twin's rules but the area's, which a VPL does not take); an unlit one gives a
   VPL of zero flux (weight 0 in gim_kmeans' means), its position and normal copied when
   finite, zero otherwise (gim_kmeans refuses a zero normal: leave those VPLs out). Sums in double in a fixed order, the GPU pass's: T row by row (each row in x
   order, then the rows), S in blocks of GIM_RSM_VPL_BLOCK VPLs, then the blocks.
   positions, normals, flux: count * 3 each, written. area (count, or NULL: not written): the
   surface each VPL stands for (gim_vpl.area, its near field), its texel's footprint times the
   texels it stands for, A_t(i) (T_r + T_g + T_b) / (S_r + S_g + S_b), so that the patch leaves
   the texel's own exitance; 0 for an unlit texel, a footprint that is not finite and > 0, or an
   RSM without areas. Errors (GIM_ERROR_INVALID_ARGUMENT): NULL
   arrays, zero sizes or count, offsets outside [0,1); a total beyond FLT_MAX is
   GIM_ERROR_OUT_OF_RANGE. Outputs untouched on error. */
#define GIM_RSM_VPL_BLOCK 1024u

/* Input of gim_rsm_vpls_twin; zero means default. */
typedef struct gim_rsm_vpls_desc {
    const gim_rsm_data *rsm;        /* one light's RSM */
    uint32_t count;                 /* VPLs, > 0 */
    gim_vpl_sequence sequence;
    const float *offsets;           /* 2 values in [0,1), or NULL: no rotation */
    /* Incremental instant radiosity (Laine et al. 2007): the last frame's count VPLs of this RSM,
       slot for slot (gim_vpl layout), or NULL: every VPL drawn at its texel. VPL i keeps its
       previous position and normal where it is lit, view_proj (the RSM's camera now, clip =
       view_proj (x, 1)) puts it on a texel inside the RSM within gim__rsm_vpl_radius of its slot's
       texel (so the VPLs stay one per stratum of the sequence and the weights stay equal), that
       texel is lit, holds a point within 2 sqrt(its footprint) of the VPL (the light still sees
       it) and a normal within acos 0.9 of its own; it takes that texel's flux and footprint, and
       T / S counts that texel. The float steps are the GPU pass's, in its order. */
    const struct gim_vpl *previous;
    gim_mat4 view_proj;
    unsigned char *kept;            /* out: count flags, 1 where VPL i was kept (0 without previous), or NULL */
    gim_env env;
} gim_rsm_vpls_desc;

GIMANY_API gim_result gim_rsm_vpls_twin(const gim_rsm_vpls_desc *desc, float *positions, float *normals, float *flux,
                                        float *area);

/* Caches of a mesh placed by an instance (the runtime's "caches to world space" step): the
   position through model, the normal through its inverse transpose (normalised), the area
   scaled as the surface element is, |det M| |M^-T n| for the 3x3 M of model, so the areas of
   a mesh's caches still sum to the area of the placed mesh under any non-uniform scale or
   shear; reflectance kept. out may be in. A model that is not finite or singular, or a
   result that is not finite, is GIM_ERROR_INVALID_ARGUMENT (out partly written then). */
GIMANY_API gim_result gim_caches_to_world(const gim_cache *in, uint32_t count, gim_mat4 model, gim_cache *out,
                                          gim_env env);

/* Caches on a deforming (skinned, morphing) mesh follow its surface: each is bound once to the
   triangle it lies on, and each frame its position, normal and area are made again from the
   deformed vertices (the GL runtime does this per frame in caches_follow.comp for meshes
   added with gim_mesh_desc.deforming; gim_caches_follow_twin is its twin). */
typedef struct gim_cache_binding {
    uint32_t vertex[3];  /* the triangle's vertex indices (a, b, c) */
    float u, v;          /* barycentrics of b and c of the cache's foot point on the triangle */
    float h;             /* signed height of the cache above its foot point along the unit face
                            normal, model units (0 for a cache on the surface; kept unscaled) */
    float area2;         /* |(b - a) x (c - a)| at binding: twice the triangle's area, units^2 */
    float frame[3];      /* the cache normal in the triangle's frame: n.(b - a), n.(c - a), n.n_face */
} gim_cache_binding;

/* Bind count caches to mesh (positions, indices; strides honoured; normals unused): each to the
   non-degenerate triangle nearest to its position (exact point-triangle distance, ties to the
   lower triangle index; a uniform grid over the triangles finds it: 39 ms for 20000 triangles
   and 5288 caches), with the foot point, height and normal frame above. Errors
   (GIM_ERROR_INVALID_ARGUMENT): NULL arrays, an index out of range, non-finite positions or
   caches, no non-degenerate triangle; GIM_ERROR_OUT_OF_MEMORY. out partly written on error. */
GIMANY_API gim_result gim_cache_bind(const gim_mesh_data *mesh, const gim_cache *caches, uint32_t count,
                                     gim_cache_binding *out, gim_env env);
/* Caches moved with their triangles (twin of caches_follow.comp): for the deformed triangle
   (a', b', c') with unit normal n' = (b'-a') x (c'-a') / |.|, position (1-u-v) a' + u b' + v c'
   + h n'; normal the rest normal carried by the triangle's own linear map M (M^-T n:
   frame[0] (c'-a') x n' + frame[1] n' x (b'-a') + frame[2] (b'-a') x (c'-a'), normalised, where
   M maps the edges to the new edges and the unit face normal to the new one: a cache tilted
   from its triangle keeps its place in the triangle's frame; a cache along its face normal
   (a flat surface) under an affine map A of the mesh gets A's own A^-T n, while for a tilted
   one A's action off the plane is not known from the triangle, M stands for it); area
   rest.area x |(b'-a') x (c'-a')| / area2, the triangle's area ratio,
   so the caches' areas still sum to the stretched surface's area; reflectance kept. A triangle
   collapsed to zero area keeps the rest normal with area 0. positions: vertex_count float3
   (model space). out may not alias rest. Errors (GIM_ERROR_INVALID_ARGUMENT): NULL arrays, a
   binding's vertex >= vertex_count, a result that is not finite (out partly written then). */
/* Input of gim_caches_follow_twin. */
typedef struct gim_follow_desc {
    const gim_cache *rest;          /* count caches as gim_cache_bind bound them (model space) */
    const gim_cache_binding *bind;  /* count bindings (gim_cache_bind) */
    uint32_t count;
    const float *positions;         /* vertex_count * 3: the deformed vertices (model space) */
    uint32_t vertex_count;
    gim_env env;
} gim_follow_desc;

GIMANY_API gim_result gim_caches_follow_twin(const gim_follow_desc *desc, gim_cache *out);


/* twins of the scene passes: RSM texel, G-buffer, view samples ------------------------------
   The scene description the GL runtime takes (gim_set_materials, gim_set_lights) and the CPU
   twins of the shared passes of the frame (docs/design.md sec. 3): each casts the ray through one
   texel centre against a world-space triangle soup (brute force: for tests and small scenes)
   and computes what the GPU pass writes at that texel.

   Units (docs/design.md sec. 5). Lengths in the host's unit L; a directional light's irradiance E
   is power per unit area perpendicular to its direction (W / L^2); a spot's intensity I is
   power per steradian (W / sr) inside its cone and 0 outside. An RSM texel is a VAL:
     footprint area A (L^2): for the spot the texel's solid angle w at the light times d^2
       over the cosine at the surface, A = w d^2 / cos (eq. 1 of Bischoff 2017 is the on-axis
       case w = s^2, with s the texel side on the plane at distance 1; the exact
       w = s^2 / (1 + u^2 + v^2)^(3/2) at image-plane point (u, v) makes the texels' w sum to
       the cone's solid angle); for the orthographic sun A = a / cos with a = (width / size) x
       (height / size) of its window, the texel's area perpendicular to the light. cos is clamped below at
       GIM_RSM_MIN_COS so a grazing texel's A stays finite.
     flux Phi (W) = albedo x the power arriving on the footprint: the sun's E x a (E cos on
       an area a / cos: the tilt cancels), the spot's I x w (I w over A = w d^2 / cos is
       irradiance I cos / d^2 on A). Summed over the texels that see a diffuse plane of
       albedo rho: rho E (projected area) for the sun, rho I (solid angle of the plane
       within the cone) for the spot.
   Normals face the light (the RSM) or the eye (the G-buffer): a surface seen from its back
   is lit and seen on that side (two-sided). */

/* The light's camera: a look-at view and a projection fitted to the scene bounds (bmin, bmax:
   the world bounds of everything that casts or receives). SPOT: perspective of field of view
   2 x cone_angle, aspect 1, far just past the farthest bounds corner, near at the bounds (or
   far / 10^4 when the light is inside them). DIRECTIONAL: orthographic, +-extent around the
   bounds' centre or (extent 0) the rectangle of the 8 bounds corners seen along the light plus
   0.1% of the bounds' radius each side, the bounds' sphere inside its depth range. The GL runtime uses the same. */
GIMANY_API gim_result gim_light_camera(const gim_light *light, const float bmin[3], const float bmax[3],
                                       gim_mat4 *view, gim_mat4 *proj);

/* The six square spots a POINT light is rendered as (gim_set_lights does this): axes +x, -x,
   +y, -y, +z, -z, cone_angle pi / 4 with square_cone (their frusta tile the sphere, so the
   faces' texels' solid angles sum to 4 pi), the point's position, intensity, colour and
   rsm_size. Non-POINT lights: GIM_ERROR_INVALID_ARGUMENT. */
GIMANY_API gim_result gim_point_light_faces(const gim_light *point, gim_light faces[6]);

/* The bounds and light gim_light_camera takes for a fit_view sun: the part of the camera's
   frustum (near plane to min(far plane, view_distance); view_distance 0: the far plane) inside
   the scene bounds is the focus; out_light's extent is the focus' bounding radius (or the
   light's own extent when > 0), and out_min/out_max are the focus stretched along the light
   direction by the scene's diagonal both ways, so the orthographic window covers the focus
   while its depth range still holds every caster of the scene. A focus that is empty (the
   camera looks out of the scene) falls back to the scene bounds. Other lights are copied
   with the scene bounds. */
typedef struct gim_fit_view_desc {
    const gim_light *light;
    const float *scene_min, *scene_max; /* 3 each: the scene's world bounds */
    gim_mat4 view, proj;                /* the host's camera (finite, invertible) */
    float view_distance;                /* >= 0, finite; 0: the far plane */
} gim_fit_view_desc;

GIMANY_API gim_result gim_light_fit_view(const gim_fit_view_desc *desc, gim_light *out_light, float out_min[3],
                                         float out_max[3]);

/* What the G-buffer and view-sample passes render from: the host's camera and view size. */
typedef struct gim_camera {
    gim_mat4 view, proj;     /* finite; proj invertible */
    uint32_t width, height;  /* pixels, > 0 */
} gim_camera;

/* What an RSM is rendered from: a light and the world bounds its camera is fitted to (what
   gim_light_camera takes; gim_light_fit_view writes them for a fit_view sun). */
typedef struct gim_rsm_view {
    const gim_light *light;
    const float *bmin, *bmax;  /* 3 each */
} gim_rsm_view;

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
   its clip space, as GL stores it); the camera is gim_light_camera's of view. */
GIMANY_API gim_result gim_rsm_texel_twin(const gim_twin_scene *scene, const gim_rsm_view *view, uint32_t x, uint32_t y,
                                         gim_rsm_texel *out);

/* What the G-buffer pass writes at one pixel. */
typedef struct gim_gbuffer_texel {
    float position[3];       /* world */
    float normal[3];         /* unit, towards the eye; 0 where nothing is hit */
    float albedo[3];         /* diffuse rgb */
    float depth;             /* window depth in [0, 1]; 1 where nothing is hit */
    uint32_t triangle;       /* UINT32_MAX: none */
} gim_gbuffer_texel;

/* How a host's G-buffer holds its normals and depth (gim_frame.gbuffer's fields) and the
   camera it was drawn with: the input of gim_gbuffer_decode_twin. */
typedef struct gim_decode_desc {
    gim_normal_encoding encoding;
    int view_space;          /* 1: the normal is in view's space and turned back by its inverse rotation */
    int depth_view_z;        /* 1: depth holds the positive view-space distance along -z; 0: window depth */
    gim_mat4 view, proj;
} gim_decode_desc;

/* Twin of the G-buffer decode pass at one pixel: the host's stored normal (its texel's rgba as
   the GPU reads it: unorm in [0, 1], snorm in [-1, 1]) and depth to a unit world normal
   (out_normal, w = 1 where drawn; 0 elsewhere) and window depth (1 where nothing is drawn). */
GIMANY_API gim_result gim_gbuffer_decode_twin(const gim_decode_desc *desc, const float host_normal[4], float host_depth,
                                              float out_normal[4], float *out_depth);

/* Twin of the G-buffer pass at pixel (x, y) of camera's width x height view. */
GIMANY_API gim_result gim_gbuffer_texel_twin(const gim_twin_scene *scene, const gim_camera *camera, uint32_t x,
                                             uint32_t y, gim_gbuffer_texel *out);

/* The pixels of the view samples (Bischoff 2017 sec. 4): Halton points 1..count in bases 2 and 3
   (point 0 is the corner), Cranley-Patterson rotated by offsets (2 values in [0,1), e.g. from
   gim_rotation_offsets(off, 2, frame), or NULL), scaled to the width x height G-buffer:
   pixels[2 i] = min(floor(u_i width), width - 1), pixels[2 i + 1] likewise with v_i, height. */
GIMANY_API gim_result gim_view_sample_pixels(uint32_t count, uint32_t width, uint32_t height, const float *offsets,
                                             uint32_t *pixels);

/* Twin of the view-sample pass: the G-buffer at each of count pixels (x, y pairs) as a
   gim_view_sample into out[count]. depth: width * height window depths in [0, 1] (row-major,
   row 0 at the bottom; width, height the camera's); normal: width * height * 4 (xyz used:
   world normal). The position is unprojected through the inverses of the camera's proj and
   view (in double). Where depth >= 1 (nothing drawn) or the normal is zero or not finite the
   sample is unusable: position and normal are written as zero (the importance pass skips a
   zero normal). */
GIMANY_API gim_result gim_view_samples_twin(const float *depth, const float *normal, const gim_camera *camera,
                                            const uint32_t *pixels, uint32_t count, gim_view_sample *out);

/* twins of the VPL methods: clustered visibility (Dong et al.) and SSVP (Aranha et al.) -------
   Units: a VPL is a point y_i on a surface with normal n_i and flux Phi_i (W, rgb) that emits
   like a small Lambertian patch: intensity Phi_i (n_i . omega)+ / pi. A VPL lights a receiver
   x (normal n_x) with irradiance
     E_i = Phi_i (n_i . omega)+ (n_x . -omega)+ / (pi max(d^2, d_c^2)) V_i,  omega = (x - y_i) / d,
   d = |x - y_i|, d_c the clamping distance (Krivanek's slides: the 1 / d^2 singularity traded
   for bias; the energy it removes is measured by make bench) and V_i the visibility of the
   VPL's cluster (1 without visibility). Near field: a VPL with an area A > 0 (one from an RSM:
   its share of the surface, gim_vpl.area) lights a receiver nearer than GIM__VAL_NEAR sqrt(A) as the
   patch it stands for, a regular octagon of area A around y_i in its plane (as LightSkin's
   VALs, gim__val_near):
     E_i = Phi_i F_i / A V_i,  F_i the point-to-polygon form factor (Lambert's contour formula),
   unclamped (F <= 1 bounds it), faded into the far field between 1.5 and 2 sqrt(A). That is
   the expectation of the point's term over that patch (a VPL jittered inside its share),
   so the near field is the same estimator without its singularity; the clamp alone removed
   most of the light within d_c of a contact edge. A receiver leaves
     L = rho_d / pi sum E_i + rho_g (k + 2) / (2 pi) sum ((r_i . view)+)^k E_i,
   r_i = -omega mirrored at n_x, the same lobe as gim_lightskin_shade_twin. SSVP's eq. 6 divides by
   the total VPL count N; here each VPL's flux already carries its share (first bounce: the
   RSM's total over the VPLs, gim_rsm_vpls_twin; second bounce: 1 / (S pdf), gim_second_bounce_vpls_twin),
   which is the same estimator with each bounce normalised by its own sample count.

   Paraboloid maps (Brabec et al. 2002; Dong sec. 4.2; SSVP sec. 3.C): a hemisphere around a
   cluster's normal n, seen from origin o. With t, b = gim__basis(n), a point p has local
   l = ((p - o) . t, (p - o) . b, (p - o) . n), direction w = l / |l| and, for w.z >= 0, map
   point (u, v) = (w.x, w.y) / (1 + w.z) in the unit disk (the stereographic projection: solid
   angle d omega = 4 du dv / (1 + u^2 + v^2)^2; an angle alpha near w spans alpha / (1 + w.z)).
   Texel (x, y) of a size^2 map has centre u = (2 x + 1) / size - 1, v = (2 y + 1) / size - 1
   and direction w = (2 u, 2 v, 1 - u^2 - v^2) / (1 + u^2 + v^2); texels outside the disk
   (u^2 + v^2 > 1) hold nothing. A point maps to texel x = min(floor((u + 1) size / 2), size - 1),
   likewise y. Maps are stored layer by layer (one per cluster), rows from y = 0. */

/* One VPL: three vec4, the layout of the GPU's VPL buffers (48 bytes). */
typedef struct gim_vpl {
    float position[3];
    float lit;              /* 1: a VPL; 0: it emits nothing (an unlit RSM texel) */
    float normal[3];        /* unit */
    float area;             /* A (L^2): the surface the VPL stands for, its RSM texel's footprint times the
                               texels it stands for (gim_rsm_vpls_twin), which its near field spreads it
                               over; 0: a point (far field and clamp only) */
    float flux[3];          /* Phi, rgb, >= 0 */
    float kept;             /* 1: a first-bounce VPL kept from the last frame (gim_rsm_vpls_desc.previous),
                               its imperfect shadow map with it; 0: drawn this frame */
} gim_vpl;

/* First-bounce VPLs drawn by BRSM's importance (gim_frame_vpl.importance): VAL i of a light's
   selection (gim_vals_gather_twin, weight w = 1 / (N P)) as VPL i, the twin of vals_gather.comp's
   VPL mode: position, lit 1, normal, area w A, flux w Phi (each one float multiply); kept 1
   where previous (the slot's VPLs of the last frame, or NULL: kept 0) holds a lit VPL at the
   same position and normal bit for bit, whose imperfect shadow map then still holds (the
   selection's offsets drift, so most picks stay on their texel from frame to frame); a VAL of
   weight 0 (an invalid texel) an all-zero, unlit VPL. The VPL stands for the 1 / (N P) texels
   the pick stands for, as a slot of gim_rsm_vpls_twin stands for its share. out may not be vals
   or previous. Errors: GIM_ERROR_INVALID_ARGUMENT (NULL with count > 0, out aliasing an input). */
GIMANY_API gim_result gim_vpls_from_vals(const gim_val *vals, uint32_t count, const gim_vpl *previous, gim_vpl *out,
                                         gim_env env);

/* The paraboloid map of one cluster (a virtual area light, VAL): three vec4 (48 bytes). */
typedef struct gim_paraboloid {
    float origin[3];        /* o: the cluster's centre, lifted 1e-4 scene scales along its normal */
    float near_distance;    /* hits nearer than this are the VAL's own surface, not blockers */
    float normal[3];        /* n, unit: the axis of the hemisphere */
    float size;             /* Delta >= 0: the VAL's side, sqrt of its area (penumbra width) */
    float flux[3];          /* the cluster's summed VPL flux, rgb (lights its second bounce) */
    float attribute_near;   /* >= 0: the attribute maps' (second bounce's) own skip: hits nearer than
                               this are the surface under the origin; small (a second-bounce ray
                               must land on the first surface it meets, not behind it) */
} gim_paraboloid;



/* The paraboloid maps of clustered VPLs (Dong sec. 5-6), the twin of the runtime's cluster
   pass. Per cluster m with centre c_m and normal n_m (gim_kmeans' centres and normals, or the
   GPU k-means'): flux = the sum of its VPLs' flux; origin = c_m + 1e-4 scene_scale n_m;
   size Delta = sqrt(A) with A = 12 sqrt(det C), C the flux-weighted 2x2 covariance of its
   VPLs' positions projected on the plane of n_m (weights as gim_kmeans' means, plain when the
   cluster has no flux): the area of the rectangle that a uniform distribution with the same
   second moments fills, invariant under in-plane rotation like Dong's bounding rectangle but
   not set by one outlying VPL; near_distance = max(Delta / 2, 1e-4 scene_scale): geometry
   within the VAL's own extent is what emits it (Dong fig. 7), no blocker of its light;
   attribute_near = min(1e-2 scene_scale, near_distance): the second bounce's rays land on
   the first surface past the origin, however near (a wall beside the cluster, a box on its
   floor), or their flux lands behind it (with Delta / 2, 0.175 of the second bounce's flux on
   the Cornell box, tests/gl/gltest_reference.c); the 1e-2 only passes the surface under the
   origin where it curves away (on the Cornell box the same VPLs as the lift alone). A
   cluster without VPLs gets
   zero flux and size, its centre and normal kept. Sums in double in VPL order.
   out[cluster_count]; input: */
typedef struct gim_cluster_desc {
    const gim_vpl *vpls;
    uint32_t vpl_count;             /* > 0 */
    const uint32_t *cluster;        /* vpl_count: the cluster of each VPL, < cluster_count */
    const float *centres;           /* cluster_count * 3 */
    const float *normals;           /* cluster_count * 3, unit */
    uint32_t cluster_count;         /* > 0 */
    float scene_scale;              /* > 0 */
    gim_env env;
} gim_cluster_desc;

GIMANY_API gim_result gim_cluster_paraboloids_twin(const gim_cluster_desc *desc, gim_paraboloid *out);

/* What the paraboloid pass writes at one texel. */
#define GIM_PARABOLOID_EMPTY 3.0e38f   /* distance where the texel sees nothing */
typedef struct gim_paraboloid_texel {
    /* the visibility map: */
    float distance;         /* from the origin along the texel's direction to the nearest hit
                               beyond near_distance; GIM_PARABOLOID_EMPTY where none */
    int hit;                /* 1 where a surface is beyond near_distance */
    uint32_t triangle;      /* UINT32_MAX: none */
    /* the attribute maps (the second bounce): the nearest hit beyond attribute_near */
    float attribute_distance; /* GIM_PARABOLOID_EMPTY where none */
    float position[3];      /* the hit, world */
    float normal[3];        /* unit, towards the origin (two-sided) */
    float albedo[3];        /* diffuse rgb of the hit triangle */
    int attribute_hit;      /* 1 where a surface is beyond attribute_near */
    uint32_t attribute_triangle; /* UINT32_MAX: none */
} gim_paraboloid_texel;

/* Twin of the paraboloid pass at texel (x, y) of the size^2 map of map (see the convention
   above): the ray from the origin through the texel centre's direction against the scene,
   its nearest hit beyond near_distance (the visibility map) and beyond attribute_near (the
   attribute maps). */
GIMANY_API gim_result gim_paraboloid_texel_twin(const gim_twin_scene *scene, const gim_paraboloid *map, uint32_t size,
                                                uint32_t x, uint32_t y, gim_paraboloid_texel *out);

/* Soft visibility of a cluster's VAL from receiver x (Dong sec. 4: a PCSS-style blocker search
   and filter on its paraboloid map; distance: the map's size^2 distances). *out in [0, 1];
   1 where x lies behind the VAL's plane (w.z <= 0: the map knows nothing there, Dong fig. 7).
   PCSS rather than Dong's CSSM: it needs only the one distance layer per cluster (CSSM keeps
   8-16 prefiltered basis textures per VAL), and its mean |V - exact from-area visibility|
   behind random plates is 0.048 (tests/unit/test_vpl_shade.c). normal: the receiver's unit normal,
   whose plane is the depth a blocker must be in front of (no self-shadowing of planar
   receivers), or NULL: the receiver's distance less a slope bias. See the implementation
   for the kernel and the bias. */
GIMANY_API gim_result gim_paraboloid_visibility_twin(const float *distance, uint32_t size, const gim_paraboloid *map,
                                                gim_vec3 receiver, const gim_vec3 *normal, float *out);

/* Imperfect shadow maps (Ritschel et al. 2008): the scene as points, one small paraboloid
   depth map per cache (the hemisphere around its normal, the convention above) in which a
   subset of the points is splatted, holes filled by pull-push. Each point is splatted as a
   surfel, a disk of the area it stands for in its triangle's plane, written at the depth of
   that plane along each texel's ray: one texel per point (the paper's splat) leaves most
   texels of a sparsely sampled near wall to the points behind it (light through walls), and
   a texel's nearest point lies up to a texel's slope nearer than the surface at its centre
   (false shadow on surfaces seen at grazing angles). The maps
   are looked up per VAL inside the proxy-light sum, so a proxy light carries only the light
   its cache sees. Sizes: map side GIM_ISM_MIN_SIZE..GIM_ISM_MAX_SIZE, a power of two (the
   pull-push pyramid of one map fits a GPU work group's shared memory), 1..GIM_ISM_MAX_POINTS
   points per map. */
#define GIM_ISM_MIN_SIZE 4u
#define GIM_ISM_MAX_SIZE 64u
#define GIM_ISM_MAX_POINTS 65536u
#define GIM_ISM_DEFAULT_SIZE 64u      /* the paper has 32^2; 64^2 halves the Cornell box's error (docs/methods.md) */
#define GIM_ISM_DEFAULT_POINTS 16384u
#define GIM_ISM_DEFAULT_VPL_POINTS 65536u /* the VPL methods' maps, made for the VPLs new in a frame (SSVP's
                                             second bounce: every frame): with the caches' surfels and bias
                                             0.04, inside Sponza's atrium clustered 0.458 -> 0.278 rel. MAE
                                             against 2048 points and the old surfels (first frame 1.9 -> 6.6 s
                                             on llvmpipe; SSVP + ISM on the Cornell box 326 -> 1523 ms a
                                             frame; docs/methods.md, "The VPLs' surfels"); 0.259 since
                                             (GIM_ISM_VPL_SPLAT) */
#define GIM_ISM_BUDGET_BYTES (256u << 20)  /* LightSkin's default side halves until the caches' maps fit */
#define GIM_ISM_MAX_BYTES (1u << 30)      /* the most an explicit side may take (maps of 16 bits a texel) */
#define GIM_ISM_LIFT 1e-4f            /* map origin above its cache, in scene scales */
#define GIM_ISM_BIAS 0.15f            /* depth bias, a fraction of the distance (unit-free; bench_ism) */
#define GIM_ISM_SLOPE 0.25f           /* slope bias: texels of angle per unit of tan(theta_l) */
#define GIM_ISM_MAX_TAN 8.0f          /* tan(theta_l) at most (84 degrees) */
#define GIM_ISM_VPL_BIAS 0.03f        /* the VPL methods' maps: a relative bias b lets a VPL's light through a
                                         wall of thickness t once the VPL is t / b away (0.15: 2 m of ground
                                         lit through the 0.3 walls of tests/gl/gltest_visibility.c; 0.03
                                         there leaves 0.1 % inside). With GIM_ISM_VPL_SPLAT's disks, Sponza's
                                         atrium (clustered + importance) 0.249 / 0.237 / 0.236 rel. MAE at
                                         0.02 / 0.03 / 0.04, its mean 1.01 / 1.04 / 1.06x the reference's;
                                         an open corner loses 0.3-0.6 / 0.2-0.5 % at 0.02 / 0.03
                                         (tests/gl/gltest_physics.c; docs/methods.md, "The slope's fill") */
#define GIM_ISM_VPL_SLOPE 0.05f
#define GIM_VPL_SHADOW_MAP_BIAS 0.01f  /* GIM_VISIBILITY_SHADOW_MAPS' maps (from the triangles, exact at each
                                          texel): 0.04 there leaves 1.4 % of the closed room's pixels above
                                          5 % with importance VPLs (0.87 % at 0.02) */
#define GIM_ISM_SPLAT 1.5f            /* surfel radius over the radius of the area a point stands for */
#define GIM_ISM_VPL_SPLAT 1.2f        /* the VPL methods' maps (65,536 points): smaller disks widen thin things
                                         less; Sponza's atrium 0.282 -> 0.237 rel. MAE (clustered + importance,
                                         with the slope's hole fill; docs/methods.md) */
#define GIM_ISM_MAX_SPLAT 8.0f        /* gim_ism_desc.splat at most */
/* A surfel covers only the texels whose centre ray meets its disk, up to 8 texels out: written
   also to the texel its point lands in (the VPLs' maps until 2026-12-04, below), a surfel widens
   every silhouette by up to a texel (false shadow), and cut at 3 texels the near ones leave holes
   (light through them). Against that set, on the Cornell box BRSM + ISM 0.0429 -> 0.0370
   rel. MAE, the closed room 0.0047 -> 0.0030 inside, Sponza's atrium 0.358 -> 0.352 (one draw)
   (docs/methods.md, "The surfels' reach"). */
#define GIM_ISM_SPLAT_TEXELS 8        /* a surfel covers at most (2 x 8 + 1)^2 texels */
/* The VPL methods' maps take the same surfels, smaller. Until 2026-12-04 they had 2048 points,
   each also written to the texel it lands in and cut at 3 texels (metres-wide surfels in Sponza
   overhang its columns); at 65,536 points disks of 1.5 take Sponza's atrium from 0.508 to 0.282
   rel. MAE (clustered + importance) and the Cornell box from 0.068 to 0.043 (docs/methods.md,
   "The VPLs' surfels"). Disks of 1.2 leave holes in surfaces seen at grazing angles; while
   pull-push filled a hole with its parent alone, a nearer depth, an open corner lost 1.2-1.9 %
   of its light, pixels near the contact edge over 20 %; the slope's fill (gim_ism_render_twin)
   takes that to 0.3-0.6 %, none over 20 % (tests/gl/gltest_physics.c). */

/* count points area-uniform over the scene's triangles, deterministic and low-discrepancy:
   point i takes u = (i + 0.5) / count of the cumulative area (which picks the triangle and a
   fraction r along it) and v = frac(i phi), phi the golden ratio (a radical inverse would put
   every point of a stride-2^k subset in one 2^-k band of v), and lands at the barycentrics
   (1 - sqrt(r), v sqrt(r)) of vertices 1, 2 (area-uniform inside the triangle). Consecutive
   points walk the triangles in order, so any stride through them covers the scene evenly.
   out: count * 8 floats, two vec4 as the GPU buffer: (x, y, z, A / count) with A the scene's
   area, (the triangle's unit face normal, 0). A scene of zero area is
   GIM_ERROR_INVALID_ARGUMENT. */
GIMANY_API gim_result gim_ism_points(const gim_twin_scene *scene, uint32_t count, float *out);

/* Input of gim_ism_render_twin and gim_ism_visibility_twin; zero means default. */
typedef struct gim_ism_desc {
    const gim_cache *caches;        /* one map per cache: origin c + GIM_ISM_LIFT scene_scale n */
    uint32_t cache_count;
    const float *points;            /* point_count * 8 (gim_ism_points) */
    uint32_t point_count;
    uint32_t size;                  /* map side; 0: GIM_ISM_DEFAULT_SIZE */
    uint32_t points_per_map;        /* P; 0: GIM_ISM_DEFAULT_POINTS (at most point_count are taken) */
    float bias;                     /* relative depth bias; 0: GIM_ISM_BIAS */
    float slope;                    /* slope bias; 0: GIM_ISM_SLOPE */
    float splat;                    /* surfel radius over a point's; 0: GIM_ISM_SPLAT (the caches'), the VPL
                                       methods' maps GIM_ISM_VPL_SPLAT; at most GIM_ISM_MAX_SPLAT */
    float scene_scale;              /* > 0 */
    gim_env env;
} gim_ism_desc;

/* The maps, distance_out[cache_count * size^2] (map m row-major at m size^2). Map m splats
   the P points offset + k stride, k < P, stride = point_count / P, offset = frac(m phi) stride
   (phi the golden ratio; a stratified subset of the points, shifted per map: each map sees a
   different subset, all evenly spread), each standing for area a = stride x its .w. A point p
   in front of the map's plane (w.z > 0) at distance dist > GIM_ISM_LIFT scene_scale lands in
   the texel under w.xy / (1 + w.z) (floor, clamped). As a surfel of radius
   rs = splat sqrt(a / pi) in its plane it covers each texel within
   R = min(ceil(rs / dist size / 2), T) of that one whose centre ray meets the plane
   (|ray . normal| >= 1e-3) beyond the lift and within rs of p, at that ray's distance;
   T = GIM_ISM_SPLAT_TEXELS. The nearest wins; texels nothing covered are
   GIM_PARABOLOID_EMPTY before pull-push. Pull: each coarser texel is the farthest of its
   non-empty children (the paper's mean lets a near occluder's depth into the holes around it:
   false shadow); push, from the coarsest level down: an empty texel takes the farther of its
   parent and the bilinear blend (9 3 3 1 / 16) of the four parents nearest its centre (the
   parent alone is a step that puts a nearer depth into the holes of a surface seen at a grazing
   angle: false shadow).
   A map no point reached stays empty (sees nothing: visibility 1). Float arithmetic in the order of
   ism.comp. Stored in 16 bits a texel (the GPU packs two to a uint: Sponza's 24,863 caches at 64^2
   take 204 MB): the upper half of the float's bits, rounded to nearest (gim_ism_quantize: 7
   mantissa bits, relative error at most 2^-8, far below the bias); distance_out holds those values
   as floats, bit for bit what the GPU's maps decode to. An empty texel stays >=
   GIM_PARABOLOID_EMPTY. */
GIMANY_API gim_result gim_ism_render_twin(const gim_ism_desc *desc, float *distance_out);

/* The 16-bit depth of an ISM texel: (bits of d + 0x8000) >> 16 for d >= 0 (ism.comp's
   rounding); gim_ism_dequantize gives it back as a float (the bits shifted up). */
GIMANY_API uint16_t gim_ism_quantize(float d);
GIMANY_API float gim_ism_dequantize(uint16_t q);

/* One shadow map per VPL rendered from the triangles (GIM_VISIBILITY_SHADOW_MAPS: Keller 1997's
   instant radiosity with a real shadow map per VPL, where an ISM has Ritschel et al.'s surfels),
   in the ISMs' layout, so gim_vpl_shade_desc.ism and ism_lookup.glsl take either:
   maps_out[count * size^2], map i of vpls[i], its origin o = position + (GIM_ISM_LIFT
   scene_scale) normal (in float, as gim__ism_frame), its axis the VPL's normal; texel (x, y) is
   gim_paraboloid_texel_twin's distance of that map with near_distance 0 (the nearest triangle
   along the texel centre's ray in front of the map's plane, or GIM_PARABOLOID_EMPTY), stored as
   gim_ism_quantize / gim_ism_dequantize. An unlit VPL's map is every texel empty (the GPU pass
   leaves it unwritten: no pass reads it). size a power of two in GIM_ISM_MIN_SIZE ..
   GIM_ISM_MAX_SIZE, scene_scale > 0. Errors: GIM_ERROR_INVALID_ARGUMENT. */
GIMANY_API gim_result gim_vpl_shadow_maps_twin(const gim_twin_scene *scene, const gim_vpl *vpls, uint32_t count,
                                               uint32_t size, float scene_scale, float *maps_out, gim_env env);

/* Visibility V(c, x_j) of every VAL from every cache through the maps (desc's caches, size,
   bias, slope, scene_scale; points unused): out[cache * val_count + j] in {0, 1}. 1 where x_j
   is behind the map's plane (w.z <= 0); else, with z the distance in its texel and d_ref the
   distance along that texel's centre ray to the VAL's own plane (the VAL's distance dist
   where the ray runs along the plane or meets it outside (0, 2 dist)), 1 where
   d_ref <= z + dist (bias + slope 2 / size min(tan theta_l, GIM_ISM_MAX_TAN)), theta_l the
   angle between the VAL's normal and the direction to the cache. Measured on the same ray as
   the surfels, a VAL on the surface its texel holds compares equal whatever the angle it is
   seen at; the slope term absorbs the surfels' own tilt. (proxy_lights.comp's lookup, in
   float.) The matrix gim_proxy_desc.visibility takes. */
GIMANY_API gim_result gim_ism_visibility_twin(const gim_ism_desc *desc, const float *distance, const gim_val *vals,
                                         uint32_t val_count, float *out);

/* Visibility by rays: a pixel's own line of sight to its neighbour caches. LightSkin
   interpolates each pixel's light from its nearest caches (eq. 8-9); inside a building two
   thirds of them can lie behind a column, an arch or a floor from the pixel, and their light
   is not the pixel's (docs/methods.md, "Where Sponza's error is"). A bounding volume hierarchy
   over the scene's world triangles answers "does this segment cross a triangle", on the CPU
   here and in lightskin_shade.comp (shaders/bvh.glsl, the same steps in float), and each pixel
   drops the neighbours it cannot see (gim_frame_visibility.neighbour_rays). */

/* One node, 32 bytes as the GPU buffer holds it: the box (grown by 5e-4 of its size and a
   millionth of its distance from the origin, past its triangles as the segment test grows
   them), then either an inner node (count 0: the first child is the next
   node, the second is node `index`) or a leaf (count triangles from triangle `index` on). */
typedef struct gim_bvh_node {
    float lo[3];
    uint32_t index;
    float hi[3];
    uint32_t count;
} gim_bvh_node;

/* A hierarchy made by gim_bvh_build (free it with gim_bvh_free). Its boxes and triangles are
   in the frame x' = (x - origin) scale, the bounds' centre and a power of two near the inverse of
   their diagonal, so that the segment test's triple products stay in float's range at any
   scene size (at 1e15 they overflow, at 1e-15 they underflow) and keep their precision far
   from the origin; gim_bvh_occluded takes world points. */
typedef struct gim_bvh {
    gim_bvh_node *nodes;        /* node_count, depth first; node 0 is the root (none: nothing blocks) */
    float *triangles;           /* triangle_count * 12 in the leaves' order: (v0, i), (v1 - v0, 0), (v2 - v0, 0),
                                   i the bits of the triangle's index in the scene (a uint32_t) */
    float origin[3], scale;     /* the frame of nodes and triangles */
    uint32_t node_count, triangle_count;
    uint32_t depth;             /* of the deepest leaf (the root's is 0), < GIM_BVH_MAX_DEPTH */
    gim_env env;                /* what allocated the arrays */
} gim_bvh;

#define GIM_BVH_MAX_DEPTH 48            /* the traversal's stack; the build stays below it */
#define GIM_BVH_MAX_TRIANGLES 16777216u /* 2^24: past 24 levels of SAH splits, halving reaches a leaf within 24 more */
#define GIM_BVH_LEAF 4                  /* triangles per leaf at most */
#define GIM_NEIGHBOUR_RAY_LIFT 1e-3f    /* a pixel-to-cache ray's ends above their surfaces, in scene scales */

/* A bounding volume hierarchy over scene->positions (triangle_count triangles; normals and
   albedo are not read): binned surface-area heuristic splits (16 bins on the longest axis of
   the triangles' centroids) for 24 levels, then halves by count, leaves of at most
   GIM_BVH_LEAF triangles. Unit-free (no length threshold). A vertex that is not finite is
   GIM_ERROR_INVALID_ARGUMENT; more than GIM_BVH_MAX_TRIANGLES, or bounds whose extent is not a
   finite float, GIM_ERROR_OUT_OF_RANGE; degenerate
   triangles are kept (they block nothing); 0 triangles give an empty hierarchy. out is written
   only on GIM_OK and owns arrays allocated through env. */
GIMANY_API gim_result gim_bvh_build(const gim_twin_scene *scene, gim_env env, gim_bvh *out);
/* Free what gim_bvh_build allocated; NULL or zeroed is fine. */
GIMANY_API void gim_bvh_free(gim_bvh *bvh);
/* 1 when a triangle (either side) crosses the open segment from -> to: with d = to - from,
   e1, e2 a triangle's edges from v0, s = from - v0, p = d x e2, q = s x e1 and det = e1 . p
   (Moller and Trumbore 1997 without the division, signs flipped where det < 0) and g = 1e-4
   det, a hit is det != 0, s . p >= -g, d . q >= -g, s . p + d . q <= det + g and 0 < e2 . q <
   det (each triangle grown by 1e-4 of itself, so no segment slips between two that share an
   edge); all in float, in this order, in the hierarchy's frame (the ends taken there first:
   (x - origin) scale). The nodes' boxes are conservative (grown past the grown triangles, the
   slab test with a relative slack of 1e-6): the walk's hits are its triangles' hits, and it
   loses none that lies inside a triangle by more than float's rounding (a segment in or nearly
   in a triangle's plane gets rounding's verdict, which a box may cut: tests/fuzz/fuzz_bvh.c).
   0 for an empty hierarchy or a non-finite end. */
GIMANY_API int gim_bvh_occluded(const gim_bvh *bvh, gim_vec3 from, gim_vec3 to);

/* The nearest crossing of the open segment from -> to, gim_bvh_occluded's test on every
   triangle (either side) the walk meets: hit->slot its triangle in bvh->triangles, hit->triangle
   its index in the scene the hierarchy was built from, hit->t its place along the segment (the
   hit is from + t (to - from), 0 <= t <= 1: e2 . q / det of a crossing, 0 < e2 . q < det,
   rounded). Of two crossings the one with the smaller e2 . q / det
   wins, compared as the products (e2 . q) det' < (e2 . q)' det so that no division decides (a
   tie keeps the first met); a node whose box starts past the nearest so far is skipped. 1 on a
   hit; 0 (hit untouched) for none, an empty hierarchy or a non-finite end. */
typedef struct gim_bvh_hit {
    uint32_t slot, triangle;
    float t;
} gim_bvh_hit;
GIMANY_API int gim_bvh_nearest(const gim_bvh *bvh, gim_vec3 from, gim_vec3 to, gim_bvh_hit *hit);

/* Input of gim_neighbour_rays_twin: the neighbour rows of gim_cache_neighbours and the
   receivers they are for. */
typedef struct gim_neighbour_rays_desc {
    const gim_bvh *bvh;
    const gim_cache *caches;           /* unit normals */
    uint32_t cache_count;
    const gim_receiver *receivers;     /* position and unit normal read */
    uint32_t receiver_count;
    const uint32_t *neighbour_index;   /* receiver_count * neighbour_stride, nearest first; UINT32_MAX pads */
    const uint32_t *neighbour_count;   /* receiver_count, each <= stride */
    uint32_t neighbour_stride;         /* 1..GIM_MAX_NEIGHBOUR_CACHES */
    float scene_scale;                 /* > 0 */
    gim_env env;
} gim_neighbour_rays_desc;

/* The neighbours each receiver sees, the twin of lightskin_shade.comp with neighbour_rays: a
   neighbour cache c (normal n_c) of receiver x (normal n_x) is kept unless
   gim_bvh_occluded(x + l n_x, c + l n_c), l = GIM_NEIGHBOUR_RAY_LIFT scene_scale (each
   component a float multiply-add in that order); the kept ones in their order, d_cmax the
   distance of the farthest kept (as gim_cache_neighbours computes it). A receiver that sees
   none keeps its whole row: an interpolation from caches it cannot see beats none. out's arrays
   may be the desc's own (in place). */
GIMANY_API gim_result gim_neighbour_rays_twin(const gim_neighbour_rays_desc *desc, gim_neighbour_result *out);

/* The caches' side (GIM_VISIBILITY_RAYS), the twin of proxy_lights.comp's rays: out[c *
   val_count + j] = 0 where gim_bvh_occluded(c + l n_c, x_j + l n_j), l = GIM_NEIGHBOUR_RAY_LIFT
   scene_scale (each component a float multiply-add in that order), else 1: the matrix
   gim_proxy_desc.visibility takes. cache_count * val_count rays. */
GIMANY_API gim_result gim_val_rays_twin(const gim_bvh *bvh, const gim_cache *caches, uint32_t cache_count, const gim_val *vals,
                                        uint32_t val_count, float scene_scale, gim_env env, float *out);

/* Input of gim_second_bounce_vpls_twin; zero means default. */
typedef struct gim_second_bounce_desc {
    const gim_paraboloid *maps;     /* map_count clusters (origin, normal, flux used) */
    uint32_t map_count;
    uint32_t size;                  /* side of each map */
    const float *position;          /* map_count * size^2 * 4: hit position, w = 1 where hit */
    const float *normal;            /* map_count * size^2 * 4: unit normal towards the origin */
    const float *albedo;            /* map_count * size^2 * 4: diffuse rgb */
    uint32_t vpl_count;             /* S: map m takes S / map_count VPLs, one more for m < S mod map_count */
    const float *ism;               /* map_count * ism_size^2: each cluster's imperfect shadow map
                                       (gim_ism_render_twin with map m's origin and normal as a cache), or NULL.
                                       A hit the map's own lookup does not see (gim_ism_visibility_twin's, the
                                       hit as the VAL) is an unlit VPL: the maps' hits lie past
                                       attribute_near, so one behind a nearer surface within that skip
                                       (maps made with a larger one) is dropped; the ISM has no skip */
    uint32_t ism_size;              /* 0: GIM_ISM_DEFAULT_SIZE */
    float ism_bias, ism_slope;      /* as gim_ism_desc's; 0: GIM_ISM_BIAS, GIM_ISM_SLOPE */
    float scene_scale;              /* > 0 with ism (the maps' lift) */
    gim_env env;
} gim_second_bounce_desc;

/* Second-bounce VPLs (SSVP sec. 3.C): map m's j-th of S_m VPLs is at the texel under the
   area-preserving unit-disk point gim_square_to_disk of the Hammersley point ((j + 0.5) / S_m,
   radical inverse base 2 of j), the surface its cluster sees in that direction; it carries
     Phi = albedo * Phi_m w.z / (pi S_m pdf),  pdf = (1 + u^2 + v^2)^2 / (4 pi)
   (w and u, v of the texel centre): the cluster as a cosine emitter of its summed flux Phi_m,
   the solid angle 1 / (S_m pdf) of each sample, and the hit's own distance and cosine
   cancelling between the irradiance and the area the sample stands for. A texel with no hit
   gives an unlit VPL. out[vpl_count], in map order. */
GIMANY_API gim_result gim_second_bounce_vpls_twin(const gim_second_bounce_desc *desc, gim_vpl *out);

/* Input of gim_second_bounce_rays_twin. */
typedef struct gim_second_bounce_rays_desc {
    const gim_bvh *bvh;             /* the scene's triangles (gim_bvh_build); empty: every VPL unlit */
    const float *albedo;            /* the scene's triangle_count * 3 diffuse rgb, by the scene's triangle index */
    const gim_vpl *vpls;            /* the first-bounce VPLs */
    uint32_t vpl_count;             /* N, 1..GIM_SECOND_RAYS_MAX_VPLS */
    uint32_t count;                 /* S second-bounce VPLs, 1..65536 */
    float scene_scale;              /* > 0: the rays' lift */
    gim_env env;
} gim_second_bounce_rays_desc;

#define GIM_SECOND_RAYS_MAX_VPLS 32768u   /* first-bounce VPLs: a ray's stratum loop (one ray: all), strata in 32 bits */
#define GIM_SECOND_RAY_LIFT 1e-4f         /* a second-bounce ray's start above its VPL, in scene scales */

/* Second-bounce VPLs by rays (Keller 1997's instant radiosity; GIM_SECOND_BOUNCE_RAYS),
   the twin of second_bounce_rays.comp: each of S rays starts on a first-bounce VPL of its own
   stratum, leaves it cosine-distributed about its normal and lands on the nearest triangle
   (gim_bvh_nearest), where it is a VPL of flux
     Phi = albedo Phi_i W_j / w_i
   (the cosine emitter's Phi_i cos / pi over the cosine pdf: only the pick is left), the
   triangle's unit normal turned towards the ray's start, the area the rays' landing density
   gives it (gim__second_ray_area: a near field, as the first bounce's VPLs have; as points,
   clamped only, the street's SSVP error was 0.239 against 0.217, docs/methods.md); a miss is
   an unlit VPL.
   Ray j's stratum is [j N / S, (j + 1) N / S) of the VPL list (VPL i covering [i, i + 1));
   it picks VPL i with probability w_i o_ij / W_j, w_i = (Phi_r + Phi_g) + Phi_b (0 for an
   unlit or non-finite VPL), o_ij the share of VPL i inside the stratum, W_j = sum_i w_i o_ij;
   since sum_j o_ij = 1 the S VPLs' mean is the first bounce's albedo-weighted flux, unbiased
   for any N and S. The pick: u = radical inverse base 5 of j times W_j against the running sum
   (in float, in VPL order); the direction gim_square_to_disk of (radical inverses base 2 and 3
   of j), lifted to the hemisphere, in gim_basis of the VPL's normal; the ray from the VPL lifted
   GIM_SECOND_RAY_LIFT scene scales along its normal, 4 / bvh->scale long (past the scene).
   Strata keep the picks still: a VPL followed from the last frame (vpl.redraw 0) keeps its
   rays while the fluxes change a little, where one pick over the running sums of all N moved
   every ray to a distant VPL (the street's flicker 0.160 against the maps' 0.018).
   Where light goes after its first bounce decides the second: with a cluster's centre as the
   emitter (gim_second_bounce_vpls_twin) it leaves from points on no surface; here it leaves
   from the VPLs themselves, so the second bounce converges to the real one as S grows.
   out[count]. */
GIMANY_API gim_result gim_second_bounce_rays_twin(const gim_second_bounce_rays_desc *desc, gim_vpl *out);

/* Input of gim_vpl_shade_twin; zero means default. */
typedef struct gim_vpl_shade_desc {
    const gim_vpl *vpls;
    uint32_t vpl_count;
    const uint32_t *cluster;        /* vpl_count: the map of each VPL's cluster, UINT32_MAX for none
                                       (unshadowed); NULL: no visibility at all */
    const gim_paraboloid *maps;
    uint32_t map_count;
    const float *distance;          /* map_count * map_size^2 distances (gim_paraboloid_texel's) */
    uint32_t map_size;
    const gim_receiver *receivers;  /* width * height, row-major, row 0 first; a zero normal: no surface */
    uint32_t width, height;
    uint32_t interleave;            /* k (Dong sec. 6, Segovia et al.): pixel (x, y) takes subset
                                       s = x mod k + k (y mod k): the VPLs scramble(j), j = s, s + k^2,
                                       ... < N (scramble: a fixed bijection of [0, N) that spreads
                                       every subset over the whole list), their sum scaled by
                                       N / n_s (n_s: how many there are); 0 or 1: every VPL */
    float clamp_distance;           /* d_c (lengths), >= 0; 0: no clamping */
    float scene_scale;              /* > 0 */
    const float *ism;               /* vpl_count * ism_size^2: one imperfect shadow map per VPL (Keller's instant
                                       radiosity with Ritschel et al. 2008's maps): map i is gim_ism_render_twin's for
                                       VPL i taken as a cache (its position and normal), and V_i its hard
                                       visibility by gim_ism_visibility_twin's lookup with the receiver as the VAL;
                                       NULL: none. With cluster: maps only for the VPLs from ism_first on that
                                       have no cluster (UINT32_MAX), map i - ism_first: SSVP's second bounce,
                                       whose VPLs no cluster's paraboloid map sees from */
    uint32_t ism_first;             /* with cluster and ism: the first VPL with a map (> 0); else 0 */
    uint32_t ism_size;              /* 0: GIM_ISM_DEFAULT_SIZE */
    float ism_bias, ism_slope;      /* as gim_ism_desc's; 0: GIM_ISM_BIAS, GIM_ISM_SLOPE */
    gim_env env;
} gim_vpl_shade_desc;

/* Indirect radiance of every receiver from the VPLs (units above), rgb into
   radiance_out[width * height * 3]; one independent invocation per pixel, VPLs in index order. */
GIMANY_API gim_result gim_vpl_shade_twin(const gim_vpl_shade_desc *desc, float *radiance_out);

/* Input of gim_geometry_blur_twin; zero means default. */
typedef struct gim_blur_desc {
    const float *radiance;          /* width * height * 3 (gim_vpl_shade_twin's) */
    const gim_receiver *receivers;  /* width * height, as gim_vpl_shade_twin's */
    uint32_t width, height;
    uint32_t window;                /* k: the k x k window [x - k/2, x + k/2 - 1]^2 holds every interleaved
                                       subset once; 0 or 1: a copy */
    float position_tolerance;       /* > 0: neighbours farther than this from the pixel are left out */
    float normal_tolerance;         /* neighbours with n . n_x below this are left out; 0: 0.8 */
    gim_env env;
} gim_blur_desc;

/* Geometry-aware blur (Dong sec. 6 after Laine et al.): each pixel with a surface becomes the
   mean of the pixels with a surface in its window that pass both tolerances (it passes itself)
   and are, like it, diffuse-only or glossy (a glossy colour > 0). The light is averaged, not
   the albedo: a diffuse-only pixel takes, per channel, the mean of radiance / albedo over
   those neighbours with albedo > 0 in that channel, times its own albedo (blurring radiance
   smeared a bright material's light onto a dark neighbour: the Cornell box's ceiling panel
   came out 2.29x too bright); a glossy pixel averages radiance (its lobe is in it). Pixels
   without a surface get 0. out[width * height * 3], not the input. */
GIMANY_API gim_result gim_geometry_blur_twin(const gim_blur_desc *desc, float *out);

#ifdef __cplusplus
}
#endif

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

/* private helpers that a build (GIMANY_NO_GL, say) may leave unused */
#if defined(__GNUC__) || defined(__clang__)
#define GIM__UNUSED __attribute__((unused))
#else
#define GIM__UNUSED
#endif
#ifdef GIMANY_STATIC
#define GIMANY_DEF static GIM__UNUSED /* a host calls some of them, not all */
#else
#define GIMANY_DEF
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
static GIM__UNUSED gim_vec3 gim__v3_add(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static GIM__UNUSED gim_vec3 gim__v3_sub(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static GIM__UNUSED gim_vec3 gim__v3_scale(gim_vec3 a, float s) { return gim_v3(a.x * s, a.y * s, a.z * s); }
static GIM__UNUSED gim_vec3 gim__v3_mul(gim_vec3 a, gim_vec3 b) { return gim_v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static GIM__UNUSED float gim__v3_dot(gim_vec3 a, gim_vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static GIM__UNUSED gim_vec3 gim__v3_cross(gim_vec3 a, gim_vec3 b) {
    return gim_v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static GIM__UNUSED float gim__v3_length(gim_vec3 a) { return sqrtf(gim__v3_dot(a, a)); }
GIMANY_DEF gim_vec3 gim_v3_normalize(gim_vec3 a) {
    /* in double so tiny (1e-30) and huge (1e30) vectors still normalise */
    double l = sqrt((double)a.x * a.x + (double)a.y * a.y + (double)a.z * a.z);
    if (!(l > 0.0) || l > DBL_MAX) return gim_v3(0.0f, 0.0f, 0.0f);
    return gim_v3((float)(a.x / l), (float)(a.y / l), (float)(a.z / l));
}
static GIM__UNUSED float gim__v3_luminance(gim_vec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
static GIM__UNUSED int gim__v3_isfinite(gim_vec3 a) { return gim__isfinitef(a.x) && gim__isfinitef(a.y) && gim__isfinitef(a.z); }
static GIM__UNUSED void gim__basis(gim_vec3 n, gim_vec3 *t, gim_vec3 *b) {
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
static GIM__UNUSED gim_vec4 gim__mat4_vec4(gim_mat4 m, gim_vec4 v) {
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
    r = gim__mat4_vec4(m, v);
    if (r.w != 1.0f && r.w != 0.0f) return gim_v3(r.x / r.w, r.y / r.w, r.z / r.w);
    return gim_v3(r.x, r.y, r.z);
}
static GIM__UNUSED gim_vec3 gim__mat4_dir(gim_mat4 m, gim_vec3 d) {
    return gim_v3(m.m[0] * d.x + m.m[4] * d.y + m.m[8] * d.z,
                  m.m[1] * d.x + m.m[5] * d.y + m.m[9] * d.z,
                  m.m[2] * d.x + m.m[6] * d.y + m.m[10] * d.z);
}
static GIM__UNUSED gim_mat4 gim__mat4_transpose(gim_mat4 m) {
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
static GIM__UNUSED gim_mat4 gim__mat4_normal(gim_mat4 model) {
    gim_mat4 inv, r;
    if (!gim_mat4_invert(model, &inv)) return gim_mat4_identity();
    r = gim__mat4_transpose(inv);
    r.m[3] = r.m[7] = r.m[11] = 0.0f;
    r.m[12] = r.m[13] = r.m[14] = 0.0f;
    r.m[15] = 1.0f;
    return r;
}
GIMANY_DEF gim_mat4 gim_mat4_look_at(gim_vec3 eye, gim_vec3 target, gim_vec3 up) {
    gim_vec3 f = gim_v3_normalize(gim__v3_sub(target, eye));
    gim_vec3 s = gim_v3_normalize(gim__v3_cross(f, up));
    gim_vec3 u = gim__v3_cross(s, f);
    gim_mat4 r = gim_mat4_identity();
    r.m[0] = s.x; r.m[4] = s.y; r.m[8] = s.z;
    r.m[1] = u.x; r.m[5] = u.y; r.m[9] = u.z;
    r.m[2] = -f.x; r.m[6] = -f.y; r.m[10] = -f.z;
    r.m[12] = -gim__v3_dot(s, eye);
    r.m[13] = -gim__v3_dot(u, eye);
    r.m[14] = gim__v3_dot(f, eye);
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
static GIM__UNUSED int gim__mat4_isfinite(gim_mat4 m) { return gim__all_finite(m.m, 16); }

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

GIMANY_DEF void gim_drift_offsets(float *out, uint32_t dims, uint32_t seed, uint32_t frame, double step) {
    float r[16];
    uint32_t d;
    if (!out || dims == 0 || dims > 8u) return;
    gim_rotation_offsets(r, 2u * dims, seed);
    for (d = 0; d < dims; ++d) {
        double g = (double)d * 0.61803398874989484820, o;
        g = d == 0 ? 1.0 : g - floor(g);   /* along (1, 0.618..., ...): the walk never repeats */
        o = (double)r[d] + (double)r[d + dims] * (1.0 / 16777216.0) + (double)frame * step * g;
        o -= floor(o);
        o *= 16777216.0;   /* the high and low 24 bits */
        {
            double hi = floor(o), lo = floor((o - hi) * 16777216.0);
            out[d] = (float)(hi * (1.0 / 16777216.0));
            out[d + dims] = (float)(lo * (1.0 / 16777216.0));
        }
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
    int warm, want_area;
    size_t a;
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

/* Largest axis scale of a model matrix's 3x3 (the length of its longest column): exact for
   rotation, translation and any axis scale, the spacing bound a cache set must meet. */
static double gim__cg_model_scale(const gim_mat4 *m) {
    double best = 0.0;
    int c;
    for (c = 0; c < 3; ++c) {
        double x = m->m[c * 4], y = m->m[c * 4 + 1], z = m->m[c * 4 + 2], l = sqrt(x * x + y * y + z * z);
        if (l > best) best = l;
    }
    return best;
}

GIMANY_DEF gim_result gim_cache_generate_scene(const gim_cache_scene_desc *desc, gim_cache_set *out) {
    const char *fn = "gim_cache_generate_scene";
    const gim_env *env = desc ? &desc->env : NULL;
    double lo[3], hi[3], scale, d_eps;
    gim_cache_set *sets;
    gim_result res = GIM_OK;
    uint32_t i, made = 0;
    int k, any = 0;
    if (!desc || !out || (desc->count && !desc->meshes))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "desc, out and meshes must not be NULL");
    if (!(desc->d_eps >= 0.0f) || !gim__isfinitef(desc->d_eps) || !(desc->scene_scale >= 0.0f) ||
        !gim__isfinitef(desc->scene_scale))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "d_eps and scene_scale must be finite and >= 0 (0 = default)");
    for (k = 0; k < 3; ++k) { lo[k] = DBL_MAX; hi[k] = -DBL_MAX; }
    /* world bounds: each mesh's finite vertices (those its triangles use) through its placement */
    for (i = 0; i < desc->count; ++i) {
        const gim_mesh_data *m = &desc->meshes[i].mesh;
        size_t j;
        double s;
        res = gim__cg_check(&desc->meshes[i]);
        if (res != GIM_OK) return res;
        if (desc->models) {
            s = gim__cg_model_scale(&desc->models[i]);
            if (!gim__mat4_isfinite(desc->models[i]) || !(s > 0.0))
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "models[%u] must be finite with a non-zero scale", (unsigned)i);
        }
        for (j = 0; j < m->index_count; ++j) {
            const float *p = gim__cg_position(m, gim__cg_index(m, j));
            double w[3];
            if (!gim__all_finite(p, 3)) continue;
            if (desc->models) {
                gim_vec3 q = gim_mat4_point(desc->models[i], gim_v3(p[0], p[1], p[2]));
                w[0] = q.x; w[1] = q.y; w[2] = q.z;
            } else {
                w[0] = p[0]; w[1] = p[1]; w[2] = p[2];
            }
            for (k = 0; k < 3; ++k) {
                if (w[k] < lo[k]) lo[k] = w[k];
                if (w[k] > hi[k]) hi[k] = w[k];
            }
            any = 1;
        }
    }
    if (!any) for (k = 0; k < 3; ++k) lo[k] = hi[k] = 0.0;
    scale = desc->scene_scale > 0.0f ? (double)desc->scene_scale
                                     : sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                                            (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(scale > 0.0) || !gim__isfinitef((float)scale)) scale = 1.0; /* one point: nothing has area */
    d_eps = desc->d_eps > 0.0f ? (double)desc->d_eps : scale / 32.0;
    sets = (gim_cache_set *)gim__alloc_array(env, desc->count ? desc->count : 1u, sizeof *sets);
    if (!sets) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "allocation failed");
    for (i = 0; i < desc->count && res == GIM_OK; ++i) {
        gim_cache_desc cd = desc->meshes[i];
        double s = desc->models ? gim__cg_model_scale(&desc->models[i]) : 1.0;
        cd.d_eps = (float)(d_eps / s);
        cd.scene_scale = (float)(scale / s);
        if (!(cd.d_eps > 0.0f) || !gim__isfinitef(cd.d_eps) || !gim__isfinitef(cd.scene_scale)) {
            res = gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "mesh %u: model-space d_eps %g is outside float range",
                            (unsigned)i, d_eps / s);
            break;
        }
        res = gim_cache_generate(&cd, &sets[i]);
        if (res == GIM_OK) made = i + 1u;
    }
    if (res == GIM_OK) {
        for (i = 0; i < desc->count; ++i) out[i] = sets[i];
    } else {
        for (i = 0; i < made; ++i) gim_cache_set_free(&sets[i]);
    }
    gim__free(env, sets);
    return res;
}

GIMANY_DEF void gim_cache_set_free(gim_cache_set *set) {
    if (!set) return;
    gim__free(&set->env, set->caches);
    memset(set, 0, sizeof *set);
}

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
            if (!gim__v3_isfinite(p[0]) || !gim__v3_isfinite(p[1]) || !gim__v3_isfinite(p[2])) continue;
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
    double theta, cos_theta, radius2;
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
    if (!(desc->max_distance >= 0.0f) || !gim__isfinitef(desc->max_distance))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "max_distance %g must be finite and >= 0",
                         (double)desc->max_distance);
    /* the radius as a squared distance: a float squared is exact in double, so d2 <= r2 is
       exactly |p - c| <= max_distance for the d2 the order uses */
    radius2 = desc->max_distance > 0.0f ? (double)desc->max_distance * (double)desc->max_distance : HUGE_VAL;
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
        if (gim__v3_isfinite(p)) {
            /* max_distance starts the pruning bound: a node or cache beyond it is never
               visited, and the n best inside it are the unlimited row's first entries */
            double bound = radius2;
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
                if (k < n || bound > radius2) bound = radius2;
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

GIMANY_DEF gim_result gim_cache_blob_read(const void *blob, size_t size, gim_cache_set *out, gim_env env) {
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
            gim_cache_set_free(&set);
            return gim__fail(&env, GIM_ERROR_CORRUPT_DATA, where, "cache %u: %s", i, why);
        }
    }
    *out = set;
    return GIM_OK;
}

/* @impl importance ======================================================================== */

#define GIM__IMPORTANCE_DEFAULT_CLAMP (1.0f / 64.0f)

/* The sum of eq. 10 over the view samples for a point p (in scene scales) with unit normal n;
   vs holds 6 doubles per view sample: position / scene_scale and a unit normal (zero for a
   sample that sees nothing). */
static double gim__importance_geometry(double px, double py, double pz, double nx, double ny, double nz,
                                       const double *vs, uint32_t vs_count, double clamp2) {
    double sum = 0.0;
    uint32_t j;
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
    return sum;
}

/* A texel's luminance where gim_importance_map counts it (finite position, normal and flux, a
   non-zero normal, luminance > 0; clamped at FLT_MAX), else 0; its unit normal into n. */
static double gim__importance_phi(const float *p, const float *nrm, const float *flux, double n[3]) {
    double len, phi;
    if (!gim__all_finite(p, 3) || !gim__all_finite(nrm, 3) || !gim__all_finite(flux, 3)) return 0.0;
    phi = gim__v3_luminance(gim_v3(flux[0], flux[1], flux[2]));
    if (!(phi > 0.0)) return 0.0;                  /* black, or negative (non-physical) flux */
    if (phi > FLT_MAX) phi = FLT_MAX;              /* the float luminance of huge rgb overflowed */
    len = sqrt((double)nrm[0] * nrm[0] + (double)nrm[1] * nrm[1] + (double)nrm[2] * nrm[2]);
    if (!(len > 0.0)) return 0.0;
    n[0] = nrm[0] / len; n[1] = nrm[1] / len; n[2] = nrm[2] / len;
    return phi;
}

/* eq. 10-11 for one texel (vs as gim__importance_geometry's). Per texel independent: a GPU thread. */
static float gim__importance_texel(const float *p, const float *nrm, const float *flux,
                                   const double *vs, uint32_t vs_count, double inv_scale, double clamp2) {
    double n[3], phi = gim__importance_phi(p, nrm, flux, n), r;
    if (!(phi > 0.0)) return 0.0f;
    r = phi * gim__importance_geometry(p[0] * inv_scale, p[1] * inv_scale, p[2] * inv_scale, n[0], n[1], n[2], vs,
                                       vs_count, clamp2) / (double)vs_count;
    return r < FLT_MAX ? (float)r : FLT_MAX;
}

/* The checks of gim_importance_map and gim_importance_tile_map, and the view samples as
   gim__importance_geometry reads them into *vs_out (free with gim__free). */
static gim_result gim__importance_prepare(const gim_importance_desc *desc, const char *fn, double **vs_out,
                                          double *inv_scale_out, double *clamp_out) {
    const gim_env *env = &desc->env;
    size_t texels;
    uint32_t j, unusable = 0;
    double *vs, inv_scale, clamp;
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
        if (!gim__v3_isfinite(s.position) || !gim__v3_isfinite(s.normal) || !(len > 0.0) || len > DBL_MAX) {
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
    *vs_out = vs;
    *inv_scale_out = inv_scale;
    *clamp_out = clamp;
    return GIM_OK;
}

GIMANY_DEF gim_result gim_importance_map(const gim_importance_desc *desc, float *out) {
    static const char fn[] = "gim_importance_map";
    size_t texels, i;
    double *vs = NULL, inv_scale = 0.0, clamp = 0.0;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT; /* no env to log through */
    if (!out) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "out is NULL");
    r = gim__importance_prepare(desc, fn, &vs, &inv_scale, &clamp);
    if (r != GIM_OK) return r;
    texels = (size_t)desc->width * desc->height;
    for (i = 0; i < texels; ++i) {
        if (desc->rsm_valid && !(desc->rsm_valid[i] > 0.0f)) { out[i] = 0.0f; continue; }
        out[i] = gim__importance_texel(desc->rsm_position + i * 3u, desc->rsm_normal + i * 3u,
                                       desc->rsm_flux + i * 3u, vs, desc->view_sample_count,
                                       inv_scale, clamp * clamp);
    }
    gim__free(&desc->env, vs);
    return GIM_OK;
}

/* The two-level map's planes per tile (see gim_importance_tile_map): at most GIM__TILE_PLANES,
   a texel on a seed's plane when its normal is within acos(0.9) = 26 degrees of the seed's and
   it lies within GIM__TILE_PLANE_DISTANCE scene scales of the seed's plane. */
#define GIM__TILE_PLANES 4
#define GIM__TILE_PLANE_COS 0.9
#define GIM__TILE_PLANE_DISTANCE 0.01

/* Texel (unit normal n, position p) on the plane of seed (ns, ps); plane: the distance in world units. */
static int gim__tile_on_plane(const double *n, const float *p, const double *ns, const float *ps, double plane) {
    double dx = (double)p[0] - ps[0], dy = (double)p[1] - ps[1], dz = (double)p[2] - ps[2];
    return n[0] * ns[0] + n[1] * ns[1] + n[2] * ns[2] >= GIM__TILE_PLANE_COS &&
           fabs(ns[0] * dx + ns[1] * dy + ns[2] * dz) <= plane;
}

GIMANY_DEF gim_result gim_importance_tile_map(const gim_importance_desc *desc, uint32_t tile, float *tile_map,
                                              float *weight) {
    static const char fn[] = "gim_importance_tile_map";
    uint32_t tx, ty, tiles_x, tiles_y, w, h, k, i, count;
    double *vs = NULL, inv_scale = 0.0, clamp = 0.0, plane, *tn, *tphi;
    uint32_t *tidx;
    int *cls;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT; /* no env to log through */
    if (!tile_map || !weight) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "tile_map and weight are required");
    if (tile == 0 || tile > GIM_MAX_IMPORTANCE_TILE)
        return gim__fail(&desc->env, GIM_ERROR_OUT_OF_RANGE, fn, "tile %u outside 1..%d", (unsigned)tile,
                         GIM_MAX_IMPORTANCE_TILE);
    r = gim__importance_prepare(desc, fn, &vs, &inv_scale, &clamp);
    if (r != GIM_OK) return r;
    /* one tile's VALs: index, luminance, unit normal, plane */
    tn = (double *)gim__alloc_array(&desc->env, (size_t)tile * tile, 4u * sizeof(double));
    tidx = (uint32_t *)gim__alloc_array(&desc->env, (size_t)tile * tile, sizeof(uint32_t) + sizeof(int));
    if (!tn || !tidx) {
        gim__free(&desc->env, tn);
        gim__free(&desc->env, tidx);
        gim__free(&desc->env, vs);
        return gim__fail(&desc->env, GIM_ERROR_OUT_OF_MEMORY, fn, "tile %u", (unsigned)tile);
    }
    tphi = tn + (size_t)tile * tile * 3u;
    cls = (int *)(void *)(tidx + (size_t)tile * tile);
    plane = GIM__TILE_PLANE_DISTANCE * (double)desc->scene_scale;
    w = desc->width; h = desc->height;
    tiles_x = (w - 1u) / tile + 1u;
    tiles_y = (h - 1u) / tile + 1u;
    /* one independent invocation per tile (a GPU thread): its VALs split into planes, eq. 10 once
       per plane at the plane's aggregate, each texel's weight its luminance times its plane's term */
    for (ty = 0; ty < tiles_y; ++ty)
        for (tx = 0; tx < tiles_x; ++tx) {
            uint32_t x1 = tx * tile + tile < w ? tx * tile + tile : w, y1 = ty * tile + tile < h ? ty * tile + tile : h, x, y;
            uint32_t seed[GIM__TILE_PLANES];
            double phi_c[GIM__TILE_PLANES], p_c[GIM__TILE_PLANES][3], n_c[GIM__TILE_PLANES][3], g_c[GIM__TILE_PLANES];
            double sum = 0.0;
            uint32_t seeds = 0;
            count = 0;
            for (y = ty * tile; y < y1; ++y)   /* the tile's VALs in raster order */
                for (x = tx * tile; x < x1; ++x) {
                    size_t t = (size_t)y * w + x;
                    double phi = 0.0;
                    weight[t] = 0.0f;
                    if (!desc->rsm_valid || desc->rsm_valid[t] > 0.0f)
                        phi = gim__importance_phi(desc->rsm_position + t * 3u, desc->rsm_normal + t * 3u,
                                                  desc->rsm_flux + t * 3u, tn + (size_t)count * 3u);
                    if (!(phi > 0.0)) continue;
                    tidx[count] = (uint32_t)t;
                    tphi[count] = (float)phi;   /* the luminance as the GPU holds it */
                    ++count;
                }
            /* planes: seed k is the first VAL on none of the planes 0..k-1; a VAL belongs to the first
               plane it lies on, the last plane takes the VALs on none */
            for (i = 0; i < count; ++i) {
                int c = -1;
                for (k = 0; k < seeds && c < 0; ++k)
                    if (k + 1u == GIM__TILE_PLANES ||
                        gim__tile_on_plane(tn + (size_t)i * 3u, desc->rsm_position + (size_t)tidx[i] * 3u,
                                           tn + (size_t)seed[k] * 3u, desc->rsm_position + (size_t)tidx[seed[k]] * 3u, plane))
                        c = (int)k;
                if (c < 0) { seed[seeds] = i; c = (int)seeds++; }
                cls[i] = c;
            }
            for (k = 0; k < seeds; ++k) {
                phi_c[k] = 0.0;
                p_c[k][0] = p_c[k][1] = p_c[k][2] = n_c[k][0] = n_c[k][1] = n_c[k][2] = 0.0;
            }
            for (i = 0; i < count; ++i) {   /* each plane's flux-weighted mean position and normal */
                const float *p = desc->rsm_position + (size_t)tidx[i] * 3u;
                double phi = tphi[i];
                int c = cls[i];
                phi_c[c] += phi;
                p_c[c][0] += phi * p[0]; p_c[c][1] += phi * p[1]; p_c[c][2] += phi * p[2];
                n_c[c][0] += phi * tn[i * 3u]; n_c[c][1] += phi * tn[i * 3u + 1u]; n_c[c][2] += phi * tn[i * 3u + 2u];
            }
            for (k = 0; k < seeds; ++k) {
                double len = sqrt(n_c[k][0] * n_c[k][0] + n_c[k][1] * n_c[k][1] + n_c[k][2] * n_c[k][2]);
                g_c[k] = 0.0;
                if (!(phi_c[k] > 0.0) || !(len > 0.0) || phi_c[k] > DBL_MAX || len > DBL_MAX) continue;
                g_c[k] = gim__importance_geometry(p_c[k][0] / phi_c[k] * inv_scale, p_c[k][1] / phi_c[k] * inv_scale,
                                                  p_c[k][2] / phi_c[k] * inv_scale, n_c[k][0] / len, n_c[k][1] / len,
                                                  n_c[k][2] / len, vs, desc->view_sample_count, clamp * clamp) /
                         (double)desc->view_sample_count;
            }
            for (i = 0; i < count; ++i) {   /* weights, and the tile's importance: their sum */
                double v = tphi[i] * g_c[cls[i]];
                float f = v < FLT_MAX ? (float)v : FLT_MAX;
                weight[tidx[i]] = f;
                sum += (double)f;
            }
            tile_map[(size_t)ty * tiles_x + tx] = sum < FLT_MAX ? (float)sum : FLT_MAX;
        }
    gim__free(&desc->env, tn);
    gim__free(&desc->env, tidx);
    gim__free(&desc->env, vs);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_importance_luminance(const gim_importance_desc *desc, uint32_t tile, float *tile_map,
                                               float *weight) {
    static const char fn[] = "gim_importance_luminance";
    uint32_t tx, ty, tiles_x, tiles_y, w, h, x, y;
    size_t texels;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT; /* no env to log through */
    if (!tile_map || (tile > 1u && !weight))
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "tile_map (and weight with tile > 1) are required");
    if (tile == 0 || tile > GIM_MAX_IMPORTANCE_TILE)
        return gim__fail(&desc->env, GIM_ERROR_OUT_OF_RANGE, fn, "tile %u outside 1..%d", (unsigned)tile,
                         GIM_MAX_IMPORTANCE_TILE);
    if (!desc->rsm_position || !desc->rsm_normal || !desc->rsm_flux)
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm_position, rsm_normal and rsm_flux are required");
    w = desc->width; h = desc->height;
    texels = gim__array_size(w, h);
    if (w == 0 || h == 0 || texels == 0 || gim__array_size(texels, 3u * sizeof(float)) == 0)
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "RSM size %ux%u is empty or overflows size_t",
                         (unsigned)w, (unsigned)h);
    tiles_x = (w - 1u) / tile + 1u;
    tiles_y = (h - 1u) / tile + 1u;
    for (ty = 0; ty < tiles_y; ++ty)   /* one invocation per tile, as gim_importance_tile_map */
        for (tx = 0; tx < tiles_x; ++tx) {
            uint32_t x1 = tx * tile + tile < w ? tx * tile + tile : w, y1 = ty * tile + tile < h ? ty * tile + tile : h;
            double sum = 0.0;
            for (y = ty * tile; y < y1; ++y)
                for (x = tx * tile; x < x1; ++x) {
                    size_t i = (size_t)y * w + x;
                    double n[3], phi = desc->rsm_valid && !(desc->rsm_valid[i] > 0.0f)
                                           ? 0.0
                                           : gim__importance_phi(desc->rsm_position + i * 3u, desc->rsm_normal + i * 3u,
                                                                 desc->rsm_flux + i * 3u, n);
                    float f = (float)phi;   /* gim__importance_phi clamps at FLT_MAX */
                    if (weight) weight[i] = f;
                    sum += (double)f;
                }
            tile_map[(size_t)ty * tiles_x + tx] = sum < FLT_MAX ? (float)sum : FLT_MAX;
        }
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

/* One set of eq. 12 tables (the importance's or the luminance's) as the selection reads them. */
typedef struct gim__select_tables {
    const double *column, *row, *totals;  /* totals: the last row of column */
    const float *weight;                  /* tile > 1 */
    uint32_t width, height, tile, rsm_width, rsm_height;  /* rsm_*: the texels (tile 1: width, height) */
    double total;
} gim__select_tables;

/* The O(width) check of what every search relies on; the interior of the columns is checked
   per sample (a NaN there shows as a non-positive difference). */
static gim_result gim__select_tables_check(const gim_env *env, const char *fn, const gim__select_tables *t,
                                           const char *which) {
    double prev = 0.0;
    uint32_t x;
    for (x = 0; x < t->width; ++x) {
        if (!(t->row[x] >= prev && t->row[x] <= DBL_MAX) || !(t->totals[x] >= 0.0 && t->totals[x] <= DBL_MAX) ||
            (t->row[x] > prev && !(t->totals[x] > 0.0)))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "%s tables are not cumulative sums at column %u (row %g, column total %g)", which,
                             (unsigned)x, t->row[x], t->totals[x]);
        prev = t->row[x];
    }
    return GIM_OK;
}

/* The sum of tile (tx, ty)'s weights in row-major order (the GPU's order). */
static double gim__select_tile_sum(const gim__select_tables *t, uint32_t tx, uint32_t ty) {
    uint32_t x0 = tx * t->tile, y0 = ty * t->tile, xx, yy;
    uint32_t x1 = x0 + t->tile < t->rsm_width ? x0 + t->tile : t->rsm_width;
    uint32_t y1 = y0 + t->tile < t->rsm_height ? y0 + t->tile : t->rsm_height;
    double sum = 0.0;
    for (yy = y0; yy < y1; ++yy)
        for (xx = x0; xx < x1; ++xx) sum += (double)t->weight[(size_t)yy * t->rsm_width + xx];
    return sum;
}

/* The probability the tables give texel (x, y) (an RSM texel when tile > 1); 0 where they
   cannot pick it. */
static double gim__select_pdf_at(const gim__select_tables *t, uint32_t x, uint32_t y) {
    uint32_t tx = x / t->tile, ty = y / t->tile;
    double ct = t->totals[tx], p, hi, lo;
    if (!(t->total > 0.0) || !(ct > 0.0)) return 0.0;
    hi = t->column[(size_t)ty * t->width + tx];
    lo = ty ? t->column[(size_t)(ty - 1u) * t->width + tx] : 0.0;
    p = (t->row[tx] - (tx ? t->row[tx - 1u] : 0.0)) / t->total * ((hi - lo) / ct);
    if (t->tile > 1u && p > 0.0) {
        double sum = gim__select_tile_sum(t, tx, ty);
        p = sum > 0.0 ? p * ((double)t->weight[(size_t)y * t->rsm_width + x] / sum) : 0.0;
    }
    return p;
}

/* One pick from the tables at (u, v) in [0, 1)^2 (total > 0): the texel and its probability. */
static gim_result gim__select_pick(const gim_env *env, const char *fn, const gim__select_tables *t, double u, double v,
                                   uint32_t *ox, uint32_t *oy, double *op) {
    double col_total, p_col, p_row, p, tt, lo, hi;
    uint32_t sx, sy, width = t->width, height = t->height;
    sx = gim__first_above(t->row, 1u, width, gim__below(u * t->total, t->total));
    col_total = t->totals[sx];
    tt = gim__below(v * col_total, col_total);
    sy = gim__first_above(t->column + sx, width, height, tt);
    lo = sy ? t->column[(size_t)(sy - 1u) * width + sx] : 0.0;
    hi = t->column[(size_t)sy * width + sx];
    p_col = (t->row[sx] - (sx ? t->row[sx - 1u] : 0.0)) / t->total;
    p_row = (hi - lo) / col_total;
    p = p_col * p_row;
    if (!(p > 0.0 && p <= 1.0))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                         "column %u of the tables is not a cumulative sum (texel %u has P = %g)", (unsigned)sx,
                         (unsigned)sy, p);
    if (t->tile > 1u) {
        /* second level: the residual of v in the tile's interval picks the texel by weight */
        double res = (tt - lo) / (hi - lo), sum, acc = 0.0, w = 0.0;
        uint32_t x0 = sx * t->tile, y0 = sy * t->tile, xx, yy, px = 0, py = 0;
        uint32_t x1 = x0 + t->tile < t->rsm_width ? x0 + t->tile : t->rsm_width;
        uint32_t y1 = y0 + t->tile < t->rsm_height ? y0 + t->tile : t->rsm_height;
        int found = 0;
        res = res < 1.0 ? (res > 0.0 ? res : 0.0) : 0.0;   /* NaN-safe; [0, 1) */
        sum = gim__select_tile_sum(t, sx, sy);
        if (!(sum > 0.0 && sum <= DBL_MAX))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "tile (%u, %u) was picked but its weights sum to %g (not the tile map's weights)",
                             (unsigned)sx, (unsigned)sy, sum);
        /* the first texel whose running sum exceeds res * sum; rounding past the end: the last
           texel of positive weight (so a picked texel always has weight > 0) */
        for (yy = y0; yy < y1 && !found; ++yy)
            for (xx = x0; xx < x1 && !found; ++xx) {
                double wt = (double)t->weight[(size_t)yy * t->rsm_width + xx];
                acc += wt;
                if (wt > 0.0) { px = xx; py = yy; w = wt; }
                found = acc > res * sum;
            }
        if (!found) {   /* res * sum rounded to the tile's sum or past it: the last positive one */
            for (yy = y0; yy < y1; ++yy)
                for (xx = x0; xx < x1; ++xx) {
                    double wt = (double)t->weight[(size_t)yy * t->rsm_width + xx];
                    if (wt > 0.0) { px = xx; py = yy; w = wt; }
                }
        }
        p *= w / sum;
        if (!(p > 0.0 && p <= 1.0))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "texel (%u, %u) has P = %g: weights not finite and >= 0",
                             (unsigned)px, (unsigned)py, p);
        sx = px;
        sy = py;
    }
    *ox = sx;
    *oy = sy;
    *op = p;
    return GIM_OK;
}

GIMANY_DEF gim_result gim_importance_select(const gim_select_desc *desc, gim_selected_val *out) {
    static const char fn[] = "gim_importance_select";
    const gim_env *env;
    gim__select_tables t[2];
    float seeded[4];
    const float *off;
    double o0, o1;
    uint32_t i, tile, count, n1, n2, rsm_height;
    gim_result r;
    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc is NULL");
    env = &desc->env;
    count = desc->count;
    if (!desc->column || !desc->row || !out)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "column, row and out are required");
    off = desc->offsets;
    if (!off) {
        gim_rotation_offsets(seeded, 4u, desc->seed);
        off = seeded;
    }
    if (count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "count is 0");
    r = gim__importance_tables_check(env, fn, desc->width, desc->height);
    if (r != GIM_OK) return r;
    tile = desc->tile > 1u ? desc->tile : 1u;
    if (tile > 1u) {
        if (tile > GIM_MAX_IMPORTANCE_TILE)
            return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "tile %u above %d", (unsigned)tile, GIM_MAX_IMPORTANCE_TILE);
        if (!desc->weight) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "tile %u needs weight", (unsigned)tile);
        if (desc->rsm_width == 0 || desc->rsm_height == 0 || (desc->rsm_width - 1u) / tile + 1u != desc->width ||
            (desc->rsm_height - 1u) / tile + 1u != desc->height)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "a %ux%u RSM in tiles of %u is not %ux%u tiles",
                             (unsigned)desc->rsm_width, (unsigned)desc->rsm_height, (unsigned)tile,
                             (unsigned)desc->width, (unsigned)desc->height);
    }
    n2 = desc->defensive_count;
    if (n2 >= count)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "defensive_count %u is not below count %u", (unsigned)n2,
                         (unsigned)count);
    if (n2 && (!desc->lum_column || !desc->lum_row || (tile > 1u && !desc->lum_weight)))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "defensive_count %u needs the luminance tables%s",
                         (unsigned)n2, tile > 1u ? " and lum_weight" : "");
    rsm_height = tile > 1u ? desc->rsm_height : desc->height;
    for (i = 0; i < (n2 ? 2u : 1u); ++i) {
        t[i].column = i ? desc->lum_column : desc->column;
        t[i].row = i ? desc->lum_row : desc->row;
        t[i].weight = i ? desc->lum_weight : desc->weight;
        t[i].width = desc->width;
        t[i].height = desc->height;
        t[i].tile = tile;
        t[i].rsm_width = tile > 1u ? desc->rsm_width : desc->width;
        t[i].rsm_height = rsm_height;
        t[i].totals = t[i].column + (size_t)(desc->height - 1u) * desc->width;
        r = gim__select_tables_check(env, fn, &t[i], i ? "the luminance" : "the importance");
        if (r != GIM_OK) return r;
        t[i].total = t[i].row[desc->width - 1u];
    }
    if (n2 && !(t[1].total > 0.0)) n2 = 0;   /* no luminance (tables that cannot be the map's): no share */
    n1 = count - n2;
    /* 48-bit Cranley-Patterson offsets, two 24-bit ones per dimension: over all seeds u_i
       only takes values on the offsets' lattice, so with 24 bits a column holding less than
       2^-24 of the total would be picked with the wrong frequency (never, or far too often) */
    o0 = (double)off[0] + (double)off[2] * (1.0 / 16777216.0);
    o1 = (double)off[1] + (double)off[3] * (1.0 / 16777216.0);
    if (!(t[0].total > 0.0))
        gim__log(env, GIM_LOG_WARNING, fn, "the importance map is all zero: %u texels selected uniformly",
                 (unsigned)count);
    for (i = 0; i < count; ++i) {
        uint32_t l = i < n1 ? 0u : 1u, k = l ? i - n1 : i, n = l ? n2 : n1, sx = 0, sy = 0;
        double u = (double)k / (double)n + o0, v = gim_van_der_corput(k) + o1, p = 0.0;
        u = u < 1.0 ? u : u - 1.0;
        v = v < 1.0 ? v : v - 1.0;
        if (!(t[0].total > 0.0)) { /* documented fallback: every pick uniform, pdf 1 / texels */
            uint32_t tw = tile > 1u ? desc->rsm_width : desc->width, th = rsm_height;
            sx = (uint32_t)(u * tw); sy = (uint32_t)(v * th);
            out[i].x = sx < tw ? sx : tw - 1u;
            out[i].y = sy < th ? sy : th - 1u;
            out[i].pdf = (float)(1.0 / ((double)tw * (double)th));
            continue;
        }
        r = gim__select_pick(env, fn, &t[l], u, v, &sx, &sy, &p);
        if (r != GIM_OK) return r;
        if (n2) {   /* the mixture's pdf: the other set's probability of the same texel */
            double q = gim__select_pdf_at(&t[1u - l], sx, sy);
            p = l ? ((double)n1 * q + (double)n2 * p) / (double)count : ((double)n1 * p + (double)n2 * q) / (double)count;
        }
        out[i].x = sx;
        out[i].y = sy;
        out[i].pdf = p > FLT_MIN ? (float)p : FLT_MIN;
    }
    return GIM_OK;
}

/* @impl twins ============================================================================= */
#define GIM__PI 3.14159265358979323846
#define GIM__TWINS_MAX_EXPONENT 1e6f
/* a VAL or cache nearer than this (in scene scales) has no direction from the cache */
#define GIM__TWINS_COINCIDENT 1e-6f

/* |v|^2 of a unit vector within 1e-3 of 1 (or exactly 0 where allowed) */
static int gim__unit_or_zero(const float *n, int zero_ok) {
    float l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (zero_ok && l2 == 0.0f) return 1;
    return l2 > 0.999f && l2 < 1.001f;
}
/* Phong lobe value ((r . v)+)^k; k = 0 is the constant lobe (pow(0, 0) = 1). r . v is held to
   1: a VAL's near field blends its cos_x and direction apart, so r = 2 cos_x n - d is not quite
   unit there, and 1.0001^1e6 is no float (a fuzzed glossy proxy's sums became inf, its
   position NaN). */
static float gim__lobe(float cos_e, float k) {
    if (k == 0.0f) return 1.0f;
    return cos_e > 0.0f ? powf(cos_e < 1.0f ? cos_e : 1.0f, k) : 0.0f;
}
static float gim__clamp_flt(double x) { return x < (double)FLT_MAX ? (float)x : FLT_MAX; }

GIMANY_DEF gim_result gim_vals_gather_twin(const gim_rsm_data *rsm, const gim_selected_val *selected,
                                      uint32_t selected_count, gim_val *out, gim_env env) {
    static const char fn[] = "gim_vals_gather_twin";
    size_t n, i;
    if (!rsm) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm is NULL");
    if (!out) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "out is NULL");
    if (!rsm->position || !rsm->normal || !rsm->flux || !rsm->area)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm position, normal, flux and area are required");
    if (rsm->width == 0 || rsm->height == 0) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "empty RSM");
    if (selected && selected_count == 0) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "selected_count is 0");
    n = selected ? (size_t)selected_count : (size_t)rsm->width * rsm->height;
    for (i = 0; i < n; ++i) {
        size_t t = i;
        float w = 1.0f;
        gim_val *v = out + i;
        if (selected) {
            const gim_selected_val *s = selected + i;
            double wd;
            if (s->x >= rsm->width || s->y >= rsm->height)
                return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "selected[%zu] = (%u, %u) is outside the %ux%u RSM",
                                 i, s->x, s->y, rsm->width, rsm->height);
            if (!(s->pdf > 0.0f) || !gim__isfinitef(s->pdf))
                return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "selected[%zu].pdf is not finite and > 0", i);
            t = (size_t)s->y * rsm->width + s->x;
            wd = 1.0 / ((double)selected_count * (double)s->pdf);   /* eq. 13-15: 1 / (N P) */
            w = gim__clamp_flt(wd);
        }
        memcpy(v->position, rsm->position + t * 3, sizeof v->position);
        memcpy(v->normal, rsm->normal + t * 3, sizeof v->normal);
        memcpy(v->flux, rsm->flux + t * 3, sizeof v->flux);
        v->area = rsm->area[t];
        v->weight = w;
        v->unused = 0.0f;
        if ((rsm->valid && !(rsm->valid[t] > 0.0f)) || !gim__all_finite(v->position, 3) ||
            !gim__all_finite(v->normal, 3) || !gim__all_finite(v->flux, 3) || !gim__isfinitef(v->area) ||
            !(v->area >= 0.0f) || !(v->flux[0] >= 0.0f && v->flux[1] >= 0.0f && v->flux[2] >= 0.0f)) {
            memset(v, 0, sizeof *v);   /* lights nothing, passes gim_proxy_lights_twin' checks */
        }
    }
    return GIM_OK;
}

/* Diagonal of the bounds of the caches and VALs (the default scene scale); 1 when all coincide. */
static float gim__twins_scale(const gim_cache *caches, uint32_t cache_count, const gim_val *vals, uint32_t val_count) {
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, d2 = 0.0;
    uint32_t i;
    int a;
    for (i = 0; i < cache_count; ++i)
        for (a = 0; a < 3; ++a) {
            double p = caches[i].position[a];
            lo[a] = p < lo[a] ? p : lo[a]; hi[a] = p > hi[a] ? p : hi[a];
        }
    for (i = 0; i < val_count; ++i)
        if (vals[i].weight > 0.0f)
            for (a = 0; a < 3; ++a) {
                double p = vals[i].position[a];
                lo[a] = p < lo[a] ? p : lo[a]; hi[a] = p > hi[a] ? p : hi[a];
            }
    for (a = 0; a < 3; ++a) if (hi[a] >= lo[a]) d2 += (hi[a] - lo[a]) * (hi[a] - lo[a]);
    return d2 > 0.0 ? gim__clamp_flt(sqrt(d2)) : 1.0f;
}

static gim_result gim__check_caches(const gim_env *env, const char *fn, const gim_cache *caches, uint32_t count) {
    uint32_t i;
    for (i = 0; i < count; ++i) {
        const gim_cache *c = caches + i;
        if (!gim__all_finite(c->position, 3) || !gim__all_finite(c->normal, 3) || !gim__isfinitef(c->area) ||
            !(c->area >= 0.0f) || !gim__unit_or_zero(c->normal, 0))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "cache %u: position, normal and area must be finite, the normal unit, the area >= 0", i);
    }
    return GIM_OK;
}

static gim_result gim__check_vals(const gim_env *env, const char *fn, const gim_val *vals, uint32_t count) {
    uint32_t i;
    for (i = 0; i < count; ++i) {
        const gim_val *v = vals + i;
        if (!gim__all_finite(v->position, 3) || !gim__all_finite(v->normal, 3) || !gim__all_finite(v->flux, 3) ||
            !gim__isfinitef(v->area) || !gim__isfinitef(v->weight) || !(v->area >= 0.0f) || !(v->weight >= 0.0f) ||
            !(v->flux[0] >= 0.0f && v->flux[1] >= 0.0f && v->flux[2] >= 0.0f) || !gim__unit_or_zero(v->normal, 1))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "VAL %u: not finite, negative area/weight/flux, or a normal neither unit nor zero", i);
    }
    return GIM_OK;
}

/* Sums of one proxy light of one cache (the registers of one GPU invocation). */
typedef struct gim__proxy_sums {
    double s[3];      /* S: sum e_j (diffuse) or sum g_j e_j (glossy), rgb */
    double en;        /* lum(E_n) = sum lum(Phi_j) e_j / cos theta_x,j */
    double w;         /* sum W_j */
    double m1[3];     /* sum W_j (x_l,j - c) */
    double m2[3];     /* sum W_j (x_l,j - c)^2 per axis */
} gim__proxy_sums;

static void gim__sums_add(gim__proxy_sums *a, const float *d, double weight, const float *phi, double e, double lum_en) {
    int k;
    for (k = 0; k < 3; ++k) {
        a->s[k] += (double)phi[k] * e;
        a->m1[k] += weight * d[k];
        a->m2[k] += weight * d[k] * d[k];
    }
    a->en += lum_en;
    a->w += weight;
}

/* Position, sigma and flux (eq. 5/13, eq. 7 with the guard) from the sums; glossy_k < 0: diffuse. */
static void gim__proxy_finish(const gim__proxy_sums *a, const gim_cache *c, const float *v, float glossy_k,
                              gim_proxy_light *out) {
    double o[3], d2 = 0.0, dp, cos_p = 0.0, dproxy, floor_, lum_s, smax = 0.0;
    int k;
    memset(out, 0, sizeof *out);
    out->visibility = 1.0f;
    for (k = 0; k < 3; ++k) {
        double var;
        o[k] = a->w > 0.0 ? a->m1[k] / a->w : 0.0;
        var = a->w > 0.0 ? a->m2[k] / a->w - o[k] * o[k] : 0.0;
        out->sigma[k] = var > 0.0 ? gim__clamp_flt(sqrt(var)) : 0.0f;
        smax = out->sigma[k] > smax ? out->sigma[k] : smax;
        out->position[k] = (float)((double)c->position[k] + o[k]);
        d2 += o[k] * o[k];
    }
    out->radius = gim__clamp_flt(2.0 * smax);
    lum_s = 0.2126 * a->s[0] + 0.7152 * a->s[1] + 0.0722 * a->s[2];
    if (!(lum_s > 0.0) || !(a->en > 0.0) || !(d2 > 0.0)) return;  /* dark: flux 0 */
    dp = sqrt(d2);
    for (k = 0; k < 3; ++k) cos_p += (double)c->normal[k] * o[k] / dp;
    dproxy = cos_p > 0.0 ? cos_p : 0.0;
    if (glossy_k >= 0.0f && dproxy > 0.0) {
        /* lobe at the proxy's direction: omega_p mirrored at n_c, dotted with v */
        double re = 0.0;
        for (k = 0; k < 3; ++k) re += (2.0 * cos_p * c->normal[k] - o[k] / dp) * v[k];
        dproxy *= gim__lobe((float)re, glossy_k);
    }
    floor_ = lum_s / a->en;                 /* the guard: normal irradiance <= E_n */
    if (dproxy < floor_) dproxy = floor_;
    for (k = 0; k < 3; ++k) out->flux[k] = gim__clamp_flt(4.0 * GIM__PI * d2 * a->s[k] / dproxy);
}

/* Near field of a VAL. A VAL stands for its texel's patch; the disk formula A cos cos / (A +
   pi d^2) treats it as a point seen from afar (exact only on the disk's axis), which near a
   contact edge, where a receiver sees a neighbouring surface's VALs at grazing angles from
   less than a texel away, loses light: the corner's floor 0.025 from the wall got 0.37 of the
   wall's light at RSM 128^2, 0.76 at 0.067 (tests/unit/test_physics.c; of the rest, 0.17 at 0.067
   lies in the wall's strip below its lowest texel centres, which the RSM gives to floor
   texels). Within d < GIM__VAL_NEAR sqrt(A) the VAL is a regular octagon of area A in its
   plane (gim__basis(n_l) axes), clipped to the receiver's hemisphere, and Lambert's contour
   formula gives its vector form factor Phi = 1/(2 pi) sum_k angle(r_k, r_k+1) unit(r_k x
   r_k+1): the form factor F = n . Phi and the irradiance direction unit(Phi). In: d = x_l - c,
   n the receiver's normal, nl the VAL's, cos_x > 0 at the centre, the VAL's weight w and its
   far-field E_n term en = w cos_l / (A + pi d^2). Out: the E_n term blended towards
   w |Phi| / (2 pi A) (the irradiance perpendicular to the light's direction; computed as such,
   not as a factor on en, whose cos_l can be near 0 where the patch's term is not), with
   *cos_x = F / |Phi| and d turned to unit(Phi)
   (its length kept), so that e = E_n cos_x = w F / A and the proxy is placed where the light
   comes from. Faded to the far field between d = 0.75 and 1 GIM__VAL_NEAR sqrt(A): no step
   where the GPU and the twin round d^2 to either side. */
#define GIM__VAL_NEAR 2.0f
/* The near field of a VAL or VPL needs the receiver this far (times sqrt(A)) in front of the
   patch's plane: the other side of a thin plate lies in the plane, inside the octagon, and
   rounding put the whole octagon in its hemisphere (F = 1 for a surface that sees nothing of
   it; the VPL methods' parallel plates, sun: 56% of pixels within 10% before, 93% after). */
#define GIM__VPL_NEAR_LIFT 0.01f
/* The GPU evaluates the near VALs out of its VAL loop: the first GIM__VAL_NEAR_CAP of a cache
   from a list after each chunk's loop, any more in a dispatch of their own that only the work
   groups holding such a cache run. In the loop a branch around the patch's form factor costs
   every VAL on SIMD CPUs (llvmpipe masks both sides), 11x the proxy pass on the street. */
#define GIM__VAL_NEAR_CAP 16u
/* The patch of a VAL or a VPL near a receiver: a regular octagon of area A around d (the
   light's centre relative to the receiver) in the plane of normal nl (gim__basis(nl) axes),
   clipped to the receiver's hemisphere n . y >= 0, and its vector form factor by Lambert's
   contour formula, 2 pi times it: phi = sum_k angle(r_k, r_k+1) unit(r_k x r_k+1), turned so
   that n . phi >= 0. Returns f = n . phi (the form factor is f / (2 pi)); 0 with phi = 0 when
   nothing of the patch is above the receiver's horizon. */
static float gim__octagon_phi(const float *d, const float *n, const float *nl, float area, float *phi) {
    static const float dirs[8][2] = {{1.0f, 0.0f}, {0.70710678f, 0.70710678f}, {0.0f, 1.0f}, {-0.70710678f, 0.70710678f},
                                     {-1.0f, 0.0f}, {-0.70710678f, -0.70710678f}, {0.0f, -1.0f}, {0.70710678f, -0.70710678f}};
    /* a convex octagon clipped by a plane has at most 9 corners, but rounding can make h change
       sign more than twice around it (a plane through several corners): room for each corner and
       each crossing */
    float v[8][3], h[8], poly[16][3], r, f;
    gim_vec3 t, b;
    int k, a, m = 0;
    gim__basis(gim_v3(nl[0], nl[1], nl[2]), &t, &b);
    r = sqrtf(area / (2.0f * 1.41421356f));   /* octagon of area 2 sqrt(2) r^2 = A */
    phi[0] = phi[1] = phi[2] = 0.0f;
    for (k = 0; k < 8; ++k) {   /* the vertices relative to the receiver */
        float ct = dirs[k][0], st = dirs[k][1];
        v[k][0] = d[0] + r * (ct * t.x + st * b.x);
        v[k][1] = d[1] + r * (ct * t.y + st * b.y);
        v[k][2] = d[2] + r * (ct * t.z + st * b.z);
        h[k] = n[0] * v[k][0] + n[1] * v[k][1] + n[2] * v[k][2];
    }
    for (k = 0; k < 8; ++k) {   /* clipped to n . y >= 0 (Sutherland-Hodgman) */
        int k1 = (k + 1) & 7;
        if (h[k] >= 0.0f) { for (a = 0; a < 3; ++a) poly[m][a] = v[k][a]; ++m; }
        if ((h[k] >= 0.0f) != (h[k1] >= 0.0f)) {
            float s_ = h[k] / (h[k] - h[k1]);
            for (a = 0; a < 3; ++a) poly[m][a] = v[k][a] + s_ * (v[k1][a] - v[k][a]);
            ++m;
        }
    }
    for (k = 0; k < m; ++k) {   /* Lambert's contour formula, as a vector */
        const float *p0 = poly[k], *p1 = poly[(k + 1) % m];
        float l0 = sqrtf(p0[0] * p0[0] + p0[1] * p0[1] + p0[2] * p0[2]);
        float l1 = sqrtf(p1[0] * p1[0] + p1[1] * p1[1] + p1[2] * p1[2]);
        float c[3], lc, dt, ll = l0 * l1, g;
        if (!(l0 > 0.0f) || !(l1 > 0.0f)) continue;
        c[0] = (p0[1] * p1[2] - p0[2] * p1[1]) / ll;
        c[1] = (p0[2] * p1[0] - p0[0] * p1[2]) / ll;
        c[2] = (p0[0] * p1[1] - p0[1] * p1[0]) / ll;
        lc = sqrtf(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        dt = (p0[0] * p1[0] + p0[1] * p1[1] + p0[2] * p1[2]) / ll;
        if (!(lc > 0.0f)) continue;
        g = atan2f(lc, dt) / lc;
        for (a = 0; a < 3; ++a) phi[a] += g * c[a];
    }
    f = n[0] * phi[0] + n[1] * phi[1] + n[2] * phi[2];
    if (f < 0.0f) { f = -f; for (a = 0; a < 3; ++a) phi[a] = -phi[a]; }   /* the winding faces n */
    return f;
}

/* The near field's weight at d^2 from a light of area A: 1 within 1.5 sqrt(A), 0 from
   GIM__VAL_NEAR sqrt(A) on, linear in d^2 between (no step where the GPU and the twin round
   d^2 to either side). */
static float gim__near_weight(float d2, float area) {
    float w = (GIM__VAL_NEAR * GIM__VAL_NEAR - d2 / area) / ((1.0f - 0.5625f) * GIM__VAL_NEAR * GIM__VAL_NEAR);
    return w < 1.0f ? w : 1.0f;
}

/* The near field of a VAL or VPL at a receiver: its weight w (gim__near_weight) where the patch
   applies, 0 where the far field stands (beyond 2 sqrt(A), a receiver within
   GIM__VPL_NEAR_LIFT sqrt(A) of the patch's plane, nothing of the patch above its horizon).
   d: the light's centre relative to the receiver (d2 = |d|^2), n the receiver's normal, nl
   the light's; phi, f = n . phi and fv = |phi| as gim__octagon_phi gives them. */
static float gim__near_patch(const float *d, float d2, const float *n, const float *nl, float area, float *phi, float *f,
                             float *fv) {
    float w = gim__near_weight(d2, area);
    if (!(w > 0.0f)) return 0.0f;
    /* a receiver (nearly) in the patch's plane: the other side of a thin surface, whose points
       coincide with the light's own; its octagon would be all in or all out of the receiver's
       hemisphere by rounding (F 1 or 0) */
    if (!(-(nl[0] * d[0] + nl[1] * d[1] + nl[2] * d[2]) > GIM__VPL_NEAR_LIFT * sqrtf(area))) return 0.0f;
    *f = gim__octagon_phi(d, n, nl, area, phi);
    *fv = sqrtf(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]);
    if (!(*f > 0.0f) || !(*fv > 0.0f) || !gim__isfinitef(*fv) || !(area > 0.0f)) return 0.0f;   /* no patch */
    return w;
}

static double gim__val_near(float *d, const float *n, const float *nl, float area, double weight, double en, float *cos_x) {
    float phi[3], f, d2, dl, fv, w, u[3], ul;
    int a;
    d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    w = gim__near_patch(d, d2, n, nl, area, phi, &f, &fv);
    if (!(w > 0.0f)) return en;   /* the far field */
    dl = sqrtf(d2);
    for (a = 0; a < 3; ++a) u[a] = d[a] / dl + w * (phi[a] / fv - d[a] / dl);
    ul = sqrtf(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (ul > 0.0f && gim__isfinitef(ul))
        for (a = 0; a < 3; ++a) d[a] = u[a] * (dl / ul);
    *cos_x += w * (f / fv - *cos_x);
    /* 1 / (2 pi) of the formula: E_n = w |Phi| / A */
    return en + w * (weight * ((double)fv / (2.0 * GIM__PI) / (double)area) - en);   /* in double, as en */
}

/* One invocation of the proxy pass: cache c against every VAL. */
static void gim__proxy_cache(const gim_cache *c, const gim_val *vals, uint32_t val_count, const float *vis,
                             const float *v, float k, float coincident2, gim_proxy_light *diffuse,
                             gim_proxy_light *glossy) {
    gim__proxy_sums sd, sg;
    uint32_t j, q;
    const float *n = c->normal;
    memset(&sd, 0, sizeof sd);
    memset(&sg, 0, sizeof sg);
    /* every VAL far from the cache, then the near ones as the patches they stand for: the
       GPU's order */
    for (q = 0; q < 2u * val_count; ++q) {
        const int late = q >= val_count;
        const gim_val *l;
        float d[3], d2, inv, cos_x, cos_l, den;
        double en, e, lphi, wgt;
        int near;
        j = late ? q - val_count : q;
        l = vals + j;
        d[0] = l->position[0] - c->position[0];
        d[1] = l->position[1] - c->position[1];
        d[2] = l->position[2] - c->position[2];
        d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        inv = d2 > coincident2 ? 1.0f / sqrtf(d2) : 0.0f;          /* no direction: no light */
        cos_x = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) * inv;
        cos_l = -(l->normal[0] * d[0] + l->normal[1] * d[1] + l->normal[2] * d[2]) * inv;
        cos_x = cos_x > 0.0f ? cos_x : 0.0f;                       /* (also NaN from inf * 0) */
        cos_l = cos_l > 0.0f ? cos_l : 0.0f;
        den = l->area + (float)GIM__PI * d2;
        /* eq. 3/14 per unit flux without cos_x; in double, so weights near FLT_MAX stay finite */
        en = den > 0.0f ? (double)l->weight * cos_l / den : 0.0;
        near = d2 < GIM__VAL_NEAR * GIM__VAL_NEAR * l->area && cos_l > 0.0f && cos_x > 0.0f;
        if (near != late) continue;   /* each in its pass */
        if (late) en = gim__val_near(d, n, l->normal, l->area, l->weight, en, &cos_x);   /* the near field: the VAL's patch */
        if (vis) en *= vis[j];                                     /* V(c, x_j) */
        e = en * cos_x;
        if (!(e > 0.0)) continue;          /* behind, grazing, coincident or weight 0: adds nothing */
        lphi = 0.2126 * l->flux[0] + 0.7152 * l->flux[1] + 0.0722 * l->flux[2];
        wgt = lphi * e;                                            /* W_j: what the VAL adds */
        gim__sums_add(&sd, d, wgt, l->flux, e, lphi * en);
        if (glossy) {
            float re = 0.0f;
            double g;
            int a;
            for (a = 0; a < 3; ++a) re += (2.0f * cos_x * n[a] - d[a] * inv) * v[a];
            g = gim__lobe(re, k);                                  /* eq. 4/15, eq. 6 cos^k theta_e */
            if (g > 0.0) gim__sums_add(&sg, d, wgt * g, l->flux, e * g, lphi * en);
            else sg.en += lphi * en;                               /* E_n counts all the light */
        }
    }
    /* a dark cache: the paper's form-factor weights of eq. 6 place the proxy (a second loop,
       only in the invocations that need it) */
    if (!(sd.w > 0.0)) {
        int a;
        for (j = 0; j < val_count; ++j) {
            const gim_val *l = vals + j;
            float d[3], d2, inv, cos_x, cos_l, den;
            double f;
            for (a = 0; a < 3; ++a) d[a] = l->position[a] - c->position[a];
            d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            inv = d2 > coincident2 ? 1.0f / sqrtf(d2) : 0.0f;
            cos_x = (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) * inv;
            cos_l = -(l->normal[0] * d[0] + l->normal[1] * d[1] + l->normal[2] * d[2]) * inv;
            cos_x = cos_x > 0.0f ? cos_x : 0.0f;
            cos_l = cos_l > 0.0f ? cos_l : 0.0f;
            den = l->area + (float)GIM__PI * d2;
            f = den > 0.0f ? (double)l->weight * l->area * cos_l * cos_x / den : 0.0;   /* F */
            if (!(f > 0.0)) continue;
            sd.w += f;
            for (a = 0; a < 3; ++a) { sd.m1[a] += f * d[a]; sd.m2[a] += f * d[a] * d[a]; }
        }
    }
    gim__proxy_finish(&sd, c, v, -1.0f, diffuse);
    if (glossy) {
        if (!(sg.w > 0.0)) {    /* the lobe sees no light: the diffuse proxy's place, flux 0 */
            int a;
            sg.w = sd.w;
            for (a = 0; a < 3; ++a) { sg.m1[a] = sd.m1[a]; sg.m2[a] = sd.m2[a]; }
        }
        gim__proxy_finish(&sg, c, v, k, glossy);
    }
}

GIMANY_DEF gim_result gim_proxy_lights_twin(const gim_proxy_desc *desc, gim_proxy_light *diffuse_out,
                                       gim_proxy_light *glossy_out) {
    static const char fn[] = "gim_proxy_lights_twin";
    const gim_env *env;
    gim_result r;
    float scale, coincident2;
    uint32_t i;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    if (!diffuse_out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "diffuse_out is NULL");
    if (!desc->caches || desc->cache_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no caches");
    if (desc->val_count > 0 && !desc->vals) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "vals is NULL");
    if (!gim__isfinitef(desc->scene_scale) || desc->scene_scale < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale must be finite and >= 0 (0: default)");
    if (glossy_out) {
        if (!gim__v3_isfinite(desc->eye)) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "eye is not finite");
        if (!(desc->glossy_exponent >= 0.0f && desc->glossy_exponent <= GIM__TWINS_MAX_EXPONENT))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "glossy_exponent must be in [0, 1e6]");
        if (desc->cache_glossy_exponent)
            for (i = 0; i < desc->cache_count; ++i)
                if (!(desc->cache_glossy_exponent[i] >= 0.0f && desc->cache_glossy_exponent[i] <= GIM__TWINS_MAX_EXPONENT))
                    return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "cache_glossy_exponent[%u] must be in [0, 1e6]", i);
    }
    if ((r = gim__check_caches(env, fn, desc->caches, desc->cache_count)) != GIM_OK) return r;
    if ((r = gim__check_vals(env, fn, desc->vals, desc->val_count)) != GIM_OK) return r;
    if (desc->visibility) {
        size_t m = (size_t)desc->cache_count * desc->val_count, q;
        for (q = 0; q < m; ++q)
            if (!(desc->visibility[q] >= 0.0f && desc->visibility[q] <= 1.0f))
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "visibility[%zu] is not in [0, 1]", q);
    }
    scale = desc->scene_scale > 0.0f ? desc->scene_scale
                                     : gim__twins_scale(desc->caches, desc->cache_count, desc->vals, desc->val_count);
    coincident2 = GIM__TWINS_COINCIDENT * scale * (GIM__TWINS_COINCIDENT * scale);
    for (i = 0; i < desc->cache_count; ++i) {
        const gim_cache *c = desc->caches + i;
        float v[3] = {0.0f, 0.0f, 0.0f}, k = 0.0f;
        if (glossy_out) {
            gim_vec3 vv = gim_v3_normalize(gim_v3(desc->eye.x - c->position[0], desc->eye.y - c->position[1],
                                                  desc->eye.z - c->position[2]));
            v[0] = vv.x; v[1] = vv.y; v[2] = vv.z;    /* an eye at the cache: v = 0, only k = 0 lights */
            k = desc->cache_glossy_exponent ? desc->cache_glossy_exponent[i] : desc->glossy_exponent;
        }
        gim__proxy_cache(c, desc->vals, desc->val_count,
                         desc->visibility ? desc->visibility + (size_t)i * desc->val_count : NULL, v, k, coincident2,
                         diffuse_out + i,
                         glossy_out ? glossy_out + i : NULL);
    }
    return GIM_OK;
}

/* One proxy light set interpolated at x (eq. 8-9): the irradiance each neighbour's proxy
   light delivers at x, moved along with the surface point (at x + x_p,j - c_j), averaged with
   eq. 8's weights w'. For the glossy set the receiver's lobe is evaluated per neighbour, in
   the direction of its own proxy: out = sum w' E_j f_j / sum w', f_j = (k+2)/(2 pi)
   ((r_j . view)+)^k (f = 1 for the diffuse set). Sums per pass: [0] with eq. 8's weights,
   [1] with the normal term alone (used when every eq. 8 weight is 0).
   Why irradiance and not eq. 9's flux and position: eq. 7 makes a proxy's flux grow with the
   square of its distance, so averaging fluxes and positions separately and then applying
   1 / |l|^2 gives E_v / E = M2^3 / M3^2 <= 1 for neighbours at different distances (M_k the
   weighted moments of the offsets; 0.5-0.85 of the light measured near contact edges), and
   eq. 9's plain w' gives M2 / M1^2 >= 1. Averaging what each neighbour delivers is exact for
   one neighbour and for any neighbours that agree, and never divides one cache's flux by
   another's distance. */
static void gim__interp_light(const gim_shade_desc *d, const gim_proxy_light *lights, int glossy,
                              const gim_receiver *rc, const uint32_t *idx, uint32_t cnt, float dcmax,
                              float near_, double *e_out) {
    double sw[2] = {0, 0}, se[2][3] = {{0, 0, 0}, {0, 0, 0}};
    uint32_t j;
    int a, pass, use;
    e_out[0] = e_out[1] = e_out[2] = 0.0;
    for (j = 0; j < cnt; ++j) {
        const gim_cache *c;
        const gim_proxy_light *p;
        double dist = 0.0, tent, nterm = 0.0, op[3], dp2 = 0.0, lp, cos_x = 0.0, f = 1.0, ej[3];
        if (idx[j] == UINT32_MAX) continue;
        c = d->caches + idx[j];
        p = lights + idx[j];
        for (a = 0; a < 3; ++a) {
            double dx = (double)rc->position[a] - c->position[a];
            dist += dx * dx;
            op[a] = (double)p->position[a] - c->position[a];          /* the proxy's offset */
            dp2 += op[a] * op[a];
        }
        dist = sqrt(dist);
        tent = dcmax > near_ ? 1.0 - dist / dcmax : 1.0;             /* eq. 8 distance term */
        if (tent < 0.0) tent = 0.0;
        lp = sqrt(dp2);
        if (lp > 0.0)
            for (a = 0; a < 3; ++a) cos_x += rc->normal[a] * op[a] / lp;
        if (glossy && lp > 0.0) {
            /* r_x . r_c: the direction towards the proxy, mirrored at n_x and at n_c */
            double w_[3], cc = 0.0, re = 0.0;
            for (a = 0; a < 3; ++a) { w_[a] = op[a] / lp; cc += c->normal[a] * w_[a]; }
            for (a = 0; a < 3; ++a) {
                nterm += (2.0 * cos_x * rc->normal[a] - w_[a]) * (2.0 * cc * c->normal[a] - w_[a]);
                re += (2.0 * cos_x * rc->normal[a] - w_[a]) * rc->view[a];
            }
            f = (rc->exponent + 2.0) / (2.0 * GIM__PI) * gim__lobe((float)re, rc->exponent);
        } else {   /* diffuse, or a glossy proxy with no direction (dark): the normals */
            for (a = 0; a < 3; ++a) nterm += (double)rc->normal[a] * c->normal[a];
        }
        nterm = nterm > 0.0 ? sqrt(nterm) : 0.0;
        /* E_j at x: the proxy at x + op, never nearer than 1e-6 scene scales */
        if (dp2 < (double)near_ * near_) dp2 = (double)near_ * near_;
        for (a = 0; a < 3; ++a)
            ej[a] = cos_x > 0.0 ? (double)p->flux[a] * p->visibility * cos_x / (4.0 * GIM__PI * dp2) * f : 0.0;
        for (pass = 0; pass < 2; ++pass) {
            double w = pass == 0 ? tent * nterm : nterm;
            if (!(w > 0.0)) continue;
            sw[pass] += w;
            for (a = 0; a < 3; ++a) se[pass][a] += w * ej[a];
        }
    }
    use = sw[0] > 0.0 ? 0 : 1;
    if (!(sw[use] > 0.0)) return;                                      /* no neighbour */
    for (a = 0; a < 3; ++a) e_out[a] = se[use][a] / sw[use];
}

/* The arguments of the shading pass; lights 0 leaves out the proxy lights (gim_lightskin_frame_twin
   checks the rest before it spends the proxy pass). */
static gim_result gim__check_shade(const gim_shade_desc *d, const char *fn, int lights) {
    const gim_env *env = &d->env;
    gim_result r;
    uint32_t i, j;
    if (!d->caches || d->cache_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no caches");
    if (lights && !d->diffuse) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "diffuse proxy lights are required");
    if (!d->receivers || d->receiver_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no receivers");
    if (!d->neighbour_index || !d->d_cmax) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "neighbour_index and d_cmax are required");
    if (d->neighbour_stride == 0 || d->neighbour_stride > GIM_MAX_NEIGHBOUR_CACHES)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "neighbour_stride must be 1..%d", GIM_MAX_NEIGHBOUR_CACHES);
    if (!gim__isfinitef(d->scene_scale) || !(d->scene_scale > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale must be finite and > 0");
    if ((r = gim__check_caches(env, fn, d->caches, d->cache_count)) != GIM_OK) return r;
    for (i = 0; lights && i < d->cache_count; ++i) {
        const gim_proxy_light *p = d->diffuse + i, *g = d->glossy ? d->glossy + i : NULL;
        if (!gim__all_finite(p->position, 3) || !gim__all_finite(p->flux, 3) || !(p->visibility >= 0.0f && p->visibility <= 1.0f) ||
            (g && (!gim__all_finite(g->position, 3) || !gim__all_finite(g->flux, 3) || !(g->visibility >= 0.0f && g->visibility <= 1.0f))))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "proxy light %u: not finite or visibility outside [0,1]", i);
        if (!(p->flux[0] >= 0.0f && p->flux[1] >= 0.0f && p->flux[2] >= 0.0f) ||
            (g && !(g->flux[0] >= 0.0f && g->flux[1] >= 0.0f && g->flux[2] >= 0.0f)))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "proxy light %u: negative flux", i);
    }
    for (i = 0; i < d->receiver_count; ++i) {
        const gim_receiver *rc = d->receivers + i;
        uint32_t cnt = d->neighbour_count ? d->neighbour_count[i] : d->neighbour_stride;
        const uint32_t *idx = d->neighbour_index + (size_t)i * d->neighbour_stride;
        if (!gim__all_finite(rc->position, 3) || !gim__all_finite(rc->albedo, 3) || !gim__all_finite(rc->glossy, 3) ||
            !gim__unit_or_zero(rc->normal, 0) || !gim__unit_or_zero(rc->view, 0) ||
            !(rc->albedo[0] >= 0.0f && rc->albedo[1] >= 0.0f && rc->albedo[2] >= 0.0f) ||
            !(rc->glossy[0] >= 0.0f && rc->glossy[1] >= 0.0f && rc->glossy[2] >= 0.0f) ||
            !(rc->exponent >= 0.0f && rc->exponent <= GIM__TWINS_MAX_EXPONENT))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "receiver %u: not finite, normal or view not unit, negative colour, or k outside [0, 1e6]", i);
        if (cnt > d->neighbour_stride)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "neighbour_count[%u] = %u exceeds the stride %u", i, cnt, d->neighbour_stride);
        if (d->source && d->source[i] >= d->receiver_count)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "source[%u] = %u: not a receiver (of %u)", i, d->source[i], d->receiver_count);
        if (!gim__isfinitef(d->d_cmax[i]) || !(d->d_cmax[i] >= 0.0f))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "d_cmax[%u] must be finite and >= 0", i);
        for (j = 0; j < cnt; ++j)
            if (idx[j] != UINT32_MAX && idx[j] >= d->cache_count)
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "receiver %u: neighbour %u is cache %u of %u", i, j, idx[j], d->cache_count);
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_lightskin_shade_twin(const gim_shade_desc *desc, float *radiance_out) {
    static const char fn[] = "gim_lightskin_shade_twin";
    gim_result r;
    uint32_t i;
    float near_;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    if (!radiance_out) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "radiance_out is NULL");
    if ((r = gim__check_shade(desc, fn, 1)) != GIM_OK) return r;
    near_ = GIM__TWINS_COINCIDENT * desc->scene_scale;
    for (i = 0; i < desc->receiver_count; ++i) {
        uint32_t s = desc->source ? desc->source[i] : i;   /* whose light: its own or its block's */
        const gim_receiver *rc = desc->receivers + s, *own = desc->receivers + i;
        const uint32_t *idx = desc->neighbour_index + (size_t)s * desc->neighbour_stride;
        uint32_t cnt = desc->neighbour_count ? desc->neighbour_count[s] : desc->neighbour_stride;
        double ed[3], eg[3], out[3];
        int a;
        gim__interp_light(desc, desc->diffuse, 0, rc, idx, cnt, desc->d_cmax[s], near_, ed);
        for (a = 0; a < 3; ++a) out[a] = own->albedo[a] / GIM__PI * ed[a];
        if (desc->glossy) {
            gim__interp_light(desc, desc->glossy, 1, rc, idx, cnt, desc->d_cmax[s], near_, eg);
            for (a = 0; a < 3; ++a) out[a] += own->glossy[a] * eg[a];
        }
        for (a = 0; a < 3; ++a) radiance_out[(size_t)i * 3 + (size_t)a] = gim__clamp_flt(out[a]);
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_lightskin_frame_twin(const gim_lightskin_desc *desc, float *radiance_out) {
    static const char fn[] = "gim_lightskin_frame_twin";
    const gim_env *env;
    gim_proxy_desc pd;
    gim_shade_desc sd;
    gim_proxy_light *lights;
    gim_result r;
    size_t n;
    float scale;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    if (!radiance_out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "radiance_out is NULL");
    if (!desc->caches || desc->cache_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no caches");
    if (desc->val_count > 0 && !desc->vals) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "vals is NULL");
    if (!gim__isfinitef(desc->scene_scale) || desc->scene_scale < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale must be finite and >= 0 (0: default)");
    scale = desc->scene_scale > 0.0f ? desc->scene_scale
                                     : gim__twins_scale(desc->caches, desc->cache_count, desc->vals, desc->val_count);
    memset(&pd, 0, sizeof pd);
    pd.caches = desc->caches; pd.cache_count = desc->cache_count;
    pd.vals = desc->vals; pd.val_count = desc->val_count;
    pd.eye = desc->eye; pd.glossy_exponent = desc->glossy_exponent;
    pd.cache_glossy_exponent = desc->cache_glossy_exponent;
    pd.scene_scale = scale; pd.env = desc->env;
    pd.visibility = desc->visibility;
    memset(&sd, 0, sizeof sd);
    sd.caches = desc->caches; sd.cache_count = desc->cache_count;
    sd.receivers = desc->receivers; sd.receiver_count = desc->receiver_count;
    sd.neighbour_index = desc->neighbour_index; sd.neighbour_count = desc->neighbour_count;
    sd.neighbour_stride = desc->neighbour_stride; sd.d_cmax = desc->d_cmax;
    sd.source = desc->source;
    sd.scene_scale = scale; sd.env = desc->env;
    if ((r = gim__check_shade(&sd, fn, 0)) != GIM_OK) return r;   /* before the costly passes */
    n = (size_t)desc->cache_count * (desc->glossy ? 2u : 1u);
    lights = (gim_proxy_light *)gim__alloc_array(env, n, sizeof *lights);
    if (!lights) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "%zu proxy lights", n);
    sd.diffuse = lights;
    sd.glossy = desc->glossy ? lights + desc->cache_count : NULL;
    r = gim_proxy_lights_twin(&pd, lights, desc->glossy ? lights + desc->cache_count : NULL);
    if (r == GIM_OK) r = gim_lightskin_shade_twin(&sd, radiance_out);
    gim__free(env, lights);
    return r;
}


/* lightskin_shade.comp's shares(), in the same float steps */
static int gim__shares_light(const gim_receiver *x, const gim_receiver *r, float cell) {
    float d[3], dl, nn = 0.0f, nd = 0.0f;
    int a;
    for (a = 0; a < 3; ++a) d[a] = x->position[a] - r->position[a];
    dl = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (a = 0; a < 3; ++a) { nn += x->normal[a] * r->normal[a]; nd += r->normal[a] * d[a]; }
    return nn >= 0.995f && fabsf(nd) <= 0.05f * dl && dl <= 0.25f * cell && x->exponent == r->exponent;
}

GIMANY_DEF gim_result gim_shade_sources(const gim_shade_blocks_desc *desc, uint32_t *source_out) {
    static const char fn[] = "gim_shade_sources";
    const gim_env *env;
    uint32_t i, b, bw, bh, *first;
    size_t blocks;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    b = desc->block ? desc->block : GIM_DEFAULT_SHADE_BLOCK;
    if (!source_out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "source_out is NULL");
    if (desc->receiver_count > 0 && (!desc->receivers || !desc->pixels))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "receivers and pixels are required");
    if (b > 2) return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "block %u: 1 or 2", (unsigned)b);
    if (desc->width == 0 || desc->height == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "empty image");
    if (!gim__isfinitef(desc->cell) || !(desc->cell > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "cell must be finite and > 0");
    bw = (desc->width + b - 1u) / b;
    bh = (desc->height + b - 1u) / b;
    blocks = (size_t)bw * bh;
    first = (uint32_t *)gim__alloc_array(env, blocks, sizeof *first);
    if (!first) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, fn, "%zu blocks", blocks);
    for (i = 0; i < blocks; ++i) first[i] = UINT32_MAX;
    /* each block's first receiver: the least position (x mod B) + B (y mod B) */
    for (i = 0; i < desc->receiver_count; ++i) {
        uint32_t x = desc->pixels[2 * i], y = desc->pixels[2 * i + 1], q, k;
        size_t blk;
        if (x >= desc->width || y >= desc->height) {
            gim__free(env, first);
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "receiver %u: pixel (%u, %u) outside %ux%u", i, x, y,
                             desc->width, desc->height);
        }
        blk = (size_t)(y / b) * bw + x / b;
        q = x % b + b * (y % b);
        k = first[blk];
        if (k == UINT32_MAX || q < desc->pixels[2 * k] % b + b * (desc->pixels[2 * k + 1] % b)) first[blk] = i;
    }
    for (i = 0; i < desc->receiver_count; ++i) {
        uint32_t x = desc->pixels[2 * i], y = desc->pixels[2 * i + 1];
        uint32_t r = first[(size_t)(y / b) * bw + x / b];
        source_out[i] = r != i && gim__shares_light(desc->receivers + i, desc->receivers + r, desc->cell) ? r : i;
    }
    gim__free(env, first);
    return GIM_OK;
}

/* Sample j of the gather pattern: its texel offset (r cos phi, r sin phi), r = radius u,
   phi = 2 pi v, and its weight 1 / (N pdf) = 2 pi r radius / N, as floats: the GPU pass reads
   the same three numbers, so both sample the same texels. */
static void gim__gather_offset(const float uv[2], float radius, uint32_t n, float out[3]) {
    double r = (double)radius * uv[0], phi = 2.0 * GIM__PI * uv[1];
    out[0] = (float)(r * cos(phi));
    out[1] = (float)(r * sin(phi));
    out[2] = (float)(2.0 * GIM__PI * r * radius / n);
}

GIMANY_DEF gim_result gim_rsm_gather_twin(const gim_gather_desc *d, float *radiance_out) {
    static const char fn[] = "gim_rsm_gather_twin";
    const gim_rsm_data *m;
    uint32_t i, j;
    double near2;
    if (!d) return GIM_ERROR_INVALID_ARGUMENT;
    m = d->rsm;
    if (!radiance_out || !m || !d->samples || !d->receivers)
        return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "NULL rsm, samples, receivers or output");
    if (!m->position || !m->normal || !m->flux || !m->area || m->width == 0 || m->height == 0)
        return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm position, normal, flux, area and a size are required");
    if (d->sample_count == 0 || d->receiver_count == 0)
        return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "no samples or no receivers");
    if (!gim__isfinitef(d->radius) || !(d->radius > 0.0f) || !gim__isfinitef(d->scene_scale) || !(d->scene_scale > 0.0f) ||
        !gim__mat4_isfinite(d->light_view_proj))
        return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "radius, scene_scale or the light's matrix invalid");
    if (!gim__all_finite(d->samples, (size_t)d->sample_count * 2u))
        return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "samples not finite");
    for (i = 0; i < d->receiver_count; ++i) {
        const gim_receiver *rc = d->receivers + i;
        if (!gim__all_finite(rc->position, 3) || !gim__all_finite(rc->albedo, 3) || !gim__all_finite(rc->glossy, 3) ||
            !gim__unit_or_zero(rc->normal, 0) || !gim__unit_or_zero(rc->view, 0) ||
            !(rc->albedo[0] >= 0.0f && rc->albedo[1] >= 0.0f && rc->albedo[2] >= 0.0f) ||
            !(rc->glossy[0] >= 0.0f && rc->glossy[1] >= 0.0f && rc->glossy[2] >= 0.0f) ||
            !(rc->exponent >= 0.0f && rc->exponent <= GIM__TWINS_MAX_EXPONENT))
            return gim__fail(&d->env, GIM_ERROR_INVALID_ARGUMENT, fn, "receiver %u: not finite, not unit or out of range", i);
    }
    near2 = (double)GIM__TWINS_COINCIDENT * d->scene_scale * ((double)GIM__TWINS_COINCIDENT * d->scene_scale);
    for (i = 0; i < d->receiver_count; ++i) {
        const gim_receiver *rc = d->receivers + i;
        const float *mm = d->light_view_proj.m;
        double clip[4], px, py, sd[3] = {0, 0, 0}, sg[3] = {0, 0, 0};
        int a;
        for (a = 0; a < 4; ++a)
            clip[a] = mm[a] * (double)rc->position[0] + mm[4 + a] * (double)rc->position[1] + mm[8 + a] * (double)rc->position[2] +
                      mm[12 + a];
        radiance_out[i * 3] = radiance_out[i * 3 + 1] = radiance_out[i * 3 + 2] = 0.0f;
        if (clip[3] > 0.0) {
            px = (clip[0] / clip[3] * 0.5 + 0.5) * m->width;   /* texel space: texel t covers [t, t + 1) */
            py = (clip[1] / clip[3] * 0.5 + 0.5) * m->height;
            px = px < 0.0 ? 0.0 : (px > m->width ? (double)m->width : px);   /* off the map: its nearest point */
            py = py < 0.0 ? 0.0 : (py > m->height ? (double)m->height : py);
        } else {   /* behind the light's eye: the map's centre */
            px = 0.5 * m->width;
            py = 0.5 * m->height;
        }
        for (j = 0; j < d->sample_count; ++j) {
            float o[3];
            double tx, ty, w, dd[3], d2 = 0.0, inv, cx = 0.0, cl = 0.0, e;
            size_t t;
            const float *xl, *nl, *fl;
            float al;
            gim__gather_offset(d->samples + j * 2, d->radius, d->sample_count, o);
            tx = floor((double)((float)px + o[0]));   /* in float, as the pass adds them */
            ty = floor((double)((float)py + o[1]));
            if (!(tx >= 0.0 && ty >= 0.0 && tx < (double)m->width && ty < (double)m->height)) continue;
            t = (size_t)ty * m->width + (size_t)tx;
            if (m->valid && !(m->valid[t] > 0.0f)) continue;
            xl = m->position + t * 3; nl = m->normal + t * 3; fl = m->flux + t * 3; al = m->area[t];
            if (!gim__all_finite(xl, 3) || !gim__all_finite(nl, 3) || !gim__all_finite(fl, 3) || !gim__isfinitef(al) ||
                !(al >= 0.0f) || !(fl[0] >= 0.0f && fl[1] >= 0.0f && fl[2] >= 0.0f))
                continue;
            for (a = 0; a < 3; ++a) { dd[a] = (double)xl[a] - rc->position[a]; d2 += dd[a] * dd[a]; }
            if (!(d2 > near2)) continue;
            inv = 1.0 / sqrt(d2);
            for (a = 0; a < 3; ++a) { cx += rc->normal[a] * dd[a] * inv; cl -= nl[a] * dd[a] * inv; }
            if (!(cx > 0.0) || !(cl > 0.0)) continue;
            w = o[2];   /* 1 / (N pdf) */
            e = w * cl * cx / ((double)al + GIM__PI * d2);
            for (a = 0; a < 3; ++a) sd[a] += e * fl[a];
            if (rc->glossy[0] > 0.0f || rc->glossy[1] > 0.0f || rc->glossy[2] > 0.0f) {
                double re = 0.0, g;
                for (a = 0; a < 3; ++a) re += (2.0 * cx * rc->normal[a] - dd[a] * inv) * rc->view[a];
                g = gim__lobe((float)re, rc->exponent);
                for (a = 0; a < 3; ++a) sg[a] += g * e * fl[a];
            }
        }
        for (a = 0; a < 3; ++a)
            radiance_out[i * 3 + (uint32_t)a] = gim__clamp_flt(rc->albedo[a] / GIM__PI * sd[a] +
                                                     rc->glossy[a] * (rc->exponent + 2.0) / (2.0 * GIM__PI) * sg[a]);
    }
    return GIM_OK;
}

/* The RSM texel of VPL i: Halton point i + 1 in bases 2, 3 (gim_halton_points). */
static void gim__rsm_vpl_texel(uint32_t i, uint32_t count, gim_vpl_sequence sequence, uint32_t width, uint32_t height,
                               const float *offsets, uint32_t *x, uint32_t *y) {
    float uv[2];
    double fx, fy;
    if (sequence == GIM_VPL_SEQUENCE_HAMMERSLEY) {   /* SSVP eq. 1, centred in its stratum */
        uv[0] = (float)(((double)i + 0.5) / (double)count);
        uv[1] = (float)gim_van_der_corput(i);
        if (offsets) { uv[0] = gim_rotate01(uv[0], offsets[0]); uv[1] = gim_rotate01(uv[1], offsets[1]); }
    } else {
        gim_halton_points(uv, 1, 2, i + 1u, offsets);
    }
    fx = floor((double)uv[0] * width);
    fy = floor((double)uv[1] * height);
    *x = fx < (double)width ? (uint32_t)fx : width - 1u;
    *y = fy < (double)height ? (uint32_t)fy : height - 1u;
}

/* Lit texel t of the RSM (the rules of gim_vals_gather_twin without area, which a VPL does not take). */
static int gim__rsm_vpl_lit(const gim_rsm_data *m, size_t t) {
    const float *f = m->flux + t * 3;
    if (m->valid && !(m->valid[t] > 0.0f)) return 0;
    if (!gim__all_finite(m->position + t * 3, 3) || !gim__all_finite(m->normal + t * 3, 3) || !gim__all_finite(f, 3))
        return 0;
    return f[0] >= 0.0f && f[1] >= 0.0f && f[2] >= 0.0f;
}

/* How far (in texels, Chebyshev) a kept VPL of slot i may stand from its slot's texel: half the
   sequence's spacing sqrt(w h / count) at most, a quarter at least, the share frac(i phi) in
   24 bits between, so that the VPLs of one light do not all reach their bound in the same
   frame (a burst of new ones). Computed on the CPU for both twins and uploaded with the texels. */
static float gim__rsm_vpl_radius(uint32_t i, uint32_t count, uint32_t width, uint32_t height) {
    double spacing = sqrt((double)width * (double)height / (double)count);
    double j = (double)((uint32_t)(i * 2654435769u) >> 8) / 16777216.0;
    return (float)(spacing * (0.25 + 0.25 * j));
}

/* The texel that the previous VPL p of a slot at texel (sx, sy) with radius r stands on now, or -1
   when it is not kept (gim_rsm_vpls_desc.previous; rsm_vpls.comp's follow(), step for step). */
static long gim__rsm_vpl_follow(const gim_rsm_data *m, const gim_vpl *p, const float *vp, uint32_t sx, uint32_t sy,
                                float r) {
    float x = p->position[0], y = p->position[1], z = p->position[2], cx, cy, cw, u, v, fx, fy, dx, dy, d2, a, c;
    const float *q, *n;
    size_t t;
    if (!(p->lit == 1.0f) || !gim__all_finite(p->position, 3) || !gim__all_finite(p->normal, 3)) return -1;
    cx = vp[0] * x; cx += vp[4] * y; cx += vp[8] * z; cx += vp[12];
    cy = vp[1] * x; cy += vp[5] * y; cy += vp[9] * z; cy += vp[13];
    cw = vp[3] * x; cw += vp[7] * y; cw += vp[11] * z; cw += vp[15];
    if (!(cw > 0.0f)) return -1;
    u = cx / cw; u = u * 0.5f + 0.5f; u = u * (float)m->width;
    v = cy / cw; v = v * 0.5f + 0.5f; v = v * (float)m->height;
    fx = (float)floor((double)u);
    fy = (float)floor((double)v);
    if (!(fx >= 0.0f && fy >= 0.0f && fx < (float)m->width && fy < (float)m->height)) return -1;
    dx = fx - (float)sx; dy = fy - (float)sy;
    if (!(fabsf(dx) <= r && fabsf(dy) <= r)) return -1;
    t = (size_t)fy * m->width + (size_t)fx;
    if (!gim__rsm_vpl_lit(m, t)) return -1;
    q = m->position + t * 3; n = m->normal + t * 3;
    dx = q[0] - x; dy = q[1] - y; cw = q[2] - z;
    d2 = dx * dx; d2 += dy * dy; d2 += cw * cw;
    a = m->area ? m->area[t] : 0.0f;
    a = 4.0f * a;
    if (!(d2 <= a)) return -1;   /* a footprint that is NaN or < 0 keeps nothing */
    c = n[0] * p->normal[0]; c += n[1] * p->normal[1]; c += n[2] * p->normal[2];
    if (!(c >= 0.9f)) return -1;
    return (long)t;
}

GIMANY_DEF gim_result gim_rsm_vpls_twin(const gim_rsm_vpls_desc *desc, float *positions, float *normals, float *flux,
                                        float *area) {
    static const char fn[] = "gim_rsm_vpls_twin";
    double total[3] = {0.0, 0.0, 0.0}, sampled[3] = {0.0, 0.0, 0.0}, scale[3], ts, ss, area_scale;
    uint32_t i, x, y, count;
    int a;
    const gim_rsm_data *rsm;
    gim_vpl_sequence sequence;
    const float *offsets;
    size_t *texel;
    unsigned char *kept;
    gim_env env;
    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc is NULL");
    rsm = desc->rsm; count = desc->count; sequence = desc->sequence; offsets = desc->offsets; env = desc->env;
    if (!rsm || !positions || !normals || !flux)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm and the output arrays are required");
    if (!rsm->position || !rsm->normal || !rsm->flux)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "rsm position, normal and flux are required");
    if (rsm->width == 0 || rsm->height == 0 || count == 0)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "RSM %ux%u and count %u must be > 0", (unsigned)rsm->width,
                         (unsigned)rsm->height, (unsigned)count);
    if (offsets && !(offsets[0] >= 0.0f && offsets[0] < 1.0f && offsets[1] >= 0.0f && offsets[1] < 1.0f))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "offsets must be in [0,1)");
    if ((unsigned)sequence > (unsigned)GIM_VPL_SEQUENCE_HAMMERSLEY)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "unknown sequence %d", (int)sequence);
    if (desc->previous && !gim__mat4_isfinite(desc->view_proj))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "view_proj is not finite");
    /* T: each row in x order, then the rows (the GPU's per-row invocations) */
    for (y = 0; y < rsm->height; ++y) {
        double row[3] = {0.0, 0.0, 0.0};
        for (x = 0; x < rsm->width; ++x) {
            size_t t = (size_t)y * rsm->width + x;
            if (gim__rsm_vpl_lit(rsm, t))
                for (a = 0; a < 3; ++a) row[a] += rsm->flux[t * 3 + (size_t)a];
        }
        for (a = 0; a < 3; ++a) total[a] += row[a];
    }
    if (total[0] > FLT_MAX || total[1] > FLT_MAX || total[2] > FLT_MAX)
        return gim__fail(&env, GIM_ERROR_OUT_OF_RANGE, fn, "the RSM's total flux exceeds the float range");
    /* each VPL's texel: its slot's, or the one its previous VPL stands on now */
    texel = (size_t *)gim__alloc_array(&env, count, sizeof *texel + 1u);   /* then a kept flag each */
    if (!texel) return gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, fn, "%u VPL texels", (unsigned)count);
    kept = (unsigned char *)(texel + count);
    for (i = 0; i < count; ++i) {
        long k = -1;
        gim__rsm_vpl_texel(i, count, sequence, rsm->width, rsm->height, offsets, &x, &y);
        if (desc->previous)
            k = gim__rsm_vpl_follow(rsm, desc->previous + i, desc->view_proj.m, x, y,
                                    gim__rsm_vpl_radius(i, count, rsm->width, rsm->height));
        texel[i] = k >= 0 ? (size_t)k : (size_t)y * rsm->width + x;
        kept[i] = (unsigned char)(k >= 0);
    }
    /* S: blocks of GIM_RSM_VPL_BLOCK VPLs, then the blocks */
    for (i = 0; i < count; i += GIM_RSM_VPL_BLOCK) {
        double block[3] = {0.0, 0.0, 0.0};
        uint32_t e = count - i < GIM_RSM_VPL_BLOCK ? count : i + GIM_RSM_VPL_BLOCK, k;
        for (k = i; k < e; ++k)
            if (gim__rsm_vpl_lit(rsm, texel[k]))
                for (a = 0; a < 3; ++a) block[a] += rsm->flux[texel[k] * 3 + (size_t)a];
        for (a = 0; a < 3; ++a) sampled[a] += block[a];
    }
    for (a = 0; a < 3; ++a) scale[a] = sampled[a] > 0.0 ? total[a] / sampled[a] : 0.0;
    ts = total[0] + total[1] + total[2];
    ss = sampled[0] + sampled[1] + sampled[2];
    area_scale = ss > 0.0 ? ts / ss : 0.0;
    for (i = 0; i < count; ++i) {
        size_t t = texel[i];
        int lit = gim__rsm_vpl_lit(rsm, t);
        const gim_vpl *p = kept[i] ? desc->previous + i : NULL;
        if (area) {
            float at = rsm->area && lit ? rsm->area[t] : 0.0f;
            double av = at > 0.0f && at <= FLT_MAX ? (double)at * area_scale : 0.0;
            area[i] = (float)(av < FLT_MAX ? av : FLT_MAX);
        }
        {   /* position and normal copied where finite (an unlit texel may hold anything); a kept VPL's its own */
            int pok = gim__all_finite(rsm->position + t * 3, 3), nok = gim__all_finite(rsm->normal + t * 3, 3);
            for (a = 0; a < 3; ++a) {
                double f = lit ? (double)rsm->flux[t * 3 + (size_t)a] * scale[a] : 0.0;
                positions[(size_t)i * 3 + (size_t)a] = p ? p->position[a] : pok ? rsm->position[t * 3 + (size_t)a] : 0.0f;
                normals[(size_t)i * 3 + (size_t)a] = p ? p->normal[a] : nok ? rsm->normal[t * 3 + (size_t)a] : 0.0f;
                flux[(size_t)i * 3 + (size_t)a] = (float)(f < FLT_MAX ? f : FLT_MAX); /* a share of T <= T: never clamps */
            }
        }
    }
    if (desc->kept) memcpy(desc->kept, kept, count);
    gim__free(&env, texel);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_vpls_from_vals(const gim_val *vals, uint32_t count, const gim_vpl *previous, gim_vpl *out,
                                         gim_env env) {
    static const char fn[] = "gim_vpls_from_vals";
    uint32_t i;
    int a;
    if (count && (!vals || !out)) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "vals or out is NULL");
    if (count && ((const void *)vals == (const void *)out || previous == out))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "out is vals or previous");
    for (i = 0; i < count; ++i) {
        const gim_val *v = vals + i;
        gim_vpl *p = out + i;
        float w = v->weight;
        memset(p, 0, sizeof *p);
        if (w == 0.0f) continue;   /* invalid (gim_vals_gather_twin zeroes it), or below the floats */
        for (a = 0; a < 3; ++a) {
            p->position[a] = v->position[a];
            p->normal[a] = v->normal[a];
            p->flux[a] = v->flux[a] * w;
        }
        p->lit = 1.0f;
        p->area = v->area * w;
        if (previous && previous[i].lit == 1.0f && !memcmp(previous[i].position, p->position, sizeof p->position) &&
            !memcmp(previous[i].normal, p->normal, sizeof p->normal))
            p->kept = 1.0f;   /* the same point: its map still holds */
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_caches_to_world(const gim_cache *in, uint32_t count, gim_mat4 model, gim_cache *out,
                                          gim_env env) {
    static const char fn[] = "gim_caches_to_world";
    gim_mat4 nm;
    double det;
    const float *m = model.m;
    uint32_t i;
    if (count && (!in || !out)) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "in or out is NULL");
    det = (double)m[0] * ((double)m[5] * m[10] - (double)m[9] * m[6]) -
          (double)m[4] * ((double)m[1] * m[10] - (double)m[9] * m[2]) +
          (double)m[8] * ((double)m[1] * m[6] - (double)m[5] * m[2]);
    if (!gim__mat4_isfinite(model) || !(fabs(det) > 0.0) || !gim_mat4_invert(model, &nm))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "model is not finite or its 3x3 is singular");
    nm = gim__mat4_normal(model);
    for (i = 0; i < count; ++i) {
        gim_cache c = in[i];
        gim_vec3 p = gim_mat4_point(model, gim_v3(c.position[0], c.position[1], c.position[2]));
        gim_vec3 n = gim__mat4_dir(nm, gim_v3(c.normal[0], c.normal[1], c.normal[2]));
        double len = sqrt((double)n.x * n.x + (double)n.y * n.y + (double)n.z * n.z);
        double len0 = sqrt((double)c.normal[0] * c.normal[0] + (double)c.normal[1] * c.normal[1] +
                           (double)c.normal[2] * c.normal[2]);
        double area = (double)c.area * fabs(det) * len / len0;   /* det M M^-T maps area vectors */
        if (!gim__v3_isfinite(p) || !(len > 0.0) || !(len0 > 0.0) || !(area < (double)FLT_MAX) || !(area >= 0.0))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "cache %u: not finite in world space", i);
        c.position[0] = p.x; c.position[1] = p.y; c.position[2] = p.z;
        c.normal[0] = (float)(n.x / len); c.normal[1] = (float)(n.y / len); c.normal[2] = (float)(n.z / len);
        c.area = (float)area;
        out[i] = c;
    }
    return GIM_OK;
}

/* Ericson 2005 (Real-Time Collision Detection, 5.1.5): the point of triangle abc nearest to p,
   as barycentrics (u of b, v of c), by the Voronoi region p falls in. */
static void gim__closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double *u,
                                     double *v) {
    double ab[3], ac[3], ap[3], bp[3], cp[3], d1, d2, d3, d4, d5, d6, va, vb, vc, den;
    int k;
    for (k = 0; k < 3; ++k) { ab[k] = b[k] - a[k]; ac[k] = c[k] - a[k]; ap[k] = p[k] - a[k]; bp[k] = p[k] - b[k]; cp[k] = p[k] - c[k]; }
    d1 = ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2];
    d2 = ac[0] * ap[0] + ac[1] * ap[1] + ac[2] * ap[2];
    if (d1 <= 0.0 && d2 <= 0.0) { *u = 0.0; *v = 0.0; return; }
    d3 = ab[0] * bp[0] + ab[1] * bp[1] + ab[2] * bp[2];
    d4 = ac[0] * bp[0] + ac[1] * bp[1] + ac[2] * bp[2];
    if (d3 >= 0.0 && d4 <= d3) { *u = 1.0; *v = 0.0; return; }
    vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) { *u = d1 / (d1 - d3); *v = 0.0; return; }
    d5 = ab[0] * cp[0] + ab[1] * cp[1] + ab[2] * cp[2];
    d6 = ac[0] * cp[0] + ac[1] * cp[1] + ac[2] * cp[2];
    if (d6 >= 0.0 && d5 <= d6) { *u = 0.0; *v = 1.0; return; }
    vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) { *u = 0.0; *v = d2 / (d2 - d6); return; }
    va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        *v = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        *u = 1.0 - *v;
        return;
    }
    den = 1.0 / (va + vb + vc);
    *u = vb * den;
    *v = vc * den;
}

/* One triangle of gim_cache_bind: its vertices as doubles, its indices. */
static void gim__bind_triangle(const gim_mesh_data *mesh, uint32_t pstride, uint32_t t, uint32_t vi[3], double q[3][3]) {
    int k, j;
    for (k = 0; k < 3; ++k) {
        const float *x;
        vi[k] = gim__cg_index(mesh, (size_t)t * 3u + (uint32_t)k);
        x = (const float *)(const void *)((const char *)mesh->positions + (size_t)vi[k] * pstride);
        for (j = 0; j < 3; ++j) q[k][j] = x[j];
    }
}

/* The nearest triangle through a uniform grid of cells holding the triangles whose bounds
   overlap them (about one cell per triangle), searched in growing shells of cells around the
   cache's: after shell r every triangle not yet met lies at least r cell sides away, so the
   search stops once the best distance is within that. A tie goes to the lower triangle index,
   so the result is what testing every triangle in order gives (brute force: 5.1 s for 20000
   triangles and 5288 caches; a grid does it in tens of ms). */
GIMANY_DEF gim_result gim_cache_bind(const gim_mesh_data *mesh, const gim_cache *caches, uint32_t count,
                                     gim_cache_binding *out, gim_env env) {
    static const char fn[] = "gim_cache_bind";
    uint32_t pstride, i, t, tris, cells, *start = NULL, *list = NULL, *seen = NULL, *fill = NULL, usable = 0;
    int32_t dims[3];
    double lo[3], hi[3], h, total = 0.0;
    gim_result r = GIM_OK;
    int k;
    if (!mesh || !mesh->positions || !mesh->indices || (count && (!caches || !out)))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "mesh, its positions and indices, caches and out are required");
    if (mesh->index_count % 3u != 0 || mesh->index_count == 0 || mesh->vertex_count == 0)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "%u indices, %u vertices", (unsigned)mesh->index_count,
                         (unsigned)mesh->vertex_count);
    pstride = mesh->position_stride ? mesh->position_stride : 12u;
    tris = mesh->index_count / 3u;
    for (i = 0; i < mesh->index_count; ++i)
        if (gim__cg_index(mesh, i) >= mesh->vertex_count)
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "index %u out of range", (unsigned)i);
    for (k = 0; k < 3; ++k) { lo[k] = DBL_MAX; hi[k] = -DBL_MAX; }
    for (i = 0; i < mesh->vertex_count; ++i) {
        const float *x = (const float *)(const void *)((const char *)mesh->positions + (size_t)i * pstride);
        if (!gim__all_finite(x, 3))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "position %u is not finite", (unsigned)i);
        for (k = 0; k < 3; ++k) {
            if (x[k] < lo[k]) lo[k] = x[k];
            if (x[k] > hi[k]) hi[k] = x[k];
        }
    }
    for (i = 0; i < count; ++i)
        if (!gim__all_finite(caches[i].position, 3) || !gim__all_finite(caches[i].normal, 3))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "cache %u is not finite", (unsigned)i);
    /* the grid: a cube side giving about one cell per triangle over the bounds */
    for (k = 0; k < 3; ++k) total += hi[k] - lo[k];
    h = total / 3.0 / cbrt((double)tris) + 1e-30;
    for (;;) {
        double c = 1.0;
        for (k = 0; k < 3; ++k) {
            double n = floor((hi[k] - lo[k]) / h) + 1.0;
            dims[k] = n > 1024.0 ? 1024 : (int32_t)n;
            c *= dims[k];
        }
        if (c <= 4.0 * tris + 64.0 && (double)dims[0] * h >= hi[0] - lo[0] && (double)dims[1] * h >= hi[1] - lo[1] &&
            (double)dims[2] * h >= hi[2] - lo[2])
            break;
        h *= 1.5;   /* a flat or thin mesh: fewer, larger cells */
    }
    cells = (uint32_t)dims[0] * (uint32_t)dims[1] * (uint32_t)dims[2];
    start = (uint32_t *)gim__alloc_array(&env, (size_t)cells + 1u, sizeof(uint32_t));
    fill = (uint32_t *)gim__alloc_array(&env, cells, sizeof(uint32_t));
    seen = (uint32_t *)gim__alloc_array(&env, tris, sizeof(uint32_t));
    if (!start || !fill || !seen) {
        r = gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, fn, "a grid of %u cells", (unsigned)cells);
        goto done;
    }
    memset(start, 0, ((size_t)cells + 1u) * sizeof(uint32_t));
    memset(fill, 0, (size_t)cells * sizeof(uint32_t));
    memset(seen, 0, (size_t)tris * sizeof(uint32_t));   /* per triangle: the last cache that tested it, + 1 */
    for (k = 0; k < 2; ++k) {   /* count the entries of each cell, then place them */
        for (t = 0; t < tris; ++t) {
            double q[3][3], e1[3], e2[3], f[3];
            uint32_t vi[3];
            int32_t c0[3], c1[3], x, y, z, j;
            gim__bind_triangle(mesh, pstride, t, vi, q);
            for (j = 0; j < 3; ++j) { e1[j] = q[1][j] - q[0][j]; e2[j] = q[2][j] - q[0][j]; }
            f[0] = e1[1] * e2[2] - e1[2] * e2[1];
            f[1] = e1[2] * e2[0] - e1[0] * e2[2];
            f[2] = e1[0] * e2[1] - e1[1] * e2[0];
            if (!(f[0] * f[0] + f[1] * f[1] + f[2] * f[2] > 0.0)) continue;   /* degenerate: no frame to follow */
            if (k == 0) ++usable;
            for (j = 0; j < 3; ++j) {
                double a = q[0][j] < q[1][j] ? q[0][j] : q[1][j], b = q[0][j] > q[1][j] ? q[0][j] : q[1][j];
                a = a < q[2][j] ? a : q[2][j];
                b = b > q[2][j] ? b : q[2][j];
                c0[j] = (int32_t)floor((a - lo[j]) / h);
                c1[j] = (int32_t)floor((b - lo[j]) / h);
                c0[j] = c0[j] < 0 ? 0 : c0[j] >= dims[j] ? dims[j] - 1 : c0[j];
                c1[j] = c1[j] < 0 ? 0 : c1[j] >= dims[j] ? dims[j] - 1 : c1[j];
            }
            for (z = c0[2]; z <= c1[2]; ++z)
                for (y = c0[1]; y <= c1[1]; ++y)
                    for (x = c0[0]; x <= c1[0]; ++x) {
                        uint32_t c = ((uint32_t)z * (uint32_t)dims[1] + (uint32_t)y) * (uint32_t)dims[0] + (uint32_t)x;
                        if (k == 0) ++start[c + 1u];
                        else list[start[c] + fill[c]++] = t;
                    }
        }
        if (k == 0) {
            uint64_t sum = 0;
            if (usable == 0) {
                r = gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "the mesh has no non-degenerate triangle");
                goto done;
            }
            for (i = 0; i < cells; ++i) { sum += start[i + 1u]; start[i + 1u] = (uint32_t)sum; }
            if (sum > 0xFFFFFFFFu) {
                r = gim__fail(&env, GIM_ERROR_OUT_OF_RANGE, fn, "%llu grid entries", (unsigned long long)sum);
                goto done;
            }
            list = (uint32_t *)gim__alloc_array(&env, sum ? (size_t)sum : 1u, sizeof(uint32_t));
            if (!list) {
                r = gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, fn, "%llu grid entries", (unsigned long long)sum);
                goto done;
            }
        }
    }
    for (i = 0; i < count; ++i) {
        const gim_cache *c = &caches[i];
        double p[3], best = DBL_MAX, n[3], out2 = 0.0;
        uint32_t best_t = 0xFFFFFFFFu;
        int32_t pc[3], rr, rmax = 0;
        gim_cache_binding b;
        memset(&b, 0, sizeof b);
        for (k = 0; k < 3; ++k) {
            p[k] = c->position[k];
            n[k] = c->normal[k];
            pc[k] = (int32_t)floor((p[k] - lo[k]) / h);
            pc[k] = pc[k] < 0 ? 0 : pc[k] >= dims[k] ? dims[k] - 1 : pc[k];
            if (dims[k] > rmax) rmax = dims[k];
        }
        for (k = 0; k < 3; ++k) {   /* p's squared distance from the grid's box */
            double g = p[k] < lo[k] ? lo[k] - p[k] : p[k] > lo[k] + dims[k] * h ? p[k] - lo[k] - dims[k] * h : 0.0;
            out2 += g * g;
        }
        for (rr = 0; rr <= rmax; ++rr) {
            int32_t x, y, z, z0, z1, y0, y1, x0, x1;
            /* a triangle not yet met overlaps no cell within rr - 1 of pc, so it is at least
               (rr - 1) h from p', p's nearest point in the grid (in cell pc), and |p - x|^2 >=
               |p - p'|^2 + |p' - x|^2 for x in the (convex) grid */
            double reach = (rr - 1) * h;
            if (best_t != 0xFFFFFFFFu && reach > 0.0 && best < out2 + reach * reach) break;
            z0 = pc[2] - rr < 0 ? 0 : pc[2] - rr; z1 = pc[2] + rr >= dims[2] ? dims[2] - 1 : pc[2] + rr;
            y0 = pc[1] - rr < 0 ? 0 : pc[1] - rr; y1 = pc[1] + rr >= dims[1] ? dims[1] - 1 : pc[1] + rr;
            x0 = pc[0] - rr < 0 ? 0 : pc[0] - rr; x1 = pc[0] + rr >= dims[0] ? dims[0] - 1 : pc[0] + rr;
            for (z = z0; z <= z1; ++z)
                for (y = y0; y <= y1; ++y) {
                    /* the shell only: a row inside it holds two cells of it, at x = pc +- rr */
                    int32_t step = (z == pc[2] - rr || z == pc[2] + rr || y == pc[1] - rr || y == pc[1] + rr) ? 1 : 2 * rr;
                    for (x = step == 1 ? x0 : pc[0] - rr; x <= x1; x += step > 0 ? step : 1) {
                        uint32_t cell, e;
                        if (x < x0) continue;
                        cell = ((uint32_t)z * (uint32_t)dims[1] + (uint32_t)y) * (uint32_t)dims[0] + (uint32_t)x;
                        for (e = start[cell]; e < start[cell + 1u]; ++e) {
                            double q[3][3], u, v, d2 = 0.0;
                            uint32_t vi[3];
                            t = list[e];
                            if (seen[t] == i + 1u) continue;
                            seen[t] = i + 1u;
                            gim__bind_triangle(mesh, pstride, t, vi, q);
                            gim__closest_on_triangle(p, q[0], q[1], q[2], &u, &v);
                            for (k = 0; k < 3; ++k) {
                                double d = p[k] - ((1.0 - u - v) * q[0][k] + u * q[1][k] + v * q[2][k]);
                                d2 += d * d;
                            }
                            if (d2 < best || (d2 == best && t < best_t)) { best = d2; best_t = t; }
                        }
                    }
                }
        }
        {   /* the binding to the nearest triangle */
            double q[3][3], e1[3], e2[3], f[3], len, u, v, foot = 0.0;
            uint32_t vi[3];
            gim__bind_triangle(mesh, pstride, best_t, vi, q);
            for (k = 0; k < 3; ++k) { e1[k] = q[1][k] - q[0][k]; e2[k] = q[2][k] - q[0][k]; }
            f[0] = e1[1] * e2[2] - e1[2] * e2[1];
            f[1] = e1[2] * e2[0] - e1[0] * e2[2];
            f[2] = e1[0] * e2[1] - e1[1] * e2[0];
            len = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
            for (k = 0; k < 3; ++k) f[k] /= len;
            gim__closest_on_triangle(p, q[0], q[1], q[2], &u, &v);
            for (k = 0; k < 3; ++k) foot += (p[k] - ((1.0 - u - v) * q[0][k] + u * q[1][k] + v * q[2][k])) * f[k];
            b.vertex[0] = vi[0]; b.vertex[1] = vi[1]; b.vertex[2] = vi[2];
            b.u = (float)u;
            b.v = (float)v;
            b.h = (float)foot;   /* the part of the offset off the plane; an in-plane part (a cache past an edge) is dropped */
            b.area2 = (float)len;
            b.frame[0] = (float)(n[0] * e1[0] + n[1] * e1[1] + n[2] * e1[2]);
            b.frame[1] = (float)(n[0] * e2[0] + n[1] * e2[1] + n[2] * e2[2]);
            b.frame[2] = (float)(n[0] * f[0] + n[1] * f[1] + n[2] * f[2]);
        }
        out[i] = b;
    }
done:
    gim__free(&env, start);
    gim__free(&env, fill);
    gim__free(&env, list);
    gim__free(&env, seen);
    return r;
}

/* In float, operation for operation as caches_follow.comp, so the twin and the pass agree to
   rounding. */
GIMANY_DEF gim_result gim_caches_follow_twin(const gim_follow_desc *desc, gim_cache *out) {
    static const char fn[] = "gim_caches_follow_twin";
    const gim_cache *rest;
    const gim_cache_binding *bind;
    const float *positions;
    uint32_t i, count, vertex_count;
    gim_env env;
    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc is NULL");
    rest = desc->rest; bind = desc->bind; count = desc->count; positions = desc->positions;
    vertex_count = desc->vertex_count; env = desc->env;
    if (count && (!rest || !bind || !positions || !out))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "rest, bind, positions and out are required");
    for (i = 0; i < count; ++i) {
        const gim_cache_binding *b = &bind[i];
        gim_vec3 a, pb, pc, e1, e2, cr, n, m, p;
        float len, w;
        gim_cache c = rest[i];
        if (b->vertex[0] >= vertex_count || b->vertex[1] >= vertex_count || b->vertex[2] >= vertex_count)
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "binding %u names a vertex past %u", (unsigned)i,
                             (unsigned)vertex_count);
        a = gim_v3(positions[b->vertex[0] * 3u], positions[b->vertex[0] * 3u + 1u], positions[b->vertex[0] * 3u + 2u]);
        pb = gim_v3(positions[b->vertex[1] * 3u], positions[b->vertex[1] * 3u + 1u], positions[b->vertex[1] * 3u + 2u]);
        pc = gim_v3(positions[b->vertex[2] * 3u], positions[b->vertex[2] * 3u + 1u], positions[b->vertex[2] * 3u + 2u]);
        e1 = gim__v3_sub(pb, a);
        e2 = gim__v3_sub(pc, a);
        cr = gim__v3_cross(e1, e2);
        len = sqrtf(cr.x * cr.x + cr.y * cr.y + cr.z * cr.z);
        w = 1.0f - b->u - b->v;
        n = len > 0.0f ? gim_v3(cr.x / len, cr.y / len, cr.z / len) : gim_v3(0.0f, 0.0f, 0.0f);
        p = gim_v3(w * a.x + b->u * pb.x + b->v * pc.x + b->h * n.x, w * a.y + b->u * pb.y + b->v * pc.y + b->h * n.y,
                   w * a.z + b->u * pb.z + b->v * pc.z + b->h * n.z);
        /* M^-T n through the dual basis of (e1, e2, n'): each term a cross product, det dropped */
        m = gim__v3_add(gim__v3_add(gim__v3_scale(gim__v3_cross(e2, n), b->frame[0]), gim__v3_scale(gim__v3_cross(n, e1), b->frame[1])),
                       gim__v3_scale(cr, b->frame[2]));
        {
            float ml = sqrtf(m.x * m.x + m.y * m.y + m.z * m.z);
            if (len > 0.0f && ml > 0.0f) {
                c.normal[0] = m.x / ml; c.normal[1] = m.y / ml; c.normal[2] = m.z / ml;
            }   /* else: a collapsed triangle, the rest normal */
        }
        c.position[0] = p.x; c.position[1] = p.y; c.position[2] = p.z;
        c.area = b->area2 > 0.0f ? rest[i].area * (len / b->area2) : 0.0f;
        if (!gim__all_finite(c.position, 3) || !gim__all_finite(c.normal, 3) || !gim__isfinitef(c.area))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "cache %u: not finite (non-finite positions?)", (unsigned)i);
        out[i] = c;
    }
    return GIM_OK;
}

/* The clusters' VALs and paraboloid maps (see the declaration): one independent loop per
   cluster over the VPLs in index order, as the GPU pass (clusters.comp) runs it. */
GIMANY_DEF gim_result gim_cluster_paraboloids_twin(const gim_cluster_desc *desc, gim_paraboloid *out) {
    static const char fn[] = "gim_cluster_paraboloids_twin";
    const gim_vpl *vpls;
    const uint32_t *cluster;
    const float *centres, *normals;
    uint32_t i, m, vpl_count, cluster_count;
    float scene_scale;
    gim_env env;
    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, fn, "desc is NULL");
    vpls = desc->vpls; vpl_count = desc->vpl_count; cluster = desc->cluster; centres = desc->centres;
    normals = desc->normals; cluster_count = desc->cluster_count; scene_scale = desc->scene_scale; env = desc->env;
    if (!vpls || !cluster || !centres || !normals || !out)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "vpls, cluster, centres, normals and out are required");
    if (vpl_count == 0 || cluster_count == 0)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "vpl_count (%u) and cluster_count (%u) must be > 0",
                         (unsigned)vpl_count, (unsigned)cluster_count);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale %g must be finite and > 0", (double)scene_scale);
    for (m = 0; m < cluster_count; ++m) {
        const float *n = normals + 3 * m;
        if (!gim__all_finite(centres + 3 * m, 3) || !gim__all_finite(n, 3) || n[0] * n[0] + n[1] * n[1] + n[2] * n[2] == 0.0f)
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "cluster %u: centre or normal not finite, or a zero normal",
                             (unsigned)m);
    }
    for (i = 0; i < vpl_count; ++i) {
        const gim_vpl *v = vpls + i;
        if (cluster[i] >= cluster_count)
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u: cluster %u >= %u", (unsigned)i,
                             (unsigned)cluster[i], (unsigned)cluster_count);
        if (!gim__all_finite(v->position, 3) || !gim__all_finite(v->flux, 3) || v->flux[0] < 0.0f || v->flux[1] < 0.0f ||
            v->flux[2] < 0.0f)
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u: position or flux not finite, or negative flux",
                             (unsigned)i);
    }
    for (m = 0; m < cluster_count; ++m) {
        gim_paraboloid *p = out + m;
        gim_vec3 n = gim_v3_normalize(gim_v3(normals[3 * m], normals[3 * m + 1], normals[3 * m + 2])), t, b;
        double c[3], f[3] = {0.0, 0.0, 0.0}, w[2] = {0.0, 0.0}, s1[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
        double s2[2][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}};   /* [weighted, plain] x (ss, tt, st) */
        double area = 0.0, det;
        int k, plain;
        float lift = 1e-4f * scene_scale, near_skip = 1e-2f * scene_scale;
        gim__basis(n, &t, &b);
        for (k = 0; k < 3; ++k) c[k] = centres[3 * m + (uint32_t)k];
        for (i = 0; i < vpl_count; ++i) {
            const gim_vpl *v = vpls + i;
            double d[3], ps, pt, wi;
            if (cluster[i] != m) continue;
            for (k = 0; k < 3; ++k) d[k] = (double)v->position[k] - c[k];
            ps = d[0] * t.x + d[1] * t.y + d[2] * t.z;
            pt = d[0] * b.x + d[1] * b.y + d[2] * b.z;
            wi = ((double)v->flux[0] + v->flux[1] + v->flux[2]) / 3.0;   /* gim_kmeans' weight */
            for (k = 0; k < 3; ++k) f[k] += v->flux[k];
            w[0] += wi; w[1] += 1.0;
            s1[0][0] += wi * ps; s1[0][1] += wi * pt;
            s1[1][0] += ps;      s1[1][1] += pt;
            s2[0][0] += wi * ps * ps; s2[0][1] += wi * pt * pt; s2[0][2] += wi * ps * pt;
            s2[1][0] += ps * ps;      s2[1][1] += pt * pt;      s2[1][2] += ps * pt;
        }
        plain = !(w[0] > 0.0);
        if (w[1] > 0.0) {   /* covariance of the projected positions; area of the uniform rectangle */
            int q = plain ? 1 : 0;
            double W = w[q], ms = s1[q][0] / W, mt = s1[q][1] / W;
            double css = s2[q][0] / W - ms * ms, ctt = s2[q][1] / W - mt * mt, cst = s2[q][2] / W - ms * mt;
            det = css * ctt - cst * cst;
            area = det > 0.0 ? 12.0 * sqrt(det) : 0.0;
        }
        p->origin[0] = centres[3 * m] + lift * n.x;
        p->origin[1] = centres[3 * m + 1] + lift * n.y;
        p->origin[2] = centres[3 * m + 2] + lift * n.z;
        p->normal[0] = n.x; p->normal[1] = n.y; p->normal[2] = n.z;
        p->size = (float)sqrt(area);
        p->near_distance = 0.5f * p->size > lift ? 0.5f * p->size : lift;
        for (k = 0; k < 3; ++k) p->flux[k] = f[k] < (double)FLT_MAX ? (float)f[k] : FLT_MAX;
        p->attribute_near = near_skip < p->near_distance ? near_skip : p->near_distance;
    }
    return GIM_OK;
}

/* twins of the scene passes: RSM texel, G-buffer, view samples ---------------------------- */

/* A light the runtime and the twins accept; index names it in the message. */
static gim_result gim__light_check(const gim_light *l, const gim_env *env, const char *where, uint32_t index) {
    if (l->type != GIM_LIGHT_DEFAULT && l->type != GIM_LIGHT_DIRECTIONAL && l->type != GIM_LIGHT_SPOT &&
        l->type != GIM_LIGHT_POINT)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: unknown type %d", (unsigned)index, (int)l->type);
    if (!gim__all_finite(l->color, 3) || l->color[0] < 0.0f || l->color[1] < 0.0f || l->color[2] < 0.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: color must be finite and >= 0", (unsigned)index);
    if (l->type != GIM_LIGHT_POINT && (!gim__v3_isfinite(l->direction) || gim__v3_length(gim_v3_normalize(l->direction)) == 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: direction must be finite and non-zero",
                         (unsigned)index);
    if (l->rsm_size > 16384u)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: rsm_size %u above 16384", (unsigned)index,
                         (unsigned)l->rsm_size);
    if (l->type == GIM_LIGHT_SPOT || l->type == GIM_LIGHT_POINT) {
        if (!gim__isfinitef(l->intensity) || l->intensity < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: intensity %g must be finite and >= 0",
                             (unsigned)index, (double)l->intensity);
        if (!gim__v3_isfinite(l->position))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: position is not finite", (unsigned)index);
        if (l->type == GIM_LIGHT_SPOT && !(l->cone_angle > 0.0f && l->cone_angle <= 1.5f))
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
    float p = l->type == GIM_LIGHT_SPOT || l->type == GIM_LIGHT_POINT ? l->intensity : l->irradiance;
    for (i = 0; i < 3; ++i) out[i] = (white ? 1.0f : l->color[i]) * p;
}

/* World axis least aligned with d: an up vector look_at cannot fold onto d. */
static gim_vec3 gim__up_for(gim_vec3 d) {
    float ax = fabsf(d.x), ay = fabsf(d.y), az = fabsf(d.z);
    if (ay <= ax && ay <= az) return gim_v3(0.0f, 1.0f, 0.0f);
    if (az <= ax) return gim_v3(0.0f, 0.0f, 1.0f);
    return gim_v3(1.0f, 0.0f, 0.0f);
}

/* gim__up_for with memory (*axis: 1 x, 2 y, 3 z, 0 none yet; *last: the direction it was kept
   for; both written): the axis of the light's last camera while the unit d stays within 10
   degrees of that camera's direction (the same light, moving) and more than acos 0.8 (37
   degrees) from the axis. gim__up_for alone turns the map by 90 degrees where two of d's
   components cross, so a light moving through such a direction would move every texel, every
   VAL and every VPL at once (a frame of flicker, and no VPL to follow); with the memory the map
   turns only with the light, and a light set anew (another scene) gets gim__up_for's axis. */
static gim_vec3 gim__up_kept(gim_vec3 d, int *axis, gim_vec3 *last) {
    gim_vec3 u;
    float c = *axis == 1 ? d.x : *axis == 2 ? d.y : d.z;
    int near = d.x * last->x + d.y * last->y + d.z * last->z > 0.985f;
    *last = d;
    if (*axis >= 1 && *axis <= 3 && near && fabsf(c) < 0.8f)
        return gim_v3(*axis == 1 ? 1.0f : 0.0f, *axis == 2 ? 1.0f : 0.0f, *axis == 3 ? 1.0f : 0.0f);
    u = gim__up_for(d);
    *axis = u.x > 0.0f ? 1 : u.y > 0.0f ? 2 : 3;
    return u;
}

/* look_at(eye, eye + dir, up) with the rotation taken from dir alone and the translation in
   double: a float eye + dir rounds to the eye's ulp, which far from the origin turns the
   light's axis by ulp(|eye|) / |dir| (1e-3 rad at 1e4 units, the whole axis past 1e7). */
static gim_mat4 gim__look_along(const double eye[3], gim_vec3 dir, gim_vec3 up) {
    gim_mat4 v = gim_mat4_look_at(gim_v3(0.0f, 0.0f, 0.0f), dir, up);
    int r;
    for (r = 0; r < 3; ++r) /* row r of the rotation dotted with -eye */
        v.m[12 + r] = (float)-((double)v.m[r] * eye[0] + (double)v.m[4 + r] * eye[1] + (double)v.m[8 + r] * eye[2]);
    return v;
}

GIMANY_DEF gim_result gim_point_light_faces(const gim_light *point, gim_light faces[6]) {
    static const char where[] = "gim_point_light_faces";
    gim_result r;
    int k;
    if (!point || !faces) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL argument");
    if (point->type != GIM_LIGHT_POINT) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "not a POINT light");
    r = gim__light_check(point, NULL, where, 0);
    if (r != GIM_OK) return r;
    for (k = 0; k < 6; ++k) {
        float a[3] = {0.0f, 0.0f, 0.0f};
        a[k / 2] = (k & 1) ? -1.0f : 1.0f;
        faces[k] = *point;
        faces[k].type = GIM_LIGHT_SPOT;
        faces[k].direction = gim_v3(a[0], a[1], a[2]);
        faces[k].cone_angle = 0.78539816f;   /* pi / 4: a 90 degree square frustum, the up vector a world axis */
        faces[k].square_cone = 1;
        faces[k].extent = 0.0f;
        faces[k].fit_view = 0;
    }
    return GIM_OK;
}

static gim_result gim__light_camera_kept(const gim_light *light, const float bmin[3], const float bmax[3],
                                        gim_mat4 *view, gim_mat4 *proj, int *up_axis, gim_vec3 *up_dir);
GIMANY_DEF gim_result gim_light_camera(const gim_light *light, const float bmin[3], const float bmax[3],
                                       gim_mat4 *view, gim_mat4 *proj) {
    int axis = 0;
    gim_vec3 dir = gim_v3(0.0f, 0.0f, 0.0f);
    return gim__light_camera_kept(light, bmin, bmax, view, proj, &axis, &dir);
}

/* gim_light_camera with the up axis of the light's last camera (gim__up_kept; *up_axis 0: none;
   *up_dir the direction it was kept for). */
static gim_result gim__light_camera_kept(const gim_light *light, const float bmin[3], const float bmax[3],
                                        gim_mat4 *view, gim_mat4 *proj, int *up_axis, gim_vec3 *up_dir) {
    static const char where[] = "gim_light_camera";
    double c[3], radius = 0.0;
    gim_result r;
    int i;
    if (!light || !bmin || !bmax || !view || !proj)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL argument");
    r = gim__light_check(light, NULL, where, 0);
    if (r != GIM_OK) return r;
    if (light->type == GIM_LIGHT_POINT)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "a POINT light has six cameras: those of gim_point_light_faces");
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
        /* a lit point at distance >= box within the cone has view depth >= box cos(cone); a
           square cone's widest direction is its corner's, at tan^2 = 2 tan^2(cone) */
        far_d *= 1.01;
        if (light->square_cone) {
            double t = tan((double)light->cone_angle);
            near_d = sqrt(box) / sqrt(1.0 + 2.0 * t * t) * 0.99;
        } else {
            near_d = sqrt(box) * cos((double)light->cone_angle) * 0.99;
        }
        if (near_d < far_d * 1e-4) near_d = far_d * 1e-4;
        double eye[3];
        eye[0] = p.x; eye[1] = p.y; eye[2] = p.z;
        *view = gim__look_along(eye, d, gim__up_kept(d, up_axis, up_dir));
        *proj = gim_mat4_perspective(2.0f * light->cone_angle, 1.0f, (float)near_d, (float)far_d);
    } else {
        gim_vec3 l = gim_v3_normalize(light->direction);
        float e = light->extent, R = (float)radius;
        double eye[3], lo[2] = {0.0, 0.0}, hi[2] = {0.0, 0.0};
        int k;
        /* the eye 2R out along the light: the bounds' sphere lies between depths R and 3R */
        eye[0] = c[0] + 2.0 * R * l.x; eye[1] = c[1] + 2.0 * R * l.y; eye[2] = c[2] + 2.0 * R * l.z;
        *view = gim__look_along(eye, gim__v3_scale(l, -1.0f), gim__up_kept(l, up_axis, up_dir));
        if (e > 0.0f) {
            *proj = gim_mat4_ortho(-e, e, -e, e, 0.5f * R, 3.5f * R);
        } else {
            /* the window is the bounds' shadow on the light's plane, a rectangle: the sphere's
               square left a long scene's texels mostly empty (the street: 22% of them lit) */
            for (k = 0; k < 8; ++k) {
                double x = (k & 1) ? bmax[0] : bmin[0], y = (k & 2) ? bmax[1] : bmin[1], z = (k & 4) ? bmax[2] : bmin[2];
                double u = view->m[0] * x + view->m[4] * y + view->m[8] * z + view->m[12];
                double v = view->m[1] * x + view->m[5] * y + view->m[9] * z + view->m[13];
                if (k == 0 || u < lo[0]) lo[0] = u;
                if (k == 0 || u > hi[0]) hi[0] = u;
                if (k == 0 || v < lo[1]) lo[1] = v;
                if (k == 0 || v > hi[1]) hi[1] = v;
            }
            for (k = 0; k < 2; ++k) {   /* a margin of 0.1% of the sphere; a flat scene edge-on stays 0.1% wide */
                double m = 0.5 * (lo[k] + hi[k]), h = 0.5 * (hi[k] - lo[k]) + 1e-3 * R;
                lo[k] = m - h;
                hi[k] = m + h;
            }
            *proj = gim_mat4_ortho((float)lo[0], (float)hi[0], (float)lo[1], (float)hi[1], 0.5f * R, 3.5f * R);
        }
    }
    if (!gim__mat4_isfinite(*view) || !gim__mat4_isfinite(*proj))
        return gim__fail(NULL, GIM_ERROR_OUT_OF_RANGE, where, "the light's camera is not finite");
    return GIM_OK;
}

/* m * (x, y, z, w) in double. */
static void gim__mat4_apply_d(const gim_mat4 *m, const double v[4], double out[4]) {
    int r;
    for (r = 0; r < 4; ++r)
        out[r] = m->m[r] * v[0] + m->m[4 + r] * v[1] + m->m[8 + r] * v[2] + m->m[12 + r] * v[3];
}

GIMANY_DEF gim_result gim_light_fit_view(const gim_fit_view_desc *desc, gim_light *out_light, float out_min[3],
                                         float out_max[3]) {
    static const char where[] = "gim_light_fit_view";
    gim_mat4 inv_view, inv_proj, view, proj;
    double lo[3] = {DBL_MAX, DBL_MAX, DBL_MAX}, hi[3] = {-DBL_MAX, -DBL_MAX, -DBL_MAX}, diag = 0.0, rad = 0.0, eye[3];
    gim_vec3 l;
    int k, a;
    const gim_light *light;
    const float *scene_min, *scene_max;
    float view_distance;
    if (!desc) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL argument");
    light = desc->light; scene_min = desc->scene_min; scene_max = desc->scene_max;
    view = desc->view; proj = desc->proj; view_distance = desc->view_distance;
    if (!light || !scene_min || !scene_max || !out_light || !out_min || !out_max)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL argument");
    if (!gim__all_finite(scene_min, 3) || !gim__all_finite(scene_max, 3) || !gim__mat4_isfinite(view) ||
        !gim__mat4_isfinite(proj) || !gim_mat4_invert(view, &inv_view) || !gim_mat4_invert(proj, &inv_proj) ||
        !gim__isfinitef(view_distance) || view_distance < 0.0f)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "bounds, camera or view_distance not finite or invalid");
    *out_light = *light;
    memcpy(out_min, scene_min, 3 * sizeof(float));
    memcpy(out_max, scene_max, 3 * sizeof(float));
    if (light->type == GIM_LIGHT_SPOT || light->type == GIM_LIGHT_POINT || !light->fit_view) return GIM_OK;
    for (a = 0; a < 3; ++a) eye[a] = inv_view.m[12 + a];
    for (k = 0; k < 8; ++k) { /* the frustum's corners, the far ones pulled in to view_distance */
        double ndc[4], v[4], w[4];
        ndc[0] = (k & 1) ? 1.0 : -1.0; ndc[1] = (k & 2) ? 1.0 : -1.0; ndc[2] = (k & 4) ? 1.0 : -1.0; ndc[3] = 1.0;
        gim__mat4_apply_d(&inv_proj, ndc, v);
        if (!(v[3] != 0.0)) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "proj maps a corner to infinity");
        for (a = 0; a < 3; ++a) v[a] /= v[3];
        v[3] = 1.0;
        gim__mat4_apply_d(&inv_view, v, w);
        if (view_distance > 0.0f) {
            double d = 0.0, t;
            for (a = 0; a < 3; ++a) d += (w[a] - eye[a]) * (w[a] - eye[a]);
            d = sqrt(d);
            t = d > view_distance ? view_distance / d : 1.0;
            for (a = 0; a < 3; ++a) w[a] = eye[a] + (w[a] - eye[a]) * t;
        }
        for (a = 0; a < 3; ++a) {
            if (w[a] < lo[a]) lo[a] = w[a];
            if (w[a] > hi[a]) hi[a] = w[a];
        }
    }
    for (a = 0; a < 3; ++a) { /* clipped to the scene */
        if (lo[a] < scene_min[a]) lo[a] = scene_min[a];
        if (hi[a] > scene_max[a]) hi[a] = scene_max[a];
        diag += ((double)scene_max[a] - scene_min[a]) * ((double)scene_max[a] - scene_min[a]);
        if (!(lo[a] <= hi[a])) return GIM_OK; /* the camera looks out of the scene: the scene bounds */
        rad += 0.25 * (hi[a] - lo[a]) * (hi[a] - lo[a]);
    }
    diag = sqrt(diag);
    rad = sqrt(rad);
    if (!(rad > 0.0)) return GIM_OK;
    l = gim_v3_normalize(light->direction);
    for (a = 0; a < 3; ++a) {
        double la = fabs(a == 0 ? l.x : a == 1 ? l.y : l.z) * diag;
        out_min[a] = (float)(lo[a] - la);
        out_max[a] = (float)(hi[a] + la);
    }
    if (!(light->extent > 0.0f)) out_light->extent = (float)rad;
    return GIM_OK;
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

/* Moller-Trumbore in double: the ray o + t d against triangle v (9 floats); 1 with t and the
   barycentrics (u, w) of v[1], v[2] on a hit (t unbounded: the caller clips it). */
static int gim__ray_triangle(const double o[3], const double d[3], const float *v, double *t, double *u, double *w) {
    double e1[3], e2[3], pv[3], tv[3], qv[3], det;
    int i;
    for (i = 0; i < 3; ++i) { e1[i] = (double)v[3 + i] - v[i]; e2[i] = (double)v[6 + i] - v[i]; tv[i] = o[i] - v[i]; }
    pv[0] = d[1] * e2[2] - d[2] * e2[1]; pv[1] = d[2] * e2[0] - d[0] * e2[2]; pv[2] = d[0] * e2[1] - d[1] * e2[0];
    det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0.0) return 0;
    *u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) / det;
    if (*u < 0.0 || *u > 1.0) return 0;
    qv[0] = tv[1] * e1[2] - tv[2] * e1[1]; qv[1] = tv[2] * e1[0] - tv[0] * e1[2]; qv[2] = tv[0] * e1[1] - tv[1] * e1[0];
    *w = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) / det;
    if (*w < 0.0 || *u + *w > 1.0) return 0;
    *t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) / det;
    return 1;
}

/* The unnormalised normal at barycentrics (bu, bv) of triangle tri: the interpolated vertex
   normals, or the face normal without them (the GPU's interpolation, before it normalises). */
static void gim__twin_normal(const gim_twin_scene *s, uint32_t tri, double bu, double bv, double nn[3]) {
    const float *v = s->positions + (size_t)tri * 9;
    int i;
    if (s->normals) {
        const float *n = s->normals + (size_t)tri * 9;
        for (i = 0; i < 3; ++i) nn[i] = (1.0 - bu - bv) * n[i] + bu * n[3 + i] + bv * n[6 + i];
    } else {
        double e1[3], e2[3];
        for (i = 0; i < 3; ++i) { e1[i] = (double)v[3 + i] - v[i]; e2[i] = (double)v[6 + i] - v[i]; }
        nn[0] = e1[1] * e2[2] - e1[2] * e2[1]; nn[1] = e1[2] * e2[0] - e1[0] * e2[2]; nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
    }
}

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
    for (t = 0; t < s->triangle_count; ++t) { /* t in [0, 1] from near to far */
        double u, w, tt;
        if (!gim__ray_triangle(o, d, s->positions + (size_t)t * 9, &tt, &u, &w)) continue;
        if (tt < 0.0 || tt > 1.0 || tt >= best) continue;
        best = tt; best_t = t; bu = u; bv = w;
    }
    if (best_t == UINT32_MAX) return 0;
    h->triangle = best_t;
    for (i = 0; i < 3; ++i) { h->p[i] = o[i] + best * d[i]; h->toward[i] = -d[i]; }
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (i = 0; i < 3; ++i) h->toward[i] /= len;
    {
        double nn[3];
        gim__twin_normal(s, best_t, bu, bv, nn);
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

GIMANY_DEF gim_result gim_rsm_texel_twin(const gim_twin_scene *scene, const gim_rsm_view *rsm_view, uint32_t x, uint32_t y,
                                         gim_rsm_texel *out) {
    static const char where[] = "gim_rsm_texel_twin";
    gim_mat4 view, proj;
    gim__twin_hit h;
    uint32_t size;
    float power[3];
    double a_perp, cosv, omega = 0.0;
    gim_result r;
    int i, hit;
    const gim_light *light;
    if (!out) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL");
    if (!rsm_view) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "view is NULL");
    light = rsm_view->light;
    r = gim__twin_scene_check(scene, where);
    if (r == GIM_OK) r = gim_light_camera(light, rsm_view->bmin, rsm_view->bmax, &view, &proj);
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
        out->lit = light->square_cone || inside >= cos((double)light->cone_angle);
        a_perp = omega;
    } else {
        a_perp = (2.0 / proj.m[0] / size) * (2.0 / proj.m[5] / size); /* the window's width / size x height / size */
        out->area = (float)gim__min_d(a_perp / cosv, FLT_MAX);
        out->lit = 1;
    }
    if (out->lit) {
        const float *al = scene->albedo + (size_t)h.triangle * 3;
        for (i = 0; i < 3; ++i) out->flux[i] = (float)gim__min_d((double)al[i] * power[i] * a_perp, FLT_MAX);
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_gbuffer_decode_twin(const gim_decode_desc *desc, const float host_normal[4], float host_depth,
                                              float out_normal[4], float *out_depth) {
    float n[3], d = host_depth, l;
    int k, drawn, view_space, depth_view_z;
    gim_normal_encoding encoding;
    const gim_mat4 *view, *proj;
    if (!desc || !host_normal || !out_normal || !out_depth)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, "gim_gbuffer_decode_twin", "NULL argument");
    encoding = desc->encoding; view_space = desc->view_space; depth_view_z = desc->depth_view_z;
    view = &desc->view; proj = &desc->proj;
    if ((unsigned)encoding > (unsigned)GIM_NORMAL_OCTAHEDRAL_UNORM)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, "gim_gbuffer_decode_twin", "unknown encoding %d", (int)encoding);
    for (k = 0; k < 3; ++k) n[k] = encoding == GIM_NORMAL_XYZ_UNORM ? host_normal[k] * 2.0f - 1.0f : host_normal[k];
    if (encoding == GIM_NORMAL_OCTAHEDRAL || encoding == GIM_NORMAL_OCTAHEDRAL_UNORM) {
        /* Cigolle et al. 2014: the upper half folded out, the lower folded back over the diagonals */
        float fx = encoding == GIM_NORMAL_OCTAHEDRAL_UNORM ? host_normal[0] * 2.0f - 1.0f : host_normal[0];
        float fy = encoding == GIM_NORMAL_OCTAHEDRAL_UNORM ? host_normal[1] * 2.0f - 1.0f : host_normal[1];
        n[0] = fx; n[1] = fy; n[2] = 1.0f - fabsf(fx) - fabsf(fy);
        if (n[2] < 0.0f) {
            n[0] = (1.0f - fabsf(fy)) * (fx >= 0.0f ? 1.0f : -1.0f);
            n[1] = (1.0f - fabsf(fx)) * (fy >= 0.0f ? 1.0f : -1.0f);
        }
    }
    if (depth_view_z) {   /* a point at view z = -d: ndc z = (P22 z + P32) / (P23 z + P33) */
        float z = -d, w = proj->m[11] * z + proj->m[15], ndc = (proj->m[10] * z + proj->m[14]) / w;
        d = d > 0.0f && w > 0.0f && ndc <= 1.0f ? ndc * 0.5f + 0.5f : 1.0f;
        if (d != d) d = 1.0f;
    }
    if (view_space) {   /* normals go back by the transpose of view's 3x3 (its inverse transpose, inverted) */
        float w[3];
        for (k = 0; k < 3; ++k) w[k] = view->m[k * 4] * n[0] + view->m[k * 4 + 1] * n[1] + view->m[k * 4 + 2] * n[2];
        memcpy(n, w, sizeof n);
    }
    l = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    drawn = d < 1.0f && gim__all_finite(n, 3) && l > 0.0f;
    l = drawn ? sqrtf(l) : 1.0f;
    for (k = 0; k < 3; ++k) out_normal[k] = drawn ? n[k] / l : 0.0f;
    out_normal[3] = drawn ? 1.0f : 0.0f;
    *out_depth = drawn ? d : 1.0f;
    return GIM_OK;
}

GIMANY_DEF gim_result gim_gbuffer_texel_twin(const gim_twin_scene *scene, const gim_camera *camera, uint32_t x,
                                             uint32_t y, gim_gbuffer_texel *out) {
    static const char where[] = "gim_gbuffer_texel_twin";
    gim__twin_hit h;
    gim_result r;
    int i, hit;
    gim_mat4 view, proj;
    uint32_t width, height;
    if (!out) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL");
    r = gim__twin_scene_check(scene, where);
    if (r != GIM_OK) return r;
    if (!camera) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "camera is NULL");
    view = camera->view; proj = camera->proj; width = camera->width; height = camera->height;
    if (!gim__mat4_isfinite(view) || !gim__mat4_isfinite(proj) || x >= width || y >= height)
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
        out->albedo[i] = scene->albedo[(size_t)h.triangle * 3 + (size_t)i];
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

GIMANY_DEF gim_result gim_view_samples_twin(const float *depth, const float *normal, const gim_camera *camera,
                                            const uint32_t *pixels, uint32_t count, gim_view_sample *out) {
    static const char where[] = "gim_view_samples_twin";
    gim_mat4 inv_view, inv_proj, view, proj;
    uint32_t i, width, height;
    if (!depth || !normal || !camera || !pixels || !out || count == 0 || camera->width == 0 || camera->height == 0)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "NULL array or zero count/size");
    view = camera->view; proj = camera->proj; width = camera->width; height = camera->height;
    if (!gim__mat4_isfinite(view) || !gim__mat4_isfinite(proj) || !gim_mat4_invert(view, &inv_view) ||
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

/* --- paraboloid maps and second-bounce VPLs (Dong sec. 4.2; SSVP sec. 3.C) ------------------- */

/* A map's frame: unit n (normalised in float, as the GPU does) and t, b = gim__basis(n).
   0 where the map is unusable (origin or normal not finite, |n|^2 not within 1e-3 of 1,
   near_distance or attribute_near not finite and >= 0). */
static int gim__paraboloid_frame(const gim_paraboloid *m, gim_vec3 *t, gim_vec3 *b, gim_vec3 *n) {
    if (!gim__all_finite(m->origin, 3) || !gim__all_finite(m->normal, 3) || !gim__isfinitef(m->near_distance) ||
        !(m->near_distance >= 0.0f) || !gim__isfinitef(m->attribute_near) || !(m->attribute_near >= 0.0f) ||
        !gim__unit_or_zero(m->normal, 0))
        return 0;
    *n = gim_v3_normalize(gim_v3(m->normal[0], m->normal[1], m->normal[2]));
    gim__basis(*n, t, b);
    return 1;
}

/* Texel (x, y)'s centre (u, v) on the map and its local direction w (see @section scene);
   0 outside the unit disk. */
static int gim__paraboloid_texel_dir(uint32_t size, uint32_t x, uint32_t y, double uv[2], double w[3]) {
    double r2, k;
    uv[0] = (2.0 * x + 1.0) / size - 1.0;
    uv[1] = (2.0 * y + 1.0) / size - 1.0;
    r2 = uv[0] * uv[0] + uv[1] * uv[1];
    if (r2 > 1.0) return 0;
    k = 1.0 / (1.0 + r2);
    w[0] = 2.0 * uv[0] * k;
    w[1] = 2.0 * uv[1] * k;
    w[2] = (1.0 - r2) * k;
    return 1;
}

GIMANY_DEF gim_result gim_paraboloid_texel_twin(const gim_twin_scene *scene, const gim_paraboloid *map, uint32_t size,
                                                uint32_t x, uint32_t y, gim_paraboloid_texel *out) {
    static const char where[] = "gim_paraboloid_texel_twin";
    gim_vec3 t, b, n;
    double uv[2], w[3], d[3], o[3], best[2] = {-1.0, -1.0}, bu = 0.0, bv = 0.0, len, skip[2];
    uint32_t tri, best_t[2] = {UINT32_MAX, UINT32_MAX};
    int i, k;
    gim_result r;
    if (!out || !map) return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "out or map is NULL");
    r = gim__twin_scene_check(scene, where);
    if (r != GIM_OK) return r;
    if (!gim__paraboloid_frame(map, &t, &b, &n))
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where,
                         "the map's origin or normal is not finite, the normal not unit or a near distance not >= 0");
    if (size == 0 || x >= size || y >= size)
        return gim__fail(NULL, GIM_ERROR_INVALID_ARGUMENT, where, "texel (%u, %u) outside the %u^2 map", (unsigned)x,
                         (unsigned)y, (unsigned)size);
    memset(out, 0, sizeof *out);
    out->distance = out->attribute_distance = GIM_PARABOLOID_EMPTY;
    out->triangle = out->attribute_triangle = UINT32_MAX;
    if (!gim__paraboloid_texel_dir(size, x, y, uv, w)) return GIM_OK;
    d[0] = w[0] * t.x + w[1] * b.x + w[2] * n.x;
    d[1] = w[0] * t.y + w[1] * b.y + w[2] * n.y;
    d[2] = w[0] * t.z + w[1] * b.z + w[2] * n.z;
    len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (i = 0; i < 3; ++i) { d[i] /= len; o[i] = map->origin[i]; }
    /* [0] the visibility map: nearer than near_distance is the VAL's own surface (Dong fig. 7),
       not a blocker; [1] the attribute maps: only the surface under the origin is skipped */
    skip[0] = map->near_distance;
    skip[1] = map->attribute_near;
    for (tri = 0; tri < scene->triangle_count; ++tri) { /* s the distance along unit d */
        double u, vv, s;
        if (!gim__ray_triangle(o, d, scene->positions + (size_t)tri * 9, &s, &u, &vv)) continue;
        for (k = 0; k < 2; ++k) {
            if (!(s > skip[k]) || (best_t[k] != UINT32_MAX && s >= best[k])) continue;
            best[k] = s; best_t[k] = tri;
            if (k == 1) { bu = u; bv = vv; }
        }
    }
    if (best_t[0] != UINT32_MAX && best[0] <= FLT_MAX) {
        out->hit = 1;
        out->triangle = best_t[0];
        out->distance = (float)best[0];
    }
    if (best_t[1] == UINT32_MAX || !(best[1] <= FLT_MAX)) return GIM_OK;
    out->attribute_hit = 1;
    out->attribute_triangle = best_t[1];
    out->attribute_distance = (float)best[1];
    {
        double nn[3], side = 0.0;
        gim__twin_normal(scene, best_t[1], bu, bv, nn);
        len = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        for (i = 0; i < 3; ++i) side -= nn[i] * d[i];
        for (i = 0; i < 3; ++i) {
            out->position[i] = (float)(o[i] + best[1] * d[i]);
            /* two-sided: turned towards the origin (zero for a degenerate normal) */
            out->normal[i] = len > 0.0 ? (float)((side < 0.0 ? -nn[i] : nn[i]) / len) : 0.0f;
            out->albedo[i] = scene->albedo[(size_t)best_t[1] * 3 + (size_t)i];
        }
    }
    return GIM_OK;
}

/* S_m = S / M, one more for m < S mod M: map m's share of the second-bounce VPLs, and the
   index of its first one. */
static uint32_t gim__second_bounce_share(uint32_t vpl_count, uint32_t map_count, uint32_t m, uint32_t *first) {
    uint32_t q = vpl_count / map_count, rem = vpl_count % map_count;
    *first = m * q + (m < rem ? m : rem);
    return q + (m < rem ? 1u : 0u);
}

/* The texel of map sample j of s_m (SSVP sec. 3.C): the Hammersley point ((j + 0.5) / s_m,
   radical inverse of j) through the area-preserving gim_square_to_disk, to the texel that
   holds it (x = min(floor((u + 1) size / 2), size - 1)). */
static void gim__second_bounce_texel(uint32_t j, uint32_t s_m, uint32_t size, uint32_t *x, uint32_t *y) {
    gim_vec2 p = gim_square_to_disk((float)((j + 0.5) / s_m), (float)gim_van_der_corput(j));
    double fx = floor(((double)p.x + 1.0) * size * 0.5), fy = floor(((double)p.y + 1.0) * size * 0.5);
    *x = fx < 0.0 ? 0u : fx >= (double)size ? size - 1u : (uint32_t)fx;
    *y = fy < 0.0 ? 0u : fy >= (double)size ? size - 1u : (uint32_t)fy;
}

static void gim__ism_frame(const float *c, const float *normal, float lift, float o[3], gim_vec3 *t, gim_vec3 *b,
                           gim_vec3 *n);
static float gim__ism_visible(const float *map, uint32_t size, const float o[3], gim_vec3 t, gim_vec3 b, gim_vec3 n,
                              const float *x, const float *nl, float bias, float texel);

GIMANY_DEF gim_result gim_second_bounce_vpls_twin(const gim_second_bounce_desc *desc, gim_vpl *out) {
    static const char where[] = "gim_second_bounce_vpls_twin";
    const gim_env *env = desc ? &desc->env : NULL;
    uint32_t m, j, isz = 0;
    size_t texels;
    float ibias = 0.0f, itexel = 0.0f;
    if (!desc || !out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "desc or out is NULL");
    if (!desc->maps || !desc->position || !desc->normal || !desc->albedo)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "maps, position, normal or albedo is NULL");
    if (desc->map_count == 0 || desc->size == 0 || desc->vpl_count == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "map_count, size or vpl_count is 0");
    if (desc->size > 65535u)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, where, "size %u above 65535", (unsigned)desc->size);
    texels = (size_t)desc->size * desc->size;
    if (desc->ism) {
        isz = desc->ism_size ? desc->ism_size : GIM_ISM_DEFAULT_SIZE;
        if (isz < GIM_ISM_MIN_SIZE || isz > GIM_ISM_MAX_SIZE || (isz & (isz - 1u)) || !gim__isfinitef(desc->ism_bias) ||
            desc->ism_bias < 0.0f || desc->ism_bias > 1.0f || !gim__isfinitef(desc->ism_slope) || desc->ism_slope < 0.0f ||
            desc->ism_slope > 64.0f || !gim__isfinitef(desc->scene_scale) || !(desc->scene_scale > 0.0f))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where,
                             "ism: ism_size a power of two in %u..%u, ism_bias in [0, 1], ism_slope in [0, 64], "
                             "scene_scale > 0", GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
        ibias = desc->ism_bias > 0.0f ? desc->ism_bias : GIM_ISM_BIAS;
        itexel = (desc->ism_slope > 0.0f ? desc->ism_slope : GIM_ISM_SLOPE) * 2.0f / (float)isz;
    }
    for (m = 0; m < desc->map_count; ++m) {
        const gim_paraboloid *p = &desc->maps[m];
        gim_vec3 t, b, n;
        if (!gim__paraboloid_frame(p, &t, &b, &n) || !gim__all_finite(p->flux, 3) || p->flux[0] < 0.0f ||
            p->flux[1] < 0.0f || p->flux[2] < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where,
                             "map %u: origin, normal, near distances or flux not finite, unit and >= 0", (unsigned)m);
    }
    for (m = 0; m < desc->map_count; ++m) {
        const gim_paraboloid *p = &desc->maps[m];
        uint32_t first, s_m = gim__second_bounce_share(desc->vpl_count, desc->map_count, m, &first);
        for (j = 0; j < s_m; ++j) {
            gim_vpl *v = &out[first + j];
            uint32_t x, y;
            size_t k;
            const float *hp, *hn, *ha;
            double uv[2], w[3], r2, scale;
            int i;
            gim__second_bounce_texel(j, s_m, desc->size, &x, &y);
            k = ((size_t)m * texels + (size_t)y * desc->size + x) * 4u;
            hp = desc->position + k; hn = desc->normal + k; ha = desc->albedo + k;
            memset(v, 0, sizeof *v);
            /* a texel without a hit, with broken data or outside the disk: an unlit VPL */
            if (!(hp[3] > 0.0f) || !gim__all_finite(hp, 3) || !gim__all_finite(hn, 3) || !gim__all_finite(ha, 3) ||
                ha[0] < 0.0f || ha[1] < 0.0f || ha[2] < 0.0f || !gim__paraboloid_texel_dir(desc->size, x, y, uv, w))
                continue;
            /* Phi = albedo Phi_m w.z / (pi S_m pdf), pdf = (1 + r^2)^2 / (4 pi), w.z = (1 - r^2) / (1 + r^2) */
            r2 = uv[0] * uv[0] + uv[1] * uv[1];
            scale = 4.0 * (1.0 - r2) / ((double)s_m * (1.0 + r2) * (1.0 + r2) * (1.0 + r2));
            v->lit = 1.0f;
            for (i = 0; i < 3; ++i) {
                v->position[i] = hp[i];
                v->normal[i] = hn[i];
                v->flux[i] = gim__clamp_flt((double)ha[i] * p->flux[i] * scale);
            }
            if (desc->ism) {   /* the hit as the cluster's own ISM sees it */
                float o[3];
                gim_vec3 it, ib, in;
                gim__ism_frame(p->origin, p->normal, GIM_ISM_LIFT * desc->scene_scale, o, &it, &ib, &in);
                if (gim__ism_visible(desc->ism + (size_t)m * isz * isz, isz, o, it, ib, in, hp, hn, ibias, itexel) == 0.0f)
                    memset(v, 0, sizeof *v);
            }
        }
    }
    return GIM_OK;
}

#ifdef __cplusplus
}
#endif

/* --- VPL shading: soft visibility, shading, geometry-aware blur ---------------------------
   Twins of vpl_shade.comp and geometry_blur.comp. Every step is float arithmetic written in
   the order the shaders write it (their variables `precise`, so no multiply-add is fused),
   so the GPU reads the same texels and sums the same terms. */

/* The 16 taps of the visibility kernel: a Vogel (golden-angle) disk, tap j at radius
   sqrt((j + 0.5) / 16) and angle j pi (3 - sqrt 5), as (r cos, r sin): equal area per tap
   and no grid alignment (a regular grid of taps bands the penumbra). vpl_shade.comp holds
   the same floats. */
#define GIM__VIS_TAPS 16
static const float gim__vogel16[GIM__VIS_TAPS][2] = {
    {0.176776692f, 0.0f}, {-0.225772187f, 0.206825823f}, {0.0345580503f, -0.393771172f},
    {0.28457123f, 0.371172756f}, {-0.522223175f, -0.0923739299f}, {0.494695395f, -0.314684719f},
    {-0.165465921f, 0.615525007f}, {-0.315561473f, -0.60759443f}, {0.684642136f, 0.25003022f},
    {-0.712256074f, 0.29400897f}, {0.343354493f, -0.733728647f}, {0.253730237f, 0.808932006f},
    {-0.764745891f, -0.443185866f}, {0.897134006f, -0.197232395f}, {-0.547506928f, 0.778772235f},
    {-0.126486778f, -0.976089716f}};
#define GIM__VPL_MAX_INTERLEAVE 64u   /* k of interleaved sampling and the blur window, at most */

/* One tap at map point (u, v): 1 where the texel under it (the declared texel rule) holds a
   blocker, its distance into *z. Outside the unit disk (directions below the VAL's plane,
   where it emits nothing) there is no blocker, nor where the stored value is not a finite
   positive distance. A blocker is nearer than the reference: with a receiver plane (pl: its
   normal in the map's frame t, b, n; pd = pl . (x - o), the plane's distance from the
   origin), 0.99 of where the texel's centre ray meets that plane (FLT_MAX where it never
   does), so a planar receiver never shadows itself however the filter tilts across it;
   without one, ref. */
static int gim__paraboloid_block(const float *distance, uint32_t size, float u, float v, const float *pl, float pd,
                                 float ref, float *z) {
    float fs = (float)size, fx, fy, r;
    uint32_t x, y;
    if (!(u * u + v * v <= 1.0f)) return 0;
    fx = floorf((u + 1.0f) * fs * 0.5f);
    fy = floorf((v + 1.0f) * fs * 0.5f);
    x = fx < 0.0f ? 0u : (fx > fs - 1.0f ? size - 1u : (uint32_t)fx);
    y = fy < 0.0f ? 0u : (fy > fs - 1.0f ? size - 1u : (uint32_t)fy);
    *z = distance[(size_t)y * size + x];
    if (!(*z > 0.0f)) return 0;
    r = ref;
    if (pl) {
        float uc = (2.0f * (float)x + 1.0f) / fs - 1.0f, vc = (2.0f * (float)y + 1.0f) / fs - 1.0f;
        float q = 1.0f + uc * uc + vc * vc;
        float den = pl[0] * (2.0f * uc / q) + pl[1] * (2.0f * vc / q) + pl[2] * ((1.0f - uc * uc - vc * vc) / q);
        r = den * pd > 0.0f ? 0.99f * (pd / den) : FLT_MAX;
    }
    return *z < r;
}

/* Soft visibility of map m from x (Dong sec. 4.2, PCSS on a paraboloid map in angles).
   In map units the stereographic map stretches an angle a around w by J = 1 / (1 + w.z), so
   a cone of half-angle a is a disk of radius J a around the receiver's map point (u, v).
   0. the VAL as x sees it: a square of side Delta' = Delta sqrt(w.z), the side of a square
      of its projected area Delta^2 w.z (Dong's filter uses Delta; foreshortening the VAL
      brings the mean |V - exact from-area visibility| behind random plates, VALs and
      receivers from 0.058 to 0.048, test_vpl_shade.c visibility_near_exact);
   1. blocker search over a_s = min(0.5, 1.5 Delta' / d): a blocker at distance z from the
      VAL's centre shadows x from points of the VAL up to (Delta' / 2)(1 / z - 1 / d) radians
      away, which is 1.5 Delta' / d for z = d / 4: blockers nearer the VAL than a quarter of
      the way are only partly searched (their penumbra is wide and faint);
   2. z_avg: the mean distance of the taps that block (0 < z < d - bias); none: V = 1;
   3. penumbra (Dong's p cos beta = (d - z_avg) Delta / z_avg, seen from the VAL's centre as
      the angle alpha = p cos beta / d): its half-width a_p = (Delta' / 2)(1 / z_avg - 1 / d)
      is the filter's radius, clamped to [one texel's angle 2 / (size J), 0.5];
   4. V = the fraction of the 16 filter taps that do not block (PCF).
   A tap blocks where its texel's distance is nearer than the receiver's plane along that
   texel's ray (by 1%: the map's float and texel-centre error; gim__paraboloid_block), so a
   planar receiver does not shadow itself wherever the filter reaches across it (PCSS
   against one receiver depth took 24% of the light off an open floor next to a wall, where
   the wall's maps see the floor at grazing angles). Without a receiver normal (nx NULL),
   or where x's plane passes within 1e-6 d of the VAL's origin, the reference is
   d - bias, bias = d (0.01 + 4 (1 + w.z) / size): d times two texels' angle, what the
   distance to a surface inclined 63 degrees (tan = 2) from facing the VAL changes across one
   texel. A stored value that is not a finite positive distance (NaN, <= 0) blocks nothing.
   size: 1..65536. */
static float gim__paraboloid_vis(const float *distance, uint32_t size, const gim_paraboloid *m, const float *x,
                                 const float *nx) {
    gim_vec3 t, b, n = gim_v3(m->normal[0], m->normal[1], m->normal[2]);
    float p0 = x[0] - m->origin[0], p1 = x[1] - m->origin[1], p2 = x[2] - m->origin[2];
    float lx, ly, lz, d, wz, opz, jac, u, v, fs = (float)size, texel, bias, ref, dv, as, s, zsum = 0.0f, zavg, ap, af;
    float pl[3], pd = 0.0f, z;
    const float *plane = NULL;
    int k, found = 0, open = 0;
    gim__basis(n, &t, &b);
    lx = p0 * t.x + p1 * t.y + p2 * t.z;
    ly = p0 * b.x + p1 * b.y + p2 * b.z;
    lz = p0 * n.x + p1 * n.y + p2 * n.z;
    d = sqrtf(lx * lx + ly * ly + lz * lz);
    if (!(d > 0.0f) || !(d <= FLT_MAX)) return 1.0f;     /* at the origin, or too far for floats */
    wz = lz / d;
    if (!(wz > 0.0f)) return 1.0f;                        /* behind the VAL's plane (Dong fig. 7) */
    opz = 1.0f + wz;
    jac = 1.0f / opz;
    u = lx / d / opz;
    v = ly / d / opz;
    texel = 2.0f * opz / fs;
    bias = d * (0.01f + 4.0f * opz / fs);
    ref = d - bias;
    if (nx) {   /* the receiver's plane in the map's frame */
        pl[0] = nx[0] * t.x + nx[1] * t.y + nx[2] * t.z;
        pl[1] = nx[0] * b.x + nx[1] * b.y + nx[2] * b.z;
        pl[2] = nx[0] * n.x + nx[1] * n.y + nx[2] * n.z;
        pd = pl[0] * lx + pl[1] * ly + pl[2] * lz;
        if (pd > 1e-6f * d || pd < -1e-6f * d) plane = pl;
    }
    dv = m->size * sqrtf(wz);                             /* Delta', the foreshortened VAL */
    as = 1.5f * dv / d;
    as = as < 0.5f ? as : 0.5f;
    s = jac * as;
    for (k = 0; k < GIM__VIS_TAPS; ++k)
        if (gim__paraboloid_block(distance, size, u + s * gim__vogel16[k][0], v + s * gim__vogel16[k][1], plane, pd, ref, &z)) {
            zsum += z;
            ++found;
        }
    if (found == 0) return 1.0f;
    zavg = zsum / (float)found;
    ap = 0.5f * dv * (1.0f / zavg - 1.0f / d);
    af = ap > texel ? ap : texel;
    af = af < 0.5f ? af : 0.5f;
    s = jac * af;
    for (k = 0; k < GIM__VIS_TAPS; ++k)
        if (!gim__paraboloid_block(distance, size, u + s * gim__vogel16[k][0], v + s * gim__vogel16[k][1], plane, pd, ref, &z))
            ++open;
    return (float)open / (float)GIM__VIS_TAPS;
}

static int gim__paraboloid_ok(const gim_paraboloid *m) {
    return gim__all_finite(m->origin, 3) && gim__unit_or_zero(m->normal, 0) && gim__isfinitef(m->size) &&
           m->size >= 0.0f;
}

GIMANY_DEF gim_result gim_paraboloid_visibility_twin(const float *distance, uint32_t size, const gim_paraboloid *map,
                                                gim_vec3 receiver, const gim_vec3 *normal, float *out) {
    static const char fn[] = "gim_paraboloid_visibility_twin";
    gim_env env;
    float x[3];
    memset(&env, 0, sizeof env);
    if (!distance || !map || !out) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "distance, map and out are required");
    if (size == 0 || size > 65536u) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "size %u must be 1..65536", size);
    if (!gim__paraboloid_ok(map))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "map: origin not finite, normal not unit or size not >= 0");
    if (!gim__v3_isfinite(receiver)) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "receiver is not finite");
    if (normal && (!gim__v3_isfinite(*normal) || fabsf(gim__v3_dot(*normal, *normal) - 1.0f) > 1e-3f))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "normal is not a finite unit vector");
    x[0] = receiver.x; x[1] = receiver.y; x[2] = receiver.z;
    if (normal) {
        float nx[3];
        nx[0] = normal->x; nx[1] = normal->y; nx[2] = normal->z;
        *out = gim__paraboloid_vis(distance, size, map, x, nx);
    } else {
        *out = gim__paraboloid_vis(distance, size, map, x, NULL);
    }
    return GIM_OK;
}

/* --- imperfect shadow maps (Ritschel et al. 2008) ------------------------------------------ */

GIMANY_DEF gim_result gim_ism_points(const gim_twin_scene *scene, uint32_t count, float *out) {
    float per;
    static const char where[] = "gim_ism_points";
    double *cdf, total = 0.0;
    uint32_t t, i, tri = 0;
    gim_env env;
    gim_result r;
    memset(&env, 0, sizeof env);
    if (!out || count == 0) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL or count is 0");
    if ((r = gim__twin_scene_check(scene, where)) != GIM_OK) return r;
    cdf = (double *)gim__alloc_array(&env, scene->triangle_count, sizeof(double));
    if (!cdf) return gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, where, "%u triangles", scene->triangle_count);
    for (t = 0; t < scene->triangle_count; ++t) {
        const float *v = scene->positions + (size_t)t * 9;
        double e1[3], e2[3], c[3];
        int a;
        for (a = 0; a < 3; ++a) { e1[a] = (double)v[3 + a] - v[a]; e2[a] = (double)v[6 + a] - v[a]; }
        c[0] = e1[1] * e2[2] - e1[2] * e2[1]; c[1] = e1[2] * e2[0] - e1[0] * e2[2]; c[2] = e1[0] * e2[1] - e1[1] * e2[0];
        total += 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        cdf[t] = total;
    }
    if (!(total > 0.0) || !(total <= DBL_MAX)) {
        gim__free(&env, cdf);
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "the scene has no area");
    }
    per = gim__clamp_flt(total / count);
    for (i = 0; i < count; ++i) {
        double u = (i + 0.5) / count * total, lo, rr, su, b1, b2, e1[3], e2[3], c[3], len;
        const float *v;
        float *o = out + (size_t)i * 8;
        int a;
        while (tri + 1u < scene->triangle_count && cdf[tri] <= u) ++tri;   /* u increases with i */
        lo = tri > 0 ? cdf[tri - 1] : 0.0;
        rr = cdf[tri] > lo ? (u - lo) / (cdf[tri] - lo) : 0.5;
        rr = rr < 0.0 ? 0.0 : rr > 1.0 ? 1.0 : rr;
        su = sqrt(rr);
        b1 = 1.0 - su;
        b2 = fmod((double)i * 0.61803398874989485, 1.0) * su;
        v = scene->positions + (size_t)tri * 9;
        for (a = 0; a < 3; ++a) {
            o[a] = (float)((1.0 - b1 - b2) * v[a] + b1 * v[3 + a] + b2 * v[6 + a]);
            e1[a] = (double)v[3 + a] - v[a];
            e2[a] = (double)v[6 + a] - v[a];
        }
        c[0] = e1[1] * e2[2] - e1[2] * e2[1]; c[1] = e1[2] * e2[0] - e1[0] * e2[2]; c[2] = e1[0] * e2[1] - e1[1] * e2[0];
        len = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        for (a = 0; a < 3; ++a) o[4 + a] = len > 0.0 ? (float)(c[a] / len) : 0.0f;
        o[3] = per;
        o[7] = 0.0f;
    }
    gim__free(&env, cdf);
    return GIM_OK;
}

static gim_result gim__ism_check(const gim_ism_desc *d, const char *fn, int points, uint32_t *size, uint32_t *per_map,
                                 float *bias, float *slope, float *splat) {
    const gim_env *env = &d->env;
    gim_result r;
    *size = d->size ? d->size : GIM_ISM_DEFAULT_SIZE;
    *per_map = d->points_per_map ? d->points_per_map : GIM_ISM_DEFAULT_POINTS;
    *bias = d->bias > 0.0f ? d->bias : GIM_ISM_BIAS;
    *slope = d->slope > 0.0f ? d->slope : GIM_ISM_SLOPE;
    *splat = d->splat > 0.0f ? d->splat : GIM_ISM_SPLAT;
    if (!d->caches || d->cache_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no caches");
    if (*size < GIM_ISM_MIN_SIZE || *size > GIM_ISM_MAX_SIZE || (*size & (*size - 1u)))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "size %u: a power of two in %u..%u", *size, GIM_ISM_MIN_SIZE,
                         GIM_ISM_MAX_SIZE);
    if (*per_map > GIM_ISM_MAX_POINTS)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "points_per_map %u above %u", *per_map, GIM_ISM_MAX_POINTS);
    if (!gim__isfinitef(d->bias) || d->bias < 0.0f || *bias > 1.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "bias must be in [0, 1]");
    if (!gim__isfinitef(d->slope) || d->slope < 0.0f || *slope > 64.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "slope must be in [0, 64]");
    if (!gim__isfinitef(d->splat) || d->splat < 0.0f || *splat > GIM_ISM_MAX_SPLAT)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "splat must be in [0, %g]", (double)GIM_ISM_MAX_SPLAT);
    if (!gim__isfinitef(d->scene_scale) || !(d->scene_scale > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale must be finite and > 0");
    if (points) {
        if (!d->points || d->point_count == 0) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "no points");
        if (!gim__all_finite(d->points, (size_t)d->point_count * 8))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "a point is not finite");
    }
    if ((r = gim__check_caches(env, fn, d->caches, d->cache_count)) != GIM_OK) return r;
    return GIM_OK;
}

/* A map's frame from its cache's (or VPL's) position c and normal: origin (c + lift n), t, b,
   n, in float as ism.comp. */
static void gim__ism_frame(const float *c, const float *normal, float lift, float o[3], gim_vec3 *t, gim_vec3 *b,
                           gim_vec3 *n) {
    int a;
    *n = gim_v3(normal[0], normal[1], normal[2]);
    gim__basis(*n, t, b);
    for (a = 0; a < 3; ++a) o[a] = c[a] + lift * normal[a];
}

/* The texel of direction d (unnormalised, length dist > 0) on a size^2 map of frame (t, b, n);
   -1 behind the map's plane. */
static int32_t gim__ism_texel(const float d[3], float dist, gim_vec3 t, gim_vec3 b, gim_vec3 n, uint32_t size) {
    float wz = (d[0] * n.x + d[1] * n.y + d[2] * n.z) / dist, wx, wy, fx, fy;
    int32_t ix, iy;
    if (!(wz > 0.0f)) return -1;
    wx = (d[0] * t.x + d[1] * t.y + d[2] * t.z) / dist;
    wy = (d[0] * b.x + d[1] * b.y + d[2] * b.z) / dist;
    fx = floorf((wx / (1.0f + wz) + 1.0f) * 0.5f * (float)size);
    fy = floorf((wy / (1.0f + wz) + 1.0f) * 0.5f * (float)size);
    ix = fx < 0.0f ? 0 : fx > (float)(size - 1u) ? (int32_t)size - 1 : (int32_t)fx;
    iy = fy < 0.0f ? 0 : fy > (float)(size - 1u) ? (int32_t)size - 1 : (int32_t)fy;
    return iy * (int32_t)size + ix;
}

/* Map m's subset: stride = point_count / P (>= 1), offset = frac(m phi) stride in 32-bit
   fixed point (umulExtended in ism.comp); point k is offset + k stride. */
static uint32_t gim__ism_offset(uint32_t m, uint32_t stride) {
    return (uint32_t)(((uint64_t)(uint32_t)(m * 2654435769u) * stride) >> 32);
}

/* Pull-push of one size^2 map in place; scratch: size^2 floats. */
static void gim__ism_pull_push(float *map, uint32_t size, float *scratch) {
    float *lv[8];
    uint32_t sz[8], l, levels = 0, x, y;
    size_t off = 0;
    lv[0] = map; sz[0] = size;
    for (l = 0; sz[l] > 1u; ++l) {      /* pull: the farthest of the non-empty children */
        sz[l + 1] = sz[l] / 2u;
        lv[l + 1] = scratch + off;
        off += (size_t)sz[l + 1] * sz[l + 1];
        for (y = 0; y < sz[l + 1]; ++y)
            for (x = 0; x < sz[l + 1]; ++x) {
                float s = 0.0f, cnt = 0.0f, c;
                int k;
                for (k = 0; k < 4; ++k) {
                    c = lv[l][(2u * y + (uint32_t)(k >> 1)) * sz[l] + 2u * x + (uint32_t)(k & 1)];
                    if (c < GIM_PARABOLOID_EMPTY) { s = c > s ? c : s; cnt += 1.0f; }
                }
                lv[l + 1][y * sz[l + 1] + x] = cnt > 0.0f ? s : GIM_PARABOLOID_EMPTY;
            }
    }
    levels = l;
    /* push: a hole takes the farther of its parent and the bilinear blend (9 3 3 1 / 16) of the
       four parents nearest its centre. The parent alone is a step: on a surface seen at a grazing
       angle its depth runs away across a block, and a hole on the block's far side took a nearer
       depth than the surface there (false shadow); the blend follows the slope, and the farther
       of the two never brings a near occluder's depth into a hole beside it. */
    for (l = levels; l-- > 0;) {
        const float *pv = lv[l + 1];
        uint32_t ps = sz[l + 1];
        for (y = 0; y < sz[l]; ++y)
            for (x = 0; x < sz[l]; ++x) {
                float *c = lv[l] + y * sz[l] + x, p00, p10, p01, p11, fill;
                uint32_t xa = x / 2u, ya = y / 2u, xb, yb;
                if (*c < GIM_PARABOLOID_EMPTY) continue;
                xb = (x & 1u) ? (xa + 1u < ps ? xa + 1u : ps - 1u) : (xa > 0u ? xa - 1u : 0u);
                yb = (y & 1u) ? (ya + 1u < ps ? ya + 1u : ps - 1u) : (ya > 0u ? ya - 1u : 0u);
                p00 = pv[ya * ps + xa]; p10 = pv[ya * ps + xb];
                p01 = pv[yb * ps + xa]; p11 = pv[yb * ps + xb];
                fill = p00;
                if (p00 < GIM_PARABOLOID_EMPTY && p10 < GIM_PARABOLOID_EMPTY && p01 < GIM_PARABOLOID_EMPTY &&
                    p11 < GIM_PARABOLOID_EMPTY) {
                    float blend = (9.0f * p00 + 3.0f * p10 + 3.0f * p01 + p11) * 0.0625f;
                    fill = blend > p00 ? blend : p00;
                }
                *c = fill;
            }
    }
}

/* The unit direction (world) of texel tx's centre ray. */
static void gim__ism_texel_ray(int32_t tx, uint32_t size, gim_vec3 t, gim_vec3 b, gim_vec3 n, float dir[3]) {
    float fs = (float)size, u, v, r2, k, w[3];
    u = (2.0f * (float)(tx % (int32_t)size) + 1.0f) / fs - 1.0f;
    v = (2.0f * (float)(tx / (int32_t)size) + 1.0f) / fs - 1.0f;
    r2 = u * u + v * v;
    k = 1.0f / (1.0f + r2);
    w[0] = 2.0f * u * k; w[1] = 2.0f * v * k; w[2] = (1.0f - r2) * k;
    dir[0] = w[0] * t.x + w[1] * b.x + w[2] * n.x;
    dir[1] = w[0] * t.y + w[1] * b.y + w[2] * n.y;
    dir[2] = w[0] * t.z + w[1] * b.z + w[2] * n.z;
}

/* One surfel into a map (see gim_ism_render_twin), in float as ism.comp. */
static void gim__ism_splat(float *map, uint32_t size, const float o[3], gim_vec3 t, gim_vec3 b, gim_vec3 n, float lift,
                           const float *p, float area, float splat) {
    float d[3], dist, rs, rs2, rf, dn, fs = (float)size;
    int32_t tx, cx, cy, x, y, r;
    d[0] = p[0] - o[0]; d[1] = p[1] - o[1]; d[2] = p[2] - o[2];
    dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(dist > lift)) return;                         /* the cache's own point */
    tx = gim__ism_texel(d, dist, t, b, n, size);
    if (tx < 0) return;
    cx = tx % (int32_t)size;
    cy = tx / (int32_t)size;
    rs = splat * sqrtf(area / (float)GIM__PI);
    rs2 = rs * rs;
    rf = ceilf(rs / dist * fs * 0.5f);
    r = rf < (float)GIM_ISM_SPLAT_TEXELS ? (int32_t)rf : GIM_ISM_SPLAT_TEXELS;
    dn = d[0] * p[4] + d[1] * p[5] + d[2] * p[6];
    for (y = cy - r; y <= cy + r; ++y)
        for (x = cx - r; x <= cx + r; ++x) {
            float dir[3], den, s, h[3];
            if (x < 0 || y < 0 || x >= (int32_t)size || y >= (int32_t)size) continue;
            gim__ism_texel_ray(y * (int32_t)size + x, size, t, b, n, dir);
            den = dir[0] * p[4] + dir[1] * p[5] + dir[2] * p[6];
            if (!(den >= 1e-3f || den <= -1e-3f)) continue;   /* the ray runs along the plane */
            s = dn / den;
            if (!(s > lift)) continue;
            h[0] = s * dir[0] - d[0]; h[1] = s * dir[1] - d[1]; h[2] = s * dir[2] - d[2];
            if (h[0] * h[0] + h[1] * h[1] + h[2] * h[2] > rs2) continue;
            if (s < map[y * (int32_t)size + x]) map[y * (int32_t)size + x] = s;
        }
}

GIMANY_DEF uint16_t gim_ism_quantize(float d) {
    uint32_t u;
    memcpy(&u, &d, 4);
    return (uint16_t)((u + 0x8000u) >> 16);
}

GIMANY_DEF float gim_ism_dequantize(uint16_t q) {
    uint32_t u = (uint32_t)q << 16;
    float d;
    memcpy(&d, &u, 4);
    return d;
}

GIMANY_DEF gim_result gim_ism_render_twin(const gim_ism_desc *desc, float *distance_out) {
    static const char fn[] = "gim_ism_render_twin";
    uint32_t size, per, m, k, stride, n_take;
    float bias, slope, splat, lift, *scratch;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    if (!distance_out) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "distance_out is NULL");
    if ((r = gim__ism_check(desc, fn, 1, &size, &per, &bias, &slope, &splat)) != GIM_OK) return r;
    scratch = (float *)gim__alloc_array(&desc->env, (size_t)size * size, sizeof(float));
    if (!scratch) return gim__fail(&desc->env, GIM_ERROR_OUT_OF_MEMORY, fn, "%u^2 floats", size);
    lift = GIM_ISM_LIFT * desc->scene_scale;
    n_take = per < desc->point_count ? per : desc->point_count;
    stride = desc->point_count / n_take;
    for (m = 0; m < desc->cache_count; ++m) {
        float *map = distance_out + (size_t)m * size * size, o[3];
        gim_vec3 t, b, n;
        uint32_t off = gim__ism_offset(m, stride);
        size_t q;
        for (q = 0; q < (size_t)size * size; ++q) map[q] = GIM_PARABOLOID_EMPTY;
        gim__ism_frame(desc->caches[m].position, desc->caches[m].normal, lift, o, &t, &b, &n);
        for (k = 0; k < n_take; ++k) {
            const float *p = desc->points + (size_t)(off + k * stride) * 8;
            gim__ism_splat(map, size, o, t, b, n, lift, p, (float)stride * p[3], splat);
        }
        gim__ism_pull_push(map, size, scratch);
        for (q = 0; q < (size_t)size * size; ++q) map[q] = gim_ism_dequantize(gim_ism_quantize(map[q]));
    }
    gim__free(&desc->env, scratch);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_vpl_shadow_maps_twin(const gim_twin_scene *scene, const gim_vpl *vpls, uint32_t count,
                                               uint32_t size, float scene_scale, float *maps_out, gim_env env) {
    static const char fn[] = "gim_vpl_shadow_maps_twin";
    uint32_t i, x, y;
    float lift = GIM_ISM_LIFT * scene_scale;
    if (!scene || (count && (!vpls || !maps_out)))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene, vpls or maps_out is NULL");
    if (size < GIM_ISM_MIN_SIZE || size > GIM_ISM_MAX_SIZE || (size & (size - 1u)))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "size %u: a power of two in %u..%u", (unsigned)size,
                         GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale %g must be finite and > 0", (double)scene_scale);
    for (i = 0; i < count; ++i) {
        const gim_vpl *v = &vpls[i];
        float *map = maps_out + (size_t)i * size * size;
        gim_paraboloid m;
        size_t q;
        for (q = 0; q < (size_t)size * size; ++q) map[q] = gim_ism_dequantize(gim_ism_quantize(GIM_PARABOLOID_EMPTY));
        if (!(v->lit > 0.0f)) continue;
        memset(&m, 0, sizeof m);
        for (x = 0; x < 3; ++x) {
            m.origin[x] = v->position[x] + lift * v->normal[x];
            m.normal[x] = v->normal[x];
        }
        for (y = 0; y < size; ++y)
            for (x = 0; x < size; ++x) {
                gim_paraboloid_texel o;
                gim_result r = gim_paraboloid_texel_twin(scene, &m, size, x, y, &o);
                if (r != GIM_OK) return gim__fail(&env, r, fn, "VPL %u: no map (its normal is not finite and unit?)", (unsigned)i);
                map[(size_t)y * size + x] = gim_ism_dequantize(gim_ism_quantize(o.hit ? o.distance : GIM_PARABOLOID_EMPTY));
            }
    }
    return GIM_OK;
}

/* The lookup of gim_ism_visibility_twin: 1 or 0, receiver x with normal nl through one map of frame
   (o, t, b, n); texel = slope 2 / size. Also each VPL's own map in gim_vpl_shade_twin. */
static float gim__ism_visible(const float *map, uint32_t size, const float o[3], gim_vec3 t, gim_vec3 b, gim_vec3 n,
                              const float *x, const float *nl, float bias, float texel) {
    float d[3], dist, z, cl, tn;
    int32_t tx;
    d[0] = x[0] - o[0]; d[1] = x[1] - o[1]; d[2] = x[2] - o[2];
    dist = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    tx = dist > 0.0f ? gim__ism_texel(d, dist, t, b, n, size) : -1;
    if (tx >= 0) {
        float dref = dist, dir[3], den;
        z = map[tx];
        gim__ism_texel_ray(tx, size, t, b, n, dir);
        den = dir[0] * nl[0] + dir[1] * nl[1] + dir[2] * nl[2];
        if (den >= 1e-3f || den <= -1e-3f) {    /* the receiver's plane along the texel's ray */
            float s_ = (d[0] * nl[0] + d[1] * nl[1] + d[2] * nl[2]) / den;
            if (s_ > 0.0f && s_ < 2.0f * dist) dref = s_;
        }
        cl = -(nl[0] * d[0] + nl[1] * d[1] + nl[2] * d[2]) / dist;   /* cos theta_l */
        cl = cl < 0.0f ? -cl : cl;
        tn = cl * GIM_ISM_MAX_TAN > sqrtf(1.0f - (cl < 1.0f ? cl * cl : 1.0f)) ? sqrtf(1.0f - (cl < 1.0f ? cl * cl : 1.0f)) / cl
                                                                            : GIM_ISM_MAX_TAN;
        if (z < GIM_PARABOLOID_EMPTY && dref > z + dist * (bias + texel * tn)) return 0.0f;
    }
    return 1.0f;
}

GIMANY_DEF gim_result gim_ism_visibility_twin(const gim_ism_desc *desc, const float *distance, const gim_val *vals,
                                         uint32_t val_count, float *out) {
    static const char fn[] = "gim_ism_visibility_twin";
    uint32_t size, per, m, j;
    float bias, slope, splat, lift, texel;
    gim_result r;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    if (!distance || !out || (val_count > 0 && !vals))
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "distance, vals and out are required");
    if ((r = gim__ism_check(desc, fn, 0, &size, &per, &bias, &slope, &splat)) != GIM_OK) return r;
    lift = GIM_ISM_LIFT * desc->scene_scale;
    texel = slope * 2.0f / (float)size;
    for (m = 0; m < desc->cache_count; ++m) {
        const float *map = distance + (size_t)m * size * size;
        float o[3];
        gim_vec3 t, b, n;
        gim__ism_frame(desc->caches[m].position, desc->caches[m].normal, lift, o, &t, &b, &n);
        for (j = 0; j < val_count; ++j)
            out[(size_t)m * val_count + j] = gim__ism_visible(map, size, o, t, b, n, vals[j].position, vals[j].normal, bias,
                                                              texel);
    }
    return GIM_OK;
}

/* rays: the BVH and the pixels' neighbour test ------------------------------------------- */

/* The build's working set: each triangle's box and centroid, and the triangles' order. */
typedef struct gim__bvh_build {
    const float *pos;          /* the scene's triangles, 9 floats each, in the hierarchy's frame */
    float *local;              /* the same, owned */
    float *box;                /* triangle_count * 6: lo xyz, hi xyz */
    float *centroid;           /* triangle_count * 3 */
    uint32_t *order;           /* the leaves' order */
    gim_bvh_node *nodes;
    uint32_t node_count, depth;
} gim__bvh_build;

#define GIM__BVH_BINS 16
#define GIM__BVH_SAH_LEVELS 24 /* below them the build halves by count (GIM_BVH_MAX_TRIANGLES) */

static float gim__bvh_area(const float *lo, const float *hi) {
    float x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
    return x < 0.0f || y < 0.0f || z < 0.0f ? 0.0f : x * y + y * z + z * x;
}

static void gim__bvh_grow(float *lo, float *hi, const float *b) {
    int a;
    for (a = 0; a < 3; ++a) {
        if (b[a] < lo[a]) lo[a] = b[a];
        if (b[3 + a] > hi[a]) hi[a] = b[3 + a];
    }
}

/* Put order[begin, end)'s element of rank k (by centroid on axis a) at k, the smaller before
   it and the larger after (Hoare's selection). */
static void gim__bvh_select(gim__bvh_build *b, uint32_t begin, uint32_t end, uint32_t k, int a) {
    while (end - begin > 1u) {
        /* the lower middle: Hoare's partition then always splits [begin, end) in two */
        float pivot = b->centroid[(size_t)b->order[begin + (end - 1u - begin) / 2u] * 3u + (size_t)a];
        uint32_t i = begin, j = end - 1u, t;
        for (;;) {
            while (b->centroid[(size_t)b->order[i] * 3u + (size_t)a] < pivot) ++i;
            while (b->centroid[(size_t)b->order[j] * 3u + (size_t)a] > pivot) --j;
            if (i >= j) break;
            t = b->order[i]; b->order[i] = b->order[j]; b->order[j] = t;
            ++i; --j;
        }
        /* order[begin, j] <= pivot <= order[j + 1, end) */
        if (k <= j) end = j + 1u;
        else begin = j + 1u;
    }
}

/* Node for order[begin, end) at depth, then its subtrees (the first right after it). */
static void gim__bvh_node_make(gim__bvh_build *b, uint32_t begin, uint32_t end, uint32_t depth) {
    uint32_t self = b->node_count++, i, count = end - begin, mid = begin;
    gim_bvh_node *node = b->nodes + self;
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    float clo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, chi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX}, ext = 0.0f, far_ = 0.0f;
    int a, axis = 0;
    for (i = begin; i < end; ++i) {
        const float *c = b->centroid + (size_t)b->order[i] * 3u;
        gim__bvh_grow(lo, hi, b->box + (size_t)b->order[i] * 6u);
        for (a = 0; a < 3; ++a) {
            if (c[a] < clo[a]) clo[a] = c[a];
            if (c[a] > chi[a]) chi[a] = c[a];
        }
    }
    /* grown past the triangles grown by GIM__BVH_GROW (5e-4 of its size) and by 1e-6 of its
       distance from the origin, for the rounding of the box's coordinates: no hit of a grown
       triangle lies outside its nodes' boxes (the slab test's own rounding is gim_bvh_occluded's
       relative slack) */
    for (a = 0; a < 3; ++a) {
        float e = hi[a] - lo[a], f = fabsf(lo[a]) > fabsf(hi[a]) ? fabsf(lo[a]) : fabsf(hi[a]);
        if (e > ext) ext = e;
        if (f > far_) far_ = f;
    }
    for (a = 0; a < 3; ++a) {
        node->lo[a] = lo[a] - (5e-4f * ext + 1e-6f * far_);
        node->hi[a] = hi[a] + (5e-4f * ext + 1e-6f * far_);
    }
    if (depth > b->depth) b->depth = depth;
    if (count <= (uint32_t)GIM_BVH_LEAF) {
        node->index = begin;
        node->count = count;
        return;
    }
    for (a = 1; a < 3; ++a)
        if (chi[a] - clo[a] > chi[axis] - clo[axis]) axis = a;
    if (depth < GIM__BVH_SAH_LEVELS && chi[axis] > clo[axis]) {
        /* binned SAH (Wald 2007): the plane between bins with the least A_l N_l + A_r N_r */
        float blo[GIM__BVH_BINS][3], bhi[GIM__BVH_BINS][3], scale = (float)GIM__BVH_BINS / (chi[axis] - clo[axis]);
        float best = FLT_MAX, alo[3], ahi[3], rlo[GIM__BVH_BINS][3], rhi[GIM__BVH_BINS][3];
        uint32_t bn[GIM__BVH_BINS], rn = 0, ln = 0;
        int k, split = -1;
        for (k = 0; k < GIM__BVH_BINS; ++k) {
            bn[k] = 0;
            for (a = 0; a < 3; ++a) { blo[k][a] = FLT_MAX; bhi[k][a] = -FLT_MAX; }
        }
        for (i = begin; i < end; ++i) {
            float t = (b->centroid[(size_t)b->order[i] * 3u + (size_t)axis] - clo[axis]) * scale;
            int bin = t >= (float)(GIM__BVH_BINS - 1) ? GIM__BVH_BINS - 1 : t > 0.0f ? (int)t : 0;
            const float *tb = b->box + (size_t)b->order[i] * 6u;
            ++bn[bin];
            for (a = 0; a < 3; ++a) {
                if (tb[a] < blo[bin][a]) blo[bin][a] = tb[a];
                if (tb[3 + a] > bhi[bin][a]) bhi[bin][a] = tb[3 + a];
            }
        }
        for (a = 0; a < 3; ++a) { alo[a] = FLT_MAX; ahi[a] = -FLT_MAX; }
        for (k = GIM__BVH_BINS - 1; k > 0; --k) {   /* the boxes of bins k.. */
            float bb[6];
            for (a = 0; a < 3; ++a) { bb[a] = blo[k][a]; bb[3 + a] = bhi[k][a]; }
            if (bn[k]) gim__bvh_grow(alo, ahi, bb);
            for (a = 0; a < 3; ++a) { rlo[k][a] = alo[a]; rhi[k][a] = ahi[a]; }
        }
        for (a = 0; a < 3; ++a) { alo[a] = FLT_MAX; ahi[a] = -FLT_MAX; }
        for (k = 0; k < GIM__BVH_BINS - 1; ++k) {   /* the plane after bin k */
            float bb[6], cost;
            for (a = 0; a < 3; ++a) { bb[a] = blo[k][a]; bb[3 + a] = bhi[k][a]; }
            if (bn[k]) gim__bvh_grow(alo, ahi, bb);
            ln += bn[k];
            rn = count - ln;
            if (ln == 0 || rn == 0) continue;
            cost = gim__bvh_area(alo, ahi) * (float)ln + gim__bvh_area(rlo[k + 1], rhi[k + 1]) * (float)rn;
            if (cost < best) { best = cost; split = k; }
        }
        if (split >= 0) {   /* partition: the bins up to split first */
            uint32_t j = end;
            i = begin;
            while (i < j) {
                float t = (b->centroid[(size_t)b->order[i] * 3u + (size_t)axis] - clo[axis]) * scale;
                int bin = t >= (float)(GIM__BVH_BINS - 1) ? GIM__BVH_BINS - 1 : t > 0.0f ? (int)t : 0;
                if (bin <= split) { ++i; continue; }
                --j;
                { uint32_t s = b->order[i]; b->order[i] = b->order[j]; b->order[j] = s; }
            }
            mid = i;
        }
    }
    if (mid <= begin || mid >= end) {   /* no plane splits them (or below the SAH levels): halves by count */
        mid = begin + count / 2u;
        if (chi[axis] > clo[axis]) gim__bvh_select(b, begin, end, mid, axis);
    }
    node->count = 0;
    gim__bvh_node_make(b, begin, mid, depth + 1u);
    node->index = b->node_count;   /* the second child follows the first's subtree */
    gim__bvh_node_make(b, mid, end, depth + 1u);
}

GIMANY_DEF gim_result gim_bvh_build(const gim_twin_scene *scene, gim_env env, gim_bvh *out) {
    static const char where[] = "gim_bvh_build";
    gim__bvh_build b;
    gim_bvh res;
    uint32_t n, i;
    if (!scene || !out) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "scene or out is NULL");
    n = scene->triangle_count;
    if (n > 0 && !scene->positions) return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "no positions");
    if (n > GIM_BVH_MAX_TRIANGLES)
        return gim__fail(&env, GIM_ERROR_OUT_OF_RANGE, where, "%u triangles exceed %u", n, GIM_BVH_MAX_TRIANGLES);
    for (i = 0; i < n; ++i)
        if (!gim__all_finite(scene->positions + (size_t)i * 9u, 9))
            return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "triangle %u has a vertex that is not finite", i);
    memset(&b, 0, sizeof b);
    memset(&res, 0, sizeof res);
    res.env = env;
    res.scale = 1.0f;
    if (n == 0) {
        *out = res;
        return GIM_OK;
    }
    {   /* the frame: the bounds' centre, a power of two near 1 / their diagonal */
        double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL}, diag = 0.0;
        size_t k;
        int a, e;
        for (k = 0; k < (size_t)n * 9u; ++k) {
            a = (int)(k % 3u);
            if (scene->positions[k] < lo[a]) lo[a] = scene->positions[k];
            if (scene->positions[k] > hi[a]) hi[a] = scene->positions[k];
        }
        for (a = 0; a < 3; ++a) {
            res.origin[a] = (float)(0.5 * lo[a] + 0.5 * hi[a]);
            diag += (hi[a] - lo[a]) * (hi[a] - lo[a]);
        }
        diag = sqrt(diag);
        if (!(diag <= (double)FLT_MAX))
            return gim__fail(&env, GIM_ERROR_OUT_OF_RANGE, where, "the triangles' bounds (%g across) exceed a float", diag);
        if (diag > 0.0) {
            (void)frexp(diag, &e);
            res.scale = (float)ldexp(1.0, e > 126 ? -126 : e < -126 ? 126 : -e);   /* the diagonal becomes 0.5 .. 1 */
        }
    }
    b.pos = scene->positions;
    b.box = (float *)gim__alloc_array(&env, n, 6u * sizeof(float));
    b.centroid = (float *)gim__alloc_array(&env, n, 3u * sizeof(float));
    b.order = (uint32_t *)gim__alloc_array(&env, n, sizeof(uint32_t));
    b.nodes = (gim_bvh_node *)gim__alloc_array(&env, 2u * (size_t)n, sizeof(gim_bvh_node));
    res.triangles = (float *)gim__alloc_array(&env, n, 12u * sizeof(float));
    b.local = (float *)gim__alloc_array(&env, n, 9u * sizeof(float));
    if (!b.box || !b.centroid || !b.order || !b.nodes || !res.triangles || !b.local) {
        gim__free(&env, b.box); gim__free(&env, b.centroid); gim__free(&env, b.order); gim__free(&env, b.nodes);
        gim__free(&env, res.triangles); gim__free(&env, b.local);
        res.triangles = NULL;
        return gim__fail(&env, GIM_ERROR_OUT_OF_MEMORY, where, "a hierarchy of %u triangles", n);
    }
    for (i = 0; i < n * 9u; ++i) b.local[i] = (b.pos[i] - res.origin[i % 3u]) * res.scale;
    b.pos = b.local;
    for (i = 0; i < n; ++i) {
        const float *v = b.pos + (size_t)i * 9u;
        float *bx = b.box + (size_t)i * 6u;
        int a, k;
        for (a = 0; a < 3; ++a) {
            bx[a] = bx[3 + a] = v[a];
            for (k = 1; k < 3; ++k) {
                float x = v[k * 3 + a];
                if (x < bx[a]) bx[a] = x;
                if (x > bx[3 + a]) bx[3 + a] = x;
            }
            b.centroid[(size_t)i * 3u + (size_t)a] = 0.5f * bx[a] + 0.5f * bx[3 + a];   /* the box's centre: never overflows */
        }
        b.order[i] = i;
    }
    gim__bvh_node_make(&b, 0, n, 0);
    for (i = 0; i < n; ++i) {   /* the triangles in the leaves' order, as v0 and the two edges */
        const float *v = b.pos + (size_t)b.order[i] * 9u;
        float *t = res.triangles + (size_t)i * 12u;
        int a;
        for (a = 0; a < 3; ++a) {
            t[a] = v[a];
            t[4 + a] = v[3 + a] - v[a];
            t[8 + a] = v[6 + a] - v[a];
        }
        memcpy(t + 3, &b.order[i], sizeof(uint32_t));   /* which scene triangle: gim_bvh_hit.triangle */
        t[7] = t[11] = 0.0f;
    }
    gim__free(&env, b.box);
    gim__free(&env, b.centroid);
    gim__free(&env, b.order);
    gim__free(&env, b.local);
    res.nodes = b.nodes;   /* 2n - 1 at most were used */
    res.node_count = b.node_count;
    res.triangle_count = n;
    res.depth = b.depth;
    *out = res;
    return GIM_OK;
}

GIMANY_DEF void gim_bvh_free(gim_bvh *bvh) {
    if (!bvh) return;
    gim__free(&bvh->env, bvh->nodes);
    gim__free(&bvh->env, bvh->triangles);
    bvh->nodes = NULL;
    bvh->triangles = NULL;
    bvh->node_count = bvh->triangle_count = bvh->depth = 0;
    bvh->origin[0] = bvh->origin[1] = bvh->origin[2] = 0.0f;
    bvh->scale = 1.0f;
}

/* Each triangle grown by 1e-4 of its size (in barycentrics): a segment through the edge two
   triangles share, whose rounded barycentrics can put it just outside both, hits one; without
   it 152 of 2000 segments through the diagonal of tests/unit/test_bvh.c's wall slipped through. */
#define GIM__BVH_GROW 1e-4f

/* The segment o + t d, 0 < t < 1, against one triangle (gim_bvh_occluded's steps; bvh.glsl);
   on a hit *tt and *dd the crossing's e2 . q and det (sign-flipped where det < 0). */
static int gim__bvh_triangle_at(const float *tri, const float *o, const float *d, float *tt, float *dd) {
    float px, py, pz, det, sx, sy, sz, u, qx, qy, qz, v, t, g;
    const float *e1 = tri + 4, *e2 = tri + 8;
    px = d[1] * e2[2] - d[2] * e2[1];
    py = d[2] * e2[0] - d[0] * e2[2];
    pz = d[0] * e2[1] - d[1] * e2[0];
    det = e1[0] * px + e1[1] * py + e1[2] * pz;
    if (det == 0.0f) return 0;
    sx = o[0] - tri[0]; sy = o[1] - tri[1]; sz = o[2] - tri[2];
    u = sx * px + sy * py + sz * pz;
    qx = sy * e1[2] - sz * e1[1];
    qy = sz * e1[0] - sx * e1[2];
    qz = sx * e1[1] - sy * e1[0];
    v = d[0] * qx + d[1] * qy + d[2] * qz;
    t = e2[0] * qx + e2[1] * qy + e2[2] * qz;
    if (det < 0.0f) { det = -det; u = -u; v = -v; t = -t; }
    g = GIM__BVH_GROW * det;   /* a ray along the edge two triangles share hits one of them */
    *tt = t;
    *dd = det;
    return u >= -g && v >= -g && u + v <= det + g && t > 0.0f && t < det;
}

/* ... without the crossing (the tests' every-triangle answers) */
static GIM__UNUSED int gim__bvh_triangle(const float *tri, const float *o, const float *d) {
    float t, det;
    return gim__bvh_triangle_at(tri, o, d, &t, &det);
}

/* The segment from -> to in the hierarchy's frame: its start o and its vector d; 0 where one is
   not finite. */
static int gim__bvh_segment(const gim_bvh *bvh, gim_vec3 from, gim_vec3 to, float *o, float *d) {
    float e[3];
    o[0] = (from.x - bvh->origin[0]) * bvh->scale;
    o[1] = (from.y - bvh->origin[1]) * bvh->scale;
    o[2] = (from.z - bvh->origin[2]) * bvh->scale;
    e[0] = (to.x - bvh->origin[0]) * bvh->scale;
    e[1] = (to.y - bvh->origin[1]) * bvh->scale;
    e[2] = (to.z - bvh->origin[2]) * bvh->scale;
    d[0] = e[0] - o[0]; d[1] = e[1] - o[1]; d[2] = e[2] - o[2];
    return gim__all_finite(o, 3) && gim__all_finite(d, 3);
}

/* The slab test of node nd against the segment o + t d, 0 <= t <= reach (inv: 1 / d, 0 on an
   axis along which the segment barely moves, tested by its extent there instead). Each t is
   within 3 rounding steps of its value (Ize 2013): the slack keeps the test conservative
   wherever the segment starts. bvh.glsl's bvh_box. */
static int gim__bvh_box(const gim_bvh_node *nd, const float *o, const float *d, const float *inv, float reach) {
    float tn = 0.0f, tf = reach;
    int a;
    for (a = 0; a < 3; ++a) {
        if (inv[a] != 0.0f) {
            float t0 = (nd->lo[a] - o[a]) * inv[a], t1 = (nd->hi[a] - o[a]) * inv[a];
            float lo_ = t0 < t1 ? t0 : t1, hi_ = t0 < t1 ? t1 : t0;
            tn = lo_ > tn ? lo_ : tn;
            tf = hi_ < tf ? hi_ : tf;
        } else if (o[a] + fabsf(d[a]) < nd->lo[a] || o[a] - fabsf(d[a]) > nd->hi[a]) {
            tf = -1.0f;
        }
    }
    return tn <= tf * 1.000001f;
}

/* The walk: the slot of the first triangle met that the segment o + t d crosses (any), or of the
   nearest (the segment cut at each nearer crossing, compared as e2 . q det' < e2 . q' det, no
   division deciding; *bt / *bd its e2 . q and det); UINT32_MAX for none. */
static uint32_t gim__bvh_walk(const gim_bvh *bvh, const float *o, const float *d, int any, float *bt, float *bd) {
    uint32_t stack[GIM_BVH_MAX_DEPTH], sp = 0, node = 0, best = UINT32_MAX;
    float inv[3], reach = 1.0f;
    int a;
    *bt = *bd = 1.0f;
    /* an axis along which the segment barely moves (|d| < 1e-30, whose reciprocal may be
       infinite) is tested by the segment's extent on it instead of a slab */
    for (a = 0; a < 3; ++a) inv[a] = fabsf(d[a]) >= 1e-30f ? 1.0f / d[a] : 0.0f;
    for (;;) {
        const gim_bvh_node *nd = bvh->nodes + node;
        if (gim__bvh_box(nd, o, d, inv, reach)) {
            if (nd->count == 0) {
                stack[sp++] = nd->index;
                node = node + 1u;
                continue;
            } else {
                uint32_t k;
                for (k = 0; k < nd->count; ++k) {
                    float t, det;
                    if (gim__bvh_triangle_at(bvh->triangles + (size_t)(nd->index + k) * 12u, o, d, &t, &det) &&
                        t * *bd < *bt * det) {
                        *bt = t;
                        *bd = det;
                        best = nd->index + k;
                        if (any) return best;
                        reach = *bt / *bd;
                    }
                }
            }
        }
        if (sp == 0) return best;
        node = stack[--sp];
    }
}

GIMANY_DEF int gim_bvh_occluded(const gim_bvh *bvh, gim_vec3 from, gim_vec3 to) {
    float o[3], d[3], bt, bd;
    if (!bvh || !bvh->node_count || !bvh->nodes || !bvh->triangles) return 0;
    if (!gim__bvh_segment(bvh, from, to, o, d)) return 0;
    return gim__bvh_walk(bvh, o, d, 1, &bt, &bd) != UINT32_MAX;
}

GIMANY_DEF int gim_bvh_nearest(const gim_bvh *bvh, gim_vec3 from, gim_vec3 to, gim_bvh_hit *hit) {
    float o[3], d[3], bt, bd;
    uint32_t best;
    if (!bvh || !hit || !bvh->node_count || !bvh->nodes || !bvh->triangles) return 0;
    if (!gim__bvh_segment(bvh, from, to, o, d)) return 0;
    best = gim__bvh_walk(bvh, o, d, 0, &bt, &bd);
    if (best == UINT32_MAX) return 0;
    hit->slot = best;
    memcpy(&hit->triangle, bvh->triangles + (size_t)best * 12u + 3u, sizeof(uint32_t));
    hit->t = bt / bd;
    return 1;
}

/* A ray's end: p lifted by l along n, each component a float multiply-add in this order (the
   shaders' `precise` steps). */
static gim_vec3 gim__ray_end(const float *p, const float *n, float l) {
    return gim_v3(p[0] + l * n[0], p[1] + l * n[1], p[2] + l * n[2]);
}

/* --- the second bounce by rays (gim_second_bounce_rays_twin; second_bounce_rays.comp) --- */

/* Ray j: its pick u inside its stratum, the direction's (x, y) in the VPL's frame and its z
   (in [0, 1]). */
static void gim__second_ray_sample(uint32_t j, float *out4) {
    gim_vec2 p = gim_square_to_disk((float)gim_van_der_corput(j), (float)gim_radical_inverse(3u, j));
    double z2 = 1.0 - (double)p.x * p.x - (double)p.y * p.y;
    out4[0] = (float)gim_radical_inverse(5u, j);
    out4[1] = p.x;
    out4[2] = p.y;
    out4[3] = (float)(z2 > 0.0 ? sqrt(z2) : 0.0);
}

/* A first-bounce VPL's pick weight: (Phi_r + Phi_g) + Phi_b of a lit VPL with finite position,
   normal and non-negative finite flux, else 0. */
static float gim__second_ray_weight(const gim_vpl *v) {
    if (!(v->lit > 0.0f) || !gim__all_finite(v->position, 3) || !gim__all_finite(v->normal, 3) ||
        !gim__all_finite(v->flux, 3) || !(v->flux[0] >= 0.0f && v->flux[1] >= 0.0f && v->flux[2] >= 0.0f))
        return 0.0f;
    return (v->flux[0] + v->flux[1]) + v->flux[2];
}

/* Ray j's stratum of n VPLs among s rays: [j n, (j + 1) n) in units of 1 / s VPL, VPL i
   covering [i s, (i + 1) s); the VPLs lo..hi it overlaps. */
static void gim__second_ray_stratum(uint32_t j, uint32_t n, uint32_t s, uint32_t *lo, uint32_t *hi) {
    *lo = (uint32_t)((uint64_t)j * n / s);
    *hi = (uint32_t)(((uint64_t)j * n + n - 1u) / s);
}

/* VPL i's weight in ray j's stratum: its pick weight times its overlap (units of 1 / s VPL). */
static float gim__second_ray_share(const gim_vpl *vpls, uint32_t i, uint32_t j, uint32_t n, uint32_t s) {
    uint64_t a = (uint64_t)j * n, b = a + n, c = (uint64_t)i * s, d = c + s;
    uint64_t ov = (b < d ? b : d) - (a > c ? a : c);
    return gim__second_ray_weight(vpls + i) * (float)ov;
}

/* The surface a second-bounce VPL at x (normal nx) stands for, which its near field spreads
   it over as a first-bounce VPL's texel footprint: one over the rays' expected landings per
   unit area there, S sum_i (w_i / W) cos_i cos_x / (pi d_i^2) over the first-bounce VPLs, as if
   each sent its flux's share S w_i / W of the rays, cosine-distributed. The strata send one ray
   a stratum, which is that share where the strata's fluxes are equal and differs where they
   differ: the area only sets how far a VPL's light is spread, and the exact shares would cost a
   pass over the strata. Visibility is left out, which only overstates the density:
   the area errs towards a point. In VPL order, as second_bounce_rays.comp sums them (an S x N
   cost, one pass over the list per ray). 0 where the density is not finite and > 0. */
static float gim__second_ray_area(const gim_vpl *vpls, uint32_t n, uint32_t s, const float *x, const float *nx) {
    float wsum = 0.0f, dens = 0.0f, area;
    uint32_t i;
    for (i = 0; i < n; ++i) {
        const gim_vpl *v = vpls + i;
        float w = gim__second_ray_weight(v), dx, dy, dz, d2, ci, cx, g;
        if (!(w > 0.0f)) continue;
        wsum += w;
        dx = x[0] - v->position[0];
        dy = x[1] - v->position[1];
        dz = x[2] - v->position[2];
        d2 = (dx * dx + dy * dy) + dz * dz;
        ci = (v->normal[0] * dx + v->normal[1] * dy) + v->normal[2] * dz;
        cx = -((nx[0] * dx + nx[1] * dy) + nx[2] * dz);
        if (!(d2 > 0.0f) || !(ci > 0.0f) || !(cx > 0.0f)) continue;
        g = ((ci * cx) / d2) / d2;
        dens += w * g;
    }
    area = (3.14159265f * wsum) / ((float)s * dens);
    return area > 0.0f && area < FLT_MAX ? area : 0.0f;
}

GIMANY_DEF gim_result gim_second_bounce_rays_twin(const gim_second_bounce_rays_desc *desc, gim_vpl *out) {
    static const char where[] = "gim_second_bounce_rays_twin";
    const gim_env *env = desc ? &desc->env : NULL;
    const gim_bvh *bvh;
    float lift, far;
    uint32_t j, n, s;
    if (!desc || !out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "desc or out is NULL");
    bvh = desc->bvh;
    n = desc->vpl_count;
    s = desc->count;
    if (!bvh || !desc->vpls) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "bvh or vpls is NULL");
    if (bvh->triangle_count && !desc->albedo) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "albedo is NULL");
    for (j = 0; j < bvh->triangle_count * 3u; ++j)
        if (!gim__isfinitef(desc->albedo[j]) || desc->albedo[j] < 0.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "albedo %u is not finite and >= 0", (unsigned)j);
    if (n == 0 || n > GIM_SECOND_RAYS_MAX_VPLS || s == 0 || s > 65536u)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs (1..%u) or %u rays (1..65536)", (unsigned)n,
                         GIM_SECOND_RAYS_MAX_VPLS, (unsigned)s);
    if (!(desc->scene_scale > 0.0f) || !gim__isfinitef(desc->scene_scale))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale must be finite and > 0");
    lift = GIM_SECOND_RAY_LIFT * desc->scene_scale;
    far = 4.0f / bvh->scale;
    for (j = 0; j < s; ++j) {
        gim_vpl *o = out + j;
        float smp[4], total = 0.0f, run = 0.0f, target, w = 0.0f, k, dir[3], org[3], end[3], nn[3], l;
        const float *e1, *e2, *alb;
        const gim_vpl *v;
        gim_vec3 t, b, nv;
        gim_bvh_hit h;
        uint32_t lo, hi, i, a;
        memset(o, 0, sizeof *o);
        gim__second_ray_stratum(j, n, s, &lo, &hi);
        for (i = lo; i <= hi; ++i) total += gim__second_ray_share(desc->vpls, i, j, n, s);
        if (!(total > 0.0f) || !gim__isfinitef(total)) continue;
        gim__second_ray_sample(j, smp);
        target = smp[0] * total;
        for (i = lo; i <= hi; ++i) {   /* the first VPL whose running sum passes the target */
            run += gim__second_ray_share(desc->vpls, i, j, n, s);
            if (run > target) break;
        }
        if (i > hi) continue;
        w = gim__second_ray_weight(desc->vpls + i);
        if (!(w > 0.0f)) continue;
        v = desc->vpls + i;
        nv = gim_v3(v->normal[0], v->normal[1], v->normal[2]);
        gim__basis(nv, &t, &b);
        dir[0] = (t.x * smp[1] + b.x * smp[2]) + nv.x * smp[3];
        dir[1] = (t.y * smp[1] + b.y * smp[2]) + nv.y * smp[3];
        dir[2] = (t.z * smp[1] + b.z * smp[2]) + nv.z * smp[3];
        for (a = 0; a < 3; ++a) {
            org[a] = v->position[a] + lift * v->normal[a];
            end[a] = org[a] + far * dir[a];
        }
        if (!gim_bvh_nearest(bvh, gim_v3(org[0], org[1], org[2]), gim_v3(end[0], end[1], end[2]), &h)) continue;
        e1 = bvh->triangles + (size_t)h.slot * 12u + 4u;
        e2 = e1 + 4;
        nn[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nn[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nn[2] = e1[0] * e2[1] - e1[1] * e2[0];
        l = sqrtf(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
        if (!(l > 0.0f) || !gim__isfinitef(l)) continue;
        if (nn[0] * dir[0] + nn[1] * dir[1] + nn[2] * dir[2] > 0.0f) l = -l;   /* towards the ray's start */
        k = total / (w * (float)s);
        alb = desc->albedo + (size_t)h.triangle * 3u;
        for (a = 0; a < 3; ++a) {
            float f = alb[a] * (v->flux[a] * k);
            o->position[a] = org[a] + h.t * (end[a] - org[a]);
            o->normal[a] = nn[a] / l;
            o->flux[a] = f < FLT_MAX ? f : FLT_MAX;
        }
        o->area = gim__second_ray_area(desc->vpls, n, s, o->position, o->normal);
        o->lit = 1.0f;
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_neighbour_rays_twin(const gim_neighbour_rays_desc *desc, gim_neighbour_result *out) {
    static const char where[] = "gim_neighbour_rays_twin";
    const gim_env *env;
    uint32_t r, n;
    float lift;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    n = desc->neighbour_stride;
    if (!out || !out->index || !out->count || !out->d_cmax)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "result or one of its arrays (index, count, d_cmax) is NULL");
    if (!desc->bvh || !desc->caches || !desc->cache_count || !desc->receivers || !desc->neighbour_index ||
        !desc->neighbour_count)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "bvh, caches, receivers and the neighbour rows are required");
    if (n == 0 || n > GIM_MAX_NEIGHBOUR_CACHES)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "neighbour_stride must be 1..%d", GIM_MAX_NEIGHBOUR_CACHES);
    if (!gim__isfinitef(desc->scene_scale) || !(desc->scene_scale > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale must be finite and > 0");
    for (r = 0; r < desc->receiver_count; ++r) {
        const uint32_t *row = desc->neighbour_index + (size_t)r * n;
        uint32_t k, cnt = desc->neighbour_count[r];
        if (cnt > n) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "neighbour_count[%u] = %u exceeds the stride", r, cnt);
        for (k = 0; k < cnt; ++k)
            if (row[k] >= desc->cache_count)
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, where, "receiver %u: neighbour %u is cache %u of %u", r, k,
                                 row[k], desc->cache_count);
    }
    lift = GIM_NEIGHBOUR_RAY_LIFT * desc->scene_scale;
    for (r = 0; r < desc->receiver_count; ++r) {
        const gim_receiver *rc = desc->receivers + r;
        const uint32_t *row = desc->neighbour_index + (size_t)r * n;
        uint32_t kept[GIM_MAX_NEIGHBOUR_CACHES], cnt = desc->neighbour_count[r], nk = 0, k;
        gim_vec3 x = gim__ray_end(rc->position, rc->normal, lift);
        for (k = 0; k < cnt; ++k) {
            const gim_cache *c = desc->caches + row[k];
            if (!gim_bvh_occluded(desc->bvh, x, gim__ray_end(c->position, c->normal, lift))) kept[nk++] = row[k];
        }
        if (nk == 0)   /* sees none: keeps them all */
            for (k = 0; k < cnt; ++k) kept[nk++] = row[k];
        for (k = 0; k < n; ++k) out->index[(size_t)r * n + k] = k < nk ? kept[k] : UINT32_MAX;
        out->count[r] = nk;
        out->d_cmax[r] = 0.0f;
        if (nk) {   /* gim_cache_neighbours' distance: the double of the float coordinates */
            const float *cp = desc->caches[kept[nk - 1u]].position;
            double dx = (double)rc->position[0] - cp[0], dy = (double)rc->position[1] - cp[1],
                   dz = (double)rc->position[2] - cp[2];
            out->d_cmax[r] = (float)sqrt(dx * dx + dy * dy + dz * dz);
        }
    }
    return GIM_OK;
}

GIMANY_DEF gim_result gim_val_rays_twin(const gim_bvh *bvh, const gim_cache *caches, uint32_t cache_count, const gim_val *vals,
                                        uint32_t val_count, float scene_scale, gim_env env, float *out) {
    static const char where[] = "gim_val_rays_twin";
    uint32_t c, j;
    float lift;
    if (!bvh || !caches || !cache_count || (val_count && !vals) || !out)
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "bvh, caches, vals and out are required");
    if (!gim__isfinitef(scene_scale) || !(scene_scale > 0.0f))
        return gim__fail(&env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale must be finite and > 0");
    lift = GIM_NEIGHBOUR_RAY_LIFT * scene_scale;
    for (c = 0; c < cache_count; ++c) {
        gim_vec3 o = gim__ray_end(caches[c].position, caches[c].normal, lift);
        for (j = 0; j < val_count; ++j)
            out[(size_t)c * val_count + j] =
                gim_bvh_occluded(bvh, o, gim__ray_end(vals[j].position, vals[j].normal, lift)) ? 0.0f : 1.0f;
    }
    return GIM_OK;
}

/* A receiver of gim_vpl_shade_twin / gim_geometry_blur_twin: a surface (unit normal) or none (zero). */
static int gim__receiver_ok(const gim_receiver *rc) {
    if (!gim__all_finite(rc->position, 3) || !gim__all_finite(rc->normal, 3) || !gim__unit_or_zero(rc->normal, 1))
        return 0;
    if (rc->normal[0] == 0.0f && rc->normal[1] == 0.0f && rc->normal[2] == 0.0f) return 1;
    return gim__unit_or_zero(rc->view, 0) && gim__all_finite(rc->albedo, 3) && gim__all_finite(rc->glossy, 3) &&
           rc->albedo[0] >= 0.0f && rc->albedo[1] >= 0.0f && rc->albedo[2] >= 0.0f && rc->glossy[0] >= 0.0f &&
           rc->glossy[1] >= 0.0f && rc->glossy[2] >= 0.0f && rc->exponent >= 0.0f &&
           rc->exponent <= GIM__TWINS_MAX_EXPONENT;
}
/* A receiver whose material has a glossy colour: the blur keeps its radiance as it is. */
static int gim__receiver_glossy(const gim_receiver *rc) {
    return rc->glossy[0] > 0.0f || rc->glossy[1] > 0.0f || rc->glossy[2] > 0.0f;
}

static int gim__receiver_surface(const gim_receiver *rc) {
    return rc->normal[0] != 0.0f || rc->normal[1] != 0.0f || rc->normal[2] != 0.0f;
}

static gim_result gim__check_vpl_shade(const gim_vpl_shade_desc *d, const char *fn) {
    const gim_env *env = &d->env;
    uint32_t i;
    if (!d->receivers || d->width == 0 || d->height == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "receivers, width and height are required");
    if ((uint64_t)d->width * d->height > (uint64_t)SIZE_MAX / 16u)
        return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "%u x %u receivers", d->width, d->height);
    if (d->vpl_count > 0 && !d->vpls) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "vpls is NULL");
    if (d->interleave > GIM__VPL_MAX_INTERLEAVE)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "interleave %u exceeds %u", d->interleave, GIM__VPL_MAX_INTERLEAVE);
    if (!gim__isfinitef(d->clamp_distance) || !(d->clamp_distance >= 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "clamp_distance must be finite and >= 0");
    if (!gim__isfinitef(d->scene_scale) || !(d->scene_scale > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "scene_scale must be finite and > 0");
    if (d->ism_first && (!d->ism || !d->cluster))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "ism_first needs ism and cluster");
    if (d->ism) {
        uint32_t size = d->ism_size ? d->ism_size : GIM_ISM_DEFAULT_SIZE;
        if (d->cluster && (d->ism_first == 0 || d->ism_first >= d->vpl_count))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "ism with cluster needs ism_first in 1..%u", d->vpl_count - 1u);
        if (size < GIM_ISM_MIN_SIZE || size > GIM_ISM_MAX_SIZE || (size & (size - 1u)))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "ism_size %u: a power of two in %u..%u", size,
                             GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
        if (!gim__isfinitef(d->ism_bias) || d->ism_bias < 0.0f || d->ism_bias > 1.0f || !gim__isfinitef(d->ism_slope) ||
            d->ism_slope < 0.0f || d->ism_slope > 64.0f)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "ism_bias in [0, 1] and ism_slope in [0, 64]");
    }
    if (d->cluster) {
        if (!d->maps || !d->distance || d->map_count == 0 || d->map_size == 0 || d->map_size > 65536u)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "cluster needs maps, distance, map_count > 0 and map_size 1..65536");
        for (i = 0; i < d->map_count; ++i)
            if (!gim__paraboloid_ok(d->maps + i))
                return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "map %u: origin not finite, normal not unit or size not >= 0", i);
    }
    for (i = 0; i < d->vpl_count; ++i) {
        const gim_vpl *v = d->vpls + i;
        if (!gim__all_finite(v->position, 3) || !gim__all_finite(v->normal, 3) || !gim__all_finite(v->flux, 3) ||
            !gim__isfinitef(v->lit) || !gim__isfinitef(v->area))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u is not finite", i);
        if (v->area < 0.0f) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u: negative area", i);
        if (v->lit > 0.0f && (!gim__unit_or_zero(v->normal, 0) || !(v->flux[0] >= 0.0f && v->flux[1] >= 0.0f && v->flux[2] >= 0.0f)))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u: normal not unit or negative flux", i);
        if (d->cluster && d->cluster[i] != UINT32_MAX && d->cluster[i] >= d->map_count)
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "VPL %u: cluster %u of %u maps", i, d->cluster[i], d->map_count);
    }
    for (i = 0; i < d->width * d->height; ++i)
        if (!gim__receiver_ok(d->receivers + i))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn,
                             "receiver %u: not finite, normal not unit or zero, view not unit, negative colour or k outside [0, 1e6]", i);
    return GIM_OK;
}

/* A bijection of [0, n) for interleaved sampling: member j of subset s is VPL
   scramble(s + j k^2). VPLs come from radical-inverse sequences (and second-bounce VPLs map by
   map), so the plain i mod k^2 subsets were strips of the RSM or single maps, and the image
   striped; this spreads every subset over all of them. A 4-round Feistel network on the
   smallest even number of bits that covers n, walked back into [0, n) (expected < 4 steps; it
   ends, since i's own cycle comes back into the range). vpl_shade.comp has the same integer
   steps. */
static uint32_t gim__vpl_scramble(uint32_t i, uint32_t n) {
    uint32_t half = 1u, mask, l, r, t, round;
    while (half < 15u && (1u << (2u * half)) < n) ++half;
    mask = (1u << half) - 1u;
    do {
        l = i >> half;
        r = i & mask;
        for (round = 0u; round < 4u; ++round) {
            t = r * 0x9E3779B1u + round * 0x7F4A7C15u;
            t ^= t >> 15;
            t *= 0x2C1B3C6Du;
            t ^= t >> 12;
            t = l ^ (t & mask);
            l = r;
            r = t;
        }
        i = (l << half) | r;
    } while (i >= n);
    return i;
}

/* The near VPLs of a pixel's subset that take the near field, in member order; any more (a
   subset with more than this many VPLs within 2 sqrt(A): up to about 6 expected on a plane
   with every VPL in one subset, since a VPL's area is its share of the surface; 0.1 at the
   default interleave) take the clamped far field. The GPU lists them in its VPL loop and
   evaluates them after it (vpl_shade.comp). */
#define GIM__VPL_NEAR_CAP 8u

/* Near field of a VPL of area A (units of the VPL twins): E_i / Phi_i at a receiver (normal n)
   dist from it along omega = o (VPL -> receiver), from its far-field value g_far blended
   towards the octagon's F / A (gim__octagon_phi), and o turned towards where the patch's light
   comes from (-unit(phi)), for the glossy lobe. The far field where no part of the patch is
   above the receiver's horizon. */
static float gim__vpl_near(float *o, float dist, const float *n, const float *nl, float area, float g_far) {
    float d[3], phi[3], f, fv, w, u[3], ul;
    int a;
    for (a = 0; a < 3; ++a) d[a] = -o[a] * dist;   /* receiver -> VPL */
    w = gim__near_patch(d, dist * dist, n, nl, area, phi, &f, &fv);
    if (!(w > 0.0f)) return g_far;
    for (a = 0; a < 3; ++a) u[a] = o[a] + w * (-phi[a] / fv - o[a]);
    ul = sqrtf(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    if (ul > 0.0f && gim__isfinitef(ul))
        for (a = 0; a < 3; ++a) o[a] = u[a] / ul;
    return g_far + w * (f / (2.0f * (float)GIM__PI * area) - g_far);
}

/* One pixel of gim_vpl_shade_twin (see vpl_shade.comp, the same steps): the members s, s + k^2, ...
   of its subset (each the VPL gim__vpl_scramble gives) summed in member order in float; vis
   caches the visibility per map (< 0: not yet). */
static void gim__vpl_pixel(const gim_vpl_shade_desc *d, const gim_receiver *rc, uint32_t s, uint32_t step, float *vis,
                           float *out) {
    const float pi = (float)GIM__PI, near_ = GIM__TWINS_COINCIDENT * d->scene_scale;
    const float dc2 = d->clamp_distance * d->clamp_distance;
    float sd[3] = {0.0f, 0.0f, 0.0f}, sg[3] = {0.0f, 0.0f, 0.0f}, scale, fd, fg;
    uint32_t j, i, count = 0, near_n = 0;
    int a;
    for (j = s; j < d->vpl_count; j += step) {
        const gim_vpl *v = d->vpls + (i = gim__vpl_scramble(j, d->vpl_count));
        float dx, dy, dz, d2, dist, ox, oy, oz, cl, cx, vv = 1.0f, g, rx, ry, rz, lobe;
        ++count;
        if (!(v->lit > 0.0f)) continue;
        dx = rc->position[0] - v->position[0];
        dy = rc->position[1] - v->position[1];
        dz = rc->position[2] - v->position[2];
        d2 = dx * dx + dy * dy + dz * dz;
        dist = sqrtf(d2);
        if (!(dist > near_)) continue;                    /* no direction */
        ox = dx / dist; oy = dy / dist; oz = dz / dist;   /* omega, VPL -> receiver */
        cl = v->normal[0] * ox + v->normal[1] * oy + v->normal[2] * oz;
        cx = -(rc->normal[0] * ox + rc->normal[1] * oy + rc->normal[2] * oz);
        if (!(cl > 0.0f) || !(cx > 0.0f)) continue;
        if (d->cluster && d->cluster[i] != UINT32_MAX) {
            uint32_t m = d->cluster[i];
            if (vis[m] < 0.0f)
                vis[m] = gim__paraboloid_vis(d->distance + (size_t)m * d->map_size * d->map_size, d->map_size, d->maps + m,
                                             rc->position, rc->normal);
            vv = vis[m];
        } else if (d->ism && (!d->cluster || i >= d->ism_first)) {   /* its own map, hard (gim_ism_visibility_twin's lookup) */
            uint32_t size = d->ism_size ? d->ism_size : GIM_ISM_DEFAULT_SIZE, map = d->cluster ? i - d->ism_first : i;
            float o[3], bias = d->ism_bias > 0.0f ? d->ism_bias : GIM_ISM_BIAS;
            float texel = (d->ism_slope > 0.0f ? d->ism_slope : GIM_ISM_SLOPE) * 2.0f / (float)size;
            gim_vec3 t, b, n;
            gim__ism_frame(v->position, v->normal, GIM_ISM_LIFT * d->scene_scale, o, &t, &b, &n);
            vv = gim__ism_visible(d->ism + (size_t)map * size * size, size, o, t, b, n, rc->position, rc->normal, bias, texel);
        }
        /* E_i / Phi_i: Krivanek's clamping, max(d^2, d_c^2); near its patch, the patch's */
        if (v->area > 0.0f && d2 < GIM__VAL_NEAR * GIM__VAL_NEAR * v->area && near_n++ < GIM__VPL_NEAR_CAP) {
            float o[3];
            o[0] = ox; o[1] = oy; o[2] = oz;
            g = vv * gim__vpl_near(o, dist, rc->normal, v->normal, v->area, cl * cx / (pi * (d2 > dc2 ? d2 : dc2)));
            ox = o[0]; oy = o[1]; oz = o[2];
            cx = -(rc->normal[0] * ox + rc->normal[1] * oy + rc->normal[2] * oz);
        } else {
            g = cl * cx * vv / (pi * (d2 > dc2 ? d2 : dc2));
        }
        /* r_i = -omega mirrored at n_x: 2 (n_x . -omega) n_x + omega */
        rx = 2.0f * cx * rc->normal[0] + ox;
        ry = 2.0f * cx * rc->normal[1] + oy;
        rz = 2.0f * cx * rc->normal[2] + oz;
        lobe = gim__lobe(rx * rc->view[0] + ry * rc->view[1] + rz * rc->view[2], rc->exponent);
        for (a = 0; a < 3; ++a) {
            float e = v->flux[a] * g;
            sd[a] += e;
            sg[a] += e * lobe;
        }
    }
    if (count == 0) { out[0] = out[1] = out[2] = 0.0f; return; }
    scale = (float)d->vpl_count / (float)count;              /* N / n_s */
    fd = scale / pi;
    fg = scale * (rc->exponent + 2.0f) / (2.0f * pi);
    for (a = 0; a < 3; ++a) {
        float ed = sd[a] < FLT_MAX ? sd[a] : FLT_MAX, eg = sg[a] < FLT_MAX ? sg[a] : FLT_MAX;
        float o = rc->albedo[a] * (fd * ed) + rc->glossy[a] * (fg * eg);
        out[a] = o < FLT_MAX ? o : FLT_MAX;
    }
}

GIMANY_DEF gim_result gim_vpl_shade_twin(const gim_vpl_shade_desc *desc, float *radiance_out) {
    static const char fn[] = "gim_vpl_shade_twin";
    gim_result r;
    float *vis = NULL;
    uint32_t x, y, k, m;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    if (!radiance_out) return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, fn, "radiance_out is NULL");
    if ((r = gim__check_vpl_shade(desc, fn)) != GIM_OK) return r;
    if (desc->cluster) {
        vis = (float *)gim__alloc_array(&desc->env, desc->map_count, sizeof(float));
        if (!vis) return gim__fail(&desc->env, GIM_ERROR_OUT_OF_MEMORY, fn, "visibility of %u maps", desc->map_count);
    }
    k = desc->interleave > 1u ? desc->interleave : 1u;
    for (y = 0; y < desc->height; ++y)
        for (x = 0; x < desc->width; ++x) {
            size_t p = (size_t)y * desc->width + x;
            const gim_receiver *rc = desc->receivers + p;
            if (!gim__receiver_surface(rc)) {
                radiance_out[p * 3] = radiance_out[p * 3 + 1] = radiance_out[p * 3 + 2] = 0.0f;
                continue;
            }
            for (m = 0; vis && m < desc->map_count; ++m) vis[m] = -1.0f;
            gim__vpl_pixel(desc, rc, x % k + k * (y % k), k * k, vis, radiance_out + p * 3);
        }
    gim__free(&desc->env, vis);
    return GIM_OK;
}

GIMANY_DEF gim_result gim_geometry_blur_twin(const gim_blur_desc *desc, float *out) {
    static const char fn[] = "gim_geometry_blur_twin";
    const gim_env *env;
    uint32_t x, y, k, i, w, h;
    float tol2, ncos;
    if (!desc) return GIM_ERROR_INVALID_ARGUMENT;
    env = &desc->env;
    w = desc->width; h = desc->height;
    if (!out || !desc->radiance || !desc->receivers || w == 0 || h == 0)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "radiance, receivers, out, width and height are required");
    if ((uint64_t)w * h > (uint64_t)SIZE_MAX / 16u) return gim__fail(env, GIM_ERROR_OUT_OF_RANGE, fn, "%u x %u pixels", w, h);
    if (desc->radiance == out) return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "out must not be the input");
    if (desc->window > GIM__VPL_MAX_INTERLEAVE)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "window %u exceeds %u", desc->window, GIM__VPL_MAX_INTERLEAVE);
    if (!gim__isfinitef(desc->position_tolerance) || !(desc->position_tolerance > 0.0f))
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "position_tolerance must be finite and > 0");
    if (!gim__isfinitef(desc->normal_tolerance) || desc->normal_tolerance < -1.0f || desc->normal_tolerance > 1.0f)
        return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "normal_tolerance must be in [-1, 1]");
    for (i = 0; i < w * h; ++i) {
        if (!gim__receiver_ok(desc->receivers + i))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "receiver %u: not finite or normal not unit or zero", i);
        if (!gim__all_finite(desc->radiance + (size_t)i * 3, 3))
            return gim__fail(env, GIM_ERROR_INVALID_ARGUMENT, fn, "radiance of pixel %u is not finite", i);
    }
    k = desc->window > 1u ? desc->window : 1u;
    tol2 = desc->position_tolerance * desc->position_tolerance;
    ncos = desc->normal_tolerance != 0.0f ? desc->normal_tolerance : 0.8f;   /* Laine et al.'s beta */
    for (y = 0; y < h; ++y)
        for (x = 0; x < w; ++x) {
            size_t p = (size_t)y * w + x;
            const gim_receiver *rc = desc->receivers + p;
            /* the window [x - k/2, x - k/2 + k - 1]^2, clipped to the image */
            int32_t x0 = (int32_t)x - (int32_t)(k / 2u), y0 = (int32_t)y - (int32_t)(k / 2u), xx, yy;
            float sum[3] = {0.0f, 0.0f, 0.0f}, cnt[3] = {0.0f, 0.0f, 0.0f};
            int a, gx = gim__receiver_glossy(rc);
            if (!gim__receiver_surface(rc)) {
                out[p * 3] = out[p * 3 + 1] = out[p * 3 + 2] = 0.0f;
                continue;
            }
            for (yy = y0 < 0 ? 0 : y0; yy < y0 + (int32_t)k && yy < (int32_t)h; ++yy)
                for (xx = x0 < 0 ? 0 : x0; xx < x0 + (int32_t)k && xx < (int32_t)w; ++xx) {
                    size_t q = (size_t)yy * w + (size_t)xx;
                    const gim_receiver *nb = desc->receivers + q;
                    if (q != p) {
                        float dx, dy, dz, c;
                        if (!gim__receiver_surface(nb) || gim__receiver_glossy(nb) != gx) continue;
                        dx = nb->position[0] - rc->position[0];
                        dy = nb->position[1] - rc->position[1];
                        dz = nb->position[2] - rc->position[2];
                        if (!(dx * dx + dy * dy + dz * dz <= tol2)) continue;
                        c = nb->normal[0] * rc->normal[0] + nb->normal[1] * rc->normal[1] + nb->normal[2] * rc->normal[2];
                        if (!(c >= ncos)) continue;
                    }
                    for (a = 0; a < 3; ++a) {
                        if (gx) {
                            sum[a] += desc->radiance[q * 3 + (size_t)a];
                            cnt[a] += 1.0f;
                        } else if (nb->albedo[a] > 0.0f) {   /* the light, without the neighbour's albedo */
                            sum[a] += desc->radiance[q * 3 + (size_t)a] / nb->albedo[a];
                            cnt[a] += 1.0f;
                        }
                    }
                }
            for (a = 0; a < 3; ++a) {
                float o = cnt[a] > 0.0f ? sum[a] / cnt[a] : 0.0f;
                if (!gx) o = rc->albedo[a] > 0.0f ? rc->albedo[a] * o : 0.0f;   /* no albedo: no light, even from an overflowed sum */
                out[p * 3 + (size_t)a] = gim__isfinitef(o) ? o : (o > 0.0f ? FLT_MAX : -FLT_MAX);
            }
        }
    return GIM_OK;
}

/* @impl gl ================================================================================ */
#ifndef GIMANY_NO_GL
#include "shaders_embedded.h"
#include <time.h>

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
typedef struct gim__GLsync_ *gim__GLsync;

enum {
    GIM__GL_NO_ERROR = 0,
    GIM__GL_FALSE = 0,
    GIM__GL_TRUE = 1,
    GIM__GL_VENDOR = 0x1F00,
    GIM__GL_RENDERER = 0x1F01,
    GIM__GL_VERSION = 0x1F02,
    GIM__GL_SHADING_LANGUAGE_VERSION = 0x8B8C,
    GIM__GL_EXTENSIONS = 0x1F03,
    GIM__GL_NUM_EXTENSIONS = 0x821D,
    GIM__GL_MAJOR_VERSION = 0x821B,
    GIM__GL_MINOR_VERSION = 0x821C,
    GIM__GL_CURRENT_PROGRAM = 0x8B8D,
    GIM__GL_VERTEX_ARRAY_BINDING = 0x85B5,
    GIM__GL_ARRAY_BUFFER = 0x8892,
    GIM__GL_ARRAY_BUFFER_BINDING = 0x8894,
    GIM__GL_ELEMENT_ARRAY_BUFFER = 0x8893,
    GIM__GL_COPY_READ_BUFFER = 0x8F36,
    GIM__GL_COPY_READ_BUFFER_BINDING = 0x8F36,
    GIM__GL_COPY_WRITE_BUFFER = 0x8F37,
    GIM__GL_COPY_WRITE_BUFFER_BINDING = 0x8F37,
    GIM__GL_SHADER_STORAGE_BUFFER = 0x90D2,
    GIM__GL_SHADER_STORAGE_BUFFER_BINDING = 0x90D3,
    GIM__GL_SHADER_STORAGE_BUFFER_START = 0x90D4,
    GIM__GL_SHADER_STORAGE_BUFFER_SIZE = 0x90D5,
    GIM__GL_DRAW_FRAMEBUFFER = 0x8CA9,
    GIM__GL_DRAW_FRAMEBUFFER_BINDING = 0x8CA6,
    GIM__GL_VIEWPORT = 0x0BA2,
    GIM__GL_BLEND = 0x0BE2,
    GIM__GL_CULL_FACE = 0x0B44,
    GIM__GL_DEPTH_TEST = 0x0B71,
    GIM__GL_SCISSOR_TEST = 0x0C11,
    GIM__GL_PRIMITIVE_RESTART = 0x8F9D,
    GIM__GL_RASTERIZER_DISCARD = 0x8C89,
    GIM__GL_POLYGON_OFFSET_FILL = 0x8037,
    GIM__GL_DEPTH_CLAMP = 0x864F,
    GIM__GL_DEPTH_FUNC = 0x0B74,
    GIM__GL_DEPTH_WRITEMASK = 0x0B72,
    GIM__GL_COLOR_WRITEMASK = 0x0C23,
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
    GIM__GL_COMPUTE_SHADER = 0x91B9,
    GIM__GL_VERTEX_SHADER = 0x8B31,
    GIM__GL_FRAGMENT_SHADER = 0x8B30,
    GIM__GL_GEOMETRY_SHADER = 0x8DD9,
    GIM__GL_COMPILE_STATUS = 0x8B81,
    GIM__GL_LINK_STATUS = 0x8B82,
    GIM__GL_SHADER_STORAGE_BARRIER_BIT = 0x00002000,
    GIM__GL_TEXTURE_FETCH_BARRIER_BIT = 0x00000008,
    GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT = 0x00000020,
    GIM__GL_BUFFER_UPDATE_BARRIER_BIT = 0x00000200,
    GIM__GL_DYNAMIC_COPY = 0x88EA,
    GIM__GL_R32F = 0x822E,
    GIM__GL_RGBA32F = 0x8814,
    GIM__GL_READ_ONLY = 0x88B8,
    GIM__GL_R8 = 0x8229,
    GIM__GL_FLOAT = 0x1406,
    GIM__GL_MAX_SHADER_STORAGE_BLOCK_SIZE = 0x90DE,
    GIM__GL_BUFFER_SIZE = 0x8764,
    GIM__GL_TEXTURE_WIDTH = 0x1000,
    GIM__GL_TEXTURE_HEIGHT = 0x1001,
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
    GIM__GL_POLYGON_SMOOTH = 0x0B41,
    GIM__GL_WRITE_ONLY = 0x88B9,
    GIM__GL_TIMESTAMP = 0x8E28,
    GIM__GL_QUERY_RESULT = 0x8866,
    GIM__GL_DYNAMIC_DRAW = 0x88E8,
    GIM__GL_TEXTURE_UPDATE_BARRIER_BIT = 0x00000100,
    GIM__GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT = 0x90DF,
    GIM__GL_TEXTURE_INTERNAL_FORMAT = 0x1003,
    GIM__GL_RGBA32UI = 0x8D70,
    GIM__GL_MAX_ARRAY_TEXTURE_LAYERS = 0x88FF,
    GIM__GL_MAX_FRAMEBUFFER_LAYERS = 0x9317,
    GIM__GL_COLOR_LOGIC_OP = 0x0BF2,
    GIM__GL_PRIMITIVE_RESTART_FIXED_INDEX = 0x8D69,
    GIM__GL_PROVOKING_VERTEX = 0x8E4F,
    GIM__GL_LAST_VERTEX_CONVENTION = 0x8E4E,
    GIM__GL_CLIP_ORIGIN = 0x935C,
    GIM__GL_CLIP_DEPTH_MODE = 0x935D,
    GIM__GL_LOWER_LEFT = 0x8CA1,
    GIM__GL_NEGATIVE_ONE_TO_ONE = 0x935E,
    GIM__GL_TEXTURE_TARGET = 0x1006,
    GIM__GL_TEXTURE_SWIZZLE_R = 0x8E42,
    GIM__GL_TEXTURE_BASE_LEVEL = 0x813C,
    GIM__GL_DEPTH_STENCIL_TEXTURE_MODE = 0x90EA,
    GIM__GL_DEPTH_COMPONENT = 0x1902,
    GIM__GL_SYNC_GPU_COMMANDS_COMPLETE = 0x9117,
    GIM__GL_ALREADY_SIGNALED = 0x911A,
    GIM__GL_CONDITION_SATISFIED = 0x911C
};

/* Every GL function gimany calls: X(return type, name without "gl", parameter list). */
#define GIM__GL_FUNCS(X)                                                                          \
    X(gim__GLenum, GetError, (void))                                                              \
    X(const unsigned char *, GetString, (gim__GLenum name))                                      \
    X(const unsigned char *, GetStringi, (gim__GLenum name, gim__GLuint index))                  \
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
    X(void, DepthFunc, (gim__GLenum func))                                                       \
    X(void, DepthMask, (gim__GLboolean flag))                                                    \
    X(void, PolygonMode, (gim__GLenum face, gim__GLenum mode))                                   \
    X(void, ActiveTexture, (gim__GLenum texture))                                                \
    X(void, BindTexture, (gim__GLenum target, gim__GLuint texture))                              \
    X(void, BindSampler, (gim__GLuint unit, gim__GLuint sampler))                                \
    X(void, BindImageTexture, (gim__GLuint unit, gim__GLuint texture, gim__GLint level,          \
                               gim__GLboolean layered, gim__GLint layer, gim__GLenum access,     \
                               gim__GLenum format))                                              \
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
    X(void, Uniform3i, (gim__GLint location, gim__GLint v0, gim__GLint v1, gim__GLint v2))       \
    X(void, Uniform2d, (gim__GLint location, double v0, double v1))                              \
    X(void, GenBuffers, (gim__GLsizei n, gim__GLuint *buffers))                                  \
    X(gim__GLboolean, IsBuffer, (gim__GLuint buffer))                                           \
    X(gim__GLboolean, IsProgram, (gim__GLuint program))                                         \
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
    X(void, CopyBufferSubData, (gim__GLenum read_target, gim__GLenum write_target,               \
                                gim__GLintptr read_offset, gim__GLintptr write_offset,           \
                                gim__GLsizeiptr size))                                           \
    X(gim__GLboolean, IsEnabledi, (gim__GLenum cap, gim__GLuint index))                          \
    X(void, Enablei, (gim__GLenum cap, gim__GLuint index))                                       \
    X(void, Disablei, (gim__GLenum cap, gim__GLuint index))                                      \
    X(void, GetBooleani_v, (gim__GLenum target, gim__GLuint index, gim__GLboolean *data))        \
    X(void, ColorMaski, (gim__GLuint buf, gim__GLboolean r, gim__GLboolean g, gim__GLboolean b,  \
                         gim__GLboolean a))                                                      \
    X(void, GenQueries, (gim__GLsizei n, gim__GLuint *ids))                                      \
    X(void, DeleteQueries, (gim__GLsizei n, const gim__GLuint *ids))                             \
    X(void, QueryCounter, (gim__GLuint id, gim__GLenum target))                                  \
    X(void, Finish, (void))                                                                      \
    X(void, GetQueryObjectui64v, (gim__GLuint id, gim__GLenum pname, uint64_t *params))         \
    X(void, TexStorage3D, (gim__GLenum target, gim__GLsizei levels, gim__GLenum format,          \
                           gim__GLsizei width, gim__GLsizei height, gim__GLsizei depth))         \
    X(void, FramebufferTexture, (gim__GLenum target, gim__GLenum attachment, gim__GLuint texture, \
                                 gim__GLint level))                                              \
    X(void, DrawElementsInstanced, (gim__GLenum mode, gim__GLsizei count, gim__GLenum type,      \
                                    const void *indices, gim__GLsizei instancecount))            \
    X(void, ProvokingVertex, (gim__GLenum mode))                                                 \
    X(void, GetBufferSubData, (gim__GLenum target, gim__GLintptr offset, gim__GLsizeiptr size, void *data)) \
    X(void, GetTexParameteriv, (gim__GLenum target, gim__GLenum pname, gim__GLint *params))      \
    X(gim__GLsync, FenceSync, (gim__GLenum condition, gim__GLbitfield flags))                   \
    X(gim__GLenum, ClientWaitSync, (gim__GLsync sync, gim__GLbitfield flags, uint64_t timeout))  \
    X(void, DeleteSync, (gim__GLsync sync))

/* The function table, filled by gim__gl_load. */
typedef struct gim__gl {
#define GIM__X(ret, name, args) ret(GIM__APIENTRY *name) args;
    GIM__GL_FUNCS(GIM__X)
#undef GIM__X
    /* GL 4.5 or GL_ARB_clip_control (NULL without): a host's GL_ZERO_TO_ONE or GL_UPPER_LEFT
       would move or flip every draw, so gimany sets the default around its passes when it can */
    void(GIM__APIENTRY *ClipControl)(gim__GLenum origin, gim__GLenum depth);
    /* GL 4.5 or GL_ARB_direct_state_access: asks a host texture's target without a failing bind
       (a GL error for the host) */
    void(GIM__APIENTRY *GetTextureParameteriv)(gim__GLuint texture, gim__GLenum pname, gim__GLint *params);
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
    /* optional: kept by gim_create only on a 4.5 context or where the extension is listed (a
       driver that creates the 4.3 context asked for gives exactly 4.3 and lists them: NVIDIA) */
    if (get_proc_address) {
        gl->ClipControl = (void(GIM__APIENTRY *)(gim__GLenum, gim__GLenum))get_proc_address("glClipControl");
        gl->GetTextureParameteriv = (void(GIM__APIENTRY *)(gim__GLuint, gim__GLenum, gim__GLint *))get_proc_address(
            "glGetTextureParameteriv");
    }
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

/* 1 if the context lists the extension (glGetStringi: once per name at gim_create). */
static int gim__gl_has_extension(const gim__gl *gl, const char *name) {
    gim__GLint count = 0, i;
    gl->GetIntegerv(GIM__GL_NUM_EXTENSIONS, &count);
    for (i = 0; i < count; ++i) {
        const char *e = (const char *)gl->GetStringi(GIM__GL_EXTENSIONS, (gim__GLuint)i);
        if (e && strcmp(e, name) == 0) return 1;
    }
    return 0;
}

/* --- GL state save/restore ----------------------------------------------------------------
   The GL state gimany may touch, in one place. gim__gl_enter saves it on the way into the
   outermost call that touches GL, gim__gl_leave restores it on the way out; what is not listed
   here gimany must not change. Each item read is a GL query, a round trip on threaded drivers
   (NVIDIA's threaded optimisation, Mesa's glthread), so the list holds only what some call
   changes; state a call merely reads is made harmless instead of saved. Units and bindings are
   those gimany's passes use (within GL 4.3's minimums: 8 image units, 8 SSBO bindings, 80
   texture units, 8 draw buffers, 8 clip distances).
   Read but not saved: clip distances (the last vertex stage of every draw, scene.vert and
   paraboloid.geom, writes gl_ClipDistance[0..7] = 1, so a host's enabled planes clip nothing);
   texture state (reads go through gimany's nearest sampler; the texture state of a host's
   G-buffer, swizzle, base level, depth-stencil mode, is the host's and checked instead,
   gim__gl_check_host_gbuffer). Clip control and the provoking vertex are
   saved and set to GL's defaults for the call (gim__gl_state_baseline): the provoking vertex
   changes images although every flat value gimany draws (paraboloid.geom's) is the same on all
   vertices of its primitive, because llvmpipe sets triangles up from it (the last bit of
   interpolated values differs: gltest_hoststate with GL_FIRST_VERTEX_CONVENTION, every
   method). The draws set the rest of the list (gim__gl_raster_state).
   Neither read nor changed, so not saved: the pixel store and the pixel pack/unpack buffers (no
   call moves pixels to or from client memory: no glReadPixels, glTexSubImage, glGetTexImage,
   and no glClearBufferData with a clear value, see gim__gl_clusters_reset); the uniform and
   indirect buffer bindings (no shader has a uniform block, no draw or dispatch is indirect);
   the read framebuffer (gimany binds its FBOs to GL_DRAW_FRAMEBUFFER only); the element array
   buffer (VAO state, bound only with gimany's own mesh VAOs); the blend enable and colour mask
   of draw buffers GIM__GL_DRAW_BUFFERS and up (gimany sets those of its own attachments only,
   glDisablei / glColorMaski, never the glDisable(GL_BLEND) / glColorMask that set all eight);
   and state no call sets: blend functions and equations (blending is off in every draw),
   clear values (glClearBuffer* takes its own), front face and cull mode (culling is off), the
   scissor box (the scissor test is off). */
#define GIM__GL_TEXTURE_UNITS 7  /* the shaders' sampler bindings are 0-6 */
/* of those, the units (bits) bound to 2D arrays: 0-2 (second_bounce.comp), 4 (vpl_shade.comp) */
#define GIM__GL_TEXTURE_ARRAY_UNITS 0x17u
#define GIM__GL_IMAGE_UNITS 3    /* the shaders' image bindings are 0-2 */
#define GIM__GL_SSBO_BINDINGS 8  /* and their SSBO bindings 0-7 (proxy_lights.comp reads the ISM at 7) */
#define GIM__GL_DRAW_BUFFERS 4   /* gimany's FBOs' colour attachments: 3 (RSM, G-buffer), 4 (paraboloids) */

/* glEnable/glDisable capabilities, all off in GL's initial state; every draw turns them off but
   the depth test (gim__gl_raster_state). Not listed, because they cannot change a draw of gimany's:
   the stencil test (its FBOs have no stencil buffer, so the test passes: GL 4.5, "Stencil Test")
   and GL_FRAMEBUFFER_SRGB (it encodes only sRGB attachments, and gimany's are float: "sRGB
   Conversion"); each item left out is a query fewer a call */
static const gim__GLenum gim__gl_state_caps[] = {
    GIM__GL_CULL_FACE, GIM__GL_DEPTH_TEST, GIM__GL_SCISSOR_TEST,
    GIM__GL_PRIMITIVE_RESTART, GIM__GL_RASTERIZER_DISCARD, GIM__GL_POLYGON_OFFSET_FILL,
    GIM__GL_DEPTH_CLAMP,
    /* polygon smoothing would scale the RSM's alpha (the lit flag) at edges */
    GIM__GL_POLYGON_SMOOTH,
    /* a logic op replaces the writes to integer targets (the G-buffer's material); a fixed
       restart index would cut a mesh with 65535 or 2^32-1 vertices */
    GIM__GL_COLOR_LOGIC_OP, GIM__GL_PRIMITIVE_RESTART_FIXED_INDEX};
#define GIM__GL_STATE_CAPS (sizeof gim__gl_state_caps / sizeof gim__gl_state_caps[0])

/* Non-indexed buffer bindings gimany changes: {target, its binding query} (meshes are uploaded
   through ARRAY_BUFFER, buffers copied and read back through COPY_READ/WRITE, SSBOs sized
   through SHADER_STORAGE_BUFFER). The generic SSBO binding comes after the indexed ones on
   restore, because glBindBufferBase/Range also sets it. */
static const gim__GLenum gim__gl_state_buffers[][2] = {
    {GIM__GL_ARRAY_BUFFER, GIM__GL_ARRAY_BUFFER_BINDING},
    {GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_READ_BUFFER_BINDING},
    {GIM__GL_COPY_WRITE_BUFFER, GIM__GL_COPY_WRITE_BUFFER_BINDING},
    {GIM__GL_SHADER_STORAGE_BUFFER, GIM__GL_SHADER_STORAGE_BUFFER_BINDING}};
#define GIM__GL_STATE_BUFFERS (sizeof gim__gl_state_buffers / sizeof gim__gl_state_buffers[0])

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
    gim__GLint program, vertex_array, draw_framebuffer;
    gim__GLint viewport[4];
    gim__GLboolean caps[GIM__GL_STATE_CAPS];
    gim__GLint buffers[GIM__GL_STATE_BUFFERS];
    gim__GLint depth_func;
    gim__GLboolean depth_mask;
    /* per draw buffer of gimany's FBOs (glEnablei/glColorMaski) */
    gim__GLboolean blend_i[GIM__GL_DRAW_BUFFERS], color_mask_i[GIM__GL_DRAW_BUFFERS][4];
    gim__GLint polygon_mode[2];
    double depth_range[2];
    gim__GLint active_texture;
    gim__GLint texture_2d[GIM__GL_TEXTURE_UNITS], texture_2d_array[GIM__GL_TEXTURE_UNITS];
    gim__GLint sampler[GIM__GL_TEXTURE_UNITS];
    gim__gl_image_binding image[GIM__GL_IMAGE_UNITS];
    gim__gl_indexed_buffer ssbo[GIM__GL_SSBO_BINDINGS];
    gim__GLint provoking_vertex;
    gim__GLint clip_origin, clip_depth_mode;  /* with ClipControl only */
} gim__gl_state;

static void gim__gl_indexed_save(const gim__gl *gl, gim__GLenum binding, gim__GLenum start, gim__GLenum size,
                                 gim__gl_indexed_buffer *b, unsigned count) {
    unsigned i;
    for (i = 0; i < count; ++i) {
        gl->GetIntegeri_v(binding, i, &b[i].buffer);
        if (!b[i].buffer) continue; /* binding 0 resets start and size to 0: nothing more to ask */
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
    gl->GetIntegerv(GIM__GL_DRAW_FRAMEBUFFER_BINDING, &s->draw_framebuffer);
    gl->GetIntegerv(GIM__GL_VIEWPORT, s->viewport);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) s->caps[i] = gl->IsEnabled(gim__gl_state_caps[i]);
    for (i = 0; i < GIM__GL_STATE_BUFFERS; ++i) gl->GetIntegerv(gim__gl_state_buffers[i][1], &s->buffers[i]);
    gl->GetIntegerv(GIM__GL_DEPTH_FUNC, &s->depth_func);
    gl->GetBooleanv(GIM__GL_DEPTH_WRITEMASK, &s->depth_mask);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        s->blend_i[i] = gl->IsEnabledi(GIM__GL_BLEND, i);
        gl->GetBooleani_v(GIM__GL_COLOR_WRITEMASK, i, s->color_mask_i[i]);
    }
    gl->GetIntegerv(GIM__GL_POLYGON_MODE, s->polygon_mode); /* front and back; core has one mode */
    gl->GetDoublev(GIM__GL_DEPTH_RANGE, s->depth_range);
    gl->GetIntegerv(GIM__GL_ACTIVE_TEXTURE, &s->active_texture);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->GetIntegerv(GIM__GL_TEXTURE_BINDING_2D, &s->texture_2d[i]);
        if (GIM__GL_TEXTURE_ARRAY_UNITS >> i & 1u)
            gl->GetIntegerv(GIM__GL_TEXTURE_BINDING_2D_ARRAY, &s->texture_2d_array[i]);
        gl->GetIntegerv(GIM__GL_SAMPLER_BINDING, &s->sampler[i]);
    }
    gl->ActiveTexture((gim__GLenum)s->active_texture);
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) {
        gim__gl_image_binding *b = &s->image[i];
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_NAME, i, &b->texture);
        if (!b->texture) { /* unbinding resets the unit to its initial state: nothing more to ask */
            b->access = GIM__GL_READ_ONLY;
            b->format = GIM__GL_R8;
            continue;
        }
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LEVEL, i, &b->level);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LAYERED, i, &b->layered);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_LAYER, i, &b->layer);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_ACCESS, i, &b->access);
        gl->GetIntegeri_v(GIM__GL_IMAGE_BINDING_FORMAT, i, &b->format);
    }
    gim__gl_indexed_save(gl, GIM__GL_SHADER_STORAGE_BUFFER_BINDING, GIM__GL_SHADER_STORAGE_BUFFER_START,
                         GIM__GL_SHADER_STORAGE_BUFFER_SIZE, s->ssbo, GIM__GL_SSBO_BINDINGS);
    gl->GetIntegerv(GIM__GL_PROVOKING_VERTEX, &s->provoking_vertex);
    if (gl->ClipControl) {
        gl->GetIntegerv(GIM__GL_CLIP_ORIGIN, &s->clip_origin);
        gl->GetIntegerv(GIM__GL_CLIP_DEPTH_MODE, &s->clip_depth_mode);
    }
}

/* State gimany's passes read but do not each set, put to GL's defaults for the whole call
   (after the save): clip control, the provoking vertex; and texture unit 0 active, so that the
   checks of a host's G-buffer, which bind it on the active unit, bind it on a unit of the list.
   The raster passes set the rest of the list themselves (gim__gl_raster_state). */
static void gim__gl_state_baseline(const gim__gl *gl) {
    gl->ActiveTexture(GIM__GL_TEXTURE0);
    gl->ProvokingVertex(GIM__GL_LAST_VERTEX_CONVENTION);
    if (gl->ClipControl) gl->ClipControl(GIM__GL_LOWER_LEFT, GIM__GL_NEGATIVE_ONE_TO_ONE);
}

/* Set every item of the list to s's values (the viewport only with viewport != 0). */
static void gim__gl_state_apply(const gim__gl *gl, const gim__gl_state *s, int viewport) {
    unsigned i;
    /* the host may have deleted its program while current: it lived only as long as it stayed
       current, and binding the dead name would leave GL_INVALID_VALUE for the host (imgui's guard) */
    if (s->program == 0 || gl->IsProgram((gim__GLuint)s->program)) gl->UseProgram((gim__GLuint)s->program);
    else gl->UseProgram(0);
    gl->BindVertexArray((gim__GLuint)s->vertex_array);
    gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, (gim__GLuint)s->draw_framebuffer);
    if (viewport) gl->Viewport(s->viewport[0], s->viewport[1], s->viewport[2], s->viewport[3]);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) {
        if (s->caps[i]) gl->Enable(gim__gl_state_caps[i]);
        else gl->Disable(gim__gl_state_caps[i]);
    }
    gl->DepthFunc((gim__GLenum)s->depth_func);
    gl->DepthMask(s->depth_mask);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        if (s->blend_i[i]) gl->Enablei(GIM__GL_BLEND, i);
        else gl->Disablei(GIM__GL_BLEND, i);
        gl->ColorMaski(i, s->color_mask_i[i][0], s->color_mask_i[i][1], s->color_mask_i[i][2], s->color_mask_i[i][3]);
    }
    gl->PolygonMode(GIM__GL_FRONT_AND_BACK, (gim__GLenum)s->polygon_mode[0]);
    gl->DepthRange(s->depth_range[0], s->depth_range[1]);
    for (i = 0; i < GIM__GL_TEXTURE_UNITS; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->BindTexture(GIM__GL_TEXTURE_2D, (gim__GLuint)s->texture_2d[i]);
        if (GIM__GL_TEXTURE_ARRAY_UNITS >> i & 1u)
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
    for (i = 0; i < GIM__GL_STATE_BUFFERS; ++i)
        gl->BindBuffer(gim__gl_state_buffers[i][0], (gim__GLuint)s->buffers[i]);
    gl->ProvokingVertex((gim__GLenum)s->provoking_vertex);
    if (gl->ClipControl) gl->ClipControl((gim__GLenum)s->clip_origin, (gim__GLenum)s->clip_depth_mode);
}

static void gim__gl_state_restore(const gim__gl *gl, const gim__gl_state *s) {
    gim__gl_state_apply(gl, s, 1);
}

/* GIM_GL_STATE_RESET's exit: every item of the list at GL's initial value but the viewport
   (which has none a library can know). Sets only; no query. */
static void gim__gl_state_reset(const gim__gl *gl) {
    gim__gl_state s;
    unsigned i, k;
    memset(&s, 0, sizeof s);   /* bindings 0, capabilities and blending off */
    s.depth_func = GIM__GL_LESS;
    s.depth_mask = GIM__GL_TRUE;
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i)
        for (k = 0; k < 4; ++k) s.color_mask_i[i][k] = GIM__GL_TRUE;
    s.polygon_mode[0] = s.polygon_mode[1] = GIM__GL_FILL;
    s.depth_range[1] = 1.0;
    s.active_texture = GIM__GL_TEXTURE0;
    for (i = 0; i < GIM__GL_IMAGE_UNITS; ++i) {
        s.image[i].access = GIM__GL_READ_ONLY;
        s.image[i].format = GIM__GL_R8;
    }
    s.provoking_vertex = GIM__GL_LAST_VERTEX_CONVENTION;
    s.clip_origin = GIM__GL_LOWER_LEFT;
    s.clip_depth_mode = GIM__GL_NEGATIVE_ONE_TO_ONE;
    gim__gl_state_apply(gl, &s, 0);
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
    GIM__PROGRAM_PROXY_LIGHTS,       /* LightSkin proxy lights per cache (eq. 3-7, 13-15) */
    GIM__PROGRAM_LIGHTSKIN_SHADE,    /* neighbours, interpolation (eq. 8-9) and shading per pixel */
    GIM__PROGRAM_RSM_GATHER,         /* RSM gather per pixel (Dachsbacher 2005) */
    GIM__PROGRAM_VALS_GATHER,        /* RSM texels (all, or the selected ones) -> VAL list */
    GIM__PROGRAM_RSM_VPLS,           /* VPLs at the RSM's Halton texels, flux to the RSM's total (Dong sec. 4) */
    GIM__PROGRAM_KMEANS_ASSIGN,      /* k-means assignment per VPL (Dong 5.1, SSVP eq. 2) */
    GIM__PROGRAM_KMEANS_UPDATE,      /* k-means flux-weighted means per cluster (a gather) */
    GIM__PROGRAM_CLUSTERS,           /* k-means seeds; the clusters' VALs and paraboloid maps */
    GIM__PROGRAM_PARABOLOID,         /* paraboloid maps of the clusters, one layer each (Dong sec. 4.2) */
    GIM__PROGRAM_SECOND_BOUNCE,      /* second-bounce VPLs from the maps (SSVP sec. 3.C) */
    GIM__PROGRAM_VPL_SHADE,          /* VPL shading per pixel: soft visibility, clamping, interleaving (Dong sec. 6) */
    GIM__PROGRAM_GEOMETRY_BLUR,      /* geometry-aware blur (Dong sec. 6, Laine et al.) */
    GIM__PROGRAM_ISM,                /* imperfect shadow maps of the caches (Ritschel et al. 2008) */
    GIM__PROGRAM_GBUFFER_DECODE,     /* the host's packed normals / view-space depth to gimany's layout */
    GIM__PROGRAM_CACHES_FOLLOW,      /* a deforming mesh's caches moved with their triangles; its bounds */
    GIM__PROGRAM_IMPORTANCE_TILES,   /* eq. 10-11 per tile of the two-level map, texel weights */
    GIM__PROGRAM_ISM_FROM_PARABOLOID, /* the VPLs' triangle shadow maps into the ISM format */
    GIM__PROGRAM_SECOND_BOUNCE_RAYS, /* second-bounce VPLs by rays from the first (Keller 1997) */
    GIM__PROGRAM_COUNT
} gim__program_id;

/* Shader files of each program (compute: one file; draw programs: vertex, [geometry,] fragment). */
static const char *const gim__program_files[GIM__PROGRAM_COUNT][3] = {
    {"importance_map.comp", NULL},
    {"importance_scan_columns.comp", NULL},
    {"importance_scan_totals.comp", NULL},
    {"importance_scan_offsets.comp", NULL},
    {"importance_select.comp", NULL},
    {"scene.vert", "rsm.frag"},
    {"scene.vert", "gbuffer.frag"},
    {"view_samples.comp", NULL},
    {"proxy_lights.comp", NULL},
    {"lightskin_shade.comp", NULL},
    {"rsm_gather.comp", NULL},
    {"vals_gather.comp", NULL},
    {"rsm_vpls.comp", NULL},
    {"kmeans_assign.comp", NULL},
    {"kmeans_update.comp", NULL},
    {"clusters.comp", NULL},
    {"paraboloid.vert", "paraboloid.geom", "paraboloid.frag"},
    {"second_bounce.comp", NULL},
    {"vpl_shade.comp", NULL},
    {"geometry_blur.comp", NULL},
    {"ism.comp", NULL},
    {"gbuffer_decode.comp", NULL},
    {"caches_follow.comp", NULL},
    {"importance_tiles.comp", NULL},
    {"ism_from_paraboloid.comp", NULL},
    {"second_bounce_rays.comp", NULL}};

/* One uploaded mesh (a slot; used == 0: free). */
typedef struct gim__mesh {
    int used;
    uint32_t generation;          /* bumped when the slot is freed, so old handles fail */
    gim__GLuint vao, positions, normals, indices, triangle_material;
    uint32_t index_count, triangle_count;
    gim__GLenum index_type;
    int host_buffers;             /* 1: positions, normals, indices are the host's (gim_mesh_buffers) */
    uint32_t position_offset, position_stride, index_offset;   /* bytes (own buffers: 0, 12, 0) */
    uint32_t max_material;        /* largest material id of its triangles */
    float bmin[3], bmax[3];       /* model-space bounds */
    gim_cache *caches;            /* the host's model-space caches (copied), for later passes */
    uint32_t *cache_material;     /* per cache: the material of its nearest triangle (its glossy lobe); NULL: 0 */
    uint32_t cache_count;
    float theta_eps;              /* of the cache set (0: the generator's default) */
    uint64_t bytes;               /* of its GL buffers */
    /* a deforming mesh only (gim_mesh_desc.deforming; all 0 for a static one, which pays nothing) */
    int deforming;
    int follow_dirty;             /* its vertices changed since the caches last followed them */
    uint32_t vertex_count;
    uint32_t *tri_vertex;         /* own buffers: 3 vertex indices per triangle (vertex normals of new positions) */
    gim__GLuint bound;            /* SSBO: per cache its binding and rest cache (caches_follow.comp's Bound) */
    gim__GLuint followed;         /* SSBO: per cache the followed model-space gim_cache */
    gim_cache *follow_cpu;        /* those read back: the hash grid over the caches is built on the CPU */
} gim__mesh;

/* One light's GL objects, sized to its last frame. */
typedef struct gim__light_gpu {
    uint32_t size;                /* side of the RSM textures; 0: none yet */
    gim__GLuint position, normal, flux, depth, fbo;
    gim__GLuint map, column, row, selected;
    uint64_t map_bytes, column_bytes, row_bytes, selected_bytes;
    gim__GLuint tiles;            /* two-level map (tile > 1): eq. 10-11 per tile; map then holds the texel weights */
    uint64_t tiles_bytes;
    /* the selection's defensive share (gim_frame_lightskin.defensive_share): the texels' luminance
       (lum_map; per tile in lum_tiles with tile > 1, lum_map then the texel weights) and its tables */
    gim__GLuint lum_map, lum_tiles, lum_column, lum_row;
    uint64_t lum_map_bytes, lum_tiles_bytes, lum_column_bytes, lum_row_bytes;
    uint32_t tile, table_side;    /* the tile side of the last BRSM frame, its tables' side (ceil(size / tile)) */
    gim_mat4 view, proj;
    int up_axis;                  /* the up axis of the last camera (gim__up_kept); 0: none */
    gim_vec3 up_dir;              /* the direction of the last camera */
} gim__light_gpu;

/* The hash grid over the world-space caches that lightskin_shade.comp searches. */
typedef struct gim__grid {
    float origin[3], h;          /* cell (i, j, k) covers origin + h [i, i+1) x ... */
    int32_t dims[3];             /* cells per axis over the caches' bounds */
    uint32_t bucket_count;       /* a power of two >= 2 cache_count */
} gim__grid;

/* The LightSkin buffers, sized to the last frame that used them. */
typedef struct gim__lightskin_gpu {
    gim__GLuint caches, cells, buckets, vals, diffuse, glossy;
    uint64_t caches_bytes, cells_bytes, buckets_bytes, vals_bytes, diffuse_bytes, glossy_bytes;
    gim__GLuint exponents;        /* float per world cache: its material's glossy k (glossy scenes only) */
    uint64_t exponents_bytes;
    uint32_t *material;           /* CPU: the material of each world cache, in the grid's order */
    uint64_t exponents_for;       /* the materials_version the exponents were made from; 0: not made */
} gim__lightskin_gpu;

/* The scene's hierarchy on the GPU (neighbour_rays, RAYS, the second bounce's rays): gim_bvh's
   nodes then its triangles, each triangle's first vec4 w its material (gim__gl_bvh). */
typedef struct gim__bvh_gpu {
    gim__GLuint buffer;
    uint64_t bytes, version;      /* the scene_version it was built for */
    float origin[3], scale;       /* its frame (gim_bvh.origin, scale) */
    uint32_t nodes;               /* its node count (the triangles start at vec4 2 nodes) */
} gim__bvh_gpu;

/* The GPU state of the VPL methods (see "the VPL frame"), sized to what the last frame used. */
typedef struct gim__vpl_gpu {
    gim__GLuint vpls;             /* gim_vpl: first bounce (every light's), then the second */
    gim__GLuint staging;          /* one light's VPLs before they are copied behind the others' */
    gim__GLuint cluster_of;       /* uint per VPL: the k-means assignment, 0xffffffff for the second bounce */
    gim__GLuint centres;          /* k-means centres {vec4 centre (w: VPLs), vec4 normal} */
    gim__GLuint maps;             /* gim_paraboloid per cluster */
    uint64_t vpls_bytes, staging_bytes, cluster_of_bytes, centres_bytes, maps_bytes;
    uint32_t warm_clusters, warm_vpls, warm_metric; /* what the centres were made for (the warm start); 0: none */
    /* gim__gl_rsm_vpls' texel list and its sums scratch, kept while its inputs stay the same */
    gim__GLuint texels, sums;
    uint64_t texels_bytes, sums_bytes;
    gim__GLuint kmeans_acc;       /* gim__gl_kmeans_step's per-cluster sums (contents undefined between steps) */
    uint64_t kmeans_acc_bytes;
    uint32_t texels_key[3];       /* count, sequence, size of the list in texels; count 0: none */
    float texels_offsets[3];      /* offsets[0..1], [2] = 1 when offsets were given */
    uint64_t follow_key;          /* gim__vpl_follow_key of the first-bounce VPLs in vpls; 0: none to follow */
    gim__GLuint made;             /* two uints: the VPLs' imperfect shadow maps made so far (ism.comp), and that
                                     count before this frame's maps */
    uint64_t made_bytes;
    /* the second bounce by rays (GIM_SECOND_BOUNCE_RAYS): the rays' samples (kept while their
       count stays: ray_key) */
    gim__GLuint ray_samples;
    uint64_t ray_samples_bytes;
    uint32_t ray_key;
} gim__vpl_gpu;

#define GIM__MAX_STAMPS 96   /* timestamps a frame may take (a pass run per light merges into one) */

struct gim_context {
    gim_env env;
    gim__gl gl;
    int gl_major, gl_minor;
    int clip_control;           /* the context has glClipControl's state (4.5, GL_ARB_clip_control) */
    int gl_depth;               /* nesting of gim__gl_enter: only the outermost saves/restores */
    gim_gl_state gl_state;      /* gim_desc.gl_state: restore the host's state, or reset to GL's */
    int own_objects;            /* 1 inside gim_update's passes: every object is the context's own, made to
                                   size by the frame, so the host-object checks (GL queries) are skipped */
    gim__gl_state saved;
    gim__GLint64 max_ssbo_bytes;  /* GL_MAX_SHADER_STORAGE_BLOCK_SIZE */
    gim__GLuint programs[GIM__PROGRAM_COUNT];
    gim__GLuint scan_blocks;      /* eq. 12 scratch: per-block column totals, then offsets */
    size_t scan_blocks_bytes;
    gim__GLuint proxy_state;      /* the proxy-light sums between chunk dispatches, 96 bytes a cache's lane */
    uint64_t proxy_state_bytes;
    uint32_t proxy_chunk;         /* VALs per proxy-light dispatch */
    uint32_t proxy_lanes;         /* lanes per cache in the proxy pass; 0: gim__proxy_lanes's choice (tests set it) */
    gim__GLint ssbo_align;        /* GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT */
    gim__GLint max_texture_size, max_viewport[2];
    gim__GLint max_layers[2];     /* GL_MAX_ARRAY_TEXTURE_LAYERS, GL_MAX_FRAMEBUFFER_LAYERS (asked once, not a frame) */
    /* the scene (see "the scene" below) */
    gim__mesh *meshes;            /* slots; a handle is slot + 1 | generation << 16 */
    uint32_t mesh_slots;
    gim_instance *instances;
    uint32_t instance_count, instance_capacity;
    gim_light *lights;            /* light_capacity RSMs: a POINT light's six faces in its place */
    uint32_t light_count, light_capacity;
    gim__GLuint light_buffer;     /* gim_set_lights_buffer's (0: none), read back by every gim_update */
    uint32_t light_buffer_count;
    gim_light_std430 *light_buffer_last; /* what the last read held (light_buffer_last_count; 0: none) */
    uint32_t light_buffer_last_count;
    gim__GLuint materials;        /* SSBO: per material vec4 diffuse, vec4 (glossy, k) */
    uint32_t material_count;
    uint32_t glossy_material_count; /* materials with a glossy colour: the glossy pass runs */
    float glossy_min_exponent;    /* the widest of their lobes */
    float *material_exponent;     /* CPU: each material's k (for the caches' glossy lobes) */
    uint64_t materials_version;   /* bumped by gim_set_materials */
    /* the frame's resources, sized to what the last frame used */
    gim__light_gpu *light_gpu;    /* light_capacity; a culled RSM has none */
    unsigned char *light_on;      /* per RSM: rendered this frame */
    uint32_t *light_vals;         /* per RSM: VALs selected this frame (BRSM) */
    double *light_total;          /* per RSM: its importance total this frame (BRSM) */
    gim_light_outputs *light_outputs; /* what gim_frame_outputs.lights points to */
    uint32_t light_on_count;      /* RSMs rendered this frame */
    gim__GLuint light_totals;     /* BRSM's shared budget: the RSMs' importance totals, read back */
    uint64_t light_totals_bytes;
    uint32_t gbuffer_width, gbuffer_height;
    gim__GLuint decoded_normal, decoded_depth;   /* the host's G-buffer decoded (RGBA16F, R32F) */
    uint32_t decoded_width, decoded_height;
    gim__GLuint gbuffer_depth, gbuffer_normal, gbuffer_albedo, gbuffer_material, gbuffer_fbo;
    gim__GLuint nearest_sampler;  /* texelFetch of a depth texture needs compare mode NONE */
    gim__GLuint view_sample_pixels, view_samples;
    uint64_t view_sample_pixels_bytes, view_samples_bytes;
    uint32_t view_sample_key[3];  /* count, width, height of view_sample_pixels (count 0: none) */
    float view_sample_off[3];     /* its rotation offsets, [2] = 1 when rotated */
    gim__GLuint indirect;         /* the LightSkin output (see "the LightSkin frame") */
    uint32_t indirect_width, indirect_height;
    gim__GLenum indirect_format;
    gim__lightskin_gpu ls;
    gim__bvh_gpu bvh;             /* the scene's hierarchy, while a frame's rays use it */
    gim__GLuint ism_maps, ism_points;  /* visibility ISM: the caches' (or VPLs') maps and the scene's points */
    uint64_t ism_maps_bytes, ism_points_bytes, ism_version;
    gim__GLuint ism_cluster_maps;      /* SSVP's second bounce with ISM: one map per cluster */
    uint64_t ism_cluster_maps_bytes;
    uint32_t ism_size, ism_per_map, ism_point_count;
    float ism_scale;
    uint64_t ism_vpl_key;         /* what the first-bounce VPLs' maps in ism_maps were made from: gim__vpl_ism_key
                                     with the RSM cameras, xor 1 when the VPLs were followed */
    uint64_t ism_vpl_layout;      /* the same without the cameras: ism_maps holds one map per VPL slot, made
                                     for what each slot held; 0: ism_maps holds no VPL maps */
    uint32_t ism_maps_made;       /* imperfect shadow maps rendered by this frame (gim_stats.ism_maps_made) */
    int ism_made_counted;         /* 1: this frame's VPL maps were counted on the GPU (ctx->vpl.made) */
    uint64_t scene_version;       /* bumped when meshes, instances or a deforming mesh's vertices change */
    gim__GLuint deform_box;       /* 28 bytes: a host-buffer deforming mesh's bounds (caches_follow.comp mode 0; bound in mode 1 too); 0: none yet */
    uint64_t ls_version;          /* the scene_version the world caches and their grid were made for */
    float ls_scale;               /* and the scene scale */
    gim__grid ls_grid;
    float ls_cos_theta;
    gim__GLuint gather_samples, gather_sum;  /* RSM gather: the pattern, the per-pixel sum over lights */
    uint64_t gather_samples_bytes, gather_sum_bytes;
    /* what gather_samples holds: samples, lights, radius and each light's RSM size (n 0: nothing) */
    uint32_t gather_key_n, gather_key_lights, *gather_key_sizes;   /* sizes: light_capacity */
    float gather_key_frac;
    gim__vpl_gpu vpl;             /* the VPL methods (CLUSTERED, SSVP; see "the VPL frame") */
    /* GL timestamps of the last timed frame: queries[i] after the pass stamp_pass[i] */
    gim__GLuint queries[GIM__MAX_STAMPS];
    uint32_t query_count, stamp_count;
    unsigned char stamp_pass[GIM__MAX_STAMPS];
    double stamp_ms[GIM__MAX_STAMPS];  /* timing 2: the clock (gim__clock_ms) after each stamp's glFinish */
    gim_stats stats;
    gim_frame_outputs outputs;
    gim_debug_outputs debug;    /* gim_debug's, set with outputs */
    /* paraboloid maps */
    uint32_t para_size, para_count;   /* of the textures below; 0: none */
    int para_attributes;              /* GIM__PARA_*: the maps that exist (distance, attributes, both) */
    gim__GLuint para_distance, para_depth, para_position, para_normal, para_albedo, para_fbo;
    gim__GLuint vsm_distance, vsm_depth, vsm_fbo; /* GIM_VISIBILITY_SHADOW_MAPS' layered targets */
    gim__GLuint vsm_list;          /* its VPLs whose maps a frame makes (uint each) */
    uint64_t vsm_list_bytes;
    uint32_t vsm_size, vsm_layers;
    uint32_t vsm_batch;           /* layers a batch of those maps (0: GIM__VSM_LAYERS; tests set fewer) */
    gim__GLuint para_samples;         /* second bounce: the texel of each VPL (uvec4), for para_key */
    uint64_t para_samples_bytes;
    uint32_t para_key[3];             /* map_count, size, vpl_count para_samples was made for */
    /* VPL shading */
    gim__GLuint vpl_partial;      /* per pixel running sums between VPL-shading dispatches (2 vec4) */
    uint64_t vpl_partial_bytes;
    uint32_t vpl_chunk;           /* subset members per VPL-shading dispatch (GIM__VPL_SHADE_CHUNK) */
    gim__GLuint vpl_raw;          /* the VPL shading before the geometry-aware blur (gim__gl_vpl_raw_texture) */
    uint32_t vpl_raw_width, vpl_raw_height;
    gim__GLenum vpl_raw_format;
    int half_warned;              /* the RGBA16F saturation warning was given for these lights */
    /* LightSkin frames: fragments of gimany's G-buffer seen from behind their normal
       (gbuffer.frag), counted one frame in GIM__FACING_PERIOD (atomics on one address are slow
       on a GPU) and read once its fence has passed, so the count never stalls */
    gim__GLuint facing;           /* SSBO: uint drawn, uint back-facing */
    gim__GLsync facing_sync;      /* the counted frame's fence; 0: none pending */
    uint32_t facing_frame;        /* G-buffer passes drawn */
    int facing_warned;
};

static void gim__vpl_release(gim_context *ctx);

/* Enter a call that touches GL: the outermost saves the host's state (not with
   GIM_GL_STATE_RESET) and sets the baseline. Under GIMANY_DEBUG an error the host left pending
   is logged and cleared, so it is not blamed on gimany. */
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
    if (ctx->gl_state != GIM_GL_STATE_RESET) gim__gl_state_save(&ctx->gl, &ctx->saved);
    gim__gl_state_baseline(&ctx->gl);
}

/* Leave it: the outermost restores the host's state, or with GIM_GL_STATE_RESET leaves GL's
   initial values. Returns r, so calls end `return gim__gl_leave(ctx, r);`. */
static gim_result gim__gl_leave(gim_context *ctx, gim_result r) {
    GIMANY_ASSERT(ctx->gl_depth > 0);
    if (--ctx->gl_depth == 0) {
        if (ctx->gl_state == GIM_GL_STATE_RESET) gim__gl_state_reset(&ctx->gl);
        else gim__gl_state_restore(&ctx->gl, &ctx->saved);
    }
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
    gim__shader_stage stages[3];
    int n = 0, i;
    gim_result r;
    GIMANY_ASSERT((unsigned)id < GIM__PROGRAM_COUNT);
    if (ctx->programs[id]) { *out = ctx->programs[id]; return GIM_OK; }
    for (i = 0; i < 3 && gim__program_files[id][i]; ++i) {
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

/* --- importance sampling passes (Bischoff 2017 sec. 4) -------------------------------
   The shape of every pass: argument checks (no GL) -> gim__gl_enter -> the host objects it
   reads or writes checked (gim__gl_check_buffer/_texture) -> gim__gl_program (built on first
   use) -> bindings on the units/bindings of the state list only -> dispatch -> barrier for how
   the output is read next -> gim__gl_leave(ctx, gim__gl_check(ctx, where)). Every return after
   the enter goes through the leave. A new binding point or state item goes into the state list
   first (and into tests/gl/gltest_runtime.c's distinctive state). */

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
    if (ctx->own_objects) return GIM_OK;
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
    if (ctx->own_objects) return GIM_OK;
    if (!texture || !ctx->gl.IsTexture(texture))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s (%u) is not a texture", what, (unsigned)texture);
    if (ctx->gl.GetTextureParameteriv) {
        gim__GLint target = 0;
        ctx->gl.GetTextureParameteriv(texture, GIM__GL_TEXTURE_TARGET, &target);
        if (target != GIM__GL_TEXTURE_2D)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s (%u) is not a 2D texture (target 0x%04x)",
                             what, (unsigned)texture, (unsigned)target);
    }
    ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, texture);
    ctx->gl.GetIntegerv(GIM__GL_TEXTURE_BINDING_2D, &w);
    if ((gim__GLuint)w != texture) { /* GL 4.3 cannot ask a texture's target: the bind failed */
        /* that GL_INVALID_OPERATION is ours, with or without GIMANY_DEBUG: the host must not
           find it in its queue (under GIMANY_DEBUG enter cleared the host's own) */
        ctx->gl.GetError();
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

/* The host's G-buffer formats: depth a depth format (a colour texture reads as garbage depth),
   the normal a float or signed-normalised RGB(A) (RGBA8 clamps every negative component to 0). */
static gim_result gim__gl_check_host_gbuffer(gim_context *ctx, const char *where, const gim_frame *fr, gim__GLuint depth,
                                             gim__GLuint normal) {
    static const gim__GLint depth_formats[] = {0x81A5, 0x81A6, 0x81A7, 0x8CAC, 0x88F0, 0x8CAD, 0};
    static const gim__GLint view_z_formats[] = {0x822E, 0x822D, 0};   /* R32F, R16F */
    /* per gim_normal_encoding: signed xyz; unorm xyz; signed octahedral (RG or the first two of
       RGB(A)); unorm octahedral */
    static const gim__GLint xyz[] = {0x881A, 0x8814, 0x881B, 0x8815, 0x8F9B, 0x8F97, 0x8F9A, 0x8F96, 0};
    static const gim__GLint xyz_unorm[] = {0x8059, 0x8058, 0x805B, 0x8051, 0x8054, 0};
    static const gim__GLint oct[] = {0x8F99, 0x8F95, 0x822F, 0x8230, 0x881A, 0x8814, 0x8F9B, 0x8F97, 0};
    static const gim__GLint oct_unorm[] = {0x822C, 0x822B, 0x8059, 0x8058, 0x805B, 0};
    static const gim__GLint *const normal_formats[4] = {xyz, xyz_unorm, oct, oct_unorm};
    static const char *const normal_names[4] = {
        "GIM_NORMAL_XYZ needs signed values (GL_RGB(A)16F/32F, GL_RGB(A)8_SNORM, GL_RGB(A)16_SNORM)",
        "GIM_NORMAL_XYZ_UNORM needs GL_RGB10_A2, GL_RGB(A)8 or GL_RGB(A)16",
        "GIM_NORMAL_OCTAHEDRAL needs GL_RG16_SNORM, GL_RG8_SNORM, GL_RG16F, GL_RG32F (or RGBA16F/32F/SNORM)",
        "GIM_NORMAL_OCTAHEDRAL_UNORM needs GL_RG16, GL_RG8, GL_RGB10_A2, GL_RGBA8 or GL_RGBA16"};
    const gim__GLint *list = fr->gbuffer.depth_view_z ? view_z_formats : depth_formats;
    gim__GLint f = 0;
    unsigned i, ok = 0;
    ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, depth);
    ctx->gl.GetTexLevelParameteriv(GIM__GL_TEXTURE_2D, 0, GIM__GL_TEXTURE_INTERNAL_FORMAT, &f);
    for (i = 0; list[i]; ++i) ok |= f == list[i];
    if (!ok)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         fr->gbuffer.depth_view_z ? "gbuffer_depth has internal format 0x%04x: view-space depth needs GL_R32F "
                                                    "or GL_R16F"
                                                  : "gbuffer_depth has internal format 0x%04x: it must be a depth format "
                                                    "(GL_DEPTH_COMPONENT16/24/32/32F, GL_DEPTH24_STENCIL8, GL_DEPTH32F_STENCIL8; "
                                                    "or set gbuffer_depth_view_z)", (unsigned)f);
    ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, normal);
    ctx->gl.GetTexLevelParameteriv(GIM__GL_TEXTURE_2D, 0, GIM__GL_TEXTURE_INTERNAL_FORMAT, &f);
    list = normal_formats[fr->gbuffer.normal_encoding];
    for (i = 0, ok = 0; list[i]; ++i) ok |= f == list[i];
    if (!ok)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "gbuffer_normal has internal format 0x%04x: %s",
                         (unsigned)f, normal_names[fr->gbuffer.normal_encoding]);
    /* texture state texelFetch obeys and no sampler overrides: the host's to keep, so refused */
    for (i = 0; i < 2; ++i) {
        gim__GLint v = 0, k;
        ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, i ? normal : depth);
        for (k = 0; k < 4; ++k) {
            ctx->gl.GetTexParameteriv(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_SWIZZLE_R + (gim__GLenum)k, &v);
            if (v != (k == 0 ? 0x1903 : k == 1 ? 0x1904 : k == 2 ? 0x1905 : 0x1906)) /* GL_RED .. GL_ALPHA */
                return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                                 "%s has a texture swizzle: gimany reads the components as stored (set the identity)",
                                 i ? "gbuffer_normal" : "gbuffer_depth");
        }
        ctx->gl.GetTexParameteriv(GIM__GL_TEXTURE_2D, GIM__GL_TEXTURE_BASE_LEVEL, &v);
        if (v != 0)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                             "%s has GL_TEXTURE_BASE_LEVEL %d: gimany reads level 0 (set 0)",
                             i ? "gbuffer_normal" : "gbuffer_depth", (int)v);
    }
    ctx->gl.BindTexture(GIM__GL_TEXTURE_2D, depth);
    ctx->gl.GetTexParameteriv(GIM__GL_TEXTURE_2D, GIM__GL_DEPTH_STENCIL_TEXTURE_MODE, &f);
    if (f != GIM__GL_DEPTH_COMPONENT)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "gbuffer_depth's GL_DEPTH_STENCIL_TEXTURE_MODE is not GL_DEPTH_COMPONENT: it would read stencil");
    return GIM_OK;
}

/* The importance passes' shared argument checks (no GL): the RSM side, the view samples, the
   scene scale and the eq. 11 clamp (0: the default, written back). */
static GIM__UNUSED gim_result gim__importance_args(gim_context *ctx, const char *where, uint32_t width,
                                                   uint32_t height, uint32_t view_sample_count, float scene_scale,
                                                   float *clamp) {
    if (width == 0 || height == 0 || width > GIM__SCAN_MAX_SIZE || height > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..%u", (unsigned)width,
                         (unsigned)height, GIM__SCAN_MAX_SIZE);
    if (view_sample_count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no view samples");
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if (*clamp == 0.0f) *clamp = GIM__IMPORTANCE_DEFAULT_CLAMP;
    if (!(*clamp > 0.0f) || !gim__isfinitef(*clamp) || !gim__isfinitef(*clamp * *clamp))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "clamp %g must be finite and > 0", (double)*clamp);
    return GIM_OK;
}

/* The three RSM textures and the view samples of an importance pass checked (inside the enter),
   then bound: textures on units 0-2 with no sampler, the view samples at binding 0. */
static GIM__UNUSED gim_result gim__gl_importance_inputs(gim_context *ctx, const char *where, gim__GLuint rsm_position,
                                                        gim__GLuint rsm_normal, gim__GLuint rsm_flux, uint32_t width,
                                                        uint32_t height, gim__GLuint view_samples,
                                                        uint32_t view_sample_count) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint textures[3];
    gim_result r;
    unsigned i;
    textures[0] = rsm_position;
    textures[1] = rsm_normal;
    textures[2] = rsm_flux;
    r = gim__gl_check_texture(ctx, where, "rsm_position", rsm_position, width, height);
    if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "rsm_normal", rsm_normal, width, height);
    if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "rsm_flux", rsm_flux, width, height);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "view_samples", view_samples, (uint64_t)view_sample_count * 32u);
    if (r != GIM_OK) return r;
    for (i = 0; i < 3; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->BindTexture(GIM__GL_TEXTURE_2D, textures[i]);
        gl->BindSampler(i, 0); /* a host sampler with mip filtering would make the texture incomplete */
    }
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, view_samples);
    return GIM_OK;
}

/* eq. 10-11 on the GPU, the twin of gim_importance_map. rsm_position, rsm_normal, rsm_flux:
   2D float textures of width x height (position.xyz with .w > 0 where the RSM saw a surface,
   the twin's rsm_valid; normal.xyz; flux.rgb), read with texelFetch on units 0-2.
   view_samples: SSBO of view_sample_count {vec4 position; vec4 normal} (xyz used). map: SSBO
   of width * height floats (row-major, row 0 first), written. clamp 0 means 1/64 of scene_scale.
   Cost: width * height * view_sample_count terms. */
static gim_result gim__gl_importance_map_lum(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                            gim__GLuint rsm_flux, uint32_t width, uint32_t height,
                                            gim__GLuint view_samples, uint32_t view_sample_count, float scene_scale,
                                            float clamp, gim__GLuint map, gim__GLuint lum_map);
static GIM__UNUSED gim_result gim__gl_importance_map(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                                     gim__GLuint rsm_flux, uint32_t width, uint32_t height,
                                                     gim__GLuint view_samples, uint32_t view_sample_count,
                                                     float scene_scale, float clamp, gim__GLuint map) {
    return gim__gl_importance_map_lum(ctx, rsm_position, rsm_normal, rsm_flux, width, height, view_samples,
                                      view_sample_count, scene_scale, clamp, map, 0u);
}

/* gim__gl_importance_map, and with lum_map != 0 each texel's luminance into lum_map (width *
   height floats, the twin's gim_importance_luminance at tile 1). */
static gim_result gim__gl_importance_map_lum(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                            gim__GLuint rsm_flux, uint32_t width, uint32_t height,
                                            gim__GLuint view_samples, uint32_t view_sample_count, float scene_scale,
                                            float clamp, gim__GLuint map, gim__GLuint lum_map) {
    static const char where[] = "importance map (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_result r;
    if (!rsm_position || !rsm_normal || !rsm_flux || !view_samples || !map)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a texture or buffer is 0");
    r = gim__importance_args(ctx, where, width, height, view_sample_count, scene_scale, &clamp);
    if (r != GIM_OK) return r;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "map", map, (uint64_t)width * height * 4u);
    if (r == GIM_OK && lum_map) r = gim__gl_check_buffer(ctx, where, "lum_map", lum_map, (uint64_t)width * height * 4u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_IMPORTANCE_MAP, &program);
    if (r == GIM_OK)
        r = gim__gl_importance_inputs(ctx, where, rsm_position, rsm_normal, rsm_flux, width, height, view_samples,
                                      view_sample_count);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, map);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, lum_map ? lum_map : map);   /* 0: unwritten */
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, view_sample_count);
    gl->Uniform1f(2, (float)(1.0 / (double)scene_scale));
    gl->Uniform1f(3, clamp * clamp);
    gl->Uniform1ui(4, lum_map ? 1u : 0u);
    gl->DispatchCompute((width + 15u) / 16u, (height + 15u) / 16u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* The two-level map's first level on the GPU, the twin of gim_importance_tile_map: textures and
   view samples as gim__gl_importance_map's; tile_map: SSBO of ceil(width / tile) * ceil(height /
   tile) floats, weight: SSBO of width * height floats, both written. tile in 1..GIM_MAX_IMPORTANCE_TILE.
   Cost: 4 planes x tiles x view_sample_count terms + 2 x width * height texel reads, against
   width * height * view_sample_count for the per-texel map. Float sums with running means; on
   the twin's inputs the tile map and weights agree to ~6e-7 relative (tests/gl/gltest_importance.c). */
static gim_result gim__gl_importance_tile_map_lum(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                                 gim__GLuint rsm_flux, uint32_t width, uint32_t height, uint32_t tile,
                                                 gim__GLuint view_samples, uint32_t view_sample_count,
                                                 float scene_scale, float clamp, gim__GLuint tile_map,
                                                 gim__GLuint weight, gim__GLuint lum_tiles, gim__GLuint lum_weight);
static GIM__UNUSED gim_result gim__gl_importance_tile_map(gim_context *ctx, gim__GLuint rsm_position,
                                                          gim__GLuint rsm_normal, gim__GLuint rsm_flux, uint32_t width,
                                                          uint32_t height, uint32_t tile, gim__GLuint view_samples,
                                                          uint32_t view_sample_count, float scene_scale, float clamp,
                                                          gim__GLuint tile_map, gim__GLuint weight) {
    return gim__gl_importance_tile_map_lum(ctx, rsm_position, rsm_normal, rsm_flux, width, height, tile, view_samples,
                                           view_sample_count, scene_scale, clamp, tile_map, weight, 0u, 0u);
}

/* gim__gl_importance_tile_map, and with lum_tiles != 0 the texels' luminance into lum_weight and
   its tile sums into lum_tiles (the twin's gim_importance_luminance; sizes as weight, tile_map). */
static gim_result gim__gl_importance_tile_map_lum(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                                 gim__GLuint rsm_flux, uint32_t width, uint32_t height, uint32_t tile,
                                                 gim__GLuint view_samples, uint32_t view_sample_count,
                                                 float scene_scale, float clamp, gim__GLuint tile_map,
                                                 gim__GLuint weight, gim__GLuint lum_tiles, gim__GLuint lum_weight) {
    static const char where[] = "importance tile map (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    uint32_t tiles_x, tiles_y;
    gim_result r;
    if (!rsm_position || !rsm_normal || !rsm_flux || !view_samples || !tile_map || !weight)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a texture or buffer is 0");
    r = gim__importance_args(ctx, where, width, height, view_sample_count, scene_scale, &clamp);
    if (r != GIM_OK) return r;
    if (tile == 0 || tile > GIM_MAX_IMPORTANCE_TILE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "tile %u outside 1..%d", (unsigned)tile,
                         GIM_MAX_IMPORTANCE_TILE);
    tiles_x = (width - 1u) / tile + 1u;
    tiles_y = (height - 1u) / tile + 1u;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "tile_map", tile_map, (uint64_t)tiles_x * tiles_y * 4u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "weight", weight, (uint64_t)width * height * 4u);
    if (r == GIM_OK && (lum_tiles || lum_weight)) {
        if (!lum_tiles || !lum_weight) r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "lum_tiles without lum_weight");
        if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "lum_tiles", lum_tiles, (uint64_t)tiles_x * tiles_y * 4u);
        if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "lum_weight", lum_weight, (uint64_t)width * height * 4u);
    }
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_IMPORTANCE_TILES, &program);
    if (r == GIM_OK)
        r = gim__gl_importance_inputs(ctx, where, rsm_position, rsm_normal, rsm_flux, width, height, view_samples,
                                      view_sample_count);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, tile_map);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, weight);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, lum_tiles ? lum_tiles : tile_map);   /* 0: unwritten */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, lum_weight ? lum_weight : weight);
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, view_sample_count);
    gl->Uniform1f(2, (float)(1.0 / (double)scene_scale));
    gl->Uniform1f(3, clamp * clamp);
    gl->Uniform1ui(4, tile);
    gl->Uniform1f(5, (float)(GIM__TILE_PLANE_DISTANCE * (double)scene_scale));
    gl->Uniform1ui(6, lum_tiles ? 1u : 0u);
    gl->DispatchCompute((tiles_x + 7u) / 8u, (tiles_y + 7u) / 8u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* eq. 12 on the GPU, the twin of gim_importance_cumsum. map: SSBO of width * height floats
   (row-major, row 0 first); column: SSBO of width * height doubles, written with
   column[y * width + x] = sum of map(x, 0..y); row: SSBO of width doubles, written with
   row[x] = sum of the column totals 0..x. block_rows: rows per block of the first level
   (0: chosen from the size). Three dispatches, O(width * height) adds, in double like the twin: a float
   table at 1024^2 of uniform random importance already gives 0.1% of the texels a selection
   frequency more than 1% away from their P (bench/src/bench_gl.c), a bias the 1/P weights do not
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
static gim_result gim__gl_importance_select_offsets(gim_context *ctx, gim__GLuint column, gim__GLuint row,
                                                    uint32_t width, uint32_t height, uint32_t count, const float off[4],
                                                    gim__GLuint out);
static gim_result gim__gl_importance_select_tiles(gim_context *ctx, gim__GLuint column, gim__GLuint row, uint32_t width,
                                                  uint32_t height, uint32_t count, const float off[4], uint32_t tile,
                                                  gim__GLuint weight, uint32_t rsm_width, uint32_t rsm_height,
                                                  gim__GLuint out);
static GIM__UNUSED gim_result gim__gl_importance_select(gim_context *ctx, gim__GLuint column, gim__GLuint row,
                                                        uint32_t width, uint32_t height, uint32_t count,
                                                        uint32_t seed, gim__GLuint out) {
    float off[4];
    gim_rotation_offsets(off, 4u, seed);
    return gim__gl_importance_select_offsets(ctx, column, row, width, height, count, off, out);
}

/* The seed of light i's selection in a frame. */
static uint32_t gim__select_seed(uint32_t frame_index, uint32_t light) {
    return frame_index * GIM_MAX_LIGHTS + light;
}

/* The offsets of light i's selection of count VALs in frame f: drawn anew from the frame's
   seed, or with f->temporal_steps L > 1 light i's offsets of frame 0 moved by frame_index / (count
   L) (gim_drift_offsets). */
static void gim__select_offsets(const gim_frame *f, uint32_t light, uint32_t count, float off[4]) {
    if (f->lightskin.temporal_steps > 1u)
        gim_drift_offsets(off, 2u, gim__select_seed(0u, light), f->frame_index, 1.0 / ((double)count * f->lightskin.temporal_steps));
    else
        gim_rotation_offsets(off, 4u, gim__select_seed(f->frame_index, light));
}

/* gim__gl_importance_select with the offsets given as gim_select_desc.offsets holds them. */
static gim_result gim__gl_importance_select_offsets(gim_context *ctx, gim__GLuint column, gim__GLuint row,
                                                    uint32_t width, uint32_t height, uint32_t count, const float off[4],
                                                    gim__GLuint out) {
    return gim__gl_importance_select_tiles(ctx, column, row, width, height, count, off, 1u, 0u, width, height, out);
}

/* The two-level selection on the GPU, the twin of gim_importance_select with gim_select_desc's
   tile, weight, rsm_width, rsm_height: column, row are the tile map's tables (width x height tiles),
   weight an SSBO of rsm_width * rsm_height floats (gim__gl_importance_tile_map's); tile 1: the
   per-texel selection (weight unused, may be 0). Same offsets, same picks and pdf as the twin;
   pdf 0 marks a pick in a tile whose weights sum to 0 (the twin's error). */
/* The luminance tables of the selection's defensive share (gim_select_desc.defensive_count):
   count picks of the last defensive_count, lum_column / lum_row the size of column / row, lum_weight
   (tile > 1) rsm texels' luminance. */
typedef struct gim__gl_defensive {
    uint32_t count;
    gim__GLuint lum_column, lum_row, lum_weight;
} gim__gl_defensive;
static gim_result gim__gl_importance_select_mix(gim_context *ctx, gim__GLuint column, gim__GLuint row, uint32_t width,
                                                uint32_t height, uint32_t count, const float off[4], uint32_t tile,
                                                gim__GLuint weight, uint32_t rsm_width, uint32_t rsm_height,
                                                const gim__gl_defensive *dfs, gim__GLuint out);
static gim_result gim__gl_importance_select_tiles(gim_context *ctx, gim__GLuint column, gim__GLuint row, uint32_t width,
                                                  uint32_t height, uint32_t count, const float off[4], uint32_t tile,
                                                  gim__GLuint weight, uint32_t rsm_width, uint32_t rsm_height,
                                                  gim__GLuint out) {
    return gim__gl_importance_select_mix(ctx, column, row, width, height, count, off, tile, weight, rsm_width, rsm_height,
                                         NULL, out);
}

/* gim__gl_importance_select_tiles with a defensive share (dfs; NULL or count 0: none), the twin of
   gim_importance_select with gim_select_desc's defensive_count and luminance tables. */
static gim_result gim__gl_importance_select_mix(gim_context *ctx, gim__GLuint column, gim__GLuint row, uint32_t width,
                                                uint32_t height, uint32_t count, const float off[4], uint32_t tile,
                                                gim__GLuint weight, uint32_t rsm_width, uint32_t rsm_height,
                                                const gim__gl_defensive *dfs, gim__GLuint out) {
    static const char where[] = "importance select (GL)";
    uint32_t n2 = dfs ? dfs->count : 0u;
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_result r;
    if (!column || !row || !out || !off || (tile > 1u && !weight))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "count is 0");
    if (width == 0 || height == 0 || width > GIM__SCAN_MAX_SIZE || height > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..%u", (unsigned)width,
                         (unsigned)height, GIM__SCAN_MAX_SIZE);
    if (count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "count %u above %u", (unsigned)count, 65535u * 64u);
    if (tile == 0 || tile > GIM_MAX_IMPORTANCE_TILE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "tile %u outside 1..%d", (unsigned)tile,
                         GIM_MAX_IMPORTANCE_TILE);
    if (tile > 1u && (rsm_width == 0 || rsm_height == 0 || (rsm_width - 1u) / tile + 1u != width ||
                      (rsm_height - 1u) / tile + 1u != height))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a %ux%u RSM in tiles of %u is not %ux%u tiles",
                         (unsigned)rsm_width, (unsigned)rsm_height, (unsigned)tile, (unsigned)width, (unsigned)height);
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "column", column, (uint64_t)width * height * 8u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "row", row, (uint64_t)width * 8u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "out", out, (uint64_t)count * 12u);
    if (r == GIM_OK && tile > 1u)
        r = gim__gl_check_buffer(ctx, where, "weight", weight, (uint64_t)rsm_width * rsm_height * 4u);
    if (r == GIM_OK && n2) {
        if (n2 >= count || !dfs->lum_column || !dfs->lum_row || (tile > 1u && !dfs->lum_weight))
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                          "a defensive share of %u picks of %u needs fewer picks and the luminance tables",
                          (unsigned)n2, (unsigned)count);
        if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "lum_column", dfs->lum_column, (uint64_t)width * height * 8u);
        if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "lum_row", dfs->lum_row, (uint64_t)width * 8u);
        if (r == GIM_OK && tile > 1u)
            r = gim__gl_check_buffer(ctx, where, "lum_weight", dfs->lum_weight, (uint64_t)rsm_width * rsm_height * 4u);
    }
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SELECT, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    /* the twin's 48-bit rotation: two 24-bit offsets per dimension */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, tile > 1u ? weight : column);   /* per texel: unread */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, column);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, row);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, out);
    /* without a share the luminance tables are not read: the importance's stand in */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 5, n2 ? dfs->lum_column : column);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 6, n2 ? dfs->lum_row : row);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 7, n2 && tile > 1u ? dfs->lum_weight : (tile > 1u ? weight : column));
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->Uniform1ui(1, count);
    gl->Uniform1ui(5, n2);
    gl->Uniform2d(2, (double)off[0] + (double)off[2] * (1.0 / 16777216.0),
                  (double)off[1] + (double)off[3] * (1.0 / 16777216.0));
    gl->Uniform1ui(3, tile);
    gl->Uniform2ui(4, tile > 1u ? rsm_width : width, tile > 1u ? rsm_height : height);
    gl->DispatchCompute((count + 63u) / 64u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* --- LightSkin passes (Bischoff 2017 sec. 3) ----------------------------------------------- */

#define GIM__PROXY_GROUP 64u   /* TILE of proxy_lights.comp */
/* VALs per dispatch: under 65535 loop iterations per invocation, the
   bound of Mesa's llvmpipe over all loops of one invocation (it stops them silently there),
   and short enough for a desktop GPU's watchdog */
#define GIM__PROXY_CHUNK 32768u
/* ... and with GIM_VISIBILITY_RAYS, VALs per lane of a dispatch: each VAL a walk of the hierarchy
   (in Sponza's, 187,364 triangles, a throwaway counter over 200,000 random pairs of surface points
   measured 83 loop iterations a walk on average, 219 for the segments nothing blocks, 838 at
   most), so 16 stay far under the bound */
#define GIM__PROXY_RAY_CHUNK 16u
/* Lanes per cache of the proxy pass (proxy_lights.comp), a power of two up to
   GIM__PROXY_MAX_LANES: doubled while the pass stays within GIM__PROXY_INVOCATIONS invocations,
   about what a large GPU keeps in flight (an H100: 132 multiprocessors x 2048), so a scene of
   few caches still fills it (one invocation per cache left 98% of it idle on Sponza's 24,863),
   and while every lane keeps GIM__PROXY_LANE_VALS VALs, against each lane's fixed cost (its
   cache, its sums read and written per dispatch). Each lane sums its own VALs, mode 2 merges
   them; their sums cost 96 bytes a lane (beyond one lane, at most 2^17 x 96 bytes = 12 MiB). */
#define GIM__PROXY_MAX_LANES 16u
#define GIM__PROXY_INVOCATIONS (1u << 17)
#define GIM__PROXY_LANE_VALS 512u
static uint32_t gim__proxy_lanes(const gim_context *ctx, uint32_t cache_count, uint32_t val_count) {
    uint32_t l = 1u;
    if (ctx->proxy_lanes) return ctx->proxy_lanes;
    while (l < GIM__PROXY_MAX_LANES && (uint64_t)cache_count * l * 2u <= GIM__PROXY_INVOCATIONS &&
           (uint64_t)val_count >= (uint64_t)l * 2u * GIM__PROXY_LANE_VALS)
        l *= 2u;
    return l;
}

/* Caches of `lanes` lanes whose sums one storage block holds (the proxy pass's ranges), all of
   cache_count where they fit, else a power of two; 0 where not even one cache fits. */
static uint32_t gim__proxy_sums_range(const gim_context *ctx, uint32_t lanes, uint32_t cache_count) {
    uint64_t cap = (uint64_t)ctx->max_ssbo_bytes / ((uint64_t)lanes * 96u);
    uint32_t n = 1u;
    if (cap >= cache_count) return cache_count;
    if (cap == 0) return 0u;
    while ((uint64_t)n * 2u <= cap) n *= 2u;
    return n;
}

/* The scene's points the maps draw their subsets from: four times a map's, so the subsets
   differ per map (at most GIM_ISM_MAX_POINTS). */
static uint32_t gim__ism_pool(uint32_t points_per_map) {
    return points_per_map <= GIM_ISM_MAX_POINTS / 4u ? 4u * points_per_map : GIM_ISM_MAX_POINTS;
}

/* Maps of side `size` that one shader storage block holds, a power of two at most cap: the
   maps of every cache exceed one block at scale (Sponza's 24,863 caches at 64^2 take 204 MB,
   llvmpipe's and Intel's blocks 128 MiB, GL's minimum 16 MiB), so the passes bind them a range
   of this many maps at a time. 0 where the ranges' offsets would not be multiples of
   GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT: never on a driver we know (a power of two up to
   256, and a split range holds 128 KiB at least), refused by the callers before any GL work. */
/* Maps per ISM dispatch: a desktop GPU's watchdog bounds one dispatch's time. */
#define GIM__ISM_CHUNK 4096u

static uint32_t gim__ism_block_maps(const gim_context *ctx, uint32_t size, uint32_t cap) {
    uint64_t map_bytes = (uint64_t)size * size * 2u;
    uint32_t n = 1u;
    while (n < cap && (uint64_t)n * 2u * map_bytes <= (uint64_t)ctx->max_ssbo_bytes) n *= 2u;
    return n < cap && ((uint64_t)n * map_bytes) % (uint64_t)ctx->ssbo_align ? 0u : n;
}

/* The fewest maps (a power of two) whose bytes are a multiple of the SSBO offset alignment: a
   range of maps may start at any multiple of it. */
static uint32_t gim__ism_align_maps(const gim_context *ctx, uint32_t size) {
    uint64_t map_bytes = (uint64_t)size * size * 2u;
    uint32_t n = 1u;
    while (n < GIM__ISM_CHUNK && ((uint64_t)n * map_bytes) % (uint64_t)ctx->ssbo_align) n *= 2u;
    return n;
}

/* Proxy lights on the GPU, the twin of gim_proxy_lights_twin (same formulas, guards and clamps;
   see there). caches: SSBO of cache_count gim_cache (32 bytes: vec4 position + area, vec4
   normal + reflectance; world space, unit normals). vals: SSBO of val_count gim_val (48 bytes;
   val_count 0 is dark, not an error, and vals may then be 0). diffuse_out: SSBO of cache_count
   gim_proxy_light (48 bytes), written; glossy_out: the same for the glossy lobe of exponent k
   seen from eye, or 0 to skip the glossy sums (a scene without glossy materials pays nothing).
   k per cache from exponents (cache_count floats, the twin's cache_glossy_exponent), or
   `exponent` for every cache where exponents is 0. scene_scale > 0 (the
   twin's default 0 would need the bounds on the CPU). Sums in float, not double: on the
   twin's inputs the results agree to ~1e-5 relative (more with large exponents, whose lobe
   amplifies the float error of the reflected direction k-fold; tests/gl/gltest_proxy.c). A VAL
   that is not finite or has negative area, weight or flux adds nothing (the twin rejects it),
   and a sum that overflows float gives the proxy x_p = c and zero flux, so every output is
   finite. Cost: cache_count * val_count terms (twice in the work groups holding a cache that
   no VAL lights), in dispatches of ctx->proxy_chunk VALs (GIM__PROXY_CHUNK) with the sums in
   a scratch buffer of 96 bytes a lane of a cache between them (gim__proxy_lanes), a range of
   caches at a time where one storage block would not hold them all (gim__proxy_sums_range). */
/* The caches' imperfect shadow maps for the proxy pass: maps (cache_count size^2 floats,
   gim__gl_ism_render's), 0 for none; bias and slope as gim_ism_desc's (0: defaults). */
typedef struct gim__gl_ism {
    gim__GLuint maps;
    uint32_t size;
    float bias, slope;
    gim__GLuint bvh;      /* GIM_VISIBILITY_RAYS instead of maps: the hierarchy (gim__gl_bvh's buffer), or 0 */
    uint32_t bvh_nodes;
    float bvh_origin[3], bvh_scale;   /* its frame */
} gim__gl_ism;

static gim_result gim__gl_proxy_lights_ism(gim_context *ctx, gim__GLuint caches, uint32_t cache_count, gim__GLuint vals,
                                           uint32_t val_count, gim_vec3 eye, float exponent, gim__GLuint exponents,
                                           float scene_scale, gim__GLuint diffuse_out, gim__GLuint glossy_out,
                                           const gim__gl_ism *ism);

static GIM__UNUSED gim_result gim__gl_proxy_lights(gim_context *ctx, gim__GLuint caches, uint32_t cache_count,
                                                   gim__GLuint vals, uint32_t val_count, gim_vec3 eye, float exponent,
                                                   gim__GLuint exponents, float scene_scale, gim__GLuint diffuse_out,
                                                   gim__GLuint glossy_out) {
    return gim__gl_proxy_lights_ism(ctx, caches, cache_count, vals, val_count, eye, exponent, exponents, scene_scale,
                                    diffuse_out, glossy_out, NULL);
}

/* gim__gl_proxy_lights with each VAL's contribution to a cache times its visibility through
   the cache's imperfect shadow map (gim_ism_visibility_twin's lookup; ism NULL or ism->maps 0: none).
   The maps may exceed one storage block: the caches run in ranges of gim__ism_block_maps, each
   with its maps' range bound. */
static gim_result gim__gl_proxy_lights_ism(gim_context *ctx, gim__GLuint caches, uint32_t cache_count, gim__GLuint vals,
                                           uint32_t val_count, gim_vec3 eye, float exponent, gim__GLuint exponents,
                                           float scene_scale, gim__GLuint diffuse_out, gim__GLuint glossy_out,
                                           const gim__gl_ism *ism) {
    static const char where[] = "proxy lights (GL)";
    int with_ism = ism && ism->maps, with_rays = ism && !ism->maps && ism->bvh;
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    float coincident;
    uint32_t step, range, sums_range, cache_first, lanes;
    uint64_t map_bytes;
    gim_result r;
    if (!caches || !diffuse_out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (cache_count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "cache_count is 0");
    if (val_count > 0 && !vals) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "vals is 0");
    lanes = gim__proxy_lanes(ctx, cache_count, val_count);
    if (cache_count > 65535u * GIM__PROXY_GROUP)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "cache_count %u above %u", (unsigned)cache_count,
                         65535u * GIM__PROXY_GROUP);
    if ((uint64_t)val_count * 48u > (uint64_t)ctx->max_ssbo_bytes || (uint64_t)cache_count * 48u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "%u caches / %u VALs exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes)", (unsigned)cache_count,
                         (unsigned)val_count, (long long)ctx->max_ssbo_bytes);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if (glossy_out) {
        if (!gim__v3_isfinite(eye)) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "eye is not finite");
        if (!(exponent >= 0.0f && exponent <= GIM__TWINS_MAX_EXPONENT))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "exponent %g must be in [0, 1e6]",
                             (double)exponent);
    }
    if (with_ism && (ism->size < GIM_ISM_MIN_SIZE || ism->size > GIM_ISM_MAX_SIZE || (ism->size & (ism->size - 1u)) ||
                     !(ism->bias >= 0.0f && ism->bias <= 1.0f) || !(ism->slope >= 0.0f && ism->slope <= 64.0f)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ISM size %u, bias %g or slope %g out of range",
                         (unsigned)ism->size, (double)ism->bias, (double)ism->slope);
    range = with_ism ? gim__ism_block_maps(ctx, ism->size, cache_count) : cache_count;
    map_bytes = with_ism ? (uint64_t)ism->size * ism->size * 2u : 0u;
    /* the sums of a range's lanes are one storage block too (96 bytes a cache's lane: a range
       of caches at a time past about 1.4 M caches in one lane at 128 MiB, 175 k at GL's 16 MiB) */
    sums_range = gim__proxy_sums_range(ctx, lanes, cache_count);
    if (sums_range < range) {
        range = sums_range;
        if (with_ism && range > 0 && (range * map_bytes) % (uint64_t)ctx->ssbo_align) range = 0;
    }
    if (range == 0)
        return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where,
                         "GL_MAX_SHADER_STORAGE_BLOCK_SIZE %lld or GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT %d",
                         (long long)ctx->max_ssbo_bytes, (int)ctx->ssbo_align);
    coincident = GIM__TWINS_COINCIDENT * scene_scale;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "caches", caches, (uint64_t)cache_count * 32u);
    if (r == GIM_OK && with_ism)
        r = gim__gl_check_buffer(ctx, where, "ISM maps", ism->maps, (uint64_t)cache_count * ism->size * ism->size * 2u);
    if (r == GIM_OK && val_count > 0) r = gim__gl_check_buffer(ctx, where, "vals", vals, (uint64_t)val_count * 48u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "diffuse_out", diffuse_out, (uint64_t)cache_count * 48u);
    if (r == GIM_OK && glossy_out)
        r = gim__gl_check_buffer(ctx, where, "glossy_out", glossy_out, (uint64_t)cache_count * 48u);
    if (r == GIM_OK && glossy_out && exponents)
        r = gim__gl_check_buffer(ctx, where, "exponents", exponents, (uint64_t)cache_count * 4u);
    if (r == GIM_OK && (diffuse_out == glossy_out || diffuse_out == caches || diffuse_out == vals ||
                        (glossy_out && (glossy_out == caches || glossy_out == vals))))
        r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "an output buffer is also an input or the other output");
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_PROXY_LIGHTS, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, caches);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, val_count > 0 ? vals : caches); /* never read then */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, diffuse_out);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, glossy_out ? glossy_out : diffuse_out); /* never written then */
    r = gim__gl_sized_buffer(ctx, &ctx->proxy_state, &ctx->proxy_state_bytes, (uint64_t)range * lanes * 96u, where);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, ctx->proxy_state);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 5, glossy_out && exponents ? exponents : caches); /* read only then */
    gl->UseProgram(program);
    gl->Uniform1ui(0, cache_count);
    gl->Uniform1ui(1, val_count);
    gl->Uniform3f(2, glossy_out ? eye.x : 0.0f, glossy_out ? eye.y : 0.0f, glossy_out ? eye.z : 0.0f);
    gl->Uniform1f(3, glossy_out ? exponent : 0.0f);
    gl->Uniform1f(4, coincident * coincident);
    gl->Uniform1ui(5, glossy_out ? 1u : 0u);
    gl->Uniform1ui(9, glossy_out && exponents ? 1u : 0u);
    gl->Uniform1ui(10, lanes);
    gl->Uniform1ui(12, with_ism ? ism->size : 0u);
    gl->Uniform1f(13, with_ism ? (ism->bias > 0.0f ? ism->bias : GIM_ISM_BIAS) : 0.0f);
    gl->Uniform1f(14, with_ism ? (ism->slope > 0.0f ? ism->slope : GIM_ISM_SLOPE) * 2.0f / (float)ism->size : 0.0f);
    gl->Uniform1f(15, GIM_ISM_LIFT * scene_scale);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 6, with_rays ? ism->bvh : caches);   /* never read without rays */
    gl->Uniform1ui(17, with_rays ? ism->bvh_nodes : 0u);
    gl->Uniform1ui(18, with_rays ? ism->bvh_nodes * 2u : 0u);
    gl->Uniform1ui(19, with_rays ? 1u : 0u);
    gl->Uniform1f(20, GIM_NEIGHBOUR_RAY_LIFT * scene_scale);
    gl->Uniform3f(21, with_rays ? ism->bvh_origin[0] : 0.0f, with_rays ? ism->bvh_origin[1] : 0.0f,
                  with_rays ? ism->bvh_origin[2] : 0.0f);
    gl->Uniform1f(22, with_rays ? ism->bvh_scale : 1.0f);
    /* per range of caches whose maps fit one storage block (all caches in one without maps):
       sums over the VALs chunk by chunk (mode 0), the near VALs past a cache's first
       GIM__VAL_NEAR_CAP (mode 3), the dark caches' positions (mode 1), the proxy lights (mode 2);
       one dispatch each, the sums kept in proxy_state between them */
    for (cache_first = 0; cache_first < cache_count; cache_first += range) {
        uint32_t cache_end = cache_count - cache_first < range ? cache_count : cache_first + range;
        if (with_ism)
            gl->BindBufferRange(GIM__GL_SHADER_STORAGE_BUFFER, 7, ism->maps, (gim__GLintptr)(cache_first * map_bytes),
                                (gim__GLsizeiptr)((cache_end - cache_first) * map_bytes));
        else
            gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 7, caches);   /* never read without */
        gl->Uniform1ui(0, cache_end);
        gl->Uniform1ui(16, cache_first);
        for (step = 0; step < 4u; ++step) {
            static const uint32_t modes[4] = {0u, 3u, 1u, 2u};
            uint32_t first = 0, mode = modes[step];
            if (mode == 3u && val_count <= GIM__VAL_NEAR_CAP) continue;   /* no cache can have more */
            do {
                /* mode 3's list adds up to a loop iteration per VAL: half the chunk; a ray's walk
                   adds its nodes' (GIM__PROXY_RAY_CHUNK) */
                uint32_t chunk = mode == 3u ? (ctx->proxy_chunk + 1u) / 2u : ctx->proxy_chunk;
                if (with_rays && chunk > GIM__PROXY_RAY_CHUNK * lanes) chunk = GIM__PROXY_RAY_CHUNK * lanes;
                uint32_t n = mode == 2u ? 0u : (val_count - first < chunk ? val_count - first : chunk);
                gl->Uniform1ui(6, first);
                gl->Uniform1ui(7, n);
                gl->Uniform1ui(8, mode);
                gl->DispatchCompute((cache_end - cache_first + GIM__PROXY_GROUP - 1u) / GIM__PROXY_GROUP,
                                    mode == 0u || mode == 3u ? lanes : 1u, 1u);   /* lane 0 alone merges */
                gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
                first += n;
            } while (mode != 2u && first < val_count);
        }
    }
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* The caches' imperfect shadow maps on the GPU, the twin of gim_ism_render_twin (same subsets,
   surfels, pull-push and float arithmetic; see there): one work group per map, the map and its
   pyramid in shared memory. caches: SSBO of cache_count gim_cache (32 bytes); points: SSBO of
   point_count gim_ism_points (32 bytes each); maps_out: SSBO of cache_count size^2 16-bit
   depths, two to a uint (texel 2k in the low half; gim_ism_quantize), size^2 / 2 uints a map,
   written. size a power of two in GIM_ISM_MIN_SIZE..GIM_ISM_MAX_SIZE, points_per_map in
   1..GIM_ISM_MAX_POINTS (at most point_count taken), scene_scale > 0: checked before any GL
   work. Cost: cache_count P surfels of up to (2 T + 1)^2 texels each, T = GIM_ISM_SPLAT_TEXELS. */
static gim_result gim__gl_ism_render_of(gim_context *ctx, gim__GLuint caches, uint32_t source_vec4s, uint32_t source_first,
                                        uint32_t map_first, uint32_t cache_count, gim__GLuint points, uint32_t point_count,
                                        uint32_t size, uint32_t points_per_map, float scene_scale, gim__GLuint maps_out);
static GIM__UNUSED gim_result gim__gl_ism_render(gim_context *ctx, gim__GLuint caches, uint32_t cache_count,
                                                 gim__GLuint points, uint32_t point_count, uint32_t size,
                                                 uint32_t points_per_map, float scene_scale, gim__GLuint maps_out) {
    return gim__gl_ism_render_of(ctx, caches, 2u, 0u, 0u, cache_count, points, point_count, size, points_per_map,
                                 scene_scale, maps_out);
}

/* ... with the maps' origins in any buffer of source_vec4s vec4 per map, the position in the
   first, the normal in the second: 2 for gim_cache, 3 for gim_vpl (one map per VPL, Keller's
   instant radiosity with Ritschel et al.'s maps; gim_ism_render_twin on the VPLs taken as caches);
   map m from entry source_first + m (its point subset is m's). Only the maps map_first ..
   map_first + cache_count - 1 are made, each into its own place (maps_out holds map_first +
   cache_count maps): the others keep what an earlier call wrote. map_first must be a multiple
   of gim__ism_align_maps. */
static gim_result gim__gl_ism_render_ex(gim_context *ctx, gim__GLuint caches, uint32_t source_vec4s, uint32_t source_first,
                                        uint32_t map_first, uint32_t cache_count, gim__GLuint points, uint32_t point_count,
                                        uint32_t size, uint32_t points_per_map, float scene_scale, gim__GLuint maps_out,
                                        gim__GLuint made, int keep);
static gim_result gim__gl_ism_render_of(gim_context *ctx, gim__GLuint caches, uint32_t source_vec4s, uint32_t source_first,
                                        uint32_t map_first, uint32_t cache_count, gim__GLuint points, uint32_t point_count,
                                        uint32_t size, uint32_t points_per_map, float scene_scale, gim__GLuint maps_out) {
    return gim__gl_ism_render_ex(ctx, caches, source_vec4s, source_first, map_first, cache_count, points, point_count, size,
                                 points_per_map, scene_scale, maps_out, 0u, 0);
}

/* ... and with made (a buffer of one uint, or 0) for VPLs (gim_vpl, source_vec4s 3): an unlit
   VPL's map is not made (no pass reads it: its light is 0), nor with keep a kept VPL's
   (gim_vpl.kept 1), which keeps what the buffer holds; made counts the maps made
   (ctx->ism_maps_made counts none of them: gim_frame_stats reads made). */
static gim_result gim__gl_ism_render_ex(gim_context *ctx, gim__GLuint caches, uint32_t source_vec4s, uint32_t source_first,
                                        uint32_t map_first, uint32_t cache_count, gim__GLuint points, uint32_t point_count,
                                        uint32_t size, uint32_t points_per_map, float scene_scale, gim__GLuint maps_out,
                                        gim__GLuint made, int keep) {
    static const char where[] = "imperfect shadow maps (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    uint32_t take, stride, first, chunk;
    uint64_t map_bytes;
    gim_result r;
    if (!caches || !points || !maps_out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (cache_count == 0 || point_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no caches or no points");
    if (size < GIM_ISM_MIN_SIZE || size > GIM_ISM_MAX_SIZE || (size & (size - 1u)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "map size %u: a power of two in %u..%u",
                         (unsigned)size, GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
    if (points_per_map == 0 || points_per_map > GIM_ISM_MAX_POINTS)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%u points per map: 1..%u", (unsigned)points_per_map,
                         GIM_ISM_MAX_POINTS);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if ((uint64_t)point_count * 32u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "%u points exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes)", (unsigned)point_count,
                         (long long)ctx->max_ssbo_bytes);
    if (((uint64_t)map_first + cache_count) * size * size * 2u > (uint64_t)GIM_ISM_MAX_BYTES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u maps of %u^2 exceed GIM_ISM_MAX_BYTES",
                         (unsigned)(map_first + cache_count), (unsigned)size);
    chunk = gim__ism_block_maps(ctx, size, GIM__ISM_CHUNK);
    map_bytes = (uint64_t)size * size * 2u;
    if (chunk == 0)
        return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where, "GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT %d",
                         (int)ctx->ssbo_align);
    if (map_first % gim__ism_align_maps(ctx, size))
        return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where,
                         "map_first %u is not a multiple of the %u maps that "
                         "GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT %d allows",
                         (unsigned)map_first, (unsigned)gim__ism_align_maps(ctx, size), (int)ctx->ssbo_align);
    take = points_per_map < point_count ? points_per_map : point_count;
    stride = point_count / take;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "caches", caches,
                             ((uint64_t)source_first + map_first + cache_count) * source_vec4s * 16u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "points", points, (uint64_t)point_count * 32u);
    if (r == GIM_OK)
        r = gim__gl_check_buffer(ctx, where, "maps_out", maps_out, ((uint64_t)map_first + cache_count) * size * size * 2u);
    if (r == GIM_OK && (maps_out == caches || maps_out == points))
        r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "maps_out is also an input");
    if (r == GIM_OK && made && source_vec4s != 3u)
        r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "only VPLs keep their maps");
    if (r == GIM_OK && made) r = gim__gl_check_buffer(ctx, where, "made", made, 8u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_ISM, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, caches);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, points);
    gl->UseProgram(program);
    gl->Uniform1ui(1, size);
    gl->Uniform1ui(2, stride);
    gl->Uniform1ui(3, take);
    gl->Uniform1f(4, GIM_ISM_LIFT * scene_scale);
    gl->Uniform1f(5, source_vec4s == 3u ? GIM_ISM_VPL_SPLAT : GIM_ISM_SPLAT);
    gl->Uniform1i(6, GIM_ISM_SPLAT_TEXELS);
    gl->Uniform1ui(7, source_vec4s);
    gl->Uniform1ui(8, source_first);
    gl->Uniform1ui(10, !made ? 0u : keep ? 2u : 1u);
    if (made) gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, made);
    for (first = map_first; first < map_first + cache_count; first += chunk) {   /* each dispatch within one block */
        uint32_t n = map_first + cache_count - first < chunk ? map_first + cache_count - first : chunk;
        gl->BindBufferRange(GIM__GL_SHADER_STORAGE_BUFFER, 2, maps_out, (gim__GLintptr)(first * map_bytes),
                            (gim__GLsizeiptr)(n * map_bytes));
        gl->Uniform1ui(0, first);
        gl->Uniform1ui(9, first);
        gl->DispatchCompute(n, 1u, 1u);
    }
    if (!made) ctx->ism_maps_made += cache_count;
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* The three RSM textures a pass reads (position, normal, flux as gim__gl_rsm writes them):
   each size x size and RGBA32F, for the passes that read them bit for bit as rgba32ui images.
   Inside gim__gl_enter/leave. */
static gim_result gim__gl_check_rsm(gim_context *ctx, const char *where, const gim__GLuint textures[3], uint32_t size) {
    static const char *const names[3] = {"rsm_position", "rsm_normal", "rsm_flux"};
    gim_result r = GIM_OK;
    int i;
    if (ctx->own_objects) return GIM_OK;
    for (i = 0; i < 3 && r == GIM_OK; ++i) {
        gim__GLint format = 0;
        r = gim__gl_check_texture(ctx, where, names[i], textures[i], size, size);
        if (r != GIM_OK) break;
        ctx->gl.GetTexLevelParameteriv(GIM__GL_TEXTURE_2D, 0, GIM__GL_TEXTURE_INTERNAL_FORMAT, &format);
        if (format != GIM__GL_RGBA32F)
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%s has format 0x%04x, not RGBA32F", names[i],
                          (unsigned)format);
    }
    return r;
}

#define GIM__GATHER_GROUP 64u   /* local_size_x of vals_gather.comp */

/* The VAL list on the GPU, the twin of gim_vals_gather_twin (Bischoff 2017 sec. 3, eq. 13-15).
   rsm_position, rsm_normal, rsm_flux: RGBA32F 2D textures of size x size as gim__gl_rsm writes
   them (position.w > 0 where lit: the twin's valid; normal.w = area A; flux.rgb), read on image
   units 0-2 as rgba32ui, so every value reaches the VAL bit for bit (texelFetch would also need
   a sampler, and a GPU's float path may flush denormals the twin's memcpy keeps). They must be
   complete by their own state (glTexStorage2D, or no mipmap min filter): an image unit on an
   incomplete texture reads zeros, every VAL then weight 0. selected == 0 (FULL): size^2 VALs,
   texel (x, y) at first + y * size + x, weight 1, and selected_count must be 0. Else (BRSM):
   selected is an SSBO of selected_count gim_selected_val (12 bytes; gim__gl_importance_select
   writes it), VAL first + i from selected[i] with weight 1 / (selected_count * pdf), in double
   as the twin, so the weights agree to the rounding of GLSL's double division and conversion.
   vals_out: SSBO of at least (first + count) gim_val (48 bytes), only [first, first + count)
   written, so the runtime can lay several lights' lists end to end. An invalid texel (not lit,
   a NaN/Inf, negative area or flux) is an all-zero VAL, as in the twin; so is a selected entry
   outside the RSM or whose pdf is not finite and > 0, which the twin returns as
   GIM_ERROR_INVALID_ARGUMENT and a shader cannot report (gim__gl_importance_select writes
   pdf 0 for a pick from broken tables: it lights nothing). Cost: count texel reads.
   vpl 1: each written as a first-bounce VPL instead (gim_vpl, 48 bytes too: the VPL methods'
   vpl.importance), the twin's gim_vpls_from_vals on the VAL; 2: the same with the slots' last
   VPLs (what vals_out holds) as its previous. */
static gim_result gim__gl_vals_gather_as(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                         gim__GLuint rsm_flux, uint32_t size, gim__GLuint selected,
                                         uint32_t selected_count, gim__GLuint vals_out, uint32_t first, int vpl) {
    static const char where[] = "VAL gather (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0, textures[3];
    uint64_t count, groups;
    uint32_t gx, gy;
    gim_result r = GIM_OK;
    unsigned i;
    if (!rsm_position || !rsm_normal || !rsm_flux || !vals_out)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a texture or vals_out is 0");
    if (size == 0 || size > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %u outside 1..%u", (unsigned)size,
                         GIM__SCAN_MAX_SIZE);
    if (selected && selected_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "selected_count is 0");
    if (!selected && selected_count != 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "selected_count %u without a selected buffer (FULL takes every texel)", (unsigned)selected_count);
    count = selected ? (uint64_t)selected_count : (uint64_t)size * size;
    if ((uint64_t)first + count > (uint64_t)UINT32_MAX ||
        ((uint64_t)first + count) * 48u > (uint64_t)ctx->max_ssbo_bytes ||
        (uint64_t)selected_count * 12u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "VALs %u..%llu exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes)", (unsigned)first,
                         (unsigned long long)((uint64_t)first + count), (long long)ctx->max_ssbo_bytes);
    if (selected && selected == vals_out)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "selected is also vals_out");
    textures[0] = rsm_position;
    textures[1] = rsm_normal;
    textures[2] = rsm_flux;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_rsm(ctx, where, textures, size);
    if (r == GIM_OK && selected) r = gim__gl_check_buffer(ctx, where, "selected", selected, (uint64_t)selected_count * 12u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "vals_out", vals_out, ((uint64_t)first + count) * 48u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_VALS_GATHER, &program);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    for (i = 0; i < 3; ++i)
        gl->BindImageTexture(i, textures[i], 0, GIM__GL_FALSE, 0, GIM__GL_READ_ONLY, GIM__GL_RGBA32UI);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, selected ? selected : vals_out); /* never read in FULL */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, vals_out);
    gl->UseProgram(program);
    gl->Uniform1ui(0, size);
    gl->Uniform1ui(1, (gim__GLuint)count);
    gl->Uniform1ui(2, first);
    gl->Uniform1ui(3, selected ? 1u : 0u);
    gl->Uniform1ui(4, (gim__GLuint)vpl);
    /* up to 16384^2 VALs: rows of at most 65535 groups (GL 4.3's minimum per dimension) */
    groups = (count + GIM__GATHER_GROUP - 1u) / GIM__GATHER_GROUP;
    gx = (uint32_t)(groups < 65535u ? groups : 65535u);
    gy = (uint32_t)((groups + gx - 1u) / gx);
    gl->DispatchCompute(gx, gy, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

static GIM__UNUSED gim_result gim__gl_vals_gather(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                                  gim__GLuint rsm_flux, uint32_t size, gim__GLuint selected,
                                                  uint32_t selected_count, gim__GLuint vals_out, uint32_t first) {
    return gim__gl_vals_gather_as(ctx, rsm_position, rsm_normal, rsm_flux, size, selected, selected_count, vals_out,
                                  first, 0);
}

/* VPLs from an RSM on the GPU (Dong et al. sec. 4), the twin of gim_rsm_vpls_twin (see there):
   count VPLs at the texels of sequence (gim_rsm_vpls_twin; rotated by offsets, 2 values in [0,1), or NULL) of
   the size x size RSM textures (RGBA32F as gim__gl_rsm writes them: position.w > 0 where lit,
   normal.w area, flux.rgb; read as rgba32ui images like gim__gl_vals_gather, complete by
   their own state), into vpls_out: an SSBO of at least count {vec4 position (w: 1 lit, 0
   unlit), vec4 normal (w 0), vec4 flux (w 0)} (48 bytes each). The texels are computed on the
   CPU by the twin's own function and uploaded (as the view samples' pixels), so both take the
   same texels bit for bit. The normalisation T / S needs a reduction over the whole RSM: it is
   done on the GPU (the RSM never comes back to the host), in four dispatches of rsm_vpls.comp
   (row sums, block sums of the VPLs, the two totals, the scale), in double and in the twin's
   order, each loop under llvmpipe's 65535 iterations (a row of <= 16384 texels; the final sum
   over size + count / GIM_RSM_VPL_BLOCK partials). The texel list and the partial sums live
   in two buffers of the context (ctx->vpl), the list remade only when count, sequence, size
   or offsets change. Cost: size^2 + 3 count texel reads.
   follow (NULL: none) is the RSM's camera now (proj view) when vpls_out holds this RSM's VPLs of
   the last frame, slot for slot: they are kept where gim_rsm_vpls_twin's previous keeps them
   (flux.w 1), so that this pass is the twin with previous = what vpls_out held. */
static gim_result gim__gl_rsm_vpls_follow(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                          gim__GLuint rsm_flux, uint32_t size, uint32_t count,
                                          gim_vpl_sequence sequence, const float *offsets, gim__GLuint vpls_out,
                                          const gim_mat4 *follow);
static GIM__UNUSED gim_result gim__gl_rsm_vpls(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                               gim__GLuint rsm_flux, uint32_t size, uint32_t count,
                                               gim_vpl_sequence sequence, const float *offsets, gim__GLuint vpls_out) {
    return gim__gl_rsm_vpls_follow(ctx, rsm_position, rsm_normal, rsm_flux, size, count, sequence, offsets, vpls_out, NULL);
}
static gim_result gim__gl_rsm_vpls_follow(gim_context *ctx, gim__GLuint rsm_position, gim__GLuint rsm_normal,
                                          gim__GLuint rsm_flux, uint32_t size, uint32_t count,
                                          gim_vpl_sequence sequence, const float *offsets, gim__GLuint vpls_out,
                                          const gim_mat4 *follow) {
    static const char where[] = "RSM VPLs (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__vpl_gpu *v = &ctx->vpl;
    gim__GLuint program = 0, textures[3];
    uint32_t *texels = NULL, i, mode, blocks;
    uint64_t sums_bytes;
    gim_result r = GIM_OK;
    int same;
    if (!rsm_position || !rsm_normal || !rsm_flux || !vpls_out)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a texture or vpls_out is 0");
    if (size == 0 || size > GIM__SCAN_MAX_SIZE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %u outside 1..%u", (unsigned)size,
                         GIM__SCAN_MAX_SIZE);
    if (count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "count is 0");
    if (offsets && !(offsets[0] >= 0.0f && offsets[0] < 1.0f && offsets[1] >= 0.0f && offsets[1] < 1.0f))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "offsets must be in [0,1)");
    if (follow && !gim__mat4_isfinite(*follow))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "the RSM's camera is not finite");
    blocks = (count + GIM_RSM_VPL_BLOCK - 1u) / GIM_RSM_VPL_BLOCK;
    sums_bytes = ((uint64_t)size + blocks + 1u) * 32u;
    if ((uint64_t)count * 48u > (uint64_t)ctx->max_ssbo_bytes || sums_bytes > (uint64_t)ctx->max_ssbo_bytes ||
        count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs exceed the SSBO or dispatch limits",
                         (unsigned)count);
    /* the texel list depends on these only: made and uploaded when one changes */
    same = v->texels && v->texels_key[0] == count && v->texels_key[1] == (uint32_t)sequence && v->texels_key[2] == size &&
           (offsets ? v->texels_offsets[2] == 1.0f && v->texels_offsets[0] == offsets[0] && v->texels_offsets[1] == offsets[1]
                    : v->texels_offsets[2] == 0.0f);
    if (!same) {
        texels = (uint32_t *)gim__alloc_array(&ctx->env, count, 4u * sizeof(uint32_t));
        if (!texels) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u VPL texels", (unsigned)count);
        for (i = 0; i < count; ++i) {   /* x, y, the keep radius's bits, 0 */
            float radius = gim__rsm_vpl_radius(i, count, size, size);
            gim__rsm_vpl_texel(i, count, sequence, size, size, offsets, texels + 4 * i, texels + 4 * i + 1);
            memcpy(texels + 4 * i + 2, &radius, 4);
            texels[4 * i + 3] = 0;
        }
    }
    textures[0] = rsm_position;
    textures[1] = rsm_normal;
    textures[2] = rsm_flux;
    gim__gl_enter(ctx, where);
    r = gim__gl_check_rsm(ctx, where, textures, size);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "vpls_out", vpls_out, (uint64_t)count * 48u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_RSM_VPLS, &program);
    if (r == GIM_OK && !same) {
        v->texels_key[0] = 0;   /* none until the upload is done */
        r = gim__gl_sized_buffer(ctx, &v->texels, &v->texels_bytes, (uint64_t)count * 16u, where);
        if (r == GIM_OK) {
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->texels);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)count * 16, texels);
            r = gim__gl_check(ctx, where);
        }
        if (r == GIM_OK) {
            v->texels_key[0] = count;
            v->texels_key[1] = (uint32_t)sequence;
            v->texels_key[2] = size;
            v->texels_offsets[0] = offsets ? offsets[0] : 0.0f;
            v->texels_offsets[1] = offsets ? offsets[1] : 0.0f;
            v->texels_offsets[2] = offsets ? 1.0f : 0.0f;
        }
    }
    gim__free(&ctx->env, texels);
    if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &v->sums, &v->sums_bytes, sums_bytes, where);
    if (r == GIM_OK) {
        for (i = 0; i < 3; ++i)
            gl->BindImageTexture(i, textures[i], 0, GIM__GL_FALSE, 0, GIM__GL_READ_ONLY, GIM__GL_RGBA32UI);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, v->texels);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, vpls_out);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, v->sums);
        gl->UseProgram(program);
        gl->Uniform1ui(0, size);
        gl->Uniform1ui(1, count);
        gl->Uniform1ui(3, GIM_RSM_VPL_BLOCK);
        gl->Uniform1ui(4, follow ? 1u : 0u);
        if (follow) gl->UniformMatrix4fv(5, 1, GIM__GL_FALSE, follow->m);
        for (mode = 0; mode < 4u; ++mode) {
            uint32_t n = mode == 0u ? (size > count ? size : count) : mode == 1u ? blocks : mode == 2u ? 1u : count;
            gl->Uniform1ui(2, mode);
            gl->DispatchCompute((n + 63u) / 64u, 1u, 1u);
            gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
        }
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
        r = gim__gl_check(ctx, where);
    }
    return gim__gl_leave(ctx, r);
}

/* One k-means step on the GPU (Dong et al. sec. 5; SSVP sec. 3): assignment then update, the
   twin of one iteration of gim_kmeans (see its assignment and "Means"; the same metric and
   weights, the same tie rule, the same weighted means). vpls: SSBO of vpl_count VPLs as
   gim__gl_rsm_vpls writes them (48 bytes: position, normal, flux rgb; the w's ignored).
   centres: SSBO of cluster_count {vec4 position (w: VPLs in the cluster after this step),
   vec4 normal (renormalised in the pass, as the twin does its init normals)} (32 bytes), read
   and updated in place. assignment: SSBO of vpl_count
   uint, the cluster of each VPL, read and updated in place; 0xffffffff (none yet) before
   the first step, as in gim_kmeans' first iteration. metric, w_x, w_a: as gim_kmeans_desc
   (both weights 0: the metric's defaults); scene_scale > 0 (gim_kmeans' default 0 would need
   the VPL bounds on the CPU). Differences from the twin, by design:
   - an empty cluster keeps its old centre and normal, count 0 (gim_kmeans re-seeds it from the
     worst cluster's farthest VPL: a serial repair left to the caller, which sees the count);
   - distances in float (the twin: double, relative to the VPLs' bounds centre), Dong's angle
     as 2 atan(|n - n_c|, |n + n_c|) (accurate where acos of a float cosine is not); the sums
     of the update in double in the twin's VPL order, the centres stored as float between
     steps. So a VPL within float rounding of a tie (relative ~1e-6 of the distances, more
     far from the origin: the centres' float ulp over the scene scale) may choose the other
     cluster (tests/gl/gltest_vpls.c counts them).
   K steps from the same centres, with the assignment reset to none, give gim_kmeans with init
   WARM, max_iterations K (its convergence stop skips only an update that changes nothing).
   Cost: vpl_count * cluster_count distance terms and as many VPL reads in the update (a gather
   per cluster, in dispatches of ctx->proxy_chunk VPLs); a scratch buffer of 160 bytes per
   cluster, kept in the context (ctx->vpl.kmeans_acc). cluster_count <= 4096 (one loop over the centres
   per invocation stays under llvmpipe's 65535 iterations). */
#define GIM__KMEANS_MAX_CLUSTERS 4096u
static GIM__UNUSED gim_result gim__gl_kmeans_step(gim_context *ctx, gim__GLuint vpls, uint32_t vpl_count,
                                                  gim__GLuint centres, uint32_t cluster_count, gim__GLuint assignment,
                                                  gim_kmeans_metric metric, float w_x, float w_a, float scene_scale) {
    static const char where[] = "k-means step (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint p_assign = 0, p_update = 0, acc = 0;
    int ssvp = metric == GIM_KMEANS_METRIC_SSVP;
    float wx = w_x, wa = w_a;
    gim_result r;
    if (!vpls || !centres || !assignment)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (vpls == centres || vpls == assignment || centres == assignment)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "the three buffers must differ");
    if (vpl_count == 0 || cluster_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "vpl_count (%u) and cluster_count (%u) must be > 0",
                         (unsigned)vpl_count, (unsigned)cluster_count);
    if (cluster_count > vpl_count)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "cluster_count %u > vpl_count %u",
                         (unsigned)cluster_count, (unsigned)vpl_count);
    if (cluster_count > GIM__KMEANS_MAX_CLUSTERS || vpl_count > 65535u * 64u ||
        (uint64_t)vpl_count * 48u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs / %u clusters above the limits",
                         (unsigned)vpl_count, (unsigned)cluster_count);
    if ((unsigned)metric > (unsigned)GIM_KMEANS_METRIC_SSVP)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown metric %d", (int)metric);
    if (!gim__isfinitef(w_x) || !gim__isfinitef(w_a) || w_x < 0.0f || w_a < 0.0f)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "weights w_x %g, w_a %g must be finite and >= 0",
                         (double)w_x, (double)w_a);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if (wx == 0.0f && wa == 0.0f) { wx = ssvp ? 0.6f : 0.7f; wa = ssvp ? 0.4f : 0.3f; }
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "vpls", vpls, (uint64_t)vpl_count * 48u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "centres", centres, (uint64_t)cluster_count * 32u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "assignment", assignment, (uint64_t)vpl_count * 4u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_KMEANS_ASSIGN, &p_assign);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_KMEANS_UPDATE, &p_update);
    if (r == GIM_OK)
        r = gim__gl_sized_buffer(ctx, &ctx->vpl.kmeans_acc, &ctx->vpl.kmeans_acc_bytes, (uint64_t)cluster_count * 160u, where);
    acc = ctx->vpl.kmeans_acc;
    if (r == GIM_OK) {
        uint32_t first = 0, groups = (cluster_count + 63u) / 64u;
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, vpls);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, centres);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, assignment);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, acc);
        /* assignment (Dong 5.1 / SSVP eq. 2) */
        gl->UseProgram(p_assign);
        gl->Uniform1ui(0, vpl_count);
        gl->Uniform1ui(1, cluster_count);
        gl->Uniform1f(2, (float)((double)wx / scene_scale));
        gl->Uniform1f(3, ssvp ? wa : (float)(wa / 3.14159265358979323846));
        gl->Uniform1ui(4, ssvp ? 1u : 0u);
        gl->Uniform1ui(5, 0u);   /* assign, not reset (gim__gl_clusters_reset) */
        gl->DispatchCompute((vpl_count + 63u) / 64u, 1u, 1u);
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
        /* update: the sums chunk by chunk, then the means */
        gl->UseProgram(p_update);
        gl->Uniform1ui(0, cluster_count);
        gl->Uniform1ui(3, 0u);
        do {
            uint32_t n = vpl_count - first < ctx->proxy_chunk ? vpl_count - first : ctx->proxy_chunk;
            gl->Uniform1ui(1, first);
            gl->Uniform1ui(2, n);
            gl->DispatchCompute(groups, 1u, 1u);
            gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
            first += n;
        } while (first < vpl_count);
        gl->Uniform1ui(3, 1u);
        gl->DispatchCompute(groups, 1u, 1u);
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
        r = gim__gl_check(ctx, where);
    }
    return gim__gl_leave(ctx, r);
}


/* --- the scene ----------------------------------------------------------
   Meshes live in GL buffers (one VAO each); instances, lights and materials are small CPU
   copies (materials also an SSBO). Every setter checks all of its input first, so an error
   leaves the scene as it was. */

#define GIM__MAX_MESHES 65535u
#define GIM__MAX_VIEW_SAMPLES 32768u
#define GIM__DEFAULT_VIEW_SAMPLES 256u
#define GIM__DEFAULT_VAL_COUNT 2048u
/* Farthest a scene's world bounds may lie from the origin, in diagonals of those bounds.
   Float positions there are quantised to ~2^-23 of the distance; the vertex transforms round
   clip z and w separately by as much, and a spot inside the scene (near plane at 1e-4 of its
   far plane) then loses its depth order: tests/gl/gltest_extremes.c measured the room at 1e5
   units intact up to ~960 diagonals (0.07% mean error) and broken (2-10%) from ~1400. */
#define GIM__MAX_ORIGIN_DIAGONALS 1024.0
/* Scene diagonals the float passes hold: squared lengths and 1/d^2 stay normal floats, and
   tests/gl/gltest_extremes.c gets the image of size 1 within 4e-5 from 1e-17 to 1e17 (1e-19
   breaks); a margin of 100 on each side. */
#define GIM__MIN_SCENE_DIAGONAL 1e-15
#define GIM__MAX_SCENE_DIAGONAL 1e15
/* Largest power a light may bring into the scene (a sun's E times the diagonal squared, a
   spot's 4 pi I, times its brightest colour): the proxy lights' flux and second moments must
   stay floats. tests/gl/gltest_extremes.c: linear up to 1e36, the image saturates at 1e38. */
#define GIM__MAX_LIGHT_POWER 1e36
/* An explicit scene_scale sets every unit-free threshold (clamps, epsilons, blur and cache
   distances); beyond these multiples of the scene's diagonal they all collapse or swallow the
   scene (1e30 gave a black image) */
#define GIM__MIN_SCALE_DIAGONALS 1e-3
#define GIM__MAX_SCALE_DIAGONALS 1e3
/* Below this side an RSM gives a light a handful of VALs/VPLs: blotchy or saturated images
   (accepted, as the twins test 1^2, with a warning) */
#define GIM__MIN_GOOD_RSM 16u
/* RGBA16F's largest finite value: the passes clamp the indirect radiance to it */
#define GIM__HALF_MAX 65504.0

static gim__mesh *gim__mesh_get(gim_context *ctx, gim_mesh m) {
    uint32_t slot = (m.id & 0xFFFFu), gen = m.id >> 16;
    if (slot == 0 || slot > ctx->mesh_slots) return NULL;
    if (!ctx->meshes[slot - 1].used || (ctx->meshes[slot - 1].generation & 0xFFFFu) != gen) return NULL;
    return &ctx->meshes[slot - 1];
}

static void gim__mesh_release(gim_context *ctx, gim__mesh *m) {
    const gim__gl *gl = &ctx->gl;
    if (m->vao) gl->DeleteVertexArrays(1, &m->vao);
    if (!m->host_buffers) {
        if (m->positions) gl->DeleteBuffers(1, &m->positions);
        if (m->normals) gl->DeleteBuffers(1, &m->normals);
        if (m->indices) gl->DeleteBuffers(1, &m->indices);
    }
    if (m->triangle_material) gl->DeleteBuffers(1, &m->triangle_material);
    if (m->bound) gl->DeleteBuffers(1, &m->bound);
    if (m->followed) gl->DeleteBuffers(1, &m->followed);
    gim__free(&ctx->env, m->tri_vertex);
    gim__free(&ctx->env, m->follow_cpu);
    gim__free(&ctx->env, m->caches);
    gim__free(&ctx->env, m->cache_material);
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

/* Area-weighted vertex normals: the sum of the unnormalised face normals around each vertex
   (gim_add_mesh without normals, gim_update_mesh_vertices of a deforming mesh without them). */
static void gim__vertex_normals(const float *pos, uint32_t vertex_count, const void *indices, gim_index_type index_type,
                                uint32_t tri_count, float *nrm) {
    uint32_t i;
    memset(nrm, 0, (size_t)vertex_count * 3u * sizeof(float));
    for (i = 0; i < tri_count; ++i) {
        uint32_t a = gim__index_at(indices, index_type, i * 3u), b = gim__index_at(indices, index_type, i * 3u + 1u),
                 c = gim__index_at(indices, index_type, i * 3u + 2u);
        gim_vec3 pa = gim_v3(pos[a * 3], pos[a * 3 + 1], pos[a * 3 + 2]);
        gim_vec3 fn = gim__v3_cross(gim__v3_sub(gim_v3(pos[b * 3], pos[b * 3 + 1], pos[b * 3 + 2]), pa),
                                   gim__v3_sub(gim_v3(pos[c * 3], pos[c * 3 + 1], pos[c * 3 + 2]), pa));
        uint32_t v[3];
        int k;
        v[0] = a; v[1] = b; v[2] = c;
        if (!gim__v3_isfinite(fn)) continue;
        for (k = 0; k < 3; ++k) {
            nrm[v[k] * 3] += fn.x;
            nrm[v[k] * 3 + 1] += fn.y;
            nrm[v[k] * 3 + 2] += fn.z;
        }
    }
    for (i = 0; i < vertex_count; ++i) {
        gim_vec3 n = gim_v3_normalize(gim_v3(nrm[i * 3], nrm[i * 3 + 1], nrm[i * 3 + 2]));
        if (n.x == 0.0f && n.y == 0.0f && n.z == 0.0f) n = gim_v3(0.0f, 0.0f, 1.0f); /* only on degenerate triangles */
        nrm[i * 3] = n.x; nrm[i * 3 + 1] = n.y; nrm[i * 3 + 2] = n.z;
    }
}

/* The material of each cache: that of the triangle whose centroid is nearest among those facing
   the cache's side (normals within 90 degrees; any triangle where none does), through the
   neighbour search's k-d tree over the centroids. A cache then carries its own material's
   glossy lobe (one lobe for every cache made a k = 50 surface's glossy light 1.8x off next to a
   k = 1 one). *out: count ids, allocated through the context's env. */
static gim_result gim__cache_materials(gim_context *ctx, const float *pos, const void *indices, gim_index_type index_type,
                                       uint32_t tri_count, const uint32_t *tri_material, const gim_cache *caches,
                                       uint32_t count, uint32_t **out) {
    static const char where[] = "gim_add_mesh (cache materials)";
    gim_cache *tc = (gim_cache *)gim__alloc_array(&ctx->env, tri_count ? tri_count : 1u, sizeof(gim_cache));
    uint32_t *idx = (uint32_t *)gim__alloc_array(&ctx->env, count, sizeof(uint32_t)), i, pass;
    uint32_t *cnt = (uint32_t *)gim__alloc_array(&ctx->env, count, sizeof(uint32_t));
    float *dmax = (float *)gim__alloc_array(&ctx->env, count, sizeof(float));
    uint32_t *mat = (uint32_t *)gim__alloc_array(&ctx->env, count, sizeof(uint32_t));
    gim_result r = GIM_OK;
    *out = NULL;
    if (!tc || !idx || !cnt || !dmax || !mat) {
        r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u caches, %u triangles", (unsigned)count, (unsigned)tri_count);
        goto done;
    }
    for (i = 0; i < tri_count; ++i) {
        uint32_t v[3], k;
        gim_vec3 a, b, c, n;
        for (k = 0; k < 3; ++k) v[k] = gim__index_at(indices, index_type, i * 3u + k);
        a = gim_v3(pos[v[0] * 3], pos[v[0] * 3 + 1], pos[v[0] * 3 + 2]);
        b = gim_v3(pos[v[1] * 3], pos[v[1] * 3 + 1], pos[v[1] * 3 + 2]);
        c = gim_v3(pos[v[2] * 3], pos[v[2] * 3 + 1], pos[v[2] * 3 + 2]);
        n = gim_v3_normalize(gim__v3_cross(gim__v3_sub(b, a), gim__v3_sub(c, a)));
        if (!(n.x != 0.0f || n.y != 0.0f || n.z != 0.0f) || !gim__v3_isfinite(n)) n = gim_v3(0.0f, 0.0f, 1.0f);
        tc[i].position[0] = (a.x + b.x + c.x) / 3.0f;
        tc[i].position[1] = (a.y + b.y + c.y) / 3.0f;
        tc[i].position[2] = (a.z + b.z + c.z) / 3.0f;
        tc[i].normal[0] = n.x; tc[i].normal[1] = n.y; tc[i].normal[2] = n.z;
        tc[i].area = 0.0f;
        tc[i].reflectance = 0.0f;
    }
    for (i = 0; i < count; ++i) mat[i] = tri_count ? tri_material[0] : 0u;
    for (pass = 0; pass < 2u && tri_count; ++pass) {   /* facing triangles, then any for the caches left */
        gim_cache_set set;
        gim_neighbour_desc nd;
        gim_neighbour_result nr;
        memset(&set, 0, sizeof set);
        set.caches = tc;
        set.count = tri_count;
        memset(&nd, 0, sizeof nd);
        nd.mesh.positions = caches[0].position;
        nd.mesh.position_stride = (uint32_t)sizeof(gim_cache);
        nd.mesh.normals = caches[0].normal;
        nd.mesh.normal_stride = (uint32_t)sizeof(gim_cache);
        nd.mesh.vertex_count = count;
        nd.caches = &set;
        nd.n = 1;
        nd.theta_eps = pass == 0 ? 1.5707963f : 3.14159265f;
        nd.env = ctx->env;
        nr.index = idx; nr.count = cnt; nr.d_cmax = dmax;
        if ((r = gim_cache_neighbours(&nd, &nr)) != GIM_OK) goto done;
        for (i = 0; i < count; ++i)
            if (cnt[i] > 0 && (pass == 0 || mat[i] == UINT32_MAX)) mat[i] = tri_material[idx[i]];
            else if (pass == 0) mat[i] = UINT32_MAX;   /* none facing: the second pass decides */
        if (pass == 0) {
            for (i = 0; i < count && mat[i] != UINT32_MAX; ++i) {}
            if (i == count) break;
        }
    }
    *out = mat;
    mat = NULL;
done:
    gim__free(&ctx->env, tc);
    gim__free(&ctx->env, idx);
    gim__free(&ctx->env, cnt);
    gim__free(&ctx->env, dmax);
    gim__free(&ctx->env, mat);
    return r;
}

/* The host's mesh buffers checked (names, sizes, alignment) and read back once into tight
   arrays (*positions: vertex_count float3, *indices: index_count of the index type). */
static gim_result gim__host_mesh_read(gim_context *ctx, const gim_mesh_desc *desc, float **positions, void **indices) {
    static const char where[] = "gim_add_mesh";
    const gim_mesh_buffers *b = &desc->buffers;
    const gim_mesh_data *d = &desc->data;
    const gim__gl *gl = &ctx->gl;
    uint32_t ps = b->position_stride ? b->position_stride : 12u, ns = b->normal_stride ? b->normal_stride : 12u;
    uint32_t isize = d->index_type == GIM_INDEX_U16 ? 2u : 4u, i;
    uint64_t need[3];
    gim__GLuint names[3];
    unsigned char *raw = NULL;
    gim_result r = GIM_OK;
    int k;
    *positions = NULL;
    *indices = NULL;
    if (!b->positions || !b->normals || !b->indices)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "buffers: positions, normals and indices all needed");
    if (d->vertex_count == 0 || d->index_count == 0 || d->index_count % 3u != 0 || d->vertex_count > 0x7FFFFFFFu / 3u)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "buffers: %u vertices, %u indices",
                         (unsigned)d->vertex_count, (unsigned)d->index_count);
    if (d->index_type != GIM_INDEX_DEFAULT && d->index_type != GIM_INDEX_U32 && d->index_type != GIM_INDEX_U16)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown index_type %d", (int)d->index_type);
    if (ps < 12u || ps % 4u || ns < 12u || ns % 4u || b->position_offset % 4u || b->normal_offset % 4u ||
        b->index_offset % isize)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "buffers: strides >= 12 and offsets must be "
                         "multiples of 4 (index_offset of the index size)");
    names[0] = b->positions; names[1] = b->normals; names[2] = b->indices;
    need[0] = b->position_offset + (uint64_t)(d->vertex_count - 1u) * ps + 12u;
    need[1] = b->normal_offset + (uint64_t)(d->vertex_count - 1u) * ns + 12u;
    need[2] = b->index_offset + (uint64_t)d->index_count * isize;
    gim__gl_enter(ctx, where);
    for (k = 0; k < 3 && r == GIM_OK; ++k) {
        gim__GLint64 size = 0;
        static const char *const what[3] = {"positions", "normals", "indices"};
        if (!gl->IsBuffer(names[k])) {
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "buffers.%s (%u) is not a GL buffer", what[k],
                          (unsigned)names[k]);
            break;
        }
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, names[k]);
        gl->GetBufferParameteri64v(GIM__GL_COPY_READ_BUFFER, GIM__GL_BUFFER_SIZE, &size);
        if ((uint64_t)size < need[k])
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "buffers.%s holds %lld bytes, the layout needs %llu",
                          what[k], (long long)size, (unsigned long long)need[k]);
    }
    if (r == GIM_OK) {
        *positions = (float *)gim__alloc_array(&ctx->env, (size_t)d->vertex_count * 3u, sizeof(float));
        *indices = gim__alloc_array(&ctx->env, (size_t)d->index_count, isize);
        raw = (unsigned char *)gim__alloc_array(&ctx->env, (size_t)(need[0] - b->position_offset), 1u);
        if (!*positions || !*indices || !raw)
            r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "a copy of %u vertices", (unsigned)d->vertex_count);
    }
    if (r == GIM_OK) {
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, b->positions);
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, (gim__GLintptr)b->position_offset,
                             (gim__GLsizeiptr)(need[0] - b->position_offset), raw);
        for (i = 0; i < d->vertex_count; ++i) memcpy(*positions + (size_t)i * 3u, raw + (size_t)i * ps, 12u);
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, b->indices);
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, (gim__GLintptr)b->index_offset,
                             (gim__GLsizeiptr)d->index_count * isize, *indices);
        r = gim__gl_check(ctx, where);
    }
    gim__free(&ctx->env, raw);
    if (r != GIM_OK) {
        gim__free(&ctx->env, *positions);
        gim__free(&ctx->env, *indices);
        *positions = NULL;
        *indices = NULL;
    }
    return gim__gl_leave(ctx, r);
}

static gim_result gim__add_mesh(gim_context *ctx, const gim_mesh_desc *desc, const gim_mesh_data *d, int host, gim_mesh *out);

GIMANY_DEF gim_result gim_add_mesh(gim_context *ctx, const gim_mesh_desc *desc, gim_mesh *out) {
    gim_mesh_data host_data;
    float *host_pos = NULL;
    void *host_idx = NULL;
    gim_result r;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!desc || !out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, "gim_add_mesh", "desc or out is NULL");
    if (!desc->buffers.positions && !desc->buffers.normals && !desc->buffers.indices)
        return gim__add_mesh(ctx, desc, &desc->data, 0, out);
    /* the host's buffers: what they hold, read once, stands in for the arrays */
    r = gim__host_mesh_read(ctx, desc, &host_pos, &host_idx);
    if (r != GIM_OK) return r;
    host_data = desc->data;
    host_data.positions = host_pos;
    host_data.position_stride = 0;
    host_data.normals = NULL;   /* drawn from the host's; the computed ones are not used */
    host_data.normal_stride = 0;
    host_data.indices = host_idx;
    r = gim__add_mesh(ctx, desc, &host_data, 1, out);
    gim__free(&ctx->env, host_pos);
    gim__free(&ctx->env, host_idx);
    return r;
}

static gim_result gim__add_mesh(gim_context *ctx, const gim_mesh_desc *desc, const gim_mesh_data *d, int host, gim_mesh *out) {
    static const char where[] = "gim_add_mesh";
    const gim__gl *gl = &ctx->gl;
    uint32_t pstride, nstride, i, slot, tri_count, max_material = 0;
    float *pos = NULL, *nrm = NULL;
    uint32_t *tri_material = NULL;
    uint32_t *cache_material = NULL;
    gim_cache *caches = NULL;
    float *bound = NULL;           /* deforming: per cache the 16 words of caches_follow.comp's Bound */
    uint32_t *tri_vertex = NULL;   /* deforming, own buffers: the indices, for new vertex normals */
    gim_cache *follow_cpu = NULL;
    gim__mesh m;
    gim_result r = GIM_OK;
    size_t index_bytes;
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
            pos[i * 3 + (uint32_t)k] = p[k];
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
        gim__vertex_normals(pos, d->vertex_count, d->indices, d->index_type, tri_count, nrm);
    }
    for (i = 0; i < tri_count; ++i) {
        tri_material[i] = d->triangle_material ? d->triangle_material[i] : 0u;
        if (tri_material[i] > max_material) max_material = tri_material[i];
    }
    if (caches) {
        for (i = 0; i < desc->caches->count; ++i) {
            const gim_cache *c = &desc->caches->caches[i];
            if (!gim__all_finite(c->position, 3) || !gim__all_finite(c->normal, 3) || !gim__isfinitef(c->area) ||
                !gim__isfinitef(c->reflectance) || !(c->area >= 0.0f) ||
                (c->normal[0] == 0.0f && c->normal[1] == 0.0f && c->normal[2] == 0.0f)) {
                r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                              "cache %u: not finite, negative area or zero normal", (unsigned)i);
                goto done;
            }
        }
        if (!(desc->caches->theta_eps >= 0.0f && desc->caches->theta_eps <= 1.5707964f)) {
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "caches->theta_eps %g not in [0, pi/2]",
                          (double)desc->caches->theta_eps);
            goto done;
        }
        memcpy(caches, desc->caches->caches, (size_t)desc->caches->count * sizeof(gim_cache));
        if (d->triangle_material) {
            r = gim__cache_materials(ctx, pos, d->indices, d->index_type, tri_count, tri_material, caches,
                                     desc->caches->count, &cache_material);
            if (r != GIM_OK) goto done;
        }
    }
    if (desc->deforming) {   /* bind the caches to their triangles now, in the rest pose */
        uint32_t cc = caches ? desc->caches->count : 0u;
        if (!host) {
            tri_vertex = (uint32_t *)gim__alloc_array(&ctx->env, d->index_count, sizeof(uint32_t));
            if (!tri_vertex) {
                r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u indices", (unsigned)d->index_count);
                goto done;
            }
            for (i = 0; i < d->index_count; ++i) tri_vertex[i] = gim__index_at(d->indices, d->index_type, i);
        }
        if (cc) {
            gim_cache_binding *bind = (gim_cache_binding *)gim__alloc_array(&ctx->env, cc, sizeof(gim_cache_binding));
            gim_mesh_data tight = *d;
            bound = (float *)gim__alloc_array(&ctx->env, cc, 64u);
            follow_cpu = (gim_cache *)gim__alloc_array(&ctx->env, cc, sizeof(gim_cache));
            if (!bind || !bound || !follow_cpu) {
                gim__free(&ctx->env, bind);
                r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "bindings of %u caches", (unsigned)cc);
                goto done;
            }
            tight.positions = pos;
            tight.position_stride = 0;
            r = gim_cache_bind(&tight, caches, cc, bind, ctx->env);
            for (i = 0; r == GIM_OK && i < cc; ++i) {
                float *w = bound + (size_t)i * 16u;
                memcpy(w, bind[i].vertex, 12u);   /* uvec4 tri (w unused) */
                w[3] = 0.0f;
                w[4] = bind[i].u; w[5] = bind[i].v; w[6] = bind[i].h; w[7] = bind[i].area2;
                w[8] = bind[i].frame[0]; w[9] = bind[i].frame[1]; w[10] = bind[i].frame[2]; w[11] = caches[i].area;
                w[12] = caches[i].reflectance; w[13] = caches[i].normal[0]; w[14] = caches[i].normal[1]; w[15] = caches[i].normal[2];
            }
            gim__free(&ctx->env, bind);
            if (r != GIM_OK) goto done;
            memcpy(follow_cpu, caches, (size_t)cc * sizeof(gim_cache));
        }
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
    if (host) {
        const gim_mesh_buffers *b = &desc->buffers;
        m.host_buffers = 1;
        m.positions = b->positions;
        m.normals = b->normals;
        m.indices = b->indices;
        m.position_offset = b->position_offset;
        m.position_stride = b->position_stride ? b->position_stride : 12u;
        m.index_offset = b->index_offset;
    } else {
        gim__GLenum usage = desc->deforming ? GIM__GL_DYNAMIC_DRAW : GIM__GL_STATIC_DRAW;   /* rewritten per frame */
        m.positions = gim__gl_buffer_with(ctx, pos, (size_t)d->vertex_count * 12u, usage);
        m.normals = gim__gl_buffer_with(ctx, nrm, (size_t)d->vertex_count * 12u, usage);
        m.indices = gim__gl_buffer_with(ctx, d->indices, index_bytes, GIM__GL_STATIC_DRAW);
        m.position_stride = 12u;
    }
    m.triangle_material = gim__gl_buffer_with(ctx, tri_material, (size_t)tri_count * 4u, GIM__GL_STATIC_DRAW);
    if (bound) {
        m.bound = gim__gl_buffer_with(ctx, bound, (size_t)desc->caches->count * 64u, GIM__GL_STATIC_DRAW);
        m.followed = gim__gl_buffer_with(ctx, NULL, (size_t)desc->caches->count * 32u, GIM__GL_DYNAMIC_COPY);
    }
    gl->GenVertexArrays(1, &m.vao);
    if (m.vao && m.positions && m.normals && m.indices) {
        const gim_mesh_buffers *b = &desc->buffers;
        gl->BindVertexArray(m.vao);
        gl->BindBuffer(GIM__GL_ARRAY_BUFFER, m.positions);
        gl->VertexAttribPointer(0, 3, GIM__GL_FLOAT, GIM__GL_FALSE, (gim__GLsizei)m.position_stride,
                                (const void *)(size_t)m.position_offset);
        gl->EnableVertexAttribArray(0);
        gl->BindBuffer(GIM__GL_ARRAY_BUFFER, m.normals);
        gl->VertexAttribPointer(1, 3, GIM__GL_FLOAT, GIM__GL_FALSE,
                                (gim__GLsizei)(host ? (b->normal_stride ? b->normal_stride : 12u) : 12u),
                                (const void *)(size_t)(host ? b->normal_offset : 0u));
        gl->EnableVertexAttribArray(1);
        gl->BindBuffer(GIM__GL_ELEMENT_ARRAY_BUFFER, m.indices); /* VAO state */
    }
    r = gim__gl_check(ctx, where);
    if (r == GIM_OK && !(m.vao && m.positions && m.normals && m.indices && m.triangle_material && (!bound || (m.bound && m.followed))))
        r = gim__fail(&ctx->env, GIM_ERROR_GL, where, "glGen* returned 0");
    m.deforming = desc->deforming ? 1 : 0;
    m.follow_dirty = 1;
    m.vertex_count = d->vertex_count;
    m.tri_vertex = tri_vertex;
    tri_vertex = NULL;
    m.follow_cpu = follow_cpu;
    follow_cpu = NULL;
    m.caches = caches;
    m.cache_material = cache_material;
    cache_material = NULL;
    m.cache_count = caches ? desc->caches->count : 0u;
    m.theta_eps = caches ? desc->caches->theta_eps : 0.0f;
    m.bytes = (host ? 0u : (uint64_t)d->vertex_count * 24u + index_bytes) + (uint64_t)tri_count * 4u +
              (bound ? (uint64_t)desc->caches->count * 96u : 0u);
    if (r != GIM_OK) {
        gl->BindVertexArray(0); /* not the host's: leave restores it */
        gim__mesh_release(ctx, &m); /* frees caches too */
        caches = NULL;
        gim__gl_leave(ctx, r);
        goto done;
    }
    gim__gl_leave(ctx, r);
    m.used = 1;
    ++ctx->scene_version;
    ctx->meshes[slot] = m;
    caches = NULL;
    out->id = (slot + 1u) | ((m.generation & 0xFFFFu) << 16);
done:
    gim__free(&ctx->env, pos);
    gim__free(&ctx->env, nrm);
    gim__free(&ctx->env, tri_material);
    gim__free(&ctx->env, caches);
    gim__free(&ctx->env, cache_material);
    gim__free(&ctx->env, bound);
    gim__free(&ctx->env, tri_vertex);
    gim__free(&ctx->env, follow_cpu);
    return r;
}

GIMANY_DEF gim_result gim_remove_mesh(gim_context *ctx, gim_mesh mesh) {
    gim__mesh *m;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    m = gim__mesh_get(ctx, mesh);
    if (!m) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, "gim_remove_mesh", "mesh %u is not a mesh", (unsigned)mesh.id);
    gim__gl_enter(ctx, "gim_remove_mesh");
    gim__mesh_release(ctx, m);
    ++ctx->scene_version;
    return gim__gl_leave(ctx, gim__gl_check(ctx, "gim_remove_mesh"));
}

GIMANY_DEF gim_result gim_update_mesh_vertices(gim_context *ctx, gim_mesh mesh, const float *positions,
                                               const float *normals, uint32_t vertex_count) {
    static const char where[] = "gim_update_mesh_vertices";
    gim__mesh *m;
    float *nrm = NULL, bmin[3], bmax[3];
    uint32_t i;
    int k;
    gim_result r;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    m = gim__mesh_get(ctx, mesh);
    if (!m) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "mesh %u is not a mesh", (unsigned)mesh.id);
    if (!m->deforming)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "mesh %u was not added with gim_mesh_desc.deforming: its caches are not bound to its triangles",
                         (unsigned)mesh.id);
    if (m->host_buffers)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "mesh %u is drawn from the host's buffers: write the new vertices there (gim_update reads them)",
                         (unsigned)mesh.id);
    if (!positions) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "positions is NULL");
    if (vertex_count != m->vertex_count)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "%u vertices, the mesh has %u", (unsigned)vertex_count,
                         (unsigned)m->vertex_count);
    for (k = 0; k < 3; ++k) { bmin[k] = FLT_MAX; bmax[k] = -FLT_MAX; }
    for (i = 0; i < vertex_count; ++i) {
        const float *p = positions + (size_t)i * 3u;
        if (!gim__all_finite(p, 3)) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "position %u is not finite", (unsigned)i);
        if (normals && (!gim__all_finite(normals + (size_t)i * 3u, 3) ||
                        (normals[i * 3u] == 0.0f && normals[i * 3u + 1u] == 0.0f && normals[i * 3u + 2u] == 0.0f)))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "normal %u is zero or not finite", (unsigned)i);
        for (k = 0; k < 3; ++k) {
            if (p[k] < bmin[k]) bmin[k] = p[k];
            if (p[k] > bmax[k]) bmax[k] = p[k];
        }
    }
    if (!normals) {
        nrm = (float *)gim__alloc_array(&ctx->env, (size_t)vertex_count * 3u, sizeof(float));
        if (!nrm) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "normals of %u vertices", (unsigned)vertex_count);
        gim__vertex_normals(positions, vertex_count, m->tri_vertex, GIM_INDEX_U32, m->triangle_count, nrm);
    }
    /* new storage (glBufferData), not glBufferSubData into the old: no wait on frames in flight
       that still draw the last vertices, and on NVIDIA 580 a glBufferSubData before the mesh's
       first frame left the buffer as gim_add_mesh filled it (gltest_deform twin) */
    gim__gl_enter(ctx, where);
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, m->positions);
    ctx->gl.BufferData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLsizeiptr)vertex_count * 12, positions, GIM__GL_DYNAMIC_DRAW);
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, m->normals);
    ctx->gl.BufferData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLsizeiptr)vertex_count * 12, normals ? normals : nrm,
                       GIM__GL_DYNAMIC_DRAW);
    gim__free(&ctx->env, nrm);
    r = gim__gl_check(ctx, where);
    if (r == GIM_OK) {
        memcpy(m->bmin, bmin, sizeof bmin);
        memcpy(m->bmax, bmax, sizeof bmax);
        m->follow_dirty = 1;
        ++ctx->scene_version;   /* like a moved instance: the world caches, their grid and the ISMs are made again */
    }
    return gim__gl_leave(ctx, r);
}

/* Before a frame's bounds are taken: every instanced deforming mesh whose vertices may have
   changed (the host's buffers: always; gimany's copy: after gim_update_mesh_vertices) gets
   its bounds (host buffers, caches_follow.comp mode 0) and its caches moved with their
   triangles (mode 1, LightSkin frames only, the only ones that use caches), both read back in
   one go: the world caches' hash grid is built on the CPU, so the followed caches (32 bytes
   each, not the vertices) cross to it once per frame. A static mesh is skipped at no cost. */
static gim_result gim__deform_prepare(gim_context *ctx, const gim_frame *f) {
    static const char where[] = "gim_update (deforming meshes)";
    const gim__gl *gl = &ctx->gl;
    int lightskin = f->method == GIM_METHOD_DEFAULT || f->method == GIM_METHOD_LIGHTSKIN_BRSM ||
                    f->method == GIM_METHOD_LIGHTSKIN_FULL;
    gim__GLuint program = 0;
    uint32_t i, j;
    gim_result r = GIM_OK;
    for (i = 0; i < ctx->instance_count; ++i) {
        gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        if (m && m->deforming && (m->host_buffers || (lightskin && m->follow_dirty && m->cache_count))) break;
    }
    if (i == ctx->instance_count) return GIM_OK;   /* no deforming mesh, or none changed */
    gim__gl_enter(ctx, where);
    r = gim__gl_program(ctx, GIM__PROGRAM_CACHES_FOLLOW, &program);
    if (r == GIM_OK) gl->UseProgram(program);
    for (i = 0; r == GIM_OK && i < ctx->instance_count; ++i) {
        gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        uint32_t words[7];
        int follow;
        if (!m || !m->deforming) continue;
        for (j = 0; j < i && ctx->instances[j].mesh.id != ctx->instances[i].mesh.id; ++j) {}
        if (j < i) continue;   /* done for an earlier instance of the same mesh */
        follow = lightskin && m->cache_count > 0 && (m->host_buffers || m->follow_dirty);
        if (!m->host_buffers && !follow) continue;
        /* every storage block of the program bound whatever the mode uses: NVIDIA skips a
           dispatch whose program names a block with nothing bound (mode 1 then left the caches
           where they were); the box stands in for the blocks a mode does not read */
        if (!ctx->deform_box) {
            for (j = 0; j < 7; ++j) words[j] = 0u;
            ctx->deform_box = gim__gl_buffer_with(ctx, words, 28u, GIM__GL_DYNAMIC_COPY);
            if (!ctx->deform_box) {
                r = gim__fail(&ctx->env, GIM_ERROR_GL, where, "glGenBuffers returned 0");
                break;
            }
        }
        for (j = 1; j <= 3; ++j) gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, j, ctx->deform_box);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, m->positions);
        gl->Uniform1ui(2, m->position_offset / 4u);
        gl->Uniform1ui(3, m->position_stride / 4u);
        if (m->host_buffers) {   /* the bounds of what the host's buffer holds now */
            for (j = 0; j < 3; ++j) { words[j] = 0xFFFFFFFFu; words[3 + j] = 0u; }
            words[6] = 0u;
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->deform_box);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, 28, words);
            gl->Uniform1ui(0, 0u);
            gl->Uniform1ui(1, m->vertex_count);
            gl->DispatchCompute((m->vertex_count + 63u) / 64u, 1u, 1u);
        }
        if (follow) {
            gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, m->bound);
            gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, m->followed);
            gl->Uniform1ui(0, 1u);
            gl->Uniform1ui(1, m->cache_count);
            gl->DispatchCompute((m->cache_count + 63u) / 64u, 1u, 1u);
        }
        gl->MemoryBarrier(GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
        if (m->host_buffers) {
            float lo[3], hi[3];
            gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, ctx->deform_box);
            gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, 28, words);
            for (j = 0; j < 3; ++j) {   /* back from the ordered encoding */
                uint32_t a = words[j] & 0x80000000u ? words[j] & 0x7FFFFFFFu : ~words[j];
                uint32_t b = words[3 + j] & 0x80000000u ? words[3 + j] & 0x7FFFFFFFu : ~words[3 + j];
                memcpy(&lo[j], &a, 4);
                memcpy(&hi[j], &b, 4);
            }
            if (words[6] || !gim__all_finite(lo, 3) || !gim__all_finite(hi, 3)) {
                r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                              "mesh %u: its host buffer holds a non-finite position", (unsigned)ctx->instances[i].mesh.id);
                break;
            }
            memcpy(m->bmin, lo, sizeof lo);
            memcpy(m->bmax, hi, sizeof hi);
            ++ctx->scene_version;   /* it may have moved: world caches, grid and ISMs are made again */
        }
        if (follow) {
            gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, m->followed);
            gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, (gim__GLsizeiptr)m->cache_count * 32, m->follow_cpu);
            for (j = 0; j < m->cache_count; ++j)
                if (!gim__all_finite(m->follow_cpu[j].position, 3) || !gim__all_finite(m->follow_cpu[j].normal, 3) ||
                    !gim__isfinitef(m->follow_cpu[j].area))
                    break;
            if (j < m->cache_count) {
                r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "mesh %u: cache %u followed to a non-finite place",
                              (unsigned)ctx->instances[i].mesh.id, (unsigned)j);
                break;
            }
            m->follow_dirty = 0;
        }
    }
    if (r == GIM_OK) r = gim__gl_check(ctx, where);
    return gim__gl_leave(ctx, r);
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
            m->glossy[1] < 0.0f || m->glossy[2] < 0.0f || m->exponent < 0.0f || m->exponent > GIM__TWINS_MAX_EXPONENT)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                             "material %u: values must be finite and >= 0, the exponent at most 1e6", (unsigned)i);
    }
    {   /* a surface that reflects more than it receives gains energy at every bounce */
        uint32_t over = 0, first = 0;
        for (i = 0; i < count; ++i) {
            const gim_material *m = &materials[i];
            int c;
            for (c = 0; c < 3; ++c)
                if (m->diffuse[c] + m->glossy[c] > 1.0f) break;
            if (c < 3 && over++ == 0) first = i;
        }
        if (over)
            gim__log(&ctx->env, GIM_LOG_WARNING, where,
                     "%u material(s) reflect more than they receive (diffuse + glossy > 1 in a channel; first: material %u): "
                     "their bounces gain energy", (unsigned)over, (unsigned)first);
    }
    ++ctx->materials_version;
    gim__free(&ctx->env, ctx->material_exponent);
    ctx->material_exponent = NULL;
    if (count == 0) {
        gim__gl_enter(ctx, where);
        if (ctx->materials) ctx->gl.DeleteBuffers(1, &ctx->materials);
        ctx->materials = 0;
        ctx->material_count = 0;
        ctx->glossy_material_count = 0;
        return gim__gl_leave(ctx, gim__gl_check(ctx, where));
    }
    packed = (float *)gim__alloc_array(&ctx->env, count, 8u * sizeof(float));
    ctx->material_exponent = (float *)gim__alloc_array(&ctx->env, count, sizeof(float));
    if (!packed || !ctx->material_exponent) {
        gim__free(&ctx->env, packed);
        ctx->material_count = 0;
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u materials", (unsigned)count);
    }
    for (i = 0; i < count; ++i) {
        float *p = packed + (size_t)i * 8u;
        memcpy(p, materials[i].diffuse, 3 * sizeof(float));
        p[3] = 0.0f;
        memcpy(p + 4, materials[i].glossy, 3 * sizeof(float));
        p[7] = materials[i].exponent;
        ctx->material_exponent[i] = materials[i].exponent;
    }
    ctx->glossy_material_count = 0;
    ctx->glossy_min_exponent = 0.0f;
    for (i = 0; i < count; ++i) {
        const gim_material *m = &materials[i];
        if (!(m->glossy[0] > 0.0f || m->glossy[1] > 0.0f || m->glossy[2] > 0.0f)) continue;
        if (ctx->glossy_material_count++ == 0 || m->exponent < ctx->glossy_min_exponent)
            ctx->glossy_min_exponent = m->exponent > GIM__TWINS_MAX_EXPONENT ? GIM__TWINS_MAX_EXPONENT : m->exponent;
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
        if (!gim__mat4_isfinite(instances[i].model) || !gim_mat4_invert(instances[i].model, &inv))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instance %u: model matrix not finite or singular",
                             (unsigned)i);
    }
    if (count > ctx->instance_capacity) {
        gim_instance *grown = (gim_instance *)gim__alloc_array(&ctx->env, count, sizeof(gim_instance));
        if (!grown) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u instances", (unsigned)count);
        if (ctx->instance_count) memcpy(grown, ctx->instances, (size_t)ctx->instance_count * sizeof(gim_instance));
        gim__free(&ctx->env, ctx->instances);
        ctx->instances = grown;
        ctx->instance_capacity = count;
    }
    if (count != ctx->instance_count || (count && memcmp(ctx->instances, instances, (size_t)count * sizeof(gim_instance))))
        ++ctx->scene_version;   /* the caches' world positions must be made again */
    if (count) memcpy(ctx->instances, instances, (size_t)count * sizeof(gim_instance));
    ctx->instance_count = count;
    return GIM_OK;
}

/* Delete one light's buffers of the defensive share (a frame without it keeps none). */
static void gim__light_lum_release(gim_context *ctx, gim__light_gpu *g) {
    gim__GLuint b[4];
    if (!g->lum_map && !g->lum_tiles && !g->lum_column && !g->lum_row) return;   /* none: no GL call a frame */
    b[0] = g->lum_map; b[1] = g->lum_tiles; b[2] = g->lum_column; b[3] = g->lum_row;
    ctx->gl.DeleteBuffers(4, b);   /* 0 names are ignored */
    g->lum_map = g->lum_tiles = g->lum_column = g->lum_row = 0;
    g->lum_map_bytes = g->lum_tiles_bytes = g->lum_column_bytes = g->lum_row_bytes = 0;
}

/* Delete one light's GL objects. */
static void gim__light_gpu_release(gim_context *ctx, gim__light_gpu *g) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint t[4], b[9];
    t[0] = g->position; t[1] = g->normal; t[2] = g->flux; t[3] = g->depth;
    b[0] = g->map; b[1] = g->column; b[2] = g->row; b[3] = g->selected; b[4] = g->tiles;
    b[5] = g->lum_map; b[6] = g->lum_tiles; b[7] = g->lum_column; b[8] = g->lum_row;
    gl->DeleteTextures(4, t); /* 0 names are ignored */
    gl->DeleteBuffers(9, b);
    if (g->fbo) gl->DeleteFramebuffers(1, &g->fbo);
    memset(g, 0, sizeof *g);
}

/* Grow the per-RSM arrays to hold n (they only grow; the GL objects are made by the frame). */
static gim_result gim__lights_reserve(gim_context *ctx, uint32_t n, const char *where) {
    const gim_env *env = &ctx->env;
    gim_light *l;
    gim__light_gpu *g;
    unsigned char *on;
    uint32_t *vals, *sizes;
    double *total;
    gim_light_outputs *lo;
    uint32_t cap = ctx->light_capacity, old = ctx->light_capacity;
    if (n <= cap) return GIM_OK;
    while (cap < n) cap = cap ? cap * 2u : 16u;
    if (cap > GIM_MAX_LIGHTS) cap = GIM_MAX_LIGHTS;
    l = (gim_light *)gim__alloc_array(env, cap, sizeof *l);
    g = (gim__light_gpu *)gim__alloc_array(env, cap, sizeof *g);
    on = (unsigned char *)gim__alloc_array(env, cap, 1u);
    vals = (uint32_t *)gim__alloc_array(env, cap, sizeof *vals);
    sizes = (uint32_t *)gim__alloc_array(env, cap, sizeof *sizes);
    total = (double *)gim__alloc_array(env, cap, sizeof *total);
    lo = (gim_light_outputs *)gim__alloc_array(env, cap, sizeof *lo);
    if (!l || !g || !on || !vals || !sizes || !total || !lo) {
        gim__free(env, l); gim__free(env, g); gim__free(env, on); gim__free(env, vals);
        gim__free(env, sizes); gim__free(env, total); gim__free(env, lo);
        return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "%u lights", (unsigned)n);
    }
    memset(g, 0, (size_t)cap * sizeof *g);
    memset(on, 0, cap);
    memset(vals, 0, (size_t)cap * sizeof *vals);
    memset(sizes, 0, (size_t)cap * sizeof *sizes);
    memset(total, 0, (size_t)cap * sizeof *total);
    memset(lo, 0, (size_t)cap * sizeof *lo);
    if (old) {
        memcpy(l, ctx->lights, (size_t)old * sizeof *l);
        memcpy(g, ctx->light_gpu, (size_t)old * sizeof *g);
        memcpy(on, ctx->light_on, old);
        memcpy(vals, ctx->light_vals, (size_t)old * sizeof *vals);
        memcpy(sizes, ctx->gather_key_sizes, (size_t)old * sizeof *sizes);
        memcpy(total, ctx->light_total, (size_t)old * sizeof *total);
        memcpy(lo, ctx->light_outputs, (size_t)old * sizeof *lo);
    }
    gim__free(env, ctx->lights); gim__free(env, ctx->light_gpu); gim__free(env, ctx->light_on);
    gim__free(env, ctx->light_vals); gim__free(env, ctx->gather_key_sizes); gim__free(env, ctx->light_total);
    gim__free(env, ctx->light_outputs);
    ctx->lights = l; ctx->light_gpu = g; ctx->light_on = on; ctx->light_vals = vals;
    ctx->gather_key_sizes = sizes; ctx->light_total = total; ctx->light_outputs = lo;
    ctx->outputs.lights = lo;   /* the last frame's, moved */
    ctx->light_capacity = cap;
    return GIM_OK;
}

/* gim_set_lights' work (buffer: from gim_set_lights_buffer, kept set). */
static gim_result gim__set_lights(gim_context *ctx, const gim_light *lights, uint32_t count, const char *where) {
    uint32_t i, limit, n = 0;
    gim_result r;
    for (i = 0; i < count && n <= GIM_MAX_LIGHTS; ++i) n += lights[i].type == GIM_LIGHT_POINT ? 6u : 1u;
    if (n > GIM_MAX_LIGHTS)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u lights need more than %u RSMs (a point light takes 6)",
                         (unsigned)count, GIM_MAX_LIGHTS);
    limit = (uint32_t)ctx->max_texture_size;
    if ((uint32_t)ctx->max_viewport[0] < limit) limit = (uint32_t)ctx->max_viewport[0];
    if ((uint32_t)ctx->max_viewport[1] < limit) limit = (uint32_t)ctx->max_viewport[1];
    for (i = 0; i < count; ++i) {
        r = gim__light_check(&lights[i], &ctx->env, where, i);
        if (r != GIM_OK) return r;
        if (gim__light_rsm_size(&lights[i]) > limit)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: rsm_size %u above the GL limit %u",
                             (unsigned)i, (unsigned)gim__light_rsm_size(&lights[i]), (unsigned)limit);
    }
    r = gim__lights_reserve(ctx, n, where);
    if (r != GIM_OK) return r;
    for (i = 0; i < count; ++i)
        if (gim__light_rsm_size(&lights[i]) < GIM__MIN_GOOD_RSM)
            gim__log(&ctx->env, GIM_LOG_WARNING, where,
                     "light %u: a %u^2 RSM gives it %u VALs: expect a blotchy or saturated image (good: %u..16384)",
                     (unsigned)i, (unsigned)lights[i].rsm_size, (unsigned)(lights[i].rsm_size * lights[i].rsm_size),
                     GIM__MIN_GOOD_RSM);
    ctx->half_warned = 0;
    for (i = 0, n = 0; i < count; ++i) {   /* what the passes light with: a POINT light's six faces */
        if (lights[i].type == GIM_LIGHT_POINT) {
            gim_point_light_faces(&lights[i], ctx->lights + n);
            n += 6u;
        } else {
            ctx->lights[n++] = lights[i];
        }
    }
    count = n;
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

GIMANY_DEF gim_result gim_set_lights(gim_context *ctx, const gim_light *lights, uint32_t count) {
    static const char where[] = "gim_set_lights";
    gim_result r;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (count && !lights) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "lights is NULL");
    r = gim__set_lights(ctx, lights, count, where);
    if (r == GIM_OK) ctx->light_buffer = 0, ctx->light_buffer_count = 0, ctx->light_buffer_last_count = 0;
    return r;
}

/* A gim_light from its std430 form (gim_light_std430). */
static gim_light gim__light_from_std430(const gim_light_std430 *b) {
    gim_light l;
    memset(&l, 0, sizeof l);
    l.type = (gim_light_type)b->type_square_size_fit[0];
    memcpy(l.color, b->color_power, sizeof l.color);
    if (l.type == GIM_LIGHT_SPOT || l.type == GIM_LIGHT_POINT) l.intensity = b->color_power[3];
    else l.irradiance = b->color_power[3];
    l.position = gim_v3(b->position_cone[0], b->position_cone[1], b->position_cone[2]);
    l.cone_angle = b->position_cone[3];
    l.direction = gim_v3(b->direction_extent[0], b->direction_extent[1], b->direction_extent[2]);
    l.extent = b->direction_extent[3];
    l.square_cone = (int)b->type_square_size_fit[1];
    l.rsm_size = b->type_square_size_fit[2];
    l.fit_view = (int)b->type_square_size_fit[3];
    return l;
}

/* Read the host's light buffer back and set its lights (inside gim__gl_enter). */
static gim_result gim__gl_lights_from_buffer(gim_context *ctx, const char *where) {
    uint32_t i, count = ctx->light_buffer_count;
    gim_light_std430 *raw;
    gim_light *lights;
    gim_result r;
    gim__GLuint buffer = ctx->light_buffer;
    r = gim__gl_check_buffer(ctx, where, "light buffer", buffer, (uint64_t)count * sizeof(gim_light_std430));
    if (r != GIM_OK) return r;
    raw = (gim_light_std430 *)gim__alloc_array(&ctx->env, count, sizeof *raw);
    lights = (gim_light *)gim__alloc_array(&ctx->env, count, sizeof *lights);
    if (!raw || !lights) {
        gim__free(&ctx->env, raw);
        gim__free(&ctx->env, lights);
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u lights", (unsigned)count);
    }
    ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, buffer);
    ctx->gl.GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, (gim__GLsizeiptr)count * (gim__GLsizeiptr)sizeof *raw, raw);
    r = gim__gl_check(ctx, where);
    if (r == GIM_OK && ctx->light_buffer_last_count == count &&
        memcmp(ctx->light_buffer_last, raw, (size_t)count * sizeof *raw) == 0) { /* unchanged: the lights stand */
        gim__free(&ctx->env, raw);
        gim__free(&ctx->env, lights);
        return GIM_OK;
    }
    for (i = 0; i < count && r == GIM_OK; ++i) {
        if (raw[i].type_square_size_fit[0] > (uint32_t)GIM_LIGHT_POINT)
            r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "light %u: type %u", (unsigned)i,
                          (unsigned)raw[i].type_square_size_fit[0]);
        lights[i] = gim__light_from_std430(&raw[i]);
    }
    if (r == GIM_OK) r = gim__set_lights(ctx, lights, count, where);
    gim__free(&ctx->env, ctx->light_buffer_last);   /* kept to skip the checks while it does not change */
    ctx->light_buffer_last = r == GIM_OK ? raw : NULL;
    ctx->light_buffer_last_count = r == GIM_OK ? count : 0u;
    if (r != GIM_OK) gim__free(&ctx->env, raw);
    gim__free(&ctx->env, lights);
    return r;
}

GIMANY_DEF gim_result gim_set_lights_buffer(gim_context *ctx, uint32_t buffer, uint32_t count) {
    static const char where[] = "gim_set_lights_buffer";
    gim_result r;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (buffer == 0 || count == 0) {
        r = gim__set_lights(ctx, NULL, 0, where);
        ctx->light_buffer = 0, ctx->light_buffer_count = 0, ctx->light_buffer_last_count = 0;
        return r;
    }
    if (count > GIM_MAX_LIGHTS)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u lights above %u", (unsigned)count, GIM_MAX_LIGHTS);
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "buffer", buffer, (uint64_t)count * sizeof(gim_light_std430));
    r = gim__gl_leave(ctx, r);
    if (r != GIM_OK) return r;
    ctx->light_buffer = buffer;
    ctx->light_buffer_count = count;
    ctx->light_buffer_last_count = 0;   /* read at the next gim_update */
    return GIM_OK;
}

static void gim__lightskin_drop(gim_context *ctx);
static void gim__bvh_release(gim_context *ctx);
static void gim__ism_release(gim_context *ctx);
static uint32_t gim__ism_frame_size(const gim_frame *f, uint64_t caches);

static void gim__scene_destroy(gim_context *ctx) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i;
    gim__GLuint t[5], b[2];
    for (i = 0; i < ctx->mesh_slots; ++i)
        if (ctx->meshes[i].used) gim__mesh_release(ctx, &ctx->meshes[i]);
    gim__free(&ctx->env, ctx->meshes);
    gim__free(&ctx->env, ctx->instances);
    for (i = 0; i < ctx->light_capacity; ++i) gim__light_gpu_release(ctx, &ctx->light_gpu[i]);
    gim__free(&ctx->env, ctx->lights); gim__free(&ctx->env, ctx->light_gpu); gim__free(&ctx->env, ctx->light_on);
    gim__free(&ctx->env, ctx->light_vals); gim__free(&ctx->env, ctx->gather_key_sizes);
    gim__free(&ctx->env, ctx->light_total); gim__free(&ctx->env, ctx->light_outputs);
    gim__free(&ctx->env, ctx->light_buffer_last);
    if (ctx->light_totals) gl->DeleteBuffers(1, &ctx->light_totals);
    t[0] = ctx->gbuffer_depth; t[1] = ctx->gbuffer_normal; t[2] = ctx->gbuffer_albedo;
    t[3] = ctx->gbuffer_material; t[4] = ctx->indirect;
    gl->DeleteTextures(5, t);
    t[0] = ctx->decoded_normal; t[1] = ctx->decoded_depth;
    gl->DeleteTextures(2, t);
    gim__lightskin_drop(ctx);
    gim__bvh_release(ctx);
    gim__free(&ctx->env, ctx->material_exponent);
    b[0] = ctx->gather_samples; b[1] = ctx->gather_sum;
    gl->DeleteBuffers(2, b);
    gim__ism_release(ctx);
    if (ctx->facing) gl->DeleteBuffers(1, &ctx->facing);
    if (ctx->facing_sync) gl->DeleteSync(ctx->facing_sync);
    gim__vpl_release(ctx);
    if (ctx->query_count) gl->DeleteQueries((gim__GLsizei)ctx->query_count, ctx->queries);
    if (ctx->gbuffer_fbo) gl->DeleteFramebuffers(1, &ctx->gbuffer_fbo);
    if (ctx->nearest_sampler) gl->DeleteSamplers(1, &ctx->nearest_sampler);
    if (ctx->materials) gl->DeleteBuffers(1, &ctx->materials);
    if (ctx->view_sample_pixels) gl->DeleteBuffers(1, &ctx->view_sample_pixels);
    if (ctx->view_samples) gl->DeleteBuffers(1, &ctx->view_samples);
}

/* --- the shared passes of the frame (docs/design.md sec. 3) ------------------------------------- */

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
    gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, *fbo);   /* not the read framebuffer: the host's stays */
    for (i = 0; i < n; ++i) {
        gl->FramebufferTexture2D(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i,
                                 GIM__GL_TEXTURE_2D, color[i], 0);
        bufs[i] = GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i;
    }
    gl->FramebufferTexture2D(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_DEPTH_ATTACHMENT, GIM__GL_TEXTURE_2D, depth, 0);
    gl->DrawBuffers(n, bufs);
    status = gl->CheckFramebufferStatus(GIM__GL_DRAW_FRAMEBUFFER);
    if (status != GIM__GL_FRAMEBUFFER_COMPLETE)
        return gim__fail(&ctx->env, GIM_ERROR_GL, where, "framebuffer incomplete (0x%04x)", (unsigned)status);
    return gim__gl_check(ctx, where);
}

/* Raster state of the RSM, G-buffer and paraboloid passes, everything from the state list.
   Blend and colour mask per draw buffer of gimany's FBOs only: glDisable(GL_BLEND) and
   glColorMask would change all eight, and the state list saves these four. */
static void gim__gl_raster_state(const gim__gl *gl, gim__GLuint fbo, uint32_t w, uint32_t h) {
    unsigned i;
    gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, fbo);
    gl->Viewport(0, 0, (gim__GLsizei)w, (gim__GLsizei)h);
    for (i = 0; i < GIM__GL_STATE_CAPS; ++i) gl->Disable(gim__gl_state_caps[i]);
    gl->Enable(GIM__GL_DEPTH_TEST);
    gl->DepthFunc(GIM__GL_LESS);
    gl->DepthMask(GIM__GL_TRUE);
    for (i = 0; i < GIM__GL_DRAW_BUFFERS; ++i) {
        gl->Disablei(GIM__GL_BLEND, i);
        gl->ColorMaski(i, GIM__GL_TRUE, GIM__GL_TRUE, GIM__GL_TRUE, GIM__GL_TRUE);
    }
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
/* Every instance, copies times each (GL instancing: the paraboloid pass's one copy per map);
   model and normal matrices at uniforms 0 and 1, the mesh's triangle materials at binding 1. */
static void gim__gl_draw_meshes(gim_context *ctx, uint32_t copies) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i;
    for (i = 0; i < ctx->instance_count; ++i) {
        const gim_instance *in = &ctx->instances[i];
        const gim__mesh *m = gim__mesh_get(ctx, in->mesh);
        gim_mat4 nm = gim__mat4_normal(in->model);
        gl->UniformMatrix4fv(0, 1, GIM__GL_FALSE, in->model.m);
        gl->UniformMatrix4fv(1, 1, GIM__GL_FALSE, nm.m);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, m->triangle_material);
        gl->BindVertexArray(m->vao);
        if (copies == 1u)
            gl->DrawElements(GIM__GL_TRIANGLES, (gim__GLsizei)m->index_count, m->index_type,
                             (const void *)(size_t)m->index_offset);
        else
            gl->DrawElementsInstanced(GIM__GL_TRIANGLES, (gim__GLsizei)m->index_count, m->index_type,
                                      (const void *)(size_t)m->index_offset, (gim__GLsizei)copies);
    }
}

static void gim__gl_draw_instances(gim_context *ctx, gim_mat4 view_proj) {
    ctx->gl.UniformMatrix4fv(2, 1, GIM__GL_FALSE, view_proj.m);
    ctx->gl.BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->materials);
    gim__gl_draw_meshes(ctx, 1u);
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

/* RSM of light i (Bischoff 2017 sec. 3; units in @section twins): position (w = lit),
   normal (w = A), flux, depth. */
static gim_result gim__gl_rsm(gim_context *ctx, uint32_t i, const gim_light *l, const float bmin[3], const float bmax[3]) {
    static const char where[] = "RSM (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__light_gpu *g = &ctx->light_gpu[i];
    uint32_t size = gim__light_rsm_size(l);
    gim__GLuint program = 0;
    float power[3], eye[4];
    gim_result r = gim__light_camera_kept(l, bmin, bmax, &g->view, &g->proj, &g->up_axis, &g->up_dir);
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
        gl->Uniform4f(7, axis.x, axis.y, axis.z, l->square_cone ? -2.0f : cosf(l->cone_angle));   /* -2: all lit */
        gl->Uniform4f(8, (float)size, tan_half, s * s, 0.0f);
    } else {
        float a = (float)((2.0 / g->proj.m[0] / size) * (2.0 / g->proj.m[5] / size));   /* perpendicular texel area */
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
   where drawn), diffuse albedo (RGBA8), material id (R32F). */
#define GIM__FACING_PERIOD 32u

/* The counted LightSkin frame's G-buffer counts (ctx->facing, bound to COPY_WRITE_BUFFER): when
   most fragments showed the back of their surface, warn once. LightSkin's caches receive on
   their normal's side only (the other methods are two-sided), so a closed object whose normals
   face outward, seen from inside, gets no indirect light: measured on the Cornell box with
   every normal and winding flipped, 4% of the image's mean, the other methods unchanged. */
static void gim__facing_check(gim_context *ctx) {
    uint32_t c[2] = {0u, 0u};
    ctx->gl.GetBufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, sizeof c, c);
    if (c[0] > 0u && c[1] > c[0] / 2u) {
        ctx->facing_warned = 1;
        gim__log(&ctx->env, GIM_LOG_WARNING, "gim_update",
                 "%u of %u G-buffer fragments show the back of their surface (the normal faces away from the "
                 "eye): LightSkin lights surfaces on their normal's side only, so these get no indirect light; "
                 "flip those meshes' normals and winding (RSM gather, CLUSTERED and SSVP are two-sided)",
                 (unsigned)c[1], (unsigned)c[0]);
    }
}

static gim_result gim__gl_gbuffer(gim_context *ctx, const gim_frame *f) {
    static const char where[] = "G-buffer (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    int count;
    float eye[4];
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_GBUFFER, &program);
    if (r != GIM_OK) return r;
    if (ctx->gbuffer_width != f->width || ctx->gbuffer_height != f->height || !ctx->gbuffer_fbo) {
        gim__GLuint color[3];
        gim__gl_texture(ctx, &ctx->gbuffer_depth, GIM__GL_DEPTH_COMPONENT32F, f->width, f->height);
        /* 20 bytes a pixel: half normals (~5e-4) are plenty for the cosines of eq. 8-10, 8-bit
           albedo is what engines keep, a float material id; positions come from the 32-bit depth */
        gim__gl_texture(ctx, &ctx->gbuffer_normal, GIM__GL_RGBA16F, f->width, f->height);
        gim__gl_texture(ctx, &ctx->gbuffer_albedo, GIM__GL_RGBA8, f->width, f->height);
        gim__gl_texture(ctx, &ctx->gbuffer_material, GIM__GL_R32F, f->width, f->height);
        color[0] = ctx->gbuffer_normal; color[1] = ctx->gbuffer_albedo; color[2] = ctx->gbuffer_material;
        ctx->gbuffer_width = ctx->gbuffer_height = 0;
        r = gim__gl_framebuffer(ctx, &ctx->gbuffer_fbo, color, 3, ctx->gbuffer_depth, where);
        if (r != GIM_OK) return r;
        ctx->gbuffer_width = f->width;
        ctx->gbuffer_height = f->height;
    }
    gim__camera_eye(f->view, f->proj, eye);
    if (!ctx->facing) {
        static const uint32_t zero[2] = {0u, 0u};
        gl->GenBuffers(1, &ctx->facing);
        gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->facing);
        gl->BufferData(GIM__GL_COPY_WRITE_BUFFER, sizeof zero, zero, GIM__GL_DYNAMIC_COPY);
    }
    gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->facing);
    if (ctx->facing_sync) {   /* no flush, no wait: read when the counted frame is done */
        gim__GLenum st = gl->ClientWaitSync(ctx->facing_sync, 0u, 0u);
        if (st == GIM__GL_ALREADY_SIGNALED || st == GIM__GL_CONDITION_SATISFIED) {
            gl->DeleteSync(ctx->facing_sync);
            ctx->facing_sync = 0;
            gim__facing_check(ctx);
        }
    }
    count = !ctx->facing_warned && !ctx->facing_sync && ctx->facing_frame++ % GIM__FACING_PERIOD == 0u &&
            (f->method == GIM_METHOD_DEFAULT || f->method == GIM_METHOD_LIGHTSKIN_BRSM ||
             f->method == GIM_METHOD_LIGHTSKIN_FULL);
    if (count) {
        static const uint32_t zero[2] = {0u, 0u};
        gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, sizeof zero, zero);
    }
    gim__gl_raster_state(gl, ctx->gbuffer_fbo, f->width, f->height);
    gim__gl_clear_targets(gl, 3);
    gl->UseProgram(program);
    gl->Uniform1ui(3, ctx->material_count);
    gl->Uniform4f(4, eye[0], eye[1], eye[2], eye[3]);
    gl->Uniform1ui(5, (gim__GLuint)count);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, ctx->facing);
    gim__gl_draw_instances(ctx, gim_mat4_mul(f->proj, f->view));
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    if (count) ctx->facing_sync = gl->FenceSync(GIM__GL_SYNC_GPU_COMMANDS_COMPLETE, 0u);
    return gim__gl_check(ctx, where);
}

/* The sampler the passes read textures through: nearest, no depth comparison (texelFetch of a
   host's depth texture with compare mode on is undefined). */
static void gim__gl_nearest_sampler(gim_context *ctx) {
    const gim__gl *gl = &ctx->gl;
    if (ctx->nearest_sampler) return;
    gl->GenSamplers(1, &ctx->nearest_sampler);
    gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_MIN_FILTER, GIM__GL_NEAREST);
    gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_MAG_FILTER, GIM__GL_NEAREST);
    gl->SamplerParameteri(ctx->nearest_sampler, GIM__GL_TEXTURE_COMPARE_MODE, GIM__GL_NONE);
}

/* View samples (Bischoff 2017 sec. 4): the G-buffer at count Halton pixels (gim_view_sample_pixels,
   computed here and uploaded: the same pixels as the twin, bit for bit), unprojected. */
/* 1 when the frame's host G-buffer needs the decode pass (not gimany's own layout). */
static int gim__gbuffer_needs_decode(const gim_frame *f) {
    return f->gbuffer.depth && (f->gbuffer.normal_encoding != GIM_NORMAL_XYZ || f->gbuffer.view_space || f->gbuffer.depth_view_z);
}

/* The host's packed G-buffer into decoded_normal / decoded_depth (shaders/gbuffer_decode.comp;
   twin gim_gbuffer_decode_twin); *depth and *normal name them after. */
static gim_result gim__gl_gbuffer_decode(gim_context *ctx, const gim_frame *f, gim__GLuint *depth, gim__GLuint *normal) {
    static const char where[] = "G-buffer decode (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_mat4 r3 = gim_mat4_identity();
    int k;
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_GBUFFER_DECODE, &program);
    if (r != GIM_OK) return r;
    if (ctx->decoded_width != f->width || ctx->decoded_height != f->height || !ctx->decoded_normal) {
        gim__gl_texture(ctx, &ctx->decoded_normal, GIM__GL_RGBA16F, f->width, f->height);
        gim__gl_texture(ctx, &ctx->decoded_depth, GIM__GL_R32F, f->width, f->height);
        ctx->decoded_width = f->width;
        ctx->decoded_height = f->height;
    }
    for (k = 0; k < 3; ++k) {   /* view_to_world's 3x3, column k: row k of view's */
        r3.m[k * 4] = f->view.m[k];
        r3.m[k * 4 + 1] = f->view.m[4 + k];
        r3.m[k * 4 + 2] = f->view.m[8 + k];
    }
    gim__gl_nearest_sampler(ctx);
    gl->ActiveTexture(GIM__GL_TEXTURE0);
    gl->BindTexture(GIM__GL_TEXTURE_2D, *depth);
    gl->BindSampler(0, ctx->nearest_sampler);
    gl->ActiveTexture(GIM__GL_TEXTURE0 + 1);
    gl->BindTexture(GIM__GL_TEXTURE_2D, *normal);
    gl->BindSampler(1, ctx->nearest_sampler);
    gl->BindImageTexture(0, ctx->decoded_normal, 0, GIM__GL_FALSE, 0, GIM__GL_WRITE_ONLY, GIM__GL_RGBA16F);
    gl->BindImageTexture(1, ctx->decoded_depth, 0, GIM__GL_FALSE, 0, GIM__GL_WRITE_ONLY, GIM__GL_R32F);
    gl->UseProgram(program);
    gl->Uniform2ui(0, f->width, f->height);
    gl->Uniform1i(1, (gim__GLint)f->gbuffer.normal_encoding);
    gl->Uniform1i(2, f->gbuffer.view_space ? 1 : 0);
    gl->UniformMatrix4fv(3, 1, GIM__GL_FALSE, r3.m);
    gl->Uniform1i(7, f->gbuffer.depth_view_z ? 1 : 0);
    gl->Uniform4f(8, f->proj.m[10], f->proj.m[14], f->proj.m[11], f->proj.m[15]);
    gl->DispatchCompute((f->width + 7u) / 8u, (f->height + 7u) / 8u, 1u);
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    *depth = ctx->decoded_depth;
    *normal = ctx->decoded_normal;
    return gim__gl_check(ctx, where);
}

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
    off[0] = off[1] = 0.0f;
    if (f->lightskin.rotate_view_samples && f->lightskin.temporal_steps > 1u) {   /* frame 0's offsets, moving 1 / (count L) a frame */
        float o4[4];
        gim_drift_offsets(o4, 2u, 0u, f->frame_index, 1.0 / ((double)count * f->lightskin.temporal_steps));
        off[0] = o4[0];
        off[1] = o4[1];
    } else if (f->lightskin.rotate_view_samples) {
        gim_rotation_offsets(off, 2u, f->frame_index);
    }
    r = gim__gl_sized_buffer(ctx, &ctx->view_samples, &ctx->view_samples_bytes, (uint64_t)count * 32u, where);
    if (r != GIM_OK) return r;
    /* the pixels depend on these only: made and uploaded when one changes */
    if (!ctx->view_sample_pixels || ctx->view_sample_key[0] != count || ctx->view_sample_key[1] != f->width ||
        ctx->view_sample_key[2] != f->height || ctx->view_sample_off[0] != off[0] || ctx->view_sample_off[1] != off[1] ||
        ctx->view_sample_off[2] != (f->lightskin.rotate_view_samples ? 1.0f : 0.0f)) {
        pixels = (uint32_t *)gim__alloc_array(&ctx->env, count, 2u * sizeof(uint32_t));
        if (!pixels) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u view samples", (unsigned)count);
        gim_view_sample_pixels(count, f->width, f->height, f->lightskin.rotate_view_samples ? off : NULL, pixels);
        ctx->view_sample_key[0] = 0;
        r = gim__gl_sized_buffer(ctx, &ctx->view_sample_pixels, &ctx->view_sample_pixels_bytes, (uint64_t)count * 8u, where);
        if (r == GIM_OK) {
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->view_sample_pixels);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)count * 8, pixels);
            ctx->view_sample_key[0] = count;
            ctx->view_sample_key[1] = f->width;
            ctx->view_sample_key[2] = f->height;
            ctx->view_sample_off[0] = off[0];
            ctx->view_sample_off[1] = off[1];
            ctx->view_sample_off[2] = f->lightskin.rotate_view_samples ? 1.0f : 0.0f;
        }
        gim__free(&ctx->env, pixels);
        if (r != GIM_OK) return r;
    }
    gim__gl_nearest_sampler(ctx);
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

/* --- the LightSkin frame (Bischoff 2017 sec. 3-4) ------------------------------------------
   After the shared passes: caches to world space (CPU, gim_caches_to_world) sorted into a hash
   grid -> the lights' VALs -> proxy lights -> per pixel neighbours,
   interpolation and shading into the indirect texture. */

/* The indirect texture at width x height of format, made anew when either changes. */
static void gim__gl_indirect_texture(gim_context *ctx, uint32_t width, uint32_t height, gim__GLenum format) {
    if (ctx->indirect && ctx->indirect_width == width && ctx->indirect_height == height && ctx->indirect_format == format)
        return;
    gim__gl_texture(ctx, &ctx->indirect, format, width, height);
    ctx->indirect_width = width;
    ctx->indirect_height = height;
    ctx->indirect_format = format;
}

/* What the per-pixel passes (lightskin_shade.comp, rsm_gather.comp) share: the G-buffer on
   texture units 0-3 (albedo and material 0: the host's G-buffer, unit 2-3 get the normal,
   never read), the output image on unit 0, the program, and uniforms 0-3: size, the inverses
   of proj and view, the eye. */
static gim_result gim__gl_pixel_pass(gim_context *ctx, gim__GLuint program, gim__GLuint depth, gim__GLuint normal,
                                     gim__GLuint albedo, gim__GLuint material, uint32_t width, uint32_t height, gim_mat4 view,
                                     gim_mat4 proj, gim__GLuint output, gim__GLenum format, const char *where) {
    const gim__gl *gl = &ctx->gl;
    gim_mat4 inv_view, inv_proj;
    gim__GLuint tex[4];
    float eye[4];
    int i;
    if (!gim_mat4_invert(view, &inv_view) || !gim_mat4_invert(proj, &inv_proj))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj is singular");
    gim__camera_eye(view, proj, eye);
    gim__gl_nearest_sampler(ctx);
    tex[0] = depth; tex[1] = normal; tex[2] = albedo ? albedo : normal; tex[3] = material ? material : normal;
    for (i = 0; i < 4; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + (gim__GLenum)i);
        gl->BindTexture(GIM__GL_TEXTURE_2D, tex[i]);
        gl->BindSampler((gim__GLuint)i, ctx->nearest_sampler);
    }
    gl->BindImageTexture(0, output, 0, GIM__GL_FALSE, 0, GIM__GL_WRITE_ONLY, format);
    gl->UseProgram(program);
    gl->Uniform2ui(0, width, height);
    gl->UniformMatrix4fv(1, 1, GIM__GL_FALSE, inv_proj.m);
    gl->UniformMatrix4fv(2, 1, GIM__GL_FALSE, inv_view.m);
    gl->Uniform4f(3, eye[0], eye[1], eye[2], eye[3]);
    return GIM_OK;
}

#define GIM__NEIGHBOUR_RINGS 3   /* grid shells a pixel searches: neighbours within 3 cells */
#define GIM__SHADE_LIST_CAP 768u /* lightskin_shade.comp's LIST_CAP: caches in a tile's shared list */


/* Bucket of a cell before the mask; the shader's cell_hash, in the same uint arithmetic. */
static uint32_t gim__grid_hash(int32_t x, int32_t y, int32_t z) {
    return ((uint32_t)x * 73856093u) ^ ((uint32_t)y * 19349663u) ^ ((uint32_t)z * 83492791u);
}

/* Sort count > 0 world-space caches into a hash grid: *out (count, in bucket order), *cells
   (4 int32 per cache: its cell), *buckets (bucket_count + 1 starts), all allocated through env
   (the caller frees them, also on error). The cell side h is twice the caches' mean spacing,
   the square root of their mean area (the areas tile the surfaces, so each cache stands for
   about spacing^2): the n = 16 nearest of a cache on a plane lie within ~2.3 spacings, two
   shells. fallback_h serves caches of zero area; h grows where the bounds would need more
   than 2^20 cells per axis. Buckets are hashed, so memory is linear in the caches whatever
   the extent of the scene (an open world has most of its volume empty). */
static gim_result gim__grid_build(const gim_env *env, const gim_cache *in, uint32_t count, float fallback_h, gim__grid *g,
                                  gim_cache **out, int32_t **cells, uint32_t **buckets) {
    static const char where[] = "caches to world (grid)";
    double area = 0.0, ext = 0.0;
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    uint32_t i, t = 1, *key = NULL, *fill = NULL;
    int k;
    *out = NULL; *cells = NULL; *buckets = NULL;
    GIMANY_ASSERT(count > 0);
    while (t < 2u * count && t < 0x80000000u) t <<= 1;
    for (i = 0; i < count; ++i) {
        area += in[i].area;
        for (k = 0; k < 3; ++k) {
            if (in[i].position[k] < lo[k]) lo[k] = in[i].position[k];
            if (in[i].position[k] > hi[k]) hi[k] = in[i].position[k];
        }
    }
    for (k = 0; k < 3; ++k) if ((double)hi[k] - lo[k] > ext) ext = (double)hi[k] - lo[k];
    g->h = (float)(2.0 * sqrt(area / count));
    if (!(g->h > 0.0f) || !gim__isfinitef(g->h)) g->h = fallback_h;
    if ((double)g->h < ext / 1048576.0) g->h = (float)(ext / 1048576.0);
    for (k = 0; k < 3; ++k) {
        g->origin[k] = lo[k];
        g->dims[k] = (int32_t)floor(((double)hi[k] - lo[k]) / g->h) + 1;
        if (g->dims[k] > 1048577) g->dims[k] = 1048577;
    }
    g->bucket_count = t;
    *out = (gim_cache *)gim__alloc_array(env, count, sizeof(gim_cache));
    *cells = (int32_t *)gim__alloc_array(env, count, 4u * sizeof(int32_t));
    *buckets = (uint32_t *)gim__alloc_array(env, (size_t)t + 1u, sizeof(uint32_t));
    key = (uint32_t *)gim__alloc_array(env, count, sizeof(uint32_t));
    fill = (uint32_t *)gim__alloc_array(env, t, sizeof(uint32_t));
    if (!*out || !*cells || !*buckets || !key || !fill) {
        gim__free(env, key);
        gim__free(env, fill);
        return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "a grid of %u caches", (unsigned)count);
    }
    memset(*buckets, 0, ((size_t)t + 1u) * sizeof(uint32_t));
    for (i = 0; i < count; ++i) {
        int32_t c[3];
        for (k = 0; k < 3; ++k) {
            float f = (in[i].position[k] - g->origin[k]) / g->h;   /* float, as the shader */
            c[k] = (int32_t)floorf(f);
            if (c[k] < 0) c[k] = 0;
            if (c[k] > g->dims[k] - 1) c[k] = g->dims[k] - 1;
        }
        key[i] = gim__grid_hash(c[0], c[1], c[2]) & (t - 1u);
        ++(*buckets)[key[i] + 1u];
        (*cells)[i * 4u] = c[0]; (*cells)[i * 4u + 1u] = c[1]; (*cells)[i * 4u + 2u] = c[2];
        (*cells)[i * 4u + 3u] = (int32_t)i;   /* where the cache was before the sort */
    }
    for (i = 0; i < t; ++i) (*buckets)[i + 1u] += (*buckets)[i];
    memcpy(fill, *buckets, (size_t)t * sizeof(uint32_t));
    {   /* counting sort, stable: the caches of a bucket keep their order */
        int32_t *sorted_cells = (int32_t *)gim__alloc_array(env, count, 4u * sizeof(int32_t));
        if (!sorted_cells) {
            gim__free(env, key);
            gim__free(env, fill);
            return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, where, "a grid of %u caches", (unsigned)count);
        }
        for (i = 0; i < count; ++i) {
            uint32_t d = fill[key[i]]++;
            (*out)[d] = in[i];
            memcpy(sorted_cells + (size_t)d * 4u, *cells + (size_t)i * 4u, 4u * sizeof(int32_t));
        }
        gim__free(env, *cells);
        *cells = sorted_cells;
    }
    gim__free(env, key);
    gim__free(env, fill);
    return GIM_OK;
}

/* What the shading pass reads and writes. */
typedef struct gim__shade_args {
    gim__GLuint depth, normal;   /* the G-buffer (gimany's or the host's) */
    gim__GLuint albedo, material; /* gimany's G-buffer; both 0 with the host's: albedo 1, no glossy */
    uint32_t width, height;
    gim_mat4 view, proj;
    gim__GLuint caches, cells, buckets, diffuse, glossy; /* glossy 0: no glossy term */
    uint32_t cache_count;
    gim__grid grid;
    uint32_t n;                  /* neighbours, 1..GIM_MAX_NEIGHBOUR_CACHES */
    float cos_theta;             /* normal compatibility */
    float scene_scale;
    uint32_t list_limit;         /* caches a tile's shared list may hold; 0: GIM__SHADE_LIST_CAP (tests
                                    set fewer to send tiles to the per pixel search) */
    int neighbours_out;          /* tests: write each pixel's (d_cmax, count, sum of indices) instead */
    uint32_t block;              /* B of gim_frame_lightskin.shade_block: 1 or 2 (0: 1) */
    uint32_t slabs;              /* a tile's list in slabs where its box is long (0); tests: 1 in slabs, 2 in rings
                                    in every tile */
    gim__GLuint bvh;             /* neighbour_rays: the hierarchy (gim__gl_bvh's layout), or 0: no rays */
    uint32_t bvh_nodes;          /* its nodes (0: nothing blocks) */
    float bvh_origin[3], bvh_scale;  /* its frame (gim_bvh.origin, scale) */
    gim__GLuint indirect;        /* width x height texture of format */
    gim__GLenum format;          /* RGBA16F or RGBA32F */
} gim__shade_args;

/* Per pixel neighbours (the n nearest compatible caches within GIM__NEIGHBOUR_RINGS h),
   interpolation (eq. 8-9) and shading: the twin is gim_cache_neighbours (max_distance =
   rings h) then gim_lightskin_shade_twin, on receivers unprojected from the G-buffer (see
   lightskin_shade.comp), in B x B blocks (gim_shade_sources). One work group per 8B x 8B tile
   gathers the caches its pixels could take into shared memory once, then each block's first
   receiver picks its n nearest from that list (the same choice as a search per pixel, which a
   tile whose list overflows does instead), and the block's pixels off its surface search for
   themselves. Cost: tiles x cells of the tile's box grown by the radius, + searches x (the
   part of the tile's list in the rings or slabs a search visits + 2 n), searches = the blocks
   + the pixels that do not share; with a->bvh (neighbour_rays) each search's n neighbours are
   then tested by rays (gim_neighbour_rays_twin after gim_cache_neighbours): + searches x n rays. */
static gim_result gim__gl_lightskin_shade(gim_context *ctx, const gim__shade_args *a) {
    static const char where[] = "LightSkin shading (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    int host = a->albedo == 0;
    uint32_t block = a->block == 2u ? 2u : 1u;
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_LIGHTSKIN_SHADE, &program);
    if (r != GIM_OK) return r;
    if (!host && ctx->material_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no materials");
    r = gim__gl_pixel_pass(ctx, program, a->depth, a->normal, a->albedo, a->material, a->width, a->height, a->view, a->proj,
                           a->indirect, a->format, where);
    if (r != GIM_OK) return r;
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, a->caches);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, a->diffuse);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, a->glossy ? a->glossy : a->diffuse); /* never read then */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, a->buckets);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, a->cells);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 5, host ? a->caches : ctx->materials);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 6, a->bvh ? a->bvh : a->caches);   /* never read without rays */
    gl->Uniform1ui(4, a->n);
    gl->Uniform1f(5, a->cos_theta);
    gl->Uniform4f(6, a->grid.origin[0], a->grid.origin[1], a->grid.origin[2], a->grid.h);
    gl->Uniform3i(7, a->grid.dims[0], a->grid.dims[1], a->grid.dims[2]);
    gl->Uniform1ui(8, a->grid.bucket_count - 1u);
    gl->Uniform1i(9, GIM__NEIGHBOUR_RINGS);
    gl->Uniform1f(10, GIM__TWINS_COINCIDENT * a->scene_scale);
    gl->Uniform1ui(11, (a->glossy && !host ? 1u : 0u) | (host ? 2u : 0u) | (a->neighbours_out ? 4u : 0u) |
                           (a->bvh ? 8u : 0u));
    gl->Uniform1ui(12, host ? 1u : ctx->material_count);
    gl->Uniform1f(13, a->format == GIM__GL_RGBA16F ? 65504.0f : FLT_MAX);
    gl->Uniform1ui(14, a->list_limit && a->list_limit < GIM__SHADE_LIST_CAP ? a->list_limit : GIM__SHADE_LIST_CAP);
    gl->Uniform1ui(15, block);
    gl->Uniform1ui(16, a->slabs <= 2u ? a->slabs : 0u);
    gl->Uniform1ui(17, a->bvh ? a->bvh_nodes : 0u);
    gl->Uniform1ui(18, a->bvh_nodes * 2u);
    gl->Uniform1f(19, GIM_NEIGHBOUR_RAY_LIFT * a->scene_scale);
    gl->Uniform3f(20, a->bvh_origin[0], a->bvh_origin[1], a->bvh_origin[2]);
    gl->Uniform1f(21, a->bvh ? a->bvh_scale : 1.0f);
    gl->DispatchCompute((a->width + 8u * block - 1u) / (8u * block), (a->height + 8u * block - 1u) / (8u * block), 1u);
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GIM__GL_TEXTURE_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* timing 2's clock in ms (gim_stats.cpu_clock): POSIX's monotonic clock where <time.h> declares
   it (_POSIX_C_SOURCE >= 199309L before the first system header), else the GL's own clock read
   at once; after a glFinish either is the time the work so far took. */
#ifdef CLOCK_MONOTONIC
#define GIM__CPU_CLOCK 1
static double gim__clock_ms(gim_context *ctx) {
    struct timespec t;
    (void)ctx;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}
#else
#define GIM__CPU_CLOCK 2
static double gim__clock_ms(gim_context *ctx) {
    gim__GLint64 t = 0;
    ctx->gl.GetInteger64v(GIM__GL_TIMESTAMP, &t);
    return (double)t * 1e-6;
}
#endif

/* A stamp after pass (GIM_PASS_COUNT: the frame's start), when the frame is timed: a GL
   timestamp (timing 1), or glFinish and the clock (timing 2: llvmpipe runs queued work at the
   next flush, so its timestamps charge a pass's work to a later one). */
static void gim__stamp(gim_context *ctx, int timed, gim_pass pass) {
    if (!timed) return;
    /* a stamp after one of the same pass replaces it: the two intervals charged to the pass are
       one, so a pass run once per light costs one stamp whatever the light count */
    if (ctx->stamp_count > 1 && ctx->stamp_pass[ctx->stamp_count - 1] == (unsigned char)pass) --ctx->stamp_count;
    if (ctx->stamp_count >= GIM__MAX_STAMPS) return;
    if (timed == 2) {
        ctx->gl.Finish();
        ctx->stamp_ms[ctx->stamp_count] = gim__clock_ms(ctx);
    } else {
        if (ctx->query_count == 0) {
            ctx->gl.GenQueries(GIM__MAX_STAMPS, ctx->queries);
            ctx->query_count = GIM__MAX_STAMPS;
        }
        ctx->gl.QueryCounter(ctx->queries[ctx->stamp_count], GIM__GL_TIMESTAMP);
    }
    ctx->stamp_pass[ctx->stamp_count++] = (unsigned char)pass;
}

/* The ISM buffers: visibility off costs no memory. */
/* The layered targets of the VPLs' triangle shadow maps (gim__gl_vpl_shadow_maps) ... */
static void gim__vsm_targets_release(gim_context *ctx) {
    gim__GLuint t[2];
    t[0] = ctx->vsm_distance; t[1] = ctx->vsm_depth;
    if (t[0] || t[1]) ctx->gl.DeleteTextures(2, t);
    if (ctx->vsm_fbo) ctx->gl.DeleteFramebuffers(1, &ctx->vsm_fbo);
    ctx->vsm_distance = ctx->vsm_depth = ctx->vsm_fbo = 0;
    ctx->vsm_size = ctx->vsm_layers = 0;
}

/* ... and with them the list of the maps to make. */
static void gim__vsm_release(gim_context *ctx) {
    gim__vsm_targets_release(ctx);
    if (ctx->vsm_list) ctx->gl.DeleteBuffers(1, &ctx->vsm_list);
    ctx->vsm_list = 0;
    ctx->vsm_list_bytes = 0;
}

static void gim__ism_release(gim_context *ctx) {
    gim__GLuint b[3];
    b[0] = ctx->ism_maps; b[1] = ctx->ism_points; b[2] = ctx->ism_cluster_maps;
    if (b[0] || b[1] || b[2]) ctx->gl.DeleteBuffers(3, b);
    ctx->ism_maps = ctx->ism_points = ctx->ism_cluster_maps = 0;
    ctx->ism_maps_bytes = ctx->ism_points_bytes = ctx->ism_cluster_maps_bytes = 0;
    ctx->ism_size = ctx->ism_per_map = ctx->ism_point_count = 0;
    ctx->ism_version = 0;
    ctx->ism_vpl_key = 0;
    ctx->ism_vpl_layout = 0;
    gim__vsm_release(ctx);
}

static gim_result gim__gl_upload(gim_context *ctx, gim__GLuint *b, uint64_t *have, const void *data, uint64_t bytes,
                                 const char *where);

/* Every instance's world triangles (9 floats each: gim_twin_scene.positions), read back from
   the meshes' buffers into *positions (allocated through ctx->env, the caller frees it), their
   count in *count: the points of the ISMs and the hierarchy of neighbour_rays are made from
   them when the scene changes. */
static gim_result gim__gl_world_triangles(gim_context *ctx, float **positions, uint32_t *count, const char *where) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i, tris = 0, t;
    float *pos;
    *positions = NULL;
    *count = 0;
    for (i = 0; i < ctx->instance_count; ++i) tris += gim__mesh_get(ctx, ctx->instances[i].mesh)->triangle_count;
    pos = (float *)gim__alloc_array(&ctx->env, (size_t)tris * 9u, sizeof(float));
    if (!pos && tris) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "a copy of %u triangles", (unsigned)tris);
    for (i = 0, t = 0; i < ctx->instance_count; ++i) {
        const gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        gim__GLint64 vbytes = 0;
        size_t ibytes = (size_t)m->index_count * (m->index_type == GIM__GL_UNSIGNED_SHORT ? 2u : 4u), k;
        float *v;
        void *idx;
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, m->positions);
        gl->GetBufferParameteri64v(GIM__GL_COPY_READ_BUFFER, GIM__GL_BUFFER_SIZE, &vbytes);
        vbytes -= (gim__GLint64)m->position_offset;   /* a host's buffer: the mesh from its offset on */
        v = (float *)gim__alloc_array(&ctx->env, (size_t)vbytes / 4u + 1u, sizeof(float));
        idx = gim__alloc_array(&ctx->env, ibytes + 4u, 1u);
        if (!v || !idx) {
            gim__free(&ctx->env, v); gim__free(&ctx->env, idx); gim__free(&ctx->env, pos);
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "a mesh's copy");
        }
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, (gim__GLintptr)m->position_offset, (gim__GLsizeiptr)vbytes, v);
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, m->indices);
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, (gim__GLintptr)m->index_offset, (gim__GLsizeiptr)ibytes, idx);
        for (k = 0; k < (size_t)m->triangle_count * 3u; ++k) {
            uint32_t vi = m->index_type == GIM__GL_UNSIGNED_SHORT ? ((const uint16_t *)idx)[k] : ((const uint32_t *)idx)[k];
            const float *vp = v + (size_t)vi * (m->position_stride / 4u);
            gim_vec3 w = gim_mat4_point(ctx->instances[i].model, gim_v3(vp[0], vp[1], vp[2]));
            pos[(size_t)t * 9u + k * 3u] = w.x; pos[(size_t)t * 9u + k * 3u + 1u] = w.y; pos[(size_t)t * 9u + k * 3u + 2u] = w.z;
        }
        t += m->triangle_count;
        gim__free(&ctx->env, v);
        gim__free(&ctx->env, idx);
    }
    *positions = pos;
    *count = tris;
    return GIM_OK;
}

/* The scene's ISM points (gim_ism_points over every instance's world triangles), uploaded to
   ctx->ism_points; count of them in *count. */
static gim_result gim__gl_ism_scene_points(gim_context *ctx, uint32_t count, const char *where) {
    uint32_t tris;
    float *pos, *alb, *pts;
    gim_twin_scene sc;
    gim_result r = gim__gl_world_triangles(ctx, &pos, &tris, where);
    if (r != GIM_OK) return r;
    alb = (float *)gim__alloc_array(&ctx->env, (size_t)tris * 3u, sizeof(float));
    pts = (float *)gim__alloc_array(&ctx->env, (size_t)count * 8u, sizeof(float));
    if (!alb || !pts) {
        gim__free(&ctx->env, pos); gim__free(&ctx->env, alb); gim__free(&ctx->env, pts);
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "ISM points of %u triangles", (unsigned)tris);
    }
    memset(alb, 0, (size_t)tris * 3u * sizeof(float));
    sc.positions = pos; sc.normals = NULL; sc.albedo = alb; sc.triangle_count = tris;
    r = gim_ism_points(&sc, count, pts);
    if (r == GIM_OK) r = gim__gl_upload(ctx, &ctx->ism_points, &ctx->ism_points_bytes, pts, (uint64_t)count * 32u, where);
    gim__free(&ctx->env, pos); gim__free(&ctx->env, alb); gim__free(&ctx->env, pts);
    return r;
}

/* Every instance's world triangles' material ids, in gim__gl_world_triangles' order, read back
   from the meshes' triangle_material buffers into *ids (allocated through ctx->env; count of
   them: that function's). */
static gim_result gim__gl_world_materials(gim_context *ctx, uint32_t **ids, const char *where) {
    const gim__gl *gl = &ctx->gl;
    uint32_t i, tris = 0, t = 0;
    uint32_t *out;
    *ids = NULL;
    for (i = 0; i < ctx->instance_count; ++i) tris += gim__mesh_get(ctx, ctx->instances[i].mesh)->triangle_count;
    out = (uint32_t *)gim__alloc_array(&ctx->env, (size_t)tris + 1u, sizeof(uint32_t));
    if (!out) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "the materials of %u triangles", (unsigned)tris);
    for (i = 0; i < ctx->instance_count; ++i) {
        const gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, m->triangle_material);
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, (gim__GLsizeiptr)m->triangle_count * 4, out + t);
        t += m->triangle_count;
    }
    *ids = out;
    return GIM_OK;
}

/* The rays' hierarchy of the scene's world triangles (gim_bvh_build), in one buffer: the nodes
   (32 bytes each), then the triangles (48 bytes each, the first vec4's w the triangle's
   material id instead of its scene index: the second bounce's albedo); made again when the
   scene changes (scene_version), not per frame. */
static gim_result gim__gl_bvh(gim_context *ctx, const char *where) {
    uint32_t tris, *ids = NULL, k;
    float *pos;
    gim_twin_scene sc;
    gim_bvh bvh;
    gim_result r;
    r = gim__gl_world_triangles(ctx, &pos, &tris, where);
    if (r != GIM_OK) return r;
    memset(&sc, 0, sizeof sc);
    sc.positions = pos;
    sc.triangle_count = tris;
    r = gim_bvh_build(&sc, ctx->env, &bvh);
    gim__free(&ctx->env, pos);
    if (r != GIM_OK) return r;
    r = gim__gl_world_materials(ctx, &ids, where);
    for (k = 0; r == GIM_OK && k < bvh.triangle_count; ++k) {
        uint32_t at;
        memcpy(&at, bvh.triangles + (size_t)k * 12u + 3u, sizeof at);
        memcpy(bvh.triangles + (size_t)k * 12u + 3u, ids + at, sizeof at);
    }
    gim__free(&ctx->env, ids);
    if (r != GIM_OK) {
        gim_bvh_free(&bvh);
        return r;
    }
    {
        uint64_t nb = (uint64_t)bvh.node_count * 32u, tb = (uint64_t)bvh.triangle_count * 48u;
        r = gim__gl_upload(ctx, &ctx->bvh.buffer, &ctx->bvh.bytes, NULL, nb + tb > 0u ? nb + tb : 32u, where);
        if (r == GIM_OK && nb) {
            ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->bvh.buffer);
            ctx->gl.BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)nb, bvh.nodes);
            ctx->gl.BufferSubData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLintptr)nb, (gim__GLsizeiptr)tb, bvh.triangles);
        }
    }
    if (r == GIM_OK) {
        ctx->bvh.nodes = bvh.node_count;
        memcpy(ctx->bvh.origin, bvh.origin, sizeof ctx->bvh.origin);
        ctx->bvh.scale = bvh.scale;
        ctx->bvh.version = ctx->scene_version;
    }
    gim_bvh_free(&bvh);
    return r;
}

/* The scene's hierarchy (a frame without rays keeps none). */
static void gim__bvh_release(gim_context *ctx) {
    if (ctx->bvh.buffer) ctx->gl.DeleteBuffers(1, &ctx->bvh.buffer);
    memset(&ctx->bvh, 0, sizeof ctx->bvh);
}

/* The LightSkin buffers, the proxy pass's sums and the caches' materials (a frame of another
   method keeps none). */
static void gim__lightskin_drop(gim_context *ctx) {
    gim__lightskin_gpu *ls = &ctx->ls;
    gim__GLuint b[8];
    b[0] = ls->caches; b[1] = ls->cells; b[2] = ls->buckets; b[3] = ls->vals; b[4] = ls->diffuse; b[5] = ls->glossy;
    b[6] = ls->exponents; b[7] = ctx->proxy_state;
    ctx->gl.DeleteBuffers(8, b);
    gim__free(&ctx->env, ls->material);
    memset(ls, 0, sizeof *ls);
    ctx->proxy_state = 0;
    ctx->proxy_state_bytes = 0;
}

/* ... and the indirect texture (a LightSkin frame with nothing to light). */
static void gim__lightskin_release(gim_context *ctx) {
    gim__lightskin_drop(ctx);
    if (ctx->indirect) ctx->gl.DeleteTextures(1, &ctx->indirect);
    ctx->indirect = 0;
    ctx->indirect_width = ctx->indirect_height = 0;
}

/* Upload bytes into a buffer sized by gim__gl_sized_buffer. */
static gim_result gim__gl_upload(gim_context *ctx, gim__GLuint *b, uint64_t *have, const void *data, uint64_t bytes,
                                 const char *where) {
    gim_result r;
    if (bytes > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%llu bytes exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE",
                         (unsigned long long)bytes);
    r = gim__gl_sized_buffer(ctx, b, have, bytes, where);
    if (r != GIM_OK) return r;
    if (data) {
        ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, *b);
        ctx->gl.BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)bytes, data);
    }
    return GIM_OK;
}

/* The LightSkin passes of gim_update (see there); fills the LightSkin part of o and dbg. */
static gim_result gim__gl_lightskin(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                    float scale, gim_frame_outputs *o, gim_debug_outputs *dbg) {
    static const char where[] = "gim_update (LightSkin)";
    gim__lightskin_gpu *ls = &ctx->ls;
    gim_cache *world = NULL, *sorted = NULL;
    int32_t *cells = NULL;
    uint32_t *buckets = NULL;
    uint32_t i, total = 0, off = 0, vals_total = 0, n;
    double theta = 0.0;
    float k_glossy, eye[4];
    gim__grid grid;
    gim__shade_args sa;
    gim__gl_ism ism;
    gim__GLenum format = f->indirect_float32 ? GIM__GL_RGBA32F : GIM__GL_RGBA16F;
    gim_result r = GIM_OK;
    int glossy = 0, rays;
    for (i = 0; i < ctx->instance_count; ++i) total += gim__mesh_get(ctx, ctx->instances[i].mesh)->cache_count;
    if (total == 0 || ctx->light_count == 0) { /* nothing to light with: no passes, no buffers */
        gim__lightskin_release(ctx);
        gim__ism_release(ctx);
        return GIM_OK;
    }
    n = f->lightskin.neighbour_count;
    if (ls->caches && ctx->ls_version == ctx->scene_version && ctx->ls_scale == scale) {
        grid = ctx->ls_grid;   /* nothing moved: the world caches and their grid stand */
        goto vals;
    }
    /* caches to world space (and their materials), the compatibility angle (2 theta_eps of the
       sets, at most 90 degrees) */
    world = (gim_cache *)gim__alloc_array(&ctx->env, total, sizeof(gim_cache));
    gim__free(&ctx->env, ls->material);
    ls->material = (uint32_t *)gim__alloc_array(&ctx->env, total, sizeof(uint32_t));
    ls->exponents_for = 0;
    if (!world || !ls->material) {
        gim__free(&ctx->env, world);
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u caches", (unsigned)total);
    }
    for (i = 0; i < ctx->instance_count && r == GIM_OK; ++i) {
        const gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        double t = 2.0 * (m->theta_eps > 0.0f ? m->theta_eps : 0.52359877559829887);
        uint32_t j;
        if (!m->cache_count) continue;
        /* a deforming mesh's caches as they followed its triangles this frame (gim__deform_prepare) */
        r = gim_caches_to_world(m->deforming && m->follow_cpu ? m->follow_cpu : m->caches, m->cache_count,
                                ctx->instances[i].model, world + off, ctx->env);
        for (j = 0; j < m->cache_count; ++j) ls->material[off + j] = m->cache_material ? m->cache_material[j] : 0u;
        off += m->cache_count;
        if (t > theta) theta = t;
    }
    if (theta > 1.5707963267948966) theta = 1.5707963267948966;
    if (r == GIM_OK) r = gim__grid_build(&ctx->env, world, total, scale / 32.0f, &grid, &sorted, &cells, &buckets);
    if (r == GIM_OK) {   /* the materials in the grid's order: cell w is each cache's index before the sort */
        uint32_t *unsorted = ls->material;
        ls->material = (uint32_t *)gim__alloc_array(&ctx->env, total, sizeof(uint32_t));
        if (!ls->material) r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u caches", (unsigned)total);
        for (i = 0; r == GIM_OK && i < total; ++i) ls->material[i] = unsorted[cells[i * 4u + 3u]];
        gim__free(&ctx->env, unsorted);
    }
    if (r == GIM_OK) r = gim__gl_upload(ctx, &ls->caches, &ls->caches_bytes, sorted, (uint64_t)total * 32u, where);
    if (r == GIM_OK) r = gim__gl_upload(ctx, &ls->cells, &ls->cells_bytes, cells, (uint64_t)total * 16u, where);
    if (r == GIM_OK)
        r = gim__gl_upload(ctx, &ls->buckets, &ls->buckets_bytes, buckets, ((uint64_t)grid.bucket_count + 1u) * 4u, where);
    gim__free(&ctx->env, world);
    gim__free(&ctx->env, sorted);
    gim__free(&ctx->env, cells);
    gim__free(&ctx->env, buckets);
    if (r != GIM_OK) {
        ctx->ls_version = ctx->scene_version - 1u;   /* made again next frame */
        return r;
    }
    ctx->ls_version = ctx->scene_version;
    ctx->ls_scale = scale;
    ctx->ls_grid = grid;
    ctx->ls_cos_theta = (float)cos(theta);
vals:
    gim__stamp(ctx, f->timing, GIM_PASS_CACHES);
    /* the VALs of every light, one after the other */
    vals_total = 0;
    for (i = 0; i < ctx->light_count; ++i) {
        uint64_t c = !ctx->light_on[i]                       ? 0u
                     : f->method == GIM_METHOD_LIGHTSKIN_FULL ? (uint64_t)ctx->light_gpu[i].size * ctx->light_gpu[i].size
                                                              : (uint64_t)ctx->light_vals[i];
        if ((uint64_t)vals_total + c > 0xFFFFFFFFu / 48u)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "too many VALs");
        vals_total += (uint32_t)c;
    }
    if (vals_total == 0) {   /* no light reaches a view sample: one zero VAL, so the passes make the (black) image */
        static const float zero_val[12] = {0.0f};
        r = gim__gl_upload(ctx, &ls->vals, &ls->vals_bytes, zero_val, sizeof zero_val, where);
        vals_total = 1;
    } else {
        r = gim__gl_upload(ctx, &ls->vals, &ls->vals_bytes, NULL, (uint64_t)vals_total * 48u, where);
    }
    for (i = 0, off = 0; i < ctx->light_count && r == GIM_OK; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        int full = f->method == GIM_METHOD_LIGHTSKIN_FULL;
        if (!ctx->light_on[i] || (!full && !ctx->light_vals[i])) continue;
        r = gim__gl_vals_gather(ctx, g->position, g->normal, g->flux, g->size, full ? 0u : g->selected,
                                full ? 0u : ctx->light_vals[i], ls->vals, off);
        off += full ? g->size * g->size : ctx->light_vals[i];
    }
    if (r != GIM_OK) return r;
    gim__stamp(ctx, f->timing, GIM_PASS_VALS);
    /* glossy proxy lights only when a material has a glossy colour, each cache with the lobe of
       its own material (made again when the caches or the materials change) */
    k_glossy = ctx->glossy_min_exponent;
    glossy = ctx->glossy_material_count > 0;
    r = gim__gl_upload(ctx, &ls->diffuse, &ls->diffuse_bytes, NULL, (uint64_t)total * 48u, where);
    if (r == GIM_OK && glossy) r = gim__gl_upload(ctx, &ls->glossy, &ls->glossy_bytes, NULL, (uint64_t)total * 48u, where);
    if (r == GIM_OK && glossy && ls->exponents_for != ctx->materials_version) {
        float *k = (float *)gim__alloc_array(&ctx->env, total, sizeof(float));
        if (!k) return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u cache exponents", (unsigned)total);
        for (i = 0; i < total; ++i) {
            float e = ls->material[i] < ctx->material_count ? ctx->material_exponent[ls->material[i]] : 0.0f;
            k[i] = e < GIM__TWINS_MAX_EXPONENT ? e : GIM__TWINS_MAX_EXPONENT;
        }
        r = gim__gl_upload(ctx, &ls->exponents, &ls->exponents_bytes, k, (uint64_t)total * 4u, where);
        gim__free(&ctx->env, k);
        if (r == GIM_OK) ls->exponents_for = ctx->materials_version;
    }
    if (r == GIM_OK && !glossy && ls->glossy) {
        gim__GLuint b[2];
        b[0] = ls->glossy; b[1] = ls->exponents;
        ctx->gl.DeleteBuffers(ls->exponents ? 2 : 1, b);
        ls->glossy = ls->exponents = 0;
        ls->glossy_bytes = ls->exponents_bytes = 0;
        ls->exponents_for = 0;
    }
    if (r != GIM_OK) return r;
    gim__camera_eye(f->view, f->proj, eye);
    if (eye[3] == 0.0f) { /* orthographic: a point far along the direction to the eye */
        float c[3];
        int k;
        for (k = 0; k < 3; ++k) c[k] = 0.5f * (o->bounds_min[k] + o->bounds_max[k]) + eye[k] * 1e4f * scale;
        eye[0] = c[0]; eye[1] = c[1]; eye[2] = c[2];
    }
    memset(&ism, 0, sizeof ism);
    if (f->visibility.mode == GIM_VISIBILITY_ISM) {
        /* the caches' maps, made again only when the scene (mesh, instance) or a setting changed */
        uint32_t size = f->visibility.ism_size;   /* resolved: halved to fit the caches' maps (gim__frame_resolve_scene) */
        uint32_t per = f->visibility.ism_points;
        uint32_t pool = gim__ism_pool(per);
        if (!ctx->ism_maps || ctx->ism_version != ctx->scene_version || ctx->ism_size != size || ctx->ism_per_map != per ||
            ctx->ism_scale != scale || ctx->ism_point_count != pool) {
            ctx->ism_version = ctx->scene_version - 1u;
            r = gim__gl_ism_scene_points(ctx, pool, where);
            if (r == GIM_OK)
                r = gim__gl_sized_buffer(ctx, &ctx->ism_maps, &ctx->ism_maps_bytes, (uint64_t)total * size * size * 2u,
                                         where);   /* may exceed one storage block: the passes bind ranges */
            ctx->ism_vpl_key = 0;   /* the caches' maps take the buffer */
            ctx->ism_vpl_layout = 0;
            if (r == GIM_OK) r = gim__gl_ism_render(ctx, ls->caches, total, ctx->ism_points, pool, size, per, scale, ctx->ism_maps);
            if (r != GIM_OK) return r;
            ctx->ism_version = ctx->scene_version;
            ctx->ism_size = size; ctx->ism_per_map = per; ctx->ism_scale = scale; ctx->ism_point_count = pool;
            gim__stamp(ctx, f->timing, GIM_PASS_ISM);
        }
        ism.maps = ctx->ism_maps;
        ism.size = size;   /* the lookups' time is the proxy lights' (GIM_PASS_PROXY_LIGHTS) */
    } else if (ctx->ism_maps || ctx->ism_points) {
        gim__ism_release(ctx);
    }
    rays = f->visibility.neighbour_rays || f->visibility.mode == GIM_VISIBILITY_RAYS;
    if (rays && (!ctx->bvh.buffer || ctx->bvh.version != ctx->scene_version)) {
        r = gim__gl_bvh(ctx, where);   /* the rays' hierarchy: made again only when the scene changed */
        if (r != GIM_OK) return r;
        gim__stamp(ctx, f->timing, GIM_PASS_ISM);
    } else if (!rays && ctx->bvh.buffer) {   /* off: no buffer */
        gim__bvh_release(ctx);
    }
    if (f->visibility.mode == GIM_VISIBILITY_RAYS) {   /* each VAL at each cache by a ray */
        ism.bvh = ctx->bvh.buffer;
        ism.bvh_nodes = ctx->bvh.nodes;
        memcpy(ism.bvh_origin, ctx->bvh.origin, sizeof ism.bvh_origin);
        ism.bvh_scale = ctx->bvh.scale;
    }
    r = gim__gl_proxy_lights_ism(ctx, ls->caches, total, ls->vals, vals_total, gim_v3(eye[0], eye[1], eye[2]), k_glossy,
                                 glossy ? ls->exponents : 0u, scale, ls->diffuse, glossy ? ls->glossy : 0u, &ism);
    if (r != GIM_OK) return r;
    gim__stamp(ctx, f->timing, GIM_PASS_PROXY_LIGHTS);
    /* the indirect texture, (re)made when its size or format changes */
    gim__gl_indirect_texture(ctx, f->width, f->height, format);
    memset(&sa, 0, sizeof sa);
    sa.depth = depth;
    sa.normal = normal;
    sa.albedo = f->gbuffer.depth ? 0u : ctx->gbuffer_albedo;
    sa.material = f->gbuffer.depth ? 0u : ctx->gbuffer_material;
    sa.width = f->width;
    sa.height = f->height;
    sa.view = f->view;
    sa.proj = f->proj;
    sa.caches = ls->caches; sa.cells = ls->cells; sa.buckets = ls->buckets;
    sa.diffuse = ls->diffuse; sa.glossy = glossy ? ls->glossy : 0u;
    sa.cache_count = total;
    sa.grid = grid;
    sa.n = n;
    sa.cos_theta = ctx->ls_cos_theta;
    sa.scene_scale = scale;
    sa.indirect = ctx->indirect;
    sa.format = format;
    sa.block = f->lightskin.shade_block;
    sa.bvh = f->visibility.neighbour_rays ? ctx->bvh.buffer : 0u;
    sa.bvh_nodes = ctx->bvh.nodes;
    memcpy(sa.bvh_origin, ctx->bvh.origin, sizeof sa.bvh_origin);
    sa.bvh_scale = ctx->bvh.scale;
    r = gim__gl_lightskin_shade(ctx, &sa);
    if (r != GIM_OK) return r;
    gim__stamp(ctx, f->timing, GIM_PASS_SHADE);
    o->indirect = ctx->indirect;
    dbg->caches = ls->caches;
    dbg->cache_count = total;
    dbg->vals = ls->vals;
    dbg->val_count = vals_total;
    dbg->proxy_diffuse = ls->diffuse;
    dbg->proxy_glossy = glossy ? ls->glossy : 0u;
    dbg->glossy_exponent = glossy ? k_glossy : 0.0f;
    dbg->cache_exponents = glossy ? ls->exponents : 0u;
    dbg->neighbour_count = n;
    dbg->neighbour_cos = sa.cos_theta;
    dbg->neighbour_radius = (float)GIM__NEIGHBOUR_RINGS * grid.h;
    dbg->neighbour_cell = grid.h;
    dbg->shade_block = sa.block;
    dbg->ism_maps = ism.maps;
    dbg->ism_size = ism.maps ? ism.size : 0u;
    return GIM_OK;
}

/* --- VPL shading: clustered visibility and SSVP ------------------------------------------- */

/* Subset members per VPL-shading dispatch: each costs an invocation up to 1 + 2 x 16 loop
   iterations (the two visibility kernels) plus the subset scramble's cycle walk (5 a step,
   under 4 steps expected), a near one as much again plus the octagon's 32, and llvmpipe stops
   an invocation's loops after 65535 in all; 512 stays near 60k even with every member near
   and a 10-step walk. */
#define GIM__VPL_SHADE_CHUNK 512u

/* What the VPL shading pass reads and writes. */
typedef struct gim__vpl_shade_args {
    gim__GLuint depth, normal;     /* the G-buffer (gimany's or the host's) */
    gim__GLuint albedo, material;  /* gimany's G-buffer; both 0 with the host's: albedo 1, no glossy */
    uint32_t width, height;
    gim_mat4 view, proj;
    gim__GLuint vpls;              /* SSBO: vpl_count gim_vpl (48 bytes) */
    uint32_t vpl_count;            /* N; 0 lights nothing */
    gim__GLuint cluster;           /* SSBO: a uint map index per VPL (>= map_count, e.g. UINT32_MAX: unshadowed),
                                      or 0: no visibility */
    gim__GLuint maps;              /* SSBO: map_count gim_paraboloid (48 bytes) */
    uint32_t map_count;
    gim__GLuint distance;          /* R32F 2D array texture, map_size^2 x map_count (layer m: map m), or 0: no visibility */
    uint32_t map_size;
    gim__GLuint ism;               /* SSBO: VPL i's ISM (gim_vpl_shade_desc.ism: 16-bit texels), or 0. Without
                                      cluster every VPL's (vpl_count maps); with cluster those of the VPLs
                                      i >= ism_first that have none, map i - ism_first (vpl_count - ism_first
                                      maps; SSVP's second bounce beside the clusters' paraboloid maps) */
    uint32_t ism_first;            /* with cluster and ism: the first VPL with a map; else 0 */
    uint32_t ism_size;
    float ism_bias, ism_slope;     /* as gim_vpl_shade_desc's; 0: GIM_ISM_BIAS, GIM_ISM_SLOPE */
    uint32_t interleave;           /* k (gim_vpl_shade_desc); 0 or 1: every VPL */
    float clamp_distance;          /* d_c, >= 0 */
    float scene_scale;             /* > 0 */
    gim__GLuint output;            /* width x height texture of format */
    gim__GLenum format;            /* RGBA16F or RGBA32F */
} gim__vpl_shade_args;

/* VPL shading per pixel into a->output (twin: gim_vpl_shade_twin on the receivers unprojected from
   the G-buffer, as in lightskin_shade.comp); in dispatches of ctx->vpl_chunk members of each
   pixel's interleaved subset, the running sums in ctx->vpl_partial between them. */
static GIM__UNUSED gim_result gim__gl_vpl_shade(gim_context *ctx, const gim__vpl_shade_args *a) {
    static const char where[] = "VPL shading (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    int host = a->albedo == 0, vis = a->cluster != 0 && a->distance != 0, ism = a->ism != 0;
    uint32_t k = a->interleave > 1u ? a->interleave : 1u, members, chunk, first;
    gim_result r;
    if (a->width == 0 || a->height == 0 || !a->depth || !a->normal || !a->output)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no G-buffer or output");
    if (a->interleave > GIM__VPL_MAX_INTERLEAVE)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "interleave %u exceeds %u", a->interleave,
                         GIM__VPL_MAX_INTERLEAVE);
    if (a->vpl_count > 0 && !a->vpls) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no VPL buffer");
    if (vis && (!a->maps || a->map_count == 0 || a->map_size == 0))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "visibility needs maps, map_count and map_size");
    if (ism && (a->ism_size < GIM_ISM_MIN_SIZE || a->ism_size > GIM_ISM_MAX_SIZE || (a->ism_size & (a->ism_size - 1u))))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ISM size %u not a power of two in %u..%u",
                         (unsigned)a->ism_size, GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
    if (a->ism_first > 0u && (!ism || !vis || a->ism_first >= a->vpl_count))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ism_first %u needs ISMs, cluster visibility and "
                         "fewer than %u VPLs before it", (unsigned)a->ism_first, (unsigned)a->vpl_count);
    if (ism && vis && a->ism_first == 0u)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ISMs with cluster visibility need ism_first > 0");
    if (ism && (!(a->ism_bias >= 0.0f && a->ism_bias <= 1.0f) || !(a->ism_slope >= 0.0f && a->ism_slope <= 64.0f)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ISM bias %g or slope %g out of range",
                         (double)a->ism_bias, (double)a->ism_slope);
    if (ism && (uint64_t)(a->vpl_count - a->ism_first) * a->ism_size * a->ism_size * 2u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u ISMs of %u^2 exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE",
                         (unsigned)(a->vpl_count - a->ism_first), (unsigned)a->ism_size);
    if (!gim__isfinitef(a->clamp_distance) || !(a->clamp_distance >= 0.0f) || !gim__isfinitef(a->scene_scale) ||
        !(a->scene_scale > 0.0f))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "clamp_distance >= 0 and scene_scale > 0 must be finite");
    if (!host && ctx->material_count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no materials");
    if ((r = gim__gl_program(ctx, GIM__PROGRAM_VPL_SHADE, &program)) != GIM_OK) return r;
    members = a->vpl_count / (k * k) + (a->vpl_count % (k * k) != 0u);   /* the largest subset, s = 0 */
    chunk = ctx->vpl_chunk ? ctx->vpl_chunk : GIM__VPL_SHADE_CHUNK;
    if (members > chunk) {
        r = gim__gl_sized_buffer(ctx, &ctx->vpl_partial, &ctx->vpl_partial_bytes, (uint64_t)a->width * a->height * 32u, where);
        if (r != GIM_OK) return r;
    }
    r = gim__gl_pixel_pass(ctx, program, a->depth, a->normal, a->albedo, a->material, a->width, a->height, a->view, a->proj,
                           a->output, a->format, where);
    if (r != GIM_OK) return r;
    gl->ActiveTexture(GIM__GL_TEXTURE0 + 4u);
    gl->BindTexture(GIM__GL_TEXTURE_2D_ARRAY, vis ? a->distance : 0u);
    gl->BindSampler(4u, ctx->nearest_sampler);
    /* a binding the pass does not read gets the VPL buffer (something valid is bound) */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, a->vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, vis ? a->cluster : a->vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, vis ? a->maps : a->vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, host ? a->vpls : ctx->materials);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 4, members > chunk ? ctx->vpl_partial : a->vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 5, ism ? a->ism : a->vpls);
    gl->Uniform1ui(14, ism ? a->ism_size : 0u);
    gl->Uniform1f(15, a->ism_bias > 0.0f ? a->ism_bias : GIM_ISM_BIAS);
    gl->Uniform1f(16, ism ? (a->ism_slope > 0.0f ? a->ism_slope : GIM_ISM_SLOPE) * 2.0f / (float)a->ism_size : 0.0f);
    gl->Uniform1f(17, GIM_ISM_LIFT * a->scene_scale);
    gl->Uniform1ui(18, a->ism_first);
    gl->Uniform1ui(4, a->vpl_count);
    gl->Uniform1ui(5, k);
    gl->Uniform1ui(8, a->map_size);
    gl->Uniform1f(9, GIM__TWINS_COINCIDENT * a->scene_scale);
    gl->Uniform1f(10, a->clamp_distance * a->clamp_distance);
    gl->Uniform1ui(11, host ? 1u : ctx->material_count);
    gl->Uniform1f(12, a->format == GIM__GL_RGBA16F ? 65504.0f : FLT_MAX);
    gl->Uniform1ui(13, vis ? a->map_count : 0u);
    first = 0;
    do {
        uint32_t n = members - first < chunk ? members - first : chunk;
        uint32_t flags = (vis ? 1u : 0u) | (host ? 2u : 0u) | (first == 0u ? 4u : 0u) | (first + n >= members ? 8u : 0u) |
                         (ism && !vis ? 16u : 0u) | (ism && vis ? 32u : 0u);
        gl->Uniform2ui(6, first, first + n);
        gl->Uniform1ui(7, flags);
        gl->DispatchCompute((a->width + 7u) / 8u, (a->height + 7u) / 8u, 1u);
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
        first += n;
    } while (first < members);
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GIM__GL_TEXTURE_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* The texture the VPL shading writes before the blur reads it (the blur's output is the
   frame's indirect texture), width x height of format, made anew when either changes. */
static void gim__vpl_raw_release(gim_context *ctx) {
    if (ctx->vpl_raw) ctx->gl.DeleteTextures(1, &ctx->vpl_raw);
    ctx->vpl_raw = 0;
    ctx->vpl_raw_width = ctx->vpl_raw_height = 0;
    ctx->vpl_raw_format = 0;
}

static GIM__UNUSED void gim__gl_vpl_raw_texture(gim_context *ctx, uint32_t width, uint32_t height, gim__GLenum format) {
    if (ctx->vpl_raw && ctx->vpl_raw_width == width && ctx->vpl_raw_height == height && ctx->vpl_raw_format == format)
        return;
    gim__gl_texture(ctx, &ctx->vpl_raw, format, width, height);
    ctx->vpl_raw_width = width;
    ctx->vpl_raw_height = height;
    ctx->vpl_raw_format = format;
}

/* What the geometry-aware blur reads and writes. */
typedef struct gim__blur_args {
    gim__GLuint depth, normal;     /* the G-buffer */
    gim__GLuint albedo, material;  /* gimany's G-buffer's; 0 (the host's G-buffer): albedo 1, no glossy */
    uint32_t width, height;
    gim_mat4 view, proj;
    gim__GLuint input;             /* width x height rgb texture (the VPL shading's output) */
    uint32_t window;               /* k; 0 or 1: a copy of the pixels with a surface */
    float position_tolerance;      /* > 0, length */
    float normal_tolerance;        /* [-1, 1]; 0: 0.8 */
    gim__GLuint output;            /* width x height texture of format, not the input */
    gim__GLenum format;            /* RGBA16F or RGBA32F */
} gim__blur_args;

/* Geometry-aware blur of a->input into a->output (twin: gim_geometry_blur_twin). */
static GIM__UNUSED gim_result gim__gl_geometry_blur(gim_context *ctx, const gim__blur_args *a) {
    static const char where[] = "geometry-aware blur (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0, tex[5];
    gim_mat4 inv_view, inv_proj;
    float tol = a->position_tolerance, ncos = a->normal_tolerance != 0.0f ? a->normal_tolerance : 0.8f;
    int host = a->albedo == 0 || ctx->material_count == 0;
    int i;
    gim_result r;
    if (a->width == 0 || a->height == 0 || !a->depth || !a->normal || !a->input || !a->output || a->input == a->output)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "G-buffer, input and a distinct output are required");
    if (a->window > GIM__VPL_MAX_INTERLEAVE)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "window %u exceeds %u", a->window, GIM__VPL_MAX_INTERLEAVE);
    if (!gim__isfinitef(tol) || !(tol > 0.0f) || !(ncos >= -1.0f && ncos <= 1.0f))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "position_tolerance > 0, normal_tolerance in [-1, 1]");
    if (!gim_mat4_invert(a->view, &inv_view) || !gim_mat4_invert(a->proj, &inv_proj))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj is singular");
    if ((r = gim__gl_program(ctx, GIM__PROGRAM_GEOMETRY_BLUR, &program)) != GIM_OK) return r;
    gim__gl_nearest_sampler(ctx);
    tex[0] = a->depth; tex[1] = a->normal; tex[2] = host ? a->normal : a->albedo; tex[3] = host ? a->normal : a->material;
    tex[4] = a->input;
    for (i = 0; i < 5; ++i) {
        gim__GLuint unit = (gim__GLuint)i;
        gl->ActiveTexture(GIM__GL_TEXTURE0 + unit);
        gl->BindTexture(GIM__GL_TEXTURE_2D, tex[i]);
        gl->BindSampler(unit, ctx->nearest_sampler);
    }
    gl->BindImageTexture(0, a->output, 0, GIM__GL_FALSE, 0, GIM__GL_WRITE_ONLY, a->format);
    gl->UseProgram(program);
    gl->Uniform2ui(0, a->width, a->height);
    gl->UniformMatrix4fv(1, 1, GIM__GL_FALSE, inv_proj.m);
    gl->UniformMatrix4fv(2, 1, GIM__GL_FALSE, inv_view.m);
    gl->Uniform1ui(4, a->window > 1u ? a->window : 1u);
    gl->Uniform1f(5, tol * tol);
    gl->Uniform1f(6, ncos);
    gl->Uniform1f(7, a->format == GIM__GL_RGBA16F ? 65504.0f : FLT_MAX);
    gl->Uniform1ui(8, host ? 0u : ctx->material_count);
    /* bound in host mode too, unread there: NVIDIA may skip a dispatch with a block unbound */
    if (ctx->materials) gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->materials);
    gl->DispatchCompute((a->width + 7u) / 8u, (a->height + 7u) / 8u, 1u);
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GIM__GL_TEXTURE_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* --- RSM gather (Dachsbacher 2005) ---------------------------------------------------------- */

#define GIM__GATHER_DEFAULT_SAMPLES 256u
#define GIM__GATHER_DEFAULT_RADIUS 1.5f   /* from any point of the RSM the disk holds all of it */

/* The sample pattern of RSM gather: Hammersley points (u = i / N stratifies the radius),
   the same for every pixel and frame; the twin takes the same floats. */
static gim_result gim__gather_pattern(const gim_env *env, uint32_t n, float **out) {
    *out = (float *)gim__alloc_array(env, n, 2u * sizeof(float));
    if (!*out) return gim__fail(env, GIM_ERROR_OUT_OF_MEMORY, "RSM gather", "%u samples", (unsigned)n);
    return gim_hammersley_points(*out, n, 2u, NULL);
}

/* RSM gather of every light into the indirect texture (twin: gim_rsm_gather_twin per light, summed). */
static gim_result gim__gl_rsm_gather(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                     float scale, gim__GLenum format) {
    static const char where[] = "RSM gather (GL)";
    const gim__gl *gl = &ctx->gl;
    uint32_t n = f->gather.samples, i, on;
    float frac = f->gather.radius, *pattern = NULL, *offsets = NULL;
    int host = f->gbuffer.depth != 0;
    gim__GLuint program = 0;
    uint64_t stride;
    int same = ctx->gather_samples && ctx->gather_key_n == n && ctx->gather_key_lights == ctx->light_count &&
               ctx->gather_key_frac == frac;
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_RSM_GATHER, &program);
    if (r != GIM_OK) return r;
    for (i = 0; i < ctx->light_count && same; ++i) same = ctx->gather_key_sizes[i] == ctx->light_gpu[i].size;
    if (!same) r = gim__gather_pattern(&ctx->env, n, &pattern);   /* the offsets change only with these */
    if (r == GIM_OK && !same) {
        offsets = (float *)gim__alloc_array(&ctx->env, n, 16u);
        if (!offsets) r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u samples", (unsigned)n);
    }
    stride = ((uint64_t)n * 16u + (uint64_t)ctx->ssbo_align - 1u) / (uint64_t)ctx->ssbo_align * (uint64_t)ctx->ssbo_align;
    if (r == GIM_OK && !same) {
        ctx->gather_key_n = 0;
        r = gim__gl_sized_buffer(ctx, &ctx->gather_samples, &ctx->gather_samples_bytes, stride * ctx->light_count, where);
    }
    for (i = 0; i < ctx->light_count && r == GIM_OK && !same; ++i) { /* each light's offsets: its radius in its texels */
        uint32_t j;
        for (j = 0; j < n; ++j) {
            gim__gather_offset(pattern + j * 2, frac * (float)ctx->light_gpu[i].size, n, offsets + j * 4);
            offsets[j * 4 + 3] = 0.0f;
        }
        gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->gather_samples);
        gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, (gim__GLintptr)(i * stride), (gim__GLsizeiptr)n * 16, offsets);
        ctx->gather_key_sizes[i] = ctx->light_gpu[i].size;
    }
    if (r == GIM_OK && !same) {
        ctx->gather_key_n = n;
        ctx->gather_key_lights = ctx->light_count;
        ctx->gather_key_frac = frac;
    }
    gim__free(&ctx->env, pattern);
    gim__free(&ctx->env, offsets);
    if (r == GIM_OK && ctx->light_on_count > 1)
        r = gim__gl_sized_buffer(ctx, &ctx->gather_sum, &ctx->gather_sum_bytes, (uint64_t)f->width * f->height * 16u, where);
    if (r != GIM_OK) return r;
    gim__gl_indirect_texture(ctx, f->width, f->height, format);
    r = gim__gl_pixel_pass(ctx, program, depth, normal, host ? 0u : ctx->gbuffer_albedo, host ? 0u : ctx->gbuffer_material,
                           f->width, f->height, f->view, f->proj, ctx->indirect, format, where);
    if (r != GIM_OK) return r;
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, ctx->light_on_count > 1 ? ctx->gather_sum : ctx->gather_samples);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, host ? ctx->gather_samples : ctx->materials);
    gl->Uniform1ui(5, n);
    gl->Uniform1f(7, (GIM__TWINS_COINCIDENT * scale) * (GIM__TWINS_COINCIDENT * scale));
    gl->Uniform1ui(9, host ? 1u : ctx->material_count);
    gl->Uniform1f(10, format == GIM__GL_RGBA16F ? 65504.0f : FLT_MAX);
    for (i = 0, on = 0; i < ctx->light_count; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        gim_mat4 vp = gim_mat4_mul(g->proj, g->view);
        gim__GLuint rt[3];
        uint32_t k;
        if (!ctx->light_on[i]) continue;   /* culled: nothing in its RSM */
        ++on;
        rt[0] = g->position; rt[1] = g->normal; rt[2] = g->flux;
        for (k = 0; k < 3; ++k) {
            gl->ActiveTexture(GIM__GL_TEXTURE0 + 4u + k);
            gl->BindTexture(GIM__GL_TEXTURE_2D, rt[k]);
            gl->BindSampler(4u + k, ctx->nearest_sampler);
        }
        gl->UniformMatrix4fv(4, 1, GIM__GL_FALSE, vp.m);
        gl->BindBufferRange(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->gather_samples, (gim__GLintptr)(i * stride),
                            (gim__GLsizeiptr)n * 16);
        gl->Uniform1ui(8, (on == 1u ? 1u : 0u) | (on == ctx->light_on_count ? 2u : 0u) | (host ? 4u : 0u));
        gl->DispatchCompute((f->width + 7u) / 8u, (f->height + 7u) / 8u, 1u);
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
    }
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT |
                      GIM__GL_TEXTURE_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* --- paraboloid maps and second-bounce VPLs (Dong sec. 4.2; SSVP sec. 3.C) ---------------- */

/* Which paraboloid maps a pass makes (gim__gl_paraboloids' what). */
#define GIM__PARA_DISTANCE 0      /* the visibility maps only */
#define GIM__PARA_BOTH 1          /* both, in two passes (each with its own near skip) */
#define GIM__PARA_ATTRIBUTES 2    /* the attribute maps only (the second bounce without paraboloid visibility) */

/* Delete the paraboloid textures (all, or only the attribute ones) and, with all, the second
   bounce's sample buffer. */
static void gim__paraboloid_release(gim_context *ctx, int all) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint t[5];
    t[0] = ctx->para_position; t[1] = ctx->para_normal; t[2] = ctx->para_albedo;
    t[3] = ctx->para_distance; t[4] = ctx->para_depth;
    gl->DeleteTextures(all ? 5 : 3, t);
    ctx->para_position = ctx->para_normal = ctx->para_albedo = 0;
    ctx->para_attributes = GIM__PARA_DISTANCE;
    if (!all) return;
    ctx->para_distance = ctx->para_depth = 0;
    if (ctx->para_fbo) gl->DeleteFramebuffers(1, &ctx->para_fbo);
    if (ctx->para_samples) gl->DeleteBuffers(1, &ctx->para_samples);
    ctx->para_fbo = ctx->para_samples = 0;
    ctx->para_samples_bytes = 0;
    ctx->para_size = ctx->para_count = 0;
    memset(ctx->para_key, 0, sizeof ctx->para_key);
}

/* A size x size x layers single-level 2D array texture of format, nearest, clamped (replaces *tex). */
static void gim__gl_texture_array(gim_context *ctx, gim__GLuint *tex, gim__GLenum format, uint32_t size, uint32_t layers) {
    const gim__gl *gl = &ctx->gl;
    if (*tex) gl->DeleteTextures(1, tex);
    *tex = 0;
    gl->GenTextures(1, tex);
    gl->ActiveTexture(GIM__GL_TEXTURE0);
    gl->BindTexture(GIM__GL_TEXTURE_2D_ARRAY, *tex);
    gl->TexStorage3D(GIM__GL_TEXTURE_2D_ARRAY, 1, format, (gim__GLsizei)size, (gim__GLsizei)size, (gim__GLsizei)layers);
    gl->TexParameteri(GIM__GL_TEXTURE_2D_ARRAY, GIM__GL_TEXTURE_MIN_FILTER, GIM__GL_NEAREST);
    gl->TexParameteri(GIM__GL_TEXTURE_2D_ARRAY, GIM__GL_TEXTURE_MAG_FILTER, GIM__GL_NEAREST);
    gl->TexParameteri(GIM__GL_TEXTURE_2D_ARRAY, GIM__GL_TEXTURE_WRAP_S, GIM__GL_CLAMP_TO_EDGE);
    gl->TexParameteri(GIM__GL_TEXTURE_2D_ARRAY, GIM__GL_TEXTURE_WRAP_T, GIM__GL_CLAMP_TO_EDGE);
}

/* The layered textures and framebuffer of count size^2 maps (kept while they fit exactly):
   attachment 0 the distance (not with GIM__PARA_ATTRIBUTES), 1-3 the attributes (not with
   GIM__PARA_DISTANCE), one depth texture the passes share. */
static gim_result gim__gl_paraboloid_targets(gim_context *ctx, uint32_t count, uint32_t size, int what,
                                             const char *where) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint color[4];
    gim__GLenum status;
    int i;
    if (ctx->para_size == size && ctx->para_count == count && ctx->para_attributes == what && ctx->para_fbo)
        return GIM_OK;
    if (what == GIM__PARA_DISTANCE) gim__paraboloid_release(ctx, 0);  /* only what is enabled is allocated */
    ctx->para_size = ctx->para_count = 0;
    if (what != GIM__PARA_ATTRIBUTES) {
        gim__gl_texture_array(ctx, &ctx->para_distance, GIM__GL_R32F, size, count);
    } else if (ctx->para_distance) {
        gl->DeleteTextures(1, &ctx->para_distance);
        ctx->para_distance = 0;
    }
    gim__gl_texture_array(ctx, &ctx->para_depth, GIM__GL_DEPTH_COMPONENT32F, size, count);
    if (what != GIM__PARA_DISTANCE) {
        gim__gl_texture_array(ctx, &ctx->para_position, GIM__GL_RGBA32F, size, count);
        gim__gl_texture_array(ctx, &ctx->para_normal, GIM__GL_RGBA32F, size, count);
        gim__gl_texture_array(ctx, &ctx->para_albedo, GIM__GL_RGBA32F, size, count);
    }
    color[0] = ctx->para_distance; color[1] = ctx->para_position; color[2] = ctx->para_normal; color[3] = ctx->para_albedo;
    if (ctx->para_fbo) gl->DeleteFramebuffers(1, &ctx->para_fbo);
    ctx->para_fbo = 0;
    gl->GenFramebuffers(1, &ctx->para_fbo);
    gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, ctx->para_fbo);
    for (i = 0; i < 4; ++i) /* layered attachments: gl_Layer picks the map */
        if (color[i])
            gl->FramebufferTexture(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i, color[i], 0);
    gl->FramebufferTexture(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_DEPTH_ATTACHMENT, ctx->para_depth, 0);
    {   /* what the first pass draws (gim__gl_paraboloids sets each pass's) */
        gim__GLenum bufs[4] = {GIM__GL_COLOR_ATTACHMENT0, GIM__GL_NONE, GIM__GL_NONE, GIM__GL_NONE};
        if (what != GIM__PARA_DISTANCE)
            for (i = 0; i < 4; ++i)
                bufs[i] = i == 0 && what == GIM__PARA_ATTRIBUTES ? (gim__GLenum)GIM__GL_NONE
                                                                 : (gim__GLenum)(GIM__GL_COLOR_ATTACHMENT0 + (gim__GLenum)i);
        gl->DrawBuffers(4, bufs);
    }
    status = gl->CheckFramebufferStatus(GIM__GL_DRAW_FRAMEBUFFER);
    if (status != GIM__GL_FRAMEBUFFER_COMPLETE)
        return gim__fail(&ctx->env, GIM_ERROR_GL, where, "layered framebuffer incomplete (0x%04x)", (unsigned)status);
    if (gim__gl_check(ctx, where) != GIM_OK) return GIM_ERROR_GL;
    ctx->para_size = size;
    ctx->para_count = count;
    ctx->para_attributes = what;
    return GIM_OK;
}

/* Before a paraboloid pass draws the scene (inside gim__gl_enter): every instance's mesh exists. */
static gim_result gim__paraboloid_draw_check(gim_context *ctx, const char *where) {
    uint32_t i;
    for (i = 0; i < ctx->instance_count; ++i)
        if (!gim__mesh_get(ctx, ctx->instances[i].mesh))
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "instance %u names a removed mesh", (unsigned)i);
    return GIM_OK;
}

/* The paraboloid program's uniforms but the pass (7): material_count (0: albedo 0), the maps'
   side, scene_scale (the depth encoding), the quad's margin (rounding only: a quarter texel
   beyond the rigorous bound); list_first and vpl_lift for the VPLs' maps (0, 0: the clusters'). */
static void gim__paraboloid_uniforms(const gim__gl *gl, uint32_t material_count, uint32_t size, float scene_scale,
                                     uint32_t list_first, float vpl_lift) {
    gl->Uniform1ui(3, material_count);
    gl->Uniform1f(4, 0.5f / (float)size + 1e-5f);
    gl->Uniform1ui(5, size);
    gl->Uniform1f(6, scene_scale);
    gl->Uniform1ui(8, list_first);
    gl->Uniform1f(9, vpl_lift);
}

/* The paraboloid maps of count clusters in layered passes, the GPU twin of
   gim_paraboloid_texel_twin at every texel. maps_ssbo: count gim_paraboloid (48 bytes, std430
   3 vec4), read by the shaders only (the cluster pass writes it on the GPU). Every scene
   instance is drawn instanced count times; paraboloid.geom sends instance i's triangles to
   layer i as a conservative quad around their exact (curved) image, and paraboloid.frag
   intersects each covered texel's ray with the triangle, so the maps are exact for any
   triangle size (the papers project vertices and rasterise linearly, which bends nothing).
   what (GIM__PARA_*) picks the maps; each kind is its own pass because each keeps its own
   nearest hit: the visibility map's past near_distance (the VAL's own surface is no blocker),
   the attribute maps' past attribute_near (a second-bounce ray lands on the first surface it
   meets, however near). Writes, in ctx (size x size x count 2D arrays, layer = map, rows from
   y = 0):
     para_distance  R32F: distance to the nearest hit beyond near_distance, GIM_PARABOLOID_EMPTY
                    where none (not with GIM__PARA_ATTRIBUTES: deleted);
     para_depth     DEPTH_COMPONENT32F: d / (d + scene_scale) (the depth test), 1 where none;
   and with attributes (otherwise they are deleted), of the nearest hit beyond attribute_near:
     para_position  RGBA32F: the hit, w = 1 (0 where none);
     para_normal    RGBA32F: unit normal towards the origin (two-sided), w = 0;
     para_albedo    RGBA32F: diffuse rgb of the triangle's material, w = 1.
   scene_scale > 0 only shapes the depth encoding. Cost: per map and pass, every triangle in
   front of its plane, each covering its image's bounding box. */
static GIM__UNUSED gim_result gim__gl_paraboloids(gim_context *ctx, gim__GLuint maps_ssbo, uint32_t count, uint32_t size,
                                                  int what, float scene_scale) {
    static const char where[] = "paraboloid maps (GL)";
    static const float empty[4] = {GIM_PARABOLOID_EMPTY, 0.0f, 0.0f, 0.0f}, zero[4] = {0.0f, 0.0f, 0.0f, 0.0f};
    static const float one = 1.0f;
    static const gim__GLenum bufs[2][4] = {{GIM__GL_COLOR_ATTACHMENT0, GIM__GL_NONE, GIM__GL_NONE, GIM__GL_NONE},
                                           {GIM__GL_NONE, GIM__GL_COLOR_ATTACHMENT0 + 1, GIM__GL_COLOR_ATTACHMENT0 + 2,
                                            GIM__GL_COLOR_ATTACHMENT0 + 3}};
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_result r = GIM_OK;
    int k, pass;
    if (!maps_ssbo) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "maps_ssbo is 0");
    if (count == 0 || size == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "count or size is 0");
    if (what != GIM__PARA_DISTANCE && what != GIM__PARA_BOTH && what != GIM__PARA_ATTRIBUTES)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown maps %d", what);
    if (!gim__isfinitef(scene_scale) || !(scene_scale > 0.0f))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale must be finite and > 0");
    if (size > (uint32_t)ctx->max_texture_size || size > (uint32_t)ctx->max_viewport[0] ||
        size > (uint32_t)ctx->max_viewport[1])
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %u above the texture or viewport limit",
                         (unsigned)size);
    if ((uint64_t)count * 48u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u maps exceed the SSBO limit", (unsigned)count);
    if ((int64_t)count > (int64_t)ctx->max_layers[0] || (int64_t)count > (int64_t)ctx->max_layers[1])
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u maps exceed the layer limits (%d, %d)",
                         (unsigned)count, (int)ctx->max_layers[0], (int)ctx->max_layers[1]);
    gim__gl_enter(ctx, where);
    r = gim__paraboloid_draw_check(ctx, where);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "maps_ssbo", maps_ssbo, (uint64_t)count * 48u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_PARABOLOID, &program);
    if (r == GIM_OK) r = gim__gl_paraboloid_targets(ctx, count, size, what, where);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gim__gl_raster_state(gl, ctx->para_fbo, size, size);
    gl->UseProgram(program);
    gim__paraboloid_uniforms(gl, ctx->materials ? ctx->material_count : 0u, size, scene_scale, 0u, 0.0f);
    /* with no materials, binding 0 is never read (albedo 0) but must name a buffer */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->materials ? ctx->materials : maps_ssbo);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, maps_ssbo);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, maps_ssbo);   /* the VPL list, not read here */
    for (pass = 0; pass < 2; ++pass) {   /* 0: the visibility maps, 1: the attribute maps */
        if ((pass == 0 && what == GIM__PARA_ATTRIBUTES) || (pass == 1 && what == GIM__PARA_DISTANCE)) continue;
        gl->DrawBuffers(4, bufs[pass]);
        if (pass == 0) gl->ClearBufferfv(GIM__GL_COLOR, 0, empty);
        else for (k = 1; k < 4; ++k) gl->ClearBufferfv(GIM__GL_COLOR, k, zero);
        gl->ClearBufferfv(GIM__GL_DEPTH, 0, &one);
        gl->Uniform1ui(7, (gim__GLuint)pass);
        gim__gl_draw_meshes(ctx, count);
    }
    gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT | GIM__GL_SHADER_IMAGE_ACCESS_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* Layers of the VPLs' shadow-map targets: a batch of maps drawn, then stored (64^2: 32 KiB a layer). */
#define GIM__VSM_LAYERS 1024u

/* One paraboloid shadow map per VPL from the triangles (GIM_VISIBILITY_SHADOW_MAPS; Keller 1997's
   instant radiosity, each VPL's map kept with the VPL as Laine et al. 2007 do), in the imperfect
   shadow maps' format, so that the VPL shading looks them up as it does ISMs (ism_lookup.glsl):
   map m in map_first .. map_first + count - 1 of maps_out (size^2 16-bit depths a map,
   gim_ism_quantize) is VPL source_first + m of vpls (gim_vpl, 48 bytes), its origin the VPL
   lifted GIM_ISM_LIFT scene scales along its normal (gim__ism_frame's), each texel the distance
   along its centre ray to the nearest triangle (paraboloid.geom / .frag in VPL mode: no near
   skip; the twin is gim_paraboloid_texel_twin with near_distance 0, then gim_ism_quantize). An
   unlit VPL's map is not made (no pass reads it), nor with keep a kept VPL's (gim_vpl.kept 1),
   which keeps what maps_out holds: the VPLs' flags are read back (a sync, in the frames that
   make maps; drawing every VPL's copy of the scene to skip the kept ones in the geometry shader
   cost the street 32 s a frame on llvmpipe for 2 maps made) and the ones to make listed
   (ctx->vsm_list). In batches of up to GIM__VSM_LAYERS layers: the paraboloid pass draws VPL
   list[first + l] into layer l, ism_from_paraboloid.comp stores the layers, a dispatch per
   storage range of maps; made (one uint) counts the maps made. Cost: every triangle of the
   scene once per map made, each covered texel a ray-triangle test (an ISM splats 65,536
   surfels), only for the VPLs new this frame. */
static gim_result gim__gl_vpl_shadow_maps(gim_context *ctx, gim__GLuint vpls, uint32_t source_first, uint32_t map_first,
                                          uint32_t count, uint32_t size, float scene_scale, gim__GLuint maps_out,
                                          gim__GLuint made, int keep) {
    static const char where[] = "VPL shadow maps (GL)";
    static const float empty[4] = {GIM_PARABOLOID_EMPTY, 0.0f, 0.0f, 0.0f};
    static const float one = 1.0f;
    const gim__gl *gl = &ctx->gl;
    gim__GLuint draw = 0, store = 0;
    gim_vpl *flags = NULL;
    uint32_t *list = NULL;
    uint32_t layers, first, chunk, i, n = 0;
    uint64_t map_bytes = (uint64_t)size * size * 2u;
    gim_result r = GIM_OK;
    if (!vpls || !maps_out || !made) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "a buffer is 0");
    if (count == 0) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no maps");
    if (size < GIM_ISM_MIN_SIZE || size > GIM_ISM_MAX_SIZE || (size & (size - 1u)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "map size %u: a power of two in %u..%u",
                         (unsigned)size, GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale %g must be finite and > 0",
                         (double)scene_scale);
    if (((uint64_t)map_first + count) * map_bytes > (uint64_t)GIM_ISM_MAX_BYTES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u maps of %u^2 exceed GIM_ISM_MAX_BYTES",
                         (unsigned)(map_first + count), (unsigned)size);
    chunk = gim__ism_block_maps(ctx, size, GIM__ISM_CHUNK);
    if (chunk == 0)
        return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where, "GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT %d",
                         (int)ctx->ssbo_align);
    layers = ctx->vsm_batch ? ctx->vsm_batch : GIM__VSM_LAYERS;
    if (map_first + count < layers) layers = map_first + count;   /* of every map in the buffer: the targets stay */
    if ((int64_t)layers > (int64_t)ctx->max_layers[0]) layers = (uint32_t)ctx->max_layers[0];
    if ((int64_t)layers > (int64_t)ctx->max_layers[1]) layers = (uint32_t)ctx->max_layers[1];
    if (layers == 0 || size > (uint32_t)ctx->max_texture_size || size > (uint32_t)ctx->max_viewport[0] ||
        size > (uint32_t)ctx->max_viewport[1])
        return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where, "no layered target of %u^2 (layer limits %d, %d)",
                         (unsigned)size, (int)ctx->max_layers[0], (int)ctx->max_layers[1]);
    gim__gl_enter(ctx, where);
    r = gim__paraboloid_draw_check(ctx, where);
    if (r == GIM_OK)
        r = gim__gl_check_buffer(ctx, where, "vpls", vpls, ((uint64_t)source_first + map_first + count) * 48u);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "maps_out", maps_out, ((uint64_t)map_first + count) * map_bytes);
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "made", made, 4u);
    if (r == GIM_OK && (maps_out == vpls || made == vpls || made == maps_out))
        r = gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "an output is also an input");
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_PARABOLOID, &draw);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_ISM_FROM_PARABOLOID, &store);
    if (r == GIM_OK) {   /* the maps to make: the lit VPLs, but with keep the kept ones */
        flags = (gim_vpl *)gim__alloc_array(&ctx->env, count, sizeof *flags);
        list = (uint32_t *)gim__alloc_array(&ctx->env, count, sizeof *list);
        if (!flags || !list) r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "the flags of %u VPLs", (unsigned)count);
    }
    if (r == GIM_OK) {
        gl->MemoryBarrier(GIM__GL_BUFFER_UPDATE_BARRIER_BIT);   /* the VPL passes wrote them from shaders */
        gl->BindBuffer(GIM__GL_COPY_READ_BUFFER, vpls);
        gl->GetBufferSubData(GIM__GL_COPY_READ_BUFFER, (gim__GLintptr)(((uint64_t)source_first + map_first) * 48u),
                             (gim__GLsizeiptr)((uint64_t)count * 48u), flags);
        for (i = 0; i < count; ++i)
            if (flags[i].lit > 0.0f && !(keep && flags[i].kept == 1.0f)) list[n++] = source_first + map_first + i;
        if (n) r = gim__gl_sized_buffer(ctx, &ctx->vsm_list, &ctx->vsm_list_bytes, (uint64_t)count * 4u, where);
        if (r == GIM_OK && n) {
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->vsm_list);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)n * 4, list);
        }
    }
    if (r == GIM_OK && n && (ctx->vsm_size != size || ctx->vsm_layers != layers || !ctx->vsm_fbo)) {
        gim__GLenum status;
        gim__vsm_targets_release(ctx);
        gim__gl_texture_array(ctx, &ctx->vsm_distance, GIM__GL_R32F, size, layers);
        gim__gl_texture_array(ctx, &ctx->vsm_depth, GIM__GL_DEPTH_COMPONENT32F, size, layers);
        gl->GenFramebuffers(1, &ctx->vsm_fbo);
        gl->BindFramebuffer(GIM__GL_DRAW_FRAMEBUFFER, ctx->vsm_fbo);
        gl->FramebufferTexture(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_COLOR_ATTACHMENT0, ctx->vsm_distance, 0);
        gl->FramebufferTexture(GIM__GL_DRAW_FRAMEBUFFER, GIM__GL_DEPTH_ATTACHMENT, ctx->vsm_depth, 0);
        status = gl->CheckFramebufferStatus(GIM__GL_DRAW_FRAMEBUFFER);
        if (status != GIM__GL_FRAMEBUFFER_COMPLETE)
            r = gim__fail(&ctx->env, GIM_ERROR_GL, where, "layered framebuffer incomplete (0x%04x)", (unsigned)status);
        if (r == GIM_OK) r = gim__gl_check(ctx, where);
        if (r == GIM_OK) { ctx->vsm_size = size; ctx->vsm_layers = layers; }
        else gim__vsm_targets_release(ctx);
    }
    for (first = 0; r == GIM_OK && first < n; first += layers) {
        uint32_t nb = n - first < layers ? n - first : layers, at;
        /* draw: VPL list[first + l] into layer l */
        gim__gl_raster_state(gl, ctx->vsm_fbo, size, size);
        gl->UseProgram(draw);
        gim__paraboloid_uniforms(gl, 0u, size, scene_scale, first, GIM_ISM_LIFT * scene_scale);   /* no albedo */
        gl->Uniform1ui(7, 0u);   /* the distance pass only */
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, vpls);   /* materials: never read (count 0) */
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, vpls);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, ctx->vsm_list);
        gl->ClearBufferfv(GIM__GL_COLOR, 0, empty);
        gl->ClearBufferfv(GIM__GL_DEPTH, 0, &one);
        gim__gl_draw_meshes(ctx, nb);
        gl->MemoryBarrier(GIM__GL_TEXTURE_FETCH_BARRIER_BIT);
        /* store: layer l as VPL list[first + l]'s map, a dispatch per storage range (the list ascends) */
        gl->UseProgram(store);
        gl->ActiveTexture(GIM__GL_TEXTURE0);
        gl->BindTexture(GIM__GL_TEXTURE_2D_ARRAY, ctx->vsm_distance);
        gl->BindSampler(0, ctx->nearest_sampler);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, ctx->vsm_list);
        gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, made);
        gl->Uniform1ui(0, size);
        gl->Uniform1ui(1, first);
        gl->Uniform1ui(3, source_first);
        for (at = first; at < first + nb;) {
            uint32_t m = list[at] - source_first, block = m - m % chunk, end = at;
            uint64_t maps = (uint64_t)map_first + count - block < chunk ? (uint64_t)map_first + count - block : chunk;
            while (end < first + nb && list[end] - source_first < block + chunk) ++end;
            gl->BindBufferRange(GIM__GL_SHADER_STORAGE_BUFFER, 2, maps_out, (gim__GLintptr)((uint64_t)block * map_bytes),
                                (gim__GLsizeiptr)(maps * map_bytes));
            gl->Uniform1ui(2, block);
            gl->Uniform1ui(5, at - first);
            gl->DispatchCompute(end - at, 1u, 1u);
            at = end;
        }
        gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
    }
    gim__free(&ctx->env, flags);
    gim__free(&ctx->env, list);
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* Second-bounce VPLs on the GPU, the twin of gim_second_bounce_vpls_twin on the maps of the last
   gim__gl_paraboloids (made with attributes, map_count <= its count, the same size): VPL
   first + i of vpls_out (gim_vpl, 48 bytes) for i < vpl_count, map m's share in map order.
   The texels are the twin's own (gim__second_bounce_texel), computed on the CPU and kept in
   ctx->para_samples while map_count, size and vpl_count stay the same. maps_ssbo: as for the
   maps (flux read). */
static gim_result gim__gl_second_bounce_ism(gim_context *ctx, gim__GLuint maps_ssbo, uint32_t map_count, uint32_t size,
                                            uint32_t vpl_count, gim__GLuint vpls_out, uint32_t first, const gim__gl_ism *ism,
                                            float scene_scale);
static GIM__UNUSED gim_result gim__gl_second_bounce(gim_context *ctx, gim__GLuint maps_ssbo, uint32_t map_count,
                                                    uint32_t size, uint32_t vpl_count, gim__GLuint vpls_out,
                                                    uint32_t first) {
    return gim__gl_second_bounce_ism(ctx, maps_ssbo, map_count, size, vpl_count, vpls_out, first, NULL, 1.0f);
}

/* ... with each hit checked in its cluster's imperfect shadow map (ism->maps: map_count of
   ism->size^2 floats, made from maps_ssbo's origins and normals; gim_second_bounce_desc.ism),
   scene_scale > 0 their lift; ism NULL or ism->maps 0: none. */
static gim_result gim__gl_second_bounce_ism(gim_context *ctx, gim__GLuint maps_ssbo, uint32_t map_count, uint32_t size,
                                            uint32_t vpl_count, gim__GLuint vpls_out, uint32_t first, const gim__gl_ism *ism,
                                            float scene_scale) {
    static const char where[] = "second-bounce VPLs (GL)";
    int with_ism = ism && ism->maps;
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0, textures[3];
    gim_result r = GIM_OK;
    uint32_t m, j, i;
    if (!maps_ssbo || !vpls_out)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "maps_ssbo or vpls_out is 0");
    if (map_count == 0 || size == 0 || vpl_count == 0)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "map_count, size or vpl_count is 0");
    if (ctx->para_attributes == GIM__PARA_DISTANCE || ctx->para_size != size || ctx->para_count < map_count)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "no paraboloid maps with attributes of size %u and %u layers (run the paraboloid pass first)",
                         (unsigned)size, (unsigned)map_count);
    if ((uint64_t)first + vpl_count > UINT32_MAX || ((uint64_t)first + vpl_count) * 48u > (uint64_t)ctx->max_ssbo_bytes ||
        (uint64_t)vpl_count * 16u > (uint64_t)ctx->max_ssbo_bytes || vpl_count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs from %u exceed the SSBO or dispatch limits",
                         (unsigned)vpl_count, (unsigned)first);
    if (with_ism && (ism->size < GIM_ISM_MIN_SIZE || ism->size > GIM_ISM_MAX_SIZE || (ism->size & (ism->size - 1u)) ||
                     !(ism->bias >= 0.0f && ism->bias <= 1.0f) || !(ism->slope >= 0.0f && ism->slope <= 64.0f) ||
                     !(scene_scale > 0.0f) || !gim__isfinitef(scene_scale)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ISM size %u, bias %g, slope %g or scene_scale %g out of range",
                         (unsigned)ism->size, (double)ism->bias, (double)ism->slope, (double)scene_scale);
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "maps_ssbo", maps_ssbo, (uint64_t)map_count * 48u);
    if (r == GIM_OK && with_ism)
        r = gim__gl_check_buffer(ctx, where, "ISM maps", ism->maps, (uint64_t)map_count * ism->size * ism->size * 2u);   /* 16 bits a texel */
    if (r == GIM_OK) r = gim__gl_check_buffer(ctx, where, "vpls_out", vpls_out, ((uint64_t)first + vpl_count) * 48u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SECOND_BOUNCE, &program);
    if (r == GIM_OK && (!ctx->para_samples || ctx->para_key[0] != map_count || ctx->para_key[1] != size ||
                        ctx->para_key[2] != vpl_count)) {
        uint32_t *texels = (uint32_t *)gim__alloc_array(&ctx->env, vpl_count, 4u * sizeof(uint32_t));
        if (!texels) r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u VPL texels", (unsigned)vpl_count);
        for (m = 0; m < map_count && texels; ++m) {
            uint32_t at, s_m = gim__second_bounce_share(vpl_count, map_count, m, &at);
            for (j = 0; j < s_m; ++j) {
                uint32_t *t = texels + (size_t)(at + j) * 4u;
                t[0] = m;
                gim__second_bounce_texel(j, s_m, size, &t[1], &t[2]);
                t[3] = s_m;
            }
        }
        memset(ctx->para_key, 0, sizeof ctx->para_key);
        if (r == GIM_OK)
            r = gim__gl_sized_buffer(ctx, &ctx->para_samples, &ctx->para_samples_bytes, (uint64_t)vpl_count * 16u, where);
        if (r == GIM_OK) {
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->para_samples);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)vpl_count * 16, texels);
            r = gim__gl_check(ctx, where);
        }
        if (r == GIM_OK) { ctx->para_key[0] = map_count; ctx->para_key[1] = size; ctx->para_key[2] = vpl_count; }
        gim__free(&ctx->env, texels);
    }
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gim__gl_nearest_sampler(ctx);
    textures[0] = ctx->para_position; textures[1] = ctx->para_normal; textures[2] = ctx->para_albedo;
    for (i = 0; i < 3; ++i) {
        gl->ActiveTexture(GIM__GL_TEXTURE0 + i);
        gl->BindTexture(GIM__GL_TEXTURE_2D_ARRAY, textures[i]);
        gl->BindSampler(i, ctx->nearest_sampler);
    }
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, maps_ssbo);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, ctx->para_samples);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, vpls_out);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, with_ism ? ism->maps : maps_ssbo);   /* never read without */
    gl->UseProgram(program);
    gl->Uniform1ui(0, vpl_count);
    gl->Uniform1ui(1, first);
    gl->Uniform1ui(2, size);
    gl->Uniform1ui(3, with_ism ? ism->size : 0u);
    gl->Uniform1f(4, with_ism ? (ism->bias > 0.0f ? ism->bias : GIM_ISM_BIAS) : 0.0f);
    gl->Uniform1f(5, with_ism ? (ism->slope > 0.0f ? ism->slope : GIM_ISM_SLOPE) * 2.0f / (float)ism->size : 0.0f);
    gl->Uniform1f(6, GIM_ISM_LIFT * scene_scale);
    gl->DispatchCompute((vpl_count + 63u) / 64u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* Second-bounce VPLs by rays on the GPU, the twin of gim_second_bounce_rays_twin on ctx->bvh
   (gim__gl_bvh: built for this scene) and the materials: the first vpl_count VPLs of vpls (gim_vpl,
   48 bytes) give count VPLs, written from VPL first on (first >= vpl_count): second_bounce_rays.comp,
   an invocation per ray. */
static gim_result gim__gl_second_bounce_rays(gim_context *ctx, gim__GLuint vpls, uint32_t vpl_count, uint32_t count,
                                             uint32_t first, float scene_scale) {
    static const char where[] = "second-bounce rays (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__vpl_gpu *v = &ctx->vpl;
    gim__GLuint program = 0;
    gim_result r = GIM_OK;
    if (!vpls) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "vpls is 0");
    if (vpl_count == 0 || vpl_count > GIM_SECOND_RAYS_MAX_VPLS || count == 0 || count > 65536u || first < vpl_count)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs (1..%u), %u rays (1..65536) from %u",
                         (unsigned)vpl_count, GIM_SECOND_RAYS_MAX_VPLS, (unsigned)count, (unsigned)first);
    if (!(scene_scale > 0.0f) || !gim__isfinitef(scene_scale))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale must be finite and > 0");
    if (!ctx->bvh.buffer || ctx->bvh.version != ctx->scene_version)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no hierarchy of this scene (gim__gl_bvh first)");
    if (((uint64_t)first + count) * 48u > (uint64_t)ctx->max_ssbo_bytes)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs exceed the SSBO limit", (unsigned)(first + count));
    gim__gl_enter(ctx, where);
    r = gim__gl_check_buffer(ctx, where, "vpls", vpls, ((uint64_t)first + count) * 48u);
    if (r == GIM_OK) r = gim__gl_program(ctx, GIM__PROGRAM_SECOND_BOUNCE_RAYS, &program);
    if (r == GIM_OK && (!v->ray_samples || v->ray_key != count)) {
        float *smp = (float *)gim__alloc_array(&ctx->env, count, 4u * sizeof(float));
        uint32_t j;
        v->ray_key = 0;
        if (!smp) r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_MEMORY, where, "%u ray samples", (unsigned)count);
        for (j = 0; j < count && smp; ++j) gim__second_ray_sample(j, smp + (size_t)j * 4u);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &v->ray_samples, &v->ray_samples_bytes, (uint64_t)count * 16u, where);
        if (r == GIM_OK) {
            gl->BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->ray_samples);
            gl->BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, (gim__GLsizeiptr)count * 16, smp);
            r = gim__gl_check(ctx, where);
        }
        if (r == GIM_OK) v->ray_key = count;
        gim__free(&ctx->env, smp);
    }
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, v->ray_samples);
    /* with no materials, binding 3 is never read (albedo 0) but must name a buffer */
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, ctx->materials ? ctx->materials : v->ray_samples);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 6, ctx->bvh.buffer);
    gl->UseProgram(program);
    gl->Uniform1ui(1, vpl_count);
    gl->Uniform1ui(2, count);
    gl->Uniform1ui(3, first);
    gl->Uniform1f(4, GIM_SECOND_RAY_LIFT * scene_scale);
    gl->Uniform1f(5, 4.0f / ctx->bvh.scale);
    gl->Uniform1ui(6, ctx->materials ? ctx->material_count : 0u);
    gl->Uniform1ui(17, ctx->bvh.nodes);
    gl->Uniform1ui(18, ctx->bvh.nodes * 2u);
    gl->Uniform3f(20, ctx->bvh.origin[0], ctx->bvh.origin[1], ctx->bvh.origin[2]);
    gl->Uniform1f(21, ctx->bvh.scale);
    gl->DispatchCompute((count + 255u) / 256u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
}

/* --- the frame's settings resolved ---------------------------------------------------------
   gim_update checks the host's frame, then resolves it once: every zero becomes its default
   (gim_frame_defaults), and every pass after that reads the resolved frame. */

GIMANY_DEF gim_frame gim_frame_defaults(gim_method method) {
    gim_frame f;
    int vplm = method == GIM_METHOD_CLUSTERED || method == GIM_METHOD_SSVP;
    memset(&f, 0, sizeof f);
    f.method = method == GIM_METHOD_DEFAULT ? GIM_METHOD_LIGHTSKIN_BRSM : method;
    f.visibility.mode = GIM_VISIBILITY_OFF;
    f.visibility.ism_size = GIM_ISM_DEFAULT_SIZE;   /* the VPL methods' too (their frame has always used it) */
    f.visibility.ism_points = vplm ? GIM_ISM_DEFAULT_VPL_POINTS : GIM_ISM_DEFAULT_POINTS;
    f.lightskin.val_count = GIM__DEFAULT_VAL_COUNT;
    f.lightskin.temporal_steps = GIM_DEFAULT_TEMPORAL_STEPS;   /* VALs kept from frame to frame */
    f.lightskin.view_sample_count = GIM__DEFAULT_VIEW_SAMPLES;
    f.lightskin.importance_clamp = GIM__IMPORTANCE_DEFAULT_CLAMP;
    f.lightskin.neighbour_count = GIM_MAX_NEIGHBOUR_CACHES;
    f.lightskin.importance_tile = GIM_DEFAULT_IMPORTANCE_TILE;
    f.lightskin.defensive_share = GIM_DEFAULT_DEFENSIVE_SHARE;
    f.lightskin.shade_block = GIM_DEFAULT_SHADE_BLOCK;
    f.gather.samples = GIM__GATHER_DEFAULT_SAMPLES;
    f.gather.radius = GIM__GATHER_DEFAULT_RADIUS;
    /* CLUSTERED: 2048 VPLs at interleave 4 (128 a pixel, a 4 x 4 blur) against 4096 at 8: the
       Cornell box 0.087 against 0.101, the street 0.257 against 0.316 (rel. MAE vs Embree) at
       1.0-1.3x the frame; SSVP keeps 4096 at 8 (its one-bounce error rose 0.105 -> 0.113). Either
       puts 80%+ of pixels within 20% of the closed forms (gltest_physics); 1024 at 8: 57-79% */
    f.vpl.count = method == GIM_METHOD_CLUSTERED ? 2048u : 4096u;
    f.vpl.cluster_count = method == GIM_METHOD_SSVP ? 8u : 30u;
    f.vpl.kmeans_iterations = 0u;   /* depends on the frame: 3 warm, 8 from seeds (gim__vpl_settings_of) */
    f.vpl.paraboloid_size = 256u;
    f.vpl.bounces = method == GIM_METHOD_SSVP ? 2u : 1u;
    f.vpl.second_bounce_vpls = 256u;
    f.vpl.second_bounce = GIM_SECOND_BOUNCE_RAYS;
    f.vpl.interleave = 0u;   /* depends on the view (gim_vpl_default_interleave) */
    f.vpl.clamp_distance = 0.01f;
    f.vpl.blur_distance = 0.1f;
    return f;
}

/* The default interleave (vpl.interleave 0) of a width x height view: the method's k_m at 720
   rows (of the shorter side) and more, in proportion below. A fixed 8 x 8 window spans a fifth
   of a 64x36 view, where the geometry-aware blur keeps few neighbours across columns and edges
   and a subset's k^2 weight stays (the atrium's SSVP + ISM + importance at 64x36: interleave 1
   0.380, 8 0.887 rel. MAE; at 160x90 0.408 / 0.454). Scaled, the window is about the share of
   the view it is at 720 rows, and since a pixel shades N / k^2 VPLs, rounding up keeps the
   frame's work at most 720 rows'. */
GIMANY_DEF uint32_t gim_vpl_default_interleave(gim_method method, uint32_t width, uint32_t height, uint32_t count) {
    uint32_t km = method == GIM_METHOD_CLUSTERED ? 4u : 8u, side = width < height ? width : height;
    uint64_t k = ((uint64_t)km * side + 719u) / 720u;   /* the smallest k of at most 720 rows' work */
    if (count == 0u) count = gim_frame_defaults(method).vpl.count;
    if (k > km) k = km;
    while (k > 1u && k * k > count) --k;
    return k > 1u ? (uint32_t)k : 1u;
}

/* `in` with every zero made its default (gim_frame_defaults of its method; the interleave by
   the view, gim_vpl_default_interleave); `in` checked. A negative clamp_distance (none) stays. */
static void gim__frame_resolve(const gim_frame *in, gim_frame *out) {
    gim_frame d = gim_frame_defaults(in->method);
    *out = *in;
#define GIM__RESOLVE(field) if (out->field == 0) out->field = d.field
    GIM__RESOLVE(method);
    GIM__RESOLVE(visibility.mode);
    GIM__RESOLVE(visibility.ism_size);
    GIM__RESOLVE(visibility.ism_points);
    GIM__RESOLVE(lightskin.val_count);
    GIM__RESOLVE(lightskin.temporal_steps);
    GIM__RESOLVE(lightskin.view_sample_count);
    GIM__RESOLVE(lightskin.importance_clamp);
    GIM__RESOLVE(lightskin.neighbour_count);
    GIM__RESOLVE(lightskin.importance_tile);
    GIM__RESOLVE(lightskin.defensive_share);
    GIM__RESOLVE(lightskin.shade_block);
    GIM__RESOLVE(gather.samples);
    GIM__RESOLVE(gather.radius);
    GIM__RESOLVE(vpl.count);
    GIM__RESOLVE(vpl.cluster_count);
    GIM__RESOLVE(vpl.paraboloid_size);
    GIM__RESOLVE(vpl.bounces);
    GIM__RESOLVE(vpl.second_bounce_vpls);
    GIM__RESOLVE(vpl.second_bounce);
    GIM__RESOLVE(vpl.clamp_distance);
    GIM__RESOLVE(vpl.blur_distance);
#undef GIM__RESOLVE
    if (out->vpl.interleave == 0u)
        out->vpl.interleave = gim_vpl_default_interleave(out->method, out->width, out->height, out->vpl.count);
}

/* --- the VPL frame (CLUSTERED, SSVP) ----------------------------------------------------------
   Dong et al. 2009 and SSVP (Aranha et al.) on the shared passes: per light VPLs from its
   RSM (rsm_vpls.comp) copied one light after the other -> k-means on the GPU (warm from the
   last frame's centres, or seeded every frame: gim_frame.vpl.kmeans_restart) -> the clusters' VALs and
   paraboloid parameters (clusters.comp) -> a layered pass of paraboloid maps for each of
   visibility (distance) and the second bounce (position, normal, albedo), each with its own
   near skip -> second-bounce VPLs -> per
   pixel shading of every VPL (interleaved) with its cluster's soft visibility -> the
   geometry-aware blur. Only what the frame enables is made: no maps without visibility or a
   second bounce, no attribute maps at one bounce, no blur buffer without interleaving. */

#define GIM__VPL_MAX 32768u       /* first-bounce VPLs of all lights: one loop of clusters.comp */
#define GIM__VPL_MAX_CLUSTERS 256u
#define GIM__VPL_MAX_SECOND 65536u

static void gim__vpl_release(gim_context *ctx) {
    gim__vpl_gpu *v = &ctx->vpl;
    gim__GLuint b[8];
    b[0] = v->vpls; b[1] = v->staging; b[2] = v->cluster_of; b[3] = v->centres; b[4] = v->maps;
    b[5] = v->texels; b[6] = v->sums; b[7] = v->kmeans_acc;
    ctx->gl.DeleteBuffers(8, b);
    if (v->made) ctx->gl.DeleteBuffers(1, &v->made);
    if (v->ray_samples) ctx->gl.DeleteBuffers(1, &v->ray_samples);
    memset(v, 0, sizeof *v);
    gim__vpl_raw_release(ctx);
    gim__paraboloid_release(ctx, 1);
    if (ctx->vpl_partial) ctx->gl.DeleteBuffers(1, &ctx->vpl_partial);
    ctx->vpl_partial = 0;
    ctx->vpl_partial_bytes = 0;
}

/* The settings of a resolved VPL frame (gim__frame_resolve), as the passes use them. */
typedef struct gim__vpl_settings {
    int ssvp, visibility, restart;
    int second_ism;   /* SSVP's second bounce beside the clusters' paraboloid maps: one ISM per second-bounce VPL */
    int second_rays;  /* the second bounce by rays (vpl.second_bounce_rays), not from attribute maps */
    uint32_t vpls, clusters, iterations, size, bounces, second, interleave;
    float clamp_distance, blur_distance;   /* in scene scales (clamp 0: none) */
} gim__vpl_settings;

static void gim__vpl_settings_of(const gim_frame *f, gim__vpl_settings *s) {
    s->ssvp = f->method == GIM_METHOD_SSVP;
    s->visibility = !f->vpl.no_visibility;
    s->vpls = f->vpl.count;
    s->clusters = f->vpl.cluster_count;
    s->restart = f->vpl.kmeans_restart != 0;
    /* 0 (the default): 3 steps from the last frame's centres; from seeds (restart, or a cold
       start) gim__gl_vpl_frame takes 8 */
    s->iterations = f->vpl.kmeans_iterations ? f->vpl.kmeans_iterations : s->restart ? 8u : 3u;
    s->size = f->vpl.paraboloid_size;
    s->bounces = f->vpl.bounces;
    s->second = s->bounces == 2u ? f->vpl.second_bounce_vpls : 0u;
    s->second_ism = f->visibility.mode != GIM_VISIBILITY_ISM && f->visibility.mode != GIM_VISIBILITY_SHADOW_MAPS &&
                    s->visibility && s->second > 0u;
    s->second_rays = s->second > 0u && f->vpl.second_bounce == GIM_SECOND_BOUNCE_RAYS;
    s->interleave = f->vpl.interleave;
    s->clamp_distance = f->vpl.clamp_distance < 0.0f ? 0.0f : f->vpl.clamp_distance;
    s->blur_distance = f->vpl.blur_distance;
}

/* First-bounce VPLs of a frame with `lights` rendered RSMs: vpl_count each (per_light_budget),
   or vpl_count in all, at least one per RSM. */
static uint32_t gim__vpl_first(const gim_frame *f, const gim__vpl_settings *s, uint32_t lights) {
    if (f->per_light_budget) return s->vpls * lights;
    return s->vpls > lights ? s->vpls : lights;
}

/* The share of the k-th of `lights` rendered RSMs: vpl_count split evenly (the VPL methods have
   no importance to split it by; each RSM's VPLs weigh 1 / its count, so the sum stays
   unbiased), the remainder one each to the first ones. */
static uint32_t gim__vpl_share(const gim_frame *f, const gim__vpl_settings *s, uint32_t lights, uint32_t k) {
    if (f->per_light_budget) return s->vpls;
    if (s->vpls <= lights) return 1u;
    return s->vpls / lights + (k < s->vpls % lights ? 1u : 0u);
}

/* The VPL fields of a frame, checked before any GL work (lights: the context's count); f as
   the host wrote it, rf resolved (gim__frame_resolve). */
static gim_result gim__vpl_check(gim_context *ctx, const gim_frame *f, const gim_frame *rf) {
    static const char where[] = "gim_update";
    gim__vpl_settings s;
    uint32_t lights = ctx->light_count ? ctx->light_count : 1u;
    if (!gim__isfinitef(f->vpl.clamp_distance) || !gim__isfinitef(f->vpl.blur_distance) || f->vpl.blur_distance < 0.0f)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "clamp_distance and blur_distance must be finite "
                         "(blur_distance >= 0)");
    if (f->vpl.importance != 0 && f->vpl.importance != 1)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "vpl.importance %d: 0 or 1", f->vpl.importance);
    if ((int)f->vpl.second_bounce < 0 || (int)f->vpl.second_bounce > (int)GIM_SECOND_BOUNCE_MAPS)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "vpl.second_bounce %d: DEFAULT, RAYS or MAPS",
                         (int)f->vpl.second_bounce);
    if (f->method != GIM_METHOD_CLUSTERED && f->method != GIM_METHOD_SSVP) return GIM_OK;
    gim__vpl_settings_of(rf, &s);
    if ((uint64_t)s.vpls * (f->per_light_budget ? lights : 1u) > GIM__VPL_MAX || lights > GIM__VPL_MAX)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u VPLs%s x %u lights above %u", (unsigned)s.vpls,
                         f->per_light_budget ? " per light" : "", (unsigned)lights, GIM__VPL_MAX);
    if (s.clusters > GIM__VPL_MAX_CLUSTERS || s.clusters > gim__vpl_first(f, &s, lights))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "cluster_count %u: at most %u and at most the VPLs (%u)",
                         (unsigned)s.clusters, GIM__VPL_MAX_CLUSTERS, (unsigned)gim__vpl_first(f, &s, lights));
    if (s.iterations > 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "kmeans_iterations %u above 64", (unsigned)s.iterations);
    if (s.size > 2048u || s.size > (uint32_t)ctx->max_texture_size || s.size > (uint32_t)ctx->max_viewport[0] ||
        s.size > (uint32_t)ctx->max_viewport[1])
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "paraboloid_size %u above 2048 or the GL limits",
                         (unsigned)s.size);
    if (s.bounces > 2u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "bounces %u: 1 or 2", (unsigned)s.bounces);
    if (s.second > GIM__VPL_MAX_SECOND)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "second_bounce_vpls %u above %u", (unsigned)s.second,
                         GIM__VPL_MAX_SECOND);
    if (s.interleave > 32u || s.interleave * s.interleave > gim__vpl_first(f, &s, lights) + s.second)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "interleave %u: at most 32, and k^2 at most the VPLs",
                         (unsigned)s.interleave);
    return GIM_OK;
}

/* The k-means seeds (mode 1), the repair of empty clusters (mode 2: one dispatch per cluster,
   each a single invocation that does nothing unless its cluster is empty) or the clusters' VALs
   and paraboloid parameters (mode 0, the twin of gim_cluster_paraboloids_twin): clusters.comp on
   ctx->vpl's buffers. */
static gim_result gim__gl_clusters(gim_context *ctx, uint32_t vpl_count, uint32_t cluster_count, float scale, uint32_t mode) {
    static const char where[] = "clusters (GL)";
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_result r = gim__gl_program(ctx, GIM__PROGRAM_CLUSTERS, &program);
    if (r != GIM_OK) return r;
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 0, ctx->vpl.vpls);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 1, ctx->vpl.centres);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, ctx->vpl.cluster_of);
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 3, ctx->vpl.maps);
    gl->UseProgram(program);
    gl->Uniform1ui(0, vpl_count);
    gl->Uniform1ui(1, cluster_count);
    gl->Uniform1f(2, scale);
    gl->Uniform1ui(3, mode);
    if (mode == 2u) {
        uint32_t e;
        for (e = 0; e < cluster_count; ++e) {
            gl->Uniform1ui(4, e);
            gl->DispatchCompute(1u, 1u, 1u);
            gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
        }
    } else {
        gl->DispatchCompute((cluster_count + 63u) / 64u, 1u, 1u);
    }
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT | GIM__GL_BUFFER_UPDATE_BARRIER_BIT);
    return gim__gl_check(ctx, where);
}

/* Every VPL's cluster (count) reset to none (0xffffffff): the k-means' first assignment, and
   the second bounce's "no cluster" (their own ISMs shadow them); on the GPU, no upload. A
   dispatch of kmeans_assign.comp's reset mode, not glClearBufferData: that reads its clear
   value from client memory under the host's unpack pixel store (Mesa applies the skips), which
   gimany would then have to save and set (8 GL queries a call). */
static gim_result gim__gl_clusters_reset(gim_context *ctx, uint32_t count) {
    const gim__gl *gl = &ctx->gl;
    gim__GLuint program = 0;
    gim_result r;
    if (count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, "gim_update", "%u VPLs above the dispatch limit",
                         (unsigned)count);
    r = gim__gl_program(ctx, GIM__PROGRAM_KMEANS_ASSIGN, &program);
    if (r != GIM_OK) return r;
    gl->BindBufferBase(GIM__GL_SHADER_STORAGE_BUFFER, 2, ctx->vpl.cluster_of);
    gl->UseProgram(program);
    gl->Uniform1ui(0, count);
    gl->Uniform1ui(5, 1u);
    gl->DispatchCompute((count + 63u) / 64u, 1u, 1u);
    gl->MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
    return gim__gl_check(ctx, "gim_update");
}

/* FNV-1a over n bytes, continuing from h. */
static uint64_t gim__fnv64(uint64_t h, const void *p, size_t n) {
    const unsigned char *b = (const unsigned char *)p;
    size_t i;
    for (i = 0; i < n; ++i) h = (h ^ b[i]) * 1099511628211ull;
    return h;
}

/* What the first-bounce VPLs' maps depend on: the scene (its version), every rendered RSM's
   side and (cameras 1) camera (the VPLs' texels, positions and normals; not the light's colour
   or power), the VPL counts and sequence, and the maps' settings. Never 0. */
static uint64_t gim__vpl_ism_key(const gim_context *ctx, uint32_t first, uint32_t total, uint32_t size, uint32_t per,
                                 float scale, int ssvp, int cameras) {
    uint64_t h = 14695981039346656037ull;
    uint32_t u[6], i;
    u[0] = first; u[1] = total; u[2] = size; u[3] = per; u[4] = (uint32_t)ssvp; u[5] = ctx->light_count;
    h = gim__fnv64(h, &ctx->scene_version, sizeof ctx->scene_version);
    h = gim__fnv64(h, u, sizeof u);
    h = gim__fnv64(h, &scale, sizeof scale);
    for (i = 0; i < ctx->light_count; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        h = gim__fnv64(h, &ctx->light_on[i], sizeof ctx->light_on[i]);
        if (!ctx->light_on[i]) continue;
        h = gim__fnv64(h, &g->size, sizeof g->size);
        if (!cameras) continue;
        h = gim__fnv64(h, g->view.m, sizeof g->view.m);
        h = gim__fnv64(h, g->proj.m, sizeof g->proj.m);
    }
    return h ? h : 1u;
}

/* What makes the first-bounce VPLs of the last frame the ones to follow (incremental instant
   radiosity, Laine et al. 2007: gim_rsm_vpls_desc.previous) slot for slot: the scene (its
   version: a moved instance moves the points the VPLs stand on and their maps), the lights that
   rendered an RSM and its side, the VPLs per RSM and their sequence. Not the cameras, which the
   follow test looks through. Never 0. */
static uint64_t gim__vpl_follow_key(const gim_context *ctx, const gim_frame *f, const gim__vpl_settings *s) {
    uint64_t h = 14695981039346656037ull;
    uint32_t i, k, n, u[2];
    u[0] = (uint32_t)s->ssvp; u[1] = ctx->light_count;
    h = gim__fnv64(h, &ctx->scene_version, sizeof ctx->scene_version);
    h = gim__fnv64(h, u, sizeof u);
    for (i = 0, k = 0; i < ctx->light_count; ++i) {
        h = gim__fnv64(h, &ctx->light_on[i], sizeof ctx->light_on[i]);
        if (!ctx->light_on[i]) continue;
        n = gim__vpl_share(f, s, ctx->light_on_count, k++);
        h = gim__fnv64(h, &ctx->light_gpu[i].size, sizeof ctx->light_gpu[i].size);
        h = gim__fnv64(h, &n, sizeof n);
    }
    return h ? h : 1u;
}

static gim_result gim__gl_brsm_select(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                      float scale, const gim__vpl_settings *vpls);

static gim_result gim__gl_vpl_frame(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal, float scale,
                                    gim_frame_outputs *o, gim_debug_outputs *dbg) {
    static const char where[] = "gim_update";
    gim__vpl_gpu *v = &ctx->vpl;
    gim__vpl_settings s;
    uint32_t i, k, off, first, total, it, iterations, ism_size = f->visibility.ism_size;
    gim_result r = GIM_OK;
    uint32_t ism_per = f->visibility.ism_points;
    uint32_t ism_pool = gim__ism_pool(ism_per);
    /* ism: a map per VPL, of points (ISM) or of the triangles (tri, SHADOW_MAPS) */
    int warm, last, follow, tri = f->visibility.mode == GIM_VISIBILITY_SHADOW_MAPS,
        ism = f->visibility.mode == GIM_VISIBILITY_ISM || tri;
    uint64_t follow_key, had_bytes;
    gim__GLuint had;
    gim__vpl_settings_of(f, &s);
    if (ctx->light_on_count == 0) { gim__vpl_release(ctx); return GIM_OK; }   /* no light: nothing to bounce */
    first = gim__vpl_first(f, &s, ctx->light_on_count);
    total = first + s.second;
    if (s.clusters > first || s.interleave * s.interleave > total)   /* fewer VPLs than checked: lights were culled */
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "%u of %u lights reach the scene: %u VPLs, below "
                         "cluster_count %u or interleave^2 %u", (unsigned)ctx->light_on_count, (unsigned)ctx->light_count,
                         (unsigned)total, (unsigned)s.clusters, (unsigned)(s.interleave * s.interleave));
    /* first-bounce VPLs, one light after the other; the last frame's followed where they are
       still the same VPLs' (incremental instant radiosity, Laine et al. 2007; vpl.redraw 1: not) */
    follow_key = gim__vpl_follow_key(ctx, f, &s);
    had = v->vpls;
    had_bytes = v->vpls_bytes;
    r = gim__gl_sized_buffer(ctx, &v->vpls, &v->vpls_bytes, (uint64_t)total * 48u, where);
    last = r == GIM_OK && had && had_bytes == v->vpls_bytes;   /* not remade: its slots hold the last frame's VPLs */
    follow = last && !f->vpl.redraw && !f->vpl.importance && follow_key == v->follow_key;
    v->follow_key = 0;
    if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &v->cluster_of, &v->cluster_of_bytes, (uint64_t)total * 4u, where);
    if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &v->centres, &v->centres_bytes, (uint64_t)s.clusters * 32u, where);
    if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &v->maps, &v->maps_bytes, (uint64_t)s.clusters * 48u, where);
    /* the staging buffer of the lights' VPLs drawn one after the other (not with importance) */
    if (r == GIM_OK && ctx->light_on_count > 1u && !f->vpl.importance)
        r = gim__gl_sized_buffer(ctx, &v->staging, &v->staging_bytes,
                                 (uint64_t)gim__vpl_share(f, &s, ctx->light_on_count, 0u) * 48u, where);
    if (r == GIM_OK && (ctx->light_on_count == 1u || f->vpl.importance) && v->staging) {
        ctx->gl.DeleteBuffers(1, &v->staging);
        v->staging = 0; v->staging_bytes = 0;
    }
    if (r == GIM_OK && f->vpl.importance) {
        /* drawn by BRSM's importance (vpl.importance): each light's even share of the VPLs picked
           from its eq. 12 tables, written as VPLs weighing 1 / (N P) (gim_vpls_from_vals); with
           the last frame's VPLs in the slots, a pick on the same point is flagged kept */
        r = gim__gl_brsm_select(ctx, f, depth, normal, scale, &s);
        for (i = 0, off = 0; i < ctx->light_count && r == GIM_OK; ++i) {
            const gim__light_gpu *g = &ctx->light_gpu[i];
            if (!ctx->light_on[i] || !ctx->light_vals[i]) continue;
            r = gim__gl_vals_gather_as(ctx, g->position, g->normal, g->flux, g->size, g->selected, ctx->light_vals[i],
                                       v->vpls, off, last ? 2 : 1);
            off += ctx->light_vals[i];
        }
        dbg->view_samples = ctx->view_samples;
        dbg->view_sample_count = f->lightskin.view_sample_count;
    }
    for (i = 0, k = 0, off = 0; i < ctx->light_count && r == GIM_OK && !f->vpl.importance; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        gim_mat4 vp;
        uint32_t n;
        if (!ctx->light_on[i]) continue;   /* culled: an empty RSM */
        n = gim__vpl_share(f, &s, ctx->light_on_count, k++);
        if (follow) vp = gim_mat4_mul(g->proj, g->view);
        if (follow && ctx->light_on_count > 1u) {   /* this light's VPLs of the last frame, to follow in place */
            ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, v->vpls);
            ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->staging);
            ctx->gl.CopyBufferSubData(GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_WRITE_BUFFER,
                                      (gim__GLintptr)((uint64_t)off * 48u), 0, (gim__GLsizeiptr)n * 48);
            ctx->gl.MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
        }
        r = gim__gl_rsm_vpls_follow(ctx, g->position, g->normal, g->flux, g->size, n,
                                    s.ssvp ? GIM_VPL_SEQUENCE_HAMMERSLEY : GIM_VPL_SEQUENCE_HALTON, NULL,
                                    ctx->light_on_count > 1u ? v->staging : v->vpls, follow ? &vp : NULL);
        if (r == GIM_OK && ctx->light_on_count > 1u) {
            ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, v->staging);
            ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->vpls);
            ctx->gl.CopyBufferSubData(GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_WRITE_BUFFER, 0,
                                      (gim__GLintptr)((uint64_t)off * 48u), (gim__GLsizeiptr)n * 48);
            r = gim__gl_check(ctx, where);
        }
        off += n;
    }
    if (r == GIM_OK && !f->vpl.importance) v->follow_key = follow_key;
    gim__stamp(ctx, f->timing, GIM_PASS_VPLS);
    /* k-means (Dong 5; SSVP 3.B) and the clusters' VALs */
    warm = !s.restart && v->warm_clusters == s.clusters && v->warm_vpls == first && v->warm_metric == 1u + (uint32_t)s.ssvp;
    if (r == GIM_OK) r = gim__gl_clusters_reset(ctx, total);
    if (r == GIM_OK && !warm) r = gim__gl_clusters(ctx, first, s.clusters, scale, 1u);
    iterations = warm || s.iterations >= 8u || f->vpl.kmeans_iterations ? s.iterations : 8u;   /* from seeds: 8 at least */
    for (it = 0; it < iterations && r == GIM_OK; ++it) {   /* each step, then the empty clusters repaired */
        r = gim__gl_kmeans_step(ctx, v->vpls, first, v->centres, s.clusters, v->cluster_of,
                                s.ssvp ? GIM_KMEANS_METRIC_SSVP : GIM_KMEANS_METRIC_DONG, 0.0f, 0.0f, scale);
        if (r == GIM_OK) r = gim__gl_clusters(ctx, first, s.clusters, scale, 2u);
    }
    if (r == GIM_OK) r = gim__gl_clusters(ctx, first, s.clusters, scale, 0u);
    v->warm_clusters = r == GIM_OK ? s.clusters : 0u;
    v->warm_vpls = r == GIM_OK ? first : 0u;
    v->warm_metric = r == GIM_OK ? 1u + (uint32_t)s.ssvp : 0u;
    gim__stamp(ctx, f->timing, GIM_PASS_KMEANS);
    if (r != GIM_OK) return r;
    /* the paraboloid maps (Dong 4.2; SSVP 3.C): depth for visibility (not with ISMs), attributes
       for the second bounce */
    if ((s.visibility && !ism) || (s.second && !s.second_rays)) {
        r = gim__gl_paraboloids(ctx, v->maps, s.clusters, s.size,
                                !s.second || s.second_rays ? GIM__PARA_DISTANCE
                                : s.visibility && !ism     ? GIM__PARA_BOTH
                                                           : GIM__PARA_ATTRIBUTES,
                                scale);
        gim__stamp(ctx, f->timing, GIM_PASS_PARABOLOID);
    } else {
        gim__paraboloid_release(ctx, 1);
    }
    if (r == GIM_OK && ((ism && !tri) || s.second_ism || (tri && s.second && !s.second_rays))) {
        /* the scene's points for the imperfect shadow maps (Ritschel et al. 2008), made again
           only when the scene changed; the maps take ctx->ism_maps (a LightSkin frame after
           this one makes its caches' again: ism_size 0 says they are not theirs) */
        if (!ctx->ism_points || ctx->ism_version != ctx->scene_version || ctx->ism_point_count != ism_pool) {
            ctx->ism_version = ctx->scene_version - 1u;
            r = gim__gl_ism_scene_points(ctx, ism_pool, where);
            if (r == GIM_OK) { ctx->ism_version = ctx->scene_version; ctx->ism_point_count = ism_pool; }
        }
        ctx->ism_size = 0;
    }
    if (r == GIM_OK && s.second_rays) {
        /* rays from the first-bounce VPLs through the scene's hierarchy (made again only when
           the scene changed) */
        if (!ctx->bvh.buffer || ctx->bvh.version != ctx->scene_version) r = gim__gl_bvh(ctx, where);
        if (r == GIM_OK) r = gim__gl_second_bounce_rays(ctx, v->vpls, first, s.second, first, scale);
        gim__stamp(ctx, f->timing, GIM_PASS_SECOND_BOUNCE);
    } else if (ctx->bvh.buffer) {
        gim__bvh_release(ctx);
    }
    if (r == GIM_OK && s.second && !s.second_rays) {
        gim__gl_ism gi;
        memset(&gi, 0, sizeof gi);
        if (ism) {   /* each cluster's ISM: the hits its paraboloid map found past its near skip, checked */
            r = gim__gl_upload(ctx, &ctx->ism_cluster_maps, &ctx->ism_cluster_maps_bytes, NULL,
                               (uint64_t)s.clusters * ism_size * ism_size * 2u, where);   /* 16 bits a texel */
            if (r == GIM_OK)
                r = gim__gl_ism_render_of(ctx, v->maps, 3u, 0u, 0u, s.clusters, ctx->ism_points, ism_pool, ism_size,
                                          ism_per, scale, ctx->ism_cluster_maps);
            gi.maps = ctx->ism_cluster_maps;
            gi.size = ism_size;
            gi.bias = GIM_ISM_VPL_BIAS;
            gi.slope = GIM_ISM_VPL_SLOPE;
        }
        if (r == GIM_OK) r = gim__gl_second_bounce_ism(ctx, v->maps, s.clusters, s.size, s.second, v->vpls, first, &gi, scale);
        gim__stamp(ctx, f->timing, GIM_PASS_SECOND_BOUNCE);
    }
    if (r == GIM_OK && (ism || s.second_ism)) {
        /* one imperfect shadow map per VPL, both bounces (Keller's instant radiosity with
           Ritschel et al.'s maps). With the clusters' paraboloid maps (s.second_ism), only the
           second bounce's: no cluster's map sees from where they lie. A first-bounce VPL kept
           from the last frame (follow) keeps its map (incremental instant radiosity, Laine et
           al. 2007): ism.comp skips it and counts the maps it makes. While the scene and every
           rendered RSM's camera stay (and the VPLs are followed, or drawn at their texels, as in
           the last frame), they are the last frame's VPLs and their maps are kept without a
           dispatch. The second
           bounce's follow the clusters and are made every frame. Their time is
           GIM_PASS_PARABOLOID's. */
        uint32_t from = s.second_ism ? first : 0u, make = from;
        uint64_t key = ism && !f->vpl.importance   /* importance: the view moves the picks; kept flags below */
                           ? gim__vpl_ism_key(ctx, first, total, ism_size, tri ? 0u : ism_per, scale, s.ssvp, 1) ^ (uint64_t)follow : 0u;
        uint64_t layout = ism ? gim__vpl_ism_key(ctx, first, total, ism_size, tri ? 0u : ism_per, scale, s.ssvp, 0) : 0u;
        uint64_t had_maps = ctx->ism_maps_bytes;
        gim__GLuint name = ctx->ism_maps, made = 0;
        int same, keep = 0;
        r = gim__gl_upload(ctx, &ctx->ism_maps, &ctx->ism_maps_bytes, NULL,
                           (uint64_t)(total - from) * ism_size * ism_size * 2u, where);
        same = r == GIM_OK && name == ctx->ism_maps && had_maps == ctx->ism_maps_bytes;
        if (same && key && key == ctx->ism_vpl_key)
            make = first - first % gim__ism_align_maps(ctx, ism_size);   /* kept: [0, make) */
        else if (same && (follow || f->vpl.importance) && layout && layout == ctx->ism_vpl_layout)
            keep = 1;   /* the maps of the VPLs flagged kept (followed, or picked at the same point again) */
        if (r == GIM_OK && make < total) {
            /* the maps made are counted on the GPU: a running count (zeroed once, when the buffer is
               made) and, copied there on the GPU before this frame's, what it was; no upload a frame */
            static const uint32_t zero[2] = {0u, 0u};
            int fresh = v->made_bytes == 0;
            r = gim__gl_sized_buffer(ctx, &v->made, &v->made_bytes, 8u, where);
            if (r == GIM_OK && fresh) {
                ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->made);
                ctx->gl.BufferSubData(GIM__GL_COPY_WRITE_BUFFER, 0, 8, zero);
            }
            if (r == GIM_OK) {
                ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, v->made);
                ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, v->made);
                ctx->gl.CopyBufferSubData(GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_WRITE_BUFFER, 0, 4, 4);
                ctx->gl.MemoryBarrier(GIM__GL_SHADER_STORAGE_BARRIER_BIT);
                made = v->made;
            }
        }
        ctx->ism_vpl_key = 0;
        ctx->ism_vpl_layout = 0;
        if (r == GIM_OK && make < total && tri)
            r = gim__gl_vpl_shadow_maps(ctx, v->vpls, from, make - from, total - make, ism_size, scale, ctx->ism_maps, made,
                                        keep);
        else if (r == GIM_OK && make < total)
            r = gim__gl_ism_render_ex(ctx, v->vpls, 3u, from, make - from, total - make, ctx->ism_points, ism_pool,
                                      ism_size, ism_per, scale, ctx->ism_maps, made, keep);
        if (r == GIM_OK) {
            ctx->ism_vpl_key = key;
            ctx->ism_vpl_layout = layout;
            ctx->ism_made_counted = made != 0u;
        }
        gim__stamp(ctx, f->timing, GIM_PASS_PARABOLOID);
    } else if (ctx->ism_maps || ctx->ism_points || ctx->ism_cluster_maps) {
        gim__ism_release(ctx);
    }
    if (r == GIM_OK && ism && (!s.second || s.second_rays) && ctx->ism_cluster_maps) {
        ctx->gl.DeleteBuffers(1, &ctx->ism_cluster_maps);
        ctx->ism_cluster_maps = 0;
        ctx->ism_cluster_maps_bytes = 0;
    }
    if (r != GIM_OK) return r;
    /* shading (Dong 6; SSVP eq. 6 with each bounce's own normalisation), then the blur */
    {
        gim__GLenum format = f->indirect_float32 ? GIM__GL_RGBA32F : GIM__GL_RGBA16F;
        gim__vpl_shade_args a;
        gim__blur_args b;
        int blur = s.interleave > 1u;
        gim__gl_indirect_texture(ctx, f->width, f->height, format);
        if (blur) gim__gl_vpl_raw_texture(ctx, f->width, f->height, GIM__GL_RGBA32F);   /* full precision to blur */
        else gim__vpl_raw_release(ctx);   /* k = 1: no blur, nothing between */
        memset(&a, 0, sizeof a);
        a.depth = depth;
        a.normal = normal;
        a.albedo = f->gbuffer.depth ? 0u : ctx->gbuffer_albedo;
        a.material = f->gbuffer.depth ? 0u : ctx->gbuffer_material;
        a.width = f->width;
        a.height = f->height;
        a.view = f->view;
        a.proj = f->proj;
        a.vpls = v->vpls;
        a.vpl_count = total;
        a.cluster = s.visibility && !ism ? v->cluster_of : 0u;
        a.maps = v->maps;
        a.map_count = s.clusters;
        a.distance = s.visibility && !ism ? ctx->para_distance : 0u;
        a.ism = ism || s.second_ism ? ctx->ism_maps : 0u;
        a.ism_first = s.second_ism ? first : 0u;
        a.ism_size = ism_size;
        a.ism_bias = tri ? GIM_VPL_SHADOW_MAP_BIAS : GIM_ISM_VPL_BIAS;
        a.ism_slope = GIM_ISM_VPL_SLOPE;
        a.map_size = s.size;
        a.interleave = s.interleave;
        a.clamp_distance = s.clamp_distance * scale;
        a.scene_scale = scale;
        a.output = blur ? ctx->vpl_raw : ctx->indirect;
        a.format = blur ? (gim__GLenum)GIM__GL_RGBA32F : format;
        r = gim__gl_vpl_shade(ctx, &a);
        gim__stamp(ctx, f->timing, GIM_PASS_SHADE);
        if (r == GIM_OK && blur) {
            memset(&b, 0, sizeof b);
            b.depth = depth;
            b.normal = normal;
            b.albedo = a.albedo;
            b.material = a.material;
            b.width = f->width;
            b.height = f->height;
            b.view = f->view;
            b.proj = f->proj;
            b.input = ctx->vpl_raw;
            b.window = s.interleave;
            b.position_tolerance = s.blur_distance * scale;
            b.normal_tolerance = 0.8f;
            b.output = ctx->indirect;
            b.format = format;
            r = gim__gl_geometry_blur(ctx, &b);
            gim__stamp(ctx, f->timing, GIM_PASS_BLUR);
        }
        if (r != GIM_OK) return r;
    }
    o->indirect = ctx->indirect;
    dbg->vpls = v->vpls;
    dbg->vpl_count = total;
    dbg->first_bounce_count = first;
    dbg->vpl_clusters = v->cluster_of;
    dbg->clusters = v->maps;
    dbg->cluster_count = s.clusters;
    dbg->kmeans_centres = v->centres;
    dbg->paraboloid_size = s.size;
    dbg->paraboloid_distance = ctx->para_distance;
    dbg->paraboloid_position = ctx->para_position;
    dbg->paraboloid_normal = ctx->para_normal;
    dbg->paraboloid_albedo = ctx->para_albedo;
    dbg->ism_maps = ism || s.second_ism ? ctx->ism_maps : 0u;
    dbg->ism_size = ism || s.second_ism ? ism_size : 0u;
    return GIM_OK;
}

/* The frame's own fields and the instances, before any GL work, with the world bounds into
   bmin, bmax. f as the host wrote it (an explicit value is checked as given where a zero may
   be resolved to something else), rf the same frame resolved (gim__frame_resolve): the checks
   resolve nothing themselves. */
static gim_result gim__frame_check(gim_context *ctx, const gim_frame *f, const gim_frame *rf, float bmin[3],
                                   float bmax[3]) {
    static const char where[] = "gim_update";
    gim_mat4 inv;
    uint32_t i, limit;
    if (!gim__mat4_isfinite(f->view) || !gim__mat4_isfinite(f->proj) || !gim_mat4_invert(f->view, &inv) ||
        !gim_mat4_invert(f->proj, &inv))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view or proj is not finite or singular");
    limit = (uint32_t)ctx->max_texture_size;
    if (f->width == 0 || f->height == 0 || f->width > limit || f->height > limit ||
        f->width > (uint32_t)ctx->max_viewport[0] || f->height > (uint32_t)ctx->max_viewport[1])
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "size %ux%u outside 1..GL limits (%d, viewport %dx%d)",
                         (unsigned)f->width, (unsigned)f->height, (int)ctx->max_texture_size, (int)ctx->max_viewport[0],
                         (int)ctx->max_viewport[1]);
    if ((f->gbuffer.depth == 0) != (f->gbuffer.normal == 0))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "gbuffer_depth and gbuffer_normal: both or neither");
    if ((unsigned)f->gbuffer.normal_encoding > (unsigned)GIM_NORMAL_OCTAHEDRAL_UNORM)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown gbuffer_normal_encoding %d",
                         (int)f->gbuffer.normal_encoding);
    if (!f->gbuffer.depth && (f->gbuffer.normal_encoding != GIM_NORMAL_XYZ || f->gbuffer.view_space || f->gbuffer.depth_view_z))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "gbuffer_normal_encoding, gbuffer_view_space and "
                         "gbuffer_depth_view_z describe the host's G-buffer: none is given");
    if (f->lightskin.view_sample_count > GIM__MAX_VIEW_SAMPLES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "view_sample_count %u above %u",
                         (unsigned)f->lightskin.view_sample_count, GIM__MAX_VIEW_SAMPLES);
    if (f->lightskin.val_count > 65535u * 64u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "val_count %u above %u", (unsigned)f->lightskin.val_count,
                         65535u * 64u);
    if (f->lightskin.temporal_steps > GIM_MAX_TEMPORAL_STEPS)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "temporal_steps %u above %u",
                         (unsigned)f->lightskin.temporal_steps, GIM_MAX_TEMPORAL_STEPS);
    if (!gim__isfinitef(f->scene_scale) || f->scene_scale < 0.0f || !gim__isfinitef(f->lightskin.importance_clamp) ||
        f->lightskin.importance_clamp < 0.0f)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "scene_scale and importance_clamp: finite, >= 0");
    if (f->method != GIM_METHOD_DEFAULT && f->method != GIM_METHOD_LIGHTSKIN_BRSM && f->method != GIM_METHOD_LIGHTSKIN_FULL &&
        f->method != GIM_METHOD_RSM_GATHER && f->method != GIM_METHOD_CLUSTERED && f->method != GIM_METHOD_SSVP)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown method %d", (int)f->method);
    {
        gim_result r = gim__vpl_check(ctx, f, rf);
        if (r != GIM_OK) return r;
    }
    if (f->gather.samples > 16384u || !gim__isfinitef(f->gather.radius) || f->gather.radius < 0.0f || f->gather.radius > 2.0f)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "gather_samples at most 16384, gather_radius in [0, 2]");
    if (!gim__isfinitef(f->view_distance) || f->view_distance < 0.0f)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "view_distance must be finite and >= 0");
    if (f->timing < 0 || f->timing > 2)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "timing %d: 0 (off), 1 (GL timestamps) or 2 (glFinish and the CPU clock)", f->timing);
    if (f->lightskin.importance_tile > GIM_MAX_IMPORTANCE_TILE)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "importance_tile %u above %d",
                         (unsigned)f->lightskin.importance_tile, GIM_MAX_IMPORTANCE_TILE);
    if (!gim__isfinitef(f->lightskin.defensive_share) || f->lightskin.defensive_share > 0.5f)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "defensive_share %g: in (0, 0.5], negative for none, 0 for the default",
                         (double)f->lightskin.defensive_share);
    if (f->lightskin.neighbour_count > GIM_MAX_NEIGHBOUR_CACHES)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "neighbour_count %u above %d", (unsigned)f->lightskin.neighbour_count,
                         GIM_MAX_NEIGHBOUR_CACHES);
    if (f->lightskin.shade_block > 2)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "shade_block %u: 1 (per pixel) or 2 (2 x 2 blocks)",
                         (unsigned)f->lightskin.shade_block);
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

/* The map side of a frame: f->ism_size, or the default halved until caches maps of 16 bits a
   texel fit GIM_ISM_BUDGET_BYTES (never below GIM_ISM_MIN_SIZE). The passes split the maps over
   storage blocks (gim__ism_block_maps), so the budget is one of memory, not of the GL. */
static uint32_t gim__ism_frame_size(const gim_frame *f, uint64_t caches) {
    uint32_t size = GIM_ISM_DEFAULT_SIZE;
    if (f->visibility.ism_size) return f->visibility.ism_size;
    while (size > GIM_ISM_MIN_SIZE && caches * size * size * 2u > (uint64_t)GIM_ISM_BUDGET_BYTES) size /= 2u;
    return size;
}

/* After gim__frame_resolve and the checks (every instance's mesh exists), the one default
   that depends on the scene: a LightSkin frame's zero ism_size (in: the host's frame) halved
   until every cache's map fits GIM_ISM_BUDGET_BYTES, into the resolved out. */
static void gim__frame_resolve_scene(gim_context *ctx, const gim_frame *in, gim_frame *out) {
    uint64_t caches = 0;
    uint32_t i;
    if (in->visibility.ism_size || out->method == GIM_METHOD_CLUSTERED || out->method == GIM_METHOD_SSVP) return;
    for (i = 0; i < ctx->instance_count; ++i) caches += gim__mesh_get(ctx, ctx->instances[i].mesh)->cache_count;
    out->visibility.ism_size = gim__ism_frame_size(in, caches);
}

/* The visibility settings, before any GL work: a known mode, a map side that is a power of two
   in range, a point count in range, every cache's map within GIM_ISM_MAX_BYTES, and every
   VPL's within one shader storage block (also SSVP's second-bounce ISMs beside the paraboloid
   maps). f as the host wrote it, rf resolved (gim__frame_resolve: the VPL frame's map side). */
static gim_result gim__visibility_check(gim_context *ctx, const gim_frame *f, const gim_frame *rf, const char *where) {
    uint32_t size, i;
    uint64_t caches = 0;
    int vplm = f->method == GIM_METHOD_CLUSTERED || f->method == GIM_METHOD_SSVP;
    gim__vpl_settings s;
    if (f->visibility.mode != GIM_VISIBILITY_DEFAULT && f->visibility.mode != GIM_VISIBILITY_OFF &&
        f->visibility.mode != GIM_VISIBILITY_ISM && f->visibility.mode != GIM_VISIBILITY_SHADOW_MAPS &&
        f->visibility.mode != GIM_VISIBILITY_RAYS)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "unknown visibility %d", (int)f->visibility.mode);
    if (f->visibility.mode == GIM_VISIBILITY_RAYS && (vplm || f->method == GIM_METHOD_RSM_GATHER))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "visibility RAYS tests each VAL at each cache: LIGHTSKIN_BRSM or LIGHTSKIN_FULL");
    if (f->visibility.mode == GIM_VISIBILITY_SHADOW_MAPS && !vplm)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "visibility SHADOW_MAPS is one map per VPL: CLUSTERED or SSVP (LightSkin: ISM)");
    if (f->visibility.neighbour_rays > 1u)
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "visibility.neighbour_rays %u: 0 or 1",
                         (unsigned)f->visibility.neighbour_rays);
    if (f->visibility.neighbour_rays &&
        f->method != GIM_METHOD_LIGHTSKIN_BRSM && f->method != GIM_METHOD_LIGHTSKIN_FULL && f->method != GIM_METHOD_DEFAULT)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where,
                         "visibility.neighbour_rays tests LightSkin's neighbour caches: LIGHTSKIN_BRSM or LIGHTSKIN_FULL");
    if (vplm) gim__vpl_settings_of(rf, &s);
    if (f->visibility.mode != GIM_VISIBILITY_ISM && f->visibility.mode != GIM_VISIBILITY_SHADOW_MAPS &&
        !(vplm && s.second_ism))
        return GIM_OK;
    for (i = 0; i < ctx->instance_count; ++i) caches += gim__mesh_get(ctx, ctx->instances[i].mesh)->cache_count;
    size = gim__ism_frame_size(f, caches);
    if (size < GIM_ISM_MIN_SIZE || size > GIM_ISM_MAX_SIZE || (size & (size - 1u)))
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ism_size %u: a power of two in %u..%u",
                         (unsigned)f->visibility.ism_size, GIM_ISM_MIN_SIZE, GIM_ISM_MAX_SIZE);
    if (f->visibility.ism_points > GIM_ISM_MAX_POINTS)
        return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "ism_points %u above %u", (unsigned)f->visibility.ism_points,
                         GIM_ISM_MAX_POINTS);
    if (vplm) {   /* one map per VPL of both bounces, or per second-bounce VPL (s.second_ism) */
        uint64_t maps;
        uint32_t vsize = rf->visibility.ism_size;   /* the map side the VPL frame renders with */
        if (f->vpl.no_visibility)
            return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no_visibility with visibility ISM or SHADOW_MAPS: one or the other");
        maps = (s.second_ism ? 0u : (uint64_t)gim__vpl_first(f, &s, ctx->light_count ? ctx->light_count : 1u)) + s.second;
        if (maps * vsize * vsize * 2u > (uint64_t)ctx->max_ssbo_bytes)   /* 16 bits a texel */
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                             "%llu VPLs' ISMs of %u^2 exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes): fewer VPLs or "
                             "a smaller ism_size", (unsigned long long)maps, (unsigned)vsize, (long long)ctx->max_ssbo_bytes);
        return GIM_OK;
    }
    if (caches * size * size * 2u > (uint64_t)GIM_ISM_MAX_BYTES)   /* 16 bits a texel */
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "%llu ISMs of %u^2 exceed GIM_ISM_MAX_BYTES (%u bytes): a smaller ism_size",
                         (unsigned long long)caches, (unsigned)size, (unsigned)GIM_ISM_MAX_BYTES);
    {   /* the passes bind one map, and the whole point pool, as one storage block at least */
        uint32_t per = f->visibility.ism_points ? f->visibility.ism_points : GIM_ISM_DEFAULT_POINTS;
        uint64_t pool = gim__ism_pool(per);
        if ((uint64_t)size * size * 2u > (uint64_t)ctx->max_ssbo_bytes || pool * 32u > (uint64_t)ctx->max_ssbo_bytes)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                             "an ISM of %u^2 or %llu points exceed GL_MAX_SHADER_STORAGE_BLOCK_SIZE (%lld bytes)",
                             (unsigned)size, (unsigned long long)pool, (long long)ctx->max_ssbo_bytes);
    }
    return GIM_OK;
}

/* 1 when the frustum of a light's RSM camera (view, proj) meets the world bounds of an
   instance: an RSM that meets none holds no texel, so it is not rendered (the library models
   only what the scene requires). Conservative: a box is out only when its 8 corners lie beyond
   one of the six clip planes (each a half-space of homogeneous clip space, linear in the
   world position, so the box lies beyond it too). */
static int gim__light_meets_instances(gim_context *ctx, gim_mat4 view, gim_mat4 proj) {
    gim_mat4 vp = gim_mat4_mul(proj, view);
    uint32_t i;
    for (i = 0; i < ctx->instance_count; ++i) {
        const gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        gim_mat4 mvp;
        unsigned out = 63u;
        int k;
        if (!m) return 1;   /* gim__frame_check refused it already; be safe */
        mvp = gim_mat4_mul(vp, ctx->instances[i].model);
        for (k = 0; k < 8 && out; ++k) {
            gim_vec4 c;
            unsigned code;
            c.x = (k & 1) ? m->bmax[0] : m->bmin[0];
            c.y = (k & 2) ? m->bmax[1] : m->bmin[1];
            c.z = (k & 4) ? m->bmax[2] : m->bmin[2];
            c.w = 1.0f;
            c = gim__mat4_vec4(mvp, c);
            code = (c.x < -c.w ? 1u : 0u) | (c.x > c.w ? 2u : 0u) | (c.y < -c.w ? 4u : 0u) |
                            (c.y > c.w ? 8u : 0u) | (c.z < -c.w ? 16u : 0u) | (c.z > c.w ? 32u : 0u);
            out &= code;
        }
        if (!out) return 1;
    }
    return 0;
}

/* BRSM's VALs per rendered RSM (ctx->light_vals) after the eq. 12 tables: per_light, val_count
   each (the budget before the lights shared one); shared, val_count split in proportion to each RSM's
   importance total T_l (the last entry of its row table: the sum of its eq. 10-11 map, its
   power reaching the view samples), by largest remainder, at least 1 where T_l > 0, none
   where T_l = 0. Each RSM's VALs weigh 1 / (N_l P), so every N_l >= 1 keeps the sum unbiased
   (Bischoff 2017 eq. 13-15 per light); the split only moves the variance to where the light is.
   Reads the totals back (one buffer): one wait for the importance passes per frame; with one
   rendered RSM there is nothing to split, it gets val_count without it. */
static gim_result gim__gl_val_budget(gim_context *ctx, int per_light, uint32_t val_count, const char *where) {
    uint32_t i, k, given = 0, left, on = ctx->light_on_count;
    double sum = 0.0;
    gim_result r;
    for (i = 0; i < ctx->light_count; ++i) {
        ctx->light_vals[i] = per_light || on == 1u ? (ctx->light_on[i] ? val_count : 0u) : 0u;
        ctx->light_total[i] = 0.0;
    }
    if (per_light || on <= 1u) return GIM_OK;   /* nothing to split: no read-back, no wait */
    /* every total into one buffer on the GPU, then one read-back */
    r = gim__gl_sized_buffer(ctx, &ctx->light_totals, &ctx->light_totals_bytes, (uint64_t)on * 8u, where);
    if (r != GIM_OK) return r;
    ctx->gl.MemoryBarrier(GIM__GL_BUFFER_UPDATE_BARRIER_BIT);   /* the scans' writes, then the copies */
    ctx->gl.BindBuffer(GIM__GL_COPY_WRITE_BUFFER, ctx->light_totals);
    for (i = 0, k = 0; i < ctx->light_count; ++i) {
        if (!ctx->light_on[i]) continue;
        ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, ctx->light_gpu[i].row);
        ctx->gl.CopyBufferSubData(GIM__GL_COPY_READ_BUFFER, GIM__GL_COPY_WRITE_BUFFER,
                                  (gim__GLintptr)((uint64_t)(ctx->light_gpu[i].table_side - 1u) * 8u), (gim__GLintptr)k * 8, 8);
        ++k;
    }
    ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, ctx->light_totals);
    ctx->gl.GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, (gim__GLsizeiptr)on * 8, ctx->light_total);
    if (gim__gl_check(ctx, where) != GIM_OK) return GIM_ERROR_GL;
    for (i = ctx->light_count, k = on; i-- > 0;) {   /* the k-th total to its light (k <= i: from the end) */
        double t = 0.0;
        if (ctx->light_on[i]) t = ctx->light_total[--k];
        if (!(t >= 0.0) || t > DBL_MAX) t = 0.0;   /* NaN-safe */
        ctx->light_total[i] = t;
        sum += t;
    }
    if (!(sum > 0.0)) return GIM_OK;   /* nothing reaches a view sample: no VALs */
    for (i = 0; i < ctx->light_count; ++i) {
        double share = (double)val_count * (ctx->light_total[i] / sum);
        uint32_t n;
        if (!(ctx->light_total[i] > 0.0)) continue;
        n = (uint32_t)floor(share);
        if (n < 1u) n = 1u;
        ctx->light_vals[i] = n;
        given += n;
    }
    left = given < val_count ? val_count - given : 0u;
    while (left) {   /* the rest to the largest remainders, one each (left < the lights given VALs) */
        uint32_t best = ctx->light_count;
        double best_rem = -1.0;
        for (i = 0; i < ctx->light_count; ++i) {
            double rem;
            if (!ctx->light_vals[i]) continue;
            rem = (double)val_count * (ctx->light_total[i] / sum) - (double)ctx->light_vals[i];
            if (rem > best_rem) { best_rem = rem; best = i; }
        }
        if (best == ctx->light_count) break;
        ctx->light_vals[best]++;
        --left;
    }
    return GIM_OK;
}

/* The checks of gim_update that need the scene's bounds: its extent and scene_scale, each
   light's power, the distance from the origin (README "Supported ranges"); the scale of the
   frame's unit-free thresholds into *scale. Warns once when RGBA16F output can saturate. */
static gim_result gim__frame_scene_check(gim_context *ctx, const gim_frame *frame, const float bmin[3], const float bmax[3],
                                         float *scale_out) {
    static const char where[] = "gim_update";
    double diag = sqrt(((double)bmax[0] - bmin[0]) * ((double)bmax[0] - bmin[0]) +
                       ((double)bmax[1] - bmin[1]) * ((double)bmax[1] - bmin[1]) +
                       ((double)bmax[2] - bmin[2]) * ((double)bmax[2] - bmin[2]));
    float scale = frame->scene_scale > 0.0f ? frame->scene_scale : (float)diag;
    uint32_t i;
    if (!(scale > 0.0f) || !gim__isfinitef(scale))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "scene scale %g (the scene has no extent)", (double)scale);
    if (!(diag >= GIM__MIN_SCENE_DIAGONAL && diag <= GIM__MAX_SCENE_DIAGONAL))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "the scene is %g across, outside %g..%g", diag,
                         GIM__MIN_SCENE_DIAGONAL, GIM__MAX_SCENE_DIAGONAL);
    if (frame->scene_scale > 0.0f &&
        !(scale >= GIM__MIN_SCALE_DIAGONALS * diag && scale <= GIM__MAX_SCALE_DIAGONALS * diag))
        return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                         "scene_scale %g is %g times the scene's diagonal %g: valid within %g..%g diagonals (0: the diagonal)",
                         (double)scale, scale / diag, diag, GIM__MIN_SCALE_DIAGONALS, GIM__MAX_SCALE_DIAGONALS);
    for (i = 0; i < ctx->light_count; ++i) {
        const gim_light *l = &ctx->lights[i];
        float c[3];
        double p;
        gim__light_power(l, c);   /* colour times E or I */
        p = c[0] > c[1] ? c[0] : c[1];
        p = p > c[2] ? p : c[2];
        p *= l->type == GIM_LIGHT_SPOT ? 4.0 * 3.14159265358979323846 : diag * diag;
        if (p > GIM__MAX_LIGHT_POWER)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                             "light %u brings %g into the scene, above %g: its fluxes would overflow float", (unsigned)i,
                             p, GIM__MAX_LIGHT_POWER);
        /* a bounce's radiance is at most the irradiance / pi (a spot's mean over the scene's
           sphere: 4 I / diag^2); above RGBA16F's range the passes clamp it */
        p = l->type == GIM_LIGHT_SPOT ? p / (3.14159265358979323846 * diag * diag) : p / (diag * diag);
        if (!frame->indirect_float32 && !ctx->half_warned && p / 3.14159265358979323846 > GIM__HALF_MAX) {
            ctx->half_warned = 1;
            gim__log(&ctx->env, GIM_LOG_WARNING, where,
                     "light %u: indirect radiance up to %g, RGBA16F holds up to %g (clamped there): set indirect_float32",
                     (unsigned)i, p / 3.14159265358979323846, GIM__HALF_MAX);
        }
    }
    for (i = 0; i < 3; ++i) {
        double d = fabs((double)bmin[i]) > fabs((double)bmax[i]) ? fabs((double)bmin[i]) : fabs((double)bmax[i]);
        if (d > GIM__MAX_ORIGIN_DIAGONALS * diag)
            return gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where,
                             "the scene (%g across) lies %g from the origin, more than %g times its size: float "
                             "positions are too coarse there; move the world origin near the scene",
                             diag, d, GIM__MAX_ORIGIN_DIAGONALS);
    }
    *scale_out = scale;
    return GIM_OK;
}

/* The buffers of the methods this frame does not run, freed (a feature not used costs no
   memory): BRSM's importance tables, view samples and scan scratch unless BRSM, LightSkin's
   unless LightSkin, the VPL methods' unless one of them, the gather's unless RSM_GATHER. */
static void gim__release_other_methods(gim_context *ctx, const gim_frame *f) {
    gim_method method = f->method;
    int vplm = method == GIM_METHOD_CLUSTERED || method == GIM_METHOD_SSVP;
    int brsm = method == GIM_METHOD_LIGHTSKIN_BRSM || (vplm && f->vpl.importance);   /* BRSM's selection */
    int lightskin = method == GIM_METHOD_LIGHTSKIN_BRSM || method == GIM_METHOD_LIGHTSKIN_FULL;
    int gather = method == GIM_METHOD_RSM_GATHER;
    uint32_t i;
    for (i = 0; i < ctx->light_count && !brsm; ++i) {
        gim__light_gpu *g = &ctx->light_gpu[i];
        gim__GLuint b[5];
        b[0] = g->map; b[1] = g->column; b[2] = g->row; b[3] = g->selected; b[4] = g->tiles;
        ctx->gl.DeleteBuffers(5, b);
        g->map = g->column = g->row = g->selected = g->tiles = 0;
        g->map_bytes = g->column_bytes = g->row_bytes = g->selected_bytes = g->tiles_bytes = 0;
        gim__light_lum_release(ctx, g);
    }
    if (!brsm) {   /* and the view samples and the scan's scratch, BRSM's only */
        gim__GLuint b[3];
        b[0] = ctx->view_samples; b[1] = ctx->view_sample_pixels; b[2] = ctx->scan_blocks;
        ctx->gl.DeleteBuffers(3, b);
        ctx->view_samples = ctx->view_sample_pixels = ctx->scan_blocks = 0;
        ctx->view_samples_bytes = ctx->view_sample_pixels_bytes = 0;
        ctx->scan_blocks_bytes = 0;
        ctx->view_sample_key[0] = 0;
    }
    if (!lightskin) gim__lightskin_drop(ctx);
    if (!lightskin && !vplm) gim__bvh_release(ctx);   /* the rays' hierarchy: theirs only */
    if (!vplm) gim__vpl_release(ctx);
    if (!vplm || f->visibility.mode != GIM_VISIBILITY_SHADOW_MAPS) gim__vsm_release(ctx);   /* SHADOW_MAPS' targets */
    if (!gather) {
        gim__GLuint b[2];
        b[0] = ctx->gather_samples; b[1] = ctx->gather_sum;
        ctx->gl.DeleteBuffers(2, b);
        ctx->gather_samples = ctx->gather_sum = 0;
        ctx->gather_samples_bytes = ctx->gather_sum_bytes = 0;
    }
}

/* The passes every method shares: an RSM per light whose frustum meets an instance's bounds
   (the others culled: no pass, no memory), then the G-buffer (gimany's, or the host's checked
   and, when its encoding asks, decoded) into *depth, *normal. */
static gim_result gim__gl_shared_passes(gim_context *ctx, const gim_frame *f, const float bmin[3], const float bmax[3],
                                        gim__GLuint *depth, gim__GLuint *normal) {
    static const char where[] = "gim_update";
    gim_result r = GIM_OK;
    uint32_t i;
    *depth = *normal = 0;
    ctx->light_on_count = 0;
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) {
        gim_light fl;
        gim_mat4 lv, lp;
        float fmin[3], fmax[3];
        gim_fit_view_desc fd;
        ctx->light_on[i] = 0;
        ctx->light_vals[i] = 0;
        ctx->light_total[i] = 0.0;
        fd.light = &ctx->lights[i]; fd.scene_min = bmin; fd.scene_max = bmax;
        fd.view = f->view; fd.proj = f->proj; fd.view_distance = f->view_distance;
        r = gim_light_fit_view(&fd, &fl, fmin, fmax);
        if (r == GIM_OK) r = gim_light_camera(&fl, fmin, fmax, &lv, &lp);
        if (r == GIM_OK && !gim__light_meets_instances(ctx, lv, lp) &&
            (ctx->light_on_count || i + 1u < ctx->light_count)) { /* the last of all-culled renders: the frame has outputs */
            gim__light_gpu_release(ctx, &ctx->light_gpu[i]);   /* an empty RSM: no pass, no memory */
            continue;
        }
        if (r == GIM_OK) r = gim__gl_rsm(ctx, i, &fl, fmin, fmax);
        ctx->light_on[i] = 1;
        ctx->light_on_count++;
        gim__stamp(ctx, f->timing, GIM_PASS_RSM);
    }
    if (r != GIM_OK) return r;
    if (f->gbuffer.depth) {
        *depth = f->gbuffer.depth;
        *normal = f->gbuffer.normal;
        ctx->own_objects = 0;   /* the host's */
        r = gim__gl_check_texture(ctx, where, "gbuffer_depth", *depth, f->width, f->height);
        if (r == GIM_OK) r = gim__gl_check_texture(ctx, where, "gbuffer_normal", *normal, f->width, f->height);
        if (r == GIM_OK) r = gim__gl_check_host_gbuffer(ctx, where, f, *depth, *normal);
        ctx->own_objects = 1;
        if (r == GIM_OK && gim__gbuffer_needs_decode(f)) {
            r = gim__gl_gbuffer_decode(ctx, f, depth, normal);
            gim__stamp(ctx, f->timing, GIM_PASS_GBUFFER);
        }
    } else {
        r = gim__gl_gbuffer(ctx, f);
        *depth = ctx->gbuffer_depth;
        *normal = ctx->gbuffer_normal;
        gim__stamp(ctx, f->timing, GIM_PASS_GBUFFER);
    }
    return r;
}

/* The picks of a light's count VALs drawn by luminance (gim_frame_lightskin.defensive_share):
   round(share count), fewer than count. */
static uint32_t gim__defensive_count(const gim_frame *f, uint32_t count) {
    uint32_t n;
    if (!(f->lightskin.defensive_share > 0.0f)) return 0u;
    n = (uint32_t)((double)f->lightskin.defensive_share * count + 0.5);
    return n < count ? n : count - 1u;
}

/* BRSM's selection (Bischoff 2017 sec. 4), per rendered light: view samples -> importance map
   (eq. 10-11; per tile of importance_tile^2 texels with the texels' weights when the tile is > 1)
   -> cumulative sums (eq. 12) -> its share of val_count (gim__gl_val_budget) -> that many VALs
   drawn (none where no light reaches a view sample). */
static gim_result gim__gl_brsm_select(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                      float scale, const gim__vpl_settings *vpls) {
    static const char where[] = "gim_update";
    uint32_t i, k, vs_count = f->lightskin.view_sample_count;
    uint32_t val_count = vpls ? gim__vpl_first(f, vpls, ctx->light_on_count) : f->lightskin.val_count;
    uint32_t tile = f->lightskin.importance_tile;
    int defensive = f->lightskin.defensive_share > 0.0f;
    gim_result r = gim__gl_view_samples(ctx, f, depth, normal, vs_count);
    gim__stamp(ctx, f->timing, GIM_PASS_VIEW_SAMPLES);
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) {
        gim__light_gpu *g = &ctx->light_gpu[i];
        uint64_t texels = (uint64_t)g->size * g->size, cells;
        if (!ctx->light_on[i]) continue;
        /* the two-level map at tile T > 1: its tables are of ceil(size / T)^2 tiles */
        g->tile = tile;
        g->table_side = (g->size - 1u) / tile + 1u;
        cells = (uint64_t)g->table_side * g->table_side;
        if (cells * 8u > (uint64_t)ctx->max_ssbo_bytes || texels * 4u > (uint64_t)ctx->max_ssbo_bytes)
            r = gim__fail(&ctx->env, GIM_ERROR_OUT_OF_RANGE, where, "light %u: a %u^2 RSM's eq. 12 table exceeds "
                          "GL_MAX_SHADER_STORAGE_BLOCK_SIZE", (unsigned)i, (unsigned)g->size);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->map, &g->map_bytes, texels * 4u, where);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->column, &g->column_bytes, cells * 8u, where);
        if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->row, &g->row_bytes, (uint64_t)g->table_side * 8u, where);
        if (defensive) {   /* the luminance map (per texel, or the weights and tile sums) and its tables */
            if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->lum_map, &g->lum_map_bytes, texels * 4u, where);
            if (r == GIM_OK) r = gim__gl_sized_buffer(ctx, &g->lum_column, &g->lum_column_bytes, cells * 8u, where);
            if (r == GIM_OK)
                r = gim__gl_sized_buffer(ctx, &g->lum_row, &g->lum_row_bytes, (uint64_t)g->table_side * 8u, where);
            if (r == GIM_OK && tile > 1u) r = gim__gl_sized_buffer(ctx, &g->lum_tiles, &g->lum_tiles_bytes, cells * 4u, where);
            if (r == GIM_OK && tile == 1u && g->lum_tiles) {
                ctx->gl.DeleteBuffers(1, &g->lum_tiles);
                g->lum_tiles = 0;
                g->lum_tiles_bytes = 0;
            }
        } else {
            gim__light_lum_release(ctx, g);
        }
        if (r == GIM_OK && tile > 1u) {
            r = gim__gl_sized_buffer(ctx, &g->tiles, &g->tiles_bytes, cells * 4u, where);
            if (r == GIM_OK)
                r = gim__gl_importance_tile_map_lum(ctx, g->position, g->normal, g->flux, g->size, g->size, tile,
                                                    ctx->view_samples, vs_count, scale, f->lightskin.importance_clamp,
                                                    g->tiles, g->map, g->lum_tiles, g->lum_map);
        } else if (r == GIM_OK) {
            if (g->tiles) ctx->gl.DeleteBuffers(1, &g->tiles);   /* per texel: no tile map */
            g->tiles = 0;
            g->tiles_bytes = 0;
            r = gim__gl_importance_map_lum(ctx, g->position, g->normal, g->flux, g->size, g->size, ctx->view_samples,
                                           vs_count, scale, f->lightskin.importance_clamp, g->map, g->lum_map);
        }
        gim__stamp(ctx, f->timing, GIM_PASS_IMPORTANCE_MAP);
    }
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) { /* apart, so the stamps of a pass merge */
        gim__light_gpu *g = &ctx->light_gpu[i];
        if (!ctx->light_on[i]) continue;
        r = gim__gl_importance_cumsum(ctx, tile > 1u ? g->tiles : g->map, g->column, g->row, g->table_side,
                                      g->table_side, 0u);
        if (r == GIM_OK && defensive)
            r = gim__gl_importance_cumsum(ctx, tile > 1u ? g->lum_tiles : g->lum_map, g->lum_column, g->lum_row,
                                          g->table_side, g->table_side, 0u);
        gim__stamp(ctx, f->timing, GIM_PASS_CUMSUM);
    }
    if (r == GIM_OK && !vpls) r = gim__gl_val_budget(ctx, f->per_light_budget, val_count, where);
    for (i = 0, k = 0; i < ctx->light_count && r == GIM_OK && vpls; ++i)   /* the VPL methods' even shares */
        ctx->light_vals[i] = ctx->light_on[i] ? gim__vpl_share(f, vpls, ctx->light_on_count, k++) : 0u;
    for (i = 0; i < ctx->light_count && r == GIM_OK; ++i) {
        gim__light_gpu *g = &ctx->light_gpu[i];
        if (!ctx->light_vals[i]) {   /* none of its light reaches a view sample: no VALs, no selection */
            gim__GLuint b = g->selected;
            if (b) ctx->gl.DeleteBuffers(1, &b);
            g->selected = 0;
            g->selected_bytes = 0;
            continue;
        }
        r = gim__gl_sized_buffer(ctx, &g->selected, &g->selected_bytes, (uint64_t)ctx->light_vals[i] * 12u, where);
        if (r == GIM_OK) {
            float off[4];
            /* temporal_steps: the drift's step from the frame's total, so a split that changes
               by a VAL does not move the offsets */
            gim__gl_defensive dfs;
            gim__select_offsets(f, i, val_count, off);
            dfs.count = gim__defensive_count(f, ctx->light_vals[i]);
            dfs.lum_column = g->lum_column;
            dfs.lum_row = g->lum_row;
            dfs.lum_weight = g->lum_map;
            r = gim__gl_importance_select_mix(ctx, g->column, g->row, g->table_side, g->table_side, ctx->light_vals[i],
                                              off, tile, g->map, g->size, g->size, &dfs, g->selected);
        }
        gim__stamp(ctx, f->timing, GIM_PASS_SELECT);
    }
    return r;
}

/* LIGHTSKIN_BRSM and LIGHTSKIN_FULL: BRSM's selection, then the LightSkin passes. */
static gim_result gim__gl_lightskin_frame(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                          float scale, gim_frame_outputs *o, gim_debug_outputs *dbg) {
    gim_result r = GIM_OK;
    if (f->method == GIM_METHOD_LIGHTSKIN_BRSM) {
        r = gim__gl_brsm_select(ctx, f, depth, normal, scale, NULL);
        dbg->view_samples = ctx->view_samples;
        dbg->view_sample_count = f->lightskin.view_sample_count;
    }
    if (r == GIM_OK) r = gim__gl_lightskin(ctx, f, depth, normal, scale, o, dbg);
    return r;
}

/* RSM_GATHER: every pixel gathers its pattern of RSM texels (nothing to gather without a light). */
static gim_result gim__gl_gather_frame(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal,
                                       float scale, gim_frame_outputs *o) {
    gim_result r;
    if (!ctx->light_on_count) return GIM_OK;
    r = gim__gl_rsm_gather(ctx, f, depth, normal, scale, f->indirect_float32 ? GIM__GL_RGBA32F : GIM__GL_RGBA16F);
    if (r != GIM_OK) return r;
    o->indirect = ctx->indirect;
    gim__stamp(ctx, f->timing, GIM_PASS_SHADE);
    return GIM_OK;
}

/* The frame's outputs, the lights' and the stats, after every pass succeeded. */
static void gim__frame_outputs(gim_context *ctx, const gim_frame *f, gim__GLuint depth, gim__GLuint normal, float scale,
                               gim_frame_outputs *o, const gim_debug_outputs *dbg) {
    int vplm = f->method == GIM_METHOD_CLUSTERED || f->method == GIM_METHOD_SSVP;
    int brsm = f->method == GIM_METHOD_LIGHTSKIN_BRSM || (vplm && f->vpl.importance);   /* BRSM's selection ran */
    uint32_t i;
    o->valid = 1;
    o->width = f->width;
    o->height = f->height;
    o->gbuffer_depth = depth;
    o->gbuffer_normal = normal;
    o->gbuffer_albedo = f->gbuffer.depth ? 0u : ctx->gbuffer_albedo;
    o->gbuffer_material = f->gbuffer.depth ? 0u : ctx->gbuffer_material;
    o->scene_scale = scale;
    o->light_count = ctx->light_count;
    o->lights = ctx->light_outputs;
    for (i = 0; i < ctx->light_count; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        gim_light_outputs *lo = &ctx->light_outputs[i];
        memset(lo, 0, sizeof *lo);
        lo->light = ctx->lights[i];
        lo->rsm_size = g->size;
        lo->rsm_position = g->position;
        lo->rsm_normal = g->normal;
        lo->rsm_flux = g->flux;
        lo->rsm_depth = g->depth;
        lo->view = g->view;
        lo->proj = g->proj;
        lo->importance = g->map;
        lo->importance_tiles = brsm && g->tile > 1u ? g->tiles : 0u;
        lo->importance_tile = brsm && g->map ? g->tile : 0u;
        lo->column = g->column;
        lo->row = g->row;
        lo->selected = g->selected;
        lo->selected_count = brsm ? ctx->light_vals[i] : 0u;
        lo->defensive_count = brsm && g->lum_map ? gim__defensive_count(f, ctx->light_vals[i]) : 0u;
        lo->luminance = lo->defensive_count ? g->lum_map : 0u;
        lo->luminance_column = lo->defensive_count ? g->lum_column : 0u;
        lo->luminance_row = lo->defensive_count ? g->lum_row : 0u;
        lo->rendered = ctx->light_on[i];
        lo->importance_total = f->method == GIM_METHOD_LIGHTSKIN_BRSM ? ctx->light_total[i] : 0.0;
    }
    ctx->outputs = *o;
    ctx->debug = *dbg;
    memset(&ctx->stats, 0, sizeof ctx->stats);
    ctx->stats.timed = f->timing ? 1 : 0;
    ctx->stats.cpu_clock = f->timing == 2 ? GIM__CPU_CLOCK : 0;
    ctx->stats.light_count = ctx->light_count;
    ctx->stats.view_sample_count = dbg->view_sample_count;
    ctx->stats.cache_count = dbg->cache_count;
    ctx->stats.val_count = dbg->val_count;
    ctx->stats.vpl_count = dbg->vpl_count;
    ctx->stats.cluster_count = dbg->cluster_count;
    ctx->stats.pixel_count = f->width * f->height;
    ctx->stats.rsm_count = ctx->light_on_count;
    ctx->stats.ism_maps_made = ctx->ism_maps_made;
    for (i = 0; i < ctx->light_count && brsm; ++i) ctx->stats.val_light_count += ctx->light_vals[i] > 0u;
}

/* check -> resolve -> shared passes -> the method's passes -> outputs (see the declaration). */
GIMANY_DEF gim_result gim_update(gim_context *ctx, const gim_frame *frame) {
    static const char where[] = "gim_update";
    gim_frame_outputs o;
    gim_debug_outputs dbg;
    gim_frame f;
    float bmin[3], bmax[3], scale = 0.0f;
    gim__GLuint depth = 0, normal = 0;
    gim_result r;
    /* check */
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!frame) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "frame is NULL");
    /* without a current context every GL call is a no-op returning 0: say so before a pass
       reports a failure that only follows from it */
    if (!ctx->gl.GetString(GIM__GL_VERSION))
        return gim__fail(&ctx->env, GIM_ERROR_GL, where, "no GL context is current on this thread");
    if (ctx->light_buffer) { /* the host's light buffer, read back: the RSMs need the cameras on the CPU */
        gim__gl_enter(ctx, where);
        r = gim__gl_lights_from_buffer(ctx, where);
        r = gim__gl_leave(ctx, r);
        if (r != GIM_OK) return r;
    }
    if (!ctx->gl.ClipControl && ctx->clip_control) {
        gim__GLint origin = GIM__GL_LOWER_LEFT, mode = GIM__GL_NEGATIVE_ONE_TO_ONE;
        ctx->gl.GetIntegerv(GIM__GL_CLIP_ORIGIN, &origin);
        ctx->gl.GetIntegerv(GIM__GL_CLIP_DEPTH_MODE, &mode);
        if (origin != GIM__GL_LOWER_LEFT || mode != GIM__GL_NEGATIVE_ONE_TO_ONE)
            return gim__fail(&ctx->env, GIM_ERROR_UNSUPPORTED, where,
                             "the host's glClipControl is not the default and glClipControl was not loaded "
                             "(GIMANY_EXTERNAL_GL without get_proc_address): set GL_LOWER_LEFT, GL_NEGATIVE_ONE_TO_ONE");
    }
    /* resolve, once: the checks read the host's frame and f, every later pass f alone */
    gim__frame_resolve(frame, &f);
    r = gim__deform_prepare(ctx, frame);   /* before the bounds: a deforming mesh's are this frame's */
    if (r == GIM_OK) r = gim__frame_check(ctx, frame, &f, bmin, bmax);
    if (r == GIM_OK) r = gim__visibility_check(ctx, frame, &f, where);
    if (r == GIM_OK) r = gim__frame_scene_check(ctx, frame, bmin, bmax, &scale);
    if (r != GIM_OK) return r;
    gim__frame_resolve_scene(ctx, frame, &f);   /* the default the scene sets, now that it is checked */
    /* the shared passes */
    ctx->outputs.valid = 0;
    ctx->stamp_count = 0;
    ctx->ism_maps_made = 0;
    ctx->ism_made_counted = 0;
    gim__gl_enter(ctx, where);
    ctx->own_objects = 1;
    gim__stamp(ctx, f.timing, GIM_PASS_COUNT);
    r = gim__gl_shared_passes(ctx, &f, bmin, bmax, &depth, &normal);
    /* the method's own passes */
    memset(&o, 0, sizeof o);
    memset(&dbg, 0, sizeof dbg);
    memcpy(o.bounds_min, bmin, sizeof bmin);
    memcpy(o.bounds_max, bmax, sizeof bmax);
    if (r == GIM_OK) {
        gim__release_other_methods(ctx, &f);
        if (f.method == GIM_METHOD_RSM_GATHER) r = gim__gl_gather_frame(ctx, &f, depth, normal, scale, &o);
        else if (f.method == GIM_METHOD_CLUSTERED || f.method == GIM_METHOD_SSVP)
            r = gim__gl_vpl_frame(ctx, &f, depth, normal, scale, &o, &dbg);
        else r = gim__gl_lightskin_frame(ctx, &f, depth, normal, scale, &o, &dbg);
    }
    ctx->own_objects = 0;
    if (r != GIM_OK) return gim__gl_leave(ctx, r);
    /* outputs */
    gim__frame_outputs(ctx, &f, depth, normal, scale, &o, &dbg);
    return gim__gl_leave(ctx, GIM_OK);
}

GIMANY_DEF gim_frame_outputs gim_outputs(const gim_context *ctx) {
    gim_frame_outputs o;
    if (ctx) return ctx->outputs;
    memset(&o, 0, sizeof o);
    return o;
}

GIMANY_DEF gim_debug_outputs gim_debug(const gim_context *ctx) {
    gim_debug_outputs d;
    if (ctx) return ctx->debug;
    memset(&d, 0, sizeof d);
    return d;
}

/* GL bytes of a buffer or texture set the context owns. */
static uint64_t gim__context_bytes(const gim_context *ctx) {
    uint64_t b = ctx->scan_blocks_bytes + ctx->proxy_state_bytes + ctx->view_sample_pixels_bytes + ctx->view_samples_bytes +
                 ctx->light_totals_bytes +
                 (uint64_t)ctx->material_count * 32u;
    uint32_t i;
    for (i = 0; i < ctx->mesh_slots; ++i)
        if (ctx->meshes[i].used) b += ctx->meshes[i].bytes;
    for (i = 0; i < ctx->light_capacity; ++i) {
        const gim__light_gpu *g = &ctx->light_gpu[i];
        b += (uint64_t)g->size * g->size * 52u + g->map_bytes + g->column_bytes + g->row_bytes + g->selected_bytes +
             g->tiles_bytes + g->lum_map_bytes + g->lum_tiles_bytes + g->lum_column_bytes + g->lum_row_bytes;
    }
    b += (uint64_t)ctx->gbuffer_width * ctx->gbuffer_height * 20u + (uint64_t)ctx->decoded_width * ctx->decoded_height * 12u;
    b += (uint64_t)ctx->indirect_width * ctx->indirect_height * (ctx->indirect_format == GIM__GL_RGBA32F ? 16u : 8u);
    b += ctx->ls.caches_bytes + ctx->ls.cells_bytes + ctx->ls.buckets_bytes + ctx->ls.vals_bytes + ctx->ls.diffuse_bytes +
         ctx->ls.glossy_bytes + ctx->ls.exponents_bytes + ctx->bvh.bytes + ctx->gather_samples_bytes +
         ctx->gather_sum_bytes;
    b += ctx->vpl.vpls_bytes + ctx->vpl.staging_bytes + ctx->vpl.cluster_of_bytes + ctx->vpl.centres_bytes +
         ctx->vpl.maps_bytes + ctx->vpl.made_bytes + ctx->vpl.ray_samples_bytes;
    b += (uint64_t)ctx->para_size * ctx->para_size * ctx->para_count *
             (4u + (ctx->para_attributes != GIM__PARA_ATTRIBUTES ? 4u : 0u) + (ctx->para_attributes != GIM__PARA_DISTANCE ? 48u : 0u)) +
         ctx->para_samples_bytes;
    b += ctx->vpl_partial_bytes + ctx->ism_maps_bytes + ctx->ism_points_bytes + ctx->ism_cluster_maps_bytes +
         (ctx->deform_box ? 28u : 0u);
    b += (uint64_t)ctx->vsm_size * ctx->vsm_size * ctx->vsm_layers * 8u + ctx->vsm_list_bytes;   /* SHADOW_MAPS' layers, list */
    b += (uint64_t)ctx->vpl_raw_width * ctx->vpl_raw_height * (ctx->vpl_raw_format == GIM__GL_RGBA32F ? 16u : 8u);
    return b;
}

/* BRSM's selection programs after ids[0..n): view samples, the importance map (or its tiles),
   the scan, the selection (BRSM, and the VPL methods' vpl.importance); the new count. */
static uint32_t gim__select_programs(const gim_frame *f, gim__program_id *ids, uint32_t n) {
    ids[n++] = GIM__PROGRAM_VIEW_SAMPLES;
    ids[n++] = f->lightskin.importance_tile > 1u ? GIM__PROGRAM_IMPORTANCE_TILES : GIM__PROGRAM_IMPORTANCE_MAP;
    ids[n++] = GIM__PROGRAM_SCAN_COLUMNS;
    ids[n++] = GIM__PROGRAM_SCAN_TOTALS;
    ids[n++] = GIM__PROGRAM_SCAN_OFFSETS;
    ids[n++] = GIM__PROGRAM_SELECT;
    return n;
}

GIMANY_DEF gim_result gim_prepare(gim_context *ctx, const gim_frame *frame) {
    static const char where[] = "gim_prepare";
    gim__program_id ids[GIM__PROGRAM_COUNT];
    gim_frame f;
    float bmin[3], bmax[3];
    uint32_t n = 0, i;
    gim_result r;
    gim__GLuint program;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!frame) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "frame is NULL");
    if (!ctx->gl.GetString(GIM__GL_VERSION))
        return gim__fail(&ctx->env, GIM_ERROR_GL, where, "no GL context is current on this thread");
    gim__frame_resolve(frame, &f);
    r = gim__frame_check(ctx, frame, &f, bmin, bmax);
    if (r == GIM_OK) r = gim__visibility_check(ctx, frame, &f, where);
    if (r != GIM_OK) return r;
    /* what gim_update's passes build for this method and these settings */
    ids[n++] = GIM__PROGRAM_RSM;
    if (!f.gbuffer.depth) ids[n++] = GIM__PROGRAM_GBUFFER;
    if (gim__gbuffer_needs_decode(&f)) ids[n++] = GIM__PROGRAM_GBUFFER_DECODE;
    if (f.method == GIM_METHOD_RSM_GATHER) {
        ids[n++] = GIM__PROGRAM_RSM_GATHER;
    } else if (f.method == GIM_METHOD_CLUSTERED || f.method == GIM_METHOD_SSVP) {
        gim__vpl_settings s;
        gim__vpl_settings_of(&f, &s);
        if (f.vpl.importance) {   /* BRSM's selection, its picks written as VPLs */
            n = gim__select_programs(&f, ids, n);
            ids[n++] = GIM__PROGRAM_VALS_GATHER;
        } else {
            ids[n++] = GIM__PROGRAM_RSM_VPLS;
        }
        ids[n++] = GIM__PROGRAM_CLUSTERS;
        ids[n++] = GIM__PROGRAM_KMEANS_ASSIGN;
        ids[n++] = GIM__PROGRAM_KMEANS_UPDATE;
        /* the clusters' maps, or SHADOW_MAPS' drawn through the same program */
        if ((s.visibility && f.visibility.mode != GIM_VISIBILITY_ISM) || (s.second && !s.second_rays))
            ids[n++] = GIM__PROGRAM_PARABOLOID;
        /* ISMs: every VPL's, or the second bounce's (beside the paraboloid maps, or checking
           its clusters' hits with SHADOW_MAPS) */
        if (f.visibility.mode == GIM_VISIBILITY_ISM || s.second_ism ||
            (f.visibility.mode == GIM_VISIBILITY_SHADOW_MAPS && s.second && !s.second_rays))
            ids[n++] = GIM__PROGRAM_ISM;
        if (f.visibility.mode == GIM_VISIBILITY_SHADOW_MAPS) ids[n++] = GIM__PROGRAM_ISM_FROM_PARABOLOID;
        if (s.second) ids[n++] = s.second_rays ? GIM__PROGRAM_SECOND_BOUNCE_RAYS : GIM__PROGRAM_SECOND_BOUNCE;
        ids[n++] = GIM__PROGRAM_VPL_SHADE;
        if (s.interleave > 1u) ids[n++] = GIM__PROGRAM_GEOMETRY_BLUR;
    } else {
        if (f.method != GIM_METHOD_LIGHTSKIN_FULL) n = gim__select_programs(&f, ids, n);
        ids[n++] = GIM__PROGRAM_VALS_GATHER;
        ids[n++] = GIM__PROGRAM_PROXY_LIGHTS;
        if (f.visibility.mode == GIM_VISIBILITY_ISM) ids[n++] = GIM__PROGRAM_ISM;
        ids[n++] = GIM__PROGRAM_LIGHTSKIN_SHADE;
    }
    for (i = 0; i < ctx->instance_count; ++i) {   /* a deforming mesh's bounds and caches follow it */
        const gim__mesh *m = gim__mesh_get(ctx, ctx->instances[i].mesh);
        if (m && m->deforming) {
            ids[n++] = GIM__PROGRAM_CACHES_FOLLOW;
            break;
        }
    }
    gim__gl_enter(ctx, where);
    for (i = 0; i < n && r == GIM_OK; ++i) r = gim__gl_program(ctx, ids[i], &program);
    return gim__gl_leave(ctx, r == GIM_OK ? gim__gl_check(ctx, where) : r);
}

GIMANY_DEF gim_result gim_frame_stats(gim_context *ctx, gim_stats *out) {
    static const char where[] = "gim_frame_stats";
    uint64_t t[GIM__MAX_STAMPS];
    uint32_t i;
    if (!ctx) return GIM_ERROR_INVALID_ARGUMENT;
    if (!out) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "out is NULL");
    if (!ctx->outputs.valid) return gim__fail(&ctx->env, GIM_ERROR_INVALID_ARGUMENT, where, "no successful gim_update yet");
    *out = ctx->stats;
    out->gpu_bytes = gim__context_bytes(ctx);
    if (ctx->ism_made_counted && ctx->vpl.made) {   /* the VPLs' maps the GPU made (a wait for the frame) */
        uint32_t made[2] = {0u, 0u};
        gim_result r;
        gim__gl_enter(ctx, where);
        ctx->gl.BindBuffer(GIM__GL_COPY_READ_BUFFER, ctx->vpl.made);
        ctx->gl.GetBufferSubData(GIM__GL_COPY_READ_BUFFER, 0, 8, made);
        r = gim__gl_leave(ctx, gim__gl_check(ctx, where));
        if (r != GIM_OK) return r;
        out->ism_maps_made += made[0] - made[1];   /* the running count now less before the frame */
    }
    if (!ctx->stats.timed || ctx->stamp_count < 2) return GIM_OK;
    if (ctx->stats.cpu_clock) {   /* timing 2: the clock after each glFinish */
        const double *c = ctx->stamp_ms;
        for (i = 1; i < ctx->stamp_count; ++i)
            if (ctx->stamp_pass[i] < GIM_PASS_COUNT && c[i] >= c[i - 1]) out->pass_ms[ctx->stamp_pass[i]] += c[i] - c[i - 1];
        out->frame_ms = c[ctx->stamp_count - 1] >= c[0] ? c[ctx->stamp_count - 1] - c[0] : 0.0;
        return GIM_OK;
    }
    gim__gl_enter(ctx, where);
    for (i = 0; i < ctx->stamp_count; ++i) ctx->gl.GetQueryObjectui64v(ctx->queries[i], GIM__GL_QUERY_RESULT, &t[i]);
    for (i = 1; i < ctx->stamp_count; ++i)
        if (ctx->stamp_pass[i] < GIM_PASS_COUNT && t[i] >= t[i - 1])
            out->pass_ms[ctx->stamp_pass[i]] += (double)(t[i] - t[i - 1]) * 1e-6;
    out->frame_ms = t[ctx->stamp_count - 1] >= t[0] ? (double)(t[ctx->stamp_count - 1] - t[0]) * 1e-6 : 0.0;
    return gim__gl_leave(ctx, gim__gl_check(ctx, where));
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
    if ((unsigned)desc->gl_state > (unsigned)GIM_GL_STATE_RESET)
        return gim__fail(&desc->env, GIM_ERROR_INVALID_ARGUMENT, "gim_create",
                         "desc.gl_state %d is not a gim_gl_state (GIM_GL_STATE_RESTORE or GIM_GL_STATE_RESET)",
                         (int)desc->gl_state);
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
    ctx->gl_state = desc->gl_state;
    if (major == 4 && minor < 5) { /* 4.5 core, or the extensions on an older context */
        ctx->clip_control = gim__gl_has_extension(&gl, "GL_ARB_clip_control");
        if (!ctx->clip_control) gl.ClipControl = NULL;
        if (!gim__gl_has_extension(&gl, "GL_ARB_direct_state_access")) gl.GetTextureParameteriv = NULL;
    } else {
        ctx->clip_control = 1;
    }
    ctx->gl = gl;
    ctx->gl_major = (int)major;
    ctx->gl_minor = (int)minor;
    gl.GetInteger64v(GIM__GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &ctx->max_ssbo_bytes);
    gl.GetIntegerv(GIM__GL_MAX_TEXTURE_SIZE, &ctx->max_texture_size);
    gl.GetIntegerv(GIM__GL_MAX_VIEWPORT_DIMS, ctx->max_viewport);
    gl.GetIntegerv(GIM__GL_MAX_ARRAY_TEXTURE_LAYERS, &ctx->max_layers[0]);
    gl.GetIntegerv(GIM__GL_MAX_FRAMEBUFFER_LAYERS, &ctx->max_layers[1]);
    ctx->proxy_chunk = GIM__PROXY_CHUNK;
    gl.GetIntegerv(GIM__GL_SHADER_STORAGE_BUFFER_OFFSET_ALIGNMENT, &ctx->ssbo_align);
    if (ctx->ssbo_align < 1) ctx->ssbo_align = 256;
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
    if (ctx->proxy_state) ctx->gl.DeleteBuffers(1, &ctx->proxy_state);
    if (ctx->deform_box) ctx->gl.DeleteBuffers(1, &ctx->deform_box);
    gim__paraboloid_release(ctx, 1);
    if (ctx->vpl_partial) ctx->gl.DeleteBuffers(1, &ctx->vpl_partial);
    if (ctx->vpl_raw) ctx->gl.DeleteTextures(1, &ctx->vpl_raw);
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
