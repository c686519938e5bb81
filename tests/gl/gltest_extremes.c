/* The extremes suite for the LightSkin frame of gim_update (GPU, headless): the same
   room scaled from 1e-4 to 1e4 and moved far from the origin, grazing and parallel suns and
   a sun below the horizon, surfaces edge-on to the camera, a near plane cutting the scene,
   coincident caches, exponents 0 / 1 / 1e4, albedo 0 and 1, glossy without diffuse, RSMs of
   1^2 and 2048^2, more VALs than texels, one view sample, one neighbour, one triangle, meshes
   without caches, a non-uniformly scaled instance, lights of 0, 1e-30 and 1e30, a light the
   camera does not see; and hostile arguments to every public GL entry point.

   Every frame's outputs are read back in full (indirect texture, RSM textures, importance
   map, eq. 12 tables, selection, VALs, caches, both proxy light sets) and must be finite and
   non-negative where they are radiometric; where the answer is known the image is compared
   with it, tolerances stated at each case. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define W 64
#define H 48
#define NPIX (W * H)

/* --- geometry: quads --------------------------------------------------------------------- */

#define MAX_Q 24
typedef struct geo {
    float pos[MAX_Q * 12], nrm[MAX_Q * 12];
    uint32_t idx[MAX_Q * 6], mat[MAX_Q * 2];
    uint32_t quads;
} geo;

/* A quad at corner c spanned by u and v (normal u x v), in double so far offsets round once. */
static void geo_quad(geo *g, const double c[3], const double u[3], const double v[3], uint32_t material) {
    uint32_t q = g->quads++, k;
    double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    assert_true(q < MAX_Q);
    for (k = 0; k < 3; ++k) {
        g->pos[q * 12 + k] = (float)c[k];
        g->pos[q * 12 + 3 + k] = (float)(c[k] + u[k]);
        g->pos[q * 12 + 6 + k] = (float)(c[k] + u[k] + v[k]);
        g->pos[q * 12 + 9 + k] = (float)(c[k] + v[k]);
    }
    for (k = 0; k < 12; ++k) g->nrm[q * 12 + k] = (float)(n[k % 3] / l);
    g->idx[q * 6 + 0] = q * 4; g->idx[q * 6 + 1] = q * 4 + 1; g->idx[q * 6 + 2] = q * 4 + 2;
    g->idx[q * 6 + 3] = q * 4; g->idx[q * 6 + 4] = q * 4 + 2; g->idx[q * 6 + 5] = q * 4 + 3;
    g->mat[q * 2] = g->mat[q * 2 + 1] = material;
}

#define SET3(a, x, y, z) ((a)[0] = (x), (a)[1] = (y), (a)[2] = (z))

/* The room of side L with its corner at o: floor y = 0 (material 0), left wall x = 0 (1),
   right wall x = L (2), back wall z = 0 (3), a block 0.3 L high on the floor (0). Open at
   the top and the front. */
static void geo_room(geo *g, double L, const double o[3]) {
    double c[3], u[3], v[3], b0 = 0.35 * L, b1 = 0.65 * L, bh = 0.3 * L;
    memset(g, 0, sizeof *g);
    SET3(c, o[0], o[1], o[2]); SET3(u, 0, 0, L); SET3(v, L, 0, 0); geo_quad(g, c, u, v, 0);
    SET3(c, o[0], o[1], o[2]); SET3(u, 0, L, 0); SET3(v, 0, 0, L); geo_quad(g, c, u, v, 1);
    SET3(c, o[0] + L, o[1], o[2]); SET3(u, 0, 0, L); SET3(v, 0, L, 0); geo_quad(g, c, u, v, 2);
    SET3(c, o[0], o[1], o[2]); SET3(u, L, 0, 0); SET3(v, 0, L, 0); geo_quad(g, c, u, v, 3);
    SET3(c, o[0] + b0, o[1] + bh, o[2] + b0); SET3(u, 0, 0, b1 - b0); SET3(v, b1 - b0, 0, 0); geo_quad(g, c, u, v, 0);
    SET3(c, o[0] + b0, o[1], o[2] + b1); SET3(u, b1 - b0, 0, 0); SET3(v, 0, bh, 0); geo_quad(g, c, u, v, 0);
    SET3(c, o[0] + b0, o[1], o[2] + b0); SET3(u, 0, 0, b1 - b0); SET3(v, 0, bh, 0); geo_quad(g, c, u, v, 0);
    SET3(c, o[0] + b1, o[1], o[2] + b0); SET3(u, 0, bh, 0); SET3(v, 0, 0, b1 - b0); geo_quad(g, c, u, v, 0);
}

static gim_mesh_data geo_mesh(const geo *g) {
    gim_mesh_data m;
    memset(&m, 0, sizeof m);
    m.positions = g->pos;
    m.normals = g->nrm;
    m.vertex_count = g->quads * 4;
    m.indices = g->idx;
    m.index_count = g->quads * 6;
    m.triangle_material = g->mat;
    return m;
}

static const gim_material room_materials[4] = {
    {{0.8f, 0.8f, 0.8f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.8f, 0.1f, 0.1f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.1f, 0.8f, 0.1f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.6f, 0.6f, 0.6f}, {0.0f, 0.0f, 0.0f}, 0.0f}};

/* --- a scene of up to 4 meshes and instances -------------------------------------------- */

typedef struct ex {
    gltest_fixture f;
    gim_mesh mesh[4];
    gim_cache_set set[4];
    int has_set[4];
    uint32_t mesh_count;
    gim_instance inst[4];
    uint32_t inst_count;
    gim_frame fr;
    gim_light light;
    int host_gbuffer;       /* 1: the G-buffer is the test's own (its normals may be hostile) */
} ex;

static void ex_begin(ex *e) {
    memset(e, 0, sizeof *e);
    gltest_fixture_begin(&e->f);
}

/* Add g as a mesh; caches (d_eps = cache_d) when cache_d > 0; an identity instance of it. */
static uint32_t ex_add(ex *e, const geo *g, double cache_d) {
    gim_mesh_desc md;
    uint32_t k = e->mesh_count++;
    memset(&md, 0, sizeof md);
    md.data = geo_mesh(g);
    if (cache_d > 0.0) {
        gim_cache_desc cd;
        memset(&cd, 0, sizeof cd);
        cd.mesh = geo_mesh(g);
        cd.d_eps = (float)cache_d;
        cd.env = e->f.env;
        assert_int_equal(gim_cache_generate(&cd, &e->set[k]), GIM_OK);
        e->has_set[k] = 1;
        md.caches = &e->set[k];
    }
    assert_int_equal(gim_add_mesh(e->f.ctx, &md, &e->mesh[k]), GIM_OK);
    e->inst[e->inst_count].mesh = e->mesh[k];
    e->inst[e->inst_count].model = gim_mat4_identity();
    e->inst_count++;
    return k;
}

static void ex_end(ex *e) {
    uint32_t i;
    for (i = 0; i < e->mesh_count; ++i) {
        assert_int_equal(gim_remove_mesh(e->f.ctx, e->mesh[i]), GIM_OK);
        if (e->has_set[i]) gim_cache_set_free(&e->set[i]);
    }
    gltest_fixture_end(&e->f);
}

/* look_at(eye, eye + dir, up) with the translation in double: a host far from the origin
   must not round eye + dir to the eye's ulp (the camera would turn by ulp(|eye|) / |dir|). */
static gim_mat4 look_along(const double eye[3], const double dir[3]) {
    gim_mat4 v = gim_mat4_look_at(gim_v3(0, 0, 0), gim_v3((float)dir[0], (float)dir[1], (float)dir[2]), gim_v3(0, 1, 0));
    int r;
    for (r = 0; r < 3; ++r) v.m[12 + r] = (float)-(v.m[r] * eye[0] + v.m[4 + r] * eye[1] + v.m[8 + r] * eye[2]);
    return v;
}

/* The room's camera: from the open front, a little above, looking at the back wall. */
static void room_camera(gim_frame *fr, double L, const double o[3]) {
    double eye[3], dir[3];
    SET3(eye, o[0] + 0.5 * L, o[1] + 0.55 * L, o[2] + 1.9 * L);
    SET3(dir, 0.0, -0.25, -1.9);
    fr->view = look_along(eye, dir);
    fr->proj = gim_mat4_perspective(1.0f, (float)W / H, (float)(0.05 * L), (float)(5.0 * L));
    fr->width = W;
    fr->height = H;
}

static gim_light sun(float irradiance, gim_vec3 towards, uint32_t rsm) {
    gim_light l;
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_DIRECTIONAL;
    l.irradiance = irradiance;
    l.direction = towards;
    l.rsm_size = rsm;
    return l;
}

static gim_light spot(double I, double L, const double o[3], uint32_t rsm) {
    gim_light l;
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.intensity = (float)I;
    l.position = gim_v3((float)(o[0] + 0.5 * L), (float)(o[1] + 0.95 * L), (float)(o[2] + 0.8 * L));
    l.direction = gim_v3(-0.1f, -1.0f, -0.5f);
    l.cone_angle = 1.0f;
    l.rsm_size = rsm;
    return l;
}

/* --- the frame and what it left: every output read back ------------------------------------ */

typedef struct ex_out {
    float img[NPIX * 4];        /* indirect (zero when there is none) */
    float nrm[NPIX * 4];        /* G-buffer normal, w = 1 where drawn */
    float depth[NPIX];          /* G-buffer window depth */
    double max;                 /* largest rgb value of img */
    double sum;                 /* sum of rgb over img */
    uint32_t drawn, lit;        /* pixels with a surface, and with some indirect light */
    double val_flux, proxy_flux; /* sums over the VALs (times weight) and the diffuse proxies */
    uint32_t warnings;          /* log warnings during the frame */
} ex_out;

static int finite_nonneg(float v) { return isfinite(v) && v >= 0.0f; }

