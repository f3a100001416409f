// The sampler interface of lib/bdpt.glsl for MMLT's kernels (lib/mmlt_wave.glsl): primary sample space
// (Kelemen et al. 2002) with lazy mutation, in three streams so that changing the
// strategy (s,t) does not shift one subpath's numbers onto another's:
//   STREAM_CAMERA  the strategy number, the film position, the camera walk
//   STREAM_LIGHT   the light walk (emitter pick, point, direction, bounces)
//   STREAM_CONNECT the s = 1 light sample (emitter pick, point)
// Numbers are 32-bit fixed point in [0,1): emitter picks take all 32 bits (so their pick
// pdfs are exact, as in bdpt), warps take the top 24 (as rng_to_unit does), and a
// small step's wrap into [0,1) is the integer's own wrap-around, never reaching 1.
//
// A chain's numbers live in chain_samples[dim * chains + chain] as uvec4(value,
// last-modified step, backup value, backup step). A proposal mutates a number only when
// the path asks for it (pbrt's MLTSampler): a number last modified before the last
// accepted large step is first redrawn (its value then is independent of everything
// the chain has seen), then takes the large step (fresh) or the n small steps it missed
// as one Gaussian of sigma * sqrt(n). A rejected proposal restores every number it
// changed, with its step; the chain's step counter advances only on acceptance.
//
// The mutation's random numbers are hashes of (chain, proposal number, seed, purpose and
// dimension) (a redraw after a large step: of that step instead of the proposal), so they never depend on the order in which a path asks for numbers, and
// a bootstrap sample's numbers are hashes of (index, depth, seed, dimension), so a chain
// started from it reproduces its path exactly. The CPU mirror is
// src/integrators/mmlt_sampler.rs.
#ifndef SAMPLER_PSS_GLSL
#define SAMPLER_PSS_GLSL
#extension GL_EXT_control_flow_attributes : require
#include "rng.glsl"

#define STREAM_CAMERA 0u
#define STREAM_LIGHT 1u
#define STREAM_CONNECT 2u

layout(std430, set = 0, binding = BINDING_CHAIN_SAMPLES) buffer ChainSampleBuffer { uvec4 chain_samples[]; };

#define PSS_FROM_KEY 0u   // a bootstrap sample: numbers are hashes of its key
#define PSS_READ 1u       // a chain's stored numbers, unchanged
#define PSS_MUTATE 2u     // a proposal: numbers mutated as they are asked for

// Purposes of a mutation's random numbers (bits 16.. of the hash key's last word).
#define PSS_TAG_DECIDE 0u   // dimension 0: large step or not; 1: accept or not
#define PSS_TAG_RESET 1u
#define PSS_TAG_LARGE 2u
#define PSS_TAG_GAUSS 3u

// The sampler's state for this invocation (one bootstrap sample or one chain); the
// kernel fills it before the first path.
struct PssState {
    uint mode;
    uint seed;
    uint key_index;     // PSS_FROM_KEY: the bootstrap sample
    uint key_depth;
    uint chain;         // the chain and the chain count (the buffer's stride)
    uint chains;
    uint step;          // the proposal's step: the chain's accepted steps + 1
    uint last_large;    // the step of the chain's last accepted large step
    uint proposal;      // proposals the chain has made before this one
    bool large;
    float sigma;
    uint base[3];       // each stream's first dimension, its capacity, the numbers used
    uint capacity[3];
    uint used[3];
};
PssState pss;

void pss_begin_path() {
    pss.used[0] = 0u;
    pss.used[1] = 0u;
    pss.used[2] = 0u;
}

uint pss_key_number(uint index, uint depth, uint dim) {
    return pcg4d(uvec4(index, depth, pss.seed, 0x80000000u | dim)).x;
}

uvec4 pss_hash(uint tag, uint dim) {
    return pcg4d(uvec4(pss.chain, pss.proposal, pss.seed, 0x40000000u | (tag << 16) | dim));
}

