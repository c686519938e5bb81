/* scene.cpp - the implementation of scene.h: built-in scenes, glTF loading (tinygltf), the
   shared command line, camera rays and PFM files. C++ inside, C outside.

   glTF -> scene mapping
     geometry   every TRIANGLES / TRIANGLE_STRIP / TRIANGLE_FAN primitive reached from the
                default scene (or from every root node when the file has no scene), with the
                node's world matrix (matrix, or T * R * S, down the hierarchy) applied;
                mirroring transforms flip the winding; POINTS and LINES are skipped (a warning).
                Indices 8, 16 or 32 bit, or none (vertices in order). Sparse accessors work.
     normals    NORMAL when present and usable; otherwise face normals, each triangle with its
                own vertices (also when any given normal is zero or not finite: a warning).
     materials  (mirrors the glTF metallic-roughness model onto rho_d, rho_g, k)
                base   = baseColorFactor.rgb * average of baseColorTexture (sRGB decoded)
                m, r   = metallicFactor, roughnessFactor (times the averages of the B and G
                         channels of metallicRoughnessTexture when present)
                alpha  = max(r^2, 0.01), k = 2 / alpha^2 - 2 (Phong exponent of the same
                         width as a GGX lobe of roughness alpha, Walter 2007), at most 20000
                F0     = 0.04 (or ((ior-1)/(ior+1))^2 with KHR_materials_ior), times
                         specularFactor * specularColorFactor with KHR_materials_specular
                k >= 1 (smooth):  rho_d = base (1 - m),  rho_g = F0 (1 - m) + base m
                k <  1 (rough):   rho_d = base,          rho_g = 0  (a k < 1 Phong lobe is
                                  nearly Lambertian; the Cornell albedos stay as measured)
                no material: rho_d = 0.8 grey, no glossy lobe.
     lights     KHR_lights_punctual: directional -> sun (E = intensity in lux), spot -> spot
                (I = intensity in candela, half-angle = outerConeAngle), point -> spot with
                half-angle pi. Without them, emissive surfaces (emissiveFactor times
                KHR_materials_emissive_strength) become one spot just in front of their
                area-weighted centre, along their mean normal, half-angle 60 deg, with the
                on-axis intensity of the emitter I = sum L_e A. Without either: a sun from
                (0.4, 1, 0.3), E = 1.
     camera     the first perspective camera node (eye, -Z axis, yfov); else the bounds
                framed from +Z, slightly above.
*/
#define TINYGLTF_IMPLEMENTATION
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define TINYGLTF_NO_EXTERNAL_IMAGE_LOADER_DEFAULT_PLACEHOLDER
#include <tiny_gltf.h>

#include "scene.h"
#include "street.h" /* scene/street.h: the procedural street, shared with the cache tests */

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>
#include <sys/stat.h>
#include <sys/types.h>

