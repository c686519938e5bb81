/* display.h - what the demo and the viewer do with gimany's outputs to make a picture: the
   DIRECT light from gimany's G-buffer and each light's RSM depth as a shadow map, then the
   final image (direct + gimany's indirect, tone mapped, sRGB). Both programs call the same
   passes, so both show the same image. Two GL 4.3 compute passes; everything here is static.
   Include after gimany.h and a GL 4.3 header with prototypes (<GL/glcorearb.h> with
   GL_GLEXT_PROTOTYPES, linked with libGL).

   Direct light (the BRDF of scene/scene.h, Bischoff 2017 eq. 3-4, the same the reference uses)
       L_direct(x -> eye) = sum over lights  f_r(l, v) E_l (n . l)+ V(x)
       f_r = rho_d / pi + rho_g (k + 2) / (2 pi) cos+^k(theta_e),  theta_e between v and l mirrored at n
       sun:   E_l = E colour, l the direction towards the sun
       spot:  E_l = I colour / d^2 inside the cone (hard edge), 0 outside; l = (p - x) / d
   n is the G-buffer's normal (two-sided surfaces: turned towards the eye), rho_d the G-buffer
   albedo, rho_g and k the material's (G-buffer material id). x comes from the G-buffer depth
   through the inverse of proj x view.

   Visibility V(x) reads the light's RSM depth (gimany's gim_light_outputs.rsm_depth with its
   view and proj) as a shadow map, 3x3 texels averaged (PCF). The bias, unit-free: t is the
   world size of one RSM texel at x, its longer side (sun: the window's width or height / size; spot: 2 z tan(cone) / size at light
   distance z along the axis). x is moved by 1.5 t along n towards the lit side (normal offset:
   removes self-shadowing on slanted surfaces, whose depth changes by up to t tan(theta) within
   a texel), then x is lit where its light-space distance is at most the stored one + t. So
   contact shadows start about 1.5 texels from the occluder; raise --rsm for crisper ones.

   Final image: c = direct + indirect (linear radiance); exposure a = key / Lw (Reinhard et al.
   2002: Lw the log-average luminance of the surface pixels, key 0.18) unless given; then
   Reinhard on luminance, c' = a c / (1 + a L(c)), clamped to [0, 1] and sRGB encoded. Pixels
   without a surface are black. */
#ifndef GIMANY_EXAMPLES_DISPLAY_H
#define GIMANY_EXAMPLES_DISPLAY_H

#include <math.h>
#include <stdlib.h>
#include <string.h>

#if defined(__GNUC__) || defined(__clang__)
#define DISPLAY_FN static __attribute__((unused))
#else
#define DISPLAY_FN static
#endif

typedef struct display {
    GLuint direct_program, compose_program;
    GLuint direct;          /* RGBA32F: rgb direct radiance towards the eye, a = 1 where a surface is */
    GLuint final_image;     /* RGBA8: sRGB-encoded tone-mapped colour, a = 1 where a surface is */
    GLuint materials;       /* SSBO: {diffuse, glossy rgb + k} per material */
    GLuint black;           /* 1x1 RGBA32F zero texture, the indirect when there is none */
    GLuint queries[3];      /* timestamps: before direct, after direct, after compose */
    uint32_t width, height, material_count;
    int timed;              /* the last display_direct/display_compose pair was timed */
    char error[512];        /* the last shader compile / link log */
} display;

