/* Meshes in the host's own GL buffers (gim_mesh_desc.buffers): an engine's interleaved vertex
   buffer (position, normal, uv; 36-byte stride, a header before vertex 0) and a 16-bit index
   buffer at an offset. The same room drawn from them gives the image of the uploaded copy, bit
   for bit, for LightSkin with imperfect shadow maps (which read the positions back) and for
   clustered visibility (the paraboloid maps draw the mesh too); gimany allocates no vertex or
   index buffer for it and deletes none of the host's. Bad layouts are refused with one message
   and no GL error left for the host. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "room.h"

enum { W = 40, H = 30, STRIDE = 36, VOFF = 20, IOFF = 64 };

typedef struct host_fx {
    gltest_fixture f;
    room r;
    gim_cache_set set;
    gim_mesh mesh;
    GLuint vbo, ibo;
    gim_frame fr;
} host_fx;

/* The room as an engine keeps it: one interleaved buffer, one 16-bit index buffer, both with
   other data in front. */
static void host_buffers(host_fx *h) {
    uint32_t nv = h->r.quads * 4, ni = h->r.quads * 6, i;
    unsigned char *vb = (unsigned char *)calloc(VOFF + (size_t)nv * STRIDE, 1), *ib = (unsigned char *)calloc(IOFF + (size_t)ni * 2, 1);
    memset(vb, 0x7f, VOFF);   /* a header of NaNs: drawing from offset 0 would show */
    memset(ib, 0xff, IOFF);
    for (i = 0; i < nv; ++i) {
        float uv[2] = {0.25f, 0.75f};
        memcpy(vb + VOFF + (size_t)i * STRIDE, h->r.pos + i * 3, 12);
        memcpy(vb + VOFF + (size_t)i * STRIDE + 12, h->r.nrm + i * 3, 12);
        memcpy(vb + VOFF + (size_t)i * STRIDE + 24, uv, 8);
    }
    for (i = 0; i < ni; ++i) {
        uint16_t s = (uint16_t)h->r.idx[i];
        memcpy(ib + IOFF + (size_t)i * 2, &s, 2);
    }
    glGenBuffers(1, &h->vbo);
    glGenBuffers(1, &h->ibo);
    glBindBuffer(GL_ARRAY_BUFFER, h->vbo);
    glBufferData(GL_ARRAY_BUFFER, VOFF + (GLsizeiptr)nv * STRIDE, vb, GL_STATIC_DRAW);
    glBindBuffer(GL_ARRAY_BUFFER, h->ibo);   /* not the element target: no VAO is bound */
    glBufferData(GL_ARRAY_BUFFER, IOFF + (GLsizeiptr)ni * 2, ib, GL_STATIC_DRAW);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    free(vb);
    free(ib);
}

static gim_mesh_desc host_desc(const host_fx *h) {
    gim_mesh_desc md;
    memset(&md, 0, sizeof md);
    md.data.vertex_count = h->r.quads * 4;
    md.data.index_count = h->r.quads * 6;
    md.data.index_type = GIM_INDEX_U16;
    md.data.triangle_material = h->r.mat;
    md.caches = &h->set;
    md.buffers.positions = h->vbo;
    md.buffers.position_offset = VOFF;
    md.buffers.position_stride = STRIDE;
    md.buffers.normals = h->vbo;
    md.buffers.normal_offset = VOFF + 12;
    md.buffers.normal_stride = STRIDE;
    md.buffers.indices = h->ibo;
    md.buffers.index_offset = IOFF;
    return md;
}

static void setup(host_fx *h, int host) {
    gim_cache_desc cd;
    gim_mesh_desc md;
    gim_instance in;
    gim_light sun;
    memset(h, 0, sizeof *h);
    gltest_fixture_begin(&h->f);
    room_open_box(&h->r);
    memset(&cd, 0, sizeof cd);
    cd.mesh = room_arrays(&h->r);
    cd.d_eps = 0.5f;
    assert_int_equal(gim_cache_generate(&cd, &h->set), GIM_OK);
    host_buffers(h);
    if (host) {
        md = host_desc(h);
    } else {
        memset(&md, 0, sizeof md);
        md.data = room_arrays(&h->r);
        md.caches = &h->set;
    }
    assert_int_equal(gim_add_mesh(h->f.ctx, &md, &h->mesh), GIM_OK);
    assert_int_equal(gim_set_materials(h->f.ctx, room_materials, 4), GIM_OK);
    in.mesh = h->mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(h->f.ctx, &in, 1), GIM_OK);
    sun = room_sun();
    assert_int_equal(gim_set_lights(h->f.ctx, &sun, 1), GIM_OK);
    memset(&h->fr, 0, sizeof h->fr);
    h->fr.view = gim_mat4_look_at(gim_v3(0.0f, 1.2f, 3.5f), gim_v3(0.0f, 0.8f, -2.0f), gim_v3(0, 1, 0));
    h->fr.proj = gim_mat4_perspective(1.2f, (float)W / H, 0.05f, 50.0f);
    h->fr.width = W;
    h->fr.height = H;
}

