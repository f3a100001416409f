// The traversal probe (for tests): traces a list of rays with trace_closest and
// trace_occluded, so that each visibility backend can be checked against brute force on
// the device itself (src/probe.rs). In: two vec4 per ray, (origin, tmax) and
// (direction, 0); pass_params.samples rays. Out: two uvec4 per ray, (closest primitive or
// 0xffffffff, its t as float bits, 1 if occluded, 0) and surface_at's shading normal at
// the closest hit (float bits; bump and normal maps included, for their mirror's test).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = PROBE_WORKGROUP_SIZE) in;
#include "bindings.glsl"
#include "trace.glsl"
#include "geometry.glsl"

layout(std430, set = 0, binding = BINDING_PROBE_RAYS) readonly buffer ProbeRays { vec4 probe_rays[]; };
layout(std430, set = 0, binding = BINDING_PROBE_HITS) writeonly buffer ProbeHits { uvec4 probe_hits[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pass_params.samples) return;
    vec4 a = probe_rays[2u * i];
    vec4 b = probe_rays[2u * i + 1u];
    Hit hit;
    bool found = trace_closest(a.xyz, b.xyz, a.w, hit);
    bool occluded = trace_occluded(a.xyz, b.xyz, a.w);
    probe_hits[2u * i] = uvec4(found ? hit.prim : 0xffffffffu, floatBitsToUint(hit.t), occluded ? 1u : 0u, 0u);
    vec3 ns = found ? surface_at(hit, a.xyz, b.xyz).ns : vec3(0.0);
    probe_hits[2u * i + 1u] = uvec4(floatBitsToUint(ns), 0u);
}
