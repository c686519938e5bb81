/* Bischoff 2017 eq. 12, first level: the vertical (per-column) cumulative sums of the importance
   map, inclusive, in double, inside blocks of block_rows rows; each block's total goes to
   block_total. One invocation per (column, block): O(width * height) adds in all, and
   width * ceil(height / block_rows) invocations in flight. Double, because a float sum of a
   4096-texel column keeps only ~1e-4 of the column total in the small texels' terms. */
layout(local_size_x = 64) in;

layout(std430, binding = 0) readonly buffer ImportanceMap { float map[]; };       /* width * height */
layout(std430, binding = 1) writeonly buffer ColumnSums { double column[]; };     /* width * height */
layout(std430, binding = 2) writeonly buffer BlockTotals { double block_total[]; }; /* blocks * width */

layout(location = 0) uniform uvec2 size;       /* width, height */
layout(location = 1) uniform uint block_rows;

void main() {
    uint x = gl_GlobalInvocationID.x, b = gl_GlobalInvocationID.y;
    uint y0 = b * block_rows;
    if (x >= size.x || y0 >= size.y) return;
    uint y1 = min(y0 + block_rows, size.y);
    double s = 0.0LF;
    for (uint y = y0; y < y1; ++y) {
        s += double(map[y * size.x + x]);
        column[y * size.x + x] = s;
    }
    block_total[b * size.x + x] = s;
}