/* Check every buffer and texture the last frame wrote. */
static void ex_read(ex *e, ex_out *out) {
    gim_frame_outputs o = gim_outputs(e->f.ctx);
    gim_debug_outputs od = gim_debug(e->f.ctx);
    uint32_t i, l, k;
    assert_true(o.valid);
    memset(out, 0, sizeof *out);
    gltest_read_texture(o.gbuffer_normal, GL_RGBA, out->nrm);
    if (!e->host_gbuffer)
        for (i = 0; i < NPIX * 4; ++i) assert_true(isfinite(out->nrm[i]));
    gltest_read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, out->depth);
    for (i = 0; i < NPIX; ++i) {
        assert_true(out->depth[i] >= 0.0f && out->depth[i] <= 1.0f);
        if (out->nrm[i * 4 + 3] == 1.0f) out->drawn++;
    }
    if (od.view_samples) {   /* {vec4 position; vec4 normal}: finite (an unusable sample is zero) */
        float *vs = (float *)malloc((size_t)od.view_sample_count * 32u);
        gltest_read_buffer(od.view_samples, (size_t)od.view_sample_count * 32u, vs);
        for (i = 0; i < od.view_sample_count * 8u; ++i) assert_true(isfinite(vs[i]));
        free(vs);
    }
    if (o.indirect) {
        gltest_read_texture(o.indirect, GL_RGBA, out->img);
        for (i = 0; i < NPIX; ++i) {
            float s = 0.0f;
            for (k = 0; k < 3; ++k) {
                float v = out->img[i * 4 + k];
                if (!finite_nonneg(v)) fail_msg("indirect pixel %u channel %u is %g", (unsigned)i, (unsigned)k, (double)v);
                if (v > out->max) out->max = v;
                out->sum += v;
                s += v;
            }
            assert_true(out->img[i * 4 + 3] == 0.0f || out->img[i * 4 + 3] == 1.0f);
            if (s > 0.0f) out->lit++;
        }
    }
    for (l = 0; l < o.light_count; ++l) {
        const gim_light_outputs *lo = &o.lights[l];
        uint32_t n = lo->rsm_size * lo->rsm_size;
        float *t = (float *)malloc((size_t)n * 16u);
        gltest_read_texture(lo->rsm_position, GL_RGBA, t);
        for (i = 0; i < n * 4; ++i) assert_true(isfinite(t[i]));
        gltest_read_texture(lo->rsm_normal, GL_RGBA, t);
        for (i = 0; i < n; ++i) assert_true(isfinite(t[i * 4]) && isfinite(t[i * 4 + 1]) && isfinite(t[i * 4 + 2]) &&
                                            finite_nonneg(t[i * 4 + 3]));
        gltest_read_texture(lo->rsm_flux, GL_RGBA, t);
        for (i = 0; i < n * 4; ++i) assert_true(finite_nonneg(t[i]));
        if (lo->importance) {
            /* the tables' side: texels, or tiles of the two-level map */
            uint32_t side = (lo->rsm_size - 1u) / lo->importance_tile + 1u, cells = side * side;
            double *d = (double *)malloc((size_t)n * 8u), prev;
            gim_selected_val *s = (gim_selected_val *)malloc((size_t)lo->selected_count * sizeof *s);
            gltest_read_buffer(lo->importance, (size_t)n * 4u, t);
            for (i = 0; i < n; ++i) assert_true(finite_nonneg(t[i]));
            if (lo->importance_tiles) {
                gltest_read_buffer(lo->importance_tiles, (size_t)cells * 4u, t);
                for (i = 0; i < cells; ++i) assert_true(finite_nonneg(t[i]));
            }
            gltest_read_buffer(lo->column, (size_t)cells * 8u, d);   /* cumulative down each column */
            for (i = 0; i < cells; ++i) {
                assert_true(isfinite(d[i]) && d[i] >= 0.0);
                if (i >= side) assert_true(d[i] >= d[i - side]);
            }
            gltest_read_buffer(lo->row, (size_t)side * 8u, d);
            for (i = 0, prev = 0.0; i < side; ++i) {
                if (!(isfinite(d[i]) && d[i] >= prev))
                    fail_msg("light %u: row[%u] = %.17g after %.17g", (unsigned)l, (unsigned)i, d[i], prev);
                prev = d[i];
            }
            if (lo->selected_count) gltest_read_buffer(lo->selected, (size_t)lo->selected_count * sizeof *s, s);
            else assert_true(lo->selected == 0 && d[side - 1u] == 0.0);   /* shared budget: none to a zero total */
            for (i = 0; i < lo->selected_count; ++i)
                assert_true(s[i].x < lo->rsm_size && s[i].y < lo->rsm_size && isfinite(s[i].pdf) && s[i].pdf > 0.0f &&
                            s[i].pdf <= 1.0f);
            free(d);
            free(s);
        }
        free(t);
    }
    if (od.vals) {
        gim_val *v = (gim_val *)malloc((size_t)od.val_count * sizeof *v);
        gltest_read_buffer(od.vals, (size_t)od.val_count * sizeof *v, v);
        for (i = 0; i < od.val_count; ++i) {
            assert_true(gim__all_finite(v[i].position, 3) && gim__all_finite(v[i].normal, 3));
            assert_true(finite_nonneg(v[i].area) && finite_nonneg(v[i].weight));
            for (k = 0; k < 3; ++k) {
                assert_true(finite_nonneg(v[i].flux[k]));
                out->val_flux += (double)v[i].flux[k] * v[i].weight;
            }
        }
        free(v);
    }
    if (od.caches) {
        gim_cache *c = (gim_cache *)malloc((size_t)od.cache_count * sizeof *c);
        gim_proxy_light *p = (gim_proxy_light *)malloc((size_t)od.cache_count * sizeof *p);
        gltest_read_buffer(od.caches, (size_t)od.cache_count * sizeof *c, c);
        for (i = 0; i < od.cache_count; ++i)
            assert_true(gim__all_finite(c[i].position, 3) && gim__all_finite(c[i].normal, 3) && finite_nonneg(c[i].area));
        for (k = 0; k < 2; ++k) {
            uint32_t b = k == 0 ? od.proxy_diffuse : od.proxy_glossy;
            if (!b) continue;
            gltest_read_buffer(b, (size_t)od.cache_count * sizeof *p, p);
            for (i = 0; i < od.cache_count; ++i) {
                int a;
                assert_true(gim__all_finite(p[i].position, 3) && finite_nonneg(p[i].radius));
                assert_true(p[i].visibility >= 0.0f && p[i].visibility <= 1.0f);
                for (a = 0; a < 3; ++a) {
                    if (!finite_nonneg(p[i].flux[a]) || !finite_nonneg(p[i].sigma[a]))
                        fail_msg("proxy %u (%s): flux %g sigma %g", (unsigned)i, k ? "glossy" : "diffuse",
                                 (double)p[i].flux[a], (double)p[i].sigma[a]);
                    if (k == 0) out->proxy_flux += p[i].flux[a];
                }
            }
        }
        free(c);
        free(p);
    }
}

/* Set the scene's instances and light, run the frame, read it all back. */
static void ex_frame(ex *e, ex_out *out) {
    int warnings = e->f.log.warnings;
    assert_int_equal(gim_set_instances(e->f.ctx, e->inst, e->inst_count), GIM_OK);
    assert_int_equal(gim_set_lights(e->f.ctx, &e->light, 1), GIM_OK);
    assert_int_equal(gim_update(e->f.ctx, &e->fr), GIM_OK);
    gltest_state_unchanged(&e->f);
    ex_read(e, out);
    out->warnings = (uint32_t)(e->f.log.warnings - warnings);
}

/* Differences of image a against the reference b over the pixels drawn in both: the largest
   per-pixel relative difference (relative to the pixel, floored at floor_rel of b's largest
   value), how many pixels exceed tol, and the mean relative difference sum|a-b| / sum b. */
typedef struct ex_diff { double max_rel, mean_rel; uint32_t above, pixels; } ex_diff;

static ex_diff ex_compare(const ex_out *a, const ex_out *b, double floor_rel, double tol) {
    ex_diff d;
    double num = 0.0, den = 0.0;
    uint32_t i, k;
    memset(&d, 0, sizeof d);
    for (i = 0; i < NPIX; ++i) {
        double e = 0.0;
        if (a->nrm[i * 4 + 3] != 1.0f || b->nrm[i * 4 + 3] != 1.0f) continue;
        d.pixels++;
        for (k = 0; k < 3; ++k) {
            double x = a->img[i * 4 + k], r = b->img[i * 4 + k];
            double fl = floor_rel * b->max, rel = fabs(x - r) / (r > fl ? r : fl);
            num += fabs(x - r);
            den += r;
            if (rel > e) e = rel;
        }
        if (e > tol) d.above++;
        if (e > d.max_rel) d.max_rel = e;
    }
    d.mean_rel = den > 0.0 ? num / den : (num > 0.0 ? 1.0 : 0.0);
    return d;
}

/* --- scale and position ----------------------------------------------------------------- */

/* The room at side s (caches d_eps = s / 8), a light that gives the same irradiance at every
   scale, the camera scaled with it. */
static void room_at(ex *e, double s, const double o[3], int use_spot, gim_method method, ex_out *out) {
    geo g;
    ex_begin(e);
    geo_room(&g, s, o);
    ex_add(e, &g, s / 8.0);
    assert_int_equal(gim_set_materials(e->f.ctx, room_materials, 4), GIM_OK);
    /* the spot's intensity goes with s^2: irradiance I cos / d^2 stays; the sun's E is per area */
    e->light = use_spot ? spot(40.0 * s * s, s, o, 32) : sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e->fr, s, o);
    e->fr.method = method;
    e->fr.lightskin.val_count = 512;
    e->fr.lightskin.view_sample_count = 64;
    e->fr.indirect_float32 = 1;
    ex_frame(e, out);
}

/* One bounce is scale-invariant in radiance: the same room at 1e-4 ... 1e4 (and at 2^+-13)
   gives the image of side 1. FULL: every texel a VAL, so only float rounding differs (a
   decimal scale is not exact in binary): mean relative difference < 1e-4 (measured <= 3e-6),
   at most 1% of the pixels above 1e-3 (measured: none; max 7e-5). At a power-of-two scale
   everything is bit for bit the same (measured 0), BRSM included (the map is scale-free).
   BRSM at a decimal scale: a rounding in the importance map can move one of the 512 picks
   (seen: one), worth ~1/512 of the light of the caches near it: mean < 5e-3 (measured up to
   1.9e-3, max 1.6e-2). 1e-15 and 5e14 hold the FULL bound too (measured: 1e-10 ... 1e17 all
   below 4e-5 max; 1e-19 breaks, 1e19 cannot be lit: I = 40 s^2 overflows); gim_update
   refuses scenes outside 1e-15..1e15 across. Bugs this found: before gim_light_camera built
   the light's view in double, the spot at 1e4 (its axis rounded by ulp(1e4) / 1) gave mean
   2.1e-4 and 115 pixels above 1e-3 in FULL; before lightskin_shade.comp normalised eq. 9's
   luminance weights, the spot room went black at 1e10 (w lum |op|^2 overflowed) and was off
   by 25% (max 24x) at 1e-15 (it flushed to 0). */
