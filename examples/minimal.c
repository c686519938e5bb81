/* gimany-minimal - the smallest whole host of gimany: a GLFW window, a Cornell-like box built in
   code (one mesh, a material per triangle), a spot under the ceiling, the host's own direct
   light (unshadowed, to stay short) plus gimany's indirect light. It needs gimany.h,
   shaders_embedded.h, GLFW and the system's GL headers, nothing else. Per frame:
     gim_update (gimany draws its RSM and G-buffer, selects VALs, shades the indirect texture)
     -> one forward pass of the host: albedo / pi x the spot's irradiance + gimany's indirect
        radiance at the same pixel (its own G-buffer already applied the albedo), tone mapped.
   Usage: gimany-minimal [--size WxH] [--frames N] [--pfm FILE]
     --frames N  render N frames, then exit (default: until the window closes)
     --pfm FILE  with --frames: write the last frame's indirect radiance (linear rgb) to FILE
   At the end it prints "indirect mean X" and "window mean Y" (the shown image, 0..1). */
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

#define PROG "gimany-minimal"
#define FAIL(...) do { fprintf(stderr, PROG ": " __VA_ARGS__); fputc('\n', stderr); goto out; } while (0)
#define CHECK(call) do { if ((call) != GIM_OK) FAIL("%s: %s", #call, last_error); } while (0)

enum { QUADS = 10, VERT = 9 };   /* vertex: position, normal, albedo (9 floats, 36 bytes) */
static float verts[QUADS * 4 * VERT];
static uint16_t idx[QUADS * 6];
static uint32_t tri_mat[QUADS * 2];
static const gim_material mats[3] = {{{0.75f, 0.75f, 0.75f}, {0, 0, 0}, 0}, {{0.7f, 0.12f, 0.1f}, {0, 0, 0}, 0},
                                     {{0.12f, 0.6f, 0.15f}, {0, 0, 0}, 0}};

/* Quad q: corner o, edges u and w, facing u x w, material m. */
static void quad(int q, uint32_t m, const float *o, const float *u, const float *w) {
    float n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    float l = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    int c, k;
    for (c = 0; c < 4; ++c) {
        float s = (float)(c == 1 || c == 2), t = (float)(c >= 2), *v = verts + (q * 4 + c) * VERT;
        for (k = 0; k < 3; ++k) { v[k] = o[k] + s * u[k] + t * w[k]; v[3 + k] = n[k] / l; v[6 + k] = mats[m].diffuse[k]; }
    }
    for (c = 0; c < 6; ++c) idx[q * 6 + c] = (uint16_t)(q * 4 + (c < 3 ? c : c == 3 ? 0 : c - 2));
    tri_mat[q * 2] = tri_mat[q * 2 + 1] = m;
}

/* A 2 x 2 x 2 box open towards the camera (+z) and a block: every normal u x w points into the
   box and out of the block (gimany's caches and G-buffer take the normals as given). */
static void build_scene(void) {
    static const float q[QUADS][9] = {   /* corner, u, w */
        {-1, 0, 1, 2, 0, 0, 0, 0, -2}, {-1, 2, -1, 2, 0, 0, 0, 0, 2}, {-1, 0, -1, 2, 0, 0, 0, 2, 0},   /* floor, ceiling, back */
        {-1, 0, -1, 0, 2, 0, 0, 0, 2}, {1, 0, -1, 0, 0, 2, 0, 2, 0},                                  /* left, right */
        {-0.65f, 0, 0, 0.6f, 0, 0, 0, 1.2f, 0}, {-0.05f, 0, -0.6f, -0.6f, 0, 0, 0, 1.2f, 0},           /* block */
        {-0.65f, 0, -0.6f, 0, 0, 0.6f, 0, 1.2f, 0}, {-0.05f, 0, 0, 0, 0, -0.6f, 0, 1.2f, 0},
        {-0.65f, 1.2f, 0, 0.6f, 0, 0, 0, 0, -0.6f}};
    int i;
    for (i = 0; i < QUADS; ++i) quad(i, i == 3 ? 1u : i == 4 ? 2u : 0u, q[i], q[i] + 3, q[i] + 6);
}

static const char *vs_src =
    "#version 430 core\n"
    "layout(location = 0) in vec3 pos; layout(location = 1) in vec3 nrm; layout(location = 2) in vec3 alb;\n"
    "uniform mat4 view_proj; out vec3 wpos; out vec3 wnrm; out vec3 walb;\n"
    "void main() { wpos = pos; wnrm = nrm; walb = alb; gl_Position = view_proj * vec4(pos, 1.0); }\n";