namespace {

const double PI = 3.14159265358979323846;

void set_err(char *err, size_t cap, const char *fmt, ...) {
    if (!err || cap == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, cap, fmt, ap);
    va_end(ap);
}

/* A failure inside the loaders: one line, thrown to the C boundary. */
struct scene_error {
    std::string msg;
    int code; /* what the C functions return: 1, or SCENE_NO_TRIANGLES */
};
[[noreturn]] void fail(const char *fmt, ...) {
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    throw scene_error{buf, 1};
}

struct vec3 {
    double x, y, z;
};
vec3 sub(vec3 a, vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
vec3 add(vec3 a, vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
vec3 mul(vec3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
vec3 cross(vec3 a, vec3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double len(vec3 a) { return std::sqrt(dot(a, a)); }
vec3 normalize(vec3 a) {
    double l = len(a);
    return l > 0 ? mul(a, 1.0 / l) : vec3{0, 0, 0};
}
bool finite3(const float *v) { return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]); }

/* Column-major 4x4 in double. */
struct mat4 {
    double m[16];
};
mat4 identity() {
    mat4 r;
    for (int i = 0; i < 16; ++i) r.m[i] = (i % 5 == 0) ? 1.0 : 0.0;
    return r;
}
mat4 mul(const mat4 &a, const mat4 &b) {
    mat4 r;
    for (int c = 0; c < 4; ++c)
        for (int row = 0; row < 4; ++row) {
            double s = 0;
            for (int k = 0; k < 4; ++k) s += a.m[k * 4 + row] * b.m[c * 4 + k];
            r.m[c * 4 + row] = s;
        }
    return r;
}
vec3 xform_point(const mat4 &a, vec3 p) {
    return {a.m[0] * p.x + a.m[4] * p.y + a.m[8] * p.z + a.m[12], a.m[1] * p.x + a.m[5] * p.y + a.m[9] * p.z + a.m[13],
            a.m[2] * p.x + a.m[6] * p.y + a.m[10] * p.z + a.m[14]};
}
vec3 xform_dir(const mat4 &a, vec3 p) {
    return {a.m[0] * p.x + a.m[4] * p.y + a.m[8] * p.z, a.m[1] * p.x + a.m[5] * p.y + a.m[9] * p.z,
            a.m[2] * p.x + a.m[6] * p.y + a.m[10] * p.z};
}
double det3(const mat4 &a) {
    vec3 c0{a.m[0], a.m[1], a.m[2]}, c1{a.m[4], a.m[5], a.m[6]}, c2{a.m[8], a.m[9], a.m[10]};
    return dot(c0, cross(c1, c2));
}
/* Normals transform with the cofactor matrix (det * M^-T): no division, right for any
   invertible M; the sign of det is applied by the caller (mirrors). */
vec3 xform_normal(const mat4 &a, vec3 n) {
    vec3 c0{a.m[0], a.m[1], a.m[2]}, c1{a.m[4], a.m[5], a.m[6]}, c2{a.m[8], a.m[9], a.m[10]};
    vec3 r0 = cross(c1, c2), r1 = cross(c2, c0), r2 = cross(c0, c1); /* rows of the cofactor matrix */
    return {r0.x * n.x + r1.x * n.y + r2.x * n.z, r0.y * n.x + r1.y * n.y + r2.y * n.z,
            r0.z * n.x + r1.z * n.y + r2.z * n.z};
}

/* ---- scene assembly ------------------------------------------------------------------------ */

struct mesh_b {
    std::vector<float> pos, nrm;
    std::vector<uint32_t> idx, mat;
};

struct builder {
    std::vector<mesh_b> meshes;
    std::vector<scene_material> materials;
    std::vector<scene_light> lights;
    scene_camera camera;
    bool has_camera = false;
    uint32_t warnings = 0;
    std::string first_warning;
    std::string name;

    builder() { std::memset(&camera, 0, sizeof camera); }
    void warn(const std::string &w) {
        if (warnings++ == 0) first_warning = w;
    }
};

template <class T> T *copy_out(const std::vector<T> &v) {
    if (v.empty()) return nullptr;
    T *p = static_cast<T *>(std::malloc(v.size() * sizeof(T)));
    if (!p) fail("out of memory");
    std::memcpy(p, v.data(), v.size() * sizeof(T));
    return p;
}

/* Face normals for a mesh without usable normals: every triangle gets its own three vertices.
   Averaging over shared vertices invents curvature that a decimated mesh does not have (Sponza's
   LOD averages across its sharp edges), and a shading normal that differs from the geometric
   one is handled differently by every renderer; with face normals gimany and the reference
   shade the same surface. */
void flat_normals(mesh_b &m) {
    std::vector<float> pos;
    pos.reserve(m.idx.size() * 3);
    m.nrm.clear();
    m.nrm.reserve(m.idx.size() * 3);
    for (size_t t = 0; t + 2 < m.idx.size(); t += 3) {
        const float *a = &m.pos[3 * m.idx[t]], *b = &m.pos[3 * m.idx[t + 1]], *c = &m.pos[3 * m.idx[t + 2]];
        vec3 A{a[0], a[1], a[2]}, B{b[0], b[1], b[2]}, C{c[0], c[1], c[2]};
        vec3 n = normalize(cross(sub(B, A), sub(C, A)));
        if (len(n) == 0) n = {0, 1, 0}; /* degenerate: no area, never seen */
        for (int k = 0; k < 3; ++k) {
            pos.insert(pos.end(), &m.pos[3 * m.idx[t + k]], &m.pos[3 * m.idx[t + k]] + 3);
            m.nrm.push_back((float)n.x); m.nrm.push_back((float)n.y); m.nrm.push_back((float)n.z);
        }
    }
    m.pos.swap(pos);
    for (size_t i = 0; i < m.idx.size(); ++i) m.idx[i] = (uint32_t)i;
}

void finish(builder &b, scene *out) {
    scene s;
    std::memset(&s, 0, sizeof s);
    try {
        uint32_t count = 0;
        for (auto &m : b.meshes)
            if (!m.idx.empty()) ++count;
        s.mesh_count = count;
        s.meshes = static_cast<scene_mesh *>(std::calloc(count ? count : 1, sizeof(scene_mesh)));
        if (!s.meshes) fail("out of memory");
        size_t k = 0;
        for (auto &m : b.meshes) {
            if (m.idx.empty()) continue;
            scene_mesh &sm = s.meshes[k++];
            sm.vertex_count = (uint32_t)(m.pos.size() / 3);
            sm.triangle_count = (uint32_t)(m.idx.size() / 3);
            sm.positions = copy_out(m.pos);
            sm.normals = copy_out(m.nrm);
            sm.indices = copy_out(m.idx);
            sm.triangle_material = copy_out(m.mat);
        }
        s.material_count = (uint32_t)b.materials.size();
        s.materials = copy_out(b.materials);
        s.light_count = (uint32_t)b.lights.size();
        s.lights = copy_out(b.lights);
    } catch (...) {
        scene_free(&s);
        throw;
    }
    s.camera = b.camera;
    if (!s.camera.width || !s.camera.height) { /* the options' default; scene_load sets --size */
        s.camera.width = 640;
        s.camera.height = 360;
    }
    s.warning_count = b.warnings;
    std::snprintf(s.warning, sizeof s.warning, "%s", b.first_warning.c_str());
    std::snprintf(s.name, sizeof s.name, "%s", b.name.c_str());
    *out = s;
}

/* Bounds of the builder's meshes (for default cameras and light placement). */
void builder_bounds(const builder &b, vec3 &lo, vec3 &hi) {
    lo = {HUGE_VAL, HUGE_VAL, HUGE_VAL};
    hi = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (auto &m : b.meshes)
        for (size_t i = 0; i + 2 < m.pos.size(); i += 3) {
            lo = {std::min(lo.x, (double)m.pos[i]), std::min(lo.y, (double)m.pos[i + 1]), std::min(lo.z, (double)m.pos[i + 2])};
            hi = {std::max(hi.x, (double)m.pos[i]), std::max(hi.y, (double)m.pos[i + 1]), std::max(hi.z, (double)m.pos[i + 2])};
        }
}

void frame_bounds(builder &b) {
    vec3 lo, hi;
    builder_bounds(b, lo, hi);
    if (!(lo.x <= hi.x)) lo = hi = {0, 0, 0};
    vec3 c = mul(add(lo, hi), 0.5);
    double r = 0.5 * len(sub(hi, lo));
    double fovy = 45.0 * PI / 180.0;
    vec3 eye = add(c, mul(normalize(vec3{0, 0.25, 1}), r / std::sin(fovy / 2) * 1.05));
    b.camera.eye[0] = (float)eye.x; b.camera.eye[1] = (float)eye.y; b.camera.eye[2] = (float)eye.z;
    b.camera.target[0] = (float)c.x; b.camera.target[1] = (float)c.y; b.camera.target[2] = (float)c.z;
    b.camera.fovy = (float)fovy;
}

scene_material make_material(float dr, float dg, float db) {
    scene_material m;
    std::memset(&m, 0, sizeof m);
    m.diffuse[0] = dr; m.diffuse[1] = dg; m.diffuse[2] = db;
    return m;
}

void set3(float *d, double x, double y, double z) {
    d[0] = (float)x; d[1] = (float)y; d[2] = (float)z;
}

/* ---- built-in: the Cornell box -------------------------------------------------------------- */
/* The measured Cornell box (Cornell University Program of Computer Graphics), millimetres to
   metres, turned 180 degrees about Y so the camera looks down -Z with the red wall on the left.
   Faces are quads; each wall's normal points into the box, each block face's out of the block. */
const float cornell_quads[][12] = {
    /* floor */ {552.8f, 0, 0, 0, 0, 0, 0, 0, 559.2f, 549.6f, 0, 559.2f},
    /* ceiling */ {556.0f, 548.8f, 0, 556.0f, 548.8f, 559.2f, 0, 548.8f, 559.2f, 0, 548.8f, 0},
    /* back */ {549.6f, 0, 559.2f, 0, 0, 559.2f, 0, 548.8f, 559.2f, 556.0f, 548.8f, 559.2f},
    /* green */ {0, 0, 559.2f, 0, 0, 0, 0, 548.8f, 0, 0, 548.8f, 559.2f},
    /* red */ {552.8f, 0, 0, 549.6f, 0, 559.2f, 556.0f, 548.8f, 559.2f, 556.0f, 548.8f, 0},
    /* short block */
    {130, 165, 65, 82, 165, 225, 240, 165, 272, 290, 165, 114},
    {290, 0, 114, 290, 165, 114, 240, 165, 272, 240, 0, 272},
    {130, 0, 65, 130, 165, 65, 290, 165, 114, 290, 0, 114},
    {82, 0, 225, 82, 165, 225, 130, 165, 65, 130, 0, 65},
    {240, 0, 272, 240, 165, 272, 82, 165, 225, 82, 0, 225},
    /* tall block */
    {423, 330, 247, 265, 330, 296, 314, 330, 456, 472, 330, 406},
    {423, 0, 247, 423, 330, 247, 472, 330, 406, 472, 0, 406},
    {472, 0, 406, 472, 330, 406, 314, 330, 456, 314, 0, 456},
    {314, 0, 456, 314, 330, 456, 265, 330, 296, 265, 0, 296},
    {265, 0, 296, 265, 330, 296, 423, 330, 247, 423, 0, 247},
};

void build_cornell(builder &b) {
    b.name = "cornell";
    /* white, red, green: the usual RGB fit of the measured spectra */
    b.materials.push_back(make_material(0.725f, 0.71f, 0.68f));
    b.materials.push_back(make_material(0.63f, 0.065f, 0.05f));
    b.materials.push_back(make_material(0.14f, 0.45f, 0.091f));
    const double W = 0.556; /* x -> W - x, z -> -z: 180 degrees about Y */
    const vec3 box_centre{W - 0.278, 0.2744, -0.2796};
    const vec3 short_centre{W - 0.186, 0.0825, -0.1685};
    const vec3 tall_centre{W - 0.3685, 0.165, -0.3515};
    mesh_b m;
    for (size_t q = 0; q < sizeof cornell_quads / sizeof cornell_quads[0]; ++q) {
        vec3 v[4];
        for (int i = 0; i < 4; ++i)
            v[i] = {W - cornell_quads[q][3 * i] * 0.001, cornell_quads[q][3 * i + 1] * 0.001,
                    -cornell_quads[q][3 * i + 2] * 0.001};
        vec3 n = normalize(cross(sub(v[1], v[0]), sub(v[2], v[0])));
        vec3 c = mul(add(add(v[0], v[1]), add(v[2], v[3])), 0.25);
        bool wall = q < 5;
        vec3 ref = wall ? box_centre : (q < 10 ? short_centre : tall_centre);
        double s = dot(n, sub(ref, c)); /* walls face the box centre, blocks face away */
        bool flip = wall ? s < 0 : s > 0;
        if (flip) n = mul(n, -1.0);
        uint32_t base = (uint32_t)(m.pos.size() / 3);
        for (int i = 0; i < 4; ++i) {
            m.pos.push_back((float)v[i].x); m.pos.push_back((float)v[i].y); m.pos.push_back((float)v[i].z);
            m.nrm.push_back((float)n.x); m.nrm.push_back((float)n.y); m.nrm.push_back((float)n.z);
        }
        uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
        if (flip) { tri[1] = 2; tri[2] = 1; tri[4] = 3; tri[5] = 2; }
        for (int i = 0; i < 6; ++i) m.idx.push_back(base + tri[i]);
        uint32_t mat = q == 3 ? 2 : (q == 4 ? 1 : 0);
        m.mat.push_back(mat); m.mat.push_back(mat);
    }
    b.meshes.push_back(m);
    /* a spot 1 cm under the ceiling light's centre, pointing down; I = 0.3 W/sr gives about
       E = 1 on the floor below it */
    scene_light l;
    std::memset(&l, 0, sizeof l);
    l.type = SCENE_LIGHT_SPOT;
    set3(l.color, 1, 1, 1);
    set3(l.position, W - 0.278, 0.5388, -0.2795);
    set3(l.direction, 0, -1, 0);
    l.half_angle = (float)(60.0 * PI / 180.0);
    l.intensity = 0.3f;
    b.lights.push_back(l);
    /* the measured camera: 35 mm lens, 25 mm film -> fovy = 2 atan(12.5 / 35) */
    set3(b.camera.eye, W - 0.278, 0.273, 0.8);
    set3(b.camera.target, W - 0.278, 0.273, -0.2796);
    b.camera.fovy = (float)(2.0 * std::atan(12.5 / 35.0));
    b.has_camera = true;
}

/* ---- built-in: the street ---------------------------------------------------------------- */
/* The open-world street after Bischoff 2017's urban scene (scene/street.h): a road along +x between
   two rows of box buildings, red / green / blue panels beside the road, a sun from the +z side
   that lights the -z row's facades and the panels in front of them, which bleed their colour
   across the road onto the shadowed +z row. About 100,000 triangles, metres, diffuse. The
   camera stands at the start of the road looking down it at the shadowed row. */
void build_street(builder &b) {
    b.name = "street";
    street_params sp;
    std::memset(&sp, 0, sizeof sp);
    street_mesh sm;
    if (street_build(&sp, &sm) != 0) fail("the street generator failed (out of memory)");
    mesh_b m;
    m.pos.assign(sm.positions, sm.positions + (size_t)sm.vertex_count * 3);
    m.nrm.assign(sm.normals, sm.normals + (size_t)sm.vertex_count * 3);
    m.idx.assign(sm.indices, sm.indices + (size_t)sm.triangle_count * 3);
    m.mat.assign(sm.triangle_material, sm.triangle_material + sm.triangle_count);
    for (uint32_t i = 0; i < sm.material_count; ++i)
        b.materials.push_back(make_material(sm.albedo[i][0], sm.albedo[i][1], sm.albedo[i][2]));
    scene_light l;
    std::memset(&l, 0, sizeof l);
    l.type = SCENE_LIGHT_DIRECTIONAL;
    set3(l.color, 1, 1, 1);
    set3(l.direction, sm.sun_direction[0], sm.sun_direction[1], sm.sun_direction[2]);
    l.irradiance = 1.0f;
    b.lights.push_back(l);
    street_free(&sm);
    b.meshes.push_back(std::move(m));
    set3(b.camera.eye, -5.0, 4.0, -5.0);
    set3(b.camera.target, 50.0, 6.0, 9.0);
    b.camera.fovy = (float)(60.0 * PI / 180.0);
    b.has_camera = true;
}

/* ---- built-in: the courtyard ------------------------------------------------------------- */
/* A sunlit courtyard floor (8 x 5 m, sandstone) in front of a wall (8 x 3 m, pale) with a
   free-standing pillar (0.8 x 0.8 x 1.2 m, grey) between them, 0.8 m from the wall: the wall
   gets no sun (the sun shines along it, from +x, 63 degrees up), only the floor's light, and
   the pillar blocks that light from the low wall behind it: an indirect shadow that only
   visibility between the senders and the wall reproduces (Ritschel et al. 2008's motivating
   case), with nothing else in the way. Metres; the wall at z = 0 facing +z, the floor at
   y = 0. The camera looks steeply down at the wall over the pillar, so the wall behind the
   pillar (|x| < 0.4, y < 0.8) is in view. */
void courtyard_quad(mesh_b &m, vec3 c, vec3 u, vec3 v, uint32_t mat) {
    vec3 n = normalize(cross(u, v));
    uint32_t base = (uint32_t)(m.pos.size() / 3);
    const vec3 p[4] = {c, add(c, u), add(add(c, u), v), add(c, v)};
    for (int i = 0; i < 4; ++i) {
        m.pos.push_back((float)p[i].x); m.pos.push_back((float)p[i].y); m.pos.push_back((float)p[i].z);
        m.nrm.push_back((float)n.x); m.nrm.push_back((float)n.y); m.nrm.push_back((float)n.z);
    }
    const uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
    for (int i = 0; i < 6; ++i) m.idx.push_back(base + tri[i]);
    m.mat.push_back(mat); m.mat.push_back(mat);
}

void build_courtyard(builder &b) {
    b.name = "courtyard";
    b.materials.push_back(make_material(0.75f, 0.62f, 0.45f)); /* floor */
    b.materials.push_back(make_material(0.80f, 0.80f, 0.78f)); /* wall */
    b.materials.push_back(make_material(0.50f, 0.50f, 0.50f)); /* pillar */
    mesh_b m;
    courtyard_quad(m, {-4, 0, 5}, {8, 0, 0}, {0, 0, -5}, 0);  /* floor, normal +y */
    courtyard_quad(m, {-4, 0, 0}, {8, 0, 0}, {0, 3, 0}, 1);   /* wall, normal +z */
    const double x0 = -0.4, x1 = 0.4, z0 = 0.8, z1 = 1.6, h = 1.2;
    courtyard_quad(m, {x0, 0, z1}, {x1 - x0, 0, 0}, {0, h, 0}, 2);  /* pillar: +z */
    courtyard_quad(m, {x1, 0, z0}, {0, h, 0}, {0, 0, z1 - z0}, 2);  /* +x */
    courtyard_quad(m, {x0, 0, z0}, {0, h, 0}, {x1 - x0, 0, 0}, 2);  /* -z */
    courtyard_quad(m, {x0, 0, z0}, {0, 0, z1 - z0}, {0, h, 0}, 2);  /* -x */
    courtyard_quad(m, {x0, h, z1}, {x1 - x0, 0, 0}, {0, 0, z0 - z1}, 2); /* top, +y */
    b.meshes.push_back(m);
    scene_light l;
    std::memset(&l, 0, sizeof l);
    l.type = SCENE_LIGHT_DIRECTIONAL;
    set3(l.color, 1, 1, 1);
    vec3 sun = normalize(vec3{0.5, 1, 0}); /* along the wall: none on its face */
    set3(l.direction, sun.x, sun.y, sun.z);
    l.irradiance = 1.0f;
    b.lights.push_back(l);
    set3(b.camera.eye, 0.5, 4.0, 2.5);
    set3(b.camera.target, 0.0, 0.4, 0.0);
    b.camera.fovy = (float)(60.0 * PI / 180.0);
    b.has_camera = true;
}

/* ---- glTF ---------------------------------------------------------------------------------- */

namespace gl = tinygltf;

/* What a hostile file may cost the loader (README "Reliability"): the JSON parser recurses once
   per nesting level (16,000 levels overflowed the stack); a 261 KB PNG can decode to 16384^2
   (1 GiB); a node graph listing each child twice, 18 deep, expands to 262,144 instances. */
const unsigned MAX_JSON_DEPTH = SCENE_MAX_JSON_DEPTH;
const uint64_t MAX_FILE_BYTES = SCENE_MAX_FILE_BYTES;
const uint64_t MAX_IMAGE_PIXELS = SCENE_MAX_IMAGE_PIXELS;
const uint64_t MAX_DECODED_BYTES = SCENE_MAX_DECODED_BYTES;
const double MAX_INSTANCES = SCENE_MAX_INSTANCES;
const double MAX_TRIANGLES = SCENE_MAX_TRIANGLES;

/* Bytes of RGBA8 decoded so far in one load (the image loader's user data). */
struct image_budget {
    uint64_t decoded = 0;
};

/* Images decode through stb_image into RGBA8; an image that fails to decode is a warning
   (the material keeps its factor), never a failure of the whole file. The scene layer only
   averages base colour and metal/roughness textures, so an image above MAX_IMAGE_PIXELS, or
   past MAX_DECODED_BYTES in all, is skipped the same way before it is decoded. */
bool load_image(gl::Image *image, const int index, std::string * /*err*/, std::string *warn, int, int,
                const unsigned char *bytes, int size, void *user) {
    image_budget *budget = static_cast<image_budget *>(user);
    int w = 0, h = 0, comp = 0;
    if (size > 0 && stbi_info_from_memory(bytes, size, &w, &h, &comp) && w > 0 && h > 0) {
        uint64_t px = (uint64_t)w * (uint64_t)h;
        if (px > MAX_IMAGE_PIXELS || (budget && budget->decoded + px * 4 > MAX_DECODED_BYTES)) {
            char buf[200];
            std::snprintf(buf, sizeof buf, "image %d is %dx%d: above %llu pixels, or %llu MiB decoded in all; skipped\n",
                          index, w, h, (unsigned long long)MAX_IMAGE_PIXELS,
                          (unsigned long long)(MAX_DECODED_BYTES >> 20));
            if (warn) *warn += buf;
            image->width = image->height = 0;
            image->image.clear();
            return true;
        }
        if (budget) budget->decoded += px * 4;
    }
    unsigned char *data = size > 0 ? stbi_load_from_memory(bytes, size, &w, &h, &comp, 4) : nullptr;
    if (!data || w <= 0 || h <= 0) {
        if (data) stbi_image_free(data);
        if (warn) *warn += "an image could not be decoded\n";
        image->width = image->height = 0;
        image->image.clear();
        return true;
    }
    image->width = w;
    image->height = h;
    image->component = 4;
    image->bits = 8;
    image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    image->image.assign(data, data + (size_t)w * (size_t)h * 4);
    stbi_image_free(data);
    return true;
}

double srgb_to_linear(double c) { return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4); }

/* Average of a texture's four channels (rgb sRGB-decoded when srgb); false when unusable. */
bool texture_average(const gl::Model &m, int tex, bool srgb, double avg[4]) {
    if (tex < 0 || tex >= (int)m.textures.size()) return false;
    int src = m.textures[tex].source;
    if (src < 0 || src >= (int)m.images.size()) return false;
    const gl::Image &im = m.images[src];
    size_t n = (size_t)std::max(im.width, 0) * (size_t)std::max(im.height, 0);
    if (n == 0 || im.component != 4 || im.bits != 8 || im.image.size() < n * 4) return false;
    double lut[256];
    for (int i = 0; i < 256; ++i) lut[i] = srgb ? srgb_to_linear(i / 255.0) : i / 255.0;
    double s[4] = {0, 0, 0, 0};
    for (size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) s[c] += lut[im.image[4 * i + c]];
        s[3] += im.image[4 * i + 3] / 255.0;
    }
    for (int c = 0; c < 4; ++c) avg[c] = s[c] / (double)n;
    return true;
}

double num(const gl::Value &v, const char *key, double def) {
    if (!v.IsObject() || !v.Has(key)) return def;
    const gl::Value &x = v.Get(key);
    return x.IsNumber() ? x.GetNumberAsDouble() : def;
}

double clamp01(double x) { return std::isfinite(x) ? std::min(1.0, std::max(0.0, x)) : 0.0; }

scene_material map_material(const gl::Model &model, const gl::Material &mat) {
    const gl::PbrMetallicRoughness &pbr = mat.pbrMetallicRoughness;
    double base[3] = {1, 1, 1};
    if (pbr.baseColorFactor.size() >= 3)
        for (int c = 0; c < 3; ++c) base[c] = pbr.baseColorFactor[c];
    double avg[4];
    if (texture_average(model, pbr.baseColorTexture.index, true, avg))
        for (int c = 0; c < 3; ++c) base[c] *= avg[c];
    double metal = pbr.metallicFactor, rough = pbr.roughnessFactor;
    if (texture_average(model, pbr.metallicRoughnessTexture.index, false, avg)) {
        rough *= avg[1];
        metal *= avg[2];
    }
    metal = clamp01(metal);
    rough = clamp01(rough);
    double f0 = 0.04, spec_factor = 1, spec_color[3] = {1, 1, 1};
    auto ior = mat.extensions.find("KHR_materials_ior");
    if (ior != mat.extensions.end()) {
        double n = num(ior->second, "ior", 1.5);
        if (std::isfinite(n) && n >= 1) f0 = ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
    }
    auto spec = mat.extensions.find("KHR_materials_specular");
    if (spec != mat.extensions.end()) {
        spec_factor = num(spec->second, "specularFactor", 1.0);
        if (spec->second.IsObject() && spec->second.Has("specularColorFactor")) {
            const gl::Value &c = spec->second.Get("specularColorFactor");
            if (c.IsArray() && c.ArrayLen() >= 3)
                for (int i = 0; i < 3; ++i)
                    if (c.Get(i).IsNumber()) spec_color[i] = c.Get(i).GetNumberAsDouble();
        }
    }
    double alpha = std::max(rough * rough, 0.01);
    double k = std::min(2.0 / (alpha * alpha) - 2.0, 20000.0);
    scene_material out;
    std::memset(&out, 0, sizeof out);
    if (k >= 1.0) {
        for (int c = 0; c < 3; ++c) {
            double d = clamp01(f0 * spec_color[c]) * clamp01(spec_factor);
            /* the specular layer reflects d first, the diffuse base gets the rest: the sum stays <= 1 */
            out.diffuse[c] = (float)clamp01(base[c] * (1 - metal) * (1 - d));
            out.glossy[c] = (float)clamp01(d * (1 - metal) + base[c] * metal);
        }
        out.exponent = (float)k;
        if (out.glossy[0] == 0 && out.glossy[1] == 0 && out.glossy[2] == 0) out.exponent = 0;
    } else {
        for (int c = 0; c < 3; ++c) out.diffuse[c] = (float)clamp01(base[c]);
    }
    return out;
}

const char *type_name(int t) {
    switch (t) {
    case TINYGLTF_TYPE_SCALAR: return "SCALAR";
    case TINYGLTF_TYPE_VEC2: return "VEC2";
    case TINYGLTF_TYPE_VEC3: return "VEC3";
    case TINYGLTF_TYPE_VEC4: return "VEC4";
    case TINYGLTF_TYPE_MAT2: return "MAT2";
    case TINYGLTF_TYPE_MAT3: return "MAT3";
    case TINYGLTF_TYPE_MAT4: return "MAT4";
    default: return "unknown";
    }
}

size_t component_size(int ct) {
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
    }
}

