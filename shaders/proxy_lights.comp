/* LightSkin proxy lights (Bischoff 2017 eq. 3-7, eq. 13-15), the GPU twin of gim_proxy_lights_twin:
   one invocation per cache and lane looping over the lane's VALs in a fixed order, the VAL
   list passed through shared memory in tiles of TILE (one VAL loaded per invocation). The
   VALs' tiles (VALs [T TILE, (T + 1) TILE)) are dealt to `lanes` lanes, tile T to lane T mod
   lanes (gl_WorkGroupID.y), each lane with sums of its own, and the last dispatch (mode 2)
   merges a cache's lanes (Chan et al.'s pairwise form of the weighted mean and sum of squares)
   and writes its proxy lights. Lanes exist for a large GPU: one invocation per cache left an
   H100 under 2% busy on Sponza's 24,863 caches; the host picks them so the pass has about 2^17
   invocations (gim__proxy_lanes), 1 where the caches alone give that many. The lane is the
   work group's, so every invocation reads the same tile entry at a time (a broadcast). The formulas,
   guards and clamps are the twin's (see gim_proxy_lights_twin in gimany.h); the sums are in float
   here (double in the twin). Visibility per VAL from the cache's imperfect shadow map or, with
   rays, a walk of the scene's hierarchy (bvh.glsl). A VAL that is not finite or has a negative area, weight or flux
   adds nothing (the twin rejects it; the GPU gather zeroes it), and every output is finite. */
#include "common.glsl"
#include "near_field.glsl"
#define TILE 64
layout(local_size_x = TILE) in;

struct Cache { vec4 position_area; vec4 normal_reflectance; };          /* gim_cache */
struct Val { vec4 position_area; vec4 normal_weight; vec4 flux; };      /* gim_val */
struct Proxy { vec4 position_radius; vec4 flux_visibility; vec4 sigma; }; /* gim_proxy_light */
layout(std430, binding = 0) readonly buffer Caches { Cache cache[]; };
layout(std430, binding = 1) readonly buffer Vals { Val val[]; };
layout(std430, binding = 2) writeonly buffer Diffuse { Proxy diffuse_out[]; };
layout(std430, binding = 3) writeonly buffer Glossy { Proxy glossy_out[]; };
layout(std430, binding = 5) readonly buffer Exponents { float cache_k[]; };   /* per cache, when per_cache_k */

layout(location = 0) uniform uint cache_count;   /* this dispatch's caches: [cache_first, cache_count) */
layout(location = 16) uniform uint cache_first;  /* a range whose maps fit one storage block (the host splits them) */
layout(location = 1) uniform uint val_count;
layout(location = 2) uniform vec3 eye;
layout(location = 3) uniform float exponent;     /* Phong k of the glossy lobe (every cache's unless per_cache_k) */
layout(location = 4) uniform float coincident2;  /* (1e-6 scene_scale)^2: no direction nearer */
layout(location = 5) uniform uint with_glossy;   /* 0: diffuse only, glossy_out untouched */
layout(location = 6) uniform uint first;         /* this dispatch's VALs: [first, first + chunk) */
layout(location = 7) uniform uint chunk;
layout(location = 9) uniform uint per_cache_k;  /* 1: each cache's k from cache_k (its material's lobe) */
layout(location = 10) uniform uint lanes;        /* lanes per cache (modes 0 and 3; 1 and 2 run lane 0 alone) */
layout(location = 8) uniform uint mode;          /* 0: the sums (first == 0 starts them); 3: the
                                                    near VALs past the first NEAR_CAP; 1: the
                                                    form-factor positions of dark caches; 2: write
                                                    the proxy lights */
/* The sums of every lane of every cache of this range between dispatches, 6 vec4 each (lane l
   of cache i from vec4 ((i - cache_first) lanes + l) 6 on: the ranges run one after another
   and share the buffer, which the host sizes to one storage block): (s, w), (mean, E_n),
   (m2, aux) of the diffuse sums, (s, w), (mean, shift), (m2, near VALs seen) of the glossy ones.
   The VALs are taken in chunks, each its own dispatch: a driver may bound the loop iterations
   of one invocation (Mesa's llvmpipe stops every loop of an invocation after 65535 iterations
   in all) or the length of one dispatch (a desktop's GPU watchdog), and FULL LightSkin has
   ~10^6 VALs. */
