// Reproducible randomness, counter-based: the n-th draw of a sample is
// pcg4d(pixel, sample index, seed, n) (Jarzynski & Olano 2020, "Hash Functions for GPU
// Rendering"). pcg4d is a bijection of uvec4, so distinct (pixel, sample, seed, n)
// never share a draw: streams do not overlap, and a render is a pure function of
// (scene, settings, seed).
#ifndef RNG_GLSL
#define RNG_GLSL

uvec4 pcg4d(uvec4 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v ^= v >> 16u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

struct Rng {
    uvec3 key;    // pixel, sample index, seed
    uint counter; // draws so far
};

Rng rng_init(uint seed, uint pixel, uint sample_index) {
    Rng r;
    r.key = uvec3(pixel, sample_index, seed);
    r.counter = 0u;
    return r;
}

#ifdef PROFILE_X2_RNG
// lightpath profile: every draw hashes twice (the second result is kept only in a case
// that never happens in practice), so the extra time is the RNG's share of a pass.
uvec4 rng_block(inout Rng r) {
    uvec4 b = pcg4d(uvec4(r.key.yxz, r.counter));
    uvec4 a = pcg4d(uvec4(r.key, r.counter++));
    return b.x == 0x9e3779b9u && b.y == 0x7f4a7c15u ? a ^ b : a;
}
#else
uvec4 rng_block(inout Rng r) { return pcg4d(uvec4(r.key, r.counter++)); }
#endif

// Uniform in [0, 1): the top 24 bits.
vec4 rng_to_unit(uvec4 x) { return vec4(x >> 8u) * (1.0 / 16777216.0); }

float rng_next(inout Rng r) { return rng_to_unit(rng_block(r)).x; }
vec2 rng_next2(inout Rng r) { return rng_to_unit(rng_block(r)).xy; }
vec3 rng_next3(inout Rng r) { return rng_to_unit(rng_block(r)).xyz; }
#endif
