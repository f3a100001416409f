//! The scene model: what a `.test` file describes, in world space.
//!
//! The parser (`parse.rs`) fills a [`Scene`]; everything downstream (acceleration
//! structures, GPU buffers, integrators) reads only this model.

mod displace;
pub mod lens;
mod parse;
mod pbrt;
pub mod ply;
pub mod sensor;
pub mod spectrum;
mod subdiv;
mod triangles;

pub use parse::{parse_file, parse_str, ParseError};
pub use pbrt::{parse_pbrt_file, parse_pbrt_str};
pub use triangles::{TriangleCorners, Triangles, DEFAULT_UV};

/// Reads a scene file: pbrt-v4's format for `.pbrt`, else the `.test` format.
///
/// # Errors
/// As [`parse_file`] and [`parse_pbrt_file`].
pub fn load(path: &std::path::Path) -> Result<Scene, ParseError> {
    let pbrt = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pbrt"));
    if pbrt {
        parse_pbrt_file(path)
    } else {
        parse_file(path)
    }
}

use glam::{Mat3, Mat4, Vec2, Vec3};
use std::path::PathBuf;
use std::sync::Arc;

pub use crate::abi::{BsdfKind, SampleMode};
use crate::abi::{
    GpuMaterial, MATERIAL_BUMP_MAP, MATERIAL_MEDIUM_INTERFACE, MATERIAL_MIX, MATERIAL_NORMAL_MAP,
    MATERIAL_PASS_THROUGH, MATERIAL_REMAP_ROUGHNESS, MATERIAL_TWO_SIDED_EMISSION,
    MAX_MATERIAL_MIX_DEPTH, MEDIUM_VACUUM, NO_TEXTURE,
};
pub use crate::texture::{Environment, EnvironmentMap, Texture, UV_MAPPING};

/// One material: the sticky material state at the moment a shape was declared.
///
/// Hair (pbrt-v4's `hair`, src/hair.rs) keeps its parameters in the fields of the same
/// role: `k` its absorption σa, `ior` its index, `roughness` and `roughness_v` its
/// longitudinal and azimuthal roughness β_m and β_n, `shininess` its scales' tilt α in
/// degrees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub bsdf: BsdfKind,
    pub diffuse: Vec3,
    pub specular: Vec3,
    pub shininess: f32,
    /// The microfacet alpha (GGX; dielectric and conductor along the tangent; 0 is
    /// smooth for those).
    pub roughness: f32,
    /// Dielectric and conductor: the alpha along the bitangent (`roughness A AV`; the
    /// same as `roughness` when one value is given).
    pub roughness_v: f32,
    /// Dielectric, thin dielectric: the index of refraction inside over outside.
    pub ior: f32,
    /// Conductor, and the conductor under a coated conductor's coating: the complex index
    /// of refraction eta + i k per channel (absolute; the record makes a coated one's
    /// relative to the coating).
    pub eta: Vec3,
    pub k: Vec3,
    /// Coated conductor: the conductor's microfacet alphas (tangent, bitangent) and the
    /// float texture that replaces both (`roughness` and `ior` are the coating's).
    pub base_roughness: f32,
    pub base_roughness_v: f32,
    pub base_roughness_texture: Option<u32>,
    /// Coated diffuse and coated conductor: the thickness of the absorbing layer under the coating (unit
    /// extinction), and the random walk's maximum depth and samples per evaluation
    /// (pbrt-v4's `thickness`, `maxdepth`, `nsamples`).
    pub thickness: f32,
    /// The float texture that replaces `thickness` (its first channel).
    pub thickness_texture: Option<u32>,
    pub layer_max_depth: u32,
    pub layer_samples: u32,
    /// Coated: the single-scattering albedo of the layer's medium (0: it only absorbs)
    /// and the Henyey–Greenstein g of its phase function (pbrt-v4's `albedo`, `g`).
    pub layer_albedo: Vec3,
    pub layer_g: f32,
    /// Diffuse transmission: the transmittance T (its reflectance R is `diffuse`).
    pub transmittance: Vec3,
    pub emission: Vec3,
    /// `emission` emits from both sides; a `quadLight` only from its front
    /// (the side its geometric normal points to).
    pub two_sided_emission: bool,
    /// The texture (an index into `Scene::textures`) that replaces `diffuse`.
    pub diffuse_texture: Option<u32>,
    /// The float texture (its first channel) that replaces the microfacet alpha
    /// (`roughness` and `roughness_v` alike).
    pub roughness_texture: Option<u32>,
    /// The roughness texture holds pbrt's roughness r rather than alpha: alpha = √r at
    /// each lookup (pbrt-v4's `remaproughness` with a texture).
    pub remap_roughness_texture: bool,
    /// Diffuse transmission: the texture that replaces `transmittance`.
    pub transmittance_texture: Option<u32>,
    /// A bump or normal map: the shading normal it gives replaces the surface's
    /// (src/shading_map.rs).
    pub shading_map: Option<ShadingMap>,
    /// Measured (pbrt-v4's `measured`): its tables, an index into `Scene::measured`.
    pub measured: Option<u32>,
    /// pbrt-v4's `mix`: not a surface but a choice between two materials at each point
    /// (the BSDF fields are unused; `emission` is the emitter's, and both materials
    /// carry it too).
    pub mix: Option<MaterialMix>,
    /// The media on either side of the surface, where they differ (pbrt-v4's
    /// `MediumInterface` when it is a transition); `None`: a ray leaving the surface is in
    /// the medium it arrived in.
    pub medium_interface: Option<MediumInterface>,
    /// pbrt-v4's interface material: no surface, only a boundary between media, which
    /// rays cross unchanged (the BSDF fields are unused).
    pub pass_through: bool,
}

