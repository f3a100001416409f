// BDPT's wavefront (lib/bdpt_wave.glsl): the visibility stage. The pixel's pending
// shadow ray first (its contribution added to the splat film or to the pixel's sum when
// nothing blocks it), then its walk's closest hit.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    uvec4 counts = walks[slot].counts;
    if ((flags & BDPT_WALK_SHADOW) != 0u) {
        vec4 o = walks[slot].ls_wi;
        vec4 d = walks[slot].ls_le;
        if (!trace_occluded(o.xyz, d.xyz, o.w)) {
            vec4 c = walks[slot].ls_p;
            uvec2 st = floatBitsToUint(walks[slot].ls_n.xy);
            if ((flags & BDPT_WALK_SHADOW_SPLAT) != 0u) {
                uint to = floatBitsToUint(d.w);
                add_splat(uvec2(to % scene.width, to / scene.width), st.x, c.xyz, c.w);
            } else {
                vec3 L = walks[slot].radiance.xyz;
                add_camera(L, st.x, st.y, index, c.xyz, c.w);
                walks[slot].radiance.xyz = L;
            }
        }
        flags &= ~(BDPT_WALK_SHADOW | BDPT_WALK_SHADOW_SPLAT);
    }
    if ((flags & BDPT_WALK_RAY) != 0u) {
        Hit hit;
        bool found = trace_closest(walks[slot].o.xyz, walks[slot].d.xyz, INF, hit);
        counts.y++;
        walks[slot].hit = vec4(uintBitsToFloat(found ? hit.prim : NO_HIT), hit.bary, hit.t);
        walks[slot].counts.y = counts.y;
    }
    walks[slot].d.w = uintBitsToFloat(flags);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
