// BDPT's wavefront (lib/bdpt_wave.glsl): the surface interaction. The vertex at the
// walk's hit (light side: y_i; camera side: z_k), stored in the path-vertex buffer when a
// connection can use it; on the camera side the emission found there or in the
// environment (s = 0) and the point of the s = 1 strategy's light sample. The vertex then
// waits for its material class's shade stage. All of BDPT's emitter code is here.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

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
    if (prim != NO_HIT) {
        s = surface_at(hit, w.o, w.d);
        graze = pass_params.side == BDPT_SIDE_LIGHT ? !light_walk_vertex(w, hit.t, s, v) : !camera_walk_vertex(w, hit.t, s, v);
    }
    if (pass_params.side == BDPT_SIDE_LIGHT) {
        if (prim == NO_HIT || graze) {
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
        sampler_resume(index, g);
        uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : max_scatter();
        vec3 L = g.radiance.xyz;
        vec3 value;
        bool found = prim != NO_HIT && !graze;
        // s = 0: the camera subpath found an emitter, or escaped toward the environment
        // (k - 1 scattering vertices either way).
        w.escaped = prim == NO_HIT;
        if (!found) v.emitter = NO_EMITTER;
        EmissionQuery q[2];
        bool ask[2] = bool[2](false, false);
        bool emission = (found || w.escaped) && k - 1u >= min_scatter() && emission_found(w, v, !found, value, q[0], ask[0]);
        // s = 1: a fresh sample on a light (k scattering vertices); its BSDF half is the
        // shade stage's.
        LightSample ls;
        bool sampled = found && k <= max_vertices && k >= min_scatter() && light_sample_draw(v, ls, q[1]);
        ask[1] = sampled && w.vertices <= max_scatter();
        // Both strategies' emitter densities, asked in one place.
        vec2 pdfs[2] = vec2[2](vec2(0.0), vec2(0.0));
        [[dont_unroll]] for (uint i = 0u; i < 2u; ++i) {
            if (ask[i]) pdfs[i] = emission_pdfs(q[i]);
        }
        if (emission) add_camera(L, 0u, k + 1u, index, value, emission_weight(w, v, !found, q[0], pdfs[0]));
        if (emission) walks[slot].radiance.xyz = L;
        if (found && k <= max_vertices) {
            if (sampled) {
                flags |= BDPT_WALK_LIGHT_SAMPLE;
                pack_light_sample(ls, walks[slot].ls_wi, walks[slot].ls_le, walks[slot].ls_p, walks[slot].ls_n);
                walks[slot].ls_pdfs = vec4(pdfs[1], 0.0, 0.0);
            }
            // s >= 2: light vertices y_j with j + k <= max_scatter() (shade, then trace).
            if (k < max_scatter() && g.counts.z > 0u) {
                store_path_vertex(base + vertex_stride() + k - 1u, v);
                walks[slot].counts.w = k;
                uint first, last;
                if (connection_range(k, g.counts.z, first, last)) flags |= BDPT_WALK_CONNECTIONS;
            }
            flags |= BDPT_WALK_VERTEX | BDPT_WALK_EXTEND;
        }
        walks[slot].o.w = uintBitsToFloat(sampler_rng.counter);
    }
    if ((flags & BDPT_WALK_VERTEX) != 0u) store_vertex(slot, v);
    store_walk_vertex(slot, w, flags);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
