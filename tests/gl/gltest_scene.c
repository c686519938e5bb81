/* The scene API and the shared passes of the frame (docs/design.md sec. 3): RSM per light,
   G-buffer, view samples, chained into the importance passes, against their CPU twins
   (gim_rsm_texel_twin, gim_gbuffer_texel_twin, gim_view_samples_twin), the flux totals the
   physics fixes exactly, argument errors, allocation failures, zero GL errors throughout. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define PI_D 3.14159265358979323846

/* --- matrices and the test scene ---------------------------------------------------------- */


#define MAX_TRI 64
/* A world-space copy of everything drawn, for the twins. */
typedef struct twin_soup {
    float pos[MAX_TRI * 9], nrm[MAX_TRI * 9], alb[MAX_TRI * 3];
    uint32_t n;
} twin_soup;

static const gim_material materials[3] = {
    {{0.8f, 0.7f, 0.6f}, {0.0f, 0.0f, 0.0f}, 0.0f},
    {{0.2f, 0.5f, 0.9f}, {0.1f, 0.1f, 0.1f}, 20.0f},
    {{0.9f, 0.1f, 0.3f}, {0.0f, 0.0f, 0.0f}, 0.0f}};

/* A square [-h, h]^2 in the y = 0 plane: 4 vertices, 16-bit indices, normals (0, 2, 0) (not
   unit: the GPU and the twin normalise after interpolation). */
static const float quad_normals[12] = {0, 2, 0, 0, 2, 0, 0, 2, 0, 0, 2, 0};
static const uint16_t quad_indices[6] = {0, 1, 2, 0, 2, 3};
static void quad_positions(float h, float out[12]) {
    const float p[12] = {-h, 0, -h, -h, 0, h, h, 0, h, h, 0, -h};
    memcpy(out, p, sizeof p);
}

/* An open box [-1, 1]^3 without a bottom: 5 faces, unshared vertices, no normals (computed:
   flat), 32-bit indices, materials 1 and 2 by face. */
static float box_pos[20 * 3];
static uint32_t box_idx[30], box_mat[10];
static void make_box(void) {
    static const int faces[5][4][3] = {
        {{-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}, {1, 1, -1}},     /* top */
        {{-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}},     /* +z */
        {{1, -1, -1}, {-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}}, /* -z */
        {{1, -1, 1}, {1, -1, -1}, {1, 1, -1}, {1, 1, 1}},     /* +x */
        {{-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}}  /* -x */
    };
    int f, v;
    for (f = 0; f < 5; ++f) {
        for (v = 0; v < 4; ++v) {
            box_pos[(f * 4 + v) * 3] = (float)faces[f][v][0];
            box_pos[(f * 4 + v) * 3 + 1] = (float)faces[f][v][1];
            box_pos[(f * 4 + v) * 3 + 2] = (float)faces[f][v][2];
        }
        box_idx[f * 6] = (uint32_t)f * 4; box_idx[f * 6 + 1] = (uint32_t)f * 4 + 1; box_idx[f * 6 + 2] = (uint32_t)f * 4 + 2;
        box_idx[f * 6 + 3] = (uint32_t)f * 4; box_idx[f * 6 + 4] = (uint32_t)f * 4 + 2; box_idx[f * 6 + 5] = (uint32_t)f * 4 + 3;
        box_mat[f * 2] = box_mat[f * 2 + 1] = 1u + (uint32_t)(f & 1);
    }
}

/* Append a mesh placed by model to the twin's soup; normals NULL: face normals. */
static void soup_add(twin_soup *s, const float *pos, const float *nrm, const void *idx, int u16, uint32_t index_count,
                     const uint32_t *mat, gim_mat4 model) {
    gim_mat4 nm = gim__mat4_normal(model);
    uint32_t t, k;
    for (t = 0; t < index_count / 3; ++t) {
        float *P = s->pos + s->n * 9, *N = s->nrm + s->n * 9;
        gim_vec3 w[3];
        assert_true(s->n < MAX_TRI);
        for (k = 0; k < 3; ++k) {
            uint32_t v = u16 ? ((const uint16_t *)idx)[t * 3 + k] : ((const uint32_t *)idx)[t * 3 + k];
            w[k] = gim_mat4_point(model, gim_v3(pos[v * 3], pos[v * 3 + 1], pos[v * 3 + 2]));
            P[k * 3] = w[k].x; P[k * 3 + 1] = w[k].y; P[k * 3 + 2] = w[k].z;
            if (nrm) {
                gim_vec3 n = gim__mat4_dir(nm, gim_v3(nrm[v * 3], nrm[v * 3 + 1], nrm[v * 3 + 2]));
                N[k * 3] = n.x; N[k * 3 + 1] = n.y; N[k * 3 + 2] = n.z;
            }
        }
        if (!nrm) { /* the model-space face normal through the normal matrix, as the GPU gets it
                       (world positions far from the origin are too coarse for a cross product) */
            uint32_t v0 = ((const uint32_t *)idx)[t * 3], v1 = ((const uint32_t *)idx)[t * 3 + 1],
                     v2 = ((const uint32_t *)idx)[t * 3 + 2];
            gim_vec3 a = gim_v3(pos[v0 * 3], pos[v0 * 3 + 1], pos[v0 * 3 + 2]);
            gim_vec3 fn = gim__mat4_dir(nm, gim__v3_cross(gim__v3_sub(gim_v3(pos[v1 * 3], pos[v1 * 3 + 1], pos[v1 * 3 + 2]), a),
                                                        gim__v3_sub(gim_v3(pos[v2 * 3], pos[v2 * 3 + 1], pos[v2 * 3 + 2]), a)));
            for (k = 0; k < 3; ++k) { N[k * 3] = fn.x; N[k * 3 + 1] = fn.y; N[k * 3 + 2] = fn.z; }
        }
        memcpy(s->alb + s->n * 3, materials[mat ? mat[t] : 0].diffuse, 3 * sizeof(float));
        s->n++;
    }
}

typedef struct fixture {
    test_alloc_stats stats;
    test_log log;
    gim_context *ctx;
    gim_mesh floor, box;
    twin_soup soup;
    gim_twin_scene twin;
} fixture;

static void fixture_begin(fixture *f) {
    gim_desc d;
    memset(f, 0, sizeof *f);
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env = test_env(&f->stats, &f->log);
    assert_int_equal(gim_create(&d, &f->ctx), GIM_OK);
}

static void fixture_end(fixture *f) {
    gim_destroy(f->ctx);
    assert_int_equal(f->stats.live, 0);
}

