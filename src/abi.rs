//! The host/GLSL interface, Rust side of glsl/lib/abi.h: the constants (generated from
//! the header by build.rs), `#[repr(C)]` mirrors of the buffer structs and the enums
//! whose values the header defines. tests/abi.rs checks the offsets against the compiled
//! kernels. This module imports nothing from the rest of the crate.
#![allow(dead_code)]

include!(concat!(env!("OUT_DIR"), "/abi_constants.rs"));

use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTriangle {
    pub v0: [f32; 4],
    pub v1: [f32; 4],
    pub v2: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTriangleUv {
    pub uv01: [f32; 4],
    pub uv2: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTriangleShading {
    pub n0: [f32; 4],
    pub n1: [f32; 4],
    pub n2: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTexture {
    pub info: [u32; 4],
    pub flags: [u32; 4],
    pub scale: [f32; 4],
    pub other: [f32; 4],
    pub mapping: [f32; 4],
    pub proj0: [f32; 4],
    pub proj1: [f32; 4],
    pub proj2: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSphere {
    pub o2w0: [f32; 4],
    pub o2w1: [f32; 4],
    pub o2w2: [f32; 4],
    pub w2o0: [f32; 4],
    pub w2o1: [f32; 4],
    pub w2o2: [f32; 4],
    pub info: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuInstance {
    pub w2o0: [f32; 4],
    pub w2o1: [f32; 4],
    pub w2o2: [f32; 4],
    pub o2w0: [f32; 4],
    pub o2w1: [f32; 4],
    pub o2w2: [f32; 4],
    pub info: [u32; 4],
}

/// A material record (abi.h explains each field); fields a kind does not use are zero.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuMaterial {
    pub diffuse: [f32; 4],
    pub specular: [f32; 4],
    pub emission: [f32; 4],
    pub eta: [f32; 4],
    pub k: [f32; 4],
    pub roughness: [f32; 4],
    pub info: [u32; 4],
    pub base: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuEmitter {
    pub p0: [f32; 4],
    pub p1: [f32; 4],
    pub p2: [f32; 4],
    pub radiance: [f32; 4],
    pub info: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuMedium {
    pub sigma_a: [f32; 4],
    pub sigma_s: [f32; 4],
    pub emission: [f32; 4],
    pub info: [u32; 4],
    pub unit_x: [f32; 4],
    pub unit_y: [f32; 4],
    pub unit_z: [f32; 4],
    pub density_res: [u32; 4],
    pub le_res: [u32; 4],
}

/// The uniform scene parameters (abi.h explains each field).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SceneParams {
    pub cam_eye: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub cam_forward: [f32; 4],
    pub bounds: [f32; 4],
    pub width: u32,
    pub height: u32,
    pub triangle_count: u32,
    pub sphere_count: u32,
    pub emitter_count: u32,
    pub max_depth: u32,
    pub unbounded: u32,
    pub spp: u32,
    pub integrator: u32,
    pub seed: u32,
    pub sample_mode: u32,
    pub nee: u32,
    pub russian_roulette: u32,
    pub light_samples: u32,
    pub light_stratify: u32,
    pub min_depth: u32,
    pub strategy_first: u32,
    pub strategy_count: u32,
    pub environment: u32,
    pub environment_count: u32,
    pub lens: u32,
    pub gbuffer_world: u32,
    pub reserved6: u32,
    pub camera_medium: u32,
    pub cam_window: [f32; 4],
    pub lens_radius: f32,
    pub focal_distance: f32,
    pub flat_triangle_count: u32,
    pub instance_count: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuPathVertex {
    pub p: [f32; 4],
    pub n: [f32; 4],
    pub wi: [f32; 4],
    pub beta: [f32; 4],
    pub ns: [f32; 4],
}

/// What the gbuffer film's hit stage keeps of a pixel's surface for its albedo stage
/// (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuGbufferSurface {
    pub wo: [f32; 4],
    pub ns: [f32; 4],
    pub tex0: [f32; 4],
    pub tex1: [f32; 4],
    pub rng: [u32; 4],
}

/// One path of the wavefront path tracer (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuPtPath {
    pub o: [f32; 4],
    pub d: [f32; 4],
    pub beta: [f32; 4],
    pub radiance: [f32; 4],
    pub prev_p: [f32; 4],
    pub hit: [f32; 4],
    pub p: [f32; 4],
    pub n: [f32; 4],
    pub ns: [f32; 4],
    pub ls_wi: [f32; 4],
    pub ls_le: [f32; 4],
    pub ls_p: [f32; 4],
    pub ls_n: [f32; 4],
    pub tex0: [f32; 4],
    pub tex1: [f32; 4],
}

/// A wavefront stage's push constants (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct WavefrontParams {
    pub first_sample: u32,
    pub samples: u32,
    pub row_begin: u32,
    pub row_end: u32,
    pub slots: u32,
    pub depth: u32,
    pub reset: u32,
    pub reserved: u32,
}

/// A pass's push constants (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PassParams {
    pub first_sample: u32,
    pub samples: u32,
    pub row_begin: u32,
    pub row_end: u32,
}

/// The push constants of BDPT's stages (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct BdptParams {
    pub first_sample: u32,
    pub samples: u32,
    pub row_begin: u32,
    pub row_end: u32,
    pub bounce: u32,
    pub side: u32,
    pub reserved0: u32,
    pub reserved1: u32,
}

/// A pixel's subpath walk in BDPT's wavefront (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuBdptWalk {
    pub o: [f32; 4],
    pub d: [f32; 4],
    pub beta: [f32; 4],
    pub prev_p: [f32; 4],
    pub counts: [u32; 4],
    pub radiance: [f32; 4],
    pub hit: [f32; 4],
    pub v_p: [f32; 4],
    pub v_n: [f32; 4],
    pub v_wi: [f32; 4],
    pub v_beta: [f32; 4],
    pub v_ns: [f32; 4],
    pub ls_wi: [f32; 4],
    pub ls_le: [f32; 4],
    pub ls_p: [f32; 4],
    pub ls_n: [f32; 4],
    pub ls_pdfs: [f32; 4],
    pub connected: [f32; 4],
}

