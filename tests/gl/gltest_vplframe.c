/* The VPL methods of gim_update end to end on the Cornell box (Dong 2009, Aranha et al.): the GPU
   clusters against their twin on the frame's own VPLs, the GPU frame against the CPU chain
   (gim_vpl_shade_twin + gim_geometry_blur_twin on the frame's own VPLs, clusters and paraboloid maps),
   indirect shadows (visibility on against off behind a block), the second bounce's energy,
   temporal coherence of the clusters while the light moves, and that only what a frame
   enables is allocated. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 64
#define H 64
#include "framefix.h"

/* The built-in Cornell box with its spot turned to the green (right) wall, above the blocks:
   the floor gets only indirect light, most of it from that wall, so the tall block casts an
   indirect shadow on the floor between it and the red wall. */
static void wall_light(frame_fixture *ff, float yaw_deg) {
    gim_light l = ff->g.lights[0];
    double a = yaw_deg * 3.14159265358979323846 / 180.0;
    l.position = gim_v3(0.10f, 0.42f, -0.12f);
    l.direction = gim_v3((float)cos(a), 0.1f, (float)sin(a));
    l.cone_angle = 0.45f;
    assert_int_equal(gim_set_lights(ff->f.ctx, &l, 1), GIM_OK);
}

static void vpl_frame_begin(frame_fixture *ff, gim_method m) {
    assert_int_equal(frame_begin(ff, NULL, 64), 0);
    wall_light(ff, 0.0f);
    ff->fr.method = m;
    ff->fr.vpl.count = 256;
    ff->fr.vpl.cluster_count = 8;
    ff->fr.vpl.paraboloid_size = 64;
    ff->fr.vpl.interleave = 4;
}

/* The GPU's clusters against gim_cluster_paraboloids_twin on the GPU's own VPLs, assignment and
   k-means centres. */
static void clusters_match_twin(frame_fixture *ff) {
    gim_frame_outputs o = gim_outputs(ff->f.ctx);
    gim_debug_outputs od = gim_debug(ff->f.ctx);
    uint32_t n = od.first_bounce_count, m = od.cluster_count, i, *asg = (uint32_t *)malloc(n * 4);
    gim_vpl *v = (gim_vpl *)malloc(n * sizeof *v);
    gim_paraboloid *gpu = (gim_paraboloid *)malloc(m * sizeof *gpu), *cpu = (gim_paraboloid *)malloc(m * sizeof *cpu);
    float *centres4 = (float *)malloc(m * 32), *c3 = (float *)malloc(m * 12), *n3 = (float *)malloc(m * 12);
    double worst = 0.0;
    gim_cluster_desc cd;
    assert_true(n > 0 && m > 0 && od.vpls && od.clusters && od.kmeans_centres && od.vpl_clusters);
    gltest_read_buffer(od.vpls, n * sizeof *v, v);
    gltest_read_buffer(od.vpl_clusters, n * 4, asg);
    gltest_read_buffer(od.clusters, m * sizeof *gpu, gpu);
    gltest_read_buffer(od.kmeans_centres, m * 32, centres4);
    for (i = 0; i < n; ++i) assert_true(asg[i] < m);
    for (i = 0; i < m; ++i) {
        memcpy(c3 + 3 * i, centres4 + 8 * i, 12);
        memcpy(n3 + 3 * i, centres4 + 8 * i + 4, 12);
        assert_true(centres4[8 * i + 3] >= 1.0f);   /* no cluster lost */
    }
    memset(&cd, 0, sizeof cd);
    cd.vpls = v; cd.vpl_count = n; cd.cluster = asg; cd.centres = c3; cd.normals = n3; cd.cluster_count = m;
    cd.scene_scale = o.scene_scale; cd.env = ff->f.env;
    assert_int_equal(gim_cluster_paraboloids_twin(&cd, cpu), GIM_OK);
    for (i = 0; i < m; ++i) {
        int k;
        double e = 0.0;
        for (k = 0; k < 3; ++k) {
            e = fmax(e, fabs((double)gpu[i].origin[k] - cpu[i].origin[k]) / o.scene_scale);
            e = fmax(e, fabs((double)gpu[i].normal[k] - cpu[i].normal[k]));
            e = fmax(e, fabs((double)gpu[i].flux[k] - cpu[i].flux[k]) / fmax(1e-30, fabs((double)cpu[i].flux[k])));
        }
        e = fmax(e, fabs((double)gpu[i].size - cpu[i].size) / o.scene_scale);
        e = fmax(e, fabs((double)gpu[i].near_distance - cpu[i].near_distance) / o.scene_scale);
        e = fmax(e, fabs((double)gpu[i].attribute_near - cpu[i].attribute_near) / o.scene_scale);
        assert_true(cpu[i].attribute_near > 0.0f && cpu[i].attribute_near <= cpu[i].near_distance);
        worst = fmax(worst, e);
        assert_true(cpu[i].size >= 0.0f && cpu[i].size < o.scene_scale);   /* 0: a one-VPL cluster, a point */
    }
    print_message("clusters: %u VALs from %u VPLs, GPU vs twin worst %.2e (size %.3g..)\n", m, n, worst,
                  (double)cpu[0].size);
    assert_true(worst < 1e-5);
    free(asg); free(v); free(gpu); free(cpu); free(centres4); free(c3); free(n3);
}

