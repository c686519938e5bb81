/* LightSkin interpolation and shading per pixel (Bischoff 2017 "Interpolation using the Proxy
   Lights", eq. 8-9), the GPU twin of gim_cache_neighbours (with max_distance) followed by
   gim_lightskin_shade_twin with gim_shade_sources' blocks (and gim_neighbour_rays_twin between
   them with neighbour_rays): one invocation per B x B block of
   pixels (B = `block`, 1 or 2), one work group per 8B x 8B tile.
   1. finds the n nearest caches whose normal is within the compatibility angle, within
      `radius`, ties by cache index, as the twin, for the block's first receiver. The tile
      searches together: the work group gathers once into shared memory every cache that any
      of its pixels could take (within radius of the box around the tile's receivers, its
      normal within the compatibility angle of the cone around their normals), each cell of the
      hash grid over that box read by one invocation; then every search picks its n nearest
      from that list, the list sorted into rings of distance from the box so that a search
      stops at the first ring beyond its n-th nearest, or, in a tile whose box is much longer
      than the search is wide (it reaches far into the scene), into slabs across the box's
      long axis, searched outward from the pixel's own until the next on both sides lie beyond
      its n-th nearest. The list holds every cache the pixel's own search accepts, so the
      choice is the same. A tile whose list would not fit (a depth edge spans the scene, a box
      over too many cells) searches per pixel instead: shells of cells around the pixel's
      cell, nearest first, until the n-th found is nearer than any unvisited cell;
      with neighbour_rays (flags 8) the receiver then keeps only the caches it sees, a ray
      each through the scene's bounding volume hierarchy (bvh.glsl; gim_neighbour_rays_twin);
   2. interpolates the diffuse (and glossy) proxy lights of those caches there, with the
      formulas, weights and guards of gim_lightskin_shade_twin (read there);
   3. shades every pixel of the block on that receiver's surface with that light and its own
      albedo (shares(), gim_shade_sources); the block's other pixels go to a list that the
      whole work group then searches and interpolates for, one pixel per invocation. The light
      changes over a grid cell, so a block costs about a quarter of its pixels' searches.
   Sums in float (double in the twin). Writes rgb radiance, a = 1 where a surface is. */
#include "common.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

#define MAX_N 16
#define TILE 64u          /* invocations per work group, each a block of B x B pixels */
#define FALLBACK_CAP 192u /* a tile's pixels that cannot take their block's light (3 per block) */
#define LIST_CAP 768u     /* caches a tile's list holds (24 KiB of shared memory) */
#define CELL_CAP 4096     /* cells a tile's box may cover */
#define RINGS 8u          /* the list in rings of distance from the tile's box */
#define SLABS 32u         /* or, in a tile whose box is long, in slabs across its long axis */
#define SLAB_LENGTH 4.0   /* long: over this many times the search's radius */

layout(binding = 0) uniform sampler2D gbuffer_depth;
layout(binding = 1) uniform sampler2D gbuffer_normal;    /* world normal in xyz, w = 1 where drawn */
layout(binding = 2) uniform sampler2D gbuffer_albedo;    /* diffuse rgb (unused with host_gbuffer) */
layout(binding = 3) uniform sampler2D gbuffer_material;  /* material id (unused with host_gbuffer) */
layout(binding = 0) writeonly uniform image2D indirect;  /* RGBA16F or RGBA32F, set by the runtime */

struct Cache { vec4 position_area; vec4 normal_reflectance; };             /* gim_cache */
struct Proxy { vec4 position_radius; vec4 flux_visibility; vec4 sigma; };  /* gim_proxy_light */
struct Material { vec4 diffuse; vec4 glossy; };                            /* rgb, (rgb, k) */
layout(std430, binding = 0) readonly buffer Caches { Cache cache[]; };
layout(std430, binding = 1) readonly buffer Diffuse { Proxy diffuse[]; };
layout(std430, binding = 2) readonly buffer Glossy { Proxy glossy[]; };
layout(std430, binding = 3) readonly buffer BucketStart { uint bucket_start[]; };  /* bucket_count + 1 */
layout(std430, binding = 4) readonly buffer CacheCell { ivec4 cache_cell[]; };     /* grid cell of each cache */
layout(std430, binding = 5) readonly buffer Materials { Material material[]; };

