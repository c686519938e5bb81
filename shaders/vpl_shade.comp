/* VPL shading per pixel (Dong sec. 6, SSVP eq. 6; units in gimany.h "twins of the VPL
   methods"), the GPU twin of gim_vpl_shade_twin: one invocation per G-buffer pixel sums the VPLs
   of its interleaved subset (members j = s, s + k^2, ...; s = x mod k + k (y mod k); member j
   is VPL scramble(j), a bijection that spreads each subset over the list) in member order,
   each with its cluster's soft visibility from the paraboloid maps (gim_paraboloid_visibility_twin,
   the same float steps; `precise` keeps the compiler from fusing them into multiply-adds),
   clamped at d_c (Krivanek), diffuse + Phong lobe; a VPL with an area whose patch is near the
   pixel as that patch (gim__vpl_near), summed after the others. The subset is split into dispatches of
   [first, last) of its members (llvmpipe stops an invocation's loops after 65535 iterations in
   all), the running float sums kept per pixel in `partial` between them. Writes rgb radiance,
   a = 1 where a surface is, at the last dispatch. */
#include "common.glsl"
#include "near_field.glsl"
layout(local_size_x = 8, local_size_y = 8) in;

#define TAPS 16

layout(binding = 0) uniform sampler2D gbuffer_depth;
layout(binding = 1) uniform sampler2D gbuffer_normal;     /* world normal in xyz, w = 1 where drawn */
layout(binding = 2) uniform sampler2D gbuffer_albedo;     /* diffuse rgb (unused with host_gbuffer) */
layout(binding = 3) uniform sampler2D gbuffer_material;   /* material id (unused with host_gbuffer) */
layout(binding = 4) uniform sampler2DArray distance_map;  /* R32F: one paraboloid map per layer */
layout(binding = 0) writeonly uniform image2D indirect;   /* RGBA16F or RGBA32F */

struct Vpl { vec4 position_lit; vec4 normal; vec4 flux; };        /* gim_vpl */
struct Map { vec4 origin_near; vec4 normal_size; vec4 flux; };    /* gim_paraboloid */
struct Material { vec4 diffuse; vec4 glossy; };                   /* rgb, (rgb, k) */
layout(std430, binding = 0) readonly buffer Vpls { Vpl vpl[]; };
layout(std430, binding = 1) readonly buffer Clusters { uint cluster[]; };   /* UINT_MAX: none */
layout(std430, binding = 2) readonly buffer Maps { Map map[]; };
layout(std430, binding = 3) readonly buffer Materials { Material material[]; };
layout(std430, binding = 4) buffer Partial { vec4 partial[]; };   /* per pixel: diffuse sum, glossy sum */

layout(location = 0) uniform uvec2 size;
layout(location = 1) uniform mat4 inv_proj;
layout(location = 2) uniform mat4 inv_view;
layout(location = 3) uniform vec4 eye;          /* perspective: (position, 1); orthographic: (direction, 0) */
layout(location = 4) uniform uint vpl_count;    /* N */
layout(location = 5) uniform uint k;            /* interleave, >= 1 */
layout(location = 6) uniform uvec2 range;       /* members [first, last) of the pixel's subset this dispatch */
layout(location = 7) uniform uint flags;        /* 1: visibility; 2: host G-buffer; 4: first dispatch; 8: last; 16: ISM;
                                                   32: ISM for the VPLs with no cluster from ism_first on */
layout(location = 8) uniform uint map_size;
layout(location = 9) uniform float near_;       /* 1e-6 scene_scale */
layout(location = 10) uniform float dc2;        /* clamp distance squared */
layout(location = 11) uniform uint material_count;
layout(location = 12) uniform float max_value;  /* largest value of the output format */
layout(location = 13) uniform uint map_count;   /* a cluster index beyond it is unshadowed */

