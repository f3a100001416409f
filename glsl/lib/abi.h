// The host/GLSL interface: constants and buffer structs shared by every kernel.
// build.rs turns each `#define NAME <integer>` line into a Rust `pub const NAME: u32`;
// src/gpu/abi.rs mirrors the structs and a test checks their offsets in the SPIR-V.
// Buffer structs are made only of 16-byte vectors.
#ifndef ABI_H
#define ABI_H

#define WORKGROUP_SIZE_X 8
#define WORKGROUP_SIZE_Y 8

// Descriptor bindings (set 0), one number per resource. Each kernel's layout is read
// from its SPIR-V (src/gpu/reflect.rs): a kernel declares only what it uses, and the
// host binds each resource by these numbers.
// The scene:
#define BINDING_SCENE 0
// The first chunk of the triangles, the BVH's nodes and its primitive references where it
// fits one binding (DATA_IN_BINDING; lib/scene_data.glsl): a binding's gathers are half
// those of an address's on lavapipe. (23, 24 and 35 held texels, attributes and grids:
// they are read by address only.)
#define BINDING_TRIANGLES 1
#define BINDING_SPHERES 2
#define BINDING_MATERIALS 3
#define BINDING_EMITTERS 4
#define BINDING_EMITTER_CDF 5
#define BINDING_TLAS 6
#define BINDING_BVH_NODES 7
#define BINDING_BVH_PRIMS 8
// Integrator outputs and state:
#define BINDING_FILM 9
#define BINDING_STATS 10
#define BINDING_SPLAT 11
#define BINDING_PATH_VERTICES 12
#define BINDING_STRATEGIES 13
#define BINDING_DEPTH_FILMS 14
#define BINDING_CHAIN_SAMPLES 15
#define BINDING_CHAINS 16
#define BINDING_BOOTSTRAP 17
// Probes (tests of the GLSL against its CPU mirrors):
#define BINDING_PROBE_RAYS 18
#define BINDING_PROBE_HITS 19
#define BINDING_BSDF_PROBE_INPUTS 20
#define BINDING_BSDF_PROBE_OUTPUTS 21
// Textures and surface attributes (the scene, continued):
#define BINDING_TEXTURES 22
// Wavefront state (lib/wavefront.glsl): the paths, the queues' counts and dispatch
// arguments, and the queues' entries.
#define BINDING_WF_PATHS 25
#define BINDING_WF_QUEUES 26
#define BINDING_WF_ITEMS 27
// BDPT's wavefront: per pixel sample, the BSDFs' answers for the connections of its
// newest camera vertex z_k to the light vertices y_j (BDPT_ANSWER_FLOATS per j), written
// by the shade stages of the two vertices' classes, read by the trace stage.
#define BINDING_BDPT_ANSWERS 28
// BDPT's wavefront (glsl/lib/bdpt_wave.glsl): per pixel of a band, its subpath walk.
#define BINDING_BDPT_WALKS 29
// MMLT's wavefront (glsl/lib/mmlt_wave.glsl): per slot (a chain or a bootstrap sample),
// its proposal's path beyond the walk.
#define BINDING_MMLT_PATHS 30
// BDPT's wavefront at maxdepth -1: per camera bounce, the walks that go on (the host
// reads it to know when to stop).
#define BINDING_BDPT_LIVE 31
// BDPT's path vertices' material texture values (two vec4 per vertex of
// BINDING_PATH_VERTICES, PathVertex.tex0 and tex1), in scenes with
// FEATURE_MATERIAL_TEXTURES (a placeholder elsewhere).
#define BINDING_PATH_VERTEX_TEXTURES 32
// The material texture values of each walk's vertex waiting for its shade stage (two vec4
// per GpuBdptWalk slot, beside it rather than in it: a larger walk slowed BDPT on lavapipe
// by 5 %), in scenes with FEATURE_MATERIAL_TEXTURES (a placeholder elsewhere).
#define BINDING_WALK_TEXTURES 33
// Participating media (the scene, continued): GpuMedium records (lib/media.glsl).
#define BINDING_MEDIA 34
// The gbuffer film's stages (lib/gbuffer.glsl): per pixel of a band, the surface its
// camera sample found (GpuGbufferSurface), for the albedo stage of its material class.
#define BINDING_GBUFFER_SURFACES 36
// The instances of objects (GpuInstance), with FEATURE_INSTANCES.
#define BINDING_INSTANCES 37
// The scene's large arrays, by device address (lib/scene_data.glsl): per kind (DATA_*)
// a header (the first chunk's address, the chunk's size as a power of two of records,
// where the kind's chunk addresses start), then every chunk's address.
#define BINDING_SCENE_DATA 38

// The kinds of scene data read by address, each in chunks (lib/scene_data.glsl):
// GpuTriangle records (the world's, then each object's); GpuTriangleUv records;
// the BVH's nodes (BvhNode or CwbvhNode, as the backend's walk reads them); the BVH
// leaves' primitive references (uint); texels (floats: images, tables, lens systems);
// grid media's floats (density, Le-scale and majorant grids; FEATURE_GRID_MEDIA);
// GpuTriangleShading records.
#define DATA_TRIANGLES 0
#define DATA_ATTRIBUTES 1
#define DATA_BVH_NODES 2
#define DATA_BVH_PRIMS 3
#define DATA_TEXELS 4
#define DATA_GRIDS 5
#define DATA_SHADING 6
#define DATA_KINDS 7
// A kind's shift (its header's z) when its one chunk is also bound at its binding
// (triangles, BVH nodes, BVH primitive references): the kernels read the binding.
#define DATA_IN_BINDING 32

// Emitter kinds (GpuEmitter.info.x).
#define EMITTER_TRIANGLE 0
#define EMITTER_SPHERE 1
#define EMITTER_POINT 2
#define EMITTER_DIRECTIONAL 3
#define EMITTER_SPOT 4
#define EMITTER_INFINITE 5
#define EMITTER_GONIOMETRIC 6
#define EMITTER_PROJECTION 7
// GpuEmitter.info.w of pbrt-v4's invisible area light (a triangle emitter whose alpha is
// 0: lights.glsl's emitter_is_hidden); 0 for every other emitter.
#define EMITTER_HIDDEN 1

