// The host/GLSL interface: constants and buffer structs shared by every kernel.
// build.rs turns each `#define NAME <integer>` line into a Rust `pub const NAME: u32`;
// src/gpu/abi.rs mirrors the structs and a test checks their offsets in the SPIR-V.
// Buffer structs are made only of 16-byte vectors.
#ifndef ABI_H
#define ABI_H

#define WORKGROUP_SIZE_X 8
#define WORKGROUP_SIZE_Y 8

// Descriptor bindings (set 0).
#define BINDING_SCENE 0
#define BINDING_TRIANGLES 1
#define BINDING_SPHERES 2
#define BINDING_MATERIALS 3
#define BINDING_EMITTERS 4
#define BINDING_EMITTER_CDF 5
#define BINDING_FILM 6
#define BINDING_STATS 7
#define BINDING_TLAS 8
#define BINDING_BVH_NODES 8
#define BINDING_BVH_PRIMS 9
#define BINDING_SPLAT 10
#define BINDING_PATH_VERTICES 11
#define BINDING_STRATEGIES 12
#define BINDING_CHAIN_SAMPLES 13
#define BINDING_CHAINS 14
#define BINDING_BOOTSTRAP 15

// Emitter kinds (GpuEmitter.info.x).
#define EMITTER_TRIANGLE 0
#define EMITTER_SPHERE 1
#define EMITTER_POINT 2
#define EMITTER_DIRECTIONAL 3

// Integrators (SceneParams.options.w).
#define INTEGRATOR_PATHTRACER 0
#define INTEGRATOR_DIRECT 1
#define INTEGRATOR_ANALYTIC 2
#define INTEGRATOR_BDPT 3

// Next-event estimation (SceneParams.options.x).
#define NEE_OFF 0
#define NEE_ON 1
#define NEE_MIS 2

// Slots of the stats buffer (uint counters).
#define STAT_NONFINITE 0
// Invocations whose slice of a per-pixel buffer would pass the buffer's end (a bug of
// the host's tiling: the host fails the render when it is not 0).
#define STAT_OUT_OF_RANGE 1
// MMLT chain starts whose first path's target differs from its bootstrap sample's (a
// bug: the host fails the render when it is not 0).
#define STAT_START_MISMATCH 2
// Rays traced by MMLT's bootstrap (chains count theirs in GpuChain.start.y).
#define STAT_MMLT_RAYS 3
#define STAT_COUNT 4

// MMLT dispatch modes (MmltParams.run.x).
#define MMLT_MODE_BOOTSTRAP 0
#define MMLT_MODE_START 1
#define MMLT_MODE_CHAINS 2
// The start and chain modes on a synthetic path (tests of the sampler against its CPU
// mirror).
#define MMLT_MODE_PROBE_START 3
#define MMLT_MODE_PROBE_CHAINS 4
// Threads per MMLT workgroup (one bootstrap sample or one chain each).
#define MMLT_WORKGROUP_SIZE 64
// Primary-sample streams of an MMLT chain.
#define MMLT_STREAM_COUNT 3

// BDPT with maxdepth -1: paths of up to this many scattering vertices get every
// strategy (light-subpath vertices are stored per pixel, so the bound sets the buffer
// size); longer ones continue on the camera side only, with Russian roulette.
#define BDPT_UNBOUNDED_DEPTH_CAP 32

// Marks "no emitter" in per-primitive emitter indices.
#define NO_EMITTER 4294967295

// Hard cap on path length when maxdepth is -1 (unbounded, ended by Russian roulette).
#define UNBOUNDED_DEPTH_CAP 1024

#ifdef GL_core_profile
// A world-space triangle. v0.w: material index, v1.w: emitter index (NO_EMITTER if
// none), both as uint bits.
struct GpuTriangle {
    vec4 v0;
    vec4 v1;
    vec4 v2;
};

// The unit sphere under an affine transform: rows of object-to-world and
// world-to-object 3x4 matrices. info.x: material, info.y: emitter index.
struct GpuSphere {
    vec4 o2w0;
    vec4 o2w1;
    vec4 o2w2;
    vec4 w2o0;
    vec4 w2o1;
    vec4 w2o2;
    uvec4 info;
};

// params: x shininess, y roughness (GGX alpha), z brdf kind (0 phong, 1 ggx),
// w 1 when emission is two-sided.
struct GpuMaterial {
    vec4 diffuse;
    vec4 specular;
    vec4 emission;
    vec4 params;
};

// An emitter. Triangles: p0,p1,p2 the vertices. Spheres: info.y the sphere. Point:
// p0 the position. Directional: p0 the unit direction toward the light.
// radiance.w: the probability of picking this emitter. info: x kind, y primitive,
// z 1 when two-sided, w unused. p0.w: area (triangles, spheres).
struct GpuEmitter {
    vec4 p0;
    vec4 p1;
    vec4 p2;
    vec4 radiance;
    uvec4 info;
};

// Everything a kernel needs to know about the scene and the render settings.
struct SceneParams {
    vec4 cam_eye;        // w: tan(fovy / 2)
    vec4 cam_right;      // w: aspect (width / height)
    vec4 cam_up;
    vec4 cam_forward;
    vec4 bounds;         // xyz: centre of the scene's bounding sphere, w: its radius
    uvec4 dims;          // x width, y height, z triangles, w spheres
    uvec4 counts;        // x emitters, y max scattering vertices, z 1 if maxdepth is -1, w total spp
    uvec4 options;       // x nee mode, y russian roulette, z importance sampling, w integrator
    uvec4 direct;        // x light samples, y stratify, z seed, w unused
    uvec4 bdpt;          // x BDPT strategies to record: first << 16 | count (0: none), y add only paths of at least this many scattering vertices (MMLT's tail)
};

// A vertex of a BDPT light subpath (stored per pixel, read back by the camera subpath).
// p.w: material (uint bits); n: unit normal on the side the path arrived from, w: dVCM;
// wi: unit direction toward the previous vertex, w: dVC; beta: throughput (w unused).
struct GpuPathVertex {
    vec4 p;
    vec4 n;
    vec4 wi;
    vec4 beta;
};

// Per-dispatch constants.
struct PassParams {
    uvec4 pass;          // x first sample index of the pass, y samples in the pass, z first row, w end row of the band
};

// MMLT's per-dispatch constants (push constants of mmlt.comp).
struct MmltParams {
    uvec4 run;           // x mode (MMLT_MODE_*), y first item (bootstrap sample or chain), z items, w mutations per chain
    uvec4 sizes;         // x chains, y bootstrap samples per depth, z depths (D + 1), w 1: record per-depth images
    uvec4 streams;       // x camera numbers, y light numbers, z connection numbers, w numbers per chain (their sum)
    vec4 mutation;       // x sigma of a small step, y large-step probability
};

// An MMLT chain. Its primary numbers are in the chain-sample buffer, dimension-major:
// number i of chain c at i * chains + c, as uvec4(value (32-bit fixed point in [0,1)),
// last-modified step, backup value, backup step).
struct GpuChain {
    vec4 current;        // xyz contribution C of the current path, w its target f = luminance(C)
    uvec4 state;         // x pixel of the current path, y depth, z step (accepted mutations), w step of the last accepted large step
    uvec4 counts;        // x large steps proposed, y accepted, z small steps proposed, w accepted
    uvec4 start;         // x the bootstrap sample it started from (index within its depth), y rays traced
};
#endif

#endif
