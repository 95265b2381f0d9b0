//! [`WgpuSimulator`]: buffers, the substep pipeline, and the `Simulator` implementation.

use std::sync::{Arc, Mutex};

use cloth_core::layout::{GpuBuffers, GpuSimParams, GpuSphere, MemoryEstimate};
use cloth_core::{AdvanceCounts, ClothModel, ClothState, Diagnostics, Scene, SimError, Simulator};
use wgpu::util::DeviceExt;

use crate::BACKEND_NAME;
use crate::context::{AdapterChoice, GpuContext};
use crate::passes::{StateBuffers, SubstepPlan};
use crate::timer::GpuTimer;

/// The cloth simulated by WGSL compute shaders through wgpu.
pub struct WgpuSimulator {
    context: GpuContext,
    scene: Scene,
    /// The dispatches of one substep (see `passes.rs`); a substep leaves the new state in buffer
    /// `1 - k` when `k` is current.
    plan: SubstepPlan,
    buffers: StateBuffers,
    /// Which of the two state buffers holds the current state.
    current: usize,
    /// `w` of each vertex's position: 1 free, 0 pinned (kept to rebuild positions in `write_state`).
    free: Vec<f32>,
    /// GPU time of each advance, when timing is on (`set_gpu_timing`) and the device can.
    timer: Option<GpuTimer>,
    /// GPU seconds already read from a full timer and not yet taken.
    timed_seconds: f64,
    time_s: f64,
    substeps_run: u64,
    last_advance: AdvanceCounts,
    device_error: Arc<Mutex<Option<String>>>,
}

fn device_error(reason: impl Into<String>) -> SimError {
    SimError::Device { backend: BACKEND_NAME, reason: reason.into() }
}

impl WgpuSimulator {
    /// Creates the simulator on its own device, on the adapter `choice` picks.
    ///
    /// # Errors
    /// As [`Simulator::new`].
    pub fn with_options(scene: &Scene, choice: &AdapterChoice) -> Result<Self, SimError> {
        scene.validate()?;
        let context = GpuContext::new(choice)?;
        Self::on_device(scene, context)
    }

