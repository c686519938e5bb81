/* The LightSkin shading pass (per pixel neighbours, interpolation eq. 8-9, shading) on a real
   G-buffer against its twin: gim_cache_neighbours on the unprojected pixels, truncated at the
   pass's search radius, then gim_lightskin_shade_twin. And gim_caches_to_world and the hash grid
   the pass searches. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

/* --- a room: floor, three walls, a block; big triangles (two per face) ----------------------- */

#include "room.h"

/* Side L: floor y = 0 (material 0, white), left wall x = 0 (1, red), right wall x = L (2,
   green), back wall z = 0 (3, glossy), a block 0.3 L wide on the floor (0). */
static void make_room(room *r, float L) {
    float c[3], u[3], v[3];
    float b0 = 0.35f * L, b1 = 0.65f * L, bh = 0.3f * L;
    memset(r, 0, sizeof *r);
#define SET3(a, x, y, z) ((a)[0] = (x), (a)[1] = (y), (a)[2] = (z))
    SET3(c, 0, 0, 0); SET3(u, 0, 0, L); SET3(v, L, 0, 0); add_quad(r, c, u, v, 0);       /* floor, +y */
    SET3(c, 0, 0, 0); SET3(u, 0, L, 0); SET3(v, 0, 0, L); add_quad(r, c, u, v, 1);       /* left, +x */
    SET3(c, L, 0, 0); SET3(u, 0, 0, L); SET3(v, 0, L, 0); add_quad(r, c, u, v, 2);       /* right, -x */
    SET3(c, 0, 0, 0); SET3(u, L, 0, 0); SET3(v, 0, L, 0); add_quad(r, c, u, v, 3);       /* back, +z */
    SET3(c, b0, bh, b0); SET3(u, 0, 0, b1 - b0); SET3(v, b1 - b0, 0, 0); add_quad(r, c, u, v, 0); /* block top */
    SET3(c, b0, 0, b1); SET3(u, b1 - b0, 0, 0); SET3(v, 0, bh, 0); add_quad(r, c, u, v, 0);       /* block +z */
    SET3(c, b0, 0, b0); SET3(u, 0, 0, b1 - b0); SET3(v, 0, bh, 0); add_quad(r, c, u, v, 0);       /* block -x */
    SET3(c, b1, 0, b0); SET3(u, 0, bh, 0); SET3(v, 0, 0, b1 - b0); add_quad(r, c, u, v, 0);       /* block +x */
#undef SET3
}

static gim_mesh_data room_mesh(const room *r) {
    gim_mesh_data m;
    memset(&m, 0, sizeof m);
    m.positions = r->pos;
    m.normals = r->nrm;
    m.vertex_count = r->quads * 4;
    m.indices = r->idx;
    m.index_count = r->quads * 6;
    m.triangle_material = r->mat;
    return m;
}


/* VALs of a lit patch on the floor and on the block top (normal up), random flux. */
static gim_val *make_vals(float L, uint32_t count) {
    gim_val *v = (gim_val *)calloc(count, sizeof *v);
    uint32_t i;
    for (i = 0; i < count; ++i) {
        int top = i % 5 == 0;
        v[i].position[0] = top ? test_rnd(0.35f, 0.65f) * L : test_rnd(0.05f, 0.3f) * L;
        v[i].position[1] = top ? 0.3f * L : 0.0f;
        v[i].position[2] = top ? test_rnd(0.35f, 0.65f) * L : test_rnd(0.4f, 0.95f) * L;
        v[i].normal[1] = 1.0f;
        v[i].area = 0.5f * L * L / (float)count;
        v[i].weight = 1.0f;
        v[i].flux[0] = test_rnd(0.2f, 1.0f) / (float)count;
        v[i].flux[1] = test_rnd(0.2f, 1.0f) / (float)count;
        v[i].flux[2] = test_rnd(0.2f, 1.0f) / (float)count;
    }
    return v;
}

/* --- caches to world ------------------------------------------------------------------------ */