/// The media inside and outside a surface (the side its geometric normal points to is
/// the outside): indices into `Scene::media`, `None` for vacuum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MediumInterface {
    pub inside: Option<u32>,
    pub outside: Option<u32>,
}

impl MediumInterface {
    /// abi.h's medium code of a medium: 0 vacuum, else its index + 1.
    pub fn code(medium: Option<u32>) -> u32 {
        medium.map_or(MEDIUM_VACUUM, |m| m + 1)
    }

    /// The two codes as GpuMaterial.emission.w holds them (inside low, outside high).
    pub fn packed(&self) -> u32 {
        Self::code(self.inside) | Self::code(self.outside) << 16
    }
}

/// A participating medium: absorption and scattering coefficients per channel (per unit
/// length, its `scale` applied; a grid's per unit of its grid's values), the
/// Henyey–Greenstein asymmetry `g` of its phase function, and the radiance it emits
/// (`Le` × `Lescale`, a grid's times its grid's; it adds sigma_a Le per unit length).
/// Homogeneous (pbrt-v4's `homogeneous`) where `grid` is `None`; else pbrt-v4's
/// `uniformgrid` or `rgbgrid` (`GridValues`).
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    pub g: f32,
    pub emission: Vec3,
    pub grid: Option<Arc<MediumGrid>>,
}

/// Samples over the unit cube (pbrt-v4's `SampledGrid`): `res` = nx, ny, nz values at the
/// cells' centres, x fastest then y then z; trilinear between them, zero outside
/// (src/media.rs's `lookup`). Values are numbers (`f32`) or RGB triples (`Vec3`).
#[derive(Clone, Debug, PartialEq)]
pub struct SampledGrid<T = f32> {
    pub res: [u32; 3],
    pub values: Vec<T>,
}

/// A grid medium's varying part over the unit cube that `unit_from_world` (affine) maps
/// the medium's bounds to, and its majorant grid (`MEDIUM_MAJORANT_RES`³ cells, each the
/// most the extinction reaches in it in units of src/media.rs's `majorant_scale`; its
/// `grid_majorants`).
#[derive(Clone, Debug, PartialEq)]
pub struct MediumGrid {
    pub unit_from_world: Mat4,
    pub values: GridValues,
    pub majorants: Vec<f32>,
}

/// What a grid medium's grids hold.
#[derive(Clone, Debug, PartialEq)]
pub enum GridValues {
    /// pbrt-v4's `uniformgrid`: a density (the medium's sigma_a and sigma_s are per unit
    /// density) and an Le scale (the emitted radiance is the medium's Le times it, times
    /// the blackbody of its temperature where it has one).
    Density {
        density: SampledGrid,
        le_scale: SampledGrid,
        temperature: Option<Temperature>,
    },
    /// pbrt-v4's `rgbgrid`: sigma_a, sigma_s and Le per channel, each times the medium's
    /// (`scale` for both coefficients, `Lescale` for the emission); sigma_a and sigma_s
    /// are 1 where their grid is not given, and there is no emission without an Le grid.
    /// All of one resolution.
    Rgb {
        sigma_a: Option<SampledGrid<Vec3>>,
        sigma_s: Option<SampledGrid<Vec3>>,
        le: Option<SampledGrid<Vec3>>,
    },
    /// pbrt-v4's `nanovdb`: a density grid read from a NanoVDB file (the medium's sigma_a
    /// and sigma_s are per unit density) and, where the file has one, a temperature grid
    /// (emission as a uniformgrid's temperature, times the medium's Le, pbrt-v4's
    /// `Lescale`), each as sparse bricks (src/nanovdb.rs) with its own map from the unit
    /// cube (the grids' bounds) to its index space.
    NanoVdb {
        density: SparseGrid,
        temperature: Option<(SparseGrid, f32, f32)>,
    },
    /// pbrt-v4's procedural `cloud`: a density in [0, 1] made of noise (src/media.rs's
    /// `cloud_density`) at the point of the medium's space (the box `p0` + the unit cube
    /// times `extent`); the medium's sigma_a and sigma_s are per unit density; no emission.
    Cloud {
        density: f32,
        wispiness: f32,
        frequency: f32,
        p0: Vec3,
        extent: Vec3,
    },
}

/// A grid medium's temperature (pbrt-v4's `temperature` grid of a `uniformgrid`): where
/// (grid - `offset`) × `scale` exceeds 100 K it emits the blackbody of that temperature
/// (src/media.rs's `blackbody`: the spectrum over its peak value, as pbrt-v4's
/// `BlackbodySpectrum`), times the medium's Le scale.
#[derive(Clone, Debug, PartialEq)]
pub struct Temperature {
    pub grid: SampledGrid,
    pub offset: f32,
    pub scale: f32,
}

/// A NanoVDB grid as sparse 8³ bricks and the affine map from its medium's unit cube to
/// the grid's index space (voxel values at integer points, trilinear between them as
/// pbrt-v4's `SampleFromVoxels`: src/nanovdb.rs's `Bricks::sample`).
#[derive(Clone, Debug, PartialEq)]
pub struct SparseGrid {
    pub index_from_unit: Mat4,
    pub bricks: crate::nanovdb::Bricks,
}

