//! pbrt-v4's `gbuffer` film: beside the image, what the camera sees first in each pixel —
//! the surface's albedo, position, geometric and shading normals and (u, v) — as the EXR
//! channels pbrt-v4 names them (`Albedo.R`…, `P.X`…, `N.X`…, `Ns.X`…, `u`, `v`), for
//! denoisers and compositing. A pass of its own after the render (glsl/gbuffer.comp):
//! [`GBUFFER_SAMPLES`] camera samples per pixel at most (the render's spp where fewer),
//! averaged, a sample that sees nothing counting as zeros (as pbrt-v4's film averages
//! them). The albedo is the directional albedo ρ(wo) of the BSDF, estimated from 16 of its
//! samples as pbrt-v4's VisibleSurface does; positions and normals are in camera space (x
//! right, y up, z ahead, the eye at the origin) unless the film asks for the world.
use crate::abi::*;
use crate::engine::passes::PassWork;
use crate::engine::{band_rows, Engine, PassStage, Passes, RunOptions};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;

/// Camera samples per pixel of the g-buffer, at most.
pub const GBUFFER_SAMPLES: u32 = 64;

/// One named channel beside the image: a value per pixel, rows from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct AuxChannel {
    pub name: String,
    pub values: Vec<f32>,
}

/// The channels, in the order they are written: the four vec4 per pixel the kernel sums
/// (albedo, 0), (P, u), (N, v), (Ns, 0), by (vec4, component).
const CHANNELS: [(&str, usize, usize); 14] = [
    ("Albedo.R", 0, 0),
    ("Albedo.G", 0, 1),
    ("Albedo.B", 0, 2),
    ("P.X", 1, 0),
    ("P.Y", 1, 1),
    ("P.Z", 1, 2),
    ("N.X", 2, 0),
    ("N.Y", 2, 1),
    ("N.Z", 2, 2),
    ("Ns.X", 3, 0),
    ("Ns.Y", 3, 1),
    ("Ns.Z", 3, 2),
    ("u", 1, 3),
    ("v", 2, 3),
];

/// Render the g-buffer of `scene` (whose settings ask for one) with `seed`.
pub fn render(
    engine: &mut Engine,
    scene: &Scene,
    seed: u32,
    trace: &mut Trace,
) -> Result<Vec<AuxChannel>> {
    let (width, height) = (scene.width, scene.height);
    let pixels = width as u64 * height as u64;
    let bytes = engine.gbuffer_bytes(width, height)?;
    let rows = band_rows(width, height, 0, u64::MAX)?;
    let prepared = engine.prepare(scene, seed, |_| {}, trace)?;
    let kernel = trace.cpu("pipeline creation", || {
        engine.kernel("gbuffer", None, prepared.specialization())
    })?;
    let (film, stats) = trace.cpu("film allocation", || -> Result<_> {
        Ok((
            engine.storage_buffer("gbuffer", bytes)?,
            engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
        ))
    })?;
    let set = engine.bind(
        &kernel,
        Some(&prepared),
        &[(BINDING_FILM, &film), (BINDING_STATS, &stats)],
    )?;
    let passes = Passes {
        stages: vec![PassStage {
            kernel,
            set,
            span: "gbuffer pass".into(),
        }],
        width,
        height,
        band_rows: rows,
    };
    engine.warm_up_passes(&passes, trace)?;
    let samples = scene.settings.spp.clamp(1, GBUFFER_SAMPLES);
    let mut work = PassWork {
        passes: &passes,
        first: 0,
        spp: samples,
        resolve: None,
    };
    let mut options = RunOptions::passes("gbuffer");
    options.time_limited = false;
    let run = engine.run(&mut work, &options, trace)?;
    let done = run.done.max(1) as f32;
    let data = trace.cpu("readback", || film.download(bytes))?;
    let sums: &[[f32; 4]] = bytemuck::cast_slice(&data);
    Ok(CHANNELS
        .iter()
        .map(|&(name, vec, component)| AuxChannel {
            name: name.to_owned(),
            values: (0..pixels as usize)
                .map(|i| sums[4 * i + vec][component] / done)
                .collect(),
        })
        .collect())
}
