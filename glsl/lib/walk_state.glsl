// A subpath walk kept in device memory between the stages of a wavefront (BDPT's,
// MMLT's): GpuBdptWalk (abi.h) per slot, and what each stage reads and stores of it.
// The including kernel has lib/bdpt.glsl (Walk, PathVertex).
#ifndef WALK_STATE_GLSL
#define WALK_STATE_GLSL

layout(std430, set = 0, binding = BINDING_BDPT_WALKS) buffer BdptWalkBuffer { GpuBdptWalk walks[]; };
// Beside each, its vertex's material texture values (scenes with FEATURE_MATERIAL_TEXTURES).
layout(std430, set = 0, binding = BINDING_WALK_TEXTURES) buffer WalkTextureBuffer { vec4 walk_textures[]; };

// The walk as lib/bdpt.glsl has it.
Walk walk_load(GpuBdptWalk g) {
    Walk w;
    uint flags = floatBitsToUint(g.d.w);
    w.o = g.o.xyz;
    w.d = g.d.xyz;
    w.beta = g.beta.xyz;
    w.dvcm = g.beta.w;
    w.dvc = g.prev_p.w;
    w.vertices = g.counts.x;
    w.infinite = (flags & BDPT_WALK_INFINITE) != 0u;
    w.prev_pdf_w = g.radiance.w;
    w.prev_delta = (flags & BDPT_WALK_PREV_DELTA) != 0u;
    w.prev_p = g.prev_p.xyz;
    w.escaped = (flags & BDPT_WALK_ESCAPED) != 0u;
    w.medium = flags >> BDPT_WALK_MEDIUM_SHIFT;
    return w;
}

// The flags with the walk's own (infinite, previous delta, escaped, its medium) set from w.
uint walk_flags(Walk w, uint flags) {
    flags &= ~(BDPT_WALK_INFINITE | BDPT_WALK_PREV_DELTA | BDPT_WALK_ESCAPED) & ((1u << BDPT_WALK_MEDIUM_SHIFT) - 1u);
    flags |= w.medium << BDPT_WALK_MEDIUM_SHIFT;
    if (w.infinite) flags |= BDPT_WALK_INFINITE;
    if (w.prev_delta) flags |= BDPT_WALK_PREV_DELTA;
    if (w.escaped) flags |= BDPT_WALK_ESCAPED;
    return flags;
}

// Write the whole walk into g.
void walk_save(inout GpuBdptWalk g, Walk w, uint flags) {
    g.o.xyz = w.o;
    g.d = vec4(w.d, uintBitsToFloat(walk_flags(w, flags)));
    g.beta = vec4(w.beta, w.dvcm);
    g.prev_p = vec4(w.prev_p, w.dvc);
    g.counts.x = w.vertices;
    g.radiance.w = w.prev_pdf_w;
}

// Store what a new vertex changes of the walk (its MIS sums and vertex count) and the
// flags. (Each stage stores only what it changed: on lavapipe every word of a walk
// is a memory access per pixel.)
void store_walk_vertex(uint slot, Walk w, uint flags) {
    walks[slot].beta.w = w.dvcm;
    walks[slot].prev_p.w = w.dvc;
    walks[slot].counts.x = w.vertices;
    walks[slot].d.w = uintBitsToFloat(walk_flags(w, flags));
}

// Store what a scattering changes of the walk: its next ray, throughput, MIS sums and
// last bounce, and the flags.
void store_walk_scatter(uint slot, Walk w, uint flags) {
    walks[slot].o.xyz = w.o;
    walks[slot].d = vec4(w.d, uintBitsToFloat(walk_flags(w, flags)));
    walks[slot].beta = vec4(w.beta, w.dvcm);
    walks[slot].prev_p = vec4(w.prev_p, w.dvc);
    walks[slot].radiance.w = w.prev_pdf_w;
}

// Store the whole walk (a new one), and the flags.
void store_walk(uint slot, Walk w, uint flags) {
    store_walk_scatter(slot, w, flags);
    walks[slot].counts.x = w.vertices;
}

// The vertex waiting for the shade stage (g: the walk of `slot`).
PathVertex walk_vertex(uint slot, GpuBdptWalk g) {
    GpuPathVertex v;
    v.p = g.v_p;
    v.n = g.v_n;
    v.wi = g.v_wi;
    v.beta = g.v_beta;
    v.ns = g.v_ns;
    PathVertex y = unpack_vertex(v);
    if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
        y.tex0 = walk_textures[2u * slot];
        y.tex1 = walk_textures[2u * slot + 1u];
    }
    return y;
}

void store_vertex(uint slot, PathVertex y) {
    GpuPathVertex v = pack_vertex(y);
    walks[slot].v_p = v.p;
    walks[slot].v_n = v.n;
    walks[slot].v_wi = v.wi;
    walks[slot].v_beta = v.beta;
    walks[slot].v_ns = v.ns;
    if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
        walk_textures[2u * slot] = y.tex0;
        walk_textures[2u * slot + 1u] = y.tex1;
    }
}
#endif
