/* Imperfect shadow maps (Ritschel et al. 2008), the GPU twin of gim_ism_render_twin: one work group
   per map (a cache's, or a VPL's), the map and its pull-push pyramid in shared memory. Each invocation splats
   the points k = local, local + GROUP, ... of the map's subset (offset + k stride) as surfels
   (atomicMin on the distance's bits: a positive float orders as its bits), then the pyramid
   is pulled (farthest non-empty child) and pushed (a hole takes the farther of its parent and the
   bilinear blend of the four nearest parents, which follows a slope), level by level.
   The float arithmetic is the twin's, in its order (see gim_ism_render_twin in gimany.h). Each
   texel is stored in 16 bits, the upper half of its float's bits rounded to nearest
   (gim_ism_quantize), two to a uint: texel 2k in the low half, 2k + 1 in the high. */
#include "common.glsl"
#define GROUP 256
#define MAX_SIZE 64
#define PYRAMID 1365                  /* 32^2 + 16^2 + ... + 1 */
layout(local_size_x = GROUP) in;

struct Point { vec4 position_area; vec4 normal; };                /* gim_ism_points */
/* the maps' origins: gim_cache (2 vec4: position, normal) or gim_vpl (3 vec4: position,
   normal, flux), source_vec4s apart */
layout(std430, binding = 0) readonly buffer Sources { vec4 source[]; };
layout(std430, binding = 1) readonly buffer Points { Point point[]; };
layout(std430, binding = 2) writeonly buffer Maps { uint map_out[]; };   /* size^2 / 2 per map */

layout(location = 0) uniform uint first_map;   /* this dispatch's maps: first_map + work group */
layout(location = 1) uniform uint size;        /* power of two, 4..64 */
layout(location = 2) uniform uint stride;      /* point_count / P */
layout(location = 3) uniform uint count;       /* P: points per map */
layout(location = 4) uniform float lift;       /* GIM_ISM_LIFT scene_scale */
layout(location = 5) uniform float splat;      /* GIM_ISM_SPLAT (caches), GIM_ISM_VPL_SPLAT (VPLs) */
layout(location = 6) uniform int max_texels;   /* GIM_ISM_SPLAT_TEXELS */
layout(location = 7) uniform uint source_vec4s; /* 2: caches; 3: VPLs */
layout(location = 8) uniform uint source_first; /* map m's origin is source entry source_first + m */
layout(location = 9) uniform uint out_first;    /* Maps is bound from map out_first on (a block holds a range) */
layout(location = 10) uniform uint vpl_mode;    /* 0: every map made. VPLs (gim_vpl): 1: not an unlit VPL's (its
                                                   light is 0, no pass reads its map), the maps made counted in
                                                   made; 2: nor a kept VPL's (flux.w 1), which keeps its map */
layout(std430, binding = 3) buffer Made { uint made; };

shared uint level0[MAX_SIZE * MAX_SIZE];
shared float pyramid[PYRAMID];

void put(int tx, float s) { atomicMin(level0[tx], floatBitsToUint(s)); }

/* one surfel, as gim__ism_splat */
void splat_point(vec3 o, vec3 t, vec3 b, vec3 n, Point p, float area) {
    vec3 d = vec3(p.position_area.x - o.x, p.position_area.y - o.y, p.position_area.z - o.z);
    float dist = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(dist > lift)) return;
    int tx = ism_texel_index(d, dist, size, t, b, n);
    if (tx < 0) return;
    int cx = tx % int(size), cy = tx / int(size);
    float rs = splat * sqrt(area / PI);
    float rs2 = rs * rs;
    float rf = ceil(rs / dist * float(size) * 0.5);
    int r = rf < float(max_texels) ? int(rf) : max_texels;
    vec3 pn = p.normal.xyz;
    float dn = d.x * pn.x + d.y * pn.y + d.z * pn.z;
    for (int y = cy - r; y <= cy + r; ++y)
        for (int x = cx - r; x <= cx + r; ++x) {
            if (x < 0 || y < 0 || x >= int(size) || y >= int(size)) continue;
            vec3 dir = ism_texel_ray(y * int(size) + x, size, t, b, n);
            float den = dir.x * pn.x + dir.y * pn.y + dir.z * pn.z;
            if (!(den >= 1e-3 || den <= -1e-3)) continue;
            float s = dn / den;
            if (!(s > lift)) continue;
            vec3 h = vec3(s * dir.x - d.x, s * dir.y - d.y, s * dir.z - d.z);
            if (h.x * h.x + h.y * h.y + h.z * h.z > rs2) continue;
            put(y * int(size) + x, s);
        }
}

