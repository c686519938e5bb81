/* gimany-host-buffers - gimany driven entirely from a host's GL buffers: the small
   engine below keeps its geometry, its lights and its G-buffer itself and lends them to gimany.
   - geometry: a Cornell-like box with a block, in ONE interleaved vertex buffer (position,
     normal, uv; 32-byte stride) and a 16-bit index buffer, handed over by gim_mesh_desc.buffers.
     The caches are made once on the CPU from the arrays before they go to the GPU (the only CPU
     copy gimany sees besides the per-triangle materials the API asks for);
   - lights: a GL buffer of gim_light_std430 (gim_set_lights_buffer), which the engine's own
     direct-light shader reads too;
   - G-buffer: the engine's depth (DEPTH_COMPONENT32F) and octahedral normals in GL_RG16
     (GIM_NORMAL_OCTAHEDRAL_UNORM), drawn by its own shaders and passed in gim_frame.
   Per frame: G-buffer + direct light (no shadows: kept simple) -> gim_update -> composite
   direct + albedo x indirect (the host's G-buffer gives albedo-1 indirect) to the window.
   Options: --size WxH, --frames N (render N frames, then exit), --rsm N (the light's RSM side,
   128), --screenshot FILE.png. A failing gimany call: one line on stderr, exit 1. At the end
   it prints the mean of gimany's indirect texture ("indirect mean X"). */
#define _POSIX_C_SOURCE 200809L
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmissing-prototypes"
#endif
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb_image_write.h>
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic pop
#endif

#define PROG "gimany-host-buffers"
#define FAIL(...) do { fprintf(stderr, PROG ": " __VA_ARGS__); fputc('\n', stderr); goto out; } while (0)
#define CHECK(call) do { if ((call) != GIM_OK) FAIL("%s: %s", #call, last_error); } while (0)

enum { MAX_QUADS = 16, STRIDE = 32 };   /* vertex: position, normal, uv (8 floats) */

/* The engine's scene on the CPU while it is built: quads grouped by material (0 white, 1 red,
   2 green) so each material is one indexed draw. */
typedef struct geometry {
    float v[MAX_QUADS * 4 * 8];
    uint16_t idx[MAX_QUADS * 6];
    uint32_t tri_mat[MAX_QUADS * 2];
    uint32_t quads, first[4];           /* first[m]: first quad of material m; first[3] = quads */
} geometry;

static const gim_material materials[3] = {{{0.75f, 0.75f, 0.75f}, {0, 0, 0}, 0}, {{0.7f, 0.12f, 0.1f}, {0, 0, 0}, 0},
                                          {{0.12f, 0.6f, 0.15f}, {0, 0, 0}, 0}};

/* One quad o + s*u + t*w (s, t in [0, 1]), facing u x w. */
static void quad(geometry *g, uint32_t mat, const float o[3], const float u[3], const float w[3]) {
    float n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    uint32_t q = g->quads++, c, k;
    for (c = 0; c < 4; ++c) {
        float s = (float)(c == 1 || c == 2), t = (float)(c >= 2), *p = g->v + (q * 4 + c) * 8;
        for (k = 0; k < 3; ++k) { p[k] = o[k] + s * u[k] + t * w[k]; p[3 + k] = n[k] / l; }
        p[6] = s; p[7] = t;
    }
    for (c = 0; c < 6; ++c) g->idx[q * 6 + c] = (uint16_t)(q * 4 + (uint32_t[]){0, 1, 2, 0, 2, 3}[c]);
    g->tri_mat[q * 2] = g->tri_mat[q * 2 + 1] = mat;
}

