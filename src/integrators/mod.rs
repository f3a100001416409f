//! The integrators, each behind one interface: an [`Integrator`] owns its options, its
//! buffers, its dispatch plan (through the engine's dispatch recording and run loop) and
//! its resolve, and returns a [`RenderOutput`] with its own results in `details`.
//! [`create`] is the factory; adding an integrator adds a module, a kernel in glsl/ and
//! one line in [`REGISTRY`] (and its name in the scene format's list,
//! `crate::scene::IntegratorKind`). CPU mirrors of their GPU math live beside them
//! (`bdpt_mis`, `mmlt_sampler`).
pub mod bdpt;
pub mod bdpt_mis;
pub mod gbuffer;
pub mod mmlt;
pub mod mmlt_sampler;
pub mod pt;

use crate::abi::{FIXED_FILM_WORDS_PER_PIXEL, SPLAT_FRACTION_BITS, SPLAT_WORDS_PER_PIXEL};
use crate::engine::Engine;
use crate::gpu::kernels::Backend;
use crate::io::Image;
use crate::scene::{IntegratorKind, Scene};
use crate::trace::Trace;
use anyhow::{bail, Result};
use std::any::Any;

/// A render's result and what was measured along the way.
pub struct RenderOutput {
    pub image: Image,
    /// Samples (BDPT: contributions) that came out NaN or infinite, or that a splat could not
    /// add (negative, or beyond the fixed-point range), left out of the film.
    pub nonfinite_samples: u64,
    pub rays: f64,
    pub samples_per_pixel: u32,
    /// Time in the render dispatches only (GPU timestamps when the device has them).
    pub dispatch_seconds: f64,
    pub backend: Backend,
    /// Stopped early by this signal (see `RunControl::interrupt`).
    pub interrupted: Option<usize>,
    /// The integrator's own results (`bdpt::BdptDetails`, `mmlt::MmltReport`), if any.
    pub details: Option<Box<dyn Any + Send>>,
    /// Channels written beside the image: a `gbuffer` film's (`gbuffer::render`).
    pub aux: Vec<gbuffer::AuxChannel>,
}

impl RenderOutput {
    /// The integrator's own results, when they are a `T`.
    pub fn details<T: 'static>(&self) -> Option<&T> {
        self.details.as_ref()?.downcast_ref::<T>()
    }
}

/// What the command line (or a test) asks of the integrators beyond the scene's settings.
#[derive(Clone, Debug, Default)]
pub struct IntegratorOptions {
    pub bdpt: bdpt::BdptOptions,
    pub mmlt: mmlt::MmltOptions,
    /// `lightpath profile`: render the pass kernels (pt, bdpt) in this profiling variant
    /// ("x2trace", "x2prim", "x2rng", "x2bsdf", "x2light": one stage done twice).
    pub profile_variant: Option<&'static str>,
    /// The wavefront path tracer's size in paths (default `pt::WAVEFRONT_SLOTS`, or the
    /// `LIGHTPATH_WAVEFRONT_SLOTS` environment variable); images do not depend on it.
    pub wavefront_slots: Option<u64>,
}

/// One integrator: renders a scene (its settings already overridden by the command line)
/// with a seed on the engine.
pub trait Integrator {
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput>;
}

/// A constructor of the registry.
pub type Create = fn(&IntegratorOptions) -> Box<dyn Integrator>;

/// Every integrator lightpath renders with, by the scene format's name.
pub const REGISTRY: &[(IntegratorKind, Create)] = &[
    (IntegratorKind::PathTracer, pt::create_pathtracer),
    (IntegratorKind::Direct, pt::create_direct),
    (IntegratorKind::AnalyticDirect, pt::create_analytic),
    (IntegratorKind::Bdpt, bdpt::create),
    (IntegratorKind::Mmlt, mmlt::create),
];

/// The names of the integrators lightpath renders, in the registry's order, as a message
/// lists them: "a, b, c or d".
pub fn names() -> String {
    let names: Vec<&str> = REGISTRY.iter().map(|(k, _)| k.name()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        Some((last, _)) => last.to_string(),
        None => String::new(),
    }
}

/// The integrator `kind` with `options`; an error for a kind the scene format knows but
/// lightpath does not render.
pub fn create(kind: IntegratorKind, options: &IntegratorOptions) -> Result<Box<dyn Integrator>> {
    match REGISTRY.iter().find(|(k, _)| *k == kind) {
        Some((_, make)) => Ok(make(options)),
        None => bail!(
            "integrator '{}' is not available in this version of lightpath",
            kind.name()
        ),
    }
}

/// A film of vec4s (w: rays) as an image, each channel times `scale`.
pub fn film_image(data: &[[f32; 4]], width: u32, height: u32, scale: f32) -> Image {
    Image {
        width,
        height,
        pixels: data
            .iter()
            .map(|p| [p[0] * scale, p[1] * scale, p[2] * scale])
            .collect(),
    }
}

/// Add a splat film (glsl/lib/splat.glsl: per pixel and channel an unsigned 64-bit
/// fixed-point sum with SPLAT_FRACTION_BITS fractional bits, as low and high 32-bit
/// words), each channel times `scale`, to `image`.
pub fn add_splat_film(image: &mut Image, data: &[u32], scale: f32) {
    add_fixed_point_film(image, data, SPLAT_WORDS_PER_PIXEL as usize, scale);
}

/// Add a fixed-point film of `words` words per pixel (the splat film's 8, the diagnostic
/// films' FIXED_FILM_WORDS_PER_PIXEL) to `image`, each channel times `scale`.
fn add_fixed_point_film(image: &mut Image, data: &[u32], words: usize, scale: f32) {
    let unit = (-(SPLAT_FRACTION_BITS as f64)).exp2();
    for (p, q) in image.pixels.iter_mut().zip(data.chunks_exact(words)) {
        for c in 0..3 {
            let fixed = (q[2 * c + 1] as u64) << 32 | q[2 * c] as u64;
            p[c] += (fixed as f64 * unit) as f32 * scale;
        }
    }
}

/// A diagnostic film (BDPT's strategy images, MMLT's per-depth images: fixed point,
/// FIXED_FILM_WORDS_PER_PIXEL words per pixel) as an image, each channel times `scale`.
pub fn fixed_film_image(data: &[u32], width: u32, height: u32, scale: f32) -> Image {
    let mut image = Image {
        width,
        height,
        pixels: vec![[0.0; 3]; width as usize * height as usize],
    };
    add_fixed_point_film(&mut image, data, FIXED_FILM_WORDS_PER_PIXEL as usize, scale);
    image
}

/// A splat film alone as an image, each channel times `scale`.
pub fn splat_image(data: &[u32], width: u32, height: u32, scale: f32) -> Image {
    let mut image = Image {
        width,
        height,
        pixels: vec![[0.0; 3]; width as usize * height as usize],
    };
    add_splat_film(&mut image, data, scale);
    image
}

/// Add a film of vec4s, each channel times `scale`, to `image`.
pub fn add_film(image: &mut Image, data: &[[f32; 4]], scale: f32) {
    for (p, q) in image.pixels.iter_mut().zip(data) {
        for c in 0..3 {
            p[c] += q[c] * scale;
        }
    }
}
