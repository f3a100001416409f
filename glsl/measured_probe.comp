// The measured-material probe (for tests): f, the pdf and a sample of the measured BRDF
// (lib/measured.glsl) on given inputs, so that tests/bsdf_probe.rs can check the GLSL
// against its CPU mirror (src/measured.rs), as bsdf_probe.comp does for the other BSDFs.
// The material packed in the texel buffer at info.x; directions in the local frame;
// pass_params.samples inputs. Outputs as bsdf_probe.comp's (abi.h BsdfProbeOutput).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = PROBE_WORKGROUP_SIZE) in;
#include "bindings.glsl"
#include "measured.glsl"

layout(std430, set = 0, binding = BINDING_BSDF_PROBE_INPUTS) readonly buffer ProbeInputs { BsdfProbeInput probe_inputs[]; };
layout(std430, set = 0, binding = BINDING_BSDF_PROBE_OUTPUTS) writeonly buffer ProbeOutputs { BsdfProbeOutput probe_outputs[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pass_params.samples) return;
    BsdfProbeInput p = probe_inputs[i];
    uint base = p.info.x;
    vec3 wo = p.wo.xyz;
    vec3 wi = p.wi.xyz;
    BsdfProbeOutput o;
    o.eval = vec4(measured_eval(base, wo, wi), measured_pdf(base, wo, wi));
    vec3 swi, sf;
    float spdf;
    bool ok = measured_sample(base, wo, p.u.xy, swi, sf, spdf);
    o.sample_dir = vec4(swi, spdf);
    o.sample_f = vec4(sf, ok ? 1.0 : 0.0);
    o.info = uvec4(0u);
    probe_outputs[i] = o;
}
