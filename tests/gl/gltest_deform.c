/* Deforming meshes (gim_mesh_desc.deforming): a plate over the open room, bound once
   and then bent or sheared, its vertices handed over by gim_update_mesh_vertices (gimany's copy)
   or written by the host into its own interleaved buffer (read by every gim_update on the GPU).
   - twin: caches_follow.comp's caches equal gim_caches_follow_twin's (twin tolerance, float rounding).
   - affine: under an affine map A that is no rigid motion, the followed caches are A applied to
     the rest caches (gim_caches_to_world with A: position A p, normal A^-T n, area |det A||A^-T n|),
     and their areas sum to the sheared plate's closed-form area; the rest caches, i.e. the pass
     disabled, miss by more than a tenth of the plate.
   - images: after a first frame at rest (world caches, grid and imperfect shadow maps made for
     the rest pose), the deformed plate lights the room as the same geometry added as a static
     mesh with the caches moved on the CPU does, through both paths, with and without ISMs; the
     rest pose's frame (nothing invalidated) differs from it by far more.
   - bad input: a wrong vertex count, a non-finite position or normal, a mesh not flagged
     deforming, a host-buffer mesh handed to gim_update_mesh_vertices, a non-finite position in
     the host's buffer: one error each, no GL error, the scene unchanged. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "room.h"

enum { W = 40, H = 30, N = 6, NV = (N + 1) * (N + 1), NI = N * N * 6, STRIDE = 32, VOFF = 16 };

/* the plate: (N+1)^2 vertices over [-1.2, 1.2] x [-1.2, 1.2] at height 0.7, normal +y */
static void plate_rest(float *p) {
    int i, j;
    for (j = 0; j <= N; ++j)
        for (i = 0; i <= N; ++i) {
            float *v = p + (j * (N + 1) + i) * 3;
            v[0] = -1.2f + 2.4f * (float)i / N;
            v[1] = 0.7f;
            v[2] = -1.2f + 2.4f * (float)j / N;
        }
}
static void plate_indices(uint32_t *idx) {
    int i, j, t = 0;
    for (j = 0; j < N; ++j)
        for (i = 0; i < N; ++i) {
            uint32_t a = (uint32_t)(j * (N + 1) + i), b = a + 1u, c = a + (N + 1) + 1u, d = a + (N + 1);
            idx[t++] = a; idx[t++] = d; idx[t++] = c;   /* counter-clockwise seen from +y */
            idx[t++] = a; idx[t++] = c; idx[t++] = b;
        }
}
static uint32_t plate_idx[NI], plate_mat[NI / 3];

/* The affine map of the test: a shear, a tilt and an uneven stretch (not a rigid motion). */
static const float A3[9] = {1.15f, 0.35f, 0.0f, 0.0f, 1.0f, 0.0f, 0.25f, 0.2f, 0.7f};   /* columns */
static const float At[3] = {0.05f, -0.1f, 0.1f};
static gim_mat4 affine(void) {
    gim_mat4 m = gim_mat4_identity();
    int c, r;
    for (c = 0; c < 3; ++c)
        for (r = 0; r < 3; ++r) m.m[c * 4 + r] = A3[c * 3 + r];
    m.m[12] = At[0]; m.m[13] = At[1]; m.m[14] = At[2];
    return m;
}
static void deform_affine(const float *rest, float *out) {
    gim_mat4 m = affine();
    int i;
    for (i = 0; i < NV; ++i) {
        gim_vec3 p = gim_mat4_point(m, gim_v3(rest[i * 3], rest[i * 3 + 1], rest[i * 3 + 2]));
        out[i * 3] = p.x; out[i * 3 + 1] = p.y; out[i * 3 + 2] = p.z;
    }
}
/* A bend no affine map makes: the plate curls up towards +x and sags along z. */
static void deform_bend(const float *rest, float *out) {
    int i;
    for (i = 0; i < NV; ++i) {
        float x = rest[i * 3], z = rest[i * 3 + 2];
        out[i * 3] = x - 0.08f * x * x;
        out[i * 3 + 1] = rest[i * 3 + 1] + 0.35f * (x + 1.2f) * (x + 1.2f) / 5.76f - 0.15f * (1.0f - z * z / 1.44f);
        out[i * 3 + 2] = z;
    }
}

