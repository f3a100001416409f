// pbrt-v4's `gbuffer` film (src/integrators/gbuffer.rs) in stages, one camera sample per
// pixel a pass (PassParams: samples is 1, or 0 when the host warms the kernels up):
//   gbuffer_hit.comp           the camera ray, the first surface that is not only a
//                              boundary of media, its position, normals and (u, v) added
//                              to the film; the surface kept for the albedo stage
//                              (GpuGbufferSurface, one per pixel of the band)
//   gbuffer_albedo_CLASS.comp  one per material class (bsdf.glsl's SHADE_CLASS): the
//                              albedo of the pixels whose surface is of its class
// The film holds four vec4 per pixel, sums over samples: (albedo, 0), (P, u), (N, v),
// (Ns, 0); a sample that sees no surface adds nothing (zeros, as pbrt-v4's film averages).
// Split so that no kernel holds every BSDF with the traversal (the compile-time budget):
// each stage's kernel is as small as the wavefront path tracer's.
#ifndef GBUFFER_GLSL
#define GBUFFER_GLSL
#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bindings.glsl"

layout(std430, set = 0, binding = BINDING_GBUFFER_SURFACES) buffer GbufferSurfaceBuffer {
    GpuGbufferSurface gbuffer_surfaces[];
};

// This invocation's pixel, its index in the film and its slot in the band's surfaces;
// false outside the image or the band, and when the pass has no sample (a warm-up).
bool gbuffer_pixel(out uvec2 pixel, out uint index, out uint slot) {
    pixel = gl_GlobalInvocationID.xy + uvec2(0u, pass_params.row_begin);
    index = 0u;
    slot = 0u;
    if (pass_params.samples == 0u) return false;
    if (pixel.x >= scene.width || pixel.y >= min(scene.height, pass_params.row_end)) return false;
    index = pixel.y * scene.width + pixel.x;
    slot = gl_GlobalInvocationID.y * scene.width + pixel.x;
    return true;
}
#endif