/* Bytes [offset, offset + (count-1) * stride + elem) of a buffer view, all checked. */
struct view_span {
    const unsigned char *base;
    size_t stride;
};
view_span checked_view(const gl::Model &m, int view, size_t offset, size_t count, size_t elem, const char *what) {
    if (view < 0 || view >= (int)m.bufferViews.size()) fail("%s: buffer view %d does not exist", what, view);
    const gl::BufferView &bv = m.bufferViews[view];
    if (bv.buffer < 0 || bv.buffer >= (int)m.buffers.size()) fail("%s: buffer %d does not exist", what, bv.buffer);
    const std::vector<unsigned char> &data = m.buffers[bv.buffer].data;
    size_t stride = bv.byteStride ? bv.byteStride : elem;
    if (stride < elem) fail("%s: byte stride %zu is smaller than an element (%zu bytes)", what, stride, elem);
    if (bv.byteOffset > data.size() || bv.byteLength > data.size() - bv.byteOffset)
        fail("%s: buffer view %d runs past the end of buffer %d (%zu bytes; missing or truncated .bin?)", what, view,
             bv.buffer, data.size());
    if (count > 0) {
        if (count > (SIZE_MAX - elem) / stride) fail("%s: accessor too large", what);
        size_t need = (count - 1) * stride + elem;
        if (offset > bv.byteLength || need > bv.byteLength - offset)
            fail("%s: accessor needs %zu bytes from offset %zu but buffer view %d has %zu", what, need, offset, view,
                 bv.byteLength);
    }
    return {data.data() + bv.byteOffset + offset, stride};
}

