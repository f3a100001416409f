// BDPT's wavefront (lib/bdpt_wave.glsl): its last stage, one invocation per pixel of the
// band. For each sample of the dispatch in order, the sums its walk kept: the camera
// subpath's strategies (s = 0, 1) and rays, then its s, t >= 2 connections and their
// shadow rays, added to the pixel's film: the order in which passes of one sample each
// would add them.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint stride = 2u * vertex_stride();
    for (uint s = 0u; s < pass_params.samples; ++s) {
        uint at = slot + s * band_pixels();
        if (stride > 0u && (at + 1u) * stride > uint(path_vertices.length())) break;
        film[index] += vec4(walks[at].radiance.xyz, float(walks[at].counts.y));
        film[index] += walks[at].connected;
    }
}
