/* LightSkin proxy-light occlusion (paper 000 "Occlusion"; Lensing and Broll 2013), the GPU twin
   of gim_proxy_occlusion: one invocation per target cache i looping over every cache j in a
   fixed order, the caches passed through shared memory in tiles of TILE (one cache loaded per
   invocation). Projections onto the unit disk of cache i's tangent plane (t, b as gim_basis),
   each made an axis-aligned square of the same area: the light's sphere (F = (r / D)^2 cos),
   each blocker's disk (F = a ci |cj| / (a + pi d^2)); occlusion = the summed overlap of the
   blockers' squares with the light's, over its area, clamped to 1. Writes only .visibility.
   In float (the twin in double), so the overlap is taken in coordinates centred on the
   light's square: its edges are then exactly +-ps/2, a light far smaller than a blocker that
   covers it is covered exactly, and the fraction is a product of ratios <= 1 (no underflow of
   ps^2). A cache or light that is not finite adds nothing or keeps visibility 1 (the twin
   rejects it), so every output is finite and in [0,1]. */
#define TILE 64
layout(local_size_x = TILE) in;

struct Cache { vec4 position_area; vec4 normal_reflectance; };            /* gim_cache */
struct Proxy { vec4 position_radius; vec4 flux_visibility; vec4 sigma; }; /* gim_proxy_light */
layout(std430, binding = 0) readonly buffer Caches { Cache cache[]; };
layout(std430, binding = 1) buffer Lights { Proxy light[]; };

layout(location = 0) uniform uint cache_count;
layout(location = 1) uniform float near_;   /* 1e-6 scene_scale: no direction nearer */
layout(location = 2) uniform uint first;    /* the blockers of this dispatch: [first, first + chunk); */
layout(location = 3) uniform uint chunk;    /* first > 0 goes on from the visibility written before */

shared vec4 tile_pa[TILE];   /* position, area (area 0: skipped) */
shared vec3 tile_n[TILE];    /* normal */

const float PI = 3.14159265358979323846;

bool finite4(vec4 v) {   /* exponent bits, not isinf/isnan, which fast-math may fold away */
    uvec4 e = (floatBitsToUint(v) >> 23) & 0xffu;
    return all(notEqual(e, uvec4(0xffu)));
}

/* load cache j into the tile slot; a broken cache (not finite, negative area) gets area 0 */
void load(uint j, uint slot) {
    vec4 pa = vec4(0.0), nr = vec4(0.0);
    if (j < cache_count) {
        pa = cache[j].position_area;
        nr = cache[j].normal_reflectance;
        if (!finite4(pa) || !finite4(vec4(nr.xyz, 0.0)) || !(pa.w >= 0.0)) { pa = vec4(0.0); nr = vec4(0.0); }
    }
    tile_pa[slot] = pa;
    tile_n[slot] = nr.xyz;
}

/* Length of the overlap of [-s/2, s/2] and [c - q/2, c + q/2] over s (the light's side s > 0): in [0, 1]. */
float cover(float s, float c, float q) {
    float o = min(0.5 * s, c + 0.5 * q) - max(-0.5 * s, c - 0.5 * q);
    return o > 0.0 ? min(o / s, 1.0) : 0.0;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint local = gl_LocalInvocationIndex;
    bool inside = i < cache_count;
    uint ii = min(i, cache_count - 1u);
    vec4 ca = cache[ii].position_area;
    vec3 c = ca.xyz, n = cache[ii].normal_reflectance.xyz;
    vec4 pr = light[ii].position_radius;
    vec3 flux = light[ii].flux_visibility.xyz;
    /* does light i need the loop at all? (the twin's special cases keep visibility 1; so does
       a broken cache or light, which the twin rejects) */
    bool occludable = inside && finite4(ca) && ca.w >= 0.0 && finite4(vec4(n, 0.0)) && finite4(pr) &&
                      finite4(vec4(flux, 0.0)) && pr.w >= 0.0 && any(greaterThan(flux, vec3(0.0)));
    vec3 o = pr.xyz - c;
    float dist = occludable ? length(o) : 0.0;
    float r = pr.w;
    occludable = occludable && dist > near_ && dist > r;   /* D <= r: the light surrounds the cache */
    o = occludable ? o / dist : vec3(0.0);
    float cos_p = dot(n, o);
    occludable = occludable && cos_p > 0.0;                /* below the horizon */
    /* gim_basis (Duff et al. 2017), the same formula */
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float bb = n.x * n.y * a;
    vec3 t = vec3(1.0 + s * n.x * n.x * a, s * bb, -s * n.x);
    vec3 b = vec3(bb, s + n.y * n.y * a, -n.y);
    /* sphere form factor (r / D)^2 cos_p as an equal-area square of side ps = sqrt(pi F) */
    float ps = sqrt(PI * cos_p) * (r / dist);
    float far_ = dist - r;                              /* blockers strictly nearer than this */
    float occ = first > 0u && occludable ? 1.0 - light[ii].flux_visibility.w : 0.0;
    uint end = first + chunk;
    for (uint base = first; base < end; base += uint(TILE)) {
        load(base + local, local);
        barrier();
        uint count = min(uint(TILE), end - base);
        if (occludable)
            for (uint k = 0u; k < count && occ < 1.0; ++k) {
                if (base + k == i) continue;
                vec3 u = tile_pa[k].xyz - c;
                float d = length(u);
                if (!(d > near_) || !(d < far_)) continue;    /* strictly between */
                u /= d;
                float ci = dot(n, u);
                if (!(ci > 0.0)) continue;
                float cj = abs(dot(tile_n[k], u));
                float area = tile_pa[k].w;
                float fq = area * ci * cj / (area + PI * d * d);   /* disk form factor (eq. 3) */
                if (!(fq > 0.0)) continue;
                float qs = sqrt(PI * fq);
                vec3 w = u - o;                                 /* blocker centre - light centre */
                float dx = dot(t, w), dy = dot(b, w);
                if (ps > 0.0) occ += cover(ps, dx, qs) * cover(ps, dy, qs);
                else if (abs(dx) <= 0.5 * qs && abs(dy) <= 0.5 * qs) occ = 1.0;   /* point light */
            }
        barrier();
    }
    if (!inside) return;
    light[i].flux_visibility.w = occ < 1.0 ? 1.0 - occ : 0.0;
}