layout(std430, binding = 4) buffer State { vec4 state[]; };

/* Visibility per VAL through each cache's imperfect shadow map (gim_ism_visibility_twin's lookup,
   its float arithmetic in its order); ism_size 0: every VAL seen. Texels in 16 bits, two to a
   uint (ism.comp): texel 2k in the low half; a texel's float is its bits shifted up. */
layout(std430, binding = 7) readonly buffer IsmMaps { uint ism[]; };   /* bound from cache cache_first's map on */
layout(location = 12) uniform uint ism_size;
layout(location = 13) uniform float ism_bias;
layout(location = 14) uniform float ism_texel;   /* slope 2 / size */
layout(location = 15) uniform float ism_lift;
float ism_visibility(uint i, vec3 o, vec3 t, vec3 b, vec3 n, vec3 x, vec3 nl) {
    vec3 d = vec3(x.x - o.x, x.y - o.y, x.z - o.z);
    float dist = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(dist > 0.0)) return 1.0;
    float wz = (d.x * n.x + d.y * n.y + d.z * n.z) / dist;
    if (!(wz > 0.0)) return 1.0;
    float wx = (d.x * t.x + d.y * t.y + d.z * t.z) / dist;
    float wy = (d.x * b.x + d.y * b.y + d.z * b.z) / dist;
    float fs = float(ism_size);
    float fx = floor((wx / (1.0 + wz) + 1.0) * 0.5 * fs);
    float fy = floor((wy / (1.0 + wz) + 1.0) * 0.5 * fs);
    int ix = fx < 0.0 ? 0 : fx > float(ism_size - 1u) ? int(ism_size) - 1 : int(fx);
    int iy = fy < 0.0 ? 0 : fy > float(ism_size - 1u) ? int(ism_size) - 1 : int(fy);
    int tx = iy * int(ism_size) + ix;
    uint zi = (i - cache_first) * ism_size * ism_size + uint(tx);
    float z = ism_unpack(ism[zi >> 1u], zi);
    float dref = dist;
    vec3 dir = ism_texel_ray(tx, ism_size, t, b, n);
    float den = dir.x * nl.x + dir.y * nl.y + dir.z * nl.z;
    if (den >= 1e-3 || den <= -1e-3) {   /* the VAL's plane along the texel's ray */
        float s = (d.x * nl.x + d.y * nl.y + d.z * nl.z) / den;
        if (s > 0.0 && s < 2.0 * dist) dref = s;
    }
    float cl = -(nl.x * d.x + nl.y * d.y + nl.z * d.z) / dist;
    cl = cl < 0.0 ? -cl : cl;
    float sn = sqrt(1.0 - (cl < 1.0 ? cl * cl : 1.0));
    float tn = cl * ISM_MAX_TAN > sn ? sn / cl : ISM_MAX_TAN;
    return z < ISM_EMPTY && dref > z + dist * (ism_bias + ism_texel * tn) ? 0.0 : 1.0;
}

/* GIM_VISIBILITY_RAYS (rays 1, instead of the maps): a VAL is seen where no triangle crosses
   the segment from ray_lift above the cache to ray_lift above the VAL (gim_val_rays_twin) */
layout(std430, binding = 6) readonly buffer Bvh { vec4 bvh[]; };
layout(location = 17) uniform uint bvh_nodes;
layout(location = 18) uniform uint bvh_triangles;   /* the triangles' first vec4 */
layout(location = 19) uniform uint rays;
layout(location = 20) uniform float ray_lift;       /* GIM_NEIGHBOUR_RAY_LIFT scene_scale */
layout(location = 21) uniform vec3 bvh_origin;      /* the hierarchy's frame */
layout(location = 22) uniform float bvh_scale;
#include "bvh.glsl"

shared vec4 tile_pa[TILE];    /* position, area */
shared vec4 tile_nw[TILE];    /* normal, weight (0: skipped) */
shared vec3 tile_flux[TILE];
shared uint any_work;   /* an invocation of the group has work in mode 1 or 3 */

/* A VAL at p with normal nl seen from the cache at c with normal n: d = p - c, d2 = |d|^2,
   inv = 1 / |d| (0 nearer than coincident2: no direction, no light), and the cosines at the
   cache and at the VAL (gim_proxy_lights_twin's float steps) */
