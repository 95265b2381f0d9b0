//! [`VulkanoBackend`]: the plan's objects as Vulkan objects through vulkano, a frame as one
//! command buffer with one memory barrier between dispatches (`raw.rs`).

use std::sync::Arc;

use cloth_core::SimError;
use cloth_gpu::plan::{BindGroupDesc, Binding, BufferDesc, BufferUsage, KernelDesc, PipelineDesc, Shader};
use cloth_gpu::simulator::TIMER_PAIRS;
use cloth_gpu::{DeviceLimits, Frame, GpuBackend, GpuTuning};
use vulkano::buffer::{Buffer, BufferCreateInfo, Subbuffer};
use vulkano::command_buffer::allocator::StandardCommandBufferAllocator;
use vulkano::command_buffer::{
    AutoCommandBufferBuilder, CommandBufferUsage, CopyBufferInfo, DispatchIndirectCommand, PrimaryAutoCommandBuffer,
    PrimaryCommandBufferAbstract,
};
use vulkano::descriptor_set::allocator::StandardDescriptorSetAllocator;
use vulkano::descriptor_set::layout::DescriptorType;
use vulkano::descriptor_set::{DescriptorBufferInfo, DescriptorSet, WriteDescriptorSet};
use vulkano::memory::allocator::{AllocationCreateInfo, MemoryTypeFilter, StandardMemoryAllocator};
use vulkano::pipeline::compute::ComputePipelineCreateInfo;
use vulkano::pipeline::layout::PipelineDescriptorSetLayoutCreateInfo;
use vulkano::pipeline::{ComputePipeline, Pipeline, PipelineBindPoint, PipelineLayout, PipelineShaderStageCreateInfo};
use vulkano::query::{QueryPool, QueryPoolCreateInfo, QueryResultFlags, QueryType};
use vulkano::shader::{ShaderModule, ShaderModuleCreateInfo, SpecializationConstant};
use vulkano::sync::future::FenceSignalFuture;
use vulkano::sync::{GpuFuture, PipelineStage};

use crate::context::VulkanContext;
use crate::raw::{FrameRecorder, RawPrimary};
use crate::{
    BACKEND_NAME, COPY_SPIRV, IMPLICIT_SPIRV, SELF_HASH_SPIRV, STEP_SPIRV, TILED_STEP_SPIRV, VBD_SPIRV, XPBD_SPIRV,
};

/// The cloth simulated by GLSL compute shaders (SPIR-V) through vulkano.
pub type VulkanoSimulator = cloth_gpu::GpuSimulator<VulkanoBackend>;

/// A Vulkan device running the simulation's kernels.
pub struct VulkanoBackend {
    memory: Arc<StandardMemoryAllocator>,
    commands: Arc<StandardCommandBufferAllocator>,
    descriptors: Arc<StandardDescriptorSetAllocator>,
    /// An empty automatic command buffer: the resource usage the frames report (`raw.rs`).
    no_resources: Arc<PrimaryAutoCommandBuffer>,
    /// The uploads of the objects being created, submitted at the end of the set-up.
    setup: Option<AutoCommandBufferBuilder<PrimaryAutoCommandBuffer>>,
    /// The last submission, if not yet waited for.
    in_flight: Option<FenceSignalFuture<Box<dyn GpuFuture>>>,
    /// The timestamp pairs of the submissions and the mask of a timestamp's valid bits, once
    /// timing was asked for and the queue can.
    timer: Option<(Arc<QueryPool>, u64)>,
    /// Whether to print each pipeline's statistics as it is built.
    statistics: bool,
    context: VulkanContext,
}

/// A kernel: its SPIR-V module and the pipeline layout reflected from it.
pub struct VulkanoKernel {
    module: Arc<ShaderModule>,
    layout: Arc<PipelineLayout>,
    bindings: Vec<Binding>,
}

fn device_error(reason: impl std::fmt::Display) -> SimError {
    SimError::Device { backend: BACKEND_NAME, reason: reason.to_string() }
}

