/* Second-bounce VPLs by rays (Keller 1997's instant radiosity), the GPU twin of
   gim_second_bounce_rays_twin: one invocation per ray. Ray j picks a first-bounce VPL of its
   stratum by flux (the VPLs it overlaps, [j N, (j + 1) N) in units of 1 / S VPL), walks the
   scene's hierarchy from it to the nearest triangle (bvh.glsl, the segment cut at each nearer
   crossing) and writes its VPL to vpl[first + j]. The rays' samples (pick u, direction x, y, z
   in the VPL's frame) are the twin's, computed on the CPU (gim__second_ray_sample). Each VPL's
   area: one over the rays' expected landings per unit area there (gim__second_ray_area). The
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
float weight_of(Vpl v) {
    uvec3 f = floatBitsToUint(v.flux.rgb);
    if (!positive(floatBitsToUint(v.position.w)) || !finite3(floatBitsToUint(v.position.xyz)) ||
        !finite3(floatBitsToUint(v.normal.xyz)) || !finite3(f) || !nonneg3(f))
        return 0.0;
    precise float w = (v.flux.r + v.flux.g) + v.flux.b;
    return w;
}

float weight(uint i) { return weight_of(vpl[i]); }

/* gim__second_ray_share: weight(i) times VPL i's overlap of ray j's stratum */
float share(uint i, uint j) {
    uint a = j * vpl_count, b = a + vpl_count, c = i * count, d = c + count;
    precise float s = weight(i) * float(min(b, d) - max(a, c));
    return s;
}

/* VPL i's terms of gim__second_ray_area at x (normal nx): its weight w and w cos_i cos_x / d^2
   (0 behind either side) */
vec2 density_terms(uint i, vec3 x, vec3 nx) {
    Vpl v = vpl[i];
    float w = weight_of(v);
    if (!(w > 0.0)) return vec2(0.0);
    precise float dx = x.x - v.position.x, dy = x.y - v.position.y, dz = x.z - v.position.z;
    precise float d2 = (dx * dx + dy * dy) + dz * dz;
    precise float ci = (v.normal.x * dx + v.normal.y * dy) + v.normal.z * dz;
    precise float cx = -((nx.x * dx + nx.y * dy) + nx.z * dz);
    if (!(d2 > 0.0) || !(ci > 0.0) || !(cx > 0.0)) return vec2(w, 0.0);
    precise float g = ((ci * cx) / d2) / d2;
    precise float wg = w * g;
    return vec2(w, wg);
}

/* gim__second_ray_area: the surface the VPL landing at x stands for, pi W / (S sum_i w_i cos_i
   cos_x / d_i^2), summed in VPL order four VPLs a step (llvmpipe ends an invocation's loops after
   65535 iterations in all) */
float landing_area(vec3 x, vec3 nx) {
    precise float wsum = 0.0, dens = 0.0;
    uint i = 0u;
    for (; i + 4u <= vpl_count; i += 4u) {
        vec2 t0 = density_terms(i, x, nx), t1 = density_terms(i + 1u, x, nx);
        vec2 t2 = density_terms(i + 2u, x, nx), t3 = density_terms(i + 3u, x, nx);
        wsum += t0.x; dens += t0.y;
        wsum += t1.x; dens += t1.y;
        wsum += t2.x; dens += t2.y;
        wsum += t3.x; dens += t3.y;
    }
    for (; i < vpl_count; ++i) {
        vec2 t = density_terms(i, x, nx);
        wsum += t.x; dens += t.y;
    }
    precise float area = (PI * wsum) / (float(count) * dens);
    return area > 0.0 && area < FLT_MAX ? area : 0.0;
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
    /* four VPLs a step: a stratum is the whole list at S = 1, and llvmpipe ends an invocation's
       loops after 65535 iterations in all */
    for (i = lo; i + 3u <= hi; i += 4u) {
        total += share(i, j);
        total += share(i + 1u, j);
        total += share(i + 2u, j);
        total += share(i + 3u, j);
    }
    for (; i <= hi; ++i) total += share(i, j);
    if (total > 0.0 && finite3(vec3(total))) {
        vec4 smp = sample_point[j];
        precise float target = smp.x * total;
        bool picked = false;
        for (i = lo; i + 3u <= hi; i += 4u) {
            precise float r0 = run + share(i, j);
            precise float r1 = r0 + share(i + 1u, j);
            precise float r2 = r1 + share(i + 2u, j);
            precise float r3 = r2 + share(i + 3u, j);
            if (r3 > target) {   /* the first of the four whose running sum passes the target */
                i += r0 > target ? 0u : r1 > target ? 1u : r2 > target ? 2u : 3u;
                picked = true;
                break;
            }
            run = r3;
        }
        for (; !picked && i <= hi; ++i) {
            run += share(i, j);
            if (run > target) { picked = true; break; }
        }
        float w = picked ? weight(i) : 0.0;
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
                    vec3 nrm = nn / l;
                    o.position = vec4(p, 1.0);
                    o.normal = vec4(nrm, landing_area(p, nrm));
                    o.flux = vec4(min(f, vec3(FLT_MAX)), 0.0);
                }
            }
        }
    }
    vpl[first + j] = o;
}
