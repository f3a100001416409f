//! The scene on the device: triangles in BVH leaf order, spheres, materials, the
//! emitter table (selection by power) and the uniform scene parameters, with the
//! resources that bind them for a kernel. Integrators set their own fields of the
//! parameters (`Engine::prepare` lets them); nothing here knows one.
use crate::abi::*;
use crate::accel::BvhData;
use crate::gpu::buffer::Buffer;
use crate::gpu::kernels::{Backend, Resource};
use crate::gpu::rayquery::RayQueryScene;
use crate::gpu::scene_data::{DataArray, SceneData};
use crate::gpu::{other_error, Device};
use crate::io::Image;
use crate::scene::{DeltaLight, GridValues, NextEventEstimation, Scene, Texture, UV_MAPPING};
use crate::texture::{
    environment_mean, environment_weights, ByteDecoding, Distribution2D, EnvMapping, Operand,
    Texels as _, TextureImage, Wrap,
};
use anyhow::Result;
use ash::vk;
use glam::{Mat3, Vec2, Vec3};
use std::sync::Arc;

/// The scene's GPU buffers.
pub struct GpuScene {
    /// What `scene_params` holds.
    pub params: SceneParams,
    pub scene_params: Buffer,
    pub spheres: Buffer,
    pub materials: Buffer,
    pub emitters: Buffer,
    pub emitter_cdf: Buffer,
    pub textures: Buffer,
    pub media: Buffer,
    pub instances: Buffer,
    /// Triangles, their attributes, the BVH (none for ray query), texels and medium
    /// grids, in chunks read by address.
    pub data: SceneData,
}

/// The emitter table: every emissive triangle and sphere, point and directional light,
/// with selection probabilities proportional to power.
pub struct EmitterTable {
    pub emitters: Vec<GpuEmitter>,
    /// End of each emitter's range of 32-bit random values (see `pick_emitter`).
    pub cdf: Vec<u32>,
    /// Per triangle and per sphere: index of its emitter, or NO_EMITTER.
    pub triangle_emitter: Vec<u32>,
    pub sphere_emitter: Vec<u32>,
    /// The first infinite light's emitter, or NO_EMITTER; the infinite lights are the
    /// last emitters, in a row.
    pub environment: u32,
    /// The scene's index (`Scene::environments`) of each infinite light's emitter (a
    /// light that emits nothing has none).
    pub environment_sources: Vec<usize>,
}

fn avg(v: Vec3) -> f32 {
    (v.x + v.y + v.z) / 3.0
}

/// Surface area of the unit sphere under the linear map m (a quadrature; only used to
/// weigh emitters by power, never in a pdf).
fn ellipsoid_area(m: Mat3) -> f32 {
    let n = 512;
    let det = m.determinant().abs();
    let inv_t = m.inverse().transpose();
    let mut sum = 0.0;
    for i in 0..n {
        // Fibonacci sphere points.
        let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = i as f32 * 2.399_963;
        let q = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        sum += det * (inv_t * q).length();
    }
    4.0 * std::f32::consts::PI * sum / n as f32
}

pub fn scene_bounds(scene: &Scene) -> (Vec3, f32) {
    // (The triangles a piece per core: a minimum and maximum are the same in any order.)
    let (mut lo, mut hi) =
        crate::accel::map_pieces(&scene.triangles, 1 << 20, crate::accel::threads(), |p| {
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for t in p.iter() {
                for v in t.v {
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            (lo, hi)
        })
        .into_iter()
        .fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), (a, b)| (lo.min(a), hi.max(b)),
        );
    for s in &scene.spheres {
        let b = crate::accel::geometry::sphere_world_bounds(&s.object_to_world);
        lo = lo.min(b.min);
        hi = hi.max(b.max);
    }
    // Instances: their objects' boxes carried to the world.
    let boxes: Vec<crate::accel::geometry::Aabb> = scene
        .objects
        .iter()
        .map(|o| {
            let mut b = crate::accel::geometry::Aabb::empty();
            for t in o.triangles.iter() {
                for v in t.v {
                    b.grow(v);
                }
            }
            b
        })
        .collect();
    for i in &scene.instances {
        let b = &boxes[i.object as usize];
        if !b.is_empty() {
            let w = crate::accel::geometry::transformed_bounds(b, &i.object_to_world);
            lo = lo.min(w.min);
            hi = hi.max(w.max);
        }
    }
    if lo.x > hi.x {
        return (Vec3::ZERO, 1.0);
    }
    let c = (lo + hi) * 0.5;
    (c, ((hi - lo).length() * 0.5).max(1e-3))
}

/// A goniometric or projection light's sampling weights, one per pixel of its image (its
/// mean channel times the solid angle per unit of image area at the pixel's centre, so
/// that directions are drawn in proportion to intensity), and its flux per unit of its
/// colour (the weights' sum over the pixel count: ∫ value dω). None for other lights.
pub fn profile_weights(scene: &Scene, l: &DeltaLight) -> Option<(Vec<f32>, f32)> {
    l.profile_pixel_integral(&scene.light_profiles, |c| {
        c.iter().sum::<f32>() / c.len() as f32
    })
}

pub fn emitter_table(scene: &Scene) -> EmitterTable {
    let order: Vec<u32> = (0..scene.triangles.len() as u32).collect();
    emitter_table_in(scene, &order, || scene_bounds(scene).1)
}

/// [`emitter_table`] with the world's triangles in `order` (the old index of each: their
/// records' order, `BvhData::triangle_order`); triangle indices are positions in it.
/// `radius` gives the scene's bounding radius ([`scene_bounds`]), asked for only where
/// a light outside the scene needs it.
pub fn emitter_table_in(scene: &Scene, order: &[u32], radius: impl Fn() -> f32) -> EmitterTable {
    let pi = std::f32::consts::PI;
    let mut emitters = Vec::new();
    let mut power = Vec::new();
    let mut triangle_emitter = vec![NO_EMITTER; scene.triangles.len()];
    let mut sphere_emitter = vec![NO_EMITTER; scene.spheres.len()];
    // (A walk in the BVH's order reads the triangles scattered: taken only where one
    // emits, found by a walk in their own order, a piece per core.)
    let emissive: Vec<bool> = scene.materials.iter().map(|m| m.is_emissive()).collect();
    let any = crate::accel::map_pieces(&scene.triangles, 1 << 20, crate::accel::threads(), |p| {
        p.iter().any(|t| emissive[t.material as usize])
    })
    .contains(&true);
    let triangles = order
        .iter()
        .take(if any { order.len() } else { 0 })
        .map(|&i| (i as usize, &scene.triangles[i as usize]));
    for (i, (j, t)) in triangles.enumerate() {
        let m = &scene.materials[t.material as usize];
        if !m.is_emissive() {
            continue;
        }
        let area = 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
        if area <= 0.0 {
            continue;
        }
        triangle_emitter[i] = emitters.len() as u32;
        let sides = if m.two_sided_emission { 2.0 } else { 1.0 };
        power.push(avg(m.emission) * area * pi * sides);
        emitters.push(GpuEmitter {
            p0: t.v[0].extend(area).to_array(),
            p1: t.v[1].extend(0.0).to_array(),
            p2: t.v[2].extend(0.0).to_array(),
            radiance: m.emission.extend(0.0).to_array(),
            info: [
                EMITTER_TRIANGLE,
                i as u32,
                m.two_sided_emission as u32,
                // (pbrt-v4's invisible area light: alpha 0, cut out of every ray.)
                if scene
                    .triangles
                    .alpha(j)
                    .is_some_and(crate::scene::Alpha::is_zero)
                {
                    EMITTER_HIDDEN
                } else {
                    0
                },
            ],
        });
    }
    for (i, s) in scene.spheres.iter().enumerate() {
        let m = &scene.materials[s.material as usize];
        if !m.is_emissive() {
            continue;
        }
        let lin = Mat3::from_mat4(s.object_to_world);
        let det = lin.determinant().abs();
        if det == 0.0 {
            continue;
        }
        sphere_emitter[i] = emitters.len() as u32;
        power.push(avg(m.emission) * ellipsoid_area(lin) * pi);
        emitters.push(GpuEmitter {
            p0: [0.0; 4],
            p1: [det, 0.0, 0.0, 0.0],
            p2: [0.0; 4],
            radiance: m.emission.extend(0.0).to_array(),
            info: [
                EMITTER_SPHERE,
                i as u32,
                m.two_sided_emission as u32,
                // (pbrt-v4's invisible area light: in no acceleration structure.)
                if s.hidden { EMITTER_HIDDEN } else { 0 },
            ],
        });
    }
    // The scene's radius, for the lights outside it (asked for once, where one is).
    let bounds = std::cell::OnceCell::new();
    let radius = || *bounds.get_or_init(&radius);
    // Delta lights that emit nothing are left out: they could never contribute.
    for (index, l) in scene
        .delta_lights
        .iter()
        .enumerate()
        .filter(|(_, l)| match l {
            DeltaLight::Point { intensity, .. } => avg(*intensity) > 0.0,
            DeltaLight::Directional { radiance, .. } => avg(*radiance) > 0.0,
            DeltaLight::Spot { intensity, .. } => avg(*intensity) > 0.0,
            DeltaLight::Goniometric { intensity, .. } => avg(*intensity) > 0.0,
            DeltaLight::Projection { scale, .. } => avg(*scale) > 0.0,
        })
    {
        // (info.w's high bits: the medium code of the light's place.)
        let medium = crate::scene::MediumInterface::code(scene.delta_light_medium(index)) << 16;
        match *l {
            DeltaLight::Point {
                position,
                intensity,
            } => {
                power.push(4.0 * pi * avg(intensity));
                emitters.push(GpuEmitter {
                    p0: position.extend(0.0).to_array(),
                    radiance: intensity.extend(0.0).to_array(),
                    info: [EMITTER_POINT, 0, 0, medium],
                    ..Default::default()
                });
            }
            DeltaLight::Spot {
                position,
                direction,
                intensity,
                cos_falloff_start,
                cos_falloff_end,
            } => {
                // pbrt-v4's SpotLight::Phi: the full cone inside the falloff, half of
                // the falloff band.
                let solid_angle = 2.0
                    * pi
                    * ((1.0 - cos_falloff_start) + (cos_falloff_start - cos_falloff_end) / 2.0);
                power.push(avg(intensity) * solid_angle);
                emitters.push(GpuEmitter {
                    p0: position.extend(0.0).to_array(),
                    p1: direction.extend(cos_falloff_end).to_array(),
                    p2: [cos_falloff_start, 0.0, 0.0, 0.0],
                    radiance: intensity.extend(0.0).to_array(),
                    info: [EMITTER_SPOT, 0, 0, medium],
                });
            }
            DeltaLight::Goniometric {
                position,
                light_from_world: m,
                intensity: colour,
                profile,
            }
            | DeltaLight::Projection {
                position,
                screen_from_world: m,
                scale: colour,
                profile,
            } => {
                let image = &scene.light_profiles[profile as usize];
                let (_, flux) = profile_weights(scene, l).expect("a profiled light");
                power.push(avg(colour) * flux);
                let (r0, r1, r2) = (m.row(0), m.row(1), m.row(2));
                let kind = if matches!(l, DeltaLight::Goniometric { .. }) {
                    EMITTER_GONIOMETRIC
                } else {
                    EMITTER_PROJECTION
                };
                emitters.push(GpuEmitter {
                    p0: position.extend(r2.x).to_array(),
                    p1: r0.extend(r2.y).to_array(),
                    p2: r1.extend(r2.z).to_array(),
                    radiance: colour.extend(0.0).to_array(),
                    // (info.y: the image's index in Scene::light_profiles, made its first
                    // texel by GpuScene::new.)
                    info: [kind, profile, image.width | image.height << 16, medium],
                });
            }
            DeltaLight::Directional {
                direction,
                radiance,
            } => {
                power.push(pi * radius() * radius() * avg(radiance));
                emitters.push(GpuEmitter {
                    p0: direction.normalize().extend(0.0).to_array(),
                    radiance: radiance.extend(0.0).to_array(),
                    // (Its subpaths start outside the scene, in vacuum, as pbrt-v4's
                    // distant light's: the medium where it is made is not theirs.)
                    info: [EMITTER_DIRECTIONAL, 0, 0, 0],
                    ..Default::default()
                });
            }
        }
    }
    // The infinite lights (pbrt-v4's Phi: 4π · πR² · the mean radiance over the sphere)
    // come last, in a row. Their map, its distribution and their portal are filled in by
    // `GpuScene::new` (`TextureData::environments`).
    let mut environment = NO_EMITTER;
    let mut environment_sources = Vec::new();
    for (i, env) in scene.environments.iter().enumerate() {
        let mean = match &env.map {
            None => env.radiance,
            Some(map) => env.radiance * environment_mean(&map.image, map.mapping),
        };
        if avg(mean) > 0.0 {
            if environment == NO_EMITTER {
                environment = emitters.len() as u32;
            }
            environment_sources.push(i);
            power.push(4.0 * pi * pi * radius() * radius() * avg(mean));
            let (to_world, mapping) = env
                .map
                .as_ref()
                .map_or((Mat3::IDENTITY, ENV_MAPPING_LATLONG), |m| {
                    (m.to_world, m.mapping.code())
                });
            emitters.push(GpuEmitter {
                p0: to_world.col(0).extend(0.0).to_array(),
                p1: to_world.col(1).extend(0.0).to_array(),
                p2: to_world
                    .col(2)
                    .extend(f32::from_bits(NO_TEXTURE))
                    .to_array(),
                radiance: env.radiance.extend(0.0).to_array(),
                info: [EMITTER_INFINITE, NO_TEXTURE, mapping, 0],
            });
        }
    }
    let total: f64 = power.iter().map(|&p| p.max(0.0) as f64).sum();
    let n = emitters.len();
    // Each emitter owns a range of the 2^32 values of a random integer, of a length
    // proportional to its power; its pick pdf is its range's exact share. (A float CDF
    // picked with a 24-bit uniform would be off by up to 2^-24 absolute: 1% for each of
    // 10^5 equal emitters, and emitters below that never picked though weighted.)
    const RANGE: f64 = 4294967296.0;
    let mut cdf = Vec::with_capacity(n);
    let mut acc = 0.0f64;
    let mut prev_end = 0u64;
    for (i, (e, &p)) in emitters.iter_mut().zip(&power).enumerate() {
        acc += if total > 0.0 {
            p.max(0.0) as f64 / total
        } else {
            1.0 / n as f64
        };
        let end = if i + 1 == n {
            1u64 << 32
        } else {
            ((acc * RANGE).round() as u64).clamp(prev_end, 1u64 << 32)
        };
        e.radiance[3] = ((end - prev_end) as f64 / RANGE) as f32;
        // The kernel never reads the last entry (it takes the last emitter when x is
        // past every other end).
        cdf.push(end.min(u32::MAX as u64) as u32);
        prev_end = end;
    }
    EmitterTable {
        emitters,
        cdf,
        triangle_emitter,
        sphere_emitter,
        environment,
        environment_sources,
    }
}