static const char display_direct_src[] =
    "#version 430\n"
    "layout(local_size_x = 8, local_size_y = 8) in;\n"
    "layout(binding = 0) uniform sampler2D g_depth;\n"
    "layout(binding = 1) uniform sampler2D g_normal;\n"
    "layout(binding = 2) uniform sampler2D g_albedo;\n"
    "layout(binding = 3) uniform sampler2D g_material;\n"
    "layout(binding = 4) uniform sampler2D shadow_map;\n"
    "layout(rgba32f, binding = 0) uniform image2D direct_out;\n"
    "struct Material { vec4 diffuse; vec4 glossy; };\n"
    "layout(std430, binding = 0) readonly buffer Materials { Material material[]; };\n"
    "layout(location = 0) uniform mat4 inv_view_proj;\n"
    "layout(location = 1) uniform vec3 eye;\n"
    "layout(location = 2) uniform ivec2 size;\n"
    "layout(location = 3) uniform int light_type;\n"      /* 0: clear only, 1: sun, 2: spot */
    "layout(location = 4) uniform vec3 power;\n"          /* E colour or I colour */
    "layout(location = 5) uniform vec3 light_dir;\n"      /* sun: towards it; spot: its axis */
    "layout(location = 6) uniform vec3 light_pos;\n"
    "layout(location = 7) uniform float cos_cone;\n"
    "layout(location = 8) uniform mat4 light_view;\n"
    "layout(location = 9) uniform mat4 light_proj;\n"
    "layout(location = 10) uniform int accumulate;\n"
    "layout(location = 11) uniform uint material_count;\n"
    "const float PI = 3.14159265358979;\n"
    /* distance along the light's -z axis of window depth d (ortho and perspective alike) */
    "float light_distance(float d) {\n"
    "    float zn = 2.0 * d - 1.0;\n"
    "    return -(light_proj[3][2] - zn * light_proj[3][3]) / (zn * light_proj[2][3] - light_proj[2][2]);\n"
    "}\n"
    "float visibility(vec3 x, vec3 n) {\n"
    "    ivec2 sm = textureSize(shadow_map, 0);\n"
    "    float z = -(light_view * vec4(x, 1.0)).z;\n"
    /* world size of one texel at x, its longer side: 2 / (min(P00, P11) size), times z in perspective (P33 = 0) */
    "    float t = 2.0 / (min(light_proj[0][0], light_proj[1][1]) * float(sm.x)) * (light_proj[3][3] == 0.0 ? max(z, 0.0) : 1.0);\n"
    "    vec3 xo = x + n * (1.5 * t);\n"
    "    vec4 v = light_view * vec4(xo, 1.0);\n"
    "    vec4 c = light_proj * v;\n"
    "    if (!(c.w > 0.0)) return light_type == 1 ? 1.0 : 0.0;\n"
    "    vec2 uv = c.xy / c.w * 0.5 + 0.5;\n"
    "    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0))))\n"
    "        return light_type == 1 ? 1.0 : 0.0;\n"   /* outside the sun's map: nothing there casts */
    "    ivec2 p = ivec2(uv * vec2(sm));\n"
    "    float lit = 0.0;\n"
    "    for (int dy = -1; dy <= 1; ++dy)\n"
    "        for (int dx = -1; dx <= 1; ++dx) {\n"
    "            ivec2 q = clamp(p + ivec2(dx, dy), ivec2(0), sm - 1);\n"
    "            float d = texelFetch(shadow_map, q, 0).r;\n"
    "            lit += (d >= 1.0 || -v.z <= light_distance(d) + t) ? 1.0 : 0.0;\n"
    "        }\n"
    "    return lit / 9.0;\n"
    "}\n"
    "void main() {\n"
    "    ivec2 px = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (px.x >= size.x || px.y >= size.y) return;\n"
    "    vec4 prev = accumulate != 0 ? imageLoad(direct_out, px) : vec4(0.0);\n"
    "    vec4 nw = texelFetch(g_normal, px, 0);\n"
    "    float d = texelFetch(g_depth, px, 0).r;\n"
    "    if (nw.w != 1.0 || !(d < 1.0) || light_type == 0) {\n"
    "        imageStore(direct_out, px, vec4(prev.rgb, nw.w == 1.0 && d < 1.0 ? 1.0 : 0.0));\n"
    "        return;\n"
    "    }\n"
    "    vec4 h = inv_view_proj * vec4((vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0, 2.0 * d - 1.0, 1.0);\n"
    "    vec3 x = h.xyz / h.w;\n"
    "    vec3 n = normalize(nw.xyz);\n"
    "    vec3 l, e;\n"
    "    if (light_type == 1) {\n"
    "        l = light_dir;\n"
    "        e = power;\n"
    "    } else {\n"
    "        vec3 to = light_pos - x;\n"
    "        float d2 = dot(to, to);\n"
    "        l = to * inversesqrt(max(d2, 1e-30));\n"
    "        e = (d2 > 0.0 && dot(-l, light_dir) >= cos_cone) ? power / d2 : vec3(0.0);\n"
    "    }\n"
    "    float cn = dot(n, l);\n"
    "    vec3 rgb = vec3(0.0);\n"
    "    if (cn > 0.0 && any(greaterThan(e, vec3(0.0)))) {\n"
    "        uint id = min(uint(texelFetch(g_material, px, 0).r + 0.5), max(material_count, 1u) - 1u);\n"
    "        vec3 f = texelFetch(g_albedo, px, 0).rgb / PI;\n"
    "        if (material_count > 0u) {\n"
    "            vec4 g = material[id].glossy;\n"
    "            vec3 r = 2.0 * cn * n - l;\n"                 /* l mirrored at n */
    "            float cr = dot(r, normalize(eye - x));\n"
    /* cos+^k as the reference takes it: 0 when cr <= 0 (also for k = 0; pow(0, 0) is undefined) */
    "            f += g.rgb * (cr > 0.0 ? (g.w + 2.0) / (2.0 * PI) * pow(min(cr, 1.0), g.w) : 0.0);\n"
    "        }\n"
    "        rgb = f * e * cn * visibility(x, n);\n"
    "    }\n"
    "    imageStore(direct_out, px, vec4(prev.rgb + rgb, 1.0));\n"
    "}\n";