/* The floor (half-size 2) and a rotated, non-uniformly scaled box on it, materials set.
   offset moves everything (a scene far from the origin); s scales all lengths. */
static void build_scene(fixture *f, float s, const float offset[3]) {
    gim_mesh_desc md;
    gim_instance inst[2];
    float qp[12];
    gim_mat4 place = gim_mat4_mul(translate(offset[0], offset[1], offset[2]), scale3(s, s, s));
    make_box();
    quad_positions(2.0f, qp);
    memset(&md, 0, sizeof md);
    md.data.positions = qp;
    md.data.vertex_count = 4;
    md.data.normals = quad_normals;
    md.data.indices = quad_indices;
    md.data.index_count = 6;
    md.data.index_type = GIM_INDEX_U16;
    assert_int_equal(gim_add_mesh(f->ctx, &md, &f->floor), GIM_OK);
    memset(&md, 0, sizeof md);
    md.data.positions = box_pos;
    md.data.vertex_count = 20;
    md.data.indices = box_idx;
    md.data.index_count = 30;
    md.data.triangle_material = box_mat;
    assert_int_equal(gim_add_mesh(f->ctx, &md, &f->box), GIM_OK);
    assert_int_equal(gim_set_materials(f->ctx, materials, 3), GIM_OK);
    inst[0].mesh = f->floor;
    inst[0].model = place;
    inst[1].mesh = f->box;
    inst[1].model = gim_mat4_mul(place, gim_mat4_mul(translate(0.2f, 0.4f, -0.1f),
                                                     gim_mat4_mul(rotate_y(0.3f), scale3(0.5f, 0.4f, 0.3f))));
    assert_int_equal(gim_set_instances(f->ctx, inst, 2), GIM_OK);
    f->soup.n = 0;
    soup_add(&f->soup, qp, quad_normals, quad_indices, 1, 6, NULL, inst[0].model);
    soup_add(&f->soup, box_pos, NULL, box_idx, 0, 30, box_mat, inst[1].model);
    f->twin.positions = f->soup.pos;
    f->twin.normals = f->soup.nrm;
    f->twin.albedo = f->soup.alb;
    f->twin.triangle_count = f->soup.n;
}

static void read_texture(GLuint tex, GLenum format, int comps, int w, int h, float *out) {
    GLint pack = 4;
    glGetIntegerv(GL_PACK_ALIGNMENT, &pack);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    glBindTexture(GL_TEXTURE_2D, tex);
    glGetTexImage(GL_TEXTURE_2D, 0, format, GL_FLOAT, out);
    glBindTexture(GL_TEXTURE_2D, 0);
    glPixelStorei(GL_PACK_ALIGNMENT, pack);
    (void)comps; (void)w; (void)h;
}


static gim_frame default_frame(float s, const float offset[3], int w, int h) {
    gim_frame fr;
    gim_vec3 o = gim_v3(offset[0], offset[1], offset[2]);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim__v3_add(o, gim_v3(2.2f * s, 2.5f * s, 3.4f * s)), gim__v3_add(o, gim_v3(0.0f, 0.2f * s, 0.0f)),
                               gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(0.9f, (float)w / (float)h, 0.5f * s, 20.0f * s);
    fr.width = (uint32_t)w;
    fr.height = (uint32_t)h;
    fr.lightskin.view_sample_count = 64;
    fr.lightskin.val_count = 128;
    return fr;
}

static int rel_close(float a, float b, float rel, float abs_tol) {
    return fabsf(a - b) <= rel * fmaxf(fabsf(a), fabsf(b)) + abs_tol;
}

/* --- RSM against its twin ------------------------------------------------------------------- */

/* Every texel away from triangle edges (its 4 neighbours see the same triangle and cone state
   in the twin; the GPU's coverage and the twin's ray may disagree within a texel of an edge)
   matches the twin: position, normal, area, flux, depth, lit. */