layout(location = 0) uniform uvec2 size;
layout(location = 1) uniform mat4 inv_proj;
layout(location = 2) uniform mat4 inv_view;
layout(location = 3) uniform vec4 eye;          /* perspective: (position, 1); orthographic: (direction, 0) */
layout(location = 4) uniform uint n;            /* neighbours, 1..MAX_N */
layout(location = 5) uniform float cos_theta;   /* normal compatibility */
layout(location = 6) uniform vec4 grid;         /* origin xyz, cell side h */
layout(location = 7) uniform ivec3 dims;        /* cells per axis (the caches lie in 0..dims-1) */
layout(location = 8) uniform uint bucket_mask;  /* bucket_count - 1 (a power of two) */
layout(location = 9) uniform int rings;         /* shells searched: radius = rings h */
layout(location = 10) uniform float near_;      /* 1e-6 scene_scale */
layout(location = 11) uniform uint flags;       /* 1: glossy proxy lights; 2: host G-buffer; 4: tests: write
                                                   the neighbours (d_cmax, count, sum of indices) */
layout(location = 12) uniform uint material_count;
layout(location = 13) uniform float max_value;  /* largest value of the output format (65504 for RGBA16F) */
layout(location = 14) uniform uint list_limit;  /* caches a tile's list may hold, <= LIST_CAP (0: every tile per pixel) */
layout(location = 15) uniform uint block;       /* B: each invocation a B x B block of pixels, 1 or 2 */
layout(location = 16) uniform uint slabs;       /* 0: a tile's list in slabs where its box is long (SLAB_LENGTH), else
                                                   in rings; tests: 1 slabs, 2 rings in every tile */

/* flags 8 (gim_frame_visibility.neighbour_rays): each search's neighbours that its receiver
   cannot see dropped (gim_neighbour_rays_twin), by a ray through the scene's hierarchy from
   ray_lift above the receiver to ray_lift above the cache. A walk takes 83 loop iterations on
   average in Sponza's hierarchy, 838 at most measured: an invocation's up to 4 searches of 16
   walks stay under llvmpipe's 65535 iterations an invocation but for walks far past that */
layout(std430, binding = 6) readonly buffer Bvh { vec4 bvh[]; };
layout(location = 17) uniform uint bvh_nodes;
layout(location = 18) uniform uint bvh_triangles;   /* the triangles' first vec4 */
layout(location = 19) uniform float ray_lift;       /* GIM_NEIGHBOUR_RAY_LIFT scene_scale */
layout(location = 20) uniform vec3 bvh_origin;      /* the hierarchy's frame */
layout(location = 21) uniform float bvh_scale;
#include "bvh.glsl"

uint cell_hash(ivec3 c) {   /* the runtime's gim__grid_hash */
    return (uint(c.x) * 73856093u) ^ (uint(c.y) * 19349663u) ^ (uint(c.z) * 83492791u);
}

/* a receiver's nearest caches so far: local to each search (a private array that lived across
   a barrier would be kept in memory) */
struct Near { float d[MAX_N]; uint i[MAX_N]; uint found; };

/* Keep the MAX_N nearest (distance, index) pairs, sorted (the first n are the n nearest): an
   insertion unrolled into compares and selects at constant indices, so the arrays live in
   registers (a loop that shifts at a varying index puts them in memory: local memory on GPUs,
   a scatter per lane on llvmpipe). Empty slots hold (FLT_MAX, ~0). */
bool before(float d, uint idx, float bd, uint bi) { return d < bd || (d == bd && idx < bi); }
void offer(inout Near b, float d, uint idx) {
    for (int j = MAX_N - 1; j > 0; --j) {
        bool here = before(d, idx, b.d[j], b.i[j]), above = before(d, idx, b.d[j - 1], b.i[j - 1]);
        b.d[j] = above ? b.d[j - 1] : (here ? d : b.d[j]);
        b.i[j] = above ? b.i[j - 1] : (here ? idx : b.i[j]);
    }
    bool first = before(d, idx, b.d[0], b.i[0]);
    b.d[0] = first ? d : b.d[0];
    b.i[0] = first ? idx : b.i[0];
    b.found = min(b.found + 1u, n);
}

