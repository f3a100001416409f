//! Images read as textures and environment maps, the mappings between an environment
//! map's (u, v) and directions, and the piecewise-constant 2D distribution that
//! importance-samples a map. The kernels' versions are in glsl/lib/texture.glsl and
//! glsl/lib/lights.glsl; these are their CPU mirrors and what the host builds.
//! The scene's texture and environment types are defined here (and re-exported by
//! `crate::scene`), so this module depends on nothing of the scene's.
use crate::abi::{
    TEXTURE_MAP_CYLINDRICAL, TEXTURE_MAP_PLANAR, TEXTURE_MAP_SOLID, TEXTURE_MAP_SPHERICAL,
    TEXTURE_MAP_UV,
};
use crate::io::Image;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use std::f32::consts::PI;
use std::path::Path;
use std::sync::Arc;

/// An image texture's `maxanisotropy` where none is given (pbrt-v4's default).
pub const DEFAULT_MAX_ANISOTROPY: f32 = 8.0;
/// The largest `maxanisotropy` the reader accepts (pbrt-v4 sets none): an EWA lookup
/// visits the texels of its ellipse's bounding box at the level where the ellipse is a
/// texel wide: about half this squared for a diagonal one (half a million texels).
pub const MAX_ANISOTROPY: f32 = 1024.0;

/// A texture: what a material reads at a surface point's (u, v), after the mapping
/// `(s, t) = (su u + du, sv v + dv)` (`mapping` holds su, sv, du, dv).
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// An image, filtered as `filter` says; t = 0 is its bottom row (as pbrt's).
    /// Values are `scale` times the (linear) texels.
    Image {
        image: Arc<TextureImage>,
        scale: Vec3,
        mapping: [f32; 4],
        /// Beyond the image's sides (both axes alike).
        wrap: Wrap,
        projection: Projection,
        filter: Filter,
        /// The longest an EWA footprint may be for its width (pbrt-v4's `maxanisotropy`,
        /// [`DEFAULT_MAX_ANISOTROPY`] unless given; read by [`Filter::Ewa`] alone).
        max_anisotropy: f32,
    },
    /// pbrt's 2D checkerboard: `even` where floor(s) + floor(t) is even, else `odd`.
    Checkerboard {
        even: Vec3,
        odd: Vec3,
        mapping: [f32; 4],
        projection: Projection,
    },
    /// pbrt-v4's noise textures at the point in the texture's space (`projection` is
    /// `Solid`; noise.rs): `fbm`, `wrinkled` (turbulence) and `windy` (floats, in every
    /// channel), `marble` (a colour; `scale` and `variation` are its own).
    Noise {
        kind: NoiseKind,
        octaves: u32,
        /// pbrt's `roughness`: each octave's weight relative to the last.
        omega: f32,
        scale: f32,
        variation: f32,
        projection: Projection,
    },
    /// pbrt-v4's `dots`: `inside` within the polka dot of (s, t)'s cell, else `outside`.
    Dots {
        inside: Vec3,
        outside: Vec3,
        mapping: [f32; 4],
        projection: Projection,
    },
    /// pbrt-v4's `bilerp`: (1−s)(1−t) v00 + s(1−t) v10 + (1−s)t v01 + st v11 (`v` in
    /// that order: v00, v01, v10, v11), extrapolated outside [0, 1]².
    Bilerp {
        v: [Vec3; 4],
        mapping: [f32; 4],
        projection: Projection,
    },
    /// pbrt-v4's `scale` texture: `tex` times the first channel of `scale` (a float
    /// texture).
    Scale { tex: Operand, scale: Operand },
    /// pbrt-v4's `mix` texture: (1 - a) `tex1` + a `tex2`, a the first channel of
    /// `amount` (a float texture).
    Mix {
        tex1: Operand,
        tex2: Operand,
        amount: Operand,
    },
    /// pbrt-v4's `directionmix`: w `tex1` + (1 - w) `tex2`, w = |ng · dir| where ng is the
    /// surface's unit geometric normal and `dir` a unit world direction.
    DirectionMix {
        tex1: Operand,
        tex2: Operand,
        dir: Vec3,
    },
}

/// Which of pbrt-v4's noise textures (abi.h `NOISE_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseKind {
    Fbm,
    Wrinkled,
    Windy,
    Marble,
}

impl NoiseKind {
    pub fn code(self) -> u32 {
        match self {
            NoiseKind::Fbm => crate::abi::NOISE_FBM,
            NoiseKind::Wrinkled => crate::abi::NOISE_WRINKLED,
            NoiseKind::Windy => crate::abi::NOISE_WINDY,
            NoiseKind::Marble => crate::abi::NOISE_MARBLE,
        }
    }
}

/// An input of a texture made of textures: a constant or a texture (its own tree).
#[derive(Clone, Debug, PartialEq)]
pub enum Operand {
    Const(Vec3),
    Texture(Box<Texture>),
}

impl Operand {
    fn value(&self, uv: Vec2, p: Vec3, ng: Vec3, footprint: Footprint) -> Vec3 {
        match self {
            Operand::Const(c) => *c,
            Operand::Texture(t) => texture_value_in(t, uv, p, ng, footprint),
        }
    }
}

impl Texture {
    /// How the texture finds its (s, t) (a texture made of textures: none of its own).
    pub fn projection(&self) -> Projection {
        match self {
            Texture::Image { projection, .. }
            | Texture::Checkerboard { projection, .. }
            | Texture::Noise { projection, .. }
            | Texture::Dots { projection, .. }
            | Texture::Bilerp { projection, .. } => *projection,
            Texture::Scale { .. } | Texture::Mix { .. } | Texture::DirectionMix { .. } => {
                Projection::Uv
            }
        }
    }

    /// The texture's operands, if it is made of textures.
    pub fn operands(&self) -> Vec<&Operand> {
        match self {
            Texture::Image { .. }
            | Texture::Checkerboard { .. }
            | Texture::Noise { .. }
            | Texture::Dots { .. }
            | Texture::Bilerp { .. } => Vec::new(),
            Texture::Scale { tex, scale } => vec![tex, scale],
            Texture::Mix { tex1, tex2, amount } => vec![tex1, tex2, amount],
            Texture::DirectionMix { tex1, tex2, .. } => vec![tex1, tex2],
        }
    }

    /// Each image of its tree (itself, if it is an image), to change.
    pub fn for_each_image_mut(&mut self, f: &mut impl FnMut(&mut Arc<TextureImage>)) {
        self.for_each_image_texture_mut(&mut |image, _| f(image));
    }

