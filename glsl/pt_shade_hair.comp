// The wavefront path tracer's shading stage for the hair material class (lib/pt_shade.glsl).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "abi.h"
#define SHADE_CLASS MATERIAL_CLASS_HAIR
#include "pt_shade.glsl"
