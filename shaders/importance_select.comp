/* Bischoff 2017 sec. 4: select VALs with probability proportional to the importance map by binary
   search in the cumulative sums of eq. 12, the twin of gim_importance_select. One invocation
   per selected VAL i: u = i / count and v = van der Corput(i), both rotated by the seed's
   Cranley-Patterson offsets (computed on the CPU, in double); the column comes from u in the
   horizontal sums, the texel from v in that column's vertical sums; P = P(column) P(row | column).
   Two levels (tile > 1): the tables are of the tile map (importance_tiles.comp); the residual of v
   in the picked tile's interval then picks a texel of the tile by its weight (first running sum
   in row-major order above residual * the tile's sum, in double as the twin), P times weight / sum.
   Defensive share (defensive > 0): the last `defensive` invocations pick from the second set of
   tables, of the texels' luminance (same layout), as a Hammersley set of their own, and every
   pdf is the mixture's, (N_1 P_importance + N_2 P_luminance) / count (the balance heuristic's
   multi-sample estimator), so a texel of little importance but much light weighs at most
   count / N_2 times its share of the RSM's luminance. */
layout(local_size_x = 64) in;

layout(std430, binding = 1) readonly buffer ColumnSums { double column[]; };   /* width * height */
layout(std430, binding = 3) readonly buffer RowSums { double row[]; };         /* width */
struct SelectedVal { uint x; uint y; float pdf; };                               /* = gim_selected_val */
layout(std430, binding = 4) writeonly buffer Selected { SelectedVal selected[]; };
layout(std430, binding = 0) readonly buffer Weights { float weight[]; };        /* tile > 1: rsm_size texels */
layout(std430, binding = 5) readonly buffer LumColumnSums { double lum_column[]; };   /* defensive > 0: as column */
layout(std430, binding = 6) readonly buffer LumRowSums { double lum_row[]; };         /* defensive > 0: as row */
layout(std430, binding = 7) readonly buffer LumWeights { float lum_weight[]; };       /* defensive > 0, tile > 1 */

layout(location = 0) uniform uvec2 size;     /* width, height */
layout(location = 1) uniform uint count;
layout(location = 2) uniform dvec2 offsets;  /* Cranley-Patterson rotation of (u, v) */
layout(location = 3) uniform uint tile;      /* 1: the tables are per texel; > 1: per tile x tile texels */
layout(location = 4) uniform uvec2 rsm_size; /* tile > 1: the RSM's width, height in texels */
layout(location = 5) uniform uint defensive; /* N_2: the last N_2 of count pick by luminance */

const float FLT_MIN = 1.175494351e-38;

/* Table set l (0: importance, 1: luminance). */
double col(uint l, uint k) { return l == 0u ? column[k] : lum_column[k]; }
double rowv(uint l, uint k) { return l == 0u ? row[k] : lum_row[k]; }
double wgt(uint l, uint k) { return double(l == 0u ? weight[k] : lum_weight[k]); }