double read_component(const unsigned char *p, int ct) {
    switch (ct) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: { int8_t v; std::memcpy(&v, p, 1); return v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return *p;
    case TINYGLTF_COMPONENT_TYPE_SHORT: { int16_t v; std::memcpy(&v, p, 2); return v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { uint16_t v; std::memcpy(&v, p, 2); return v; }
    case TINYGLTF_COMPONENT_TYPE_INT: { int32_t v; std::memcpy(&v, p, 4); return v; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: { uint32_t v; std::memcpy(&v, p, 4); return v; }
    default: { float v; std::memcpy(&v, p, 4); return v; }
    }
}

/* Reads an accessor as doubles (ncomp per element), sparse substitution included. The caller
   has checked type and component type. */
std::vector<double> read_accessor(const gl::Model &m, int index, int ncomp, const char *what) {
    if (index < 0 || index >= (int)m.accessors.size()) fail("%s: accessor %d does not exist", what, index);
    const gl::Accessor &a = m.accessors[index];
    size_t cs = component_size(a.componentType);
    if (cs == 0) fail("%s: accessor %d has an invalid component type %d", what, index, a.componentType);
    size_t count = a.count, elem = cs * (size_t)ncomp;
    if (count > ((size_t)1 << 31)) fail("%s: accessor %d has too many elements (%zu)", what, index, count);
    std::vector<double> out;
    if (a.bufferView < 0 && count > ((size_t)1 << 24))
        fail("%s: accessor %d has %zu elements and no buffer view", what, index, count);
    if (a.bufferView >= 0) {
        view_span v = checked_view(m, a.bufferView, a.byteOffset, count, elem, what); /* before allocating */
        out.assign(count * (size_t)ncomp, 0.0);
        for (size_t i = 0; i < count; ++i)
            for (int c = 0; c < ncomp; ++c) out[i * ncomp + c] = read_component(v.base + i * v.stride + c * cs, a.componentType);
    } else
        out.assign(count * (size_t)ncomp, 0.0);
    if (a.sparse.isSparse) {
        size_t n = (size_t)std::max(a.sparse.count, 0);
        int ict = a.sparse.indices.componentType;
        size_t ics = component_size(ict);
        if (ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
            ict != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            fail("%s: sparse indices of accessor %d are not unsigned integers", what, index);
        view_span iv = checked_view(m, a.sparse.indices.bufferView, a.sparse.indices.byteOffset, n, ics, what);
        view_span vv = checked_view(m, a.sparse.values.bufferView, a.sparse.values.byteOffset, n, elem, what);
        iv.stride = ics; /* sparse data are tightly packed */
        vv.stride = elem;
        for (size_t i = 0; i < n; ++i) {
            double t = read_component(iv.base + i * ics, ict);
            if (t >= (double)count) fail("%s: sparse index %.0f of accessor %d is out of range", what, t, index);
            for (int c = 0; c < ncomp; ++c)
                out[(size_t)t * ncomp + c] = read_component(vv.base + i * elem + c * cs, a.componentType);
        }
    }
    return out;
}

std::vector<float> read_vec3f(const gl::Model &m, int index, const char *what) {
    if (index < 0 || index >= (int)m.accessors.size()) fail("%s: accessor %d does not exist", what, index);
    const gl::Accessor &a = m.accessors[index];
    if (a.type != TINYGLTF_TYPE_VEC3 || a.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
        fail("%s: accessor %d must be VEC3 of FLOAT, not %s of component type %d", what, index, type_name(a.type),
             a.componentType);
    std::vector<double> d = read_accessor(m, index, 3, what);
    return std::vector<float>(d.begin(), d.end());
}

std::vector<uint32_t> read_indices(const gl::Model &m, int index, const char *what) {
    if (index < 0 || index >= (int)m.accessors.size()) fail("%s: accessor %d does not exist", what, index);
    const gl::Accessor &a = m.accessors[index];
    int ct = a.componentType;
    if (a.type != TINYGLTF_TYPE_SCALAR ||
        (ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         ct != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT))
        fail("%s: index accessor %d must be SCALAR of unsigned 8/16/32-bit integers, not %s of component type %d", what,
             index, type_name(a.type), ct);
    std::vector<double> d = read_accessor(m, index, 1, what);
    std::vector<uint32_t> out(d.size());
    for (size_t i = 0; i < d.size(); ++i) out[i] = (uint32_t)d[i];
    return out;
}

mat4 node_matrix(const gl::Node &n, int index) {
    mat4 r = identity();
    if (n.matrix.size() == 16) {
        for (int i = 0; i < 16; ++i) r.m[i] = n.matrix[i];
    } else {
        if (!n.matrix.empty()) fail("node %d: matrix must have 16 numbers", index);
        double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
        if (n.translation.size() == 3) for (int i = 0; i < 3; ++i) t[i] = n.translation[i];
        else if (!n.translation.empty()) fail("node %d: translation must have 3 numbers", index);
        if (n.rotation.size() == 4) for (int i = 0; i < 4; ++i) q[i] = n.rotation[i];
        else if (!n.rotation.empty()) fail("node %d: rotation must have 4 numbers", index);
        if (n.scale.size() == 3) for (int i = 0; i < 3; ++i) s[i] = n.scale[i];
        else if (!n.scale.empty()) fail("node %d: scale must have 3 numbers", index);
        double ql = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(ql > 0)) fail("node %d: rotation is not a unit quaternion", index);
        double x = q[0] / ql, y = q[1] / ql, z = q[2] / ql, w = q[3] / ql;
        double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
                       2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                       2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y)}; /* column-major */
        for (int c = 0; c < 3; ++c)
            for (int row = 0; row < 3; ++row) r.m[c * 4 + row] = R[c * 3 + row] * s[c];
        r.m[12] = t[0]; r.m[13] = t[1]; r.m[14] = t[2];
    }
    for (int i = 0; i < 16; ++i)
        if (!std::isfinite(r.m[i])) fail("node %d: transform is not finite", index);
    return r;
}

struct gltf_loader {
    const gl::Model &model;
    builder &b;
    std::vector<uint32_t> material_slot; /* glTF material -> builder material */
    uint32_t default_material = UINT32_MAX;
    std::vector<char> on_path;
    size_t visits = 0;
    /* emissive surfaces, for the fallback light */
    double emit_area = 0, emit_power[3] = {0, 0, 0};
    vec3 emit_centre{0, 0, 0}, emit_normal{0, 0, 0};
    std::vector<double> emission; /* per glTF material: rgb radiance */
    bool camera_found = false;
    uint32_t skipped_primitives = 0;

    gltf_loader(const gl::Model &m, builder &bb) : model(m), b(bb) {}

    void materials() {
        for (size_t i = 0; i < model.materials.size(); ++i) {
            const gl::Material &mat = model.materials[i];
            material_slot.push_back((uint32_t)b.materials.size());
            b.materials.push_back(map_material(model, mat));
            double strength = 1.0;
            auto es = mat.extensions.find("KHR_materials_emissive_strength");
            if (es != mat.extensions.end()) strength = num(es->second, "emissiveStrength", 1.0);
            for (int c = 0; c < 3; ++c) {
                double e = mat.emissiveFactor.size() >= 3 ? mat.emissiveFactor[c] * strength : 0.0;
                emission.push_back(std::isfinite(e) && e > 0 ? e : 0.0);
            }
        }
    }

    uint32_t material_of(int m) {
        if (m < 0) {
            if (default_material == UINT32_MAX) {
                default_material = (uint32_t)b.materials.size();
                b.materials.push_back(make_material(0.8f, 0.8f, 0.8f));
            }
            return default_material;
        }
        if (m >= (int)model.materials.size()) fail("a primitive uses material %d, which does not exist", m);
        return material_slot[m];
    }

    void primitive(const mat4 &world, int mesh_index, int prim_index) {
        const gl::Primitive &p = model.meshes[mesh_index].primitives[prim_index];
        char what[96];
        std::snprintf(what, sizeof what, "mesh %d primitive %d", mesh_index, prim_index);
        int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN) {
            ++skipped_primitives;
            b.warn(std::string(what) + ": points or lines skipped");
            return;
        }
        auto pa = p.attributes.find("POSITION");
        if (pa == p.attributes.end()) {
            ++skipped_primitives;
            b.warn(std::string(what) + ": no POSITION, skipped");
            return;
        }
        std::vector<float> pos = read_vec3f(model, pa->second, what);
        size_t nv = pos.size() / 3;
        for (size_t v = 0; v < nv; ++v)
            if (!finite3(&pos[3 * v])) fail("%s: POSITION of vertex %zu is not finite", what, v);
        std::vector<uint32_t> idx;
        if (p.indices >= 0) idx = read_indices(model, p.indices, what);
        else {
            idx.resize(nv);
            for (size_t i = 0; i < nv; ++i) idx[i] = (uint32_t)i;
        }
        for (size_t i = 0; i < idx.size(); ++i)
            if (idx[i] >= nv) fail("%s: index %u at position %zu is out of range (%zu vertices)", what, idx[i], i, nv);
        std::vector<uint32_t> tris;
        if (mode == TINYGLTF_MODE_TRIANGLES) {
            if (idx.size() % 3) b.warn(std::string(what) + ": index count not a multiple of 3, extra ones ignored");
            tris.assign(idx.begin(), idx.begin() + (idx.size() / 3) * 3);
        } else {
            for (size_t i = 2; i < idx.size(); ++i) {
                uint32_t a, c, d;
                if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
                    a = idx[i - 2]; c = idx[i - 1]; d = idx[i];
                    if (i % 2) std::swap(a, c); /* keep the winding of odd strip triangles */
                } else {
                    a = idx[0]; c = idx[i - 1]; d = idx[i];
                }
                tris.push_back(a); tris.push_back(c); tris.push_back(d);
            }
        }
        if (tris.empty()) return;

        mesh_b m;
        double det = det3(world);
        if (!(std::fabs(det) > 0)) {
            b.warn(std::string(what) + ": node transform is singular, skipped");
            return;
        }
        m.pos.resize(nv * 3);
        for (size_t v = 0; v < nv; ++v) {
            vec3 w = xform_point(world, vec3{pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]});
            set3(&m.pos[3 * v], w.x, w.y, w.z);
            if (!finite3(&m.pos[3 * v])) fail("%s: vertex %zu is not finite after the node transform", what, v);
        }
        m.idx = tris;
        if (det < 0)
            for (size_t t = 0; t < m.idx.size(); t += 3) std::swap(m.idx[t + 1], m.idx[t + 2]);
        bool normals_ok = false;
        auto na = p.attributes.find("NORMAL");
        if (na != p.attributes.end()) {
            std::vector<float> nrm = read_vec3f(model, na->second, what);
            if (nrm.size() != pos.size()) fail("%s: NORMAL and POSITION counts differ", what);
            normals_ok = true;
            m.nrm.resize(nv * 3);
            double sign = det < 0 ? -1.0 : 1.0;
            for (size_t v = 0; v < nv && normals_ok; ++v) {
                vec3 n = normalize(mul(xform_normal(world, vec3{nrm[3 * v], nrm[3 * v + 1], nrm[3 * v + 2]}), sign));
                if (!finite3(&nrm[3 * v]) || !(len(n) > 0.5)) normals_ok = false;
                set3(&m.nrm[3 * v], n.x, n.y, n.z);
            }
            if (!normals_ok) b.warn(std::string(what) + ": some NORMAL is zero or not finite, normals recomputed");
        }
        if (!normals_ok) flat_normals(m);
        uint32_t mat = material_of(p.material);
        m.mat.assign(m.idx.size() / 3, mat);
        if (p.material >= 0) {
            const double *e = &emission[3 * p.material];
            if (e[0] + e[1] + e[2] > 0)
                for (size_t t = 0; t < m.idx.size(); t += 3) {
                    const float *A = &m.pos[3 * m.idx[t]], *B = &m.pos[3 * m.idx[t + 1]], *C = &m.pos[3 * m.idx[t + 2]];
                    vec3 a{A[0], A[1], A[2]}, bb{B[0], B[1], B[2]}, c{C[0], C[1], C[2]};
                    vec3 n = cross(sub(bb, a), sub(c, a));
                    /* orient by the vertex normals: emitters shine to their front */
                    const float *na0 = &m.nrm[3 * m.idx[t]];
                    if (dot(n, vec3{na0[0], na0[1], na0[2]}) < 0) n = mul(n, -1.0);
                    double area = 0.5 * len(n);
                    emit_area += area;
                    emit_centre = add(emit_centre, mul(add(add(a, bb), c), area / 3.0));
                    emit_normal = add(emit_normal, mul(n, 0.5));
                    for (int k = 0; k < 3; ++k) emit_power[k] += e[k] * area;
                }
        }
        b.meshes.push_back(std::move(m));
    }

    void node(int index, const mat4 &parent, int depth) {
        if (index < 0 || index >= (int)model.nodes.size()) fail("node %d does not exist", index);
        if (on_path[index]) fail("node %d is its own ancestor (a cycle in the node hierarchy)", index);
        if (depth > 1000 || ++visits > 1000000) fail("node hierarchy too deep or too large");
        on_path[index] = 1;
        const gl::Node &n = model.nodes[index];
        mat4 world = mul(parent, node_matrix(n, index));
        if (n.mesh >= 0) {
            if (n.mesh >= (int)model.meshes.size()) fail("node %d: mesh %d does not exist", index, n.mesh);
            for (size_t p = 0; p < model.meshes[n.mesh].primitives.size(); ++p) primitive(world, n.mesh, (int)p);
        }
        if (n.camera >= 0 && !camera_found && n.camera < (int)model.cameras.size() &&
            model.cameras[n.camera].type == "perspective") {
            double yfov = model.cameras[n.camera].perspective.yfov;
            vec3 eye = xform_point(world, vec3{0, 0, 0});
            vec3 fwd = normalize(xform_dir(world, vec3{0, 0, -1}));
            if (yfov > 0 && yfov < PI && len(fwd) > 0) {
                camera_found = true;
                set3(b.camera.eye, eye.x, eye.y, eye.z);
                vec3 t = add(eye, fwd);
                set3(b.camera.target, t.x, t.y, t.z);
                b.camera.fovy = (float)yfov;
                b.has_camera = true;
            }
        }
        auto le = n.extensions.find("KHR_lights_punctual");
        if (le != n.extensions.end() && le->second.IsObject() && le->second.Has("light")) {
            const gl::Value &li = le->second.Get("light");
            int l = li.IsNumber() ? li.GetNumberAsInt() : -1;
            if (l < 0 || l >= (int)model.lights.size()) fail("node %d: light %d does not exist", index, l);
            punctual(model.lights[l], world);
        }
        for (int c : n.children) node(c, world, depth + 1);
        on_path[index] = 0;
    }

    /* Triangles of one primitive as declared by its accessors (0 where they are unusable: the
       expansion reports those). */
    double declared_triangles(const gl::Primitive &p) const {
        int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
        int acc = p.indices;
        if (acc < 0) {
            auto pa = p.attributes.find("POSITION");
            acc = pa == p.attributes.end() ? -1 : pa->second;
        }
        if (acc < 0 || acc >= (int)model.accessors.size()) return 0;
        double n = (double)model.accessors[acc].count;
        if (mode == TINYGLTF_MODE_TRIANGLES) return std::floor(n / 3);
        if (mode == TINYGLTF_MODE_TRIANGLE_STRIP || mode == TINYGLTF_MODE_TRIANGLE_FAN) return n > 2 ? n - 2 : 0;
        return 0;
    }

    /* What the node graph expands to, counted over its paths before anything is expanded
       (each node once, memoised; a node reached twice is expanded twice): mesh instances and
       declared triangles above the limits are refused with the totals. */
    void expansion_check(const std::vector<int> &roots) {
        size_t n = model.nodes.size();
        std::vector<double> inst(n, 0), tris(n, 0);
        std::vector<char> state(n, 0); /* 0 new, 1 on the path, 2 done */
        struct walk {
            const gltf_loader &L;
            std::vector<double> &inst, &tris;
            std::vector<char> &state;
            void go(int i, int depth) {
                if (i < 0 || i >= (int)state.size() || depth > 1000) return; /* the expansion reports these */
                if (state[i]) return;                                     /* a cycle: reported there too */
                state[i] = 1;
                const gl::Node &nd = L.model.nodes[i];
                double a = 0, t = 0;
                if (nd.mesh >= 0 && nd.mesh < (int)L.model.meshes.size()) {
                    a = 1;
                    for (const gl::Primitive &p : L.model.meshes[nd.mesh].primitives) t += L.declared_triangles(p);
                }
                for (int c : nd.children) {
                    go(c, depth + 1);
                    if (c >= 0 && c < (int)state.size() && state[c] == 2) { a += inst[c]; t += tris[c]; }
                }
                inst[i] = a; tris[i] = t;
                state[i] = 2;
            }
        } w{*this, inst, tris, state};
        double a = 0, t = 0;
        for (int r : roots) {
            w.go(r, 0);
            if (r >= 0 && r < (int)n && state[r] == 2) { a += inst[r]; t += tris[r]; }
        }
        if (a > MAX_INSTANCES || t > MAX_TRIANGLES)
            fail("the node graph expands to %.0f mesh instances and %.0f triangles, above the loader's limits "
                 "(%.0f instances, %.0f triangles)", a, t, MAX_INSTANCES, MAX_TRIANGLES);
    }

    void punctual(const gl::Light &gl_light, const mat4 &world) {
        scene_light l;
        std::memset(&l, 0, sizeof l);
        double col[3] = {1, 1, 1};
        if (gl_light.color.size() >= 3)
            for (int c = 0; c < 3; ++c) col[c] = gl_light.color[c];
        for (int c = 0; c < 3; ++c) l.color[c] = (float)(std::isfinite(col[c]) ? std::max(0.0, col[c]) : 0.0);
        vec3 pos = xform_point(world, vec3{0, 0, 0});
        vec3 axis = normalize(xform_dir(world, vec3{0, 0, -1}));
        double I = std::isfinite(gl_light.intensity) ? std::max(0.0, gl_light.intensity) : 0.0;
        if (len(axis) == 0) axis = {0, -1, 0};
        if (gl_light.type == "directional") {
            l.type = SCENE_LIGHT_DIRECTIONAL;
            set3(l.direction, -axis.x, -axis.y, -axis.z);
            l.irradiance = (float)I;
        } else if (gl_light.type == "spot" || gl_light.type == "point") {
            l.type = SCENE_LIGHT_SPOT;
            set3(l.position, pos.x, pos.y, pos.z);
            set3(l.direction, axis.x, axis.y, axis.z);
            double a = gl_light.type == "spot" ? gl_light.spot.outerConeAngle : PI;
            l.half_angle = (float)(a > 0 && a <= PI ? a : PI / 4);
            l.intensity = (float)I;
        } else {
            b.warn("light of unknown type '" + gl_light.type + "' skipped");
            return;
        }
        b.lights.push_back(l);
    }

    void run() {
        materials();
        on_path.assign(model.nodes.size(), 0);
        std::vector<int> roots;
        int sc = model.defaultScene >= 0 ? model.defaultScene : (model.scenes.empty() ? -1 : 0);
        if (sc >= (int)model.scenes.size()) fail("default scene %d does not exist", sc);
        if (sc >= 0) roots = model.scenes[sc].nodes;
        else {
            std::vector<char> child(model.nodes.size(), 0);
            for (auto &n : model.nodes)
                for (int c : n.children)
                    if (c >= 0 && c < (int)child.size()) child[c] = 1;
            for (size_t i = 0; i < model.nodes.size(); ++i)
                if (!child[i]) roots.push_back((int)i);
        }
        expansion_check(roots);
        for (int r : roots) node(r, identity(), 0);
        size_t tris = 0;
        for (auto &m : b.meshes) tris += m.idx.size() / 3;
        if (tris == 0) {
            char buf[160];
            std::snprintf(buf, sizeof buf, "the file has no triangles in its scene (%u primitives of points or lines skipped)",
                          skipped_primitives);
            throw scene_error{skipped_primitives ? buf : "the file has no triangles in its scene", SCENE_NO_TRIANGLES};
        }
        if (tris > 0xffffffffu) fail("too many triangles");
        vec3 lo, hi;
        builder_bounds(b, lo, hi);
        double scale = len(sub(hi, lo));
        if (b.lights.empty() && emit_area > 0) {
            /* emissive surfaces -> one spot: Lambertian emitter's on-axis intensity is L_e * A */
            vec3 c = mul(emit_centre, 1.0 / emit_area);
            vec3 n = normalize(emit_normal);
            if (len(n) == 0) n = {0, -1, 0};
            scene_light l;
            std::memset(&l, 0, sizeof l);
            l.type = SCENE_LIGHT_SPOT;
            vec3 p = add(c, mul(n, 1e-3 * scale));
            set3(l.position, p.x, p.y, p.z);
            set3(l.direction, n.x, n.y, n.z);
            l.half_angle = (float)(60.0 * PI / 180.0);
            double mx = std::max(emit_power[0], std::max(emit_power[1], emit_power[2]));
            l.intensity = (float)mx;
            for (int k = 0; k < 3; ++k) l.color[k] = (float)(emit_power[k] / mx);
            b.lights.push_back(l);
        }
        if (b.lights.empty()) { /* the default sun */
            scene_light l;
            std::memset(&l, 0, sizeof l);
            l.type = SCENE_LIGHT_DIRECTIONAL;
            set3(l.color, 1, 1, 1);
            vec3 d = normalize(vec3{0.4, 1.0, 0.3});
            set3(l.direction, d.x, d.y, d.z);
            l.irradiance = 1.0f;
            b.lights.push_back(l);
        }
        if (!b.has_camera) frame_bounds(b);
    }
};