impl VulkanoBackend {
    /// The backend on an open device.
    ///
    /// # Errors
    /// [`SimError::Device`] when the command buffer allocator fails.
    pub fn on(context: VulkanContext, statistics: bool) -> Result<Self, SimError> {
        let device = context.device.clone();
        let commands = Arc::new(StandardCommandBufferAllocator::new(device.clone(), Default::default()));
        let no_resources = AutoCommandBufferBuilder::primary(
            commands.clone(),
            context.queue.queue_family_index(),
            CommandBufferUsage::MultipleSubmit,
        )
        .and_then(|b| b.build())
        .map_err(|e| device_error(format!("command buffer: {e}")))?;
        Ok(Self {
            memory: Arc::new(StandardMemoryAllocator::new_default(device.clone())),
            descriptors: Arc::new(StandardDescriptorSetAllocator::new(device, Default::default())),
            commands,
            no_resources,
            setup: None,
            in_flight: None,
            timer: None,
            statistics,
            context,
        })
    }

    /// The device this simulation runs on, in words, and whether validation is on.
    pub fn context(&self) -> &VulkanContext {
        &self.context
    }

    fn builder(&self) -> Result<AutoCommandBufferBuilder<PrimaryAutoCommandBuffer>, SimError> {
        AutoCommandBufferBuilder::primary(
            self.commands.clone(),
            self.context.queue.queue_family_index(),
            CommandBufferUsage::OneTimeSubmit,
        )
        .map_err(|e| device_error(format!("command buffer: {e}")))
    }

    fn buffer(&self, usage: vulkano::buffer::BufferUsage, size: u64, host: bool) -> Result<Subbuffer<[u8]>, SimError> {
        let memory_type_filter = if host {
            MemoryTypeFilter::PREFER_HOST | MemoryTypeFilter::HOST_RANDOM_ACCESS
        } else {
            MemoryTypeFilter::PREFER_DEVICE
        };
        Buffer::new_slice::<u8>(
            self.memory.clone(),
            BufferCreateInfo { usage, ..Default::default() },
            AllocationCreateInfo { memory_type_filter, ..Default::default() },
            size.max(4),
        )
        .map_err(|e| device_error(format!("allocating {size} bytes: {e}")))
    }

    /// Records a copy of `bytes` into `dst` through a host-visible staging buffer.
    fn copy_in(
        &self,
        builder: &mut AutoCommandBufferBuilder<PrimaryAutoCommandBuffer>,
        bytes: &[u8],
        dst: &Subbuffer<[u8]>,
    ) -> Result<(), SimError> {
        if bytes.is_empty() {
            return Ok(());
        }
        let staging = self.buffer(vulkano::buffer::BufferUsage::TRANSFER_SRC, bytes.len() as u64, true)?;
        staging.write().map_err(|e| device_error(format!("writing a staging buffer: {e}")))?[..bytes.len()]
            .copy_from_slice(bytes);
        let src = staging.slice(0..bytes.len() as u64);
        builder
            .copy_buffer(CopyBufferInfo::buffers(src, dst.clone().slice(0..bytes.len() as u64)))
            .map_err(|e| device_error(format!("recording a copy: {e}")))?;
        Ok(())
    }

