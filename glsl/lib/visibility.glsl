// Visibility as the one-invocation-per-path kernels ask it (direct lighting, BDPT, MMLT):
// the closest hit and a light sample's shadow ray through the backend's trace.glsl,
// counted in rays_traced. (The wavefront path tracer traces in stages of its own:
// pt_trace.comp, pt_shadow.comp.)
#ifndef VISIBILITY_GLSL
#define VISIBILITY_GLSL
#include "trace.glsl"
#include "lights.glsl"

// Rays this invocation has traced (film.w, MMLT's ray counts).
uint rays_traced = 0u;

bool closest(vec3 o, vec3 d, out Hit hit) {
    rays_traced++;
    return trace_closest(o, d, INF, hit);
}

// Is the light sample visible from p (offset along n toward the light)? Not counted:
// the callers count their shadow rays.
bool light_sample_visible(vec3 p, vec3 n, LightSample ls) {
    vec3 o, d;
    float tmax;
    light_sample_shadow_ray(p, n, ls, o, d, tmax);
    return !trace_occluded(o, d, tmax);
}
#endif
