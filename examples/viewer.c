/* gimany-viewer - the demo in a window (GLFW, GL 4.3 core): the code to copy into an engine.
   Per frame: gim_set_lights (when the sun moves) -> gim_update -> the direct light and the
   final image of examples/display.h (the same passes as build/gimany-demo, so the same picture)
   -> blit to the window. Options: those of gimany-demo (--help), plus --screenshot FILE; with
   --frames N it renders N frames, writes the screenshot (if asked) and exits.

   Keys:  W A S D  move, Q E  down / up, Shift  faster; drag with the left button to look around
          1 2 3    method brsm / full / none          [ ]  halve / double the VAL count
          4 5      method clustered / ssvp
          - =      halve / double the RSM size         I  imperfect shadow maps on / off
          Space    animate the sun (turns about +Y)   X  re-meter the exposure
          P        screenshot (gimany-viewer-N.png)    Esc  quit
   The title shows the method, its parameters and the per-pass GPU times (GL timestamps). */
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
#include "scene_gimany.h"
#include "display.h"
#include "options.h"
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

#define PROG "gimany-viewer"

typedef struct viewer {
    scene s;
    demo_options d;
    gim_context *ctx;
    scene_gimany g;
    gim_mesh *plain;            /* the meshes without caches, for method none */
    gim_instance *plain_inst;
    display dp;
    gim_light lights[SCENE_GIMANY_MAX_LIGHTS];
    float yaw, pitch;           /* of the view direction; used once the camera moved */
    int moved, dragging, animate, meter, shots, lights_dirty, instances_dirty;
    int bounces;                /* --bounces: 1, or 2 with clustered / ssvp */
    double drag_x, drag_y, sun_angle;
    float exposure;
} viewer;

static void viewer_log(gim_log_level level, const char *message, void *user) {
    (void)user;
    if (level != GIM_LOG_INFO) fprintf(stderr, PROG ": %s: %s\n", level == GIM_LOG_ERROR ? "error" : "warning", message);
}

static void glfw_error(int code, const char *message) { fprintf(stderr, PROG ": GLFW error 0x%x: %s\n", code, message); }

static int write_screenshot(viewer *v, const char *path) {
    unsigned char *rgb = (unsigned char *)malloc((size_t)v->dp.width * v->dp.height * 3);
    int ok;
    if (!rgb) return 0;
    display_read_final(&v->dp, rgb);
    ok = stbi_write_png(path, (int)v->dp.width, (int)v->dp.height, 3, rgb, (int)v->dp.width * 3);
    free(rgb);
    if (ok) printf("wrote %s\n", path);
    else fprintf(stderr, PROG ": cannot write %s\n", path);
    return ok;
}

static void on_key(GLFWwindow *w, int key, int scancode, int action, int mods) {
    viewer *v = (viewer *)glfwGetWindowUserPointer(w);
    uint32_t i;
    (void)scancode; (void)mods;
    if (action != GLFW_PRESS && action != GLFW_REPEAT) return;
    switch (key) {
    case GLFW_KEY_ESCAPE: glfwSetWindowShouldClose(w, 1); break;
    case GLFW_KEY_1: v->d.method = "brsm"; v->instances_dirty = 1; break;
    case GLFW_KEY_2: v->d.method = "full"; v->instances_dirty = 1; break;
    case GLFW_KEY_3: v->d.method = "none"; v->instances_dirty = 1; break;
    case GLFW_KEY_4: v->d.method = "clustered"; v->instances_dirty = 1; break;
    case GLFW_KEY_5: v->d.method = "ssvp"; v->instances_dirty = 1; break;
    case GLFW_KEY_LEFT_BRACKET: if (v->d.vals > 16) v->d.vals /= 2; break;
    case GLFW_KEY_RIGHT_BRACKET: if (v->d.vals < (1u << 20)) v->d.vals *= 2; break;
    case GLFW_KEY_MINUS:
    case GLFW_KEY_EQUAL: {
        GLint max_tex = 0;
        glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
        if (key == GLFW_KEY_MINUS && v->d.rsm > 16) v->d.rsm /= 2;
        if (key == GLFW_KEY_EQUAL && v->d.rsm * 2 <= (uint32_t)max_tex && v->d.rsm < 8192) v->d.rsm *= 2;
        for (i = 0; i < v->g.light_count; ++i) v->lights[i].rsm_size = v->d.rsm;
        v->lights_dirty = 1;
        break;
    }
    case GLFW_KEY_I: v->d.ism = !v->d.ism; break;
    case GLFW_KEY_SPACE: v->animate = !v->animate; break;
    case GLFW_KEY_X: v->meter = 1; break;
    case GLFW_KEY_P: {
        char path[64];
        snprintf(path, sizeof path, "gimany-viewer-%d.png", ++v->shots);
        write_screenshot(v, path);
        break;
    }
    default: break;
    }
}