    /// Records `frame` into one command buffer; with `profile`, a pool of one timestamp more
    /// than the frame has dispatches, a timestamp before the first dispatch and after each.
    fn record(&self, frame: Frame<'_, Self>, profile: Option<&Arc<QueryPool>>) -> Result<Arc<RawPrimary>, SimError> {
        let mut recorder = FrameRecorder::begin(self.commands.clone(), self.context.queue.queue_family_index())
            .map_err(device_error)?;
        let timer = self.timer.as_ref().zip(frame.timestamps).map(|((pool, _), pair)| (pool.clone(), 2 * pair));
        if let Some(pool) = profile {
            // SAFETY: the pool's queries are reset just before, in the same command buffer, and
            // read only after a wait for the device; the pool outlives the wait.
            unsafe {
                recorder
                    .recording
                    .reset_query_pool(pool, 0..frame.dispatches.len() as u32 + 1)
                    .map_err(device_error)?;
                recorder.recording.write_timestamp(pool, 0, PipelineStage::BottomOfPipe).map_err(device_error)?;
            }
        }
        if let Some((pool, first)) = &timer {
            // SAFETY: the pair is reset just before, in the same command buffer, and read only
            // after a wait for the device; the pool lives as long as the backend.
            unsafe {
                recorder.recording.reset_query_pool(pool, *first..first + 2).map_err(device_error)?;
                recorder.recording.write_timestamp(pool, *first, PipelineStage::TopOfPipe).map_err(device_error)?;
            }
        }
        let mut bound = None;
        for (k, d) in frame.dispatches.iter().enumerate() {
            let pipeline = &frame.pipelines[d.pipeline];
            let rec = &mut recorder.recording;
            // SAFETY: the pipelines, descriptor sets and buffers live as long as the simulator,
            // which waits for the device before dropping them; every kernel bounds-checks its
            // invocation index (against the vertex count, a colour's constraint count or the
            // grid), every buffer it indexes holds that many elements (the plan sizes them), and
            // the indices it reads from buffers (springs' ends, candidates, hash links) are
            // below the vertex count (the wgpu backend's shader modules give the whole argument).
            unsafe {
                if bound != Some(d.pipeline) {
                    rec.bind_pipeline_compute(pipeline).map_err(|e| device_error(format!("binding: {e}")))?;
                    bound = Some(d.pipeline);
                }
                let set = frame.bind_groups[d.bind_group].as_raw();
                rec.bind_descriptor_sets(
                    PipelineBindPoint::Compute,
                    pipeline.layout(),
                    0,
                    &[set],
                    d.dynamic_offset.as_slice(),
                )
                .map_err(|e| device_error(format!("binding: {e}")))?;
                match (d.indirect, frame.indirect) {
                    (Some(offset), Some(buffer)) => {
                        let size = size_of::<DispatchIndirectCommand>() as u64;
                        let sizes =
                            buffer.clone().slice(offset..offset + size).reinterpret::<[DispatchIndirectCommand]>();
                        rec.dispatch_indirect(&sizes)
                    }
                    _ => rec.dispatch([d.workgroups[0], d.workgroups[1], 1]),
                }
                .map_err(|e| device_error(format!("dispatch: {e}")))?;
            }
            if let Some(pool) = profile {
                // SAFETY: as the timer's timestamps.
                unsafe { recorder.recording.write_timestamp(pool, k as u32 + 1, PipelineStage::BottomOfPipe) }
                    .map_err(device_error)?;
            }
            let next_is_indirect = frame.dispatches.get(k + 1).is_some_and(|next| next.indirect.is_some());
            recorder.between_dispatches(next_is_indirect).map_err(device_error)?;
        }
        if let Some((pool, first)) = &timer {
            // SAFETY: as above.
            unsafe { recorder.recording.write_timestamp(pool, first + 1, PipelineStage::BottomOfPipe) }
                .map_err(device_error)?;
        }
        recorder.end(self.no_resources.clone()).map_err(device_error)
    }

    /// The mask of a timestamp's valid bits on the queue, `None` where it writes none.
    fn timestamp_mask(&self) -> Option<u64> {
        let (device, queue) = (&self.context.device, &self.context.queue);
        let family = &device.physical_device().queue_family_properties()[queue.queue_family_index() as usize];
        family.timestamp_valid_bits.map(|bits| if bits >= 64 { u64::MAX } else { (1u64 << bits) - 1 })
    }

    /// Submits after the previous submission, without waiting for it.
    fn submit_after<C: PrimaryCommandBufferAbstract + 'static>(&mut self, cb: Arc<C>) -> Result<(), SimError> {
        let previous: Box<dyn GpuFuture> = match self.in_flight.take() {
            Some(mut f) => {
                f.cleanup_finished();
                f.boxed()
            }
            None => vulkano::sync::now(self.context.device.clone()).boxed(),
        };
        let future = (previous.then_execute(self.context.queue.clone(), cb))
            .map_err(|e| device_error(format!("submitting: {e}")))?
            .boxed()
            .then_signal_fence_and_flush()
            .map_err(|e| device_error(format!("submitting: {e}")))?;
        self.in_flight = Some(future);
        self.context.check_validation()
    }
}

