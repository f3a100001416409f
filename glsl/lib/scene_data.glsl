// The scene's large arrays (triangles, their attributes, the BVH, texels, medium grids,
// the triangles' shading records)
// read by device address, so that none is bounded by a binding's range (lavapipe: 128
// MiB) or by one allocation (2 GiB): each kind (abi.h DATA_*) is cut into chunks of 2^shift
// records, each chunk a buffer of its own (src/gpu_scene.rs `SceneData`, which picks the
// shift from the device's limits). BINDING_SCENE_DATA holds a header per kind (x, y: the
// first chunk's address; z: shift; w: where the kind's chunk addresses start in
// data_chunks) and then every chunk's address. A record never straddles two chunks; a
// float array's reader asks per float (`texel`, `grid_value`). The triangles, the BVH's
// nodes and its references, the walks' hottest reads, are read from their binding where
// they fit one (shift DATA_IN_BINDING): an address per lane costs lavapipe twice the
// gathers of a binding's 32-bit offsets (docs/performance.md, issue 30). The others read
// the table every time: a branch that skipped it for one-chunk kinds made the
// every-feature scene's BDPT kernels compile 24 % longer cold.
#ifndef SCENE_DATA_GLSL
#define SCENE_DATA_GLSL
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#include "abi.h"

layout(std430, set = 0, binding = BINDING_SCENE_DATA) restrict readonly buffer SceneDataBuffer {
    uvec4 data_kinds[DATA_KINDS];
    uvec2 data_chunks[];
};

layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer TriangleChunk { GpuTriangle at[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer AttributeChunk { GpuTriangleUv at[]; };
layout(buffer_reference, std430, buffer_reference_align = 16) readonly buffer ShadingChunk { GpuTriangleShading at[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer FloatChunk { float at[]; };
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer UintChunk { uint at[]; };

// The address of the chunk that holds record i of kind k, and (j) its index there (a
// kind in one chunk has shift 31: every index is in chunk 0).
uvec2 data_chunk(uint k, uint i, out uint j) {
    uvec4 h = data_kinds[k];
    j = i & ((1u << h.z) - 1u);
    return data_chunks[h.w + (i >> h.z)];
}

// The kinds that may also be bound (DATA_IN_BINDING): their first chunk, where it fits.
layout(std430, set = 0, binding = BINDING_TRIANGLES) readonly buffer TriangleBuffer { GpuTriangle triangles[]; };
layout(std430, set = 0, binding = BINDING_BVH_PRIMS) readonly buffer BvhPrimBuffer { uint bvh_prims[]; };

GpuTriangle triangle_record(uint i) {
    if (data_kinds[DATA_TRIANGLES].z == DATA_IN_BINDING) return triangles[i];
    uint j;
    uvec2 a = data_chunk(DATA_TRIANGLES, i, j);
    return TriangleChunk(a).at[j];
}

// A triangle's attributes as one value: its GpuTriangleUv record i and the
// GpuTriangleShading record that names (zero where it names none: no shading normals,
// ALPHA_NONE).
struct TriangleAttributes {
    vec4 uv01;
    vec4 uv2;
    vec4 n0;
    vec4 n1;
    vec4 n2;
};

TriangleAttributes attribute_record(uint i) {
    uint j;
    uvec2 a = data_chunk(DATA_ATTRIBUTES, i, j);
    GpuTriangleUv uv = AttributeChunk(a).at[j];
    TriangleAttributes at = TriangleAttributes(uv.uv01, uv.uv2, vec4(0.0), vec4(0.0), vec4(0.0));
    uint s = floatBitsToUint(uv.uv2.w);
    if (s != NO_ATTRIBUTES) {
        uvec2 b = data_chunk(DATA_SHADING, s, j);
        GpuTriangleShading sh = ShadingChunk(b).at[j];
        at.n0 = sh.n0;
        at.n1 = sh.n1;
        at.n2 = sh.n2;
    }
    return at;
}

float texel(uint i) {
    uint j;
    uvec2 a = data_chunk(DATA_TEXELS, i, j);
    return FloatChunk(a).at[j];
}

float grid_value(uint i) {
    uint j;
    uvec2 a = data_chunk(DATA_GRIDS, i, j);
    return FloatChunk(a).at[j];
}

uint bvh_prim(uint i) {
    if (data_kinds[DATA_BVH_PRIMS].z == DATA_IN_BINDING) return bvh_prims[i];
    uint j;
    uvec2 a = data_chunk(DATA_BVH_PRIMS, i, j);
    return UintChunk(a).at[j];
}
#endif