impl SparseGrid {
    /// Its value at `p` of the unit cube.
    pub fn lookup(&self, p: Vec3) -> f32 {
        self.bricks.sample(self.index_from_unit.transform_point3(p))
    }
}

impl MediumGrid {
    /// A grid medium of `values` over the unit cube of `unit_from_world`, with the
    /// majorants of its extinction (src/media.rs's `grid_majorants`).
    pub fn new(unit_from_world: Mat4, values: GridValues) -> Self {
        let majorants = crate::media::grid_majorants(&values);
        MediumGrid {
            unit_from_world,
            values,
            majorants,
        }
    }

    /// A nanovdb medium's.
    pub fn nano_vdb(
        unit_from_world: Mat4,
        density: SparseGrid,
        temperature: Option<(SparseGrid, f32, f32)>,
    ) -> Self {
        Self::new(
            unit_from_world,
            GridValues::NanoVdb {
                density,
                temperature,
            },
        )
    }

    /// A uniformgrid's.
    pub fn density(
        unit_from_world: Mat4,
        density: SampledGrid,
        le_scale: SampledGrid,
        temperature: Option<Temperature>,
    ) -> Self {
        Self::new(
            unit_from_world,
            GridValues::Density {
                density,
                le_scale,
                temperature,
            },
        )
    }

    /// An rgbgrid's.
    pub fn rgb(
        unit_from_world: Mat4,
        sigma_a: Option<SampledGrid<Vec3>>,
        sigma_s: Option<SampledGrid<Vec3>>,
        le: Option<SampledGrid<Vec3>>,
    ) -> Self {
        Self::new(
            unit_from_world,
            GridValues::Rgb {
                sigma_a,
                sigma_s,
                le,
            },
        )
    }
}

impl GridValues {
    /// Whether it emits a blackbody (a uniformgrid's or nanovdb's temperature grid).
    pub fn has_temperature(&self) -> bool {
        matches!(
            self,
            GridValues::Density {
                temperature: Some(_),
                ..
            } | GridValues::NanoVdb {
                temperature: Some(_),
                ..
            }
        )
    }
}

/// The most media a scene may hold (their codes fill 16 bits).
pub const MAX_MEDIA: usize = 65534;

/// What perturbs a material's shading normal (textures are indices into
/// `Scene::textures`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadingMap {
    /// pbrt-v4's `displacement`: a float texture (its first channel), the height of the
    /// surface along its shading normal.
    Bump(u32),
    /// pbrt-v4's `normalmap`: an RGB texture (linear, repeating) whose 2c - 1 is the
    /// normal in the tangent frame (dp/du, n x dp/du, n).
    Normal(u32),
}

/// A choice between two materials (indices into `Scene::materials`), made at each
/// surface point by a hash of its position: the second with probability `amount` (or
/// the first channel of `amount_texture`), as pbrt-v4's `MixMaterial` chooses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialMix {
    pub materials: [u32; 2],
    pub amount: f32,
    pub amount_texture: Option<u32>,
}

/// The deepest nesting of mixes the kernels resolve.
pub const MAX_MIX_DEPTH: u32 = MAX_MATERIAL_MIX_DEPTH;

/// A dielectric's index of refraction when the scene does not give one (glass).
pub const DEFAULT_IOR: f32 = 1.5;
/// A conductor's eta and k when the scene does not give them: copper, as RGB (pbrt-v4's
/// default conductor is copper, "metal-Cu-eta" / "metal-Cu-k").
pub const COPPER_ETA: Vec3 = Vec3::new(0.200_438, 0.924_033, 1.102_21);
pub const COPPER_K: Vec3 = Vec3::new(3.912_95, 2.452_85, 2.142_19);

impl Default for Material {
    fn default() -> Self {
        Material {
            bsdf: BsdfKind::Phong,
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            shininess: 1.0,
            roughness: 0.0,
            roughness_v: 0.0,
            ior: DEFAULT_IOR,
            eta: COPPER_ETA,
            k: COPPER_K,
            base_roughness: 0.0,
            base_roughness_v: 0.0,
            base_roughness_texture: None,
            thickness: 0.01,
            thickness_texture: None,
            layer_max_depth: 10,
            layer_samples: 1,
            layer_albedo: Vec3::ZERO,
            layer_g: 0.0,
            transmittance: Vec3::ZERO,
            emission: Vec3::ZERO,
            two_sided_emission: true,
            diffuse_texture: None,
            roughness_texture: None,
            remap_roughness_texture: false,
            transmittance_texture: None,
            shading_map: None,
            measured: None,
            mix: None,
            medium_interface: None,
            pass_through: false,
        }
    }
}

impl Material {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// The flags of the material's medium interface and pass-through, and the word
    /// (GpuMaterial.emission.w, as float bits) of its media.
    fn media_record(&self) -> (u32, f32) {
        let mut flags = 0;
        if self.pass_through {
            flags |= MATERIAL_PASS_THROUGH;
        }
        match self.medium_interface {
            Some(mi) => (
                flags | MATERIAL_MEDIUM_INTERFACE,
                f32::from_bits(mi.packed()),
            ),
            None => (flags, 0.0),
        }
    }

