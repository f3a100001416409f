// BDPT's wavefront (lib/bdpt_wave.glsl): the shade stage of the material class
// SHADE_CLASS (defined by the bdpt_shade_*.comp that includes this), for the vertices of
// that class. Light side: the connection to the camera (t = 1); camera side: the BSDF's
// half of the s = 1 light sample; either's shadow ray queued for the trace stage. Then
// the BSDF sample that continues the walk (the camera's with Russian roulette beyond
// max_scatter()). Only the class's own BSDFs are compiled in (bsdf.glsl's SHADE_CLASS),
// and each is asked in one place for both sides: one evaluation, one sample.
#ifndef BDPT_SHADE_GLSL
#define BDPT_SHADE_GLSL
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & BDPT_WALK_VERTEX) == 0u) return;
    uint material = floatBitsToUint(walks[slot].v_p.w) & ~PATH_VERTEX_FRONT;
    if (material_class(materials[material].info.x) != SHADE_CLASS) return;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    PathVertex v = walk_vertex(g);
    BsdfParams b = vertex_bsdf(v);
    sampler_resume(index, g);
    bool camera = pass_params.side == BDPT_SIDE_CAMERA;
    // The connection's direction from v and what the BSDF is asked about it.
    bool connect = false;
    vec3 wi = vec3(0.0, 0.0, 1.0);
    uint transport = TRANSPORT_RADIANCE;
    bool want_fwd = false;
    bool want_rev = true;
    // t = 1
    vec3 eye, to_eye;
    float dist;
    uvec2 px;
    // s = 1
    LightSample ls;
    float cos_s;
    if (!camera) {
        if ((flags & BDPT_WALK_CONNECT) != 0u) {
            connect = camera_connection_faces(v, eye, px, to_eye, dist);
            wi = to_eye;
            transport = TRANSPORT_IMPORTANCE;
        }
    } else if ((flags & BDPT_WALK_LIGHT_SAMPLE) != 0u) {
        ls = unpack_light_sample(g.ls_wi, g.ls_le, g.ls_p, g.ls_n);
        connect = light_sample_faces(b, v, ls, cos_s);
        wi = ls.wi;
        want_fwd = true;
        want_rev = light_sample_weighs_all(w);
    }
    if (connect) {
        float pdf_fwd, pdf_rev;
        vec3 f = bsdf_eval_pdfs(b, scene.sample_mode, v.ns, v.w, wi, transport, want_fwd, want_rev, pdf_fwd, pdf_rev);
        vec3 value, o, d;
        float weight, tmax;
        if (!camera) {
            if (camera_connection_end(v, eye, to_eye, dist, f, pdf_rev, value, weight, o, d, tmax)) {
                walks[slot].counts.y = g.counts.y + 1u;
                queue_shadow(slot, flags, o, d, tmax, w.vertices + 1u, 1u, px.y * scene.width + px.x, value, weight);
            }
        } else if (light_sample_end(w, v, ls, g.ls_pdfs.xy, cos_s, f, pdf_fwd, pdf_rev, value, weight, o, d, tmax)) {
            walks[slot].counts.y = g.counts.y + 1u;
            queue_shadow(slot, flags, o, d, tmax, 1u, w.vertices + 1u, index, value, weight);
        }
    }
    bool extend = (flags & BDPT_WALK_EXTEND) != 0u && walk_extend(w, v, b, camera);
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
