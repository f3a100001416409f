// MMLT's wavefront (lib/mmlt_wave.glsl): the visibility stage. The slot's queued shadow
// ray first (the path's contribution counts when nothing blocks it), then its walk's
// closest hit, for mmlt_hit.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & (BDPT_WALK_SHADOW | BDPT_WALK_RAY)) == 0u) return;
    uint rays = 0u;
    if ((flags & BDPT_WALK_SHADOW) != 0u) {
        vec4 o = walks[slot].ls_wi;
        vec3 d = walks[slot].ls_le.xyz;
        rays++;
        if (!(o.w > 0.0) || !trace_occluded(o.xyz, d, o.w)) mpaths[slot].path.z |= MMLT_PATH_FOUND;
        flags &= ~BDPT_WALK_SHADOW;
        walks[slot].d.w = uintBitsToFloat(flags);
    }
    if ((flags & BDPT_WALK_RAY) != 0u) {
        Hit hit;
        bool found = trace_closest(walks[slot].o.xyz, walks[slot].d.xyz, INF, hit);
        rays++;
        walks[slot].hit = vec4(uintBitsToFloat(found ? hit.prim : NO_HIT), hit.bary, hit.t);
    }
    mpaths[slot].used.w += rays;
}
