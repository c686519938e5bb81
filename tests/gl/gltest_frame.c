/* The whole LightSkin frame of gim_update on the Cornell box (Bischoff 2017 end to end): the GPU
   frame against the CPU frame (gim_lightskin_frame_twin on the frame's own VALs, caches and pixels),
   colour bleeding, BRSM converging to FULL as N_sVAL grows, glossy only when a
   material is glossy, what FULL frees, stats, no NaN, zero GL errors. Runs on the measured
   Cornell box of ../shared/scenes when present and always on the built-in one. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 96
#define H 96
#define CORNELL_GLTF "../shared/scenes/cornell_box/CornellBox.gltf"
#include "framefix.h"

/* The CPU frame on the GPU frame's inputs: its VALs and world caches (read back), the pixels
   of its G-buffer; neighbours by gim_cache_neighbours truncated at the pass's radius. Returns
   the largest relative difference (floored at 1e-3 of the image's largest value) over the
   pixels, and how many exceed tol. */
static uint32_t compare_with_cpu_frame(frame_fixture *ff, const float *gpu, double tol, double *max_rel) {
    gim_frame_outputs o = gim_outputs(ff->f.ctx);
    gim_debug_outputs od = gim_debug(ff->f.ctx);
    uint32_t n = od.neighbour_count, nrec, i, bad, *map = (uint32_t *)malloc(W * H * 4), *nb_idx, *nb_cnt, *src;
    gim_receiver *rec = (gim_receiver *)calloc(W * H, sizeof *rec);
    gim_cache *caches = (gim_cache *)malloc(od.cache_count * sizeof *caches);
    gim_val *vals = (gim_val *)malloc((size_t)od.val_count * sizeof *vals);
    float *pos_nrm = (float *)malloc(W * H * 24), *dcmax, *cpu, *kc = NULL;
    gim_cache_set set;
    gim_neighbour_desc nd;
    gim_neighbour_result nr;
    gim_lightskin_desc ld;
    gim_vec3 eye;
    gltest_read_buffer(od.caches, od.cache_count * sizeof *caches, caches);
    gltest_read_buffer(od.vals, (size_t)od.val_count * sizeof *vals, vals);
    nrec = frame_receivers(ff, rec, map, &eye);
    for (i = 0; i < nrec; ++i) {
        memcpy(pos_nrm + i * 6, rec[i].position, 12);
        memcpy(pos_nrm + i * 6 + 3, rec[i].normal, 12);
    }
    nb_idx = (uint32_t *)malloc((size_t)nrec * n * 4);
    nb_cnt = (uint32_t *)malloc(nrec * 4);
    dcmax = (float *)malloc(nrec * 4);
    cpu = (float *)malloc(nrec * 12);
    memset(&set, 0, sizeof set);
    set.caches = caches;
    set.count = od.cache_count;
    memset(&nd, 0, sizeof nd);
    nd.mesh.positions = pos_nrm; nd.mesh.position_stride = 24;
    nd.mesh.normals = pos_nrm + 3; nd.mesh.normal_stride = 24;
    nd.mesh.vertex_count = nrec;
    nd.caches = &set;
    nd.n = n;
    nd.theta_eps = (float)acos((double)od.neighbour_cos);
    nd.max_distance = od.neighbour_radius;   /* the pass searches within this radius */
    nd.env = ff->f.env;
    nr.index = nb_idx; nr.count = nb_cnt; nr.d_cmax = dcmax;
    assert_int_equal(gim_cache_neighbours(&nd, &nr), GIM_OK);
    memset(&ld, 0, sizeof ld);
    ld.caches = caches; ld.cache_count = od.cache_count;
    ld.vals = vals; ld.val_count = od.val_count;
    ld.eye = eye;
    ld.glossy = od.proxy_glossy != 0;
    ld.glossy_exponent = od.glossy_exponent;
    if (od.cache_exponents) {   /* each cache's own lobe, as the frame made it */
        kc = (float *)malloc(od.cache_count * sizeof(float));
        gltest_read_buffer(od.cache_exponents, od.cache_count * sizeof(float), kc);
        ld.cache_glossy_exponent = kc;
    }
    ld.receivers = rec; ld.receiver_count = nrec;
    ld.neighbour_index = nb_idx; ld.neighbour_count = nb_cnt; ld.neighbour_stride = n; ld.d_cmax = dcmax;
    src = (uint32_t *)malloc(nrec * 4);
    frame_sources(ff, rec, map, nrec, src);   /* the pass's blocks */
    ld.source = src;
    ld.scene_scale = o.scene_scale;
    ld.env = ff->f.env;
    assert_int_equal(gim_lightskin_frame_twin(&ld, cpu), GIM_OK);
    bad = compare_pixels(gpu, cpu, map, nrec, tol, max_rel);
    free(pos_nrm); free(rec); free(caches); free(vals); free(map); free(nb_idx); free(nb_cnt); free(dcmax); free(cpu);
    free(kc); free(src);
    return bad;
}

