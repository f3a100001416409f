// `analyticdirect`: the exact direct lighting of diffuse surfaces, with no visibility,
// from polygonal emitters (Lambert's formula for the irradiance of a polygon:
// E = L/2 * sum_i theta_i * dot(n, gamma_i), Arvo 1995), point, spot and directional
// lights, a constant environment (E = pi L), and spheres (a sphere of radius r whose
// centre is at distance D, at angle theta from the normal, gives E = pi L (r/D)^2
// cos theta, whatever side of it emits toward p: its visible cap is the same disk of
// directions; in front of a constant environment it replaces that disk of the
// environment's radiance). A closed-form oracle for the Monte Carlo integrators on unoccluded
// scenes. Ellipsoids (non-uniformly scaled spheres) are left out. No horizon clipping:
// lights must lie entirely above the surfaces they light.
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

// Irradiance factor sum_i theta_i * dot(n, gamma_i) / 2 of the triangle (v0, v1, v2) at p.
float polygon_irradiance_factor(vec3 p, vec3 n, vec3 v0, vec3 v1, vec3 v2) {
    vec3 r[3] = vec3[3](normalize(v0 - p), normalize(v1 - p), normalize(v2 - p));
    float sum = 0.0;
    for (int i = 0; i < 3; ++i) {
        vec3 a = r[i];
        vec3 b = r[(i + 1) % 3];
        float theta = acos(clamp(dot(a, b), -1.0, 1.0));
        vec3 c = cross(a, b);
        float len = length(c);
        if (len > 0.0) sum += theta * dot(n, c / len);
    }
    return 0.5 * abs(sum);
}

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
        camera_ray(camera_pixel_film(pixel, u_pixel), u_lens, o, d);
        Hit hit;
        rays++;
        if (!trace_closest(o, d, INF, hit)) {
            if (scene.environment != NO_EMITTER) sum += environment_radiance(d);
            continue;
        }
        Surface s = surface_at(hit, o, d);
        vec3 wo = -d;
        vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;
        vec3 L = s.emitter != NO_EMITTER ? emitted_radiance(s.material, s.ng, wo) : vec3(0.0);
        vec3 E = vec3(0.0);
        for (uint e = 0u; e < scene.emitter_count; ++e) {
            GpuEmitter em = emitters[e];
            if (em.info.x == EMITTER_TRIANGLE) {
                if (em.info.y == s.prim) continue;
                vec3 ne = cross(em.p1.xyz - em.p0.xyz, em.p2.xyz - em.p0.xyz);
                // One-sided emitters light only the half-space in front of them.
                if (em.info.z == 0u && dot(s.p - em.p0.xyz, ne) <= 0.0) continue;
                E += em.radiance.xyz * polygon_irradiance_factor(s.p, n, em.p0.xyz, em.p1.xyz, em.p2.xyz);
            } else if (em.info.x == EMITTER_POINT) {
                vec3 to = em.p0.xyz - s.p;
                float d2 = dot(to, to);
                E += em.radiance.xyz * max(0.0, dot(n, to) / sqrt(d2)) / d2;
            } else if (em.info.x == EMITTER_INFINITE) {
                // The whole hemisphere, unoccluded: E = pi L.
                E += PI * em.radiance.xyz;
            } else if (em.info.x == EMITTER_SPOT) {
                vec3 to = em.p0.xyz - s.p;
                float d2 = dot(to, to);
                vec3 w = to / sqrt(d2);
                E += em.radiance.xyz * spot_falloff(em, -w) * max(0.0, dot(n, w)) / d2;
            } else if (em.info.x == EMITTER_DIRECTIONAL) {
                E += em.radiance.xyz * max(0.0, dot(n, em.p0.xyz));
            } else if (em.info.x == EMITTER_SPHERE) {
                GpuSphere sp = spheres[em.info.y];
                if (em.info.y + scene.triangle_count == s.prim) continue;
                vec3 to = vec3(sp.o2w0.w, sp.o2w1.w, sp.o2w2.w) - s.p;
                // (A uniform scale: every column of the object-to-world map has length r.)
                float r2 = dot(vec3(sp.o2w0.x, sp.o2w1.x, sp.o2w2.x), vec3(sp.o2w0.x, sp.o2w1.x, sp.o2w2.x));
                float d2 = dot(to, to);
                // (It hides the constant environment behind it: that part of the
                // hemisphere's E = pi L_env is replaced.)
                vec3 behind = scene.environment != NO_EMITTER ? emitters[scene.environment].radiance.xyz : vec3(0.0);
                E += (em.radiance.xyz - behind) * (PI * r2 / d2) * max(0.0, dot(n, to) / sqrt(d2));
            }
        }
        sum += L + material_bsdf(materials[s.material], true, s.uv).kd * INV_PI * E;
    }
    film[index] += vec4(sum, float(rays));
}
