// MMLT as a wavefront of small kernels: one slot per bootstrap sample or chain of the
// dispatch, one path (one strategy (s, t) of bdpt) per proposal, built by stages over
// state in device memory (walks[], GpuBdptWalk; mpaths[], GpuMmltPath):
//   mmlt_start.comp         the proposal (lib/mmlt_chain.glsl: mutation, or the start's
//                           copy), its strategy and film position, the first ray of the
//                           light subpath (s >= 2 or t = 1; s = 1, t = 1: the light's
//                           point seen by the camera, its shadow ray queued) or of the
//                           camera subpath;
//   mmlt_trace.comp         the queued shadow ray, then the walk's closest hit: the only
//                           kernel that holds the visibility backend;
//   mmlt_hit.comp           the vertex at the hit; at the light subpath's last vertex y the
//                           camera subpath's start (or, t = 1, the camera's side of the
//                           connection); at the camera subpath's last vertex z what the
//                           emitters give (s = 0: the emission found; s = 1: the light
//                           sample and its densities) or the s, t >= 2 connection's
//                           geometry: all of MMLT's emitter code;
//   mmlt_shade_CLASS.comp   one per material class: the BSDF sample that continues a
//                           walk, or the strategy's questions to the BSDFs at z and y of
//                           that class;
//   mmlt_end.comp           the strategy's contribution, MIS weight and shadow ray;
//   mmlt_accept.comp        after the shadow ray's trace: the contribution and target,
//                           and what the chain does with them (lib/mmlt_chain.glsl).
// The host records, per proposal, mmlt_start, then depth cap + 1 rounds of mmlt_trace,
// mmlt_hit and the scene's mmlt_shade_CLASS kernels, then mmlt_end, mmlt_trace and
// mmlt_accept. Each stage draws the path's numbers in the order the one-kernel
// evaluation did (per stream: the streams are separate), so the paths are its.
#ifndef MMLT_WAVE_GLSL
#define MMLT_WAVE_GLSL
// Walks never go beyond max_scatter() here (lib/bdpt.glsl's walk_beyond).
#define BDPT_BOUNDED_WALKS
#define OWN_PUSH_CONSTANTS
#include "bindings.glsl"
layout(push_constant) uniform MmltBlock { MmltParams params; };
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"
#include "sampler_pss.glsl"
#include "bdpt.glsl"
#include "splat.glsl"
#include "walk_state.glsl"
#include "mmlt_chain.glsl"

layout(std430, set = 0, binding = BINDING_MMLT_PATHS) buffer MmltPathBuffer { GpuMmltPath mpaths[]; };

// This invocation's slot and its item (bootstrap sample or chain); false past the
// dispatch's items.
bool mmlt_slot(out uint slot, out uint item) {
    slot = gl_GlobalInvocationID.x;
    item = params.first_item + slot;
    return slot < params.items;
}

// The sampler where the slot's last stage left it.
void pss_resume(uint slot, uint item) {
    mmlt_pss_init(item, params.mode);
    uvec4 key = mpaths[slot].key;
    uvec4 used = mpaths[slot].used;
    pss.proposal = key.x;
    pss.step = key.y;
    pss.last_large = key.z;
    pss.large = key.w != 0u;
    pss.used[0] = used.x;
    pss.used[1] = used.y;
    pss.used[2] = used.z;
}

void pss_save(uint slot) { mpaths[slot].used.xyz = uvec3(pss.used[0], pss.used[1], pss.used[2]); }

uint path_flags(uint slot) { return mpaths[slot].path.z; }
uint path_kind(uint flags) { return flags >> 8u; }

// y, the light subpath's last vertex.
PathVertex path_y(uint slot) {
    GpuPathVertex g;
    g.p = mpaths[slot].y_p;
    g.n = mpaths[slot].y_n;
    g.wi = mpaths[slot].y_wi;
    g.beta = mpaths[slot].y_beta;
    g.ns = mpaths[slot].y_ns;
    PathVertex y = unpack_vertex(g);
    y.tex0 = mpaths[slot].y_tex0;   // (read only where the scene has material textures)
    y.tex1 = mpaths[slot].y_tex1;
    return y;
}

void store_path_y(uint slot, PathVertex y) {
    GpuPathVertex g = pack_vertex(y);
    mpaths[slot].y_p = g.p;
    mpaths[slot].y_n = g.n;
    mpaths[slot].y_wi = g.wi;
    mpaths[slot].y_beta = g.beta;
    mpaths[slot].y_ns = g.ns;
    if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
        mpaths[slot].y_tex0 = y.tex0;
        mpaths[slot].y_tex1 = y.tex1;
    }
}

// A shadow ray for mmlt_trace; the path's contribution counts when nothing blocks it
// (times the transmittance of the media it crosses, from `medium` on).
void queue_path_shadow(uint slot, inout uint walk_flags, vec3 o, vec3 d, float tmax, uint medium) {
    walks[slot].ls_wi = vec4(o, tmax);
    walks[slot].ls_le = vec4(d, uintBitsToFloat(medium));
    walk_flags |= BDPT_WALK_SHADOW;
}
#endif
