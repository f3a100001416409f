//! The film-only integrators: `pathtracer` and `direct` (glsl/pt.comp) and
//! `analyticdirect` (glsl/analytic.comp). Passes of one sample per pixel in bands, each
//! pixel written by its own invocation; image = film / spp.
use super::{film_image, Integrator, IntegratorOptions, RenderOutput};
use crate::abi::*;
use crate::engine::passes::PassWork;
use crate::engine::{band_rows, Engine, Passes, RunOptions};
use crate::io::Image;
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;

/// One of the film-only integrators: its kernel and its code in `SceneParams`.
pub struct FilmIntegrator {
    kernel: &'static str,
    code: u32,
    profile_variant: Option<&'static str>,
}

pub fn create_pathtracer(o: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(FilmIntegrator {
        kernel: "pt",
        code: INTEGRATOR_PATHTRACER,
        profile_variant: o.profile_variant,
    })
}

pub fn create_direct(o: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(FilmIntegrator {
        kernel: "pt",
        code: INTEGRATOR_DIRECT,
        profile_variant: o.profile_variant,
    })
}

pub fn create_analytic(_: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(FilmIntegrator {
        kernel: "analytic",
        code: INTEGRATOR_ANALYTIC,
        profile_variant: None,
    })
}

impl Integrator for FilmIntegrator {
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let (width, height) = (scene.width, scene.height);
        if self.code == INTEGRATOR_ANALYTIC
            && scene.environment.as_ref().is_some_and(|e| e.map.is_some())
        {
            anyhow::bail!(
                "analyticdirect has a closed form for a constant environment (envlight) only, \
                 not for an environment map: use pathtracer, bdpt or mmlt"
            );
        }
        let film_bytes = engine.film_bytes(width, height)?;
        let rows = band_rows(width, height, 0, u64::MAX)?;
        let code = self.code;
        let prepared = engine.prepare(scene, seed, |p| p.integrator = code, trace)?;
        let kernel = trace.cpu("pipeline creation", || {
            engine.kernel(self.kernel, self.profile_variant, prepared.specialization())
        })?;
        let (film, stats) = trace.cpu("film allocation", || -> Result<_> {
            Ok((
                engine.storage_buffer("film", film_bytes)?,
                engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
            ))
        })?;
        let set = engine.bind(
            &kernel,
            Some(&prepared),
            &[(BINDING_FILM, &film), (BINDING_STATS, &stats)],
        )?;
        let passes = Passes {
            kernel,
            set,
            width,
            height,
            band_rows: rows,
            span: format!("{} pass", self.kernel),
        };
        engine.warm_up(passes.idle(), trace)?;
        let resolve = |done: u32| -> Result<Image> {
            let data = film.download(film_bytes)?;
            Ok(film_image(
                bytemuck::cast_slice(&data),
                width,
                height,
                1.0 / done as f32,
            ))
        };
        let mut work = PassWork {
            passes: &passes,
            first: 0,
            spp: scene.settings.spp.max(1),
            resolve: Some(&resolve),
        };
        let run = engine.run(&mut work, &RunOptions::passes(self.kernel), trace)?;
        let spp = run.done as u32;
        let (film_data, stat) = trace.cpu("readback", || -> Result<_> {
            Ok((
                film.download(film_bytes)?,
                engine.read_stats(&stats, self.kernel)?,
            ))
        })?;
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        Ok(RenderOutput {
            image: film_image(film, width, height, 1.0 / spp.max(1) as f32),
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays: film.iter().map(|p| p[3] as f64).sum(),
            samples_per_pixel: spp,
            dispatch_seconds: run.times.total(),
            backend: engine.backend(),
            interrupted: engine.interrupt_signal(),
            details: None,
        })
    }
}
