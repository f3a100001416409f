// What BDPT's kernels share (the wavefront, lib/bdpt_wave.glsl): the push constants,
// the pixel a slot serves, the path-vertex buffer (per pixel sample, its light vertices
// y_1.. and then its camera vertices z_1.. that connections use), the films and the
// strategy images, and which stored vertices an s, t >= 2 connection joins. The walks,
// connections and MIS weights are lib/bdpt.glsl's, shared with MMLT's kernels.
//
// Films: film[pixel] (camera strategies, written only by the pixel's own invocations,
// bdpt_finish's) and
// the splat film (t = 1 strategies, fixed-point integer atomics whose sum does not depend
// on the order: lib/splat.glsl). The image is (film + splat) / spp.
// A contribution that comes out NaN or infinite is left out and counted in
// stats[STAT_NONFINITE] (per contribution, not per sample).
//
// scene.min_depth > 0 restricts the pass to paths of at least that many scattering
// vertices (MMLT's tail beyond its chains' depth cap): shorter ones are not added.
#ifndef BDPT_PASS_GLSL
#define BDPT_PASS_GLSL
#define OWN_PUSH_CONSTANTS
#include "bindings.glsl"
layout(push_constant) uniform BdptBlock { BdptParams pass_params; };
#include "sampler_pcg.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"
#include "bdpt.glsl"
#include "splat.glsl"

// A pixel's slice: `stride` light vertices y_1.., then `stride` camera vertices z_1...
layout(std430, set = 0, binding = BINDING_PATH_VERTICES) buffer PathVertexBuffer { GpuPathVertex path_vertices[]; };
// Debug output (--bdpt-strategies): per (s,t), a weighted and an unweighted film, each
// pixel FIXED_FILM_WORDS_PER_PIXEL words of the splat film's fixed point (splat.glsl: the
// sums do not depend on the order of the additions), laid out [strategy][weighted 0 /
// unweighted 1][pixel].
layout(std430, set = 0, binding = BINDING_STRATEGIES) buffer StrategyBuffer { uint strategy_film[]; };

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
    // (Values the fixed point cannot hold, beyond 2^32, are left out of these images.)
    if (!splat_in_range(weighted) || !splat_in_range(unweighted)) return;
    for (uint k = 0u; k < 2u; ++k) {
        vec3 v = k == 0u ? weighted : unweighted;
        uint base = ((strategy * 2u + k) * npix + pixel) * FIXED_FILM_WORDS_PER_PIXEL;
        for (uint c = 0u; c < 3u; ++c) {
            bool wrapped;
            if (v[c] > 0.0) FIXED_POINT_ADD(strategy_film, base + 2u * c, v[c], wrapped);
        }
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

// Vertices a subpath stores: those a connection can use (s + t - 2 <= max_scatter()
// with s, t >= 2); none when only paths too long for them are added.
uint vertex_stride() { return min_scatter() > max_scatter() ? 0u : max(max_scatter(), 2u) - 1u; }

// The band's pixels.
uint band_pixels() { return (min(scene.height, pass_params.row_end) - pass_params.row_begin) * scene.width; }

// The sample this invocation adds: a dispatch over pass_params.samples samples of the
// band has one z layer per sample (BDPT's wavefront; the three stages run one).
uint bdpt_sample() { return pass_params.first_sample + gl_GlobalInvocationID.z; }

// This invocation's pixel, its index in the image and its slot (its walk, its slice of
// the path-vertex buffer, which holds the band's pixels for each sample of the
// dispatch), and the base of that slice. False when it has no pixel, or (counted once, by
// the light stage) when its slice is past the buffer's end.
bool bdpt_pixel(bool count_out_of_range, out uvec2 pixel, out uint index, out uint slot, out uint base) {
    pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    index = 0u;
    slot = 0u;
    base = 0u;
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return false;
    if (gl_GlobalInvocationID.z >= max(pass_params.samples, 1u)) return false;
    index = pixel.y * scene.width + pixel.x;
    slot = gl_GlobalInvocationID.z * band_pixels() + (pixel.y - pass_params.row_begin) * scene.width + pixel.x;
    uint stride = vertex_stride();
    base = slot * 2u * stride;
    if (stride > 0u && base + 2u * stride > uint(path_vertices.length())) {
        if (count_out_of_range) atomicAdd(stats[STAT_OUT_OF_RANGE], 1u);
        return false;
    }
    return true;
}

// Beside each, its material texture values (in scenes with FEATURE_MATERIAL_TEXTURES).
layout(std430, set = 0, binding = BINDING_PATH_VERTEX_TEXTURES) buffer PathVertexTextureBuffer { vec4 path_vertex_textures[]; };

PathVertex stored_vertex(uint index) {
    PathVertex y = unpack_vertex(path_vertices[index]);
    if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
        y.tex0 = path_vertex_textures[2u * index];
        y.tex1 = path_vertex_textures[2u * index + 1u];
    }
    return y;
}

// Store y at `index` of the path-vertex buffer (its texture values only where the scene
// has material textures: every word is a memory access per pixel).
void store_path_vertex(uint index, PathVertex y) {
    GpuPathVertex v = pack_vertex(y);
    path_vertices[index].p = v.p;
    path_vertices[index].n = v.n;
    path_vertices[index].wi = v.wi;
    path_vertices[index].beta = v.beta;
    path_vertices[index].ns = v.ns;
    if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
        path_vertex_textures[2u * index] = y.tex0;
        path_vertex_textures[2u * index + 1u] = y.tex1;
    }
}

// The light vertices y_first ..= y_last that the camera vertex z_k connects to (s, t >= 2)
// when `stored` light vertices are: those whose path stays within maxdepth (and, for
// MMLT's tail, reaches min_scatter()). False when there are none.
bool connection_range(uint k, uint stored, out uint first, out uint last) {
    first = max(1u, min_scatter() - min(min_scatter(), k));
    last = min(stored, max_scatter() - min(max_scatter(), k));
    return first <= last;
}
#endif
