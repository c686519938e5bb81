/* Ground truth (tools/reference) against closed forms, and the shared scene layer
   (scene/scene.*): glTF loading on real and hostile files, the command line, PFM files.

   The closed forms (each scene small enough that the image mean is tight in a second):
     lit plane   Lambertian plane of albedo rho under a sun of irradiance E at angle theta_s:
                 it leaves L = rho E cos(theta_s) / pi everywhere. A receiver facing it sees
                 irradiance E_ind = L * pi * F, F the point-to-polygon form factor (Lambert's
                 contour integral, exact for any polygon; -> 1 for an infinite plane), and
                 sends rho_r / pi * E_ind = rho_r rho E cos(theta_s) F / pi to the camera.
     disk        the same with a disk of radius R at distance h: F = R^2 / (R^2 + h^2).
     blocker     a black square between the two, its silhouette inside the reflector's:
                 F = F(reflector) - F(blocker).
     glossy      a normalised Phong receiver seen along its normal, facing a uniform plane:
                 L_out = rho_g L exactly (the lobe integrates cos^(k+1) to 2 pi / (k + 2)).
     corner      an infinite floor and wall, both sunlit: each sees the other as exactly half
                 of its hemisphere, so bounce 1 = rho_w/2 * L_floor, bounce 2 =
                 rho_w/2 * rho_f/2 * L_wall with L_wall = rho_w E s_x / pi.
   Each comparison allows 3 standard errors of the image mean (from the renderer's own
   per-pixel errors) plus a stated model tolerance for what the finite geometry leaves out. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
extern "C" {
#include <cmocka.h>
}

#include "reference.h"
#include "scene.h"
#include "street.h"

#include <stb_image_write.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/stat.h>
#include <vector>

#ifndef REF_BIN
#define REF_BIN "build/gimany-reference"
#endif

namespace {

const double PI = 3.14159265358979323846;

struct V {
    double x, y, z;
};
V operator+(V a, V b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V operator-(V a, V b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V operator*(V a, double s) { return {a.x * s, a.y * s, a.z * s}; }
double dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
V cross(V a, V b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
double len(V a) { return std::sqrt(dot(a, a)); }
V unit(V a) { return a * (1.0 / len(a)); }

/* ---- hand-built scenes --------------------------------------------------------------------- */
struct test_scene {
    struct mesh {
        std::vector<float> p, n;
        std::vector<uint32_t> i, m;
    };
    std::vector<mesh> meshes;
    std::vector<scene_mesh> sm;
    std::vector<scene_material> mats;
    std::vector<scene_light> lights;
    scene_camera cam;
    scene s;

    test_scene() { std::memset(&cam, 0, sizeof cam); }
    uint32_t material(double rd, double rg = 0, double k = 0) {
        scene_material m;
        std::memset(&m, 0, sizeof m);
        for (int c = 0; c < 3; ++c) { m.diffuse[c] = (float)rd; m.glossy[c] = (float)rg; }
        m.exponent = (float)k;
        mats.push_back(m);
        return (uint32_t)mats.size() - 1;
    }
    /* A convex polygon as a fan, one flat normal. */
    void polygon(const std::vector<V> &v, uint32_t mat) {
        mesh m;
        V n = unit(cross(v[1] - v[0], v[2] - v[0]));
        for (const V &p : v) {
            m.p.push_back((float)p.x); m.p.push_back((float)p.y); m.p.push_back((float)p.z);
            m.n.push_back((float)n.x); m.n.push_back((float)n.y); m.n.push_back((float)n.z);
        }
        for (uint32_t k = 1; k + 1 < v.size(); ++k) {
            m.i.push_back(0); m.i.push_back(k); m.i.push_back(k + 1);
            m.m.push_back(mat);
        }
        meshes.push_back(m);
    }
    /* square of half-size a centred at c with normal along +axis u x v */
    void square(V c, V u, V v, double a, uint32_t mat) {
        polygon({c - u * a - v * a, c + u * a - v * a, c + u * a + v * a, c - u * a + v * a}, mat);
    }
    void sun(V dir, double E) {
        scene_light l;
        std::memset(&l, 0, sizeof l);
        l.type = SCENE_LIGHT_DIRECTIONAL;
        V d = unit(dir);
        l.direction[0] = (float)d.x; l.direction[1] = (float)d.y; l.direction[2] = (float)d.z;
        l.irradiance = (float)E;
        l.color[0] = l.color[1] = l.color[2] = 1;
        lights.push_back(l);
    }
    void spot(V p, V dir, double half_deg, double I) {
        scene_light l;
        std::memset(&l, 0, sizeof l);
        l.type = SCENE_LIGHT_SPOT;
        V d = unit(dir);
        l.position[0] = (float)p.x; l.position[1] = (float)p.y; l.position[2] = (float)p.z;
        l.direction[0] = (float)d.x; l.direction[1] = (float)d.y; l.direction[2] = (float)d.z;
        l.half_angle = (float)(half_deg * PI / 180);
        l.intensity = (float)I;
        l.color[0] = l.color[1] = l.color[2] = 1;
        lights.push_back(l);
    }
    void camera(V eye, V target, double fovy_deg, uint32_t w, uint32_t h) {
        cam.eye[0] = (float)eye.x; cam.eye[1] = (float)eye.y; cam.eye[2] = (float)eye.z;
        cam.target[0] = (float)target.x; cam.target[1] = (float)target.y; cam.target[2] = (float)target.z;
        cam.fovy = (float)(fovy_deg * PI / 180);
        cam.width = w;
        cam.height = h;
    }
    const scene *get() {
        sm.clear();
        for (mesh &m : meshes) {
            scene_mesh x;
            x.positions = m.p.data();
            x.normals = m.n.data();
            x.vertex_count = (uint32_t)(m.p.size() / 3);
            x.indices = m.i.data();
            x.triangle_material = m.m.data();
            x.triangle_count = (uint32_t)(m.i.size() / 3);
            sm.push_back(x);
        }
        std::memset(&s, 0, sizeof s);
        s.meshes = sm.data();
        s.mesh_count = (uint32_t)sm.size();
        s.materials = mats.data();
        s.material_count = (uint32_t)mats.size();
        s.lights = lights.data();
        s.light_count = (uint32_t)lights.size();
        s.camera = cam;
        return &s;
    }
    /* every length times f, then moved by t */
    void transform(double f, V t) {
        for (mesh &m : meshes)
            for (size_t k = 0; k < m.p.size(); k += 3) {
                m.p[k] = (float)(m.p[k] * f + t.x); m.p[k + 1] = (float)(m.p[k + 1] * f + t.y); m.p[k + 2] = (float)(m.p[k + 2] * f + t.z);
            }
        for (scene_light &l : lights)
            if (l.type == SCENE_LIGHT_SPOT) {
                l.position[0] = (float)(l.position[0] * f + t.x); l.position[1] = (float)(l.position[1] * f + t.y);
                l.position[2] = (float)(l.position[2] * f + t.z);
            }
        for (int c = 0; c < 3; ++c) {
            double tc = c == 0 ? t.x : c == 1 ? t.y : t.z;
            cam.eye[c] = (float)(cam.eye[c] * f + tc);
            cam.target[c] = (float)(cam.target[c] * f + tc);
        }
    }
};

/* Lambert's formula: form factor from a point x with unit normal n to a planar polygon that
   lies entirely in front of it: F = 1/(2 pi) sum_i angle_i (n . unit(r_i x r_i+1)). */
double form_factor(V x, V n, const std::vector<V> &poly) {
    double s = 0;
    for (size_t i = 0; i < poly.size(); ++i) {
        V a = unit(poly[i] - x), b = unit(poly[(i + 1) % poly.size()] - x);
        V c = cross(a, b);
        double lc = len(c);
        if (lc == 0) continue;
        s += std::atan2(lc, dot(a, b)) * dot(n, c * (1.0 / lc));
    }
    return std::fabs(s) / (2 * PI);
}

std::vector<V> square_pts(V c, V u, V v, double a) {
    return {c - u * a - v * a, c + u * a - v * a, c + u * a + v * a, c - u * a + v * a};
}
std::vector<V> disk_pts(V c, double R, int n) {
    std::vector<V> p;
    for (int i = 0; i < n; ++i) p.push_back(c + V{R * std::cos(2 * PI * i / n), 0, R * std::sin(2 * PI * i / n)});
    return p;
}

