// The wavefront path tracer's closest hits: every queued ray against the scene, through
// the backend's trace.glsl (the only stage besides pt_shadow that holds it).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "trace.glsl"

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_RAYS, i)) return;
    Hit hit;
    bool found = trace_closest(paths[i].o.xyz, paths[i].d.xyz, INF, hit);
    paths[i].radiance.w = uintBitsToFloat(floatBitsToUint(paths[i].radiance.w) + 1u);
    paths[i].prev_p.w = found ? hit.t : 0.0;
    paths[i].hit.xyz = vec3(uintBitsToFloat(found ? hit.prim : NO_HIT), hit.bary);
}
