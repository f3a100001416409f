// One pass of the `direct` integrator (lightsamples, lightstratify): one invocation per
// pixel adds pass_params.samples samples to the film; film.w counts the rays traced.
// (The path tracer is the wavefront of pt_*.comp.)
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bindings.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "visibility.glsl"
#include "camera.glsl"

bool light_visible(vec3 p, vec3 n, LightSample ls) {
    rays_traced++;
    return light_sample_visible(p, n, ls);
}

// Light sampling at a surface point (geometric normal n and shading normal ns on the side
// of wo): f * cos * L / pdf, MIS-weighted when asked.
vec3 estimate_direct(BsdfParams b, vec3 p, vec3 n, vec3 ns, vec3 wo, uint e, vec2 u, bool mis, uint mode) {
    LightSample ls;
    vec3 f;
    float cos_s;
    float pdf_fwd, pdf_rev;
    if (!sample_direct_light(b, e, p, n, ns, wo, u, mode, mis, false, ls, f, cos_s, pdf_fwd, pdf_rev)) return vec3(0.0);
    if (!light_visible(p, n, ls)) return vec3(0.0);
    float w = 1.0;
    if (mis) w = light_sample_mis_weight(ls, pdf_fwd);
    return f * ls.L * (cos_s * w / ls.pdf);
}

// The `direct` integrator: emission seen by the camera plus lightsamples light samples
// at the first hit, stratified on a sqrt(N) x sqrt(N) grid when asked.
vec3 direct_radiance(vec3 o, vec3 d, inout Rng rng);

vec3 direct_sample(uvec2 pixel, inout Rng rng) {
    vec3 o, d;
    float weight = camera_sample(pixel, rng, o, d);
    return weight == 0.0 ? vec3(0.0) : weight * direct_radiance(o, d, rng);
}

// The radiance along the camera ray (o, d).
vec3 direct_radiance(vec3 o, vec3 d, inout Rng rng) {
    Hit hit;
    if (!closest(o, d, hit)) return scene.environment != NO_EMITTER ? environment_radiance(o, d) : vec3(0.0);
    Surface s = surface_at(hit, o, d);
    vec3 wo = -d;
    vec3 L = vec3(0.0);
    if (s.emitter != NO_EMITTER) L += emitted_radiance(s.material, s.ng, wo);
    if (scene.emitter_count == 0u || (scene.max_depth == 0u && scene.unbounded == 0u)) return L;
    BsdfParams b = material_bsdf(materials[s.material], dot(s.ng, wo) >= 0.0, s.tex0, s.tex1);
    vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;
    vec3 ns = dot(s.ng, wo) < 0.0 ? -s.ns : s.ns;
    uint count = max(scene.light_samples, 1u);
    uint strata = scene.light_stratify != 0u ? uint(floor(sqrt(float(count)) + 1e-3)) : 0u;
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < count; ++k) {
        uint e = pick_emitter(rng_block(rng).x);
        vec2 u = rng_next2(rng);
        if (k < strata * strata) u = (vec2(float(k % strata), float(k / strata)) + u) / float(strata);
        sum += estimate_direct(b, s.p, n, ns, wo, e, u, false, SAMPLE_BRDF);
    }
    return L + sum / float(count);
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return;
    uint index = pixel.y * scene.width + pixel.x;
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < pass_params.samples; ++i) {
        Rng rng = rng_init(scene.seed, index, pass_params.first_sample + i);
        vec3 L = direct_sample(pixel, rng);
        if (any(isnan(L)) || any(isinf(L))) {
            atomicAdd(stats[STAT_NONFINITE], 1u);
        } else {
            sum += L;
        }
    }
    film[index] += vec4(sum, float(rays_traced));
}