static gim_mesh_data plate_data(const float *p) {
    gim_mesh_data d;
    memset(&d, 0, sizeof d);
    d.positions = p;
    d.vertex_count = NV;
    d.indices = plate_idx;
    d.index_count = NI;
    d.index_type = GIM_INDEX_U32;
    d.triangle_material = plate_mat;
    return d;
}

typedef struct deform_fx {
    gltest_fixture f;
    room r;
    gim_cache_set room_set, plate_set;
    float rest[NV * 3];
    gim_mesh room_mesh, plate;
    GLuint vbo;               /* the host path: interleaved position, normal, 8 bytes of other data */
    gim_frame fr;
} deform_fx;

/* The host's interleaved buffer of p, with the area-weighted vertex normals gimany computes for
   a mesh without normals (the same operations), as an engine's skinning would write them. */
static void host_write(deform_fx *h, const float *p) {
    unsigned char vb[VOFF + NV * STRIDE];
    float n[NV * 3];
    int i, k;
    memset(n, 0, sizeof n);
    for (i = 0; i < NI / 3; ++i) {
        uint32_t a = plate_idx[i * 3], b = plate_idx[i * 3 + 1], c = plate_idx[i * 3 + 2], v[3];
        gim_vec3 pa = gim_v3(p[a * 3], p[a * 3 + 1], p[a * 3 + 2]);
        gim_vec3 fn = gim__v3_cross(gim__v3_sub(gim_v3(p[b * 3], p[b * 3 + 1], p[b * 3 + 2]), pa),
                                   gim__v3_sub(gim_v3(p[c * 3], p[c * 3 + 1], p[c * 3 + 2]), pa));
        v[0] = a; v[1] = b; v[2] = c;
        for (k = 0; k < 3; ++k) { n[v[k] * 3] += fn.x; n[v[k] * 3 + 1] += fn.y; n[v[k] * 3 + 2] += fn.z; }
    }
    memset(vb, 0x7f, sizeof vb);   /* NaN bytes where gimany must not read */
    for (i = 0; i < NV; ++i) {
        gim_vec3 u = gim_v3_normalize(gim_v3(n[i * 3], n[i * 3 + 1], n[i * 3 + 2]));
        memcpy(vb + VOFF + i * STRIDE, p + i * 3, 12);
        memcpy(vb + VOFF + i * STRIDE + 12, &u, 12);
    }
    glBindBuffer(GL_ARRAY_BUFFER, h->vbo);
    glBufferSubData(GL_ARRAY_BUFFER, 0, sizeof vb, vb);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
}

/* The room (static) and the plate: mode 0 static (at plate_pos, with plate_caches), 1 deforming
   from arrays, 2 deforming from the host's buffer. */