ref_image render(const scene *s, uint32_t spp, int bounces, uint32_t seed = 1, unsigned threads = 0) {
    ref_settings st;
    std::memset(&st, 0, sizeof st);
    st.spp = spp;
    st.bounces = bounces;
    st.seed = seed;
    st.threads = threads;
    ref_image img;
    char err[256] = "";
    int r = ref_render(s, &st, &img, err, sizeof err);
    if (r) std::printf("ref_render: %s\n", err);
    assert_int_equal(r, 0);
    assert_int_equal(img.nonfinite_samples, 0);
    return img;
}

/* Mean over covered pixels of (radiance - expected) per channel-mean, with the standard error
   of that mean; expected(pixel position, normal) gives the closed form. */
struct cmp {
    double mean, expected, se;
};
template <class F> cmp compare(const ref_image &img, F expected) {
    cmp c{0, 0, 0};
    uint32_t n = 0;
    double se2 = 0;
    for (size_t i = 0; i < (size_t)img.width * img.height; ++i) {
        if (!img.covered[i]) continue;
        V p{img.position[3 * i], img.position[3 * i + 1], img.position[3 * i + 2]};
        double v = (img.radiance[3 * i] + img.radiance[3 * i + 1] + img.radiance[3 * i + 2]) / 3.0;
        double s = (img.std_error[3 * i] + img.std_error[3 * i + 1] + img.std_error[3 * i + 2]) / 3.0;
        c.mean += v;
        c.expected += expected(p);
        se2 += s * s;
        ++n;
    }
    assert_true(n > 0);
    c.mean /= n;
    c.expected /= n;
    c.se = std::sqrt(se2) / n;
    return c;
}
void check(const char *what, cmp c, double rel_tol) {
    double diff = std::fabs(c.mean - c.expected), allowed = 3 * c.se + rel_tol * std::fabs(c.expected);
    std::printf("  %-34s reference %.6g  closed form %.6g  diff %.2e  (3 SE %.2e + tol %.2e)\n", what, c.mean,
                c.expected, diff, 3 * c.se, rel_tol * std::fabs(c.expected));
    assert_true(diff <= allowed);
}

const V X{1, 0, 0}, Y{0, 1, 0}, Z{0, 0, 1};

/* (a) a receiver facing a uniformly lit, huge plane */
void plane_receiver(void **) {
    const double rho = 0.5, rho_r = 0.8, E = 2.0, S = 1000.0, theta = 60 * PI / 180;
    test_scene t;
    uint32_t plane = t.material(rho), recv = t.material(rho_r);
    t.square({0, 0, 0}, X, Z * -1.0, S, plane);
    t.square({0, 1, 0}, X, Z, 0.01, recv); /* 2 cm receiver 1 m up, seen from below */
    t.sun({std::sin(theta), std::cos(theta), 0}, E);
    t.camera({0, 0.5, 0}, {0, 1, 0}, 1.0, 8, 8);
    ref_image img = render(t.get(), 64, 1);
    assert_int_equal(img.covered_pixels, 64);
    double L = rho * E * std::cos(theta) / PI;
    auto plane_pts = square_pts({0, 0, 0}, X, Z, S);
    check("plane: rho_r rho E cos / pi", compare(img, [&](V p) { return rho_r * L * form_factor(p, Y * -1.0, plane_pts); }), 1e-3);
    /* the infinite-plane limit itself */
    check("plane: infinite limit", compare(img, [&](V) { return rho_r * rho * E * std::cos(theta) / PI; }), 2e-3);
    ref_image_free(&img);
}

/* (b) a finite disk at distance h on the axis */
void disk_form_factor(void **) {
    const double rho = 0.7, rho_r = 0.9, E = 1.5, R = 1.0, h = 1.0, theta = 60 * PI / 180;
    test_scene t;
    uint32_t refl = t.material(rho), recv = t.material(rho_r);
    auto disk = disk_pts({0, 0, 0}, R, 256);
    t.polygon(disk, refl);
    t.square({0, h, 0}, X, Z, 0.005, recv);
    t.sun({std::sin(theta), std::cos(theta), 0}, E); /* the receiver's shadow falls 1.7 m away, off the disk */
    t.camera({0, 0.5, 0}, {0, h, 0}, 0.5, 12, 12);
    ref_image img = render(t.get(), 480, 1);
    double L = rho * E * std::cos(theta) / PI;
    /* the 256-gon's form factor is within 1e-4 of the disk's R^2 / (R^2 + h^2) */
    assert_true(std::fabs(form_factor({0, h, 0}, Y * -1.0, disk) - R * R / (R * R + h * h)) < 2e-4);
    check("disk: L pi R^2/(R^2+h^2)", compare(img, [&](V p) { return rho_r / PI * L * PI * form_factor(p, Y * -1.0, disk); }), 1e-3);
    check("disk: formula", compare(img, [&](V) { return rho_r / PI * L * PI * R * R / (R * R + h * h); }), 2e-3);
    ref_image_free(&img);
}

/* (c) albedo 0 anywhere on the path, or a light that misses: exactly 0 */
void zero_albedo_gives_zero(void **) {
    for (int variant = 0; variant < 4; ++variant) {
        test_scene t;
        uint32_t refl = t.material(variant == 0 ? 0.0 : 0.7), recv = t.material(variant == 1 ? 0.0 : 0.9);
        t.polygon(disk_pts({0, 0, 0}, 1.0, 64), refl);
        t.square({0, 1, 0}, X, Z, 0.005, recv);
        if (variant == 2) t.spot({0, 3, 0}, {1, 0, 0}, 30, 10); /* points sideways: the disk is outside the cone */
        else t.sun({0.8, 0.6, 0}, variant == 3 ? 0.0 : 1.0);
        t.camera({0, 0.5, 0}, {0, 1, 0}, 0.5, 4, 4);
        for (int b = 1; b <= 2; ++b) {
            ref_image img = render(t.get(), 16, b);
            assert_int_equal(img.covered_pixels, 16);
            for (size_t i = 0; i < 16 * 3; ++i) {
                assert_true(img.radiance[i] == 0.0f);
                assert_true(img.std_error[i] == 0.0f);
            }
            ref_image_free(&img);
        }
    }
}

/* (d) a black square between reflector and receiver: exact visibility */
void blocker_reduces_exactly(void **) {
    const double rho = 0.6, rho_r = 1.0, E = 1.0, R = 1.0, h = 1.0, b = 0.2, theta = 75 * PI / 180;
    auto build = [&](test_scene &t, bool blocker) {
        uint32_t refl = t.material(rho), recv = t.material(rho_r), black = t.material(0.0);
        t.polygon(disk_pts({0, 0, 0}, R, 256), refl);
        t.square({0, h, 0}, X, Z, 0.004, recv);
        if (blocker) t.square({0, 0.5 * h, 0}, X, Z, b, black); /* its sun shadow lands 1.87 m away */
        t.sun({std::sin(theta), std::cos(theta), 0}, E);
        t.camera({0, 0.75 * h, 0}, {0, h, 0}, 0.5, 12, 12);
    };
    test_scene open, blocked;
    build(open, false);
    build(blocked, true);
    ref_image a = render(open.get(), 384, 1), c = render(blocked.get(), 384, 1);
    double L = rho * E * std::cos(theta) / PI;
    auto disk = disk_pts({0, 0, 0}, R, 256);
    auto blk = square_pts({0, 0.5 * h, 0}, X, Z, b);
    cmp co = compare(a, [&](V p) { return rho_r * L * form_factor(p, Y * -1.0, disk); });
    cmp cb = compare(c, [&](V p) { return rho_r * L * (form_factor(p, Y * -1.0, disk) - form_factor(p, Y * -1.0, blk)); });
    check("open disk", co, 1e-3);
    check("disk minus blocker", cb, 1e-3);
    assert_true(cb.mean < co.mean - 10 * (co.se + cb.se));
    ref_image_free(&a);
    ref_image_free(&c);
}

/* shadow rays: a black square above the receiver's horizon shades part of the reflector, so
   the lit part is the disk minus the square's shadow, a translated copy of it */
