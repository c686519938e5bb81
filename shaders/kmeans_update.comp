/* k-means update step on the GPU, the twin of gim_kmeans' update (see its "Means"): a gather,
   one invocation per cluster looping over the VPLs in index order, so the sums are
   deterministic (no atomics) and in the twin's order, in double. A VPL weighs its mean rgb
   flux (r + g + b) / 3; the centre is the weighted mean position, the normal the normalised
   weighted mean normal (kept where the normals cancel, |sum| <= 1e-9 sum of weights); a
   cluster whose VPLs all have zero flux takes the plain means. An empty cluster keeps its
   centre and normal (the CPU re-seeds it; the GPU step reports it by count 0).
     mode 0: sums over VPLs [first, first + n) added to acc[cluster] (reset when first == 0);
             one dispatch per chunk, each loop under llvmpipe's 65535 iterations;
     mode 1: the means written to centre[cluster], position.w = its VPL count. */
layout(local_size_x = 64) in;

struct Vpl { vec4 position; vec4 normal; vec4 flux; };
layout(std430, binding = 0) readonly buffer Vpls { Vpl vpl[]; };
struct Centre { vec4 position; vec4 normal; };
layout(std430, binding = 1) buffer Centres { Centre centre[]; };
layout(std430, binding = 2) readonly buffer Assignment { uint assignment[]; };
/* per cluster: (W, count), sum w x, sum w n, sum x, sum n */
struct Acc { dvec4 w; dvec4 wx; dvec4 wn; dvec4 x; dvec4 n; };
layout(std430, binding = 3) buffer Accs { Acc acc[]; };

layout(location = 0) uniform uint cluster_count;
layout(location = 1) uniform uint first;
layout(location = 2) uniform uint n;
layout(location = 3) uniform uint mode;

void main() {
    uint j = gl_GlobalInvocationID.x;
    if (j >= cluster_count) return;
    if (mode == 0u) {
        Acc a;
        if (first == 0u) {
            a.w = dvec4(0.0); a.wx = dvec4(0.0); a.wn = dvec4(0.0); a.x = dvec4(0.0); a.n = dvec4(0.0);
        } else {
            a = acc[j];
        }
        for (uint i = first; i < first + n; ++i) {
            if (assignment[i] != j) continue;
            dvec3 x = dvec3(vpl[i].position.xyz), nx = dvec3(vpl[i].normal.xyz), f = dvec3(vpl[i].flux.rgb);
            double len = length(nx), w = (f.r + f.g + f.b) / 3.0LF;
            nx = len > 0.0LF ? nx / len : dvec3(0.0);
            a.w.xy += dvec2(w, 1.0LF);
            a.wx.xyz += w * x; a.wn.xyz += w * nx;
            a.x.xyz += x;      a.n.xyz += nx;
        }
        acc[j] = a;
    } else {
        Acc a = acc[j];
        if (a.w.y == 0.0LF) { centre[j].position.w = 0.0; return; }   /* empty: keep the old centre */
        bool plain = !(a.w.x > 0.0LF);
        double wsum = plain ? a.w.y : a.w.x;
        dvec3 sp = plain ? a.x.xyz : a.wx.xyz, sn = plain ? a.n.xyz : a.wn.xyz;
        double len = length(sn);
        centre[j].position = vec4(vec3(sp / wsum), float(a.w.y));
        if (len > 1e-9LF * wsum) centre[j].normal = vec4(vec3(sn / len), 0.0);
    }
}