static void setup(deform_fx *h, int mode, const float *plate_pos, const gim_cache_set *plate_caches) {
    gim_cache_desc cd;
    gim_mesh_desc md;
    gim_instance in[2];
    gim_light sun;
    gim_material mats[5];
    int i;
    memset(h, 0, sizeof *h);
    gltest_fixture_begin(&h->f);
    room_open_box(&h->r);
    plate_rest(h->rest);
    plate_indices(plate_idx);
    for (i = 0; i < NI / 3; ++i) plate_mat[i] = 4;
    memset(&cd, 0, sizeof cd);
    cd.mesh = room_arrays(&h->r);
    cd.d_eps = 0.5f;
    assert_int_equal(gim_cache_generate(&cd, &h->room_set), GIM_OK);
    cd.mesh = plate_data(h->rest);
    cd.d_eps = 0.3f;
    cd.scene_scale = 6.0f;
    assert_int_equal(gim_cache_generate(&cd, &h->plate_set), GIM_OK);
    memset(&md, 0, sizeof md);
    md.data = room_arrays(&h->r);
    md.caches = &h->room_set;
    assert_int_equal(gim_add_mesh(h->f.ctx, &md, &h->room_mesh), GIM_OK);
    memset(&md, 0, sizeof md);
    md.data = plate_data(mode == 0 ? plate_pos : h->rest);
    md.caches = mode == 0 ? plate_caches : &h->plate_set;
    md.deforming = mode != 0;
    if (mode == 2) {
        glGenBuffers(1, &h->vbo);
        glBindBuffer(GL_ARRAY_BUFFER, h->vbo);
        glBufferData(GL_ARRAY_BUFFER, VOFF + NV * STRIDE, NULL, GL_DYNAMIC_DRAW);
        glBindBuffer(GL_ARRAY_BUFFER, 0);
        host_write(h, h->rest);
        md.data.positions = NULL;
        md.buffers.positions = md.buffers.normals = h->vbo;
        md.buffers.position_offset = VOFF;
        md.buffers.normal_offset = VOFF + 12;
        md.buffers.position_stride = md.buffers.normal_stride = STRIDE;
        md.buffers.indices = gltest_ssbo(sizeof plate_idx, plate_idx);
    }
    assert_int_equal(gim_add_mesh(h->f.ctx, &md, &h->plate), GIM_OK);
    if (mode == 2) {
        GLuint ib = md.buffers.indices;
        (void)ib;   /* kept alive by the mesh until teardown */
    }
    memcpy(mats, room_materials, sizeof room_materials);
    mats[3].glossy[0] = mats[3].glossy[1] = mats[3].glossy[2] = 0.0f;   /* diffuse only: no glossy pass */
    mats[4] = room_materials[0];
    mats[4].diffuse[0] = 0.9f; mats[4].diffuse[1] = 0.7f; mats[4].diffuse[2] = 0.3f;
    assert_int_equal(gim_set_materials(h->f.ctx, mats, 5), GIM_OK);
    in[0].mesh = h->room_mesh;
    in[0].model = gim_mat4_identity();
    in[1].mesh = h->plate;
    in[1].model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(h->f.ctx, in, 2), GIM_OK);
    sun = room_sun();
    assert_int_equal(gim_set_lights(h->f.ctx, &sun, 1), GIM_OK);
    memset(&h->fr, 0, sizeof h->fr);
    h->fr.view = gim_mat4_look_at(gim_v3(0.0f, 1.6f, 3.8f), gim_v3(0.0f, 0.6f, -2.0f), gim_v3(0, 1, 0));
    h->fr.proj = gim_mat4_perspective(1.2f, (float)W / H, 0.05f, 50.0f);
    h->fr.width = W;
    h->fr.height = H;
    h->fr.method = GIM_METHOD_LIGHTSKIN_FULL;   /* every RSM texel a VAL: no sampling noise between the runs */
}

static void teardown(deform_fx *h) {
    GLuint ib = 0;
    if (h->vbo) {
        gim__mesh *m = gim__mesh_get(h->f.ctx, h->plate);
        ib = m->indices;
    }
    gim_cache_set_free(&h->room_set);
    gim_cache_set_free(&h->plate_set);
    gltest_fixture_end(&h->f);
    if (h->vbo) {
        glDeleteBuffers(1, &h->vbo);
        glDeleteBuffers(1, &ib);
    }
}

/* The GPU's followed caches of the plate (model space). */
static void read_followed(deform_fx *h, gim_cache *out) {
    gim__mesh *m = gim__mesh_get(h->f.ctx, h->plate);
    assert_non_null(m);
    assert_true(m->followed != 0);
    gltest_read_buffer(m->followed, (size_t)m->cache_count * sizeof(gim_cache), out);
}

