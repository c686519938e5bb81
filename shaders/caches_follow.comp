/* Caches of a deforming mesh follow its triangles (twin: gim_caches_follow_twin). Each cache was
   bound once (gim_cache_bind) to a triangle: its foot point in barycentrics, its height along
   the face normal, its normal in the triangle's frame. Here the deformed vertices, read where
   the mesh's positions live (gimany's copy, or the host's buffer with its offset and stride),
   put it back: position on the moved triangle, normal through the triangle's linear map M
   (M^-T n by the dual basis), area scaled by the triangle's area ratio. mode 0 instead takes
   the bounds of the vertices (and flags a non-finite one), so a host's deforming buffers need
   no read-back of the vertices. */
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer Positions { float pos[]; };
struct Bound {
    uvec4 tri;        /* xyz: the triangle's vertices */
    vec4 uvh;         /* u, v, h, |(b - a) x (c - a)| at binding */
    vec4 frame_area;  /* n.(b - a), n.(c - a), n.n_face at binding; rest area */
    vec4 rest;        /* reflectance, rest normal */
};
layout(std430, binding = 1) readonly buffer Bounds { Bound bound[]; };
layout(std430, binding = 2) writeonly buffer Followed { vec4 followed[]; };   /* gim_cache: position + area, normal + rho */
layout(std430, binding = 3) buffer Box { uint box[]; };   /* mode 0: ordered min xyz, max xyz, non-finite flag */

layout(location = 0) uniform uint mode;
layout(location = 1) uniform uint count;       /* caches (mode 1) or vertices (mode 0) */
layout(location = 2) uniform uint pos_offset;  /* floats before vertex 0 */
layout(location = 3) uniform uint pos_stride;  /* floats between vertices */

vec3 vertex(uint i) {
    uint b = pos_offset + i * pos_stride;
    return vec3(pos[b], pos[b + 1u], pos[b + 2u]);
}

/* a float's bits made to order as unsigned integers do, for atomicMin / atomicMax */
uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : (u | 0x80000000u);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    if (mode == 0u) {
        vec3 p = vertex(i);
        if (any(isnan(p)) || any(isinf(p))) { atomicOr(box[6], 1u); return; }
        for (int k = 0; k < 3; ++k) {
            atomicMin(box[k], ordered(p[k]));
            atomicMax(box[3 + k], ordered(p[k]));
        }
        return;
    }
    Bound b = bound[i];
    vec3 a = vertex(b.tri.x), pb = vertex(b.tri.y), pc = vertex(b.tri.z);
    vec3 e1 = pb - a, e2 = pc - a;
    vec3 cr = cross(e1, e2);
    float len = sqrt(cr.x * cr.x + cr.y * cr.y + cr.z * cr.z);
    float u = b.uvh.x, v = b.uvh.y, w = 1.0 - u - v;
    vec3 n = len > 0.0 ? cr / len : vec3(0.0);
    vec3 p = w * a + u * pb + v * pc + b.uvh.z * n;
    vec3 m = cross(e2, n) * b.frame_area.x + cross(n, e1) * b.frame_area.y + cr * b.frame_area.z;
    float ml = sqrt(m.x * m.x + m.y * m.y + m.z * m.z);
    vec3 nrm = len > 0.0 && ml > 0.0 ? m / ml : b.rest.yzw;   /* a collapsed triangle: the rest normal */
    float area = b.uvh.w > 0.0 ? b.frame_area.w * (len / b.uvh.w) : 0.0;
    followed[i * 2u] = vec4(p, area);
    followed[i * 2u + 1u] = vec4(nrm, b.rest.x);
}
