//! Image files: EXR (linear float RGB) and PNG (8-bit with the scene's gamma), written
//! to a temporary name beside the target and renamed, so a failed run leaves no
//! partial file.
use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// A linear RGB image, row-major from the top-left pixel.
#[derive(Clone, Debug)]
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

pub fn write_image(path: &Path, image: &Image, gamma: f32) -> Result<()> {
    let format = format_of(path)?;
    write_via_temp(path, |tmp| match format {
        Format::Exr => {
            let (w, h) = (image.width as usize, image.height as usize);
            exr::prelude::write_rgb_file(tmp, w, h, |x, y| {
                let p = image.pixels[y * w + x];
                (p[0], p[1], p[2])
            })
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
    Ok(image.layer_data.channel_data.pixels)
}

/// Mean per channel of A, RMSE and relMSE (ε = 0.01) of A against the reference B.
#[derive(Clone, Copy, Debug)]
pub struct Comparison {
    pub mean_a: [f64; 3],
    pub mean_b: [f64; 3],
    pub rmse: f64,
    pub relmse: f64,
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
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
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
    })
}
