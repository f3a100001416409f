//! Compute pipelines for the kernels in glsl/: each kernel's descriptor-set layout is
//! read from its SPIR-V (`reflect`), so the GLSL declaration is the only list of what a
//! kernel binds; descriptor sets are written by binding number from abi.h.
use super::reflect::{kernel_bindings, KernelBinding};
use super::{other_error, Device, GpuResult, Stage};
use crate::abi::{MmltParams, PassParams, WavefrontParams};
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
}

/// The SPIR-V of one kernel for one backend.
pub fn spirv(kernel: &str, backend: Backend) -> Option<&'static [u8]> {
    KERNELS
        .iter()
        .find(|(k, b, _)| *k == kernel && *b == backend.name())
        .map(|(_, _, s)| *s)
}

/// The push-constant range every kernel shares: the largest per-dispatch struct.
pub fn push_constant_bytes() -> u32 {
    std::mem::size_of::<PassParams>()
        .max(std::mem::size_of::<MmltParams>())
        .max(std::mem::size_of::<WavefrontParams>()) as u32
}

/// A kernel ready to dispatch: its pipeline, layouts and the bindings it uses.
#[derive(Clone)]
pub struct Kernel {
    pub name: &'static str,
    pub pipeline: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    pub bindings: Arc<[KernelBinding]>,
}

/// What a descriptor of a kernel's set points at.
#[derive(Clone, Copy, Debug)]
pub enum Resource {
    Buffer(vk::Buffer),
    AccelerationStructure(vk::AccelerationStructureKHR),
}

/// The values of a kernel's specialization constants (abi.h's `SPEC_*`), chosen per
/// scene: code for what the scene lacks is removed before the driver compiles the
/// pipeline (glsl/lib/features.glsl). lavapipe's compile time grows faster than a
/// kernel's code, so a kernel without the features a scene lacks compiles several
/// times faster (docs/performance.md, "Kernels specialized to the scene").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Specialization {
    /// abi.h's `FEATURE_*` bits: what the scene has.
    pub features: u32,
    /// abi.h's `MORE_FEATURE_*` bits (`SPEC_MORE_FEATURES`): what else it has.
    pub more_features: u32,
}

