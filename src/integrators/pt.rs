//! Host side of the film-only integrators: `pathtracer` and `direct` (glsl/pt.comp) and
//! `analyticdirect` (glsl/analytic.comp). Passes of one sample per pixel in bands, each
//! pixel written by its own invocation; image = film / spp.
use crate::gpu::abi::*;
use crate::io::Image;
use crate::render::{band_rows, film_image, Passes, Prepared, RenderOutput, Renderer};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;

impl Renderer {
    /// Render with the pass kernel `kernel` ("pt" or "analytic").
    pub(crate) fn render_pt(
        &mut self,
        scene: &Scene,
        seed: u32,
        kernel: &'static str,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let (width, height) = (scene.width, scene.height);
        let film_bytes = self.film_bytes(width, height)?;
        let rows = band_rows(width, height, 0, u64::MAX)?;
        let Prepared { gpu_scene, rq, .. } = self.prepare(scene, seed, 0, trace)?;
        let pipeline = trace.cpu("pipeline creation", || self.pass_pipeline(kernel))?;
        let (film, stats) = trace.cpu("film allocation", || -> Result<_> {
            Ok((
                self.storage_buffer("film", film_bytes)?,
                self.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
            ))
        })?;
        let set = self.descriptor_set(
            &gpu_scene,
            &[(BINDING_FILM, &film), (BINDING_STATS, &stats)],
            rq.as_ref(),
        )?;
        let params = PassParams { pass: [0, 0, 0, 1] };
        self.warm_up(pipeline, set, bytemuck::bytes_of(&params), trace)?;
        let passes = Passes {
            pipeline,
            set,
            kernel,
            width,
            height,
            band_rows: rows,
        };
        let resolve = |done: u32| -> Result<Image> {
            let data = film.download(film_bytes)?;
            Ok(film_image(
                bytemuck::cast_slice(&data),
                width,
                height,
                1.0 / done as f32,
            ))
        };
        let (dispatch_seconds, spp) =
            self.dispatch_passes(passes, 0, scene.settings.spp.max(1), Some(&resolve), trace)?;
        let (film_data, stat) = trace.cpu("readback", || -> Result<_> {
            Ok((film.download(film_bytes)?, self.read_stats(&stats, kernel)?))
        })?;
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        Ok(RenderOutput {
            image: film_image(film, width, height, 1.0 / spp.max(1) as f32),
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays: film.iter().map(|p| p[3] as f64).sum(),
            samples_per_pixel: spp,
            dispatch_seconds,
            backend: self.backend(),
            strategies: Vec::new(),
            mmlt: None,
            interrupted: self.interrupt_signal(),
        })
    }
}