// Integrators (SceneParams.integrator): each has its own code.
#define INTEGRATOR_PATHTRACER 0
#define INTEGRATOR_DIRECT 1
#define INTEGRATOR_ANALYTIC 2
#define INTEGRATOR_BDPT 3
#define INTEGRATOR_MMLT 4

// Next-event estimation (SceneParams.nee).
#define NEE_OFF 0
#define NEE_ON 1
#define NEE_MIS 2

// BSDF kinds (GpuMaterial.info.x); src/abi.rs mirrors them as `BsdfKind`.
#define BSDF_PHONG 0
#define BSDF_GGX 1
#define BSDF_DIELECTRIC 2
#define BSDF_THIN_DIELECTRIC 3
#define BSDF_CONDUCTOR 4
#define BSDF_COATED_DIFFUSE 5
// pbrt-v4's diffusetransmission: Lambertian reflection (kd) on wo's side, Lambertian
// transmission (ks) through to the other.
#define BSDF_DIFFUSE_TRANSMISSION 6
// pbrt-v4's coatedconductor: a dielectric coating (eta.x, roughness.yz) over a conductor
// (specular.xyz its eta, diffuse.xyz its k, both relative to the coating; base.xy its
// alphas), the layer between them as coated diffuse's (k.xyz; coated kinds: eta.yzw the
// layer's scattering albedo, k.w its Henyey-Greenstein g).
#define BSDF_COATED_CONDUCTOR 7
// pbrt-v4's measured material (RGL's tabulated BRDFs, lib/measured.glsl): base.x (uint
// bits) the texel index of its tables (MeasuredBsdf::pack); the class of its own.
#define BSDF_MEASURED 8
// pbrt-v4's hair (lib/hair.glsl): k.xyz sigma_a, eta.x its index, roughness.y beta_m,
// roughness.z beta_n, roughness.x the scales' tilt in degrees; the class of its own.
#define BSDF_HAIR 9

// Specialization constants (set per scene when a pipeline is created): code for what
// the scene lacks is removed before the driver compiles the kernel (lib/features.glsl).
// SPEC_FEATURES: a uint, the FEATURE_* bits of what the scene has.
#define SPEC_FEATURES 0
// Coated materials, the coated class (their walk engine, layered.glsl).
#define FEATURE_COATED 1
// Dielectric, thin dielectric and conductor materials.
#define FEATURE_INTERFACES 2
// Materials with a diffuse or roughness texture.
#define FEATURE_MATERIAL_TEXTURES 4
// An environment light with an image (a constant one needs no code of its own).
#define FEATURE_ENVIRONMENT_MAP 8
// Mix materials.
#define FEATURE_MIX 16
// maxdepth -1: BDPT's camera walks go on beyond the strategies' cap, with Russian
// roulette and the weights of the two strategies left there (lib/bdpt.glsl).
#define FEATURE_UNBOUNDED 32
// Diffuse transmission materials (a case of the interface class's kernels).
#define FEATURE_DIFFUSE_TRANSMISSION 64
// Textures mapped other than by uv (spherical, cylindrical, planar).
#define FEATURE_TEXTURE_PROJECTIONS 128
// Bump and normal maps (surface_at's shading normal, lib/shading_map.glsl).
#define FEATURE_SHADING_MAPS 256
// Alpha cut-outs on triangles (every visibility backend's alpha test, geometry.glsl).
#define FEATURE_ALPHA 512
// Coated conductors (a case of the coated class: the walk engine's conductor base).
#define FEATURE_COATED_CONDUCTOR 1024
// Textures made of textures (pbrt-v4's scale and mix of textures: texture.glsl's
// programs).
#define FEATURE_TEXTURE_GRAPHS 2048
// Coated materials whose layer scatters (pbrt-v4's albedo > 0: the walk's free flights
// and phase function, layered.glsl).
#define FEATURE_LAYER_MEDIUM 4096
// Procedural textures: noise (fbm, wrinkled, windy, marble) and dots.
#define FEATURE_PROCEDURAL_TEXTURES 8192
// Measured materials, the measured class (lib/measured.glsl's tables).
#define FEATURE_MEASURED 16384
// Hair, the hair class (lib/hair.glsl; surfaces give it their dp/du and offset).
#define FEATURE_HAIR 32768
// The bilerp texture.
#define FEATURE_BILERP_TEXTURES 65536
// The texture features of the alpha textures alone (the alpha test is inlined in every
// traversal; texture.glsl's alpha_texture_features): projections, graphs, procedural
// (noise, dots) and bilerp textures.
#define FEATURE_ALPHA_TEXTURE_PROJECTIONS 131072
#define FEATURE_ALPHA_TEXTURE_GRAPHS 262144
#define FEATURE_ALPHA_PROCEDURAL_TEXTURES 524288
#define FEATURE_ALPHA_BILERP_TEXTURES 1048576
// Goniometric and projection lights (lights.glsl: point lights whose intensity an image
// sets per direction).
#define FEATURE_PROFILE_LIGHTS 2097152
// Participating media (lib/media.glsl): paths in media, surfaces that bound them, shadow
// rays through them, in all three integrators.
#define FEATURE_MEDIA 4194304
// Grid media (pbrt-v4's uniformgrid, rgbgrid; its cloud too): delta and ratio tracking
// through majorant grids.
#define FEATURE_GRID_MEDIA 8388608
// pbrt-v4's procedural cloud medium (with FEATURE_GRID_MEDIA): its noise-made density.
#define FEATURE_CLOUD_MEDIA 16777216
// pbrt-v4's rgbgrid medium (with FEATURE_GRID_MEDIA): its per-channel grids.
#define FEATURE_RGB_GRID_MEDIA 33554432
// A uniformgrid's temperature (with FEATURE_GRID_MEDIA): blackbody emission.
#define FEATURE_TEMPERATURE_MEDIA 67108864
// pbrt-v4's nanovdb medium (with FEATURE_GRID_MEDIA): sparse bricks of NanoVDB grids.
#define FEATURE_NANOVDB_MEDIA 134217728
// Several infinite lights (lights.glsl's loops over them; without it there is at most one,
// and they are no loops: lavapipe compiles a kernel with them 40 % longer).
#define FEATURE_ENVIRONMENTS 268435456
// pbrt-v4's realistic camera (camera.glsl's lens system).
#define FEATURE_REALISTIC_CAMERA 536870912
// Instanced objects (BINDING_INSTANCES): the BVH walks enter an object's own tree under
// its instance's transform, and triangle ids past the world's are instances' triangles.
#define FEATURE_INSTANCES 1073741824
// Image textures with MIP levels (pbrt-v4's imagemap; texture.glsl image_value): the
// surfaces find the footprint's extent in (u, v) and the lookups pick their level by it.
#define FEATURE_MIP_TEXTURES 2147483648u
// Every feature (kernels that must serve any scene: the BSDF probe).
#define FEATURE_ALL 4294967295u
// SPEC_MORE_FEATURES: a uint, the MORE_FEATURE_* bits (FEATURE_*'s 32 are all taken).
#define SPEC_MORE_FEATURES 1
// Image textures read by pbrt-v4's elliptically weighted average (texture.glsl
// image_ewa_level): a loop over the texels under the footprint's ellipse.
#define MORE_FEATURE_EWA_TEXTURES 1

