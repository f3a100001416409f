//! MIP maps for pbrt-v4's image textures (its `imagemap`), as pbrt-v4 builds and reads them:
//! a pyramid whose base is the image, resampled up to a power of two on each side where it
//! is not one (a separable windowed sinc of radius 2 with τ = 2, four texels per axis,
//! weights normalised, results clamped at 0), each level above it the 2×2 box average of
//! the one below, down to one texel; every level kept in the image's own kind (an 8-bit
//! image's levels are bytes, rounded through its encoding). A lookup picks its level from
//! the pixel footprint's extent in (s, t) (`2 max |∂(s,t)/∂(x,y)|`, level
//! `levels − 1 + log2(width)`) and reads it as `filter` says: the nearest texel or
//! bilinear at that level's floor, or (trilinear) between it and the next. EWA (pbrt-v4's
//! elliptically weighted average, after Heckbert) weighs the texels under the footprint's
//! ellipse by a Gaussian, in the level of the ellipse's minor axis and the next ([`ewa`]).
//!
//! The CPU mirror of texture.glsl's `image_value`; the kernels read the levels one after
//! another in the texel data ([`crate::gpu_scene`]), each `max(1, w >> l) × max(1, h >> l)`.
use crate::io::Image;
use crate::texture::{
    bilinear, nearest, texel_at, wrap_texel, ByteDecoding, Encoding, Filter, Texels, TextureImage,
    Wrap,
};
use glam::{Vec2, Vec3};

/// pbrt-v4's windowed sinc: sinc(x) sinc(x / τ) within `radius`, else 0.
fn windowed_sinc(x: f32, radius: f32, tau: f32) -> f32 {
    let sinc = |x: f32| {
        let x = std::f32::consts::PI * x;
        if 1.0 - x * x == 1.0 {
            1.0
        } else {
            x.sin() / x
        }
    };
    if x.abs() > radius {
        0.0
    } else {
        sinc(x) * sinc(x / tau)
    }
}

/// Per texel of a side resampled from `old` to `new` texels (new ≥ old): the first of the
/// four source texels it reads and their normalised weights.
fn resample_weights(old: u32, new: u32) -> Vec<(i64, [f32; 4])> {
    (0..new)
        .map(|i| {
            let centre = (i as f32 + 0.5) * old as f32 / new as f32;
            let first = (centre - 2.0 + 0.5).floor();
            let mut w: [f32; 4] =
                std::array::from_fn(|j| windowed_sinc(first + j as f32 + 0.5 - centre, 2.0, 2.0));
            let inv = 1.0 / w.iter().sum::<f32>();
            for v in &mut w {
                *v *= inv;
            }
            (first as i64, w)
        })
        .collect()
}

/// The image resampled up to `w × h` (pbrt-v4's FloatResize): in x, then in y, texels
/// beyond the sides as `wrap` says, results clamped at 0.
fn resize_up(image: &Image, w: u32, h: u32, wrap: Wrap) -> Image {
    let xw = resample_weights(image.width, w);
    let yw = resample_weights(image.height, h);
    let at = |x: i64, y: u32| match wrap_texel(x as f32, image.width as i64, wrap) {
        Some(x) => Vec3::from_array(image.pixels[(y * image.width) as usize + x]),
        None => Vec3::ZERO,
    };
    // In x, every source row.
    let mut rows = vec![Vec3::ZERO; (w * image.height) as usize];
    for y in 0..image.height {
        for (x, (first, wt)) in xw.iter().enumerate() {
            rows[(y * w) as usize + x] =
                (0..4).fold(Vec3::ZERO, |s, j| s + wt[j] * at(first + j as i64, y));
        }
    }
    let row = |x: u32, y: i64| match wrap_texel(y as f32, image.height as i64, wrap) {
        Some(y) => rows[y * w as usize + x as usize],
        None => Vec3::ZERO,
    };
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for (first, wt) in &yw {
        for x in 0..w {
            let v = (0..4).fold(Vec3::ZERO, |s, j| s + wt[j] * row(x, first + j as i64));
            pixels.push(v.max(Vec3::ZERO).to_array());
        }
    }
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// The level above one of `width` × `height` texels (`at(i)`: texel i's linear value, row
/// by row): each texel the mean of the 2 × 2 below it (a side of one texel read twice).
fn halve(width: u32, height: u32, at: impl Fn(usize) -> Vec3) -> Image {
    let (w, h) = ((width / 2).max(1), (height / 2).max(1));
    let at = |x: u32, y: u32| at((y.min(height - 1) * width + x.min(width - 1)) as usize);
    let mut pixels = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let (x2, y2) = (2 * x, 2 * y);
            let s = at(x2, y2) + at(x2 + 1, y2) + at(x2, y2 + 1) + at(x2 + 1, y2 + 1);
            pixels.push((0.25 * s).to_array());
        }
    }
    Image {
        width: w,
        height: h,
        pixels,
    }
}

