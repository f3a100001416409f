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

    /// Render `scene` (its settings already overridden by the command line) with `seed`,
    /// by the integrator its settings name.
    pub fn render(&mut self, scene: &Scene, seed: u32, trace: &mut Trace) -> Result<RenderOutput> {
        let mut integrator = crate::integrators::create(scene.settings.integrator, &self.options)?;
        integrator.render(&mut self.engine, scene, seed, trace)
    }
}
