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
    // Both rays through one trace_ray (each call site is a copy of the backend): r = 0 the
    // shadow ray, r = 1 the walk's.
    uint rays = 0u;
    [[dont_unroll]] for (uint r = 0u; r < 2u; ++r) {
        bool closest = r == 1u;
        if ((flags & (closest ? BDPT_WALK_RAY : BDPT_WALK_SHADOW)) == 0u) continue;
        vec4 o = closest ? vec4(walks[slot].o.xyz, INF) : walks[slot].ls_wi;
        vec3 d = closest ? walks[slot].d.xyz : walks[slot].ls_le.xyz;
        rays++;
        Hit hit;
        bool found = (closest || o.w > 0.0) && trace_ray(o.xyz, d, o.w, !closest, hit);
        if (closest) {
            walks[slot].hit = vec4(uintBitsToFloat(found ? hit.prim : NO_HIT), hit.bary, hit.t);
        } else {
            if (!found) mpaths[slot].path.z |= MMLT_PATH_FOUND;
            flags &= ~BDPT_WALK_SHADOW;
            walks[slot].d.w = uintBitsToFloat(flags);
        }
    }
    mpaths[slot].used.w += rays;
}