/// [`halve`] of a level of floats.
fn halve_floats(image: &Image) -> Image {
    halve(image.width, image.height, |i| {
        Vec3::from_array(image.pixels[i])
    })
}

/// Linear values to an 8-bit encoding's codes: the values at which each code begins (code k
/// from the k-th on: the encoding's curve at the half-codes (k − ½)/255, so that a value's
/// code is its encoding times 255, rounded: pbrt-v4's v·255 + ½, or the sRGB curve's,
/// truncated), and per 1/4096 of [0, 1] the code where that bucket begins (a bucket holds
/// at most two beginnings: a step or two past the table finds the code).
struct Quantizer {
    starts: [f32; 255],
    buckets: Vec<u8>,
}

const BUCKETS: usize = 4096;

impl Quantizer {
    fn of(encoding: Encoding) -> &'static Quantizer {
        static TABLES: std::sync::OnceLock<[Quantizer; 2]> = std::sync::OnceLock::new();
        let tables = TABLES.get_or_init(|| {
            let make = |curve: fn(f32) -> f32| {
                let starts: [f32; 255] = std::array::from_fn(|k| curve((k as f32 + 0.5) / 255.0));
                let buckets = (0..=BUCKETS)
                    .map(|b| starts.partition_point(|&t| t <= b as f32 / BUCKETS as f32) as u8)
                    .collect();
                Quantizer { starts, buckets }
            };
            [make(|v| v), make(crate::texture::srgb_to_linear)]
        });
        &tables[(encoding == Encoding::Srgb) as usize]
    }

    /// The code of linear value v (0 below the first beginning, 255 from the last on).
    fn code(&self, v: f32) -> u8 {
        if !(v > 0.0) {
            return self.starts.partition_point(|&t| t <= v) as u8;
        }
        let mut k = self.buckets[((v * BUCKETS as f32) as usize).min(BUCKETS)] as usize;
        while k < 255 && self.starts[k] <= v {
            k += 1;
        }
        k as u8
    }
}

/// A level of linear floats as bytes in `decoding`'s encoding ([`Quantizer`]).
fn quantize(image: &Image, decoding: ByteDecoding) -> TextureImage {
    let q = Quantizer::of(decoding.encoding);
    TextureImage::Bytes {
        width: image.width,
        height: image.height,
        texels: image.pixels.iter().map(|p| p.map(|v| q.code(v))).collect(),
        decoding,
    }
}

