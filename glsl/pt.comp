// One pass of the unidirectional integrators: `pathtracer` (every option of the scene
// format) and `direct` (lightsamples, lightstratify). One invocation per pixel adds
// pass_params.samples samples to the film; film.w counts the rays traced.
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
#include "camera.glsl"

uint rays_traced = 0u;

bool closest(vec3 o, vec3 d, out Hit hit) { rays_traced++; return trace_closest(o, d, INF, hit); }

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

// A camera ray through the pixel: two numbers over the pixel, two over a thin lens.
void camera_sample(uvec2 pixel, inout Rng rng, out vec3 o, out vec3 d) {
    vec2 u_pixel = rng_next2(rng);
    vec2 u_lens = vec2(0.0);
    if (camera_has_lens()) u_lens = rng_next2(rng);
    camera_ray(camera_pixel_film(pixel, u_pixel), u_lens, o, d);
}

vec3 path_sample(uvec2 pixel, inout Rng rng) {
    vec3 o, d;
    camera_sample(pixel, rng, o, d);
    uint nee = scene.nee;
    bool rr = scene.russian_roulette != 0u;
    uint mode = scene.sample_mode;
    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : scene.max_depth;
    bool have_emitters = scene.emitter_count > 0u;

    vec3 L = vec3(0.0);
    vec3 beta = vec3(1.0);
    float prev_pdf = 0.0;   // solid-angle pdf of the BSDF sample that led here
    bool prev_delta = false; // ... or whether it was a delta lobe (no light sample could find it)
    vec3 prev_p = o;
    for (uint depth = 0u;; ++depth) {
        Hit hit;
        if (!closest(o, d, hit)) {
            // The environment, found by the path itself.
            if (scene.environment != NO_EMITTER) {
                vec3 Le = environment_radiance(d);
                if (depth == 0u || nee == NEE_OFF || prev_delta) {
                    L += beta * Le;
                } else if (nee == NEE_MIS) {
                    L += beta * Le * power_heuristic(prev_pdf, environment_pdf(d));
                }
            }
            break;
        }
        Surface s = surface_at(hit, o, d);
        vec3 wo = -d;
        BsdfParams b = material_bsdf(materials[s.material], dot(s.ng, wo) >= 0.0, s.uv);
        // Emission found by the path itself.
        if (s.emitter != NO_EMITTER) {
            vec3 Le = emitted_radiance(s.material, s.ng, wo);
            if (depth == 0u || nee == NEE_OFF || prev_delta) {
                L += beta * Le;
            } else if (nee == NEE_MIS && Le != vec3(0.0)) {
                L += beta * Le * emitter_hit_mis_weight(s.emitter, prev_p, prev_pdf, s.p, s.ng);
            }
        }
        // This hit is scattering vertex depth+1; paths have at most max_vertices of them.
        if (depth + 1u > max_vertices) break;
        vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;
        vec3 ns = dot(s.ng, wo) < 0.0 ? -s.ns : s.ns;
        // Seen from behind its shading normal, the surface reflects nothing.
        if (!(dot(ns, wo) > 0.0)) break;
        // (A delta BSDF cannot be reached by a light sample: no NEE there.)
        bool delta = bsdf_is_delta(b);
        if (nee != NEE_OFF && have_emitters && !delta) {
            uint e = pick_emitter(rng_block(rng).x);
            L += beta * estimate_direct(b, s.p, n, ns, wo, e, rng_next2(rng), nee == NEE_MIS, mode);
        }
        // With NEE on, emission found by the next bounce would not count (unless this
        // vertex is a delta one): stop here.
        if (nee == NEE_ON && depth + 1u == max_vertices && !delta) break;
        BsdfSample bs;
        if (!bsdf_sample(b, mode, ns, wo, rng_next3(rng), TRANSPORT_RADIANCE, bs)) break;
        if (!shading_side_agrees(n, ns, bs.wi)) break;
        float cos_i = dot(n, bs.wi);
        beta *= bs.f * (abs(dot(ns, bs.wi)) / bs.pdf);
        if (beta == vec3(0.0)) break;
        if (rr) {
            float survive = min(1.0, max(beta.x, max(beta.y, beta.z)));
            if (rng_next(rng) >= survive) break;
            beta /= survive;
        }
        prev_pdf = bs.pdf;
        prev_delta = (bs.flags & BSDF_LOBE_DELTA) != 0u;
        prev_p = s.p;
        o = offset_ray_origin(s.p, cos_i > 0.0 ? n : -n);
        d = bs.wi;
    }
    return L;
}

// The `direct` integrator: emission seen by the camera plus lightsamples light samples
// at the first hit, stratified on a sqrt(N) x sqrt(N) grid when asked.
vec3 direct_sample(uvec2 pixel, inout Rng rng) {
    vec3 o, d;
    camera_sample(pixel, rng, o, d);
    Hit hit;
    if (!closest(o, d, hit)) return scene.environment != NO_EMITTER ? environment_radiance(d) : vec3(0.0);
    Surface s = surface_at(hit, o, d);
    vec3 wo = -d;
    vec3 L = vec3(0.0);
    if (s.emitter != NO_EMITTER) L += emitted_radiance(s.material, s.ng, wo);
    if (scene.emitter_count == 0u || (scene.max_depth == 0u && scene.unbounded == 0u)) return L;
    BsdfParams b = material_bsdf(materials[s.material], dot(s.ng, wo) >= 0.0, s.uv);
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
        vec3 L = scene.integrator == INTEGRATOR_DIRECT ? direct_sample(pixel, rng) : path_sample(pixel, rng);
        if (any(isnan(L)) || any(isinf(L))) {
            atomicAdd(stats[STAT_NONFINITE], 1u);
        } else {
            sum += L;
        }
    }
    film[index] += vec4(sum, float(rays_traced));
}