void val_geometry(vec3 p, vec3 nl, vec3 c, vec3 n, out vec3 d, out float d2, out float inv, out float cos_x,
                  out float cos_l) {
    d = p - c;
    d2 = dot(d, d);
    inv = d2 > coincident2 ? 1.0 / sqrt(d2) : 0.0;
    cos_x = max(dot(n, d) * inv, 0.0);
    cos_l = max(-dot(nl, d) * inv, 0.0);
}

/* eq. 3/14's irradiance term per unit flux of a VAL of area a and weight w */
float val_e_n(float a, float w, float cos_l, float d2) {
    float den = a + PI * d2;
    return den > 0.0 ? w * cos_l / den : 0.0;
}

/* Near field of a VAL (gim__val_near, the same float steps): within d < 2 sqrt(A) the VAL is
   a regular octagon of area A in its plane, clipped to the receiver's hemisphere, with vector
   form factor Phi by Lambert's contour formula (near_patch in near_field.glsl). Returns the E_n
   term e_n blended towards w |Phi| / A, sets cos_x = F / |Phi| and turns d to unit(Phi) (its
   length kept); faded to the far field between d = 1.5 and 2 sqrt(A). */
const uint NEAR_CAP = 16u;   /* GIM__VAL_NEAR_CAP: near VALs per cache listed in mode 0; mode 3 takes the rest */
float val_near(inout vec3 d, vec3 n, vec3 nl, float area, float weight, float e_n, inout float cos_x) {
    float d2 = dot(d, d), f, fv;
    vec3 phi;
    float w = near_patch(d, d2, n, nl, area, phi, f, fv);
    if (!(w > 0.0)) return e_n;   /* the far field */
    float dl = sqrt(d2);
    vec3 u = d / dl + w * (phi / fv - d / dl);
    float ul = length(u);
    if (ul > 0.0 && ul <= 3.402823466e+38) d = u * (dl / ul);
    cos_x += w * (f / fv - cos_x);
    return e_n + w * (weight * (fv / (2.0 * PI) / area) - e_n);   /* E_n = w |Phi| / A */
}

const vec3 LUM = vec3(0.2126, 0.7152, 0.0722);

/* S, sum W, and the W-weighted mean and sum of squared deviations of d = x_l - c, updated
   per VAL (West's weighted form of Welford's update): float sums of W d and W d^2 would lose
   sigma to cancellation where the VALs' spread is small against their distance to c (the
   twin's double m2 / w - o^2 has the headroom) */
struct Sums { vec3 s; float w; vec3 mean; vec3 m2; };

bool finite4(vec4 v) {   /* exponent bits, not isinf/isnan, which fast-math may fold away */
    uvec4 e = (floatBitsToUint(v) >> 23) & 0xffu;
    return all(notEqual(e, uvec4(0xffu)));
}

/* log2 of the Phong lobe ((r . v)+)^k (k = 0: the constant lobe 1), or NO_LOBE where the twin's
   float powf gives 0 (below the smallest float denormal 2^-149). The glossy sums are kept
   scaled by 2^-shift, shift the largest log2 lobe seen so far: at k = 1000 a cache whose
   lobe sees its light at r . v ~ 0.9 has every lobe value near 1e-46, which a GPU's float
   flushes to 0 (it keeps no denormals), while the twin's double sums keep them, and eq. 7
   with its guard gives such a cache a flux of the order of the diffuse one (a light of
   normal irradiance E_n that the receiver's lobe will dim again) */
const float NO_LOBE = -1e30;
float log2_lobe(float c, float k) {
    if (k == 0.0) return 0.0;
    float l = c > 0.0 ? k * log2(min(c, 1.0)) : NO_LOBE;   /* r . v held to 1, as the twin's gim__lobe */
    return l >= -149.0 ? l : NO_LOBE;
}

/* The position sums of a joined by a set of weight w, mean d and squared deviations m2 (one VAL:
   m2 = 0; a lane's sums in mode 2: Chan et al. 1979's pairwise form, of which West's update is
   the one-VAL case) */