    /// The material as the kernels read it (abi.h `GpuMaterial`). Two materials are the
    /// same material exactly when their records are equal, so the parser deduplicates by
    /// the whole record.
    pub fn record(&self) -> GpuMaterial {
        let (media_flags, media) = self.media_record();
        if let Some(mix) = self.mix {
            let flags = MATERIAL_MIX
                | media_flags
                | if self.two_sided_emission {
                    MATERIAL_TWO_SIDED_EMISSION
                } else {
                    0
                };
            return GpuMaterial {
                specular: [
                    f32::from_bits(mix.materials[0]),
                    f32::from_bits(mix.materials[1]),
                    mix.amount,
                    0.0,
                ],
                emission: self.emission.extend(media).to_array(),
                info: [
                    BsdfKind::Phong as u32,
                    flags,
                    mix.amount_texture.unwrap_or(NO_TEXTURE),
                    NO_TEXTURE,
                ],
                ..GpuMaterial::default()
            };
        }
        let transmits = self.bsdf == BsdfKind::DiffuseTransmission;
        let coated_conductor = self.bsdf == BsdfKind::CoatedConductor;
        GpuMaterial {
            diffuse: if coated_conductor {
                self.k / self.ior
            } else {
                self.diffuse
            }
            .extend(0.0)
            .to_array(),
            specular: if transmits {
                self.transmittance
            } else if coated_conductor {
                self.eta / self.ior
            } else {
                self.specular
            }
            .extend(0.0)
            .to_array(),
            emission: self.emission.extend(media).to_array(),
            // Only the fields of the material's own kind, so that materials differing
            // only in another kind's parameters are one material.
            eta: match self.bsdf {
                BsdfKind::Dielectric | BsdfKind::ThinDielectric => {
                    [self.ior, self.ior, self.ior, 0.0]
                }
                // (y, z, w: the layer's albedo.)
                BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor => [
                    self.ior,
                    self.layer_albedo.x,
                    self.layer_albedo.y,
                    self.layer_albedo.z,
                ],
                BsdfKind::Conductor => self.eta.extend(0.0).to_array(),
                BsdfKind::Hair => [self.ior, 0.0, 0.0, 0.0],
                BsdfKind::Phong
                | BsdfKind::Ggx
                | BsdfKind::DiffuseTransmission
                | BsdfKind::Measured => [0.0; 4],
            },
            k: match self.bsdf {
                // (Hair: its absorption sigma_a.)
                BsdfKind::Conductor | BsdfKind::Hair => self.k.extend(0.0).to_array(),
                BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor => [
                    self.thickness,
                    self.layer_max_depth as f32,
                    self.layer_samples as f32,
                    self.layer_g,
                ],
                _ => [0.0; 4],
            },
            roughness: [
                self.shininess,
                self.roughness,
                self.roughness_v,
                match self.shading_map {
                    Some(ShadingMap::Bump(t) | ShadingMap::Normal(t)) => f32::from_bits(t),
                    None => 0.0,
                },
            ],
            info: [
                self.bsdf as u32,
                if self.two_sided_emission {
                    MATERIAL_TWO_SIDED_EMISSION
                } else {
                    0
                } | if self.remap_roughness_texture
                    && !transmits
                    && (self.roughness_texture.is_some()
                        || coated_conductor && self.base_roughness_texture.is_some())
                {
                    MATERIAL_REMAP_ROUGHNESS
                } else {
                    0
                } | match self.shading_map {
                    Some(ShadingMap::Bump(_)) => MATERIAL_BUMP_MAP,
                    Some(ShadingMap::Normal(_)) => MATERIAL_NORMAL_MAP,
                    None => 0,
                } | media_flags,
                self.diffuse_texture.unwrap_or(NO_TEXTURE),
                if transmits {
                    self.transmittance_texture
                } else {
                    self.roughness_texture
                }
                .unwrap_or(NO_TEXTURE),
            ],
            base: match self.bsdf {
                BsdfKind::CoatedConductor => [
                    self.base_roughness,
                    self.base_roughness_v,
                    f32::from_bits(self.base_roughness_texture.unwrap_or(NO_TEXTURE)),
                    f32::from_bits(self.thickness_texture.unwrap_or(NO_TEXTURE)),
                ],
                BsdfKind::CoatedDiffuse => [
                    0.0,
                    0.0,
                    0.0,
                    f32::from_bits(self.thickness_texture.unwrap_or(NO_TEXTURE)),
                ],
                // (The index into `Scene::measured`: the upload puts the texel index of
                // its tables there, gpu_scene::material_records.)
                BsdfKind::Measured => [f32::from_bits(self.measured.unwrap_or(0)), 0.0, 0.0, 0.0],
                _ => [0.0; 4],
            },
        }
    }
}

/// A world-space triangle. Its geometric normal is `cross(v1 - v0, v2 - v0)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub v: [Vec3; 3],
    pub material: u32,
    /// Texture coordinates at the corners; `None`: pbrt's (0,0), (1,0), (1,1).
    pub uv: Option<[Vec2; 3]>,
    /// Unit shading normals at the corners (world space), interpolated across the
    /// triangle; `None`: the geometric normal.
    pub normals: Option<[Vec3; 3]>,
    /// pbrt-v4's `alpha` cut-out (src/alpha.rs); `None`: opaque.
    pub alpha: Option<Alpha>,
}

/// A shape's alpha (pbrt-v4's `alpha`): where it is below 1 a hit is cut out (ignored by
/// every ray) with probability 1 − alpha, decided by a hash of the ray and the triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Alpha {
    Constant(f32),
    /// A float texture (its first channel; an index into `Scene::textures`).
    Texture(u32),
}

