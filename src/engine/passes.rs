//! Pass-shaped work: one invocation per pixel adds one sample per pass, a pass split into
//! bands of rows (so no dispatch runs long and per-pixel scratch of a band fits one
//! buffer). Used by the path tracer, BDPT and MMLT's tail.
use super::dispatch::Dispatch;
use super::run::Work;
use crate::abi::{PassParams, WORKGROUP_SIZE_X, WORKGROUP_SIZE_Y};
use crate::gpu::kernels::Kernel;
use crate::io::Image;
use anyhow::{bail, Result};
use ash::vk;

/// Pixels per dispatch: a pass over a larger image is split into bands of rows.
pub const BAND_PIXELS: u32 = 1 << 18;

/// Rows per band (tile) of a pass: at most about BAND_PIXELS pixels, whole workgroup rows
/// where possible, and no more pixels than `per_pixel_bytes` lets fit in `limit` bytes.
pub fn band_rows(width: u32, height: u32, per_pixel_bytes: u64, limit: u64) -> Result<u32> {
    let by_dispatch = ((BAND_PIXELS / width.max(1)) / WORKGROUP_SIZE_Y).max(1) * WORKGROUP_SIZE_Y;
    let mut rows = by_dispatch;
    if per_pixel_bytes > 0 {
        let by_memory = limit / (per_pixel_bytes * width as u64);
        if by_memory == 0 {
            bail!(
                "one row of {width} pixels needs {} bytes of BDPT light vertices, more than the device allows in one buffer ({limit} bytes); render a smaller width or maxdepth",
                per_pixel_bytes * width as u64
            );
        }
        let by_memory = by_memory.min(u32::MAX as u64) as u32;
        let by_memory = if by_memory >= WORKGROUP_SIZE_Y {
            by_memory / WORKGROUP_SIZE_Y * WORKGROUP_SIZE_Y
        } else {
            by_memory
        };
        rows = rows.min(by_memory);
    }
    Ok(rows.min(height.max(1)))
}

/// One kernel of a pass and its descriptor set, timed as "`span`".
#[derive(Clone)]
pub struct PassStage {
    pub kernel: Kernel,
    pub set: vk::DescriptorSet,
    pub span: String,
}

/// What a render's passes dispatch: over a `width` × `height` image, in bands of
/// `band_rows` rows, each band's stages in order (BDPT: its light subpaths, then its
/// camera subpaths; the other integrators: one kernel).
#[derive(Clone)]
pub struct Passes {
    pub stages: Vec<PassStage>,
    pub width: u32,
    pub height: u32,
    pub band_rows: u32,
}

impl Passes {
    /// The dispatches of passes `first .. first + count` (one sample per pixel each),
    /// band by band, each band's stages in order.
    pub fn dispatches(&self, first: u32, count: u32) -> Vec<Dispatch> {
        let mut list = Vec::new();
        for i in 0..count {
            for y0 in (0..self.height).step_by(self.band_rows as usize) {
                let rows = self.band_rows.min(self.height - y0);
                let params = PassParams {
                    first_sample: first + i,
                    samples: 1,
                    row_begin: y0,
                    row_end: y0 + rows,
                };
                let groups = [
                    self.width.div_ceil(WORKGROUP_SIZE_X),
                    rows.div_ceil(WORKGROUP_SIZE_Y),
                    1,
                ];
                for stage in &self.stages {
                    list.push(
                        Dispatch::new(&stage.kernel, stage.set, &params, groups).timed(&stage.span),
                    );
                }
            }
        }
        list
    }

    /// Dispatches that do nothing (no samples), one per stage, to warm the kernels up.
    pub fn idle(&self) -> Vec<Dispatch> {
        let params = PassParams {
            first_sample: 0,
            samples: 0,
            row_begin: 0,
            row_end: 1,
        };
        self.stages
            .iter()
            .map(|s| Dispatch::new(&s.kernel, s.set, &params, [1, 1, 1]))
            .collect()
    }
}

/// `spp` passes from pass `first`, with an optional resolve for snapshots (the image
/// after a number of passes).
pub struct PassWork<'a> {
    pub passes: &'a Passes,
    pub first: u32,
    pub spp: u32,
    pub resolve: Option<&'a dyn Fn(u32) -> Result<Image>>,
}

impl Work for PassWork<'_> {
    fn total(&self) -> u64 {
        self.spp as u64
    }

    fn dispatches(&mut self, first: u64, count: u64) -> Result<Vec<Dispatch>> {
        Ok(self
            .passes
            .dispatches(self.first + first as u32, count as u32))
    }

    fn snapshot(&self, done: u64) -> Result<Option<(Image, u64)>> {
        match self.resolve {
            Some(r) => Ok(Some((r(done as u32)?, done))),
            None => Ok(None),
        }
    }
}
