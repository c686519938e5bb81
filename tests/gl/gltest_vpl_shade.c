/* The VPL shading pass (vpl_shade.comp: soft visibility from paraboloid maps, clamping,
   interleaved sampling) and the geometry-aware blur (geometry_blur.comp) on a real G-buffer
   against their twins gim_vpl_shade_twin and gim_geometry_blur_twin, on receivers unprojected from the
   read-back G-buffer; the distance maps are synthetic plates written into the R32F array. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "vplshade_util.h"

/* --- a room: floor, three walls, a block (as gltest_lightskin) ------------------------------- */
#include "room.h"

static void make_room(room *r, float L, const float o[3]) {
    float c[3], u[3], v[3];
    float b0 = 0.35f * L, b1 = 0.65f * L, bh = 0.3f * L;
    uint32_t i;
    memset(r, 0, sizeof *r);
#define SET3(a, x, y, z) ((a)[0] = (x), (a)[1] = (y), (a)[2] = (z))
    SET3(c, 0, 0, 0); SET3(u, 0, 0, L); SET3(v, L, 0, 0); add_quad(r, c, u, v, 0);
    SET3(c, 0, 0, 0); SET3(u, 0, L, 0); SET3(v, 0, 0, L); add_quad(r, c, u, v, 1);
    SET3(c, L, 0, 0); SET3(u, 0, 0, L); SET3(v, 0, L, 0); add_quad(r, c, u, v, 2);
    SET3(c, 0, 0, 0); SET3(u, L, 0, 0); SET3(v, 0, L, 0); add_quad(r, c, u, v, 3);
    SET3(c, b0, bh, b0); SET3(u, 0, 0, b1 - b0); SET3(v, b1 - b0, 0, 0); add_quad(r, c, u, v, 0);
    SET3(c, b0, 0, b1); SET3(u, b1 - b0, 0, 0); SET3(v, 0, bh, 0); add_quad(r, c, u, v, 0);
    SET3(c, b0, 0, b0); SET3(u, 0, 0, b1 - b0); SET3(v, 0, bh, 0); add_quad(r, c, u, v, 0);
    SET3(c, b1, 0, b0); SET3(u, 0, bh, 0); SET3(v, 0, 0, b1 - b0); add_quad(r, c, u, v, 0);
#undef SET3
    for (i = 0; i < r->quads * 4; ++i) { r->pos[i * 3] += o[0]; r->pos[i * 3 + 1] += o[1]; r->pos[i * 3 + 2] += o[2]; }
}

/* --- the case ------------------------------------------------------------------------------- */

enum { W = 80, H = 60, NV = 240, M = 3, S = 64, IS = 16, NP = 4096 };

typedef struct shade_case {
    float L;                 /* room side */
    float origin[3];
    uint32_t interleave;
    float clamp;             /* in L */
    uint32_t chunk;          /* ctx->vpl_chunk; 0: default */
    int visibility;          /* 1: the clusters' paraboloid maps; 2: one ISM per VPL */
    int host;                /* the host's G-buffer: albedo 1, no glossy */
    gim__GLenum format;
    int probe;               /* also measure the visibility per map */
    float area;              /* > 0: each VPL a patch of about (area L)^2 (0.5-1.5x), the near field */
} shade_case;

typedef struct compare_stats { double max_rel, mean_rel; uint32_t above, count; } compare_stats;

/* Per pixel and channel: |gpu - cpu| / max(|cpu|, 1e-3 of the image's largest value). */
static compare_stats compare(const float *gpu4, const float *cpu3, const int *surface, uint32_t n, double tol) {
    compare_stats s;
    double ref_max = 0.0, sum = 0.0;
    uint32_t i;
    memset(&s, 0, sizeof s);
    for (i = 0; i < n * 3; ++i) if (cpu3[i] > ref_max) ref_max = cpu3[i];
    for (i = 0; i < n; ++i) {
        double e = 0.0;
        int a;
        if (!surface[i]) continue;
        for (a = 0; a < 3; ++a) {
            double ref = cpu3[i * 3 + a], den = fabs(ref) > 1e-3 * ref_max ? fabs(ref) : 1e-3 * ref_max;
            double rel = den > 0.0 ? fabs((double)gpu4[i * 4 + a] - ref) / den : fabs((double)gpu4[i * 4 + a]);
            if (rel > e) e = rel;
        }
        if (e > s.max_rel) s.max_rel = e;
        sum += e;
        if (e > tol) s.above++;
        s.count++;
    }
    s.mean_rel = s.count ? sum / s.count : 0.0;
    return s;
}