impl Drop for VulkanoBackend {
    /// Waits for the last submission: the frames use buffers and pipelines without vulkano
    /// tracking them (`raw.rs`).
    fn drop(&mut self) {
        if let Some(f) = self.in_flight.take() {
            let _ = f.wait(None);
        }
    }
}

impl GpuBackend for VulkanoBackend {
    type Buffer = Subbuffer<[u8]>;
    type Kernel = VulkanoKernel;
    type Pipeline = Arc<ComputePipeline>;
    type BindGroup = Arc<DescriptorSet>;
    const NAME: &'static str = BACKEND_NAME;

    fn open(tuning: &GpuTuning) -> Result<Self, SimError> {
        let context = VulkanContext::new(tuning.adapter.as_deref(), tuning.pipeline_statistics)?;
        Self::on(context, tuning.pipeline_statistics)
    }

    fn adapter_name(&self) -> String {
        let validation = if self.context.validation { ", validation on" } else { "" };
        format!("{}{validation}", self.context.description)
    }

    fn limits(&self) -> DeviceLimits {
        let p = self.context.device.physical_device().properties();
        let [x, y, _] = p.max_compute_work_group_size;
        DeviceLimits {
            max_workgroups_per_dimension: p.max_compute_work_group_count[0].min(p.max_compute_work_group_count[1]),
            max_invocations: p.max_compute_work_group_invocations.min(x * y),
            workgroup_memory: p.max_compute_shared_memory_size,
            max_storage_binding: p.max_storage_buffer_range as u64,
            storage_buffers_per_stage: p.max_per_stage_descriptor_storage_buffers,
            cpu: p.device_type == vulkano::device::physical::PhysicalDeviceType::Cpu,
        }
    }

    fn setup<T>(&mut self, create: impl FnOnce(&mut Self) -> Result<T, SimError>) -> Result<T, SimError> {
        self.setup = Some(self.builder()?);
        let created = create(self);
        let builder = self.setup.take();
        let created = created?;
        if let Some(builder) = builder {
            let cb = builder.build().map_err(|e| device_error(format!("recording the upload: {e}")))?;
            self.submit_after(cb)?;
        }
        Ok(created)
    }

    fn create_buffer(&mut self, desc: &BufferDesc) -> Result<Subbuffer<[u8]>, SimError> {
        use vulkano::buffer::BufferUsage as U;
        let usage = match desc.usage {
            BufferUsage::Uniform => U::UNIFORM_BUFFER | U::TRANSFER_DST,
            BufferUsage::Storage | BufferUsage::StorageDrawable => {
                U::STORAGE_BUFFER | U::TRANSFER_DST | U::TRANSFER_SRC
            }
            BufferUsage::StorageIndirect => U::STORAGE_BUFFER | U::INDIRECT_BUFFER | U::TRANSFER_DST | U::TRANSFER_SRC,
        };
        let buffer = self.buffer(usage, desc.size, false)?;
        let mut builder = match self.setup.take() {
            Some(builder) => builder,
            None => self.builder()?,
        };
        let recorded = match &desc.contents {
            Some(bytes) => self.copy_in(&mut builder, bytes, &buffer),
            None => builder.fill_buffer(buffer.clone().reinterpret(), 0).map(|_| ()).map_err(device_error),
        };
        self.setup = Some(builder);
        recorded.map(|()| buffer)
    }