static void teardown(host_fx *h) {
    gim_cache_set_free(&h->set);
    gltest_fixture_end(&h->f);
    assert_true(glIsBuffer(h->vbo) && glIsBuffer(h->ibo));   /* gimany deleted neither */
    glDeleteBuffers(1, &h->vbo);
    glDeleteBuffers(1, &h->ibo);
}

/* The indirect image of `method` (visibility as given) for the room uploaded or drawn from the
   host's buffers, and the GPU bytes gimany owns. */
static void render(int host, gim_method method, gim_visibility vis, float *rgba, uint64_t *bytes) {
    host_fx h;
    gim_stats st;
    setup(&h, host);
    h.fr.method = method;
    h.fr.visibility.mode = vis;
    assert_int_equal(gim_update(h.f.ctx, &h.fr), GIM_OK);
    gltest_read_texture(gim_outputs(h.f.ctx).indirect, GL_RGBA, rgba);
    assert_int_equal(gim_frame_stats(h.f.ctx, &st), GIM_OK);
    *bytes = st.gpu_bytes;
    gltest_state_unchanged(&h.f);
    teardown(&h);
}

static void same_image(gim_method method, gim_visibility vis) {
    float *a = (float *)malloc(W * H * 16), *b = (float *)malloc(W * H * 16);
    uint64_t bytes_own, bytes_host;
    double sum = 0.0;
    int i;
    render(0, method, vis, a, &bytes_own);
    render(1, method, vis, b, &bytes_host);
    for (i = 0; i < W * H * 4; ++i) sum += a[i];
    print_message("method %d visibility %d: images %s (mean %.5f); GPU bytes %llu uploaded, %llu from the host's buffers\n",
                  (int)method, (int)vis, memcmp(a, b, W * H * 16) == 0 ? "identical" : "DIFFER", sum / (W * H * 3),
                  (unsigned long long)bytes_own, (unsigned long long)bytes_host);
    assert_true(sum > 0.0);
    assert_memory_equal(a, b, W * H * 16);
    /* the host's mesh costs gimany its per-triangle materials only: 20 vertices x 24 + 30 indices x 4 fewer bytes */
    assert_true(bytes_own - bytes_host == 20u * 24u + 30u * 4u);
    free(a);
    free(b);
}

static void lightskin_with_ism(void **state) {
    (void)state;
    GLTEST_BEGIN();
    same_image(GIM_METHOD_LIGHTSKIN_BRSM, GIM_VISIBILITY_ISM);
    GLTEST_END();
}

static void clustered(void **state) {
    (void)state;
    GLTEST_BEGIN();
    same_image(GIM_METHOD_CLUSTERED, GIM_VISIBILITY_OFF);
    GLTEST_END();
}

static void bad_layouts(void **state) {
    host_fx h;
    gim_mesh_desc md;
    gim_mesh mesh;
    int errors = 0;
    (void)state;
    GLTEST_BEGIN();
    setup(&h, 0);
#define EXPECT(call, code) do { assert_int_equal((call), (code)); assert_int_equal(h.f.log.errors, ++errors); \
        assert_int_equal(glGetError(), GL_NO_ERROR); } while (0)
    md = host_desc(&h);
    md.buffers.normals = 0;                         /* a name missing */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md = host_desc(&h);
    md.buffers.indices = 987654;                    /* not a buffer */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md = host_desc(&h);
    md.data.vertex_count += 1;                      /* past the buffer's end */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md = host_desc(&h);
    md.buffers.index_offset = IOFF + 1;             /* misaligned */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md = host_desc(&h);
    md.buffers.position_stride = 8;                 /* shorter than a float3 */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
    md = host_desc(&h);
    md.data.vertex_count = 19;                      /* the indices name vertex 19: checked on the read-back */
    EXPECT(gim_add_mesh(h.f.ctx, &md, &mesh), GIM_ERROR_INVALID_ARGUMENT);
#undef EXPECT
    h.f.log.errors = 0;
    gltest_state_unchanged(&h.f);
    teardown(&h);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lightskin_with_ism),
        cmocka_unit_test(clustered),
        cmocka_unit_test(bad_layouts),
    };
    int r;
    (void)room_receiver;
    r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