static void caches_to_world_keeps_area_and_normals(void **state) {
    room r;
    gim_cache_desc cd;
    gim_cache_set set;
    gim_cache *w;
    gim_mat4 m = gim_mat4_identity(), bad = gim_mat4_identity();
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    double a0 = 0.0, a1 = 0.0, det;
    uint32_t i;
    (void)state;
    make_room(&r, 2.0f);
    memset(&cd, 0, sizeof cd);
    cd.mesh = room_mesh(&r);
    cd.env = env;
    assert_int_equal(gim_cache_generate(&cd, &set), GIM_OK);
    w = (gim_cache *)malloc(set.count * sizeof *w);
    /* a non-uniform scale and shear, rotated and moved far away */
    m.m[0] = 2.0f; m.m[5] = 0.5f; m.m[10] = 3.0f; m.m[4] = 0.7f; m.m[9] = -0.4f;
    m.m[12] = 1e4f; m.m[13] = -3e3f; m.m[14] = 5.0f;
    det = 2.0 * (0.5 * 3.0 - (-0.4) * 0.0) - 0.7 * (0.0 * 3.0 - (-0.4) * 0.0) + 0.0;
    assert_true(det > 0.0);
    assert_int_equal(gim_caches_to_world(set.caches, set.count, m, w, env), GIM_OK);
    for (i = 0; i < set.count; ++i) {
        gim_vec3 n0 = gim_v3(set.caches[i].normal[0], set.caches[i].normal[1], set.caches[i].normal[2]);
        gim_vec3 n1 = gim_v3(w[i].normal[0], w[i].normal[1], w[i].normal[2]);
        gim_vec3 t, b, tw, bw;
        gim__basis(n0, &t, &b);
        tw = gim__mat4_dir(m, t);
        bw = gim__mat4_dir(m, b);
        /* the world normal is perpendicular to the placed tangents, unit, and the area scales
           with the placed parallelogram t x b */
        assert_true(fabsf(gim__v3_dot(n1, tw)) < 1e-5f * gim__v3_length(tw));
        assert_true(fabsf(gim__v3_dot(n1, bw)) < 1e-5f * gim__v3_length(bw));
        assert_true(fabsf(gim__v3_length(n1) - 1.0f) < 1e-6f);
        assert_true(fabs(w[i].area - set.caches[i].area * gim__v3_length(gim__v3_cross(tw, bw))) <=
                    1e-5 * w[i].area);
        assert_true(gim__v3_dot(n1, gim__v3_cross(tw, bw)) > 0.0f);
        a0 += set.caches[i].area;
        a1 += w[i].area;
    }
    assert_true(a0 > 0.0 && a1 > a0);
    /* singular and non-finite models; NULL arrays */
    bad.m[5] = 0.0f;
    assert_int_equal(gim_caches_to_world(set.caches, set.count, bad, w, env), GIM_ERROR_INVALID_ARGUMENT);
    bad = gim_mat4_identity();
    bad.m[12] = NAN;
    assert_int_equal(gim_caches_to_world(set.caches, set.count, bad, w, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_caches_to_world(NULL, 3, m, w, env), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_caches_to_world(NULL, 0, m, NULL, env), GIM_OK);
    assert_int_equal(lg.errors, 3);
    free(w);
    gim_cache_set_free(&set);
    assert_int_equal(st.live, 0);
}

/* The grid sorts every cache into the bucket of its cell, and a bucket's caches are found. */
static void grid_holds_every_cache_once(void **state) {
    enum { N = 3000 };
    gim_cache *in = (gim_cache *)calloc(N, sizeof *in), *out;
    int32_t *cells;
    uint32_t *buckets, i;
    gim__grid g;
    test_alloc_stats st;
    test_log lg;
    gim_env env = test_env(&st, &lg);
    double sum_in = 0.0, sum_out = 0.0;
    (void)state;
    for (i = 0; i < N; ++i) {
        in[i].position[0] = test_rnd(-5e3f, -4e3f);  /* far from the origin */
        in[i].position[1] = test_rnd(0.0f, 1.0f) * (i % 2 ? 1.0f : 0.0f);
        in[i].position[2] = test_rnd(0.0f, 800.0f);
        in[i].normal[1] = 1.0f;
        in[i].area = test_rnd(0.5f, 2.0f);
        sum_in += in[i].position[0] + 3.0 * in[i].position[2] + in[i].area;
    }
    assert_int_equal(gim__grid_build(&env, in, N, 1.0f, &g, &out, &cells, &buckets), GIM_OK);
    assert_true(g.bucket_count >= 2u * N && (g.bucket_count & (g.bucket_count - 1u)) == 0u);
    assert_int_equal(buckets[0], 0);
    assert_int_equal(buckets[g.bucket_count], N);
    for (i = 0; i < g.bucket_count; ++i) {
        uint32_t k;
        assert_true(buckets[i] <= buckets[i + 1]);
        for (k = buckets[i]; k < buckets[i + 1]; ++k) {
            const int32_t *c = cells + k * 4;
            int a;
            assert_int_equal(gim__grid_hash(c[0], c[1], c[2]) & (g.bucket_count - 1u), i);
            for (a = 0; a < 3; ++a) {
                float f = (out[k].position[a] - g.origin[a]) / g.h;
                assert_true(c[a] >= 0 && c[a] < g.dims[a]);
                assert_true(c[a] == (int32_t)floorf(f) || (c[a] == g.dims[a] - 1 && f >= (float)c[a]));
            }
        }
    }
    for (i = 0; i < N; ++i) sum_out += out[i].position[0] + 3.0 * out[i].position[2] + out[i].area;
    assert_true(fabs(sum_in - sum_out) <= 1e-9 * fabs(sum_in)); /* a permutation (same sum) */
    /* the cell is twice the mean spacing: sqrt of the mean area (1.25) */
    assert_true(fabsf(g.h - 2.0f * sqrtf(1.25f)) < 0.05f);
    gim__free(&env, out);
    gim__free(&env, cells);
    gim__free(&env, buckets);
    free(in);
    assert_int_equal(st.live, 0);
}

/* --- the shading pass against its twin --------------------------------------------------- */

typedef struct shade_case {
    uint32_t n;          /* neighbours */
    int glossy;
    int host;            /* the host's G-buffer: albedo 1, no glossy */
    uint32_t list_limit; /* caches a tile's list may hold; 0: the pass's; 1: every tile per pixel */
    uint32_t block;      /* the pass's shade_block: 1 or 2 */
    uint32_t slabs;      /* the tiles' lists: 0 by their box, 1 in slabs, 2 in rings */
    int rays;            /* neighbour_rays: the room's hierarchy, the twin gim_neighbour_rays_twin */
} shade_case;

/* The room's triangles in a hierarchy (gim_bvh_build), uploaded as gim__gl_bvh lays it out:
   nodes, then triangles. */
static GLuint room_bvh(const room *r, gim_env env, uint32_t *nodes, gim_bvh *b) {
    float *tri = (float *)malloc(r->quads * 2u * 9u * sizeof(float)), *buf;
    gim_twin_scene ts;
    uint32_t t, k;
    GLuint id;
    size_t nb, tb;
    for (t = 0; t < r->quads * 2u; ++t)
        for (k = 0; k < 3u; ++k) memcpy(tri + t * 9u + k * 3u, r->pos + r->idx[t * 3u + k] * 3u, 12);
    memset(&ts, 0, sizeof ts);
    ts.positions = tri;
    ts.triangle_count = r->quads * 2u;
    assert_int_equal(gim_bvh_build(&ts, env, b), GIM_OK);
    free(tri);
    nb = (size_t)b->node_count * 32u;
    tb = (size_t)b->triangle_count * 48u;
    buf = (float *)malloc(nb + tb);
    memcpy(buf, b->nodes, nb);
    memcpy((char *)buf + nb, b->triangles, tb);
    id = gltest_ssbo((GLsizeiptr)(nb + tb), buf);
    free(buf);
    *nodes = b->node_count;
    return id;
}

static void run_shade_case(const shade_case *sc, float L, const float origin[3]) {
    enum { W = 80, H = 60, NV = 400 };
    gltest_fixture f;
    room r;
    gim_cache_desc cd;
    gim_cache_set set, ws;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance in;
    gim_frame fr;
    gim_camera cam;
    gim_frame_outputs o;
    gim_cache *world, *sorted;
    int32_t *cells;
    uint32_t *buckets, i, nrec = 0, *pix, *nb_idx, *nb_cnt, *src, *rpix, shared_n = 0;
    float *depth, *nrm, *alb, *mat, *gpu, *cpu, *dcmax, *pos_nrm;
    gim_view_sample *vs;
    gim_receiver *rec;
    gim_proxy_light *pd, *pg;
    gim_val *vals;
    gim__grid g;
    gim__shade_args sa;
    gim_proxy_desc pdesc;
    gim_neighbour_desc nd;
    gim_neighbour_result nr;
    gim_shade_desc sdesc;
    GLuint b_caches, b_cells, b_buckets, b_pd, b_pg = 0, t_ind, t_depth = 0, t_normal = 0, b_bvh = 0;
    gim_bvh bvh;
    uint32_t bvh_nodes = 0, dropped = 0;
    gim_vec3 eye = gim_v3(origin[0] + 0.5f * L, origin[1] + 0.55f * L, origin[2] + 1.9f * L);
    double cos_t, radius, max_rel = 0.0, ref_max = 0.0;
    uint32_t bad = 0, lit = 0;
    gltest_fixture_begin(&f);
    make_room(&r, L);
    for (i = 0; i < r.quads * 4; ++i) { r.pos[i * 3] += origin[0]; r.pos[i * 3 + 1] += origin[1]; r.pos[i * 3 + 2] += origin[2]; }
    memset(&bvh, 0, sizeof bvh);
    if (sc->rays) b_bvh = room_bvh(&r, f.env, &bvh_nodes, &bvh);
    memset(&cd, 0, sizeof cd);
    cd.mesh = room_mesh(&r);
    /* blocks share where a pixel lies within a quarter of a grid cell of its block's first receiver:
       at 80 x 60 a pixel spans ~L / 30 on the back wall, so the blocks' cases space the caches
       twice as far (the cell is twice their spacing) */
    cd.d_eps = sc->block == 2 ? L / 6.0f : L / 12.0f;
    assert_int_equal(gim_cache_generate(&cd, &set), GIM_OK);
    memset(&md, 0, sizeof md);
    md.data = room_mesh(&r);
    md.caches = &set;
    assert_int_equal(gim_add_mesh(f.ctx, &md, &mesh), GIM_OK);
    assert_int_equal(gim_set_materials(f.ctx, room_materials, 4), GIM_OK);
    in.mesh = mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(f.ctx, &in, 1), GIM_OK);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(eye, gim_v3(origin[0] + 0.5f * L, origin[1] + 0.3f * L, origin[2]), gim_v3(0, 1, 0));
    fr.proj = gim_mat4_perspective(1.0f, (float)W / H, 0.05f * L, 5.0f * L);
    fr.width = W;
    fr.height = H;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);   /* no lights: the G-buffer only */
    o = gim_outputs(f.ctx);
    assert_int_equal(o.indirect, 0);                      /* nothing lights it: no LightSkin */
    gltest_state_unchanged(&f);

    /* caches to world, the grid, the proxy lights of some VALs (CPU), uploaded */
    world = (gim_cache *)malloc(set.count * sizeof *world);
    assert_int_equal(gim_caches_to_world(set.caches, set.count, in.model, world, f.env), GIM_OK);
    assert_int_equal(gim__grid_build(&f.env, world, set.count, L / 32.0f, &g, &sorted, &cells, &buckets), GIM_OK);
    vals = make_vals(L, NV);
    for (i = 0; i < NV; ++i) {
        vals[i].position[0] += origin[0]; vals[i].position[1] += origin[1]; vals[i].position[2] += origin[2];
    }
    pd = (gim_proxy_light *)calloc(set.count, sizeof *pd);
    pg = (gim_proxy_light *)calloc(set.count, sizeof *pg);
    memset(&pdesc, 0, sizeof pdesc);
    pdesc.caches = sorted; pdesc.cache_count = set.count;
    pdesc.vals = vals; pdesc.val_count = NV;
    pdesc.eye = eye; pdesc.glossy_exponent = 12.0f;
    pdesc.scene_scale = L * 1.7320508f;
    assert_int_equal(gim_proxy_lights_twin(&pdesc, pd, pg), GIM_OK);
    b_caches = gltest_ssbo(set.count * 32u, sorted);
    b_cells = gltest_ssbo(set.count * 16u, cells);
    b_buckets = gltest_ssbo((g.bucket_count + 1u) * 4u, buckets);
    b_pd = gltest_ssbo(set.count * 48u, pd);
    if (sc->glossy) b_pg = gltest_ssbo(set.count * 48u, pg);
    glGenTextures(1, &t_ind);
    glBindTexture(GL_TEXTURE_2D, t_ind);
    glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA32F, W, H);
    glBindTexture(GL_TEXTURE_2D, 0);
    if (sc->host) { /* the host's G-buffer: copies of gimany's depth and normal */
        t_depth = o.gbuffer_depth;
        t_normal = o.gbuffer_normal;
    }
    cos_t = cos(2.0 * (double)set.theta_eps);
    memset(&sa, 0, sizeof sa);
    sa.depth = o.gbuffer_depth; sa.normal = o.gbuffer_normal;
    sa.albedo = sc->host ? 0u : o.gbuffer_albedo;
    sa.material = sc->host ? 0u : o.gbuffer_material;
    sa.width = W; sa.height = H; sa.view = fr.view; sa.proj = fr.proj;
    sa.caches = b_caches; sa.cells = b_cells; sa.buckets = b_buckets; sa.diffuse = b_pd; sa.glossy = b_pg;
    sa.cache_count = set.count; sa.grid = g; sa.n = sc->n; sa.cos_theta = (float)cos_t;
    sa.scene_scale = pdesc.scene_scale; sa.indirect = t_ind; sa.format = GL_RGBA32F;
    sa.list_limit = sc->list_limit;
    sa.block = sc->block;
    sa.slabs = sc->slabs;
    sa.bvh = b_bvh;
    sa.bvh_nodes = bvh_nodes;
    memcpy(sa.bvh_origin, bvh.origin, sizeof sa.bvh_origin);
    sa.bvh_scale = bvh.scale;
    gim__gl_enter(f.ctx, "test");
    assert_int_equal(gim__gl_lightskin_shade(f.ctx, &sa), GIM_OK);
    assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
    gltest_state_unchanged(&f);
    (void)t_depth; (void)t_normal;

    /* read back; the twin on the same pixels */
    depth = (float *)malloc(W * H * 4); nrm = (float *)malloc(W * H * 16); alb = (float *)malloc(W * H * 16);
    mat = (float *)malloc(W * H * 4); gpu = (float *)malloc(W * H * 16);
    gltest_read_texture(o.gbuffer_depth, GL_DEPTH_COMPONENT, depth);
    gltest_read_texture(o.gbuffer_normal, GL_RGBA, nrm);
    gltest_read_texture(o.gbuffer_albedo, GL_RGBA, alb);
    gltest_read_texture(o.gbuffer_material, GL_RED, mat);
    gltest_read_texture(t_ind, GL_RGBA, gpu);
    pix = (uint32_t *)malloc(W * H * 8);
    vs = (gim_view_sample *)malloc(W * H * sizeof *vs);
    for (i = 0; i < W * H; ++i) { pix[i * 2] = i % W; pix[i * 2 + 1] = i / W; }
    cam.view = fr.view; cam.proj = fr.proj; cam.width = W; cam.height = H;
    assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, pix, W * H, vs), GIM_OK);
    rec = (gim_receiver *)calloc(W * H, sizeof *rec);
    pos_nrm = (float *)malloc(W * H * 24);
    {
        uint32_t *map = (uint32_t *)malloc(W * H * 4);
        for (i = 0; i < W * H; ++i) {
            gim_receiver *rc = rec + nrec;
            if (!room_receiver(&vs[i], eye, alb + i * 4, mat[i], sc->host, rc)) {
                /* nothing drawn: the pass writes 0 */
                assert_true(gpu[i * 4] == 0.0f && gpu[i * 4 + 1] == 0.0f && gpu[i * 4 + 2] == 0.0f && gpu[i * 4 + 3] == 0.0f);
                continue;
            }
            assert_true(gpu[i * 4 + 3] == 1.0f);
            memcpy(pos_nrm + nrec * 6, rc->position, 12);
            memcpy(pos_nrm + nrec * 6 + 3, rc->normal, 12);
            map[nrec++] = i;
        }
        assert_true(nrec > W * H / 2);
        /* neighbours: the n nearest compatible caches, truncated at the pass's radius */
        nb_idx = (uint32_t *)malloc(nrec * sc->n * 4);
        nb_cnt = (uint32_t *)malloc(nrec * 4);
        dcmax = (float *)malloc(nrec * 4);
        ws = set;
        ws.caches = sorted;
        memset(&nd, 0, sizeof nd);
        nd.mesh.positions = pos_nrm;
        nd.mesh.position_stride = 24;
        nd.mesh.normals = pos_nrm + 3;
        nd.mesh.normal_stride = 24;
        nd.mesh.vertex_count = nrec;
        nd.caches = &ws;
        nd.n = sc->n;
        nd.theta_eps = (float)acos((double)(float)cos_t);
        nd.env = f.env;
        nr.index = nb_idx; nr.count = nb_cnt; nr.d_cmax = dcmax;
        assert_int_equal(gim_cache_neighbours(&nd, &nr), GIM_OK);
        radius = (double)GIM__NEIGHBOUR_RINGS * g.h;
        for (i = 0; i < nrec; ++i) {
            uint32_t k, keep = 0;
            float far_ = 0.0f;
            for (k = 0; k < nb_cnt[i]; ++k) {
                const float *c = sorted[nb_idx[i * sc->n + k]].position, *x = rec[i].position;
                double d = sqrt(((double)x[0] - c[0]) * ((double)x[0] - c[0]) + ((double)x[1] - c[1]) * ((double)x[1] - c[1]) +
                                ((double)x[2] - c[2]) * ((double)x[2] - c[2]));
                if (d > radius) break;
                keep = k + 1;
                far_ = (float)d;
            }
            for (k = keep; k < sc->n; ++k) nb_idx[i * sc->n + k] = UINT32_MAX;
            nb_cnt[i] = keep;
            dcmax[i] = far_;
        }
        if (sc->rays) {   /* the neighbours each receiver sees, in place */
            gim_neighbour_rays_desc rd;
            uint32_t *before = (uint32_t *)malloc(nrec * 4);
            memcpy(before, nb_cnt, nrec * 4);
            memset(&rd, 0, sizeof rd);
            rd.bvh = &bvh; rd.caches = sorted; rd.cache_count = set.count; rd.receivers = rec; rd.receiver_count = nrec;
            rd.neighbour_index = nb_idx; rd.neighbour_count = nb_cnt; rd.neighbour_stride = sc->n;
            rd.scene_scale = pdesc.scene_scale; rd.env = f.env;
            assert_int_equal(gim_neighbour_rays_twin(&rd, &nr), GIM_OK);
            for (i = 0; i < nrec; ++i) dropped += nb_cnt[i] != before[i];
            free(before);
            /* the block hides the caches inside it and behind it from the floor and walls around it */
            print_message("  rays: %u of %u receivers see fewer neighbours\n", dropped, nrec);
            assert_true(dropped > nrec / 50);
        }
        {   /* whose light each receiver takes in the pass's blocks */
            gim_shade_blocks_desc bd;
            src = (uint32_t *)malloc(nrec * 4);
            rpix = (uint32_t *)malloc(nrec * 8);
            for (i = 0; i < nrec; ++i) { rpix[i * 2] = map[i] % W; rpix[i * 2 + 1] = map[i] / W; }
            memset(&bd, 0, sizeof bd);
            bd.receivers = rec; bd.receiver_count = nrec; bd.pixels = rpix;
            bd.width = W; bd.height = H; bd.block = sc->block; bd.cell = g.h; bd.env = f.env;
            assert_int_equal(gim_shade_sources(&bd, src), GIM_OK);
            for (i = 0; i < nrec; ++i) shared_n += src[i] != i;
            /* blocks of one surface share, every receiver's source is its block's first */
            if (sc->block == 1) assert_int_equal(shared_n, 0);
            else assert_true(shared_n > nrec / 4);
            for (i = 0; i < nrec; ++i)
                assert_true(src[i] == i || (rpix[src[i] * 2] / 2 == rpix[i * 2] / 2 && rpix[src[i] * 2 + 1] / 2 == rpix[i * 2 + 1] / 2));
            free(rpix);
        }
        cpu = (float *)malloc(nrec * 12);
        memset(&sdesc, 0, sizeof sdesc);
        sdesc.caches = sorted; sdesc.cache_count = set.count;
        sdesc.diffuse = pd; sdesc.glossy = sc->glossy && !sc->host ? pg : NULL;
        sdesc.receivers = rec; sdesc.receiver_count = nrec;
        sdesc.neighbour_index = nb_idx; sdesc.neighbour_count = nb_cnt; sdesc.neighbour_stride = sc->n;
        sdesc.d_cmax = dcmax; sdesc.scene_scale = pdesc.scene_scale; sdesc.env = f.env;
        sdesc.source = src;
        assert_int_equal(gim_lightskin_shade_twin(&sdesc, cpu), GIM_OK);
        for (i = 0; i < nrec * 3; ++i) if (cpu[i] > ref_max) ref_max = cpu[i];
        assert_true(ref_max > 0.0);
        /* per pixel and channel: relative to itself, floored at 1e-3 of the image's largest
           value (a dark pixel's light is a difference of small sums) */
        for (i = 0; i < nrec; ++i) {
            int a;
            const float *q = gpu + map[i] * 4;
            double e = 0.0;
            for (a = 0; a < 3; ++a) {
                double ref = cpu[i * 3 + a], den = fabs(ref) > 1e-3 * ref_max ? fabs(ref) : 1e-3 * ref_max;
                double rel = fabs((double)q[a] - ref) / den;
                assert_true(isfinite(q[a]) && q[a] >= 0.0f);
                if (rel > e) e = rel;
            }
            if (cpu[i * 3] + cpu[i * 3 + 1] + cpu[i * 3 + 2] > 0.0f) lit++;
            if (e > 2e-3) bad++;
            else if (e > max_rel) max_rel = e;
        }
        print_message("shade n=%u glossy=%d host=%d list %u block %u slabs %u rays %d scale %g: %u receivers (%u share), %u lit, %u caches, "
                      "max rel err %.2e, %u above 2e-3\n",
                      sc->n, sc->glossy, sc->host, (unsigned)sc->list_limit, (unsigned)sc->block, (unsigned)sc->slabs, sc->rays, (double)L,
                      nrec, shared_n, lit,
                      set.count, max_rel, bad);
        assert_true(lit > nrec / 2);
        /* a float distance that ties or crosses the radius where the twin's double does not
           swaps a neighbour whose tent weight is ~0: a handful of pixels at most */
        assert_true(bad <= nrec / 200);
        {   /* the neighbour choice itself: count, d_cmax and the sum of the indices per pixel */
            float *nb = (float *)malloc(W * H * 16);
            uint32_t differ = 0;
            sa.neighbours_out = 1;
            gim__gl_enter(f.ctx, "test");
            assert_int_equal(gim__gl_lightskin_shade(f.ctx, &sa), GIM_OK);
            assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
            gltest_read_texture(t_ind, GL_RGBA, nb);
            for (i = 0; i < nrec; ++i) {   /* each pixel writes its source's */
                const float *q = nb + map[i] * 4;
                uint32_t k, s_ = src[i];
                double sum = 0.0;
                for (k = 0; k < nb_cnt[s_]; ++k) sum += nb_idx[s_ * sc->n + k];
                if (q[1] != (float)nb_cnt[s_] || q[2] != (float)sum || fabs((double)q[0] - dcmax[s_]) > 2e-4 * (double)dcmax[s_])
                {
                    if (differ < 3) print_message("  px %u: gpu %.9g %g %g twin %.9g %u %g\n", i, q[0], q[1], q[2], dcmax[s_], nb_cnt[s_], sum);
                    differ++;
                }
            }
            print_message("  neighbours: %u of %u pixels choose otherwise than the twin\n", differ, nrec);
            /* a float distance that ties with the n-th or the radius where the double does not */
            assert_true(differ <= nrec / 500);
            free(nb);
        }
        free(map);
    }
    free(depth); free(nrm); free(alb); free(mat); free(gpu); free(pix); free(vs); free(rec); free(pos_nrm);
    free(nb_idx); free(nb_cnt); free(dcmax); free(cpu); free(pd); free(pg); free(vals); free(world); free(src);
    gim__free(&f.env, sorted);
    gim__free(&f.env, cells);
    gim__free(&f.env, buckets);
    glDeleteBuffers(1, &b_caches); glDeleteBuffers(1, &b_cells); glDeleteBuffers(1, &b_buckets);
    glDeleteBuffers(1, &b_pd);
    if (b_pg) glDeleteBuffers(1, &b_pg);
    if (b_bvh) glDeleteBuffers(1, &b_bvh);
    gim_bvh_free(&bvh);
    glDeleteTextures(1, &t_ind);
    gim_cache_set_free(&set);
    gltest_fixture_end(&f);
}

