// MMLT's wavefront shade stage for scattering vertices in media (lib/mmlt_shade.glsl):
// the phase function's questions and draws (scenes with media only).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
#define SHADE_CLASS SHADE_CLASS_MEDIUM
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_shade.glsl"
