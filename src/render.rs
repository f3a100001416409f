//! The library's front door: a [`Renderer`] is an [`Engine`] (a device and its kernels)
//! plus the integrators' options; `render` picks the scene's integrator from the
//! registry (`integrators::create`) and runs it. What a render shares lives in
//! `engine`, what an integrator owns in `integrators`.
use crate::engine::Engine;
pub use crate::engine::{AccelChoice, Snapshots, Validation, DEFAULT_BVH};
use crate::gpu::kernels::Backend;
use crate::gpu::ValidationReport;
pub use crate::integrators::bdpt::{BdptDetails, StrategyImages};
pub use crate::integrators::mmlt::MmltReport;
pub use crate::integrators::{IntegratorOptions, RenderOutput};
use crate::scene::{IntegratorKind, Scene};
use crate::trace::Trace;
use anyhow::{bail, Result};

/// One render as the command line and the Python package both ask for it: the scene with
/// its settings as they will render (the front end's overrides applied), the seed, what
/// to record beyond the image, and how the run is controlled. The integrator is the
/// scene's, by its registry name.
#[derive(Clone, Debug)]
pub struct RenderRequest {
    pub scene: Scene,
    pub seed: u32,
    /// BDPT's image of every strategy (`--bdpt-strategies`, `strategies=True`).
    pub record_strategies: bool,
    /// MMLT's image of every depth (`--mmlt-depths`, `depths=True`).
    pub record_depths: bool,
    /// Stop after about this many seconds of rendering (passes stay whole).
    pub time_limit: Option<f64>,
    pub show_progress: bool,
}

impl RenderRequest {
    /// A request for `scene` with `seed` that records nothing more and has no limit.
    pub fn new(scene: Scene, seed: u32) -> RenderRequest {
        RenderRequest {
            scene,
            seed,
            record_strategies: false,
            record_depths: false,
            time_limit: None,
            show_progress: false,
        }
    }

    /// What does not belong together, as an error naming the front end's own words for
    /// the strategy and depth images (`--bdpt-strategies`, `strategies=True`) and the time
    /// limit.
    pub fn check(&self, strategies: &str, depths: &str, time_limit: &str) -> Result<()> {
        let kind = self.scene.settings.integrator;
        if self.record_strategies && kind != IntegratorKind::Bdpt {
            bail!(
                "{strategies} needs the bdpt integrator (this render uses {})",
                kind.name()
            );
        }
        if self.record_depths && kind != IntegratorKind::Mmlt {
            bail!(
                "{depths} needs the mmlt integrator (this render uses {})",
                kind.name()
            );
        }
        if let Some(t) = self.time_limit {
            if !(t > 0.0 && t.is_finite()) {
                bail!("{time_limit} must be a positive number of seconds, got {t}");
            }
        }
        Ok(())
    }
}

/// An open device with its kernels for one backend and the integrators' options;
/// renders any number of scenes.
pub struct Renderer {
    pub engine: Engine,
    pub options: IntegratorOptions,
}

impl Renderer {
    pub fn new(device_name: Option<&str>, accel: AccelChoice) -> Result<Renderer> {
        Renderer::open(device_name, accel, Validation::Off)
    }

    /// With `validation`, everything runs under the Khronos validation layer (see
    /// [`Validation`]); [`Renderer::validation`] tells what it reported.
    pub fn open(
        device_name: Option<&str>,
        accel: AccelChoice,
        validation: Validation,
    ) -> Result<Renderer> {
        Ok(Renderer {
            engine: Engine::open(device_name, accel, validation)?,
            options: IntegratorOptions::default(),
        })
    }

    pub fn backend(&self) -> Backend {
        self.engine.backend()
    }

    /// The device's name, driver and limits.
    pub fn device_info(&self) -> &crate::gpu::DeviceInfo {
        &self.engine.device.info
    }

    /// What the validation layer has reported since the device was opened; `None` when
    /// it was opened without validation.
    pub fn validation(&self) -> Option<ValidationReport> {
        self.engine.validation()
    }

    /// The metadata of a render of `scene` (read from `scene_file`, whose contents are
    /// `scene_bytes`) with `seed` on this renderer, before it runs: the samples and
    /// seconds are filled in after.
    pub fn render_info(
        &self,
        scene: &Scene,
        scene_file: &std::path::Path,
        scene_bytes: &[u8],
        seed: u32,
    ) -> crate::io::RenderInfo {
        crate::io::RenderInfo {
            integrator: scene.settings.integrator.name().to_string(),
            samples_per_pixel: 0,
            seeds: vec![seed],
            max_depth: scene.settings.max_depth,
            backend: self.backend().name().to_string(),
            device: self.device_info().name.clone(),
            render_seconds: 0.0,
            version: env!("CARGO_PKG_VERSION").to_string(),
            scene_file: scene_file
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default(),
            scene_hash: crate::io::sha256_hex(scene_bytes),
        }
    }

    /// Render `scene` (its settings already overridden by the command line) with `seed`,
    /// by the integrator its settings name.
    pub fn render(&mut self, scene: &Scene, seed: u32, trace: &mut Trace) -> Result<RenderOutput> {
        if scene.lens.is_some()
            && matches!(
                scene.settings.integrator,
                crate::scene::IntegratorKind::Bdpt | crate::scene::IntegratorKind::Mmlt
            )
        {
            anyhow::bail!(
                "a realistic camera (a lens system) has no importance for light subpaths to \
                 connect to (pbrt-v4's has none either: its bdpt and mlt refuse it): render \
                 it with the path tracer (pathtracer, direct)"
            );
        }
        let mut integrator = crate::integrators::create(scene.settings.integrator, &self.options)?;
        // A gbuffer film's passes run on the scene the integrator prepared.
        let gbuffer = scene.settings.gbuffer.is_some();
        self.engine.keep_next_scene(gbuffer);
        let result = integrator.render(&mut self.engine, scene, seed, trace);
        // Taken in any case: nothing of the scene stays on the device after the render.
        let prepared = self.engine.take_kept_scene();
        let mut out = result?;
        apply_film_matrix(&mut out.image, scene.settings.output_from_render);
        // A gbuffer film's channels, but not after an interruption (the user asked to stop).
        if gbuffer && out.interrupted.is_none() {
            out.aux = crate::integrators::gbuffer::render(
                &mut self.engine,
                scene,
                prepared,
                seed,
                trace,
            )?;
        }
        Ok(out)
    }

    /// Render `request`: its recordings and run control become this renderer's options
    /// and the engine's control for the render (interruption and snapshots stay as the
    /// caller set them on `engine.control`).
    pub fn render_request(
        &mut self,
        request: &RenderRequest,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        self.options.bdpt.record_strategies = request.record_strategies;
        self.options.mmlt.record_depths = request.record_depths;
        self.engine.control.show_progress = request.show_progress;
        self.engine.control.time_limit = request.time_limit;
        self.render(&request.scene, request.seed, trace)
    }
}

/// The film's colour matrix (`Settings::output_from_render`: pbrt-v4's sensor and white
/// balance) on every pixel of `image`; nothing for the identity.
pub fn apply_film_matrix(image: &mut crate::io::Image, m: glam::Mat3) {
    if m == glam::Mat3::IDENTITY {
        return;
    }
    for p in &mut image.pixels {
        *p = (m * glam::Vec3::from_array(*p)).to_array();
    }
}
