// MMLT's wavefront (lib/mmlt_wave.glsl): a path's start. The proposal (a chain's
// mutation; a starting chain's copy of its bootstrap sample), then as the path asks: the
// strategy (s, t) among the depth + 2 of its depth, the film position, and the first ray
// of the light subpath (s >= 2, or t = 1) or of the camera subpath. s = 1, t = 1 ends
// here: the light's point seen by the camera, its shadow ray queued.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint mode = params.mode;
    mmlt_pss_init(item, mode);
    if (mode == MMLT_MODE_START) mmlt_copy_start(item);
    if (mode == MMLT_MODE_CHAINS) mmlt_propose(chains[item]);
    uint depth = mmlt_depth(item, mode);
    pss_begin_path();
    uint strategies = depth + 2u;
    uint s = min(uint(sample_1d(STREAM_CAMERA) * float(strategies)), depth + 1u);
    uint t = strategies - s;
    vec2 film = sample_2d(STREAM_CAMERA);
    uvec2 px = min(uvec2(film * vec2(uvec2(scene.width, scene.height))), uvec2(scene.width, scene.height) - 1u);
    Walk w;
    uint wflags = 0u;
    uint pflags = 0u;
    uint kind = MMLT_KIND_NONE;
    vec3 value = vec3(0.0);
    float weight = 0.0;
    bool light = t == 1u || s >= 2u;
    bool lit = false;
    if (light) {
        LightEmission le;
        uint e;
        lit = light_walk_start(w, le, e);
        if (lit && s == 1u) {
            kind = MMLT_KIND_LIGHT_POINT;
            vec3 o, d;
            float tmax;
            if (light_point_seen(le, e, px, value, weight, o, d, tmax)) queue_path_shadow(slot, wflags, o, d, tmax, light_medium(e, le.n, d));
        } else if (lit) {
            wflags |= BDPT_WALK_RAY;
        }
    }
    // The camera subpath's first ray. After a light subpath mmlt_hit starts the camera
    // subpath with it (the camera stream's numbers are those it would draw then: the
    // light walk draws none of them).
    if (t >= 2u && (!light || lit)) {
        Walk c;
        camera_walk_start(film, c);
        if (light) {
            mpaths[slot].camera_o = vec4(c.o, 0.0);
            mpaths[slot].camera_d = vec4(c.d, 0.0);
        } else {
            w = c;
            pflags |= MMLT_PATH_CAMERA;
            wflags |= BDPT_WALK_RAY;
        }
    }
    store_walk(slot, w, wflags);
    mpaths[slot].path = uvec4(s, t, pflags | (kind << 8u), px.y * scene.width + px.x);
    mpaths[slot].key = uvec4(pss.proposal, pss.step, pss.last_large, pss.large ? 1u : 0u);
    mpaths[slot].used = uvec4(pss.used[0], pss.used[1], pss.used[2], 0u);
    mpaths[slot].value = vec4(value, weight);
}
