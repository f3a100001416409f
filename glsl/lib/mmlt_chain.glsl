// MMLT's chains (Hachisuka, Kaplanyan & Dachsbacher 2014, over Kelemen et al.'s primary
// sample space): what happens to a bootstrap sample or a chain before and after its path
// is evaluated, written once for the wavefront's stages (mmlt_start.comp,
// mmlt_accept.comp) and for the sampler probe (mmlt_probe.comp). The including kernel
// declares `MmltParams params` (its push constants) and includes lib/sampler_pss.glsl
// and lib/splat.glsl before this file.
//
// Three kinds of dispatch (params.mode):
//   MMLT_MODE_BOOTSTRAP  sample `item` of the bootstrap: depth item / per_depth, its
//                        numbers hashed from (index, depth, seed); writes its target f.
//   MMLT_MODE_START      chain `item`: its bootstrap sample's numbers copied into the
//                        chain state and evaluated by the same stages, so the chain
//                        starts exactly on that sample.
//   MMLT_MODE_CHAINS     chain `item` makes one Metropolis-Hastings proposal.
// A proposal splats a * C'/f' at its pixel and (1 - a) * C/f is owed to the current one:
// the debt is kept in the chain (GpuChain.start.z) and splatted when the chain moves, and
// the host adds what is still owed when it resolves the image. So the image does not
// depend on how proposals are grouped into dispatches. Splats are fixed point
// (lib/splat.glsl); the host scales the splat film by b * width * height / mutations.
#ifndef MMLT_CHAIN_GLSL
#define MMLT_CHAIN_GLSL

// --mmlt-depths: one film per depth, [depth][pixel], each pixel FIXED_FILM_WORDS_PER_PIXEL
// words of the splat film's fixed point (the sums do not depend on the order).
layout(std430, set = 0, binding = BINDING_DEPTH_FILMS) buffer DepthFilmBuffer { uint depth_film[]; };
layout(std430, set = 0, binding = BINDING_CHAINS) buffer ChainBuffer { GpuChain chains[]; };
layout(std430, set = 0, binding = BINDING_BOOTSTRAP) buffer BootstrapBuffer { float bootstrap_f[]; };

uint nonfinite = 0u;

float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// The sampler's state for `item` in the dispatch's mode (a proposal's own numbers:
// mmlt_propose).
void mmlt_pss_init(uint item, uint mode) {
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
    pss.step = 0u;
    pss.last_large = 0u;
    pss.large = false;
    pss.key_depth = 0u;
    pss.key_index = 0u;
    if (mode == MMLT_MODE_BOOTSTRAP) {
        pss.mode = PSS_FROM_KEY;
        pss.key_depth = item / params.bootstrap_per_depth;
        pss.key_index = item % params.bootstrap_per_depth;
    } else {
        pss.mode = mode == MMLT_MODE_START ? PSS_READ : PSS_MUTATE;
    }
}

// The depth of item's paths.
uint mmlt_depth(uint item, uint mode) {
    return mode == MMLT_MODE_BOOTSTRAP ? item / params.bootstrap_per_depth : chains[item].state.y;
}

// MMLT_MODE_START: the chain's numbers become its bootstrap sample's.
void mmlt_copy_start(uint item) {
    GpuChain ch = chains[item];
    for (uint dim = 0u; dim < params.numbers; ++dim) {
        uint v = pss_key_number(ch.start.x, ch.state.y, dim);
        chain_samples[dim * pss.chains + item] = uvec4(v, 0u, v, 0u);
    }
}

// MMLT_MODE_CHAINS: the next proposal of chain ch, a large step or a small one.
void mmlt_propose(GpuChain ch) {
    pss.proposal = ch.counts.x + ch.counts.z;
    pss.step = ch.state.z + 1u;
    pss.last_large = ch.state.w;
    pss.large = pss_unit(pss_hash(PSS_TAG_DECIDE, 0u).x) < params.large_step;
}

// A path's contribution as the chains take it, and its target f = luminance(C): a NaN
// or infinite contribution counts as f = 0 (and is counted).
vec3 mmlt_target(vec3 c, out float f) {
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

void splat_add(uint pixel, uint depth, vec3 v) {
    if (v == vec3(0.0)) return;
    if (!splat_add_fixed(pixel, v)) { nonfinite++; return; }
    if (params.record_depths != 0u) {
        uint base = (depth * scene.width * scene.height + pixel) * FIXED_FILM_WORDS_PER_PIXEL;
        for (uint c = 0u; c < 3u; ++c) {
            bool wrapped;
            if (v[c] > 0.0) FIXED_POINT_ADD(depth_film, base + 2u * c, v[c], wrapped);
        }
    }
}

// What the evaluated path (contribution C2, target f2, at pixel2; `rays` traced for it)
// does to item in `mode`: a bootstrap sample's target is written; a starting chain takes
// it as its current path (`check`: it must be its bootstrap sample's); a chain's proposal
// is splatted and accepted or rejected (the sampler restores what it changed).
void mmlt_step(uint item, uint mode, bool check, vec3 C2, float f2, uint pixel2, uint rays) {
    if (mode == MMLT_MODE_BOOTSTRAP) {
        bootstrap_f[item] = f2;
        atomicAdd(stats[STAT_MMLT_RAYS], rays);
        return;
    }
    GpuChain ch = chains[item];
    uint depth = ch.state.y;
    if (mode == MMLT_MODE_START) {
        if (check && f2 != bootstrap_f[depth * params.bootstrap_per_depth + ch.start.x]) atomicAdd(stats[STAT_START_MISMATCH], 1u);
        ch.current = vec4(C2, f2);
        ch.state = uvec4(pixel2, depth, 0u, 0u);
        ch.counts = uvec4(0u);
        ch.start.yz = uvec2(rays, floatBitsToUint(0.0));
        chains[item] = ch;
        return;
    }
    vec3 C = ch.current.xyz;
    float f = ch.current.w;
    float pending = uintBitsToFloat(ch.start.z);
    // A chain on f = 0 (only where the bootstrap found nothing) accepts anything.
    float a = f > 0.0 ? min(1.0, f2 / f) : 1.0;
    if (f2 > 0.0) splat_add(pixel2, depth, C2 * (a / f2));
    if (f > 0.0) pending += 1.0 - a;
    bool accept = pss_unit(pss_hash(PSS_TAG_DECIDE, 1u).x) < a;
    if (pss.large) ch.counts.x++; else ch.counts.z++;
    if (accept) {
        if (pending > 0.0) splat_add(ch.state.x, depth, C * (pending / f));
        pending = 0.0;
        ch.current = vec4(C2, f2);
        ch.state.x = pixel2;
        ch.state.z = pss.step;
        if (pss.large) {
            ch.state.w = pss.step;
            ch.counts.y++;
        } else {
            ch.counts.w++;
        }
    } else {
        pss_reject();
    }
    ch.start.y += rays;
    ch.start.z = floatBitsToUint(pending);
    chains[item] = ch;
}
#endif