bool is_glb(const unsigned char *d, size_t n) { return n >= 4 && std::memcmp(d, "glTF", 4) == 0; }

/* Deepest nesting of objects and arrays in JSON text (strings skipped), counted up to
   MAX_JSON_DEPTH + 1: the parser recurses once per level, so the text is refused first. */
unsigned json_depth(const unsigned char *d, size_t n) {
    unsigned depth = 0, deepest = 0;
    bool in_string = false, escaped = false;
    for (size_t i = 0; i < n && deepest <= MAX_JSON_DEPTH; ++i) {
        unsigned char c = d[i];
        if (in_string) {
            if (escaped) escaped = false;
            else if (c == '\\') escaped = true;
            else if (c == '"') in_string = false;
        } else if (c == '"') {
            in_string = true;
        } else if (c == '{' || c == '[') {
            if (++depth > deepest) deepest = depth;
        } else if ((c == '}' || c == ']') && depth > 0) {
            --depth;
        }
    }
    return deepest;
}

/* A regular file of at most MAX_FILE_BYTES, read by its size: a FIFO would block, a device
   (a symlink to /dev/zero) would read without end. Empty string: fine; else why not. */
std::string check_regular(const std::string &path, uint64_t *size) {
    struct stat st;
    if (stat(path.c_str(), &st) != 0) return std::string("cannot open: ") + std::strerror(errno);
    if (!S_ISREG(st.st_mode)) return "not a regular file (a FIFO, device or directory)";
    if ((uint64_t)st.st_size > MAX_FILE_BYTES) return "larger than the loader's limit";
    *size = (uint64_t)st.st_size;
    return std::string();
}

