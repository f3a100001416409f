// BDPT's wavefront (lib/bdpt_wave.glsl): the shade stage of the material class
// SHADE_CLASS (defined by the bdpt_shade_*.comp that includes this), for the vertices of
// that class. Light side: the connection to the camera (t = 1); camera side: the BSDF's
// half of the s = 1 light sample; either's shadow ray queued for the trace stage. Then
// the BSDF sample that continues the walk (the camera's with Russian roulette beyond
// max_scatter()). On the camera side also the s, t >= 2 connections of the new vertex
// z_k to the light vertices y_j: the question to z's BSDF when z is of the class, and to
// each y_j's that is; the answers wait in answers[] for the trace stage. Only the class's
// own BSDFs are compiled in (bsdf.glsl's SHADE_CLASS), and each is asked in one place for
// every question (bsdf_ask), the sample too where the class's engine answers both (the
// coated walk, the measured tables, hair: inlined once; SAMPLE_IN_LOOP below).
#ifndef BDPT_SHADE_GLSL
#define BDPT_SHADE_GLSL
#include "bdpt_wave.glsl"

// Where the walk's sample is asked. The engines that answer questions and draw samples in
// one body (the coated walk, the measured tables, hair) are asked it as the question
// loop's last iteration: compiled in once. The small BSDFs of the basic and interface
// classes are asked it after the loop, at a second site whose `draw` is constant (its
// sampling code alone): inside the loop, lanes that draw would wait for lanes that still
// evaluate and back (measured: 12 % of the basic shade stage's time on the Cornell box).
#if SHADE_CLASS == MATERIAL_CLASS_BASIC || SHADE_CLASS == MATERIAL_CLASS_INTERFACE || SHADE_CLASS == SHADE_CLASS_MEDIUM
const bool SAMPLE_IN_LOOP = false;
#else
const bool SAMPLE_IN_LOOP = true;
#endif

