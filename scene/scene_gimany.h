/* scene_gimany.h - hand a scene of scene/scene.h to a gimany context: one gimany mesh per
   scene mesh (world space, identity instance), LightSkin caches at one spacing for all, the
   materials, the lights and the camera matrices. Shared by the frame tests, the benchmarks
   and the demo. Include after gimany.h and scene.h; everything here is static. */
#ifndef GIMANY_SCENE_GIMANY_H
#define GIMANY_SCENE_GIMANY_H

#include <string.h>
#include <math.h>
#include "scene.h"

#if defined(__GNUC__) || defined(__clang__)
#define SCENE_GIMANY_FN static __attribute__((unused))
#else
#define SCENE_GIMANY_FN static
#endif

/* RSMs the examples keep from a scene (fixed arrays; gimany itself takes up to GIM_MAX_LIGHTS). */
#define SCENE_GIMANY_MAX_LIGHTS 256

/* What scene_gimany_load made; free with scene_gimany_free. */
typedef struct scene_gimany {
    gim_mesh *meshes;
    gim_cache_set *caches;       /* per mesh */
    gim_instance *instances;
    uint32_t mesh_count;
    uint32_t cache_count;        /* over all meshes */
    gim_light lights[SCENE_GIMANY_MAX_LIGHTS];
    uint32_t light_count;
} scene_gimany;

/* A scene light as a gimany light: spots wider than gimany's 1.5 rad cone are narrowed to it
   (a point light lights the half space below its cone then; say so in the log). */
SCENE_GIMANY_FN gim_light scene_gimany_light(const scene_light *l, uint32_t rsm_size) {
    gim_light g;
    memset(&g, 0, sizeof g);
    memcpy(g.color, l->color, sizeof g.color);
    g.rsm_size = rsm_size;
    if (l->type == SCENE_LIGHT_SPOT) {
        /* a cone wider than gimany's spots (glTF point lights come as half-angle pi): a point
           light, its six cube faces each an RSM; light outside the cone of a half-angle in
           (1.5, pi) is bounced too, which the reference does not */
        g.type = l->half_angle > 1.5f ? GIM_LIGHT_POINT : GIM_LIGHT_SPOT;
        g.intensity = l->intensity;
        g.position = gim_v3(l->position[0], l->position[1], l->position[2]);
        g.direction = gim_v3(l->direction[0], l->direction[1], l->direction[2]);
        g.cone_angle = l->half_angle < 1.5f ? l->half_angle : 1.5f;
    } else {
        g.type = GIM_LIGHT_DIRECTIONAL;
        g.irradiance = l->irradiance;
        g.direction = gim_v3(l->direction[0], l->direction[1], l->direction[2]);
    }
    return g;
}

/* Upload s into ctx: meshes with caches at one scene-level spacing (gim_cache_generate_scene:
   d_eps = d_eps_frac x the scene's scale; 0: 1/32; below 0: each mesh's own default, its own
   diagonal / 32, to compare with what a host gets from gim_cache_generate alone), materials,
   instances and lights (RSM rsm_size). GIM_OK or the first error (logged through the context's
   env); on error what was made is freed. */