/// MMLT's push constants (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct MmltParams {
    pub mode: u32,
    pub first_item: u32,
    pub items: u32,
    pub mutations: u32,
    pub chains: u32,
    pub bootstrap_per_depth: u32,
    pub depths: u32,
    pub record_depths: u32,
    pub camera_numbers: u32,
    pub light_numbers: u32,
    pub connect_numbers: u32,
    pub numbers: u32,
    pub sigma: f32,
    pub large_step: f32,
    pub reserved0: f32,
    pub reserved1: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuChain {
    pub current: [f32; 4],
    pub state: [u32; 4],
    pub counts: [u32; 4],
    pub start: [u32; 4],
}

/// One proposal's path in MMLT's wavefront (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuMmltPath {
    pub path: [u32; 4],
    pub key: [u32; 4],
    pub used: [u32; 4],
    pub camera_o: [f32; 4],
    pub camera_d: [f32; 4],
    pub value: [f32; 4],
    pub y_p: [f32; 4],
    pub y_n: [f32; 4],
    pub y_wi: [f32; 4],
    pub y_beta: [f32; 4],
    pub y_ns: [f32; 4],
    pub conn: [f32; 4],
    pub to_eye: [f32; 4],
    pub answer_z: [f32; 4],
    pub answer_y: [f32; 4],
    pub answer_rev: [f32; 4],
    pub y_tex0: [f32; 4],
    pub y_tex1: [f32; 4],
}

/// The BSDF probe's input (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct BsdfProbeInput {
    pub info: [u32; 4],
    pub n: [f32; 4],
    pub wo: [f32; 4],
    pub wi: [f32; 4],
    pub u: [f32; 4],
    /// The surface's `Surface.tex1` (hair: its ∂p/∂u and the offset h across the fiber).
    pub tex1: [f32; 4],
}

/// The BSDF probe's output (abi.h).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct BsdfProbeOutput {
    pub eval: [f32; 4],
    pub sample_dir: [f32; 4],
    pub sample_f: [f32; 4],
    pub info: [u32; 4],
}

