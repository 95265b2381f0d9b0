//! [`WgpuBackend`]: the plan's objects as wgpu objects, a frame as one compute pass.

use std::sync::{Arc, Mutex};

use cloth_core::SimError;
use cloth_gpu::plan::{BindGroupDesc, Binding, BufferDesc, BufferUsage, KernelDesc, PipelineDesc, Shader};
use cloth_gpu::simulator::TIMER_PAIRS;
use cloth_gpu::{DeviceLimits, Frame, GpuBackend, GpuTuning};
use wgpu::util::DeviceExt;

use crate::context::GpuContext;
use crate::{
    BACKEND_NAME, COPY_SHADER, IMPLICIT_SHADER, SELF_HASH_SHADER, STEP_SHADER, VBD_SHADER, XPBD_SHADER,
    tiled_shader_source,
};

/// The cloth simulated by WGSL compute shaders through wgpu.
pub type WgpuSimulator = cloth_gpu::GpuSimulator<WgpuBackend>;

/// A wgpu device running the simulation's kernels.
pub struct WgpuBackend {
    context: GpuContext,
    /// Timestamp pairs of the submissions, and the buffer they are resolved into (one every
    /// `QUERY_RESOLVE_BUFFER_ALIGNMENT` bytes), once timing was asked for and the device can.
    timer: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    /// Why the device was lost, once it is.
    lost: Arc<Mutex<Option<String>>>,
}

/// A kernel: its module and the layout its pipelines and bind groups share.
pub struct WgpuKernel {
    module: wgpu::ShaderModule,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    bindings: Vec<Binding>,
    entry_point: &'static str,
}

fn device_error(reason: impl std::fmt::Display) -> SimError {
    SimError::Device { backend: BACKEND_NAME, reason: reason.to_string() }
}

impl WgpuBackend {
    /// The backend on an open device (e.g. eframe's, so a renderer draws the simulation's
    /// buffers without a copy).
    pub fn on(context: GpuContext) -> Self {
        let lost = Arc::new(Mutex::new(None));
        let slot = lost.clone();
        context.device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut s) = slot.lock() {
                *s = Some(format!("device lost ({reason:?}): {message}"));
            }
        });
        Self { context, timer: None, lost }
    }

    /// The device and queue the simulation runs on.
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    fn check_device(&self) -> Result<(), SimError> {
        match self.lost.lock().ok().and_then(|s| s.clone()) {
            Some(reason) => Err(device_error(reason)),
            None => Ok(()),
        }
    }

    /// Encodes `frame` in one compute pass; with `profile` (query sets of
    /// `QUERY_SET_MAX_QUERIES` timestamps each), a timestamp before the first dispatch and after
    /// each, numbered on across the sets.
    fn encode(&self, frame: &Frame<'_, Self>, profile: &[wgpu::QuerySet]) -> wgpu::CommandEncoder {
        let mut encoder =
            self.context.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("cloth frames") });
        {
            let timestamp_writes = match (&self.timer, frame.timestamps) {
                (Some((query_set, _)), Some(pair)) => Some(wgpu::ComputePassTimestampWrites {
                    query_set,
                    beginning_of_pass_write_index: Some(2 * pair),
                    end_of_pass_write_index: Some(2 * pair + 1),
                }),
                _ => None,
            };
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("cloth substeps"), timestamp_writes });
            let mut bound = None;
            let stamp = |pass: &mut wgpu::ComputePass, at: u32| {
                if !profile.is_empty() {
                    let max = wgpu::QUERY_SET_MAX_QUERIES;
                    pass.write_timestamp(&profile[(at / max) as usize], at % max);
                }
            };
            stamp(&mut pass, 0);
            for (k, d) in frame.dispatches.iter().enumerate() {
                if bound != Some(d.pipeline) {
                    pass.set_pipeline(&frame.pipelines[d.pipeline]);
                    bound = Some(d.pipeline);
                }
                let offsets = d.dynamic_offset.as_slice();
                pass.set_bind_group(0, &frame.bind_groups[d.bind_group], offsets);
                match (d.indirect, frame.indirect) {
                    (Some(offset), Some(buffer)) => pass.dispatch_workgroups_indirect(buffer, offset),
                    _ => pass.dispatch_workgroups(d.workgroups[0], d.workgroups[1], 1),
                }
                stamp(&mut pass, k as u32 + 1);
            }
        }
        if let (Some((queries, resolved)), Some(pair)) = (&self.timer, frame.timestamps) {
            let offset = pair as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
            encoder.resolve_query_set(queries, 2 * pair..2 * pair + 2, resolved, offset);
        }
        encoder
    }
}