static const char *fs_src =
    "#version 430 core\n"
    "uniform vec3 spot_pos, spot_dir; uniform float spot_cos, spot_intensity;\n"
    "layout(binding = 0) uniform sampler2D indirect;\n"
    "in vec3 wpos; in vec3 wnrm; in vec3 walb; out vec4 color;\n"
    "void main() {\n"
    "  vec3 n = normalize(wnrm), d = spot_pos - wpos;\n"
    "  float r2 = dot(d, d); d *= inversesqrt(r2);\n"   /* E = I cos / d^2 inside the cone */
    "  float e = spot_intensity * max(dot(n, d), 0.0) / r2 * step(spot_cos, dot(-d, spot_dir));\n"
    "  vec3 c = walb / 3.14159265 * e + texelFetch(indirect, ivec2(gl_FragCoord.xy), 0).rgb;\n"
    "  color = vec4(pow(1.0 - exp(-2.0 * c), vec3(1.0 / 2.2)), 1.0);\n"   /* exponential tone map */
    "}\n";

static GLuint program(void) {
    const char *src[2] = {vs_src, fs_src};
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
    return ok ? p : 0;
}

static char last_error[512] = "no message";   /* gimany's last error, for the failing call's line */
static void log_gimany(gim_log_level level, const char *message, void *user) {
    (void)user;
    if (level == GIM_LOG_ERROR) snprintf(last_error, sizeof last_error, "%s", message);
}