// Texture slots of a material (texture.glsl's material_texture).
#define MATERIAL_TEXTURE_SLOTS 4u

// Material flags (GpuMaterial.info.y).
#define MATERIAL_TWO_SIDED_EMISSION 1
// pbrt's mix, not a surface: specular.xy (uint bits) the two materials, specular.z the
// second's probability, info.z its float texture; resolved by surface_at.
#define MATERIAL_MIX 2
// The roughness texture (info.w) holds pbrt's roughness r, not alpha: alpha = sqrt(r) at
// lookup (pbrt-v4's `remaproughness`, RoughnessToAlpha).
#define MATERIAL_REMAP_ROUGHNESS 4
// pbrt-v4's BumpMap: roughness.w (uint bits) is the float texture of the displacement.
#define MATERIAL_BUMP_MAP 8
// pbrt-v4's NormalMap: roughness.w (uint bits) is the texture of the tangent-space normal
// (RGB in [0, 1], linear, repeating).
#define MATERIAL_NORMAL_MAP 16
// pbrt-v4's MediumInterface where it is a transition: emission.w (uint bits) holds the
// media inside (low 16 bits) and outside (high 16 bits) as medium codes (MEDIUM_*
// below); a ray leaving the surface along w is in the outside one where w is on the
// geometric normal's side. Other surfaces leave a ray in the medium it was in.
#define MATERIAL_MEDIUM_INTERFACE 32
// pbrt-v4's interface material ("", "interface", "none"): no surface, only the boundary
// of media; rays pass through it unchanged (not a scattering vertex).
#define MATERIAL_PASS_THROUGH 64
// The step in u and in v of the bump map's finite differences (pbrt-v4's du when a
// point has no differentials).
#define BUMP_DELTA 0.0005
// The deepest nesting of mixes.
#define MAX_MATERIAL_MIX_DEPTH 8

// No texture (GpuMaterial.info.zw; an infinite light's GpuEmitter.info.y).
#define NO_TEXTURE 4294967295

// Texture kinds (GpuTexture.info.x).
#define TEXTURE_IMAGE 0
#define TEXTURE_CHECKERBOARD 1
// A texture made of textures: info.y the first record of its program, info.z the
// program's length (records evaluated in order, each into a register; the last is the
// value). A program's records are leaves (image, checkerboard) and these nodes, whose
// operands flags.x (a), flags.y (b) and flags.z (amount) are earlier registers, or
// NO_TEXTURE for the constants scale.xyz, other.xyz and mapping.x:
#define TEXTURE_GRAPH 2
// pbrt-v4's scale: a times the first channel of b.
#define TEXTURE_SCALE 3
// pbrt-v4's mix: (1 - amount) a + amount b, amount's first channel.
#define TEXTURE_MIX 4
// pbrt-v4's directionmix: w a + (1 - w) b with w = |ng . dir|, ng the surface's geometric
// normal and dir (mapping.xyz) a unit world direction.
#define TEXTURE_DIRECTION_MIX 5
// pbrt-v4's noise textures (noise.glsl; CPU mirror src/noise.rs) at the point in texture
// space (proj0..2 its rows): info.y the noise table's first float in the texel buffer
// (the permutation twice, then the marble colours), info.z the kind (NOISE_*), info.w
// the octaves; mapping.x omega, .y marble's scale, .z its variation.
#define TEXTURE_NOISE 6
#define NOISE_FBM 0
#define NOISE_WRINKLED 1
#define NOISE_WINDY 2
#define NOISE_MARBLE 3
// pbrt-v4's dots: scale inside the polka dot of (s, t)'s cell, other outside; info.y the
// noise table.
#define TEXTURE_DOTS 7
// pbrt-v4's bilerp: info.y the first of 12 floats in the texel buffer, v00 v01 v10 v11.
#define TEXTURE_BILERP 8
// The most records of a texture's program.
#define MAX_TEXTURE_PROGRAM 8
// How an image texture is read (GpuTexture.other.x; pbrt-v4's imagemap `filter`).
#define TEXTURE_FILTER_BILINEAR 0
#define TEXTURE_FILTER_POINT 1
#define TEXTURE_FILTER_TRILINEAR 2
// pbrt-v4's ewa: a Gaussian over the footprint's ellipse in the two MIP levels about its
// minor axis's, the ellipse at most other.z times longer than wide (its maxanisotropy).
#define TEXTURE_FILTER_EWA 3
// How an image texture wraps (GpuTexture.flags.x).
#define TEXTURE_WRAP_REPEAT 0
// u repeats, v clamps (latitude-longitude environment maps).
#define TEXTURE_WRAP_REPEAT_U 1
#define TEXTURE_WRAP_CLAMP 2
// Texels outside the image are black (pbrt-v4's `black`).
#define TEXTURE_WRAP_BLACK 3
// How a texture finds its (s, t) (GpuTexture.flags.z; pbrt-v4's TextureMapping2D): the
// surface's uv; or the point in texture space (proj rows applied to the world point) by
// its spherical angles, its cylinder angle and height, or a plane's two axes.
#define TEXTURE_MAP_UV 0
#define TEXTURE_MAP_SPHERICAL 1
#define TEXTURE_MAP_CYLINDRICAL 2
#define TEXTURE_MAP_PLANAR 3
// pbrt-v4's TextureMapping3D (the 3D checkerboard): the texture-space point itself (proj0..2).
#define TEXTURE_MAP_SOLID 4