static void scale_invariance(void **state) {
    static const double scales[8] = {1e-4, 1e-2, 1e2, 1e4, 1.0 / 8192.0, 8192.0, 1e-15, 5e14};
    static const double o0[3] = {0.0, 0.0, 0.0};
    ex e;
    ex_out *ref = (ex_out *)malloc(sizeof *ref), *cur = (ex_out *)malloc(sizeof *cur);
    int light, method, k;
    (void)state;
    GLTEST_BEGIN();
    for (light = 0; light < 2; ++light)
        for (method = 0; method < 2; ++method) {
            gim_method m = method ? GIM_METHOD_LIGHTSKIN_BRSM : GIM_METHOD_LIGHTSKIN_FULL;
            room_at(&e, 1.0, o0, light, m, ref);
            ex_end(&e);
            assert_true(ref->lit > ref->drawn / 2 && ref->max > 0.0);
            for (k = 0; k < 8; ++k) {
                ex_diff d;
                int exact = !method || k == 4 || k == 5;
                room_at(&e, scales[k], o0, light, m, cur);
                ex_end(&e);
                d = ex_compare(cur, ref, 1e-3, 1e-3);
                print_message("scale %-9.3g %s %s: %u pixels, max rel %.2e, mean rel %.2e, %u above 1e-3\n", scales[k],
                              light ? "spot" : "sun ", method ? "BRSM" : "FULL", d.pixels, d.max_rel, d.mean_rel, d.above);
                assert_true(d.pixels > NPIX / 2);
                assert_true(d.mean_rel < (exact ? 1e-4 : 5e-3));
                if (exact) assert_true(d.above <= d.pixels / 100);
            }
        }
    /* outside 1e-15..1e15 across: refused with a log line, not an image that goes dark */
    for (k = 0; k < 2; ++k) {
        geo g;
        double side = k ? 1e16 : 1e-16;
        int errors;
        ex_begin(&e);
        geo_room(&g, side, o0);
        ex_add(&e, &g, side / 8.0);
        assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
        e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
        room_camera(&e.fr, side, o0);
        assert_int_equal(gim_set_instances(e.f.ctx, e.inst, 1), GIM_OK);
        assert_int_equal(gim_set_lights(e.f.ctx, &e.light, 1), GIM_OK);
        errors = e.f.log.errors;
        assert_int_equal(gim_update(e.f.ctx, &e.fr), GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(e.f.log.errors, errors + 1);
        e.f.log.errors = 0;
        ex_end(&e);
    }
    free(ref);
    free(cur);
    GLTEST_END();
}

/* The room moved far from the origin. Float positions there are quantised to ulp(|o|)
   (2^-7 = 0.0078 at 1e5): vertices, caches, RSM texels and the pixels unprojected from the
   G-buffer each carry an absolute error of that order, so the image differs from the room at
   the origin by about ulp(|o|) / L relative (the tent weights of eq. 8 move by the position
   error over d_c,max ~ L / 10). Measured at |o| = 1e5 (mean / max per pixel): L = 1000:
   4e-5 / 5e-4, L = 200: 2e-4 / 2.4e-3; L = 60 (960 diagonals out) 5e-4 / 1e-2; from L = 40
   (1400 diagonals) the spot inside the room loses its depth order (clip z and w are rounded
   separately by ~ulp(|o|), its near plane is 1e-4 of its far plane): 2.4% mean, 58% max, and
   L = 25: 11% mean. gim_update refuses scenes more than 1024 diagonals from the origin.
   (The camera here is built with its translation in double, as a host far from the origin
   must: a float look_at(eye, eye + dir) turns the view by ulp(|eye|) / |dir|.) */
static void far_from_origin(void **state) {
    static const double sides[3] = {1000.0, 200.0, 60.0};
    static const double o0[3] = {0.0, 0.0, 0.0}, ofar[3] = {1e5, 2e4, -5e4};
    ex e;
    ex_out *ref = (ex_out *)malloc(sizeof *ref), *cur = (ex_out *)malloc(sizeof *cur);
    int k, light;
    (void)state;
    GLTEST_BEGIN();
    for (light = 0; light < 2; ++light)
        for (k = 0; k < 3; ++k) {
            ex_diff d;
            double q = 0.0078125 / sides[k];   /* ulp(1e5) / L */
            room_at(&e, sides[k], o0, light, GIM_METHOD_LIGHTSKIN_FULL, ref);
            ex_end(&e);
            room_at(&e, sides[k], ofar, light, GIM_METHOD_LIGHTSKIN_FULL, cur);
            ex_end(&e);
            d = ex_compare(cur, ref, 1e-3, 1e-2);
            print_message("offset 1e5, side %-5g %s (ulp/L %.1e): %u pixels, max rel %.2e, mean rel %.2e, %u above 1e-2\n",
                          sides[k], light ? "spot" : "sun ", q, d.pixels, d.max_rel, d.mean_rel, d.above);
            assert_true(d.pixels > NPIX / 2);
            assert_true(d.mean_rel < 10.0 * q);        /* measured 3-7 ulp / L */
            assert_true(d.above <= d.pixels / 100);
        }
    /* farther than 1024 diagonals: refused, logged, and the context still renders */
    {
        geo g;
        int errors;
        ex_begin(&e);
        geo_room(&g, 50.0, ofar);       /* 87 across at 1e5: 1150 diagonals */
        ex_add(&e, &g, 50.0 / 8.0);
        assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
        e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
        room_camera(&e.fr, 50.0, ofar);
        assert_int_equal(gim_set_instances(e.f.ctx, e.inst, 1), GIM_OK);
        assert_int_equal(gim_set_lights(e.f.ctx, &e.light, 1), GIM_OK);
        errors = e.f.log.errors;
        assert_int_equal(gim_update(e.f.ctx, &e.fr), GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(e.f.log.errors, errors + 1);
        assert_true(strstr(e.f.log.last, "origin") != NULL);
        assert_false(gim_outputs(e.f.ctx).valid);
        gltest_state_unchanged(&e.f);
        e.inst[0].model.m[12] = -1e5f; e.inst[0].model.m[13] = -2e4f; e.inst[0].model.m[14] = 5e4f; /* moved home */
        room_camera(&e.fr, 50.0, o0);
        ex_frame(&e, cur);
        assert_true(cur->lit > cur->drawn / 2);
        e.f.log.errors = 0;
        ex_end(&e);
    }
    free(ref);
    free(cur);
    GLTEST_END();
}

/* --- angles ------------------------------------------------------------------------------ */

/* A floor 2L x 2L (y = 0) and a wall (z = 0, normal +z) standing on it; the sun's direction
   lies in the wall's plane, so only the floor is lit and the wall's light is the floor's
   bounce: proportional to cos(theta) of the sun on the floor. */
static void floor_wall(ex *e, double theta_deg, uint32_t rsm, ex_out *out) {
    static const gim_material m[2] = {{{0.7f, 0.7f, 0.7f}, {0, 0, 0}, 0.0f}, {{0.5f, 0.6f, 0.7f}, {0, 0, 0}, 0.0f}};
    geo g;
    double c[3], u[3], v[3], t = theta_deg * 3.14159265358979323846 / 180.0, eye[3], dir[3];
    ex_begin(e);
    memset(&g, 0, sizeof g);
    SET3(c, -1, 0, 0); SET3(u, 0, 0, 2); SET3(v, 2, 0, 0); geo_quad(&g, c, u, v, 0);
    SET3(c, -1, 0, 0); SET3(u, 2, 0, 0); SET3(v, 0, 1, 0); geo_quad(&g, c, u, v, 1);
    ex_add(e, &g, 2.0 / 10.0);
    assert_int_equal(gim_set_materials(e->f.ctx, m, 2), GIM_OK);
    e->light = sun(2.0f, gim_v3((float)sin(t), (float)cos(t), 0.0f), rsm);
    SET3(eye, 0.0, 0.9, 2.6); SET3(dir, 0.0, -0.5, -2.0);
    e->fr.view = look_along(eye, dir);
    e->fr.proj = gim_mat4_perspective(1.1f, (float)W / H, 0.05f, 10.0f);
    e->fr.width = W;
    e->fr.height = H;
    e->fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e->fr.indirect_float32 = 1;
    ex_frame(e, out);
}

/* Mean rgb of the pixels whose normal is close to n (the wall: +z, the floor: +y). */
static double mean_where(const ex_out *o, int axis, uint32_t *count) {
    double s = 0.0;
    uint32_t i, c = 0;
    for (i = 0; i < NPIX; ++i)
        if (o->nrm[i * 4 + 3] == 1.0f && o->nrm[i * 4 + axis] > 0.99f) {
            s += o->img[i * 4] + o->img[i * 4 + 1] + o->img[i * 4 + 2];
            c++;
        }
    if (count) *count = c;
    return c ? s / (3.0 * c) : 0.0;
}

/* The sun at 60, 80 and 89.9 degrees from the floor's normal, exactly parallel to it (90) and
   below the horizon (100); a camera that sees the floor edge-on. The wall's light goes with
   cos(theta): at 80 degrees within 5% of 60's times the cosine ratio (measured 3%: the RSM
   samples the floor at 64^2 texels either way); at 89.9 the floor is 0.15 texel rows high in
   the RSM, so its texels are all or nothing: below 3x the cosine law, measured 0 (no texel
   centre falls on it; an RSM misses a surface thinner than a texel, here 0.35% of the
   bounce at 60 degrees). At 90
   nothing is lit (no RSM texel: the floor and the wall are edge-on to the light) and below
   the horizon the lit underside of the floor faces away from the wall: all zero. */
static void grazing_sun(void **state) {
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    double wall60, wall80, wall899, r80, r899;
    uint32_t nw;
    (void)state;
    GLTEST_BEGIN();
    floor_wall(&e, 60.0, 64, a);
    ex_end(&e);
    wall60 = mean_where(a, 2, &nw);
    assert_true(nw > NPIX / 8 && wall60 > 0.0);
    floor_wall(&e, 80.0, 64, b);
    ex_end(&e);
    wall80 = mean_where(b, 2, NULL);
    r80 = wall80 / wall60 / (cos(80.0 * 3.14159265358979323846 / 180.0) / cos(60.0 * 3.14159265358979323846 / 180.0));
    floor_wall(&e, 89.9, 64, b);
    ex_end(&e);
    wall899 = mean_where(b, 2, NULL);
    r899 = wall899 / wall60 / (cos(89.9 * 3.14159265358979323846 / 180.0) / cos(60.0 * 3.14159265358979323846 / 180.0));
    print_message("wall radiance / cosine law: 80 deg %.4f, 89.9 deg %.4f (wall at 60: %.4g)\n", r80, r899, wall60);
    assert_true(fabs(r80 - 1.0) < 0.05);
    assert_true(r899 >= 0.0 && r899 < 3.0);
    floor_wall(&e, 90.0, 64, b);
    ex_end(&e);
    print_message("parallel sun: max %g, VAL flux %g\n", b->max, b->val_flux);
    assert_true(b->max == 0.0 && b->val_flux == 0.0);
    floor_wall(&e, 100.0, 64, b);
    ex_end(&e);
    print_message("sun below the horizon: max %g (at 60: %g), VAL flux %g\n", b->max, a->max, b->val_flux);
    assert_true(b->val_flux > 0.0);            /* the floor's underside is lit (two-sided) ... */
    assert_true(b->max <= 1e-6 * a->max);      /* ... and lights nothing above it */
    /* the floor seen exactly edge-on (eye at its height) and nearly so (1e-6 above) */
    {
        double eye[3], dir[3];
        int k;
        for (k = 0; k < 2; ++k) {
            floor_wall(&e, 60.0, 64, b);
            SET3(eye, 0.0, k ? 1e-6 : 0.0, 2.6); SET3(dir, 0.0, 0.0, -1.0);
            e.fr.view = look_along(eye, dir);
            ex_frame(&e, b);
            print_message("floor edge-on (eye %g above): %u pixels drawn, %u lit, max %g\n", eye[1], b->drawn, b->lit, b->max);
            assert_true(b->lit > NPIX / 8);      /* the wall, lit by the floor */
            ex_end(&e);
        }
    }
    free(a);
    free(b);
    GLTEST_END();
}

/* --- distances --------------------------------------------------------------------------- */

/* A near plane that cuts the room: the surfaces behind it are the same points, so where a
   pixel sees the same surface (same normal, depth of the same point) its light is the same;
   the unprojected positions differ only by the depth buffer's rounding (< 1e-3 relative).
   Per pixel (shade_block 1): blocks share a light across the pixels of a block.
   A spot light just above the floor (receivers inside its near plane): finite and lit.
   Two identical instances (every cache doubled, d_c,max ties, hash buckets twice as full)
   with n = 16 neighbours give the image of one instance with n = 8: each cache counts twice
   in both sums of eq. 9. */
static void near_plane_and_coincident_caches(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    ex_diff d;
    uint32_t i, same = 0, cut = 0;
    (void)state;
    GLTEST_BEGIN();
    gim_mat4 pa, pb;
    room_at(&e, 1.0, o0, 0, GIM_METHOD_LIGHTSKIN_FULL, a);
    /* per pixel: in 2 x 2 blocks a pixel takes its block's first receiver's light, and the
       near plane changes which receiver is first where it cuts a block (measured: mean rel
       1.5e-3 over the kept pixels, 30 of 970 above 1e-3) */
    e.fr.lightskin.shade_block = 1;
    ex_frame(&e, a);
    pa = e.fr.proj;
    pb = e.fr.proj = gim_mat4_perspective(1.0f, (float)W / H, 1.3f, 5.0f);   /* cuts the block and the floor */
    ex_frame(&e, b);
    ex_end(&e);
    for (i = 0; i < NPIX; ++i) {   /* keep the pixels that see the same point in both: view depth within 1e-4 */
        double za = -pa.m[14] / (2.0 * a->depth[i] - 1.0 + pa.m[10]), zb = -pb.m[14] / (2.0 * b->depth[i] - 1.0 + pb.m[10]);
        if (a->nrm[i * 4 + 3] == 1.0f && b->nrm[i * 4 + 3] == 1.0f && fabs(za - zb) < 1e-4 * fabs(za)) same++;
        else if (a->nrm[i * 4 + 3] == 1.0f) { a->nrm[i * 4 + 3] = 0.0f; cut++; }
    }
    d = ex_compare(b, a, 1e-3, 1e-3);
    print_message("near plane at 1.3 L: %u pixels changed surface, %u compared: max rel %.2e, mean rel %.2e, %u above 1e-3\n",
                  cut, d.pixels, d.max_rel, d.mean_rel, d.above);
    assert_true(cut > 50 && d.pixels == same && same > NPIX / 4);
    assert_true(d.mean_rel < 1e-3 && d.above <= d.pixels / 50);

    /* an infinite far plane (m10 = -1, m14 = -2 n: engines' favourite) sees the same points
       as far = 5 L, so the same light, within the depth buffer's rounding near 1 (measured
       max 3e-5); an orthographic camera, with a glossy wall too: finite and lit */
    room_at(&e, 1.0, o0, 0, GIM_METHOD_LIGHTSKIN_FULL, a);
    e.fr.proj.m[10] = -1.0f;
    e.fr.proj.m[14] = -2.0f * 0.05f;
    ex_frame(&e, b);
    d = ex_compare(b, a, 1e-3, 1e-3);
    print_message("infinite far plane: %u pixels, max rel %.2e, mean rel %.2e, %u above 1e-3\n", d.pixels, d.max_rel,
                  d.mean_rel, d.above);
    assert_true(d.pixels > NPIX / 2 && d.mean_rel < 1e-4 && d.above <= d.pixels / 100);
    e.fr.proj = gim_mat4_ortho(-0.8f, 0.8f, -0.6f, 0.6f, 0.05f, 5.0f);
    ex_frame(&e, b);
    print_message("orthographic camera: %u lit of %u drawn, max %g\n", b->lit, b->drawn, b->max);
    assert_true(b->lit > b->drawn / 2 && b->drawn > NPIX / 2);
    {   /* ... with a glossy back wall: the lobe's eye is a point far along the view direction */
        gim_material m[4];
        memcpy(m, room_materials, sizeof m);
        m[3].glossy[0] = m[3].glossy[1] = m[3].glossy[2] = 0.5f;
        m[3].exponent = 50.0f;
        assert_int_equal(gim_set_materials(e.f.ctx, m, 4), GIM_OK);
        ex_frame(&e, b);
        assert_true(gim_debug(e.f.ctx).proxy_glossy != 0 && b->lit > b->drawn / 2);
    }
    ex_end(&e);

    /* a spot 1e-4 above the floor: the floor under it lies inside its RSM's near plane (1e-4
       of the far plane), the VALs next to it have areas ~1e-10 and distances ~1e-4 */
    room_at(&e, 1.0, o0, 1, GIM_METHOD_LIGHTSKIN_FULL, a);
    e.light.position = gim_v3(0.2f, 1e-4f, 0.6f);
    e.light.direction = gim_v3(1.0f, -0.4f, -0.2f);
    ex_frame(&e, b);
    print_message("spot 1e-4 above the floor: %u lit of %u, max %g, VAL flux %g\n", b->lit, b->drawn, b->max, b->val_flux);
    assert_true(b->lit > b->drawn / 4 && b->val_flux > 0.0);
    e.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    ex_frame(&e, b);
    ex_end(&e);

    room_at(&e, 1.0, o0, 0, GIM_METHOD_LIGHTSKIN_FULL, a);
    e.fr.lightskin.neighbour_count = 8;
    ex_frame(&e, a);
    e.inst[1] = e.inst[0];
    e.inst_count = 2;
    e.fr.lightskin.neighbour_count = 16;
    ex_frame(&e, b);
    assert_int_equal(gim_debug(e.f.ctx).cache_count, 2u * e.set[0].count);
    ex_end(&e);
    d = ex_compare(b, a, 1e-3, 1e-4);
    print_message("coincident caches (n 16, doubled) vs n 8: max rel %.2e, mean rel %.2e, %u above 1e-4\n", d.max_rel,
                  d.mean_rel, d.above);
    assert_true(d.mean_rel < 1e-5 && d.above <= d.pixels / 200);
    free(a);
    free(b);
    GLTEST_END();
}

/* VALs at a cache (d = 0), inside and just outside its 1e-6 scene-scale coincidence radius
   with zero area (eq. 3's A + pi d^2 -> 0), of flux up to 1e30: the GPU proxy pass is finite
   and agrees with its twin (which sums in double). */
static void val_on_cache(void **state) {
    enum { NC = 3, NV = 5 };
    gltest_fixture f;
    gim_cache c[NC];
    gim_val v[NV];
    gim_proxy_light gd[NC], gg[NC], cd[NC], cg[NC];
    gim_proxy_desc pd;
    GLuint bc, bv, bd, bg;
    uint32_t i, k;
    float s = 1.0f;   /* scene scale */
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(c, 0, sizeof c);
    memset(v, 0, sizeof v);
    for (i = 0; i < NC; ++i) {
        c[i].position[0] = 0.3f * (float)i;
        c[i].normal[1] = 1.0f;
        c[i].area = 0.01f;
        c[i].reflectance = 1.0f;
    }
    for (i = 0; i < NV; ++i) {   /* above cache 0, facing it (normal -y): at 0, 0.5e-6, 1.5e-6, 1e-3, 0.2 */
        static const float dy[NV] = {0.0f, 0.5e-6f, 1.5e-6f, 1e-3f, 0.2f};
        v[i].position[0] = i == 4 ? 0.25f : 0.0f;
        v[i].position[1] = dy[i];
        v[i].normal[1] = -1.0f;
        v[i].area = i < 4 ? 0.0f : 1e-4f;                         /* eq. 3's A + pi d^2 -> 0 */
        v[i].weight = 1.0f;
        v[i].flux[0] = v[i].flux[1] = v[i].flux[2] = i == 3 ? 1e30f : 1.0f;   /* e ~ 3e35 at 1e-3 */
    }
    memset(&pd, 0, sizeof pd);
    pd.caches = c; pd.cache_count = NC; pd.vals = v; pd.val_count = NV;
    pd.eye = gim_v3(0.0f, 2.0f, 3.0f); pd.glossy_exponent = 20.0f; pd.scene_scale = s; pd.env = f.env;
    assert_int_equal(gim_proxy_lights_twin(&pd, cd, cg), GIM_OK);
    bc = gltest_ssbo(sizeof c, c);
    bv = gltest_ssbo(sizeof v, v);
    bd = gltest_ssbo(sizeof gd, NULL);
    bg = gltest_ssbo(sizeof gg, NULL);
    assert_int_equal(gim__gl_proxy_lights(f.ctx, bc, NC, bv, NV, pd.eye, 20.0f, 0u, s, bd, bg), GIM_OK);
    gltest_read_buffer(bd, sizeof gd, gd);
    gltest_read_buffer(bg, sizeof gg, gg);
    for (i = 0; i < NC; ++i)
        for (k = 0; k < 3; ++k) {
            double rd = fabs((double)gd[i].flux[k] - cd[i].flux[k]) / (cd[i].flux[k] > 0.0f ? cd[i].flux[k] : 1.0);
            double rg = fabs((double)gg[i].flux[k] - cg[i].flux[k]) / (cg[i].flux[k] > 0.0f ? cg[i].flux[k] : 1.0);
            assert_true(finite_nonneg(gd[i].flux[k]) && finite_nonneg(gg[i].flux[k]));
            assert_true(isfinite(gd[i].position[k]) && isfinite(gg[i].position[k]));
            if (k == 0) print_message("cache %u: diffuse flux GPU %g twin %g (rel %.1e), glossy %g / %g (rel %.1e)\n",
                                      (unsigned)i, (double)gd[i].flux[0], (double)cd[i].flux[0], rd, (double)gg[i].flux[0],
                                      (double)cg[i].flux[0], rg);
            assert_true(rd < 1e-3 && rg < 1e-3);
        }
    glDeleteBuffers(1, &bc); glDeleteBuffers(1, &bv); glDeleteBuffers(1, &bd); glDeleteBuffers(1, &bg);
    gltest_fixture_end(&f);
    GLTEST_END();
}

/* --- materials ---------------------------------------------------------------------------- */

/* The room (side 1, sun) with its materials replaced. */
static void room_with(ex *e, const gim_material *m, uint32_t count, ex_out *out) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    geo g;
    ex_begin(e);
    geo_room(&g, 1.0, o0);
    ex_add(e, &g, 1.0 / 8.0);
    assert_int_equal(gim_set_materials(e->f.ctx, m, count), GIM_OK);
    e->light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e->fr, 1.0, o0);
    e->fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e->fr.indirect_float32 = 1;
    ex_frame(e, out);
}

