// The MMLT sampler's probe (tests only; src/probe.rs): the start and chain modes of
// lib/mmlt_chain.glsl on a synthetic path, one invocation per chain making
// params.mutations proposals. Tests compare the chain state it leaves with the CPU
// mirror (src/integrators/mmlt_sampler.rs). The path asks each stream for a
// hash-chosen count of numbers and its target is a hash, so accept/reject decisions
// are known to the CPU without evaluating paths.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#define OWN_PUSH_CONSTANTS
#include "bindings.glsl"
layout(push_constant) uniform MmltBlock { MmltParams params; };
#include "sampling.glsl"
#include "sampler_pss.glsl"
#include "splat.glsl"
#include "mmlt_chain.glsl"

float probe_sample() {
    pss_begin_path();
    uvec4 h = pcg4d(uvec4(pss.chain, pss.proposal, pss.seed, 0x20000000u));
    uint counts[3] = uint[3](1u + h.x % pss.capacity[0], h.y % (pss.capacity[1] + 1u), h.z % (pss.capacity[2] + 1u));
    for (uint s = 0u; s < 3u; ++s) {
        for (uint i = 0u; i < counts[s]; ++i) sample_u32(s);
    }
    return pss_unit(h.w) + 0.01;
}

void main() {
    uint item = params.first_item + gl_GlobalInvocationID.x;
    if (gl_GlobalInvocationID.x >= params.items) return;
    uint mode = params.mode - (MMLT_MODE_PROBE_START - MMLT_MODE_START);
    mmlt_pss_init(item, mode);
    if (mode == MMLT_MODE_START) mmlt_copy_start(item);
    uint iterations = mode == MMLT_MODE_CHAINS ? params.mutations : 1u;
    for (uint k = 0u; k < iterations; ++k) {
        if (mode == MMLT_MODE_CHAINS) mmlt_propose(chains[item]);
        mmlt_step(item, mode, false, vec3(0.0), probe_sample(), 0u, 0u);
    }
}