float pss_unit(uint x) { return float(x >> 8u) * (1.0 / 16777216.0); }

// A standard normal number (Box-Muller) for a dimension's small step, from its hash
// h = pss_hash(PSS_TAG_GAUSS, dim).
float pss_gaussian(uvec4 h) {
    float u1 = (float(h.x >> 8u) + 1.0) * (1.0 / 16777216.0);   // (0, 1]
    float u2 = pss_unit(h.y);
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

// The fixed-point offset of a Gaussian step of standard deviation `sigma`, wrapped into
// [-1/2, 1/2] of the unit interval.
uint pss_small_step_offset(float g, float sigma) {
    float t = g * sigma;
    t -= roundEven(t);
    return uint(int(clamp(t * 4294967296.0, -2147483648.0, 2147483520.0)));
}

// (Two hashes per number, each computed in one place: every call site of a sampler
// function is a copy of this one.)
uint pss_next(uint stream) {
    uint i = pss.used[stream];
    pss.used[stream] = i + 1u;
    // Past the stream's capacity (the host sizes streams for the depth cap, so this is a
    // bug): a fresh number, outside the chain's state.
    bool past = i >= pss.capacity[stream];
    bool key = pss.mode == PSS_FROM_KEY;
    uint dim = pss.base[stream] + min(i, pss.capacity[stream] - 1u);
    uint slot = dim * pss.chains + pss.chain;
    uvec4 x = past || key ? uvec4(0u) : chain_samples[slot];
    if (!past && pss.mode == PSS_READ) return x.x;
    // A number last modified before the chain's last accepted large step is redrawn
    // first, keyed by that step, not the proposal: its value since that step is one
    // fixed draw, however many rejected proposals look at it.
    bool reset = x.y < pss.last_large;
    uvec4 h = pcg4d(past ? uvec4(pss.chain, pss.proposal, pss.seed, 0x40000000u | (PSS_TAG_LARGE << 16) | 0xffffu)
                    : key ? uvec4(pss.key_index, pss.key_depth, pss.seed, 0x80000000u | dim)
                          : uvec4(pss.chain, pss.last_large, pss.seed, 0x40000000u | (PSS_TAG_RESET << 16) | dim));
    if (past) return h.y ^ i;
    if (key) return h.x;
    if (reset) x.xy = uvec2(h.x, pss.last_large);
    x.zw = x.xy;
    h = pss_hash(pss.large ? PSS_TAG_LARGE : PSS_TAG_GAUSS, dim);
    if (pss.large) {
        x.x = h.x;
    } else {
        float n = float(pss.step - x.y);
        x.x += pss_small_step_offset(pss_gaussian(h), pss.sigma * sqrt(n));
    }
    x.y = pss.step;
    chain_samples[slot] = x;
    return x.x;
}

// A rejected proposal: every number it changed goes back, with its step.
void pss_reject() {
    for (uint s = 0u; s < 3u; ++s) {
        uint used = min(pss.used[s], pss.capacity[s]);
        for (uint i = 0u; i < used; ++i) {
            uint slot = (pss.base[s] + i) * pss.chains + pss.chain;
            uvec4 x = chain_samples[slot];
            if (x.y == pss.step) chain_samples[slot] = uvec4(x.zw, x.zw);
        }
    }
}

// (Each call site is a copy of pss_next: sample_2d and sample_3d ask in one place.)
uint sample_u32(uint stream) { return pss_next(stream); }
float sample_1d(uint stream) { return pss_unit(pss_next(stream)); }
vec2 sample_2d(uint stream) {
    vec2 u;
    [[dont_unroll]] for (uint i = 0u; i < 2u; ++i) u[i] = sample_1d(stream);
    return u;
}
vec3 sample_3d(uint stream) {
    vec3 u;
    [[dont_unroll]] for (uint i = 0u; i < 3u; ++i) u[i] = sample_1d(stream);
    return u;
}
#endif