/* flags & 16: each VPL's own imperfect shadow map (Ritschel et al. 2008) instead of its
   cluster's, map i of VPL i, hard visibility: gim_ism_visibility_twin's lookup with the receiver as
   the VAL, its float steps in its order (the twin: gim_vpl_shade_twin's ism) */
layout(std430, binding = 5) readonly buffer IsmMaps { uint ism[]; };   /* 16-bit depths, two to a uint (gim_ism_dequantize) */
layout(location = 14) uniform uint ism_size;
layout(location = 15) uniform float ism_bias;
layout(location = 16) uniform float ism_texel;  /* slope 2 / size */
layout(location = 17) uniform float ism_lift;   /* GIM_ISM_LIFT scene_scale */
/* flags & 32: with the clusters' maps (flags & 1), a VPL i >= ism_first that has no cluster (SSVP's
   second bounce) is shadowed by its own ISM, map i - ism_first */
layout(location = 18) uniform uint ism_first;

const vec2 VOGEL[TAPS] = vec2[TAPS](            /* gim__vogel16 */
    vec2(0.176776692, 0.0), vec2(-0.225772187, 0.206825823), vec2(0.0345580503, -0.393771172),
    vec2(0.28457123, 0.371172756), vec2(-0.522223175, -0.0923739299), vec2(0.494695395, -0.314684719),
    vec2(-0.165465921, 0.615525007), vec2(-0.315561473, -0.60759443), vec2(0.684642136, 0.25003022),
    vec2(-0.712256074, 0.29400897), vec2(0.343354493, -0.733728647), vec2(0.253730237, 0.808932006),
    vec2(-0.764745891, -0.443185866), vec2(0.897134006, -0.197232395), vec2(-0.547506928, 0.778772235),
    vec2(-0.126486778, -0.976089716));

/* gim__paraboloid_block: 1 where the texel under (u, v) holds a blocker nearer than the
   reference (the receiver's plane along the texel's centre ray when pl_on, else ref) */
bool blocks(int layer, precise float u, precise float v, bool pl_on, precise vec3 pl, precise float pd, precise float ref,
            out float z) {
    z = 0.0;
    precise float r2 = u * u + v * v;
    if (!(r2 <= 1.0)) return false;
    precise float fs = float(map_size);
    precise float fx = floor((u + 1.0) * fs * 0.5);
    precise float fy = floor((v + 1.0) * fs * 0.5);
    int x = fx < 0.0 ? 0 : (fx > fs - 1.0 ? int(map_size) - 1 : int(fx));
    int y = fy < 0.0 ? 0 : (fy > fs - 1.0 ? int(map_size) - 1 : int(fy));
    z = texelFetch(distance_map, ivec3(x, y, layer), 0).r;
    if (!(z > 0.0)) return false;
    precise float r = ref;
    if (pl_on) {
        precise float uc = (2.0 * float(x) + 1.0) / fs - 1.0;
        precise float vc = (2.0 * float(y) + 1.0) / fs - 1.0;
        precise float q = 1.0 + uc * uc + vc * vc;
        precise float den = pl.x * (2.0 * uc / q) + pl.y * (2.0 * vc / q) + pl.z * ((1.0 - uc * uc - vc * vc) / q);
        r = den * pd > 0.0 ? 0.99 * (pd / den) : FLT_MAX;
    }
    return z < r;
}

