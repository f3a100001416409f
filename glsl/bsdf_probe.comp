// The BSDF probe (for tests): evaluates, samples and takes the pdf of the GLSL BSDFs
// (lib/bsdf.glsl) on given inputs, so that tests/bsdf_probe.rs can check the GLSL
// itself against its CPU mirror (src/bsdf.rs), as trace_probe.comp does for traversal.
// Materials at BINDING_MATERIALS (the probe's own records), measured materials' tables at
// DATA_TEXELS; pass_params.samples inputs.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = PROBE_WORKGROUP_SIZE) in;
#include "bindings.glsl"
#include "bsdf.glsl"

layout(std430, set = 0, binding = BINDING_BSDF_PROBE_INPUTS) readonly buffer ProbeInputs { BsdfProbeInput probe_inputs[]; };
layout(std430, set = 0, binding = BINDING_BSDF_PROBE_OUTPUTS) writeonly buffer ProbeOutputs { BsdfProbeOutput probe_outputs[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pass_params.samples) return;
    BsdfProbeInput p = probe_inputs[i];
    BsdfParams b = material_bsdf(materials[p.info.x], p.info.w == 0u, vec4(0.0), p.tex1);
    uint mode = p.info.y;
    uint transport = p.info.z;
    vec3 n = p.n.xyz;
    vec3 wo = p.wo.xyz;
    vec3 wi = p.wi.xyz;
    BsdfProbeOutput o;
    o.eval = vec4(bsdf_eval(b, n, wo, wi, transport), bsdf_pdf(b, mode, n, wo, wi));
    BsdfSample s;
    bool ok = bsdf_sample(b, mode, n, wo, p.u.xyz, transport, s);
    o.sample_dir = vec4(s.wi, s.pdf);
    o.sample_f = vec4(s.f, ok ? 1.0 : 0.0);
    // The combined queries the integrators' connections use (bsdf_eval_pdfs,
    // bsdf_sample_rev), for their densities.
    float pdf_fwd, pdf_rev, sample_rev;
    bsdf_eval_pdfs(b, mode, n, wo, wi, transport, true, true, pdf_fwd, pdf_rev);
    BsdfSample s2;
    bsdf_sample_rev(b, mode, n, wo, p.u.xyz, transport, true, s2, sample_rev);
    o.info = uvec4(s.flags, floatBitsToUint(sample_rev), floatBitsToUint(pdf_fwd), floatBitsToUint(pdf_rev));
    probe_outputs[i] = o;
}
