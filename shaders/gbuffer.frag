/* gimany's own G-buffer: the world normal turned towards the eye (two-sided; w = 1 where a
   surface was drawn), the diffuse albedo and the material id (for the glossy colour and
   exponent of the shading pass); depth goes to the depth attachment. */
layout(early_fragment_tests) in;   /* the counts below see only fragments that pass the depth test */

in vec3 world_position;
in vec3 world_normal;

layout(location = 0) out vec4 out_normal;
layout(location = 1) out vec4 out_albedo;
layout(location = 2) out float out_material;   /* R32F: ids up to 2^24 are exact */

struct Material { vec4 diffuse; vec4 glossy; };
layout(std430, binding = 0) readonly buffer Materials { Material material[]; };
layout(std430, binding = 1) readonly buffer TriangleMaterial { uint triangle_material[]; };

layout(location = 3) uniform uint material_count;
layout(location = 4) uniform vec4 eye;       /* perspective: (position, 1); orthographic: (direction to the eye, 0) */
/* 1: count the fragments drawn ([0]) and those seen from behind their normal ([1]); LightSkin's
   caches are one-sided, so a mesh with flipped normals gets no indirect light there */
layout(location = 5) uniform uint count_facing;
layout(std430, binding = 2) buffer Facing { uint facing[2]; };

void main() {
    uint id = min(triangle_material[gl_PrimitiveID], material_count - 1u);
    vec3 toward = eye.w > 0.0 ? eye.xyz - world_position : eye.xyz;
    vec3 n = normalize(world_normal);
    bool back = dot(n, toward) < 0.0;
    out_normal = vec4(back ? -n : n, 1.0);
    if (count_facing != 0u) {
        atomicAdd(facing[0], 1u);
        if (back) atomicAdd(facing[1], 1u);
    }
    out_albedo = vec4(material[id].diffuse.rgb, 1.0);
    out_material = float(id);
}