    /// Each image texture of its tree (itself, if it is one), its image to change and its
    /// wrap mode.
    pub fn for_each_image_texture_mut(&mut self, f: &mut impl FnMut(&mut Arc<TextureImage>, Wrap)) {
        let operands = match self {
            Texture::Image { image, wrap, .. } => return f(image, *wrap),
            Texture::Checkerboard { .. }
            | Texture::Noise { .. }
            | Texture::Dots { .. }
            | Texture::Bilerp { .. } => return,
            Texture::Scale { tex, scale } => vec![tex, scale],
            Texture::Mix { tex1, tex2, amount } => vec![tex1, tex2, amount],
            Texture::DirectionMix { tex1, tex2, .. } => vec![tex1, tex2],
        };
        for o in operands {
            if let Operand::Texture(t) = o {
                t.for_each_image_texture_mut(f);
            }
        }
    }

    /// The textures of its tree that are not made of textures (itself, if it is one).
    pub fn leaves(&self) -> Vec<&Texture> {
        let mut out = Vec::new();
        let mut stack = vec![self];
        while let Some(t) = stack.pop() {
            let ops = t.operands();
            if ops.is_empty() {
                out.push(t);
            }
            for o in ops {
                if let Operand::Texture(c) = o {
                    stack.push(c);
                }
            }
        }
        out
    }

    /// Whether it is made of textures (a program on the device).
    pub fn is_graph(&self) -> bool {
        !self.operands().is_empty()
    }

    /// The records of its program on the device (texture.glsl's `texture_value`): one
    /// per texture of its tree, itself included.
    pub fn program_length(&self) -> usize {
        1 + self
            .operands()
            .iter()
            .map(|o| match o {
                Operand::Const(_) => 0,
                Operand::Texture(t) => t.program_length(),
            })
            .sum::<usize>()
    }
}

/// How a texture finds its (s, t) (pbrt-v4's TextureMapping2D; abi.h `TEXTURE_MAP_*`):
/// from the surface's (u, v) (`Uv`, with the texture's `mapping` scales and offsets), or
/// from the world point taken to texture space (the inverse of the transform in force
/// where the texture was declared).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    Uv,
    /// s = θ/π, t = φ/2π of the direction from texture space's origin.
    Spherical {
        texture_from_world: Mat4,
    },
    /// s = (π + atan2(y, x))/2π, t = z.
    Cylindrical {
        texture_from_world: Mat4,
    },
    /// s = ds + vs·q, t = dt + vt·q for the texture-space point q: the two rows s, t of
    /// (p, 1) here, with the texture space folded in.
    Planar {
        rows: [Vec4; 2],
    },
    /// pbrt-v4's TextureMapping3D: the texture-space point q itself (the 3D checkerboard
    /// looks at floor(q.x) + floor(q.y) + floor(q.z)); (s, t) = (q.x, q.y).
    Solid {
        texture_from_world: Mat4,
    },
}

impl Projection {
    /// The three rows a kernel applies to the world point (homogeneous), and the kind.
    pub fn record(&self) -> (u32, [[f32; 4]; 3]) {
        let rows = |m: &Mat4| {
            [
                m.row(0).to_array(),
                m.row(1).to_array(),
                m.row(2).to_array(),
            ]
        };
        match self {
            Projection::Uv => (TEXTURE_MAP_UV, [[0.0; 4]; 3]),
            Projection::Spherical { texture_from_world } => {
                (TEXTURE_MAP_SPHERICAL, rows(texture_from_world))
            }
            Projection::Cylindrical { texture_from_world } => {
                (TEXTURE_MAP_CYLINDRICAL, rows(texture_from_world))
            }
            Projection::Planar { rows } => (
                TEXTURE_MAP_PLANAR,
                [rows[0].to_array(), rows[1].to_array(), [0.0; 4]],
            ),
            Projection::Solid { texture_from_world } => {
                (TEXTURE_MAP_SOLID, rows(texture_from_world))
            }
        }
    }

    /// (s, t) at surface coordinates uv and world point p (texture.glsl's `texture_st`).
    pub fn st(&self, mapping: &[f32; 4], uv: Vec2, p: Vec3) -> Vec2 {
        let h = p.extend(1.0);
        match self {
            Projection::Uv => Vec2::new(
                mapping[0] * uv.x + mapping[2],
                mapping[1] * uv.y + mapping[3],
            ),
            Projection::Planar { rows } => Vec2::new(rows[0].dot(h), rows[1].dot(h)),
            Projection::Solid { texture_from_world } => {
                (*texture_from_world * h).truncate().truncate()
            }
            Projection::Cylindrical { texture_from_world } => {
                let q = *texture_from_world * h;
                Vec2::new(
                    (std::f32::consts::PI + q.y.atan2(q.x)) / std::f32::consts::TAU,
                    q.z,
                )
            }
            Projection::Spherical { texture_from_world } => {
                let d = (*texture_from_world * h).truncate().normalize();
                let mut phi = d.y.atan2(d.x);
                if phi < 0.0 {
                    phi += std::f32::consts::TAU;
                }
                Vec2::new(
                    d.z.clamp(-1.0, 1.0).acos() / std::f32::consts::PI,
                    phi / std::f32::consts::TAU,
                )
            }
        }
    }
}

/// The identity texture mapping.
pub const UV_MAPPING: [f32; 4] = [1.0, 1.0, 0.0, 0.0];

/// An environment map: an image over the sphere of directions.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    pub image: Arc<Image>,
    pub mapping: EnvMapping,
    /// The rotation from the map's frame to the world.
    pub to_world: Mat3,
}

/// The environment light: radiance arriving from every direction that leaves the scene,
/// `radiance` times the map's value in that direction (1 without a map).
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    pub radiance: Vec3,
    pub map: Option<EnvironmentMap>,
    /// pbrt-v4's `portal`: a rectangle (corners p0..p3, world space) that the light is
    /// seen through and only through: radiance arrives at a point p from the direction w
    /// when the ray from p along w crosses the rectangle, with w on the side of
    /// (p3 − p0) × (p1 − p0).
    pub portal: Option<[Vec3; 4]>,
}

/// How the integers of an 8- or 16-bit image become linear values (float images are
/// linear already). pbrt-v4's `imagemap` decodes them from sRGB unless told otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    Srgb,
    Linear,
}

/// The sRGB transfer function (IEC 61966-2-1), linear to encoded.
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// How an 8-bit image's bytes become linear values: through one of four tables of 256
/// (`table`). An image is kept as its bytes ([`TextureImage::Bytes`]) and read through its
/// table on the host and in the kernels (gpu_scene.rs stores each table once in the
/// texels), so that its values are bit for bit those of decoding the file to floats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ByteDecoding {
    pub encoding: Encoding,
    /// A grey file (with or without alpha): the image crate turns grey bytes into floats
    /// by another path than colour bytes, an ulp apart at some codes.
    pub grey: bool,
}