void shadow_on_reflector(void **) {
    const double rho = 0.6, rho_r = 1.0, E = 1.0, R = 1.0, h = 1.0, b = 0.2, theta = 60 * PI / 180;
    const double lift = 2.0, shift = lift * std::tan(theta); /* the square at y = 2 throws its shadow this far */
    test_scene t;
    uint32_t refl = t.material(rho), recv = t.material(rho_r), black = t.material(0.0);
    t.polygon(disk_pts({0, 0, 0}, R, 256), refl);
    t.square({0, h, 0}, X, Z, 0.004, recv);
    t.square({0.4 + shift, lift, 0}, X, Z, b, black);
    t.sun({std::sin(theta), std::cos(theta), 0}, E);
    t.camera({0, 0.75 * h, 0}, {0, h, 0}, 0.5, 12, 12);
    ref_image img = render(t.get(), 384, 1);
    double L = rho * E * std::cos(theta) / PI;
    auto disk = disk_pts({0, 0, 0}, R, 256);
    auto shadow = square_pts({0.4, 0, 0}, X, Z, b);
    cmp c = compare(img, [&](V p) { return rho_r * L * (form_factor(p, Y * -1.0, disk) - form_factor(p, Y * -1.0, shadow)); });
    check("disk minus the blocker's shadow", c, 1e-3);
    /* without shadow rays the answer would be the whole disk's: far outside the noise */
    double whole = rho_r * L * form_factor({0, h, 0}, Y * -1.0, disk);
    assert_true(whole - c.mean > 10 * c.se);
    ref_image_free(&img);
}

/* glossy receiver seen along its normal, facing a uniform plane: rho_g L (+ rho_d L) */
void glossy_receiver_normal_view(void **) {
    const double rho = 0.5, E = 1.0, theta = 60 * PI / 180, S = 1000.0;
    const double cases[][3] = {{0.0, 0.6, 20.0}, {0.3, 0.4, 200.0}, {0.0, 0.8, 0.0}};
    for (auto &cs : cases) {
        test_scene t;
        uint32_t plane = t.material(rho), recv = t.material(cs[0], cs[1], cs[2]);
        t.square({0, 0, 0}, X, Z, S, plane);
        t.square({0, 1, 0}, X, Z, 0.01, recv);
        t.sun({std::sin(theta), std::cos(theta), 0}, E);
        t.camera({0, 0.5, 0}, {0, 1, 0}, 1.0, 1, 1); /* the single pixel centre looks along the normal */
        ref_image img = render(t.get(), 4096, 1);
        double L = rho * E * std::cos(theta) / PI;
        char what[64];
        std::snprintf(what, sizeof what, "glossy k=%g: (rho_d + rho_g) L", cs[2]);
        check(what, compare(img, [&](V) { return (cs[0] + cs[1]) * L; }), 2e-3);
        ref_image_free(&img);
    }
}

/* a glossy plane under the sun lights a diffuse receiver above it: E_r = E cos rho_g (k+2)/(2pi) J,
   J = integral over the upper hemisphere of cos+^k(u . r) u_y (quadrature) */
void glossy_reflector(void **) {
    const double rho_g = 0.5, k = 10, rho_r = 0.8, E = 1.0, theta = 60 * PI / 180, S = 1000.0;
    test_scene t;
    uint32_t plane = t.material(0.0, rho_g, k), recv = t.material(rho_r);
    t.square({0, 0, 0}, X, Z, S, plane);
    t.square({0, 1, 0}, X, Z, 0.01, recv);
    V sun{std::sin(theta), std::cos(theta), 0};
    t.sun(sun, E);
    t.camera({0, 0.5, 0}, {0, 1, 0}, 1.0, 8, 8);
    ref_image img = render(t.get(), 256, 1);
    V r{-sun.x, sun.y, -sun.z}; /* mirror direction of the sun */
    const int NT = 1200, NP = 2400;
    double J = 0;
    for (int i = 0; i < NT; ++i) {
        double th = (i + 0.5) * (PI / 2) / NT;
        for (int j = 0; j < NP; ++j) {
            double ph = (j + 0.5) * 2 * PI / NP;
            V u{std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph)};
            double c = dot(u, r);
            if (c > 0) J += std::pow(c, k) * u.y * std::sin(th);
        }
    }
    J *= (PI / 2 / NT) * (2 * PI / NP);
    double Er = E * std::cos(theta) * rho_g * (k + 2) / (2 * PI) * J;
    check("glossy reflector (quadrature)", compare(img, [&](V) { return rho_r / PI * Er; }), 2e-3);
    ref_image_free(&img);
}

/* a spot lights a small diffuse patch, which lights a receiver beside it (2D quadrature over
   the patch of the exact point-to-point transport) */
void spot_patch(void **) {
    const double rho = 0.7, rho_r = 0.9, I = 5.0, a = 0.1;
    const V spot{0, 2, 0}, rp{0.3, 0.1, 0};
    const V rn = unit(V{0, 0, 0} - rp);
    test_scene t;
    uint32_t patch = t.material(rho), recv = t.material(rho_r);
    t.square({0, 0, 0}, X, Z * -1.0, a, patch);
    V u = unit(cross(rn, Z)), v = cross(u, rn);
    t.square(rp, u, v, 0.003, recv);
    t.spot(spot, {0, -1, 0}, 30, I);
    t.camera(rp + rn * 0.2, rp, 0.6, 4, 4);
    ref_image img = render(t.get(), 24000, 1);
    assert_int_equal(img.covered_pixels, 16);
    auto expected = [&](V x) {
        const int N = 300;
        double sum = 0, dA = (2 * a / N) * (2 * a / N);
        for (int i = 0; i < N; ++i)
            for (int j = 0; j < N; ++j) {
                V y{-a + (i + 0.5) * 2 * a / N, 0, -a + (j + 0.5) * 2 * a / N};
                V ls = spot - y;
                double dl = len(ls);
                double Ey = I * (ls.y / dl) / (dl * dl);
                V d = x - y;
                double dd = len(d);
                double ct_y = d.y / dd, ct_x = dot(rn, d * (-1.0 / dd));
                if (ct_y > 0 && ct_x > 0) sum += rho / PI * Ey * ct_y * ct_x / (dd * dd) * dA;
            }
        return rho_r / PI * sum;
    };
    check("spot -> patch -> receiver", compare(img, expected), 2e-3);
    ref_image_free(&img);
}

/* two bounces in a sunlit corner of a huge floor and wall */
void corner_two_bounces(void **) {
    const double rho_f = 0.6, rho_w = 0.5, E = 1.0, S = 3000.0;
    V sun = unit(V{1, 2, 0.5});
    test_scene t;
    uint32_t floor_m = t.material(rho_f), wall_m = t.material(rho_w);
    t.polygon({{0, 0, -S}, {S, 0, -S}, {S, 0, S}, {0, 0, S}}, floor_m);
    t.polygon({{0, 0, -S}, {0, 0, S}, {0, S, S}, {0, S, -S}}, wall_m);
    t.sun(sun, E);
    t.camera({0.5, 1, 0}, {0, 1, 0}, 0.5, 8, 8);
    ref_image b1 = render(t.get(), 1536, 1), b2 = render(t.get(), 1536, 2);
    std::vector<V> floor_pts{{0, 0, -S}, {S, 0, -S}, {S, 0, S}, {0, 0, S}};
    double Lf = rho_f * E * sun.y / PI, Lw = rho_w * E * sun.x / PI;
    check("corner bounce 1 (Lambert)", compare(b1, [&](V p) { return rho_w * Lf * form_factor(p, X, floor_pts); }), 1e-3);
    check("corner bounce 1 (half plane)", compare(b1, [&](V) { return rho_w * Lf / 2; }), 3e-3);
    /* bounce 2 alone: the difference of the two images (same seed, so the first segments
       match; its standard error is bounded by the sum) */
    cmp c1 = compare(b1, [](V) { return 0.0; }), c2 = compare(b2, [](V) { return 0.0; });
    cmp d{c2.mean - c1.mean, rho_w / 2 * rho_f / 2 * Lw, c1.se + c2.se};
    check("corner bounce 2 (infinite planes)", d, 1e-2);
    assert_true(c2.mean > c1.mean);
    ref_image_free(&b1);
    ref_image_free(&b2);
}

