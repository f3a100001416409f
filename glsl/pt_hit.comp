// The wavefront path tracer's surface interaction, for every traced path: the
// environment when the ray left the scene, else the surface at the hit, the emission
// the path found there (MIS-weighted against light sampling), the end of paths at the
// depth limit, the light sample of next-event estimation (its shadow ray waits for the
// material), and the path queued for its material class's shading stage. All the
// emitters' code of the path tracer is here.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"
#include "geometry.glsl"
#include "lights.glsl"

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
    // The light sample (a delta BSDF cannot be reached by one: no NEE there). Its BSDF
    // value and its shadow ray are the shading stage's and pt_shadow's.
    flags &= ~(PT_PATH_LIGHT_SAMPLE | PT_PATH_LIGHT_SAMPLE_OK);
    if (nee != NEE_OFF && scene.emitter_count > 0u && !bsdf_is_delta(b)) {
        Rng rng = wf_rng(i, path.o.w);
        uint e = pick_emitter(rng_block(rng).x);
        vec2 u = rng_next2(rng);
        LightSample ls;
        flags |= PT_PATH_LIGHT_SAMPLE;
        if (sample_emitter(e, s.p, u, ls) && ls.pdf > 0.0) {
            flags |= PT_PATH_LIGHT_SAMPLE_OK;
            pack_light_sample(ls, paths[i].ls_wi, paths[i].ls_le, paths[i].ls_p, paths[i].ls_n);
        }
        paths[i].o.w = uintBitsToFloat(rng.counter);
    }
    paths[i].d.w = uintBitsToFloat(flags);
    queue_push(WF_QUEUE_CLASS_BASIC + material_class(b.kind), i);
}
