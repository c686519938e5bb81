/* VPLs from an RSM (Dong et al. sec. 4), the GPU twin of gim_rsm_vpls_twin: VPL i on the texel
   texel[i] (the Halton texels, computed on the CPU by the twin's own function), with its
   position and normal and the texel's flux times T / S per channel: T the RSM's total over
   the lit texels, S the sum over the VPLs' texels; its area (normal.w, the near field's patch)
   the texel's footprint times (T_r + T_g + T_b) / (S_r + S_g + S_b). Four modes, one dispatch each (the sums
   pass through the scratch buffer `sums` between them, every loop under Mesa llvmpipe's 65535
   iterations per invocation):
     0: invocation y < size sums row y's lit flux into sums[y] (in double, x order); invocation
        i < count writes VPL i with its texel's raw flux (0 where unlit);
     1: invocation b sums the raw flux of VPLs [b BLOCK, (b + 1) BLOCK) into sums[size + b];
     2: invocation 0 sums the rows (T) and the blocks (S), writes T / S (0 where S = 0) and the
        areas' factor to sums[size + blocks];
     3: invocation i < count multiplies VPL i's flux and area by them.
   The same order of sums as the twin, in double. Lit: position.w > 0 and position, normal,
   flux finite with flux >= 0 (read as bits, so no fast-math folds the tests away).
   follow (incremental instant radiosity, Laine et al. 2007; gim_rsm_vpls_desc.previous): mode 0
   reads VPL i as the last frame left it and keeps it where follow() finds its texel now: its
   position and normal stay, flux and area come from that texel, flux.w = 1 (its imperfect
   shadow map stays too: ism.comp's vpl_mode 2); else the slot's texel as without, flux.w = 0. */
#include "common.glsl"
layout(local_size_x = 64) in;

layout(binding = 0, rgba32ui) readonly uniform uimage2D rsm_position;  /* xyz; w > 0: lit */
layout(binding = 1, rgba32ui) readonly uniform uimage2D rsm_normal;    /* xyz; w = area A */
layout(binding = 2, rgba32ui) readonly uniform uimage2D rsm_flux;      /* rgb */

layout(std430, binding = 0) readonly buffer Texels { uvec4 texel[]; };   /* x, y, keep radius (float bits), 0 */
struct Vpl { vec4 position; vec4 normal; vec4 flux; };   /* w: lit 1 / 0; area; kept 1 / 0 */
layout(std430, binding = 1) buffer Vpls { Vpl vpl[]; };
layout(std430, binding = 2) buffer Sums { dvec4 sums[]; };

layout(location = 0) uniform uint size;    /* RSM side */
layout(location = 1) uniform uint count;   /* VPLs */
layout(location = 2) uniform uint mode;
layout(location = 3) uniform uint block;   /* VPLs per block sum of mode 1 (GIM_RSM_VPL_BLOCK) */
layout(location = 4) uniform uint follow;  /* 1: vpl[] holds the last frame's VPLs of these slots */
layout(location = 5) uniform mat4 view_proj;   /* the RSM's camera now */

/* The twin's lit texel: position.w > 0 (not NaN), position, normal, flux finite, flux >= 0. */
bool lit(uvec4 x, uvec4 n, uvec4 f) {
    return positive(x.w) && finite3(x.xyz) && finite3(n.xyz) && finite3(f.rgb) &&
           nonneg3(f.rgb);
}

/* gim__rsm_vpl_follow step for step (precise: no fused multiply-add the twin does not make):
   the texel that the previous VPL p of slot s (texel s.xy, radius s.z) stands on now, or (-1, -1). */
ivec2 follow_texel(Vpl p, uvec4 s) {
    ivec2 none = ivec2(-1);
    if (!(p.position.w == 1.0) || !finite3(p.position.xyz) || !finite3(p.normal.xyz)) return none;
    precise float x = p.position.x, y = p.position.y, z = p.position.z;
    precise float cx = view_proj[0][0] * x; cx += view_proj[1][0] * y; cx += view_proj[2][0] * z; cx += view_proj[3][0];
    precise float cy = view_proj[0][1] * x; cy += view_proj[1][1] * y; cy += view_proj[2][1] * z; cy += view_proj[3][1];
    precise float cw = view_proj[0][3] * x; cw += view_proj[1][3] * y; cw += view_proj[2][3] * z; cw += view_proj[3][3];
    if (!(cw > 0.0)) return none;
    precise float u = cx / cw; u = u * 0.5 + 0.5; u = u * float(size);
    precise float v = cy / cw; v = v * 0.5 + 0.5; v = v * float(size);
    float fx = floor(u), fy = floor(v);
    if (!(fx >= 0.0 && fy >= 0.0 && fx < float(size) && fy < float(size))) return none;
    float r = uintBitsToFloat(s.z);
    if (!(abs(fx - float(s.x)) <= r && abs(fy - float(s.y)) <= r)) return none;
    ivec2 t = ivec2(int(fx), int(fy));
    uvec4 qx = imageLoad(rsm_position, t), qn = imageLoad(rsm_normal, t), qf = imageLoad(rsm_flux, t);
    if (!lit(qx, qn, qf)) return none;
    vec3 q = uintBitsToFloat(qx.xyz), n = uintBitsToFloat(qn.xyz);
    precise float dx = q.x - x, dy = q.y - y, dz = q.z - z;
    precise float d2 = dx * dx; d2 += dy * dy; d2 += dz * dz;
    precise float a = 4.0 * uintBitsToFloat(qn.w);
    if (!(d2 <= a)) return none;
    precise float c = n.x * p.normal.x; c += n.y * p.normal.y; c += n.z * p.normal.z;
    if (!(c >= 0.9)) return none;
    return t;
}

