// The wavefront path tracer's last stage: each pixel of the band adds its samples'
// radiance to the film in sample order (a sample that is NaN or infinite adds nothing and
// is counted), and film.w the rays they traced.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "wavefront.glsl"

void main() {
    uint p = gl_GlobalInvocationID.x;
    uint band = wf_band_pixels();
    if (p >= band) return;
    uvec2 pixel = wf_pixel(p);
    uint index = pixel.y * scene.width + pixel.x;
    for (uint s = 0u; s < wf.samples; ++s) {
        vec4 r = paths[s * band + p].radiance;
        vec3 sum = vec3(0.0);
        if (any(isnan(r.xyz)) || any(isinf(r.xyz))) {
            atomicAdd(stats[STAT_NONFINITE], 1u);
        } else {
            sum += r.xyz;
        }
        film[index] += vec4(sum, float(floatBitsToUint(r.w)));
    }
}