static void clusters_of_both_methods(void **state) {
    frame_fixture ff;
    int k;
    (void)state;
    GLTEST_BEGIN();
    for (k = 0; k < 2; ++k) {
        vpl_frame_begin(&ff, k ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED);
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        gltest_state_unchanged(&ff.f);
        clusters_match_twin(&ff);
        frame_end(&ff);
    }
    GLTEST_END();
}

/* The frame's receivers on the whole W x H grid (a zero normal where no surface). */
static void grid_receivers(frame_fixture *ff, gim_receiver *grid) {
    gim_receiver *rec = (gim_receiver *)calloc(W * H, sizeof *rec);
    uint32_t *map = (uint32_t *)malloc(W * H * 4), n, i;
    gim_vec3 eye;
    n = frame_receivers(ff, rec, map, &eye);
    memset(grid, 0, W * H * sizeof *grid);
    for (i = 0; i < n; ++i) grid[map[i]] = rec[i];
    free(rec);
    free(map);
}

/* The GPU frame against the CPU chain on its own VPLs, clusters and maps: gim_vpl_shade_twin with
   the frame's interleave and clamp, then gim_geometry_blur_twin. Returns the pixels whose largest
   channel differs by more than tol relative (floored at 1e-3 of the image's maximum). */
static uint32_t compare_with_cpu_chain(frame_fixture *ff, const float *gpu, double tol, double *max_rel) {
    gim_frame_outputs o = gim_outputs(ff->f.ctx);
    gim_debug_outputs od = gim_debug(ff->f.ctx);
    uint32_t n = od.vpl_count, m = od.cluster_count, s = od.paraboloid_size, i, bad;
    uint32_t k = ff->fr.vpl.interleave ? ff->fr.vpl.interleave : 8u, *cl = (uint32_t *)malloc(n * 4), *map = (uint32_t *)malloc(W * H * 4);
    gim_vpl *v = (gim_vpl *)malloc(n * sizeof *v);
    gim_paraboloid *maps = (gim_paraboloid *)malloc(m * sizeof *maps);
    float *dist = NULL, *ism = NULL, *shade = (float *)malloc(W * H * 12), *blur = (float *)malloc(W * H * 12);
    gim_receiver *grid = (gim_receiver *)malloc(W * H * sizeof *grid);
    gim_vpl_shade_desc sd;
    gim_blur_desc bd;
    gltest_read_buffer(od.vpls, n * sizeof *v, v);
    gltest_read_buffer(od.vpl_clusters, n * 4, cl);
    gltest_read_buffer(od.clusters, m * sizeof *maps, maps);
    if (od.paraboloid_distance) {
        dist = (float *)malloc((size_t)m * s * s * 4);
        glBindTexture(GL_TEXTURE_2D_ARRAY, od.paraboloid_distance);
        glGetTexImage(GL_TEXTURE_2D_ARRAY, 0, GL_RED, GL_FLOAT, dist);
        glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
    }
    grid_receivers(ff, grid);
    memset(&sd, 0, sizeof sd);
    if (dist && od.ism_maps) {   /* SSVP's second bounce: one ISM per VPL beside the clusters' maps */
        size_t texels = (size_t)(n - od.first_bounce_count) * od.ism_size * od.ism_size;
        ism = (float *)malloc(texels * 4);
        gltest_read_ism(od.ism_maps, texels, ism);
        sd.ism = ism; sd.ism_first = od.first_bounce_count; sd.ism_size = od.ism_size;
        sd.ism_bias = GIM_ISM_VPL_BIAS; sd.ism_slope = GIM_ISM_VPL_SLOPE;
    }
    sd.vpls = v; sd.vpl_count = n;
    sd.cluster = dist ? cl : NULL;
    sd.maps = maps; sd.map_count = m;
    sd.distance = dist; sd.map_size = s;
    sd.receivers = grid; sd.width = W; sd.height = H;
    sd.interleave = k;
    sd.clamp_distance = (ff->fr.vpl.clamp_distance < 0.0f ? 0.0f : ff->fr.vpl.clamp_distance > 0.0f ? ff->fr.vpl.clamp_distance : 0.01f) *
                        o.scene_scale;
    sd.scene_scale = o.scene_scale;
    sd.env = ff->f.env;
    assert_int_equal(gim_vpl_shade_twin(&sd, shade), GIM_OK);
    memset(&bd, 0, sizeof bd);
    bd.radiance = shade; bd.receivers = grid; bd.width = W; bd.height = H; bd.window = k;
    bd.position_tolerance = (ff->fr.vpl.blur_distance > 0.0f ? ff->fr.vpl.blur_distance : 0.1f) * o.scene_scale;
    bd.normal_tolerance = 0.8f;
    bd.env = ff->f.env;
    if (k > 1) assert_int_equal(gim_geometry_blur_twin(&bd, blur), GIM_OK);
    else memcpy(blur, shade, W * H * 12);
    for (i = 0; i < W * H; ++i) map[i] = i;
    bad = compare_pixels(gpu, blur, map, W * H, tol, max_rel);
    free(cl); free(map); free(v); free(maps); free(dist); free(ism); free(shade); free(blur); free(grid);
    return bad;
}

