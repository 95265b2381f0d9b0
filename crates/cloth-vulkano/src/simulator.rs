//! [`VulkanoSimulator`]: buffers, the specialized substep pipeline, and the `Simulator`
//! implementation.

use std::sync::Arc;

use cloth_core::layout::{GpuBuffers, GpuSimParams, GpuSphere, MemoryEstimate};
use cloth_core::{AdvanceCounts, ClothModel, ClothState, Diagnostics, Scene, SimError, Simulator};
use vulkano::buffer::{Buffer, BufferContents, BufferCreateInfo, BufferUsage, Subbuffer};
use vulkano::command_buffer::allocator::StandardCommandBufferAllocator;
use vulkano::command_buffer::{
    AutoCommandBufferBuilder, CommandBufferUsage, CopyBufferInfo, PrimaryAutoCommandBuffer,
    PrimaryCommandBufferAbstract,
};
use vulkano::descriptor_set::allocator::StandardDescriptorSetAllocator;
use vulkano::memory::allocator::{AllocationCreateInfo, MemoryTypeFilter, StandardMemoryAllocator};
use vulkano::pipeline::{Pipeline, PipelineBindPoint};
use vulkano::sync::future::FenceSignalFuture;
use vulkano::sync::{AccessFlags, GpuFuture, PipelineStages};

use crate::BACKEND_NAME;
use crate::context::VulkanContext;
use crate::passes::{StateBuffers, SubstepPlan};
use crate::raw::FrameRecorder;
use crate::timer::GpuTimer;

/// The cloth simulated by GLSL compute shaders (SPIR-V) through vulkano.
pub struct VulkanoSimulator {
    context: VulkanContext,
    scene: Scene,
    /// The dispatches of one substep (see `passes.rs`); a substep leaves the new state in buffer
    /// `1 - k` when `k` is current.
    plan: SubstepPlan,
    /// An empty automatic command buffer: the resource usage the frames report (`raw.rs`).
    no_resources: Arc<PrimaryAutoCommandBuffer>,
    buffers: StateBuffers,
    /// Allocates the descriptor sets of a tiled pass built later (`set_tiling`).
    descriptors: Arc<StandardDescriptorSetAllocator>,
    memory: Arc<StandardMemoryAllocator>,
    commands: Arc<StandardCommandBufferAllocator>,
    /// The last submission, if not yet waited for.
    in_flight: Option<FenceSignalFuture<Box<dyn GpuFuture>>>,
    /// Parameters to write at the start of the next command buffer.
    pending_parameters: Option<(GpuSimParams, Vec<GpuSphere>)>,
    /// GPU time of each advance, when timing is on (`set_gpu_timing`) and the queue can.
    timer: Option<GpuTimer>,
    /// GPU seconds already read from a full timer and not yet taken.
    timed_seconds: f64,
    current: usize,
    free: Vec<f32>,
    time_s: f64,
    substeps_run: u64,
    last_advance: AdvanceCounts,
}

fn device_error(reason: impl std::fmt::Display) -> SimError {
    SimError::Device { backend: BACKEND_NAME, reason: reason.to_string() }
}

impl VulkanoSimulator {
    /// Creates the simulator on the best device, or the first whose name contains `adapter`.
    ///
    /// # Errors
    /// As [`Simulator::new`].
    pub fn with_adapter(scene: &Scene, adapter: Option<&str>) -> Result<Self, SimError> {
        scene.validate()?;
        let context = VulkanContext::new(adapter)?;
        Self::on_context(scene, context)
    }