/* Largest differences between two cache lists: position (absolute), normal, area (relative). */
static void cache_diff(const gim_cache *a, const gim_cache *b, uint32_t n, double *dp, double *dn, double *da) {
    uint32_t i;
    int k;
    *dp = *dn = *da = 0.0;
    for (i = 0; i < n; ++i) {
        for (k = 0; k < 3; ++k) {
            double p = fabs((double)a[i].position[k] - b[i].position[k]), q = fabs((double)a[i].normal[k] - b[i].normal[k]);
            if (p > *dp) *dp = p;
            if (q > *dn) *dn = q;
        }
        if (fabs((double)a[i].area - b[i].area) / (b[i].area > 1e-6f ? b[i].area : 1e-6) > *da)
            *da = fabs((double)a[i].area - b[i].area) / (b[i].area > 1e-6f ? b[i].area : 1e-6);
        assert_true(a[i].reflectance == b[i].reflectance);
    }
}

static void twin(void **state) {
    deform_fx h;
    float bent[NV * 3];
    gim_cache *gpu, *cpu;
    gim_cache_binding *bind;
    gim_follow_desc fd;
    gim_mesh_data d;
    double dp, dn, da;
    int path;
    (void)state;
    GLTEST_BEGIN();
    for (path = 1; path <= 2; ++path) {
        setup(&h, path, NULL, NULL);
        deform_bend(h.rest, bent);
        if (path == 1) {
            float v0[3];
            assert_int_equal(gim_update_mesh_vertices(h.f.ctx, h.plate, bent, NULL, NV), GIM_OK);
            gltest_read_buffer(gim__mesh_get(h.f.ctx, h.plate)->positions, sizeof v0, v0);
            if (v0[0] != bent[0] || v0[1] != bent[1] || v0[2] != bent[2])
                print_message("vertex 0 before the frame: %g %g %g, bent %g %g %g\n", (double)v0[0], (double)v0[1],
                              (double)v0[2], (double)bent[0], (double)bent[1], (double)bent[2]);
            assert_true(v0[0] == bent[0] && v0[1] == bent[1] && v0[2] == bent[2]);
        } else {
            host_write(&h, bent);
        }
        assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
        gpu = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
        cpu = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
        bind = (gim_cache_binding *)malloc(h.plate_set.count * sizeof(gim_cache_binding));
        read_followed(&h, gpu);
        d = plate_data(h.rest);
        assert_int_equal(gim_cache_bind(&d, h.plate_set.caches, h.plate_set.count, bind, h.f.env), GIM_OK);
        memset(&fd, 0, sizeof fd);
        fd.rest = h.plate_set.caches; fd.bind = bind; fd.count = h.plate_set.count; fd.positions = bent;
        fd.vertex_count = NV; fd.env = h.f.env;
        assert_int_equal(gim_caches_follow_twin(&fd, cpu), GIM_OK);
        cache_diff(gpu, cpu, h.plate_set.count, &dp, &dn, &da);
        print_message("path %d: %u caches, GPU vs twin: position %.2e, normal %.2e, area %.2e (relative)\n", path,
                      (unsigned)h.plate_set.count, dp, dn, da);
        if (!(dp < 2.4e-5))   /* where the GPU's caches parted from the twin's: moved, or left at rest */
            print_message("  cache 0: GPU %g %g %g area %g, twin %g %g %g area %g, rest %g %g %g area %g\n",
                          (double)gpu[0].position[0], (double)gpu[0].position[1], (double)gpu[0].position[2], (double)gpu[0].area,
                          (double)cpu[0].position[0], (double)cpu[0].position[1], (double)cpu[0].position[2], (double)cpu[0].area,
                          (double)h.plate_set.caches[0].position[0], (double)h.plate_set.caches[0].position[1],
                          (double)h.plate_set.caches[0].position[2], (double)h.plate_set.caches[0].area);
        /* float rounding of the same operations (llvmpipe may fuse multiply-adds): 1e-5 of the plate's 2.4 */
        assert_true(dp < 2.4e-5 && dn < 1e-5 && da < 1e-5);
        /* the bend moved them: a pass that did nothing would fail the line above */
        cache_diff(h.plate_set.caches, cpu, h.plate_set.count, &dp, &dn, &da);
        assert_true(dp > 0.1 && dn > 0.1);
        gltest_state_unchanged(&h.f);
        {   /* what following costs a frame (llvmpipe: a ratio, not a GPU figure): the arrays' mesh
               unchanged since the last frame (nothing followed: a static scene's frame), the same
               with new vertices every frame, the host's buffer (followed every frame) */
            double t0, ms[2];
            int k, v;
            for (v = 0; v < (path == 1 ? 2 : 1); ++v) {
                glFinish();
                t0 = gim__clock_ms(h.f.ctx);
                for (k = 0; k < 4; ++k) {
                    if (v == 1) assert_int_equal(gim_update_mesh_vertices(h.f.ctx, h.plate, k & 1 ? h.rest : bent, NULL, NV), GIM_OK);
                    assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
                }
                glFinish();
                ms[v] = (gim__clock_ms(h.f.ctx) - t0) / 4.0;
            }
            if (path == 1) print_message("path 1: %.1f ms a frame unchanged, %.1f ms with new vertices every frame\n", ms[0], ms[1]);
            else print_message("path 2: %.1f ms a frame (the host's buffer followed every frame)\n", ms[0]);
        }
        free(gpu); free(cpu); free(bind);
        teardown(&h);
    }
    GLTEST_END();
}