/// The textures, their texels and the environment map's sampling distribution, as the
/// kernels read them (abi.h `GpuTexture`, the texel buffer of floats).
pub struct TextureData {
    pub textures: Vec<GpuTexture>,
    /// The texel floats, then (not held here: `texel_words`) each of `byte_images`' texels
    /// as one word.
    pub texels: Vec<f32>,
    /// The 8-bit images, in the order their words follow `texels`.
    pub byte_images: Vec<Arc<TextureImage>>,
    /// Per infinite light (`Scene::environments`' order): its map's texture and the
    /// first floats of the map's marginal and conditional CDFs in `texels` (NO_TEXTURE,
    /// 0, 0 for a constant light), and the first of its portal's nine floats (corner p0,
    /// edges p1 − p0 and p3 − p0; NO_TEXTURE: none).
    pub environments: Vec<[u32; 4]>,
    /// The texel index of each measured material's tables (`Scene::measured`'s order,
    /// `MeasuredBsdf::pack`'s layout).
    pub measured: Vec<u32>,
    /// The texel index of each light profile (`Scene::light_profiles`' order): its values,
    /// then its distribution's marginal CDF (height + 1) and conditional CDFs (height ×
    /// (width + 1)); 0 for a profile no light shows.
    pub light_profiles: Vec<u32>,
    /// A realistic camera's lens system's first float (`LensSystem::pack`).
    pub lens: Option<u32>,
    /// The noise table's first float, where a texture or a cloud medium needs it.
    pub noise: Option<u32>,
    /// The blackbody table's first float (src/media.rs's `blackbody_table`), where a
    /// medium has a temperature.
    pub blackbody: Option<u32>,
}

impl TextureData {
    /// The words of the kernels' texel data: `texels`, then the 8-bit images' texels,
    /// each R | G << 8 | B << 16 as a float's bits (texture.glsl `texel`).
    pub fn texel_words(&self) -> impl Iterator<Item = f32> + '_ {
        let bytes = self
            .byte_images
            .iter()
            .flat_map(|image| image.levels())
            .flat_map(|level| match level {
                TextureImage::Bytes { texels, .. } => texels.iter(),
                _ => [].iter(),
            });
        self.texels.iter().copied().chain(
            bytes.map(|&[r, g, b]| f32::from_bits(r as u32 | (g as u32) << 8 | (b as u32) << 16)),
        )
    }

    /// A writer of `texel_words` into byte slices: `write(at, out)` fills `out` with the
    /// words from byte `at` on (both whole words), in any order and from any thread (the
    /// upload's pieces); a piece (the floats, an 8-bit level) at a time, the floats copied
    /// whole.
    pub fn texel_writer(&self) -> impl Fn(u64, &mut [u8]) + Send + Sync + '_ {
        let mut pieces: Vec<TexelPiece<'_>> = vec![TexelPiece::Floats(&self.texels)];
        for level in self.byte_images.iter().flat_map(|image| image.levels()) {
            if let TextureImage::Bytes { texels, .. } = level {
                pieces.push(TexelPiece::Bytes(texels));
            }
        }
        // Each piece's first word.
        let starts: Vec<usize> = std::iter::once(0)
            .chain(pieces.iter().scan(0, |end, p| {
                *end += p.len();
                Some(*end)
            }))
            .collect();
        move |at: u64, mut out: &mut [u8]| {
            assert!(at % 4 == 0 && out.len() % 4 == 0, "texel words are whole");
            let word = (at / 4) as usize;
            // The last piece starting at or before `word` (a non-empty one, or the end).
            let mut piece = starts.partition_point(|&s| s <= word) - 1;
            let mut at = word - starts[piece];
            while !out.is_empty() {
                let p = pieces.get(piece).expect("as many words as texels");
                let n = (p.len() - at).min(out.len() / 4);
                let (head, rest) = out.split_at_mut(4 * n);
                match p {
                    TexelPiece::Floats(f) => {
                        head.copy_from_slice(bytemuck::cast_slice(&f[at..at + n]))
                    }
                    TexelPiece::Bytes(b) => {
                        for (word, &[r, g, b]) in head.chunks_exact_mut(4).zip(&b[at..at + n]) {
                            let w = r as u32 | (g as u32) << 8 | (b as u32) << 16;
                            word.copy_from_slice(&w.to_ne_bytes());
                        }
                    }
                }
                out = rest;
                at += n;
                if at == p.len() {
                    (piece, at) = (piece + 1, 0);
                }
            }
        }
    }

    /// How many words `texel_words` gives.
    pub fn texel_count(&self) -> u64 {
        let words: u64 = self
            .byte_images
            .iter()
            .flat_map(|i| i.levels())
            .map(|l| {
                let (w, h) = l.size();
                w as u64 * h as u64
            })
            .sum();
        self.texels.len() as u64 + words
    }
}

/// A run of the texel words: floats as they are, or an 8-bit level's texels.
enum TexelPiece<'a> {
    Floats(&'a [f32]),
    Bytes(&'a [[u8; 3]]),
}

impl TexelPiece<'_> {
    fn len(&self) -> usize {
        match self {
            TexelPiece::Floats(f) => f.len(),
            TexelPiece::Bytes(b) => b.len(),
        }
    }
}

fn push_image(texels: &mut Vec<f32>, image: &Image) -> u32 {
    let first = texels.len() as u32;
    texels.extend(image.pixels.iter().flatten());
    first
}