/* same seed -> same bits for any thread count; another seed -> other bits, same answer */
void deterministic(void **) {
    scene s;
    char err[256];
    assert_int_equal(scene_builtin("cornell", &s, err, sizeof err), 0);
    s.camera.width = 24;
    s.camera.height = 16;
    ref_image a = render(&s, 6, 2, 7, 1), b = render(&s, 6, 2, 7, 2), c = render(&s, 6, 2, 7, 3), d = render(&s, 6, 2, 8, 2);
    size_t n = 24 * 16 * 3 * sizeof(float);
    assert_memory_equal(a.radiance, b.radiance, n);
    assert_memory_equal(a.radiance, c.radiance, n);
    assert_memory_equal(a.std_error, c.std_error, n);
    assert_memory_not_equal(a.radiance, d.radiance, n);
    assert_true(a.mean_radiance > 0);
    assert_true(std::fabs(a.mean_radiance - d.mean_radiance) < 4 * a.mean_radiance * (a.relative_std_error_image + d.relative_std_error_image));
    ref_image_free(&a); ref_image_free(&b); ref_image_free(&c); ref_image_free(&d);
    scene_free(&s);
}

/* the disk scene in millimetres far from the origin, and in kilometres: the same radiance */
void unit_free(void **) {
    auto build = [](test_scene &t) {
        uint32_t refl = t.material(0.7), recv = t.material(0.9);
        t.polygon(disk_pts({0, 0, 0}, 1.0, 128), refl);
        t.square({0, 1, 0}, X, Z, 0.005, recv);
        t.sun({0.8, 0.6, 0}, 1.0);
        t.spot({-0.3, 2, 0.2}, {0.1, -1, 0}, 40, 3.0); /* intensity scales with length^2 */
        t.camera({0, 0.5, 0}, {0, 1, 0}, 0.5, 6, 6);
    };
    test_scene m, mm, km;
    build(m);
    build(mm);
    build(km);
    mm.transform(1000.0, {2.0e5, -3.0e5, 1.0e5});
    mm.lights[1].intensity *= 1.0e6f;
    km.transform(0.001, {0, 0, 0});
    km.lights[1].intensity *= 1.0e-6f;
    ref_image a = render(m.get(), 256, 2), b = render(mm.get(), 256, 2), c = render(km.get(), 256, 2);
    std::printf("  unit-free: m %.6g, mm far away %.6g, km %.6g\n", a.mean_radiance, b.mean_radiance, c.mean_radiance);
    /* the same random numbers drive the same paths: agreement far tighter than the noise */
    double se = a.mean_radiance * a.relative_std_error_image;
    assert_true(std::fabs(a.mean_radiance - b.mean_radiance) < 0.2 * se + 1e-4 * a.mean_radiance);
    assert_true(std::fabs(a.mean_radiance - c.mean_radiance) < 0.2 * se + 1e-4 * a.mean_radiance);
    ref_image_free(&a); ref_image_free(&b); ref_image_free(&c);
}

/* bad scenes and settings are errors, not crashes */
void renderer_rejects_bad_input(void **) {
    test_scene t;
    uint32_t m = t.material(0.5);
    t.square({0, 0, 0}, X, Z, 1, m);
    t.sun({0, 1, 0}, 1);
    t.camera({0, 1, 1}, {0, 0, 0}, 40, 4, 4);
    ref_settings st;
    std::memset(&st, 0, sizeof st);
    st.spp = 4;
    st.bounces = 1;
    ref_image img;
    char err[256];
    assert_int_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    ref_image_free(&img);
    st.bounces = 3;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    st.bounces = 1;
    st.spp = 0;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    st.spp = 4;
    t.meshes[0].p[4] = NAN;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    assert_non_null(std::strstr(err, "not finite"));
    t.meshes[0].p[4] = 0;
    t.meshes[0].i[2] = 99;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    t.meshes[0].i[2] = 2;
    t.mats[0].diffuse[1] = 1.5f;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    t.mats[0].diffuse[1] = 0.5f;
    t.cam.fovy = 0;
    assert_int_not_equal(ref_render(t.get(), &st, &img, err, sizeof err), 0);
    assert_int_not_equal(ref_render(nullptr, &st, &img, err, sizeof err), 0);
}

/* ---- command line ------------------------------------------------------------------------ */
int parse(std::vector<const char *> args, unsigned flags, scene_options *o, char *err) {
    std::vector<char *> argv;
    argv.push_back(const_cast<char *>("prog"));
    for (const char *a : args) argv.push_back(const_cast<char *>(a));
    scene_options_defaults(o, "out/x");
    return scene_parse_args((int)argv.size(), argv.data(), flags, o, err, 256);
}

void args_parse(void **) {
    scene_options o;
    char err[256];
    assert_int_equal(parse({}, 0, &o, err), SCENE_ARGS_OK);
    assert_string_equal(o.scene, "street");
    assert_int_equal(o.width, 640);
    assert_int_equal(o.height, 360);
    assert_int_equal(o.bounces, 1);
    assert_true(o.sun_irradiance == 1.0f);
    assert_int_equal(parse({"--scene", "cornell", "--sun-dir", "0,2,0", "--sun-irradiance=3.5", "--spot",
                            "1,2,3,0,-1,0,45,10", "--camera", "0,1,5,0,1,0,50", "--size", "320x200", "--out", "o",
                            "--bounces", "2", "--spp", "64", "--seed", "9"},
                           SCENE_ARGS_REFERENCE, &o, err),
                     SCENE_ARGS_OK);
    assert_string_equal(o.scene, "cornell");
    assert_true(o.has_sun_dir && o.sun_dir[1] == 1.0f && o.sun_dir[0] == 0.0f);
    assert_true(o.has_sun_irradiance && o.sun_irradiance == 3.5f);
    assert_true(o.has_spot && o.spot_position[2] == 3.0f && o.spot_direction[1] == -1.0f &&
                o.spot_half_angle_deg == 45.0f && o.spot_intensity == 10.0f);
    assert_true(o.has_camera && o.camera_eye[2] == 5.0f && o.camera_fovy_deg == 50.0f);
    assert_int_equal(o.width, 320);
    assert_int_equal(o.height, 200);
    assert_string_equal(o.out_dir, "o");
    assert_int_equal(o.bounces, 2);
    assert_int_equal(o.spp, 64);
    assert_int_equal(o.seed, 9);
    const std::vector<std::vector<const char *>> bad = {
        {"--bogus"}, {"cornell"}, {"--scene"}, {"--sun-dir", "1,2"}, {"--sun-dir", "0,0,0"}, {"--sun-dir", "1,2,3,4"},
        {"--sun-dir", "nan,1,0"}, {"--sun-irradiance", "-1"}, {"--sun-irradiance", "x"}, {"--spot", "1,2,3,0,-1,0,0,1"},
        {"--spot", "1,2,3,0,-1,0,190,1"}, {"--spot", "1,2,3,0,0,0,45,1"}, {"--spot", "1,2,3,0,-1,0,45,-2"},
        {"--camera", "0,0,0,0,0,0,40"}, {"--camera", "0,0,1,0,0,0,180"}, {"--size", "640"}, {"--size", "0x10"},
        {"--size", "10x-1"}, {"--size", "99999x10"}, {"--bounces", "3"}, {"--bounces", "1.5"}, {"--spp", "0"},
        {"--spp", "-4"}, {"--seed", "4294967296"}, {"--out", ""}, {"--size", "1e3x10"}, {"--sun-dir", "1,,2"}};
    for (auto &b : bad) {
        err[0] = 0;
        assert_int_equal(parse(b, SCENE_ARGS_REFERENCE, &o, err), SCENE_ARGS_ERROR);
        assert_true(std::strlen(err) > 10 && !std::strchr(err, '\n'));
    }
    /* --spp and --seed belong to the reference only */
    assert_int_equal(parse({"--spp", "4"}, 0, &o, err), SCENE_ARGS_ERROR);
    assert_int_equal(parse({"--seed", "4"}, 0, &o, err), SCENE_ARGS_ERROR);
}

