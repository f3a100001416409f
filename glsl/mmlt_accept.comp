// MMLT's wavefront (lib/mmlt_wave.glsl): the path's contribution C = weighted value x
// (depth + 2) (0 when its shadow ray was blocked or it ended early), its target
// f = luminance(C), and what the bootstrap sample or chain does with them
// (lib/mmlt_chain.glsl: the target written, the chain started, or the proposal splatted
// and accepted or rejected).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uvec4 path = mpaths[slot].path;
    vec4 c = mpaths[slot].value;
    bool found = (path.z & MMLT_PATH_FOUND) != 0u;
    uint strategies = path.x + path.y;
    float f;
    vec3 C = mmlt_target(found ? c.xyz * (c.w * float(strategies)) : vec3(0.0), f);
    pss_resume(slot, item);
    mmlt_step(item, params.mode, true, C, f, path.w, mpaths[slot].used.w);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