/* The view direction from yaw and pitch (yaw 0 looks down -Z, pitch up positive). */
static void view_dir(const viewer *v, float out[3]) {
    out[0] = -sinf(v->yaw) * cosf(v->pitch);
    out[1] = sinf(v->pitch);
    out[2] = -cosf(v->yaw) * cosf(v->pitch);
}

/* Fly camera: WASD / QE along the view, Shift x4; drag to turn. Moves s.camera. */
static void fly(viewer *v, GLFWwindow *w, double dt) {
    float dir[3], right[3], speed = 0.05f * v->s.scale * (float)dt, move[3] = {0, 0, 0}, dist;
    double cx, cy;
    int k;
    glfwGetCursorPos(w, &cx, &cy);
    if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
        if (v->dragging && (cx != v->drag_x || cy != v->drag_y)) {
            v->yaw -= (float)(cx - v->drag_x) * 0.004f;
            v->pitch -= (float)(cy - v->drag_y) * 0.004f;
            if (v->pitch > 1.55f) v->pitch = 1.55f;
            if (v->pitch < -1.55f) v->pitch = -1.55f;
            v->moved = 1;
        }
        v->dragging = 1;
    } else {
        v->dragging = 0;
    }
    v->drag_x = cx;
    v->drag_y = cy;
    if (glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS) speed *= 4.0f;
    view_dir(v, dir);
    right[0] = -dir[2]; right[1] = 0.0f; right[2] = dir[0];
    dist = sqrtf(right[0] * right[0] + right[2] * right[2]);
    if (dist > 0.0f) { right[0] /= dist; right[2] /= dist; }
    for (k = 0; k < 3; ++k) {
        if (glfwGetKey(w, GLFW_KEY_W) == GLFW_PRESS) move[k] += dir[k];
        if (glfwGetKey(w, GLFW_KEY_S) == GLFW_PRESS) move[k] -= dir[k];
        if (glfwGetKey(w, GLFW_KEY_D) == GLFW_PRESS) move[k] += right[k];
        if (glfwGetKey(w, GLFW_KEY_A) == GLFW_PRESS) move[k] -= right[k];
    }
    if (glfwGetKey(w, GLFW_KEY_E) == GLFW_PRESS) move[1] += 1.0f;
    if (glfwGetKey(w, GLFW_KEY_Q) == GLFW_PRESS) move[1] -= 1.0f;
    if (move[0] != 0.0f || move[1] != 0.0f || move[2] != 0.0f) v->moved = 1;
    if (!v->moved) return;   /* untouched: exactly the scene's camera, as the demo renders it */
    for (k = 0; k < 3; ++k) {
        v->s.camera.eye[k] += move[k] * speed;
        v->s.camera.target[k] = v->s.camera.eye[k] + dir[k];
    }
}

static const char *short_pass[GIM_PASS_COUNT] = {"rsm", "gbuf", "vs", "imp", "scan", "sel", "cache", "vals", "proxy", "shade",
                                                   "vpls", "kmean", "parab", "2nd", "blur", "ism"};

static void set_title(viewer *v, GLFWwindow *w, const gim_stats *st, double direct_ms, double compose_ms) {
    char t[1024];
    int n, p;
    n = snprintf(t, sizeof t, PROG " | %s | VALs %u | RSM %u | ISM %s | %.1f ms |", v->d.method,
                 (unsigned)(strcmp(v->d.method, "brsm") ? st->val_count : v->d.vals), (unsigned)v->d.rsm,
                 v->d.ism ? "on" : "off", st->frame_ms + direct_ms + compose_ms);
    for (p = 0; p < GIM_PASS_COUNT && n > 0 && n < (int)sizeof t; ++p)
        if (st->pass_ms[p] > 0.005) n += snprintf(t + n, sizeof t - (size_t)n, " %s %.1f", short_pass[p], st->pass_ms[p]);
    if (n > 0 && n < (int)sizeof t) snprintf(t + n, sizeof t - (size_t)n, " direct %.1f", direct_ms);
    glfwSetWindowTitle(w, t);
}

