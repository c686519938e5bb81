/* A sun whose RSM follows the view (gim_light.fit_view, gim_light_fit_view): on a world far
   larger than what the camera sees, its texels shrink to the visible region, every visible
   point is inside the RSM, casters outside the view still cast, the RSM still matches its
   twin, and its flux is the sun's power on the window. */
#define GIMANY_IMPLEMENTATION
#include "gltest.h"

#define S 64

/* A 2000 x 2000 floor (y = 0) and a 40 x 40 roof at y = 100 over (-20..20, -20..20): outside the
   camera's view (it looks down at the floor near the origin from y = 5), but between the sun
   and the floor it sees. */
static const float world_pos[] = {-1000, 0, -1000, -1000, 0, 1000, 1000, 0, 1000, 1000, 0, -1000,
                                  -20, 100, -20, -20, 100, 20, 20, 100, 20, 20, 100, -20};
static const float world_nrm[] = {0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0};
static const uint32_t world_idx[] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};

static void read_rsm(GLuint tex, float *out) { gltest_read_texture(tex, GL_RGBA, out); }

static void fit_view_follows_the_camera(void **state) {
    gltest_fixture f;
    gim_mesh_desc md;
    gim_mesh mesh;
    gim_instance in;
    gim_material mat;
    gim_light l, fl;
    gim_frame fr;
    gim_frame_outputs o;
    gim_debug_outputs od;
    gim_fit_view_desc fd;
    gim_rsm_view rv;
    float fmin[3], fmax[3], *pos = (float *)malloc(S * S * 16), *nrm = (float *)malloc(S * S * 16),
                            *flux = (float *)malloc(S * S * 16), vs[256 * 8];
    double area_scene, area_view, total = 0.0, a;
    int i, lit = 0, roof = 0;
    uint32_t x, y;
    (void)state;
    GLTEST_BEGIN();
    gltest_fixture_begin(&f);
    memset(&md, 0, sizeof md);
    md.data.positions = world_pos;
    md.data.normals = world_nrm;
    md.data.vertex_count = 8;
    md.data.indices = world_idx;
    md.data.index_count = 12;
    assert_int_equal(gim_add_mesh(f.ctx, &md, &mesh), GIM_OK);
    memset(&mat, 0, sizeof mat);
    mat.diffuse[0] = mat.diffuse[1] = mat.diffuse[2] = 0.5f;
    assert_int_equal(gim_set_materials(f.ctx, &mat, 1), GIM_OK);
    in.mesh = mesh;
    in.model = gim_mat4_identity();
    assert_int_equal(gim_set_instances(f.ctx, &in, 1), GIM_OK);
    memset(&l, 0, sizeof l);
    l.irradiance = 2.0f;
    l.direction = gim_v3(0.05f, 1.0f, 0.02f);
    l.rsm_size = S;
    memset(&fr, 0, sizeof fr);
    fr.view = gim_mat4_look_at(gim_v3(0.0f, 5.0f, 8.0f), gim_v3(0.0f, 0.0f, 0.0f), gim_v3(0.0f, 1.0f, 0.0f));
    fr.proj = gim_mat4_perspective(1.0f, 1.0f, 0.1f, 40.0f);
    fr.width = 32;
    fr.height = 32;
    fr.lightskin.view_sample_count = 256;

    /* the whole world: the window is the world's bounding radius */
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
    area_scene = pow(2.0 / o.lights[0].proj.m[0] / S, 2.0);

    /* following the view */
    l.fit_view = 1;
    assert_int_equal(gim_set_lights(f.ctx, &l, 1), GIM_OK);
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    gltest_state_unchanged(&f);
    o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
    area_view = pow(2.0 / o.lights[0].proj.m[0] / S, 2.0);
    print_message("texel area: whole world %.4g, fitted to the view %.4g (%.0f x smaller)\n", area_scene, area_view,
                  area_scene / area_view);
    assert_true(area_view < area_scene / 1000.0);

    /* every visible point (the view samples) lies inside the RSM's window */
    gltest_read_buffer(od.view_samples, sizeof vs, vs);
    for (i = 0; i < 256; ++i) {
        gim_vec4 c;
        if (vs[i * 8 + 4] == 0.0f && vs[i * 8 + 5] == 0.0f && vs[i * 8 + 6] == 0.0f) continue;
        c = gim__mat4_vec4(gim_mat4_mul(o.lights[0].proj, o.lights[0].view), (gim_vec4){vs[i * 8], vs[i * 8 + 1], vs[i * 8 + 2], 1.0f});
        assert_true(fabsf(c.x / c.w) <= 1.0f && fabsf(c.y / c.w) <= 1.0f && c.z / c.w >= -1.0f && c.z / c.w <= 1.0f);
    }

    /* the same camera as the twin's: gim_light_fit_view then gim_light_camera */
    memset(&fd, 0, sizeof fd);
    fd.light = &l; fd.scene_min = o.bounds_min; fd.scene_max = o.bounds_max; fd.view = fr.view; fd.proj = fr.proj;
    rv.light = &fl; rv.bmin = fmin; rv.bmax = fmax;
    {
        gim_mat4 v, p;
        int k;
        assert_int_equal(gim_light_fit_view(&fd, &fl, fmin, fmax), GIM_OK);
        assert_int_equal(gim_light_camera(&fl, fmin, fmax, &v, &p), GIM_OK);
        for (k = 0; k < 16; ++k) {
            assert_true(v.m[k] == o.lights[0].view.m[k]);
            assert_true(p.m[k] == o.lights[0].proj.m[k]);
        }
    }

    /* the roof, outside the view, still casts: the window's centre sees the roof, not the floor;
       and the flux over the window is the sun's power on it (every texel hits something) */
    read_rsm(o.lights[0].rsm_position, pos);
    read_rsm(o.lights[0].rsm_normal, nrm);
    read_rsm(o.lights[0].rsm_flux, flux);
    for (y = 0; y < S; ++y)
        for (x = 0; x < S; ++x) {
            const float *q = pos + (y * S + x) * 4;
            if (q[3] > 0.0f) lit++;
            if (q[3] > 0.0f && fabsf(q[1] - 100.0f) < 1e-2f) roof++;
            total += flux[(y * S + x) * 4 + 1];
        }
    a = pow(2.0 / o.lights[0].proj.m[0], 2.0);
    print_message("RSM: %d lit texels, %d on the roof; flux %.6g of rho E window %.6g\n", lit, roof, total, 0.5 * 2.0 * a);
    assert_int_equal(lit, S * S);
    assert_true(roof > S * S / 4);
    assert_true(fabs(total - 0.5 * 2.0 * a) < 1e-3 * total);
    {   /* a few texels against the twin */
        gim_twin_scene ts;
        float tp[12 * 3], tn[12 * 3], ta[4 * 3];
        int t, k;
        for (t = 0; t < 4; ++t)
            for (k = 0; k < 3; ++k) {
                memcpy(tp + (t * 3 + k) * 3, world_pos + world_idx[t * 3 + k] * 3, 12);
                memcpy(tn + (t * 3 + k) * 3, world_nrm + world_idx[t * 3 + k] * 3, 12);
                ta[t * 3 + k] = 0.5f;
            }
        ts.positions = tp; ts.normals = tn; ts.albedo = ta; ts.triangle_count = 4;
        for (k = 0; k < 64; ++k) {
            gim_rsm_texel tw;
            x = (uint32_t)(k * 7) % S;
            y = (uint32_t)(k * 13 + 5) % S;
            assert_int_equal(gim_rsm_texel_twin(&ts, &rv, x, y, &tw), GIM_OK);
            if (tw.triangle == UINT32_MAX) continue;
            for (t = 0; t < 3; ++t) {
                assert_true(fabsf(pos[(y * S + x) * 4 + t] - tw.position[t]) < 1e-3f * 100.0f);
                assert_true(fabsf(flux[(y * S + x) * 4 + t] - tw.flux[t]) <= 1e-4f * tw.flux[t] + 1e-12f);
            }
        }
    }
    /* a view_distance nearer than the far plane shrinks the window further; bad values fail */
    fr.view_distance = 10.0f;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
    assert_true(pow(2.0 / o.lights[0].proj.m[0] / S, 2.0) < area_view);
    fr.view_distance = -1.0f;
    assert_int_equal(gim_update(f.ctx, &fr), GIM_ERROR_INVALID_ARGUMENT);
    fd.view_distance = NAN;
    assert_int_equal(gim_light_fit_view(&fd, &fl, fmin, fmax), GIM_ERROR_INVALID_ARGUMENT);
    assert_int_equal(gim_light_fit_view(NULL, &fl, fmin, fmax), GIM_ERROR_INVALID_ARGUMENT);
    f.log.errors = 0;
    /* a camera looking out of the world: the whole world again */
    fr.view_distance = 0.0f;
    fr.view = gim_mat4_look_at(gim_v3(0.0f, 3000.0f, 0.0f), gim_v3(0.0f, 4000.0f, 1.0f), gim_v3(0.0f, 1.0f, 0.0f));
    assert_int_equal(gim_update(f.ctx, &fr), GIM_OK);
    o = gim_outputs(f.ctx); od = gim_debug(f.ctx);
    assert_true(fabs(pow(2.0 / o.lights[0].proj.m[0] / S, 2.0) - area_scene) < 1e-3 * area_scene);
    gim_remove_mesh(f.ctx, mesh);
    free(pos); free(nrm); free(flux);
    gltest_fixture_end(&f);
    GLTEST_END();
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(fit_view_follows_the_camera),
    };
    int r = cmocka_run_group_tests(tests, NULL, NULL);
    gltest_shutdown();
    return r;
}
