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
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;

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
        let mut integrator = crate::integrators::create(scene.settings.integrator, &self.options)?;
        integrator.render(&mut self.engine, scene, seed, trace)
    }
}
