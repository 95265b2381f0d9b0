//! The frame's command buffer, recorded without vulkano's automatic synchronisation.
//!
//! vulkano's `AutoCommandBufferBuilder` tracks every use of every buffer to place barriers, and
//! its cost grows faster than the commands of a command buffer: measured on the H100, 64 XPBD
//! substeps per frame (7 800 dispatches) took 750 ms of recording per frame. A cloth substep needs
//! no such tracking: every dispatch may read what the one before wrote, so one global memory
//! barrier between dispatches is exactly the synchronisation required. [`FrameRecorder`] records
//! that directly (the commands are validated by vulkano, the barriers are ours), and [`RawPrimary`]
//! lets the result join vulkano's futures like any primary command buffer.

use std::sync::Arc;

use parking_lot::{Mutex, MutexGuard};
use vulkano::VulkanObject;
use vulkano::command_buffer::allocator::CommandBufferAllocator;
use vulkano::command_buffer::{
    CommandBuffer, CommandBufferBeginInfo, CommandBufferLevel, CommandBufferResourcesUsage, CommandBufferState,
    CommandBufferUsage, PrimaryAutoCommandBuffer, PrimaryCommandBufferAbstract, RecordingCommandBuffer,
};
use vulkano::device::{Device, DeviceOwned};
use vulkano::sync::{AccessFlags, DependencyInfo, MemoryBarrier, PipelineStages};

/// A primary command buffer recorded by [`FrameRecorder`].
pub(crate) struct RawPrimary {
    inner: CommandBuffer,
    state: Mutex<CommandBufferState>,
    /// An empty automatic command buffer whose (empty) resource usage this one reports to
    /// vulkano's futures: `CommandBufferResourcesUsage` cannot be built outside vulkano, and this
    /// command buffer's buffers are synchronised by its own barriers.
    no_resources: Arc<PrimaryAutoCommandBuffer>,
}

// SAFETY: the handle is the recorded command buffer's.
unsafe impl VulkanObject for RawPrimary {
    type Handle = <CommandBuffer as VulkanObject>::Handle;

    fn handle(&self) -> Self::Handle {
        self.inner.handle()
    }
}

// SAFETY: the device is the recorded command buffer's.
unsafe impl DeviceOwned for RawPrimary {
    fn device(&self) -> &Arc<Device> {
        self.inner.device()
    }
}

// SAFETY: the command buffer is fully recorded and ended; it is submitted once (one-time
// submit, as its state records); the resources its commands use are kept alive by the simulator,
// which waits for the device before dropping them, and their hazards are covered by the barriers
// it recorded (see `FrameRecorder`), so it reports no resource for vulkano to track.
unsafe impl PrimaryCommandBufferAbstract for RawPrimary {
    fn as_raw(&self) -> &CommandBuffer {
        &self.inner
    }

    fn queue_family_index(&self) -> u32 {
        self.inner.queue_family_index()
    }

    fn usage(&self) -> CommandBufferUsage {
        CommandBufferUsage::OneTimeSubmit
    }

    fn state(&self) -> MutexGuard<'_, CommandBufferState> {
        self.state.lock()
    }

    fn resources_usage(&self) -> &CommandBufferResourcesUsage {
        self.no_resources.resources_usage()
    }
}

/// Records one frame's commands with explicit barriers.
pub(crate) struct FrameRecorder {
    pub recording: RecordingCommandBuffer,
}

impl FrameRecorder {
    /// Begins a one-time primary command buffer whose first command waits for everything
    /// submitted before it (uploads, read-backs, earlier frames) and makes its writes visible.
    pub fn begin(allocator: Arc<dyn CommandBufferAllocator>, queue_family_index: u32) -> Result<Self, String> {
        let recording = RecordingCommandBuffer::new(
            allocator,
            queue_family_index,
            CommandBufferLevel::Primary,
            CommandBufferBeginInfo { usage: CommandBufferUsage::OneTimeSubmit, ..Default::default() },
        )
        .map_err(|e| format!("command buffer: {e}"))?;
        let mut recorder = Self { recording };
        let all = PipelineStages::ALL_COMMANDS;
        recorder.barrier(all, AccessFlags::MEMORY_WRITE, all, AccessFlags::MEMORY_READ)?;
        Ok(recorder)
    }

    /// Records a global memory barrier: what `stages` wrote (`written`) is visible to `then_stages`
    /// after it, for `then` and writing.
    fn barrier(
        &mut self,
        stages: PipelineStages,
        written: AccessFlags,
        then_stages: PipelineStages,
        then: AccessFlags,
    ) -> Result<(), String> {
        let barrier = MemoryBarrier {
            src_stages: stages,
            src_access: written,
            dst_stages: then_stages,
            dst_access: then | written,
            ..Default::default()
        };
        let dependency = DependencyInfo { memory_barriers: [barrier].into_iter().collect(), ..Default::default() };
        // SAFETY: a memory barrier has no resource to keep alive.
        unsafe { self.recording.pipeline_barrier(&dependency) }.map_err(|e| format!("barrier: {e}"))?;
        Ok(())
    }

    /// The barrier between two dispatches: the next one may read and write what this one wrote,
    /// and, where it is `indirect`, read its size from it. Only the barrier before an indirect
    /// dispatch waits for the indirect-command stage: a barrier's second scope covers every later
    /// command, so the indirect reads further on are covered too, and the write of the next sizes
    /// waits for those reads anyway, since a dispatch's indirect read comes before its shader.
    pub fn between_dispatches(&mut self, indirect: bool) -> Result<(), String> {
        let compute = PipelineStages::COMPUTE_SHADER;
        let (stages, reads) = if indirect {
            (compute | PipelineStages::DRAW_INDIRECT, AccessFlags::SHADER_READ | AccessFlags::INDIRECT_COMMAND_READ)
        } else {
            (compute, AccessFlags::SHADER_READ)
        };
        self.barrier(compute, AccessFlags::SHADER_WRITE, stages, reads)
    }

    /// Ends the command buffer after a barrier that makes its writes visible to whatever is
    /// submitted after it (read-backs, the next frame).
    pub fn end(mut self, no_resources: Arc<PrimaryAutoCommandBuffer>) -> Result<Arc<RawPrimary>, String> {
        let all = PipelineStages::ALL_COMMANDS;
        self.barrier(all, AccessFlags::MEMORY_WRITE, all, AccessFlags::MEMORY_READ)?;
        // SAFETY: every command recorded is complete (no open render pass or query).
        let inner = unsafe { self.recording.end() }.map_err(|e| format!("ending the command buffer: {e}"))?;
        Ok(Arc::new(RawPrimary { inner, state: Mutex::new(CommandBufferState::default()), no_resources }))
    }
}
