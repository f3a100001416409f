// The sampler interface of lib/bdpt.glsl for bdpt.comp: counter-based pcg draws of one
// sample (pixel, sample index, seed), one pcg4d block per call whatever the stream
// (a sample is one stream of independent draws; the stream only matters to MMLT).
#ifndef SAMPLER_PCG_GLSL
#define SAMPLER_PCG_GLSL
#include "rng.glsl"

#define STREAM_CAMERA 0u
#define STREAM_LIGHT 1u
#define STREAM_CONNECT 2u

Rng sampler_rng;

void sampler_start(uint seed, uint pixel, uint sample_index) {
    sampler_rng = rng_init(seed, pixel, sample_index);
}
uint sample_u32(uint stream) { return rng_block(sampler_rng).x; }
float sample_1d(uint stream) { return rng_next(sampler_rng); }
vec2 sample_2d(uint stream) { return rng_next2(sampler_rng); }
vec3 sample_3d(uint stream) { return rng_next3(sampler_rng); }
#endif
