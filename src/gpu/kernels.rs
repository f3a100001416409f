//! Compute pipelines for the kernels in glsl/, one descriptor layout per traversal
//! backend, and the descriptor set that binds a scene's buffers.
use super::abi::*;
use super::{other_error, Device, GpuResult, Stage};
use ash::vk;
use std::collections::HashMap;
use std::sync::Arc;

include!(concat!(env!("OUT_DIR"), "/kernels.rs"));

/// Which visibility implementation the kernels are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    RayQuery,
    /// The compressed 8-wide BVH in storage buffers.
    Cwbvh,
    /// The binary SAH BVH in storage buffers.
    Bvh2,
}

impl Backend {
    pub fn name(self) -> &'static str {
        match self {
            Backend::RayQuery => "rayquery",
            Backend::Cwbvh => "cwbvh",
            Backend::Bvh2 => "bvh2",
        }
    }

    /// The tree the kernels walk from storage buffers; `None` for ray query.
    pub fn bvh_kind(self) -> Option<crate::accel::BvhKind> {
        match self {
            Backend::RayQuery => None,
            Backend::Cwbvh => Some(crate::accel::BvhKind::Compressed),
            Backend::Bvh2 => Some(crate::accel::BvhKind::Binary),
        }
    }
}

/// The SPIR-V of one kernel for one backend.
pub fn spirv(kernel: &str, backend: Backend) -> Option<&'static [u8]> {
    KERNELS
        .iter()
        .find(|(k, b, _)| *k == kernel && *b == backend.name())
        .map(|(_, _, s)| *s)
}

/// Every binding of set 0 and its descriptor type for a backend.
pub fn bindings(backend: Backend) -> Vec<(u32, vk::DescriptorType)> {
    let storage = vk::DescriptorType::STORAGE_BUFFER;
    let mut b = vec![
        (BINDING_SCENE, vk::DescriptorType::UNIFORM_BUFFER),
        (BINDING_TRIANGLES, storage),
        (BINDING_SPHERES, storage),
        (BINDING_MATERIALS, storage),
        (BINDING_EMITTERS, storage),
        (BINDING_EMITTER_CDF, storage),
        (BINDING_FILM, storage),
        (BINDING_STATS, storage),
        (BINDING_SPLAT, storage),
        (BINDING_PATH_VERTICES, storage),
        (BINDING_STRATEGIES, storage),
        (BINDING_CHAIN_SAMPLES, storage),
        (BINDING_CHAINS, storage),
        (BINDING_BOOTSTRAP, storage),
    ];
    match backend {
        Backend::RayQuery => b.push((BINDING_TLAS, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)),
        Backend::Cwbvh | Backend::Bvh2 => {
            b.push((BINDING_BVH_NODES, storage));
            b.push((BINDING_BVH_PRIMS, storage));
        }
    }
    b
}

/// The push-constant range every kernel shares: the largest per-dispatch struct.
pub fn push_constant_bytes() -> u32 {
    std::mem::size_of::<PassParams>().max(std::mem::size_of::<MmltParams>()) as u32
}

pub struct Kernels {
    device: Arc<Device>,
    pub backend: Backend,
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pipelines: HashMap<&'static str, vk::Pipeline>,
    pool: vk::DescriptorPool,
}

impl Kernels {
    pub fn new(device: &Arc<Device>, backend: Backend) -> GpuResult<Kernels> {
        let stage = "creating the descriptor layout";
        let layout_bindings: Vec<_> = bindings(backend)
            .into_iter()
            .map(|(b, t)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(t)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_layout = unsafe {
            device.raw.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings),
                None,
            )
        }
        .stage(stage)?;
        let set_layouts = [set_layout];
        let push = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .size(push_constant_bytes())];
        let layout = unsafe {
            device.raw.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&push),
                None,
            )
        }
        .stage("creating the pipeline layout")?;
        let mut sizes = vec![
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: 4,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: 64,
            },
        ];
        if backend == Backend::RayQuery {
            sizes.push(vk::DescriptorPoolSize {
                ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                descriptor_count: 4,
            });
        }
        let pool = unsafe {
            device.raw.create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(4)
                    .pool_sizes(&sizes),
                None,
            )
        }
        .stage("creating the descriptor pool")?;
        Ok(Kernels {
            device: device.clone(),
            backend,
            set_layout,
            layout,
            pipelines: HashMap::new(),
            pool,
        })
    }

    /// The pipeline of a kernel, created (through the on-disk pipeline cache) on first use.
    pub fn pipeline(&mut self, kernel: &'static str) -> GpuResult<vk::Pipeline> {
        if let Some(&p) = self.pipelines.get(kernel) {
            return Ok(p);
        }
        let stage = format!("creating the '{kernel}' pipeline ({})", self.backend.name());
        let code = spirv(kernel, self.backend)
            .ok_or_else(|| other_error(&stage, "kernel not compiled in"))?;
        let words: Vec<u32> = code
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let module = unsafe {
            self.device
                .raw
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
        }
        .stage(&stage)?;
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(vk::ShaderStageFlags::COMPUTE)
                    .module(module)
                    .name(c"main"),
            )
            .layout(self.layout)];
        let result = unsafe {
            self.device
                .raw
                .create_compute_pipelines(self.device.pipeline_cache, &info, None)
        };
        unsafe { self.device.raw.destroy_shader_module(module, None) };
        let pipeline = result.map_err(|(_, e)| e).stage(&stage)?[0];
        self.pipelines.insert(kernel, pipeline);
        Ok(pipeline)
    }

    /// Allocate a descriptor set and point its bindings at `buffers` (binding → buffer)
    /// and, for ray query, `tlas`.
    pub fn descriptor_set(
        &self,
        buffers: &[(u32, vk::Buffer, vk::DescriptorType)],
        tlas: Option<vk::AccelerationStructureKHR>,
    ) -> GpuResult<vk::DescriptorSet> {
        let stage = "writing the descriptor set";
        // One render's set is live at a time: recycle the pool's sets.
        unsafe {
            self.device
                .raw
                .reset_descriptor_pool(self.pool, vk::DescriptorPoolResetFlags::empty())
        }
        .stage(stage)?;
        let layouts = [self.set_layout];
        let set = unsafe {
            self.device.raw.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(self.pool)
                    .set_layouts(&layouts),
            )
        }
        .stage(stage)?[0];
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|(_, b, _)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(*b)
                    .range(vk::WHOLE_SIZE)]
            })
            .collect();
        let mut writes: Vec<vk::WriteDescriptorSet> = buffers
            .iter()
            .zip(&infos)
            .map(|((binding, _, ty), info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*binding)
                    .descriptor_type(*ty)
                    .buffer_info(info)
            })
            .collect();
        let tlas_list = tlas.map(|t| [t]);
        let mut as_write = tlas_list.as_ref().map(|l| {
            vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(l)
        });
        if let Some(w) = as_write.as_mut() {
            let mut write = vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(BINDING_TLAS)
                .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
                .push_next(w);
            write.descriptor_count = 1;
            writes.push(write);
        }
        unsafe { self.device.raw.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }
}

impl Drop for Kernels {
    fn drop(&mut self) {
        unsafe {
            for (_, p) in self.pipelines.drain() {
                self.device.raw.destroy_pipeline(p, None);
            }
            self.device.raw.destroy_descriptor_pool(self.pool, None);
            self.device.raw.destroy_pipeline_layout(self.layout, None);
            self.device
                .raw
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
