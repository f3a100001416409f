// The gbuffer film's hit stage (lib/gbuffer.glsl): for each pixel of the band, its camera
// sample's first surface that is not only a boundary of media (pbrt's "interface"
// surfaces are passed through), whose P, N and Ns (in camera space, x right, y up, z
// ahead; or in the world, by scene.gbuffer_world) and (u, v) it adds to the film, and
// which it keeps for the albedo stage of the surface's material class.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "gbuffer.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "trace.glsl"
#include "visibility.glsl"
#include "camera.glsl"
#include "media.glsl"

// Pass-through surfaces a camera ray crosses at most before it counts as a miss.
const uint GBUFFER_MAX_CROSSINGS = 64u;

vec3 to_output(vec3 v, bool point) {
    if (scene.gbuffer_world != 0u) return v;
    if (point) v -= scene.cam_eye.xyz;
    return vec3(dot(v, scene.cam_right.xyz), dot(v, scene.cam_up.xyz), dot(v, scene.cam_forward.xyz));
}

void main() {
    uvec2 pixel;
    uint index, slot;
    if (!gbuffer_pixel(pixel, index, slot)) return;
    GpuGbufferSurface kept;
    kept.wo = vec4(0.0, 0.0, 0.0, uintBitsToFloat(GBUFFER_NO_SURFACE));
    kept.ns = vec4(0.0);
    kept.tex0 = vec4(0.0);
    kept.tex1 = vec4(0.0);
    kept.rng = uvec4(0u);
    Rng rng = rng_init(scene.seed, index, pass_params.first_sample);
    vec3 o, d;
    if (camera_sample(pixel, rng, o, d) != 0.0) {
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
        if (found) {
            vec3 wo = -d;
            bool front = dot(s.ng, wo) >= 0.0;
            kept.wo = vec4(wo, uintBitsToFloat(s.material));
            kept.ns = vec4(front ? s.ns : -s.ns, front ? 1.0 : 0.0);
            kept.tex0 = s.tex0;
            kept.tex1 = s.tex1;
            kept.rng = uvec4(rng.key, rng.counter);
            film[4u * index + 1u] += vec4(to_output(s.p, true), s.uv.x);
            film[4u * index + 2u] += vec4(to_output(s.ng, false), s.uv.y);
            film[4u * index + 3u] += vec4(to_output(s.ns, false), 0.0);
        }
    }
    gbuffer_surfaces[slot] = kept;
}