void main() {
    uint i = gl_GlobalInvocationID.y * (gl_NumWorkGroups.x * gl_WorkGroupSize.x) + gl_GlobalInvocationID.x;
    uint blocks = (count + block - 1u) / block;
    if (mode == 0u) {
        if (i < size) {
            dvec3 row = dvec3(0.0);
            for (uint x = 0u; x < size; ++x) {
                ivec2 p = ivec2(x, i);
                uvec4 f = imageLoad(rsm_flux, p);
                if (lit(imageLoad(rsm_position, p), imageLoad(rsm_normal, p), f)) row += dvec3(uintBitsToFloat(f.rgb));
            }
            sums[i] = dvec4(row, 0.0);
        }
        if (i < count) {
            uvec4 s = texel[i];
            ivec2 p = ivec2(s.xy), k = ivec2(-1);
            Vpl prev;
            if (follow != 0u) {
                prev = vpl[i];
                k = follow_texel(prev, s);
                if (k.x >= 0) p = k;
            }
            uvec4 x = imageLoad(rsm_position, p), n = imageLoad(rsm_normal, p), f = imageLoad(rsm_flux, p);
            bool l = lit(x, n, f);
            Vpl v;
            /* position and normal where finite (an unlit texel may hold anything), else 0 */
            v.position = vec4(finite3(x.xyz) ? uintBitsToFloat(x.xyz) : vec3(0.0), l ? 1.0 : 0.0);
            float area = uintBitsToFloat(n.w);   /* the texel's footprint: the VPL's near field */
            v.normal = vec4(finite3(n.xyz) ? uintBitsToFloat(n.xyz) : vec3(0.0),
                            l && area > 0.0 && area <= FLT_MAX ? area : 0.0);
            v.flux = vec4(l ? uintBitsToFloat(f.rgb) : vec3(0.0), 0.0);
            if (k.x >= 0) {   /* kept: where it stood (lit, as follow_texel asked) */
                v.position.xyz = prev.position.xyz;
                v.normal.xyz = prev.normal.xyz;
                v.flux.w = 1.0;
            }
            vpl[i] = v;
        }
    } else if (mode == 1u) {
        if (i < blocks) {
            dvec3 s = dvec3(0.0);
            uint e = min(count, (i + 1u) * block);
            for (uint k = i * block; k < e; ++k) s += dvec3(vpl[k].flux.rgb);
            sums[size + i] = dvec4(s, 0.0);
        }
    } else if (mode == 2u) {
        if (i == 0u) {
            dvec3 t = dvec3(0.0), s = dvec3(0.0);
            for (uint y = 0u; y < size; ++y) t += sums[y].xyz;
            for (uint b = 0u; b < blocks; ++b) s += sums[size + b].xyz;
            double ts = t.x + t.y + t.z, ss = s.x + s.y + s.z;   /* the areas' share: over all channels */
            sums[size + blocks] = dvec4(s.x > 0.0LF ? t.x / s.x : 0.0LF, s.y > 0.0LF ? t.y / s.y : 0.0LF,
                                        s.z > 0.0LF ? t.z / s.z : 0.0LF, ss > 0.0LF ? ts / ss : 0.0LF);
        }
    } else if (i < count) {
        dvec4 scale = sums[size + blocks];
        vpl[i].flux.rgb = vec3(min(dvec3(vpl[i].flux.rgb) * scale.xyz, dvec3(3.4028234663852886e38LF)));
        /* the VPL's patch: its texel's footprint times the texels it stands for, so that the patch
           leaves the texel's own exitance */
        vpl[i].normal.w = float(min(double(vpl[i].normal.w) * scale.w, 3.4028234663852886e38LF));
    }
}
