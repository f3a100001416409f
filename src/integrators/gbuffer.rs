//! pbrt-v4's `gbuffer` film: beside the image, what the camera sees first in each pixel —
//! the surface's albedo, position, geometric and shading normals and (u, v) — as the EXR
//! channels pbrt-v4 names them (`Albedo.R`…, `P.X`…, `N.X`…, `Ns.X`…, `u`, `v`), for
//! denoisers and compositing. Passes of their own after the render, on the scene the
//! render prepared (glsl/lib/gbuffer.glsl): a hit stage (the camera ray, the surface, its
//! P, N, Ns and (u, v)), then an albedo stage per material class of the scene (as the
//! wavefront path tracer shades: no kernel holds every BSDF). [`GBUFFER_SAMPLES`] camera
//! samples per pixel at most (the render's spp where fewer), averaged, a sample that sees
//! nothing counting as zeros (as pbrt-v4's film averages them). The albedo is the
//! directional albedo ρ(wo) of the BSDF, estimated from 16 of its samples as pbrt-v4's
//! VisibleSurface does; positions and normals are in camera space (x right, y up, z ahead,
//! the eye at the origin) unless the film asks for the world.
use super::pt::{film_passes, material_classes, FilmPasses};
use crate::abi::*;
use crate::engine::passes::PassWork;
use crate::engine::{band_rows, Engine, PreparedScene, RunOptions};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;
use std::sync::Arc;

/// Camera samples per pixel of the g-buffer, at most.
pub const GBUFFER_SAMPLES: u32 = 64;

/// One named channel beside the image: a value per pixel, rows from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct AuxChannel {
    pub name: String,
    pub values: Vec<f32>,
}

/// The channels, in the order they are written: the four vec4 per pixel the kernels sum
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

/// The albedo stage of a material class: (kernel, span).
fn albedo_stage(class: u32) -> (&'static str, &'static str) {
    match class {
        MATERIAL_CLASS_BASIC => ("gbuffer_albedo_basic", "gbuffer albedo basic"),
        MATERIAL_CLASS_INTERFACE => ("gbuffer_albedo_interface", "gbuffer albedo interface"),
        MATERIAL_CLASS_COATED => ("gbuffer_albedo_coated", "gbuffer albedo coated"),
        MATERIAL_CLASS_MEASURED => ("gbuffer_albedo_measured", "gbuffer albedo measured"),
        _ => ("gbuffer_albedo_hair", "gbuffer albedo hair"),
    }
}

/// Render the g-buffer of `scene` (whose settings ask for one) with `seed`, on `prepared`
/// (the render's scene, made with the same seed) or, without one, on the scene made anew.
/// The kernels read none of the parameters an integrator sets for itself.
pub fn render(
    engine: &mut Engine,
    scene: &Scene,
    prepared: Option<Arc<PreparedScene>>,
    seed: u32,
    trace: &mut Trace,
) -> Result<Vec<AuxChannel>> {
    let (width, height) = (scene.width, scene.height);
    let pixels = width as u64 * height as u64;
    let bytes = engine.gbuffer_bytes(width, height)?;
    let surface_bytes = std::mem::size_of::<GpuGbufferSurface>() as u64;
    let range = engine.device.info.max_storage_buffer_range;
    let rows = band_rows(width, height, surface_bytes, range)?;
    let prepared = match prepared {
        Some(p) => p,
        None => engine.prepare(scene, seed, |_| {}, trace)?,
    };
    let surfaces = trace.cpu("film allocation", || {
        engine.storage_buffer(
            "gbuffer surfaces",
            surface_bytes * width as u64 * rows as u64,
        )
    })?;
    let mut stages = vec![("gbuffer_hit", None, "gbuffer hit".to_string())];
    stages.extend(material_classes(scene).into_iter().map(|class| {
        let (kernel, span) = albedo_stage(class);
        (kernel, None, span.to_string())
    }));
    let FilmPasses { passes, film, .. } = film_passes(
        engine,
        &prepared,
        ("gbuffer", bytes),
        &stages,
        &[(BINDING_GBUFFER_SURFACES, &surfaces)],
        rows,
        trace,
    )?;
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
