/* The scene's triangles for the paraboloid maps (Dong sec. 4.2, SSVP sec. 3.C): world
   position and normal, and the instance as the map (layer) the triangle is drawn into. */
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;

layout(location = 0) uniform mat4 model;
layout(location = 1) uniform mat4 normal_matrix;

out vec3 world_position;
out vec3 world_normal;
flat out int map_index;

void main() {
    vec4 w = model * vec4(position, 1.0);
    world_position = w.xyz;
    world_normal = mat3(normal_matrix) * normal;
    map_index = gl_InstanceID;
    gl_Position = w;
}
