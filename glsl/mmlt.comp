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

// The strategies of a path, by what they ask (mmlt_path).
#define MMLT_NONE 0u
#define MMLT_LIGHT_POINT 1u        // s = 1, t = 1
#define MMLT_CAMERA_CONNECTION 2u  // s >= 2, t = 1
#define MMLT_EMISSION 3u           // s = 0 (an emitter or the environment)
#define MMLT_LIGHT_SAMPLE 4u       // s = 1, t >= 2
#define MMLT_CONNECTION 5u         // s >= 2, t >= 2

// One path of `depth` scattering vertices from the sampler's numbers: its contribution
// C (MIS-weighted, times the number of strategies) and the pixel it lands on. Each step
// of a walk, each question to a BSDF or to an emitter's densities and each shadow ray
// appears once in this function, whichever strategy asks it: lavapipe's compiler
// inlines everything, and every copy costs compile time and memory.
vec3 mmlt_path(uint depth, out uint pixel) {
    uint strategies = depth + 2u;
    uint s = min(uint(sample_1d(STREAM_CAMERA) * float(strategies)), depth + 1u);
    uint t = strategies - s;
    vec2 film = sample_2d(STREAM_CAMERA);
    uvec2 px = min(uvec2(film * vec2(uvec2(scene.width, scene.height))), uvec2(scene.width, scene.height) - 1u);
    vec3 value = vec3(0.0);
    float weight = 0.0;
    bool found = false;

    // The walks, in one loop: the light subpath's vertices y_1 .. y_{s-1} (for s >= 2;
    // for t = 1 its start too), then the camera subpath's z_1 .. z_{t-1} (t >= 2; for
    // s >= 2 only when the light subpath has its vertices). w is the walk going on, v its
    // last vertex; y keeps the light subpath's last.
    bool light_walk = t == 1u || s >= 2u;
    uint light_steps = s >= 2u ? s - 1u : 0u;
    uint camera_steps = t >= 2u ? t - 1u : 0u;
    Walk w;
    LightEmission le;
    uint e = 0u;
    PathVertex y, v;
    bool lit = false;
    bool camera = false;    // the camera subpath started
    bool alive = false;     // ... and has all its vertices
    bool escaped = false;   // ... or its last ray escaped toward the environment
    if (light_walk) lit = light_walk_start(w, le, e);
    for (uint step = 0u; step < light_steps + camera_steps; ++step) {
        bool cam = step >= light_steps;
        uint k = cam ? step - light_steps + 1u : step + 1u;
        if (cam && k == 1u) {
            if (light_walk && !lit) break;
            y = v;
            camera_walk_start(film, w);
            camera = true;
        }
        bool ok = k == 1u || walk_extend(w, v, vertex_bsdf(v), cam);
        if (ok) {
            Hit hit;
            if (closest(w.o, w.d, hit)) {
                Surface sf = surface_at(hit, w.o, w.d);
                ok = cam ? camera_walk_vertex(w, hit.t, sf, v) : light_walk_vertex(w, hit.t, sf, v);
            } else {
                ok = false;
                w.escaped = cam;
            }
        }
        if (!cam) {
            lit = ok;
            if (!lit) break;
            continue;
        }
        alive = ok;
        if (!alive) {
            escaped = w.escaped && k == t - 1u;
            break;
        }
    }
    if (!camera) y = v;

    // The strategy: what it asks of an emitter's densities (q), of BSDFs (up to two
    // questions) and of a shadow ray.
    uint kind = MMLT_NONE;
    EmissionQuery q;
    bool ask = false;
    uint asks = 0u;
    PathVertex qv[2];
    vec3 qdir[2];
    uint qtransport[2];
    bool qfwd[2];
    bool qrev[2];
    vec3 eye, to_eye, dir;
    float dist, d2, cos_s;
    uvec2 cpx;
    LightSample ls;
    if (t == 1u) {
        // Light tracing: the light subpath seen by the camera.
        if (lit && s == 1u) {
            kind = MMLT_LIGHT_POINT;
        } else if (lit && camera_connection_faces(y, eye, cpx, to_eye, dist)) {
            kind = MMLT_CAMERA_CONNECTION;
            qv[0] = y;
            qdir[0] = to_eye;
            qtransport[0] = TRANSPORT_IMPORTANCE;
            qfwd[0] = false;
            qrev[0] = true;
            asks = 1u;
        }
    } else if (camera && ((escaped && s == 0u) || (alive && s == 0u))) {
        if (emission_found(w, v, escaped, value, q, ask)) kind = MMLT_EMISSION;
    } else if (camera && alive && s == 1u) {
        if (light_sample_draw(v, ls, q)) {
            ask = light_sample_weighs_all(w);
            if (light_sample_faces(vertex_bsdf(v), v, ls, cos_s)) {
                kind = MMLT_LIGHT_SAMPLE;
                qv[0] = v;
                qdir[0] = ls.wi;
                qtransport[0] = TRANSPORT_RADIANCE;
                qfwd[0] = true;
                qrev[0] = ask;
                asks = 1u;
            }
        }
    } else if (camera && alive && connection_faces(v, y, dir, d2)) {
        kind = MMLT_CONNECTION;
        qv[0] = v;
        qdir[0] = dir;
        qtransport[0] = TRANSPORT_RADIANCE;
        qv[1] = y;
        qdir[1] = -dir;
        qtransport[1] = TRANSPORT_IMPORTANCE;
        qfwd[0] = true;
        qrev[0] = true;
        qfwd[1] = true;
        qrev[1] = true;
        asks = 2u;
    }
    vec2 pdfs = vec2(0.0);
    if (ask) pdfs = emission_pdfs(q);
    vec3 f[2];
    float pdf_fwd[2], pdf_rev[2];
    [[dont_unroll]] for (uint i = 0u; i < asks; ++i) {
        f[i] = bsdf_eval_pdfs(vertex_bsdf(qv[i]), scene.sample_mode, qv[i].ns, qv[i].w, qdir[i], qtransport[i], qfwd[i],
                              qrev[i], pdf_fwd[i], pdf_rev[i]);
    }
    bool shadow = false;
    vec3 o, d;
    float tmax;
    if (kind == MMLT_LIGHT_POINT) {
        shadow = light_point_seen(le, e, px, value, weight, o, d, tmax);
    } else if (kind == MMLT_CAMERA_CONNECTION) {
        px = cpx;
        shadow = camera_connection_end(y, eye, to_eye, dist, f[0], pdf_rev[0], value, weight, o, d, tmax);
    } else if (kind == MMLT_EMISSION) {
        weight = emission_weight(w, v, escaped, q, pdfs);
        found = true;
    } else if (kind == MMLT_LIGHT_SAMPLE) {
        shadow = light_sample_end(w, v, ls, pdfs, cos_s, f[0], pdf_fwd[0], pdf_rev[0], value, weight, o, d, tmax);
    } else if (kind == MMLT_CONNECTION) {
        shadow = connection_end(v, y, dir, d2, f[0], pdf_fwd[0], pdf_rev[0], f[1], pdf_fwd[1], pdf_rev[1], value, weight,
                                o, d, tmax);
    }
    if (shadow) {
        rays_traced++;
        found = !(tmax > 0.0) || !trace_occluded(o, d, tmax);
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
