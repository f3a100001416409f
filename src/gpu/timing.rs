//! GPU timestamps around dispatches (one query pool, two queries per span).
use super::{Device, GpuResult, Stage};
use ash::vk;
use std::sync::Arc;

pub struct Timestamps {
    device: Arc<Device>,
    pool: vk::QueryPool,
    capacity: u32,
    used: u32,
    pub enabled: bool,
}

impl Timestamps {
    pub fn new(device: &Arc<Device>, spans: u32) -> GpuResult<Timestamps> {
        let capacity = spans * 2;
        let enabled = device.info.timestamps;
        let pool = unsafe {
            device.raw.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(capacity.max(2)),
                None,
            )
        }
        .stage("creating the timestamp query pool")?;
        Ok(Timestamps {
            device: device.clone(),
            pool,
            capacity,
            used: 0,
            enabled,
        })
    }

    /// Reset the pool (outside a render pass; before the batch's first span).
    pub fn reset(&mut self, cmd: vk::CommandBuffer) {
        unsafe {
            self.device
                .raw
                .cmd_reset_query_pool(cmd, self.pool, 0, self.capacity.max(2))
        };
        self.used = 0;
    }

    /// Start a span; returns its index, or None when the pool is full or disabled.
    pub fn begin(&mut self, cmd: vk::CommandBuffer) -> Option<u32> {
        if !self.enabled || self.used + 2 > self.capacity {
            return None;
        }
        let i = self.used;
        unsafe {
            // Begin when all earlier work has finished, so spans never overlap even
            // where the device runs dispatches concurrently.
            self.device.raw.cmd_write_timestamp(
                cmd,
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                self.pool,
                i,
            )
        };
        self.used += 2;
        Some(i / 2)
    }

    pub fn end(&mut self, cmd: vk::CommandBuffer, span: Option<u32>) {
        if let Some(s) = span {
            unsafe {
                self.device.raw.cmd_write_timestamp(
                    cmd,
                    vk::PipelineStageFlags::BOTTOM_OF_PIPE,
                    self.pool,
                    s * 2 + 1,
                )
            };
        }
    }

    /// (start, end) of each span in nanoseconds of the device clock.
    pub fn read(&self) -> GpuResult<Vec<(f64, f64)>> {
        if !self.enabled || self.used == 0 {
            return Ok(Vec::new());
        }
        let mut data = vec![0u64; self.used as usize];
        unsafe {
            self.device.raw.get_query_pool_results(
                self.pool,
                0,
                &mut data,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .stage("reading GPU timestamps")?;
        let period = self.device.info.timestamp_period_ns as f64;
        Ok(data
            .chunks_exact(2)
            .map(|c| (c[0] as f64 * period, c[1] as f64 * period))
            .collect())
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        unsafe { self.device.raw.destroy_query_pool(self.pool, None) };
    }
}
