/* Bischoff 2017 sec. 4: select VALs with probability proportional to the importance map by binary
   search in the cumulative sums of eq. 12, the twin of gim_importance_select. One invocation
   per selected VAL i: u = i / count and v = van der Corput(i), both rotated by the seed's
   Cranley-Patterson offsets (computed on the CPU, in double); the column comes from u in the
   horizontal sums, the texel from v in that column's vertical sums; P = P(column) P(row | column).
   Two levels (tile > 1): the tables are of the tile map (importance_tiles.comp); the residual of v
   in the picked tile's interval then picks a texel of the tile by its weight (first running sum
   in row-major order above residual * the tile's sum, in double as the twin), P times weight / sum. */
layout(local_size_x = 64) in;

layout(std430, binding = 1) readonly buffer ColumnSums { double column[]; };   /* width * height */
layout(std430, binding = 3) readonly buffer RowSums { double row[]; };         /* width */
struct SelectedVal { uint x; uint y; float pdf; };                               /* = gim_selected_val */
layout(std430, binding = 4) writeonly buffer Selected { SelectedVal selected[]; };
layout(std430, binding = 0) readonly buffer Weights { float weight[]; };        /* tile > 1: rsm_size texels */

layout(location = 0) uniform uvec2 size;     /* width, height */
layout(location = 1) uniform uint count;
layout(location = 2) uniform dvec2 offsets;  /* Cranley-Patterson rotation of (u, v) */
layout(location = 3) uniform uint tile;      /* 1: the tables are per texel; > 1: per tile x tile texels */
layout(location = 4) uniform uvec2 rsm_size; /* tile > 1: the RSM's width, height in texels */

const float FLT_MIN = 1.175494351e-38;

/* First k in [0, n) with column[base + k * stride] > t (t below the last entry). */
uint first_above_column(uint base, uint stride, uint n, double t) {
    uint lo = 0u, hi = n - 1u;
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (column[base + mid * stride] > t) hi = mid; else lo = mid + 1u;
    }
    return lo;
}
uint first_above_row(uint n, double t) {
    uint lo = 0u, hi = n - 1u;
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (row[mid] > t) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

/* t, or the largest double below total when u * total rounded up to total (total > 0). */
double below(double t, double total) {
    if (t < total) return t;
    uvec2 b = unpackDouble2x32(total);
    if (b.x == 0u) { b.x = 0xffffffffu; b.y -= 1u; } else b.x -= 1u;
    return packDouble2x32(b);
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    uint width = size.x, height = size.y;
    double total = row[width - 1u];
    double u = double(i) / double(count) + offsets.x;
    double v = double(bitfieldReverse(i)) * (1.0LF / 4294967296.0LF) + offsets.y;
    u = u < 1.0LF ? u : u - 1.0LF;
    v = v < 1.0LF ? v : v - 1.0LF;
    if (!(total > 0.0LF)) {   /* all-zero map: uniform, pdf 1 / texels (still unbiased) */
        uvec2 n = tile > 1u ? rsm_size : size;
        selected[i].x = min(uint(u * double(n.x)), n.x - 1u);
        selected[i].y = min(uint(v * double(n.y)), n.y - 1u);
        selected[i].pdf = float(1.0LF / (double(n.x) * double(n.y)));
        return;
    }
    uint last = (height - 1u) * width;
    uint sx = first_above_row(width, below(u * total, total));
    double col_total = column[last + sx];
    double t = below(v * col_total, col_total);
    uint sy = first_above_column(sx, width, height, t);
    double lo = sy > 0u ? column[(sy - 1u) * width + sx] : 0.0LF, hi = column[sy * width + sx];
    double p_col = (row[sx] - (sx > 0u ? row[sx - 1u] : 0.0LF)) / total;
    double p_row = (hi - lo) / col_total;
    double p = p_col * p_row;
    if (tile > 1u && p > 0.0LF) {
        double res = (t - lo) / (hi - lo);
        res = res < 1.0LF ? (res > 0.0LF ? res : 0.0LF) : 0.0LF;
        uvec2 t0 = uvec2(sx, sy) * tile, t1 = min(t0 + tile, rsm_size);
        double sum = 0.0LF;
        for (uint y = t0.y; y < t1.y; ++y)
            for (uint x = t0.x; x < t1.x; ++x) sum += double(weight[y * rsm_size.x + x]);
        /* the first texel whose running sum exceeds res * sum; past the end by rounding: the last
           texel of positive weight */
        double target = res * sum, acc = 0.0LF, w = 0.0LF;
        uvec2 pick = t0;
        bool found = false;
        for (uint y = t0.y; y < t1.y; ++y)
            for (uint x = t0.x; x < t1.x; ++x)
                if (!found) {
                    double wt = double(weight[y * rsm_size.x + x]);
                    acc += wt;
                    if (wt > 0.0LF) { pick = uvec2(x, y); w = wt; }
                    found = acc > target;
                }
        /* a tile whose weights sum to 0 or NaN (weights that are not the tile map's): pdf 0 marks it */
        p = sum > 0.0LF && w > 0.0LF ? p * (w / sum) : 0.0LF;
        sx = pick.x;
        sy = pick.y;
    }
    selected[i].x = sx;
    selected[i].y = sy;
    /* p <= 0 only from tables that are not cumulative sums (a NaN in the map): pdf 0 marks it */
    selected[i].pdf = p > 0.0LF ? max(float(p), FLT_MIN) : 0.0;
}
