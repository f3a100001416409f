// The splat film: contributions that land on pixels other than the invocation's own
// (BDPT's light tracing, t = 1; every MMLT mutation), added so that the sum does not
// depend on the order in which invocations add (DESIGN.md, "Randomness is
// reproducible"). Float atomics round after every addition, so their sum depends on the
// order; integer additions are exact and commute.
//
// Each channel of a pixel is an unsigned 64-bit fixed-point number with
// SPLAT_FRACTION_BITS = 32 fractional bits, kept as two 32-bit words (low, high) added
// with 32-bit atomics and a carry: the final sum is exact, whatever the order.
//   range:     a pixel channel's sum must stay below 2^32 (4.29e9) over the whole render;
//              the high word's wrap is counted (STAT_SPLAT_OVERFLOW) and fails the render.
//   precision: a contribution v >= 2^-9 is represented exactly (a float has 24 bits, so
//              its last bit is at or above 2^-32); smaller ones round to the nearest
//              multiple of 2^-32 (2.3e-10), even on ties.
// A contribution that is negative, NaN, infinite or >= 2^32 is not added (the caller
// counts it with the NaN/Inf samples). Layout: SPLAT_WORDS_PER_PIXEL (8) words per
// pixel, channel c at 2c (low) and 2c + 1 (high). CPU side: src/integrators/mod.rs
// (add_splat_film).
#ifndef SPLAT_GLSL
#define SPLAT_GLSL
#include "bindings.glsl"

layout(std430, set = 0, binding = BINDING_SPLAT) buffer SplatBuffer { uint splat[]; };

bool finite3(vec3 v) { return !any(isnan(v)) && !any(isinf(v)); }

bool splat_in_range(vec3 v) {
    return all(greaterThanEqual(v, vec3(0.0))) && all(lessThan(v, vec3(4294967296.0)));
}

// Add v (in [0, 2^32)) exactly to the fixed-point number in words WORD (low) and
// WORD + 1 (high) of the uint array BUF; WRAPPED: whether the high word wrapped. (A macro:
// the splat film and the diagnostic films, BDPT's strategy images and MMLT's per-depth
// images, are buffers of their own, and GLSL passes no buffer to a function.)
#define FIXED_POINT_ADD(BUF, WORD, V, WRAPPED)                                  \
    {                                                                          \
        float whole_ = floor(V);                                               \
        uint hi_ = uint(whole_);                                               \
        uint lo_ = uint(roundEven(((V) - whole_) * 4294967296.0));             \
        WRAPPED = false;                                                       \
        if (lo_ != 0u) {                                                       \
            uint old_ = atomicAdd(BUF[WORD], lo_);                             \
            if (old_ + lo_ < old_) hi_ += 1u; /* the carry out of the low word */ \
        }                                                                      \
        if (hi_ != 0u) {                                                       \
            uint old_ = atomicAdd(BUF[(WORD) + 1u], hi_);                      \
            WRAPPED = old_ + hi_ < old_;                                       \
        }                                                                      \
    }

void splat_channel(uint word, float v) {
    bool wrapped;
    FIXED_POINT_ADD(splat, word, v, wrapped);
    if (wrapped) atomicAdd(stats[STAT_SPLAT_OVERFLOW], 1u);
}

// Add v (each channel in [0, 2^32)) to the pixel's splat. False, adding nothing, when v
// is out of that range or not finite.
bool splat_add_fixed(uint pixel, vec3 v) {
    if (!splat_in_range(v)) return false;
    uint base = pixel * SPLAT_WORDS_PER_PIXEL;
    for (uint c = 0u; c < 3u; ++c) {
        if (v[c] > 0.0) splat_channel(base + 2u * c, v[c]);
    }
    return true;
}
#endif
