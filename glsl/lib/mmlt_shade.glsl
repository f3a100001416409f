// MMLT's wavefront (lib/mmlt_wave.glsl): the shade stage of the material class
// SHADE_CLASS (defined by the mmlt_shade_*.comp that includes this), for the vertices of
// that class: the BSDF sample that continues a walk, or the strategy's questions to the
// BSDF at z (the camera subpath's last vertex: s = 1 toward the light sample, s, t >= 2
// toward y) and at y (the light subpath's last: t = 1 toward the lens, s, t >= 2 toward
// z). Only the class's own BSDFs are compiled in (bsdf.glsl's SHADE_CLASS), asked in one
// place for the questions and the sample (bsdf_ask).
#ifndef MMLT_SHADE_GLSL
#define MMLT_SHADE_GLSL
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint wflags = floatBitsToUint(walks[slot].d.w);
    uint pflags = path_flags(slot);
    bool extend = (wflags & BDPT_WALK_EXTEND) != 0u;
    if (!extend && (pflags & (MMLT_PATH_ASK_Z | MMLT_PATH_ASK_Y)) == 0u) return;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    bool cam = (pflags & MMLT_PATH_CAMERA) != 0u;
    uint kind = path_kind(pflags);
    bool asked = false;
    bool extended = false;
    [[dont_unroll]] for (uint i = 0u; i < 2u; ++i) {
        uint bit = i == 0u ? MMLT_PATH_ASK_Z : MMLT_PATH_ASK_Y;
        if (!(i == 0u ? extend || (pflags & bit) != 0u : (pflags & bit) != 0u)) continue;
        PathVertex x = i == 0u ? walk_vertex(slot, g) : path_y(slot);
        if (vertex_class(x) != SHADE_CLASS) continue;
        BsdfParams b = class_bsdf(x);
        vec3 wi = vec3(0.0);
        uint transport = i == 0u ? TRANSPORT_RADIANCE : TRANSPORT_IMPORTANCE;
        bool want_fwd = true;
        bool want_rev = true;
        float cos_s = 0.0;
        vec3 u = vec3(0.0);
        bool beyond = false;
        if (extend) {
            // The sample that continues the walk (asked where the questions are
            // asked: one copy of the BSDF).
            pss_resume(slot, item);
            beyond = walk_beyond(w, cam);
            u = sample_3d(cam ? STREAM_CAMERA : STREAM_LIGHT);
            transport = cam ? TRANSPORT_RADIANCE : TRANSPORT_IMPORTANCE;
            want_fwd = false;
            want_rev = !beyond;
            if (!(dot(x.ns, x.w) > 0.0)) {
                wflags &= ~BDPT_WALK_EXTEND;
                pss_save(slot);
                continue;
            }
        } else {
            pflags &= ~bit;
            if (kind == MMLT_KIND_LIGHT_SAMPLE) {
                LightSample ls = unpack_light_sample(g.ls_wi, g.ls_le, g.ls_p, g.ls_n);
                if (!light_sample_faces(b, x, ls, cos_s)) {
                    pflags &= ~(MMLT_PATH_ASK_Z | MMLT_PATH_ASK_Y);
                    kind = MMLT_KIND_NONE;
                    asked = true;
                    continue;
                }
                wi = ls.wi;
                want_rev = light_sample_weighs_all(w);
            } else if (kind == MMLT_KIND_CAMERA_CONNECTION) {
                wi = mpaths[slot].to_eye.xyz;
                want_fwd = false;
            } else {
                vec3 dir = mpaths[slot].conn.xyz;
                wi = i == 0u ? dir : -dir;
            }
        }
        BsdfSample q;
        q.wi = wi;
        float pdf_rev;
        bool answered = class_ask(b, x, extend, u, transport, want_fwd, want_rev, q, pdf_rev);
        if (extend) {
            extended = answered && walk_scatter_sampled(w, x, q, pdf_rev, transport, !beyond) && walk_survives(w, beyond);
            wflags &= ~BDPT_WALK_EXTEND;
            if (extended) wflags |= BDPT_WALK_RAY;
            pss_save(slot);
            continue;
        }
        vec3 f = q.f;
        float pdf_fwd = q.pdf;
        if (i == 0u) {
            mpaths[slot].answer_z = vec4(f, pdf_fwd);
            mpaths[slot].answer_rev.xz = vec2(pdf_rev, cos_s);
        } else {
            mpaths[slot].answer_y = vec4(f, pdf_fwd);
            mpaths[slot].answer_rev.y = pdf_rev;
        }
        asked = true;
    }
    if (extended) {
        store_walk_scatter(slot, w, wflags);
    } else if (extend) {
        walks[slot].d.w = uintBitsToFloat(walk_flags(w, wflags));
    }
    if (asked) mpaths[slot].path.z = (pflags & 0xffu) | (kind << 8u);
}
#endif
