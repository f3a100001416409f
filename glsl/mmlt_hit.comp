// MMLT's wavefront (lib/mmlt_wave.glsl): the surface interaction. The vertex at the
// walk's hit. A light vertex before the subpath's last waits for its class's shade stage
// to scatter; at the last, y, the camera subpath starts (or, t = 1, the camera's side of
// the connection to y: the lens point, the pixel). A camera vertex before the last
// scatters; at the last, z (or where the camera subpath escaped), the strategy: s = 0 the
// emission found, whole; s = 1 a light sample (its BSDF half is the shade stage's);
// s, t >= 2 the connection's geometry: mmlt_emit's, which holds every emitter's code of
// MMLT (kept apart from the surfaces' and textures' code here: lavapipe's compile time
// grows faster than a kernel).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint wflags = floatBitsToUint(walks[slot].d.w);
    if ((wflags & BDPT_WALK_RAY) == 0u) return;
    wflags &= ~BDPT_WALK_RAY;
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    Walk w = walk_load(g);
    uvec4 path = mpaths[slot].path;
    uint s = path.x;
    uint t = path.y;
    uint pflags = path.z;
    bool cam = (pflags & MMLT_PATH_CAMERA) != 0u;
    uint prim = floatBitsToUint(g.hit.x);
    Hit hit;
    hit.t = g.hit.w;
    hit.prim = prim;
    hit.bary = g.hit.yz;
    PathVertex v;
    bool ok = false;
    if (has_feature(FEATURE_MEDIA) && prim == MEDIUM_HIT) {
        // A scattering vertex in the walk's medium (mmlt_trace's free flight).
        if (cam) camera_walk_medium_vertex(w, hit.t, v); else light_walk_medium_vertex(w, hit.t, v);
        ok = true;
    } else if (prim != NO_HIT) {
        Surface sf = surface_at(hit, w.o, w.d);
        ok = cam ? camera_walk_vertex(w, hit.t, sf, v) : light_walk_vertex(w, hit.t, sf, v);
    } else {
        w.escaped = cam;
    }
    // (The sampler only where this stage draws numbers: t = 1's lens point; each word of
    // state is a memory access per slot on lavapipe.)
    bool draws = !cam && ok && w.vertices == s - 1u && t == 1u;
    if (draws) pss_resume(slot, item);
    uint kind = MMLT_KIND_NONE;
    bool vertex = false;   // v waits for the shade stage
    bool started = false;  // the camera subpath starts
    if (!cam) {
        if (ok && w.vertices < s - 1u) {
            wflags |= BDPT_WALK_EXTEND;
            vertex = true;
        } else if (ok) {
            store_path_y(slot, v);
            if (t == 1u) {
                vec3 eye, to_eye;
                float dist;
                uvec2 cpx;
                if (camera_connection_faces(v, eye, cpx, to_eye, dist)) {
                    kind = MMLT_KIND_CAMERA_CONNECTION;
                    pflags |= MMLT_PATH_ASK_Y;
                    mpaths[slot].conn = vec4(eye, dist);
                    mpaths[slot].to_eye = vec4(to_eye, 0.0);
                    path.w = cpx.y * scene.width + cpx.x;
                }
            } else {
                camera_walk_from(mpaths[slot].camera_o.xyz, mpaths[slot].camera_d.xyz, w);
                started = true;
                pflags |= MMLT_PATH_CAMERA;
                wflags |= BDPT_WALK_RAY;
            }
        }
    } else {
        // The camera subpath's vertex z_k (k = w.vertices when found).
        uint k = ok ? w.vertices : w.vertices + 1u;
        bool last = k == t - 1u;
        bool escaped = !ok && w.escaped && last;
        if (ok && !last) {
            wflags |= BDPT_WALK_EXTEND;
            vertex = true;
        } else if (ok || escaped) {
            // The strategy at the last camera vertex: the emit stage's.
            wflags |= BDPT_WALK_EMIT;
            vertex = ok;
        }
    }
    if (vertex) store_vertex(slot, v);
    if (started) {
        store_walk(slot, w, wflags);
    } else {
        store_walk_vertex(slot, w, wflags);
    }
    mpaths[slot].path.zw = uvec2(pflags | (kind << 8u), path.w);
    if (draws) pss_save(slot);
    if (nonfinite > 0u) atomicAdd(stats[STAT_NONFINITE], nonfinite);
}
