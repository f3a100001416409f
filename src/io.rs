//! Image files: EXR (linear float RGB) and PNG (8-bit with the scene's gamma), written
//! to a temporary name beside the target and renamed, so a failed run leaves no
//! partial file.
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    pub fn mean(&self) -> [f64; 3] {
        let mut m = [0.0f64; 3];
        for p in &self.pixels {
            for c in 0..3 {
                m[c] += p[c] as f64;
            }
        }
        m.map(|v| v / self.pixels.len().max(1) as f64)
    }

    /// Mean over a pixel rectangle [x0, x1) × [y0, y1).
    pub fn region_mean(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> [f64; 3] {
        let mut m = [0.0f64; 3];
        let mut n = 0usize;
        for y in y0..y1.min(self.height) {
            for x in x0..x1.min(self.width) {
                let p = self.pixels[(y * self.width + x) as usize];
                for c in 0..3 {
                    m[c] += p[c] as f64;
                }
                n += 1;
            }
        }
        m.map(|v| v / n.max(1) as f64)
    }
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.partial-{}", std::process::id()))
}

/// Write `path` through a temporary file beside it and a rename; the temporary file
/// is removed when anything fails.
fn write_via_temp(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let tmp = temp_path(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Write bytes to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_via_temp(path, |tmp| {
        std::fs::write(tmp, bytes).with_context(|| format!("cannot write {}", path.display()))
    })
}

pub enum Format {
    Exr,
    Png,
}

pub fn format_of(path: &Path) -> Result<Format> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("exr") => Ok(Format::Exr),
        Some("png") => Ok(Format::Png),
        _ => bail!(
            "{}: unsupported image format (expected a .exr or .png file name)",
            path.display()
        ),
    }
}

/// Check up front that an image can be written there (format and directory), so a
/// long render does not end in an unwritable path.
pub fn check_writable(path: &Path) -> Result<()> {
    format_of(path)?;
    check_writable_file(path)
}

