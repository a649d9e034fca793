//! A minimal Vulkan compute context (ash): one device, one queue, host-visible storage
//! buffers, one dispatch at a time. Enough to run the test kernels on lavapipe or a GPU.
//!
//! This is a test harness, so `unsafe` (every Vulkan call) is allowed here; the workspace's
//! `forbid(unsafe_code)` applies to the library crates.

use std::ffi::{CStr, CString};
use std::time::{Duration, Instant};

use ash::vk;

/// Number of storage-buffer bindings every pipeline's descriptor set has (0..BINDINGS).
pub const BINDINGS: usize = 13;

/// Result of one dispatch.
pub struct Dispatch {
    /// Contents of the output binding after the dispatch.
    pub output: Vec<f32>,
    /// Pipeline creation (shader compilation by the driver).
    pub compile: Duration,
    /// First dispatch, submit to fence.
    pub first: Duration,
    /// Second, identical dispatch (warm).
    pub second: Duration,
}

pub struct Context {
    _entry: ash::Entry,
    instance: ash::Instance,
    device: ash::Device,
    queue: vk::Queue,
    pool: vk::CommandPool,
    mem_props: vk::PhysicalDeviceMemoryProperties,
    pub device_name: String,
    shader: vk::ShaderModule,
}

struct Buffer {
    buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    size: u64,
}

impl Context {
    /// Opens the first device with a compute queue (preferring a CPU device such as lavapipe
    /// when `prefer_cpu`), and loads the SPIR-V module `spv`.
    pub fn new(spv: &[u8], prefer_cpu: bool) -> Result<Self, String> {
        unsafe {
            let entry = ash::Entry::load().map_err(|e| format!("loading libvulkan: {e}"))?;
            let app = CString::new("neusample-gpu-runner").unwrap();
            let app_info = vk::ApplicationInfo::default()
                .application_name(&app)
                .api_version(vk::make_api_version(0, 1, 2, 0));
            let instance = entry
                .create_instance(
                    &vk::InstanceCreateInfo::default().application_info(&app_info),
                    None,
                )
                .map_err(|e| format!("vkCreateInstance: {e:?}"))?;
            let devices = instance
                .enumerate_physical_devices()
                .map_err(|e| format!("vkEnumeratePhysicalDevices: {e:?}"))?;
            let mut chosen: Option<(vk::PhysicalDevice, u32, bool, vk::PhysicalDeviceProperties)> =
                None;
            for &pd in &devices {
                let props = instance.get_physical_device_properties(pd);
                let qf = instance.get_physical_device_queue_family_properties(pd);
                let Some(family) = qf
                    .iter()
                    .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
                else {
                    continue;
                };
                let is_cpu = props.device_type == vk::PhysicalDeviceType::CPU;
                let better = match chosen {
                    None => true,
                    Some((_, _, was_cpu, _)) => prefer_cpu && is_cpu && !was_cpu,
                };
                if better {
                    chosen = Some((pd, family as u32, is_cpu, props));
                }
            }
            let (pd, family, _, props) =
                chosen.ok_or_else(|| "no Vulkan device with a compute queue".to_string())?;
            let device_name = CStr::from_ptr(props.device_name.as_ptr())
                .to_string_lossy()
                .into_owned();
            let prio = [1.0f32];
            let qci = [vk::DeviceQueueCreateInfo::default()
                .queue_family_index(family)
                .queue_priorities(&prio)];
            let device = instance
                .create_device(
                    pd,
                    &vk::DeviceCreateInfo::default().queue_create_infos(&qci),
                    None,
                )
                .map_err(|e| format!("vkCreateDevice: {e:?}"))?;
            let queue = device.get_device_queue(family, 0);
            let pool = device
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .map_err(|e| format!("vkCreateCommandPool: {e:?}"))?;
            let mem_props = instance.get_physical_device_memory_properties(pd);
            if !spv.len().is_multiple_of(4) {
                return Err("SPIR-V module length is not a multiple of 4".into());
            }
            let words: Vec<u32> = spv
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            let shader = device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
                .map_err(|e| format!("vkCreateShaderModule: {e:?}"))?;
            Ok(Context {
                _entry: entry,
                instance,
                device,
                queue,
                pool,
                mem_props,
                device_name,
                shader,
            })
        }
    }

