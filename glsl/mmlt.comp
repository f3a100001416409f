// Multiplexed Metropolis light transport (Hachisuka, Kaplanyan & Dachsbacher 2014) over
// primary sample space (Kelemen et al. 2002), one invocation per bootstrap sample or
// per chain. Three kinds of dispatch (MmltParams.run.x):
//   MMLT_MODE_BOOTSTRAP  sample `item` of the bootstrap: depth item / per_depth, its
//                        numbers hashed from (index, depth, seed); writes its target f.
//   MMLT_MODE_START      chain `item`: copies its bootstrap sample's numbers into the
//                        chain state and evaluates its path through the same function,
//                        so the chain starts exactly on that sample.
//   MMLT_MODE_CHAINS     chain `item` makes run.w Metropolis-Hastings proposals.
//
// A path of depth d is one strategy (s,t) of bdpt, chosen by the first camera number
// among the d + 2 that bdpt combines for that depth (s = 0..d+1, t = d+2-s), with
// exactly bdpt's MIS weight (lib/bdpt.glsl, N = width * height light paths). Its
// contribution C = weighted value * (d + 2) and its target f = luminance(C). The
// film position is uniform over the whole image; t = 1 paths land where their light
// vertex projects. Each proposal splats a * C'/f' at its pixel and (1 - a) * C/f at the
// current one (the latter accumulated while the chain stays and splatted when it moves
// or the dispatch ends), in fixed point (lib/splat.glsl); the host scales the splat film by
// b * width * height / mutations.
#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_float : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#define OWN_PUSH_CONSTANTS
#include "bindings.glsl"
layout(push_constant) uniform MmltBlock { MmltParams params; };
#include "sampling.glsl"
#include "bsdf.glsl"
#include "trace.glsl"
#include "lights.glsl"
#include "camera.glsl"
#include "sampler_pss.glsl"
#include "bdpt.glsl"
#include "splat.glsl"

// --mmlt-depths: one vec4 film per depth, [depth][pixel].
layout(std430, set = 0, binding = BINDING_DEPTH_FILMS) buffer DepthFilmBuffer { float depth_film[]; };
layout(std430, set = 0, binding = BINDING_CHAINS) buffer ChainBuffer { GpuChain chains[]; };
layout(std430, set = 0, binding = BINDING_BOOTSTRAP) buffer BootstrapBuffer { float bootstrap_f[]; };

uint nonfinite = 0u;

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// One path of `depth` scattering vertices from the sampler's numbers: its contribution
// C (MIS-weighted, times the number of strategies) and the pixel it lands on. (Each
// walk and each connection appears once in this function: lavapipe's compiler inlines
// everything, and every copy of a walk costs compile time and memory.)
vec3 mmlt_path(uint depth, out uint pixel) {
    uint strategies = depth + 2u;
    uint s = min(uint(sample_1d(STREAM_CAMERA) * float(strategies)), depth + 1u);
    uint t = strategies - s;
    vec2 film = sample_2d(STREAM_CAMERA);
    uvec2 px = min(uvec2(film * vec2(uvec2(scene.width, scene.height))), uvec2(scene.width, scene.height) - 1u);
    vec3 value = vec3(0.0);
    float weight = 0.0;
    bool found = false;

    // The light subpath's last vertex y_{s-1}, for s >= 2 (and the light point for
    // s = 1, t = 1).
    Walk lw;
    LightEmission le;
    uint e = 0u;
    PathVertex y;
    bool lit = false;
    if (t == 1u || s >= 2u) {
        lit = light_walk_start(lw, le, e);
        for (uint i = 1u; lit && i < s; ++i) {
            lit = (i == 1u || light_walk_extend(lw, y)) && light_walk_next(lw, y);
        }
    }
    if (t == 1u) {
        // Light tracing: the light subpath seen by the camera.
        if (lit) {
            if (s == 1u) {
                found = strategy_light_point_seen(le, e, px, value, weight);
            } else {
                found = strategy_camera_connection(y, px, value, weight);
            }
        }
    } else if (s < 2u || lit) {
        // A camera subpath of t vertices (the camera and t - 1 surface vertices).
        Walk cw;
        camera_walk_start(film, cw);
        PathVertex z;
        bool alive = true;
        bool escaped = false;   // the last vertex is the environment
        for (uint k = 1u; alive && k < t; ++k) {
            alive = k == 1u || camera_walk_extend(cw, z);
            if (alive) {
                alive = camera_walk_next(cw, z);
                escaped = !alive && cw.escaped && k == t - 1u;
            }
        }
        if (escaped && s == 0u) {
            found = strategy_environment_hit(cw, value, weight);
        } else if (alive) {
            if (s == 0u) {
                found = strategy_emitter_hit(cw, z, value, weight);
            } else if (s == 1u) {
                found = strategy_light_sample(cw, z, value, weight);
            } else {
                found = strategy_connection(z, y, value, weight);
            }
        }
    }
    pixel = px.y * scene.width + px.x;
    return found ? value * (weight * float(strategies)) : vec3(0.0);
}

