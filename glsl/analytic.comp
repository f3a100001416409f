// `analyticdirect`: the exact direct lighting of diffuse surfaces, with no visibility,
// from every emitter (each kind's closed form is lights.glsl's
// emitter_unoccluded_irradiance). A closed-form oracle for the Monte Carlo integrators on
// unoccluded scenes.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bindings.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return;
    uint index = pixel.y * scene.width + pixel.x;
    vec3 sum = vec3(0.0);
    uint rays = 0u;
    for (uint i = 0u; i < pass_params.samples; ++i) {
        Rng rng = rng_init(scene.seed, index, pass_params.first_sample + i);
        vec2 u_pixel = rng_next2(rng);
        vec2 u_lens = vec2(0.0);
        if (camera_has_lens()) u_lens = rng_next2(rng);
        vec3 o, d;
        float weight = camera_ray(camera_pixel_film(pixel, u_pixel), u_lens, o, d);
        Hit hit;
        rays++;
        if (weight == 0.0) continue;
        if (!trace_closest(o, d, INF, hit)) {
            if (scene.environment != NO_EMITTER) sum += weight * environment_radiance(o, d);
            continue;
        }
        Surface s = surface_at(hit, o, d);
        vec3 wo = -d;
        vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;
        vec3 L = s.emitter != NO_EMITTER ? emitted_radiance(s.material, s.ng, wo) : vec3(0.0);
        vec3 E = vec3(0.0);
        for (uint e = 0u; e < scene.emitter_count; ++e) E += emitter_unoccluded_irradiance(e, s.p, n, s.prim);
        sum += weight * (L + material_bsdf(materials[s.material], true, s.tex0, s.tex1).kd * INV_PI * E);
    }
    film[index] += vec4(sum, float(rays));
}