impl GpuBackend for WgpuBackend {
    type Buffer = wgpu::Buffer;
    type Kernel = WgpuKernel;
    type Pipeline = wgpu::ComputePipeline;
    type BindGroup = wgpu::BindGroup;
    const NAME: &'static str = BACKEND_NAME;

    fn open(tuning: &GpuTuning) -> Result<Self, SimError> {
        if tuning.pipeline_statistics {
            return Err(SimError::Unsupported {
                backend: BACKEND_NAME,
                what: "pipeline statistics (GpuTuning::pipeline_statistics)".into(),
                fix: "use the vulkano backend, which reads them from the Vulkan driver".into(),
            });
        }
        Ok(Self::on(GpuContext::new(tuning.adapter.as_deref())?))
    }

    fn adapter_name(&self) -> String {
        self.context.adapter_description.clone()
    }

    fn limits(&self) -> DeviceLimits {
        let l = self.context.device.limits();
        DeviceLimits {
            max_workgroups_per_dimension: l.max_compute_workgroups_per_dimension,
            max_invocations: l
                .max_compute_invocations_per_workgroup
                .min(l.max_compute_workgroup_size_x * l.max_compute_workgroup_size_y),
            workgroup_memory: l.max_compute_workgroup_storage_size,
            max_storage_binding: l.max_storage_buffer_binding_size.min(l.max_buffer_size),
            storage_buffers_per_stage: l.max_storage_buffers_per_shader_stage,
            cpu: self.context.device_type == wgpu::DeviceType::Cpu,
        }
    }

    fn setup<T>(&mut self, create: impl FnOnce(&mut Self) -> Result<T, SimError>) -> Result<T, SimError> {
        let validation = self.context.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory = self.context.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let created = create(self);
        if let Some(e) = pollster::block_on(memory.pop()) {
            return Err(device_error(format!("out of device memory while creating the buffers: {e}")));
        }
        if let Some(e) = pollster::block_on(validation.pop()) {
            return Err(device_error(format!("creating the GPU objects failed: {e}")));
        }
        created
    }

