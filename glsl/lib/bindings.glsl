// Descriptor declarations shared by every kernel (set 0; numbers from abi.h).
#ifndef BINDINGS_GLSL
#define BINDINGS_GLSL
#include "abi.h"
#include "scene_data.glsl"

layout(std140, set = 0, binding = BINDING_SCENE) uniform SceneBlock { SceneParams scene; };
layout(std430, set = 0, binding = BINDING_SPHERES) readonly buffer SphereBuffer { GpuSphere spheres[]; };
layout(std430, set = 0, binding = BINDING_INSTANCES) readonly buffer InstanceBuffer { GpuInstance instances[]; };
layout(std430, set = 0, binding = BINDING_MATERIALS) readonly buffer MaterialBuffer { GpuMaterial materials[]; };
layout(std430, set = 0, binding = BINDING_EMITTERS) readonly buffer EmitterBuffer { GpuEmitter emitters[]; };
layout(std430, set = 0, binding = BINDING_EMITTER_CDF) readonly buffer EmitterCdfBuffer { uint emitter_cdf[]; };
layout(std430, set = 0, binding = BINDING_TEXTURES) readonly buffer TextureBuffer { GpuTexture textures[]; };
layout(std430, set = 0, binding = BINDING_FILM) buffer FilmBuffer { vec4 film[]; };
layout(std430, set = 0, binding = BINDING_STATS) buffer StatsBuffer { uint stats[]; };

#ifndef OWN_PUSH_CONSTANTS
layout(push_constant) uniform PassBlock { PassParams pass_params; };
#endif

const float INF = 1.0 / 0.0;
#endif