impl ByteDecoding {
    /// The linear value of each code: the image crate's float (about k / 255), or
    /// [`srgb_to_linear`] of it.
    pub fn table(self) -> &'static [f32; 256] {
        static TABLES: std::sync::OnceLock<[[f32; 256]; 4]> = std::sync::OnceLock::new();
        let tables = TABLES.get_or_init(|| {
            let floats = |image: image::DynamicImage| -> [f32; 256] {
                let f = image.to_rgb32f();
                std::array::from_fn(|k| f.get_pixel(k as u32, 0).0[0])
            };
            let colour = floats(image::DynamicImage::ImageRgb8(image::RgbImage::from_fn(
                256,
                1,
                |x, _| image::Rgb([x as u8; 3]),
            )));
            let grey = floats(image::DynamicImage::ImageLuma8(image::GrayImage::from_fn(
                256,
                1,
                |x, _| image::Luma([x as u8]),
            )));
            [
                colour,
                colour.map(srgb_to_linear),
                grey,
                grey.map(srgb_to_linear),
            ]
        });
        &tables[2 * self.grey as usize + (self.encoding == Encoding::Srgb) as usize]
    }
}

/// The texels of an image texture: linear floats, or (an 8-bit file) its bytes, decoded
/// through a [`ByteDecoding`]'s table where read, a quarter of the memory on the host and a third in
/// the kernels' texel data.
#[derive(Clone, Debug, PartialEq)]
pub enum TextureImage {
    Float(Image),
    Bytes {
        width: u32,
        height: u32,
        texels: Vec<[u8; 3]>,
        decoding: ByteDecoding,
    },
    /// An image's MIP levels ([`crate::mipmap::pyramid`]), from its base (which the
    /// image's size and texels are) to one texel, all floats or all bytes.
    Pyramid(Vec<TextureImage>),
}

/// An image's size and linear RGB texels, row by row from the top (for [`bilinear`]).
pub trait Texels {
    fn size(&self) -> (u32, u32);
    fn texel(&self, i: usize) -> [f32; 3];
}

impl Texels for Image {
    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    fn texel(&self, i: usize) -> [f32; 3] {
        self.pixels[i]
    }
}

impl Texels for TextureImage {
    fn size(&self) -> (u32, u32) {
        match self {
            TextureImage::Float(image) => image.size(),
            TextureImage::Bytes { width, height, .. } => (*width, *height),
            TextureImage::Pyramid(levels) => levels[0].size(),
        }
    }
    fn texel(&self, i: usize) -> [f32; 3] {
        match self {
            TextureImage::Float(image) => image.pixels[i],
            TextureImage::Pyramid(levels) => levels[0].texel(i),
            TextureImage::Bytes {
                texels, decoding, ..
            } => {
                let table = decoding.table();
                texels[i].map(|k| table[k as usize])
            }
        }
    }
}

impl TextureImage {
    /// Its MIP levels: a pyramid's, else the image alone.
    pub fn levels(&self) -> &[TextureImage] {
        match self {
            TextureImage::Pyramid(levels) => levels,
            _ => std::slice::from_ref(self),
        }
    }

    /// The texels as linear floats (a pyramid's base's).
    pub fn into_floats(self) -> Image {
        match self {
            TextureImage::Float(image) => image,
            TextureImage::Pyramid(mut levels) => levels.swap_remove(0).into_floats(),
            TextureImage::Bytes {
                width,
                height,
                texels,
                decoding,
            } => {
                let table = decoding.table();
                Image {
                    width,
                    height,
                    pixels: texels
                        .iter()
                        .map(|t| t.map(|k| table[k as usize]))
                        .collect(),
                }
            }
        }
    }
}

/// Reads an image file as linear RGB: PNG, TGA (8 or 16 bits, decoded per `encoding`),
/// Radiance HDR, OpenEXR and PFM (linear floats). The error says what is wrong with the
/// file (the caller adds where it was named).
pub fn load_image(path: &Path, encoding: Encoding) -> Result<Image, String> {
    load_texture(path, encoding).map(TextureImage::into_floats)
}

/// [`load_image`], keeping an 8-bit file's bytes ([`TextureImage::Bytes`]).
pub fn load_texture(path: &Path, encoding: Encoding) -> Result<TextureImage, String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let image = match ext.as_str() {
        "exr" => crate::io::read_exr(path).map_err(|e| format!("{e:#}"))?,
        "pfm" => {
            let bytes =
                std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            read_pfm(&bytes).map_err(|e| format!("{}: {e}", path.display()))?
        }
        "png" | "tga" | "hdr" => {
            use image::ColorType;
            let img =
                image::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
            if matches!(
                img.color(),
                ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8
            ) {
                let rgb = img.to_rgb8();
                if rgb.width() == 0 || rgb.height() == 0 {
                    return Err(format!("{}: the image is empty", path.display()));
                }
                return Ok(TextureImage::Bytes {
                    width: rgb.width(),
                    height: rgb.height(),
                    texels: rgb.pixels().map(|p| p.0).collect(),
                    decoding: ByteDecoding {
                        encoding,
                        grey: matches!(img.color(), ColorType::L8 | ColorType::La8),
                    },
                });
            }
            let integer = !matches!(img.color(), ColorType::Rgb32F | ColorType::Rgba32F);
            let rgb = img.to_rgb32f();
            let srgb = integer && encoding == Encoding::Srgb;
            let decode = |c: f32| if srgb { srgb_to_linear(c) } else { c };
            Image {
                width: rgb.width(),
                height: rgb.height(),
                pixels: rgb
                    .pixels()
                    .map(|p| [decode(p[0]), decode(p[1]), decode(p[2])])
                    .collect(),
            }
        }
        _ => {
            return Err(format!(
                "{}: unsupported image format (expected .png, .tga, .hdr, .exr or .pfm)",
                path.display()
            ))
        }
    };
    if image.width == 0 || image.height == 0 {
        return Err(format!("{}: the image is empty", path.display()));
    }
    if let Some(bad) = image
        .pixels
        .iter()
        .flatten()
        .find(|c| !c.is_finite() || **c < 0.0)
    {
        return Err(format!(
            "{}: pixel values must be finite and not negative, found {bad}",
            path.display()
        ));
    }
    Ok(TextureImage::Float(image))
}

/// A Portable Float Map: "PF" (RGB) or "Pf" (grey), width and height, a scale whose sign
/// is the byte order (negative: little-endian), then rows of 32-bit floats from the
/// bottom of the image up.
pub fn read_pfm(bytes: &[u8]) -> Result<Image, String> {
    let mut pos = 0;
    let mut token = || -> Result<String, String> {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err("truncated PFM header".into());
        }
        let t = String::from_utf8_lossy(&bytes[start..pos]).to_string();
        pos += 1; // the single whitespace byte after each header field
        Ok(t)
    };
    let channels = match token()?.as_str() {
        "PF" => 3,
        "Pf" => 1,
        other => return Err(format!("not a PFM file (magic '{other}')")),
    };
    let width: usize = token()?.parse().map_err(|_| "bad PFM width")?;
    let height: usize = token()?.parse().map_err(|_| "bad PFM height")?;
    let scale: f32 = token()?.parse().map_err(|_| "bad PFM scale")?;
    if scale == 0.0 || !scale.is_finite() {
        return Err("bad PFM scale".into());
    }
    let little = scale < 0.0;
    let count = width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(channels * 4))
        .ok_or("PFM too large")?;
    let data = bytes
        .get(pos..pos + count)
        .ok_or_else(|| format!("truncated PFM data: {width}x{height} needs {count} bytes"))?;
    let value = |i: usize| {
        let b = [
            data[4 * i],
            data[4 * i + 1],
            data[4 * i + 2],
            data[4 * i + 3],
        ];
        if little {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut pixels = vec![[0.0; 3]; width * height];
    for y in 0..height {
        let row = height - 1 - y; // the file starts at the bottom row
        for x in 0..width {
            let i = (y * width + x) * channels;
            pixels[row * width + x] = if channels == 3 {
                [value(i), value(i + 1), value(i + 2)]
            } else {
                [value(i); 3]
            };
        }
    }
    Ok(Image {
        width: width as u32,
        height: height as u32,
        pixels,
    })
}

/// What an image lookup finds beyond a side of the image (pbrt-v4's wrap modes; abi.h
/// `TEXTURE_WRAP_*`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    Repeat,
    Clamp,
    /// Texels outside the image are black.
    Black,
}