/// The image's pyramid (module docs): the levels from the base (a power of two on each
/// side; the image itself where it is one) to one texel, in the image's own kind. An
/// image that is a pyramid already is returned as it is.
pub fn pyramid(image: TextureImage, wrap: Wrap) -> TextureImage {
    if let TextureImage::Pyramid(_) = image {
        return image;
    }
    let (w, h) = image.size();
    let pow2 = w.is_power_of_two() && h.is_power_of_two();
    let decoding = match &image {
        TextureImage::Bytes { decoding, .. } => Some(*decoding),
        _ => None,
    };
    // The level above the base, from the base's linear values (an 8-bit power-of-two base
    // read through its table where it is), then each level from the one below.
    let resampled = (!pow2).then(|| {
        let floats = image.clone().into_floats();
        resize_up(&floats, w.next_power_of_two(), h.next_power_of_two(), wrap)
    });
    let mut upper: Vec<Image> = Vec::new();
    if w > 1 || h > 1 {
        upper.push(match (&resampled, &image) {
            (Some(r), _) => halve_floats(r),
            (None, TextureImage::Float(f)) => halve_floats(f),
            (
                None,
                TextureImage::Bytes {
                    texels, decoding, ..
                },
            ) => {
                let table = decoding.table();
                halve(w, h, |i| {
                    Vec3::from_array(texels[i].map(|k| table[k as usize]))
                })
            }
            (None, TextureImage::Pyramid(_)) => unreachable!("returned above"),
        });
    }
    loop {
        let Some(below) = upper.last() else {
            break;
        };
        if below.width == 1 && below.height == 1 {
            break;
        }
        let next = halve_floats(below);
        upper.push(next);
    }
    let store = |l: Image| match decoding {
        Some(d) => quantize(&l, d),
        None => TextureImage::Float(l),
    };
    let mut levels = Vec::with_capacity(upper.len() + 1);
    levels.push(match resampled {
        Some(r) => store(r),
        // (A power-of-two base is the image itself: an 8-bit file's own bytes.)
        None => image,
    });
    levels.extend(upper.into_iter().map(store));
    TextureImage::Pyramid(levels)
}

/// The footprint's extent that picks a level (pbrt-v4's non-EWA width): twice the largest
/// of |∂s/∂x|, |∂t/∂x|, |∂s/∂y|, |∂t/∂y|.
pub fn filter_width(dst: (Vec2, Vec2)) -> f32 {
    2.0 * dst.0.abs().max_element().max(dst.1.abs().max_element())
}

/// A footprint's component this large or larger (or NaN) makes it degenerate: read as none.
const DEGENERATE: f32 = (1u64 << 60) as f32;

/// `image` (a pyramid, or one level) at `at` (x to the right, y down, in [0,1]²) where
/// the footprint's (s, t) derivatives are `dst`, read as `filter` says (module docs; EWA's
/// footprint at most `max_anisotropy` times longer than wide). A footprint with a component
/// NaN, infinite or of 2^60 or more is read as none. GLSL: texture.glsl image_value.
pub fn image_value(
    image: &TextureImage,
    filter: Filter,
    at: Vec2,
    dst: (Vec2, Vec2),
    wrap: Wrap,
    max_anisotropy: f32,
) -> Vec3 {
    let levels = image.levels();
    let n = levels.len();
    let bilerp = |l: usize| bilinear(&levels[l], at, wrap, wrap);
    // A footprint with a component NaN, infinite or of 2^60 or more (a degenerate
    // differential) is none.
    let sane = [dst.0, dst.1]
        .iter()
        .all(|d| d.x.abs() < DEGENERATE && d.y.abs() < DEGENERATE);
    let dst = if sane { dst } else { (Vec2::ZERO, Vec2::ZERO) };
    if n <= 1 {
        return match filter {
            Filter::Point => nearest(&levels[0], at, wrap, wrap),
            _ => bilerp(0),
        };
    }
    if filter == Filter::Ewa {
        // (In the image's frame, y down: the footprint turned as `at` was.)
        let flip = Vec2::new(1.0, -1.0);
        return ewa(levels, at, dst.0 * flip, dst.1 * flip, wrap, max_anisotropy);
    }
    let level = (n - 1) as f32 + filter_width(dst).max(1e-8).log2();
    if level >= (n - 1) as f32 {
        return Vec3::from_array(levels[n - 1].texel(0));
    }
    let i = level.floor().max(0.0) as usize;
    match filter {
        Filter::Point => nearest(&levels[i], at, wrap, wrap),
        Filter::Bilinear => bilerp(i),
        Filter::Trilinear | Filter::Ewa => {
            // (EWA returned above.)
            if i == 0 {
                bilerp(0)
            } else {
                let t = level - i as f32;
                (1.0 - t) * bilerp(i) + t * bilerp(i + 1)
            }
        }
    }
}