// How an environment map covers the sphere (an infinite light's GpuEmitter.info.z); src/texture.rs
// (EnvMapping) says which pixel is which direction.
#define ENV_MAPPING_LATLONG 0
#define ENV_MAPPING_EQUAL_AREA 1

// A realistic camera's exit pupil bounds: per this many intervals of the film point's
// distance from the axis (src/scene/lens.rs).
#define LENS_PUPIL_INTERVALS 64

// A triangle without texture coordinates or shading normals (GpuTriangle.v2.w).
#define NO_ATTRIBUTES 4294967295

// The bit of GpuPathVertex.p.w that marks a vertex seen from its material's outside.
#define PATH_VERTEX_FRONT 2147483648
// The bit of GpuPathVertex.p.w that marks a scattering vertex in a medium (FEATURE_MEDIA):
// the low 16 bits are then its medium code, not a material (lib/bdpt.glsl).
#define PATH_VERTEX_MEDIUM 1073741824
// GpuBdptWalk.hit.x of a walk whose free flight ended in its medium (a scattering vertex
// at hit.w), rather than at a surface (a primitive) or nowhere (NO_HIT).
#define MEDIUM_HIT 4294967294
// The shade class of medium vertices (BDPT's bdpt_shade_medium: the phase function), past
// the material classes.
#define SHADE_CLASS_MEDIUM 5

// How directions are sampled (SceneParams.sample_mode: the scene's importancesampling);
// src/abi.rs mirrors them as `SampleMode`.
#define SAMPLE_HEMISPHERE 0
#define SAMPLE_COSINE 1
#define SAMPLE_BRDF 2

// What a path carries (an argument of the BSDF functions; src/abi.rs: `Transport`):
// radiance on camera subpaths, importance on light subpaths (refraction and shading
// normals make the BSDF non-symmetric between the two).
#define TRANSPORT_RADIANCE 0
#define TRANSPORT_IMPORTANCE 1

// Lobes of a sampled direction (BsdfSample.flags).
#define BSDF_LOBE_REFLECTION 1
#define BSDF_LOBE_TRANSMISSION 2
#define BSDF_LOBE_DELTA 4

// Threads per workgroup of the probes.
#define PROBE_WORKGROUP_SIZE 64

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
// Splat-film channels whose fixed-point sum passed 2^32 (glsl/lib/splat.glsl): the host
// fails the render when it is not 0.
#define STAT_SPLAT_OVERFLOW 4
#define STAT_COUNT 5
// The splat film's fixed point (glsl/lib/splat.glsl): fractional bits of each channel's
// 64-bit sum, and 32-bit words per pixel (low and high word of r, g, b; two unused).
#define SPLAT_FRACTION_BITS 32
#define SPLAT_WORDS_PER_PIXEL 8
// The diagnostic films (BDPT's strategy images, MMLT's per-depth images) in the same
// fixed point, unpadded: low and high word of r, g, b.
#define FIXED_FILM_WORDS_PER_PIXEL 6

// The wavefront path tracer (pt_*.comp, lib/wavefront.glsl). Threads per workgroup of
// its stages (one path, or one pixel, each).
#define WF_WORKGROUP_SIZE 64
// Its queues of path indices: paths with a ray to trace, paths with a shadow ray, and
// one queue per material class (the shading stage of each class consumes its own).
#define WF_QUEUE_RAYS 0
#define WF_QUEUE_SHADOW 1
#define WF_QUEUE_CLASS_BASIC 2
#define WF_QUEUE_CLASS_INTERFACE 3
#define WF_QUEUE_CLASS_COATED 4
#define WF_QUEUE_CLASS_MEASURED 5
#define WF_QUEUE_CLASS_HAIR 6
// Media (FEATURE_MEDIA): scattering vertices in a medium and pass-through surfaces to
// cross, for pt_medium.
#define WF_QUEUE_MEDIUM 7
#define WF_QUEUE_COUNT 8
// Material classes, each shaded by its own kernel: the course BRDFs (Phong, GGX); the
// interfaces (dielectric, thin dielectric, conductor) and diffuse transmission; coated
// diffuse and coated conductor; measured; hair.
#define MATERIAL_CLASS_BASIC 0
#define MATERIAL_CLASS_INTERFACE 1
#define MATERIAL_CLASS_COATED 2
#define MATERIAL_CLASS_MEASURED 3
#define MATERIAL_CLASS_HAIR 4
#define MATERIAL_CLASS_COUNT 5
// GpuPtPath.hit.x of a ray that left the scene.
#define NO_HIT 4294967295

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

// A medium code: 0 vacuum, else the index of the medium's GpuMedium record + 1.
#define MEDIUM_VACUUM 0
// Medium kinds (GpuMedium.info.x).
#define MEDIUM_HOMOGENEOUS 0
#define MEDIUM_UNIFORMGRID 1
#define MEDIUM_RGBGRID 2
#define MEDIUM_CLOUD 3
#define MEDIUM_NANOVDB 4
// An rgbgrid's grid that is not given (GpuMedium offsets).
#define MEDIUM_NO_GRID 4294967295
// A grid medium's majorant grid: this many cells per axis over its bounds (pbrt-v4's).
#define MEDIUM_MAJORANT_RES 16
// The most pass-through surfaces (MATERIAL_PASS_THROUGH) a path or a shadow ray crosses:
// a path ends there, a shadow ray is blocked.
#define MAX_PASS_THROUGH 64

#ifdef GL_core_profile
// An instance of an object (FEATURE_INSTANCES): its transform both ways (rows) and
// info: x the id of its first triangle (triangle ids of the instances follow the world's,
// instance after instance, each in its object's order), y that id less the object's first
// triangle record (a triangle id of the instance less y is the record; the object tree's
// leaves hold records), z the root node of the object's tree (storage-buffer BVHs), w 1
// where the transform swaps handedness (the geometric normal is flipped back).
struct GpuInstance {
    vec4 w2o0;
    vec4 w2o1;
    vec4 w2o2;
    vec4 o2w0;
    vec4 o2w1;
    vec4 o2w2;
    uvec4 info;
};

