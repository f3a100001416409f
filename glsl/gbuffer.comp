// pbrt-v4's `gbuffer` film: what the camera sees first in each pixel, beside the image
// (src/integrators/gbuffer.rs). One invocation per pixel adds pass_params.samples camera
// samples into four vec4 of the film buffer: (albedo, 0), (P, u), (N, v), (Ns, 0) — sums
// over samples; a sample that sees no surface adds zeros, as pbrt-v4's film does.
// P, N and Ns are in camera space (x right, y up, z ahead) or in the world, by
// scene.gbuffer_world. The albedo is the BSDF's directional albedo ρ(wo), the mean of
// f |cos| / pdf over GBUFFER_RHO_SAMPLES samples of the BSDF (pbrt-v4's VisibleSurface
// estimates it so, with 16). Surfaces that only bound media (pbrt's "interface") are
// passed through.
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
#include "media.glsl"

const uint GBUFFER_RHO_SAMPLES = 16u;
// Pass-through surfaces a camera ray crosses at most before it counts as a miss.
const uint GBUFFER_MAX_CROSSINGS = 64u;

vec3 to_output(vec3 v, bool point) {
    if (scene.gbuffer_world != 0u) return v;
    if (point) v -= scene.cam_eye.xyz;
    return vec3(dot(v, scene.cam_right.xyz), dot(v, scene.cam_up.xyz), dot(v, scene.cam_forward.xyz));
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return;
    uint index = pixel.y * scene.width + pixel.x;
    vec4 sums[4] = vec4[4](vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    for (uint i = 0u; i < pass_params.samples; ++i) {
        Rng rng = rng_init(scene.seed, index, pass_params.first_sample + i);
        vec3 o, d;
        if (camera_sample(pixel, rng, o, d) == 0.0) continue;
        Hit hit;
        Surface s;
        bool found = false;
        for (uint k = 0u; k < GBUFFER_MAX_CROSSINGS; ++k) {
            if (!closest(o, d, hit)) break;
            s = surface_at(hit, o, d);
            if (!material_passes_through(s.material)) {
                found = true;
                break;
            }
            o = offset_ray_origin(s.p, dot(s.ng, d) > 0.0 ? s.ng : -s.ng);
        }
        if (!found) continue;
        vec3 wo = -d;
        BsdfParams b = material_bsdf(materials[s.material], dot(s.ng, wo) >= 0.0, s.tex0, s.tex1);
        vec3 ns = dot(s.ng, wo) < 0.0 ? -s.ns : s.ns;
        vec3 rho = vec3(0.0);
        for (uint j = 0u; j < GBUFFER_RHO_SAMPLES; ++j) {
            BsdfSample bs;
            if (bsdf_sample(b, SAMPLE_BRDF, ns, wo, rng_next3(rng), TRANSPORT_RADIANCE, bs) && bs.pdf > 0.0)
                rho += bs.f * abs(dot(bs.wi, ns)) / bs.pdf;
        }
        rho /= float(GBUFFER_RHO_SAMPLES);
        if (any(isnan(rho)) || any(isinf(rho))) rho = vec3(0.0);
        sums[0].xyz += rho;
        sums[1] += vec4(to_output(s.p, true), s.uv.x);
        sums[2] += vec4(to_output(s.ng, false), s.uv.y);
        sums[3].xyz += to_output(s.ns, false);
    }
    for (uint k = 0u; k < 4u; ++k) film[4u * index + k] += sums[k];
}
