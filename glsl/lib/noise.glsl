// Procedural textures' noise (CPU mirror: src/noise.rs): Perlin's gradient noise and
// what pbrt-v4 builds on it (fBm, turbulence, windy waves, the marble spline, polka
// dots). The table (the permutation twice, then marble's colours) is in the texel
// buffer from float `table` on (abi.h TEXTURE_NOISE).
#ifndef NOISE_GLSL
#define NOISE_GLSL
#include "bindings.glsl"

int noise_perm(uint table, int i) { return int(texels[table + uint(i)]); }

// The gradient of lattice point (x, y, z) dotted with the offset d from it.
float noise_grad(uint table, int x, int y, int z, vec3 d) {
    int h = noise_perm(table, noise_perm(table, noise_perm(table, x) + y) + z) & 15;
    float u = h < 8 || h == 12 || h == 13 ? d.x : d.y;
    float v = h < 4 || h == 12 || h == 13 ? d.y : d.z;
    return ((h & 1) != 0 ? -u : u) + ((h & 2) != 0 ? -v : v);
}

float noise_fade(float t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

// Gradient noise at p: 0 on the lattice, within about [-1, 1].
float noise3(uint table, vec3 p) {
    p = p - 1073741824.0 * trunc(p / 1073741824.0);
    vec3 f = floor(p);
    vec3 d = p - f;
    ivec3 i = ivec3(f) & 255;
    float g[8];
    for (int k = 0; k < 8; ++k) {
        ivec3 c = ivec3(k & 1, (k >> 1) & 1, k >> 2);
        g[k] = noise_grad(table, i.x + c.x, i.y + c.y, i.z + c.z, d - vec3(c));
    }
    vec3 w = vec3(noise_fade(d.x), noise_fade(d.y), noise_fade(d.z));
    float y0 = mix(mix(g[0], g[1], w.x), mix(g[2], g[3], w.x), w.y);
    float y1 = mix(mix(g[4], g[5], w.x), mix(g[6], g[7], w.x), w.y);
    return mix(y0, y1, w.z);
}

// Fractional Brownian motion (turbulence: of |noise|, plus pbrt-v4's 0.2 for the octave
// after the last). Every octave: no ray differentials (see noise.rs).
float noise_fbm(uint table, vec3 p, float omega, uint octaves, bool turbulence) {
    float sum = 0.0, lambda = 1.0, o = 1.0;
    for (uint k = 0u; k < octaves; ++k) {
        float n = noise3(table, lambda * p);
        sum += o * (turbulence ? abs(n) : n);
        lambda *= 1.99;
        o *= omega;
    }
    return turbulence ? sum + o * 0.2 : sum;
}

// pbrt-v4's marble colour at t in [0, 1]: a cubic Bezier segment of its colours, 1.5x.
vec3 noise_marble_colour(uint table, float t) {
    float first = max(min(floor(t * 6.0), 5.0), 0.0);
    float u = t * 6.0 - first;
    uint c = table + 512u + 3u * uint(first);
    vec3 p[4];
    for (uint k = 0u; k < 4u; ++k) p[k] = vec3(texels[c + 3u * k], texels[c + 3u * k + 1u], texels[c + 3u * k + 2u]);
    float s = 1.0 - u;
    vec3 rgb = s * s * s * p[0] + 3.0 * s * s * u * p[1] + 3.0 * s * u * u * p[2] + u * u * u * p[3];
    return clamp(1.5 * rgb, vec3(0.0), vec3(1.0));
}

// pbrt-v4's noise textures at the texture-space point q (abi.h NOISE_*).
vec3 noise_texture(uint table, uint kind, uint octaves, vec4 params, vec3 q) {
    float omega = params.x;
    if (kind == NOISE_WINDY) {
        return vec3(abs(noise_fbm(table, 0.1 * q, 0.5, 3u, false)) * noise_fbm(table, q, 0.5, 6u, false));
    }
    if (kind == NOISE_MARBLE) q *= params.y;
    float n = noise_fbm(table, q, omega, octaves, kind == NOISE_WRINKLED);
    if (kind != NOISE_MARBLE) return vec3(n);
    return noise_marble_colour(table, 0.5 + 0.5 * sin(q.y + params.z * n));
}

// Whether (s, t) is inside the polka dot of its cell (pbrt-v4's dots).
bool noise_inside_polka_dot(uint table, vec2 st) {
    vec2 cell = floor(st + 0.5);
    if (noise3(table, vec3(cell + 0.5, 0.5)) <= 0.0) return false;
    float radius = 0.35;
    float shift = 0.5 - radius;
    vec2 centre = cell + shift * vec2(noise3(table, vec3(cell + vec2(1.5, 2.8), 0.5)),
                                      noise3(table, vec3(cell + vec2(4.5, 9.8), 0.5)));
    vec2 d = st - centre;
    return dot(d, d) < radius * radius;
}
#endif