impl Alpha {
    /// A constant alpha of 0 (or below): cut out of every ray; on an area light, pbrt-v4's
    /// invisible light.
    pub fn is_zero(self) -> bool {
        matches!(self, Alpha::Constant(a) if a <= 0.0)
    }
}

impl Triangle {
    /// Whether it has attribute records (texture coordinates, shading normals or
    /// alpha; gpu_scene.rs `triangle_uv`).
    pub fn has_attributes(&self) -> bool {
        self.uv.is_some() || self.has_shading()
    }

    /// Whether its attributes include a shading record (shading normals or alpha;
    /// gpu_scene.rs `triangle_shading`).
    pub fn has_shading(&self) -> bool {
        self.normals.is_some() || self.alpha.is_some()
    }

    pub fn new(v: [Vec3; 3], material: u32) -> Triangle {
        Triangle {
            v,
            material,
            uv: None,
            normals: None,
            alpha: None,
        }
    }

    /// The triangle with its orientation reversed (its geometric normal flipped): v1 and
    /// v2 swap, with their texture coordinates and normals.
    pub fn flipped(mut self) -> Triangle {
        self.v.swap(1, 2);
        if let Some(uv) = &mut self.uv {
            uv.swap(1, 2);
        }
        n_swap(&mut self.normals);
        self
    }

    /// The triangle wound so that its geometric normal lies on the side of its shading
    /// normals (as pbrt-v4 turns a mesh's geometric normal toward its shading normal):
    /// which side is the outside of a glass object then follows the mesh's normals.
    pub fn facing_its_normals(mut self) -> Triangle {
        if let Some(n) = self.normals {
            let ng = (self.v[1] - self.v[0]).cross(self.v[2] - self.v[0]);
            if ng.dot(n[0] + n[1] + n[2]) < 0.0 {
                self.v.swap(1, 2);
                n_swap(&mut self.normals);
                if let Some(uv) = &mut self.uv {
                    uv.swap(1, 2);
                }
            }
        }
        self
    }
}

fn n_swap(n: &mut Option<[Vec3; 3]>) {
    if let Some(n) = n {
        n.swap(1, 2);
    }
}

/// A sphere as the unit sphere at the origin under an affine `object_to_world`
/// transform (the file's centre and radius are folded into it). A non-uniform scale
/// makes it an ellipsoid. `inward`: its surface normal faces inward (pbrt-v4's
/// `ReverseOrientation`, or a transform that swaps handedness, as pbrt-v4 defines it for
/// spheres): a one-sided emitter then lights its inside, and a dielectric's outside (the
/// side its index of refraction is relative to) is the inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub object_to_world: Mat4,
    pub material: u32,
    pub inward: bool,
    /// pbrt-v4's invisible area light (alpha 0 on an emitting sphere): it emits, but no
    /// ray meets it (it is left out of every acceleration structure), so only light
    /// sampling finds it.
    pub hidden: bool,
}

/// A parallelogram light as written in the file (world space): corner `a`, edges
/// `ab` and `ac`, emitting `radiance` toward `normalize(cross(ac, ab))`.
/// The parser also adds its two triangles (with a one-sided emissive material) to
/// [`Scene::triangles`], so it is geometry and an area light like any other.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadLight {
    pub a: Vec3,
    pub ab: Vec3,
    pub ac: Vec3,
    pub radiance: Vec3,
}

/// Lights that are not geometry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DeltaLight {
    /// Intensity (W/sr per channel), 1/d² falloff.
    Point { position: Vec3, intensity: Vec3 },
    /// Light arriving from `direction` (pointing from the scene toward the light)
    /// with irradiance `radiance` on a surface facing it.
    Directional { direction: Vec3, radiance: Vec3 },
    /// pbrt-v4's spot light: intensity `intensity` along the unit `direction` from
    /// `position`, falling off by a smoothstep in cosθ from `cos_falloff_start` (full) to
    /// `cos_falloff_end` (zero, the cone's edge), 1/d² with distance.
    Spot {
        position: Vec3,
        direction: Vec3,
        intensity: Vec3,
        cos_falloff_start: f32,
        cos_falloff_end: f32,
    },
    /// pbrt-v4's goniometric light: intensity `intensity` × the value of the image
    /// `Scene::light_profiles[profile]` (one channel) at the direction
    /// `light_from_world · w` on the equal-area square (normalized), 1/d² with distance.
    Goniometric {
        position: Vec3,
        light_from_world: Mat3,
        intensity: Vec3,
        profile: u32,
    },
    /// pbrt-v4's projection light: `scale` × the RGB image `Scene::light_profiles[profile]`
    /// projected from `position`: the direction w shows the pixel at the screen point
    /// (q.x / q.z, q.y / q.z), q = `screen_from_world · w`, on the image's screen bounds
    /// (\[-a, a\] × \[-1, 1\] for an image of aspect a ≥ 1, \[-1, 1\] × \[-1/a, 1/a\] below;
    /// y down the image), dark where q.z ≤ 0 or outside; 1/d² with distance.
    Projection {
        position: Vec3,
        screen_from_world: Mat3,
        scale: Vec3,
        profile: u32,
    },
}

/// The half extents (a, 1) or (1, 1/a) of pbrt-v4's screen bounds for a projection
/// light's image of aspect a = width / height.
pub fn projection_half_extent(width: u32, height: u32) -> Vec2 {
    let aspect = width as f32 / height as f32;
    if aspect > 1.0 {
        Vec2::new(aspect, 1.0)
    } else {
        Vec2::new(1.0, 1.0 / aspect)
    }
}