/* b.d[i] for a varying i, by selects */
float best_at(Near b, uint i) {
    float v = FLT_MAX;
    for (int j = 0; j < MAX_N; ++j) v = uint(j) == i ? b.d[j] : v;
    return v;
}

void visit(inout Near b, ivec3 c, vec3 x, vec3 nx, float radius) {
    uint bucket = cell_hash(c) & bucket_mask;
    for (uint k = bucket_start[bucket]; k < bucket_start[bucket + 1u]; ++k) {
        if (cache_cell[k].xyz != c) continue;   /* another cell in the same bucket */
        vec3 p = cache[k].position_area.xyz;
        if (dot(nx, cache[k].normal_reflectance.xyz) < cos_theta) continue;
        float d = length(x - p);
        if (d <= radius) offer(b, d, k);
    }
}

/* One proxy light set interpolated at x (eq. 8-9, gim__interp_light): the mean, with eq. 8's
   weights, of what each neighbour's proxy light delivers at x when it moves along with the
   surface point (seen at x + its offset from its cache); for the glossy set each term carries
   the receiver's lobe in that proxy's direction (k, view). */
vec3 interp_light(Near b, bool is_glossy, vec3 x, vec3 nx, vec3 view, float k, float dcmax) {
    float sw[2] = float[2](0.0, 0.0);
    vec3 se[2] = vec3[2](vec3(0.0), vec3(0.0));
    for (int j = 0; j < MAX_N; ++j) {   /* constant indices into b.i (see offer) */
        if (uint(j) >= b.found) break;
        uint i = b.i[j];
        vec3 c = cache[i].position_area.xyz, nc = cache[i].normal_reflectance.xyz;
        /* the two fields used, not the whole Proxy (its sigma is not read here) */
        vec3 op = (is_glossy ? glossy[i].position_radius.xyz : diffuse[i].position_radius.xyz) - c;   /* the proxy's offset */
        vec4 fv = is_glossy ? glossy[i].flux_visibility : diffuse[i].flux_visibility;
        float dp2 = dot(op, op);
        float dist = length(x - c);
        float tent = dcmax > near_ ? max(1.0 - dist / dcmax, 0.0) : 1.0;   /* eq. 8 distance term */
        float lp = sqrt(dp2), nterm, f = 1.0;
        vec3 w = lp > 0.0 ? op / lp : vec3(0.0);
        float cos_x = dot(nx, w);
        if (is_glossy && lp > 0.0) {   /* r_x . r_c: the direction to the proxy mirrored at n_x and n_c */
            vec3 rx = 2.0 * cos_x * nx - w;
            nterm = dot(rx, 2.0 * dot(nc, w) * nc - w);
            float re = dot(rx, view);
            f = (k + 2.0) / (2.0 * PI) * (k == 0.0 ? 1.0 : (re > 0.0 ? pow(re, k) : 0.0));
        } else {
            nterm = dot(nx, nc);
        }
        nterm = nterm > 0.0 ? sqrt(nterm) : 0.0;
        /* E_j at x, the proxy never nearer than 1e-6 scene scales; the division first keeps
           flux / distance^2 (an irradiance) in range at any scale */
        vec3 ej = cos_x > 0.0 ? fv.xyz / (4.0 * PI * max(dp2, near_ * near_)) * (fv.w * cos_x * f)
                              : vec3(0.0);
        for (int pass = 0; pass < 2; ++pass) {
            float wt = pass == 0 ? tent * nterm : nterm;
            if (!(wt > 0.0)) continue;
            sw[pass] += wt;
            se[pass] += wt * ej;
        }
    }
    int use = sw[0] > 0.0 ? 0 : 1;
    return sw[use] > 0.0 ? se[use] / sw[use] : vec3(0.0);
}