    /// Creates the simulator on an open device.
    ///
    /// # Errors
    /// [`SimError::TooLarge`] beyond `maxStorageBufferRange`, [`SimError::Device`] when creating
    /// the GPU objects fails.
    pub fn on_context(scene: &Scene, context: VulkanContext) -> Result<Self, SimError> {
        scene.validate()?;
        cloth_core::layout::checked_workgroup_size(BACKEND_NAME)?;
        // The packed-state knob too, whatever the integrator (only Euler uses it).
        cloth_core::layout::PackedState::checked_enabled(BACKEND_NAME)?;
        let device = context.device.clone();
        let properties = device.physical_device().properties();
        let limit = properties.max_storage_buffer_range as u64;
        let needed = MemoryEstimate::of(scene).largest_buffer_bytes;
        if needed > limit {
            let [nx, ny] = scene.cloth.resolution;
            return Err(SimError::TooLarge {
                nx,
                ny,
                resource: "storage buffer (the device's maxStorageBufferRange)".into(),
                needed_bytes: needed,
                limit_bytes: limit,
                largest_square: cloth_core::layout::largest_square_grid(scene, limit),
            });
        }
        let model = ClothModel::new(scene);
        let data = GpuBuffers::new(&model);
        let memory = Arc::new(StandardMemoryAllocator::new_default(device.clone()));
        let commands = Arc::new(StandardCommandBufferAllocator::new(device.clone(), Default::default()));
        let descriptors = Arc::new(StandardDescriptorSetAllocator::new(device.clone(), Default::default()));

        let storage = BufferUsage::STORAGE_BUFFER | BufferUsage::TRANSFER_DST | BufferUsage::TRANSFER_SRC;
        let device_local = |usage: BufferUsage, bytes: u64| -> Result<Subbuffer<[u8]>, SimError> {
            Buffer::new_slice::<u8>(
                memory.clone(),
                BufferCreateInfo { usage, ..Default::default() },
                AllocationCreateInfo { memory_type_filter: MemoryTypeFilter::PREFER_DEVICE, ..Default::default() },
                bytes.max(4),
            )
            .map_err(|e| device_error(format!("allocating {bytes} bytes of device memory: {e}")))
        };
        let state_bytes = bytes_of_slice(&data.positions);
        let buffers = StateBuffers {
            params: device_local(
                BufferUsage::UNIFORM_BUFFER | BufferUsage::TRANSFER_DST,
                size_of::<GpuSimParams>() as u64,
            )?
            .reinterpret(),
            spheres: device_local(storage, bytes_of_slice(&data.spheres))?.reinterpret(),
            positions: [
                device_local(storage, state_bytes)?.reinterpret(),
                device_local(storage, state_bytes)?.reinterpret(),
            ],
            velocities: [
                device_local(storage, state_bytes)?.reinterpret(),
                device_local(storage, state_bytes)?.reinterpret(),
            ],
            max_penetration: device_local(storage, 4)?.reinterpret(),
        };
        let plan = crate::passes::plan(&device, scene, &data, &buffers, &descriptors, &device_local)?;
        let mut sim = Self {
            free: data.positions.iter().map(|p| p[3]).collect(),
            scene: scene.clone(),
            plan,
            no_resources: AutoCommandBufferBuilder::primary(
                commands.clone(),
                context.queue.queue_family_index(),
                CommandBufferUsage::MultipleSubmit,
            )
            .and_then(|b| b.build())
            .map_err(|e| device_error(format!("command buffer: {e}")))?,
            buffers,
            descriptors,
            memory,
            commands,
            in_flight: None,
            pending_parameters: None,
            timer: None,
            timed_seconds: 0.0,
            current: 0,
            time_s: 0.0,
            substeps_run: 0,
            last_advance: AdvanceCounts::default(),
            context,
        };
        // Initial upload: one command buffer of copies from host-visible staging buffers.
        let mut builder = sim.builder()?;
        sim.copy_in(&mut builder, &[data.params], sim.buffers.params.clone().into_bytes())?;
        sim.copy_in(&mut builder, &data.spheres, sim.buffers.spheres.clone().into_bytes())?;
        for k in 0..2 {
            sim.copy_in(&mut builder, &data.positions, sim.buffers.positions[k].clone().into_bytes())?;
            sim.copy_in(&mut builder, &data.velocities, sim.buffers.velocities[k].clone().into_bytes())?;
        }
        sim.copy_in(&mut builder, &[0u32], sim.buffers.max_penetration.clone().into_bytes())?;
        for (buffer, bytes) in std::mem::take(&mut sim.plan.uploads) {
            sim.copy_in(&mut builder, &bytes, buffer)?;
        }
        let cb = builder.build().map_err(|e| device_error(format!("recording the upload: {e}")))?;
        sim.submit(cb)?;
        sim.context.check_validation()?;
        Ok(sim)
    }

