// The texture probe (for tests): lib/texture.glsl's texture_value on given inputs, so that
// tests/textures.rs can check the GLSL against its CPU mirror (src/texture.rs
// texture_value_in, src/mipmap.rs) point by point, the MIP level each lookup picks
// included. Inputs are the BSDF probe's records (abi.h BsdfProbeInput), read as: info.x
// the texture, u.xy the surface's (u, v), tex1.xyz the world point, n.xyz the unit
// geometric normal, wo.xyz dp/dx, wi.xyz dp/dy, (u.z, u.w, tex1.w, n.w) the footprint in
// (u, v) (du/dx, dv/dx, du/dy, dv/dy). Out: eval.xyz the texture's value.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = PROBE_WORKGROUP_SIZE) in;
#include "bindings.glsl"
#include "texture.glsl"

layout(std430, set = 0, binding = BINDING_BSDF_PROBE_INPUTS) readonly buffer ProbeInputs { BsdfProbeInput probe_inputs[]; };
layout(std430, set = 0, binding = BINDING_BSDF_PROBE_OUTPUTS) writeonly buffer ProbeOutputs { BsdfProbeOutput probe_outputs[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pass_params.samples) return;
    BsdfProbeInput q = probe_inputs[i];
    vec4 duv = vec4(q.u.zw, q.tex1.w, q.n.w);
    vec3 v = texture_value(q.info.x, q.u.xy, q.tex1.xyz, q.n.xyz, q.wo.xyz, q.wi.xyz, duv, spec_features);
    BsdfProbeOutput o;
    o.eval = vec4(v, 0.0);
    o.sample_dir = vec4(0.0);
    o.sample_f = vec4(0.0);
    o.info = uvec4(0u);
    probe_outputs[i] = o;
}