/* A 2 x 2 x 2 box open at +z, walls facing in, and a 0.6 x 1.2 x 0.6 block facing out. */
static void build_scene(geometry *g) {
    static const float box[5][9] = {  /* origin, u, w: floor, ceiling, back (white), left (red), right (green) */
        {-1, 0, 1, 2, 0, 0, 0, 0, -2}, {-1, 2, -1, 2, 0, 0, 0, 0, 2}, {-1, 0, -1, 2, 0, 0, 0, 2, 0},
        {-1, 0, 1, 0, 0, -2, 0, 2, 0}, {1, 0, -1, 0, 0, 2, 0, 2, 0}};
    static const float blk[5][9] = {  /* block at x [-0.65, -0.05], z [-0.6, 0]: +z, -z, -x, +x, top */
        {-0.65f, 0, 0, 0.6f, 0, 0, 0, 1.2f, 0}, {-0.05f, 0, -0.6f, -0.6f, 0, 0, 0, 1.2f, 0},
        {-0.65f, 0, -0.6f, 0, 0, 0.6f, 0, 1.2f, 0}, {-0.05f, 0, 0, 0, 0, -0.6f, 0, 1.2f, 0},
        {-0.65f, 1.2f, 0, 0.6f, 0, 0, 0, 0, -0.6f}};
    int i;
    memset(g, 0, sizeof *g);
    for (i = 0; i < 3; ++i) quad(g, 0, box[i], box[i] + 3, box[i] + 6);
    for (i = 0; i < 5; ++i) quad(g, 0, blk[i], blk[i] + 3, blk[i] + 6);
    g->first[1] = g->quads;
    quad(g, 1, box[3], box[3] + 3, box[3] + 6);
    g->first[2] = g->quads;
    quad(g, 2, box[4], box[4] + 3, box[4] + 6);
    g->first[3] = g->quads;
}

/* The engine's shaders: the G-buffer pass (depth, octahedral normal, albedo, direct light from
   the light buffer) and the composite. */
static const char *gbuf_vs =
    "#version 430 core\n"
    "layout(location = 0) in vec3 pos; layout(location = 1) in vec3 nrm; layout(location = 2) in vec2 uv;\n"
    "uniform mat4 view_proj; out vec3 wpos; out vec3 wnrm;\n"
    "void main() { wpos = pos; wnrm = nrm; gl_Position = view_proj * vec4(pos, 1.0); }\n";
static const char *gbuf_fs =
    "#version 430 core\n"
    "struct GimLight { vec4 color_power; vec4 position_cone; vec4 direction_extent; uvec4 type_square_size_fit; };\n"
    "layout(std430, binding = 0) readonly buffer Lights { GimLight lights[]; };\n"
    "uniform vec3 albedo; uniform int light_count; in vec3 wpos; in vec3 wnrm;\n"
    "layout(location = 0) out vec2 oct; layout(location = 1) out vec4 alb; layout(location = 2) out vec4 direct;\n"
    "void main() {\n"
    "  vec3 n = normalize(gl_FrontFacing ? wnrm : -wnrm), e = vec3(0.0);\n"
    "  vec3 p = n / (abs(n.x) + abs(n.y) + abs(n.z));\n" /* octahedral map, Cigolle et al. 2014 */
    "  vec2 o = p.z >= 0.0 ? p.xy : (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);\n"
    "  oct = o * 0.5 + 0.5; alb = vec4(albedo, 1.0);\n"
    "  for (int i = 0; i < light_count; ++i) {\n" /* spots only: I cos / d^2 inside the cone, unshadowed */
    "    vec3 d = lights[i].position_cone.xyz - wpos; float r2 = dot(d, d); d *= inversesqrt(r2);\n"
    "    float in_cone = step(cos(lights[i].position_cone.w), dot(-d, normalize(lights[i].direction_extent.xyz)));\n"
    "    e += lights[i].color_power.rgb * lights[i].color_power.a * max(dot(n, d), 0.0) / r2 * in_cone;\n"
    "  }\n"
    "  direct = vec4(albedo / 3.14159265 * e, 1.0);\n"
    "}\n";
static const char *comp_vs =
    "#version 430 core\nout vec2 uv;\n"
    "void main() { uv = vec2(gl_VertexID & 1, gl_VertexID >> 1) * 2.0; gl_Position = vec4(uv * 2.0 - 1.0, 0.0, 1.0); }\n";
static const char *comp_fs =
    "#version 430 core\nin vec2 uv; out vec4 color;\n"
    "layout(binding = 0) uniform sampler2D direct; layout(binding = 1) uniform sampler2D albedo;\n"
    "layout(binding = 2) uniform sampler2D indirect; uniform float exposure;\n"
    "void main() {\n"
    "  vec3 c = texture(direct, uv).rgb + texture(albedo, uv).rgb * texture(indirect, uv).rgb;\n"
    "  c = 1.0 - exp(-exposure * c);\n" /* a simple exponential tone map */
    "  color = vec4(pow(c, vec3(1.0 / 2.2)), 1.0);\n"
    "}\n";

