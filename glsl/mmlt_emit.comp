// MMLT's wavefront (lib/mmlt_wave.glsl): the strategy at the camera subpath's last vertex
// z that mmlt_hit found (or where the camera subpath escaped): s = 0 the emission found,
// whole (beside the media's emission on the way, mmlt_trace's); s = 1 a light sample (its BSDF half is the shade stage's); s, t >= 2 the
// connection's geometry. Every emitter's code of MMLT is here, each of the emitters'
// densities asked in one place.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint wflags = floatBitsToUint(walks[slot].d.w);
    if ((wflags & BDPT_WALK_EMIT) == 0u) return;
    wflags &= ~BDPT_WALK_EMIT;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    uvec4 path = mpaths[slot].path;
    uint s = path.x;
    uint pflags = path.z;
    // The camera subpath's vertex z_k (w.vertices counts it when found), its last.
    bool escaped = w.escaped;
    bool ok = !escaped;
    PathVertex v;
    if (ok) {
        v = walk_vertex(slot, g);
        uint prim = floatBitsToUint(g.hit.x);
        v.emitter = has_feature(FEATURE_MEDIA) && prim == MEDIUM_HIT ? NO_EMITTER : primitive_emitter(prim);
    } else {
        v.emitter = NO_EMITTER;
    }
    // (The sampler only where this stage draws numbers: s = 1's light sample.)
    bool draws = ok && s == 1u;
    if (draws) pss_resume(slot, item);
    uint kind = MMLT_KIND_NONE;
    // The emitters' densities, asked in one place for s = 0 and s = 1.
    EmissionQuery q;
    bool ask = false;
    vec3 value;
    LightSample ls;
    // (An escaped camera subpath has a strategy only with s = 0: the environment.)
    if (s == 0u) {
        if (emission_found(w, v, escaped, value, q, ask)) kind = MMLT_KIND_EMISSION;
    } else if (!ok) {
    } else if (s == 1u) {
        if (light_sample_draw(v, ls, q)) {
            kind = MMLT_KIND_LIGHT_SAMPLE;
            ask = light_sample_weighs_all(w);
        }
    } else {
        vec3 dir;
        float d2;
        if (connection_faces(v, path_y(slot), dir, d2)) {
            kind = MMLT_KIND_CONNECTION;
            mpaths[slot].conn = vec4(dir, d2);
        }
    }
    vec2 pdfs = vec2(0.0);
    if (ask) pdfs = emission_pdfs(q);
    if (kind == MMLT_KIND_EMISSION) {
        vec4 c = vec4(value, emission_weight(w, v, escaped, q, pdfs));
        // (With the media's emission on the way to z, weight 1: mmlt_trace's.)
        if (has_feature(FEATURE_MEDIA) && (pflags & MMLT_PATH_FOUND) != 0u) c = vec4(c.xyz * c.w + mpaths[slot].value.xyz, 1.0);
        mpaths[slot].value = c;
        pflags |= MMLT_PATH_FOUND;
    } else if (kind == MMLT_KIND_LIGHT_SAMPLE) {
        pack_light_sample(ls, walks[slot].ls_wi, walks[slot].ls_le, walks[slot].ls_p, walks[slot].ls_n);
        walks[slot].ls_pdfs = vec4(pdfs, 0.0, 0.0);
        pflags |= MMLT_PATH_ASK_Z;
    } else if (kind == MMLT_KIND_CONNECTION) {
        pflags |= MMLT_PATH_ASK_Z | MMLT_PATH_ASK_Y;
    }
    walks[slot].d.w = uintBitsToFloat(wflags);
    mpaths[slot].path.z = pflags | (kind << 8u);
    if (draws) pss_save(slot);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
