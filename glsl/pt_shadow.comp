// The wavefront path tracer's shadow rays: each queued light sample's estimate is added
// to its path's radiance when nothing blocks it (and zero when something does, as an
// invocation carrying the path would add it).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "trace.glsl"

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_SHADOW, i)) return;
    GpuPtPath path = paths[i];
    bool visible = !trace_occluded(path.ls_wi.xyz, path.ls_le.xyz, path.ls_wi.w);
    vec3 L = path.radiance.xyz;
    L += path.ls_n.xyz * (visible ? path.ls_p.xyz : vec3(0.0));
    paths[i].radiance = vec4(L, uintBitsToFloat(floatBitsToUint(path.radiance.w) + 1u));
}
