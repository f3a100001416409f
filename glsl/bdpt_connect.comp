// BDPT's third stage: every stored camera vertex z_k connected to every stored light
// vertex y_j whose path stays within maxdepth (s = j + 1 >= 2, t = k + 1 >= 2), added to
// the pixel's film after the camera stage's strategies (lib/bdpt_pass.glsl says how the
// three stages divide a pass). It draws no random numbers.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_pass.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uvec4 counts = subpaths[slot];
    vec3 L = connect_strategies(index, base, counts.x, counts.w);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
    film[index] += vec4(L, float(rays_traced));
}