static const char display_compose_src[] =
    "#version 430\n"
    "layout(local_size_x = 8, local_size_y = 8) in;\n"
    "layout(binding = 0) uniform sampler2D direct_tex;\n"
    "layout(binding = 1) uniform sampler2D indirect_tex;\n"
    "layout(rgba8, binding = 0) uniform writeonly image2D final_out;\n"
    "layout(location = 0) uniform ivec2 size;\n"
    "layout(location = 1) uniform int has_indirect;\n"
    "layout(location = 2) uniform float exposure;\n"
    "vec3 srgb(vec3 c) {\n"
    "    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));\n"
    "}\n"
    "void main() {\n"
    "    ivec2 px = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (px.x >= size.x || px.y >= size.y) return;\n"
    "    vec4 d = texelFetch(direct_tex, px, 0);\n"
    "    vec3 c = d.rgb;\n"
    "    if (has_indirect != 0) c += texelFetch(indirect_tex, px, 0).rgb;\n"
    "    c = max(c, vec3(0.0)) * exposure;\n"
    "    float lum = dot(c, vec3(0.2126, 0.7152, 0.0722));\n"
    "    c = d.a == 1.0 ? clamp(c / (1.0 + lum), 0.0, 1.0) : vec3(0.0);\n"
    "    imageStore(final_out, px, vec4(srgb(c), d.a));\n"
    "}\n";

static GLuint display__program(display *dp, const char *src) {
    GLuint sh = glCreateShader(GL_COMPUTE_SHADER), prog;
    GLint ok = 0;
    glShaderSource(sh, 1, &src, NULL);
    glCompileShader(sh);
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        glGetShaderInfoLog(sh, (GLsizei)sizeof dp->error, NULL, dp->error);
        glDeleteShader(sh);
        return 0;
    }
    prog = glCreateProgram();
    glAttachShader(prog, sh);
    glLinkProgram(prog);
    glDeleteShader(sh);
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        glGetProgramInfoLog(prog, (GLsizei)sizeof dp->error, NULL, dp->error);
        glDeleteProgram(prog);
        return 0;
    }
    return prog;
}