void merge_position(inout Sums a, vec3 d, float w, vec3 m2) {
    float w1 = a.w + w;
    if (w1 > 0.0) {
        vec3 delta = d - a.mean;
        /* m2 grows by w a.w / w1 delta^2 (West 1979), not by w delta (d - mean'): (d - mean') is
           delta (1 - w / w1), and a GPU's w / w1 (NVIDIA: w times an approximate reciprocal)
           may miss 1 by an ulp, so a cache lit by one VAL got sigma = sqrt(ulp) |d|, 3e-4 of its
           offset (H100); this way the first VAL adds exactly 0 */
        a.mean = a.w > 0.0 ? a.mean + delta * (w / w1) : d;
        a.m2 += m2 + (w * (a.w / w1)) * delta * delta;
    }
    a.w = w1;
}

void add_position(inout Sums a, vec3 d, float w) { merge_position(a, d, w, vec3(0.0)); }

void add(inout Sums a, vec3 d, float w, vec3 phi, float e) {
    a.s += phi * e;
    add_position(a, d, w);
}

/* Rescale glossy sums from 2^-shift to 2^-to (to > shift); the mean is scale-free. */
void rescale(inout Sums a, inout float shift, float to) {
    float r = exp2(max(shift - to, -200.0));
    a.s *= r;
    a.w *= r;
    a.m2 *= r;
    shift = to;
}

/* a += b: the sums of two disjoint sets of VALs */
void merge(inout Sums a, Sums b) {
    a.s += b.s;
    merge_position(a, b.mean, b.w, b.m2);
}

/* eq. 5/13 position, sigma, eq. 7 flux with the guard (normal irradiance <= E_n); the sums
   (not E_n) scaled by 2^-shift */
Proxy finish(Sums a, float en, vec3 c, vec3 n, vec3 v, bool glossy_lobe, float shift, float k) {
    Proxy p;
    bool ok = a.w > 0.0 && finite4(vec4(a.mean, a.w)) && finite4(vec4(a.m2, 0.0)) && finite4(vec4(a.s, en));
    vec3 o = ok ? a.mean : vec3(0.0);
    vec3 var = ok ? a.m2 / a.w : vec3(0.0);
    vec3 sigma = min(sqrt(max(var, vec3(0.0))), vec3(FLT_MAX));
    if (!finite4(vec4(o, 0.0))) { o = vec3(0.0); sigma = vec3(0.0); ok = false; }
    float d2 = dot(o, o);
    float lum_s = dot(LUM, a.s);
    vec3 flux = vec3(0.0);
    if (ok && lum_s > 0.0 && en > 0.0 && d2 > 0.0) {
        float dp = sqrt(d2);
        vec3 w = o / dp;
        float cos_p = dot(n, w);
        float dproxy = max(cos_p, 0.0);
        if (glossy_lobe && dproxy > 0.0) {
            float l = log2_lobe(dot(2.0 * cos_p * n - w, v), k);
            dproxy = l == NO_LOBE ? 0.0 : dproxy * exp2(min(l - shift, 126.0));   /* scaled as S */
        }
        dproxy = max(dproxy, lum_s / en);                       /* the guard */
        flux = min(4.0 * PI * d2 * a.s / dproxy, vec3(FLT_MAX)); /* eq. 7 */
        if (!finite4(vec4(flux, 0.0))) flux = vec3(0.0);
    }
    p.position_radius = vec4(c + o, min(2.0 * max(sigma.x, max(sigma.y, sigma.z)), FLT_MAX));
    p.flux_visibility = vec4(flux, 1.0);
    p.sigma = vec4(sigma, 0.0);
    return p;
}

/* load VAL j (of the dispatch's [first, end)) into the tile slot; a broken VAL, or none, gets
   weight 0 and adds nothing */
void load(uint j, uint end, uint slot) {
    vec4 pa = vec4(0.0), nw = vec4(0.0);
    vec3 f = vec3(0.0);
    if (j < val_count && j >= first && j < end) {
        pa = val[j].position_area;
        nw = val[j].normal_weight;
        f = val[j].flux.rgb;
        if (!finite4(pa) || !finite4(nw) || !finite4(vec4(f, 0.0)) || !(pa.w >= 0.0) || !(nw.w >= 0.0) ||
            !all(greaterThanEqual(f, vec3(0.0)))) {
            pa = vec4(0.0); nw = vec4(0.0); f = vec3(0.0);
        }
    }
    tile_pa[slot] = pa;
    tile_nw[slot] = nw;
    tile_flux[slot] = f;
}