/* Keep only the back wall's pixels (normal +z) of o, for comparisons. */
static uint32_t back_wall_only(ex_out *o) {
    uint32_t i, n = 0;
    for (i = 0; i < NPIX; ++i) {
        if (o->nrm[i * 4 + 2] > 0.999f) n++;
        else o->nrm[i * 4 + 3] = 0.0f;
    }
    return n;
}

/* Albedo 0 everywhere: no flux anywhere, an image of exact zeros. Albedo 1 against 0.2: the
   bounce is linear in the albedo at both ends (RSM flux and receiver), so 25 times the image
   (51/255 = 0.2 is exact in the RGBA8 G-buffer), within float rounding (1e-5). A glossy
   colour without diffuse, exponent 0: the lobe is the constant 1 and (k + 2) / (2 pi) = 1 /
   pi, so the glossy proxy lights are the diffuse ones and the back wall (coplanar caches and
   pixels: the mirrored directions of eq. 8 equal the normals' cosine 1) shows exactly the
   image of the same colour as diffuse albedo (measured 5e-7). Exponents 1 and 1e4: finite and
   non-negative everywhere, proxies included. */
static void materials_at_the_ends(void **state) {
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    gim_material m[4];
    ex_diff d;
    uint32_t i, k;
    (void)state;
    GLTEST_BEGIN();
    memset(m, 0, sizeof m);
    room_with(&e, m, 4, a);
    ex_end(&e);
    print_message("albedo 0: max %g, VAL flux %g, proxy flux %g\n", a->max, a->val_flux, a->proxy_flux);
    assert_true(a->max == 0.0 && a->val_flux == 0.0 && a->proxy_flux == 0.0);
    for (i = 0; i < 4; ++i) m[i].diffuse[0] = m[i].diffuse[1] = m[i].diffuse[2] = 0.2f;
    room_with(&e, m, 4, a);
    ex_end(&e);
    for (i = 0; i < 4; ++i) m[i].diffuse[0] = m[i].diffuse[1] = m[i].diffuse[2] = 1.0f;
    room_with(&e, m, 4, b);
    ex_end(&e);
    for (i = 0; i < NPIX * 4; ++i) a->img[i] *= 25.0f;
    a->max *= 25.0;
    d = ex_compare(b, a, 1e-3, 1e-4);
    print_message("albedo 1 vs 25 x albedo 0.2: max rel %.2e, mean rel %.2e, %u above 1e-4\n", d.max_rel, d.mean_rel, d.above);
    assert_true(b->lit > b->drawn / 2);
    assert_true(d.mean_rel < 1e-5 && d.above == 0);

    memcpy(m, room_materials, sizeof m);
    room_with(&e, m, 4, a);                                /* back wall: diffuse 0.6 */
    ex_end(&e);
    m[3].diffuse[0] = m[3].diffuse[1] = m[3].diffuse[2] = 0.0f;
    m[3].glossy[0] = m[3].glossy[1] = m[3].glossy[2] = 0.6f;
    m[3].exponent = 0.0f;
    room_with(&e, m, 4, b);                                /* back wall: glossy 0.6, k = 0 */
    assert_true(gim_debug(e.f.ctx).proxy_glossy != 0 && gim_debug(e.f.ctx).glossy_exponent == 0.0f);
    ex_end(&e);
    k = back_wall_only(a);
    back_wall_only(b);
    d = ex_compare(b, a, 1e-3, 1e-4);
    print_message("glossy without diffuse, k = 0, vs diffuse (%u back wall pixels): max rel %.2e, mean rel %.2e\n", k,
                  d.max_rel, d.mean_rel);
    assert_true(k > NPIX / 8 && a->max > 0.0);
    assert_true(d.mean_rel < 1e-5 && d.above == 0);
    {
        static const float ks[3] = {1.0f, 1e4f, 1e6f};
        for (i = 0; i < 3; ++i) {
            m[3].exponent = ks[i];
            m[3].diffuse[0] = m[3].diffuse[1] = m[3].diffuse[2] = 0.2f;
            room_with(&e, m, 4, b);
            assert_true(gim_debug(e.f.ctx).glossy_exponent == ks[i]);
            ex_end(&e);
            print_message("glossy exponent %g: %u lit of %u, max %g\n", (double)ks[i], b->lit, b->drawn, b->max);
            assert_true(b->lit > b->drawn / 2);
        }
    }
    free(a);
    free(b);
    GLTEST_END();
}

