// BDPT as a wavefront of small kernels: each pixel of a band walks its
// light subpath, then its camera subpath, one bounce per round of dispatches over the
// band, its state in walks[] between them:
//   bdpt_start.comp         a subpath's first ray (the light's emission, with the
//                           s = 1, t = 1 strategy; or the camera's ray);
//   bdpt_trace.comp         the pending shadow ray (its contribution added when nothing
//                           blocks it) and the s, t >= 2 connections of the newest camera
//                           vertex (joined from the shade stages' answers, their shadow
//                           rays traced), then the walk's closest hit: the only kernel
//                           that holds the visibility backend;
//   bdpt_hit.comp           the vertex at the hit, stored for connections, and what the
//                           emitters give there (s = 0, the s = 1 light sample's point):
//                           every emitter's code;
//   bdpt_shade_CLASS.comp   one per material class (bsdf.glsl's SHADE_CLASS): the BSDF
//                           toward the camera (t = 1) or toward the light sample (s = 1),
//                           their shadow rays queued for the trace stage, the BSDF
//                           sample that continues the walk, and the connections'
//                           questions to the ends of its class (answers[]); a vertex of
//                           another class is left to its own kernel;
//   bdpt_finish.comp        per pixel, each sample's camera strategies and then its
//                           connections' sum (kept in the walk) added to the film, in
//                           sample order.
// A pixel's draws, contributions and their order are the same as when one invocation
// walked both subpaths (the three stages that preceded this wavefront), so the images
// are theirs (to the last bits where the compiler fuses multiply-adds differently). The host records
// bdpt_start, per bounce bdpt_trace, bdpt_hit and one bdpt_shade_CLASS per class the
// scene has, then bdpt_trace for the last shadow rays, for the light side and then the
// camera side (BdptParams.side and .bounce), then bdpt_finish. At maxdepth -1 the camera
// walks go on with Russian roulette beyond the strategies' cap (BDPT_UNBOUNDED_DEPTH_CAP
// scattering vertices): the shade stages count the walks that go on per bounce
// (bdpt_live[]), and the host records further bounces while some do.
#ifndef BDPT_WAVE_GLSL
#define BDPT_WAVE_GLSL
#include "bdpt_pass.glsl"
#include "walk_state.glsl"

layout(std430, set = 0, binding = BINDING_BDPT_LIVE) buffer BdptLiveBuffer { uint bdpt_live[]; };
// Per slot, vertex_stride() connections of its newest camera vertex z_k, one per light
// vertex y_j: BDPT_ANSWER_FLOATS floats each, z's BSDF toward y and then y's toward z
// (value rgb, pdf in the direction asked, pdf back). Each float of a connection is an
// array over the dispatch's slots, so that neighbouring invocations touch neighbouring
// words.
layout(std430, set = 0, binding = BINDING_BDPT_ANSWERS) buffer BdptAnswerBuffer { float answers[]; };

uint answer_slots() { return band_pixels() * max(pass_params.samples, 1u); }

// Where the first float of slot's answer for the connection to y_j, side 0 (z) or 1 (y),
// is; the next are answer_slots() apart.
uint answer_at(uint slot, uint j, uint side) {
    return ((j - 1u) * BDPT_ANSWER_FLOATS + side * (BDPT_ANSWER_FLOATS / 2u)) * answer_slots() + slot;
}

float answer(uint at, uint i) { return answers[at + i * answer_slots()]; }

void store_answer(uint at, vec3 f, float pdf_dir, float pdf_rev) {
    uint n = answer_slots();
    answers[at] = f.x;
    answers[at + n] = f.y;
    answers[at + 2u * n] = f.z;
    answers[at + 3u * n] = pdf_dir;
    answers[at + 4u * n] = pdf_rev;
}

vec3 answer_f(uint at) { return vec3(answer(at, 0u), answer(at, 1u), answer(at, 2u)); }

// The pixel's sampler, resumed where the walk's last stage left it.
void sampler_resume(uint index, GpuBdptWalk g) {
    sampler_start(scene.seed, index, bdpt_sample());
    sampler_rng.counter = floatBitsToUint(g.o.w);
}

// A shadow ray for the trace stage and what it adds when nothing blocks it: strategy
// (s, t), its unweighted value and MIS weight, added to the splat film at `pixel` (t = 1)
// or to the walk's own pixel; `medium` the code of the medium it starts in.
void queue_shadow(uint slot, inout uint flags, vec3 o, vec3 d, float tmax, uint s, uint t, uint pixel, vec3 value,
                  float weight, uint medium) {
    walks[slot].ls_wi = vec4(o, tmax);
    walks[slot].ls_le = vec4(d, uintBitsToFloat(pixel));
    walks[slot].ls_p = vec4(value, weight);
    walks[slot].ls_n = vec4(uintBitsToFloat(s), uintBitsToFloat(t), uintBitsToFloat(medium), 0.0);
    flags |= BDPT_WALK_SHADOW;
    if (t == 1u) flags |= BDPT_WALK_SHADOW_SPLAT;
}

#endif