    fn create_buffer(&self, data: &[f32]) -> Result<Buffer, String> {
        // Zero-sized buffers are invalid: pad to 16 bytes.
        let size = (std::mem::size_of_val(data) as u64).max(16);
        unsafe {
            let buffer = self
                .device
                .create_buffer(
                    &vk::BufferCreateInfo::default()
                        .size(size)
                        .usage(vk::BufferUsageFlags::STORAGE_BUFFER)
                        .sharing_mode(vk::SharingMode::EXCLUSIVE),
                    None,
                )
                .map_err(|e| format!("vkCreateBuffer: {e:?}"))?;
            let req = self.device.get_buffer_memory_requirements(buffer);
            let want =
                vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
            let type_index = (0..self.mem_props.memory_type_count)
                .find(|&i| {
                    req.memory_type_bits & (1 << i) != 0
                        && self.mem_props.memory_types[i as usize]
                            .property_flags
                            .contains(want)
                })
                .ok_or_else(|| "no host-visible coherent memory type".to_string())?;
            let memory = self
                .device
                .allocate_memory(
                    &vk::MemoryAllocateInfo::default()
                        .allocation_size(req.size)
                        .memory_type_index(type_index),
                    None,
                )
                .map_err(|e| format!("vkAllocateMemory: {e:?}"))?;
            self.device
                .bind_buffer_memory(buffer, memory, 0)
                .map_err(|e| format!("vkBindBufferMemory: {e:?}"))?;
            let ptr = self
                .device
                .map_memory(memory, 0, size, vk::MemoryMapFlags::empty())
                .map_err(|e| format!("vkMapMemory: {e:?}"))? as *mut u8;
            std::ptr::write_bytes(ptr, 0, size as usize);
            std::ptr::copy_nonoverlapping(
                data.as_ptr() as *const u8,
                ptr,
                std::mem::size_of_val(data),
            );
            self.device.unmap_memory(memory);
            Ok(Buffer {
                buffer,
                memory,
                size,
            })
        }
    }

    fn read_buffer(&self, b: &Buffer, len: usize) -> Result<Vec<f32>, String> {
        let mut out = vec![0.0f32; len];
        unsafe {
            let ptr = self
                .device
                .map_memory(b.memory, 0, b.size, vk::MemoryMapFlags::empty())
                .map_err(|e| format!("vkMapMemory: {e:?}"))? as *const u8;
            std::ptr::copy_nonoverlapping(ptr, out.as_mut_ptr() as *mut u8, len * 4);
            self.device.unmap_memory(b.memory);
        }
        Ok(out)
    }

    fn destroy_buffer(&self, b: Buffer) {
        unsafe {
            self.device.destroy_buffer(b.buffer, None);
            self.device.free_memory(b.memory, None);
        }
    }