// A world-space triangle (an object's: in object space). v0.w: material index, v1.w: emitter index (NO_EMITTER if
// none), v2.w: its attributes (NO_ATTRIBUTES if none), all as uint bits.
struct GpuTriangle {
    vec4 v0;
    vec4 v1;
    vec4 v2;
};

// A triangle's attributes: its texture coordinates at its corners (a GpuTriangleUv
// record, DATA_ATTRIBUTES) and, where it has shading normals or alpha, a
// GpuTriangleShading record (DATA_SHADING) that the first names. Without attributes a
// triangle has pbrt's (0,0), (1,0), (1,1) and its geometric normal; without shading
// normals, its geometric normal. A triangle's alpha (pbrt-v4's `alpha`,
// GpuTriangleShading.n0.w as a float): none (opaque), a constant (n1.w) or a float
// texture (n1.w, uint bits).
#define ALPHA_NONE 0
#define ALPHA_CONSTANT 1
#define ALPHA_TEXTURE 2

struct GpuTriangleUv {
    vec4 uv01;          // (u0, v0, u1, v1)
    vec4 uv2;           // xy: (u2, v2), z: 1 when n0..n2 hold shading normals, w: the
                        // shading record (uint bits), NO_ATTRIBUTES for none
};

struct GpuTriangleShading {
    vec4 n0;            // w: the alpha's kind (ALPHA_*)
    vec4 n1;            // w: the alpha constant, or its texture (uint bits)
    vec4 n2;
};

// A texture. Images: texels are RGB float triples in the texel buffer from float
// info.y on, row-major from the top row; t = 0 is the bottom row unless flags.y is 1
// (environment maps: v = 0 is the top row). With flags.w > 0 (an 8-bit image) a texel
// is one word instead, R | G << 8 | B << 16 as a float's bits, each byte an index into
// the 256-float table at float flags.w - 1 (src/texture.rs ByteDecoding::table).
// Values are scale * the lookup other.x says (TEXTURE_FILTER_*): bilinear, the texel whose
// centre is nearest (pbrt-v4's point filter), or trilinear. other.y > 1 (pbrt-v4's
// imagemap, FEATURE_MIP_TEXTURES): the image is a pyramid of other.y levels one after
// another from info.y, each max(1, w >> l) x max(1, h >> l) texels (src/mipmap.rs), and
// the footprint picks the level the filter reads.
// Checkerboards: scale where floor(s) + floor(t) is even, other where odd.
// (s, t) = (mapping.x u + mapping.z, mapping.y v + mapping.w).
struct GpuTexture {
    uvec4 info;         // x kind (TEXTURE_*), y first float, z width, w height
    uvec4 flags;        // x wrap (TEXTURE_WRAP_*), y 1: rows top-down in v, z mapping (TEXTURE_MAP_*), w byte table + 1 (0: float texels)
    vec4 scale;
    vec4 other;
    vec4 mapping;       // uv mapping: s = x u + z, t = y v + w
    vec4 proj0;         // the other mappings: rows of texture space from world (planar: the s and t rows)
    vec4 proj1;
    vec4 proj2;
};

// The unit sphere under an affine transform: rows of object-to-world and
// world-to-object 3x4 matrices. info.x: material, info.y: emitter index, info.z: 1 when
// its normal faces inward (pbrt's ReverseOrientation: it emits into its inside).
struct GpuSphere {
    vec4 o2w0;
    vec4 o2w1;
    vec4 o2w2;
    vec4 w2o0;
    vec4 w2o1;
    vec4 w2o2;
    uvec4 info;
};

// A material: one record for every BSDF kind, with room for the parameters of the
// kinds to come (a dielectric's index of refraction, a conductor's complex Fresnel per
// channel, anisotropic roughness, textures). Fields a kind does not use are zero.
struct GpuMaterial {
    vec4 diffuse;        // xyz diffuse reflectance kd (diffuse transmission: its reflectance)
    vec4 specular;       // xyz specular colour ks (Phong), Fresnel F0 (GGX), transmittance (diffuse transmission)
    vec4 emission;       // xyz emitted radiance
    vec4 eta;            // dielectric, thin dielectric: x index of refraction (inside over outside); conductor: xyz per channel
    vec4 k;              // xyz conductor absorption
    vec4 roughness;      // x Phong exponent, y GGX alpha (u), z GGX alpha (v), w (uint bits) bump or normal map texture (MATERIAL_BUMP_MAP, MATERIAL_NORMAL_MAP)
    uvec4 info;          // x kind (BSDF_*), y flags (MATERIAL_*), z diffuse texture (coated conductor: the conductor's reflectance), w roughness texture (diffuse transmission: transmittance texture; coated conductor: the coating's; NO_TEXTURE: none)
    vec4 base;           // coated conductor: xy the conductor's alphas, z (uint bits) its roughness texture; coated (both kinds): w (uint bits) the layer's thickness texture (NO_TEXTURE: none); other kinds: zero
};

