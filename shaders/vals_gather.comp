/* The VAL list of one light (Bischoff 2017 sec. 3: every RSM texel is a virtual area light; sec. 4
   eq. 13-15: a selected one weighs 1 / (N P)), the GPU twin of gim_vals_gather_twin. One invocation
   per VAL i < count, written to val[first + i]:
     brsm == 0 (FULL): texel (i % size, i / size), row-major, row 0 first, weight 1;
     brsm == 1 (BRSM): texel selected[i], weight 1 / (count * pdf), in double like the twin.
   The RSM is read as rgba32ui images of its RGBA32F textures, so each value moves bit for bit
   into the VAL (the twin's memcpy; no float path that could flush a denormal), and every test
   of the twin is made on the bits (no isnan/isinf, which fast-math may fold away, and no
   float compare, which a GPU that flushes denormals would get wrong for a -1e-40 flux).
   An invalid texel (lit flag position.w not > 0, a NaN/Inf, a negative area or flux) becomes
   an all-zero VAL, as in the twin. So does a selected entry outside the RSM or with a pdf
   that is not finite and > 0, which the twin reports as an error and a shader cannot. */
#include "common.glsl"
layout(local_size_x = 64) in;

layout(binding = 0, rgba32ui) readonly uniform uimage2D rsm_position;  /* xyz; w > 0: lit */
layout(binding = 1, rgba32ui) readonly uniform uimage2D rsm_normal;    /* xyz; w = area A */
layout(binding = 2, rgba32ui) readonly uniform uimage2D rsm_flux;      /* rgb */

struct SelectedVal { uint x; uint y; uint pdf; };   /* gim_selected_val, pdf as its float bits */
layout(std430, binding = 0) readonly buffer Selected { SelectedVal selected[]; };
struct Val { uvec4 position_area; uvec4 normal_weight; uvec4 flux; };   /* gim_val, as bits */
layout(std430, binding = 1) buffer Vals { Val val[]; };   /* read only in VPL mode, each slot by its own invocation */

layout(location = 0) uniform uint size;    /* RSM side */
layout(location = 1) uniform uint count;   /* VALs to write: size^2 (FULL) or selected_count */
layout(location = 2) uniform uint first;   /* index of the first one in val[] */
layout(location = 3) uniform uint brsm;    /* 1: one VAL per selected entry */
/* 1: write each as a first-bounce VPL instead (gim_vpl, the VPL methods' vpl.importance;
   gim_vpls_from_vals): position and lit 1, normal and area w A, flux w Phi, each product one
   float multiply as in the twin; an invalid VAL an all-zero (unlit) VPL. 2: the same, and kept
   1 where the slot's last VPL (what val[first + i] holds) was lit at the same position and
   normal, bit for bit: its imperfect shadow map still holds (the twin's previous) */
layout(location = 4) uniform uint vpl;

const uint FLT_MAX_BITS = 0x7f7fffffu;
const uint FLT_MIN_BITS = 0x00800000u;

bool finite(uint b) { return (b & EXPONENT) != EXPONENT; }
/* the twin's x >= 0 on a finite x: +x, or -0 */
bool nonneg(uint b) { return (b & SIGN) == 0u || b == SIGN; }

/* The exact value of a finite float from its bits, denormals included. */
double exact(uint b) {
    uint e = (b >> 23) & 0xffu, m = b & 0x7fffffu;
    double v = ldexp(double(e == 0u ? m : (m | 0x800000u)), int(max(e, 1u)) - 150);
    return (b & SIGN) != 0u ? -v : v;
}

/* The twin's gim__clamp_flt: x < FLT_MAX ? (float)x : FLT_MAX, as bits (x > 0); a result
   below FLT_MIN is rounded to its denormal by hand, not left to a conversion that may flush it. */
uint clamp_flt_bits(double x) {
    if (!(x < exact(FLT_MAX_BITS))) return FLT_MAX_BITS;
    if (x < exact(FLT_MIN_BITS)) return uint(roundEven(ldexp(x, 149)));   /* <= 2^23 = FLT_MIN */
    return floatBitsToUint(float(x));
}

void main() {
    uint i = gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * gl_WorkGroupSize.x) + gl_GlobalInvocationID.x;
    if (i >= count) return;
    uvec2 t = uvec2(i % size, i / size);
    uint weight = floatBitsToUint(1.0);
    bool ok = true;
    if (brsm != 0u) {
        SelectedVal s = selected[i];
        t = uvec2(s.x, s.y);
        /* pdf finite and > 0: sign clear, not 0, exponent not all ones (denormals count) */
        ok = s.x < size && s.y < size && s.pdf != 0u && s.pdf < EXPONENT;
        if (ok) weight = clamp_flt_bits(1.0LF / (double(count) * exact(s.pdf)));   /* eq. 13-15: 1 / (N P) */
    }
    Val v;
    v.position_area = uvec4(0u);
    v.normal_weight = uvec4(0u);
    v.flux = uvec4(0u);
    if (ok) {
        ivec2 p = ivec2(t);
        uvec4 x = imageLoad(rsm_position, p), n = imageLoad(rsm_normal, p), f = imageLoad(rsm_flux, p);
        /* lit: position.w > 0 (sign clear, not 0, not NaN) */
        if (positive(x.w) && finite3(x.xyz) && finite3(n.xyz) && finite3(f.rgb) && finite(n.w) && nonneg(n.w) &&
            nonneg3(f.rgb)) {
            v.position_area = uvec4(x.xyz, n.w);
            v.normal_weight = uvec4(n.xyz, weight);
            v.flux = uvec4(f.rgb, 0u);
        }
    }
    if (vpl != 0u && v.normal_weight.w == 0u) {   /* weight 0 (invalid, or 1 / (N P) below the floats): unlit */
        v.position_area = uvec4(0u);
        v.normal_weight = uvec4(0u);
        v.flux = uvec4(0u);
    } else if (vpl != 0u) {
        uint kept = 0u;
        if (vpl == 2u) {
            Val p = val[first + i];
            kept = p.position_area.w == floatBitsToUint(1.0) && all(equal(p.position_area.xyz, v.position_area.xyz)) &&
                   all(equal(p.normal_weight.xyz, v.normal_weight.xyz)) ? floatBitsToUint(1.0) : 0u;
        }
        precise float w = uintBitsToFloat(v.normal_weight.w);
        precise float a = uintBitsToFloat(v.position_area.w) * w;
        precise vec3 phi = uintBitsToFloat(v.flux.rgb) * w;
        v.position_area.w = floatBitsToUint(1.0);
        v.normal_weight.w = floatBitsToUint(a);
        v.flux = uvec4(floatBitsToUint(phi), kept);
    }
    val[first + i] = v;
}