/* the options shape the lights and the camera */
void options_apply(void **) {
    scene_options o;
    char err[256];
    scene s;
    assert_int_equal(parse({"--scene", "cornell"}, 0, &o, err), SCENE_ARGS_OK);
    assert_int_equal(scene_load(&o, &s, err, sizeof err), 0);
    assert_int_equal(s.light_count, 1);
    assert_int_equal(s.lights[0].type, SCENE_LIGHT_SPOT);
    assert_true(s.lights[0].direction[1] == -1.0f);
    assert_int_equal(s.camera.width, 640);
    assert_int_equal(s.camera.height, 360);
    assert_int_equal(s.meshes[0].triangle_count, 30);
    scene_free(&s);
    assert_int_equal(parse({"--scene", "cornell", "--sun-dir", "1,1,0", "--spot", "0.2,0.5,-0.2,0,-1,0,30,2",
                            "--camera", "0.2,0.3,1,0.2,0.3,0,30", "--size", "20x10"},
                           0, &o, err),
                     SCENE_ARGS_OK);
    assert_int_equal(scene_load(&o, &s, err, sizeof err), 0);
    assert_int_equal(s.light_count, 2);
    assert_int_equal(s.lights[0].type, SCENE_LIGHT_DIRECTIONAL);
    assert_true(std::fabs(s.lights[0].direction[0] - std::sqrt(0.5)) < 1e-6);
    assert_true(s.lights[0].irradiance == 1.0f);
    assert_int_equal(s.lights[1].type, SCENE_LIGHT_SPOT);
    assert_true(std::fabs(s.lights[1].half_angle - PI / 6) < 1e-6);
    assert_true(s.lights[1].intensity == 2.0f);
    assert_true(s.camera.eye[2] == 1.0f && std::fabs(s.camera.fovy - PI / 6) < 1e-6);
    assert_int_equal(s.camera.width, 20);
    /* the pixel-centre ray through the middle of an even image is the view axis, to rounding */
    float org[3], dir[3];
    scene_camera_ray(&s.camera, 10.0f, 5.0f, org, dir);
    assert_true(std::fabs(dir[2] + 1.0f) < 1e-6f);
    /* the top-left pixel centre: up and to the left */
    scene_camera_ray(&s.camera, 0.5f, 0.5f, org, dir);
    assert_true(dir[0] < 0 && dir[1] > 0);
    /* the matrices project that ray back to the pixel */
    float view[16], proj[16];
    scene_camera_matrices(&s.camera, 0.01f, 10.0f, view, proj);
    double p[4] = {org[0] + dir[0], org[1] + dir[1], org[2] + dir[2], 1}, e[4], c[4];
    for (int r = 0; r < 4; ++r) e[r] = view[r] * p[0] + view[4 + r] * p[1] + view[8 + r] * p[2] + view[12 + r];
    for (int r = 0; r < 4; ++r) c[r] = proj[r] * e[0] + proj[4 + r] * e[1] + proj[8 + r] * e[2] + proj[12 + r] * e[3];
    double px = (c[0] / c[3] * 0.5 + 0.5) * 20, py = (0.5 - c[1] / c[3] * 0.5) * 10;
    assert_true(std::fabs(px - 0.5) < 1e-3 && std::fabs(py - 0.5) < 1e-3);
    scene_free(&s);
    /* loaders alone give the options' default size */
    assert_int_equal(scene_builtin("cornell", &s, err, sizeof err), 0);
    assert_int_equal(s.camera.width, 640);
    assert_int_equal(s.camera.height, 360);
    scene_free(&s);
    assert_int_equal(parse({"--scene", "nosuch"}, 0, &o, err), SCENE_ARGS_OK);
    assert_int_not_equal(scene_load(&o, &s, err, sizeof err), 0);
    assert_non_null(std::strstr(err, "nosuch"));
    assert_int_equal(parse({"--scene", "missing/file.glb"}, 0, &o, err), SCENE_ARGS_OK);
    assert_int_not_equal(scene_load(&o, &s, err, sizeof err), 0);
    assert_non_null(std::strstr(err, "missing/file.glb"));
}

std::string run_cmd(const std::string &cmd, int *rc) {
    std::string out;
    FILE *p = popen((cmd + " 2>&1").c_str(), "r");
    if (!p) { *rc = -1; return out; }
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    int st = pclose(p);
    *rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return out;
}

/* the binary: one clear line and a non-zero exit for bad options; files that match the API */
void cli(void **) {
    int rc;
    const char *bad[] = {"--bogus", "--size 12", "--bounces 0", "--spot 1,2", "--scene cornell --camera 1,1,1,1,1,1,40",
                         "--scene /nonexistent/x.gltf"};
    for (const char *b : bad) {
        std::string out = run_cmd(std::string(REF_BIN) + " " + b, &rc);
        assert_int_not_equal(rc, 0);
        assert_true(out.size() > 20);
        assert_true(out.find('\n') == out.size() - 1); /* exactly one line */
        assert_true(out.compare(0, 17, "gimany-reference:") == 0);
    }
    std::string dir = "build/ref/cli_out";
    std::string out = run_cmd(std::string(REF_BIN) + " --scene cornell --size 10x6 --spp 4 --bounces 2 --seed 3 --out " + dir, &rc);
    assert_int_equal(rc, 0);
    float *rgb = nullptr;
    uint32_t w = 0, h = 0;
    char err[256];
    assert_int_equal(scene_read_pfm((dir + "/reference.pfm").c_str(), &rgb, &w, &h, err, sizeof err), 0);
    assert_int_equal(w, 10);
    assert_int_equal(h, 6);
    scene s;
    assert_int_equal(scene_builtin("cornell", &s, err, sizeof err), 0);
    s.camera.width = 10;
    s.camera.height = 6;
    ref_image img = render(&s, 4, 2, 3, 1);
    assert_memory_equal(rgb, img.radiance, 10 * 6 * 3 * sizeof(float)); /* same bits, rows in order */
    std::free(rgb);
    FILE *f = std::fopen((dir + "/reference.json").c_str(), "r");
    assert_non_null(f);
    char js[4096] = "";
    size_t n = std::fread(js, 1, sizeof js - 1, f);
    js[n] = 0;
    std::fclose(f);
    assert_non_null(std::strstr(js, "\"relative_std_error\""));
    assert_non_null(std::strstr(js, "\"spp\": 4"));
    ref_image_free(&img);
    scene_free(&s);
}

/* PFM: rows bottom first in the file, both endiannesses read back */
void pfm_files(void **) {
    const float img[2 * 2 * 3] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}; /* top row: 1..6 */
    char err[256];
    const char *path = "build/ref/t.pfm";
    assert_int_equal(scene_write_pfm(path, img, 2, 2, err, sizeof err), 0);
    FILE *f = std::fopen(path, "rb");
    assert_non_null(f);
    char head[16];
    assert_int_equal(std::fread(head, 1, 12, f), 12);
    assert_memory_equal(head, "PF\n2 2\n-1.0\n", 12);
    float first;
    assert_int_equal(std::fread(&first, 4, 1, f), 1);
    assert_true(first == 7.0f); /* the bottom row comes first */
    std::fclose(f);
    float *back;
    uint32_t w, h;
    assert_int_equal(scene_read_pfm(path, &back, &w, &h, err, sizeof err), 0);
    assert_memory_equal(back, img, sizeof img);
    std::free(back);
    /* big-endian file */
    f = std::fopen(path, "wb");
    std::fprintf(f, "PF\n1 1\n1.0\n");
    const unsigned char be[12] = {0x3f, 0x80, 0, 0, 0x40, 0, 0, 0, 0x40, 0x40, 0, 0};
    std::fwrite(be, 1, 12, f);
    std::fclose(f);
    assert_int_equal(scene_read_pfm(path, &back, &w, &h, err, sizeof err), 0);
    assert_true(back[0] == 1.0f && back[1] == 2.0f && back[2] == 3.0f);
    std::free(back);
    /* truncated */
    f = std::fopen(path, "wb");
    std::fprintf(f, "PF\n4 4\n-1.0\n");
    std::fwrite(be, 1, 12, f);
    std::fclose(f);
    assert_int_not_equal(scene_read_pfm(path, &back, &w, &h, err, sizeof err), 0);
}

/* ---- glTF ------------------------------------------------------------------------------- */
bool exists(const char *p) {
    struct stat st;
    return stat(p, &st) == 0;
}

void check_scene_sane(const scene &s) {
    for (uint32_t m = 0; m < s.mesh_count; ++m)
        for (uint32_t v = 0; v < s.meshes[m].vertex_count; ++v) {
            const float *n = s.meshes[m].normals + 3 * v;
            assert_true(std::fabs(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) - 1.0) < 1e-3);
        }
    assert_true(s.scale > 0 && std::isfinite(s.scale));
}

uint64_t triangles(const scene &s) {
    uint64_t t = 0;
    for (uint32_t m = 0; m < s.mesh_count; ++m) t += s.meshes[m].triangle_count;
    return t;
}

