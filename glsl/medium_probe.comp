// The medium probe (for tests): lib/media.glsl's free flight and the Henyey-Greenstein
// phase function (lib/sampling.glsl) on given inputs, so that tests/media.rs can check
// the GLSL against its CPU mirror (src/media.rs, bsdf/coated.rs's hg). Inputs and outputs
// are the BSDF probe's records (abi.h BsdfProbeInput, BsdfProbeOutput), read as: info.x
// the medium code, info.y the shadow ray's generator seed, u.xy the free flight's
// uniforms, u.z its tmax (INF where negative), tex1.xyz the ray's origin, wo its direction
// (and the phase function's), wi another unit direction, n.xy the phase function's draw's
// uniforms. Out: eval.xyz the flight's weight, eval.w its t; sample_dir.xyz its emission,
// sample_dir.w 1 where it scattered; sample_f.xyz the phase function's draw around wo,
// sample_f.w the phase function between wo and wi (the medium's g); info.xyz (float bits)
// the transmittance of the ray to tmax (ratio-tracked in grids), info.w the generator's
// state after it.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = PROBE_WORKGROUP_SIZE) in;
#include "bindings.glsl"
#include "media.glsl"

layout(std430, set = 0, binding = BINDING_BSDF_PROBE_INPUTS) readonly buffer ProbeInputs { BsdfProbeInput probe_inputs[]; };
layout(std430, set = 0, binding = BINDING_BSDF_PROBE_OUTPUTS) writeonly buffer ProbeOutputs { BsdfProbeOutput probe_outputs[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pass_params.samples) return;
    BsdfProbeInput p = probe_inputs[i];
    uint code = p.info.x;
    float tmax = p.u.z < 0.0 ? INF : p.u.z;
    MediumEvent ev = sample_medium(code, p.tex1.xyz, p.wo.xyz, tmax, p.u.xy);
    uint seed = p.info.y;
    vec3 tr = medium_segment_transmittance(code, p.tex1.xyz, p.wo.xyz, tmax, seed);
    float g = medium_g(code);
    BsdfProbeOutput o;
    o.eval = vec4(ev.weight, ev.t);
    o.sample_dir = vec4(ev.emitted, ev.scattered ? 1.0 : 0.0);
    o.sample_f = vec4(hg_sample(p.wo.xyz, g, p.n.xy), hg_phase(p.wo.xyz, p.wi.xyz, g));
    o.info = uvec4(floatBitsToUint(tr), seed);
    probe_outputs[i] = o;
}