    fn create_kernel(&mut self, desc: &KernelDesc) -> Result<VulkanoKernel, SimError> {
        let device = &self.context.device;
        let spirv = match desc.shader {
            Shader::Step => STEP_SPIRV,
            Shader::Tiled(_) => TILED_STEP_SPIRV,
            Shader::Xpbd => XPBD_SPIRV,
            Shader::Vbd => VBD_SPIRV,
            Shader::Implicit => IMPLICIT_SPIRV,
            Shader::Copy => COPY_SPIRV,
            Shader::SelfHash => SELF_HASH_SPIRV,
        };
        let words = vulkano::shader::spirv::bytes_to_words(spirv).map_err(device_error)?;
        // SAFETY: the SPIR-V comes from glslc, which emits valid modules for Vulkan 1.1.
        let module = unsafe { ShaderModule::new(device.clone(), ShaderModuleCreateInfo::new(&words)) }
            .map_err(|e| device_error(format!("loading the SPIR-V: {e}")))?;
        let entry = module.entry_point("main").ok_or_else(|| device_error("the SPIR-V has no `main` entry point"))?;
        let mut info = PipelineDescriptorSetLayoutCreateInfo::from_stages([&PipelineShaderStageCreateInfo::new(entry)]);
        // The layout comes from reflection; the plan says which uniforms a dynamic offset selects.
        for (binding, b) in desc.bindings.iter().enumerate() {
            if let (Binding::Uniform { dynamic: true, .. }, Some(set)) = (b, info.set_layouts.first_mut())
                && let Some(reflected) = set.bindings.get_mut(&(binding as u32))
            {
                reflected.descriptor_type = DescriptorType::UniformBufferDynamic;
            }
        }
        let layout_info = (info.into_pipeline_layout_create_info(device.clone()))
            .map_err(|e| device_error(format!("pipeline layout: {e:?}")))?;
        let layout = PipelineLayout::new(device.clone(), layout_info)
            .map_err(|e| device_error(format!("pipeline layout: {e}")))?;
        Ok(VulkanoKernel { module, layout, bindings: desc.bindings.clone() })
    }

    fn create_pipeline(
        &mut self,
        kernel: &VulkanoKernel,
        desc: &PipelineDesc,
    ) -> Result<Arc<ComputePipeline>, SimError> {
        let constants: Vec<(u32, SpecializationConstant)> = (desc.constants.iter())
            .map(|&(c, value)| {
                let constant = if c.is_boolean() {
                    SpecializationConstant::Bool(value != 0)
                } else {
                    SpecializationConstant::U32(value)
                };
                (c.spec_id(), constant)
            })
            .collect();
        let entry = (kernel.module.specialize(constants.iter().cloned().collect()))
            .map_err(|e| device_error(format!("specializing the shader: {e}")))?
            .entry_point("main")
            .ok_or_else(|| device_error("the SPIR-V has no `main` entry point"))?;
        let stage = PipelineShaderStageCreateInfo::new(entry);
        let pipeline = ComputePipeline::new(
            self.context.device.clone(),
            None,
            ComputePipelineCreateInfo::stage_layout(stage, kernel.layout.clone()),
        )
        .map_err(|e| device_error(format!("compute pipeline {}: {e}", desc.label)))?;
        if self.statistics {
            match crate::statistics::of(&self.context.device, &kernel.module, &kernel.layout, &constants) {
                Ok(lines) => eprintln!("pipeline statistics ({}): {}", desc.label, lines.join(", ")),
                Err(e) => eprintln!("pipeline statistics ({}): none: {e}", desc.label),
            }
        }
        Ok(pipeline)
    }

    fn create_bind_group(
        &mut self,
        kernel: &VulkanoKernel,
        _desc: &BindGroupDesc,
        buffers: &[&Subbuffer<[u8]>],
    ) -> Result<Arc<DescriptorSet>, SimError> {
        let writes = (buffers.iter().zip(&kernel.bindings).enumerate()).map(|(binding, (buffer, kind))| {
            match kind.bound_bytes() {
                Some(size) => WriteDescriptorSet::buffer_with_range(
                    binding as u32,
                    DescriptorBufferInfo { buffer: (*buffer).clone(), range: 0..size },
                ),
                None => WriteDescriptorSet::buffer(binding as u32, (*buffer).clone()),
            }
        });
        DescriptorSet::new(self.descriptors.clone(), kernel.layout.set_layouts()[0].clone(), writes, [])
            .map_err(|e| device_error(format!("descriptor set: {e}")))
    }

    fn submit(&mut self, frame: Frame<'_, Self>) -> Result<(), SimError> {
        let cb = self.record(frame, None)?;
        self.submit_after(cb)
    }