    /// The device this simulation runs on, in words, and whether validation is on.
    pub fn context(&self) -> &VulkanContext {
        &self.context
    }

    /// Records `substeps` substeps (with pending parameter writes and the timer's timestamps)
    /// into one command buffer, with one memory barrier between dispatches (`raw.rs`), and
    /// submits it without waiting.
    fn record_and_submit(&mut self, substeps: u64) -> Result<(), SimError> {
        if self.timer.as_ref().is_some_and(GpuTimer::is_full) {
            // Only after 256 advances without `take_gpu_seconds`: keep the measurements.
            self.read_timer()?;
            self.last_advance.host_waits += 1;
        }
        let mut frame = FrameRecorder::begin(self.commands.clone(), self.context.queue.queue_family_index())
            .map_err(device_error)?;
        let rec = &mut frame.recording;
        if let Some((params, spheres)) = self.pending_parameters.take() {
            // SAFETY: the buffers live as long as the simulator, which waits for the device
            // before dropping them.
            unsafe {
                rec.update_buffer(&self.buffers.params, &params)
                    .map_err(|e| device_error(format!("parameters: {e}")))?;
                if !spheres.is_empty() {
                    let dst = self.buffers.spheres.clone().slice(0..spheres.len() as u64);
                    rec.update_buffer(&dst, spheres.as_slice()).map_err(|e| device_error(format!("spheres: {e}")))?;
                }
            }
            frame
                .barrier(
                    PipelineStages::ALL_TRANSFER,
                    AccessFlags::TRANSFER_WRITE,
                    PipelineStages::COMPUTE_SHADER,
                    AccessFlags::UNIFORM_READ | AccessFlags::SHADER_READ,
                )
                .map_err(device_error)?;
        }
        if let Some(timer) = &self.timer {
            timer.begin(&mut frame.recording).map_err(device_error)?;
        }
        let mut bound = None;
        let mut left = substeps;
        // Semi-implicit Euler without the tiled kernel: the substeps on the packed state, from
        // the vec4 state `current` to `1 - current` (passes.rs, PackedPasses).
        if let Some(packed) = self.plan.active_packed()
            && substeps >= 2
        {
            let k = self.current;
            let mut dispatch = |pipeline: &Arc<vulkano::pipeline::ComputePipeline>,
                                set: &Arc<vulkano::descriptor_set::DescriptorSet>|
             -> Result<(), SimError> {
                let rec = &mut frame.recording;
                // SAFETY: as below; the packed buffers hold a vertex count's elements (and the
                // time after them), the pin bits a word per 32 vertices.
                unsafe {
                    rec.bind_pipeline_compute(pipeline).map_err(|e| device_error(format!("binding: {e}")))?;
                    rec.bind_descriptor_sets(PipelineBindPoint::Compute, pipeline.layout(), 0, &[set.as_raw()], &[])
                        .map_err(|e| device_error(format!("binding: {e}")))?;
                    rec.dispatch(packed.workgroups).map_err(|e| device_error(format!("dispatch: {e}")))?;
                }
                frame.between_dispatches().map_err(device_error)
            };
            // Substep s takes the blocks backward when s is odd (the same pipeline both ways
            // unless the order alternates).
            dispatch(&packed.first_pipeline, &packed.first[k])?;
            let mut m = 0;
            for s in 1..substeps - 1 {
                dispatch(&packed.middle_pipelines[(s % 2) as usize], &packed.middle[m])?;
                m = 1 - m;
            }
            dispatch(&packed.last_pipelines[((substeps - 1) % 2) as usize], &packed.last[k][m])?;
            self.current = 1 - k;
            left = 0;
        }
        while left > 0 {
            // Several substeps in one tiled dispatch where they fit, the rest one at a time.
            if let Some(tiled) = &self.plan.tiled
                && left >= tiled.substeps as u64
            {
                let rec = &mut frame.recording;
                // SAFETY: as below; the tiled kernel bounds-checks every cell against the grid.
                unsafe {
                    rec.bind_pipeline_compute(&tiled.pipeline).map_err(|e| device_error(format!("binding: {e}")))?;
                    rec.bind_descriptor_sets(
                        PipelineBindPoint::Compute,
                        tiled.pipeline.layout(),
                        0,
                        &[tiled.sets[self.current].as_raw()],
                        &[],
                    )
                    .map_err(|e| device_error(format!("binding: {e}")))?;
                    rec.dispatch(tiled.workgroups).map_err(|e| device_error(format!("dispatch: {e}")))?;
                }
                bound = None;
                frame.between_dispatches().map_err(device_error)?;
                self.current = 1 - self.current;
                left -= tiled.substeps as u64;
                continue;
            }
            left -= 1;
            for pass in &self.plan.passes {
                let pipeline = &self.plan.pipelines[pass.pipeline];
                let rec = &mut frame.recording;
                // SAFETY: the pipelines and descriptor sets live as long as the simulator, which
                // waits for the device before dropping them; every kernel bounds-checks its
                // invocation index (against the vertex count, or the colour's constraint count),
                // and every buffer it indexes holds that many elements.
                unsafe {
                    if bound != Some(pass.pipeline) {
                        rec.bind_pipeline_compute(pipeline).map_err(|e| device_error(format!("binding: {e}")))?;
                        bound = Some(pass.pipeline);
                    }
                    let offsets: &[u32] = match &pass.dynamic_offset {
                        Some(offset) => std::slice::from_ref(offset),
                        None => &[],
                    };
                    rec.bind_descriptor_sets(
                        PipelineBindPoint::Compute,
                        pipeline.layout(),
                        0,
                        &[pass.sets[self.current].as_raw()],
                        offsets,
                    )
                    .map_err(|e| device_error(format!("binding: {e}")))?;
                    rec.dispatch(pass.workgroups).map_err(|e| device_error(format!("dispatch: {e}")))?;
                }
                frame.between_dispatches().map_err(device_error)?;
            }
            self.current = 1 - self.current;
        }
        if let Some(timer) = &mut self.timer {
            timer.end(&mut frame.recording).map_err(device_error)?;
        }
        let cb = frame.end(self.no_resources.clone()).map_err(device_error)?;
        self.submit(cb)
    }