float fetch(uint level, uint off, uint sz, uint x, uint y) {
    return level == 0u ? uintBitsToFloat(level0[y * sz + x]) : pyramid[off + y * sz + x];
}

void main() {
    uint m = first_map + gl_WorkGroupID.x;
    uint local = gl_LocalInvocationIndex;
    if (vpl_mode != 0u) {   /* the whole work group leaves, before any barrier */
        uint v = (source_first + m) * source_vec4s;
        if (!(source[v].w > 0.0) || (vpl_mode == 2u && source[v + 2u].w == 1.0)) return;
        if (local == 0u) atomicAdd(made, 1u);
    }
    uint texels = size * size;
    for (uint q = local; q < texels; q += uint(GROUP)) level0[q] = floatBitsToUint(ISM_EMPTY);
    barrier();
    vec3 n = source[(source_first + m) * source_vec4s + 1u].xyz, t, b;
    basis(n, t, b);
    vec3 c = source[(source_first + m) * source_vec4s].xyz;
    vec3 o = vec3(c.x + lift * n.x, c.y + lift * n.y, c.z + lift * n.z);
    /* the map's offset frac(m phi) stride, as gim__ism_offset */
    uint hi, lo;
    umulExtended(m * 2654435769u, stride, hi, lo);
    for (uint k = local; k < count; k += uint(GROUP)) {
        Point p = point[hi + k * stride];
        splat_point(o, t, b, n, p, float(stride) * p.position_area.w);
    }
    barrier();
    /* pull: level l + 1 from level l (offsets into the pyramid: level 1 at 0) */
    uint sz = size, off = 0u, prev_off = 0u, levels = 0u;
    for (uint l = 0u; sz > 1u; ++l) {
        uint nsz = sz / 2u;
        for (uint q = local; q < nsz * nsz; q += uint(GROUP)) {
            uint x = q % nsz, y = q / nsz;
            float s = 0.0, cnt = 0.0;
            for (uint k = 0u; k < 4u; ++k) {
                float v = fetch(l, prev_off, sz, 2u * x + (k & 1u), 2u * y + (k >> 1u));
                if (v < ISM_EMPTY) { s = v > s ? v : s; cnt += 1.0; }
            }
            pyramid[off + q] = cnt > 0.0 ? s : ISM_EMPTY;
        }
        barrier();
        prev_off = off;
        off += nsz * nsz;
        sz = nsz;
        ++levels;
    }
    /* push: from the coarsest level down; level l (>= 1) sits at offset(l) */
    for (uint l = levels; l-- > 0u;) {
        uint lsz = size >> l, psz = lsz / 2u;
        uint loff = 0u, poff = 0u, s2 = size / 2u;
        for (uint j = 1u; j < l; ++j) { loff += s2 * s2; s2 /= 2u; }
        s2 = size / 2u;
        for (uint j = 1u; j < l + 1u; ++j) { poff += s2 * s2; s2 /= 2u; }
        for (uint q = local; q < lsz * lsz; q += uint(GROUP)) {
            uint x = q % lsz, y = q / lsz;
            uint xa = x / 2u, ya = y / 2u;
            uint xb = (x & 1u) == 1u ? min(xa + 1u, psz - 1u) : (xa > 0u ? xa - 1u : 0u);
            uint yb = (y & 1u) == 1u ? min(ya + 1u, psz - 1u) : (ya > 0u ? ya - 1u : 0u);
            float p00 = pyramid[poff + ya * psz + xa], p10 = pyramid[poff + ya * psz + xb];
            float p01 = pyramid[poff + yb * psz + xa], p11 = pyramid[poff + yb * psz + xb];
            float fill = p00;
            if (p00 < ISM_EMPTY && p10 < ISM_EMPTY && p01 < ISM_EMPTY && p11 < ISM_EMPTY) {
                float blend = (9.0 * p00 + 3.0 * p10 + 3.0 * p01 + p11) * 0.0625;
                fill = blend > p00 ? blend : p00;
            }
            if (l == 0u) {
                if (!(uintBitsToFloat(level0[q]) < ISM_EMPTY)) level0[q] = floatBitsToUint(fill);
            } else if (!(pyramid[loff + q] < ISM_EMPTY)) {
                pyramid[loff + q] = fill;
            }
        }
        barrier();
    }
    uint half_texels = texels / 2u;
    for (uint q = local; q < half_texels; q += uint(GROUP))
        map_out[(m - out_first) * half_texels + q] = ism_pack(level0[2u * q], level0[2u * q + 1u]);
}
