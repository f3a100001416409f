// BDPT's second stage: the pixel's camera subpath, its strategies with s = 0 and s = 1
// added to the pixel's film, and its vertices that can connect stored for the third
// (lib/bdpt_pass.glsl says how the three stages divide a pass). Its draws continue the
// light stage's sample where that one stopped.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_pass.glsl"

// The camera subpath with s = 0 and s = 1 strategies at each vertex; the vertices that
// can connect to one of the `stored` light vertices (s >= 2) are stored at
// path_vertices[base + vertex_stride() + k - 1], `connectable` of them. Returns the
// pixel's camera-film contribution.
//
// maxdepth -1: paths of up to max_scatter (BDPT_UNBOUNDED_DEPTH_CAP) scattering vertices
// get every strategy. Longer ones, which only the camera subpath reaches (light
// subpaths are stored, so bounded), go on with Russian roulette up to the path tracer's
// UNBOUNDED_DEPTH_CAP and combine the two strategies left to them, s = 0 and s = 1, by
// the power heuristic, as the path tracer does. Path length splits path space, so the
// two regimes add up to the whole, unbiased.
vec3 camera_subpath(uvec2 pixel, uint base, uint stored, out uint connectable) {
    connectable = 0u;
    uint pixel_index = pixel.y * scene.width + pixel.x;
    Walk w;
    camera_walk_start((vec2(pixel) + sample_2d(STREAM_CAMERA)) / vec2(uvec2(scene.width, scene.height)), w);
    vec3 L = vec3(0.0);
    bool unbounded = scene.unbounded != 0u;
    uint max_vertices = unbounded ? UNBOUNDED_DEPTH_CAP : max_scatter();
    for (uint k = 1u; k <= max_vertices + 1u; ++k) {
        // The vertex z_k; strategies here have t = k + 1.
        PathVertex z;
        vec3 value;
        float weight;
        if (!camera_walk_next(w, z)) {
            // s = 0 toward the environment (k - 1 scattering vertices).
            if (w.escaped && k - 1u >= min_scatter() && strategy_environment_hit(w, value, weight)) add_camera(L, 0u, k + 1u, pixel_index, value, weight);
            break;
        }
        // s = 0: the camera subpath found an emitter (k - 1 scattering vertices).
        if (k - 1u >= min_scatter() && strategy_emitter_hit(w, z, value, weight)) add_camera(L, 0u, k + 1u, pixel_index, value, weight);
        if (k > max_vertices) break;
        // s = 1: a fresh sample on a light (k scattering vertices).
        if (k >= min_scatter() && strategy_light_sample(w, z, value, weight)) add_camera(L, 1u, k + 1u, pixel_index, value, weight);
        // s >= 2 (bdpt_connect.comp): light vertices y_j with j + k <= max_scatter().
        if (k < max_scatter() && stored > 0u) {
            path_vertices[base + vertex_stride() + k - 1u] = pack_vertex(z);
            connectable = k;
        }
        if (!camera_walk_extend(w, z)) break;
    }
    return L;
}

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uvec4 light = subpaths[slot];
    sampler_start(scene.seed, index, bdpt_sample());
    sampler_rng.counter = light.y;
    rays_traced = light.z;
    uint connectable;
    vec3 sum = camera_subpath(pixel, base, light.x, connectable);
    subpaths[slot].w = connectable;
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
    film[index] += vec4(sum, float(rays_traced));
}