impl DeltaLight {
    /// A goniometric or projection light's map, its image and whether it projects.
    fn profiled(&self) -> Option<(Mat3, u32, bool)> {
        match *self {
            DeltaLight::Goniometric {
                light_from_world,
                profile,
                ..
            } => Some((light_from_world, profile, false)),
            DeltaLight::Projection {
                screen_from_world,
                profile,
                ..
            } => Some((screen_from_world, profile, true)),
            _ => None,
        }
    }

    /// For a goniometric or projection light (CPU mirror of lights.glsl `profile_uv`): the
    /// image point toward the unit world direction `w` and the solid angle of directions
    /// per unit of image area there; None where the light is dark (behind or beside a
    /// projection, or not such a light).
    pub fn profile_uv(&self, profiles: &[LightProfile], w: Vec3) -> Option<(Vec2, f32)> {
        let (m, profile, projects) = self.profiled()?;
        let p = &profiles[profile as usize];
        let q = m * w;
        let det = m.determinant().abs();
        if !projects {
            let len = q.length();
            let uv = crate::texture::equal_area_sphere_to_square(q / len);
            return Some((uv, 4.0 * std::f32::consts::PI * len * len * len / det));
        }
        if !(q.z > 0.0) {
            return None;
        }
        let half = projection_half_extent(p.width, p.height);
        let uv = (Vec2::new(q.x, q.y) / q.z + half) / (2.0 * half);
        if !(uv.cmpge(Vec2::ZERO).all() && uv.cmple(Vec2::ONE).all()) {
            return None;
        }
        Some((uv, 4.0 * half.x * half.y * q.z * q.z * q.z / det))
    }

    /// The unit world direction of the image point uv of a goniometric or projection
    /// light, with the solid angle per unit of image area there (lights.glsl
    /// `profile_direction`).
    pub fn profile_direction(&self, profiles: &[LightProfile], uv: Vec2) -> Option<(Vec3, f32)> {
        let (m, profile, projects) = self.profiled()?;
        let p = &profiles[profile as usize];
        let inv = m.inverse();
        let det = m.determinant().abs();
        if !projects {
            let v = inv * crate::texture::equal_area_square_to_sphere(uv);
            let len = v.length();
            // |M w| = 1 / |v| for w = v / |v|.
            return Some((
                v / len,
                4.0 * std::f32::consts::PI / (len * len * len * det),
            ));
        }
        let half = projection_half_extent(p.width, p.height);
        let s = (2.0 * uv - Vec2::ONE) * half;
        let v = inv * s.extend(1.0);
        let len = v.length();
        Some((v / len, 4.0 * half.x * half.y / (len * len * len * det)))
    }

    /// For a goniometric or projection light: `weight` of each pixel of its image (given
    /// the pixel's channels) times the solid angle of directions per unit of image area
    /// at the pixel's centre, row-major, and the integral of the weight over directions
    /// (their sum over the pixel count). None for other lights.
    pub fn profile_pixel_integral(
        &self,
        profiles: &[LightProfile],
        weight: impl Fn(&[f32]) -> f32,
    ) -> Option<(Vec<f32>, f32)> {
        let (_, profile, _) = self.profiled()?;
        let p = &profiles[profile as usize];
        let (w, h) = (p.width, p.height);
        let weights: Vec<f32> = p
            .values
            .chunks(p.channels as usize)
            .enumerate()
            .map(|(i, c)| {
                let uv = Vec2::new(
                    ((i as u32 % w) as f32 + 0.5) / w as f32,
                    ((i as u32 / w) as f32 + 0.5) / h as f32,
                );
                let jac = self.profile_direction(profiles, uv).map_or(0.0, |(_, j)| j);
                (weight(c).max(0.0) * jac).max(0.0)
            })
            .collect();
        let integral = weights.iter().map(|&x| x as f64).sum::<f64>() / (w * h) as f64;
        Some((weights, integral as f32))
    }

    /// A goniometric or projection light's intensity toward the unit world direction w.
    pub fn profile_intensity(&self, profiles: &[LightProfile], w: Vec3) -> Vec3 {
        let colour = match *self {
            DeltaLight::Goniometric { intensity, .. } => intensity,
            DeltaLight::Projection { scale, .. } => scale,
            _ => return Vec3::ZERO,
        };
        let (_, profile, _) = self.profiled().expect("a profiled light");
        self.profile_uv(profiles, w).map_or(Vec3::ZERO, |(uv, _)| {
            colour * profiles[profile as usize].nearest(uv)
        })
    }
}

/// The image of a goniometric or projection light: `channels` (1 or 3) linear values per
/// pixel, row-major from the top row, none negative.
#[derive(Clone, Debug, PartialEq)]
pub struct LightProfile {
    pub width: u32,
    pub height: u32,
    pub channels: u32,
    pub values: Vec<f32>,
}