shared vec4 list_p[LIST_CAP];   /* a tile's caches: position, w = cache index (bits) */
shared vec4 list_n[LIST_CAP];   /* normal, w = distance from the receivers' box */
shared uint list_count;
shared uint list_order[LIST_CAP];        /* the list by ring, nearest ring first (or by slab) */
shared uint ring_start[SLABS + 1u], ring_fill[SLABS];   /* the rings' (or slabs') starts in list_order */
shared int slab_axis;           /* -1: rings; else the axis of the slabs */
shared float slab_lo, slab_w;   /* the slabs' first edge and width along it */
shared vec4 part_lo[TILE];      /* each block's receivers: box lo, w = their count */
shared vec4 part_hi[TILE];      /* box hi, w = the least cosine of a normal to the cone's axis */
shared vec3 part_n[TILE];       /* sum of normals */
shared vec4 box_lo, box_hi;     /* the receivers' box; lo.w: cos of the cone's bound, hi.w: the radius grown */
shared vec3 cone_axis;
shared ivec3 cell_lo, cell_n;   /* the cells over the box */
shared int mode;                /* 0: no receiver in the tile; 1: the tile's list; 2: per pixel */
shared uint fallback[FALLBACK_CAP];   /* pixels (x | y << 16) that search for themselves */
shared uint fallback_count;

/* The per pixel search: shell r holds the cells at Chebyshev distance r from the pixel's;
   every cache outside shells 0..r is farther than r h. */
void search_pixel(inout Near b, vec3 x, vec3 nx, float radius) {
    float h = grid.w;
    ivec3 pc = ivec3(floor((x - grid.xyz) / h));
    for (int r = 0; r <= rings; ++r) {
        ivec3 lo = max(pc - r, ivec3(0)), hi = min(pc + r, dims - 1);
        for (int cz = lo.z; cz <= hi.z; ++cz)
            for (int cy = lo.y; cy <= hi.y; ++cy) {
                bool face = abs(cz - pc.z) == r || abs(cy - pc.y) == r;
                if (face) {
                    for (int cx = lo.x; cx <= hi.x; ++cx) visit(b, ivec3(cx, cy, cz), x, nx, radius);
                } else {   /* inside the shell's faces in y and z: only its two x ends */
                    if (pc.x - r >= 0 && pc.x - r < dims.x) visit(b, ivec3(pc.x - r, cy, cz), x, nx, radius);
                    if (r > 0 && pc.x + r >= 0 && pc.x + r < dims.x) visit(b, ivec3(pc.x + r, cy, cz), x, nx, radius);
                }
            }
        if (b.found == n && best_at(b, n - 1u) <= float(r) * h) break;
    }
}

/* The tile's box, cone and cells (invocation 0), from each block's part (part_*). The box
   and the cone are grown a little beyond float rounding: the list may hold a few caches no
   pixel takes, never miss one a pixel's own search would. */
void plan_tile(float radius) {
    vec3 lo = vec3(FLT_MAX), hi = vec3(-FLT_MAX), axis = vec3(0.0);
    float count = 0.0;
    for (uint i = 0u; i < TILE; ++i) {
        if (part_lo[i].w == 0.0) continue;
        lo = min(lo, part_lo[i].xyz);
        hi = max(hi, part_hi[i].xyz);
        axis += part_n[i];
        count += part_lo[i].w;
    }
    list_count = 0u;
    fallback_count = 0u;
    for (uint r = 0u; r < SLABS; ++r) ring_fill[r] = 0u;
    box_lo = vec4(lo, -2.0);
    box_hi = vec4(hi, radius * 1.001 + 1e-5 * max(max(abs(lo.x), abs(lo.y)), max(max(abs(lo.z), abs(hi.x)), max(abs(hi.y), abs(hi.z)))));
    float la = length(axis);
    cone_axis = la > 1e-3 * count && cos_theta > -1.0 ? axis / la : vec3(0.0);
    mode = count == 0.0 ? 0 : 1;
}

