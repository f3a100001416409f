// BDPT's first stage: the pixel's light subpath, its t = 1 splats and its stored
// vertices (lib/bdpt_pass.glsl says how the three stages divide a pass).
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_pass.glsl"

// Trace the light subpath, splatting t = 1 connections and storing vertices 1..stored
// at path_vertices[base + i - 1] (the light half of the pixel's slice). Returns the
// number stored.
uint light_subpath(uint base) {
    Walk w;
    LightEmission le;
    uint e;
    if (!light_walk_start(w, le, e)) return 0u;
    uvec2 px;
    vec3 value;
    float weight;
    if (min_scatter() == 0u && strategy_light_point_seen(le, e, px, value, weight)) add_splat(px, 1u, value, weight);
    // Light vertices serve only paths of at most max_scatter() scattering vertices.
    if (max_scatter() == 0u || min_scatter() > max_scatter()) return 0u;
    uint stored = 0u;
    for (uint i = 1u; i <= max_scatter(); ++i) {
        PathVertex y;
        if (!light_walk_next(w, y)) break;
        // Vertices that a camera vertex can still connect to (s + t - 2 <= max_scatter()
        // with t >= 2) are stored.
        if (i < max_scatter()) {
            path_vertices[base + i - 1u] = pack_vertex(y);
            stored = i;
        }
        if (i >= min_scatter() && strategy_camera_connection(y, px, value, weight)) add_splat(px, i + 1u, value, weight);
        if (i == max_scatter()) break;
        if (!light_walk_extend(w, y)) break;
    }
    return stored;
}

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(true, pixel, index, slot, base) || pass_params.samples == 0u) return;
    sampler_start(scene.seed, index, bdpt_sample());
    uint stored = light_subpath(base);
    subpaths[slot] = uvec4(stored, sampler_rng.counter, rays_traced, 0u);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