static int run(viewer *v, GLFWwindow *w) {
    GLuint fbo = 0;
    double last = glfwGetTime(), title_at = 0.0;
    uint32_t frame = 0;
    int fw = 0, fh = 0, rc = 0;
    float base_dir[3] = {0, 1, 0};
    int sun = -1;
    uint32_t i;
    for (i = 0; i < v->g.light_count; ++i)
        if (v->lights[i].type == GIM_LIGHT_DIRECTIONAL && sun < 0) {
            sun = (int)i;
            base_dir[0] = v->lights[i].direction.x; base_dir[1] = v->lights[i].direction.y; base_dir[2] = v->lights[i].direction.z;
        }
    glGenFramebuffers(1, &fbo);
    v->meter = 1;
    while (!glfwWindowShouldClose(w)) {
        gim_frame f;
        gim_frame_outputs o;
        gim_stats st;
        double now = glfwGetTime(), dt = now - last, direct_ms, compose_ms;
        int last_frame = v->d.frames > 0 && frame + 1u == v->d.frames;
        last = now;
        glfwPollEvents();
        fly(v, w, dt);
        if (v->animate && sun >= 0) { /* the sun turns about +Y at 0.3 rad/s, its elevation kept */
            float c, s_;
            v->sun_angle += 0.3 * dt;
            c = cosf((float)v->sun_angle);
            s_ = sinf((float)v->sun_angle);
            v->lights[sun].direction = gim_v3(c * base_dir[0] + s_ * base_dir[2], base_dir[1], -s_ * base_dir[0] + c * base_dir[2]);
            v->lights_dirty = 1;
        }
        if (v->lights_dirty) {
            if (gim_set_lights(v->ctx, v->lights, v->g.light_count) != GIM_OK) { rc = 1; break; }
            v->lights_dirty = 0;
        }
        if (v->instances_dirty) {
            int none = !strcmp(v->d.method, "none");
            if (gim_set_instances(v->ctx, none ? v->plain_inst : v->g.instances, v->g.mesh_count) != GIM_OK) { rc = 1; break; }
            v->instances_dirty = 0;
        }
        glfwGetFramebufferSize(w, &fw, &fh);
        if (fw <= 0 || fh <= 0) { glfwWaitEvents(); continue; }  /* minimised */
        v->s.camera.width = (uint32_t)fw;
        v->s.camera.height = (uint32_t)fh;
        memset(&f, 0, sizeof f);
        scene_gimany_camera(&v->s, &f.view, &f.proj);
        f.width = (uint32_t)fw;
        f.height = (uint32_t)fh;
        demo_frame_settings(&v->d, v->bounces, &f);
        f.frame_index = frame;
        f.timing = 1;
        if (gim_update(v->ctx, &f) != GIM_OK) { rc = 1; break; }
        o = gim_outputs(v->ctx);
        display_direct(&v->dp, &o, f.view, f.proj, 1);
        if (v->meter || (last_frame && v->d.exposure <= 0.0f)) {
            /* Reinhard's key from this frame (the demo meters its last frame the same way) */
            float *dr = (float *)malloc((size_t)fw * fh * 16), *ir = (float *)malloc((size_t)fw * fh * 16);
            if (dr && ir) {
                display_read(v->dp.direct, dr);
                if (o.indirect) display_read(o.indirect, ir);
                v->exposure = v->d.exposure > 0.0f ? v->d.exposure : display_auto_exposure(dr, o.indirect ? ir : NULL, (uint32_t)(fw * fh));
            }
            free(dr);
            free(ir);
            v->meter = 0;
        }
        display_compose(&v->dp, o.indirect, v->exposure);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
        glFramebufferTexture2D(GL_READ_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, v->dp.final_image, 0);
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
        glBlitFramebuffer(0, 0, fw, fh, 0, 0, fw, fh, GL_COLOR_BUFFER_BIT, GL_NEAREST);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        glfwSwapBuffers(w);
        if (gim_frame_stats(v->ctx, &st) == GIM_OK && display_timings(&v->dp, &direct_ms, &compose_ms) && now >= title_at) {
            set_title(v, w, &st, direct_ms, compose_ms);
            title_at = now + 0.5;
        }
        frame++;
        if (last_frame) {
            if (v->d.screenshot && !write_screenshot(v, v->d.screenshot)) rc = 1;
            break;
        }
    }
    glDeleteFramebuffers(1, &fbo);
    return rc;
}