/* The cone (the widest angle between its axis and a receiver's normal: a cache within theta
   of some normal lies within theta + that angle of the axis) and the cells over the box. */
void plan_cells() {
    vec3 lo = box_lo.xyz, hi = box_hi.xyz;
    float grow = box_hi.w;
    if (cone_axis != vec3(0.0)) {
        float spread = 1.0;
        for (uint i = 0u; i < TILE; ++i)
            if (part_lo[i].w != 0.0) spread = min(spread, part_hi[i].w);
        float angle = acos(clamp(cos_theta, -1.0, 1.0)) + acos(clamp(spread, -1.0, 1.0)) + 2e-3;
        if (angle < PI) box_lo.w = cos(angle);
    }
    /* clamped as floats first: a receiver far off the grid would overflow an int */
    ivec3 clo = ivec3(clamp(floor((lo - grow - grid.xyz) / grid.w), vec3(0.0), vec3(dims)));
    ivec3 chi = ivec3(clamp(floor((hi + grow - grid.xyz) / grid.w), vec3(-1.0), vec3(dims - 1)));
    ivec3 cn = max(chi - clo + 1, ivec3(0));
    cell_lo = clo;
    cell_n = cn;
    /* a box much longer than the search is wide (a tile that reaches far into the scene):
       every pixel's nearest lie in a few slabs across its long axis, where the rings of
       distance from the box would send each search over most of the list */
    vec3 ext = hi - lo;
    int k = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    slab_axis = slabs == 1u || (slabs == 0u && ext[k] > SLAB_LENGTH * grow) ? k : -1;
    slab_lo = lo[k] - grow;
    slab_w = (ext[k] + 2.0 * grow) / float(SLABS);
    /* the extent first: a box past CELL_CAP cells on one axis would overflow the product */
    mode = list_limit > 0u && all(lessThanEqual(cn, ivec3(CELL_CAP))) && cn.x * cn.y * cn.z <= CELL_CAP ? 1 : 2;
}

/* Every cache of cell c that a receiver of the tile could take, into the list. */
void gather_cell(ivec3 c) {
    vec3 lo = box_lo.xyz, hi = box_hi.xyz;
    float grow = box_hi.w;
    /* a cell whose box (grown by a thousandth of a cell) lies farther than that from the
       receivers' box holds none */
    vec3 clo = grid.xyz + vec3(c) * grid.w - 1e-3 * grid.w, chi = clo + 1.002 * grid.w;
    if (length(max(max(clo - hi, lo - chi), vec3(0.0))) > grow) return;
    uint b = cell_hash(c) & bucket_mask;
    for (uint k = bucket_start[b]; k < bucket_start[b + 1u]; ++k) {
        if (cache_cell[k].xyz != c) continue;
        vec3 p = cache[k].position_area.xyz, nc = cache[k].normal_reflectance.xyz;
        float db = length(max(max(p - hi, lo - p), vec3(0.0)));
        if (db > grow) continue;
        if (dot(cone_axis, nc) < box_lo.w) continue;
        uint slot = atomicAdd(list_count, 1u);
        if (slot < list_limit) {
            list_p[slot] = vec4(p, uintBitsToFloat(k));
            list_n[slot] = vec4(nc, db);
        }
    }
}

/* The receiver at pixel px: its position and unit normal, false where nothing is drawn. */
bool receiver_at(ivec2 px, out vec3 x, out vec3 nx) {
    x = vec3(0.0);
    nx = vec3(0.0);
    if (px.x >= int(size.x) || px.y >= int(size.y)) return false;
    float depth = texelFetch(gbuffer_depth, px, 0).r;
    vec4 nw = texelFetch(gbuffer_normal, px, 0);
    if (!(depth < 1.0 && finite3(nw.xyz) && dot(nw.xyz, nw.xyz) > 0.0)) return false;
    x = unproject(px, depth, size, inv_proj, inv_view);
    nx = normalize(nw.xyz);
    return true;
}

