// Between the wavefront's stages: each queue's dispatch arguments from its count (for
// the stage that consumes it), then the queues in wf.reset emptied. One invocation.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"

void main() {
    if (gl_GlobalInvocationID.x != 0u) return;
    for (uint q = 0u; q < WF_QUEUE_COUNT; ++q) {
        uint count = queues[q].x;
        queues[q].yzw = uvec3((count + WF_WORKGROUP_SIZE - 1u) / WF_WORKGROUP_SIZE, 1u, 1u);
        if ((wf.reset & (1u << q)) != 0u) queues[q].x = 0u;
    }
}
