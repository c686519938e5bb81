/* Bischoff 2017 sec. 4: select VALs with probability proportional to the importance map by binary
   search in the cumulative sums of eq. 12, the twin of gim_importance_select. One invocation
   per selected VAL i: u = i / count and v = van der Corput(i), both rotated by the seed's
   Cranley-Patterson offsets (computed on the CPU, in double); the column comes from u in the
   horizontal sums, the texel from v in that column's vertical sums; P = P(column) P(row | column). */
layout(local_size_x = 64) in;

layout(std430, binding = 1) readonly buffer ColumnSums { double column[]; };   /* width * height */
layout(std430, binding = 3) readonly buffer RowSums { double row[]; };         /* width */
struct SelectedVal { uint x; uint y; float pdf; };                               /* = gim_selected_val */
layout(std430, binding = 4) writeonly buffer Selected { SelectedVal selected[]; };

layout(location = 0) uniform uvec2 size;     /* width, height */
layout(location = 1) uniform uint count;
layout(location = 2) uniform dvec2 offsets;  /* Cranley-Patterson rotation of (u, v) */

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
        selected[i].x = min(uint(u * double(width)), width - 1u);
        selected[i].y = min(uint(v * double(height)), height - 1u);
        selected[i].pdf = float(1.0LF / (double(width) * double(height)));
        return;
    }
    uint last = (height - 1u) * width;
    uint sx = first_above_row(width, below(u * total, total));
    double col_total = column[last + sx];
    uint sy = first_above_column(sx, width, height, below(v * col_total, col_total));
    double p_col = (row[sx] - (sx > 0u ? row[sx - 1u] : 0.0LF)) / total;
    double p_row = (column[sy * width + sx] - (sy > 0u ? column[(sy - 1u) * width + sx] : 0.0LF)) / col_total;
    double p = p_col * p_row;
    selected[i].x = sx;
    selected[i].y = sy;
    /* p <= 0 only from tables that are not cumulative sums (a NaN in the map): pdf 0 marks it */
    selected[i].pdf = p > 0.0LF ? max(float(p), FLT_MIN) : 0.0;
}