/* Mean R / G of the floor pixels (normal up) in the left and the right third of the image. */
static void floor_redness(const float *rgba, const float *nrm, double *left, double *right) {
    double s[2][2] = {{0, 0}, {0, 0}};
    int x, y;
    for (y = 0; y < H; ++y)
        for (x = 0; x < W; ++x) {
            int i = y * W + x, side = x < W / 3 ? 0 : (x >= 2 * W / 3 ? 1 : -1);
            if (side < 0 || nrm[i * 4 + 3] != 1.0f || nrm[i * 4 + 1] < 0.99f) continue;
            s[side][0] += rgba[i * 4];
            s[side][1] += rgba[i * 4 + 1];
        }
    assert_true(s[0][1] > 0.0 && s[1][1] > 0.0);
    *left = s[0][0] / s[0][1];
    *right = s[1][0] / s[1][1];
}

static void cornell_frame(const char *gltf) {
    frame_fixture ff;
    float *full = (float *)malloc(W * H * 16), *brsm = (float *)malloc(W * H * 16), *nrm = (float *)malloc(W * H * 16);
    gim_frame_outputs o;
    gim_debug_outputs od;
    gim_stats st;
    double left, right, err[3], max_rel;
    static const uint32_t counts[3] = {128, 512, 2048};
    uint32_t bad, k, seed;
    if (frame_begin(&ff, gltf, 48)) {
        print_message("%s absent: skipped\n", gltf);
        free(full); free(brsm); free(nrm);
        return;
    }
    /* FULL: every RSM texel a VAL */
    ff.fr.method = GIM_METHOD_LIGHTSKIN_FULL;
    ff.fr.timing = 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    gltest_state_unchanged(&ff.f);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    assert_int_equal(od.val_count, 48u * 48u);
    assert_int_equal(od.cache_count, ff.g.cache_count);
    assert_int_equal(o.lights[0].importance, 0);    /* FULL has no importance buffers */
    assert_int_equal(o.lights[0].selected, 0);
    assert_int_equal(od.proxy_glossy, 0);             /* no glossy material in the box */
    read_indirect(&o, full);
    gltest_read_texture(o.gbuffer_normal, GL_RGBA, nrm);
    bad = compare_with_cpu_frame(&ff, full, 5e-4, &max_rel);
    print_message("%s FULL: %u caches, GPU vs CPU frame max rel %.2e, %u pixels above 5e-4\n",
                  gltf ? "glTF" : "builtin", od.cache_count, max_rel, bad);
    assert_true(bad <= W * H / 200);
    /* colour bleeding: the white floor is redder near the red (left) wall */
    floor_redness(full, nrm, &left, &right);
    print_message("floor R/G: left %.3f, right %.3f\n", left, right);
    assert_true(left > 1.15 * right);
    /* stats of a timed frame */
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    assert_true(st.timed && st.frame_ms > 0.0);
    assert_true(st.pass_ms[GIM_PASS_PROXY_LIGHTS] > 0.0 && st.pass_ms[GIM_PASS_SHADE] > 0.0);
    assert_true(st.pass_ms[GIM_PASS_IMPORTANCE_MAP] == 0.0);
    assert_int_equal(st.cache_count, od.cache_count);
    assert_int_equal(st.val_count, od.val_count);
    assert_true(st.gpu_bytes > (uint64_t)od.cache_count * 32u + (uint64_t)W * H * 8u);

    /* BRSM converges to FULL as N_sVAL grows (each error the mean of two frames) */
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    ff.fr.timing = 0;
    ff.fr.lightskin.temporal_steps = 1;   /* two independent frames */
    for (k = 0; k < 3; ++k) {
        err[k] = 0.0;
        for (seed = 0; seed < 2; ++seed) {
            ff.fr.lightskin.val_count = counts[k];
            ff.fr.frame_index = seed + 1;
            assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
            o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
            assert_int_equal(od.val_count, counts[k]);
            assert_true(o.lights[0].importance != 0);
            read_indirect(&o, brsm);
            err[k] += 0.5 * mean_rel_diff(brsm, full);
        }
        print_message("BRSM %u VALs: mean relative difference to FULL %.4f\n", counts[k], err[k]);
    }
    assert_true(err[2] < err[0]);
    assert_true(err[2] < 0.5 * err[0]);
    assert_true(err[2] < 0.1);
    bad = compare_with_cpu_frame(&ff, brsm, 5e-4, &max_rel);
    print_message("BRSM 2048: GPU vs CPU frame max rel %.2e, %u pixels above 5e-4\n", max_rel, bad);
    assert_true(bad <= W * H / 200);

    gltest_state_unchanged(&ff.f);
    frame_end(&ff);
    free(full); free(brsm); free(nrm);
}