/* The direction from x towards the eye (perspective) or the eye's direction (orthographic). */
vec3 view_at(vec3 x) { return normalize(eye.w > 0.0 ? eye.xyz - x : eye.xyz); }

/* The glossy lobe of pixel px's material: rgb, w = Phong exponent (0 with the host's G-buffer). */
vec4 lobe_at(ivec2 px) {
    if ((flags & 2u) != 0u) return vec4(0.0);
    uint id = min(uint(max(texelFetch(gbuffer_material, px, 0).r, 0.0)), material_count - 1u);
    return material[id].glossy;
}

/* The list entries list_order[j0 .. j1) offered to b. */
void scan_list(inout Near b, uint j0, uint j1, vec3 x, vec3 nx, float radius) {
    for (uint j = j0; j < j1; ++j) {
        uint e = list_order[j];
        vec4 p = list_p[e];
        if (dot(nx, list_n[e].xyz) < cos_theta) continue;
        float d = length(x - p.xyz);
        if (d <= radius) offer(b, d, floatBitsToUint(p.w));
    }
}

/* b := the n nearest compatible caches to (x, nx): from the tile's list or per pixel. */
void neighbours(out Near b, bool listed, vec3 x, vec3 nx, float radius) {
    b.found = 0u;
    for (int j = 0; j < MAX_N; ++j) { b.d[j] = FLT_MAX; b.i[j] = 0xffffffffu; }
    if (listed && slab_axis < 0) {
        float step = box_hi.w / float(RINGS);
        /* the slack of box_hi.w over the radius bounds the float rounding of both distances */
        float slack = box_hi.w - radius + 1e-3 * step;
        for (uint r = 0u; r < RINGS; ++r) {
            if (b.found == n && float(r) * step - slack > best_at(b, n - 1u)) break;
            scan_list(b, ring_start[r], ring_start[r + 1u], x, nx, radius);
        }
    } else if (listed) {
        /* the pixel's slab, then the nearer of the next slabs on either side, until the n-th
           nearest is nearer than both: a cache of a slab not yet seen lies at least the gap
           to its edge along the axis from x */
        float xk = x[slab_axis], slack = box_hi.w - radius + 1e-3 * slab_w;
        int lo = clamp(int(floor((xk - slab_lo) / slab_w)), 0, int(SLABS) - 1), hi = lo;
        scan_list(b, ring_start[lo], ring_start[lo + 1], x, nx, radius);
        for (;;) {
            float gl = lo > 0 ? xk - (slab_lo + float(lo) * slab_w) : FLT_MAX;
            float gh = hi < int(SLABS) - 1 ? slab_lo + float(hi + 1) * slab_w - xk : FLT_MAX;
            float g = min(gl, gh);
            if (g == FLT_MAX || (b.found == n && g - slack > best_at(b, n - 1u))) break;
            if (gl <= gh) { --lo; scan_list(b, ring_start[lo], ring_start[lo + 1], x, nx, radius); }
            else { ++hi; scan_list(b, ring_start[hi], ring_start[hi + 1], x, nx, radius); }
        }
    } else {
        search_pixel(b, x, nx, radius);
    }
}

/* flags 8: b's neighbours that x (normal nx) sees, in their order; all of them where it sees
   none (gim_neighbour_rays_twin) */
void visible_only(inout Near b, vec3 x, vec3 nx) {
    Near k;
    k.found = 0u;
    for (int j = 0; j < MAX_N; ++j) { k.d[j] = FLT_MAX; k.i[j] = 0xffffffffu; }
    precise vec3 o = vec3(x.x + ray_lift * nx.x, x.y + ray_lift * nx.y, x.z + ray_lift * nx.z);
    for (int j = 0; j < MAX_N; ++j) {   /* constant indices into b (see offer) */
        if (uint(j) >= b.found) break;
        vec3 c = cache[b.i[j]].position_area.xyz, nc = cache[b.i[j]].normal_reflectance.xyz;
        precise vec3 t = vec3(c.x + ray_lift * nc.x, c.y + ray_lift * nc.y, c.z + ray_lift * nc.z);
        if (!bvh_occluded(o, t)) offer(k, b.d[j], b.i[j]);
    }
    if (k.found > 0u) b = k;
}