    fn submit_profiled(&mut self, frame: Frame<'_, Self>) -> Result<Option<Vec<f64>>, SimError> {
        let Some(mask) = self.timestamp_mask() else { return Ok(None) };
        let count = frame.dispatches.len() as u32 + 1;
        let info = QueryPoolCreateInfo { query_count: count, ..QueryPoolCreateInfo::query_type(QueryType::Timestamp) };
        let pool = QueryPool::new(self.context.device.clone(), info)
            .map_err(|e| device_error(format!("a query pool of {count} timestamps: {e}")))?;
        let cb = self.record(frame, Some(&pool))?;
        self.submit_after(cb)?;
        self.wait()?;
        let mut stamps = vec![0u64; count as usize];
        (pool.get_results(0..count, &mut stamps, QueryResultFlags::WAIT))
            .map_err(|e| device_error(format!("reading the timestamps: {e}")))?;
        let period_s = self.context.device.physical_device().properties().timestamp_period as f64 * 1e-9;
        Ok(Some(stamps.windows(2).map(|t| (t[1].wrapping_sub(t[0]) & mask) as f64 * period_s).collect()))
    }

    fn write(&mut self, buffer: &Subbuffer<[u8]>, bytes: &[u8]) -> Result<(), SimError> {
        let mut builder = self.builder()?;
        self.copy_in(&mut builder, bytes, buffer)?;
        let cb = builder.build().map_err(|e| device_error(format!("recording the upload: {e}")))?;
        self.submit_after(cb)
    }

    fn read(&mut self, sources: &[(&Subbuffer<[u8]>, u64)]) -> Result<Vec<Vec<u8>>, SimError> {
        let total: u64 = sources.iter().map(|(_, size)| size).sum();
        let staging = self.buffer(vulkano::buffer::BufferUsage::TRANSFER_DST, total, true)?;
        let mut builder = self.builder()?;
        let mut offset = 0;
        for &(b, size) in sources {
            let (src, dst) = (b.clone().slice(0..size), staging.clone().slice(offset..offset + size));
            builder
                .copy_buffer(CopyBufferInfo::buffers(src, dst))
                .map_err(|e| device_error(format!("read-back: {e}")))?;
            offset += size;
        }
        let cb = builder.build().map_err(|e| device_error(format!("recording the read-back: {e}")))?;
        self.submit_after(cb)?;
        self.wait()?;
        let bytes = staging.read().map_err(|e| device_error(format!("reading the read-back buffer: {e}")))?;
        Ok(cloth_gpu::simulator::split_read_back(&bytes, sources))
    }

    fn wait(&mut self) -> Result<(), SimError> {
        if let Some(f) = self.in_flight.take() {
            f.wait(None).map_err(|e| device_error(format!("waiting for the device: {e}")))?;
        }
        self.context.check_validation()
    }

    fn create_timer(&mut self) -> bool {
        if self.timer.is_none() {
            let info = QueryPoolCreateInfo {
                query_count: 2 * TIMER_PAIRS,
                ..QueryPoolCreateInfo::query_type(QueryType::Timestamp)
            };
            if let (Some(mask), Ok(pool)) = (self.timestamp_mask(), QueryPool::new(self.context.device.clone(), info)) {
                self.timer = Some((pool, mask));
            }
        }
        self.timer.is_some()
    }

    fn read_timer(&mut self, pairs: u32) -> Result<f64, SimError> {
        let Some((pool, mask)) = self.timer.clone() else { return Ok(0.0) };
        self.wait()?;
        let mut stamps = vec![0u64; 2 * pairs as usize];
        (pool.get_results(0..2 * pairs, &mut stamps, QueryResultFlags::WAIT))
            .map_err(|e| device_error(format!("reading the timestamps: {e}")))?;
        let ticks: u64 = stamps.chunks_exact(2).map(|p| (p[1].wrapping_sub(p[0])) & mask).sum();
        let period_ns = self.context.device.physical_device().properties().timestamp_period as f64;
        Ok(ticks as f64 * period_ns * 1e-9)
    }
}
