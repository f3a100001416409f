// BDPT's wavefront (lib/bdpt_wave.glsl): what the emitters give at the camera vertex z_k
// that bdpt_hit found (or where its walk escaped): the emission found there (s = 0) and
// the point of the s = 1 strategy's light sample, whose BSDF half is the shade stage's.
// All of BDPT's emitter code is here (kept apart from the surfaces' and textures' code of
// bdpt_hit: lavapipe's compile time grows faster than a kernel).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & BDPT_WALK_EMIT) == 0u) return;
    flags &= ~BDPT_WALK_EMIT;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    uint prim = floatBitsToUint(g.hit.x);
    bool found = !w.escaped;
    // z_k (w.vertices counts it when found); strategies here have t = k + 1.
    uint k = found ? w.vertices : w.vertices + 1u;
    PathVertex v;
    if (found) {
        v = walk_vertex(slot, g);
        v.emitter = has_feature(FEATURE_MEDIA) && prim == MEDIUM_HIT ? NO_EMITTER : primitive_emitter(prim);
    } else {
        v.emitter = NO_EMITTER;
    }
    sampler_resume(index, g);
    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : max_scatter();
    vec3 L = g.radiance.xyz;
    vec3 value;
    // s = 0: the camera subpath found an emitter, or escaped toward the environment
    // (k - 1 scattering vertices either way).
    EmissionQuery q[2];
    bool ask[2] = bool[2](false, false);
    bool emission = k - 1u >= min_scatter() && emission_found(w, v, !found, value, q[0], ask[0]);
    // s = 1: a fresh sample on a light (k scattering vertices); its BSDF half is the
    // shade stage's.
    LightSample ls;
    bool sampled = found && k <= max_vertices && k >= min_scatter() && light_sample_draw(v, ls, q[1]);
    ask[1] = sampled && w.vertices <= max_scatter();
    // Both strategies' emitter densities, asked in one place.
    vec2 pdfs[2] = vec2[2](vec2(0.0), vec2(0.0));
    [[dont_unroll]] for (uint i = 0u; i < 2u; ++i) {
        if (ask[i]) pdfs[i] = emission_pdfs(q[i]);
    }
    if (emission) add_camera(L, 0u, k + 1u, index, value, emission_weight(w, v, !found, q[0], pdfs[0]));
    if (emission) walks[slot].radiance.xyz = L;
    if (sampled) {
        flags |= BDPT_WALK_LIGHT_SAMPLE;
        pack_light_sample(ls, walks[slot].ls_wi, walks[slot].ls_le, walks[slot].ls_p, walks[slot].ls_n);
        walks[slot].ls_pdfs = vec4(pdfs[1], 0.0, 0.0);
    }
    walks[slot].o.w = uintBitsToFloat(sampler_rng.counter);
    walks[slot].d.w = uintBitsToFloat(flags);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