static void run_case(const shade_case *sc) {
    const float L = sc->L, *o = sc->origin;
    gltest_fixture f;
    room r;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance in;
    gim_frame fr;
    gim_camera cam;
    gim_frame_outputs out;
    gim_vpl vpls[NV];
    uint32_t cluster[NV], i, pix_count = W * H;
    gim_paraboloid maps[M];
    float *dist = (float *)malloc((size_t)M * S * S * 4), *depth, *nrm, *alb, *mat, *gpu, *cpu, *gpu_blur, *cpu_blur, *cpu3;
    uint32_t *pixels;
    gim_view_sample *vs;
    gim_receiver *rec;
    int *surface;
    GLuint b_vpls, b_cluster, b_maps, t_dist, t_out, t_blur, b_ism = 0;
    float *ism = NULL;
    uint32_t ism_first = sc->visibility == 3 ? NV / 2 : 0;   /* the hybrid: SSVP's second bounce */
    gim__vpl_shade_args a;
    gim__blur_args ba;
    gim_vec3 eye = gim_v3(o[0] + 0.5f * L, o[1] + 0.55f * L, o[2] + 1.9f * L);
    compare_stats cs, cb, cfail;
    uint32_t same;
    gim_vpl_shade_desc sd;
    gim_blur_desc bd;

    gltest_fixture_begin(&f);
    make_room(&r, L, o);
    memset(&md, 0, sizeof md);
    md.data.positions = r.pos; md.data.normals = r.nrm; md.data.vertex_count = r.quads * 4;
    md.data.indices = r.idx; md.data.index_count = r.quads * 6; md.data.triangle_material = r.mat;
    assert_int_equal(gim_add_mesh(f.ctx, &md, &mesh), GIM_OK);
    assert_int_equal(gim_set_materials(f.ctx, room_materials, 4), GIM_OK);
    in.mesh = mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(f.ctx, &in, 1), GIM_OK);
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(eye, gim_v3(o[0] + 0.5f * L, o[1] + 0.3f * L, o[2]), gim_v3(0, 1, 0));
    fr.proj = gim_mat4_perspective(1.0f, (float)W / H, 0.05f * L, 5.0f * L);
    fr.width = W; fr.height = H;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);   /* no lights: the G-buffer only */
    out = gim_outputs(f.ctx);

    /* three clusters: a VAL on the left wall (normal +x), one on the floor near the back (+y),
       one on the right wall (-x); each map holds a plate between its VAL and the room */
    {
        static const float nrm3[M][3] = {{1, 0, 0}, {0, 1, 0}, {-1, 0, 0}};
        const float c3[M][3] = {{0.0f, 0.5f, 0.5f}, {0.5f, 0.0f, 0.15f}, {1.0f, 0.6f, 0.3f}};
        uint32_t m;
        for (m = 0; m < M; ++m) {
            memset(&maps[m], 0, sizeof maps[m]);
            for (i = 0; i < 3; ++i) {
                maps[m].normal[i] = nrm3[m][i];
                maps[m].origin[i] = o[i] + c3[m][i] * L + 1e-4f * L * nrm3[m][i];
            }
            maps[m].size = (0.1f + 0.1f * (float)m) * L;
            maps[m].near_distance = maps[m].size / 2;
            vs_plate_map(dist + (size_t)m * S * S, S, (0.2f + 0.1f * (float)m) * L, 0.05f * L, -0.05f * L, 0.12f * L);
        }
        for (i = 0; i < NV; ++i) {
            uint32_t mm = i % 4u < 3u ? i % 4u : (i / 4u) % 3u;   /* every 4th VPL unshadowed */
            gim_vec3 p = vs_local(&maps[mm], test_rnd(-0.1f, 0.1f) * L, test_rnd(-0.1f, 0.1f) * L, 0.0f);
            memset(&vpls[i], 0, sizeof vpls[i]);
            vpls[i].position[0] = p.x; vpls[i].position[1] = p.y; vpls[i].position[2] = p.z;
            vpls[i].lit = i % 17u == 3u ? 0.0f : 1.0f;
            memcpy(vpls[i].normal, maps[mm].normal, 12);
            vpls[i].flux[0] = test_rnd(0.2f, 1.0f) / NV;
            vpls[i].flux[1] = test_rnd(0.2f, 1.0f) / NV;
            vpls[i].flux[2] = test_rnd(0.2f, 1.0f) / NV;
            if (sc->area > 0.0f) vpls[i].area = sc->area * L * sc->area * L * test_rnd(0.5f, 1.5f);
            cluster[i] = i % 4u < 3u ? mm : UINT32_MAX;
        }
    }
    if (sc->visibility >= 2) {   /* one ISM per VPL (gim_ism_render_twin on the VPLs as caches) of the room's points;
                                    3: for the VPLs from ism_first on only, the clusters' maps for the rest */
        gim_twin_scene ts;
        gim_cache vc[NV];
        gim_ism_desc idd;
        float *pos = (float *)malloc((size_t)r.quads * 2 * 9 * 4), *alb3 = (float *)malloc((size_t)r.quads * 2 * 3 * 4);
        float *pts = (float *)malloc((size_t)NP * 32);
        uint32_t t, k;
        for (t = 0; t < r.quads * 2; ++t)
            for (k = 0; k < 3; ++k) {
                memcpy(pos + t * 9 + k * 3, r.pos + r.idx[t * 3 + k] * 3, 12);
                alb3[t * 3 + k] = 0.8f;
            }
        ts.positions = pos; ts.normals = NULL; ts.albedo = alb3; ts.triangle_count = r.quads * 2;
        assert_int_equal(gim_ism_points(&ts, NP, pts), GIM_OK);
        for (i = 0; i < NV; ++i) {
            memcpy(vc[i].position, vpls[i].position, 12);
            memcpy(vc[i].normal, vpls[i].normal, 12);
            vc[i].area = 1.0f;
            vc[i].reflectance = 0.5f;
        }
        memset(&idd, 0, sizeof idd);
        idd.caches = vc + ism_first; idd.cache_count = NV - ism_first; idd.points = pts; idd.point_count = NP;
        idd.size = IS; idd.points_per_map = NP / 4; idd.splat = GIM_ISM_VPL_SPLAT; idd.scene_scale = 1.7320508f * L; idd.env = f.env;
        ism = (float *)malloc((size_t)NV * IS * IS * 4);
        assert_int_equal(gim_ism_render_twin(&idd, ism), GIM_OK);
        b_ism = gltest_ism_ssbo(ism, (size_t)(NV - ism_first) * IS * IS);
        free(pos); free(alb3); free(pts);
    }
    b_vpls = gltest_ssbo(sizeof vpls, vpls);
    b_cluster = gltest_ssbo(sizeof cluster, cluster);
    b_maps = gltest_ssbo(sizeof maps, maps);
    glGenTextures(1, &t_dist);
    glBindTexture(GL_TEXTURE_2D_ARRAY, t_dist);
    glTexStorage3D(GL_TEXTURE_2D_ARRAY, 1, GL_R32F, S, S, M);
    glTexSubImage3D(GL_TEXTURE_2D_ARRAY, 0, 0, 0, 0, S, S, M, GL_RED, GL_FLOAT, dist);
    glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
    glGenTextures(1, &t_blur);
    glBindTexture(GL_TEXTURE_2D, t_blur);
    glTexStorage2D(GL_TEXTURE_2D, 1, sc->format, W, H);
    glBindTexture(GL_TEXTURE_2D, 0);
    gltest_reset_errors();
    f.ctx->vpl_chunk = sc->chunk;

    memset(&a, 0, sizeof a);
    a.depth = out.gbuffer_depth; a.normal = out.gbuffer_normal;
    a.albedo = sc->host ? 0u : out.gbuffer_albedo; a.material = sc->host ? 0u : out.gbuffer_material;
    a.width = W; a.height = H; a.view = fr.view; a.proj = fr.proj;
    a.vpls = b_vpls; a.vpl_count = NV;
    a.cluster = sc->visibility & 1 ? b_cluster : 0u; a.maps = b_maps; a.map_count = M;
    a.distance = sc->visibility & 1 ? t_dist : 0u; a.map_size = S;
    a.ism_first = ism_first;
    a.ism = b_ism; a.ism_size = IS;
    a.interleave = sc->interleave; a.clamp_distance = sc->clamp * L; a.scene_scale = 1.7320508f * L;
    a.format = sc->format;
    memset(&ba, 0, sizeof ba);
    ba.depth = out.gbuffer_depth; ba.normal = out.gbuffer_normal; ba.width = W; ba.height = H;
    ba.albedo = a.albedo; ba.material = a.material;
    ba.view = fr.view; ba.proj = fr.proj; ba.window = sc->interleave;
    ba.position_tolerance = 0.1f * 1.7320508f * L;   /* Laine et al.'s alpha: 10 % of the extent */
    ba.output = t_blur; ba.format = sc->format;
    gim__gl_enter(f.ctx, "test");
    gim__gl_vpl_raw_texture(f.ctx, W, H, sc->format);   /* the context's texture between the passes */
    t_out = a.output = ba.input = f.ctx->vpl_raw;
    assert_int_equal(gim__gl_vpl_shade(f.ctx, &a), GIM_OK);
    assert_int_equal(gim__gl_geometry_blur(f.ctx, &ba), GIM_OK);
    assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
    gltest_state_unchanged(&f);

    /* read back; the receivers as gltest_lightskin builds them */
    depth = (float *)malloc(W * H * 4); nrm = (float *)malloc(W * H * 16); alb = (float *)malloc(W * H * 16);
    mat = (float *)malloc(W * H * 4); gpu = (float *)malloc(W * H * 16); gpu_blur = (float *)malloc(W * H * 16);
    cpu = (float *)malloc(W * H * 12); cpu_blur = (float *)malloc(W * H * 12); cpu3 = (float *)malloc(W * H * 12);
    gltest_read_texture(out.gbuffer_depth, GL_DEPTH_COMPONENT, depth);
    gltest_read_texture(out.gbuffer_normal, GL_RGBA, nrm);
    gltest_read_texture(out.gbuffer_albedo, GL_RGBA, alb);
    gltest_read_texture(out.gbuffer_material, GL_RED, mat);
    gltest_read_texture(t_out, GL_RGBA, gpu);
    gltest_read_texture(t_blur, GL_RGBA, gpu_blur);
    pixels = (uint32_t *)malloc(W * H * 8);
    vs = (gim_view_sample *)malloc(W * H * sizeof *vs);
    rec = (gim_receiver *)calloc(W * H, sizeof *rec);
    surface = (int *)calloc(W * H, sizeof *surface);
    for (i = 0; i < pix_count; ++i) { pixels[i * 2] = i % W; pixels[i * 2 + 1] = i / W; }
    cam.view = fr.view; cam.proj = fr.proj; cam.width = W; cam.height = H;
    assert_int_equal(gim_view_samples_twin(depth, nrm, &cam, pixels, W * H, vs), GIM_OK);
    for (i = 0; i < pix_count; ++i) {
        surface[i] = room_receiver(&vs[i], eye, alb + i * 4, mat[i], sc->host, rec + i);
    }
    memset(&sd, 0, sizeof sd);
    sd.vpls = vpls; sd.vpl_count = NV;
    sd.cluster = sc->visibility & 1 ? cluster : NULL; sd.maps = maps; sd.ism_first = ism_first;
    sd.ism = ism; sd.ism_size = IS; sd.map_count = M; sd.distance = dist; sd.map_size = S;
    sd.receivers = rec; sd.width = W; sd.height = H; sd.interleave = sc->interleave;
    sd.clamp_distance = a.clamp_distance; sd.scene_scale = a.scene_scale; sd.env = f.env;
    assert_int_equal(gim_vpl_shade_twin(&sd, cpu), GIM_OK);
    for (i = 0; i < pix_count; ++i) {
        assert_true(gpu[i * 4 + 3] == (surface[i] ? 1.0f : 0.0f));
        assert_true(isfinite(gpu[i * 4]) && gpu[i * 4] >= 0.0f);
    }
    cs = compare(gpu, cpu, surface, pix_count, 1e-3);
    same = compare(gpu, cpu, surface, pix_count, 1e-5).above;
    /* the blur of the GPU's own shading, so the comparison isolates the blur */
    for (i = 0; i < pix_count; ++i) memcpy(cpu3 + i * 3, gpu + i * 4, 12);
    memset(&bd, 0, sizeof bd);
    bd.radiance = cpu3; bd.receivers = rec; bd.width = W; bd.height = H; bd.window = ba.window;
    bd.position_tolerance = ba.position_tolerance; bd.env = f.env;
    assert_int_equal(gim_geometry_blur_twin(&bd, cpu_blur), GIM_OK);
    cb = compare(gpu_blur, cpu_blur, surface, pix_count, 1e-3);
    if (ba.window > 1u) {   /* the blur did something: the input and its blur differ */
        compare_stats moved = compare(gpu_blur, cpu3, surface, pix_count, 1e-3);
        assert_true(moved.above > moved.count / 20);
    }
    if (sc->area > 0.0f) {   /* the near field changed the image: the twin with point VPLs is far */
        gim_vpl *pts = (gim_vpl *)malloc(sizeof vpls);
        compare_stats cn;
        memcpy(pts, vpls, sizeof vpls);
        for (i = 0; i < NV; ++i) pts[i].area = 0.0f;
        sd.vpls = pts;
        assert_int_equal(gim_vpl_shade_twin(&sd, cpu), GIM_OK);
        cn = compare(gpu, cpu, surface, pix_count, 1e-2);
        print_message("near field: %u of %u pixels differ by over 1%% from point VPLs\n", cn.above, cn.count);
        assert_true(cn.above > cn.count / 50);
        sd.vpls = vpls;
        free(pts);
    }
    if (sc->visibility == 3) {   /* the ISMs shadow: the twin with those VPLs unshadowed is far */
        compare_stats cu;
        sd.ism = NULL; sd.ism_first = 0;
        assert_int_equal(gim_vpl_shade_twin(&sd, cpu), GIM_OK);
        cu = compare(gpu, cpu, surface, pix_count, 1e-2);
        print_message("hybrid: %u of %u pixels differ by over 1%% with the ISM VPLs unshadowed\n", cu.above, cu.count);
        assert_true(cu.above > cu.count / 50);
    }
    /* the test can fail: the twin without visibility (or with the other interleave) is far */
    sd.cluster = sc->visibility ? NULL : cluster;
    sd.ism_first = 0;
    sd.ism = NULL;
    assert_int_equal(gim_vpl_shade_twin(&sd, cpu), GIM_OK);
    cfail = compare(gpu, cpu, surface, pix_count, 1e-3);
    print_message("L %g k %u clamp %g chunk %u vis %d host %d fmt %s: %u pixels; shade max rel %.2e mean %.2e, %u (%.2f %%) "
                  "above 1e-3, %u above 1e-5; blur max %.2e mean %.2e, %u above; against the wrong twin %u (%.1f %%) above\n",
                  (double)L, sc->interleave, (double)sc->clamp, sc->chunk, sc->visibility, sc->host,
                  sc->format == GL_RGBA32F ? "32F" : "16F", cs.count, cs.max_rel, cs.mean_rel, cs.above,
                  100.0 * cs.above / cs.count, same, cb.max_rel, cb.mean_rel, cb.above, cfail.above, 100.0 * cfail.above / cfail.count);
    assert_true(cs.count > pix_count / 2);
    if (sc->format == GL_RGBA32F) {
        /* a receiver unprojected in float (GPU) or double (twin) can fall on the other side of a
           texel edge in one visibility tap (1/16 of a VPL's light): a few pixels at most */
        assert_true(cs.above <= cs.count / 100);
        assert_true(cs.mean_rel < 1e-3);
        assert_true(cb.above <= cb.count / 100);
    } else {   /* RGBA16F: 11-bit mantissa */
        assert_true(cs.mean_rel < 2e-3);
        assert_true(cb.mean_rel < 2e-3);
    }
    assert_true(cfail.above > cfail.count / 20);

    /* the visibility itself: one VPL of cluster m at a time, V_gpu = the GPU's radiance over
       the twin's unshadowed one (both scale by V), against gim_paraboloid_visibility_twin on the
       twin's receiver; a mismatch is a tap that read another texel */
    if (sc->probe) {
        uint32_t m, lit = 0, mismatch = 0, partial = 0;
        for (m = 0; m < M; ++m) {
            gim_vpl one = vpls[m];
            uint32_t cm = m;
            double ref_max = 0.0;
            one.lit = 1.0f;
            one.flux[0] = one.flux[1] = one.flux[2] = 1.0f;
            glBindBuffer(GL_SHADER_STORAGE_BUFFER, b_vpls);
            glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof one, &one);
            glBindBuffer(GL_SHADER_STORAGE_BUFFER, b_cluster);
            glBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, sizeof cm, &cm);
            glBindBuffer(GL_SHADER_STORAGE_BUFFER, 0);
            a.vpl_count = 1; a.interleave = 1; a.cluster = b_cluster; a.distance = t_dist;
            gim__gl_enter(f.ctx, "test");
            assert_int_equal(gim__gl_vpl_shade(f.ctx, &a), GIM_OK);
            assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
            gltest_read_texture(t_out, GL_RGBA, gpu);
            sd.vpls = &one; sd.vpl_count = 1; sd.interleave = 1; sd.cluster = NULL;
            assert_int_equal(gim_vpl_shade_twin(&sd, cpu), GIM_OK);
            for (i = 0; i < pix_count; ++i) if (cpu[i * 3] > ref_max) ref_max = cpu[i * 3];
            for (i = 0; i < pix_count; ++i) {
                float vc;
                gim_vec3 rn;
                if (!surface[i] || !(cpu[i * 3] > 1e-3 * ref_max)) continue;
                rn = gim_v3(rec[i].normal[0], rec[i].normal[1], rec[i].normal[2]);
                assert_int_equal(gim_paraboloid_visibility_twin(dist + (size_t)m * S * S, S, &maps[m],
                                                           gim_v3(rec[i].position[0], rec[i].position[1], rec[i].position[2]),
                                                           &rn, &vc),
                                 GIM_OK);
                lit++;
                if (vc > 0.0f && vc < 1.0f) partial++;
                if (fabs(gpu[i * 4] / cpu[i * 3] - vc) > 1e-3) mismatch++;
            }
        }
        print_message("visibility: %u lit pixel-maps, %u in a penumbra, %u (%.2f %%) where the GPU's V differs\n", lit, partial,
                      mismatch, 100.0 * mismatch / lit);
        assert_true(partial > lit / 50);
        assert_true(mismatch <= lit / 100);
    }

    glDeleteBuffers(1, &b_vpls); glDeleteBuffers(1, &b_cluster); glDeleteBuffers(1, &b_maps);
    glDeleteTextures(1, &t_dist); glDeleteTextures(1, &t_blur);
    if (b_ism) glDeleteBuffers(1, &b_ism);
    free(ism);
    free(dist); free(depth); free(nrm); free(alb); free(mat); free(gpu); free(gpu_blur); free(cpu); free(cpu_blur);
    free(cpu3); free(pixels); free(vs); free(rec); free(surface);
    gltest_fixture_end(&f);
}