    /// Runs entry point `entry` over `groups` workgroups with `buffers[i]` bound at binding
    /// `i` (missing bindings get a dummy buffer) and `push` as push constants. Returns the
    /// contents of binding `output` (`output_len` floats) and timings.
    pub fn dispatch(
        &self,
        entry: &str,
        buffers: &[&[f32]],
        output: usize,
        output_len: usize,
        push: &[u8],
        groups: u32,
    ) -> Result<Dispatch, String> {
        assert!(buffers.len() <= BINDINGS && output < buffers.len());
        let dummy = [0.0f32; 4];
        let mut bufs = Vec::with_capacity(BINDINGS);
        for i in 0..BINDINGS {
            let data: &[f32] = if i < buffers.len() {
                buffers[i]
            } else {
                &dummy
            };
            bufs.push(self.create_buffer(data)?);
        }
        let d = &self.device;
        let result = unsafe {
            let bindings: Vec<_> = (0..BINDINGS as u32)
                .map(|i| {
                    vk::DescriptorSetLayoutBinding::default()
                        .binding(i)
                        .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                        .descriptor_count(1)
                        .stage_flags(vk::ShaderStageFlags::COMPUTE)
                })
                .collect();
            let dsl = d
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                    None,
                )
                .map_err(|e| format!("vkCreateDescriptorSetLayout: {e:?}"))?;
            let pcr = [vk::PushConstantRange::default()
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
                .offset(0)
                .size(push.len() as u32)];
            let dsls = [dsl];
            let layout = d
                .create_pipeline_layout(
                    &vk::PipelineLayoutCreateInfo::default()
                        .set_layouts(&dsls)
                        .push_constant_ranges(&pcr),
                    None,
                )
                .map_err(|e| format!("vkCreatePipelineLayout: {e:?}"))?;
            let name = CString::new(entry).unwrap();
            let t = Instant::now();
            let stage = vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::COMPUTE)
                .module(self.shader)
                .name(&name);
            let pipeline = d
                .create_compute_pipelines(
                    vk::PipelineCache::null(),
                    &[vk::ComputePipelineCreateInfo::default()
                        .stage(stage)
                        .layout(layout)],
                    None,
                )
                .map_err(|(_, e)| format!("vkCreateComputePipelines({entry}): {e:?}"))?[0];
            let compile = t.elapsed();
            let sizes = [vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(BINDINGS as u32)];
            let dpool = d
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(1)
                        .pool_sizes(&sizes),
                    None,
                )
                .map_err(|e| format!("vkCreateDescriptorPool: {e:?}"))?;
            let set = d
                .allocate_descriptor_sets(
                    &vk::DescriptorSetAllocateInfo::default()
                        .descriptor_pool(dpool)
                        .set_layouts(&dsls),
                )
                .map_err(|e| format!("vkAllocateDescriptorSets: {e:?}"))?[0];
            let infos: Vec<[vk::DescriptorBufferInfo; 1]> = bufs
                .iter()
                .map(|b| {
                    [vk::DescriptorBufferInfo::default()
                        .buffer(b.buffer)
                        .offset(0)
                        .range(vk::WHOLE_SIZE)]
                })
                .collect();
            let writes: Vec<_> = infos
                .iter()
                .enumerate()
                .map(|(i, info)| {
                    vk::WriteDescriptorSet::default()
                        .dst_set(set)
                        .dst_binding(i as u32)
                        .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                        .buffer_info(info)
                })
                .collect();
            d.update_descriptor_sets(&writes, &[]);

            let cb = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(self.pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .map_err(|e| format!("vkAllocateCommandBuffers: {e:?}"))?[0];
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(|e| format!("vkCreateFence: {e:?}"))?;
            let mut times = [Duration::ZERO; 2];
            for time in &mut times {
                d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                    .map_err(|e| format!("vkResetCommandBuffer: {e:?}"))?;
                d.begin_command_buffer(
                    cb,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(|e| format!("vkBeginCommandBuffer: {e:?}"))?;
                d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::COMPUTE, pipeline);
                d.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::COMPUTE,
                    layout,
                    0,
                    &[set],
                    &[],
                );
                d.cmd_push_constants(cb, layout, vk::ShaderStageFlags::COMPUTE, 0, push);
                d.cmd_dispatch(cb, groups, 1, 1);
                let barrier = [vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                    .dst_access_mask(vk::AccessFlags::HOST_READ)];
                d.cmd_pipeline_barrier(
                    cb,
                    vk::PipelineStageFlags::COMPUTE_SHADER,
                    vk::PipelineStageFlags::HOST,
                    vk::DependencyFlags::empty(),
                    &barrier,
                    &[],
                    &[],
                );
                d.end_command_buffer(cb)
                    .map_err(|e| format!("vkEndCommandBuffer: {e:?}"))?;
                let cbs = [cb];
                let t = Instant::now();
                d.queue_submit(
                    self.queue,
                    &[vk::SubmitInfo::default().command_buffers(&cbs)],
                    fence,
                )
                .map_err(|e| format!("vkQueueSubmit: {e:?}"))?;
                d.wait_for_fences(&[fence], true, u64::MAX)
                    .map_err(|e| format!("vkWaitForFences: {e:?}"))?;
                *time = t.elapsed();
                d.reset_fences(&[fence])
                    .map_err(|e| format!("vkResetFences: {e:?}"))?;
            }
            let out = self.read_buffer(&bufs[output], output_len);
            d.destroy_fence(fence, None);
            d.free_command_buffers(self.pool, &[cb]);
            d.destroy_descriptor_pool(dpool, None);
            d.destroy_pipeline(pipeline, None);
            d.destroy_pipeline_layout(layout, None);
            d.destroy_descriptor_set_layout(dsl, None);
            out.map(|output| Dispatch {
                output,
                compile,
                first: times[0],
                second: times[1],
            })
        };
        for b in bufs {
            self.destroy_buffer(b);
        }
        result
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_shader_module(self.shader, None);
            self.device.destroy_command_pool(self.pool, None);
            self.device.destroy_device(None);
            self.instance.destroy_instance(None);
        }
    }
}
