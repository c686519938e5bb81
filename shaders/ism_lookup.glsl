/* The imperfect shadow map lookup (Ritschel et al. 2008) of point x, normal nl, in map m of
   centre c and normal nv: 1 where the map sees x, 0 where it is hidden (gim__ism_visible, the
   lookup of gim_ism_visibility_twin: its float steps in its order, `precise` so that the compiler
   fuses none of them into a multiply-add). tools/embed_shaders.c puts this file in place of
   a shader's line `#include "ism_lookup.glsl"`, which must come after common.glsl's and after
   the shader's declarations of the maps, `uint ism[]` (ism_pack's format), and the uniforms
   ism_size, ism_bias, ism_texel (the slope bias per unit tan, 2 / size) and ism_lift (the
   map's origin above c along nv). vpl_shade.comp looks the receiver up in VPL i's map,
   second_bounce.comp a hit in its cluster's. */
float ism_visibility(uint m, vec3 c, vec3 nv, vec3 x, vec3 nl) {
    precise vec3 n = nv;
    precise vec3 t, b;
    basis_precise(n, t, b);
    precise vec3 o = vec3(c.x + ism_lift * n.x, c.y + ism_lift * n.y, c.z + ism_lift * n.z);
    precise vec3 d = vec3(x.x - o.x, x.y - o.y, x.z - o.z);
    precise float dist = sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
    if (!(dist > 0.0)) return 1.0;
    precise float wz = (d.x * n.x + d.y * n.y + d.z * n.z) / dist;
    if (!(wz > 0.0)) return 1.0;
    precise float wx = (d.x * t.x + d.y * t.y + d.z * t.z) / dist;
    precise float wy = (d.x * b.x + d.y * b.y + d.z * b.z) / dist;
    precise float fs = float(ism_size);
    precise float fx = floor((wx / (1.0 + wz) + 1.0) * 0.5 * fs);
    precise float fy = floor((wy / (1.0 + wz) + 1.0) * 0.5 * fs);
    int ix = fx < 0.0 ? 0 : fx > float(ism_size - 1u) ? int(ism_size) - 1 : int(fx);
    int iy = fy < 0.0 ? 0 : fy > float(ism_size - 1u) ? int(ism_size) - 1 : int(fy);
    int tx = iy * int(ism_size) + ix;
    uint zi = m * ism_size * ism_size + uint(tx);
    uint zw = ism[zi >> 1u];
    float z = ism_unpack(zw, zi);
    precise float u = (2.0 * float(ix) + 1.0) / fs - 1.0;   /* the texel's centre ray, gim__ism_texel_ray */
    precise float v = (2.0 * float(iy) + 1.0) / fs - 1.0;
    precise float r2 = u * u + v * v;
    precise float q = 1.0 / (1.0 + r2);
    precise vec3 w = vec3(2.0 * u * q, 2.0 * v * q, (1.0 - r2) * q);
    precise vec3 dir = vec3(w.x * t.x + w.y * b.x + w.z * n.x, w.x * t.y + w.y * b.y + w.z * n.y,
                            w.x * t.z + w.y * b.z + w.z * n.z);
    precise float dref = dist;
    precise float den = dir.x * nl.x + dir.y * nl.y + dir.z * nl.z;
    if (den >= 1e-3 || den <= -1e-3) {                    /* the receiver's plane along the texel's ray */
        precise float s = (d.x * nl.x + d.y * nl.y + d.z * nl.z) / den;
        if (s > 0.0 && s < 2.0 * dist) dref = s;
    }
    precise float cl = -(nl.x * d.x + nl.y * d.y + nl.z * d.z) / dist;
    cl = cl < 0.0 ? -cl : cl;
    precise float sn = sqrt(1.0 - (cl < 1.0 ? cl * cl : 1.0));
    precise float tn = cl * ISM_MAX_TAN > sn ? sn / cl : ISM_MAX_TAN;
    return z < ISM_EMPTY && dref > z + dist * (ism_bias + ism_texel * tn) ? 0.0 : 1.0;
}