static void check_rsm(fixture *f, const gim_light *light, uint32_t light_index, float s) {
    gim_frame_outputs o = gim_outputs(f->ctx);
    const gim_light_outputs *lo = &o.lights[light_index];
    int n = (int)lo->rsm_size, x, y, j, compared = 0, lit = 0;
    float *pos = (float *)malloc((size_t)n * n * 16), *nrm = (float *)malloc((size_t)n * n * 16);
    float *flux = (float *)malloc((size_t)n * n * 16), *depth = (float *)malloc((size_t)n * n * 4);
    gim_rsm_texel *tw = (gim_rsm_texel *)malloc((size_t)n * n * sizeof *tw);
    double flux_gpu = 0.0, flux_twin = 0.0;
    float radius = 0.0f, far_off = 0.0f, depth_tol, snap, step_d, step_p[3];
    gim_rsm_view rv;
    rv.light = light; rv.bmin = o.bounds_min; rv.bmax = o.bounds_max;
    for (x = 0; x < 3; ++x) {
        radius += 0.25f * (o.bounds_max[x] - o.bounds_min[x]) * (o.bounds_max[x] - o.bounds_min[x]);
        far_off = fmaxf(far_off, fmaxf(fabsf(o.bounds_min[x]), fabsf(o.bounds_max[x])));
    }
    radius = sqrtf(radius);
    /* the GPU's float transform of coordinates far from the origin: a few ulps of them, over
       the light's depth range (a few radii) */
    depth_tol = 2e-5f + 2.4e-7f * far_off / radius;
    {   /* the rasteriser snaps vertices to 1 / 2^GL_SUBPIXEL_BITS of a texel, so what is read at
           a texel's centre (depth, attributes) may move by a few such steps of its change from one
           texel to the next, taken from the twin's four neighbours on the same triangle (H100,
           driver 580, 8 bits: a position 2.3e-4 off at texel 7,7 of the 40^2 RSM, past the 1e-4
           llvmpipe keeps within) */
        GLint bits = 8;
        glGetIntegerv(GL_SUBPIXEL_BITS, &bits);
        snap = 4.0f / (float)(1 << (bits < 4 ? 4 : bits > 16 ? 16 : bits));
    }
    assert_true(o.valid);
    read_texture(lo->rsm_position, GL_RGBA, 4, n, n, pos);
    read_texture(lo->rsm_normal, GL_RGBA, 4, n, n, nrm);
    read_texture(lo->rsm_flux, GL_RGBA, 4, n, n, flux);
    read_texture(lo->rsm_depth, GL_DEPTH_COMPONENT, 1, n, n, depth);
    for (y = 0; y < n; ++y)
        for (x = 0; x < n; ++x)
            assert_int_equal(gim_rsm_texel_twin(&f->twin, &rv, (uint32_t)x, (uint32_t)y, &tw[y * n + x]), GIM_OK);
    for (y = 1; y < n - 1; ++y)
        for (x = 1; x < n - 1; ++x) {
            const gim_rsm_texel *t = &tw[y * n + x];
            int k, i = y * n + x, nb[4];
            nb[0] = i - 1; nb[1] = i + 1; nb[2] = i - n; nb[3] = i + n;
            for (k = 0; k < 4; ++k)
                if (tw[nb[k]].triangle != t->triangle || tw[nb[k]].lit != t->lit) break;
            if (k < 4) continue;
            compared++;
            step_d = 0.0f;
            for (k = 0; k < 3; ++k) step_p[k] = 0.0f;
            for (j = 0; j < 4; ++j) {   /* the twin's change to a neighbour on the same triangle */
                const gim_rsm_texel *u = &tw[nb[j]];
                step_d = fmaxf(step_d, fabsf(u->depth - t->depth));
                if (t->triangle != UINT32_MAX)
                    for (k = 0; k < 3; ++k) step_p[k] = fmaxf(step_p[k], fabsf(u->position[k] - t->position[k]));
            }
            if (!(fabsf(depth[i] - t->depth) < depth_tol + snap * step_d))
                print_message("texel %d,%d of %d: depth GPU %.9g twin %.9g (tolerance %g + %g)\n", x, y, n, (double)depth[i],
                              (double)t->depth, (double)depth_tol, (double)(snap * step_d));
            assert_true(fabsf(depth[i] - t->depth) < depth_tol + snap * step_d);
            if (t->triangle == UINT32_MAX) {
                assert_true(pos[i * 4 + 3] == 0.0f && flux[i * 4] == 0.0f);
                continue;
            }
            assert_int_equal(pos[i * 4 + 3] > 0.5f, t->lit);
            lit += t->lit;
            for (k = 0; k < 3; ++k) {
                /* 1e-4 of the scene, or a few float ulps of the largest coordinate the transform
                   rounds (far_off, not this axis's own: the GPU's clip x, y, w mix all three) */
                if (!(fabsf(pos[i * 4 + k] - t->position[k]) < 1e-4f * s + 1e-6f * far_off + snap * step_p[k]))
                    print_message("texel %d,%d of %d axis %d: GPU %.9g twin %.9g (scale %g, far_off %g, step %g)\n", x, y,
                                  n, k, (double)pos[i * 4 + k], (double)t->position[k], (double)s, (double)far_off,
                                  (double)step_p[k]);
                assert_true(fabsf(pos[i * 4 + k] - t->position[k]) < 1e-4f * s + 1e-6f * far_off + snap * step_p[k]);
                assert_true(fabsf(nrm[i * 4 + k] - t->normal[k]) < 1e-4f);
                assert_true(rel_close(flux[i * 4 + k], t->flux[k], 1e-4f, 0.0f));
            }
            assert_true(rel_close(nrm[i * 4 + 3], t->area, 1e-3f, 0.0f));
        }
    for (x = 0; x < n * n; ++x) {
        flux_gpu += flux[x * 4] + flux[x * 4 + 1] + flux[x * 4 + 2];
        flux_twin += tw[x].flux[0] + tw[x].flux[1] + tw[x].flux[2];
    }
    /* whole RSM, edges included: edge texels are few, their flux one texel's */
    assert_true(fabs(flux_gpu - flux_twin) <= 0.03 * flux_twin);
    assert_true(compared > n * n / 2);
    assert_true(lit > n * n / 8);
    free(pos); free(nrm); free(flux); free(depth); free(tw);
}

static void rsm_sun_and_spot_match_twin(void **state) {
    static const float origin[3] = {0.0f, 0.0f, 0.0f}, far_away[3] = {3000.0f, -200.0f, 1500.0f};
    int pass;
    (void)state;
    GLTEST_BEGIN();
    for (pass = 0; pass < 2; ++pass) { /* at the origin in metres; far away in millimetres */
        fixture f;
        gim_light l[2];
        gim_frame fr;
        const float s = pass ? 1000.0f : 1.0f;
        const float *off = pass ? far_away : origin;
        float o2[3];
        o2[0] = off[0] * s; o2[1] = off[1] * s; o2[2] = off[2] * s;
        fixture_begin(&f);
        build_scene(&f, s, o2);
        memset(l, 0, sizeof l);
        l[0].type = GIM_LIGHT_DIRECTIONAL;
        l[0].irradiance = 3.0f;
        l[0].color[0] = 1.0f; l[0].color[1] = 0.9f; l[0].color[2] = 0.5f;
        l[0].direction = gim_v3(0.4f, 1.0f, 0.3f);
        l[0].rsm_size = 40;
        l[1].type = GIM_LIGHT_SPOT;
        l[1].intensity = 5.0f * s * s;
        l[1].position = gim_v3(o2[0] - 1.0f * s, o2[1] + 2.5f * s, o2[2] + 0.8f * s);
        l[1].direction = gim_v3(0.4f, -1.0f, -0.3f);
        l[1].cone_angle = 0.7f;
        l[1].rsm_size = 48;
        assert_int_equal(gim_set_lights(f.ctx, l, 2), GIM_OK);
        fr = default_frame(s, o2, 64, 48);
        assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
        check_rsm(&f, &l[0], 0, s);
        check_rsm(&f, &l[1], 1, s);
        assert_int_equal(f.log.errors, 0);
        fixture_end(&f);
    }
    GLTEST_END();
}

/* --- flux totals fixed by the physics ------------------------------------------------------ */

static double total_flux(gim_context *ctx, uint32_t light, double rgb[3]) {
    gim_frame_outputs o = gim_outputs(ctx);
    int n = (int)o.lights[light].rsm_size, i;
    float *flux = (float *)malloc((size_t)n * n * 16);
    double sum = 0.0;
    rgb[0] = rgb[1] = rgb[2] = 0.0;
    read_texture(o.lights[light].rsm_flux, GL_RGBA, 4, n, n, flux);
    for (i = 0; i < n * n; ++i) {
        rgb[0] += flux[i * 4]; rgb[1] += flux[i * 4 + 1]; rgb[2] += flux[i * 4 + 2];
        sum += flux[i * 4 + 1];
    }
    free(flux);
    return sum;
}

