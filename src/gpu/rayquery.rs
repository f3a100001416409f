//! Acceleration structures for VK_KHR_ray_query: one triangle BLAS (the scene's
//! triangles, already in BVH leaf order — lavapipe's builder splits index ranges
//! without sorting, so file order can trace hundreds of times slower), one unit-cube
//! AABB BLAS shared by every sphere, and a TLAS with one instance per sphere whose
//! transform is the sphere's object-to-world matrix.
use crate::gpu::buffer::{writes_visible_to_later_commands, Buffer};
use crate::gpu::{other_error, Device, GpuResult, Stage};
use ash::vk;
use glam::Mat4;
use std::sync::Arc;

pub struct AccelStructure {
    device: Arc<Device>,
    pub raw: vk::AccelerationStructureKHR,
    _storage: Buffer,
}

impl Drop for AccelStructure {
    fn drop(&mut self) {
        if let Some(loader) = &self.device.accel_loader {
            unsafe { loader.destroy_acceleration_structure(self.raw, None) };
        }
    }
}

pub struct RayQueryScene {
    pub tlas: AccelStructure,
    _blas: Vec<AccelStructure>,
    _inputs: Vec<Buffer>,
}

impl RayQueryScene {
    /// The bytes of device memory the acceleration structures and their inputs hold.
    pub fn device_bytes(&self) -> u64 {
        std::iter::once(&self.tlas)
            .chain(&self._blas)
            .map(|a| a._storage.size)
            .chain(self._inputs.iter().map(|b| b.size))
            .sum()
    }
}

const INPUT_USAGE: vk::BufferUsageFlags = vk::BufferUsageFlags::from_raw(
    vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS.as_raw()
        | vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR.as_raw()
        | vk::BufferUsageFlags::STORAGE_BUFFER.as_raw(),
);

/// An acceleration structure over `geometries`, each with its primitive count.
fn build(
    device: &Arc<Device>,
    name: &str,
    ty: vk::AccelerationStructureTypeKHR,
    geometries: &[(vk::AccelerationStructureGeometryKHR, u32)],
) -> GpuResult<AccelStructure> {
    let stage = format!("building the {name} acceleration structure");
    let loader = device
        .accel_loader
        .as_ref()
        .ok_or_else(|| other_error(&stage, "ray query not enabled"))?;
    let counts: Vec<u32> = geometries.iter().map(|g| g.1).collect();
    let geometries: Vec<_> = geometries.iter().map(|g| g.0).collect();
    let mut info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(&geometries);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    unsafe {
        loader.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &info,
            &counts,
            &mut sizes,
        )
    };
    let storage = Buffer::new(
        device,
        &format!("{name} acceleration structure"),
        sizes.acceleration_structure_size,
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        gpu_allocator::MemoryLocation::GpuOnly,
    )?;
    let raw = unsafe {
        loader.create_acceleration_structure(
            &vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(storage.raw)
                .size(sizes.acceleration_structure_size)
                .ty(ty),
            None,
        )
    }
    .stage(&stage)?;
    let accel = AccelStructure {
        device: device.clone(),
        raw,
        _storage: storage,
    };
    // Scratch alignment is a device limit; over-allocate and align the address.
    let align = 256u64;
    let scratch = Buffer::new(
        device,
        &format!("{name} build scratch"),
        sizes.build_scratch_size + align,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        gpu_allocator::MemoryLocation::GpuOnly,
    )?;
    let scratch_address = (scratch.device_address() + align - 1) & !(align - 1);
    info = info
        .dst_acceleration_structure(raw)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: scratch_address,
        });
    let range: Vec<_> = counts
        .iter()
        .map(|&c| vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(c))
        .collect();
    let ranges: [&[vk::AccelerationStructureBuildRangeInfoKHR]; 1] = [&range];
    device.run_commands(&stage, |cmd| unsafe {
        loader.cmd_build_acceleration_structures(cmd, std::slice::from_ref(&info), &ranges);
        // The TLAS build reads the BLASes, and the kernels read the TLAS.
        writes_visible_to_later_commands(
            device,
            cmd,
            vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR,
        );
    })?;
    Ok(accel)
}

fn address_of(device: &Device, a: &AccelStructure) -> u64 {
    let loader = device.accel_loader.as_ref().expect("checked by build");
    unsafe {
        loader.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(a.raw),
        )
    }
}

