//! The one place that records dispatches: a list of them (kernel, descriptor set, push
//! constants, group counts, an optional GPU span) becomes one submission, with a barrier
//! after every dispatch and timestamps around the timed ones.
use super::Engine;
use crate::gpu::buffer::memory_barrier;
use crate::gpu::kernels::Kernel;
use crate::gpu::timing::Timestamps;
use crate::trace::Trace;
use anyhow::Result;
use ash::vk;
use std::time::Instant;

/// One dispatch of a kernel.
#[derive(Clone)]
pub struct Dispatch {
    /// The kernel's name, for messages.
    pub kernel: &'static str,
    pub pipeline: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set: vk::DescriptorSet,
    pub push: Vec<u8>,
    pub groups: [u32; 3],
    /// The GPU span it is timed as in the trace; `None`: not timed.
    pub span: Option<String>,
    /// Group counts read on the device from this buffer at this offset (a
    /// `VkDispatchIndirectCommand` a previous dispatch wrote) instead of `groups`.
    pub indirect: Option<(vk::Buffer, u64)>,
}

impl Dispatch {
    /// `kernel` with descriptor set `set`, push constants `push`, `groups` workgroups.
    pub fn new(
        kernel: &Kernel,
        set: vk::DescriptorSet,
        push: &impl bytemuck::Pod,
        groups: [u32; 3],
    ) -> Dispatch {
        Dispatch {
            kernel: kernel.name,
            pipeline: kernel.pipeline,
            layout: kernel.layout,
            set,
            push: bytemuck::bytes_of(push).to_vec(),
            groups,
            span: None,
            indirect: None,
        }
    }

    /// `kernel` with its group counts read from `buffer` at `offset` when it runs.
    pub fn indirect(
        kernel: &Kernel,
        set: vk::DescriptorSet,
        push: &impl bytemuck::Pod,
        buffer: vk::Buffer,
        offset: u64,
    ) -> Dispatch {
        let mut d = Dispatch::new(kernel, set, push, [0, 0, 0]);
        d.indirect = Some((buffer, offset));
        d
    }

    /// Time it on the device as a span named `span`.
    pub fn timed(mut self, span: &str) -> Dispatch {
        self.span = Some(span.to_string());
        self
    }
}

/// The device time of a submission's timed dispatches, by span name, in the order they
/// first appear.
#[derive(Clone, Debug, Default)]
pub struct SubmitTimes {
    pub spans: Vec<(String, f64)>,
}

impl SubmitTimes {
    pub fn total(&self) -> f64 {
        self.spans.iter().map(|(_, s)| s).sum()
    }

    pub fn of(&self, span: &str) -> f64 {
        self.spans
            .iter()
            .filter(|(n, _)| n == span)
            .map(|(_, s)| s)
            .sum()
    }

    pub fn add(&mut self, span: &str, seconds: f64) {
        match self.spans.iter_mut().find(|(n, _)| n == span) {
            Some((_, s)) => *s += seconds,
            None => self.spans.push((span.to_string(), seconds)),
        }
    }

    pub fn merge(&mut self, other: &SubmitTimes) {
        for (n, s) in &other.spans {
            self.add(n, *s);
        }
    }
}

impl Engine {
    /// Record `list` as one submission (`stage` names it in errors), submit it and wait.
    /// Every dispatch is ordered after the previous one by a barrier (passes accumulate
    /// into the same film pixels, bands reuse buffers, MMLT's modes feed each other).
    /// Each timed dispatch becomes a GPU span in `trace` (one span for the submission
    /// when the device has no timestamps); returns the device seconds by span.
    pub fn submit(&self, list: &[Dispatch], stage: &str, trace: &mut Trace) -> Result<SubmitTimes> {
        let device = &self.device;
        let timed = list.iter().filter(|d| d.span.is_some()).count() as u32;
        let mut timestamps = Timestamps::new(device, timed.max(1))?;
        let cmd = device.begin_commands(stage)?;
        timestamps.reset(cmd);
        let mut bound: Option<(vk::Pipeline, vk::DescriptorSet)> = None;
        let mut spans: Vec<&str> = Vec::new();
        let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
        unsafe {
            for d in list {
                if bound != Some((d.pipeline, d.set)) {
                    device
                        .raw
                        .cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, d.pipeline);
                    device.raw.cmd_bind_descriptor_sets(
                        cmd,
                        vk::PipelineBindPoint::COMPUTE,
                        d.layout,
                        0,
                        &[d.set],
                        &[],
                    );
                    bound = Some((d.pipeline, d.set));
                }
                if !d.push.is_empty() {
                    device.raw.cmd_push_constants(
                        cmd,
                        d.layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        &d.push,
                    );
                }
                let span = match &d.span {
                    Some(name) => {
                        spans.push(name);
                        timestamps.begin(cmd)
                    }
                    None => None,
                };
                match d.indirect {
                    Some((buffer, offset)) => device.raw.cmd_dispatch_indirect(cmd, buffer, offset),
                    None => device
                        .raw
                        .cmd_dispatch(cmd, d.groups[0], d.groups[1], d.groups[2]),
                }
                timestamps.end(cmd, span);
                memory_barrier(
                    device,
                    cmd,
                    (compute, vk::AccessFlags::SHADER_WRITE),
                    (
                        compute
                            | vk::PipelineStageFlags::TRANSFER
                            | vk::PipelineStageFlags::DRAW_INDIRECT,
                        vk::AccessFlags::SHADER_READ
                            | vk::AccessFlags::SHADER_WRITE
                            | vk::AccessFlags::TRANSFER_READ
                            | vk::AccessFlags::INDIRECT_COMMAND_READ,
                    ),
                );
            }
        }
        let submit_us = trace.now_us();
        let t0 = Instant::now();
        device.submit_and_wait(cmd, stage)?;
        let wall = t0.elapsed().as_secs_f64();
        let times = timestamps.read()?;
        let mut out = SubmitTimes::default();
        if times.is_empty() {
            if let Some(first) = spans.first() {
                trace.add_gpu(first, submit_us, wall * 1e6);
                out.add(first, wall);
            }
            return Ok(out);
        }
        let origin = times[0].0;
        for (name, (s, e)) in spans.iter().zip(&times) {
            trace.add_gpu(name, submit_us + (s - origin) / 1e3, (e - s) / 1e3);
            out.add(name, (e - s) / 1e9);
        }
        Ok(out)
    }
}
