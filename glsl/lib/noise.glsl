// Procedural textures' noise (CPU mirror: src/noise.rs): Perlin's gradient noise and
// what pbrt-v4 builds on it (fBm, turbulence, windy waves, the marble spline, polka
// dots). The table (the permutation twice, then marble's colours) is in the texel
// buffer from float `table` on (abi.h TEXTURE_NOISE).
//
// Compile time: every lookup a texture makes goes through the one noise3 call of
// `procedural_value`'s loop, and noise3's eight corners through one noise_grad call (a
// kernel inlines these once per texture lookup site; unrolled copies cost lavapipe
// minutes).
#ifndef NOISE_GLSL
#define NOISE_GLSL
#extension GL_EXT_control_flow_attributes : require
#include "bindings.glsl"

int noise_perm(uint table, int i) { return int(texel(table + uint(i))); }

// The gradient of lattice point (x, y, z) dotted with the offset d from it.
float noise_grad(uint table, ivec3 c, vec3 d) {
    int h = noise_perm(table, noise_perm(table, noise_perm(table, c.x) + c.y) + c.z) & 15;
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
    vec3 w = vec3(noise_fade(d.x), noise_fade(d.y), noise_fade(d.z));
    // The trilinear interpolation of the corners' values as their weighted sum (no
    // array: a dynamically indexed one becomes a chain of selects).
    float sum = 0.0;
    [[dont_unroll]] for (int k = 0; k < 8; ++k) {
        ivec3 c = ivec3(k & 1, (k >> 1) & 1, k >> 2);
        vec3 a = mix(1.0 - w, w, vec3(c));
        sum += a.x * a.y * a.z * noise_grad(table, i + c, d - vec3(c));
    }
    return sum;
}

// pbrt-v4's marble colour at t in [0, 1]: a cubic Bezier segment of its colours, 1.5x.
vec3 noise_marble_colour(uint table, float t) {
    float first = max(min(floor(t * 6.0), 5.0), 0.0);
    float u = t * 6.0 - first;
    uint c = table + 512u + 3u * uint(first);
    vec3 p[4];
    for (uint k = 0u; k < 4u; ++k) p[k] = vec3(texel(c + 3u * k), texel(c + 3u * k + 1u), texel(c + 3u * k + 2u));
    float s = 1.0 - u;
    vec3 rgb = s * s * s * p[0] + 3.0 * s * s * u * p[1] + 3.0 * s * u * u * p[2] + u * u * u * p[3];
    return clamp(1.5 * rgb, vec3(0.0), vec3(1.0));
}

// pbrt-v4's count of octaves of a noise sum for a footprint of squared length len2 in the
// noise's space: the octaves coarser than the footprint, the last of them in part.
float noise_octaves(float len2, uint max_octaves) {
    return clamp(-1.0 - 0.5 * log2(len2), 0.0, float(max_octaves));
}

// A noise texture (abi.h TEXTURE_NOISE: NOISE_* in info.z, octaves in info.w, omega,
// marble's scale and variation in mapping.xyz) at the texture-space point q, whose pixel
// footprint there has squared length len2 (0: none, every octave), or dots
// (TEXTURE_DOTS) at (s, t). As pbrt-v4's: fBm sums the octaves coarser than the
// footprint, the last weighted by a smoothstep of its fraction; turbulence sums |noise|
// likewise, the partial octave blended toward 0.2, and 0.2 for each octave left out
// (pbrt-v4 counts the first of them twice); windy is three octaves of fBm at a tenth of
// the frequency (its strength) times six (its height); marble perturbs a sine by fBm and
// reads the colour spline; dots are three noise values of (s, t)'s cell. One loop and
// one noise3 call serve them all (the passes: windy's strength, then every sum's own).
vec3 procedural_value(GpuTexture t, vec3 q, vec2 st, float len2) {
    uint table = t.info.y;
    bool dots = t.info.x == TEXTURE_DOTS;
    uint kind = t.info.z;
    bool windy = !dots && kind == NOISE_WINDY;
    bool turbulence = !dots && kind == NOISE_WRINKLED;
    float omega = windy ? 0.5 : t.mapping.x;
    if (!dots && kind == NOISE_MARBLE) {
        q *= t.mapping.y;
        len2 *= t.mapping.y * t.mapping.y;
    }
    vec2 cell = floor(st + 0.5);
    // The pass: windy's strength first (at a tenth of the frequency), then the sum.
    bool strength_pass = windy;
    uint max_octaves = windy ? 3u : t.info.w;
    float n = dots ? 2.0 : noise_octaves(strength_pass ? 0.01 * len2 : len2, max_octaves);
    uint whole = uint(floor(n));
    float partial = dots ? 1.0 : n - floor(n);
    float sum = 0.0, strength = 0.0, lambda = 1.0, o = 1.0;
    float n0 = 0.0, n1 = 0.0, n2 = 0.0;
    uint k = 0u;
    [[dont_unroll]] while (true) {
        bool last = k == whole;
        float w = last ? (dots ? 1.0 : smoothstep(0.3, 0.7, partial)) : 1.0;
        if (w > 0.0) {
            vec3 x;
            if (dots) {
                x = vec3(cell + (k == 0u ? vec2(0.5) : k == 1u ? vec2(1.5, 2.8) : vec2(4.5, 9.8)), 0.5);
            } else {
                x = lambda * (strength_pass ? 0.1 * q : q);
            }
            float v = noise3(table, x);
            if (dots) {
                if (k == 0u) n0 = v; else if (k == 1u) n1 = v; else n2 = v;
            } else {
                if (turbulence) v = abs(v);
                sum += o * (!last ? v : turbulence ? mix(0.2, v, w) : w * v);
            }
        } else if (turbulence) {
            sum += o * 0.2;
        }
        if (!last) {
            lambda *= 1.99;
            o *= omega;
            k += 1u;
            continue;
        }
        if (dots) break;
        // The octaves left out.
        if (turbulence) {
            for (uint i = whole; i < max_octaves; ++i) {
                sum += o * 0.2;
                o *= omega;
            }
        }
        if (!strength_pass) break;
        strength = sum;
        strength_pass = false;
        max_octaves = 6u;
        n = noise_octaves(len2, max_octaves);
        whole = uint(floor(n));
        partial = n - floor(n);
        sum = 0.0;
        lambda = 1.0;
        o = 1.0;
        k = 0u;
    }
    if (dots) {
        float radius = 0.35;
        vec2 d = st - (cell + (0.5 - radius) * vec2(n1, n2));
        return n0 > 0.0 && dot(d, d) < radius * radius ? t.scale.xyz : t.other.xyz;
    }
    if (windy) return vec3(abs(strength) * sum);
    if (kind == NOISE_MARBLE) return noise_marble_colour(table, 0.5 + 0.5 * sin(q.y + t.mapping.z * sum));
    return vec3(sum);
}
#endif