static void frame_matches_cpu_chain(void **state) {
    frame_fixture ff;
    float *img = (float *)malloc(W * H * 16);
    double max_rel;
    uint32_t bad;
    int k;
    (void)state;
    GLTEST_BEGIN();
    for (k = 0; k < 3; ++k) {   /* CLUSTERED; CLUSTERED without interleaving; SSVP, two bounces */
        vpl_frame_begin(&ff, k == 2 ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED);
        if (k == 1) ff.fr.vpl.interleave = 1;
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        gltest_state_unchanged(&ff.f);
        { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
        bad = compare_with_cpu_chain(&ff, img, 1e-3, &max_rel);
        print_message("%s: GPU vs CPU chain, %u of %u pixels above 1e-3, the others within %.2e\n",
                      k == 0 ? "clustered" : k == 1 ? "clustered, k = 1" : "ssvp", bad, W * H, max_rel);
        assert_true(bad <= W * H / 50);   /* a visibility tap across a texel edge flips a few */
        frame_end(&ff);
    }
    free(img);
    GLTEST_END();
}

/* Mean luminance of the floor pixels between the tall block and the red wall, and of every
   pixel. */
static void shadow_region(frame_fixture *ff, const float *img, double *region, double *all, uint32_t *count) {
    gim_receiver *grid = (gim_receiver *)malloc(W * H * sizeof *grid);
    double s = 0.0, t = 0.0;
    uint32_t i, n = 0, m = 0;
    grid_receivers(ff, grid);
    for (i = 0; i < W * H; ++i) {
        const gim_receiver *r = grid + i;
        double l = 0.2126 * img[i * 4] + 0.7152 * img[i * 4 + 1] + 0.0722 * img[i * 4 + 2];
        if (r->normal[0] == 0.0f && r->normal[1] == 0.0f && r->normal[2] == 0.0f) continue;
        t += l; m++;
        if (r->normal[1] > 0.9f && r->position[1] < 0.01f && r->position[0] < 0.075f && r->position[2] < -0.30f &&
            r->position[2] > -0.42f) { s += l; n++; }
    }
    assert_true(n > 0 && m > 0);
    *region = s / n;
    *all = t / m;
    *count = n;
    free(grid);
}

/* Indirect shadows: with visibility the floor behind the tall block, seen from the lit wall, is
   darker than without, while the whole image changes less. The second bounce adds energy
   where one bounce leaves it dark. Clamping only removes energy. */
static void shadows_and_second_bounce(void **state) {
    frame_fixture ff;
    float *img = (float *)malloc(W * H * 16);
    double on, off, all_on, all_off, b1, b2, all1, all2, unclamped, all_unclamped;
    uint32_t n;
    (void)state;
    GLTEST_BEGIN();
    vpl_frame_begin(&ff, GIM_METHOD_CLUSTERED);
    ff.fr.vpl.count = 1024;
    ff.fr.vpl.cluster_count = 16;
    ff.fr.vpl.kmeans_restart = 1;   /* every frame the same clusters, whatever came before */
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
    shadow_region(&ff, img, &on, &all_on, &n);
    ff.fr.vpl.no_visibility = 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
    shadow_region(&ff, img, &off, &all_off, &n);
    print_message("indirect shadow: floor behind the block %.4g with visibility, %.4g without (%u pixels); "
                  "image %.4g / %.4g\n", on, off, n, all_on, all_off);
    assert_true(on < 0.7 * off);
    assert_true(all_on > 0.7 * all_off);
    ff.fr.vpl.no_visibility = 0;
    ff.fr.vpl.clamp_distance = -1.0f;   /* no clamping */
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
    shadow_region(&ff, img, &unclamped, &all_unclamped, &n);
    print_message("clamping at 0.01 scene scales removes %.2f%% of the image's energy\n",
                  100.0 * (1.0 - all_on / all_unclamped));
    assert_true(all_on <= all_unclamped * (1.0 + 1e-6));
    frame_end(&ff);

    vpl_frame_begin(&ff, GIM_METHOD_SSVP);
    ff.fr.vpl.kmeans_restart = 1;
    ff.fr.vpl.bounces = 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
    shadow_region(&ff, img, &b1, &all1, &n);
    ff.fr.vpl.bounces = 2;
    ff.fr.vpl.second_bounce_vpls = 1024;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
    shadow_region(&ff, img, &b2, &all2, &n);
    print_message("second bounce: floor behind the block %.4g -> %.4g, image %.4g -> %.4g\n", b1, b2, all1, all2);
    assert_true(b2 > 1.3 * b1);
    assert_true(all2 > 1.05 * all1);
    frame_end(&ff);
    free(img);
    GLTEST_END();
}

/* Temporal coherence (Dong sec. 5.2; SSVP's warm start): the light turns 1 degree a frame; no
   cluster is lost and, from the last frame's centres, no centre jumps across the scene. With
   Dong's restart from the same seeds every frame no cluster is lost either; its jumps are
   reported (the documented reason the default is warm). */
static void clusters_move_smoothly(void **state) {
    frame_fixture ff;
    float prev[8 * 8], cur[8 * 8];
    int k, fr;
    uint32_t i;
    (void)state;
    GLTEST_BEGIN();
    for (k = 0; k < 3; ++k) {   /* CLUSTERED, SSVP (both warm), CLUSTERED restarting */
        double worst = 0.0, mean = 0.0;
        uint32_t steps = 0;
        vpl_frame_begin(&ff, k == 1 ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED);
        ff.fr.vpl.bounces = 1;
        ff.fr.vpl.kmeans_restart = k == 2;
        for (fr = 0; fr < 8; ++fr) {
            gim_frame_outputs o;
            gim_debug_outputs od;
            wall_light(&ff, (float)fr);
            ff.fr.frame_index = (uint32_t)fr;
            assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
            o = gim_outputs(ff.f.ctx); od = gim_debug(ff.f.ctx);
            assert_int_equal(od.cluster_count, 8u);
            gltest_read_buffer(od.kmeans_centres, 8 * 32, cur);
            for (i = 0; i < 8; ++i) {
                assert_true(cur[i * 8 + 3] >= 1.0f);   /* no cluster lost */
                if (fr > 0) {
                    double d = sqrt(pow(cur[i * 8] - prev[i * 8], 2) + pow(cur[i * 8 + 1] - prev[i * 8 + 1], 2) +
                                    pow(cur[i * 8 + 2] - prev[i * 8 + 2], 2)) / o.scene_scale;
                    worst = fmax(worst, d);
                    mean += d;
                    steps++;
                }
            }
            memcpy(prev, cur, sizeof cur);
        }
        mean /= steps;
        print_message("%s: centres move %.4f scene scales a frame on average, %.4f at most\n",
                      k == 0 ? "clustered" : k == 1 ? "ssvp" : "clustered, restarting (Dong 5.2)", mean, worst);
        if (k < 2) {
            assert_true(worst < 0.1);
            assert_true(mean < 0.02);
        }
        frame_end(&ff);
    }
    GLTEST_END();
}

/* Only what a frame enables exists: no maps without visibility and a second bounce, no
   attribute maps at one bounce, and nothing of the VPL methods in a LightSkin frame. */
static void only_what_is_enabled(void **state) {
    frame_fixture ff;
    gim_debug_outputs od;
    gim_stats st;
    uint64_t with_maps, without, two;
    (void)state;
    GLTEST_BEGIN();
    vpl_frame_begin(&ff, GIM_METHOD_CLUSTERED);
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    od = gim_debug(ff.f.ctx);
    assert_true(od.paraboloid_distance != 0);
    assert_true(od.paraboloid_position == 0 && od.paraboloid_normal == 0 && od.paraboloid_albedo == 0);
    assert_int_equal(od.vpl_count, od.first_bounce_count);
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    with_maps = st.gpu_bytes;
    ff.fr.vpl.no_visibility = 1;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    od = gim_debug(ff.f.ctx);
    assert_true(od.paraboloid_distance == 0 && od.paraboloid_position == 0);
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    without = st.gpu_bytes;
    print_message("GPU bytes: %llu with visibility, %llu without\n", (unsigned long long)with_maps,
                  (unsigned long long)without);
    assert_true(without + 8ull * 64 * 64 * 8 <= with_maps);   /* 8 maps of 64^2: distance + depth */
    ff.fr.vpl.bounces = 2;   /* by rays: the scene's hierarchy, no map at all */
    ff.fr.vpl.second_bounce = GIM_SECOND_BOUNCE_DEFAULT;   /* RAYS */
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    od = gim_debug(ff.f.ctx);
    assert_true(od.paraboloid_distance == 0 && od.paraboloid_position == 0 && od.paraboloid_albedo == 0);
    assert_true(ff.f.ctx->bvh.buffer != 0 && ff.f.ctx->bvh.version == ff.f.ctx->scene_version);
    assert_int_equal(od.vpl_count, od.first_bounce_count + 256u);
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    assert_true(st.gpu_bytes >= without + 256u * 48u + ff.f.ctx->bvh.bytes && st.gpu_bytes < without + 8ull * 64 * 64 * 48);
    ff.fr.vpl.second_bounce = GIM_SECOND_BOUNCE_MAPS;   /* from the maps: their attributes, no hierarchy */
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    od = gim_debug(ff.f.ctx);
    assert_int_equal(ff.f.ctx->bvh.buffer, 0);
    assert_true(od.paraboloid_position != 0 && od.paraboloid_normal != 0 && od.paraboloid_albedo != 0);
    assert_true(od.paraboloid_distance == 0);   /* without visibility, the attribute pass alone */
    assert_true(od.ism_maps == 0);              /* nor the second bounce's ISMs */
    assert_int_equal(od.vpl_count, od.first_bounce_count + 256u);
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    two = st.gpu_bytes;
    assert_true(two > without + 8ull * 64 * 64 * 48);
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    od = gim_debug(ff.f.ctx);
    assert_true(od.vpls == 0 && od.clusters == 0 && od.paraboloid_distance == 0 && od.paraboloid_position == 0);
    assert_int_equal(gim_frame_stats(ff.f.ctx, &st), GIM_OK);
    /* the VPL buffers gone: BRSM's frame without its proxy pass's sums (96 bytes a cache and
       lane, up to 16 lanes on these few caches) holds less than the two-bounce VPL frame */
    assert_true(st.gpu_bytes - ff.f.ctx->proxy_state_bytes < two);
    assert_true(ff.f.ctx->view_samples != 0 && ff.f.ctx->view_sample_pixels != 0 && ff.f.ctx->scan_blocks != 0);
    /* and back: BRSM's view samples and scan scratch go with its importance tables */
    ff.fr.method = GIM_METHOD_CLUSTERED;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    assert_true(ff.f.ctx->view_samples == 0 && ff.f.ctx->view_sample_pixels == 0 && ff.f.ctx->scan_blocks == 0);
    assert_true(ff.f.ctx->view_samples_bytes == 0 && ff.f.ctx->scan_blocks_bytes == 0);
    assert_true(ff.f.ctx->ls.caches == 0 && ff.f.ctx->proxy_state == 0);
    /* and BRSM again makes them anew */
    ff.fr.method = GIM_METHOD_LIGHTSKIN_BRSM;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
    assert_true(ff.f.ctx->view_samples != 0 && ff.f.ctx->view_sample_pixels != 0 && ff.f.ctx->scan_blocks != 0);
    gltest_state_unchanged(&ff.f);
    frame_end(&ff);
    GLTEST_END();
}

/* Unit-free: the box scaled by 1e-3 and by 1e3 (and the large one moved 50 of its diagonals
   from the origin), its spot's intensity by the square of the scale so the irradiance stays,
   gives the same image: every length threshold of the VPL methods (the VALs' lift and near
   distance, the clamp, the blur, the maps' depth, the visibility bias) follows the scene scale. */
static void same_image_at_any_scale(void **state) {
    static const double scales[2] = {1e-3, 1e3};
    frame_fixture ff;
    float *ref = (float *)malloc(W * H * 16), *img = (float *)malloc(W * H * 16);
    int k, m;
    (void)state;
    GLTEST_BEGIN();
    for (m = 0; m < 2; ++m) {
        gim_light l0;
        gim_frame f0;
        vpl_frame_begin(&ff, m ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED);
        ff.fr.vpl.kmeans_restart = 1;   /* each frame from the same seeds */
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, ref); }
        l0 = ff.g.lights[0];   /* the box's own spot, which wall_light turns */
        f0 = ff.fr;
        for (k = 0; k < 2; ++k) {
            double sc = scales[k], off = k ? 50.0 * 0.96 * sc : 0.0, d;
            gim_instance in = ff.g.instances[0];
            gim_mat4 S = gim_mat4_identity(), Sinv = gim_mat4_identity();
            gim_light l;
            int a;
            S.m[0] = S.m[5] = S.m[10] = (float)sc;
            S.m[12] = S.m[13] = S.m[14] = (float)off;
            Sinv.m[0] = Sinv.m[5] = Sinv.m[10] = (float)(1.0 / sc);
            Sinv.m[12] = Sinv.m[13] = Sinv.m[14] = (float)(-off / sc);
            in.model = gim_mat4_mul(S, ff.g.instances[0].model);
            assert_int_equal(gim_set_instances(ff.f.ctx, &in, 1), GIM_OK);
            l = l0;   /* wall_light's spot, scaled and moved with the box */
            l.position = gim_v3((float)(0.10 * sc + off), (float)(0.42 * sc + off), (float)(-0.12 * sc + off));
            l.direction = gim_v3(1.0f, 0.1f, 0.0f);
            l.cone_angle = 0.45f;
            l.intensity = (float)(l0.intensity * sc * sc);
            assert_int_equal(gim_set_lights(ff.f.ctx, &l, 1), GIM_OK);
            ff.fr = f0;
            ff.fr.view = gim_mat4_mul(f0.view, Sinv);
            assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
            { gim_frame_outputs oo = gim_outputs(ff.f.ctx); read_indirect(&oo, img); }
            d = mean_rel_diff(img, ref);
            for (a = 0; a < W * H * 4; ++a) assert_true(isfinite(img[a]));
            print_message("%s at scale %g%s: mean relative difference to scale 1: %.2e\n", m ? "ssvp" : "clustered", sc,
                          k ? ", 50 diagonals from the origin" : "", d);
            assert_true(d < 0.01);
        }
        frame_end(&ff);
    }
    free(ref);
    free(img);
    GLTEST_END();
}

