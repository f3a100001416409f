// The gbuffer film's albedo stage for the material class SHADE_CLASS (defined by the
// gbuffer_albedo_*.comp that includes this; lib/gbuffer.glsl): for each pixel whose kept
// surface is of the class, the BSDF's directional albedo ρ(wo), the mean of f |cos| / pdf
// over GBUFFER_RHO_SAMPLES samples of the BSDF (pbrt-v4's VisibleSurface estimates it so,
// with 16), drawn with the sample's random numbers after its camera ray. Only the class's
// own BSDFs are compiled in (bsdf.glsl's SHADE_CLASS).
#ifndef GBUFFER_ALBEDO_GLSL
#define GBUFFER_ALBEDO_GLSL
#include "gbuffer.glsl"
#include "rng.glsl"
#include "sampling.glsl"
#include "bsdf.glsl"

const uint GBUFFER_RHO_SAMPLES = 16u;

void main() {
    uvec2 pixel;
    uint index, slot;
    if (!gbuffer_pixel(pixel, index, slot)) return;
    GpuGbufferSurface kept = gbuffer_surfaces[slot];
    uint material = floatBitsToUint(kept.wo.w);
    if (material == GBUFFER_NO_SURFACE || material_class(materials[material].info.x) != SHADE_CLASS) return;
    Rng rng;
    rng.key = kept.rng.xyz;
    rng.counter = kept.rng.w;
    vec3 wo = kept.wo.xyz;
    vec3 ns = kept.ns.xyz;
    BsdfParams b = material_bsdf(materials[material], kept.ns.w != 0.0, kept.tex0, kept.tex1);
    vec3 rho = vec3(0.0);
    for (uint j = 0u; j < GBUFFER_RHO_SAMPLES; ++j) {
        BsdfSample bs;
        if (bsdf_sample(b, SAMPLE_BRDF, ns, wo, rng_next3(rng), TRANSPORT_RADIANCE, bs) && bs.pdf > 0.0)
            rho += bs.f * abs(dot(bs.wi, ns)) / bs.pdf;
    }
    rho /= float(GBUFFER_RHO_SAMPLES);
    if (any(isnan(rho)) || any(isinf(rho))) rho = vec3(0.0);
    film[4u * index] += vec4(rho, 0.0);
}
#endif