// mmlt_path with its target; a NaN or infinite contribution counts as f = 0 (and is
// counted).
vec3 mmlt_sample(uint depth, out uint pixel, out float f) {
    pss_begin_path();
    vec3 c = mmlt_path(depth, pixel);
    f = luminance(c);
    if (!finite3(c) || isnan(f) || isinf(f)) {
        nonfinite++;
        c = vec3(0.0);
        f = 0.0;
    }
    if (!(f > 0.0)) {
        c = vec3(0.0);
        f = 0.0;
    }
    return c;
}

// The sampler probe's synthetic path (tests compare the chain state it leaves with the
// CPU mirror, src/integrators/mmlt_sampler.rs): it asks each stream for a hash-chosen
// count of numbers and its target is a hash, so accept/reject decisions are known to the
// CPU without evaluating paths.
vec3 probe_sample(out uint pixel, out float f) {
    pss_begin_path();
    uvec4 h = pcg4d(uvec4(pss.chain, pss.proposal, pss.seed, 0x20000000u));
    uint counts[3] = uint[3](1u + h.x % pss.capacity[0], h.y % (pss.capacity[1] + 1u), h.z % (pss.capacity[2] + 1u));
    for (uint s = 0u; s < 3u; ++s) {
        for (uint i = 0u; i < counts[s]; ++i) sample_u32(s);
    }
    pixel = 0u;
    f = pss_unit(h.w) + 0.01;
    return vec3(0.0);
}

void splat_add(uint pixel, uint depth, vec3 v) {
    if (v == vec3(0.0)) return;
    if (!splat_add_fixed(pixel, v)) { nonfinite++; return; }
    if (params.record_depths != 0u) {
        uint i = (depth * scene.width * scene.height + pixel) * 4u;
        atomicAdd(depth_film[i + 0u], v.x);
        atomicAdd(depth_film[i + 1u], v.y);
        atomicAdd(depth_film[i + 2u], v.z);
    }
}