/* One plane [-h, h]^2 (y = 0, albedo rho) and one light; returns the RSM's total flux (green). */
static double plane_flux(float h, float plane_size_for_instances, const gim_light *light, double rgb[3]) {
    test_alloc_stats stats;
    test_log log;
    gim_desc d;
    gim_context *ctx = NULL;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance inst;
    gim_material m;
    gim_frame fr;
    float qp[12];
    double total;
    (void)plane_size_for_instances;
    memset(&d, 0, sizeof d);
    d.get_proc_address = gltest_get_proc;
    d.env = test_env(&stats, &log);
    assert_int_equal(gim_create(&d, &ctx), GIM_OK);
    quad_positions(h, qp);
    memset(&md, 0, sizeof md);
    md.data.positions = qp;
    md.data.vertex_count = 4;
    md.data.indices = quad_indices;
    md.data.index_count = 6;
    md.data.index_type = GIM_INDEX_U16;
    assert_int_equal(gim_add_mesh(ctx, &md, &mesh), GIM_OK);
    memset(&m, 0, sizeof m);
    m.diffuse[0] = 0.5f; m.diffuse[1] = 0.25f; m.diffuse[2] = 1.0f;
    assert_int_equal(gim_set_materials(ctx, &m, 1), GIM_OK);
    inst.mesh = mesh;
    inst.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(ctx, &inst, 1), GIM_OK);
    assert_int_equal(gim_set_lights(ctx, light, 1), GIM_OK);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim_v3(0.0f, 3.0f * h, 0.1f), gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(1.2f, 1.0f, 0.1f * h, 10.0f * h);
    fr.width = fr.height = 16;
    fr.lightskin.view_sample_count = 16;
    fr.lightskin.val_count = 16;
    assert_int_equal(gim_update(ctx, &fr), GIM_OK);
    total = total_flux(ctx, 0, rgb);
    gim_destroy(ctx);
    assert_int_equal(stats.live, 0);
    assert_int_equal(log.errors, 0);
    return total;
}

/* Sun: Phi_total = rho E (projected area), whatever the tilt (here the plane's edges fall on
   texel boundaries, so the count of covered texels is exact). Spot: Phi_total = rho I Omega,
   Omega the solid angle of the plane inside the cone: 4 asin(a^2 / (a^2 + d^2)) for a square
   of half-side a at distance d under the light (fully inside the cone), 2 pi (1 - cos alpha)
   for a plane covering the whole cone. */
static void flux_totals(void **state) {
    gim_light l;
    double rgb[3], t;
    const double rho = 0.25, E = 3.0, I = 7.0;
    (void)state;
    GLTEST_BEGIN();
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_DIRECTIONAL;
    l.irradiance = (float)E;
    l.direction = gim_v3(0.0f, 1.0f, 0.0f);
    l.extent = 2.0f;               /* texel 4/32 = 0.125: the plane's edges +-1 on texel boundaries */
    l.rsm_size = 32;
    t = plane_flux(1.0f, 0.0f, &l, rgb);
    assert_true(fabs(t - rho * E * 4.0) <= 1e-4 * rho * E * 4.0);
    assert_true(fabs(rgb[0] - 0.5 * E * 4.0) <= 1e-4 * 0.5 * E * 4.0); /* red albedo 0.5 */
    /* tilted by acos(0.75): projected area 4 x 0.75, its edges again on texel boundaries */
    l.direction = gim_v3(0.0f, 0.75f, sqrtf(1.0f - 0.5625f));
    t = plane_flux(1.0f, 0.0f, &l, rgb);
    assert_true(fabs(t - rho * E * 3.0) <= 1e-4 * rho * E * 3.0);
    /* spot 1 above a square of half-side 0.5, cone 45 degrees: the square spans u in
       [-0.5, 0.5] of the image plane [-1, 1], 64 texels: edges on texel boundaries; the
       midpoint rule of the solid-angle density converges as the texel size squared */
    memset(&l, 0, sizeof l);
    l.type = GIM_LIGHT_SPOT;
    l.intensity = (float)I;
    l.position = gim_v3(0.0f, 1.0f, 0.0f);
    l.direction = gim_v3(0.0f, -1.0f, 0.0f);
    l.cone_angle = (float)(PI_D / 4.0);
    l.rsm_size = 64;
    t = plane_flux(0.5f, 0.0f, &l, rgb);
    {
        double omega = 4.0 * asin(0.25 / 1.25);
        assert_true(fabs(t - rho * I * omega) <= 1e-3 * rho * I * omega);
    }
    /* a plane wider than the cone: the disk's boundary cuts texels, a fraction of a percent */
    t = plane_flux(4.0f, 0.0f, &l, rgb);
    {
        double omega = 2.0 * PI_D * (1.0 - cos(PI_D / 4.0));
        assert_true(fabs(t - rho * I * omega) <= 0.01 * rho * I * omega);
    }
    GLTEST_END();
}

/* --- G-buffer and view samples ------------------------------------------------------------- */