/* limit: the most bytes the caller will take from this file (UINT64_MAX: any up to
   MAX_FILE_BYTES); a larger file is refused from its size, before anything is read. */
std::string read_regular(std::vector<unsigned char> *out, const std::string &path, uint64_t limit = UINT64_MAX) {
    uint64_t size = 0;
    std::string why = check_regular(path, &size);
    if (why.empty() && size > limit)
        why = std::to_string(size) + " bytes, more than the " + std::to_string(limit) + " its buffer declares";
    if (why.empty()) {
        std::ifstream f(path, std::ios::binary);
        if (!f) why = std::string("cannot open: ") + std::strerror(errno);
        else {
            out->resize((size_t)size);
            if (size && !f.read(reinterpret_cast<char *>(out->data()), (std::streamsize)size)) why = "read error";
        }
    }
    return why;
}

/* The byteLength each external buffer declares, by the path tinygltf will read it from
   (JoinPath of the base directory or ".", as its FindFile does; no expansion, see fs_expand).
   tinygltf takes a buffer's file only when its size equals byteLength, so a file of any
   other size is refused without being read whole: a larger one from its size (else it was
   read, up to MAX_FILE_BYTES, only to be refused), a shorter one by tinygltf's size check.
   Paths named by several buffers keep the largest. */
struct declared_sizes {
    std::vector<std::pair<std::string, uint64_t>> paths;
    uint64_t limit(const std::string &path) const {
        uint64_t l = 0;
        bool found = false;
        for (const auto &p : paths)
            if (p.first == path) {
                l = std::max(l, p.second);
                found = true;
            }
        return found ? l : UINT64_MAX;
    }
};

/* Only the top-level "buffers" array is kept from the JSON (the rest is dropped while
   parsing); text that does not parse gives no sizes, tinygltf then says why. */
void collect_buffer_sizes(const unsigned char *text, size_t n, const std::string &base_dir, declared_sizes *out) {
    nlohmann::json::parser_callback_t keep = [](int depth, nlohmann::json::parse_event_t ev, nlohmann::json &j) {
        return !(depth == 1 && ev == nlohmann::json::parse_event_t::key && j != "buffers");
    };
    nlohmann::json doc = nlohmann::json::parse(text, text + n, keep, false);
    if (!doc.is_object() || !doc.contains("buffers") || !doc["buffers"].is_array()) return;
    for (const nlohmann::json &b : doc["buffers"]) {
        if (!b.is_object() || !b.contains("uri") || !b["uri"].is_string()) continue;
        if (!b.contains("byteLength") || !b["byteLength"].is_number_unsigned()) continue;
        std::string uri = b["uri"].get<std::string>();
        if (gl::IsDataURI(uri)) continue;
        uint64_t len = b["byteLength"].get<uint64_t>();
        std::string file = gl::dlib::urldecode(uri);
        out->paths.emplace_back(gl::JoinPath(base_dir, file), len);
        out->paths.emplace_back(gl::JoinPath(".", file), len);
    }
}

/* tinygltf's file access for buffers and images given by uri: regular files only (fs_read
   says why not; "exists" only sends the path there), no path expansion, buffers bounded by
   their declared sizes (user_data: the declared_sizes). */
bool fs_exists(const std::string &path, void *) {
    struct stat st;
    return stat(path.c_str(), &st) == 0;
}
std::string fs_expand(const std::string &path, void *) { return path; }
bool fs_read(std::vector<unsigned char> *out, std::string *err, const std::string &path, void *user) {
    const declared_sizes *sizes = static_cast<const declared_sizes *>(user);
    std::string why = read_regular(out, path, sizes ? sizes->limit(path) : UINT64_MAX);
    if (!why.empty() && err) *err += path + ": " + why + "\n";
    return why.empty();
}
bool fs_write(std::string *err, const std::string &, const std::vector<unsigned char> &, void *) {
    if (err) *err += "the loader writes no files\n";
    return false;
}

void load_gltf(const unsigned char *data, size_t size, const std::string &base_dir, builder &b) {
    if (size > 0xffffffffu) fail("file too large");
    declared_sizes sizes;
    {
        const unsigned char *text = data;
        size_t text_size = size;
        if (is_glb(data, size) && size >= 20) { /* the JSON chunk; its length is checked by the parser */
            uint32_t len = 0;
            std::memcpy(&len, data + 12, 4);
            text = data + 20;
            text_size = std::min((size_t)len, size - 20);
        }
        if (json_depth(text, text_size) > MAX_JSON_DEPTH)
            fail("the JSON nests objects and arrays more than %u levels deep", MAX_JSON_DEPTH);
        collect_buffer_sizes(text, text_size, base_dir, &sizes);
    }
    gl::TinyGLTF ctx;
    image_budget budget;
    gl::FsCallbacks fs;
    fs.FileExists = fs_exists;
    fs.ExpandFilePath = fs_expand;
    fs.ReadWholeFile = fs_read;
    fs.WriteWholeFile = fs_write;
    fs.user_data = &sizes;
    ctx.SetFsCallbacks(fs);
    ctx.SetImageLoader(load_image, &budget);
    gl::Model model;
    std::string err, warn;
    bool ok = is_glb(data, size)
                  ? ctx.LoadBinaryFromMemory(&model, &err, &warn, data, (unsigned)size, base_dir)
                  : ctx.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char *>(data), (unsigned)size,
                                            base_dir);
    if (!ok) {
        std::string e = err.empty() ? warn : err;
        for (char &c : e)
            if (c == '\n' || c == '\r') c = ' ';
        for (size_t at = e.find(";base64,"); at != std::string::npos; at = e.find(";base64,", at + 1)) {
            size_t end = e.find_first_of(" '\"", at + 8); /* a data URI's payload says nothing */
            e.replace(at + 8, (end == std::string::npos ? e.size() : end) - (at + 8), "...");
        }
        while (!e.empty() && e.back() == ' ') e.pop_back();
        fail("not a valid glTF file: %s", e.empty() ? "parse failed" : e.c_str());
    }
    if (!warn.empty()) {
        std::string w = warn.substr(0, warn.find('\n'));
        b.warn("tinygltf: " + w);
    }
    gltf_loader L(model, b);
    L.run();
}

std::string dir_of(const std::string &path) {
    size_t s = path.find_last_of('/');
    return s == std::string::npos ? std::string(".") : path.substr(0, s == 0 ? 1 : s);
}

std::string base_name(const std::string &path) {
    size_t s = path.find_last_of('/');
    std::string n = s == std::string::npos ? path : path.substr(s + 1);
    size_t d = n.find_last_of('.');
    return d == std::string::npos ? n : n.substr(0, d);
}

int guarded(scene *out, char *err, size_t cap, const char *prefix, void (*fn)(void *, builder &), void *arg) {
    if (out) std::memset(out, 0, sizeof *out);
    if (!out) {
        set_err(err, cap, "%s: no output scene", prefix);
        return 1;
    }
    try {
        builder b;
        fn(arg, b);
        finish(b, out);
        if (scene_validate(out, err, cap) != 0) {
            std::string e = err ? std::string(err) : std::string();
            scene_free(out);
            set_err(err, cap, "%s: %s", prefix, e.c_str());
            return 1;
        }
        return 0;
    } catch (const scene_error &e) {
        set_err(err, cap, "%s: %s", prefix, e.msg.c_str());
        std::memset(out, 0, sizeof *out);
        return e.code;
    } catch (const std::bad_alloc &) {
        set_err(err, cap, "%s: out of memory", prefix);
    } catch (const std::exception &e) {
        set_err(err, cap, "%s: %s", prefix, e.what());
    } catch (...) {
        set_err(err, cap, "%s: unexpected failure", prefix);
    }
    std::memset(out, 0, sizeof *out);
    return 1;
}

struct mem_args {
    const void *data;
    size_t size;
    std::string base_dir;
};
void run_mem(void *p, builder &b) {
    mem_args *a = static_cast<mem_args *>(p);
    if (!a->data && a->size) fail("no data");
    load_gltf(static_cast<const unsigned char *>(a->data), a->size, a->base_dir, b);
}

struct file_args {
    std::string path;
};
void run_file(void *p, builder &b) {
    file_args *a = static_cast<file_args *>(p);
    std::vector<unsigned char> data;
    std::string why = read_regular(&data, a->path);
    if (!why.empty()) fail("%s", why.c_str());
    if (data.empty()) fail("the file is empty");
    load_gltf(data.data(), data.size(), dir_of(a->path), b);
    b.name = base_name(a->path);
}

void run_builtin(void *p, builder &b) {
    const char *name = static_cast<const char *>(p);
    if (std::strcmp(name, "cornell") == 0) build_cornell(b);
    else if (std::strcmp(name, "street") == 0) build_street(b);
    else if (std::strcmp(name, "courtyard") == 0) build_courtyard(b);
    else fail("unknown built-in scene '%s' (cornell, street, courtyard, or a .gltf/.glb path)", name);
}

/* ---- argument parsing ----------------------------------------------------------------------- */

bool parse_floats(const char *s, float *out, int n) {
    const char *p = s;
    for (int i = 0; i < n; ++i) {
        char *end;
        errno = 0;
        double v = std::strtod(p, &end);
        if (end == p || errno == ERANGE || !std::isfinite(v) || std::fabs(v) > 3.0e38) return false;
        out[i] = (float)v;
        p = end;
        if (i + 1 < n) {
            if (*p != ',') return false;
            ++p;
        }
    }
    return *p == 0;
}

bool parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out) {
    if (!s || !*s || *s == '-' || *s == '+' || *s == ' ') return false;
    char *end;
    errno = 0;
    unsigned long long v = std::strtoull(s, &end, 10);
    if (*end || errno == ERANGE || v < lo || v > hi) return false;
    *out = (uint32_t)v;
    return true;
}

bool unit3(float *v) {
    double l = std::sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
    if (!(l > 1e-30) || !std::isfinite(l)) return false;
    for (int i = 0; i < 3; ++i) v[i] = (float)(v[i] / l);
    return true;
}

} /* namespace */