/// How an image texture is read between its texels (pbrt-v4's `imagemap` `filter`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// Bilinear between the four nearest texel centres (pbrt-v4's default).
    #[default]
    Bilinear,
    /// The texel whose centre is nearest (pbrt-v4's `point`).
    Point,
    /// Bilinear in the two MIP levels about the footprint's, blended (pbrt-v4's
    /// `trilinear`; [`crate::mipmap`]).
    Trilinear,
    /// pbrt-v4's `ewa`: a Gaussian over the footprint's ellipse in the two MIP levels
    /// about its minor axis's ([`crate::mipmap`]).
    Ewa,
}

impl Filter {
    /// The kernels' code (abi.h GpuTexture: `other.x`).
    pub fn code(self) -> u32 {
        match self {
            Filter::Bilinear => crate::abi::TEXTURE_FILTER_BILINEAR,
            Filter::Point => crate::abi::TEXTURE_FILTER_POINT,
            Filter::Trilinear => crate::abi::TEXTURE_FILTER_TRILINEAR,
            Filter::Ewa => crate::abi::TEXTURE_FILTER_EWA,
        }
    }
}

/// Texel column (or row) `i` of `n`, wrapped as `wrap` says; `None` outside a `Black`
/// image (texture.glsl `wrap_texel`).
pub(crate) fn wrap_texel(i: f32, n: i64, wrap: Wrap) -> Option<usize> {
    if wrap == Wrap::Black && (i < 0.0 || i >= n as f32) {
        return None;
    }
    let i = if wrap == Wrap::Repeat {
        i - n as f32 * (i / n as f32).floor()
    } else {
        i
    };
    Some((i as i64).clamp(0, n - 1) as usize)
}

/// The texel of `image` whose centre is nearest (x, y) in [0,1]² from its top-left
/// corner (pbrt-v4's point filter: x·width − ½ rounded; here half up, where pbrt-v4
/// rounds half away from zero), wrapped as [`bilinear`] wraps.
pub fn nearest(image: &(impl Texels + ?Sized), p: Vec2, wrap_x: Wrap, wrap_y: Wrap) -> Vec3 {
    let (w, h) = image.size();
    let round = |x: f32| x.floor() + (x - x.floor() >= 0.5) as u32 as f32;
    let x = round(p.x * w as f32 - 0.5);
    let y = round(p.y * h as f32 - 0.5);
    texel_at(image, x, y, wrap_x, wrap_y)
}

/// `image`'s texel at the integer-valued (x, y), each side wrapped as `wrap_x`, `wrap_y`
/// say ([`wrap_texel`]); outside a black side, black.
pub fn texel_at(
    image: &(impl Texels + ?Sized),
    x: f32,
    y: f32,
    wrap_x: Wrap,
    wrap_y: Wrap,
) -> Vec3 {
    let (w, h) = image.size();
    match (
        wrap_texel(x, w as i64, wrap_x),
        wrap_texel(y, h as i64, wrap_y),
    ) {
        (Some(x), Some(y)) => Vec3::from_array(image.texel(y * w as usize + x)),
        _ => Vec3::ZERO,
    }
}

/// Bilinear lookup of `image` at (x, y) in [0,1]² from its top-left corner (texel
/// centres at half-integers of x·width, y·height), each side wrapped as `wrap_x`,
/// `wrap_y` say.
pub fn bilinear(image: &(impl Texels + ?Sized), p: Vec2, wrap_x: Wrap, wrap_y: Wrap) -> Vec3 {
    let (w, h) = image.size();
    let x = p.x * w as f32 - 0.5;
    let y = p.y * h as f32 - 0.5;
    let (fx, fy) = (x.floor(), y.floor());
    let (ax, ay) = (x - fx, y - fy);
    let at = |i: f32, j: f32| texel_at(image, i, j, wrap_x, wrap_y);
    let top = at(fx, fy).lerp(at(fx + 1.0, fy), ax);
    let bottom = at(fx, fy + 1.0).lerp(at(fx + 1.0, fy + 1.0), ax);
    top.lerp(bottom, ay)
}

/// The pixel footprint at a surface point: dp/dx and dp/dy (the kernels'
/// `surface_footprint`, [`crate::gpu_scene::surface_footprint`]) and their (u, v) over the
/// surface's dp/du, dp/dv (geometry.glsl's `uv_footprint`,
/// [`crate::shading_map::uv_footprint`]). All zero: none.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Footprint {
    pub dpdx: Vec3,
    pub dpdy: Vec3,
    pub duvdx: Vec2,
    pub duvdy: Vec2,
}

impl Footprint {
    /// dp/dx and dp/dy alone (no (u, v) extent: MIP lookups read the base).
    pub fn of_point(dpdx: Vec3, dpdy: Vec3) -> Footprint {
        Footprint {
            dpdx,
            dpdy,
            ..Footprint::default()
        }
    }
}

/// The footprint's (s, t) derivatives for a texture projected as `projection` (texture.glsl
/// `texture_st_footprint`): uv's scaled by the mapping, a plane's rows applied to dp/dx and
/// dp/dy, and for the spherical and cylindrical mappings the difference of (s, t) one
/// footprint step away (the periodic coordinate taken the short way round).
pub fn st_footprint(
    projection: &Projection,
    mapping: &[f32; 4],
    uv: Vec2,
    p: Vec3,
    f: &Footprint,
) -> (Vec2, Vec2) {
    let m = Vec2::new(mapping[0], mapping[1]);
    match projection {
        Projection::Uv => (m * f.duvdx, m * f.duvdy),
        Projection::Planar { rows } => {
            let d = |v: Vec3| Vec2::new(rows[0].truncate().dot(v), rows[1].truncate().dot(v));
            (d(f.dpdx), d(f.dpdy))
        }
        Projection::Solid { .. } => (Vec2::ZERO, Vec2::ZERO),
        Projection::Spherical { .. } | Projection::Cylindrical { .. } => {
            let st = projection.st(mapping, uv, p);
            let step = |dp: Vec3| {
                let mut d = projection.st(mapping, uv, p + dp) - st;
                if matches!(projection, Projection::Spherical { .. }) {
                    d.y -= d.y.round();
                } else {
                    d.x -= d.x.round();
                }
                d
            };
            (step(f.dpdx), step(f.dpdy))
        }
    }
}

