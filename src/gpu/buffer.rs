//! Buffers that free themselves: allocate → bind → (use) → free → destroy.
use super::{other_error, Device, GpuResult, Stage};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;
use std::sync::Arc;

/// A global memory barrier: `src` (stages, accesses) of earlier commands, including
/// earlier submissions, before `dst` of later ones.
pub fn memory_barrier(
    device: &Device,
    cmd: vk::CommandBuffer,
    src: (vk::PipelineStageFlags, vk::AccessFlags),
    dst: (vk::PipelineStageFlags, vk::AccessFlags),
) {
    let barrier = vk::MemoryBarrier::default()
        .src_access_mask(src.1)
        .dst_access_mask(dst.1);
    unsafe {
        device.raw.cmd_pipeline_barrier(
            cmd,
            src.0,
            dst.0,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        )
    };
}

/// A barrier from the given writes to any later use: a fence wait alone does not make
/// device writes visible to later commands. Uploads are rare, so the broad scope costs
/// nothing that matters.
pub fn writes_visible_to_later_commands(
    device: &Device,
    cmd: vk::CommandBuffer,
    written: vk::AccessFlags,
) {
    let all = vk::PipelineStageFlags::ALL_COMMANDS;
    memory_barrier(
        device,
        cmd,
        (all, written),
        (
            all,
            vk::AccessFlags::MEMORY_READ | vk::AccessFlags::MEMORY_WRITE,
        ),
    );
}

/// An upload's `fill` that copies `data`.
fn copy_from(data: &[u8]) -> impl FnMut(u64, &mut [u8]) + '_ {
    |at, out| out.copy_from_slice(&data[at as usize..at as usize + out.len()])
}

/// The largest staging buffer an upload makes (64 MiB).
pub const STAGING_BYTES: usize = 64 << 20;

pub struct Buffer {
    device: Arc<Device>,
    pub raw: vk::Buffer,
    allocation: Option<Allocation>,
    pub size: u64,
    pub name: String,
}

