/* Bischoff 2017 eq. 12, last level: add each block's offset to its block-local column sums, so
   column[y * width + x] = sum of map(x, 0..y). One invocation per texel. */
layout(local_size_x = 16, local_size_y = 16) in;

layout(std430, binding = 1) buffer ColumnSums { double column[]; };             /* width * height */
layout(std430, binding = 2) readonly buffer BlockOffsets { double block_offset[]; }; /* blocks * width */

layout(location = 0) uniform uvec2 size;       /* width, height */
layout(location = 1) uniform uint block_rows;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= size.x || p.y >= size.y || p.y < block_rows) return;   /* block 0's offset is 0 */
    column[p.y * size.x + p.x] += block_offset[(p.y / block_rows) * size.x + p.x];
}
