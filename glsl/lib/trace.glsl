// The one visibility interface of every kernel:
//   bool trace_closest(vec3 o, vec3 d, float tmax, out Hit hit)
//   bool trace_occluded(vec3 o, vec3 d, float tmax)
// Rays start at t = 0 (origins are offset off surfaces by the caller). Two
// implementations, picked by build.rs's define: ray query or the BVH storage buffer.
#ifndef TRACE_GLSL
#define TRACE_GLSL
#include "geometry.glsl"

#if defined(ACCEL_RAYQUERY)
#include "trace_rayquery.glsl"
#elif defined(ACCEL_BVH)
#include "trace_bvh.glsl"
#else
#error "define ACCEL_RAYQUERY or ACCEL_BVH"
#endif
#endif
