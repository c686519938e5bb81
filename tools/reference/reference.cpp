/* reference.cpp - see reference.h. */
#include "reference.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace {

const double PI = 3.14159265358979323846;

void set_err(char *err, size_t cap, const char *fmt, ...) {
    if (!err || cap == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(err, cap, fmt, ap);
    va_end(ap);
}

struct v3 {
    double x, y, z;
};
inline v3 operator+(v3 a, v3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline v3 operator-(v3 a, v3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline v3 operator*(v3 a, double s) { return {a.x * s, a.y * s, a.z * s}; }
inline v3 operator-(v3 a) { return {-a.x, -a.y, -a.z}; }
inline double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline v3 cross(v3 a, v3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
inline double length(v3 a) { return std::sqrt(dot(a, a)); }
inline v3 normalize(v3 a) {
    double l = length(a);
    return l > 0 ? a * (1.0 / l) : v3{0, 0, 0};
}
inline v3 load(const float *p) { return {p[0], p[1], p[2]}; }

/* PCG32 (O'Neill): one stream per pixel. */
struct rng {
    uint64_t state, inc;
    uint32_t next() {
        uint64_t old = state;
        state = old * 6364136223846793005ull + inc;
        uint32_t xs = (uint32_t)(((old >> 18u) ^ old) >> 27u);
        uint32_t rot = (uint32_t)(old >> 59u);
        return (xs >> rot) | (xs << ((32u - rot) & 31u));
    }
    double uniform() { /* [0,1) with 53 bits */
        uint64_t a = next(), b = next();
        return (double)((a << 21) ^ b) * (1.0 / 9007199254740992.0) ; 
    }
};
uint64_t splitmix(uint64_t z) {
    z += 0x9e3779b97f4a7c15ull;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
rng pixel_rng(uint32_t seed, uint64_t pixel) {
    rng r;
    r.state = 0;
    r.inc = (splitmix(pixel) << 1u) | 1u;
    r.next();
    r.state += splitmix(((uint64_t)seed << 32) ^ (pixel * 0x2545f4914f6cdd1dull) ^ 0x5851f42d4c957f2dull);
    r.next();
    return r;
}

/* Orthonormal basis around n (Duff et al. 2017). */
void basis(v3 n, v3 &t, v3 &b) {
    double s = n.z >= 0 ? 1.0 : -1.0;
    double a = -1.0 / (s + n.z);
    double bb = n.x * n.y * a;
    t = {1.0 + s * n.x * n.x * a, s * bb, -s * n.x};
    b = {bb, s + n.y * n.y * a, -n.y};
}

struct material {
    double rd[3], rg[3], k;
    double wd, wg; /* lobe selection weights (mean albedos) */
};

/* A surface point as the path sees it. */
struct surface {
    v3 p;          /* position */
    v3 ng;         /* geometric normal, facing the side the ray came from */
    v3 n;          /* shading normal, on the same side as ng */
    const material *m;
    unsigned geom, prim; /* the triangle, which a ray leaving it must not hit again */
};

/* A ray leaving a (flat) triangle cannot hit it again: hits on it are rounding, and the filter
   drops them, so the origin offset only has to clear the neighbouring triangles. */
struct self_context {
    RTCIntersectContext ctx; /* first member: Embree hands this pointer back */
    unsigned geom, prim;
};
void skip_self(const RTCFilterFunctionNArguments *args) {
    const self_context *c = reinterpret_cast<const self_context *>(args->context);
    for (unsigned i = 0; i < args->N; ++i)
        if (args->valid[i] && RTCHitN_geomID(args->hit, args->N, i) == c->geom &&
            RTCHitN_primID(args->hit, args->N, i) == c->prim)
            args->valid[i] = 0;
}
void init_context(self_context &c, const struct surface *from) {
    rtcInitIntersectContext(&c.ctx);
    c.geom = from ? from->geom : RTC_INVALID_GEOMETRY_ID;
    c.prim = from ? from->prim : RTC_INVALID_GEOMETRY_ID;
    if (from) c.ctx.filter = skip_self;
}

struct tracer {
    const scene *s;
    RTCScene rs;
    std::vector<material> mats;
    double scale;
    int bounces;

    /* Offset along the facing geometric normal: relative to the point's magnitude (float
       precision) and to the scene scale, so the same scene at any unit or origin behaves the same. */
    v3 offset(const surface &x, v3 dir) const {
        double m = std::max(std::fabs(x.p.x), std::max(std::fabs(x.p.y), std::fabs(x.p.z)));
        double d = 1.0 / 1048576.0 * m + 1e-6 * scale; /* 2^-20 |p|: a few float ulps */
        return x.p + x.ng * (dot(dir, x.ng) >= 0 ? d : -d);
    }

    bool intersect(v3 o, v3 d, const surface *from, surface &out, uint64_t &rays) const {
        self_context ctx;
        init_context(ctx, from);
        RTCRayHit rh;
        rh.ray.org_x = (float)o.x; rh.ray.org_y = (float)o.y; rh.ray.org_z = (float)o.z;
        rh.ray.dir_x = (float)d.x; rh.ray.dir_y = (float)d.y; rh.ray.dir_z = (float)d.z;
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = INFINITY;
        rh.ray.time = 0.0f;
        rh.ray.mask = 0xffffffffu;
        rh.ray.id = 0;
        rh.ray.flags = 0;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(rs, &ctx.ctx, &rh);
        ++rays;
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
        const scene_mesh &m = s->meshes[rh.hit.geomID];
        const uint32_t *tri = m.indices + 3 * (size_t)rh.hit.primID;
        v3 a = load(m.positions + 3 * (size_t)tri[0]), b = load(m.positions + 3 * (size_t)tri[1]),
           c = load(m.positions + 3 * (size_t)tri[2]);
        double u = rh.hit.u, v = rh.hit.v, w = 1.0 - u - v;
        out.p = a * w + b * u + c * v; /* from barycentrics: closer to the surface than o + t d */
        v3 ng = normalize(cross(b - a, c - a));
        if (length(ng) == 0) ng = normalize(v3{rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z});
        if (dot(ng, d) > 0) ng = -ng;
        v3 n = normalize(load(m.normals + 3 * (size_t)tri[0]) * w + load(m.normals + 3 * (size_t)tri[1]) * u +
                         load(m.normals + 3 * (size_t)tri[2]) * v);
        if (length(n) == 0) n = ng;
        if (dot(n, ng) < 0) n = -n; /* two-sided: the shading normal follows the seen side */
        out.ng = ng;
        out.n = n;
        out.m = &mats[m.triangle_material[rh.hit.primID]];
        out.geom = rh.hit.geomID;
        out.prim = rh.hit.primID;
        return true;
    }

    bool occluded(v3 o, v3 d, double tfar, const surface *from, uint64_t &rays) const {
        self_context ctx;
        init_context(ctx, from);
        RTCRay r;
        r.org_x = (float)o.x; r.org_y = (float)o.y; r.org_z = (float)o.z;
        r.dir_x = (float)d.x; r.dir_y = (float)d.y; r.dir_z = (float)d.z;
        r.tnear = 0.0f;
        r.tfar = (float)tfar;
        r.time = 0.0f;
        r.mask = 0xffffffffu;
        r.id = 0;
        r.flags = 0;
        rtcOccluded1(rs, &ctx.ctx, &r);
        ++rays;
        return r.tfar < 0.0f; /* Embree sets tfar = -inf on a hit */
    }

    /* f_r(wi, wo) * 1 per channel; wi, wo unit, away from the surface (Bischoff 2017 eq. 3-4). */
    static void brdf(const surface &x, v3 wi, v3 wo, double f[3]) {
        const material &m = *x.m;
        double ce = 0;
        if (m.wg > 0) {
            v3 r = x.n * (2.0 * dot(x.n, wi)) - wi; /* mirror direction of wi */
            double c = dot(r, wo);
            ce = c > 0 ? (m.k + 2.0) / (2.0 * PI) * std::pow(std::min(c, 1.0), m.k) : 0.0;
        }
        for (int i = 0; i < 3; ++i) f[i] = m.rd[i] / PI + m.rg[i] * ce;
    }

    /* Mixture pdf of sampling wi given wo (solid angle). */
    static double pdf(const surface &x, v3 wi, v3 wo) {
        const material &m = *x.m;
        double tot = m.wd + m.wg;
        double p = 0;
        double cn = dot(x.n, wi);
        if (m.wd > 0 && cn > 0) p += m.wd / tot * cn / PI;
        if (m.wg > 0) {
            v3 r = x.n * (2.0 * dot(x.n, wo)) - wo;
            double c = dot(r, wi);
            if (c > 0) p += m.wg / tot * (m.k + 1.0) / (2.0 * PI) * std::pow(std::min(c, 1.0), m.k);
        }
        return p;
    }

    /* Samples wi; returns false when the path ends (black material, below the surface). */
    static bool sample(const surface &x, v3 wo, rng &g, v3 &wi, double weight[3]) {
        const material &m = *x.m;
        double tot = m.wd + m.wg;
        if (!(tot > 0)) return false;
        double u0 = g.uniform(), u1 = g.uniform(), u2 = g.uniform();
        v3 axis;
        double cos_a;
        if (u0 * tot < m.wd) { /* cosine lobe */
            axis = x.n;
            cos_a = std::sqrt(1.0 - u1);
        } else {             /* Phong lobe around the mirror direction of wo */
            axis = x.n * (2.0 * dot(x.n, wo)) - wo;
            cos_a = std::pow(1.0 - u1, 1.0 / (m.k + 1.0));
        }
        double sin_a = std::sqrt(std::max(0.0, 1.0 - cos_a * cos_a)), phi = 2.0 * PI * u2;
        v3 t, b;
        basis(axis, t, b);
        wi = normalize(t * (sin_a * std::cos(phi)) + b * (sin_a * std::sin(phi)) + axis * cos_a);
        double cn = dot(x.n, wi);
        if (cn <= 0 || dot(x.ng, wi) <= 0) return false;
        double p = pdf(x, wi, wo);
        if (!(p > 0)) return false;
        double f[3];
        brdf(x, wi, wo, f);
        for (int i = 0; i < 3; ++i) weight[i] = f[i] * cn / p;
        return true;
    }

    /* Light reflected at x towards wo straight from the lights (next-event estimation). */
    void direct(const surface &x, v3 wo, double out[3], uint64_t &rays) const {
        out[0] = out[1] = out[2] = 0;
        if (!(x.m->wd + x.m->wg > 0)) return;
        for (uint32_t i = 0; i < s->light_count; ++i) {
            const scene_light &l = s->lights[i];
            v3 wl;
            double e, tfar;
            if (l.type == SCENE_LIGHT_DIRECTIONAL) {
                wl = load(l.direction);
                e = l.irradiance;
                tfar = INFINITY;
            } else {
                v3 d = load(l.position) - x.p;
                double dist = length(d);
                if (!(dist > 0)) continue;
                wl = d * (1.0 / dist);
                if (dot(-wl, load(l.direction)) < std::cos((double)l.half_angle)) continue; /* outside the cone */
                e = l.intensity / (dist * dist);
                tfar = dist;
            }
            double cn = dot(x.n, wl);
            if (cn <= 0 || dot(x.ng, wl) <= 0 || !(e > 0)) continue;
            v3 o = offset(x, wl);
            if (std::isfinite(tfar)) tfar = length(load(l.position) - o) * (1.0 - 1e-7);
            if (occluded(o, wl, tfar, &x, rays)) continue;
            double f[3];
            brdf(x, wl, wo, f);
            for (int c = 0; c < 3; ++c) out[c] += f[c] * e * l.color[c] * cn;
        }
    }

    /* One path from x0 (seen along wo0): indirect radiance, bounce 1 (+ bounce 2). */
    void path(const surface &x0, v3 wo0, rng &g, double L[3], uint64_t &rays) const {
        L[0] = L[1] = L[2] = 0;
        double T[3];
        v3 wi;
        if (!sample(x0, wo0, g, wi, T)) return;
        surface x1;
        if (!intersect(offset(x0, wi), wi, &x0, x1, rays)) return;
        double d1[3];
        direct(x1, -wi, d1, rays);
        for (int c = 0; c < 3; ++c) L[c] += T[c] * d1[c];
        if (bounces < 2) return;
        double T2[3];
        v3 wi2;
        if (!sample(x1, -wi, g, wi2, T2)) return;
        surface x2;
        if (!intersect(offset(x1, wi2), wi2, &x1, x2, rays)) return;
        double d2[3];
        direct(x2, -wi2, d2, rays);
        for (int c = 0; c < 3; ++c) L[c] += T[c] * T2[c] * d2[c];
    }
};

void embree_error(void *user, RTCError code, const char *msg) {
    std::string *s = static_cast<std::string *>(user);
    if (s->empty()) *s = "Embree error " + std::to_string((int)code) + ": " + (msg ? msg : "");
}

} /* namespace */

extern "C" double ref_luminance(const float rgb[3]) {
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

extern "C" void ref_image_free(ref_image *img) {
    if (!img) return;
    std::free(img->radiance);
    std::free(img->std_error);
    std::free(img->position);
    std::free(img->normal);
    std::free(img->covered);
    std::memset(img, 0, sizeof *img);
}

extern "C" int ref_render(const scene *s, const ref_settings *st, ref_image *out, char *err, size_t cap) {
    if (out) std::memset(out, 0, sizeof *out);
    if (!s || !st || !out) {
        set_err(err, cap, "reference: no scene, settings or output");
        return 1;
    }
    scene copy = *s; /* scene_validate fills bounds and normalises light directions: on copies */
    std::vector<scene_light> lights(s->lights, s->lights + (s->lights ? s->light_count : 0));
    copy.lights = lights.data();
    char verr[256] = "";
    if (scene_validate(&copy, verr, sizeof verr) != 0) {
        set_err(err, cap, "reference: invalid scene: %s", verr);
        return 1;
    }
    if (st->spp < 1 || (st->bounces != 1 && st->bounces != 2)) {
        set_err(err, cap, "reference: spp must be >= 1 and bounces 1 or 2");
        return 1;
    }
    const uint32_t W = s->camera.width, H = s->camera.height;
    if (W < 1 || H < 1 || W > 16384 || H > 16384) {
        set_err(err, cap, "reference: image size %ux%u outside 1..16384", W, H);
        return 1;
    }
    size_t np = (size_t)W * H;
    out->width = W;
    out->height = H;
    out->radiance = static_cast<float *>(std::calloc(np * 3, sizeof(float)));
    out->std_error = static_cast<float *>(std::calloc(np * 3, sizeof(float)));
    out->position = static_cast<float *>(std::calloc(np * 3, sizeof(float)));
    out->normal = static_cast<float *>(std::calloc(np * 3, sizeof(float)));
    out->covered = static_cast<unsigned char *>(std::calloc(np, 1));
    std::vector<double> lum_mean(np, 0.0), lum_se(np, 0.0);
    if (!out->radiance || !out->std_error || !out->position || !out->normal || !out->covered) {
        ref_image_free(out);
        set_err(err, cap, "reference: out of memory");
        return 1;
    }

    auto t0 = std::chrono::steady_clock::now();
    std::string emb_err;
    /* one build thread: the BVH, and so every tie between hits, is the same on every machine */
    RTCDevice dev = rtcNewDevice("threads=1,set_affinity=0");
    if (!dev) {
        ref_image_free(out);
        set_err(err, cap, "reference: Embree device creation failed (error %d)", (int)rtcGetDeviceError(nullptr));
        return 1;
    }
    rtcSetDeviceErrorFunction(dev, embree_error, &emb_err);
    RTCScene rs = rtcNewScene(dev);
    rtcSetSceneFlags(rs, (RTCSceneFlags)(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
    rtcSetSceneBuildQuality(rs, RTC_BUILD_QUALITY_HIGH);
    for (uint32_t i = 0; i < s->mesh_count && emb_err.empty(); ++i) {
        const scene_mesh &m = s->meshes[i];
        RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
        float *vb = static_cast<float *>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.vertex_count));
        unsigned *ib = static_cast<unsigned *>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m.triangle_count));
        if (vb && ib) {
            std::memcpy(vb, m.positions, (size_t)m.vertex_count * 3 * sizeof(float));
            std::memcpy(ib, m.indices, (size_t)m.triangle_count * 3 * sizeof(unsigned));
            rtcCommitGeometry(g);
            rtcAttachGeometryByID(rs, g, i);
        }
        rtcReleaseGeometry(g);
    }
    rtcCommitScene(rs);
    if (!emb_err.empty()) {
        rtcReleaseScene(rs);
        rtcReleaseDevice(dev);
        ref_image_free(out);
        set_err(err, cap, "reference: %s", emb_err.c_str());
        return 1;
    }
    auto t1 = std::chrono::steady_clock::now();

    tracer tr;
    tr.s = &copy;
    tr.rs = rs;
    tr.scale = copy.scale;
    tr.bounces = st->bounces;
    for (uint32_t i = 0; i < s->material_count; ++i) {
        const scene_material &sm = s->materials[i];
        material m;
        for (int c = 0; c < 3; ++c) { m.rd[c] = sm.diffuse[c]; m.rg[c] = sm.glossy[c]; }
        m.k = sm.exponent;
        m.wd = (m.rd[0] + m.rd[1] + m.rd[2]) / 3.0;
        m.wg = (m.rg[0] + m.rg[1] + m.rg[2]) / 3.0;
        tr.mats.push_back(m);
    }

    unsigned nt = st->threads ? st->threads : std::max(1u, std::thread::hardware_concurrency());
    nt = std::min<unsigned>(nt, H);
    std::atomic<uint32_t> next_row(0);
    std::vector<uint64_t> rays(nt, 0);
    const uint32_t spp = st->spp;
    std::vector<uint64_t> bad(nt, 0);
    auto work = [&](unsigned tid) {
        uint64_t nrays = 0, nonfinite = 0;
        for (;;) {
            uint32_t y = next_row.fetch_add(1);
            if (y >= H) break;
            for (uint32_t x = 0; x < W; ++x) {
                size_t pi = (size_t)y * W + x;
                float o[3], d[3];
                scene_camera_ray(&s->camera, (float)x + 0.5f, (float)y + 0.5f, o, d);
                v3 dir = normalize(load(d));
                surface x0;
                if (!tr.intersect(load(o), dir, nullptr, x0, nrays)) continue;
                out->covered[pi] = 1;
                for (int c = 0; c < 3; ++c) {
                    out->position[3 * pi + c] = (float)(c == 0 ? x0.p.x : c == 1 ? x0.p.y : x0.p.z);
                    out->normal[3 * pi + c] = (float)(c == 0 ? x0.n.x : c == 1 ? x0.n.y : x0.n.z);
                }
                rng g = pixel_rng(st->seed, pi);
                double sum[3] = {0, 0, 0}, sq[3] = {0, 0, 0}, sy = 0, syy = 0;
                for (uint32_t k = 0; k < spp; ++k) {
                    double L[3];
                    tr.path(x0, -dir, g, L, nrays);
                    if (!std::isfinite(L[0] + L[1] + L[2])) { /* never seen; counted, not hidden */
                        ++nonfinite;
                        L[0] = L[1] = L[2] = 0;
                    }
                    for (int c = 0; c < 3; ++c) { sum[c] += L[c]; sq[c] += L[c] * L[c]; }
                    double yl = 0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2];
                    sy += yl;
                    syy += yl * yl;
                }
                double n = (double)spp;
                for (int c = 0; c < 3; ++c) {
                    double mean = sum[c] / n;
                    double var = spp > 1 ? std::max(0.0, (sq[c] - sum[c] * mean) / (n - 1.0)) : 0.0;
                    out->radiance[3 * pi + c] = (float)mean;
                    out->std_error[3 * pi + c] = (float)std::sqrt(var / n);
                }
                double my = sy / n;
                lum_mean[pi] = my;
                lum_se[pi] = spp > 1 ? std::sqrt(std::max(0.0, (syy - sy * my) / (n - 1.0)) / n) : 0.0;
            }
        }
        rays[tid] = nrays;
        bad[tid] = nonfinite;
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < nt; ++t) pool.emplace_back(work, t);
    work(0);
    for (auto &t : pool) t.join();
    auto t2 = std::chrono::steady_clock::now();
    rtcReleaseScene(rs);
    rtcReleaseDevice(dev);

    /* statistics in pixel order: the same sums for any thread count */
    double sm = 0, sse = 0, sse2 = 0;
    uint32_t cov = 0;
    for (size_t i = 0; i < np; ++i)
        if (out->covered[i]) {
            ++cov;
            sm += lum_mean[i];
            sse += lum_se[i];
            sse2 += lum_se[i] * lum_se[i];
        }
    out->covered_pixels = cov;
    out->mean_radiance = cov ? sm / cov : 0.0;
    out->mean_std_error = cov ? sse / cov : 0.0;
    out->relative_std_error = out->mean_radiance > 0 ? out->mean_std_error / out->mean_radiance : 0.0;
    out->relative_std_error_image = out->mean_radiance > 0 ? std::sqrt(sse2) / cov / out->mean_radiance : 0.0;
    out->build_seconds = std::chrono::duration<double>(t1 - t0).count();
    out->seconds = std::chrono::duration<double>(t2 - t1).count();
    for (uint64_t r : rays) out->rays += r;
    for (uint64_t b : bad) out->nonfinite_samples += b;
    return 0;
}