void shared_scenes(void **) {
    const char *cb = "../shared/scenes/cornell_box/CornellBox.gltf";
    const char *vb = "../shared/scenes/cornell_box_vinc3r/cornellBox-2.80-Eevee-gltf.gltf";
    const char *sp = "../shared/scenes/sponza_lod4/sponza_lod4.glb";
    if (!exists(cb) && !exists(vb) && !exists(sp)) skip();
    scene s;
    char err[256];
    if (exists(cb)) {
        assert_int_equal(scene_load_gltf(cb, &s, err, sizeof err), 0);
        assert_int_equal(triangles(s), 32);
        assert_int_equal(s.material_count, 4);
        /* the emissive ceiling quad becomes a spot just under it, pointing down */
        assert_int_equal(s.light_count, 1);
        assert_int_equal(s.lights[0].type, SCENE_LIGHT_SPOT);
        assert_true(s.lights[0].direction[1] < -0.99f);
        assert_true(s.lights[0].position[1] > 0.5f && s.lights[0].position[1] < s.bounds_max[1]);
        /* on-axis intensity of the 13 x 10.5 cm emitter: L_e A = 17 * 0.01365 */
        assert_true(std::fabs(s.lights[0].intensity - 17.0 * 0.13 * 0.105) < 0.01);
        assert_true(std::fabs(s.materials[1].diffuse[0] - 0.63f) < 1e-6f); /* red, rough: rho_d = base */
        assert_true(s.materials[1].glossy[0] == 0.0f);
        assert_true(std::fabs(s.camera.fovy - 0.6860478808414068) < 1e-6);
        assert_true(s.camera.target[2] > s.camera.eye[2]); /* the node's rotation turns -Z to +Z */
        check_scene_sane(s);
        scene_free(&s);
    }
    if (exists(vb)) {
        assert_int_equal(scene_load_gltf(vb, &s, err, sizeof err), 0);
        assert_int_equal(triangles(s), 4410);
        check_scene_sane(s);
        scene_free(&s);
    }
    if (exists(sp)) {
        assert_int_equal(scene_load_gltf(sp, &s, err, sizeof err), 0);
        assert_int_equal(triangles(s), 187364);
        /* no normals in the file: face normals, every triangle with its own vertices (both
           renderers then shade the same flat surface); no material: the default grey; no
           light: the sun */
        for (uint32_t m = 0; m < s.mesh_count; ++m) {
            const scene_mesh &sm = s.meshes[m];
            assert_int_equal(sm.vertex_count, 3 * sm.triangle_count);
            for (uint32_t t = 0; t < sm.triangle_count; t += 997) {
                const uint32_t *i = sm.indices + 3 * t;
                const float *p0 = sm.positions + 3 * i[0], *p1 = sm.positions + 3 * i[1], *p2 = sm.positions + 3 * i[2];
                double e1[3], e2[3], c[3], l;
                for (int k = 0; k < 3; ++k) { e1[k] = p1[k] - p0[k]; e2[k] = p2[k] - p0[k]; }
                c[0] = e1[1] * e2[2] - e1[2] * e2[1];
                c[1] = e1[2] * e2[0] - e1[0] * e2[2];
                c[2] = e1[0] * e2[1] - e1[1] * e2[0];
                l = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
                if (!(l > 0)) continue;
                for (int v = 0; v < 3; ++v) {
                    const float *n = sm.normals + 3 * i[v];
                    assert_true((n[0] * c[0] + n[1] * c[1] + n[2] * c[2]) / l > 0.999);
                }
            }
        }
        assert_true(s.materials[0].diffuse[0] == 0.8f);
        assert_int_equal(s.light_count, 1);
        assert_int_equal(s.lights[0].type, SCENE_LIGHT_DIRECTIONAL);
        assert_true(s.bounds_max[0] - s.bounds_min[0] > 20);
        check_scene_sane(s);
        scene_free(&s);
    }
}

/* broken files shipped by Debian's assimp-testmodels: one error line each, no crash */
void hostile_files(void **) {
    const std::string d = "/usr/share/assimp/models/glTF2/";
    if (!exists(d.c_str())) skip();
    const char *must_fail[] = {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
                               "IndexOutOfRange/IndexOutOfRange.gltf",
                               "IndexOutOfRange/AllIndicesOutOfRange.gltf",
                               "MissingBin/BoxTextured.gltf",
                               "RecursiveNodes/RecursiveNodes.gltf",
                               "wrongTypes/badArray.gltf",
                               "SchemaFailures/sceneWrongType.gltf",
                               "TestNoRootNode/NoScene.gltf",
                               "TestNoRootNode/SceneWithoutNodes.gltf",
                               "draco/2CylinderEngine.gltf",
                               "no/such/file.gltf"};
    for (const char *f : must_fail) {
        scene s;
        char err[512] = "";
        int r = scene_load_gltf((d + f).c_str(), &s, err, sizeof err);
        std::printf("  %-52s -> %s\n", f, r ? err : "loaded");
        assert_int_not_equal(r, 0);
        assert_true(std::strlen(err) > 10 && !std::strchr(err, '\n'));
        assert_null(s.meshes);
    }
    /* wrong types in fields the scene does not use (names, normal-texture scale), or index
       counts that are not a multiple of 3: either a clean load or one error line */
    const char *either[] = {"wrongTypes/badNumber.gltf", "wrongTypes/badObject.gltf", "wrongTypes/badString.gltf",
                            "wrongTypes/badUint.gltf", "wrongTypes/badExtension.gltf", "IncorrectVertexArrays/Cube.gltf"};
    scene s;
    char err[512];
    for (const char *f : either) {
        err[0] = 0;
        int r = scene_load_gltf((d + f).c_str(), &s, err, sizeof err);
        std::printf("  %-52s -> %s\n", f, r ? err : "loaded");
        if (r) assert_true(std::strlen(err) > 10 && !std::strchr(err, '\n'));
        else check_scene_sane(s);
        scene_free(&s);
    }
    /* bad normals are recomputed (a warning), the file loads */
    if (exists((d + "BoxBadNormals-glTF-Binary/BoxBadNormals.glb").c_str())) {
        assert_int_equal(scene_load_gltf((d + "BoxBadNormals-glTF-Binary/BoxBadNormals.glb").c_str(), &s, err, sizeof err), 0);
        check_scene_sane(s);
        scene_free(&s);
    }
}

/* the default scene: scene/street.h's street with its sun; a small render is finite and lit */
void street_scene(void **) {
    scene s;
    char err[256];
    assert_int_equal(scene_builtin("street", &s, err, sizeof err), 0);
    /* the same geometry and albedos as street.h builds with default parameters */
    street_params sp;
    std::memset(&sp, 0, sizeof sp);
    street_mesh sm;
    assert_int_equal(street_build(&sp, &sm), 0);
    assert_int_equal(s.mesh_count, 1);
    assert_int_equal(s.meshes[0].triangle_count, sm.triangle_count);
    assert_int_equal(s.meshes[0].vertex_count, sm.vertex_count);
    assert_memory_equal(s.meshes[0].positions, sm.positions, (size_t)sm.vertex_count * 3 * sizeof(float));
    assert_memory_equal(s.meshes[0].indices, sm.indices, (size_t)sm.triangle_count * 3 * sizeof(uint32_t));
    assert_int_equal(s.material_count, STREET_MATERIAL_COUNT);
    for (uint32_t m = 0; m < STREET_MATERIAL_COUNT; ++m) assert_true(s.materials[m].diffuse[1] == sm.albedo[m][1]);
    street_free(&sm);
    assert_true(triangles(s) >= 100000);
    assert_int_equal(s.light_count, 1);
    assert_int_equal(s.lights[0].type, SCENE_LIGHT_DIRECTIONAL);
    assert_true(s.lights[0].direction[1] > 0.5f);
    check_scene_sane(s);
    s.camera.width = 32;
    s.camera.height = 18;
    ref_image img = render(&s, 8, 2);
    assert_true(img.covered_pixels > 32 * 18 / 2);
    double red = 0, green = 0;
    for (size_t i = 0; i < 32 * 18 * 3; ++i) assert_true(std::isfinite(img.radiance[i]) && img.radiance[i] >= 0);
    for (size_t i = 0; i < 32 * 18; ++i) { red += img.radiance[3 * i]; green += img.radiance[3 * i + 1]; }
    assert_true(img.mean_radiance > 0 && red > 0 && green > 0);
    ref_image_free(&img);
    scene_free(&s);
}