    /// Creates the simulator on an existing device (e.g. eframe's, to draw from
    /// [`WgpuSimulator::position_buffer`] without a read-back).
    ///
    /// # Errors
    /// [`SimError::Scene`] for an invalid scene, [`SimError::TooLarge`] when a buffer exceeds the
    /// device's limits, [`SimError::Unsupported`] when the device lacks what a kernel needs,
    /// [`SimError::Device`] when creating the GPU objects fails.
    pub fn on_device(scene: &Scene, context: GpuContext) -> Result<Self, SimError> {
        scene.validate()?;
        check_limits(scene, &context.device.limits())?;
        cloth_core::layout::checked_workgroup_size(BACKEND_NAME)?;
        // The packed-state knob too, whatever the integrator (only Euler uses it).
        cloth_core::layout::PackedState::checked_enabled(BACKEND_NAME)?;
        let model = ClothModel::new(scene);
        let data = GpuBuffers::new(&model);
        let device = &context.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let oom_scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);

        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
        let init = |label: &str, contents: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage })
        };
        let buffers = StateBuffers {
            params: init(
                "cloth params",
                bytemuck::bytes_of(&data.params),
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
            spheres: init("cloth spheres", bytemuck::cast_slice(&data.spheres), storage),
            positions: [
                init("cloth positions A", bytemuck::cast_slice(&data.positions), storage | wgpu::BufferUsages::VERTEX),
                init("cloth positions B", bytemuck::cast_slice(&data.positions), storage | wgpu::BufferUsages::VERTEX),
            ],
            velocities: [
                init("cloth velocities A", bytemuck::cast_slice(&data.velocities), storage),
                init("cloth velocities B", bytemuck::cast_slice(&data.velocities), storage),
            ],
            max_penetration: init("cloth max penetration", &[0u8; 4], storage),
        };
        let plan = crate::passes::plan(device, scene, &data, &buffers, context.device_type == wgpu::DeviceType::Cpu);
        if let Some(e) = pollster::block_on(oom_scope.pop()) {
            return Err(device_error(format!("out of device memory while creating the buffers: {e}")));
        }
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(device_error(format!("creating the GPU objects failed: {e}")));
        }
        let plan = plan?;

        let device_error_slot = Arc::new(Mutex::new(None));
        let slot = device_error_slot.clone();
        device.set_device_lost_callback(move |reason, message| {
            if let Ok(mut s) = slot.lock() {
                *s = Some(format!("device lost ({reason:?}): {message}"));
            }
        });
        Ok(Self {
            free: data.positions.iter().map(|p| p[3]).collect(),
            scene: scene.clone(),
            plan,
            buffers,
            current: 0,
            timer: None,
            timed_seconds: 0.0,
            time_s: 0.0,
            substeps_run: 0,
            last_advance: AdvanceCounts::default(),
            device_error: device_error_slot,
            context,
        })
    }

    /// The buffer holding the current positions (`vec4<f32>` per vertex, xyz in m), valid until
    /// the next `advance`. Usable as a vertex buffer on the same device.
    pub fn position_buffer(&self) -> &wgpu::Buffer {
        &self.buffers.positions[self.current]
    }

    /// The buffer holding the current velocities (`vec4<f32>` per vertex, xyz in m/s), valid until
    /// the next `advance`.
    pub fn velocity_buffer(&self) -> &wgpu::Buffer {
        &self.buffers.velocities[self.current]
    }

    /// The device and queue the simulation runs on.
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    fn check_device(&self) -> Result<(), SimError> {
        match self.device_error.lock().ok().and_then(|s| s.clone()) {
            Some(reason) => Err(device_error(reason)),
            None => Ok(()),
        }
    }

    /// Copies the first `size` bytes of each buffer into one staging buffer, waits once, and
    /// returns the bytes.
    fn read_back(&mut self, sources: &[(&wgpu::Buffer, u64)]) -> Result<Vec<Vec<u8>>, SimError> {
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
            if size > 0 {
                encoder.copy_buffer_to_buffer(b, 0, &staging, offset, size);
            }
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
        let mut out = Vec::with_capacity(sources.len());
        let mut offset = 0usize;
        for &(_, size) in sources {
            out.push(view[offset..offset + size as usize].to_vec());
            offset += size as usize;
        }
        drop(view);
        staging.unmap();
        self.check_device()?;
        Ok(out)
    }

    /// Reads the timer's pending timestamp pairs (one host wait) and adds them to
    /// `timed_seconds`.
    fn read_timer(&mut self) -> Result<(), SimError> {
        let Some(timer) = &self.timer else { return Ok(()) };
        let (resolved, size) = (timer.resolved.clone(), timer.pending_bytes());
        if size == 0 {
            return Ok(());
        }
        let bytes = self.read_back(&[(&resolved, size)])?;
        if let Some(timer) = &mut self.timer {
            self.timed_seconds += timer.take(&bytes[0]);
        }
        Ok(())
    }
}

/// Refuses a scene whose largest buffer exceeds the device's limits, naming the grid, the bytes
/// and the limit. Uses the closed-form estimate, so nothing is built for a scene that cannot fit.
fn check_limits(scene: &Scene, limits: &wgpu::Limits) -> Result<(), SimError> {
    let [nx, ny] = scene.cloth.resolution;
    let binding_limit = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
    let needed = MemoryEstimate::of(scene).largest_buffer_bytes;
    if needed > binding_limit {
        return Err(SimError::TooLarge {
            nx,
            ny,
            resource: "storage buffer (the device's max_storage_buffer_binding_size)".into(),
            needed_bytes: needed,
            limit_bytes: binding_limit,
            largest_square: cloth_core::layout::largest_square_grid(scene, binding_limit),
        });
    }
    Ok(())
}