SCENE_GIMANY_FN gim_result scene_gimany_load(gim_context *ctx, const scene *s, float d_eps_frac, uint32_t rsm_size,
                                    gim_env env, scene_gimany *out) {
    gim_material *mats;
    gim_cache_desc *cds;
    gim_cache_scene_desc sd;
    gim_result r = GIM_OK;
    uint32_t i;
    memset(out, 0, sizeof *out);
    out->meshes = (gim_mesh *)calloc(s->mesh_count ? s->mesh_count : 1, sizeof *out->meshes);
    out->caches = (gim_cache_set *)calloc(s->mesh_count ? s->mesh_count : 1, sizeof *out->caches);
    out->instances = (gim_instance *)calloc(s->mesh_count ? s->mesh_count : 1, sizeof *out->instances);
    mats = (gim_material *)calloc(s->material_count ? s->material_count : 1, sizeof *mats);
    cds = (gim_cache_desc *)calloc(s->mesh_count ? s->mesh_count : 1, sizeof *cds);
    if (!out->meshes || !out->caches || !out->instances || !mats || !cds) {
        free(mats); free(cds);
        free(out->meshes); free(out->caches); free(out->instances);
        memset(out, 0, sizeof *out);
        return GIM_ERROR_OUT_OF_MEMORY;
    }
    for (i = 0; i < s->material_count; ++i) {
        memcpy(mats[i].diffuse, s->materials[i].diffuse, sizeof mats[i].diffuse);
        memcpy(mats[i].glossy, s->materials[i].glossy, sizeof mats[i].glossy);
        mats[i].exponent = s->materials[i].exponent;
    }
    r = gim_set_materials(ctx, mats, s->material_count);
    free(mats);
    for (i = 0; i < s->mesh_count; ++i) { /* world space: the scene's meshes need no placement */
        const scene_mesh *m = &s->meshes[i];
        cds[i].mesh.positions = m->positions;
        cds[i].mesh.normals = m->normals;
        cds[i].mesh.vertex_count = m->vertex_count;
        cds[i].mesh.indices = m->indices;
        cds[i].mesh.index_count = m->triangle_count * 3u;
        cds[i].env = env;
    }
    memset(&sd, 0, sizeof sd);
    sd.meshes = cds;
    sd.count = s->mesh_count;
    sd.d_eps = (d_eps_frac > 0.0f ? d_eps_frac : 1.0f / 32.0f) * s->scale;
    sd.scene_scale = s->scale;
    sd.env = env;
    if (r == GIM_OK && d_eps_frac < 0.0f) {
        for (i = 0; i < s->mesh_count && r == GIM_OK; ++i) r = gim_cache_generate(&cds[i], &out->caches[i]);
    } else if (r == GIM_OK) {
        r = gim_cache_generate_scene(&sd, out->caches);
    }
    for (i = 0; i < s->mesh_count && r == GIM_OK; ++i) {
        gim_mesh_desc md;
        out->cache_count += out->caches[i].count;
        memset(&md, 0, sizeof md);
        md.data = cds[i].mesh;
        md.data.triangle_material = s->meshes[i].triangle_material;
        md.caches = &out->caches[i];
        r = gim_add_mesh(ctx, &md, &out->meshes[i]);
        if (r != GIM_OK) break;
        out->mesh_count = i + 1u;
        out->instances[i].mesh = out->meshes[i];
        out->instances[i].model = gim_mat4_identity();
    }
    free(cds);
    if (r == GIM_OK) r = gim_set_instances(ctx, out->instances, out->mesh_count);
    {   /* as many as fit gimany's RSMs, in order (a point light takes six) */
        uint32_t rsms = 0;
        for (i = 0; i < s->light_count && out->light_count < SCENE_GIMANY_MAX_LIGHTS; ++i) {
            gim_light g = scene_gimany_light(&s->lights[i], rsm_size);
            rsms += g.type == GIM_LIGHT_POINT ? 6u : 1u;
            if (rsms > SCENE_GIMANY_MAX_LIGHTS) break;
            out->lights[out->light_count++] = g;
        }
        if (i < s->light_count && env.logger.func) {
            char msg[160];
            snprintf(msg, sizeof msg, "scene_gimany_load: lights after the first %u skipped: they need more than "
                     "the examples' %u RSMs (a point light takes 6)", (unsigned)i, (unsigned)SCENE_GIMANY_MAX_LIGHTS);
            env.logger.func(GIM_LOG_WARNING, msg, env.logger.user_data);
        }
    }
    if (r == GIM_OK) r = gim_set_lights(ctx, out->lights, out->light_count);
    if (r != GIM_OK) {
        for (i = 0; i < s->mesh_count; ++i) gim_cache_set_free(&out->caches[i]);
        for (i = 0; i < out->mesh_count; ++i) gim_remove_mesh(ctx, out->meshes[i]);
        free(out->meshes); free(out->caches); free(out->instances);
        memset(out, 0, sizeof *out);
    }
    return r;
}

SCENE_GIMANY_FN void scene_gimany_free(gim_context *ctx, scene_gimany *g) {
    uint32_t i;
    for (i = 0; i < g->mesh_count; ++i) {
        gim_cache_set_free(&g->caches[i]);
        if (ctx) gim_remove_mesh(ctx, g->meshes[i]);
    }
    free(g->meshes); free(g->caches); free(g->instances);
    memset(g, 0, sizeof *g);
}

/* The meshes of s once more WITHOUT caches (meshes[i], instances[i] for scene mesh i, arrays of
   s->mesh_count): instancing them instead of scene_gimany_load's runs only the shared passes,
   no LightSkin (the demo's and viewer's method "none"). On error what was added is removed. */
SCENE_GIMANY_FN gim_result scene_gimany_add_plain(gim_context *ctx, const scene *s, gim_mesh *meshes,
                                                  gim_instance *instances) {
    gim_result r = GIM_OK;
    uint32_t i;
    for (i = 0; i < s->mesh_count && r == GIM_OK; ++i) {
        const scene_mesh *m = &s->meshes[i];
        gim_mesh_desc md;
        memset(&md, 0, sizeof md);
        md.data.positions = m->positions;
        md.data.normals = m->normals;
        md.data.vertex_count = m->vertex_count;
        md.data.indices = m->indices;
        md.data.index_count = m->triangle_count * 3u;
        md.data.triangle_material = m->triangle_material;
        r = gim_add_mesh(ctx, &md, &meshes[i]);
        instances[i].mesh = meshes[i];
        instances[i].model = gim_mat4_identity();
    }
    if (r != GIM_OK)
        while (i-- > 1u) {
            gim_remove_mesh(ctx, meshes[i - 1u]);
            meshes[i - 1u].id = 0;
        }
    return r;
}

/* The camera of s as a gim_frame's view and proj (near and far from the scene's bounds). */
SCENE_GIMANY_FN void scene_gimany_camera(const scene *s, gim_mat4 *view, gim_mat4 *proj) {
    float zfar = 0.0f, znear;
    int k;
    for (k = 0; k < 8; ++k) { /* the farthest bounds corner */
        float d2 = 0.0f;
        int a;
        for (a = 0; a < 3; ++a) {
            float c = (k >> a) & 1 ? s->bounds_max[a] : s->bounds_min[a], d = c - s->camera.eye[a];
            d2 += d * d;
        }
        if (sqrtf(d2) > zfar) zfar = sqrtf(d2);
    }
    zfar *= 1.01f;
    znear = zfar * 1e-3f;
    scene_camera_matrices(&s->camera, znear, zfar, view->m, proj->m);
}

#endif
