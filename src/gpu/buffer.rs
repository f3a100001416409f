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

    /// A device-local buffer holding `data`, copied through a staging buffer.
    pub fn with_data(
        device: &Arc<Device>,
        name: &str,
        data: &[u8],
        usage: vk::BufferUsageFlags,
    ) -> GpuResult<Buffer> {
        let size = (data.len() as u64).max(16);
        let buffer = Buffer::device_local(device, name, size, usage)?;
        buffer.upload(data)?;
        Ok(buffer)
    }

    /// Copy `data` into the start of this device-local buffer (made with TRANSFER_DST),
    /// ordered after every earlier command and before every later one: through a
    /// staging buffer of at most `STAGING_BYTES`, piece by piece, so that a large upload
    /// does not hold a second copy of itself in host memory.
    pub fn upload(&self, data: &[u8]) -> GpuResult<()> {
        self.upload_with(data.len() as u64, 1, &mut |at, out| {
            out.copy_from_slice(&data[at as usize..at as usize + out.len()])
        })
    }

    /// As [`Buffer::upload`], the `len` bytes written by `fill(offset, piece)` straight
    /// into the staging memory, piece by piece in order, each piece a whole number of
    /// `record`-byte records.
    pub fn upload_with(
        &self,
        len: u64,
        record: u64,
        fill: &mut dyn FnMut(u64, &mut [u8]),
    ) -> GpuResult<()> {
        if len == 0 {
            return Ok(());
        }
        let device = &self.device;
        let stage = format!("uploading into '{}'", self.name);
        if len > self.size {
            return Err(other_error(&stage, "data larger than the buffer"));
        }
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
            fill(at, &mut staging.mapped_mut(&stage)?[..part as usize]);
            device.run_commands(&stage, |cmd| unsafe {
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