/* ---- generated glTF ------------------------------------------------------------------------ */
std::string base64(const std::vector<unsigned char> &d) {
    static const char *t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string o;
    for (size_t i = 0; i < d.size(); i += 3) {
        uint32_t v = (uint32_t)d[i] << 16 | (i + 1 < d.size() ? (uint32_t)d[i + 1] << 8 : 0) | (i + 2 < d.size() ? d[i + 2] : 0);
        o += t[v >> 18 & 63];
        o += t[v >> 12 & 63];
        o += i + 1 < d.size() ? t[v >> 6 & 63] : '=';
        o += i + 2 < d.size() ? t[v & 63] : '=';
    }
    return o;
}
template <class T> void put(std::vector<unsigned char> &b, T v) {
    unsigned char c[sizeof(T)];
    std::memcpy(c, &v, sizeof v);
    b.insert(b.end(), c, c + sizeof v);
}

/* One glTF: a unit right triangle (positions), indices of the given component type, nodes:
   root translated (1,2,3) with a child scaled 2 and turned 90 deg about Y. */
struct gen {
    std::vector<float> pos{0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::vector<uint32_t> idx{0, 1, 2};
    int index_ct = 5125; /* UNSIGNED_INT */
    bool indexed = true;
    std::string pos_type = "VEC3";
    int pos_ct = 5126;
    std::string material = "{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.5,0.25,1,1],\"roughnessFactor\":0.5,\"metallicFactor\":0}}";
    std::string extra_images; /* ",\"images\":[...],\"textures\":[...]" */
    std::string nodes = "[{\"children\":[1],\"translation\":[1,2,3]},{\"mesh\":0,\"scale\":[2,2,2],\"rotation\":[0,0.7071067811865476,0,0.7071067811865476]}]";
    long buffer_len_delta = 0;

    std::string json(std::vector<unsigned char> *glb_bin = nullptr) const {
        std::vector<unsigned char> bin;
        for (float f : pos) put(bin, f);
        size_t ioff = bin.size();
        for (uint32_t i : idx) {
            if (index_ct == 5121) put(bin, (uint8_t)i);
            else if (index_ct == 5123) put(bin, (uint16_t)i);
            else put(bin, i);
        }
        while (bin.size() % 4) bin.push_back(0);
        char buf[4096];
        std::string uri = glb_bin ? "" : ",\"uri\":\"data:application/octet-stream;base64," + base64(bin) + "\"";
        std::snprintf(buf, sizeof buf,
                      "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":%s,"
                      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0}%s,\"material\":0}]}],"
                      "\"materials\":[%s]%s,"
                      "\"accessors\":[{\"bufferView\":0,\"componentType\":%d,\"count\":%zu,\"type\":\"%s\"},"
                      "{\"bufferView\":1,\"componentType\":%d,\"count\":%zu,\"type\":\"SCALAR\"}],"
                      "\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":%zu},{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}],"
                      "\"buffers\":[{\"byteLength\":%ld%s}]}",
                      nodes.c_str(), indexed ? ",\"indices\":1" : "", material.c_str(), extra_images.c_str(), pos_ct,
                      pos.size() / 3, pos_type.c_str(), index_ct, idx.size(), ioff, ioff, bin.size() - ioff,
                      (long)bin.size() + buffer_len_delta, uri.c_str());
        if (glb_bin) *glb_bin = bin;
        return buf;
    }
    std::vector<unsigned char> glb() const {
        std::vector<unsigned char> bin;
        std::string j = json(&bin);
        while (j.size() % 4) j += ' ';
        std::vector<unsigned char> out;
        put(out, (uint32_t)0x46546C67u);
        put(out, (uint32_t)2);
        put(out, (uint32_t)(12 + 8 + j.size() + 8 + bin.size()));
        put(out, (uint32_t)j.size());
        put(out, (uint32_t)0x4E4F534Au);
        out.insert(out.end(), j.begin(), j.end());
        put(out, (uint32_t)bin.size());
        put(out, (uint32_t)0x004E4942u);
        out.insert(out.end(), bin.begin(), bin.end());
        return out;
    }
};

int load_mem(const std::string &s, scene *out, char *err) { return scene_load_gltf_memory(s.data(), s.size(), nullptr, out, err, 512); }

void gltf_features(void **) {
    scene s;
    char err[512];
    gen g;
    assert_int_equal(load_mem(g.json(), &s, err), 0);
    assert_int_equal(triangles(s), 1);
    /* world = T(1,2,3) R_y(90) S(2): (1,0,0) -> (0,0,-2) + t; (0,1,0) -> (0,2,0) + t */
    const float *p = s.meshes[0].positions;
    const float want[9] = {1, 2, 3, 1, 2, 1, 1, 4, 3};
    for (int i = 0; i < 9; ++i) assert_true(std::fabs(p[i] - want[i]) < 1e-5f);
    /* computed normal: the triangle's own (+Z turned to +X) */
    assert_true(std::fabs(s.meshes[0].normals[0] - 1.0f) < 1e-5f);
    /* material: rough 0.5 -> alpha 0.25 -> k = 2/0.0625 - 2 = 30, F0 0.04 */
    assert_true(std::fabs(s.materials[0].exponent - 30.0f) < 1e-3f);
    assert_true(std::fabs(s.materials[0].glossy[0] - 0.04f) < 1e-6f);
    assert_true(std::fabs(s.materials[0].diffuse[1] - 0.25f * (1.0f - 0.04f)) < 1e-6f);   /* the rest after F0 */
    /* a default sun and a camera framing the bounds */
    assert_int_equal(s.light_count, 1);
    scene_free(&s);

    /* the same geometry with 8-, 16-bit indices, non-indexed, as .glb and with a matrix node */
    std::vector<float> ref;
    {
        gen a;
        assert_int_equal(load_mem(a.json(), &s, err), 0);
        ref.assign(s.meshes[0].positions, s.meshes[0].positions + 9);
        scene_free(&s);
    }
    for (int variant = 0; variant < 5; ++variant) {
        gen a;
        if (variant == 0) a.index_ct = 5121;
        if (variant == 1) a.index_ct = 5123;
        if (variant == 2) a.indexed = false;
        if (variant == 4)
            a.nodes = "[{\"children\":[1],\"matrix\":[1,0,0,0,0,1,0,0,0,0,1,0,1,2,3,1]},{\"mesh\":0,\"matrix\":[0,0,-2,0,0,2,0,0,2,0,0,0,0,0,0,1]}]";
        int r;
        if (variant == 3) {
            std::vector<unsigned char> b = a.glb();
            r = scene_load_gltf_memory(b.data(), b.size(), nullptr, &s, err, sizeof err);
        } else
            r = load_mem(a.json(), &s, err);
        if (r) std::printf("variant %d: %s\n", variant, err);
        assert_int_equal(r, 0);
        for (int i = 0; i < 9; ++i) assert_true(std::fabs(s.meshes[0].positions[i] - ref[i]) < 1e-5f);
        scene_free(&s);
    }
    /* no normals: face normals, not averaged, though a triangle in z=0 and one in x=0 share
       vertex 0: each triangle gets its own vertices */
    {
        gen a;
        a.nodes = "[{\"mesh\":0}]";
        a.pos = {0, 0, 0, 4, 0, 0, 0, 4, 0, 0, 1, 0, 0, 0, 1};
        a.idx = {0, 1, 2, 0, 3, 4};
        assert_int_equal(load_mem(a.json(), &s, err), 0);
        assert_int_equal(s.meshes[0].vertex_count, 6);
        for (int v = 0; v < 6; ++v) {
            const float *n = s.meshes[0].normals + 3 * s.meshes[0].indices[v];
            const float want_n[2][3] = {{0, 0, 1}, {1, 0, 0}};
            for (int k = 0; k < 3; ++k) assert_true(std::fabs(n[k] - want_n[v / 3][k]) < 1e-6f);
        }
        assert_true(s.meshes[0].positions[3 * s.meshes[0].indices[3] + 0] == 0.0f &&
                    s.meshes[0].positions[3 * s.meshes[0].indices[4] + 1] == 1.0f);
        scene_free(&s);
    }
    /* metal and KHR_materials_specular */
    {
        gen a;
        a.material = "{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.9,0.6,0.3,1],\"roughnessFactor\":0.3,\"metallicFactor\":1}}";
        assert_int_equal(load_mem(a.json(), &s, err), 0);
        assert_true(s.materials[0].diffuse[0] == 0.0f && std::fabs(s.materials[0].glossy[1] - 0.6f) < 1e-6f);
        double alpha = 0.09;
        assert_true(std::fabs(s.materials[0].exponent - (2 / (alpha * alpha) - 2)) < 0.05);
        scene_free(&s);
        a.material = "{\"pbrMetallicRoughness\":{\"roughnessFactor\":0.2,\"metallicFactor\":0},\"extensions\":{\"KHR_materials_specular\":{\"specularFactor\":0.5,\"specularColorFactor\":[1,0.5,0]}}}";
        assert_int_equal(load_mem(a.json(), &s, err), 0);
        assert_true(std::fabs(s.materials[0].glossy[0] - 0.02f) < 1e-6f && std::fabs(s.materials[0].glossy[1] - 0.01f) < 1e-6f &&
                    s.materials[0].glossy[2] == 0.0f);
        /* white base: the diffuse layer gets what the specular one leaves, the sum stays 1 */
        assert_true(std::fabs(s.materials[0].diffuse[0] - 0.98f) < 1e-6f && std::fabs(s.materials[0].diffuse[1] - 0.99f) < 1e-6f &&
                    s.materials[0].diffuse[2] == 1.0f);
        scene_free(&s);
    }
    /* baseColorTexture: factor times the average of the sRGB-decoded texels */
    {
        const unsigned char px[2 * 4] = {255, 0, 188, 255, 0, 0, 188, 255};
        std::vector<unsigned char> pv;
        assert_true(stbi_write_png_to_func(
            [](void *ctx, void *data, int size) {
                std::vector<unsigned char> *v = static_cast<std::vector<unsigned char> *>(ctx);
                v->insert(v->end(), static_cast<unsigned char *>(data), static_cast<unsigned char *>(data) + size);
            },
            &pv, 2, 1, 4, px, 8) != 0);
        gen a;
        a.material = "{\"pbrMetallicRoughness\":{\"baseColorFactor\":[0.8,1,1,1],\"baseColorTexture\":{\"index\":0}}}";
        a.extra_images = ",\"images\":[{\"uri\":\"data:image/png;base64," + base64(pv) + "\"}],\"textures\":[{\"source\":0}]";
        assert_int_equal(load_mem(a.json(), &s, err), 0);
        double lin188 = std::pow((188 / 255.0 + 0.055) / 1.055, 2.4);
        assert_true(std::fabs(s.materials[0].diffuse[0] - 0.8 * 0.5) < 1e-5);
        assert_true(s.materials[0].diffuse[1] == 0.0f);
        assert_true(std::fabs(s.materials[0].diffuse[2] - lin188) < 1e-5);
        scene_free(&s);
    }
    /* KHR_lights_punctual: a spot on a node, intensity in candela, the cone's outer angle */
    {
        gen a;
        a.nodes = "[{\"mesh\":0},{\"translation\":[0,3,0],\"rotation\":[-0.7071067811865476,0,0,0.7071067811865476],"
                  "\"extensions\":{\"KHR_lights_punctual\":{\"light\":0}}}]";
        std::string j = a.json();
        j.insert(j.size() - 1, ",\"extensionsUsed\":[\"KHR_lights_punctual\"],\"extensions\":{\"KHR_lights_punctual\":{\"lights\":"
                               "[{\"type\":\"spot\",\"intensity\":40,\"color\":[1,0.5,0.25],\"spot\":{\"outerConeAngle\":0.5}}]}}");
        j.replace(j.find("\"scenes\":[{\"nodes\":[0]}]"), 24, "\"scenes\":[{\"nodes\":[0,1]}]");
        int r = load_mem(j, &s, err);
        if (r) std::printf("lights: %s\n", err);
        assert_int_equal(r, 0);
        assert_int_equal(s.light_count, 1);
        assert_int_equal(s.lights[0].type, SCENE_LIGHT_SPOT);
        assert_true(std::fabs(s.lights[0].direction[1] + 1) < 1e-5 && std::fabs(s.lights[0].position[1] - 3) < 1e-5);
        assert_true(s.lights[0].intensity == 40.0f && s.lights[0].half_angle == 0.5f && s.lights[0].color[1] == 0.5f);
        scene_free(&s);
    }
}