/// `triangles` is the GPU triangle buffer (three vec4 vertices per triangle, used as a
/// vertex buffer of stride 16), `sphere_transforms` the spheres' object-to-world maps
/// (`None`: a hidden sphere, an invisible light, which gets no instance).
/// `alpha`: some triangles have alpha cut-outs, so the triangles are not opaque (the
/// shaders test each candidate, trace_rayquery.glsl); otherwise everything is opaque.
pub fn build_scene(
    device: &Arc<Device>,
    (chunks, shift): (&[Buffer], u32),
    triangle_count: u32,
    sphere_transforms: &[Option<Mat4>],
    alpha: bool,
    objects: &[(u32, u32)],
    object_instances: &[crate::scene::Instance],
) -> GpuResult<RayQueryScene> {
    let mut blas = Vec::new();
    let mut inputs = Vec::new();
    let mut instances: Vec<vk::AccelerationStructureInstanceKHR> = Vec::new();
    let opaque = vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE
        | vk::GeometryInstanceFlagsKHR::FORCE_OPAQUE;
    let triangle_flags = if alpha {
        vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE
    } else {
        opaque
    };
    let instance = |transform: [f32; 12],
                    custom: u32,
                    reference: u64,
                    flags: vk::GeometryInstanceFlagsKHR|
     -> vk::AccelerationStructureInstanceKHR {
        vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR { matrix: transform },
            instance_custom_index_and_mask: vk::Packed24_8::new(custom, 0xff),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                0,
                flags.as_raw() as u8,
            ),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                device_handle: reference,
            },
        }
    };
    // The geometries of triangle records `first..first + count`: the range cut where the
    // triangle data's chunks begin (a geometry's corners lie in one buffer), so that
    // geometry g > 0 starts at a chunk (trace_rayquery.glsl `rq_record`).
    let per_chunk = if shift >= 31 { u64::MAX } else { 1u64 << shift };
    let triangle_geometries = |first: u32, count: u32, flags: vk::GeometryFlagsKHR| {
        let (first, end) = (first as u64, first as u64 + count as u64);
        let mut geometries = Vec::new();
        let mut at = first;
        while at < end {
            let chunk = at / per_chunk;
            let chunk_start = chunk * per_chunk;
            let n = (end - at).min(chunk_start + per_chunk - at);
            let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                .vertex_data(vk::DeviceOrHostAddressConstKHR {
                    device_address: chunks[chunk as usize].device_address()
                        + 48 * (at - chunk_start),
                })
                .vertex_stride(16)
                .max_vertex(n as u32 * 3 - 1)
                .index_type(vk::IndexType::NONE_KHR);
            let geometry = vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
                .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
                .flags(flags);
            geometries.push((geometry, n as u32));
            at += n;
        }
        geometries
    };
    if triangle_count > 0 {
        let flags = if alpha {
            vk::GeometryFlagsKHR::empty()
        } else {
            vk::GeometryFlagsKHR::OPAQUE
        };
        let b = build(
            device,
            "triangle BLAS",
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            &triangle_geometries(0, triangle_count, flags),
        )?;
        let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        instances.push(instance(
            identity,
            0,
            address_of(device, &b),
            triangle_flags,
        ));
        blas.push(b);
    }
    if sphere_transforms.iter().any(Option::is_some) {
        let aabb: [f32; 6] = [-1.0, -1.0, -1.0, 1.0, 1.0, 1.0];
        let aabb_buffer = Buffer::with_data(
            device,
            "sphere AABB",
            bytemuck::cast_slice(&aabb),
            INPUT_USAGE,
        )?;
        let aabbs = vk::AccelerationStructureGeometryAabbsDataKHR::default()
            .data(vk::DeviceOrHostAddressConstKHR {
                device_address: aabb_buffer.device_address(),
            })
            .stride(24);
        let geometry = vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::AABBS)
            .geometry(vk::AccelerationStructureGeometryDataKHR { aabbs })
            .flags(vk::GeometryFlagsKHR::OPAQUE);
        let b = build(
            device,
            "sphere BLAS",
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            &[(geometry, 1)],
        )?;
        let reference = address_of(device, &b);
        for (i, m) in sphere_transforms.iter().enumerate() {
            let Some(m) = m else { continue };
            let r = m.transpose().to_cols_array(); // rows of m
            instances.push(instance(
                [
                    r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11],
                ],
                i as u32,
                reference,
                opaque,
            ));
        }
        blas.push(b);
        inputs.push(aabb_buffer);
    }
    // Each object's BLAS (opaque: an object's triangles have no alpha), and an instance
    // of it per instance, custom index 1 + the instance's index (trace_rayquery.glsl).
    if object_instances.len() >= (1 << 24) - 1 {
        return Err(other_error(
            "building the TLAS",
            format!(
                "{} instances: a TLAS instance's custom index holds fewer than 2^24",
                object_instances.len()
            ),
        ));
    }
    let mut object_blas = Vec::with_capacity(objects.len());
    for (o, &(first, count)) in objects.iter().enumerate() {
        let b = build(
            device,
            &format!("object {o}'s BLAS"),
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            &triangle_geometries(first, count, vk::GeometryFlagsKHR::OPAQUE),
        )?;
        object_blas.push(address_of(device, &b));
        blas.push(b);
    }
    for (k, inst) in object_instances.iter().enumerate() {
        let r = inst.object_to_world.transpose().to_cols_array(); // rows
        instances.push(instance(
            [
                r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8], r[9], r[10], r[11],
            ],
            k as u32 + 1,
            object_blas[inst.object as usize],
            opaque,
        ));
    }
    let instance_bytes: Vec<u8> = instances
        .iter()
        .flat_map(|i| {
            // SAFETY: AccelerationStructureInstanceKHR is a plain 64-byte C struct.
            unsafe {
                std::slice::from_raw_parts(i as *const _ as *const u8, std::mem::size_of_val(i))
            }
            .to_vec()
        })
        .collect();
    let instance_buffer =
        Buffer::with_data(device, "TLAS instances", &instance_bytes, INPUT_USAGE)?;
    let data = vk::AccelerationStructureGeometryInstancesDataKHR::default()
        .array_of_pointers(false)
        .data(vk::DeviceOrHostAddressConstKHR {
            device_address: instance_buffer.device_address(),
        });
    let geometry = vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::INSTANCES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { instances: data })
        .flags(vk::GeometryFlagsKHR::OPAQUE);
    let tlas = build(
        device,
        "TLAS",
        vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        &[(geometry, instances.len() as u32)],
    )?;
    inputs.push(instance_buffer);
    Ok(RayQueryScene {
        tlas,
        _blas: blas,
        _inputs: inputs,
    })
}