/* gim__paraboloid_vis: PCSS on map m's paraboloid map in angles (read the twin) */
float visibility(uint m, vec3 x, vec3 nx) {
    precise vec3 n = map[m].normal_size.xyz;
    precise vec3 o = map[m].origin_near.xyz;
    precise float delta = map[m].normal_size.w;
    precise vec3 t, b;
    basis_precise(n, t, b);
    precise float p0 = x.x - o.x, p1 = x.y - o.y, p2 = x.z - o.z;
    precise float lx = p0 * t.x + p1 * t.y + p2 * t.z;
    precise float ly = p0 * b.x + p1 * b.y + p2 * b.z;
    precise float lz = p0 * n.x + p1 * n.y + p2 * n.z;
    precise float d = sqrt(lx * lx + ly * ly + lz * lz);
    if (!(d > 0.0) || !(d <= FLT_MAX)) return 1.0;
    precise float wz = lz / d;
    if (!(wz > 0.0)) return 1.0;                          /* behind the VAL's plane */
    precise float opz = 1.0 + wz;
    precise float jac = 1.0 / opz;
    precise float u = lx / d / opz;
    precise float v = ly / d / opz;
    precise float fs = float(map_size);
    precise float texel = 2.0 * opz / fs;
    precise float bias = d * (0.01 + 4.0 * opz / fs);
    precise float ref = d - bias;
    precise vec3 pl = vec3(nx.x * t.x + nx.y * t.y + nx.z * t.z, nx.x * b.x + nx.y * b.y + nx.z * b.z,
                           nx.x * n.x + nx.y * n.y + nx.z * n.z);   /* the receiver's plane in the map's frame */
    precise float pd = pl.x * lx + pl.y * ly + pl.z * lz;
    bool pl_on = pd > 1e-6 * d || pd < -1e-6 * d;
    precise float dv = delta * sqrt(wz);                  /* the foreshortened VAL */
    precise float as_ = 1.5 * dv / d;
    as_ = as_ < 0.5 ? as_ : 0.5;
    precise float s = jac * as_;
    precise float zsum = 0.0;
    int found = 0, open = 0, layer = int(m);
    float z;
    for (int j = 0; j < TAPS; ++j)                        /* blocker search */
        if (blocks(layer, u + s * VOGEL[j].x, v + s * VOGEL[j].y, pl_on, pl, pd, ref, z)) { zsum += z; ++found; }
    if (found == 0) return 1.0;
    precise float zavg = zsum / float(found);
    precise float ap = 0.5 * dv * (1.0 / zavg - 1.0 / d);      /* penumbra half-width */
    precise float af = ap > texel ? ap : texel;
    af = af < 0.5 ? af : 0.5;
    s = jac * af;
    for (int j = 0; j < TAPS; ++j)                        /* PCF */
        if (!blocks(layer, u + s * VOGEL[j].x, v + s * VOGEL[j].y, pl_on, pl, pd, ref, z)) ++open;
    return float(open) / float(TAPS);
}

/* VPL i's ISM, seen from x (normal nx): 1 or 0 */
#include "ism_lookup.glsl"

/* gim__vpl_scramble: member j of an interleaved subset is this VPL (a bijection of [0, n));
   half_ (the Feistel halves' bits, scramble_bits(n)) is computed once per invocation */
uint scramble_bits(uint n) {
    uint half_ = 1u;
    while (half_ < 15u && (1u << (2u * half_)) < n) ++half_;
    return half_;
}
uint scramble(uint i, uint n, uint half_) {
    uint mask = (1u << half_) - 1u;
    do {
        uint l = i >> half_, r = i & mask;
        for (uint round_ = 0u; round_ < 4u; ++round_) {
            uint t = r * 0x9E3779B1u + round_ * 0x7F4A7C15u;
            t ^= t >> 15;
            t *= 0x2C1B3C6Du;
            t ^= t >> 12;
            t = l ^ (t & mask);
            l = r;
            r = t;
        }
        i = (l << half_) | r;
    } while (i >= n);
    return i;
}

/* VPL i's visibility from x (normal nx): its own ISM (flags & 16), its cluster's paraboloid
   map (flags & 1), or beside those maps its own second-bounce ISM (flags & 32); 1 unshadowed */
float vpl_visibility(uint i, Vpl p, vec3 x, vec3 nx) {
    if ((flags & 16u) != 0u) return ism_visibility(i, p.position_lit.xyz, p.normal.xyz, x, nx);
    if ((flags & 1u) != 0u && cluster[i] < map_count) return visibility(cluster[i], x, nx);
    if ((flags & 32u) != 0u && i >= ism_first) return ism_visibility(i - ism_first, p.position_lit.xyz, p.normal.xyz, x, nx);
    return 1.0;
}

