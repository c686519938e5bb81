/* The clusters' VALs and paraboloid maps, the twin of gim_cluster_paraboloids_twin: one invocation
   per cluster looping over the VPLs in index order (<= 32768: under llvmpipe's 65535
   iterations), sums in double. Per cluster: the summed flux, the flux-weighted (plain when the
   cluster has no flux) covariance C of its VPLs projected on the plane of its normal, the VAL
   side Delta = sqrt(12 sqrt(det C)), the origin lifted 1e-4 scene scales along the normal,
   near = max(Delta / 2, the lift) and the attribute maps' near min(1e-2 scene scales, near).
     mode 0: the maps from the k-means centres (centre.w: VPLs; the normal renormalised);
     mode 1: seed the centres: centre[k] = VPL floor(k N / M) (Dong sec. 5.2, the same seeds
             every frame; gim_kmeans' FIXED init), or the first lit VPL after it (an unlit one
             carries no light: a cluster seeded there would sit wherever the cone is not, and
             jump when the light moves), a zero normal taken as +z;
     mode 2: repair cluster `target` if the last update left it empty (centre.w = 0), one
             invocation: the lit VPL farthest from its own centre among the clusters of two or
             more VPLs (ties: the lowest index) moves to it and seeds it, as gim_kmeans
             re-seeds (which takes the farthest VPL of the cluster of largest error). */
#include "common.glsl"
layout(local_size_x = 64) in;

struct Vpl { vec4 position; vec4 normal; vec4 flux; };
layout(std430, binding = 0) readonly buffer Vpls { Vpl vpl[]; };
struct Centre { vec4 position; vec4 normal; };
layout(std430, binding = 1) buffer Centres { Centre centre[]; };
layout(std430, binding = 2) buffer Assignment { uint assignment[]; };
struct Map { vec4 origin_near; vec4 normal_size; vec4 flux; };
layout(std430, binding = 3) writeonly buffer Maps { Map map[]; };

layout(location = 0) uniform uint vpl_count;
layout(location = 1) uniform uint cluster_count;
layout(location = 2) uniform float scene_scale;
layout(location = 3) uniform uint mode;
layout(location = 4) uniform uint target;

void main() {
    uint m = gl_GlobalInvocationID.x;
    if (m >= cluster_count) return;
    if (mode == 2u) {
        if (m != 0u || centre[target].position.w != 0.0) return;
        float best = -1.0;
        uint arg = 0xffffffffu;
        for (uint i = 0u; i < vpl_count; ++i) {
            uint c = assignment[i];
            if (c >= cluster_count || centre[c].position.w < 2.0 || vpl[i].position.w <= 0.0) continue;
            float d = length(vpl[i].position.xyz - centre[c].position.xyz);
            if (d > best) { best = d; arg = i; }
        }
        if (arg == 0xffffffffu) return;
        uint from = assignment[arg];
        vec3 n = vpl[arg].normal.xyz;
        assignment[arg] = target;
        centre[from].position.w -= 1.0;
        centre[target].position = vec4(vpl[arg].position.xyz, 1.0);
        centre[target].normal = vec4(dot(n, n) > 0.0 ? n : vec3(0.0, 0.0, 1.0), 0.0);
        return;
    }
    if (mode == 1u) {
        uint i0 = (m * vpl_count) / cluster_count, i = i0;   /* < 256 * 32768: no overflow */
        for (uint j = 0u; j < vpl_count; ++j) {
            uint c = i0 + j < vpl_count ? i0 + j : i0 + j - vpl_count;
            if (vpl[c].position.w > 0.0) { i = c; break; }
        }
        vec3 n = vpl[i].normal.xyz;
        centre[m].position = vec4(vpl[i].position.xyz, 0.0);
        centre[m].normal = vec4(dot(n, n) > 0.0 ? n : vec3(0.0, 0.0, 1.0), 0.0);
        return;
    }
    vec3 n = centre[m].normal.xyz, t, b;
    float len = length(n);
    n = len > 0.0 ? n / len : vec3(0.0, 0.0, 1.0);
    basis(n, t, b);
    dvec3 c = dvec3(centre[m].position.xyz), dt = dvec3(t), db = dvec3(b);
    dvec3 f = dvec3(0.0);
    dvec2 w = dvec2(0.0), s1w = dvec2(0.0), s1p = dvec2(0.0);
    dvec3 s2w = dvec3(0.0), s2p = dvec3(0.0);
    for (uint i = 0u; i < vpl_count; ++i) {
        if (assignment[i] != m) continue;
        dvec3 d = dvec3(vpl[i].position.xyz) - c, fl = dvec3(vpl[i].flux.rgb);
        double ps = d.x * dt.x + d.y * dt.y + d.z * dt.z;
        double pt = d.x * db.x + d.y * db.y + d.z * db.z;
        double wi = (fl.r + fl.g + fl.b) / 3.0LF;
        f += fl;
        w += dvec2(wi, 1.0LF);
        s1w += wi * dvec2(ps, pt);
        s1p += dvec2(ps, pt);
        s2w += wi * dvec3(ps * ps, pt * pt, ps * pt);
        s2p += dvec3(ps * ps, pt * pt, ps * pt);
    }
    double area = 0.0LF;
    if (w.y > 0.0LF) {
        bool plain = !(w.x > 0.0LF);
        double W = plain ? w.y : w.x;
        dvec2 s1 = plain ? s1p : s1w;
        dvec3 s2 = plain ? s2p : s2w;
        double ms = s1.x / W, mt = s1.y / W;
        double css = s2.x / W - ms * ms, ctt = s2.y / W - mt * mt, cst = s2.z / W - ms * mt;
        double det = css * ctt - cst * cst;
        area = det > 0.0LF ? 12.0LF * sqrt(det) : 0.0LF;
    }
    float lift = 1e-4 * scene_scale, size = float(sqrt(area));
    float near_distance = max(0.5 * size, lift);
    map[m].origin_near = vec4(centre[m].position.xyz + lift * n, near_distance);
    map[m].normal_size = vec4(n, size);
    /* w: attribute_near, the second bounce's own skip (gim_cluster_paraboloids_twin) */
    map[m].flux = vec4(vec3(min(f, dvec3(3.4028234663852886e38LF))), min(1e-2 * scene_scale, near_distance));
}