/* RSM gather (GIM_METHOD_RSM_GATHER) against its twin gim_rsm_gather_twin on the frame's own RSM and
   pixels; a wider pattern gathers more of the RSM. */
static void rsm_gather_matches_twin(void **state) {
    frame_fixture ff;
    gim_frame_outputs o;
    gim_debug_outputs od;
    gim_rsm_data rsm;
    gim_gather_desc gd;
    float *gpu = (float *)malloc(W * H * 16), *pos, *nrm, *flux, *cpu, *area, *valid, *pattern;
    gim_receiver *rec = (gim_receiver *)calloc(W * H, sizeof *rec);
    uint32_t *map = (uint32_t *)malloc(W * H * 4), nrec, n, i, bad;
    gim_vec3 eye;
    double max_rel, sum_narrow = 0.0, sum_wide = 0.0;
    (void)state;
    GLTEST_BEGIN();
    frame_begin(&ff, NULL, 32);
    ff.fr.method = GIM_METHOD_RSM_GATHER;
    ff.fr.gather.samples = 64;
    ff.fr.gather.radius = 0.15f;   /* Dachsbacher's narrow pattern (the default holds the whole RSM) */
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    gltest_state_unchanged(&ff.f);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    assert_int_equal(od.cache_count, 0);          /* no LightSkin passes in a gather frame */
    assert_int_equal(o.lights[0].importance, 0);
    read_indirect(&o, gpu);
    for (i = 0; i < W * H; ++i) sum_narrow += gpu[i * 4];
    n = o.lights[0].rsm_size;
    pos = (float *)malloc(n * n * 16); nrm = (float *)malloc(n * n * 16); flux = (float *)malloc(n * n * 16);
    gltest_read_texture(o.lights[0].rsm_position, GL_RGBA, pos);
    gltest_read_texture(o.lights[0].rsm_normal, GL_RGBA, nrm);
    gltest_read_texture(o.lights[0].rsm_flux, GL_RGBA, flux);
    area = (float *)malloc(n * n * 4); valid = (float *)malloc(n * n * 4);
    for (i = 0; i < n * n; ++i) { /* RGBA -> the twin's arrays */
        area[i] = nrm[i * 4 + 3]; valid[i] = pos[i * 4 + 3];
        memmove(pos + i * 3, pos + i * 4, 12); memmove(nrm + i * 3, nrm + i * 4, 12); memmove(flux + i * 3, flux + i * 4, 12);
    }
    rsm.position = pos; rsm.normal = nrm; rsm.flux = flux; rsm.area = area; rsm.valid = valid; rsm.width = rsm.height = n;
    nrec = frame_receivers(&ff, rec, map, &eye);
    pattern = (float *)malloc(64 * 8);
    assert_int_equal(gim_hammersley_points(pattern, 64, 2, NULL), GIM_OK);
    cpu = (float *)malloc(nrec * 12);
    memset(&gd, 0, sizeof gd);
    gd.rsm = &rsm; gd.light_view_proj = gim_mat4_mul(o.lights[0].proj, o.lights[0].view);
    gd.samples = pattern; gd.sample_count = 64; gd.radius = 0.15f * (float)n;
    gd.receivers = rec; gd.receiver_count = nrec; gd.scene_scale = o.scene_scale; gd.env = ff.f.env;
    assert_int_equal(gim_rsm_gather_twin(&gd, cpu), GIM_OK);
    /* a sample whose texel index floor(p + offset) falls on the other side of a texel edge with
       the GPU's float unprojection than with the twin's double one reads a neighbouring texel:
       one sample of 64 differs there, which near a contact (a texel at a few texels' distance,
       e ~ 1 / d^2) moves the pixel by up to ~25% (2 pixels of 8591 here) */
    bad = compare_pixels(gpu, cpu, map, nrec, 1e-3, &max_rel);
    print_message("RSM gather: GPU vs twin max rel %.2e, %u of %u pixels above 1e-3\n", max_rel, bad, nrec);
    assert_true(bad <= nrec / 30);
    bad = compare_pixels(gpu, cpu, map, nrec, 0.15, &max_rel);
    print_message("RSM gather: max rel %.2e, %u pixels above 0.15\n", max_rel, bad);
    assert_true(bad <= nrec / 1000);
    /* a wider pattern gathers more of the light */
    ff.fr.gather.radius = 1.0f;
    ff.fr.gather.samples = 1024;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    read_indirect(&o, gpu);
    for (i = 0; i < W * H; ++i) sum_wide += gpu[i * 4];
    print_message("RSM gather: image sum %.4g at radius 0.15, %.4g at 1\n", sum_narrow, sum_wide);
    assert_true(sum_wide > sum_narrow);
    free(gpu); free(pos); free(nrm); free(flux); free(cpu); free(area); free(valid); free(pattern); free(rec); free(map);
    frame_end(&ff);
    GLTEST_END();
}