/* glBindTextureUnit is GL 4.5; this is the 4.3 way. Leaves unit 0 active. */
static void display__bind(GLuint unit, GLuint tex) {
    glActiveTexture(GL_TEXTURE0 + unit);
    glBindTexture(GL_TEXTURE_2D, tex);
    glActiveTexture(GL_TEXTURE0);
}

static GLuint display__texture(GLenum format, uint32_t w, uint32_t h) {
    GLuint t = 0;
    glGenTextures(1, &t);
    glBindTexture(GL_TEXTURE_2D, t);
    glTexStorage2D(GL_TEXTURE_2D, 1, format, (GLsizei)w, (GLsizei)h);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glBindTexture(GL_TEXTURE_2D, 0);
    return t;
}

/* Compiles the passes; 0 with dp->error set when the GL cannot. */
DISPLAY_FN int display_init(display *dp) {
    static const float zero[4] = {0, 0, 0, 0};
    memset(dp, 0, sizeof *dp);
    dp->direct_program = display__program(dp, display_direct_src);
    if (!dp->direct_program) return 0;
    dp->compose_program = display__program(dp, display_compose_src);
    if (!dp->compose_program) return 0;
    dp->black = display__texture(GL_RGBA32F, 1, 1);
    glBindTexture(GL_TEXTURE_2D, dp->black);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, 1, 1, GL_RGBA, GL_FLOAT, zero);
    glBindTexture(GL_TEXTURE_2D, 0);
    glGenQueries(3, dp->queries);
    return 1;
}

DISPLAY_FN void display_free(display *dp) {
    glDeleteProgram(dp->direct_program);
    glDeleteProgram(dp->compose_program);
    glDeleteTextures(1, &dp->direct);
    glDeleteTextures(1, &dp->final_image);
    glDeleteTextures(1, &dp->black);
    glDeleteBuffers(1, &dp->materials);
    if (dp->queries[0]) glDeleteQueries(3, dp->queries);
    memset(dp, 0, sizeof *dp);
}

/* The materials of the frame (the same array handed to gim_set_materials). */
DISPLAY_FN void display_set_materials(display *dp, const gim_material *m, uint32_t count) {
    float *buf = (float *)calloc(count ? count : 1, 8 * sizeof(float));
    uint32_t i;
    if (!buf) return;
    for (i = 0; i < count; ++i) {
        memcpy(buf + i * 8, m[i].diffuse, 3 * sizeof(float));
        memcpy(buf + i * 8 + 4, m[i].glossy, 3 * sizeof(float));
        buf[i * 8 + 7] = m[i].exponent;
    }
    if (!dp->materials) glGenBuffers(1, &dp->materials);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, dp->materials);
    glBufferData(GL_SHADER_STORAGE_BUFFER, (GLsizeiptr)((count ? count : 1) * 8 * sizeof(float)), buf, GL_STATIC_DRAW);
    glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
    dp->material_count = count;
    free(buf);
}

static void display__size(display *dp, uint32_t w, uint32_t h) {
    if (dp->direct && dp->width == w && dp->height == h) return;
    glDeleteTextures(1, &dp->direct);
    glDeleteTextures(1, &dp->final_image);
    dp->direct = display__texture(GL_RGBA32F, w, h);
    dp->final_image = display__texture(GL_RGBA8, w, h);
    dp->width = w;
    dp->height = h;
}

/* The direct light of the last gim_update (o: gim_outputs, one light per RSM: a point light's
   six cube faces are six; view, proj: the frame's camera) into dp->direct.
   timed: GL timestamps around this pass and the next display_compose (display_timings). */
