// MMLT's wavefront (lib/mmlt_wave.glsl): the visibility stage. The slot's queued shadow
// ray first (the path's contribution counts when nothing blocks it), then its walk's
// closest hit, for mmlt_hit. In media (FEATURE_MEDIA) both go on through pass-through
// surfaces: the shadow ray's contribution times the transmittance of each medium it
// crosses, the walk's ray a free flight (as bdpt_trace's: its distance from the walk's
// stream) that may end at a scattering vertex in its medium (MEDIUM_HIT), and that
// gathers the media's emission on its way (s = 0's, on the camera subpath's last ray).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    if ((flags & (BDPT_WALK_SHADOW | BDPT_WALK_RAY)) == 0u) return;
    // Both rays through one trace_ray (each call site is a copy of the backend): r = 0 the
    // shadow ray, r = 1 the walk's.
    uint rays = 0u;
    bool media = has_feature(FEATURE_MEDIA);
    bool cam = (mpaths[slot].path.z & MMLT_PATH_CAMERA) != 0u;
    [[dont_unroll]] for (uint r = 0u; r < 2u; ++r) {
        bool closest = r == 1u;
        if ((flags & (closest ? BDPT_WALK_RAY : BDPT_WALK_SHADOW)) == 0u) continue;
        vec4 o = closest ? vec4(walks[slot].o.xyz, INF) : walks[slot].ls_wi;
        vec3 d = closest ? walks[slot].d.xyz : walks[slot].ls_le.xyz;
        uint medium = closest ? flags >> BDPT_WALK_MEDIUM_SHIFT : floatBitsToUint(walks[slot].ls_le.w);
        rays++;
        Hit hit;
        bool found = false;
        bool scattered = false;
        vec3 tr = vec3(1.0);
        float travelled = 0.0;
        uint seed = media && !closest ? medium_ray_seed(o.xyz, d) : 0u;  // grids' ratio tracking
        // (The walk's free flight: one pair of numbers per ray, in media scenes.)
        FreeFlight flight;
        if (media && closest) {
            pss_resume(slot, item);
            flight = free_flight_start(sample_2d(cam ? STREAM_CAMERA : STREAM_LIGHT));
            pss_save(slot);
        }
        vec3 weight = vec3(1.0);
        [[dont_unroll]] for (uint k = 0u; k <= MAX_PASS_THROUGH; ++k) {
            found = (closest || o.w > 0.0) && trace_ray(o.xyz, d, o.w, !closest && !media, hit);
            if (!media) break;
            if (closest) {
                float t;
                if (free_flight_segment(flight, medium, o.xyz, d, found ? hit.t : INF, t, weight)) {
                    scattered = true;
                    hit.t = travelled + t;
                    break;
                }
            } else if (medium != MEDIUM_VACUUM) {
                tr *= medium_segment_transmittance(medium, o.xyz, d, found ? hit.t : o.w, seed);
            }
            if (!found) break;
            vec3 ng;
            uint m = primitive_material(hit, o.xyz, d, ng);
            if (!material_passes_through(m)) break;
            if (k == MAX_PASS_THROUGH) {
                weight = vec3(0.0);
                break;
            }
            medium = medium_after(m, ng, d, medium);
            vec3 next = offset_ray_origin(o.xyz + hit.t * d, dot(d, ng) > 0.0 ? ng : -ng);
            float step = dot(next - o.xyz, d);
            travelled += step;
            o = vec4(next, isinf(o.w) ? o.w : max(o.w - step, 0.0));
            rays++;
        }
        if (closest) {
            if (media) {
                flags = (flags & ((1u << BDPT_WALK_MEDIUM_SHIFT) - 1u)) | (medium << BDPT_WALK_MEDIUM_SHIFT);
                // s = 0: the media's emission along the camera subpath's last segment (from
                // z_{t-2}) ends a path of this depth that no other strategy samples (lights
                // are not in media): weight 1, as BDPT's camera subpaths count it, and below
                // the depth cap only (pbrt-v4's volpath counts a medium's emission while
                // depth < maxdepth). mmlt_emit adds an emitter's found at z_{t-1}.
                uvec2 st = mpaths[slot].path.xy;
                uint k = walks[slot].counts.x;
                if (cam && st.x == 0u && k + 2u == st.y && k < max_scatter() && flight.emitted != vec3(0.0)) {
                    mpaths[slot].value = vec4(walks[slot].beta.xyz * flight.emitted, 1.0);
                    mpaths[slot].path.z |= MMLT_PATH_FOUND;
                }
                if (!scattered && any(notEqual(weight, vec3(0.0)))) weight = free_flight_through(flight);
                walks[slot].beta.xyz *= weight;
            }
            uint prim = scattered ? MEDIUM_HIT : found ? hit.prim : NO_HIT;
            walks[slot].hit = vec4(uintBitsToFloat(prim), hit.bary, scattered ? hit.t : travelled + hit.t);
            if (media) walks[slot].d.w = uintBitsToFloat(flags);
        } else {
            if (!found) {
                mpaths[slot].path.z |= MMLT_PATH_FOUND;
                if (media) mpaths[slot].value.xyz *= tr;
            }
            flags &= ~BDPT_WALK_SHADOW;
            walks[slot].d.w = uintBitsToFloat(flags);
        }
    }
    mpaths[slot].used.w += rays;
}
