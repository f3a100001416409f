// MMLT's wavefront (lib/mmlt_wave.glsl): the strategy's end, once the shade stages have
// answered its questions to the BSDFs: the unweighted contribution, the MIS weight and
// the shadow ray that decides it (traced by mmlt_trace) of the t = 1 connection to the
// camera, the s = 1 light sample, or the s, t >= 2 connection.
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_wave.glsl"

void main() {
    uint slot, item;
    if (!mmlt_slot(slot, item)) return;
    uint pflags = path_flags(slot);
    uint kind = path_kind(pflags);
    if (kind != MMLT_KIND_CAMERA_CONNECTION && kind != MMLT_KIND_LIGHT_SAMPLE && kind != MMLT_KIND_CONNECTION) return;
    if ((pflags & (MMLT_PATH_ASK_Z | MMLT_PATH_ASK_Y)) != 0u) return;   // (a class without its stage: no contribution)
    GpuBdptWalk g = walks[slot];   // (the compiler loads only the members read)
    vec4 az = mpaths[slot].answer_z;
    vec4 ay = mpaths[slot].answer_y;
    vec4 rev = mpaths[slot].answer_rev;
    vec4 conn = mpaths[slot].conn;
    vec3 value, o, d;
    float weight, tmax;
    bool shadow;
    if (kind == MMLT_KIND_CAMERA_CONNECTION) {
        shadow = camera_connection_end(path_y(slot), conn.xyz, mpaths[slot].to_eye.xyz, conn.w, ay.xyz, rev.y, value,
                                       weight, o, d, tmax);
    } else if (kind == MMLT_KIND_LIGHT_SAMPLE) {
        LightSample ls = unpack_light_sample(g.ls_wi, g.ls_le, g.ls_p, g.ls_n);
        shadow = light_sample_end(walk_load(g), walk_vertex(slot, g), ls, g.ls_pdfs.xy, rev.z, az.xyz, az.w, rev.x, value,
                                  weight, o, d, tmax);
    } else {
        shadow = connection_end(walk_vertex(slot, g), path_y(slot), conn.xyz, conn.w, az.xyz, az.w, rev.x, ay.xyz, ay.w, rev.y,
                                value, weight, o, d, tmax);
    }
    if (!shadow) return;
    uint wflags = floatBitsToUint(g.d.w);
    // (The medium the shadow ray starts in: the walk's at the vertex it leaves, y for
    // t = 1 (no camera subpath), else z.)
    uint medium = MEDIUM_VACUUM;
    if (has_feature(FEATURE_MEDIA))
        medium = vertex_medium_toward(kind == MMLT_KIND_CAMERA_CONNECTION ? path_y(slot) : walk_vertex(slot, g), d,
                                      wflags >> BDPT_WALK_MEDIUM_SHIFT);
    queue_path_shadow(slot, wflags, o, d, tmax, medium);
    walks[slot].d.w = uintBitsToFloat(wflags);
    mpaths[slot].value = vec4(value, weight);
}