// An emitter. Triangles: p0,p1,p2 the vertices. Spheres: info.y the sphere. Point:
// p0 the position. Directional: p0 the unit direction toward the light. Spot: p0 the
// position, p1.xyz the unit axis, p1.w the cosine of the cone angle, p2.x the cosine of
// the angle where the falloff starts (pbrt-v4's cosFalloffEnd and cosFalloffStart).
// Goniometric and projection: p0.xyz the position; the 3x3 map from world directions to
// the light's image space, its rows p1.xyz, p2.xyz and (p0.w, p1.w, p2.w); info.y the
// first texel of the image (then its sampling distribution), info.z its width | height << 16.
// Infinite (an environment light; lights.glsl): radiance.xyz the radiance (times the map's
// value); p0.xyz, p1.xyz, p2.xyz the world directions of the map frame's axes; info.y the
// map (a GpuTexture; NO_TEXTURE: constant), info.z its ENV_MAPPING_*; as uint bits, p0.w
// and p1.w the first floats of the map's marginal CDF (height + 1) and of its rows' CDFs
// (height rows of width + 1) in DATA_TEXELS, p2.w the first of its portal's nine floats
// there (pbrt-v4's portal: corner p0, edges p1 - p0 and p3 - p0, the light coming through
// along (p3 - p0) x (p1 - p0); NO_TEXTURE: no portal).
// radiance.w: the probability of picking this emitter. info: x kind, y primitive,
// z 1 when two-sided, w EMITTER_HIDDEN for an invisible light (else 0). p0.w: area (triangles, spheres).
// A participating medium: sigma_a and sigma_s per channel (pbrt's `scale` applied; a
// grid's per unit density), w of sigma_a the Henyey-Greenstein g; emission the radiance
// Le it emits (pbrt-v4's Le times Lescale: the emission per unit length is sigma_a Le; a
// grid's Le is also times its Le-scale grid). Grids (MEDIUM_UNIFORMGRID, FEATURE_GRID_MEDIA):
// info.y the first float of the density grid in DATA_GRIDS, info.z that of the
// Le-scale grid, info.w that of the majorant grid (MEDIUM_MAJORANT_RES^3 cells, each the
// most the extinction reaches in it, per unit length, in its largest channel); unit_x,
// unit_y and unit_z the rows of the affine map from world space to the grid's unit cube
// (pbrt's bounds p0, p1 in the medium's space); density_res and le_res the two grids'
// sample counts nx, ny, nz (pbrt's SampledGrid: samples at cell centres, trilinear, zero
// outside); density_res.w the first float of the temperature grid (density_res.xyz samples;
// MEDIUM_NO_GRID where there is none, FEATURE_TEMPERATURE_MEDIA), sigma_s.w and emission.w
// its offset and scale (pbrt-v4's temperatureoffset, temperaturescale), le_res.w the
// blackbody table's first float in DATA_TEXELS (src/media.rs's blackbody_table; the
// medium's emission.xyz is then 1). RGB grids (MEDIUM_RGBGRID): sigma_a.xyz and sigma_s.xyz pbrt's `scale`,
// emission.xyz its `Lescale` (0 without an Le grid); three floats per sample (RGB) in
// DATA_GRIDS; info.y the first of the sigma_a grid, density_res.w that of the
// sigma_s grid (MEDIUM_NO_GRID where not given: 1), info.z that of the Le grid, info.w the
// majorants; density_res.xyz and le_res.xyz the grids' sample counts. Clouds
// (MEDIUM_CLOUD, FEATURE_CLOUD_MEDIA; pbrt-v4's procedural cloud, sigma_a and sigma_s per
// unit density as a uniformgrid's): float bits of density_res.xyz the box's corner p0 and
// le_res.xyz its extent p1 - p0 in the medium's space (the unit cube mapped back), of
// density_res.w the `density` parameter, le_res.w `wispiness`, info.z `frequency`; info.y
// the noise table's first float in DATA_TEXELS, info.w the majorants (each the largest
// channel's extinction: the density is at most 1). NanoVDB grids (MEDIUM_NANOVDB,
// FEATURE_NANOVDB_MEDIA; sigma_a and sigma_s per unit density): info.y the first float of
// the density grid's header in DATA_GRIDS, info.z that of the temperature grid's
// (MEDIUM_NO_GRID where there is none; its offset and scale in sigma_s.w and emission.w,
// the blackbody table at le_res.w as a uniformgrid's), info.w the majorants. A header:
// 12 floats, the rows of the affine map from the unit cube to the grid's index space; the
// bricks' origin (3 ints), their counts per axis (3), the first word of their table and
// the first float of their values (src/nanovdb.rs's Bricks: per brick of 8^3 voxels a
// table entry, 0 for none, else the brick's number + 1; 512 values per brick, x fastest).
struct GpuMedium {
    vec4 sigma_a;
    vec4 sigma_s;
    vec4 emission;
    uvec4 info;         // x kind (MEDIUM_*)
    vec4 unit_x;
    vec4 unit_y;
    vec4 unit_z;
    uvec4 density_res;
    uvec4 le_res;
};

struct GpuEmitter {
    vec4 p0;
    vec4 p1;
    vec4 p2;
    vec4 radiance;
    uvec4 info;
};

// Everything a kernel needs to know about the scene and the render settings.
// Scalars come in fours, so every row is 16 bytes in std140 and in Rust alike.
struct SceneParams {
    vec4 cam_eye;        // the eye (the lens centre); w unused
    vec4 cam_right;      // unit vectors: the image's right, up and the view direction; w unused
    vec4 cam_up;
    vec4 cam_forward;
    vec4 bounds;         // xyz: centre of the scene's bounding sphere, w: its radius
    uint width;
    uint height;
    uint triangle_count;
    uint sphere_count;
    uint emitter_count;
    uint max_depth;      // scattering vertices of the longest path (BDPT, MMLT: their cap for -1)
    uint unbounded;      // 1 if maxdepth is -1
    uint spp;
    uint integrator;     // INTEGRATOR_*
    uint seed;
    uint sample_mode;    // SAMPLE_*
    uint nee;            // NEE_*
    uint russian_roulette;
    uint light_samples;  // direct: light samples per hit
    uint light_stratify; // direct: stratify them
    uint min_depth;      // bdpt: add only paths of at least this many scattering vertices (MMLT's tail)
    uint strategy_first; // bdpt: record the images of strategies first ..
    uint strategy_count; //       .. first + count (0: none)
    uint environment;    // the emitter of the first infinite light, or NO_EMITTER ..
    uint environment_count; // .. and how many there are (the last emitters, in a row)
    uint lens;           // a realistic camera's lens system: its first float in the texel buffer (src/scene/lens.rs pack), or NO_TEXTURE
    uint gbuffer_world;  // the gbuffer film's P, N, Ns in the world (1) or in camera space (0)
    uint reserved6;
    uint camera_medium; // the medium code (MEDIUM_VACUUM, index + 1) the camera is in
    vec4 cam_window;     // the film on the plane at distance 1 ahead: x0, x1 along cam_right, y0, y1 along cam_up
    float lens_radius;   // a thin lens's radius (0: a pinhole) ..
    float focal_distance;// .. and the distance of its plane of focus
    uint flat_triangle_count; // triangles of the world itself: ids below it; instances' follow
    uint instance_count;      // GpuInstance records (FEATURE_INSTANCES)
};

// A vertex of a BDPT light subpath (stored per pixel, read back by the camera subpath).
// p.w: material (uint bits), with PATH_VERTEX_FRONT set when n is on the material's
// outside (the geometric normal's side); n: unit normal on the side the path arrived
// from, w: dVCM; wi: unit direction toward the previous vertex, w: dVC; beta: throughput,
// w: the texture coordinate v; ns: the unit shading normal on n's side, w: u.
struct GpuPathVertex {
    vec4 p;
    vec4 n;
    vec4 wi;
    vec4 beta;
    vec4 ns;
};