    fn builder(&self) -> Result<AutoCommandBufferBuilder<PrimaryAutoCommandBuffer>, SimError> {
        AutoCommandBufferBuilder::primary(
            self.commands.clone(),
            self.context.queue.queue_family_index(),
            CommandBufferUsage::OneTimeSubmit,
        )
        .map_err(|e| device_error(format!("command buffer: {e}")))
    }

    /// Records a copy of `data` into `dst` through a host-visible staging buffer.
    fn copy_in<T: BufferContents + Copy>(
        &self,
        builder: &mut AutoCommandBufferBuilder<PrimaryAutoCommandBuffer>,
        data: &[T],
        dst: Subbuffer<[u8]>,
    ) -> Result<(), SimError> {
        if data.is_empty() {
            return Ok(());
        }
        let staging = Buffer::from_iter(
            self.memory.clone(),
            BufferCreateInfo { usage: BufferUsage::TRANSFER_SRC, ..Default::default() },
            AllocationCreateInfo {
                memory_type_filter: MemoryTypeFilter::PREFER_HOST | MemoryTypeFilter::HOST_SEQUENTIAL_WRITE,
                ..Default::default()
            },
            data.iter().copied(),
        )
        .map_err(|e| device_error(format!("allocating a staging buffer: {e}")))?;
        builder
            .copy_buffer(CopyBufferInfo::buffers(staging, dst))
            .map_err(|e| device_error(format!("recording a copy: {e}")))?;
        Ok(())
    }