/// The BSDF kinds (abi.h `BSDF_*`; `GpuMaterial.info.x`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum BsdfKind {
    Phong = BSDF_PHONG,
    Ggx = BSDF_GGX,
    Dielectric = BSDF_DIELECTRIC,
    ThinDielectric = BSDF_THIN_DIELECTRIC,
    Conductor = BSDF_CONDUCTOR,
    CoatedDiffuse = BSDF_COATED_DIFFUSE,
    DiffuseTransmission = BSDF_DIFFUSE_TRANSMISSION,
    CoatedConductor = BSDF_COATED_CONDUCTOR,
    Measured = BSDF_MEASURED,
    Hair = BSDF_HAIR,
}

impl BsdfKind {
    pub const ALL: [BsdfKind; 10] = [
        BsdfKind::Phong,
        BsdfKind::Ggx,
        BsdfKind::Dielectric,
        BsdfKind::ThinDielectric,
        BsdfKind::Conductor,
        BsdfKind::CoatedDiffuse,
        BsdfKind::DiffuseTransmission,
        BsdfKind::CoatedConductor,
        BsdfKind::Measured,
        BsdfKind::Hair,
    ];

    /// The material class (abi.h `MATERIAL_CLASS_*`) whose shade kernels hold this kind:
    /// GLSL `material_class`.
    pub fn class(self) -> u32 {
        match self {
            BsdfKind::Phong | BsdfKind::Ggx => MATERIAL_CLASS_BASIC,
            BsdfKind::Dielectric
            | BsdfKind::ThinDielectric
            | BsdfKind::Conductor
            | BsdfKind::DiffuseTransmission => MATERIAL_CLASS_INTERFACE,
            BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor => MATERIAL_CLASS_COATED,
            BsdfKind::Measured => MATERIAL_CLASS_MEASURED,
            BsdfKind::Hair => MATERIAL_CLASS_HAIR,
        }
    }

    /// The kind of a record's `info.x`, if it is one.
    pub fn from_code(code: u32) -> Option<BsdfKind> {
        Self::ALL.into_iter().find(|k| *k as u32 == code)
    }
}

/// How BSDF sampling draws directions (the scene's `importancesampling`; abi.h `SAMPLE_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum SampleMode {
    /// Uniform over the hemisphere of n, pdf 1/(2π).
    Hemisphere = SAMPLE_HEMISPHERE,
    /// Cosine-weighted around n, pdf cosθ/π.
    Cosine = SAMPLE_COSINE,
    /// The material's own lobe mixture.
    Brdf = SAMPLE_BRDF,
}

impl SampleMode {
    pub const ALL: [SampleMode; 3] = [SampleMode::Hemisphere, SampleMode::Cosine, SampleMode::Brdf];
}

/// What a path carries (abi.h `TRANSPORT_*`): radiance on camera subpaths, importance on
/// light subpaths.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Transport {
    Radiance = TRANSPORT_RADIANCE,
    Importance = TRANSPORT_IMPORTANCE,
}

/// A struct's name in GLSL, its members' (name, Rust offset, Rust size) and its Rust size.
pub type StructLayout = (&'static str, Vec<(&'static str, usize, usize)>, usize);