/// CPU mirror of texture.glsl's `texture_value`: the texture at surface coordinates uv
/// and world point p where the surface's unit geometric normal is ng (either side; only a
/// direction mix reads it).
pub fn texture_value(t: &Texture, uv: Vec2, p: Vec3, ng: Vec3) -> Vec3 {
    texture_value_in(t, uv, p, ng, Footprint::default())
}

/// [`texture_value`] where the pixel footprint is `footprint`: the noise textures drop the
/// octaves finer than it, MIP-mapped images read the level it spans.
pub fn texture_value_in(t: &Texture, uv: Vec2, p: Vec3, ng: Vec3, footprint: Footprint) -> Vec3 {
    let f = footprint;
    match t {
        Texture::Scale { tex, scale } => tex.value(uv, p, ng, f) * scale.value(uv, p, ng, f).x,
        Texture::Mix { tex1, tex2, amount } => {
            let a = amount.value(uv, p, ng, f).x;
            (1.0 - a) * tex1.value(uv, p, ng, f) + a * tex2.value(uv, p, ng, f)
        }
        Texture::DirectionMix { tex1, tex2, dir } => {
            let w = ng.dot(*dir).abs();
            w * tex1.value(uv, p, ng, f) + (1.0 - w) * tex2.value(uv, p, ng, f)
        }
        Texture::Noise {
            kind,
            octaves,
            omega,
            scale,
            variation,
            projection,
        } => {
            let Projection::Solid { texture_from_world } = projection else {
                unreachable!("a noise texture's point is in its texture space")
            };
            let q = (*texture_from_world * p.extend(1.0)).truncate();
            // The footprint in the texture's space.
            let linear = glam::Mat3::from_mat4(*texture_from_world);
            let len2 = (linear * f.dpdx)
                .length_squared()
                .max((linear * f.dpdy).length_squared());
            match kind {
                NoiseKind::Fbm => Vec3::splat(crate::noise::fbm(q, len2, *omega, *octaves)),
                NoiseKind::Wrinkled => {
                    Vec3::splat(crate::noise::turbulence(q, len2, *omega, *octaves))
                }
                NoiseKind::Windy => Vec3::splat(crate::noise::windy(q, len2)),
                NoiseKind::Marble => {
                    crate::noise::marble(q, len2, *omega, *octaves, *scale, *variation)
                }
            }
        }
        Texture::Dots {
            inside,
            outside,
            mapping,
            projection,
        } => {
            if crate::noise::inside_polka_dot(projection.st(mapping, uv, p)) {
                *inside
            } else {
                *outside
            }
        }
        Texture::Bilerp {
            v,
            mapping,
            projection,
        } => {
            let st = projection.st(mapping, uv, p);
            let (s, t) = (st.x, st.y);
            (1.0 - s) * (1.0 - t) * v[0]
                + (1.0 - s) * t * v[1]
                + s * (1.0 - t) * v[2]
                + s * t * v[3]
        }
        Texture::Checkerboard {
            even,
            odd,
            mapping,
            projection,
        } => {
            let parity = match projection {
                Projection::Solid { texture_from_world } => {
                    let q = (*texture_from_world * p.extend(1.0)).truncate();
                    q.x.floor() + q.y.floor() + q.z.floor()
                }
                _ => {
                    let st = projection.st(mapping, uv, p);
                    st.x.floor() + st.y.floor()
                }
            };
            if parity.rem_euclid(2.0) == 0.0 {
                *even
            } else {
                *odd
            }
        }
        Texture::Image {
            image,
            scale,
            mapping,
            wrap,
            projection,
            filter,
            max_anisotropy,
        } => {
            let st = projection.st(mapping, uv, p);
            let at = Vec2::new(st.x, 1.0 - st.y);
            let dst = st_footprint(projection, mapping, uv, p, &f);
            *scale * crate::mipmap::image_value(image, *filter, at, dst, *wrap, *max_anisotropy)
        }
    }
}

/// CPU mirror of lights.glsl's `environment_radiance`: radiance arriving along -dir.
pub fn environment_radiance(env: &Environment, dir: Vec3) -> Vec3 {
    let Some(map) = &env.map else {
        return env.radiance;
    };
    let local = map.to_world.transpose() * dir;
    let uv = map.mapping.uv(local);
    let wrap_x = if map.mapping == EnvMapping::LatLong {
        Wrap::Repeat
    } else {
        Wrap::Clamp
    };
    env.radiance * bilinear(&*map.image, uv, wrap_x, Wrap::Clamp)
}

/// How an environment map's (u, v) in [0,1]² (u to the right, v down from the top row)
/// covers the sphere of directions, in the map's own frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvMapping {
    /// Latitude-longitude (2:1), +y up: v = θ/π from +y; u = 1/2 looks along -z and u
    /// grows toward +x (so the default camera sees the map unmirrored, its centre ahead).
    LatLong,
    /// pbrt-v4's equal-area square (Clarberg's octahedral map), +z at the centre.
    EqualArea,
}

impl EnvMapping {
    pub fn code(self) -> u32 {
        match self {
            EnvMapping::LatLong => crate::abi::ENV_MAPPING_LATLONG,
            EnvMapping::EqualArea => crate::abi::ENV_MAPPING_EQUAL_AREA,
        }
    }

    /// The unit direction of the map point uv.
    pub fn direction(self, uv: Vec2) -> Vec3 {
        match self {
            EnvMapping::LatLong => {
                let theta = PI * uv.y;
                let phi = 2.0 * PI * (uv.x - 0.5);
                let s = theta.sin();
                Vec3::new(s * phi.sin(), theta.cos(), -s * phi.cos())
            }
            EnvMapping::EqualArea => equal_area_square_to_sphere(uv),
        }
    }

    /// The map point of the unit direction d (the inverse of `direction`).
    pub fn uv(self, d: Vec3) -> Vec2 {
        match self {
            EnvMapping::LatLong => {
                let v = d.y.clamp(-1.0, 1.0).acos() / PI;
                let u = d.x.atan2(-d.z) / (2.0 * PI) + 0.5;
                Vec2::new(u, v)
            }
            EnvMapping::EqualArea => equal_area_sphere_to_square(d),
        }
    }

    /// dω/d(u v): the solid angle per unit of map area at uv; 0 within 1e-4 rad of a
    /// latitude-longitude map's poles, which the kernels leave to BSDF sampling (the
    /// density of a direction sampled there, 1/sin θ, overflows the MIS sums).
    pub fn jacobian(self, uv: Vec2) -> f32 {
        match self {
            EnvMapping::LatLong => {
                let s = (PI * uv.y).sin();
                if s > 1e-4 {
                    2.0 * PI * PI * s
                } else {
                    0.0
                }
            }
            EnvMapping::EqualArea => 4.0 * PI,
        }
    }
}