impl LightProfile {
    /// The value at the pixel holding the point uv of \[0,1\]² (pbrt-v4's nearest lookup).
    pub fn nearest(&self, uv: Vec2) -> Vec3 {
        let x = ((uv.x * self.width as f32) as u32).min(self.width - 1);
        let y = ((uv.y * self.height as f32) as u32).min(self.height - 1);
        let i = ((y * self.width + x) * self.channels) as usize;
        if self.channels == 1 {
            Vec3::splat(self.values[i])
        } else {
            Vec3::new(self.values[i], self.values[i + 1], self.values[i + 2])
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    pub fovy_degrees: f32,
    /// The image is mirrored left to right: its right is up × forward rather than
    /// forward × up (pbrt's left-handed camera space).
    pub mirror: bool,
    /// The film on the plane at distance 1 ahead of the eye, in units along the image's
    /// right and up: `[x0, x1, y0, y1]` (pbrt's screen window times tan(fov / 2), or a
    /// crop of it). `None`: centred, spanning `fovy_degrees` vertically and the image's
    /// aspect horizontally (the course's camera).
    pub window: Option<[f32; 4]>,
    /// A thin lens: its radius (0: a pinhole) and the distance of the plane in focus.
    pub lens_radius: f32,
    pub focal_distance: f32,
}

impl Default for Camera {
    fn default() -> Self {
        Camera {
            eye: Vec3::new(0.0, 0.0, 1.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fovy_degrees: 45.0,
            mirror: false,
            window: None,
            lens_radius: 0.0,
            focal_distance: 1e6,
        }
    }
}

impl Camera {
    /// The film rectangle `[x0, x1, y0, y1]` on the plane at distance 1 for an image of
    /// `width` × `height` pixels.
    pub fn film_window(&self, width: u32, height: u32) -> [f32; 4] {
        self.window.unwrap_or_else(|| {
            let t = (self.fovy_degrees.to_radians() * 0.5).tan();
            let a = width as f32 / height as f32;
            [-t * a, t * a, -t, t]
        })
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum IntegratorKind {
    PathTracer,
    Direct,
    AnalyticDirect,
    Bdpt,
    Mmlt,
    /// The course's Whitted ray tracer: parsed, not rendered by lightpath.
    RayTracer,
}

impl IntegratorKind {
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "pathtracer" => Self::PathTracer,
            "direct" => Self::Direct,
            "analyticdirect" => Self::AnalyticDirect,
            "bdpt" => Self::Bdpt,
            "mmlt" => Self::Mmlt,
            "raytracer" => Self::RayTracer,
            _ => return None,
        })
    }
    pub fn name(self) -> &'static str {
        match self {
            Self::PathTracer => "pathtracer",
            Self::Direct => "direct",
            Self::AnalyticDirect => "analyticdirect",
            Self::Bdpt => "bdpt",
            Self::Mmlt => "mmlt",
            Self::RayTracer => "raytracer",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NextEventEstimation {
    Off,
    On,
    Mis,
}

/// Integrator settings (docs/scene-format.md, "Integrator settings").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub integrator: IntegratorKind,
    pub spp: u32,
    /// At most this many scattering vertices; -1 is unbounded.
    pub max_depth: i32,
    pub nee: NextEventEstimation,
    pub russian_roulette: bool,
    pub importance_sampling: SampleMode,
    pub light_samples: u32,
    pub light_stratify: bool,
    pub gamma: f32,
    pub mmlt: MmltSettings,
    /// The film's map from the transported linear sRGB to the image's, applied to the
    /// finished image: pbrt-v4's sensor and white balance (src/scene/sensor.rs); the
    /// identity but for a pbrt-v4 film that names them.
    pub output_from_render: glam::Mat3,
    /// pbrt-v4's `gbuffer` film: the first surface's albedo, position, normals and (u, v)
    /// written beside the image (src/integrators/gbuffer.rs), in this space; `None`: the
    /// image alone.
    pub gbuffer: Option<GBufferSpace>,
}

/// Where a g-buffer's positions and normals are (pbrt-v4's gbuffer film
/// `coordinatesystem`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GBufferSpace {
    /// The camera's: x right, y up, z ahead, the eye at the origin (pbrt-v4's default).
    Camera,
    /// The scene's world space.
    World,
}

/// MMLT's settings (scene commands `mmltbootstrap`, `mmltchains`, `mmltsigma`,
/// `mmltlargestep`; command-line `--mmlt-*`). `None`: the device-dependent default.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MmltSettings {
    /// Bootstrap samples per depth.
    pub bootstrap: Option<u32>,
    /// Independent Markov chains.
    pub chains: Option<u32>,
    /// Standard deviation of a small step's Gaussian offset in primary sample space.
    pub sigma: f32,
    /// Probability that a mutation is a large step (all numbers fresh).
    pub large_step: f32,
}

impl Default for MmltSettings {
    fn default() -> Self {
        MmltSettings {
            bootstrap: None,
            chains: None,
            sigma: 0.01,
            large_step: 0.3,
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            integrator: IntegratorKind::PathTracer,
            spp: 1,
            max_depth: 5,
            nee: NextEventEstimation::Off,
            russian_roulette: false,
            importance_sampling: SampleMode::Hemisphere,
            light_samples: 1,
            light_stratify: false,
            gamma: 1.0,
            mmlt: MmltSettings::default(),
            output_from_render: glam::Mat3::IDENTITY,
            gbuffer: None,
        }
    }
}

/// A parsed scene, all in world space.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file it came from (for messages); `None` when parsed from a string.
    pub source: Option<PathBuf>,
    pub width: u32,
    pub height: u32,
    /// The `output` command's file name, if any.
    pub output: Option<String>,
    pub camera: Camera,
    pub settings: Settings,
    pub materials: Vec<Material>,
    pub triangles: Triangles,
    pub spheres: Vec<Sphere>,
    pub quad_lights: Vec<QuadLight>,
    pub delta_lights: Vec<DeltaLight>,
    /// The infinite lights (`envlight`, `envmap`; pbrt-v4's `infinite` lights), each
    /// sampled as its own emitter; their radiance adds. Empty: black.
    pub environments: Vec<Environment>,
    /// pbrt-v4's realistic camera: the lens system the camera's rays go through (the
    /// camera's eye is the film's centre); None: a pinhole or a thin lens.
    pub lens: Option<std::sync::Arc<lens::LensSystem>>,
    /// The textures materials refer to.
    pub textures: Vec<Texture>,
    /// The measured materials' tables (`Material::measured` indexes them).
    pub measured: Vec<Arc<crate::measured::MeasuredBsdf>>,
    /// The goniometric and projection lights' images (`DeltaLight::profile` indexes them).
    pub light_profiles: Vec<LightProfile>,
    /// Participating media (`Material::medium_interface` and `camera_medium` index them).
    pub media: Vec<Medium>,
    /// The medium the camera is in (`None`: vacuum).
    pub camera_medium: Option<u32>,
    /// The medium each of `delta_lights` is in, by index (`None`, or no entry: vacuum).
    /// (An area light's is its material's `medium_interface`.)
    pub delta_light_media: Vec<Option<u32>>,
    /// Objects kept once and seen through `instances` (pbrt-v4's `ObjectBegin` /
    /// `ObjectInstance`): their triangles are in object space. (Emitting, alpha-cut and
    /// displaced shapes and spheres of an object are flattened into `triangles` and
    /// `spheres` at each instance instead.)
    pub objects: Vec<Object>,
    /// The instances of `objects`, each under its object-to-world transform.
    pub instances: Vec<Instance>,
}