/* The light at receiver (x, nx, view, k) from its neighbours (those it sees, with flags 8):
   diffuse irradiance in dl, the glossy lobe's in gl (0 without glossy proxies); tests (flags
   4): the neighbours themselves, (d_cmax, count, sum of indices) in dl. */
void light_at(Near b, vec3 x, vec3 nx, vec3 view, float k, out vec3 dl, out vec3 gl) {
    if ((flags & 8u) != 0u) visible_only(b, x, nx);
    float dcmax = b.found > 0u ? best_at(b, b.found - 1u) : 0.0;
    gl = vec3(0.0);
    if ((flags & 4u) != 0u) {
        uint sum = 0u;
        for (int j = 0; j < MAX_N; ++j) sum += uint(j) < b.found ? b.i[j] : 0u;
        dl = vec3(dcmax, float(b.found), float(sum));
        return;
    }
    dl = interp_light(b, false, x, nx, view, k, dcmax);
    if ((flags & 1u) != 0u) gl = interp_light(b, true, x, nx, view, k, dcmax);
}

/* Pixel px's radiance from the light at its receiver (or its block's): its albedo and glossy
   colour (1 and 0 with the host's G-buffer); clamped to the format (GL leaves a float beyond
   RGBA16F's range to the implementation: llvmpipe stores 65504, others Inf). */
void shade(ivec2 px, vec3 gcol, vec3 dl, vec3 gl) {
    if ((flags & 4u) != 0u) { imageStore(indirect, px, vec4(dl, 1.0)); return; }
    vec3 albedo = (flags & 2u) == 0u ? texelFetch(gbuffer_albedo, px, 0).rgb : vec3(1.0);
    vec3 outc = albedo / PI * dl + gcol * gl;
    imageStore(indirect, px, vec4(min(outc, vec3(max_value)), 1.0));
}

/* A pixel of a block takes the light found at the block's first receiver r when it lies on
   the same surface near it: normals within ~5.7 degrees, the offset within ~2.9 degrees of
   r's plane and under a quarter of a grid cell, the same Phong exponent (gim_shade_sources). */
bool shares(vec3 x, vec3 nx, float k, vec3 xr, vec3 nr, float kr) {
    vec3 d = x - xr;
    float dl = length(d);
    return dot(nx, nr) >= 0.995 && abs(dot(nr, d)) <= 0.05 * dl && dl <= 0.25 * grid.w && k == kr;
}

/* List entry j's ring (of width step from the receivers' box) or slab. */
uint bucket_of(uint j, float step) {
    if (slab_axis < 0) return min(uint(list_n[j].w / step), RINGS - 1u);
    return uint(clamp(int(floor((list_p[j][slab_axis] - slab_lo) / slab_w)), 0, int(SLABS) - 1));
}