static void vpl_shade_matches_twin(void **state) {
    shade_case sc;
    (void)state;
    GLTEST_BEGIN();
    memset(&sc, 0, sizeof sc);
    sc.L = 4.0f; sc.interleave = 2; sc.clamp = 0.05f; sc.visibility = 1; sc.format = GL_RGBA32F; sc.probe = 1;
    run_case(&sc);
    sc.probe = 0;
    sc.interleave = 4; sc.chunk = 4;               /* 15 members per pixel in 4 dispatches */
    sc.area = 0.25f;                               /* near VPLs counted across the dispatches */
    run_case(&sc);
    sc.interleave = 1; sc.chunk = 0; sc.clamp = 0.0f; sc.host = 1;
    sc.area = 0.3f;                                /* more near VPLs than GIM__VPL_NEAR_CAP at a pixel */
    run_case(&sc);
    sc.area = 0.0f;
    sc.host = 0; sc.visibility = 0; sc.interleave = 2; sc.clamp = 0.1f; sc.format = GL_RGBA16F;
    run_case(&sc);
    sc.visibility = 1; sc.format = GL_RGBA32F; sc.L = 0.004f;   /* millimetres, far from the origin */
    sc.origin[0] = 0.3f; sc.origin[1] = -0.1f; sc.origin[2] = 0.2f;
    sc.probe = 1;
    run_case(&sc);
    sc.probe = 0;
    sc.L = 40.0f; sc.origin[0] = 3e3f; sc.origin[1] = -1e3f; sc.origin[2] = 2e3f;
    run_case(&sc);
    GLTEST_END();
}

