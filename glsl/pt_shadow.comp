// The wavefront path tracer's shadow rays: each queued light sample's estimate is added
// to its path's radiance when nothing blocks it (and zero when something does, as an
// invocation carrying the path would add it). In media (FEATURE_MEDIA) the ray goes on
// through pass-through surfaces (boundaries of media, MATERIAL_PASS_THROUGH), and the
// estimate is multiplied by the transmittance of each medium it crosses (the medium it
// starts in: GpuPtPath.ls_le.w).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "trace.glsl"
#include "media.glsl"

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_SHADOW, i)) return;
    GpuPtPath path = paths[i];
    vec3 o = path.ls_wi.xyz;
    vec3 d = path.ls_le.xyz;
    float tmax = path.ls_wi.w;
    uint rays = 1u;
    vec3 L = path.radiance.xyz;
    if (!has_feature(FEATURE_MEDIA)) {
        bool visible = !trace_occluded(o, d, tmax);
        L += path.ls_n.xyz * (visible ? path.ls_p.xyz : vec3(0.0));
    } else {
        vec3 tr = vec3(1.0);
        uint medium = floatBitsToUint(path.ls_le.w);
        vec3 end = o + tmax * d;
        uint seed = medium_ray_seed(o, d);
        for (uint k = 0u; k <= MAX_PASS_THROUGH; ++k) {
            Hit hit;
            bool found = trace_closest(o, d, tmax, hit);
            tr *= medium_segment_transmittance(medium, o, d, found ? hit.t : tmax, seed);
            if (!found) break;
            vec3 ng;
            uint m = primitive_material(hit, o, d, ng);
            if (!material_passes_through(m) || k == MAX_PASS_THROUGH) {
                tr = vec3(0.0);
                break;
            }
            medium = medium_after(m, ng, d, medium);
            o = offset_ray_origin(o + hit.t * d, dot(d, ng) > 0.0 ? ng : -ng);
            tmax = isinf(tmax) ? tmax : max(dot(end - o, d), 0.0);
            rays++;
        }
        L += path.ls_n.xyz * (path.ls_p.xyz * tr);
    }
    paths[i].radiance = vec4(L, uintBitsToFloat(floatBitsToUint(path.radiance.w) + rays));
}
