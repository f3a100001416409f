// The wavefront path tracer's surface interaction, for every traced path: the
// environment when the ray left the scene, else the surface at the hit, the emission
// the path found there (MIS-weighted against light sampling), the end of paths at the
// depth limit, the light sample of next-event estimation (its shadow ray waits for the
// material), and the path queued for its material class's shading stage. All the
// emitters' code of the path tracer is here. In media (FEATURE_MEDIA) the ray's next
// event first: a scattering vertex in the medium (its light sample drawn here, the rest
// pt_medium's) or the surface, with the transmittance between; a pass-through surface
// (a boundary of media) goes to pt_medium too, to be crossed.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "geometry.glsl"
#include "lights.glsl"
#include "media.glsl"

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_RAYS, i)) return;
    GpuPtPath path = paths[i];
    uint depth = wf.depth;
    uint nee = scene.nee;
    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : scene.max_depth;
    uint flags = floatBitsToUint(path.d.w);
    bool prev_delta = (flags & PT_PATH_PREV_DELTA) != 0u;
    float prev_pdf = path.beta.w;
    vec3 beta = path.beta.xyz;
    vec3 L = path.radiance.xyz;
    vec3 o = path.o.xyz;
    vec3 d = path.d.xyz;
    uint prim = floatBitsToUint(path.hit.x);
    // The vertex this hit makes (depth + 1): a surface, or a scattering point in a medium.
    bool in_medium = false;
    vec3 at = vec3(0.0);
    bool delta = false;
    uint queue = WF_QUEUE_MEDIUM;
    if (has_feature(FEATURE_MEDIA)) {
        // (Pass-through surfaces crossed are not vertices.)
        depth -= flags >> PT_PATH_CROSSINGS_SHIFT;
        uint medium = (flags >> PT_PATH_MEDIUM_SHIFT) & 0xFFFFu;
        if (medium != MEDIUM_VACUUM) {
            Rng rng = wf_rng(i, path.o.w);
            MediumEvent ev = sample_medium(medium, o, d, prim == NO_HIT ? INF : path.prev_p.w, rng_next2(rng));
            path.o.w = uintBitsToFloat(rng.counter);
            paths[i].o.w = path.o.w;
            // The medium's emission counts as a vertex's would (pbrt-v4's volpath adds it
            // while depth < maxdepth).
            if (depth < max_vertices) L += beta * ev.emitted;
            beta *= ev.weight;
            paths[i].beta.xyz = beta;
            paths[i].radiance.xyz = L;
            if (beta == vec3(0.0)) return;
            if (ev.scattered) {
                if (depth + 1u > max_vertices) return;
                in_medium = true;
                at = o + ev.t * d;
                paths[i].p = vec4(at, 0.0);
            }
        }
    }
    if (!in_medium) {
        if (prim == NO_HIT) {
            // The environment, found by the path itself.
            if (scene.environment != NO_EMITTER) {
                vec3 Le = environment_radiance(o, d);
                if (depth == 0u || nee == NEE_OFF || prev_delta) {
                    L += beta * Le;
                } else if (nee == NEE_MIS) {
                    L += beta * Le * power_heuristic(prev_pdf, environment_pdf(d));
                }
                paths[i].radiance.xyz = L;
            }
            return;
        }
        Hit hit;
        hit.t = path.prev_p.w;
        hit.prim = prim;
        hit.bary = path.hit.yz;
        Surface s = surface_at(hit, o, d);
        if (has_feature(FEATURE_MEDIA) && material_passes_through(s.material)) {
            // A boundary of media, crossed by pt_medium.
            paths[i].hit.w = uintBitsToFloat(s.material);
            paths[i].p = vec4(s.p, 0.0);
            paths[i].n = vec4(s.ng, 0.0);
            paths[i].d.w = uintBitsToFloat(flags | PT_PATH_PASS_THROUGH);
            queue_push(WF_QUEUE_MEDIUM, i);
            return;
        }
        vec3 wo = -d;
        bool front = dot(s.ng, wo) >= 0.0;
        BsdfParams b = material_bsdf(materials[s.material], front, s.tex0, s.tex1);
        // Emission found by the path itself.
        if (s.emitter != NO_EMITTER) {
            vec3 Le = emitted_radiance(s.material, s.ng, wo);
            if (depth == 0u || nee == NEE_OFF || prev_delta) {
                L += beta * Le;
            } else if (nee == NEE_MIS && Le != vec3(0.0)) {
                L += beta * Le * emitter_hit_mis_weight(s.emitter, path.prev_p.xyz, prev_pdf, s.p, s.ng);
            }
            paths[i].radiance.xyz = L;
        }
        // This hit is scattering vertex depth+1; paths have at most max_vertices of them.
        if (depth + 1u > max_vertices) return;
        vec3 n = dot(s.ng, wo) < 0.0 ? -s.ng : s.ng;
        vec3 ns = dot(s.ng, wo) < 0.0 ? -s.ns : s.ns;
        // Seen from behind its shading normal, the surface reflects nothing.
        if (!(dot(ns, wo) > 0.0)) return;
        paths[i].hit.w = uintBitsToFloat(s.material);
        paths[i].p = vec4(s.p, s.uv.x);
        paths[i].n = vec4(n, s.uv.y);
        paths[i].ns = vec4(ns, front ? 1.0 : 0.0);
        if (has_feature(FEATURE_MATERIAL_TEXTURES)) {
            paths[i].tex0 = s.tex0;
            paths[i].tex1 = s.tex1;
        }
        at = s.p;
        delta = bsdf_is_delta(b);
        queue = WF_QUEUE_CLASS_BASIC + material_class(b.kind);
    }
    // The light sample (a delta BSDF cannot be reached by one: no NEE there). Its BSDF
    // or phase function value and its shadow ray are the shading stage's (pt_medium's)
    // and pt_shadow's.
    flags &= ~(PT_PATH_LIGHT_SAMPLE | PT_PATH_LIGHT_SAMPLE_OK);
    if (nee != NEE_OFF && scene.emitter_count > 0u && !delta) {
        Rng rng = wf_rng(i, path.o.w);
        uint e = pick_emitter(rng_block(rng).x);
        vec2 u = rng_next2(rng);
        LightSample ls;
        flags |= PT_PATH_LIGHT_SAMPLE;
        if (sample_emitter(e, at, u, ls) && ls.pdf > 0.0) {
            flags |= PT_PATH_LIGHT_SAMPLE_OK;
            pack_light_sample(ls, paths[i].ls_wi, paths[i].ls_le, paths[i].ls_p, paths[i].ls_n);
        }
        paths[i].o.w = uintBitsToFloat(rng.counter);
    }
    paths[i].d.w = uintBitsToFloat(flags);
    queue_push(queue, i);
}
