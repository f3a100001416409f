// BDPT's wavefront (lib/bdpt_wave.glsl): the surface interaction. The vertex at the
// walk's hit (light side: y_i; camera side: z_k), found with its material's textures and
// maps, stored in the walk for the stages after (the camera side's emit stage, the shade
// stage of its material class) and in the path-vertex buffer when a connection can use
// it. No emitter code: what the emitters give at a camera vertex is bdpt_emit's.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & BDPT_WALK_RAY) == 0u) return;
    flags &= ~BDPT_WALK_RAY;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    uint prim = floatBitsToUint(g.hit.x);
    Hit hit;
    hit.t = g.hit.w;
    hit.prim = prim;
    hit.bary = g.hit.yz;
    PathVertex v;
    // (One surface_at for both sides: each call site is a copy of the shapes' and
    // textures' code.)
    Surface s;
    bool graze = true;
    bool light = pass_params.side == BDPT_SIDE_LIGHT;
    if (has_feature(FEATURE_MEDIA) && prim == MEDIUM_HIT) {
        // A scattering vertex in the walk's medium (bdpt_trace's free flight).
        if (light) light_walk_medium_vertex(w, hit.t, v); else camera_walk_medium_vertex(w, hit.t, v);
        graze = false;
    } else if (prim != NO_HIT) {
        s = surface_at(hit, w.o, w.d);
        graze = light ? !light_walk_vertex(w, hit.t, s, v) : !camera_walk_vertex(w, hit.t, s, v);
    }
    bool found = prim != NO_HIT && !graze;
    if (pass_params.side == BDPT_SIDE_LIGHT) {
        if (!found) {
            walks[slot].d.w = uintBitsToFloat(flags);
            return;
        }
        uint i = w.vertices;
        // Vertices that a camera vertex can still connect to (s + t - 2 <= max_scatter()
        // with t >= 2) are stored.
        if (i < max_scatter()) {
            store_path_vertex(base + i - 1u, v);
            walks[slot].counts.z = i;
        }
        flags |= BDPT_WALK_VERTEX;
        if (i >= min_scatter()) flags |= BDPT_WALK_CONNECT;
        if (i < max_scatter()) flags |= BDPT_WALK_EXTEND;
    } else {
        // The vertex z_k; strategies here have t = k + 1.
        uint k = g.counts.x + 1u;   // (w.vertices before this vertex)
        uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : max_scatter();
        // The emit stage looks at what the walk found: an emitter (s = 0), a point for
        // the s = 1 light sample, or the environment.
        w.escaped = prim == NO_HIT;
        if (found || w.escaped) flags |= BDPT_WALK_EMIT;
        if (found && k <= max_vertices) {
            // s >= 2: light vertices y_j with j + k <= max_scatter() (shade, then trace).
            if (k < max_scatter() && g.counts.z > 0u) {
                store_path_vertex(base + vertex_stride() + k - 1u, v);
                walks[slot].counts.w = k;
                uint first, last;
                if (connection_range(k, g.counts.z, first, last)) flags |= BDPT_WALK_CONNECTIONS;
            }
            flags |= BDPT_WALK_VERTEX | BDPT_WALK_EXTEND;
        }
    }
    if ((flags & (BDPT_WALK_VERTEX | BDPT_WALK_EMIT)) != 0u && found) store_vertex(slot, v);
    store_walk_vertex(slot, w, flags);
}