static GLuint program(const char *vs, const char *fs) {
    const char *src[2] = {vs, fs};
    GLenum type[2] = {GL_VERTEX_SHADER, GL_FRAGMENT_SHADER};
    GLuint p = glCreateProgram();
    GLint ok = 0;
    char log[512];
    int i;
    for (i = 0; i < 2; ++i) {
        GLuint s = glCreateShader(type[i]);
        glShaderSource(s, 1, &src[i], NULL);
        glCompileShader(s);
        glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
        if (!ok) { glGetShaderInfoLog(s, sizeof log, NULL, log); fprintf(stderr, PROG ": shader: %s\n", log); return 0; }
        glAttachShader(p, s);
        glDeleteShader(s);
    }
    glLinkProgram(p);
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) { glGetProgramInfoLog(p, sizeof log, NULL, log); fprintf(stderr, PROG ": link: %s\n", log); return 0; }
    return p;
}

static GLuint texture(GLenum format, int w, int h) {
    GLuint t;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, format, w, h);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    return t;
}

/* gimany's last error message, printed on the one line of the failing call */
static char last_error[512] = "no message";
static void log_gimany(gim_log_level level, const char *message, void *user) {
    (void)user;
    if (level == GIM_LOG_ERROR) snprintf(last_error, sizeof last_error, "%s", message);
}

