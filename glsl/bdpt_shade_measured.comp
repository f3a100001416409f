// BDPT's wavefront shade stage for the measured material class (lib/bdpt_shade.glsl).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
#define SHADE_CLASS MATERIAL_CLASS_MEASURED
layout(local_size_x = WORKGROUP_SIZE_X, local_size_y = WORKGROUP_SIZE_Y) in;
#include "bdpt_shade.glsl"
