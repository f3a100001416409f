//! Host side of the integrators that need more than `Renderer::render`'s common
//! dispatch loop, and CPU mirrors of their GPU math.
pub mod bdpt;
pub mod bdpt_mis;
pub mod mmlt;
pub mod mmlt_sampler;
pub mod pt;