/// The kernels of one backend, created on first use, and the pool their sets come from.
pub struct Kernels {
    device: Arc<Device>,
    pub backend: Backend,
    kernels: HashMap<(&'static str, Specialization), Kernel>,
    pool: vk::DescriptorPool,
}

/// Descriptor sets one render may hold at once (reset by `Kernels::reset_sets`).
const MAX_SETS: u32 = 32;

impl Kernels {
    pub fn new(device: &Arc<Device>, backend: Backend) -> GpuResult<Kernels> {
        let mut sizes = vec![
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::UNIFORM_BUFFER,
                descriptor_count: MAX_SETS,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: MAX_SETS * 24,
            },
        ];
        if backend == Backend::RayQuery {
            sizes.push(vk::DescriptorPoolSize {
                ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                descriptor_count: MAX_SETS,
            });
        }
        let pool = unsafe {
            device.raw.create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(MAX_SETS)
                    .pool_sizes(&sizes),
                None,
            )
        }
        .stage("creating the descriptor pool")?;
        Ok(Kernels {
            device: device.clone(),
            backend,
            kernels: HashMap::new(),
            pool,
        })
    }

    /// Whether `kernel` was compiled in.
    pub fn has(&self, kernel: &str) -> bool {
        spirv(kernel, self.backend).is_some()
    }

    /// The kernel `name` specialized by `spec`, its pipeline created (through the on-disk
    /// pipeline cache) on first use.
    pub fn get(&mut self, name: &'static str, spec: Specialization) -> GpuResult<Kernel> {
        if let Some(k) = self.kernels.get(&(name, spec)) {
            return Ok(k.clone());
        }
        let stage = format!("creating the '{name}' pipeline ({})", self.backend.name());
        let code = spirv(name, self.backend)
            .ok_or_else(|| other_error(&stage, "kernel not compiled in"))?;
        let bindings = kernel_bindings(code).map_err(|e| other_error(&stage, e))?;
        let d = &self.device.raw;
        let layout_bindings: Vec<_> = bindings
            .iter()
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b.binding)
                    .descriptor_type(b.ty)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_layout = unsafe {
            d.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings),
                None,
            )
        }
        .stage(&stage)?;
        let set_layouts = [set_layout];
        let push = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .size(push_constant_bytes())];
        let layout = match unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&push),
                None,
            )
        } {
            Ok(l) => l,
            Err(e) => {
                unsafe { d.destroy_descriptor_set_layout(set_layout, None) };
                return Err(e).stage(&stage);
            }
        };
        let code_words: Vec<u32> = code
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        let pipeline = (|| {
            let module = unsafe {
                d.create_shader_module(
                    &vk::ShaderModuleCreateInfo::default().code(&code_words),
                    None,
                )
            }?;
            let values = [spec.features, spec.more_features];
            let entries = [
                vk::SpecializationMapEntry {
                    constant_id: crate::abi::SPEC_FEATURES,
                    offset: 0,
                    size: std::mem::size_of::<u32>(),
                },
                vk::SpecializationMapEntry {
                    constant_id: crate::abi::SPEC_MORE_FEATURES,
                    offset: std::mem::size_of::<u32>() as u32,
                    size: std::mem::size_of::<u32>(),
                },
            ];
            let spec_info = vk::SpecializationInfo::default()
                .map_entries(&entries)
                .data(bytemuck::cast_slice(&values));
            let info = [vk::ComputePipelineCreateInfo::default()
                .stage(
                    vk::PipelineShaderStageCreateInfo::default()
                        .stage(vk::ShaderStageFlags::COMPUTE)
                        .module(module)
                        .name(c"main")
                        .specialization_info(&spec_info),
                )
                .layout(layout)];
            let result =
                unsafe { d.create_compute_pipelines(self.device.pipeline_cache, &info, None) };
            unsafe { d.destroy_shader_module(module, None) };
            result.map(|p| p[0]).map_err(|(_, e)| e)
        })();
        let pipeline = match pipeline {
            Ok(p) => p,
            Err(e) => {
                unsafe {
                    d.destroy_pipeline_layout(layout, None);
                    d.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(e).stage(&stage);
            }
        };
        let kernel = Kernel {
            name,
            pipeline,
            layout,
            set_layout,
            bindings: bindings.into(),
        };
        self.kernels.insert((name, spec), kernel.clone());
        Ok(kernel)
    }

    /// Free every descriptor set allocated so far (at the start of a render: the sets of
    /// the previous one are no longer in use).
    pub fn reset_sets(&self) -> GpuResult<()> {
        unsafe {
            self.device
                .raw
                .reset_descriptor_pool(self.pool, vk::DescriptorPoolResetFlags::empty())
        }
        .stage("resetting the descriptor pool")
    }

    /// A descriptor set for `kernel` with each of its bindings pointed at the resource of
    /// the same binding number in `resources`. Resources the kernel does not use are
    /// ignored; a binding it uses that `resources` lacks is an error naming it.
    pub fn descriptor_set(
        &self,
        kernel: &Kernel,
        resources: &[(u32, Resource)],
    ) -> GpuResult<vk::DescriptorSet> {
        let stage = format!("binding the resources of the '{}' kernel", kernel.name);
        let mut chosen = Vec::with_capacity(kernel.bindings.len());
        for b in kernel.bindings.iter() {
            let Some((_, r)) = resources.iter().find(|(n, _)| *n == b.binding) else {
                return Err(other_error(
                    &stage,
                    format!("nothing is bound at binding {} ({})", b.binding, b.name),
                ));
            };
            let matches = match r {
                Resource::Buffer(_) => b.ty != vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                Resource::AccelerationStructure(_) => {
                    b.ty == vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
                }
            };
            if !matches {
                return Err(other_error(
                    &stage,
                    format!("binding {} ({}) needs a {:?}", b.binding, b.name, b.ty),
                ));
            }
            chosen.push((b.clone(), *r));
        }
        let layouts = [kernel.set_layout];
        let set = unsafe {
            self.device.raw.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(self.pool)
                    .set_layouts(&layouts),
            )
        }
        .stage(&stage)?[0];
        let buffer_infos: Vec<[vk::DescriptorBufferInfo; 1]> = chosen
            .iter()
            .map(|(_, r)| match r {
                Resource::Buffer(buffer) => [vk::DescriptorBufferInfo::default()
                    .buffer(*buffer)
                    .range(vk::WHOLE_SIZE)],
                Resource::AccelerationStructure(_) => [vk::DescriptorBufferInfo::default()],
            })
            .collect();
        let structures: Vec<[vk::AccelerationStructureKHR; 1]> = chosen
            .iter()
            .map(|(_, r)| match r {
                Resource::AccelerationStructure(a) => [*a],
                Resource::Buffer(_) => [vk::AccelerationStructureKHR::null()],
            })
            .collect();
        let mut as_writes: Vec<vk::WriteDescriptorSetAccelerationStructureKHR> = structures
            .iter()
            .map(|s| {
                vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(s)
            })
            .collect();
        let mut writes = Vec::with_capacity(chosen.len());
        for (i, ((b, r), as_write)) in chosen.iter().zip(as_writes.iter_mut()).enumerate() {
            let write = vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(b.binding)
                .descriptor_type(b.ty);
            let write = match r {
                Resource::Buffer(_) => write.buffer_info(&buffer_infos[i]),
                Resource::AccelerationStructure(_) => {
                    let mut w = write.push_next(as_write);
                    w.descriptor_count = 1;
                    w
                }
            };
            writes.push(write);
        }
        unsafe { self.device.raw.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }
}

impl Drop for Kernels {
    fn drop(&mut self) {
        unsafe {
            for (_, k) in self.kernels.drain() {
                self.device.raw.destroy_pipeline(k.pipeline, None);
                self.device.raw.destroy_pipeline_layout(k.layout, None);
                self.device
                    .raw
                    .destroy_descriptor_set_layout(k.set_layout, None);
            }
            self.device.raw.destroy_descriptor_pool(self.pool, None);
        }
    }
}