/* One imperfect shadow map per VPL (Ritschel et al. 2008): hard visibility through the VPL's
   own map, the GPU against gim_vpl_shade_twin's ism on the room's points. */
static void vpl_shade_ism_matches_twin(void **state) {
    shade_case sc;
    (void)state;
    GLTEST_BEGIN();
    memset(&sc, 0, sizeof sc);
    sc.L = 4.0f; sc.interleave = 2; sc.clamp = 0.05f; sc.visibility = 2; sc.format = GL_RGBA32F;
    run_case(&sc);
    sc.L = 0.004f; sc.origin[0] = 0.3f; sc.origin[1] = -0.1f; sc.origin[2] = 0.2f; sc.interleave = 4; sc.chunk = 4;
    run_case(&sc);
    /* the clusters' paraboloid maps and, for the VPLs from NV / 2 on that have no cluster, their
       own ISMs (SSVP's second bounce), with the near field */
    sc.visibility = 3; sc.area = 0.25f;
    run_case(&sc);
    GLTEST_END();
}

/* Bad arguments fail with a message and leave the GL state alone. */
static void bad_arguments(void **state) {
    gltest_fixture f;
    gim__vpl_shade_args a;
    gim__blur_args b;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    gim__gl_enter(f.ctx, "test");
    assert_int_equal(gim__gl_vpl_shade(f.ctx, &a), GIM_ERROR_INVALID_ARGUMENT);
    a.depth = a.normal = a.output = 1; a.width = a.height = 4; a.interleave = 65;
    assert_int_equal(gim__gl_vpl_shade(f.ctx, &a), GIM_ERROR_INVALID_ARGUMENT);
    a.interleave = 2; a.cluster = 1; a.distance = 1; a.scene_scale = 1.0f;
    assert_int_equal(gim__gl_vpl_shade(f.ctx, &a), GIM_ERROR_INVALID_ARGUMENT);   /* no maps */
    assert_int_equal(gim__gl_geometry_blur(f.ctx, &b), GIM_ERROR_INVALID_ARGUMENT);
    b.depth = b.normal = b.input = b.output = 1; b.width = b.height = 4;
    assert_int_equal(gim__gl_geometry_blur(f.ctx, &b), GIM_ERROR_INVALID_ARGUMENT); /* same input and output */
    b.output = 2; b.position_tolerance = -1.0f;
    assert_int_equal(gim__gl_geometry_blur(f.ctx, &b), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim__gl_leave(f.ctx, GIM_OK), GIM_OK);
    gltest_state_unchanged(&f);
    assert_int_equal(f.log.errors, 6);
    f.log.errors = 0;
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(vpl_shade_matches_twin),
        cmocka_unit_test(vpl_shade_ism_matches_twin),
        cmocka_unit_test(bad_arguments),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