/* VAL (position p, normal nl, flux phi) at offset d from the cache, its eq. 3/14 term e_n and
   cosine cos_x: visibility, then the diffuse and glossy sums */
void accumulate(inout Sums sd, inout Sums sg, inout float en, inout float shift, vec3 d, float inv, float cos_x, float e_n,
                vec3 p, vec3 nl, vec3 phi, uint ii, vec3 ism_o, vec3 ism_t, vec3 ism_b, vec3 n, bool glossy, vec3 v,
                float k, vec3 ray_o) {
    if (ism_size != 0u && e_n * cos_x > 0.0) e_n *= ism_visibility(ii, ism_o, ism_t, ism_b, n, p, nl);
    if (rays != 0u && e_n * cos_x > 0.0) {   /* ray_o: ray_lift above the cache, made once per cache */
        precise vec3 t = vec3(p.x + ray_lift * nl.x, p.y + ray_lift * nl.y, p.z + ray_lift * nl.z);
        if (bvh_occluded(ray_o, t)) e_n = 0.0;
    }
    float e = e_n * cos_x;
    if (!(e > 0.0)) return;   /* behind, grazing, coincident or weight 0 */
    float lphi = dot(LUM, phi);
    float wgt = lphi * e;       /* W_j: what the VAL adds */
    add(sd, d, wgt, phi, e);
    en += lphi * e_n;
    if (glossy && wgt > 0.0) {   /* a black VAL adds nothing, nor may it set the shift */
        float l = log2_lobe(dot(2.0 * cos_x * n - d * inv, v), k);   /* eq. 4/15 */
        if (l != NO_LOBE) {
            if (l > shift) rescale(sg, shift, l);
            float g = exp2(l - shift);
            add(sg, d, wgt * g, phi, e * g);
        }
    }
}