/* --- sizes and counts ------------------------------------------------------------------------ */

/* RSMs of 1^2 (one VAL for the whole light) and 2048^2 (BRSM; 4M texels); more VALs than
   texels, where BRSM's picks repeat with weights 1 / (N P) and the mean approaches FULL;
   one view sample; one neighbour; a one-triangle mesh (a plane cannot light itself: zero). */
static void sizes_and_counts(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    ex_diff d;
    int light;
    (void)state;
    GLTEST_BEGIN();
    for (light = 0; light < 2; ++light) {
        room_at(&e, 1.0, o0, light, GIM_METHOD_LIGHTSKIN_FULL, a);
        e.light.rsm_size = 1;
        ex_frame(&e, a);
        assert_int_equal(gim_debug(e.f.ctx).val_count, 1);
        e.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
        e.fr.lightskin.val_count = 100;
        ex_frame(&e, b);
        print_message("RSM 1^2 %s: FULL %u lit, max %g; BRSM x100 %u lit, max %g\n", light ? "spot" : "sun", a->lit, a->max,
                      b->lit, b->max);
        d = ex_compare(b, a, 1e-3, 1e-4);      /* 100 picks of the one texel, weight 1 / 100 each */
        assert_true(d.mean_rel < 1e-5);
        ex_end(&e);
    }
    /* more VALs than texels: 8^2 texels, 8192 picks */
    room_at(&e, 1.0, o0, 1, GIM_METHOD_LIGHTSKIN_FULL, a);
    e.light.rsm_size = 8;
    ex_frame(&e, a);
    e.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    e.fr.lightskin.val_count = 8192;
    ex_frame(&e, b);
    d = ex_compare(b, a, 1e-3, 1e-2);
    print_message("RSM 8^2, 8192 VALs vs FULL: max rel %.2e, mean rel %.2e, %u above 1e-2\n", d.max_rel, d.mean_rel, d.above);
    assert_true(d.mean_rel < 5e-3);
    /* one view sample, one neighbour */
    e.fr.lightskin.val_count = 256;
    e.fr.lightskin.view_sample_count = 1;
    ex_frame(&e, b);
    print_message("1 view sample: %u lit, max %g, warnings %u\n", b->lit, b->max, b->warnings);
    e.fr.lightskin.view_sample_count = 64;
    e.fr.lightskin.neighbour_count = 1;
    ex_frame(&e, b);
    print_message("1 neighbour: %u lit, max %g\n", b->lit, b->max);
    assert_true(b->lit > b->drawn / 2);
    /* 2048^2, BRSM: the largest RSM llvmpipe holds quickly (4M texels x 52 bytes + 48 MB of tables) */
    e.light.rsm_size = 2048;
    e.fr.lightskin.neighbour_count = 0;
    e.fr.lightskin.view_sample_count = 16;
    e.fr.lightskin.val_count = 1024;
    ex_frame(&e, b);
    print_message("RSM 2048^2 BRSM: %u lit, max %g\n", b->lit, b->max);
    assert_true(b->lit > b->drawn / 2);
    {   /* beyond the GL limit: refused, logged, nothing changed */
        GLint max_tex = 0;
        int errors = e.f.log.errors;
        glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
        e.light.rsm_size = (uint32_t)max_tex + 1u;
        if (max_tex < 16384) {
            assert_int_equal(gim_set_lights(e.f.ctx, &e.light, 1), GIM_ERROR_OUT_OF_RANGE);
            assert_int_equal(e.f.log.errors, errors + 1);
            e.f.log.errors = errors;
        }
        assert_int_equal(gim_update(e.f.ctx, &e.fr), GIM_OK);
        assert_int_equal(gim_outputs(e.f.ctx).lights[0].rsm_size, 2048);
    }
    ex_end(&e);
    /* one triangle with its caches: it cannot light itself */
    {
        geo g;
        double c[3], u[3], v[3];
        ex_begin(&e);
        memset(&g, 0, sizeof g);
        SET3(c, 0, 0, 0); SET3(u, 0, 0, 1); SET3(v, 1, 0, 0); geo_quad(&g, c, u, v, 0);
        g.quads = 0;
        {
            gim_mesh_desc md;
            gim_cache_desc cd;
            memset(&cd, 0, sizeof cd);
            cd.mesh = geo_mesh(&g);
            cd.mesh.vertex_count = 4;
            cd.mesh.index_count = 3;
            cd.env = e.f.env;
            assert_int_equal(gim_cache_generate(&cd, &e.set[0]), GIM_OK);
            e.has_set[0] = 1;
            memset(&md, 0, sizeof md);
            md.data = cd.mesh;
            md.caches = &e.set[0];
            assert_int_equal(gim_add_mesh(e.f.ctx, &md, &e.mesh[0]), GIM_OK);
            e.mesh_count = 1;
            e.inst[0].mesh = e.mesh[0];
            e.inst[0].model = gim_mat4_identity();
            e.inst_count = 1;
        }
        assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 1), GIM_OK);
        e.light = sun(3.0f, gim_v3(0.2f, 1.0f, 0.3f), 16);
        SET3(c, 0.3, 1.0, 1.5); SET3(u, 0.0, -1.0, -1.3);
        e.fr.view = look_along(c, u);
        e.fr.proj = gim_mat4_perspective(1.0f, (float)W / H, 0.05f, 10.0f);
        e.fr.width = W; e.fr.height = H;
        ex_frame(&e, b);
        print_message("one triangle: %u caches, %u pixels drawn, max %g, VAL flux %g\n", e.set[0].count, b->drawn, b->max,
                      b->val_flux);
        assert_true(b->drawn > 100 && b->val_flux > 0.0 && b->max == 0.0);
        ex_end(&e);
    }
    free(a);
    free(b);
    GLTEST_END();
}