impl Simulator for WgpuSimulator {
    fn new(scene: &Scene) -> Result<Self, SimError> {
        Self::with_options(scene, &AdapterChoice::from_env())
    }

    fn backend_name(&self) -> &'static str {
        BACKEND_NAME
    }

    fn adapter_name(&self) -> String {
        self.context.adapter_description.clone()
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
        let cpu = self.context.device_type == wgpu::DeviceType::Cpu;
        let device = &self.context.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let tiled = crate::passes::tiled_pass(device, &self.scene, &self.buffers, tiling, cpu);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(device_error(format!("creating the tiled pipeline failed: {e}")));
        }
        self.plan.tiled = tiled?;
        Ok(self.fused_substeps())
    }

    fn advance(&mut self, frames: u32) -> Result<(), SimError> {
        self.check_device()?;
        self.last_advance = AdvanceCounts { frames, submissions: 0, host_waits: 0 };
        let substeps = self.scene.substeps_per_frame() as u64 * frames as u64;
        if substeps == 0 {
            return Ok(());
        }
        if self.timer.as_ref().is_some_and(GpuTimer::is_full) {
            // Only after 256 advances without `take_gpu_seconds`: keep the measurements.
            self.read_timer()?;
            self.last_advance.host_waits = 1;
        }
        let device = &self.context.device;
        let mut encoder =
            device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("cloth frames") });
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("cloth substeps"),
                timestamp_writes: self.timer.as_ref().map(GpuTimer::pass_writes),
            });
            let mut bound = None;
            let mut left = substeps;
            // Semi-implicit Euler without the tiled kernel: the substeps on the packed state,
            // from the vec4 state `current` to `1 - current` (passes.rs, PackedPasses).
            if let Some(packed) = self.plan.active_packed()
                && substeps >= 2
            {
                let k = self.current;
                let (x, y) = packed.workgroups;
                pass.set_pipeline(&packed.first_pipeline);
                pass.set_bind_group(0, &packed.first[k], &[]);
                pass.dispatch_workgroups(x, y, 1);
                // Substep s takes the blocks backward when s is odd (the same pipeline both ways
                // unless the order alternates: then set once).
                let alternate = packed.middle_pipelines[0] != packed.middle_pipelines[1];
                if !alternate {
                    pass.set_pipeline(&packed.middle_pipelines[0]);
                }
                let mut m = 0;
                for s in 1..substeps - 1 {
                    if alternate {
                        pass.set_pipeline(&packed.middle_pipelines[(s % 2) as usize]);
                    }
                    pass.set_bind_group(0, &packed.middle[m], &[]);
                    pass.dispatch_workgroups(x, y, 1);
                    m = 1 - m;
                }
                pass.set_pipeline(&packed.last_pipelines[((substeps - 1) % 2) as usize]);
                pass.set_bind_group(0, &packed.last[k][m], &[]);
                pass.dispatch_workgroups(x, y, 1);
                self.current = 1 - k;
                left = 0;
            }
            while left > 0 {
                // Several substeps in one tiled dispatch where they fit, the rest one at a time.
                if let Some(tiled) = &self.plan.tiled
                    && left >= tiled.substeps as u64
                {
                    pass.set_pipeline(&tiled.pipeline);
                    bound = None;
                    pass.set_bind_group(0, &tiled.groups[self.current], &[]);
                    pass.dispatch_workgroups(tiled.workgroups.0, tiled.workgroups.1, 1);
                    self.current = 1 - self.current;
                    left -= tiled.substeps as u64;
                    continue;
                }
                left -= 1;
                for step in &self.plan.passes {
                    if bound != Some(step.pipeline) {
                        pass.set_pipeline(&self.plan.pipelines[step.pipeline]);
                        bound = Some(step.pipeline);
                    }
                    match step.dynamic_offset {
                        Some(offset) => pass.set_bind_group(0, &step.groups[self.current], &[offset]),
                        None => pass.set_bind_group(0, &step.groups[self.current], &[]),
                    }
                    pass.dispatch_workgroups(step.workgroups.0, step.workgroups.1, 1);
                }
                self.current = 1 - self.current;
            }
        }
        if let Some(timer) = &mut self.timer {
            timer.resolve(&mut encoder);
        }
        self.context.queue.submit([encoder.finish()]);
        self.last_advance.submissions = 1;
        // Frees finished work without waiting for the GPU.
        let _ = self.context.device.poll(wgpu::PollType::Poll);
        let dt = self.scene.substep_dt();
        for _ in 0..substeps {
            self.time_s += dt;
        }
        self.substeps_run += substeps;
        Ok(())
    }

    fn update_parameters(&mut self, scene: &Scene) -> Result<(), SimError> {
        if let Some(what) = self.scene.rebuild_reason(scene) {
            return Err(SimError::RebuildRequired { what });
        }
        scene.validate()?;
        let queue = &self.context.queue;
        queue.write_buffer(&self.buffers.params, 0, bytemuck::bytes_of(&GpuSimParams::from_scene(scene)));
        if scene.effects.contains(cloth_core::Effect::SphereContact) && !scene.spheres.is_empty() {
            let spheres: Vec<GpuSphere> = scene.spheres.iter().map(GpuSphere::from_spec).collect();
            queue.write_buffer(&self.buffers.spheres, 0, bytemuck::cast_slice(&spheres));
        }
        self.scene = scene.clone();
        Ok(())
    }

    fn read_state(&mut self) -> Result<ClothState, SimError> {
        let (p, v) = (self.buffers.positions[self.current].clone(), self.buffers.velocities[self.current].clone());
        let bytes = self.read_back(&[(&p, p.size()), (&v, v.size())])?;
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
        let queue = &self.context.queue;
        queue.write_buffer(&self.buffers.positions[self.current], 0, bytemuck::cast_slice(&positions));
        queue.write_buffer(&self.buffers.velocities[self.current], 0, bytemuck::cast_slice(&velocities));
        self.time_s = state.time_s;
        Ok(())
    }

    fn diagnostics(&mut self) -> Result<Diagnostics, SimError> {
        let buffer = self.buffers.max_penetration.clone();
        let bytes = self.read_back(&[(&buffer, 4)])?;
        let max_penetration = f32::from_bits(u32::from_le_bytes([bytes[0][0], bytes[0][1], bytes[0][2], bytes[0][3]]));
        Ok(Diagnostics { max_penetration_m: max_penetration as f64, substeps_run: self.substeps_run })
    }

    fn last_advance_counts(&self) -> AdvanceCounts {
        self.last_advance
    }

    fn set_gpu_timing(&mut self, on: bool) -> bool {
        if !on {
            self.timer = None;
        } else if self.timer.is_none() {
            self.timer = GpuTimer::new(&self.context.device, &self.context.queue);
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_beyond_the_binding_limit_is_refused_with_the_numbers() {
        let mut scene = Scene::default();
        // The largest buffer of a force-based scene is a position buffer, 16 bytes a vertex.
        scene.cloth.resolution = [4096, 4096];
        let limits = wgpu::Limits::default(); // 128 MiB bindings
        let err = check_limits(&scene, &limits).unwrap_err().to_string();
        assert!(err.contains("grid 4096x4096 needs 268435456 bytes"), "{err}");
        assert!(err.contains("the device allows 134217728"), "{err}");
        assert!(err.contains("use a smaller grid"), "{err}");
        assert!(err.contains("the largest square one that fits is 2896x2896"), "{err}");
        scene.cloth.resolution = [2048, 2048];
        assert!(check_limits(&scene, &limits).is_ok());
    }
}
