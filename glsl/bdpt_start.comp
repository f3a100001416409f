// BDPT's wavefront (lib/bdpt_wave.glsl): a subpath's start. The light side picks a light
// by power, places a point and a direction on it, and queues the s = 1, t = 1 strategy's
// shadow ray; the camera side resumes the pixel's sampler after the light subpath and
// shoots the camera ray.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    bool light = pass_params.side == BDPT_SIDE_LIGHT;
    if (!bdpt_pixel(light, pixel, index, slot, base) || pass_params.samples == 0u) return;
    GpuBdptWalk g = walks[slot];
    Walk w;
    uint flags = 0u;
    if (light) {
        sampler_start(scene.seed, index, bdpt_sample());
        g.counts = uvec4(0u);
        g.radiance = vec4(0.0);
        LightEmission le;
        uint e;
        if (light_walk_start(w, le, e)) {
            uvec2 px;
            vec3 value, o, d;
            float weight, tmax;
            if (min_scatter() == 0u && light_point_seen(le, e, px, value, weight, o, d, tmax)) {
                g.counts.y++;
                g.ls_wi = vec4(o, tmax);
                g.ls_le = vec4(d, uintBitsToFloat(px.y * scene.width + px.x));
                g.ls_p = vec4(value, weight);
                g.ls_n = vec4(uintBitsToFloat(1u), uintBitsToFloat(1u), uintBitsToFloat(light_medium(e, le.n, d)), 0.0);
                flags |= BDPT_WALK_SHADOW | BDPT_WALK_SHADOW_SPLAT;
            }
            // Light vertices serve only paths of at most max_scatter() scattering vertices.
            if (max_scatter() > 0u && min_scatter() <= max_scatter()) flags |= BDPT_WALK_RAY;
        }
    } else {
        sampler_resume(index, g);
        camera_walk_start((vec2(pixel) + sample_2d(STREAM_CAMERA)) / vec2(uvec2(scene.width, scene.height)), w);
        g.counts.w = 0u;
        g.radiance = vec4(0.0);
        g.connected = vec4(0.0);
        flags = BDPT_WALK_RAY;
    }
    walk_save(g, w, flags);
    g.o.w = uintBitsToFloat(sampler_rng.counter);
    walks[slot] = g;
}