/* First k in [0, n) with col(l, base + k * stride) > t (t below the last entry). */
uint first_above_column(uint l, uint base, uint stride, uint n, double t) {
    uint lo = 0u, hi = n - 1u;
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (col(l, base + mid * stride) > t) hi = mid; else lo = mid + 1u;
    }
    return lo;
}
uint first_above_row(uint l, uint n, double t) {
    uint lo = 0u, hi = n - 1u;
    while (lo < hi) {
        uint mid = lo + (hi - lo) / 2u;
        if (rowv(l, mid) > t) hi = mid; else lo = mid + 1u;
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

/* The sum of tile (tx, ty)'s weights of set l, in row-major order. */
double tile_sum(uint l, uvec2 tp) {
    uvec2 t0 = tp * tile, t1 = min(t0 + tile, rsm_size);
    double sum = 0.0LF;
    for (uint y = t0.y; y < t1.y; ++y)
        for (uint x = t0.x; x < t1.x; ++x) sum += wgt(l, y * rsm_size.x + x);
    return sum;
}

/* The probability set l's tables give texel s (an RSM texel when tile > 1): 0 where they
   cannot pick it. */
double pdf_at(uint l, uvec2 s) {
    uint width = size.x;
    double total = rowv(l, width - 1u);
    if (!(total > 0.0LF)) return 0.0LF;
    uvec2 tp = s / tile;
    double col_total = col(l, (size.y - 1u) * width + tp.x);
    if (!(col_total > 0.0LF)) return 0.0LF;
    double p = (rowv(l, tp.x) - (tp.x > 0u ? rowv(l, tp.x - 1u) : 0.0LF)) / total *
               ((col(l, tp.y * width + tp.x) - (tp.y > 0u ? col(l, (tp.y - 1u) * width + tp.x) : 0.0LF)) / col_total);
    if (tile > 1u && p > 0.0LF) {
        double sum = tile_sum(l, tp), w = wgt(l, s.y * rsm_size.x + s.x);
        p = sum > 0.0LF ? p * (w / sum) : 0.0LF;
    }
    return p;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) return;
    uint width = size.x, height = size.y;
    /* no luminance tables' total (tables that cannot be the map's): no defensive share */
    uint n2 = defensive > 0u && lum_row[width - 1u] > 0.0LF ? defensive : 0u, n1 = count - n2;
    uint l = i < n1 ? 0u : 1u, k = i < n1 ? i : i - n1, n = i < n1 ? n1 : n2;
    double total = rowv(l, width - 1u);
    double u = double(k) / double(n) + offsets.x;
    double v = double(bitfieldReverse(k)) * (1.0LF / 4294967296.0LF) + offsets.y;
    u = u < 1.0LF ? u : u - 1.0LF;
    v = v < 1.0LF ? v : v - 1.0LF;
    if (!(row[width - 1u] > 0.0LF)) {   /* all-zero map: every pick uniform, pdf 1 / texels (still unbiased) */
        uvec2 m = tile > 1u ? rsm_size : size;
        selected[i].x = min(uint(u * double(m.x)), m.x - 1u);
        selected[i].y = min(uint(v * double(m.y)), m.y - 1u);
        selected[i].pdf = float(1.0LF / (double(m.x) * double(m.y)));
        return;
    }
    uint last = (height - 1u) * width;
    uint sx = first_above_row(l, width, below(u * total, total));
    double col_total = col(l, last + sx);
    double t = below(v * col_total, col_total);
    uint sy = first_above_column(l, sx, width, height, t);
    double lo = sy > 0u ? col(l, (sy - 1u) * width + sx) : 0.0LF, hi = col(l, sy * width + sx);
    double p_col = (rowv(l, sx) - (sx > 0u ? rowv(l, sx - 1u) : 0.0LF)) / total;
    double p_row = (hi - lo) / col_total;
    double p = p_col * p_row;
    if (tile > 1u && p > 0.0LF) {
        double res = (t - lo) / (hi - lo);
        res = res < 1.0LF ? (res > 0.0LF ? res : 0.0LF) : 0.0LF;
        uvec2 t0 = uvec2(sx, sy) * tile, t1 = min(t0 + tile, rsm_size);
        double sum = tile_sum(l, uvec2(sx, sy));
        /* the first texel whose running sum exceeds res * sum; past the end by rounding: the last
           texel of positive weight */
        double target = res * sum, acc = 0.0LF, w = 0.0LF;
        uvec2 pick = t0;
        bool found = false;
        for (uint y = t0.y; y < t1.y; ++y)
            for (uint x = t0.x; x < t1.x; ++x)
                if (!found) {
                    double wt = wgt(l, y * rsm_size.x + x);
                    acc += wt;
                    if (wt > 0.0LF) { pick = uvec2(x, y); w = wt; }
                    found = acc > target;
                }
        /* a tile whose weights sum to 0 or NaN (weights that are not the tile map's): pdf 0 marks it */
        p = sum > 0.0LF && w > 0.0LF ? p * (w / sum) : 0.0LF;
        sx = pick.x;
        sy = pick.y;
    }
    /* the mixture's pdf: the other set's probability of the same texel */
    if (n2 > 0u && p > 0.0LF) {
        double q = pdf_at(1u - l, uvec2(sx, sy));
        p = l == 0u ? (double(n1) * p + double(n2) * q) / double(count) : (double(n1) * q + double(n2) * p) / double(count);
    }
    selected[i].x = sx;
    selected[i].y = sy;
    /* p <= 0 only from tables that are not cumulative sums (a NaN in the map): pdf 0 marks it */
    selected[i].pdf = p > 0.0LF ? max(float(p), FLT_MIN) : 0.0;
}