/// The equal-area map from the square to the sphere: the square's diamond (|x|+|y| < 1
/// in [-1,1]²) covers z > 0, its corners z < 0; the distance from the diagonal sets z,
/// the position along it the azimuth, so equal areas map to equal solid angles.
pub fn equal_area_square_to_sphere(p: Vec2) -> Vec3 {
    let u = 2.0 * p.x - 1.0;
    let v = 2.0 * p.y - 1.0;
    let (au, av) = (u.abs(), v.abs());
    let signed = 1.0 - (au + av);
    let r = 1.0 - signed.abs();
    let phi = if r == 0.0 { 1.0 } else { (av - au) / r + 1.0 } * PI / 4.0;
    let z = (1.0 - r * r).copysign(signed);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    Vec3::new(phi.cos().copysign(u) * s, phi.sin().copysign(v) * s, z)
}

/// The inverse of [`equal_area_square_to_sphere`].
pub fn equal_area_sphere_to_square(d: Vec3) -> Vec2 {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = if a == 0.0 { 0.0 } else { x.min(y) / a };
    let mut phi = b.atan() * 2.0 / PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    Vec2::new(0.5 * (u.copysign(d.x) + 1.0), 0.5 * (v.copysign(d.y) + 1.0))
}

/// A piecewise-constant distribution over [0,1]² on a width × height grid (row 0 at
/// v = 0): a marginal CDF over rows and one CDF per row. Sampling and the pdf both read
/// only the CDFs (a cell's probability is a difference of two entries), so the pdf a
/// sample reports is exactly the density it was drawn with.
#[derive(Clone, Debug, PartialEq)]
pub struct Distribution2D {
    pub width: usize,
    pub height: usize,
    /// height + 1 entries, 0 .. 1.
    pub marginal: Vec<f32>,
    /// height rows of width + 1 entries, each 0 .. 1.
    pub conditional: Vec<f32>,
}

fn cdf_of(f: &[f64]) -> (Vec<f32>, f64) {
    let total: f64 = f.iter().sum();
    let mut cdf = Vec::with_capacity(f.len() + 1);
    cdf.push(0.0);
    let mut acc = 0.0;
    for (i, &x) in f.iter().enumerate() {
        acc += x;
        cdf.push(if i + 1 == f.len() {
            1.0
        } else if total > 0.0 {
            (acc / total) as f32
        } else {
            (i + 1) as f32 / f.len() as f32
        });
    }
    (cdf, total)
}