static void affine_caches(void **state) {
    deform_fx h;
    float moved[NV * 3];
    gim_cache *gpu, *want;
    double dp, dn, da, sum = 0.0, closed;
    uint32_t i;
    int path;
    (void)state;
    GLTEST_BEGIN();
    for (path = 1; path <= 2; ++path) {
        setup(&h, path, NULL, NULL);
        deform_affine(h.rest, moved);
        if (path == 1) assert_int_equal(gim_update_mesh_vertices(h.f.ctx, h.plate, moved, NULL, NV), GIM_OK);
        else host_write(&h, moved);
        assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
        gpu = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
        want = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
        read_followed(&h, gpu);
        assert_int_equal(gim_caches_to_world(h.plate_set.caches, h.plate_set.count, affine(), want, h.f.env), GIM_OK);
        cache_diff(gpu, want, h.plate_set.count, &dp, &dn, &da);
        for (i = 0; i < h.plate_set.count; ++i) sum += gpu[i].area;
        {   /* the sheared plate's area: 2.4^2 |det A| |A^-T y| = 2.4^2 |A e_x x A e_z| */
            gim_vec3 ax = gim_v3(A3[0], A3[1], A3[2]), az = gim_v3(A3[6], A3[7], A3[8]);
            gim_vec3 c = gim__v3_cross(ax, az);
            closed = 2.4 * 2.4 * sqrt((double)c.x * c.x + (double)c.y * c.y + (double)c.z * c.z);
        }
        print_message("path %d: followed vs A applied to the rest caches: position %.2e, normal %.2e, area %.2e; "
                      "area sum %.6f, closed form %.6f\n", path, dp, dn, da, sum, closed);
        assert_true(dp < 1e-4 && dn < 1e-4 && da < 1e-4);
        assert_true(fabs(sum - closed) < 1e-4 * closed);
        cache_diff(h.plate_set.caches, want, h.plate_set.count, &dp, &dn, &da);
        print_message("  the rest caches (the pass off) miss by position %.3f, normal %.3f, area %.3f\n", dp, dn, da);
        assert_true(dp > 0.1 && dn > 0.1 && da > 0.05);
        sum = 0.0;
        free(gpu); free(want);
        teardown(&h);
    }
    GLTEST_END();
}