int main(int argc, char **argv) {
    static geometry g;
    int width = 320, height = 240, frames = 0, rsm = 128, rc = 1, i, frame;
    const char *shot = NULL;
    GLFWwindow *win = NULL;
    gim_context *ctx = NULL;
    gim_desc gd;
    gim_cache_desc cd;
    gim_cache_set caches;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance inst;
    gim_light_std430 spot;
    GLuint vbo = 0, ibo = 0, lbo = 0, vao = 0, empty_vao = 0, fbo = 0, tex[4] = {0, 0, 0, 0}, gprog = 0, cprog = 0;
    float *rgba = NULL;
    memset(&caches, 0, sizeof caches);
    for (i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--frames") && i + 1 < argc && (frames = atoi(argv[i + 1])) > 0) ++i;
        else if (!strcmp(argv[i], "--rsm") && i + 1 < argc && (rsm = atoi(argv[i + 1])) > 0) ++i;
        else if (!strcmp(argv[i], "--screenshot") && i + 1 < argc) shot = argv[++i];
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%dx%d", &width, &height) == 2 &&
                 width >= 16 && height >= 16 && width <= 4096 && height <= 4096) ++i;
        else { fprintf(stderr, PROG ": bad option %s (--size WxH, --frames N, --rsm N, --screenshot FILE.png)\n", argv[i]); return 2; }
    }
    if (shot && frames <= 0) { fprintf(stderr, PROG ": --screenshot needs --frames N\n"); return 2; }
    if (!glfwInit()) { fprintf(stderr, PROG ": no window system (GLFW cannot start; is DISPLAY set?)\n"); return 1; }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);   /* the G-buffer keeps the first size */
    if (!(win = glfwCreateWindow(width, height, PROG, NULL, NULL))) FAIL("cannot open a GL 4.3 core window");
    glfwMakeContextCurrent(win);
    glfwSwapInterval(frames > 0 ? 0 : 1);
    glfwGetFramebufferSize(win, &width, &height);

    /* The engine's buffers: geometry, then the caches from the same arrays, once, on the CPU. */
    build_scene(&g);
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)g.quads * 4 * STRIDE, g.v, GL_STATIC_DRAW);
    glGenBuffers(1, &ibo);
    glBindBuffer(GL_ARRAY_BUFFER, ibo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)g.quads * 12, g.idx, GL_STATIC_DRAW);
    memset(&cd, 0, sizeof cd);
    cd.mesh.positions = g.v;
    cd.mesh.position_stride = STRIDE;
    cd.mesh.normals = g.v + 3;
    cd.mesh.normal_stride = STRIDE;
    cd.mesh.vertex_count = g.quads * 4;
    cd.mesh.indices = g.idx;
    cd.mesh.index_count = g.quads * 6;
    cd.mesh.index_type = GIM_INDEX_U16;
    cd.env.logger.func = log_gimany;
    cd.d_eps = 0.125f;   /* a cache within 1/8 of every point: 16 across a wall */
    CHECK(gim_cache_generate(&cd, &caches));

    /* the light: a spot under the ceiling, aimed down, in the engine's light buffer */
    memset(&spot, 0, sizeof spot);
    spot.color_power[0] = spot.color_power[1] = spot.color_power[2] = 1.0f;
    spot.color_power[3] = 3.0f;                                   /* intensity, per steradian */
    spot.position_cone[1] = 1.95f; spot.position_cone[3] = 1.2f;  /* y, half-angle (radians) */
    spot.direction_extent[1] = -1.0f;
    spot.type_square_size_fit[0] = GIM_LIGHT_SPOT;
    spot.type_square_size_fit[2] = (uint32_t)rsm;                 /* RSM size: gimany checks it */
    glGenBuffers(1, &lbo);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, lbo);
    glBufferData(GL_SHADER_STORAGE_BUFFER, sizeof spot, &spot, GL_STATIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);

    memset(&gd, 0, sizeof gd);
    gd.get_proc_address = (gim_gl_proc (*)(const char *))glfwGetProcAddress;
    gd.env.logger.func = log_gimany;
    CHECK(gim_create(&gd, &ctx));
    memset(&md, 0, sizeof md);
    md.data.vertex_count = g.quads * 4;
    md.data.index_count = g.quads * 6;
    md.data.index_type = GIM_INDEX_U16;
    md.data.triangle_material = g.tri_mat;
    md.caches = &caches;
    md.buffers.positions = md.buffers.normals = vbo;
    md.buffers.position_stride = md.buffers.normal_stride = STRIDE;
    md.buffers.normal_offset = 12;
    md.buffers.indices = ibo;
    CHECK(gim_add_mesh(ctx, &md, &mesh));
    inst.mesh = mesh;
    inst.model = gim_mat4_identity();
    CHECK(gim_set_materials(ctx, materials, 3));
    CHECK(gim_set_instances(ctx, &inst, 1));
    CHECK(gim_set_lights_buffer(ctx, lbo, 1));

    /* the engine's G-buffer: depth, octahedral normals (RG16), albedo, direct light */
    tex[0] = texture(GL_DEPTH_COMPONENT32F, width, height);
    tex[1] = texture(GL_RG16, width, height);
    tex[2] = texture(GL_RGBA8, width, height);
    tex[3] = texture(GL_RGBA16F, width, height);
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, tex[0], 0);
    for (i = 0; i < 3; ++i) glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + (GLenum)i, GL_TEXTURE_2D, tex[1 + i], 0);
    {
        static const GLenum bufs[3] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2};
        glDrawBuffers(3, bufs);
    }
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) FAIL("G-buffer framebuffer incomplete");
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    for (i = 0; i < 3; ++i) {
        glEnableVertexAttribArray((GLuint)i);
        glVertexAttribPointer((GLuint)i, i == 2 ? 2 : 3, GL_FLOAT, GL_FALSE, STRIDE, (const void *)(size_t)(i * 12));
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo);
    glBindVertexArray(0);
    glGenVertexArrays(1, &empty_vao);
    if (!(gprog = program(gbuf_vs, gbuf_fs)) || !(cprog = program(comp_vs, comp_fs))) goto out;

    for (frame = 0; !glfwWindowShouldClose(win) && (frames <= 0 || frame < frames); ++frame) {
        gim_frame f;
        gim_mat4 vp;
        static const float far_depth = 1.0f, zero[4] = {0, 0, 0, 0};
        int m;
        glfwPollEvents();
        memset(&f, 0, sizeof f);
        f.view = gim_mat4_look_at(gim_v3(0.0f, 1.0f, 3.4f), gim_v3(0.0f, 1.0f, 0.0f), gim_v3(0, 1, 0));
        f.proj = gim_mat4_perspective(0.8f, (float)width / (float)height, 0.05f, 20.0f);
        vp = gim_mat4_mul(f.proj, f.view);
        /* 1. the engine's G-buffer and direct light */
        glBindFramebuffer(GL_FRAMEBUFFER, fbo);
        glViewport(0, 0, width, height);
        glEnable(GL_DEPTH_TEST);
        glClearBufferfv(GL_DEPTH, 0, &far_depth);
        for (i = 0; i < 3; ++i) glClearBufferfv(GL_COLOR, i, zero);
        glUseProgram(gprog);
        glUniformMatrix4fv(glGetUniformLocation(gprog, "view_proj"), 1, GL_FALSE, vp.m);
        glUniform1i(glGetUniformLocation(gprog, "light_count"), 1);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, lbo);
        glBindVertexArray(vao);
        for (m = 0; m < 3; ++m) {
            glUniform3fv(glGetUniformLocation(gprog, "albedo"), 1, materials[m].diffuse);
            glDrawElements(GL_TRIANGLES, (GLsizei)((g.first[m + 1] - g.first[m]) * 6), GL_UNSIGNED_SHORT,
                           (const void *)(size_t)(g.first[m] * 12));
        }
        glDisable(GL_DEPTH_TEST);
        glBindFramebuffer(GL_FRAMEBUFFER, 0);
        /* 2. gimany's indirect light on that G-buffer */
        f.width = (uint32_t)width;
        f.height = (uint32_t)height;
        f.gbuffer.depth = tex[0];
        f.gbuffer.normal = tex[1];
        f.gbuffer.normal_encoding = GIM_NORMAL_OCTAHEDRAL_UNORM;
        f.lightskin.val_count = 512;
        f.frame_index = (uint32_t)frame;
        f.lightskin.rotate_view_samples = 1;
        CHECK(gim_update(ctx, &f));
        /* 3. composite to the window */
        glUseProgram(cprog);
        glUniform1f(glGetUniformLocation(cprog, "exposure"), 2.0f);
        for (i = 0; i < 3; ++i) {
            glActiveTexture(GL_TEXTURE0 + (GLenum)i);
            glBindTexture(GL_TEXTURE_2D, i == 0 ? tex[3] : i == 1 ? tex[2] : gim_outputs(ctx).indirect);
        }
        glActiveTexture(GL_TEXTURE0);
        glBindVertexArray(empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        if (frames > 0 && frame + 1 == frames && shot) {
            unsigned char *rgb = (unsigned char *)malloc((size_t)width * height * 3);
            int ok;
            if (!rgb) FAIL("out of memory");
            glPixelStorei(GL_PACK_ALIGNMENT, 1);
            glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, rgb);
            stbi_flip_vertically_on_write(1);
            ok = stbi_write_png(shot, width, height, 3, rgb, width * 3);
            free(rgb);
            if (!ok) FAIL("cannot write %s", shot);
            printf("wrote %s\n", shot);
        }
        glfwSwapBuffers(win);
    }
    {   /* the last frame's indirect light, read back once */
        double sum = 0.0;
        size_t n = (size_t)width * height, k;
        if (!(rgba = (float *)malloc(n * 16))) FAIL("out of memory");
        glBindTexture(GL_TEXTURE_2D, gim_outputs(ctx).indirect);
        glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, rgba);
        for (k = 0; k < n; ++k) sum += (double)rgba[k * 4] + rgba[k * 4 + 1] + rgba[k * 4 + 2];
        printf("indirect mean %.6g\n", sum / (double)(n * 3));
    }
    if (glGetError() != GL_NO_ERROR) FAIL("a GL error");
    rc = 0;
out:
    free(rgba);
    if (ctx) gim_destroy(ctx);   /* before the buffers it draws from go */
    gim_cache_set_free(&caches);
    if (win) {
        glDeleteProgram(gprog);
        glDeleteProgram(cprog);
        glDeleteTextures(4, tex);
        glDeleteFramebuffers(1, &fbo);
        glDeleteVertexArrays(1, &vao);
        glDeleteVertexArrays(1, &empty_vao);
        glDeleteBuffers(1, &vbo);
        glDeleteBuffers(1, &ibo);
        glDeleteBuffers(1, &lbo);
        glfwDestroyWindow(win);
    }
    glfwTerminate();
    return rc;
}
