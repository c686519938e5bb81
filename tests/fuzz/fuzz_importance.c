/* libFuzzer: hostile RSMs, maps and tables through the importance map, the eq. 12 scans and
   the selection. Whatever the bytes, a call returns a code; on GIM_OK every map value is
   finite and >= 0, every selection is inside the map with a finite pdf > 0, and a texel of
   importance 0 is picked only by the all-zero fallback. */
#define GIMANY_IMPLEMENTATION
#include "gimany.h"
#include "fuzzutil.h"
#include <stdlib.h>
#include <string.h>


int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    reader r;
    uint32_t mode, w, h, count, seed, nvs, i;
    size_t n;
    float *map, *pos, *nrm, *flux, *valid, scale;
    double *col, *row;
    gim_view_sample vs[8];
    gim_selected_val sel[64];
    gim_env env;
    gim_select_desc sd;
    gim_result res;
    int all_zero = 1;
    r.p = data; r.n = size;
    mode = take_u32(&r);
    w = 1u + take_u32(&r) % 16u;
    h = 1u + take_u32(&r) % 16u;
    count = 1u + take_u32(&r) % 64u;
    seed = take_u32(&r);
    n = (size_t)w * h;
    memset(&env, 0, sizeof env);
    map = (float *)malloc(n * sizeof(float));
    col = (double *)malloc(n * sizeof(double));
    row = (double *)malloc(w * sizeof(double));
    pos = (float *)malloc(n * 3 * sizeof(float));
    nrm = (float *)malloc(n * 3 * sizeof(float));
    flux = (float *)malloc(n * 3 * sizeof(float));
    valid = (float *)malloc(n * sizeof(float));
    if (!map || !col || !row || !pos || !nrm || !flux || !valid) abort();
    memset(&sd, 0, sizeof sd);
    sd.column = col; sd.row = row; sd.width = w; sd.height = h; sd.count = count; sd.seed = seed; sd.env = env;
    if (mode % 3 == 0) { /* an RSM and view samples: the whole chain */
        gim_importance_desc d;
        take_bytes(&r, pos, n * 3 * sizeof(float));
        take_bytes(&r, nrm, n * 3 * sizeof(float));
        take_bytes(&r, flux, n * 3 * sizeof(float));
        take_bytes(&r, valid, n * sizeof(float));
        nvs = 1u + take_u32(&r) % 8u;
        take_bytes(&r, vs, sizeof vs);
        take_bytes(&r, &scale, sizeof scale);
        memset(&d, 0, sizeof d);
        d.rsm_position = pos; d.rsm_normal = nrm; d.rsm_flux = flux;
        d.rsm_valid = (mode & 8u) ? valid : NULL;
        d.width = w; d.height = h; d.view_samples = vs; d.view_sample_count = nvs;
        d.scene_scale = scale;
        take_bytes(&r, &d.clamp, sizeof d.clamp);
        res = gim_importance_map(&d, map);
        if (res != GIM_OK) goto done;
        for (i = 0; i < n; ++i) if (!(map[i] >= 0.0f && map[i] <= FLT_MAX)) abort();
    } else {
        take_bytes(&r, map, n * sizeof(float));
    }
    if (mode % 3 == 2) { /* raw tables: select must survive anything */
        take_bytes(&r, col, n * sizeof(double));
        take_bytes(&r, row, w * sizeof(double));
        res = gim_importance_select(&sd, sel);
        if (res != GIM_OK) goto done;
        for (i = 0; i < count; ++i)
            if (sel[i].x >= w || sel[i].y >= h || !(sel[i].pdf > 0.0f && sel[i].pdf <= 1.0f)) abort();
        goto done;
    }
    if (gim_importance_cumsum(map, w, h, col, row, env) != GIM_OK) goto done;
    for (i = 0; i < n; ++i) if (map[i] > 0.0f) all_zero = 0;
    if (gim_importance_select(&sd, sel) != GIM_OK) abort();
    for (i = 0; i < count; ++i) {
        if (sel[i].x >= w || sel[i].y >= h || !(sel[i].pdf > 0.0f && sel[i].pdf <= 1.0f)) abort();
        if (!all_zero && !(map[(size_t)sel[i].y * w + sel[i].x] > 0.0f)) abort();
    }
done:
    free(map); free(col); free(row); free(pos); free(nrm); free(flux); free(valid);
    return 0;
}