/* The indirect image of the scene with the plate at p: static (caches given), or deforming
   through path 1 / 2 after a first frame at rest; rest_only: the deforming plate's frame at
   rest only, then p is handed over but no frame is run (what a frame would show had nothing
   followed). */
static void image(int mode, const float *p, const gim_cache_set *caches, gim_visibility vis, float *rgba) {
    deform_fx h;
    setup(&h, mode, p, caches);
    h.fr.visibility.mode = vis;
    if (mode != 0) {
        assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);   /* at rest: caches, grid, ISMs made for it */
        if (mode == 1) assert_int_equal(gim_update_mesh_vertices(h.f.ctx, h.plate, p, NULL, NV), GIM_OK);
        else host_write(&h, p);
    }
    assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
    gltest_read_texture(gim_outputs(h.f.ctx).indirect, GL_RGBA, rgba);
    gltest_state_unchanged(&h.f);
    teardown(&h);
}

static double image_diff(const float *a, const float *b, double *mean) {
    double num = 0.0, den = 0.0;
    int i;
    for (i = 0; i < W * H * 4; ++i) {
        if (i % 4 == 3) continue;
        num += fabs((double)a[i] - b[i]);
        den += fabs((double)b[i]);
    }
    *mean = den / (W * H * 3);
    return num / den;
}

/* The same geometry as a static mesh: its caches the rest ones moved on the CPU. */
static void same_as_static(void (*deform)(const float *, float *), gim_visibility vis, const char *what) {
    float p[NV * 3], *stat = (float *)malloc(W * H * 16), *def = (float *)malloc(W * H * 16), *rest = (float *)malloc(W * H * 16);
    deform_fx h;
    gim_cache_set moved;
    gim_cache_binding *bind;
    gim_follow_desc fd;
    gim_mesh_data d;
    double e1, e2, e0, mean;
    /* the rest caches, generated as setup generates them, followed on the CPU */
    setup(&h, 1, NULL, NULL);
    deform(h.rest, p);
    memset(&moved, 0, sizeof moved);
    moved = h.plate_set;
    moved.caches = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
    bind = (gim_cache_binding *)malloc(h.plate_set.count * sizeof(gim_cache_binding));
    d = plate_data(h.rest);
    assert_int_equal(gim_cache_bind(&d, h.plate_set.caches, h.plate_set.count, bind, h.f.env), GIM_OK);
    memset(&fd, 0, sizeof fd);
    fd.rest = h.plate_set.caches; fd.bind = bind; fd.count = h.plate_set.count; fd.positions = p; fd.vertex_count = NV;
    fd.env = h.f.env;
    assert_int_equal(gim_caches_follow_twin(&fd, moved.caches), GIM_OK);
    teardown(&h);
    image(0, p, &moved, vis, stat);
    image(1, p, NULL, vis, def);
    e1 = image_diff(def, stat, &mean);
    image(2, p, NULL, vis, def);
    e2 = image_diff(def, stat, &mean);
    {   /* the pass and the invalidation off: the rest pose's frame */
        deform_fx r;
        setup(&r, 1, NULL, NULL);
        r.fr.visibility.mode = vis;
        assert_int_equal(gim_update(r.f.ctx, &r.fr), GIM_OK);
        gltest_read_texture(gim_outputs(r.f.ctx).indirect, GL_RGBA, rest);
        teardown(&r);
    }
    e0 = image_diff(rest, stat, &mean);
    print_message("%s, visibility %d: deformed vs static, rel. MAE %.2e (arrays), %.2e (host buffer); rest pose %.3f; "
                  "mean %.5f\n", what, (int)vis, e1, e2, e0, mean);
    assert_true(mean > 1e-3);
    assert_true(e1 < 2e-4 && e2 < 2e-4);
    assert_true(e0 > 0.05);
    free(moved.caches); free(bind);
    free(stat); free(def); free(rest);
}