void main() {
    uint i = cache_first + gl_GlobalInvocationID.x;
    uint local = gl_LocalInvocationIndex;
    uint lane = gl_WorkGroupID.y;
    bool inside = i < cache_count;
    uint ii = min(i, cache_count - 1u);
    Cache cc = cache[ii];
    vec3 c = cc.position_area.xyz, n = cc.normal_reflectance.xyz;
    bool glossy = with_glossy != 0u;
    float k = glossy && per_cache_k != 0u ? cache_k[ii] : exponent;
    vec3 te = eye - c;
    float le = dot(te, te);
    vec3 v = glossy && le > 0.0 ? te / sqrt(le) : vec3(0.0);   /* eye at the cache: only k = 0 lights */
    Sums sd = Sums(vec3(0.0), 0.0, vec3(0.0), vec3(0.0));
    Sums sg = sd;
    float en = 0.0;       /* lum(E_n) = sum lum(Phi) e / cos theta_x */
    float shift = -200.0; /* the glossy sums are scaled by 2^-shift */
    float aux = 0.0;         /* mode 1-2: 1 for a dark cache; mode 3: near VALs counted so far */
    float near_seen = 0.0;   /* near-field VALs, over mode 0's chunks */
    uint near_list[NEAR_CAP];
    uint near_n = 0u;
    if (mode != 0u || first != 0u) {
        uint b = ((ii - cache_first) * lanes + lane) * 6u;
        vec4 a0 = state[b], a1 = state[b + 1u], a2 = state[b + 2u], g0 = state[b + 3u], g1 = state[b + 4u], g2 = state[b + 5u];
        sd = Sums(a0.xyz, a0.w, a1.xyz, a2.xyz);
        en = a1.w;
        aux = mode == 0u ? 0.0 : a2.w;
        sg = Sums(g0.xyz, g0.w, g1.xyz, g2.xyz);
        shift = g1.w;
        near_seen = g2.w;
    }
    /* the dispatch's VALs [first, end) in the tiles T0 <= T < T1 that touch them: this lane's
       are T = lane mod lanes (modes 0 and 3; the same tiles whatever the chunks, so mode 3
       counts the near VALs of mode 0 again); mode 1 runs lane 0 over all of them */
    uint end = first + chunk;
    uint deal = mode == 1u ? 1u : lanes;
    uint tile0 = first / uint(TILE), tile1 = (end + uint(TILE) - 1u) / uint(TILE);
    uint mine = tile0 + (lane + deal - tile0 % deal) % deal;
    vec3 ism_o = vec3(c.x + ism_lift * n.x, c.y + ism_lift * n.y, c.z + ism_lift * n.z), ism_t = vec3(0.0), ism_b = vec3(0.0);
    if (ism_size != 0u) basis(n, ism_t, ism_b);
    precise vec3 ray_o = vec3(c.x + ray_lift * n.x, c.y + ray_lift * n.y, c.z + ray_lift * n.z);
    if (mode == 0u) {
        for (uint tile = mine; tile < tile1; tile += deal) {
            uint base = tile * uint(TILE);
            load(base + local, end, local);
            barrier();
            uint count = min(uint(TILE), end - base);
            if (inside)
                for (uint t = base < first ? first - base : 0u; t < count; ++t) {
                    vec3 d;
                    float d2, inv, cos_x, cos_l;
                    val_geometry(tile_pa[t].xyz, tile_nw[t].xyz, c, n, d, d2, inv, cos_x, cos_l);
                    float e_n = val_e_n(tile_pa[t].w, tile_nw[t].w, cos_l, d2);
                    if (d2 < VAL_NEAR * VAL_NEAR * tile_pa[t].w && cos_l > 0.0 && cos_x > 0.0) {
                        if (near_seen < float(NEAR_CAP)) near_list[near_n++] = base + t;   /* the near field after the loop */
                        near_seen += 1.0;
                        continue;
                    }
                    accumulate(sd, sg, en, shift, d, inv, cos_x, e_n, tile_pa[t].xyz, tile_nw[t].xyz, tile_flux[t], ii, ism_o,
                               ism_t, ism_b, n, glossy, v, k, ray_o);
                }
            barrier();
        }
        /* the near field: the VAL as the patch it stands for (val_near), for the few VALs near
           this cache, out of the loop so the others do not pay for it */
        for (uint q = 0u; q < near_n; ++q) {
            uint j = near_list[q];
            vec4 pa = val[j].position_area, nw = val[j].normal_weight;
            vec3 d;
            float d2, inv, cos_x, cos_l;
            val_geometry(pa.xyz, nw.xyz, c, n, d, d2, inv, cos_x, cos_l);
            float e_n = val_e_n(pa.w, nw.w, cos_l, d2);
            e_n = val_near(d, n, nw.xyz, pa.w, nw.w, e_n, cos_x);
            accumulate(sd, sg, en, shift, d, inv, cos_x, e_n, pa.xyz, nw.xyz, val[j].flux.rgb, ii, ism_o, ism_t, ism_b, n,
                       glossy, v, k, ray_o);
        }
    } else if (mode == 3u) {
        /* the near VALs past the first NEAR_CAP of a cache (many VALs on one spot: BRSM's
           repeated picks, many lights on one surface), listed per tile (8-bit slots, four to
           a uint) and evaluated after the tile's loop, so the VALs far from every cache of a
           SIMD vector do not pay for the patch (llvmpipe runs both sides of a branch); only the
           work groups that hold such a cache loop. The host halves the chunk for this mode:
           the list's loop adds up to TILE iterations per tile */
        bool over = inside && near_seen > float(NEAR_CAP);
        if (local == 0u) any_work = 0u;
        barrier();
        if (over) any_work = 1u;
        barrier();
        if (any_work != 0u) {
            for (uint tile = mine; tile < tile1; tile += deal) {
                uint base = tile * uint(TILE);
                load(base + local, end, local);
                barrier();
                uint count = min(uint(TILE), end - base);
                uint late[TILE / 4];
                uint late_n = 0u;
                if (over)
                    for (uint t = base < first ? first - base : 0u; t < count; ++t) {
                        vec3 d;
                        float d2, inv, cos_x, cos_l;
                        val_geometry(tile_pa[t].xyz, tile_nw[t].xyz, c, n, d, d2, inv, cos_x, cos_l);
                        if (!(d2 < VAL_NEAR * VAL_NEAR * tile_pa[t].w && cos_l > 0.0 && cos_x > 0.0)) continue;
                        aux += 1.0;
                        if (aux <= float(NEAR_CAP)) continue;   /* listed in mode 0 */
                        uint sh = (late_n & 3u) * 8u;
                        late[late_n >> 2u] = sh == 0u ? t : late[late_n >> 2u] | (t << sh);
                        late_n += 1u;
                    }
                for (uint q = 0u; q < late_n; ++q) {
                    uint t = (late[q >> 2u] >> ((q & 3u) * 8u)) & 0xffu;
                    vec3 d;
                    float d2, inv, cos_x, cos_l;
                    val_geometry(tile_pa[t].xyz, tile_nw[t].xyz, c, n, d, d2, inv, cos_x, cos_l);
                    float e_n = val_e_n(tile_pa[t].w, tile_nw[t].w, cos_l, d2);
                    e_n = val_near(d, n, tile_nw[t].xyz, tile_pa[t].w, tile_nw[t].w, e_n, cos_x);
                    accumulate(sd, sg, en, shift, d, inv, cos_x, e_n, tile_pa[t].xyz, tile_nw[t].xyz, tile_flux[t], ii,
                               ism_o, ism_t, ism_b, n, glossy, v, k, ray_o);
                }
                barrier();
            }
        }
    } else if (mode == 1u) {
        /* a dark cache (no VAL lit it: decided at the first chunk): the form-factor weights of
           eq. 6 place the proxy; the loop runs in the work groups that hold one (barrier()
           needs the whole group) */
        if (first == 0u) {   /* dark: no lane of the cache lit (lane 0 alone runs here) */
            bool lit = sd.w > 0.0;
            for (uint l = 1u; l < lanes; ++l) lit = lit || state[((ii - cache_first) * lanes + l) * 6u].w > 0.0;
            aux = inside && !lit ? 1.0 : 0.0;
        }
        if (local == 0u) any_work = 0u;
        barrier();
        if (aux > 0.0) any_work = 1u;
        barrier();
        if (any_work != 0u) {
            for (uint tile = mine; tile < tile1; tile += deal) {
                uint base = tile * uint(TILE);
                load(base + local, end, local);
                barrier();
                uint count = min(uint(TILE), end - base);
                if (aux > 0.0)
                    for (uint t = base < first ? first - base : 0u; t < count; ++t) {
                        vec3 d;
                        float d2, inv, cos_x, cos_l;
                        val_geometry(tile_pa[t].xyz, tile_nw[t].xyz, c, n, d, d2, inv, cos_x, cos_l);
                        float den = tile_pa[t].w + PI * d2;
                        float f = den > 0.0 ? tile_nw[t].w * tile_pa[t].w * cos_l * cos_x / den : 0.0;   /* F */
                        if (!(f > 0.0)) continue;
                        add_position(sd, d, f);
                    }
                barrier();
            }
        }
    }
    if (!inside) return;
    if (mode != 2u) {
        uint b = ((i - cache_first) * lanes + lane) * 6u;
        state[b] = vec4(sd.s, sd.w);
        state[b + 1u] = vec4(sd.mean, en);
        state[b + 2u] = vec4(sd.m2, aux);
        state[b + 3u] = vec4(sg.s, sg.w);
        state[b + 4u] = vec4(sg.mean, shift);
        state[b + 5u] = vec4(sg.m2, near_seen);
        return;
    }
    /* mode 2 (lane 0): the cache's lanes merged into its own sums (loaded above), the glossy
       ones first brought to the larger shift */
    for (uint l = 1u; l < lanes; ++l) {
        uint b = ((i - cache_first) * lanes + l) * 6u;
        vec4 a0 = state[b], a1 = state[b + 1u], a2 = state[b + 2u], g0 = state[b + 3u], g1 = state[b + 4u], g2 = state[b + 5u];
        merge(sd, Sums(a0.xyz, a0.w, a1.xyz, a2.xyz));
        en += a1.w;
        Sums gl = Sums(g0.xyz, g0.w, g1.xyz, g2.xyz);
        float gshift = g1.w;
        if (gshift > shift) rescale(sg, shift, gshift);
        else if (gshift < shift) rescale(gl, gshift, shift);
        merge(sg, gl);
    }
    diffuse_out[i] = finish(sd, en, c, n, v, false, 0.0, k);
    if (glossy) {
        if (!(sg.w > 0.0)) {   /* the lobe sees no light: the diffuse proxy's place, flux 0 */
            sg.w = sd.w;
            sg.mean = sd.mean;
            sg.m2 = sd.m2;
            shift = 0.0;
        }
        glossy_out[i] = finish(sg, en, c, n, v, true, shift, k);
    }
}
