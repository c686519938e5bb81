/* Second-bounce VPLs by rays (Keller 1997's instant radiosity), the GPU twin of
   gim_second_bounce_rays_twin: one invocation per ray. Ray j picks a first-bounce VPL of its
   stratum by flux (the VPLs it overlaps, [j N, (j + 1) N) in units of 1 / S VPL), walks the
   scene's hierarchy from it to the nearest triangle (bvh.glsl, the segment cut at each nearer
   crossing) and writes its VPL to vpl[first + j]. The rays' samples (pick u, direction x, y, z
   in the VPL's frame) are the twin's, computed on the CPU (gim__second_ray_sample). The
   hierarchy's triangles carry their material in the w of their first vec4 (gim__gl_bvh). */
#include "common.glsl"
layout(local_size_x = 256) in;

struct Vpl { vec4 position; vec4 normal; vec4 flux; };   /* w: lit; area; kept */
layout(std430, binding = 0) buffer Vpls { Vpl vpl[]; };   /* reads [0, N), writes [first, first + S) */
layout(std430, binding = 1) readonly buffer Samples { vec4 sample_point[]; };
struct Material { vec4 diffuse; vec4 glossy; };
layout(std430, binding = 3) readonly buffer Materials { Material material[]; };
layout(std430, binding = 6) readonly buffer Bvh { vec4 bvh[]; };

layout(location = 1) uniform uint vpl_count;
layout(location = 2) uniform uint count;
layout(location = 3) uniform uint first;
layout(location = 4) uniform float lift;          /* GIM_SECOND_RAY_LIFT scene_scale */
layout(location = 5) uniform float far_length;    /* 4 / bvh_scale */
layout(location = 6) uniform uint material_count; /* 0: albedo 0 */
layout(location = 17) uniform uint bvh_nodes;
layout(location = 18) uniform uint bvh_triangles;
layout(location = 20) uniform vec3 bvh_origin;
layout(location = 21) uniform float bvh_scale;
#include "bvh.glsl"

/* gim__second_ray_weight */
float weight(uint i) {
    Vpl v = vpl[i];
    uvec3 f = floatBitsToUint(v.flux.rgb);
    if (!positive(floatBitsToUint(v.position.w)) || !finite3(floatBitsToUint(v.position.xyz)) ||
        !finite3(floatBitsToUint(v.normal.xyz)) || !finite3(f) || !nonneg3(f))
        return 0.0;
    precise float w = (v.flux.r + v.flux.g) + v.flux.b;
    return w;
}

/* gim__second_ray_share: weight(i) times VPL i's overlap of ray j's stratum */
float share(uint i, uint j) {
    uint a = j * vpl_count, b = a + vpl_count, c = i * count, d = c + count;
    precise float s = weight(i) * float(min(b, d) - max(a, c));
    return s;
}

void main() {
    uint j = gl_GlobalInvocationID.x;
    if (j >= count) return;
    Vpl o;
    o.position = vec4(0.0);
    o.normal = vec4(0.0);
    o.flux = vec4(0.0);
    uint lo = j * vpl_count / count, hi = (j * vpl_count + vpl_count - 1u) / count, i;
    precise float total = 0.0, run = 0.0;
    for (i = lo; i <= hi; ++i) total += share(i, j);
    if (total > 0.0 && finite3(vec3(total))) {
        vec4 smp = sample_point[j];
        precise float target = smp.x * total;
        for (i = lo; i <= hi; ++i) {
            run += share(i, j);
            if (run > target) break;
        }
        float w = i <= hi ? weight(i) : 0.0;
        if (w > 0.0) {
            Vpl v = vpl[i];
            vec3 n = v.normal.xyz, t, b;
            basis_precise(n, t, b);
            precise vec3 dir = vec3((t.x * smp.y + b.x * smp.z) + n.x * smp.w, (t.y * smp.y + b.y * smp.z) + n.y * smp.w,
                                    (t.z * smp.y + b.z * smp.z) + n.z * smp.w);
            precise vec3 org = vec3(v.position.x + lift * n.x, v.position.y + lift * n.y, v.position.z + lift * n.z);
            precise vec3 end = vec3(org.x + far_length * dir.x, org.y + far_length * dir.y, org.z + far_length * dir.z);
            float ht;
            uint slot = bvh_nearest(org, end, ht);
            if (slot != 0xffffffffu) {
                uint at = bvh_triangles + 3u * slot;
                precise vec3 e1 = bvh[at + 1u].xyz, e2 = bvh[at + 2u].xyz;
                precise vec3 nn = vec3(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x);
                precise float l = sqrt(nn.x * nn.x + nn.y * nn.y + nn.z * nn.z);
                precise float side = nn.x * dir.x + nn.y * dir.y + nn.z * dir.z;
                if (l > 0.0 && finite3(vec3(l))) {
                    if (side > 0.0) l = -l;
                    precise float kk = total / (w * float(count));
                    uint id = floatBitsToUint(bvh[at].w);
                    vec3 albedo = material_count > 0u ? material[min(id, material_count - 1u)].diffuse.rgb : vec3(0.0);
                    precise vec3 f = vec3(albedo.r * (v.flux.r * kk), albedo.g * (v.flux.g * kk), albedo.b * (v.flux.b * kk));
                    precise vec3 p = vec3(org.x + ht * (end.x - org.x), org.y + ht * (end.y - org.y), org.z + ht * (end.z - org.z));
                    o.position = vec4(p, 1.0);
                    o.normal = vec4(nn / l, 0.0);
                    o.flux = vec4(min(f, vec3(FLT_MAX)), 0.0);
                }
            }
        }
    }
    vpl[first + j] = o;
}
