// What a kernel can do, set per scene (abi.h's SPEC_FEATURES): a kernel specialized
// for a scene without a feature has that feature's code removed before the driver compiles
// it. The guarded code is most of a kernel (the interfaces' BSDFs, texture lookups, the
// environment map's sampling, coated diffuse's walk engine); lavapipe's compile time grows
// faster than the code, and much faster with the validation layer's instrumentation.
// The host (Engine::prepare) sets the bit of everything the scene uses.
#ifndef FEATURES_GLSL
#define FEATURES_GLSL
#include "abi.h"

layout(constant_id = SPEC_FEATURES) const uint spec_features = 0u;

bool has_feature(uint feature) { return (spec_features & feature) != 0u; }

// The MORE_FEATURE_* bits (abi.h SPEC_MORE_FEATURES), as spec_features's.
layout(constant_id = SPEC_MORE_FEATURES) const uint spec_more_features = 0u;

bool has_more_feature(uint feature) { return (spec_more_features & feature) != 0u; }
#endif