static void cornell_builtin(void **state) {
    (void)state;
    GLTEST_BEGIN();
    cornell_frame(NULL);
    GLTEST_END();
}

static void cornell_gltf(void **state) {
    (void)state;
    GLTEST_BEGIN();
    cornell_frame(CORNELL_GLTF);
    GLTEST_END();
}

/* Glossy proxy lights exist exactly when a material is glossy; the GPU frame still matches
   the CPU frame; sizes change between frames without a new context; no caches: no LightSkin. */
static void glossy_sizes_and_no_caches(void **state) {
    frame_fixture ff;
    gim_material *m;
    gim_frame_outputs o;
    gim_debug_outputs od;
    float *img = (float *)malloc(W * H * 16);
    double max_rel;
    uint32_t i, bad;
    (void)state;
    GLTEST_BEGIN();
    frame_begin(&ff, NULL, 32);
    /* make the back wall's material glossy */
    m = (gim_material *)calloc(ff.s.material_count, sizeof *m);
    for (i = 0; i < ff.s.material_count; ++i) {
        memcpy(m[i].diffuse, ff.s.materials[i].diffuse, 12);
        if (i == 0) {
            m[i].glossy[0] = m[i].glossy[1] = m[i].glossy[2] = 0.3f;
            m[i].exponent = 30.0f;
            ff.s.materials[i].glossy[0] = ff.s.materials[i].glossy[1] = ff.s.materials[i].glossy[2] = 0.3f;
            ff.s.materials[i].exponent = 30.0f;
        }
    }
    assert_int_equal(gim_set_materials(ff.f.ctx, m, ff.s.material_count), GIM_OK);
    ff.fr.lightskin.val_count = 512;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    assert_true(od.proxy_glossy != 0);
    assert_true(od.glossy_exponent == 30.0f);
    read_indirect(&o, img);
    bad = compare_with_cpu_frame(&ff, img, 5e-4, &max_rel);
    print_message("glossy BRSM: GPU vs CPU frame max rel %.2e, %u pixels above 5e-4\n", max_rel, bad);
    assert_true(bad <= W * H / 200);
    /* the default RGBA16F output: the same frame within half precision (2^-11 relative) */
    ff.fr.indirect_float32 = 0;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    read_indirect(&o, img);
    bad = compare_with_cpu_frame(&ff, img, 1.1e-3, &max_rel);
    print_message("glossy BRSM, RGBA16F: GPU vs CPU frame max rel %.2e, %u pixels above 1.1e-3\n", max_rel, bad);
    assert_true(bad <= W * H / 200);
    /* the world caches and their grid are made again only when an instance or mesh changes */
    {
        uint64_t v = ff.f.ctx->scene_version;
        gim_cache *cs = (gim_cache *)malloc(ff.g.cache_count * sizeof *cs);
        double y_moved = 0.0, y_back = 0.0;
        uint32_t k;
        assert_int_equal(gim_set_instances(ff.f.ctx, ff.g.instances, ff.g.mesh_count), GIM_OK);
        assert_true(ff.f.ctx->scene_version == v && ff.f.ctx->ls_version == v);
        for (i = 0; i < ff.g.mesh_count; ++i) ff.g.instances[i].model.m[13] += 0.05f;   /* lift everything 5 cm */
        assert_int_equal(gim_set_instances(ff.f.ctx, ff.g.instances, ff.g.mesh_count), GIM_OK);
        assert_true(ff.f.ctx->scene_version != v);
        ff.fr.indirect_float32 = 1;
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        assert_true(ff.f.ctx->ls_version == ff.f.ctx->scene_version);
        o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
        gltest_read_buffer(od.caches, ff.g.cache_count * sizeof *cs, cs);
        for (k = 0; k < ff.g.cache_count; ++k) y_moved += cs[k].position[1];
        read_indirect(&o, img);
        bad = compare_with_cpu_frame(&ff, img, 5e-4, &max_rel);   /* its caches: the moved ones */
        print_message("moved instances: GPU vs CPU frame max rel %.2e, %u pixels above 5e-4\n", max_rel, bad);
        assert_true(bad <= W * H / 200);
        for (i = 0; i < ff.g.mesh_count; ++i) ff.g.instances[i].model.m[13] -= 0.05f;
        assert_int_equal(gim_set_instances(ff.f.ctx, ff.g.instances, ff.g.mesh_count), GIM_OK);
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        gltest_read_buffer(gim_debug(ff.f.ctx).caches, ff.g.cache_count * sizeof *cs, cs);
        for (k = 0; k < ff.g.cache_count; ++k) y_back += cs[k].position[1];
        assert_true(fabs((y_moved - y_back) / ff.g.cache_count - 0.05) < 1e-5);
        free(cs);
    }
    /* back to diffuse only: the glossy buffer goes */
    for (i = 0; i < ff.s.material_count; ++i) { m[i].glossy[0] = m[i].glossy[1] = m[i].glossy[2] = 0.0f; }
    assert_int_equal(gim_set_materials(ff.f.ctx, m, ff.s.material_count), GIM_OK);
    ff.fr.indirect_float32 = 1;
    ff.fr.lightskin.neighbour_count = 6;
    ff.fr.lightskin.val_count = 300;
    ff.g.lights[0].rsm_size = 40;
    assert_int_equal(gim_set_lights(ff.f.ctx, ff.g.lights, 1), GIM_OK);
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    assert_int_equal(od.proxy_glossy, 0);
    assert_int_equal(ff.f.ctx->ls.glossy, 0);
    assert_int_equal(od.neighbour_count, 6);
    assert_int_equal(od.val_count, 300);
    assert_int_equal(o.lights[0].rsm_size, 40);
    read_indirect(&o, img);
    /* no lights: no LightSkin passes, and what they owned is freed */
    assert_int_equal(gim_set_lights(ff.f.ctx, NULL, 0), GIM_OK);
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
    assert_int_equal(o.indirect, 0);
    assert_int_equal(ff.f.ctx->ls.vals, 0);
    assert_int_equal(ff.f.ctx->ls.diffuse, 0);
    assert_int_equal(ff.f.ctx->proxy_state, 0);   /* the proxy pass's sums, 96 bytes a cache and lane */
    /* bad frame settings */
    ff.fr.method = (gim_method)7;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_INVALID_ARGUMENT);
    ff.fr.method = GIM_METHOD_DEFAULT;
    ff.fr.lightskin.neighbour_count = GIM_MAX_NEIGHBOUR_CACHES + 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
    ff.f.log.errors = 0;
    gltest_state_unchanged(&ff.f);
    free(m);
    free(img);
    frame_end(&ff);
    GLTEST_END();
}