// A pass's push constants: samples first_sample .. first_sample + samples of the rows
// row_begin .. row_end (a band of the image).
struct PassParams {
    uint first_sample;
    uint samples;
    uint row_begin;
    uint row_end;
};

// The push constants of a wavefront stage: the wavefront is samples first_sample ..
// first_sample + samples of the rows row_begin .. row_end, one path each (slots paths,
// path i is sample i / P of pixel i % P of the band, P its pixels); depth: the bounce
// (vertices so far); reset: the queues wf_queues.comp empties (bit q: queue q).
struct WavefrontParams {
    uint first_sample;
    uint samples;
    uint row_begin;
    uint row_end;
    uint slots;
    uint depth;
    uint reset;
    uint reserved;
};

// The push constants of BDPT's stages (glsl/lib/bdpt_pass.glsl): samples first_sample ..
// first_sample + samples of the rows row_begin .. row_end (a wavefront dispatch has a z
// layer per sample; the three stages take one), then the bounce of a wavefront stage
// (the vertex being found) and the subpath it walks (BDPT_SIDE_*).
struct BdptParams {
    uint first_sample;
    uint samples;
    uint row_begin;
    uint row_end;
    uint bounce;
    uint side;
    uint reserved0;
    uint reserved1;
};
#define BDPT_SIDE_LIGHT 0
#define BDPT_SIDE_CAMERA 1

// A pixel's subpath walk in BDPT's wavefront (glsl/lib/bdpt_wave.glsl): its light
// subpath, then its camera subpath, through the start, trace, hit and shade stages.
struct GpuBdptWalk {
    vec4 o;          // xyz the next ray's origin, w the sampler's draw counter (uint bits)
    vec4 d;          // xyz its direction, w flags (BDPT_WALK_*)
    vec4 beta;       // xyz throughput, w dVCM
    vec4 prev_p;     // xyz the vertex the ray left, w dVC
    uvec4 counts;    // x the walk's vertices, y rays traced, z light vertices stored, w camera vertices stored
    vec4 radiance;   // xyz the camera strategies' sum (s = 0, 1), w the last bounce's BSDF pdf
    vec4 hit;        // x primitive (NO_HIT: none; uint bits), yz barycentrics, w t
    vec4 v_p;        // the vertex for the shade stage, packed as GpuPathVertex
    vec4 v_n;
    vec4 v_wi;
    vec4 v_beta;
    vec4 v_ns;
    vec4 ls_wi;      // s = 1's light sample: direction, distance; then a shadow ray's origin, extent
    vec4 ls_le;      // radiance, pdf; then the shadow ray's direction, w the pixel it adds to (uint bits)
    vec4 ls_p;       // point, w 1 when delta; then the unweighted contribution, w the MIS weight
    vec4 ls_n;       // normal, w unused; then x s, y t (uint bits)
    vec4 ls_pdfs;    // x, y the light's emission densities toward the vertex (area, direction)
    vec4 connected;  // xyz the s, t >= 2 strategies' sum, w their shadow rays
};
// GpuBdptWalk.d.w flags.
#define BDPT_WALK_RAY 1            // the walk goes on: its ray is to be traced
#define BDPT_WALK_VERTEX 2         // a vertex waits for its material's shade stage
#define BDPT_WALK_SHADOW 4         // a shadow ray waits (trace stage), with its contribution
#define BDPT_WALK_SHADOW_SPLAT 8   // ... added to the splat film (t = 1), not the pixel's
#define BDPT_WALK_LIGHT_SAMPLE 16  // the vertex has an s = 1 light sample (ls_*)
#define BDPT_WALK_CONNECT 32       // the light vertex connects to the camera (t = 1)
#define BDPT_WALK_EXTEND 64        // the vertex scatters
#define BDPT_WALK_INFINITE 128
#define BDPT_WALK_PREV_DELTA 256
#define BDPT_WALK_ESCAPED 512
#define BDPT_WALK_CONNECTIONS 1024 // z_k's s, t >= 2 connections wait: answers (shade), then rays (trace)
#define BDPT_WALK_EMIT 2048        // a camera walk's hit (or escape) waits for the emit stage
// The flags' high 16 bits: the medium code of the walk's next ray (FEATURE_MEDIA).
#define BDPT_WALK_MEDIUM_SHIFT 16
// Floats per connection in the answers buffer: z's BSDF toward y (rgb, pdf there, pdf
// back), then y's toward z (the same).
#define BDPT_ANSWER_FLOATS 10

// What the gbuffer film's hit stage found for a pixel's camera sample, for the albedo
// stage of the surface's material class (lib/gbuffer.glsl).
struct GpuGbufferSurface {
    vec4 wo;    // xyz the direction back along the camera ray, w the material (uint bits;
                // GBUFFER_NO_SURFACE: the sample found none)
    vec4 ns;    // xyz the shading normal on wo's side, w 1 when wo is on the material's front
    vec4 tex0;  // the material's texture values there (Surface.tex0, tex1)
    vec4 tex1;
    uvec4 rng;  // the sample's random numbers after the camera ray (Rng key, counter)
};
#define GBUFFER_NO_SURFACE 4294967295