/// The record of an image or checkerboard texture (its texels appended to `texels`).
/// Texels: the floats and, per image already in them, its first float and its
/// `GpuTexture.flags.w` (an image that several textures read is stored once).
#[derive(Default)]
struct Texels {
    floats: Vec<f32>,
    /// The 8-bit images, their words after every float (the record's first float is
    /// counted from there until `texture_data` adds the floats' count), and their words.
    bytes: Vec<Arc<TextureImage>>,
    words: u32,
    first: std::collections::HashMap<*const TextureImage, (u32, u32)>,
    /// Where each byte table is ([`ByteDecoding::table`]), once an
    /// 8-bit image needs it.
    tables: std::collections::HashMap<ByteDecoding, u32>,
    /// Where the noise table is (src/noise.rs), once a texture needs it.
    noise: Option<u32>,
}

impl Texels {
    /// An image's first float and its record's `flags.w`: 0 for float RGB texels (three
    /// floats each), else one word per texel (R | G << 8 | B << 16, stored as the float of
    /// those bits) and the first float of the 256-entry table its bytes are read through,
    /// plus 1 (texture.glsl `texel`).
    fn image(&mut self, image: &Arc<TextureImage>) -> (u32, u32) {
        if let Some(&found) = self.first.get(&Arc::as_ptr(image)) {
            return found;
        }
        // (A pyramid's levels follow one another, all of the base's kind.)
        let levels = image.levels();
        let found = match &levels[0] {
            TextureImage::Bytes { decoding, .. } => {
                let table = *self.tables.entry(*decoding).or_insert_with(|| {
                    let first = self.floats.len() as u32;
                    self.floats.extend(decoding.table());
                    first
                });
                let first = self.words;
                for l in levels {
                    let (w, h) = l.size();
                    self.words += w * h;
                }
                self.bytes.push(image.clone());
                (first, table + 1)
            }
            _ => {
                let first = self.floats.len() as u32;
                for l in levels {
                    match l {
                        TextureImage::Float(l) => {
                            push_image(&mut self.floats, l);
                        }
                        _ => unreachable!("a pyramid's levels are of one kind"),
                    }
                }
                (first, 0)
            }
        };
        self.first.insert(Arc::as_ptr(image), found);
        found
    }

    /// The noise table's first float (stored once).
    fn noise_table(&mut self) -> u32 {
        *self.noise.get_or_insert_with(|| {
            let first = self.floats.len() as u32;
            self.floats.extend(crate::noise::noise_table());
            first
        })
    }
}

fn leaf_record(t: &Texture, texels: &mut Texels) -> GpuTexture {
    let mut record = match t {
        Texture::Image {
            image,
            scale,
            mapping,
            wrap,
            filter,
            max_anisotropy,
            ..
        } => {
            let (first, bytes) = texels.image(image);
            let (width, height) = image.size();
            GpuTexture {
                info: [TEXTURE_IMAGE, first, width, height],
                flags: [
                    match wrap {
                        Wrap::Repeat => TEXTURE_WRAP_REPEAT,
                        Wrap::Clamp => TEXTURE_WRAP_CLAMP,
                        Wrap::Black => TEXTURE_WRAP_BLACK,
                    },
                    0,
                    0,
                    bytes,
                ],
                scale: scale.extend(0.0).to_array(),
                // (x: the filter; y: the MIP levels; z: EWA's longest footprint for its
                // width.)
                other: [
                    filter.code() as f32,
                    image.levels().len() as f32,
                    *max_anisotropy,
                    0.0,
                ],
                mapping: *mapping,
                ..GpuTexture::default()
            }
        }
        Texture::Checkerboard {
            even, odd, mapping, ..
        } => GpuTexture {
            info: [TEXTURE_CHECKERBOARD, 0, 0, 0],
            scale: even.extend(0.0).to_array(),
            other: odd.extend(0.0).to_array(),
            mapping: *mapping,
            ..GpuTexture::default()
        },
        Texture::Noise {
            kind,
            octaves,
            omega,
            scale,
            variation,
            ..
        } => GpuTexture {
            info: [TEXTURE_NOISE, texels.noise_table(), kind.code(), *octaves],
            mapping: [*omega, *scale, *variation, 0.0],
            ..GpuTexture::default()
        },
        Texture::Dots {
            inside,
            outside,
            mapping,
            ..
        } => GpuTexture {
            info: [TEXTURE_DOTS, texels.noise_table(), 0, 0],
            scale: inside.extend(0.0).to_array(),
            other: outside.extend(0.0).to_array(),
            mapping: *mapping,
            ..GpuTexture::default()
        },
        Texture::Bilerp { v, mapping, .. } => {
            let first = texels.floats.len() as u32;
            texels.floats.extend(v.iter().flat_map(|c| c.to_array()));
            GpuTexture {
                info: [TEXTURE_BILERP, first, 0, 0],
                mapping: *mapping,
                ..GpuTexture::default()
            }
        }
        Texture::Scale { .. } | Texture::Mix { .. } | Texture::DirectionMix { .. } => {
            unreachable!("not a leaf")
        }
    };
    let (kind, [proj0, proj1, proj2]) = t.projection().record();
    record.flags[2] = kind;
    (record.proj0, record.proj1, record.proj2) = (proj0, proj1, proj2);
    record
}

/// Appends the program of `t` (texture.glsl: its tree in post-order, each record into
/// the next register) to `program`; returns the register of its value.
fn push_program(t: &Texture, program: &mut Vec<GpuTexture>, texels: &mut Texels) -> u32 {
    if !t.is_graph() {
        program.push(leaf_record(t, texels));
        return program.len() as u32 - 1;
    }
    let mut record = GpuTexture {
        info: [
            match t {
                Texture::Scale { .. } => TEXTURE_SCALE,
                Texture::DirectionMix { .. } => TEXTURE_DIRECTION_MIX,
                _ => TEXTURE_MIX,
            },
            0,
            0,
            0,
        ],
        flags: [NO_TEXTURE; 4],
        ..GpuTexture::default()
    };
    record.flags[3] = 0;
    if let Texture::DirectionMix { dir, .. } = t {
        record.mapping = dir.extend(0.0).to_array();
    }
    for (slot, o) in t.operands().into_iter().enumerate() {
        match o {
            Operand::Texture(c) => record.flags[slot] = push_program(c, program, texels),
            Operand::Const(c) => match slot {
                0 => record.scale = c.extend(0.0).to_array(),
                1 => record.other = c.extend(0.0).to_array(),
                _ => record.mapping[0] = c.x,
            },
        }
    }
    program.push(record);
    program.len() as u32 - 1
}

pub fn texture_data(scene: &Scene) -> TextureData {
    let mut textures = Vec::new();
    let mut texels = Texels::default();
    // Textures made of textures get their programs after every scene texture.
    let mut programs = Vec::new();
    for t in &scene.textures {
        if t.is_graph() {
            programs.push((textures.len(), t));
            textures.push(GpuTexture::default());
        } else {
            textures.push(leaf_record(t, &mut texels));
        }
    }
    for (index, t) in programs {
        let mut program = Vec::new();
        push_program(t, &mut program, &mut texels);
        assert!(program.len() <= MAX_TEXTURE_PROGRAM as usize);
        textures[index] = GpuTexture {
            info: [
                TEXTURE_GRAPH,
                textures.len() as u32,
                program.len() as u32,
                0,
            ],
            ..GpuTexture::default()
        };
        textures.extend(program);
    }
    let mut environments = Vec::new();
    for env in &scene.environments {
        let portal = match env.portal {
            None => NO_TEXTURE,
            Some(q) => {
                let first = texels.floats.len() as u32;
                for v in [q[0], q[1] - q[0], q[3] - q[0]] {
                    texels.floats.extend(v.to_array());
                }
                first
            }
        };
        let Some(map) = &env.map else {
            environments.push([NO_TEXTURE, 0, 0, portal]);
            continue;
        };
        let image = &map.image;
        let index = textures.len() as u32;
        textures.push(GpuTexture {
            info: [
                TEXTURE_IMAGE,
                push_image(&mut texels.floats, image),
                image.width,
                image.height,
            ],
            flags: [
                match map.mapping {
                    EnvMapping::LatLong => TEXTURE_WRAP_REPEAT_U,
                    EnvMapping::EqualArea => TEXTURE_WRAP_CLAMP,
                },
                1,
                0,
                0,
            ],
            scale: [1.0; 4],
            other: [0.0; 4],
            mapping: UV_MAPPING,
            ..GpuTexture::default()
        });
        let weights = environment_weights(image, map.mapping);
        let d = Distribution2D::new(&weights, image.width as usize, image.height as usize);
        let marginal = texels.floats.len() as u32;
        texels.floats.extend(&d.marginal);
        let conditional = texels.floats.len() as u32;
        texels.floats.extend(&d.conditional);
        environments.push([index, marginal, conditional, portal]);
    }
    let measured = scene
        .measured
        .iter()
        .map(|m| {
            let first = texels.floats.len() as u32;
            texels.floats.extend(m.pack());
            first
        })
        .collect();
    // Each goniometric or projection light's image, then its sampling distribution
    // (marginal and conditional CDFs), from the first light that shows it.
    let mut light_profiles = vec![None; scene.light_profiles.len()];
    for l in &scene.delta_lights {
        let Some((weights, _)) = profile_weights(scene, l) else {
            continue;
        };
        let (DeltaLight::Goniometric { profile, .. } | DeltaLight::Projection { profile, .. }) = l
        else {
            continue;
        };
        let slot = &mut light_profiles[*profile as usize];
        if slot.is_some() {
            continue;
        }
        let image = &scene.light_profiles[*profile as usize];
        let first = texels.floats.len() as u32;
        texels.floats.extend(&image.values);
        let d = Distribution2D::new(&weights, image.width as usize, image.height as usize);
        texels.floats.extend(&d.marginal);
        texels.floats.extend(&d.conditional);
        *slot = Some(first);
    }
    // (Cloud media read the noise table too.)
    let noise = scene
        .any_grid(|g| matches!(g, GridValues::Cloud { .. }))
        .then(|| texels.noise_table());
    let blackbody = scene.any_grid(GridValues::has_temperature).then(|| {
        let first = texels.floats.len() as u32;
        texels
            .floats
            .extend_from_slice(crate::media::blackbody_table());
        first
    });
    let lens = scene.lens.as_ref().map(|l| {
        let first = texels.floats.len() as u32;
        texels
            .floats
            .extend(l.for_image(scene.width, scene.height).pack());
        first
    });
    // The 8-bit images' words follow the floats.
    let base = texels.floats.len() as u32;
    for r in &mut textures {
        if r.info[0] == TEXTURE_IMAGE && r.flags[3] != 0 {
            r.info[1] += base;
        }
    }
    TextureData {
        lens,
        noise,
        blackbody,
        textures,
        texels: texels.floats,
        byte_images: texels.bytes,
        environments,
        measured,
        light_profiles: light_profiles.into_iter().map(|x| x.unwrap_or(0)).collect(),
    }
}

