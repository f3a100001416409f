// The wavefront path tracer's stage for media (FEATURE_MEDIA), beside the material
// classes' shading stages: at a scattering vertex in a medium, the phase function toward
// the light sample pt_hit drew (queued as a shadow ray with its estimate, and the medium
// it starts in) and the phase function's draw that continues the path; at a pass-through
// surface (a boundary of media), the crossing: the ray goes on beyond it, in the medium
// on its other side, as the same path segment (the previous vertex and its pdf kept for
// the MIS weight of the emission it finds).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"
#include "sampling.glsl"
#include "geometry.glsl"
#include "lights.glsl"
#include "media.glsl"

void main() {
    uint i;
    if (!queue_take(WF_QUEUE_MEDIUM, i)) return;
    GpuPtPath path = paths[i];
    uint flags = floatBitsToUint(path.d.w);
    uint medium = (flags >> PT_PATH_MEDIUM_SHIFT) & 0xFFFFu;
    uint crossings = flags >> PT_PATH_CROSSINGS_SHIFT;
    vec3 d = path.d.xyz;
    vec3 p = path.p.xyz;
    if ((flags & PT_PATH_PASS_THROUGH) != 0u) {
        if (crossings >= MAX_PASS_THROUGH) return;
        vec3 ng = path.n.xyz;
        medium = medium_after(floatBitsToUint(path.hit.w), ng, d, medium);
        flags = (flags & (PT_PATH_PREV_DELTA | PT_PATH_LIGHT_SAMPLE | PT_PATH_LIGHT_SAMPLE_OK))
              | (medium << PT_PATH_MEDIUM_SHIFT) | ((crossings + 1u) << PT_PATH_CROSSINGS_SHIFT);
        paths[i].o.xyz = offset_ray_origin(p, dot(d, ng) > 0.0 ? ng : -ng);
        paths[i].d.w = uintBitsToFloat(flags);
        queue_push(WF_QUEUE_RAYS, i);
        return;
    }
    uint depth = wf.depth - crossings;
    uint nee = scene.nee;
    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : scene.max_depth;
    vec3 beta = path.beta.xyz;
    vec3 wo = -d;
    float g = medium_g(medium);
    Rng rng = wf_rng(i, path.o.w);
    if ((flags & PT_PATH_LIGHT_SAMPLE_OK) != 0u) {
        LightSample ls = unpack_light_sample(path.ls_wi, path.ls_le, path.ls_p, path.ls_n);
        float ph = hg_phase(wo, ls.wi, g);
        float w = nee == NEE_MIS ? light_sample_mis_weight(ls, ph) : 1.0;
        vec3 so, sd;
        float tmax;
        light_sample_shadow_ray(p, vec3(0.0), ls, so, sd, tmax);
        paths[i].ls_wi = vec4(so, tmax);
        paths[i].ls_le = vec4(sd, uintBitsToFloat(medium));
        paths[i].ls_p = vec4(ls.L * (ph * w / ls.pdf), 0.0);
        paths[i].ls_n = vec4(beta, 0.0);
        queue_push(WF_QUEUE_SHADOW, i);
    }
    // With NEE on, emission found by the next bounce would not count: no sample.
    if (nee == NEE_ON && depth + 1u == max_vertices) return;
    // The phase function's draw: f / pdf = 1, the throughput stays.
    vec3 wi = hg_sample(wo, g, rng_next2(rng));
    float pdf = hg_phase(wo, wi, g);
    if (scene.russian_roulette != 0u) {
        float survive = min(1.0, max(beta.x, max(beta.y, beta.z)));
        if (rng_next(rng) >= survive) return;
        beta /= survive;
    }
    flags &= ~(PT_PATH_PREV_DELTA | PT_PATH_LIGHT_SAMPLE | PT_PATH_LIGHT_SAMPLE_OK);
    paths[i].o = vec4(p, uintBitsToFloat(rng.counter));
    paths[i].d = vec4(wi, uintBitsToFloat(flags));
    paths[i].beta = vec4(beta, pdf);
    paths[i].prev_p.xyz = p;
    queue_push(WF_QUEUE_RAYS, i);
}
