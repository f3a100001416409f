// The wavefront path tracer's shading stage for the material class SHADE_CLASS (defined
// by the pt_shade_*.comp that includes this): the BSDF toward the path's light sample
// (queued as a shadow ray with its estimate), then the BSDF sample that continues the
// path (throughput, Russian roulette, the next ray queued for tracing). Only the class's
// own BSDFs are compiled in (bsdf.glsl's SHADE_CLASS).
#ifndef PT_SHADE_GLSL
#define PT_SHADE_GLSL
#include "wavefront.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "geometry.glsl"
#include "lights.glsl"
#include "media.glsl"

// Whether the light sample's question and the sample are asked at one bsdf_ask (the
// engine classes) or at two sites (the closed forms: lanes that draw would wait for
// lanes that evaluate).
#if SHADE_CLASS == MATERIAL_CLASS_BASIC || SHADE_CLASS == MATERIAL_CLASS_INTERFACE
const bool ONE_ASK = false;
#else
const bool ONE_ASK = true;
#endif

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_CLASS_BASIC + SHADE_CLASS, i)) return;
    GpuPtPath path = paths[i];
    uint depth = wf.depth;
    uint nee = scene.nee;
    bool rr = scene.russian_roulette != 0u;
    uint mode = scene.sample_mode;
    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : scene.max_depth;
    uint flags = floatBitsToUint(path.d.w);
    // In media: the medium the path arrived in, and pbrt's geometric normal (the side of
    // the material's outside), by which the rays leaving here find theirs.
    uint medium = MEDIUM_VACUUM;
    vec3 ng = path.ns.w != 0.0 ? path.n.xyz : -path.n.xyz;
    if (has_feature(FEATURE_MEDIA)) {
        depth -= flags >> PT_PATH_CROSSINGS_SHIFT;
        medium = (flags >> PT_PATH_MEDIUM_SHIFT) & 0xFFFFu;
    }
    uint material = floatBitsToUint(path.hit.w);
    vec3 beta = path.beta.xyz;
    vec3 p = path.p.xyz;
    vec3 n = path.n.xyz;
    vec3 ns = path.ns.xyz;
    vec3 wo = -path.d.xyz;
    Rng rng = wf_rng(i, path.o.w);
    BsdfParams b = material_bsdf(materials[material], path.ns.w != 0.0, path.tex0, path.tex1);
    bool delta = bsdf_is_delta(b);
    // The questions to the BSDF: f and the pdf toward the light sample, then the sample
    // that continues the path, in a kept loop through one bsdf_ask where the class's
    // engine answers both (ONE_ASK: the coated walk, the measured tables, hair, inlined
    // once); the small BSDFs of the basic and interface classes are asked at two sites.
    bool light_question = false;
    LightSample ls;
    float cos_s;
    bool mis = nee == NEE_MIS;
    if ((flags & PT_PATH_LIGHT_SAMPLE_OK) != 0u) {
        ls = unpack_light_sample(path.ls_wi, path.ls_le, path.ls_p, path.ls_n);
        light_question = direct_light_faces(b, n, ns, wo, ls.wi, cos_s);
    }
    // With NEE on, emission found by the next bounce would not count (unless this
    // vertex is a delta one): no sample.
    bool sample_question = !(nee == NEE_ON && depth + 1u == max_vertices && !delta);
    vec3 f = vec3(0.0);
    float pdf_fwd = 0.0;
    bool sampled = false;
    BsdfSample bs;
    [[dont_unroll]] for (uint q = ONE_ASK ? 0u : 1u; q < 2u; ++q) {
        bool draw = ONE_ASK && q == 1u;
        if (draw ? !sample_question : !light_question) continue;
        BsdfSample s;
        s.wi = ls.wi;
        vec3 u = draw ? rng_next3(rng) : vec3(0.0);
        float pdf_rev;
        bool answered = bsdf_ask(b, mode, ns, wo, draw, u, TRANSPORT_RADIANCE, !draw && mis, false, s, pdf_rev);
        if (draw) {
            sampled = answered;
            bs = s;
        } else {
            f = s.f;
            pdf_fwd = s.pdf;
        }
    }
    if ((flags & PT_PATH_LIGHT_SAMPLE) != 0u) {
        bool queued = false;
        if (light_question && f != vec3(0.0)) {
            float w = 1.0;
            if (mis) w = light_sample_mis_weight(ls, pdf_fwd);
            vec3 estimate = f * ls.L * (cos_s * w / ls.pdf);
            vec3 so, sd;
            float tmax;
            light_sample_shadow_ray(p, n, ls, so, sd, tmax);
            paths[i].ls_wi = vec4(so, tmax);
            uint shadow_medium = has_feature(FEATURE_MEDIA) ? medium_after(material, ng, sd, medium) : 0u;
            paths[i].ls_le = vec4(sd, uintBitsToFloat(shadow_medium));
            paths[i].ls_p = vec4(estimate, 0.0);
            paths[i].ls_n = vec4(beta, 0.0);
            queue_push(WF_QUEUE_SHADOW, i);
            queued = true;
        }
        // A light sample that cannot contribute adds zero, as it would on one invocation.
        if (!queued) paths[i].radiance.xyz = path.radiance.xyz + beta * vec3(0.0);
    }
    if (!sample_question) return;
    if (!ONE_ASK) sampled = bsdf_sample(b, mode, ns, wo, rng_next3(rng), TRANSPORT_RADIANCE, bs);
    if (!sampled) return;
    if (!shading_side_agrees(n, ns, bs.wi)) return;
    float cos_i = dot(n, bs.wi);
    beta *= bs.f * (abs(dot(ns, bs.wi)) / bs.pdf);
    if (beta == vec3(0.0)) return;
    if (rr) {
        float survive = min(1.0, max(beta.x, max(beta.y, beta.z)));
        if (rng_next(rng) >= survive) return;
        beta /= survive;
    }
    uint kept = 0u;
    if (has_feature(FEATURE_MEDIA)) {
        kept = (medium_after(material, ng, bs.wi, medium) << PT_PATH_MEDIUM_SHIFT)
             | (flags & (0xFFu << PT_PATH_CROSSINGS_SHIFT));
    }
    flags = ((bs.flags & BSDF_LOBE_DELTA) != 0u ? PT_PATH_PREV_DELTA : 0u) | kept;
    paths[i].o = vec4(offset_ray_origin(p, cos_i > 0.0 ? n : -n), uintBitsToFloat(rng.counter));
    paths[i].d = vec4(bs.wi, uintBitsToFloat(flags));
    paths[i].beta = vec4(beta, bs.pdf);
    paths[i].prev_p.xyz = p;
    queue_push(WF_QUEUE_RAYS, i);
}
#endif