/// An object's triangles, in object space, drawn wherever an `Instance` names it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Object {
    /// The name the file gave it (for messages).
    pub name: String,
    pub triangles: Triangles,
}

/// One object of `Scene::objects` under an invertible object-to-world transform.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    pub object: u32,
    pub object_to_world: Mat4,
}

impl Instance {
    /// Whether the transform mirrors (its determinant is negative): the triangles'
    /// winding turns, and their geometric normals are flipped back (as pbrt-v4 flips a
    /// shape's normal under a transform that swaps handedness).
    pub fn swaps_handedness(&self) -> bool {
        Mat3::from_mat4(self.object_to_world).determinant() < 0.0
    }
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            source: None,
            width: 640,
            height: 480,
            output: None,
            camera: Camera::default(),
            settings: Settings::default(),
            materials: Vec::new(),
            triangles: Triangles::default(),
            spheres: Vec::new(),
            quad_lights: Vec::new(),
            delta_lights: Vec::new(),
            environments: Vec::new(),
            lens: None,
            textures: Vec::new(),
            measured: Vec::new(),
            light_profiles: Vec::new(),
            media: Vec::new(),
            camera_medium: None,
            delta_light_media: Vec::new(),
            objects: Vec::new(),
            instances: Vec::new(),
        }
    }
}

impl Scene {
    /// The triangles the instances draw (each object's, once per instance).
    pub fn instanced_triangle_count(&self) -> u64 {
        self.instances
            .iter()
            .map(|i| self.objects[i.object as usize].triangles.len() as u64)
            .sum()
    }

    /// The scene with its instances copied into the world (the triangles each instance
    /// draws, in instance order after the world's): what the reader made before objects
    /// were kept once, and what an instanced render must agree with. Corners by the
    /// transform, shading normals by its inverse transpose (normalized); under a
    /// mirroring transform a triangle with normals is wound to face them, one without is
    /// flipped back (as pbrt-v4 orients shapes under transforms that swap handedness).
    pub fn flattened(&self) -> Scene {
        let mut s = self.clone();
        s.objects.clear();
        s.instances.clear();
        for i in &self.instances {
            let m = i.object_to_world;
            let normal_matrix = Mat3::from_mat4(m).inverse().transpose();
            let swaps = i.swaps_handedness();
            for t in self.objects[i.object as usize].triangles.all() {
                let mut w = t;
                w.v = t.v.map(|v| m.transform_point3(v));
                w.normals = t
                    .normals
                    .map(|n| n.map(|n| (normal_matrix * n).normalize_or_zero()));
                if swaps {
                    w = if w.normals.is_some() {
                        w.facing_its_normals()
                    } else {
                        w.flipped()
                    };
                }
                s.triangles.push(w);
            }
        }
        s
    }

    /// The triangles stored once: the world's and the objects'.
    pub fn unique_triangle_count(&self) -> u64 {
        self.triangles.len() as u64
            + self
                .objects
                .iter()
                .map(|o| o.triangles.len() as u64)
                .sum::<u64>()
    }
}

impl Scene {
    /// Whether a medium of the scene has a grid whose values satisfy `f`.
    pub fn any_grid(&self, f: impl Fn(&GridValues) -> bool) -> bool {
        self.media
            .iter()
            .any(|m| m.grid.as_deref().is_some_and(|g| f(&g.values)))
    }

    /// Say that the delta lights added since the last call are in `medium`.
    pub fn place_new_delta_lights(&mut self, medium: Option<u32>) {
        self.delta_light_media
            .resize(self.delta_lights.len(), medium);
    }

    /// The medium of delta light `i`.
    pub fn delta_light_medium(&self, i: usize) -> Option<u32> {
        self.delta_light_media.get(i).copied().flatten()
    }
}