/* A room whose walls have no caches next to a floor that has: the floor still
   gathers the walls' light (their VALs are in the RSM) and matches the all-cached room where
   its neighbours are the same floor caches (within 1e-3 on 95% of the floor pixels: the cell
   of the hash grid, hence the search radius, follows the caches' mean area); the walls, with
   no compatible cache near, stay dark. And an instance with a non-uniform scale and a rotation
   (normals through the inverse transpose, cache areas through |det M| |M^-T n|) against the
   same room transformed on the CPU: the same image within float rounding. */
static void partial_caches_and_nonuniform_scale(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    ex_diff d;
    geo g, floor_g, walls_g;
    uint32_t i, q, floor_px = 0, wall_lit = 0, wall_px = 0;
    (void)state;
    GLTEST_BEGIN();
    geo_room(&g, 1.0, o0);
    g.quads = 4;                      /* the floor and the three walls, no block */
    ex_begin(&e);
    ex_add(&e, &g, 1.0 / 8.0);
    assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
    e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e.fr, 1.0, o0);
    e.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e.fr.indirect_float32 = 1;
    ex_frame(&e, a);
    ex_end(&e);
    memset(&floor_g, 0, sizeof floor_g);
    memset(&walls_g, 0, sizeof walls_g);
    for (q = 0; q < g.quads; ++q) {   /* quads 1-3 are the walls */
        geo *t = (q >= 1 && q <= 3) ? &walls_g : &floor_g;
        double c[3], u[3], v[3];
        int k;
        for (k = 0; k < 3; ++k) {
            c[k] = g.pos[q * 12 + k];
            u[k] = (double)g.pos[q * 12 + 3 + k] - g.pos[q * 12 + k];
            v[k] = (double)g.pos[q * 12 + 9 + k] - g.pos[q * 12 + k];
        }
        geo_quad(t, c, u, v, g.mat[q * 2]);
    }
    ex_begin(&e);
    ex_add(&e, &floor_g, 1.0 / 8.0);
    ex_add(&e, &walls_g, 0.0);
    assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
    e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e.fr, 1.0, o0);
    e.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e.fr.indirect_float32 = 1;
    ex_frame(&e, b);
    ex_end(&e);
    for (i = 0; i < NPIX; ++i) {
        if (b->nrm[i * 4 + 3] != 1.0f) continue;
        if (b->nrm[i * 4 + 1] > 0.999f) { floor_px++; continue; }
        a->nrm[i * 4 + 3] = 0.0f;   /* compare the floor only */
        wall_px++;
        if (b->img[i * 4] + b->img[i * 4 + 1] + b->img[i * 4 + 2] > 0.0f) wall_lit++;
    }
    d = ex_compare(b, a, 1e-3, 1e-3);
    print_message("walls without caches: %u wall pixels (%u lit), %u floor pixels: max rel %.2e, mean rel %.2e, %u above 1e-3\n",
                  wall_px, wall_lit, floor_px, d.max_rel, d.mean_rel, d.above);
    assert_true(floor_px > NPIX / 8 && wall_px > NPIX / 8);
    assert_int_equal(wall_lit, 0);
    assert_true(d.above <= d.pixels / 20 && d.mean_rel < 1e-2);

    {   /* non-uniform scale and rotation */
        gim_mat4 rot = gim_mat4_identity(), sc = gim_mat4_identity(), model;
        gim_cache *wc;
        gim_cache_set ws;
        float ca = cosf(0.4f), sa = sinf(0.4f);
        rot.m[0] = ca; rot.m[2] = -sa; rot.m[8] = sa; rot.m[10] = ca;
        sc.m[0] = 1.5f; sc.m[5] = 0.8f; sc.m[10] = 1.1f;
        model = gim_mat4_mul(sc, rot);
        ex_begin(&e);
        ex_add(&e, &g, 1.0 / 8.0);
        e.inst[0].model = model;
        assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
        e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
        room_camera(&e.fr, 1.2, o0);
        e.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
        e.fr.indirect_float32 = 1;
        ex_frame(&e, a);
        /* the same room placed on the CPU: positions, normals (M^-T) and caches in world space */
        wc = (gim_cache *)malloc(e.set[0].count * sizeof *wc);
        assert_int_equal(gim_caches_to_world(e.set[0].caches, e.set[0].count, model, wc, e.f.env), GIM_OK);
        {
            gim_mat4 nm = gim__mat4_normal(model);
            gim_mesh_desc md;
            for (i = 0; i < g.quads * 4; ++i) {
                gim_vec3 p = gim_mat4_point(model, gim_v3(g.pos[i * 3], g.pos[i * 3 + 1], g.pos[i * 3 + 2]));
                gim_vec3 n = gim_v3_normalize(gim__mat4_dir(nm, gim_v3(g.nrm[i * 3], g.nrm[i * 3 + 1], g.nrm[i * 3 + 2])));
                g.pos[i * 3] = p.x; g.pos[i * 3 + 1] = p.y; g.pos[i * 3 + 2] = p.z;
                g.nrm[i * 3] = n.x; g.nrm[i * 3 + 1] = n.y; g.nrm[i * 3 + 2] = n.z;
            }
            ws = e.set[0];
            ws.caches = wc;
            memset(&md, 0, sizeof md);
            md.data = geo_mesh(&g);
            md.caches = &ws;
            assert_int_equal(gim_add_mesh(e.f.ctx, &md, &e.mesh[1]), GIM_OK);
            e.mesh_count = 2;
            e.inst[0].mesh = e.mesh[1];
            e.inst[0].model = gim_mat4_identity();
        }
        ex_frame(&e, b);
        ex_end(&e);
        free(wc);
        d = ex_compare(a, b, 1e-3, 1e-3);
        print_message("non-uniform scale instance vs placed on the CPU: %u pixels, %u lit, max rel %.2e, mean rel %.2e, %u above 1e-3\n",
                      d.pixels, a->lit, d.max_rel, d.mean_rel, d.above);
        assert_true(a->lit > a->drawn / 2 && d.pixels > NPIX / 4);
        assert_true(d.mean_rel < 1e-4 && d.above <= d.pixels / 200);
    }
    free(a);
    free(b);
    GLTEST_END();
}

/* A million triangles: the room's floor as a 708 x 708 grid of quads (1,002,528 triangles,
   32-bit indices, caches generated from it) against the same room with a one-quad floor. The
   surface is the same, so are its caches up to rounding, and the images agree (mean < 1e-5,
   no pixel above 1e-4; measured max 8e-6). ~5 s under ASan on llvmpipe. */