/* Bad VPL settings are refused before any GL work. */
static void bad_settings(void **state) {
    frame_fixture ff;
    static const struct { uint32_t vpls, clusters, size, bounces, interleave, iters; } bad[] = {
        {40000, 8, 64, 1, 4, 0}, {256, 300, 64, 1, 4, 0}, {256, 8, 4096, 1, 4, 0},
        {256, 8, 64, 3, 4, 0},   {256, 8, 64, 1, 40, 0},  {16, 8, 64, 1, 8, 0}, {256, 8, 64, 1, 4, 65}};
    size_t k;
    (void)state;
    GLTEST_BEGIN();
    vpl_frame_begin(&ff, GIM_METHOD_CLUSTERED);
    for (k = 0; k < sizeof bad / sizeof bad[0]; ++k) {
        gim_frame f = ff.fr;
        f.vpl.count = bad[k].vpls; f.vpl.cluster_count = bad[k].clusters; f.vpl.paraboloid_size = bad[k].size;
        f.vpl.bounces = bad[k].bounces; f.vpl.interleave = bad[k].interleave; f.vpl.kmeans_iterations = bad[k].iters;
        assert_int_equal(gim_update(ff.f.ctx, &f), GIM_ERROR_OUT_OF_RANGE);
        gltest_state_unchanged(&ff.f);
    }
    ff.fr.vpl.clamp_distance = NAN;
    assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_INVALID_ARGUMENT);
    ff.f.log.errors = 0;
    frame_end(&ff);
    GLTEST_END();
}

