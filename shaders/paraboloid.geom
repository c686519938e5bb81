/* One triangle into map map_index[0] (the layer): a screen-space quad that conservatively
   covers the triangle's exact image, for paraboloid.frag to ray-cast texel by texel. The
   image of a straight edge under the paraboloid (stereographic) map is curved, so the
   projected vertices alone do not bound it. In the map's frame (t, b = gim_basis(n)):
   the triangle is culled when it lies wholly behind the origin's plane (z <= 0), clipped to
   z >= 0 (up to 4 vertices), and each edge's arc of directions is sampled at K + 1 points. A
   sub-arc of angle alpha between samples w0, w1 maps to a curve of length <= alpha /
   (1 + min(w0.z, w1.z)) (the map scales an angle near w by 1 / (1 + w.z), and z along a great
   circle arc in z >= 0 is smallest at an end), so every point of it lies within half that of
   an end: padding the ends by it bounds the image rigorously. K grows with the edge's angle
   (padding of at most ~half a texel, up to 16 samples), so a small triangle costs one or two
   samples per edge. The rasteriser draws the texels whose centres (the rays' texels) fall
   inside the quad, so margin only absorbs rounding (a quarter texel). A triangle through the
   origin covers the whole map. The last vertex stage: every clip distance GL 4.3 guarantees
   (8) is written positive, so the planes a host left enabled clip nothing (gimany does not
   save them). */
#include "common.glsl"
layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

in vec3 world_position[];
in vec3 world_normal[];
flat in int map_index[];

struct Paraboloid { vec4 origin_near; vec4 normal_size; vec4 flux; };
layout(std430, binding = 2) readonly buffer Maps { Paraboloid map[]; };
struct Material { vec4 diffuse; vec4 glossy; };
layout(std430, binding = 0) readonly buffer Materials { Material material[]; };
layout(std430, binding = 1) readonly buffer TriangleMaterial { uint triangle_material[]; };

layout(location = 3) uniform uint material_count;  /* 0: albedo 0 */
layout(location = 4) uniform float margin;         /* map units */
layout(location = 5) uniform uint size;            /* of the maps */
layout(location = 8) uniform uint list_first;      /* with vpl_lift: instance i draws VPL list[list_first + i] */
layout(location = 9) uniform float vpl_lift;       /* > 0: Maps holds gim_vpl (3 vec4: position, lit in w;
                                                      normal; flux, kept in w), each a map of origin
                                                      position + vpl_lift normal, no near skip; 0: the
                                                      clusters' maps, instance i map i */
layout(std430, binding = 3) readonly buffer List { uint list[]; };   /* the VPLs whose maps are made */

flat out vec3 tri_v0;      /* vertices relative to the map's origin, world axes */
flat out vec3 tri_v1;
flat out vec3 tri_v2;
flat out vec3 tri_n0;      /* world vertex normals */
flat out vec3 tri_n1;
flat out vec3 tri_n2;
flat out vec3 tri_albedo;
flat out vec3 tri_origin;  /* the map's frame: origin, unit axis, the two skips */
flat out vec3 tri_axis;
flat out float tri_near;
flat out float tri_attribute_near;
out float gl_ClipDistance[8];

const int MAX_K = 16;

void main() {
    int m = vpl_lift > 0.0 ? int(list[list_first + uint(map_index[0])]) : map_index[0];
    vec3 o = map[m].origin_near.xyz;
    vec3 n = normalize(map[m].normal_size.xyz);
    float near = map[m].origin_near.w, attribute_near = map[m].flux.w;
    if (vpl_lift > 0.0) {   /* a VPL's map (gim__gl_vpl_shadow_maps) */
        vec3 c = map[m].origin_near.xyz, nv = map[m].normal_size.xyz;
        o = vec3(c.x + vpl_lift * nv.x, c.y + vpl_lift * nv.y, c.z + vpl_lift * nv.z);   /* gim__ism_frame's */
        n = nv;   /* unit already; as the maps' lookup (ism_lookup.glsl) takes it */
        near = 0.0;
        attribute_near = 0.0;
    }
    vec3 t, b;
    basis(n, t, b);
    vec3 rel[3], l[3];
    for (int i = 0; i < 3; ++i) {
        rel[i] = world_position[i] - o;
        l[i] = vec3(dot(rel[i], t), dot(rel[i], b), dot(rel[i], n));
    }
    if (l[0].z <= 0.0 && l[1].z <= 0.0 && l[2].z <= 0.0) return;
    /* clip to z >= 0 */
    vec3 poly[4];
    int k = 0;
    for (int i = 0; i < 3; ++i) {
        vec3 a = l[i], c = l[(i + 1) % 3];
        if (a.z >= 0.0) poly[k++] = a;
        if ((a.z >= 0.0) != (c.z >= 0.0)) {
            vec3 p = mix(a, c, a.z / (a.z - c.z));
            p.z = max(p.z, 0.0);
            poly[k++] = p;
        }
    }
    vec2 lo = vec2(1.0), hi = vec2(-1.0);
    bool whole = false;
    for (int e = 0; e < k && !whole; ++e) {
        vec3 a = poly[e], c = poly[(e + 1) % k];
        float la = length(a), lc = length(c), tiny = 1e-6 * max(la, lc);
        if (!(la > tiny && lc > tiny)) { whole = true; break; }
        /* the edge's angle over a texel's worth of map units (2 / size; 1 / (1 + z) <= 1) */
        float edge = 2.0 * asin(min(0.5 * length(a / la - c / lc), 1.0));
        int K = clamp(int(ceil(edge * float(size) / 2.0)), 1, MAX_K);
        vec3 prev = vec3(0.0);
        vec2 prev_uv = vec2(0.0);
        for (int j = 0; j <= K; ++j) {
            vec3 p = mix(a, c, float(j) / float(K));
            float len = length(p);
            if (!(len > tiny)) { whole = true; break; }
            vec3 w = p / len;
            vec2 uv = w.xy / (1.0 + max(w.z, 0.0));
            lo = min(lo, uv);
            hi = max(hi, uv);
            if (j > 0) {
                float alpha = 2.0 * asin(min(0.5 * length(w - prev), 1.0));
                float pad = 0.5 * alpha / (1.0 + max(min(w.z, prev.z), 0.0));
                lo = min(lo, min(uv, prev_uv) - pad);
                hi = max(hi, max(uv, prev_uv) + pad);
            }
            prev = w;
            prev_uv = uv;
        }
    }
    if (whole) { lo = vec2(-1.0); hi = vec2(1.0); }
    lo = clamp(lo - margin, -1.0, 1.0);
    hi = clamp(hi + margin, -1.0, 1.0);
    vec3 albedo = vec3(0.0);
    if (material_count > 0u) albedo = material[min(triangle_material[gl_PrimitiveIDIn], material_count - 1u)].diffuse.rgb;
    for (int v = 0; v < 4; ++v) {
        tri_v0 = rel[0]; tri_v1 = rel[1]; tri_v2 = rel[2];
        tri_n0 = world_normal[0]; tri_n1 = world_normal[1]; tri_n2 = world_normal[2];
        tri_albedo = albedo;
        tri_origin = o;
        tri_axis = n;
        tri_near = near;
        tri_attribute_near = attribute_near;
        gl_Layer = map_index[0];
        gl_Position = vec4((v & 1) == 0 ? lo.x : hi.x, v < 2 ? lo.y : hi.y, 0.5, 1.0);
        for (int c = 0; c < 8; ++c) gl_ClipDistance[c] = 1.0;
        EmitVertex();
    }
    EndPrimitive();
}