/// Check that a non-image file (a trace) can be created there.
pub fn check_writable_file(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let probe = dir.join(format!(".lightpath-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| {
        format!(
            "cannot write {}: directory {} is not writable",
            path.display(),
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// How an image was made, recorded in its EXR header as string, int and float
/// attributes (`lightpath compare` prints it, `lightpath merge` checks and combines it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderInfo {
    pub integrator: String,
    /// Samples per pixel reached (MMLT: mutations per pixel).
    pub samples_per_pixel: u64,
    /// The seed of a render; of a merge, every input's.
    pub seeds: Vec<u32>,
    pub max_depth: i32,
    pub backend: String,
    pub device: String,
    pub render_seconds: f64,
    /// The lightpath version that made it.
    pub version: String,
    /// The scene file's name and the SHA-256 of its contents (hex).
    pub scene_file: String,
    pub scene_hash: String,
}

/// The header attributes of a RenderInfo.
const ATTR_INTEGRATOR: &str = "lightpath:integrator";
const ATTR_SAMPLES: &str = "lightpath:samplesPerPixel";
const ATTR_SEEDS: &str = "lightpath:seeds";
const ATTR_MAX_DEPTH: &str = "lightpath:maxDepth";
const ATTR_BACKEND: &str = "lightpath:backend";
const ATTR_DEVICE: &str = "lightpath:device";
const ATTR_SECONDS: &str = "lightpath:renderSeconds";
const ATTR_VERSION: &str = "lightpath:version";
const ATTR_SCENE: &str = "lightpath:sceneFile";
const ATTR_SCENE_HASH: &str = "lightpath:sceneSha256";

type Attributes =
    std::collections::HashMap<exr::meta::attribute::Text, exr::meta::attribute::AttributeValue>;

impl RenderInfo {
    fn to_attributes(&self) -> Vec<(&'static str, exr::meta::attribute::AttributeValue)> {
        use exr::meta::attribute::{AttributeValue as V, Text};
        let text = |s: &str| V::Text(Text::new_or_panic(sanitize(s)));
        let seeds: Vec<String> = self.seeds.iter().map(|s| s.to_string()).collect();
        vec![
            (ATTR_INTEGRATOR, text(&self.integrator)),
            // Text: a count of samples may pass i32.
            (ATTR_SAMPLES, text(&self.samples_per_pixel.to_string())),
            (ATTR_SEEDS, text(&seeds.join(","))),
            (ATTR_MAX_DEPTH, V::I32(self.max_depth)),
            (ATTR_BACKEND, text(&self.backend)),
            (ATTR_DEVICE, text(&self.device)),
            (ATTR_SECONDS, V::F64(self.render_seconds)),
            (ATTR_VERSION, text(&self.version)),
            (ATTR_SCENE, text(&self.scene_file)),
            (ATTR_SCENE_HASH, text(&self.scene_hash)),
        ]
    }

    /// The RenderInfo in `attributes`, or None when they have none (an EXR not made by
    /// lightpath). Errors name the attribute that is malformed.
    fn from_attributes(attributes: &Attributes) -> Result<Option<RenderInfo>> {
        use exr::meta::attribute::{AttributeValue as V, Text};
        let get = |name: &str| attributes.get(&Text::new_or_panic(name));
        let text = |name: &str| -> Result<String> {
            match get(name) {
                Some(V::Text(t)) => Ok(t.to_string()),
                _ => bail!("attribute {name} is missing or not a string"),
            }
        };
        if get(ATTR_INTEGRATOR).is_none() {
            return Ok(None);
        }
        let seeds = text(ATTR_SEEDS)?;
        Ok(Some(RenderInfo {
            integrator: text(ATTR_INTEGRATOR)?,
            samples_per_pixel: text(ATTR_SAMPLES)?
                .parse()
                .with_context(|| format!("attribute {ATTR_SAMPLES} is not a count"))?,
            seeds: if seeds.is_empty() {
                Vec::new()
            } else {
                seeds
                    .split(',')
                    .map(|s| s.parse::<u32>())
                    .collect::<Result<_, _>>()
                    .with_context(|| format!("attribute {ATTR_SEEDS} is not a list of seeds"))?
            },
            max_depth: match get(ATTR_MAX_DEPTH) {
                Some(V::I32(d)) => *d,
                _ => bail!("attribute {ATTR_MAX_DEPTH} is missing or not an int"),
            },
            backend: text(ATTR_BACKEND)?,
            device: text(ATTR_DEVICE)?,
            render_seconds: match get(ATTR_SECONDS) {
                Some(V::F64(s)) => *s,
                Some(V::F32(s)) => *s as f64,
                _ => bail!("attribute {ATTR_SECONDS} is missing or not a number"),
            },
            version: text(ATTR_VERSION)?,
            scene_file: text(ATTR_SCENE)?,
            scene_hash: text(ATTR_SCENE_HASH)?,
        }))
    }

    /// One line for people.
    pub fn summary(&self) -> String {
        let seeds: Vec<String> = self.seeds.iter().map(|s| s.to_string()).collect();
        format!(
            "{} of {} (sha256 {}), {} spp, seed {}, maxdepth {}, {} on {}, {:.1} s, lightpath {}",
            self.integrator,
            self.scene_file,
            &self.scene_hash[..self.scene_hash.len().min(12)],
            self.samples_per_pixel,
            seeds.join(","),
            self.max_depth,
            self.backend,
            self.device,
            self.render_seconds,
            self.version
        )
    }
}

/// EXR text attributes are Latin-1: other characters become '?'.
fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect()
}

/// The SHA-256 of `bytes`, in hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    sha2::Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

pub fn write_image(path: &Path, image: &Image, gamma: f32) -> Result<()> {
    write_image_with_info(path, image, gamma, None)
}

/// Write an image; an EXR also records `info` in its header.
pub fn write_image_with_info(
    path: &Path,
    image: &Image,
    gamma: f32,
    info: Option<&RenderInfo>,
) -> Result<()> {
    write_image_with_aux(path, image, gamma, info, &[])
}

/// [`write_image_with_info`] with channels beside the image (a gbuffer film's: an EXR
/// holds them after R, G and B; a PNG cannot, and is an error when there are any).
pub fn write_image_with_aux(
    path: &Path,
    image: &Image,
    gamma: f32,
    info: Option<&RenderInfo>,
    aux: &[crate::integrators::gbuffer::AuxChannel],
) -> Result<()> {
    let format = format_of(path)?;
    if !aux.is_empty() && !matches!(format, Format::Exr) {
        anyhow::bail!(
            "{}: a gbuffer film's channels ({} and more) need an EXR file (name it .exr, or \
             use an rgb film)",
            path.display(),
            aux[0].name
        );
    }
    write_via_temp(path, |tmp| match format {
        Format::Exr => {
            use exr::prelude::*;
            let (w, h) = (image.width as usize, image.height as usize);
            let mut attributes = LayerAttributes::named("");
            attributes.software_name = Some(Text::new_or_panic(format!(
                "lightpath {}",
                env!("CARGO_PKG_VERSION")
            )));
            if let Some(info) = info {
                for (name, value) in info.to_attributes() {
                    attributes.other.insert(Text::new_or_panic(name), value);
                }
            }
            if !aux.is_empty() {
                let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
                for (c, name) in ["R", "G", "B"].iter().enumerate() {
                    let values = image.pixels.iter().map(|p| p[c]).collect();
                    channels.push(AnyChannel::new(*name, FlatSamples::F32(values)));
                }
                for a in aux {
                    channels.push(AnyChannel::new(
                        a.name.as_str(),
                        FlatSamples::F32(a.values.clone()),
                    ));
                }
                let layer = Layer::new(
                    (w, h),
                    attributes,
                    Encoding::FAST_LOSSLESS,
                    AnyChannels::sort(channels),
                );
                return exr::prelude::Image::from_layer(layer)
                    .write()
                    .to_file(tmp)
                    .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()));
            }
            let layer = Layer::new(
                (w, h),
                attributes,
                Encoding::FAST_LOSSLESS,
                SpecificChannels::rgb(|pos: Vec2<usize>| {
                    let p = image.pixels[pos.y() * w + pos.x()];
                    (p[0], p[1], p[2])
                }),
            );
            exr::prelude::Image::from_layer(layer)
                .write()
                .to_file(tmp)
                .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
        }
        Format::Png => {
            let inv = 1.0 / if gamma > 0.0 { gamma } else { 1.0 };
            let bytes: Vec<u8> = image
                .pixels
                .iter()
                .flat_map(|p| p.map(|v| (v.max(0.0).powf(inv).min(1.0) * 255.0 + 0.5) as u8))
                .collect();
            image::save_buffer_with_format(
                tmp,
                &bytes,
                image.width,
                image.height,
                image::ExtendedColorType::Rgb8,
                image::ImageFormat::Png,
            )
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))
        }
    })
}