/* vpl.importance: the first-bounce VPLs are the frame's BRSM selection written as VPLs. The
   picks are the twin's (gim_importance_select on the frame's own eq. 12 tables, light 0's
   offsets of the frame), VPL i is gim_vpls_from_vals of gim_vals_gather_twin on the frame's
   own RSM bit for bit (a second frame, 8 on, with the first's VPLs as previous: its kept
   flags), and the image is the CPU chain's on them; both methods. Back to 0 the
   selection's buffers and the view samples are released; 2 is refused. */
static void importance_vpls_match_twin(void **state) {
    enum { NV = 256 };
    frame_fixture ff;
    float *img = (float *)malloc(W * H * 16);
    gim_selected_val *gpu_sel = (gim_selected_val *)malloc(NV * sizeof *gpu_sel),
                     *twin_sel = (gim_selected_val *)malloc(NV * sizeof *twin_sel);
    gim_val *vals = (gim_val *)malloc(NV * sizeof *vals);
    gim_vpl *gpu_vpl = (gim_vpl *)malloc(NV * sizeof *gpu_vpl), *twin_vpl = (gim_vpl *)malloc(NV * sizeof *twin_vpl),
            *prev_vpl = (gim_vpl *)malloc(NV * sizeof *prev_vpl);
    double max_rel;
    uint32_t bad, i, n, lit;
    int k;
    (void)state;
    GLTEST_BEGIN();
    for (k = 0; k < 2; ++k) {
        gim_frame_outputs o;
        gim_debug_outputs od;
        gim_frame rf;
        gim_select_desc sd;
        gim_rsm_data rsm;
        float off[4];
        double *column, *row;
        int fi;
        vpl_frame_begin(&ff, k ? GIM_METHOD_SSVP : GIM_METHOD_CLUSTERED);
        ff.fr.vpl.importance = 1;
        ff.fr.lightskin.view_sample_count = 64;
        for (fi = 0; fi < 2; ++fi) {   /* a first frame, then one 8 frames on: its kept flags from the first's VPLs */
        uint32_t kept = 0;
        ff.fr.frame_index = fi ? 13 : 5;
        if (fi) memcpy(prev_vpl, gpu_vpl, NV * sizeof *gpu_vpl);
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        gltest_state_unchanged(&ff.f);
        o = gim_outputs(ff.f.ctx);
        od = gim_debug(ff.f.ctx);
        assert_int_equal(o.lights[0].selected_count, NV);
        assert_int_equal(od.first_bounce_count, NV);
        assert_true(od.view_samples != 0 && od.view_sample_count == 64);
        /* the picks: the twin's on the frame's tables (per texel: the default tile) */
        n = o.lights[0].rsm_size;
        assert_int_equal(o.lights[0].importance_tile, 1);
        column = (double *)malloc((size_t)n * n * sizeof(double));
        row = (double *)malloc(n * sizeof(double));
        gltest_read_buffer(o.lights[0].column, (size_t)n * n * sizeof(double), column);
        gltest_read_buffer(o.lights[0].row, n * sizeof(double), row);
        gltest_read_buffer(o.lights[0].selected, NV * sizeof *gpu_sel, gpu_sel);
        rf = ff.fr;
        rf.lightskin.temporal_steps = GIM_DEFAULT_TEMPORAL_STEPS;
        gim__select_offsets(&rf, 0u, NV, off);
        memset(&sd, 0, sizeof sd);
        sd.column = column; sd.row = row; sd.width = n; sd.height = n; sd.count = NV; sd.offsets = off; sd.env = ff.f.env;
        assert_int_equal(gim_importance_select(&sd, twin_sel), GIM_OK);
        for (i = 0; i < NV; ++i)
            assert_true(gpu_sel[i].x == twin_sel[i].x && gpu_sel[i].y == twin_sel[i].y && gpu_sel[i].pdf == twin_sel[i].pdf);
        /* the VPLs: the twin chain on the frame's RSM */
        rsm = gltest_rsm_read(o.lights[0].rsm_position, o.lights[0].rsm_normal, o.lights[0].rsm_flux, n);
        assert_int_equal(gim_vals_gather_twin(&rsm, twin_sel, NV, vals, ff.f.env), GIM_OK);
        assert_int_equal(gim_vpls_from_vals(vals, NV, fi ? prev_vpl : NULL, twin_vpl, ff.f.env), GIM_OK);
        gltest_read_buffer(od.vpls, NV * sizeof *gpu_vpl, gpu_vpl);
        for (i = 0, lit = 0; i < NV; ++i) {
            assert_memory_equal(gpu_vpl + i, twin_vpl + i, sizeof *gpu_vpl);
            lit += gpu_vpl[i].lit == 1.0f;
            kept += gpu_vpl[i].kept == 1.0f;
        }
        assert_true(lit > NV / 2);   /* drawn where the light is: nearly every pick lit */
        if (fi) assert_true(kept >= lit / 2u && kept < lit);   /* most picks stay on their texel */
        print_message("%s, importance VPLs, frame %u: %u of %u lit, %u kept\n", k ? "ssvp" : "clustered",
                      ff.fr.frame_index, lit, NV, kept);
        if (!fi) {   /* the image (a kept flag changes nothing in the shading; the count of visibility taps across a
                        texel edge varies with the clusters: 74-101 of these pixels at frame 13) */
            read_indirect(&o, img);
            bad = compare_with_cpu_chain(&ff, img, 1e-3, &max_rel);
            print_message("  GPU vs CPU chain, %u of %u pixels above 1e-3, the others within %.2e\n", bad, W * H, max_rel);
            assert_true(bad <= W * H / 50);
        }
        free(column); free(row);
        gltest_rsm_free(&rsm);
        }
        /* off again: no selection, no view samples; an importance of 2 is refused */
        ff.fr.vpl.importance = 0;
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_OK);
        o = gim_outputs(ff.f.ctx);
        assert_true(o.lights[0].selected == 0 && o.lights[0].column == 0 && o.lights[0].selected_count == 0);
        assert_true(ff.f.ctx->view_samples == 0);
        ff.fr.vpl.importance = 2;
        assert_int_equal(gim_update(ff.f.ctx, &ff.fr), GIM_ERROR_OUT_OF_RANGE);
        gltest_state_unchanged(&ff.f);
        ff.f.log.errors = 0;
        frame_end(&ff);
    }
    free(img); free(gpu_sel); free(twin_sel); free(vals); free(gpu_vpl); free(twin_vpl); free(prev_vpl);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(clusters_of_both_methods),
        cmocka_unit_test(frame_matches_cpu_chain),
        cmocka_unit_test(shadows_and_second_bounce),
        cmocka_unit_test(clusters_move_smoothly),
        cmocka_unit_test(only_what_is_enabled),
        cmocka_unit_test(same_image_at_any_scale),
        cmocka_unit_test(bad_settings),
        cmocka_unit_test(importance_vpls_match_twin),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