/// pbrt-v4's EWA lookup of the pyramid `levels` at `at` under the footprint `d0`, `d1`
/// (the image's frame, [0,1]², y down): the longer axis no more than `most` times the
/// shorter (pbrt-v4's `maxanisotropy`: the shorter grown to it); no shorter axis,
/// bilinear at the base; else [`ewa_level`] at `lod = levels − 1 + log2 |shorter|` (at
/// least 0) and the next, blended by its fraction, a level past the top its one texel.
/// texture.glsl `image_ewa_lod` and `image_value`.
pub fn ewa(levels: &[TextureImage], at: Vec2, d0: Vec2, d1: Vec2, wrap: Wrap, most: f32) -> Vec3 {
    let (mut d0, mut d1) = (d0, d1);
    if d0.length_squared() < d1.length_squared() {
        std::mem::swap(&mut d0, &mut d1);
    }
    let longer = d0.length();
    let mut shorter = d1.length();
    if shorter * most < longer && shorter > 0.0 {
        let k = longer / (shorter * most);
        d1 *= k;
        shorter *= k;
    }
    if shorter == 0.0 {
        return bilinear(&levels[0], at, wrap, wrap);
    }
    let n = levels.len();
    let lod = ((n - 1) as f32 + shorter.log2()).max(0.0);
    let first = lod.floor() as usize;
    let blend = lod - first as f32;
    let level = |l: usize| match levels.get(l) {
        Some(image) => ewa_level(image, at, d0, d1, wrap),
        None => Vec3::from_array(levels[n - 1].texel(0)),
    };
    (1.0 - blend) * level(first) + blend * level(first + 1)
}

/// One level of [`ewa`]: in the level's texels (centres at half-integers), the ellipse
/// `q(x) = A x² + B x y + C y² < 1` whose quadratic form is the inverse of the footprint's
/// covariance `d0 d0ᵀ + d1 d1ᵀ` grown by one texel each way (the form's coefficients
/// divided by its determinant), each texel centre inside it weighted by the Gaussian
/// `exp(−2 q) − exp(−2)`, `q` quantised down to 1/128 (pbrt-v4's table of 128), the
/// weights normalised; texels wrapped as `wrap` says (outside a black image: black,
/// weighed still). texture.glsl `image_ewa_level`.
pub fn ewa_level(image: &TextureImage, at: Vec2, d0: Vec2, d1: Vec2, wrap: Wrap) -> Vec3 {
    let (w, h) = image.size();
    let res = Vec2::new(w as f32, h as f32);
    let c = at * res - 0.5;
    let (d0, d1) = (d0 * res, d1 * res);
    let mut a = d0.y * d0.y + d1.y * d1.y + 1.0;
    let mut b = -2.0 * (d0.x * d0.y + d1.x * d1.y);
    let mut cc = d0.x * d0.x + d1.x * d1.x + 1.0;
    let inv_f = 1.0 / (a * cc - 0.25 * b * b);
    a *= inv_f;
    b *= inv_f;
    cc *= inv_f;
    let det = 4.0 * a * cc - b * b;
    let hx = 2.0 * (det * cc).max(0.0).sqrt() / det;
    let hy = 2.0 * (a * det).max(0.0).sqrt() / det;
    let (x0, x1) = ((c.x - hx).ceil() as i64, (c.x + hx).floor() as i64);
    let (y0, y1) = ((c.y - hy).ceil() as i64, (c.y + hy).floor() as i64);
    let (mut sum, mut weights) = (Vec3::ZERO, 0.0);
    for y in y0..=y1 {
        let dy = y as f32 - c.y;
        for x in x0..=x1 {
            let dx = x as f32 - c.x;
            let q = a * dx * dx + b * dx * dy + cc * dy * dy;
            if q < 1.0 {
                let k = ((q * 128.0) as i64).min(127) as f32 / 127.0;
                let weight = (-2.0 * k).exp() - (-2.0f32).exp();
                let texel = texel_at(image, x as f32, y as f32, wrap, wrap);
                sum += weight * texel;
                weights += weight;
            }
        }
    }
    sum / weights
}