    /// Submits after the previous submission (without waiting for it).
    fn submit<C: PrimaryCommandBufferAbstract + 'static>(&mut self, cb: Arc<C>) -> Result<(), SimError> {
        let previous: Box<dyn GpuFuture> = match self.in_flight.take() {
            Some(mut f) => {
                f.cleanup_finished();
                f.boxed()
            }
            None => vulkano::sync::now(self.context.device.clone()).boxed(),
        };
        let future = previous
            .then_execute(self.context.queue.clone(), cb)
            .map_err(|e| device_error(format!("submitting: {e}")))?
            .boxed()
            .then_signal_fence_and_flush()
            .map_err(|e| device_error(format!("submitting: {e}")))?;
        self.in_flight = Some(future);
        Ok(())
    }

    /// Waits for every submission so far: the one host wait a read-back needs.
    fn wait(&mut self) -> Result<(), SimError> {
        if let Some(f) = self.in_flight.take() {
            f.wait(None).map_err(|e| device_error(format!("waiting for the device: {e}")))?;
        }
        self.context.check_validation()
    }

    /// Copies buffers into one host-visible buffer, waits once, returns their bytes.
    fn read_back(&mut self, sources: &[Subbuffer<[u8]>]) -> Result<Vec<Vec<u8>>, SimError> {
        let total: u64 = sources.iter().map(|b| b.size()).sum();
        let staging = Buffer::new_slice::<u8>(
            self.memory.clone(),
            BufferCreateInfo { usage: BufferUsage::TRANSFER_DST, ..Default::default() },
            AllocationCreateInfo {
                memory_type_filter: MemoryTypeFilter::PREFER_HOST | MemoryTypeFilter::HOST_RANDOM_ACCESS,
                ..Default::default()
            },
            total,
        )
        .map_err(|e| device_error(format!("allocating the read-back buffer: {e}")))?;
        let mut builder = self.builder()?;
        let mut offset = 0;
        for b in sources {
            builder
                .copy_buffer(CopyBufferInfo::buffers(b.clone(), staging.clone().slice(offset..offset + b.size())))
                .map_err(|e| device_error(format!("recording the read-back: {e}")))?;
            offset += b.size();
        }
        let cb = builder.build().map_err(|e| device_error(format!("recording the read-back: {e}")))?;
        self.submit(cb)?;
        self.wait()?;
        let bytes = staging.read().map_err(|e| device_error(format!("reading the read-back buffer: {e}")))?;
        let mut out = Vec::with_capacity(sources.len());
        let mut offset = 0usize;
        for b in sources {
            out.push(bytes[offset..offset + b.size() as usize].to_vec());
            offset += b.size() as usize;
        }
        Ok(out)
    }
}

impl Drop for VulkanoSimulator {
    /// Waits for the last submission first: the frames' command buffers use the pipelines,
    /// descriptor sets and buffers without vulkano tracking them (`raw.rs`), so they must outlive
    /// the device's work.
    fn drop(&mut self) {
        if let Some(f) = self.in_flight.take() {
            let _ = f.wait(None);
        }
    }
}

impl VulkanoSimulator {
    /// Waits for the device and adds the timer's pending pairs to `timed_seconds`.
    fn read_timer(&mut self) -> Result<(), SimError> {
        if self.timer.is_none() {
            return Ok(());
        }
        self.wait()?;
        if let Some(timer) = &mut self.timer {
            self.timed_seconds += timer.take().map_err(device_error)?;
        }
        Ok(())
    }
}

fn bytes_of_slice<T>(data: &[T]) -> u64 {
    std::mem::size_of_val(data) as u64
}

impl Simulator for VulkanoSimulator {
    fn new(scene: &Scene) -> Result<Self, SimError> {
        let adapter = std::env::var("CLOTH_ADAPTER").ok().filter(|s| !s.is_empty());
        Self::with_adapter(scene, adapter.as_deref())
    }