static void million_triangles(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    enum { N = 708 };
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    geo g, walls;
    uint32_t nv = (N + 1) * (N + 1), nt = N * N * 2, i, j, t = 0, q;
    float *pos = (float *)malloc((size_t)nv * 12u), *nrm = (float *)malloc((size_t)nv * 12u);
    uint32_t *idx = (uint32_t *)malloc((size_t)nt * 12u);
    gim_mesh_data md;
    ex_diff d;
    (void)state;
    GLTEST_BEGIN();
    geo_room(&g, 1.0, o0);
    g.quads = 4;                                   /* floor and walls, no block */
    memset(&walls, 0, sizeof walls);
    for (q = 1; q < 4; ++q) {
        double c[3], u[3], v[3];
        int k;
        for (k = 0; k < 3; ++k) {
            c[k] = g.pos[q * 12 + k];
            u[k] = (double)g.pos[q * 12 + 3 + k] - g.pos[q * 12 + k];
            v[k] = (double)g.pos[q * 12 + 9 + k] - g.pos[q * 12 + k];
        }
        geo_quad(&walls, c, u, v, g.mat[q * 2]);
    }
    ex_begin(&e);                                  /* the one-quad floor */
    ex_add(&e, &g, 1.0 / 8.0);
    assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
    e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e.fr, 1.0, o0);
    e.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e.fr.indirect_float32 = 1;
    ex_frame(&e, a);
    ex_end(&e);
    for (j = 0; j <= N; ++j)
        for (i = 0; i <= N; ++i) {
            float *p = pos + 3 * (j * (N + 1) + i), *n = nrm + 3 * (j * (N + 1) + i);
            p[0] = (float)i / N; p[1] = 0.0f; p[2] = (float)j / N;
            n[0] = 0.0f; n[1] = 1.0f; n[2] = 0.0f;
        }
    for (j = 0; j < N; ++j)
        for (i = 0; i < N; ++i) {
            uint32_t v0 = j * (N + 1) + i;
            idx[t++] = v0; idx[t++] = v0 + N + 1; idx[t++] = v0 + 1;
            idx[t++] = v0 + 1; idx[t++] = v0 + N + 1; idx[t++] = v0 + N + 2;
        }
    ex_begin(&e);
    memset(&md, 0, sizeof md);
    md.positions = pos; md.normals = nrm; md.vertex_count = nv; md.indices = idx; md.index_count = nt * 3;
    {
        gim_cache_desc cd;
        gim_mesh_desc mdesc;
        memset(&cd, 0, sizeof cd);
        cd.mesh = md;
        cd.d_eps = 1.0f / 8.0f;
        cd.env = e.f.env;
        assert_int_equal(gim_cache_generate(&cd, &e.set[0]), GIM_OK);
        e.has_set[0] = 1;
        memset(&mdesc, 0, sizeof mdesc);
        mdesc.data = md;
        mdesc.caches = &e.set[0];
        assert_int_equal(gim_add_mesh(e.f.ctx, &mdesc, &e.mesh[0]), GIM_OK);
        e.mesh_count = 1;
        e.inst[0].mesh = e.mesh[0];
        e.inst[0].model = gim_mat4_identity();
        e.inst_count = 1;
    }
    ex_add(&e, &walls, 1.0 / 8.0);
    assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 4), GIM_OK);
    e.light = sun(3.0f, gim_v3(0.3f, 1.0f, 0.45f), 32);
    room_camera(&e.fr, 1.0, o0);
    e.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    e.fr.indirect_float32 = 1;
    ex_frame(&e, b);
    d = ex_compare(b, a, 1e-3, 1e-4);
    print_message("1M-triangle floor (%u caches) vs one quad: %u pixels, max rel %.2e, mean rel %.2e, %u above 1e-4\n",
                  e.set[0].count, d.pixels, d.max_rel, d.mean_rel, d.above);
    assert_true(d.pixels > NPIX / 2 && b->lit > b->drawn / 2);
    /* the same light to float rounding, and to the rasteriser's: H100 / driver 580 gives mean
       1.4e-4, max 1.0e-3 (462 pixels above 1e-4), llvmpipe mean < 1e-5 and none above 1e-4. The
       likely cause (not isolated): vertices snapped to 1 / 2^GL_SUBPIXEL_BITS of a pixel move a
       sub-pixel triangle's plane equations, so the depth and position a pixel reads */
    {
        GLint bits = 0;
        glGetIntegerv(GL_SUBPIXEL_BITS, &bits);
        print_message("GL_SUBPIXEL_BITS %d\n", (int)bits);
    }
    assert_true(d.mean_rel < 5e-4 && d.max_rel < 5e-3);
    ex_end(&e);
    free(pos); free(nrm); free(idx); free(a); free(b);
    GLTEST_END();
}

/* --- the light ---------------------------------------------------------------------------- */

/* Zero power: every output exactly zero (the importance map too: the selection goes uniform).
   (gim_update refuses a light bringing more than 1e36 into the scene; tested at the end.)
   1e-30 and 1e30 (E and I): one bounce is linear in the light, so the image is the image of
   power 1 times the power, within 1e-4 relative (float32 output), until a sum leaves the float
   range. The default RGBA16F output holds at most 65504: the 1e30 frame must not store Inf. */
static void light_power_range(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    static const float powers[3] = {1e-30f, 1e30f, 0.0f};
    ex e;
    ex_out *a = (ex_out *)malloc(sizeof *a), *b = (ex_out *)malloc(sizeof *b);
    int light, k;
    (void)state;
    GLTEST_BEGIN();
    for (light = 0; light < 2; ++light) {
        room_at(&e, 1.0, o0, light, GIM_METHOD_LIGHTSKIN_BRSM, a);   /* the reference, power 1 */
        if (light) e.light.intensity = 1.0f; else e.light.irradiance = 1.0f;
        ex_frame(&e, a);
        for (k = 0; k < 3; ++k) {
            ex_diff d;
            uint32_t i;
            if (light) e.light.intensity = powers[k]; else e.light.irradiance = powers[k];
            ex_frame(&e, b);
            if (powers[k] == 0.0f) {
                print_message("%s power 0: max %g, VAL flux %g, proxy flux %g\n", light ? "spot" : "sun", b->max, b->val_flux,
                              b->proxy_flux);
                assert_true(b->max == 0.0 && b->val_flux == 0.0 && b->proxy_flux == 0.0);
                continue;
            }
            for (i = 0; i < NPIX * 4; ++i) b->img[i] = (float)((double)b->img[i] / powers[k]);
            b->max /= powers[k];
            d = ex_compare(b, a, 1e-3, 1e-4);
            print_message("%s power %g / %g: max rel %.2e, mean rel %.2e, %u above 1e-4\n", light ? "spot" : "sun",
                          (double)powers[k], 1.0, d.max_rel, d.mean_rel, d.above);
            assert_true(d.mean_rel < 1e-5 && d.above <= d.pixels / 200);
        }
        /* RGBA16F at 1e30: clamped to the format's largest value, never Inf */
        e.fr.indirect_float32 = 0;
        if (light) e.light.intensity = 1e30f; else e.light.irradiance = 1e30f;
        ex_frame(&e, b);
        print_message("%s 1e30 into RGBA16F: max %g, %u lit\n", light ? "spot" : "sun", b->max, b->lit);
        assert_true(b->max == 65504.0 && b->lit > b->drawn / 2);
        ex_end(&e);
    }
    /* the power a light brings into the scene (E diagonal^2, 4 pi I) is linear up to 1e36 and
       refused above (measured: 1e36 within 1.1e-6; 1e38 saturates the image at FLT_MAX) */
    room_at(&e, 1e8, o0, 0, GIM_METHOD_LIGHTSKIN_FULL, a);
    e.light.irradiance = 1.0f;
    ex_frame(&e, a);
    e.light.irradiance = 3e19f;                          /* 3e19 x (1.7e8)^2 = 9e35 */
    ex_frame(&e, b);
    {
        ex_diff d;
        uint32_t i;
        int errors;
        for (i = 0; i < NPIX * 4; ++i) b->img[i] = (float)((double)b->img[i] / 3e19);
        b->max /= 3e19;
        d = ex_compare(b, a, 1e-3, 1e-4);
        print_message("sun power 9e35 into a scene 1.7e8 across: max rel %.2e, mean rel %.2e\n", d.max_rel, d.mean_rel);
        assert_true(d.mean_rel < 1e-5 && d.above <= d.pixels / 200);
        e.light.irradiance = 1e21f;                      /* 3e37 */
        assert_int_equal(gim_set_lights(e.f.ctx, &e.light, 1), GIM_OK);
        errors = e.f.log.errors;
        assert_int_equal(gim_update(e.f.ctx, &e.fr), GIM_ERROR_OUT_OF_RANGE);
        assert_int_equal(e.f.log.errors, errors + 1);
        e.f.log.errors = 0;
    }
    ex_end(&e);
    free(a);
    free(b);
    GLTEST_END();
}

/* A sun lights a roof the camera, below it, never sees: every texel faces away from every
   view sample (importance 0 everywhere), the selection goes uniform, and the roof's light
   goes up, away from the floor below: a finite frame of zeros. */
static void light_unseen(void **state) {
    ex e;
    ex_out *o = (ex_out *)malloc(sizeof *o);
    geo g;
    double c[3], u[3], v[3];
    (void)state;
    GLTEST_BEGIN();
    ex_begin(&e);
    memset(&g, 0, sizeof g);
    SET3(c, -1, 0, -1); SET3(u, 0, 0, 2); SET3(v, 2, 0, 0); geo_quad(&g, c, u, v, 0);    /* floor */
    SET3(c, -2, 1, -2); SET3(u, 0, 0, 4); SET3(v, 4, 0, 0); geo_quad(&g, c, u, v, 0);    /* roof over it */
    ex_add(&e, &g, 0.2);
    assert_int_equal(gim_set_materials(e.f.ctx, room_materials, 1), GIM_OK);
    e.light = sun(5.0f, gim_v3(0.1f, 1.0f, 0.2f), 32);
    SET3(c, 0.0, 0.6, 0.0); SET3(u, 0.1, -1.0, 0.05);
    e.fr.view = look_along(c, u);
    e.fr.proj = gim_mat4_perspective(1.2f, (float)W / H, 0.05f, 5.0f);   /* the roof is behind the eye */
    e.fr.width = W; e.fr.height = H;
    e.fr.lightskin.val_count = 256;
    e.fr.lightskin.view_sample_count = 64;
    ex_frame(&e, o);
    {
        gim_frame_outputs fo = gim_outputs(e.f.ctx);
        float map[32 * 32];
        gim_selected_val sel[256];
        uint32_t i;
        double s = 0.0;
        /* the importance: per texel, or of the two-level map's tiles (its texel weights are fluxes) */
        uint32_t side = 31u / fo.lights[0].importance_tile + 1u, cells = side * side;
        gltest_read_buffer(fo.lights[0].importance_tiles ? fo.lights[0].importance_tiles : fo.lights[0].importance,
                           cells * sizeof(float), map);
        for (i = 0; i < cells; ++i) s += map[i];
        gltest_read_buffer(fo.lights[0].selected, sizeof sel, sel);
        print_message("unseen light: importance sum %g, pdf %g (uniform %g), VAL flux %g, image max %g\n", s,
                      (double)sel[0].pdf, 1.0 / 1024.0, o->val_flux, o->max);
        assert_true(s == 0.0 && o->val_flux > 0.0 && o->max == 0.0 && o->drawn > NPIX / 2);
        for (i = 0; i < 256; ++i) assert_true(sel[i].pdf == 1.0f / 1024.0f);
    }
    ex_end(&e);
    free(o);
    GLTEST_END();
}

/* --- hostile arguments ------------------------------------------------------------------- */