/// The materials as the kernels read them: their records, a measured material's with the
/// texel index of its tables (`TextureData::measured`) where `Material::record` put its
/// index into `Scene::measured`.
pub fn material_records(scene: &Scene, textures: &TextureData) -> Vec<GpuMaterial> {
    scene
        .materials
        .iter()
        .map(|m| {
            let mut record = m.record();
            if let (BsdfKind::Measured, Some(i)) = (m.bsdf, m.measured) {
                record.base[0] = f32::from_bits(textures.measured[i as usize]);
            }
            record
        })
        .collect()
}

/// The media as the kernels read them (abi.h `GpuMedium`; one unused record for a scene
/// without media, so that the buffer is never empty) and the grid media's floats
/// (DATA_GRIDS: each grid's density, Le-scale and majorant grids; the
/// majorants per unit length, times the largest channel's extinction per unit density).
pub fn medium_records(scene: &Scene, textures: &TextureData) -> (Vec<GpuMedium>, Vec<f32>) {
    medium_data(
        &scene.media,
        textures.noise.unwrap_or(0),
        textures.blackbody.unwrap_or(0),
    )
}

/// `medium_records` of a list of media (the medium probe's), the noise table (clouds') at
/// texel `noise`, the blackbody table (temperatures') at texel `blackbody`.
pub fn medium_data(
    media: &[crate::scene::Medium],
    noise: u32,
    blackbody: u32,
) -> (Vec<GpuMedium>, Vec<f32>) {
    let mut floats = Vec::new();
    let mut records: Vec<GpuMedium> = media
        .iter()
        .map(|m| {
            let mut r = GpuMedium {
                sigma_a: m.sigma_a.extend(m.g).to_array(),
                sigma_s: m.sigma_s.extend(0.0).to_array(),
                emission: m.emission.extend(0.0).to_array(),
                info: [MEDIUM_HOMOGENEOUS, 0, 0, 0],
                ..Default::default()
            };
            if let Some(g) = &m.grid {
                let first = |floats: &Vec<f32>| floats.len() as u32;
                let u = g.unit_from_world.transpose();
                r.unit_x = u.x_axis.to_array();
                r.unit_y = u.y_axis.to_array();
                r.unit_z = u.z_axis.to_array();
                match &g.values {
                    GridValues::Density {
                        density,
                        le_scale,
                        temperature,
                    } => {
                        let d = first(&floats);
                        floats.extend_from_slice(&density.values);
                        let le = first(&floats);
                        floats.extend_from_slice(&le_scale.values);
                        let t = match temperature {
                            None => crate::abi::MEDIUM_NO_GRID,
                            Some(t) => {
                                r.sigma_s[3] = t.offset;
                                r.emission[3] = t.scale;
                                let at = first(&floats);
                                floats.extend_from_slice(&t.grid.values);
                                at
                            }
                        };
                        r.info = [crate::abi::MEDIUM_UNIFORMGRID, d, le, 0];
                        r.density_res = [density.res[0], density.res[1], density.res[2], t];
                        r.le_res = [le_scale.res[0], le_scale.res[1], le_scale.res[2], blackbody];
                    }
                    GridValues::NanoVdb {
                        density,
                        temperature,
                    } => {
                        let d = sparse_grid(&mut floats, density);
                        let t = match temperature {
                            None => crate::abi::MEDIUM_NO_GRID,
                            Some((t, offset, scale)) => {
                                r.sigma_s[3] = *offset;
                                r.emission[3] = *scale;
                                sparse_grid(&mut floats, t)
                            }
                        };
                        r.info = [crate::abi::MEDIUM_NANOVDB, d, t, 0];
                        r.le_res = [0, 0, 0, blackbody];
                    }
                    GridValues::Cloud {
                        density,
                        wispiness,
                        frequency,
                        p0,
                        extent,
                    } => {
                        let b = |v: Vec3, w: f32| [v.x, v.y, v.z, w].map(f32::to_bits);
                        r.info = [crate::abi::MEDIUM_CLOUD, noise, frequency.to_bits(), 0];
                        r.density_res = b(*p0, *density);
                        r.le_res = b(*extent, *wispiness);
                    }
                    GridValues::Rgb {
                        sigma_a,
                        sigma_s,
                        le,
                    } => {
                        let mut rgb = |grid: &Option<crate::scene::SampledGrid<Vec3>>| match grid {
                            None => (crate::abi::MEDIUM_NO_GRID, [0; 3]),
                            Some(grid) => {
                                let at = first(&floats);
                                floats.extend(grid.values.iter().flat_map(|v| v.to_array()));
                                (at, grid.res)
                            }
                        };
                        let (a, a_res) = rgb(sigma_a);
                        let (s, s_res) = rgb(sigma_s);
                        let (l, l_res) = rgb(le);
                        let res = if a == crate::abi::MEDIUM_NO_GRID {
                            s_res
                        } else {
                            a_res
                        };
                        r.info = [crate::abi::MEDIUM_RGBGRID, a, l, 0];
                        r.density_res = [res[0], res[1], res[2], s];
                        r.le_res = [l_res[0], l_res[1], l_res[2], 0];
                    }
                }
                r.info[3] = first(&floats);
                let scale = crate::media::majorant_scale(m);
                floats.extend(g.majorants.iter().map(|v| v * scale));
            }
            r
        })
        .collect();
    if records.is_empty() {
        records.push(GpuMedium::default());
    }
    if floats.is_empty() {
        floats.push(0.0);
    }
    (records, floats)
}

/// A NanoVDB grid's header, brick table and values (abi.h) at the end of `floats`: the
/// header's first float.
fn sparse_grid(floats: &mut Vec<f32>, g: &crate::scene::SparseGrid) -> u32 {
    let at = floats.len() as u32;
    let m = g.index_from_unit.transpose();
    for row in [m.x_axis, m.y_axis, m.z_axis] {
        floats.extend(row.to_array());
    }
    let b = &g.bricks;
    let table = at + 20;
    let values = table + b.table.len() as u32;
    let words = [
        b.origin.x as u32,
        b.origin.y as u32,
        b.origin.z as u32,
        b.dims.x,
        b.dims.y,
        b.dims.z,
        table,
        values,
    ];
    floats.extend(words.map(f32::from_bits));
    floats.extend(b.table.iter().map(|&w| f32::from_bits(w)));
    floats.extend_from_slice(&b.values);
    at
}

/// Triangle `i` of `list`'s texture-coordinate record, naming its shading record `shading`
/// (NO_ATTRIBUTES for none): made for a triangle with any attributes (texture coordinates,
/// shading normals or alpha; its triangle record's index NO_ATTRIBUTES without), pbrt's
/// (0,0), (1,0), (1,1) where it has none of its own. The records are in the triangles'
/// order (the world's, then each object's), one for each that has attributes.
pub fn triangle_uv(list: &crate::scene::Triangles, i: usize, shading: u32) -> GpuTriangleUv {
    let uv = list.uv(i);
    let normals = list.normals(i).is_some();
    GpuTriangleUv {
        uv01: [uv[0].x, uv[0].y, uv[1].x, uv[1].y],
        uv2: [
            uv[2].x,
            uv[2].y,
            normals as u32 as f32,
            f32::from_bits(shading),
        ],
    }
}

/// Triangle `i` of `list`'s shading record (its shading normals, zero without, and its
/// alpha): none for one with neither. In the triangles' order, one for each that has one.
pub fn triangle_shading(list: &crate::scene::Triangles, i: usize) -> Option<GpuTriangleShading> {
    if !list[i].has_shading() {
        return None;
    }
    let n = list.normals(i).unwrap_or([Vec3::ZERO; 3]);
    let (alpha_kind, alpha_value) = match list.alpha(i) {
        None => (crate::abi::ALPHA_NONE, 0.0),
        Some(crate::scene::Alpha::Constant(a)) => (crate::abi::ALPHA_CONSTANT, a),
        Some(crate::scene::Alpha::Texture(i)) => (crate::abi::ALPHA_TEXTURE, f32::from_bits(i)),
    };
    Some(GpuTriangleShading {
        n0: n[0].extend(alpha_kind as f32).to_array(),
        n1: n[1].extend(alpha_value).to_array(),
        n2: n[2].extend(0.0).to_array(),
    })
}