/* gim_frame_defaults writes out the documented defaults, and a frame of them renders exactly
   what the zero frame renders (gim_update resolves every zero from gim_frame_defaults once):
   every method, and ISM visibility with LightSkin and CLUSTERED, each on a fresh context (the
   k-means start warm from a context's last frame). vpl.interleave, like kmeans_iterations, is
   left 0: its default is the view's (gim_vpl_default_interleave, checked here at its corners).
   Shown to fail: with gim_frame_defaults writing the methods' 4 and 8, CLUSTERED's frame of
   defaults (4 x 4) differs from its zero frame (every VPL at every pixel at 96 rows). */
static void frame_defaults_render_as_zero(void **state) {
    static const gim_method methods[] = {GIM_METHOD_LIGHTSKIN_BRSM, GIM_METHOD_LIGHTSKIN_FULL, GIM_METHOD_RSM_GATHER,
                                         GIM_METHOD_CLUSTERED, GIM_METHOD_SSVP, GIM_METHOD_LIGHTSKIN_BRSM, GIM_METHOD_CLUSTERED};
    float *img[2];
    gim_frame d = gim_frame_defaults(GIM_METHOD_DEFAULT);
    unsigned mi, k;
    (void)state;
    GLTEST_BEGIN();
    assert_int_equal(d.method, GIM_METHOD_LIGHTSKIN_BRSM);
    assert_int_equal(d.visibility.mode, GIM_VISIBILITY_OFF);
    assert_int_equal(d.visibility.ism_size, 64);
    assert_int_equal(d.visibility.ism_points, 16384);
    assert_int_equal(d.lightskin.val_count, 2048);
    assert_int_equal(d.lightskin.temporal_steps, 32);
    assert_int_equal(d.lightskin.view_sample_count, 256);
    assert_true(d.lightskin.importance_clamp == 1.0f / 64.0f);
    assert_int_equal(d.lightskin.neighbour_count, 16);
    assert_int_equal(d.gather.samples, 256);
    assert_true(d.gather.radius == 1.5f);
    assert_int_equal(d.vpl.count, 4096);
    assert_int_equal(d.vpl.cluster_count, 30);
    assert_int_equal(d.vpl.bounces, 1);
    assert_int_equal(d.vpl.paraboloid_size, 256);
    assert_int_equal(d.vpl.second_bounce_vpls, 256);
    assert_int_equal(d.vpl.interleave, 0);
    assert_true(d.vpl.clamp_distance == 0.01f && d.vpl.blur_distance == 0.1f);
    assert_true(d.width == 0 && d.height == 0 && d.gbuffer.depth == 0 && d.scene_scale == 0.0f && d.vpl.kmeans_iterations == 0);
    d = gim_frame_defaults(GIM_METHOD_SSVP);
    assert_true(d.method == GIM_METHOD_SSVP && d.vpl.cluster_count == 8 && d.vpl.bounces == 2 && d.visibility.ism_points == 65536u);
    assert_true(d.vpl.count == 4096 && d.vpl.interleave == 0);
    /* k_m = 8 from 720 rows up, 8 x rows / 720 rounded up below; k^2 at most the VPLs */
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 1920, 1080, 0), 8);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 1280, 720, 0), 8);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 720, 1280, 0), 8);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 1280, 719, 0), 8);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 640, 360, 0), 4);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 642, 361, 0), 5);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 160, 90, 0), 1);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 64, 36, 0), 1);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, W, H, 0), 2);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 0, 0, 0), 1);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 1920, 1080, 63), 7);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 1920, 1080, 1), 1);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_SSVP, 65535, 65535, 0), 8);
    d = gim_frame_defaults(GIM_METHOD_CLUSTERED);
    assert_true(d.vpl.cluster_count == 30 && d.vpl.bounces == 1 && d.visibility.ism_size == 64 && d.visibility.ism_points == 65536u);
    assert_true(d.vpl.count == 2048 && d.vpl.interleave == 0);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_CLUSTERED, 1920, 1080, 0), 4);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_CLUSTERED, 640, 360, 0), 2);
    assert_int_equal(gim_vpl_default_interleave(GIM_METHOD_CLUSTERED, W, H, 0), 1);
    img[0] = (float *)malloc(W * H * 16);
    img[1] = (float *)malloc(W * H * 16);
    for (mi = 0; mi < sizeof methods / sizeof methods[0]; ++mi) {
        int ism = mi >= 5;
        double sum = 0.0;
        for (k = 0; k < 2; ++k) {
            frame_fixture ff;
            gim_frame zero = {0};
            frame_begin(&ff, NULL, 32);
            if (k == 1) ff.fr = gim_frame_defaults(methods[mi]);
            else ff.fr = zero, ff.fr.method = methods[mi];
            scene_gimany_camera(&ff.s, &ff.fr.view, &ff.fr.proj);
            ff.fr.width = W;
            ff.fr.height = H;
            ff.fr.indirect_float32 = 1;
            if (ism) ff.fr.visibility.mode = GIM_VISIBILITY_ISM;
            assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
            {
                gim_frame_outputs o = gim_outputs(ff.f.ctx);
                read_indirect(&o, img[k]);
            }
            frame_end(&ff);
        }
        for (k = 0; k < W * H; ++k) sum += img[0][k * 4];
        print_message("method %d%s: zero and default frames %s, red sum %.4g\n", (int)methods[mi], ism ? " ISM" : "",
                      memcmp(img[0], img[1], W * H * 16) ? "DIFFER" : "identical", sum);
        assert_true(sum > 0.0);
        assert_memory_equal(img[0], img[1], W * H * 16);
    }
    free(img[0]); free(img[1]);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cornell_builtin),
        cmocka_unit_test(cornell_gltf),
        cmocka_unit_test(glossy_sizes_and_no_caches),
        cmocka_unit_test(rsm_gather_matches_twin),
        cmocka_unit_test(frame_defaults_render_as_zero),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