/* The near field (gim__vpl_near): VPL p of area A, dist from x along o (VPL -> x), with its
   far-field g_far; returns E / Phi blended towards the octagon's F / A and turns o towards
   -unit(phi). */
float vpl_near(inout vec3 o, float dist, vec3 nx, vec3 nl, float area, float g_far) {
    vec3 d = -o * dist, phi;
    float f, fv;
    float w = near_patch(d, dist * dist, nx, nl, area, phi, f, fv);
    if (!(w > 0.0)) return g_far;
    vec3 u = o + w * (-phi / fv - o);
    float ul = length(u);
    if (ul > 0.0 && ul <= FLT_MAX) o = u / ul;
    return g_far + w * (f / (2.0 * PI * area) - g_far);
}

/* VPL i near x (d2 < VAL_NEAR^2 A, in front of both): its visibility, near field and lobe
   added to the sums. Out of the main loop: on SIMD CPUs (llvmpipe masks both sides of a
   branch) a branch around the patch in the loop would cost every VPL. */
void add_near(uint i, vec3 x, vec3 nx, vec3 view, float kexp, inout vec3 sd, inout vec3 sgl) {
    Vpl p = vpl[i];
    precise float dx = x.x - p.position_lit.x, dy = x.y - p.position_lit.y, dz = x.z - p.position_lit.z;
    precise float d2 = dx * dx + dy * dy + dz * dz;
    precise float dist = sqrt(d2);
    vec3 o = vec3(dx, dy, dz) / dist;
    float cl = dot(p.normal.xyz, o), cx = -dot(nx, o);
    float g = vpl_visibility(i, p, x, nx) * vpl_near(o, dist, nx, p.normal.xyz, p.normal.w, cl * cx / (PI * (d2 > dc2 ? d2 : dc2)));
    cx = -dot(nx, o);
    vec3 r = 2.0 * cx * nx + o;
    float re = dot(r, view);
    float lobe = kexp == 0.0 ? 1.0 : (re > 0.0 ? pow(re, kexp) : 0.0);
    vec3 e = p.flux.xyz * g;
    sd += e;
    sgl += e * lobe;
}

