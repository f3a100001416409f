// Reproducible randomness: a PCG32 stream per (seed, pixel, sample), so a render is a
// pure function of (scene, settings, seed). PCG: O'Neill 2014; hash: Jarzynski & Olano 2020.
#ifndef RNG_GLSL
#define RNG_GLSL

uint pcg_hash(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

struct Rng { uint state; };

Rng rng_init(uint seed, uint pixel, uint sample_index) {
    Rng r;
    r.state = pcg_hash(seed ^ pcg_hash(pixel ^ pcg_hash(sample_index + 0x9e3779b9u)));
    return r;
}

uint rng_next_uint(inout Rng r) {
    r.state = r.state * 747796405u + 2891336453u;
    uint s = r.state;
    uint word = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    return (word >> 22u) ^ word;
}

// Uniform in [0, 1).
float rng_next(inout Rng r) { return float(rng_next_uint(r) >> 8) * (1.0 / 16777216.0); }
vec2 rng_next2(inout Rng r) { return vec2(rng_next(r), rng_next(r)); }
vec3 rng_next3(inout Rng r) { return vec3(rng_next(r), rng_next(r), rng_next(r)); }
#endif
