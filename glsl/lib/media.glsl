// Participating media (FEATURE_MEDIA): pbrt-v4's homogeneous medium, the medium a ray is
// in (a medium code: MEDIUM_VACUUM or the GpuMedium's index + 1), and the two questions
// light transport asks of a medium along a ray: where a path's next event is (free-flight
// sampling, with the emission it passes) and how much of a shadow ray's light gets through
// (transmittance). CPU mirror: src/media.rs.
//
// RGB media are chromatic: sigma_t differs per channel. A distance is drawn from the
// density of one channel picked uniformly, and weighed by the mean of the three channels'
// densities (the one-sample MIS of the three, the balance heuristic: pbrt-v4's hero
// wavelength with its spectral MIS, for three channels), so that every channel is
// estimated without bias and none is sampled from a density that ignores it.
#ifndef MEDIA_GLSL
#define MEDIA_GLSL
#include "bindings.glsl"
#include "sampling.glsl"

layout(std430, set = 0, binding = BINDING_MEDIA) readonly buffer MediumBuffer { GpuMedium media[]; };

// The medium a ray leaving a surface of material m along w is in: the outside medium of
// the material's interface where w is on the side of pbrt's geometric normal ng, the
// inside one otherwise; the medium it arrived in (current) where the material bounds none.
uint medium_after(uint m, vec3 ng, vec3 w, uint current) {
    if ((materials[m].info.y & MATERIAL_MEDIUM_INTERFACE) == 0u) return current;
    uint packed = floatBitsToUint(materials[m].emission.w);
    return dot(w, ng) > 0.0 ? packed >> 16 : packed & 0xFFFFu;
}

bool material_passes_through(uint m) {
    return (materials[m].info.y & MATERIAL_PASS_THROUGH) != 0u;
}

vec3 medium_sigma_t(uint code) {
    return media[code - 1u].sigma_a.xyz + media[code - 1u].sigma_s.xyz;
}

float medium_g(uint code) { return media[code - 1u].sigma_a.w; }

// exp(-sigma_t d) per channel, 1 where sigma_t is 0 (also at d = INF).
vec3 medium_transmittance(vec3 sigma_t, float d) {
    return vec3(sigma_t.x > 0.0 ? exp(-sigma_t.x * d) : 1.0,
                sigma_t.y > 0.0 ? exp(-sigma_t.y * d) : 1.0,
                sigma_t.z > 0.0 ? exp(-sigma_t.z * d) : 1.0);
}

// A path's next event along its ray in the medium `code`, tmax the distance to the
// surface it meets (INF: none): from u, a channel c (u.x) and a distance t with density
// sigma_t[c] exp(-sigma_t[c] t) (u.y). scattered: t < tmax, a scattering vertex at t,
// and weight = sigma_s Tr(t) / p(t) (the phase function's draw goes on from there with
// f / pdf = 1; absorption is in the weight, not an event); else the surface is reached,
// weight = Tr(tmax) / P(t >= tmax). emitted: the medium's emission along [0, tmax), the
// estimate sigma_a Le Tr(t) / p(t) where t < tmax (to be multiplied by the throughput
// before this segment). p and P are the means of the three channels' densities.
struct MediumEvent {
    bool scattered;
    float t;
    vec3 weight;
    vec3 emitted;
};

MediumEvent sample_medium(uint code, float tmax, vec2 u) {
    GpuMedium m = media[code - 1u];
    vec3 sigma_a = m.sigma_a.xyz;
    vec3 sigma_s = m.sigma_s.xyz;
    vec3 sigma_t = sigma_a + sigma_s;
    uint c = min(uint(u.x * 3.0), 2u);
    float sc = sigma_t[c];
    MediumEvent ev;
    ev.t = sc > 0.0 ? -log(1.0 - u.y) / sc : INF;
    ev.scattered = ev.t < tmax;
    ev.emitted = vec3(0.0);
    if (ev.scattered) {
        vec3 tr = medium_transmittance(sigma_t, ev.t);
        float pdf = dot(sigma_t * tr, vec3(1.0 / 3.0));
        ev.weight = sigma_s * tr / pdf;
        ev.emitted = sigma_a * m.emission.xyz * tr / pdf;
    } else {
        vec3 tr = medium_transmittance(sigma_t, tmax);
        ev.weight = tr / dot(tr, vec3(1.0 / 3.0));
    }
    return ev;
}

// The same free flight drawn once for a whole ray through several media (pass-through
// boundaries between them), from one pair of numbers: a channel c (u.x) and an optical
// depth tau ~ Exp(1) (u.y) that the ray spends segment by segment in c's extinction;
// the ray scatters where it is spent. Its distance has channel c's density
// sigma_t[c](t) exp(-depth[c](t)) (depth: the optical depth from the ray's origin), and
// the weights are those of sample_medium with the three channels' densities along the
// whole ray. (MMLT's trace stage: its primary samples are a fixed number per ray,
// however many boundaries it crosses.)
struct FreeFlight {
    uint c;
    float tau;      // the optical depth left in channel c
    vec3 depth;     // the optical depth so far, per channel
};

FreeFlight free_flight_start(vec2 u) {
    FreeFlight f;
    f.c = min(uint(u.x * 3.0), 2u);
    f.tau = -log(1.0 - u.y);
    f.depth = vec3(0.0);
    return f;
}

// A segment of length len (INF: none ends it) in the medium `code`: true when the
// flight ends in it, at t (from the segment's start), weight sigma_s Tr / p; else the
// segment's optical depth is spent.
bool free_flight_segment(inout FreeFlight f, uint code, float len, out float t, out vec3 weight) {
    t = len;
    weight = vec3(1.0);
    if (code == MEDIUM_VACUUM) return false;
    vec3 sigma_t = medium_sigma_t(code);
    float sc = sigma_t[f.c];
    if (sc > 0.0 && f.tau < sc * len) {
        t = f.tau / sc;
        vec3 tr = exp(-(f.depth + sigma_t * t));
        weight = media[code - 1u].sigma_s.xyz * tr / dot(sigma_t * tr, vec3(1.0 / 3.0));
        return true;
    }
    // (A clear channel spends nothing, even along an endless segment.)
    vec3 spent = vec3(sigma_t.x > 0.0 ? sigma_t.x * len : 0.0, sigma_t.y > 0.0 ? sigma_t.y * len : 0.0,
                      sigma_t.z > 0.0 ? sigma_t.z * len : 0.0);
    f.tau -= spent[f.c];
    f.depth += spent;
    return false;
}

// The weight of a flight that reached the end of its ray: Tr / P(reaching it).
vec3 free_flight_through(FreeFlight f) {
    vec3 tr = exp(-f.depth);
    float p = dot(tr, vec3(1.0 / 3.0));
    return p > 0.0 ? tr / p : vec3(0.0);
}
#endif
