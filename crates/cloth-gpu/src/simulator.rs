//! [`GpuSimulator`]: the [`Simulator`] of every GPU backend, written once over [`GpuBackend`],
//! the few calls in which the backends differ (creating objects, recording a frame, copying
//! bytes in and out).

use cloth_core::self_collision::CandidateListStats;
use cloth_core::{AdvanceCounts, ClothState, Diagnostics, PassTime, Scene, SimError, Simulator};

use crate::geometry::DeviceLimits;
use crate::layout::{GpuCollider, GpuSelfControl, GpuSimParams};
use crate::plan::{BindGroupDesc, BufferDesc, KernelDesc, PipelineDesc, Plan, StateBuffers};
use crate::schedule::{Dispatch, Schedule};
use crate::tuning::GpuTuning;

/// Timestamp pairs a timer holds before they must be read: one per advance.
pub const TIMER_PAIRS: u32 = 256;

/// A frame to record: its dispatches, in order, and the objects they name.
pub struct Frame<'a, B: GpuBackend> {
    /// The timer's pair to write before and after the dispatches, while timing is on.
    pub timestamps: Option<u32>,
    /// The dispatches ([`Schedule::frame_from`]).
    pub dispatches: &'a [Dispatch],
    /// The pipelines, by [`crate::plan::PipelineId`].
    pub pipelines: &'a [B::Pipeline],
    /// The bind groups, by [`crate::plan::BindGroupId`].
    pub bind_groups: &'a [B::BindGroup],
    /// The buffer indirect dispatches read their sizes from ([`StateBuffers::indirect`]).
    pub indirect: Option<&'a B::Buffer>,
}

/// What a GPU API provides the simulator: objects made from the plan's descriptions, one
/// submission a frame, and copies in and out. Every fallible call returns
/// [`SimError::Device`] when the device fails (and `open` [`SimError::Unavailable`] when there
/// is no such device).
pub trait GpuBackend: Sized {
    /// A device buffer.
    type Buffer: Clone;
    /// A shader module with its binding layout.
    type Kernel;
    /// A compute pipeline.
    type Pipeline;
    /// A bind group (descriptor set).
    type BindGroup;
    /// Backend name used by the tools.
    const NAME: &'static str;