void main() {
    uint id = gl_GlobalInvocationID.x;
    if (id >= params.items) return;
    uint item = params.first_item + id;
    pss.seed = scene.seed;
    pss.chains = params.chains;
    pss.sigma = params.sigma;
    pss.base[0] = 0u;
    pss.base[1] = params.camera_numbers;
    pss.base[2] = params.camera_numbers + params.light_numbers;
    pss.capacity[0] = params.camera_numbers;
    pss.capacity[1] = params.light_numbers;
    pss.capacity[2] = params.connect_numbers;
    pss.chain = item;
    pss.proposal = 0u;
    // The sampler probe (tests only) runs the start and chain modes on a synthetic path.
    bool probe = params.mode >= MMLT_MODE_PROBE_START;
    uint mode = probe ? params.mode - (MMLT_MODE_PROBE_START - MMLT_MODE_START) : params.mode;

    // Every mode evaluates paths at the one call of mmlt_sample below.
    GpuChain ch = GpuChain(vec4(0.0), uvec4(0u), uvec4(0u), uvec4(0u));
    uint depth;
    uint iterations = 1u;
    if (mode == MMLT_MODE_BOOTSTRAP) {
        pss.mode = PSS_FROM_KEY;
        depth = item / params.bootstrap_per_depth;
        pss.key_depth = depth;
        pss.key_index = item % params.bootstrap_per_depth;
    } else if (mode == MMLT_MODE_START) {
        // Copy the bootstrap sample's numbers into the chain, then evaluate them.
        ch = chains[item];
        depth = ch.state.y;
        for (uint dim = 0u; dim < params.numbers; ++dim) {
            uint v = pss_key_number(ch.start.x, depth, dim);
            chain_samples[dim * pss.chains + item] = uvec4(v, 0u, v, 0u);
        }
        pss.mode = PSS_READ;
    } else {
        ch = chains[item];
        depth = ch.state.y;
        pss.mode = PSS_MUTATE;
        iterations = params.mutations;
    }
    vec3 C = ch.current.xyz;
    float f = ch.current.w;
    uint pixel = ch.state.x;
    uint step = ch.state.z;
    uint last_large = ch.state.w;
    float pending = 0.0;   // the current path's splat weight not yet splatted
    for (uint k = 0u; k < iterations; ++k) {
        if (mode == MMLT_MODE_CHAINS) {
            pss.proposal = ch.counts.x + ch.counts.z;
            pss.step = step + 1u;
            pss.last_large = last_large;
            pss.large = pss_unit(pss_hash(PSS_TAG_DECIDE, 0u).x) < params.large_step;
        }
        uint pixel2;
        float f2;
        vec3 C2 = probe ? probe_sample(pixel2, f2) : mmlt_sample(depth, pixel2, f2);
        if (mode == MMLT_MODE_BOOTSTRAP) {
            bootstrap_f[item] = f2;
        } else if (mode == MMLT_MODE_START) {
            if (!probe && f2 != bootstrap_f[depth * params.bootstrap_per_depth + ch.start.x]) atomicAdd(stats[STAT_START_MISMATCH], 1u);
            C = C2;
            f = f2;
            pixel = pixel2;
            step = 0u;
            last_large = 0u;
            ch.counts = uvec4(0u);
            ch.start.y = 0u;
        } else {
            // A chain on f = 0 (only where the bootstrap found nothing) accepts anything.
            float a = f > 0.0 ? min(1.0, f2 / f) : 1.0;
            if (f2 > 0.0) splat_add(pixel2, depth, C2 * (a / f2));
            if (f > 0.0) pending += 1.0 - a;
            bool accept = pss_unit(pss_hash(PSS_TAG_DECIDE, 1u).x) < a;
            if (pss.large) ch.counts.x++; else ch.counts.z++;
            if (accept) {
                if (pending > 0.0) splat_add(pixel, depth, C * (pending / f));
                pending = 0.0;
                C = C2;
                f = f2;
                pixel = pixel2;
                step = pss.step;
                if (pss.large) {
                    last_large = pss.step;
                    ch.counts.y++;
                } else {
                    ch.counts.w++;
                }
            } else {
                pss_reject();
            }
        }
    }
    if (mode == MMLT_MODE_BOOTSTRAP) {
        atomicAdd(stats[STAT_MMLT_RAYS], rays_traced);
    } else {
        if (pending > 0.0 && f > 0.0) splat_add(pixel, depth, C * (pending / f));
        ch.current = vec4(C, f);
        ch.state = uvec4(pixel, depth, step, last_large);
        ch.start.y += rays_traced;
        chains[item] = ch;
    }
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