impl Buffer {
    pub fn new(
        device: &Arc<Device>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> GpuResult<Buffer> {
        let stage = format!("creating buffer '{name}' ({size} bytes)");
        let size = size.max(16);
        let raw = unsafe {
            device.raw.create_buffer(
                &vk::BufferCreateInfo::default().size(size).usage(usage),
                None,
            )
        }
        .stage(&stage)?;
        let requirements = unsafe { device.raw.get_buffer_memory_requirements(raw) };
        let allocation = device
            .allocator
            .lock()
            .map_err(|_| other_error(&stage, "allocator lock poisoned"))?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            });
        let allocation = match allocation {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.raw.destroy_buffer(raw, None) };
                return Err(other_error(&stage, e));
            }
        };
        if let Err(e) = unsafe {
            device
                .raw
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        } {
            let _ = device.allocator.lock().map(|mut a| a.free(allocation));
            unsafe { device.raw.destroy_buffer(raw, None) };
            return Err(e).stage(&stage);
        }
        Ok(Buffer {
            device: device.clone(),
            raw,
            allocation: Some(allocation),
            size,
            name: name.to_string(),
        })
    }

    /// A device-local buffer that transfers can fill.
    pub fn device_local(
        device: &Arc<Device>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> GpuResult<Buffer> {
        Buffer::new(
            device,
            name,
            size,
            usage | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )
    }

    /// A device-local buffer holding `data` (see [`Buffer::upload`]).
    pub fn with_data(
        device: &Arc<Device>,
        name: &str,
        data: &[u8],
        usage: vk::BufferUsageFlags,
    ) -> GpuResult<Buffer> {
        let size = (data.len() as u64).max(16);
        let mut buffer = Buffer::device_local(device, name, size, usage)?;
        buffer.upload_with(data.len() as u64, 1, &mut copy_from(data))?;
        Ok(buffer)
    }

    /// Copy `data` into the start of this device-local buffer (made with TRANSFER_DST),
    /// ordered after every earlier command and before every later one, through a
    /// staging buffer (of at most `STAGING_BYTES`, piece by piece, so that a large upload
    /// does not hold a second copy of itself in host memory).
    pub fn upload(&self, data: &[u8]) -> GpuResult<()> {
        if data.is_empty() {
            return Ok(());
        }
        let stage = format!("uploading into '{}'", self.name);
        if data.len() as u64 > self.size {
            return Err(other_error(&stage, "data larger than the buffer"));
        }
        self.upload_staged(data.len() as u64, 1, &mut copy_from(data), &stage)
    }

    /// As [`Buffer::upload`], the `len` bytes written by `fill(offset, piece)` in order,
    /// each piece a whole number of `record`-byte records: in place where the host sees
    /// the buffer's memory ([`Buffer::host_writable`]), else into the staging memory.
    pub fn upload_with(
        &mut self,
        len: u64,
        record: u64,
        fill: &mut dyn FnMut(u64, &mut [u8]),
    ) -> GpuResult<()> {
        if len == 0 {
            return Ok(());
        }
        let stage = format!("uploading into '{}'", self.name);
        if len > self.size {
            return Err(other_error(&stage, "data larger than the buffer"));
        }
        match self.host_writable() {
            // Every command submitted so far has ended (`Device::submit_and_wait`, the
            // one way commands are submitted, waits for each), so none reads or writes
            // this memory now; host writes to coherent memory before a submission are
            // visible to its commands.
            Some(memory) => {
                fill(0, &mut memory[..len as usize]);
                Ok(())
            }
            None => self.upload_staged(len, record, fill, &stage),
        }
    }

    /// The buffer's memory, where the host sees it and its writes need no flush (memory
    /// both device local and host visible and coherent: lavapipe's, an integrated GPU's;
    /// gpu-allocator maps such memory): uploads write it in place, with no staging copy.
    pub fn host_writable(&mut self) -> Option<&mut [u8]> {
        let allocation = self.allocation.as_mut()?;
        let coherent = allocation
            .memory_properties()
            .contains(vk::MemoryPropertyFlags::HOST_COHERENT);
        allocation.mapped_slice_mut().filter(|_| coherent)
    }

    /// [`Buffer::upload_with`] through a staging buffer (the only way into memory the
    /// host does not see).
    pub(crate) fn upload_staged(
        &self,
        len: u64,
        record: u64,
        fill: &mut dyn FnMut(u64, &mut [u8]),
        stage: &str,
    ) -> GpuResult<()> {
        let device = &self.device;
        let record = record.max(1);
        let piece = len.min((STAGING_BYTES as u64 / record).max(1) * record);
        let mut staging = Buffer::new(
            device,
            &format!("{} (staging)", self.name),
            piece,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        let mut at = 0;
        while at < len {
            let part = piece.min(len - at);
            // (Each piece's commands have ended before the next overwrites the staging.)
            fill(at, &mut staging.mapped_mut(stage)?[..part as usize]);
            device.run_commands(stage, |cmd| unsafe {
                writes_visible_to_later_commands(
                    device,
                    cmd,
                    vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                );
                device.raw.cmd_copy_buffer(
                    cmd,
                    staging.raw,
                    self.raw,
                    &[vk::BufferCopy::default().dst_offset(at).size(part)],
                );
                writes_visible_to_later_commands(device, cmd, vk::AccessFlags::TRANSFER_WRITE);
            })?;
            at += part;
        }
        Ok(())
    }

    /// Fill the whole buffer with zeros, ordered after every earlier command.
    pub fn clear(&self) -> GpuResult<()> {
        let device = &self.device;
        device.run_commands(&format!("clearing '{}'", self.name), |cmd| unsafe {
            writes_visible_to_later_commands(
                device,
                cmd,
                vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
            );
            device
                .raw
                .cmd_fill_buffer(cmd, self.raw, 0, vk::WHOLE_SIZE, 0);
            writes_visible_to_later_commands(device, cmd, vk::AccessFlags::TRANSFER_WRITE);
        })
    }

    /// A zero-filled device-local buffer.
    pub fn zeroed(
        device: &Arc<Device>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> GpuResult<Buffer> {
        let buffer = Buffer::device_local(device, name, size, usage)?;
        device.run_commands(&format!("clearing '{name}'"), |cmd| unsafe {
            device
                .raw
                .cmd_fill_buffer(cmd, buffer.raw, 0, vk::WHOLE_SIZE, 0);
            writes_visible_to_later_commands(device, cmd, vk::AccessFlags::TRANSFER_WRITE);
        })?;
        Ok(buffer)
    }

    /// The memory of a host-visible buffer, to write into.
    fn mapped_mut(&mut self, stage: &str) -> GpuResult<&mut [u8]> {
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or_else(|| other_error(stage, "buffer is not host visible"))
    }

    /// Read `len` bytes of a host-visible buffer.
    pub fn read(&self, len: usize) -> GpuResult<Vec<u8>> {
        let stage = format!("reading buffer '{}'", self.name);
        let mapped = self
            .allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .ok_or_else(|| other_error(&stage, "buffer is not host visible"))?;
        Ok(mapped[..len.min(mapped.len())].to_vec())
    }

    /// Copy a device-local buffer back to the host.
    pub fn download(&self, len: u64) -> GpuResult<Vec<u8>> {
        let device = &self.device;
        let staging = Buffer::new(
            device,
            &format!("{} (readback)", self.name),
            len,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        device.run_commands(&format!("reading back '{}'", self.name), |cmd| {
            memory_barrier(
                device,
                cmd,
                (
                    vk::PipelineStageFlags::ALL_COMMANDS,
                    vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE,
                ),
                (
                    vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::TRANSFER_READ,
                ),
            );
            let region = [vk::BufferCopy::default().size(len)];
            unsafe {
                device
                    .raw
                    .cmd_copy_buffer(cmd, self.raw, staging.raw, &region)
            };
            // Make the copy visible to the host (a fence alone does not).
            memory_barrier(
                device,
                cmd,
                (
                    vk::PipelineStageFlags::TRANSFER,
                    vk::AccessFlags::TRANSFER_WRITE,
                ),
                (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
            );
        })?;
        staging.read(len as usize)
    }

    pub fn device_address(&self) -> vk::DeviceAddress {
        unsafe {
            self.device
                .raw
                .get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(self.raw))
        }
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if let Some(allocation) = self.allocation.take() {
            if let Ok(mut a) = self.device.allocator.lock() {
                let _ = a.free(allocation);
            }
        }
        unsafe { self.device.raw.destroy_buffer(self.raw, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Validation;

    /// The two ways into a device-local buffer give the same bytes: in place (lavapipe's
    /// memory is host visible and coherent, so `upload_with` writes it) and through the
    /// staging buffer, piece by piece (the way into a discrete GPU's memory), with records
    /// of 48 bytes over more than one staging piece; both read back by a copy on the device.
    #[test]
    fn uploads_in_place_and_through_staging_give_the_same_bytes() {
        let device = Arc::new(
            Device::open(None, false, Validation::Off).expect("a Vulkan device (lavapipe)"),
        );
        let record = 48u64;
        let len = (STAGING_BYTES as u64 / record + 1000) * record;
        let word = |i: u64| (i.wrapping_mul(2654435761) >> 7) as u32;
        let mut fill = |at: u64, out: &mut [u8]| {
            assert_eq!(at % record, 0, "a piece starts at a record");
            assert_eq!(out.len() as u64 % record, 0, "a piece is whole records");
            for (k, w) in out.chunks_exact_mut(4).enumerate() {
                w.copy_from_slice(&word(at / 4 + k as u64).to_ne_bytes());
            }
        };
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let mut in_place = Buffer::device_local(&device, "in place", len, usage).unwrap();
        assert!(
            in_place.host_writable().is_some(),
            "{}: device-local memory the host does not see (the test is for lavapipe)",
            device.info.name
        );
        in_place.upload_with(len, record, &mut fill).unwrap();
        let staged = Buffer::device_local(&device, "staged", len, usage).unwrap();
        staged
            .upload_staged(len, record, &mut fill, "test")
            .unwrap();
        let want: Vec<u8> = (0..len / 4).flat_map(|i| word(i).to_ne_bytes()).collect();
        for (how, buffer) in [("in place", &in_place), ("staged", &staged)] {
            let got = buffer.download(len).unwrap();
            let first = got.iter().zip(&want).position(|(a, b)| a != b);
            assert_eq!(first, None, "{how}: the first byte that differs");
        }
    }
}
