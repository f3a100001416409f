// MMLT's wavefront shade stage for the hair material class (lib/mmlt_shade.glsl).
#version 460
#extension GL_GOOGLE_include_directive : require

#include "abi.h"
#define SHADE_CLASS MATERIAL_CLASS_HAIR
layout(local_size_x = MMLT_WORKGROUP_SIZE) in;
#include "mmlt_shade.glsl"