/// CPU mirror of lights.glsl's `pick_emitter`: the first i with x < cdf[i], else the
/// last emitter.
pub fn pick_emitter(cdf: &[u32], x: u32) -> usize {
    let (mut lo, mut hi) = (0, cdf.len() - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if x < cdf[mid] {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    lo
}

/// The camera ray through the film position `film` in [0,1)² ((0,0) the top-left
/// corner) from the lens point for `u_lens`: origin and unit direction (camera.glsl's
/// `camera_ray`, mirrored for the tests).
pub fn camera_ray(p: &SceneParams, film: Vec2, u_lens: Vec2) -> (Vec3, Vec3) {
    let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    let w = p.cam_window;
    let sx = w[0] + (w[1] - w[0]) * film.x;
    let sy = w[3] + (w[2] - w[3]) * film.y;
    let (eye, right, up) = (v(p.cam_eye), v(p.cam_right), v(p.cam_up));
    let dir = v(p.cam_forward) + sx * right + sy * up;
    if p.lens_radius <= 0.0 {
        return (eye, dir.normalize());
    }
    let focus = eye + p.focal_distance * dir;
    let d = p.lens_radius * crate::bsdf::sampling::sample_uniform_disk_concentric(u_lens);
    let o = eye + d.x * right + d.y * up;
    (o, (focus - o).normalize())
}

/// The pixel footprint (dp/dx, dp/dy) at the surface point `point` with unit geometric
/// normal `n` (geometry.glsl's `surface_footprint`, mirrored): where the camera rays
/// through the pixels beside the point's film position meet its tangent plane, less the
/// point, times 1/8; zero where undefined.
pub fn surface_footprint(p: &SceneParams, point: Vec3, n: Vec3) -> (Vec3, Vec3) {
    let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    let to = point - v(p.cam_eye);
    let z = to.dot(v(p.cam_forward));
    let k = if z > 0.0 { z } else { to.length() };
    let w = p.cam_window;
    let sx = (w[1] - w[0]) / p.width as f32;
    let sy = (w[3] - w[2]) / p.height as f32;
    let rx = to + (k * sx) * v(p.cam_right);
    let ry = to - (k * sy) * v(p.cam_up);
    let pn = n.dot(to);
    let (ax, ay) = (n.dot(rx), n.dot(ry));
    let dpdx = if ax != 0.0 {
        0.125 * ((pn / ax) * rx - to)
    } else {
        Vec3::ZERO
    };
    let dpdy = if ay != 0.0 {
        0.125 * ((pn / ay) * ry - to)
    } else {
        Vec3::ZERO
    };
    if dpdx.is_finite() && dpdy.is_finite() {
        (dpdx, dpdy)
    } else {
        (Vec3::ZERO, Vec3::ZERO)
    }
}

/// The scene's parameters for a render with `seed`: the camera, bounds, counts and the
/// settings every integrator reads (`emitter_count` is filled in by `GpuScene::new`). `max_depth` is the scene's (0 for -1, with
/// `unbounded` set); integrators adjust their own fields before upload.
pub fn scene_params(scene: &Scene, seed: u32) -> SceneParams {
    let c = &scene.camera;
    let forward = (c.look_at - c.eye).normalize();
    let unmirrored_right = forward.cross(c.up).normalize();
    let up = unmirrored_right.cross(forward);
    // A mirrored camera (pbrt's left-handed one) turns the image's right around.
    let right = if c.mirror {
        -unmirrored_right
    } else {
        unmirrored_right
    };
    let s = &scene.settings;
    let (center, radius) = scene_bounds(scene);
    SceneParams {
        cam_eye: c.eye.extend(0.0).to_array(),
        cam_right: right.extend(0.0).to_array(),
        cam_up: up.extend(0.0).to_array(),
        cam_forward: forward.extend(0.0).to_array(),
        bounds: center.extend(radius).to_array(),
        width: scene.width,
        height: scene.height,
        triangle_count: (scene.triangles.len() as u64 + scene.instanced_triangle_count())
            .min(u32::MAX as u64) as u32,
        sphere_count: scene.spheres.len() as u32,
        emitter_count: 0,
        max_depth: s.max_depth.max(0) as u32,
        unbounded: (s.max_depth < 0) as u32,
        spp: s.spp,
        integrator: 0,
        seed,
        sample_mode: s.importance_sampling as u32,
        nee: match s.nee {
            NextEventEstimation::Off => NEE_OFF,
            NextEventEstimation::On => NEE_ON,
            NextEventEstimation::Mis => NEE_MIS,
        },
        russian_roulette: s.russian_roulette as u32,
        light_samples: s.light_samples.max(1),
        light_stratify: s.light_stratify as u32,
        min_depth: 0,
        strategy_first: 0,
        strategy_count: 0,
        environment: NO_EMITTER,
        environment_count: 0,
        lens: NO_TEXTURE,
        gbuffer_world: matches!(s.gbuffer, Some(crate::scene::GBufferSpace::World)) as u32,
        reserved6: 0,
        camera_medium: crate::scene::MediumInterface::code(scene.camera_medium),
        cam_window: c.film_window(scene.width, scene.height),
        lens_radius: c.lens_radius,
        focal_distance: c.focal_distance,
        flat_triangle_count: scene.triangles.len() as u32,
        instance_count: scene.instances.len() as u32,
    }
}

/// The largest chunk of scene data the device allows: its largest allocation and buffer,
/// at most 2 GiB (the kernels index a chunk's bytes with 32 bits).
pub fn device_chunk_bytes(device: &Device) -> u64 {
    device
        .info
        .max_allocation_bytes
        .min(device.info.max_buffer_bytes)
        .min(1 << 31)
}

/// The instance buffer of a scene without instances (a binding is never empty).
const NO_INSTANCES: [GpuInstance; 1] = [GpuInstance {
    w2o0: [0.0; 4],
    w2o1: [0.0; 4],
    w2o2: [0.0; 4],
    o2w0: [0.0; 4],
    o2w1: [0.0; 4],
    o2w2: [0.0; 4],
    info: [0; 4],
}];

/// The triangle records' triangles: the world's, then each object's, each in its BVH
/// leaf order (`BvhData::triangle_order`, `object_orders`), found by record index, with
/// the count of texture-coordinate and of shading records before every
/// `ATTRIBUTE_BLOCK`-th record, so that any piece of the triangle, texture-coordinate and
/// shading records can be made on its own.
struct TriangleRecords<'a> {
    scene: &'a Scene,
    bvh: &'a BvhData,
    /// Each object's first record.
    object_first: Vec<usize>,
    count: usize,
    /// The records of each kind ([`Attribute`]).
    totals: [usize; 2],
    /// The records of each kind before record `k * ATTRIBUTE_BLOCK`, for each k.
    blocks: Vec<[usize; 2]>,
}

const ATTRIBUTE_BLOCK: usize = 4096;

/// The kinds of a triangle's attribute records: texture coordinates (any attributes),
/// shading (normals or alpha).
#[derive(Clone, Copy)]
enum Attribute {
    Uv = 0,
    Shading = 1,
}

impl Attribute {
    fn has(self, t: &crate::scene::TriangleCorners) -> bool {
        match self {
            Attribute::Uv => t.has_attributes(),
            Attribute::Shading => t.has_shading(),
        }
    }
}

impl<'a> TriangleRecords<'a> {
    fn new(scene: &'a Scene, bvh: &'a BvhData) -> TriangleRecords<'a> {
        let mut object_first = Vec::with_capacity(bvh.object_orders.len());
        let mut count = bvh.triangle_order.len();
        for order in &bvh.object_orders {
            object_first.push(count);
            count += order.len();
        }
        let mut records = TriangleRecords {
            scene,
            bvh,
            object_first,
            count,
            totals: [0; 2],
            blocks: Vec::new(),
        };
        let mut blocks: Vec<usize> = (0..count.div_ceil(ATTRIBUTE_BLOCK)).collect();
        let counts = crate::accel::map_in_parallel(&mut blocks, crate::accel::threads(), |b| {
            let range = *b * ATTRIBUTE_BLOCK..((*b + 1) * ATTRIBUTE_BLOCK).min(count);
            let mut n = [0; 2];
            for r in range {
                let t = records.triangle(r);
                n[0] += t.has_attributes() as usize;
                n[1] += t.has_shading() as usize;
            }
            n
        });
        let mut before = [0; 2];
        records.blocks = counts
            .iter()
            .map(|&c| {
                let here = before;
                before = [before[0] + c[0], before[1] + c[1]];
                here
            })
            .collect();
        records.totals = before;
        records
    }

    /// Record `r`'s triangle: its list and its index there.
    fn at(&self, r: usize) -> (&'a crate::scene::Triangles, usize) {
        let world = &self.bvh.triangle_order;
        if r < world.len() {
            return (&self.scene.triangles, world[r] as usize);
        }
        let k = self.object_first.partition_point(|&f| f <= r) - 1;
        let order = &self.bvh.object_orders[k];
        (
            &self.scene.objects[k].triangles,
            order[r - self.object_first[k]] as usize,
        )
    }

    /// Record `r`'s triangle's corners and material.
    fn triangle(&self, r: usize) -> &'a crate::scene::TriangleCorners {
        let (list, i) = self.at(r);
        &list[i]
    }

    /// The records of kind `a` before record `r`.
    fn before(&self, r: usize, a: Attribute) -> usize {
        let b = r / ATTRIBUTE_BLOCK;
        let Some(before) = self.blocks.get(b) else {
            return self.totals[a as usize];
        };
        before[a as usize]
            + (b * ATTRIBUTE_BLOCK..r)
                .filter(|&r| a.has(self.triangle(r)))
                .count()
    }

    /// The record whose triangle has record `k` of kind `a` (`k < totals[a]`).
    fn with(&self, k: usize, a: Attribute) -> usize {
        let b = self
            .blocks
            .partition_point(|before| before[a as usize] <= k)
            - 1;
        let mut before = self.blocks[b][a as usize];
        let mut r = b * ATTRIBUTE_BLOCK;
        loop {
            if a.has(self.triangle(r)) {
                if before == k {
                    return r;
                }
                before += 1;
            }
            r += 1;
        }
    }

    /// Records of kind `a` from record `k` on, each with its triangle's record index.
    fn each(&self, k: usize, a: Attribute) -> impl Iterator<Item = usize> + '_ {
        self.each_from(self.with(k, a), a)
    }

    /// The triangle records from `r` on whose triangles have a record of kind `a`.
    fn each_from(&self, r: usize, a: Attribute) -> impl Iterator<Item = usize> + '_ {
        (r..self.count).filter(move |&r| a.has(self.triangle(r)))
    }

    /// For a walk over the triangle records from `r` on, in order: each one's record of
    /// kind `a` (its index among them), or NO_ATTRIBUTES where its triangle has none.
    fn ranks(&self, r: usize, a: Attribute) -> impl FnMut(&crate::scene::TriangleCorners) -> u32 {
        let mut next = self.before(r, a) as u32;
        move |t| {
            if a.has(t) {
                next += 1;
                next - 1
            } else {
                NO_ATTRIBUTES
            }
        }
    }
}