static void images_affine(void **state) {
    (void)state;
    GLTEST_BEGIN();
    same_as_static(deform_affine, GIM_VISIBILITY_OFF, "affine");
    GLTEST_END();
}

static void images_bend_ism(void **state) {
    (void)state;
    GLTEST_BEGIN();
    same_as_static(deform_bend, GIM_VISIBILITY_ISM, "bend");
    GLTEST_END();
}

static void bad_input(void **state) {
    deform_fx h, s;
    float p[NV * 3];
    gim_cache *before;
    int errors = 0, serrors = 0;
    (void)state;
    GLTEST_BEGIN();
    setup(&h, 1, NULL, NULL);
    plate_rest(p);
#define EXPECT(fx, e, call) do { assert_int_equal((call), GIM_ERROR_INVALID_ARGUMENT); assert_int_equal(fx.f.log.errors, ++e); \
        assert_int_equal(glGetError(), GL_NO_ERROR); } while (0)
    EXPECT(h, errors, gim_update_mesh_vertices(h.f.ctx, h.plate, p, NULL, NV - 1));     /* wrong count */
    p[7] = NAN;
    EXPECT(h, errors, gim_update_mesh_vertices(h.f.ctx, h.plate, p, NULL, NV));         /* non-finite position */
    p[7] = 0.7f;
    {
        float n[NV * 3];
        int i;
        for (i = 0; i < NV * 3; ++i) n[i] = i % 3 == 1 ? 1.0f : 0.0f;
        n[4] = INFINITY;
        EXPECT(h, errors, gim_update_mesh_vertices(h.f.ctx, h.plate, p, n, NV));        /* non-finite normal */
    }
    EXPECT(h, errors, gim_update_mesh_vertices(h.f.ctx, h.room_mesh, p, NULL, NV));     /* not deforming */
    EXPECT(h, errors, gim_update_mesh_vertices(h.f.ctx, h.plate, NULL, NULL, NV));      /* no positions */
    /* the scene is as it was: the plate's caches still at rest */
    before = (gim_cache *)malloc(h.plate_set.count * sizeof(gim_cache));
    assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
    read_followed(&h, before);
    {
        double dp, dn, da;
        cache_diff(before, h.plate_set.caches, h.plate_set.count, &dp, &dn, &da);
        assert_true(dp < 1e-5 && dn < 1e-5 && da < 1e-5);
    }
    free(before);
    { /* a static mesh pays nothing: no binding, no followed caches, no index copy */
        gim__mesh *m = gim__mesh_get(h.f.ctx, h.room_mesh);
        assert_true(!m->deforming && !m->bound && !m->followed && !m->follow_cpu && !m->tri_vertex);
    }
    h.f.log.errors = 0;
    gltest_state_unchanged(&h.f);
    teardown(&h);
    /* the host's buffer */
    setup(&s, 2, NULL, NULL);
    plate_rest(p);
    EXPECT(s, serrors, gim_update_mesh_vertices(s.f.ctx, s.plate, p, NULL, NV));       /* its vertices are the host's */
    {
        float keep = p[3 * 5 + 2];
        p[3 * 5 + 2] = NAN;
        host_write(&s, p);
        EXPECT(s, serrors, gim_update(s.f.ctx, &s.fr));                                   /* a NaN in the host's buffer */
        p[3 * 5 + 2] = keep;
    }
    host_write(&s, p);
    assert_int_equal(gim_update(s.f.ctx, &s.fr), GIM_OK);                               /* and well again */
#undef EXPECT
    s.f.log.errors = 0;
    gltest_state_unchanged(&s.f);
    teardown(&s);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(twin),
        cmocka_unit_test(affine_caches),
        cmocka_unit_test(images_affine),
        cmocka_unit_test(images_bend_ism),
        cmocka_unit_test(bad_input),
    };
    int r;
    (void)room_receiver;
    r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