// The walk's sample's numbers (from the walk's stream), and its question; false
// when v is seen from behind (no sample).
bool walk_sample_question(PathVertex v, bool camera, bool beyond, out vec3 u, out uint transport, out bool want_rev) {
    transport = camera ? TRANSPORT_RADIANCE : TRANSPORT_IMPORTANCE;
    want_rev = !beyond;
    u = sample_3d(camera ? STREAM_CAMERA : STREAM_LIGHT);
    return dot(v.ns, v.w) > 0.0;
}

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & (BDPT_WALK_VERTEX | BDPT_WALK_CONNECTIONS)) == 0u) return;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    PathVertex v = walk_vertex(slot, g);
    // The vertex is this class's (its walk goes on here), or only some y_j it connects to is.
    bool own = (flags & BDPT_WALK_VERTEX) != 0u && vertex_class(v) == SHADE_CLASS;
    uint first, last;
    uint connections = 0u;
    if ((flags & BDPT_WALK_CONNECTIONS) != 0u && connection_range(g.counts.w, g.counts.z, first, last))
        connections = last + 1u - first;
    if (!own && connections == 0u) return;
    Walk w = walk_load(g);
    bool camera = pass_params.side == BDPT_SIDE_CAMERA;
    if (own) sampler_resume(index, g);
    // t = 1
    vec3 eye, to_eye;
    float dist;
    uvec2 px;
    // s = 1
    LightSample ls;
    float cos_s;
    BsdfParams b;
    // The sample that continues the walk (asked after the other questions: the draws keep
    // their order).
    bool extending = own && (flags & BDPT_WALK_EXTEND) != 0u;
    bool beyond = walk_beyond(w, camera);
    bool sampled = false;
    BsdfSample bs;
    float bs_rev = 0.0;
    // The questions, in kept loops through one bsdf_ask (each BSDF is compiled in once):
    // i = 0 v's own connection (t = 1 or s = 1), i >= 1 the connection to y_j,
    // j = first + i - 1, asked of each end of the class (side 0: v toward y_j, side 1:
    // y_j toward v), and last (extending) v's sample.
    uint ext = connections + 1u;
    [[dont_unroll]] for (uint i = 0u; i <= (SAMPLE_IN_LOOP && extending ? ext : connections); ++i) {
        uint j = first + i - 1u;
        PathVertex y;
        vec3 dir;
        float d2;
        if (i > 0u && i != ext) {
            y = stored_vertex(base + j - 1u);
            if (!connection_faces(v, y, dir, d2)) continue;
        }
        [[dont_unroll]] for (uint side = 0u; side < (i == 0u || i == ext ? 1u : 2u); ++side) {
            PathVertex x = side == 0u ? v : y;
            if (side == 0u ? !own : vertex_class(x) != SHADE_CLASS) continue;
            BsdfParams bx = b;
            if (i == 0u || side == 1u) bx = class_bsdf(x);
            if (i == 0u) b = bx;
            vec3 wi = side == 0u ? dir : -dir;
            uint transport = side == 0u ? TRANSPORT_RADIANCE : TRANSPORT_IMPORTANCE;
            bool want_fwd = true;
            bool want_rev = true;
            if (i == 0u) {
                bool connect = false;
                want_fwd = false;
                if (!camera) {
                    if ((flags & BDPT_WALK_CONNECT) != 0u) {
                        connect = camera_connection_faces(v, eye, px, to_eye, dist);
                        wi = to_eye;
                        transport = TRANSPORT_IMPORTANCE;
                    }
                } else if ((flags & BDPT_WALK_LIGHT_SAMPLE) != 0u) {
                    ls = unpack_light_sample(g.ls_wi, g.ls_le, g.ls_p, g.ls_n);
                    connect = light_sample_faces(bx, v, ls, cos_s);
                    wi = ls.wi;
                    want_fwd = true;
                    want_rev = light_sample_weighs_all(w);
                }
                if (!connect) continue;
            }
            vec3 u = vec3(0.0);
            bool draw = SAMPLE_IN_LOOP && i == ext;
            if (draw) {
                want_fwd = false;
                if (!walk_sample_question(v, camera, beyond, u, transport, want_rev)) continue;
            }
            BsdfSample q;
            q.wi = wi;
            float pdf_rev;
            bool answered = class_ask(bx, x, draw, u, transport, want_fwd, want_rev, q, pdf_rev);
            if (draw) {
                sampled = answered;
                bs = q;
                bs_rev = pdf_rev;
                continue;
            }
            vec3 f = q.f;
            float pdf_fwd = q.pdf;
            if (i > 0u) {
                store_answer(answer_at(slot, j, side), f, pdf_fwd, pdf_rev);
                continue;
            }
            vec3 value, o, d;
            float weight, tmax;
            if (!camera) {
                if (camera_connection_end(v, eye, to_eye, dist, f, pdf_rev, value, weight, o, d, tmax)) {
                    walks[slot].counts.y = g.counts.y + 1u;
                    queue_shadow(slot, flags, o, d, tmax, w.vertices + 1u, 1u, px.y * scene.width + px.x, value, weight,
                                 vertex_medium_toward(v, to_eye, w.medium));
                }
            } else if (light_sample_end(w, v, ls, g.ls_pdfs.xy, cos_s, f, pdf_fwd, pdf_rev, value, weight, o, d, tmax)) {
                walks[slot].counts.y = g.counts.y + 1u;
                queue_shadow(slot, flags, o, d, tmax, 1u, w.vertices + 1u, index, value, weight,
                             vertex_medium_toward(v, ls.wi, w.medium));
            }
        }
    }
    // The walk is the vertex's class's to go on with; another class only answered.
    if (!own) return;
    if (!SAMPLE_IN_LOOP && extending) {
        vec3 u;
        uint transport;
        bool want_rev;
        if (walk_sample_question(v, camera, beyond, u, transport, want_rev))
            sampled = class_ask(b, v, true, u, transport, false, want_rev, bs, bs_rev);
    }
    bool extend = sampled && walk_scatter_sampled(w, v, bs, bs_rev, camera ? TRANSPORT_RADIANCE : TRANSPORT_IMPORTANCE, !beyond)
               && walk_survives(w, beyond);
    flags &= ~(BDPT_WALK_VERTEX | BDPT_WALK_CONNECT | BDPT_WALK_EXTEND | BDPT_WALK_LIGHT_SAMPLE);
    if (extend) flags |= BDPT_WALK_RAY;
    // maxdepth -1: how many camera walks go on after this bounce, for the host to know
    // when none do.
    if (extend && camera && has_feature(FEATURE_UNBOUNDED)) atomicAdd(bdpt_live[pass_params.bounce], 1u);
    if (extend) {
        store_walk_scatter(slot, w, flags);
    } else {
        walks[slot].d.w = uintBitsToFloat(walk_flags(w, flags));
    }
    walks[slot].o.w = uintBitsToFloat(sampler_rng.counter);
}
#endif
