// The wavefront path tracer's state (pt_*.comp): one GpuPtPath per path in device
// memory, and queues of path indices that its stages fill with atomics and that the next
// stages consume through indirect dispatches (Laine, Karras & Aila 2013, "Megakernels
// Considered Harmful"). Each stage is its own small kernel: the visibility backend lives
// only in pt_trace and pt_shadow, each material class only in its pt_shade_* kernel, the
// emitters only in pt_hit. A path's arithmetic is the same, in the same order, as one
// invocation carrying it from the camera to its end would do, so the wavefront renders
// the same bits whatever order the queues hold it in.
//
// A wavefront is the samples first_sample .. first_sample + samples of a band of rows:
// path i is sample i / P of the band's pixel i % P (P the band's pixels).
#ifndef WAVEFRONT_GLSL
#define WAVEFRONT_GLSL
#include "abi.h"
#define OWN_PUSH_CONSTANTS
#include "bindings.glsl"
#include "rng.glsl"

layout(local_size_x = WF_WORKGROUP_SIZE) in;
layout(push_constant) uniform WavefrontBlock { WavefrontParams wf; };
layout(std430, set = 0, binding = BINDING_WF_PATHS) buffer PtPathBuffer { GpuPtPath paths[]; };
// Per queue: x its count, yzw the group counts of the dispatch that consumes it
// (written by wf_queues.comp).
layout(std430, set = 0, binding = BINDING_WF_QUEUES) buffer QueueBuffer { uvec4 queues[]; };
layout(std430, set = 0, binding = BINDING_WF_ITEMS) buffer QueueItemBuffer { uint queue_items[]; };

// Append path i to queue q.
void queue_push(uint q, uint i) {
    uint at = atomicAdd(queues[q].x, 1u);
    queue_items[q * wf.slots + at] = i;
}

// The path this invocation takes from queue q: false past the queue's end.
bool queue_take(uint q, out uint i) {
    uint at = gl_GlobalInvocationID.x;
    i = 0u;
    if (at >= queues[q].x) return false;
    i = queue_items[q * wf.slots + at];
    return true;
}

// The band's pixels.
uint wf_band_pixels() { return (wf.row_end - wf.row_begin) * scene.width; }

// Path i's pixel (image coordinates) and its sample index.
uvec2 wf_pixel(uint i) {
    uint p = i % wf_band_pixels();
    return uvec2(p % scene.width, wf.row_begin + p / scene.width);
}
uint wf_sample(uint i) { return wf.first_sample + i / wf_band_pixels(); }

// Path i's random numbers, `counter` (GpuPtPath.o.w) drawn so far: the stream an
// invocation carrying the path would draw from.
Rng wf_rng(uint i, float counter) {
    uvec2 pixel = wf_pixel(i);
    Rng rng = rng_init(scene.seed, pixel.y * scene.width + pixel.x, wf_sample(i));
    rng.counter = floatBitsToUint(counter);
    return rng;
}
#endif
