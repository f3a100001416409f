// One pass of bidirectional path tracing (integrator `bdpt`). Each invocation owns one
// pixel: it traces a light subpath, connecting every light vertex to the camera (t = 1,
// splatted to whichever pixel it lands on) and storing the vertices
// in its slice of the path-vertex buffer, then traces a camera subpath that, at each
// vertex, takes the emission it finds (s = 0), a fresh light sample (s = 1) and a
// connection to every stored light vertex (s >= 2). The walks, connections and MIS
// weights are lib/bdpt.glsl's, shared with mmlt.comp.
//
// Films: film[pixel] (camera strategies, written only by the pixel's own invocation) and
// the splat film (t = 1 strategies, fixed-point integer atomics whose sum does not depend
// on the order: lib/splat.glsl). The image is (film + splat) / spp.
// A contribution that comes out NaN or infinite is left out and counted in
// stats[STAT_NONFINITE] (per contribution, not per sample).
//
// scene.min_depth > 0 restricts the pass to paths of at least that many scattering
// vertices (MMLT's tail beyond its chains' depth cap): shorter ones are not added.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bindings.glsl"
#include "sampler_pcg.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"
#include "bdpt.glsl"
#include "splat.glsl"

layout(std430, set = 0, binding = BINDING_PATH_VERTICES) buffer PathVertexBuffer { GpuPathVertex light_vertices[]; };
// Debug output (--bdpt-strategies): per (s,t), a weighted and an unweighted film of
// vec4s, laid out [strategy][weighted 0 / unweighted 1][pixel].
layout(std430, set = 0, binding = BINDING_STRATEGIES) buffer StrategyBuffer { float strategy_film[]; };

uint nonfinite = 0u;
// Paths with fewer scattering vertices are not added (MMLT's tail: its chains have them).
uint min_scatter() { return scene.min_depth; }

// Strategy (s, t): s light vertices, t camera vertices (the camera itself included).
// Only the group of strategies [first, first + count) that the host asked for is
// recorded (scene.strategy_first, scene.strategy_count; count 0: none), at group-relative
// indices: when all strategies do not fit one buffer, the host re-renders the same samples once
// per group.
void record_strategy(uint s, uint t, uint pixel, vec3 weighted, vec3 unweighted) {
    uint count = scene.strategy_count;
    if (count == 0u) return;
    uint n = s + t - 2u;
    uint strategy = n * (n + 3u) / 2u + s - scene.strategy_first;
    if (strategy >= count) return;   // (strategies before the group wrap around to large values)
    uint npix = scene.width * scene.height;
    uint i = ((strategy * 2u) * npix + pixel) * 4u;
    uint j = ((strategy * 2u + 1u) * npix + pixel) * 4u;
    for (uint c = 0u; c < 3u; ++c) {
        atomicAdd(strategy_film[i + c], weighted[c]);
        atomicAdd(strategy_film[j + c], unweighted[c]);
    }
}

// Add one strategy's MIS-weighted contribution to the camera film's running sum L,
// unless it is NaN or infinite (then it is counted and left out, and the sample's other
// strategies still count).
void add_camera(inout vec3 L, uint s, uint t, uint pixel, vec3 unweighted, float weight) {
    if (s + t - 2u < min_scatter()) return;
    vec3 v = unweighted * weight;
    if (!finite3(v) || !finite3(unweighted)) { nonfinite++; return; }
    L += v;
    record_strategy(s, t, pixel, v, unweighted);
}

void add_splat(uvec2 px, uint s, vec3 unweighted, float weight) {
    if (s - 1u < min_scatter()) return;
    vec3 v = unweighted * weight;
    if (!finite3(v) || !finite3(unweighted)) { nonfinite++; return; }
    uint pixel = px.y * scene.width + px.x;
    if (!splat_add_fixed(pixel, v)) { nonfinite++; return; }
    record_strategy(s, 1u, pixel, v, unweighted);
}

// Trace the light subpath, splatting t = 1 connections and storing vertices 1..stored
// at light_vertices[base + i - 1]. Returns the number stored.
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
            GpuPathVertex v;
            bool front = dot(y.n, y.ng) > 0.0;
            v.p = vec4(y.p, uintBitsToFloat(y.material | (front ? PATH_VERTEX_FRONT : 0u)));
            v.n = vec4(y.n, y.dvcm);
            v.wi = vec4(y.w, y.dvc);
            v.beta = vec4(y.beta, y.uv.y);
            v.ns = vec4(y.ns, y.uv.x);
            light_vertices[base + i - 1u] = v;
            stored = i;
        }
        if (i >= min_scatter() && strategy_camera_connection(y, px, value, weight)) add_splat(px, i + 1u, value, weight);
        if (i == max_scatter()) break;
        if (!light_walk_extend(w, y)) break;
    }
    return stored;
}

PathVertex stored_light_vertex(uint index) {
    GpuPathVertex g = light_vertices[index];
    PathVertex y;
    y.p = g.p.xyz;
    uint m = floatBitsToUint(g.p.w);
    y.material = m & ~PATH_VERTEX_FRONT;
    y.n = g.n.xyz;
    y.dvcm = g.n.w;
    y.w = g.wi.xyz;
    y.dvc = g.wi.w;
    y.beta = g.beta.xyz;
    y.emitter = NO_EMITTER;
    y.ng = (m & PATH_VERTEX_FRONT) != 0u ? y.n : -y.n;   // (only its side matters: emission is not read here)
    y.uv = vec2(g.ns.w, g.beta.w);
    y.ns = g.ns.xyz;
    return y;
}

// The camera subpath with s = 0, s = 1 and s >= 2 strategies at each vertex. Returns
// the pixel's camera-film contribution.
//
// maxdepth -1: paths of up to max_scatter (BDPT_UNBOUNDED_DEPTH_CAP) scattering vertices
// get every strategy. Longer ones, which only the camera subpath reaches (light
// subpaths are stored, so bounded), go on with Russian roulette up to the path tracer's
// UNBOUNDED_DEPTH_CAP and combine the two strategies left to them, s = 0 and s = 1, by
// the power heuristic, as the path tracer does. Path length splits path space, so the
// two regimes add up to the whole, unbiased.
vec3 camera_subpath(uvec2 pixel, uint base, uint stored) {
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
        // s >= 2: connect to the stored light vertices y_1 .. y_j with j + k <= max_scatter().
        uint last = k < max_scatter() ? min(stored, max_scatter() - k) : 0u;
        for (uint j = max(1u, min_scatter() - min(min_scatter(), k)); j <= last; ++j) {
            if (strategy_connection(z, stored_light_vertex(base + j - 1u), value, weight)) add_camera(L, j + 1u, k + 1u, pixel_index, value, weight);
        }
        if (!camera_walk_extend(w, z)) break;
    }
    return L;
}

void main() {
    uvec2 pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return;
    uint index = pixel.y * scene.width + pixel.x;
    // This invocation's slice of the light-vertex buffer (which holds one band; none
    // when only paths too long for light vertices are added).
    uint stride = min_scatter() > max_scatter() ? 0u : max(max_scatter(), 2u) - 1u;
    uint base = ((pixel.y - pass_params.row_begin) * scene.width + pixel.x) * stride;
    if (stride > 0u && base + stride > uint(light_vertices.length())) {
        atomicAdd(stats[STAT_OUT_OF_RANGE], 1u);
        return;
    }
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < pass_params.samples; ++i) {
        sampler_start(scene.seed, index, pass_params.first_sample + i);
        uint stored = light_subpath(base);
        sum += camera_subpath(pixel, base, stored);
    }
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
    film[index] += vec4(sum, float(rays_traced));
}