int main(int argc, char **argv) {
    viewer v;
    char err[512] = "", **rest;
    int rest_count = 0, pr, rc = 1;
    uint32_t i;
    GLFWwindow *w = NULL;
    gim_desc gd;
    gim_material *mats = NULL;
    memset(&v, 0, sizeof v);
    demo_defaults(&v.d, DEMO_PARSE_VIEWER);
    {
        scene_options o;
        scene_options_defaults(&o, ".");
        rest = (char **)calloc((size_t)argc + 1u, sizeof *rest);
        if (!rest) return 1;
        pr = demo_parse(argc, argv, DEMO_PARSE_VIEWER, &v.d, rest, &rest_count, err, sizeof err);
        if (pr == 1) {
            fputs("usage: gimany-viewer [options]\n", stdout);
            fputs(demo_usage_text, stdout);
            fputs(demo_usage_text2, stdout);
            fputs("  --frames N            render N frames and exit (default: until the window closes)\n"
                  "  --screenshot FILE     write the last frame as a PNG (with --frames)\n", stdout);
            fputs(scene_usage(0), stdout);
            free(rest);
            return 0;
        }
        if (pr == 0) pr = scene_parse_args(rest_count, rest, 0, &o, err, sizeof err) == SCENE_ARGS_OK ? 0 : -1;
        free(rest);
        if (pr != 0) { fprintf(stderr, PROG ": %s\n", err); return 2; }
        if (demo_bounces_unavailable(&v.d, o.bounces)) {
            fprintf(stderr, PROG ": --bounces %d %s\n", o.bounces, demo_bounces_unavailable(&v.d, o.bounces));
            return 2;
        }
        v.bounces = o.bounces;
        pr = scene_load(&o, &v.s, err, sizeof err);
        if (pr != 0) { fprintf(stderr, PROG ": %s\n", err); return 1; }
    }
    if (!v.d.glossy)
        for (i = 0; i < v.s.material_count; ++i) memset(v.s.materials[i].glossy, 0, sizeof v.s.materials[i].glossy);
    glfwSetErrorCallback(glfw_error);
    if (!glfwInit()) { fprintf(stderr, PROG ": no window system (GLFW cannot start; is DISPLAY set?)\n"); scene_free(&v.s); return 1; }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    w = glfwCreateWindow((int)v.s.camera.width, (int)v.s.camera.height, PROG, NULL, NULL);
    if (!w) { fprintf(stderr, PROG ": cannot open a GL 4.3 core window\n"); goto out; }
    glfwMakeContextCurrent(w);
    glfwSwapInterval(v.d.frames > 0 ? 0 : 1);
    glfwSetWindowUserPointer(w, &v);
    glfwSetKeyCallback(w, on_key);
    memset(&gd, 0, sizeof gd);
    gd.get_proc_address = (gim_gl_proc (*)(const char *))glfwGetProcAddress;
    gd.env.logger.func = viewer_log;
    if (gim_create(&gd, &v.ctx) != GIM_OK) goto out;
    if (scene_gimany_load(v.ctx, &v.s, 0.0f, v.d.rsm, gd.env, &v.g) != GIM_OK) goto out;
    {   /* the demo's limits on the starting settings (the keys can still raise them) */
        char why[512];
        if (demo_cost_check(&v.d, v.s.camera.width, v.s.camera.height, v.s.light_count,
                            strcmp(v.d.method, "none") ? v.g.cache_count : 0u, v.bounces, why, sizeof why)) {
            fprintf(stderr, PROG ": %s\n", why);
            goto out;
        }
    }
    memcpy(v.lights, v.g.lights, sizeof v.lights);
    v.plain = (gim_mesh *)calloc(v.g.mesh_count + 1u, sizeof *v.plain);
    v.plain_inst = (gim_instance *)calloc(v.g.mesh_count + 1u, sizeof *v.plain_inst);
    if (!v.plain || !v.plain_inst || scene_gimany_add_plain(v.ctx, &v.s, v.plain, v.plain_inst) != GIM_OK) goto out;
    if (!display_init(&v.dp)) { fprintf(stderr, PROG ": display shaders: %s\n", v.dp.error); goto out; }
    mats = (gim_material *)calloc(v.s.material_count + 1u, sizeof *mats);
    if (!mats) goto out;
    for (i = 0; i < v.s.material_count; ++i) {
        memcpy(mats[i].diffuse, v.s.materials[i].diffuse, sizeof mats[i].diffuse);
        memcpy(mats[i].glossy, v.s.materials[i].glossy, sizeof mats[i].glossy);
        mats[i].exponent = v.s.materials[i].exponent;
    }
    display_set_materials(&v.dp, mats, v.s.material_count);
    {   /* yaw and pitch of the scene's camera, for when the user starts to turn */
        float d[3], l;
        int k;
        for (k = 0; k < 3; ++k) d[k] = v.s.camera.target[k] - v.s.camera.eye[k];
        l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        v.pitch = asinf(d[1] / l);
        v.yaw = atan2f(-d[0], -d[2]);
    }
    v.instances_dirty = !strcmp(v.d.method, "none");
    rc = run(&v, w);
    if (glGetError() != GL_NO_ERROR) { fprintf(stderr, PROG ": a GL error\n"); rc = 1; }
out:
    free(mats);
    if (v.dp.direct_program) display_free(&v.dp);
    if (v.ctx) {
        for (i = 0; v.plain && i < v.g.mesh_count; ++i)
            if (v.plain[i].id) gim_remove_mesh(v.ctx, v.plain[i]);
        scene_gimany_free(v.ctx, &v.g);
        gim_destroy(v.ctx);
    }
    free(v.plain);
    free(v.plain_inst);
    if (w) glfwDestroyWindow(w);
    glfwTerminate();
    scene_free(&v.s);
    return rc;
}