DISPLAY_FN void display_direct(display *dp, const gim_frame_outputs *o, gim_mat4 view, gim_mat4 proj, int timed) {
    gim_mat4 vp = gim_mat4_mul(proj, view), inv_vp, inv_view;
    uint32_t i, n = o->light_count;
    if (!gim_mat4_invert(vp, &inv_vp) || !gim_mat4_invert(view, &inv_view)) return;
    display__size(dp, o->width, o->height);
    dp->timed = timed;
    if (timed) glQueryCounter(dp->queries[0], GL_TIMESTAMP);
    glUseProgram(dp->direct_program);
    glUniformMatrix4fv(0, 1, GL_FALSE, inv_vp.m);
    glUniform3f(1, inv_view.m[12], inv_view.m[13], inv_view.m[14]);
    glUniform2i(2, (GLint)o->width, (GLint)o->height);
    glUniform1ui(11, dp->material_count);
    display__bind(0, o->gbuffer_depth);
    display__bind(1, o->gbuffer_normal);
    display__bind(2, o->gbuffer_albedo);
    display__bind(3, o->gbuffer_material);
    glBindImageTexture(0, dp->direct, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
    if (dp->materials) glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, dp->materials);
    for (i = 0; i < (n ? n : 1u); ++i) {   /* one dispatch per light, adding up */
        const gim_light *l = n ? &o->lights[i].light : NULL;
        const gim_light_outputs *lo = n ? &o->lights[i] : NULL;
        float col[3] = {1.0f, 1.0f, 1.0f};
        gim_vec3 dir = gim_v3(0.0f, 1.0f, 0.0f);
        if (l) {
            if (l->color[0] != 0.0f || l->color[1] != 0.0f || l->color[2] != 0.0f) memcpy(col, l->color, sizeof col);
            dir = gim_v3_normalize(l->direction);
        }
        glUniform1i(3, !l ? 0 : (l->type == GIM_LIGHT_SPOT ? 2 : 1));
        if (l) {
            float p = l->type == GIM_LIGHT_SPOT ? l->intensity : l->irradiance;
            glUniform3f(4, p * col[0], p * col[1], p * col[2]);
            glUniform3f(5, dir.x, dir.y, dir.z);
            glUniform3f(6, l->position.x, l->position.y, l->position.z);
            glUniform1f(7, l->square_cone ? -2.0f : cosf(l->cone_angle));   /* a cube face: its whole frustum */
            glUniformMatrix4fv(8, 1, GL_FALSE, lo->view.m);
            glUniformMatrix4fv(9, 1, GL_FALSE, lo->proj.m);
            display__bind(4, lo->rsm_depth);
        }
        glUniform1i(10, i > 0);
        glDispatchCompute((o->width + 7u) / 8u, (o->height + 7u) / 8u, 1);
        glMemoryBarrier(GL_SHADER_IMAGE_ACCESS_BARRIER_BIT | GL_TEXTURE_FETCH_BARRIER_BIT);
    }
    if (timed) glQueryCounter(dp->queries[1], GL_TIMESTAMP);
    glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_READ_WRITE, GL_RGBA32F);
    for (i = 0; i < 5; ++i) display__bind(i, 0);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, 0);
    glUseProgram(0);
}

/* dp->direct + indirect (0: none) tone mapped with exposure into dp->final_image. */
DISPLAY_FN void display_compose(display *dp, GLuint indirect, float exposure) {
    glUseProgram(dp->compose_program);
    glUniform2i(0, (GLint)dp->width, (GLint)dp->height);
    glUniform1i(1, indirect != 0);
    glUniform1f(2, exposure);
    display__bind(0, dp->direct);
    display__bind(1, indirect ? indirect : dp->black);
    glBindImageTexture(0, dp->final_image, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA8);
    glDispatchCompute((dp->width + 7u) / 8u, (dp->height + 7u) / 8u, 1);
    glMemoryBarrier(GL_TEXTURE_FETCH_BARRIER_BIT | GL_TEXTURE_UPDATE_BARRIER_BIT | GL_FRAMEBUFFER_BARRIER_BIT);
    if (dp->timed) glQueryCounter(dp->queries[2], GL_TIMESTAMP);
    glBindImageTexture(0, 0, 0, GL_FALSE, 0, GL_WRITE_ONLY, GL_RGBA8);
    display__bind(0, 0);
    display__bind(1, 0);
    glUseProgram(0);
}