void gltf_hostile_generated(void **) {
    scene s;
    char err[512];
    struct bad {
        const char *what;
        gen g;
    };
    std::vector<bad> cases;
    { bad b{"POSITION as VEC2", gen()}; b.g.pos_type = "VEC2"; cases.push_back(b); }
    { bad b{"POSITION as SHORT", gen()}; b.g.pos_ct = 5122; cases.push_back(b); }
    { bad b{"index out of range", gen()}; b.g.idx = {0, 1, 3}; cases.push_back(b); }
    { bad b{"NaN position", gen()}; b.g.pos[4] = NAN; cases.push_back(b); }
    { bad b{"Inf position", gen()}; b.g.pos[0] = INFINITY; cases.push_back(b); }
    { bad b{"huge scale overflows", gen()}; b.g.nodes = "[{\"mesh\":0,\"scale\":[1e38,1e38,1e38]}]"; b.g.pos[3] = 1e10f; cases.push_back(b); }
    { bad b{"buffer shorter than its views", gen()}; b.g.buffer_len_delta = -8; cases.push_back(b); }
    { bad b{"node cycle", gen()}; b.g.nodes = "[{\"children\":[1]},{\"mesh\":0,\"children\":[0]}]"; cases.push_back(b); }
    { bad b{"missing mesh", gen()}; b.g.nodes = "[{\"mesh\":7}]"; cases.push_back(b); }
    { bad b{"float indices", gen()}; b.g.index_ct = 5126; cases.push_back(b); }
    for (bad &b : cases) {
        err[0] = 0;
        int r = load_mem(b.g.json(), &s, err);
        std::printf("  %-30s -> %s\n", b.what, r ? err : "loaded");
        assert_int_not_equal(r, 0);
        assert_true(std::strlen(err) > 10 && !std::strchr(err, '\n'));
        assert_null(s.meshes);
    }
    /* every truncation of a valid .gltf and .glb fails cleanly (ASan watches the reads) */
    gen g;
    std::string j = g.json();
    for (size_t n = 0; n < j.size(); n += 7) assert_int_not_equal(scene_load_gltf_memory(j.data(), n, nullptr, &s, err, sizeof err), 0);
    std::vector<unsigned char> b = g.glb();
    for (size_t n = 0; n < b.size(); ++n) {
        std::vector<unsigned char> cut(b.begin(), b.begin() + n); /* exact-size heap copy */
        assert_int_not_equal(scene_load_gltf_memory(cut.empty() ? nullptr : cut.data(), n, nullptr, &s, err, sizeof err), 0);
    }
    assert_int_equal(scene_load_gltf_memory(b.data(), b.size(), nullptr, &s, err, sizeof err), 0);
    scene_free(&s);
    /* a glb whose chunk lengths lie */
    std::vector<unsigned char> lie = b;
    uint32_t big = 0x7ffffff0u;
    std::memcpy(&lie[12], &big, 4);
    assert_int_not_equal(scene_load_gltf_memory(lie.data(), lie.size(), nullptr, &s, err, sizeof err), 0);
    lie = b;
    std::memcpy(&lie[8], &big, 4);
    assert_int_not_equal(scene_load_gltf_memory(lie.data(), lie.size(), nullptr, &s, err, sizeof err), 0);
}

} /* namespace */

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(plane_receiver),
        cmocka_unit_test(disk_form_factor),
        cmocka_unit_test(zero_albedo_gives_zero),
        cmocka_unit_test(blocker_reduces_exactly),
        cmocka_unit_test(shadow_on_reflector),
        cmocka_unit_test(glossy_receiver_normal_view),
        cmocka_unit_test(glossy_reflector),
        cmocka_unit_test(spot_patch),
        cmocka_unit_test(corner_two_bounces),
        cmocka_unit_test(deterministic),
        cmocka_unit_test(street_scene),
        cmocka_unit_test(unit_free),
        cmocka_unit_test(renderer_rejects_bad_input),
        cmocka_unit_test(args_parse),
        cmocka_unit_test(options_apply),
        cmocka_unit_test(cli),
        cmocka_unit_test(pfm_files),
        cmocka_unit_test(shared_scenes),
        cmocka_unit_test(hostile_files),
        cmocka_unit_test(gltf_features),
        cmocka_unit_test(gltf_hostile_generated),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