void main() {
    uint lid = gl_LocalInvocationIndex;
    int B = int(block);
    ivec2 base = ivec2(gl_WorkGroupID.xy * 8u + gl_LocalInvocationID.xy) * B;
    /* the block's receivers, at constant indices (q < B^2) */
    vec3 bx[4], bn[4];
    vec4 bg[4];   /* glossy lobes */
    bool br[4];
    vec3 lo = vec3(FLT_MAX), hi = vec3(-FLT_MAX), ns = vec3(0.0);
    float count = 0.0;
    for (int q = 0; q < 4; ++q) {
        br[q] = q < B * B && receiver_at(base + ivec2(q % B, q / B), bx[q], bn[q]);
        bg[q] = vec4(0.0);
        if (!br[q]) continue;
        bg[q] = lobe_at(base + ivec2(q % B, q / B));
        lo = min(lo, bx[q]);
        hi = max(hi, bx[q]);
        ns += bn[q];
        count += 1.0;
    }
    part_lo[lid] = vec4(lo, count);
    part_hi[lid] = vec4(hi, 1.0);
    part_n[lid] = ns;
    float radius = float(rings) * grid.w;
    barrier();
    if (lid == 0u) plan_tile(radius);
    barrier();
    if (mode == 0) {   /* nothing drawn in the tile */
        for (int q = 0; q < 4; ++q) {
            ivec2 px = base + ivec2(q % B, q / B);
            if (q < B * B && px.x < int(size.x) && px.y < int(size.y)) imageStore(indirect, px, vec4(0.0));
        }
        return;
    }
    float spread = 1.0;
    for (int q = 0; q < 4; ++q)
        if (br[q]) spread = min(spread, dot(cone_axis, bn[q]));
    part_hi[lid].w = spread;
    barrier();
    if (lid == 0u) plan_cells();
    barrier();
    if (mode == 1) {   /* the tile's list: the box's cells, one invocation each */
        uint cells = uint(cell_n.x * cell_n.y * cell_n.z);
        for (uint t = lid; t < cells; t += TILE) {
            uint cx = t % uint(cell_n.x), cyz = t / uint(cell_n.x);
            gather_cell(cell_lo + ivec3(int(cx), int(cyz % uint(cell_n.y)), int(cyz / uint(cell_n.y))));
        }
    }
    barrier();
    /* the list sorted into rings of distance from the receivers' box (a counting sort): a
       cache of ring r lies at least r grow / RINGS from every receiver of the tile, so a pixel
       stops at the first ring beyond its n-th nearest */
    bool listed = mode == 1 && list_count <= list_limit;
    float step = box_hi.w / float(RINGS);
    if (listed)
        for (uint j = lid; j < list_count; j += TILE) atomicAdd(ring_fill[bucket_of(j, step)], 1u);
    barrier();
    if (listed && lid == 0u) {
        ring_start[0] = 0u;
        for (uint r = 0u; r < (slab_axis < 0 ? RINGS : SLABS); ++r) {
            ring_start[r + 1u] = ring_start[r] + ring_fill[r];
            ring_fill[r] = ring_start[r];
        }
    }
    barrier();
    if (listed)
        for (uint j = lid; j < list_count; j += TILE)
            list_order[atomicAdd(ring_fill[bucket_of(j, step)], 1u)] = j;
    barrier();

    /* 1. the light at the block's first receiver r (eq. 8-9 over its n nearest caches) */
    vec3 xr = vec3(0.0), nr = vec3(0.0);
    float kr = 0.0;
    bool any = false;
    int r = 0;
    for (int q = 3; q >= 0; --q)
        if (br[q]) { xr = bx[q]; nr = bn[q]; kr = bg[q].w; r = q; any = true; }
    vec3 dl = vec3(0.0), gl = vec3(0.0);
    if (any) {
        Near b;
        neighbours(b, listed, xr, nr, radius);
        light_at(b, xr, nr, view_at(xr), kr, dl, gl);
    }
    /* 2. the block's pixels: r's light where they share it, else each its own later */
    for (int q = 0; q < 4; ++q) {   /* constant indices into bx, bn, bg, br (see offer) */
        ivec2 px = base + ivec2(q % B, q / B);
        if (q >= B * B || px.x >= int(size.x) || px.y >= int(size.y)) continue;
        if (!br[q]) { imageStore(indirect, px, vec4(0.0)); continue; }
        if (q == r || shares(bx[q], bn[q], bg[q].w, xr, nr, kr)) shade(px, bg[q].rgb, dl, gl);
        else fallback[atomicAdd(fallback_count, 1u)] = uint(px.x) | (uint(px.y) << 16);
    }
    barrier();
    /* 3. the pixels that did not share, spread over the work group */
    for (uint e = lid; e < fallback_count; e += TILE) {
        ivec2 px = ivec2(int(fallback[e] & 0xffffu), int(fallback[e] >> 16));
        vec3 x, nx;
        receiver_at(px, x, nx);
        vec4 g = lobe_at(px);
        vec3 d2, g2;
        Near b;
        neighbours(b, listed, x, nx, radius);
        light_at(b, x, nx, view_at(x), g.w, d2, g2);
        shade(px, g.rgb, d2, g2);
    }
}