/* What tests/gl/gltest_scene.c's argument_errors does not already try: Inf (not only NaN) in
   every matrix, NaN/Inf in every float of a light, material, frame and cache, zero and
   over-the-limit heights, a NULL context or output for every entry point. Each is an error
   with exactly one log line (none for a NULL context: it has no logger), leaves the GL state
   and the scene as they were, and the context renders a good frame afterwards. */
static void hostile_arguments(void **state) {
    static const double o0[3] = {0.0, 0.0, 0.0};
    ex e;
    ex_out *o = (ex_out *)malloc(sizeof *o);
    gim_frame fr;
    gim_light l;
    gim_material m;
    gim_instance in;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_stats st;
    int errors, k;
    GLint max_tex = 0;
    const float bad[3] = {NAN, INFINITY, -INFINITY};
    (void)state;
    memset(&md, 0, sizeof md); /* the NULL-context and NULL-out calls below must fail on those alone */
    GLTEST_BEGIN();
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    ex_begin(&e);
    /* before any frame: no stats */
    errors = e.f.log.errors;
#define EXPECT(call, code) do { assert_int_equal((call), (code)); assert_int_equal(e.f.log.errors, ++errors); } while (0)
    EXPECT(gim_frame_stats(e.f.ctx, &st), GIM_ERROR_INVALID_ARGUMENT);
    e.f.log.errors = 0;
    ex_end(&e);
    room_at(&e, 1.0, o0, 1, GIM_METHOD_LIGHTSKIN_BRSM, o);
    errors = e.f.log.errors;
    /* NULL context: an error, no crash, nothing to log through */
    assert_int_equal(gim_update(NULL, &e.fr), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_set_lights(NULL, &e.light, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_set_materials(NULL, room_materials, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_set_instances(NULL, e.inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_add_mesh(NULL, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_remove_mesh(NULL, e.mesh[0]), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_frame_stats(NULL, &st), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_outputs(NULL).valid, 0);
    gim_destroy(NULL);
    assert_int_equal(e.f.log.errors, errors);
    EXPECT(gim_frame_stats(e.f.ctx, NULL), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_add_mesh(e.f.ctx, &md, NULL), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_set_materials(e.f.ctx, NULL, 2), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_set_lights(e.f.ctx, NULL, 1), GIM_ERROR_INVALID_ARGUMENT);
    {
        gim_mesh none;
        none.id = 0;
        EXPECT(gim_remove_mesh(e.f.ctx, none), GIM_ERROR_INVALID_ARGUMENT);
    }
    /* frames: Inf and NaN anywhere in view and proj; zero and over-the-limit sizes; bad floats */
    for (k = 0; k < 3; ++k) {
        int entry;
        for (entry = 0; entry < 16; entry += 5) {
            fr = e.fr; fr.view.m[entry] = bad[k];
            EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
            fr = e.fr; fr.proj.m[entry] = bad[k];
            EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
        }
        fr = e.fr; fr.scene_scale = bad[k];
        EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
        fr = e.fr; fr.lightskin.importance_clamp = bad[k];
        EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    }
    fr = e.fr; fr.view = gim_mat4_mul(fr.view, gim_mat4_ortho(1, 1, -1, 1, -1, 1));   /* finite, not invertible */
    EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr = e.fr; fr.height = 0;
    EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr = e.fr; fr.height = (uint32_t)max_tex + 1u;
    EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr = e.fr; fr.width = 0xFFFFFFFFu;
    EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr = e.fr; fr.lightskin.importance_clamp = -1.0f;
    EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    /* instances: Inf in the model */
    in = e.inst[0];
    in.model.m[14] = INFINITY;
    EXPECT(gim_set_instances(e.f.ctx, &in, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* materials: NaN/Inf in any float, negative glossy, exponent beyond 1e6 */
    for (k = 0; k < 3; ++k) {
        m = room_materials[0]; m.diffuse[2] = bad[k];
        EXPECT(gim_set_materials(e.f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
        m = room_materials[0]; m.glossy[0] = bad[k];
        EXPECT(gim_set_materials(e.f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
        m = room_materials[0]; m.exponent = bad[k];
        EXPECT(gim_set_materials(e.f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
    }
    m = room_materials[0]; m.glossy[1] = -0.1f;
    EXPECT(gim_set_materials(e.f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
    m = room_materials[0]; m.exponent = 2e6f;
    EXPECT(gim_set_materials(e.f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* lights: NaN/Inf in every float of both kinds */
    for (k = 0; k < 3; ++k) {
        l = e.light; l.intensity = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
        l = e.light; l.color[1] = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
        l = e.light; l.cone_angle = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
        l = e.light; l.direction.z = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
        l = sun(1.0f, gim_v3(0, 1, 0), 16); l.irradiance = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
        l = sun(1.0f, gim_v3(0, 1, 0), 16); l.extent = bad[k];
        EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    }
    l = e.light; l.color[0] = -1.0f;
    EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l = e.light; l.intensity = -1e-30f;
    EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l = sun(1.0f, gim_v3(0, 1, 0), 16); l.extent = -1.0f;
    EXPECT(gim_set_lights(e.f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* meshes: NaN normals, caches with a NaN area, a zero normal, theta_eps beyond pi/2 */
    {
        geo g;
        double c[3], u[3], v[3];
        gim_cache_set cs;
        gim_cache cc[2];
        memset(&g, 0, sizeof g);
        SET3(c, 0, 0, 0); SET3(u, 0, 0, 1); SET3(v, 1, 0, 0); geo_quad(&g, c, u, v, 0);
        memset(&md, 0, sizeof md);
        md.data = geo_mesh(&g);
        g.nrm[4] = NAN;
        EXPECT(gim_add_mesh(e.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        g.nrm[4] = 1.0f;
        memset(cc, 0, sizeof cc);
        memset(&cs, 0, sizeof cs);
        cc[0].normal[1] = cc[1].normal[1] = 1.0f;
        cc[0].area = cc[1].area = 0.5f;
        cs.caches = cc;
        cs.count = 2;
        md.caches = &cs;
        for (k = 0; k < 3; ++k) {
            cc[1].area = bad[k];
            EXPECT(gim_add_mesh(e.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        }
        cc[1].area = 0.5f;
        cc[1].normal[1] = 0.0f;
        EXPECT(gim_add_mesh(e.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        cc[1].normal[1] = 1.0f;
        cs.theta_eps = 2.0f;
        EXPECT(gim_add_mesh(e.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        cs.theta_eps = 0.5f;
        assert_int_equal(gim_add_mesh(e.f.ctx, &md, &mesh), GIM_OK);
        assert_int_equal(gim_remove_mesh(e.f.ctx, mesh), GIM_OK);
    }
    {   /* the host's G-buffer: too small is refused; NaN, Inf and zero normals and depths of
           0 and 1 are not errors (a host's data) but must not reach the image as NaN */
        GLuint tex[2];
        float *dep = (float *)malloc(NPIX * 4), *nor = (float *)malloc(NPIX * 16);
        uint32_t i;
        glGenTextures(2, tex);
        glBindTexture(GL_TEXTURE_2D, tex[0]);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_DEPTH_COMPONENT32F, 8, 8);
        glBindTexture(GL_TEXTURE_2D, tex[1]);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, 8, 8);
        fr = e.fr;
        fr.gbuffer.depth = tex[0];
        fr.gbuffer.normal = tex[1];
        EXPECT(gim_update(e.f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
        glDeleteTextures(2, tex);
        glGenTextures(2, tex);
        for (i = 0; i < NPIX; ++i) {
            static const float odd[6] = {NAN, INFINITY, 0.0f, -INFINITY, 1e30f, 1.0f};
            /* gimany's own G-buffer of this view (read back into o), then spoilt */
            dep[i] = i % 7 == 0 ? 1.0f : i % 11 == 0 ? 0.0f : o->depth[i];
            memcpy(nor + i * 4, o->nrm + i * 4, 16);
            if (i % 3 == 0) nor[i * 4] = odd[i % 6];
            if (i % 5 == 0) nor[i * 4 + 2] = odd[(i / 5) % 6];
        }
        glBindTexture(GL_TEXTURE_2D, tex[0]);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_DEPTH_COMPONENT32F, W, H);
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, W, H, GL_DEPTH_COMPONENT, GL_FLOAT, dep);
        glBindTexture(GL_TEXTURE_2D, tex[1]);
        glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, W, H);
        glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, W, H, GL_RGBA, GL_FLOAT, nor);
        glBindTexture(GL_TEXTURE_2D, 0);
        e.fr.gbuffer.depth = tex[0];
        e.fr.gbuffer.normal = tex[1];
        e.host_gbuffer = 1;
        ex_frame(&e, o);
        print_message("hostile host G-buffer: %u lit, max %g\n", o->lit, o->max);
        assert_true(o->lit > NPIX / 4);    /* the pixels whose normal is usable */
        e.fr.gbuffer.depth = e.fr.gbuffer.normal = 0;
        e.host_gbuffer = 0;
        glDeleteTextures(2, tex);
        free(dep);
        free(nor);
        room_camera(&e.fr, 1.0, o0);
        ex_frame(&e, o);   /* the reference frame again, gimany's G-buffer */
    }
#undef EXPECT
    gltest_state_unchanged(&e.f);
    /* the scene is as it was: the same frame renders, lit, with its outputs sound */
    {
        ex_out *again = (ex_out *)malloc(sizeof *again);
        ex_diff d;
        ex_frame(&e, again);
        d = ex_compare(again, o, 1e-3, 0.0);
        assert_true(again->lit > again->drawn / 2 && d.max_rel == 0.0);
        assert_int_equal(gim_frame_stats(e.f.ctx, &st), GIM_OK);
        free(again);
    }
    e.f.log.errors = 0;
    ex_end(&e);
    free(o);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(scale_invariance),
        cmocka_unit_test(far_from_origin),
        cmocka_unit_test(grazing_sun),
        cmocka_unit_test(near_plane_and_coincident_caches),
        cmocka_unit_test(val_on_cache),
        cmocka_unit_test(materials_at_the_ends),
        cmocka_unit_test(sizes_and_counts),
        cmocka_unit_test(partial_caches_and_nonuniform_scale),
        cmocka_unit_test(million_triangles),
        cmocka_unit_test(light_power_range),
        cmocka_unit_test(light_unseen),
        cmocka_unit_test(hostile_arguments),
    };
    int r;
    if (getenv("GIMANY_TEST_FILTER")) cmocka_set_test_filter(getenv("GIMANY_TEST_FILTER"));  /* one case while iterating */
    r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
