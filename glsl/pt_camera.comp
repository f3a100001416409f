// The wavefront path tracer's first stage: each path's camera ray, its throughput and
// radiance set, and the path queued for tracing.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "camera.glsl"
#include "features.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= wf.slots) return;
    Rng rng = wf_rng(i, uintBitsToFloat(0u));
    vec3 o, d;
    float weight = camera_sample(wf_pixel(i), rng, o, d);
    paths[i].o = vec4(o, uintBitsToFloat(rng.counter));
    // (In media, the path starts in the camera's medium.)
    uint flags = has_feature(FEATURE_MEDIA) ? scene.camera_medium << PT_PATH_MEDIUM_SHIFT : 0u;
    paths[i].d = vec4(d, uintBitsToFloat(flags));
    paths[i].beta = vec4(vec3(weight), 0.0);
    paths[i].radiance = vec4(vec3(0.0), uintBitsToFloat(0u));
    paths[i].prev_p = vec4(o, 0.0);
    queue_push(WF_QUEUE_RAYS, i);
}