/* ============================================================================================ */
extern "C" {

void scene_options_defaults(scene_options *o, const char *default_out_dir) {
    if (!o) return;
    std::memset(o, 0, sizeof *o);
    o->scene = "street";
    o->sun_irradiance = 1.0f;
    o->width = 640;
    o->height = 360;
    o->out_dir = default_out_dir ? default_out_dir : "out";
    o->bounces = 1;
    o->spp = 256;
    o->seed = 1;
}

const char *scene_usage(unsigned flags) {
    return (flags & SCENE_ARGS_REFERENCE)
               ? "options:\n"
                 "  --scene NAME|PATH     street (default), cornell, courtyard, or a .gltf/.glb file\n"
                 "  --sun-dir X,Y,Z       direction towards the sun\n"
                 "  --sun-irradiance E    irradiance of the sun on a surface facing it (default 1)\n"
                 "  --spot PX,PY,PZ,DX,DY,DZ,HALF_ANGLE_DEG,INTENSITY   a spot light instead\n"
                 "  --camera EX,EY,EZ,TX,TY,TZ,FOVY_DEG\n"
                 "  --size WxH            image size (default 640x360)\n"
                 "  --out DIR             output folder\n"
                 "  --bounces 1|2         indirect bounces (default 1)\n"
                 "  --spp N               paths per pixel (default 256)\n"
                 "  --seed N              random seed (default 1)\n"
               : "options:\n"
                 "  --scene NAME|PATH     street (default), cornell, courtyard, or a .gltf/.glb file\n"
                 "  --sun-dir X,Y,Z       direction towards the sun\n"
                 "  --sun-irradiance E    irradiance of the sun on a surface facing it (default 1)\n"
                 "  --spot PX,PY,PZ,DX,DY,DZ,HALF_ANGLE_DEG,INTENSITY   a spot light instead\n"
                 "  --camera EX,EY,EZ,TX,TY,TZ,FOVY_DEG\n"
                 "  --size WxH            image size (default 640x360)\n"
                 "  --out DIR             output folder\n"
                 "  --bounces 1|2         indirect bounces (default 1)\n";
}

int scene_parse_args(int argc, char *const *argv, unsigned flags, scene_options *o, char *err, size_t cap) {
    if (!o) {
        set_err(err, cap, "no options struct");
        return SCENE_ARGS_ERROR;
    }
    for (int i = 1; i < argc; ++i) {
        const char *arg = argv[i];
        if (!arg) continue;
        if (!std::strcmp(arg, "--help") || !std::strcmp(arg, "-h")) {
            std::fputs(scene_usage(flags), stdout);
            return SCENE_ARGS_HELP;
        }
        if (std::strncmp(arg, "--", 2) != 0) {
            set_err(err, cap, "unexpected argument '%s' (options start with --; see --help)", arg);
            return SCENE_ARGS_ERROR;
        }
        std::string name(arg), value;
        bool inline_value = false;
        size_t eq = name.find('=');
        if (eq != std::string::npos) {
            value = name.substr(eq + 1);
            name = name.substr(0, eq);
            inline_value = true;
        }
        static const char *known[] = {"--scene", "--sun-dir", "--sun-irradiance", "--spot", "--camera", "--size",
                                      "--out", "--bounces", "--spp", "--seed"};
        bool ok = false;
        for (const char *k : known)
            if (name == k) ok = true;
        if (!(flags & SCENE_ARGS_REFERENCE) && (name == "--spp" || name == "--seed")) ok = false;
        if (!ok) {
            set_err(err, cap, "unknown option '%s' (see --help)", name.c_str());
            return SCENE_ARGS_ERROR;
        }
        const char *v;
        if (inline_value) {
            /* points into argv: after the '=' */
            v = arg + eq + 1;
        } else {
            if (i + 1 >= argc || !argv[i + 1]) {
                set_err(err, cap, "option %s needs a value (see --help)", name.c_str());
                return SCENE_ARGS_ERROR;
            }
            v = argv[++i];
        }
        (void)value;
        if (name == "--scene") {
            if (!*v) { set_err(err, cap, "--scene needs a name or a path"); return SCENE_ARGS_ERROR; }
            o->scene = v;
        } else if (name == "--sun-dir") {
            float d[3];
            if (!parse_floats(v, d, 3) || !unit3(d)) {
                set_err(err, cap, "--sun-dir wants X,Y,Z (three finite numbers, not all zero), got '%s'", v);
                return SCENE_ARGS_ERROR;
            }
            std::memcpy(o->sun_dir, d, sizeof d);
            o->has_sun_dir = 1;
        } else if (name == "--sun-irradiance") {
            float e;
            if (!parse_floats(v, &e, 1) || e < 0) {
                set_err(err, cap, "--sun-irradiance wants a finite number >= 0, got '%s'", v);
                return SCENE_ARGS_ERROR;
            }
            o->sun_irradiance = e;
            o->has_sun_irradiance = 1;
        } else if (name == "--spot") {
            float s[8];
            if (!parse_floats(v, s, 8) || !unit3(s + 3) || !(s[6] > 0 && s[6] <= 180) || !(s[7] >= 0)) {
                set_err(err, cap,
                        "--spot wants PX,PY,PZ,DX,DY,DZ,HALF_ANGLE_DEG,INTENSITY (direction not zero, half-angle in "
                        "(0,180], intensity >= 0), got '%s'",
                        v);
                return SCENE_ARGS_ERROR;
            }
            std::memcpy(o->spot_position, s, 3 * sizeof(float));
            std::memcpy(o->spot_direction, s + 3, 3 * sizeof(float));
            o->spot_half_angle_deg = s[6];
            o->spot_intensity = s[7];
            o->has_spot = 1;
        } else if (name == "--camera") {
            float c[7];
            bool good = parse_floats(v, c, 7) && c[6] > 0 && c[6] < 180;
            if (good) {
                float d[3] = {c[3] - c[0], c[4] - c[1], c[5] - c[2]};
                good = unit3(d);
            }
            if (!good) {
                set_err(err, cap, "--camera wants EX,EY,EZ,TX,TY,TZ,FOVY_DEG (eye != target, fovy in (0,180)), got '%s'", v);
                return SCENE_ARGS_ERROR;
            }
            std::memcpy(o->camera_eye, c, 3 * sizeof(float));
            std::memcpy(o->camera_target, c + 3, 3 * sizeof(float));
            o->camera_fovy_deg = c[6];
            o->has_camera = 1;
        } else if (name == "--size") {
            std::string s(v);
            size_t x = s.find('x');
            uint32_t w, h;
            if (x == std::string::npos || !parse_u32(s.substr(0, x).c_str(), 1, 16384, &w) ||
                !parse_u32(s.substr(x + 1).c_str(), 1, 16384, &h)) {
                set_err(err, cap, "--size wants WxH with each in 1..16384, got '%s'", v);
                return SCENE_ARGS_ERROR;
            }
            o->width = w;
            o->height = h;
        } else if (name == "--out") {
            if (!*v) { set_err(err, cap, "--out needs a folder"); return SCENE_ARGS_ERROR; }
            o->out_dir = v;
        } else if (name == "--bounces") {
            uint32_t b;
            if (!parse_u32(v, 1, 2, &b)) { set_err(err, cap, "--bounces wants 1 or 2, got '%s'", v); return SCENE_ARGS_ERROR; }
            o->bounces = (int)b;
        } else if (name == "--spp") {
            uint32_t n;
            if (!parse_u32(v, 1, 1u << 20, &n)) { set_err(err, cap, "--spp wants an integer in 1..1048576, got '%s'", v); return SCENE_ARGS_ERROR; }
            o->spp = n;
        } else if (name == "--seed") {
            uint32_t n;
            if (!parse_u32(v, 0, 0xffffffffu, &n)) { set_err(err, cap, "--seed wants an integer in 0..4294967295, got '%s'", v); return SCENE_ARGS_ERROR; }
            o->seed = n;
        }
    }
    return SCENE_ARGS_OK;
}

int scene_builtin(const char *name, scene *out, char *err, size_t cap) {
    if (!name) {
        if (out) std::memset(out, 0, sizeof *out);
        set_err(err, cap, "scene: no name");
        return 1;
    }
    std::string prefix = std::string("scene '") + name + "'";
    return guarded(out, err, cap, prefix.c_str(), run_builtin, const_cast<char *>(name));
}

int scene_load_gltf(const char *path, scene *out, char *err, size_t cap) {
    if (!path) {
        if (out) std::memset(out, 0, sizeof *out);
        set_err(err, cap, "glTF: no path");
        return 1;
    }
    file_args a{path};
    return guarded(out, err, cap, path, run_file, &a);
}

int scene_load_gltf_memory(const void *data, size_t size, const char *base_dir, scene *out, char *err, size_t cap) {
    mem_args a{data, size, base_dir ? std::string(base_dir) : std::string(".")};
    return guarded(out, err, cap, "glTF (memory)", run_mem, &a);
}

int scene_load(const scene_options *o, scene *out, char *err, size_t cap) {
    if (out) std::memset(out, 0, sizeof *out);
    if (!o || !out || !o->scene) {
        set_err(err, cap, "scene_load: no options or no output");
        return 1;
    }
    std::string n(o->scene);
    auto ends = [&](const char *suf) {
        size_t l = std::strlen(suf);
        if (n.size() < l) return false;
        for (size_t i = 0; i < l; ++i)
            if (std::tolower((unsigned char)n[n.size() - l + i]) != suf[i]) return false;
        return true;
    };
    int r;
    if (ends(".gltf") || ends(".glb")) r = scene_load_gltf(o->scene, out, err, cap);
    else if (n.find('/') != std::string::npos) {
        set_err(err, cap, "--scene %s: a path must end in .gltf or .glb", o->scene);
        return 1;
    } else
        r = scene_builtin(o->scene, out, err, cap);
    if (r) return r;

    /* lights from the options */
    if (o->has_sun_dir || o->has_sun_irradiance || o->has_spot) {
        float sun_default[3] = {0.4f, 1.0f, 0.3f};
        unit3(sun_default);
        for (uint32_t i = 0; i < out->light_count; ++i)
            if (out->lights[i].type == SCENE_LIGHT_DIRECTIONAL) {
                std::memcpy(sun_default, out->lights[i].direction, sizeof sun_default);
                break;
            }
        std::vector<scene_light> ls;
        if (o->has_sun_dir || o->has_sun_irradiance) {
            scene_light l;
            std::memset(&l, 0, sizeof l);
            l.type = SCENE_LIGHT_DIRECTIONAL;
            set3(l.color, 1, 1, 1);
            std::memcpy(l.direction, o->has_sun_dir ? o->sun_dir : sun_default, sizeof l.direction);
            unit3(l.direction);
            l.irradiance = o->sun_irradiance;
            ls.push_back(l);
        }
        if (o->has_spot) {
            scene_light l;
            std::memset(&l, 0, sizeof l);
            l.type = SCENE_LIGHT_SPOT;
            set3(l.color, 1, 1, 1);
            std::memcpy(l.position, o->spot_position, sizeof l.position);
            std::memcpy(l.direction, o->spot_direction, sizeof l.direction);
            unit3(l.direction);
            l.half_angle = (float)(o->spot_half_angle_deg * PI / 180.0);
            l.intensity = o->spot_intensity;
            ls.push_back(l);
        }
        scene_light *nl = static_cast<scene_light *>(std::malloc(ls.size() * sizeof(scene_light)));
        if (!nl) {
            scene_free(out);
            set_err(err, cap, "scene_load: out of memory");
            return 1;
        }
        std::memcpy(nl, ls.data(), ls.size() * sizeof(scene_light));
        std::free(out->lights);
        out->lights = nl;
        out->light_count = (uint32_t)ls.size();
    }
    if (o->has_camera) {
        std::memcpy(out->camera.eye, o->camera_eye, sizeof out->camera.eye);
        std::memcpy(out->camera.target, o->camera_target, sizeof out->camera.target);
        out->camera.fovy = (float)(o->camera_fovy_deg * PI / 180.0);
    }
    out->camera.width = o->width;
    out->camera.height = o->height;
    if (scene_validate(out, err, cap) != 0) {
        std::string e = err ? std::string(err) : std::string();
        scene_free(out);
        set_err(err, cap, "%s: %s", o->scene, e.c_str());
        return 1;
    }
    return 0;
}

int scene_validate(scene *s, char *err, size_t cap) {
    if (!s) { set_err(err, cap, "no scene"); return 1; }
    if (s->mesh_count == 0 || !s->meshes) { set_err(err, cap, "the scene has no meshes"); return 1; }
    if (s->material_count == 0 || !s->materials) { set_err(err, cap, "the scene has no materials"); return 1; }
    for (uint32_t i = 0; i < s->material_count; ++i) {
        const scene_material &m = s->materials[i];
        for (int c = 0; c < 3; ++c)
            if (!(m.diffuse[c] >= 0 && m.diffuse[c] <= 1) || !(m.glossy[c] >= 0 && m.glossy[c] <= 1)) {
                set_err(err, cap, "material %u: albedo outside [0,1] or not finite", i);
                return 1;
            }
        if (!(m.exponent >= 0 && m.exponent <= 1e6f)) { set_err(err, cap, "material %u: exponent k outside [0,1e6]", i); return 1; }
    }
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    uint64_t tris = 0;
    for (uint32_t k = 0; k < s->mesh_count; ++k) {
        scene_mesh &m = s->meshes[k];
        if (m.triangle_count == 0 || m.vertex_count == 0 || !m.positions || !m.normals || !m.indices || !m.triangle_material) {
            set_err(err, cap, "mesh %u: empty or missing arrays", k);
            return 1;
        }
        for (uint32_t v = 0; v < m.vertex_count; ++v) {
            const float *p = m.positions + 3 * v, *n = m.normals + 3 * v;
            if (!finite3(p)) { set_err(err, cap, "mesh %u: vertex %u is not finite", k, v); return 1; }
            double l = std::sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
            if (!(std::fabs(l - 1.0) < 1e-3)) { set_err(err, cap, "mesh %u: normal %u is not unit length", k, v); return 1; }
            for (int c = 0; c < 3; ++c) { lo[c] = std::min(lo[c], (double)p[c]); hi[c] = std::max(hi[c], (double)p[c]); }
        }
        for (uint32_t t = 0; t < m.triangle_count; ++t) {
            for (int c = 0; c < 3; ++c)
                if (m.indices[3 * t + c] >= m.vertex_count) { set_err(err, cap, "mesh %u: triangle %u has an index out of range", k, t); return 1; }
            if (m.triangle_material[t] >= s->material_count) { set_err(err, cap, "mesh %u: triangle %u has material %u out of range", k, t, m.triangle_material[t]); return 1; }
        }
        tris += m.triangle_count;
    }
    if (tris > 0xffffffffu) { set_err(err, cap, "too many triangles"); return 1; }
    for (uint32_t i = 0; i < s->light_count; ++i) {
        scene_light &l = s->lights[i];
        float d[3] = {l.direction[0], l.direction[1], l.direction[2]};
        if (!finite3(l.color) || l.color[0] < 0 || l.color[1] < 0 || l.color[2] < 0 || !unit3(d)) {
            set_err(err, cap, "light %u: colour negative or direction zero / not finite", i);
            return 1;
        }
        std::memcpy(l.direction, d, sizeof d);
        if (l.type == SCENE_LIGHT_DIRECTIONAL) {
            if (!(l.irradiance >= 0 && std::isfinite(l.irradiance))) { set_err(err, cap, "light %u: irradiance must be finite and >= 0", i); return 1; }
        } else if (l.type == SCENE_LIGHT_SPOT) {
            if (!finite3(l.position) || !(l.intensity >= 0 && std::isfinite(l.intensity)) ||
                !(l.half_angle > 0 && l.half_angle <= (float)PI + 1e-6f)) {
                set_err(err, cap, "light %u: spot position, intensity or half-angle invalid", i);
                return 1;
            }
        } else {
            set_err(err, cap, "light %u: unknown type %d", i, (int)l.type);
            return 1;
        }
    }
    scene_camera &c = s->camera;
    float d[3] = {c.target[0] - c.eye[0], c.target[1] - c.eye[1], c.target[2] - c.eye[2]};
    if (!finite3(c.eye) || !finite3(c.target) || !unit3(d) || !(c.fovy > 0 && c.fovy < (float)PI)) {
        set_err(err, cap, "camera: eye, target or fovy invalid");
        return 1;
    }
    set3(c.up, 0, 1, 0);
    for (int k = 0; k < 3; ++k) { s->bounds_min[k] = (float)lo[k]; s->bounds_max[k] = (float)hi[k]; }
    double diag = std::sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));
    if (!(diag > 0) || !std::isfinite(diag)) { set_err(err, cap, "the scene's bounds are empty or not finite"); return 1; }
    s->scale = (float)diag;
    return 0;
}