static void gbuffer_and_view_samples_match_twin(void **state) {
    enum { W = 64, H = 48 };
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    fixture f;
    gim_light l;
    gim_frame fr;
    gim_frame_outputs o;
    gim_debug_outputs od;
    float *nrm = (float *)malloc(W * H * 16), *alb = (float *)malloc(W * H * 16), *depth = (float *)malloc(W * H * 4);
    gim_gbuffer_texel *tw = (gim_gbuffer_texel *)malloc(W * H * sizeof *tw);
    float vs_gpu[256 * 8], off[2];
    gim_view_sample vs_twin[256];
    uint32_t pixels[256 * 2];
    int x, y, i, compared = 0, usable = 0, round;
    gim_camera cam;
    (void)state;
    GLTEST_BEGIN();
    fixture_begin(&f);
    build_scene(&f, 1.0f, origin);
    memset(&l, 0, sizeof l);
    l.irradiance = 1.0f;
    l.direction = gim_v3(0.2f, 1.0f, 0.1f);
    l.rsm_size = 32;
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    fr = default_frame(1.0f, origin, W, H);
    fr.lightskin.view_sample_count = 256;
    cam.view = fr.view; cam.proj = fr.proj; cam.width = W; cam.height = H;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
    read_texture(o.gbuffer_normal, GL_RGBA, 4, W, H, nrm);
    read_texture(o.gbuffer_albedo, GL_RGBA, 4, W, H, alb);
    read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, 1, W, H, depth);
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x)
            assert_int_equal(gim_gbuffer_texel_twin(&f.twin, &cam, (uint32_t)x, (uint32_t)y, &tw[y * W + x]), GIM_OK);
    for (y = 1; y < H - 1; ++y)
        for (x = 1; x < W - 1; ++x) {
            int k, j = y * W + x, nb[4];
            nb[0] = j - 1; nb[1] = j + 1; nb[2] = j - W; nb[3] = j + W;
            for (k = 0; k < 4; ++k)
                if (tw[nb[k]].triangle != tw[j].triangle) break;
            if (k < 4) continue;
            compared++;
            assert_true(fabsf(depth[j] - tw[j].depth) < 2e-5f);
            if (tw[j].triangle == UINT32_MAX) { assert_true(nrm[j * 4 + 3] == 0.0f); continue; }
            assert_true(nrm[j * 4 + 3] == 1.0f);
            for (k = 0; k < 3; ++k) {
                assert_true(fabsf(nrm[j * 4 + k] - tw[j].normal[k]) < 1e-3f);           /* RGBA16F */
                assert_true(fabsf(alb[j * 4 + k] - tw[j].albedo[k]) < 0.5f / 255.0f + 1e-6f); /* RGBA8 */
            }
        }
    assert_true(compared > W * H / 2);
    /* view samples: not rotated, then rotated per frame */
    for (round = 0; round < 2; ++round) {
        if (round) {
            fr.lightskin.rotate_view_samples = 1;
            fr.lightskin.temporal_steps = 1;   /* rotated anew each frame (drifting: gltest_temporal) */
            fr.frame_index = 5;
            assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
            o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
            gim_rotation_offsets(off, 2, 5);
        }
        assert_int_equal(od.view_sample_count, 256);
        gltest_read_buffer(od.view_samples, sizeof vs_gpu, vs_gpu);
        assert_int_equal(gim_view_sample_pixels(256, W, H, round ? off : NULL, pixels), GIM_OK);
        assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, pixels, 256, vs_twin), GIM_OK);
        usable = 0;
        for (i = 0; i < 256; ++i) {
            const gim_gbuffer_texel *t = &tw[pixels[2 * i + 1] * W + pixels[2 * i]];
            assert_true(fabsf(vs_gpu[i * 8] - vs_twin[i].position.x) < 1e-5f);
            assert_true(fabsf(vs_gpu[i * 8 + 1] - vs_twin[i].position.y) < 1e-5f);
            assert_true(fabsf(vs_gpu[i * 8 + 2] - vs_twin[i].position.z) < 1e-5f);
            assert_true(fabsf(vs_gpu[i * 8 + 4] - vs_twin[i].normal.x) < 1e-6f);
            assert_true(fabsf(vs_gpu[i * 8 + 5] - vs_twin[i].normal.y) < 1e-6f);
            assert_true(fabsf(vs_gpu[i * 8 + 6] - vs_twin[i].normal.z) < 1e-6f);
            if (vs_twin[i].normal.x == 0.0f && vs_twin[i].normal.y == 0.0f && vs_twin[i].normal.z == 0.0f) continue;
            usable++;
            /* and the unprojected point is where the ray through the pixel meets the scene
               (float depth: ~1e-4 of the distance) */
            if (t->triangle != UINT32_MAX) {
                assert_true(fabsf(vs_twin[i].position.x - t->position[0]) < 2e-3f);
                assert_true(fabsf(vs_twin[i].position.y - t->position[1]) < 2e-3f);
                assert_true(fabsf(vs_twin[i].position.z - t->position[2]) < 2e-3f);
            }
        }
        assert_true(usable > 80);
    }
    /* the host's G-buffer: gimany's own textures handed back give the same samples */
    {
        float again[256 * 8];
        gim_frame hf = fr;
        hf.gbuffer.depth = o.gbuffer_depth;
        hf.gbuffer.normal = o.gbuffer_normal;
        gltest_read_buffer(od.view_samples, sizeof vs_gpu, vs_gpu);
        assert_int_equal(gim_update(f.ctx, &hf), GIM_OK);
        o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
        assert_int_equal(o.gbuffer_albedo, 0);
        gltest_read_buffer(od.view_samples, sizeof again, again);
        assert_memory_equal(vs_gpu, again, sizeof again);
        hf.width = W + 1; /* larger than the host's textures */
        assert_int_equal(gim_update(f.ctx, &hf), GIM_ERROR_INVALID_ARGUMENT);
        assert_false(gim_outputs(f.ctx).valid);
    }
    fixture_end(&f);
    free(nrm); free(alb); free(depth); free(tw);
    GLTEST_END();
}

/* --- the chain into the importance passes ------------------------------------------------- */

/* The frame's importance passes on its own RSM and view samples against the twins: per texel
   (importance_tile 1: gim_importance_map) and the two-level map of tile side 8
   (gim_importance_tile_map: the tile map and the texel weights), every pick a texel of positive
   importance (weight). */
