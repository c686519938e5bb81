/* View samples (Bischoff 2017 sec. 4): the G-buffer at the Halton pixels the CPU computed
   (gim_view_sample_pixels), unprojected to world space through the inverses of proj and view,
   written as {vec4 position; vec4 normal} for the importance pass. Where nothing was drawn
   (depth 1) or the normal is zero or not finite the sample is unusable: zero normal. */
#include "common.glsl"
layout(local_size_x = 64) in;

layout(binding = 0) uniform sampler2D gbuffer_depth;
layout(binding = 1) uniform sampler2D gbuffer_normal;   /* world normal in xyz */

layout(std430, binding = 0) readonly buffer Pixels { uvec2 pixel[]; };
struct ViewSample { vec4 position; vec4 normal; };
layout(std430, binding = 1) writeonly buffer ViewSamples { ViewSample view_sample[]; };

layout(location = 0) uniform uint count;
layout(location = 1) uniform uvec2 size;
layout(location = 2) uniform mat4 inv_proj;
layout(location = 3) uniform mat4 inv_view;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    ivec2 p = ivec2(pixel[i]);
    float depth = texelFetch(gbuffer_depth, p, 0).r;
    vec3 n = texelFetch(gbuffer_normal, p, 0).xyz;
    ViewSample s;
    s.position = vec4(0.0);
    s.normal = vec4(0.0);
    if (depth < 1.0 && finite3(n) && dot(n, n) > 0.0) {
        s.position = vec4(unproject(p, depth, size, inv_proj, inv_view), 1.0);
        s.normal = vec4(normalize(n), 0.0);
    }
    view_sample[i] = s;
}
