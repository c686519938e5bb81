/* Bischoff 2017 eq. 12, second level, in one work group: per column, the block totals become
   exclusive block offsets (sequentially down the column, as the CPU sums); the column totals
   then give the horizontal cumulative sums row[x] = sum of column totals 0..x. Each invocation
   scans a contiguous run of columns, then the runs' sums are scanned in shared memory
   (serially, see below). */
#define THREADS 256
layout(local_size_x = THREADS) in;

layout(std430, binding = 2) buffer BlockTotals { double block_total[]; };   /* blocks * width: totals in, offsets out */
layout(std430, binding = 3) buffer RowSums { double row[]; };               /* width */

layout(location = 0) uniform uvec2 size;       /* width, height */
layout(location = 1) uniform uint block_rows;

shared double run_sum[THREADS];

void main() {
    uint t = gl_LocalInvocationID.x;
    uint width = size.x, blocks = (size.y + block_rows - 1u) / block_rows;
    uint per = (width + THREADS - 1u) / THREADS;
    uint x0 = min(t * per, width), x1 = min(x0 + per, width);
    double run = 0.0LF;
    for (uint x = x0; x < x1; ++x) {
        double offset = 0.0LF;
        for (uint b = 0u; b < blocks; ++b) {
            double total = block_total[b * width + x];
            block_total[b * width + x] = offset;
            offset += total;
        }
        run += offset;              /* offset is now the column total */
        row[x] = run;
    }
    run_sum[t] = run;
    barrier();
    /* exclusive scan of the runs, serially (256 adds): before_t = before_(t-1) + run_(t-1) is
       then bit for bit the last row[] that invocation t-1 wrote, so row[] never decreases at
       a run's edge (a tree scan rounds differently and could dip by an ulp after a column of
       zero importance, which gim_importance_select rejects as "not a cumulative sum") */
    if (t == 0u) {
        double acc = 0.0LF;
        for (uint i = 0u; i < uint(THREADS); ++i) {
            double r = run_sum[i];
            run_sum[i] = acc;
            acc += r;
        }
    }
    barrier();
    double before = run_sum[t];
    if (t > 0u)
        for (uint x = x0; x < x1; ++x) row[x] += before;
}