static void importance_chain_matches_twin(void **state) {
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    fixture f;
    gim_light l;
    gim_frame fr;
    gim_frame_outputs o;
    gim_debug_outputs od;
    enum { N = 32, VS = 64, VALS = 128 };
    float *pos = (float *)malloc(N * N * 16), *nrm = (float *)malloc(N * N * 16), *flux = (float *)malloc(N * N * 16);
    float p3[N * N * 3], n3[N * N * 3], f3[N * N * 3], valid[N * N], map_gpu[N * N], map_twin[N * N], vsb[VS * 8];
    float tiles_gpu[N * N], tiles_twin[N * N];
    gim_view_sample vs[VS];
    uint32_t sel[VALS * 3], pass, tile;
    int i, k, bad = 0, cells;
    (void)state;
    GLTEST_BEGIN();
    fixture_begin(&f);
    build_scene(&f, 1.0f, origin);
    memset(&l, 0, sizeof l);
    l.irradiance = 2.0f;
    l.direction = gim_v3(0.5f, 1.0f, -0.2f);
    l.rsm_size = N;
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    for (pass = 0; pass < 2; ++pass) {
        tile = pass == 0 ? 1u : 8u;
        cells = (int)(((N - 1) / tile + 1) * ((N - 1) / tile + 1));
        fr = default_frame(1.0f, origin, 32, 24);
        fr.lightskin.view_sample_count = VS;
        fr.lightskin.val_count = VALS;
        fr.lightskin.importance_tile = pass == 0 ? 0u : 8u;   /* 0: the default, 1 */
        assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
        o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
        assert_int_equal(o.lights[0].importance_tile, tile);
        assert_true(pass == 0 ? o.lights[0].importance_tiles == 0 : o.lights[0].importance_tiles != 0);
        read_texture(o.lights[0].rsm_position, GL_RGBA, 4, N, N, pos);
        read_texture(o.lights[0].rsm_normal, GL_RGBA, 4, N, N, nrm);
        read_texture(o.lights[0].rsm_flux, GL_RGBA, 4, N, N, flux);
        gltest_read_buffer(od.view_samples, sizeof vsb, vsb);
        gltest_read_buffer(o.lights[0].importance, sizeof map_gpu, map_gpu);
        if (tile > 1u) gltest_read_buffer(o.lights[0].importance_tiles, (size_t)cells * sizeof(float), tiles_gpu);
        gltest_read_buffer(o.lights[0].selected, sizeof sel, sel);
        for (i = 0; i < N * N; ++i) {
            for (k = 0; k < 3; ++k) { p3[i * 3 + k] = pos[i * 4 + k]; n3[i * 3 + k] = nrm[i * 4 + k]; f3[i * 3 + k] = flux[i * 4 + k]; }
            valid[i] = pos[i * 4 + 3];
        }
        for (i = 0; i < VS; ++i) {
            vs[i].position = gim_v3(vsb[i * 8], vsb[i * 8 + 1], vsb[i * 8 + 2]);
            vs[i].normal = gim_v3(vsb[i * 8 + 4], vsb[i * 8 + 5], vsb[i * 8 + 6]);
        }
        {
            gim_importance_desc d;
            memset(&d, 0, sizeof d);
            d.rsm_position = p3; d.rsm_normal = n3; d.rsm_flux = f3; d.rsm_valid = valid;
            d.width = d.height = N;
            d.view_samples = vs;
            d.view_sample_count = VS;
            d.scene_scale = o.scene_scale;
            if (tile == 1u) assert_int_equal(gim_importance_map(&d, map_twin), GIM_OK);
            else assert_int_equal(gim_importance_tile_map(&d, tile, tiles_twin, map_twin), GIM_OK);
        }
        for (i = 0; i < N * N; ++i)
            if (!rel_close(map_gpu[i], map_twin[i], 1e-3f, 1e-30f)) bad++;
        for (i = 0; tile > 1u && i < cells; ++i)
            if (!rel_close(tiles_gpu[i], tiles_twin[i], 1e-3f, 1e-30f)) bad++;
        assert_int_equal(bad, 0);
        for (i = 0; i < VALS; ++i) { /* every pick a lit texel of positive importance (weight) */
            float pdf;
            memcpy(&pdf, &sel[i * 3 + 2], 4);
            assert_true(sel[i * 3] < N && sel[i * 3 + 1] < N && pdf > 0.0f);
            assert_true(map_gpu[sel[i * 3 + 1] * N + sel[i * 3]] > 0.0f);
        }
        assert_int_equal(o.lights[0].selected_count, VALS);
    }
    fixture_end(&f);
    free(pos); free(nrm); free(flux);
    GLTEST_END();
}

/* --- argument errors, sizes that change, allocation failures ------------------------------- */

