/* VPL shadow maps from the triangles (GIM_VISIBILITY_SHADOW_MAPS: Keller 1997's instant radiosity,
   a map per VPL, kept with the VPL as Laine et al. 2007 do): the paraboloid pass drew VPL
   list[list_first + l] into layer l of its distance array (the texel's ray against the
   triangles, exact); this pass stores each layer in the imperfect shadow maps' format, so that
   the VPL shading and its lookup (ism_lookup.glsl) are the same for both kinds of map: 16 bits a
   texel, two to a uint, texel 2k in the low half (ism_pack). The paraboloid pass's empty texel
   (GIM_PARABOLOID_EMPTY) is the maps' ISM_EMPTY, the same float. One work group per layer, the
   maps written counted in made. */
#include "common.glsl"
#define GROUP 256
layout(local_size_x = GROUP) in;

layout(binding = 0) uniform sampler2DArray distance_maps;                /* R32F, layer l = list[list_first + l] */
layout(std430, binding = 1) readonly buffer List { uint list[]; };       /* VPL indices */
layout(std430, binding = 2) writeonly buffer Maps { uint map_out[]; };   /* size^2 / 2 per map */
layout(std430, binding = 3) buffer Made { uint made; };

layout(location = 0) uniform uint size;
layout(location = 1) uniform uint list_first;    /* layer l is VPL list[list_first + l] */
layout(location = 2) uniform uint out_first;     /* Maps is bound from map out_first on */
layout(location = 3) uniform uint source_first;  /* VPL v's map is map v - source_first */
layout(location = 5) uniform uint layer_first;   /* this dispatch's layers: layer_first + work group */

void main() {
    uint l = layer_first + gl_WorkGroupID.x, m = list[list_first + l] - source_first;
    if (gl_LocalInvocationIndex == 0u) atomicAdd(made, 1u);
    uint half_texels = size * size / 2u;
    for (uint q = gl_LocalInvocationIndex; q < half_texels; q += uint(GROUP)) {
        uint t0 = 2u * q, t1 = t0 + 1u;
        float d0 = texelFetch(distance_maps, ivec3(int(t0 % size), int(t0 / size), int(l)), 0).r;
        float d1 = texelFetch(distance_maps, ivec3(int(t1 % size), int(t1 / size), int(l)), 0).r;
        map_out[(m - out_first) * half_texels + q] = ism_pack(floatBitsToUint(d0), floatBitsToUint(d1));
    }
}