static void shade_matches_twin(void **state) {
    static const float o0[3] = {0.0f, 0.0f, 0.0f}, ofar[3] = {3e3f, -1e3f, 2e3f};
    shade_case sc;
    (void)state;
    GLTEST_BEGIN();
    sc.n = 16; sc.glossy = 1; sc.host = 0; sc.list_limit = 0; sc.block = 2; sc.slabs = 0; sc.rays = 0;
    run_shade_case(&sc, 4.0f, o0);
    sc.slabs = 1;                               /* every tile's list in slabs across its box's long axis */
    run_shade_case(&sc, 4.0f, o0);
    sc.block = 1;
    run_shade_case(&sc, 4.0f, o0);
    sc.list_limit = 60;                         /* and some tiles per pixel */
    run_shade_case(&sc, 4.0f, o0);
    sc.slabs = 2;                               /* every tile's list in rings */
    run_shade_case(&sc, 4.0f, o0);
    sc.list_limit = 0; sc.slabs = 0;
    sc.block = 1;                               /* per pixel */
    run_shade_case(&sc, 4.0f, o0);
    sc.list_limit = 1;                          /* every tile searches per pixel */
    run_shade_case(&sc, 4.0f, o0);
    sc.block = 2;
    run_shade_case(&sc, 4.0f, o0);
    sc.list_limit = 60;                         /* some tiles by their list, some per pixel */
    run_shade_case(&sc, 4.0f, o0);
    sc.block = 1;
    run_shade_case(&sc, 4.0f, o0);
    sc.n = 4; sc.glossy = 0; sc.host = 0; sc.list_limit = 0; sc.block = 2;
    run_shade_case(&sc, 4.0f, o0);
    sc.n = 16; sc.glossy = 1; sc.host = 1;     /* glossy proxies given, but no materials: diffuse, albedo 1 */
    run_shade_case(&sc, 4.0f, o0);
    sc.n = 8; sc.glossy = 1; sc.host = 0;      /* millimetres, far from the origin */
    run_shade_case(&sc, 0.004f, o0);
    run_shade_case(&sc, 40.0f, ofar);
    sc.slabs = 1;                               /* the slabs' edges at those scales */
    run_shade_case(&sc, 0.004f, o0);
    run_shade_case(&sc, 40.0f, ofar);
    sc.n = 16; sc.slabs = 0; sc.rays = 1;       /* neighbour_rays: in blocks, per pixel, per pixel search, far */
    run_shade_case(&sc, 4.0f, o0);
    sc.block = 1; sc.list_limit = 1;
    run_shade_case(&sc, 4.0f, o0);
    sc.block = 2; sc.list_limit = 0; sc.host = 1;
    run_shade_case(&sc, 0.004f, o0);
    run_shade_case(&sc, 40.0f, ofar);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(caches_to_world_keeps_area_and_normals),
        cmocka_unit_test(grid_holds_every_cache_once),
        cmocka_unit_test(shade_matches_twin),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