static void argument_errors(void **state) {
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    fixture f;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance inst;
    gim_material m;
    gim_light l;
    gim_frame fr;
    float qp[12];
    uint16_t bad_idx[6] = {0, 1, 2, 0, 2, 4};
    int errors;
    (void)state;
    GLTEST_BEGIN();
    fixture_begin(&f);
    build_scene(&f, 1.0f, origin);
    quad_positions(1.0f, qp);
    memset(&md, 0, sizeof md);
    md.data.positions = qp;
    md.data.vertex_count = 4;
    md.data.indices = quad_indices;
    md.data.index_count = 6;
    md.data.index_type = GIM_INDEX_U16;
    errors = f.log.errors;
#define EXPECT(call, code) do { assert_int_equal((call), (code)); assert_int_equal(f.log.errors, ++errors); } while (0)
    EXPECT(gim_add_mesh(f.ctx, NULL, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md.data.index_count = 5;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md.data.index_count = 6;
    md.data.indices = bad_idx;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md.data.indices = quad_indices;
    qp[4] = NAN;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    qp[4] = INFINITY;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    qp[4] = 0.0f;
    {
        float zero_n[12] = {0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0};
        md.data.normals = zero_n;
        EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        md.data.normals = NULL;
    }
    md.data.position_stride = 8;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md.data.position_stride = 0;
    md.data.index_type = (gim_index_type)7;
    EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md.data.index_type = GIM_INDEX_U16;
    {   /* the mesh's caches are copied for later passes: NULL array or a NaN is an error */
        gim_cache c[2];
        gim_cache_set cs;
        memset(c, 0, sizeof c);
        memset(&cs, 0, sizeof cs);
        c[0].normal[1] = c[1].normal[1] = 1.0f;
        c[0].area = c[1].area = 2.0f;
        cs.count = 2;
        md.caches = &cs;
        EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        cs.caches = c;
        c[1].position[2] = NAN;
        EXPECT(gim_add_mesh(f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
        c[1].position[2] = 0.5f;
        assert_int_equal(gim_add_mesh(f.ctx, &md, &mesh), GIM_OK);
        c[1].position[2] = 9.0f; /* the host's array may change: gimany kept its copy */
        assert_int_equal(f.ctx->meshes[(mesh.id & 0xFFFFu) - 1].cache_count, 2);
        assert_true(f.ctx->meshes[(mesh.id & 0xFFFFu) - 1].caches[1].position[2] == 0.5f);
        md.caches = NULL;
    }
    /* instances */
    inst.mesh = mesh;
    inst.model = gim_mat4_identity();
    inst.model.m[13] = NAN;
    EXPECT(gim_set_instances(f.ctx, &inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    inst.model = scale3(1.0f, 0.0f, 1.0f); /* singular */
    EXPECT(gim_set_instances(f.ctx, &inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    inst.model = gim_mat4_identity();
    inst.mesh.id = 0;
    EXPECT(gim_set_instances(f.ctx, &inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    inst.mesh.id = mesh.id + 1000u;
    EXPECT(gim_set_instances(f.ctx, &inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_set_instances(f.ctx, NULL, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* materials */
    m = materials[0];
    m.diffuse[1] = NAN;
    EXPECT(gim_set_materials(f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
    m = materials[0];
    m.exponent = -1.0f;
    EXPECT(gim_set_materials(f.ctx, &m, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* lights */
    memset(&l, 0, sizeof l);
    l.irradiance = 1.0f;
    l.direction = gim_v3(0.0f, 1.0f, 0.0f);
    l.type = (gim_light_type)9;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.type = GIM_LIGHT_DIRECTIONAL;
    l.direction = gim_v3(0.0f, 0.0f, 0.0f);
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.direction = gim_v3(0.0f, NAN, 0.0f);
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.direction = gim_v3(0.0f, 1.0f, 0.0f);
    l.irradiance = -1.0f;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.irradiance = 1.0f;
    l.rsm_size = 16384u; /* above llvmpipe's 8192 textures (and any viewport limit) */
    {
        GLint max_tex = 0;
        glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
        if (max_tex < 16384) EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_OUT_OF_RANGE);
    }
    l.rsm_size = 100000u;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_OUT_OF_RANGE);
    l.rsm_size = 16;
    l.type = GIM_LIGHT_SPOT;
    l.intensity = 1.0f;
    l.cone_angle = 0.0f;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.cone_angle = 1.6f;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.cone_angle = 0.5f;
    l.position.x = INFINITY;
    EXPECT(gim_set_lights(f.ctx, &l, 1), GIM_ERROR_INVALID_ARGUMENT);
    l.position.x = 0.0f;
    l.position.y = 3.0f;
    l.direction = gim_v3(0.0f, -1.0f, 0.0f);
    {
        gim_light *many = (gim_light *)calloc(GIM_MAX_LIGHTS + 1, sizeof *many);
        int i;
        assert_non_null(many);
        for (i = 0; i < GIM_MAX_LIGHTS + 1; ++i) many[i] = l;
        EXPECT(gim_set_lights(f.ctx, many, GIM_MAX_LIGHTS + 1), GIM_ERROR_OUT_OF_RANGE);
        /* a point light takes six RSMs: two of them and GIM_MAX_LIGHTS - 12 spots fill the limit, a
           third point does not fit */
        many[0].type = many[1].type = GIM_LIGHT_POINT;
        assert_int_equal(gim_set_lights(f.ctx, many, GIM_MAX_LIGHTS - 10), GIM_OK);
        assert_int_equal(f.ctx->light_count, (uint32_t)GIM_MAX_LIGHTS);
        many[2].type = GIM_LIGHT_POINT;
        EXPECT(gim_set_lights(f.ctx, many, GIM_MAX_LIGHTS - 10), GIM_ERROR_OUT_OF_RANGE);
        many[0].intensity = -1.0f;   /* checked as a spot's intensity */
        EXPECT(gim_set_lights(f.ctx, many, 1), GIM_ERROR_INVALID_ARGUMENT);
        free(many);
    }
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    /* frames */
    fr = default_frame(1.0f, origin, 16, 12);
    EXPECT(gim_update(f.ctx, NULL), GIM_ERROR_INVALID_ARGUMENT);
    fr.view.m[5] = NAN;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr = default_frame(1.0f, origin, 16, 12);
    fr.proj = scale3(1.0f, 1.0f, 0.0f);
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr = default_frame(1.0f, origin, 16, 12);
    fr.width = 0;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr.width = 1u << 20;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr.width = 16;
    fr.gbuffer.depth = 5;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr.gbuffer.normal = 987654; /* not textures */
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr.gbuffer.depth = fr.gbuffer.normal = 0;
    fr.lightskin.view_sample_count = 1u << 20;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr.lightskin.view_sample_count = 0;
    fr.lightskin.val_count = 0xFFFFFFFFu;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_OUT_OF_RANGE);
    fr.lightskin.val_count = 0;
    fr.scene_scale = -1.0f;
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fr.scene_scale = 0.0f;
    /* a mesh with material 2 but one material; then no instances; then a removed mesh */
    assert_int_equal(gim_set_materials(f.ctx, materials, 1), GIM_OK);
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_set_materials(f.ctx, materials, 3), GIM_OK);
    inst.mesh = mesh;
    inst.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(f.ctx, NULL, 0), GIM_OK);
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_set_instances(f.ctx, &inst, 1), GIM_OK);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK); /* defaults: 256 view samples, 2048 VALs */
    assert_int_equal(gim_debug(f.ctx).view_sample_count, 256);
    /* one rendered light: nothing to split, it gets the 2048 in both budgets (drawn uniformly:
       a flat quad does not light itself, every importance is 0) */
    assert_int_equal(gim_outputs(f.ctx).lights[0].rendered, 1);
    assert_int_equal(gim_outputs(f.ctx).lights[0].selected_count, 2048);
    fr.per_light_budget = 1;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    assert_int_equal(gim_outputs(f.ctx).lights[0].selected_count, 2048);
    fr.per_light_budget = 0;
    assert_int_equal(gim_remove_mesh(f.ctx, mesh), GIM_OK);
    EXPECT(gim_remove_mesh(f.ctx, mesh), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    EXPECT(gim_set_instances(f.ctx, &inst, 1), GIM_ERROR_INVALID_ARGUMENT);
    /* a new mesh in the freed slot does not answer to the old handle */
    {
        gim_mesh again;
        assert_int_equal(gim_add_mesh(f.ctx, &md, &again), GIM_OK);
        assert_true(again.id != mesh.id);
        inst.mesh = again;
        assert_int_equal(gim_set_instances(f.ctx, &inst, 1), GIM_OK);
    }
    /* still usable, sizes changed without a new context */
    l.rsm_size = 24;
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    fr = default_frame(1.0f, origin, 20, 10);
    fr.lightskin.view_sample_count = 32;
    fr.lightskin.val_count = 40;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    assert_int_equal(gim_outputs(f.ctx).lights[0].rsm_size, 24);
    assert_int_equal(gim_outputs(f.ctx).width, 20);
    assert_int_equal(gim_set_lights(f.ctx, NULL, 0), GIM_OK); /* no lights: the G-buffer and samples only */
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    assert_int_equal(gim_outputs(f.ctx).light_count, 0);
    assert_int_equal(gim_outputs(NULL).valid, 0);
#undef EXPECT
    fixture_end(&f);
    GLTEST_END();
}

/* Every allocation failing in turn: GIM_ERROR_OUT_OF_MEMORY (or OK once past the last), no
   leak, no GL error, and the context still works afterwards. */
static void out_of_memory(void **state) {
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    long n;
    int reached_ok = 0;
    (void)state;
    GLTEST_BEGIN();
    for (n = 0; n < 40 && !reached_ok; ++n) {
        fixture f;
        gim_mesh_desc md;
        gim_mesh mesh;
        gim_instance inst;
        gim_light l;
        gim_frame fr;
        gim_result r;
        float qp[12];
        fixture_begin(&f);
        quad_positions(1.0f, qp);
        memset(&md, 0, sizeof md);
        md.data.positions = qp;
        md.data.vertex_count = 4;
        md.data.indices = quad_indices;
        md.data.index_count = 6;
        md.data.index_type = GIM_INDEX_U16;
        memset(&l, 0, sizeof l);
        l.irradiance = 1.0f;
        l.direction = gim_v3(0.0f, 1.0f, 0.0f);
        l.rsm_size = 16;
        f.stats.fail_after = f.stats.allocs + n;
        r = gim_add_mesh(f.ctx, &md, &mesh);
        if (r == GIM_OK) r = gim_set_materials(f.ctx, materials, 3);
        if (r == GIM_OK) {
            inst.mesh = mesh;
            inst.model = gim_mat4_identity();
            r = gim_set_instances(f.ctx, &inst, 1);
        }
        if (r == GIM_OK) r = gim_set_lights(f.ctx, &l, 1);
        if (r == GIM_OK) {
            fr = default_frame(1.0f, origin, 16, 12);
            r = gim_update(f.ctx, &fr);
        }
        assert_true(r == GIM_OK || r == GIM_ERROR_OUT_OF_MEMORY);
        reached_ok = r == GIM_OK;
        f.stats.fail_after = -1;
        fixture_end(&f);
    }
    assert_true(reached_ok);
    GLTEST_END();
}

/* --- the host's state does not reach gimany's passes -------------------------------------- */

static void read_outputs(gim_context *ctx, float *rsm_flux, float *rsm_pos, float *gb_normal, float *gb_depth) {
    gim_frame_outputs o = gim_outputs(ctx);
    int n = (int)o.lights[0].rsm_size;
    GLint fbo = 0;
    glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &fbo);
    read_texture(o.lights[0].rsm_flux, GL_RGBA, 4, n, n, rsm_flux);
    read_texture(o.lights[0].rsm_position, GL_RGBA, 4, n, n, rsm_pos);
    read_texture(o.gbuffer_normal, GL_RGBA, 4, (int)o.width, (int)o.height, gb_normal);
    read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, 1, (int)o.width, (int)o.height, gb_depth);
}

/* The same frame under GL's defaults and under a hostile host state (culling, clip planes,
   line mode, inverted depth test and range, masks, scissor, blending, smoothing, a bound
   program, VAO and FBO): the same RSM and G-buffer, bit for bit, and the host state back. */
static void host_state_isolated(void **state) {
    enum { N = 32, W = 40, H = 30 };
    static const float origin[3] = {0.0f, 0.0f, 0.0f};
    fixture f;
    gim_light l;
    gim_frame fr;
    float *a = (float *)malloc((N * N * 8 + W * H * 5) * sizeof(float)), *b = (float *)malloc((N * N * 8 + W * H * 5) * sizeof(float));
    GLuint vao, fbo, tex;
    GLint v4[4];
    (void)state;
    GLTEST_BEGIN();
    fixture_begin(&f);
    build_scene(&f, 1.0f, origin);
    memset(&l, 0, sizeof l);
    l.irradiance = 1.0f;
    l.direction = gim_v3(0.3f, 1.0f, 0.5f);
    l.rsm_size = N;
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    fr = default_frame(1.0f, origin, W, H);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    read_outputs(f.ctx, a, a + N * N * 4, a + N * N * 8, a + N * N * 8 + W * H * 4);
    glGenVertexArrays(1, &vao);
    glBindVertexArray(vao);
    glGenTextures(1, &tex);
    glBindTexture(GL_TEXTURE_2D, tex);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, 4, 4);
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
    glEnable(GL_CULL_FACE); glCullFace(GL_FRONT_AND_BACK);
    glEnable(GL_CLIP_DISTANCE0); glEnable(GL_CLIP_DISTANCE5);
    glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    glEnable(GL_DEPTH_TEST); glDepthFunc(GL_GREATER); glDepthMask(GL_FALSE); glDepthRange(0.9, 0.1);
    glColorMask(GL_FALSE, GL_TRUE, GL_FALSE, GL_FALSE);
    glEnable(GL_SCISSOR_TEST); glScissor(1, 1, 2, 2);
    glEnable(GL_BLEND); glBlendFunc(GL_ONE, GL_ONE);
    glEnable(GL_POLYGON_SMOOTH); glEnable(GL_POLYGON_OFFSET_FILL); glPolygonOffset(5.0f, 5.0f);
    glEnable(GL_DEPTH_CLAMP); glEnable(GL_PRIMITIVE_RESTART); glPrimitiveRestartIndex(0);
    glViewport(0, 0, 1, 1);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    glGetIntegerv(GL_VIEWPORT, v4);
    assert_true(v4[2] == 1 && v4[3] == 1);
    assert_true(glIsEnabled(GL_CLIP_DISTANCE5) && glIsEnabled(GL_POLYGON_SMOOTH));
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    read_outputs(f.ctx, b, b + N * N * 4, b + N * N * 8, b + N * N * 8 + W * H * 4);
    assert_memory_equal(a, b, (N * N * 8 + W * H * 5) * sizeof(float));
    /* back to GL's defaults for the tests after this one */
    glDisable(GL_CULL_FACE); glCullFace(GL_BACK);
    glDisable(GL_CLIP_DISTANCE0); glDisable(GL_CLIP_DISTANCE5);
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    glDisable(GL_DEPTH_TEST); glDepthFunc(GL_LESS); glDepthMask(GL_TRUE); glDepthRange(0.0, 1.0);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDisable(GL_SCISSOR_TEST);
    glDisable(GL_BLEND); glBlendFunc(GL_ONE, GL_ZERO);
    glDisable(GL_POLYGON_SMOOTH); glDisable(GL_POLYGON_OFFSET_FILL); glPolygonOffset(0.0f, 0.0f);
    glDisable(GL_DEPTH_CLAMP); glDisable(GL_PRIMITIVE_RESTART);
    glBindVertexArray(0);
    glDeleteVertexArrays(1, &vao);
    glDeleteFramebuffers(1, &fbo);
    glDeleteTextures(1, &tex);
    fixture_end(&f);
    free(a); free(b);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rsm_sun_and_spot_match_twin),
        cmocka_unit_test(flux_totals),
        cmocka_unit_test(gbuffer_and_view_samples_match_twin),
        cmocka_unit_test(importance_chain_matches_twin),
        cmocka_unit_test(host_state_isolated),
        cmocka_unit_test(argument_errors),
        cmocka_unit_test(out_of_memory),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