/* GPU ms of the last timed display_direct and display_compose (waits for them); 0 if untimed. */
DISPLAY_FN int display_timings(display *dp, double *direct_ms, double *compose_ms) {
    GLuint64 t[3];
    int i;
    *direct_ms = *compose_ms = 0.0;
    if (!dp->timed) return 0;
    for (i = 0; i < 3; ++i) glGetQueryObjectui64v(dp->queries[i], GL_QUERY_RESULT, &t[i]);
    *direct_ms = (double)(t[1] - t[0]) * 1e-6;
    *compose_ms = (double)(t[2] - t[1]) * 1e-6;
    dp->timed = 0;
    return 1;
}

/* Reads a whole texture (level 0) as floats: 4 per texel (format GL_RGBA), rows bottom first. */
DISPLAY_FN void display_read(GLuint tex, float *rgba) {
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glBindTexture(GL_TEXTURE_2D, tex);
    glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_FLOAT, rgba);
    glBindTexture(GL_TEXTURE_2D, 0);
}

/* dp->final_image as 8-bit RGB, TOP row first (as image files want). */
DISPLAY_FN void display_read_final(display *dp, unsigned char *rgb) {
    unsigned char *rgba = (unsigned char *)malloc((size_t)dp->width * dp->height * 4);
    uint32_t x, y;
    if (!rgba) return;
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glBindTexture(GL_TEXTURE_2D, dp->final_image);
    glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    glBindTexture(GL_TEXTURE_2D, 0);
    for (y = 0; y < dp->height; ++y)
        for (x = 0; x < dp->width; ++x) {
            const unsigned char *s = rgba + ((size_t)(dp->height - 1u - y) * dp->width + x) * 4;
            memcpy(rgb + ((size_t)y * dp->width + x) * 3, s, 3);
        }
    free(rgba);
}

/* Reinhard's exposure key / Lw, Lw the log-average luminance of direct + indirect over the
   pixels with a surface (a == 1 in direct); indirect may be NULL. 1 when the image is black.
   delta keeps black pixels from sending the log to -inf; relative to the mean, so unit-free. */
DISPLAY_FN float display_auto_exposure(const float *direct, const float *indirect, uint32_t pixels) {
    double mean = 0.0, logsum = 0.0, delta;
    uint32_t i, n = 0;
    for (i = 0; i < pixels; ++i) {
        const float *d = direct + (size_t)i * 4, *g = indirect ? indirect + (size_t)i * 4 : NULL;
        if (d[3] != 1.0f) continue;
        mean += 0.2126 * (d[0] + (g ? g[0] : 0.0f)) + 0.7152 * (d[1] + (g ? g[1] : 0.0f)) + 0.0722 * (d[2] + (g ? g[2] : 0.0f));
        n++;
    }
    if (n == 0 || !(mean > 0.0) || !isfinite(mean)) return 1.0f;
    mean /= n;
    delta = 1e-3 * mean;
    for (i = 0; i < pixels; ++i) {
        const float *d = direct + (size_t)i * 4, *g = indirect ? indirect + (size_t)i * 4 : NULL;
        if (d[3] != 1.0f) continue;
        logsum += log(delta + 0.2126 * (d[0] + (g ? g[0] : 0.0f)) + 0.7152 * (d[1] + (g ? g[1] : 0.0f)) +
                      0.0722 * (d[2] + (g ? g[2] : 0.0f)));
    }
    return (float)(0.18 / exp(logsum / n));
}

#endif