const uint NEAR_CAP = 8u;   /* GIM__VPL_NEAR_CAP */
void main() {
    ivec2 px = ivec2(gl_GlobalInvocationID.xy);
    if (px.x >= int(size.x) || px.y >= int(size.y)) return;
    uint pix = uint(px.y) * size.x + uint(px.x);
    bool last = (flags & 8u) != 0u;
    /* the receiver, as lightskin_shade.comp builds it */
    float depth = texelFetch(gbuffer_depth, px, 0).r;
    vec4 nw = texelFetch(gbuffer_normal, px, 0);
    if (!(depth < 1.0) || !finite3(nw.xyz) || !(dot(nw.xyz, nw.xyz) > 0.0)) {
        if (last) imageStore(indirect, px, vec4(0.0));
        return;
    }
    vec3 x = unproject(px, depth, size, inv_proj, inv_view);
    vec3 nx = normalize(nw.xyz);
    vec3 view = normalize(eye.w > 0.0 ? eye.xyz - x : eye.xyz);
    vec3 albedo = vec3(1.0), gcol = vec3(0.0);
    float kexp = 0.0;
    if ((flags & 2u) == 0u) {
        albedo = texelFetch(gbuffer_albedo, px, 0).rgb;
        uint id = min(uint(max(texelFetch(gbuffer_material, px, 0).r, 0.0)), material_count - 1u);
        gcol = material[id].glossy.rgb;
        kexp = material[id].glossy.w;
    }

    precise vec3 sd = vec3(0.0), sgl = vec3(0.0);
    uint near_count = 0u;   /* near VPLs of the pixel's subset so far (GIM__VPL_NEAR_CAP take the near field) */
    if ((flags & 4u) == 0u) {
        sd = partial[pix * 2u].xyz;
        sgl = partial[pix * 2u + 1u].xyz;
        near_count = uint(partial[pix * 2u].w);
    }
    uint step = k * k, s = uint(px.x) % k + k * (uint(px.y) % k);
    uint bits = scramble_bits(vpl_count);
    uvec4 near_a = uvec4(0u), near_b = uvec4(0u);   /* VPL indices of this dispatch's near ones */
    uint near_first = near_count;
    for (uint j = range.x; j < range.y; ++j) {
        uint member = s + j * step;
        if (member >= vpl_count) break;
        uint i = scramble(member, vpl_count, bits);
        Vpl p = vpl[i];
        if (!(p.position_lit.w > 0.0)) continue;
        precise float dx = x.x - p.position_lit.x, dy = x.y - p.position_lit.y, dz = x.z - p.position_lit.z;
        precise float d2 = dx * dx + dy * dy + dz * dz;
        precise float dist = sqrt(d2);
        if (!(dist > near_)) continue;
        precise float ox = dx / dist, oy = dy / dist, oz = dz / dist;
        precise float cl = p.normal.x * ox + p.normal.y * oy + p.normal.z * oz;
        precise float cx = -(nx.x * ox + nx.y * oy + nx.z * oz);
        if (!(cl > 0.0) || !(cx > 0.0)) continue;
        if (p.normal.w > 0.0 && d2 < VAL_NEAR * VAL_NEAR * p.normal.w && near_count < NEAR_CAP) {
            /* its patch, after the loop: listed by selects (a dynamically indexed local array
               is a gather and scatter on llvmpipe: several times this pass) */
            uint slot = near_count++ - near_first;
            near_a += uvec4(equal(uvec4(0u, 1u, 2u, 3u), uvec4(slot))) * (i - near_a);
            near_b += uvec4(equal(uvec4(4u, 5u, 6u, 7u), uvec4(slot))) * (i - near_b);
            continue;
        }
        precise float vv = vpl_visibility(i, p, x, nx);
        precise float g = cl * cx * vv / (PI * (d2 > dc2 ? d2 : dc2));
        precise float rx = 2.0 * cx * nx.x + ox, ry = 2.0 * cx * nx.y + oy, rz = 2.0 * cx * nx.z + oz;
        precise float re = rx * view.x + ry * view.y + rz * view.z;
        float lobe = kexp == 0.0 ? 1.0 : (re > 0.0 ? pow(re, kexp) : 0.0);
        precise vec3 e = p.flux.xyz * g;
        sd += e;
        sgl += e * lobe;
    }
    /* the near ones: a loop, not a branch, so that they cost only where a pixel of the SIMD group has
       them (llvmpipe leaves a loop when no lane is active; both sides of a branch always run) */
    for (uint q = near_first; q < near_count; ++q) {
        uint slot = q - near_first;
        add_near(slot < 4u ? near_a[slot] : near_b[slot - 4u], x, nx, view, kexp, sd, sgl);
    }
    if (!last) {
        partial[pix * 2u] = vec4(sd, float(near_count));
        partial[pix * 2u + 1u] = vec4(sgl, 0.0);
        return;
    }
    uint count = s < vpl_count ? (vpl_count - s + step - 1u) / step : 0u;   /* n_s */
    vec3 outc = vec3(0.0);
    if (count > 0u) {
        precise float scale = float(vpl_count) / float(count);
        precise float fd = scale / PI;
        precise float fg = scale * (kexp + 2.0) / (2.0 * PI);
        precise vec3 ed = min(sd, vec3(FLT_MAX)), eg = min(sgl, vec3(FLT_MAX));
        outc = albedo * (fd * ed) + gcol * (fg * eg);
    }
    imageStore(indirect, px, vec4(min(outc, vec3(max_value)), 1.0));
}