    fn create_buffer(&mut self, desc: &BufferDesc) -> Result<wgpu::Buffer, SimError> {
        use wgpu::BufferUsages as U;
        let storage = U::STORAGE | U::COPY_DST | U::COPY_SRC;
        let usage = match desc.usage {
            BufferUsage::Uniform => U::UNIFORM | U::COPY_DST,
            BufferUsage::Storage => storage,
            BufferUsage::StorageDrawable => storage | U::VERTEX,
            BufferUsage::StorageIndirect => storage | U::INDIRECT,
        };
        let device = &self.context.device;
        Ok(match &desc.contents {
            Some(contents) => device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(&desc.label),
                contents,
                usage,
            }),
            None => device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&desc.label),
                size: desc.size,
                usage,
                mapped_at_creation: false,
            }),
        })
    }

    fn create_kernel(&mut self, desc: &KernelDesc) -> Result<WgpuKernel, SimError> {
        let device = &self.context.device;
        let (name, entry_point, source) = match desc.shader {
            Shader::Step => ("cloth_step.wgsl", "substep", STEP_SHADER.to_string()),
            Shader::Tiled(tile) => ("cloth_step_tiled.wgsl", "substeps", tiled_shader_source(&tile)),
            Shader::Xpbd => ("xpbd.wgsl", "xpbd", XPBD_SHADER.to_string()),
            Shader::Vbd => ("vbd.wgsl", "vbd", VBD_SHADER.to_string()),
            Shader::Implicit => ("implicit.wgsl", "implicit", IMPLICIT_SHADER.to_string()),
            Shader::Copy => ("copy.wgsl", "copy", COPY_SHADER.to_string()),
            Shader::SelfHash => ("self_hash.wgsl", "build", SELF_HASH_SHADER.to_string()),
        };
        let descriptor =
            wgpu::ShaderModuleDescriptor { label: Some(name), source: wgpu::ShaderSource::Wgsl(source.into()) };
        // SAFETY: the kernels run without wgpu's index clamping and loop bounding (1.6-2.7% of a
        // large GPU's frame), as the vulkano backend runs its SPIR-V. Every index they form is in
        // bounds given what the plan guarantees: `vertex_count = nx · ny` is the length of every
        // per-vertex buffer, and a vertex index comes from grid coordinates checked against `nx`,
        // `ny` (or is an offset of at most two rows and columns from a vertex two or more from
        // every edge); `collider_count` is at most the colliders' block's `MAX_COLLIDERS`
        // (validation refuses more, and a change of count rebuilds the simulator), and a mesh's
        // field cell is clamped into its grid; XPBD's and VBD's constraints have their ends below
        // the vertex count, and their colour ranges lie inside their buffers; RK4's stages run
        // only with the full scratch bound; the tiled kernel reads only tile cells it wrote;
        // self-collision's buckets are masked to the table's power-of-two size, and every vertex
        // index its lists and links hold is one the rebuild wrote, below the vertex count (the
        // simulation's first substep rebuilds them); the copy kernel's loop stops at its
        // buffer's length. Every loop is bounded: over the colliders, the colour ranges, the
        // fused substeps, a list's at most `LIST_CAPACITY` candidates, the copy's elements; the
        // walk of a bucket's list ends because a rebuild pushes every vertex once, on fresh
        // heads, so no list has a cycle.
        let module = unsafe { device.create_shader_module_trusted(descriptor, wgpu::ShaderRuntimeChecks::unchecked()) };
        let entries: Vec<wgpu::BindGroupLayoutEntry> = (desc.bindings.iter().enumerate())
            .map(|(binding, b)| wgpu::BindGroupLayoutEntry {
                binding: binding as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: match *b {
                    Binding::Uniform { size, dynamic } => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: dynamic,
                        min_binding_size: wgpu::BufferSize::new(size),
                    },
                    Binding::Storage { read_only } => wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                },
                count: None,
            })
            .collect();
        let label = format!("{name} bind group layout");
        let layout = device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(&label), entries: &entries });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Ok(WgpuKernel { module, layout, pipeline_layout, bindings: desc.bindings.clone(), entry_point })
    }

    fn create_pipeline(&mut self, kernel: &WgpuKernel, desc: &PipelineDesc) -> Result<wgpu::ComputePipeline, SimError> {
        // The tile's sizes are written into the tiled kernel's source (they size its workgroup
        // arrays); the rest are overrides.
        let constants: Vec<(&str, f64)> = (desc.constants.iter())
            .filter(|(c, _)| !c.is_wgsl_module_constant())
            .map(|&(c, value)| (c.name(), value as f64))
            .collect();
        Ok(self.context.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(&desc.label),
            layout: Some(&kernel.pipeline_layout),
            module: &kernel.module,
            entry_point: Some(kernel.entry_point),
            // Every kernel reads only workgroup memory it has written.
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants,
                zero_initialize_workgroup_memory: false,
            },
            cache: None,
        }))
    }

    fn create_bind_group(
        &mut self,
        kernel: &WgpuKernel,
        desc: &BindGroupDesc,
        buffers: &[&wgpu::Buffer],
    ) -> Result<wgpu::BindGroup, SimError> {
        let entries: Vec<wgpu::BindGroupEntry> = (buffers.iter().zip(&kernel.bindings).enumerate())
            .map(|(binding, (buffer, kind))| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset: 0,
                    size: kind.bound_bytes().and_then(wgpu::BufferSize::new),
                }),
            })
            .collect();
        Ok(self.context.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(&desc.label),
            layout: &kernel.layout,
            entries: &entries,
        }))
    }

    fn submit(&mut self, frame: Frame<'_, Self>) -> Result<(), SimError> {
        self.check_device()?;
        let encoder = self.encode(&frame, &[]);
        self.context.queue.submit([encoder.finish()]);
        // Frees finished work without waiting for the GPU.
        let _ = self.context.device.poll(wgpu::PollType::Poll);
        Ok(())
    }

    fn submit_profiled(&mut self, frame: Frame<'_, Self>) -> Result<Option<Vec<f64>>, SimError> {
        let needed = wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES;
        if !self.context.device.features().contains(needed) {
            return Ok(None);
        }
        self.check_device()?;
        let device = &self.context.device;
        // A query set holds at most QUERY_SET_MAX_QUERIES timestamps: a frame of more dispatches
        // (an XPBD frame) takes several.
        let count = frame.dispatches.len() as u32 + 1;
        let sets: Vec<wgpu::QuerySet> = (0..count.div_ceil(wgpu::QUERY_SET_MAX_QUERIES))
            .map(|_| {
                device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some("cloth profile timestamps"),
                    ty: wgpu::QueryType::Timestamp,
                    count: wgpu::QUERY_SET_MAX_QUERIES,
                })
            })
            .collect();
        let resolved = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cloth resolved profile timestamps"),
            size: sets.len() as u64 * wgpu::QUERY_SET_MAX_QUERIES as u64 * wgpu::QUERY_SIZE as u64,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut encoder = self.encode(&frame, &sets);
        for (k, set) in sets.iter().enumerate() {
            let queries = count.saturating_sub(k as u32 * wgpu::QUERY_SET_MAX_QUERIES).min(wgpu::QUERY_SET_MAX_QUERIES);
            let offset = k as u64 * wgpu::QUERY_SET_MAX_QUERIES as u64 * wgpu::QUERY_SIZE as u64;
            encoder.resolve_query_set(set, 0..queries, &resolved, offset);
        }
        self.context.queue.submit([encoder.finish()]);
        let bytes = self.read(&[(&resolved, count as u64 * wgpu::QUERY_SIZE as u64)])?.remove(0);
        let stamps: Vec<u64> = bytemuck::pod_collect_to_vec(&bytes);
        let period_s = self.context.queue.get_timestamp_period() as f64 * 1e-9;
        Ok(Some(stamps.windows(2).map(|t| t[1].saturating_sub(t[0]) as f64 * period_s).collect()))
    }

    fn write(&mut self, buffer: &wgpu::Buffer, bytes: &[u8]) -> Result<(), SimError> {
        self.context.queue.write_buffer(buffer, 0, bytes);
        Ok(())
    }

    fn read(&mut self, sources: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, SimError> {
        let device = &self.context.device;
        let total: u64 = sources.iter().map(|(_, size)| size).sum::<u64>().max(4);
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("cloth read-back staging"),
            size: total,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("cloth read-back") });
        let mut offset = 0;
        for &(b, size) in sources {
            encoder.copy_buffer_to_buffer(b, 0, &staging, offset, size);
            offset += size;
        }
        self.context.queue.submit([encoder.finish()]);
        let (tx, rx) = std::sync::mpsc::channel();
        staging.map_async(wgpu::MapMode::Read, .., move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| device_error(format!("waiting for the GPU: {e}")))?;
        rx.recv()
            .map_err(|_| device_error("the read-back never completed"))?
            .map_err(|e| device_error(format!("mapping the read-back buffer: {e}")))?;
        let view =
            staging.get_mapped_range(..).map_err(|e| device_error(format!("reading the mapped buffer: {e:?}")))?;
        let out = cloth_gpu::simulator::split_read_back(&view, sources);
        drop(view);
        staging.unmap();
        self.check_device()?;
        Ok(out)
    }

    fn wait(&mut self) -> Result<(), SimError> {
        let waited = self.context.device.poll(wgpu::PollType::wait_indefinitely());
        waited.map(|_| ()).map_err(|e| device_error(format!("waiting for the GPU: {e}")))
    }

    fn create_timer(&mut self) -> bool {
        let device = &self.context.device;
        if self.timer.is_none() && device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("cloth advance timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * TIMER_PAIRS,
            });
            let resolved = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("cloth resolved timestamps"),
                size: TIMER_PAIRS as u64 * wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            self.timer = Some((queries, resolved));
        }
        self.timer.is_some()
    }

    fn read_timer(&mut self, pairs: u32) -> Result<f64, SimError> {
        let Some((_, resolved)) = self.timer.clone() else { return Ok(0.0) };
        let stride = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
        let bytes = self.read(&[(&resolved, pairs as u64 * stride)])?.remove(0);
        let ticks: u64 = (bytes.chunks(stride as usize).map(|c| bytemuck::pod_read_unaligned::<[u64; 2]>(&c[..16])))
            .map(|[begin, end]| end.saturating_sub(begin))
            .sum();
        Ok(ticks as f64 * self.context.queue.get_timestamp_period() as f64 * 1e-9)
    }
}