// One path of the wavefront path tracer (lib/pt_path.glsl packs and unpacks it).
struct GpuPtPath {
    vec4 o;          // xyz the ray's origin, w the rng's counter (uint bits)
    vec4 d;          // xyz its direction, w flags (PT_PATH_*)
    vec4 beta;       // xyz throughput, w the pdf of the BSDF sample that led here
    vec4 radiance;   // xyz radiance so far, w rays traced (uint bits)
    vec4 prev_p;     // xyz the previous vertex, w the hit's t
    vec4 hit;        // x primitive (NO_HIT: none), yz barycentrics, w material
    vec4 p;          // xyz the hit point, w its u
    vec4 n;          // xyz geometric normal on the side of -d, w its v
    vec4 ns;         // xyz shading normal on n's side, w 1 when n is the material's front
    vec4 ls_wi;      // light sample: direction, distance; then the shadow ray's origin, extent
    vec4 ls_le;      // light sample: radiance, pdf; then the shadow ray's direction
    vec4 ls_p;       // light sample: point, w 1 when delta; then the estimate f L cos w / pdf
    vec4 ls_n;       // light sample: normal; then the throughput that multiplies the estimate
    vec4 tex0;       // the hit's material texture values (Surface.tex0, tex1; FEATURE_MATERIAL_TEXTURES)
    vec4 tex1;
};
// GpuPtPath.d.w flags.
#define PT_PATH_PREV_DELTA 1
#define PT_PATH_LIGHT_SAMPLE 2
#define PT_PATH_LIGHT_SAMPLE_OK 4
// The path's hit is a pass-through surface (MATERIAL_PASS_THROUGH) for pt_medium to cross.
#define PT_PATH_PASS_THROUGH 8
// ... and above them (FEATURE_MEDIA): the medium code of the path's ray in bits 8-23,
// the pass-through surfaces it has crossed in bits 24-31 (the path's scattering vertices
// are WavefrontParams.depth less those).
#define PT_PATH_MEDIUM_SHIFT 8
#define PT_PATH_CROSSINGS_SHIFT 24

// MMLT's push constants (mmlt.comp).
struct MmltParams {
    uint mode;                // MMLT_MODE_*
    uint first_item;          // the first bootstrap sample or chain of the dispatch
    uint items;               // bootstrap samples or chains in the dispatch
    uint mutations;           // proposals per chain (MMLT_MODE_CHAINS)
    uint chains;
    uint bootstrap_per_depth;
    uint depths;              // D + 1
    uint record_depths;       // 1: add to the per-depth films
    uint camera_numbers;      // primary numbers per stream ..
    uint light_numbers;
    uint connect_numbers;
    uint numbers;             // .. and their sum (numbers per chain)
    float sigma;              // a small step's standard deviation
    float large_step;         // probability of a large step
    float reserved0;
    float reserved1;
};

// An MMLT chain. Its primary numbers are in the chain-sample buffer, dimension-major:
// number i of chain c at i * chains + c, as uvec4(value (32-bit fixed point in [0,1)),
// last-modified step, backup value, backup step).
struct GpuChain {
    vec4 current;        // xyz contribution C of the current path, w its target f = luminance(C)
    uvec4 state;         // x pixel of the current path, y depth, z step (accepted mutations), w step of the last accepted large step
    uvec4 counts;        // x large steps proposed, y accepted, z small steps proposed, w accepted
    uvec4 start;         // x the bootstrap sample it started from (index within its depth), y rays traced,
                         // z the current path's splat weight not yet splatted (float bits; the host adds it)
};

// One proposal's path in MMLT's wavefront (glsl/lib/mmlt_wave.glsl), beside its walk
// (GpuBdptWalk, the same slot): the strategy, the sampler's place, the light subpath's
// last vertex, the strategy's questions to the BSDFs and their answers, the result.
struct GpuMmltPath {
    uvec4 path;      // x s, y t, z flags (MMLT_PATH_*) | kind (MMLT_KIND_*) << 8, w the pixel the path lands on
    uvec4 key;       // the proposal: x its number, y its step, z the chain's last large step, w 1 for a large step
    uvec4 used;      // xyz numbers used per stream, w rays traced
    vec4 camera_o;   // s >= 2, t >= 2: the camera subpath's first ray (drawn by mmlt_start), its origin
    vec4 camera_d;   // ... and direction
    vec4 value;      // xyz the unweighted contribution, w its MIS weight
    vec4 y_p;        // y, the light subpath's last vertex, packed as GpuPathVertex
    vec4 y_n;
    vec4 y_wi;
    vec4 y_beta;
    vec4 y_ns;
    vec4 conn;       // t = 1: the lens point, w the distance to it; s, t >= 2: direction z -> y, w squared distance
    vec4 to_eye;     // t = 1: the direction from y to the lens point
    vec4 answer_z;   // the BSDF at z (the camera subpath's last vertex): xyz f, w forward pdf
    vec4 answer_y;   // the BSDF at y (importance): xyz f, w forward pdf
    vec4 answer_rev; // x z's reverse pdf, y y's, z the s = 1 light sample's shading cosine
    vec4 y_tex0;     // y's material texture values (PathVertex.tex0, tex1; the same)
    vec4 y_tex1;
};
// GpuMmltPath.path.z flags.
#define MMLT_PATH_CAMERA 1   // the walk is the camera subpath (else the light subpath)
#define MMLT_PATH_ASK_Z 2    // a question to the BSDF at z waits for its class's shade stage
#define MMLT_PATH_ASK_Y 4    // ... to the BSDF at y
#define MMLT_PATH_FOUND 8    // the contribution (value) is the path's: nothing blocks it
// The strategy of a path, by what it asks (GpuMmltPath.path.z >> 8).
#define MMLT_KIND_NONE 0
#define MMLT_KIND_LIGHT_POINT 1        // s = 1, t = 1
#define MMLT_KIND_CAMERA_CONNECTION 2  // s >= 2, t = 1
#define MMLT_KIND_EMISSION 3           // s = 0 (an emitter or the environment)
#define MMLT_KIND_LIGHT_SAMPLE 4       // s = 1, t >= 2
#define MMLT_KIND_CONNECTION 5         // s >= 2, t >= 2
// The BSDF probe's input: material `info.x` (an index into the material buffer),
// sampling mode info.y, transport info.z, info.w 1 when n is on the material's inside;
// unit n, wo, wi; u the sample's three uniforms.
struct BsdfProbeInput {
    uvec4 info;
    vec4 n;
    vec4 wo;
    vec4 wi;
    vec4 u;
    vec4 tex1;          // the surface's Surface.tex1 (hair: its dp/du and offset h)
};

// The BSDF probe's output: eval.xyz f(wo, wi), eval.w pdf(wo, wi); sample.xyz the
// sampled direction, sample.w its pdf; sample_f.xyz its f, sample_f.w 1 when the sample
// succeeded; info.x its lobe flags. The combined queries' densities, as float bits:
// info.y bsdf_sample_rev's pdf(wi -> wo) of its sample, info.z and info.w
// bsdf_eval_pdfs's pdf(wo -> wi) and pdf(wi -> wo).
struct BsdfProbeOutput {
    vec4 eval;
    vec4 sample_dir;
    vec4 sample_f;
    uvec4 info;
};
#endif

#endif