/// The layouts of every mirrored struct, for the test that compares them with the
/// offsets in the compiled SPIR-V (tests/abi.rs).
pub fn layouts() -> Vec<StructLayout> {
    use std::mem::{offset_of, size_of};
    macro_rules! layout {
        ($t:ident, $($f:ident),*) => {{
            let value = $t::default();
            (stringify!($t), vec![$((stringify!($f), offset_of!($t, $f), std::mem::size_of_val(&value.$f))),*], size_of::<$t>())
        }};
    }
    vec![
        layout!(GpuTriangle, v0, v1, v2),
        layout!(GpuSphere, o2w0, o2w1, o2w2, w2o0, w2o1, w2o2, info),
        layout!(
            GpuMaterial,
            diffuse,
            specular,
            emission,
            eta,
            k,
            roughness,
            info,
            base
        ),
        layout!(GpuEmitter, p0, p1, p2, radiance, info),
        layout!(
            GpuMedium,
            sigma_a,
            sigma_s,
            emission,
            info,
            unit_x,
            unit_y,
            unit_z,
            density_res,
            le_res
        ),
        layout!(
            SceneParams,
            cam_eye,
            cam_right,
            cam_up,
            cam_forward,
            bounds,
            width,
            height,
            triangle_count,
            sphere_count,
            emitter_count,
            max_depth,
            unbounded,
            spp,
            integrator,
            seed,
            sample_mode,
            nee,
            russian_roulette,
            light_samples,
            light_stratify,
            min_depth,
            strategy_first,
            strategy_count,
            environment,
            environment_count,
            lens,
            gbuffer_world,
            reserved6,
            camera_medium,
            cam_window,
            lens_radius,
            focal_distance,
            flat_triangle_count,
            instance_count
        ),
        layout!(GpuInstance, w2o0, w2o1, w2o2, o2w0, o2w1, o2w2, info),
        layout!(GpuPathVertex, p, n, wi, beta, ns),
        layout!(
            GpuPtPath, o, d, beta, radiance, prev_p, hit, p, n, ns, ls_wi, ls_le, ls_p, ls_n, tex0,
            tex1
        ),
        layout!(GpuGbufferSurface, wo, ns, tex0, tex1, rng),
        layout!(GpuTriangleUv, uv01, uv2),
        layout!(GpuTriangleShading, n0, n1, n2),
        layout!(GpuTexture, info, flags, scale, other, mapping, proj0, proj1, proj2),
        layout!(PassParams, first_sample, samples, row_begin, row_end),
        layout!(
            BdptParams,
            first_sample,
            samples,
            row_begin,
            row_end,
            bounce,
            side,
            reserved0,
            reserved1
        ),
        layout!(
            GpuBdptWalk,
            o,
            d,
            beta,
            prev_p,
            counts,
            radiance,
            hit,
            v_p,
            v_n,
            v_wi,
            v_beta,
            v_ns,
            ls_wi,
            ls_le,
            ls_p,
            ls_n,
            ls_pdfs,
            connected
        ),
        layout!(
            WavefrontParams,
            first_sample,
            samples,
            row_begin,
            row_end,
            slots,
            depth,
            reset,
            reserved
        ),
        layout!(
            MmltParams,
            mode,
            first_item,
            items,
            mutations,
            chains,
            bootstrap_per_depth,
            depths,
            record_depths,
            camera_numbers,
            light_numbers,
            connect_numbers,
            numbers,
            sigma,
            large_step,
            reserved0,
            reserved1
        ),
        layout!(GpuChain, current, state, counts, start),
        layout!(
            GpuMmltPath,
            path,
            key,
            used,
            camera_o,
            camera_d,
            value,
            y_p,
            y_n,
            y_wi,
            y_beta,
            y_ns,
            conn,
            to_eye,
            answer_z,
            answer_y,
            answer_rev,
            y_tex0,
            y_tex1
        ),
        layout!(BsdfProbeInput, info, n, wo, wi, u, tex1),
        layout!(BsdfProbeOutput, eval, sample_dir, sample_f, info),
    ]
}

const _: () = assert!(std::mem::size_of::<GpuTriangle>() == 48);
const _: () = assert!(std::mem::size_of::<GpuSphere>() == 112);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 128);
const _: () = assert!(std::mem::size_of::<GpuEmitter>() == 80);
const _: () = assert!(std::mem::size_of::<SceneParams>() == 208);
const _: () = assert!(std::mem::size_of::<MmltParams>() == 64);
const _: () = assert!(std::mem::size_of::<GpuPathVertex>() == 80);
const _: () = assert!(std::mem::size_of::<GpuPtPath>() == 240);
const _: () = assert!(std::mem::size_of::<GpuGbufferSurface>() == 80);
const _: () = assert!(std::mem::size_of::<GpuBdptWalk>() == 288);
const _: () = assert!(std::mem::size_of::<BdptParams>() == 32);
const _: () = assert!(std::mem::size_of::<WavefrontParams>() == 32);
