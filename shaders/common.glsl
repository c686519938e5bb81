/* What several shaders share: constants, float tests made on the bits, gim_basis, the imperfect
   shadow maps' texel format and rays, the G-buffer's unprojection. tools/embed_shaders.c puts
   this file in place of a shader's line `#include "common.glsl"`, its first include (compiler
   messages give the lines here as 10000 + line). The compiler drops what a shader does not call. */

const float PI = 3.14159265358979323846;
const float FLT_MAX = 3.402823466e+38;
const uint SIGN = 0x80000000u, EXPONENT = 0x7f800000u;   /* a float's sign and exponent bits */

/* Finite: exponent bits, not isinf/isnan, which fast-math may fold away. */
bool finite3(vec3 v) {
    uvec3 e = (floatBitsToUint(v) >> 23) & 0xffu;
    return all(notEqual(e, uvec3(0xffu)));
}
bool finite3(uvec3 b) { return all(notEqual(b & EXPONENT, uvec3(EXPONENT))); }   /* on the bits */

/* The twins' x >= 0 on a finite x: +x or -0 (on the bits: a GPU that flushes denormals would
   get a float compare wrong for -1e-40) */
bool nonneg3(uvec3 b) {
    return all(bvec3((b.x & SIGN) == 0u || b.x == SIGN, (b.y & SIGN) == 0u || b.y == SIGN,
                     (b.z & SIGN) == 0u || b.z == SIGN));
}
bool nonneg3(vec3 x) { return nonneg3(floatBitsToUint(x)); }

/* x > 0 and not NaN (+Inf counts), on the bits: the lit flag of an RSM texel or a hit */
bool positive(uint b) { return (b & SIGN) == 0u && b != 0u && b <= EXPONENT; }

/* gim_basis (Duff et al. 2017): t, b such that (t, b, n) is orthonormal, n a unit vector */
void basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

/* basis() with every step `precise`, so that no multiply-add is fused: for the lookups that
   follow their twins' float steps */
void basis_precise(vec3 n, out vec3 t, out vec3 b) {
    precise float s = n.z >= 0.0 ? 1.0 : -1.0;
    precise float a = -1.0 / (s + n.z);
    precise float c = n.x * n.y * a;
    precise vec3 pt = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    precise vec3 pb = vec3(c, s + n.y * n.y * a, -n.y);
    t = pt;
    b = pb;
}

/* Imperfect shadow maps (Ritschel et al. 2008): size x size texels in the hemisphere of the
   map's frame (t, b, n) under the paraboloid map, each texel the distance to the nearest
   point, stored in 16 bits: the upper half of its float's bits rounded to nearest
   (gim_ism_quantize), two to a uint, texel 2k in the low half (ism.comp writes them). */
const float ISM_EMPTY = 3.0e38;   /* a texel no point reached */
const float ISM_MAX_TAN = 8.0;    /* the lookup's slope bias stops at this tan of the VAL's angle */

/* Two texels' float bits (positive floats) into one uint. */
uint ism_pack(uint lo, uint hi) { return ((lo + 0x8000u) >> 16) | (((hi + 0x8000u) >> 16) << 16); }

/* Texel `texel` of the map's uint `word` that holds it (gim_ism_dequantize: its bits shifted up). */
float ism_unpack(uint word, uint texel) {
    return uintBitsToFloat((texel & 1u) != 0u ? word & 0xffff0000u : word << 16u);
}

/* The texel of direction d (length dist) as gim__ism_texel; -1 behind the map's plane. */
int ism_texel_index(vec3 d, float dist, uint size, vec3 t, vec3 b, vec3 n) {
    float wz = (d.x * n.x + d.y * n.y + d.z * n.z) / dist;
    if (!(wz > 0.0)) return -1;
    float wx = (d.x * t.x + d.y * t.y + d.z * t.z) / dist;
    float wy = (d.x * b.x + d.y * b.y + d.z * b.z) / dist;
    float fs = float(size);
    float fx = floor((wx / (1.0 + wz) + 1.0) * 0.5 * fs);
    float fy = floor((wy / (1.0 + wz) + 1.0) * 0.5 * fs);
    int ix = fx < 0.0 ? 0 : fx > float(size - 1u) ? int(size) - 1 : int(fx);
    int iy = fy < 0.0 ? 0 : fy > float(size - 1u) ? int(size) - 1 : int(fy);
    return iy * int(size) + ix;
}

/* Texel tx's centre ray as gim__ism_texel_ray. */
vec3 ism_texel_ray(int tx, uint size, vec3 t, vec3 b, vec3 n) {
    float fs = float(size);
    float u = (2.0 * float(tx % int(size)) + 1.0) / fs - 1.0;
    float v = (2.0 * float(tx / int(size)) + 1.0) / fs - 1.0;
    float r2 = u * u + v * v;
    float k = 1.0 / (1.0 + r2);
    vec3 w = vec3(2.0 * u * k, 2.0 * v * k, (1.0 - r2) * k);
    return vec3(w.x * t.x + w.y * b.x + w.z * n.x, w.x * t.y + w.y * b.y + w.z * n.y,
                w.x * t.z + w.y * b.z + w.z * n.z);
}

/* The world position of the G-buffer's pixel px (of size) at window depth `depth`, through
   the inverses of the camera's projection and view. */
vec3 unproject(ivec2 px, float depth, uvec2 size, mat4 inv_proj, mat4 inv_view) {
    vec4 ndc = vec4((vec2(px) + 0.5) / vec2(size) * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    vec4 v = inv_proj * ndc;
    v /= v.w;
    return (inv_view * vec4(v.xyz, 1.0)).xyz;
}