pub fn read_exr(path: &Path) -> Result<Image> {
    Ok(read_exr_with_info(path)?.0)
}

/// An EXR's pixels and, when lightpath made it, how.
pub fn read_exr_with_info(path: &Path) -> Result<(Image, Option<RenderInfo>)> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| Image {
            width: resolution.width() as u32,
            height: resolution.height() as u32,
            pixels: vec![[0.0; 3]; resolution.width() * resolution.height()],
        },
        |img: &mut Image, pos: exr::math::Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
            let w = img.width as usize;
            img.pixels[pos.y() * w + pos.x()] = [r, g, b];
        },
    )
    .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
    let info = RenderInfo::from_attributes(&image.layer_data.attributes.other)
        .with_context(|| format!("{}: malformed lightpath metadata", path.display()))?;
    Ok((image.layer_data.channel_data.pixels, info))
}

/// Average renders of one scene and settings made with different seeds, weighted by
/// their samples per pixel: statistically the render of all their samples. Refuses
/// inputs without metadata, of different scenes (by content), sizes, integrators or
/// depths, or that share a seed.
pub fn merge(inputs: &[(PathBuf, Image, Option<RenderInfo>)]) -> Result<(Image, RenderInfo)> {
    if inputs.len() < 2 {
        bail!("merge needs at least two input images");
    }
    let mut infos = Vec::new();
    for (path, _, info) in inputs {
        match info {
            Some(i) => infos.push(i),
            None => bail!(
                "{} has no lightpath metadata (it was not rendered by lightpath 0.1 or later)",
                path.display()
            ),
        }
    }
    let (p0, i0, f0) = (&inputs[0].0, &inputs[0].1, infos[0]);
    let mut seen = std::collections::BTreeMap::new();
    for ((path, img, _), info) in inputs.iter().zip(&infos) {
        let differ = |what: &str, a: String, b: String| -> Result<()> {
            if a != b {
                bail!(
                    "cannot merge {} and {}: they differ in {what} ({a} vs {b})",
                    p0.display(),
                    path.display()
                );
            }
            Ok(())
        };
        differ(
            "scene (SHA-256 of the scene file)",
            f0.scene_hash.clone(),
            info.scene_hash.clone(),
        )?;
        differ(
            "size",
            format!("{}x{}", i0.width, i0.height),
            format!("{}x{}", img.width, img.height),
        )?;
        differ("integrator", f0.integrator.clone(), info.integrator.clone())?;
        differ(
            "maxdepth",
            f0.max_depth.to_string(),
            info.max_depth.to_string(),
        )?;
        if info.samples_per_pixel == 0 {
            bail!("{} records no samples", path.display());
        }
        for &seed in &info.seeds {
            if let Some(other) = seen.insert(seed, path.clone()) {
                bail!(
                    "cannot merge {} and {}: both used seed {seed}, so their samples are the same, not independent",
                    other.display(),
                    path.display()
                );
            }
        }
    }
    let total: u64 = infos.iter().map(|i| i.samples_per_pixel).sum();
    let mut pixels = vec![[0.0f64; 3]; i0.pixels.len()];
    for ((_, img, _), info) in inputs.iter().zip(&infos) {
        let w = info.samples_per_pixel as f64 / total as f64;
        for (p, q) in pixels.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                p[c] += w * q[c] as f64;
            }
        }
    }
    let join = |f: fn(&RenderInfo) -> &String| -> String {
        let mut v: Vec<&str> = infos.iter().map(|i| f(i).as_str()).collect();
        v.sort_unstable();
        v.dedup();
        v.join(" + ")
    };
    let merged = RenderInfo {
        integrator: f0.integrator.clone(),
        samples_per_pixel: total,
        seeds: seen.keys().copied().collect(),
        max_depth: f0.max_depth,
        backend: join(|i| &i.backend),
        device: join(|i| &i.device),
        render_seconds: infos.iter().map(|i| i.render_seconds).sum(),
        version: join(|i| &i.version),
        scene_file: join(|i| &i.scene_file),
        scene_hash: f0.scene_hash.clone(),
    };
    let image = Image {
        width: i0.width,
        height: i0.height,
        pixels: pixels.iter().map(|p| p.map(|v| v as f32)).collect(),
    };
    Ok((image, merged))
}

