/* The scene's triangles for the RSM and G-buffer passes: world position and normal. The
   normal matrix (inverse transpose of the model's 3x3) keeps normals perpendicular to
   surfaces under non-uniform scales. Every clip distance GL 4.3 guarantees (8) is written
   positive, so the planes a host left enabled clip nothing (gimany does not save them). */
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;

layout(location = 0) uniform mat4 model;
layout(location = 1) uniform mat4 normal_matrix;
layout(location = 2) uniform mat4 view_proj;

out vec3 world_position;
out vec3 world_normal;
out float gl_ClipDistance[8];

void main() {
    vec4 w = model * vec4(position, 1.0);
    world_position = w.xyz;
    world_normal = mat3(normal_matrix) * normal;
    gl_Position = view_proj * w;
    for (int c = 0; c < 8; ++c) gl_ClipDistance[c] = 1.0;
}