    /// Opens a device on the adapter `tuning.adapter` names (the best one without).
    fn open(tuning: &GpuTuning) -> Result<Self, SimError>;
    /// The device, in words.
    fn adapter_name(&self) -> String;
    /// What the device allows.
    fn limits(&self) -> DeviceLimits;
    /// Runs `create`, which creates a simulation's objects, then uploads what they hold and
    /// reports any creation call that failed without saying so.
    fn setup<T>(&mut self, create: impl FnOnce(&mut Self) -> Result<T, SimError>) -> Result<T, SimError>;
    /// Creates a buffer with the description's contents.
    fn create_buffer(&mut self, desc: &BufferDesc) -> Result<Self::Buffer, SimError>;
    /// Creates a kernel.
    fn create_kernel(&mut self, desc: &KernelDesc) -> Result<Self::Kernel, SimError>;
    /// Creates a pipeline of a kernel.
    fn create_pipeline(&mut self, kernel: &Self::Kernel, desc: &PipelineDesc) -> Result<Self::Pipeline, SimError>;
    /// Creates a bind group of a kernel with `buffers`, one a binding.
    fn create_bind_group(
        &mut self,
        kernel: &Self::Kernel,
        desc: &BindGroupDesc,
        buffers: &[&Self::Buffer],
    ) -> Result<Self::BindGroup, SimError>;
    /// Records the frame into one command buffer (with a memory barrier between dispatches, and
    /// the timer's timestamps when timing is on) and submits it without waiting.
    fn submit(&mut self, frame: Frame<'_, Self>) -> Result<(), SimError>;
    /// Records the frame as [`GpuBackend::submit`] does (the frame's `timestamps` are `None`), with
    /// a timestamp before the first dispatch and after each, submits it and waits: the seconds
    /// from each timestamp to the next, one a dispatch. `None`, recording nothing, where the device
    /// cannot write timestamps between dispatches.
    fn submit_profiled(&mut self, frame: Frame<'_, Self>) -> Result<Option<Vec<f64>>, SimError>;
    /// Writes `bytes` at the start of `buffer`, before the next submission runs.
    fn write(&mut self, buffer: &Self::Buffer, bytes: &[u8]) -> Result<(), SimError>;
    /// Reads the first `bytes` of each buffer, after everything submitted, with one host wait.
    fn read(&mut self, sources: &[(&Self::Buffer, u64)]) -> Result<Vec<Vec<u8>>, SimError>;
    /// Waits for everything submitted: the objects a submission uses may be dropped after.
    fn wait(&mut self) -> Result<(), SimError>;
    /// Creates a timer of [`TIMER_PAIRS`] timestamp pairs, where the device has timestamps.
    fn create_timer(&mut self) -> bool;
    /// The seconds the timer's pairs `0..pairs` span together, after everything submitted (one
    /// host wait).
    fn read_timer(&mut self, pairs: u32) -> Result<f64, SimError>;
}

/// The passes of a profiled frame: the seconds of each dispatch (as
/// [`GpuBackend::submit_profiled`] returns them) summed by pipeline name (`names`, by
/// [`crate::plan::PipelineId`]), in the order the passes first run.
pub fn passes_of(dispatches: &[Dispatch], seconds: &[f64], names: &[String]) -> Vec<PassTime> {
    let mut passes: Vec<PassTime> = Vec::new();
    for (d, &t) in dispatches.iter().zip(seconds) {
        PassTime::of_dispatch(&names[d.pipeline], t).add_to(&mut passes);
    }
    passes
}

/// Splits one read-back, the first bytes of each buffer of `sources` one after another (as a
/// backend copies them into one staging buffer for [`GpuBackend::read`]), into a vector a source.
pub fn split_read_back<T>(bytes: &[u8], sources: &[(T, u64)]) -> Vec<Vec<u8>> {
    let mut offset = 0usize;
    (sources.iter())
        .map(|&(_, size)| {
            offset += size as usize;
            bytes[offset - size as usize..offset].to_vec()
        })
        .collect()
}

/// A cloth simulated on a GPU through backend `B`.
pub struct GpuSimulator<B: GpuBackend> {
    scene: Scene,
    buffers: Vec<B::Buffer>,
    /// Bytes of each buffer.
    sizes: Vec<u64>,
    pipelines: Vec<B::Pipeline>,
    /// What each pipeline does, in words (a profile's rows).
    pipeline_names: Vec<String>,
    bind_groups: Vec<B::BindGroup>,
    schedule: Schedule,
    state: StateBuffers,
    /// The last frame's dispatches (kept, so a frame allocates nothing).
    dispatches: Vec<Dispatch>,
    /// Which of the two state buffers holds the current state.
    current: usize,
    /// `w` of each vertex's position: 1 free, minus its pin group pinned.
    free: Vec<f32>,
    /// Pairs of the timer written since it was last read, while timing is on.
    timed: Option<u32>,
    /// GPU seconds read from a full timer and not yet taken.
    pending_seconds: f64,
    time_s: f64,
    substeps_run: u64,
    /// Whether the state or the parameters were written since the last frame: self-collision's
    /// candidate lists are rebuilt before the next substep.
    hash_stale: bool,
    last_advance: AdvanceCounts,
    /// Last, so that it is dropped after every object made on it.
    backend: B,
}

impl<B: GpuBackend> Drop for GpuSimulator<B> {
    /// Waits for the device first: the submitted frames use the pipelines, bind groups and
    /// buffers dropped next.
    fn drop(&mut self) {
        let _ = self.backend.wait();
    }
}

impl<B: GpuBackend> GpuSimulator<B> {
    /// What an implicit integrator's solver spent since creation: VBD's sweeps are fixed by the
    /// scene, so the host counts them; backward Euler's conjugate gradients count theirs on the
    /// device (`counters`, read back with the diagnostics).
    fn solver_spent(
        &self,
        counters: Option<crate::layout::GpuCgCounters>,
    ) -> Option<cloth_core::solver::SolverIterations> {
        let substeps = self.substeps_run;
        match self.scene.integrator {
            cloth_core::Integrator::BackwardEuler => counters.map(|c| cloth_core::solver::SolverIterations {
                substeps,
                newton: c.newton.into(),
                cg: c.cg.into(),
                cg_most: c.cg_most,
                vbd: 0,
            }),
            cloth_core::Integrator::Vbd => Some(cloth_core::solver::SolverIterations {
                substeps,
                vbd: substeps * u64::from(self.scene.solver.vbd_iterations),
                ..Default::default()
            }),
            _ => None,
        }
    }

    /// Creates the simulator on its own device, as `tuning` asks.
    ///
    /// # Errors
    /// As [`GpuSimulator::on_backend`], and [`SimError::Unavailable`] without an adapter.
    pub fn with_tuning(scene: &Scene, tuning: &GpuTuning) -> Result<Self, SimError> {
        scene.validate()?;
        tuning.check()?;
        Self::on_backend(scene, B::open(tuning)?, tuning)
    }

    /// Creates the simulator on an open device (e.g. a renderer's, to draw from
    /// [`GpuSimulator::position_buffer`] without a read-back). `tuning.adapter` is not used.
    ///
    /// # Errors
    /// [`SimError::Scene`] for an invalid scene, [`SimError::InvalidOption`] for a tuning value
    /// that is wrong or that the device cannot run, [`SimError::TooLarge`] when a buffer exceeds
    /// the device's limits, [`SimError::Unsupported`] when the device lacks what a kernel needs,
    /// [`SimError::Device`] when creating the GPU objects fails.
    pub fn on_backend(scene: &Scene, mut backend: B, tuning: &GpuTuning) -> Result<Self, SimError> {
        scene.validate()?;
        let plan = Plan::new(scene, tuning, &backend.limits(), B::NAME)?;
        let (buffers, pipelines, bind_groups) = backend.setup(|backend| {
            let buffers = plan.buffers.iter().map(|d| backend.create_buffer(d)).collect::<Result<Vec<_>, _>>()?;
            let kernels = plan.kernels.iter().map(|d| backend.create_kernel(d)).collect::<Result<Vec<_>, _>>()?;
            let pipelines = (plan.pipelines.iter())
                .map(|d| backend.create_pipeline(&kernels[d.kernel], d))
                .collect::<Result<Vec<_>, _>>()?;
            let bind_groups = (plan.bind_groups.iter())
                .map(|d| {
                    let bound: Vec<&B::Buffer> = d.buffers.iter().map(|&b| &buffers[b]).collect();
                    backend.create_bind_group(&kernels[d.kernel], d, &bound)
                })
                .collect::<Result<Vec<_>, _>>()?;
            Ok((buffers, pipelines, bind_groups))
        })?;
        let positions = plan.buffers[plan.state.positions[0]].contents.as_deref().unwrap_or_default();
        Ok(Self {
            scene: scene.clone(),
            sizes: plan.buffers.iter().map(|b| b.size).collect(),
            free: bytemuck::cast_slice::<u8, [f32; 4]>(positions).iter().map(|p| p[3]).collect(),
            buffers,
            pipelines,
            pipeline_names: plan.pipelines.iter().map(|p| p.name.clone()).collect(),
            bind_groups,
            schedule: plan.schedule,
            state: plan.state,
            dispatches: Vec::new(),
            current: 0,
            timed: None,
            pending_seconds: 0.0,
            time_s: 0.0,
            substeps_run: 0,
            hash_stale: true,
            last_advance: AdvanceCounts::default(),
            backend,
        })
    }

    /// The buffer holding the current positions (`vec4<f32>` per vertex, xyz in m), valid until
    /// the next `advance`; drawable as a vertex buffer on the same device.
    pub fn position_buffer(&self) -> &B::Buffer {
        &self.buffers[self.state.positions[self.current]]
    }

    /// The buffer holding the current velocities (`vec4<f32>` per vertex, xyz in m/s), valid
    /// until the next `advance`.
    pub fn velocity_buffer(&self) -> &B::Buffer {
        &self.buffers[self.state.velocities[self.current]]
    }

    /// The backend, with its device.
    pub fn backend(&self) -> &B {
        &self.backend
    }

    /// Lays out the dispatches of the next `substeps` substeps in `self.dispatches`; returns the
    /// state buffer they leave current.
    fn record(&mut self, substeps: u64) -> usize {
        self.dispatches.clear();
        self.schedule.frame_from(self.substeps_run, self.hash_stale, substeps, self.current, &mut self.dispatches)
    }

    /// After the dispatches of `substeps` substeps were submitted, leaving state buffer `next`
    /// current.
    fn submitted(&mut self, substeps: u64, next: usize) {
        self.current = next;
        self.hash_stale = false;
        // The clock advances substep by substep, as the kernels' `velocity.w` does.
        let dt = self.scene.substep_dt();
        for _ in 0..substeps {
            self.time_s += dt;
        }
        self.substeps_run += substeps;
    }

    fn read_buffers(&mut self, ids: &[usize]) -> Result<Vec<Vec<u8>>, SimError> {
        let sources: Vec<(&B::Buffer, u64)> = ids.iter().map(|&id| (&self.buffers[id], self.sizes[id])).collect();
        self.backend.read(&sources)
    }
}

impl<B: GpuBackend> Simulator for GpuSimulator<B> {
    fn new(scene: &Scene) -> Result<Self, SimError> {
        Self::with_tuning(scene, &GpuTuning::default())
    }

    fn backend_name(&self) -> &'static str {
        B::NAME
    }

    fn adapter_name(&self) -> String {
        self.backend.adapter_name()
    }

    fn scene(&self) -> &Scene {
        &self.scene
    }

    fn fused_substeps(&self) -> u32 {
        self.schedule.fused_substeps()
    }

    fn substep_state_bytes(&self) -> Option<u32> {
        Some(self.schedule.state_bytes())
    }

    fn advance(&mut self, frames: u32) -> Result<(), SimError> {
        self.last_advance = AdvanceCounts { frames, submissions: 0, host_waits: 0 };
        let substeps = self.scene.substeps_per_frame() as u64 * frames as u64;
        if substeps == 0 {
            return Ok(());
        }
        if self.timed == Some(TIMER_PAIRS) {
            // Only after as many advances as the timer holds without `take_gpu_seconds`: keep
            // the measurements.
            self.pending_seconds += self.backend.read_timer(TIMER_PAIRS)?;
            self.timed = Some(0);
            self.last_advance.host_waits = 1;
        }
        let next = self.record(substeps);
        let (dispatches, pipelines, bind_groups) = (&self.dispatches, &self.pipelines, &self.bind_groups);
        let indirect = self.state.indirect.map(|id| &self.buffers[id]);
        self.backend.submit(Frame { timestamps: self.timed, dispatches, pipelines, bind_groups, indirect })?;
        self.timed = self.timed.map(|pairs| pairs + 1);
        self.last_advance.submissions = 1;
        self.submitted(substeps, next);
        Ok(())
    }

    fn profile_frame(&mut self) -> Result<Option<Vec<PassTime>>, SimError> {
        let substeps = self.scene.substeps_per_frame() as u64;
        let next = self.record(substeps);
        let (dispatches, pipelines, bind_groups) = (&self.dispatches, &self.pipelines, &self.bind_groups);
        let indirect = self.state.indirect.map(|id| &self.buffers[id]);
        let frame = Frame { timestamps: None, dispatches, pipelines, bind_groups, indirect };
        let Some(seconds) = self.backend.submit_profiled(frame)? else { return Ok(None) };
        self.last_advance = AdvanceCounts { frames: 1, submissions: 1, host_waits: 1 };
        self.submitted(substeps, next);
        Ok(Some(passes_of(&self.dispatches, &seconds, &self.pipeline_names)))
    }

    fn update_parameters(&mut self, scene: &Scene) -> Result<(), SimError> {
        if let Some(what) = self.scene.rebuild_reason(scene) {
            return Err(SimError::RebuildRequired { what });
        }
        scene.validate()?;
        let (params, colliders) = (&self.buffers[self.state.params], &self.buffers[self.state.colliders]);
        self.backend.write(params, bytemuck::bytes_of(&GpuSimParams::of(scene)))?;
        self.backend.write(colliders, bytemuck::cast_slice(&GpuCollider::of_scene(scene)))?;
        self.scene = scene.clone();
        self.hash_stale = true;
        Ok(())
    }

    fn read_state(&mut self) -> Result<ClothState, SimError> {
        let k = self.current;
        let bytes = self.read_buffers(&[self.state.positions[k], self.state.velocities[k]])?;
        let xyz = |b: &[u8]| bytemuck::cast_slice::<u8, [f32; 4]>(b).iter().map(|q| [q[0], q[1], q[2]]).collect();
        Ok(ClothState { time_s: self.time_s, positions: xyz(&bytes[0]), velocities: xyz(&bytes[1]) })
    }

    fn write_state(&mut self, state: &ClothState) -> Result<(), SimError> {
        cloth_core::simulator::check_state_size(self.free.len(), state)?;
        let positions: Vec<[f32; 4]> =
            state.positions.iter().zip(&self.free).map(|(p, &w)| [p[0], p[1], p[2], w]).collect();
        // w: the state's time, which moving pins, moving colliders and gusts read on the GPU.
        let time = state.time_s as f32;
        let velocities: Vec<[f32; 4]> = state.velocities.iter().map(|v| [v[0], v[1], v[2], time]).collect();
        let k = self.current;
        let (p, v) = (&self.buffers[self.state.positions[k]], &self.buffers[self.state.velocities[k]]);
        self.backend.write(p, bytemuck::cast_slice(&positions))?;
        self.backend.write(v, bytemuck::cast_slice(&velocities))?;
        if let Some(last) = self.state.vbd_last_velocities {
            // VBD takes a state with no previous substep as in free fall (the reference's
            // assume_free_fall).
            let q = cloth_core::SceneQuantities::of(&self.scene);
            let hg = q.gravity.map(|g| (g * q.substep_dt) as f32);
            let before: Vec<[f32; 4]> =
                state.velocities.iter().map(|v| [v[0] - hg[0], v[1] - hg[1], v[2] - hg[2], 0.0]).collect();
            self.backend.write(&self.buffers[last], bytemuck::cast_slice(&before))?;
        }
        self.time_s = state.time_s;
        self.hash_stale = true;
        Ok(())
    }

    fn diagnostics(&mut self) -> Result<Diagnostics, SimError> {
        let mut read = vec![self.state.max_penetration];
        read.extend(self.state.self_control);
        read.extend(self.state.cg_counters);
        let bytes = self.read_buffers(&read)?;
        let bits = u32::from_le_bytes([bytes[0][0], bytes[0][1], bytes[0][2], bytes[0][3]]);
        let candidate_lists = self.state.self_control.map(|_| {
            let c: GpuSelfControl = bytemuck::pod_read_unaligned(&bytes[1][..size_of::<GpuSelfControl>()]);
            CandidateListStats {
                checks: c.checks.into(),
                rebuilds: c.rebuilds.into(),
                overflowed_lists: c.overflows.into(),
            }
        });
        let counters = self.state.cg_counters.map(|_| {
            let last = bytes.last().expect("the counters were read");
            bytemuck::pod_read_unaligned::<crate::layout::GpuCgCounters>(
                &last[..size_of::<crate::layout::GpuCgCounters>()],
            )
        });
        Ok(Diagnostics {
            max_penetration_m: f32::from_bits(bits) as f64,
            substeps_run: self.substeps_run,
            candidate_lists,
            solver: self.solver_spent(counters),
        })
    }

    fn last_advance_counts(&self) -> AdvanceCounts {
        self.last_advance
    }

    fn set_gpu_timing(&mut self, on: bool) -> bool {
        if !on {
            self.timed = None;
        } else if self.timed.is_none() && self.backend.create_timer() {
            self.timed = Some(0);
        }
        self.timed.is_some()
    }

    fn take_gpu_seconds(&mut self) -> Result<Option<f64>, SimError> {
        let Some(pairs) = self.timed else { return Ok(None) };
        let seconds = if pairs > 0 { self.backend.read_timer(pairs)? } else { 0.0 };
        self.timed = Some(0);
        Ok(Some(seconds + std::mem::take(&mut self.pending_seconds)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_profile_sums_each_pipelines_dispatches_in_the_order_they_first_run() {
        let names: Vec<String> = ["check", "insert", "step", "forced check"].iter().map(|s| s.to_string()).collect();
        let dispatch =
            |pipeline| Dispatch { pipeline, bind_group: 0, workgroups: [1, 1], dynamic_offset: None, indirect: None };
        // A check and an insert before every other substep, as a self-collision frame has them.
        let frame: Vec<Dispatch> = [0, 1, 2, 2, 0, 1, 2, 2].into_iter().map(dispatch).collect();
        let seconds = [1.0, 2.0, 10.0, 20.0, 3.0, 4.0, 30.0, 40.0];
        let passes = passes_of(&frame, &seconds, &names);
        let rows: Vec<(&str, u32, f64, f64, f64)> =
            passes.iter().map(|p| (p.name.as_str(), p.dispatches, p.seconds, p.shortest_s, p.longest_s)).collect();
        assert_eq!(rows, [("check", 2, 4.0, 1.0, 3.0), ("insert", 2, 6.0, 2.0, 4.0), ("step", 4, 100.0, 10.0, 40.0)]);
        // A pipeline that never runs has no row; the rows add up to the frame.
        let total: f64 = passes.iter().map(|p| p.seconds).sum();
        assert_eq!(total, seconds.iter().sum::<f64>());
    }
}
