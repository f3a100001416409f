// The gbuffer film's albedo stage for the interface material class (lib/gbuffer_albedo.glsl).
#version 460
#extension GL_GOOGLE_include_directive : require
#include "abi.h"
#define SHADE_CLASS MATERIAL_CLASS_INTERFACE
#include "gbuffer_albedo.glsl"