impl GpuScene {
    pub fn new(
        device: &Arc<Device>,
        scene: &Scene,
        bvh: &BvhData,
        backend: Backend,
        params: SceneParams,
        max_chunk_bytes: u64,
    ) -> Result<GpuScene> {
        // (The bounds scene_params found.)
        let mut table = emitter_table_in(scene, &bvh.triangle_order, || params.bounds[3]);
        let textures = texture_data(scene);
        let bits = f32::from_bits;
        // The world's triangles, then each object's (in object space; none emits), each
        // in the BVH's leaf order; the records made as they are uploaded, piece by piece
        // on every core (DataArray::made).
        let records = TriangleRecords::new(scene, bvh);
        let triangle_count = records.count as u64;
        let [uv_count, shading_count] = records.totals.map(|n| n as u64);
        let triangle_emitter = std::mem::take(&mut table.triangle_emitter);
        let triangle_records = |at: u64, out: &mut [u8]| {
            let size = std::mem::size_of::<GpuTriangle>();
            let first = at as usize / size;
            let mut rank = records.ranks(first, Attribute::Uv);
            for (record, r) in out.chunks_exact_mut(size).zip(first..) {
                let t = records.triangle(r);
                let a = rank(t);
                let emitter = triangle_emitter.get(r).copied().unwrap_or(NO_EMITTER);
                record.copy_from_slice(bytemuck::bytes_of(&GpuTriangle {
                    v0: t.v[0].extend(bits(t.material)).to_array(),
                    v1: t.v[1].extend(bits(emitter)).to_array(),
                    v2: t.v[2].extend(bits(a)).to_array(),
                }));
            }
        };
        let uv_records = |at: u64, out: &mut [u8]| {
            let size = std::mem::size_of::<GpuTriangleUv>();
            let first = records.with(at as usize / size, Attribute::Uv);
            let mut rank = records.ranks(first, Attribute::Shading);
            for (record, r) in out
                .chunks_exact_mut(size)
                .zip(records.each_from(first, Attribute::Uv))
            {
                let (list, i) = records.at(r);
                let s = rank(&list[i]);
                record.copy_from_slice(bytemuck::bytes_of(&triangle_uv(list, i, s)));
            }
        };
        let shading_records = |at: u64, out: &mut [u8]| {
            let size = std::mem::size_of::<GpuTriangleShading>();
            let each = records.each(at as usize / size, Attribute::Shading);
            for (record, r) in out.chunks_exact_mut(size).zip(each) {
                let (list, i) = records.at(r);
                let s = triangle_shading(list, i).expect("a shading record");
                record.copy_from_slice(bytemuck::bytes_of(&s));
            }
        };
        let spheres: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let o2w = s.object_to_world.transpose().to_cols_array_2d(); // rows
                let w2o = s.object_to_world.inverse().transpose().to_cols_array_2d();
                GpuSphere {
                    o2w0: o2w[0],
                    o2w1: o2w[1],
                    o2w2: o2w[2],
                    w2o0: w2o[0],
                    w2o1: w2o[1],
                    w2o2: w2o[2],
                    info: [s.material, table.sphere_emitter[i], s.inward as u32, 0],
                }
            })
            .collect();
        let materials = material_records(scene, &textures);
        let (media, medium_grids) = medium_records(scene, &textures);
        for e in &mut table.emitters {
            if matches!(e.info[0], EMITTER_GONIOMETRIC | EMITTER_PROJECTION) {
                e.info[1] = textures.light_profiles[e.info[1] as usize];
            }
        }
        let mut params = params;
        params.emitter_count = table.emitters.len() as u32;
        params.environment = table.environment;
        params.environment_count = table.environment_sources.len() as u32;
        params.lens = textures.lens.unwrap_or(NO_TEXTURE);
        for (k, &i) in table.environment_sources.iter().enumerate() {
            let e = &mut table.emitters[table.environment as usize + k];
            let [texture, marginal, conditional, portal] = textures.environments[i];
            e.info[1] = texture;
            e.p0[3] = bits(marginal);
            e.p1[3] = bits(conditional);
            e.p2[3] = bits(portal);
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let limit = device.info.max_storage_buffer_range;
        for (name, bytes) in [
            ("spheres", spheres.len() * 112),
            (
                "materials",
                materials.len() * std::mem::size_of::<GpuMaterial>(),
            ),
            ("instances", bvh.instances.len() * 112),
            ("emitters", table.emitters.len() * 80),
            ("textures", textures.textures.len() * 80),
            ("media", media.len() * std::mem::size_of::<GpuMedium>()),
        ] {
            if bytes as u64 > limit {
                return Err(other_error(
                    "uploading the scene",
                    format!("{name} need {bytes} bytes, more than the device's storage-buffer range ({limit})"),
                )
                .into());
            }
        }
        let mut triangle_data = DataArray::made(
            "triangles",
            triangle_count,
            std::mem::size_of::<GpuTriangle>() as u64,
            triangle_records,
        );
        triangle_data.bindable = true;
        if backend == Backend::RayQuery {
            // The BLAS builds read the triangles' corners where they lie, chunk by chunk
            // (src/gpu/rayquery.rs).
            triangle_data.usage =
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR;
        }
        let ray_query = backend == Backend::RayQuery;
        let node_record = if backend == Backend::Cwbvh { 80 } else { 32 };
        let data = SceneData::new(
            device,
            [
                triangle_data,
                DataArray::made(
                    "triangle texture coordinates",
                    uv_count,
                    std::mem::size_of::<GpuTriangleUv>() as u64,
                    uv_records,
                ),
                if ray_query {
                    DataArray::none("BVH nodes")
                } else {
                    DataArray {
                        bindable: true,
                        ..DataArray::new("BVH nodes", &bvh.nodes, node_record)
                    }
                },
                if ray_query {
                    DataArray::none("BVH primitive references")
                } else {
                    DataArray {
                        bindable: true,
                        ..DataArray::new(
                            "BVH primitive references",
                            bytemuck::cast_slice(&bvh.prim_refs),
                            4,
                        )
                    }
                },
                DataArray::made("texels", textures.texel_count(), 4, textures.texel_writer()),
                DataArray::new("medium grids", bytemuck::cast_slice(&medium_grids), 4),
                DataArray::made(
                    "triangle shading",
                    shading_count,
                    std::mem::size_of::<GpuTriangleShading>() as u64,
                    shading_records,
                ),
            ],
            max_chunk_bytes,
        )?;
        Ok(GpuScene {
            params,
            scene_params: Buffer::with_data(
                device,
                "scene parameters",
                bytemuck::bytes_of(&params),
                vk::BufferUsageFlags::UNIFORM_BUFFER,
            )?,
            spheres: Buffer::with_data(device, "spheres", bytemuck::cast_slice(&spheres), storage)?,
            materials: Buffer::with_data(
                device,
                "materials",
                bytemuck::cast_slice(&materials),
                storage,
            )?,
            emitters: Buffer::with_data(
                device,
                "emitters",
                bytemuck::cast_slice(&table.emitters),
                storage,
            )?,
            emitter_cdf: Buffer::with_data(
                device,
                "emitter CDF",
                bytemuck::cast_slice(&table.cdf),
                storage,
            )?,
            textures: Buffer::with_data(
                device,
                "textures",
                bytemuck::cast_slice(&textures.textures),
                storage,
            )?,
            media: Buffer::with_data(device, "media", bytemuck::cast_slice(&media), storage)?,
            instances: Buffer::with_data(
                device,
                "instances",
                bytemuck::cast_slice(if bvh.instances.is_empty() {
                    &NO_INSTANCES[..]
                } else {
                    &bvh.instances[..]
                }),
                storage,
            )?,
            data,
        })
    }

    /// The triangle buffer (one chunk: ray query's BLAS builds read it).
    /// The triangle records' chunks and the shift of their record count (31 or more:
    /// one chunk holds every record).
    pub fn triangle_chunks(&self) -> (&[Buffer], u32) {
        let kind = DATA_TRIANGLES as usize;
        (&self.data.chunks[kind], self.data.shifts[kind])
    }

    /// The bytes of device memory the scene's buffers hold.
    pub fn device_bytes(&self) -> u64 {
        [
            &self.scene_params,
            &self.spheres,
            &self.materials,
            &self.emitters,
            &self.emitter_cdf,
            &self.textures,
            &self.media,
            &self.instances,
        ]
        .iter()
        .map(|b| b.size)
        .sum::<u64>()
            + self.data.device_bytes()
    }

    /// The scene's resources by binding number, for `Kernels::descriptor_set` (a kernel
    /// binds those it uses). `rq` holds the TLAS on the ray-query backend.
    pub fn resources(&self, rq: Option<&RayQueryScene>) -> Vec<(u32, Resource)> {
        let mut list = vec![
            (BINDING_SCENE, Resource::Buffer(self.scene_params.raw)),
            (BINDING_SCENE_DATA, Resource::Buffer(self.data.table.raw)),
            (
                BINDING_TRIANGLES,
                Resource::Buffer(self.data.bound(DATA_TRIANGLES).raw),
            ),
            (
                BINDING_BVH_NODES,
                Resource::Buffer(self.data.bound(DATA_BVH_NODES).raw),
            ),
            (
                BINDING_BVH_PRIMS,
                Resource::Buffer(self.data.bound(DATA_BVH_PRIMS).raw),
            ),
            (BINDING_INSTANCES, Resource::Buffer(self.instances.raw)),
            (BINDING_SPHERES, Resource::Buffer(self.spheres.raw)),
            (BINDING_MATERIALS, Resource::Buffer(self.materials.raw)),
            (BINDING_EMITTERS, Resource::Buffer(self.emitters.raw)),
            (BINDING_EMITTER_CDF, Resource::Buffer(self.emitter_cdf.raw)),
            (BINDING_TEXTURES, Resource::Buffer(self.textures.raw)),
            (BINDING_MEDIA, Resource::Buffer(self.media.raw)),
        ];
        if let Some(rq) = rq {
            list.push((BINDING_TLAS, Resource::AccelerationStructure(rq.tlas.raw)));
        }
        list
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_str;

    #[test]
    fn triangle_records_find_any_record_and_its_attributes() {
        // The world's triangles and two objects', some with texture coordinates, some
        // with shading normals (runs and lone ones across block boundaries), in shuffled
        // leaf orders: each record's triangle, its rank among each kind of attribute
        // record and the record of each attribute as a walk in order finds them.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = move |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let triangles = |count: usize, next: &mut dyn FnMut(u64) -> u64| {
            let (mut with, mut shaded) = (false, false);
            (0..count)
                .map(|i| {
                    if next(97) == 0 {
                        with = !with;
                    }
                    if next(89) == 0 {
                        shaded = !shaded;
                    }
                    let mut t = crate::scene::Triangle::new([Vec3::splat(i as f32); 3], i as u32);
                    if with || next(11) == 0 {
                        t.uv = Some([glam::Vec2::ZERO; 3]);
                    }
                    if (shaded && next(2) == 0) || next(13) == 0 {
                        t.normals = Some([Vec3::Z; 3]);
                    }
                    t
                })
                .collect::<crate::scene::Triangles>()
        };
        let mut scene = Scene {
            triangles: triangles(3 * ATTRIBUTE_BLOCK + 77, &mut next),
            ..Scene::default()
        };
        for (name, n) in [("a", 1), ("b", 2 * ATTRIBUTE_BLOCK + 5)] {
            scene.objects.push(crate::scene::Object {
                name: name.into(),
                triangles: triangles(n, &mut next),
            });
        }
        let mut shuffled = |n: usize| {
            let mut order: Vec<u32> = (0..n as u32).collect();
            for i in (1..n).rev() {
                order.swap(i, next(i as u64 + 1) as usize);
            }
            order
        };
        let bvh = BvhData {
            nodes: Vec::new(),
            prim_refs: Vec::new(),
            triangle_order: shuffled(scene.triangles.len()),
            object_orders: scene
                .objects
                .iter()
                .map(|o| shuffled(o.triangles.len()))
                .collect(),
            instances: Vec::new(),
            triangle_ids: 0,
        };
        let all: Vec<&crate::scene::TriangleCorners> = (bvh
            .triangle_order
            .iter()
            .map(|&i| &scene.triangles[i as usize]))
        .chain(
            scene
                .objects
                .iter()
                .zip(&bvh.object_orders)
                .flat_map(|(o, order)| order.iter().map(|&i| &o.triangles[i as usize])),
        )
        .collect();
        let records = TriangleRecords::new(&scene, &bvh);
        assert_eq!(records.count, all.len());
        for a in [Attribute::Uv, Attribute::Shading] {
            let mut before = 0;
            for (r, t) in all.iter().enumerate() {
                assert!(std::ptr::eq(records.triangle(r), *t), "record {r}");
                assert_eq!(records.before(r, a), before, "record {r}");
                if a.has(t) {
                    assert_eq!(records.with(before, a), r, "attribute {before}");
                    assert_eq!(records.each(before, a).next(), Some(r));
                    before += 1;
                }
            }
            assert_eq!(records.totals[a as usize], before);
            assert!(before > ATTRIBUTE_BLOCK && before < all.len() - ATTRIBUTE_BLOCK);
        }
        assert!(records.totals[1] < records.totals[0]);
    }

    #[test]
    fn spot_lights_are_picked_by_their_cone_power() {
        // A point light of intensity 1 (power 4π) and a spot of intensity 2 with a 60°
        // cone and no falloff band (power 2 · 2π(1 − cos 60°) = 2π).
        let s = parse_str("point 0 3 0  1 1 1\nspot 0 3 0  0 0 0  2 2 2  60 0\n", "t").unwrap();
        let t = emitter_table(&s);
        assert_eq!(t.emitters.len(), 2);
        assert_eq!(t.emitters[1].info[0], EMITTER_SPOT);
        assert!((t.emitters[0].radiance[3] - 2.0 / 3.0).abs() < 1e-6);
        assert!((t.emitters[1].radiance[3] - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(t.emitters[1].p1[..3], [0.0, -1.0, 0.0]);
        assert!(
            (t.emitters[1].p1[3] - 0.5).abs() < 1e-6,
            "cos of the cone angle"
        );
    }

    /// Several infinite lights: one emitter each, the last ones in a row (one that emits
    /// nothing left out), each with its map's frame and mapping, its portal's corner and
    /// edges in the texels.
    #[test]
    fn infinite_lights_are_the_last_emitters_in_a_row() {
        let s = crate::scene::parse_pbrt_str(
            "WorldBegin\nLightSource \"point\" \"rgb I\" [ 1 1 1 ]\n\
             LightSource \"infinite\" \"rgb L\" [ 1 1 1 ] \"point3 portal\" [ 0 1 0  1 1 0  1 1 1  0 1 1 ]\n\
             LightSource \"infinite\" \"rgb L\" [ 0 0 0 ] \"point3 portal\" [ 0 2 0  1 2 0  1 2 1  0 2 1 ]\n\
             Rotate 90 0 0 1\nLightSource \"infinite\" \"rgb L\" [ 2 2 2 ]\n",
            "envs.pbrt",
        )
        .unwrap();
        assert_eq!(s.environments.len(), 3);
        let t = emitter_table(&s);
        assert_eq!(t.environment, 1);
        assert_eq!(t.environment_sources, vec![0, 2]);
        assert_eq!(t.emitters.len(), 3);
        for e in &t.emitters[1..] {
            assert_eq!(e.info[0], EMITTER_INFINITE);
            assert_eq!(e.info[1], NO_TEXTURE);
        }
        // (A constant light's frame is the identity: it has no map to turn.)
        assert_eq!(t.emitters[2].p0, [1.0, 0.0, 0.0, 0.0]);
        let d = texture_data(&s);
        assert_eq!(d.environments.len(), 3);
        assert_eq!(d.environments[2][3], NO_TEXTURE);
        let first = d.environments[0][3] as usize;
        assert_eq!(
            d.texels[first..first + 9],
            [0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
        );
        let p0 = d.environments[1][3] as usize;
        assert_eq!(d.texels[p0 + 1], 2.0);
    }

    /// An 8-bit image is stored as one word a texel after its table (once per decoding,
    /// however many images read it; an image read twice stored once), its record's
    /// flags.w the table + 1; a float image three floats a texel, flags.w 0.
    #[test]
    fn eight_bit_images_are_one_word_a_texel_after_their_table() {
        use crate::texture::{Encoding, Projection, TextureImage};
        let bytes = |texels: Vec<[u8; 3]>, grey| {
            Arc::new(TextureImage::Bytes {
                width: 2,
                height: 1,
                texels,
                decoding: ByteDecoding {
                    encoding: Encoding::Srgb,
                    grey,
                },
            })
        };
        let a = bytes(vec![[1, 2, 3], [250, 0, 9]], false);
        let b = bytes(vec![[7, 7, 7], [0, 0, 0]], false);
        let c = bytes(vec![[5, 5, 5], [6, 6, 6]], true);
        let f = Arc::new(TextureImage::Float((*a).clone().into_floats()));
        let mut s = Scene::default();
        for image in [&a, &b, &a, &c, &f] {
            s.textures.push(Texture::Image {
                image: image.clone(),
                scale: Vec3::ONE,
                mapping: UV_MAPPING,
                wrap: Wrap::Repeat,
                projection: Projection::Uv,
                filter: crate::texture::Filter::Bilinear,
                max_anisotropy: crate::texture::DEFAULT_MAX_ANISOTROPY,
            });
        }
        let d = texture_data(&s);
        assert_eq!(d.texel_count(), 256 + 2 + 2 + 256 + 2 + 6);
        let words: Vec<f32> = d.texel_words().collect();
        assert_eq!(words.len() as u64, d.texel_count());
        // The upload's writer gives the same words, in chunks of any size.
        // (Last piece first: each piece is written from its offset alone.)
        for chunk in [1, 3, 7, 1000] {
            let write = d.texel_writer();
            let mut bytes = vec![0u8; 4 * words.len()];
            for (k, piece) in bytes.chunks_mut(4 * chunk).enumerate().rev() {
                write((4 * chunk * k) as u64, piece);
            }
            let written: &[f32] = bytemuck::cast_slice(&bytes);
            assert!(
                written
                    .iter()
                    .zip(&words)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "chunks of {chunk}"
            );
        }
        assert_eq!(words[..d.texels.len()], d.texels[..]);
        let d = TextureData { texels: words, ..d };
        let r = &d.textures;
        let table = r[0].flags[3] as usize - 1;
        assert_eq!(r[1].flags[3], r[0].flags[3]);
        assert_eq!(r[2].info, r[0].info);
        assert_ne!(r[3].flags[3], r[0].flags[3]);
        assert_eq!(r[4].flags[3], 0);
        assert_eq!(d.texels[table..table + 256], decoding_table(false)[..]);
        let word = d.texels[r[0].info[1] as usize + 1].to_bits();
        assert_eq!(word, 250 | 9 << 16);
        let floats = r[4].info[1] as usize;
        assert_eq!(d.texels[floats + 3..floats + 6], a.texel(1));
        assert_eq!(a.texel(1)[0], d.texels[table + 250]);
    }

    fn decoding_table(grey: bool) -> &'static [f32; 256] {
        ByteDecoding {
            encoding: crate::texture::Encoding::Srgb,
            grey,
        }
        .table()
    }

    #[test]
    fn the_environment_is_the_last_emitter_with_its_power() {
        // Bounding radius √3 (the corners of a unit cube), L = 1: power 4π · π · 3 = 12π²;
        // a point light of intensity 3π has 4π · 3π = 12π² too: equal shares.
        let s = parse_str(
            "vertex -1 -1 -1\nvertex 1 1 1\nvertex 1 -1 1\ntri 0 1 2\n\
             point 0 0 0  9.424778 9.424778 9.424778\nenvlight 1 1 1\n",
            "t",
        )
        .unwrap();
        let t = emitter_table(&s);
        assert_eq!(t.environment, 1);
        assert_eq!(t.emitters[1].info[0], EMITTER_INFINITE);
        let share = t.emitters[1].radiance[3];
        assert!((share - 0.5).abs() < 1e-5, "{share}");
        let none = emitter_table(&parse_str("envlight 0 0 0\n", "t").unwrap());
        assert_eq!(none.environment, NO_EMITTER);
    }

    /// The footprint of a pixel on a plane facing the camera at distance 4 is 4 times the
    /// film's pixel (at distance 1) along the image's right and up, over 8; on the plane
    /// turned 60 degrees about the image's up it is twice as long along right (to first
    /// order in the pixel's size).
    #[test]
    fn a_pixel_footprint_grows_with_distance_and_tilt() {
        let s = parse_str("size 4000 2000\ncamera 0 0 0  0 0 -1  0 1 0  90\n", "t").unwrap();
        let p = scene_params(&s, 0);
        // fovy 90: the film spans 2 vertically at distance 1, 4 horizontally: 0.001 a pixel.
        let pixel = 4.0 * 0.001 / 8.0;
        let (dx, dy) = surface_footprint(&p, Vec3::new(0.0, 0.0, -4.0), Vec3::Z);
        assert!((dx.length() - pixel).abs() < 1e-6 * pixel, "{dx}");
        assert!((dy.length() - pixel).abs() < 1e-6 * pixel, "{dy}");
        assert!(
            dx.y.abs() < 1e-9 && dx.z.abs() < 1e-9,
            "{dx} along the right"
        );
        let n = Vec3::new((60f32).to_radians().sin(), 0.0, (60f32).to_radians().cos());
        let (dx, dy) = surface_footprint(&p, Vec3::new(0.0, 0.0, -4.0), n);
        assert!((dx.length() - 2.0 * pixel).abs() < 0.01 * pixel, "{dx}");
        assert!((dy.length() - pixel).abs() < 0.01 * pixel, "{dy}");
        // Grazing: no footprint rather than an infinite one.
        let (dx, _) = surface_footprint(&p, Vec3::new(0.0, 0.0, -4.0), Vec3::X);
        assert!(dx.is_finite());
    }

    /// Goniometric and projection lights: their records (the map's rows, the image's
    /// size) and their power, the image's value integrated over the directions it covers
    /// (`profile_weights`): 4π for a uniform goniometric image; for a projection of a
    /// uniform image of aspect 2 at fov 90°, the solid angle of a 4 × 2 rectangle at
    /// distance 1, 4 atan(2 / √6).
    #[test]
    fn goniometric_and_projection_lights_have_their_records_and_power() {
        use crate::scene::LightProfile;
        let pi = std::f32::consts::PI;
        let mut s = Scene::default();
        s.light_profiles.push(LightProfile {
            width: 8,
            height: 8,
            channels: 1,
            values: vec![1.0; 64],
        });
        s.light_profiles.push(LightProfile {
            width: 64,
            height: 32,
            channels: 3,
            values: vec![1.0; 64 * 32 * 3],
        });
        let turn = Mat3::from_rotation_y(0.3);
        s.delta_lights.push(DeltaLight::Goniometric {
            position: Vec3::new(1.0, 2.0, 3.0),
            light_from_world: turn,
            intensity: Vec3::splat(2.0),
            profile: 0,
        });
        s.delta_lights.push(DeltaLight::Projection {
            position: Vec3::ZERO,
            screen_from_world: Mat3::from_diagonal(Vec3::new(1.0, -1.0, 1.0)),
            scale: Vec3::ONE,
            profile: 1,
        });
        let (_, flux) = profile_weights(&s, &s.delta_lights[0]).unwrap();
        assert!((flux - 4.0 * pi).abs() < 1e-4, "{flux}");
        let (weights, flux) = profile_weights(&s, &s.delta_lights[1]).unwrap();
        let rectangle = 4.0 * (2.0 / 6.0f32.sqrt()).atan();
        assert!(
            (flux - rectangle).abs() < 0.005 * rectangle,
            "{flux} vs {rectangle}"
        );
        // (Directions are drawn in proportion to intensity: the image's centre's pixels
        // subtend the most.)
        assert!(weights[16 * 64 + 32] > 2.0 * weights[0]);
        let t = emitter_table(&s);
        assert_eq!(t.emitters[0].info[0], EMITTER_GONIOMETRIC);
        assert_eq!(t.emitters[0].info[1], 0);
        assert_eq!(t.emitters[0].info[2], 8 | 8 << 16);
        assert_eq!(t.emitters[1].info[0], EMITTER_PROJECTION);
        assert_eq!(t.emitters[1].info[2], 64 | 32 << 16);
        let e = &t.emitters[0];
        assert_eq!(&e.p0[..3], &[1.0, 2.0, 3.0]);
        let rows = [
            Vec3::new(e.p1[0], e.p1[1], e.p1[2]),
            Vec3::new(e.p2[0], e.p2[1], e.p2[2]),
            Vec3::new(e.p0[3], e.p1[3], e.p2[3]),
        ];
        for (i, r) in rows.iter().enumerate() {
            assert!((*r - turn.row(i)).length() < 1e-6, "row {i}");
        }
        // Power: 2 · 4π and 1 · the rectangle's solid angle.
        let p = e.radiance[3];
        assert!((p - 8.0 * pi / (8.0 * pi + rectangle)).abs() < 1e-3, "{p}");
    }

    #[test]
    fn emitter_table_picks_by_power() {
        let s = parse_str(
            "quadLight 0 1 0  1 0 0  0 0 1  2 2 2\nquadLight 5 1 0  2 0 0  0 0 2  1 1 1\npoint 0 3 0 4 4 4\n\
             emission 1 1 1\nsphere 0 -3 0 0.5\n",
            "t",
        )
        .unwrap();
        let t = emitter_table(&s);
        assert_eq!(t.emitters.len(), 2 + 2 + 1 + 1);
        let probs: Vec<f32> = t.emitters.iter().map(|e| e.radiance[3]).collect();
        assert!((probs.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert_eq!(*t.cdf.last().unwrap(), u32::MAX);
        assert_pick_pdfs_are_the_ranges(&t);
        // Quad 1: area 1, L 2, one-sided → power 2π; quad 2: area 4, L 1 → 4π;
        // point: 4π·4 = 16π; sphere r 0.5, two-sided (but closed): area π, L 1 → π·π.
        let pi = std::f32::consts::PI;
        let total = 2.0 * pi + 4.0 * pi + 16.0 * pi + pi * pi;
        let quad1 = probs[0] + probs[1];
        assert!((quad1 - 2.0 * pi / total).abs() < 1e-4, "{quad1}");
        let sphere = probs[4];
        assert!((sphere - pi * pi / total).abs() < 1e-3, "{sphere}");
        assert_eq!(t.emitters[0].info[2], 0, "quad lights are one-sided");
        assert_eq!(t.emitters[4].info[0], EMITTER_SPHERE);
        assert!(
            (t.emitters[4].p1[0] - 0.125).abs() < 1e-6,
            "|det| of a 0.5 scale"
        );
        assert_eq!(t.triangle_emitter, vec![0, 1, 2, 3]);
    }

    /// Each emitter's pick pdf is exactly its share of the 2^32 random values that
    /// `pick_emitter` maps to it (checked at the ends of every range).
    fn assert_pick_pdfs_are_the_ranges(t: &EmitterTable) {
        let mut start = 0u64;
        for (i, e) in t.emitters.iter().enumerate() {
            let end = if i + 1 == t.cdf.len() {
                1u64 << 32
            } else {
                t.cdf[i] as u64
            };
            let share = (end - start) as f64 / 4294967296.0;
            assert!(
                (e.radiance[3] as f64 - share).abs() <= 1e-7 * share,
                "emitter {i}: pdf {} for a share {share}",
                e.radiance[3]
            );
            if end > start {
                assert_eq!(pick_emitter(&t.cdf, start as u32), i);
                assert_eq!(pick_emitter(&t.cdf, (end - 1) as u32), i);
            }
            start = end;
        }
    }

    #[test]
    fn emitters_too_dim_for_the_pick_range_are_never_picked_and_have_pdf_zero() {
        // A quad 1e-12 as bright as the others: less than one of the 2^32 values.
        let s = parse_str(
            "quadLight 0 1 0  1 0 0  0 0 1  1 1 1\n\
             quadLight 5 1 0  1 0 0  0 0 1  1e-12 1e-12 1e-12\n\
             quadLight 9 1 0  1 0 0  0 0 1  1 1 1\n",
            "t",
        )
        .unwrap();
        let t = emitter_table(&s);
        assert_eq!(t.emitters.len(), 6);
        assert_eq!(t.emitters[2].radiance[3], 0.0);
        assert_eq!(t.emitters[3].radiance[3], 0.0);
        assert!((t.emitters[0].radiance[3] - 0.25).abs() < 1e-7);
        assert_pick_pdfs_are_the_ranges(&t);
        // Around the dim quad's (empty) ranges, neighbours are picked.
        let boundary = t.cdf[1];
        assert_eq!(pick_emitter(&t.cdf, boundary - 1), 1);
        assert_eq!(pick_emitter(&t.cdf, boundary), 4);
        // Many equal emitters: shares equal within 1e-4 relative (a float CDF with 24-bit
        // uniforms would be off by up to 1% each).
        let mut text = String::new();
        for _ in 0..50_000 {
            text += "quadLight 0 0 0  0.01 0 0  0 0 0.01  1 1 1\n";
        }
        let t = emitter_table(&parse_str(&text, "many").unwrap());
        assert_eq!(t.emitters.len(), 100_000);
        for e in &t.emitters {
            assert!(
                (e.radiance[3] as f64 * 1e5 - 1.0).abs() < 1e-4,
                "{}",
                e.radiance[3]
            );
        }
        assert_pick_pdfs_are_the_ranges(&t);
    }

    #[test]
    fn ellipsoid_area_quadrature_is_accurate() {
        let a = ellipsoid_area(Mat3::from_diagonal(Vec3::new(2.0, 2.0, 2.0)));
        assert!((a - 16.0 * std::f32::consts::PI).abs() / a < 1e-3);
        // Prolate spheroid a = b = 1, c = 2: 2π(1 + c²/(e) asin e / ... ) ≈ 21.4784.
        let a = ellipsoid_area(Mat3::from_diagonal(Vec3::new(1.0, 1.0, 2.0)));
        assert!((a - 21.4784).abs() / 21.4784 < 2e-3, "{a}");
    }

    #[test]
    fn camera_basis_is_orthonormal_and_looks_at_the_target() {
        let s = parse_str("size 200 100\ncamera 1 2 3  0 1 0  0 1 0  45\n", "t").unwrap();
        let p = scene_params(&s, 0);
        let f = Vec3::from_slice(&p.cam_forward[..3]);
        let r = Vec3::from_slice(&p.cam_right[..3]);
        let u = Vec3::from_slice(&p.cam_up[..3]);
        assert!((f - (Vec3::new(-1.0, -1.0, -3.0)).normalize()).length() < 1e-6);
        assert!(f.dot(r).abs() < 1e-6 && f.dot(u).abs() < 1e-6 && r.dot(u).abs() < 1e-6);
        assert!(u.y > 0.0);
        let t = (22.5f32).to_radians().tan();
        assert_eq!(p.cam_window, [-2.0 * t, 2.0 * t, -t, t]);
        // The centre of the film looks ahead, its top-left corner up and left.
        let (o, d) = camera_ray(&p, Vec2::splat(0.5), Vec2::ZERO);
        assert_eq!(o, Vec3::new(1.0, 2.0, 3.0));
        assert!((d - f).length() < 1e-6);
        let (_, d) = camera_ray(&p, Vec2::ZERO, Vec2::ZERO);
        assert!(d.dot(r) < 0.0 && d.dot(u) > 0.0);
        // A point seen through any point of a thin lens lands where it is in focus.
        let film = Vec2::new(0.3, 0.8);
        let (_, pinhole) = camera_ray(&p, film, Vec2::ZERO);
        let mut p = p;
        p.lens_radius = 0.25;
        p.focal_distance = 5.0;
        let focus = Vec3::new(1.0, 2.0, 3.0) + pinhole * (5.0 / pinhole.dot(f));
        for u in [Vec2::new(0.1, 0.9), Vec2::new(0.7, 0.2)] {
            let (o, d) = camera_ray(&p, film, u);
            assert!((o - Vec3::new(1.0, 2.0, 3.0)).length() > 1e-3);
            let t = (focus - o).length();
            assert!((o + d * t - focus).length() < 1e-4);
        }
    }
}