    fn backend_name(&self) -> &'static str {
        BACKEND_NAME
    }

    fn adapter_name(&self) -> String {
        let validation = if self.context.validation { ", validation on" } else { "" };
        format!("{}{validation}", self.context.description)
    }

    fn scene(&self) -> &Scene {
        &self.scene
    }

    fn fused_substeps(&self) -> u32 {
        self.plan.tiled.as_ref().map_or(1, |tiled| tiled.substeps)
    }

    fn substep_state_bytes(&self) -> Option<u32> {
        Some(self.plan.state_bytes())
    }

    fn set_tiling(&mut self, tiling: cloth_core::tiling::Tiling) -> Result<u32, SimError> {
        // The recorded frames hold no references to the pipelines (raw.rs): none may be in
        // flight when the old tiled pass is dropped.
        self.wait()?;
        let device = self.context.device.clone();
        self.plan.tiled = crate::passes::tiled_pass(&device, &self.scene, &self.buffers, &self.descriptors, tiling)?;
        Ok(self.fused_substeps())
    }

    fn advance(&mut self, frames: u32) -> Result<(), SimError> {
        self.last_advance = AdvanceCounts { frames, submissions: 0, host_waits: 0 };
        let per_frame = self.scene.substeps_per_frame() as u64;
        if per_frame == 0 || frames == 0 {
            return Ok(());
        }
        self.record_and_submit(per_frame * frames as u64)?;
        self.last_advance.submissions = 1;
        let dt = self.scene.substep_dt();
        let substeps = per_frame * frames as u64;
        for _ in 0..substeps {
            self.time_s += dt;
        }
        self.substeps_run += substeps;
        self.context.check_validation()
    }

    fn update_parameters(&mut self, scene: &Scene) -> Result<(), SimError> {
        if let Some(what) = self.scene.rebuild_reason(scene) {
            return Err(SimError::RebuildRequired { what });
        }
        scene.validate()?;
        let spheres = if scene.effects.contains(cloth_core::Effect::SphereContact) {
            scene.spheres.iter().map(GpuSphere::from_spec).collect()
        } else {
            Vec::new()
        };
        self.pending_parameters = Some((GpuSimParams::from_scene(scene), spheres));
        self.scene = scene.clone();
        Ok(())
    }

    fn read_state(&mut self) -> Result<ClothState, SimError> {
        let sources = [
            self.buffers.positions[self.current].clone().into_bytes(),
            self.buffers.velocities[self.current].clone().into_bytes(),
        ];
        let bytes = self.read_back(&sources)?;
        let xyz = |b: &[u8]| bytemuck::cast_slice::<u8, [f32; 4]>(b).iter().map(|q| [q[0], q[1], q[2]]).collect();
        Ok(ClothState { time_s: self.time_s, positions: xyz(&bytes[0]), velocities: xyz(&bytes[1]) })
    }

    fn write_state(&mut self, state: &ClothState) -> Result<(), SimError> {
        cloth_core::simulator::check_state_size(self.free.len(), state)?;
        let positions: Vec<[f32; 4]> =
            state.positions.iter().zip(&self.free).map(|(p, &w)| [p[0], p[1], p[2], w]).collect();
        // w: the state's time, which moving pins, moving spheres and gusts read on the GPU.
        let time = state.time_s as f32;
        let velocities: Vec<[f32; 4]> = state.velocities.iter().map(|v| [v[0], v[1], v[2], time]).collect();
        let mut builder = self.builder()?;
        self.copy_in(&mut builder, &positions, self.buffers.positions[self.current].clone().into_bytes())?;
        self.copy_in(&mut builder, &velocities, self.buffers.velocities[self.current].clone().into_bytes())?;
        let cb = builder.build().map_err(|e| device_error(format!("recording the upload: {e}")))?;
        self.submit(cb)?;
        self.time_s = state.time_s;
        Ok(())
    }

    fn diagnostics(&mut self) -> Result<Diagnostics, SimError> {
        let bytes = self.read_back(&[self.buffers.max_penetration.clone().into_bytes()])?;
        let bits = u32::from_le_bytes([bytes[0][0], bytes[0][1], bytes[0][2], bytes[0][3]]);
        Ok(Diagnostics { max_penetration_m: f32::from_bits(bits) as f64, substeps_run: self.substeps_run })
    }

    fn last_advance_counts(&self) -> AdvanceCounts {
        self.last_advance
    }

    fn set_gpu_timing(&mut self, on: bool) -> bool {
        if !on {
            self.timer = None;
        } else if self.timer.is_none() {
            self.timer = GpuTimer::new(&self.context.queue);
        }
        self.timer.is_some()
    }

    fn take_gpu_seconds(&mut self) -> Result<Option<f64>, SimError> {
        if self.timer.is_none() {
            return Ok(None);
        }
        self.read_timer()?;
        Ok(Some(std::mem::take(&mut self.timed_seconds)))
    }
}