void scene_free(scene *s) {
    if (!s) return;
    if (s->meshes)
        for (uint32_t i = 0; i < s->mesh_count; ++i) {
            std::free(s->meshes[i].positions);
            std::free(s->meshes[i].normals);
            std::free(s->meshes[i].indices);
            std::free(s->meshes[i].triangle_material);
        }
    std::free(s->meshes);
    std::free(s->materials);
    std::free(s->lights);
    std::memset(s, 0, sizeof *s);
}

/* Orthonormal camera basis: forward, right, up (up +Y; -Z when looking straight up or down). */
static void camera_basis(const scene_camera *c, vec3 &f, vec3 &r, vec3 &u) {
    f = normalize(vec3{(double)c->target[0] - c->eye[0], (double)c->target[1] - c->eye[1], (double)c->target[2] - c->eye[2]});
    vec3 up{0, 1, 0};
    if (std::fabs(f.y) > 0.9999) up = {0, 0, -1};
    r = normalize(cross(f, up));
    u = cross(r, f);
}

void scene_camera_ray(const scene_camera *c, float px, float py, float origin[3], float dir[3]) {
    vec3 f, r, u;
    camera_basis(c, f, r, u);
    double t = std::tan(0.5 * c->fovy), aspect = (double)c->width / (double)(c->height ? c->height : 1);
    double x = (2.0 * px / (double)c->width - 1.0) * t * aspect;
    double y = (1.0 - 2.0 * py / (double)c->height) * t;
    vec3 d = normalize(add(f, add(mul(r, x), mul(u, y))));
    set3(origin, c->eye[0], c->eye[1], c->eye[2]);
    set3(dir, d.x, d.y, d.z);
}

void scene_camera_matrices(const scene_camera *c, float zn, float zf, float view[16], float proj[16]) {
    vec3 f, r, u;
    camera_basis(c, f, r, u);
    vec3 e{c->eye[0], c->eye[1], c->eye[2]};
    double V[16] = {r.x, u.x, -f.x, 0, r.y, u.y, -f.y, 0, r.z, u.z, -f.z, 0, -dot(r, e), -dot(u, e), dot(f, e), 1};
    double t = std::tan(0.5 * c->fovy), aspect = (double)c->width / (double)(c->height ? c->height : 1);
    double P[16] = {0};
    P[0] = 1.0 / (t * aspect);
    P[5] = 1.0 / t;
    P[10] = -(double)(zf + zn) / (double)(zf - zn);
    P[11] = -1;
    P[14] = -2.0 * zf * zn / (double)(zf - zn);
    for (int i = 0; i < 16; ++i) { view[i] = (float)V[i]; proj[i] = (float)P[i]; }
}

int scene_make_dir(const char *dir, char *err, size_t cap) {
    if (!dir || !*dir) { set_err(err, cap, "no folder name"); return 1; }
    std::string p(dir);
    for (size_t i = 1; i <= p.size(); ++i) {
        if (i < p.size() && p[i] != '/') continue;
        std::string part = p.substr(0, i);
        if (mkdir(part.c_str(), 0777) != 0 && errno != EEXIST) {
            set_err(err, cap, "cannot create folder %s: %s", part.c_str(), std::strerror(errno));
            return 1;
        }
    }
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) { set_err(err, cap, "%s is not a folder", dir); return 1; }
    return 0;
}

int scene_write_pfm(const char *path, const float *rgb, uint32_t w, uint32_t h, char *err, size_t cap) {
    if (!path || !rgb || !w || !h) { set_err(err, cap, "pfm: nothing to write"); return 1; }
    FILE *f = std::fopen(path, "wb");
    if (!f) { set_err(err, cap, "cannot write %s: %s", path, std::strerror(errno)); return 1; }
    std::fprintf(f, "PF\n%u %u\n-1.0\n", w, h); /* negative scale: little-endian */
    std::vector<unsigned char> row((size_t)w * 12);
    bool ok = true;
    for (uint32_t y = h; y-- > 0 && ok;) { /* PFM rows run bottom to top */
        for (size_t i = 0; i < (size_t)w * 3; ++i) {
            uint32_t b;
            std::memcpy(&b, &rgb[((size_t)y * w) * 3 + i], 4);
            for (int k = 0; k < 4; ++k) row[i * 4 + k] = (unsigned char)(b >> (8 * k));
        }
        ok = std::fwrite(row.data(), 1, row.size(), f) == row.size();
    }
    if (std::fclose(f) != 0) ok = false;
    if (!ok) { set_err(err, cap, "write error on %s", path); return 1; }
    return 0;
}

int scene_read_pfm(const char *path, float **rgb, uint32_t *w, uint32_t *h, char *err, size_t cap) {
    if (!path || !rgb || !w || !h) { set_err(err, cap, "pfm: bad arguments"); return 1; }
    *rgb = nullptr;
    FILE *f = std::fopen(path, "rb");
    if (!f) { set_err(err, cap, "cannot open %s: %s", path, std::strerror(errno)); return 1; }
    char magic[3] = {0};
    unsigned ww = 0, hh = 0;
    double sc = 0;
    int c;
    bool ok = std::fread(magic, 1, 2, f) == 2 && magic[0] == 'P' && magic[1] == 'F' &&
              std::fscanf(f, "%u %u %lf", &ww, &hh, &sc) == 3 && ww > 0 && hh > 0 && ww <= 65536 && hh <= 65536 &&
              sc != 0 && std::isfinite(sc);
    if (ok) { c = std::fgetc(f); ok = c == '\n' || c == ' ' || c == '\r'; }
    std::vector<unsigned char> raw;
    if (ok) {
        raw.resize((size_t)ww * hh * 12);
        ok = std::fread(raw.data(), 1, raw.size(), f) == raw.size();
    }
    std::fclose(f);
    if (!ok) { set_err(err, cap, "%s is not an RGB PFM file (or is truncated)", path); return 1; }
    float *out = static_cast<float *>(std::malloc(raw.size()));
    if (!out) { set_err(err, cap, "out of memory"); return 1; }
    bool little = sc < 0;
    for (uint32_t y = 0; y < hh; ++y)
        for (size_t i = 0; i < (size_t)ww * 3; ++i) {
            const unsigned char *b = &raw[((size_t)(hh - 1 - y) * ww * 3 + i) * 4];
            uint32_t v = little ? (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24
                                : (uint32_t)b[3] | (uint32_t)b[2] << 8 | (uint32_t)b[1] << 16 | (uint32_t)b[0] << 24;
            std::memcpy(&out[(size_t)y * ww * 3 + i], &v, 4);
        }
    *rgb = out;
    *w = ww;
    *h = hh;
    return 0;
}

} /* extern "C" */