int main(int argc, char **argv) {
    int width = 320, height = 240, frames = 0, frame, i, rc = 1;
    size_t npx, k;   /* pixels; index */
    const char *pfm = NULL;
    GLFWwindow *win = NULL;
    gim_context *ctx = NULL;
    gim_desc gd = {0};
    gim_cache_desc cd = {0};
    gim_cache_set caches = {0};
    gim_mesh_desc md = {0};
    gim_mesh mesh;
    gim_instance inst;
    gim_light spot = {0};
    GLuint vbo = 0, ibo = 0, vao = 0, prog = 0;
    float *rgba = NULL;
    for (i = 1; i < argc; ++i) {
        if (!strcmp(argv[i], "--frames") && i + 1 < argc && (frames = atoi(argv[i + 1])) > 0) ++i;
        else if (!strcmp(argv[i], "--pfm") && i + 1 < argc) pfm = argv[++i];
        else if (!strcmp(argv[i], "--size") && i + 1 < argc && sscanf(argv[i + 1], "%dx%d", &width, &height) == 2 &&
                 width >= 16 && height >= 16 && width <= 4096 && height <= 4096) ++i;
        else { fprintf(stderr, PROG ": bad option %s (--size WxH, --frames N, --pfm FILE)\n", argv[i]); return 2; }
    }
    if (pfm && frames <= 0) { fprintf(stderr, PROG ": --pfm needs --frames N\n"); return 2; }
    if (!glfwInit()) { fprintf(stderr, PROG ": no window system (GLFW cannot start; is DISPLAY set?)\n"); return 1; }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);   /* gimany needs GL 4.3 core */
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
    if (!(win = glfwCreateWindow(width, height, PROG, NULL, NULL))) FAIL("cannot open a GL 4.3 core window");
    glfwMakeContextCurrent(win);
    glfwGetFramebufferSize(win, &width, &height);
    npx = (size_t)width * (size_t)height;

    /* The scene to gimany: caches (once, on the CPU), the mesh, materials, one instance, the spot. */
    build_scene();
    cd.mesh.positions = verts;
    cd.mesh.position_stride = VERT * 4;
    cd.mesh.normals = verts + 3;
    cd.mesh.normal_stride = VERT * 4;
    cd.mesh.vertex_count = QUADS * 4;
    cd.mesh.indices = idx;
    cd.mesh.index_count = QUADS * 6;
    cd.mesh.index_type = GIM_INDEX_U16;
    cd.env.logger.func = log_gimany;
    CHECK(gim_cache_generate(&cd, &caches));   /* one mesh: its own scale is the scene's */
    gd.get_proc_address = (gim_gl_proc (*)(const char *))glfwGetProcAddress;
    gd.env.logger.func = log_gimany;
    CHECK(gim_create(&gd, &ctx));
    md.data = cd.mesh;
    md.data.triangle_material = tri_mat;
    md.caches = &caches;
    CHECK(gim_add_mesh(ctx, &md, &mesh));
    inst.mesh = mesh;
    inst.model = gim_mat4_identity();
    CHECK(gim_set_materials(ctx, mats, 3));
    CHECK(gim_set_instances(ctx, &inst, 1));
    spot.type = GIM_LIGHT_SPOT;
    spot.intensity = 3.0f;                         /* per steradian */
    spot.position = gim_v3(0.0f, 1.95f, 0.0f);     /* under the ceiling, aimed down */
    spot.direction = gim_v3(0.0f, -1.0f, 0.0f);
    spot.cone_angle = 1.2f;                        /* half-angle, radians */
    spot.rsm_size = 128;
    CHECK(gim_set_lights(ctx, &spot, 1));

    /* The host's own copy of the mesh, for its direct light. */
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenBuffers(1, &vbo);
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, sizeof verts, verts, GL_STATIC_DRAW);
    glGenBuffers(1, &ibo);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, sizeof idx, idx, GL_STATIC_DRAW);
    for (i = 0; i < 3; ++i) {
        glEnableVertexAttribArray((GLuint)i);
        glVertexAttribPointer((GLuint)i, 3, GL_FLOAT, GL_FALSE, VERT * 4, (const void *)(size_t)(i * 12));
    }
    glBindVertexArray(0);
    if (!(prog = program())) FAIL("the host's shader did not build");

    for (frame = 0; !glfwWindowShouldClose(win) && (frames <= 0 || frame < frames); ++frame) {
        gim_frame f = {0};
        gim_mat4 vp;
        glfwPollEvents();
        f.view = gim_mat4_look_at(gim_v3(0.0f, 1.0f, 3.4f), gim_v3(0.0f, 1.0f, 0.0f), gim_v3(0, 1, 0));
        f.proj = gim_mat4_perspective(0.8f, (float)width / (float)height, 0.05f, 20.0f);
        f.width = (uint32_t)width;
        f.height = (uint32_t)height;
        f.method = GIM_METHOD_LIGHTSKIN_BRSM;
        f.frame_index = (uint32_t)frame;
        CHECK(gim_update(ctx, &f));
        vp = gim_mat4_mul(f.proj, f.view);
        glViewport(0, 0, width, height);
        glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        glUseProgram(prog);
        glUniformMatrix4fv(glGetUniformLocation(prog, "view_proj"), 1, GL_FALSE, vp.m);
        glUniform3f(glGetUniformLocation(prog, "spot_pos"), spot.position.x, spot.position.y, spot.position.z);
        glUniform3f(glGetUniformLocation(prog, "spot_dir"), spot.direction.x, spot.direction.y, spot.direction.z);
        glUniform1f(glGetUniformLocation(prog, "spot_cos"), cosf(spot.cone_angle));
        glUniform1f(glGetUniformLocation(prog, "spot_intensity"), spot.intensity);
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, gim_outputs(ctx).indirect);
        glBindVertexArray(vao);
        glDrawElements(GL_TRIANGLES, QUADS * 6, GL_UNSIGNED_SHORT, NULL);
        glBindVertexArray(0);
        glDisable(GL_DEPTH_TEST);
        if (frame + 1 == frames) {   /* the last frame: what the window shows, before the swap */
            double sum = 0.0;
            unsigned char *rgb = (unsigned char *)malloc(npx * 3);
            if (!rgb) FAIL("out of memory");
            glPixelStorei(GL_PACK_ALIGNMENT, 1);
            glReadPixels(0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE, rgb);
            for (k = 0; k < npx * 3; ++k) sum += rgb[k];
            free(rgb);
            printf("window mean %.4f\n", sum / 255.0 / (double)(npx * 3));
        }
        glfwSwapBuffers(win);
    }
    {   /* the last frame's indirect light, read back once (PFM: rows bottom to top, as GL's) */
        double sum = 0.0;
        FILE *fp;
        if (!(rgba = (float *)malloc(npx * 16))) FAIL("out of memory");
        glBindTexture(GL_TEXTURE_2D, gim_outputs(ctx).indirect);
        glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, rgba);
        for (k = 0; k < npx; ++k) {
            sum += (double)rgba[k * 4] + rgba[k * 4 + 1] + rgba[k * 4 + 2];
            memmove(rgba + k * 3, rgba + k * 4, 12);   /* rgba -> rgb in place */
        }
        printf("indirect mean %.6g\n", sum / (double)(npx * 3));
        if (pfm) {
            if (!(fp = fopen(pfm, "wb"))) FAIL("cannot write %s", pfm);
            fprintf(fp, "PF\n%d %d\n-1.0\n", width, height);   /* -1: little-endian floats */
            k = fwrite(rgba, 12, npx, fp);
            if (fclose(fp) != 0 || k != npx) FAIL("cannot write %s", pfm);
        }
    }
    if (glGetError() != GL_NO_ERROR) FAIL("a GL error");
    rc = 0;
out:
    free(rgba);
    if (ctx) gim_destroy(ctx);
    gim_cache_set_free(&caches);
    if (win) {
        glDeleteProgram(prog);
        glDeleteBuffers(1, &vbo);
        glDeleteBuffers(1, &ibo);
        glDeleteVertexArrays(1, &vao);
        glfwDestroyWindow(win);
    }
    glfwTerminate();
    return rc;
}
