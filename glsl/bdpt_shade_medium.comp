// BDPT's wavefront shade stage for scattering vertices in media (lib/bdpt_shade.glsl):
// the phase function's questions and draws (scenes with media only).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
#define SHADE_CLASS SHADE_CLASS_MEDIUM
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_shade.glsl"