/// Mean per channel of A, RMSE and relMSE (ε = 0.01) of A against the reference B, and
/// the pixels whose bits differ (0: the images are bit-identical).
#[derive(Clone, Copy, Debug)]
pub struct Comparison {
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    pub rmse: f64,
    pub relmse: f64,
    pub differing_pixels: usize,
}

pub fn compare(a: &Image, b: &Image) -> Result<Comparison> {
    if a.width != b.width || a.height != b.height {
        bail!(
            "images differ in size: {}x{} vs {}x{}",
            a.width,
            a.height,
            b.width,
            b.height
        );
    }
    let mut se = 0.0f64;
    let mut rel = 0.0f64;
    let mut differing_pixels = 0;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        if pa.iter().zip(pb).any(|(x, y)| x.to_bits() != y.to_bits()) {
            differing_pixels += 1;
        }
        for c in 0..3 {
            let d = pa[c] as f64 - pb[c] as f64;
            se += d * d;
            rel += d * d / (pb[c] as f64 * pb[c] as f64 + 0.01);
        }
    }
    let n = (a.pixels.len() * 3).max(1) as f64;
    Ok(Comparison {
        mean_a: a.mean(),
        mean_b: b.mean(),
        rmse: (se / n).sqrt(),
        relmse: rel / n,
        differing_pixels,
    })
}
