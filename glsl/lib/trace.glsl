// The one visibility interface of every kernel:
//   bool trace_ray(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit)
// the backend's traversal: the closest hit along the ray within tmax, or (any_hit) whether
// anything blocks it; and over it
//   bool trace_closest(vec3 o, vec3 d, float tmax, out Hit hit)
//   bool trace_occluded(vec3 o, vec3 d, float tmax)
// Each call site is a copy of the backend (with the alpha test's textures): a kernel that
// traces both kinds of ray in one place passes any_hit at run time (bdpt_trace,
// mmlt_trace). Rays start at t = 0 (origins are offset off surfaces by the caller). Three
// implementations, picked by build.rs's define: ray query, or one of two BVHs in storage
// buffers (compressed 8-wide or binary).
#ifndef TRACE_GLSL
#define TRACE_GLSL
#include "geometry.glsl"

#ifdef PROFILE_X2_TRACE
// lightpath profile: every ray is traced twice (the extra time is visibility's share
// of a pass: traversal and primitive tests).
#define trace_ray trace_ray_once
#endif

#if defined(ACCEL_RAYQUERY)
#include "trace_rayquery.glsl"
#elif defined(ACCEL_CWBVH)
#include "trace_cwbvh.glsl"
#elif defined(ACCEL_BVH2)
#include "trace_bvh2.glsl"
#else
#error "define ACCEL_RAYQUERY, ACCEL_CWBVH or ACCEL_BVH2"
#endif

#ifdef PROFILE_X2_TRACE
#undef trace_ray
// The second ray's origin and extent differ by an ulp and its answer is kept only where the first
// found nothing and it did (never in practice), so both traversals are computed.
bool trace_ray(vec3 o, vec3 d, float tmax, bool any_hit, out Hit hit) {
    Hit other;
    bool b = trace_ray_once(o * 1.0000001, d, tmax * 0.99999994, any_hit, other);
    bool a = trace_ray_once(o, d, tmax, any_hit, hit);
    if (any_hit) return a || (b && tmax < 0.0);
    if (!a && b) {
        hit = other;
        return true;
    }
    return a;
}
#endif

bool trace_closest(vec3 o, vec3 d, float tmax, out Hit hit) {
    return trace_ray(o, d, tmax, false, hit);
}

bool trace_occluded(vec3 o, vec3 d, float tmax) {
    Hit hit;
    return trace_ray(o, d, tmax, true, hit);
}
#endif