/// The last i in 0..n with cdf[i] <= u (cdf has n + 1 entries, cdf[0] = 0).
fn find_interval(cdf: &[f32], u: f32) -> usize {
    let (mut lo, mut hi) = (0usize, cdf.len() - 2);
    while lo < hi {
        let mid = (lo + hi + 1) / 2;
        if cdf[mid] <= u {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    lo
}

impl Distribution2D {
    /// From non-negative cell weights, row-major.
    pub fn new(weights: &[f32], width: usize, height: usize) -> Distribution2D {
        assert_eq!(weights.len(), width * height);
        let mut conditional = Vec::with_capacity(height * (width + 1));
        let mut rows = Vec::with_capacity(height);
        for y in 0..height {
            let row: Vec<f64> = weights[y * width..(y + 1) * width]
                .iter()
                .map(|&w| w.max(0.0) as f64)
                .collect();
            let (cdf, total) = cdf_of(&row);
            conditional.extend(cdf);
            rows.push(total);
        }
        let (marginal, _) = cdf_of(&rows);
        Distribution2D {
            width,
            height,
            marginal,
            conditional,
        }
    }

    fn row(&self, y: usize) -> &[f32] {
        &self.conditional[y * (self.width + 1)..(y + 1) * (self.width + 1)]
    }

    /// A point of [0,1]² for uniforms u, with its density (0 when the cell has none).
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let y = find_interval(&self.marginal, u.y);
        let (m0, m1) = (self.marginal[y], self.marginal[y + 1]);
        let row = self.row(y);
        let x = find_interval(row, u.x);
        let (c0, c1) = (row[x], row[x + 1]);
        let fy = if m1 > m0 {
            ((u.y - m0) / (m1 - m0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let fx = if c1 > c0 {
            ((u.x - c0) / (c1 - c0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let p = Vec2::new(
            ((x as f32 + fx) / self.width as f32).min(1.0 - f32::EPSILON / 2.0),
            ((y as f32 + fy) / self.height as f32).min(1.0 - f32::EPSILON / 2.0),
        );
        (p, (m1 - m0) * (c1 - c0) * (self.width * self.height) as f32)
    }

    /// The density at the point p of [0,1]².
    pub fn pdf(&self, p: Vec2) -> f32 {
        let x = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((p.y * self.height as f32) as usize).min(self.height - 1);
        let row = self.row(y);
        (self.marginal[y + 1] - self.marginal[y])
            * (row[x + 1] - row[x])
            * (self.width * self.height) as f32
    }
}

/// The sampling weights of an environment map: each pixel's mean channel, dilated to the
/// largest of its 3×3 neighbourhood (so every direction that bilinear lookup gives
/// radiance has density), times the mapping's solid angle per pixel.
pub fn environment_weights(image: &Image, mapping: EnvMapping) -> Vec<f32> {
    let (w, h) = (image.width as usize, image.height as usize);
    let mean = |x: usize, y: usize| {
        let p = image.pixels[y * w + x];
        (p[0] + p[1] + p[2]) / 3.0
    };
    let mut weights = vec![0.0; w * h];
    for y in 0..h {
        let jac = mapping.jacobian(Vec2::new(0.5, (y as f32 + 0.5) / h as f32));
        for x in 0..w {
            let mut m = 0.0f32;
            for dy in -1i64..=1 {
                let yy = (y as i64 + dy).clamp(0, h as i64 - 1) as usize;
                for dx in -1i64..=1 {
                    let xx = match mapping {
                        EnvMapping::LatLong => (x as i64 + dx).rem_euclid(w as i64) as usize,
                        EnvMapping::EqualArea => (x as i64 + dx).clamp(0, w as i64 - 1) as usize,
                    };
                    m = m.max(mean(xx, yy));
                }
            }
            weights[y * w + x] = m * jac;
        }
    }
    weights
}

/// The radiance of the map averaged over the sphere of directions (each pixel weighted
/// by its solid angle), for the light's power.
pub fn environment_mean(image: &Image, mapping: EnvMapping) -> Vec3 {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut sum = [0.0f64; 3];
    let mut total = 0.0f64;
    for y in 0..h {
        let jac = mapping.jacobian(Vec2::new(0.5, (y as f32 + 0.5) / h as f32)) as f64;
        for x in 0..w {
            let p = image.pixels[y * w + x];
            for c in 0..3 {
                sum[c] += p[c] as f64 * jac;
            }
            total += jac;
        }
    }
    if total == 0.0 {
        return Vec3::ZERO;
    }
    Vec3::new(
        (sum[0] / total) as f32,
        (sum[1] / total) as f32,
        (sum[2] / total) as f32,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 8-bit file read as a texture keeps its bytes, and every texel reads bit for bit
    /// as decoding the file to floats did (the image crate's k / 255, then `srgb_to_linear`
    /// unless linear), in each of the 8-bit layouts (mutation: a table entry off by one
    /// ulp, or the channels' order changed, fails). 16-bit files stay floats.
    #[test]
    fn eight_bit_textures_read_as_their_decoded_floats() {
        let dir = std::env::temp_dir().join(format!("lightpath-bytes-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let codes: Vec<u8> = (0..256 * 3).map(|i| (i * 7 % 256) as u8).collect();
        for (name, data, layout) in [
            ("rgb.png", codes.clone(), image::ExtendedColorType::Rgb8),
            ("rgba.png", codes.clone(), image::ExtendedColorType::Rgba8),
            ("grey.png", codes.clone(), image::ExtendedColorType::L8),
            (
                "grey-alpha.png",
                codes.clone(),
                image::ExtendedColorType::La8,
            ),
            ("rgb.tga", codes.clone(), image::ExtendedColorType::Rgb8),
        ] {
            let channels = match layout {
                image::ExtendedColorType::Rgba8 => 4,
                image::ExtendedColorType::L8 => 1,
                image::ExtendedColorType::La8 => 2,
                _ => 3,
            };
            let n = (data.len() / channels) as u32;
            let path = dir.join(name);
            image::save_buffer(&path, &data[..n as usize * channels], n, 1, layout).unwrap();
            let floats = image::open(&path).unwrap().to_rgb32f();
            for encoding in [Encoding::Srgb, Encoding::Linear] {
                let t = load_texture(&path, encoding).unwrap();
                assert!(matches!(t, TextureImage::Bytes { .. }), "{name}");
                assert_eq!(t.size(), (n, 1));
                for (i, p) in floats.pixels().enumerate() {
                    let want = p.0.map(|c| match encoding {
                        Encoding::Srgb => srgb_to_linear(c),
                        Encoding::Linear => c,
                    });
                    assert_eq!(
                        t.texel(i).map(f32::to_bits),
                        want.map(f32::to_bits),
                        "{name} {i}"
                    );
                }
                assert_eq!(t.clone().into_floats().pixels[5], t.texel(5));
            }
        }
        let wide: Vec<u16> = (0..64 * 3).map(|i| (i * 1021 % 65536) as u16).collect();
        let path = dir.join("wide.png");
        let img = image::ImageBuffer::<image::Rgb<u16>, _>::from_raw(64, 1, wide).unwrap();
        img.save(&path).unwrap();
        assert!(matches!(
            load_texture(&path, Encoding::Srgb).unwrap(),
            TextureImage::Float(_)
        ));
        std::fs::remove_dir_all(&dir).ok();
    }

    fn rng(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 40) as f32) / (1u64 << 24) as f32
    }

    #[test]
    fn the_mappings_invert_exactly() {
        let mut s = 7u64;
        for mapping in [EnvMapping::LatLong, EnvMapping::EqualArea] {
            for _ in 0..20_000 {
                let uv = Vec2::new(rng(&mut s), rng(&mut s).clamp(1e-4, 1.0 - 1e-4));
                let d = mapping.direction(uv);
                assert!((d.length() - 1.0).abs() < 1e-5, "{mapping:?} {uv} -> {d}");
                let back = mapping.uv(d);
                let mut du = (back.x - uv.x).abs();
                if mapping == EnvMapping::LatLong {
                    du = du.min(1.0 - du); // u wraps
                }
                assert!(
                    du < 2e-4 && (back.y - uv.y).abs() < 2e-4,
                    "{mapping:?}: {uv} -> {d} -> {back}"
                );
                // And from the direction side.
                let again = mapping.direction(back);
                assert!((again - d).length() < 1e-3, "{mapping:?}: {d} -> {again}");
            }
        }
    }

    #[test]
    fn the_lat_long_map_is_oriented_as_documented() {
        let m = EnvMapping::LatLong;
        assert!((m.direction(Vec2::new(0.5, 0.5)) - Vec3::NEG_Z).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.75, 0.5)) - Vec3::X).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.25, 0.5)) - Vec3::NEG_X).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.0, 0.5)) - Vec3::Z).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.3, 0.0)) - Vec3::Y).length() < 1e-6);
        assert!((m.direction(Vec2::new(0.3, 1.0)) - Vec3::NEG_Y).length() < 1e-6);
        let e = EnvMapping::EqualArea;
        assert!((e.direction(Vec2::new(0.5, 0.5)) - Vec3::Z).length() < 1e-6);
        assert!((e.direction(Vec2::new(0.0, 0.0)) - Vec3::NEG_Z).length() < 1e-6);
        assert!((e.direction(Vec2::new(1.0, 0.5)) - Vec3::X).length() < 1e-6);
    }

    /// The Jacobians are right: ∫ jacobian du dv over the square is 4π, and the
    /// equal-area map's cells all cover the same solid angle (checked by the spread of
    /// directions of cells' corners: the area of a cell's spherical quad).
    #[test]
    fn the_jacobians_integrate_to_the_sphere() {
        for mapping in [EnvMapping::LatLong, EnvMapping::EqualArea] {
            let n = 400;
            let mut sum = 0.0f64;
            for j in 0..n {
                for i in 0..n {
                    let uv = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    sum += mapping.jacobian(uv) as f64 / (n * n) as f64;
                }
            }
            assert!(
                (sum - 4.0 * std::f64::consts::PI).abs() < 1e-3,
                "{mapping:?}: {sum}"
            );
        }
        // Equal area: a cell's solid angle by the triangle-fan area of its corners.
        let m = EnvMapping::EqualArea;
        let n = 16;
        let tri = |a: Vec3, b: Vec3, c: Vec3| {
            // Van Oosterom & Strackee.
            let num = a.dot(b.cross(c)).abs();
            let den = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
            2.0 * num.atan2(den)
        };
        for j in 0..n {
            for i in 0..n {
                // Subdivide each cell finely so the spherical quad is well approximated.
                let k = 8;
                let mut area = 0.0;
                for b in 0..k {
                    for a in 0..k {
                        let p = |da: usize, db: usize| {
                            m.direction(Vec2::new(
                                (i as f32 + (a + da) as f32 / k as f32) / n as f32,
                                (j as f32 + (b + db) as f32 / k as f32) / n as f32,
                            ))
                        };
                        area += tri(p(0, 0), p(1, 0), p(1, 1)) + tri(p(0, 0), p(1, 1), p(0, 1));
                    }
                }
                let expected = 4.0 * PI / (n * n) as f32;
                assert!(
                    (area - expected).abs() < 0.02 * expected,
                    "cell ({i},{j}): {area} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn distribution_samples_follow_their_pdf() {
        let (w, h) = (7, 5);
        let weights: Vec<f32> = (0..w * h)
            .map(|i| {
                if i % 6 == 0 {
                    0.0
                } else {
                    (i % 5) as f32 + 0.5
                }
            })
            .collect();
        let d = Distribution2D::new(&weights, w, h);
        let total: f32 = weights.iter().sum();
        let mut counts = vec![0u32; w * h];
        let mut s = 3u64;
        let n = 200_000;
        for _ in 0..n {
            let (p, pdf) = d.sample(Vec2::new(rng(&mut s), rng(&mut s)));
            assert!(
                (d.pdf(p) - pdf).abs() <= 1e-5 * pdf.max(1.0),
                "{p}: {pdf} vs {}",
                d.pdf(p)
            );
            assert!(pdf > 0.0);
            let x = (p.x * w as f32) as usize;
            let y = (p.y * h as f32) as usize;
            counts[y * w + x] += 1;
        }
        for i in 0..w * h {
            let expected = weights[i] / total;
            let got = counts[i] as f32 / n as f32;
            assert!(
                (got - expected).abs() < 0.005,
                "cell {i}: {got} vs {expected}"
            );
            // The pdf of a cell is its share times the cell count.
            let p = Vec2::new(
                ((i % w) as f32 + 0.5) / w as f32,
                ((i / w) as f32 + 0.5) / h as f32,
            );
            assert!((d.pdf(p) - expected * (w * h) as f32).abs() < 1e-4);
        }
    }

    #[test]
    fn eight_bit_images_are_decoded_from_srgb_unless_linear() {
        let dir = std::env::temp_dir().join(format!("lightpath-srgb-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("grey.png");
        image::save_buffer(&path, &[128, 255, 0], 1, 1, image::ExtendedColorType::Rgb8).unwrap();
        let srgb = load_image(&path, Encoding::Srgb).unwrap().pixels[0];
        assert!((srgb[0] - 0.215_861).abs() < 1e-4, "{srgb:?}");
        assert_eq!((srgb[1], srgb[2]), (1.0, 0.0));
        let linear = load_image(&path, Encoding::Linear).unwrap().pixels[0];
        assert!((linear[0] - 128.0 / 255.0).abs() < 1e-6);
        std::fs::remove_dir_all(&dir).ok();
        // Texture lookup: t = 0 is the bottom row; the image repeats.
        let img = Image {
            width: 2,
            height: 2,
            pixels: vec![[1.0; 3], [2.0; 3], [3.0; 3], [4.0; 3]],
        };
        let t = Texture::Image {
            image: std::sync::Arc::new(TextureImage::Float(img)),
            scale: Vec3::ONE,
            mapping: UV_MAPPING,
            wrap: Wrap::Repeat,
            projection: Projection::Uv,
            filter: Filter::Bilinear,
            max_anisotropy: DEFAULT_MAX_ANISOTROPY,
        };
        assert_eq!(
            texture_value(&t, Vec2::new(0.25, 0.25), Vec3::ZERO, Vec3::Z),
            Vec3::splat(3.0)
        );
        assert_eq!(
            texture_value(&t, Vec2::new(1.75, 0.75), Vec3::ZERO, Vec3::Z),
            Vec3::splat(2.0)
        );
        assert_eq!(
            texture_value(&t, Vec2::new(0.5, 0.25), Vec3::ZERO, Vec3::Z),
            Vec3::splat(3.5)
        );
        // Between the last and the first column: repeating mixes them, clamping keeps
        // the last, black fades to 0 beyond the side; outside entirely, black is 0.
        let filtered = |wrap, filter| match &t {
            Texture::Image { image, .. } => Texture::Image {
                image: image.clone(),
                scale: Vec3::ONE,
                mapping: UV_MAPPING,
                wrap,
                projection: Projection::Uv,
                filter,
                max_anisotropy: DEFAULT_MAX_ANISOTROPY,
            },
            _ => unreachable!(),
        };
        let with = |wrap| filtered(wrap, Filter::Bilinear);
        let at = Vec2::new(1.0, 0.25);
        assert_eq!(
            texture_value(&with(Wrap::Repeat), at, Vec3::ZERO, Vec3::Z),
            Vec3::splat(3.5)
        );
        assert_eq!(
            texture_value(&with(Wrap::Clamp), at, Vec3::ZERO, Vec3::Z),
            Vec3::splat(4.0)
        );
        assert_eq!(
            texture_value(&with(Wrap::Black), at, Vec3::ZERO, Vec3::Z),
            Vec3::splat(2.0)
        );
        assert_eq!(
            texture_value(
                &with(Wrap::Black),
                Vec2::new(1.6, 0.25),
                Vec3::ZERO,
                Vec3::Z
            ),
            Vec3::ZERO
        );
        assert_eq!(
            texture_value(
                &with(Wrap::Clamp),
                Vec2::new(-3.0, 0.25),
                Vec3::ZERO,
                Vec3::Z
            ),
            Vec3::splat(3.0)
        );
        // pbrt-v4's point filter: the texel whose centre is nearest (s·w − ½ rounded), on
        // either side of the columns' midpoint, and past the side as each wrap says.
        let point = |wrap| filtered(wrap, Filter::Point);
        for (wrap, s, want) in [
            (Wrap::Repeat, 0.49, 3.0),
            (Wrap::Repeat, 0.51, 4.0),
            (Wrap::Repeat, 1.2, 3.0),
            (Wrap::Clamp, 1.2, 4.0),
            (Wrap::Black, 1.2, 0.0),
            (Wrap::Black, 0.99, 4.0),
        ] {
            assert_eq!(
                texture_value(&point(wrap), Vec2::new(s, 0.3), Vec3::ZERO, Vec3::Z),
                Vec3::splat(want),
                "{wrap:?} at s = {s}"
            );
        }
    }

    #[test]
    fn pfm_reads_both_byte_orders_bottom_up() {
        let mut le = b"PF\n2 1\n-1.0\n".to_vec();
        for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.0] {
            le.extend(v.to_le_bytes());
        }
        let img = read_pfm(&le).unwrap();
        assert_eq!((img.width, img.height), (2, 1));
        assert_eq!(img.pixels, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        let mut be = b"Pf\n1 2\n1.0\n".to_vec();
        for v in [7.0f32, 8.0] {
            be.extend(v.to_be_bytes());
        }
        let img = read_pfm(&be).unwrap();
        // The first row in the file is the bottom one.
        assert_eq!(img.pixels, vec![[8.0; 3], [7.0; 3]]);
        assert!(read_pfm(b"PF\n2 2\n-1.0\n1234")
            .unwrap_err()
            .contains("truncated"));
        assert!(read_pfm(b"P6\n2 2\n").is_err());
    }
}