#[cfg(test)]
mod tests {
    use super::*;

    fn floats(w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> TextureImage {
        TextureImage::Float(Image {
            width: w,
            height: h,
            pixels: (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .map(|(x, y)| f(x, y))
                .collect(),
        })
    }

    /// A power-of-two image's pyramid: its base is the image, each level the 2 × 2 means
    /// of the one below, sides halving to one texel (a side of one read twice), and the
    /// top the image's mean.
    /// EWA's weights are normalised: a constant image reads as itself under any footprint
    /// (long, turned, clamped by the anisotropy, past the top level, none), in every wrap
    /// but black (whose outside texels are black, weighed still).
    #[test]
    fn ewa_reads_a_constant_image_as_itself() {
        let image = pyramid(floats(16, 8, |_, _| [0.25, 0.5, 0.75]), Wrap::Repeat);
        let footprints = [
            (Vec2::ZERO, Vec2::ZERO),
            (Vec2::new(0.01, 0.0), Vec2::new(0.0, 0.002)),
            (Vec2::new(0.3, 0.2), Vec2::new(-0.01, 0.02)),
            (Vec2::new(0.001, 0.0), Vec2::ZERO),
            (Vec2::new(3.0, 1.0), Vec2::new(-2.0, 4.0)),
        ];
        for wrap in [Wrap::Repeat, Wrap::Clamp] {
            for (d0, d1) in footprints {
                for most in [1.0, 8.0] {
                    let at = Vec2::new(0.3, 0.9);
                    let v = image_value(&image, Filter::Ewa, at, (d0, d1), wrap, most);
                    assert!(
                        (v - Vec3::new(0.25, 0.5, 0.75)).abs().max_element() < 1e-5,
                        "{wrap:?} {d0} {d1} {most}: {v}"
                    );
                }
            }
        }
    }

    /// One EWA level is the Gaussian-weighted mean over every texel of the level under the
    /// ellipse `xᵀ Σ⁻¹ x < 1`, Σ the footprint's covariance `d0 d0ᵀ + d1 d1ᵀ` plus one texel²
    /// each way (a brute-force sum over a square of texels well past the ellipse, with the
    /// inverse taken by glam: the bounding box cuts no texel out); and centred on a texel
    /// centre of a ramp, the weights (symmetric about it) read the ramp's value there.
    #[test]
    fn an_ewa_level_is_the_gaussian_mean_under_the_ellipse() {
        let ramp = |x: u32, y: u32| [x as f32, y as f32, (x * 3 + y) as f32 % 5.0];
        let image = floats(32, 16, ramp);
        let brute = |at: Vec2, d0: Vec2, d1: Vec2| {
            let res = Vec2::new(32.0, 16.0);
            let c = at * res - 0.5;
            let (d0, d1) = (d0 * res, d1 * res);
            let cov = glam::Mat2::from_cols(d0 * d0.x + d1 * d1.x, d0 * d0.y + d1 * d1.y)
                + glam::Mat2::IDENTITY;
            let inv = cov.inverse();
            let (mut sum, mut weights) = (Vec3::ZERO, 0.0);
            for y in -40i64..=56 {
                for x in -40i64..=72 {
                    let v = Vec2::new(x as f32, y as f32) - c;
                    let q = v.dot(inv * v);
                    if q < 1.0 {
                        let k = ((q * 128.0) as i64).min(127) as f32 / 127.0;
                        let w = (-2.0 * k).exp() - (-2.0f32).exp();
                        let texel =
                            image.texel(y.rem_euclid(16) as usize * 32 + x.rem_euclid(32) as usize);
                        sum += w * Vec3::from_array(texel);
                        weights += w;
                    }
                }
            }
            sum / weights
        };
        let cases = [
            (
                Vec2::new(0.5, 0.5),
                Vec2::new(0.05, 0.0),
                Vec2::new(0.0, 0.1),
            ),
            (
                Vec2::new(0.13, 0.71),
                Vec2::new(0.2, 0.1),
                Vec2::new(-0.01, 0.02),
            ),
            (
                Vec2::new(0.91, 0.05),
                Vec2::new(-0.1, 0.3),
                Vec2::new(0.05, 0.02),
            ),
            (Vec2::new(0.4, 0.3), Vec2::ZERO, Vec2::ZERO),
        ];
        for (at, d0, d1) in cases {
            let got = ewa_level(&image, at, d0, d1, Wrap::Repeat);
            let want = brute(at, d0, d1);
            assert!(
                (got - want).abs().max_element() < 1e-4 * want.abs().max_element().max(1.0),
                "{at} {d0} {d1}: {got} against {want}"
            );
        }
        // Texel (10, 6)'s centre, far from the sides: the ramp's (x, y) there.
        let at = Vec2::new(10.5 / 32.0, 6.5 / 16.0);
        let v = ewa_level(
            &image,
            at,
            Vec2::new(0.04, 0.05),
            Vec2::new(-0.03, 0.02),
            Wrap::Clamp,
        );
        assert!(
            (v.truncate() - Vec2::new(10.0, 6.0)).abs().max_element() < 1e-4,
            "{v}"
        );
    }

    /// EWA filters along the footprint's ellipse, turned as the image is read (y down): on
    /// stripes constant along (1, −1) in the image (x + y), so along (1, 1) in (s, t), a
    /// footprint long along the stripes keeps their contrast and one long across them
    /// blurs it away; with the anisotropy at 1 both are circles of the longer radius.
    #[test]
    fn ewa_blurs_across_its_ellipse_not_along_it() {
        let stripes = |x: u32, y: u32| {
            let v = 0.5 + 0.5 * (std::f32::consts::TAU * (x + y) as f32 / 8.0).cos();
            [v; 3]
        };
        let image = pyramid(floats(64, 64, stripes), Wrap::Repeat);
        // A crest: texel (8, 8)'s centre (x + y = 16); (s, t) = (x, 1 − y).
        let at = Vec2::new(8.5 / 64.0, 8.5 / 64.0);
        let (long, short) = (8.0 / 64.0 / 2f32.sqrt(), 1.0 / 64.0 / 2f32.sqrt());
        let along = (Vec2::new(long, long), Vec2::new(short, -short));
        let across = (Vec2::new(long, -long), Vec2::new(short, short));
        let read = |(d0, d1): (Vec2, Vec2), most: f32| {
            image_value(&image, Filter::Ewa, at, (d0, d1), Wrap::Repeat, most).x
        };
        let (a, c) = (read(along, 8.0), read(across, 8.0));
        assert!(a > 0.85 && c < 0.6, "along {a}, across {c}");
        let (a1, c1) = (read(along, 1.0), read(across, 1.0));
        assert!((a1 - c1).abs() < 1e-5 && a1 < 0.6, "circles: {a1} {c1}");
    }

    #[test]
    fn a_pyramid_halves_by_box_means_to_one_texel() {
        let image = floats(8, 2, |x, y| [x as f32, y as f32, (x * y) as f32]);
        let p = pyramid(image.clone(), Wrap::Repeat);
        let levels = p.levels();
        let sizes: Vec<_> = levels.iter().map(|l| l.size()).collect();
        assert_eq!(sizes, [(8, 2), (4, 1), (2, 1), (1, 1)]);
        let one = floats(1, 1, |_, _| [0.5; 3]);
        assert_eq!(pyramid(one.clone(), Wrap::Clamp).levels(), [one]);
        assert_eq!(levels[0], image);
        assert_eq!(levels[1].texel(1), [2.5, 0.5, 1.25]);
        let mean = image.clone().into_floats().mean();
        let top = levels[3].texel(0);
        for c in 0..3 {
            assert!((top[c] as f64 - mean[c]).abs() < 1e-5, "{top:?} {mean:?}");
        }
    }

    /// A side that is not a power of two is resampled up to the next (a constant stays
    /// itself: the weights are normalised), and the windowed sinc interpolates: a texel
    /// whose centre falls on a source texel's centre is that texel.
    #[test]
    fn a_side_not_a_power_of_two_is_resampled_up() {
        let constant = floats(3, 5, |_, _| [0.25, 0.5, 0.75]);
        let p = pyramid(constant, Wrap::Clamp);
        assert_eq!(p.size(), (4, 8));
        for l in p.levels() {
            let (w, h) = l.size();
            for i in 0..(w * h) as usize {
                for (c, v) in l.texel(i).into_iter().zip([0.25, 0.5, 0.75]) {
                    assert!((c - v).abs() < 1e-6, "{c} {v}");
                }
            }
        }
        // A ramp 6 → 8 texels: within the ramp's range (the sinc's negative lobes clamped
        // at 0, its overshoot at the clamped ends small), rising as the ramp does.
        let ramp = floats(6, 1, |x, _| [x as f32, 1.0, 0.0]);
        let p = pyramid(ramp, Wrap::Clamp);
        let base = &p.levels()[0];
        assert_eq!(base.size(), (8, 1));
        for i in 0..8 {
            let v = base.texel(i)[0];
            assert!((-0.0..=5.2).contains(&v), "{i}: {v}");
        }
        assert!((2..6).all(|i| base.texel(i)[0] < base.texel(i + 1)[0]));
    }

    /// An 8-bit image's levels are bytes through its encoding, each code the rounded
    /// encoding of the mean of the decoded level below.
    #[test]
    fn an_8_bit_images_levels_are_bytes_rounded_through_its_encoding() {
        let decoding = ByteDecoding {
            encoding: Encoding::Srgb,
            grey: false,
        };
        let image = TextureImage::Bytes {
            width: 2,
            height: 2,
            texels: vec![[0, 255, 10], [255, 255, 200], [0, 0, 30], [255, 0, 40]],
            decoding,
        };
        let p = pyramid(image.clone(), Wrap::Repeat);
        let levels = p.levels();
        assert_eq!(levels[0], image);
        let TextureImage::Bytes { texels, .. } = &levels[1] else {
            panic!("bytes expected: {:?}", levels[1]);
        };
        let table = decoding.table();
        let mean = |c: usize| {
            let s: f32 = [0usize, 1, 2, 3]
                .iter()
                .map(|&i| match &image {
                    TextureImage::Bytes { texels, .. } => table[texels[i][c] as usize],
                    _ => unreachable!(),
                })
                .sum();
            0.25 * s
        };
        for c in 0..3 {
            let want = (crate::texture::linear_to_srgb(mean(c)) * 255.0 + 0.5) as u8;
            assert_eq!(texels[0][c], want, "channel {c}");
        }
        // Half of 0 and half of 255 is not code 128 in sRGB: the mean is linear.
        assert!(texels[0][0] > 180, "{:?}", texels[0]);
    }

    /// The quantizer's table gives every value the code of a search of the beginnings, and
    /// that code is the encoding's rounded (pbrt-v4's) but at an ulp or so from a half-code.
    #[test]
    fn the_quantizer_rounds_through_the_encoding() {
        for encoding in [Encoding::Linear, Encoding::Srgb] {
            let q = Quantizer::of(encoding);
            let mut rough = 0;
            for i in 0..=200_000 {
                let v = i as f32 / 180_000.0 - 0.01;
                let searched = q.starts.partition_point(|&t| t <= v) as u8;
                assert_eq!(q.code(v), searched, "{encoding:?} {v}");
                let e = match encoding {
                    Encoding::Linear => v,
                    Encoding::Srgb => crate::texture::linear_to_srgb(v),
                };
                let rounded = (e * 255.0 + 0.5).clamp(0.0, 255.0) as u8;
                if rounded != searched {
                    assert!(rounded.abs_diff(searched) == 1, "{encoding:?} {v}");
                    rough += 1;
                }
            }
            assert!(rough < 20, "{encoding:?}: {rough} values off by a code");
        }
    }

    /// The level follows the footprint: below one texel the base, bilinear; at a width of
    /// 2^k texels of the base, level k (trilinear: exactly level k's bilinear value); past
    /// the top, the top texel; point reads the nearest texel of its level.
    #[test]
    fn the_footprint_picks_the_level() {
        let image = floats(16, 16, |x, y| {
            [((x / 4 + y / 4) % 2) as f32, x as f32 / 15.0, 0.5]
        });
        let p = pyramid(image.clone(), Wrap::Repeat);
        let levels = p.levels();
        let at = Vec2::new(0.3, 0.6);
        let fp = |texels: f32| {
            // width = 2·d: d = texels / (2·16) in s.
            let d = texels / 32.0;
            (Vec2::new(d, 0.0), Vec2::new(0.0, d * 0.5))
        };
        let read = |f, texels| image_value(&p, f, at, fp(texels), Wrap::Repeat, 8.0);
        let bil = |l: usize| bilinear(&levels[l], at, Wrap::Repeat, Wrap::Repeat);
        assert_eq!(read(Filter::Bilinear, 0.5), bil(0));
        assert_eq!(read(Filter::Trilinear, 0.5), bil(0));
        assert_eq!(read(Filter::Bilinear, 4.0), bil(2));
        let tri = read(Filter::Trilinear, 4.0);
        assert!(
            (tri - bil(2)).abs().max_element() < 1e-6,
            "{tri} {:?}",
            bil(2)
        );
        // Between levels 2 and 3: trilinear mixes them.
        let mid = read(Filter::Trilinear, 4.0 * 2f32.sqrt());
        let t = 0.5;
        let want = (1.0 - t) * bil(2) + t * bil(3);
        assert!((mid - want).abs().max_element() < 1e-4, "{mid} {want}");
        assert_eq!(read(Filter::Bilinear, 4.0 * 2f32.sqrt()), bil(2));
        // Past the top.
        assert_eq!(
            read(Filter::Bilinear, 64.0),
            Vec3::from_array(levels[4].texel(0))
        );
        assert_eq!(
            read(Filter::Point, 4.0),
            nearest(&levels[2], at, Wrap::Repeat, Wrap::Repeat)
        );
        // One level alone (no pyramid): the filter at full resolution, any footprint.
        assert_eq!(
            image_value(&image, Filter::Bilinear, at, fp(64.0), Wrap::Repeat, 8.0),
            bilinear(&image, at, Wrap::Repeat, Wrap::Repeat)
        );
    }

    /// A degenerate footprint (a component NaN, infinite or of 2^60 or more) is read as
    /// none by every filter: the base level, never a level or ellipse made from it; one
    /// just below the bound is a footprint still.
    #[test]
    fn a_nan_or_infinite_footprint_reads_as_none() {
        let image = floats(16, 16, |x, y| {
            [x as f32 / 15.0, y as f32 / 15.0, ((x ^ y) & 1) as f32]
        });
        let p = pyramid(image, Wrap::Repeat);
        let at = Vec2::new(0.37, 0.61);
        let none = (Vec2::ZERO, Vec2::ZERO);
        for filter in [
            Filter::Point,
            Filter::Bilinear,
            Filter::Trilinear,
            Filter::Ewa,
        ] {
            let want = image_value(&p, filter, at, none, Wrap::Repeat, 8.0);
            for bad in [
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                -1e30,
                2f32.powi(60),
            ] {
                for dst in [
                    (Vec2::new(bad, 0.01), Vec2::new(0.0, 0.01)),
                    (Vec2::new(0.01, 0.0), Vec2::new(0.02, bad)),
                    (Vec2::splat(bad), Vec2::splat(bad)),
                ] {
                    let got = image_value(&p, filter, at, dst, Wrap::Repeat, 8.0);
                    assert_eq!(got, want, "{filter:?} {dst:?}");
                }
            }
            if filter != Filter::Bilinear {
                let large = 2f32.powi(59);
                let top = (Vec2::new(large, 0.0), Vec2::new(0.0, large));
                let got = image_value(&p, filter, at, top, Wrap::Repeat, 8.0);
                assert_eq!(got, Vec3::from_array(p.levels()[4].texel(0)), "{filter:?}");
            }
        }
    }
}
