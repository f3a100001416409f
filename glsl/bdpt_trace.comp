// BDPT's wavefront (lib/bdpt_wave.glsl): the visibility stage. The pixel's pending
// shadow ray (its contribution added to the splat film or to the pixel's sum when nothing
// blocks it) and the s, t >= 2 connections of its newest camera vertex z_k, whose BSDFs
// the shade stages have answered (each connection's contribution, MIS weight and shadow
// ray; its sum kept in the walk for bdpt_finish), then the walk's closest hit. The only
// kernel of BDPT's that holds the visibility backend.
//
// In media (FEATURE_MEDIA) the walk's ray is a free flight: a distance drawn in its medium
// (the walk's stream) ends it at a scattering vertex (MEDIUM_HIT) or it reaches the
// surface, through pass-through surfaces (boundaries of media, crossed here: no vertex),
// the throughput times each segment's weight (lib/media.glsl's sample_medium); a camera
// walk adds the media's emission on the way (s = 0: no other strategy finds it, weight
// 1). Shadow rays go on through pass-through surfaces too, their light times the
// transmittance of each medium they cross (the medium each starts in: ls_n.z for the
// queued ray, the newest camera vertex's toward the light vertex for a connection).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_wave.glsl"

void main() {
    uvec2 pixel;
    uint index, slot, base;
    if (!bdpt_pixel(false, pixel, index, slot, base) || pass_params.samples == 0u) return;
    uint flags = floatBitsToUint(walks[slot].d.w);
    uvec4 counts = walks[slot].counts;
    bool shadow = (flags & BDPT_WALK_SHADOW) != 0u;
    uint first, last;
    uint connections = 0u;
    if ((flags & BDPT_WALK_CONNECTIONS) != 0u && connection_range(counts.w, counts.z, first, last))
        connections = last + 1u - first;
    vec4 connected = walks[slot].connected;
    vec3 radiance = walks[slot].radiance.xyz;
    PathVertex z;
    if (connections > 0u) z = stored_vertex(base + vertex_stride() + counts.w - 1u);
    bool media = has_feature(FEATURE_MEDIA);
    bool camera = pass_params.side == BDPT_SIDE_CAMERA;
    uint walk_medium = flags >> BDPT_WALK_MEDIUM_SHIFT;
    bool emitted = false;
    // Every ray in one kept loop, through one trace_ray (each call site is a copy of the
    // backend): i = 0 the walk's own ray, for its closest hit, then (r = i - 1) r = 0 the
    // pending shadow ray and one per connection z_k - y_j. (The closest hits first, so
    // that every lane traces its long ray in the same iteration: a SIMD loop runs each
    // iteration until its slowest lane ends.)
    bool walk_ray = (flags & BDPT_WALK_RAY) != 0u;
    uint first_ray = walk_ray ? 0u : shadow ? 1u : 2u;
    [[dont_unroll]] for (uint i = first_ray; i <= connections + 1u; ++i) {
        bool closest = i == 0u;
        uint r = i - 1u;
        if (i == 1u && !shadow) continue;
        vec3 o, d, value;
        float tmax, weight;
        uint j = 0u;
        uint medium = MEDIUM_VACUUM;
        if (closest) {
            o = walks[slot].o.xyz;
            d = walks[slot].d.xyz;
            tmax = INF;
            medium = walk_medium;
        } else if (r == 0u) {
            vec4 ow = walks[slot].ls_wi;
            vec4 dw = walks[slot].ls_le;
            vec4 c = walks[slot].ls_p;
            o = ow.xyz;
            tmax = ow.w;
            d = dw.xyz;
            value = c.xyz;
            weight = c.w;
            medium = floatBitsToUint(walks[slot].ls_n.z);
        } else {
            j = first + r - 1u;
            PathVertex y = stored_vertex(base + j - 1u);
            vec3 dir;
            float d2;
            if (!connection_faces(z, y, dir, d2)) continue;
            uint az = answer_at(slot, j, 0u), ay = answer_at(slot, j, 1u);
            if (!connection_end(z, y, dir, d2, answer_f(az), answer(az, 3u), answer(az, 4u), answer_f(ay),
                                answer(ay, 3u), answer(ay, 4u), value, weight, o, d, tmax))
                continue;
            connected.w += 1.0;
            medium = vertex_medium_toward(z, dir, walk_medium);
        }
        // (A connection of no length has nothing to block it.) In media, segment by
        // segment through the pass-through surfaces (closest hits).
        Hit hit;
        bool found = false;
        bool scattered = false;
        vec3 tr = vec3(1.0);       // a shadow ray's transmittance
        float travelled = 0.0;     // the walk's ray: the distance to the last crossing
        uint seed = media && !closest ? medium_ray_seed(o, d) : 0u;  // grids' ratio tracking
        [[dont_unroll]] for (uint k = 0u; k <= MAX_PASS_THROUGH; ++k) {
            found = (closest || r == 0u || tmax > 0.0) && trace_ray(o, d, tmax, !closest && !media, hit);
            if (!media) break;
            if (medium != MEDIUM_VACUUM) {
                if (closest) {
                    Walk w = walk_load(walks[slot]);
                    sampler_resume(index, walks[slot]);
                    MediumEvent ev = sample_medium(medium, o, d, found ? hit.t : INF, sample_2d(camera ? STREAM_CAMERA : STREAM_LIGHT));
                    walks[slot].o.w = uintBitsToFloat(sampler_rng.counter);
                    uint max_vertices = scene.unbounded != 0u ? UNBOUNDED_DEPTH_CAP : max_scatter();
                    if (camera && w.vertices < max_vertices && ev.emitted != vec3(0.0)) {
                        add_camera(radiance, 0u, w.vertices + 2u, index, w.beta * ev.emitted, 1.0);
                        emitted = true;
                    }
                    walks[slot].beta.xyz = w.beta * ev.weight;
                    if (ev.scattered) {
                        scattered = true;
                        hit.t = travelled + ev.t;
                        break;
                    }
                } else {
                    tr *= medium_segment_transmittance(medium, o, d, found ? hit.t : tmax, seed);
                }
            }
            if (!found) break;
            vec3 ng;
            uint m = primitive_material(hit, o, d, ng);
            if (!material_passes_through(m)) break;
            if (k == MAX_PASS_THROUGH) {
                // (Too many boundaries: the path ends, the shadow ray counts as blocked.)
                if (closest) walks[slot].beta.xyz = vec3(0.0);
                break;
            }
            medium = medium_after(m, ng, d, medium);
            vec3 next = offset_ray_origin(o + hit.t * d, dot(d, ng) > 0.0 ? ng : -ng);
            float step = dot(next - o, d);
            travelled += step;
            tmax = isinf(tmax) ? tmax : max(tmax - step, 0.0);
            o = next;
            counts.y++;
        }
        if (closest) {
            counts.y++;
            // (The medium the ray ends in, past its crossings.)
            if (media) flags = (flags & ((1u << BDPT_WALK_MEDIUM_SHIFT) - 1u)) | (medium << BDPT_WALK_MEDIUM_SHIFT);
            uint prim = scattered ? MEDIUM_HIT : found ? hit.prim : NO_HIT;
            walks[slot].hit = vec4(uintBitsToFloat(prim), hit.bary, travelled + (scattered ? 0.0 : hit.t));
            if (scattered) walks[slot].hit.w = hit.t;
            walks[slot].counts.y = counts.y;
            continue;
        }
        if (found) continue;
        value *= tr;
        uvec2 st = r > 0u ? uvec2(j + 1u, counts.w + 1u) : floatBitsToUint(walks[slot].ls_n.xy);
        if (r == 0u && (flags & BDPT_WALK_SHADOW_SPLAT) != 0u) {
            uint to = floatBitsToUint(walks[slot].ls_le.w);
            add_splat(uvec2(to % scene.width, to / scene.width), st.x, value, weight);
            continue;
        }
        // (s = 1 joins the camera strategies' sum, the connections their own.)
        vec3 L = r > 0u ? connected.xyz : radiance;
        add_camera(L, st.x, st.y, index, value, weight);
        if (r > 0u) connected.xyz = L; else radiance = L;
    }
    if (shadow || emitted) walks[slot].radiance.xyz = radiance;
    if (connections > 0u) walks[slot].connected = connected;
    flags &= ~(BDPT_WALK_SHADOW | BDPT_WALK_SHADOW_SPLAT | BDPT_WALK_CONNECTIONS);
    walks[slot].d.w = uintBitsToFloat(flags);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
